//! The supervisor's relay: tools that hold no module address (every address of the domain is
//! taken) call modules through it. One iceoryx2 request-response service, `relay`; its
//! messages are [`modbot_ipc_schema::relay`]'s.

use core::time::Duration;
use std::time::Instant;

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::client::Client;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::request_response::{
    RequestResponseCreateError, RequestResponseOpenError,
};
use iceoryx2::service::port_factory::request_response::PortFactory;

use modbot_ipc_schema::Addr;

use super::wake::{WakeTable, Word};
use super::{service_name, IpcTransport};
use crate::{IpcResult, TransportError};

/// The relay service.
const SERVICE: &str = "relay";
/// Largest request or response: a frame's payload and the names.
const MAX_MESSAGE: usize = 64 * 1024 + 128;
/// Tools calling through the relay at once.
const MAX_CLIENTS: usize = 16;
/// Requests a tool has in flight at once.
const MAX_IN_FLIGHT: usize = 32;

type Factory = PortFactory<ipc::Service, [u8], (), [u8], ()>;

fn service(node: &Node<ipc::Service>, create: bool) -> Result<Option<Factory>, TransportError> {
    let name = service_name(SERVICE)?;
    let builder = || {
        node.service_builder(&name)
            .request_response::<[u8], [u8]>()
            .max_servers(1)
            .max_clients(MAX_CLIENTS)
            .max_nodes(MAX_CLIENTS + 1)
            .max_active_requests_per_client(MAX_IN_FLIGHT)
            .max_response_buffer_size(1)
            .max_borrowed_responses_per_pending_response(1)
    };
    if !create {
        return match builder().open() {
            Ok(f) => Ok(Some(f)),
            Err(RequestResponseOpenError::DoesNotExist) => Ok(None),
            Err(e) => Err(TransportError::ipc("open the relay", e)),
        };
    }
    // A tool may still hold the relay of an earlier supervisor (stopped, or dead and cleaned
    // up): it is taken over. If the tool leaves between the refused create and the open, the
    // relay is created after all.
    for _ in 0..3 {
        match builder().create() {
            Ok(f) => return Ok(Some(f)),
            Err(RequestResponseCreateError::AlreadyExists) => {}
            Err(e) => return Err(TransportError::ipc("create the relay", e)),
        }
        match builder().open() {
            Ok(f) => return Ok(Some(f)),
            Err(RequestResponseOpenError::DoesNotExist) => {}
            Err(e) => return Err(TransportError::ipc("take over the relay", e)),
        }
    }
    Err(TransportError::Contended {
        op: "create the relay",
    })
}

/// A request waiting for its answer, held by the supervisor.
pub struct RelayRequest(ActiveRequest<ipc::Service, [u8], (), [u8], ()>);

impl RelayRequest {
    pub fn payload(&self) -> &[u8] {
        self.0.payload()
    }

    /// Sends the answer (a [`modbot_ipc_schema::relay::Response`]).
    pub fn answer(self, bytes: &[u8]) -> Result<(), TransportError> {
        let response = self
            .0
            .loan_slice_uninit(bytes.len())
            .ipc("loan a relay answer")?;
        response
            .write_from_slice(bytes)
            .send()
            .ipc("send a relay answer")
    }
}

/// The supervisor's side.
pub struct RelayServer {
    server: Server<ipc::Service, [u8], (), [u8], ()>,
    _service: Factory,
    _node: Node<ipc::Service>,
}

impl RelayServer {
    pub fn create(transport: &IpcTransport) -> Result<RelayServer, TransportError> {
        let node = transport.node(&format!("relay.{}", std::process::id()))?;
        let service = service(&node, true)?.expect("created");
        let server = service
            .server_builder()
            .initial_max_slice_len(MAX_MESSAGE)
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_responses_per_request(1)
            .create()
            .map_err(|e| match e {
                // A domain's relay has one server: another supervisor's.
                iceoryx2::service::port_factory::server::ServerCreateError::ExceedsMaxSupportedServers => {
                    TransportError::AnotherSupervisor { pid: None }
                }
                e => TransportError::ipc("relay server", e),
            })?;
        Ok(RelayServer {
            server,
            _service: service,
            _node: node,
        })
    }

    /// The next waiting request, if any.
    pub fn receive(&self) -> Result<Option<RelayRequest>, TransportError> {
        self.server
            .receive()
            .map(|r| r.map(RelayRequest))
            .ipc("receive a relay request")
    }
}

/// A tool's side.
pub struct RelayClient {
    client: Client<ipc::Service, [u8], (), [u8], ()>,
    /// Wakes the supervisor (it sleeps in blocking mode): the domain's table and its word.
    wake: (WakeTable, Word),
    _service: Factory,
    _node: Node<ipc::Service>,
}

impl RelayClient {
    /// Opens the relay of `transport`'s domain, whose supervisor is at `supervisor`; `Ok(None)`
    /// if no supervisor offers one.
    pub fn open(
        transport: &IpcTransport,
        supervisor: Addr,
    ) -> Result<Option<RelayClient>, TransportError> {
        let node = transport.node(&format!("relay.{}", std::process::id()))?;
        let Some(service) = service(&node, false)? else {
            return Ok(None);
        };
        let client = service
            .client_builder()
            .max_active_requests(MAX_IN_FLIGHT)
            .initial_max_slice_len(MAX_MESSAGE)
            .allocation_strategy(AllocationStrategy::Static)
            .create()
            .ipc("relay client")?;
        let wake = (
            WakeTable::open(transport.domain())?,
            Word::module(supervisor),
        );
        Ok(Some(RelayClient {
            client,
            wake,
            _service: service,
            _node: node,
        }))
    }

    /// Sends `request` and waits up to `timeout` for the answer, which `read` reads in place.
    pub fn call<R>(
        &self,
        request: &[u8],
        timeout: Duration,
        read: impl FnOnce(&[u8]) -> R,
    ) -> Result<R, TransportError> {
        let mut read = Some(read);
        let mut out = None;
        self.call_many(&[request], timeout, |_, answer| {
            out = Some(answer.map(|bytes| (read.take().expect("one answer"))(bytes)));
        })?;
        out.expect("every request is answered or fails")
    }

    /// Sends every request (several in flight at once) and hands each answer, by index, to
    /// `read`: in place, or why there is none (the supervisor did not answer within
    /// `timeout` of the request).
    pub fn call_many(
        &self,
        requests: &[&[u8]],
        timeout: Duration,
        mut read: impl FnMut(usize, Result<&[u8], TransportError>),
    ) -> Result<(), TransportError> {
        let mut next = 0;
        let mut in_flight = Vec::new();
        while next < requests.len() || !in_flight.is_empty() {
            while next < requests.len() && in_flight.len() < MAX_IN_FLIGHT {
                let request = requests[next];
                let pending = self
                    .client
                    .loan_slice_uninit(request.len())
                    .ipc("loan a relay request")?
                    .write_from_slice(request)
                    .send()
                    .ipc("send a relay request")?;
                in_flight.push((next, pending, Instant::now() + timeout));
                next += 1;
            }
            self.wake.0.notify(self.wake.1);
            let mut progress = false;
            let mut i = 0;
            while i < in_flight.len() {
                let (index, pending, deadline) = &in_flight[i];
                let response = pending.receive().ipc("receive a relay answer")?;
                if let Some(response) = response {
                    read(*index, Ok(response.payload()));
                } else if Instant::now() >= *deadline {
                    read(*index, Err(TransportError::RelayTimeout { timeout }));
                } else {
                    i += 1;
                    continue;
                }
                in_flight.swap_remove(i);
                progress = true;
            }
            if !progress {
                std::thread::sleep(Duration::from_micros(50));
            }
        }
        Ok(())
    }
}

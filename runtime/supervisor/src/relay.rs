//! Calls of tools that hold no module address, made by the supervisor as its own: the tool's
//! request arrives on the relay service, the supervisor calls the module, and the answer (or
//! why there is none) goes back to the tool.

use std::time::Duration;

use modbot_ipc_schema::relay::{self, Request};
use modbot_ipc_schema::Args;

use super::shared::Shared;
use modbot_core::calls::{CallHandle, CallOptions};
use modbot_core::ctx::Ctx;
use modbot_core::error::CallError;
use modbot_core::module::Module;
use modbot_core::transport::ipc::{IpcTransport, RelayRequest, RelayServer};
use modbot_core::transport::TransportError;

/// Requests in flight.
pub(super) struct Relay {
    server: RelayServer,
    waiting: Vec<(CallHandle, RelayRequest)>,
}

impl Relay {
    pub(super) fn new(transport: &IpcTransport) -> Result<Relay, TransportError> {
        Ok(Relay {
            server: RelayServer::create(transport)?,
            waiting: Vec::new(),
        })
    }

    /// Starts the calls of new requests, and answers the requests whose calls ended.
    pub(super) fn serve(&mut self, endpoint: &mut Module<Shared>) {
        loop {
            let request = match self.server.receive() {
                Ok(Some(r)) => r,
                Ok(None) => break,
                Err(e) => {
                    tracing::debug!("relay: {e}");
                    break;
                }
            };
            match start(endpoint.ctx(), request.payload()) {
                Ok(handle) => self.waiting.push((handle, request)),
                Err(why) => answer(request, &relay::encode_failed(&why.to_string())),
            }
        }
        let done = std::mem::take(&mut endpoint.state_mut().relayed);
        for (handle, response) in done {
            if let Some(i) = self.waiting.iter().position(|(h, _)| *h == handle) {
                let (_, request) = self.waiting.swap_remove(i);
                answer(request, &response);
            }
        }
    }
}

/// Why a relayed call could not be made: the tool's request, or the call.
#[derive(Debug, thiserror::Error)]
enum StartError {
    #[error(transparent)]
    Request(#[from] relay::RelayError),
    #[error(transparent)]
    Call(#[from] CallError),
}

fn start(ctx: &mut Ctx, payload: &[u8]) -> Result<CallHandle, StartError> {
    let request = Request::parse(payload)?;
    let args = request.values()?;
    let timeout = Duration::from_millis(u64::from(request.timeout_ms.clamp(1, 60_000)));
    Ok(ctx.call_with(
        request.module,
        request.method,
        args.as_slice(),
        CallOptions::timeout(timeout),
    )?)
}

fn answer(request: RelayRequest, response: &[u8]) {
    if let Err(e) = request.answer(response) {
        tracing::debug!("relay: the answer did not reach the tool: {e}");
    }
}

/// The supervisor module's `on_done`: a relayed call ended.
pub(super) fn on_done(
    shared: &mut Shared,
    _: &mut Ctx,
    handle: CallHandle,
    result: Result<&Args<'_>, &CallError>,
) {
    let response = match result {
        Ok(args) => relay::encode_answered(args.as_slice())
            .unwrap_or_else(|e| relay::encode_failed(&e.to_string())),
        Err(e) => relay::encode_failed(&e.to_string()),
    };
    shared.relayed.push((handle, response));
}

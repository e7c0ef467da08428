//! A tool's way into a running system (`modbot ls`, `call`, `bb`, ...): a short-lived endpoint
//! at a free address, or, when every address of the domain is taken, calls relayed by the
//! supervisor and the supervisor's published directory.

use core::time::Duration;

use modbot_ipc_schema::relay::{self, Response};
use modbot_ipc_schema::value::Values;
use modbot_ipc_schema::{Addr, Args, OwnedValue, Value};

use crate::calls::{owned_answer, CallOptions};
use crate::domain::Domain;
use crate::error::{CallError, ModuleError};
use crate::module::{Module, ModuleBuilder};
use crate::transport::ipc::{IpcTransport, RelayClient};
use crate::transport::{Directory, PeerInfo, Transport, TransportError};

/// Something that can call a module and wait for the answer: a module, or a [`Tool`].
pub trait Calls {
    /// Calls `method` of `module` and waits for the answer, which `on_answer` reads in place.
    fn call_blocking<R>(
        &mut self,
        module: &str,
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
        on_answer: impl FnOnce(Result<&Args<'_>, &CallError>) -> R,
    ) -> R;

    /// Like [`Calls::call_blocking`], returning owned values.
    fn call_owned(
        &mut self,
        module: &str,
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
    ) -> Result<Vec<OwnedValue>, CallError> {
        self.call_blocking(module, method, args, opts, owned_answer)
    }
}

impl<S> Calls for Module<S> {
    fn call_blocking<R>(
        &mut self,
        module: &str,
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
        on_answer: impl FnOnce(Result<&Args<'_>, &CallError>) -> R,
    ) -> R {
        Module::call_blocking(self, module, method, args, opts, on_answer)
    }
}

impl Calls for Tool {
    fn call_blocking<R>(
        &mut self,
        module: &str,
        method: &str,
        args: &[Value<'_>],
        opts: CallOptions,
        on_answer: impl FnOnce(Result<&Args<'_>, &CallError>) -> R,
    ) -> R {
        let (relay, module_name) = match self {
            Tool::Endpoint(m) => return m.call_blocking(module, method, args, opts, on_answer),
            Tool::Relay { relay, .. } => (relay, module),
        };
        let timeout_ms = opts.timeout.as_millis().min(u128::from(u32::MAX)) as u32;
        let request = match relay::encode_request(module_name, method, timeout_ms, args) {
            Ok(r) => r,
            Err(e) => return on_answer(Err(&CallError::Encode(e.to_string()))),
        };
        let mut on_answer = Some(on_answer);
        // The supervisor answers within the call's timeout; a second more is its own delay.
        let waited = relay.call(&request, opts.timeout + Duration::from_secs(1), |bytes| {
            read_response(module_name, bytes, on_answer.take().expect("called once"))
        });
        match waited {
            Ok(r) => r,
            Err(e) => (on_answer.take().expect("not called"))(Err(&CallError::Transport(e))),
        }
    }
}

/// What a tool calls through.
pub enum Tool {
    /// An endpoint of its own, at a free address.
    Endpoint(Box<Module<()>>),
    /// Every address is taken: the supervisor calls for the tool.
    Relay {
        relay: Box<RelayClient>,
        directory: Box<dyn Directory>,
    },
}

impl Tool {
    /// Joins `domain` as the tool named `name`: at a free address if there is one, else
    /// through the supervisor.
    pub fn open(domain: &Domain, name: &str) -> Result<Tool, ModuleError> {
        let transport = IpcTransport::new(domain)?;
        match ModuleBuilder::new(name, 0).open_tool(transport.clone(), ()) {
            Ok(m) => Ok(Tool::Endpoint(Box::new(m))),
            Err(ModuleError::Transport(TransportError::NoFreeAddress)) => {
                let directory = transport.directory()?;
                let mut supervisor = None;
                directory.list(&mut |p| {
                    if p.name == "supervisor" && p.alive {
                        supervisor = Some(p.addr);
                    }
                })?;
                let no_relay = || ModuleError::Transport(TransportError::DomainFull);
                let supervisor = supervisor.ok_or_else(no_relay)?;
                let relay = RelayClient::open(&transport, supervisor)?.ok_or_else(no_relay)?;
                Ok(Tool::Relay {
                    relay: Box::new(relay),
                    directory,
                })
            }
            Err(e) => Err(e),
        }
    }

    /// The tool's own address, if it has one.
    pub fn addr(&self) -> Option<Addr> {
        match self {
            Tool::Endpoint(m) => Some(m.addr()),
            Tool::Relay { .. } => None,
        }
    }

    /// Every module of the domain, by address.
    pub fn list_modules(&self) -> Result<Vec<PeerInfo>, TransportError> {
        match self {
            Tool::Endpoint(m) => m.list_modules(),
            Tool::Relay { directory, .. } => {
                let mut out = Vec::new();
                directory.list(&mut |p| out.push(p))?;
                out.sort_by_key(|p| (p.addr, !p.alive));
                Ok(out)
            }
        }
    }

    /// Calls `method` (without arguments) of every module of `modules`, and hands each answer
    /// to `on_answer` with the module's index. Through the supervisor the calls go out
    /// together; from an endpoint one after the other.
    pub fn call_each(
        &mut self,
        modules: &[&str],
        method: &str,
        opts: CallOptions,
        mut on_answer: impl FnMut(usize, Result<&Args<'_>, &CallError>),
    ) {
        let relay = match self {
            Tool::Endpoint(m) => {
                for (i, module) in modules.iter().enumerate() {
                    m.call_blocking(module, method, &[], opts, |r| on_answer(i, r));
                }
                return;
            }
            Tool::Relay { relay, .. } => relay,
        };
        let timeout_ms = opts.timeout.as_millis().min(u128::from(u32::MAX)) as u32;
        let mut requests = Vec::with_capacity(modules.len());
        for (i, module) in modules.iter().enumerate() {
            match relay::encode_request(module, method, timeout_ms, &[]) {
                Ok(r) => requests.push((i, r)),
                Err(e) => on_answer(i, Err(&CallError::Encode(e.to_string()))),
            }
        }
        let bytes: Vec<&[u8]> = requests.iter().map(|(_, r)| r.as_slice()).collect();
        let sent = relay.call_many(
            &bytes,
            opts.timeout + Duration::from_secs(1),
            |k, answer| {
                let i = requests[k].0;
                match answer {
                    Ok(bytes) => read_response(modules[i], bytes, |r| on_answer(i, r)),
                    Err(e) => on_answer(i, Err(&CallError::Transport(e))),
                }
            },
        );
        if let Err(e) = sent {
            tracing::debug!("relay: {e}");
        }
    }

    /// Removes what dead modules left (an endpoint of an unsupervised domain only).
    pub fn reap_dead(&self) {
        if let Tool::Endpoint(m) = self {
            m.reap_dead();
        }
    }
}

/// Reads a relay response and hands the answer (or why there is none) to `f`.
fn read_response<R>(
    module: &str,
    bytes: &[u8],
    f: impl FnOnce(Result<&Args<'_>, &CallError>) -> R,
) -> R {
    match Response::parse(bytes) {
        Ok(Response::Answered(values)) => match Args::decode(Values::new(values, 1)) {
            Ok(args) => f(Ok(&args)),
            Err(e) => f(Err(&CallError::BadAnswer {
                module: module.to_owned(),
                detail: e.to_string(),
            })),
        },
        Ok(Response::Failed(why)) => f(Err(&CallError::Relayed(why.to_owned()))),
        Err(e) => f(Err(&CallError::BadAnswer {
            module: "supervisor".into(),
            detail: e.to_string(),
        })),
    }
}

//! Errors of the module runtime.

use modbot_ipc_schema::{Addr, ArgError, NakCode};
use thiserror::Error;

use crate::transport::{SendError, TransportError};

/// Why a call to another module failed.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CallError {
    #[error("module '{0}' is not available: no module of that name is running in this domain")]
    UnknownModule(String),
    #[error("module '{name}' is not available: {why}")]
    NotAvailable { name: String, why: String },
    #[error("module '{module}' has no method '{method}' (it has: {known})")]
    UnknownMethod {
        module: String,
        method: String,
        known: String,
    },
    #[error("'{module}' refused the call: {code}{}", detail_suffix(.detail))]
    Nak {
        module: String,
        code: NakCode,
        detail: String,
    },
    #[error("no answer from '{module}' within {timeout_ms} ms (request sent {})", times(*.sends))]
    Timeout {
        module: String,
        timeout_ms: u64,
        /// How many times the request was sent (first send and retransmissions).
        sends: u8,
    },
    #[error("too many calls outstanding to module {0} (32 per peer)")]
    TooManyOutstanding(Addr),
    #[error("the method queue is full ({0} calls outstanding)")]
    QueueFull(usize),
    #[error("arguments too large: {0}")]
    Encode(String),
    #[error("malformed answer from '{module}': {detail}")]
    BadAnswer { module: String, detail: String },
    /// A call the supervisor made for a tool without an address failed; why, as it said.
    #[error("{0}")]
    Relayed(String),
    #[error(transparent)]
    Send(#[from] SendError),
    #[error(transparent)]
    Transport(#[from] TransportError),
}

fn times(n: u8) -> String {
    match n {
        0 => "never: the peer could not be reached".into(),
        1 => "once".into(),
        n => format!("{n} times"),
    }
}

fn detail_suffix(detail: &str) -> String {
    if detail.is_empty() {
        String::new()
    } else {
        format!(": {detail}")
    }
}

/// Why a local method refused a call; becomes a NAK with the matching code.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MethodError {
    #[error("bad arguments: {0}")]
    BadArguments(#[from] ArgError),
    #[error("busy: {0}")]
    Busy(String),
    #[error("{0}")]
    Failed(String),
    #[error("not ready: {0}")]
    NotReady(String),
    /// A request that names no blackboard item of this module.
    #[error("{0}")]
    UnknownItem(String),
    /// A write to an item other modules may only read.
    #[error("{0}")]
    ReadOnly(String),
}

impl MethodError {
    pub fn code(&self) -> NakCode {
        match self {
            MethodError::BadArguments(_) => NakCode::BAD_ARGUMENTS,
            MethodError::Busy(_) => NakCode::BUSY,
            MethodError::Failed(_) => NakCode::FAILED,
            MethodError::NotReady(_) => NakCode::NOT_READY,
            MethodError::UnknownItem(_) => NakCode::UNKNOWN_ITEM,
            MethodError::ReadOnly(_) => NakCode::READ_ONLY,
        }
    }
}

/// Why a module could not start or run.
#[derive(Debug, Error)]
pub enum ModuleError {
    #[error("module '{name}' at address {addr}: {source}")]
    Open {
        name: String,
        addr: Addr,
        source: TransportError,
    },
    #[error("module definition: {0}")]
    Definition(String),
    /// This process was started to take a running module over and could not
    /// ([`crate::upgrade`]).
    #[error("live upgrade of module '{name}': {why}")]
    Upgrade { name: String, why: String },
    #[error(transparent)]
    Transport(#[from] TransportError),
    #[error(transparent)]
    Domain(#[from] crate::domain::DomainNameError),
}

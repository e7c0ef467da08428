//! What failed below the transport, typed: iceoryx2's errors ([`IpcFailure`]) and the
//! operating system's ([`IoFailure`]). Both are `Copy`, so a [`TransportError`](crate::TransportError) made of one on
//! a failed send or receive allocates nothing, and a caller can match on what failed.

use iceoryx2::node::{NodeCreationFailure, NodeListFailure};
use iceoryx2::port::client::RequestSendError;
use iceoryx2::port::publisher::PublisherCreateError;
use iceoryx2::port::reader::{EntryHandleError, ReaderCreateError};
use iceoryx2::port::subscriber::SubscriberCreateError;
use iceoryx2::port::update_connections::ConnectionFailure;
use iceoryx2::port::writer::{EntryHandleMutError, WriterCreateError};
use iceoryx2::port::{LoanError, ReceiveError};
use iceoryx2::prelude::SemanticStringError;
use iceoryx2::service::builder::blackboard::{BlackboardCreateError, BlackboardOpenError};
use iceoryx2::service::builder::event::EventCreateError;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError;
use iceoryx2::service::builder::request_response::{
    RequestResponseCreateError, RequestResponseOpenError,
};
use iceoryx2::service::port_factory::client::ClientCreateError;
use iceoryx2::service::port_factory::server::ServerCreateError;
use iceoryx2::service::service_name::ServiceNameError;
use thiserror::Error;

/// An iceoryx2 error, one variant per iceoryx2 error type the transport meets. Its text is
/// iceoryx2's: the error type and its variant (`LoanError::OutOfMemory`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum IpcFailure {
    /// A node name, the domain's prefix or iceoryx2's root path is not a valid name or path.
    #[error(transparent)]
    Name(#[from] SemanticStringError),
    /// A service name is not valid.
    #[error(transparent)]
    ServiceName(#[from] ServiceNameError),
    /// The module's (or tool's) node could not be created.
    #[error(transparent)]
    NodeCreation(#[from] NodeCreationFailure),
    /// The domain's nodes could not be listed.
    #[error(transparent)]
    NodeList(#[from] NodeListFailure),
    /// An event service (a claim of an address or a name) could not be created.
    #[error(transparent)]
    EventCreate(#[from] EventCreateError),
    /// A publish-subscribe service (an inbox, a bus, a channel, ...) could not be opened or
    /// created.
    #[error(transparent)]
    PublishSubscribe(#[from] PublishSubscribeOpenOrCreateError),
    /// A blackboard (the supervisor's directory) could not be created.
    #[error(transparent)]
    BlackboardCreate(#[from] BlackboardCreateError),
    /// A blackboard (the supervisor's directory) could not be opened.
    #[error(transparent)]
    BlackboardOpen(#[from] BlackboardOpenError),
    /// A request-response service (the supervisor's relay) could not be created.
    #[error(transparent)]
    RequestResponseCreate(#[from] RequestResponseCreateError),
    /// A request-response service (the supervisor's relay) could not be opened.
    #[error(transparent)]
    RequestResponseOpen(#[from] RequestResponseOpenError),
    /// A publisher could not be created.
    #[error(transparent)]
    PublisherCreate(#[from] PublisherCreateError),
    /// A subscriber could not be created.
    #[error(transparent)]
    SubscriberCreate(#[from] SubscriberCreateError),
    /// A request-response server could not be created.
    #[error(transparent)]
    ServerCreate(#[from] ServerCreateError),
    /// A request-response client could not be created.
    #[error(transparent)]
    ClientCreate(#[from] ClientCreateError),
    /// A blackboard writer could not be created.
    #[error(transparent)]
    WriterCreate(#[from] WriterCreateError),
    /// A blackboard reader could not be created.
    #[error(transparent)]
    ReaderCreate(#[from] ReaderCreateError),
    /// A blackboard writer's entry could not be had.
    #[error(transparent)]
    WriterEntry(#[from] EntryHandleMutError),
    /// A blackboard reader's entry could not be had.
    #[error(transparent)]
    ReaderEntry(#[from] EntryHandleError),
    /// No sample (or request, or response) could be loaned to write into.
    #[error(transparent)]
    Loan(#[from] LoanError),
    /// A sample (or a response) could not be sent.
    #[error(transparent)]
    Send(#[from] iceoryx2::port::SendError),
    /// A request could not be sent.
    #[error(transparent)]
    RequestSend(#[from] RequestSendError),
    /// A sample (or a request, or a response) could not be received.
    #[error(transparent)]
    Receive(#[from] ReceiveError),
    /// A port could not connect to its counterparts.
    #[error(transparent)]
    Connection(#[from] ConnectionFailure),
}

/// An operating-system error, kept as its kind and code so that it stays `Copy` and
/// comparable; its text is the system's (`Permission denied (os error 13)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IoFailure {
    /// What kind of error it is.
    pub kind: std::io::ErrorKind,
    /// The system's error number, when it came from the system.
    pub code: Option<i32>,
}

impl From<&std::io::Error> for IoFailure {
    fn from(e: &std::io::Error) -> IoFailure {
        IoFailure {
            kind: e.kind(),
            code: e.raw_os_error(),
        }
    }
}

impl From<std::io::Error> for IoFailure {
    fn from(e: std::io::Error) -> IoFailure {
        IoFailure::from(&e)
    }
}

impl From<rustix::io::Errno> for IoFailure {
    fn from(e: rustix::io::Errno) -> IoFailure {
        IoFailure::from(std::io::Error::from(e))
    }
}

impl core::fmt::Display for IoFailure {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.code {
            Some(code) => std::io::Error::from_raw_os_error(code).fmt(f),
            None => self.kind.fmt(f),
        }
    }
}

impl std::error::Error for IoFailure {}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TransportError;

    #[test]
    fn failures_read_as_iceoryx2_and_the_system_name_them() {
        let e = TransportError::ipc("loan", LoanError::OutOfMemory);
        assert_eq!(
            e.to_string(),
            "iceoryx2 loan failed: LoanError::OutOfMemory"
        );
        assert_eq!(
            e,
            TransportError::Ipc {
                op: "loan",
                failure: IpcFailure::Loan(LoanError::OutOfMemory),
            }
        );
        let io = IoFailure::from(std::io::Error::from_raw_os_error(13));
        assert_eq!(io.kind, std::io::ErrorKind::PermissionDenied);
        assert_eq!(
            io.to_string(),
            std::io::Error::from_raw_os_error(13).to_string()
        );
        let kind_only = IoFailure::from(std::io::Error::from(std::io::ErrorKind::NotFound));
        assert_eq!(kind_only.to_string(), "entity not found");
    }
}

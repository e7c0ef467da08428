//! Where a domain's published directory lives: the blackboard service `directory`, or, while
//! a process still holds one that a dead supervisor wrote, the next free of `directory.1` ..
//! `directory.7`.
//!
//! iceoryx2 frees a blackboard entry's writer handle when the writer drops it, never when a
//! dead writer is cleaned up: a SIGKILLed supervisor's directory cannot be written again, and
//! it lives on as long as any process holds it (a tool that opened it, say). The next
//! supervisor then publishes in the next slot; readers take the slot whose writer lives. A
//! slot nobody holds any more is removed by iceoryx2, so the next start uses `directory` again.

use iceoryx2::config::Config;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::blackboard::BlackboardOpenError;
use iceoryx2::service::messaging_pattern::MessagingPattern;
use iceoryx2::service::port_factory::blackboard::PortFactory;
use iceoryx2::service::port_factory::PortFactory as _;
use nix::sys::signal::kill;
use nix::unistd::Pid;

use super::{service_name, MAX_NODES};
use crate::TransportError;

/// The first slot's name; the others append `.1` to `.7`.
const SERVICE: &str = "directory";
/// How many slots there are: as many supervisors in a row may die while a process holds what
/// the one before published.
pub(super) const SLOTS: usize = 8;

/// The name of slot `i`.
pub(super) fn slot_name(i: usize) -> Result<ServiceName, TransportError> {
    if i == 0 {
        service_name(SERVICE)
    } else {
        service_name(&format!("{SERVICE}.{i}"))
    }
}

/// Whether a directory exists in the domain with `config` (a supervisor publishes it, or did).
pub(super) fn any_exists(config: &Config) -> bool {
    (0..SLOTS).any(|i| {
        slot_name(i).is_ok_and(|name| {
            ipc::Service::does_exist(&name, config, MessagingPattern::Blackboard).unwrap_or(false)
        })
    })
}

/// How long a slot another process is creating (or removing) this moment is waited for.
const UNSETTLED_WAIT: std::time::Duration = std::time::Duration::from_millis(500);

/// Opens slot `i` through `node`; `Ok(None)` if it does not exist.
pub(super) fn open_slot(
    node: &Node<ipc::Service>,
    i: usize,
) -> Result<Option<PortFactory<ipc::Service, u8>>, TransportError> {
    let name = slot_name(i)?;
    open_slot_once(node, &name).map_err(|e| TransportError::ipc("open the directory", e))
}

/// [`open_slot`] for a supervisor creating the directory: a slot another process is creating
/// this moment (two `modbot up` of one domain at once: its resources are not all there yet) or
/// removing is waited for, up to half a second. Readers do not wait: they look again later.
pub(super) fn open_slot_settled(
    node: &Node<ipc::Service>,
    i: usize,
) -> Result<Option<PortFactory<ipc::Service, u8>>, TransportError> {
    let name = slot_name(i)?;
    let started = std::time::Instant::now();
    loop {
        match open_slot_once(node, &name) {
            Err(
                BlackboardOpenError::ServiceInCorruptedState
                | BlackboardOpenError::IsMarkedForDestruction,
            ) if started.elapsed() < UNSETTLED_WAIT => {
                std::thread::sleep(std::time::Duration::from_millis(2));
            }
            other => return other.map_err(|e| TransportError::ipc("open the directory", e)),
        }
    }
}

fn open_slot_once(
    node: &Node<ipc::Service>,
    name: &ServiceName,
) -> Result<Option<PortFactory<ipc::Service, u8>>, BlackboardOpenError> {
    match node
        .service_builder(name)
        .blackboard_opener::<u8>()
        .max_readers(MAX_NODES)
        .max_nodes(MAX_NODES)
        .open()
    {
        Ok(s) => Ok(Some(s)),
        Err(BlackboardOpenError::DoesNotExist) => Ok(None),
        Err(e) => Err(e),
    }
}

/// The pid of a live process among `service`'s writers.
pub(super) fn live_writer(service: &PortFactory<ipc::Service, u8>) -> Option<i32> {
    let mut alive = None;
    service.dynamic_config().list_writers(|w| {
        if let Ok(pid) = w.node_id.pid::<ipc::Service>() {
            if kill(Pid::from_raw(pid.value()), None).is_ok() {
                alive = Some(pid.value());
                return CallbackProgression::Stop;
            }
        }
        CallbackProgression::Continue
    });
    alive
}

/// The domain's directory as a reader finds it: the slot a live supervisor writes, else the
/// first that exists (its supervisor stopped or died: readers fall back to a scan).
pub(super) fn open_current(
    node: &Node<ipc::Service>,
) -> Result<Option<PortFactory<ipc::Service, u8>>, TransportError> {
    let mut orphaned = None;
    for i in 0..SLOTS {
        let Some(service) = open_slot(node, i)? else {
            continue;
        };
        if live_writer(&service).is_some() {
            return Ok(Some(service));
        }
        orphaned.get_or_insert(service);
    }
    Ok(orphaned)
}

//! Serving a chain on a Linux network interface: every EtherCAT frame that arrives on the
//! interface (a raw link of `modbot_bus::link`) is processed by the chain and sent back, as a
//! real line of slaves would.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use modbot_bus::link::{LinkError, RawLink, ETHERTYPE_ETHERCAT};

use crate::chain::{Chain, Reply};
use crate::frame::{self, LOCALLY_ADMINISTERED_BIT};

/// How long the loop waits for a frame before it looks at the stop flag.
const LOOK_EVERY: Duration = Duration::from_millis(50);

/// Why serving could not start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The interface could not be opened (missing, no CAP_NET_RAW, ...).
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The socket failed while serving.
    #[error("raw socket on interface {interface:?}: {source}")]
    Io {
        /// The interface.
        interface: String,
        /// The system error.
        source: std::io::Error,
    },
}

/// What a serving loop did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServeStats {
    /// Frames received and processed.
    pub frames: u64,
    /// Frames received that were not EtherCAT or were malformed.
    pub refused: u64,
    /// Frames dropped by fault injection.
    pub lost: u64,
}

/// Serves `chain` on `interface` until `stop` is set (looked at every 50 ms at least).
pub fn serve(
    interface: &str,
    chain: &Mutex<Chain>,
    stop: &AtomicBool,
) -> Result<ServeStats, ServeError> {
    serve_ready(interface, chain, stop, || {})
}

/// As [`serve`], calling `ready` once the interface is open, before the first frame.
///
/// Frames whose source MAC has the locally administered bit (replies, ours or another line's)
/// are ignored; the chain is locked for each frame, so faults may be injected meanwhile.
pub fn serve_ready(
    interface: &str,
    chain: &Mutex<Chain>,
    stop: &AtomicBool,
    ready: impl FnOnce(),
) -> Result<ServeStats, ServeError> {
    let link = RawLink::open(interface, ETHERTYPE_ETHERCAT)?;
    tracing::info!(interface, "serving EtherCAT slaves");
    ready();
    let mut stats = ServeStats::default();
    let mut buf = vec![0u8; 2048];
    let io = |source| ServeError::Io {
        interface: interface.to_owned(),
        source,
    };
    while !stop.load(Ordering::Relaxed) {
        let Some(n) = link.recv(&mut buf, LOOK_EVERY).map_err(io)? else {
            continue;
        };
        let frame = &mut buf[..n];
        if frame::source_mac(frame).is_some_and(|mac| mac[0] & LOCALLY_ADMINISTERED_BIT != 0) {
            continue;
        }
        let reply = {
            let mut chain = chain
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner());
            chain.process(frame)
        };
        match reply {
            Ok(Reply::Frame) => {
                stats.frames += 1;
                link.send(frame).map_err(io)?;
            }
            Ok(Reply::Lost) => stats.lost += 1,
            Err(error) => {
                stats.refused += 1;
                tracing::debug!(%error, "frame refused");
            }
        }
    }
    Ok(stats)
}

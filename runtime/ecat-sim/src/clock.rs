//! Time, injected: the chain never reads a clock of its own, so tests decide what time it is.

use std::sync::{
    atomic::{AtomicU64, Ordering},
    Arc,
};
use std::time::Instant;

/// A source of nanoseconds for the slaves' local clocks (the DC registers). Monotonic; the
/// origin is arbitrary.
pub trait Clock: Send {
    /// Nanoseconds now.
    fn now_ns(&self) -> u64;
}

/// A clock moved by hand: clones share the same time, so a test keeps one and gives one to
/// the chain.
#[derive(Debug, Clone, Default)]
pub struct ManualClock {
    ns: Arc<AtomicU64>,
}

impl ManualClock {
    /// A clock at `start_ns`.
    pub fn new(start_ns: u64) -> Self {
        Self {
            ns: Arc::new(AtomicU64::new(start_ns)),
        }
    }

    /// Moves time forward by `delta_ns`.
    pub fn advance(&self, delta_ns: u64) {
        self.ns.fetch_add(delta_ns, Ordering::SeqCst);
    }

    /// Sets the time (never backwards: a smaller value is ignored).
    pub fn set(&self, ns: u64) {
        self.ns.fetch_max(ns, Ordering::SeqCst);
    }
}

impl Clock for ManualClock {
    fn now_ns(&self) -> u64 {
        self.ns.load(Ordering::SeqCst)
    }
}

/// The host's monotonic clock, for serving real masters.
#[derive(Debug, Clone, Copy)]
pub struct MonotonicClock {
    origin: Instant,
}

impl Default for MonotonicClock {
    fn default() -> Self {
        Self {
            origin: Instant::now(),
        }
    }
}

impl Clock for MonotonicClock {
    fn now_ns(&self) -> u64 {
        u64::try_from(self.origin.elapsed().as_nanos()).unwrap_or(u64::MAX)
    }
}

impl<F> Clock for F
where
    F: Fn() -> u64 + Send,
{
    fn now_ns(&self) -> u64 {
        self()
    }
}

//! A module's heartbeats: when the next is due, how many went out, and what each carries. The
//! message manager beats at its housekeeping; a method that waits long (a file to close, a
//! device to answer) beats while it waits with [`Ctx::keep_alive`](crate::Ctx::keep_alive), since
//! the supervisor judges a module silent for its heartbeat timeout hung and kills it.

use modbot_ipc_schema::heartbeat::{Counters, Heartbeat, ModuleState};
use modbot_ipc_schema::Addr;
use zerocopy::IntoBytes;

use crate::transport::Tx;

/// The heartbeat schedule of one module.
#[derive(Debug)]
pub(crate) struct Heartbeats {
    pub(crate) period_ns: u64,
    /// When the next beat is due.
    pub(crate) next_ns: u64,
    /// Beats sent.
    pub(crate) sent: u64,
    /// The digest of the module's method names, in every beat.
    pub(crate) methods_digest: u32,
}

impl Heartbeats {
    /// Beats at once and then every `period_ns`.
    pub(crate) fn new(period_ns: u64, now_ns: u64, methods_digest: u32) -> Heartbeats {
        Heartbeats {
            period_ns,
            next_ns: now_ns,
            sent: 0,
            methods_digest,
        }
    }

    /// Whether a beat is due at `now_ns`; if so, the one after is scheduled.
    pub(crate) fn due(&mut self, now_ns: u64) -> bool {
        if now_ns < self.next_ns {
            return false;
        }
        self.next_ns = now_ns + self.period_ns;
        true
    }

    /// Publishes a heartbeat now.
    pub(crate) fn send(
        &mut self,
        tx: &mut dyn Tx,
        addr: Addr,
        state: ModuleState,
        counters: Counters,
    ) {
        self.sent += 1;
        let hb = Heartbeat::new(addr, std::process::id(), state, self.sent, counters)
            .with_methods_digest(self.methods_digest);
        if let Err(e) = tx.heartbeat(hb.as_bytes()) {
            tracing::debug!("heartbeat not sent: {e}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_beat_is_due_at_once_and_then_once_per_period() {
        let mut sut = Heartbeats::new(100, 1_000, 7);
        assert!(sut.due(1_000));
        assert!(!sut.due(1_099));
        assert!(sut.due(1_100));
        assert!(!sut.due(1_150));
    }
}

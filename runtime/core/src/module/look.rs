//! Looking before sleeping. A module in blocking mode that expects a frame soon — the answer to
//! the call it just sent ([`CallOptions::spin`](crate::CallOptions::spin)), the next call of a
//! caller it just answered ([`ModuleBuilder::linger`](super::ModuleBuilder::linger)) — looks
//! for it a while before it goes to sleep: where idle cores halt (a KVM guest's vCPUs, say),
//! waking a sleeping thread costs tens of µs, far more than the look.
//!
//! Looking is adaptive: after a look that missed, the next [`SKIPS_AFTER_MISS`] occasions of its
//! kind sleep at once. Where the peer shares the looker's core, or the machine is loaded, a look
//! only keeps the peer away from the core it needs, and a missed look says so. A thread under
//! SCHED_FIFO or SCHED_RR never looks: it would keep every lower-priority thread of its core
//! away, the peer included.

use core::time::Duration;

/// Occasions that sleep at once after a look that missed.
pub(crate) const SKIPS_AFTER_MISS: u32 = 16;

/// One kind of look (for answers, or for the next call) and how it has fared.
#[derive(Debug, Default)]
pub(crate) struct Look {
    /// Occasions left that sleep at once.
    skipped: u32,
}

impl Look {
    /// Whether to look `span` long on this occasion (`realtime`: the thread runs under a
    /// real-time policy); an occasion passed over because of a missed look is counted.
    pub(crate) fn begin(&mut self, span: Duration, realtime: bool) -> bool {
        if span.is_zero() || realtime {
            return false;
        }
        if self.skipped > 0 {
            self.skipped -= 1;
            return false;
        }
        true
    }

    /// The look ended without what it looked for.
    pub(crate) fn missed(&mut self) {
        self.skipped = SKIPS_AFTER_MISS;
    }
}

/// Whether the calling thread runs under SCHED_FIFO or SCHED_RR.
pub(crate) fn realtime_thread() -> bool {
    // SAFETY: sched_getscheduler reads the policy of the calling thread (pid 0); it takes no
    // pointers and cannot fail for the calling thread.
    let policy = unsafe { libc::sched_getscheduler(0) };
    policy == libc::SCHED_FIFO || policy == libc::SCHED_RR
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPAN: Duration = Duration::from_micros(50);

    #[test]
    fn a_look_that_missed_makes_the_next_sixteen_occasions_sleep_at_once() {
        let mut look = Look::default();
        assert!(look.begin(SPAN, false));
        look.missed();
        for _ in 0..SKIPS_AFTER_MISS {
            assert!(!look.begin(SPAN, false));
        }
        assert!(look.begin(SPAN, false));
    }

    #[test]
    fn a_look_that_found_its_frame_is_tried_again_at_once() {
        let mut look = Look::default();
        assert!(look.begin(SPAN, false));
        assert!(look.begin(SPAN, false));
    }

    #[test]
    fn a_real_time_thread_or_a_zero_span_never_looks_and_uses_up_no_skipped_occasion() {
        let mut look = Look::default();
        look.missed();
        assert!(!look.begin(SPAN, true));
        assert!(!look.begin(Duration::ZERO, false));
        assert_eq!(look.skipped, SKIPS_AFTER_MISS);
    }
}

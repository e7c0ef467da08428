//! How the coordinator's wake-ups kept to the base tick: expirations, missed ticks, the tick
//! error (the lateness of each wake-up) and the tick rate over the last second.

use modbot_core::stats::Histogram;

/// The coordinator's record of its wake-ups.
#[derive(Debug, Default)]
pub(super) struct TickTiming {
    /// Timer expirations so far (ticks run plus ticks missed).
    expirations: u64,
    missed: u64,
    error: Histogram,
    /// Ticks and time at the last rate measurement, and the rate then.
    rate: (u64, u64, f64),
}

impl TickTiming {
    /// A wake-up at `now` that found `elapsed` expirations, before tick `tick` runs;
    /// `due_ns(k)` says when the k-th expiration was due.
    pub(super) fn woke(&mut self, tick: u64, elapsed: u64, now: u64, due_ns: impl Fn(u64) -> u64) {
        self.expirations += elapsed;
        if tick == 0 {
            self.rate = (0, now, 0.0);
        }
        let due = due_ns(self.expirations.saturating_sub(1));
        self.error.record(now.saturating_sub(due));
        self.missed += elapsed.saturating_sub(1);
        if now.saturating_sub(self.rate.1) >= 1_000_000_000 {
            let ticks = tick - self.rate.0;
            self.rate = (tick, now, ticks as f64 * 1e9 / (now - self.rate.1) as f64);
        }
    }

    /// Ticks missed: expirations a late wake-up found beyond the one it ran.
    pub(super) fn missed(&self) -> u64 {
        self.missed
    }

    /// The lateness of every wake-up.
    pub(super) fn error(&self) -> &Histogram {
        &self.error
    }

    /// Ticks per second over the last whole second measured.
    pub(super) fn rate(&self) -> f64 {
        self.rate.2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_late_wake_up_counts_the_ticks_it_found_beyond_one_as_missed() {
        let mut sut = TickTiming::default();
        let due = |k: u64| 1_000_000 * (k + 1);
        sut.woke(0, 1, 1_000_100, due);
        sut.woke(1, 3, 4_000_300, due);
        assert_eq!(sut.missed(), 2);
        assert_eq!(sut.error().count(), 2);
    }

    #[test]
    fn the_rate_is_measured_over_whole_seconds() {
        let mut sut = TickTiming::default();
        let due = |k: u64| 1_000_000 * (k + 1);
        sut.woke(0, 1, 1_000_000, due);
        for n in 1..=1000 {
            sut.woke(n, 1, 1_000_000 * (n + 1), due);
        }
        assert!((sut.rate() - 1000.0).abs() < 1e-6, "{}", sut.rate());
    }
}

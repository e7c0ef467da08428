//! The nominal time of the grid's ticks, as the bus bridge can know it: the time a bus cycle
//! gives a backend that phase-locks its bus to the grid (EtherCAT's distributed clocks).
//!
//! A real-time coordinator's tick `n` is due at `start + n·period` of CLOCK_MONOTONIC (an
//! absolute timer: no drift), and a release reaches the bus host later, by the wake-ups and
//! the hand-over in between. The release says its tick and the host reads the clock when it
//! takes it; `start` is not sent. So the bridge takes as the ticks' origin the least
//! `now − n·period` it has seen: the nominal time plus the smallest latency of the path, a
//! constant to within that latency's floor, which moves only downwards (by a few µs, early in
//! a run). A grid that restarts its ticks (a new coordinator) is seen as every release being
//! late by more than a period: after [`RESEAT_AFTER`] such releases in a row the origin is
//! taken afresh.

/// Releases in a row more than a period behind the origin after which it is taken afresh.
pub const RESEAT_AFTER: u32 = 1_000;

/// The ticks' origin as the releases show it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TickClock {
    /// The least `now − n·period` seen (the nominal time of tick 0 plus the least latency).
    origin_ns: Option<u64>,
    /// Releases in a row that came more than a period after their nominal time.
    late_in_a_row: u32,
}

impl TickClock {
    /// The nominal time of tick `tick`, released at `now_ns` (CLOCK_MONOTONIC), the ticks
    /// `period_ns` apart. `None` for a tick that cannot be on this clock (after `now_ns`
    /// counted from 0).
    pub fn tick_ns(&mut self, tick: u64, now_ns: u64, period_ns: u64) -> Option<u64> {
        let since_origin = tick.checked_mul(period_ns)?;
        let base = now_ns.checked_sub(since_origin)?;
        let origin = match self.origin_ns {
            Some(origin) if base <= origin => {
                self.late_in_a_row = 0;
                base
            }
            Some(origin) if base - origin <= period_ns => {
                self.late_in_a_row = 0;
                origin
            }
            Some(origin) => {
                self.late_in_a_row += 1;
                if self.late_in_a_row < RESEAT_AFTER {
                    origin
                } else {
                    self.late_in_a_row = 0;
                    base
                }
            }
            None => base,
        };
        self.origin_ns = Some(origin);
        Some(origin + since_origin)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: u64 = 1_000_000;

    #[test]
    fn the_nominal_time_is_the_least_latency_seen_on_the_tick_grid() {
        let mut sut = TickClock::default();
        let start = 5_000_000_000;
        assert_eq!(
            sut.tick_ns(1, start + P + 80_000, P),
            Some(start + P + 80_000)
        );
        // A release with less latency moves the origin down; later ones keep it.
        assert_eq!(
            sut.tick_ns(2, start + 2 * P + 30_000, P),
            Some(start + 2 * P + 30_000)
        );
        assert_eq!(
            sut.tick_ns(3, start + 3 * P + 90_000, P),
            Some(start + 3 * P + 30_000)
        );
        // A late release (more than a period) still gets its tick's nominal time.
        assert_eq!(
            sut.tick_ns(4, start + 6 * P, P),
            Some(start + 4 * P + 30_000)
        );
    }

    #[test]
    fn a_grid_that_restarts_its_ticks_is_followed_after_the_reseat_count() {
        let mut sut = TickClock::default();
        let start = 5_000_000_000;
        sut.tick_ns(10, start + 10 * P + 20_000, P);
        // The ticks start again from 0, 7.5 s later.
        let restart = start + 7_500_000_000;
        for n in 0..RESEAT_AFTER as u64 - 1 {
            let got = sut.tick_ns(n, restart + n * P + 20_000, P).unwrap();
            assert_eq!(got, start + n * P + 20_000);
        }
        let n = RESEAT_AFTER as u64 - 1;
        assert_eq!(
            sut.tick_ns(n, restart + n * P + 20_000, P),
            Some(restart + n * P + 20_000)
        );
        assert_eq!(
            sut.tick_ns(n + 1, restart + (n + 1) * P + 25_000, P),
            Some(restart + (n + 1) * P + 20_000)
        );
    }

    #[test]
    fn a_tick_beyond_the_clock_has_no_time() {
        let mut sut = TickClock::default();
        assert_eq!(sut.tick_ns(10, 5 * P, P), None);
    }
}

//! Distributed clocks, phase-locked to the grid: the grid leads, the slaves' SYNC0 follows.
//!
//! The coordinator's tick releases the bus; tick `n` is due at a fixed time of CLOCK_MONOTONIC
//! (`start + n·period`). Each cycle the master writes that tick's nominal time, in the DC time
//! base, into the reference clock's system time (0x0910, an FPWR beside the cycle's frame):
//! the reference clock's time control loop follows the master's time (IgH's "sync the
//! reference clock to the application time"), and ethercrab's FRMW in the cycle's frame keeps
//! every other slave's clock on the reference. SYNC0 fires at `start time + k·period` of each
//! slave's system time, so it keeps a fixed phase to the grid's ticks.
//!
//! The DC time base: ns since ethercrab's epoch, CLOCK_MONOTONIC minus 946 684 800 ns as its
//! `ethercat_now` gives it (with the latency of its bring-up added: the slaves' system times
//! are set from a frame's receive time and the master's clock read afterwards). The map from
//! the grid's time is `dc = tick + offset`, the offset fixed at the first cycle with a tick
//! time ([`GridLock::observe`]): the slaves' time base at that cycle, moved by less than half
//! a period so that SYNC0 fires [`SYNC0_AFTER_TICK`] of the period after the tick is due
//! (ethercrab starts SYNC0 on a whole number of periods of system time). The reference clock
//! then slews to the map at its loop's bounded speed (an ESC's loop changes its clock's
//! speed, never steps it; up to half a period takes up to ~0.5 s at 1000 ppm).
//!
//! Placement: SYNC0 fires half a period after the tick is due. The frame leaves the master
//! after the tick (wake-up, the grid's hand-over to the bus host, the cycle's own work): half
//! a period is its margin to reach every slave before the outputs are latched at SYNC0, and
//! the inputs latched at SYNC0 are half a period old when the next frame reads them. Locked,
//! the frame reaches the reference clock half a period into the SYNC0 cycle (its system time
//! then reads the tick's time, plus the jitter of the frame's own latency).

use modbot_bus::Sync0Phase;

/// Where SYNC0 fires after the tick is due, as a fraction of the period.
pub const SYNC0_AFTER_TICK: f64 = 0.5;
/// The lock window: the frames' mean distance to their place, as a fraction of the period.
pub const LOCK_WINDOW: f64 = 0.05;
/// Cycles of the map before it can be called locked.
const LOCK_MIN_CYCLES: u64 = 64;
/// The frames' mean distance is averaged over about this many cycles.
const MEAN_OVER: f64 = 16.0;
/// A frame this many periods from its tick's time means another grid time (a restarted
/// coordinator): the map is fixed afresh.
const REMAP_PERIODS: u64 = 4;

/// The phase lock of one segment's SYNC0 to the grid's ticks.
#[derive(Debug, Clone)]
pub struct GridLock {
    period_ns: u64,
    /// Where a locked frame lands in the SYNC0 cycle, ns.
    target_ns: u64,
    /// DC time − grid time (CLOCK_MONOTONIC), fixed at the first cycle with a tick time.
    offset_ns: Option<i64>,
    /// Cycles since the map was fixed.
    cycles: u64,
    /// The frames' mean distance to `target_ns`, ns (signed).
    mean_ns: f64,
    /// What `modbot bus` shows.
    phase: Option<Sync0Phase>,
}

/// `x` into (−period/2, period/2].
fn centred(x: i64, period: i64) -> i64 {
    let r = x.rem_euclid(period);
    if r > period / 2 {
        r - period
    } else {
        r
    }
}

impl GridLock {
    /// A lock for SYNC0 every `period_ns`.
    pub fn new(period_ns: u64) -> GridLock {
        let period_ns = period_ns.max(1);
        let after = (SYNC0_AFTER_TICK * period_ns as f64) as u64 % period_ns;
        GridLock {
            period_ns,
            target_ns: (period_ns - after) % period_ns,
            offset_ns: None,
            cycles: 0,
            mean_ns: 0.0,
            phase: None,
        }
    }

    /// The time to write into the reference clock for the cycle of the tick due at `tick_ns`
    /// (CLOCK_MONOTONIC): the tick's time in the DC time base. `None` until the map is fixed
    /// (the first cycle with a tick time only measures).
    pub fn app_time(&self, tick_ns: u64) -> Option<u64> {
        let offset = self.offset_ns?;
        Some((tick_ns as i64).wrapping_add(offset) as u64)
    }

    /// After a cycle: the reference clock's system time when the frame passed it (`dc_ns`,
    /// ethercrab's `dc_system_time`), and the cycle's tick time (`None`: a cycle without one,
    /// which is measured but not locked).
    pub fn observe(&mut self, tick_ns: Option<u64>, dc_ns: u64) {
        let period = self.period_ns as i64;
        let last = dc_ns % self.period_ns;
        let Some(tick) = tick_ns else {
            self.record(last, None, false);
            return;
        };
        let far = self.app_time(tick).is_none_or(|app| {
            (dc_ns as i64).wrapping_sub(app as i64).unsigned_abs() > REMAP_PERIODS * self.period_ns
        });
        if far {
            // The slaves' time base now, moved by less than half a period onto the placement.
            let raw = (dc_ns as i64).wrapping_sub(tick as i64);
            let shift = centred(self.target_ns as i64 - last as i64, period);
            self.offset_ns = Some(raw.wrapping_add(shift));
            self.cycles = 0;
            self.mean_ns = 0.0;
            self.phase = None;
        }
        let distance = centred(last as i64 - self.target_ns as i64, period) as f64;
        self.mean_ns = if self.cycles == 0 {
            distance
        } else {
            self.mean_ns + (distance - self.mean_ns) / MEAN_OVER
        };
        self.cycles += 1;
        let window = LOCK_WINDOW * self.period_ns as f64;
        let was = self.phase.is_some_and(|p| p.locked);
        // Hysteresis: won within the window, lost beyond twice it.
        let locked = self.cycles >= LOCK_MIN_CYCLES
            && self.mean_ns.abs() <= if was { 2.0 * window } else { window };
        self.record(last, Some(self.target_ns), locked);
    }

    fn record(&mut self, last: u64, target_ns: Option<u64>, locked: bool) {
        let fresh = Sync0Phase {
            last_ns: last,
            least_ns: last,
            most_ns: last,
            target_ns,
            locked,
        };
        self.phase = Some(match self.phase {
            Some(p) if p.locked == locked && p.target_ns.is_some() == target_ns.is_some() => {
                Sync0Phase {
                    least_ns: p.least_ns.min(last),
                    most_ns: p.most_ns.max(last),
                    ..fresh
                }
            }
            _ => fresh,
        });
    }

    /// Where the last frame landed, the least and most since the lock was won or lost, and
    /// the lock.
    pub fn phase(&self) -> Option<Sync0Phase> {
        self.phase
    }

    /// The frames' mean distance to their place in the SYNC0 cycle, ns (signed).
    pub fn mean_distance_ns(&self) -> f64 {
        self.mean_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: u64 = 1_000_000;

    #[test]
    fn the_map_puts_the_tick_half_a_period_before_sync0() {
        let mut sut = GridLock::new(P);
        let tick = 7_000_000_123;
        // The slaves' time base: the frame reached the reference at DC time 3_000_250_000.
        sut.observe(Some(tick), 3_000_250_000);
        let app = sut.app_time(tick).unwrap();
        // SYNC0 fires at whole periods of DC time: the tick maps half a period before one.
        assert_eq!((app + P / 2) % P, 0);
        assert!((app as i64 - 3_000_250_000i64).unsigned_abs() <= P / 2);
        assert_eq!(sut.app_time(tick + P), Some(app + P));
    }

    #[test]
    fn frames_on_their_place_win_the_lock_and_a_far_drift_loses_it() {
        let mut sut = GridLock::new(P);
        let start = 9_000_000_000;
        sut.observe(Some(start), 11_000_100_000);
        for n in 1..LOCK_MIN_CYCLES + 5 {
            let tick = start + n * P;
            let app = sut.app_time(tick).unwrap();
            sut.observe(Some(tick), app + 20_000 - (n % 3) * 20_000);
        }
        let phase = sut.phase().unwrap();
        assert!(phase.locked, "{phase:?}");
        assert_eq!(phase.target_ns, Some(P / 2));
        for n in LOCK_MIN_CYCLES + 5..LOCK_MIN_CYCLES + 100 {
            let tick = start + n * P;
            let app = sut.app_time(tick).unwrap();
            sut.observe(Some(tick), app + 300_000);
        }
        assert!(!sut.phase().unwrap().locked);
    }

    #[test]
    fn a_cycle_without_a_tick_time_is_measured_but_not_locked() {
        let mut sut = GridLock::new(P);
        sut.observe(None, 5_000_123_000);
        let phase = sut.phase().unwrap();
        assert_eq!(
            (phase.last_ns, phase.target_ns, phase.locked),
            (123_000, None, false)
        );
        assert_eq!(sut.app_time(1), None);
    }
}

//! Taking samples: a warm-up that is thrown away, then a fixed count (or until a time cap)
//! recorded into an hdrhistogram of nanoseconds.

use std::time::{Duration, Instant};

use hdrhistogram::Histogram;

use crate::opts::Opts;

/// How many samples one row takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Plan {
    /// Samples taken and thrown away first (caches, page faults, lazy connections).
    pub warm: u64,
    /// Samples recorded.
    pub n: u64,
    /// The row stops early (with fewer samples) when it takes longer than this.
    pub cap: Duration,
}

impl Plan {
    /// The plan for a payload of `bytes`: fewer samples for big payloads, far fewer in quick
    /// mode.
    pub fn for_bytes(opts: &Opts, bytes: usize) -> Plan {
        let n = match bytes {
            0..=4096 => opts.samples(5_000, 50_000),
            4097..=65_536 => opts.samples(1_000, 10_000),
            _ => opts.samples(200, 2_000),
        };
        Plan::new(opts, n)
    }

    /// `n` samples, with a tenth of that (at least 50) for warm-up.
    pub fn new(opts: &Opts, n: u64) -> Plan {
        Plan {
            warm: (n / 10).max(50),
            n,
            cap: if opts.quick {
                Duration::from_secs(3)
            } else {
                Duration::from_secs(60)
            },
        }
    }
}

/// A histogram of nanoseconds from 1 ns to an hour, 3 significant digits.
pub fn histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, 3_600_000_000_000, 3).expect("valid histogram bounds")
}

/// Runs `one` for the warm-up, then records what it returns (nanoseconds) `plan.n` times or
/// until the time cap. Checks for Ctrl-C every so often.
pub fn record(
    plan: &Plan,
    mut one: impl FnMut() -> anyhow::Result<u64>,
) -> anyhow::Result<Histogram<u64>> {
    let mut h = histogram();
    for i in 0..plan.warm {
        one()?;
        if i % 256 == 0 {
            crate::procs::check_interrupted()?;
        }
    }
    let start = Instant::now();
    for i in 0..plan.n {
        let ns = one()?;
        h.saturating_record(ns.max(1));
        if i % 256 == 0 {
            crate::procs::check_interrupted()?;
            if start.elapsed() > plan.cap {
                break;
            }
        }
    }
    Ok(h)
}

/// CLOCK_MONOTONIC in nanoseconds: one time base for every process of the machine, so a
/// stamp taken in one process can be compared with the clock in another.
pub fn now_ns() -> u64 {
    use modbot_core::clock::{Clock, MonotonicClock};
    MonotonicClock.now_ns()
}

/// Nanoseconds since `t`.
pub fn since(t: Instant) -> u64 {
    u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX)
}

/// A small generator for picking victims and faults (xorshift64): the same seed gives the
/// same picks, so a run can be repeated from the seed it printed.
#[derive(Debug, Clone)]
pub struct Pick(u64);

impl Pick {
    /// The generator for `seed` (any value; 0 included).
    pub fn new(seed: u64) -> Pick {
        // xorshift stays at 0 forever: every other state is fine.
        Pick((seed ^ 0x9e37_79b9_7f4a_7c15).max(1))
    }

    /// The next number.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// A number below `n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            return 0;
        }
        (self.next_u64() % n as u64) as usize
    }
}

/// A seed from the clock, for a run that was given none.
pub fn clock_seed() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(1, |d| d.as_nanos() as u64)
}

/// A payload size for people: `8 B`, `4 KiB`, `1 MiB`.
pub fn size_label(bytes: usize) -> String {
    match bytes {
        b if b >= 1 << 20 && b % (1 << 20) == 0 => format!("{} MiB", b >> 20),
        b if b >= 1 << 10 && b % (1 << 10) == 0 => format!("{} KiB", b >> 10),
        b => format!("{b} B"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(quick: bool) -> Opts {
        Opts {
            quick,
            pin: false,
            fifo: false,
            out: "/tmp".into(),
            exe: "/bin/true".into(),
            soak: Default::default(),
        }
    }

    #[test]
    fn quick_plans_are_smaller_and_shrink_with_the_payload() {
        let q = Plan::for_bytes(&opts(true), 8);
        let f = Plan::for_bytes(&opts(false), 8);
        assert!(q.n < f.n);
        assert!(Plan::for_bytes(&opts(true), 1 << 20).n < q.n);
        assert!(q.warm >= 50);
    }

    #[test]
    fn record_keeps_only_the_samples_after_the_warm_up() {
        let plan = Plan {
            warm: 3,
            n: 10,
            cap: Duration::from_secs(10),
        };
        let mut calls = 0;
        let h = record(&plan, || {
            calls += 1;
            Ok(if calls <= 3 { 1_000_000 } else { 100 })
        })
        .unwrap();
        assert_eq!(h.len(), 10);
        assert!(h.max() < 1000);
    }

    #[test]
    fn the_same_seed_gives_the_same_picks_and_zero_is_a_seed_too() {
        let picks = |seed| {
            let mut sut = Pick::new(seed);
            (0..20).map(|_| sut.below(7)).collect::<Vec<_>>()
        };
        assert_eq!(picks(42), picks(42));
        assert_ne!(picks(42), picks(43));
        assert!(picks(0).iter().any(|&p| p != picks(0)[0]));
        assert!(picks(0).iter().all(|&p| p < 7));
        assert_eq!(Pick::new(1).below(0), 0);
    }

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(size_label(8), "8 B");
        assert_eq!(size_label(4096), "4 KiB");
        assert_eq!(size_label(1 << 20), "1 MiB");
        assert_eq!(size_label(1000), "1000 B");
    }
}

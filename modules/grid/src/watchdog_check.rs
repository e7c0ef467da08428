//! Whether this machine gives the grid what the bus bridge's watchdog assumes: a tick at
//! least every `watchdog` base periods. At the start of a real-time grid the bus bridge
//! looks, and says so in the log (`modbot up` shows it) when the machine cannot: the grid's
//! threads do not run under SCHED_FIFO, or a sleep of one base period overshoots by as much as
//! the watchdog's budget. Then the robot would stop itself on a healthy system.

use std::time::{Duration, Instant};

/// How many sleeps of one base period are measured.
pub const SAMPLES: usize = 300;

/// The watchdog's budget: it judges the coordinator lost after `periods` base periods of
/// `period_ns` without a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Budget {
    pub periods: u64,
    pub period_ns: u64,
}

/// What was seen of the machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Seen {
    /// The grid's real-time thread runs under SCHED_FIFO.
    pub fifo: bool,
    /// How late a sleep of one base period woke up: the 99th percentile and the most, ns.
    pub late_p99_ns: u64,
    pub late_max_ns: u64,
}

/// Sleeps one base period `samples` times on this thread; how late it woke (p99, most), ns.
pub fn measure(period: Duration, samples: usize) -> (u64, u64) {
    let mut late: Vec<u64> = (0..samples.max(1))
        .map(|_| {
            let start = Instant::now();
            std::thread::sleep(period);
            start.elapsed().saturating_sub(period).as_nanos() as u64
        })
        .collect();
    late.sort_unstable();
    let p99 = late[(late.len() * 99 / 100).min(late.len() - 1)];
    (p99, late[late.len() - 1])
}

/// The warning to give, if the machine cannot give the grid what `budget` assumes.
pub fn verdict(budget: Budget, seen: Seen) -> Option<String> {
    let allowance = budget.periods.saturating_sub(1) * budget.period_ns;
    let ms = |ns: u64| ns as f64 / 1e6;
    let why = if !seen.fifo {
        format!(
            "the grid's threads do not run under SCHED_FIFO (no `grid {{ priority = N }}`, or \
             not root / no CAP_SYS_NICE), so any busy process can hold a tick back; a sleep of \
             one base period here woke up to {:.2} ms late",
            ms(seen.late_max_ns)
        )
    } else if seen.late_max_ns >= allowance {
        format!(
            "a sleep of one base period woke up to {:.2} ms late here (p99 {:.2} ms), beyond \
             the {:.2} ms the watchdog leaves",
            ms(seen.late_max_ns),
            ms(seen.late_p99_ns),
            ms(allowance)
        )
    } else {
        return None;
    };
    Some(format!(
        "the bus watchdog stops the drives after {} base periods ({:.1} ms) without a tick, \
         and {why}: the robot may stop itself on a healthy system. Give the watchdog more \
         periods (bus param `watchdog`; the examples take `--var watchdog=N`) or the grid \
         SCHED_FIFO; see docs/runtime.md, \"The bus watchdog\"",
        budget.periods,
        ms(budget.periods * budget.period_ns)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    const BUDGET: Budget = Budget {
        periods: 3,
        period_ns: 1_000_000,
    };

    #[test]
    fn a_machine_with_sched_fifo_and_little_slack_gets_no_warning() {
        let seen = Seen {
            fifo: true,
            late_p99_ns: 80_000,
            late_max_ns: 400_000,
        };
        assert_eq!(verdict(BUDGET, seen), None);
    }

    #[test]
    fn no_sched_fifo_or_slack_beyond_the_budget_is_said_with_what_to_do() {
        let without = verdict(
            BUDGET,
            Seen {
                fifo: false,
                late_p99_ns: 80_000,
                late_max_ns: 400_000,
            },
        )
        .unwrap();
        assert!(without.contains("do not run under SCHED_FIFO"), "{without}");
        assert!(without.contains("--var watchdog=N"), "{without}");
        let slack = verdict(
            BUDGET,
            Seen {
                fifo: true,
                late_p99_ns: 300_000,
                late_max_ns: 2_500_000,
            },
        )
        .unwrap();
        assert!(
            slack.contains("woke up to 2.50 ms late here (p99 0.30 ms), beyond the 2.00 ms"),
            "{slack}"
        );
    }

    #[test]
    fn a_measured_sleep_is_never_early() {
        let (p99, max) = measure(Duration::from_micros(200), 20);
        assert!(p99 <= max);
    }
}

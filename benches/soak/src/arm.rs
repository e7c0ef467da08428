//! The arm during the soak: the bus ledger's first line once a second (`bus sim  axes 6  cycles
//! N  missed M  running` or `... SAFE STOP at cycle C: why; ...`), and the safe stops read
//! from it.
//!
//! The bus bridge stops every drive when no tick came for 3 base periods or when the assembly
//! faulted, and holds them until an operator's reset (no assembly switch ends a stop) or until
//! its own process is restarted (a new bus bridge starts with fresh drives, which the running
//! assembly enables). Here the safe stops are counted as the ledger shows them, and the
//! samples the arm spent in one; [`crate::robot`] resets the robot after each.

use std::time::Duration;

use modbot_bench_kit::supervised::Supervised;
use modbot_supervisor::status;

/// The bus bridge's module.
const BUS: &str = "host_bus";

/// What the bus bridge said at one sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Seen {
    /// When, since the soak started.
    pub at: Duration,
    /// The bridge's process.
    pub pid: u32,
    /// The ledger's first line.
    pub line: String,
}

/// Reads the bus ledger, unless the bridge is not running or `stopped` (a stopped process
/// would hold the call up until its time-out).
pub fn read(
    at: Duration,
    sys: &mut Supervised,
    rows: &[status::Row],
    stopped: impl Fn(u32) -> bool,
) -> Option<Seen> {
    let pid = rows
        .iter()
        .find(|r| r.name == BUS && r.state == "running" && r.pid != 0)?
        .pid;
    if stopped(pid) {
        return None;
    }
    let ledger = modbot_bench_kit::arm_system::bus_ledger(sys.tool().ok()?)?;
    Some(Seen {
        at,
        pid,
        line: ledger.lines().next().unwrap_or_default().trim().to_owned(),
    })
}

/// The safe stops among the samples.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Summary {
    /// Samples with an answer from the bus bridge.
    pub answered: usize,
    /// Of those, in a safe stop.
    pub stopped: usize,
    /// Distinct safe stops (a bridge process and the cycle it stopped at), by why: (why, how
    /// many), in the order first seen.
    pub by_reason: Vec<(String, usize)>,
}

impl Summary {
    pub fn safe_stops(&self) -> usize {
        self.by_reason.iter().map(|(_, n)| n).sum()
    }
}

/// Counts the safe stops in `seen`.
pub fn summarize<'a>(seen: impl IntoIterator<Item = &'a Seen>) -> Summary {
    let mut sut = Summary::default();
    let mut known: Vec<(u32, String)> = Vec::new();
    for s in seen {
        sut.answered += 1;
        let Some((cycle, why)) = safe_stop(&s.line) else {
            continue;
        };
        sut.stopped += 1;
        if known.iter().any(|(p, c)| *p == s.pid && c == cycle) {
            continue;
        }
        known.push((s.pid, cycle.to_owned()));
        match sut.by_reason.iter_mut().find(|(w, _)| w == why) {
            Some((_, n)) => *n += 1,
            None => sut.by_reason.push((why.to_owned(), 1)),
        }
    }
    sut
}

/// "... SAFE STOP at cycle 1006: coordinator lost: no tick for 3 base periods; ..." →
/// ("1006", "coordinator lost").
fn safe_stop(line: &str) -> Option<(&str, &str)> {
    let rest = line.split_once("SAFE STOP at cycle ")?.1;
    let (cycle, why) = rest.split_once(": ")?;
    let why = why.split([':', ';']).next().unwrap_or(why).trim();
    Some((cycle, why))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seen(pid: u32, line: &str) -> Seen {
        Seen {
            at: Duration::ZERO,
            pid,
            line: line.to_owned(),
        }
    }

    #[test]
    fn a_safe_stop_counts_once_per_bridge_process_and_cycle() {
        let lost = "bus sim  axes 6  cycles 2759  missed 26  SAFE STOP at cycle 1006: coordinator \
                    lost: no tick for 3 base periods; every drive stopped at cycle 1007, 3.05 base \
                    periods after the last tick";
        let faulted =
            "bus sim  axes 6  cycles 900  missed 0  SAFE STOP at cycle 812: the assembly \
                       faulted";
        let running = "bus sim  axes 6  cycles 100  missed 0  running";
        let samples = [
            seen(1, running),
            seen(1, lost),
            seen(1, lost),
            seen(2, running),
            seen(2, faulted),
            seen(3, lost),
        ];
        let sut = summarize(&samples);
        assert_eq!(sut.answered, 6);
        assert_eq!(sut.stopped, 4);
        assert_eq!(
            sut.by_reason,
            [
                ("coordinator lost".to_owned(), 2),
                ("the assembly faulted".to_owned(), 1)
            ]
        );
        assert_eq!(sut.safe_stops(), 3);
    }
}

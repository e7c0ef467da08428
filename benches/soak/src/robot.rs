//! The robot during the soak: its state once a second (the bus bridge's method `robot`), an
//! operator's reset after every safe stop or fault, and the stops seen with how each ended.
//!
//! A safe stop or a fault is ended by an operator's reset only (docs/robot-state.md), so the
//! soak is the operator: once a second, when the robot is in `safe_stop` or `fault` and its bus
//! bridge is not stopped by a fault, it asks for a reset ([`RESET_TIMEOUT`]: the loop keeps
//! roughly its second). A refused reset (the grid not ticking while a host is stalled, say) is
//! counted by its reason and asked again the next second; one refused because the running
//! assembly is the one that faulted is followed by a switch to `hold`, as the refusal says.
//! After a reset that succeeded the state is read again: `operational since` the tick the
//! robot followed again, so a stop's recovery is (that tick − the stop's since tick) × the
//! base period, in grid time.
//!
//! The bus bridge itself may be SIGKILLed and restarted by the supervisor: the fresh bridge
//! keeps the coordinator's ticks, starts disabled and becomes operational once the running
//! assembly enables its drives. A stop of the dead bridge is then ended by the restart, not by
//! a reset, and the robot was not operational just before the fresh bridge's first
//! `operational since`: [`Watch::spans`] gives both kinds of interval to the motions' check.

use std::collections::BTreeMap;
use std::time::Duration;

use hdrhistogram::Histogram;
use modbot_bench_kit::supervised::Supervised;
use modbot_bus::ask as robot_state;
use modbot_bus::RobotState;
use modbot_supervisor::status;

/// The bus bridge's module.
const BUS: &str = "host_bus";
/// How long the state may take to come.
const STATE_TIMEOUT: Duration = Duration::from_millis(500);
/// How long after a reset's answer the state may still say `disabled`: the bridge publishes
/// what the `robot` method answers every 20 ms (at once only when a stop begins or ends), the
/// reset's answer at once.
const SETTLE: Duration = Duration::from_millis(300);
/// How long a reset may take from the ask to its answer (the bridge refuses one the grid does
/// not take within 1 s).
const RESET_TIMEOUT: Duration = Duration::from_millis(1500);
/// How long the switch to `hold` after a faulted assembly may take.
const SWITCH_TIMEOUT: Duration = Duration::from_secs(5);
/// The assembly a reset refused for a faulted assembly switches to.
const HOLD: &str = "hold";
/// The arm's base period.
pub const BASE_PERIOD_NS: u64 = 1_000_000;

/// How a stop ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ended {
    /// The soak's reset (its answer seen, or the state operational again afterwards).
    Reset,
    /// The bus bridge that held it died and a fresh one became operational.
    Restart,
}

/// One safe stop or fault the soak saw.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stop {
    /// The bus bridge process that held it.
    pub pid: u32,
    /// The tick it began, as the robot state says.
    pub since_tick: u64,
    /// A drive's fault rather than a safe stop.
    pub fault: bool,
    /// Why, in the bridge's words.
    pub cause: String,
    /// The tick the robot was operational again, and how; `None`: still held at the end.
    pub end: Option<(u64, Ended)>,
    /// The reset's own ticks, from its beginning to every drive enabled (its answer).
    pub reset_ticks: Option<u64>,
}

impl Stop {
    /// Grid time from the stop to operational again.
    pub fn recovery_ns(&self) -> Option<u64> {
        let (tick, _) = self.end?;
        Some(tick.saturating_sub(self.since_tick) * BASE_PERIOD_NS)
    }
}

/// A bus bridge that took over from a dead one.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Restart {
    pub pid: u32,
    /// Its first `operational since` tick, once seen.
    pub operational: Option<u64>,
}

/// Ticks in which the robot was not operational: `[from, to)`; `to` is `None` while it still
/// was not at the end.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Span {
    pub from: u64,
    pub to: Option<u64>,
    /// What it was, for the note.
    pub what: String,
}

/// What the soak saw of the robot and did about it.
#[derive(Debug, Default)]
pub struct Watch {
    /// Every stop, in the order seen.
    pub stops: Vec<Stop>,
    /// Fresh bus bridges (not the first).
    pub restarts: Vec<Restart>,
    /// Samples the bridge answered with its state.
    pub answered: u64,
    /// Samples without a state (the call failed), by reason.
    pub unanswered: BTreeMap<String, u64>,
    /// Resets asked.
    pub resets: u64,
    /// Resets refused or not answered, by reason (numbers as N).
    pub refused: BTreeMap<String, u64>,
    /// Resets that succeeded after which the robot was still not operational: its state.
    pub not_back: Vec<String>,
    /// Resets after whose answer the state still said `disabled` at first (it is published
    /// every 20 ms).
    pub lagged: u64,
    /// Switches to `hold` after a reset refused for a faulted assembly: done, and why failed.
    pub switches: (u64, Vec<String>),
    /// The bridge process of the last answer.
    pid: Option<u32>,
}

impl Watch {
    /// Reads the robot's state; resets it when it is held. `stopped`: whether a process is
    /// stopped by a fault now (a stopped bridge would hold every call up to its time-out).
    pub fn second(
        &mut self,
        sys: &mut Supervised,
        rows: &[status::Row],
        stopped: impl Fn(u32) -> bool,
    ) -> anyhow::Result<()> {
        let Some(pid) = rows
            .iter()
            .find(|r| r.name == BUS && r.state == "running" && r.pid != 0)
            .map(|r| r.pid)
        else {
            return Ok(());
        };
        if stopped(pid) {
            return Ok(());
        }
        let Some(state) = self.read(sys, pid)? else {
            return Ok(());
        };
        if matches!(
            state,
            RobotState::SafeStop { .. } | RobotState::Fault { .. }
        ) {
            self.reset(sys, pid)?;
        }
        Ok(())
    }

    /// The state, observed; `None` when the bridge did not answer.
    fn read(&mut self, sys: &mut Supervised, pid: u32) -> anyhow::Result<Option<RobotState>> {
        match robot_state::robot_state(sys.tool()?, STATE_TIMEOUT) {
            Ok(Some(state)) => {
                self.answered += 1;
                self.observe(pid, &state);
                Ok(Some(state))
            }
            Ok(None) => {
                *self.unanswered.entry("no bus bridge".into()).or_default() += 1;
                Ok(None)
            }
            Err(why) => {
                *self.unanswered.entry(reason(&why.to_string())).or_default() += 1;
                Ok(None)
            }
        }
    }

    /// Asks for a reset; on success reads the state again for the tick it was operational.
    fn reset(&mut self, sys: &mut Supervised, pid: u32) -> anyhow::Result<()> {
        self.resets += 1;
        match robot_state::reset(sys.tool()?, RESET_TIMEOUT) {
            Ok(answer) => {
                let ticks = reset_ticks(&answer);
                let (after, lagged) = operational_after_reset(sys)?;
                self.lagged += u64::from(lagged);
                match after {
                    Ok(since_tick) => self.close(pid, since_tick, ticks.map(|t| t.1)),
                    Err(seen) => {
                        // The answer's tick, every drive enabled, is when it followed again.
                        if let Some((enabled, t)) = ticks {
                            self.close(pid, enabled, Some(t));
                        }
                        self.not_back.push(format!("{answer} → {seen}"));
                        if let Some(state) = seen.state {
                            self.observe(pid, &state);
                        }
                    }
                }
            }
            Err(why) => {
                let why = why.to_string();
                *self.refused.entry(reason(&why)).or_default() += 1;
                if why.starts_with("the running assembly faulted") {
                    match modbot_grid::switch::switch(sys.tool()?, HOLD, SWITCH_TIMEOUT) {
                        Ok(_) => self.switches.0 += 1,
                        Err(e) => self.switches.1.push(e.to_string()),
                    }
                }
            }
        }
        Ok(())
    }

    /// Takes in the state bridge `pid` answered: a new stop, or the end of the open ones.
    pub fn observe(&mut self, pid: u32, state: &RobotState) {
        if self.pid != Some(pid) {
            if self.pid.is_some() && !self.restarts.iter().any(|r| r.pid == pid) {
                self.restarts.push(Restart {
                    pid,
                    operational: None,
                });
            }
            self.pid = Some(pid);
        }
        match state {
            RobotState::SafeStop { since_tick, cause }
            | RobotState::Fault {
                since_tick, cause, ..
            } => {
                let known = self
                    .stops
                    .iter()
                    .any(|s| s.since_tick == *since_tick && s.cause == *cause);
                if !known {
                    self.stops.push(Stop {
                        pid,
                        since_tick: *since_tick,
                        fault: matches!(state, RobotState::Fault { .. }),
                        cause: cause.clone(),
                        end: None,
                        reset_ticks: None,
                    });
                }
            }
            RobotState::Operational { since_tick } => {
                if let Some(r) = self
                    .restarts
                    .iter_mut()
                    .find(|r| r.pid == pid && r.operational.is_none())
                {
                    r.operational = Some(*since_tick);
                }
                self.close(pid, *since_tick, None);
            }
            RobotState::Disabled { .. } => {}
        }
    }

    /// Ends the open stops that began by `tick`, at which bridge `pid` was operational: by a
    /// reset when that bridge held them, by a restart when a bridge before it did.
    fn close(&mut self, pid: u32, tick: u64, reset_ticks: Option<u64>) {
        for s in self
            .stops
            .iter_mut()
            .filter(|s| s.end.is_none() && s.since_tick <= tick)
        {
            if s.pid == pid {
                s.end = Some((tick, Ended::Reset));
                s.reset_ticks = reset_ticks;
            } else {
                s.end = Some((tick, Ended::Restart));
            }
        }
    }

    /// The stops a reset ended.
    pub fn recovered(&self) -> impl Iterator<Item = &Stop> {
        self.stops
            .iter()
            .filter(|s| matches!(s.end, Some((_, Ended::Reset))))
    }

    /// The stops a restart of the bridge ended, and those still held at the end.
    pub fn by_restart_and_open(&self) -> (usize, usize) {
        let restart = self
            .stops
            .iter()
            .filter(|s| matches!(s.end, Some((_, Ended::Restart))))
            .count();
        (
            restart,
            self.stops.iter().filter(|s| s.end.is_none()).count(),
        )
    }

    /// Grid time from each stop a reset ended to operational again, and the resets' own
    /// share of it (from their beginning to every drive enabled), in ns.
    pub fn histograms(&self) -> (Histogram<u64>, Histogram<u64>) {
        let (mut recovery, mut reset) = (
            modbot_bench_kit::sample::histogram(),
            modbot_bench_kit::sample::histogram(),
        );
        for s in self.recovered() {
            if let Some(ns) = s.recovery_ns() {
                recovery.saturating_record(ns.max(1));
            }
            if let Some(t) = s.reset_ticks {
                reset.saturating_record((t * BASE_PERIOD_NS).max(1));
            }
        }
        (recovery, reset)
    }

    /// The ticks in which the robot was not operational, as far as the soak knows: every stop
    /// until operational again (open at the end: `to` is `None`), and the tick before a fresh
    /// bridge's first `operational since` (the dead bridge's time before it is not known).
    pub fn spans(&self) -> Vec<Span> {
        let stops = self.stops.iter().map(|s| Span {
            from: s.since_tick,
            to: s.end.map(|(t, _)| t),
            what: format!(
                "{} since tick {} ({})",
                if s.fault { "fault" } else { "safe stop" },
                s.since_tick,
                s.cause
            ),
        });
        let restarts = self.restarts.iter().filter_map(|r| {
            let op = r.operational?;
            Some(Span {
                from: op.saturating_sub(1),
                to: Some(op),
                what: format!(
                    "the bus bridge restarted (pid {}, operational since tick {op})",
                    r.pid
                ),
            })
        });
        stops.chain(restarts).collect()
    }

    /// The stops by cause (the bridge's words up to their first colon): (cause, how many), in
    /// the order first seen.
    pub fn causes(&self) -> Vec<(String, usize)> {
        let mut out: Vec<(String, usize)> = Vec::new();
        for s in &self.stops {
            let cause = s.cause.split(": ").next().unwrap_or(&s.cause).to_owned();
            match out.iter_mut().find(|(c, _)| *c == cause) {
                Some((_, n)) => *n += 1,
                None => out.push((cause, 1)),
            }
        }
        out
    }
}

/// The tick since which the robot is operational after a reset answered ok, waiting up to
/// [`SETTLE`] while it still says `disabled` (else what it said), and whether it said so at
/// first.
fn operational_after_reset(sys: &mut Supervised) -> anyhow::Result<(Result<u64, Seen>, bool)> {
    let until = std::time::Instant::now() + SETTLE;
    let mut lagged = false;
    loop {
        let seen = match robot_state::robot_state(sys.tool()?, STATE_TIMEOUT) {
            Ok(Some(RobotState::Operational { since_tick })) => {
                return Ok((Ok(since_tick), lagged))
            }
            Ok(Some(RobotState::Disabled { .. })) if std::time::Instant::now() < until => {
                lagged = true;
                std::thread::sleep(Duration::from_millis(5));
                continue;
            }
            Ok(state) => Seen {
                text: state
                    .as_ref()
                    .map_or("no bus bridge".into(), ToString::to_string),
                state,
            },
            Err(why) => Seen {
                text: why.to_string(),
                state: None,
            },
        };
        return Ok((Err(seen), lagged));
    }
}

/// What the robot state said after a reset instead of `operational`.
struct Seen {
    text: String,
    state: Option<RobotState>,
}

impl std::fmt::Display for Seen {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.text)
    }
}

/// "every drive enabled at tick 5398 (7 cycles after the reset began at tick 5392), ..." →
/// (5398, 6): the tick every drive was enabled, and the ticks from the reset's beginning to it.
pub fn reset_ticks(answer: &str) -> Option<(u64, u64)> {
    let number = |text: &str| -> Option<u64> {
        let digits: String = text.chars().take_while(char::is_ascii_digit).collect();
        digits.parse().ok()
    };
    let enabled = number(answer.split_once("every drive enabled at tick ")?.1)?;
    let began = number(answer.split_once("the reset began at tick ")?.1)?;
    Some((enabled, enabled.checked_sub(began)?))
}

/// A reason to count by: the text up to its first colon, each number as N ("the grid is not
/// ticking", "the grid has not ticked for N ms since the reset was asked (last tick N)").
pub fn reason(why: &str) -> String {
    let head = why.split(": ").next().unwrap_or(why);
    let mut out = String::with_capacity(head.len());
    let mut in_number = false;
    for c in head.chars() {
        if c.is_ascii_digit() {
            if !in_number {
                out.push('N');
            }
            in_number = true;
        } else {
            in_number = false;
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stop(since: u64) -> RobotState {
        RobotState::SafeStop {
            since_tick: since,
            cause: "coordinator lost: no tick for 505 base periods".into(),
        }
    }

    fn operational(since: u64) -> RobotState {
        RobotState::Operational { since_tick: since }
    }

    #[test]
    fn a_stop_counts_once_and_ends_at_the_tick_it_was_operational_again() {
        let mut sut = Watch::default();
        sut.observe(7, &operational(100));
        sut.observe(7, &stop(4012));
        sut.observe(7, &stop(4012));
        sut.close(7, 4512, Some(6));
        sut.observe(7, &operational(4512));
        assert_eq!(sut.stops.len(), 1);
        assert_eq!(sut.stops[0].end, Some((4512, Ended::Reset)));
        assert_eq!(sut.stops[0].recovery_ns(), Some(500 * BASE_PERIOD_NS));
        assert_eq!(sut.stops[0].reset_ticks, Some(6));
        assert!(sut.restarts.is_empty());
        assert_eq!(sut.causes(), [("coordinator lost".to_owned(), 1)]);
    }

    #[test]
    fn a_stop_of_a_dead_bridge_is_ended_by_the_restart_not_by_a_reset() {
        let mut sut = Watch::default();
        sut.observe(7, &operational(100));
        sut.observe(7, &stop(2000));
        sut.observe(8, &RobotState::Disabled { since_tick: 0 });
        sut.observe(8, &operational(3100));
        assert_eq!(sut.stops[0].end, Some((3100, Ended::Restart)));
        assert_eq!(sut.recovered().count(), 0);
        assert_eq!(sut.by_restart_and_open(), (1, 0));
        assert_eq!(
            sut.restarts,
            [Restart {
                pid: 8,
                operational: Some(3100)
            }]
        );
        let spans = sut.spans();
        assert_eq!((spans[0].from, spans[0].to), (2000, Some(3100)));
        assert_eq!((spans[1].from, spans[1].to), (3099, Some(3100)));
    }

    #[test]
    fn a_stop_still_held_at_the_end_is_an_open_span() {
        let mut sut = Watch::default();
        sut.observe(7, &stop(50));
        let spans = sut.spans();
        assert_eq!((spans[0].from, spans[0].to), (50, None));
        assert_eq!(sut.by_restart_and_open(), (0, 1));
        assert_eq!(sut.histograms().0.len(), 0);
    }

    #[test]
    fn the_recovery_percentiles_are_grid_time_from_stop_to_operational() {
        let mut sut = Watch::default();
        for (i, took) in [300_u64, 500, 700, 900, 2100].into_iter().enumerate() {
            let since = 10_000 * (i as u64 + 1);
            sut.observe(7, &stop(since));
            sut.close(7, since + took, Some(7));
        }
        let (recovery, reset) = sut.histograms();
        assert_eq!(recovery.len(), 5);
        let ms = |q: f64| recovery.value_at_quantile(q) as f64 / 1e6;
        assert!((ms(0.5) - 700.0).abs() < 1.0, "{}", ms(0.5));
        assert!((ms(0.99) - 2100.0).abs() < 2.0, "{}", ms(0.99));
        // Three significant digits, as every histogram of the benchmarks.
        assert!(reset.equivalent(reset.value_at_quantile(0.5), 7 * BASE_PERIOD_NS));
    }

    #[test]
    fn the_resets_answer_gives_its_own_ticks() {
        let answer = "every drive enabled at tick 5398 (7 cycles after the reset began at tick \
                      5392), holding where it was found";
        assert_eq!(reset_ticks(answer), Some((5398, 6)));
        assert_eq!(
            reset_ticks("nothing to reset: the robot is operational"),
            None
        );
    }

    #[test]
    fn refusals_are_counted_by_their_words_without_numbers() {
        assert_eq!(
            reason("the grid is not ticking: no tick for 505 base periods (the coordinator is stopped or lost); reset once it runs again"),
            "the grid is not ticking"
        );
        assert_eq!(
            reason("the grid has not ticked for 1003 ms since the reset was asked (last tick 4410): the coordinator is stopped or lost"),
            "the grid has not ticked for N ms since the reset was asked (last tick N)"
        );
    }
}

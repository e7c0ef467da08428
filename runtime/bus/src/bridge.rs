//! The bus bridge: the backend's drives, served every base tick by the grid, with a watchdog of
//! its own.
//!
//! Each release of the grid's `bus` component is one bus cycle: the commands of the tick go to
//! the drives and their actuals come back. The bridge process checks between releases: when
//! no release came for [`LOST_AFTER`] base periods the coordinator is lost, and the bridge
//! brings every drive in operation enabled to a safe stop (quick stop; a silence before any
//! drive was enabled stops nothing) and keeps cycling the bus on its own clock,
//! so the drives decelerate and report it. The drives stay latched in quick stop until they are
//! sent disable voltage (CiA 402 transition 12) and enabled again; the ledger records when
//! the stop happened.

use std::sync::Mutex;

use super::backend::{AxisActual, AxisCommand, Backend, BlockError, BusFault};
use super::cia402::DriveState;

/// Base periods without a release after which the coordinator counts as lost.
pub const LOST_AFTER: u64 = 3;

/// In lockstep (a simulation that waits for its slowest process, and for an assembly being
/// prepared) the coordinator counts as lost only after this long without a release.
pub const LOCKSTEP_LOST_AFTER_NS: u64 = 30_000_000_000;

/// Why the drives were stopped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SafeStop {
    pub reason: String,
    /// The bus cycle at which quick stop was commanded.
    pub at_cycle: u64,
    /// When every drive first reported quick stop active (or a state without torque): the
    /// cycle, and the time since the last tick the grid served, in ns.
    pub all_stopped: Option<(u64, u64)>,
    /// The bus itself failed (a slave lost, the segment silent): an assembly switch does not
    /// end this stop.
    pub latched: bool,
}

pub use modbot_ipc_schema::bus::{Switch, Switches, SwitchesError};

/// How many ticks around a switch count as its neighbourhood for missed cycles.
pub const NEAR_SWITCH: u64 = 5;

/// Switches the bridge remembers.
const SWITCHES_KEPT: usize = 1024;

/// How often the bridge's methods' view is refreshed, ns.
pub const PUBLISH_EVERY_NS: u64 = 20_000_000;

/// The drives and their bookkeeping.
pub struct Bridge {
    backend: Box<dyn Backend>,
    commands: Vec<AxisCommand>,
    actuals: Vec<AxisActual>,
    period_ns: u64,
    /// Bus cycles run (by the grid or by the watchdog).
    pub cycles: u64,
    /// Base periods in which the grid did not serve the bus.
    pub missed: u64,
    /// Cycles whose frames did not come back, and bus faults of the backend (a slave lost).
    pub lost_frames: u64,
    pub bus_faults: u64,
    /// Cycles in a row without a reply from the bus.
    silent_cycles: u64,
    /// When the last cycle ran, ns of CLOCK_MONOTONIC (0: never).
    last_cycle_ns: u64,
    /// When the grid last served the bus.
    last_release_ns: u64,
    pub safe_stop: Option<SafeStop>,
    /// The assembly generation whose outputs command the drives (0: none yet).
    pub generation: u16,
    /// The assembly switches seen, oldest first (at most [`SWITCHES_KEPT`]).
    pub switches: Vec<Switch>,
    /// The largest change of commanded position between two cycles of one assembly, rad, on
    /// an axis in operation enabled: one tick's motion, to compare a switch's with.
    pub max_step: f64,
    /// The same for the commanded velocity, rad/s: one tick's worth of acceleration.
    pub max_velocity_step: f64,
    /// The position commanded at the last cycle and at the one before, per axis.
    last_target: Vec<f64>,
    before_target: Vec<f64>,
    /// The tick of the last release after which cycles were missed, and how many.
    last_miss: (u64, u64),
    /// Cycles since the last switch (a velocity step needs two cycles of one assembly).
    cycles_in_assembly: u64,
    /// When the view was last published, and the switches and safe stop it had then.
    published: (u64, usize, bool),
    /// Silence after which the coordinator counts as lost, ns.
    lost_after_ns: u64,
    /// The grid runs in lockstep: releases come as fast as the grid goes, so gaps between
    /// them are not missed cycles.
    lockstep: bool,
}

impl Bridge {
    pub fn new(backend: Box<dyn Backend>, period_ns: u64) -> Bridge {
        let n = backend.axes();
        Bridge {
            backend,
            commands: vec![AxisCommand::default(); n],
            actuals: vec![AxisActual::default(); n],
            period_ns: period_ns.max(1),
            cycles: 0,
            missed: 0,
            lost_frames: 0,
            bus_faults: 0,
            silent_cycles: 0,
            last_cycle_ns: 0,
            last_release_ns: 0,
            safe_stop: None,
            generation: 0,
            switches: Vec::new(),
            max_step: 0.0,
            max_velocity_step: 0.0,
            last_target: vec![0.0; n],
            before_target: vec![0.0; n],
            last_miss: (0, 0),
            cycles_in_assembly: 0,
            published: (0, 0, false),
            lost_after_ns: LOST_AFTER * period_ns.max(1),
            lockstep: false,
        }
    }

    /// The watchdog judges the coordinator lost after `periods` base periods without a
    /// release instead of [`LOST_AFTER`] (at least 1): more on a host that steals milliseconds
    /// at a time, where three would stop the drives of a healthy system.
    pub fn watchdog_periods(mut self, periods: u64) -> Bridge {
        self.lost_after_ns = periods.max(1) * self.period_ns.max(1);
        self
    }

    /// For a grid in lockstep: no missed cycles are counted, and the watchdog waits
    /// [`LOCKSTEP_LOST_AFTER_NS`].
    pub fn lockstep(mut self) -> Bridge {
        self.lockstep = true;
        self.lost_after_ns = LOCKSTEP_LOST_AFTER_NS;
        self
    }

    /// How long from `now_ns` until the watchdog must look again: when the silence since the
    /// last release reaches its limit, or, while it cycles the bus itself, the next period.
    pub fn next_look_ns(&self, now_ns: u64) -> u64 {
        if self.safe_stop.is_some() && now_ns >= self.last_release_ns + self.lost_after_ns {
            return (self.last_cycle_ns + self.period_ns).saturating_sub(now_ns);
        }
        if self.last_release_ns == 0 {
            return self.lost_after_ns;
        }
        (self.last_release_ns + self.lost_after_ns).saturating_sub(now_ns)
    }

    pub fn axes(&self) -> usize {
        self.commands.len()
    }

    /// One cycle served by the grid at `now_ns`: `commands` go out, the actuals come back.
    pub fn serve(&mut self, now_ns: u64, commands: impl Fn(usize) -> AxisCommand) -> &[AxisActual] {
        self.serve_release(now_ns, &Served::default(), commands)
    }

    /// One cycle of the grid's release `served`: a release of a new assembly generation is a
    /// switch (recorded; it ends a safe stop that release does not ask for), and a release
    /// that asks for a safe stop brings one about.
    pub fn serve_release(
        &mut self,
        now_ns: u64,
        served: &Served,
        commands: impl Fn(usize) -> AxisCommand,
    ) -> &[AxisActual] {
        if self.last_release_ns != 0 && !self.lockstep {
            let gap = now_ns.saturating_sub(self.last_release_ns);
            let missed = ((gap + self.period_ns / 2) / self.period_ns).saturating_sub(1);
            if missed > 0 {
                tracing::debug!(
                    "{missed} bus cycle(s) missed before tick {}: {} us since the last release",
                    served.tick,
                    gap / 1000
                );
                self.missed += missed;
                self.last_miss = (served.tick, missed);
                if let Some(s) = self.switches.last_mut() {
                    if served.tick <= s.tick + NEAR_SWITCH {
                        s.missed_near += missed;
                    }
                }
            }
        }
        self.last_release_ns = now_ns;
        let switched = served.generation != self.generation;
        let ends = self.safe_stop.as_ref().is_some_and(|s| !s.latched);
        if switched && !served.safe_stop && ends {
            tracing::info!(
                "assembly generation {} takes over: the safe stop ends",
                served.generation
            );
            self.safe_stop = None;
        }
        if served.safe_stop && self.safe_stop.is_none() {
            self.stop("the assembly faulted".into());
        }
        if self.safe_stop.is_none() {
            for (i, c) in self.commands.iter_mut().enumerate() {
                *c = commands(i);
            }
            let (mut step, mut velocity_step) = (0.0f64, 0.0f64);
            let dt = self.period_ns as f64 * 1e-9;
            for (((c, last), before), a) in self
                .commands
                .iter()
                .zip(&self.last_target)
                .zip(&self.before_target)
                .zip(&self.actuals)
            {
                if a.state == DriveState::OperationEnabled && c.target_position.is_finite() {
                    step = step.max((c.target_position - last).abs());
                    let change = (c.target_position - 2.0 * last + before) / dt;
                    if change.is_finite() {
                        velocity_step = velocity_step.max(change.abs());
                    }
                }
            }
            if switched {
                if self.switches.len() == SWITCHES_KEPT {
                    self.switches.remove(0);
                }
                let (miss_tick, misses) = self.last_miss;
                let missed_near = if misses > 0 && miss_tick + NEAR_SWITCH >= served.tick {
                    misses
                } else {
                    0
                };
                self.switches.push(Switch {
                    generation: served.generation,
                    tick: served.tick,
                    step,
                    velocity_step,
                    missed_near,
                });
            } else if self.cycles_in_assembly == 1 {
                // The velocity into the cycle after a switch is the new assembly's first.
                if let Some(last) = self.switches.last_mut() {
                    last.velocity_step = last.velocity_step.max(velocity_step);
                }
            } else {
                self.max_step = self.max_step.max(step);
                self.max_velocity_step = self.max_velocity_step.max(velocity_step);
            }
        }
        self.cycles_in_assembly = if switched {
            1
        } else {
            self.cycles_in_assembly.saturating_add(1)
        };
        self.generation = served.generation;
        for ((before, last), c) in self
            .before_target
            .iter_mut()
            .zip(self.last_target.iter_mut())
            .zip(&self.commands)
        {
            *before = *last;
            *last = c.target_position;
        }
        self.cycle(now_ns);
        &self.actuals
    }

    fn cycle(&mut self, now_ns: u64) {
        let dt = self.period_ns as f64 * 1e-9;
        match self.backend.cycle(dt, &self.commands, &mut self.actuals) {
            Ok(()) => self.silent_cycles = 0,
            Err(BusFault::NoReply) => {
                self.lost_frames += 1;
                self.silent_cycles += 1;
                if self.silent_cycles >= LOST_AFTER && !self.latched() {
                    let cycles = self.silent_cycles;
                    self.stop_latched(format!("the bus did not answer for {cycles} cycles"));
                }
            }
            Err(fault) => {
                self.bus_faults += 1;
                if !self.latched() {
                    let reason = self.backend.describe(&fault);
                    self.stop_latched(reason);
                }
            }
        }
        self.cycles += 1;
        self.last_cycle_ns = now_ns;
        if let Some(stop) = self.safe_stop.as_mut() {
            let stopped = self.actuals.iter().all(|a| {
                !matches!(
                    a.state,
                    DriveState::OperationEnabled | DriveState::FaultReactionActive
                )
            });
            if stop.all_stopped.is_none() && stopped {
                let since = now_ns.saturating_sub(self.last_release_ns);
                stop.all_stopped = Some((self.cycles, since));
            }
        }
    }

    /// Blocks (or frees) the link of `axis` in the simulation: a collision or a jammed gear.
    pub fn block_axis(&mut self, axis: usize, blocked: bool) -> Result<(), BlockError> {
        if axis >= self.axes() {
            return Err(BlockError::NoSuchAxis {
                axis,
                axes: self.axes(),
            });
        }
        self.backend.block_axis(axis, blocked)
    }

    /// Called between releases: after the watchdog's periods without one ([`LOST_AFTER`]
    /// unless set otherwise), stops the drives and
    /// cycles the bus on its own every period. Returns whether it cycled.
    pub fn watch(&mut self, now_ns: u64) -> bool {
        if self.last_release_ns == 0 {
            return false; // the grid has not started serving the bus yet
        }
        let silent = now_ns.saturating_sub(self.last_release_ns);
        if silent < self.lost_after_ns {
            return false;
        }
        if self.safe_stop.is_none() {
            // A drive that produces no torque needs no stop: before the grid has enabled any,
            // a silent moment (a slow start) must not latch the drives in quick stop.
            if !self
                .actuals
                .iter()
                .any(|a| a.state == DriveState::OperationEnabled)
            {
                return false;
            }
            self.stop(format!(
                "coordinator lost: no tick for {} base periods",
                silent / self.period_ns
            ));
        }
        if now_ns.saturating_sub(self.last_cycle_ns) >= self.period_ns {
            self.cycle(now_ns);
            return true;
        }
        false
    }

    /// Commands quick stop to every drive and holds it.
    pub fn stop(&mut self, reason: String) {
        tracing::error!("safe stop: {reason}");
        self.backend.quick_stop_all();
        self.safe_stop = Some(SafeStop {
            reason,
            at_cycle: self.cycles,
            all_stopped: None,
            latched: false,
        });
    }

    /// A safe stop for a fault of the bus itself: no assembly switch ends it.
    fn stop_latched(&mut self, reason: String) {
        self.stop(reason);
        if let Some(s) = self.safe_stop.as_mut() {
            s.latched = true;
        }
    }

    fn latched(&self) -> bool {
        self.safe_stop.as_ref().is_some_and(|s| s.latched)
    }

    /// The bus ledger, as `modbot bus` prints it.
    pub fn ledger(&self) -> String {
        let mut view = BusView::default();
        view.copy_from(self);
        view.ledger()
    }

    /// Copies what the bridge's methods show into `view`, unless a reader holds it (then
    /// nothing happens: the real-time thread never waits for a thread of normal priority).
    /// No allocation once the view has held as many switches and as long a reason.
    pub fn publish(&self, view: &Mutex<BusView>) {
        if let Ok(mut v) = view.try_lock() {
            v.copy_from(self);
        }
    }

    /// [`Bridge::publish`] every [`PUBLISH_EVERY_NS`] at `now_ns`, and at once after a switch or
    /// a safe stop.
    pub fn publish_due(&mut self, now_ns: u64, view: &Mutex<BusView>) {
        let changed =
            self.published.1 != self.switches.len() || self.published.2 != self.safe_stop.is_some();
        if changed || now_ns.saturating_sub(self.published.0) >= PUBLISH_EVERY_NS {
            if let Ok(mut v) = view.try_lock() {
                v.copy_from(self);
                self.published = (now_ns, self.switches.len(), self.safe_stop.is_some());
            }
        }
    }

    /// What the drives reported at the last cycle.
    pub fn actuals(&self) -> &[AxisActual] {
        &self.actuals
    }

    /// Where `axis` was last commanded to be: the target position while it is in operation
    /// enabled in CSP (CiA 402's position demand value), else its actual position.
    pub fn demand_position(&self, axis: usize) -> f64 {
        let (Some(a), Some(c)) = (self.actuals.get(axis), self.commands.get(axis)) else {
            return 0.0;
        };
        if a.state == DriveState::OperationEnabled && a.mode == 8 && c.target_position.is_finite() {
            c.target_position
        } else {
            a.motor_position
        }
    }

    /// Every drive's state.
    pub fn states(&self) -> Vec<DriveState> {
        self.actuals.iter().map(|a| a.state).collect()
    }
}

/// What the bus bridge's methods show (`modbot bus`, `host_bus.switches`): a copy the
/// real-time thread refreshes with [`Bridge::publish`], so a method call never holds a lock the
/// real-time thread needs.
#[derive(Debug, Clone, Default)]
pub struct BusView {
    backend: &'static str,
    period_ns: u64,
    pub cycles: u64,
    pub missed: u64,
    pub lost_frames: u64,
    pub bus_faults: u64,
    pub safe_stop: Option<SafeStop>,
    pub generation: u16,
    pub switches: Vec<Switch>,
    pub max_step: f64,
    pub max_velocity_step: f64,
    pub actuals: Vec<AxisActual>,
    /// With distributed clocks: the frame's place in the SYNC0 cycle (last, least, most), ns.
    pub sync0_offset_ns: Option<(u64, u64, u64)>,
}

impl BusView {
    fn copy_from(&mut self, b: &Bridge) {
        self.backend = b.backend.name();
        self.period_ns = b.period_ns;
        self.cycles = b.cycles;
        self.missed = b.missed;
        self.lost_frames = b.lost_frames;
        self.bus_faults = b.bus_faults;
        match (&mut self.safe_stop, &b.safe_stop) {
            (Some(mine), Some(theirs)) => {
                mine.reason.clone_from(&theirs.reason);
                mine.at_cycle = theirs.at_cycle;
                mine.all_stopped = theirs.all_stopped;
                mine.latched = theirs.latched;
            }
            (mine, theirs) => mine.clone_from(theirs),
        }
        self.generation = b.generation;
        self.switches.clone_from(&b.switches);
        self.max_step = b.max_step;
        self.max_velocity_step = b.max_velocity_step;
        self.actuals.clone_from(&b.actuals);
        self.sync0_offset_ns = b.backend.sync0_offset_ns();
    }

    /// The bus ledger, as `modbot bus` prints it.
    pub fn ledger(&self) -> String {
        let mut out = format!(
            "bus {}  axes {}  cycles {}  missed {}  lost frames {}  bus faults {}  {}\n",
            self.backend,
            self.actuals.len(),
            self.cycles,
            self.missed,
            self.lost_frames,
            self.bus_faults,
            match &self.safe_stop {
                Some(s) => format!(
                    "SAFE STOP at cycle {}: {}{}",
                    s.at_cycle,
                    s.reason,
                    match s.all_stopped {
                        Some((cycle, ns)) => format!(
                            "; every drive stopped at cycle {cycle}, {:.2} base periods after the last tick",
                            ns as f64 / self.period_ns as f64
                        ),
                        None => String::new(),
                    }
                ),
                None => "running".to_owned(),
            }
        );
        if let Some((last, least, most)) = self.sync0_offset_ns {
            out.push_str(&format!(
                "distributed clocks: the frame reaches the reference clock {:.1} us into the SYNC0 cycle (least {:.1}, most {:.1})\n",
                last as f64 / 1e3,
                least as f64 / 1e3,
                most as f64 / 1e3
            ));
        }
        if let Some(last) = self.switches.last() {
            out.push_str(&format!(
                "assembly generation {}  switches {}  last at tick {}  largest step: at a switch {:.6} rad, within an assembly {:.6} rad; velocity step: at a switch {:.4} rad/s, within an assembly {:.4} rad/s\n",
                self.generation,
                self.switches.len(),
                last.tick,
                self.switches.iter().fold(0.0f64, |m, s| m.max(s.step)),
                self.max_step,
                self.switches.iter().fold(0.0f64, |m, s| m.max(s.velocity_step)),
                self.max_velocity_step
            ));
        }
        out.push_str(
            "AXIS  STATE                    MODE  STATUSWORD  POSITION     VELOCITY  ERROR\n",
        );
        for (i, a) in self.actuals.iter().enumerate() {
            out.push_str(&format!(
                "{:>4}  {:<24} {:>4}  0x{:04x}      {:>10.4}  {:>10.4}  0x{:04x}\n",
                i,
                a.state.to_string(),
                a.mode,
                a.statusword,
                a.motor_position,
                a.motor_velocity,
                a.error_code
            ));
        }
        out
    }

    /// `host_bus.switches`: the record of switches, encoded (`modbot_ipc_schema::bus`).
    pub fn encode_switches(&self, out: &mut Vec<u8>) -> Result<(), SwitchesError> {
        modbot_ipc_schema::bus::encode(self.max_step, self.max_velocity_step, &self.switches, out)
    }
}

/// The record of switches as `modbot bus --switches` prints it: a line
/// `max_step S max_velocity_step V`, then per switch `GENERATION TICK STEP MISSED VSTEP`.
pub fn render_switches(record: &Switches) -> String {
    let mut text = format!(
        "max_step {:e} max_velocity_step {:e}\n",
        record.max_step, record.max_velocity_step
    );
    for s in &record.switches {
        text.push_str(&format!(
            "{} {} {:e} {} {:e}\n",
            s.generation, s.tick, s.step, s.missed_near, s.velocity_step
        ));
    }
    text
}

/// What the grid's release of the bus says besides its inputs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Served {
    /// The release tick.
    pub tick: u64,
    /// The assembly generation whose outputs the inputs are.
    pub generation: u16,
    /// The assembly faulted: stop the drives.
    pub safe_stop: bool,
}

/// Locks the bridge, whoever panicked while holding it.
pub fn lock(bridge: &Mutex<Bridge>) -> std::sync::MutexGuard<'_, Bridge> {
    bridge.lock().unwrap_or_else(|p| p.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::PlantParams;
    use crate::sim::SimBackend;

    const MS: u64 = 1_000_000;

    fn enabled(sut: &mut Bridge, t: &mut u64) {
        for cw in [0x06u16, 0x07, 0x0f, 0x0f, 0x0f] {
            *t += MS;
            sut.serve(*t, |_| AxisCommand {
                controlword: cw,
                mode: 8,
                ..Default::default()
            });
        }
    }

    /// The base periods of silence after which every drive of `sut` (enabled, served at 1 ms)
    /// is in quick stop, looked at every millisecond.
    fn periods_until_quick_stop(mut sut: Bridge) -> Option<u64> {
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        assert!(
            sut.states()
                .iter()
                .all(|s| *s == DriveState::OperationEnabled),
            "{:?}",
            sut.states()
        );
        let last = t;
        for k in 1..=20 {
            sut.watch(last + k * MS);
            if sut
                .states()
                .iter()
                .all(|s| *s == DriveState::QuickStopActive)
            {
                assert!(sut.ledger().contains("SAFE STOP"), "{}", sut.ledger());
                return Some(k);
            }
        }
        None
    }

    #[test]
    fn a_lost_coordinator_quick_stops_every_drive_within_three_periods() {
        let sut = Bridge::new(Box::new(SimBackend::new(6, PlantParams::default())), MS);
        assert_eq!(periods_until_quick_stop(sut), Some(LOST_AFTER));
    }

    #[test]
    fn the_watchdog_waits_the_periods_it_is_given() {
        let sut = Bridge::new(Box::new(SimBackend::new(2, PlantParams::default())), MS)
            .watchdog_periods(7);
        assert_eq!(periods_until_quick_stop(sut), Some(7));
    }

    #[test]
    fn a_release_asking_for_safe_stop_stops_the_drives_until_a_new_assembly_takes_over() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(2, PlantParams::default())), MS);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        let faulted = Served {
            tick: 10,
            generation: 0,
            safe_stop: true,
        };
        t += MS;
        sut.serve_release(t, &faulted, |_| AxisCommand::default());
        t += MS;
        sut.serve_release(t, &faulted, |_| AxisCommand::default());
        assert!(
            sut.states()
                .iter()
                .all(|s| *s == DriveState::QuickStopActive),
            "{}",
            sut.ledger()
        );
        assert!(sut.ledger().contains("the assembly faulted"));
        let recovery = Served {
            tick: 12,
            generation: 2,
            safe_stop: false,
        };
        for cw in [0x00u16, 0x06, 0x07, 0x0f, 0x0f] {
            t += MS;
            sut.serve_release(t, &recovery, |_| AxisCommand {
                controlword: cw,
                mode: 8,
                ..Default::default()
            });
        }
        assert!(sut.safe_stop.is_none(), "{}", sut.ledger());
        assert!(
            sut.states()
                .iter()
                .all(|s| *s == DriveState::OperationEnabled),
            "{}",
            sut.ledger()
        );
        assert_eq!(sut.switches.len(), 1);
        assert_eq!((sut.switches[0].generation, sut.switches[0].tick), (2, 12));
    }

    #[test]
    fn a_switch_records_the_step_of_the_commanded_position() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(1, PlantParams::default())), MS);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        let at = |generation, tick| Served {
            tick,
            generation,
            safe_stop: false,
        };
        let csp = |q: f64| {
            move |_| AxisCommand {
                controlword: 0x0f,
                mode: 8,
                target_position: q,
                ..Default::default()
            }
        };
        t += MS;
        sut.serve_release(t, &at(0, 1), csp(0.0));
        t += MS;
        sut.serve_release(t, &at(0, 2), csp(0.001));
        t += MS;
        sut.serve_release(t, &at(3, 3), csp(0.0015));
        assert!((sut.max_step - 0.001).abs() < 1e-12, "{}", sut.max_step);
        assert_eq!(sut.switches.len(), 1);
        assert!((sut.switches[0].step - 0.0005).abs() < 1e-12);
        assert!((sut.demand_position(0) - 0.0015).abs() < 1e-12);
        // The record as the `switches` method answers it, and as `modbot bus --switches`
        // prints it.
        let mut view = BusView::default();
        view.copy_from(&sut);
        let mut bytes = Vec::new();
        view.encode_switches(&mut bytes).unwrap();
        let record = modbot_ipc_schema::bus::decode(&bytes).unwrap();
        assert_eq!(record.switches, sut.switches);
        let text = render_switches(&record);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 2, "{text}");
        assert!(
            lines[0].starts_with("max_step 1e-3 max_velocity_step "),
            "{text}"
        );
        assert!(
            lines[1].starts_with("3 3 "),
            "generation 3 at tick 3: {text}"
        );
    }

    #[test]
    fn the_watchdog_looks_again_when_the_silence_reaches_three_periods() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(1, PlantParams::default())), MS);
        sut.serve(10 * MS, |_| AxisCommand::default());
        assert_eq!(sut.next_look_ns(10 * MS), 3 * MS);
        assert_eq!(sut.next_look_ns(12 * MS + 500), MS - 500);
        assert_eq!(sut.next_look_ns(14 * MS), 0);
    }

    #[test]
    fn in_lockstep_gaps_between_releases_are_not_missed_cycles_and_the_watchdog_waits_long() {
        let mut sut =
            Bridge::new(Box::new(SimBackend::new(1, PlantParams::default())), MS).lockstep();
        sut.serve(10 * MS, |_| AxisCommand::default());
        sut.serve(500 * MS, |_| AxisCommand::default());
        assert_eq!((sut.cycles, sut.missed), (2, 0));
        assert!(!sut.watch(600 * MS));
        assert_eq!(sut.next_look_ns(500 * MS), LOCKSTEP_LOST_AFTER_NS);
    }

    #[test]
    fn a_silent_grid_before_any_drive_is_enabled_stops_nothing() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(2, PlantParams::default())), MS);
        sut.serve(MS, |_| AxisCommand::default());
        assert!(!sut.watch(20 * MS));
        assert!(sut.safe_stop.is_none());
    }

    /// A backend whose cycles fail from cycle `from` on with `fault`.
    struct Failing {
        sim: SimBackend,
        cycle: u64,
        from: u64,
        fault: BusFault,
    }

    impl Backend for Failing {
        fn axes(&self) -> usize {
            self.sim.axes()
        }
        fn cycle(
            &mut self,
            dt_s: f64,
            commands: &[AxisCommand],
            actuals: &mut [AxisActual],
        ) -> Result<(), BusFault> {
            self.cycle += 1;
            self.sim.cycle(dt_s, commands, actuals)?;
            if self.cycle >= self.from {
                return Err(self.fault);
            }
            Ok(())
        }
        fn quick_stop_all(&mut self) {
            self.sim.quick_stop_all();
        }
        fn name(&self) -> &'static str {
            "failing"
        }
    }

    fn failing(from: u64, fault: BusFault) -> Bridge {
        let sim = SimBackend::new(2, PlantParams::default());
        Bridge::new(
            Box::new(Failing {
                sim,
                cycle: 0,
                from,
                fault,
            }),
            MS,
        )
    }

    #[test]
    fn a_lost_slave_stops_the_drives_at_once_and_no_switch_ends_that_stop() {
        let mut sut = failing(7, BusFault::SlaveLost { position: 1 });
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        for tick in 6..8 {
            t += MS;
            let served = Served {
                tick,
                generation: 0,
                safe_stop: false,
            };
            sut.serve_release(t, &served, |_| AxisCommand {
                controlword: 0x0f,
                mode: 8,
                ..Default::default()
            });
        }
        let stop = sut.safe_stop.clone().expect("a safe stop");
        // The seventh cycle (numbered from 0) was the first that failed.
        assert_eq!((stop.at_cycle, stop.latched), (6, true), "{}", sut.ledger());
        assert!(
            sut.ledger().contains("slave 1 stopped answering"),
            "{}",
            sut.ledger()
        );
        let next = Served {
            tick: 9,
            generation: 2,
            safe_stop: false,
        };
        t += MS;
        sut.serve_release(t, &next, |_| AxisCommand::default());
        assert!(
            sut.safe_stop.is_some(),
            "an assembly switch ended a bus fault's stop"
        );
        assert_eq!(sut.bus_faults, 2);
    }

    #[test]
    fn three_cycles_without_a_reply_stop_the_drives_one_lost_frame_does_not() {
        let mut sut = failing(6, BusFault::NoReply);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        sut.serve(t + MS, |_| AxisCommand::default());
        assert!(sut.safe_stop.is_none());
        sut.serve(t + 2 * MS, |_| AxisCommand::default());
        assert!(sut.safe_stop.is_none());
        sut.serve(t + 3 * MS, |_| AxisCommand::default());
        let stop = sut
            .safe_stop
            .clone()
            .expect("a safe stop after three silent cycles");
        assert!(
            stop.reason.contains("did not answer for 3 cycles"),
            "{}",
            stop.reason
        );
        assert_eq!(sut.lost_frames, 3);
    }

    #[test]
    fn a_served_bus_counts_the_periods_it_missed() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(1, PlantParams::default())), MS);
        sut.serve(10 * MS, |_| AxisCommand::default());
        sut.serve(11 * MS, |_| AxisCommand::default());
        sut.serve(14 * MS, |_| AxisCommand::default());
        assert_eq!((sut.cycles, sut.missed), (3, 2));
    }
}

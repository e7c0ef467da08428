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
//!
//! The bridge owns the robot's state ([`RobotState`]): a stop of any cause, and a drive that
//! reports a fault (it disables itself; the bridge quick-stops the others), hold the robot
//! until an operator's reset ([`Bridge::ask_reset`], see [`super::reset`]); no assembly switch
//! ends them. While it holds the robot the bridge says so ([`Bridge::holding`]), and the
//! coordinator releases the running assembly's components to track.

use std::sync::Mutex;

use super::backend::{
    AxisActual, AxisCommand, Backend, BlockError, BusFault, DriveFault, Sync0Phase,
};
use super::cia402::DriveState;
pub use super::reset::ResetRefused;
use super::reset::{self, Recovery, ResetAsk};
use super::robot_state::{self, RobotState};
use super::tick_time::TickClock;

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
    /// The bus itself failed (a slave lost, the segment silent).
    pub latched: bool,
    /// The grid's tick when it happened (the last release's).
    pub since_tick: u64,
    /// A drive's fault caused it, or came during it: the drive and its error code.
    pub fault: Option<(usize, u16)>,
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
    /// When the view was last published, and the switches and robot state it had then.
    published: (u64, usize, usize),
    /// Silence after which the coordinator counts as lost, ns.
    lost_after_ns: u64,
    /// The grid runs in lockstep: releases come as fast as the grid goes, so gaps between
    /// them are not missed cycles.
    lockstep: bool,
    /// The tick of the last release.
    last_tick: u64,
    /// The last cycle's bus fault, in words (`None`: the cycle went through).
    bus_failure: Option<String>,
    /// The last release said the running assembly faulted.
    assembly_faulted: bool,
    /// A reset under way, and what the bridge says of the last one asked for.
    recovery: Option<Recovery>,
    reset: Option<ResetAsk>,
    /// What the backend did to bring a failing bus back for the reset under way, in words.
    rejoined: Option<String>,
    /// Per axis: the position a reset holds, and the controlword it sent last.
    hold: Vec<f64>,
    sent: Vec<u16>,
    /// The robot state's kind ([`RobotState::code`]) and the tick since which it holds.
    state: (usize, u64),
    /// The grid stopped normally: its silence is no lost coordinator.
    grid_stopped: bool,
    /// The nominal time of the grid's ticks, for a backend that phase-locks its bus to them.
    ticks: TickClock,
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
            published: (0, 0, usize::MAX),
            lost_after_ns: LOST_AFTER * period_ns.max(1),
            lockstep: false,
            last_tick: 0,
            bus_failure: None,
            assembly_faulted: false,
            recovery: None,
            reset: None,
            rejoined: None,
            hold: vec![0.0; n],
            sent: vec![0; n],
            state: (0, 0),
            grid_stopped: false,
            ticks: TickClock::default(),
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
    /// switch (recorded; it does not end a safe stop), a release that asks for a safe stop
    /// brings one about, and a reset asked for is taken (see [`super::reset`]).
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
        self.last_tick = served.tick;
        let switched = served.generation != self.generation;
        self.assembly_faulted = served.safe_stop;
        if served.safe_stop && self.safe_stop.is_none() {
            self.stop("the assembly faulted".into());
        }
        if matches!(self.reset, Some(ResetAsk::Asked { .. })) {
            self.begin_reset();
        }
        if let Some(recovery) = &self.recovery {
            let first = recovery.cycles == 0;
            for (((c, a), hold), sent) in self
                .commands
                .iter_mut()
                .zip(&self.actuals)
                .zip(&self.hold)
                .zip(self.sent.iter_mut())
            {
                *c = reset::command(first, a.state, *sent, *hold);
                *sent = c.controlword;
            }
        } else if self.safe_stop.is_none() {
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
        // In lockstep the ticks do not follow real time: nothing to lock to.
        let tick_ns = if self.lockstep {
            None
        } else {
            self.ticks.tick_ns(served.tick, now_ns, self.period_ns)
        };
        self.cycle(now_ns, tick_ns);
        self.recovery_cycle();
        self.note_state();
        &self.actuals
    }

    /// After a cycle of a reset under way: done once every drive has been in operation
    /// enabled for [`reset::SETTLE_CYCLES`] cycles; failed after [`reset::RESET_CYCLES`].
    fn recovery_cycle(&mut self) {
        let Some(recovery) = self.recovery.as_mut() else {
            return;
        };
        recovery.cycles += 1;
        let enabled = self
            .actuals
            .iter()
            .all(|a| a.state == DriveState::OperationEnabled);
        recovery.enabled_for = if enabled { recovery.enabled_for + 1 } else { 0 };
        let (cycles, since) = (recovery.cycles, recovery.since_tick);
        if recovery.enabled_for >= reset::SETTLE_CYCLES {
            self.recovery = None;
            let rejoined = self
                .rejoined
                .take()
                .map_or(String::new(), |what| format!("{what}; "));
            let done = format!(
                "{rejoined}every drive enabled at tick {} ({} cycles after the reset began at tick {since}), holding where it was found",
                self.last_tick, cycles
            );
            tracing::info!("reset: {done}");
            self.reset = Some(ResetAsk::Done(done));
        } else if cycles >= reset::RESET_CYCLES {
            let stuck = self
                .actuals
                .iter()
                .position(|a| a.state != DriveState::OperationEnabled)
                .unwrap_or(0);
            let state = self.actuals.get(stuck).map(|a| a.state).unwrap_or_default();
            let why = ResetRefused::DriveStuck {
                axis: stuck,
                state,
                cycles,
            };
            self.stop(why.to_string());
            // The stop's reason is the failure itself: it is answered as it is.
            self.reset = Some(ResetAsk::Refused(why));
        }
    }

    /// Takes the reset asked for at a release: refused while the stop's cause persists,
    /// else begun (see [`super::reset`]).
    fn begin_reset(&mut self) {
        let refused = if self.assembly_faulted {
            Some(ResetRefused::AssemblyFaulted)
        } else if let Some(why) = self.bus_failure.take() {
            self.rejoin(why)
        } else {
            (0..self.axes()).find_map(|axis| {
                self.backend
                    .fault_cause(axis)
                    .map(|cause| ResetRefused::DriveFault { axis, cause })
            })
        };
        if let Some(why) = refused {
            tracing::warn!("reset refused: {why}");
            self.reset = Some(ResetAsk::Refused(why));
            return;
        }
        if self.safe_stop.is_none() {
            let state = self.robot_state();
            self.reset = Some(ResetAsk::Done(format!(
                "nothing to reset: the robot is {state}"
            )));
            return;
        }
        if let Some(stop) = self.safe_stop.take() {
            tracing::info!(
                "reset at tick {}: ends the {} ({})",
                self.last_tick,
                if stop.fault.is_some() {
                    "fault"
                } else {
                    "safe stop"
                },
                stop.reason
            );
        }
        for (hold, a) in self.hold.iter_mut().zip(&self.actuals) {
            *hold = a.motor_position;
        }
        self.sent.fill(0xffff);
        self.recovery = Some(Recovery {
            since_tick: self.last_tick,
            cycles: 0,
            enabled_for: 0,
        });
        self.reset = None;
    }

    /// A reset asked for while the bus fails (`why`): the backend brings the segment back
    /// ([`Backend::rejoin`]); refused if it cannot, or if it did not come back.
    fn rejoin(&mut self, why: String) -> Option<ResetRefused> {
        match self.backend.rejoin() {
            Ok(Some(what)) => {
                tracing::info!("reset: {what}");
                self.rejoined = Some(what);
                None
            }
            Ok(None) => {
                self.bus_failure = Some(why.clone());
                Some(ResetRefused::BusFails(why))
            }
            Err(error) => {
                let still = format!("{why} (brought up again: {error})");
                self.bus_failure = Some(still.clone());
                Some(ResetRefused::BusFails(still))
            }
        }
    }

    /// An operator asks for a reset at `now_ns` (`modbot robot reset`): it is taken at the
    /// next release; on a real-time grid that has been silent for the watchdog's periods it
    /// is refused at once. [`Bridge::take_reset_answer`] has the answer.
    pub fn ask_reset(&mut self, now_ns: u64) {
        let silent = now_ns.saturating_sub(self.last_release_ns);
        if !self.lockstep && self.last_release_ns != 0 && silent >= self.lost_after_ns {
            let why = ResetRefused::GridSilent {
                periods: silent / self.period_ns,
            };
            tracing::warn!("reset refused: {why}");
            self.reset = Some(ResetAsk::Refused(why));
        } else {
            self.reset = Some(ResetAsk::Asked { at_ns: now_ns });
        }
    }

    /// The answer to the reset asked for, once there is one: `Ok` with what happened, in
    /// words, or why it was refused or failed. A reset the grid has not taken within
    /// [`reset::RESET_WAIT_NS`] (by `now_ns`) is refused.
    pub fn take_reset_answer(&mut self, now_ns: u64) -> Option<Result<String, ResetRefused>> {
        match &self.reset {
            Some(ResetAsk::Asked { at_ns })
                if now_ns.saturating_sub(*at_ns) >= reset::RESET_WAIT_NS =>
            {
                let why = ResetRefused::NotTaken {
                    silent_ms: now_ns.saturating_sub(self.last_release_ns.max(*at_ns)) / 1_000_000,
                    last_tick: self.last_tick,
                };
                self.reset = None;
                Some(Err(why))
            }
            Some(ResetAsk::Done(_)) | Some(ResetAsk::Refused(_)) => match self.reset.take() {
                Some(ResetAsk::Done(what)) => Some(Ok(what)),
                Some(ResetAsk::Refused(why)) => Some(Err(why)),
                _ => None,
            },
            _ => None,
        }
    }

    /// Whether the bridge holds the robot: the drives do not follow the running assembly (a
    /// safe stop, a fault, a reset under way). The coordinator then releases the assembly's
    /// components to track.
    pub fn holding(&self) -> bool {
        self.safe_stop.is_some() || self.recovery.is_some()
    }

    /// The robot's state.
    pub fn robot_state(&self) -> RobotState {
        let since_tick = self.state.1;
        match (&self.safe_stop, self.state.0) {
            (Some(stop), _) => match stop.fault {
                Some((drive, error_code)) => RobotState::Fault {
                    since_tick: stop.since_tick,
                    drive,
                    error_code,
                    cause: stop.reason.clone(),
                },
                None => RobotState::SafeStop {
                    since_tick: stop.since_tick,
                    cause: stop.reason.clone(),
                },
            },
            (None, 1) => RobotState::Operational { since_tick },
            (None, _) => RobotState::Disabled { since_tick },
        }
    }

    /// The robot state's kind now ([`RobotState::code`]).
    pub fn state_code(&self) -> usize {
        match &self.safe_stop {
            Some(stop) if stop.fault.is_some() => 3,
            Some(_) => 2,
            None if self.recovery.is_none()
                && self
                    .actuals
                    .iter()
                    .all(|a| a.state == DriveState::OperationEnabled) =>
            {
                1
            }
            None => 0,
        }
    }

    /// Notes a change of the robot state: its tick, and a line in the log with the cause.
    fn note_state(&mut self) {
        let code = self.state_code();
        if code == self.state.0 {
            return;
        }
        self.state = (code, self.last_tick);
        let state = self.robot_state();
        match code {
            2 | 3 if !self.grid_stopped => tracing::error!("robot state: {state}"),
            _ => tracing::info!("robot state: {state}"),
        }
    }

    /// Injects a drive fault into `axis` of a simulated or emulated bus (or takes a lasting
    /// cause away).
    pub fn inject(&mut self, axis: usize, fault: DriveFault, on: bool) -> Result<(), BlockError> {
        if axis >= self.axes() {
            return Err(BlockError::NoSuchAxis {
                axis,
                axes: self.axes(),
            });
        }
        self.backend.inject(axis, fault, on)
    }

    /// One bus cycle at `now_ns`, of the tick whose nominal time is `tick_ns` (`None`: a cycle
    /// the bridge runs on its own).
    fn cycle(&mut self, now_ns: u64, tick_ns: Option<u64>) {
        let dt = self.period_ns as f64 * 1e-9;
        let result = self
            .backend
            .cycle_at(tick_ns, dt, &self.commands, &mut self.actuals);
        self.bus_failure = match &result {
            Ok(()) => None,
            Err(fault) => Some(self.backend.describe(fault)),
        };
        match result {
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
        self.watch_drive_faults();
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

    /// A drive that reports a fault (it disabled itself) stops the others (quick stop) and
    /// holds the robot in `fault`; during a stop it turns the stop into a fault. A reset under
    /// way gives the drives it is resetting a few cycles to leave their fault.
    fn watch_drive_faults(&mut self) {
        if self.safe_stop.as_ref().is_some_and(|s| s.fault.is_some()) {
            return;
        }
        if self.recovery.is_some_and(|r| r.cycles < 4) {
            return;
        }
        let Some((drive, code)) = self.actuals.iter().enumerate().find_map(|(i, a)| {
            matches!(a.state, DriveState::Fault | DriveState::FaultReactionActive)
                .then_some((i, a.error_code))
        }) else {
            return;
        };
        let cause = robot_state::fault_cause(drive, code);
        match self.safe_stop.as_mut() {
            Some(stop) => {
                tracing::debug!("{cause} (during the safe stop: {})", stop.reason);
                stop.fault = Some((drive, code));
            }
            None => {
                self.stop(cause);
                if let Some(stop) = self.safe_stop.as_mut() {
                    stop.fault = Some((drive, code));
                }
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
        if self.safe_stop.is_none() && !self.grid_stopped {
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
            self.cycle(now_ns, None);
            self.note_state();
            return true;
        }
        false
    }

    /// The grid stops normally (`modbot down`, its ticks done): no release follows. Drives
    /// in operation enabled quick-stop, as at any stop, but the silence that follows is no lost
    /// coordinator and nothing is logged as an error.
    pub fn grid_stopping(&mut self) {
        self.grid_stopped = true;
        if self.safe_stop.is_some() {
            return;
        }
        let enabled = self
            .actuals
            .iter()
            .any(|a| a.state == DriveState::OperationEnabled);
        if enabled {
            let reason = "the grid stopped normally: every drive quick-stops";
            self.hold_stopped(reason.to_owned());
            self.note_state();
        }
    }

    /// Commands quick stop to every drive and holds it.
    /// The log's line is the robot state's change, with the cause (see `note_state`).
    pub fn stop(&mut self, reason: String) {
        tracing::debug!("safe stop at tick {}: {reason}", self.last_tick);
        self.hold_stopped(reason);
    }

    fn hold_stopped(&mut self, reason: String) {
        self.backend.quick_stop_all();
        if self.recovery.take().is_some() {
            self.rejoined = None;
            self.reset = Some(ResetAsk::Refused(ResetRefused::Stopped(reason.clone())));
        }
        self.safe_stop = Some(SafeStop {
            reason,
            at_cycle: self.cycles,
            all_stopped: None,
            latched: false,
            since_tick: self.last_tick,
            fault: None,
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
    /// a change of the robot state (a stop, the end of a reset).
    pub fn publish_due(&mut self, now_ns: u64, view: &Mutex<BusView>) {
        let state = self.state_code();
        let changed = self.published.1 != self.switches.len() || self.published.2 != state;
        if changed || now_ns.saturating_sub(self.published.0) >= PUBLISH_EVERY_NS {
            if let Ok(mut v) = view.try_lock() {
                v.copy_from(self);
                self.published = (now_ns, self.switches.len(), state);
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
    /// With distributed clocks: the frame's place in the SYNC0 cycle, and the phase lock.
    pub sync0: Option<Sync0Phase>,
    /// The robot's state.
    pub robot: Option<RobotState>,
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
        self.sync0 = b.backend.sync0_phase();
        // Cloned (its cause allocates) only when it changed.
        let kind_since = |r: &RobotState| (r.code(), r.since_tick());
        let now = (
            b.state_code(),
            b.safe_stop.as_ref().map_or(b.state.1, |s| s.since_tick),
        );
        if self.robot.as_ref().map(kind_since) != Some(now)
            || self.robot.as_ref().is_some_and(|r| {
                r.cause() != b.safe_stop.as_ref().map_or("", |s| s.reason.as_str())
            })
        {
            self.robot = Some(b.robot_state());
        }
    }

    /// The backend's name (`sim`, `ethercat`).
    pub fn backend(&self) -> &'static str {
        self.backend
    }

    /// The robot's state as last published (`disabled` before the first cycle).
    pub fn robot_state(&self) -> RobotState {
        self.robot
            .clone()
            .unwrap_or(RobotState::Disabled { since_tick: 0 })
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
        out.push_str(&format!("robot {}\n", self.robot_state()));
        if let Some(phase) = &self.sync0 {
            out.push_str(&sync0_line(phase));
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

/// The ledger's line of the distributed clocks: where the frame reaches the reference clock in
/// the SYNC0 cycle (last, least, most) and whether SYNC0 is phase-locked to the grid's tick.
pub fn sync0_line(p: &Sync0Phase) -> String {
    let us = |ns: u64| ns as f64 / 1e3;
    let lock = match (p.target_ns, p.locked) {
        (Some(target), true) => format!(
            "locked to the grid's tick (the frame due {:.1} us into the cycle)",
            us(target)
        ),
        (Some(target), false) => format!(
            "not locked yet (locking the frame to {:.1} us into the cycle)",
            us(target)
        ),
        (None, _) => "not locked (no tick time: a lockstep grid does not follow real time)".into(),
    };
    format!(
        "distributed clocks: the frame reaches the reference clock {:.1} us into the SYNC0 cycle (least {:.1}, most {:.1}); {lock}\n",
        us(p.last_ns),
        us(p.least_ns),
        us(p.most_ns),
    )
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

    /// Serves `sut` one release at `*t` + 1 ms with `served` and CSP commands at `q`.
    fn serve_at(sut: &mut Bridge, t: &mut u64, served: Served, q: f64) {
        *t += MS;
        sut.serve_release(*t, &served, |_| AxisCommand {
            controlword: 0x0f,
            mode: 8,
            target_position: q,
            ..Default::default()
        });
    }

    fn release(tick: u64, generation: u16, safe_stop: bool) -> Served {
        Served {
            tick,
            generation,
            safe_stop,
        }
    }

    #[test]
    fn a_safe_stop_holds_through_an_assembly_switch_and_only_a_reset_ends_it() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(2, PlantParams::default())), MS);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        assert!(sut.robot_state().is_operational(), "{}", sut.robot_state());
        serve_at(&mut sut, &mut t, release(10, 0, true), 0.0);
        serve_at(&mut sut, &mut t, release(11, 0, true), 0.0);
        assert!(sut.holding());
        assert_eq!(
            sut.robot_state(),
            RobotState::SafeStop {
                since_tick: 10,
                cause: "the assembly faulted".into()
            }
        );
        // A new assembly that enables the drives: they stay in quick stop.
        for tick in 12..40 {
            serve_at(&mut sut, &mut t, release(tick, 2, false), 0.0);
        }
        assert!(
            sut.states()
                .iter()
                .all(|s| *s == DriveState::QuickStopActive),
            "{}",
            sut.ledger()
        );
        assert_eq!(sut.robot_state().kind(), "safe_stop");
        // The reset: taken at the next release, every drive enabled at once, holding.
        sut.ask_reset(t);
        let mut tick = 40;
        let answer = loop {
            serve_at(&mut sut, &mut t, release(tick, 2, false), 0.0);
            tick += 1;
            if let Some(a) = sut.take_reset_answer(t) {
                break a;
            }
            assert!(tick < 100, "no answer: {}", sut.ledger());
        };
        let done = answer.expect("the reset went through");
        assert!(done.starts_with("every drive enabled at tick"), "{done}");
        assert!(!sut.holding());
        assert_eq!(
            sut.robot_state(),
            RobotState::Operational {
                since_tick: tick - 1
            }
        );
        assert!(
            sut.ledger().contains("robot operational since tick"),
            "{}",
            sut.ledger()
        );
    }

    #[test]
    fn a_reset_is_refused_while_the_running_assembly_is_faulted_or_the_grid_is_silent() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(1, PlantParams::default())), MS);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        serve_at(&mut sut, &mut t, release(10, 0, true), 0.0);
        sut.ask_reset(t);
        serve_at(&mut sut, &mut t, release(11, 0, true), 0.0);
        let why = sut.take_reset_answer(t).unwrap().unwrap_err();
        assert_eq!(why, ResetRefused::AssemblyFaulted);
        // Ten periods of silence on a real-time grid: refused at once.
        sut.ask_reset(t + 10 * MS);
        let why = sut.take_reset_answer(t + 10 * MS).unwrap().unwrap_err();
        assert_eq!(why, ResetRefused::GridSilent { periods: 10 });
        assert!(
            why.to_string()
                .starts_with("the grid is not ticking: no tick for 10 base periods"),
            "{why}"
        );
        assert_eq!(sut.robot_state().kind(), "safe_stop");
    }

    #[test]
    fn a_reset_takes_over_where_the_drives_stopped_without_a_jump() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(1, PlantParams::default())), MS);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        // Moving at 1 rad/s, then stopped by the assembly's fault.
        let mut q = 0.0;
        for tick in 5..300 {
            q += 0.001;
            serve_at(&mut sut, &mut t, release(tick, 0, false), q);
        }
        serve_at(&mut sut, &mut t, release(300, 0, true), q);
        for tick in 301..800 {
            serve_at(&mut sut, &mut t, release(tick, 2, false), q);
        }
        let stopped_at = sut.actuals()[0].motor_position;
        sut.ask_reset(t);
        let mut tick = 800;
        while sut.take_reset_answer(t).is_none() {
            // The assembly's generator tracked while the robot was held: it commands the
            // position the drive reports as its demand.
            let demand = sut.demand_position(0);
            serve_at(&mut sut, &mut t, release(tick, 2, false), demand);
            tick += 1;
        }
        let demand = sut.demand_position(0);
        assert!(
            (demand - stopped_at).abs() < 1e-3,
            "{demand} vs {stopped_at}"
        );
        serve_at(&mut sut, &mut t, release(tick, 2, false), demand);
        assert!(sut.robot_state().is_operational());
        assert!(sut.max_step <= 0.001 + 1e-12, "step {} rad", sut.max_step);
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
    fn a_grid_that_stops_normally_quick_stops_the_drives_without_judging_the_coordinator_lost() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(2, PlantParams::default())), MS);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        sut.grid_stopping();
        for k in 1..=20 {
            sut.watch(t + k * MS);
        }
        let stop = sut.safe_stop.clone().expect("the drives stop");
        assert!(
            stop.reason.starts_with("the grid stopped"),
            "{}",
            stop.reason
        );
        assert!(sut
            .states()
            .iter()
            .all(|s| *s == DriveState::QuickStopActive));
    }

    #[test]
    fn a_silent_grid_before_any_drive_is_enabled_stops_nothing() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(2, PlantParams::default())), MS);
        sut.serve(MS, |_| AxisCommand::default());
        assert!(!sut.watch(20 * MS));
        assert!(sut.safe_stop.is_none());
    }

    /// A backend whose cycles fail from cycle `from` on with `fault`, until a rejoin brings
    /// it back (`rejoins`: `None` cannot rejoin; `Some(false)`: a rejoin fails).
    struct Failing {
        sim: SimBackend,
        cycle: u64,
        from: u64,
        fault: BusFault,
        rejoins: Option<bool>,
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
        fn rejoin(&mut self) -> Result<Option<String>, Box<dyn std::error::Error + Send + Sync>> {
            match self.rejoins {
                None => Ok(None),
                Some(false) => Err("slave 1 is missing".into()),
                Some(true) => {
                    self.from = u64::MAX;
                    Ok(Some("the segment brought up again".into()))
                }
            }
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
                rejoins: None,
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

    /// The bridge of `failing` after its bus failed at cycle 7 and stopped the robot, its
    /// backend rejoining as `rejoins` says; and the time.
    fn stopped_by_a_lost_slave(rejoins: Option<bool>) -> (Bridge, u64) {
        let sim = SimBackend::new(2, PlantParams::default());
        let backend = Failing {
            sim,
            cycle: 0,
            from: 7,
            fault: BusFault::SlaveLost { position: 1 },
            rejoins,
        };
        let mut sut = Bridge::new(Box::new(backend), MS);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        for tick in 6..10 {
            serve_at(&mut sut, &mut t, release(tick, 0, false), 0.0);
        }
        assert_eq!(sut.robot_state().kind(), "safe_stop");
        (sut, t)
    }

    /// Asks for a reset and serves releases until it is answered.
    fn reset_answer(sut: &mut Bridge, t: &mut u64) -> Result<String, ResetRefused> {
        sut.ask_reset(*t);
        for tick in 10..100 {
            serve_at(sut, t, release(tick, 0, false), 0.0);
            if let Some(answer) = sut.take_reset_answer(*t) {
                return answer;
            }
        }
        panic!("no answer to the reset: {}", sut.ledger());
    }

    #[test]
    fn a_reset_while_the_bus_fails_brings_the_segment_back_and_enables_every_drive() {
        let (mut sut, mut t) = stopped_by_a_lost_slave(Some(true));
        let done = reset_answer(&mut sut, &mut t).expect("the reset went through");
        assert!(
            done.starts_with("the segment brought up again; every drive enabled at tick"),
            "{done}"
        );
        assert!(sut.robot_state().is_operational(), "{}", sut.robot_state());
    }

    #[test]
    fn a_reset_is_refused_naming_the_bus_when_the_segment_does_not_come_back() {
        let (mut sut, mut t) = stopped_by_a_lost_slave(Some(false));
        let why = reset_answer(&mut sut, &mut t).unwrap_err();
        assert_eq!(
            why.to_string(),
            "the bus still fails: slave 1 stopped answering (brought up again: slave 1 is missing)"
        );
        assert_eq!(sut.robot_state().kind(), "safe_stop");
        // A backend that cannot rejoin: refused with the bus's fault alone.
        let (mut sut, mut t) = stopped_by_a_lost_slave(None);
        let why = reset_answer(&mut sut, &mut t).unwrap_err();
        assert_eq!(
            why.to_string(),
            "the bus still fails: slave 1 stopped answering"
        );
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

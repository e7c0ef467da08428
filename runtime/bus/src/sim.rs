//! The `sim` backend: N simulated CiA 402 drives, each a [`DriveStateMachine`], the drive's
//! internal controllers and an elastic-joint [`Plant`].
//!
//! Each cycle, per axis: the first cycle completes initialisation (transition 1); the mode is
//! taken if supported (else the warning bit is set and the previous mode kept); the
//! controlword is applied; the drive computes a motor torque; it checks its fault limits (a
//! fault takes the torque away at once); the plant advances by `dt`; at standstill a quick
//! stop or fault reaction completes; the actuals are filled.
//!
//! The drive's loops run at the bus rate on the motor-side measurements:
//! - operation enabled, CSP: `v* = kp·(target_position − qm) + target_velocity`, then CSV;
//! - operation enabled, CSV: `τ = kv·(v* − ωm) + ki·∫(v* − ωm) + target_torque`;
//! - operation enabled, CST: `τ = target_torque`;
//! - quick stop active, and the braking fault reaction of [`SimBackend::inject_fault`] (when
//!   operation was enabled): a reference that decelerates from the motor's speed to 0 at
//!   `quick_stop_deceleration`, then holds its position, tracked as in CSP;
//! - any other state, and the fault reaction *disable drive* of the faults the drive detects:
//!   no torque (the brake is not modelled).
//!
//! The torque saturates at the plant's `torque_limit` (statusword bit 11), and the integral
//! stops while saturated (anti-windup). A torque that is not finite (a NaN target) becomes 0
//! and sets the warning bit. Everything is plain `f64` arithmetic in a fixed order: the same
//! commands give the same actuals, bit for bit. Nothing allocates after [`SimBackend::new`].
//!
//! The drive faults on a lasting following error in CSP and on a torque held at its limit,
//! and a test can inject those faults and an encoder loss ([`Backend::inject`]); the
//! submodule `faults` has the rules and the error codes (0x603F).

mod faults;

use super::backend::{
    AxisActual, AxisCommand, Backend, BlockError, BusFault, DriveFault, MISSING_COMMAND,
};
use super::cia402::{
    sw, Command, DriveState, DriveStateMachine, IllegalCommand, ModeOfOperation, QuickStopOption,
    Transition,
};
use super::plant::{require, InvalidParameter, Plant, PlantParams};
use faults::Faults;

/// The drive's controller settings (the same for every axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveParams {
    /// Position loop gain `kp` (1/s).
    pub position_gain: f64,
    /// Velocity loop proportional gain `kv` (Nm·s/rad).
    pub velocity_gain: f64,
    /// Velocity loop integral gain `ki` (Nm/rad).
    pub velocity_integral_gain: f64,
    /// Quick stop deceleration (0x6085), rad/s².
    pub quick_stop_deceleration: f64,
    /// The drive's estimate of the joint's total inertia (kg·m²), for the torque
    /// feed-forward of its own stopping ramp (the master feeds forward in CSP and CSV).
    pub inertia_estimate: f64,
    /// Standstill: the stopping reference is at 0 and the motor slower than
    /// `standstill_velocity` (rad/s) for `standstill_time` (s).
    pub standstill_velocity: f64,
    pub standstill_time: f64,
    /// Following error window (0x6065), rad: beyond it, CSP sets statusword bit 13. The drive
    /// does not fault on it (see `following_error_limit`).
    pub following_error_window: f64,
    /// Following error limit, rad: beyond it for longer than `following_error_timeout` (s),
    /// CSP faults with 0x8611. Loose by default: the master's monitoring, upstream, is meant
    /// to stop first; this is the drive's last line.
    pub following_error_limit: f64,
    pub following_error_timeout: f64,
    /// The torque at its limit for longer than this (s) faults with 0x8311 (a blocked axis
    /// the master did not stop).
    pub torque_limit_time: f64,
    /// Quick stop option code (0x605A).
    pub quick_stop_option: QuickStopOption,
}

impl Default for DriveParams {
    /// Tuned for [`PlantParams::default`] at 1 ms: velocity loop ≈ 600 rad/s on the motor
    /// alone (120 rad/s on the rigid joint), integral corner 20 rad/s, position loop 30 rad/s.
    /// A CSP step of 0.01 rad settles within 2 % in ≈ 0.13 s without overshoot. The fault
    /// limits are loose, a last line behind the master's monitoring: a link blocked under a
    /// 0.5 rad/s CSP ramp saturates the torque within 35 ms and passes 0.5 rad of following
    /// error after ≈ 1 s, and still runs after 2 s.
    fn default() -> Self {
        DriveParams {
            position_gain: 30.0,
            velocity_gain: 300.0,
            velocity_integral_gain: 6000.0,
            quick_stop_deceleration: 10.0,
            inertia_estimate: 2.5,
            standstill_velocity: 1e-3,
            standstill_time: 0.02,
            following_error_window: 0.05,
            following_error_limit: 1.5,
            following_error_timeout: 0.05,
            torque_limit_time: 3.0,
            quick_stop_option: QuickStopOption::HoldAfterStop,
        }
    }
}

impl DriveParams {
    pub fn check(&self) -> Result<(), InvalidParameter> {
        let p = self;
        require(
            "position_gain",
            p.position_gain,
            p.position_gain >= 0.0,
            ">= 0",
        )?;
        require(
            "velocity_gain",
            p.velocity_gain,
            p.velocity_gain >= 0.0,
            ">= 0",
        )?;
        let ki = p.velocity_integral_gain;
        require("velocity_integral_gain", ki, ki >= 0.0, ">= 0")?;
        let decel = p.quick_stop_deceleration;
        require("quick_stop_deceleration", decel, decel > 0.0, "> 0")?;
        let inertia = p.inertia_estimate;
        require("inertia_estimate", inertia, inertia >= 0.0, ">= 0")?;
        let still = p.standstill_velocity;
        require("standstill_velocity", still, still > 0.0, "> 0")?;
        let time = p.standstill_time;
        require("standstill_time", time, time >= 0.0, ">= 0")?;
        let window = p.following_error_window;
        require("following_error_window", window, window > 0.0, "> 0")?;
        let limit = p.following_error_limit;
        require("following_error_limit", limit, limit > 0.0, "> 0")?;
        let timeout = p.following_error_timeout;
        require("following_error_timeout", timeout, timeout > 0.0, "> 0")?;
        let time = p.torque_limit_time;
        require("torque_limit_time", time, time > 0.0, "> 0")
    }
}

/// One simulated drive.
#[derive(Debug, Clone)]
struct Drive {
    sm: DriveStateMachine,
    plant: Plant,
    /// The mode in effect (modes of operation display); `None` until one was commanded.
    mode: Option<ModeOfOperation>,
    /// The velocity loop's integral term (Nm).
    integral: f64,
    /// The stopping reference of a quick stop or fault reaction.
    stop_position: f64,
    stop_velocity: f64,
    /// How long the stopping drive has been still (s).
    still_for: f64,
    /// Whether the fault reaction brakes (operation was enabled) or only waits (no torque).
    braking: bool,
    /// A quick stop reached standstill and holds (statusword bit 10).
    halted: bool,
    /// Safe stop: enabling is inhibited until the master sends disable voltage.
    held: bool,
    /// This cycle's torque, and its flags for the statusword.
    torque: f64,
    warning: bool,
    saturated: bool,
    following_error_exceeded: bool,
    /// Controlwords the state machine rejected, and the last such.
    rejected: u64,
    last_rejected: Option<IllegalCommand>,
    /// Fault detection, the injected causes and the error code.
    faults: Faults,
}

impl Drive {
    fn new(plant: PlantParams, option: QuickStopOption) -> Drive {
        Drive {
            sm: DriveStateMachine::new().with_quick_stop_option(option),
            plant: Plant::new(plant),
            mode: None,
            integral: 0.0,
            stop_position: 0.0,
            stop_velocity: 0.0,
            still_for: 0.0,
            braking: false,
            halted: false,
            held: false,
            torque: 0.0,
            warning: false,
            saturated: false,
            following_error_exceeded: false,
            rejected: 0,
            last_rejected: None,
            faults: Faults::default(),
        }
    }

    fn cycle(&mut self, p: &DriveParams, dt: f64, cmd: &AxisCommand) -> AxisActual {
        if let Some(t) = self.sm.complete_initialisation() {
            self.entered(t);
        }
        self.warning = false;
        match ModeOfOperation::try_from(cmd.mode) {
            Ok(mode) => self.mode = Some(mode),
            Err(_) => self.warning = true,
        }
        let command = Command::decode(cmd.controlword, self.sm.last_controlword());
        match self.sm.apply(cmd.controlword) {
            Ok(Some(t)) => self.entered(t),
            Ok(None) => {}
            Err(e) => {
                self.rejected += 1;
                self.last_rejected = Some(e);
            }
        }
        if self.held && command == Command::DisableVoltage {
            self.held = false;
            self.sm.inhibit_enable(false);
        }
        let torque = self.control(p, dt, cmd);
        self.torque = if torque.is_finite() {
            torque
        } else {
            self.warning = true;
            0.0
        };
        self.watch(p, dt, cmd);
        self.plant.step(self.torque, dt);
        self.check_standstill(p, dt);
        self.actual()
    }

    /// Resets the controllers on entering a state.
    fn entered(&mut self, t: Transition) {
        self.faults.entered(t);
        self.integral = 0.0;
        self.halted = false;
        let s = self.plant.state();
        self.stop_position = s.motor_position;
        self.stop_velocity = s.motor_velocity;
        self.still_for = 0.0;
        if t.to == DriveState::FaultReactionActive {
            self.braking = matches!(
                t.from,
                DriveState::OperationEnabled | DriveState::QuickStopActive
            );
        }
    }

    fn control(&mut self, p: &DriveParams, dt: f64, cmd: &AxisCommand) -> f64 {
        self.saturated = false;
        self.following_error_exceeded = false;
        let braking = match self.sm.state() {
            DriveState::OperationEnabled => {
                return match self.mode {
                    Some(ModeOfOperation::Csp) => {
                        let error = cmd.target_position - self.plant.state().motor_position;
                        self.following_error_exceeded = error.abs() > p.following_error_window;
                        let v = p.position_gain * error + cmd.target_velocity;
                        self.velocity_loop(p, dt, v, cmd.target_torque)
                    }
                    Some(ModeOfOperation::Csv) => {
                        self.velocity_loop(p, dt, cmd.target_velocity, cmd.target_torque)
                    }
                    Some(ModeOfOperation::Cst) => self.saturate(cmd.target_torque),
                    None => 0.0,
                };
            }
            DriveState::QuickStopActive => true,
            DriveState::FaultReactionActive => self.braking,
            _ => false,
        };
        if !braking {
            return 0.0;
        }
        let dt = dt.max(0.0);
        let step = p.quick_stop_deceleration * dt;
        let change = -self.stop_velocity.clamp(-step, step);
        self.stop_velocity += change;
        self.stop_position += self.stop_velocity * dt;
        let error = self.stop_position - self.plant.state().motor_position;
        let v = p.position_gain * error + self.stop_velocity;
        let acceleration = if dt > 0.0 { change / dt } else { 0.0 };
        self.velocity_loop(p, dt, v, p.inertia_estimate * acceleration)
    }

    /// The velocity PI with torque feed-forward, saturated, integrating only when unsaturated.
    fn velocity_loop(&mut self, p: &DriveParams, dt: f64, v: f64, feed_forward: f64) -> f64 {
        let error = v - self.plant.state().motor_velocity;
        let wanted = p.velocity_gain * error + self.integral + feed_forward;
        let torque = self.saturate(wanted);
        if !self.saturated {
            self.integral += p.velocity_integral_gain * error * dt.max(0.0);
        }
        torque
    }

    fn saturate(&mut self, torque: f64) -> f64 {
        let limit = self.plant.params().torque_limit;
        let out = torque.clamp(-limit, limit);
        self.saturated = out != torque;
        out
    }

    /// Ends a quick stop or fault reaction once the reference and the motor have stood still
    /// for `standstill_time` (a fault reaction that does not brake ends at once).
    fn check_standstill(&mut self, p: &DriveParams, dt: f64) {
        let still = self.stop_velocity == 0.0
            && self.plant.state().motor_velocity.abs() <= p.standstill_velocity;
        self.still_for = if still {
            self.still_for + dt.max(0.0)
        } else {
            0.0
        };
        let stood = still && self.still_for >= p.standstill_time;
        let done = match self.sm.state() {
            DriveState::QuickStopActive => stood && !self.halted,
            DriveState::FaultReactionActive => stood || !self.braking,
            _ => false,
        };
        if done {
            match self.sm.motion_stopped() {
                Some(t) => self.entered(t),
                None => self.halted = true,
            }
        }
    }

    fn actual(&self) -> AxisActual {
        let state = self.sm.state();
        let s = self.plant.state();
        let enabled = state == DriveState::OperationEnabled && self.mode.is_some();
        let mut statusword = self.sm.statusword();
        let flags = [
            (sw::WARNING, self.warning),
            (sw::TARGET_REACHED, self.halted),
            (
                sw::INTERNAL_LIMIT_ACTIVE,
                self.saturated || self.plant.limits().any(),
            ),
            (sw::MODE_SPECIFIC_12, enabled),
            (sw::MODE_SPECIFIC_13, self.following_error_exceeded),
        ];
        for (bit, on) in flags {
            if on {
                statusword |= bit;
            }
        }
        let (motor_position, motor_velocity) =
            self.faults.measured(s.motor_position, s.motor_velocity);
        AxisActual {
            statusword,
            mode: self.mode.map_or(0, i8::from),
            motor_position,
            motor_velocity,
            motor_torque: self.torque,
            link_position: s.link_position,
            state,
            error_code: self.faults.error_code,
        }
    }
}

/// N simulated drives behind the [`Backend`] trait.
#[derive(Debug, Clone)]
pub struct SimBackend {
    params: DriveParams,
    drives: Vec<Drive>,
}

impl SimBackend {
    /// `axes` drives with [`DriveParams::default`], each just powered on, its joint at rest at
    /// 0.
    ///
    /// # Panics
    /// If `params` fail [`PlantParams::check`]; use [`SimBackend::try_new`] to handle that.
    pub fn new(axes: usize, params: PlantParams) -> SimBackend {
        match SimBackend::try_new(axes, params, DriveParams::default()) {
            Ok(sut) => sut,
            Err(e) => panic!("SimBackend::new: {e}"),
        }
    }

    pub fn try_new(
        axes: usize,
        plant: PlantParams,
        drive: DriveParams,
    ) -> Result<SimBackend, InvalidParameter> {
        SimBackend::with_joints(&vec![plant; axes], drive)
    }

    /// A drive per joint of `plants` (a robot whose joints differ), with `drive`'s settings.
    pub fn with_joints(
        plants: &[PlantParams],
        drive: DriveParams,
    ) -> Result<SimBackend, InvalidParameter> {
        drive.check()?;
        let drives = plants
            .iter()
            .map(|plant| {
                plant.check()?;
                Ok(Drive::new(*plant, drive.quick_stop_option))
            })
            .collect::<Result<Vec<_>, InvalidParameter>>()?;
        Ok(SimBackend {
            params: drive,
            drives,
        })
    }

    pub fn drive_params(&self) -> &DriveParams {
        &self.params
    }

    /// Clamps (or releases) `axis`'s link. Panics if `axis >= axes()`.
    pub fn block_axis(&mut self, axis: usize, blocked: bool) {
        self.drives[axis].plant.set_blocked(blocked);
    }

    /// Faults `axis` (transition 13) with error code 0xFF00; the fault reaction brakes if
    /// operation was enabled, and ends in fault (14) at standstill. Panics if
    /// `axis >= axes()`. [`Backend::inject`] injects the faults a drive detects instead.
    pub fn inject_fault(&mut self, axis: usize) {
        self.drives[axis].inject_braking_fault();
    }

    /// `axis`, or the error a caller gets for an axis that does not exist.
    fn drive_mut(&mut self, axis: usize) -> Result<&mut Drive, BlockError> {
        let axes = self.drives.len();
        self.drives
            .get_mut(axis)
            .ok_or(BlockError::NoSuchAxis { axis, axes })
    }

    /// `axis`'s joint, for tests and scenarios. Panics if `axis >= axes()`.
    pub fn plant(&self, axis: usize) -> &Plant {
        &self.drives[axis].plant
    }

    /// `axis`'s state machine. Panics if `axis >= axes()`.
    pub fn state_machine(&self, axis: usize) -> &DriveStateMachine {
        &self.drives[axis].sm
    }

    /// How many controlwords `axis` rejected, and the last of them.
    pub fn rejected(&self, axis: usize) -> (u64, Option<IllegalCommand>) {
        let drive = &self.drives[axis];
        (drive.rejected, drive.last_rejected)
    }

    /// Whether `axis` is held by [`Backend::quick_stop_all`] (until disable voltage).
    pub fn held(&self, axis: usize) -> bool {
        self.drives[axis].held
    }
}

impl Backend for SimBackend {
    fn axes(&self) -> usize {
        self.drives.len()
    }

    fn cycle(
        &mut self,
        dt_s: f64,
        commands: &[AxisCommand],
        actuals: &mut [AxisActual],
    ) -> Result<(), BusFault> {
        for (axis, drive) in self.drives.iter_mut().enumerate() {
            let command = commands.get(axis).unwrap_or(&MISSING_COMMAND);
            let actual = drive.cycle(&self.params, dt_s, command);
            if let Some(slot) = actuals.get_mut(axis) {
                *slot = actual;
            }
        }
        Ok(())
    }

    fn quick_stop_all(&mut self) {
        for drive in &mut self.drives {
            if let Some(t) = drive.sm.quick_stop() {
                drive.entered(t);
            }
            drive.held = true;
            drive.sm.inhibit_enable(true);
        }
    }

    fn block_axis(&mut self, axis: usize, blocked: bool) -> Result<(), BlockError> {
        self.drive_mut(axis)?.plant.set_blocked(blocked);
        Ok(())
    }

    fn inject(&mut self, axis: usize, fault: DriveFault, on: bool) -> Result<(), BlockError> {
        self.drive_mut(axis)?.inject(fault, on);
        Ok(())
    }

    fn fault_cause(&self, axis: usize) -> Option<&'static str> {
        let lost = self.drives.get(axis)?.faults.encoder_lost();
        lost.then_some(faults::ENCODER_LOST)
    }

    fn name(&self) -> &'static str {
        "sim"
    }
}

//! The simulated drive's faults: those it detects itself, those a test injects, and the error
//! code (0x603F) they leave.
//!
//! Detected, in operation enabled only, each with the fault reaction *disable drive*
//! (transition 13, then 14 at once: no braking, no torque):
//! - following error (0x8611): in CSP, |target position − motor position| beyond
//!   [`DriveParams::following_error_limit`] for longer than
//!   [`DriveParams::following_error_timeout`];
//! - excess torque (0x8311): the torque at the torque limit for longer than
//!   [`DriveParams::torque_limit_time`].
//!
//! Injected ([`crate::Backend::inject`]): a following error or excess torque faults the drive
//! at once, as if detected, in any state from which the state machine takes transition 13. A
//! lost encoder (0x7305) does too, and lasts until it is back: meanwhile the drive reports the
//! motor position and velocity it last measured, and refuses the fault reset (it stays in
//! fault; the reset is not an illegal command). The plant moves on, without torque, throughout.
//!
//! The error code stays while the drive is in fault and after, until a fault reset (15)
//! clears it to 0. Transition 13 keeps the first fault: a second one while the drive is in
//! fault reaction or fault changes neither the state nor the code.

use super::{Drive, DriveParams};
use crate::backend::{AxisCommand, DriveFault};
use crate::cia402::{DriveState, FaultReason, ModeOfOperation, Transition};

/// The error code of [`super::SimBackend::inject_fault`]'s fault (manufacturer specific).
pub(super) const INJECTED: u16 = 0xFF00;

/// Why a drive whose encoder is lost cannot leave its fault, for [`crate::Backend::fault_cause`].
pub(super) const ENCODER_LOST: &str = "its motor encoder is still lost";

/// Times within this of a limit count as at the limit (s): a time-out of a whole number of
/// cycles is then met after exactly that many, whatever the rounding of the sum of `dt`s.
const TIME_EPSILON: f64 = 1e-9;

/// A drive's fault monitoring and its injected causes.
#[derive(Debug, Clone, Default)]
pub(super) struct Faults {
    /// How long the CSP following error has been beyond its limit without a break (s).
    following_for: f64,
    /// How long the torque has been at its limit without a break (s).
    saturated_for: f64,
    /// The error code (0x603F) of the fault that took the drive to fault reaction; 0 after a
    /// fault reset.
    pub(super) error_code: u16,
    /// While the motor encoder is lost: the motor position and velocity it last measured
    /// (rad, rad/s), which the drive keeps reporting.
    lost: Option<(f64, f64)>,
}

impl Faults {
    /// Whether the motor encoder is lost (a fault reset cannot clear the fault).
    pub(super) fn encoder_lost(&self) -> bool {
        self.lost.is_some()
    }

    /// The motor position and velocity the drive reports, given the plant's: the last
    /// measured while the encoder is lost.
    pub(super) fn measured(&self, position: f64, velocity: f64) -> (f64, f64) {
        self.lost.unwrap_or((position, velocity))
    }

    /// A transition happened: the timers start again, and a fault reset clears the code.
    pub(super) fn entered(&mut self, t: Transition) {
        self.following_for = 0.0;
        self.saturated_for = 0.0;
        if t.number == 15 {
            self.error_code = 0;
        }
    }
}

/// `time` plus `dt` if `on`, else 0.
fn accumulate(time: f64, on: bool, dt: f64) -> f64 {
    if on {
        time + dt.max(0.0)
    } else {
        0.0
    }
}

impl Drive {
    /// After the cycle's torque was computed and before the plant moves: the fault this cycle
    /// detects, if any, taken at once (the torque becomes 0).
    pub(super) fn watch(&mut self, p: &DriveParams, dt: f64, cmd: &AxisCommand) {
        if self.sm.state() != DriveState::OperationEnabled {
            self.faults.following_for = 0.0;
            self.faults.saturated_for = 0.0;
            return;
        }
        let beyond = self.mode == Some(ModeOfOperation::Csp)
            && (cmd.target_position - self.plant.state().motor_position).abs()
                > p.following_error_limit;
        let f = &mut self.faults;
        f.following_for = accumulate(f.following_for, beyond, dt);
        f.saturated_for = accumulate(f.saturated_for, self.saturated, dt);
        let fault = if f.following_for > p.following_error_timeout + TIME_EPSILON {
            DriveFault::Following
        } else if f.saturated_for > p.torque_limit_time + TIME_EPSILON {
            DriveFault::Torque
        } else {
            return;
        };
        self.disable_on_fault(fault.error_code());
    }

    /// Injects `fault` (see the module documentation).
    pub(super) fn inject(&mut self, fault: DriveFault, on: bool) {
        match (fault, on) {
            (DriveFault::Encoder, true) if !self.faults.encoder_lost() => {
                let s = self.plant.state();
                self.faults.lost = Some((s.motor_position, s.motor_velocity));
                self.sm.inhibit_fault_reset(true);
                // Without its encoder a braking fault reaction cannot brake: it ends at once.
                self.braking = false;
                self.disable_on_fault(fault.error_code());
            }
            (DriveFault::Encoder, false) => {
                self.faults.lost = None;
                self.sm.inhibit_fault_reset(false);
            }
            (DriveFault::Following | DriveFault::Torque, true) => {
                self.disable_on_fault(fault.error_code());
            }
            _ => {}
        }
    }

    /// [`super::SimBackend::inject_fault`]'s fault: transition 13 with a braking reaction if
    /// operation was enabled.
    pub(super) fn inject_braking_fault(&mut self) {
        if let Some(t) = self.sm.fault(FaultReason::Injected) {
            self.entered(t);
            self.faults.error_code = INJECTED;
        }
    }

    /// The fault reaction *disable drive*: 13 and 14 at once, with no torque from now on.
    /// Nothing if a fault is already being handled (the first is kept).
    fn disable_on_fault(&mut self, code: u16) {
        let Some(t) = self.sm.fault(FaultReason::ErrorCode(code)) else {
            return;
        };
        self.entered(t);
        self.braking = false;
        self.faults.error_code = code;
        if let Some(t) = self.sm.motion_stopped() {
            self.entered(t);
        }
        self.torque = 0.0;
        self.saturated = false;
        self.following_error_exceeded = false;
    }
}

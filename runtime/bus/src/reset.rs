//! An operator's reset: what brings the drives back from a safe stop or a fault without a
//! restart.
//!
//! The bridge takes a reset at a release of the grid (a reset needs the grid ticking: a
//! silent coordinator refuses it), checks that the stop's cause is gone (the running assembly
//! no longer faulted, the bus answering, no drive whose fault persists), then commands every
//! drive itself: a fault reset (a rising edge of controlword bit 7) for a drive in fault,
//! disable voltage for one held in quick stop, then shutdown, switch on and enable operation,
//! every drive at once, in cyclic synchronous position mode at the position it was found at.
//! Once every drive has been in operation enabled for [`SETTLE_CYCLES`] cycles, the running
//! assembly's commands go to the drives again: it tracked all along (the bridge said it holds
//! the robot) and takes over from the held position without a jump.

use super::backend::AxisCommand;
use super::cia402::DriveState;

/// Cycles the bridge keeps holding every enabled drive before the assembly's commands go
/// through again: the grid's LET (a command takes two ticks from the bus's output back to its
/// input) plus one.
pub const SETTLE_CYCLES: u64 = 3;

/// Cycles a reset may take (every drive enabled) before it counts as failed.
pub const RESET_CYCLES: u64 = 2_000;

/// How long a reset waits for a release of the grid before it is refused, ns (a lockstep grid
/// pauses only while an assembly is prepared, a fraction of this).
pub const RESET_WAIT_NS: u64 = 1_000_000_000;

/// A reset under way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Recovery {
    /// The tick it began at.
    pub since_tick: u64,
    /// Cycles since it began.
    pub cycles: u64,
    /// Cycles in a row with every drive in operation enabled.
    pub enabled_for: u64,
}

/// Where a reset asked for stands, as the bridge answers it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ResetAsk {
    /// Asked at this time (CLOCK_MONOTONIC ns); taken at the next release.
    Asked { at_ns: u64 },
    /// Done: the robot is operational again (what happened, in words).
    Done(String),
    /// Refused or failed: why.
    Refused(ResetRefused),
}

/// The command that takes a drive in `state` one step towards operation enabled, holding
/// `hold` (rad) in CSP. The reset's first cycle (`first`) sends every drive disable voltage,
/// which ends the bridge's hold (quick stop, and the inhibited enable of the others); a drive
/// in fault then gets a fault reset: bit 7 rising after `last_controlword` 0.
pub fn command(first: bool, state: DriveState, last_controlword: u16, hold: f64) -> AxisCommand {
    let controlword = match state {
        _ if first => 0x00,
        DriveState::Fault if last_controlword == 0x00 => 0x80,
        DriveState::SwitchOnDisabled => 0x06,
        DriveState::ReadyToSwitchOn => 0x07,
        DriveState::SwitchedOn | DriveState::OperationEnabled => 0x0f,
        DriveState::Fault
        | DriveState::QuickStopActive
        | DriveState::FaultReactionActive
        | DriveState::NotReadyToSwitchOn => 0x00,
    };
    AxisCommand {
        controlword,
        mode: 8,
        target_position: hold,
        target_velocity: 0.0,
        target_torque: 0.0,
    }
}

/// Why an operator's reset was refused, or failed (see `Bridge::take_reset_answer`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ResetRefused {
    /// The running assembly faulted: only a switch to another assembly ends that.
    #[error(
        "the running assembly faulted: switch to another assembly first (`modbot assembly \
         switch hold`)"
    )]
    AssemblyFaulted,
    /// The bus itself still fails (as the backend describes it).
    #[error("the bus still fails: {0}")]
    BusFails(String),
    /// The cause of a drive's fault persists (an encoder still lost).
    #[error("drive {axis} cannot leave its fault: {cause}")]
    DriveFault { axis: usize, cause: &'static str },
    /// A real-time grid has not ticked for `periods` base periods: nothing would take the
    /// reset.
    #[error(
        "the grid is not ticking: no tick for {periods} base periods (the coordinator is \
         stopped or lost); reset once it runs again"
    )]
    GridSilent { periods: u64 },
    /// The grid did not take the reset within [`RESET_WAIT_NS`]: it has not ticked for
    /// `silent_ms` since the reset was asked, and ticked last at `last_tick`.
    #[error(
        "the grid has not ticked for {silent_ms} ms since the reset was asked (last tick \
         {last_tick}): the coordinator is stopped or lost"
    )]
    NotTaken { silent_ms: u64, last_tick: u64 },
    /// Drive `axis` was not in operation enabled after `cycles` cycles of the reset
    /// ([`RESET_CYCLES`]): it is `state`.
    #[error("the reset failed: drive {axis} is still {state} after {cycles} cycles")]
    DriveStuck {
        axis: usize,
        state: DriveState,
        cycles: u64,
    },
    /// A safe stop, for this reason, ended the reset under way.
    #[error("the reset failed: {0}")]
    Stopped(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_faulted_drive_gets_a_rising_edge_of_bit_7_after_a_zero() {
        assert_eq!(
            command(true, DriveState::Fault, 0x0f, 0.0).controlword,
            0x00
        );
        assert_eq!(
            command(false, DriveState::Fault, 0x00, 0.0).controlword,
            0x80
        );
        assert_eq!(
            command(false, DriveState::Fault, 0x80, 0.0).controlword,
            0x00
        );
    }

    #[test]
    fn a_held_drive_is_sent_disable_voltage_then_walked_to_operation_enabled_at_its_position() {
        let walk: Vec<u16> = [
            DriveState::QuickStopActive,
            DriveState::SwitchOnDisabled,
            DriveState::ReadyToSwitchOn,
            DriveState::SwitchedOn,
        ]
        .into_iter()
        .map(|s| command(s == DriveState::QuickStopActive, s, 0, 0.25).controlword)
        .collect();
        assert_eq!(walk, vec![0x00, 0x06, 0x07, 0x0f]);
        let c = command(false, DriveState::OperationEnabled, 0x0f, 0.25);
        assert_eq!(
            (c.mode, c.target_position, c.target_velocity),
            (8, 0.25, 0.0)
        );
    }
}

//! The backend trait: the one part of the bus bridge that changes with the hardware.
//!
//! The bus bridge is served every base tick of the time grid. Each tick it hands the backend
//! one [`AxisCommand`] per axis (the process data a master writes to a CiA 402 drive) and gets
//! back one [`AxisActual`] per axis (what it reads). Quantities are SI at the link side (rad,
//! rad/s, Nm); a hardware backend converts to and from the drive's units.

use super::cia402::DriveState;

/// What the master writes to one drive each cycle.
#[derive(Clone, Copy, Default, PartialEq, Debug)]
pub struct AxisCommand {
    /// Controlword (0x6040): the state machine command, see [`super::cia402`].
    pub controlword: u16,
    /// Modes of operation (0x6060): 8 CSP, 9 CSV, 10 CST.
    pub mode: i8,
    /// Target position (0x607A), rad; used in CSP.
    pub target_position: f64,
    /// Target velocity (0x60FF), rad/s; in CSV the target, in CSP the velocity feed-forward
    /// (the role of the velocity offset, 0x60B1).
    pub target_velocity: f64,
    /// Target torque (0x6071), Nm; in CST the target, in CSP and CSV the torque feed-forward
    /// (the role of the torque offset, 0x60B2).
    pub target_torque: f64,
}

/// What the master reads from one drive each cycle.
#[derive(Clone, Copy, Default, PartialEq, Debug)]
pub struct AxisActual {
    /// Statusword (0x6041).
    pub statusword: u16,
    /// Modes of operation display (0x6061); 0 until a supported mode was commanded.
    pub mode: i8,
    /// Position actual value (0x6064), rad.
    pub motor_position: f64,
    /// Velocity actual value (0x606C), rad/s.
    pub motor_velocity: f64,
    /// Torque actual value (0x6077), Nm.
    pub motor_torque: f64,
    /// The link's position measured outside the drive (the simulation's "laser tracker").
    pub link_position: f64,
    /// The state the statusword encodes, decoded for the reader's convenience.
    pub state: DriveState,
    /// Error code (0x603F): 0 without a fault, else the CiA 402 code of the last fault.
    pub error_code: u16,
}

/// A set of drives on one bus.
///
/// One call to [`Backend::cycle`] per bus cycle; it must not allocate or read a clock (its time
/// is the `dt_s` passed in), and blocks at most for the cycle's frames to come back (a hardware
/// backend's round trip on the wire; the simulator does not block).
pub trait Backend: Send {
    /// The number of axes (drives).
    fn axes(&self) -> usize;

    /// One bus cycle: apply the commands, advance by `dt_s`, fill the actuals.
    ///
    /// Both slices should hold [`Backend::axes`] elements. An axis without a command is sent
    /// a quick stop (controlword 0x0002); actuals beyond the slice's length are not written.
    /// A cycle whose commands did not reach every drive, or whose actuals did not all come
    /// back, is a [`BusFault`]: the actuals of the drives that did not answer are left as
    /// they were.
    fn cycle(
        &mut self,
        dt_s: f64,
        commands: &[AxisCommand],
        actuals: &mut [AxisActual],
    ) -> Result<(), BusFault>;

    /// One bus cycle of the grid's tick whose nominal time is `tick_ns` (ns of
    /// CLOCK_MONOTONIC, the clock the coordinator's ticks are on; `None` for a cycle the
    /// bridge runs on its own, or a grid that does not follow real time): a backend that
    /// phase-locks its bus to the grid (distributed clocks) uses it; the others run
    /// [`Backend::cycle`], the default.
    fn cycle_at(
        &mut self,
        tick_ns: Option<u64>,
        dt_s: f64,
        commands: &[AxisCommand],
        actuals: &mut [AxisActual],
    ) -> Result<(), BusFault> {
        let _ = tick_ns;
        self.cycle(dt_s, commands, actuals)
    }

    /// An operator's reset while the bus fails (a slave that lost power and came back in
    /// INIT, a cable plugged in again): brings the segment back as at start — every slave
    /// found, checked and brought to its operational state again — so the reset can go on.
    /// `Ok(Some(what))`: done, in words; `Ok(None)`: the backend cannot (the default: the
    /// simulator's bus never fails); `Err`: why the segment did not come back. It runs on
    /// the bridge's thread and takes as long as a start's bring-up (no cycle runs meanwhile:
    /// the robot stands in safe stop).
    fn rejoin(&mut self) -> Result<Option<String>, Box<dyn std::error::Error + Send + Sync>> {
        Ok(None)
    }

    /// `fault` in words for the log and the ledger, naming the slave as the backend knows it.
    fn describe(&self, fault: &BusFault) -> String {
        fault.to_string()
    }

    /// Brings every drive to quick stop and holds it there (safe stop); idempotent.
    ///
    /// Drives in operation enabled take transition 11; the others keep their state, which
    /// produces no torque. Until an axis is sent *disable voltage*, no command raises its power
    /// state (transitions 2, 3, 4, 16 are inhibited): a master that lost control cannot
    /// re-enable it by repeating a stale controlword.
    fn quick_stop_all(&mut self);

    /// Blocks the link of `axis` (a collision, a jammed gear), or frees it: for tests of the
    /// monitoring. Hardware cannot do this.
    fn block_axis(&mut self, axis: usize, blocked: bool) -> Result<(), BlockError> {
        let _ = (axis, blocked);
        Err(BlockError::Unsupported {
            backend: self.name(),
        })
    }

    /// Injects a drive fault into `axis` (a simulated or emulated drive), or, with `on`
    /// false, takes away a lasting cause (an encoder plugged back): for tests and demos.
    /// Hardware cannot do this.
    fn inject(&mut self, axis: usize, fault: DriveFault, on: bool) -> Result<(), BlockError> {
        let _ = (axis, fault, on);
        Err(BlockError::Unsupported {
            backend: self.name(),
        })
    }

    /// Why `axis` cannot leave its fault yet (its cause persists: an encoder still lost), in
    /// words; `None` when a fault reset can clear it (or it has none).
    fn fault_cause(&self, axis: usize) -> Option<&'static str> {
        let _ = axis;
        None
    }

    /// With distributed clocks: where in the slaves' SYNC0 cycle the cycle's frame reached
    /// the reference clock, and whether SYNC0 is phase-locked to the grid's tick. `None` for
    /// a backend without them.
    fn sync0_phase(&self) -> Option<Sync0Phase> {
        None
    }

    /// The backend's name for logs and `modbot top`.
    fn name(&self) -> &'static str;
}

/// Where the cycle's frame reaches the reference clock in the slaves' SYNC0 cycle (ns after
/// the last SYNC0 pulse, on the reference clock), and the phase lock of SYNC0 to the grid's
/// tick.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sync0Phase {
    /// At the last cycle.
    pub last_ns: u64,
    /// The least seen since the lock was last won or lost (since the first cycle before).
    pub least_ns: u64,
    /// The most seen since then.
    pub most_ns: u64,
    /// Where a locked frame lands (SYNC0 fires one period minus this after the tick's
    /// nominal time); `None` while the backend is not locking (no tick time: a lockstep grid).
    pub target_ns: Option<u64>,
    /// SYNC0 keeps a fixed phase to the tick: the frames' mean distance to the target is
    /// within the lock window (see `modbot_ethercat::dc`).
    pub locked: bool,
}

/// A bus cycle that did not reach every drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum BusFault {
    /// No reply to the cycle's frames came back in time (a lost frame, a cut link).
    #[error("no reply from the bus")]
    NoReply,
    /// The slave at `position` on the segment did not answer (its working counter is missing:
    /// it lost power or its link, and so did every slave behind it).
    #[error("slave {position} stopped answering")]
    SlaveLost { position: u16 },
    /// The slave at `position` left OP: its AL state (0x0130's low nibble) is `state`.
    #[error("slave {position} left OP (AL state {state:#x})")]
    SlaveState { position: u16, state: u8 },
    /// Every slave answered its state, but the process data's working counter is not what
    /// the mapping gives: a slave did not read or write its process data.
    #[error("process data working counter {received}, expected {expected}")]
    WorkingCounter { expected: u16, received: u16 },
}

/// A fault a drive detects itself, with its CiA 402 error code (0x603F) and fault reaction:
/// the faulted drive disables (no torque), and the bus bridge quick-stops the others.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DriveFault {
    /// The following error stayed beyond the drive's limit for longer than its time-out (the
    /// simulator's `following_error_limit` and `following_error_timeout`; 0x6065 and 0x6066 on
    /// a real drive).
    Following,
    /// The torque stayed at its limit for longer than the drive allows.
    Torque,
    /// The motor encoder's signal is lost: the drive no longer knows where the motor is. The
    /// cause lasts until the encoder is back.
    Encoder,
}

impl DriveFault {
    /// Every fault, in the order `modbot bus inject` lists them.
    pub const ALL: [DriveFault; 3] = [
        DriveFault::Following,
        DriveFault::Torque,
        DriveFault::Encoder,
    ];

    /// The name `modbot bus inject --fault` takes.
    pub const fn name(self) -> &'static str {
        match self {
            DriveFault::Following => "following",
            DriveFault::Torque => "torque",
            DriveFault::Encoder => "encoder",
        }
    }

    /// The fault named `name`.
    pub fn parse(name: &str) -> Option<DriveFault> {
        DriveFault::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Its error code (0x603F, CiA 402 / CiA 301 error code classes).
    pub const fn error_code(self) -> u16 {
        match self {
            DriveFault::Following => 0x8611,
            DriveFault::Torque => 0x8311,
            DriveFault::Encoder => 0x7305,
        }
    }
}

/// An error code (0x603F) in words: the codes the drives here report, and the code's class
/// (CiA 301) for others.
pub fn error_text(code: u16) -> &'static str {
    match code {
        0 => "no fault",
        0x8611 => "following error: beyond the window for longer than its time-out",
        0x8311 => "excess torque: at the torque limit for longer than allowed",
        0x7305 => "encoder lost: no signal from the motor encoder",
        0xFF00 => "injected fault",
        c => match c >> 12 {
            0x2 => "current",
            0x3 => "voltage",
            0x4 => "temperature",
            0x5 => "device hardware",
            0x6 => "device software",
            0x7 => "additional modules (sensor)",
            0x8 => "monitoring",
            0x9 => "external error",
            _ => "device-specific fault",
        },
    }
}

/// Why an axis cannot be blocked (or freed).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BlockError {
    #[error("axis {axis} does not exist: the bus has {axes} axes (0 to {})", .axes.saturating_sub(1))]
    NoSuchAxis { axis: usize, axes: usize },
    #[error("the {backend} backend cannot block an axis")]
    Unsupported { backend: &'static str },
}

/// The command an axis gets when the caller supplied none.
pub const MISSING_COMMAND: AxisCommand = AxisCommand {
    controlword: 0x0002,
    mode: 0,
    target_position: 0.0,
    target_velocity: 0.0,
    target_torque: 0.0,
};

//! modbot-bus: the bus bridge, its CiA 402 drives and the backends it drives them through.
//!
//! The bus bridge is served every base tick of the time grid and owns the drives. Only one
//! part changes with the hardware, the [`Backend`]: it takes one [`AxisCommand`] per axis
//! (controlword, mode, targets), runs one bus cycle of `dt` seconds, and returns one
//! [`AxisActual`] per axis (statusword, mode, motor and link positions, torque). Everything
//! here is pure and deterministic: no I/O, no clock (time is the cycle period passed in), no
//! allocation per cycle.
//!
//! # Layout
//! - [`backend`]: the [`Backend`] trait and the per-axis process data ([`AxisCommand`],
//!   [`AxisActual`]).
//! - [`cia402`]: the CiA 402 power drive state machine ([`DriveStateMachine`]): controlword
//!   commands, the numbered transitions 0–16, statusword encoding, modes of operation.
//! - [`plant`]: a two-mass elastic joint ([`Plant`]) integrated with sub-stepped
//!   semi-implicit Euler, with the limits it reports for monitoring.
//! - [`sim`]: the `sim` backend ([`SimBackend`]): N drives, each a state machine, the drive's
//!   internal loops (CSP, CSV, CST, quick stop ramp) and a plant.
//! - [`units`]: a CiA 402 drive's units (counts per rad, torque per mille of the rated torque)
//!   and the conversions, for the EtherCAT master and the emulated drives.
//! - [`link`]: a raw Ethernet link on a named interface, for a fieldbus master (the EtherCAT
//!   backend, `modbot-ethercat`) and the EtherCAT slave emulator (`modbot-ecat-sim`).
//! - [`bridge`]: the bus bridge: the backend served every tick, with its own watchdog that
//!   quick-stops the drives when the coordinator is lost, and the bus ledger.
//! - [`robot_state`]: [`RobotState`], the robot's state the bridge owns (operational, safe
//!   stop, fault, disabled) and the values it travels as.
//! - [`reset`]: an operator's reset: how the bridge brings the drives back without a restart.
//! - [`robot`]: the grid components `bus` (one bus cycle per release) and `drive_enable`.
//! - [`ask`]: asking the bridge from any tool: the robot's state, an operator's reset.

pub mod ask;
pub mod backend;
pub mod bridge;
pub mod cia402;
pub mod link;
pub mod plant;
pub mod reset;
pub mod robot;
pub mod robot_state;
pub mod sim;
pub mod tick_time;
pub mod units;

#[cfg(test)]
mod tests;

pub use backend::{error_text, AxisActual, AxisCommand, Backend, BusFault, DriveFault, Sync0Phase};
pub use cia402::{
    Command, DriveState, DriveStateMachine, FaultReason, IllegalCommand, ModeOfOperation,
    QuickStopOption, Transition, UnsupportedMode,
};
pub use plant::{InvalidParameter, LimitStatus, Plant, PlantParams, PlantState};
pub use robot_state::RobotState;
pub use sim::{DriveParams, SimBackend};

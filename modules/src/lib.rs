//! modbot's module programs: thin mains over the runtime.
//!
//! - `modbot-sonar`: the MRA's collision-avoidance sonar (12 ultrasonic sensors, front 180°).
//! - `modbot-mobility`: a simulated base with forward/turn/stop and odometry on its blackboard.
//! - MOSER, the MRA's security robot: `modbot-high-level` (patrol planner), `modbot-intrusion`
//!   (heat, light and motion fused into an alert), `modbot-control-station` (the operator's
//!   module); its sonars are `modbot-sonar` rings and its base is `modbot-mobility`, both in
//!   the simulated building of [`moser`].
//! - `modbot-faulty`: a module that panics, exits, hangs, floods or spams on request, for the
//!   fault-injection tests.
//! - `modbot-fleet`: a sensor fleet (sensors reporting to aggregators, [`fleet`]), the system to
//!   run at the full address space.
//! - [`moser`]: MOSER's simulated world (building, intruder, patrol planner), shared by its modules.
//!
//! [`common`] holds what every module program shares: its command-line options and logging.

pub mod common;
pub mod control_station;
pub mod faulty;
pub mod fleet;
pub mod high_level;
pub mod intrusion;
pub mod mobility;
pub mod moser;
pub mod sonar;

//! modbot's module programs: thin mains over the runtime.
//!
//! - `modbot-sonar`: the MRA's collision-avoidance sonar (12 ultrasonic sensors, front 180°).
//! - `modbot-mobility`: a simulated base with forward/turn/stop and odometry on its blackboard.
//! - `modbot-faulty`: a module that panics, exits, hangs, floods or spams on request, for the
//!   fault-injection tests.
//!
//! [`common`] holds what every module program shares: its command-line options and logging.

pub mod common;
pub mod faulty;
pub mod mobility;
pub mod sonar;

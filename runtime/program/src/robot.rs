//! What a program needs of a running system: switch assemblies, know the grid's time, read
//! what modules and components publish, call methods, and hear of a fault. [`SystemRobot`]
//! is the real one (a tool endpoint in the system's domain); the unit tests have a fake.
//!
//! [`SystemRobot`]: super::SystemRobot

use modbot_bus::RobotState;
use modbot_ipc_schema::OwnedValue;

use super::RobotError;

/// A running system, as a program drives it.
pub trait Robot {
    /// Prepares assembly `name` and switches to it, through the same path as `modbot assembly
    /// switch`; returns the tick it took over at.
    fn switch(&mut self, name: &str) -> Result<u64, RobotError>;
    /// The grid's newest tick.
    fn tick(&mut self) -> Result<u64, RobotError>;
    /// The grid's base tick, s.
    fn base_period_s(&mut self) -> Result<f64, RobotError>;
    /// `module.item` (a module's blackboard item) or `component.output` (a grid component's
    /// latest output, from its host's blackboard).
    fn read(&mut self, what: &str) -> Result<OwnedValue, RobotError>;
    /// Calls `module.method` with `args`; its answer.
    fn call(&mut self, target: &str, args: &[OwnedValue]) -> Result<Vec<OwnedValue>, RobotError>;
    /// Why the running assembly faulted, if it did (a monitor's breach, an overrun).
    fn fault(&mut self) -> Result<Option<String>, RobotError>;
    /// The robot's state as the bus bridge owns it; `None` for a system without a bus.
    fn robot_state(&mut self) -> Result<Option<RobotState>, RobotError>;
    /// An operator's reset (`modbot robot reset`): what it did, or why it was refused.
    fn reset(&mut self) -> Result<String, RobotError>;
    /// The domain, for the commands a message suggests.
    fn domain(&self) -> &str;
    /// Whether the program steps the grid (a gated lockstep grid, see `coordinator::gate`):
    /// the grid stands between commands and runs only as far as [`Robot::run_to`] says, so
    /// every tick a program sees is the same in every run. False by default.
    fn stepped(&self) -> bool {
        false
    }
    /// Runs a stepped grid until every tick up to `tick` is done; returns `tick`. Only called
    /// when [`Robot::stepped`].
    fn run_to(&mut self, tick: u64) -> Result<u64, RobotError> {
        Err(RobotError::Grid(format!(
            "this grid is not stepped: it cannot be run to tick {tick}"
        )))
    }
}

//! Tests of the bus: the CiA 402 state machine against the standard's table, the plant's
//! numerics, and the simulated drives in closed loop and their faults.

mod backend_params;
mod cia402;
mod drive_faults;
mod joints;
mod plant;
mod sim;

/// The simulated drives' tests' tools: the cycle, the modes, commands and enabling.
pub(super) mod drives {
    use crate::cia402::DriveState;
    use crate::{AxisActual, AxisCommand, Backend, PlantParams, SimBackend};

    pub const DT: f64 = 1e-3;
    pub const CSP: i8 = 8;
    pub const CSV: i8 = 9;
    pub const CST: i8 = 10;

    pub fn backend(axes: usize) -> SimBackend {
        SimBackend::new(axes, PlantParams::default())
    }

    /// One cycle with `commands`; the actuals.
    pub fn cycle(sut: &mut SimBackend, commands: &[AxisCommand]) -> Vec<AxisActual> {
        let mut actuals = vec![AxisActual::default(); sut.axes()];
        sut.cycle(DT, commands, &mut actuals).unwrap();
        actuals
    }

    pub fn command(controlword: u16, mode: i8) -> AxisCommand {
        AxisCommand {
            controlword,
            mode,
            ..AxisCommand::default()
        }
    }

    /// Shutdown, switch on, enable operation, every axis in `mode` with zero targets.
    pub fn enable(sut: &mut SimBackend, mode: i8) -> Vec<AxisActual> {
        let mut actuals = Vec::new();
        for controlword in [0x06, 0x07, 0x0F] {
            actuals = cycle(sut, &vec![command(controlword, mode); sut.axes()]);
        }
        assert!(
            actuals
                .iter()
                .all(|a| a.state == DriveState::OperationEnabled),
            "{actuals:?}"
        );
        actuals
    }
}

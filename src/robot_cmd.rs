//! `modbot robot`: the robot's state as the bus bridge owns it, and an operator's reset;
//! `modbot bus inject`: a drive fault in the simulation, for tests and demos.

use std::process::ExitCode;
use std::time::Duration;

use clap::Subcommand;
use modbot_bus::ask::{self as robot_state, RESET_TIMEOUT};
use modbot_bus::DriveFault;
use modbot_core::tool::Calls;
use modbot_core::CallOptions;
use modbot_ipc_schema::Value;

use super::tool;

/// `modbot robot` subcommands.
#[derive(Debug, Subcommand)]
pub enum RobotCommand {
    /// The robot's state (the default): operational, safe_stop, fault or disabled, since which
    /// tick, and why.
    State,
    /// Acknowledges a safe stop or a drive fault and brings the robot back without a restart:
    /// fault reset, then every drive enabled at once, holding where it is. Refused, with the
    /// reason, while the cause persists (the grid not ticking, a drive still in fault, the
    /// running assembly faulted).
    Reset,
}

/// Runs `modbot robot`.
pub fn run(domain: &str, command: Option<RobotCommand>) -> anyhow::Result<ExitCode> {
    let mut tool = tool::open(domain)?;
    match command.unwrap_or(RobotCommand::State) {
        RobotCommand::State => match robot_state::robot_state(&mut tool, Duration::from_secs(2)) {
            Ok(Some(state)) => {
                println!("{state}");
                Ok(ExitCode::SUCCESS)
            }
            Ok(None) => {
                eprintln!(
                    "modbot robot: no bus bridge runs in '{domain}': the system has no robot"
                );
                Ok(ExitCode::from(1))
            }
            Err(e) => {
                eprintln!("modbot robot: {e}");
                Ok(ExitCode::from(1))
            }
        },
        RobotCommand::Reset => match robot_state::reset(&mut tool, RESET_TIMEOUT) {
            Ok(done) => {
                println!("reset: {done}");
                Ok(ExitCode::SUCCESS)
            }
            Err(why) => {
                eprintln!("modbot robot reset: refused: {why}");
                Ok(ExitCode::from(1))
            }
        },
    }
}

/// `modbot bus inject --axis A --fault F [--off]`.
pub fn inject(
    domain: &str,
    axis: u32,
    fault: &str,
    off: bool,
    timeout_ms: u64,
) -> anyhow::Result<ExitCode> {
    if DriveFault::parse(fault).is_none() {
        let known: Vec<&str> = DriveFault::ALL.iter().map(|f| f.name()).collect();
        eprintln!(
            "modbot bus inject: no drive fault named '{fault}' (known: {})",
            known.join(", ")
        );
        return Ok(ExitCode::from(2));
    }
    let mut tool = tool::open(domain)?;
    let answer = tool.call_owned(
        &robot_state::bus_module(),
        "inject",
        &[
            Value::I64(i64::from(axis)),
            Value::Text(fault),
            Value::Bool(!off),
        ],
        CallOptions::timeout(Duration::from_millis(timeout_ms)),
    );
    match answer {
        Ok(_) => {
            let what = if off {
                "taken away from"
            } else {
                "injected into"
            };
            println!("drive fault '{fault}' {what} axis {axis}");
            Ok(ExitCode::SUCCESS)
        }
        Err(e) => {
            eprintln!("modbot bus inject: {e}");
            Ok(ExitCode::from(1))
        }
    }
}

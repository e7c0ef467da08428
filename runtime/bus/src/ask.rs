//! Asking the bus bridge (the grid's host named `bus`) from any tool: the robot's state and an
//! operator's reset — `modbot robot`, `modbot top`, the control station, and a robot program's
//! `robot_state()` and `reset {}`.

use std::time::{Duration, Instant};

use modbot_core::calls::CallOptions;
use modbot_core::error::CallError;
use modbot_core::tool::Calls;
use modbot_grid::component::Generation;
use modbot_grid::spec::{host_module_of, BUS_HOST};
use modbot_ipc_schema::{NakCode, OwnedValue, Value};
use thiserror::Error;

use crate::robot_state::{RobotState, RobotStateError};

/// How long a reset may take from the ask to its answer.
pub const RESET_TIMEOUT: Duration = Duration::from_secs(15);

/// Why the bus bridge gave no state, or no reset.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum AskError {
    /// The call failed (a timeout, a refusal of the transport).
    #[error("{0}")]
    Call(String),
    /// No bus bridge answered the reset.
    #[error("no bus bridge answers: {0}")]
    NoBridge(String),
    /// The bridge answered with values that are not a robot state.
    #[error("the bus bridge's answer: {0}")]
    Answer(#[from] RobotStateError),
    /// The bridge refused the reset, or the reset failed: its words.
    #[error("{0}")]
    Refused(String),
    /// The reset was taken and is not done yet.
    #[error("no answer from the bus bridge within {} s: the reset is still under way", .0.as_secs())]
    Pending(Duration),
}

/// The module name of the bus bridge.
pub fn bus_module() -> String {
    host_module_of(BUS_HOST, Generation::SYSTEM)
}

/// The robot's state, as the bus bridge publishes it. `Ok(None)`: the system has no bus.
pub fn robot_state(
    tool: &mut impl Calls,
    timeout: Duration,
) -> Result<Option<RobotState>, AskError> {
    let answer = tool.call_blocking(
        &bus_module(),
        "robot",
        &[],
        CallOptions::timeout(timeout),
        |r| match r {
            Ok(args) => Ok(Some(
                args.as_slice()
                    .iter()
                    .map(Value::to_owned_value)
                    .collect::<Vec<OwnedValue>>(),
            )),
            Err(CallError::UnknownModule(_)) => Ok(None),
            Err(e) => Err(AskError::Call(e.to_string())),
        },
    )?;
    match answer {
        Some(values) => Ok(Some(RobotState::from_values(&values)?)),
        None => Ok(None),
    }
}

/// Asks the bus bridge for an operator's reset and waits for its answer: `Ok` with what it
/// did, [`AskError::Refused`] with why it was refused or failed.
pub fn reset(tool: &mut impl Calls, timeout: Duration) -> Result<String, AskError> {
    reset_with(tool, timeout, &mut |_| {
        std::thread::sleep(Duration::from_millis(5));
        Ok(())
    })
}

/// As [`reset`], calling `wait` between two looks at the answer: a program that steps a gated
/// grid runs it on there (the bridge takes a reset at a release of the grid, and a held grid
/// releases nothing).
pub fn reset_with<T: Calls>(
    tool: &mut T,
    timeout: Duration,
    wait: &mut dyn FnMut(&mut T) -> Result<(), AskError>,
) -> Result<String, AskError> {
    let module = bus_module();
    let opts = || CallOptions::timeout(Duration::from_secs(2));
    let number = tool.call_blocking(&module, "reset", &[], opts(), |r| match r {
        Ok(args) => args.i64(0).map_err(|e| AskError::Call(e.to_string())),
        Err(e) => Err(AskError::NoBridge(e.to_string())),
    })?;
    let deadline = Instant::now() + timeout;
    loop {
        let answer = tool.call_blocking(
            &module,
            "reset_answer",
            &[Value::I64(number)],
            opts(),
            |r| match r {
                Ok(args) => {
                    let call = |e: modbot_ipc_schema::ArgError| AskError::Call(e.to_string());
                    let ok = args.bool(0).map_err(call)?;
                    let text = args.text(1).map_err(call)?.to_owned();
                    Ok(Some(if ok {
                        Ok(text)
                    } else {
                        Err(AskError::Refused(text))
                    }))
                }
                Err(CallError::Nak {
                    code: NakCode::NOT_READY,
                    ..
                }) => Ok(None),
                Err(e) => Err(AskError::Call(e.to_string())),
            },
        )?;
        if let Some(answer) = answer {
            return answer;
        }
        if Instant::now() > deadline {
            return Err(AskError::Pending(timeout));
        }
        wait(tool)?;
    }
}

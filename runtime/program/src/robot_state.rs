//! The robot's state and an operator's reset, asked of the bus bridge (the grid's host named
//! `bus`) by any tool: `modbot robot`, and a robot program's `robot_state()` and `reset {}`.

use std::time::{Duration, Instant};

use modbot_bus::RobotState;
use modbot_core::calls::CallOptions;
use modbot_core::error::CallError;
use modbot_core::tool::Calls;
use modbot_grid::component::Generation;
use modbot_grid::spec::host_module_of;
use modbot_ipc_schema::{NakCode, OwnedValue, Value};

/// The host whose components the bus bridge steps (the supervisor's `BUS_HOST`).
const BUS_HOST: &str = "bus";

/// The module name of the bus bridge.
pub fn bus_module() -> String {
    host_module_of(BUS_HOST, Generation::SYSTEM)
}

/// The robot's state, as the bus bridge publishes it. `Ok(None)`: the system has no bus.
pub fn robot_state(tool: &mut impl Calls, timeout: Duration) -> Result<Option<RobotState>, String> {
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
            Err(e) => Err(e.to_string()),
        },
    )?;
    match answer {
        Some(values) => RobotState::from_values(&values)
            .map(Some)
            .map_err(|e| format!("the bus bridge's answer: {e}")),
        None => Ok(None),
    }
}

/// How long a reset may take from the ask to its answer.
pub const RESET_TIMEOUT: Duration = Duration::from_secs(15);

/// Asks the bus bridge for an operator's reset and waits for its answer: `Ok` with what it
/// did, `Err` with why it was refused or failed.
pub fn reset(tool: &mut impl Calls, timeout: Duration) -> Result<String, String> {
    let module = bus_module();
    let opts = || CallOptions::timeout(Duration::from_secs(2));
    let number = tool.call_blocking(&module, "reset", &[], opts(), |r| match r {
        Ok(args) => args.i64(0).map_err(|e| e.to_string()),
        Err(e) => Err(format!("no bus bridge answers: {e}")),
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
                    let ok = args.bool(0).map_err(|e| e.to_string())?;
                    let text = args.text(1).map_err(|e| e.to_string())?.to_owned();
                    Ok(Some(if ok { Ok(text) } else { Err(text) }))
                }
                Err(CallError::Nak {
                    code: NakCode::NOT_READY,
                    ..
                }) => Ok(None),
                Err(e) => Err(e.to_string()),
            },
        )?;
        if let Some(answer) = answer {
            return answer;
        }
        if Instant::now() > deadline {
            return Err(format!(
                "no answer from the bus bridge within {} s: the reset is still under way",
                timeout.as_secs()
            ));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

//! `modbot-recorder`: the data recorder's host — steps the `record` components of one host
//! name (a description's `record { ... }`), which write the run's signals to HDF5 (see
//! `modbot_record`), beside the built-in component types. Its module's methods start and stop
//! recordings (a robot program's `record { }` and `stop_record { }`):
//!
//! - `start FILE [SIGNAL...]`: records the signals named (all without any) to FILE from now
//!   on, closing the recording before; answers the file written;
//! - `stop`: ends the recording; answers its file and rows.

use std::path::PathBuf;

use modbot_core::{Ctx, MethodError, Reply};
use modbot_ipc_schema::{Args, Value};

fn start(_: &mut (), ctx: &mut Ctx, args: &Args<'_>, reply: &mut Reply) -> Result<(), MethodError> {
    let file = PathBuf::from(args.text(0)?);
    let signals = (1..args.len())
        .map(|i| args.text(i).map(str::to_owned))
        .collect::<Result<Vec<_>, _>>()?;
    let path = modbot_record::control::start(file, signals, &mut || ctx.keep_alive())
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    reply.push(Value::Text(&path.display().to_string()));
    Ok(())
}

fn stop(_: &mut (), ctx: &mut Ctx, _: &Args<'_>, reply: &mut Reply) -> Result<(), MethodError> {
    let stopped = modbot_record::control::stop(&mut || ctx.keep_alive())
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    reply.push(Value::Text(&stopped.path.display().to_string()));
    reply.push(Value::I64(i64::try_from(stopped.rows).unwrap_or(i64::MAX)));
    Ok(())
}

fn main() -> std::process::ExitCode {
    let mut registry = modbot_components::builtin();
    modbot_record::register(&mut registry);
    modbot_grid_processes::host_process::host_main_with("modbot-recorder", registry, |module| {
        module.method("start", start).method("stop", stop)
    })
}

//! Commands: MoRC's skills. `command "name" { ... }` defines one, as the global function
//! `name`, which a program calls with a table of parameters (`ptp { q = { ... }, v = 0.5 }`):
//!
//! | field | |
//! |---|---|
//! | `doc` | what it does (`help` shows it) |
//! | `params` | `{ name = "what it is", ... }`: the parameters it takes; others are refused |
//! | `pre(p)` | the precondition: `false, "why"` (or an error) stops the program |
//! | `run(p)` | the execution: `{ assembly = "goto", args = { q = ... }, timeout = 60 }` — each arg is written to assembly data as `<assembly>.<name>` (where the assembly file reads it with `data`), then the assembly is prepared and switched to; without `assembly` the running one goes on. A command with an assembly is a motion (`motion = false` says it is not) |
//! | `done(p, r)` | the finish condition, asked until it holds (about every millisecond; on a stepped grid every [`STEP_S`] of grid time, at the same ticks in every run): `r.start_tick`, `r.tick`, `r.elapsed` (s of grid time since the start); without it, done at once |
//! | `eval(p, r)` | the evaluation, once done (`r.end_tick` too): a table of results, or `false, "why"` to stop the program |
//!
//! A run is kept in assembly data (command, assembly, where the program called it, start and
//! end tick, outcome, results), and each result also as `<command>.<name>` (the latest), so
//! later commands and programs read it with `data`. The call returns the results.
//!
//! A command stops the program with `file:line: command: why` (the line that called it) when
//! its precondition or evaluation fails, when it does not finish within `timeout` seconds of
//! grid time, when its assembly cannot be switched to or faults (a monitor's breach), and on
//! Ctrl-C.
//!
//! Nothing pretends to move: a motion is refused while the robot is not operational (a safe
//! stop, a drive fault: the bus bridge's robot state says why and since when), and one during
//! which the robot left operational fails with the cause, whatever its finish condition says.
//! A robot whose drives are still being enabled (disabled, no stop) is given
//! [`ENABLING`] to become operational first.

use std::time::{Duration, Instant};

use mlua::{Function, Lua, MultiValue, Table, Value};

use modbot_bus::RobotState;
use modbot_data::Run;
use modbot_ipc_schema::OwnedValue;
use modbot_system::sandbox::{self, from_lua, to_lua};

use super::session::{fail, fail_here, CommandInfo, Shared};
use super::{ProgramError, ScriptError};

/// The fields of a command's definition.
const FIELDS: &[&str] = &["doc", "params", "pre", "run", "done", "eval"];
/// Names a command may not take: the program's own functions.
const RESERVED: &[&str] = &[
    "command",
    "read",
    "call",
    "data",
    "require",
    "help",
    "absolute",
    "recorded",
    "plot",
    "robot_state",
    "robot_reset",
];
/// How long a command may run when its `run` does not say, s of grid time.
const DEFAULT_TIMEOUT_S: f64 = 60.0;
/// How often the finish condition is asked.
const POLL: Duration = Duration::from_millis(1);
/// On a stepped grid (a gated lockstep grid the program runs tick by tick, see
/// `SystemRobot`), how far the grid runs between two askings of the finish condition, s of
/// grid time: 10 ticks at 1 kHz (it divides the 2 s of a `wait` exactly).
const STEP_S: f64 = 0.01;
/// How often the coordinator is asked whether the assembly faulted.
const FAULT_POLL: Duration = Duration::from_millis(100);
/// A grid that has not ticked for this long (wall time) is not running.
const STALLED: Duration = Duration::from_secs(30);
/// How long a motion waits for a robot whose drives are being enabled (wall time).
pub(crate) const ENABLING: Duration = Duration::from_secs(2);

/// The registry name of the metatable of a command's results (the REPL does not print them
/// again: the run was reported).
pub(crate) const RESULTS_META: &str = "modbot.results";

/// `command "name"`, which returns the function that takes the definition.
pub(crate) fn command_fn(lua: &Lua, shared: &Shared) -> mlua::Result<Function> {
    let meta = lua.create_table()?;
    meta.raw_set("__name", "command results")?;
    lua.set_named_registry_value(RESULTS_META, meta)?;
    let shared = shared.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let name = match args.front() {
            Some(Value::String(s)) => s.to_string_lossy(),
            _ => {
                let why = "command takes a name, as in command \"square\" { run = ... }";
                return Err(fail_here(lua, &shared, why));
            }
        };
        let identifier = name
            .bytes()
            .enumerate()
            .all(|(i, b)| b.is_ascii_lowercase() || b == b'_' || (i > 0 && b.is_ascii_digit()));
        if name.is_empty() || name.len() > 32 || !identifier || RESERVED.contains(&name.as_str())
        {
            let why = format!(
                "command \"{name}\": a command's name is 1 to 32 characters of a-z, 0-9 and _, \
                 not starting with a digit, and none of {}",
                RESERVED.join(", ")
            );
            return Err(fail_here(lua, &shared, why));
        }
        let origin = sandbox::caller(lua).map_or("modbot library".into(), |(f, l)| format!("{f}:{l}"));
        let shared = shared.clone();
        lua.create_function(move |lua, args: MultiValue| {
            let Some(Value::Table(def)) = args.front().cloned() else {
                let why = format!("command \"{name}\" takes a table: command \"{name}\" {{ run = function(p) ... end }}");
                return Err(fail_here(lua, &shared, why));
            };
            let info = describe(&name, &def, &origin).map_err(|m| fail_here(lua, &shared, m))?;
            {
                let mut s = shared.borrow_mut();
                s.commands.retain(|c| c.name != name);
                s.commands.push(info);
                s.commands.sort_by(|a, b| a.name.cmp(&b.name));
            }
            let (shared, command) = (shared.clone(), name.clone());
            let f = lua.create_function(move |lua, args: MultiValue| {
                execute(lua, &shared, &command, &def, args)
            })?;
            lua.globals().raw_set(name.as_str(), f)
        })
    })
}

/// Checks a definition's fields; what `help` shows of it.
fn describe(name: &str, def: &Table, origin: &str) -> Result<CommandInfo, ScriptError> {
    let lua_failed = |e: mlua::Error| ScriptError::Definition {
        command: name.to_owned(),
        why: e.to_string(),
    };
    let mut doc = String::new();
    let mut params = Vec::new();
    for pair in def.pairs::<Value, Value>() {
        let (key, value) = pair.map_err(lua_failed)?;
        let key = match key {
            Value::String(s) => s.to_string_lossy(),
            other => {
                return Err(ScriptError::FieldName {
                    command: name.to_owned(),
                    found: other.type_name(),
                })
            }
        };
        let wrong = |expected: &'static str| ScriptError::FieldKind {
            command: name.to_owned(),
            field: key.clone(),
            expected,
            found: value.type_name(),
        };
        match (key.as_str(), &value) {
            ("doc", Value::String(s)) => doc = s.to_string_lossy(),
            ("doc", _) => return Err(wrong("a text")),
            ("params", Value::Table(t)) => {
                for pair in t.pairs::<Value, Value>() {
                    match pair.map_err(lua_failed)? {
                        (Value::String(k), Value::String(v)) => {
                            params.push((k.to_string_lossy(), v.to_string_lossy()))
                        }
                        _ => return Err(wrong("a table of name = \"what it is\"")),
                    }
                }
            }
            ("params", _) => return Err(wrong("a table of name = \"what it is\"")),
            ("pre" | "run" | "done" | "eval", Value::Function(_)) => {}
            ("pre" | "run" | "done" | "eval", _) => return Err(wrong("a function")),
            _ => {
                return Err(ScriptError::UnknownField {
                    command: name.to_owned(),
                    field: key,
                    expected: FIELDS.join(", "),
                })
            }
        }
    }
    params.sort();
    Ok(CommandInfo {
        name: name.to_owned(),
        doc,
        params,
        origin: origin.to_owned(),
    })
}

/// One run of a command: where it was called, and what it did so far.
struct Call<'a> {
    shared: &'a Shared,
    name: &'a str,
    file: String,
    line: u32,
    run: Run,
}

impl Call<'_> {
    /// Stops the program: `file:line: command: why`.
    fn fail(&self, why: impl std::fmt::Display) -> mlua::Error {
        let message = format!("{}: {why}", self.name);
        fail(
            self.shared,
            ProgramError::new(&self.file, Some(self.line), message),
        )
    }

    /// The robot's state when it matters for a motion: `None` for a system without a bus.
    fn robot_state(&self) -> mlua::Result<Option<RobotState>> {
        let state = self.shared.borrow_mut().robot.robot_state();
        state.map_err(|e| self.fail(e))
    }

    /// Refuses a motion while the robot is not operational (waiting [`ENABLING`] for drives
    /// being enabled); `Ok(false)`: the system has no bus, nothing to look at.
    fn require_operational(&self) -> mlua::Result<bool> {
        let until = Instant::now() + ENABLING;
        loop {
            let Some(state) = self.robot_state()? else {
                return Ok(false);
            };
            match state {
                RobotState::Operational { .. } => return Ok(true),
                RobotState::Disabled { .. } if Instant::now() < until => self.wait_a_little()?,
                other => return Err(self.fail(self.not_operational("is", &other))),
            }
        }
    }

    /// Lets time pass before the next look: on a stepped grid the grid runs [`STEP_S`] on,
    /// else a moment of wall time.
    fn wait_a_little(&self) -> mlua::Result<()> {
        let mut shared = self.shared.borrow_mut();
        if !shared.robot.stepped() {
            drop(shared);
            std::thread::sleep(POLL);
            return Ok(());
        }
        let stepped = shared.robot.base_period_s().and_then(|dt| {
            let tick = shared.robot.tick()?;
            shared.robot.run_to(tick + stride(dt))
        });
        drop(shared);
        stepped.map(|_| ()).map_err(|e| self.fail(e))
    }

    /// Fails a motion that began at tick `start` if the robot has left operational since.
    fn still_operational(&self, start: u64) -> mlua::Result<()> {
        match self.robot_state()? {
            Some(RobotState::Operational { since_tick }) if since_tick <= start => Ok(()),
            Some(state) => Err(self
                .fail(self.not_operational("left operational during the motion: it is", &state))),
            None => Ok(()),
        }
    }

    fn not_operational(&self, verb: &str, state: &RobotState) -> String {
        let domain = self.shared.borrow().robot.domain().to_owned();
        let what = match state {
            RobotState::Disabled { since_tick } => {
                format!("disabled since tick {since_tick} (not every drive is enabled)")
            }
            RobotState::Operational { since_tick } => {
                format!("operational again since tick {since_tick}, after a stop")
            }
            RobotState::SafeStop { .. } | RobotState::Fault { .. } => format!("in {state}"),
        };
        format!("the robot {verb} {what}; `modbot robot reset --domain {domain}` (or `reset {{}}`) brings it back")
    }

    /// A hook's error, as the program's failure at the line that called the command, with
    /// where in the hook it happened (a library's line; not the command library's, which the
    /// program cannot change): a stop recorded in it (a `read` that failed, Ctrl-C) or a Lua
    /// error.
    fn hook_failed(&self, stage: &str, e: mlua::Error) -> mlua::Error {
        let recorded = self.shared.borrow_mut().failure.take();
        let (file, line, message) = match recorded {
            Some(f) => (Some(f.file), f.line, f.message),
            None => sandbox::position(&e, super::session::WHAT),
        };
        let at = match (file, line) {
            (Some(f), Some(l)) if !f.is_empty() && f != super::session::LIBRARY_NAME => {
                format!("{f}:{l}: ")
            }
            _ => String::new(),
        };
        self.fail(format!("{stage}: {at}{message}"))
    }
}

/// Ticks of [`STEP_S`] at a base period of `dt` s (at least one).
fn stride(dt: f64) -> u64 {
    ((STEP_S / dt).round() as u64).max(1)
}

/// Runs command `name` (definition `def`) with the parameters in `args`.
fn execute(
    lua: &Lua,
    shared: &Shared,
    name: &str,
    def: &Table,
    args: MultiValue,
) -> mlua::Result<Value> {
    let (file, line) = sandbox::caller(lua).unwrap_or_default();
    let origin = format!("{file}:{line}");
    let mut call = Call {
        shared,
        name,
        file,
        line,
        run: Run {
            command: name.to_owned(),
            assembly: String::new(),
            origin,
            start_tick: 0,
            end_tick: 0,
            outcome: String::new(),
            values: Vec::new(),
        },
    };
    let result = execute_call(lua, &mut call, def, args);
    if result.is_err() {
        // Kept with why it failed, as far as it went.
        let why = shared
            .borrow()
            .failure
            .as_ref()
            .map_or_else(|| "failed".to_owned(), |f| f.message.clone());
        call.run.outcome = format!("failed: {why}");
        if let Err(e) = shared.borrow().store.add_run(&call.run) {
            tracing::warn!("the failed run was not kept: {e}");
        }
    }
    result
}

fn execute_call(
    lua: &Lua,
    call: &mut Call<'_>,
    def: &Table,
    args: MultiValue,
) -> mlua::Result<Value> {
    let shared = call.shared;
    let p = match args.front() {
        None | Some(Value::Nil) => lua.create_table()?,
        Some(Value::Table(t)) => t.clone(),
        Some(other) => {
            return Err(call.fail(format!(
                "takes a table of parameters ({}{{ ... }}), not a {}",
                call.name,
                other.type_name()
            )))
        }
    };
    check_params(call, def, &p)?;
    shared.borrow_mut().spent = 0;

    // The precondition.
    if let Some(pre) = def.raw_get::<Option<Function>>("pre")? {
        let verdict = pre
            .call::<MultiValue>(p.clone())
            .map_err(|e| call.hook_failed("precondition", e))?;
        if matches!(verdict.front(), Some(Value::Boolean(false))) {
            let why = match verdict.get(1) {
                Some(Value::String(s)) => s.to_string_lossy(),
                _ => "it does not hold".to_owned(),
            };
            return Err(call.fail(format!("precondition failed: {why}")));
        }
    }

    // The execution: its assembly, with its parameters in assembly data.
    let plan = match def.raw_get::<Option<Function>>("run")? {
        Some(run) => match run
            .call::<Value>(p.clone())
            .map_err(|e| call.hook_failed("run", e))?
        {
            Value::Table(t) => Some(t),
            Value::Nil => None,
            other => {
                return Err(call.fail(format!(
                    "run must return a table, not a {}",
                    other.type_name()
                )))
            }
        },
        None => None,
    };
    let field =
        |k: &str| -> mlua::Result<Value> { plan.as_ref().map_or(Ok(Value::Nil), |t| t.raw_get(k)) };
    let timeout = match field("timeout")? {
        Value::Nil => DEFAULT_TIMEOUT_S,
        Value::Integer(i) if i > 0 => i as f64,
        Value::Number(x) if x > 0.0 => x,
        other => {
            return Err(call.fail(format!(
                "run's timeout must be a positive number of seconds, not {other:?}"
            )))
        }
    };
    let assembly = match field("assembly")? {
        Value::Nil => None,
        Value::String(s) => Some(s.to_string_lossy()),
        other => {
            return Err(call.fail(format!(
                "run's assembly must be a name, not a {}",
                other.type_name()
            )))
        }
    };
    let motion = assembly.is_some() && !matches!(field("motion")?, Value::Boolean(false));
    let watched = motion && call.require_operational()?;
    let start = match &assembly {
        Some(assembly) => {
            let mut entries = Vec::new();
            if let Value::Table(args) = field("args")? {
                for pair in args.pairs::<String, Value>() {
                    let (k, v) = pair.map_err(|e| call.fail(format!("run's args: {e}")))?;
                    let v =
                        from_lua(&v).map_err(|e| call.fail(format!("run's args: '{k}': {e}")))?;
                    entries.push((format!("{assembly}.{k}"), v));
                }
            }
            call.run.assembly = assembly.clone();
            let stored = shared.borrow().store.put_all(&entries);
            stored.map_err(|e| call.fail(e))?;
            let switched = shared.borrow_mut().robot.switch(assembly);
            let tick = switched.map_err(|e| call.fail(e))?;
            // Switched: a failure from now on leaves the robot holding (a switch that failed
            // left the running assembly as it was).
            shared.borrow_mut().moved = true;
            tick
        }
        None => {
            let tick = shared.borrow_mut().robot.tick();
            tick.map_err(|e| call.fail(e))?
        }
    };
    call.run.start_tick = start;

    // Until it is done.
    // Each borrow ends before a failure is recorded (which borrows again).
    let dt = shared.borrow_mut().robot.base_period_s();
    let dt = dt.map_err(|e| call.fail(e))?;
    let done = def.raw_get::<Option<Function>>("done")?;
    let r = lua.create_table()?;
    r.raw_set("start_tick", start)?;
    let (mut last_tick, mut ticked) = (start, Instant::now());
    let mut fault_asked = Instant::now();
    let end = loop {
        if shared.borrow().interrupt.is_set() {
            return Err(call.fail("interrupted (Ctrl-C)"));
        }
        let tick = shared.borrow_mut().robot.tick();
        let tick = tick.map_err(|e| call.fail(e))?;
        let elapsed = tick.saturating_sub(start) as f64 * dt;
        r.raw_set("tick", tick)?;
        r.raw_set("elapsed", elapsed)?;
        let finished = match &done {
            None => true,
            Some(f) => {
                shared.borrow_mut().spent = 0;
                let v = f
                    .call::<Value>((p.clone(), r.clone()))
                    .map_err(|e| call.hook_failed("done", e))?;
                !matches!(v, Value::Nil | Value::Boolean(false))
            }
        };
        if watched {
            call.still_operational(start)?;
        }
        if finished {
            // The condition was read after the tick: the grid's tick when it held.
            let now = shared.borrow_mut().robot.tick();
            let now = now.map_err(|e| call.fail(e))?;
            if watched {
                call.still_operational(start)?;
            }
            break now.max(tick);
        }
        if elapsed > timeout {
            return Err(call.fail(format!(
                "not done within {timeout} s of grid time (ticks {start} to {tick})"
            )));
        }
        if tick != last_tick {
            (last_tick, ticked) = (tick, Instant::now());
        } else if ticked.elapsed() > STALLED {
            return Err(call.fail(format!(
                "the grid has not ticked for {} s (tick {tick})",
                STALLED.as_secs()
            )));
        }
        if fault_asked.elapsed() >= FAULT_POLL {
            fault_asked = Instant::now();
            let fault = shared.borrow_mut().robot.fault();
            let fault = fault.map_err(|e| call.fail(e))?;
            if let Some(why) = fault {
                return Err(call.fail(format!("the assembly faulted: {why}")));
            }
        }
        call.wait_a_little()?;
    };
    call.run.end_tick = end;
    r.raw_set("end_tick", end)?;

    // The evaluation.
    let results = lua.create_table()?;
    if let Some(eval) = def.raw_get::<Option<Function>>("eval")? {
        shared.borrow_mut().spent = 0;
        let verdict = eval
            .call::<MultiValue>((p, r))
            .map_err(|e| call.hook_failed("evaluation", e))?;
        match verdict.front() {
            None | Some(Value::Nil) => {}
            Some(Value::Boolean(false)) => {
                let why = match verdict.get(1) {
                    Some(Value::String(s)) => s.to_string_lossy(),
                    _ => "it says the command failed".to_owned(),
                };
                return Err(call.fail(format!("evaluation failed: {why}")));
            }
            Some(Value::Table(t)) => {
                let mut values = Vec::new();
                for pair in t.pairs::<String, Value>() {
                    let (k, v) = pair.map_err(|e| call.fail(format!("evaluation: {e}")))?;
                    let value = from_lua(&v)
                        .map_err(|e| call.fail(format!("evaluation: result '{k}': {e}")))?;
                    values.push((k, value));
                }
                values.sort_by(|a, b| a.0.cmp(&b.0));
                call.run.values = values;
            }
            Some(other) => {
                return Err(call.fail(format!(
                    "eval must return a table of results (or false, \"why\"), not a {}",
                    other.type_name()
                )))
            }
        }
    }
    call.run.outcome = "ok".into();
    keep(call)?;
    for (k, v) in &call.run.values {
        results.raw_set(k.as_str(), to_lua(lua, v)?)?;
    }
    results.set_metatable(Some(lua.named_registry_value::<Table>(RESULTS_META)?))?;
    Ok(Value::Table(results))
}

/// Refuses parameters the command does not declare (when it declares them).
fn check_params(call: &Call<'_>, def: &Table, p: &Table) -> mlua::Result<()> {
    let Some(declared) = def.raw_get::<Option<Table>>("params")? else {
        return Ok(());
    };
    for pair in p.pairs::<Value, Value>() {
        let (key, _) = pair?;
        let known = match &key {
            Value::String(s) => declared.contains_key(s.clone())?,
            _ => false,
        };
        if !known {
            let mut names: Vec<String> = declared
                .pairs::<String, Value>()
                .filter_map(|kv| kv.ok().map(|(k, _)| k))
                .collect();
            names.sort();
            let takes = if names.is_empty() {
                "none".to_owned()
            } else {
                names.join(", ")
            };
            let shown = match &key {
                Value::String(s) => s.to_string_lossy(),
                other => format!("{other:?}"),
            };
            return Err(call.fail(format!("unknown parameter '{shown}' (it takes {takes})")));
        }
    }
    Ok(())
}

/// Keeps a finished run in assembly data, and each result as `<command>.<name>`; reports it.
fn keep(call: &mut Call<'_>) -> mlua::Result<()> {
    let shared = call.shared;
    let latest: Vec<(String, OwnedValue)> = call
        .run
        .values
        .iter()
        .map(|(k, v)| (format!("{}.{k}", call.name), v.clone()))
        .collect();
    let kept = {
        let s = shared.borrow();
        s.store
            .add_run(&call.run)
            .and_then(|n| s.store.put_all(&latest).map(|()| n))
    };
    let number = kept.map_err(|e| call.fail(e))?;
    let line = format!("run {number}: {}", call.run);
    (shared.borrow_mut().report)(&line);
    Ok(())
}

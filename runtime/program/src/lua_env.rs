//! The program's Lua: the sandbox of system descriptions (`modbot_system::sandbox`: no `os`,
//! `io`, `load`; no patterns; memory and instruction limits — here the instruction budget is
//! per command: what a program computes between two robot commands) with the program's
//! functions:
//!
//! | function | |
//! |---|---|
//! | `command "name" { doc, params, pre, run, done, eval }` | defines a command (see `command`) |
//! | `read("module.item")` | a module's blackboard item, or a component's output (`read("settle.settled")`) |
//! | `call("module.method", ...)` | calls a method; returns its answer's values |
//! | `data("key")`, `data("key", value)` | reads (nil when unset) or writes assembly data |
//! | `require "name"` | runs the library `name.lua` next to the program once; returns what it returned |
//! | `absolute`, `recorded`, `plot` | a program's recordings and plots (see `recordings`) |
//!
//! A failure in any of them (an unknown module, a bad argument) stops the program with
//! `file:line: why`, as a failed command does.

use mlua::{Lua, MultiValue, Value};

use modbot_system::sandbox::{self, from_lua, to_lua, INSTRUCTION_LIMIT};

use super::session::{fail, fail_here, Shared, WHAT};
use super::{ProgramError, ScriptError};

/// The Lua state of an interpreter, with its functions.
pub(crate) fn open(shared: &Shared) -> mlua::Result<Lua> {
    let stopped = shared.clone();
    let lua = sandbox::open(WHAT, move || stopped.borrow().failure.is_some())?;
    arm_budget(&lua, shared);
    let globals = lua.globals();
    globals.raw_set("read", read_fn(&lua, shared)?)?;
    globals.raw_set("call", call_fn(&lua, shared)?)?;
    globals.raw_set("data", data_fn(&lua, shared)?)?;
    globals.raw_set("robot_state", robot_state_fn(&lua, shared)?)?;
    globals.raw_set("robot_reset", robot_reset_fn(&lua, shared)?)?;
    globals.raw_set("require", require_fn(&lua, shared)?)?;
    globals.raw_set("command", super::command::command_fn(&lua, shared)?)?;
    super::recordings::register(&lua, &globals, shared)?;
    Ok(lua)
}

/// (Re)arms the instruction hook: [`INSTRUCTION_LIMIT`] instructions between two commands,
/// and a stop asked for (Ctrl-C) stops the script at once.
pub(crate) fn arm_budget(lua: &Lua, shared: &Shared) {
    let counter = shared.clone();
    sandbox::set_budget(lua, move |lua, spent| {
        let mut s = counter.borrow_mut();
        s.spent += spent;
        let why = if s.interrupt.is_set() {
            "interrupted (Ctrl-C)".to_owned()
        } else if s.spent > INSTRUCTION_LIMIT {
            format!("the program computed too long between two commands (more than {INSTRUCTION_LIMIT} Lua instructions)")
        } else {
            return true;
        };
        if s.failure.is_none() {
            let (file, line) = sandbox::current(lua).unwrap_or_default();
            s.failure = Some(ProgramError::new(&file, Some(line), why));
        }
        false
    });
}

/// The one text argument of `name(...)`.
fn text_arg(
    args: &MultiValue,
    function: &'static str,
    example: &'static str,
) -> Result<String, ScriptError> {
    match args.front() {
        Some(Value::String(s)) => Ok(s.to_string_lossy()),
        found => Err(ScriptError::NotAText {
            function,
            example,
            found: found.map(Value::type_name),
        }),
    }
}

fn read_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let what = text_arg(&args, "read", "read(\"robot.link_position\")")
            .map_err(|m| fail_here(lua, &shared, m))?;
        let value = shared.borrow_mut().robot.read(&what);
        match value {
            Ok(v) => to_lua(lua, &v),
            Err(e) => Err(fail_here(lua, &shared, e.to_string())),
        }
    })
}

fn call_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let target = text_arg(&args, "call", "call(\"host_bus.block\", 2, true)")
            .map_err(|m| fail_here(lua, &shared, m))?;
        let values = args
            .iter()
            .skip(1)
            .enumerate()
            .map(|(i, v)| {
                from_lua(v).map_err(|e| format!("call(\"{target}\"): argument {}: {e}", i + 1))
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|m| fail_here(lua, &shared, m))?;
        let answer = shared.borrow_mut().robot.call(&target, &values);
        let answer = answer.map_err(|e| fail_here(lua, &shared, e.to_string()))?;
        answer
            .iter()
            .map(|v| to_lua(lua, v))
            .collect::<mlua::Result<MultiValue>>()
    })
}

/// `robot_state()`: the robot's state as a table (`kind`: disabled, operational, safe_stop or
/// fault; `since_tick`; `cause`; for a fault `drive` and `error_code`), nil without a bus.
fn robot_state_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    lua.create_function(move |lua, ()| {
        let state = shared.borrow_mut().robot.robot_state();
        let Some(state) = state.map_err(|e| fail_here(lua, &shared, e.to_string()))? else {
            return Ok(mlua::Value::Nil);
        };
        let t = lua.create_table()?;
        t.raw_set("kind", state.kind())?;
        t.raw_set("since_tick", state.since_tick())?;
        t.raw_set("cause", state.cause())?;
        if let modbot_bus::RobotState::Fault {
            drive, error_code, ..
        } = state
        {
            t.raw_set("drive", drive)?;
            t.raw_set("error_code", error_code)?;
        }
        Ok(mlua::Value::Table(t))
    })
}

/// `robot_reset()`: an operator's reset (the library's `reset {}`); what it did, or the
/// program stops with why it was refused.
fn robot_reset_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    lua.create_function(move |lua, ()| {
        let done = shared.borrow_mut().robot.reset();
        done.map_err(|e| fail_here(lua, &shared, format!("reset refused: {e}")))
    })
}

fn data_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let key =
            text_arg(&args, "data", "data(\"goto.q\")").map_err(|m| fail_here(lua, &shared, m))?;
        match args.get(1) {
            None => {
                let value = shared.borrow().store.get(&key);
                match value.map_err(|e| fail_here(lua, &shared, e.to_string()))? {
                    Some(v) => to_lua(lua, &v),
                    None => Ok(Value::Nil),
                }
            }
            Some(Value::Nil) => {
                let removed = shared.borrow().store.remove(&key);
                removed.map_err(|e| fail_here(lua, &shared, e.to_string()))?;
                Ok(Value::Nil)
            }
            Some(v) => {
                let value = from_lua(v)
                    .map_err(|e| fail_here(lua, &shared, format!("data(\"{key}\", ...): {e}")))?;
                let put = shared.borrow().store.put(&key, &value);
                put.map_err(|e| fail_here(lua, &shared, e.to_string()))?;
                Ok(Value::Nil)
            }
        }
    })
}

/// `require "name"`: the library `<program dir>/name.lua`, run once in the program's sandbox;
/// what it returned (true when nothing).
fn require_fn(lua: &Lua, shared: &Shared) -> mlua::Result<mlua::Function> {
    let shared = shared.clone();
    let loaded = lua.create_table()?;
    lua.create_function(move |lua, args: MultiValue| {
        let name = text_arg(&args, "require", "require \"moves\"")
            .map_err(|m| fail_here(lua, &shared, m))?;
        let plain = !name.is_empty()
            && name.len() <= 64
            && name
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_');
        if !plain {
            let why = format!(
                "require \"{name}\": a library is named by 1 to 64 characters of a-z, 0-9 and _ \
                 (the file name.lua next to the program)"
            );
            return Err(fail_here(lua, &shared, why));
        }
        if let Some(v) = loaded.raw_get::<Option<Value>>(name.as_str())? {
            return Ok(v);
        }
        let path = shared.borrow().dir.join(format!("{name}.lua"));
        let source = std::fs::read_to_string(&path).map_err(|e| {
            fail_here(
                lua,
                &shared,
                format!("require \"{name}\": cannot read {}: {e}", path.display()),
            )
        })?;
        let chunk = path.display().to_string();
        let result = lua
            .load(&source)
            .set_name(format!("={chunk}"))
            .set_mode(mlua::chunk::ChunkMode::Text)
            .eval::<Value>();
        let value = match result {
            Ok(Value::Nil) => Value::Boolean(true),
            Ok(v) => v,
            Err(e) => {
                if shared.borrow().failure.is_some() {
                    return Err(e);
                }
                let (file, line, message) = sandbox::position(&e, WHAT);
                let file = file.unwrap_or(chunk);
                return Err(fail(&shared, ProgramError::new(&file, line, message)));
            }
        };
        loaded.raw_set(name.as_str(), value.clone())?;
        shared.borrow_mut().required.push(name);
        Ok(value)
    })
}

//! The Lua sandbox every modbot Lua file runs in: system descriptions, assembly files and
//! robot programs (`modbot-program`) — one set of limits, one way of naming `file:line`.
//!
//! - only the `table`, `string`, `math`, `utf8` and `coroutine` libraries are loaded (no `os`,
//!   `io`, `package`, `debug`), and `load`, `loadfile`, `dofile`, `require` and
//!   `collectgarbage` are removed; binary chunks are refused (by the callers' `ChunkMode::Text`);
//! - memory is limited to [`MEMORY_LIMIT`]; an instruction hook ([`set_budget`]) counts every
//!   [`HOOK_EVERY`] instructions against a budget its owner keeps (a description:
//!   [`INSTRUCTION_LIMIT`] in all; a program: as many between two robot commands), and past
//!   it every instruction fails;
//! - `pcall`, `xpcall`, `coroutine.resume` and `coroutine.close` are wrapped so that they cannot
//!   swallow a stop: once the owner says the script stopped (a failure, the budget, Ctrl-C),
//!   every protected call re-raises, and the script unwinds to the end;
//! - `setmetatable` refuses metatables with `__gc`: Lua runs finalizers with hooks disabled, so
//!   a finalizer could loop forever, out of the instruction limit's reach;
//! - Lua patterns are not available (`string.match`, `gmatch`, `gsub`, and `string.find`
//!   without `plain = true` raise an error): the matcher runs in C, where the instruction
//!   limit cannot stop a pattern that backtracks for hours.

use mlua::{HookTriggers, Lua, LuaOptions, StdLib, Value, VmState};

use modbot_ipc_schema::OwnedValue;

/// The most memory a Lua state may use.
pub const MEMORY_LIMIT: usize = 16 << 20;
/// The most Lua instructions a description may execute (and a program between two commands).
pub const INSTRUCTION_LIMIT: u64 = 10_000_000;
/// How often the instruction hook runs.
pub const HOOK_EVERY: u32 = 1000;

/// The Lua globals that would reach outside the sandbox (or defeat its limits).
const REMOVED_GLOBALS: &[&str] = &["load", "loadfile", "dofile", "require", "collectgarbage"];

/// The chunk name of [`PRELUDE`]: frames of it are skipped by [`caller_line`].
pub const PRELUDE_NAME: &str = "=modbot prelude";

/// Runs before the script: protected calls re-raise once the script has stopped.
const PRELUDE: &str = r#"
local failed_check, what = ...
local pack, unpack, raw_pcall = table.pack, table.unpack, pcall
local function guarded(f)
  return function(...)
    local results = pack(f(...))
    failed_check()
    return unpack(results, 1, results.n)
  end
end
pcall = guarded(pcall)
xpcall = guarded(xpcall)
coroutine.resume = guarded(coroutine.resume)
coroutine.close = guarded(coroutine.close)
local raw_setmetatable, rawget, type, error = setmetatable, rawget, type, error
setmetatable = function(t, mt)
  if type(mt) == "table" and rawget(mt, "__gc") ~= nil then
    error("__gc metamethods are not available in " .. what, 2)
  end
  -- A refusal (a protected metatable, a bad argument) names the script's line, not ours.
  local ok, result = raw_pcall(raw_setmetatable, t, mt)
  if not ok then
    error(result, 2)
  end
  return result
end
-- Lua's pattern matching runs in C, out of the instruction limit's reach (a pattern can
-- backtrack for hours on a short string): a script finds plain text only.
local raw_find = string.find
local refusal = " is not available in " .. what .. " (patterns run out of the " ..
  "instruction limit's reach): use string.find(s, text, 1, true)"
string.find = function(s, text, init, plain)
  if plain ~= true then
    error("string.find with a pattern" .. refusal, 2)
  end
  return raw_find(s, text, init, true)
end
for _, name in ipairs({ "match", "gmatch", "gsub" }) do
  string[name] = function()
    error("string." .. name .. refusal, 2)
  end
end
"#;

/// A Lua state with the safe libraries, the memory limit and the guarded protected calls.
/// `what` names the kind of script in refusals ("a system description"); `stopped` says
/// whether the script has stopped (protected calls then re-raise [`stop`]).
pub fn open(what: &str, stopped: impl Fn() -> bool + 'static) -> mlua::Result<Lua> {
    let libs = StdLib::TABLE | StdLib::STRING | StdLib::MATH | StdLib::UTF8 | StdLib::COROUTINE;
    let lua = Lua::new_with(libs, LuaOptions::default())?;
    lua.set_memory_limit(MEMORY_LIMIT)?;
    let globals = lua.globals();
    for name in REMOVED_GLOBALS {
        globals.raw_set(*name, Value::Nil)?;
    }
    let failed_check =
        lua.create_function(move |_, ()| if stopped() { Err(stop()) } else { Ok(()) })?;
    lua.load(PRELUDE)
        .set_name(PRELUDE_NAME)
        .call::<()>((failed_check, what))?;
    Ok(lua)
}

/// Arms the instruction hook: every [`HOOK_EVERY`] instructions it calls `spend` with that
/// many; when `spend` says the budget is gone (false), that instruction and every one after it
/// fail with [`stop`] (the owner records why), until the hook is armed again.
pub fn set_budget(lua: &Lua, spend: impl FnMut(&Lua, u64) -> bool + 'static) {
    let spend = std::cell::RefCell::new(spend);
    lua.set_global_hook(
        HookTriggers::new().every_nth_instruction(HOOK_EVERY),
        move |lua, _| {
            let within = match spend.try_borrow_mut() {
                Ok(mut spend) => spend(lua, u64::from(HOOK_EVERY)),
                // Only when `spend` itself ran Lua, which it must not: count nothing.
                Err(_) => true,
            };
            if within {
                return Ok(VmState::Continue);
            }
            // From now on every instruction fails, so code that swallows errors (a finalizer,
            // whose errors Lua only turns into warnings) cannot keep the script alive.
            lua.set_global_hook(HookTriggers::new().every_nth_instruction(1), |_, _| {
                Err(stop())
            })?;
            Err(stop())
        },
    )
    .unwrap_or_else(|e| tracing::error!("the instruction hook was not set: {e}"));
}

/// The Lua error that unwinds a stopped script (its message is never shown: the owner's
/// record of why it stopped is).
pub fn stop() -> mlua::Error {
    mlua::Error::runtime("the script stopped")
}

/// The current line of the nearest Lua function on the stack above the running callback
/// (skipping C functions such as `pcall`, and the prelude's wrappers); 0 if there is none.
pub fn caller_line(lua: &Lua) -> u32 {
    caller(lua).map_or(0, |(_, line)| line)
}

/// Like [`caller_line`], with the chunk's name (`prog.lua`, `lib.lua`; `=` taken off).
pub fn caller(lua: &Lua) -> Option<(String, u32)> {
    lua_frame(lua, 1)
}

/// The chunk and line of the Lua function running now (in a hook: the one hooked).
pub fn current(lua: &Lua) -> Option<(String, u32)> {
    lua_frame(lua, 0)
}

/// The nearest Lua function's chunk and line from stack level `from` up.
fn lua_frame(lua: &Lua, from: usize) -> Option<(String, u32)> {
    for level in from..64 {
        let frame = lua.inspect_stack(level, |d| {
            let source = d.source().source.map(|s| s.into_owned());
            (source, d.current_line())
        });
        match frame {
            None => break,
            Some((source, Some(line))) if source.as_deref() != Some(PRELUDE_NAME) => {
                let name = source.unwrap_or_default();
                let name = name.strip_prefix('=').unwrap_or(&name).to_owned();
                return Some((name, u32::try_from(line).unwrap_or(u32::MAX)));
            }
            Some(_) => continue,
        }
    }
    None
}

/// A Lua error as (file, line, message), from Lua's `file:LINE: message` (any traceback cut
/// off); `what` names the script in the message of a memory error.
pub fn position(error: &mlua::Error, what: &str) -> (Option<String>, Option<u32>, String) {
    match error {
        mlua::Error::SyntaxError { message, .. } | mlua::Error::RuntimeError(message) => {
            split_position(message)
        }
        mlua::Error::MemoryError(_) => (
            None,
            None,
            format!(
                "{what} used too much memory (limit {} MiB)",
                MEMORY_LIMIT >> 20
            ),
        ),
        mlua::Error::CallbackError { cause, .. } => position(cause, what),
        mlua::Error::WithContext { cause, .. } => position(cause, what),
        other => (None, None, other.to_string()),
    }
}

/// Splits `chunk:LINE: message` (with any traceback cut off) into the chunk, the line and the
/// message.
pub fn split_position(text: &str) -> (Option<String>, Option<u32>, String) {
    let text = text
        .split_once("\nstack traceback:")
        .map_or(text, |(first, _)| first);
    for (colon, _) in text.match_indices(':') {
        let rest = &text[colon + 1..];
        let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
        if digits == 0 || rest.as_bytes().get(digits) != Some(&b':') {
            continue;
        }
        if let Ok(line) = rest[..digits].parse::<u32>() {
            let chunk = text[..colon].to_owned();
            return (
                Some(chunk),
                Some(line),
                rest[digits + 1..].trim_start().to_owned(),
            );
        }
    }
    (None, None, text.to_owned())
}

/// A modbot value as Lua sees it: a number, an integer, a boolean, a string (text and bytes),
/// a list of numbers (an f64 array).
pub fn to_lua(lua: &Lua, value: &OwnedValue) -> mlua::Result<Value> {
    Ok(match value {
        OwnedValue::F64(x) => Value::Number(*x),
        OwnedValue::I64(i) => Value::Integer(*i),
        OwnedValue::Bool(b) => Value::Boolean(*b),
        OwnedValue::Text(t) => Value::String(lua.create_string(t)?),
        OwnedValue::Bytes(b) => Value::String(lua.create_string(b)?),
        OwnedValue::F64s(xs) => Value::Table(lua.create_sequence_from(xs.iter().copied())?),
    })
}

/// A Lua value as a modbot value: numbers, integers, booleans, strings, and lists of numbers
/// (an f64 array; empty tables too). Anything else is refused, saying what it is.
pub fn from_lua(value: &Value) -> Result<OwnedValue, FromLuaError> {
    match value {
        Value::Number(x) => Ok(OwnedValue::F64(*x)),
        Value::Integer(i) => Ok(OwnedValue::I64(*i)),
        Value::Boolean(b) => Ok(OwnedValue::Bool(*b)),
        Value::String(s) => Ok(match s.to_str() {
            Ok(t) => OwnedValue::Text(t.to_owned()),
            Err(_) => OwnedValue::Bytes(s.as_bytes().to_vec()),
        }),
        Value::Table(t) => {
            let len = t.raw_len();
            let mut xs = Vec::with_capacity(len);
            for i in 1..=len {
                match t
                    .raw_get::<Value>(i)
                    .map_err(|e| FromLuaError::Lua(e.to_string()))?
                {
                    Value::Number(x) => xs.push(x),
                    Value::Integer(n) => xs.push(n as f64),
                    other => {
                        return Err(FromLuaError::NotANumber {
                            index: i,
                            found: other.type_name(),
                        })
                    }
                }
            }
            if t.pairs::<Value, Value>().count() != len {
                return Err(FromLuaError::Keys);
            }
            Ok(OwnedValue::F64s(xs))
        }
        other => Err(FromLuaError::NotAValue(other.type_name())),
    }
}

/// A Lua value that is not a modbot value.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FromLuaError {
    #[error("a list of numbers has a {found} at [{index}]")]
    NotANumber { index: usize, found: &'static str },
    #[error("a table with keys is not a value: use a list of numbers")]
    Keys,
    #[error("a {0} is not a value")]
    NotAValue(&'static str),
    /// Lua could not read the table.
    #[error("{0}")]
    Lua(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn position_is_split_from_a_lua_message() {
        let sut = split_position("robot.lua:12: attempt to call a nil value");
        assert_eq!(
            sut,
            (
                Some("robot.lua".to_owned()),
                Some(12),
                "attempt to call a nil value".to_owned()
            )
        );
    }

    #[test]
    fn traceback_is_cut_and_a_message_without_position_is_kept() {
        let sut = split_position("boom\nstack traceback:\n\t[C]: in ?");
        assert_eq!(sut, (None, None, "boom".to_owned()));
    }

    #[test]
    fn values_go_to_lua_and_back_with_their_kinds() {
        let lua = open("a test", || false).unwrap();
        for v in [
            OwnedValue::F64(1.5),
            OwnedValue::I64(-3),
            OwnedValue::Bool(true),
            OwnedValue::Text("hi".into()),
            OwnedValue::F64s(vec![0.5, -1.0]),
        ] {
            let sut = from_lua(&to_lua(&lua, &v).unwrap()).unwrap();
            assert_eq!(sut, v);
        }
        let table = lua.load("return { a = 1 }").eval::<Value>().unwrap();
        assert!(from_lua(&table).is_err());
    }
}

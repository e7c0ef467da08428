//! The sandboxed evaluation of a description.
//!
//! The description is ordinary Lua with seven declaration functions added (`domain`,
//! `supervision`, `module`, `group`, and the grid's `grid`, `component` and `connect` from
//! `grid_decl`), the table `vars` of the variables given on the command line (`modbot up FILE
//! --var speed=2`: `vars.speed == "2"`; strings, read-only, empty when none were given), and
//! everything that reaches outside taken away:
//!
//! - only the `table`, `string`, `math`, `utf8` and `coroutine` libraries are loaded (no `os`,
//!   `io`, `package`, `debug`), and `load`, `loadfile`, `dofile`, `require` and
//!   `collectgarbage` are removed; binary chunks are refused;
//! - memory is limited to [`MEMORY_LIMIT`], and a hook stops the script after
//!   [`INSTRUCTION_LIMIT`] instructions (in every coroutine too); past the limit, every
//!   instruction fails;
//! - `pcall`, `xpcall`, `coroutine.resume` and `coroutine.close` are wrapped so that they cannot
//!   swallow the stop: once the description failed (a bad declaration, the instruction limit),
//!   every protected call re-raises, and the script unwinds to the end;
//! - `setmetatable` refuses metatables with `__gc`: Lua runs finalizers with hooks disabled, so
//!   a finalizer could loop forever, out of the instruction limit's reach;
//! - Lua patterns are not available (`string.match`, `gmatch`, `gsub`, and `string.find`
//!   without `plain = true` raise an error): the matcher runs in C, where the instruction
//!   limit cannot stop a pattern that backtracks for hours.
//!
//! Each declaration records the line of the Lua code that called it. The first failure is kept
//! with its line; a Lua syntax or runtime error is translated from Lua's `file:LINE: message`.

use mlua::chunk::ChunkMode;
use mlua::{HookTriggers, Lua, LuaOptions, MultiValue, StdLib, Value, VmState};

use super::decl::{self, Declarations};
use super::record::{caller_line, fail, given, one_arg, open_body, stop, Shared, PRELUDE_NAME};
use super::{grid_decl, record_decl};
use super::{DeclError, GroupSpec, SystemError};

/// The most memory a description may use.
pub(super) const MEMORY_LIMIT: usize = 16 << 20;
/// The most Lua instructions a description may execute.
pub(super) const INSTRUCTION_LIMIT: u64 = 10_000_000;
/// How often the instruction hook runs.
const HOOK_EVERY: u32 = 1000;
/// At most this many `module` declarations (addresses are 1 to 254) and `group` declarations.
const MAX_MODULES: usize = 254;
const MAX_GROUPS: usize = 1024;

/// The Lua globals that would reach outside the sandbox (or defeat its limits).
const REMOVED_GLOBALS: &[&str] = &["load", "loadfile", "dofile", "require", "collectgarbage"];

/// The chunk name of [`VARS`].
const VARS_NAME: &str = "=modbot vars";
/// Makes the global `vars`: a read-only view of the table of variables it is given. Writing to
/// it is an error at the line that writes; `pairs(vars)` lists the variables. (`rawset` could
/// still write to the empty proxy: read-only against mistakes, not against intent, which the
/// sandbox does not need.)
const VARS: &str = r#"
local given, next, error, tostring, setmetatable = ..., next, error, tostring, setmetatable
vars = setmetatable({}, {
  __index = given,
  __newindex = function(_, key)
    error("vars is read-only (vars." .. tostring(key) .. "): give variables with --var KEY=VALUE", 2)
  end,
  __pairs = function() return next, given, nil end,
  __metatable = false,
})
"#;

/// Runs before the description: protected calls re-raise once the description has failed.
const PRELUDE: &str = r#"
local failed_check, pack, unpack, raw_pcall = ..., table.pack, table.unpack, pcall
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
    error("__gc metamethods are not available in a system description", 2)
  end
  -- A refusal (a protected metatable, a bad argument) names the description's line, not ours.
  local ok, result = raw_pcall(raw_setmetatable, t, mt)
  if not ok then
    error(result, 2)
  end
  return result
end
-- Lua's pattern matching runs in C, out of the instruction limit's reach (a pattern can
-- backtrack for hours on a short string): a description finds plain text only.
local raw_find = string.find
local refusal = " is not available in a system description (patterns run out of the " ..
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

/// Evaluates `source` (called `file` in messages) with the variables `vars` (later entries
/// win over earlier ones with the same key) and returns what it declared.
pub(super) fn evaluate(
    file: &str,
    source: &str,
    vars: &[(String, String)],
) -> Result<Declarations, SystemError> {
    let record = Shared::default();
    let lua = sandbox(&record, vars).map_err(|e| {
        SystemError::new(file, None, format!("cannot prepare the Lua sandbox: {e}"))
    })?;
    let result = lua
        .load(source)
        .set_name(format!("={file}"))
        .set_mode(ChunkMode::Text)
        .exec();
    let mut record = std::mem::take(&mut *record.borrow_mut());
    // Closing the state runs pending finalizers (user code, still under the hook).
    drop(lua);
    if let Some((line, error)) = record.failure.take() {
        return Err(SystemError::caused(file, line, error));
    }
    result.map_err(|e| translate(file, &e))?;
    if let Some(body) = record.bodies.iter().find(|b| !b.given) {
        let example = match body.kind {
            "module" => "{ addr = ..., program = ... }",
            "component" => "{ type = ..., host = ... }",
            "component_type" => "{ program = ..., outputs = { \"y:f64\" } }",
            _ => "{ \"member\", ... }",
        };
        let error = DeclError::NoTable {
            kind: body.kind,
            name: body.name.clone(),
            example,
        };
        return Err(SystemError::caused(file, Some(body.line), error));
    }
    Ok(record.decls)
}

/// A Lua state with the safe libraries, the limits, the declaration functions and `vars`.
fn sandbox(record: &Shared, vars: &[(String, String)]) -> mlua::Result<Lua> {
    let libs = StdLib::TABLE | StdLib::STRING | StdLib::MATH | StdLib::UTF8 | StdLib::COROUTINE;
    let lua = Lua::new_with(libs, LuaOptions::default())?;
    lua.set_memory_limit(MEMORY_LIMIT)?;
    let globals = lua.globals();
    for name in REMOVED_GLOBALS {
        globals.raw_set(*name, Value::Nil)?;
    }
    globals.raw_set("domain", domain_fn(&lua, record)?)?;
    globals.raw_set("supervision", supervision_fn(&lua, record)?)?;
    globals.raw_set("module", module_fn(&lua, record)?)?;
    globals.raw_set("group", group_fn(&lua, record)?)?;
    grid_decl::register(&lua, &globals, record)?;
    record_decl::register(&lua, &globals, record)?;
    let failed = record.clone();
    let failed_check = lua.create_function(move |_, ()| {
        let stopped = failed.borrow().failure.is_some();
        if stopped {
            Err(stop())
        } else {
            Ok(())
        }
    })?;
    lua.load(PRELUDE)
        .set_name(PRELUDE_NAME)
        .call::<()>(failed_check)?;
    let given = lua.create_table()?;
    for (key, value) in vars {
        given.raw_set(key.as_str(), value.as_str())?;
    }
    lua.load(VARS).set_name(VARS_NAME).call::<()>(given)?;
    let counter = record.clone();
    lua.set_global_hook(
        HookTriggers::new().every_nth_instruction(HOOK_EVERY),
        move |lua, _| {
            {
                let mut record = counter.borrow_mut();
                record.instructions += u64::from(HOOK_EVERY);
                if record.instructions <= INSTRUCTION_LIMIT {
                    return Ok(VmState::Continue);
                }
                if record.failure.is_none() {
                    record.failure = Some((None, DeclError::InstructionLimit));
                }
            }
            // From now on every instruction fails, so code that swallows errors (a finalizer,
            // whose errors Lua only turns into warnings) cannot keep the script alive.
            lua.set_global_hook(HookTriggers::new().every_nth_instruction(1), |_, _| {
                Err(stop())
            })?;
            Err(stop())
        },
    )?;
    Ok(lua)
}

/// `domain "name"`.
fn domain_fn(lua: &Lua, record: &Shared) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let name = one_arg(&args, "domain \"robot\"")
            .and_then(decl::domain)
            .map_err(|m| fail(&record, line, m))?;
        let first = record.borrow().decls.domain.as_ref().map(|d| d.1);
        if let Some(first) = first {
            let what = "domain";
            return Err(fail(&record, line, DeclError::Duplicate { what, first }));
        }
        record.borrow_mut().decls.domain = Some((name, line));
        Ok(())
    })
}

/// `supervision { ... }`.
fn supervision_fn(lua: &Lua, record: &Shared) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let supervision = one_arg(&args, "supervision { heartbeat_timeout = 1 }")
            .and_then(decl::supervision)
            .map_err(|m| fail(&record, line, m))?;
        let first = record.borrow().decls.supervision.as_ref().map(|s| s.1);
        if let Some(first) = first {
            let what = "supervision";
            return Err(fail(&record, line, DeclError::Duplicate { what, first }));
        }
        record.borrow_mut().decls.supervision = Some((supervision, line));
        Ok(())
    })
}

/// `module "name"`, which returns the function that takes the module's table.
fn module_fn(lua: &Lua, record: &Shared) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let usage = "module \"sonar\" { addr = 2, program = \"modbot-sonar\" }";
        let name = one_arg(&args, usage)
            .and_then(|v| decl::name("module", v))
            .map_err(|m| fail(&record, line, m))?;
        let index = open_body(&record, "module", &name, line, MAX_MODULES)?;
        let record = record.clone();
        lua.create_function(move |lua, args: MultiValue| {
            given(&record, index);
            let module = one_arg(&args, usage)
                .and_then(|v| decl::module(lua, &name, line, v))
                .map_err(|m| fail(&record, line, m))?;
            record.borrow_mut().decls.modules.push(module);
            Ok(())
        })
    })
}

/// `group "name"`, which returns the function that takes the member list.
fn group_fn(lua: &Lua, record: &Shared) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let usage = "group \"sensors\" { \"sonar\", \"mobility\" }";
        let name = one_arg(&args, usage)
            .and_then(|v| decl::name("group", v))
            .map_err(|m| fail(&record, line, m))?;
        let index = open_body(&record, "group", &name, line, MAX_GROUPS)?;
        let record = record.clone();
        lua.create_function(move |_, args: MultiValue| {
            given(&record, index);
            let members = one_arg(&args, usage)
                .and_then(|v| decl::group_members(&name, v))
                .map_err(|m| fail(&record, line, m))?;
            record.borrow_mut().decls.groups.push(GroupSpec {
                name: name.clone(),
                members,
                line,
            });
            Ok(())
        })
    })
}

/// A Lua error as a [`SystemError`], with the line taken out of Lua's `file:LINE: message`.
fn translate(file: &str, error: &mlua::Error) -> SystemError {
    match error {
        mlua::Error::SyntaxError { message, .. } | mlua::Error::RuntimeError(message) => {
            let (line, message) = split_position(message);
            SystemError::new(file, line, message)
        }
        mlua::Error::MemoryError(_) => SystemError::new(
            file,
            None,
            format!(
                "the description used too much memory (limit {} MiB)",
                MEMORY_LIMIT >> 20
            ),
        ),
        mlua::Error::CallbackError { cause, .. } => translate(file, cause),
        mlua::Error::WithContext { cause, .. } => translate(file, cause),
        other => SystemError::new(file, None, other.to_string()),
    }
}

/// Splits `chunk:LINE: message` (with any traceback cut off) into the line and the message.
fn split_position(text: &str) -> (Option<u32>, String) {
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
            return (Some(line), rest[digits + 1..].trim_start().to_owned());
        }
    }
    (None, text.to_owned())
}

#[cfg(test)]
mod tests {
    use super::split_position;

    #[test]
    fn position_is_split_from_a_lua_message() {
        let sut = split_position("robot.lua:12: attempt to call a nil value");
        assert_eq!(sut, (Some(12), "attempt to call a nil value".to_owned()));
    }

    #[test]
    fn traceback_is_cut_and_a_message_without_position_is_kept() {
        let sut = split_position("boom\nstack traceback:\n\t[C]: in ?");
        assert_eq!(sut, (None, "boom".to_owned()));
    }
}

//! The sandboxed evaluation of a description.
//!
//! The description is ordinary Lua with seven declaration functions added (`domain`,
//! `supervision`, `module`, `group`, and the grid's `grid`, `component` and `connect` from
//! `grid_decl`), the table `vars` of the variables given on the command line (`modbot up FILE
//! --var speed=2`: `vars.speed == "2"`; strings, read-only, empty when none were given), and
//! everything that reaches outside taken away:
//!
//! the sandbox of [`super::sandbox`] (no `os`, `io`, `load`, `require`; no Lua patterns;
//! memory and instruction limits), with [`INSTRUCTION_LIMIT`] instructions for the whole
//! description. An assembly file has `data(key)` too: the value of `key` in the domain's
//! assembly data (`modbot-data`; nil when it has none), which is how a robot program's command
//! gives its assembly parameters (MoRC: "assembly parameters rely on data stored in the
//! Assembly Data database").
//!
//! Each declaration records the line of the Lua code that called it. The first failure is kept
//! with its line; a Lua syntax or runtime error is translated from Lua's `file:LINE: message`.

use std::path::Path;

use mlua::chunk::ChunkMode;
use mlua::{Lua, MultiValue};

use super::decl::{self, Declarations};
use super::record::{caller_line, fail, given, one_arg, open_body, Shared};
use super::sandbox::{self, INSTRUCTION_LIMIT};
use super::{grid_decl, record_decl};
use super::{DeclError, GroupSpec, SystemError};
/// At most this many `module` declarations (addresses are 1 to 254) and `group` declarations.
const MAX_MODULES: usize = 254;
const MAX_GROUPS: usize = 1024;

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

/// What a description is called in refusals.
const WHAT: &str = "a system description";

/// Evaluates `source` (called `file` in messages) with the variables `vars` (later entries
/// win over earlier ones with the same key) and returns what it declared. An assembly file is
/// given its domain's assembly data file (`data`), which its `data(key)` reads.
pub(super) fn evaluate(
    file: &str,
    source: &str,
    vars: &[(String, String)],
    data: Option<&Path>,
) -> Result<Declarations, SystemError> {
    let record = Shared::default();
    let lua = sandbox(&record, vars, data).map_err(|e| {
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

/// A Lua state with the safe libraries, the limits, the declaration functions, `vars` and
/// `data`.
fn sandbox(record: &Shared, vars: &[(String, String)], data: Option<&Path>) -> mlua::Result<Lua> {
    let failed = record.clone();
    let lua = sandbox::open(WHAT, move || failed.borrow().failure.is_some())?;
    let globals = lua.globals();
    globals.raw_set("domain", domain_fn(&lua, record)?)?;
    globals.raw_set("supervision", supervision_fn(&lua, record)?)?;
    globals.raw_set("module", module_fn(&lua, record)?)?;
    globals.raw_set("group", group_fn(&lua, record)?)?;
    grid_decl::register(&lua, &globals, record)?;
    record_decl::register(&lua, &globals, record)?;
    super::bridge_decl::register(&lua, &globals, record)?;
    globals.raw_set("data", super::data_fn::data_fn(&lua, record, data)?)?;
    let given = lua.create_table()?;
    for (key, value) in vars {
        given.raw_set(key.as_str(), value.as_str())?;
    }
    lua.load(VARS).set_name(VARS_NAME).call::<()>(given)?;
    let counter = record.clone();
    sandbox::set_budget(&lua, move |_, spent| {
        let mut record = counter.borrow_mut();
        record.instructions += spent;
        if record.instructions <= INSTRUCTION_LIMIT {
            return true;
        }
        if record.failure.is_none() {
            record.failure = Some((None, DeclError::InstructionLimit));
        }
        false
    });
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
    let (_, line, message) = sandbox::position(error, "the description");
    SystemError::new(file, line, message)
}

//! `bridge { ... }`: the domain's bridge to domains on other hosts (the program
//! `modbot-zenoh`, a module of the system), at most once per description.
//!
//! ```lua
//! bridge {
//!   addr = 200,                                  -- the bridge module's address
//!   mode = "peer",                               -- Zenoh's mode: "peer" (default) or "client"
//!   listen = { "tcp/10.0.0.1:7447" },            -- endpoints to listen on
//!   connect = { "tcp/10.0.0.2:7447" },           -- endpoints to connect to (retried)
//!   config = "zenoh.json5",                      -- optional: a Zenoh configuration file
//!                                                -- (TLS, access control), relative to the
//!                                                -- directory modbot up runs in
//!   exports = { "mobility",                      -- every method of mobility
//!               high_level = { "patrol", "stop" } },   -- or these (and the reading system
//!                                                      -- methods)
//!   imports = { control_station = { addr = 20, domain = "station" },
//!               base_mobility = { addr = 41, domain = "base", module = "mobility" } },
//!   call_timeout_ms = 1500, lease_ms = 2000,     -- optional (these are the defaults)
//!   snapshot_hz = 10,                            -- optional: how often the exported modules'
//!                                                -- blackboard snapshots go (0: never)
//!   name = "bridge", restart = "on-failure",     -- optional
//! }
//! ```
//!
//! It becomes the module `name` running `modbot-zenoh` with the matching options, and each
//! import holds its name and address in the domain as a module would (checked against the
//! modules'; the supervisor gives neither to anything else).

use mlua::{Lua, MultiValue, Table, Value};

use super::decl::{self, ModuleDecl};
use super::read::{integer_in, lua_failed, show, string, string_list, text, Fields};
use super::record::{caller_line, fail, one_arg, Shared};
use super::{DeclError, ImportedName};

/// The program a bridge runs.
pub const PROGRAM: &str = "modbot-zenoh";

const FIELDS: &[&str] = &[
    "addr",
    "name",
    "mode",
    "listen",
    "connect",
    "config",
    "exports",
    "imports",
    "call_timeout_ms",
    "lease_ms",
    "snapshot_hz",
    "restart",
];

/// Adds `bridge` to `globals`.
pub(super) fn register(lua: &Lua, globals: &Table, record: &Shared) -> mlua::Result<()> {
    let record = record.clone();
    let f = lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let usage =
            "bridge { addr = 200, listen = { \"tcp/10.0.0.1:7447\" }, exports = { \"mobility\" } }";
        let (module, imported) = one_arg(&args, usage)
            .and_then(|v| read(lua, line, v))
            .map_err(|m| fail(&record, line, m))?;
        let first = record.borrow().decls.bridge;
        if let Some(first) = first {
            let what = "bridge";
            return Err(fail(&record, line, DeclError::Duplicate { what, first }));
        }
        let mut r = record.borrow_mut();
        r.decls.bridge = Some(line);
        r.decls.modules.push(module);
        r.decls.imported.extend(imported);
        Ok(())
    })?;
    globals.raw_set("bridge", f)
}

/// The table of `bridge { ... }`, declared at `line`: the module it runs and the names its
/// imports hold.
fn read(lua: &Lua, line: u32, v: &Value) -> Result<(ModuleDecl, Vec<ImportedName>), DeclError> {
    let what = "bridge";
    let mut fields = Fields::read(what, v, FIELDS)?;
    let name = match fields.take("name") {
        Some(v) => string(what, "name", &v)?,
        None => "bridge".to_owned(),
    };
    let mut args: Vec<String> = Vec::new();
    let mut option = |flag: &str, value: String| {
        args.push(flag.to_owned());
        args.push(value);
    };
    if let Some(v) = fields.take("mode") {
        match text(&v).as_deref() {
            Some(m @ ("peer" | "client")) => option("--zenoh-mode", m.to_owned()),
            _ => {
                return Err(DeclError::field(
                    what,
                    "mode",
                    "\"peer\" or \"client\"",
                    show(&v),
                ))
            }
        }
    }
    for (field, flag) in [("listen", "--listen"), ("connect", "--connect")] {
        if let Some(v) = fields.take(field) {
            for endpoint in string_list(lua, what, field, &v)? {
                if !endpoint.contains('/') {
                    let why = format!(
                        "field '{field}': '{endpoint}' is no Zenoh endpoint (tcp/10.0.0.1:7447)"
                    );
                    return Err(DeclError::invalid(what, why));
                }
                option(flag, endpoint);
            }
        }
    }
    if let Some(v) = fields.take("config") {
        option("--zenoh-config", string(what, "config", &v)?);
    }
    for (field, flag) in [
        ("call_timeout_ms", "--call-timeout-ms"),
        ("lease_ms", "--lease-ms"),
    ] {
        if let Some(v) = fields.take(field) {
            option(flag, integer_in(what, field, &v, 100, 600_000)?.to_string());
        }
    }
    if let Some(v) = fields.take("snapshot_hz") {
        let hz = match v {
            Value::Integer(i) => i as f64,
            Value::Number(n) => n,
            _ => f64::NAN,
        };
        if !(0.0..=1000.0).contains(&hz) {
            let expected = "a number of snapshots a second from 0 (never) to 1000";
            return Err(DeclError::field(what, "snapshot_hz", expected, show(&v)));
        }
        option("--snapshot-hz", hz.to_string());
    }
    if let Some(v) = fields.take("exports") {
        for export in exports(lua, &v)? {
            option("--export", export);
        }
    }
    let mut imported = Vec::new();
    if let Some(v) = fields.take("imports") {
        for (local, addr, domain, module) in imports(&v)? {
            option("--import", format!("{local}@{addr}={domain}/{module}"));
            imported.push(ImportedName {
                name: local,
                addr,
                line,
            });
        }
    }
    // The module itself, read as any module: a table of its fields.
    let table = lua.create_table().map_err(|e| lua_failed(what, &e))?;
    let set = |k: &str, v: Value| table.raw_set(k, v).map_err(|e| lua_failed(what, &e));
    match fields.take("addr") {
        Some(v) => set("addr", v)?,
        None => return Err(DeclError::missing(what, "addr", " (1 to 254)")),
    }
    if let Some(v) = fields.take("restart") {
        set("restart", v)?;
    }
    let program = lua
        .create_string(PROGRAM)
        .map_err(|e| lua_failed(what, &e))?;
    set("program", Value::String(program))?;
    let list = lua
        .create_sequence_from(args)
        .map_err(|e| lua_failed(what, &e))?;
    set("args", Value::Table(list))?;
    let name = decl::name_text("bridge", &name)?;
    let module = decl::module(lua, &name, line, &Value::Table(table))?;
    Ok((module, imported))
}

/// `exports = { "mobility", high_level = { "patrol", "stop" } }` as `--export` values.
fn exports(lua: &Lua, v: &Value) -> Result<Vec<String>, DeclError> {
    let what = "bridge";
    let Value::Table(t) = v else {
        return Err(DeclError::field(
            what,
            "exports",
            "a table of module names",
            show(v),
        ));
    };
    let mut out = Vec::new();
    for pair in t.pairs::<Value, Value>() {
        let (k, v) = pair.map_err(|e| lua_failed(what, &e))?;
        match (&k, text(&k)) {
            (Value::Integer(_), _) => out.push(module_name(&string(what, "exports", &v)?)?),
            (_, Some(module)) => {
                let module = module_name(&module)?;
                let methods = string_list(lua, what, &format!("exports.{module}"), &v)?;
                if methods.is_empty() || methods.iter().any(|m| m.contains([',', ':'])) {
                    let why = format!("exports.{module}: list the methods, as {{ \"patrol\" }}");
                    return Err(DeclError::invalid(what, why));
                }
                out.push(format!("{module}:{}", methods.join(",")));
            }
            _ => return Err(DeclError::field(what, "exports", "module names", show(&k))),
        }
    }
    // Lua's iteration order is not stable: the arguments are.
    out.sort();
    Ok(out)
}

/// `imports = { name = { addr = 20, domain = "station", module = "x" } }`.
fn imports(v: &Value) -> Result<Vec<(String, u8, String, String)>, DeclError> {
    let what = "bridge";
    let Value::Table(t) = v else {
        let expected =
            "a table of imports, as { control_station = { addr = 20, domain = \"station\" } }";
        return Err(DeclError::field(what, "imports", expected, show(v)));
    };
    let mut out = Vec::new();
    for pair in t.pairs::<Value, Value>() {
        let (k, v) = pair.map_err(|e| lua_failed(what, &e))?;
        let local = module_name(&text(&k).ok_or_else(|| {
            DeclError::field(
                what,
                "imports",
                "imports named by their local name",
                show(&k),
            )
        })?)?;
        let each = format!("bridge import '{local}'");
        let mut f = Fields::read(&each, &v, &["addr", "domain", "module"])?;
        let addr = match f.take("addr") {
            Some(v) => integer_in(&each, "addr", &v, 1, 254)?,
            None => return Err(DeclError::missing(&each, "addr", " (1 to 254)")),
        };
        let domain = match f.take("domain") {
            Some(v) => string(&each, "domain", &v)?,
            None => return Err(DeclError::missing(&each, "domain", " (the remote domain)")),
        };
        let module = match f.take("module") {
            Some(v) => module_name(&string(&each, "module", &v)?)?,
            None => local.clone(),
        };
        out.push((
            local,
            u8::try_from(addr).unwrap_or(u8::MAX),
            module_name(&domain)?,
            module,
        ));
    }
    out.sort();
    Ok(out)
}

fn module_name(n: &str) -> Result<String, DeclError> {
    decl::name_text("bridge", n)
}

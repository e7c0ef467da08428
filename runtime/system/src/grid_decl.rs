//! The grid's declarations: their Lua functions and what each one says.
//!
//! ```lua
//! grid { base_period = 0.001, cpus = { 0 }, priority = 80, mlock = true }   -- at most once
//! grid { clock = "lockstep", track_ticks = 50, spin_us = 0 }                -- timing, optional
//! component "A" { type = "counter", host = "h1", period = 1, params = { start = 0 } }
//! component "B" { type = "gain", host = "h2", period_s = 0.002, params = { k = 0.5 }, policy = "fault" }
//! component "F" { type = "fmu", fmu = "ff.fmu", host = "h_ff", params = { Jm = 0.5 } }   -- an FMU
//! connect "A.y -> B.u"                                                         -- or connect("A.y", "B.u")
//! component_type "scaler" {                          -- a type a host program of its own makes
//!   program = "my-host", doc = "y = k u",
//!   inputs = { "u:f64" }, outputs = { "y:f64" },     -- name:type (f64, i64, bool, f64[N]), in order
//!   params = { k = 1.0 },                            -- name = default
//! }
//! ```
//!
//! Like `decl`, each reader checks only what its own table says (field names, value types);
//! the checks that need the component types or other declarations (parameters, ports, periods
//! against the base tick, connections) are [`modbot_grid::GridSpec::build`]'s, called by
//! `validate`.

use std::time::Duration;

use mlua::{Lua, MultiValue, Table, Value};

use super::decl::{self, realtime};
use super::read::{integer_in, list, lua_failed, show, string, string_list, text, Fields};
use super::record::{caller_line, fail, given, one_arg, open_body, Shared};
use super::DeclError;
use modbot_grid::component::{
    intern, ComponentInfo, DeclaredType, ParamDecl, ParamValue, Params, PortDecl, PortType,
};
use modbot_grid::spec::{
    AssembliesDecl, ComponentDecl, ConnectDecl, GridClock, GridDecl, GridTiming, OverrunPolicy,
    Period, MAX_COMPONENTS,
};

const GRID_FIELDS: &[&str] = &[
    "base_period",
    "cpus",
    "priority",
    "mlock",
    "assemblies",
    "assembly",
    "clock",
    "track_ticks",
    "spin_us",
];
const COMPONENT_FIELDS: &[&str] = &[
    "type", "host", "period", "period_s", "params", "policy", "fmu",
];
const TYPE_FIELDS: &[&str] = &["program", "doc", "inputs", "outputs", "params"];
/// At most this many `component_type` declarations.
const MAX_TYPES: usize = 256;
/// The base period when `grid {}` does not say.
const DEFAULT_BASE_PERIOD: Duration = Duration::from_millis(1);
/// At most this many `connect` declarations (they are kept outside Lua's memory limit).
const MAX_CONNECTIONS: usize = 1 << 18;

/// Adds `grid`, `component` and `connect` to `globals`.
pub(super) fn register(lua: &Lua, globals: &Table, record: &Shared) -> mlua::Result<()> {
    globals.raw_set("grid", grid_fn(lua, record)?)?;
    globals.raw_set("component", component_fn(lua, record)?)?;
    globals.raw_set("connect", connect_fn(lua, record)?)?;
    globals.raw_set("component_type", component_type_fn(lua, record)?)?;
    Ok(())
}

/// `grid { ... }`.
fn grid_fn(lua: &Lua, record: &Shared) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let grid = one_arg(&args, "grid { base_period = 0.001 }")
            .and_then(|v| grid(line, v))
            .map_err(|m| fail(&record, line, m))?;
        let first = record.borrow().decls.grid.as_ref().map(|g| g.line);
        if let Some(first) = first {
            let what = "grid";
            return Err(fail(&record, line, DeclError::Duplicate { what, first }));
        }
        record.borrow_mut().decls.grid = Some(grid);
        Ok(())
    })
}

/// `component "name"`, which returns the function that takes the component's table.
fn component_fn(lua: &Lua, record: &Shared) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let usage = "component \"A\" { type = \"gain\", host = \"h1\", params = { k = 2 } }";
        let name = one_arg(&args, usage)
            .and_then(|v| decl::name("component", v))
            .map_err(|m| fail(&record, line, m))?;
        let index = open_body(&record, "component", &name, line, MAX_COMPONENTS)?;
        let record = record.clone();
        lua.create_function(move |_, args: MultiValue| {
            given(&record, index);
            let component = one_arg(&args, usage)
                .and_then(|v| component(&name, line, v))
                .map_err(|m| fail(&record, line, m))?;
            record.borrow_mut().decls.components.push(component);
            Ok(())
        })
    })
}

/// `component_type "name"`, which returns the function that takes the type's table.
fn component_type_fn(lua: &Lua, record: &Shared) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let usage = "component_type \"scaler\" { program = \"my-host\", inputs = { \"u:f64\" }, outputs = { \"y:f64\" } }";
        let name = one_arg(&args, usage)
            .and_then(|v| decl::name("component_type", v))
            .map_err(|m| fail(&record, line, m))?;
        let index = open_body(&record, "component_type", &name, line, MAX_TYPES)?;
        let record = record.clone();
        lua.create_function(move |lua, args: MultiValue| {
            given(&record, index);
            let declared = one_arg(&args, usage)
                .and_then(|v| component_type(lua, &name, line, v))
                .map_err(|m| fail(&record, line, m))?;
            let first = record
                .borrow()
                .decls
                .component_types
                .iter()
                .find(|t| t.info.type_name == declared.info.type_name)
                .map(|t| t.line);
            if let Some(first) = first {
                let what = "component_type";
                return Err(fail(&record, line, DeclError::Duplicate { what, first }));
            }
            record.borrow_mut().decls.component_types.push(declared);
            Ok(())
        })
    })
}

/// `connect "A.y -> B.u"` or `connect("A.y", "B.u")`.
fn connect_fn(lua: &Lua, record: &Shared) -> mlua::Result<mlua::Function> {
    let record = record.clone();
    lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let connection = connect(line, &args).map_err(|m| fail(&record, line, m))?;
        if record.borrow().decls.connections.len() >= MAX_CONNECTIONS {
            let (kind, max) = ("connect", MAX_CONNECTIONS);
            return Err(fail(&record, line, DeclError::TooMany { kind, max }));
        }
        record.borrow_mut().decls.connections.push(connection);
        Ok(())
    })
}

/// The table of `grid { ... }`, declared at `line`.
fn grid(line: u32, v: &Value) -> Result<GridDecl, DeclError> {
    let what = "grid";
    let mut fields = Fields::read(what, v, GRID_FIELDS)?;
    let base_period = match fields.take("base_period") {
        Some(v) => base_period(&v)?,
        None => DEFAULT_BASE_PERIOD,
    };
    let (cpus, priority, mlock) = realtime(what, &mut fields)?;
    let assemblies = match (fields.take("assemblies"), fields.take("assembly")) {
        (Some(dir), Some(first)) => Some(AssembliesDecl {
            dir: string(what, "assemblies", &dir)?,
            first: string(what, "assembly", &first)?,
        }),
        (None, None) => None,
        _ => {
            let why = "give both 'assemblies' (the directory of the assembly files) and \
                       'assembly' (the one to start with), or neither";
            return Err(DeclError::invalid(what, why));
        }
    };
    let mut timing = GridTiming::default();
    if let Some(v) = fields.take("clock") {
        let name = string(what, "clock", &v)?;
        timing.clock = GridClock::from_name(&name).ok_or_else(|| {
            let expected = "\"realtime\" or \"lockstep\"";
            DeclError::field(what, "clock", expected, format!("\"{name}\""))
        })?;
    }
    if let Some(v) = fields.take("track_ticks") {
        timing.track_ticks = integer_in(what, "track_ticks", &v, 0, 1_000_000)? as u64;
    }
    if let Some(v) = fields.take("spin_us") {
        timing.spin_us = integer_in(what, "spin_us", &v, 0, 1_000_000)? as u64;
    }
    Ok(GridDecl {
        assemblies,
        timing,
        base_period,
        cpus,
        // The range was checked above.
        priority: priority.map(|p| u8::try_from(p).unwrap_or(u8::MAX)),
        mlock,
        line,
    })
}

/// `base_period = seconds`, rounded to whole nanoseconds.
fn base_period(v: &Value) -> Result<Duration, DeclError> {
    let secs = number(v).unwrap_or(f64::NAN);
    if !(secs.is_finite() && secs > 0.0 && secs <= 3600.0) {
        let expected = "a positive number of seconds (at most 3600)";
        return Err(DeclError::field("grid", "base_period", expected, show(v)));
    }
    let nanos = (secs * 1e9).round() as u64;
    if nanos == 0 {
        let why = format!("base_period {secs} s is shorter than 1 ns");
        return Err(DeclError::invalid("grid", why));
    }
    Ok(Duration::from_nanos(nanos))
}

/// The table of `component "name" { ... }`, declared at `line`.
fn component(name: &str, line: u32, v: &Value) -> Result<ComponentDecl, DeclError> {
    let what = format!("component '{name}'");
    let what = what.as_str();
    let mut fields = Fields::read(what, v, COMPONENT_FIELDS)?;
    let type_name = match fields.take("type") {
        Some(v) => string(what, "type", &v)?,
        None => return Err(DeclError::missing(what, "type", "")),
    };
    let host = match fields.take("host") {
        Some(v) => string(what, "host", &v)?,
        None => return Err(DeclError::missing(what, "host", " (the host process)")),
    };
    let period = period(what, &mut fields)?;
    let mut params = match fields.take("params") {
        Some(v) => params(what, &v)?,
        None => Params::new(),
    };
    // An FMU component's file, as written: the loader finds it (see `fmu_path`).
    if let Some(v) = fields.take(modbot_fmu::FMU) {
        if type_name != modbot_fmu::TYPE {
            let why = format!(
                "'fmu' names the file of a component of type \"fmu\", not of type '{type_name}'"
            );
            return Err(DeclError::invalid(what, why));
        }
        params.set(modbot_fmu::FMU, ParamValue::Text(string(what, "fmu", &v)?));
    }
    let policy = match fields.take("policy") {
        Some(v) => text(&v)
            .as_deref()
            .and_then(OverrunPolicy::from_name)
            .ok_or_else(|| DeclError::field(what, "policy", "\"hold\" or \"fault\"", show(&v)))?,
        None => OverrunPolicy::Hold,
    };
    Ok(ComponentDecl {
        name: name.to_owned(),
        type_name,
        host,
        period,
        params,
        policy,
        line,
    })
}

/// `period = k` (base ticks) or `period_s = x` (seconds) of `what`; every base tick if neither.
pub(super) fn period(what: &str, fields: &mut Fields) -> Result<Period, DeclError> {
    match (fields.take("period"), fields.take("period_s")) {
        (Some(_), Some(_)) => {
            let why = "give 'period' (base ticks) or 'period_s' (seconds), not both";
            Err(DeclError::invalid(what, why))
        }
        (Some(v), None) => Ok(Period::Ticks(number(&v).ok_or_else(|| {
            DeclError::field(what, "period", "a number of base ticks", show(&v))
        })?)),
        (None, Some(v)) => Ok(Period::Seconds(number(&v).ok_or_else(|| {
            DeclError::field(what, "period_s", "a number of seconds", show(&v))
        })?)),
        (None, None) => Ok(Period::Ticks(1.0)),
    }
}

/// The table of `component_type "name" { ... }`, declared at `line`.
fn component_type(lua: &Lua, name: &str, line: u32, v: &Value) -> Result<DeclaredType, DeclError> {
    let what = format!("component_type '{name}'");
    let what = what.as_str();
    let mut fields = Fields::read(what, v, TYPE_FIELDS)?;
    let program = match fields.take("program") {
        Some(v) => string(what, "program", &v)?,
        None => {
            return Err(DeclError::missing(
                what,
                "program",
                " (the host program that makes it)",
            ))
        }
    };
    let doc = match fields.take("doc") {
        Some(v) => string(what, "doc", &v)?,
        None => String::new(),
    };
    let ports = |field: &str, fields: &mut Fields| -> Result<Vec<PortDecl>, DeclError> {
        let Some(v) = fields.take(field) else {
            return Ok(Vec::new());
        };
        string_list(lua, what, field, &v)?
            .iter()
            .map(|text| port(what, field, text))
            .collect()
    };
    let inputs = ports("inputs", &mut fields)?;
    let outputs = ports("outputs", &mut fields)?;
    if outputs.is_empty() {
        let why = "it has no outputs: give outputs = { \"y:f64\" }";
        return Err(DeclError::invalid(what, why));
    }
    let params = match fields.take("params") {
        Some(v) => params(what, &v)?
            .iter()
            .map(|(n, value)| ParamDecl::optional(intern(n), value.param_type(), value.clone()))
            .collect(),
        None => Vec::new(),
    };
    Ok(DeclaredType {
        info: ComponentInfo {
            type_name: intern(name),
            doc: intern(&doc),
            inputs,
            outputs,
            params,
        },
        program,
        line,
    })
}

/// One port of a declared type, written `name:type` (`u:f64`, `n:i64`, `on:bool`,
/// `q:f64[6]`).
fn port(what: &str, field: &str, text: &str) -> Result<PortDecl, DeclError> {
    let bad = |why: String| DeclError::invalid(what, format!("{field}: '{text}' {why}"));
    let (name, ty) = text
        .split_once(':')
        .ok_or_else(|| bad("is not name:type".into()))?;
    let (name, ty) = (name.trim(), ty.trim());
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(bad("has no valid name (letters, digits, _)".into()));
    }
    let ty = match PortType::parse(ty) {
        Some(PortType::F64s(n)) if n > MAX_ARRAY => None,
        parsed => parsed,
    }
    .ok_or_else(|| {
        bad(format!(
            "has type '{ty}': use f64, i64, bool or f64[N] (N from 1 to {MAX_ARRAY})"
        ))
    })?;
    Ok(PortDecl::new(intern(name), ty))
}

/// The longest f64 array port a declared type may have.
const MAX_ARRAY: usize = 4096;

/// `params = { name = value, ... }`: booleans, integers (i64), other numbers (f64), strings
/// and lists of numbers (f64 lists), sorted by name. Their names and types are checked
/// against the component type later.
fn params(what: &str, v: &Value) -> Result<Params, DeclError> {
    let Value::Table(table) = v else {
        let expected = "a table of name = value";
        return Err(DeclError::field(what, "params", expected, show(v)));
    };
    let mut params = Vec::new();
    for pair in table.pairs::<Value, Value>() {
        let (key, value) = pair.map_err(|e| lua_failed(what, &e))?;
        let Some(name) = text(&key) else {
            return Err(DeclError::Unnamed {
                what: what.to_owned(),
                kind: "params",
                key: show(&key),
                value: show(&value),
            });
        };
        let bad = || {
            let why = format!(
                "param '{name}' must be a boolean, a number, a string or a list of numbers, not \
                 {}",
                show(&value)
            );
            DeclError::invalid(what, why)
        };
        let value = match &value {
            Value::Boolean(b) => ParamValue::Bool(*b),
            Value::Integer(i) => ParamValue::I64(*i),
            Value::Number(x) => ParamValue::F64(*x),
            Value::String(_) => ParamValue::Text(text(&value).ok_or_else(bad)?),
            Value::Table(_) => {
                let items = list(what, &name, &value).map_err(|_| bad())?;
                let numbers: Option<Vec<f64>> = items.iter().map(number).collect();
                ParamValue::F64s(numbers.ok_or_else(bad)?)
            }
            _ => return Err(bad()),
        };
        params.push((name, value));
    }
    // Lua's iteration order is not stable across runs: sort, so the spec is.
    params.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(params.into_iter().collect())
}

/// The arguments of `connect`, declared at `line`.
fn connect(line: u32, args: &MultiValue) -> Result<ConnectDecl, DeclError> {
    let usage = "write connect \"A.y -> B.u\" or connect(\"A.y\", \"B.u\")";
    let texts: Option<Vec<String>> = args.iter().map(text).collect();
    let (from, to) = match texts.as_deref() {
        Some([one]) => match one.split_once("->") {
            Some((from, to)) => (endpoint(from.trim())?, endpoint(to.trim())?),
            None => {
                let why = format!("'{one}' has no '->': {usage}");
                return Err(DeclError::invalid("connect", why));
            }
        },
        Some([from, to]) => (endpoint(from)?, endpoint(to)?),
        _ => return Err(DeclError::ConnectArguments { usage }),
    };
    Ok(ConnectDecl { from, to, line })
}

/// `"A.y"` as (component, port).
fn endpoint(text: &str) -> Result<(String, String), DeclError> {
    match text.split_once('.') {
        Some((c, p)) if !c.is_empty() && !p.is_empty() && !p.contains(['.', ' ']) => {
            Ok((c.to_owned(), p.to_owned()))
        }
        _ => {
            let why = format!("'{text}' is not component.port (as in \"A.y\")");
            Err(DeclError::invalid("connect", why))
        }
    }
}

/// A Lua number (integer or float) as f64.
fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Integer(i) => Some(*i as f64),
        Value::Number(x) => Some(*x),
        _ => None,
    }
}

//! What one declaration says, read from its Lua values.
//!
//! Each function here takes the value a declaration was called with and returns the Rust value
//! or a [`DeclError`] naming the declaration and the field ("module 'sonar': field 'args' must
//! be a list of strings"); `lua` adds the file and the line. Checks that need more than one
//! declaration (duplicates, group members) are in `validate`.
//!
//! Tables are read with raw access (no metamethods run) and every key must be a known field,
//! so a typo is an error rather than a silently ignored setting.

use std::ops::Deref;
use std::path::PathBuf;

use mlua::{Lua, Value};

use super::read::{
    coerce, integer, integer_in, list, lua_failed, seconds, show, string, string_list, text, Fields,
};
use super::{DeclError, GiveUp, GroupSpec, ModuleSpec, Restart, RestartPolicy, Supervision};
use modbot_core::transport::{check_name, ReceiveMode};
use modbot_grid::component::DeclaredType;
use modbot_grid::spec::{ComponentDecl, ConnectDecl, GridDecl, RecordDecl};

use super::ImportedName;

/// Everything the description declared, in order, before the cross-checks.
#[derive(Debug, Default)]
pub(super) struct Declarations {
    /// The `domain` declaration and its line.
    pub domain: Option<(String, u32)>,
    /// The `supervision` declaration and its line.
    pub supervision: Option<(Supervision, u32)>,
    /// The `module` declarations in order (the start order).
    pub modules: Vec<ModuleDecl>,
    /// The `group` declarations in order; members are not checked yet.
    pub groups: Vec<GroupSpec>,
    /// The `grid` declaration.
    pub grid: Option<GridDecl>,
    /// The `component_type` declarations in order.
    pub component_types: Vec<DeclaredType>,
    /// The `component` declarations in order (their indices on the grid).
    pub components: Vec<ComponentDecl>,
    /// The `connect` declarations in order.
    pub connections: Vec<ConnectDecl>,
    /// The `record` declaration (at most one).
    pub records: Vec<RecordDecl>,
    /// The line of the `bridge` declaration (at most one), which added its module.
    pub bridge: Option<u32>,
    /// The names and addresses the bridge's imports hold.
    pub imported: Vec<ImportedName>,
}

/// A `module` declaration: its program as the description wrote it, not looked up yet, and
/// the module as a [`ModuleSpec`] that lacks what is not known yet — its `program` and
/// `program_name` are empty and its `groups` too, until [`ModuleDecl::into_spec`]. Its other
/// fields are read through it (`m.name`, `m.addr`, `m.line`).
#[derive(Debug)]
pub(super) struct ModuleDecl {
    /// The program as the description wrote it.
    pub program: String,
    module: ModuleSpec,
}

impl Deref for ModuleDecl {
    type Target = ModuleSpec;

    fn deref(&self) -> &ModuleSpec {
        &self.module
    }
}

impl ModuleDecl {
    /// The module, with its program found at `program` and its groups.
    pub fn into_spec(self, program: PathBuf, groups: Vec<String>) -> ModuleSpec {
        ModuleSpec {
            program,
            program_name: self.program,
            groups,
            ..self.module
        }
    }
}

const MODULE_FIELDS: &[&str] = &[
    "addr",
    "program",
    "args",
    "restart",
    "cpus",
    "priority",
    "mlock",
    "env",
    "mode",
    "linger_us",
];
const SUPERVISION_FIELDS: &[&str] = &[
    "start_timeout",
    "heartbeat_timeout",
    "heartbeat_period",
    "stop_grace",
];
const RESTART_FIELDS: &[&str] = &[
    "policy",
    "max_restarts",
    "window",
    "backoff",
    "max_backoff",
    "give_up",
];

/// The longest a module may linger after serving a frame (`linger_us`): one second.
const MAX_LINGER_US: i64 = 1_000_000;

/// The largest CPU index an affinity mask can hold (the kernel's `CPU_SETSIZE` - 1).
const MAX_CPU: i64 = 1023;

/// The argument of `domain "name"`.
pub(super) fn domain(v: &Value) -> Result<String, DeclError> {
    let name = text(v).ok_or_else(|| DeclError::Argument {
        what: "domain".into(),
        expected: "a name, as in domain \"robot\"".into(),
        got: show(v),
    })?;
    modbot_core::Domain::new(&name)?;
    Ok(name)
}

/// The argument of `module "name"` or `group "name"` (`what` is "module" or "group").
pub(super) fn name(what: &'static str, v: &Value) -> Result<String, DeclError> {
    let name = text(v).ok_or_else(|| DeclError::Argument {
        what: what.into(),
        expected: format!("a name, as in {what} \"sonar\" {{ ... }}"),
        got: show(v),
    })?;
    if check_name(&name).is_err() {
        return Err(DeclError::Name { what, name });
    }
    Ok(name)
}

/// `name`, checked as a name of a `what`.
pub(super) fn name_text(what: &'static str, name: &str) -> Result<String, DeclError> {
    if check_name(name).is_err() {
        return Err(DeclError::Name {
            what,
            name: name.to_owned(),
        });
    }
    Ok(name.to_owned())
}

/// The table of `supervision { ... }`.
pub(super) fn supervision(v: &Value) -> Result<Supervision, DeclError> {
    let what = "supervision";
    let mut fields = Fields::read(what, v, SUPERVISION_FIELDS)?;
    let mut sut = Supervision::default();
    if let Some(v) = fields.take("start_timeout") {
        sut.start_timeout = seconds(what, "start_timeout", &v, false)?;
    }
    if let Some(v) = fields.take("heartbeat_timeout") {
        sut.heartbeat_timeout = seconds(what, "heartbeat_timeout", &v, false)?;
    }
    if let Some(v) = fields.take("heartbeat_period") {
        sut.heartbeat_period = seconds(what, "heartbeat_period", &v, false)?;
    }
    if let Some(v) = fields.take("stop_grace") {
        sut.stop_grace = seconds(what, "stop_grace", &v, true)?;
    }
    if sut.heartbeat_period >= sut.heartbeat_timeout / 2 {
        let why = format!(
            "heartbeat_period ({:?}) must be less than half of heartbeat_timeout ({:?}), so \
             that one late heartbeat does not make a module look hung",
            sut.heartbeat_period, sut.heartbeat_timeout
        );
        return Err(DeclError::invalid(what, why));
    }
    Ok(sut)
}

/// The table of `module "name" { ... }`, declared at `line`.
pub(super) fn module(lua: &Lua, name: &str, line: u32, v: &Value) -> Result<ModuleDecl, DeclError> {
    let what = format!("module '{name}'");
    let what = what.as_str();
    let mut fields = Fields::read(what, v, MODULE_FIELDS)?;
    let addr = match fields.take("addr") {
        Some(v) => integer_in(what, "addr", &v, 1, 254)?,
        None => return Err(DeclError::missing(what, "addr", " (1 to 254)")),
    };
    let program = match fields.take("program") {
        Some(v) => string(what, "program", &v)?,
        None => return Err(DeclError::missing(what, "program", "")),
    };
    if program.is_empty() || program.contains('\0') {
        return Err(DeclError::invalid(
            what,
            "field 'program' must name a program",
        ));
    }
    let args = match fields.take("args") {
        Some(v) => string_list(lua, what, "args", &v)?,
        None => Vec::new(),
    };
    let restart = match fields.take("restart") {
        Some(v) => restart(name, &v)?,
        None => RestartPolicy::default(),
    };
    let (cpus, priority, mlock) = realtime(what, &mut fields)?;
    let mut env = match fields.take("env") {
        Some(v) => env(lua, what, &v)?,
        None => Vec::new(),
    };
    let mode = match fields.take("mode") {
        Some(v) => match text(&v).as_deref() {
            Some("blocking") => ReceiveMode::Blocking,
            Some("busy" | "busy-poll") => ReceiveMode::BusyPoll,
            _ => {
                let expected = "\"blocking\" or \"busy\"";
                return Err(DeclError::field(what, "mode", expected, show(&v)));
            }
        },
        None => ReceiveMode::Blocking,
    };
    if let Some(v) = fields.take("linger_us") {
        let us = integer_in(what, "linger_us", &v, 0, MAX_LINGER_US)?;
        if mode == ReceiveMode::BusyPoll {
            return Err(DeclError::invalid(
                what,
                "field 'linger_us' is for a module in blocking mode (a busy one never sleeps)",
            ));
        }
        let var = modbot_core::cli::LINGER_ENV;
        if env.iter().any(|(k, _)| k == var) {
            let why = format!("set linger_us or env {var}, not both");
            return Err(DeclError::invalid(what, why));
        }
        env.push((var.to_owned(), us.to_string()));
        env.sort();
    }
    let module = ModuleSpec {
        name: name.to_owned(),
        // The range was checked above.
        addr: u8::try_from(addr).unwrap_or(u8::MAX),
        program: PathBuf::new(),
        program_name: String::new(),
        args,
        restart,
        cpus,
        priority: priority.map(|p| u8::try_from(p).unwrap_or(u8::MAX)),
        mlock,
        env,
        mode,
        groups: Vec::new(),
        line,
    };
    Ok(ModuleDecl { program, module })
}

/// The list of `group "name" { "member", ... }`.
pub(super) fn group_members(name: &str, v: &Value) -> Result<Vec<String>, DeclError> {
    let what = format!("group '{name}'");
    let items = list(&what, "members", v).map_err(|_| DeclError::Argument {
        what: what.clone(),
        expected: format!(
            "a list of module names, as in group \"{name}\" {{ \"sonar\", \"mobility\" }}"
        ),
        got: show(v),
    })?;
    let mut members: Vec<String> = Vec::with_capacity(items.len());
    for (i, item) in items.iter().enumerate() {
        let member = text(item).ok_or_else(|| {
            let why = format!("member {} must be a module name, not {}", i + 1, show(item));
            DeclError::invalid(&what, why)
        })?;
        if members.contains(&member) {
            return Err(DeclError::invalid(
                &what,
                format!("'{member}' is listed twice"),
            ));
        }
        members.push(member);
    }
    if members.is_empty() {
        return Err(DeclError::NoMembers { group: name.into() });
    }
    Ok(members)
}

/// `restart = "policy"` or `restart = { policy = ..., ... }` of module `module`.
fn restart(module: &str, v: &Value) -> Result<RestartPolicy, DeclError> {
    let when = |v: &Value| match text(v) {
        Some(s) => Restart::from_name(&s).ok_or_else(|| {
            let what = format!("restart policy '{s}' for module '{module}'");
            DeclError::invalid(&what, "expected never, on-failure or always")
        }),
        None => {
            let what = format!("module '{module}'");
            let why = format!(
                "restart policy must be never, on-failure or always, not {}",
                show(v)
            );
            Err(DeclError::invalid(&what, why))
        }
    };
    let mut sut = RestartPolicy::default();
    match v {
        Value::Table(_) => {
            let what = format!("module '{module}': restart");
            let what = what.as_str();
            let mut fields = Fields::read(what, v, RESTART_FIELDS)?;
            if let Some(v) = fields.take("policy") {
                sut.when = when(&v)?;
            }
            if let Some(v) = fields.take("max_restarts") {
                let n = integer_in(what, "max_restarts", &v, 0, i64::from(u32::MAX))?;
                sut.max_restarts = u32::try_from(n).unwrap_or(u32::MAX);
            }
            if let Some(v) = fields.take("window") {
                sut.window = seconds(what, "window", &v, false)?;
            }
            if let Some(v) = fields.take("backoff") {
                sut.backoff = seconds(what, "backoff", &v, true)?;
            }
            if let Some(v) = fields.take("max_backoff") {
                sut.max_backoff = seconds(what, "max_backoff", &v, true)?;
            }
            if let Some(v) = fields.take("give_up") {
                sut.give_up = text(&v)
                    .as_deref()
                    .and_then(GiveUp::from_name)
                    .ok_or_else(|| {
                        let expected = "\"keep-others\" or \"stop-system\"";
                        DeclError::field(what, "give_up", expected, show(&v))
                    })?;
            }
            if sut.max_backoff < sut.backoff {
                let why = format!(
                    "max_backoff ({:?}) must not be less than backoff ({:?})",
                    sut.max_backoff, sut.backoff
                );
                return Err(DeclError::invalid(what, why));
            }
        }
        Value::String(_) => sut.when = when(v)?,
        _ => {
            let what = format!("module '{module}'");
            let expected = "a policy name or a table";
            return Err(DeclError::field(&what, "restart", expected, show(v)));
        }
    }
    Ok(sut)
}

/// `cpus = { 0, 2 }`: sorted, without repeats.
/// The real-time fields a module and the grid share: `cpus`, `priority` (SCHED_FIFO 1..=99)
/// and `mlock`.
pub(super) fn realtime(
    what: &str,
    fields: &mut Fields,
) -> Result<(Vec<usize>, Option<i64>, bool), DeclError> {
    let cpus = match fields.take("cpus") {
        Some(v) => cpus(what, &v)?,
        None => Vec::new(),
    };
    let priority = match fields.take("priority") {
        Some(v) => Some(integer_in(what, "priority", &v, 1, 99)?),
        None => None,
    };
    let mlock = match fields.take("mlock") {
        Some(Value::Boolean(b)) => b,
        Some(v) => return Err(DeclError::field(what, "mlock", "true or false", show(&v))),
        None => false,
    };
    Ok((cpus, priority, mlock))
}

pub(super) fn cpus(what: &str, v: &Value) -> Result<Vec<usize>, DeclError> {
    let expected = format!("a list of CPU indices 0 to {MAX_CPU}");
    let bad = || DeclError::field(what, "cpus", expected.clone(), show(v));
    let mut cpus = Vec::new();
    for item in list(what, "cpus", v).map_err(|_| bad())? {
        match integer(&item) {
            Some(cpu) if (0..=MAX_CPU).contains(&cpu) => {
                cpus.push(usize::try_from(cpu).unwrap_or(usize::MAX))
            }
            _ => {
                let why = format!(
                    "field 'cpus' must be {expected}, and {} is not one",
                    show(&item)
                );
                return Err(DeclError::invalid(what, why));
            }
        }
    }
    cpus.sort_unstable();
    cpus.dedup();
    Ok(cpus)
}

/// `env = { NAME = "value" }`: sorted by name.
fn env(lua: &Lua, what: &str, v: &Value) -> Result<Vec<(String, String)>, DeclError> {
    let bad = || DeclError::Field {
        what: what.to_owned(),
        field: "env".into(),
        expected: "a table of NAME = \"value\"".into(),
        got: None,
    };
    let Value::Table(table) = v else {
        return Err(bad());
    };
    let mut env = Vec::new();
    for pair in table.pairs::<Value, Value>() {
        let (key, value) = pair.map_err(|e| lua_failed(what, &e))?;
        let key = text(&key).ok_or_else(bad)?;
        if key.is_empty() || key.contains(['=', '\0']) {
            let why = format!("'{key}' cannot be an environment variable name");
            return Err(DeclError::invalid(what, why));
        }
        let value = coerce(lua, &value).ok_or_else(|| {
            let why = format!("env {key} must be a string, not {}", show(&value));
            DeclError::invalid(what, why)
        })?;
        if value.contains('\0') {
            let why = format!("env {key} contains a NUL character");
            return Err(DeclError::invalid(what, why));
        }
        env.push((key, value));
    }
    env.sort();
    Ok(env)
}

//! `record { ... }`: the data recorder's declaration (MoRC's Data Recorder), in a system
//! description or an assembly, at most once per file.
//!
//! ```lua
//! record {
//!   signals = { "ptp.q", "robot.link_position" },   -- outputs, comp.port, in this order
//!   file = "run.h5",                                 -- relative to the current directory;
//!                                                    -- without it, only with --record FILE
//!   on_demand = true,                                -- a system's recorder without a file:
//!                                                    -- runs anyway, and records when a robot
//!                                                    -- program says (record { }, stop_record { })
//!   units = { ["robot.link_position"] = "rad" },     -- optional: the datasets' unit attributes
//!   name = "record", host = "record", period = 1,    -- optional: these are the defaults
//!   replay = true,                                   -- optional: a recording `modbot replay`
//!                                                    -- replays (the bus played back), or
//!                                                    -- replay = { "robot", "lidar" }: these
//! }
//! ```
//!
//! The grid makes it a component on a host of its own ([`modbot_grid::spec::RecordDecl`]),
//! written by the program `modbot-recorder`. `modbot up --record FILE` records to FILE instead
//! (the variable [`RECORD_VAR`], which every process of the run gets), and when the
//! description declares no recorder, records every output of the system's own components.

use mlua::{Lua, MultiValue, Table, Value};

use super::grid_decl::period;
use super::read::{lua_failed, show, string, string_list, text, Fields};
use super::record::{caller_line, fail, one_arg, Shared};
use super::{DeclError, SystemError};
use modbot_grid::spec::{
    expand_record, ComponentDecl, ConnectDecl, GridError, RecordDecl, Signals,
};
use modbot_grid::GridSpec;

/// The variable `modbot up --record FILE` sets: the file every recorder of the run writes.
pub const RECORD_VAR: &str = "modbot.record";

/// The variable `modbot up --replayable` sets (`true`): the system's recorder is replayable.
pub const REPLAY_VAR: &str = "modbot.replay";

const FIELDS: &[&str] = &[
    "signals",
    "file",
    "units",
    "name",
    "host",
    "period",
    "period_s",
    "on_demand",
    "replay",
];
/// The recorder's component and host name unless the declaration says.
const DEFAULT_NAME: &str = "record";

/// Adds `record` to `globals`.
pub(super) fn register(lua: &Lua, globals: &Table, record: &Shared) -> mlua::Result<()> {
    let record = record.clone();
    let f = lua.create_function(move |lua, args: MultiValue| {
        let line = caller_line(lua);
        let usage = "record { signals = { \"ptp.q\" }, file = \"run.h5\" }";
        let decl = one_arg(&args, usage)
            .and_then(|v| read(lua, line, v))
            .map_err(|m| fail(&record, line, m))?;
        let first = record.borrow().decls.records.first().map(|r| r.line);
        if let Some(first) = first {
            let what = "record";
            return Err(fail(&record, line, DeclError::Duplicate { what, first }));
        }
        record.borrow_mut().decls.records.push(decl);
        Ok(())
    })?;
    globals.raw_set("record", f)
}

/// The table of `record { ... }`, declared at `line`.
fn read(lua: &Lua, line: u32, v: &Value) -> Result<RecordDecl, DeclError> {
    let what = "record";
    let mut fields = Fields::read(what, v, FIELDS)?;
    let signals = match fields.take("signals") {
        Some(v) => string_list(lua, what, "signals", &v)?,
        None => {
            return Err(DeclError::missing(
                what,
                "signals",
                " (the outputs to record)",
            ))
        }
    };
    // Without a file, the recorder runs only when `modbot up --record FILE` names one, or
    // `on_demand` (a system's, for robot programs).
    let file = match fields.take("file") {
        Some(v) => absolute(&string(what, "file", &v)?),
        None => String::new(),
    };
    let mut name = |field: &str| match fields.take(field) {
        Some(v) => string(what, field, &v),
        None => Ok(DEFAULT_NAME.to_owned()),
    };
    let (name, host) = (name("name")?, name("host")?);
    let on_demand = match fields.take("on_demand") {
        Some(Value::Boolean(b)) => b,
        Some(v) => {
            return Err(DeclError::field(
                what,
                "on_demand",
                "true or false",
                show(&v),
            ))
        }
        None => false,
    };
    let units = match fields.take("units") {
        Some(v) => units(&v)?,
        None => Vec::new(),
    };
    let replay = match fields.take("replay") {
        None | Some(Value::Boolean(false)) => None,
        Some(Value::Boolean(true)) => Some(Vec::new()),
        Some(v @ Value::Table(_)) => Some(string_list(lua, what, "replay", &v)?),
        Some(v) => {
            let expected = "true, false or a list of the components to play back";
            return Err(DeclError::field(what, "replay", expected, show(&v)));
        }
    };
    Ok(RecordDecl {
        name,
        host,
        signals: Signals::Listed(signals),
        file,
        on_demand,
        period: period(what, &mut fields)?,
        units,
        sources: Vec::new(),
        replay,
        line,
    })
}

/// `file` with `modbot up --record FILE`'s FILE (from `vars`), for the recorder of assembly
/// `assembly` (`None`: the system's): the system's writes FILE; an assembly's, without a file
/// of its own, `STEM.ASSEMBLY.EXT` beside it. `None`: this recorder does not run.
pub(super) fn file_of(
    file: &str,
    vars: &[(String, String)],
    assembly: Option<&str>,
) -> Option<String> {
    let asked = vars
        .iter()
        .rev()
        .find(|(k, _)| k == RECORD_VAR)
        .map(|(_, v)| v);
    match (asked, assembly) {
        (Some(path), None) => Some(absolute(path)),
        (Some(path), Some(name)) if file.is_empty() => {
            let path = std::path::Path::new(path);
            let stem = path
                .file_stem()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
            let name = match path.extension() {
                Some(ext) => format!("{stem}.{name}.{}", ext.to_string_lossy()),
                None => format!("{stem}.{name}"),
            };
            Some(absolute(&path.with_file_name(name).display().to_string()))
        }
        _ if file.is_empty() => None,
        _ => Some(file.to_owned()),
    }
}

/// `path` made absolute against the current directory (the processes of a run share it).
pub(super) fn absolute(path: &str) -> String {
    std::path::absolute(path).map_or_else(|_| path.to_owned(), |p| p.display().to_string())
}

/// `units = { ["comp.port"] = "unit", ... }`, sorted by signal.
fn units(v: &Value) -> Result<Vec<(String, String)>, DeclError> {
    let what = "record";
    let Value::Table(table) = v else {
        let expected = "a table of [\"comp.port\"] = \"unit\"";
        return Err(DeclError::field(what, "units", expected, show(v)));
    };
    let mut units = Vec::new();
    for pair in table.pairs::<Value, Value>() {
        let (key, value) = pair.map_err(|e| lua_failed(what, &e))?;
        match (text(&key), text(&value)) {
            (Some(signal), Some(unit)) if !signal.contains([';', '=']) && !unit.contains(';') => {
                units.push((signal, unit))
            }
            _ => {
                let why = format!(
                    "units: {} = {} is not [\"comp.port\"] = \"unit\" (without ';' or '=')",
                    show(&key),
                    show(&value)
                );
                return Err(DeclError::invalid(what, why));
            }
        }
    }
    // Lua's iteration order is not stable across runs: sort, so the spec is.
    units.sort();
    Ok(units)
}

/// Adds the recorders `records` to the declarations that `spec` is the checked grid of (without
/// them): a component and its connections each. Only components named in `own` may be
/// recorded (`None`: any), for a system's recorder that must outlive every assembly.
pub(super) fn add_recorders(
    records: &[RecordDecl],
    spec: &GridSpec,
    own: Option<&[ComponentDecl]>,
    decls: (&mut Vec<ComponentDecl>, &mut Vec<ConnectDecl>),
    refused: impl Fn(GridError) -> SystemError,
) -> Result<(), SystemError> {
    let lossless = spec.timing.clock == modbot_grid::GridClock::Lockstep;
    for r in records {
        let (component, feeding) = expand_record(r, spec, lossless).map_err(&refused)?;
        if let Some(own) = own {
            let foreign = feeding
                .iter()
                .find(|c| !own.iter().any(|o| o.name == c.from.0));
            if let Some(c) = foreign {
                return Err(refused(GridError {
                    line: Some(r.line),
                    kind: modbot_grid::spec::GridErrorKind::Record {
                        record: r.name.clone(),
                        what: format!(
                            "signal '{}.{}' is an assembly's: the system's recorder records \
                             only the system's own components (declare record in the assembly \
                             to record its signals)",
                            c.from.0, c.from.1
                        ),
                    },
                }));
            }
        }
        decls.0.push(component);
        decls.1.extend(feeding);
    }
    Ok(())
}

//! `record { ... }`: a data recorder, declared by the signals it records, becomes a component
//! of type `record` ([`crate::record_type`]) with one input per signal and a connection from
//! each signal to it.
//!
//! The recorder's input types are its signals' types, which only the checked grid knows, so a
//! grid with recorders is checked without them first ([`GridSpec::build`]), then each one is
//! added ([`expand`]) and the whole checked again.

use std::collections::HashSet;

use super::{
    ComponentDecl, ConnectDecl, GridError, GridErrorKind, GridSpec, OverrunPolicy, Period,
};
use crate::component::{ParamValue, Params};
use crate::record_type::{self, Signal};

/// A `record { ... }` declaration.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordDecl {
    /// The recorder component's name (`record` unless the declaration says).
    pub name: String,
    /// Its host (`record` unless the declaration says): a process of its own.
    pub host: String,
    pub signals: Signals,
    /// The HDF5 file, an absolute path; empty: none until a robot program starts a recording
    /// (`modbot_record::control`).
    pub file: String,
    /// A system's recorder without a file that runs anyway, for robot programs to start and
    /// stop recordings with (`on_demand = true`).
    pub on_demand: bool,
    /// Its period (every base tick unless the declaration says).
    pub period: Period,
    /// The units the declaration knows: (signal, unit).
    pub units: Vec<(String, String)>,
    /// The description files the recording keeps, with their text as the system was loaded
    /// from it (path, text): the system's, then an assembly's. The recorder stores this text,
    /// not what the file holds when it starts (a description edited meanwhile changes nothing).
    pub sources: Vec<(String, String)>,
    /// A replayable recording (`replay = true`, or `replay = { "comp", ... }` naming the
    /// sources): the components a replay plays back — empty: every component of type `bus`.
    pub replay: Option<Vec<String>>,
    pub line: u32,
}

/// The component type a replayable recording plays back unless it names its sources.
pub const BUS_TYPE: &str = "bus";

/// What a recorder records.
#[derive(Debug, Clone, PartialEq)]
pub enum Signals {
    /// These outputs, `comp.port`, in this order.
    Listed(Vec<String>),
    /// Every output of these components, in component and port order (what `modbot up
    /// --record FILE` records when the description declares no recorder: the system's own
    /// components).
    AllOf(Vec<String>),
}

fn refused(r: &RecordDecl, signal: &str, why: String) -> GridError {
    GridError {
        line: Some(r.line),
        kind: GridErrorKind::Record {
            record: r.name.clone(),
            what: format!("signal '{signal}' {why}"),
        },
    }
}

/// The sources of a replayable recorder `r` in `spec`, or why it has none.
fn replay_sources(
    r: &RecordDecl,
    named: &[String],
    spec: &GridSpec,
) -> Result<Vec<usize>, GridError> {
    let refuse = |what: String| GridError {
        line: Some(r.line),
        kind: GridErrorKind::Record {
            record: r.name.clone(),
            what,
        },
    };
    if named.is_empty() {
        let buses: Vec<usize> = (0..spec.components.len())
            .filter(|&c| spec.components[c].type_name == BUS_TYPE)
            .collect();
        if buses.is_empty() {
            return Err(refuse(
                "replay = true plays back the bus, and the grid has none: name the sources, \
                 replay = { \"comp\", ... }"
                    .into(),
            ));
        }
        return Ok(buses);
    }
    named
        .iter()
        .map(|name| {
            spec.component(name).ok_or_else(|| {
                let known: Vec<&str> = spec.components.iter().map(|c| c.name.as_str()).collect();
                refuse(format!(
                    "replay names '{name}', which is no component (components: {})",
                    known.join(", ")
                ))
            })
        })
        .collect()
}

/// The signals of `r` with their types, read from `spec` (the grid without recorders): those
/// it lists, and for a replayable recorder every output of its sources not listed and every
/// input of theirs, mirrored.
fn signals(r: &RecordDecl, spec: &GridSpec) -> Result<Vec<Signal>, GridError> {
    let mut signals = listed_signals(r, spec)?;
    let Some(named) = &r.replay else {
        return Ok(signals);
    };
    for c in replay_sources(r, named, spec)? {
        let c = &spec.components[c];
        for p in &c.info.outputs {
            let name = format!("{}.{}", c.name, p.name);
            if !signals.iter().any(|s| s.name == name) {
                signals.push(Signal { name, ty: p.ty });
            }
        }
        for p in &c.info.inputs {
            let name = record_type::mirrored(&c.name, p.name);
            signals.push(Signal { name, ty: p.ty });
        }
    }
    Ok(signals)
}

/// The signals `r` lists, with their types.
fn listed_signals(r: &RecordDecl, spec: &GridSpec) -> Result<Vec<Signal>, GridError> {
    let names: Vec<String> = match &r.signals {
        Signals::Listed(names) => names.clone(),
        Signals::AllOf(components) => components
            .iter()
            .filter_map(|c| spec.component(c))
            .flat_map(|c| {
                let c = &spec.components[c];
                c.info
                    .outputs
                    .iter()
                    .map(|p| format!("{}.{}", c.name, p.name))
            })
            .collect(),
    };
    let mut seen = HashSet::new();
    names
        .iter()
        .map(|name| {
            if !seen.insert(name.as_str()) {
                return Err(refused(r, name, "is recorded twice".into()));
            }
            let Some((comp, port)) = name.split_once('.') else {
                return Err(refused(r, name, "is not component.port".into()));
            };
            let Some(c) = spec.component(comp) else {
                let known: Vec<&str> = spec.components.iter().map(|c| c.name.as_str()).collect();
                let why = format!(
                    "no component is named '{comp}' (components: {})",
                    known.join(", ")
                );
                return Err(refused(r, name, why));
            };
            let info = &spec.components[c].info;
            let Some(p) = info.output(port) else {
                let outputs: Vec<&str> = info.outputs.iter().map(|p| p.name).collect();
                let why = format!(
                    "'{comp}' has no output '{port}' (outputs: {})",
                    outputs.join(", ")
                );
                return Err(refused(r, name, why));
            };
            Ok(Signal {
                name: name.clone(),
                ty: info.outputs[p].ty,
            })
        })
        .collect()
}

/// The recorder component `r` declares, and the connections that feed it, with the types of
/// `spec` (the grid without recorders); `lossless` when its grid runs in lockstep.
pub fn expand(
    r: &RecordDecl,
    spec: &GridSpec,
    lossless: bool,
) -> Result<(ComponentDecl, Vec<ConnectDecl>), GridError> {
    let signals = signals(r, spec)?;
    if signals.is_empty() {
        return Err(GridError {
            line: Some(r.line),
            kind: GridErrorKind::Record {
                record: r.name.clone(),
                what: "there is nothing to record: give signals = { \"comp.port\", ... }".into(),
            },
        });
    }
    let text = |s: String| ParamValue::Text(s);
    let params = Params::new()
        .with(
            record_type::SIGNALS,
            text(record_type::signals_text(&signals)),
        )
        .with(record_type::FILE, text(r.file.clone()))
        .with(record_type::UNITS, text(record_type::units_text(&r.units)))
        .with(
            record_type::SOURCES,
            text(
                r.sources
                    .iter()
                    .map(|(p, _)| p.as_str())
                    .collect::<Vec<_>>()
                    .join("\n"),
            ),
        )
        .with(
            record_type::SOURCE_TEXTS,
            text(record_type::texts_param(
                r.sources.iter().map(|(_, t)| t.as_str()),
            )),
        )
        .with(record_type::LOSSLESS, ParamValue::Bool(lossless))
        .with(
            record_type::REPLAY,
            text(match &r.replay {
                Some(named) => replay_sources(r, named, spec)?
                    .iter()
                    .map(|&c| spec.components[c].name.as_str())
                    .collect::<Vec<_>>()
                    .join(";"),
                None => String::new(),
            }),
        );
    let connections = signals
        .iter()
        .filter_map(|s| {
            let (comp, port) = s.name.split_once('.')?;
            Some(ConnectDecl {
                from: (comp.to_owned(), port.to_owned()),
                to: (r.name.clone(), s.name.clone()),
                line: r.line,
            })
        })
        .collect();
    let component = ComponentDecl {
        name: r.name.clone(),
        type_name: record_type::TYPE.to_owned(),
        host: r.host.clone(),
        period: r.period,
        params,
        policy: OverrunPolicy::Hold,
        line: r.line,
    };
    Ok((component, connections))
}

/// The connections that feed a replayable recorder's mirrored inputs (`S<input`, see
/// [`record_type::mirrored`]) in the grid of `components` and `connections`: from whatever
/// feeds the source's input there. A grid with assemblies makes them for each assembly, whose
/// components command the sources.
pub fn mirrored_connections(
    components: &[ComponentDecl],
    connections: &[ConnectDecl],
) -> Vec<ConnectDecl> {
    let mut out = Vec::new();
    for r in components
        .iter()
        .filter(|c| c.type_name == record_type::TYPE)
    {
        let Some(ParamValue::Text(text)) = r.params.get(record_type::SIGNALS) else {
            continue;
        };
        let Ok(signals) = record_type::parse_signals(text) else {
            continue;
        };
        for s in &signals {
            let Some((source, input)) = record_type::parse_mirrored(&s.name) else {
                continue;
            };
            let feeding = connections
                .iter()
                .find(|c| c.to.0 == source && c.to.1 == input);
            if let Some(c) = feeding {
                out.push(ConnectDecl {
                    from: c.from.clone(),
                    to: (r.name.clone(), s.name.clone()),
                    line: c.line,
                });
            }
        }
    }
    out
}

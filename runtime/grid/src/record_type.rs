//! The data recorder as a component type, `record` (MoRC's Data Recorder): what every process
//! knows of it — its parameters and ports. The component itself, which writes HDF5, is made by
//! the program [`PROGRAM`] (crate `modbot-record`).
//!
//! A description or an assembly says `record { signals = { "ptp.q", "robot.link_position" },
//! file = "run.h5" }` ([`crate::spec::RecordDecl`]); the grid makes that a component of this
//! type on a host of its own, with one input per signal, named like the signal and connected
//! from it. Released at tick n, it reads the signals as valid at n — the grid's LET semantics
//! decide what it records, as they decide what every component sees.
//!
//! Params (made by the grid from the declaration, not written by hand):
//! - `signals`: the recorded outputs and their types in input order, `comp.port:type` joined by
//!   `;` (`ptp.q:f64[6];robot.statusword:i64`);
//! - `file`: the HDF5 file (an absolute path);
//! - `units`: `comp.port=unit` joined by `;` (empty: none known);
//! - `sources`: the description files whose text the recording keeps (the system's, then the
//!   assembly's), joined by newlines;
//! - `source_texts`: their texts as the system was loaded from them, in the same order, each
//!   ended by a NUL character (empty: the recorder reads the files);
//! - `lossless`: wait for the writer rather than drop a row when it is behind — the lockstep
//!   clock's choice, where a release may take as long as it needs (default false: a release
//!   never waits, a row that finds no room is dropped and counted);
//! - `replay`: for a replayable recording (`record { replay = true }`), the *sources* joined by
//!   `;`: the components whose outputs a replay plays back (the bus). Their every output is
//!   recorded, and every input of theirs as `S<input` ([`mirrored`]): what the controllers
//!   commanded, fed by whichever assembly runs (empty: not replayable).
//!
//! Output: `dropped` (i64), the rows dropped so far.

use super::component::{
    intern, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, ParamValue, Params,
    PortDecl, PortType, Registry,
};

/// The type's name in descriptions and the registry.
pub const TYPE: &str = "record";
/// The host program that makes it.
pub const PROGRAM: &str = "modbot-recorder";

pub const SIGNALS: &str = "signals";
pub const FILE: &str = "file";
pub const UNITS: &str = "units";
pub const SOURCES: &str = "sources";
pub const SOURCE_TEXTS: &str = "source_texts";
pub const LOSSLESS: &str = "lossless";
pub const REPLAY: &str = "replay";

/// The name of the recorder's input (and the recording's signal) that mirrors input `input`
/// of source `source`: `source<input`, fed by what feeds that input.
pub fn mirrored(source: &str, input: &str) -> String {
    format!("{source}<{input}")
}

/// The source and input a mirrored signal's name (`source<input`) stands for.
pub fn parse_mirrored(name: &str) -> Option<(&str, &str)> {
    name.split_once('<')
}

/// The `source_texts` param of `texts`: each ended by a NUL character.
pub fn texts_param<'a>(texts: impl Iterator<Item = &'a str>) -> String {
    texts.flat_map(|t| [t, "\0"]).collect()
}

/// The texts of a `source_texts` param (none for an empty one).
pub fn parse_texts(param: &str) -> Vec<&str> {
    param.split_terminator('\0').collect()
}

/// One recorded signal: the output it reads (`comp.port`, also its input's name) and its type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Signal {
    pub name: String,
    pub ty: PortType,
}

/// The `signals` param's text for `signals`.
pub fn signals_text(signals: &[Signal]) -> String {
    let items: Vec<String> = signals
        .iter()
        .map(|s| format!("{}:{}", s.name, s.ty))
        .collect();
    items.join(";")
}

/// The signals of a `signals` param.
pub fn parse_signals(text: &str) -> Result<Vec<Signal>, ParamError> {
    if text.is_empty() {
        return Ok(Vec::new());
    }
    text.split(';')
        .map(|item| {
            let parsed = item
                .rsplit_once(':')
                .and_then(|(name, ty)| Some((name, PortType::parse(ty)?)))
                .filter(|(name, _)| name.contains('.') || parse_mirrored(name).is_some());
            match parsed {
                Some((name, ty)) => Ok(Signal {
                    name: name.to_owned(),
                    ty,
                }),
                None => Err(ParamError::invalid(
                    SIGNALS,
                    format!("has '{item}', which is not comp.port:type"),
                )),
            }
        })
        .collect()
}

/// The units of a `units` param: (signal, unit).
pub fn parse_units(text: &str) -> Vec<(String, String)> {
    text.split(';')
        .filter_map(|item| item.split_once('='))
        .map(|(s, u)| (s.to_owned(), u.to_owned()))
        .collect()
}

/// The `units` param's text for (signal, unit) pairs.
pub fn units_text(units: &[(String, String)]) -> String {
    let items: Vec<String> = units.iter().map(|(s, u)| format!("{s}={u}")).collect();
    items.join(";")
}

/// The interface of a recorder with these params: one input per signal, the `dropped` count.
pub fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let signals = match p.get(SIGNALS) {
        Some(_) => parse_signals(p.text(SIGNALS)?)?,
        None => Vec::new(),
    };
    let text = || ParamValue::Text(String::new());
    Ok(ComponentInfo {
        type_name: TYPE,
        doc: "records its inputs, tick by tick, to an HDF5 file (written off the real-time path)",
        inputs: signals
            .iter()
            .map(|s| PortDecl::new(intern(&s.name), s.ty))
            .collect(),
        outputs: vec![PortDecl::new("dropped", PortType::I64)],
        params: vec![
            ParamDecl::optional(SIGNALS, ParamType::Text, text()),
            ParamDecl::required(FILE, ParamType::Text),
            ParamDecl::optional(UNITS, ParamType::Text, text()),
            ParamDecl::optional(SOURCES, ParamType::Text, text()),
            ParamDecl::optional(SOURCE_TEXTS, ParamType::Text, text()),
            ParamDecl::optional(LOSSLESS, ParamType::Bool, ParamValue::Bool(false)),
            ParamDecl::optional(REPLAY, ParamType::Text, text()),
        ],
    })
}

/// Adds `record` to `registry` as a type the program [`PROGRAM`] makes (unless this process
/// registered it itself).
pub fn declare(registry: &mut Registry) {
    registry.declare_with(info, PROGRAM);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signals_read_back_from_their_text_and_a_bad_one_is_refused() {
        let signals = vec![
            Signal {
                name: "ptp.q".into(),
                ty: PortType::F64s(6),
            },
            Signal {
                name: "robot.statusword".into(),
                ty: PortType::I64,
            },
        ];
        let text = signals_text(&signals);
        assert_eq!(text, "ptp.q:f64[6];robot.statusword:i64");
        assert_eq!(parse_signals(&text).unwrap(), signals);
        let sut = parse_signals("ptp.q:f64[6];q:f64").unwrap_err();
        assert_eq!(
            sut.to_string(),
            "param 'signals' has 'q:f64', which is not comp.port:type"
        );
    }

    #[test]
    fn a_recorder_has_an_input_per_signal_and_counts_what_it_dropped() {
        let p = Params::new()
            .with(SIGNALS, ParamValue::Text("a.y:f64;b.n:i64".into()))
            .with(FILE, ParamValue::Text("/tmp/x.h5".into()));
        let sut = info(&p).unwrap();
        let inputs: Vec<String> = sut
            .inputs
            .iter()
            .map(|p| format!("{}:{}", p.name, p.ty))
            .collect();
        assert_eq!(inputs, ["a.y:f64", "b.n:i64"]);
        assert_eq!(sut.outputs[0].name, "dropped");
    }
}

//! Tests of the data recorder's declaration: `record { ... }` and `modbot up --record FILE`.

use std::path::PathBuf;

use super::*;
use modbot_grid::record_type;
use modbot_grid::{ParamValue, PortType};

/// Every program is found (as itself).
fn found(name: &str) -> Option<PathBuf> {
    Some(PathBuf::from(name))
}

fn load_vars(source: &str, vars: &[(String, String)]) -> Result<SystemSpec, SystemError> {
    load_str_with_vars("robot.lua", source, &found, vars)
}

/// Lines 1 to 8; a record on line 9 (or 10 after a blank line).
const GRID: &str = "domain \"t\"\ngrid {}\n\
    component \"A\" { type = \"ramp\", host = \"h1\" }\n\
    component \"P\" { type = \"pack\", host = \"h1\" }\n\
    component \"V\" { type = \"vec_gain\", host = \"h1\", params = { n = 2, k = 2 } }\n\
    connect \"A.y -> P.a\"\nconnect \"A.y -> P.b\"\n\
    connect \"P.v -> V.u\"\n";

fn recorder(spec: &SystemSpec) -> &modbot_grid::ComponentSpec {
    let grid = spec.grid.as_ref().expect("a grid");
    let c = grid.component("record").expect("a recorder");
    &grid.components[c]
}

fn text<'a>(c: &'a modbot_grid::ComponentSpec, name: &str) -> &'a str {
    c.params.text(name).unwrap()
}

#[test]
fn a_record_becomes_a_component_on_a_host_of_its_own_fed_by_its_signals() {
    let source = format!(
        "{GRID}record {{ signals = {{ \"P.v\", \"A.y\" }}, file = \"/data/run.h5\", \
         units = {{ [\"A.y\"] = \"m\" }} }}\n"
    );
    let spec = load_vars(&source, &[]).unwrap();
    let sut = recorder(&spec);
    assert_eq!(
        (sut.type_name.as_str(), sut.host.as_str()),
        ("record", "record")
    );
    assert_eq!(sut.program.as_deref(), Some(record_type::PROGRAM));
    assert_eq!((sut.period, sut.line), (1, 9));
    let inputs: Vec<(&str, PortType)> = sut.info.inputs.iter().map(|p| (p.name, p.ty)).collect();
    assert_eq!(inputs, [("P.v", PortType::F64s(2)), ("A.y", PortType::F64)]);
    assert_eq!(text(sut, "signals"), "P.v:f64[2];A.y:f64");
    assert_eq!(text(sut, "file"), "/data/run.h5");
    assert_eq!(text(sut, "units"), "A.y=m");
    assert!(text(sut, "sources").ends_with("robot.lua"));
    // The text as loaded: a recorder started later keeps it, whatever the file holds then.
    assert_eq!(
        record_type::parse_texts(text(sut, record_type::SOURCE_TEXTS)),
        [source.as_str()]
    );
    assert_eq!(sut.params.get("lossless"), Some(&ParamValue::Bool(false)));
    let grid = spec.grid.as_ref().unwrap();
    let fed = grid
        .connections
        .iter()
        .filter(|c| c.to.component == grid.component("record").unwrap());
    assert_eq!(fed.count(), 2);
    assert_eq!(
        spec.host_programs,
        [(
            record_type::PROGRAM.to_owned(),
            PathBuf::from(record_type::PROGRAM)
        )]
    );
}

#[test]
fn a_record_of_what_is_not_an_output_is_refused_at_its_line() {
    for (signals, fragment) in [
        (
            "\"A.y\", \"Q.y\"",
            "record 'record': signal 'Q.y' no component is named 'Q'",
        ),
        ("\"A.z\"", "signal 'A.z' 'A' has no output 'z' (outputs: y)"),
        ("\"A.y\", \"A.y\"", "signal 'A.y' is recorded twice"),
        ("\"Ay\"", "signal 'Ay' is not component.port"),
        ("", "there is nothing to record"),
    ] {
        let source = format!("{GRID}\nrecord {{ signals = {{ {signals} }}, file = \"x.h5\" }}\n");
        let sut = load_vars(&source, &[]).unwrap_err();
        assert_eq!(
            (sut.file.as_str(), sut.line),
            ("robot.lua", Some(10)),
            "{sut}"
        );
        assert!(sut.message.contains(fragment), "{sut} lacks {fragment}");
    }
    let no_grid = "domain \"t\"\nmodule \"m\" { addr = 2, program = \"m\" }\n\
                   record { signals = { \"A.y\" }, file = \"x.h5\" }\n";
    let sut = load_vars(no_grid, &[]).unwrap_err();
    assert_eq!(sut.line, Some(3), "{sut}");
    assert!(sut.message.contains("there is no grid to record"), "{sut}");
}

#[test]
fn a_record_without_a_file_runs_only_when_modbot_up_names_one_or_on_demand() {
    let source = format!("{GRID}record {{ signals = {{ \"A.y\" }} }}\n");
    let spec = load_vars(&source, &[]).unwrap();
    assert!(spec.grid.unwrap().component("record").is_none());
    let on_demand = format!("{GRID}record {{ signals = {{ \"A.y\" }}, on_demand = true }}\n");
    let spec = load_vars(&on_demand, &[]).unwrap();
    assert_eq!(
        text(recorder(&spec), "file"),
        "",
        "records when a program says"
    );
    let asked = [(RECORD_VAR.to_owned(), "/data/asked.h5".to_owned())];
    let spec = load_vars(&source, &asked).unwrap();
    assert_eq!(text(recorder(&spec), "file"), "/data/asked.h5");
    assert_eq!(text(recorder(&spec), "signals"), "A.y:f64");
}

#[test]
fn modbot_up_record_without_a_declaration_records_every_output_of_the_system() {
    let asked = [(RECORD_VAR.to_owned(), "/data/all.h5".to_owned())];
    let spec = load_vars(GRID, &asked).unwrap();
    let sut = recorder(&spec);
    assert_eq!(text(sut, "signals"), "A.y:f64;P.v:f64[2];V.y:f64[2]");
    assert_eq!(text(sut, "file"), "/data/all.h5");
}

#[test]
fn a_lockstep_grid_records_without_losing_a_row() {
    let source = format!("{GRID}record {{ signals = {{ \"A.y\" }}, file = \"x.h5\" }}\n")
        .replace("grid {}", "grid { clock = \"lockstep\" }");
    let spec = load_vars(&source, &[]).unwrap();
    assert_eq!(
        recorder(&spec).params.get("lossless"),
        Some(&ParamValue::Bool(true))
    );
    let mut grid = load_vars(&source.replace("clock = \"lockstep\"", ""), &[])
        .unwrap()
        .grid
        .unwrap();
    grid.set_clock(modbot_grid::GridClock::Lockstep);
    let c = grid.component("record").unwrap();
    assert_eq!(
        grid.components[c].params.get("lossless"),
        Some(&ParamValue::Bool(true))
    );
}

//! Tests of FMU components in descriptions: the `fmu` field, where the file is found, the
//! interface read from the project's own FMUs (crate `modbot-fmus`), one host each.

use std::path::PathBuf;

use super::*;
use modbot_grid::{ParamValue, PortType};

fn found(name: &str) -> Option<PathBuf> {
    Some(PathBuf::from(name))
}

/// The system description `body` (after line 2, the grid) in the directory of `modbot_ff2.fmu`,
/// so that the bare name is found beside it.
fn load_beside_the_fmus(body: &str) -> Result<SystemSpec, SystemError> {
    let dir = std::path::Path::new(modbot_fmus::FF2).parent().unwrap();
    let file = dir.join("robot.lua");
    let source = format!("domain \"t\"\ngrid {{}}\n{body}");
    load_str_with_vars(file.to_str().unwrap(), &source, &found, &[])
}

#[test]
fn an_fmu_component_has_the_ports_and_params_of_its_model_description() {
    let spec = load_beside_the_fmus(
        "component \"ff\" { type = \"fmu\", fmu = \"modbot_ff2.fmu\", host = \"h_ff\", \
         params = { Jm = 0.6 } }\n\
         component \"q\" { type = \"vec_gain\", host = \"h\", params = { n = 6, k = 0 } }\n\
         connect \"q.y -> ff.q\"\nconnect \"q.y -> ff.qd\"\nconnect \"q.y -> ff.qdd\"\n\
         connect \"ff.qm -> q.u\"\n",
    )
    .unwrap();
    let grid = spec.grid.unwrap();
    let sut = &grid.components[grid.component("ff").unwrap()];
    let ports = |ps: &[modbot_grid::PortDecl]| -> Vec<(String, PortType)> {
        ps.iter().map(|p| (p.name.to_owned(), p.ty)).collect()
    };
    let six = PortType::F64s(6);
    assert_eq!(
        ports(&sut.info.inputs),
        [("q".into(), six), ("qd".into(), six), ("qdd".into(), six)]
    );
    assert_eq!(
        ports(&sut.info.outputs),
        [("tau".into(), six), ("qm".into(), six)]
    );
    let params: Vec<&str> = sut.info.params.iter().map(|p| p.name).collect();
    assert_eq!(
        params,
        ["fmu", "Jm", "Jl", "k", "b", "tau_c", "omega_c", "Tf"]
    );
    assert_eq!(sut.params.get("Jm"), Some(&ParamValue::F64(0.6)));
    assert_eq!(
        sut.params.text("fmu").unwrap(),
        modbot_fmus::FF2,
        "a bare name is found beside the description"
    );
    assert_eq!(sut.program.as_deref(), Some("modbot-fmu-host"));
    assert!(sut
        .info
        .doc
        .starts_with("FMI 2.0 co-simulation FMU 'modbot_ff2'"));
}

#[test]
fn the_fmu_field_names_the_file_of_an_fmu_component_only() {
    let sut = load_beside_the_fmus(
        "component \"g\" { type = \"gain\", host = \"h\", fmu = \"modbot_ff2.fmu\", params = { k = 1 } }\n",
    )
    .unwrap_err();
    assert_eq!(sut.line, Some(3), "{sut}");
    assert!(
        sut.message
            .contains("'fmu' names the file of a component of type \"fmu\""),
        "{sut}"
    );
}

#[test]
fn an_fmi3_fmu_takes_its_parameters_by_type() {
    let body = |params: &str| {
        format!(
            "component \"lp\" {{ type = \"fmu\", fmu = \"modbot_filter3.fmu\", host = \"h_lp\", \
             params = {{ {params} }} }}\n\
             component \"s\" {{ type = \"sine\", host = \"h\" }}\nconnect \"s.y -> lp.u\"\n"
        )
    };
    let spec = load_beside_the_fmus(&body("k = 2, T = 0.5")).unwrap();
    let grid = spec.grid.unwrap();
    let sut = &grid.components[grid.component("lp").unwrap()];
    assert!(sut
        .info
        .doc
        .starts_with("FMI 3.0 co-simulation FMU 'modbot_filter3'"));
    let sut = load_beside_the_fmus(&body("T = \"slow\"")).unwrap_err();
    assert!(sut.message.contains("param 'T' must be f64"), "{sut}");
}

//! The interfaces of the project's FMUs, and of broken ones.

use std::io::Write;

use super::*;

/// `name:type` of every port.
fn names(ports: &[Port]) -> Vec<String> {
    ports
        .iter()
        .map(|p| format!("{}:{}", p.name, p.ty))
        .collect()
}

#[test]
fn the_fmi2_feed_forward_has_array_ports_gathered_from_its_elements() {
    let sut = Interface::read(Path::new(modbot_fmus::FF2)).unwrap();
    assert_eq!(
        (sut.version, sut.model_identifier.as_str()),
        (Version::Fmi2, "modbot_ff2")
    );
    assert_eq!(names(&sut.inputs), ["q:f64[6]", "qd:f64[6]", "qdd:f64[6]"]);
    assert_eq!(names(&sut.outputs), ["tau:f64[6]", "qm:f64[6]"]);
    assert_eq!(sut.inputs[1].refs, [6, 7, 8, 9, 10, 11]);
    let jl = sut.params.iter().find(|p| p.name == "Jl").unwrap();
    assert_eq!(
        (jl.kind, jl.start.clone(), jl.refs.clone()),
        (Kind::Real, ParamValue::F64(2.0), vec![31])
    );
}

#[test]
fn the_fmi3_filter_has_scalar_ports_and_its_parameters() {
    let sut = Interface::read(Path::new(modbot_fmus::FILTER3)).unwrap();
    assert_eq!(sut.version, Version::Fmi3);
    assert_eq!((sut.inputs.len(), sut.outputs.len()), (1, 1));
    assert_eq!(
        (sut.inputs[0].name.as_str(), sut.inputs[0].ty),
        ("u", PortType::F64)
    );
    let params: Vec<&str> = sut.params.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(params, ["k", "T"]);
}

/// A zip archive at a path of the test's own with `entries`.
fn archive(tag: &str, entries: &[(&str, &[u8])]) -> std::path::PathBuf {
    let path = std::env::temp_dir().join(format!("modbot-fmu-{tag}-{}.fmu", std::process::id()));
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
    for (name, bytes) in entries {
        zip.start_file(*name, zip::write::SimpleFileOptions::default())
            .unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap();
    path
}

#[test]
fn a_broken_fmu_is_refused_saying_what_is_wrong_with_it() {
    let xml = archive::model_description(Path::new(modbot_fmus::FF2)).unwrap();
    type Case<'a> = (&'a str, &'a [(&'a str, &'a [u8])], &'a str);
    let cases: [Case; 4] = [
        ("nomd", &[("x.txt", b"x")], "has no modelDescription.xml"),
        (
            "badxml",
            &[("modelDescription.xml", b"<fmiModelDescription")],
            "modelDescription.xml is not valid",
        ),
        (
            "nobin",
            &[("modelDescription.xml", xml.as_bytes())],
            "has no binary for this platform: binaries/linux64/modbot_ff2.so",
        ),
        (
            "v1",
            &[(
                "modelDescription.xml",
                b"<fmiModelDescription fmiVersion=\"1.0\" modelName=\"m\"/>",
            )],
            "is FMI version '1.0'",
        ),
    ];
    for (tag, entries, expected) in cases {
        let path = archive(tag, entries);
        let sut = Interface::read(&path).unwrap_err().to_string();
        assert!(
            sut.starts_with(&path.display().to_string()) && sut.contains(expected),
            "{tag}: {sut}"
        );
        let _ = std::fs::remove_file(&path);
    }
}

#[test]
fn the_fmi3_state_space_has_matrix_parameters_and_arrays_its_structural_parameters_size() {
    let sut = Interface::read(Path::new(modbot_fmus::SS3)).unwrap();
    assert_eq!(names(&sut.inputs), ["u:f64[1]"]);
    assert_eq!(names(&sut.outputs), ["y:f64[1]"]);
    let params: Vec<&str> = sut.params.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(params, ["nx", "nu", "ny", "A", "B", "C", "D", "x0"]);
    let nx = &sut.params[0];
    assert!(nx.structural && nx.kind == Kind::UInt64 && nx.ty == ParamType::I64);
    assert_eq!(nx.range.text(), "from 1 to 8");
    let a = &sut.params[3];
    assert_eq!(
        (a.dims.clone(), a.start.clone()),
        (vec![2, 2], ParamValue::F64s(vec![0.0, 1.0, -1.0, -0.2])),
        "A is 2×2, row-major"
    );

    let p = Params::new()
        .with("nx", ParamValue::I64(3))
        .with("ny", ParamValue::I64(2));
    let sut = sut.sized(&p).unwrap();
    assert_eq!(names(&sut.inputs), ["u:f64[1]"]);
    assert_eq!(names(&sut.outputs), ["y:f64[2]"]);
    let dims: Vec<Vec<u64>> = sut.params.iter().map(|p| p.dims.clone()).collect();
    assert_eq!(
        dims[3..],
        [vec![3, 3], vec![3, 1], vec![2, 3], vec![2, 1], vec![3]]
    );
    let ParamValue::F64s(a) = &sut.params[3].start else {
        panic!("A is a list");
    };
    assert_eq!(a.len(), 9, "its default has the new size");
}

#[test]
fn an_fmi2_integer_parameter_has_its_declared_range() {
    let sut = Interface::read(Path::new(modbot_fmus::STAIR2)).unwrap();
    assert_eq!(names(&sut.inputs), ["step:i64"]);
    assert_eq!(names(&sut.outputs), ["counter:i64"]);
    let start = sut.params.iter().find(|p| p.name == "start").unwrap();
    assert_eq!(
        (start.kind, start.range.text()),
        (Kind::Int32, "from -1000 to 1000".to_owned())
    );
}

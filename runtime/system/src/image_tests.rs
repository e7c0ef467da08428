//! Every example's checked grid, and every assembly of it, survives the image the supervisor
//! writes for the grid's processes: what a process reads is what the supervisor checked.

use std::path::{Path, PathBuf};

use super::{assembly_names, load_assembly, load_with_vars};
use modbot_grid::GridSpec;

/// `spec` as a grid process gets it: without the loader's context.
fn as_read(spec: &GridSpec) -> GridSpec {
    let mut read = spec.clone();
    if let Some(a) = &mut read.assembly {
        a.source = None;
    }
    read
}

fn round_trip(what: &str, spec: &GridSpec) -> usize {
    let image = spec.to_image();
    let back = GridSpec::from_image(&image).unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_eq!(back, as_read(spec), "{what}");
    assert_eq!(back.to_image(), image, "{what}: encoded again");
    image.len()
}

#[test]
fn every_examples_grid_and_assembly_reads_back_from_its_image_as_it_was_checked() {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let any_program = |name: &str| Some(PathBuf::from(format!("/usr/bin/{name}")));
    let registry = modbot_components::builtin();
    let mut grids = 0;
    for file in [
        "grid_demo.lua",
        "arm.lua",
        "kr16.lua",
        "moser.lua",
        "mra_demo.lua",
    ] {
        let path = examples.join(file);
        let spec = load_with_vars(&path, &any_program, &[]).unwrap_or_else(|e| panic!("{e}"));
        let Some(grid) = spec.grid else {
            continue;
        };
        grids += 1;
        let len = round_trip(file, &grid);
        println!("{file}: {len} bytes");
        let Some(source) = grid.assembly.as_ref().and_then(|a| a.source.clone()) else {
            continue;
        };
        // ptp_fmu's FMU is found beside the programs when the system runs: an FMU's grid is
        // the next test's.
        let names = assembly_names(&source.dir)
            .into_iter()
            .filter(|n| n != "ptp_fmu");
        for (g, name) in (2..).zip(names) {
            let what = format!("{file} with assembly {name}");
            let spec = load_assembly(
                &grid,
                &name,
                modbot_grid::component::Generation(g),
                &registry,
            )
            .unwrap_or_else(|e| panic!("{what}: {e}"));
            let len = round_trip(&what, &spec);
            println!("{what}: {len} bytes");
        }
    }
    assert!(grids >= 3, "{grids} examples with a grid");
}

#[test]
fn a_grid_with_an_fmu_reads_back_with_the_interface_its_model_description_gave() {
    let dir = Path::new(modbot_fmus::FF2).parent().unwrap();
    let source = "domain \"t\"\ngrid {}\n\
        component \"ff\" { type = \"fmu\", fmu = \"modbot_ff2.fmu\", host = \"h_ff\", params = { Jm = 0.6 } }\n\
        component \"q\" { type = \"vec_gain\", host = \"h\", params = { n = 6, k = 0 } }\n\
        connect \"q.y -> ff.q\"\nconnect \"q.y -> ff.qd\"\nconnect \"q.y -> ff.qdd\"\n\
        connect \"ff.qm -> q.u\"\n";
    let file = dir.join("robot.lua");
    let found = |name: &str| Some(PathBuf::from(name));
    let spec = super::load_str_with_vars(file.to_str().unwrap(), source, &found, &[]).unwrap();
    round_trip("fmu", &spec.grid.unwrap());
}

/// `modbot up FILE --domain D` runs the system in D from the start: its assembly files read
/// D's assembly data — where a robot program in D writes its commands' parameters — not the
/// data of the domain the description names (a program's moves then found no goal, and the
/// arm stood still).
#[test]
fn a_system_loaded_in_another_domain_reads_that_domains_assembly_data() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/kr16.lua");
    let any_program = |name: &str| Some(PathBuf::from(format!("/usr/bin/{name}")));
    let data_of = |domain: Option<&str>| {
        let spec = super::load_in_domain(&path, &any_program, &[], domain)
            .unwrap_or_else(|e| panic!("{e}"));
        let source = spec.grid.and_then(|g| g.assembly).and_then(|a| a.source);
        (spec.domain, source.and_then(|s| s.data.clone()))
    };
    assert_eq!(
        data_of(None),
        ("kr16".to_owned(), Some(modbot_data::path_for("kr16")))
    );
    assert_eq!(
        data_of(Some("kr16_elsewhere")),
        (
            "kr16_elsewhere".to_owned(),
            Some(modbot_data::path_for("kr16_elsewhere"))
        )
    );
    let refused = super::load_in_domain(&path, &any_program, &[], Some("no/slash"))
        .expect_err("a domain name with a slash");
    assert!(refused.to_string().contains("no/slash"), "{refused}");
}

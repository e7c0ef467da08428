//! Prints the FMU's modelDescription.xml, from what `export_fmu!` says of its variables (what
//! cargo-fmi's bundler does, without loading the library: this program links it).

use fmi::fmi3::schema;

/// The model identifier: the cdylib's name, and so its binary's name in the FMU.
const MODEL_IDENTIFIER: &str = "modbot_filter3";

fn main() {
    let metadata = modbot_filter3::model_metadata();
    let description = schema::Fmi3ModelDescription {
        fmi_version: "3.0".to_owned(),
        model_name: MODEL_IDENTIFIER.to_owned(),
        instantiation_token: modbot_filter3::FMI3_INSTANTIATION_TOKEN.to_owned(),
        description: Some(env!("CARGO_PKG_DESCRIPTION").to_owned()),
        version: Some(env!("CARGO_PKG_VERSION").to_owned()),
        license: Some(env!("CARGO_PKG_LICENSE").to_owned()),
        generation_tool: Some("modbot (fmi-export)".to_owned()),
        model_variables: metadata.model_variables,
        model_structure: metadata.model_structure,
        co_simulation: Some(schema::Fmi3CoSimulation {
            model_identifier: MODEL_IDENTIFIER.to_owned(),
            can_handle_variable_communication_step_size: Some(true),
            has_event_mode: Some(false),
            ..Default::default()
        }),
        ..Default::default()
    };
    match fmi::schema::serialize(&description, false) {
        Ok(xml) => println!("{xml}"),
        Err(e) => {
            eprintln!("modbot-filter3-describe: {e}");
            std::process::exit(1);
        }
    }
}

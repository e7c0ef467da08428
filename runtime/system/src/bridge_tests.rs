//! Tests of `bridge { ... }`: the module it becomes, the names its imports hold, its errors.

use std::path::PathBuf;

use super::*;

fn load_text(source: &str) -> Result<SystemSpec, SystemError> {
    let known = |program: &str| {
        ["modbot-sonar", "modbot-zenoh"]
            .contains(&program)
            .then(|| PathBuf::from("/opt/modbot/bin").join(program))
    };
    load_str("robot.lua", source, &known)
}

#[test]
fn a_bridge_becomes_a_module_running_modbot_zenoh_with_its_exports_and_imports() {
    let spec = load_text(
        r#"domain "robot"
module "sonar" { addr = 3, program = "modbot-sonar" }
bridge { addr = 200, listen = { "tcp/10.0.0.1:7447" }, mode = "peer", lease_ms = 1000,
         snapshot_hz = 2.5,
         exports = { "sonar", high_level = { "patrol", "stop" } },
         imports = { control_station = { addr = 20, domain = "station" },
                     base_mobility = { addr = 41, domain = "base", module = "mobility" } } }
"#,
    )
    .unwrap();
    let bridge = spec.modules.iter().find(|m| m.name == "bridge").unwrap();
    assert_eq!(bridge.addr, 200);
    assert_eq!(bridge.program_name, "modbot-zenoh");
    assert_eq!(bridge.line, 3);
    assert_eq!(
        bridge.args,
        [
            "--zenoh-mode",
            "peer",
            "--listen",
            "tcp/10.0.0.1:7447",
            "--lease-ms",
            "1000",
            "--snapshot-hz",
            "2.5",
            "--export",
            "high_level:patrol,stop",
            "--export",
            "sonar",
            "--import",
            "base_mobility@41=base/mobility",
            "--import",
            "control_station@20=station/control_station",
        ]
    );
    let imported: Vec<(&str, u8)> = spec
        .imported
        .iter()
        .map(|i| (i.name.as_str(), i.addr))
        .collect();
    assert_eq!(imported, [("base_mobility", 41), ("control_station", 20)]);
}

#[test]
fn an_import_on_a_modules_name_or_address_and_a_second_bridge_are_refused_with_their_line() {
    let clash = |imports: &str| {
        let text = format!(
            "domain \"robot\"\nmodule \"sonar\" {{ addr = 3, program = \"modbot-sonar\" }}\n\
             bridge {{ addr = 200, imports = {{ {imports} }} }}\n"
        );
        load_text(&text).unwrap_err()
    };
    let e = clash("sonar = { addr = 20, domain = \"station\" }");
    assert_eq!(e.line, Some(3), "{e}");
    assert!(
        e.message
            .contains("import 'sonar' has the name of a module"),
        "{e}"
    );
    let e = clash("x = { addr = 3, domain = \"station\" }");
    assert!(
        e.message.contains("address 3 is already used by 'sonar'"),
        "{e}"
    );
    let e = clash("x = { addr = 30 }");
    assert!(e.message.contains("domain"), "{e}");
    let e =
        load_text("domain \"robot\"\nbridge { addr = 200 }\nbridge { addr = 201 }\n").unwrap_err();
    assert_eq!(e.line, Some(3), "{e}");
    let e = load_text("domain \"robot\"\nbridge { addr = 200, listen = { \"10.0.0.1\" } }\n")
        .unwrap_err();
    assert!(e.message.contains("is no Zenoh endpoint"), "{e}");
    let e = load_text("domain \"robot\"\nbridge { listen = { \"tcp/1.2.3.4:1\" } }\n").unwrap_err();
    assert!(e.message.contains("addr"), "{e}");
    let e = load_text("domain \"robot\"\nbridge { addr = 200, snapshot_hz = -1 }\n").unwrap_err();
    assert!(
        e.message.contains("snapshot_hz") && e.message.contains("from 0 (never) to 1000"),
        "{e}"
    );
}

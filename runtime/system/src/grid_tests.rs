//! Tests of the grid in the system description: the language, and every error with its line.

use std::time::Duration;

use super::*;
use modbot_grid::component::{Component, ComponentError, ComponentInfo, PortDecl, Released};
use modbot_grid::{OverrunPolicy, ParamValue, PortRef, PortType, PortValue};

fn load_text(source: &str) -> Result<SystemSpec, SystemError> {
    load_str("robot.lua", source, &|_: &str| None)
}

fn grid_of(source: &str) -> GridSpec {
    match load_text(source) {
        Ok(spec) => spec.grid.expect("a grid"),
        Err(e) => panic!("{e}"),
    }
}

/// Loads `source`, expecting an error on `line` whose message contains `fragment`.
#[track_caller]
fn assert_error(source: &str, line: Option<u32>, fragment: &str) {
    assert_error_with(&modbot_components::builtin(), source, line, fragment);
}

#[track_caller]
fn assert_error_with(registry: &Registry, source: &str, line: Option<u32>, fragment: &str) {
    let sut = match load_str_with_registry("robot.lua", source, &|_: &str| None, &[], registry) {
        Ok(spec) => panic!("expected an error containing {fragment:?}, got {spec:#?}"),
        Err(e) => e,
    };
    assert_eq!(sut.file, "robot.lua", "{sut}");
    assert_eq!(sut.line, line, "{sut}");
    assert!(
        sut.message.contains(fragment),
        "{sut:?} does not contain {fragment:?}"
    );
}

/// A description with a grid: line 1 the domain, line 2 the grid, then `body` from line 3.
fn with_grid(body: &str) -> String {
    format!("domain \"t\"\ngrid {{}}\n{body}")
}

// ---- the language ----

#[test]
fn the_grid_keeps_real_time_by_default_and_lockstep_when_asked() {
    let g = grid_of(&with_grid(
        "component \"A\" { type = \"counter\", host = \"h\" }",
    ));
    assert_eq!(g.timing, modbot_grid::GridTiming::default());
    assert_eq!(g.timing.clock, modbot_grid::GridClock::RealTime);
    let g = grid_of(
        "domain \"t\"\ngrid { clock = \"lockstep\", track_ticks = 80, spin_us = 20 }\n\
         component \"A\" { type = \"counter\", host = \"h\" }",
    );
    assert_eq!(g.timing.clock, modbot_grid::GridClock::Lockstep);
    assert_eq!((g.timing.track_ticks, g.timing.spin_us), (80, 20));
    assert_error(
        "domain \"t\"\ngrid { clock = \"fast\" }",
        Some(2),
        "field 'clock' must be \"realtime\" or \"lockstep\", not \"fast\"",
    );
    assert_error(
        "domain \"t\"\ngrid { track_ticks = -1 }",
        Some(2),
        "field 'track_ticks' must be an integer from 0 to 1000000",
    );
}

#[test]
fn grid_alone_is_a_system_and_every_field_is_read() {
    let source = r#"domain "t"
grid { base_period = 0.0005, cpus = { 2, 0 }, priority = 80, mlock = true }
component "A" { type = "counter", host = "h1", period = 1, params = { start = 5 } }
component "B" { type = "gain", host = "h2", period_s = 0.003, params = { k = 2 }, policy = "fault" }
component "C" { type = "sum", host = "h1", period = 2.0 }
component "V" { type = "vec_gain", host = "h2", params = { n = 2, k = 0.5 } }
component "P" { type = "pack", host = "h3" }
connect "B.y -> C.b"
connect("B.y", "C.a")
connect "  P.v->V.u "
connect "B.y -> P.a"
connect "C.y -> P.b"
connect "C.y -> B.u"
"#;
    let spec = load_text(source).unwrap();
    assert!(spec.modules.is_empty());
    let sut = spec.grid.unwrap();
    assert_eq!(sut.base_period, Duration::from_micros(500));
    assert_eq!(
        (sut.cpus.as_slice(), sut.priority, sut.mlock),
        (&[0, 2][..], Some(80), true)
    );
    assert_eq!(sut.line, 2);
    let periods: Vec<u64> = sut.components.iter().map(|c| c.period).collect();
    assert_eq!(periods, [1, 6, 2, 1, 1]);
    let b = &sut.components[1];
    assert_eq!(
        (b.name.as_str(), b.type_name.as_str(), b.host.as_str()),
        ("B", "gain", "h2")
    );
    assert_eq!((b.policy, b.line), (OverrunPolicy::Fault, 4));
    assert_eq!(sut.components[0].policy, OverrunPolicy::Hold);
    assert_eq!(b.params.f64("k"), Ok(2.0));
    assert_eq!(b.params.f64("base_period_s"), Ok(0.0005));
    assert_eq!(b.params.f64("period_s"), Ok(6.0 * 0.0005));
    assert_eq!(sut.components[0].params.i64("start"), Ok(5));
    assert_eq!(sut.hosts(), ["h1", "h2", "h3"]);
    assert_eq!(sut.components_of("h2"), [1, 3]);
    assert_eq!(sut.output_types(3), [PortType::F64s(2)]);
    assert_eq!(sut.sources(1), [2]);
    assert_eq!(sut.sources(2), [1]);
    assert_eq!(sut.sources(4), [1, 2]);
    assert_eq!(sut.input_binding(4, 1), (1, 0));
    assert_eq!(sut.input_binding(2, 0), (0, 0));
    assert_eq!(
        (
            sut.connections[2].from,
            sut.connections[2].to,
            sut.connections[2].line
        ),
        (
            PortRef {
                component: 4,
                port: 0
            },
            PortRef {
                component: 3,
                port: 0
            },
            10
        )
    );
}

#[test]
fn grid_defaults_to_one_millisecond_and_components_to_period_one() {
    let sut =
        grid_of("domain \"t\"\ngrid {}\ncomponent \"A\" { type = \"counter\", host = \"h\" }\n");
    assert_eq!(sut.base_period, Duration::from_millis(1));
    assert!(sut.cpus.is_empty() && sut.priority.is_none() && !sut.mlock);
    assert_eq!(sut.components[0].period, 1);
}

#[test]
fn modules_and_a_grid_live_in_one_description() {
    let source = r#"domain "t"
module "m" { addr = 1, program = "anything" }
grid {}
component "A" { type = "ramp", host = "h" }
"#;
    let resolver = |p: &str| Some(std::path::PathBuf::from(p));
    let sut = load_str("robot.lua", source, &resolver).unwrap();
    assert_eq!(sut.modules.len(), 1);
    assert_eq!(sut.grid.unwrap().components.len(), 1);
}

#[test]
fn component_without_connections_or_with_a_self_loop_is_valid() {
    let sut = grid_of(&with_grid(
        "component \"S\" { type = \"sum\", host = \"h\" }\nconnect \"S.y -> S.a\"\nconnect \"S.y -> S.b\"\n",
    ));
    assert_eq!(sut.sources(0), [0]);
}

// ---- errors, each with its line ----

#[test]
fn period_that_is_not_a_multiple_of_the_base_tick_is_refused() {
    let body = "component \"A\" { type = \"ramp\", host = \"h\" }\n\
                component \"B\" { type = \"ramp\", host = \"h\", period_s = 0.0025 }\n";
    assert_error(
        &with_grid(body),
        Some(4),
        "component 'B': period 0.0025 s is not a multiple of the base tick (0.001 s)",
    );
    let body = "component \"B\" { type = \"ramp\", host = \"h\", period = 1.5 }\n";
    assert_error(
        &with_grid(body),
        Some(3),
        "component 'B': period 1.5 ticks (0.0015 s) is not a multiple of the base tick (0.001 s)",
    );
    for bad in ["period = 0", "period = -2", "period_s = 0"] {
        let body = format!("component \"B\" {{ type = \"ramp\", host = \"h\", {bad} }}\n");
        assert_error(&with_grid(&body), Some(3), "period must be positive");
    }
    let body = "component \"B\" { type = \"ramp\", host = \"h\", period = 2, period_s = 0.002 }\n";
    assert_error(&with_grid(body), Some(3), "not both");
    let body = "component \"B\" { type = \"ramp\", host = \"h\", period = \"2\" }\n";
    assert_error(
        &with_grid(body),
        Some(3),
        "field 'period' must be a number of base ticks",
    );
}

#[test]
fn unknown_component_type_is_refused_listing_the_known_ones() {
    assert_error(
        &with_grid("\ncomponent \"A\" { type = \"gian\", host = \"h\" }\n"),
        Some(4),
        "component 'A': unknown component type 'gian' (known: counter, ramp, sine, gain, sum, \
         integrator, lowpass, delay, vec_gain, pack, sleeper, ptp, hold_position, feedforward, \
         cascade, monitor, waypoints, setpoint, settle, bessel, joint_ff, bus, drive_enable, \
         record, fmu)",
    );
}

#[test]
fn unknown_missing_or_wrongly_typed_param_is_refused() {
    let gain = |params: &str| {
        with_grid(&format!(
            "component \"B\" {{ type = \"gain\", host = \"h\"{params} }}\n"
        ))
    };
    assert_error(
        &gain(""),
        Some(3),
        "component 'B': param 'k' (f64) is required for type 'gain'",
    );
    assert_error(
        &gain(", params = { k = 1, q = 2 }"),
        Some(3),
        "component 'B': unknown param 'q' for type 'gain' (params: k)",
    );
    assert_error(
        &gain(", params = { k = \"big\" }"),
        Some(3),
        "component 'B': param 'k' must be f64, not \"big\"",
    );
    assert_error(
        &gain(", params = { k = { 1, 2 } }"),
        Some(3),
        "component 'B': param 'k' must be f64, not {1.0, 2.0}",
    );
    assert_error(
        &gain(", params = { k = print }"),
        Some(3),
        "param 'k' must be a boolean, a number, a string or a list of numbers",
    );
    assert_error(
        &gain(", params = { 1 }"),
        Some(3),
        "params are written name = value",
    );
    assert_error(
        &gain(", params = { k = 1, period_s = 1 }"),
        Some(3),
        "component 'B': param 'period_s' is set automatically and cannot be given",
    );
    let counter =
        "component \"A\" { type = \"counter\", host = \"h\", params = { start = 1.5 } }\n";
    assert_error(
        &with_grid(counter),
        Some(3),
        "param 'start' must be i64, not 1.5",
    );
    let vec = "component \"V\" { type = \"vec_gain\", host = \"h\", params = { n = 65, k = 1 } }\n";
    assert_error(
        &with_grid(vec),
        Some(3),
        "component 'V': param 'n' must be from 1 to 64",
    );
}

#[test]
fn unknown_port_is_refused_listing_the_ports() {
    let body = "component \"A\" { type = \"ramp\", host = \"h\" }\n\
                component \"B\" { type = \"gain\", host = \"h\", params = { k = 1 } }\n\
                connect \"A.y -> B.u\"\nconnect \"A.y -> B.v\"\n";
    assert_error(
        &with_grid(body),
        Some(6),
        "component 'B' has no input 'v' (inputs: u)",
    );
    let body = "component \"A\" { type = \"ramp\", host = \"h\" }\n\
                component \"B\" { type = \"gain\", host = \"h\", params = { k = 1 } }\n\
                connect \"A.x -> B.u\"\n";
    assert_error(
        &with_grid(body),
        Some(5),
        "component 'A' has no output 'x' (outputs: y)",
    );
}

#[test]
fn connected_ports_must_have_exactly_the_same_type() {
    let body = "component \"A\" { type = \"counter\", host = \"h\" }\n\
                component \"B\" { type = \"gain\", host = \"h\", params = { k = 1 } }\n\
                connect \"A.y -> B.u\"\n";
    assert_error(&with_grid(body), Some(5), "A.y is i64 but B.u is f64");
    let body = "component \"A\" { type = \"vec_gain\", host = \"h\", params = { n = 3, k = 1 } }\n\
                component \"B\" { type = \"vec_gain\", host = \"h\", params = { n = 2, k = 1 } }\n\
                connect \"A.y -> B.u\"\n";
    assert_error(&with_grid(body), Some(5), "A.y is f64[3] but B.u is f64[2]");
}

#[test]
fn input_connected_twice_or_not_at_all_is_refused() {
    let body = "component \"A\" { type = \"ramp\", host = \"h\" }\n\
                component \"B\" { type = \"gain\", host = \"h\", params = { k = 1 } }\n\
                connect \"A.y -> B.u\"\n\
                connect \"B.y -> B.u\"\n";
    assert_error(
        &with_grid(body),
        Some(6),
        "B.u is already connected (from A.y at line 5)",
    );
    let body = "component \"A\" { type = \"ramp\", host = \"h\" }\n\
                component \"S\" { type = \"sum\", host = \"h\" }\n\
                connect \"A.y -> S.a\"\n";
    assert_error(
        &with_grid(body),
        Some(4),
        "component 'S': input 'b' is not connected",
    );
}

#[test]
fn connection_to_an_unknown_component_or_malformed_is_refused() {
    let body = "component \"A\" { type = \"ramp\", host = \"h\" }\nconnect \"A.y -> X.u\"\n";
    assert_error(
        &with_grid(body),
        Some(4),
        "connect A.y -> X.u: no component is named 'X' (components: A)",
    );
    for (bad, fragment) in [
        ("connect \"A.y B.u\"", "has no '->'"),
        ("connect \"Ay -> B.u\"", "'Ay' is not component.port"),
        ("connect(\"A.y\")", "'A.y' has no '->'"),
        (
            "connect(\"A.y\", 2)",
            "connect takes an output and an input",
        ),
        ("connect()", "connect takes an output and an input"),
    ] {
        assert_error(&with_grid(&format!("\n{bad}\n")), Some(4), fragment);
    }
}

#[test]
fn duplicate_component_name_is_refused() {
    let body = "component \"A\" { type = \"ramp\", host = \"h\" }\n\
                component \"A\" { type = \"ramp\", host = \"h\" }\n";
    assert_error(
        &with_grid(body),
        Some(4),
        "component name 'A' is already declared at line 3",
    );
}

/// A type with 17 inputs, to feed one component from more sources than a release notice holds.
fn wide_info(_: &modbot_grid::Params) -> Result<ComponentInfo, ComponentError> {
    const NAMES: [&str; 17] = [
        "u0", "u1", "u2", "u3", "u4", "u5", "u6", "u7", "u8", "u9", "u10", "u11", "u12", "u13",
        "u14", "u15", "u16",
    ];
    Ok(ComponentInfo {
        type_name: "wide",
        doc: "17 inputs",
        inputs: NAMES
            .iter()
            .map(|&n| PortDecl::new(n, PortType::F64))
            .collect(),
        outputs: vec![],
        params: vec![],
    })
}

struct Wide;

impl Component for Wide {
    fn step(&mut self, _: &Released, _: &[PortValue], _: &mut [PortValue]) {}
}

#[test]
fn more_than_16_source_components_is_refused() {
    let mut registry = modbot_components::builtin();
    registry.register(wide_info, |_| Ok(Box::new(Wide)));
    let source = |sources: usize| {
        let mut body = String::from("component \"W\" { type = \"wide\", host = \"h\" }\n");
        for i in 0..17 {
            body += &format!(
                "component \"R{i}\" {{ type = \"ramp\", host = \"h\" }}\nconnect \"R{}.y -> W.u{i}\"\n",
                i % sources
            );
        }
        with_grid(&body)
    };
    let ok = load_str_with_registry("robot.lua", &source(16), &|_: &str| None, &[], &registry);
    assert_eq!(ok.unwrap().grid.unwrap().sources(0).len(), 16);
    assert_error_with(
        &registry,
        &source(17),
        Some(3),
        "component 'W' is fed by 17 components; at most 16",
    );
}

#[test]
fn more_than_65535_components_is_refused() {
    let source = "domain \"t\"\ngrid {}\nfor i = 1, 65536 do\n  component(\"c\" .. i) { type = \"counter\", host = \"h\" }\nend\n";
    assert_error(
        source,
        Some(4),
        "too many component declarations (at most 65535)",
    );
}

#[test]
fn grid_declared_twice_or_missing_or_empty_is_refused() {
    assert_error(
        "domain \"t\"\ngrid {}\n\ngrid { base_period = 0.002 }\n",
        Some(4),
        "grid is already declared at line 2",
    );
    assert_error(
        "domain \"t\"\n\ncomponent \"A\" { type = \"ramp\", host = \"h\" }\n",
        Some(3),
        "there is no grid for the components",
    );
    assert_error(
        "domain \"t\"\nconnect \"A.y -> B.u\"\n",
        Some(2),
        "there is no grid for the components",
    );
    assert_error(
        "domain \"t\"\ngrid {}\n",
        Some(2),
        "the grid has no components",
    );
}

#[test]
fn bad_grid_fields_are_refused() {
    for (field, fragment) in [
        (
            "base_period = 0",
            "field 'base_period' must be a positive number of seconds",
        ),
        (
            "base_period = \"1ms\"",
            "field 'base_period' must be a positive number",
        ),
        ("base_period = 1e-12", "shorter than 1 ns"),
        (
            "priority = 100",
            "field 'priority' must be an integer from 1 to 99",
        ),
        (
            "cpus = { -1 }",
            "field 'cpus' must be a list of CPU indices",
        ),
        ("mlock = 1", "field 'mlock' must be true or false"),
        (
            "rate = 1",
            "grid: unknown field 'rate' (expected base_period, cpus, priority, mlock, assemblies, assembly, clock, track_ticks, spin_us)",
        ),
    ] {
        assert_error(
            &format!("domain \"t\"\n\ngrid {{ {field} }}\n"),
            Some(3),
            fragment,
        );
    }
    assert_error(
        "domain \"t\"\ngrid()\n",
        Some(2),
        "expected one argument but got 0",
    );
}

#[test]
fn bad_component_fields_are_refused() {
    for (fields, fragment) in [
        ("host = \"h\"", "component 'A': field 'type' is required"),
        ("type = \"ramp\"", "component 'A': field 'host' is required"),
        ("type = \"ramp\", host = \"H1\"", "host name 'H1' is invalid"),
        ("type = \"ramp\", host = \"\"", "host name '' is invalid"),
        (
            "type = \"ramp\", host = \"ctrl_g2\"",
            "host name 'ctrl_g2' is invalid: use 1 to 32 characters of a-z, 0-9 and _, not ending in _g and a number",
        ),
        (
            "type = \"ramp\", host = \"a_very_long_host_name_of_33_chars\"",
            "host name 'a_very_long_host_name_of_33_chars' is invalid",
        ),
        ("type = \"ramp\", host = \"h\", policy = \"skip\"", "field 'policy' must be \"hold\" or \"fault\", not 'skip'"),
        ("type = \"ramp\", host = \"h\", params = 3", "field 'params' must be a table"),
        ("type = \"ramp\", host = \"h\", rate = 3", "component 'A': unknown field 'rate' (expected type, host, period, period_s, params, policy, fmu)"),
    ] {
        let source = with_grid(&format!("component \"A\" {{ {fields} }}\n"));
        assert_error(&source, Some(3), fragment);
    }
    assert_error(
        &with_grid("component \"a.b\" { type = \"ramp\", host = \"h\" }\n"),
        Some(3),
        "component name 'a.b' is invalid",
    );
    assert_error(
        &with_grid("component \"A\"\n"),
        Some(3),
        "component 'A' is declared without its table: write component \"A\" { type = ..., host = ... }",
    );
}

#[test]
fn params_of_every_type_reach_the_spec() {
    let sut = grid_of(&with_grid(
        "component \"A\" { type = \"sleeper\", host = \"h\", params = { sleep_ms = 2, sleep_at = 4.0 } }\n\
         connect \"A.y -> A.u\"\n",
    ));
    let params = &sut.components[0].params;
    assert_eq!(params.f64("sleep_ms"), Ok(2.0));
    assert_eq!(params.i64("sleep_at"), Ok(4));
    assert_eq!(params.get("base_period_s"), Some(&ParamValue::F64(0.001)));
}

#[test]
fn a_chain_of_65535_components_loads() {
    let source = r#"domain "t"
grid {}
component "c1" { type = "ramp", host = "h" }
for i = 2, 65535 do
  component("c" .. i) { type = "gain", host = "h" .. (i % 7), params = { k = 1 } }
  connect(("c%d.y"):format(i - 1), ("c%d.u"):format(i))
end
"#;
    let started = std::time::Instant::now();
    let sut = grid_of(source);
    assert_eq!(sut.components.len(), 65535);
    assert_eq!(sut.connections.len(), 65534);
    assert_eq!(sut.hosts().len(), 8);
    // About a second in a debug build on a quiet machine. The bound is no figure (a slow or
    // loaded machine takes several times as long): it only catches a load that blows up,
    // quadratic in the components, say.
    assert!(
        started.elapsed() < Duration::from_secs(120),
        "loaded 65535 components in {:?}",
        started.elapsed()
    );
}

#[test]
fn grid_demo_example_loads_and_runs_the_same_twice() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/grid_demo.lua");
    let sut = load(&path, &|_: &str| None).unwrap().grid.unwrap();
    assert!(sut.components.len() >= 3);
    let registry = modbot_components::builtin();
    let trace = modbot_grid::reference_trace(&sut, &registry, 100);
    // The header, 100 ticks, the state hash after the last.
    assert_eq!(trace.lines().count(), 102);
    assert!(trace
        .lines()
        .last()
        .unwrap()
        .starts_with("# state_hash tick=99 hash=0x"));
    assert_eq!(trace, modbot_grid::reference_trace(&sut, &registry, 100));
}

/// Finds the program `my-host` (and no other).
fn my_host(name: &str) -> Option<std::path::PathBuf> {
    (name == "my-host").then(|| std::path::PathBuf::from("/usr/bin/my-host"))
}

const DECLARED: &str = r#"domain "d"
grid {}
component_type "scaler" { program = "my-host", doc = "y = k u", inputs = { "u:f64" }, outputs = { "y:f64", "n:i64" }, params = { k = 1.0 } }
component "src" { type = "ramp", host = "h1" }
component "s" { type = "scaler", host = "h2", params = { k = 3 } }
connect "src.y -> s.u"
"#;

#[test]
fn a_declared_component_type_is_used_like_a_registered_one_and_names_its_host_program() {
    let spec = load_str("robot.lua", DECLARED, &my_host).unwrap();
    let grid = spec.grid.unwrap();
    let s = &grid.components[grid.component("s").unwrap()];
    assert_eq!(s.program.as_deref(), Some("my-host"));
    assert_eq!(s.params.get("k"), Some(&ParamValue::F64(3.0)));
    assert_eq!(s.info.output_types(), vec![PortType::F64, PortType::I64]);
    assert_eq!(grid.host_program("h2"), Some("my-host"));
    assert_eq!(grid.host_program("h1"), None);
    assert_eq!(grid.declared.len(), 1);
}

#[test]
fn a_declared_component_type_with_a_bad_port_is_refused_at_its_line() {
    let source = DECLARED.replace("\"u:f64\"", "\"u:f32\"");
    let sut = load_str("robot.lua", &source, &my_host).unwrap_err();
    assert_eq!(sut.line, Some(3), "{sut}");
    assert!(
        sut.message
            .contains("inputs: 'u:f32' has type 'f32': use f64, i64, bool or f64[N]"),
        "{sut}"
    );
}

#[test]
fn two_programs_on_one_host_are_refused() {
    let source = DECLARED.replace("host = \"h2\"", "host = \"h1\"").replace(
        "component \"src\" { type = \"ramp\", host = \"h1\" }",
        "component_type \"other\" { program = \"my-host2\", outputs = { \"y:f64\" } }\n\
         component \"src\" { type = \"other\", host = \"h1\" }",
    );
    let both = |n: &str| my_host(n).or_else(|| (n == "my-host2").then(|| "/x".into()));
    let sut = load_str("robot.lua", &source, &both).unwrap_err();
    assert!(
        sut.message.contains("host 'h1' would need two programs"),
        "{sut}"
    );
}

#[test]
fn a_type_the_process_registers_itself_must_agree_with_its_declaration() {
    let mut registry = modbot_components::builtin();
    registry.register(
        |_| {
            Ok(ComponentInfo {
                type_name: "scaler",
                doc: "",
                inputs: vec![PortDecl::new("u", PortType::F64)],
                outputs: vec![PortDecl::new("y", PortType::F64)],
                params: vec![],
            })
        },
        |_| Err(ComponentError::Other("not made in this test".into())),
    );
    let sut = load_str_with_registry("robot.lua", DECLARED, &my_host, &[], &registry).unwrap_err();
    assert_eq!(sut.line, Some(3), "{sut}");
    assert!(
        sut.message
            .contains("its outputs are declared as [y:f64, n:i64], the program registers [y:f64]"),
        "{sut}"
    );
}

//! Tests of the system description: the language, every error with its line, the sandbox.

use std::path::{Path, PathBuf};
use std::time::Duration;

use super::*;

/// A resolver that knows the two MRA demo programs, at made-up paths.
fn known(program: &str) -> Option<PathBuf> {
    ["modbot-sonar", "modbot-mobility"]
        .contains(&program)
        .then(|| PathBuf::from("/opt/modbot/bin").join(program))
}

fn load_text(source: &str) -> Result<SystemSpec, SystemError> {
    load_str("robot.lua", source, &known)
}

/// Loads `source`, expecting an error on `line` whose message contains `fragment`.
#[track_caller]
fn assert_error(source: &str, line: Option<u32>, fragment: &str) -> SystemError {
    let sut = match load_text(source) {
        Ok(spec) => panic!("expected an error containing {fragment:?}, got {spec:#?}"),
        Err(e) => e,
    };
    assert_eq!(sut.file, "robot.lua", "{sut}");
    assert_eq!(sut.line, line, "{sut}");
    assert!(
        sut.message.contains(fragment),
        "{sut:?} does not contain {fragment:?}"
    );
    sut
}

// ---- the language ----

#[test]
fn example_description_loads_with_its_two_modules() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/mra_demo.lua");
    let sut = load(&path, &known).unwrap();
    assert_eq!(sut.file, path);
    assert_eq!(sut.domain, "mra_demo");
    assert_eq!(sut.supervision, Supervision::default());
    let names: Vec<&str> = sut.modules.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["sonar", "mobility"]);
    let sonar = &sut.modules[0];
    assert_eq!(sonar.addr, 2);
    assert_eq!(sonar.program, Path::new("/opt/modbot/bin/modbot-sonar"));
    assert_eq!(sonar.program_name, "modbot-sonar");
    assert_eq!(sonar.args, ["--obstacle", "3,0"]);
    assert_eq!(sonar.restart.when, Restart::OnFailure);
    let mobility = &sut.modules[1];
    assert_eq!(mobility.addr, 3);
    assert_eq!(mobility.program_name, "modbot-mobility");
    assert!(mobility.args.is_empty());
    assert_eq!(mobility.restart.when, Restart::OnFailure);
}

#[test]
fn omitted_fields_take_their_defaults() {
    let sut =
        load_text("domain \"t\"\nmodule \"a\" { addr = 1, program = \"modbot-sonar\" }\n").unwrap();
    assert_eq!(sut.supervision, Supervision::default());
    assert!(sut.groups.is_empty());
    let expected = ModuleSpec {
        name: "a".into(),
        addr: 1,
        program: PathBuf::from("/opt/modbot/bin/modbot-sonar"),
        program_name: "modbot-sonar".into(),
        args: vec![],
        restart: RestartPolicy::default(),
        cpus: vec![],
        priority: None,
        mlock: false,
        env: vec![],
        mode: ReceiveMode::Blocking,
        groups: vec![],
        line: 2,
    };
    assert_eq!(sut.modules, [expected]);
}

#[test]
fn every_module_and_supervision_field_is_read() {
    let source = r#"
domain "full"
supervision { start_timeout = 3, heartbeat_timeout = 0.5, heartbeat_period = 0.05, stop_grace = 0 }
module "arm" {
  addr = 254,
  program = "modbot-mobility",
  args = { "--rate", 250, 1.5 },
  restart = { policy = "always", max_restarts = 2, window = 10, backoff = 0.25, max_backoff = 1,
              give_up = "stop-system" },
  cpus = { 3, 1, 3 },
  priority = 99,
  mlock = true,
  env = { RUST_LOG = "debug", A = 1 },
  mode = "busy",
}
"#;
    let sut = load_text(source).unwrap();
    assert_eq!(
        sut.supervision,
        Supervision {
            start_timeout: Duration::from_secs(3),
            heartbeat_timeout: Duration::from_millis(500),
            heartbeat_period: Duration::from_millis(50),
            stop_grace: Duration::ZERO,
        }
    );
    let arm = &sut.modules[0];
    assert_eq!(arm.line, 4);
    assert_eq!(arm.addr, 254);
    assert_eq!(arm.args, ["--rate", "250", "1.5"]);
    assert_eq!(
        arm.restart,
        RestartPolicy {
            when: Restart::Always,
            max_restarts: 2,
            window: Duration::from_secs(10),
            backoff: Duration::from_millis(250),
            max_backoff: Duration::from_secs(1),
            give_up: GiveUp::StopSystem,
        }
    );
    assert_eq!(arm.cpus, [1, 3]);
    assert_eq!(arm.priority, Some(99));
    assert!(arm.mlock);
    assert_eq!(
        arm.env,
        [
            ("A".to_owned(), "1".to_owned()),
            ("RUST_LOG".to_owned(), "debug".to_owned())
        ]
    );
    assert_eq!(arm.mode, ReceiveMode::BusyPoll);
}

#[test]
fn restart_policy_by_name_keeps_the_default_limits() {
    let source =
        "domain \"t\"\nmodule \"a\" { addr = 1, program = \"modbot-sonar\", restart = \"never\" }";
    let sut = load_text(source).unwrap();
    let expected = RestartPolicy {
        when: Restart::Never,
        ..RestartPolicy::default()
    };
    assert_eq!(sut.modules[0].restart, expected);
}

#[test]
fn modules_generated_in_a_loop_keep_declaration_order() {
    let source = r#"
domain "loop"
local names = {}
for i = 1, 8 do
  local name = "worker" .. i
  module(name) { addr = 10 + i, program = "modbot-sonar", args = { "--id", i } }
  names[#names + 1] = name
end
group "workers" (names)
"#;
    let sut = load_text(source).unwrap();
    assert_eq!(sut.modules.len(), 8);
    for (i, m) in sut.modules.iter().enumerate() {
        assert_eq!(m.name, format!("worker{}", i + 1));
        assert_eq!(usize::from(m.addr), 11 + i);
        assert_eq!(m.args, ["--id".to_owned(), (i + 1).to_string()]);
        assert_eq!(m.line, 6);
        assert_eq!(m.groups, ["workers"]);
    }
    assert_eq!(sut.groups[0].members.len(), 8);
}

#[test]
fn groups_are_filled_into_their_members() {
    let source = r#"
domain "groups"
group "sensors" { "sonar" }
module "sonar" { addr = 2, program = "modbot-sonar" }
module "mobility" { addr = 3, program = "modbot-mobility" }
group "all" { "mobility", "sonar" }
"#;
    let sut = load_text(source).unwrap();
    assert_eq!(
        sut.groups,
        [
            GroupSpec {
                name: "sensors".into(),
                members: vec!["sonar".into()],
                line: 3
            },
            GroupSpec {
                name: "all".into(),
                members: vec!["mobility".into(), "sonar".into()],
                line: 6
            },
        ]
    );
    assert_eq!(sut.modules[0].groups, ["sensors", "all"]);
    assert_eq!(sut.modules[1].groups, ["all"]);
}

#[test]
fn restart_delay_doubles_from_backoff_and_is_capped() {
    let sut = RestartPolicy::default();
    assert_eq!(sut.delay(0), Duration::from_millis(100));
    assert_eq!(sut.delay(1), Duration::from_millis(200));
    assert_eq!(sut.delay(5), Duration::from_millis(3200));
    assert_eq!(sut.delay(6), Duration::from_secs(5));
    assert_eq!(sut.delay(40), Duration::from_secs(5));
    assert_eq!(sut.delay(u32::MAX), Duration::from_secs(5));
}

#[test]
fn system_error_displays_file_and_line() {
    let sut = SystemError::new("robot.lua", Some(7), "bad");
    assert_eq!(sut.to_string(), "robot.lua:7: bad");
    let sut = SystemError::new("robot.lua", None, "bad");
    assert_eq!(sut.to_string(), "robot.lua: bad");
}

// ---- variables (`--var KEY=VALUE`) ----

fn vars(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
    pairs
        .iter()
        .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
        .collect()
}

/// The description of the brief: a speed variable that becomes a module's environment.
const WITH_SPEED: &str = r#"domain "t"
local speed = tonumber(vars.speed or "1")
module "a" { addr = 1, program = "modbot-sonar", env = { MODBOT_SIM_SPEED = tostring(speed) } }
"#;

#[test]
fn variables_reach_the_description_as_strings_and_default_when_absent() {
    let sut =
        load_str_with_vars("robot.lua", WITH_SPEED, &known, &vars(&[("speed", "2.5")])).unwrap();
    assert_eq!(
        sut.modules[0].env,
        [("MODBOT_SIM_SPEED".to_owned(), "2.5".to_owned())]
    );
    let sut = load_text(WITH_SPEED).unwrap();
    assert_eq!(
        sut.modules[0].env,
        [("MODBOT_SIM_SPEED".to_owned(), "1".to_owned())],
        "vars is an empty table without variables"
    );
    let source = r#"domain "t"
assert(type(vars.n) == "string" and vars.n == "3", "a string")
local names = {}
for k, v in pairs(vars) do names[#names + 1] = k .. "=" .. v end
table.sort(names)
module "a" { addr = tonumber(vars.n), program = "modbot-sonar", args = names }
"#;
    let sut = load_str_with_vars(
        "robot.lua",
        source,
        &known,
        &vars(&[("n", "1"), ("mode", "sim"), ("n", "3")]),
    )
    .unwrap();
    assert_eq!(sut.modules[0].addr, 3, "the later of two equal keys wins");
    assert_eq!(
        sut.modules[0].args,
        ["mode=sim", "n=3"],
        "pairs(vars) lists them"
    );
}

#[test]
fn variables_are_read_only_and_a_write_names_its_line() {
    let source = "domain \"t\"\n\nvars.speed = \"3\"\n";
    let sut =
        load_str_with_vars("robot.lua", source, &known, &vars(&[("speed", "2")])).unwrap_err();
    assert_eq!(sut.line, Some(3), "{sut}");
    assert!(
        sut.message.contains("vars is read-only (vars.speed)"),
        "{sut}"
    );
    assert_error(
        "domain \"t\"\nsetmetatable(vars, nil)",
        Some(2),
        "protected metatable",
    );
}

#[test]
fn a_description_file_loads_with_variables() {
    let path = std::env::temp_dir().join(format!("modbot-vars-{}.lua", std::process::id()));
    std::fs::write(&path, WITH_SPEED).unwrap();
    let sut = load_with_vars(&path, &known, &vars(&[("speed", "4")]));
    let _ = std::fs::remove_file(&path);
    assert_eq!(sut.unwrap().modules[0].env[0].1, "4");
}

#[test]
fn a_var_argument_is_key_equals_value() {
    assert_eq!(parse_var("speed=2"), Ok(("speed".into(), "2".into())));
    assert_eq!(parse_var("a.b-c_1="), Ok(("a.b-c_1".into(), "".into())));
    assert_eq!(parse_var("url=x=y"), Ok(("url".into(), "x=y".into())));
    let no_eq = parse_var("speed").unwrap_err();
    assert!(no_eq.to_string().contains("no '='"), "{no_eq}");
    let no_key = parse_var("=2").unwrap_err();
    assert!(no_key.to_string().contains("no key"), "{no_key}");
    let bad_key = parse_var("my speed=2").unwrap_err();
    assert_eq!(
        bad_key,
        VarError::BadKey {
            key: "my speed".into(),
            bad: ' '
        }
    );
    assert!(bad_key.to_string().contains("' '"), "{bad_key}");
}

// ---- errors, each with its line ----

#[test]
fn lua_syntax_error_names_its_line() {
    assert_error(
        "domain \"t\"\n\nmodule \"a\" { addr = = 1 }\n",
        Some(3),
        "unexpected symbol",
    );
}

#[test]
fn lua_runtime_error_names_its_line() {
    assert_error(
        "domain \"t\"\nlocal x = nil\nlocal y = x.field\n",
        Some(3),
        "attempt to index",
    );
    assert_error("domain \"t\"\nerror(\"custom\")\n", Some(2), "custom");
}

#[test]
fn missing_or_repeated_or_bad_domain_is_refused() {
    assert_error(
        "module \"a\" { addr = 1, program = \"modbot-sonar\" }",
        None,
        "no domain declared",
    );
    assert_error(
        "domain \"a\"\n\ndomain \"b\"\n",
        Some(3),
        "domain is already declared at line 1",
    );
    assert_error(
        "\ndomain \"Bad Name\"\n",
        Some(2),
        "invalid domain name 'Bad Name'",
    );
    assert_error("domain(42)\n", Some(1), "domain must be given a name");
    assert_error("domain()\n", Some(1), "expected one argument but got 0");
}

#[test]
fn no_modules_and_no_grid_is_refused() {
    assert_error(
        "domain \"t\"\n",
        None,
        "nothing to run: declare at least one module",
    );
}

#[test]
fn duplicate_module_name_or_address_is_refused() {
    let source = r#"domain "t"

module "sonar" { addr = 2, program = "modbot-sonar" }
module "sonar" { addr = 4, program = "modbot-sonar" }
"#;
    assert_error(
        source,
        Some(4),
        "module name 'sonar' is already declared at line 3",
    );
    let source = r#"domain "t"

module "sonar" { addr = 2, program = "modbot-sonar" }
module "other" { addr = 2, program = "modbot-sonar" }
"#;
    assert_error(
        source,
        Some(4),
        "address 2 is already used by 'sonar' (line 3)",
    );
}

#[test]
fn address_out_of_range_missing_or_not_an_integer_is_refused() {
    for (addr, shown) in [("0", "0"), ("255", "255"), ("2.5", "2.5"), ("\"2\"", "'2'")] {
        let source =
            format!("domain \"t\"\nmodule \"a\" {{ addr = {addr}, program = \"modbot-sonar\" }}");
        assert_error(
            &source,
            Some(2),
            &format!("module 'a': field 'addr' must be an integer from 1 to 254, not {shown}"),
        );
    }
    assert_error(
        "domain \"t\"\nmodule \"a\" { program = \"modbot-sonar\" }",
        Some(2),
        "field 'addr' is required",
    );
    assert_error(
        "domain \"t\"\nmodule \"a\" { addr = 2.0, program = 3 }",
        Some(2),
        "field 'program' must be a string, not 3",
    );
}

#[test]
fn unknown_program_is_refused_with_where_it_was_looked_for() {
    let source = "domain \"t\"\n\nmodule \"x\" { addr = 1, program = \"modbot-sonr\" }";
    let sut = load_str(
        "robot.lua",
        source,
        &DefaultResolver::new()
            .with_exe_dir("/opt/robot/bin")
            .with_search_path("/nonexistent"),
    )
    .unwrap_err();
    assert_eq!(sut.line, Some(3));
    assert!(sut
        .message
        .starts_with("unknown program 'modbot-sonr' for module 'x': not found next to "));
    assert!(
        sut.message.ends_with("(/opt/robot/bin) or on $PATH"),
        "{sut}"
    );
}

#[test]
fn bad_restart_policy_is_refused() {
    let module = |restart: &str| {
        format!("domain \"t\"\nmodule \"x\" {{ addr = 1, program = \"modbot-sonar\", restart = {restart} }}")
    };
    assert_error(
        &module("\"sometimes\""),
        Some(2),
        "restart policy 'sometimes' for module 'x': expected never, on-failure or always",
    );
    assert_error(
        &module("{ policy = \"always\", tries = 3 }"),
        Some(2),
        "module 'x': restart: unknown field 'tries' (expected policy, max_restarts, window, backoff, max_backoff, give_up)",
    );
    assert_error(
        &module("{ give_up = \"panic\" }"),
        Some(2),
        "field 'give_up' must be \"keep-others\" or \"stop-system\", not 'panic'",
    );
    assert_error(
        &module("{ max_restarts = -1 }"),
        Some(2),
        "field 'max_restarts' must be an integer from 0 to",
    );
    assert_error(
        &module("{ backoff = 2, max_backoff = 1 }"),
        Some(2),
        "max_backoff (1s) must not be less than backoff (2s)",
    );
    assert_error(&module("true"), Some(2), "must be a policy name or a table");
}

#[test]
fn unknown_field_is_refused_naming_the_expected_ones() {
    assert_error(
        "domain \"t\"\nmodule \"sonar\" { adr = 2, program = \"modbot-sonar\" }",
        Some(2),
        "module 'sonar': unknown field 'adr' (expected addr, program, args, restart, cpus, priority, mlock, env, mode, linger_us)",
    );
    assert_error(
        "domain \"t\"\n\nsupervision { heartbeat = 1 }",
        Some(3),
        "supervision: unknown field 'heartbeat' (expected start_timeout, heartbeat_timeout, heartbeat_period, stop_grace)",
    );
    assert_error(
        "domain \"t\"\nmodule \"sonar\" { \"modbot-sonar\", addr = 2 }",
        Some(2),
        "fields are written name = value",
    );
}

#[test]
fn wrongly_typed_field_is_refused() {
    let module = |field: &str| {
        format!(
            "domain \"t\"\nmodule \"sonar\" {{ addr = 1, program = \"modbot-sonar\", {field} }}"
        )
    };
    for (field, expected) in [
        (
            "args = \"--fast\"",
            "module 'sonar': field 'args' must be a list of strings",
        ),
        (
            "args = { true }",
            "module 'sonar': field 'args' must be a list of strings",
        ),
        (
            "args = { [1] = \"a\", [3] = \"b\" }",
            "field 'args' must be a list of strings",
        ),
        (
            "cpus = { -1 }",
            "field 'cpus' must be a list of CPU indices 0 to 1023",
        ),
        ("cpus = 1", "field 'cpus' must be a list of CPU indices"),
        ("mlock = \"yes\"", "field 'mlock' must be true or false"),
        (
            "env = { \"x\" }",
            "field 'env' must be a table of NAME = \"value\"",
        ),
        ("env = { A = {} }", "env A must be a string"),
        (
            "mode = \"spin\"",
            "field 'mode' must be \"blocking\" or \"busy\", not 'spin'",
        ),
    ] {
        assert_error(&module(field), Some(2), expected);
    }
    assert_error(
        "domain \"t\"\nmodule \"sonar\" \"modbot-sonar\"",
        Some(2),
        "module 'sonar' must be given a table of fields",
    );
}

#[test]
fn priority_outside_1_to_99_is_refused() {
    for priority in ["0", "100", "50.5"] {
        let source = format!(
            "domain \"t\"\nmodule \"a\" {{ addr = 1, program = \"modbot-sonar\", priority = {priority} }}"
        );
        assert_error(
            &source,
            Some(2),
            "field 'priority' must be an integer from 1 to 99",
        );
    }
}

#[test]
fn bad_supervision_timings_are_refused() {
    assert_error(
        "domain \"t\"\nsupervision { heartbeat_timeout = 1, heartbeat_period = 0.5 }",
        Some(2),
        "heartbeat_period (500ms) must be less than half of heartbeat_timeout (1s)",
    );
    assert_error(
        "domain \"t\"\nsupervision { stop_grace = -1 }",
        Some(2),
        "supervision: field 'stop_grace' must be a number of seconds, 0 or more, not -1",
    );
    assert_error(
        "domain \"t\"\nsupervision { start_timeout = 0 }",
        Some(2),
        "field 'start_timeout' must be a positive number of seconds, not 0",
    );
    assert_error(
        "domain \"t\"\nsupervision { start_timeout = 1/0 }",
        Some(2),
        "field 'start_timeout' must be a positive number of seconds, not inf",
    );
    assert_error(
        "domain \"t\"\nsupervision {}\nsupervision {}",
        Some(3),
        "supervision is already declared at line 2",
    );
}

#[test]
fn bad_groups_are_refused() {
    let modules = "domain \"t\"\nmodule \"sonar\" { addr = 2, program = \"modbot-sonar\" }\n";
    assert_error(
        &format!("{modules}group \"g\" {{ \"sonar\", \"sonr\" }}"),
        Some(3),
        "group 'g': no module is named 'sonr' (modules: sonar)",
    );
    assert_error(
        &format!("{modules}group \"g\" {{ \"sonar\" }}\n\ngroup \"g\" {{ \"sonar\" }}"),
        Some(5),
        "group 'g' is already declared at line 3",
    );
    assert_error(
        &format!("{modules}group \"g\" {{}}"),
        Some(3),
        "group 'g' has no members",
    );
    assert_error(
        &format!("{modules}group \"g\" {{ \"sonar\", \"sonar\" }}"),
        Some(3),
        "'sonar' is listed twice",
    );
    assert_error(
        &format!("{modules}group \"g\" {{ 7 }}"),
        Some(3),
        "member 1 must be a module name, not 7",
    );
}

#[test]
fn bad_module_name_or_missing_table_is_refused() {
    assert_error(
        "domain \"t\"\nmodule \"no spaces\" { addr = 1, program = \"modbot-sonar\" }",
        Some(2),
        "module name 'no spaces' is invalid",
    );
    assert_error(
        "domain \"t\"\nmodule { addr = 1, program = \"modbot-sonar\" }",
        Some(2),
        "module must be given a name",
    );
    assert_error(
        "domain \"t\"\nmodule \"a\" { addr = 1, program = \"modbot-sonar\" }\nmodule \"b\"\n",
        Some(3),
        "module 'b' is declared without its table",
    );
}

#[test]
fn first_failure_is_reported_even_if_the_script_catches_it() {
    let source = r#"domain "t"
local ok = pcall(module "a", { adr = 1 })
module "b" { addr = 1, program = "modbot-sonar" }
"#;
    assert_error(source, Some(2), "module 'a': unknown field 'adr'");
    let source = "\n\nlocal ok = pcall(domain, \"Bad Name\")\n";
    assert_error(source, Some(3), "invalid domain name 'Bad Name'");
}

// ---- the sandbox ----

#[test]
fn os_io_and_require_are_not_available() {
    assert_error("domain \"t\"\nos.execute(\"true\")", Some(2), "global 'os'");
    assert_error(
        "domain \"t\"\nio.open(\"/etc/passwd\")",
        Some(2),
        "global 'io'",
    );
    assert_error("domain \"t\"\nrequire(\"os\")", Some(2), "global 'require'");
    assert_error(
        "domain \"t\"\nlocal f = load(\"return 1\")",
        Some(2),
        "global 'load'",
    );
    assert_error(
        "domain \"t\"\ndofile(\"/etc/passwd\")",
        Some(2),
        "global 'dofile'",
    );
    assert_error(
        "domain \"t\"\nloadfile(\"/etc/passwd\")",
        Some(2),
        "global 'loadfile'",
    );
    assert_error(
        "domain \"t\"\ncollectgarbage()",
        Some(2),
        "global 'collectgarbage'",
    );
    assert_error("domain \"t\"\ndebug.getinfo(1)", Some(2), "global 'debug'");
    assert_error(
        "domain \"t\"\npackage.loadlib(\"x\", \"y\")",
        Some(2),
        "global 'package'",
    );
}

#[test]
fn infinite_loop_is_stopped_by_the_instruction_limit() {
    let sut = assert_error(
        "domain \"t\"\nwhile true do end",
        None,
        "the description ran too long (instruction limit)",
    );
    assert_eq!(
        sut.to_string(),
        "robot.lua: the description ran too long (instruction limit)"
    );
}

#[test]
fn infinite_loop_is_stopped_even_inside_pcall_or_a_coroutine() {
    for source in [
        "while true do pcall(function() while true do end end) end",
        "while true do xpcall(function() while true do end end, function(e) return e end) end",
        "while true do coroutine.resume(coroutine.create(function() while true do end end)) end",
        "coroutine.wrap(function() while true do end end)()",
    ] {
        assert_error(
            source,
            None,
            "the description ran too long (instruction limit)",
        );
    }
}

#[test]
fn finalizers_cannot_be_declared() {
    // Lua runs __gc with hooks off: a looping finalizer would escape the instruction limit.
    let source = "domain \"t\"\nwhile true do\n  setmetatable({}, { __gc = function() while true do end end })\nend";
    assert_error(source, Some(3), "__gc metamethods are not available");
    let source = "domain \"t\"\nlocal t = setmetatable({}, { __index = function() return 1 end })\nmodule \"a\" { addr = t.x, program = \"modbot-sonar\" }";
    assert_eq!(load_text(source).unwrap().modules[0].addr, 1);
}

#[test]
fn patterns_that_would_backtrack_out_of_the_instruction_limit_are_refused() {
    // This one takes hours in C, where the instruction hook never runs.
    let slow =
        "local s = string.rep(\"a\", 40)\nlocal x = s:match(\"(.-)(.-)(.-)(.-)(.-)(.-)(.-)b\")";
    assert_error(
        &format!("domain \"t\"\n{slow}"),
        Some(3),
        "string.match is not available in a system description",
    );
    for (call, name) in [
        ("string.gsub(\"ab\", \"a\", \"c\")", "string.gsub"),
        (
            "for w in string.gmatch(\"a b\", \"%a\") do end",
            "string.gmatch",
        ),
        ("string.find(\"ab\", \"a.\")", "string.find with a pattern"),
    ] {
        assert_error(&format!("domain \"t\"\n{call}"), Some(2), name);
    }
    let source = "domain \"t\"\nlocal at = string.find(\"a.b\", \".\", 1, true)\nmodule \"a\" { addr = at, program = \"modbot-sonar\" }";
    assert_eq!(
        load_text(source).unwrap().modules[0].addr,
        2,
        "plain find works"
    );
}

#[test]
fn huge_allocation_is_stopped_by_the_memory_limit() {
    assert_error(
        "domain \"t\"\nlocal s = string.rep(\"x\", 1 << 30)",
        None,
        "the description used too much memory (limit 16 MiB)",
    );
    assert_error(
        "domain \"t\"\nlocal t = {}\nfor i = 1, 1e8 do t[i] = i end",
        None,
        "the description used too much memory",
    );
}

#[test]
fn unbounded_recursion_is_a_clean_error() {
    let sut = load_text("domain \"t\"\nlocal function f() return 1 + f() end\nf()").unwrap_err();
    assert!(
        sut.message.contains("stack overflow") || sut.message.contains("memory"),
        "{sut}"
    );
}

#[test]
fn binary_chunks_are_refused() {
    let sut = load_text("\x1bLua\x54\x00").unwrap_err();
    assert!(sut.message.contains("binary"), "{sut}");
}

#[test]
fn file_that_cannot_be_read_is_an_error_without_a_line() {
    let sut = load(Path::new("/nonexistent/robot.lua"), &known).unwrap_err();
    assert_eq!(sut.file, "/nonexistent/robot.lua");
    assert_eq!(sut.line, None);
    assert!(
        sut.message.starts_with("cannot read the description"),
        "{sut}"
    );
}

#[test]
fn linger_us_sets_the_module_programs_linger_and_is_refused_where_it_cannot_apply() {
    let module = |fields: &str| {
        format!("domain \"t\"\nmodule \"x\" {{ addr = 1, program = \"modbot-sonar\", {fields} }}")
    };
    let sut = load_text(&module("linger_us = 0, env = { RUST_LOG = \"info\" }")).unwrap();
    assert_eq!(
        sut.modules[0].env,
        [
            ("MODBOT_LINGER_US".to_owned(), "0".to_owned()),
            ("RUST_LOG".to_owned(), "info".to_owned())
        ],
        "in the environment, sorted with the rest"
    );
    assert_error(
        &module("linger_us = -1"),
        Some(2),
        "field 'linger_us' must be an integer from 0 to 1000000",
    );
    assert_error(
        &module("linger_us = 20, mode = \"busy\""),
        Some(2),
        "field 'linger_us' is for a module in blocking mode",
    );
    assert_error(
        &module("linger_us = 20, env = { MODBOT_LINGER_US = \"5\" }"),
        Some(2),
        "set linger_us or env MODBOT_LINGER_US, not both",
    );
}

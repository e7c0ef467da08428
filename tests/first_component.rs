//! README's "Your first grid component" (examples/first_component) builds and runs: a
//! component type of its own, registered in a host program of its own, declared and used by a
//! system description; a declaration that differs from what the program registers is refused.

mod common;

use std::path::Path;
use std::time::Duration;

use common::TestDomain;

fn example() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/first_component/limited.lua")
}

/// The value of `key=` on a trace line.
fn field(line: &str, key: &str) -> f64 {
    line.split(' ')
        .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
        .unwrap_or_else(|| panic!("no {key} in {line}"))
        .parse()
        .unwrap()
}

#[test]
fn your_first_component_clamps_what_it_reads_one_tick_later() {
    let mut sut = TestDomain::new("first_component");
    let checked = sut.modbot_ok(&["check", example().to_str().unwrap()]);
    assert!(checked.contains("limiter"), "{checked}");
    // In lockstep: every release is served, whatever the machine's load (LET's values, not
    // its timing, are under test).
    let (trace, _) = sut.traced_up(&example(), 400, &["--lockstep"], "limited");
    let lines: Vec<&str> = trace.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(lines.len(), 400, "{trace}");
    let mut last_clamped = 0.0;
    for pair in lines.windows(2) {
        // LET: released at n, the limiter reads the wave valid at n; its outputs are valid at
        // n + 1.
        let (u, y) = (field(pair[0], "wave.y"), field(pair[1], "limit.y"));
        assert_eq!(y, u.clamp(-1.5, 1.5), "{} / {}", pair[0], pair[1]);
        let clamped = field(pair[1], "limit.clamped");
        assert!(clamped >= last_clamped, "{}", pair[1]);
        last_clamped = clamped;
    }
    assert!(
        last_clamped > 0.0,
        "a wave of amplitude 2 is clamped at 1.5"
    );
}

#[test]
fn a_declaration_that_differs_from_the_program_s_type_is_refused_by_its_host() {
    let mut sut = TestDomain::new("first_component_differs");
    let text = std::fs::read_to_string(example()).unwrap();
    let wrong = text.replace(
        "outputs = { \"y:f64\", \"clamped:i64\" }",
        "outputs = { \"y:f64\" }",
    );
    assert_ne!(wrong, text);
    let body: String = wrong
        .lines()
        .filter(|l| !l.starts_with("domain("))
        .map(|l| format!("{l}\n"))
        .collect();
    let file = sut.write_system(&body);
    // The description alone is consistent: check cannot know the program's own type.
    sut.modbot_ok(&["check", file.to_str().unwrap()]);
    let up = sut.spawn_logged("modbot", &["up", file.to_str().unwrap()]);
    let status = sut.wait_exit(up, Duration::from_secs(60));
    let output = sut.output_of(up);
    assert_ne!(status.code(), Some(0), "{output}");
    assert!(
        output.contains(
            "its outputs are declared as [y:f64], the program registers [y:f64, clamped:i64]"
        ),
        "{output}"
    );
}

#[test]
fn a_declared_type_whose_program_is_missing_is_refused_at_its_line() {
    let mut sut = TestDomain::new("first_component_missing");
    let file = sut.write_system(
        "grid {}\ncomponent_type \"x\" { program = \"no-such-program\", outputs = { \"y:f64\" } }\n\
         component \"c\" { type = \"x\", host = \"h\" }\n",
    );
    let out = sut.modbot(&["check", file.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{text}");
    assert!(
        text.contains(":3: unknown program 'no-such-program' for component type 'x'"),
        "{text}"
    );
}

#[test]
fn the_readme_shows_the_first_component_as_it_is() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    for file in ["src/main.rs", "limited.lua"] {
        let text =
            std::fs::read_to_string(root.join("examples/first_component").join(file)).unwrap();
        let fence = if file.ends_with(".rs") { "rust" } else { "lua" };
        assert!(
            readme.contains(&format!("```{fence}\n{text}```")),
            "README's \"Your first grid component\" differs from examples/first_component/{file}"
        );
    }
}

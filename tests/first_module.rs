//! README's "Your first module" (examples/first_module) builds and runs: two of them under
//! the supervisor, one adding to the other every second, answering calls and keeping their
//! blackboards.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::TestDomain;

fn bb_i64(sut: &TestDomain, module: &str, item: &str) -> Option<i64> {
    let out = sut.modbot(&["bb", module, item]);
    String::from_utf8_lossy(&out.stdout).trim().parse().ok()
}

#[test]
fn your_first_module_counts_what_its_peer_adds_and_answers_calls() {
    let mut sut = TestDomain::new("first_module");
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/first_module/counters.lua");
    let domain = format!("domain={}", sut.name());
    let up = sut.spawn_logged("modbot", &["up", file.to_str().unwrap(), "--var", &domain]);
    sut.wait_until(
        "a has added to b twice",
        Duration::from_secs(60),
        || match (bb_i64(&sut, "b", "total"), bb_i64(&sut, "a", "peer_total")) {
            (Some(total), Some(seen)) if total >= 2 && seen >= 2 => Ok(()),
            other => Err(format!(
                "b.total, a.peer_total: {other:?}\n{}",
                sut.output_of(up)
            )),
        },
    );
    let before = bb_i64(&sut, "b", "total").unwrap();
    let answer: i64 = sut
        .modbot_ok(&["call", "b.add", "1000"])
        .trim()
        .parse()
        .unwrap();
    assert!(answer >= before + 1000, "{answer} after {before}");
    let refused = sut.modbot(&["call", "b.add", "many"]);
    assert_eq!(refused.status.code(), Some(1), "a bad argument is refused");
    sut.modbot_ok(&["down"]);
    let status = sut.wait_exit(up, Duration::from_secs(60));
    assert_eq!(status.code(), Some(0), "{}", sut.output_of(up));
    assert_eq!(sut.leftover_files(), Vec::<PathBuf>::new());
}

#[test]
fn the_readme_shows_the_first_module_as_it_is() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let program = std::fs::read_to_string(root.join("examples/first_module/src/main.rs")).unwrap();
    assert!(
        readme.contains(&format!("```rust\n{program}```")),
        "README's \"Your first module\" differs from examples/first_module/src/main.rs"
    );
}

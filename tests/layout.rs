//! The crates' layering: each workspace crate depends only on crates below it, and the module
//! programs link no grid, bus or Lua. Read from the manifests, so a dependency added upward
//! fails here before it is used.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Workspace crates from the bottom up: a crate may depend on crates of lower layers only.
const LAYERS: &[(&str, &str, u8)] = &[
    ("modbot-ipc-schema", "ipc_schema", 0),
    ("modbot-transport", "runtime/transport", 1),
    ("modbot-core", "runtime/core", 2),
    ("modbot-testkit", "runtime/testkit", 2),
    ("modbot-grid", "runtime/grid", 3),
    ("modbot-modules", "modules", 3),
    ("modbot-system", "runtime/system", 4),
    ("modbot-supervisor", "runtime/supervisor", 5),
    ("modbot-runtime", "runtime", 6),
    ("modbot-grid-processes", "modules/grid", 7),
    ("modbot", ".", 8),
    ("modbot-benches", "benches", 8),
    ("modbot-example-first-module", "examples/first_module", 3),
    (
        "modbot-example-first-component",
        "examples/first_component",
        8,
    ),
];

/// The names in the `[dependencies]` of the manifest in `dir` (dev-dependencies are tests'
/// business).
fn dependencies(dir: &str) -> BTreeSet<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join(dir).join("Cargo.toml")).unwrap();
    let mut section = String::new();
    let mut found = BTreeSet::new();
    for line in text.lines().map(str::trim) {
        if line.starts_with('[') {
            section = line.to_owned();
        } else if section == "[dependencies]" && !line.is_empty() && !line.starts_with('#') {
            found.insert(
                line.split(['=', '.', ' '])
                    .next()
                    .unwrap_or_default()
                    .to_owned(),
            );
        }
    }
    found
}

/// The workspace crates among [`dependencies`].
fn internal_dependencies(dir: &str) -> BTreeSet<String> {
    let mut found = dependencies(dir);
    found.retain(|name| LAYERS.iter().any(|(crate_name, ..)| crate_name == name));
    found
}

#[test]
fn every_crate_depends_only_on_crates_below_it() {
    let layer: BTreeMap<&str, u8> = LAYERS.iter().map(|(n, _, l)| (*n, *l)).collect();
    let mut upward = Vec::new();
    for (name, dir, own) in LAYERS {
        for dependency in internal_dependencies(dir) {
            if layer[dependency.as_str()] >= *own {
                upward.push(format!("{name} (layer {own}) -> {dependency}"));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "dependencies that do not point down: {upward:?}"
    );
}

#[test]
fn the_module_programs_link_neither_the_grid_nor_the_bus_nor_lua() {
    // The grid and the bus are modbot-grid's, the system descriptions (mlua) modbot-system's;
    // modbot-runtime is the facade over all of them.
    let dirs: BTreeMap<&str, &str> = LAYERS.iter().map(|(n, d, _)| (*n, *d)).collect();
    let mut seen = BTreeSet::new();
    let mut todo = vec!["modbot-modules".to_owned()];
    while let Some(name) = todo.pop() {
        if seen.insert(name.clone()) {
            todo.extend(internal_dependencies(dirs[name.as_str()]));
        }
    }
    assert!(
        !seen.contains("modbot-runtime"),
        "modbot-modules reaches {seen:?}"
    );
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("modules/Cargo.toml"))
            .unwrap();
    assert!(!manifest.contains("mlua"));
}

#[test]
fn only_the_system_descriptions_link_lua() {
    let lua: Vec<&str> = LAYERS
        .iter()
        .filter(|(_, dir, _)| dependencies(dir).contains("mlua"))
        .map(|(name, ..)| *name)
        .collect();
    assert_eq!(lua, ["modbot-system"]);
}

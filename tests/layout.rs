//! The crates' layering: each workspace crate depends only on crates below it, and the module
//! programs link no grid, bus or Lua. Read from the manifests, so a dependency added upward
//! fails here before it is used.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Workspace crates from the bottom up: a crate may depend on crates of lower layers only.
const LAYERS: &[(&str, &str, u8)] = &[
    ("modbot-ipc-schema", "ipc_schema", 0),
    ("modbot-transport", "runtime/transport", 1),
    ("modbot-data", "runtime/data", 1),
    ("modbot-core", "runtime/core", 2),
    ("modbot-testkit", "runtime/testkit", 2),
    ("modbot-grid", "runtime/grid", 3),
    ("modbot-modules", "modules", 3),
    ("modbot-control", "runtime/control", 4),
    ("modbot-bus", "runtime/bus", 5),
    ("modbot-components", "runtime/components", 6),
    ("modbot-ethercat", "runtime/ethercat", 6),
    ("modbot-ecat-sim", "runtime/ecat-sim", 6),
    ("modbot-station", "station", 6),
    ("modbot-zenoh", "bridge/zenoh", 3),
    ("modbot-record", "runtime/record", 4),
    ("modbot-fmu", "runtime/fmu", 4),
    ("modbot-system", "runtime/system", 7),
    ("modbot-supervisor", "runtime/supervisor", 8),
    ("modbot-program", "runtime/program", 8),
    ("modbot-grid-processes", "modules/grid", 10),
    ("modbot-fmu-host", "modules/fmu", 11),
    ("modbot", ".", 11),
    ("modbot-bench-kit", "benches/kit", 9),
    ("modbot-bench-ipc", "benches/ipc", 10),
    ("modbot-bench-soak", "benches/soak", 10),
    ("modbot-bench-system", "benches/system", 11),
    ("modbot-benches", "benches", 12),
    ("modbot-fmus", "fmus", 0),
    ("modbot-example-first-module", "examples/first_module", 3),
    (
        "modbot-example-first-component",
        "examples/first_component",
        11,
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

/// The code of a crate (its `src/` and `build.rs`), without comments.
fn sources_of(dir: &str) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join(dir);
    let mut files = Vec::new();
    for part in ["src", "build.rs"] {
        let path = root.join(part);
        if path.is_dir() {
            rust_files(&path, &mut files);
        } else if path.is_file() {
            files.push(path);
        }
    }
    let mut code = String::new();
    for file in files {
        let text = std::fs::read_to_string(file).unwrap();
        for line in text.lines().filter(|l| !l.trim_start().starts_with("//")) {
            code.push_str(line);
            code.push('\n');
        }
    }
    code
}

/// Dependencies a crate declares for what they do, not for a name its code uses.
const USED_WITHOUT_NAMING: &[(&str, &str, &str)] = &[
    // Its build script builds the project's FMUs and puts them beside the programs, where the
    // FMU benchmark finds them.
    ("modbot-benches", "modbot-fmus", "builds the FMUs"),
];

#[test]
fn every_crate_uses_every_dependency_it_declares() {
    let mut unused = Vec::new();
    for (name, dir, _) in LAYERS {
        let code = sources_of(dir);
        for dependency in dependencies(dir) {
            let ident = dependency.replace('-', "_");
            let named = code.match_indices(&ident).any(|(i, _)| {
                let before = code[..i].chars().next_back();
                let after = code[i + ident.len()..].chars().next();
                !before.is_some_and(|c| c.is_alphanumeric() || c == '_')
                    && !after.is_some_and(|c| c.is_alphanumeric() || c == '_')
            });
            let excused = USED_WITHOUT_NAMING
                .iter()
                .any(|(n, d, _)| n == name && *d == dependency);
            if !named && !excused {
                unused.push(format!("{name}: {dependency}"));
            }
        }
    }
    assert!(unused.is_empty(), "declared and not used: {unused:?}");
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
    // The grid and the bus are modbot-grid's and modbot-bus's, the system descriptions (mlua)
    // modbot-system's.
    let seen = reached_from("modbot-modules");
    for far in [
        "modbot-grid",
        "modbot-bus",
        "modbot-system",
        "modbot-program",
    ] {
        assert!(!seen.contains(far), "modbot-modules reaches {seen:?}");
    }
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("modules/Cargo.toml"))
            .unwrap();
    assert!(!manifest.contains("mlua"));
}

/// The crates `name` depends on, directly or not (among the workspace's).
fn reached_from(name: &str) -> BTreeSet<String> {
    let dirs: BTreeMap<&str, &str> = LAYERS.iter().map(|(n, d, _)| (*n, *d)).collect();
    let mut seen = BTreeSet::new();
    let mut todo = vec![name.to_owned()];
    while let Some(name) = todo.pop() {
        if seen.insert(name.clone()) {
            todo.extend(internal_dependencies(dirs[name.as_str()]));
        }
    }
    seen
}

#[test]
fn the_grid_processes_read_no_description_and_link_no_lua() {
    // The supervisor reads the description and writes the checked grid; the coordinator, the
    // hosts, the bus bridge, the recorder and the FMU host read that.
    for program in [
        "modbot-grid-processes",
        "modbot-fmu-host",
        "modbot-example-first-component",
    ] {
        let seen = reached_from(program);
        for lua in ["modbot-system", "modbot-supervisor", "modbot-program"] {
            assert!(!seen.contains(lua), "{program} reaches {lua}: {seen:?}");
        }
    }
}

#[test]
fn only_the_system_descriptions_and_the_robot_programs_link_lua() {
    let lua: Vec<&str> = LAYERS
        .iter()
        .filter(|(_, dir, _)| dependencies(dir).contains("mlua"))
        .map(|(name, ..)| *name)
        .collect();
    assert_eq!(lua, ["modbot-system", "modbot-program"]);
}

/// The module path of the source file `file` of a crate whose sources are in `src`
/// (`lib.rs` and `mod.rs` name their folder's module).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("lib" | "mod" | "main")
    ) {
        parts.pop();
    }
    parts
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The modules of the crate in `src` that each module names through `crate::`, `super::` or
/// `self::` paths outside comments and tests: module → the modules it uses.
fn file_imports(src: &Path) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let modules: BTreeMap<Vec<String>, std::path::PathBuf> = files
        .iter()
        .map(|f| (module_of(src, f), f.clone()))
        .collect();
    let mut graph = BTreeMap::new();
    for (module, file) in &modules {
        let text = std::fs::read_to_string(file).unwrap();
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        let mut uses = BTreeSet::new();
        for line in code.lines().filter(|l| !l.trim_start().starts_with("//")) {
            for (i, _) in line.match_indices("::") {
                let before = &line[..i];
                let head = before
                    .rsplit(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                    .next()
                    .unwrap_or("");
                let mut path: Vec<String> = match head {
                    "crate" => Vec::new(),
                    "super" => module[..module.len().saturating_sub(1)].to_vec(),
                    "self" => module.clone(),
                    _ => continue,
                };
                let rest = &line[i + 2..];
                for segment in rest.split("::") {
                    let name: String = segment
                        .chars()
                        .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
                        .collect();
                    if name.is_empty() || name.len() != segment.len() && !segment.starts_with(&name)
                    {
                        break;
                    }
                    path.push(name.clone());
                    if name.len() != segment.len() {
                        break;
                    }
                }
                // The longest prefix that is a module of the crate.
                while !path.is_empty() && !modules.contains_key(&path) {
                    path.pop();
                }
                if &path != module {
                    uses.insert(path);
                }
            }
        }
        graph.insert(module.clone(), uses);
    }
    graph
}

/// A circle in `graph`, if there is one: the modules along it.
fn circle(graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Option<Vec<String>> {
    fn visit(
        node: &Vec<String>,
        graph: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
    ) -> Option<Vec<String>> {
        state.insert(node.clone(), 1);
        stack.push(node.clone());
        for next in graph.get(node).into_iter().flatten() {
            match state.get(next).copied().unwrap_or(0) {
                0 => {
                    if let Some(c) = visit(next, graph, state, stack) {
                        return Some(c);
                    }
                }
                1 => {
                    let from = stack.iter().position(|m| m == next).unwrap_or(0);
                    let name = |m: &Vec<String>| {
                        if m.is_empty() {
                            "lib".to_owned()
                        } else {
                            m.join("::")
                        }
                    };
                    return Some(stack[from..].iter().chain([next]).map(name).collect());
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(node.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for node in graph.keys() {
        if state.get(node).copied().unwrap_or(0) == 0 {
            if let Some(c) = visit(node, graph, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn no_file_of_a_library_crate_imports_in_a_circle() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut circles = Vec::new();
    for (name, dir, _) in LAYERS {
        let src = root.join(dir).join("src");
        if !src.join("lib.rs").exists() {
            continue;
        }
        if let Some(c) = circle(&file_imports(&src)) {
            circles.push(format!("{name}: {}", c.join(" -> ")));
        }
    }
    assert!(circles.is_empty(), "imports in a circle: {circles:#?}");
}

#[test]
fn a_circle_of_imports_is_found() {
    let graph: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = [
        (vec!["a".to_owned()], BTreeSet::from([vec!["b".to_owned()]])),
        (vec!["b".to_owned()], BTreeSet::from([vec!["a".to_owned()]])),
        (vec!["c".to_owned()], BTreeSet::new()),
    ]
    .into_iter()
    .collect();
    assert_eq!(
        circle(&graph),
        Some(vec!["a".into(), "b".into(), "a".into()])
    );
}

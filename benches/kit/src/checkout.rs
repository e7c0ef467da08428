//! The checkout the benchmarks were built from: its workspace root and its examples.

use std::path::{Path, PathBuf};

use anyhow::Context;

/// The workspace root of this checkout (`benches/kit/../..`) when built from it, else the
/// current directory if it holds a Cargo.toml.
pub fn workspace_root() -> Option<PathBuf> {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    if let Some(root) = manifest
        .parent()
        .and_then(Path::parent)
        .filter(|r| r.join("Cargo.toml").is_file())
    {
        return Some(root.to_path_buf());
    }
    let cwd = std::env::current_dir().ok()?;
    cwd.join("Cargo.toml").is_file().then_some(cwd)
}

/// `examples/NAME` of this checkout (whether it is there or not).
pub fn example(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples")).join(name)
}

/// `examples/NAME` of this checkout, made absolute; an error if it is missing.
pub fn existing_example(name: &str) -> anyhow::Result<PathBuf> {
    let path = example(name);
    std::fs::canonicalize(&path)
        .with_context(|| format!("{} is missing (run from a checkout)", path.display()))
}

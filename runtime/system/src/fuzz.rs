//! The entry point of the fuzz target `description` and of the test that replays its corpus:
//! a system description from untrusted text, loaded and checked in the sandbox. It may be
//! refused; it must not panic, hang or get out of the sandbox.

use std::path::PathBuf;

/// Loads `text` as a description whose programs all exist.
pub fn description(text: &str) {
    let anywhere = |program: &str| Some(PathBuf::from("/nonexistent").join(program));
    let _ = crate::load_str("fuzz.lua", text, &anywhere);
}

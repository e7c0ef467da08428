//! What is wrong with what a program's script asked for ([`ScriptError`]): an argument of the
//! wrong kind, a command definition with a field it cannot have, a plot it cannot draw. The
//! program stops with it at the script's line (`file:line: why`).

use std::path::PathBuf;

use thiserror::Error;

/// A script's request that cannot be carried out as written.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ScriptError {
    /// `read(...)`, `call(...)`, `data(...)` or `require ...` without the text it takes.
    #[error("{function} takes a text, as in {example}{}", not_a(.found))]
    NotAText {
        function: &'static str,
        example: &'static str,
        /// The kind given instead (none: nothing given).
        found: Option<&'static str>,
    },
    /// A command definition's field named by something other than a text.
    #[error("command \"{command}\": a field named by a {found}")]
    FieldName {
        command: String,
        found: &'static str,
    },
    /// A command definition's field of the wrong kind.
    #[error("command \"{command}\": field '{field}' must be {expected}, not a {found}")]
    FieldKind {
        command: String,
        field: String,
        expected: &'static str,
        found: &'static str,
    },
    /// A command definition's field that commands do not have.
    #[error("command \"{command}\": unknown field '{field}' (expected {expected})")]
    UnknownField {
        command: String,
        field: String,
        expected: String,
    },
    /// A command definition that Lua could not walk through.
    #[error("command \"{command}\": {why}")]
    Definition { command: String, why: String },
    /// `plot { }` without its lines.
    #[error("lines = {{ {{ name = \"...\", x = {{ ... }}, y = {{ ... }} }}, ... }} is required")]
    NoLines,
    /// `lines[n]` of a plot is not a table.
    #[error("lines[{0}] must be a table")]
    LineNotATable(usize),
    /// `lines[n].x` or `.y` is not a table of numbers, or holds something else.
    #[error("{what} must be a table of numbers")]
    NotNumbers { what: String },
    /// A line's x and y of different lengths.
    #[error("lines[{line}] has {x} x and {y} y values")]
    Unequal { line: usize, x: usize, y: usize },
    /// The SVG could not be drawn or written.
    #[error("{}: {why}", .path.display())]
    Plot { path: PathBuf, why: String },
}

fn not_a(found: &Option<&'static str>) -> String {
    found.map(|t| format!(", not a {t}")).unwrap_or_default()
}

//! The errors of loading a description: [`SystemError`] (`file:line: message`, with its cause),
//! [`DeclError`] (what one declaration's values say wrong) and [`VarError`] (`--var`).

use std::sync::Arc;

use thiserror::Error;

use modbot_core::domain::DomainNameError;

/// Why a system description was refused: `file:line: message`.
#[derive(Debug, Clone, Error)]
#[error("{file}{}: {message}", line_suffix(.line))]
pub struct SystemError {
    /// The description file, as it was named.
    pub file: String,
    /// The line the problem is on, when it is on one.
    pub line: Option<u32>,
    /// What is wrong, and what was expected.
    pub message: String,
    /// The error `message` tells, when there is one (a declaration's refusal, the grid's
    /// checks), with its own sources.
    #[source]
    pub cause: Option<Arc<dyn std::error::Error + Send + Sync>>,
}

fn line_suffix(line: &Option<u32>) -> String {
    line.map(|l| format!(":{l}")).unwrap_or_default()
}

impl SystemError {
    /// A refusal that is only a message.
    pub(crate) fn new(file: &str, line: Option<u32>, message: impl Into<String>) -> SystemError {
        SystemError {
            file: file.to_owned(),
            line,
            message: message.into(),
            cause: None,
        }
    }

    /// A refusal for `cause`, which says what is wrong.
    pub(crate) fn caused(
        file: &str,
        line: Option<u32>,
        cause: impl std::error::Error + Send + Sync + 'static,
    ) -> SystemError {
        SystemError::new(file, line, cause.to_string()).because(cause)
    }

    /// This refusal, whose message tells of `cause` (and ends with its text).
    pub(crate) fn because(
        mut self,
        cause: impl std::error::Error + Send + Sync + 'static,
    ) -> SystemError {
        self.cause = Some(Arc::new(cause));
        self
    }
}

/// Why a declaration is refused, from what its own values say: `what` names the declaration
/// ("module 'sonar'", "grid"), and the variant what is wrong with which field. The file and
/// the line are added by the evaluation ([`SystemError`]).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DeclError {
    /// A declaration function called with other than one argument.
    #[error("expected one argument but got {got}: write {usage}")]
    Arguments { got: usize, usage: &'static str },
    /// `connect` called with other than one or two strings.
    #[error("connect takes an output and an input: {usage}")]
    ConnectArguments { usage: &'static str },
    /// A declaration given the wrong kind of value: `domain(42)`, `module "x" (3)`.
    #[error("{what} must be given {expected}, not {got}")]
    Argument {
        what: String,
        /// What it takes, with an example.
        expected: String,
        /// The value given, as a message shows it (`3`, `'text'`, `a table`).
        got: String,
    },
    /// A module, group or component name that is not a transport name.
    #[error("{what} name '{name}' is invalid: use 1 to 48 characters of a-z, A-Z, 0-9, _ and -")]
    Name { what: &'static str, name: String },
    #[error(transparent)]
    Domain(#[from] DomainNameError),
    /// A field the declaration does not know (a typo, most often).
    #[error("{what}: unknown field '{field}' (expected {})", .expected.join(", "))]
    UnknownField {
        what: String,
        field: String,
        expected: &'static [&'static str],
    },
    /// A table entry whose key is not a name (`[1] = 2` among `name = value` fields).
    #[error("{what}: {kind} are written name = value, and [{key}] = {value} is not")]
    Unnamed {
        what: String,
        /// `fields` or `params`.
        kind: &'static str,
        key: String,
        value: String,
    },
    /// A required field is not given; `hint` says what it takes (may be empty).
    #[error("{what}: field '{field}' is required{hint}")]
    Missing {
        what: String,
        field: &'static str,
        hint: &'static str,
    },
    /// A field's value is not what the field takes.
    #[error("{what}: field '{field}' must be {expected}{}", not(.got))]
    Field {
        what: String,
        field: String,
        expected: String,
        /// The value given, when the message shows it.
        got: Option<String>,
    },
    /// Values that are each fine but not together, or a list item that is not: `why` says
    /// what is wrong.
    #[error("{what}: {why}")]
    Invalid { what: String, why: String },
    #[error("group '{group}' has no members")]
    NoMembers { group: String },
    /// A declaration that may be made once (`domain`, `supervision`, `grid`), made again.
    #[error("{what} is already declared at line {first}")]
    Duplicate { what: &'static str, first: u32 },
    #[error("too many {kind} declarations (at most {max})")]
    TooMany { kind: &'static str, max: usize },
    #[error("the description ran too long (instruction limit)")]
    InstructionLimit,
    /// `module "x"` (or `group`, `component`) called without the table that follows.
    #[error("{kind} '{name}' is declared without its table: write {kind} \"{name}\" {example}")]
    NoTable {
        kind: &'static str,
        name: String,
        example: &'static str,
    },
    /// Lua failed while a table was read (out of memory, say). Its text is kept, not the
    /// `mlua::Error`, which is not `Send` (nor is anything that holds it).
    #[error("{what}: {detail}")]
    Lua { what: String, detail: String },
}

fn not(got: &Option<String>) -> String {
    got.as_ref()
        .map(|g| format!(", not {g}"))
        .unwrap_or_default()
}

impl DeclError {
    /// `what`: field `field` must be `expected`, not `got`.
    pub(crate) fn field(
        what: &str,
        field: &str,
        expected: impl Into<String>,
        got: impl Into<String>,
    ) -> DeclError {
        DeclError::Field {
            what: what.to_owned(),
            field: field.to_owned(),
            expected: expected.into(),
            got: Some(got.into()),
        }
    }

    /// `what`: `why`.
    pub(crate) fn invalid(what: &str, why: impl Into<String>) -> DeclError {
        DeclError::Invalid {
            what: what.to_owned(),
            why: why.into(),
        }
    }

    /// `what`: field `field` is required, and `hint` (" (1 to 254)", or "").
    pub(crate) fn missing(what: &str, field: &'static str, hint: &'static str) -> DeclError {
        DeclError::Missing {
            what: what.to_owned(),
            field,
            hint,
        }
    }
}

/// Why a `--var KEY=VALUE` is refused ([`parse_var`](crate::parse_var)).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum VarError {
    #[error("'{text}' is not KEY=VALUE (no '=')")]
    NoEquals { text: String },
    #[error("'{text}' has no key before the '=': write KEY=VALUE")]
    NoKey { text: String },
    #[error(
        "key '{key}' contains {bad:?}: a key is made of ASCII letters, digits, '_', '-' and '.'"
    )]
    BadKey { key: String, bad: char },
}

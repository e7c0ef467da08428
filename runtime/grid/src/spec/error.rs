//! Why declarations are not a valid grid ([`GridError`]): the line, and what is wrong
//! ([`GridErrorKind`]), with the refusal of a component's type, host name or period as its
//! source.

use modbot_ipc_schema::grid::MAX_SOURCES;
use thiserror::Error;

use super::{Period, MAX_COMPONENTS, MAX_PERIOD_TICKS};
use crate::component::{list_or_none, ComponentError, PortType};

/// Why declarations are not a valid grid: the line (when there is one) and what is wrong.
#[derive(Debug, Error)]
#[error("{}{kind}", line_prefix(.line))]
pub struct GridError {
    pub line: Option<u32>,
    /// What is wrong.
    #[source]
    pub kind: GridErrorKind,
}

fn line_prefix(line: &Option<u32>) -> String {
    line.map(|l| format!("line {l}: ")).unwrap_or_default()
}

/// What is wrong with a grid's declarations.
#[derive(Debug, Error)]
pub enum GridErrorKind {
    #[error("grid: base_period must be positive")]
    BasePeriod,
    #[error("the grid has no components: add component \"name\" {{ type = ..., host = ... }}")]
    NoComponents,
    #[error("too many components (at most {MAX_COMPONENTS})")]
    TooManyComponents,
    #[error(transparent)]
    HostPrograms(Box<HostPrograms>),
    #[error("component name '{name}' is already declared at line {first}")]
    DuplicateComponent { name: String, first: u32 },
    #[error(
        "component '{component}': the name is invalid: use 1 to 48 characters of a-z, A-Z, 0-9, \
         _ and -"
    )]
    ComponentName { component: String },
    #[error("component '{component}': {error}")]
    Host {
        component: String,
        #[source]
        error: HostNameError,
    },
    #[error("component '{component}': {error}")]
    Period {
        component: String,
        #[source]
        error: PeriodError,
    },
    #[error("component '{component}': param '{param}' is set automatically and cannot be given")]
    AutomaticParam {
        component: String,
        param: &'static str,
    },
    /// Its type refuses its parameters (or is not known).
    #[error("component '{component}': {error}")]
    Component {
        component: String,
        #[source]
        error: ComponentError,
    },
    #[error(
        "connect {connect}: no component is named '{name}' (components: {}{})",
        .known.join(", "),
        if *.more { ", ..." } else { "" }
    )]
    NoComponent {
        /// The connection as written: `A.y -> B.u`.
        connect: String,
        name: String,
        /// The first components of the grid, and whether there are more.
        known: Vec<String>,
        more: bool,
    },
    #[error("component '{component}' has no {side} '{port}' ({side}s: {})", list_or_none(.ports))]
    NoPort {
        component: String,
        /// `input` or `output`.
        side: &'static str,
        port: String,
        /// The ports it has on that side.
        ports: Vec<&'static str>,
    },
    #[error("{from} is {from_ty} but {to} is {to_ty}")]
    TypeMismatch {
        /// The output, `A.y`, and its type.
        from: String,
        from_ty: PortType,
        /// The input, `B.u`, and its type.
        to: String,
        to_ty: PortType,
    },
    #[error("{input} is already connected (from {from} at line {first})")]
    AlreadyConnected {
        /// The input, `B.u`.
        input: String,
        /// The output that feeds it, and the line of that connection.
        from: String,
        first: u32,
    },
    #[error(
        "component '{component}': input '{input}' is not connected: every input needs a connect \
         \"X.y -> {component}.{input}\""
    )]
    Unconnected {
        component: String,
        input: &'static str,
    },
    /// A `record` declaration names a signal that is not an output, or nothing.
    #[error("record '{record}': {what}")]
    Record { record: String, what: String },
    #[error("component '{component}' is fed by {sources} components; at most {MAX_SOURCES}")]
    TooManySources { component: String, sources: usize },
}

/// Why a host name is refused (see [`check_host`](super::check_host)).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error(
    "host name '{host}' is invalid: use 1 to 32 characters of a-z, 0-9 and _, not ending in _g \
     and a number"
)]
pub struct HostNameError {
    pub host: String,
}

/// Why a component's period is refused: not a whole multiple of the base tick, or out of range.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum PeriodError {
    #[error("period must be positive, not {}", shown(.period, .base_s))]
    NotPositive { period: Period, base_s: f64 },
    #[error("period {} is not a multiple of the base tick ({base_s} s)", shown(.period, .base_s))]
    NotMultiple { period: Period, base_s: f64 },
    #[error(
        "period {} is too long (at most {MAX_PERIOD_TICKS} base ticks)",
        shown(.period, .base_s)
    )]
    TooLong { period: Period, base_s: f64 },
}

/// A period as a message shows it: `3 ticks (0.003 s)` or `0.002 s`.
fn shown(period: &Period, base_s: &f64) -> String {
    match *period {
        Period::Ticks(k) => format!("{k} ticks ({} s)", k * base_s),
        Period::Seconds(s) => format!("{s} s"),
    }
}

/// Two components of one host whose types are made by different programs.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("host '{host}' would need two programs: component '{}' is made by '{}', component '{}' by '{}'; give them hosts of their own", .first.0, .first.1, .second.0, .second.1)]
pub struct HostPrograms {
    pub host: String,
    /// (component, program) of each.
    pub first: (String, String),
    pub second: (String, String),
}

//! The checked grid ("grid spec image"): the time grid as the supervisor evaluated and checked
//! it from the system description, written once per assembly generation
//! (`/dev/shm/modbot_<domain>.spec.g<N>`) and read by every grid process started with
//! `--spec-generation N`, so that only the supervisor evaluates the description.
//!
//! One run of values in the payload encoding ([`encode`], [`decode`]):
//!
//! ```text
//! image       := "MBGS" (text)  1 (i64, the version)  GRID  ASSEMBLY  DECLARED  COMPONENTS  CONNECTIONS
//! GRID        := base_period_ns  priority (0: none)  mlock (bool)  k, k × cpu  line  clock (text)
//!                track_ticks  spin_us
//! ASSEMBLY    := 0  |  1 name generation base
//! DECLARED    := d, d × ( program  line  INFO )
//! COMPONENTS  := n, n × ( name  type  program ("": none)  host  period  policy (text)  line
//!                         p, p × (param name, value)  INFO )
//! INFO        := type (text)  doc (text)  ki, ki × (name, port type)  ko, ko × (name, port type)
//!                q, q × (name, param type, has_default (bool), [default value])
//! CONNECTIONS := m, m × ( from_component  from_port  to_component  to_port  line )
//! ```
//!
//! Numbers are i64 ≥ 0 (counts, indices, lines, periods); texts are names, the clock
//! (`realtime`, `lockstep`), the policy (`hold`, `fault`), port types as
//! [`PortType`]'s `Display` writes them (`bool`, `i64`, `f64`, `f64[6]`) and parameter types
//! as [`ParamType`]'s (`bool`, `i64`, `f64`, `f64 list`, `text`). A parameter's value is the
//! payload value of its kind: bool, i64, f64, f64 array or text (bytes are no parameter).
//!
//! [`decode`] reads the shape (`decode.rs`), then checks what makes the image safe to index
//! (`check.rs`, [`GridImage::check`]): names, ranges, and connections that name existing
//! ports of one type, feed every input exactly once and give no component more than
//! [`MAX_SOURCES`](crate::grid::MAX_SOURCES) source components. A count is refused before
//! anything is read for it when the bytes left cannot hold that many entries.

mod check;
mod decode;
mod encode;

pub use decode::decode;
pub use encode::encode;

use core::fmt;

use thiserror::Error;

use crate::fields::FieldError;
use crate::grid::{Generation, GridClock, OverrunPolicy, ParamType, ParamValue, PortType};
use crate::value::ValueKind;

/// The image's first value.
pub const MAGIC: &str = "MBGS";

/// The layout's version, the image's second value.
pub const VERSION: i64 = 1;

/// The highest CPU number an image names (a `cpu_set_t` holds 1024 on glibc; 4096 leaves room).
pub const MAX_CPU: usize = 4095;

/// The longest f64 array port an image gives (2^16 f64s, 512 KiB): a grid process allocates
/// its ports and records from these lengths. A description's arrays are shorter (4096).
pub const MAX_ARRAY: usize = 1 << 16;

/// The checked grid of one assembly generation.
#[derive(Debug, Clone, PartialEq)]
pub struct GridImage {
    /// The base tick's period, ns (≥ 1): every period counts base ticks.
    pub base_period_ns: u64,
    /// The CPUs the grid's threads are pinned to (each ≤ [`MAX_CPU`]); empty: not pinned.
    pub cpus: Vec<usize>,
    /// The SCHED_FIFO priority of the grid's threads (1..=99); `None`: the default policy.
    pub priority: Option<u8>,
    /// Whether the grid's processes lock their memory.
    pub mlock: bool,
    /// The description's line of the grid, for messages.
    pub line: u32,
    /// Where the base tick comes from.
    pub clock: GridClock,
    /// How many ticks the coordinator records in its trace.
    pub track_ticks: u64,
    /// How long a waiter spins before it sleeps, µs.
    pub spin_us: u64,
    /// The assembly this image belongs to; `None`: a grid without assemblies.
    pub assembly: Option<AssemblyImage>,
    /// The component types the description declares, which hosts check against the types
    /// their programs register.
    pub declared: Vec<DeclaredImage>,
    /// The components, in the order the grid's indices (connections, notices) use.
    pub components: Vec<ComponentImage>,
    /// Which output feeds which input.
    pub connections: Vec<ConnectionImage>,
}

/// The assembly an image belongs to.
#[derive(Debug, Clone, PartialEq)]
pub struct AssemblyImage {
    /// Its name (an assembly name: the file it comes from).
    pub name: String,
    /// The generation it was prepared as (≥ 1; 0 is the system's own components).
    pub generation: Generation,
    /// The index of its first component (≤ the number of components): the ones before are the
    /// system's own, which every assembly keeps.
    pub base: usize,
}

/// A component type the description declares.
#[derive(Debug, Clone, PartialEq)]
pub struct DeclaredImage {
    /// The host program that makes it (not empty).
    pub program: String,
    /// The line of its declaration, for messages.
    pub line: u32,
    /// Its interface as declared.
    pub info: InfoImage,
}

/// One component of the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentImage {
    /// Its name (not empty, unique among the components): connections and tools use it.
    pub name: String,
    /// Its type's name (not empty), as the host's registry knows it.
    pub type_name: String,
    /// The host program of a declared type (on the wire `""` is `None`).
    pub program: Option<String>,
    /// The host module it runs in (a module name).
    pub host: String,
    /// Its period in base ticks (1..=u32::MAX).
    pub period: u64,
    /// What a missed deadline does.
    pub policy: OverrunPolicy,
    /// Its line in the description, for messages.
    pub line: u32,
    /// Its parameters, in the registry's order (names not empty).
    pub params: Vec<(String, ParamValue)>,
    /// Its type's interface: the ports connections index.
    pub info: InfoImage,
}

/// A component type's interface.
#[derive(Debug, Clone, PartialEq)]
pub struct InfoImage {
    /// The type's name (not empty).
    pub type_name: String,
    /// One sentence on what it computes (any text).
    pub doc: String,
    /// Inputs in port order.
    pub inputs: Vec<PortImage>,
    /// Outputs in port order (the order of the output record).
    pub outputs: Vec<PortImage>,
    /// The parameters a description may set.
    pub params: Vec<ParamDeclImage>,
}

/// A named port (on the wire: its name, then its type's text).
#[derive(Debug, Clone, PartialEq)]
pub struct PortImage {
    /// Not empty.
    pub name: String,
    pub ty: PortType,
}

/// A declared parameter (on the wire: its name, its type's text, whether it has a default,
/// then the default if it has one).
#[derive(Debug, Clone, PartialEq)]
pub struct ParamDeclImage {
    /// Not empty.
    pub name: String,
    pub ty: ParamType,
    /// `None`: the parameter must be given. Its kind is not checked against `ty` (a default
    /// may be coerced, as a description's value is).
    pub default: Option<ParamValue>,
}

/// An output feeding an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConnectionImage {
    /// An output: `port` indexes the component's `info.outputs`.
    pub from: PortAt,
    /// An input: `port` indexes the component's `info.inputs`.
    pub to: PortAt,
    /// Its line in the description, for messages.
    pub line: u32,
}

/// A port of a component, by indices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PortAt {
    /// Indexes [`GridImage::components`].
    pub component: usize,
    /// Indexes the component's inputs or outputs.
    pub port: usize,
}

/// The part of an image a name, a type or a value belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    Assembly,
    /// A declared type, by index.
    Declared(usize),
    /// A component, by index.
    Component(usize),
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Place::Assembly => f.write_str("the assembly"),
            Place::Declared(i) => write!(f, "declared type {i}"),
            Place::Component(i) => write!(f, "component {i}"),
        }
    }
}

/// An end of a connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    /// The output, `from`.
    From,
    /// The input, `to`.
    To,
}

impl fmt::Display for End {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            End::From => "from",
            End::To => "to",
        })
    }
}

/// Why bytes are not a checked grid.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum GridSpecError {
    /// A value missing, malformed, of another kind or out of its field's range.
    #[error("grid spec: {0}")]
    Field(#[from] FieldError),
    #[error("grid spec: magic '{found}', expected '{MAGIC}'")]
    Magic { found: String },
    #[error("grid spec: version {found}, this reader knows {VERSION}")]
    Version { found: i64 },
    #[error("grid spec: {what}: {count} of them cannot fit in the {remaining} bytes left")]
    Count {
        what: &'static str,
        count: usize,
        remaining: usize,
    },
    #[error("grid spec: the assembly's tag is {tag}, expected 0 (none) or 1")]
    AssemblyTag { tag: i64 },
    #[error("grid spec: unknown clock '{name}' (realtime or lockstep)")]
    Clock { name: String },
    #[error("grid spec: component {component}: unknown overrun policy '{name}' (hold or fault)")]
    Policy { component: usize, name: String },
    #[error("grid spec: {at}: port '{port}' has unknown type '{ty}'")]
    PortType { at: Place, port: String, ty: String },
    #[error("grid spec: {at}: port '{port}' is an array of {len} f64, not 1 to {MAX_ARRAY}")]
    ArrayLength { at: Place, port: String, len: usize },
    #[error("grid spec: {at}: parameter '{param}' has unknown type '{ty}'")]
    ParamType {
        at: Place,
        param: String,
        ty: String,
    },
    #[error("grid spec: {at}: parameter '{param}' is {found}, not a parameter's kind (bool, i64, f64, f64 array, text)")]
    ParamKind {
        at: Place,
        param: String,
        found: ValueKind,
    },
    #[error("grid spec: values follow the image, from byte {offset}")]
    Trailing { offset: usize },
    #[error("grid spec: a base period of 0 ns")]
    BasePeriod,
    #[error("grid spec: priority {priority} is outside 1..=99")]
    Priority { priority: u8 },
    #[error("grid spec: CPU {cpu} is past {MAX_CPU}")]
    Cpu { cpu: usize },
    #[error("grid spec: the assembly's generation is 0 (the system's own components)")]
    Generation,
    #[error("grid spec: {at}: {what} '{name}' is not {rule}")]
    Name {
        at: Place,
        what: &'static str,
        name: String,
        rule: &'static str,
    },
    #[error("grid spec: components {first} and {second} are both named '{name}'")]
    DuplicateComponent {
        name: String,
        first: usize,
        second: usize,
    },
    #[error("grid spec: component {component}: period {period} is outside 1..=4294967295 ticks")]
    Period { component: usize, period: u64 },
    #[error(
        "grid spec: the assembly's first component {base} is past the {components} components"
    )]
    Base { base: usize, components: usize },
    #[error("grid spec: connection {connection} ({end}): {what} {index} is out of range (there are {len})")]
    OutOfRange {
        connection: usize,
        end: End,
        /// `component`, or `output`/`input` of the component named.
        what: &'static str,
        index: usize,
        len: usize,
    },
    #[error("grid spec: connection {connection}: {from} is {from_ty} but {to} is {to_ty}")]
    TypeMismatch {
        connection: usize,
        /// `component.port`.
        from: String,
        from_ty: PortType,
        to: String,
        to_ty: PortType,
    },
    #[error("grid spec: input {component}.{input} is fed by nothing")]
    Unfed { component: String, input: String },
    #[error(
        "grid spec: input {component}.{input} is fed twice (connections {first} and {second})"
    )]
    FedTwice {
        component: String,
        input: String,
        first: usize,
        second: usize,
    },
    #[error(
        "grid spec: component {component}'s inputs come from {sources} components; at most {}",
        crate::grid::MAX_SOURCES
    )]
    TooManySources { component: String, sources: usize },
}

#[cfg(test)]
mod tests;

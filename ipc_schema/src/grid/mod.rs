//! The time grid's wire formats: port values, the output record a component publishes, and
//! the notices between the coordinator and the component hosts.
//!
//! # Port values
//! A port has a fixed type: bool, i64, f64, or an f64 array of fixed length. On the wire every
//! scalar takes 8 bytes little-endian (bool: 0 or 1 as u64; f64: its IEEE bits) and an array of
//! n takes 8·n bytes, so a component's outputs pack into one record of fixed size.
//!
//! # Output sample (`grid.out.<component>`)
//! ```text
//! offset size field
//!  0     8    valid_from: the logical tick from which these outputs are valid (release + period)
//!  8     8    release: the tick at which the component was released
//! 16     …    the outputs, packed in port order
//! ```
//! The notices between the coordinator and the hosts (release, prepare, done) are in
//! `notices.rs`.

mod notices;
mod param;
mod timing;

pub use notices::{Done, Prepare, PrepareNameError, Release, PREPARE_NAME_MAX};
pub use param::{ParamType, ParamValue};
pub use timing::{GridClock, OverrunPolicy};

use thiserror::Error;
use zerocopy::byteorder::little_endian::U64;
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

/// A base tick of the grid, counted by the coordinator from 0: the time of the grid's
/// semantics (a release at tick n reads what is valid at n).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Tick(pub u64);

impl Tick {
    /// The tick `ticks` after this one.
    pub fn after(self, ticks: u64) -> Tick {
        Tick(self.0 + ticks)
    }
}

impl core::fmt::Display for Tick {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// An assembly generation: 0 for the system's own components (or a grid without assemblies),
/// then one more for each assembly prepared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Generation(pub u16);

impl Generation {
    /// The system's own components, whatever the assembly.
    pub const SYSTEM: Generation = Generation(0);
}

impl core::fmt::Display for Generation {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// The component index of a warm-up release: the host answers it at once with a done notice
/// of the same index, so that the notice channels and the host's paths are warm before tick 0.
pub const PING: u16 = u16::MAX;

/// The component index of a done notice that says a host is ready for an assembly.
pub const READY: u16 = u16::MAX - 1;

/// Special component index of a release notice: the grid stops (a normal stop, `modbot down`
/// or its ticks done), no release follows; a host tells its components
/// (`Component::stopping`), so the bus stops the drives without judging the coordinator lost.
/// It needs no done notice.
pub const STOPPING: u16 = u16::MAX - 2;

/// Special component index of a release notice: a new process of the host takes its
/// components over at tick `tick` (a live upgrade, `modbot upgrade`; see [`SUCCESSOR`] and
/// [`UPGRADE`] for what comes before). The notice comes after
/// every release before that tick, as the last of its batch; `released_ns` carries the new
/// process's pid. Both processes of the host read it: the running one hands the components'
/// state over and serves no more (once the new one says it took it), the new one takes the
/// state and serves every release from `tick` on.
pub const HANDOVER: u16 = u16::MAX - 3;

/// Special component index of a done notice: a new process of a host is ready to take its
/// components over (subscribed, standing by). `tick` carries the index of one of the host's
/// components (so the coordinator knows the host), `exec_ns` the new process's pid; the
/// coordinator answers with an [`UPGRADE`] release.
pub const SUCCESSOR: u16 = u16::MAX - 4;

/// Special component index of a release notice and of its answer: a new process of the host
/// stands by (`released_ns`: its pid). The running process opens its end of the handover off
/// its serving thread and then answers with a done notice of this index (`tick`: one of its
/// components, as [`SUCCESSOR`]); the coordinator then sends the [`HANDOVER`]. The new process
/// ignores it.
pub const UPGRADE: u16 = u16::MAX - 5;

/// The most source components one component's inputs come from.
pub const MAX_SOURCES: usize = 16;
/// Size of the output sample header.
pub const OUT_HEADER_LEN: usize = 16;

/// A port's type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PortType {
    Bool,
    I64,
    F64,
    /// An array of exactly this many f64.
    F64s(usize),
}

impl PortType {
    /// Bytes on the wire.
    pub fn wire_len(self) -> usize {
        match self {
            PortType::F64s(n) => 8 * n,
            _ => 8,
        }
    }

    /// The value a port holds before anything was written: false, 0, 0.0, zeros.
    pub fn zero(self) -> PortValue {
        match self {
            PortType::Bool => PortValue::Bool(false),
            PortType::I64 => PortValue::I64(0),
            PortType::F64 => PortValue::F64(0.0),
            PortType::F64s(n) => PortValue::F64s(vec![0.0; n]),
        }
    }
}

impl PortType {
    /// The type written as [`Display`](core::fmt::Display) writes it (`bool`, `i64`, `f64`,
    /// `f64[N]` with N ≥ 1); `None` for anything else.
    pub fn parse(text: &str) -> Option<PortType> {
        match text {
            "bool" => Some(PortType::Bool),
            "i64" => Some(PortType::I64),
            "f64" => Some(PortType::F64),
            array => {
                let digits = array.strip_prefix("f64[")?.strip_suffix(']')?;
                let n: usize = digits.parse().ok().filter(|&n| n >= 1)?;
                // Only the canonical spelling: "f64[06]" and "f64[+6]" are not types.
                (n.to_string() == digits).then_some(PortType::F64s(n))
            }
        }
    }
}

impl core::fmt::Display for PortType {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PortType::Bool => f.write_str("bool"),
            PortType::I64 => f.write_str("i64"),
            PortType::F64 => f.write_str("f64"),
            PortType::F64s(n) => write!(f, "f64[{n}]"),
        }
    }
}

/// A port's value.
#[derive(Debug, Clone, PartialEq)]
pub enum PortValue {
    Bool(bool),
    I64(i64),
    F64(f64),
    F64s(Vec<f64>),
}

impl PortValue {
    pub fn port_type(&self) -> PortType {
        match self {
            PortValue::Bool(_) => PortType::Bool,
            PortValue::I64(_) => PortType::I64,
            PortValue::F64(_) => PortType::F64,
            PortValue::F64s(v) => PortType::F64s(v.len()),
        }
    }

    pub fn as_f64(&self) -> f64 {
        match self {
            PortValue::Bool(b) => f64::from(u8::from(*b)),
            PortValue::I64(i) => *i as f64,
            PortValue::F64(x) => *x,
            PortValue::F64s(v) => v.first().copied().unwrap_or(0.0),
        }
    }

    /// Copies `other` into `self` without allocating when both are arrays of one length.
    pub fn assign(&mut self, other: &PortValue) {
        match (self, other) {
            (PortValue::F64s(a), PortValue::F64s(b)) if a.len() == b.len() => a.copy_from_slice(b),
            (me, other) => *me = other.clone(),
        }
    }
}

impl core::fmt::Display for PortValue {
    /// Exact: f64 values print as the shortest text that reads back to the same bits.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PortValue::Bool(b) => write!(f, "{b}"),
            PortValue::I64(i) => write!(f, "{i}"),
            PortValue::F64(x) => write!(f, "{x:?}"),
            PortValue::F64s(v) => {
                f.write_str("[")?;
                for (i, x) in v.iter().enumerate() {
                    if i > 0 {
                        f.write_str(",")?;
                    }
                    write!(f, "{x:?}")?;
                }
                f.write_str("]")
            }
        }
    }
}

/// Why bytes are not a valid grid record or notice.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum GridWireError {
    #[error("record of {got} bytes, expected {expected}")]
    Length { expected: usize, got: usize },
    #[error("release notice with {0} sources; at most {MAX_SOURCES}")]
    TooManySources(usize),
    #[error("bool port holds {0}, not 0 or 1")]
    BadBool(u64),
    #[error("done notice of component {component} with unknown status {status}")]
    UnknownStatus { component: u16, status: u16 },
    #[error("prepare notice: {0}")]
    PrepareName(#[from] PrepareNameError),
}

/// The bytes the outputs of these types take.
pub fn record_len(types: &[PortType]) -> usize {
    types.iter().map(|t| t.wire_len()).sum()
}

/// Packs `values` into `out` (exactly [`record_len`] bytes).
pub fn write_record(values: &[PortValue], out: &mut [u8]) -> Result<(), GridWireError> {
    let expected: usize = values.iter().map(|v| v.port_type().wire_len()).sum();
    if out.len() != expected {
        return Err(GridWireError::Length {
            expected,
            got: out.len(),
        });
    }
    let mut at = 0;
    let mut put = |word: u64| {
        out[at..at + 8].copy_from_slice(&word.to_le_bytes());
        at += 8;
    };
    for v in values {
        match v {
            PortValue::Bool(b) => put(u64::from(*b)),
            PortValue::I64(i) => put(*i as u64),
            PortValue::F64(x) => put(x.to_bits()),
            PortValue::F64s(xs) => xs.iter().for_each(|x| put(x.to_bits())),
        }
    }
    Ok(())
}

/// Unpacks a record into `values`, whose types say how to read it; no allocation when the
/// arrays already have their lengths.
pub fn read_record(bytes: &[u8], values: &mut [PortValue]) -> Result<(), GridWireError> {
    let expected: usize = values.iter().map(|v| v.port_type().wire_len()).sum();
    if bytes.len() != expected {
        return Err(GridWireError::Length {
            expected,
            got: bytes.len(),
        });
    }
    let mut words = bytes
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8])));
    let mut next = || words.next().unwrap_or(0);
    for v in values.iter_mut() {
        match v {
            PortValue::Bool(b) => {
                *b = match next() {
                    0 => false,
                    1 => true,
                    other => return Err(GridWireError::BadBool(other)),
                }
            }
            PortValue::I64(i) => *i = next() as i64,
            PortValue::F64(x) => *x = f64::from_bits(next()),
            PortValue::F64s(xs) => xs.iter_mut().for_each(|x| *x = f64::from_bits(next())),
        }
    }
    Ok(())
}

/// The header of an output sample, read in place.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct OutHeader {
    pub valid_from: U64,
    pub release: U64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    #[test]
    fn a_port_type_reads_back_from_its_text_and_nothing_else_is_one() {
        for ty in [
            PortType::Bool,
            PortType::I64,
            PortType::F64,
            PortType::F64s(1),
            PortType::F64s(4096),
        ] {
            assert_eq!(PortType::parse(&ty.to_string()), Some(ty));
        }
        for text in [
            "", "f32", "f64[]", "f64[0]", "f64[06]", "f64[+6]", "f64[6", "F64",
        ] {
            assert_eq!(PortType::parse(text), None, "{text}");
        }
    }

    #[test]
    fn a_record_packs_every_port_into_8_byte_words_and_reads_back() {
        let values = vec![
            PortValue::Bool(true),
            PortValue::I64(-2),
            PortValue::F64(1.5),
            PortValue::F64s(vec![1.0, -0.0]),
        ];
        let types: Vec<PortType> = values.iter().map(PortValue::port_type).collect();
        let mut out = vec![0; record_len(&types)];
        write_record(&values, &mut out).unwrap();
        assert_eq!(
            hex::encode(&out),
            concat!(
                "0100000000000000",
                "feffffffffffffff",
                "000000000000f83f",
                "000000000000f03f",
                "0000000000000080"
            )
        );
        let mut back: Vec<PortValue> = types.iter().map(|t| t.zero()).collect();
        read_record(&out, &mut back).unwrap();
        assert_eq!(back, values);
        assert!(read_record(&out[1..], &mut back).is_err());
    }

    #[test]
    fn values_print_exactly() {
        assert_eq!(PortValue::F64(0.1).to_string(), "0.1");
        assert_eq!(PortValue::F64s(vec![1.0, 2.5]).to_string(), "[1.0,2.5]");
    }
}

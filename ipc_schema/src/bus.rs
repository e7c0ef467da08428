//! The bus bridge's record of assembly switches: its answer to the method `switches`
//! (`modbot bus --switches`), one bytes value.
//!
//! ```text
//! header, 24 bytes
//! offset size field
//!  0     4    magic "MBSW"
//!  4     1    version (1)
//!  5     1    reserved, 0
//!  6     2    switches that follow, u16 LE
//!  8     8    max step: the largest change of commanded position between two cycles of one
//!             assembly, rad (f64 LE)
//! 16     8    max velocity step: the same for the commanded velocity, rad/s (f64 LE)
//! then one 40-byte record per switch, oldest first:
//!  0     2    the assembly's generation, u16 LE
//!  2     6    reserved, 0
//!  8     8    tick of the first cycle it commanded, u64 LE
//! 16     8    cycles missed within 5 ticks of it, before or after, u64 LE
//! 24     8    step: the largest change of commanded position on any axis at it, rad (f64 LE)
//! 32     8    velocity step: the same for the commanded velocity, rad/s (f64 LE)
//! ```
//!
//! Steps are magnitudes: a step that is NaN, infinite or negative is malformed, as is a record
//! count that disagrees with the length (no byte may follow the last record). Reserved bytes
//! are written 0 and ignored by readers. The records' order is the bridge's (oldest first) and
//! is not checked: a coordinator that restarts counts its ticks from 0 again.

use thiserror::Error;
use zerocopy::byteorder::little_endian::{F64, U16, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use crate::preamble::{Format, Headed, Preamble};

/// The first four bytes.
pub const MAGIC: [u8; 4] = *b"MBSW";
/// The format version this crate writes and reads.
pub const VERSION: u8 = 1;
/// Header size.
pub const HEADER_LEN: usize = 24;
/// Record size.
pub const RECORD_LEN: usize = 40;
/// The most switches one answer holds.
pub const MAX_SWITCHES: usize = u16::MAX as usize;

/// The header, as laid out on the wire.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct Header {
    preamble: Preamble,
    max_step: F64,
    max_velocity_step: F64,
}

impl Headed for Header {
    fn preamble(&self) -> &Preamble {
        &self.preamble
    }
}

/// One switch, as laid out on the wire.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct Record {
    generation: U16,
    reserved: [u8; 6],
    tick: U64,
    missed_near: U64,
    step: F64,
    velocity_step: F64,
}

/// An assembly taking over the bus.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Switch {
    /// The assembly's generation.
    pub generation: u16,
    /// The tick of the first cycle it commanded.
    pub tick: u64,
    /// The largest change of commanded position on any axis from the cycle before, rad.
    pub step: f64,
    /// The largest change of commanded velocity (the position's change per cycle over the
    /// base period) on any axis from the cycle before, rad/s.
    pub velocity_step: f64,
    /// Cycles missed within a few ticks of it (the bridge's `NEAR_SWITCH`), before or after.
    pub missed_near: u64,
}

/// The bridge's record: the switches it saw, and the largest steps within an assembly, to
/// compare a switch's with.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Switches {
    /// The largest change of commanded position between two cycles of one assembly, rad.
    pub max_step: f64,
    /// The same for the commanded velocity, rad/s.
    pub max_velocity_step: f64,
    /// Oldest first.
    pub switches: Vec<Switch>,
}

/// Why bytes are not a record of switches, or a record cannot be written.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SwitchesError {
    #[error("a record of switches is at least {HEADER_LEN} bytes, got {0}")]
    Size(usize),
    #[error("not a record of switches: magic {0:02x?}")]
    Magic([u8; 4]),
    #[error("switches format version {0}, this build reads {VERSION}")]
    Version(u8),
    #[error("a record of {count} switches is {expected} bytes, got {len}")]
    Count {
        count: usize,
        expected: usize,
        len: usize,
    },
    #[error("{what} {value} is not a magnitude (NaN, infinite or negative)")]
    Step { what: &'static str, value: String },
    #[error("{0} switches do not fit in one record (at most {MAX_SWITCHES})")]
    TooMany(usize),
}

impl SwitchesError {
    /// The record's magic and version, and how a header that is not the record's is refused.
    const FORMAT: Format<Self> =
        Format::new(MAGIC, VERSION, Self::Size, Self::Magic, Self::Version);
}

fn magnitude(what: &'static str, value: f64) -> Result<f64, SwitchesError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(SwitchesError::Step {
            what,
            value: value.to_string(),
        })
    }
}

/// Appends a record to `out` (nothing when it is refused).
pub fn encode(
    max_step: f64,
    max_velocity_step: f64,
    switches: &[Switch],
    out: &mut Vec<u8>,
) -> Result<(), SwitchesError> {
    if switches.len() > MAX_SWITCHES {
        return Err(SwitchesError::TooMany(switches.len()));
    }
    magnitude("the max step", max_step)?;
    magnitude("the max velocity step", max_velocity_step)?;
    for s in switches {
        magnitude("a switch's step", s.step)?;
        magnitude("a switch's velocity step", s.velocity_step)?;
    }
    out.reserve(HEADER_LEN + RECORD_LEN * switches.len());
    let header = Header {
        preamble: SwitchesError::FORMAT.preamble(switches.len() as u16),
        max_step: F64::new(max_step),
        max_velocity_step: F64::new(max_velocity_step),
    };
    out.extend_from_slice(header.as_bytes());
    for s in switches {
        let record = Record {
            generation: U16::new(s.generation),
            reserved: [0; 6],
            tick: U64::new(s.tick),
            missed_near: U64::new(s.missed_near),
            step: F64::new(s.step),
            velocity_step: F64::new(s.velocity_step),
        };
        out.extend_from_slice(record.as_bytes());
    }
    Ok(())
}

/// Reads a record written by [`encode`].
pub fn decode(bytes: &[u8]) -> Result<Switches, SwitchesError> {
    let (header, rest, count) = SwitchesError::FORMAT.read::<Header>(bytes)?;
    let records =
        <[Record]>::ref_from_bytes_with_elems(rest, count).map_err(|_| SwitchesError::Count {
            count,
            expected: HEADER_LEN + RECORD_LEN * count,
            len: bytes.len(),
        })?;
    let switches = records
        .iter()
        .map(|r| {
            Ok(Switch {
                generation: r.generation.get(),
                tick: r.tick.get(),
                step: magnitude("a switch's step", r.step.get())?,
                velocity_step: magnitude("a switch's velocity step", r.velocity_step.get())?,
                missed_near: r.missed_near.get(),
            })
        })
        .collect::<Result<Vec<_>, SwitchesError>>()?;
    Ok(Switches {
        max_step: magnitude("the max step", header.max_step.get())?,
        max_velocity_step: magnitude("the max velocity step", header.max_velocity_step.get())?,
        switches,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    fn example() -> Switches {
        Switches {
            max_step: 0.001,
            max_velocity_step: 4.0,
            switches: vec![Switch {
                generation: 2,
                tick: 5114,
                step: 0.5,
                velocity_step: 2.0,
                missed_near: 1,
            }],
        }
    }

    fn encoded(s: &Switches) -> Vec<u8> {
        let mut out = Vec::new();
        encode(s.max_step, s.max_velocity_step, &s.switches, &mut out).unwrap();
        out
    }

    #[test]
    fn a_record_has_the_documented_layout_and_reads_back() {
        let bytes = encoded(&example());
        assert_eq!(
            hex::encode(&bytes),
            concat!(
                "4d425357 01 00 0100", // magic, version, reserved, 1 switch
                "fca9f1d24d62503f",    // max step 0.001
                "0000000000001040",    // max velocity step 4
                "0200 000000000000",   // generation 2, reserved
                "fa13000000000000",    // tick 5114
                "0100000000000000",    // 1 cycle missed near it
                "000000000000e03f",    // step 0.5
                "0000000000000040",    // velocity step 2
            )
            .replace(' ', "")
        );
        assert_eq!(decode(&bytes), Ok(example()));
        assert_eq!(
            decode(&encoded(&Switches::default())),
            Ok(Switches::default())
        );
    }

    #[test]
    fn malformed_records_are_refused_with_the_reason() {
        let good = encoded(&example());
        assert_eq!(decode(&good[..10]), Err(SwitchesError::Size(10)));
        let mut bad = good.clone();
        bad[0] = b'X';
        assert!(matches!(decode(&bad), Err(SwitchesError::Magic(_))));
        let mut bad = good.clone();
        bad[4] = 2;
        assert_eq!(decode(&bad), Err(SwitchesError::Version(2)));
        let mut bad = good.clone();
        bad[6] = 2;
        assert!(matches!(
            decode(&bad),
            Err(SwitchesError::Count { count: 2, .. })
        ));
        let mut longer = good.clone();
        longer.push(0);
        assert!(matches!(
            decode(&longer),
            Err(SwitchesError::Count { count: 1, .. })
        ));
        let mut negative = good.clone();
        negative[HEADER_LEN + 31] = 0xbf; // step -0.5
        assert!(matches!(decode(&negative), Err(SwitchesError::Step { .. })));
        let mut nan = good.clone();
        nan[8..16].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(matches!(decode(&nan), Err(SwitchesError::Step { .. })));
        let mut reserved = good;
        reserved[5] = 0xaa;
        reserved[HEADER_LEN + 3] = 0xaa;
        assert_eq!(
            decode(&reserved),
            Ok(example()),
            "reserved bytes are ignored"
        );
    }

    #[test]
    fn writing_refuses_what_the_reader_would_refuse() {
        let mut out = Vec::new();
        assert!(encode(f64::NAN, 0.0, &[], &mut out).is_err());
        let many = vec![example().switches[0]; MAX_SWITCHES + 1];
        assert_eq!(
            encode(0.0, 0.0, &many, &mut out),
            Err(SwitchesError::TooMany(MAX_SWITCHES + 1))
        );
    }
}

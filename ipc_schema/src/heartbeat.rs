//! The heartbeat: a fixed 48-byte record every module publishes periodically, so that the
//! supervisor can tell a hung module (stopped, spinning in a handler) from a live one, and can
//! show each module's frame counters without calling it.
//!
//! ```text
//! offset size field
//!  0     4    magic "MBHB"
//!  4     1    version (1)
//!  5     1    module address
//!  6     1    state: 1 starting, 2 running, 3 stopping
//!  7     1    reserved, 0
//!  8     4    pid, u32 LE
//! 12     4    methods digest, u32 LE ([`crate::directory::methods_digest`] of its method
//!             names; 0: not given)
//! 16     8    beat number, u64 LE (starts at 1, +1 per beat)
//! 24     8    frames this module could not deliver (dropped), u64 LE
//! 32     8    malformed or misrouted frames it received and dropped (rejected), u64 LE
//! 40     8    retransmitted requests answered from its record (replayed), u64 LE
//! ```
//!
//! It is read in place: [`Heartbeat::parse`] checks the size, magic, version and state.

use thiserror::Error;
use zerocopy::byteorder::little_endian::{U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use crate::addr::Addr;

/// The heartbeat's first four bytes.
pub const MAGIC: [u8; 4] = *b"MBHB";
/// The format version this crate writes and reads.
pub const VERSION: u8 = 1;
/// The size of a heartbeat.
pub const LEN: usize = 48;

/// Where a module is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ModuleState {
    Starting = 1,
    Running = 2,
    Stopping = 3,
}

impl ModuleState {
    pub(crate) fn from_u8(b: u8) -> Option<ModuleState> {
        Some(match b {
            1 => ModuleState::Starting,
            2 => ModuleState::Running,
            3 => ModuleState::Stopping,
            _ => return None,
        })
    }
}

/// One heartbeat, as laid out on the wire.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Heartbeat {
    magic: [u8; 4],
    version: u8,
    addr: u8,
    state: u8,
    reserved0: u8,
    pid: U32,
    methods_digest: U32,
    beat: U64,
    dropped: U64,
    rejected: U64,
    replayed: U64,
}

/// Why bytes are not a heartbeat.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum HeartbeatError {
    #[error("a heartbeat is {LEN} bytes, got {0}")]
    Size(usize),
    #[error("not a heartbeat: magic {0:02x?}")]
    Magic([u8; 4]),
    #[error("heartbeat format version {0}, this build reads {VERSION}")]
    Version(u8),
    #[error("heartbeat with unknown state {0}")]
    State(u8),
}

/// The counters a heartbeat carries.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    pub dropped: u64,
    pub rejected: u64,
    pub replayed: u64,
}

impl Heartbeat {
    /// A heartbeat of module `addr` (process `pid`).
    pub fn new(
        addr: Addr,
        pid: u32,
        state: ModuleState,
        beat: u64,
        counters: Counters,
    ) -> Heartbeat {
        Heartbeat {
            magic: MAGIC,
            version: VERSION,
            addr: addr.0,
            state: state as u8,
            reserved0: 0,
            pid: U32::new(pid),
            methods_digest: U32::new(0),
            beat: U64::new(beat),
            dropped: U64::new(counters.dropped),
            rejected: U64::new(counters.rejected),
            replayed: U64::new(counters.replayed),
        }
    }

    /// Reads a heartbeat in place.
    pub fn parse(bytes: &[u8]) -> Result<&Heartbeat, HeartbeatError> {
        let hb = Heartbeat::ref_from_bytes(bytes).map_err(|_| HeartbeatError::Size(bytes.len()))?;
        if hb.magic != MAGIC {
            return Err(HeartbeatError::Magic(hb.magic));
        }
        if hb.version != VERSION {
            return Err(HeartbeatError::Version(hb.version));
        }
        ModuleState::from_u8(hb.state).ok_or(HeartbeatError::State(hb.state))?;
        Ok(hb)
    }

    pub fn addr(&self) -> Addr {
        Addr(self.addr)
    }

    pub fn pid(&self) -> u32 {
        self.pid.get()
    }

    pub fn state(&self) -> ModuleState {
        ModuleState::from_u8(self.state).unwrap_or(ModuleState::Running)
    }

    /// The same heartbeat, carrying the digest of the module's method names.
    pub fn with_methods_digest(mut self, digest: u32) -> Heartbeat {
        self.methods_digest = U32::new(digest);
        self
    }

    pub fn methods_digest(&self) -> u32 {
        self.methods_digest.get()
    }

    pub fn beat(&self) -> u64 {
        self.beat.get()
    }

    pub fn counters(&self) -> Counters {
        Counters {
            dropped: self.dropped.get(),
            rejected: self.rejected.get(),
            replayed: self.replayed.get(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    #[test]
    fn a_heartbeat_has_the_documented_layout() {
        let counters = Counters {
            dropped: 1,
            rejected: 2,
            replayed: 3,
        };
        let sut = Heartbeat::new(Addr(7), 0x1234, ModuleState::Running, 5, counters);
        assert_eq!(
            hex::encode(sut.as_bytes()),
            concat!(
                "4d424842",
                "01",
                "07",
                "02",
                "00",
                "34120000",
                "00000000",
                "0500000000000000",
                "0100000000000000",
                "0200000000000000",
                "0300000000000000"
            )
        );
        let back = Heartbeat::parse(sut.as_bytes()).unwrap();
        assert_eq!(
            (back.addr(), back.pid(), back.state(), back.beat()),
            (Addr(7), 0x1234, ModuleState::Running, 5)
        );
        assert_eq!(back.counters(), counters);
    }

    #[test]
    fn bytes_that_are_not_a_heartbeat_are_refused_with_the_reason() {
        let good = Heartbeat::new(Addr(1), 1, ModuleState::Starting, 1, Counters::default());
        assert_eq!(
            Heartbeat::parse(&good.as_bytes()[..47]).unwrap_err(),
            HeartbeatError::Size(47)
        );
        let mut bad = good.as_bytes().to_vec();
        bad[0] = b'X';
        assert!(matches!(
            Heartbeat::parse(&bad),
            Err(HeartbeatError::Magic(_))
        ));
        let mut bad = good.as_bytes().to_vec();
        bad[4] = 9;
        assert_eq!(
            Heartbeat::parse(&bad).unwrap_err(),
            HeartbeatError::Version(9)
        );
        let mut bad = good.as_bytes().to_vec();
        bad[6] = 0;
        assert_eq!(
            Heartbeat::parse(&bad).unwrap_err(),
            HeartbeatError::State(0)
        );
    }
}

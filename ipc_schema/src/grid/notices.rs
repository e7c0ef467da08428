//! The notices between the coordinator and the component hosts.
//!
//! # Batches
//! A release sample holds the release notices of one host for one tick back to back (160
//! bytes each; the warm-up releases come one per sample), and a done sample the done notices of
//! the releases a host served on one wake-up (40 bytes each): one wake-up and one sample per
//! host and tick each way, however many components it steps. [`Release::batch`] and
//! [`Done::batch`] read them in place; a sample whose length is not a whole number of notices
//! is malformed.
//!
//! # Release notice (coordinator → host, `grid.release.<host>`), 160 bytes
//! ```text
//!  0     8    tick: the release tick n
//!  8     8    when the coordinator released it, CLOCK_MONOTONIC ns
//! 16     2    component index (in the grid description's order)
//! 18     2    number of sources that follow (≤ 16)
//! 20     2    generation: the assembly whose components and outputs are meant (0: a grid
//!             without assemblies; for a component of the system, the assembly whose outputs
//!             its inputs read)
//! 22     2    flags: bit 0 TRACK (an assembly being prepared: its outputs are not obeyed yet,
//!             follow the current state), bit 1 SAFE_STOP (the assembly faulted: stop the
//!             drives and hold them), bit 2 HELD (with TRACK, for the running assembly: the
//!             robot is held — in safe stop, in fault or being brought back — and does not
//!             follow the assembly; its components track until it does again); the other
//!             bits 0
//! 24   8·16   versions: for each source component of the inputs (in the order the host was
//!             told at load), the valid_from of the outputs to read: LET says "as valid at n"
//! 152    8    the grid's state hash at n: the components' hashes of the versions valid at n,
//!             combined (`modbot_grid::state_hash`; 0 where the coordinator has none)
//! ```
//!
//! # Prepare notice (coordinator → the system's hosts, `grid.assembly`), 64 bytes
//! ```text
//!  0     2    generation of the assembly being prepared
//!  2     2    length of its name
//!  4    60    its name (UTF-8), zero-padded
//! ```
//! A host of the system's components (the bus) loads that assembly, subscribes to the outputs
//! its inputs will read, and answers with a done notice of component [`READY`] and the
//! generation (status 0, or 1 when it could not load it).
//!
//! # Done notice (host → coordinator, `grid.done`), 40 bytes
//! ```text
//!  0     8    tick: the release tick it answers
//!  8     2    component index
//! 10     2    status: 0 ok, 1 the step failed, 2 the component reports an unsafe state
//!             (a monitor's breach): its assembly faults, 3 stale: an input's version that
//!             the release names was not there (overwritten while the host was held up), so
//!             the release was not executed — LET is never served with another version
//! 12     2    generation, as in the release it answers
//! 14     2    flags: bit 0 HOLDING (the component holds the robot: its drives are stopped,
//!             faulted or being brought back and do not follow the running assembly, whose
//!             components the coordinator then releases to track), bit 1 HASHED (the
//!             state hash that follows is the component's); the other bits 0
//! 16     8    execution time of the step, ns
//! 24     8    release latency: from the coordinator's release to the step's start, ns
//! 32     8    the component's state hash after the step (with HASHED; 0 without)
//! ```

use thiserror::Error;
use zerocopy::byteorder::little_endian::{U16, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use super::{GridWireError, MAX_SOURCES, READY};

/// The size of a notice of type `T`, if `bytes` are one or more whole notices of it.
fn whole_notices<T>(bytes: &[u8]) -> Result<usize, GridWireError> {
    let each = core::mem::size_of::<T>();
    if bytes.is_empty() || !bytes.len().is_multiple_of(each) {
        return Err(GridWireError::Length {
            expected: each,
            got: bytes.len(),
        });
    }
    Ok(each)
}

/// A release notice.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Release {
    pub tick: U64,
    pub released_ns: U64,
    pub component: U16,
    pub sources: U16,
    pub generation: U16,
    pub flags: U16,
    pub versions: [U64; MAX_SOURCES],
    pub state_hash: U64,
}

impl Release {
    /// Flag: the component belongs to an assembly being prepared; nothing obeys its outputs
    /// yet, so it follows the current state (see `Component::track`).
    pub const TRACK: u16 = 1;
    /// Flag: the assembly faulted; the bus stops the drives and holds them.
    pub const SAFE_STOP: u16 = 2;
    /// Flag (with [`Release::TRACK`]): the running assembly's component is released to track
    /// because the robot is held (safe stop, drive fault, an operator's reset under way), not
    /// because its assembly is being prepared.
    pub const HELD: u16 = 4;

    pub fn new(
        tick: u64,
        released_ns: u64,
        component: u16,
        versions: &[u64],
    ) -> Result<Release, GridWireError> {
        if versions.len() > MAX_SOURCES {
            return Err(GridWireError::TooManySources(versions.len()));
        }
        let mut r = Release {
            tick: U64::new(tick),
            released_ns: U64::new(released_ns),
            component: U16::new(component),
            sources: U16::new(versions.len() as u16),
            generation: U16::new(0),
            flags: U16::new(0),
            versions: [U64::new(0); MAX_SOURCES],
            state_hash: U64::new(0),
        };
        for (slot, v) in r.versions.iter_mut().zip(versions) {
            *slot = U64::new(*v);
        }
        Ok(r)
    }

    /// The same notice for assembly `generation`, with `flags`.
    pub fn with(mut self, generation: u16, flags: u16) -> Release {
        self.generation = U16::new(generation);
        self.flags = U16::new(flags);
        self
    }

    /// The same notice carrying the grid's state hash at its tick.
    pub fn with_state_hash(mut self, hash: u64) -> Release {
        self.state_hash = U64::new(hash);
        self
    }

    pub fn has(&self, flag: u16) -> bool {
        self.flags.get() & flag != 0
    }

    /// Reads a notice in place.
    pub fn parse(bytes: &[u8]) -> Result<&Release, GridWireError> {
        let r = Release::ref_from_bytes(bytes).map_err(|_| GridWireError::Length {
            expected: core::mem::size_of::<Release>(),
            got: bytes.len(),
        })?;
        if usize::from(r.sources.get()) > MAX_SOURCES {
            return Err(GridWireError::TooManySources(usize::from(r.sources.get())));
        }
        Ok(r)
    }

    /// Reads a batch of notices in place (see the module doc): each notice, or why the batch
    /// is malformed.
    pub fn batch(bytes: &[u8]) -> Result<impl Iterator<Item = &Release>, GridWireError> {
        let each = whole_notices::<Release>(bytes)?;
        for chunk in bytes.chunks_exact(each) {
            Release::parse(chunk)?;
        }
        Ok(bytes
            .chunks_exact(each)
            .filter_map(|c| Release::parse(c).ok()))
    }

    /// The version to read of each source.
    pub fn versions(&self) -> impl Iterator<Item = u64> + '_ {
        self.versions[..usize::from(self.sources.get()).min(MAX_SOURCES)]
            .iter()
            .map(|v| v.get())
    }
}

/// A prepare notice.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Prepare {
    pub generation: U16,
    len: U16,
    name: [u8; PREPARE_NAME_MAX],
}

/// What is wrong with the name of a prepare notice.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum PrepareNameError {
    #[error("the name's length {0} is not 1..={PREPARE_NAME_MAX}")]
    Length(usize),
    #[error("the name is not UTF-8")]
    NotUtf8,
    #[error("the name's padding is not zero")]
    Padding,
}

/// The longest assembly name a prepare notice carries, in bytes.
pub const PREPARE_NAME_MAX: usize = 60;

impl Prepare {
    /// The notice for assembly `name` (1 to 60 bytes) as `generation`.
    pub fn new(generation: u16, name: &str) -> Result<Prepare, GridWireError> {
        let bytes = name.as_bytes();
        if !(1..=PREPARE_NAME_MAX).contains(&bytes.len()) {
            return Err(PrepareNameError::Length(bytes.len()).into());
        }
        let mut p = Prepare {
            generation: U16::new(generation),
            len: U16::new(bytes.len() as u16),
            name: [0; PREPARE_NAME_MAX],
        };
        p.name[..bytes.len()].copy_from_slice(bytes);
        Ok(p)
    }

    /// Reads a notice in place: exactly 64 bytes, a name of 1 to 60 bytes of UTF-8, zero
    /// padding after it.
    pub fn parse(bytes: &[u8]) -> Result<&Prepare, GridWireError> {
        let p = Prepare::ref_from_bytes(bytes).map_err(|_| GridWireError::Length {
            expected: core::mem::size_of::<Prepare>(),
            got: bytes.len(),
        })?;
        let len = usize::from(p.len.get());
        if !(1..=PREPARE_NAME_MAX).contains(&len) {
            return Err(PrepareNameError::Length(len).into());
        }
        if core::str::from_utf8(&p.name[..len]).is_err() {
            return Err(PrepareNameError::NotUtf8.into());
        }
        if p.name[len..].iter().any(|&b| b != 0) {
            return Err(PrepareNameError::Padding.into());
        }
        Ok(p)
    }

    /// The assembly's name: always `Some` for a notice that [`Prepare::parse`] or
    /// [`Prepare::new`] gave; `None` if the length or the bytes are not a name.
    pub fn name(&self) -> Option<&str> {
        let len = usize::from(self.len.get());
        core::str::from_utf8(self.name.get(..len)?).ok()
    }
}

/// A done notice.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Done {
    pub tick: U64,
    pub component: U16,
    pub status: U16,
    pub generation: U16,
    pub flags: U16,
    pub exec_ns: U64,
    pub latency_ns: U64,
    pub state_hash: U64,
}

impl Done {
    pub const OK: u16 = 0;
    pub const FAILED: u16 = 1;
    /// The component reports an unsafe state: its assembly faults.
    pub const UNSAFE: u16 = 2;
    /// A version the release names was not there: the release was not executed.
    pub const STALE: u16 = 3;
    /// Flag: the component holds the robot (its drives do not follow the running assembly).
    pub const HOLDING: u16 = 1;
    /// Flag: the notice carries the component's state hash after the step.
    pub const HASHED: u16 = 2;

    pub fn new(tick: u64, component: u16, status: u16, exec_ns: u64, latency_ns: u64) -> Done {
        Done {
            tick: U64::new(tick),
            component: U16::new(component),
            status: U16::new(status),
            generation: U16::new(0),
            flags: U16::new(0),
            exec_ns: U64::new(exec_ns),
            latency_ns: U64::new(latency_ns),
            state_hash: U64::new(0),
        }
    }

    /// The same notice for assembly `generation`.
    pub fn of_generation(mut self, generation: u16) -> Done {
        self.generation = U16::new(generation);
        self
    }

    /// The same notice with `flags` ([`Done::HOLDING`]).
    pub fn with_flags(mut self, flags: u16) -> Done {
        self.flags = U16::new(flags);
        self
    }

    /// The same notice with the component's state hash (flag [`Done::HASHED`]), or without
    /// one (`None`: the component contributes none).
    pub fn with_state_hash(mut self, hash: Option<u64>) -> Done {
        let flags = self.flags.get() & !Done::HASHED;
        match hash {
            Some(h) => {
                self.state_hash = U64::new(h);
                self.flags = U16::new(flags | Done::HASHED);
            }
            None => {
                self.state_hash = U64::new(0);
                self.flags = U16::new(flags);
            }
        }
        self
    }

    /// The component's state hash, if the notice carries one.
    pub fn hash(&self) -> Option<u64> {
        self.has(Done::HASHED).then(|| self.state_hash.get())
    }

    pub fn has(&self, flag: u16) -> bool {
        self.flags.get() & flag != 0
    }

    /// Reads a notice in place: exactly 40 bytes, and a status this format knows (0..=3; for a
    /// [`READY`] answer 0 ready or 1 could not load).
    pub fn parse(bytes: &[u8]) -> Result<&Done, GridWireError> {
        let d = Done::ref_from_bytes(bytes).map_err(|_| GridWireError::Length {
            expected: core::mem::size_of::<Done>(),
            got: bytes.len(),
        })?;
        let (component, status) = (d.component.get(), d.status.get());
        let highest = if component == READY {
            Done::FAILED
        } else {
            Done::STALE
        };
        if status > highest {
            return Err(GridWireError::UnknownStatus { component, status });
        }
        Ok(d)
    }

    /// Reads a batch of notices in place (see the module doc): each notice, or why the batch
    /// is malformed.
    pub fn batch(bytes: &[u8]) -> Result<impl Iterator<Item = &Done>, GridWireError> {
        let each = whole_notices::<Done>(bytes)?;
        for chunk in bytes.chunks_exact(each) {
            Done::parse(chunk)?;
        }
        Ok(bytes.chunks_exact(each).filter_map(|c| Done::parse(c).ok()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    #[test]
    fn notices_have_the_documented_sizes_and_read_back() {
        assert_eq!(core::mem::size_of::<Release>(), 160);
        assert_eq!(core::mem::size_of::<Done>(), 40);
        let r = Release::new(7, 99, 3, &[5, 6]).unwrap();
        let back = Release::parse(r.as_bytes()).unwrap();
        assert_eq!((back.tick.get(), back.component.get()), (7, 3));
        assert_eq!(back.versions().collect::<Vec<_>>(), vec![5, 6]);
        let d = Done::new(7, 3, Done::OK, 1200, 40);
        assert_eq!(
            hex::encode(d.as_bytes()),
            concat!(
                "0700000000000000",
                "0300",
                "0000",
                "00000000",
                "b004000000000000",
                "2800000000000000",
                "0000000000000000"
            )
        );
        assert_eq!(Done::parse(d.as_bytes()).unwrap().exec_ns.get(), 1200);
        assert!(Release::new(0, 0, 0, &[0; 17]).is_err());
    }

    #[test]
    fn a_release_of_an_assembly_carries_its_generation_and_flags_at_bytes_20_to_23() {
        let r = Release::new(7, 99, 3, &[5])
            .unwrap()
            .with(0x0102, Release::TRACK | Release::SAFE_STOP);
        assert_eq!(
            hex::encode(&r.as_bytes()[16..32]),
            "0300010002010300".to_owned() + "0500000000000000"
        );
        let back = Release::parse(r.as_bytes()).unwrap();
        assert!(back.has(Release::TRACK) && back.has(Release::SAFE_STOP));
        assert_eq!(back.generation.get(), 0x0102);
        let held = Release::new(7, 99, 3, &[])
            .unwrap()
            .with(1, Release::TRACK | Release::HELD);
        assert_eq!(hex::encode(&held.as_bytes()[20..24]), "01000500");
        let d = Done::new(7, 3, Done::UNSAFE, 0, 0).of_generation(5);
        assert_eq!(hex::encode(&d.as_bytes()[8..16]), "0300020005000000");
        let d = Done::new(7, 3, Done::STALE, 0, 0);
        assert_eq!(hex::encode(&d.as_bytes()[8..16]), "0300030000000000");
        let d = Done::new(7, 3, Done::OK, 0, 0).with_flags(Done::HOLDING);
        assert_eq!(hex::encode(&d.as_bytes()[8..16]), "0300000000000100");
        assert!(Done::parse(d.as_bytes()).unwrap().has(Done::HOLDING));
        let d = Done::new(7, 3, Done::OK, 0, 0)
            .with_flags(Done::HOLDING)
            .with_state_hash(Some(0x0123_4567_89ab_cdef));
        assert_eq!(
            hex::encode(&d.as_bytes()[14..16]),
            "0300",
            "HOLDING and HASHED"
        );
        assert_eq!(hex::encode(&d.as_bytes()[32..40]), "efcdab8967452301");
        let back = Done::parse(d.as_bytes()).unwrap();
        assert_eq!(back.hash(), Some(0x0123_4567_89ab_cdef));
        assert_eq!(back.with_state_hash(None).hash(), None);
        assert!(back.with_state_hash(None).has(Done::HOLDING));
        let r = Release::new(7, 99, 3, &[]).unwrap().with_state_hash(0x0102);
        assert_eq!(hex::encode(&r.as_bytes()[152..160]), "0201000000000000");
    }

    #[test]
    fn a_prepare_notice_names_the_assembly_and_refuses_a_bad_length() {
        let p = Prepare::new(3, "ptp").unwrap();
        assert_eq!(core::mem::size_of::<Prepare>(), 64);
        assert_eq!(hex::encode(&p.as_bytes()[..8]), "0300030070747000");
        let back = Prepare::parse(p.as_bytes()).unwrap();
        assert_eq!((back.generation.get(), back.name()), (3, Some("ptp")));
        let mut bad = *p.as_bytes().first_chunk::<64>().unwrap();
        bad[2] = 61;
        assert_eq!(
            Prepare::parse(&bad).unwrap_err(),
            GridWireError::PrepareName(PrepareNameError::Length(61))
        );
        assert!(Prepare::parse(&bad[..63]).is_err());
        assert!(Prepare::new(1, &"x".repeat(61)).is_err());
    }

    #[test]
    fn a_batch_is_notices_back_to_back_and_a_partial_one_is_refused() {
        let (a, b) = (
            Release::new(7, 99, 3, &[5]).unwrap(),
            Release::new(7, 99, 4, &[]).unwrap(),
        );
        let mut bytes = a.as_bytes().to_vec();
        bytes.extend_from_slice(b.as_bytes());
        let got: Vec<u16> = Release::batch(&bytes)
            .unwrap()
            .map(|r| r.component.get())
            .collect();
        assert_eq!(got, vec![3, 4]);
        assert!(Release::batch(&bytes[..200]).is_err());
        assert!(Release::batch(&[]).is_err());
        let mut bad = bytes.clone();
        bad[160 + 18] = 17; // 17 sources in the second notice
        assert!(Release::batch(&bad).is_err());
        let mut dones = Done::new(7, 3, Done::OK, 1, 2).as_bytes().to_vec();
        dones.extend_from_slice(Done::new(7, 4, Done::STALE, 0, 0).as_bytes());
        let got: Vec<(u16, u16)> = Done::batch(&dones)
            .unwrap()
            .map(|d| (d.component.get(), d.status.get()))
            .collect();
        assert_eq!(got, vec![(3, Done::OK), (4, Done::STALE)]);
        assert!(Done::batch(&dones[..41]).is_err());
    }
}

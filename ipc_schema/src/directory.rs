//! The published directory: the phone book a supervisor keeps for its domain, one fixed-size
//! image that every module reads in place when its generation changes (instead of scanning the
//! iceoryx2 node directory).
//!
//! ```text
//! header, 16 bytes
//! offset size field
//!  0     4    magic "MBDR"
//!  4     1    version (1)
//!  5     1    reserved, 0
//!  6     2    entries that follow, u16 LE (0..=254)
//!  8     8    generation, u64 LE (+1 per change; the image of generation 0 is empty)
//! then one 64-byte entry per module, in address order:
//!  0     1    address (1..=254, each at most once)
//!  1     1    receive mode: 'p' busy-poll, 'b' blocking
//!  2     1    state: 1 starting, 2 running, 3 stopping
//!  3     1    name length, 1..=48
//!  4     4    pid, u32 LE
//!  8     4    methods digest, u32 LE (see the heartbeat; 0: not known)
//! 12     2    upgrades, u16 LE: how often the module's process was replaced by a live upgrade
//! 14     2    reserved, 0
//! 16    48    name: a-z A-Z 0-9 _ -, zero-padded
//! ```
//!
//! The image always has room for 254 entries ([`IMAGE_LEN`] bytes); the bytes after the last
//! entry are written zero and not read. A module that is not in the image is not running.

use thiserror::Error;
use zerocopy::byteorder::little_endian::{U16, U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use crate::addr::Addr;
use crate::heartbeat::ModuleState;
use crate::names::is_module_name;
use crate::preamble::{Format, Headed, Preamble};

/// The image's first four bytes.
pub const MAGIC: [u8; 4] = *b"MBDR";
/// The format version this crate writes and reads.
pub const VERSION: u8 = 1;
/// The longest module name.
pub const NAME_MAX: usize = crate::names::MODULE_NAME_MAX;
/// The most entries an image holds: one per module address.
pub const MAX_ENTRIES: usize = 254;
/// Header size.
pub const HEADER_LEN: usize = 16;
/// Entry size.
pub const ENTRY_LEN: usize = 64;
/// The size of an image: the header and room for every address.
pub const IMAGE_LEN: usize = HEADER_LEN + ENTRY_LEN * MAX_ENTRIES;

/// An image as it is stored.
pub type Image = [u8; IMAGE_LEN];

/// The header, as laid out on the wire.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
struct Header {
    preamble: Preamble,
    generation: U64,
}

impl Headed for Header {
    fn preamble(&self) -> &Preamble {
        &self.preamble
    }
}

/// One module's entry, as laid out on the wire.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct Entry {
    addr: u8,
    mode: u8,
    state: u8,
    name_len: u8,
    pid: U32,
    methods_digest: U32,
    upgrades: U16,
    reserved: U16,
    name: [u8; NAME_MAX],
}

/// What one entry says, owned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Listing {
    pub addr: Addr,
    /// `b'p'` (busy-poll) or `b'b'` (blocking).
    pub mode: u8,
    pub state: ModuleState,
    pub pid: u32,
    pub methods_digest: u32,
    /// How often a live upgrade replaced the module's process (`modbot upgrade`): a new pid with
    /// a higher count is the same module, not a restart.
    pub upgrades: u16,
    pub name: String,
}

/// Why bytes are not a directory image.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DirectoryError {
    #[error("a directory image is at least {HEADER_LEN} bytes, got {0}")]
    Size(usize),
    #[error("not a directory image: magic {0:02x?}")]
    Magic([u8; 4]),
    #[error("directory format version {0}, this build reads {VERSION}")]
    Version(u8),
    #[error("directory of {count} entries does not fit in {len} bytes")]
    Count { count: usize, len: usize },
    #[error("directory entry {index}: {problem}")]
    Entry { index: usize, problem: EntryError },
    #[error("directory has no room for another module (254 entries)")]
    Full,
}

impl DirectoryError {
    /// The image's magic and version, and how a header that is not an image's is refused.
    const FORMAT: Format<Self> =
        Format::new(MAGIC, VERSION, Self::Size, Self::Magic, Self::Version);
}

/// What is wrong with one entry of an image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum EntryError {
    #[error("address {0} is not a module address (1..=254)")]
    Address(u8),
    #[error("address {addr} comes after address {after}: entries are in strictly increasing address order")]
    Order { addr: u8, after: u8 },
    #[error("receive mode {0:#04x} is neither 'p' nor 'b'")]
    Mode(u8),
    #[error("unknown state {0} (1 starting, 2 running, 3 stopping)")]
    State(u8),
    #[error("name length {0} is not 1..={NAME_MAX}")]
    NameLength(usize),
    #[error("the name has bytes other than a-z A-Z 0-9 _ -")]
    NameBytes,
    #[error("the name's padding is not zero")]
    NamePadding,
}

impl Entry {
    pub fn addr(&self) -> Addr {
        Addr(self.addr)
    }

    pub fn mode(&self) -> u8 {
        self.mode
    }

    pub fn state(&self) -> ModuleState {
        ModuleState::from_u8(self.state).unwrap_or(ModuleState::Running)
    }

    pub fn pid(&self) -> u32 {
        self.pid.get()
    }

    pub fn methods_digest(&self) -> u32 {
        self.methods_digest.get()
    }

    /// How often a live upgrade replaced the module's process.
    pub fn upgrades(&self) -> u16 {
        self.upgrades.get()
    }

    /// The name (checked by [`View::parse`]: ASCII).
    pub fn name(&self) -> &str {
        let len = usize::from(self.name_len).min(NAME_MAX);
        core::str::from_utf8(&self.name[..len]).unwrap_or("")
    }

    /// This entry, owned.
    pub fn listing(&self) -> Listing {
        Listing {
            addr: self.addr(),
            mode: self.mode,
            state: self.state(),
            pid: self.pid(),
            methods_digest: self.methods_digest(),
            upgrades: self.upgrades(),
            name: self.name().to_owned(),
        }
    }

    fn check(&self) -> Result<(), EntryError> {
        if !self.addr().is_module() {
            return Err(EntryError::Address(self.addr));
        }
        if !matches!(self.mode, b'p' | b'b') {
            return Err(EntryError::Mode(self.mode));
        }
        if ModuleState::from_u8(self.state).is_none() {
            return Err(EntryError::State(self.state));
        }
        let len = usize::from(self.name_len);
        if !(1..=NAME_MAX).contains(&len) {
            return Err(EntryError::NameLength(len));
        }
        if !is_module_name(&self.name[..len]) {
            return Err(EntryError::NameBytes);
        }
        if self.name[len..].iter().any(|&b| b != 0) {
            return Err(EntryError::NamePadding);
        }
        Ok(())
    }
}

/// A directory image read in place.
#[derive(Debug, Clone, Copy)]
pub struct View<'a> {
    generation: u64,
    entries: &'a [Entry],
}

impl<'a> View<'a> {
    /// Reads and checks an image: its header, and every entry (in strictly increasing address
    /// order, so no address appears twice).
    pub fn parse(bytes: &'a [u8]) -> Result<View<'a>, DirectoryError> {
        let (header, rest, count) = DirectoryError::FORMAT.read::<Header>(bytes)?;
        let too_many = DirectoryError::Count {
            count,
            len: bytes.len(),
        };
        if count > MAX_ENTRIES {
            return Err(too_many);
        }
        let (entries, _) =
            <[Entry]>::ref_from_prefix_with_elems(rest, count).map_err(|_| too_many)?;
        let mut last = 0u8;
        for (index, e) in entries.iter().enumerate() {
            e.check()
                .map_err(|problem| DirectoryError::Entry { index, problem })?;
            if e.addr <= last {
                return Err(DirectoryError::Entry {
                    index,
                    problem: EntryError::Order {
                        addr: e.addr,
                        after: last,
                    },
                });
            }
            last = e.addr;
        }
        Ok(View {
            generation: header.generation.get(),
            entries,
        })
    }

    pub fn generation(&self) -> u64 {
        self.generation
    }

    pub fn entries(&self) -> &'a [Entry] {
        self.entries
    }

    /// The entry of address `addr`.
    pub fn get(&self, addr: Addr) -> Option<&'a Entry> {
        self.entries
            .binary_search_by_key(&addr.0, |e| e.addr)
            .ok()
            .map(|i| &self.entries[i])
    }
}

/// Writes an image: entries are kept in address order, one per address.
pub fn write(
    image: &mut [u8],
    generation: u64,
    listings: &[Listing],
) -> Result<usize, DirectoryError> {
    if listings.len() > MAX_ENTRIES {
        return Err(DirectoryError::Full);
    }
    let len = HEADER_LEN + ENTRY_LEN * listings.len();
    if image.len() < len {
        return Err(DirectoryError::Count {
            count: listings.len(),
            len: image.len(),
        });
    }
    image.fill(0);
    let header = Header {
        preamble: DirectoryError::FORMAT.preamble(listings.len() as u16),
        generation: U64::new(generation),
    };
    image[..HEADER_LEN].copy_from_slice(header.as_bytes());
    let mut sorted: Vec<&Listing> = listings.iter().collect();
    sorted.sort_by_key(|l| l.addr);
    for (index, l) in sorted.into_iter().enumerate() {
        let bytes = l.name.as_bytes();
        if !(1..=NAME_MAX).contains(&bytes.len()) {
            let problem = EntryError::NameLength(bytes.len());
            return Err(DirectoryError::Entry { index, problem });
        }
        let mut name = [0u8; NAME_MAX];
        let n = bytes.len();
        name[..n].copy_from_slice(bytes);
        let entry = Entry {
            addr: l.addr.0,
            mode: l.mode,
            state: l.state as u8,
            name_len: n as u8,
            pid: U32::new(l.pid),
            methods_digest: U32::new(l.methods_digest),
            upgrades: U16::new(l.upgrades),
            reserved: U16::new(0),
            name,
        };
        entry
            .check()
            .map_err(|problem| DirectoryError::Entry { index, problem })?;
        let at = HEADER_LEN + ENTRY_LEN * index;
        image[at..at + ENTRY_LEN].copy_from_slice(entry.as_bytes());
    }
    // The reader's checks, among them one entry per address.
    View::parse(&image[..len])?;
    Ok(len)
}

/// The methods digest modules put in their heartbeat: FNV-1a (32 bits) of the method names
/// joined by commas, in id order; never 0 (0 means "not known").
pub fn methods_digest<'a>(names: impl IntoIterator<Item = &'a str>) -> u32 {
    let mut h: u32 = 0x811c_9dc5;
    let mut eat = |b: u8| {
        h ^= u32::from(b);
        h = h.wrapping_mul(0x0100_0193);
    };
    for (i, name) in names.into_iter().enumerate() {
        if i > 0 {
            eat(b',');
        }
        name.bytes().for_each(&mut eat);
    }
    h.max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    fn listing(addr: u8, name: &str) -> Listing {
        Listing {
            addr: Addr(addr),
            mode: b'b',
            state: ModuleState::Running,
            pid: 0x1234,
            methods_digest: 0xaabbccdd,
            upgrades: 0,
            name: name.into(),
        }
    }

    #[test]
    fn an_image_has_the_documented_layout() {
        let mut image = [0u8; IMAGE_LEN];
        let len = write(&mut image, 5, &[listing(7, "nav")]).unwrap();
        assert_eq!(len, 80);
        let mut expected = String::from(concat!(
            "4d424452",
            "01",
            "00",
            "0100",
            "0500000000000000", // header
            "07",
            "62",
            "02",
            "03",
            "34120000",
            "ddccbbaa",
            "00000000",
            "6e6176",
        ));
        expected.push_str(&"00".repeat(45));
        assert_eq!(hex::encode(&image[..len]), expected);
        assert!(image[len..].iter().all(|&b| b == 0));
        let view = View::parse(&image).unwrap();
        assert_eq!(view.generation(), 5);
        assert_eq!(view.entries()[0].listing(), listing(7, "nav"));
    }

    #[test]
    fn entries_come_out_in_address_order_and_are_found_by_address() {
        let mut image = [0u8; IMAGE_LEN];
        let all: Vec<Listing> = (1..=254u8)
            .rev()
            .map(|a| listing(a, &format!("m{a}")))
            .collect();
        write(&mut image, 1, &all).unwrap();
        let view = View::parse(&image).unwrap();
        assert_eq!(view.entries().len(), 254);
        assert!(view.entries().windows(2).all(|w| w[0].addr() < w[1].addr()));
        assert_eq!(view.get(Addr(200)).unwrap().name(), "m200");
        assert!(view.get(Addr(255)).is_none());
    }

    #[test]
    fn bytes_that_are_not_an_image_are_refused_with_the_reason() {
        let mut image = [0u8; IMAGE_LEN];
        write(&mut image, 1, &[listing(3, "a"), listing(4, "b")]).unwrap();
        assert_eq!(
            View::parse(&image[..10]).unwrap_err(),
            DirectoryError::Size(10)
        );
        let mut bad = image;
        bad[0] = b'X';
        assert!(matches!(View::parse(&bad), Err(DirectoryError::Magic(_))));
        let mut bad = image;
        bad[4] = 2;
        assert_eq!(View::parse(&bad).unwrap_err(), DirectoryError::Version(2));
        let mut bad = image;
        bad[6] = 0xff;
        assert!(matches!(
            View::parse(&bad),
            Err(DirectoryError::Count { .. })
        ));
        assert!(matches!(
            View::parse(&image[..HEADER_LEN + ENTRY_LEN]),
            Err(DirectoryError::Count { .. })
        ));
        let mut bad = image;
        bad[HEADER_LEN + ENTRY_LEN] = 3; // second entry at the first one's address
        assert!(matches!(
            View::parse(&bad),
            Err(DirectoryError::Entry { index: 1, .. })
        ));
        let mut bad = image;
        bad[HEADER_LEN + 16] = b'/';
        assert!(matches!(
            View::parse(&bad),
            Err(DirectoryError::Entry { index: 0, .. })
        ));
        let mut bad = image;
        bad[HEADER_LEN + 1] = b'x';
        assert!(matches!(
            View::parse(&bad),
            Err(DirectoryError::Entry { index: 0, .. })
        ));
    }

    #[test]
    fn writing_refuses_what_the_reader_would_refuse() {
        let mut image = [0u8; IMAGE_LEN];
        assert!(write(&mut image, 1, &[listing(0, "zero")]).is_err());
        assert!(write(&mut image, 1, &[listing(3, "a"), listing(3, "b")]).is_err());
        assert!(write(&mut image, 1, &[listing(3, "a b")]).is_err());
    }

    #[test]
    fn the_methods_digest_depends_on_names_and_order_and_is_never_zero() {
        let a = methods_digest(["get", "set"]);
        assert_ne!(a, methods_digest(["set", "get"]));
        assert_ne!(a, methods_digest(["getset"]));
        assert_eq!(a, methods_digest(["get", "set"]));
        assert_ne!(methods_digest([]), 0);
    }
}

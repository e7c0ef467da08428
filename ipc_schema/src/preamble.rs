//! The eight bytes that the bus bridge's record of switches ([`crate::bus`]) and the directory
//! image ([`crate::directory`]) begin with, written and checked the same way for both:
//!
//! ```text
//! offset size field
//!  0     4    magic
//!  4     1    version
//!  5     1    reserved, 0 (ignored by readers)
//!  6     2    records that follow, u16 LE
//! ```

use zerocopy::byteorder::little_endian::U16;
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

/// The preamble, as laid out on the wire.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub(crate) struct Preamble {
    magic: [u8; 4],
    version: u8,
    reserved: u8,
    count: U16,
}

/// A header, as laid out on the wire, that begins with a [`Preamble`].
pub(crate) trait Headed: FromBytes + KnownLayout + Immutable {
    /// Its first eight bytes.
    fn preamble(&self) -> &Preamble;
}

/// A format whose header begins with a [`Preamble`]: its magic and version, and how its error
/// type `E` says that bytes are shorter than the header, or have another magic or version.
pub(crate) struct Format<E> {
    magic: [u8; 4],
    version: u8,
    size: fn(usize) -> E,
    other_magic: fn([u8; 4]) -> E,
    other_version: fn(u8) -> E,
}

impl<E> Format<E> {
    /// The format of `magic` and `version`; `size`, `other_magic` and `other_version` make its
    /// errors (from the length of the bytes, their magic, their version).
    pub(crate) const fn new(
        magic: [u8; 4],
        version: u8,
        size: fn(usize) -> E,
        other_magic: fn([u8; 4]) -> E,
        other_version: fn(u8) -> E,
    ) -> Format<E> {
        Format {
            magic,
            version,
            size,
            other_magic,
            other_version,
        }
    }

    /// The preamble of a header that `count` records follow.
    pub(crate) fn preamble(&self, count: u16) -> Preamble {
        Preamble {
            magic: self.magic,
            version: self.version,
            reserved: 0,
            count: U16::new(count),
        }
    }

    /// Reads the header `H` at the start of `bytes` in place and checks its magic and version;
    /// returns it, the bytes after it, and how many records its preamble says follow.
    pub(crate) fn read<'a, H: Headed>(
        &self,
        bytes: &'a [u8],
    ) -> Result<(&'a H, &'a [u8], usize), E> {
        let (header, rest) = H::ref_from_prefix(bytes).map_err(|_| (self.size)(bytes.len()))?;
        let preamble = header.preamble();
        if preamble.magic != self.magic {
            return Err((self.other_magic)(preamble.magic));
        }
        if preamble.version != self.version {
            return Err((self.other_version)(preamble.version));
        }
        Ok((header, rest, usize::from(preamble.count.get())))
    }
}

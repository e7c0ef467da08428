//! Blackboard snapshots: a module's whole blackboard at one instant, in one buffer.
//!
//! ```text
//! offset size  field
//! 0      4     magic "MBBB"
//! 4      2     format version (u16 LE) = 1
//! 6      1     module address
//! 7      1     flags (0)
//! 8      2     item count (u16 LE)
//! 10     2     reserved (0)
//! 12     4     total length of the snapshot in bytes (u32 LE)
//! 16     8     layout hash (u64 LE): FNV-1a 64 over every item's name, a 0 byte, its kind code
//! 24     8     sequence number (u64 LE), +1 per snapshot
//! 32     8     timestamp, ns of CLOCK_MONOTONIC (u64 LE)
//! 40     16*n  item table, sorted by name (byte order):
//!              name offset u32, name length u16, kind u8, flags u8 (bit 0: writable,
//!              bit 1: bulk), value offset u32, value length u32 (offsets from the start of
//!              the snapshot)
//! ...          names (1..=255 bytes of UTF-8) back to back in table order, then the values
//!              back to back in table order, except that a bulk item's value starts at the
//!              next offset that is a multiple of 64 (zero bytes before it); the total length
//!              ends where the last value ends
//! ```
//!
//! Values are little-endian: f64 and i64 8 bytes, bool 1 byte (0 or 1), text UTF-8, bytes raw,
//! f64 arrays 8 bytes per element. A reader finds items by name with a binary search and reads
//! them in place (alignment does not matter, except that a bulk item — an array of a plain
//! `bytemuck::Pod` type such as an image, a scan or a point cloud — can be viewed as `&[T]` in
//! place when the snapshot itself starts 64-byte aligned, as modbot's shared-memory samples
//! do). Kind codes are those of [`ValueKind`].
//!
//! A writer may write a snapshot into a buffer that holds its earlier one and then writes
//! only what changed ([`SnapshotLayout::update`]): a reader never sees the difference.
//!
//! Files: `layout.rs` the writer's side, `view.rs` the reader's.

mod layout;
mod view;

use thiserror::Error;
use zerocopy::byteorder::little_endian::{U16, U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use crate::value::ValueKind;

pub use layout::{ItemSpec, SnapshotLayout, Written};
pub use view::{Item, SnapshotView};

pub const MAGIC: [u8; 4] = *b"MBBB";
pub const VERSION: u16 = 1;
pub const HEADER_LEN: usize = 40;
pub const ENTRY_LEN: usize = 16;
/// Item flag: other modules may write this item.
pub const FLAG_WRITABLE: u8 = 1;
/// Item flag: bulk data, its value aligned to [`BULK_ALIGN`].
pub const FLAG_BULK: u8 = 2;
/// The alignment of a bulk item's value within the snapshot, and of the snapshot in a sample.
pub const BULK_ALIGN: usize = 64;
/// The longest item name, in bytes.
pub const NAME_MAX: usize = 255;

/// The snapshot header, read in place.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct SnapshotHeader {
    pub magic: [u8; 4],
    pub version: U16,
    pub addr: u8,
    pub flags: u8,
    pub item_count: U16,
    pub reserved: U16,
    pub total_len: U32,
    pub layout: U64,
    pub seq: U64,
    pub stamp_ns: U64,
}

/// One row of the item table.
#[derive(Debug, Clone, Copy, FromBytes, IntoBytes, KnownLayout, Immutable, Unaligned)]
#[repr(C)]
pub struct ItemEntry {
    pub name_off: U32,
    pub name_len: U16,
    pub kind: u8,
    pub flags: u8,
    pub val_off: U32,
    pub val_len: U32,
}

/// Why a buffer is not a snapshot this reader can use.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SnapshotError {
    #[error("snapshot truncated: {needed} bytes needed, {got} present")]
    Truncated { needed: usize, got: usize },
    #[error("not a blackboard snapshot (magic {0:02x?}, expected \"MBBB\")")]
    BadMagic([u8; 4]),
    #[error(
        "snapshot format version {found} is not supported (this reader knows version {supported})"
    )]
    UnsupportedVersion { found: u16, supported: u16 },
    #[error("snapshot layout {found:016x} differs from the expected {expected:016x}: the module's blackboard items changed")]
    LayoutMismatch { expected: u64, found: u64 },
    #[error("snapshot says it is {declared} bytes long, the buffer has {actual}")]
    LengthMismatch { declared: usize, actual: usize },
    #[error("item {index} points outside the snapshot")]
    ItemOutOfBounds { index: usize },
    #[error("item {index} has unknown kind code {code}")]
    BadItemKind { index: usize, code: u8 },
    #[error("item '{name}' is {kind} but has {len} value bytes")]
    BadItemSize {
        name: String,
        kind: ValueKind,
        len: usize,
    },
    #[error("bool item '{name}' holds {byte}, not 0 or 1")]
    BadBool { name: String, byte: u8 },
    #[error("text item '{name}' is not UTF-8")]
    BadText { name: String },
    #[error("item {index} is bulk but of kind {kind}: a bulk item is bytes")]
    BulkNotBytes { index: usize, kind: ValueKind },
    #[error("item {index}'s name is at offset {found}; names follow the item table back to back in table order, so it is at {expected}")]
    NameMisplaced {
        index: usize,
        expected: usize,
        found: usize,
    },
    #[error("item {index}'s value is at offset {found}; values follow the names back to back in table order (a bulk value at the next multiple of 64), so it is at {expected}")]
    ValueMisplaced {
        index: usize,
        expected: usize,
        found: usize,
    },
    #[error("snapshot says it is {declared} bytes long, its last value ends at {end}")]
    TrailingBytes { end: usize, declared: usize },
    #[error("item {index} has a name that is empty, longer than 255 bytes or not UTF-8")]
    BadName { index: usize },
    #[error("item {index} is out of order or a duplicate: items are sorted by name")]
    Unsorted { index: usize },
    #[error("layout hash {declared:016x} does not match the items ({computed:016x})")]
    HashMismatch { declared: u64, computed: u64 },
    #[error("no blackboard item named '{0}'")]
    UnknownItem(String),
    #[error("item '{name}' is {got}, not {expected}")]
    WrongKind {
        name: String,
        expected: ValueKind,
        got: ValueKind,
    },
    #[error("duplicate item name '{0}'")]
    DuplicateItem(String),
    #[error("item name '{0}' is empty or longer than 255 bytes")]
    BadItemName(String),
    #[error("too many items ({0}, at most 65535)")]
    TooManyItems(usize),
    #[error("value for item '{name}' is {got}, the layout says {expected}")]
    ValueKindMismatch {
        name: String,
        expected: ValueKind,
        got: ValueKind,
    },
    #[error("item '{0}' is not a bulk item")]
    NotBulk(String),
    #[error("bulk item '{name}' cannot be viewed as [{element}]: {why}")]
    BulkView {
        name: String,
        element: &'static str,
        why: &'static str,
    },
    #[error("output buffer too small: {needed} bytes needed, {available} available")]
    BufferTooSmall { needed: usize, available: usize },
}

#[cfg(test)]
mod tests;

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
//!              name offset u32, name length u16, kind u8, flags u8 (bit 0: writable),
//!              value offset u32, value length u32 (offsets from the start of the snapshot)
//! ...          names (UTF-8), then values
//! ```
//!
//! Values are little-endian: f64 and i64 8 bytes, bool 1 byte (0 or 1), text UTF-8, bytes raw,
//! f64 arrays 8 bytes per element. A reader finds items by name with a binary search and reads
//! them in place (alignment does not matter). Kind codes are those of [`ValueKind`].

use core::fmt;

use thiserror::Error;
use zerocopy::byteorder::little_endian::{U16, U32, U64};
use zerocopy::{FromBytes, Immutable, IntoBytes, KnownLayout, Unaligned};

use crate::addr::Addr;
use crate::value::{AsValue, F64s, Value, ValueKind};

pub const MAGIC: [u8; 4] = *b"MBBB";
pub const VERSION: u16 = 1;
pub const HEADER_LEN: usize = 40;
pub const ENTRY_LEN: usize = 16;
/// Item flag: other modules may write this item.
pub const FLAG_WRITABLE: u8 = 1;

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
    #[error("item {index} has a name that is not UTF-8, or empty")]
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
    #[error("output buffer too small: {needed} bytes needed, {available} available")]
    BufferTooSmall { needed: usize, available: usize },
}

/// FNV-1a 64 over names and kinds, in table order.
fn layout_hash<'n>(items: impl Iterator<Item = (&'n str, ValueKind)>) -> u64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let mut hash = OFFSET;
    let mut eat = |b: u8| hash = (hash ^ u64::from(b)).wrapping_mul(PRIME);
    for (name, kind) in items {
        name.bytes().for_each(&mut eat);
        eat(0);
        eat(kind as u8);
    }
    hash
}

fn value_len(v: &Value<'_>) -> usize {
    match v {
        Value::F64(_) | Value::I64(_) => 8,
        Value::Bool(_) => 1,
        Value::Text(s) => s.len(),
        Value::Bytes(b) => b.len(),
        Value::F64s(a) => a.as_le_bytes().len(),
    }
}

/// One item of a layout.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ItemSpec {
    pub name: String,
    pub kind: ValueKind,
    pub writable: bool,
}

/// The writer's side: the items of a blackboard, sorted, with their hash.
#[derive(Debug, Clone)]
pub struct SnapshotLayout {
    items: Vec<ItemSpec>,
    names_len: usize,
    hash: u64,
}

impl SnapshotLayout {
    /// A layout for `items` (any order; they are sorted by name).
    pub fn new(mut items: Vec<ItemSpec>) -> Result<SnapshotLayout, SnapshotError> {
        if items.len() > usize::from(u16::MAX) {
            return Err(SnapshotError::TooManyItems(items.len()));
        }
        items.sort_by(|a, b| a.name.as_bytes().cmp(b.name.as_bytes()));
        for (i, item) in items.iter().enumerate() {
            if item.name.is_empty() || item.name.len() > 255 {
                return Err(SnapshotError::BadItemName(item.name.clone()));
            }
            if i > 0 && items[i - 1].name == item.name {
                return Err(SnapshotError::DuplicateItem(item.name.clone()));
            }
        }
        let names_len = items.iter().map(|i| i.name.len()).sum();
        let hash = layout_hash(items.iter().map(|i| (i.name.as_str(), i.kind)));
        Ok(SnapshotLayout {
            items,
            names_len,
            hash,
        })
    }

    /// The items, in snapshot (name) order.
    pub fn items(&self) -> &[ItemSpec] {
        &self.items
    }

    /// The position of item `name` in [`SnapshotLayout::items`].
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.items
            .binary_search_by(|i| i.name.as_bytes().cmp(name.as_bytes()))
            .ok()
    }

    pub fn hash(&self) -> u64 {
        self.hash
    }

    /// The snapshot's size with `values` (one per item, in item order).
    pub fn encoded_len<V: AsValue>(&self, values: &[V]) -> usize {
        HEADER_LEN
            + ENTRY_LEN * self.items.len()
            + self.names_len
            + values
                .iter()
                .map(|v| value_len(&v.as_value()))
                .sum::<usize>()
    }

    /// Writes a snapshot with `values` (one per item, in item order) at the start of `out`.
    pub fn write<V: AsValue>(
        &self,
        out: &mut [u8],
        addr: Addr,
        seq: u64,
        stamp_ns: u64,
        values: &[V],
    ) -> Result<usize, SnapshotError> {
        let needed = self.encoded_len(values);
        if out.len() < needed {
            return Err(SnapshotError::BufferTooSmall {
                needed,
                available: out.len(),
            });
        }
        for (item, v) in self.items.iter().zip(values) {
            let v = v.as_value();
            if item.kind != v.kind() {
                return Err(SnapshotError::ValueKindMismatch {
                    name: item.name.clone(),
                    expected: item.kind,
                    got: v.kind(),
                });
            }
        }
        let header = SnapshotHeader {
            magic: MAGIC,
            version: U16::new(VERSION),
            addr: addr.0,
            flags: 0,
            item_count: U16::new(self.items.len() as u16),
            reserved: U16::new(0),
            total_len: U32::new(needed as u32),
            layout: U64::new(self.hash),
            seq: U64::new(seq),
            stamp_ns: U64::new(stamp_ns),
        };
        out[..HEADER_LEN].copy_from_slice(header.as_bytes());
        let mut name_at = HEADER_LEN + ENTRY_LEN * self.items.len();
        let mut val_at = name_at + self.names_len;
        for (i, (item, v)) in self.items.iter().zip(values).enumerate() {
            let v = &v.as_value();
            let vlen = value_len(v);
            let entry = ItemEntry {
                name_off: U32::new(name_at as u32),
                name_len: U16::new(item.name.len() as u16),
                kind: item.kind as u8,
                flags: if item.writable { FLAG_WRITABLE } else { 0 },
                val_off: U32::new(val_at as u32),
                val_len: U32::new(vlen as u32),
            };
            let e = HEADER_LEN + ENTRY_LEN * i;
            out[e..e + ENTRY_LEN].copy_from_slice(entry.as_bytes());
            out[name_at..name_at + item.name.len()].copy_from_slice(item.name.as_bytes());
            name_at += item.name.len();
            let dst = &mut out[val_at..val_at + vlen];
            match v {
                Value::F64(x) => dst.copy_from_slice(&x.to_le_bytes()),
                Value::I64(x) => dst.copy_from_slice(&x.to_le_bytes()),
                Value::Bool(x) => dst[0] = u8::from(*x),
                Value::Text(s) => dst.copy_from_slice(s.as_bytes()),
                Value::Bytes(b) => dst.copy_from_slice(b),
                Value::F64s(a) => dst.copy_from_slice(a.as_le_bytes()),
            }
            val_at += vlen;
        }
        Ok(needed)
    }
}

/// One item read from a snapshot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Item<'a> {
    pub name: &'a str,
    pub value: Value<'a>,
    pub writable: bool,
}

/// A snapshot read in place.
#[derive(Clone, Copy)]
pub struct SnapshotView<'a> {
    header: &'a SnapshotHeader,
    entries: &'a [ItemEntry],
    bytes: &'a [u8],
}

impl fmt::Debug for SnapshotView<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SnapshotView")
            .field("addr", &self.addr())
            .field("seq", &self.seq())
            .field("items", &self.iter().collect::<Vec<_>>())
            .finish()
    }
}

impl<'a> SnapshotView<'a> {
    /// Checks `bytes` and returns a view of it. Never panics on malformed input.
    pub fn parse(bytes: &'a [u8]) -> Result<SnapshotView<'a>, SnapshotError> {
        let (header, rest) =
            SnapshotHeader::ref_from_prefix(bytes).map_err(|_| SnapshotError::Truncated {
                needed: HEADER_LEN,
                got: bytes.len(),
            })?;
        if header.magic != MAGIC {
            return Err(SnapshotError::BadMagic(header.magic));
        }
        if header.version.get() != VERSION {
            return Err(SnapshotError::UnsupportedVersion {
                found: header.version.get(),
                supported: VERSION,
            });
        }
        let declared = header.total_len.get() as usize;
        if declared != bytes.len() {
            return Err(SnapshotError::LengthMismatch {
                declared,
                actual: bytes.len(),
            });
        }
        let count = usize::from(header.item_count.get());
        let (entries, _) =
            <[ItemEntry]>::ref_from_prefix_with_elems(rest, count).map_err(|_| {
                SnapshotError::Truncated {
                    needed: HEADER_LEN + ENTRY_LEN * count,
                    got: bytes.len(),
                }
            })?;
        let view = SnapshotView {
            header,
            entries,
            bytes,
        };
        let mut previous: Option<&str> = None;
        for index in 0..count {
            let (name, value, _) = view.entry(index)?;
            if previous.is_some_and(|p| p.as_bytes() >= name.as_bytes()) {
                return Err(SnapshotError::Unsorted { index });
            }
            previous = Some(name);
            let _ = value;
        }
        let computed = layout_hash((0..count).map(|i| {
            let (name, value, _) = view.entry(i).expect("checked above");
            (name, value.kind())
        }));
        if computed != header.layout.get() {
            return Err(SnapshotError::HashMismatch {
                declared: header.layout.get(),
                computed,
            });
        }
        Ok(view)
    }

    /// Parses and checks that the layout is `expected`.
    pub fn parse_expecting(
        bytes: &'a [u8],
        expected: u64,
    ) -> Result<SnapshotView<'a>, SnapshotError> {
        let view = Self::parse(bytes)?;
        if view.layout() != expected {
            return Err(SnapshotError::LayoutMismatch {
                expected,
                found: view.layout(),
            });
        }
        Ok(view)
    }

    fn entry(&self, index: usize) -> Result<(&'a str, Value<'a>, bool), SnapshotError> {
        let e = &self.entries[index];
        let slice = |off: U32, len: usize| {
            let start = off.get() as usize;
            start
                .checked_add(len)
                .and_then(|end| self.bytes.get(start..end))
                .ok_or(SnapshotError::ItemOutOfBounds { index })
        };
        let name = slice(e.name_off, usize::from(e.name_len.get()))?;
        let name = core::str::from_utf8(name)
            .ok()
            .filter(|n| !n.is_empty())
            .ok_or(SnapshotError::BadName { index })?;
        let kind = ValueKind::from_code(e.kind).ok_or(SnapshotError::BadItemKind {
            index,
            code: e.kind,
        })?;
        let raw = slice(e.val_off, e.val_len.get() as usize)?;
        let bad_size = || SnapshotError::BadItemSize {
            name: name.to_owned(),
            kind,
            len: raw.len(),
        };
        let eight = |raw: &[u8]| -> Result<[u8; 8], SnapshotError> {
            raw.try_into().map_err(|_| bad_size())
        };
        let value = match kind {
            ValueKind::F64 => Value::F64(f64::from_le_bytes(eight(raw)?)),
            ValueKind::I64 => Value::I64(i64::from_le_bytes(eight(raw)?)),
            ValueKind::Bool => match raw {
                [0] => Value::Bool(false),
                [1] => Value::Bool(true),
                _ => return Err(bad_size()),
            },
            ValueKind::Text => Value::Text(core::str::from_utf8(raw).map_err(|_| bad_size())?),
            ValueKind::Bytes => Value::Bytes(raw),
            ValueKind::F64s => Value::F64s(F64s::from_le_bytes(raw).ok_or_else(bad_size)?),
        };
        Ok((name, value, e.flags & FLAG_WRITABLE != 0))
    }

    pub fn addr(&self) -> Addr {
        Addr(self.header.addr)
    }

    pub fn layout(&self) -> u64 {
        self.header.layout.get()
    }

    pub fn seq(&self) -> u64 {
        self.header.seq.get()
    }

    pub fn stamp_ns(&self) -> u64 {
        self.header.stamp_ns.get()
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The item named `name`, found by binary search.
    pub fn get(&self, name: &str) -> Option<Item<'a>> {
        let (mut lo, mut hi) = (0, self.entries.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            let (n, value, writable) = self.entry(mid).ok()?;
            match n.as_bytes().cmp(name.as_bytes()) {
                core::cmp::Ordering::Less => lo = mid + 1,
                core::cmp::Ordering::Greater => hi = mid,
                core::cmp::Ordering::Equal => {
                    return Some(Item {
                        name: n,
                        value,
                        writable,
                    })
                }
            }
        }
        None
    }

    /// The item `name`, or an error naming it.
    pub fn value(&self, name: &str) -> Result<Value<'a>, SnapshotError> {
        self.get(name)
            .map(|i| i.value)
            .ok_or_else(|| SnapshotError::UnknownItem(name.to_owned()))
    }

    /// The f64 item `name`.
    pub fn f64(&self, name: &str) -> Result<f64, SnapshotError> {
        match self.value(name)? {
            Value::F64(v) => Ok(v),
            other => Err(SnapshotError::WrongKind {
                name: name.to_owned(),
                expected: ValueKind::F64,
                got: other.kind(),
            }),
        }
    }

    /// The bool item `name`.
    pub fn bool(&self, name: &str) -> Result<bool, SnapshotError> {
        match self.value(name)? {
            Value::Bool(v) => Ok(v),
            other => Err(SnapshotError::WrongKind {
                name: name.to_owned(),
                expected: ValueKind::Bool,
                got: other.kind(),
            }),
        }
    }

    /// Every item, in name order.
    pub fn iter(&self) -> impl Iterator<Item = Item<'a>> + '_ {
        (0..self.entries.len()).filter_map(|i| {
            self.entry(i).ok().map(|(name, value, writable)| Item {
                name,
                value,
                writable,
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hex;

    fn layout() -> SnapshotLayout {
        SnapshotLayout::new(vec![
            ItemSpec {
                name: "y".into(),
                kind: ValueKind::F64,
                writable: false,
            },
            ItemSpec {
                name: "moving".into(),
                kind: ValueKind::Bool,
                writable: false,
            },
            ItemSpec {
                name: "x".into(),
                kind: ValueKind::F64,
                writable: true,
            },
        ])
        .unwrap()
    }

    fn golden() -> Vec<u8> {
        let sut = layout();
        let values = [Value::Bool(true), Value::F64(1.5), Value::F64(-2.0)];
        let mut out = vec![0; sut.encoded_len(&values)];
        sut.write(&mut out, Addr(2), 7, 1000, &values).unwrap();
        out
    }

    #[test]
    fn a_snapshot_encodes_to_the_documented_golden_bytes() {
        let want = concat!(
            "4d424242",
            "0100",
            "02",
            "00",
            "0300",
            "0000",
            "71000000",
            "bba3101c6e56836a",
            "0700000000000000",
            "e803000000000000",
            "58000000",
            "0600",
            "03",
            "00",
            "60000000",
            "01000000",
            "5e000000",
            "0100",
            "01",
            "01",
            "61000000",
            "08000000",
            "5f000000",
            "0100",
            "01",
            "00",
            "69000000",
            "08000000",
            "6d6f76696e67",
            "78",
            "79",
            "01",
            "000000000000f83f",
            "00000000000000c0",
        );
        assert_eq!(hex::encode(&golden()), want);
    }

    #[test]
    fn a_reader_finds_items_by_name_in_place() {
        let bytes = golden();
        let sut = SnapshotView::parse_expecting(&bytes, layout().hash()).unwrap();
        assert_eq!((sut.addr(), sut.seq(), sut.stamp_ns()), (Addr(2), 7, 1000));
        assert_eq!(sut.f64("x").unwrap(), 1.5);
        assert_eq!(sut.f64("y").unwrap(), -2.0);
        assert!(sut.bool("moving").unwrap());
        assert!(sut.get("x").unwrap().writable);
        assert_eq!(
            sut.value("z").unwrap_err(),
            SnapshotError::UnknownItem("z".into())
        );
    }

    #[test]
    fn a_reader_rejects_a_wrong_version_or_layout() {
        let mut bytes = golden();
        assert!(matches!(
            SnapshotView::parse_expecting(&bytes, 1),
            Err(SnapshotError::LayoutMismatch { expected: 1, .. })
        ));
        bytes[4] = 2;
        assert_eq!(
            SnapshotView::parse(&bytes).unwrap_err(),
            SnapshotError::UnsupportedVersion {
                found: 2,
                supported: 1
            }
        );
    }
}

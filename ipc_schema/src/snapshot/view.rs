//! The reader's side of a snapshot: checked once, then read in place.

use core::fmt;

use zerocopy::byteorder::little_endian::U32;
use zerocopy::FromBytes;

use super::layout::layout_hash;
use super::{
    ItemEntry, SnapshotError, SnapshotHeader, BULK_ALIGN, ENTRY_LEN, FLAG_BULK, FLAG_WRITABLE,
    HEADER_LEN, MAGIC, NAME_MAX, VERSION,
};
use crate::addr::Addr;
use crate::value::{F64s, Value, ValueKind};

/// One item read from a snapshot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Item<'a> {
    pub name: &'a str,
    pub value: Value<'a>,
    pub writable: bool,
    /// A bulk item: see [`SnapshotView::bulk`].
    pub bulk: bool,
}

impl<'a> Item<'a> {
    fn new(name: &'a str, value: Value<'a>, flags: u8) -> Item<'a> {
        Item {
            name,
            value,
            writable: flags & FLAG_WRITABLE != 0,
            bulk: flags & FLAG_BULK != 0,
        }
    }
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
        let end = view.check_entries()?;
        if end != declared {
            return Err(SnapshotError::TrailingBytes { end, declared });
        }
        // Every entry was checked above: none is left out.
        let computed = layout_hash(
            (0..count).filter_map(|i| view.entry(i).ok().map(|(name, v, _)| (name, v.kind()))),
        );
        if computed != header.layout.get() {
            return Err(SnapshotError::HashMismatch {
                declared: header.layout.get(),
                computed,
            });
        }
        Ok(view)
    }

    /// Checks every entry: its kind, that a bulk item is bytes, that its name and value are
    /// where a writer puts them (names back to back after the table, values back to back after
    /// the names, a bulk value at the next multiple of [`BULK_ALIGN`]: so nothing overlaps and
    /// nothing is left between them but a bulk value's padding), that both lie in the buffer,
    /// that its value is well-formed, and that the names ascend. Returns where the last value
    /// ends.
    fn check_entries(&self) -> Result<usize, SnapshotError> {
        // At most 65535 names of at most 65535 bytes: no overflow in a usize of 64 bits, nor
        // in the offsets below (each a u32 plus a u32).
        let table_end = HEADER_LEN + ENTRY_LEN * self.entries.len();
        let names_len: usize = self
            .entries
            .iter()
            .map(|e| usize::from(e.name_len.get()))
            .sum();
        let (mut name_at, mut value_at) = (table_end, table_end + names_len);
        let mut previous: Option<&str> = None;
        for (index, e) in self.entries.iter().enumerate() {
            let kind = ValueKind::from_code(e.kind).ok_or(SnapshotError::BadItemKind {
                index,
                code: e.kind,
            })?;
            let bulk = e.flags & FLAG_BULK != 0;
            if bulk && kind != ValueKind::Bytes {
                return Err(SnapshotError::BulkNotBytes { index, kind });
            }
            let found = e.name_off.get() as usize;
            if found != name_at {
                return Err(SnapshotError::NameMisplaced {
                    index,
                    expected: name_at,
                    found,
                });
            }
            name_at += usize::from(e.name_len.get());
            let expected = if bulk {
                value_at.next_multiple_of(BULK_ALIGN)
            } else {
                value_at
            };
            let found = e.val_off.get() as usize;
            if found != expected {
                return Err(SnapshotError::ValueMisplaced {
                    index,
                    expected,
                    found,
                });
            }
            value_at = expected + e.val_len.get() as usize;
            let (name, _, _) = self.entry(index)?;
            if previous.is_some_and(|p| p.as_bytes() >= name.as_bytes()) {
                return Err(SnapshotError::Unsorted { index });
            }
            previous = Some(name);
        }
        Ok(value_at)
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

    fn entry(&self, index: usize) -> Result<(&'a str, Value<'a>, u8), SnapshotError> {
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
            .filter(|n| (1..=NAME_MAX).contains(&n.len()))
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
                [byte] => {
                    return Err(SnapshotError::BadBool {
                        name: name.to_owned(),
                        byte: *byte,
                    })
                }
                _ => return Err(bad_size()),
            },
            ValueKind::Text => {
                Value::Text(
                    core::str::from_utf8(raw).map_err(|_| SnapshotError::BadText {
                        name: name.to_owned(),
                    })?,
                )
            }
            ValueKind::Bytes => Value::Bytes(raw),
            ValueKind::F64s => Value::F64s(F64s::from_le_bytes(raw).ok_or_else(bad_size)?),
        };
        Ok((name, value, e.flags))
    }

    pub fn addr(&self) -> Addr {
        Addr(self.header.addr)
    }

    /// The whole snapshot as it was parsed (to pass it on: a bridge mirrors it elsewhere).
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
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
            let (n, value, flags) = self.entry(mid).ok()?;
            match n.as_bytes().cmp(name.as_bytes()) {
                core::cmp::Ordering::Less => lo = mid + 1,
                core::cmp::Ordering::Greater => hi = mid,
                core::cmp::Ordering::Equal => {
                    return Some(Item::new(n, value, flags));
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

    /// The bulk item `name` as a slice of `T`, in place: the item must be bulk, its length a
    /// multiple of `T`'s size and its value aligned for `T` (it is, in a snapshot that starts
    /// 64-byte aligned: every shared-memory sample does). `T` is the writer's contract, as a
    /// message type is: the snapshot records the bytes, not the element type.
    pub fn bulk<T: bytemuck::Pod>(&self, name: &str) -> Result<&'a [T], SnapshotError> {
        let item = self
            .get(name)
            .ok_or_else(|| SnapshotError::UnknownItem(name.to_owned()))?;
        let bytes = match (item.bulk, item.value) {
            (true, Value::Bytes(b)) => b,
            _ => return Err(SnapshotError::NotBulk(name.to_owned())),
        };
        bytemuck::try_cast_slice(bytes).map_err(|e| SnapshotError::BulkView {
            name: name.to_owned(),
            element: core::any::type_name::<T>(),
            why: match e {
                bytemuck::PodCastError::TargetAlignmentGreaterAndInputNotAligned => {
                    "its value is not aligned for it (the snapshot does not start 64-byte aligned)"
                }
                _ => "its length is not a multiple of the element's size",
            },
        })
    }

    /// Every item, in name order.
    pub fn iter(&self) -> impl Iterator<Item = Item<'a>> + '_ {
        (0..self.entries.len()).filter_map(|i| {
            self.entry(i)
                .ok()
                .map(|(name, value, flags)| Item::new(name, value, flags))
        })
    }
}

//! The writer's side of a snapshot: the items of a blackboard in table order, where each value
//! goes, and writing a snapshot whole or only the items that changed since the one already in
//! the buffer.

use zerocopy::byteorder::little_endian::{U16, U32, U64};
use zerocopy::{FromBytes, IntoBytes};

use super::{
    ItemEntry, SnapshotError, SnapshotHeader, BULK_ALIGN, ENTRY_LEN, FLAG_BULK, FLAG_WRITABLE,
    HEADER_LEN, MAGIC, NAME_MAX, VERSION,
};
use crate::addr::Addr;
use crate::value::{AsValue, Value, ValueKind};

/// FNV-1a 64 over names and kinds, in table order.
pub(super) fn layout_hash<'n>(items: impl Iterator<Item = (&'n str, ValueKind)>) -> u64 {
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

/// Whose snapshot it is and which: what a header says besides the layout's own fields.
#[derive(Debug, Clone, Copy)]
struct Stamp {
    addr: Addr,
    seq: u64,
    stamp_ns: u64,
}

impl Stamp {
    /// Snapshot `seq` of `addr`, taken at `stamp_ns`.
    fn new(addr: Addr, seq: u64, stamp_ns: u64) -> Stamp {
        Stamp {
            addr,
            seq,
            stamp_ns,
        }
    }
}

/// One item of a layout.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ItemSpec {
    pub name: String,
    pub kind: ValueKind,
    pub writable: bool,
    /// Bulk data (an array of a `bytemuck::Pod` type, kind bytes): its value starts at an
    /// offset aligned to [`BULK_ALIGN`], so a reader can view it as `&[T]` in place.
    pub bulk: bool,
}

impl ItemSpec {
    /// A plain item.
    pub fn new(name: &str, kind: ValueKind, writable: bool) -> ItemSpec {
        ItemSpec {
            name: name.to_owned(),
            kind,
            writable,
            bulk: false,
        }
    }

    /// A bulk item (kind bytes, aligned value).
    pub fn bulk(name: &str, writable: bool) -> ItemSpec {
        ItemSpec {
            bulk: true,
            ..ItemSpec::new(name, ValueKind::Bytes, writable)
        }
    }
}

/// How a snapshot was written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Written {
    /// Header, item table, names and every value: `len` bytes.
    Whole { len: usize },
    /// The buffer held this layout's earlier snapshot with every value of the same length:
    /// only the header and the `items` values that changed since were written.
    Changed { items: usize },
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
            if item.name.is_empty() || item.name.len() > NAME_MAX {
                return Err(SnapshotError::BadItemName(item.name.clone()));
            }
            if i > 0 && items[i - 1].name == item.name {
                return Err(SnapshotError::DuplicateItem(item.name.clone()));
            }
            if item.bulk && item.kind != ValueKind::Bytes {
                return Err(SnapshotError::WrongKind {
                    name: item.name.clone(),
                    expected: ValueKind::Bytes,
                    got: item.kind,
                });
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

    /// Where the values begin: after the header, the item table and the names.
    fn values_at(&self) -> usize {
        HEADER_LEN + ENTRY_LEN * self.items.len() + self.names_len
    }

    /// Where the value of the next item goes, after `at`.
    fn place(item: &ItemSpec, at: usize) -> usize {
        if item.bulk {
            at.next_multiple_of(BULK_ALIGN)
        } else {
            at
        }
    }

    /// The snapshot's size with `values` (one per item, in item order).
    pub fn encoded_len<V: AsValue>(&self, values: &[V]) -> usize {
        self.items
            .iter()
            .zip(values)
            .fold(self.values_at(), |at, (item, v)| {
                Self::place(item, at) + value_len(&v.as_value())
            })
    }

    /// Checks that `out` can hold the snapshot of `values` and that each value has its item's
    /// kind; returns the snapshot's length.
    fn check<V: AsValue>(&self, out: &[u8], values: &[V]) -> Result<usize, SnapshotError> {
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
        Ok(needed)
    }

    fn header(&self, stamp: Stamp, len: usize) -> SnapshotHeader {
        SnapshotHeader {
            magic: MAGIC,
            version: U16::new(VERSION),
            addr: stamp.addr.0,
            flags: 0,
            item_count: U16::new(self.items.len() as u16),
            reserved: U16::new(0),
            total_len: U32::new(len as u32),
            layout: U64::new(self.hash),
            seq: U64::new(stamp.seq),
            stamp_ns: U64::new(stamp.stamp_ns),
        }
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
        let needed = self.check(out, values)?;
        let stamp = Stamp::new(addr, seq, stamp_ns);
        self.write_checked(out, stamp, values, needed);
        Ok(needed)
    }

    /// [`SnapshotLayout::write`] once `out` and `values` were checked: `needed` bytes.
    fn write_checked<V: AsValue>(&self, out: &mut [u8], stamp: Stamp, values: &[V], needed: usize) {
        out[..HEADER_LEN].copy_from_slice(self.header(stamp, needed).as_bytes());
        let mut name_at = HEADER_LEN + ENTRY_LEN * self.items.len();
        let mut val_at = self.values_at();
        for (i, (item, v)) in self.items.iter().zip(values).enumerate() {
            let v = &v.as_value();
            let start = Self::place(item, val_at);
            out[val_at..start].fill(0);
            let vlen = value_len(v);
            let flags = if item.writable { FLAG_WRITABLE } else { 0 }
                | if item.bulk { FLAG_BULK } else { 0 };
            let entry = ItemEntry {
                name_off: U32::new(name_at as u32),
                name_len: U16::new(item.name.len() as u16),
                kind: item.kind as u8,
                flags,
                val_off: U32::new(start as u32),
                val_len: U32::new(vlen as u32),
            };
            let e = HEADER_LEN + ENTRY_LEN * i;
            out[e..e + ENTRY_LEN].copy_from_slice(entry.as_bytes());
            out[name_at..name_at + item.name.len()].copy_from_slice(item.name.as_bytes());
            name_at += item.name.len();
            put_value(&mut out[start..start + vlen], v);
            val_at = start + vlen;
        }
    }

    /// Writes the snapshot `seq` of `values` into `out`, which may still hold an earlier
    /// snapshot: when `earlier` names the sequence number and stamp that the caller wrote into
    /// this very buffer, and the buffer still holds that snapshot of this layout (same
    /// address, every value of the same length), only the header and the values of the items
    /// with `written_at[i] > earlier seq` are written — `written_at[i]` is the first snapshot
    /// that carries item `i`'s current value. Otherwise the whole snapshot is written.
    ///
    /// What the buffer holds only decides how much is written, never where: every offset comes
    /// from this layout and `values`, so a buffer with any content is safe to pass.
    #[allow(clippy::too_many_arguments)]
    pub fn update<V: AsValue>(
        &self,
        out: &mut [u8],
        addr: Addr,
        seq: u64,
        stamp_ns: u64,
        values: &[V],
        written_at: &[u64],
        earlier: Option<(u64, u64)>,
    ) -> Result<Written, SnapshotError> {
        let needed = self.check(out, values)?;
        let reusable = earlier.is_some_and(|(earlier_seq, earlier_stamp)| {
            let earlier = Stamp::new(addr, earlier_seq, earlier_stamp);
            written_at.len() == self.items.len() && self.holds(out, earlier, needed, values)
        });
        let stamp = Stamp::new(addr, seq, stamp_ns);
        let Some((earlier_seq, _)) = earlier.filter(|_| reusable) else {
            self.write_checked(out, stamp, values, needed);
            return Ok(Written::Whole { len: needed });
        };
        out[..HEADER_LEN].copy_from_slice(self.header(stamp, needed).as_bytes());
        let mut val_at = self.values_at();
        let mut items = 0;
        for ((item, v), &at) in self.items.iter().zip(values).zip(written_at) {
            let v = &v.as_value();
            let start = Self::place(item, val_at);
            let vlen = value_len(v);
            if at > earlier_seq {
                put_value(&mut out[start..start + vlen], v);
                items += 1;
            }
            val_at = start + vlen;
        }
        Ok(Written::Changed { items })
    }

    /// Whether `out` holds this layout's snapshot `stamp`, `len` bytes, with each value as long
    /// as in `values`.
    fn holds<V: AsValue>(&self, out: &[u8], stamp: Stamp, len: usize, values: &[V]) -> bool {
        let Ok((header, rest)) = SnapshotHeader::ref_from_prefix(out) else {
            return false;
        };
        if *header.as_bytes() != *self.header(stamp, len).as_bytes() {
            return false;
        }
        let Ok((entries, _)) = <[ItemEntry]>::ref_from_prefix_with_elems(rest, self.items.len())
        else {
            return false;
        };
        entries
            .iter()
            .zip(values)
            .all(|(e, v)| e.val_len.get() as usize == value_len(&v.as_value()))
    }
}

/// Writes `v`'s bytes (little-endian) into `dst`, which is exactly as long.
fn put_value(dst: &mut [u8], v: &Value<'_>) {
    match v {
        Value::F64(x) => dst.copy_from_slice(&x.to_le_bytes()),
        Value::I64(x) => dst.copy_from_slice(&x.to_le_bytes()),
        Value::Bool(x) => dst[0] = u8::from(*x),
        Value::Text(s) => dst.copy_from_slice(s.as_bytes()),
        Value::Bytes(b) => dst.copy_from_slice(b),
        Value::F64s(a) => dst.copy_from_slice(a.as_le_bytes()),
    }
}

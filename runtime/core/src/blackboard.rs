//! The blackboard: a module's typed store of logical and virtual devices.
//!
//! Every item has a name and a fixed kind. A *logical device* attaches a read hook (sample the
//! sensor when the item is read) and a write hook (drive the actuator when it is written); a
//! *virtual device* is the same with hooks that simulate the hardware. Other modules read and
//! write items by message (the `bb_get`/`bb_set` system methods) and see the whole blackboard
//! through snapshots: one consistent instant in one shared-memory sample.
//!
//! A snapshot is written into the sample it goes out in, and only what changed is written:
//! a publisher's samples come back to it once every reader let go of them, still holding the
//! snapshot written into them then, so the blackboard remembers which of its snapshots went
//! into which sample and, when one comes back, writes the header and the items changed since
//! ([`SnapshotLayout::update`]). Publishing a 1 MiB blackboard whose one scalar changed costs
//! that scalar, not the megabyte.
//!
//! Bulk items ([`BlackboardBuilder::bulk_item`]) hold arrays of a `bytemuck::Pod` type
//! (images, scans, point clouds): readers view them as `&[T]` in the sample, in place
//! ([`modbot_ipc_schema::SnapshotView::bulk`]).

use modbot_ipc_schema::snapshot::{ItemSpec, Written};
use modbot_ipc_schema::{Addr, OwnedValue, SnapshotLayout, Value, ValueKind};
use thiserror::Error;

/// Samples a device into its item, when the item is read.
pub type ReadHook = Box<dyn FnMut(&mut OwnedValue) + Send>;
/// Drives a device from a new value; an error refuses the write (any error: a device's own,
/// or a message — `Err("above the maximum".into())`).
pub type WriteHook = Box<dyn FnMut(&OwnedValue) -> Result<(), DeviceError> + Send>;
/// Why a device refuses a write.
pub type DeviceError = Box<dyn std::error::Error + Send + Sync>;

/// Blackboard errors.
#[derive(Debug, Clone, Error)]
pub enum BlackboardError {
    #[error("no blackboard item named '{0}'")]
    UnknownItem(String),
    #[error("item '{name}' is {expected}, not {got}")]
    WrongKind {
        name: String,
        expected: ValueKind,
        got: ValueKind,
    },
    #[error("item '{0}' is read-only for other modules")]
    ReadOnly(String),
    #[error("device refused the write to '{name}': {reason}")]
    Refused {
        name: String,
        #[source]
        reason: std::sync::Arc<dyn std::error::Error + Send + Sync>,
    },
    #[error("invalid blackboard: {0}")]
    Layout(String),
    #[error(
        "bulk item '{name}' holds {expected} bytes; {got} were given (a bulk item keeps its size)"
    )]
    BulkLength {
        name: String,
        expected: usize,
        got: usize,
    },
}

/// A handle to an item, for writing it on a hot path without a name lookup.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ItemId(usize);

struct Device {
    read: Option<ReadHook>,
    write: Option<WriteHook>,
}

/// Declares the items of a blackboard.
#[derive(Default)]
pub struct BlackboardBuilder {
    items: Vec<(ItemSpec, OwnedValue, Device)>,
}

impl BlackboardBuilder {
    /// A plain item that only this module writes.
    pub fn item(self, name: &str, initial: OwnedValue) -> Self {
        self.device(name, initial, false, None, None)
    }

    /// An item other modules may write by message.
    pub fn writable_item(self, name: &str, initial: OwnedValue) -> Self {
        self.device(name, initial, true, None, None)
    }

    /// A logical or virtual device: an item with hooks.
    pub fn device(
        mut self,
        name: &str,
        initial: OwnedValue,
        writable: bool,
        read: Option<ReadHook>,
        write: Option<WriteHook>,
    ) -> Self {
        let spec = ItemSpec::new(name, initial.kind(), writable);
        self.items.push((spec, initial, Device { read, write }));
        self
    }

    /// A bulk item: `len` elements of `T` (zeroed), which readers view as `&[T]` in place.
    /// Written with [`Blackboard::write_bulk`]; its size stays `len` elements.
    pub fn bulk_item<T: bytemuck::Pod>(mut self, name: &str, len: usize) -> Self {
        let bytes = vec![0u8; len * core::mem::size_of::<T>()];
        let device = Device {
            read: None,
            write: None,
        };
        let spec = ItemSpec::bulk(name, false);
        self.items.push((spec, OwnedValue::Bytes(bytes), device));
        self
    }

    pub fn build(self) -> Result<Blackboard, BlackboardError> {
        let specs: Vec<ItemSpec> = self.items.iter().map(|(s, _, _)| s.clone()).collect();
        let layout =
            SnapshotLayout::new(specs).map_err(|e| BlackboardError::Layout(e.to_string()))?;
        let mut slots: Vec<Option<(OwnedValue, Device)>> =
            (0..self.items.len()).map(|_| None).collect();
        for (spec, value, device) in self.items {
            let i = layout
                .index_of(&spec.name)
                .expect("layout holds every item");
            slots[i] = Some((value, device));
        }
        let (values, devices) = slots
            .into_iter()
            .map(|s| s.expect("every slot filled"))
            .unzip();
        let written_at = vec![1; layout.items().len()];
        Ok(Blackboard {
            layout,
            values,
            devices,
            changed: true,
            seq: 0,
            written_at,
            samples: [SampleRecord::default(); SAMPLES_REMEMBERED],
            last_written: None,
        })
    }
}

/// A module's blackboard.
pub struct Blackboard {
    layout: SnapshotLayout,
    /// In layout (name) order, as in the snapshot.
    values: Vec<OwnedValue>,
    devices: Vec<Device>,
    /// Set by every write; a snapshot goes out when it is set.
    changed: bool,
    /// Sequence number of the last snapshot written.
    seq: u64,
    /// Per item: the first snapshot that carries its current value.
    written_at: Vec<u64>,
    /// The buffers the last snapshots went into, and which snapshot each got.
    samples: [SampleRecord; SAMPLES_REMEMBERED],
    /// How the last snapshot was written.
    last_written: Option<Written>,
}

/// How many sample buffers a blackboard remembers: a publisher with history 1 and a few
/// readers keeping 2 samples each cycles through fewer; with more, a buffer that comes back
/// unremembered is written whole (correct, only slower).
const SAMPLES_REMEMBERED: usize = 16;

/// A buffer a snapshot went into: its address, and the snapshot's sequence number and stamp.
#[derive(Debug, Clone, Copy, Default)]
struct SampleRecord {
    at: usize,
    seq: u64,
    stamp_ns: u64,
}

impl Blackboard {
    pub fn builder() -> BlackboardBuilder {
        BlackboardBuilder::default()
    }

    /// An empty blackboard.
    pub fn empty() -> Blackboard {
        Self::builder()
            .build()
            .expect("an empty blackboard is valid")
    }

    pub fn id(&self, name: &str) -> Result<ItemId, BlackboardError> {
        self.layout
            .index_of(name)
            .map(ItemId)
            .ok_or_else(|| BlackboardError::UnknownItem(name.to_owned()))
    }

    /// Reads an item, sampling its device first.
    pub fn read(&mut self, name: &str) -> Result<Value<'_>, BlackboardError> {
        let ItemId(i) = self.id(name)?;
        if let Some(hook) = self.devices[i].read.as_mut() {
            hook(&mut self.values[i]);
        }
        Ok(self.values[i].as_value())
    }

    /// The current value of an item, without sampling its device.
    pub fn peek(&self, id: ItemId) -> Value<'_> {
        self.values[id.0].as_value()
    }

    /// The f64 item `name` (without sampling), or 0 if it is no f64 item.
    pub fn f64(&self, name: &str) -> f64 {
        self.id(name)
            .ok()
            .and_then(|id| self.peek(id).as_f64())
            .unwrap_or(0.0)
    }

    /// Writes an item locally, driving its device.
    pub fn write(&mut self, name: &str, value: Value<'_>) -> Result<(), BlackboardError> {
        let id = self.id(name)?;
        self.write_id(id, value)
    }

    /// Writes an item by handle, driving its device. Scalars are written without allocating.
    pub fn write_id(&mut self, id: ItemId, value: Value<'_>) -> Result<(), BlackboardError> {
        let i = id.0;
        let spec = &self.layout.items()[i];
        let value = match (spec.kind, value) {
            (ValueKind::F64, Value::I64(v)) => Value::F64(v as f64),
            (_, v) => v,
        };
        if value.kind() != spec.kind {
            return Err(BlackboardError::WrongKind {
                name: spec.name.clone(),
                expected: spec.kind,
                got: value.kind(),
            });
        }
        let changed = self.values[i].as_value() != value;
        if let Some(hook) = self.devices[i].write.as_mut() {
            // The device sees the new value first; a refusal leaves the item as it was.
            let proposed = value.to_owned_value();
            hook(&proposed).map_err(|reason| BlackboardError::Refused {
                name: self.layout.items()[i].name.clone(),
                reason: reason.into(),
            })?;
            self.values[i] = proposed;
            self.mark(i, changed);
            return Ok(());
        }
        if spec.bulk {
            let (expected, got) = (self.values[i].as_value(), value);
            if let (Value::Bytes(have), Value::Bytes(new)) = (expected, got) {
                if have.len() != new.len() {
                    return Err(BlackboardError::BulkLength {
                        name: spec.name.clone(),
                        expected: have.len(),
                        got: new.len(),
                    });
                }
            }
        }
        let slot = &mut self.values[i];
        match (&mut *slot, value) {
            (OwnedValue::F64(x), Value::F64(v)) => *x = v,
            (OwnedValue::I64(x), Value::I64(v)) => *x = v,
            (OwnedValue::Bool(x), Value::Bool(v)) => *x = v,
            (OwnedValue::Text(x), Value::Text(v)) => v.clone_into(x),
            (OwnedValue::Bytes(x), Value::Bytes(v)) => v.clone_into(x),
            (OwnedValue::F64s(x), Value::F64s(v)) => {
                x.clear();
                x.extend(v.iter());
            }
            (slot, v) => *slot = v.to_owned_value(),
        }
        self.mark(i, changed);
        Ok(())
    }

    /// Writes the bulk item `id` from `elements` (as many as it holds), without allocating.
    pub fn write_bulk<T: bytemuck::Pod>(
        &mut self,
        id: ItemId,
        elements: &[T],
    ) -> Result<(), BlackboardError> {
        let spec = &self.layout.items()[id.0];
        let (OwnedValue::Bytes(have), true) = (&mut self.values[id.0], spec.bulk) else {
            return Err(BlackboardError::WrongKind {
                name: spec.name.clone(),
                expected: ValueKind::Bytes,
                got: self.values[id.0].kind(),
            });
        };
        let new: &[u8] = bytemuck::cast_slice(elements);
        if have.len() != new.len() {
            return Err(BlackboardError::BulkLength {
                name: spec.name.clone(),
                expected: have.len(),
                got: new.len(),
            });
        }
        have.copy_from_slice(new);
        self.mark(id.0, true);
        Ok(())
    }

    /// Item `i` was written: when its value `changed`, the next snapshot carries it.
    fn mark(&mut self, i: usize, changed: bool) {
        if changed {
            self.changed = true;
            self.written_at[i] = self.seq + 1;
        }
    }

    /// Writes an f64 item by handle.
    pub fn set_f64(&mut self, id: ItemId, v: f64) {
        let _ = self.write_id(id, Value::F64(v));
    }

    /// Writes a bool item by handle.
    pub fn set_bool(&mut self, id: ItemId, v: bool) {
        let _ = self.write_id(id, Value::Bool(v));
    }

    /// A write from another module: allowed only on writable items.
    pub fn write_remote(&mut self, name: &str, value: Value<'_>) -> Result<(), BlackboardError> {
        let id = self.id(name)?;
        if !self.layout.items()[id.0].writable {
            return Err(BlackboardError::ReadOnly(name.to_owned()));
        }
        self.write_id(id, value)
    }

    /// Every item's name and current value (devices not sampled), in layout order.
    pub fn values(&self) -> impl Iterator<Item = (&str, Value<'_>)> + '_ {
        self.layout
            .items()
            .iter()
            .zip(&self.values)
            .map(|(spec, v)| (spec.name.as_str(), v.as_value()))
    }

    /// Takes over the value the process of a live upgrade replaced had for `name`: written as
    /// [`Blackboard::write`] does (an output device is driven with it, so it holds what it
    /// held); an item its input device samples keeps its own.
    pub fn restore(&mut self, name: &str, value: Value<'_>) -> Result<(), BlackboardError> {
        let id = self.id(name)?;
        if self.devices[id.0].read.is_some() {
            return Ok(());
        }
        self.write_id(id, value)
    }

    /// `name:kind[:rw]` for every item, comma-separated (for `describe`).
    pub fn describe(&self) -> String {
        self.layout
            .items()
            .iter()
            .map(|i| {
                format!(
                    "{}:{}{}",
                    i.name,
                    i.kind,
                    if i.writable { ":rw" } else { "" }
                )
            })
            .collect::<Vec<_>>()
            .join(",")
    }

    pub fn layout(&self) -> &SnapshotLayout {
        &self.layout
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Whether anything changed since the last snapshot.
    pub fn changed(&self) -> bool {
        self.changed
    }

    /// Samples every device (before a snapshot at a set rate).
    pub fn sample_devices(&mut self) {
        for (i, (value, device)) in self.values.iter_mut().zip(&mut self.devices).enumerate() {
            if let Some(hook) = device.read.as_mut() {
                let before = value.clone();
                hook(value);
                if *value != before {
                    self.changed = true;
                    self.written_at[i] = self.seq + 1;
                }
            }
        }
    }

    /// The size of the next snapshot.
    pub fn snapshot_len(&self) -> usize {
        self.layout.encoded_len(&self.values)
    }

    /// Writes a snapshot into `out` (shared memory), and clears the changed flag. When `out`
    /// is a buffer an earlier snapshot of this blackboard went into, only what changed since
    /// is written.
    pub fn write_snapshot(&mut self, out: &mut [u8], addr: Addr, stamp_ns: u64) {
        self.seq += 1;
        let at = out.as_ptr() as usize;
        let slot = self
            .samples
            .iter()
            .position(|r| r.at == at && r.seq != 0)
            .unwrap_or_else(|| {
                // The buffer given the oldest snapshot is the one forgotten.
                (0..SAMPLES_REMEMBERED)
                    .min_by_key(|&i| self.samples[i].seq)
                    .expect("SAMPLES_REMEMBERED > 0")
            });
        let record = self.samples[slot];
        let earlier = (record.at == at && record.seq != 0).then_some((record.seq, record.stamp_ns));
        let written = self.layout.update(
            out,
            addr,
            self.seq,
            stamp_ns,
            &self.values,
            &self.written_at,
            earlier,
        );
        match written {
            Ok(w) => {
                self.last_written = Some(w);
                self.samples[slot] = SampleRecord {
                    at,
                    seq: self.seq,
                    stamp_ns,
                };
            }
            Err(e) => {
                tracing::error!("snapshot not written: {e}");
                self.samples[slot] = SampleRecord::default();
            }
        }
        self.changed = false;
    }

    /// How the last snapshot was written: whole, or only the items changed since the one in
    /// its buffer.
    pub fn last_written(&self) -> Option<Written> {
        self.last_written
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_ipc_schema::SnapshotView;
    use std::sync::atomic::{AtomicU32, Ordering};
    use std::sync::Arc;

    #[test]
    fn a_logical_device_is_sampled_on_read_and_driven_on_write() {
        let samples = Arc::new(AtomicU32::new(0));
        let driven = Arc::new(AtomicU32::new(0));
        let (s, d) = (samples.clone(), driven.clone());
        let mut sut = Blackboard::builder()
            .device(
                "temp",
                OwnedValue::F64(0.0),
                true,
                Some(Box::new(move |v| {
                    *v = OwnedValue::F64(20.0 + f64::from(s.fetch_add(1, Ordering::SeqCst)))
                })),
                Some(Box::new(move |_| {
                    d.fetch_add(1, Ordering::SeqCst);
                    Ok(())
                })),
            )
            .item("x", OwnedValue::F64(1.0))
            .build()
            .unwrap();
        assert_eq!(sut.read("temp").unwrap(), Value::F64(20.0));
        assert_eq!(sut.read("temp").unwrap(), Value::F64(21.0));
        sut.write_remote("temp", Value::I64(5)).unwrap();
        assert_eq!(driven.load(Ordering::SeqCst), 1);
        assert!(matches!(
            sut.write_remote("x", Value::F64(2.0)),
            Err(BlackboardError::ReadOnly(name)) if name == "x"
        ));
        assert!(matches!(
            sut.write("x", Value::Bool(true)),
            Err(BlackboardError::WrongKind { .. })
        ));
    }

    #[test]
    fn a_snapshot_holds_every_item_at_one_instant() {
        let mut sut = Blackboard::builder()
            .item("x", OwnedValue::F64(1.0))
            .item("moving", OwnedValue::Bool(false))
            .build()
            .unwrap();
        let x = sut.id("x").unwrap();
        sut.set_f64(x, 2.5);
        let mut buf = vec![0; sut.snapshot_len()];
        sut.write_snapshot(&mut buf, Addr(2), 9);
        assert!(!sut.changed());
        let view = SnapshotView::parse_expecting(&buf, sut.layout().hash()).unwrap();
        assert_eq!(view.f64("x").unwrap(), 2.5);
        assert_eq!((view.seq(), view.stamp_ns()), (1, 9));
    }

    /// A buffer that starts 64-byte aligned, as a shared-memory sample does.
    #[repr(C, align(64))]
    struct Sample([u8; 4096]);

    fn with_image() -> Blackboard {
        Blackboard::builder()
            .bulk_item::<u16>("image", 1000)
            .item("x", OwnedValue::F64(0.0))
            .item("label", OwnedValue::Text("a".into()))
            .build()
            .unwrap()
    }

    #[test]
    fn a_sample_that_comes_back_gets_only_the_items_changed_since_its_snapshot() {
        let mut sut = with_image();
        let (mut a, mut b) = (Sample([0; 4096]), Sample([0; 4096]));
        let len = sut.snapshot_len();
        sut.write_snapshot(&mut a.0[..len], Addr(2), 10);
        assert_eq!(sut.last_written(), Some(Written::Whole { len }));
        let x = sut.id("x").unwrap();
        sut.set_f64(x, 1.0);
        sut.write_snapshot(&mut b.0[..len], Addr(2), 20);
        assert_eq!(sut.last_written(), Some(Written::Whole { len }), "b is new");
        sut.set_f64(x, 2.0);
        sut.write_snapshot(&mut a.0[..len], Addr(2), 30);
        assert_eq!(
            sut.last_written(),
            Some(Written::Changed { items: 1 }),
            "only x changed since a's snapshot"
        );
        let view = SnapshotView::parse(&a.0[..len]).unwrap();
        assert_eq!((view.seq(), view.f64("x").unwrap()), (3, 2.0));
        let image = sut.id("image").unwrap();
        sut.write_bulk(image, &[7u16; 1000]).unwrap();
        sut.write_snapshot(&mut b.0[..len], Addr(2), 40);
        assert_eq!(sut.last_written(), Some(Written::Changed { items: 2 }));
        let view = SnapshotView::parse(&b.0[..len]).unwrap();
        assert_eq!(view.bulk::<u16>("image").unwrap(), &[7u16; 1000][..]);
        assert_eq!(view.f64("x").unwrap(), 2.0);
    }

    #[test]
    fn a_text_item_that_changes_length_makes_the_next_snapshot_whole() {
        let mut sut = with_image();
        let mut a = Sample([0; 4096]);
        let len = sut.snapshot_len();
        sut.write_snapshot(&mut a.0[..len], Addr(2), 10);
        sut.write("label", Value::Text("longer")).unwrap();
        let len = sut.snapshot_len();
        sut.write_snapshot(&mut a.0[..len], Addr(2), 20);
        assert_eq!(sut.last_written(), Some(Written::Whole { len }));
        let view = SnapshotView::parse(&a.0[..len]).unwrap();
        assert_eq!(view.value("label").unwrap(), Value::Text("longer"));
    }

    #[test]
    fn a_bulk_item_keeps_its_size_and_kind() {
        let mut sut = with_image();
        let image = sut.id("image").unwrap();
        let err = sut.write_bulk(image, &[1u16; 999]).unwrap_err();
        assert!(
            matches!(
                err,
                BlackboardError::BulkLength {
                    expected: 2000,
                    got: 1998,
                    ..
                }
            ),
            "{err}"
        );
        assert!(matches!(
            sut.write("image", Value::Bytes(&[0; 3])),
            Err(BlackboardError::BulkLength { .. })
        ));
        let x = sut.id("x").unwrap();
        assert!(matches!(
            sut.write_bulk(x, &[1u16; 4]),
            Err(BlackboardError::WrongKind { .. })
        ));
        sut.write_bulk(image, &[3u32; 500]).unwrap();
        assert_eq!(
            sut.peek(image),
            Value::Bytes(bytemuck::cast_slice(&[3u32; 500]))
        );
    }
}

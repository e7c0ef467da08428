//! The blackboard: a module's typed store of logical and virtual devices.
//!
//! Every item has a name and a fixed kind. A *logical device* attaches a read hook (sample the
//! sensor when the item is read) and a write hook (drive the actuator when it is written); a
//! *virtual device* is the same with hooks that simulate the hardware. Other modules read and
//! write items by message (the `bb_get`/`bb_set` system methods) and see the whole blackboard
//! through snapshots: one consistent instant in one shared-memory sample.

use modbot_ipc_schema::snapshot::ItemSpec;
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
        let spec = ItemSpec {
            name: name.to_owned(),
            kind: initial.kind(),
            writable,
        };
        self.items.push((spec, initial, Device { read, write }));
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
        Ok(Blackboard {
            layout,
            values,
            devices,
            changed: true,
            seq: 0,
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
            self.changed |= changed;
            return Ok(());
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
        self.changed |= changed;
        Ok(())
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
        for (value, device) in self.values.iter_mut().zip(&mut self.devices) {
            if let Some(hook) = device.read.as_mut() {
                let before = value.clone();
                hook(value);
                self.changed |= *value != before;
            }
        }
    }

    /// The size of the next snapshot.
    pub fn snapshot_len(&self) -> usize {
        self.layout.encoded_len(&self.values)
    }

    /// Writes a snapshot into `out` (shared memory), and clears the changed flag.
    pub fn write_snapshot(&mut self, out: &mut [u8], addr: Addr, stamp_ns: u64) {
        self.seq += 1;
        if let Err(e) = self
            .layout
            .write(out, addr, self.seq, stamp_ns, &self.values)
        {
            tracing::error!("snapshot not written: {e}");
        }
        self.changed = false;
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
}

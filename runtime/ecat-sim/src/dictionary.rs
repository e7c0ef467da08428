//! The object dictionary (CiA 301 as used by CoE): entries addressed by index and subindex,
//! each with a data type, an access right, a PDO mappability and a little-endian value.
//!
//! The application reads and writes entries directly ([`ObjectDictionary::get`],
//! [`ObjectDictionary::set`]); the master goes through the SDO server, which checks access
//! rights, sizes and the state machine first (see [`crate::coe`] and [`crate::pdo`]).

use smallvec::SmallVec;

/// CoE data types (ETG.1000.6 Table 64), the ones the model knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DataType {
    /// BOOLEAN (1 bit when mapped).
    Boolean,
    /// INTEGER8.
    Integer8,
    /// INTEGER16.
    Integer16,
    /// INTEGER32.
    Integer32,
    /// INTEGER64.
    Integer64,
    /// UNSIGNED8.
    Unsigned8,
    /// UNSIGNED16.
    Unsigned16,
    /// UNSIGNED32.
    Unsigned32,
    /// UNSIGNED64.
    Unsigned64,
    /// REAL32.
    Real32,
    /// REAL64.
    Real64,
    /// VISIBLE_STRING (its length is the value's length).
    VisibleString,
    /// OCTET_STRING.
    OctetString,
}

impl DataType {
    /// The data type's index (the code in SII PDO entries and SDO information).
    pub fn code(self) -> u16 {
        match self {
            Self::Boolean => 0x0001,
            Self::Integer8 => 0x0002,
            Self::Integer16 => 0x0003,
            Self::Integer32 => 0x0004,
            Self::Unsigned8 => 0x0005,
            Self::Unsigned16 => 0x0006,
            Self::Unsigned32 => 0x0007,
            Self::Real32 => 0x0008,
            Self::VisibleString => 0x0009,
            Self::OctetString => 0x000A,
            Self::Real64 => 0x0011,
            Self::Integer64 => 0x0015,
            Self::Unsigned64 => 0x001B,
        }
    }

    /// Bits a value of this type takes in a PDO; `None` for strings.
    pub fn bit_len(self) -> Option<u16> {
        Some(match self {
            Self::Boolean => 1,
            Self::Integer8 | Self::Unsigned8 => 8,
            Self::Integer16 | Self::Unsigned16 => 16,
            Self::Integer32 | Self::Unsigned32 | Self::Real32 => 32,
            Self::Integer64 | Self::Unsigned64 | Self::Real64 => 64,
            Self::VisibleString | Self::OctetString => return None,
        })
    }

    /// Bytes a value of this type takes; `None` for strings.
    pub fn byte_len(self) -> Option<usize> {
        self.bit_len().map(|bits| usize::from(bits).div_ceil(8))
    }
}

/// Who may write an entry over SDO (everyone may read, except write-only entries).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Access {
    /// Read only (constant or produced by the device).
    ReadOnly,
    /// Read and write in every state.
    ReadWrite,
    /// Read always; write only in PRE-OP (PDO mapping and assignment, configuration).
    ReadWritePreOp,
    /// Write only.
    WriteOnly,
}

/// Which PDOs may map an entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PdoMappable {
    /// Not mappable.
    No,
    /// RxPDO (outputs, master → slave).
    Rx,
    /// TxPDO (inputs, slave → master).
    Tx,
    /// Both.
    Both,
}

impl PdoMappable {
    /// True if an RxPDO may map it.
    pub fn rx(self) -> bool {
        matches!(self, Self::Rx | Self::Both)
    }

    /// True if a TxPDO may map it.
    pub fn tx(self) -> bool {
        matches!(self, Self::Tx | Self::Both)
    }
}

/// A value type the dictionary stores: fixed-size, little endian.
pub trait ObjectValue: Copy {
    /// Its CoE type.
    const TYPE: DataType;
    /// Little-endian bytes.
    fn to_bytes(self) -> Vec<u8>;
    /// `f` of the little-endian bytes, without allocating (the firmware's cyclic writes).
    fn with_bytes<R>(self, f: impl FnOnce(&[u8]) -> R) -> R;
    /// From little-endian bytes of exactly the right length.
    fn from_bytes(bytes: &[u8]) -> Option<Self>;
}

macro_rules! numeric_value {
    ($t:ty, $data_type:expr) => {
        impl ObjectValue for $t {
            const TYPE: DataType = $data_type;
            fn to_bytes(self) -> Vec<u8> {
                self.to_le_bytes().to_vec()
            }
            fn with_bytes<R>(self, f: impl FnOnce(&[u8]) -> R) -> R {
                f(&self.to_le_bytes())
            }
            fn from_bytes(bytes: &[u8]) -> Option<Self> {
                Some(<$t>::from_le_bytes(bytes.try_into().ok()?))
            }
        }
    };
}

numeric_value!(i8, DataType::Integer8);
numeric_value!(i16, DataType::Integer16);
numeric_value!(i32, DataType::Integer32);
numeric_value!(i64, DataType::Integer64);
numeric_value!(u8, DataType::Unsigned8);
numeric_value!(u16, DataType::Unsigned16);
numeric_value!(u32, DataType::Unsigned32);
numeric_value!(u64, DataType::Unsigned64);
numeric_value!(f32, DataType::Real32);
numeric_value!(f64, DataType::Real64);

impl ObjectValue for bool {
    const TYPE: DataType = DataType::Boolean;
    fn to_bytes(self) -> Vec<u8> {
        vec![u8::from(self)]
    }
    fn with_bytes<R>(self, f: impl FnOnce(&[u8]) -> R) -> R {
        f(&[u8::from(self)])
    }
    fn from_bytes(bytes: &[u8]) -> Option<Self> {
        match bytes {
            [b] => Some(*b & 1 != 0),
            _ => None,
        }
    }
}

/// One entry (an index:subindex) of the dictionary.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectEntry {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub sub_index: u8,
    /// Name, for logs and SDO information.
    pub name: String,
    /// Data type.
    pub data_type: DataType,
    /// SDO write right.
    pub access: Access,
    /// PDO mappability.
    pub pdo: PdoMappable,
    /// The value, little endian: numbers inside the entry, strings on the heap.
    pub value: ObjectBytes,
}

/// An entry's value: up to 8 bytes (every number) kept in place, so the cyclic copies between
/// process data and dictionary touch the entry only.
pub type ObjectBytes = SmallVec<[u8; 8]>;

impl ObjectEntry {
    /// A read-only, unmappable entry holding `value`.
    pub fn new<T: ObjectValue>(index: u16, sub_index: u8, name: &str, value: T) -> Self {
        Self {
            index,
            sub_index,
            name: name.to_owned(),
            data_type: T::TYPE,
            access: Access::ReadOnly,
            pdo: PdoMappable::No,
            value: ObjectBytes::from_vec(value.to_bytes()),
        }
    }

    /// A read-only visible string.
    pub fn string(index: u16, sub_index: u8, name: &str, value: &str) -> Self {
        Self {
            index,
            sub_index,
            name: name.to_owned(),
            data_type: DataType::VisibleString,
            access: Access::ReadOnly,
            pdo: PdoMappable::No,
            value: ObjectBytes::from_slice(value.as_bytes()),
        }
    }

    /// With another access right.
    pub fn with_access(mut self, access: Access) -> Self {
        self.access = access;
        self
    }

    /// Writable over SDO in every state.
    pub fn read_write(self) -> Self {
        self.with_access(Access::ReadWrite)
    }

    /// Mappable into RxPDOs (an output the master writes); writable over SDO too.
    pub fn rx_pdo(mut self) -> Self {
        self.pdo = PdoMappable::Rx;
        self.access = Access::ReadWrite;
        self
    }

    /// Mappable into TxPDOs (an input the master reads).
    pub fn tx_pdo(mut self) -> Self {
        self.pdo = PdoMappable::Tx;
        self
    }

    /// Bits this entry takes in a PDO (strings: their length).
    pub fn bit_len(&self) -> u16 {
        self.data_type
            .bit_len()
            .unwrap_or((self.value.len() * 8).min(usize::from(u16::MAX)) as u16)
    }
}

/// Why the application's direct access failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum OdError {
    /// No such index:subindex.
    #[error("object {index:#06x}:{sub_index} does not exist")]
    NotFound {
        /// Index.
        index: u16,
        /// Subindex.
        sub_index: u8,
    },
    /// The value's type is not the entry's.
    #[error("object {index:#06x}:{sub_index} is {expected:?}, not {given:?}")]
    TypeMismatch {
        /// Index.
        index: u16,
        /// Subindex.
        sub_index: u8,
        /// The entry's type.
        expected: DataType,
        /// The type given.
        given: DataType,
    },
}

/// The dictionary: entries ordered by index, then subindex.
///
/// A sorted pair of vectors rather than a map: a lookup is a binary search over the keys
/// alone (4 bytes each, a drive's ~70 entries in a few cache lines), and an entry keeps its
/// slot until the next insert, so a process-data image can find its entries once
/// ([`ObjectDictionary::slot`]) and reach them by slot every cycle.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ObjectDictionary {
    /// `index << 8 | sub_index` of each entry, ascending.
    keys: Vec<u32>,
    /// The entries, in the order of `keys`.
    entries: Vec<ObjectEntry>,
}

/// An index:subindex an application reads or writes every cycle, with the slot it was found in
/// last: [`ObjectDictionary::read`] and [`ObjectDictionary::write`] search only when that slot
/// no longer holds it (another dictionary, or one with entries inserted since).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Object {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub sub_index: u8,
    slot: usize,
}

impl Object {
    /// index:subindex, not looked for yet.
    pub const fn new(index: u16, sub_index: u8) -> Self {
        Self {
            index,
            sub_index,
            slot: 0,
        }
    }
}

fn key(index: u16, sub_index: u8) -> u32 {
    u32::from(index) << 8 | u32::from(sub_index)
}

impl ObjectDictionary {
    /// An empty dictionary.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds or replaces an entry; returns the one it replaced. Slots found before an insert
    /// of a new index:subindex are no longer valid.
    pub fn insert(&mut self, entry: ObjectEntry) -> Option<ObjectEntry> {
        let k = key(entry.index, entry.sub_index);
        match self.keys.binary_search(&k) {
            Ok(at) => Some(std::mem::replace(&mut self.entries[at], entry)),
            Err(at) => {
                self.keys.insert(at, k);
                self.entries.insert(at, entry);
                None
            }
        }
    }

    /// Where index:subindex is kept (valid until the next insert).
    pub fn slot(&self, index: u16, sub_index: u8) -> Option<usize> {
        self.keys.binary_search(&key(index, sub_index)).ok()
    }

    /// The entry kept at `slot`.
    pub fn at_slot(&self, slot: usize) -> Option<&ObjectEntry> {
        self.entries.get(slot)
    }

    pub(crate) fn at_slot_mut(&mut self, slot: usize) -> Option<&mut ObjectEntry> {
        self.entries.get_mut(slot)
    }

    /// The entry at index:subindex.
    pub fn entry(&self, index: u16, sub_index: u8) -> Option<&ObjectEntry> {
        self.slot(index, sub_index).map(|at| &self.entries[at])
    }

    pub(crate) fn entry_mut(&mut self, index: u16, sub_index: u8) -> Option<&mut ObjectEntry> {
        self.slot(index, sub_index).map(|at| &mut self.entries[at])
    }

    /// True if any subindex of `index` exists.
    pub fn has_object(&self, index: u16) -> bool {
        let first = self.keys.partition_point(|&k| k < key(index, 0));
        self.keys
            .get(first)
            .is_some_and(|&k| k >> 8 == u32::from(index))
    }

    /// Every entry, ordered.
    pub fn entries(&self) -> impl Iterator<Item = &ObjectEntry> {
        self.entries.iter()
    }

    /// The distinct object indices, ordered.
    pub fn indices(&self) -> Vec<u16> {
        let mut out: Vec<u16> = self.keys.iter().map(|&k| (k >> 8) as u16).collect();
        out.dedup();
        out
    }

    /// The raw value of index:subindex.
    pub fn raw(&self, index: u16, sub_index: u8) -> Option<&[u8]> {
        self.entry(index, sub_index).map(|e| e.value.as_slice())
    }

    /// The typed value of index:subindex (`None` if absent or of another type).
    pub fn get<T: ObjectValue>(&self, index: u16, sub_index: u8) -> Option<T> {
        self.read(&mut Object::new(index, sub_index))
    }

    /// Sets a typed value, as the device's firmware does (no access check).
    pub fn set<T: ObjectValue>(
        &mut self,
        index: u16,
        sub_index: u8,
        value: T,
    ) -> Result<(), OdError> {
        self.write(&mut Object::new(index, sub_index), value)
    }

    /// Where `object` is kept: its remembered slot if that still holds it, else searched
    /// (and remembered).
    fn find(&self, object: &mut Object) -> Option<usize> {
        let k = key(object.index, object.sub_index);
        if self.keys.get(object.slot) != Some(&k) {
            object.slot = self.keys.binary_search(&k).ok()?;
        }
        Some(object.slot)
    }

    /// As [`ObjectDictionary::get`], through an [`Object`] that remembers where it was found.
    pub fn read<T: ObjectValue>(&self, object: &mut Object) -> Option<T> {
        let entry = &self.entries[self.find(object)?];
        if entry.data_type != T::TYPE {
            return None;
        }
        T::from_bytes(&entry.value)
    }

    /// As [`ObjectDictionary::set`], through an [`Object`] that remembers where it was found.
    pub fn write<T: ObjectValue>(&mut self, object: &mut Object, value: T) -> Result<(), OdError> {
        let (index, sub_index) = (object.index, object.sub_index);
        let slot = self
            .find(object)
            .ok_or(OdError::NotFound { index, sub_index })?;
        let entry = &mut self.entries[slot];
        if entry.data_type != T::TYPE {
            return Err(OdError::TypeMismatch {
                index,
                sub_index,
                expected: entry.data_type,
                given: T::TYPE,
            });
        }
        // In place: the entry's buffer has the type's size already, so no allocation.
        value.with_bytes(|bytes| replace_bytes(&mut entry.value, bytes));
        Ok(())
    }

    /// Sets raw bytes (no type or access check beyond existence).
    pub fn set_raw(&mut self, index: u16, sub_index: u8, value: &[u8]) -> Result<(), OdError> {
        let entry = self
            .entry_mut(index, sub_index)
            .ok_or(OdError::NotFound { index, sub_index })?;
        replace_bytes(&mut entry.value, value);
        Ok(())
    }
}

/// `value` becomes `bytes`, reusing its buffer.
fn replace_bytes(value: &mut ObjectBytes, bytes: &[u8]) {
    if value.len() == bytes.len() {
        value.copy_from_slice(bytes);
    } else {
        value.clear();
        value.extend_from_slice(bytes);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_typed_value_reads_back_as_written() {
        let mut sut = ObjectDictionary::new();
        sut.insert(ObjectEntry::new(0x6000, 1, "x", 0i32).tx_pdo());
        sut.set(0x6000, 1, -5i32).unwrap();
        assert_eq!(sut.get::<i32>(0x6000, 1), Some(-5));
        assert_eq!(sut.raw(0x6000, 1), Some(&(-5i32).to_le_bytes()[..]));
    }

    #[test]
    fn a_value_of_the_wrong_type_is_refused() {
        let mut sut = ObjectDictionary::new();
        sut.insert(ObjectEntry::new(0x6000, 1, "x", 0i32));
        assert_eq!(
            sut.set(0x6000, 1, 1u16),
            Err(OdError::TypeMismatch {
                index: 0x6000,
                sub_index: 1,
                expected: DataType::Integer32,
                given: DataType::Unsigned16
            })
        );
        assert_eq!(sut.get::<u16>(0x6000, 1), None);
    }

    #[test]
    fn a_missing_entry_is_named_in_the_error() {
        let mut sut = ObjectDictionary::new();
        assert_eq!(
            sut.set(0x7000, 2, 1u8),
            Err(OdError::NotFound {
                index: 0x7000,
                sub_index: 2
            })
        );
    }

    #[test]
    fn strings_take_their_length_in_bits() {
        let entry = ObjectEntry::string(0x1008, 0, "Device name", "MB-IO");
        assert_eq!(entry.bit_len(), 40);
    }

    #[test]
    fn entries_are_kept_in_index_then_subindex_order_whatever_the_insert_order() {
        let mut sut = ObjectDictionary::new();
        for (index, sub_index) in [(0x6041, 0), (0x1018, 2), (0x6040, 0), (0x1018, 1)] {
            sut.insert(ObjectEntry::new(index, sub_index, "x", 0u16));
        }
        let order: Vec<(u16, u8)> = sut.entries().map(|e| (e.index, e.sub_index)).collect();
        assert_eq!(
            order,
            vec![(0x1018, 1), (0x1018, 2), (0x6040, 0), (0x6041, 0)]
        );
        assert_eq!(sut.indices(), vec![0x1018, 0x6040, 0x6041]);
        assert!(sut.has_object(0x1018) && !sut.has_object(0x1019) && !sut.has_object(0x1017));
    }

    #[test]
    fn an_object_finds_its_entry_again_after_entries_were_inserted_before_it() {
        let mut sut = ObjectDictionary::new();
        sut.insert(ObjectEntry::new(0x6041, 0, "status", 7u16));
        let mut status = Object::new(0x6041, 0);
        assert_eq!(sut.read::<u16>(&mut status), Some(7));
        sut.insert(ObjectEntry::new(0x1000, 0, "before", 1u32));
        sut.write(&mut status, 9u16).unwrap();
        assert_eq!(sut.get::<u16>(0x6041, 0), Some(9));
        assert_eq!(
            sut.get::<u32>(0x1000, 0),
            Some(1),
            "the entry now in its old slot"
        );
        assert_eq!(sut.read::<u16>(&mut Object::new(0x6042, 0)), None);
    }

    #[test]
    fn an_insert_of_an_existing_entry_replaces_it_in_its_slot() {
        let mut sut = ObjectDictionary::new();
        sut.insert(ObjectEntry::new(0x6040, 0, "old", 1u16));
        sut.insert(ObjectEntry::new(0x6041, 0, "other", 2u16));
        let slot = sut.slot(0x6040, 0);
        let old = sut.insert(ObjectEntry::new(0x6040, 0, "new", 3u16));
        assert_eq!(old.map(|e| e.name), Some("old".to_owned()));
        assert_eq!(sut.slot(0x6040, 0), slot);
        assert_eq!(sut.get::<u16>(0x6040, 0), Some(3));
        assert_eq!(sut.entries().count(), 2);
    }
}

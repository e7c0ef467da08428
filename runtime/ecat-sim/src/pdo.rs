//! PDO mapping and assignment: the standard communication objects (0x1000, 0x1008, 0x1018,
//! 0x16xx/0x1Axx, 0x1C00, 0x1C12/0x1C13), the checks an SDO write to them must pass, and the
//! layout of the process data they describe.
//!
//! Changing a mapping follows CiA 301: write subindex 0 to 0, write the entries, write
//! subindex 0 to their count. The entries are checked when written and again when the count
//! enables them; the assignment objects likewise.

use crate::coe_codes::abort;
use crate::dictionary::{Access, DataType, ObjectDictionary, ObjectEntry};
use crate::sii::Identity;

/// First RxPDO mapping object.
pub const RX_MAPPING_FIRST: u16 = 0x1600;
/// Last RxPDO mapping object.
pub const RX_MAPPING_LAST: u16 = 0x17FF;
/// First TxPDO mapping object.
pub const TX_MAPPING_FIRST: u16 = 0x1A00;
/// Last TxPDO mapping object.
pub const TX_MAPPING_LAST: u16 = 0x1BFF;
/// RxPDO assignment (sync manager 2).
pub const RX_ASSIGN: u16 = 0x1C12;
/// TxPDO assignment (sync manager 3).
pub const TX_ASSIGN: u16 = 0x1C13;
/// Sync manager communication types.
pub const SM_TYPES: u16 = 0x1C00;
/// Entries each mapping object can hold.
pub const MAX_ENTRIES: u8 = 8;
/// Bits one PDO may carry.
pub const MAX_PDO_BITS: u32 = 8 * 64;

/// Which way a PDO goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// RxPDO: outputs, master → slave, sync manager 2.
    Rx,
    /// TxPDO: inputs, slave → master, sync manager 3.
    Tx,
}

impl Direction {
    fn of_mapping(index: u16) -> Option<Self> {
        match index {
            RX_MAPPING_FIRST..=RX_MAPPING_LAST => Some(Self::Rx),
            TX_MAPPING_FIRST..=TX_MAPPING_LAST => Some(Self::Tx),
            _ => None,
        }
    }

    fn of_assign(index: u16) -> Option<Self> {
        match index {
            RX_ASSIGN => Some(Self::Rx),
            TX_ASSIGN => Some(Self::Tx),
            _ => None,
        }
    }

    /// The assignment object of this direction.
    pub fn assign_index(self) -> u16 {
        match self {
            Self::Rx => RX_ASSIGN,
            Self::Tx => TX_ASSIGN,
        }
    }
}

/// A PDO of the default configuration: its mapping object and the entries it maps.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoDefinition {
    /// 0x16xx (RxPDO) or 0x1Axx (TxPDO).
    pub index: u16,
    /// Mapped index:subindex pairs, in order.
    pub entries: Vec<(u16, u8)>,
}

/// Encodes a mapping entry: index << 16 | subindex << 8 | bits.
pub fn mapping_value(index: u16, sub_index: u8, bits: u8) -> u32 {
    (u32::from(index) << 16) | (u32::from(sub_index) << 8) | u32::from(bits)
}

/// One mapped entry in a process-data image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MappedEntry {
    /// Object index (0 or a data type index 1..=7 for padding).
    pub index: u16,
    /// Subindex.
    pub sub_index: u8,
    /// Bits.
    pub bit_len: u16,
    /// Offset of its first bit in the sync manager buffer.
    pub bit_offset: usize,
}

impl MappedEntry {
    /// True for a gap (dummy entry) that maps no object.
    pub fn is_padding(&self) -> bool {
        self.index <= 0x0007
    }
}

/// The process-data image of one direction.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PdoLayout {
    /// Entries in image order.
    pub entries: Vec<MappedEntry>,
    /// Total bits.
    pub bits: usize,
}

impl PdoLayout {
    /// Bytes of the sync manager buffer (bits rounded up).
    pub fn bytes(&self) -> usize {
        self.bits.div_ceil(8)
    }
}

/// Why the layout could not be computed (the dictionary holds an inconsistent mapping).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("PDO configuration refused with abort code {abort_code:#010x} at {index:#06x}:{sub_index}")]
pub struct LayoutError {
    /// The CoE abort code that describes the fault.
    pub abort_code: u32,
    /// Object at fault.
    pub index: u16,
    /// Subindex at fault.
    pub sub_index: u8,
}

fn decode_entry(value: u32) -> (u16, u8, u8) {
    ((value >> 16) as u16, (value >> 8) as u8, value as u8)
}

/// Checks one mapping entry value against the dictionary.
fn check_entry(od: &ObjectDictionary, direction: Direction, value: u32) -> Result<u16, u32> {
    let (index, sub_index, bits) = decode_entry(value);
    if bits == 0 {
        return Err(abort::CANNOT_MAP);
    }
    if index <= 0x0007 {
        // A gap: index 0, or a data type index whose size matches.
        return Ok(u16::from(bits));
    }
    let entry = od.entry(index, sub_index).ok_or(abort::CANNOT_MAP)?;
    let mappable = match direction {
        Direction::Rx => entry.pdo.rx(),
        Direction::Tx => entry.pdo.tx(),
    };
    if !mappable || entry.bit_len() != u16::from(bits) {
        return Err(abort::CANNOT_MAP);
    }
    Ok(u16::from(bits))
}

fn mapping_bits(
    od: &ObjectDictionary,
    direction: Direction,
    index: u16,
    count: u8,
) -> Result<u32, u32> {
    let mut bits = 0u32;
    for sub in 1..=count {
        let value = od.get::<u32>(index, sub).ok_or(abort::VALUE_TOO_HIGH)?;
        bits += u32::from(check_entry(od, direction, value)?);
    }
    if bits > MAX_PDO_BITS {
        return Err(abort::PDO_TOO_LONG);
    }
    Ok(bits)
}

/// Checks an SDO download to a mapping or assignment object before it is stored. `value` is
/// the downloaded data, already of the entry's size. Returns the abort code on refusal.
pub fn check_write(
    od: &ObjectDictionary,
    index: u16,
    sub_index: u8,
    value: &[u8],
) -> Result<(), u32> {
    if let Some(direction) = Direction::of_mapping(index) {
        let capacity = (1..=u8::MAX)
            .take_while(|&s| od.entry(index, s).is_some())
            .count() as u8;
        if sub_index == 0 {
            let count = *value.first().ok_or(abort::DATA_TOO_SHORT)?;
            if count > capacity {
                return Err(abort::VALUE_TOO_HIGH);
            }
            mapping_bits(od, direction, index, count)?;
            return Ok(());
        }
        if od.get::<u8>(index, 0).unwrap_or(0) != 0 {
            return Err(abort::SUBINDEX_0_NOT_ZERO);
        }
        let raw: [u8; 4] = value.try_into().map_err(|_| abort::LENGTH_MISMATCH)?;
        check_entry(od, direction, u32::from_le_bytes(raw))?;
        return Ok(());
    }
    if let Some(direction) = Direction::of_assign(index) {
        let capacity = (1..=u8::MAX)
            .take_while(|&s| od.entry(index, s).is_some())
            .count() as u8;
        let range = match direction {
            Direction::Rx => RX_MAPPING_FIRST..=RX_MAPPING_LAST,
            Direction::Tx => TX_MAPPING_FIRST..=TX_MAPPING_LAST,
        };
        if sub_index == 0 {
            let count = *value.first().ok_or(abort::DATA_TOO_SHORT)?;
            if count > capacity {
                return Err(abort::VALUE_TOO_HIGH);
            }
            for sub in 1..=count {
                let pdo = od.get::<u16>(index, sub).unwrap_or(0);
                if !range.contains(&pdo) || !od.has_object(pdo) {
                    return Err(abort::VALUE_OUT_OF_RANGE);
                }
            }
            return Ok(());
        }
        if od.get::<u8>(index, 0).unwrap_or(0) != 0 {
            return Err(abort::SUBINDEX_0_NOT_ZERO);
        }
        let raw: [u8; 2] = value.try_into().map_err(|_| abort::LENGTH_MISMATCH)?;
        let pdo = u16::from_le_bytes(raw);
        if !range.contains(&pdo) || !od.has_object(pdo) {
            return Err(abort::VALUE_OUT_OF_RANGE);
        }
    }
    Ok(())
}

/// The image of one direction as the assignment and mapping objects describe it now.
pub fn layout(od: &ObjectDictionary, direction: Direction) -> Result<PdoLayout, LayoutError> {
    let assign = direction.assign_index();
    let fail = |abort_code, index, sub_index| LayoutError {
        abort_code,
        index,
        sub_index,
    };
    let mut out = PdoLayout::default();
    let count = od.get::<u8>(assign, 0).unwrap_or(0);
    for sub in 1..=count {
        let pdo = od
            .get::<u16>(assign, sub)
            .ok_or(fail(abort::VALUE_OUT_OF_RANGE, assign, sub))?;
        let entries = od.get::<u8>(pdo, 0).ok_or(fail(abort::NOT_FOUND, pdo, 0))?;
        for entry_sub in 1..=entries {
            let value = od.get::<u32>(pdo, entry_sub).ok_or(fail(
                abort::SUBINDEX_NOT_FOUND,
                pdo,
                entry_sub,
            ))?;
            let bits =
                check_entry(od, direction, value).map_err(|code| fail(code, pdo, entry_sub))?;
            let (index, sub_index, _) = decode_entry(value);
            out.entries.push(MappedEntry {
                index,
                sub_index,
                bit_len: bits,
                bit_offset: out.bits,
            });
            out.bits += usize::from(bits);
        }
    }
    Ok(out)
}

/// The standard objects of a slave whose application objects are already in `od`: device
/// type, name, versions, identity, sync manager types, and the mapping and assignment objects
/// of the default PDOs (whose entries must exist in `od`).
pub fn add_standard_objects(
    od: &mut ObjectDictionary,
    identity: Identity,
    name: &str,
    rx_pdos: &[PdoDefinition],
    tx_pdos: &[PdoDefinition],
) {
    od.insert(ObjectEntry::new(0x1000, 0, "Device type", 0u32));
    od.insert(ObjectEntry::string(0x1008, 0, "Device name", name));
    od.insert(ObjectEntry::string(0x1009, 0, "Hardware version", "1"));
    od.insert(ObjectEntry::string(
        0x100A,
        0,
        "Software version",
        env!("CARGO_PKG_VERSION"),
    ));
    od.insert(ObjectEntry::new(0x1018, 0, "Identity", 4u8));
    od.insert(ObjectEntry::new(0x1018, 1, "Vendor ID", identity.vendor_id));
    od.insert(ObjectEntry::new(
        0x1018,
        2,
        "Product code",
        identity.product_code,
    ));
    od.insert(ObjectEntry::new(0x1018, 3, "Revision", identity.revision));
    od.insert(ObjectEntry::new(
        0x1018,
        4,
        "Serial number",
        identity.serial,
    ));
    od.insert(ObjectEntry::new(SM_TYPES, 0, "Sync manager types", 4u8));
    for (sub, kind) in [(1u8, 1u8), (2, 2), (3, 3), (4, 4)] {
        od.insert(ObjectEntry::new(SM_TYPES, sub, "Sync manager type", kind));
    }
    for pdo in rx_pdos.iter().chain(tx_pdos) {
        let entries: Vec<u32> = pdo
            .entries
            .iter()
            .map(|&(index, sub)| {
                let bits = od.entry(index, sub).map(|e| e.bit_len()).unwrap_or(0);
                mapping_value(index, sub, bits.min(255) as u8)
            })
            .collect();
        od.insert(
            ObjectEntry::new(pdo.index, 0, "Number of entries", entries.len() as u8)
                .with_access(Access::ReadWritePreOp),
        );
        for sub in 1..=MAX_ENTRIES {
            let value = entries.get(usize::from(sub) - 1).copied().unwrap_or(0);
            od.insert(
                ObjectEntry::new(pdo.index, sub, "Mapping entry", value)
                    .with_access(Access::ReadWritePreOp),
            );
        }
    }
    for (assign, pdos) in [(RX_ASSIGN, rx_pdos), (TX_ASSIGN, tx_pdos)] {
        od.insert(
            ObjectEntry::new(assign, 0, "Number of assigned PDOs", pdos.len() as u8)
                .with_access(Access::ReadWritePreOp),
        );
        for (i, pdo) in pdos.iter().enumerate() {
            od.insert(
                ObjectEntry::new(assign, (i + 1) as u8, "Assigned PDO", pdo.index)
                    .with_access(Access::ReadWritePreOp),
            );
        }
    }
}

/// The data type code a PDO entry of the SII describes.
pub fn sii_data_type(od: &ObjectDictionary, index: u16, sub_index: u8) -> u8 {
    od.entry(index, sub_index)
        .map(|e| e.data_type.code() as u8)
        .unwrap_or(DataType::Unsigned8.code() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dictionary() -> ObjectDictionary {
        let mut od = ObjectDictionary::new();
        od.insert(ObjectEntry::new(0x7000, 1, "out", 0u16).rx_pdo());
        od.insert(ObjectEntry::new(0x7000, 2, "out2", 0i32).rx_pdo());
        od.insert(ObjectEntry::new(0x6000, 1, "in", 0u16).tx_pdo());
        od.insert(ObjectEntry::new(0x6000, 2, "not mappable", 0u8));
        add_standard_objects(
            &mut od,
            Identity::default(),
            "x",
            &[PdoDefinition {
                index: 0x1600,
                entries: vec![(0x7000, 1), (0x7000, 2)],
            }],
            &[PdoDefinition {
                index: 0x1A00,
                entries: vec![(0x6000, 1)],
            }],
        );
        od
    }

    #[test]
    fn the_default_mapping_lays_out_entries_back_to_back() {
        let od = dictionary();
        let sut = layout(&od, Direction::Rx).unwrap();
        assert_eq!(sut.bytes(), 6);
        assert_eq!(sut.entries[1].bit_offset, 16);
        assert_eq!(layout(&od, Direction::Tx).unwrap().bytes(), 2);
    }

    #[test]
    fn mapping_an_object_that_does_not_exist_is_refused() {
        let mut od = dictionary();
        od.set(0x1600, 0, 0u8).unwrap();
        let value = mapping_value(0x7777, 1, 16).to_le_bytes();
        assert_eq!(check_write(&od, 0x1600, 1, &value), Err(abort::CANNOT_MAP));
    }

    #[test]
    fn mapping_an_unmappable_object_is_refused() {
        let mut od = dictionary();
        od.set(0x1A00, 0, 0u8).unwrap();
        let value = mapping_value(0x6000, 2, 8).to_le_bytes();
        assert_eq!(check_write(&od, 0x1A00, 1, &value), Err(abort::CANNOT_MAP));
    }

    #[test]
    fn mapping_an_output_into_a_txpdo_is_refused() {
        let mut od = dictionary();
        od.set(0x1A00, 0, 0u8).unwrap();
        let value = mapping_value(0x7000, 1, 16).to_le_bytes();
        assert_eq!(check_write(&od, 0x1A00, 1, &value), Err(abort::CANNOT_MAP));
    }

    #[test]
    fn changing_an_entry_while_the_mapping_is_enabled_is_refused() {
        let od = dictionary();
        let value = mapping_value(0x7000, 1, 16).to_le_bytes();
        assert_eq!(
            check_write(&od, 0x1600, 1, &value),
            Err(abort::SUBINDEX_0_NOT_ZERO)
        );
    }

    #[test]
    fn enabling_more_entries_than_the_object_holds_is_refused() {
        let mut od = dictionary();
        od.set(0x1600, 0, 0u8).unwrap();
        assert_eq!(
            check_write(&od, 0x1600, 0, &[9]),
            Err(abort::VALUE_TOO_HIGH)
        );
    }

    #[test]
    fn assigning_a_pdo_that_does_not_exist_is_refused() {
        let mut od = dictionary();
        od.set(RX_ASSIGN, 0, 0u8).unwrap();
        assert_eq!(
            check_write(&od, RX_ASSIGN, 1, &0x1601u16.to_le_bytes()),
            Err(abort::VALUE_OUT_OF_RANGE)
        );
        assert_eq!(
            check_write(&od, RX_ASSIGN, 1, &0x1A00u16.to_le_bytes()),
            Err(abort::VALUE_OUT_OF_RANGE)
        );
        assert_eq!(
            check_write(&od, RX_ASSIGN, 1, &0x1600u16.to_le_bytes()),
            Ok(())
        );
    }

    #[test]
    fn a_gap_entry_takes_room_without_an_object() {
        let mut od = dictionary();
        od.set(0x1600, 0, 0u8).unwrap();
        od.set(0x1600, 3, mapping_value(0, 0, 8)).unwrap();
        assert_eq!(check_write(&od, 0x1600, 0, &[3]), Ok(()));
        od.set(0x1600, 0, 3u8).unwrap();
        let sut = layout(&od, Direction::Rx).unwrap();
        assert_eq!(sut.bytes(), 7);
        assert!(sut.entries[2].is_padding());
    }
}

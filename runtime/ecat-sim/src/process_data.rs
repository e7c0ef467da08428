//! Copying between the process-data buffers of the sync managers and the dictionary entries
//! the current PDO layout maps, bit by bit (entries need not be byte aligned).
//!
//! A layout is bound to the dictionary once, when it comes into force ([`BoundLayout::bind`]
//! at PRE-OP → SAFE-OP): each entry's slot is found then, so a cycle's copies search nothing.
//! Sixty-four software slaves pass a frame one after the other; what one spends per entry and
//! cycle is spent 64 times per frame.

use crate::dictionary::ObjectDictionary;
use crate::pdo::PdoLayout;

/// A PDO layout with the dictionary slot of each entry (`None` for a gap, or an entry the
/// dictionary does not hold: its bits read as 0 and writes to it go nowhere).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BoundLayout {
    layout: PdoLayout,
    slots: Vec<Option<usize>>,
}

impl BoundLayout {
    /// `layout` with the slots of its entries in `od` (valid while `od` gets no new entry:
    /// a slave's dictionary is complete from power-on).
    pub fn bind(layout: PdoLayout, od: &ObjectDictionary) -> Self {
        let slots = layout
            .entries
            .iter()
            .map(|e| {
                if e.is_padding() {
                    None
                } else {
                    od.slot(e.index, e.sub_index)
                }
            })
            .collect();
        Self { layout, slots }
    }

    /// The layout.
    pub fn layout(&self) -> &PdoLayout {
        &self.layout
    }

    /// Bytes of the sync manager buffer.
    pub fn bytes(&self) -> usize {
        self.layout.bytes()
    }
}

fn get_bit(bytes: &[u8], bit: usize) -> bool {
    bytes
        .get(bit / 8)
        .is_some_and(|b| (b >> (bit % 8)) & 1 != 0)
}

fn set_bit(bytes: &mut [u8], bit: usize, value: bool) {
    if let Some(b) = bytes.get_mut(bit / 8) {
        if value {
            *b |= 1 << (bit % 8);
        } else {
            *b &= !(1 << (bit % 8));
        }
    }
}

/// Copies `bits` bits from `src` at bit `src_bit` to `dst` at bit `dst_bit`; whole bytes
/// when both are byte aligned. Out-of-range bits are skipped.
pub fn copy_bits(src: &[u8], src_bit: usize, dst: &mut [u8], dst_bit: usize, bits: usize) {
    if src_bit % 8 == 0 && dst_bit % 8 == 0 && bits % 8 == 0 {
        let (s, d, n) = (src_bit / 8, dst_bit / 8, bits / 8);
        if let (Some(from), Some(to)) = (src.get(s..s + n), dst.get_mut(d..d + n)) {
            to.copy_from_slice(from);
            return;
        }
    }
    for i in 0..bits {
        set_bit(dst, dst_bit + i, get_bit(src, src_bit + i));
    }
}

/// Outputs buffer → dictionary: every mapped entry takes its bits from `buffer`.
pub fn buffer_to_dictionary(bound: &BoundLayout, buffer: &[u8], od: &mut ObjectDictionary) {
    for (entry, slot) in bound.layout.entries.iter().zip(&bound.slots) {
        if let Some(object) = slot.and_then(|at| od.at_slot_mut(at)) {
            let bits = usize::from(entry.bit_len);
            if object.value.len() < bits.div_ceil(8) {
                object.value.resize(bits.div_ceil(8), 0);
            }
            copy_bits(buffer, entry.bit_offset, &mut object.value, 0, bits);
        }
    }
}

/// Dictionary → inputs buffer: every mapped entry puts its bits into `buffer`; gaps are 0.
pub fn dictionary_to_buffer(bound: &BoundLayout, od: &ObjectDictionary, buffer: &mut [u8]) {
    for (entry, slot) in bound.layout.entries.iter().zip(&bound.slots) {
        let bits = usize::from(entry.bit_len);
        match slot.and_then(|at| od.at_slot(at)) {
            Some(object) => copy_bits(&object.value, 0, buffer, entry.bit_offset, bits),
            None => {
                for i in 0..bits {
                    set_bit(buffer, entry.bit_offset + i, false);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dictionary::ObjectEntry;
    use crate::pdo::MappedEntry;

    #[test]
    fn unaligned_bits_are_copied_one_by_one() {
        let src = [0b1011_0110u8, 0b0000_0001];
        let mut dst = [0u8; 2];
        copy_bits(&src, 1, &mut dst, 3, 9);
        // Bits 1..=9 of src are 1,1,0,1,1,0,1,1,0 → at dst bits 3..=11.
        assert_eq!(dst, [0b1101_1000, 0b0000_0110]);
    }

    #[test]
    fn a_bool_and_a_u16_round_trip_through_a_buffer() {
        let mut od = ObjectDictionary::new();
        od.insert(ObjectEntry::new(0x6000, 1, "flag", true).tx_pdo());
        od.insert(ObjectEntry::new(0x6000, 2, "word", 0xBEEFu16).tx_pdo());
        let layout = PdoLayout {
            entries: vec![
                MappedEntry {
                    index: 0x6000,
                    sub_index: 1,
                    bit_len: 1,
                    bit_offset: 0,
                },
                MappedEntry {
                    index: 0,
                    sub_index: 0,
                    bit_len: 7,
                    bit_offset: 1,
                },
                MappedEntry {
                    index: 0x6000,
                    sub_index: 2,
                    bit_len: 16,
                    bit_offset: 8,
                },
            ],
            bits: 24,
        };
        let layout = BoundLayout::bind(layout, &od);
        let mut buffer = [0xFFu8; 3];
        dictionary_to_buffer(&layout, &od, &mut buffer);
        assert_eq!(buffer, [0x01, 0xEF, 0xBE]);
        let mut other = od.clone();
        other.set(0x6000, 1, false).unwrap();
        other.set(0x6000, 2, 0u16).unwrap();
        buffer_to_dictionary(&layout, &buffer, &mut other);
        assert_eq!(other, od);
    }
}

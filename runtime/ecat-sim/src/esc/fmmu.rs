//! FMMU registers (0x0600 + 16·n): windows from the logical address space of LRD/LWR/LRW
//! onto the ESC memory.

/// One FMMU, decoded. The model maps whole bytes: the start and end bits are kept but a
/// bit-wise window (start bit ≠ 0 or end bit ≠ 7) maps its first and last bytes whole.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fmmu {
    /// First logical byte.
    pub logical_start: u32,
    /// Bytes mapped.
    pub length: u16,
    /// First logical bit.
    pub logical_start_bit: u8,
    /// Last logical bit.
    pub logical_end_bit: u8,
    /// First physical byte.
    pub physical_start: u16,
    /// First physical bit.
    pub physical_start_bit: u8,
    /// Type bit 0: logical reads go through.
    pub read: bool,
    /// Type bit 1: logical writes go through.
    pub write: bool,
    /// Activate bit 0.
    pub enabled: bool,
}

impl Fmmu {
    /// Decodes the 16 register bytes.
    pub fn decode(bytes: &[u8; 16]) -> Self {
        Self {
            logical_start: u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
            length: u16::from_le_bytes([bytes[4], bytes[5]]),
            logical_start_bit: bytes[6] & 0x07,
            logical_end_bit: bytes[7] & 0x07,
            physical_start: u16::from_le_bytes([bytes[8], bytes[9]]),
            physical_start_bit: bytes[10] & 0x07,
            read: bytes[11] & 0x01 != 0,
            write: bytes[11] & 0x02 != 0,
            enabled: bytes[12] & 0x01 != 0,
        }
    }

    /// The part of a datagram at `logical` with `len` bytes that this FMMU maps: the offset in
    /// the datagram's data, the physical address and the byte count.
    pub fn overlap(&self, logical: u32, len: usize) -> Option<(usize, u16, usize)> {
        if !self.enabled || self.length == 0 || len == 0 {
            return None;
        }
        let window_start = u64::from(self.logical_start);
        let window_end = window_start + u64::from(self.length);
        let datagram_start = u64::from(logical);
        let datagram_end = datagram_start + len as u64;
        let start = window_start.max(datagram_start);
        let end = window_end.min(datagram_end);
        if start >= end {
            return None;
        }
        let data_offset = (start - datagram_start) as usize;
        let physical = u64::from(self.physical_start) + (start - window_start);
        let physical = u16::try_from(physical).ok()?;
        Some((data_offset, physical, (end - start) as usize))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn window(logical_start: u32, length: u16, physical_start: u16) -> Fmmu {
        Fmmu {
            logical_start,
            length,
            logical_start_bit: 0,
            logical_end_bit: 7,
            physical_start,
            physical_start_bit: 0,
            read: true,
            write: false,
            enabled: true,
        }
    }

    #[test]
    fn a_datagram_covering_the_window_maps_all_of_it() {
        let sut = window(0x10, 4, 0x1100);
        assert_eq!(sut.overlap(0x0C, 12), Some((4, 0x1100, 4)));
    }

    #[test]
    fn a_datagram_starting_inside_the_window_maps_its_tail() {
        let sut = window(0x10, 8, 0x1100);
        assert_eq!(sut.overlap(0x14, 12), Some((0, 0x1104, 4)));
    }

    #[test]
    fn a_disjoint_datagram_maps_nothing() {
        let sut = window(0x10, 8, 0x1100);
        assert_eq!(sut.overlap(0x18, 4), None);
        assert_eq!(sut.overlap(0x00, 0x10), None);
    }

    #[test]
    fn a_disabled_fmmu_maps_nothing() {
        let sut = Fmmu {
            enabled: false,
            ..window(0, 8, 0x1100)
        };
        assert_eq!(sut.overlap(0, 8), None);
    }
}

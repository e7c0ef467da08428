//! The process data of one CiA 402 drive as this backend maps it, and its units.
//!
//! RxPDO 0x1600 (master → drive), assigned to sync manager 2 through 0x1C12:
//!
//! | object | name | type |
//! |---|---|---|
//! | 0x6040 | controlword | u16 |
//! | 0x6060 | modes of operation | i8 |
//! | 0x607A | target position | i32, counts |
//! | 0x60FF | target velocity | i32, counts/s |
//! | 0x6071 | target torque | i16, per mille of the rated torque |
//!
//! TxPDO 0x1A00 (drive → master), assigned to sync manager 3 through 0x1C13: statusword
//! 0x6041 (u16), modes of operation display 0x6061 (i8), position actual 0x6064 (i32),
//! velocity actual 0x606C (i32), torque actual 0x6077 (i16), error code 0x603F (u16), and with
//! a load-side encoder 0x20A0 (i32, counts: the link's position, read as `link_position`).
//!
//! The mapping is written by SDO in PRE-OP ([`sdo_writes`]); the bytes are little-endian and
//! packed in the order above. Units: a drive's [`Scale`] converts rad, rad/s and Nm to its
//! counts and torque units.

use modbot_bus::cia402::DriveState;
pub use modbot_bus::units::Scale;
use modbot_bus::{AxisActual, AxisCommand};

/// One mapped object: index, subindex, bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Entry {
    pub index: u16,
    pub sub: u8,
    pub bits: u8,
}

impl Entry {
    const fn new(index: u16, bits: u8) -> Entry {
        Entry {
            index,
            sub: 0,
            bits,
        }
    }

    /// The value of a PDO mapping entry: index, subindex, bit length.
    pub fn mapping(self) -> u32 {
        (u32::from(self.index) << 16) | (u32::from(self.sub) << 8) | u32::from(self.bits)
    }
}

/// The RxPDO's objects, in order.
pub const RX: [Entry; 5] = [
    Entry::new(0x6040, 16),
    Entry::new(0x6060, 8),
    Entry::new(0x607A, 32),
    Entry::new(0x60FF, 32),
    Entry::new(0x6071, 16),
];

/// The TxPDO's objects, in order, without the load-side encoder.
pub const TX: [Entry; 6] = [
    Entry::new(0x6041, 16),
    Entry::new(0x6061, 8),
    Entry::new(0x6064, 32),
    Entry::new(0x606C, 32),
    Entry::new(0x6077, 16),
    Entry::new(0x603F, 16),
];

/// The load-side encoder's position (manufacturer-specific range).
pub const LINK: Entry = Entry::new(0x20A0, 32);

/// The RxPDO mapping object and the sync manager assignments.
pub const RX_PDO: u16 = 0x1600;
pub const TX_PDO: u16 = 0x1A00;
pub const RX_ASSIGN: u16 = 0x1C12;
pub const TX_ASSIGN: u16 = 0x1C13;

/// Bytes of the outputs and of the inputs (with or without the load-side encoder).
pub const OUT_BYTES: usize = 13;
pub fn in_bytes(link_encoder: bool) -> usize {
    15 + if link_encoder { 4 } else { 0 }
}

/// The TxPDO's entries for a drive with or without a load-side encoder.
pub fn tx_entries(link_encoder: bool) -> &'static [Entry] {
    const WITH: [Entry; 7] = [TX[0], TX[1], TX[2], TX[3], TX[4], TX[5], LINK];
    if link_encoder {
        &WITH
    } else {
        &TX
    }
}

/// One SDO download of the mapping: (index, subindex, value, bytes of the value).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SdoWrite {
    pub index: u16,
    pub sub: u8,
    pub value: u32,
    pub bytes: u8,
}

/// The SDO downloads that map the process data, in the order a slave accepts them: an
/// assignment and a mapping are cleared (subindex 0 = 0) before their entries are written and
/// their count set again.
pub fn sdo_writes(link_encoder: bool) -> Vec<SdoWrite> {
    let w = |index, sub, value, bytes| SdoWrite {
        index,
        sub,
        value,
        bytes,
    };
    let mut out = Vec::new();
    for (assign, pdo, entries) in [
        (RX_ASSIGN, RX_PDO, &RX[..]),
        (TX_ASSIGN, TX_PDO, tx_entries(link_encoder)),
    ] {
        out.push(w(assign, 0, 0, 1));
        out.push(w(pdo, 0, 0, 1));
        for (i, e) in entries.iter().enumerate() {
            out.push(w(pdo, i as u8 + 1, e.mapping(), 4));
        }
        out.push(w(pdo, 0, entries.len() as u32, 1));
        out.push(w(assign, 1, u32::from(pdo), 2));
        out.push(w(assign, 0, 1, 1));
    }
    out
}

/// Writes `command` into a drive's outputs (at least [`OUT_BYTES`]). A target that is not a
/// finite number cannot be sent: the position becomes `hold` (where the drive is), the
/// velocity and torque 0.
pub fn write_outputs(out: &mut [u8], command: &AxisCommand, scale: &Scale, hold: f64) {
    if out.len() < OUT_BYTES {
        return;
    }
    let finite = |x: f64, otherwise: f64| if x.is_finite() { x } else { otherwise };
    let position = scale.counts(finite(command.target_position, hold));
    let velocity = scale.counts(finite(command.target_velocity, 0.0));
    let torque = scale.torque(finite(command.target_torque, 0.0));
    out[0..2].copy_from_slice(&command.controlword.to_le_bytes());
    out[2] = command.mode as u8;
    out[3..7].copy_from_slice(&position.to_le_bytes());
    out[7..11].copy_from_slice(&velocity.to_le_bytes());
    out[11..13].copy_from_slice(&torque.to_le_bytes());
}

fn i32_at(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Reads a drive's inputs (at least [`in_bytes`]) into `actual`; too short inputs leave it.
pub fn read_inputs(inputs: &[u8], link_encoder: bool, scale: &Scale, actual: &mut AxisActual) {
    if inputs.len() < in_bytes(link_encoder) {
        return;
    }
    let statusword = u16::from_le_bytes([inputs[0], inputs[1]]);
    actual.statusword = statusword;
    actual.state =
        DriveState::from_statusword(statusword).unwrap_or(DriveState::NotReadyToSwitchOn);
    actual.mode = inputs[2] as i8;
    actual.motor_position = scale.rad(i32_at(inputs, 3));
    actual.motor_velocity = scale.rad(i32_at(inputs, 7));
    actual.motor_torque = scale.nm(i16::from_le_bytes([inputs[11], inputs[12]]));
    actual.error_code = u16::from_le_bytes([inputs[13], inputs[14]]);
    actual.link_position = if link_encoder {
        scale.rad(i32_at(inputs, 15))
    } else {
        actual.motor_position
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCALE: Scale = Scale {
        counts_per_rad: 1000.0,
        torque_per_nm: 10.0,
    };

    #[test]
    fn a_command_is_packed_little_endian_in_the_mapping_order() {
        let mut out = [0u8; OUT_BYTES];
        let command = AxisCommand {
            controlword: 0x000F,
            mode: 8,
            target_position: 1.5,
            target_velocity: -0.25,
            target_torque: 2.0,
        };
        write_outputs(&mut out, &command, &SCALE, 0.0);
        assert_eq!(
            out,
            [0x0F, 0x00, 0x08, 0xDC, 0x05, 0, 0, 0x06, 0xFF, 0xFF, 0xFF, 0x14, 0x00]
        );
    }

    #[test]
    fn a_target_that_is_not_a_number_holds_where_the_drive_is() {
        let mut out = [0u8; OUT_BYTES];
        let command = AxisCommand {
            target_position: f64::NAN,
            target_torque: f64::INFINITY,
            ..Default::default()
        };
        write_outputs(&mut out, &command, &SCALE, 0.5);
        assert_eq!(i32_at(&out, 3), 500);
        assert_eq!(&out[11..13], &[0, 0]);
    }

    #[test]
    fn inputs_are_read_in_si_units_with_the_link_from_the_load_side_encoder() {
        let mut inputs = [0u8; 19];
        inputs[0..2].copy_from_slice(&0x0637u16.to_le_bytes());
        inputs[2] = 8;
        inputs[3..7].copy_from_slice(&2500i32.to_le_bytes());
        inputs[7..11].copy_from_slice(&(-100i32).to_le_bytes());
        inputs[11..13].copy_from_slice(&15i16.to_le_bytes());
        inputs[13..15].copy_from_slice(&0x8611u16.to_le_bytes());
        inputs[15..19].copy_from_slice(&2490i32.to_le_bytes());
        let mut actual = AxisActual::default();
        read_inputs(&inputs, true, &SCALE, &mut actual);
        assert_eq!(actual.state, DriveState::OperationEnabled);
        assert_eq!(
            (
                actual.mode,
                actual.motor_position,
                actual.motor_velocity,
                actual.motor_torque
            ),
            (8, 2.5, -0.1, 1.5)
        );
        assert_eq!((actual.error_code, actual.link_position), (0x8611, 2.49));
    }

    #[test]
    fn the_mapping_clears_each_pdo_and_assignment_before_writing_it() {
        let writes = sdo_writes(false);
        assert_eq!(writes.len(), 2 * 5 + RX.len() + TX.len());
        assert_eq!(
            (writes[0].index, writes[0].sub, writes[0].value),
            (0x1C12, 0, 0)
        );
        assert_eq!(
            (writes[2].index, writes[2].sub, writes[2].value),
            (0x1600, 1, 0x6040_0010)
        );
        let last = writes.last().unwrap();
        assert_eq!((last.index, last.sub, last.value), (0x1C13, 0, 1));
    }
}

//! The SII (EEPROM) interface of the ESC, registers 0x0500–0x050F: the master writes a word
//! address and a command to 0x0502, the ESC executes it and clears the busy bit, and a read
//! leaves 8 bytes (this ESC's read size) in 0x0508.
//!
//! The model executes a command within the datagram that wrote it: the first status read
//! already finds the interface idle, as with a fast EEPROM.

use super::registers::{SII_ADDRESS, SII_CONTROL, SII_DATA, STATION_ALIAS};

/// 0x0502 bit 0: write access enabled (must accompany a write command).
const WRITE_ENABLE: u16 = 0x0001;
/// 0x0502 bit 6: reads return 8 bytes (an ET1100 does; ethercrab reads this bit).
pub(crate) const READ_SIZE_8: u16 = 0x0040;
const CMD_READ: u16 = 0x0100;
const CMD_WRITE: u16 = 0x0200;
const CMD_RELOAD: u16 = 0x0400;
const COMMAND_ERROR: u16 = 0x2000;
const ERROR_BITS: u16 = 0x7800;
const BUSY: u16 = 0x8000;

/// The EEPROM behind the interface.
#[derive(Debug, Clone)]
pub struct SiiInterface {
    image: Vec<u8>,
}

fn reg(mem: &[u8], at: u16) -> u16 {
    let at = usize::from(at);
    u16::from_le_bytes([mem[at], mem[at + 1]])
}

fn set_reg(mem: &mut [u8], at: u16, value: u16) {
    let at = usize::from(at);
    mem[at..at + 2].copy_from_slice(&value.to_le_bytes());
}

impl SiiInterface {
    /// An interface over an EEPROM holding `image` (padded with 0xFF, as erased cells read).
    pub fn new(image: Vec<u8>) -> Self {
        Self { image }
    }

    /// The EEPROM contents.
    pub fn image(&self) -> &[u8] {
        &self.image
    }

    /// The word at `word` (0xFFFF past the end).
    pub fn word(&self, word: usize) -> u16 {
        let at = word * 2;
        match self.image.get(at..at + 2) {
            Some(bytes) => u16::from_le_bytes([bytes[0], bytes[1]]),
            None => 0xFFFF,
        }
    }

    /// Power-on state of the registers: idle, 8-byte reads, alias loaded from word 4.
    pub fn power_on(&self, mem: &mut [u8]) {
        set_reg(mem, SII_CONTROL, READ_SIZE_8);
        set_reg(mem, STATION_ALIAS, self.word(4));
    }

    /// The master wrote somewhere in 0x0502..0x0504 with the bytes now in `mem` (the control
    /// word as written, before the ESC's read-only bits are put back in `previous`).
    pub fn on_control_written(&mut self, mem: &mut [u8], previous: u16) {
        let written = reg(mem, SII_CONTROL);
        // Only bit 0 and the command bits are writable; status bits stay as they were.
        let mut control = (previous & !(WRITE_ENABLE | CMD_READ | CMD_WRITE | CMD_RELOAD))
            | (written & (WRITE_ENABLE | CMD_READ | CMD_WRITE | CMD_RELOAD));
        control |= READ_SIZE_8;
        let commands = control & (CMD_READ | CMD_WRITE | CMD_RELOAD);
        if commands == 0 {
            set_reg(mem, SII_CONTROL, control);
            return;
        }
        control &= !(ERROR_BITS | BUSY);
        let address = u32::from_le_bytes([
            mem[usize::from(SII_ADDRESS)],
            mem[usize::from(SII_ADDRESS) + 1],
            mem[usize::from(SII_ADDRESS) + 2],
            mem[usize::from(SII_ADDRESS) + 3],
        ]) as usize;
        match commands {
            CMD_READ => {
                let data = usize::from(SII_DATA);
                for i in 0..4 {
                    let word = self.word(address + i);
                    mem[data + 2 * i..data + 2 * i + 2].copy_from_slice(&word.to_le_bytes());
                }
                tracing::trace!(address, "SII read");
            }
            CMD_WRITE if control & WRITE_ENABLE != 0 => {
                let data = usize::from(SII_DATA);
                let at = address * 2;
                if let Some(cells) = self.image.get_mut(at..at + 2) {
                    cells.copy_from_slice(&mem[data..data + 2]);
                    tracing::debug!(address, "SII word written");
                } else {
                    control |= COMMAND_ERROR;
                }
            }
            CMD_RELOAD => {
                set_reg(mem, STATION_ALIAS, self.word(4));
            }
            _ => control |= COMMAND_ERROR,
        }
        control &= !(CMD_READ | CMD_WRITE | CMD_RELOAD);
        set_reg(mem, SII_CONTROL, control);
    }
}

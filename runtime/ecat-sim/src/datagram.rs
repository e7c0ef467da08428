//! One EtherCAT datagram, viewed in place, and its command.

/// Bytes of a datagram header.
pub const DATAGRAM_HEADER_LEN: usize = 10;
/// Bytes of the working counter that ends a datagram.
pub const WKC_LEN: usize = 2;

/// The datagram commands of ETG.1000.4 (Table 19, command codes 0..=14).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// No operation: slaves ignore it.
    Nop,
    /// Auto-increment physical read.
    Aprd,
    /// Auto-increment physical write.
    Apwr,
    /// Auto-increment physical read-write.
    Aprw,
    /// Configured-address physical read.
    Fprd,
    /// Configured-address physical write.
    Fpwr,
    /// Configured-address physical read-write.
    Fprw,
    /// Broadcast read.
    Brd,
    /// Broadcast write.
    Bwr,
    /// Broadcast read-write.
    Brw,
    /// Logical read.
    Lrd,
    /// Logical write.
    Lwr,
    /// Logical read-write.
    Lrw,
    /// Auto-increment read, multiple write.
    Armw,
    /// Configured-address read, multiple write.
    Frmw,
}

/// How a command addresses slaves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Addressing {
    /// The slave whose position counter reaches 0 (each slave increments ADP).
    Position,
    /// The slave whose configured station address (0x0010) equals ADP.
    Station,
    /// Every slave.
    Broadcast,
    /// Every slave whose FMMUs map the logical address range.
    Logical,
    /// Nobody.
    None,
}

impl Command {
    /// The command of a command byte; `None` for reserved codes, which slaves pass through
    /// untouched.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0 => Self::Nop,
            1 => Self::Aprd,
            2 => Self::Apwr,
            3 => Self::Aprw,
            4 => Self::Fprd,
            5 => Self::Fpwr,
            6 => Self::Fprw,
            7 => Self::Brd,
            8 => Self::Bwr,
            9 => Self::Brw,
            10 => Self::Lrd,
            11 => Self::Lwr,
            12 => Self::Lrw,
            13 => Self::Armw,
            14 => Self::Frmw,
            _ => return None,
        })
    }

    /// The command byte.
    pub fn code(self) -> u8 {
        match self {
            Self::Nop => 0,
            Self::Aprd => 1,
            Self::Apwr => 2,
            Self::Aprw => 3,
            Self::Fprd => 4,
            Self::Fpwr => 5,
            Self::Fprw => 6,
            Self::Brd => 7,
            Self::Bwr => 8,
            Self::Brw => 9,
            Self::Lrd => 10,
            Self::Lwr => 11,
            Self::Lrw => 12,
            Self::Armw => 13,
            Self::Frmw => 14,
        }
    }

    /// How this command selects the slaves that act on it.
    pub fn addressing(self) -> Addressing {
        match self {
            Self::Nop => Addressing::None,
            Self::Aprd | Self::Apwr | Self::Aprw | Self::Armw => Addressing::Position,
            Self::Fprd | Self::Fpwr | Self::Fprw | Self::Frmw => Addressing::Station,
            Self::Brd | Self::Bwr | Self::Brw => Addressing::Broadcast,
            Self::Lrd | Self::Lwr | Self::Lrw => Addressing::Logical,
        }
    }
}

/// A datagram inside a frame buffer: header, data and working counter, all editable.
#[derive(Debug)]
pub struct Datagram<'a> {
    bytes: &'a mut [u8],
}

impl<'a> Datagram<'a> {
    /// Wraps bytes that [`crate::frame::decode`] measured: at least header + working counter,
    /// with the data length the header announces.
    pub(crate) fn new_unchecked(bytes: &'a mut [u8]) -> Self {
        Self { bytes }
    }

    fn u16_at(&self, at: usize) -> u16 {
        u16::from_le_bytes([self.bytes[at], self.bytes[at + 1]])
    }

    /// The raw command byte.
    pub fn command_code(&self) -> u8 {
        self.bytes[0]
    }

    /// The command, `None` for a reserved code.
    pub fn command(&self) -> Option<Command> {
        Command::from_code(self.command_code())
    }

    /// The index the master uses to match replies.
    pub fn index(&self) -> u8 {
        self.bytes[1]
    }

    /// ADP: position (auto-increment) or station address.
    pub fn adp(&self) -> u16 {
        self.u16_at(2)
    }

    /// Rewrites ADP (auto-increment addressing increments it at every slave).
    pub fn set_adp(&mut self, adp: u16) {
        self.bytes[2..4].copy_from_slice(&adp.to_le_bytes());
    }

    /// ADO: the register or memory offset in the slave.
    pub fn ado(&self) -> u16 {
        self.u16_at(4)
    }

    /// The whole address field as a logical address.
    pub fn logical_address(&self) -> u32 {
        u32::from_le_bytes([self.bytes[2], self.bytes[3], self.bytes[4], self.bytes[5]])
    }

    /// The data length announced in the header.
    pub fn len(&self) -> usize {
        usize::from(self.u16_at(6) & 0x07FF)
    }

    /// True for a datagram without data.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The circulating bit (set by a slave that closed a port the frame came back through).
    pub fn circulating(&self) -> bool {
        self.u16_at(6) & 0x4000 != 0
    }

    /// True if another datagram follows this one.
    pub fn more_follows(&self) -> bool {
        self.u16_at(6) & 0x8000 != 0
    }

    /// The IRQ field (ESC event requests ORed in by slaves).
    pub fn irq(&self) -> u16 {
        self.u16_at(8)
    }

    /// The data.
    pub fn data(&self) -> &[u8] {
        let len = self.bytes.len() - DATAGRAM_HEADER_LEN - WKC_LEN;
        &self.bytes[DATAGRAM_HEADER_LEN..DATAGRAM_HEADER_LEN + len]
    }

    /// The data, writable.
    pub fn data_mut(&mut self) -> &mut [u8] {
        let len = self.bytes.len() - DATAGRAM_HEADER_LEN - WKC_LEN;
        &mut self.bytes[DATAGRAM_HEADER_LEN..DATAGRAM_HEADER_LEN + len]
    }

    /// The working counter.
    pub fn working_counter(&self) -> u16 {
        self.u16_at(self.bytes.len() - WKC_LEN)
    }

    /// Adds to the working counter (wrapping, as the 16-bit hardware counter does).
    pub fn add_working_counter(&mut self, increment: u16) {
        let at = self.bytes.len() - WKC_LEN;
        let value = self.working_counter().wrapping_add(increment);
        self.bytes[at..].copy_from_slice(&value.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_command_code_round_trips() {
        for code in 0..=14u8 {
            let command = Command::from_code(code).unwrap();
            assert_eq!(command.code(), code);
        }
        assert_eq!(Command::from_code(15), None);
        assert_eq!(Command::from_code(0xFF), None);
    }

    #[test]
    fn read_multiple_write_commands_address_like_their_family() {
        assert_eq!(Command::Armw.addressing(), Addressing::Position);
        assert_eq!(Command::Frmw.addressing(), Addressing::Station);
        assert_eq!(Command::Lrw.addressing(), Addressing::Logical);
        assert_eq!(Command::Brw.addressing(), Addressing::Broadcast);
    }
}

//! Sync manager registers (0x0800 + 8·n): where a mailbox or a process-data buffer lives in
//! the process RAM, its direction, and who may access it.

/// Control byte, bits 0–1: mailbox (one buffer, full/empty handshake).
pub const MODE_MAILBOX: u8 = 0b10;
/// Control byte, bits 0–1: buffered (process data; the model keeps one buffer).
pub const MODE_BUFFERED: u8 = 0b00;
/// Status byte bit 3: the mailbox is full.
pub const STATUS_MAILBOX_FULL: u8 = 0x08;
/// Status byte bit 0: the master wrote the buffer (interrupt write).
pub const STATUS_WRITE_EVENT: u8 = 0x01;
/// Status byte bit 1: the master read the buffer (interrupt read).
pub const STATUS_READ_EVENT: u8 = 0x02;

/// Who writes the buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmDirection {
    /// The master reads (slave → master: inputs, the slave's send mailbox).
    MasterReads,
    /// The master writes (master → slave: outputs, the slave's receive mailbox).
    MasterWrites,
}

/// One sync manager's registers, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SyncManager {
    /// First byte of the buffer in the ESC memory.
    pub start: u16,
    /// Bytes of the buffer.
    pub length: u16,
    /// The control byte (mode, direction, interrupts, watchdog).
    pub control: u8,
    /// The status byte (read only for the master).
    pub status: u8,
    /// The activate byte (bit 0: enabled by the master).
    pub activate: u8,
    /// The PDI control byte (bit 0: deactivated by the slave's firmware).
    pub pdi_control: u8,
}

impl SyncManager {
    /// Decodes the 8 register bytes.
    pub fn decode(bytes: &[u8; 8]) -> Self {
        Self {
            start: u16::from_le_bytes([bytes[0], bytes[1]]),
            length: u16::from_le_bytes([bytes[2], bytes[3]]),
            control: bytes[4],
            status: bytes[5],
            activate: bytes[6],
            pdi_control: bytes[7],
        }
    }

    /// True if the master enabled it with a non-empty buffer.
    pub fn enabled(&self) -> bool {
        self.activate & 0x01 != 0 && self.length > 0
    }

    /// True if the slave's firmware deactivated it (then the master's accesses fail).
    pub fn deactivated_by_pdi(&self) -> bool {
        self.pdi_control & 0x01 != 0
    }

    /// True for the mailbox mode.
    pub fn is_mailbox(&self) -> bool {
        self.control & 0b11 == MODE_MAILBOX
    }

    /// The direction from the control byte.
    pub fn direction(&self) -> SmDirection {
        if (self.control >> 2) & 0b11 == 0b01 {
            SmDirection::MasterWrites
        } else {
            SmDirection::MasterReads
        }
    }

    /// True if the watchdog trigger is enabled (control bit 6).
    pub fn watchdog_enabled(&self) -> bool {
        self.control & 0x40 != 0
    }

    /// True if `address` is inside the buffer.
    pub fn contains(&self, address: usize) -> bool {
        let start = usize::from(self.start);
        address >= start && address < start + usize::from(self.length)
    }

    /// One past the last byte of the buffer.
    pub fn end(&self) -> usize {
        usize::from(self.start) + usize::from(self.length)
    }
}

//! The firmware's side of the ESC (the PDI): AL status, deactivating sync managers, the
//! mailbox handshake, raw memory access, and the DC sync settings it acts on.

use super::registers as reg;
use super::sync_manager::STATUS_MAILBOX_FULL;
use super::Esc;

impl Esc {
    /// AL status (0x0130).
    pub fn al_status(&self) -> u16 {
        self.get_u16(reg::AL_STATUS)
    }

    /// AL status code (0x0134).
    pub fn al_status_code(&self) -> u16 {
        self.get_u16(reg::AL_STATUS_CODE)
    }

    /// Sets AL status and status code, as the firmware does after a state request.
    pub fn set_al_status(&mut self, status: u16, code: u16) {
        self.put_u16(reg::AL_STATUS, status);
        self.put_u16(reg::AL_STATUS_CODE, code);
    }

    /// Deactivates (or reactivates) sync manager `n` from the firmware side (0x0807 bit 0):
    /// while deactivated the master's accesses to its buffer fail.
    pub fn set_sm_deactivated(&mut self, n: u8, deactivated: bool) {
        let at = usize::from(reg::SM_BASE + u16::from(n) * reg::SM_LEN + 7);
        if deactivated {
            self.mem[at] |= 0x01;
        } else {
            self.mem[at] &= !0x01;
        }
    }

    /// Reads memory without side effects.
    pub fn pdi_read(&self, address: u16, len: usize) -> &[u8] {
        let start = usize::from(address).min(reg::MEMORY_SIZE);
        let end = (start + len).min(reg::MEMORY_SIZE);
        &self.mem[start..end]
    }

    /// Writes memory without side effects (bytes past the memory are dropped).
    pub fn pdi_write(&mut self, address: u16, data: &[u8]) {
        let start = usize::from(address).min(reg::MEMORY_SIZE);
        let end = (start + data.len()).min(reg::MEMORY_SIZE);
        self.mem[start..end].copy_from_slice(&data[..end - start]);
    }

    /// Takes the request out of the full receive mailbox `sm` (and empties it).
    pub fn mailbox_take(&mut self, sm: u8) -> Option<Vec<u8>> {
        let config = self.sync_manager(sm);
        if config.status & STATUS_MAILBOX_FULL == 0 {
            return None;
        }
        let bytes = self
            .pdi_read(config.start, usize::from(config.length))
            .to_vec();
        self.mem[Self::sm_status_at(sm)] &= !STATUS_MAILBOX_FULL;
        Some(bytes)
    }

    /// Puts a reply into the send mailbox `sm` if it is enabled and empty; false otherwise.
    pub fn mailbox_put(&mut self, sm: u8, reply: &[u8]) -> bool {
        let config = self.sync_manager(sm);
        if !config.enabled() || config.status & STATUS_MAILBOX_FULL != 0 {
            return false;
        }
        let len = usize::from(config.length);
        let mut buffer = vec![0u8; len];
        let n = reply.len().min(len);
        buffer[..n].copy_from_slice(&reply[..n]);
        self.pdi_write(config.start, &buffer);
        self.mem[Self::sm_status_at(sm)] |= STATUS_MAILBOX_FULL;
        true
    }

    /// The SYNC0 cycle in ns if cyclic operation and SYNC0 are activated (0x0981 bits 0–1)
    /// with a non-zero cycle.
    pub fn sync0_cycle_ns(&self) -> Option<u32> {
        let activation = self.mem[usize::from(reg::DC_SYNC_ACTIVATION)];
        let cycle = u32::from_le_bytes(
            self.pdi_read(reg::DC_SYNC0_CYCLE, 4)
                .try_into()
                .unwrap_or([0; 4]),
        );
        (activation & 0x03 == 0x03 && cycle > 0).then_some(cycle)
    }

    /// The raw sync activation register (0x0981).
    pub fn sync_activation(&self) -> u8 {
        self.mem[usize::from(reg::DC_SYNC_ACTIVATION)]
    }

    /// The sync manager watchdog time in ns (0x0420 × (0x0400 + 2) × 40 ns); `None` if 0.
    pub fn sm_watchdog_ns(&self) -> Option<u64> {
        let divider = u64::from(self.get_u16(reg::WATCHDOG_DIVIDER));
        let time = u64::from(self.get_u16(reg::WATCHDOG_SM));
        (time > 0).then_some(time * (divider + 2) * 40)
    }

    /// Sets the watchdog status (0x0440 bit 0: 1 = running, 0 = expired).
    pub fn set_sm_watchdog_expired(&mut self, expired: bool) {
        let at = usize::from(reg::WATCHDOG_SM_STATUS);
        self.mem[at] = u8::from(!expired);
    }
}

//! One EtherCAT slave controller (ESC): its memory (4 KiB of registers and 8 KiB of process
//! RAM, like a Beckhoff ET1100) and the side effects of the master's accesses.
//!
//! The master's side ([`Esc::read`], [`Esc::write`], [`Esc::logical_write`],
//! [`Esc::logical_read`]) says whether an access succeeded, which is what the working counter
//! counts: an access fails on a mailbox that is full (write) or empty (read), on a sync
//! manager the slave's firmware deactivated, and outside the memory. What the firmware has to
//! react to (an AL control write, a mailbox that filled, an output buffer that was written)
//! is queued as an [`EscEvent`]. The firmware's side (the `pdi_*` and `set_*` methods) is
//! in [`pdi`] and used by [`crate::firmware`].

pub mod dc;
pub mod fmmu;
pub mod pdi;
pub mod registers;
pub mod sii_interface;
pub mod sync_manager;

use self::dc::{DcClock, PassTiming};
use self::fmmu::Fmmu;
use self::registers as reg;
use self::sii_interface::SiiInterface;
use self::sync_manager::{
    SmDirection, SyncManager, STATUS_MAILBOX_FULL, STATUS_READ_EVENT, STATUS_WRITE_EVENT,
};

/// Number of sync managers and FMMUs the model implements (an ET1100 has 8 of each; the
/// registers of 8..16 exist as plain memory so a master may blank them).
pub const CHANNELS: u8 = 8;

/// What the slave firmware must react to after an access of the master.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EscEvent {
    /// The master wrote AL control (the value now in 0x0120).
    AlControl(u16),
    /// A mailbox sync manager the master writes became full.
    MailboxReceived {
        /// The sync manager.
        sm: u8,
    },
    /// The master read the last byte of a full mailbox: it is empty again.
    MailboxRead {
        /// The sync manager.
        sm: u8,
    },
    /// The master wrote the last byte of a process-data buffer.
    BufferWritten {
        /// The sync manager.
        sm: u8,
    },
    /// The master read the last byte of a process-data buffer.
    BufferRead {
        /// The sync manager.
        sm: u8,
    },
}

/// The identity registers 0x0000–0x0009.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EscIdentity {
    /// 0x0000 type (0x11 for an ET1100).
    pub esc_type: u8,
    /// 0x0001 revision.
    pub revision: u8,
    /// 0x0002 build.
    pub build: u16,
    /// 0x0008 features: bit 2 DC, bit 3 64-bit DC, bit 8 enhanced DC sync, …
    pub features: u16,
}

impl Default for EscIdentity {
    fn default() -> Self {
        Self {
            esc_type: 0x11,
            revision: 0x00,
            build: 0x0003,
            // DC, 64-bit DC, low jitter, enhanced link detection (E-Bus, MII), separate FCS
            // handling, enhanced DC sync: what an ET1100 reports.
            features: 0x01FC,
        }
    }
}

/// One slave controller.
#[derive(Debug, Clone)]
pub struct Esc {
    /// Registers and process RAM.
    mem: Vec<u8>,
    /// The EEPROM and its interface registers.
    sii: SiiInterface,
    /// What 0x0000–0x0009 say.
    identity: EscIdentity,
    /// The local clock.
    clock: DcClock,
    /// True while a slave behind this one answers on port 1 (DL status, receive times).
    port1_link: bool,
    /// Events for the firmware, in order.
    events: Vec<EscEvent>,
    /// FMMUs 0..[`CHANNELS`] as their registers say, decoded when those are written: every
    /// logical datagram asks each of them, so a cyclic frame decodes none.
    fmmus: [Fmmu; CHANNELS as usize],
    /// The configured station address (0x0010), kept beside the memory: every slave compares
    /// it with every station-addressed datagram of a frame (ethercrab reads each slave's AL
    /// status by FPRD every cycle: 64 slaves, 64 × 64 compares).
    station: u16,
}

fn overlaps(start: usize, end: usize, register: u16, len: usize) -> bool {
    let register = usize::from(register);
    start < register + len && register < end
}

impl Esc {
    /// A controller powered on at chain time `now_ns`, with `eeprom` as its SII contents.
    pub fn new(identity: EscIdentity, eeprom: Vec<u8>, now_ns: u64) -> Self {
        let mut esc = Self {
            mem: vec![0; reg::MEMORY_SIZE],
            sii: SiiInterface::new(eeprom),
            identity,
            clock: DcClock::new(now_ns, 0.0),
            port1_link: false,
            events: Vec::new(),
            fmmus: [Fmmu::decode(&[0; 16]); CHANNELS as usize],
            station: 0,
        };
        esc.power_on(now_ns);
        esc
    }

    /// Power-on reset: memory cleared, identity and defaults loaded, AL status INIT.
    pub fn power_on(&mut self, now_ns: u64) {
        self.mem.fill(0);
        self.events.clear();
        // The crystal keeps its drift through a power cycle; the loop starts afresh.
        self.clock = DcClock::new(now_ns, self.clock.drift_ppm());
        let id = self.identity;
        self.mem[usize::from(reg::TYPE)] = id.esc_type;
        self.mem[usize::from(reg::REVISION)] = id.revision;
        self.put_u16(reg::BUILD, id.build);
        self.mem[usize::from(reg::FMMU_COUNT)] = CHANNELS;
        self.mem[usize::from(reg::SM_COUNT)] = CHANNELS;
        self.mem[usize::from(reg::RAM_SIZE)] = 8;
        // Ports 0 and 1 MII, 2 and 3 not implemented.
        self.mem[usize::from(reg::PORT_DESCRIPTOR)] = 0x0F;
        self.put_u16(reg::FEATURES, id.features);
        self.put_u16(reg::AL_STATUS, 0x0001);
        self.put_u16(reg::AL_CONTROL, 0x0001);
        self.put_u16(reg::WATCHDOG_DIVIDER, 0x09C2);
        self.put_u16(reg::WATCHDOG_PDI, 0x03E8);
        self.put_u16(reg::WATCHDOG_SM, 0x03E8);
        self.put_u16(reg::WATCHDOG_SM_STATUS, 0x0001);
        self.sii.power_on(&mut self.mem);
        self.mem[usize::from(reg::PDI_CONTROL)] = (self.sii.word(0) & 0xFF) as u8;
        // DC control loop parameters' reset values.
        self.put_u16(reg::DC_CONTROL_LOOP, 0x1000);
        self.put_u16(reg::DC_CONTROL_LOOP + 4, 0x0C00);
        self.refresh_dl_status();
        self.refresh_fmmus();
        self.station = self.get_u16(reg::STATION_ADDRESS);
    }

    /// Decodes the FMMU registers into the cache the logical datagrams use.
    fn refresh_fmmus(&mut self) {
        self.fmmus = std::array::from_fn(|n| self.fmmu(n as u8));
    }

    fn put_u16(&mut self, at: u16, value: u16) {
        let at = usize::from(at);
        self.mem[at..at + 2].copy_from_slice(&value.to_le_bytes());
    }

    fn get_u16(&self, at: u16) -> u16 {
        let at = usize::from(at);
        u16::from_le_bytes([self.mem[at], self.mem[at + 1]])
    }

    fn refresh_dl_status(&mut self) {
        // PDI operational, watchdog ok, port 0 link + communication, ports 2/3 loop closed.
        let mut status: u16 = 0x0003 | 0x0010 | 0x0200 | 0x1000 | 0x4000;
        if self.port1_link {
            status |= 0x0020 | 0x0800;
        } else {
            status |= 0x0400;
        }
        self.put_u16(reg::DL_STATUS, status);
    }

    /// The configured station address (0x0010).
    pub fn station_address(&self) -> u16 {
        self.station
    }

    /// Whether a slave behind this one answers on port 1.
    pub fn set_port1_link(&mut self, link: bool) {
        if self.port1_link != link {
            self.port1_link = link;
            self.refresh_dl_status();
        }
    }

    /// The local clock.
    pub fn clock(&self) -> DcClock {
        self.clock
    }

    /// The system time at chain time `global_ns`.
    pub fn system_time(&self, global_ns: u64) -> u64 {
        dc::system_time(&self.mem, self.clock.local(global_ns))
    }

    /// Lets the local clock's crystal run `drift_ppm` off from chain time `global_ns` on.
    pub fn set_clock_drift_ppm(&mut self, drift_ppm: f64, global_ns: u64) {
        self.clock.set_drift_ppm(drift_ppm, global_ns);
    }

    /// Where the slave is in its SYNC0 cycle at chain time `global_ns` (the time since its last
    /// SYNC0 pulse, on its own system time), ns; `None` while SYNC0 is not active or before its
    /// first pulse.
    pub fn sync0_phase_ns(&self, global_ns: u64) -> Option<u64> {
        let cycle = self.sync0_cycle_ns()?;
        dc::sync0_phase(&self.mem, self.system_time(global_ns), cycle)
    }

    /// The EEPROM.
    pub fn sii(&self) -> &SiiInterface {
        &self.sii
    }

    /// Sync manager `n`, decoded.
    pub fn sync_manager(&self, n: u8) -> SyncManager {
        let at = usize::from(reg::SM_BASE + u16::from(n) * reg::SM_LEN);
        let mut bytes = [0u8; 8];
        bytes.copy_from_slice(&self.mem[at..at + 8]);
        SyncManager::decode(&bytes)
    }

    /// FMMU `n`, decoded.
    pub fn fmmu(&self, n: u8) -> Fmmu {
        let at = usize::from(reg::FMMU_BASE + u16::from(n) * reg::FMMU_LEN);
        let mut bytes = [0u8; 16];
        bytes.copy_from_slice(&self.mem[at..at + 16]);
        Fmmu::decode(&bytes)
    }

    /// The events since the last call, oldest first (tests; the firmware takes them one by
    /// one with [`Esc::next_event`], which keeps the queue's buffer).
    pub fn take_events(&mut self) -> Vec<EscEvent> {
        std::mem::take(&mut self.events)
    }

    /// The oldest event not taken yet. The queue holds a frame's few events: taking from its
    /// front costs less than the allocation a fresh queue would.
    pub fn next_event(&mut self) -> Option<EscEvent> {
        if self.events.is_empty() {
            None
        } else {
            Some(self.events.remove(0))
        }
    }

    // ---- the master's side ------------------------------------------------------------

    /// A physical read of `out.len()` bytes at `address` (APRD/FPRD/BRD …). Bytes that cannot
    /// be read are left as they were. Returns true if at least one byte was read.
    pub fn read(&mut self, address: u16, out: &mut [u8], timing: &PassTiming) -> bool {
        let start = usize::from(address);
        let end = start + out.len();
        if start < usize::from(reg::PROCESS_RAM) {
            let local = self.clock.local(timing.port0_ns);
            if overlaps(start, end, reg::DC_SYSTEM_TIME, 8) {
                dc::materialize_system_time(&mut self.mem, local);
            }
        }
        let mut any = false;
        let mut at = start;
        while at < end {
            let (region, region_end) = self.region(at);
            let seg_end = region_end.min(end);
            let slice = &mut out[at - start..seg_end - start];
            any |= self.read_segment(region, at, slice);
            at = seg_end;
        }
        any
    }

    /// A physical write of `data` at `address` (APWR/FPWR/BWR …). Returns true if at least
    /// one byte was accepted (read-only registers count as accepted, as in the ESC).
    pub fn write(&mut self, address: u16, data: &[u8], timing: &PassTiming) -> bool {
        let start = usize::from(address);
        let end = start + data.len();
        let mut any = false;
        let mut at = start;
        while at < end {
            let (region, region_end) = self.region(at);
            let seg_end = region_end.min(end);
            any |= self.write_segment(region, at, &data[at - start..seg_end - start], timing);
            at = seg_end;
        }
        any
    }

    /// The write half of LWR/LRW: every enabled write FMMU that maps part of the datagram
    /// copies it to memory. Returns true if any byte was written.
    pub fn logical_write(&mut self, logical: u32, data: &[u8], timing: &PassTiming) -> bool {
        let mut any = false;
        let fmmus = self.fmmus;
        for fmmu in fmmus.iter().filter(|f| f.write) {
            if let Some((offset, physical, len)) = fmmu.overlap(logical, data.len()) {
                any |= self.write(physical, &data[offset..offset + len], timing);
            }
        }
        any
    }

    /// The read half of LRD/LRW: every enabled read FMMU that maps part of the datagram
    /// copies memory into it. Returns true if any byte was read.
    pub fn logical_read(&mut self, logical: u32, data: &mut [u8], timing: &PassTiming) -> bool {
        let mut any = false;
        let fmmus = self.fmmus;
        for fmmu in fmmus.iter().filter(|f| f.read) {
            if let Some((offset, physical, len)) = fmmu.overlap(logical, data.len()) {
                any |= self.read(physical, &mut data[offset..offset + len], timing);
            }
        }
        any
    }

    /// True if an enabled read (or write, per `write`) FMMU maps any byte of the datagram.
    pub fn logical_maps(&self, logical: u32, len: usize, write: bool) -> bool {
        self.fmmus.iter().any(|fmmu| {
            (if write { fmmu.write } else { fmmu.read }) && fmmu.overlap(logical, len).is_some()
        })
    }

    fn region(&self, at: usize) -> (Region, usize) {
        if at >= reg::MEMORY_SIZE {
            return (Region::Outside, usize::MAX);
        }
        if at < usize::from(reg::PROCESS_RAM) {
            return (Region::Registers, usize::from(reg::PROCESS_RAM));
        }
        let mut next_start = reg::MEMORY_SIZE;
        for n in 0..CHANNELS {
            let sm = self.sync_manager(n);
            if !sm.enabled() {
                continue;
            }
            if sm.contains(at) {
                return (Region::SyncManager(n), sm.end().min(reg::MEMORY_SIZE));
            }
            let start = usize::from(sm.start);
            if start > at {
                next_start = next_start.min(start);
            }
        }
        (Region::Ram, next_start)
    }

    fn sm_status_at(n: u8) -> usize {
        usize::from(reg::SM_BASE + u16::from(n) * reg::SM_LEN + 5)
    }

    fn read_segment(&mut self, region: Region, at: usize, out: &mut [u8]) -> bool {
        match region {
            Region::Outside => false,
            Region::Registers | Region::Ram => {
                out.copy_from_slice(&self.mem[at..at + out.len()]);
                true
            }
            Region::SyncManager(n) => {
                let sm = self.sync_manager(n);
                if sm.deactivated_by_pdi() {
                    return false;
                }
                let touches_last = at + out.len() == sm.end();
                if sm.is_mailbox() {
                    if sm.direction() == SmDirection::MasterReads {
                        if sm.status & STATUS_MAILBOX_FULL == 0 {
                            return false;
                        }
                        out.copy_from_slice(&self.mem[at..at + out.len()]);
                        if touches_last {
                            self.mem[Self::sm_status_at(n)] &= !STATUS_MAILBOX_FULL;
                            self.events.push(EscEvent::MailboxRead { sm: n });
                        }
                        return true;
                    }
                    out.copy_from_slice(&self.mem[at..at + out.len()]);
                    return true;
                }
                out.copy_from_slice(&self.mem[at..at + out.len()]);
                if touches_last && sm.direction() == SmDirection::MasterReads {
                    self.mem[Self::sm_status_at(n)] |= STATUS_READ_EVENT;
                    self.events.push(EscEvent::BufferRead { sm: n });
                }
                true
            }
        }
    }

    fn write_segment(
        &mut self,
        region: Region,
        at: usize,
        data: &[u8],
        timing: &PassTiming,
    ) -> bool {
        match region {
            Region::Outside => false,
            Region::Ram => {
                self.mem[at..at + data.len()].copy_from_slice(data);
                true
            }
            Region::Registers => {
                self.write_registers(at, data, timing);
                true
            }
            Region::SyncManager(n) => {
                let sm = self.sync_manager(n);
                if sm.deactivated_by_pdi() || sm.direction() == SmDirection::MasterReads {
                    return false;
                }
                let touches_last = at + data.len() == sm.end();
                if sm.is_mailbox() {
                    if sm.status & STATUS_MAILBOX_FULL != 0 {
                        return false;
                    }
                    self.mem[at..at + data.len()].copy_from_slice(data);
                    if touches_last {
                        self.mem[Self::sm_status_at(n)] |= STATUS_MAILBOX_FULL;
                        self.events.push(EscEvent::MailboxReceived { sm: n });
                    }
                    return true;
                }
                self.mem[at..at + data.len()].copy_from_slice(data);
                if touches_last {
                    self.mem[Self::sm_status_at(n)] |= STATUS_WRITE_EVENT;
                    self.events.push(EscEvent::BufferWritten { sm: n });
                }
                true
            }
        }
    }

    fn byte_writable(&self, address: usize) -> bool {
        let a = address as u16;
        if reg::READ_ONLY.iter().any(|&(s, e)| a >= s && a < e) {
            return false;
        }
        if (reg::SM_BASE..reg::SM_BASE + 16 * reg::SM_LEN).contains(&a) {
            let n = ((a - reg::SM_BASE) / reg::SM_LEN) as u8;
            let offset = (a - reg::SM_BASE) % reg::SM_LEN;
            return match offset {
                // Start, length and control only while the sync manager is disabled.
                0..=4 => self.sync_manager(n).activate & 0x01 == 0,
                5 | 7 => false,
                _ => true,
            };
        }
        true
    }

    fn write_registers(&mut self, start: usize, data: &[u8], timing: &PassTiming) {
        let end = start + data.len();
        let local = self.clock.local(timing.port0_ns);
        let sii_control_before = self.get_u16(reg::SII_CONTROL);
        let sm_activate_before: [u8; CHANNELS as usize] =
            std::array::from_fn(|n| self.sync_manager(n as u8).activate);
        // The system time register is not memory: a write is a value for the control loop.
        let mut system_time = dc::system_time(&self.mem, local).to_le_bytes();
        let mut system_time_written = [false; 8];
        for (i, &byte) in data.iter().enumerate() {
            let at = start + i;
            let sys = usize::from(reg::DC_SYSTEM_TIME);
            if (sys..sys + 8).contains(&at) {
                system_time[at - sys] = byte;
                system_time_written[at - sys] = true;
            } else if self.byte_writable(at) {
                self.mem[at] = byte;
            }
        }
        if overlaps(start, end, reg::DC_RECEIVE_TIME_PORT0, 4) {
            dc::latch_receive_times(&mut self.mem, &self.clock, timing);
        }
        if system_time_written.iter().any(|&w| w) {
            let only_low = !system_time_written[4..].iter().any(|&w| w);
            dc::on_system_time_written(
                &mut self.mem,
                &mut self.clock,
                timing.port0_ns,
                u64::from_le_bytes(system_time),
                only_low,
            );
        }
        if overlaps(start, end, reg::DC_CONTROL_LOOP, 6) {
            // Writing the control loop parameters resets the control unit and its filtered
            // difference (ethercrab writes them at init "so the DC control unit is reset").
            self.clock.reset_loop(timing.port0_ns);
            self.mem[usize::from(reg::DC_SYSTEM_TIME_DIFFERENCE)
                ..usize::from(reg::DC_SYSTEM_TIME_DIFFERENCE) + 4]
                .fill(0);
        }
        if overlaps(start, end, reg::SII_CONTROL, 2) {
            self.sii_control_written(sii_control_before);
        }
        for n in 0..CHANNELS {
            let activate_at = usize::from(reg::SM_BASE + u16::from(n) * reg::SM_LEN + 6);
            if (start..end).contains(&activate_at)
                && sm_activate_before[usize::from(n)] & 1 != self.mem[activate_at] & 1
            {
                // Enabling or disabling a sync manager resets its buffer state.
                self.mem[Self::sm_status_at(n)] = 0;
            }
        }
        if overlaps(
            start,
            end,
            reg::FMMU_BASE,
            usize::from(CHANNELS) * usize::from(reg::FMMU_LEN),
        ) {
            self.refresh_fmmus();
        }
        if overlaps(start, end, reg::STATION_ADDRESS, 2) {
            self.station = self.get_u16(reg::STATION_ADDRESS);
        }
        if overlaps(start, end, reg::AL_CONTROL, 2) {
            let value = self.get_u16(reg::AL_CONTROL);
            self.events.push(EscEvent::AlControl(value));
        }
    }

    fn sii_control_written(&mut self, before: u16) {
        self.sii.on_control_written(&mut self.mem, before);
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Region {
    Registers,
    Ram,
    SyncManager(u8),
    Outside,
}

#[cfg(test)]
mod tests;

//! Distributed clocks: the slave's 64-bit local clock, the receive-time latches, the system
//! time (local time + offset) and a drift control loop fed by writes to the system time.
//!
//! The local clock counts from the slave's power-on instant, read from the injected
//! [`crate::Clock`]. Within one frame every slave sees the frame at the instant the chain
//! computes for it (its position times the per-hop delay), so the latched receive times give
//! the master a consistent topology and propagation delay.

use super::registers::{
    DC_RECEIVE_TIME_PORT0, DC_RECEIVE_TIME_PORT1, DC_RECEIVE_TIME_PU, DC_SYSTEM_TIME,
    DC_SYSTEM_TIME_DELAY, DC_SYSTEM_TIME_DIFFERENCE, DC_SYSTEM_TIME_OFFSET,
};

/// The largest correction one system-time write applies to the offset. A real ESC slews its
/// clock speed instead; the model slews the offset, which converges the same way within the
/// master's static drift compensation.
pub const MAX_CORRECTION_NS: i64 = 1_000;

/// When a frame passes a slave, in the chain's clock (nanoseconds).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PassTiming {
    /// The frame enters port 0 (on its way out).
    pub port0_ns: u64,
    /// The frame comes back through port 1, if port 1 has a link.
    pub port1_ns: Option<u64>,
}

/// The local clock of one slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcClock {
    /// Chain clock at this slave's power-on: local time 0.
    pub power_on_ns: u64,
}

impl DcClock {
    /// Local time at chain time `global_ns`.
    pub fn local(&self, global_ns: u64) -> u64 {
        global_ns.wrapping_sub(self.power_on_ns)
    }
}

fn read_u64(mem: &[u8], at: u16) -> u64 {
    let at = usize::from(at);
    let mut bytes = [0u8; 8];
    bytes.copy_from_slice(&mem[at..at + 8]);
    u64::from_le_bytes(bytes)
}

fn read_u32(mem: &[u8], at: u16) -> u32 {
    let at = usize::from(at);
    u32::from_le_bytes([mem[at], mem[at + 1], mem[at + 2], mem[at + 3]])
}

fn write_bytes(mem: &mut [u8], at: u16, bytes: &[u8]) {
    let at = usize::from(at);
    mem[at..at + bytes.len()].copy_from_slice(bytes);
}

/// The system time (local time + offset) at local time `local`.
pub fn system_time(mem: &[u8], local: u64) -> u64 {
    local.wrapping_add(read_u64(mem, DC_SYSTEM_TIME_OFFSET))
}

/// Puts the current system time into 0x0910 before the master reads it.
pub fn materialize_system_time(mem: &mut [u8], local: u64) {
    let value = system_time(mem, local);
    write_bytes(mem, DC_SYSTEM_TIME, &value.to_le_bytes());
}

/// A write to 0x0900: latch the receive times of the frame on every port with a link.
pub fn latch_receive_times(mem: &mut [u8], clock: &DcClock, timing: &PassTiming) {
    let port0 = clock.local(timing.port0_ns);
    write_bytes(mem, DC_RECEIVE_TIME_PORT0, &(port0 as u32).to_le_bytes());
    let port1 = timing.port1_ns.map(|t| clock.local(t) as u32).unwrap_or(0);
    write_bytes(mem, DC_RECEIVE_TIME_PORT1, &port1.to_le_bytes());
    write_bytes(mem, DC_RECEIVE_TIME_PORT1 + 4, &[0; 8]);
    write_bytes(mem, DC_RECEIVE_TIME_PU, &port0.to_le_bytes());
}

/// A write to the system time: compare the received time (plus this slave's delay) with the
/// local copy, publish the difference in 0x092C and correct the offset towards it.
/// `written` holds the 8 bytes as written over the current value; `only_low` is true if the
/// master wrote the low 32 bits only (then the comparison is 32-bit).
pub fn on_system_time_written(mem: &mut [u8], local: u64, written: u64, only_low: bool) {
    let delay = u64::from(read_u32(mem, DC_SYSTEM_TIME_DELAY));
    let received = written.wrapping_add(delay);
    let own = system_time(mem, local);
    let difference: i64 = if only_low {
        i64::from((own as u32).wrapping_sub(received as u32) as i32)
    } else {
        own.wrapping_sub(received) as i64
    };
    let magnitude = difference.unsigned_abs().min(0x7FFF_FFFF) as u32;
    let register = if difference < 0 {
        magnitude | 0x8000_0000
    } else {
        magnitude
    };
    write_bytes(mem, DC_SYSTEM_TIME_DIFFERENCE, &register.to_le_bytes());
    let correction = difference.clamp(-MAX_CORRECTION_NS, MAX_CORRECTION_NS);
    let offset = read_u64(mem, DC_SYSTEM_TIME_OFFSET).wrapping_sub(correction as u64);
    write_bytes(mem, DC_SYSTEM_TIME_OFFSET, &offset.to_le_bytes());
}

//! Distributed clocks: the slave's 64-bit local clock, the receive-time latches, the system
//! time (local time + offset), the time control loop fed by writes to the system time, and
//! where the slave is in its SYNC0 cycle.
//!
//! The local clock counts from the slave's power-on instant, read from the injected
//! [`crate::Clock`] (the chain's time, the "real" time of the model). Its crystal may run off
//! by a few ppm ([`DcClock::set_drift_ppm`], 0 by default), as real ones do (±100 ppm is a common
//! crystal's tolerance). Within one frame every slave sees the frame at the instant the chain
//! computes for it (its position times the per-hop delay), so the latched receive times give
//! the master a consistent topology and propagation delay.
//!
//! ## The time control loop
//!
//! As in an ESC (Beckhoff ESC datasheet section I, "Distributed Clocks": system time
//! difference, drift compensation), a write of the system time (0x0910) is not stored: the
//! ESC compares the value written plus its delay (0x0928) with its own copy of the system
//! time, publishes the difference in 0x092C, and corrects the *speed* of its clock (never its
//! offset 0x0920, which is the master's), bounded: the control loop's output, the clock's
//! speed correction, stays within ±[`MAX_SPEED_PPM`] + ±[`MAX_SLEW_PPM`]. The model's loop is
//! a PI controller: each write replaces the phase still to correct with a fraction
//! ([`PHASE_GAIN`]) of the difference, slewed in at most [`MAX_SLEW_PPM`], and integrates the
//! difference (clamped to ±[`LOOP_CLAMP_NS`], so one late frame cannot throw the clock's
//! speed) into a lasting frequency correction ([`FREQUENCY_GAIN`]) that cancels the
//! crystal's drift. With one write per 1 ms cycle it settles in a few hundred cycles and has no
//! steady-state error. Writing the control loop parameters (0x0930) resets the loop, as in
//! the ESC. The FRMW of the master's every cycle writes the reference clock's time into every
//! other slave: each one's loop follows the reference; a write into the reference clock
//! itself (the master's time, IgH's "sync the reference clock to the application time")
//! makes the reference follow the master.

use super::registers::{
    DC_RECEIVE_TIME_PORT0, DC_RECEIVE_TIME_PORT1, DC_RECEIVE_TIME_PU, DC_START_TIME,
    DC_SYSTEM_TIME, DC_SYSTEM_TIME_DELAY, DC_SYSTEM_TIME_DIFFERENCE, DC_SYSTEM_TIME_OFFSET,
};

/// The largest lasting speed correction of the loop (the frequency it learnt), ppm.
pub const MAX_SPEED_PPM: f64 = 500.0;
/// The fastest a phase correction is slewed in, ppm of the clock's speed.
pub const MAX_SLEW_PPM: f64 = 500.0;
/// The fraction of a difference the loop corrects in phase before the next write.
pub const PHASE_GAIN: f64 = 0.1;
/// The loop's integral gain, per ns² (difference × interval): 2.5e-15 gives, at one write per
/// millisecond, a critically damped loop with a time constant of about 20 ms (10 writes).
pub const FREQUENCY_GAIN: f64 = 2.5e-15;
/// The largest difference the loop's integral takes from one write, ns.
pub const LOOP_CLAMP_NS: i64 = 50_000;
/// The longest interval between two writes the integral counts, ns.
const LOOP_INTERVAL_MAX_NS: u64 = 20_000_000;

/// When a frame passes a slave, in the chain's clock (nanoseconds).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PassTiming {
    /// The frame enters port 0 (on its way out).
    pub port0_ns: u64,
    /// The frame comes back through port 1, if port 1 has a link.
    pub port1_ns: Option<u64>,
}

/// The local clock of one slave: its crystal (with its drift) and the speed its time control
/// loop gives it. Local time is a pure function of the chain's time between two writes of the
/// system time: the clock is re-anchored at each write (and at a change of drift).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DcClock {
    /// Chain time of the anchor.
    anchor_ns: u64,
    /// Local time at the anchor.
    anchor_local: u64,
    /// The crystal's error, ppm (positive runs fast).
    drift_ppm: f64,
    /// The loop's lasting speed correction (the frequency it learnt).
    speed: f64,
    /// Phase the loop still slews in, ns (signed).
    pending_ns: f64,
    /// Chain time of the last system time write (the loop's interval).
    last_write_ns: Option<u64>,
}

impl DcClock {
    /// A clock powered on at chain time `power_on_ns` (local time 0 then), with the crystal's
    /// `drift_ppm`.
    pub fn new(power_on_ns: u64, drift_ppm: f64) -> Self {
        Self {
            anchor_ns: power_on_ns,
            anchor_local: 0,
            drift_ppm,
            speed: 0.0,
            pending_ns: 0.0,
            last_write_ns: None,
        }
    }

    /// The crystal's drift, ppm.
    pub fn drift_ppm(&self) -> f64 {
        self.drift_ppm
    }

    /// The loop's lasting speed correction, ppm (what it learnt of the drift, with the sign
    /// that cancels it).
    pub fn speed_correction_ppm(&self) -> f64 {
        self.speed * 1e6
    }

    /// Sets the crystal's drift from chain time `global_ns` on.
    pub fn set_drift_ppm(&mut self, drift_ppm: f64, global_ns: u64) {
        self.anchor_at(global_ns);
        self.drift_ppm = drift_ppm;
    }

    /// The phase slewed in over `elapsed_ns` after the anchor.
    fn slewed(&self, elapsed_ns: f64) -> f64 {
        let most = MAX_SLEW_PPM * 1e-6 * elapsed_ns;
        self.pending_ns.signum() * self.pending_ns.abs().min(most)
    }

    /// Local time at chain time `global_ns`.
    pub fn local(&self, global_ns: u64) -> u64 {
        let elapsed = i128::from(global_ns) - i128::from(self.anchor_ns);
        let elapsed_f = elapsed as f64;
        let extra = elapsed_f * (self.drift_ppm * 1e-6 + self.speed)
            + if elapsed > 0 {
                self.slewed(elapsed_f)
            } else {
                0.0
            };
        let local = i128::from(self.anchor_local) + elapsed + extra.round() as i128;
        local.clamp(0, i128::from(u64::MAX)) as u64
    }

    /// Moves the anchor to chain time `global_ns` (only forwards), consuming the phase
    /// slewed in since the last one.
    fn anchor_at(&mut self, global_ns: u64) {
        if global_ns <= self.anchor_ns {
            return;
        }
        let local = self.local(global_ns);
        self.pending_ns -= self.slewed((global_ns - self.anchor_ns) as f64);
        self.anchor_local = local;
        self.anchor_ns = global_ns;
    }

    /// The loop's answer to a difference (own copy − received, ns) found at chain time
    /// `global_ns`.
    fn steer(&mut self, difference: i64, global_ns: u64) {
        self.anchor_at(global_ns);
        let clamped = difference.clamp(-LOOP_CLAMP_NS, LOOP_CLAMP_NS) as f64;
        let interval = self
            .last_write_ns
            .map_or(0, |last| global_ns.saturating_sub(last))
            .min(LOOP_INTERVAL_MAX_NS) as f64;
        self.last_write_ns = Some(global_ns);
        // A new write replaces the phase still to slew in: the difference already holds it.
        self.pending_ns = -PHASE_GAIN * difference as f64;
        let most = MAX_SPEED_PPM * 1e-6;
        self.speed = (self.speed - FREQUENCY_GAIN * clamped * interval).clamp(-most, most);
    }

    /// Writing the control loop parameters resets the loop (the crystal stays as it is).
    pub fn reset_loop(&mut self, global_ns: u64) {
        self.anchor_at(global_ns);
        self.speed = 0.0;
        self.pending_ns = 0.0;
        self.last_write_ns = None;
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

/// Where system time `system` is in the SYNC0 cycle of `cycle_ns` that starts at 0x0990:
/// the time since the last SYNC0 pulse, ns; `None` before the first pulse.
pub fn sync0_phase(mem: &[u8], system: u64, cycle_ns: u32) -> Option<u64> {
    let start = read_u64(mem, DC_START_TIME);
    (system >= start && cycle_ns > 0).then(|| (system - start) % u64::from(cycle_ns))
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

/// A write to the system time at chain time `global_ns`: compare the received time (plus
/// this slave's delay) with the local copy, publish the difference in 0x092C and steer the
/// clock's speed towards it (see the module's doc). `written` holds the 8 bytes as written
/// over the current value; `only_low` is true if the master wrote the low 32 bits only (then
/// the comparison is 32-bit).
pub fn on_system_time_written(
    mem: &mut [u8],
    clock: &mut DcClock,
    global_ns: u64,
    written: u64,
    only_low: bool,
) {
    let delay = u64::from(read_u32(mem, DC_SYSTEM_TIME_DELAY));
    let received = written.wrapping_add(delay);
    let own = system_time(mem, clock.local(global_ns));
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
    clock.steer(difference, global_ns);
}

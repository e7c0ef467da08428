//! A line of slaves, as on a cable: a frame passes every reachable slave in order, each
//! processing every datagram, and comes back with the locally administered bit set in its
//! source MAC. Faults: a slave that loses power (it and those behind it vanish; it comes back
//! in INIT), and lost frames.

use std::any::Any;

use crate::application::Application;
use crate::clock::Clock;
use crate::esc::dc::PassTiming;
use crate::frame::{self, DatagramSpan, FrameError};
use crate::slave::Slave;

/// What became of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reply {
    /// The buffer now holds the processed frame: send it back to the master.
    Frame,
    /// The frame was lost (fault injection, or no slave reachable): send nothing.
    Lost,
}

/// Timing of the line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainConfig {
    /// Delay from one slave's port 0 to the next one's (cable, PHYs, forwarding), in ns.
    pub hop_delay_ns: u64,
    /// Application step period while DC SYNC0 is not active, in seconds.
    pub default_period_s: f64,
}

impl Default for ChainConfig {
    fn default() -> Self {
        Self {
            hop_delay_ns: 700,
            default_period_s: 0.001,
        }
    }
}

/// The slaves of one line and the faults injected into it.
pub struct Chain {
    /// The slaves, in cable order.
    slaves: Vec<Slave>,
    /// Whether each slave has power.
    powered: Vec<bool>,
    /// The time source of every local clock.
    clock: Box<dyn Clock>,
    /// Line timing.
    config: ChainConfig,
    /// Frames still to drop.
    frames_to_lose: u32,
    /// Datagram positions of the frame being processed (kept to reuse the allocation).
    spans: Vec<DatagramSpan>,
    /// Frames processed since creation.
    frames: u64,
}

impl std::fmt::Debug for Chain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Chain")
            .field("slaves", &self.slaves)
            .field("powered", &self.powered)
            .field("config", &self.config)
            .field("frames", &self.frames)
            .finish()
    }
}

impl Chain {
    /// A line of `slaves` whose local clocks read `clock`; every slave is powered on now.
    pub fn new(slaves: Vec<Slave>, clock: impl Clock + 'static) -> Self {
        Self::with_config(slaves, clock, ChainConfig::default())
    }

    /// As [`Chain::new`], with the line's timing.
    pub fn with_config(
        mut slaves: Vec<Slave>,
        clock: impl Clock + 'static,
        config: ChainConfig,
    ) -> Self {
        let now = clock.now_ns();
        for slave in &mut slaves {
            slave.set_default_period(config.default_period_s);
            slave.power_on(now);
        }
        let powered = vec![true; slaves.len()];
        Self {
            slaves,
            powered,
            clock: Box::new(clock),
            config,
            frames_to_lose: 0,
            spans: Vec::new(),
            frames: 0,
        }
    }

    /// Number of slaves (reachable or not).
    pub fn len(&self) -> usize {
        self.slaves.len()
    }

    /// True for a chain without slaves.
    pub fn is_empty(&self) -> bool {
        self.slaves.is_empty()
    }

    /// Slaves a frame reaches: those before the first one without power.
    pub fn reachable(&self) -> usize {
        self.powered
            .iter()
            .position(|p| !p)
            .unwrap_or(self.slaves.len())
    }

    /// The slave at `position`.
    pub fn slave(&self, position: usize) -> Option<&Slave> {
        self.slaves.get(position)
    }

    /// The slave at `position`, writable.
    pub fn slave_mut(&mut self, position: usize) -> Option<&mut Slave> {
        self.slaves.get_mut(position)
    }

    /// The application of the slave at `position` (to inject a device fault).
    pub fn application_mut(&mut self, position: usize) -> Option<&mut dyn Application> {
        self.slaves.get_mut(position).map(|s| s.application_mut())
    }

    /// The application of the slave at `position` as its concrete type.
    pub fn application_as<T: Application + Any>(&mut self, position: usize) -> Option<&mut T> {
        self.slaves.get_mut(position)?.application_as::<T>()
    }

    /// Frames processed so far.
    pub fn frames_processed(&self) -> u64 {
        self.frames
    }

    /// The slave at `position` loses power: it and every slave behind it stop answering, as
    /// behind a cut cable; frames come back processed by the slaves before it only.
    pub fn power_off(&mut self, position: usize) {
        if let Some(p) = self.powered.get_mut(position) {
            *p = false;
        }
    }

    /// The slave at `position` gets power back and starts as after power-on: INIT, station
    /// address 0, default dictionary.
    pub fn power_on(&mut self, position: usize) {
        let now = self.clock.now_ns();
        if let (Some(p), Some(slave)) = (
            self.powered.get_mut(position),
            self.slaves.get_mut(position),
        ) {
            if !*p {
                *p = true;
                slave.power_on(now);
            }
        }
    }

    /// The crystal of the slave at `position` runs `drift_ppm` off from now on (positive:
    /// fast); 0 by default. Its time control loop, fed by the master's writes of the system
    /// time, corrects it as an ESC does.
    pub fn set_clock_drift_ppm(&mut self, position: usize, drift_ppm: f64) {
        let now = self.clock.now_ns();
        if let Some(slave) = self.slaves.get_mut(position) {
            slave.esc.set_clock_drift_ppm(drift_ppm, now);
        }
    }

    /// The next `count` frames are lost on their way out: not processed, no reply.
    pub fn lose_next_frames(&mut self, count: u32) {
        self.frames_to_lose = self.frames_to_lose.saturating_add(count);
    }

    /// Processes one Ethernet frame in place: every reachable slave, in order, handles every
    /// datagram; the source MAC gets the locally administered bit.
    pub fn process(&mut self, frame: &mut [u8]) -> Result<Reply, FrameError> {
        frame::decode(frame, &mut self.spans)?;
        if self.frames_to_lose > 0 {
            self.frames_to_lose -= 1;
            tracing::debug!("frame lost (injected)");
            return Ok(Reply::Lost);
        }
        let reachable = self.reachable();
        if reachable == 0 {
            return Ok(Reply::Lost);
        }
        self.frames += 1;
        let now = self.clock.now_ns();
        let hop = self.config.hop_delay_ns;
        let last = reachable as u64 - 1;
        for (position, slave) in self.slaves.iter_mut().take(reachable).enumerate() {
            let i = position as u64;
            let has_next = i < last;
            let timing = PassTiming {
                port0_ns: now + i * hop,
                port1_ns: has_next.then(|| now + (2 * last - i) * hop),
            };
            slave.esc.set_port1_link(has_next);
            slave.begin_frame(timing.port0_ns);
            for &span in &self.spans {
                // Read per datagram: one of the frame's may have just set it.
                if span
                    .only_for_station
                    .is_some_and(|s| s != slave.station_address())
                {
                    continue;
                }
                if let Some(mut datagram) = frame::datagram_at(frame, span) {
                    slave.process(&mut datagram, &timing);
                }
            }
        }
        frame::mark_source_mac(frame);
        Ok(Reply::Frame)
    }
}

//! The bus bridge: the backend's drives, served every base tick by the grid, with a watchdog of
//! its own.
//!
//! Each release of the grid's `bus` component is one bus cycle: the commands of the tick go to
//! the drives and their actuals come back. The bridge process checks between releases: when
//! no release came for [`LOST_AFTER`] base periods the coordinator is lost, and the bridge
//! brings every drive to a safe stop (quick stop) and keeps cycling the bus on its own clock,
//! so the drives decelerate and report it. The drives stay latched in quick stop until they are
//! sent disable voltage (CiA 402 transition 12) and enabled again; the ledger records when
//! the stop happened.

use std::sync::{Arc, Mutex, OnceLock};

use super::backend::{AxisActual, AxisCommand, Backend};
use super::cia402::DriveState;

/// Base periods without a release after which the coordinator counts as lost.
pub const LOST_AFTER: u64 = 3;

/// Why the drives were stopped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SafeStop {
    pub reason: String,
    /// The bus cycle at which quick stop was commanded.
    pub at_cycle: u64,
}

/// The drives and their bookkeeping.
pub struct Bridge {
    backend: Box<dyn Backend>,
    commands: Vec<AxisCommand>,
    actuals: Vec<AxisActual>,
    period_ns: u64,
    /// Bus cycles run (by the grid or by the watchdog).
    pub cycles: u64,
    /// Base periods in which the grid did not serve the bus.
    pub missed: u64,
    /// When the last cycle ran, ns of CLOCK_MONOTONIC (0: never).
    last_cycle_ns: u64,
    /// When the grid last served the bus.
    last_release_ns: u64,
    pub safe_stop: Option<SafeStop>,
}

impl Bridge {
    pub fn new(backend: Box<dyn Backend>, period_ns: u64) -> Bridge {
        let n = backend.axes();
        Bridge {
            backend,
            commands: vec![AxisCommand::default(); n],
            actuals: vec![AxisActual::default(); n],
            period_ns: period_ns.max(1),
            cycles: 0,
            missed: 0,
            last_cycle_ns: 0,
            last_release_ns: 0,
            safe_stop: None,
        }
    }

    pub fn axes(&self) -> usize {
        self.commands.len()
    }

    /// One cycle served by the grid at `now_ns`: `commands` go out, the actuals come back.
    pub fn serve(&mut self, now_ns: u64, commands: impl Fn(usize) -> AxisCommand) -> &[AxisActual] {
        if self.last_release_ns != 0 {
            let gap = now_ns.saturating_sub(self.last_release_ns);
            self.missed += ((gap + self.period_ns / 2) / self.period_ns).saturating_sub(1);
        }
        self.last_release_ns = now_ns;
        if self.safe_stop.is_none() {
            for (i, c) in self.commands.iter_mut().enumerate() {
                *c = commands(i);
            }
        }
        self.cycle(now_ns);
        &self.actuals
    }

    fn cycle(&mut self, now_ns: u64) {
        let dt = self.period_ns as f64 * 1e-9;
        self.backend.cycle(dt, &self.commands, &mut self.actuals);
        self.cycles += 1;
        self.last_cycle_ns = now_ns;
    }

    /// Called between releases: after [`LOST_AFTER`] periods without one, stops the drives and
    /// cycles the bus on its own every period. Returns whether it cycled.
    pub fn watch(&mut self, now_ns: u64) -> bool {
        if self.last_release_ns == 0 {
            return false; // the grid has not started serving the bus yet
        }
        let silent = now_ns.saturating_sub(self.last_release_ns);
        if silent < LOST_AFTER * self.period_ns {
            return false;
        }
        if self.safe_stop.is_none() {
            self.stop(format!(
                "coordinator lost: no tick for {} base periods",
                silent / self.period_ns
            ));
        }
        if now_ns.saturating_sub(self.last_cycle_ns) >= self.period_ns {
            self.cycle(now_ns);
            return true;
        }
        false
    }

    /// Commands quick stop to every drive and holds it.
    pub fn stop(&mut self, reason: String) {
        tracing::error!("safe stop: {reason}");
        self.backend.quick_stop_all();
        self.safe_stop = Some(SafeStop {
            reason,
            at_cycle: self.cycles,
        });
    }

    /// The bus ledger, as `modbot bus` prints it.
    pub fn ledger(&self) -> String {
        let mut out = format!(
            "bus {}  axes {}  cycles {}  missed {}  {}\n",
            self.backend.name(),
            self.axes(),
            self.cycles,
            self.missed,
            match &self.safe_stop {
                Some(s) => format!("SAFE STOP at cycle {}: {}", s.at_cycle, s.reason),
                None => "running".to_owned(),
            }
        );
        out.push_str("AXIS  STATE                    MODE  STATUSWORD  POSITION     VELOCITY\n");
        for (i, a) in self.actuals.iter().enumerate() {
            out.push_str(&format!(
                "{:>4}  {:<24} {:>4}  0x{:04x}      {:>10.4}  {:>10.4}\n",
                i,
                a.state.to_string(),
                a.mode,
                a.statusword,
                a.motor_position,
                a.motor_velocity
            ));
        }
        out
    }

    /// Every drive's state.
    pub fn states(&self) -> Vec<DriveState> {
        self.actuals.iter().map(|a| a.state).collect()
    }
}

/// The bridge of this process, when it is the bus bridge process: the grid's `bus` component
/// then drives it instead of a private simulation.
pub fn process_bridge() -> &'static OnceLock<Arc<Mutex<Bridge>>> {
    static BRIDGE: OnceLock<Arc<Mutex<Bridge>>> = OnceLock::new();
    &BRIDGE
}

/// Locks the bridge, whoever panicked while holding it.
pub fn lock(bridge: &Mutex<Bridge>) -> std::sync::MutexGuard<'_, Bridge> {
    bridge.lock().unwrap_or_else(|p| p.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::plant::PlantParams;
    use crate::bus::sim::SimBackend;

    const MS: u64 = 1_000_000;

    fn enabled(sut: &mut Bridge, t: &mut u64) {
        for cw in [0x06u16, 0x07, 0x0f, 0x0f, 0x0f] {
            *t += MS;
            sut.serve(*t, |_| AxisCommand {
                controlword: cw,
                mode: 8,
                ..Default::default()
            });
        }
    }

    #[test]
    fn a_lost_coordinator_quick_stops_every_drive_within_three_periods() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(6, PlantParams::default())), MS);
        let mut t = 1_000 * MS;
        enabled(&mut sut, &mut t);
        assert!(
            sut.states()
                .iter()
                .all(|s| *s == DriveState::OperationEnabled),
            "{:?}",
            sut.states()
        );
        let last = t;
        let mut stopped_at = None;
        for k in 1..=10 {
            t = last + k * MS;
            sut.watch(t);
            if stopped_at.is_none()
                && sut
                    .states()
                    .iter()
                    .all(|s| *s == DriveState::QuickStopActive)
            {
                stopped_at = Some(k);
            }
        }
        assert_eq!(stopped_at, Some(LOST_AFTER), "{}", sut.ledger());
        assert!(sut.ledger().contains("SAFE STOP"), "{}", sut.ledger());
    }

    #[test]
    fn a_served_bus_counts_the_periods_it_missed() {
        let mut sut = Bridge::new(Box::new(SimBackend::new(1, PlantParams::default())), MS);
        sut.serve(10 * MS, |_| AxisCommand::default());
        sut.serve(11 * MS, |_| AxisCommand::default());
        sut.serve(14 * MS, |_| AxisCommand::default());
        assert_eq!((sut.cycles, sut.missed), (3, 2));
    }
}

//! Simulated time shared by every process of a system.
//!
//! `modbot up` reads CLOCK_MONOTONIC once when it starts a system and passes that instant to
//! every module as `MODBOT_EPOCH_NS` (the same value to modules restarted later). A module
//! that simulates something (a plant, a sonar, a robot moving) computes its simulated time
//! from that epoch and the injected clock ([`crate::Ctx::now_ns`], which is CLOCK_MONOTONIC
//! by default): so all modules of a system agree on "t = 12.5 s" without exchanging a message,
//! and a restarted module continues the system's time instead of starting again at 0.
//!
//! `MODBOT_SIM_SPEED` (set in a module's `env` in the description, or in `modbot up`'s own
//! environment) runs the simulation faster or slower than real time: at speed 2, one real
//! second is two simulated seconds.
//!
//! ```
//! use modbot_core::sim::SimTime;
//! let sim = SimTime::new(1_000_000_000, 2.0);
//! assert_eq!(sim.seconds(1_500_000_000), 1.0);
//! assert_eq!(sim.sim_dt(10_000_000), 0.02);
//! ```

use crate::clock::{Clock, MonotonicClock};
use crate::transport::launch as env;

/// A system's simulated time: an epoch on CLOCK_MONOTONIC and a speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimTime {
    /// When the system started, ns of CLOCK_MONOTONIC: simulated time 0.
    epoch_ns: u64,
    /// Simulated seconds per real second; finite and > 0.
    speed: f64,
}

impl SimTime {
    /// Simulated time from `epoch_ns` at `speed`; a speed that is not finite and > 0 is 1.
    pub fn new(epoch_ns: u64, speed: f64) -> SimTime {
        SimTime {
            epoch_ns,
            speed: if valid_speed(speed) { speed } else { 1.0 },
        }
    }

    /// This process's simulated time: the epoch from `MODBOT_EPOCH_NS` (else now), the speed
    /// from `MODBOT_SIM_SPEED` (else 1). A malformed value is a warning in the log, and the
    /// default is used.
    pub fn from_env() -> SimTime {
        let epoch = std::env::var(env::EPOCH_NS).ok();
        let speed = std::env::var(env::SIM_SPEED).ok();
        let (sim, warnings) =
            SimTime::parse(epoch.as_deref(), speed.as_deref(), MonotonicClock.now_ns());
        for w in warnings {
            tracing::warn!("{w}");
        }
        sim
    }

    /// What [`SimTime::from_env`] does with the two variables' values (`None`: not set), with
    /// `now_ns` as the fallback epoch; returns the time and a warning per malformed value.
    pub fn parse(epoch: Option<&str>, speed: Option<&str>, now_ns: u64) -> (SimTime, Vec<String>) {
        let mut warnings = Vec::new();
        let epoch_ns = match epoch.map(str::trim) {
            None => now_ns,
            Some(text) => text.parse::<u64>().unwrap_or_else(|_| {
                warnings.push(format!(
                    "{}={text:?} is not a number of nanoseconds: simulated time starts now",
                    env::EPOCH_NS
                ));
                now_ns
            }),
        };
        let speed = match speed.map(str::trim) {
            None => 1.0,
            Some(text) => match text.parse::<f64>() {
                Ok(s) if valid_speed(s) => s,
                _ => {
                    warnings.push(format!(
                        "{}={text:?} is not a speed (a finite number > 0): running at speed 1",
                        env::SIM_SPEED
                    ));
                    1.0
                }
            },
        };
        (SimTime { epoch_ns, speed }, warnings)
    }

    /// The epoch, ns of CLOCK_MONOTONIC.
    pub fn epoch_ns(&self) -> u64 {
        self.epoch_ns
    }

    /// Simulated seconds per real second.
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// Simulated seconds since the epoch at `now_ns` (CLOCK_MONOTONIC): `(now - epoch) *
    /// speed`; negative before the epoch.
    pub fn seconds(&self, now_ns: u64) -> f64 {
        let real = if now_ns >= self.epoch_ns {
            (now_ns - self.epoch_ns) as f64
        } else {
            -((self.epoch_ns - now_ns) as f64)
        };
        real / 1e9 * self.speed
    }

    /// The simulated seconds that pass in `real_dt_ns` real nanoseconds.
    pub fn sim_dt(&self, real_dt_ns: u64) -> f64 {
        real_dt_ns as f64 / 1e9 * self.speed
    }
}

fn valid_speed(s: f64) -> bool {
    s.is_finite() && s > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    const SEC: u64 = 1_000_000_000;

    #[test]
    fn simulated_seconds_count_from_the_epoch_at_the_speed() {
        let sut = SimTime::new(100 * SEC, 1.0);
        assert_eq!(sut.seconds(100 * SEC), 0.0);
        assert_eq!(sut.seconds(112 * SEC + SEC / 2), 12.5);
        assert_eq!(sut.seconds(99 * SEC), -1.0, "before the epoch");
        let fast = SimTime::new(100 * SEC, 4.0);
        assert_eq!(fast.seconds(103 * SEC), 12.0);
        assert_eq!(fast.speed(), 4.0);
        assert_eq!(fast.epoch_ns(), 100 * SEC);
    }

    #[test]
    fn a_real_step_becomes_a_simulated_step() {
        assert_eq!(SimTime::new(0, 1.0).sim_dt(10_000_000), 0.01);
        assert_eq!(SimTime::new(0, 0.5).sim_dt(SEC), 0.5);
        assert_eq!(SimTime::new(0, 3.0).sim_dt(0), 0.0);
    }

    #[test]
    fn two_processes_with_the_same_epoch_agree_whenever_they_started() {
        let epoch = 5 * SEC;
        let (first, _) = SimTime::parse(Some("5000000000"), None, 6 * SEC);
        let (restarted, _) = SimTime::parse(Some("5000000000"), None, 60 * SEC);
        assert_eq!(first.seconds(70 * SEC), restarted.seconds(70 * SEC));
        assert_eq!(first.epoch_ns(), epoch);
    }

    #[test]
    fn the_parser_takes_defaults_and_warns_about_malformed_values() {
        let now = 42 * SEC;
        assert_eq!(
            SimTime::parse(None, None, now),
            (SimTime::new(now, 1.0), vec![])
        );
        assert_eq!(
            SimTime::parse(Some(" 7 "), Some("2.5"), now),
            (SimTime::new(7, 2.5), vec![])
        );
        for bad in ["0", "-1", "inf", "NaN", "fast", ""] {
            let (sut, warnings) = SimTime::parse(Some("7"), Some(bad), now);
            assert_eq!(sut.speed(), 1.0, "speed {bad:?}");
            assert_eq!(warnings.len(), 1, "speed {bad:?}");
            assert!(warnings[0].contains("MODBOT_SIM_SPEED"), "{warnings:?}");
        }
        let (sut, warnings) = SimTime::parse(Some("-3"), None, now);
        assert_eq!(sut.epoch_ns(), now, "a malformed epoch falls back to now");
        assert!(warnings[0].contains("MODBOT_EPOCH_NS"), "{warnings:?}");
        assert_eq!(SimTime::new(0, f64::NAN).speed(), 1.0);
    }
}

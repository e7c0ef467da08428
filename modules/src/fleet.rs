//! A sensor fleet: many small sensor modules that report a reading to an aggregator each
//! period, and aggregators that keep the latest reading of every sensor that reports to them.
//! It is the system to run at the MRA's full address space (`examples/fleet.lua`).
//!
//! - A sensor reads a simulated temperature (a slow sine, its phase set by its address, so
//!   every sensor reads differently), keeps it on its blackboard (`value`), answers `read()`
//!   with a reading taken then,
//!   and sends it as a REPORT (topic [`READING_TOPIC`]) to its aggregator every period.
//! - An aggregator answers `summary()` with (sensors heard, mean, min, max, reports received)
//!   and keeps the same on its blackboard.

use std::collections::BTreeMap;

use modbot_core::module::Report;
use modbot_core::{Ctx, MethodError, Reply};
use modbot_ipc_schema::{Addr, Value};

/// The topic of a sensor's reading.
pub const READING_TOPIC: u8 = 1;

/// A sensor's state.
#[derive(Debug)]
pub struct Sensor {
    /// The module it reports to.
    pub aggregator: String,
    /// Its latest reading.
    pub value: f64,
    /// Reports that could not be sent (the aggregator was down, say).
    pub unsent: u64,
}

impl Sensor {
    pub fn new(aggregator: &str) -> Sensor {
        Sensor {
            aggregator: aggregator.to_owned(),
            value: f64::NAN,
            unsent: 0,
        }
    }
}

/// The simulated temperature at `t_s` seconds of the sensor at `addr`: 20 °C ± 5 over a
/// minute, phase by address.
pub fn temperature(addr: Addr, t_s: f64) -> f64 {
    20.0 + 5.0 * (core::f64::consts::TAU * t_s / 60.0 + f64::from(addr.0)).sin()
}

/// Every period: read, keep on the blackboard, report.
pub fn sense(s: &mut Sensor, ctx: &mut Ctx) {
    let t_s = ctx.now_ns() as f64 / 1e9;
    s.value = temperature(ctx.addr(), t_s);
    if let Err(e) = ctx.bb.write("value", Value::F64(s.value)) {
        tracing::debug!("blackboard: {e}");
    }
    let aggregator = s.aggregator.clone();
    if let Err(e) = ctx.report_to(&aggregator, READING_TOPIC, &[Value::F64(s.value)]) {
        s.unsent += 1;
        tracing::debug!("reading not reported to {aggregator}: {e}");
    }
}

/// `read()`: a reading taken now.
pub fn read(
    s: &mut Sensor,
    ctx: &mut Ctx,
    _: &modbot_ipc_schema::Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    s.value = temperature(ctx.addr(), ctx.now_ns() as f64 / 1e9);
    reply.f64(s.value);
    Ok(())
}

/// An aggregator's state: the latest reading of each sensor, by address.
#[derive(Debug, Default)]
pub struct Aggregator {
    pub latest: BTreeMap<u8, f64>,
    pub reports: u64,
}

/// What an aggregator says about its sensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    pub sensors: usize,
    pub mean: f64,
    pub min: f64,
    pub max: f64,
    pub reports: u64,
}

impl Aggregator {
    pub fn summary(&self) -> Summary {
        let n = self.latest.len();
        let values = || self.latest.values().copied();
        Summary {
            sensors: n,
            mean: if n == 0 {
                f64::NAN
            } else {
                values().sum::<f64>() / n as f64
            },
            min: values().fold(f64::INFINITY, f64::min),
            max: values().fold(f64::NEG_INFINITY, f64::max),
            reports: self.reports,
        }
    }
}

/// A sensor's REPORT.
pub fn on_reading(a: &mut Aggregator, ctx: &mut Ctx, r: &Report<'_>) {
    if r.topic != READING_TOPIC {
        return;
    }
    let Ok(value) = r.values.f64(0) else {
        return;
    };
    a.latest.insert(r.from.0, value);
    a.reports += 1;
    let s = a.summary();
    for (item, v) in [
        ("sensors", Value::I64(s.sensors as i64)),
        ("mean", Value::F64(s.mean)),
        ("reports", Value::I64(s.reports as i64)),
    ] {
        if let Err(e) = ctx.bb.write(item, v) {
            tracing::debug!("blackboard: {e}");
        }
    }
}

/// `summary()`: sensors heard, mean, min, max, reports received.
pub fn summary(
    a: &mut Aggregator,
    _: &mut Ctx,
    _: &modbot_ipc_schema::Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let s = a.summary();
    reply.push(Value::I64(s.sensors as i64));
    reply.f64(s.mean);
    reply.f64(s.min);
    reply.f64(s.max);
    reply.push(Value::I64(s.reports as i64));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_sensor_reads_between_15_and_25_degrees_and_neighbours_differ() {
        for a in 1..=254u8 {
            let t = temperature(Addr(a), 12.5);
            assert!((15.0..=25.0).contains(&t), "{a}: {t}");
        }
        assert_ne!(temperature(Addr(1), 0.0), temperature(Addr(2), 0.0));
    }

    #[test]
    fn the_summary_is_over_the_latest_reading_of_each_sensor() {
        let mut a = Aggregator::default();
        assert_eq!(a.summary().sensors, 0);
        a.latest.insert(3, 20.0);
        a.latest.insert(4, 22.0);
        a.latest.insert(3, 18.0);
        a.reports = 3;
        let s = a.summary();
        assert_eq!(
            (s.sensors, s.mean, s.min, s.max, s.reports),
            (2, 20.0, 18.0, 22.0, 3)
        );
    }
}

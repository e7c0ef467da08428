//! The collision-avoidance sonar: 12 simulated ultrasonic sensors over the front 180°.
//!
//! Each sensor measures the time of flight of an echo from the nearest obstacle inside its
//! beam and turns it into a range with the speed of sound at the air temperature on the
//! blackboard (`air_temp_c`). The world is a set of point obstacles; the robot's pose comes
//! from the mobility module's blackboard snapshots. Ranges are measured from the robot's centre.

use modbot_ipc_schema::{F64s, Value};
use modbot_runtime::{Ctx, Dest, MethodError, Reply};

pub const SENSORS: usize = 12;
/// Farthest echo a sensor hears, in metres.
pub const MAX_RANGE_M: f64 = 10.0;
/// Half-width of a sensor's beam, in degrees.
pub const BEAM_HALF_WIDTH_DEG: f64 = 12.5;
/// REPORT topic of a monitor hit: `[range_m: f64, sensor: i64]`.
pub const MONITOR_TOPIC: u8 = 1;

/// Speed of sound in air at `celsius`, m/s.
pub fn speed_of_sound(celsius: f64) -> f64 {
    331.3 * (1.0 + celsius / 273.15).sqrt()
}

/// The robot's pose: metres, and heading in degrees from +x.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pose {
    pub x: f64,
    pub y: f64,
    pub heading_deg: f64,
}

/// The simulated sonar ring and its monitor.
#[derive(Debug, Default)]
pub struct Sonar {
    pub obstacles: Vec<(f64, f64)>,
    /// Who asked to be told, and at what range.
    pub monitor: Option<(modbot_ipc_schema::Addr, f64)>,
    pub pose: Pose,
    /// Which module's snapshots carry the pose.
    pub pose_source: String,
    pub ranges: [f64; SENSORS],
}

impl Sonar {
    /// The bearing of sensor `i` relative to the heading: -90° (right) to +90° (left).
    pub fn bearing_deg(i: usize) -> f64 {
        -90.0 + 180.0 * i as f64 / (SENSORS - 1) as f64
    }

    /// Simulates one ping of every sensor at `air_temp_c`.
    pub fn ping(&mut self, air_temp_c: f64) {
        let c = speed_of_sound(air_temp_c);
        for i in 0..SENSORS {
            let beam = self.pose.heading_deg + Self::bearing_deg(i);
            let nearest = self
                .obstacles
                .iter()
                .filter_map(|&(ox, oy)| {
                    let (dx, dy) = (ox - self.pose.x, oy - self.pose.y);
                    let d = dx.hypot(dy);
                    let angle = dy.atan2(dx).to_degrees();
                    let off = (angle - beam + 540.0).rem_euclid(360.0) - 180.0;
                    (off.abs() <= BEAM_HALF_WIDTH_DEG && d <= MAX_RANGE_M).then_some(d)
                })
                .fold(f64::INFINITY, f64::min);
            // The echo's round trip, then the range the sensor computes from it.
            let range = if nearest.is_finite() {
                let time_of_flight = 2.0 * nearest / c;
                time_of_flight * c / 2.0
            } else {
                MAX_RANGE_M
            };
            self.ranges[i] = range;
        }
    }

    /// The closest sensor reading: (range, sensor).
    pub fn closest(&self) -> (f64, usize) {
        self.ranges
            .iter()
            .copied()
            .enumerate()
            .map(|(i, r)| (r, i))
            .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
    }
}

/// `ranges()` → the 12 ranges, in metres, right to left.
pub fn ranges(
    s: &mut Sonar,
    ctx: &mut Ctx,
    _: &modbot_ipc_schema::Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    update(s, ctx);
    reply.push(Value::F64s(F64s::from_slice(&s.ranges)));
    Ok(())
}

/// `monitor(threshold_m)`: reports once when something is within the threshold, then stops.
pub fn monitor(
    s: &mut Sonar,
    ctx: &mut Ctx,
    args: &modbot_ipc_schema::Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let threshold = args.f64(0)?;
    if !(threshold > 0.0 && threshold <= MAX_RANGE_M) {
        return Err(MethodError::BadArguments(
            modbot_ipc_schema::ArgError::Invalid {
                index: 0,
                reason: "threshold must be in (0, 10] m",
            },
        ));
    }
    s.monitor = Some((ctx.caller(), threshold));
    tracing::info!(
        "monitoring for objects within {threshold} m for module {}",
        ctx.caller()
    );
    Ok(())
}

/// Reads the pose and pings.
fn update(s: &mut Sonar, ctx: &mut Ctx) {
    let source = s.pose_source.clone();
    if let Ok(Some(pose)) = ctx.snapshot_of(&source, |v| Pose {
        x: v.f64("x").unwrap_or(0.0),
        y: v.f64("y").unwrap_or(0.0),
        heading_deg: v.f64("heading").unwrap_or(0.0),
    }) {
        s.pose = pose;
    }
    let temp = ctx.bb.f64("air_temp_c");
    s.ping(temp);
    let ranges = s.ranges;
    if let Ok(id) = ctx.bb.id("ranges") {
        let _ = ctx.bb.write_id(id, Value::F64s(F64s::from_slice(&ranges)));
    }
}

/// Periodic: ping, and fire the monitor when armed and something is close.
pub fn tick(s: &mut Sonar, ctx: &mut Ctx) {
    update(s, ctx);
    let Some((to, threshold)) = s.monitor else {
        return;
    };
    let (range, sensor) = s.closest();
    if range <= threshold {
        s.monitor = None;
        tracing::info!(
            "object at {range:.3} m (sensor {sensor}) within {threshold} m: reporting to {to}"
        );
        if let Err(e) = ctx.report(
            Dest::Module(to),
            MONITOR_TOPIC,
            &[Value::F64(range), Value::I64(sensor as i64)],
        ) {
            tracing::warn!("monitor report not delivered: {e}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sonar_sees_an_obstacle_ahead_in_its_middle_beams() {
        let mut sut = Sonar {
            obstacles: vec![(3.0, 0.0)],
            ..Default::default()
        };
        sut.pose = Pose {
            x: 2.0,
            y: 0.0,
            heading_deg: 0.0,
        };
        sut.ping(20.0);
        let (range, _) = sut.closest();
        assert!((range - 1.0).abs() < 1e-9, "{range}");
        assert_eq!(
            sut.ranges[0], MAX_RANGE_M,
            "the rightmost beam sees nothing"
        );
        sut.pose.heading_deg = 180.0;
        sut.ping(20.0);
        assert_eq!(
            sut.closest().0,
            MAX_RANGE_M,
            "nothing behind the front 180°"
        );
    }

    #[test]
    fn sound_is_faster_in_warm_air() {
        assert!((speed_of_sound(0.0) - 331.3).abs() < 1e-9);
        assert!(speed_of_sound(30.0) > speed_of_sound(0.0));
    }
}

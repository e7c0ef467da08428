//! A ring of range sensors: the MRA's collision-avoidance sonar (12 ultrasonic sensors over the
//! front 180°), and with other settings MOSER's navigation sonar (24 over 360°) and near-infrared
//! proximity ring (11 over the front 180°, about 3 ft).
//!
//! Each sonar sensor measures the time of flight of an echo from the nearest obstacle inside its
//! beam and turns it into a range with the speed of sound at the air temperature on the
//! blackboard (`air_temp_c`); an infrared sensor measures its short range directly. The world is
//! either a set of point obstacles or a simulated building (walls and furniture); the robot's
//! pose comes from the mobility module's blackboard snapshots. Ranges are measured from the
//! robot's centre.

use modbot_core::{Ctx, Dest, MethodError, Reply};
use modbot_ipc_schema::{F64s, Value};

use crate::moser::building::Building;
use crate::moser::geometry::P;

/// The MRA sonar's sensor count.
pub const SENSORS: usize = 12;
/// Farthest echo a sonar hears, in metres.
pub const MAX_RANGE_M: f64 = 10.0;
/// Half-width of a sensor's beam, in degrees.
pub const BEAM_HALF_WIDTH_DEG: f64 = 12.5;
/// REPORT topic of a monitor hit: `[range_m: f64, sensor: i64]`.
pub const MONITOR_TOPIC: u8 = 1;
/// Half the width of the robot's path: an object farther to the side is not in the way.
pub const PATH_HALF_WIDTH_M: f64 = 0.4;

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

/// What kind of sensors the ring has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SensorKind {
    /// Ultrasonic: time of flight, corrected for the air temperature.
    #[default]
    Sonar,
    /// Near-infrared proximity: short range, measured directly.
    Infrared,
}

/// The sensors' arrangement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ring {
    pub sensors: usize,
    /// The arc they cover, centred on the heading: 180 (front) or 360 (all around).
    pub arc_deg: f64,
    pub max_range_m: f64,
    pub kind: SensorKind,
}

impl Default for Ring {
    fn default() -> Self {
        Ring {
            sensors: SENSORS,
            arc_deg: 180.0,
            max_range_m: MAX_RANGE_M,
            kind: SensorKind::Sonar,
        }
    }
}

impl Ring {
    /// The bearing of sensor `i` relative to the heading, right to left (counter-clockwise).
    pub fn bearing_deg(&self, i: usize) -> f64 {
        if self.arc_deg >= 360.0 {
            -180.0 + 360.0 * i as f64 / self.sensors as f64
        } else if self.sensors < 2 {
            0.0
        } else {
            -self.arc_deg / 2.0 + self.arc_deg * i as f64 / (self.sensors - 1) as f64
        }
    }

    /// Half-width of one sensor's beam: the arc split between the sensors, at least the MRA
    /// sonar's 12.5°.
    pub fn beam_half_width_deg(&self) -> f64 {
        (self.arc_deg / self.sensors.max(1) as f64 / 2.0 + 2.5).max(BEAM_HALF_WIDTH_DEG)
    }
}

/// What the sensors see.
#[derive(Debug, Default)]
pub enum World {
    /// Point obstacles (the MRA demo's `--obstacle X,Y`).
    #[default]
    Empty,
    Points(Vec<(f64, f64)>),
    /// MOSER's building: walls and furniture.
    Building(Box<Building>),
}

/// The simulated ring and its monitor.
#[derive(Debug, Default)]
pub struct Sonar {
    pub ring: Ring,
    pub world: World,
    /// Who asked to be told, and at what range.
    pub monitor: Option<(modbot_ipc_schema::Addr, f64)>,
    pub pose: Pose,
    /// Which module's snapshots carry the pose.
    pub pose_source: String,
    /// Latest ranges, one per sensor.
    pub ranges: Vec<f64>,
}

impl Sonar {
    /// A ring `ring` looking at `world`, with the pose from `pose_source`'s snapshots.
    pub fn new(ring: Ring, world: World, pose_source: &str) -> Sonar {
        Sonar {
            ranges: vec![ring.max_range_m; ring.sensors],
            ring,
            world,
            pose_source: pose_source.to_owned(),
            ..Default::default()
        }
    }

    /// The distance to the nearest obstacle in the beam centred on `beam_deg` (absolute).
    fn nearest(&self, beam_deg: f64) -> f64 {
        let (max, half) = (self.ring.max_range_m, self.ring.beam_half_width_deg());
        match &self.world {
            World::Empty => f64::INFINITY,
            World::Points(points) => points
                .iter()
                .filter_map(|&(ox, oy)| {
                    let (dx, dy) = (ox - self.pose.x, oy - self.pose.y);
                    let d = dx.hypot(dy);
                    let angle = dy.atan2(dx).to_degrees();
                    let off = (angle - beam_deg + 540.0).rem_euclid(360.0) - 180.0;
                    (off.abs() <= half && d <= max).then_some(d)
                })
                .fold(f64::INFINITY, f64::min),
            World::Building(b) => {
                let origin = P {
                    x: self.pose.x,
                    y: self.pose.y,
                };
                // A beam is a cone: sample it with five rays.
                [-1.0, -0.5, 0.0, 0.5, 1.0]
                    .iter()
                    .map(|k| b.ray(origin, (beam_deg + k * half).to_radians(), max))
                    .fold(f64::INFINITY, f64::min)
            }
        }
    }

    /// Simulates one reading of every sensor at `air_temp_c`.
    pub fn ping(&mut self, air_temp_c: f64) {
        let c = speed_of_sound(air_temp_c);
        let max = self.ring.max_range_m;
        self.ranges.resize(self.ring.sensors, max);
        for i in 0..self.ring.sensors {
            let nearest = self.nearest(self.pose.heading_deg + self.ring.bearing_deg(i));
            self.ranges[i] = if nearest >= max {
                max
            } else {
                match self.ring.kind {
                    // The echo's round trip, then the range the sensor computes from it.
                    SensorKind::Sonar => {
                        let time_of_flight = 2.0 * nearest / c;
                        time_of_flight * c / 2.0
                    }
                    SensorKind::Infrared => nearest,
                }
            };
        }
    }

    /// The closest reading in the robot's path ahead within `threshold`: (range, sensor).
    pub fn in_path(&self, threshold: f64) -> Option<(f64, usize)> {
        self.ranges
            .iter()
            .enumerate()
            .filter(|(i, &r)| {
                let b = self.ring.bearing_deg(*i).to_radians();
                r < self.ring.max_range_m
                    && b.cos() > 0.0
                    && r * b.cos() <= threshold
                    && (r * b.sin()).abs() <= PATH_HALF_WIDTH_M
            })
            .map(|(i, &r)| (r, i))
            .fold(None, |best, (r, i)| match best {
                Some((br, _)) if br <= r => best,
                _ => Some((r, i)),
            })
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

/// `ranges()` → every sensor's range, in metres, right to left.
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
    if !(threshold > 0.0 && threshold <= s.ring.max_range_m) {
        return Err(MethodError::BadArguments(
            modbot_ipc_schema::ArgError::Invalid {
                index: 0,
                reason: "threshold must be > 0 m and within the sensors' range",
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
    if let Ok(id) = ctx.bb.id("ranges") {
        let _ = ctx
            .bb
            .write_id(id, Value::F64s(F64s::from_slice(&s.ranges)));
    }
}

/// Periodic: ping, and fire the monitor when armed and something is close.
pub fn tick(s: &mut Sonar, ctx: &mut Ctx) {
    update(s, ctx);
    let Some((to, threshold)) = s.monitor else {
        return;
    };
    if let Some((range, sensor)) = s.in_path(threshold) {
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
        let mut sut = Sonar::new(Ring::default(), World::Points(vec![(3.0, 0.0)]), "mobility");
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
    fn only_objects_in_the_path_fire_the_monitor() {
        let mut sut = Sonar::new(
            Ring::default(),
            World::Points(vec![(0.0, 0.5), (0.55, 0.0)]),
            "mobility",
        );
        sut.ping(20.0);
        assert_eq!(sut.closest().0, 0.5, "the object beside the robot is seen");
        let (range, _) = sut.in_path(0.61).expect("the one ahead is in the path");
        assert!((range - 0.55).abs() < 1e-9);
        sut.world = World::Points(vec![(0.0, 0.5)]);
        sut.ping(20.0);
        assert_eq!(
            sut.in_path(0.61),
            None,
            "a door frame to the side is not in the way"
        );
    }

    #[test]
    fn a_ring_of_24_covers_all_around_and_sees_walls_of_the_building() {
        let building = crate::moser::building::moser_building();
        let start = building.start;
        let ring = Ring {
            sensors: 24,
            arc_deg: 360.0,
            ..Ring::default()
        };
        let mut sut = Sonar::new(ring, World::Building(Box::new(building)), "mobility");
        sut.pose = Pose {
            x: start.x,
            y: start.y,
            heading_deg: 0.0,
        };
        sut.ping(20.0);
        assert_eq!(sut.ranges.len(), 24);
        assert!((ring.bearing_deg(0) + 180.0).abs() < 1e-9);
        assert!(
            sut.ranges.iter().any(|&r| r < MAX_RANGE_M),
            "walls are seen: {:?}",
            sut.ranges
        );
    }

    #[test]
    fn sound_is_faster_in_warm_air() {
        assert!((speed_of_sound(0.0) - 331.3).abs() < 1e-9);
        assert!(speed_of_sound(30.0) > speed_of_sound(0.0));
    }
}

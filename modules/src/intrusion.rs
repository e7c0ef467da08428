//! MOSER's intrusion detection module: heat, light and motion sensors fused into the
//! probability of an intruder, with an alert to the control station above a threshold.
//!
//! The sensors are virtual devices: each reading is computed from the robot's pose (the
//! mobility module's snapshots) and the simulated intruder at the system's simulated time, and
//! only through a line of sight (walls block, furniture does not):
//! - heat (a thermopile): body heat falling off with the square of the distance, up to 8 m;
//! - motion (a microwave Doppler sensor): a moving body within 6 m;
//! - light (a photocell): a carried flashlight within 12 m.
//!
//! Fusion treats them as independent witnesses: p = 1 − Π(1 − pᵢ). Above the threshold the
//! module reports once to the control station — `[x, y, probability, time_s, heat, motion,
//! light]` — and re-arms when the probability falls below a third of the threshold.
//! Blackboard: `heat`, `motion`, `light`, `probability`, `alerts`.

use modbot_core::sim::SimTime;
use modbot_core::Ctx;
use modbot_ipc_schema::Value;

use crate::moser::building::Building;
use crate::moser::geometry::P;
use crate::moser::intruder::Intruder;

/// REPORT topic of an alert to the control station.
pub const ALERT_TOPIC: u8 = 0x21;

const HEAT_RANGE_M: f64 = 8.0;
const MOTION_RANGE_M: f64 = 6.0;
const LIGHT_RANGE_M: f64 = 12.0;

/// The three readings, each a probability that an intruder explains it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Readings {
    pub heat: f64,
    pub motion: f64,
    pub light: f64,
}

impl Readings {
    /// The fused probability.
    pub fn fused(&self) -> f64 {
        1.0 - (1.0 - self.heat) * (1.0 - self.motion) * (1.0 - self.light)
    }
}

/// What the sensors read with the robot at `robot` and the intruder at `intruder` (moving or
/// not), in `building`.
pub fn sense(
    building: &Building,
    robot: P,
    intruder: Option<(P, bool)>,
    it: &Intruder,
) -> Readings {
    let Some((at, moving)) = intruder else {
        return Readings::default();
    };
    let d = robot.dist(at);
    if !building.line_of_sight(robot, at) {
        return Readings::default();
    }
    let heat = if d <= HEAT_RANGE_M {
        // 100 W of body heat at 1.5 m saturates the sensor.
        (it.heat_w() / 100.0 * (1.5 / d.max(0.1)).powi(2)).min(1.0) * 0.95
    } else {
        0.0
    };
    let motion = if moving && d <= MOTION_RANGE_M {
        0.9 * (1.0 - d / MOTION_RANGE_M)
    } else {
        0.0
    };
    let light = if it.carries_light() && d <= LIGHT_RANGE_M {
        0.6
    } else {
        0.0
    };
    Readings {
        heat,
        motion,
        light,
    }
}

/// The module's state.
pub struct Intrusion {
    pub building: Building,
    pub intruder: Intruder,
    pub sim: SimTime,
    pub threshold: f64,
    pub mobility: String,
    pub station: String,
    armed: bool,
    alerts: i64,
}

impl Intrusion {
    pub fn new(
        building: Building,
        intruder: Intruder,
        threshold: f64,
        mobility: &str,
        station: &str,
    ) -> Intrusion {
        Intrusion {
            building,
            intruder,
            sim: SimTime::from_env(),
            threshold,
            mobility: mobility.to_owned(),
            station: station.to_owned(),
            armed: true,
            alerts: 0,
        }
    }
}

/// Periodic: sample, fuse, alert.
pub fn tick(s: &mut Intrusion, ctx: &mut Ctx) {
    let t = s.sim.seconds(ctx.now_ns());
    let mobility = s.mobility.clone();
    let Ok(Some(robot)) = ctx.snapshot_of(&mobility, |v| P {
        x: v.f64("x").unwrap_or(0.0),
        y: v.f64("y").unwrap_or(0.0),
    }) else {
        return;
    };
    let intruder = s.intruder.position(t).map(|now| {
        let before = s.intruder.position(t - 0.2).unwrap_or(now);
        (now, now.dist(before) > 0.01)
    });
    let r = sense(&s.building, robot, intruder, &s.intruder);
    let p = r.fused();
    for (name, v) in [
        ("heat", r.heat),
        ("motion", r.motion),
        ("light", r.light),
        ("probability", p),
    ] {
        let _ = ctx.bb.write(name, Value::F64(v));
    }
    if s.armed && p >= s.threshold {
        let Some((at, _)) = intruder else { return };
        s.armed = false;
        s.alerts += 1;
        let _ = ctx.bb.write("alerts", Value::I64(s.alerts));
        tracing::warn!(
            "INTRUDER: probability {p:.2} at ({:.1}, {:.1}), t = {t:.1} s (heat {:.2}, motion {:.2}, light {:.2})",
            at.x,
            at.y,
            r.heat,
            r.motion,
            r.light
        );
        let station = s.station.clone();
        let values = [
            Value::F64(at.x),
            Value::F64(at.y),
            Value::F64(p),
            Value::F64(t),
            Value::F64(r.heat),
            Value::F64(r.motion),
            Value::F64(r.light),
        ];
        if let Err(e) = ctx.report_to(&station, ALERT_TOPIC, &values) {
            tracing::warn!("alert not delivered to {station}: {e}");
            s.armed = true; // try again on the next sample
        }
    } else if !s.armed && p < s.threshold / 3.0 {
        s.armed = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::moser::building::moser_building;
    use crate::moser::intruder::moser_intruder;

    #[test]
    fn an_intruder_close_by_and_in_sight_is_above_the_threshold_and_far_away_is_not() {
        let building = moser_building();
        let it = moser_intruder();
        let at = it.path[it.path.len() - 1];
        let near = P {
            x: at.x - 1.0,
            y: at.y,
        };
        let sut = if building.line_of_sight(near, at) {
            sense(&building, near, Some((at, true)), &it)
        } else {
            let near = P {
                x: at.x,
                y: at.y - 1.0,
            };
            sense(&building, near, Some((at, true)), &it)
        };
        assert!(sut.fused() > 0.8, "{sut:?}");
        assert_eq!(
            sense(&building, building.start, None, &it),
            Readings::default()
        );
    }

    /// The demo's promise, whatever the simulation's speed: the intruder is found only in
    /// the server room (where the robot goes round the box first), never from the corridor
    /// or another room on the way there. The robot's way is the planner's route through
    /// wing 3 on the known map; it can be at a point `s` metres along it from `s / 0.5` s on
    /// (the base's top speed) — at any later time, if it is slower.
    #[test]
    fn the_demo_intruder_is_above_the_threshold_only_for_a_robot_in_the_server_room() {
        use crate::moser::planner::{self, Grid};
        let building = moser_building();
        let it = moser_intruder();
        let threshold = 0.8;
        let server_room = building
            .rooms
            .iter()
            .find(|r| r.name == "server room")
            .expect("a server room")
            .rect;
        let grid = Grid::from_building(&building, 0.2, crate::mobility::RADIUS_M);
        let goals = planner::patrol_route(&building, 3).unwrap();
        let mut way = vec![building.start];
        for goal in goals {
            let from = *way.last().unwrap();
            way.extend(planner::plan(&grid, from, goal).unwrap());
            if server_room.contains(goal) {
                break;
            }
        }
        let (mut s, mut worst) = (0.0, (0.0, building.start, 0.0));
        for leg in way.windows(2) {
            let steps = (leg[0].dist(leg[1]) / 0.1).ceil().max(1.0) as usize;
            for i in 0..steps {
                let robot = leg[0].add(leg[1].sub(leg[0]).scale(i as f64 / steps as f64));
                let here = s + leg[0].dist(robot);
                if server_room.contains(robot) {
                    continue;
                }
                let mut t = here / 0.5;
                while t <= 200.0 {
                    let intruder = it.position(t).map(|now| {
                        let before = it.position(t - 0.2).unwrap_or(now);
                        (now, now.dist(before) > 0.01)
                    });
                    let p = sense(&building, robot, intruder, &it).fused();
                    if p > worst.0 {
                        worst = (p, robot, t);
                    }
                    t += 0.5;
                }
            }
            s += leg[0].dist(leg[1]);
        }
        assert!(
            worst.0 < threshold,
            "p = {:.2} for a robot at {:?} at t = {} s",
            worst.0,
            worst.1,
            worst.2
        );
    }

    #[test]
    fn readings_fuse_as_independent_witnesses() {
        let sut = Readings {
            heat: 0.5,
            motion: 0.5,
            light: 0.0,
        };
        assert!((sut.fused() - 0.75).abs() < 1e-12);
    }
}

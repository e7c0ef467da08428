//! The intruder: a person who comes in through wing 3's fire door some time after the patrol
//! starts, walks slowly through office 3A into the server room, and lingers there.
//!
//! Its position is a pure function of simulated time, so every module process (the intrusion
//! detector's heat, light and motion sensors alike) sees the same person at the same place.

use super::geometry::P;

/// A person walking a fixed path at a fixed speed.
#[derive(Debug, Clone, PartialEq)]
pub struct Intruder {
    /// Where it walks, leg by leg. The last leg is also where it lingers: once at the end it
    /// paces that leg back and forth for ever (unless it `leaves`), so a motion sensor sees it.
    pub path: Vec<P>,
    /// When it appears at `path[0]`, simulated seconds after the start.
    pub enters_s: f64,
    /// Walking speed, m/s.
    pub speed: f64,
    /// Whether it is gone once it reaches the end of its path, instead of lingering.
    pub leaves: bool,
}

/// The demo's intruder. It appears at t = 20 s inside the fire door at the east end of the
/// corridor (the door is shut again behind it: the outer walls stay closed for the sensors),
/// walks at 0.5 m/s into office 3A and out, crosses to the server room (t ≈ 53 s at its door),
/// steps round the delivery box and paces between (26.2, 4.5) and (26.2, 2.5), beside the
/// room's patrol point, from t ≈ 64 s on. It carries no torch, so the robot's sensors find it
/// only close by (heat and motion within about 2 m): in the server room, once the robot has gone
/// round the box — not earlier from the corridor, whatever the simulation's speed.
pub fn moser_intruder() -> Intruder {
    Intruder {
        path: vec![
            P::new(29.5, 10.0), // just in through the fire door
            P::new(27.5, 10.0), // in front of office 3A
            P::new(27.5, 14.0), // through its door
            P::new(28.5, 16.0), // looks at the desk
            P::new(27.5, 13.5),
            P::new(27.5, 10.5), // back in the corridor
            P::new(25.2, 9.0),  // in front of the server room
            P::new(25.2, 7.0),  // through its door
            P::new(26.5, 6.0),  // round the delivery box
            P::new(26.2, 4.5),  // lingers: paces this last leg
            P::new(26.2, 2.5),
        ],
        enters_s: 20.0,
        speed: 0.5,
        leaves: false,
    }
}

impl Intruder {
    /// Length of the whole path, metres.
    pub fn length(&self) -> f64 {
        self.path.windows(2).map(|w| w[0].dist(w[1])).sum()
    }

    /// When it reaches the end of its path (and starts lingering, or leaves), simulated seconds.
    pub fn end_s(&self) -> f64 {
        self.enters_s + self.length() / self.speed
    }

    /// Where it is at `t_s` simulated seconds; `None` before it enters, after it leaves, or if
    /// it has no path.
    pub fn position(&self, t_s: f64) -> Option<P> {
        let (&first, &last) = (self.path.first()?, self.path.last()?);
        if t_s < self.enters_s {
            return None;
        }
        let mut s = (t_s - self.enters_s) * self.speed;
        let total = self.length();
        if s > total {
            if self.leaves {
                return None;
            }
            return Some(self.lingering(s - total));
        }
        for w in self.path.windows(2) {
            let len = w[0].dist(w[1]);
            if s <= len && len > 0.0 {
                return Some(w[0].add(w[1].sub(w[0]).scale(s / len)));
            }
            s -= len;
        }
        Some(if self.path.len() == 1 { first } else { last })
    }

    /// Where it is `s` metres of pacing after reaching the end: back along the last leg, then
    /// forward again, and so on.
    fn lingering(&self, s: f64) -> P {
        let n = self.path.len();
        let end = self.path[n - 1];
        if n < 2 {
            return end;
        }
        let turn = self.path[n - 2];
        let len = turn.dist(end);
        if len == 0.0 {
            return end;
        }
        let phase = s % (2.0 * len);
        let back = if phase <= len {
            phase
        } else {
            2.0 * len - phase
        };
        end.add(turn.sub(end).scale(back / len))
    }

    /// Body heat it gives off, watts: a person at rest or walking slowly.
    pub fn heat_w(&self) -> f64 {
        100.0
    }

    /// Whether it carries a light the light sensors can see: the demo's intruder sneaks in
    /// the dark, without a torch.
    pub fn carries_light(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::super::building::moser_building;
    use super::*;

    #[test]
    fn intruder_path_crosses_walls_only_through_doors_and_keeps_clear_of_furniture() {
        let sut = moser_intruder();
        let building = moser_building();
        for w in sut.path.windows(2) {
            assert!(
                building.line_of_sight(w[0], w[1]),
                "leg {:?} -> {:?} crosses a wall",
                w[0],
                w[1]
            );
            let steps = (w[0].dist(w[1]) / 0.05).ceil() as usize;
            for i in 0..=steps {
                let p = w[0].add(w[1].sub(w[0]).scale(i as f64 / steps as f64));
                assert!(!building.collides(p, 0.2), "walks into something at {p:?}");
            }
        }
    }

    #[test]
    fn intruder_is_absent_before_it_enters_then_appears_at_the_start_of_its_path() {
        let sut = moser_intruder();
        assert_eq!(sut.position(0.0), None);
        assert_eq!(sut.position(sut.enters_s - 0.01), None);
        assert_eq!(sut.position(sut.enters_s), Some(sut.path[0]));
    }

    #[test]
    fn intruder_walks_at_its_speed() {
        let sut = moser_intruder();
        let (a, b) = (
            sut.position(sut.enters_s + 1.0),
            sut.position(sut.enters_s + 3.0),
        );
        let moved = a.unwrap().dist(b.unwrap());
        assert!(
            (moved - 2.0 * sut.speed).abs() < 1e-9,
            "moved {moved} m in 2 s"
        );
        assert!((sut.speed - 0.5).abs() < 0.2, "walks slowly");
    }

    #[test]
    fn intruder_goes_through_wing_3_and_lingers_pacing_in_a_wing_3_room() {
        let sut = moser_intruder();
        let building = moser_building();
        let wing_of = |t: f64| building.room_at(sut.position(t).unwrap()).map(|r| r.wing);
        assert_eq!(wing_of(sut.enters_s + 12.0), Some(3), "in office 3A");
        let end = sut.end_s();
        assert!(
            sut.enters_s >= 20.0 && end < 120.0,
            "enters at {}, arrives at {end}",
            sut.enters_s
        );
        for t in [end, end + 3.0, end + 100.0, end + 3600.0] {
            assert_eq!(
                building.room_at(sut.position(t).unwrap()).map(|r| r.name),
                Some("server room")
            );
        }
        let (a, b) = (
            sut.position(end + 1.0).unwrap(),
            sut.position(end + 2.0).unwrap(),
        );
        assert!(
            (a.dist(b) - sut.speed).abs() < 1e-9,
            "still moving while it lingers"
        );
    }

    #[test]
    fn an_intruder_who_leaves_is_gone_after_the_end_of_its_path() {
        let sut = Intruder {
            leaves: true,
            ..moser_intruder()
        };
        assert!(sut.position(sut.end_s() - 0.1).is_some());
        assert_eq!(sut.position(sut.end_s() + 0.1), None);
        assert!(sut.heat_w() > 50.0 && !sut.carries_light());
    }
}

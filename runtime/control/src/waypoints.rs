//! `waypoints`: the goals of a robot program that goes from point to point, round and round.
//!
//! Input `done: bool` (the trajectory generator's); output `goal` (f64 array of `axes`).
//! Params `points` (a flat list of `axes` × m joint positions: point 0, then point 1, …; at
//! least two points) and `dwell` (f64 seconds at each point, default 0).
//!
//! It puts out point 0 first. Once the generator has begun to move (`done` read false) and
//! then arrived (`done` read true for `dwell`), it puts out the next point, after the last
//! the first again. If the generator never reads moving within 0.5 s of a new goal (the robot
//! was at that point already), that counts as arrived.

use super::{array_mut, array_ports, axes, axes_decl};
use modbot_grid::carry::{Carry, CarryError};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, ParamValue, Params,
    PortDecl, PortType, PortValue, Released, PERIOD_S,
};

/// Seconds without a reading of `done` = false after which a goal counts as reached.
const NO_MOTION_S: f64 = 0.5;

pub(super) fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        Waypoints::new(p)?;
    }
    Ok(ComponentInfo {
        type_name: "waypoints",
        doc: "goals from point to point, round and round: the next once the generator is done",
        inputs: vec![PortDecl::new("done", PortType::Bool)],
        outputs: array_ports(&["goal"], n),
        params: vec![
            axes_decl(),
            ParamDecl::required("points", ParamType::F64s),
            ParamDecl::optional("dwell", ParamType::F64, ParamValue::F64(0.0)),
        ],
    })
}

pub(super) fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(Waypoints::new(p)?))
}

struct Waypoints {
    axes: usize,
    points: Vec<f64>,
    /// The point put out now.
    index: usize,
    /// Whether the generator read moving since the goal changed.
    moved: bool,
    /// Releases since the goal changed, and releases it has read done since it moved.
    since_goal: u64,
    at_goal: u64,
    /// Releases of `dwell` and of [`NO_MOTION_S`].
    dwell: u64,
    no_motion: u64,
}

impl Waypoints {
    fn new(p: &Params) -> Result<Waypoints, ComponentError> {
        let n = axes(p)?;
        let points = p.f64s("points")?.to_vec();
        if points.len() < 2 * n || points.len() % n != 0 {
            let why = format!(
                "must hold whole points of {n} values each, at least two: {} values given",
                points.len()
            );
            return Err(ParamError::invalid("points", why).into());
        }
        if let Some(i) = points.iter().position(|x| !x.is_finite()) {
            let why = format!("must be finite numbers, not {} (value {i})", points[i]);
            return Err(ParamError::invalid("points", why).into());
        }
        let dwell = p.f64("dwell")?;
        if !(dwell.is_finite() && dwell >= 0.0) {
            let why = format!("must be seconds >= 0, not {dwell}");
            return Err(ParamError::invalid("dwell", why).into());
        }
        let period = p.f64(PERIOD_S)?;
        let releases = |s: f64| (s / period).ceil() as u64;
        Ok(Waypoints {
            axes: n,
            points,
            index: 0,
            moved: false,
            since_goal: 0,
            at_goal: 0,
            dwell: releases(dwell),
            no_motion: releases(NO_MOTION_S).max(1),
        })
    }
}

impl Component for Waypoints {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let done = matches!(inputs[0], PortValue::Bool(true));
        self.since_goal += 1;
        if !done {
            self.moved = true;
            self.at_goal = 0;
        } else if self.moved || self.since_goal >= self.no_motion {
            self.at_goal += 1;
        }
        if self.at_goal > self.dwell {
            self.index = (self.index + 1) % (self.points.len() / self.axes);
            self.moved = false;
            self.since_goal = 0;
            self.at_goal = 0;
        }
        let point = &self.points[self.index * self.axes..(self.index + 1) * self.axes];
        array_mut(&mut outputs[0]).copy_from_slice(point);
    }

    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        let mut index = self.index as u64;
        c.u64("index", &mut index)?;
        let count = self.points.len() / self.axes;
        if index >= count as u64 {
            return Err(CarryError::Shape {
                what: "the point (index)",
                expected: count,
                got: usize::try_from(index).unwrap_or(usize::MAX),
            });
        }
        self.index = index as usize;
        c.bool("moved", &mut self.moved)?;
        c.u64("since_goal", &mut self.since_goal)?;
        c.u64("at_goal", &mut self.at_goal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_grid::Registry;

    fn waypoints(dwell: f64) -> (Box<dyn Component>, Vec<PortValue>) {
        let mut registry = Registry::new();
        super::super::register(&mut registry);
        let mut params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("points", ParamValue::F64s(vec![0.0, 0.0, 1.0, -1.0]))
            .with("dwell", ParamValue::F64(dwell));
        params.set_timing(0.001, 1);
        let sut = registry.instantiate("waypoints", &params).unwrap();
        (sut, vec![PortValue::F64s(vec![0.0; 2])])
    }

    fn goal(out: &[PortValue]) -> Vec<f64> {
        match &out[0] {
            PortValue::F64s(x) => x.clone(),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn carried_into_another_instance_it_goes_on_to_the_same_points() {
        let (mut old, mut a) = waypoints(0.002);
        let (mut new, mut b) = waypoints(0.002);
        let done = |t: u64| [PortValue::Bool(t % 7 > 2)];
        for t in 0..10 {
            old.step(&Released::at(t), &done(t), &mut a);
        }
        super::super::harness::carry_into(old.as_mut(), new.as_mut());
        for t in 10..60 {
            old.step(&Released::at(t), &done(t), &mut a);
            new.step(&Released::at(t), &done(t), &mut b);
            assert_eq!(goal(&a), goal(&b), "tick {t}");
        }
    }

    #[test]
    fn it_moves_on_once_the_generator_moved_and_arrived_and_dwelt() {
        let (mut sut, mut out) = waypoints(0.002);
        let (moving, arrived) = ([PortValue::Bool(false)], [PortValue::Bool(true)]);
        sut.step(&Released::at(0), &moving, &mut out);
        assert_eq!(goal(&out), [0.0, 0.0]);
        for t in 1..=2 {
            sut.step(&Released::at(t), &arrived, &mut out);
            assert_eq!(goal(&out), [0.0, 0.0], "dwelling at tick {t}");
        }
        sut.step(&Released::at(3), &arrived, &mut out);
        assert_eq!(goal(&out), [1.0, -1.0]);
        // Done still reads true from before the new goal: not arrived yet.
        for t in 5..100 {
            sut.step(&Released::at(t), &arrived, &mut out);
        }
        assert_eq!(goal(&out), [1.0, -1.0]);
        sut.step(&Released::at(100), &moving, &mut out);
        for t in 101..=103 {
            sut.step(&Released::at(t), &arrived, &mut out);
        }
        assert_eq!(goal(&out), [0.0, 0.0], "round and round");
    }

    #[test]
    fn a_goal_where_the_robot_is_already_counts_as_reached_after_half_a_second() {
        let (mut sut, mut out) = waypoints(0.0);
        let arrived = [PortValue::Bool(true)];
        for t in 0..499 {
            sut.step(&Released::at(t), &arrived, &mut out);
        }
        assert_eq!(goal(&out), [0.0, 0.0]);
        sut.step(&Released::at(500), &arrived, &mut out);
        assert_eq!(goal(&out), [1.0, -1.0]);
    }

    #[test]
    fn points_must_be_whole_and_at_least_two() {
        let mut registry = Registry::new();
        super::super::register(&mut registry);
        let mut params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("points", ParamValue::F64s(vec![0.0, 0.0, 1.0]));
        params.set_timing(0.001, 1);
        let e = registry.instantiate("waypoints", &params).err().unwrap();
        let e = e.to_string();
        assert!(e.contains("whole points of 2 values"), "{e}");
    }
}

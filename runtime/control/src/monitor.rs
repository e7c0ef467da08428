//! `monitor`: latching limits on the robot's state, MoRC's Monitoring component.
//!
//! Inputs `q`, `qd` (measured) and `q_ref` (commanded); outputs `ok: bool`, `code: i64` and
//! `axis: i64`. Params `q_min`, `q_max`, `qd_max`, `following_max`, all per axis. At each
//! release it checks, in this order:
//!
//! | code | breach |
//! |---|---|
//! | 1 | position limit: q outside [q_min, q_max] |
//! | 2 | velocity limit: \|qd\| > qd_max |
//! | 3 | following error: \|q_ref − q\| > following_max |
//!
//! A non-finite value is a breach of its check (a NaN q of code 1, and so on). The outputs
//! are `ok` = false, the code and `axis` = the first (lowest) axis with that breach; or true,
//! 0 and −1 when there is none. A breach latches: from then on the outputs stay those of the
//! first breach until the component is made again.
//!
//! Like every output, `ok` reads false until the first release's outputs are valid (LET), and
//! the first releases see zeros on inputs whose sources have not produced yet: a range
//! [q_min, q_max] that excludes 0 trips at once.

use super::{array, array_ports, at, axes, axes_decl, finite, per_axis, per_axis_decl, positive};
use modbot_grid::carry::{Carry, CarryError};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, ParamError, Params, PortDecl, PortType, PortValue,
    Released,
};

/// The codes of `code`.
pub const OK: i64 = 0;
pub const POSITION_LIMIT: i64 = 1;
pub const VELOCITY_LIMIT: i64 = 2;
pub const FOLLOWING_ERROR: i64 = 3;

pub(super) fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        Monitor::new(p)?;
    }
    Ok(ComponentInfo {
        type_name: "monitor",
        doc: "latching limits: ok, code (1 position, 2 velocity, 3 following error), axis",
        inputs: array_ports(&["q", "qd", "q_ref"], n),
        outputs: vec![
            PortDecl::new("ok", PortType::Bool),
            PortDecl::new("code", PortType::I64),
            PortDecl::new("axis", PortType::I64),
        ],
        params: vec![
            axes_decl(),
            per_axis_decl("q_min"),
            per_axis_decl("q_max"),
            per_axis_decl("qd_max"),
            per_axis_decl("following_max"),
        ],
    })
}

pub(super) fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(Monitor::new(p)?))
}

struct Monitor {
    q_min: Vec<f64>,
    q_max: Vec<f64>,
    qd_max: Vec<f64>,
    following_max: Vec<f64>,
    /// The first breach, (code, axis), once there was one.
    tripped: Option<(i64, i64)>,
}

impl Monitor {
    fn new(p: &Params) -> Result<Monitor, ComponentError> {
        let n = axes(p)?;
        let q_min = per_axis(p, "q_min", n, "finite", finite)?;
        let q_max = per_axis(p, "q_max", n, "finite", finite)?;
        if let Some(i) = (0..n).find(|&i| q_min[i] > q_max[i]) {
            let why = format!(
                "must not be above 'q_max': {} > {} (axis {i})",
                q_min[i], q_max[i]
            );
            return Err(ParamError::invalid("q_min", why).into());
        }
        Ok(Monitor {
            q_min,
            q_max,
            qd_max: per_axis(p, "qd_max", n, "positive", positive)?,
            following_max: per_axis(p, "following_max", n, "positive", positive)?,
            tripped: None,
        })
    }

    /// The first breach in these inputs, if any.
    fn check(&self, q: &[f64], qd: &[f64], q_ref: &[f64]) -> Option<(i64, i64)> {
        let n = self.q_min.len();
        // Within [lo, hi]: false for NaN, so NaN fails every check.
        let within = |x: f64, lo: f64, hi: f64| lo <= x && x <= hi;
        let position = |i: usize| !within(at(q, i), self.q_min[i], self.q_max[i]);
        let velocity = |i: usize| !within(at(qd, i), -self.qd_max[i], self.qd_max[i]);
        let following = |i: usize| {
            let limit = self.following_max[i];
            !within(at(q_ref, i) - at(q, i), -limit, limit)
        };
        let checks: [(i64, &dyn Fn(usize) -> bool); 3] = [
            (POSITION_LIMIT, &position),
            (VELOCITY_LIMIT, &velocity),
            (FOLLOWING_ERROR, &following),
        ];
        checks.iter().find_map(|(code, breached)| {
            let axis = (0..n).find(|&i| breached(i))?;
            Some((*code, i64::try_from(axis).unwrap_or(i64::MAX)))
        })
    }
}

impl Component for Monitor {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        if self.tripped.is_none() {
            let [q, qd, q_ref] = [0, 1, 2].map(|k| array(&inputs[k]));
            self.tripped = self.check(q, qd, q_ref);
        }
        let (code, axis) = self.tripped.unwrap_or((OK, -1));
        outputs[0] = PortValue::Bool(self.tripped.is_none());
        outputs[1] = PortValue::I64(code);
        outputs[2] = PortValue::I64(axis);
    }

    fn unsafe_state(&self) -> bool {
        self.tripped.is_some()
    }

    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        let mut tripped = self.tripped.is_some();
        let (mut code, mut axis) = self.tripped.unwrap_or((OK, -1));
        c.bool("tripped", &mut tripped)?;
        c.i64("code", &mut code)?;
        c.i64("axis", &mut axis)?;
        self.tripped = tripped.then_some((code, axis));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::harness::{list, refusal, Harness};
    use super::*;
    use modbot_grid::component::ParamValue;

    fn monitor() -> Harness {
        let params = Params::new()
            .with("axes", ParamValue::I64(3))
            .with("q_min", list(&[-1.0, -2.0, -3.0]))
            .with("q_max", list(&[1.0, 2.0, 3.0]))
            .with("qd_max", list(&[0.5]))
            .with("following_max", ParamValue::F64(0.1));
        Harness::new("monitor", params, 1)
    }

    fn verdict(sut: &Harness) -> (bool, i64, i64) {
        match sut.outputs.as_slice() {
            [PortValue::Bool(ok), PortValue::I64(code), PortValue::I64(axis)] => {
                (*ok, *code, *axis)
            }
            other => panic!("{other:?}"),
        }
    }

    /// The verdict of a fresh monitor on one release.
    fn first(q: [f64; 3], qd: [f64; 3], q_ref: [f64; 3]) -> (bool, i64, i64) {
        let mut sut = monitor();
        sut.step(0, &[&q, &qd, &q_ref]);
        verdict(&sut)
    }

    #[test]
    fn a_trip_carried_into_another_instance_holds_there() {
        let (mut old, mut new) = (monitor(), monitor());
        old.step(0, &[&[0.0, 0.0, 0.0], &[0.0; 3], &[0.0; 3]]);
        old.step(1, &[&[0.0, 2.5, 0.0], &[0.0; 3], &[0.0, 2.5, 0.0]]);
        super::super::harness::carry_into(old.sut.as_mut(), new.sut.as_mut());
        new.step(2, &[&[0.0; 3], &[0.0; 3], &[0.0; 3]]);
        assert_eq!(verdict(&new), (false, POSITION_LIMIT, 1));
        assert!(new.sut.unsafe_state());
    }

    #[test]
    fn within_every_limit_it_is_ok() {
        let q = [0.9, -1.9, 2.9];
        assert_eq!(
            first(q, [0.5, -0.5, 0.0], [1.0, -1.85, 2.95]),
            (true, OK, -1)
        );
    }

    #[test]
    fn each_breach_names_its_code_and_first_axis() {
        let zero = [0.0; 3];
        assert_eq!(first([0.0, 2.5, -3.5], zero, zero).1, POSITION_LIMIT);
        assert_eq!(first([0.0, 2.5, -3.5], zero, zero), (false, 1, 1));
        assert_eq!(first(zero, [0.0, 0.0, -0.6], zero), (false, 2, 2));
        assert_eq!(first(zero, zero, [0.2, 0.0, 0.0]), (false, 3, 0));
        // Position before velocity before following error.
        assert_eq!(first([0.0, 0.0, 4.0], [9.0; 3], [9.0; 3]), (false, 1, 2));
    }

    #[test]
    fn a_nan_input_trips_its_check() {
        let (zero, nan) = ([0.0; 3], [0.0, f64::NAN, 0.0]);
        assert_eq!(first(nan, zero, zero), (false, POSITION_LIMIT, 1));
        assert_eq!(first(zero, nan, zero), (false, VELOCITY_LIMIT, 1));
        assert_eq!(first(zero, zero, nan), (false, FOLLOWING_ERROR, 1));
    }

    #[test]
    fn a_breach_latches_until_the_monitor_is_made_again() {
        let mut sut = monitor();
        let zero = [0.0; 3];
        sut.step(0, &[&zero, &zero, &zero]);
        assert_eq!(verdict(&sut), (true, OK, -1));
        sut.step(1, &[&zero, &[0.0, 0.7, 0.0], &zero]);
        sut.step(2, &[&zero, &zero, &zero]);
        sut.step(3, &[&[5.0; 3], &zero, &zero]);
        assert_eq!(verdict(&sut), (false, VELOCITY_LIMIT, 1));
        assert_eq!(first(zero, zero, zero), (true, OK, -1));
    }

    #[test]
    fn monitor_refuses_an_empty_position_range() {
        let params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("q_min", list(&[0.0, 1.0]))
            .with("q_max", list(&[1.0, 0.5]))
            .with("qd_max", list(&[1.0]))
            .with("following_max", list(&[1.0]));
        assert_eq!(
            refusal("monitor", params),
            "param 'q_min' must not be above 'q_max': 1 > 0.5 (axis 1)"
        );
    }
}

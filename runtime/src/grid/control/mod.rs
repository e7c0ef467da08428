//! Example controllers as time-grid components: enough to move a simulated 6-axis robot from
//! A to B, in the shape of MoRC's assembly (trajectory generator → feed-forward → feedback
//! control → robot, watched by a monitor).
//!
//! Every port is an f64 array of `n` = the param `axes` (i64, default 6, 1 to 16) unless said
//! otherwise. A per-axis parameter (marked *per axis*) is a list of `n` values or one value
//! for every axis (`v_max = 2` or `v_max = { 2, 2, 3, 3, 4, 4 }`).
//!
//! | type | inputs | outputs | parameters |
//! |---|---|---|---|
//! | `ptp` | `goal`, `start`, (`handover`) | `q`, `qd`, `qdd`, `done: bool`, `handover` | `v_max`, `a_max` (per axis, required), `bessel_hz` (f64, 0: off), `handover` (bool, false) |
//! | `hold_position` | `start`, (`handover`) | `q`, `qd`, `qdd`, `handover` | `a_max` (per axis, 4), `handover` (bool, false) |
//! | `feedforward` | `q`, `qd`, `qdd` | `tau_ff` | `inertia` (per axis, required), `gravity`, `viscous` (per axis, 0), `coupling` (f64, 0) |
//! | `cascade` | `q_ref`, `qd_ref`, `tau_ff`, `q`, `qd` | `tau` | `kp`, `kv`, `ki`, `tau_max` (per axis, required) |
//! | `monitor` | `q`, `qd`, `q_ref` | `ok: bool`, `code: i64`, `axis: i64` | `q_min`, `q_max`, `qd_max`, `following_max` (per axis, required) |
//! | `waypoints` | `done: bool` | `goal` | `points` (flat list of points, required), `dwell` (f64 s, 0) |
//!
//! All are deterministic, allocate only when made, and never emit NaN: a non-finite input is
//! ignored by the generators and gives 0 on the affected axis of `feedforward` and `cascade`;
//! `monitor` trips on it. Before a component's sources have produced their first outputs its
//! inputs read zeros (LET), and so do its own outputs: `monitor.ok` is false until its first
//! release's outputs are valid.
//!
//! # Layout
//! - [`trajectory`]: `ptp` (synchronized trapezoidal point-to-point motion) and
//!   `hold_position`; [`bessel`]: the 2nd-order Bessel low-pass filter `ptp` may apply;
//!   [`handover`]: the port through which a generator taking over learns the exact command it
//!   replaces (`f64[3·axes + 1]`; an input only with param `handover = true`).
//! - [`feedforward`]: a simplified rigid-body model, τ = M(q)·q̈ + c(q, q̇) + g(q).
//! - [`cascade`]: the P-PI position/velocity cascade with anti-windup.
//! - [`monitor`]: latching limits on position, velocity and following error; a breach is an
//!   unsafe state that faults its assembly.
//! - [`waypoints`]: a robot program's goals, point to point, round and round.
//! - this file: the parameter and port helpers they share, and [`register`].

pub mod bessel;
pub mod cascade;
pub mod feedforward;
pub mod handover;
pub mod monitor;
pub mod trajectory;
pub mod waypoints;

use super::component::{ParamDecl, ParamType, ParamValue, Params, PortDecl, PortType, PortValue};
use super::Registry;

/// The most axes a control component takes.
pub const MAX_AXES: i64 = 16;
/// The axes when the description does not say: a 6-axis industrial robot.
pub const DEFAULT_AXES: i64 = 6;

/// Adds `ptp`, `hold_position`, `feedforward`, `cascade` and `monitor` to `registry`.
pub fn register(registry: &mut Registry) {
    registry.register(trajectory::ptp_info, trajectory::make_ptp);
    registry.register(trajectory::hold_info, trajectory::make_hold);
    registry.register(feedforward::info, feedforward::make);
    registry.register(cascade::info, cascade::make);
    registry.register(monitor::info, monitor::make);
    registry.register(waypoints::info, waypoints::make);
}

/// The `axes` parameter every control component declares.
fn axes_decl() -> ParamDecl {
    ParamDecl::optional("axes", ParamType::I64, ParamValue::I64(DEFAULT_AXES))
}

/// A per-axis parameter that must be given.
fn per_axis_decl(name: &'static str) -> ParamDecl {
    ParamDecl::required(name, ParamType::F64s)
}

/// A per-axis parameter that is `default` on every axis unless given.
fn per_axis_default(name: &'static str, default: f64) -> ParamDecl {
    ParamDecl::optional(name, ParamType::F64s, ParamValue::F64s(vec![default]))
}

/// The number of axes; the default when asked without parameters (the registry's probe).
fn axes(p: &Params) -> Result<usize, String> {
    let n = if p.is_empty() {
        DEFAULT_AXES
    } else {
        p.i64("axes")?
    };
    if !(1..=MAX_AXES).contains(&n) {
        return Err(format!(
            "param 'axes' must be from 1 to {MAX_AXES}, not {n}"
        ));
    }
    Ok(usize::try_from(n).unwrap_or(1))
}

/// A per-axis parameter for `n` axes: a list of `n`, or of one value for every axis. Each
/// value must pass `ok`, which `what` describes ("positive", …).
fn per_axis(
    p: &Params,
    name: &str,
    n: usize,
    what: &str,
    ok: fn(f64) -> bool,
) -> Result<Vec<f64>, String> {
    let xs = p.f64s(name)?;
    let xs = match xs.len() {
        1 => vec![xs[0]; n],
        len if len == n => xs.to_vec(),
        len => {
            return Err(format!(
                "param '{name}' must have 1 value or {n} (one per axis), not {len}"
            ))
        }
    };
    match xs.iter().position(|x| !ok(*x)) {
        Some(i) => Err(format!(
            "param '{name}' must be {what}, not {} (axis {i})",
            xs[i]
        )),
        None => Ok(xs),
    }
}

fn positive(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

fn non_negative(x: f64) -> bool {
    x.is_finite() && x >= 0.0
}

fn finite(x: f64) -> bool {
    x.is_finite()
}

/// Ports named `names`, each an f64 array of `n`.
fn array_ports(names: &[&'static str], n: usize) -> Vec<PortDecl> {
    names
        .iter()
        .map(|name| PortDecl::new(name, PortType::F64s(n)))
        .collect()
}

/// The f64s of an array port (empty if it is not one).
fn array(v: &PortValue) -> &[f64] {
    match v {
        PortValue::F64s(xs) => xs,
        _ => &[],
    }
}

/// The f64s of an array output, to write in place (empty if it is not one).
fn array_mut(v: &mut PortValue) -> &mut [f64] {
    match v {
        PortValue::F64s(xs) => xs,
        _ => &mut [],
    }
}

/// Writes a position at rest: `q` to the first output, zeros to the next two (`qd`, `qdd`).
fn rest(outputs: &mut [PortValue], q: &[f64]) {
    array_mut(&mut outputs[0]).copy_from_slice(q);
    array_mut(&mut outputs[1]).fill(0.0);
    array_mut(&mut outputs[2]).fill(0.0);
}

/// Element `i` of `xs`, NaN when there is none (a short array counts as an invalid input).
fn at(xs: &[f64], i: usize) -> f64 {
    xs.get(i).copied().unwrap_or(f64::NAN)
}

/// Helpers for the unit tests of the control components.
#[cfg(test)]
mod harness {
    use super::*;
    use crate::grid::Component;

    /// A per-axis parameter value.
    pub fn list(xs: &[f64]) -> ParamValue {
        ParamValue::F64s(xs.to_vec())
    }

    /// One instance of a control component on a 1 ms grid, stepped by hand.
    pub struct Harness {
        pub sut: Box<dyn Component>,
        pub outputs: Vec<PortValue>,
    }

    impl Harness {
        /// An instance of `type_name` with `params` (and period `period` base ticks of 1 ms).
        pub fn new(type_name: &str, params: Params, period: u64) -> Harness {
            let mut registry = Registry::new();
            register(&mut registry);
            let mut params = params;
            params.set_timing(0.001, period);
            let info = registry.info(type_name, &params).unwrap();
            let sut = registry.instantiate(type_name, &params).unwrap();
            Harness {
                sut,
                outputs: info.zero_outputs(),
            }
        }

        /// Releases at `tick` with array inputs `inputs`; the outputs.
        pub fn step(&mut self, tick: u64, inputs: &[&[f64]]) -> &[PortValue] {
            let inputs: Vec<PortValue> =
                inputs.iter().map(|x| PortValue::F64s(x.to_vec())).collect();
            self.sut.step(tick, &inputs, &mut self.outputs);
            &self.outputs
        }

        /// A tracking release at `tick` (an assembly being prepared) with `inputs`.
        pub fn track(&mut self, tick: u64, inputs: &[&[f64]]) -> &[PortValue] {
            let inputs: Vec<PortValue> =
                inputs.iter().map(|x| PortValue::F64s(x.to_vec())).collect();
            self.sut.track(tick, &inputs, &mut self.outputs);
            &self.outputs
        }

        /// Output `port` as f64s.
        pub fn out(&self, port: usize) -> &[f64] {
            array(&self.outputs[port])
        }
    }

    /// Why `type_name` refuses `params`.
    pub fn refusal(type_name: &str, params: Params) -> String {
        let mut registry = Registry::new();
        register(&mut registry);
        let mut params = params;
        params.set_timing(0.001, 1);
        match registry.instantiate(type_name, &params) {
            Ok(_) => panic!("{type_name} accepted {params:?}"),
            Err(e) => e,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{reference_run, Component, ComponentInfo};
    use crate::system;

    /// A test-only source of a constant array: `y` = the param `value`.
    fn goal_info(p: &Params) -> Result<ComponentInfo, String> {
        let n = if p.is_empty() {
            1
        } else {
            p.f64s("value")?.len()
        };
        Ok(ComponentInfo {
            type_name: "test_goal",
            doc: "y = value",
            inputs: vec![],
            outputs: array_ports(&["y"], n),
            params: vec![per_axis_decl("value")],
        })
    }

    struct Goal(Vec<f64>);

    impl Component for Goal {
        fn step(&mut self, _: u64, _: &[PortValue], outputs: &mut [PortValue]) {
            array_mut(&mut outputs[0]).copy_from_slice(&self.0);
        }
    }

    /// A test-only plant: per axis a pure double integrator, inertia · q̈ = τ (semi-implicit
    /// Euler at its period), at rest at 0 to begin with.
    fn plant_info(p: &Params) -> Result<ComponentInfo, String> {
        let n = axes(p)?;
        Ok(ComponentInfo {
            type_name: "test_plant",
            doc: "inertia * qdd = tau",
            inputs: array_ports(&["tau"], n),
            outputs: array_ports(&["q", "qd"], n),
            params: vec![axes_decl(), per_axis_decl("inertia")],
        })
    }

    struct Plant {
        inertia: Vec<f64>,
        h: f64,
        q: Vec<f64>,
        qd: Vec<f64>,
    }

    impl Component for Plant {
        fn step(&mut self, _: u64, inputs: &[PortValue], outputs: &mut [PortValue]) {
            for (i, tau) in array(&inputs[0]).iter().enumerate() {
                self.qd[i] += tau / self.inertia[i] * self.h;
                self.q[i] += self.qd[i] * self.h;
            }
            array_mut(&mut outputs[0]).copy_from_slice(&self.q);
            array_mut(&mut outputs[1]).copy_from_slice(&self.qd);
        }
    }

    fn registry() -> Registry {
        let mut registry = Registry::builtin();
        registry.register(goal_info, |p| Ok(Box::new(Goal(p.f64s("value")?.to_vec()))));
        registry.register(plant_info, |p| {
            let n = axes(p)?;
            Ok(Box::new(Plant {
                inertia: per_axis(p, "inertia", n, "positive", positive)?,
                h: p.f64(crate::grid::component::PERIOD_S)?,
                q: vec![0.0; n],
                qd: vec![0.0; n],
            }))
        });
        registry
    }

    const GOAL: [f64; 6] = [0.5, -1.0, 0.8, 1.5, -0.3, 2.0];
    const V_MAX: [f64; 6] = [1.0, 1.0, 1.2, 2.0, 2.0, 2.5];

    /// What a move of the 6-axis test robot from 0 to [`GOAL`] did, as the grid's outputs show.
    #[derive(Debug)]
    struct Move {
        /// The measured positions at the end.
        q: Vec<f64>,
        /// The largest |qd| per axis, commanded by `ptp` and measured at the plant.
        peak_commanded: [f64; 6],
        peak_measured: [f64; 6],
        /// The first tick at which `ptp.done` is valid again after the move began.
        done_at: Option<u64>,
        /// The ticks (after the first) at which `monitor.ok` was not true.
        trips: usize,
    }

    /// Runs 3 s at 1 ms: ptp (with `ptp_params`) → feedforward → cascade (kp, and kv = kv_per_kg
    /// times the axis' inertia) → the double-integrator plant, the monitor watching.
    fn move_a_to_b(ptp_params: &str, kp: f64, kv_per_kg: f64) -> Move {
        let source = format!(
            r#"domain "t"
grid {{ base_period = 0.001 }}
local inertia = {{ 2.0, 3.0, 1.5, 0.5, 0.3, 0.1 }}
local kv = {{}}
for i, m in ipairs(inertia) do kv[i] = {kv_per_kg} * m end
component "goal" {{ type = "test_goal", host = "h", params = {{ value = {{ 0.5, -1.0, 0.8, 1.5, -0.3, 2.0 }} }} }}
component "ptp" {{ type = "ptp", host = "h", params = {{ v_max = {{ 1.0, 1.0, 1.2, 2.0, 2.0, 2.5 }}, a_max = 4{ptp_params} }} }}
component "ff" {{ type = "feedforward", host = "h", params = {{ inertia = inertia }} }}
component "ctl" {{ type = "cascade", host = "h", params = {{ kp = {kp}, kv = kv, ki = 0, tau_max = 100 }} }}
component "robot" {{ type = "test_plant", host = "h", params = {{ inertia = inertia }} }}
component "mon" {{ type = "monitor", host = "h", params = {{ q_min = -3, q_max = 3, qd_max = 3, following_max = 0.01 }} }}
connect "goal.y -> ptp.goal"
connect "robot.q -> ptp.start"
connect "ptp.q -> ff.q"
connect "ptp.qd -> ff.qd"
connect "ptp.qdd -> ff.qdd"
connect "ptp.q -> ctl.q_ref"
connect "ptp.qd -> ctl.qd_ref"
connect "ff.tau_ff -> ctl.tau_ff"
connect "robot.q -> ctl.q"
connect "robot.qd -> ctl.qd"
connect "ctl.tau -> robot.tau"
connect "robot.q -> mon.q"
connect "robot.qd -> mon.qd"
connect "ptp.q -> mon.q_ref"
"#
        );
        let registry = registry();
        let spec =
            system::load_str_with_registry("grid.lua", &source, &|_: &str| None, &[], &registry)
                .unwrap()
                .grid
                .unwrap();
        let index = |name: &str| spec.components.iter().position(|c| c.name == name).unwrap();
        let (ptp, robot, mon) = (index("ptp"), index("robot"), index("mon"));
        let mut sut = Move {
            q: vec![0.0; 6],
            peak_commanded: [0.0; 6],
            peak_measured: [0.0; 6],
            done_at: None,
            trips: 0,
        };
        let peak = |peak: &mut [f64; 6], qd: &[f64]| {
            for (p, v) in peak.iter_mut().zip(qd) {
                *p = p.max(v.abs());
            }
        };
        reference_run(&spec, &registry, 3000, &mut |n, c, out| {
            if c == ptp {
                peak(&mut sut.peak_commanded, array(&out[1]));
                if n > 10 && out[3] == PortValue::Bool(true) && sut.done_at.is_none() {
                    sut.done_at = Some(n);
                }
            } else if c == robot {
                sut.q.copy_from_slice(array(&out[0]));
                peak(&mut sut.peak_measured, array(&out[1]));
            } else if c == mon && n > 0 && out[0] != PortValue::Bool(true) {
                sut.trips += 1;
            }
        })
        .unwrap();
        sut
    }

    /// The built-in registry holds the control components, and they move a 6-axis plant
    /// (double integrators) from 0 to [`GOAL`] in a grid described in Lua: every axis arrives
    /// within 1e-3 in 3 s at 1 ms, the commanded velocity never exceeds v_max, all axes arrive
    /// together, and the monitor never trips.
    #[test]
    fn ptp_feedforward_cascade_moves_a_six_axis_plant_from_a_to_b() {
        let sut = move_a_to_b("", 10.0, 40.0);
        for i in 0..6 {
            let (q, goal) = (sut.q[i], GOAL[i]);
            assert!((q - goal).abs() < 1e-3, "axis {i}: {q} not {goal}");
            assert!(sut.peak_commanded[i] <= V_MAX[i], "axis {i}: {sut:?}");
            // LET puts one tick between ptp and feedforward, so the feedback sees the plant
            // lag its reference and pushes: the plant passes v_max by 0.24 % (gain-independent).
            assert!(
                sut.peak_measured[i] <= V_MAX[i] * 1.003,
                "axis {i}: {sut:?}"
            );
        }
        assert!(
            sut.peak_commanded[5] > V_MAX[5] - 1e-12,
            "axis 5 reaches its limit"
        );
        // The slowest axis (5: 2 rad at 2.5 rad/s, 4 rad/s²) needs 1.425 s: the goal is valid
        // at tick 1, the motion begins two ticks later and ends at its release 1428, whose
        // outputs are valid at 1429.
        assert_eq!(sut.done_at, Some(1 + 2 + 1425 + 1));
        assert_eq!(sut.trips, 0);
        // With a 10 Hz Bessel filter the commanded velocity rounds off (and may pass v_max by
        // the filter's overshoot), and the plant tracks it closer still.
        let sut = move_a_to_b(", bessel_hz = 10", 10.0, 40.0);
        for i in 0..6 {
            assert!((sut.q[i] - GOAL[i]).abs() < 1e-3, "axis {i}: {sut:?}");
            assert!(
                sut.peak_commanded[i] <= V_MAX[i] * 1.0043,
                "axis {i}: {sut:?}"
            );
            assert!(
                sut.peak_measured[i] <= V_MAX[i] * 1.0043,
                "axis {i}: {sut:?}"
            );
        }
        assert_eq!(sut.trips, 0);
    }

    #[test]
    fn builtin_registry_holds_the_control_components() {
        let sut = Registry::builtin();
        for name in ["ptp", "hold_position", "feedforward", "cascade", "monitor"] {
            assert!(sut.describe(name).is_some(), "{name}");
        }
    }
}

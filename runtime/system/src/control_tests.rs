//! The example controllers in a loop from a description: ptp → feedforward → cascade → a
//! test plant, watched by the monitor.

use modbot_control::{
    array, array_mut, array_ports, axes, axes_decl, per_axis, per_axis_decl, positive,
};
use modbot_grid::component::{
    ComponentError, ComponentInfo, Params, PortValue, Registry, Released,
};
use modbot_grid::{reference_run, Component};

/// A test-only source of a constant array: `y` = the param `value`.
fn goal_info(p: &Params) -> Result<ComponentInfo, ComponentError> {
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
    fn step(&mut self, _: &Released, _: &[PortValue], outputs: &mut [PortValue]) {
        array_mut(&mut outputs[0]).copy_from_slice(&self.0);
    }
}

/// A test-only plant: per axis a pure double integrator, inertia · q̈ = τ (semi-implicit
/// Euler at its period), at rest at 0 to begin with.
fn plant_info(p: &Params) -> Result<ComponentInfo, ComponentError> {
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
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        for (i, tau) in array(&inputs[0]).iter().enumerate() {
            self.qd[i] += tau / self.inertia[i] * self.h;
            self.q[i] += self.qd[i] * self.h;
        }
        array_mut(&mut outputs[0]).copy_from_slice(&self.q);
        array_mut(&mut outputs[1]).copy_from_slice(&self.qd);
    }
}

fn registry() -> Registry {
    let mut registry = modbot_components::builtin();
    registry.register(goal_info, |p| Ok(Box::new(Goal(p.f64s("value")?.to_vec()))));
    registry.register(plant_info, |p| {
        let n = axes(p)?;
        Ok(Box::new(Plant {
            inertia: per_axis(p, "inertia", n, "positive", positive)?,
            h: p.f64(modbot_grid::component::PERIOD_S)?,
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
    let spec = crate::load_str_with_registry("grid.lua", &source, &|_: &str| None, &[], &registry)
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

//! modbot-control: example controllers as time-grid components: enough to move a simulated 6-axis robot from
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
//! | `setpoint` | — | `value` | `value` (per axis, required) |
//! | `settle` | `q`, `q_ref`, `done: bool` | `peak_following`, `residual`, `settling_s: f64`, `arrived`, `settled: bool`, `arrival_tick: i64` | `band` (f64 rad, 1e-3), `quiet` (f64 s, 0.1), `lag` (i64 releases, 0) |
//! | `bessel` | `q`, `qd`, `qdd` | `q`, `qd`, `qdd` (filtered) | `bessel_hz` (f64, required) |
//! | `joint_ff` | `q`, `qd`, `qdd` | `q_m`, `qd_m`, `tau_ff` | `model` (`rigid`/`elastic`), `motor_inertia`, `link_inertia`, `stiffness`, `damping`, `viscous`, `coulomb`, `coulomb_velocity` (per axis) |
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
//! - [`low_pass`]: `bessel`, the Bessel low-pass as a component of its own; [`joint_ff`]: the
//!   feed-forward of elastic joints, rigid or elastic (motor demand with the spring deflection).
//! - [`setpoint`]: a constant target (a program command's goal); [`settle`]: how a motion
//!   ends — peak following error, arrival, residual oscillation, settling time (what a
//!   program's command waits for and records).
//! - this file: the parameter and port helpers they share, and [`register`].

pub mod bessel;
pub mod cascade;
pub mod feedforward;
pub mod handover;
pub mod joint_ff;
pub mod low_pass;
pub mod monitor;
pub mod setpoint;
pub mod settle;
pub mod trajectory;
pub mod waypoints;

use modbot_grid::component::{
    ParamDecl, ParamError, ParamType, ParamValue, Params, PortDecl, PortType, PortValue,
};
use modbot_grid::Registry;

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
    registry.register(setpoint::info, setpoint::make);
    registry.register(settle::info, settle::make);
    registry.register(low_pass::info, low_pass::make);
    registry.register(joint_ff::info, joint_ff::make);
}

/// The `axes` parameter every control component declares.
pub fn axes_decl() -> ParamDecl {
    ParamDecl::optional("axes", ParamType::I64, ParamValue::I64(DEFAULT_AXES))
}

/// A per-axis parameter that must be given.
pub fn per_axis_decl(name: &'static str) -> ParamDecl {
    ParamDecl::required(name, ParamType::F64s)
}

/// A per-axis parameter that is `default` on every axis unless given.
fn per_axis_default(name: &'static str, default: f64) -> ParamDecl {
    ParamDecl::optional(name, ParamType::F64s, ParamValue::F64s(vec![default]))
}

/// The number of axes; the default when asked without parameters (the registry's probe).
pub fn axes(p: &Params) -> Result<usize, ParamError> {
    let n = if p.is_empty() {
        DEFAULT_AXES
    } else {
        p.i64("axes")?
    };
    if !(1..=MAX_AXES).contains(&n) {
        let why = format!("must be from 1 to {MAX_AXES}, not {n}");
        return Err(ParamError::invalid("axes", why));
    }
    Ok(usize::try_from(n).unwrap_or(1))
}

/// A per-axis parameter for `n` axes: a list of `n`, or of one value for every axis. Each
/// value must pass `ok`, which `what` describes ("positive", …).
pub fn per_axis(
    p: &Params,
    name: &str,
    n: usize,
    what: &str,
    ok: fn(f64) -> bool,
) -> Result<Vec<f64>, ParamError> {
    let xs = p.f64s(name)?;
    let xs = match xs.len() {
        1 => vec![xs[0]; n],
        len if len == n => xs.to_vec(),
        len => {
            let why = format!("must have 1 value or {n} (one per axis), not {len}");
            return Err(ParamError::invalid(name, why));
        }
    };
    match xs.iter().position(|x| !ok(*x)) {
        Some(i) => {
            let why = format!("must be {what}, not {} (axis {i})", xs[i]);
            Err(ParamError::invalid(name, why))
        }
        None => Ok(xs),
    }
}

/// Whether `x` is positive (a check for [`per_axis`]).
pub fn positive(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

fn non_negative(x: f64) -> bool {
    x.is_finite() && x >= 0.0
}

fn finite(x: f64) -> bool {
    x.is_finite()
}

/// Ports named `names`, each an f64 array of `n`.
pub fn array_ports(names: &[&'static str], n: usize) -> Vec<PortDecl> {
    names
        .iter()
        .map(|name| PortDecl::new(name, PortType::F64s(n)))
        .collect()
}

/// The f64s of an array port (empty if it is not one).
pub fn array(v: &PortValue) -> &[f64] {
    match v {
        PortValue::F64s(xs) => xs,
        _ => &[],
    }
}

/// The f64s of an array output, to write in place (empty if it is not one).
pub fn array_mut(v: &mut PortValue) -> &mut [f64] {
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
    use modbot_grid::Component;

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
            self.sut.step(
                &modbot_grid::component::Released::at(tick),
                &inputs,
                &mut self.outputs,
            );
            &self.outputs
        }

        /// A tracking release at `tick` (an assembly being prepared) with `inputs`.
        pub fn track(&mut self, tick: u64, inputs: &[&[f64]]) -> &[PortValue] {
            let inputs: Vec<PortValue> =
                inputs.iter().map(|x| PortValue::F64s(x.to_vec())).collect();
            self.sut.track(
                &modbot_grid::component::Released::at(tick),
                &inputs,
                &mut self.outputs,
            );
            &self.outputs
        }

        /// Output `port` as f64s.
        pub fn out(&self, port: usize) -> &[f64] {
            array(&self.outputs[port])
        }
    }

    /// Carries `from`'s state into `to` (another instance of its type, same parameters), as a
    /// live upgrade of their host would.
    pub fn carry_into(from: &mut dyn Component, to: &mut dyn Component) {
        modbot_grid::component::carry_state(from, to).unwrap();
    }

    /// Steps three instances made by `make` with `inputs(tick)`: the original through ticks
    /// `0..at` and on to `end`; a second one, its state carried from the original at `at`,
    /// from `at` to `end`; a third, made fresh at `at`, as well. The carried one's outputs are
    /// the original's at every tick, to the bit; the fresh one's differ at some tick (the state
    /// carried matters).
    pub fn carried_steps_as_the_original(
        make: &dyn Fn() -> Harness,
        inputs: &dyn Fn(u64) -> Vec<Vec<f64>>,
        at: u64,
        end: u64,
    ) {
        let (mut old, mut new, mut fresh) = (make(), make(), make());
        let step = |h: &mut Harness, tick: u64| {
            let inputs = inputs(tick);
            let inputs: Vec<&[f64]> = inputs.iter().map(Vec::as_slice).collect();
            h.step(tick, &inputs);
            format!("{:?}", h.outputs)
        };
        for tick in 0..at {
            step(&mut old, tick);
        }
        carry_into(old.sut.as_mut(), new.sut.as_mut());
        let mut fresh_differed = false;
        for tick in at..end {
            let original = step(&mut old, tick);
            assert_eq!(step(&mut new, tick), original, "tick {tick}");
            fresh_differed |= step(&mut fresh, tick) != original;
        }
        assert!(
            fresh_differed,
            "an instance that was not carried steps as the original too: the test shows nothing"
        );
    }

    /// Why `type_name` refuses `params`, as a description's author reads it.
    pub fn refusal(type_name: &str, params: Params) -> String {
        let mut registry = Registry::new();
        register(&mut registry);
        let mut params = params;
        params.set_timing(0.001, 1);
        match registry.instantiate(type_name, &params) {
            Ok(_) => panic!("{type_name} accepted {params:?}"),
            Err(e) => e.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn register_adds_the_control_components() {
        let mut sut = Registry::new();
        register(&mut sut);
        for name in ["ptp", "hold_position", "feedforward", "cascade", "monitor"] {
            assert!(sut.describe(name).is_some(), "{name}");
        }
    }
}

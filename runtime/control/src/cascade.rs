//! `cascade`: a P-PI position/velocity cascade per axis, with the feed-forward torque added.
//!
//! Inputs `q_ref`, `qd_ref` (the desired position and its velocity, fed forward), `tau_ff`
//! (the feed-forward torque), `q`, `qd` (measured); output `tau`. Params `kp` (1/s), `kv`
//! (N·m·s/rad), `ki` (N·m/rad) and `tau_max` (N·m, positive), all per axis. Per axis, with h
//! the component's period:
//!
//! ```text
//! e   = kp·(q_ref − q) + qd_ref − qd       the velocity error: P position loop's output
//! I  += e·h                               unless that drives tau further into saturation
//! tau = clamp(kv·e + ki·I + tau_ff, ±tau_max)
//! ```
//!
//! The anti-windup is conditional integration: the integral does not grow while the output
//! is saturated in the direction the error pushes it, so it unwinds at once when the error
//! turns. A non-finite input gives `tau` = 0 on that axis and leaves its integral as it was.

use super::{
    array, array_mut, array_ports, at, axes, axes_decl, non_negative, per_axis, per_axis_decl,
    positive,
};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, Params, PortValue, Released, PERIOD_S,
};

pub(super) fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        Cascade::new(p)?;
    }
    Ok(ComponentInfo {
        type_name: "cascade",
        doc: "P-PI cascade: tau = PI_v(kp (q_ref - q) + qd_ref - qd) + tau_ff, anti-windup",
        inputs: array_ports(&["q_ref", "qd_ref", "tau_ff", "q", "qd"], n),
        outputs: array_ports(&["tau"], n),
        params: vec![
            axes_decl(),
            per_axis_decl("kp"),
            per_axis_decl("kv"),
            per_axis_decl("ki"),
            per_axis_decl("tau_max"),
        ],
    })
}

pub(super) fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(Cascade::new(p)?))
}

struct Cascade {
    kp: Vec<f64>,
    kv: Vec<f64>,
    ki: Vec<f64>,
    tau_max: Vec<f64>,
    /// The component's period in seconds: the integration step.
    h: f64,
    /// The integral of the velocity error, per axis.
    integral: Vec<f64>,
}

impl Cascade {
    fn new(p: &Params) -> Result<Cascade, ComponentError> {
        let n = axes(p)?;
        let gain = |name| per_axis(p, name, n, "0 or more", non_negative);
        Ok(Cascade {
            kp: gain("kp")?,
            kv: gain("kv")?,
            ki: gain("ki")?,
            tau_max: per_axis(p, "tau_max", n, "positive", positive)?,
            h: p.f64(PERIOD_S)?,
            integral: vec![0.0; n],
        })
    }
}

impl Component for Cascade {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let [q_ref, qd_ref, tau_ff, q, qd] = [0, 1, 2, 3, 4].map(|k| array(&inputs[k]));
        let tau = array_mut(&mut outputs[0]);
        for (i, tau) in tau.iter_mut().enumerate() {
            let e = self.kp[i] * (at(q_ref, i) - at(q, i)) + at(qd_ref, i) - at(qd, i);
            let ff = at(tau_ff, i);
            let (limit, kv, ki) = (self.tau_max[i], self.kv[i], self.ki[i]);
            if !(e.is_finite() && ff.is_finite()) {
                *tau = 0.0;
                continue;
            }
            let integral = self.integral[i] + e * self.h;
            let wanted = kv * e + ki * integral + ff;
            let winding_up = (wanted > limit && e > 0.0) || (wanted < -limit && e < 0.0);
            if !winding_up && integral.is_finite() {
                self.integral[i] = integral;
            }
            let out = kv * e + ki * self.integral[i] + ff;
            *tau = if out.is_finite() {
                out.clamp(-limit, limit)
            } else {
                0.0
            };
        }
    }

    /// The integral of each axis's velocity error (the gains come from the parameters).
    fn carry(
        &mut self,
        c: &mut modbot_grid::carry::Carry<'_>,
    ) -> Result<(), modbot_grid::carry::CarryError> {
        c.f64s("integral", &mut self.integral)
    }
}

#[cfg(test)]
mod tests {
    use super::super::harness::{list, refusal, Harness};
    use super::*;
    use modbot_grid::component::ParamValue;

    fn cascade(ki: f64) -> Harness {
        let params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("kp", list(&[10.0, 20.0]))
            .with("kv", list(&[2.0]))
            .with("ki", list(&[ki]))
            .with("tau_max", list(&[5.0, 50.0]));
        Harness::new("cascade", params, 2)
    }

    fn step(sut: &mut Harness, tick: u64, q_ref: f64, qd_ref: f64, ff: f64, q: f64) -> f64 {
        let two = |x: f64| [x, x];
        sut.step(
            tick,
            &[&two(q_ref), &two(qd_ref), &two(ff), &two(q), &two(0.0)],
        );
        sut.out(0)[0]
    }

    #[test]
    fn its_integral_carried_into_another_instance_mid_motion_goes_on_to_the_bit() {
        let inputs = |tick: u64| {
            let t = tick as f64 * 0.001;
            let two = |x: f64| vec![x, -x];
            vec![two(t), two(1.0), two(0.5), two(0.9 * t), two(0.8)]
        };
        let make = || cascade(7.0);
        super::super::harness::carried_steps_as_the_original(&make, &inputs, 200, 600);
    }

    #[test]
    fn zero_error_gives_the_feed_forward_torque() {
        let mut sut = cascade(7.0);
        sut.step(
            0,
            &[
                &[1.0, -1.0],
                &[0.5, 0.2],
                &[3.0, -4.0],
                &[1.0, -1.0],
                &[0.5, 0.2],
            ],
        );
        assert_eq!(sut.out(0), [3.0, -4.0]);
    }

    #[test]
    fn position_and_velocity_errors_go_through_the_p_and_the_pi() {
        let mut sut = cascade(0.0);
        // e = 10 · 0.1 + 0.2 - 0 = 1.2 on axis 0, 20 · 0.1 + 0.2 = 2.2 on axis 1; tau = 2 e + 1.
        sut.step(0, &[&[0.1; 2], &[0.2; 2], &[1.0; 2], &[0.0; 2], &[0.0; 2]]);
        let tau = sut.out(0);
        assert!(
            (tau[0] - 3.4).abs() < 1e-12 && (tau[1] - 5.4).abs() < 1e-12,
            "{tau:?}"
        );
    }

    #[test]
    fn the_integral_grows_on_a_steady_error_and_stops_at_saturation() {
        let mut sut = cascade(100.0);
        // e = 0.1 rad/s, h = 2 ms: tau = 0.2 + 100 · 0.1 · 0.002 · k = 0.2 + 0.02 k.
        let taus: Vec<f64> = (0..400)
            .map(|k| step(&mut sut, 2 * k, 0.0, 0.1, 0.0, 0.0))
            .collect();
        assert!((taus[0] - 0.22).abs() < 1e-12 && (taus[99] - 2.2).abs() < 1e-9);
        let saturated = taus.iter().position(|&t| t > 5.0 - 1e-9).unwrap();
        assert!((239..=240).contains(&saturated), "{saturated}");
        assert!(taus[saturated..]
            .iter()
            .all(|&t| t == taus[saturated] && t <= 5.0));
        // No windup: as soon as the error turns, the torque leaves the limit.
        let turned = step(&mut sut, 800, 0.0, -0.1, 0.0, 0.0);
        assert!(turned < 5.0 - 0.4, "{turned}");
    }

    #[test]
    fn a_non_finite_input_gives_zero_torque_and_keeps_the_integral() {
        let mut sut = cascade(100.0);
        let before = step(&mut sut, 0, 0.0, 0.1, 0.0, 0.0);
        assert_eq!(step(&mut sut, 2, 0.0, 0.1, 0.0, f64::NAN), 0.0);
        assert_eq!(step(&mut sut, 4, 0.0, 0.1, f64::INFINITY, 0.0), 0.0);
        let after = step(&mut sut, 6, 0.0, 0.1, 0.0, 0.0);
        assert!((after - before - 0.02).abs() < 1e-12, "{before} {after}");
    }

    #[test]
    fn cascade_refuses_a_negative_gain() {
        let params = Params::new()
            .with("kp", list(&[1.0]))
            .with("kv", list(&[-1.0]))
            .with("ki", list(&[0.0]))
            .with("tau_max", list(&[1.0]));
        assert_eq!(
            refusal("cascade", params),
            "param 'kv' must be 0 or more, not -1 (axis 0)"
        );
    }
}

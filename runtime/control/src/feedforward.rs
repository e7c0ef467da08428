//! `feedforward`: the joint torques a simplified rigid-body model of the robot needs to follow
//! a trajectory.
//!
//! Inputs `q`, `qd`, `qdd` (the desired joint positions, velocities, accelerations); output
//! `tau_ff` = M(q)·q̈ + c(q, q̇) + g(q) + viscous·q̇. Params `inertia` (per axis, positive),
//! `gravity`, `viscous` (per axis, 0 unless given) and `coupling` (f64, 0).
//!
//! # The model, and what it leaves out
//! This is not the full rigid-body dynamics of a 6-axis arm (which needs the kinematics and
//! mass properties of every link). It is the part that dominates for a typical industrial arm:
//! - M(q) is diagonal, `inertia` per axis (link and motor inertia seen at the joint, constant),
//!   plus the configuration-dependent terms of a planar two-link arm between the shoulder and
//!   the elbow (0-based axes 1 and 2), with h = `coupling` (m₂·l₁·l_c2, kg·m²):
//!   M₁₁ += 2h·cos q₂ and M₁₂ = M₂₁ = h·cos q₂; its constant off-diagonal inertia is left out.
//! - c(q, q̇) holds that pair's Coriolis and centrifugal torques, c₁ = −h·sin q₂·(2q̇₁q̇₂ + q̇₂²)
//!   and c₂ = h·sin q₂·q̇₁², and a viscous friction `viscous`·q̇ on every axis.
//! - g(q): g_i = `gravity`_i · cos q_i on the shoulder and the elbow (axes 1 and 2), 0 on the
//!   others (their entries of `gravity` are not used). Each link's weight is taken from its own
//!   joint angle, not from the sum of the angles before it as in the real arm.
//!
//! The coupling terms need 3 axes or more. A non-finite result gives 0 on that axis.

use super::{
    array, array_mut, array_ports, at, axes, axes_decl, finite, non_negative, per_axis,
    per_axis_decl, per_axis_default, positive,
};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, ParamValue, Params,
    PortValue, Released,
};

/// The 0-based axes of the shoulder and the elbow.
const SHOULDER: usize = 1;
const ELBOW: usize = 2;

pub(super) fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        Feedforward::new(p)?;
    }
    Ok(ComponentInfo {
        type_name: "feedforward",
        doc: "tau_ff = M(q) qdd + c(q, qd) + g(q) of a simplified rigid-body model",
        inputs: array_ports(&["q", "qd", "qdd"], n),
        outputs: array_ports(&["tau_ff"], n),
        params: vec![
            axes_decl(),
            per_axis_decl("inertia"),
            per_axis_default("gravity", 0.0),
            per_axis_default("viscous", 0.0),
            ParamDecl::optional("coupling", ParamType::F64, ParamValue::F64(0.0)),
        ],
    })
}

pub(super) fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(Feedforward::new(p)?))
}

struct Feedforward {
    inertia: Vec<f64>,
    gravity: Vec<f64>,
    viscous: Vec<f64>,
    /// h of the shoulder–elbow terms (0 with fewer than 3 axes).
    coupling: f64,
}

impl Feedforward {
    fn new(p: &Params) -> Result<Feedforward, ComponentError> {
        let n = axes(p)?;
        let coupling = p.f64("coupling")?;
        if !coupling.is_finite() {
            let why = format!("must be finite, not {coupling}");
            return Err(ParamError::invalid("coupling", why).into());
        }
        Ok(Feedforward {
            inertia: per_axis(p, "inertia", n, "positive", positive)?,
            gravity: per_axis(p, "gravity", n, "finite", finite)?,
            viscous: per_axis(p, "viscous", n, "0 or more", non_negative)?,
            coupling: if n > ELBOW { coupling } else { 0.0 },
        })
    }
}

impl Component for Feedforward {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let (q, qd, qdd) = (array(&inputs[0]), array(&inputs[1]), array(&inputs[2]));
        let tau = array_mut(&mut outputs[0]);
        for (i, tau) in tau.iter_mut().enumerate() {
            let mut t = self.inertia[i] * at(qdd, i) + self.viscous[i] * at(qd, i);
            if i == SHOULDER || i == ELBOW {
                t += self.gravity[i] * at(q, i).cos();
            }
            *tau = t;
        }
        if self.coupling != 0.0 {
            let h = self.coupling;
            let (cos, sin) = (at(q, ELBOW).cos(), at(q, ELBOW).sin());
            let (v1, v2) = (at(qd, SHOULDER), at(qd, ELBOW));
            let (a1, a2) = (at(qdd, SHOULDER), at(qdd, ELBOW));
            tau[SHOULDER] += h * cos * (2.0 * a1 + a2) - h * sin * (2.0 * v1 * v2 + v2 * v2);
            tau[ELBOW] += h * cos * a1 + h * sin * v1 * v1;
        }
        for t in tau.iter_mut().filter(|t| !t.is_finite()) {
            *t = 0.0;
        }
    }

    /// A function of its inputs and parameters: nothing to carry.
    fn carry(
        &mut self,
        _: &mut modbot_grid::carry::Carry<'_>,
    ) -> Result<(), modbot_grid::carry::CarryError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::harness::{list, refusal, Harness};
    use super::*;

    fn feedforward(coupling: f64) -> Harness {
        let params = Params::new()
            .with("axes", ParamValue::I64(4))
            .with("inertia", list(&[1.0, 2.0, 3.0, 4.0]))
            .with("gravity", list(&[9.0, 20.0, 10.0, 7.0]))
            .with("viscous", list(&[0.5]))
            .with("coupling", ParamValue::F64(coupling));
        Harness::new("feedforward", params, 1)
    }

    #[test]
    fn at_rest_it_holds_the_weight_of_shoulder_and_elbow() {
        let mut sut = feedforward(0.8);
        let q = [0.3, 0.0, std::f64::consts::FRAC_PI_3, 1.0];
        sut.step(0, &[&q, &[0.0; 4], &[0.0; 4]]);
        let tau = sut.out(0);
        assert_eq!(tau[0], 0.0);
        assert_eq!(tau[1], 20.0);
        assert!((tau[2] - 5.0).abs() < 1e-12);
        assert_eq!(tau[3], 0.0);
    }

    #[test]
    fn pure_acceleration_takes_inertia_times_acceleration() {
        let mut sut = feedforward(0.0);
        let up = [std::f64::consts::FRAC_PI_2; 4];
        sut.step(0, &[&up, &[0.0; 4], &[1.0, -1.0, 2.0, 0.5]]);
        let tau = sut.out(0);
        assert_eq!(tau[0], 1.0);
        assert!((tau[1] + 2.0).abs() < 1e-12 && (tau[2] - 6.0).abs() < 1e-12);
        assert_eq!(tau[3], 2.0);
    }

    #[test]
    fn the_shoulder_feels_the_elbow_as_a_two_link_arm_does() {
        let mut sut = feedforward(0.8);
        let straight = [0.0, std::f64::consts::FRAC_PI_2, 0.0, 0.0];
        // Stretched out (q2 = 0) the shoulder moves 1 + 2h more, and drags the elbow by h.
        sut.step(0, &[&straight, &[0.0; 4], &[0.0, 1.0, 0.0, 0.0]]);
        let tau = sut.out(0);
        assert!((tau[1] - (2.0 + 1.6)).abs() < 1e-12 && (tau[2] - (10.0 + 0.8)).abs() < 1e-12);
        // Bent at a right angle, turning the shoulder pulls the elbow outwards: h·q̇1².
        let bent = [0.0, 0.0, std::f64::consts::FRAC_PI_2, 0.0];
        sut.step(1, &[&bent, &[0.0, 2.0, 0.0, 0.0], &[0.0; 4]]);
        let tau = sut.out(0);
        assert!((tau[1] - (20.0 + 1.0)).abs() < 1e-12, "{tau:?}");
        assert!((tau[2] - 3.2).abs() < 1e-12, "{tau:?}");
    }

    #[test]
    fn a_non_finite_input_gives_zero_torque_on_that_axis() {
        let mut sut = feedforward(0.0);
        sut.step(0, &[&[0.0; 4], &[0.0, f64::NAN, 0.0, 0.0], &[1.0; 4]]);
        assert_eq!(sut.out(0), [1.0, 0.0, 13.0, 4.0]);
    }

    #[test]
    fn feedforward_refuses_a_non_positive_inertia() {
        let params = Params::new().with("inertia", list(&[1.0, 1.0, -1.0, 1.0, 1.0, 1.0]));
        let sut = refusal("feedforward", params);
        assert_eq!(sut, "param 'inertia' must be positive, not -1 (axis 2)");
    }
}

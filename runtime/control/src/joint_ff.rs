//! `joint_ff`: the feed-forward of an elastic joint (motor, gear spring, link), rigid or
//! elastic — the two the KR16 experiment compares (MoRC's rigid-body and structural-elastic
//! inverse feed-forward).
//!
//! Inputs `q`, `qd`, `qdd`: the desired link trajectory (smooth: through a `bessel` low-pass);
//! outputs the motor-side demand `q_m`, `qd_m` (for the cascade's `q_ref`, `qd_ref`) and the
//! torque `tau_ff`. Params per axis, the joint's model as the simulation has it
//! (`modbot_bus::plant`): `motor_inertia`, `link_inertia`, `stiffness`, `damping`,
//! `viscous`, `coulomb`, `coulomb_velocity`; and `model`, `"rigid"` or `"elastic"`.
//!
//! ```text
//! rigid:    q_m = q,  qd_m = qd,  tau = (Jm + Jl)·q̈ + b·q̇ + τc·tanh(q̇/ωc)
//! elastic:  δ = (Jl/k)·(q̈ − (d/k)·q⃛)            the spring deflection that accelerates the link
//!           q_m = q + δ,  qd_m = q̇ + δ̇,  q̈_m = q̈ + δ̈
//!           tau = Jm·q̈_m + Jl·q̈ + b·qd_m + τc·tanh(qd_m/ωc)
//! ```
//!
//! From `Jl·q̈ = k·δ + d·δ̇` (the link's equation) to first order in d/k: the motor is
//! commanded ahead of the link by exactly the deflection that gives the link its
//! acceleration, so the link follows without exciting its elastic mode. The jerk q⃛ and snap
//! q⁗ are the backward differences of `qdd` over the component's period (a linear filter's
//! output differenced is the filtered difference: exact up to half a period of delay). While
//! its assembly is being prepared it tracks with jerk and snap 0. A non-finite result gives the
//! input position, zero velocity and zero torque on that axis.

use super::{array, array_mut, array_ports, axes, axes_decl, non_negative, per_axis, positive};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, ParamValue, Params,
    PortValue, Released, PERIOD_S,
};

/// The joint parameters and their defaults (those of the simulation's default joint).
const JOINT: [(&str, f64); 7] = [
    ("motor_inertia", 0.5),
    ("link_inertia", 2.0),
    ("stiffness", 2.0e4),
    ("damping", 10.0),
    ("viscous", 1.0),
    ("coulomb", 3.0),
    ("coulomb_velocity", 0.05),
];

pub(super) fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        JointFf::new(p)?;
    }
    let mut params = vec![
        axes_decl(),
        ParamDecl::optional("model", ParamType::Text, ParamValue::Text("rigid".into())),
    ];
    params.extend(JOINT.iter().map(|(name, default)| {
        ParamDecl::optional(name, ParamType::F64s, ParamValue::F64s(vec![*default]))
    }));
    Ok(ComponentInfo {
        type_name: "joint_ff",
        doc: "feed-forward of elastic joints: model rigid, or elastic (motor demand with the spring deflection)",
        inputs: array_ports(&["q", "qd", "qdd"], n),
        outputs: array_ports(&["q_m", "qd_m", "tau_ff"], n),
        params,
    })
}

pub(super) fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(JointFf::new(p)?))
}

/// One joint's model.
#[derive(Debug, Clone, Copy)]
struct Joint {
    jm: f64,
    jl: f64,
    k: f64,
    d: f64,
    b: f64,
    tc: f64,
    wc: f64,
}

impl Joint {
    fn friction(&self, v: f64) -> f64 {
        self.b * v + self.tc * (v / self.wc).tanh()
    }
}

struct JointFf {
    elastic: bool,
    joints: Vec<Joint>,
    /// The period, s: the step of the differences.
    h: f64,
    /// Per axis, the last q̈ and jerk (for the differences).
    last_qdd: Vec<f64>,
    last_jerk: Vec<f64>,
}

impl JointFf {
    fn new(p: &Params) -> Result<JointFf, ComponentError> {
        let n = axes(p)?;
        let elastic = match p.text("model")? {
            "rigid" => false,
            "elastic" => true,
            other => {
                let why = format!("must be \"rigid\" or \"elastic\", not \"{other}\"");
                return Err(ParamError::invalid("model", why).into());
            }
        };
        let get = |name: &str, ok: fn(f64) -> bool, what: &str| per_axis(p, name, n, what, ok);
        let [jm, jl, k, wc] = [
            "motor_inertia",
            "link_inertia",
            "stiffness",
            "coulomb_velocity",
        ]
        .map(|name| get(name, positive, "positive"));
        let [d, b, tc] =
            ["damping", "viscous", "coulomb"].map(|name| get(name, non_negative, "≥ 0"));
        let (jm, jl, k, wc, d, b, tc) = (jm?, jl?, k?, wc?, d?, b?, tc?);
        let joints = (0..n)
            .map(|i| Joint {
                jm: jm[i],
                jl: jl[i],
                k: k[i],
                d: d[i],
                b: b[i],
                tc: tc[i],
                wc: wc[i],
            })
            .collect();
        Ok(JointFf {
            elastic,
            joints,
            h: p.f64(PERIOD_S).unwrap_or(0.001),
            last_qdd: vec![0.0; n],
            last_jerk: vec![0.0; n],
        })
    }

    /// (q_m, qd_m, tau) of axis `i` for the desired (q, q̇, q̈, q⃛, q⁗).
    fn demand(&self, i: usize, [q, qd, qdd, jerk, snap]: [f64; 5]) -> [f64; 3] {
        let j = &self.joints[i];
        if !self.elastic {
            return [q, qd, (j.jm + j.jl) * qdd + j.friction(qd)];
        }
        let c = j.jl / j.k;
        let deflection = c * (qdd - j.d / j.k * jerk);
        let deflection_rate = c * (jerk - j.d / j.k * snap);
        let qdd_m = qdd + c * snap;
        let qd_m = qd + deflection_rate;
        [
            q + deflection,
            qd_m,
            j.jm * qdd_m + j.jl * qdd + j.friction(qd_m),
        ]
    }

    fn compute(&mut self, inputs: &[PortValue], outputs: &mut [PortValue], tracking: bool) {
        let (q, qd, qdd) = (array(&inputs[0]), array(&inputs[1]), array(&inputs[2]));
        for i in 0..self.joints.len() {
            let at = |xs: &[f64]| xs.get(i).copied().unwrap_or(f64::NAN);
            let a = at(qdd);
            let (jerk, snap) = if tracking {
                (0.0, 0.0)
            } else {
                let jerk = (a - self.last_qdd[i]) / self.h;
                (jerk, (jerk - self.last_jerk[i]) / self.h)
            };
            let mut y = self.demand(i, [at(q), at(qd), a, jerk, snap]);
            if y.iter().all(|x| x.is_finite()) {
                self.last_qdd[i] = a;
                self.last_jerk[i] = jerk;
            } else {
                let q = at(q);
                y = [if q.is_finite() { q } else { 0.0 }, 0.0, 0.0];
            }
            for (port, y) in outputs.iter_mut().zip(y) {
                if let Some(slot) = array_mut(port).get_mut(i) {
                    *slot = y;
                }
            }
        }
    }
}

impl Component for JointFf {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        self.compute(inputs, outputs, false);
    }

    fn track(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        self.compute(inputs, outputs, true);
    }

    /// The last acceleration and jerk of each axis (its differences' memory).
    fn carry(
        &mut self,
        c: &mut modbot_grid::carry::Carry<'_>,
    ) -> Result<(), modbot_grid::carry::CarryError> {
        c.f64s("last_qdd", &mut self.last_qdd)?;
        c.f64s("last_jerk", &mut self.last_jerk)
    }
}

#[cfg(test)]
mod tests {
    use super::super::harness::{list, refusal, Harness};
    use modbot_grid::component::{ParamValue, Params};

    fn joint_ff(model: &str) -> Harness {
        let params = Params::new()
            .with("axes", ParamValue::I64(1))
            .with("model", ParamValue::Text(model.into()))
            .with("motor_inertia", list(&[2.0]))
            .with("link_inertia", list(&[8.0]))
            .with("stiffness", list(&[1.0e4]))
            .with("damping", list(&[0.0]))
            .with("viscous", list(&[0.0]))
            .with("coulomb", list(&[0.0]));
        Harness::new("joint_ff", params, 1)
    }

    #[test]
    fn its_differences_carried_into_another_instance_mid_motion_go_on_to_the_bit() {
        let inputs = |tick: u64| {
            let t = tick as f64 * 0.001;
            vec![
                vec![(3.0 * t).sin()],
                vec![3.0 * (3.0 * t).cos()],
                vec![-9.0 * (3.0 * t).sin()],
            ]
        };
        let make = || joint_ff("elastic");
        super::super::harness::carried_steps_as_the_original(&make, &inputs, 100, 300);
    }

    #[test]
    fn rigid_commands_the_link_trajectory_with_the_whole_inertia() {
        // Jm + Jl = 10 kg·m² at 2 rad/s²: 20 Nm.
        let mut sut = joint_ff("rigid");
        sut.step(0, &[&[0.1], &[0.5], &[2.0]]);
        assert_eq!((sut.out(0)[0], sut.out(1)[0]), (0.1, 0.5));
        assert!((sut.out(2)[0] - 20.0).abs() < 1e-12, "{:?}", sut.out(2));
    }

    #[test]
    fn elastic_leads_the_link_by_the_deflection_its_acceleration_needs() {
        let mut sut = joint_ff("elastic");
        // A constant acceleration of 2 rad/s²: deflection Jl·a/k = 8·2/1e4 = 1.6 mrad.
        sut.track(0, &[&[0.0], &[0.0], &[2.0]]);
        sut.step(1, &[&[0.05], &[0.4], &[2.0]]);
        sut.step(2, &[&[0.1], &[0.5], &[2.0]]);
        assert!(
            (sut.out(0)[0] - (0.1 + 1.6e-3)).abs() < 1e-12,
            "{:?}",
            sut.out(0)
        );
        assert!((sut.out(1)[0] - 0.5).abs() < 1e-12);
        assert!((sut.out(2)[0] - 20.0).abs() < 1e-9, "{:?}", sut.out(2));
    }

    #[test]
    fn a_model_other_than_rigid_or_elastic_is_refused() {
        let params = Params::new().with("model", ParamValue::Text("flexible".into()));
        let e = refusal("joint_ff", params);
        assert!(e.contains("\"rigid\" or \"elastic\""), "{e}");
    }
}

//! `bessel`: a trajectory through a 2nd-order Bessel low-pass ([`super::bessel::Bessel2`]), as
//! a component of its own between a generator and a feed-forward (MoRC's PTP → Bessel →
//! feed-forward chain).
//!
//! Inputs `q`, `qd`, `qdd`; outputs the same, filtered (each by the same linear filter, so the
//! filtered `qd` is still the derivative of the filtered `q`). Param `bessel_hz` (f64, the
//! cutoff, above 0 and below the Nyquist frequency of its period).
//!
//! At its first release, and at every release while its assembly is being prepared (track),
//! the filters are put at rest at the inputs: it takes over without a transient.

use super::bessel::Bessel2;
use super::{array, array_mut, array_ports, axes, axes_decl};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, Params, PortValue,
    Released, PERIOD_S,
};

pub(super) fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        LowPass::new(p)?;
    }
    Ok(ComponentInfo {
        type_name: "bessel",
        doc: "q, qd, qdd through a 2nd-order Bessel low-pass at bessel_hz",
        inputs: array_ports(&["q", "qd", "qdd"], n),
        outputs: array_ports(&["q", "qd", "qdd"], n),
        params: vec![
            axes_decl(),
            ParamDecl::required("bessel_hz", ParamType::F64),
        ],
    })
}

pub(super) fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(LowPass::new(p)?))
}

struct LowPass {
    /// Per axis, the filters of q, qd and qdd.
    filters: Vec<[Bessel2; 3]>,
    /// Whether the filters were put at rest at the inputs.
    started: bool,
}

impl LowPass {
    fn new(p: &Params) -> Result<LowPass, ComponentError> {
        let n = axes(p)?;
        let cutoff = p.f64("bessel_hz")?;
        let period = p.f64(PERIOD_S).unwrap_or(0.001);
        let filter = Bessel2::new(cutoff, period)
            .map_err(|e| ParamError::invalid("bessel_hz", e.to_string()))?;
        Ok(LowPass {
            filters: vec![[filter; 3]; n],
            started: false,
        })
    }

    fn rest(&mut self, inputs: &[PortValue]) {
        for (i, filters) in self.filters.iter_mut().enumerate() {
            for (k, filter) in filters.iter_mut().enumerate() {
                let x = array(&inputs[k]).get(i).copied().unwrap_or(0.0);
                filter.reset(if x.is_finite() { x } else { 0.0 });
            }
        }
    }
}

impl Component for LowPass {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        if !std::mem::replace(&mut self.started, true) {
            self.rest(inputs);
        }
        for (k, out) in outputs.iter_mut().enumerate().take(3) {
            let input = array(&inputs[k]);
            for (i, y) in array_mut(out).iter_mut().enumerate() {
                let x = input.get(i).copied().unwrap_or(0.0);
                // A non-finite sample is not fed to the filter (it would stay NaN forever).
                *y = self.filters[i][k].step(if x.is_finite() { x } else { 0.0 });
            }
        }
    }

    fn track(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        self.rest(inputs);
        self.started = true;
        self.step(rel, inputs, outputs);
    }

    /// Every filter's state, and whether they were put at rest (the coefficients come from
    /// the parameters).
    fn carry(
        &mut self,
        c: &mut modbot_grid::carry::Carry<'_>,
    ) -> Result<(), modbot_grid::carry::CarryError> {
        c.length("axes", self.filters.len())?;
        for filter in self.filters.iter_mut().flatten() {
            filter.carry(c)?;
        }
        c.bool("started", &mut self.started)
    }
}

#[cfg(test)]
mod tests {
    use super::super::harness::Harness;
    use modbot_grid::component::{ParamValue, Params};

    fn low_pass() -> Harness {
        let params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("bessel_hz", ParamValue::F64(8.0));
        Harness::new("bessel", params, 1)
    }

    #[test]
    fn its_filters_carried_into_another_instance_mid_step_go_on_to_the_bit() {
        let inputs = |tick: u64| {
            let q = if tick < 50 { 0.2 } else { 1.0 };
            vec![vec![q, -q], vec![0.1 * q, 0.0], vec![0.0, 0.3 * q]]
        };
        super::super::harness::carried_steps_as_the_original(&low_pass, &inputs, 60, 400);
    }

    #[test]
    fn it_starts_at_rest_where_its_inputs_are_and_follows_a_step_smoothly() {
        let mut sut = low_pass();
        let (q, zero) = ([0.5, -0.5], [0.0, 0.0]);
        sut.step(0, &[&q, &zero, &zero]);
        assert!(
            (sut.out(0)[0] - 0.5).abs() < 1e-12,
            "no transient from zero"
        );
        let mut seen = Vec::new();
        for tick in 1..1000 {
            sut.step(tick, &[&[1.0, -0.5], &zero, &zero]);
            seen.push(sut.out(0)[0]);
        }
        // The Bessel step response: no undershoot, 0.43 % overshoot at most, then at rest.
        assert!(seen
            .iter()
            .all(|&y| (0.5..=1.0 + 0.0045 * 0.5).contains(&y)));
        assert!((seen[998] - 1.0).abs() < 1e-6, "{}", seen[998]);
        assert!((sut.out(0)[1] + 0.5).abs() < 1e-12);
    }

    #[test]
    fn tracking_rests_at_the_inputs() {
        let mut sut = low_pass();
        let zero = [0.0, 0.0];
        sut.step(0, &[&zero, &zero, &zero]);
        sut.track(1, &[&[0.3, 0.2], &zero, &zero]);
        assert!((sut.out(0)[0] - 0.3).abs() < 1e-12 && (sut.out(0)[1] - 0.2).abs() < 1e-12);
        sut.step(2, &[&[0.3, 0.2], &zero, &zero]);
        assert!((sut.out(0)[0] - 0.3).abs() < 1e-12);
    }

    #[test]
    fn a_cutoff_above_nyquist_is_refused() {
        let params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("bessel_hz", ParamValue::F64(600.0));
        let e = super::super::harness::refusal("bessel", params);
        assert!(e.contains("Nyquist"), "{e}");
    }
}

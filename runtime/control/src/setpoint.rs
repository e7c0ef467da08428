//! `setpoint`: a constant target for the axes — the goal a robot program's command gives its
//! assembly (read from assembly data when the assembly is loaded).
//!
//! No inputs; output `value` (f64 array of `axes`) = param `value` (per axis, finite) at every
//! release.

use super::{array_mut, array_ports, axes, axes_decl, finite, per_axis, per_axis_decl};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, Params, PortValue, Released,
};

pub(super) fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        Setpoint::new(p)?;
    }
    Ok(ComponentInfo {
        type_name: "setpoint",
        doc: "a constant target: value = param value, per axis",
        inputs: Vec::new(),
        outputs: array_ports(&["value"], n),
        params: vec![axes_decl(), per_axis_decl("value")],
    })
}

pub(super) fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(Setpoint::new(p)?))
}

struct Setpoint {
    value: Vec<f64>,
}

impl Setpoint {
    fn new(p: &Params) -> Result<Setpoint, ComponentError> {
        let n = axes(p)?;
        Ok(Setpoint {
            value: per_axis(p, "value", n, "finite", finite)?,
        })
    }
}

impl Component for Setpoint {
    fn step(&mut self, _: &Released, _: &[PortValue], outputs: &mut [PortValue]) {
        array_mut(&mut outputs[0]).copy_from_slice(&self.value);
    }

    /// Its value comes from its parameters: nothing to carry.
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
    use modbot_grid::component::{ParamValue, Params};

    #[test]
    fn a_setpoint_puts_out_its_value_at_every_release() {
        let params = Params::new()
            .with("axes", ParamValue::I64(3))
            .with("value", list(&[0.1, -0.2, 0.3]));
        let mut sut = Harness::new("setpoint", params, 1);
        for tick in 0..3 {
            sut.step(tick, &[]);
            assert_eq!(sut.out(0), [0.1, -0.2, 0.3]);
        }
    }

    #[test]
    fn a_setpoint_carries_nothing_and_a_carried_one_puts_out_the_same_value() {
        let params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("value", list(&[0.5, -0.25]));
        let mut old = Harness::new("setpoint", params.clone(), 1);
        let mut new = Harness::new("setpoint", params, 1);
        old.step(0, &[]);
        super::super::harness::carry_into(old.sut.as_mut(), new.sut.as_mut());
        new.step(1, &[]);
        assert_eq!(new.out(0), [0.5, -0.25]);
    }

    #[test]
    fn a_setpoint_of_the_wrong_length_is_refused() {
        let params = Params::new()
            .with("axes", ParamValue::I64(3))
            .with("value", list(&[0.1, 0.2]));
        let e = refusal("setpoint", params);
        assert!(e.contains("must have 1 value or 3"), "{e}");
    }
}

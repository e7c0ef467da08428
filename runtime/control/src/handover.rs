//! The handover port: what a trajectory generator will command two ticks on, forwarded by the
//! bus to the generator of an assembly that takes over, so that a switch is bumpless in
//! position *and* velocity whatever the running motion does in the ticks it takes to get there.
//!
//! A generator that only sees the demand the bus last commanded sees it two ticks late (LET:
//! one tick from the generator to the bus, one from the bus back) and must extrapolate; when
//! the running motion changes its acceleration in those ticks (a trapezoid's corner, the end
//! of a braking), the extrapolated velocity misses by that change times two or three ticks.
//! The running generator knows its own plan, so it writes the command it will give
//! [`TICKS`] ticks on; the bus forwards it one tick later; an incoming generator released live
//! for the first time reads, at that very tick, the command it replaces.
//!
//! Layout (`f64[3·axes + 1]`): `q` per axis, `qd` per axis, `qdd` per axis, then a flag that
//! is 1 when the values are valid. It is 0 in the port's initial value (before any generator
//! wrote one) and when the bus is in safe stop (the drives then do not follow the running
//! assembly): the incoming generator then extrapolates the bus's `demand_position` instead.
//!
//! Components: `ptp` and `hold_position` write output `handover` always; with param
//! `handover = true` they also read input `handover` (connect it to the bus's). The `bus` with
//! param `handover = true` has input `handover` (connect the running generator's) and output
//! `handover` (its input as of the last cycle). All three assume period 1.

use super::{array, array_mut};
use modbot_grid::component::{
    ParamDecl, ParamError, ParamType, ParamValue, Params, PortDecl, PortType, PortValue,
};

/// The port's (and the param's) name.
pub const NAME: &str = "handover";

/// How many ticks ahead a generator writes: one tick to the bus, one back.
pub const TICKS: u64 = 2;

/// The handover port of `axes` axes.
pub fn port(axes: usize) -> PortDecl {
    PortDecl::new(NAME, PortType::F64s(3 * axes + 1))
}

/// Param `handover` (bool, default false): whether the component has the handover input.
pub fn param() -> ParamDecl {
    ParamDecl::optional(NAME, ParamType::Bool, ParamValue::Bool(false))
}

/// Whether `p` asks for the handover input.
pub fn wanted(p: &Params) -> Result<bool, ParamError> {
    Ok(p.get(NAME).is_some() && p.bool(NAME)?)
}

/// A valid handover of `axes` axes as read from a port.
#[derive(Debug, Clone, Copy)]
pub struct Handover<'a> {
    values: &'a [f64],
    axes: usize,
}

impl<'a> Handover<'a> {
    /// The handover in `value` if it is one of `axes` axes, flagged valid and finite
    /// throughout; `None` otherwise (take over from the demand instead).
    pub fn read(value: &'a PortValue, axes: usize) -> Option<Handover<'a>> {
        let values = array(value);
        let valid = values.len() == 3 * axes + 1
            && values[3 * axes] == 1.0
            && values.iter().all(|x| x.is_finite());
        valid.then_some(Handover { values, axes })
    }

    /// The commanded positions.
    pub fn q(&self) -> &'a [f64] {
        &self.values[..self.axes]
    }

    /// The commanded velocities.
    pub fn qd(&self) -> &'a [f64] {
        &self.values[self.axes..2 * self.axes]
    }
}

/// Writes a valid handover: `command(axis)` is that axis's `[q, qd, qdd]`.
pub fn write(out: &mut PortValue, mut command: impl FnMut(usize) -> [f64; 3]) {
    let values = array_mut(out);
    let axes = values.len() / 3;
    if values.len() != 3 * axes + 1 {
        return;
    }
    for i in 0..axes {
        let [q, qd, qdd] = command(i);
        values[i] = q;
        values[axes + i] = qd;
        values[2 * axes + i] = qdd;
    }
    values[3 * axes] = 1.0;
}

/// Marks a handover invalid (its values stay, nobody takes over from them).
pub fn invalidate(out: &mut PortValue) {
    if let Some(flag) = array_mut(out).last_mut() {
        *flag = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_handover_reads_back_per_axis_and_an_invalidated_one_does_not() {
        let mut port = PortValue::F64s(vec![0.0; 7]);
        assert!(
            Handover::read(&port, 2).is_none(),
            "the initial zeros are no handover"
        );
        write(&mut port, |i| [i as f64, 10.0 + i as f64, 20.0 + i as f64]);
        assert_eq!(
            port,
            PortValue::F64s(vec![0.0, 1.0, 10.0, 11.0, 20.0, 21.0, 1.0])
        );
        let h = Handover::read(&port, 2).unwrap();
        assert_eq!((h.q(), h.qd()), (&[0.0, 1.0][..], &[10.0, 11.0][..]));
        assert!(
            Handover::read(&port, 3).is_none(),
            "the width names the axes"
        );
        invalidate(&mut port);
        assert!(Handover::read(&port, 2).is_none());
    }

    #[test]
    fn a_handover_with_a_value_that_is_not_finite_is_not_taken() {
        let mut port = PortValue::F64s(vec![0.0; 4]);
        write(&mut port, |_| [f64::NAN, 0.0, 0.0]);
        assert!(Handover::read(&port, 1).is_none());
    }
}

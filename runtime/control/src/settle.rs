//! `settle`: how a motion ends — the peak following error, the arrival, the residual
//! oscillation after it and the settling time. What a robot program's command waits for (its
//! finish condition) and records in assembly data (its results).
//!
//! Inputs `q` (measured: the link position, what the arm really does) and `q_ref` (commanded),
//! f64 arrays of `axes`, and `done: bool` (the trajectory generator's). Params `band` (f64
//! rad, default 1e-3: the settling band), `quiet` (f64 s, default 0.1: how long the error must
//! stay in the band to count as settled), `lag` (i64 releases, default 0: `q` is compared with
//! `q_ref` as it was that many releases before — the releases it takes the reference to reach
//! the robot through the components between, one each under LET).
//!
//! Counting starts at the first live release (a release while the assembly is being prepared,
//! to track, starts it afresh). The error is e = max over the axes of |q_ref − q| (q_ref
//! `lag` releases old).
//!
//! | output | |
//! |---|---|
//! | `peak_following: f64` | the largest e so far |
//! | `arrived: bool` | the generator arrived: `done` read true after it read false (it moved); or it never read false within 0.5 s (there was nowhere to go) |
//! | `arrival_tick: i64` | the tick it arrived at, −1 before |
//! | `residual: f64` | the largest e since the arrival: the residual oscillation |
//! | `settling_s: f64` | from the arrival to the last release with e > `band` (0 if none) |
//! | `settled: bool` | arrived, and e ≤ `band` at every release of the last `quiet` seconds |
//!
//! A non-finite e counts as outside the band and does not change the peaks.

use super::{array, axes, axes_decl, non_negative};
use modbot_grid::component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, ParamValue, Params,
    PortDecl, PortType, PortValue, Released, BASE_PERIOD_S, PERIOD_S,
};

/// Seconds without a reading of `done` = false after which the generator counts as arrived.
const NO_MOTION_S: f64 = 0.5;

pub(super) fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let n = axes(p)?;
    if !p.is_empty() {
        Settle::new(p)?;
    }
    Ok(ComponentInfo {
        type_name: "settle",
        doc:
            "how a motion ends: peak following error, arrival, residual oscillation, settling time",
        inputs: vec![
            PortDecl::new("q", PortType::F64s(n)),
            PortDecl::new("q_ref", PortType::F64s(n)),
            PortDecl::new("done", PortType::Bool),
        ],
        outputs: vec![
            PortDecl::new("peak_following", PortType::F64),
            PortDecl::new("arrived", PortType::Bool),
            PortDecl::new("arrival_tick", PortType::I64),
            PortDecl::new("residual", PortType::F64),
            PortDecl::new("settling_s", PortType::F64),
            PortDecl::new("settled", PortType::Bool),
        ],
        params: vec![
            axes_decl(),
            ParamDecl::optional("band", ParamType::F64, ParamValue::F64(1e-3)),
            ParamDecl::optional("quiet", ParamType::F64, ParamValue::F64(0.1)),
            ParamDecl::optional("lag", ParamType::I64, ParamValue::I64(0)),
        ],
    })
}

pub(super) fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(Settle::new(p)?))
}

/// What one motion did so far.
#[derive(Debug, Clone, Copy, Default)]
struct Motion {
    /// The first live release's tick, once there was one.
    first: Option<u64>,
    moved: bool,
    arrival: Option<u64>,
    peak: f64,
    residual: f64,
    /// The last tick since the arrival with the error outside the band.
    last_outside: Option<u64>,
}

struct Settle {
    band: f64,
    /// The last `lag + 1` references, oldest first from `next` (a ring).
    refs: Vec<Vec<f64>>,
    next: usize,
    /// Whether `refs` holds references (filled at the first release).
    filled: bool,
    /// `quiet` and [`NO_MOTION_S`] in base ticks.
    quiet_ticks: u64,
    no_motion_ticks: u64,
    base_period_s: f64,
    motion: Motion,
}

impl Settle {
    fn new(p: &Params) -> Result<Settle, ComponentError> {
        let band = p.f64("band")?;
        if !(band.is_finite() && band > 0.0) {
            let why = format!("must be a positive number of rad, not {band}");
            return Err(ParamError::invalid("band", why).into());
        }
        let quiet = p.f64("quiet")?;
        if !non_negative(quiet) {
            let why = format!("must be a number of seconds ≥ 0, not {quiet}");
            return Err(ParamError::invalid("quiet", why).into());
        }
        let lag = p.i64("lag")?;
        if !(0..=10_000).contains(&lag) {
            let why = format!("must be 0 to 10000 releases, not {lag}");
            return Err(ParamError::invalid("lag", why).into());
        }
        let n = super::axes(p)?;
        // The registry's probe has no timing: a millisecond then.
        let base = p.f64(BASE_PERIOD_S).unwrap_or(0.001);
        let period = p.f64(PERIOD_S).unwrap_or(base);
        let ticks = |s: f64| (s / base).round().max(0.0) as u64;
        Ok(Settle {
            band,
            refs: vec![vec![0.0; n]; lag as usize + 1],
            next: 0,
            filled: false,
            quiet_ticks: ticks(quiet),
            no_motion_ticks: ticks(NO_MOTION_S).max(ticks(period)),
            base_period_s: base,
            motion: Motion::default(),
        })
    }
}

impl Settle {
    /// Every reference of the history `q_ref` (a robot at rest there).
    fn fill(&mut self, q_ref: &[f64]) {
        for slot in &mut self.refs {
            for (r, x) in slot.iter_mut().zip(q_ref) {
                *r = *x;
            }
        }
    }
}

impl Component for Settle {
    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let tick = rel.tick.0;
        let q = array(&inputs[0]);
        if !std::mem::replace(&mut self.filled, true) {
            self.fill(array(&inputs[1]));
        }
        // In with the newest reference, out with the one `lag` releases old.
        let slot = &mut self.refs[self.next];
        for (r, x) in slot.iter_mut().zip(array(&inputs[1])) {
            *r = *x;
        }
        self.next = (self.next + 1) % self.refs.len();
        let q_ref = &self.refs[self.next][..];
        let done = matches!(inputs[2], PortValue::Bool(true));
        let e = q_ref
            .iter()
            .zip(q)
            .map(|(r, m)| (r - m).abs())
            .fold(
                0.0f64,
                |acc, x| if x.is_nan() { f64::NAN } else { acc.max(x) },
            );
        let m = &mut self.motion;
        let first = *m.first.get_or_insert(tick);
        if e.is_finite() {
            m.peak = m.peak.max(e);
        }
        if m.arrival.is_none() {
            m.moved |= !done;
            let nowhere = !m.moved && tick.saturating_sub(first) >= self.no_motion_ticks;
            if (m.moved && done) || nowhere {
                m.arrival = Some(tick);
            }
        }
        let outside = e.is_nan() || e > self.band;
        if let Some(arrival) = m.arrival {
            if e.is_finite() {
                m.residual = m.residual.max(e);
            }
            if outside {
                m.last_outside = Some(tick);
            }
            let quiet_since = m.last_outside.map_or(arrival, |t| t + 1);
            let settled = !outside && tick.saturating_sub(quiet_since) + 1 >= self.quiet_ticks;
            let settling = m.last_outside.map_or(0, |t| t.saturating_sub(arrival));
            outputs[1] = PortValue::Bool(true);
            outputs[2] = PortValue::I64(i64::try_from(arrival).unwrap_or(i64::MAX));
            outputs[3] = PortValue::F64(m.residual);
            outputs[4] = PortValue::F64(settling as f64 * self.base_period_s);
            outputs[5] = PortValue::Bool(settled);
        } else {
            outputs[1] = PortValue::Bool(false);
            outputs[2] = PortValue::I64(-1);
            outputs[3] = PortValue::F64(0.0);
            outputs[4] = PortValue::F64(0.0);
            outputs[5] = PortValue::Bool(false);
        }
        outputs[0] = PortValue::F64(m.peak);
    }

    /// While its assembly is prepared nothing moves by its generator yet: it starts afresh.
    fn track(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        self.step(rel, inputs, outputs);
        self.motion = Motion::default();
        // The history starts afresh too: at rest, every past reference is the current one.
        self.fill(array(&inputs[1]));
    }

    /// The references of its lag, where the ring stands, and the motion measured so far.
    fn carry(
        &mut self,
        c: &mut modbot_grid::carry::Carry<'_>,
    ) -> Result<(), modbot_grid::carry::CarryError> {
        c.length("lag", self.refs.len())?;
        for refs in &mut self.refs {
            c.f64s("references", refs)?;
        }
        let mut next = self.next as u64;
        c.u64("next", &mut next)?;
        self.next = usize::try_from(next).unwrap_or(0) % self.refs.len().max(1);
        c.bool("filled", &mut self.filled)?;
        let m = &mut self.motion;
        c.optional_u64("first", &mut m.first)?;
        c.bool("moved", &mut m.moved)?;
        c.optional_u64("arrival", &mut m.arrival)?;
        c.f64("peak", &mut m.peak)?;
        c.f64("residual", &mut m.residual)?;
        c.optional_u64("last_outside", &mut m.last_outside)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_grid::Registry;

    fn settle(band: f64, quiet: f64) -> (Box<dyn Component>, Vec<PortValue>) {
        let mut registry = Registry::new();
        super::super::register(&mut registry);
        let mut params = Params::new()
            .with("axes", ParamValue::I64(2))
            .with("band", ParamValue::F64(band))
            .with("quiet", ParamValue::F64(quiet));
        params.set_timing(0.001, 1);
        let info = registry.info("settle", &params).unwrap();
        (
            registry.instantiate("settle", &params).unwrap(),
            info.zero_outputs(),
        )
    }

    fn step(sut: &mut dyn Component, out: &mut [PortValue], tick: u64, e: f64, done: bool) {
        let inputs = [
            PortValue::F64s(vec![0.0, -e]),
            PortValue::F64s(vec![0.0, 0.0]),
            PortValue::Bool(done),
        ];
        sut.step(&Released::at(tick), &inputs, out);
    }

    fn f(v: &PortValue) -> f64 {
        v.as_f64()
    }

    #[test]
    fn a_motion_carried_into_another_instance_after_its_arrival_is_measured_on_to_the_bit() {
        let error = |t: u64| match t {
            0 => 0.0,
            1..=20 => 0.02 * t as f64,
            _ => 0.4 * (-(t as f64 - 20.0) / 10.0).exp() * ((t as f64) * 0.7).cos(),
        };
        let run = |sut: &mut dyn Component, out: &mut Vec<PortValue>, t: u64| {
            step(sut, out, t, error(t), t > 20);
            format!("{out:?}")
        };
        let (mut old, mut old_out) = settle(0.01, 0.01);
        let (mut new, mut new_out) = settle(0.01, 0.01);
        let (mut fresh, mut fresh_out) = settle(0.01, 0.01);
        for t in 0..30 {
            run(&mut *old, &mut old_out, t);
        }
        modbot_grid::component::carry_state(&mut *old, &mut *new).unwrap();
        let mut fresh_differed = false;
        for t in 30..200 {
            let original = run(&mut *old, &mut old_out, t);
            assert_eq!(run(&mut *new, &mut new_out, t), original, "tick {t}");
            fresh_differed |= run(&mut *fresh, &mut fresh_out, t) != original;
        }
        assert!(fresh_differed, "the motion carried matters");
        assert_eq!(new_out[1], PortValue::Bool(true), "arrived");
    }

    #[test]
    fn a_motion_is_measured_from_its_arrival_until_it_settles() {
        let (mut sut, mut out) = settle(0.01, 0.003);
        step(&mut *sut, &mut out, 0, 0.0, true);
        // Moving: the following error peaks at 0.5.
        for (t, e) in [(1, 0.2), (2, 0.5), (3, 0.3)] {
            step(&mut *sut, &mut out, t, e, false);
        }
        assert_eq!(out[1], PortValue::Bool(false));
        assert_eq!(f(&out[0]), 0.5);
        // Arrived at 4 with an error of 0.05, oscillating out of the band until 6.
        for (t, e) in [(4, 0.05), (5, -0.02), (6, 0.011), (7, 0.001), (8, 0.0)] {
            step(&mut *sut, &mut out, t, e, true);
        }
        assert_eq!(out[1], PortValue::Bool(true));
        assert_eq!(out[2], PortValue::I64(4));
        assert_eq!(f(&out[3]), 0.05);
        assert!((f(&out[4]) - 0.002).abs() < 1e-12, "{:?}", out[4]);
        assert_eq!(
            out[5],
            PortValue::Bool(false),
            "in the band for 2 of 3 ticks"
        );
        step(&mut *sut, &mut out, 9, 0.0, true);
        assert_eq!(out[5], PortValue::Bool(true));
        assert_eq!(f(&out[0]), 0.5);
    }

    #[test]
    fn a_generator_that_never_moves_has_arrived_after_half_a_second() {
        let (mut sut, mut out) = settle(0.01, 0.0);
        for t in 10..510 {
            step(&mut *sut, &mut out, t, 0.0, true);
        }
        assert_eq!(out[1], PortValue::Bool(false));
        step(&mut *sut, &mut out, 510, 0.0, true);
        assert_eq!(out[2], PortValue::I64(510));
        assert_eq!(out[5], PortValue::Bool(true));
    }

    #[test]
    fn tracking_starts_the_measurement_afresh() {
        let (mut sut, mut out) = settle(0.01, 0.0);
        step(&mut *sut, &mut out, 0, 0.0, false);
        let inputs = [
            PortValue::F64s(vec![0.0, 0.0]),
            PortValue::F64s(vec![0.0, 0.9]),
            PortValue::Bool(true),
        ];
        sut.track(&Released::at(1), &inputs, &mut out);
        step(&mut *sut, &mut out, 2, 0.1, true);
        assert_eq!(f(&out[0]), 0.1, "the tracked error does not count");
        assert_eq!(
            out[1],
            PortValue::Bool(false),
            "the tracked move does not count"
        );
    }

    #[test]
    fn with_a_lag_the_measure_compares_with_the_reference_that_many_releases_old() {
        let mut registry = Registry::new();
        super::super::register(&mut registry);
        let mut params = Params::new()
            .with("axes", ParamValue::I64(1))
            .with("lag", ParamValue::I64(2));
        params.set_timing(0.001, 1);
        let info = registry.info("settle", &params).unwrap();
        let mut sut = registry.instantiate("settle", &params).unwrap();
        let mut out = info.zero_outputs();
        // The robot follows the reference exactly, two releases late.
        let reference = [0.0, 0.1, 0.2, 0.3, 0.3, 0.3];
        for t in 0..reference.len() {
            let q = reference[t.saturating_sub(2)];
            let inputs = [
                PortValue::F64s(vec![q]),
                PortValue::F64s(vec![reference[t]]),
                PortValue::Bool(false),
            ];
            sut.step(&Released::at(t as u64), &inputs, &mut out);
        }
        assert_eq!(
            f(&out[0]),
            0.0,
            "no following error once the lag is taken out"
        );
    }

    #[test]
    fn a_nan_error_is_outside_the_band_and_no_peak() {
        let (mut sut, mut out) = settle(0.01, 0.0);
        step(&mut *sut, &mut out, 0, 0.0, false);
        step(&mut *sut, &mut out, 1, 0.02, true);
        step(&mut *sut, &mut out, 2, f64::NAN, true);
        assert_eq!(f(&out[0]), 0.02);
        assert_eq!(out[5], PortValue::Bool(false));
    }
}

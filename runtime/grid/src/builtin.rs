//! The built-in component types: sources, arithmetic and test helpers for the time grid.
//!
//! All are deterministic (their outputs depend only on their parameters, the release ticks and
//! their inputs) and none allocates in `step`, except `sleeper`, whose whole point is to sleep
//! so that tests can provoke an overrun.
//!
//! | type | inputs | outputs | parameters |
//! |---|---|---|---|
//! | `counter` | | `y: i64` = start + number of releases so far (1, 2, 3, …) | `start` (i64, 0) |
//! | `ramp` | | `y: f64` = slope · tick · base_period_s | `slope` (f64, 1) |
//! | `sine` | | `y: f64` = amplitude · sin(2π · freq · tick · base_period_s) | `amplitude` (1), `freq` (Hz, 1) |
//! | `gain` | `u: f64` | `y: f64` = k · u | `k` (f64, required) |
//! | `sum` | `a: f64`, `b: f64` | `y: f64` = a + b | |
//! | `integrator` | `u: f64` | `y: f64` += u · period_s at each release | `initial` (f64, 0) |
//! | `lowpass` | `u: f64` | `y: f64` ← a·y + (1 − a)·k·u, a = e^(−period_s/T) (T y' = k u − y, u held) | `k` (f64, 1), `T` (s ≥ 0, 0.01) |
//! | `delay` | `u: f64` | `y: f64` = the u of the previous release | `initial` (f64, 0) |
//! | `vec_gain` | `u: f64[n]` | `y: f64[n]` = k · u | `n` (i64 1..=64, required), `k` (f64, required) |
//! | `pack` | `a: f64`, `b: f64` | `v: f64[2]` = [a, b] | |
//! | `sleeper` | `u: f64` | `y: f64` = u | `sleep_ms` (f64 ≥ 0, 0), `sleep_at` (i64, -1: never), `sleep_tracking` (i64: its first n tracking releases sleep, 0), `sleep_live` (bool: every release that is not tracking sleeps, false) |
//!
//! Until its first release's outputs are valid, a type puts out its declared start value
//! ([`Component::initial_outputs`]): `counter` its `start`, `integrator` and `delay` their
//! `initial`; the others 0.

use std::f64::consts::PI;
use std::time::Duration;

use super::carry::{Carry, CarryError};
use super::component::{
    Component, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, ParamValue, Params,
    PortDecl, PortType, PortValue, Registry, Released, BASE_PERIOD_S, PERIOD_S,
};

/// The grid's own built-in types with the data recorder's declaration: what the grid's tests
/// use. Every built-in type (the controllers and the bus too) is `modbot_components::builtin`.
pub fn grid_registry() -> Registry {
    let mut registry = Registry::new();
    register_all(&mut registry);
    crate::record_type::declare(&mut registry);
    registry
}

/// Adds the grid's built-in types to `registry` (the controllers are `modbot-control`'s, the
/// bus `modbot-bus`'s; `modbot-components` assembles them all).
pub fn register_all(registry: &mut Registry) {
    registry.register(counter_info, |p| {
        Ok(Box::new(Counter { y: p.i64("start")? }))
    });
    registry.register(ramp_info, |p| {
        Ok(Box::new(Ramp {
            slope: p.f64("slope")?,
            dt: p.f64(BASE_PERIOD_S)?,
        }))
    });
    registry.register(sine_info, |p| {
        Ok(Box::new(Sine {
            amplitude: p.f64("amplitude")?,
            freq: p.f64("freq")?,
            dt: p.f64(BASE_PERIOD_S)?,
        }))
    });
    registry.register(gain_info, |p| Ok(Box::new(Gain { k: p.f64("k")? })));
    registry.register(sum_info, |_| Ok(Box::new(Sum)));
    registry.register(integrator_info, |p| {
        Ok(Box::new(Integrator {
            y: p.f64("initial")?,
            h: p.f64(PERIOD_S)?,
        }))
    });
    registry.register(lowpass_info, |p| {
        let time_constant = p.f64("T")?;
        if time_constant.is_nan() || time_constant < 0.0 {
            let why = format!("must be 0 or more seconds, not {time_constant}");
            return Err(ParamError::invalid("T", why).into());
        }
        Ok(Box::new(Lowpass {
            y: 0.0,
            k: p.f64("k")?,
            time_constant,
            h: p.f64(PERIOD_S)?,
        }))
    });
    registry.register(delay_info, |p| {
        Ok(Box::new(Delay {
            last: p.f64("initial")?,
        }))
    });
    registry.register(vec_gain_info, |p| {
        vec_len(p)?;
        Ok(Box::new(VecGain { k: p.f64("k")? }))
    });
    registry.register(pack_info, |_| Ok(Box::new(Pack)));
    registry.register(sleeper_info, |p| {
        Ok(Box::new(Sleeper {
            sleep: sleep_of(p)?,
            at: u64::try_from(p.i64("sleep_at")?).ok(),
            tracking: u64::try_from(p.i64("sleep_tracking")?).unwrap_or(0),
            live: p.bool("sleep_live")?,
        }))
    });
}

fn f64_param(name: &'static str, default: f64) -> ParamDecl {
    ParamDecl::optional(name, ParamType::F64, ParamValue::F64(default))
}

/// The description of a type whose ports are all f64 (the common case).
fn f64_info(
    type_name: &'static str,
    doc: &'static str,
    inputs: &[&'static str],
    outputs: &[&'static str],
    params: Vec<ParamDecl>,
) -> Result<ComponentInfo, ComponentError> {
    let ports = |names: &[&'static str]| {
        let port = |&name| PortDecl::new(name, PortType::F64);
        names.iter().map(port).collect()
    };
    Ok(ComponentInfo {
        type_name,
        doc,
        inputs: ports(inputs),
        outputs: ports(outputs),
        params,
    })
}

/// Writes `y` to an f64 output (no allocation: the slot holds an f64 already).
fn put(slot: &mut PortValue, y: f64) {
    *slot = PortValue::F64(y);
}

// ---- sources: counter, ramp, sine ----

fn counter_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    let start = ParamDecl::optional("start", ParamType::I64, ParamValue::I64(0));
    let mut info = f64_info(
        "counter",
        "y = start + number of releases",
        &[],
        &[],
        vec![start],
    )?;
    info.outputs.push(PortDecl::new("y", PortType::I64));
    Ok(info)
}

struct Counter {
    /// The last output: start plus the releases so far.
    y: i64,
}

impl Component for Counter {
    /// `start`: no release has counted yet.
    fn initial_outputs(&mut self, outputs: &mut [PortValue]) {
        outputs[0] = PortValue::I64(self.y);
    }

    fn step(&mut self, _: &Released, _: &[PortValue], outputs: &mut [PortValue]) {
        self.y = self.y.wrapping_add(1);
        outputs[0] = PortValue::I64(self.y);
    }

    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        c.i64("y", &mut self.y)
    }
}

fn ramp_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    let doc = "a ramp in time: y = slope * tick * base_period_s";
    f64_info("ramp", doc, &[], &["y"], vec![f64_param("slope", 1.0)])
}

struct Ramp {
    slope: f64,
    /// The base tick in seconds: a tick number times this is the time.
    dt: f64,
}

impl Component for Ramp {
    fn step(&mut self, rel: &Released, _: &[PortValue], outputs: &mut [PortValue]) {
        let tick = rel.tick.0;
        put(&mut outputs[0], self.slope * tick as f64 * self.dt);
    }

    /// A function of the tick and its parameters: nothing to carry.
    fn carry(&mut self, _: &mut Carry<'_>) -> Result<(), CarryError> {
        Ok(())
    }
}

fn sine_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    let doc = "a sine in time: y = amplitude * sin(2 pi * freq * tick * base_period_s)";
    let params = vec![f64_param("amplitude", 1.0), f64_param("freq", 1.0)];
    f64_info("sine", doc, &[], &["y"], params)
}

struct Sine {
    amplitude: f64,
    freq: f64,
    /// The base tick in seconds.
    dt: f64,
}

impl Component for Sine {
    fn step(&mut self, rel: &Released, _: &[PortValue], outputs: &mut [PortValue]) {
        let tick = rel.tick.0;
        let y = self.amplitude * (2.0 * PI * self.freq * tick as f64 * self.dt).sin();
        put(&mut outputs[0], y);
    }

    fn carry(&mut self, _: &mut Carry<'_>) -> Result<(), CarryError> {
        Ok(())
    }
}

// ---- arithmetic: gain, sum ----

fn gain_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    let k = ParamDecl::required("k", ParamType::F64);
    f64_info("gain", "y = k * u", &["u"], &["y"], vec![k])
}

struct Gain {
    k: f64,
}

impl Component for Gain {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        put(&mut outputs[0], self.k * inputs[0].as_f64());
    }

    fn carry(&mut self, _: &mut Carry<'_>) -> Result<(), CarryError> {
        Ok(())
    }
}

fn sum_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    f64_info("sum", "y = a + b", &["a", "b"], &["y"], vec![])
}

struct Sum;

impl Component for Sum {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        put(&mut outputs[0], inputs[0].as_f64() + inputs[1].as_f64());
    }

    fn carry(&mut self, _: &mut Carry<'_>) -> Result<(), CarryError> {
        Ok(())
    }
}

// ---- state: integrator, delay ----

fn integrator_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    let doc = "forward Euler at its own period: y += u * period_s at each release";
    let params = vec![f64_param("initial", 0.0)];
    f64_info("integrator", doc, &["u"], &["y"], params)
}

struct Integrator {
    /// The integral so far.
    y: f64,
    /// The component's own period in seconds: the step of the integration.
    h: f64,
}

impl Component for Integrator {
    /// `initial`: nothing integrated yet.
    fn initial_outputs(&mut self, outputs: &mut [PortValue]) {
        put(&mut outputs[0], self.y);
    }

    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        self.y += inputs[0].as_f64() * self.h;
        put(&mut outputs[0], self.y);
    }

    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        c.f64("y", &mut self.y)
    }
}

fn lowpass_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    let doc = "first-order low-pass with gain, T y' = k u - y, exact for u held over its period";
    let params = vec![f64_param("k", 1.0), f64_param("T", 0.01)];
    f64_info("lowpass", doc, &["u"], &["y"], params)
}

/// The arithmetic of the FMU `modbot_filter3` (fmus/filter3), step for step: the native
/// counterpart of the FMU benchmark (`modbot-benches fmu`).
struct Lowpass {
    y: f64,
    k: f64,
    /// T, seconds (0: y = k·u).
    time_constant: f64,
    /// Its period, seconds.
    h: f64,
}

impl Component for Lowpass {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let a = if self.time_constant > 0.0 {
            (-self.h / self.time_constant).exp()
        } else {
            0.0
        };
        self.y = a * self.y + (1.0 - a) * self.k * inputs[0].as_f64();
        put(&mut outputs[0], self.y);
    }

    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        c.f64("y", &mut self.y)
    }
}

fn delay_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    let doc = "y = the u of the previous release (initial at the first)";
    f64_info(
        "delay",
        doc,
        &["u"],
        &["y"],
        vec![f64_param("initial", 0.0)],
    )
}

struct Delay {
    /// The input of the previous release.
    last: f64,
}

impl Component for Delay {
    /// `initial`: what its first release puts out too.
    fn initial_outputs(&mut self, outputs: &mut [PortValue]) {
        put(&mut outputs[0], self.last);
    }

    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        put(&mut outputs[0], self.last);
        self.last = inputs[0].as_f64();
    }

    /// Its output and the input it will put out next: two delays with equal outputs but
    /// different inputs waiting are in different states.
    fn state_hash(&self, outputs: &[PortValue], hasher: &mut crate::StateHasher) {
        hasher.outputs(outputs);
        hasher.f64(self.last);
    }

    fn carry(&mut self, c: &mut Carry<'_>) -> Result<(), CarryError> {
        c.f64("last", &mut self.last)
    }
}

// ---- arrays: vec_gain, pack ----

/// The longest array `vec_gain` takes.
const MAX_VEC: i64 = 64;

/// `vec_gain`'s length; a placeholder of 1 when asked without parameters.
fn vec_len(p: &Params) -> Result<usize, ParamError> {
    let n = if p.is_empty() { 1 } else { p.i64("n")? };
    if !(1..=MAX_VEC).contains(&n) {
        let why = format!("must be from 1 to {MAX_VEC}, not {n}");
        return Err(ParamError::invalid("n", why));
    }
    Ok(usize::try_from(n).unwrap_or(1))
}

fn vec_gain_info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let ty = PortType::F64s(vec_len(p)?);
    let params = vec![
        ParamDecl::required("n", ParamType::I64),
        ParamDecl::required("k", ParamType::F64),
    ];
    let mut info = f64_info("vec_gain", "y = k * u for arrays of n", &[], &[], params)?;
    info.inputs.push(PortDecl::new("u", ty));
    info.outputs.push(PortDecl::new("y", ty));
    Ok(info)
}

struct VecGain {
    k: f64,
}

impl Component for VecGain {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        if let (PortValue::F64s(y), PortValue::F64s(u)) = (&mut outputs[0], &inputs[0]) {
            for (y, u) in y.iter_mut().zip(u) {
                *y = self.k * u;
            }
        }
    }

    /// A function of its input: nothing to carry.
    fn carry(&mut self, _: &mut Carry<'_>) -> Result<(), CarryError> {
        Ok(())
    }
}

fn pack_info(_: &Params) -> Result<ComponentInfo, ComponentError> {
    let mut info = f64_info("pack", "v = [a, b]", &["a", "b"], &[], vec![])?;
    info.outputs.push(PortDecl::new("v", PortType::F64s(2)));
    Ok(info)
}

struct Pack;

impl Component for Pack {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        if let PortValue::F64s(v) = &mut outputs[0] {
            v[0] = inputs[0].as_f64();
            v[1] = inputs[1].as_f64();
        }
    }

    /// A function of its inputs: nothing to carry.
    fn carry(&mut self, _: &mut Carry<'_>) -> Result<(), CarryError> {
        Ok(())
    }
}

// ---- sleeper ----

fn sleeper_info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    if !p.is_empty() {
        sleep_of(p)?;
    }
    let doc = "y = u; sleeps sleep_ms when released at tick sleep_at, on its first \
               sleep_tracking tracking releases, or on every live release (sleep_live), to \
               provoke an overrun";
    let params = vec![
        f64_param("sleep_ms", 0.0),
        ParamDecl::optional("sleep_at", ParamType::I64, ParamValue::I64(-1)),
        ParamDecl::optional("sleep_tracking", ParamType::I64, ParamValue::I64(0)),
        ParamDecl::optional("sleep_live", ParamType::Bool, ParamValue::Bool(false)),
    ];
    f64_info("sleeper", doc, &["u"], &["y"], params)
}

fn sleep_of(p: &Params) -> Result<Duration, ParamError> {
    let ms = p.f64("sleep_ms")?;
    Duration::try_from_secs_f64(ms / 1000.0).map_err(|_| {
        ParamError::invalid(
            "sleep_ms",
            format!("must be 0 or more milliseconds, not {ms}"),
        )
    })
}

/// A pass-through that sleeps once, at one release: a test helper that blocks in `step` on
/// purpose (the one built-in that breaks the real-time rules, to check they are enforced).
struct Sleeper {
    sleep: Duration,
    /// The release tick that sleeps; none when negative.
    at: Option<u64>,
    /// Tracking releases (of an assembly being prepared) left that sleep.
    tracking: u64,
    /// Every live release sleeps.
    live: bool,
}

impl Component for Sleeper {
    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        let tick = rel.tick.0;
        if (self.at == Some(tick) || self.live) && !self.sleep.is_zero() {
            std::thread::sleep(self.sleep);
        }
        put(&mut outputs[0], inputs[0].as_f64());
    }

    fn track(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        if self.tracking > 0 && !self.sleep.is_zero() {
            self.tracking -= 1;
            std::thread::sleep(self.sleep);
        }
        put(&mut outputs[0], inputs[0].as_f64());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(type_name: &str, params: Params, ticks: &[(u64, Vec<PortValue>)]) -> Vec<PortValue> {
        let registry = grid_registry();
        let info = registry.info(type_name, &params).unwrap();
        let mut sut = registry.instantiate(type_name, &params).unwrap();
        let mut outputs = info.zero_outputs();
        let mut seen = Vec::new();
        for (tick, inputs) in ticks {
            sut.step(&Released::at(*tick), inputs, &mut outputs);
            seen.push(outputs[0].clone());
        }
        sut.terminate();
        seen
    }

    fn timing(period: u64) -> Params {
        let mut p = Params::new();
        p.set_timing(0.5, period);
        p
    }

    /// Steps a fresh instance of `type_name` through `ticks`, carries its state into another
    /// after `split` of them, and steps both on: every output equal to the bit.
    fn carried_steps_on_the_same(
        type_name: &str,
        params: &Params,
        ticks: &[(u64, Vec<PortValue>)],
        split: usize,
    ) {
        let registry = grid_registry();
        let info = registry.info(type_name, params).unwrap();
        let mut old = registry.instantiate(type_name, params).unwrap();
        let mut new = registry.instantiate(type_name, params).unwrap();
        let (mut a, mut b) = (info.zero_outputs(), info.zero_outputs());
        old.initial_outputs(&mut a);
        for (tick, inputs) in &ticks[..split] {
            old.step(&Released::at(*tick), inputs, &mut a);
        }
        crate::component::carry_state(old.as_mut(), new.as_mut()).unwrap();
        for (tick, inputs) in &ticks[split..] {
            old.step(&Released::at(*tick), inputs, &mut a);
            new.step(&Released::at(*tick), inputs, &mut b);
            let bits = |v: &[PortValue]| {
                format!(
                    "{:?}",
                    v.iter().map(|p| p.as_f64().to_bits()).collect::<Vec<_>>()
                )
            };
            assert_eq!(bits(&a), bits(&b), "{type_name} at tick {tick}");
        }
    }

    #[test]
    fn every_stateful_builtin_carried_into_another_instance_steps_on_to_the_bit() {
        let input = |tick: u64| vec![PortValue::F64((tick as f64 * 0.37).sin())];
        let ticks: Vec<(u64, Vec<PortValue>)> = (0..40).map(|t| (t, input(t))).collect();
        let start = Params::new().with("start", ParamValue::I64(10));
        carried_steps_on_the_same("counter", &start, &ticks, 17);
        carried_steps_on_the_same(
            "integrator",
            &timing(2).with("initial", ParamValue::F64(0.5)),
            &ticks,
            17,
        );
        carried_steps_on_the_same(
            "lowpass",
            &timing(1).with("T", ParamValue::F64(3.0)),
            &ticks,
            17,
        );
        carried_steps_on_the_same("delay", &timing(1), &ticks, 17);
        carried_steps_on_the_same("ramp", &timing(1), &ticks, 17);
        carried_steps_on_the_same(
            "gain",
            &timing(1).with("k", ParamValue::F64(2.5)),
            &ticks,
            17,
        );
    }

    #[test]
    fn a_type_that_cannot_carry_its_state_says_so() {
        let registry = grid_registry();
        let mut sut = registry.instantiate("sleeper", &timing(1)).unwrap();
        assert_eq!(
            sut.carry(&mut Carry::measure()),
            Err(CarryError::Unsupported)
        );
    }

    #[test]
    fn a_declared_start_value_is_the_initial_output_and_zero_otherwise() {
        let initial = |type_name: &str, params: Params| {
            let registry = grid_registry();
            let info = registry.info(type_name, &params).unwrap();
            let mut sut = registry.instantiate(type_name, &params).unwrap();
            let mut outputs = info.zero_outputs();
            sut.initial_outputs(&mut outputs);
            outputs[0].clone()
        };
        let start = Params::new().with("start", ParamValue::I64(10));
        assert_eq!(initial("counter", start), PortValue::I64(10));
        for type_name in ["integrator", "delay"] {
            let mut p = timing(1).with("initial", ParamValue::F64(-2.5));
            p.set_timing(0.5, 1);
            assert_eq!(initial(type_name, p), PortValue::F64(-2.5), "{type_name}");
        }
        let gain = timing(1).with("k", ParamValue::F64(3.0));
        assert_eq!(initial("gain", gain), PortValue::F64(0.0));
    }

    #[test]
    fn sources_follow_their_formulas() {
        let no_inputs = |ticks: &[u64]| ticks.iter().map(|t| (*t, vec![])).collect::<Vec<_>>();
        let counter = run(
            "counter",
            Params::new().with("start", ParamValue::I64(10)),
            &no_inputs(&[0, 1, 2]),
        );
        assert_eq!(counter, [11, 12, 13].map(PortValue::I64));
        let ramp = run(
            "ramp",
            timing(1).with("slope", ParamValue::I64(2)),
            &no_inputs(&[0, 3]),
        );
        assert_eq!(ramp, [0.0, 3.0].map(PortValue::F64));
        let sine = run("sine", timing(1), &no_inputs(&[1]));
        assert_eq!(sine, [PortValue::F64((PI).sin())]);
    }

    #[test]
    fn stateful_components_integrate_and_delay_at_their_own_period() {
        let u = |tick: u64, x: f64| (tick, vec![PortValue::F64(x)]);
        let integrated = run("integrator", timing(2), &[u(0, 1.0), u(2, 3.0)]);
        assert_eq!(integrated, [1.0, 4.0].map(PortValue::F64));
        let delayed = run("delay", Params::new(), &[u(0, 1.0), u(1, 2.0), u(2, 3.0)]);
        assert_eq!(delayed, [0.0, 1.0, 2.0].map(PortValue::F64));
    }

    #[test]
    fn a_components_state_hash_is_its_outputs_unless_it_holds_more_state() {
        let registry = grid_registry();
        let hash = |sut: &dyn Component, outputs: &[PortValue]| {
            let mut h = crate::StateHasher::new();
            sut.state_hash(outputs, &mut h);
            h.finish()
        };
        let gain = Params::new().with("k", ParamValue::F64(2.0));
        let sut = registry.instantiate("gain", &gain).unwrap();
        let mut by_outputs = crate::StateHasher::new();
        by_outputs.outputs(&[PortValue::F64(4.0)]);
        assert_eq!(hash(&*sut, &[PortValue::F64(4.0)]), by_outputs.finish());
        // Two delays putting out 1.0, one with 2.0 waiting and one with 3.0.
        let mut a = registry.instantiate("delay", &Params::new()).unwrap();
        let mut b = registry.instantiate("delay", &Params::new()).unwrap();
        let mut out = [PortValue::F64(0.0)];
        for (sut, next) in [(&mut a, 2.0), (&mut b, 3.0)] {
            sut.step(&Released::at(0), &[PortValue::F64(1.0)], &mut out);
            sut.step(&Released::at(1), &[PortValue::F64(next)], &mut out);
        }
        assert_eq!(out, [PortValue::F64(1.0)]);
        assert_ne!(hash(&*a, &out), hash(&*b, &out));
    }

    #[test]
    fn array_components_take_their_length_from_a_param() {
        let registry = grid_registry();
        let params = Params::new()
            .with("n", ParamValue::I64(3))
            .with("k", ParamValue::F64(2.0));
        let info = registry.info("vec_gain", &params).unwrap();
        assert_eq!(info.output_types(), [PortType::F64s(3)]);
        let y = run(
            "vec_gain",
            params,
            &[(0, vec![PortValue::F64s(vec![1.0, 2.0, 3.0])])],
        );
        assert_eq!(y, [PortValue::F64s(vec![2.0, 4.0, 6.0])]);
        let too_long = Params::new()
            .with("n", ParamValue::I64(65))
            .with("k", ParamValue::F64(1.0));
        let sut = registry.info("vec_gain", &too_long).unwrap_err();
        assert!(
            matches!(&sut, ComponentError::Param(ParamError::Invalid { name, .. }) if name == "n"),
            "{sut:?}"
        );
        assert_eq!(sut.to_string(), "param 'n' must be from 1 to 64, not 65");
        let v = run(
            "pack",
            Params::new(),
            &[(0, vec![PortValue::F64(1.0), PortValue::F64(2.0)])],
        );
        assert_eq!(v, [PortValue::F64s(vec![1.0, 2.0])]);
    }

    #[test]
    fn sleeper_sleeps_only_at_its_tick() {
        let params = Params::new()
            .with("sleep_ms", ParamValue::F64(30.0))
            .with("sleep_at", ParamValue::I64(1));
        let started = std::time::Instant::now();
        let y = run(
            "sleeper",
            params,
            &[
                (0, vec![PortValue::F64(1.0)]),
                (1, vec![PortValue::F64(2.0)]),
            ],
        );
        assert!(started.elapsed() >= Duration::from_millis(30));
        assert_eq!(y, [1.0, 2.0].map(PortValue::F64));
        let negative = Params::new().with("sleep_ms", ParamValue::F64(-1.0));
        assert!(grid_registry().info("sleeper", &negative).is_err());
    }

    #[test]
    fn registry_checks_params_against_the_declarations() {
        let sut = grid_registry();
        assert_eq!(
            sut.type_names().len(),
            12,
            "11 built in, and the data recorder"
        );
        let err = sut.info("gain", &Params::new()).unwrap_err().to_string();
        assert_eq!(err, "param 'k' (f64) is required for type 'gain'");
        let err = sut
            .info("gain", &Params::new().with("q", ParamValue::F64(1.0)))
            .unwrap_err()
            .to_string();
        assert_eq!(err, "unknown param 'q' for type 'gain' (params: k)");
        let err = sut
            .info(
                "gain",
                &Params::new().with("k", ParamValue::Text("x".into())),
            )
            .unwrap_err();
        let ComponentError::Param(ParamError::WrongType { expected, got, .. }) = &err else {
            panic!("{err:?}");
        };
        assert_eq!(
            (*expected, got),
            (ParamType::F64, &ParamValue::Text("x".into()))
        );
        assert_eq!(err.to_string(), "param 'k' must be f64, not \"x\"");
        let err = sut.info("gian", &Params::new()).unwrap_err().to_string();
        assert!(err.starts_with("unknown component type 'gian' (known: counter, ramp,"));
        let complete = sut
            .complete(
                "counter",
                &Params::new().with(BASE_PERIOD_S, ParamValue::I64(1)),
            )
            .unwrap();
        let names: Vec<&str> = complete.iter().map(|(n, _)| n).collect();
        assert_eq!(names, ["start", BASE_PERIOD_S]);
        assert_eq!(complete.f64(BASE_PERIOD_S), Ok(1.0));
    }
}

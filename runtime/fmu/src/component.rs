//! The `fmu` component, as the host program `modbot-fmu-host` makes it: at every release its
//! inputs are set, `doStep` runs one period, and its outputs are got — into buffers laid out
//! once ([`crate::values`]), so a release allocates nothing.
//!
//! The FMU's time is the grid's: the co-simulation starts at the time of the component's
//! first release (its tick × the base period; `startTime` of `fmi2SetupExperiment` or
//! `fmi3EnterInitializationMode`), so it is initialised at that release, and each release
//! steps it by the component's period from there (a co-simulation master's communication
//! points) — an FMU of the system starts at 0, one of an assembly at the tick its first
//! (tracking) release came. Its time lines up with the built-in components' (`sine`, `ramp`)
//! and the recorder's `time`; a release a host could not execute (stale) is a step the FMU
//! does not take, and its time falls behind by that period. So that a parameter the FMU
//! refuses at initialisation is an error when the component is made, not at its first
//! release, `make` first initialises a probe instance of the FMU (at time 0) and frees it.
//!
//! Before its first outputs are valid, the component's outputs are its *initial outputs*
//! ([`Component::initial_outputs`]): the probe's outputs after initialisation at time 0 with
//! its parameters and its inputs at their start values (what a master such as FMPy reports at
//! t = 0).
//!
//! A failing FMI call — one that returns fmi2Discard/fmi3Discard or worse, or a step after
//! which the FMU asks to terminate — is an unsafe state ([`Component::unsafe_state`]): the
//! coordinator faults the assembly and the bus stops the drives, as for a monitor's breach;
//! the outputs keep their last values. The host logs which call failed, with what status, at
//! what time, and the last messages the FMU logged. A crash of the FMU's code takes its host
//! process down, and the grid's fault policy applies.
//!
//! An i64 port into an FMI `Int32` input is clamped to what an Int32 holds; the first clamped
//! value of each input is logged ([`crate::values`]).

use modbot_grid::component::{
    Component, ComponentError, Params, PortValue, Registry, Released, BASE_PERIOD_S, PERIOD_S,
};

use super::call::CallError;
use super::component_type::{self, FMU};
use super::error::{FmuError, FmuErrorKind};
use super::running::Running;
use super::values::Values;

/// Adds `fmu`, made by this process, to `registry` (the program `modbot-fmu-host`).
pub fn register(registry: &mut Registry) {
    registry.register_open(component_type::info, make);
}

/// An FMU component for these (complete) params: the FMU unpacked, instantiated, its
/// parameters set (and found to initialise, by a probe instance); it is initialised at its
/// first release.
pub fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    Ok(Box::new(build(p)?))
}

fn build(p: &Params) -> Result<FmuComponent, ComponentError> {
    let interface = component_type::read(p)?;
    let path = p.text(FMU)?;
    let refused = |e| ComponentError::param_refused(FMU, e);
    let mut probe = Running::start(path, &interface, &interface.model_name, p).map_err(refused)?;
    let mut initial = Values::new(&interface.outputs);
    let probed = probe.initialise(0.0).and_then(|()| probe.get(&mut initial));
    if let Err(call) = probed {
        let why = format!("{call}{}", probe.said());
        return Err(refused(FmuError::new(path, FmuErrorKind::Import(why))));
    }
    probe.terminate();
    drop(probe);
    let running = Running::start(path, &interface, &interface.model_name, p).map_err(refused)?;
    tracing::info!(
        "FMI {} FMU '{}' from {path}: {} input(s), {} output(s)",
        interface.version.name(),
        interface.model_name,
        interface.inputs.len(),
        interface.outputs.len()
    );
    Ok(FmuComponent {
        running,
        inputs: Values::new(&interface.inputs),
        input_names: interface.inputs.iter().map(|i| i.name.clone()).collect(),
        // The last outputs got: the initial ones until the first step's.
        outputs: initial.clone(),
        initial,
        time: None,
        base_period: p.f64(BASE_PERIOD_S)?,
        step: p.f64(PERIOD_S)?,
        failed: None,
    })
}

struct FmuComponent {
    running: Running,
    inputs: Values,
    /// The inputs' names, to say which one a value was clamped on.
    input_names: Vec<String>,
    outputs: Values,
    /// The outputs after initialisation (the probe's): valid before its first outputs are.
    initial: Values,
    /// The FMU's time at the next release; `None` until it is initialised, at its first.
    time: Option<f64>,
    /// The grid's base period, s: the time of a tick.
    base_period: f64,
    /// The communication step: the component's period, in seconds.
    step: f64,
    /// Why the FMU failed — which call, its status, the time and what the FMU logged: it is
    /// not stepped again.
    failed: Option<String>,
}

// SAFETY: an FMU instance may be called from any thread as long as no two calls overlap (FMI
// 2.0.4 and 3.0 say an instance's functions need not be thread-safe, not that they are bound to
// a thread); the host makes the component on one thread and steps it on that thread only, and
// `&mut self` keeps calls apart.
unsafe impl Send for FmuComponent {}

impl FmuComponent {
    /// Initialises the FMU at the first release (at the release's time), then steps it one
    /// period: inputs set, `doStep`, outputs got. A failure says at what time.
    fn advance(&mut self, rel: &Released, inputs: &[PortValue]) -> Result<(), (CallError, f64)> {
        let time = match self.time {
            Some(time) => time,
            None => {
                let start = rel.tick.0 as f64 * self.base_period;
                self.running.initialise(start).map_err(|c| (c, start))?;
                *self.time.insert(start)
            }
        };
        if let Some(c) = self.inputs.take(inputs) {
            tracing::warn!(
                "input '{}' is an FMI Int32: {} is clamped to {} (said once for this input)",
                self.input_names[c.port],
                c.value,
                c.to
            );
        }
        let at = |c| (c, time);
        self.running.set(&mut self.inputs).map_err(at)?;
        self.running.do_step(time, self.step).map_err(at)?;
        self.running.get(&mut self.outputs).map_err(at)?;
        self.time = Some(time + self.step);
        Ok(())
    }
}

impl Component for FmuComponent {
    fn initial_outputs(&mut self, outputs: &mut [PortValue]) {
        self.initial.give(outputs);
    }

    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        if self.failed.is_none() {
            if let Err((call, time)) = self.advance(rel, inputs) {
                let why = format!("{call} at t = {} s{}", seconds(time), self.running.said());
                tracing::error!("{why}: the FMU is stepped no more");
                self.failed = Some(why);
            }
        }
        self.outputs.give(outputs);
    }

    fn unsafe_state(&self) -> bool {
        self.failed.is_some()
    }

    fn terminate(&mut self) {
        // An FMU never initialised, or whose call failed, is only freed.
        if self.failed.is_none() && self.time.is_some() {
            self.running.terminate();
        }
    }
}

/// A time for people: `0.05`, not the `0.05000000000000004` a sum of steps makes (to the
/// nanosecond).
fn seconds(t: f64) -> String {
    let text = format!("{t:.9}");
    let text = text.trim_end_matches('0');
    text.strip_suffix('.').unwrap_or(text).to_owned()
}

#[cfg(test)]
mod tests;

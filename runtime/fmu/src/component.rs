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
//! A failing FMI call is an unsafe state ([`Component::unsafe_state`]): the coordinator faults
//! the assembly and the bus stops the drives, as for a monitor's breach; the outputs keep their
//! last values. A crash of the FMU's code takes its host process down, and the grid's fault
//! policy applies.

use modbot_grid::component::{
    Component, ComponentError, Params, PortValue, Registry, Released, BASE_PERIOD_S, PERIOD_S,
};

use super::component_type::{self, FMU};
use super::error::{FmuError, FmuErrorKind};
use super::running::{CallError, Running};
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
    probe.initialise(0.0).map_err(|call| {
        refused(FmuError::new(
            path,
            FmuErrorKind::Import(format!("{call} failed")),
        ))
    })?;
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
        outputs: Values::new(&interface.outputs),
        time: None,
        base_period: p.f64(BASE_PERIOD_S)?,
        step: p.f64(PERIOD_S)?,
        failed: None,
    })
}

struct FmuComponent {
    running: Running,
    inputs: Values,
    outputs: Values,
    /// The FMU's time at the next release; `None` until it is initialised, at its first.
    time: Option<f64>,
    /// The grid's base period, s: the time of a tick.
    base_period: f64,
    /// The communication step: the component's period, in seconds.
    step: f64,
    /// The first FMI call that failed: the FMU is not stepped again.
    failed: Option<CallError>,
}

// SAFETY: an FMU instance may be called from any thread as long as no two calls overlap (FMI
// 2.0.4 and 3.0 say an instance's functions need not be thread-safe, not that they are bound to
// a thread); the host makes the component on one thread and steps it on that thread only, and
// `&mut self` keeps calls apart.
unsafe impl Send for FmuComponent {}

impl FmuComponent {
    /// Initialises the FMU at the first release (at the release's time), then steps it one
    /// period: inputs set, `doStep`, outputs got.
    fn advance(&mut self, rel: &Released, inputs: &[PortValue]) -> Result<(), CallError> {
        let time = match self.time {
            Some(time) => time,
            None => {
                let start = rel.tick.0 as f64 * self.base_period;
                self.running.initialise(start)?;
                *self.time.insert(start)
            }
        };
        self.inputs.take(inputs);
        self.running.set(&mut self.inputs)?;
        self.running.do_step(time, self.step)?;
        self.running.get(&mut self.outputs)?;
        self.time = Some(time + self.step);
        Ok(())
    }
}

impl Component for FmuComponent {
    fn step(&mut self, rel: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        if self.failed.is_none() {
            if let Err(call) = self.advance(rel, inputs) {
                tracing::error!("{call} failed: the FMU is stepped no more");
                self.failed = Some(call);
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

#[cfg(test)]
mod tests {
    use modbot_grid::component::Component as _;
    use modbot_grid::component::{ParamValue, PortType};

    use super::*;

    /// The params of the FMI 2 feed-forward at 1 ms, with `Jm`.
    fn ff2(jm: f64) -> Params {
        let mut p = Params::new()
            .with(FMU, ParamValue::Text(modbot_fmus::FF2.into()))
            .with("Jm", ParamValue::F64(jm));
        p.set_timing(0.001, 1);
        p
    }

    #[test]
    fn an_fmu_first_released_at_tick_500_starts_its_co_simulation_at_0_5_s() {
        let mut sut = build(&ff2(0.5)).unwrap();
        assert_eq!(sut.time, None, "initialised at its first release");
        let inputs = vec![PortValue::F64s(vec![0.1; 6]); 3];
        let mut outputs = vec![PortType::F64s(6).zero(); 2];
        for tick in 500..503 {
            sut.step(&Released::at(tick), &inputs, &mut outputs);
            assert!(!sut.unsafe_state(), "the FMU took the step at tick {tick}");
        }
        let time = sut.time.expect("initialised");
        assert!(
            (time - 0.503).abs() < 1e-12,
            "its next step starts at {time}"
        );
        let PortValue::F64s(qm) = &outputs[1] else {
            panic!("qm is f64[6]");
        };
        // qm = q + Jl/k q'' with Jl = 2, k = 2e4 (the FMU's start values).
        assert!((qm[0] - 0.10001).abs() < 1e-12, "qm {qm:?}");
        sut.terminate();
    }

    #[test]
    fn a_parameter_the_fmu_refuses_at_initialisation_refuses_the_component_when_it_is_made() {
        let err = build(&ff2(-1.0)).err().expect("Jm = -1 is refused");
        let text = err.to_string();
        assert!(
            text.contains("fmi2EnterInitializationMode failed"),
            "{text}"
        );
    }
}

//! The `fmu` component, as the host program `modbot-fmu-host` makes it: at every release its
//! inputs are set, `doStep` runs one period, and its outputs are got — into buffers laid out
//! once ([`crate::values`]), so a release allocates nothing. The FMU's time starts at 0 at its
//! first release and advances by the component's period at each one (a co-simulation
//! master's communication points).
//!
//! A failing FMI call is an unsafe state ([`Component::unsafe_state`]): the coordinator faults
//! the assembly and the bus stops the drives, as for a monitor's breach; the outputs keep their
//! last values. A crash of the FMU's code takes its host process down, and the grid's fault
//! policy applies.

use modbot_grid::component::{
    Component, ComponentError, Params, PortValue, Registry, Released, PERIOD_S,
};

use super::component_type::{self, FMU};
use super::running::{CallError, Running};
use super::values::Values;

/// Adds `fmu`, made by this process, to `registry` (the program `modbot-fmu-host`).
pub fn register(registry: &mut Registry) {
    registry.register_open(component_type::info, make);
}

/// An FMU component for these (complete) params: the FMU unpacked, instantiated, its
/// parameters set, initialised.
pub fn make(p: &Params) -> Result<Box<dyn Component>, ComponentError> {
    let interface = component_type::read(p)?;
    let path = p.text(FMU)?;
    let running = Running::start(path, &interface, &interface.model_name, p)
        .map_err(|e| ComponentError::param_refused(FMU, e))?;
    tracing::info!(
        "FMI {} FMU '{}' from {path}: {} input(s), {} output(s)",
        interface.version.name(),
        interface.model_name,
        interface.inputs.len(),
        interface.outputs.len()
    );
    Ok(Box::new(FmuComponent {
        running,
        inputs: Values::new(&interface.inputs),
        outputs: Values::new(&interface.outputs),
        time: 0.0,
        step: p.f64(PERIOD_S)?,
        failed: None,
    }))
}

struct FmuComponent {
    running: Running,
    inputs: Values,
    outputs: Values,
    /// The FMU's time at the next release.
    time: f64,
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
    fn advance(&mut self, inputs: &[PortValue]) -> Result<(), CallError> {
        self.inputs.take(inputs);
        self.running.set(&mut self.inputs)?;
        self.running.do_step(self.time, self.step)?;
        self.running.get(&mut self.outputs)
    }
}

impl Component for FmuComponent {
    fn step(&mut self, _: &Released, inputs: &[PortValue], outputs: &mut [PortValue]) {
        if self.failed.is_none() {
            match self.advance(inputs) {
                Ok(()) => self.time += self.step,
                Err(call) => {
                    tracing::error!("{call} failed: the FMU is stepped no more");
                    self.failed = Some(call);
                }
            }
        }
        self.outputs.give(outputs);
    }

    fn unsafe_state(&self) -> bool {
        self.failed.is_some()
    }

    fn terminate(&mut self) {
        if self.failed.is_none() {
            self.running.terminate();
        }
    }
}

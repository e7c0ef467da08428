//! A running FMU, through the `fmi` crate (which loads its binary, unpacked by
//! [`super::unpack`], and binds the FMI C API): instantiated for co-simulation, its structural
//! parameters set in Configuration Mode (FMI 3), its parameters set, initialised, then stepped
//! — values set, `doStep`, values got — FMI 2.0 and 3.0 alike. Every call runs with the FMU's
//! messages kept ([`FmuLog`]), so a failure can say what the FMU logged.

use fmi::fmi2::import::Fmi2Import;
use fmi::fmi3::import::Fmi3Import;
use fmi::fmi3::{Fmi3Model, GetSet};
use modbot_grid::component::{ParamType, ParamValue, Params};

use super::call::CallError;
use super::error::{FmuError, FmuErrorKind};
use super::fmu_log::FmuLog;
use super::interface::{Interface, Kind, Param, Version};
use super::values::Values;

/// An FMU instance of either version. The instance comes before the import, so it is freed
/// before the unpacked files go. (Boxed: the bindings are large, and of different sizes.)
enum Instance {
    V2 {
        instance: Box<fmi::fmi2::instance::InstanceCS>,
        _import: Fmi2Import,
    },
    V3 {
        instance: Box<fmi::fmi3::instance::InstanceCS>,
        _import: Fmi3Import,
    },
}

/// A running FMU and what it logged.
pub struct Running {
    instance: Instance,
    log: FmuLog,
}

impl Running {
    /// Unpacks and instantiates the FMU at `path` (whose interface, sized for `params`, is
    /// `interface`), sets its structural parameters that `params` changes (in Configuration
    /// Mode) and then the parameters `params` sets; [`Running::initialise`] comes next.
    pub fn start(
        path: &str,
        interface: &Interface,
        name: &str,
        params: &Params,
    ) -> Result<Running, FmuError> {
        let log = FmuLog::new();
        let _scope = log.scope();
        let failed = |why: String| FmuError::new(path, FmuErrorKind::Import(why));
        let instance = match interface.version {
            Version::Fmi2 => {
                let import: Fmi2Import =
                    super::unpack::import(path).map_err(|e| failed(e.to_string()))?;
                let instance = import
                    .instantiate_cs(name, false, false)
                    .map_err(|e| failed(format!("cannot instantiate: {e}{}", log.said())))?;
                Instance::V2 {
                    instance: Box::new(instance),
                    _import: import,
                }
            }
            Version::Fmi3 => {
                let import: Fmi3Import =
                    super::unpack::import(path).map_err(|e| failed(e.to_string()))?;
                let instance = import
                    .instantiate_cs(name, false, false, false, false, &[])
                    .map_err(|e| failed(format!("cannot instantiate: {e}{}", log.said())))?;
                Instance::V3 {
                    instance: Box::new(instance),
                    _import: import,
                }
            }
        };
        drop(_scope);
        let mut running = Running { instance, log };
        running.configure(interface, params).map_err(|call| {
            failed(format!(
                "setting its structural parameters: {call}{}",
                running.log.said()
            ))
        })?;
        for q in interface.params.iter().filter(|q| !q.structural) {
            if let Some(value) = params.get(&q.name) {
                running.set_param(q, value).map_err(|call| {
                    failed(format!(
                        "setting param '{}': {call}{}",
                        q.name,
                        running.log.said()
                    ))
                })?;
            }
        }
        Ok(running)
    }

    /// `; the FMU logged: "…"`: its last messages, if it logged any.
    pub fn said(&self) -> String {
        self.log.said()
    }

    /// Sets the structural parameters whose values `params` changes from their start values,
    /// in Configuration Mode (FMI 3 lets them change only there).
    fn configure(&mut self, interface: &Interface, params: &Params) -> Result<(), CallError> {
        let changed: Vec<(u32, u64)> = interface
            .params
            .iter()
            .filter(|q| q.structural)
            .filter_map(|q| {
                let value = params.get(&q.name)?.coerce(ParamType::I64)?;
                let ParamValue::I64(n) = value else {
                    return None;
                };
                let vr = *q.refs.first()?;
                (value != q.start).then_some((vr, u64::try_from(n).ok()?))
            })
            .collect();
        let Instance::V3 { instance, .. } = &mut self.instance else {
            return Ok(());
        };
        if changed.is_empty() {
            return Ok(());
        }
        use fmi::fmi3::Common;
        let _scope = self.log.scope();
        let refs: Vec<u32> = changed.iter().map(|c| c.0).collect();
        let values: Vec<u64> = changed.iter().map(|c| c.1).collect();
        instance
            .enter_configuration_mode()
            .map_err(|e| CallError::fmi3("fmi3EnterConfigurationMode", &e))?;
        instance
            .set_uint64(&refs, &values)
            .map_err(|e| CallError::fmi3("fmi3SetUInt64", &e))?;
        instance
            .exit_configuration_mode()
            .map_err(|e| CallError::fmi3("fmi3ExitConfigurationMode", &e))?;
        Ok(())
    }

    /// Initialises the FMU for a co-simulation that starts at `start_time` (s): its first
    /// `doStep` is from there.
    pub fn initialise(&mut self, start_time: f64) -> Result<(), CallError> {
        let _scope = self.log.scope();
        match &mut self.instance {
            Instance::V2 { instance, .. } => {
                use fmi::fmi2::instance::Common;
                let fmi2 = |call| move |e| CallError::fmi2(call, &e);
                instance
                    .setup_experiment(None, start_time, None)
                    .map_err(fmi2("fmi2SetupExperiment"))?;
                instance
                    .enter_initialization_mode()
                    .map_err(fmi2("fmi2EnterInitializationMode"))?;
                instance
                    .exit_initialization_mode()
                    .map_err(fmi2("fmi2ExitInitializationMode"))?;
            }
            Instance::V3 { instance, .. } => {
                use fmi::fmi3::Common;
                let fmi3 = |call| move |e| CallError::fmi3(call, &e);
                instance
                    .enter_initialization_mode(None, start_time, None)
                    .map_err(fmi3("fmi3EnterInitializationMode"))?;
                instance
                    .exit_initialization_mode()
                    .map_err(fmi3("fmi3ExitInitializationMode"))?;
            }
        }
        Ok(())
    }

    /// Sets parameter `q` to `value` (checked against its type, shape and range by the
    /// component type).
    fn set_param(&mut self, q: &Param, value: &ParamValue) -> Result<(), CallError> {
        let mut v = Values::default();
        let refused = |why| CallError::refused("setting it", why);
        match (q.kind, value.coerce(q.ty)) {
            (Kind::Real, Some(ParamValue::F64(x))) => v.real.values = vec![x],
            (Kind::Real, Some(ParamValue::F64s(xs))) => v.real.values = xs,
            (Kind::Int32, Some(ParamValue::I64(i))) => {
                v.int32.values =
                    vec![i32::try_from(i).map_err(|_| refused("a value beyond Int32"))?]
            }
            (Kind::Int64, Some(ParamValue::I64(i))) => v.int64.values = vec![i],
            (Kind::UInt64, Some(ParamValue::I64(i))) => {
                let n = u64::try_from(i).map_err(|_| refused("a value below 0"))?;
                return self.set_uint64(&q.refs, n);
            }
            (Kind::Bool, Some(ParamValue::Bool(b))) => v.boolean.values = vec![b],
            _ => return Err(refused("a value of another type")),
        }
        match q.kind {
            Kind::Real => v.real.refs = q.refs.clone(),
            Kind::Int32 => v.int32.refs = q.refs.clone(),
            Kind::Int64 => v.int64.refs = q.refs.clone(),
            Kind::Bool => v.boolean.refs = q.refs.clone(),
            Kind::UInt64 => {}
        }
        self.set(&mut v)
    }

    /// Sets the (non-structural) UInt64 parameter `refs` to `n` (FMI 3 only has them).
    fn set_uint64(&mut self, refs: &[u32], n: u64) -> Result<(), CallError> {
        let _scope = self.log.scope();
        match &mut self.instance {
            Instance::V3 { instance, .. } => instance
                .set_uint64(refs, &[n])
                .map(|_| ())
                .map_err(|e| CallError::fmi3("fmi3SetUInt64", &e)),
            Instance::V2 { .. } => Err(CallError::refused("fmi2SetInteger", "no UInt64 in FMI 2")),
        }
    }

    /// Sets every value of `v` (the inputs).
    pub fn set(&mut self, v: &mut Values) -> Result<(), CallError> {
        let _scope = self.log.scope();
        match &mut self.instance {
            Instance::V2 { instance, .. } => super::exchange::set2(instance, v),
            Instance::V3 { instance, .. } => super::exchange::set3(instance, v),
        }
    }

    /// Gets every value of `v` (the outputs).
    pub fn get(&mut self, v: &mut Values) -> Result<(), CallError> {
        let _scope = self.log.scope();
        match &mut self.instance {
            Instance::V2 { instance, .. } => super::exchange::get2(instance, v),
            Instance::V3 { instance, .. } => super::exchange::get3(instance, v),
        }
    }

    /// One communication step from `t` to `t + h`. A step the FMU discards, or after which it
    /// asks to terminate, is an error that says so.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), CallError> {
        let _scope = self.log.scope();
        match &mut self.instance {
            Instance::V2 { instance, .. } => {
                use fmi::fmi2::instance::CoSimulation;
                if let Err(e) = instance.do_step(t, h, true) {
                    let mut failed = CallError::fmi2("fmi2DoStep", &e);
                    // FMI 2.0.4, 4.2.3: after fmi2Discard the master asks whether the FMU
                    // wants the simulation to end.
                    if matches!(e, fmi::fmi2::Fmi2Error::Discard)
                        && instance.terminated().unwrap_or(false)
                    {
                        failed.terminate = Some("fmi2Terminated");
                    }
                    return Err(failed);
                }
            }
            Instance::V3 { instance, .. } => {
                use fmi::fmi3::CoSimulation;
                let (mut event, mut terminate, mut early) = (false, false, false);
                let mut last = t;
                let done = instance.do_step(
                    t,
                    h,
                    true,
                    &mut event,
                    &mut terminate,
                    &mut early,
                    &mut last,
                );
                let mut failed = match done {
                    Ok(_) => CallError {
                        call: "fmi3DoStep",
                        status: None,
                        terminate: None,
                    },
                    Err(e) => CallError::fmi3("fmi3DoStep", &e),
                };
                if terminate {
                    failed.terminate = Some("terminateSimulation");
                }
                if failed.status.is_some() || failed.terminate.is_some() {
                    return Err(failed);
                }
            }
        }
        Ok(())
    }

    /// Ends the simulation run (the instance is freed when dropped).
    pub fn terminate(&mut self) {
        let _scope = self.log.scope();
        let ended = match &mut self.instance {
            Instance::V2 { instance, .. } => {
                use fmi::fmi2::instance::Common;
                instance.terminate().is_ok()
            }
            Instance::V3 { instance, .. } => {
                use fmi::fmi3::Common;
                instance.terminate().is_ok()
            }
        };
        if !ended {
            tracing::warn!("the FMU refused to terminate{}", self.log.said());
        }
    }
}

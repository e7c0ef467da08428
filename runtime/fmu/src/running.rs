//! A running FMU, through the `fmi` crate (which loads its binary, unpacked by
//! [`super::unpack`], and binds the FMI C API): instantiated for co-simulation, its parameters set, initialised, then
//! stepped — values set, `doStep`, values got — FMI 2.0 and 3.0 alike.

use fmi::fmi2::import::Fmi2Import;
use fmi::fmi3::import::Fmi3Import;
use fmi::fmi3::{Fmi3Model, GetSet};
use modbot_grid::component::ParamValue;

use super::error::{FmuError, FmuErrorKind};
use super::interface::{Interface, Kind, Param, Version};
use super::values::Values;

/// A failed FMI call: which one (a static text, so a failing release allocates nothing).
pub type CallError = &'static str;

/// An FMU instance of either version. The instance comes before the import, so it is freed
/// before the unpacked files go. (Boxed: the bindings are large, and of different sizes.)
pub enum Running {
    V2 {
        instance: Box<fmi::fmi2::instance::InstanceCS>,
        _import: Fmi2Import,
    },
    V3 {
        instance: Box<fmi::fmi3::instance::InstanceCS>,
        _import: Fmi3Import,
    },
}

impl Running {
    /// Unpacks and instantiates the FMU at `path` (whose interface is `interface`) and sets
    /// `params` (the FMU's among them); [`Running::initialise`] comes next.
    pub fn start(
        path: &str,
        interface: &Interface,
        name: &str,
        params: &modbot_grid::component::Params,
    ) -> Result<Running, FmuError> {
        let failed = |why: String| FmuError::new(path, FmuErrorKind::Import(why));
        let mut running = match interface.version {
            Version::Fmi2 => {
                let import: Fmi2Import = super::unpack::import(path).map_err(failed)?;
                let instance = import
                    .instantiate_cs(name, false, false)
                    .map_err(|e| failed(format!("cannot instantiate: {e}")))?;
                Running::V2 {
                    instance: Box::new(instance),
                    _import: import,
                }
            }
            Version::Fmi3 => {
                let import: Fmi3Import = super::unpack::import(path).map_err(failed)?;
                let instance = import
                    .instantiate_cs(name, false, false, false, false, &[])
                    .map_err(|e| failed(format!("cannot instantiate: {e}")))?;
                Running::V3 {
                    instance: Box::new(instance),
                    _import: import,
                }
            }
        };
        for q in &interface.params {
            if let Some(value) = params.get(&q.name) {
                running.set_param(q, value).map_err(|call| {
                    failed(format!("setting param '{}' failed ({call})", q.name))
                })?;
            }
        }
        Ok(running)
    }

    /// Initialises the FMU for a co-simulation that starts at `start_time` (s): its first
    /// `doStep` is from there.
    pub fn initialise(&mut self, start_time: f64) -> Result<(), CallError> {
        match self {
            Running::V2 { instance, .. } => {
                use fmi::fmi2::instance::Common;
                instance
                    .setup_experiment(None, start_time, None)
                    .map_err(|_| "fmi2SetupExperiment")?;
                instance
                    .enter_initialization_mode()
                    .map_err(|_| "fmi2EnterInitializationMode")?;
                instance
                    .exit_initialization_mode()
                    .map_err(|_| "fmi2ExitInitializationMode")?;
            }
            Running::V3 { instance, .. } => {
                use fmi::fmi3::Common;
                instance
                    .enter_initialization_mode(None, start_time, None)
                    .map_err(|_| "fmi3EnterInitializationMode")?;
                instance
                    .exit_initialization_mode()
                    .map_err(|_| "fmi3ExitInitializationMode")?;
            }
        }
        Ok(())
    }

    /// Sets parameter `q` to `value` (checked against its type by the component type).
    fn set_param(&mut self, q: &Param, value: &ParamValue) -> Result<(), CallError> {
        let mut v = Values::default();
        match (q.kind, value.coerce(q.ty)) {
            (Kind::Real, Some(ParamValue::F64(x))) => v.real.values = vec![x],
            (Kind::Real, Some(ParamValue::F64s(xs))) => v.real.values = xs,
            (Kind::Int32, Some(ParamValue::I64(i))) => {
                v.int32.values = vec![i32::try_from(i).map_err(|_| "a value beyond Int32")?]
            }
            (Kind::Int64, Some(ParamValue::I64(i))) => v.int64.values = vec![i],
            (Kind::Bool, Some(ParamValue::Bool(b))) => v.boolean.values = vec![b],
            _ => return Err("a value of another type"),
        }
        match q.kind {
            Kind::Real => v.real.refs = q.refs.clone(),
            Kind::Int32 => v.int32.refs = q.refs.clone(),
            Kind::Int64 => v.int64.refs = q.refs.clone(),
            Kind::Bool => v.boolean.refs = q.refs.clone(),
        }
        self.set(&mut v)
    }

    /// Sets every value of `v` (the inputs).
    pub fn set(&mut self, v: &mut Values) -> Result<(), CallError> {
        match self {
            Running::V2 { instance, .. } => {
                use fmi::fmi2::instance::Common;
                if !v.real.refs.is_empty() {
                    instance
                        .set_real(&v.real.refs, &v.real.values)
                        .map_err(|_| "fmi2SetReal")?;
                }
                if !v.int32.refs.is_empty() {
                    instance
                        .set_integer(&v.int32.refs, &v.int32.values)
                        .map_err(|_| "fmi2SetInteger")?;
                }
                if !v.boolean.refs.is_empty() {
                    // FMI 2's Boolean is an int: the buffer of Int32 values is not used for it.
                    let mut ints = [0i32; 64];
                    for chunk in v.boolean.refs.chunks(64).zip(v.boolean.values.chunks(64)) {
                        let (refs, values) = chunk;
                        for (i, b) in values.iter().enumerate() {
                            ints[i] = i32::from(*b);
                        }
                        instance
                            .set_boolean(refs, &ints[..values.len()])
                            .map_err(|_| "fmi2SetBoolean")?;
                    }
                }
            }
            Running::V3 { instance, .. } => {
                if !v.real.refs.is_empty() {
                    instance
                        .set_float64(&v.real.refs, &v.real.values)
                        .map_err(|_| "fmi3SetFloat64")?;
                }
                if !v.int32.refs.is_empty() {
                    instance
                        .set_int32(&v.int32.refs, &v.int32.values)
                        .map_err(|_| "fmi3SetInt32")?;
                }
                if !v.int64.refs.is_empty() {
                    instance
                        .set_int64(&v.int64.refs, &v.int64.values)
                        .map_err(|_| "fmi3SetInt64")?;
                }
                if !v.boolean.refs.is_empty() {
                    instance
                        .set_boolean(&v.boolean.refs, &v.boolean.values)
                        .map_err(|_| "fmi3SetBoolean")?;
                }
            }
        }
        Ok(())
    }

    /// Gets every value of `v` (the outputs).
    pub fn get(&mut self, v: &mut Values) -> Result<(), CallError> {
        match self {
            Running::V2 { instance, .. } => {
                use fmi::fmi2::instance::Common;
                if !v.real.refs.is_empty() {
                    instance
                        .get_real(&v.real.refs, &mut v.real.values)
                        .map_err(|_| "fmi2GetReal")?;
                }
                if !v.int32.refs.is_empty() {
                    instance
                        .get_integer(&v.int32.refs, &mut v.int32.values)
                        .map_err(|_| "fmi2GetInteger")?;
                }
                if !v.boolean.refs.is_empty() {
                    let mut ints = [0i32; 64];
                    for (refs, values) in v
                        .boolean
                        .refs
                        .chunks(64)
                        .zip(v.boolean.values.chunks_mut(64))
                    {
                        instance
                            .get_boolean(refs, &mut ints[..values.len()])
                            .map_err(|_| "fmi2GetBoolean")?;
                        for (b, i) in values.iter_mut().zip(ints) {
                            *b = i != 0;
                        }
                    }
                }
            }
            Running::V3 { instance, .. } => {
                if !v.real.refs.is_empty() {
                    instance
                        .get_float64(&v.real.refs, &mut v.real.values)
                        .map_err(|_| "fmi3GetFloat64")?;
                }
                if !v.int32.refs.is_empty() {
                    instance
                        .get_int32(&v.int32.refs, &mut v.int32.values)
                        .map_err(|_| "fmi3GetInt32")?;
                }
                if !v.int64.refs.is_empty() {
                    instance
                        .get_int64(&v.int64.refs, &mut v.int64.values)
                        .map_err(|_| "fmi3GetInt64")?;
                }
                if !v.boolean.refs.is_empty() {
                    instance
                        .get_boolean(&v.boolean.refs, &mut v.boolean.values)
                        .map_err(|_| "fmi3GetBoolean")?;
                }
            }
        }
        Ok(())
    }

    /// One communication step from `t` to `t + h`.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), CallError> {
        match self {
            Running::V2 { instance, .. } => {
                use fmi::fmi2::instance::CoSimulation;
                instance.do_step(t, h, true).map_err(|_| "fmi2DoStep")?;
            }
            Running::V3 { instance, .. } => {
                use fmi::fmi3::CoSimulation;
                let (mut event, mut terminate, mut early) = (false, false, false);
                let mut last = t;
                instance
                    .do_step(
                        t,
                        h,
                        true,
                        &mut event,
                        &mut terminate,
                        &mut early,
                        &mut last,
                    )
                    .map_err(|_| "fmi3DoStep")?;
                if terminate {
                    return Err("fmi3DoStep (the FMU asks to terminate)");
                }
            }
        }
        Ok(())
    }

    /// Ends the simulation run (the instance is freed when dropped).
    pub fn terminate(&mut self) {
        let ended = match self {
            Running::V2 { instance, .. } => {
                use fmi::fmi2::instance::Common;
                instance.terminate().is_ok()
            }
            Running::V3 { instance, .. } => {
                use fmi::fmi3::Common;
                instance.terminate().is_ok()
            }
        };
        if !ended {
            tracing::warn!("the FMU refused to terminate");
        }
    }
}

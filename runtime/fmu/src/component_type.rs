//! The component type `fmu`: what every process knows of an FMU component — its ports and
//! parameters, read from the FMU named by its param `fmu` ([`crate::interface`]) — and the
//! host program that runs it ([`PROGRAM`]).
//!
//! Its parameters are the FMU's (their defaults its start values), beside `fmu` (the file, an
//! absolute path: the description's loader makes it one from the component's `fmu` field).
//! The registry passes parameters it does not know on ([`Registry::declare_open`]); this
//! type's description checks them against the FMU ([`crate::params`]): an unknown one, one of
//! the wrong type or shape, or one outside its declared range is refused, naming the FMU's.
//! Its structural parameters size its arrays first ([`Interface::sized`]), so a port's length
//! is the one the description makes.

use std::path::Path;

use modbot_grid::component::{
    intern, ComponentError, ComponentInfo, ParamDecl, ParamType, Params, PortDecl, Registry,
};

use super::error::FmuError;
use super::interface::Interface;
use super::params::{self, Which};

/// The type's name in descriptions.
pub const TYPE: &str = "fmu";
/// The host program that steps FMU components.
pub const PROGRAM: &str = "modbot-fmu-host";
pub use super::params::FMU;

/// Adds `fmu` to `registry` as a type [`PROGRAM`] makes (unless this process registered it).
pub fn declare(registry: &mut Registry) {
    registry.declare_open(info, PROGRAM);
}

/// The interface of the FMU these params name (just the `fmu` param without one).
pub fn info(p: &Params) -> Result<ComponentInfo, ComponentError> {
    let fmu = ParamDecl::required(FMU, ParamType::Text);
    let Some(_) = p.get(FMU) else {
        return Ok(ComponentInfo {
            type_name: TYPE,
            doc: "an FMI 2.0 or 3.0 co-simulation FMU (fmu = \"file.fmu\"), in a host of its own",
            inputs: Vec::new(),
            outputs: Vec::new(),
            params: vec![fmu],
        });
    };
    let interface = read(p)?;
    params::check(p, &interface, Which::All)?;
    let ports = |ports: &[super::interface::Port]| {
        ports
            .iter()
            .map(|port| PortDecl::new(intern(&port.name), port.ty))
            .collect()
    };
    let mut params = vec![fmu];
    params.extend(
        interface
            .params
            .iter()
            .map(|q| ParamDecl::optional(intern(&q.name), q.ty, q.start.clone())),
    );
    Ok(ComponentInfo {
        type_name: TYPE,
        doc: intern(&format!(
            "FMI {} co-simulation FMU '{}'{}",
            interface.version.name(),
            interface.model_name,
            if interface.description.is_empty() {
                String::new()
            } else {
                format!(": {}", interface.description)
            }
        )),
        inputs: ports(&interface.inputs),
        outputs: ports(&interface.outputs),
        params,
    })
}

/// The interface of the FMU `p` names, its arrays sized by the structural parameters `p` sets
/// (checked first).
pub fn read(p: &Params) -> Result<Interface, ComponentError> {
    let path = p.text(FMU)?;
    let interface =
        Interface::read(Path::new(path)).map_err(|e| ComponentError::param_refused(FMU, e))?;
    params::check(p, &interface, Which::Structural)?;
    interface
        .sized(p)
        .map_err(|kind| ComponentError::param_refused(FMU, FmuError::new(path, kind)))
}

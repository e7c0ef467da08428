//! The component type `fmu`: what every process knows of an FMU component — its ports and
//! parameters, read from the FMU named by its param `fmu` ([`crate::interface`]) — and the
//! host program that runs it ([`PROGRAM`]).
//!
//! Its parameters are the FMU's (their defaults its start values), beside `fmu` (the file, an
//! absolute path: the description's loader makes it one from the component's `fmu` field).
//! The registry passes parameters it does not know on ([`Registry::declare_open`]); this
//! type's description checks them against the FMU: an unknown one, or one of the wrong type,
//! is refused, naming the FMU's.

use std::path::Path;

use modbot_grid::component::{
    intern, ComponentError, ComponentInfo, ParamDecl, ParamError, ParamType, Params, PortDecl,
    Registry, AUTOMATIC_PARAMS,
};

use super::interface::Interface;

/// The type's name in descriptions.
pub const TYPE: &str = "fmu";
/// The host program that steps FMU components.
pub const PROGRAM: &str = "modbot-fmu-host";
/// The param (and component field) that names the FMU.
pub const FMU: &str = "fmu";

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
    check_params(p, &interface)?;
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

/// The interface of the FMU `p` names.
pub fn read(p: &Params) -> Result<Interface, ComponentError> {
    let path = p.text(FMU)?;
    Interface::read(Path::new(path)).map_err(|e| ComponentError::param_refused(FMU, e))
}

/// Every param of `p` is the FMU's and of its type (or `fmu`, or an automatic one).
fn check_params(p: &Params, interface: &Interface) -> Result<(), ParamError> {
    for (name, value) in p.iter() {
        if name == FMU || AUTOMATIC_PARAMS.contains(&name) {
            continue;
        }
        let Some(q) = interface.params.iter().find(|q| q.name == name) else {
            return Err(ParamError::Unknown {
                name: name.to_owned(),
                type_name: format!("fmu ({})", interface.model_name),
                known: interface.params.iter().map(|q| intern(&q.name)).collect(),
            });
        };
        let fits = match (value.coerce(q.ty), &q.start) {
            (Some(modbot_grid::ParamValue::F64s(xs)), modbot_grid::ParamValue::F64s(n)) => {
                xs.len() == n.len()
            }
            (coerced, _) => coerced.is_some(),
        };
        if !fits {
            return Err(ParamError::WrongType {
                name: name.to_owned(),
                expected: q.ty,
                got: value.clone(),
            });
        }
    }
    Ok(())
}

//! The rules an image follows beyond its shape: names, ranges, and connections that make
//! indexing the components' ports safe.

use std::collections::HashMap;

use super::{
    ComponentImage, End, GridImage, GridSpecError, InfoImage, Place, PortAt, MAX_ARRAY, MAX_CPU,
};
use crate::grid::{PortType, MAX_SOURCES};
use crate::names::{is_assembly_name, is_module_name};

const NOT_EMPTY: &str = "a text that is not empty";
const MODULE_NAME: &str = "a module name (1 to 48 of a-z A-Z 0-9 _ -)";
const ASSEMBLY_NAME: &str = "an assembly name (1 to 32 of a-z 0-9 _)";

impl GridImage {
    /// Whether the image follows the rules [`decode`](super::decode) checks: the base period
    /// ≥ 1 ns, a priority of 1..=99, CPUs ≤ [`MAX_CPU`]; an assembly name, a generation ≥ 1
    /// and a first component ≤ the components; names not empty, hosts module names,
    /// component names unique, periods 1..=u32::MAX, arrays of 1..=[`MAX_ARRAY`] f64;
    /// connections between existing ports of one type (from an output to an input) that feed
    /// every input exactly once and give a component at most [`MAX_SOURCES`] source
    /// components. An image that passes is safe to index by its connections.
    pub fn check(&self) -> Result<(), GridSpecError> {
        if self.base_period_ns == 0 {
            return Err(GridSpecError::BasePeriod);
        }
        if let Some(priority) = self.priority.filter(|p| !(1..=99).contains(p)) {
            return Err(GridSpecError::Priority { priority });
        }
        if let Some(&cpu) = self.cpus.iter().find(|&&cpu| cpu > MAX_CPU) {
            return Err(GridSpecError::Cpu { cpu });
        }
        if let Some(assembly) = &self.assembly {
            if !is_assembly_name(assembly.name.as_bytes()) {
                let name = &assembly.name;
                return Err(bad_name(Place::Assembly, "the name", name, ASSEMBLY_NAME));
            }
            if assembly.generation.0 == 0 {
                return Err(GridSpecError::Generation);
            }
            if assembly.base > self.components.len() {
                return Err(GridSpecError::Base {
                    base: assembly.base,
                    components: self.components.len(),
                });
            }
        }
        for (i, declared) in self.declared.iter().enumerate() {
            let at = Place::Declared(i);
            not_empty(at, "the program", &declared.program)?;
            check_info(at, &declared.info)?;
        }
        let mut names = HashMap::new();
        for (i, component) in self.components.iter().enumerate() {
            check_component(i, component)?;
            if let Some(first) = names.insert(component.name.as_str(), i) {
                return Err(GridSpecError::DuplicateComponent {
                    name: component.name.clone(),
                    first,
                    second: i,
                });
            }
        }
        self.check_connections()
    }

    fn check_connections(&self) -> Result<(), GridSpecError> {
        // The connection feeding each input of each component.
        let mut fed: Vec<Vec<Option<usize>>> = self
            .components
            .iter()
            .map(|c| vec![None; c.info.inputs.len()])
            .collect();
        for (i, c) in self.connections.iter().enumerate() {
            let from_ty = self.port(i, End::From, c.from)?;
            let to_ty = self.port(i, End::To, c.to)?;
            if from_ty != to_ty {
                return Err(GridSpecError::TypeMismatch {
                    connection: i,
                    from: self.port_name(End::From, c.from),
                    from_ty,
                    to: self.port_name(End::To, c.to),
                    to_ty,
                });
            }
            let slot = &mut fed[c.to.component][c.to.port];
            if let Some(first) = slot.replace(i) {
                return Err(GridSpecError::FedTwice {
                    component: self.components[c.to.component].name.clone(),
                    input: self.components[c.to.component].info.inputs[c.to.port]
                        .name
                        .clone(),
                    first,
                    second: i,
                });
            }
        }
        for (component, inputs) in self.components.iter().zip(&fed) {
            if let Some(unfed) = inputs.iter().position(Option::is_none) {
                return Err(GridSpecError::Unfed {
                    component: component.name.clone(),
                    input: component.info.inputs[unfed].name.clone(),
                });
            }
            let mut sources: Vec<usize> = inputs
                .iter()
                .flatten()
                .map(|&i| self.connections[i].from.component)
                .collect();
            sources.sort_unstable();
            sources.dedup();
            if sources.len() > MAX_SOURCES {
                return Err(GridSpecError::TooManySources {
                    component: component.name.clone(),
                    sources: sources.len(),
                });
            }
        }
        Ok(())
    }

    /// The type of the port an end of connection `connection` names, if it exists.
    fn port(&self, connection: usize, end: End, at: PortAt) -> Result<PortType, GridSpecError> {
        let out_of_range = |what, index, len| GridSpecError::OutOfRange {
            connection,
            end,
            what,
            index,
            len,
        };
        let components = self.components.len();
        let component = self
            .components
            .get(at.component)
            .ok_or_else(|| out_of_range("component", at.component, components))?;
        let (what, ports) = match end {
            End::From => ("output", &component.info.outputs),
            End::To => ("input", &component.info.inputs),
        };
        let port = ports
            .get(at.port)
            .ok_or_else(|| out_of_range(what, at.port, ports.len()))?;
        Ok(port.ty)
    }

    /// `component.port` for a port [`GridImage::port`] found.
    fn port_name(&self, end: End, at: PortAt) -> String {
        let component = &self.components[at.component];
        let ports = match end {
            End::From => &component.info.outputs,
            End::To => &component.info.inputs,
        };
        format!("{}.{}", component.name, ports[at.port].name)
    }
}

fn check_component(i: usize, c: &ComponentImage) -> Result<(), GridSpecError> {
    let at = Place::Component(i);
    not_empty(at, "the name", &c.name)?;
    not_empty(at, "the type", &c.type_name)?;
    if let Some(program) = &c.program {
        // On the wire "" is no program.
        not_empty(at, "the program", program)?;
    }
    if !is_module_name(c.host.as_bytes()) {
        return Err(bad_name(at, "the host", &c.host, MODULE_NAME));
    }
    if !(1..=u64::from(u32::MAX)).contains(&c.period) {
        return Err(GridSpecError::Period {
            component: i,
            period: c.period,
        });
    }
    for (param, _) in &c.params {
        not_empty(at, "a parameter's name", param)?;
    }
    check_info(at, &c.info)
}

fn check_info(at: Place, info: &InfoImage) -> Result<(), GridSpecError> {
    not_empty(at, "the type's name", &info.type_name)?;
    for port in info.inputs.iter().chain(&info.outputs) {
        not_empty(at, "a port's name", &port.name)?;
        if let PortType::F64s(len) = port.ty {
            if !(1..=MAX_ARRAY).contains(&len) {
                return Err(GridSpecError::ArrayLength {
                    at,
                    port: port.name.clone(),
                    len,
                });
            }
        }
    }
    for param in &info.params {
        not_empty(at, "a declared parameter's name", &param.name)?;
    }
    Ok(())
}

fn not_empty(at: Place, what: &'static str, text: &str) -> Result<(), GridSpecError> {
    match text.is_empty() {
        true => Err(bad_name(at, what, text, NOT_EMPTY)),
        false => Ok(()),
    }
}

fn bad_name(at: Place, what: &'static str, name: &str, rule: &'static str) -> GridSpecError {
    GridSpecError::Name {
        at,
        what,
        name: name.to_owned(),
        rule,
    }
}

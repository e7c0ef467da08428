//! From an FMU's variables to a component's ports and parameters: each variable's role and
//! type, FMI 2 arrays (`x[1]` … `x[n]`, Real) gathered into one f64[n], FMI 3 arrays kept whole
//! (sized later, [`super::interface::Interface::sized`]), names made port names.

use modbot_grid::component::{ParamType, ParamValue, PortType};

use super::error::FmuErrorKind;
use super::ranges::Range;
use super::variables::{Extent, Kind, Param, Port};

/// A variable's role in the component.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Role {
    Input,
    Output,
    Param,
}

/// One variable (one element of an FMI 2 array), before arrays are gathered.
pub struct Var {
    pub name: String,
    pub role: Role,
    /// How its values travel; `None`: a type no port or parameter has.
    pub kind: Option<Kind>,
    pub vr: u32,
    /// An FMI 3 array's dimensions (empty for a scalar).
    pub shape: Vec<Extent>,
    pub start: Vec<ParamValue>,
    pub range: Range,
    /// An FMI 3 structural parameter.
    pub structural: bool,
}

/// The inputs, outputs and parameters.
pub type Gathered = (Vec<Port>, Vec<Port>, Vec<Param>);

/// `x[3]` → (`x`, 3).
fn element(name: &str) -> Option<(&str, usize)> {
    let (base, rest) = name.split_once('[')?;
    let index: usize = rest.strip_suffix(']')?.parse().ok()?;
    (!base.is_empty() && !base.contains('[')).then_some((base, index))
}

/// A port's name for a variable's: letters, digits and `_` kept, anything else `_`.
fn port_name(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The ports and parameters of `vars`.
pub fn gather(vars: Vec<Var>) -> Result<Gathered, FmuErrorKind> {
    let (mut inputs, mut outputs, mut params) = (Vec::new(), Vec::new(), Vec::new());
    let mut done = vec![false; vars.len()];
    for i in 0..vars.len() {
        if done[i] {
            continue;
        }
        let v = &vars[i];
        // The elements of an FMI 2 array, by index.
        let mut members: Vec<(usize, usize)> = match element(&v.name) {
            Some((base, _)) => (i..vars.len())
                .filter_map(|j| {
                    let (b, index) = element(&vars[j].name)?;
                    (b == base).then_some((index, j))
                })
                .collect(),
            None => vec![(1, i)],
        };
        members.sort_unstable();
        members.iter().for_each(|&(_, j)| done[j] = true);
        let name = element(&v.name)
            .map_or(v.name.as_str(), |(b, _)| b)
            .to_owned();
        let gathered = element(&v.name).is_some();
        let whole = members.iter().enumerate().all(|(k, &(index, j))| {
            index == k + 1 && vars[j].role == v.role && vars[j].kind == v.kind
        });
        let refuse = |why: &str| FmuErrorKind::Variable {
            name: v.name.clone(),
            why: why.to_owned(),
        };
        if gathered && !(whole && v.kind == Some(Kind::Real)) {
            if v.role == Role::Param {
                continue;
            }
            return Err(refuse(
                "an array must be Real elements name[1] to name[n], all inputs or all outputs",
            ));
        }
        let array = gathered || !v.shape.is_empty();
        let port_kind = match v.kind {
            Some(Kind::UInt64) | None => None,
            kind => kind,
        };
        if v.role != Role::Param && port_kind.is_none() {
            return Err(refuse(
                "its type cannot be a port: use Real/Float64, Integer/Int32/Int64 or Boolean",
            ));
        }
        let Some(kind) = v.kind else {
            continue; // a parameter of another type keeps its start value
        };
        if array && kind != Kind::Real {
            if v.role == Role::Param {
                continue;
            }
            return Err(refuse("only arrays of Float64 can be ports"));
        }
        let refs: Vec<u32> = members.iter().map(|&(_, j)| vars[j].vr).collect();
        let ty = match kind {
            // An FMI 3 array's size is set by `Interface::sized`.
            Kind::Real if array => PortType::F64s(members.len()),
            Kind::Real => PortType::F64,
            Kind::Int32 | Kind::Int64 | Kind::UInt64 => PortType::I64,
            Kind::Bool => PortType::Bool,
        };
        let port = || Port {
            name: port_name(&name),
            ty,
            kind,
            refs: refs.clone(),
            shape: v.shape.clone(),
        };
        match v.role {
            Role::Input => inputs.push(port()),
            Role::Output => outputs.push(port()),
            Role::Param => {
                let starts: Vec<ParamValue> = members
                    .iter()
                    .flat_map(|&(_, j)| vars[j].start.clone())
                    .collect();
                params.push(param(
                    name,
                    v,
                    kind,
                    ty,
                    refs,
                    &starts,
                    gathered.then_some(members.len()),
                ));
            }
        }
    }
    for ports in [&inputs, &outputs] {
        for (k, p) in ports.iter().enumerate() {
            if ports[..k].iter().any(|q| q.name == p.name) {
                return Err(FmuErrorKind::Variable {
                    name: p.name.clone(),
                    why: "two variables make ports of this name".into(),
                });
            }
        }
    }
    Ok((inputs, outputs, params))
}

/// The parameter of variable `v` (the first element of an FMI 2 array of `elements`).
fn param(
    name: String,
    v: &Var,
    kind: Kind,
    ty: PortType,
    refs: Vec<u32>,
    starts: &[ParamValue],
    elements: Option<usize>,
) -> Param {
    let (ty, start) = match (ty, starts.first()) {
        (PortType::F64s(_), _) => {
            let xs: Vec<f64> = starts
                .iter()
                .map(|s| if let ParamValue::F64(x) = s { *x } else { 0.0 })
                .collect();
            (ParamType::F64s, ParamValue::F64s(xs))
        }
        (PortType::F64, first) => (
            ParamType::F64,
            first.cloned().unwrap_or(ParamValue::F64(0.0)),
        ),
        (PortType::I64, first) => (ParamType::I64, first.cloned().unwrap_or(ParamValue::I64(0))),
        (PortType::Bool, first) => (
            ParamType::Bool,
            first.cloned().unwrap_or(ParamValue::Bool(false)),
        ),
    };
    Param {
        name,
        ty,
        kind,
        refs,
        start,
        shape: v.shape.clone(),
        dims: elements.map(|n| vec![n as u64]).unwrap_or_default(),
        range: v.range,
        structural: v.structural,
    }
}

//! What an FMI 3.0 modelDescription.xml says of the component's variables: its inputs,
//! outputs and parameters (Float64, Int32, Int64, Boolean; UInt64 structural parameters),
//! their start values, declared ranges and array dimensions, and the UInt64 constants a
//! `Dimension` may name.

use fmi_schema::fmi3::{
    AbstractVariableTrait, ArrayableVariableTrait, Causality, Dimension, Fmi3ModelDescription,
    InitializableVariableTrait, Variability, Variable,
};
use modbot_grid::component::ParamValue;

use super::error::FmuErrorKind;
use super::gather::{Role, Var};
use super::model::{self, Model};
use super::variables::{Extent, Interface, Kind, Version};

/// The interface `xml` describes, its arrays not yet sized ([`Interface::sized`]).
pub fn read(xml: &str) -> Result<Interface, FmuErrorKind> {
    let md: Fmi3ModelDescription = model::parse(xml)?;
    let cs = md.co_simulation.as_ref();
    let token = &md.instantiation_token;
    let model = Model::new(Version::Fmi3, &md, cs, token, md.description.as_deref())?;
    let ranges = super::ranges::scan(xml);
    let mut vars = Vec::new();
    let mut constants = Vec::new();
    for v in &md.model_variables.variables {
        let (kind, dims, start) = typed(v);
        let abstract_var = abstract_of(v);
        if let Variable::UInt64(u) = v {
            if u.variability() == Variability::Constant {
                let value = u.start().and_then(|s| s.first().copied()).unwrap_or(0);
                constants.push((u.value_reference(), value));
            }
        }
        let structural = abstract_var.causality() == Causality::StructuralParameter;
        let role = match abstract_var.causality() {
            Causality::Input => Role::Input,
            Causality::Output => Role::Output,
            Causality::Parameter => Role::Param,
            // A structural parameter that sizes arrays; others keep their start values.
            Causality::StructuralParameter if matches!(v, Variable::UInt64(_)) => Role::Param,
            _ => continue,
        };
        let name = abstract_var.name().to_owned();
        let shape = dims
            .iter()
            .map(|d| match d {
                Dimension::Fixed(n) => Extent::Fixed(*n),
                Dimension::Variable(r) => Extent::Of(*r),
            })
            .collect();
        vars.push(Var {
            range: ranges.get(&name).copied().unwrap_or_default(),
            name,
            role,
            kind,
            vr: abstract_var.value_reference(),
            shape,
            start,
            structural,
        });
    }
    model.interface(vars, constants)
}

/// How `v`'s values travel (`None`: no port or parameter has its type), its dimensions and its
/// start values.
fn typed(v: &Variable) -> (Option<Kind>, &[Dimension], Vec<ParamValue>) {
    fn starts<T: Copy>(s: Option<&[T]>, f: impl Fn(T) -> ParamValue) -> Vec<ParamValue> {
        s.unwrap_or(&[]).iter().map(|&x| f(x)).collect()
    }
    match v {
        Variable::Float64(f) => (
            Some(Kind::Real),
            f.dimensions(),
            starts(f.start(), ParamValue::F64),
        ),
        Variable::Int32(i) => (
            Some(Kind::Int32),
            i.dimensions(),
            starts(i.start(), |x| ParamValue::I64(i64::from(x))),
        ),
        Variable::Int64(i) => (
            Some(Kind::Int64),
            i.dimensions(),
            starts(i.start(), ParamValue::I64),
        ),
        Variable::UInt64(u) => (
            Some(Kind::UInt64),
            u.dimensions(),
            starts(u.start(), |x| {
                ParamValue::I64(i64::try_from(x).unwrap_or(i64::MAX))
            }),
        ),
        Variable::Boolean(b) => (
            Some(Kind::Bool),
            b.dimensions(),
            starts(b.start(), ParamValue::Bool),
        ),
        _ => (None, &[], Vec::new()),
    }
}

/// What every FMI 3 variable has: its name, value reference, causality.
fn abstract_of(v: &Variable) -> &dyn AbstractVariableTrait {
    match v {
        Variable::Float64(f) => f,
        Variable::Int32(i) => i,
        Variable::Int64(i) => i,
        Variable::Boolean(b) => b,
        Variable::Float32(f) => f,
        Variable::Int8(i) => i,
        Variable::UInt8(i) => i,
        Variable::Int16(i) => i,
        Variable::UInt16(i) => i,
        Variable::UInt32(i) => i,
        Variable::UInt64(i) => i,
        Variable::String(s) => s,
        Variable::Binary(b) => b,
        Variable::Clock(c) => c,
    }
}

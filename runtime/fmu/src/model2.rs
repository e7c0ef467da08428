//! What an FMI 2.0 modelDescription.xml says of the component's variables: its inputs, outputs
//! and parameters (Real, Integer, Boolean), their start values and declared ranges.

use fmi_schema::fmi2::{Causality, Fmi2ModelDescription, ScalarVariableElement as E};
use modbot_grid::component::ParamValue;

use super::error::FmuErrorKind;
use super::gather::{Role, Var};
use super::model::{self, Model};
use super::variables::{Interface, Kind, Version};

/// The interface `xml` describes (arrays need no sizing in FMI 2).
pub fn read(xml: &str) -> Result<Interface, FmuErrorKind> {
    let md: Fmi2ModelDescription = model::parse(xml)?;
    let cs = md.co_simulation.as_ref();
    let model = Model::new(Version::Fmi2, &md, cs, &md.guid, md.description.as_deref())?;
    let ranges = super::ranges::scan(xml);
    let vars = md.model_variables.variables.iter().filter_map(|v| {
        let role = match v.causality {
            Causality::Input => Role::Input,
            Causality::Output => Role::Output,
            Causality::Parameter => Role::Param,
            _ => return None,
        };
        let (kind, start) = match &v.elem {
            E::Real(r) => (Some(Kind::Real), ParamValue::F64(r.start.unwrap_or(0.0))),
            E::Integer(i) => (
                Some(Kind::Int32),
                ParamValue::I64(i64::from(i.start.unwrap_or(0))),
            ),
            E::Boolean(b) => (Some(Kind::Bool), ParamValue::Bool(b.start.unwrap_or(false))),
            _ => (None, ParamValue::F64(0.0)),
        };
        Some(Var {
            name: v.name.clone(),
            role,
            kind,
            vr: v.value_reference,
            shape: Vec::new(),
            start: vec![start],
            range: ranges.get(&v.name).copied().unwrap_or_default(),
            structural: false,
        })
    });
    model.interface(vars.collect(), Vec::new())
}

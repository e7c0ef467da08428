//! What the readers of both FMI versions' modelDescription.xml (`model2`, `model3`) share:
//! the XML parsed, what it says of the model itself, and the [`Interface`] assembled from
//! that and the model's variables.

use fmi_schema::traits::{FmiInterfaceType, FmiModelDescription};

use super::error::FmuErrorKind;
use super::gather::{gather, Var};
use super::variables::{Interface, Version};

/// What a model description says of the model, whichever its FMI version.
pub struct Model {
    version: Version,
    name: String,
    /// Its co-simulation interface's model identifier.
    identifier: String,
    /// FMI 2's guid, FMI 3's instantiation token.
    token: String,
    description: String,
}

/// Parses `xml` as a model description of type `M` (FMI 2's or FMI 3's).
pub fn parse<M: FmiModelDescription>(xml: &str) -> Result<M, FmuErrorKind> {
    M::deserialize(xml).map_err(|e| FmuErrorKind::Xml(e.to_string()))
}

impl Model {
    /// The model `md` describes in FMI `version`, with its co-simulation interface `cs` (an FMU
    /// without one is refused), its `token` and its `description`.
    pub fn new(
        version: Version,
        md: &impl FmiModelDescription,
        cs: Option<&impl FmiInterfaceType>,
        token: &str,
        description: Option<&str>,
    ) -> Result<Model, FmuErrorKind> {
        let cs = cs.ok_or(FmuErrorKind::NoCoSimulation)?;
        Ok(Model {
            version,
            name: md.model_name().to_owned(),
            identifier: cs.model_identifier().to_owned(),
            token: token.to_owned(),
            description: description.unwrap_or_default().to_owned(),
        })
    }

    /// The interface of this model, whose variables are `vars` and UInt64 constants
    /// `constants` (value reference, value).
    pub fn interface(
        self,
        vars: Vec<Var>,
        constants: Vec<(u32, u64)>,
    ) -> Result<Interface, FmuErrorKind> {
        let (inputs, outputs, params) = gather(vars)?;
        Ok(Interface {
            version: self.version,
            model_name: self.name,
            model_identifier: self.identifier,
            token: self.token,
            description: self.description,
            inputs,
            outputs,
            params,
            constants,
        })
    }
}

//! An FMU's interface as a component sees it, read from its modelDescription.xml: the inputs
//! and outputs that become ports, the parameters that become parameters, and how each travels
//! to and from the FMU (its value references and FMI type).
//!
//! | FMI 2.0 | FMI 3.0 | port or parameter type |
//! |---|---|---|
//! | Real | Float64 | f64 |
//! | Real `x[1]` … `x[n]` (one variable per element) | Float64 with one `Dimension` of n | f64[n] |
//! | | Float64 with `Dimension`s r, c, … (a matrix) | f64[r·c·…], row-major |
//! | | a `Dimension` that names a structural parameter (`valueReference`) | its size at instantiation |
//! | Integer | Int32, Int64 | i64 |
//! | | UInt64 parameter or structural parameter | i64 parameter, 0 or more |
//! | Boolean | Boolean | bool |
//!
//! Inputs and outputs of other types (and arrays of types other than Float64) are refused (a
//! port needs a type); parameters of other types are left at their start values. A port is
//! named like its variable, every character other than a letter, a digit or `_` made `_`
//! (`der(x)` → `der_x_`); parameters keep their names. Ports and parameters are in the order of
//! the variables (an array where its first element is).
//!
//! An array's size is fixed when the component is made: a `Dimension` with a `start` is that
//! number; one with a `valueReference` is the value of that structural parameter (UInt64) as
//! the description sets it, or else its start value (or the value of that constant). The
//! description's value is set in Configuration Mode before the FMU is initialised (see
//! `running`). So [`Interface::read`] gives the interface at the start values and
//! [`Interface::sized`] the one for a component's parameters.

use std::path::Path;

use modbot_grid::component::{ParamType, ParamValue, Params, PortType};

use super::archive;
use super::error::{FmuError, FmuErrorKind};

pub use super::variables::{Extent, Interface, Kind, Param, Port, Version, MAX_ELEMENTS};

impl Interface {
    /// Reads the interface of the FMU at `path` (and checks that it has a binary for this
    /// platform), its arrays sized by the structural parameters' start values.
    pub fn read(path: &Path) -> Result<Interface, FmuError> {
        let failed = |kind| FmuError::new(path, kind);
        let xml = archive::model_description(path)?;
        use fmi_schema::traits::FmiModelDescription;
        let version = fmi_schema::minimal::MinModelDescription::deserialize(&xml)
            .map_err(|e| failed(FmuErrorKind::Xml(e.to_string())))?
            .fmi_version;
        let interface = match version.split('.').next() {
            Some("2") => super::model2::read(&xml),
            Some("3") => super::model3::read(&xml),
            _ => Err(FmuErrorKind::Version(version)),
        }
        .and_then(|i| i.sized(&Params::new()))
        .map_err(failed)?;
        archive::check_binary(path, &interface.binary_path())?;
        Ok(interface)
    }

    /// This interface with its arrays sized by the structural parameters as `params` set them
    /// (their start values otherwise). The values are taken as they are: check them against
    /// their ranges first (`component_type`).
    pub fn sized(mut self, params: &Params) -> Result<Interface, FmuErrorKind> {
        let mut sizes = self.constants.clone();
        for q in self.params.iter().filter(|q| q.structural) {
            let value = params.get(&q.name).unwrap_or(&q.start);
            if let Some(ParamValue::I64(n)) = value.coerce(ParamType::I64) {
                sizes.extend(q.refs.first().map(|&r| (r, u64::try_from(n).unwrap_or(0))));
            }
        }
        let size_of = |name: &str, shape: &[Extent]| -> Result<Vec<u64>, FmuErrorKind> {
            let refuse = |why: String| FmuErrorKind::Variable {
                name: name.to_owned(),
                why,
            };
            let mut dims = Vec::with_capacity(shape.len());
            for extent in shape {
                dims.push(match *extent {
                    Extent::Fixed(n) => n,
                    Extent::Of(r) => sizes.iter().find(|(vr, _)| *vr == r).map(|s| s.1).ok_or_else(
                        || refuse(format!("its Dimension names value reference {r}, which is no UInt64 structural parameter or constant")),
                    )?,
                });
            }
            let total = dims.iter().try_fold(1u64, |a, &d| a.checked_mul(d));
            match total {
                Some(n) if n <= MAX_ELEMENTS => Ok(dims),
                _ => Err(refuse(format!(
                    "an array of {} elements: at most {MAX_ELEMENTS} are supported",
                    shape_text(&dims)
                ))),
            }
        };
        for port in self.inputs.iter_mut().chain(self.outputs.iter_mut()) {
            if port.shape.is_empty() {
                continue;
            }
            let n = size_of(&port.name, &port.shape)?.iter().product::<u64>();
            if n == 0 {
                return Err(FmuErrorKind::Variable {
                    name: port.name.clone(),
                    why: "an array of 0 elements cannot be a port".into(),
                });
            }
            port.ty = PortType::F64s(usize::try_from(n).unwrap_or(usize::MAX));
        }
        for q in self.params.iter_mut().filter(|q| !q.shape.is_empty()) {
            q.dims = size_of(&q.name, &q.shape)?;
            let n = usize::try_from(q.dims.iter().product::<u64>()).unwrap_or(usize::MAX);
            if let ParamValue::F64s(xs) = &mut q.start {
                // Start values that do not fit the new size: a single one fills it, others are
                // cut or filled with zeros (what is shown as the default; the FMU keeps its own).
                let fill = if xs.len() == 1 { xs[0] } else { 0.0 };
                xs.resize(n, fill);
            }
        }
        Ok(self)
    }

    /// The path in the archive of its binary for this platform.
    pub fn binary_path(&self) -> String {
        let platform = match (self.version, std::env::consts::ARCH) {
            (Version::Fmi2, _) => "linux64",
            (Version::Fmi3, "aarch64") => "aarch64-linux",
            (Version::Fmi3, _) => "x86_64-linux",
        };
        format!(
            "binaries/{platform}/{}{}",
            self.model_identifier,
            std::env::consts::DLL_SUFFIX
        )
    }
}

/// `2×3` for dimensions 2 and 3, `6` for one.
pub fn shape_text(dims: &[u64]) -> String {
    dims.iter()
        .map(u64::to_string)
        .collect::<Vec<_>>()
        .join("×")
}

#[cfg(test)]
mod tests;

//! Why an FMU cannot be a component: the file, and what is wrong with it.

use std::path::PathBuf;

use thiserror::Error;

/// An FMU that cannot be used: which file, and why.
#[derive(Debug, Error)]
#[error("{}: {kind}", .path.display())]
pub struct FmuError {
    pub path: PathBuf,
    #[source]
    pub kind: FmuErrorKind,
}

/// What is wrong with an FMU.
#[derive(Debug, Error)]
pub enum FmuErrorKind {
    #[error("no such file{}", .searched.as_deref().map(|s| format!(" ({s})")).unwrap_or_default())]
    NotFound {
        /// Where else it was looked for.
        searched: Option<String>,
    },
    #[error("cannot be read: {0}")]
    Io(#[from] std::io::Error),
    #[error("is not an FMU (a zip archive): {0}")]
    NotZip(String),
    #[error("has no modelDescription.xml")]
    NoModelDescription,
    #[error("modelDescription.xml is not valid: {0}")]
    Xml(String),
    #[error("is FMI version '{0}': FMI 2.0 and 3.0 are supported")]
    Version(String),
    #[error("is not a co-simulation FMU (its modelDescription.xml has no CoSimulation element)")]
    NoCoSimulation,
    #[error("has no binary for this platform: {expected} is not in the archive")]
    NoBinary { expected: String },
    /// A variable the component cannot map to a port.
    #[error("variable '{name}': {why}")]
    Variable { name: String, why: String },
    /// The fmi crate refused to load or run it.
    #[error("{0}")]
    Import(String),
}

impl FmuError {
    pub fn new(path: impl Into<PathBuf>, kind: FmuErrorKind) -> FmuError {
        FmuError {
            path: path.into(),
            kind,
        }
    }
}

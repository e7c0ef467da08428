//! Where a running FMU is unpacked: a temporary directory of the system's domain,
//! `<tmp>/modbot_<domain>.tmp.<pid>.<random>/` ([`Domain::temp_prefix`]). The import removes
//! it when the FMU is dropped; when the host process is killed, the supervisor removes what
//! its pid left as soon as it sees the death, and `modbot up` and `modbot down` every file
//! of the domain — so a killed host leaves nothing after the run. A host started without a
//! supervisor (no `MODBOT_DOMAIN`) unpacks under `modbot-fmu.<pid>.`.

use std::io::Read;

use fmi::traits::FmiImport;
use modbot_core::domain::Domain;
use modbot_core::transport::launch::DOMAIN;

/// The archive's description of the model, at its root.
const MODEL_DESCRIPTION: &str = "modelDescription.xml";

/// Why an FMU could not be unpacked and imported.
#[derive(Debug, thiserror::Error)]
pub enum UnpackError {
    #[error("{0}")]
    Open(std::io::Error),
    #[error("not an FMU: {0}")]
    NotAnFmu(zip::result::ZipError),
    #[error("cannot make a directory to unpack it in: {0}")]
    TempDir(std::io::Error),
    #[error("cannot unpack it: {0}")]
    Extract(zip::result::ZipError),
    #[error("{MODEL_DESCRIPTION}: {0}")]
    ModelDescription(std::io::Error),
    /// The FMI library refused the model description (its error, as it says it).
    #[error("{0}")]
    Import(String),
}

/// Unpacks the FMU at `path` into a temporary directory of the domain and imports it (what
/// `fmi::import::from_path` does, in a directory of ours).
pub fn import<Imp: FmiImport>(path: &str) -> Result<Imp, UnpackError> {
    let file = std::fs::File::open(path).map_err(UnpackError::Open)?;
    let mut archive = zip::ZipArchive::new(file).map_err(UnpackError::NotAnFmu)?;
    let dir = tempfile::Builder::new()
        .prefix(&prefix())
        .tempdir()
        .map_err(UnpackError::TempDir)?;
    archive.extract(dir.path()).map_err(UnpackError::Extract)?;
    let mut xml = String::new();
    std::fs::File::open(dir.path().join(MODEL_DESCRIPTION))
        .and_then(|mut f| f.read_to_string(&mut xml))
        .map_err(UnpackError::ModelDescription)?;
    Imp::new(dir, &xml).map_err(|e| UnpackError::Import(e.to_string()))
}

/// The name prefix of this process's temporary directories.
fn prefix() -> String {
    let pid = std::process::id();
    match std::env::var(DOMAIN)
        .ok()
        .and_then(|d| Domain::new(&d).ok())
    {
        Some(domain) => domain.temp_prefix(pid),
        None => format!("modbot-fmu.{pid}."),
    }
}

//! The .fmu archive (a zip file): its modelDescription.xml, and whether it has a binary for
//! this platform — read without unpacking, so `modbot check` finds a broken FMU before any
//! process starts.

use std::io::Read;
use std::path::Path;

use super::error::{FmuError, FmuErrorKind};

fn open(path: &Path) -> Result<zip::ZipArchive<std::fs::File>, FmuError> {
    let failed = |kind| FmuError::new(path, kind);
    let file = std::fs::File::open(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => failed(FmuErrorKind::NotFound { searched: None }),
        _ => failed(FmuErrorKind::Io(e)),
    })?;
    zip::ZipArchive::new(file).map_err(|e| failed(FmuErrorKind::NotZip(e.to_string())))
}

/// The text of the FMU's modelDescription.xml.
pub fn model_description(path: &Path) -> Result<String, FmuError> {
    let failed = |kind| FmuError::new(path, kind);
    let mut archive = open(path)?;
    let mut entry = archive
        .by_name("modelDescription.xml")
        .map_err(|_| failed(FmuErrorKind::NoModelDescription))?;
    let mut xml = String::new();
    entry
        .read_to_string(&mut xml)
        .map_err(|e| failed(FmuErrorKind::Xml(e.to_string())))?;
    Ok(xml)
}

/// `Ok` if the archive holds the file `entry` (the binary for this platform).
pub fn check_binary(path: &Path, entry: &str) -> Result<(), FmuError> {
    if open(path)?.index_for_name(entry).is_none() {
        let expected = entry.to_owned();
        return Err(FmuError::new(path, FmuErrorKind::NoBinary { expected }));
    }
    Ok(())
}

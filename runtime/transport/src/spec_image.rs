//! The checked grid of each assembly generation, as the supervisor wrote it for the domain's
//! grid processes: `/dev/shm/modbot_<domain>.spec.g<N>`, written whole once (at a scratch name,
//! then renamed), read by every grid process that starts or restarts with `--spec-generation N`.
//! The bytes are `modbot_ipc_schema::grid_spec`'s; this file only keeps them. They are among
//! the domain's files, so they go when the system goes.

use std::io::Write;
use std::os::unix::fs::OpenOptionsExt;
use std::path::PathBuf;

use thiserror::Error;

use crate::domain::Domain;

/// What the images' names have after the domain's prefix: `spec.g<N>`.
pub const SPEC_IMAGE_INFIX: &str = "spec.g";

/// A checked grid's image could not be written or read.
#[derive(Debug, Error)]
#[error("the checked grid of generation {generation} ({}): {source}", path.display())]
pub struct SpecImageError {
    pub generation: u16,
    pub path: PathBuf,
    #[source]
    pub source: std::io::Error,
}

impl Domain {
    /// Where the checked grid of assembly generation `generation` is kept.
    pub fn spec_image_path(&self, generation: u16) -> PathBuf {
        PathBuf::from("/dev/shm").join(format!("{}{SPEC_IMAGE_INFIX}{generation}", self.prefix()))
    }

    /// Writes the image of generation `generation` whole: a reader never sees part of one.
    pub fn write_spec_image(&self, generation: u16, bytes: &[u8]) -> Result<(), SpecImageError> {
        let path = self.spec_image_path(generation);
        let scratch = path.with_extension(format!("{}.new", std::process::id()));
        let written = (|| {
            let mut file = std::fs::OpenOptions::new()
                .write(true)
                .create(true)
                .truncate(true)
                .mode(0o600)
                .open(&scratch)?;
            file.write_all(bytes)?;
            std::fs::rename(&scratch, &path)
        })();
        if written.is_err() {
            let _ = std::fs::remove_file(&scratch);
        }
        written.map_err(|source| SpecImageError {
            generation,
            path,
            source,
        })
    }

    /// The image of generation `generation`.
    pub fn read_spec_image(&self, generation: u16) -> Result<Vec<u8>, SpecImageError> {
        let path = self.spec_image_path(generation);
        std::fs::read(&path).map_err(|source| SpecImageError {
            generation,
            path,
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_written_is_read_back_and_goes_with_the_domains_files() {
        let domain = Domain::new(&format!("specimg_{}", std::process::id())).unwrap();
        domain.write_spec_image(3, b"first").unwrap();
        domain.write_spec_image(3, b"second").unwrap();
        assert_eq!(domain.read_spec_image(3).unwrap(), b"second");
        assert!(domain.files().contains(&domain.spec_image_path(3)));
        let missing = domain.read_spec_image(4).unwrap_err();
        assert!(missing.to_string().contains("generation 4"), "{missing}");
        std::fs::remove_file(domain.spec_image_path(3)).unwrap();
        assert_eq!(domain.files(), Vec::<PathBuf>::new());
    }
}

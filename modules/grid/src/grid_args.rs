//! The option of the grid's programs: which checked grid they serve. The supervisor reads the
//! system description (and every assembly file) and writes each assembly generation's checked
//! grid into the domain (`modbot_transport::spec_image`); a grid process reads the one it is
//! told, so no grid process evaluates a description.

use std::sync::Arc;

use clap::Args;
use modbot_core::domain::Domain;
use modbot_core::transport::spec_image::SpecImageError;
use modbot_grid::component::{Generation, Registry};
use modbot_grid::host::{LoadAssembly, LoadError};
use modbot_grid::GridSpec;
use modbot_ipc_schema::grid_spec::GridSpecError;

/// The options of the grid's programs (coordinator, hosts, bus bridge).
#[derive(Debug, Clone, Args)]
pub struct GridArgs {
    /// The assembly generation of the checked grid this process serves (0: a grid without
    /// assemblies), as the supervisor wrote it for the domain.
    #[arg(long, value_name = "N")]
    pub spec_generation: u16,
}

impl GridArgs {
    /// The checked grid of `--spec-generation` in `domain`.
    pub fn load(&self, domain: &str) -> anyhow::Result<GridSpec> {
        Ok(read_grid(
            &Domain::new(domain)?,
            Generation(self.spec_generation),
        )?)
    }

    /// [`GridArgs::load`] for a host program with component types of its own (`registry`):
    /// what the description declares of them must be what the program registers.
    pub fn load_with(&self, domain: &str, registry: &Registry) -> anyhow::Result<GridSpec> {
        let grid = self.load(domain)?;
        registry.with_declared(&grid.declared)?;
        Ok(grid)
    }
}

/// The checked grid of a generation cannot be had.
#[derive(Debug, thiserror::Error)]
pub enum CheckedGridError {
    #[error(transparent)]
    Read(#[from] SpecImageError),
    #[error("{}: {source}", path.display())]
    Malformed {
        path: std::path::PathBuf,
        source: GridSpecError,
    },
}

/// The checked grid of `generation` in `domain`.
pub fn read_grid(domain: &Domain, generation: Generation) -> Result<GridSpec, CheckedGridError> {
    let image = domain.read_spec_image(generation.0)?;
    GridSpec::from_image(&image).map_err(|source| CheckedGridError::Malformed {
        path: domain.spec_image_path(generation.0),
        source,
    })
}

/// How a host of the system's own components gets an assembly the coordinator announces: the
/// checked grid the supervisor wrote for its generation.
pub fn assembly_loader(domain: &str) -> anyhow::Result<LoadAssembly> {
    let domain = Domain::new(domain)?;
    Ok(Arc::new(
        move |_: &GridSpec, _: &str, generation: Generation| {
            read_grid(&domain, generation).map_err(LoadError::from)
        },
    ))
}

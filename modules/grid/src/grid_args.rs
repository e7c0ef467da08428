//! The options of the grid's programs: the system description they all load.

use std::path::PathBuf;

use clap::Args;
use modbot_runtime::grid::component::Generation;
use modbot_runtime::grid::GridSpec;
use modbot_runtime::system::{self, DefaultResolver};

/// The options of the grid's programs (coordinator, hosts, bus bridge): the system
/// description they all load, with its variables.
#[derive(Debug, Clone, Args)]
pub struct GridArgs {
    /// The system description with the grid.
    #[arg(long)]
    pub system: PathBuf,
    /// A variable for the description (`vars.KEY`); repeatable.
    #[arg(long = "var", value_parser = system::parse_var)]
    pub vars: Vec<(String, String)>,
    /// The assembly whose components this host steps (its hosts are started with it).
    #[arg(long, requires = "generation")]
    pub assembly: Option<String>,
    /// The assembly's generation.
    #[arg(long, requires = "assembly")]
    pub generation: Option<u16>,
    /// Run the grid in lockstep whatever the description says (`modbot up --lockstep`).
    #[arg(long)]
    pub lockstep: bool,
}

impl GridArgs {
    /// Loads the description and returns its grid, with the built-in component types.
    pub fn load(&self) -> anyhow::Result<GridSpec> {
        self.load_with(&modbot_runtime::components::builtin())
    }

    /// Loads the description and returns its grid, with the component types of `registry`
    /// (a host program's own, checked against what the description declares of them).
    pub fn load_with(&self, registry: &modbot_runtime::grid::Registry) -> anyhow::Result<GridSpec> {
        let resolver = DefaultResolver::for_file(&self.system);
        let spec = system::load_with_registry(&self.system, &resolver, &self.vars, registry)?;
        let mut grid = spec
            .grid
            .ok_or_else(|| anyhow::anyhow!("{}: no grid", self.system.display()))?;
        if self.lockstep {
            grid.set_clock(modbot_runtime::grid::GridClock::Lockstep);
        }
        match (&self.assembly, self.generation) {
            (Some(name), Some(generation)) => Ok(system::load_assembly(
                &grid,
                name,
                Generation(generation),
                registry,
            )?),
            _ => Ok(grid),
        }
    }
}

/// Loads an assembly of the running grid with the built-in components (what a host hands
/// [`modbot_runtime::grid::host::Host::prepare_step`]).
pub fn load_assembly(
    system: &GridSpec,
    name: &str,
    generation: Generation,
) -> Result<GridSpec, modbot_runtime::grid::host::LoadError> {
    let registry = modbot_runtime::components::builtin();
    Ok(system::load_assembly(system, name, generation, &registry)?)
}

//! The checked grids of a run's assembly generations: the supervisor alone reads the system
//! description and the assembly files. It writes the first generation's grid when the system
//! starts, and loads every later assembly when the coordinator asks
//! (`load_assembly(name, generation)`), writing its checked grid for the grid processes
//! (`modbot_transport::spec_image`): a host started or restarted for generation N reads
//! image N, whatever happened to the files since.

use modbot_core::ctx::Ctx;
use modbot_core::domain::Domain;
use modbot_core::error::MethodError;
use modbot_core::module::Reply;
use modbot_core::transport::spec_image::SpecImageError;
use modbot_grid::component::Generation;
use modbot_grid::GridSpec;
use modbot_ipc_schema::{Args, Value};

use super::shared::Shared;

/// Writes the checked grid `grid` for its generation's processes.
pub(super) fn write_image(domain: &Domain, grid: &GridSpec) -> Result<usize, SpecImageError> {
    let image = grid.to_image();
    domain.write_spec_image(grid.generation().0, &image)?;
    Ok(image.len())
}

/// `load_assembly(name, generation)`: loads the assembly file `name` against the system's grid
/// as generation `generation` and writes its checked grid; answers the image's length. A file
/// that does not load is a failure naming the file, the line and what is wrong.
pub(super) fn load_assembly_method(
    shared: &mut Shared,
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let (name, generation) = (args.text(0)?, args.i64(1)?);
    let Some(loader) = &shared.assemblies else {
        return Err(MethodError::Failed("this system has no assemblies".into()));
    };
    let generation = assembly_generation(generation)?;
    let registry = modbot_components::builtin();
    let spec = modbot_system::load_assembly(&loader.grid, name, generation, &registry)
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    let len = write_image(&loader.domain, &spec).map_err(|e| MethodError::Failed(e.to_string()))?;
    tracing::info!("assembly {name} loaded as generation {generation} ({len} bytes checked)");
    reply.push(Value::I64(len as i64));
    Ok(())
}

/// An assembly's generation as a method's argument gives it: 1 to 65535.
pub(super) fn assembly_generation(n: i64) -> Result<Generation, MethodError> {
    u16::try_from(n)
        .ok()
        .filter(|g| *g >= 1)
        .map(Generation)
        .ok_or_else(|| MethodError::Failed(format!("generation {n} is out of range")))
}

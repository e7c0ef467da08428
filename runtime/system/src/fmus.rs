//! FMU components in descriptions (`component "ff" { type = "fmu", fmu = "ff.fmu", ... }`):
//! the type every description may use, where a component's FMU file is found, and the rule
//! that each FMU runs in a host process of its own.
//!
//! The file: an absolute path as it is; a path with a `/` relative to the directory of the file
//! that declares the component (the system description's, or the assembly's); a bare name there
//! too, and otherwise next to the running program — where the workspace's build puts the
//! project's own FMUs (`fmu = "modbot_ff2.fmu"`). What the FMU declares is read when the
//! description is checked ([`modbot_fmu::component_type`]).

use std::path::{Path, PathBuf};

use super::SystemError;
use modbot_grid::component::{ParamValue, Registry};
use modbot_grid::spec::ComponentDecl;
use modbot_grid::GridSpec;

/// `registry` with the type `fmu` (made by `modbot-fmu-host`, unless `registry` makes it).
pub(super) fn with_fmus(registry: &Registry) -> Registry {
    let mut registry = registry.clone();
    modbot_fmu::declare(&mut registry);
    registry
}

/// Makes the `fmu` of every FMU component of `components` a path (see the module's doc),
/// declared in a file in `dir`.
pub(super) fn find_files(components: &mut [ComponentDecl], dir: &Path) {
    for c in components {
        if let Some(ParamValue::Text(name)) = c.params.get(modbot_fmu::FMU).cloned() {
            let path = fmu_path(&name, dir).display().to_string();
            c.params.set(modbot_fmu::FMU, ParamValue::Text(path));
        }
    }
}

fn fmu_path(name: &str, dir: &Path) -> PathBuf {
    let path = Path::new(name);
    if path.is_absolute() {
        return path.to_path_buf();
    }
    let here = std::path::absolute(dir.join(path)).unwrap_or_else(|_| dir.join(path));
    if name.contains('/') || here.exists() {
        return here;
    }
    let beside = std::env::current_exe()
        .ok()
        .and_then(|exe| Some(exe.parent()?.join(path)))
        .filter(|p| p.exists());
    beside.unwrap_or(here)
}

/// Whether the FMU components of `spec` among those at `indices` (the ones declared in
/// `file`) have a host each: one FMU's crash then takes only its own host down. An error names
/// `file` and the second FMU's line.
pub(super) fn one_per_host(
    spec: &GridSpec,
    indices: std::ops::Range<usize>,
    file: &str,
) -> Result<(), SystemError> {
    let fmus: Vec<_> = spec.components[indices.start.min(spec.components.len())..]
        .iter()
        .take(indices.len())
        .filter(|c| c.type_name == modbot_fmu::TYPE)
        .collect();
    for (i, c) in fmus.iter().enumerate() {
        if let Some(first) = fmus[..i].iter().find(|o| o.host == c.host) {
            return Err(SystemError::new(
                file,
                Some(c.line),
                format!(
                    "component '{}': host '{}' runs the FMU of '{}' (line {}); give each FMU a \
                     host of its own, so that a crash of one takes no other down",
                    c.name, c.host, first.name, first.line
                ),
            ));
        }
    }
    Ok(())
}

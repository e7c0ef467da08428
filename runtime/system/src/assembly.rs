//! Assembly files: a control structure the time grid can swap while the robot runs (MoRC's
//! Assembly).
//!
//! A system whose grid says `assemblies = "DIR", assembly = "NAME"` keeps its own components
//! (the bus) and adds those of one assembly, the file `DIR/NAME.lua` next to the description.
//! An assembly file is sandboxed Lua like a description, with `vars` and `data(key)` (the
//! domain's assembly data: a robot program's parameters for it), and declares only
//! `component` and `connect`; it connects its components to the system's ports (as in
//! `connect "robot.motor_position -> hold.start"`). Its components run on hosts of their own:
//! a host of the system's components cannot take them.
//!
//! [`load_assembly`] evaluates a file and checks it together with the system's components
//! (types, parameters, every input connected once); an error names the assembly file and line.

use std::path::Path;
use std::sync::Arc;

use super::{fmus, lua, record_decl, SystemError};
use modbot_grid::component::Generation;
use modbot_grid::spec::{Assembly, AssemblySource, GridError, GridSpec, RecordDecl};
use modbot_grid::Registry;

/// Lines of assembly declarations are offset by this while the combined grid is checked, so
/// an error can say which file it is in.
const LINE_OFFSET: u32 = 1 << 28;

pub use modbot_grid::switch::check_assembly_name;

/// The assemblies in `dir`, sorted: the names of its `*.lua` files.
pub fn assembly_names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().into_string().ok()?;
            let stem = name.strip_suffix(".lua")?;
            check_assembly_name(stem).ok().map(|_| stem.to_owned())
        })
        .collect();
    names.sort();
    names
}

/// The grid of `system` (a spec of a grid with assemblies) with the assembly `name` in place
/// of its current one, as generation `generation`.
pub fn load_assembly(
    system: &GridSpec,
    name: &str,
    generation: Generation,
    registry: &Registry,
) -> Result<GridSpec, SystemError> {
    let Some(current) = &system.assembly else {
        return Err(SystemError::new(
            "",
            None,
            "this grid has no assemblies: declare grid { assemblies = \"DIR\", assembly = \"NAME\" }",
        ));
    };
    let Some(origin) = &current.source else {
        return Err(SystemError::new(
            "",
            None,
            "this grid came checked from the supervisor, without its description: only the \
             supervisor loads assemblies",
        ));
    };
    let system_file = origin.system_file.as_str();
    check_assembly_name(name).map_err(|e| SystemError::new(system_file, None, e.to_string()))?;
    let path = origin.dir.join(format!("{name}.lua"));
    let file = path.display().to_string();
    let source = match std::fs::read(&path) {
        Ok(bytes) => String::from_utf8(bytes)
            .map_err(|_| SystemError::new(&file, None, "the assembly file is not UTF-8 text"))?,
        Err(e) => {
            let known = assembly_names(&origin.dir);
            if e.kind() != std::io::ErrorKind::NotFound {
                let message = format!("cannot read the assembly file: {e}");
                return Err(SystemError::new(&file, None, message).because(e));
            }
            let message = format!(
                "no assembly named '{name}' in {} (assemblies: {})",
                origin.dir.display(),
                if known.is_empty() {
                    "none".to_owned()
                } else {
                    known.join(", ")
                }
            );
            return Err(SystemError::new(&file, None, message));
        }
    };
    let decls = lua::evaluate(&file, &source, &origin.vars, origin.data.as_deref())?;
    let stray = [
        decls.domain.as_ref().map(|d| d.1),
        decls.supervision.as_ref().map(|s| s.1),
        decls.modules.first().map(|m| m.line),
        decls.groups.first().map(|g| g.line),
        decls.grid.as_ref().map(|g| g.line),
    ];
    if let Some(line) = stray.into_iter().flatten().min() {
        return Err(SystemError::new(
            &file,
            Some(line),
            "an assembly file declares only component and connect (the domain, modules, \
             supervision and the grid belong to the system description)",
        ));
    }
    let (grid, base_components, base_connections) = origin.decls.clone();
    let base_hosts: Vec<&str> = base_components.iter().map(|c| c.host.as_str()).collect();
    let on_base_host = decls
        .components
        .iter()
        .map(|c| (&c.name, &c.host, c.line))
        .chain(decls.records.iter().map(|r| (&r.name, &r.host, r.line)))
        .find(|(_, host, _)| base_hosts.contains(&host.as_str()));
    if let Some((name, host, line)) = on_base_host {
        return Err(SystemError::new(
            &file,
            Some(line),
            format!(
                "component '{name}': host '{host}' runs the system's own components; give the \
                 assembly's components hosts of their own"
            ),
        ));
    }
    if decls.components.is_empty() {
        return Err(SystemError::new(
            &file,
            None,
            "the assembly has no components: add component \"name\" { type = ..., host = ... }",
        ));
    }
    let base = base_components.len();
    let mut components = base_components.clone();
    let mut own = decls.components;
    fmus::find_files(&mut own, &origin.dir);
    components.extend(own.into_iter().map(|mut c| {
        c.line += LINE_OFFSET;
        c
    }));
    let mut connections = base_connections.clone();
    connections.extend(decls.connections.into_iter().map(|mut c| {
        c.line += LINE_OFFSET;
        c
    }));
    // A replayable recorder of the system records what this assembly commands the sources.
    let mirrored = modbot_grid::spec::mirrored_connections(&components, &connections);
    connections.extend(mirrored);
    if let Some(r) = decls.records.iter().find(|r| r.replay.is_some()) {
        return Err(SystemError::new(
            &file,
            Some(r.line),
            "replay belongs to the system's recorder, which outlives the switches: declare it \
             in the system description",
        ));
    }
    let registry = &fmus::with_fmus(registry)
        .with_declared(&system.declared)
        .map_err(|e| SystemError::new(system_file, Some(e.line), e.to_string()))?;
    let refused = |e: GridError| match e.line {
        Some(l) if l >= LINE_OFFSET => SystemError::caused(&file, Some(l - LINE_OFFSET), e.kind),
        line => SystemError::caused(system_file, line, e.kind),
    };
    let build = |components, connections| {
        GridSpec::build(grid.clone(), components, connections, registry).map_err(refused)
    };
    let mut spec = build(components.clone(), connections.clone())?;
    if !decls.records.is_empty() {
        // The assembly's recorder: its signals may be the system's and the assembly's, and
        // it keeps the text of both files.
        spec.timing = system.timing;
        let records: Vec<RecordDecl> = (decls.records.into_iter())
            .filter_map(|mut r| {
                r.file = record_decl::file_of(&r.file, &origin.vars, Some(name))?;
                r.line += LINE_OFFSET;
                r.sources = vec![
                    (
                        record_decl::absolute(&origin.system_file),
                        origin.system_text.clone(),
                    ),
                    (file.clone(), source.clone()),
                ];
                Some(r)
            })
            .collect();
        let decls = (&mut components, &mut connections);
        record_decl::add_recorders(&records, &spec, None, decls, refused)?;
        spec = build(components, connections)?;
    }
    for c in spec.components.iter_mut().skip(base) {
        c.line -= LINE_OFFSET;
    }
    for c in spec.connections.iter_mut() {
        if c.line >= LINE_OFFSET {
            c.line -= LINE_OFFSET;
        }
    }
    fmus::one_per_host(&spec, base..spec.components.len(), &file)?;
    // How the grid keeps time is the running system's (`modbot up --lockstep` included).
    spec.timing = system.timing;
    spec.set_clock(system.timing.clock);
    spec.declared = system.declared.clone();
    spec.assembly = Some(Assembly {
        name: name.to_owned(),
        generation,
        base,
        source: Some(Arc::new(AssemblySource {
            dir: origin.dir.clone(),
            decls: (grid, base_components, base_connections),
            vars: origin.vars.clone(),
            system_file: origin.system_file.clone(),
            system_text: origin.system_text.clone(),
            data: origin.data.clone(),
        })),
    });
    Ok(spec)
}

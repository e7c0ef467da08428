//! The checks across declarations, and the program lookup: declarations become a
//! [`SystemSpec`].
//!
//! Errors are reported in file order as far as possible: the domain first (it has no line when
//! it is missing), then module by module, then the groups, then the grid (whose checks are
//! [`GridSpec::build`]'s).

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

use std::path::Path;

use super::assembly::load_assembly;
use super::decl::{Declarations, ModuleDecl};
use super::fmus;
use super::record_decl;
use super::{ProgramResolver, SystemError, SystemSpec};
use modbot_grid::component::{DeclaredType, Generation};
use modbot_grid::spec::GridError;
use modbot_grid::spec::{
    Assembly, AssemblySource, ComponentDecl, ConnectDecl, GridDecl, Period, RecordDecl, Signals,
};
use modbot_grid::{GridSpec, Registry};

/// Checks `decls` (from the file `file`), finds every module's program and checks the grid
/// against the component types of `registry`.
pub(super) fn build(
    file: &str,
    text: &str,
    decls: Declarations,
    resolver: &dyn ProgramResolver,
    registry: &Registry,
    vars: &[(String, String)],
) -> Result<SystemSpec, SystemError> {
    let error = |line: u32, message: String| SystemError::new(file, Some(line), message);
    let Some((domain, _)) = decls.domain else {
        return Err(SystemError::new(
            file,
            None,
            "no domain declared: add a line such as domain \"robot\"",
        ));
    };
    if decls.grid.is_none() {
        let first = (decls.components.first().map(|c| c.line))
            .or_else(|| decls.connections.first().map(|c| c.line));
        if let Some(line) = first {
            return Err(error(
                line,
                "there is no grid for the components: declare it, as in grid { base_period = 0.001 }"
                    .into(),
            ));
        }
    }

    let mut names: HashMap<&str, u32> = HashMap::new();
    let mut addrs: HashMap<u8, (&str, u32)> = HashMap::new();
    // The modules, then the names and addresses the bridge's imports hold: one of each.
    let holders = (decls
        .modules
        .iter()
        .map(|m| (m.name.as_str(), m.addr, m.line, false)))
    .chain(
        decls
            .imported
            .iter()
            .map(|i| (i.name.as_str(), i.addr, i.line, true)),
    );
    for (name, addr, line, imported) in holders {
        if let Some(first) = names.insert(name, line) {
            let why = if imported {
                format!("the bridge's import '{name}' has the name of a module declared at line {first}")
            } else {
                format!("module name '{name}' is already declared at line {first}")
            };
            return Err(error(line, why));
        }
        if let Some((other, first)) = addrs.insert(addr, (name, line)) {
            let who = if imported {
                format!("the bridge's import '{name}': ")
            } else {
                String::new()
            };
            return Err(error(
                line,
                format!("{who}address {addr} is already used by '{other}' (line {first})"),
            ));
        }
    }
    if decls.modules.is_empty() && decls.grid.is_none() {
        return Err(SystemError::new(
            file,
            None,
            "nothing to run: declare at least one module \"name\" { addr = ..., program = ... } \
             or a grid { ... } with its components",
        ));
    }

    let mut group_lines: HashMap<&str, u32> = HashMap::new();
    for g in &decls.groups {
        if let Some(first) = group_lines.insert(&g.name, g.line) {
            return Err(error(
                g.line,
                format!("group '{}' is already declared at line {first}", g.name),
            ));
        }
        if let Some(unknown) = g.members.iter().find(|m| !names.contains_key(m.as_str())) {
            return Err(error(
                g.line,
                format!(
                    "group '{}': no module is named '{unknown}' (modules: {})",
                    g.name,
                    module_list(&decls.modules)
                ),
            ));
        }
    }

    let mut programs: Vec<PathBuf> = Vec::with_capacity(decls.modules.len());
    for m in &decls.modules {
        match resolver.resolve(&m.program) {
            Some(path) => programs.push(path),
            None => {
                return Err(error(
                    m.line,
                    format!(
                        "unknown program '{}' for module '{}': {}",
                        m.program,
                        m.name,
                        resolver.searched(&m.program)
                    ),
                ))
            }
        }
    }

    // The component types the description declares, next to the registered ones; their
    // programs are found as modules' are, once, here.
    let declared = decls.component_types;
    let mut host_programs: Vec<(String, PathBuf)> = Vec::new();
    for t in &declared {
        if host_programs.iter().any(|(n, _)| *n == t.program) {
            continue;
        }
        let Some(path) = resolver.resolve(&t.program) else {
            return Err(error(
                t.line,
                format!(
                    "unknown program '{}' for component type '{}': {}",
                    t.program,
                    t.info.type_name,
                    resolver.searched(&t.program)
                ),
            ));
        };
        host_programs.push((t.program.clone(), path));
    }
    if decls.grid.is_none() {
        if let Some(t) = declared.first() {
            let why = "component_type declares a type for the grid, and there is no grid { ... }";
            return Err(error(t.line, why.to_owned()));
        }
    }
    let registry = &fmus::with_fmus(registry)
        .with_declared(&declared)
        .map_err(|e| error(e.line, e.to_string()))?;
    let mut components = decls.components;
    fmus::find_files(
        &mut components,
        Path::new(file).parent().unwrap_or(Path::new("")),
    );
    let records = records(
        (file, text),
        decls.records,
        &components,
        decls.grid.as_ref(),
        vars,
    )?;
    let refused = |e: GridError| SystemError::caused(file, e.line, e.kind);
    let grid = match decls.grid {
        Some(grid) if grid.assemblies.is_some() => Some(with_assemblies(
            (file, text),
            &domain,
            grid,
            (components, decls.connections),
            &records,
            registry,
            vars,
            &declared,
        )?),
        Some(grid) => {
            let mut connections = decls.connections;
            let build = |components, connections| {
                GridSpec::build(grid.clone(), components, connections, registry).map_err(refused)
            };
            let mut spec = build(components.clone(), connections.clone())?;
            if !records.is_empty() {
                let decls = (&mut components, &mut connections);
                record_decl::add_recorders(&records, &spec, None, decls, refused)?;
                let mirrored = modbot_grid::spec::mirrored_connections(&components, &connections);
                connections.extend(mirrored);
                spec = build(components, connections)?;
            }
            fmus::one_per_host(&spec, 0..spec.components.len(), file)?;
            Some(spec)
        }
        None => None,
    };
    let grid = grid.map(|mut g| {
        g.declared = declared;
        g
    });
    if let Some(grid) = &grid {
        runtime_programs(file, grid, registry, resolver, &mut host_programs)?;
    }

    let groups = decls.groups;
    let modules = decls
        .modules
        .into_iter()
        .zip(programs)
        .map(|(m, program)| {
            let member_of = groups
                .iter()
                .filter(|g| g.members.contains(&m.name))
                .map(|g| g.name.clone())
                .collect();
            m.into_spec(program, member_of)
        })
        .collect();
    Ok(SystemSpec {
        file: PathBuf::from(file),
        domain,
        supervision: decls.supervision.map(|s| s.0).unwrap_or_default(),
        modules,
        groups,
        grid,
        host_template: None,
        host_programs,
        imported: decls.imported,
    })
}

/// The grid of a description with assemblies: its own components (its recorder among them)
/// and the first assembly's (which reads the assembly data of `domain`).
// The description's parts a grid with assemblies is made of, each its own argument.
#[allow(clippy::too_many_arguments)]
fn with_assemblies(
    (file, text): (&str, &str),
    domain: &str,
    grid: GridDecl,
    (mut components, mut connections): (Vec<ComponentDecl>, Vec<ConnectDecl>),
    records: &[RecordDecl],
    registry: &Registry,
    vars: &[(String, String)],
    declared: &[DeclaredType],
) -> Result<GridSpec, SystemError> {
    let Some(decl) = grid.assemblies.clone() else {
        return GridSpec::build(grid, components, connections, registry)
            .map_err(|e| SystemError::caused(file, e.line, e.kind));
    };
    let here = Path::new(file).parent().unwrap_or(Path::new(""));
    let dir = here.join(&decl.dir);
    if !dir.is_dir() {
        return Err(SystemError::new(
            file,
            Some(grid.line),
            format!(
                "grid: the assemblies directory '{}' is not found (looked at {})",
                decl.dir,
                dir.display()
            ),
        ));
    }
    let dir = std::fs::canonicalize(&dir).unwrap_or(dir);
    let line = grid.line;
    let first = |components: Vec<ComponentDecl>, connections: Vec<ConnectDecl>| {
        let unloaded = GridSpec {
            base_period: grid.base_period,
            cpus: grid.cpus.clone(),
            priority: grid.priority,
            mlock: grid.mlock,
            components: Vec::new(),
            connections: Vec::new(),
            line,
            timing: grid.timing,
            declared: declared.to_vec(),
            assembly: Some(Assembly {
                name: String::new(),
                generation: Generation::SYSTEM,
                base: components.len(),
                source: Some(Arc::new(AssemblySource {
                    dir: dir.clone(),
                    decls: (grid.clone(), components, connections),
                    vars: vars.to_vec(),
                    system_file: file.to_owned(),
                    system_text: text.to_owned(),
                    data: Some(modbot_data::path_for(domain)),
                })),
            }),
        };
        load_assembly(&unloaded, &decl.first, Generation(1), registry).map_err(|mut e| {
            if e.file.is_empty() {
                e.file = file.to_owned();
                e.line = Some(line);
            }
            e
        })
    };
    let spec = first(components.clone(), connections.clone())?;
    fmus::one_per_host(&spec, 0..components.len(), file)?;
    if records.is_empty() {
        return Ok(spec);
    }
    // The system's recorder is one of its own components: it stays when assemblies change,
    // and records only what stays too.
    let own = components.clone();
    let decls = (&mut components, &mut connections);
    let refused = |e: GridError| SystemError::caused(file, e.line, e.kind);
    record_decl::add_recorders(records, &spec, Some(&own), decls, refused)?;
    first(components, connections)
}

/// Finds the programs of the types the runtime declares (the data recorder's, an FMU's) that
/// `grid` uses — an error at the first component whose program is missing — and, with
/// assemblies, of every such type (an assembly loaded later may use it).
fn runtime_programs(
    file: &str,
    grid: &GridSpec,
    registry: &Registry,
    resolver: &dyn ProgramResolver,
    found: &mut Vec<(String, PathBuf)>,
) -> Result<(), SystemError> {
    for c in &grid.components {
        let Some(program) = c.program.as_deref() else {
            continue;
        };
        if found.iter().any(|(n, _)| n == program) {
            continue;
        }
        let Some(path) = resolver.resolve(program) else {
            return Err(SystemError::new(
                file,
                Some(c.line),
                format!(
                    "component '{}': its type '{}' is made by the program '{program}': {}",
                    c.name,
                    c.type_name,
                    resolver.searched(program)
                ),
            ));
        };
        found.push((program.to_owned(), path));
    }
    if grid.assembly.is_some() {
        for type_name in registry.type_names() {
            let Some(program) = registry.program_of(type_name) else {
                continue;
            };
            if found.iter().any(|(n, _)| n == program) {
                continue;
            }
            if let Some(path) = resolver.resolve(program) {
                found.push((program.to_owned(), path));
            }
        }
    }
    Ok(())
}

/// The description's recorders, with `modbot up --record FILE` applied ([`RECORD_VAR`]): the
/// declared one writes FILE, or, without one, FILE records every output of the system's own
/// components. A declared one without a file and without FILE runs only `on_demand`, writing
/// between a program's `record { }` and `stop_record { }` (an empty `file`).
fn records(
    (file, text): (&str, &str),
    mut records: Vec<RecordDecl>,
    components: &[ComponentDecl],
    grid: Option<&GridDecl>,
    vars: &[(String, String)],
) -> Result<Vec<RecordDecl>, SystemError> {
    let source = (record_decl::absolute(file), text.to_owned());
    for r in &mut records {
        r.sources = vec![source.clone()];
    }
    // Without a file, the system's recorder runs if it is on demand (it records when a
    // program starts a recording), else not.
    records.retain_mut(|r| match record_decl::file_of(&r.file, vars, None) {
        Some(f) => {
            r.file = f;
            true
        }
        None => r.on_demand,
    });
    let asked = record_decl::file_of("", vars, None);
    if let (Some(path), true, Some(g)) = (asked, records.is_empty(), grid) {
        records.push(RecordDecl {
            name: "record".into(),
            host: "record".into(),
            signals: Signals::AllOf(components.iter().map(|c| c.name.clone()).collect()),
            file: path,
            on_demand: false,
            period: Period::Ticks(1.0),
            units: Vec::new(),
            sources: vec![source],
            replay: None,
            line: g.line,
        });
    }
    let replayable = vars
        .iter()
        .rev()
        .find(|(k, _)| k == record_decl::REPLAY_VAR)
        .is_some_and(|(_, v)| v == "true");
    for r in &mut records {
        if replayable && r.replay.is_none() {
            r.replay = Some(Vec::new());
        }
        if r.replay.is_some() && r.period != Period::Ticks(1.0) {
            return Err(SystemError::new(
                file,
                Some(r.line),
                "a replayable recording records every tick: leave out period",
            ));
        }
    }
    match (records.first(), grid) {
        (Some(r), None) => Err(SystemError::new(
            file,
            Some(r.line),
            "there is no grid to record: declare it, as in grid { base_period = 0.001 }",
        )),
        _ => Ok(records),
    }
}

/// The declared module names, for a message.
fn module_list(modules: &[ModuleDecl]) -> String {
    let names: Vec<&str> = modules.iter().map(|m| m.name.as_str()).collect();
    names.join(", ")
}

//! The processes of a grid: one component host per host name, and the coordinator. The
//! supervisor starts them like modules — hosts first, the coordinator last, so that every
//! host listens before the first tick. None of them reads the description: each reads the
//! checked grid the supervisor wrote for its assembly generation (`--spec-generation N`, the
//! image `modbot_transport::spec_image`), so a description edited while the system runs
//! changes nothing until the next `modbot up`.

use std::path::{Path, PathBuf};

use modbot_core::transport::ReceiveMode;
use modbot_grid::component::Generation;
use modbot_system::{ModuleSpec, ProgramResolver, Restart, RestartPolicy, SystemSpec};

pub use modbot_grid::spec::{BUS_HOST, COORDINATOR};
/// The program of the coordinator.
pub const COORDINATOR_PROGRAM: &str = "modbot-coordinator";
/// The program of a component host.
pub const HOST_PROGRAM: &str = "modbot-host";
/// The program of the bus bridge.
pub const BUS_PROGRAM: &str = "modbot-bus";

/// The module name of host `host` of the system's own components, or of a grid without
/// assemblies (an assembly's hosts: [`modbot_grid::GridSpec::host_module`]).
pub fn host_module(host: &str) -> String {
    modbot_grid::spec::host_module_of(host, modbot_grid::component::Generation::SYSTEM)
}

/// The arguments that make a grid process serve the checked grid of `generation`.
pub fn spec_generation_args(generation: Generation) -> Vec<String> {
    vec![SPEC_GENERATION_ARG.to_owned(), generation.to_string()]
}

/// The program of host `host`: the bus bridge for [`BUS_HOST`], else the generic host.
pub fn host_program(host: &str) -> &'static str {
    if host == BUS_HOST {
        BUS_PROGRAM
    } else {
        HOST_PROGRAM
    }
}

/// How the grid of a run is driven.
#[derive(Debug, Clone, Default)]
pub struct GridRun {
    /// Stop after this many base ticks (then the coordinator stops the system).
    pub ticks: Option<u64>,
    /// Write every output at every tick here (with assemblies: of the system's own
    /// components).
    pub trace: Option<std::path::PathBuf>,
    /// Write the grid's state hash into the trace every this many ticks (the coordinator's
    /// default when not given).
    pub state_hash_every: Option<u64>,
    /// Write the run's schedule for a replay here (`modbot up --replayable`).
    pub replay_log: Option<std::path::PathBuf>,
    /// Run the grid in lockstep (see [`modbot_grid::GridClock::Lockstep`]).
    pub lockstep: bool,
    /// Assembly switches at given ticks: (tick, assembly).
    pub switches: Vec<(u64, String)>,
    /// Live upgrades of hosts of the running assembly at given ticks: (tick, host).
    pub upgrades: Vec<(u64, String)>,
    /// In lockstep, hold the grid before this tick until a robot program steps it (the
    /// coordinator's gate).
    pub gate: Option<u64>,
}

/// Why the grid's processes cannot be added to a system ([`add_processes`]).
#[derive(Debug, thiserror::Error)]
pub enum GridProcessError {
    #[error(
        "{}: --ticks, --trace, --state-hash-every, --lockstep, --switch, --upgrade and --gate need a grid, and the description has none",
        .file.display()
    )]
    NoGrid { file: PathBuf },
    #[error(
        "{}: --switch needs a grid with assemblies (grid {{ assemblies = ..., assembly = ... }})",
        .file.display()
    )]
    NoAssemblies { file: PathBuf },
    #[error(
        "{}: --gate holds a grid in lockstep; add --lockstep (this grid follows real time)",
        .file.display()
    )]
    GateNeedsLockstep { file: PathBuf },
    #[error(
        "{}:{line}: the grid needs the program '{program}', which is not found ({searched})",
        .file.display()
    )]
    NoProgram {
        file: PathBuf,
        line: u32,
        program: String,
        /// Where it was looked for.
        searched: String,
    },
    #[error(
        "{}:{line}: module name '{name}' is taken; the grid's host '{host}' needs it",
        .file.display()
    )]
    NameTaken {
        file: PathBuf,
        line: u32,
        name: String,
        host: String,
    },
    /// Every address is used; `what` needed one ("the coordinator").
    #[error("no address left for {what}")]
    NoAddress { what: &'static str },
}

/// The option that tells a grid process the assembly generation of the checked grid it serves.
pub const SPEC_GENERATION_ARG: &str = "--spec-generation";

/// Adds the grid's processes to `spec`'s modules, if it has a grid (`file`: the description,
/// for messages). `--lockstep` is set in the grid itself, so the checked grid carries it.
pub fn add_processes(
    spec: &mut SystemSpec,
    resolver: &dyn ProgramResolver,
    file: &Path,
    run: &GridRun,
) -> Result<(), GridProcessError> {
    if run.lockstep {
        if let Some(grid) = &mut spec.grid {
            grid.set_clock(modbot_grid::GridClock::Lockstep);
        }
    }
    let Some(grid) = spec.grid.clone() else {
        if run.ticks.is_some()
            || run.trace.is_some()
            || run.state_hash_every.is_some()
            || run.lockstep
            || !run.switches.is_empty()
            || !run.upgrades.is_empty()
            || run.gate.is_some()
        {
            let file = file.to_path_buf();
            return Err(GridProcessError::NoGrid { file });
        }
        return Ok(());
    };
    let common = spec_generation_args(grid.generation());
    if !run.switches.is_empty() && grid.assembly.is_none() {
        let file = file.to_path_buf();
        return Err(GridProcessError::NoAssemblies { file });
    }
    if run.gate.is_some() && grid.timing.clock != modbot_grid::GridClock::Lockstep {
        let file = file.to_path_buf();
        return Err(GridProcessError::GateNeedsLockstep { file });
    }
    // The bridge's imports hold their addresses too (its process opens them).
    let mut used: Vec<u8> = (spec.modules.iter().map(|m| m.addr))
        .chain(spec.imported.iter().map(|i| i.addr))
        .collect();
    let mut next_addr = || {
        let a = (1..=253u8).rev().find(|a| !used.contains(a));
        if let Some(a) = a {
            used.push(a);
        }
        a
    };
    let program = |name: &str| {
        resolver
            .resolve(name)
            .ok_or_else(|| GridProcessError::NoProgram {
                file: spec.file.clone(),
                line: grid.line,
                program: name.to_owned(),
                searched: resolver.searched(name),
            })
    };
    let policy = RestartPolicy {
        when: Restart::OnFailure,
        ..RestartPolicy::default()
    };
    // Every host's module, but for its name, address, program and host arguments.
    let template = ModuleSpec {
        name: String::new(),
        addr: 0,
        program: program(HOST_PROGRAM)?,
        program_name: HOST_PROGRAM.into(),
        args: common.clone(),
        restart: policy.clone(),
        cpus: Vec::new(),
        // A grid process puts only its serving thread under SCHED_FIFO itself
        // (`GridSpec::host_priority`); its other threads stay at normal priority.
        priority: None,
        mlock: grid.mlock,
        env: Vec::new(),
        mode: ReceiveMode::Blocking,
        groups: Vec::new(),
        line: grid.line,
    };
    let mut added = Vec::new();
    for host in grid.hosts() {
        let name = grid.host_module(&host);
        if spec.modules.iter().any(|m| m.name == name)
            || spec.imported.iter().any(|i| i.name == name)
        {
            return Err(GridProcessError::NameTaken {
                file: spec.file.clone(),
                line: grid.line,
                name,
                host,
            });
        }
        let mut args = common.clone();
        args.extend(["--host".to_owned(), host.clone()]);
        added.push(ModuleSpec {
            name,
            addr: next_addr().ok_or(GridProcessError::NoAddress {
                what: "the grid's hosts",
            })?,
            program: match grid.host_program(&host) {
                // A declared type's program, found when the description was loaded.
                Some(own) => spec
                    .host_programs
                    .iter()
                    .find(|(n, _)| n == own)
                    .map(|(_, path)| Ok(path.clone()))
                    .unwrap_or_else(|| program(own))?,
                None => program(host_program(&host))?,
            },
            program_name: grid
                .host_program(&host)
                .unwrap_or(host_program(&host))
                .into(),
            args,
            ..template.clone()
        });
    }
    let mut args = common;
    if let Some(n) = run.ticks {
        args.extend(["--ticks".to_owned(), n.to_string()]);
    }
    if let Some(t) = &run.trace {
        let t = std::path::absolute(t).unwrap_or_else(|_| t.clone());
        args.extend(["--trace".to_owned(), t.display().to_string()]);
    }
    if let Some(log) = &run.replay_log {
        let log = std::path::absolute(log).unwrap_or_else(|_| log.clone());
        args.extend(["--replay-log".to_owned(), log.display().to_string()]);
    }
    if let Some(every) = run.state_hash_every {
        args.extend(["--state-hash-every".to_owned(), every.to_string()]);
    }
    for (tick, name) in &run.switches {
        args.extend(["--switch".to_owned(), format!("{tick}:{name}")]);
    }
    for (tick, host) in &run.upgrades {
        args.extend(["--upgrade".to_owned(), format!("{tick}:{host}")]);
    }
    if let Some(tick) = run.gate {
        args.extend(["--gate".to_owned(), tick.to_string()]);
    }
    added.push(ModuleSpec {
        name: COORDINATOR.into(),
        addr: next_addr().ok_or(GridProcessError::NoAddress {
            what: "the coordinator",
        })?,
        program: program(COORDINATOR_PROGRAM)?,
        program_name: COORDINATOR_PROGRAM.into(),
        args,
        restart: RestartPolicy {
            when: Restart::Never,
            ..RestartPolicy::default()
        },
        cpus: grid.cpus.clone(),
        // The coordinator puts its tick thread under SCHED_FIFO itself, and nothing else.
        ..template.clone()
    });
    if grid.assembly.is_some() {
        // The hosts of assemblies swapped in later: the supervisor adds the host, the
        // assembly and its generation.
        spec.host_template = Some(template);
    }
    spec.modules.extend(added);
    Ok(())
}

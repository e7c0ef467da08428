//! The checked grid description: components on hosts, their periods and parameters, and the
//! connections between their ports.
//!
//! [`GridSpec::build`] turns declarations ([`GridDecl`], [`ComponentDecl`], [`ConnectDecl`], as
//! the system description's `grid`, `component` and `connect` say them) into a [`GridSpec`],
//! with every check that needs the component types: known type, parameters, ports, exact port
//! types, every input connected exactly once, at most [`MAX_SOURCES`] source components per
//! component, periods that are whole multiples of the base tick. Errors carry the line of the
//! offending declaration and what is wrong with it ([`GridError`], in `error`).

use std::collections::HashMap;
use std::time::Duration;

use modbot_ipc_schema::grid::MAX_SOURCES;
pub use modbot_ipc_schema::grid::{GridClock, OverrunPolicy};

use super::component::{
    ComponentInfo, DeclaredType, Generation, Params, PortDecl, PortType, Registry, AUTOMATIC_PARAMS,
};
use modbot_core::transport::check_name;

mod error;
mod image;
mod record;
pub use error::{GridError, GridErrorKind, HostNameError, HostPrograms, PeriodError};
pub use record::{expand as expand_record, mirrored_connections, RecordDecl, Signals, BUS_TYPE};

/// The most components a grid may have (indices are 16 bits on the wire).
pub const MAX_COMPONENTS: usize = 65535;
/// The longest period, in base ticks.
pub const MAX_PERIOD_TICKS: u64 = u32::MAX as u64;

/// A checked grid.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSpec {
    /// The base tick T: every period is a whole multiple of it.
    pub base_period: Duration,
    /// The coordinator's CPU affinity (empty: anywhere).
    pub cpus: Vec<usize>,
    /// The coordinator's SCHED_FIFO priority (none: the normal scheduler).
    pub priority: Option<u8>,
    /// Lock the coordinator's memory.
    pub mlock: bool,
    /// The components, in declaration order: their indices are the wire's component indices.
    pub components: Vec<ComponentSpec>,
    /// The connections, in declaration order.
    pub connections: Vec<Connection>,
    /// The line of the `grid` declaration.
    pub line: u32,
    /// Where the ticks come from, and how the coordinator waits for its hosts.
    pub timing: GridTiming,
    /// When the grid runs assemblies: which one this spec holds, and how to load others.
    pub assembly: Option<Assembly>,
    /// The component types the description declares (`component_type`), made by host
    /// programs of their own: every process that loads this grid or its assemblies knows
    /// them (see [`Registry::with_declared`]).
    pub declared: Vec<DeclaredType>,
}

/// How the grid keeps time: `grid { clock = ..., track_ticks = ..., spin_us = ... }`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GridTiming {
    pub clock: GridClock,
    /// An incoming assembly runs alongside (tracking) for at least this many ticks before it
    /// takes over; its overruns in that time are counted but do not fail the switch (a fresh
    /// process is slow at first: cold caches, first page touches).
    pub track_ticks: u64,
    /// How long the coordinator may spin at a tick for a due component's done notice before it
    /// sleeps on the done wake-up (0: never spin; only worth it on a core of its own).
    pub spin_us: u64,
}

/// Ticks an incoming assembly tracks by default before it takes over.
pub const DEFAULT_TRACK_TICKS: u64 = 50;

impl Default for GridTiming {
    fn default() -> Self {
        GridTiming {
            clock: GridClock::RealTime,
            track_ticks: DEFAULT_TRACK_TICKS,
            spin_us: 0,
        }
    }
}

/// The assembly a [`GridSpec`] holds: its components follow the system's own (the bus), which
/// stay when the assembly is swapped. Loaded by `modbot_system::load_assembly`.
#[derive(Debug, Clone, PartialEq)]
pub struct Assembly {
    /// Its name: the file `<dir>/<name>.lua`.
    pub name: String,
    /// Counts the assemblies loaded in a run, from 1: it names the assembly's services and
    /// host processes, so an assembly being prepared never meets the one running.
    pub generation: Generation,
    /// The number of the system's own components: indices below it are the system's.
    pub base: usize,
    /// Where it was loaded from, to load other assemblies against (`None` in a grid process,
    /// whose spec came checked from the supervisor: only the supervisor loads assemblies).
    pub source: Option<std::sync::Arc<AssemblySource>>,
}

/// What loading another assembly against a system's grid needs: the loader's context, kept
/// by the process that reads descriptions (the supervisor, `modbot check`).
#[derive(Debug, Clone, PartialEq)]
pub struct AssemblySource {
    /// Where the assembly files are.
    pub dir: std::path::PathBuf,
    /// The system's grid declarations, to combine with another assembly's.
    pub decls: (GridDecl, Vec<ComponentDecl>, Vec<ConnectDecl>),
    /// The description's variables (assembly files see them as `vars` too).
    pub vars: Vec<(String, String)>,
    /// The system description's file, for messages.
    pub system_file: String,
    /// Its text as the system was loaded from it (what an assembly's recorder keeps).
    pub system_text: String,
    /// The domain's assembly data (`modbot-data`), which assembly files read with `data(key)`
    /// (`None`: they read nothing).
    pub data: Option<std::path::PathBuf>,
}

/// The `assemblies = "dir", assembly = "first"` fields of `grid { ... }`.
#[derive(Debug, Clone, PartialEq)]
pub struct AssembliesDecl {
    /// The directory of the assembly files, relative to the description's.
    pub dir: String,
    /// The assembly the system starts with.
    pub first: String,
}

/// One component of the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentSpec {
    /// Its name: unique, a transport name (it names the output service `grid.out.<name>`).
    pub name: String,
    /// Its type in the [`Registry`].
    pub type_name: String,
    /// The host program that makes its type, if a description declared the type
    /// (`component_type`); `None`: a type every host program makes (the built-ins).
    pub program: Option<String>,
    /// The host process that steps it.
    pub host: String,
    /// Its period in base ticks (≥ 1): released at every tick that is a multiple of it.
    pub period: u64,
    /// The complete parameters, including the automatic `base_period_s` and `period_s`.
    pub params: Params,
    /// What happens when it misses a deadline.
    pub policy: OverrunPolicy,
    /// Its ports with these parameters.
    pub info: ComponentInfo,
    /// The line of its `component` declaration.
    pub line: u32,
}

/// An output feeding an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Connection {
    /// A component's output.
    pub from: PortRef,
    /// A component's input.
    pub to: PortRef,
    /// The line of the `connect` declaration.
    pub line: u32,
}

/// A port: a component index and an output or input index (which, the context says).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PortRef {
    pub component: usize,
    pub port: usize,
}

/// The `grid { ... }` declaration, read.
#[derive(Debug, Clone, PartialEq)]
pub struct GridDecl {
    pub base_period: Duration,
    pub cpus: Vec<usize>,
    pub priority: Option<u8>,
    pub mlock: bool,
    pub line: u32,
    pub timing: GridTiming,
    /// The grid runs swappable assemblies, starting with this one.
    pub assemblies: Option<AssembliesDecl>,
}

/// A component's period as written.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Period {
    /// `period = k`: base ticks.
    Ticks(f64),
    /// `period_s = x`: seconds.
    Seconds(f64),
}

/// A `component "name" { ... }` declaration, read but not checked against its type.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentDecl {
    pub name: String,
    pub type_name: String,
    pub host: String,
    pub period: Period,
    /// The parameters as written (without the automatic ones).
    pub params: Params,
    pub policy: OverrunPolicy,
    pub line: u32,
}

/// A `connect "A.y -> B.u"` declaration: (component, port) on each side.
#[derive(Debug, Clone, PartialEq)]
pub struct ConnectDecl {
    pub from: (String, String),
    pub to: (String, String),
    pub line: u32,
}

fn at(line: u32, kind: GridErrorKind) -> GridError {
    GridError {
        line: Some(line),
        kind,
    }
}

/// The coordinator's module name.
pub const COORDINATOR: &str = "coordinator";

/// The host whose components the bus bridge process steps: it owns the drives.
pub const BUS_HOST: &str = "bus";

/// The module name of the process of `host` of assembly generation `generation` (0: a host of
/// the system's own components, or of a grid without assemblies).
pub fn host_module_of(host: &str, generation: Generation) -> String {
    match generation.0 {
        0 => format!("host_{host}"),
        g => format!("host_{host}_g{g}"),
    }
}

/// What a grid process is, read from its module name (the inverse of [`host_module_of`] and
/// [`COORDINATOR`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridRole<'a> {
    Coordinator,
    /// The host process of `host`, of assembly generation `generation` (0: of the system's
    /// own components, or of a grid without assemblies).
    Host {
        host: &'a str,
        generation: Generation,
    },
}

impl GridRole<'_> {
    /// The role of the process named `module`; `None` for a module that is no grid process.
    pub fn of(module: &str) -> Option<GridRole<'_>> {
        if module == COORDINATOR {
            return Some(GridRole::Coordinator);
        }
        let name = module.strip_prefix("host_")?;
        let (host, generation) = match generation_suffix(name) {
            Some((host, g)) => (host, g),
            None => (name, 0),
        };
        check_host(host).ok()?;
        Some(GridRole::Host {
            host,
            generation: Generation(generation),
        })
    }
}

/// `NAME_gN` → (NAME, N) for N ≥ 1.
fn generation_suffix(name: &str) -> Option<(&str, u16)> {
    let (host, g) = name.rsplit_once("_g")?;
    let generation: u16 = g.parse().ok().filter(|&g| g > 0)?;
    (g == generation.to_string()).then_some((host, generation))
}

/// A host name: 1 to 32 characters of `a-z`, `0-9` and `_` (it names a process), not ending
/// in `_g` and a number (that names an assembly's generation: see [`GridRole`]).
pub fn check_host(host: &str) -> Result<(), HostNameError> {
    if is_plain_name(host) && generation_suffix(host).is_none() {
        Ok(())
    } else {
        Err(HostNameError { host: host.into() })
    }
}

/// 1 to 32 characters of `a-z`, `0-9` and `_`: a name that is also a file or process name.
pub fn is_plain_name(name: &str) -> bool {
    (1..=32).contains(&name.len())
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
}

/// The period in base ticks, or why it is not a whole multiple of the base tick.
fn ticks(period: Period, base: Duration) -> Result<u64, PeriodError> {
    let base_s = base.as_secs_f64();
    let ratio = match period {
        Period::Ticks(k) => k,
        Period::Seconds(s) => s / base_s,
    };
    if !ratio.is_finite() || ratio <= 0.0 {
        return Err(PeriodError::NotPositive { period, base_s });
    }
    let k = ratio.round();
    if (ratio - k).abs() > 1e-9 * k.max(1.0) || k < 1.0 {
        return Err(PeriodError::NotMultiple { period, base_s });
    }
    if k > MAX_PERIOD_TICKS as f64 {
        return Err(PeriodError::TooLong { period, base_s });
    }
    Ok(k as u64)
}

/// One component, checked against its type.
fn component(
    d: ComponentDecl,
    base: Duration,
    registry: &Registry,
) -> Result<ComponentSpec, GridError> {
    let component = || d.name.clone();
    if check_name(&d.name).is_err() {
        let component = component();
        return Err(at(d.line, GridErrorKind::ComponentName { component }));
    }
    check_host(&d.host).map_err(|error| {
        let component = component();
        at(d.line, GridErrorKind::Host { component, error })
    })?;
    let period = ticks(d.period, base).map_err(|error| {
        let component = component();
        at(d.line, GridErrorKind::Period { component, error })
    })?;
    if let Some(&param) = AUTOMATIC_PARAMS.iter().find(|n| d.params.get(n).is_some()) {
        let component = component();
        return Err(at(
            d.line,
            GridErrorKind::AutomaticParam { component, param },
        ));
    }
    let refused = |error| {
        let component = component();
        at(d.line, GridErrorKind::Component { component, error })
    };
    let mut params = d.params;
    params.set_timing(base.as_secs_f64(), period);
    let params = registry.complete(&d.type_name, &params).map_err(refused)?;
    let info = registry.info(&d.type_name, &params).map_err(refused)?;
    let program = registry.program_of(&d.type_name).map(str::to_owned);
    Ok(ComponentSpec {
        name: d.name,
        program,
        type_name: d.type_name,
        host: d.host,
        period,
        params,
        policy: d.policy,
        info,
        line: d.line,
    })
}

/// One connection, checked: both components and ports exist, and the types are equal.
fn connect(
    c: &ConnectDecl,
    specs: &[ComponentSpec],
    names: &HashMap<String, usize>,
) -> Result<Connection, GridError> {
    let find = |name: &str| {
        names.get(name).copied().ok_or_else(|| {
            let known: Vec<String> = specs.iter().map(|s| s.name.clone()).take(20).collect();
            let more = specs.len() > known.len();
            let kind = GridErrorKind::NoComponent {
                connect: format!("{}.{} -> {}.{}", c.from.0, c.from.1, c.to.0, c.to.1),
                name: name.to_owned(),
                known,
                more,
            };
            at(c.line, kind)
        })
    };
    let (from_c, to_c) = (find(&c.from.0)?, find(&c.to.0)?);
    let (src, dst) = (&specs[from_c].info, &specs[to_c].info);
    let no_port = |side, (component, port): &(String, String), ports: &[PortDecl]| {
        let kind = GridErrorKind::NoPort {
            component: component.clone(),
            side,
            port: port.clone(),
            ports: ports.iter().map(|p| p.name).collect(),
        };
        at(c.line, kind)
    };
    let from_p = src
        .output(&c.from.1)
        .ok_or_else(|| no_port("output", &c.from, &src.outputs))?;
    let to_p = dst
        .input(&c.to.1)
        .ok_or_else(|| no_port("input", &c.to, &dst.inputs))?;
    let (from_ty, to_ty) = (src.outputs[from_p].ty, dst.inputs[to_p].ty);
    if from_ty != to_ty {
        let kind = GridErrorKind::TypeMismatch {
            from: format!("{}.{}", c.from.0, c.from.1),
            from_ty,
            to: format!("{}.{}", c.to.0, c.to.1),
            to_ty,
        };
        return Err(at(c.line, kind));
    }
    Ok(Connection {
        from: PortRef {
            component: from_c,
            port: from_p,
        },
        to: PortRef {
            component: to_c,
            port: to_p,
        },
        line: c.line,
    })
}

impl GridSpec {
    /// The SCHED_FIFO priority of the hosts' serving threads: just below the coordinator's
    /// tick thread, which must preempt them.
    pub fn host_priority(&self) -> Option<u8> {
        self.priority.map(|p| p.saturating_sub(1).max(1))
    }

    /// Sets the clock (`modbot up --lockstep` over the description's), and tells the recorders
    /// whether they may take their time (see [`crate::record_type`]'s `lossless`).
    pub fn set_clock(&mut self, clock: GridClock) {
        self.timing.clock = clock;
        let lossless = super::component::ParamValue::Bool(clock == GridClock::Lockstep);
        for c in &mut self.components {
            if c.type_name == crate::record_type::TYPE {
                c.params.set(crate::record_type::LOSSLESS, lossless.clone());
            }
        }
    }

    /// Checks the declarations against the component types of `registry`. Takes time linear
    /// in the size of the description. (A data recorder, `record { ... }`, is added to
    /// declarations checked without it: see [`expand_record`].)
    pub fn build(
        grid: GridDecl,
        components: Vec<ComponentDecl>,
        connections: Vec<ConnectDecl>,
        registry: &Registry,
    ) -> Result<GridSpec, GridError> {
        if grid.base_period.is_zero() {
            return Err(at(grid.line, GridErrorKind::BasePeriod));
        }
        if components.is_empty() {
            return Err(at(grid.line, GridErrorKind::NoComponents));
        }
        let mut specs: Vec<ComponentSpec> = Vec::with_capacity(components.len());
        let mut names: HashMap<String, usize> = HashMap::with_capacity(components.len());
        for d in components {
            if specs.len() >= MAX_COMPONENTS {
                return Err(at(d.line, GridErrorKind::TooManyComponents));
            }
            if let Some(&first) = names.get(&d.name) {
                let first = specs[first].line;
                let name = d.name.clone();
                return Err(at(
                    d.line,
                    GridErrorKind::DuplicateComponent { name, first },
                ));
            }
            names.insert(d.name.clone(), specs.len());
            specs.push(component(d, grid.base_period, registry)?);
        }
        // One host, one program: the types of a host's components are made by one program.
        for (i, c) in specs.iter().enumerate() {
            let Some(program) = c.program.as_deref() else {
                continue;
            };
            let other = specs[..i]
                .iter()
                .find(|o| o.host == c.host && o.program.as_deref().is_some_and(|p| p != program));
            if let Some(o) = other {
                return Err(at(
                    c.line,
                    GridErrorKind::HostPrograms(Box::new(HostPrograms {
                        host: c.host.clone(),
                        first: (o.name.clone(), o.program.clone().unwrap_or_default()),
                        second: (c.name.clone(), program.to_owned()),
                    })),
                ));
            }
        }
        // For every input, the connection feeding it.
        let mut feeding: HashMap<PortRef, usize> = HashMap::with_capacity(connections.len());
        let mut checked: Vec<Connection> = Vec::with_capacity(connections.len());
        for c in &connections {
            let connection = connect(c, &specs, &names)?;
            if let Some(&first) = feeding.get(&connection.to) {
                let first = &checked[first];
                let source = &specs[first.from.component];
                let kind = GridErrorKind::AlreadyConnected {
                    input: format!("{}.{}", c.to.0, c.to.1),
                    from: format!(
                        "{}.{}",
                        source.name, source.info.outputs[first.from.port].name
                    ),
                    first: first.line,
                };
                return Err(at(c.line, kind));
            }
            feeding.insert(connection.to, checked.len());
            checked.push(connection);
        }
        for (index, c) in specs.iter().enumerate() {
            let mut sources = Vec::with_capacity(c.info.inputs.len());
            for (i, input) in c.info.inputs.iter().enumerate() {
                let to = PortRef {
                    component: index,
                    port: i,
                };
                let Some(&k) = feeding.get(&to) else {
                    let kind = GridErrorKind::Unconnected {
                        component: c.name.clone(),
                        input: input.name,
                    };
                    return Err(at(c.line, kind));
                };
                sources.push(checked[k].from.component);
            }
            sources.sort_unstable();
            sources.dedup();
            if sources.len() > MAX_SOURCES {
                let kind = GridErrorKind::TooManySources {
                    component: c.name.clone(),
                    sources: sources.len(),
                };
                return Err(at(c.line, kind));
            }
        }
        Ok(GridSpec {
            base_period: grid.base_period,
            cpus: grid.cpus,
            priority: grid.priority,
            mlock: grid.mlock,
            components: specs,
            connections: checked,
            line: grid.line,
            timing: grid.timing,
            assembly: None,
            declared: Vec::new(),
        })
    }

    /// The assembly generation component `c` belongs to: 0 for the system's own components
    /// and for every component of a grid without assemblies.
    pub fn generation_of(&self, c: usize) -> Generation {
        match &self.assembly {
            Some(a) if c >= a.base => a.generation,
            _ => Generation::SYSTEM,
        }
    }

    /// The generation of this spec's assembly (0: none).
    pub fn generation(&self) -> Generation {
        self.assembly
            .as_ref()
            .map_or(Generation::SYSTEM, |a| a.generation)
    }

    /// The generation of the components on `host` (0: the system's own host).
    pub fn host_generation(&self, host: &str) -> Generation {
        (0..self.components.len())
            .find(|&c| self.components[c].host == host)
            .map_or(Generation::SYSTEM, |c| self.generation_of(c))
    }

    /// The hosts of the system's own components (all hosts of a grid without assemblies).
    pub fn base_hosts(&self) -> Vec<String> {
        self.hosts()
            .into_iter()
            .filter(|h| self.host_generation(h) == Generation::SYSTEM)
            .collect()
    }

    /// The hosts of the assembly's components.
    pub fn assembly_hosts(&self) -> Vec<String> {
        self.hosts()
            .into_iter()
            .filter(|h| self.host_generation(h) != Generation::SYSTEM)
            .collect()
    }

    /// The channel of component `c`'s outputs.
    pub fn out_service(&self, c: usize) -> String {
        let name = &self.components[c].name;
        match self.generation_of(c).0 {
            0 => format!("grid.out.{name}"),
            g => format!("grid.out.g{g}.{name}"),
        }
    }

    /// The channel of `host`'s release notices.
    pub fn release_service(&self, host: &str) -> String {
        match self.host_generation(host).0 {
            0 => format!("grid.release.{host}"),
            g => format!("grid.release.g{g}.{host}"),
        }
    }

    /// The channel on which a process of `host` hands its components' state to a new process
    /// of the host (a live upgrade); the new one answers on the channel of this name with
    /// `.verdict` after it.
    pub fn handover_service(&self, host: &str) -> String {
        match self.host_generation(host).0 {
            0 => format!("grid.handover.{host}"),
            g => format!("grid.handover.g{g}.{host}"),
        }
    }

    /// The wake-up of `host`.
    pub fn wake_service(&self, host: &str) -> String {
        match self.host_generation(host).0 {
            0 => format!("grid.wake.{host}"),
            g => format!("grid.wake.g{g}.{host}"),
        }
    }

    /// The module name of `host`'s process.
    pub fn host_module(&self, host: &str) -> String {
        host_module_of(host, self.host_generation(host))
    }

    /// The longest period of the assembly's components, in base ticks (1 without them).
    pub fn assembly_max_period(&self) -> u64 {
        (0..self.components.len())
            .filter(|&c| self.generation_of(c) != Generation::SYSTEM)
            .map(|c| self.components[c].period)
            .max()
            .unwrap_or(1)
    }

    /// The host processes, distinct, in order of first use.
    pub fn hosts(&self) -> Vec<String> {
        let mut hosts: Vec<String> = Vec::new();
        for c in &self.components {
            if !hosts.contains(&c.host) {
                hosts.push(c.host.clone());
            }
        }
        hosts
    }

    /// The program that must run `host`: the one that makes its components' declared types
    /// (`None`: the built-in host program will do).
    pub fn host_program(&self, host: &str) -> Option<&str> {
        self.components
            .iter()
            .filter(|c| c.host == host)
            .find_map(|c| c.program.as_deref())
    }

    /// The components `host` steps, in index order.
    pub fn components_of(&self, host: &str) -> Vec<usize> {
        (0..self.components.len())
            .filter(|&c| self.components[c].host == host)
            .collect()
    }

    /// The index of the component named `name`.
    pub fn component(&self, name: &str) -> Option<usize> {
        self.components.iter().position(|c| c.name == name)
    }

    /// The output feeding input `i` of component `c`, if it is connected.
    pub fn source_of(&self, c: usize, i: usize) -> Option<PortRef> {
        let to = PortRef {
            component: c,
            port: i,
        };
        self.connections.iter().find(|k| k.to == to).map(|k| k.from)
    }

    /// The distinct components feeding `c`'s inputs, sorted by index: the "sources" of a
    /// release notice, whose versions come in this order.
    pub fn sources(&self, c: usize) -> Vec<usize> {
        let mut sources: Vec<usize> = self
            .connections
            .iter()
            .filter(|k| k.to.component == c)
            .map(|k| k.from.component)
            .collect();
        sources.sort_unstable();
        sources.dedup();
        sources
    }

    /// For input `i` of component `c`: (the position of its source in [`sources`](Self::sources)
    /// of `c`, the output port index in that source).
    ///
    /// # Panics
    /// If the input is not connected (never in a spec from [`build`](Self::build)).
    pub fn input_binding(&self, c: usize, i: usize) -> (usize, usize) {
        let Some(from) = self.source_of(c, i) else {
            panic!("input {i} of component {c} is not connected");
        };
        let sources = self.sources(c);
        let position = sources.iter().position(|&s| s == from.component);
        (position.unwrap_or(usize::MAX), from.port)
    }

    /// The types of `c`'s outputs, in port order (the layout of its output record).
    pub fn output_types(&self, c: usize) -> Vec<PortType> {
        self.components[c].info.output_types()
    }
}

#[cfg(test)]
mod tests {
    use super::{host_module_of, Generation, GridError, GridErrorKind, GridRole, COORDINATOR};

    #[test]
    fn a_grid_process_is_told_by_its_module_name_and_nothing_else_is_one() {
        for (host, g) in [("ctrl", 0), ("ctrl", 7), ("bus", 0), ("a_g", 2), ("g2", 0)] {
            let generation = Generation(g);
            let name = host_module_of(host, generation);
            assert_eq!(
                GridRole::of(&name),
                Some(GridRole::Host { host, generation }),
                "{name}"
            );
        }
        assert_eq!(GridRole::of(COORDINATOR), Some(GridRole::Coordinator));
        for other in [
            "sonar",
            "host_",
            "host_Ctl",
            "host_a.b",
            "hosts_a",
            "coordinator2",
        ] {
            assert_eq!(GridRole::of(other), None, "{other}");
        }
    }

    #[test]
    fn a_grid_error_says_its_line() {
        let e = GridError {
            line: Some(3),
            kind: GridErrorKind::BasePeriod,
        };
        assert_eq!(e.to_string(), "line 3: grid: base_period must be positive");
        let e: Box<dyn std::error::Error> = Box::new(GridError {
            line: None,
            kind: GridErrorKind::TooManyComponents,
        });
        assert_eq!(e.to_string(), "too many components (at most 65535)");
        assert_eq!(
            e.source().map(|s| s.to_string()).as_deref(),
            Some("too many components (at most 65535)")
        );
    }
}

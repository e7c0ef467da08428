//! The system description: which module processes make up a robot, read from a Lua file.
//!
//! A robot is a set of module processes. Its *system description* is a small Lua program that
//! declares the domain, the supervision timings, the modules (program, address, restart policy,
//! real-time settings) and the multicast groups. [`load`] evaluates it in a sandbox and turns it
//! into a checked [`SystemSpec`], which the supervisor (`modbot up`) starts and `modbot check`
//! prints. Every error names the file and the line ([`SystemError`]).
//!
//! A description can take variables from the command line (`modbot up FILE --var speed=2`),
//! as strings in the read-only table `vars` ([`load_with_vars`]):
//!
//! ```lua
//! local speed = tonumber(vars.speed or "1")
//! module "plant" { addr = 4, program = "modbot-plant", env = { MODBOT_SIM_SPEED = tostring(speed) } }
//! ```
//!
//! ```lua
//! domain "mra_demo"
//! supervision { heartbeat_timeout = 1.0 }
//! module "sonar" { addr = 2, program = "modbot-sonar", args = { "--obstacle", "3,0" } }
//! module "mobility" { addr = 3, program = "modbot-mobility", restart = "always" }
//! group "sensors" { "sonar" }
//! ```
//!
//! A description may also declare a time grid: components on host processes, their periods
//! and the connections between their ports (see [`modbot_grid`]; the grid alone, without
//! modules, is a valid system):
//!
//! ```lua
//! grid { base_period = 0.001, cpus = { 0 }, priority = 80, mlock = true }
//! component "A" { type = "counter", host = "h1", period = 1, params = { start = 0 } }
//! component "B" { type = "gain", host = "h2", period = 2, params = { k = 0.5 }, policy = "fault" }
//! connect "A.y -> B.u"
//! ```
//!
//! # Layout
//! - this file: the checked description ([`SystemSpec`] and its parts), the entry points [`load`], [`load_str`], [`load_with_vars`], [`load_str_with_vars`] and, with
//!   a [`Registry`] of component types, [`load_with_registry`] and [`load_str_with_registry`];
//!   [`parse_var`] for `--var KEY=VALUE`.
//! - `error`: [`SystemError`] (`file:line: message`, with its cause), [`DeclError`] (what is
//!   wrong with one declaration's values) and [`VarError`] (a bad `--var`).
//! - [`sandbox`]: the Lua sandbox of every modbot Lua file (descriptions, assemblies, robot
//!   programs): libraries, memory and instruction limits, guarded protected calls, `file:line`
//!   out of Lua's errors, values between Lua and modbot.
//! - `lua`: the evaluation of a description in the sandbox: the declaration functions
//!   (`domain`, `supervision`, `module`, `group`), `vars`, and Lua errors as [`SystemError`].
//! - `data_fn`: `data(key)` in assembly files, read from the domain's assembly data
//!   (`modbot-data`).
//! - `grid_decl`: the grid's declaration functions (`grid`, `component`, `connect`) and what
//!   each one says; the checks against the component types are [`GridSpec::build`]'s.
//! - `fmus`: FMU components — the type `fmu`, where their files are found, one host each.
//! - `record_decl`: the data recorder's declaration (`record { signals = ..., file = ... }`)
//!   and `modbot up --record FILE` ([`RECORD_VAR`]).
//! - `decl`: what one declaration says, read field by field from its Lua table, with the
//!   checks that need nothing but that table (ranges, policies, unknown fields).
//! - `read`: typed values out of Lua values (strings, integers, seconds, lists, field tables),
//!   each refusal a [`DeclError`] that shows the value.
//! - `validate`: the checks across declarations (duplicates, group members, timings), the
//!   program lookup and the grid's checks, which produce the [`SystemSpec`].
//! - [`program`]: how a program name becomes an executable path ([`DefaultResolver`]).

pub mod assembly;
mod bridge_decl;
mod data_fn;
mod decl;
mod error;
mod fmus;
pub mod fuzz;
mod grid_decl;
mod lua;
pub mod program;
mod read;
mod record;
mod record_decl;
pub mod sandbox;
mod validate;

#[cfg(test)]
mod bridge_tests;
#[cfg(test)]
mod control_tests;
#[cfg(test)]
mod fmu_tests;
#[cfg(test)]
mod grid_tests;
#[cfg(test)]
mod image_tests;
#[cfg(test)]
mod in_process_tests;
#[cfg(test)]
mod let_tests;
#[cfg(test)]
mod record_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod trace_tests;

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

use modbot_core::transport::ReceiveMode;
use modbot_grid::{GridSpec, Registry};

pub use assembly::{assembly_names, load_assembly};
pub use error::{DeclError, SystemError, VarError};
pub use program::{DefaultResolver, ProgramResolver};
pub use record_decl::{RECORD_VAR, REPLAY_VAR};

/// A checked system description: everything the supervisor needs to start the robot.
#[derive(Debug, Clone, PartialEq)]
pub struct SystemSpec {
    /// The description file, as it was named to [`load`]: messages about the system cite it.
    pub file: PathBuf,
    /// The system's domain (the shared-memory namespace of all its modules).
    pub domain: String,
    /// How the supervisor watches the modules.
    pub supervision: Supervision,
    /// The modules in declaration order, which is the start order (stopping is in reverse).
    pub modules: Vec<ModuleSpec>,
    /// The multicast groups, in declaration order.
    pub groups: Vec<GroupSpec>,
    /// The time grid, if the description declares one.
    pub grid: Option<GridSpec>,
    /// How to start a host of an assembly at runtime (set by
    /// `modbot_supervisor::processes::add_processes` when the grid has assemblies): the host's
    /// module with the arguments every host gets; the supervisor adds the rest.
    pub host_template: Option<ModuleSpec>,
    /// The host programs of the component types the description declares
    /// (`component_type`), found when the description is loaded: (name, path).
    pub host_programs: Vec<(String, PathBuf)>,
    /// The names and addresses the bridge's imports hold in the domain (`bridge { imports }`):
    /// the bridge's process opens them; nothing else may take them.
    pub imported: Vec<ImportedName>,
}

/// A name and an address a bridge's import holds in the domain.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ImportedName {
    pub name: String,
    pub addr: u8,
    /// The `bridge` declaration's line.
    pub line: u32,
}

/// The supervisor's timings.
#[derive(Debug, Clone, PartialEq)]
pub struct Supervision {
    /// Every module must announce itself within this after it was spawned.
    pub start_timeout: Duration,
    /// A module silent this long is hung: it is killed and restarted.
    pub heartbeat_timeout: Duration,
    /// How often modules send their heartbeat; less than half of `heartbeat_timeout`, so one
    /// lost heartbeat does not make a module look hung.
    pub heartbeat_period: Duration,
    /// Between SIGTERM and SIGKILL when a module is stopped.
    pub stop_grace: Duration,
}

impl Default for Supervision {
    fn default() -> Self {
        Supervision {
            start_timeout: Duration::from_secs(10),
            heartbeat_timeout: Duration::from_secs(1),
            heartbeat_period: Duration::from_millis(100),
            stop_grace: Duration::from_secs(2),
        }
    }
}

/// One module process of the system.
#[derive(Debug, Clone, PartialEq)]
pub struct ModuleSpec {
    /// The module's name in the phone book (checked like [`modbot_core::transport::check_name`]).
    pub name: String,
    /// The module's address, 1..=254, unique in the system.
    pub addr: u8,
    /// The executable to spawn, as found by the [`ProgramResolver`].
    pub program: PathBuf,
    /// The program as the description wrote it, for messages.
    pub program_name: String,
    /// The command-line arguments after the program.
    pub args: Vec<String>,
    /// What happens when the process ends or hangs.
    pub restart: RestartPolicy,
    /// CPU affinity: the process may run only on these CPUs (empty: anywhere).
    pub cpus: Vec<usize>,
    /// SCHED_FIFO priority 1..=99 (none: the normal scheduler).
    pub priority: Option<u8>,
    /// Lock the process's memory (mlockall), so page faults do not add latency.
    pub mlock: bool,
    /// Extra environment variables, sorted by name.
    pub env: Vec<(String, String)>,
    /// How the module waits for frames.
    pub mode: ReceiveMode,
    /// The groups this module is a member of, in group declaration order.
    pub groups: Vec<String>,
    /// The line of the `module` declaration, for messages about this module.
    pub line: u32,
}

/// When a module is restarted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Restart {
    /// Never: an ended module stays down.
    Never,
    /// When it exits with a failure status, dies by a signal or hangs; a clean exit is final.
    OnFailure,
    /// Whenever it ends, even cleanly.
    Always,
}

impl Restart {
    /// The name used in descriptions: `never`, `on-failure` or `always`.
    pub fn name(self) -> &'static str {
        match self {
            Restart::Never => "never",
            Restart::OnFailure => "on-failure",
            Restart::Always => "always",
        }
    }

    /// The policy named `name` in a description.
    pub fn from_name(name: &str) -> Option<Restart> {
        match name {
            "never" => Some(Restart::Never),
            "on-failure" => Some(Restart::OnFailure),
            "always" => Some(Restart::Always),
            _ => None,
        }
    }
}

impl fmt::Display for Restart {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A module's restart policy.
#[derive(Debug, Clone, PartialEq)]
pub struct RestartPolicy {
    /// When to restart.
    pub when: Restart,
    /// At most this many restarts within `window`; one more and the module is given up.
    pub max_restarts: u32,
    /// The sliding window over which restarts are counted.
    pub window: Duration,
    /// The delay before the first restart; it doubles with each further one.
    pub backoff: Duration,
    /// The longest delay between restarts.
    pub max_backoff: Duration,
    /// What happens to the rest of the system when this module is given up.
    pub give_up: GiveUp,
}

/// What the supervisor does when a module used up its restarts (or cannot be restarted).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GiveUp {
    /// The module stays down; the other modules keep running.
    #[default]
    KeepOthers,
    /// The whole system is stopped: the robot cannot work without this module.
    StopSystem,
}

impl GiveUp {
    /// The name used in descriptions: `keep-others` or `stop-system`.
    pub fn name(self) -> &'static str {
        match self {
            GiveUp::KeepOthers => "keep-others",
            GiveUp::StopSystem => "stop-system",
        }
    }

    /// The behaviour named `name` in a description.
    pub fn from_name(name: &str) -> Option<GiveUp> {
        match name {
            "keep-others" => Some(GiveUp::KeepOthers),
            "stop-system" => Some(GiveUp::StopSystem),
            _ => None,
        }
    }
}

impl Default for RestartPolicy {
    fn default() -> Self {
        RestartPolicy {
            when: Restart::OnFailure,
            max_restarts: 5,
            window: Duration::from_secs(60),
            backoff: Duration::from_millis(100),
            max_backoff: Duration::from_secs(5),
            give_up: GiveUp::KeepOthers,
        }
    }
}

impl RestartPolicy {
    /// The delay before restart number `n` (0-based): `backoff * 2^n`, capped at `max_backoff`.
    pub fn delay(&self, n: u32) -> Duration {
        2u32.checked_pow(n)
            .and_then(|factor| self.backoff.checked_mul(factor))
            .map_or(self.max_backoff, |d| d.min(self.max_backoff))
    }
}

impl fmt::Display for RestartPolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.when {
            Restart::Never => f.write_str("never"),
            when => write!(
                f,
                "{when} (at most {} in {:?}, backoff {:?} to {:?}, then {})",
                self.max_restarts,
                self.window,
                self.backoff,
                self.max_backoff,
                self.give_up.name()
            ),
        }
    }
}

/// A multicast group: frames sent to it reach every member.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupSpec {
    /// The group's name (checked like a module name: it names a transport service).
    pub name: String,
    /// The member modules' names, as declared.
    pub members: Vec<String>,
    /// The line of the `group` declaration.
    pub line: u32,
}

/// Reads, evaluates and checks the system description in the file `path`.
pub fn load(path: &Path, resolver: &dyn ProgramResolver) -> Result<SystemSpec, SystemError> {
    load_with_vars(path, resolver, &[])
}

/// Like [`load`], with the variables `vars` in the description's table `vars` (a later entry
/// wins over an earlier one with the same key).
pub fn load_with_vars(
    path: &Path,
    resolver: &dyn ProgramResolver,
    vars: &[(String, String)],
) -> Result<SystemSpec, SystemError> {
    load_with_registry(path, resolver, vars, &modbot_components::builtin())
}

/// Like [`load_with_vars`], in the domain `domain` when one is given (`modbot up --domain`)
/// rather than the description's: everything that depends on the domain follows it — the
/// assembly data the assembly files read (`data(key)`, the first assembly's included) is the
/// given domain's, where a robot program of that domain writes its commands' parameters.
pub fn load_in_domain(
    path: &Path,
    resolver: &dyn ProgramResolver,
    vars: &[(String, String)],
    domain: Option<&str>,
) -> Result<SystemSpec, SystemError> {
    let (file, source) = read_description(path)?;
    let mut declarations = lua::evaluate(&file, &source, vars, None)?;
    if let Some(given) = domain {
        modbot_core::Domain::new(given).map_err(|e| {
            SystemError::new(&file, None, format!("--domain {given}: {e}")).because(e)
        })?;
        let line = declarations.domain.as_ref().map_or(0, |(_, line)| *line);
        declarations.domain = Some((given.to_owned(), line));
    }
    let registry = modbot_components::builtin();
    validate::build(&file, &source, declarations, resolver, &registry, vars)
}

/// Like [`load_with_vars`], with the grid's component types taken from `registry` (the others
/// use the built-in ones, [`Registry::builtin`]).
pub fn load_with_registry(
    path: &Path,
    resolver: &dyn ProgramResolver,
    vars: &[(String, String)],
    registry: &Registry,
) -> Result<SystemSpec, SystemError> {
    let (file, source) = read_description(path)?;
    load_str_with_registry(&file, &source, resolver, vars, registry)
}

/// The description in the file `path`, as text, and the file's name for messages.
fn read_description(path: &Path) -> Result<(String, String), SystemError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| {
        SystemError::new(&file, None, format!("cannot read the description: {e}")).because(e)
    })?;
    let source = String::from_utf8(bytes).map_err(|e| {
        SystemError::new(
            &file,
            None,
            format!(
                "the description is not UTF-8 text (bad byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })?;
    Ok((file, source))
}

/// Evaluates and checks the system description `source`; messages call it `file_name`.
pub fn load_str(
    file_name: &str,
    source: &str,
    resolver: &dyn ProgramResolver,
) -> Result<SystemSpec, SystemError> {
    load_str_with_vars(file_name, source, resolver, &[])
}

/// Like [`load_str`], with the variables `vars` (see [`load_with_vars`]).
pub fn load_str_with_vars(
    file_name: &str,
    source: &str,
    resolver: &dyn ProgramResolver,
    vars: &[(String, String)],
) -> Result<SystemSpec, SystemError> {
    load_str_with_registry(
        file_name,
        source,
        resolver,
        vars,
        &modbot_components::builtin(),
    )
}

/// Like [`load_str_with_vars`], with the grid's component types taken from `registry`.
pub fn load_str_with_registry(
    file_name: &str,
    source: &str,
    resolver: &dyn ProgramResolver,
    vars: &[(String, String)],
    registry: &Registry,
) -> Result<SystemSpec, SystemError> {
    let declarations = lua::evaluate(file_name, source, vars, None)?;
    validate::build(file_name, source, declarations, resolver, registry, vars)
}

/// Reads one `--var KEY=VALUE`: the key is what comes before the first `=`, made of ASCII
/// letters, digits, `_`, `-` and `.`; the value is the rest (it may be empty, and contain `=`).
pub fn parse_var(text: &str) -> Result<(String, String), VarError> {
    let Some((key, value)) = text.split_once('=') else {
        return Err(VarError::NoEquals { text: text.into() });
    };
    if key.is_empty() {
        return Err(VarError::NoKey { text: text.into() });
    }
    if let Some(bad) = key
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || "_-.".contains(*c)))
    {
        let key = key.into();
        return Err(VarError::BadKey { key, bad });
    }
    Ok((key.to_owned(), value.to_owned()))
}

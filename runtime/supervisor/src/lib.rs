//! The supervisor: starts a robot's module processes from its system description, watches
//! them, brings them back per their restart policy, and stops them in order.
//!
//! - It sweeps what dead processes left of the domain, then spawns every module (each its own
//!   process, in its own process group, killed if the supervisor dies) and waits until each has
//!   announced itself with its first heartbeat.
//! - Every module gets the same `MODBOT_EPOCH_NS`, the instant (CLOCK_MONOTONIC) the system
//!   started, restarts included: the epoch of the system's simulated time ([`modbot_core::sim`]).
//! - It keeps the domain's directory (who runs where, with which pid) and publishes it to the
//!   modules whenever a module comes, goes or restarts; it cleans up after dead processes, so
//!   the modules never scan or clean the domain themselves.
//! - It watches exits (`waitpid`) and heartbeats: a module whose heartbeat stops for the
//!   configured time is hung; it is killed and handled like a crash.
//! - Restart policies (`never`, `on-failure`, `always`, with a maximum per window and an
//!   exponential backoff) decide what comes back; a module that ends too often is failed, and
//!   its policy says whether the rest keeps running.
//! - It is itself a module of the domain, named `supervisor`: `status` answers the table that
//!   `modbot ls` shows, `down` stops the system (`modbot down`); for the coordinator,
//!   `spawn_host(host, assembly, generation)` starts the host process of an assembly being
//!   prepared and `retire(module)` stops one of an assembly that was replaced (or failed to
//!   prepare) and drops it from the table.
//! - On SIGINT/SIGTERM, `down`, or when its time is up, it stops the modules in reverse order
//!   (SIGTERM, then SIGKILL after the grace period) and removes the domain's shared memory.
//!
//! # Layout
//! - this file: the supervisor's life cycle — start, watch (exits, heartbeats, restarts),
//!   shut down — and its output;
//! - `endpoint`: its own module and methods (`status`, `down`);
//! - `hosts`: the hosts of assemblies, started and retired at the coordinator's request;
//! - `shared`: what the supervisor and its method handlers share;
//! - `sweep`: refusing a domain in use, clearing what dead processes left;
//! - `upgrades`: live upgrades, a new process taking a running module over;
//! - [`env`]: what a module process learns from its environment.
//! - `child`: spawning one module process and forwarding its output.
//! - [`policy`]: restart decisions and exit reasons.
//! - `relay`: calls of tools that hold no module address, made by the supervisor.
//! - `roster`: the domain's directory, published to every module when it changes.
//! - [`rt`]: CPU affinity and SCHED_FIFO for a module process.
//! - [`status`]: the status rows and table.

mod assemblies;
mod child;
mod endpoint;
mod hosts;
mod shared;
mod shown;
mod sweep;
mod upgrades;
pub use modbot_transport::launch as env;
pub mod policy;
pub mod processes;
mod relay;
mod roster;
pub mod rt;
pub mod status;

use core::time::Duration;
use std::io::Write;
use std::process::Child;
use std::time::Instant;

use crossbeam::channel::{unbounded, Receiver, Sender};
use modbot_ipc_schema::directory::Listing;
use modbot_ipc_schema::heartbeat::{Counters, Heartbeat, ModuleState};
use modbot_ipc_schema::Addr;
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;
use thiserror::Error;

use child::{LogLine, SystemEnv};
use endpoint::open_endpoint;
use modbot_core::clock::{Clock, MonotonicClock};
use modbot_core::domain::Domain;
use modbot_core::module::Module;
use modbot_core::signals::Shutdown;
use modbot_core::transport::ipc::{HeartbeatMonitor, IpcTransport};
use modbot_core::transport::TransportError;
use modbot_system::{GiveUp, SystemSpec};
use policy::{Decision, ExitReason, RestartTracker};
use relay::Relay;
use roster::Roster;
use shared::Shared;
use shown::Shown;
use status::{Row, RunState};
use sweep::sweep;

/// Why the supervisor could not start or run a system.
impl SupervisorError {
    /// `domain` is in use: another supervisor runs there (its pid, when known).
    pub(crate) fn another_supervisor(domain: &Domain, pid: Option<u32>) -> SupervisorError {
        SupervisorError::DomainInUse {
            domain: domain.name().to_owned(),
            modules: match pid {
                Some(pid) => format!("supervisor (pid {pid})"),
                None => "another supervisor".to_owned(),
            },
        }
    }
}

#[derive(Debug, Error)]
pub enum SupervisorError {
    #[error("domain '{domain}' is in use by a running system (live modules: {modules}); stop it first with `modbot down --domain {domain}`")]
    DomainInUse { domain: String, modules: String },
    #[error("cannot start module '{module}' ({program}): {source}")]
    Spawn {
        module: String,
        program: String,
        source: std::io::Error,
    },
    #[error("module {module} ended before it announced itself ({reason})")]
    EndedAtStart { module: String, reason: String },
    #[error("module(s) {modules} did not announce themselves within {timeout_ms} ms")]
    StartTimeout { modules: String, timeout_ms: u64 },
    #[error("the description uses all 254 addresses; the supervisor needs one free address")]
    NoAddressLeft,
    #[error("domain: {0}")]
    Domain(#[from] modbot_core::domain::DomainNameError),
    #[error(transparent)]
    Transport(#[from] TransportError),
    #[error(transparent)]
    Module(#[from] modbot_core::error::ModuleError),
    /// The checked grid could not be written for the grid's processes.
    #[error(transparent)]
    SpecImage(#[from] modbot_core::transport::spec_image::SpecImageError),
}

/// The longest the supervisor sleeps between looks at heartbeats and deadlines (calls to it
/// and its children's ends wake it at once).
const IDLE_WAIT: Duration = Duration::from_millis(20);

/// How long to run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Stop after this long (`--for`).
    pub run_for: Option<Duration>,
    /// Print the status table whenever a module changes state (the live view).
    pub show_status: bool,
}

/// How the run ended.
#[derive(Debug, Clone)]
pub struct Summary {
    /// Every module ran within its policy and stopped cleanly.
    pub ok: bool,
    /// The final status of every module.
    pub rows: Vec<Row>,
    /// What went wrong, one line each.
    pub problems: Vec<String>,
    /// How long the system ran.
    pub ran_for: Duration,
}

/// One supervised module.
struct Slot {
    child: Option<Child>,
    pid: u32,
    state: RunState,
    tracker: RestartTracker,
    last_exit: Option<ExitReason>,
    /// Why the supervisor killed it, when it did.
    killed_for: Option<ExitReason>,
    started_ns: u64,
    /// When its last heartbeat arrived; 0 until the first.
    last_beat_ns: u64,
    restart_at_ns: u64,
    counters: Counters,
    /// The digest of its method names, from its heartbeats.
    methods_digest: u32,
    /// Asked to stop for good (a replaced assembly's host): its end is not a failure.
    retiring: bool,
    /// The threads forwarding its output: what it wrote last is shown before its end is.
    log_readers: Vec<std::thread::JoinHandle<()>>,
    /// How often a live upgrade replaced its process.
    upgrades: u16,
}

impl Slot {
    /// A module not started yet.
    fn new(restart: modbot_system::RestartPolicy) -> Slot {
        Slot {
            child: None,
            pid: 0,
            state: RunState::Starting,
            tracker: RestartTracker::new(restart),
            last_exit: None,
            killed_for: None,
            started_ns: 0,
            last_beat_ns: 0,
            restart_at_ns: 0,
            counters: Counters::default(),
            methods_digest: 0,
            retiring: false,
            log_readers: Vec::new(),
            upgrades: 0,
        }
    }
}

/// A running system.
pub struct Supervisor {
    /// The system: its modules (the grid's processes and assembly hosts added as they come)
    /// and how they are supervised.
    spec: SystemSpec,
    /// When to stop: handed over by the program that runs the supervisor.
    shutdown: Shutdown,
    /// The domain the system runs in.
    domain: Domain,
    /// One per module of `spec`, in its order: its process and what the supervisor knows of it.
    slots: Vec<Slot>,
    /// The supervisor's own module (`supervisor`): its methods and the state they share.
    endpoint: Module<Shared>,
    /// The published directory of the domain's modules.
    roster: Roster,
    /// Relays the calls of tools that found no free address.
    relay: Relay,
    /// The modules' heartbeats.
    heartbeats: HeartbeatMonitor,
    /// The modules' output lines, forwarded with their names.
    logs: Logs,
    /// When the supervisor started (its clock for deadlines and restarts).
    epoch: Instant,
    /// The same instant on CLOCK_MONOTONIC, which every module gets as `MODBOT_EPOCH_NS`, and
    /// the other settings every module gets alike.
    system: SystemEnv,
    /// What went wrong, one line each, for the summary.
    problems: Vec<String>,
    /// A module did not stop within its grace period when the system stopped.
    stop_failed: bool,
    /// What the supervisor shows, and when each view is due.
    shown: Shown,
    /// SIGCHLD tells when a child ended (else every child is looked at on every wake-up).
    child_signal: bool,
    /// When every child was last looked at regardless of SIGCHLD.
    children_seen: Instant,
    /// Modules that came up and the supervisor has no link to yet: it opens them a few at a
    /// time while idle, so that the first calls it relays for a tool find them open.
    to_connect: Vec<Addr>,
    /// Live upgrades under way.
    upgrades: Vec<upgrades::Upgrade>,
    /// Processes upgrades replaced, handing over before they end.
    leaving: Vec<upgrades::Leaving>,
    /// Directories of upgrades that ended, removed a while later.
    remove_later: Vec<(std::path::PathBuf, Instant)>,
}

/// The modules' output, as the supervisor forwards it: `name | line`.
struct Logs {
    /// Given to each child's output threads.
    tx: Sender<LogLine>,
    /// Read by the supervisor's loop.
    rx: Receiver<LogLine>,
    /// The width of the name column (the longest module name).
    name_width: usize,
}

impl Supervisor {
    /// Sweeps the domain, starts every module and waits until all have announced themselves;
    /// `shutdown` ends the start-up, and later [`Supervisor::run`], when it is requested
    /// ([`Shutdown::on_signals`]: on SIGINT/SIGTERM).
    pub fn start(spec: SystemSpec, shutdown: Shutdown) -> Result<Supervisor, SupervisorError> {
        let domain = Domain::new(&spec.domain)?;
        let (epoch, system) = (
            Instant::now(),
            SystemEnv::new(
                MonotonicClock.now_ns(),
                spec.modules.len() + spec.imported.len(),
            ),
        );
        // The supervisor's own inbox is sized like its modules'.
        let transport =
            IpcTransport::for_supervisor(&domain)?.with_inbox_senders(system.inbox_senders);
        let directory = transport.scanned_directory();
        let used: Vec<u8> = spec.modules.iter().map(|m| m.addr).collect();
        sweep(&domain, directory.as_ref(), &used)?;
        // Two `modbot up` started at once may both pass the sweep: the directory has one
        // writer and the relay one server, and the one that comes second finds the domain in
        // use.
        let in_use = |e: TransportError| match e {
            TransportError::AnotherSupervisor { pid } => {
                SupervisorError::another_supervisor(&domain, pid)
            }
            e => e.into(),
        };
        let roster = Roster::new(&transport).map_err(in_use)?;
        let relay = Relay::new(&transport).map_err(in_use)?;
        // The grid's processes read the checked grid, written after the sweep (which removes
        // what an earlier run of the domain left).
        if let Some(grid) = &spec.grid {
            assemblies::write_image(&domain, grid)?;
        }
        let mut endpoint = open_endpoint(&transport, &used)?;
        endpoint.state_mut().hosts_allowed = spec.host_template.is_some();
        endpoint.state_mut().assemblies =
            spec.grid
                .as_ref()
                .filter(|g| g.assembly.is_some())
                .map(|grid| shared::AssemblyLoader {
                    grid: grid.clone(),
                    domain: domain.clone(),
                });
        let heartbeats = HeartbeatMonitor::new(&transport)?;
        // A child's end interrupts the supervisor's wait and is looked for at once.
        let child_signal = modbot_core::signals::install_child_handler();
        if let Err(e) = &child_signal {
            tracing::debug!("SIGCHLD handler: {e}; children are looked at on every wake-up");
        }
        let (tx, rx) = unbounded();
        let slots = spec
            .modules
            .iter()
            .map(|m| Slot::new(m.restart.clone()))
            .collect();
        let name_width = spec.modules.iter().map(|m| m.name.len()).max().unwrap_or(4);
        let mut sup = Supervisor {
            spec,
            shutdown,
            domain,
            slots,
            endpoint,
            roster,
            relay,
            heartbeats,
            logs: Logs { tx, rx, name_width },
            epoch,
            system,
            problems: Vec::new(),
            stop_failed: false,
            shown: Shown::new(),
            child_signal: child_signal.is_ok(),
            children_seen: Instant::now(),
            to_connect: Vec::new(),
            upgrades: Vec::new(),
            leaving: Vec::new(),
            remove_later: Vec::new(),
        };
        sup.say(&format!(
            "starting {} module(s) in domain '{}'",
            sup.slots.len(),
            sup.domain.name()
        ));
        for i in 0..sup.slots.len() {
            if let Err(e) = sup.spawn(i) {
                sup.shutdown();
                return Err(e);
            }
        }
        if let Err(e) = sup.await_announcements() {
            sup.shutdown();
            return Err(e);
        }
        sup.say(&format!(
            "all {} module(s) up in {} ms",
            sup.slots.len(),
            sup.epoch.elapsed().as_millis()
        ));
        Ok(sup)
    }

    /// The domain the system runs in.
    pub fn domain(&self) -> &Domain {
        &self.domain
    }

    /// Supervises until its shutdown is requested, `modbot down`, the end of `opts.run_for`, or a failed
    /// module whose policy stops the system; then stops everything and reports.
    pub fn run(mut self, opts: &RunOptions) -> Summary {
        let started = Instant::now();
        let mut last_table = Instant::now() - Duration::from_secs(1);
        loop {
            self.serve();
            self.handle_host_requests();
            self.handle_upgrades();
            self.watch();
            self.forward_logs();
            if opts.show_status
                && self.shown.table_stale()
                && last_table.elapsed() > Duration::from_millis(200)
                && self.shown.table_due()
            {
                last_table = Instant::now();
                self.print_table();
            }
            if self.shutdown.requested() {
                self.say("termination requested: stopping");
                break;
            }
            if self.endpoint.state().down_requested {
                self.say("`modbot down` requested: stopping");
                break;
            }
            if self.stop_failed {
                self.say("a failed module stops the system: stopping");
                break;
            }
            if opts.run_for.is_some_and(|d| started.elapsed() >= d) {
                self.say("run time is up: stopping");
                break;
            }
            // Calls and SIGCHLD wake the loop; otherwise it looks at heartbeats and deadlines
            // every IDLE_WAIT.
            if let Err(e) = self.endpoint.wait(self.idle_wait()) {
                tracing::debug!("supervisor wait: {e}");
            }
        }
        let ran_for = started.elapsed();
        self.shutdown();
        let rows = self.rows();
        let ok = self.problems.is_empty();
        Summary {
            ok,
            rows,
            problems: std::mem::take(&mut self.problems),
            ran_for,
        }
    }

    /// How long the loop may sleep: [`IDLE_WAIT`], or less if a restart is due sooner.
    fn idle_wait(&self) -> Duration {
        let now = self.now_ns();
        self.slots
            .iter()
            .filter(|s| s.state == RunState::Restarting)
            .map(|s| Duration::from_nanos(s.restart_at_ns.saturating_sub(now)))
            .chain([IDLE_WAIT])
            .min()
            .unwrap_or(IDLE_WAIT)
    }

    fn now_ns(&self) -> u64 {
        self.epoch.elapsed().as_nanos() as u64
    }

    /// A line of the supervisor's own, on stdout.
    fn say(&self, text: &str) {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{:>w$} | {text}", "modbot", w = self.logs.name_width);
    }

    fn print_table(&mut self) {
        let table = status::table(&self.rows());
        let mut out = std::io::stdout().lock();
        let _ = write!(out, "{table}");
    }

    fn rows(&self) -> Vec<Row> {
        let now = self.now_ns();
        self.spec
            .modules
            .iter()
            .zip(&self.slots)
            .filter(|(_, s)| s.state != RunState::Retired)
            .map(|(m, s)| Row {
                name: m.name.clone(),
                addr: m.addr,
                state: s.state.name().to_owned(),
                pid: if s.child.is_some() { s.pid } else { 0 },
                restarts: s.tracker.total,
                last_exit: s
                    .last_exit
                    .as_ref()
                    .map(ToString::to_string)
                    .unwrap_or_default(),
                counters: s.counters,
                upgrades: s.upgrades,
                heartbeat_age_ms: (s.child.is_some() && s.last_beat_ns > 0)
                    .then(|| now.saturating_sub(s.last_beat_ns) / 1_000_000),
            })
            .collect()
    }

    fn spawn(&mut self, i: usize) -> Result<(), SupervisorError> {
        let m = &self.spec.modules[i];
        let (child, log_readers) = child::spawn(
            i,
            m,
            &self.domain,
            &self.spec.supervision,
            &self.system,
            &self.logs.tx,
        )
        .map_err(|source| SupervisorError::Spawn {
            module: m.name.clone(),
            program: m.program.display().to_string(),
            source,
        })?;
        let pid = child.id();
        let now = self.now_ns();
        let slot = &mut self.slots[i];
        slot.child = Some(child);
        slot.log_readers = log_readers;
        slot.pid = pid;
        slot.state = RunState::Starting;
        slot.started_ns = now;
        slot.last_beat_ns = 0;
        slot.killed_for = None;
        self.shown.changed();
        Ok(())
    }

    fn await_announcements(&mut self) -> Result<(), SupervisorError> {
        let timeout = self.spec.supervision.start_timeout;
        let deadline = Instant::now() + timeout;
        loop {
            self.serve();
            self.watch();
            self.forward_logs();
            let ended = self
                .spec
                .modules
                .iter()
                .zip(&self.slots)
                .find(|(_, s)| matches!(s.state, RunState::Down | RunState::Failed));
            if let Some((m, s)) = ended {
                return Err(SupervisorError::EndedAtStart {
                    module: m.name.clone(),
                    reason: s
                        .last_exit
                        .as_ref()
                        .map(ToString::to_string)
                        .unwrap_or_default(),
                });
            }
            if self.slots.iter().all(|s| s.state == RunState::Running) {
                return Ok(());
            }
            if self.shutdown.requested() || Instant::now() >= deadline {
                let missing: Vec<&str> = self
                    .spec
                    .modules
                    .iter()
                    .zip(&self.slots)
                    .filter(|(_, s)| s.state != RunState::Running)
                    .map(|(m, _)| m.name.as_str())
                    .collect();
                return Err(SupervisorError::StartTimeout {
                    modules: missing.join(", "),
                    timeout_ms: timeout.as_millis() as u64,
                });
            }
            let _ = self.endpoint.wait(Duration::from_millis(5));
        }
    }

    /// Serves the supervisor's own calls (`status`, `down`) and keeps its phone book fresh.
    fn serve(&mut self) {
        if self.shown.directory_due(self.roster.changed()) {
            self.publish_directory();
        }
        // The rows `status` answers: at once after a change, else with fresh counters.
        if self.shown.rows_due() {
            let rows = self.rows();
            self.endpoint.state_mut().rows = rows;
        }
        self.relay.serve(&mut self.endpoint);
        for _ in 0..64 {
            match self.endpoint.poll_once() {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => {
                    tracing::debug!("supervisor receive: {e}");
                    break;
                }
            }
        }
        self.endpoint.housekeeping();
        self.relay.serve(&mut self.endpoint);
        // A link costs about a millisecond to open: a few per wake-up.
        for _ in 0..4 {
            let Some(addr) = self.to_connect.pop() else {
                break;
            };
            if let Err(e) = self.endpoint.ctx().connect(addr) {
                tracing::debug!("no link to module {addr} yet: {e}");
            }
        }
    }

    /// Heartbeats, exits, hangs and due restarts.
    fn watch(&mut self) {
        let now = self.now_ns();
        let mut beats: Vec<(u8, u32, ModuleState, Counters, u32)> = Vec::new();
        let drained = self.heartbeats.drain(&mut |bytes| {
            if let Ok(hb) = Heartbeat::parse(bytes) {
                beats.push((
                    hb.addr().0,
                    hb.pid(),
                    hb.state(),
                    hb.counters(),
                    hb.methods_digest(),
                ));
            }
        });
        if let Err(e) = drained {
            tracing::debug!("heartbeats: {e}");
        }
        let own = self.endpoint.addr().0;
        for (addr, pid, state, counters, digest) in beats {
            let mine = self
                .spec
                .modules
                .iter()
                .zip(&self.slots)
                .position(|(m, s)| {
                    m.addr == addr && (s.child.is_some() || s.state != RunState::Retired)
                });
            let Some(i) = mine else {
                if addr != own {
                    self.roster
                        .beat_of_other(Addr(addr), pid, state, digest, now);
                }
                continue;
            };
            let slot = &mut self.slots[i];
            if slot.child.is_none() || slot.pid != pid {
                continue; // a beat of an earlier incarnation, still in the queue
            }
            slot.last_beat_ns = now;
            slot.counters = counters;
            if slot.methods_digest != digest {
                slot.methods_digest = digest;
                self.shown.changed();
            }
            if slot.state == RunState::Starting && state == ModuleState::Running {
                slot.state = RunState::Running;
                self.shown.changed();
                // Its start (loading, opening channels: milliseconds to seconds of work) ran
                // at normal priority; now that it is up, its real-time settings apply, so a
                // process starting beside a running grid never holds up the grid's threads.
                let m = &self.spec.modules[i];
                for w in rt::apply(pid, &m.cpus, m.priority) {
                    self.say(&format!("warning: {}: {w}", m.name));
                }
                let name = self.spec.modules[i].name.clone();
                self.say(&format!("{name} is up (pid {pid})"));
                self.to_connect.push(Addr(addr));
            }
        }
        self.watch_leaving();
        self.roster.check_others(
            now,
            self.spec.supervision.heartbeat_timeout.as_nanos() as u64,
        );
        // Children are looked at when SIGCHLD said one ended (and once a second, in case a
        // signal was lost), not with one `waitpid` per module on every wake-up.
        let ended = !self.child_signal
            || modbot_core::signals::take_child_ended()
            || self.children_seen.elapsed() >= Duration::from_secs(1);
        if ended {
            self.children_seen = Instant::now();
        }
        for i in 0..self.slots.len() {
            if ended || self.slots[i].killed_for.is_some() {
                self.check_exit(i, now);
            }
            self.check_hang(i, now);
            let slot = &self.slots[i];
            if slot.state == RunState::Restarting && now >= slot.restart_at_ns {
                if let Err(e) = self.spawn(i) {
                    self.say(&format!("{e}"));
                    self.give_up(i, format!("{e}"));
                }
            }
        }
    }

    fn check_exit(&mut self, i: usize, now: u64) {
        self.switch_if_handed_over(i);
        let slot = &mut self.slots[i];
        let Some(child) = slot.child.as_mut() else {
            return;
        };
        let status = match child.try_wait() {
            Ok(Some(status)) => status,
            Ok(None) => return,
            Err(e) => {
                tracing::debug!("waitpid: {e}");
                return;
            }
        };
        slot.child = None;
        let reason = slot.killed_for.take().unwrap_or_else(|| reason_of(status));
        let pid = slot.pid;
        self.flush_output_of(i);
        // The dead process's ports would keep "receiving" until cleaned: clean them now, and
        // tell its peers it is gone. What it unpacked in the temporary directory (an FMU) goes.
        self.roster.reap();
        self.domain.remove_temp_of(pid);
        self.publish_directory();
        if self.slots[i].retiring {
            self.slots[i].state = RunState::Retired;
            self.shown.changed();
            return;
        }
        let name = self.spec.modules[i].name.clone();
        let decision = self.slots[i].tracker.on_exit(&reason, now);
        let slot = &mut self.slots[i];
        slot.last_exit = Some(reason.clone());
        self.shown.changed();
        match decision {
            Decision::RestartAt(at) => {
                slot.state = RunState::Restarting;
                slot.restart_at_ns = at;
                let line = format!(
                    "{name} ended ({reason}); restart {} in {} ms",
                    slot.tracker.total,
                    (at - now) / 1_000_000
                );
                self.say(&line);
            }
            Decision::StayDown => {
                slot.state = RunState::Down;
                self.say(&format!(
                    "{name} ended ({reason}); not restarted (its policy)"
                ));
                if reason.is_failure() {
                    self.problems
                        .push(format!("{name}: {reason}, not restarted"));
                }
            }
            Decision::GiveUp => {
                let window = self.spec.modules[i].restart.window;
                let max = self.spec.modules[i].restart.max_restarts;
                self.give_up(
                    i,
                    format!(
                        "ended ({reason}) after {max} restarts within {} s",
                        window.as_secs_f64()
                    ),
                );
            }
        }
    }

    fn give_up(&mut self, i: usize, why: String) {
        let m = &self.spec.modules[i];
        let name = m.name.clone();
        let stop = m.restart.give_up == GiveUp::StopSystem;
        self.slots[i].state = RunState::Failed;
        self.shown.changed();
        self.say(&format!(
            "{name} FAILED: {why}; {}",
            if stop {
                "stopping the system"
            } else {
                "the other modules keep running"
            }
        ));
        self.problems.push(format!("{name} failed: {why}"));
        if stop {
            self.stop_failed = true;
        }
    }

    fn check_hang(&mut self, i: usize, now: u64) {
        let sup = &self.spec.supervision;
        let slot = &mut self.slots[i];
        if slot.child.is_none() || slot.killed_for.is_some() {
            return;
        }
        if slot.retiring {
            if now >= slot.restart_at_ns {
                let _ = kill(Pid::from_raw(slot.pid as i32), Signal::SIGKILL);
                slot.killed_for = Some(ExitReason::Stopped(-1));
            }
            return;
        }
        let reason = match slot.state {
            RunState::Running => {
                let silent = now.saturating_sub(slot.last_beat_ns);
                (silent >= sup.heartbeat_timeout.as_nanos() as u64).then_some(ExitReason::Hung {
                    silent_ms: silent / 1_000_000,
                })
            }
            RunState::Starting => {
                let waited = now.saturating_sub(slot.started_ns);
                (waited >= sup.start_timeout.as_nanos() as u64).then_some(ExitReason::NoStart {
                    waited_ms: waited / 1_000_000,
                })
            }
            _ => None,
        };
        if let Some(reason) = reason {
            let name = &self.spec.modules[i].name;
            let pid = slot.pid;
            let _ = kill(Pid::from_raw(pid as i32), Signal::SIGKILL);
            // A stopped process must be continued for the kill to complete at once.
            let _ = kill(Pid::from_raw(pid as i32), Signal::SIGCONT);
            let line = format!("{name} (pid {pid}): {reason}");
            slot.killed_for = Some(reason);
            self.say(&line);
        }
    }

    fn forward_logs(&mut self) {
        let mut out = std::io::stdout().lock();
        while let Ok(LogLine { module, line }) = self.logs.rx.try_recv() {
            let name = self
                .spec
                .modules
                .get(module)
                .map_or("?", |m| m.name.as_str());
            let _ = writeln!(out, "{name:>w$} | {line}", w = self.logs.name_width);
        }
    }

    /// Shows what module `i`, which ended, wrote last: its output threads end when its pipes
    /// close (waited for up to 200 ms: a process it left behind may hold them open).
    fn flush_output_of(&mut self, i: usize) {
        let mut readers = std::mem::take(&mut self.slots[i].log_readers);
        self.flush_readers(&mut readers);
        self.slots[i].log_readers = readers;
    }

    /// Waits up to 200 ms for a process's output threads to end (a process it left behind may
    /// hold its pipes open), then forwards what they sent.
    fn flush_readers(&mut self, readers: &mut Vec<std::thread::JoinHandle<()>>) {
        let deadline = Instant::now() + Duration::from_millis(200);
        while readers.iter().any(|r| !r.is_finished()) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(1));
        }
        readers.retain(|r| !r.is_finished());
        self.forward_logs();
    }

    /// Stops every module in reverse order and removes the domain's shared memory.
    fn shutdown(&mut self) {
        self.stop_upgrades();
        let grace = self.spec.supervision.stop_grace;
        for i in (0..self.slots.len()).rev() {
            let Some(mut child) = self.slots[i].child.take() else {
                if self.slots[i].state == RunState::Restarting {
                    self.slots[i].state = RunState::Stopped;
                }
                continue;
            };
            let name = self.spec.modules[i].name.clone();
            let pid = Pid::from_raw(child.id() as i32);
            let _ = kill(pid, Signal::SIGCONT);
            let _ = kill(pid, Signal::SIGTERM);
            let deadline = Instant::now() + grace;
            let status = loop {
                match child.try_wait() {
                    Ok(Some(status)) => break Some(status),
                    Ok(None) if Instant::now() < deadline => {
                        self.forward_logs();
                        std::thread::sleep(Duration::from_millis(2));
                    }
                    Ok(None) => {
                        let _ = child.kill();
                        let status = child.wait().ok();
                        self.problems.push(format!(
                            "{name}: did not stop within {} ms of SIGTERM; killed",
                            grace.as_millis()
                        ));
                        break status;
                    }
                    Err(_) => break None,
                }
            };
            self.flush_output_of(i);
            self.domain.remove_temp_of(self.slots[i].pid);
            let slot = &mut self.slots[i];
            slot.state = RunState::Stopped;
            if let Some(status) = status {
                let code = match reason_of(status) {
                    ExitReason::Exited(c) => c,
                    ExitReason::Signaled(s) => 128 + s,
                    _ => -1,
                };
                if code != 0 {
                    self.problems
                        .push(format!("{name}: {} on SIGTERM", reason_of(status)));
                }
                slot.last_exit = Some(ExitReason::Stopped(code));
            }
            // The modules still running stop calling this one.
            self.publish_directory();
        }
        self.forward_logs();
        self.roster.reap();
    }

    /// Publishes the directory if anything in it changed: every module process that runs (it
    /// is "running" from its first heartbeat), and the supervisor itself.
    fn publish_directory(&mut self) {
        let mut listings: Vec<Listing> = self
            .spec
            .modules
            .iter()
            .zip(&self.slots)
            .filter(|(_, s)| s.child.is_some() && s.pid != 0)
            .map(|(m, s)| Listing {
                addr: Addr(m.addr),
                mode: m.mode.code() as u8,
                state: match s.state {
                    RunState::Running if !s.retiring => ModuleState::Running,
                    RunState::Starting => ModuleState::Starting,
                    _ => ModuleState::Stopping,
                },
                pid: s.pid,
                methods_digest: s.methods_digest,
                upgrades: s.upgrades,
                name: m.name.clone(),
            })
            .collect();
        listings.push(Listing {
            addr: self.endpoint.addr(),
            mode: self.endpoint.mode().code() as u8,
            state: ModuleState::Running,
            pid: std::process::id(),
            methods_digest: self.endpoint.methods_digest(),
            upgrades: 0,
            name: "supervisor".into(),
        });
        self.roster.publish(listings);
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        // Modules still running (an error path): stop them before the endpoint goes.
        if self.slots.iter().any(|s| s.child.is_some()) {
            self.shutdown();
        }
        // The endpoint and the heartbeat monitor are dropped after this body; the caller
        // removes the domain's files once they are gone (see `modbot up`).
    }
}

fn reason_of(status: std::process::ExitStatus) -> ExitReason {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(code), _) => ExitReason::Exited(code),
        (None, Some(sig)) => ExitReason::Signaled(sig),
        (None, None) => ExitReason::Exited(-1),
    }
}

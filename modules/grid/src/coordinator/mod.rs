//! The coordinator: the only process that reads the clock. Every base tick it releases the
//! components that are due, collects their done notices, detects overruns and keeps the ledger.
//!
//! Tick n, in this order:
//! 1. done notices that arrived are taken — for a component due now whose release still runs,
//!    after a short grace asleep on the hosts' done wake-up (the notice may be on its way); on
//!    the lockstep clock, until it is done: a release m of a component with
//!    period k that is done by now is *on time* if n ≤ m + k; its outputs become valid at
//!    m + k. A late one is only counted (its overrun was counted at its deadline);
//! 2. on-time outputs whose time has come (valid_from ≤ n) become the valid version;
//! 3. the recorder, if any, writes every output as valid at n;
//! 4. every component due at n (n mod k = 0) is released with, for each source of its inputs,
//!    the version valid at n. A component whose previous release is not done is not released:
//!    that is an overrun. With the `hold` policy downstream keeps reading its last valid
//!    outputs; with `fault` the grid stops releasing and reports the fault.
//!
//! The tick path does not allocate: notices are fixed-size and written in place.
//!
//! # Layout
//! All of the coordinator is here, its grid and its process (the program `modbot-coordinator`
//! only parses its options and calls [`service::run`]). Two threads, which talk through two
//! channels:
//! - the **tick thread** (SCHED_FIFO where the system gives it) runs the grid and nothing else:
//!   - this file, [`Coordinator`]: the tick (done notices, overruns, releases), the ledger, the
//!     trace's end;
//!   - `links`: the links to the hosts and the batch of releases each gets per tick;
//!   - `incoming`: the tick thread's side of a switch: the assembly being prepared, announced,
//!     tracking, and the switch at its tick;
//!   - `timing`: how the wake-ups kept to the base tick (missed ticks, tick error, rate);
//!   - `upgrade`: a live upgrade of a host: the tick its new process takes over at;
//!   - `tick_thread`: the thread's loop, the commands it takes between ticks and its news;
//! - the **service thread** (normal scheduling) serves the module's methods, reads the
//!   directory, calls the supervisor:
//!   - [`service`]: the process (its options, its methods, the main loop), and `shared`, what
//!     its methods and its switch job share;
//!   - `switch_job`: the service thread's side of a switch: the supervisor loads the
//!     assembly, its hosts start, the links open, the tick thread is asked to announce it;
//!   - `upgrade_job`: a scripted live upgrade of a host (`--upgrade TICK:HOST`) asked of the
//!     supervisor and followed;
//!   - `gate`: the lockstep gate a robot program steps the grid with (who owns it, where it
//!     holds, when it lifts by itself).

use std::io::Write;

use modbot_ipc_schema::grid::{
    Done, Generation, Release, MAX_SOURCES, PING, READY, STOPPING, SUCCESSOR, UPGRADE,
};
use zerocopy::IntoBytes;

use modbot_core::signals::Shutdown;
use modbot_core::stats::Histogram;
use modbot_core::transport::channels::Channels;
use modbot_core::transport::TransportError;
use modbot_grid::ledger::{self, ComponentRow, GridRow};
use modbot_grid::recorder::{self, Recorder};
use modbot_grid::state_hash;
use modbot_grid::tick::TickSource;
use modbot_grid::wire::{self, Listener, Sub};
use modbot_grid::{GridClock, GridSpec, OverrunPolicy};
use timing::TickTiming;

mod gate;
mod incoming;
mod links;
mod replay_log;
pub mod service;
mod shared;
mod switch_job;
mod tick_thread;
mod timing;
mod upgrade;
mod upgrade_job;

use incoming::Incoming;
pub use incoming::{BeginSwitchError, SwitchState};

pub use links::{link, HostLink};
use links::{release, send_release, ReleaseAt};
use replay_log::ReplayLog;

/// Why the warm-up before tick 0 failed.
#[derive(Debug, thiserror::Error)]
pub enum WarmUpError {
    /// A warm-up release could not be encoded.
    #[error("warm-up release: {0}")]
    Release(#[from] modbot_ipc_schema::grid::GridWireError),
    /// A host's release link failed.
    #[error(transparent)]
    Transport(#[from] TransportError),
}

/// Deadlines in a row a component with the `fault` policy may miss before its assembly faults:
/// one late wake-up on a shared machine is counted, a dead or stuck host faults within this
/// many periods.
pub const FAULT_AFTER: u64 = 3;

/// In lockstep, how long the coordinator waits for a due release before it gives up on
/// lockstep for that tick and counts an overrun (a dead or stopped host).
pub const LOCKSTEP_STUCK: core::time::Duration = core::time::Duration::from_secs(10);

/// How far past its first announced tick a switch may be postponed because the incoming
/// assembly's releases near the switch were late, before it fails.
pub const MAX_POSTPONE_TICKS: u64 = 2000;

/// What the trace records of a release that did not go as LET planned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Miss {
    /// Still running at its deadline (`# overrun`).
    Overrun,
    /// Not executed: an input's version was gone (`# stale`).
    Stale,
}
/// One component, as the coordinator tracks it.
struct Comp {
    period: u64,
    host: usize,
    fault_policy: bool,
    sources: Vec<usize>,
    /// The release awaiting its done notice.
    pending: Option<u64>,
    /// An on-time completion whose outputs become valid at this tick.
    ready: Option<u64>,
    /// The version of its outputs valid now (0: the initial zeros).
    valid_from: u64,
    releases: u64,
    overruns: u64,
    /// Overruns in a row, up to the last on-time release.
    in_a_row: u64,
    late: u64,
    failed: u64,
    /// Releases not executed: an input's version was gone when the host served it.
    stale: u64,
    exec_min: u64,
    exec: Histogram,
    latency: Histogram,
    /// Its last done notice said it holds the robot (`Done::HOLDING`: the bus in safe stop).
    holding: bool,
    /// Its pending release was one to track because the robot is held (`Release::HELD`).
    held_release: bool,
    /// Released at every due tick even while a release of it still runs (the data
    /// recorder: nothing reads its outputs, its host serves the releases in turn, and a row it
    /// missed would be a tick no replay can play back).
    queues: bool,
    /// The state hash of the on-time completion in `ready`, and of the valid version (none
    /// for the initial outputs, or a component that contributes none).
    ready_hash: Option<u64>,
    valid_hash: Option<u64>,
}

impl Comp {
    /// An on-time completion whose time has come becomes the valid version.
    fn take_ready(&mut self, n: u64) {
        if self.ready.is_some_and(|from| from <= n) {
            self.valid_from = self.ready.take().unwrap_or(self.valid_from);
            self.valid_hash = self.ready_hash.take();
        }
    }
}

/// The generation a replay log names component `c` of `spec` with: 0 for the system's own
/// components (they run in every generation), else the grid's.
fn log_generation(spec: &GridSpec, c: usize) -> Generation {
    match &spec.assembly {
        Some(a) if c < a.base => Generation::SYSTEM,
        _ => spec.generation(),
    }
}

/// The grid's state hash over `comps` as their versions are valid now: each one's hash with
/// its index, in component order (as the reference run combines them).
fn tick_hash(comps: &[Comp]) -> u64 {
    state_hash::combine(
        comps
            .iter()
            .enumerate()
            .filter_map(|(c, comp)| Some((c, comp.valid_hash?))),
    )
}

/// The components of `spec`, with their hosts as positions in `host_names` (unknown: 0).
fn comps_of(spec: &GridSpec, host_names: &[String]) -> Vec<Comp> {
    spec.components
        .iter()
        .enumerate()
        .map(|(c, cs)| Comp {
            period: cs.period.max(1),
            host: host_names.iter().position(|h| *h == cs.host).unwrap_or(0),
            fault_policy: cs.policy == OverrunPolicy::Fault,
            sources: spec.sources(c),
            pending: None,
            ready: None,
            valid_from: 0,
            releases: 0,
            overruns: 0,
            in_a_row: 0,
            late: 0,
            failed: 0,
            stale: 0,
            exec_min: u64::MAX,
            exec: Histogram::new(),
            latency: Histogram::new(),
            holding: false,
            held_release: false,
            queues: cs.type_name == modbot_grid::record_type::TYPE,
            ready_hash: None,
            valid_hash: None,
        })
        .collect()
}

/// The grid's clock and bookkeeping.
pub struct Coordinator<W: Write> {
    /// The grid it runs (with assemblies: the running assembly's).
    spec: GridSpec,
    /// Per component: its period, host, policy, sources and what it is doing now.
    comps: Vec<Comp>,
    /// Per host: its release publisher and wake-up.
    hosts: Vec<HostLink>,
    /// The hosts' done notices, and how long to wait for them.
    notices: DoneNotices,
    /// The trace, if one is written.
    recorder: Option<Recorder<W>>,
    /// Scratch: the valid version of every component, for the recorder.
    versions: Vec<u64>,
    /// The next tick to run.
    tick: u64,
    /// How the wake-ups kept to the base tick.
    timing: TickTiming,
    /// Why the grid (or the running assembly) faulted, once it did.
    fault: Option<String>,
    /// Every overrun (tick, component, the release still running) and stale release (its
    /// tick twice), for the trace.
    /// Only with a trace (it is written at the trace's end).
    overrun_log: Vec<(u64, usize, u64, Miss)>,
    /// The assembly being prepared, if one is.
    incoming: Option<Incoming>,
    /// What switches left behind: their record, the hosts and links to stop and drop.
    switched: Switched,
    /// Scratch: the ledger's state text.
    state_text: String,
    /// The tick a program's gate holds the grid before, while it does (the ledger says so).
    held_before: Option<u64>,
    /// The grid's state hash at the tick being run (see [`state_hash`]).
    tick_hash: u64,
    /// Whether a malformed done sample was reported (once: a host of another build).
    malformed_done: bool,
    /// The run's schedule for a replay, if it is kept.
    replay_log: ReplayLog,
    /// A new process of a host waiting to take its components over (a live upgrade).
    successor: Option<upgrade::Successor>,
    /// Hosts handed over to a new process so far.
    handovers: u64,
}

/// The hosts' done notices, as the coordinator waits for them.
struct DoneNotices {
    /// The notices.
    sub: Sub,
    /// Hosts notify it after each batch of done notices: the coordinator sleeps on it while it
    /// waits for a due one.
    wake: Listener,
    /// Scratch: the done notices of one sample.
    scratch: Vec<Done>,
    /// Ends a wait for a due done notice early (see [`Coordinator::with_shutdown`]).
    shutdown: Shutdown,
    /// How long to wait at a tick for a due component's late done notice before calling it
    /// an overrun (absorbs the wake-up latency of the notice).
    grace_ns: u64,
}

/// What assembly switches left behind, for the service thread to take.
#[derive(Default)]
struct Switched {
    /// Switches done: (generation, assembly, announced tick, tick it took over).
    record: Vec<(Generation, String, u64, u64)>,
    /// Host processes of replaced assemblies, to be stopped (module names).
    retired: Vec<String>,
    /// Links to hosts no longer released, to be dropped off the tick thread.
    retired_links: Vec<HostLink>,
}

impl<W: Write> Coordinator<W> {
    /// Opens the grid's services on `node`; with `trace`, records every output at every tick.
    pub fn new(
        node: &dyn Channels,
        spec: GridSpec,
        trace: Option<W>,
    ) -> Result<Coordinator<W>, TransportError> {
        let host_names = spec.hosts();
        let hosts = host_names
            .iter()
            .map(|h| link(node, &spec, h))
            .collect::<Result<Vec<_>, TransportError>>()?;
        let comps = comps_of(&spec, &host_names);
        let recorder = match trace {
            Some(out) => Some(Recorder::new(node, &spec, out)?),
            None => None,
        };
        Ok(Coordinator {
            versions: vec![0; comps.len()],
            comps,
            hosts,
            notices: DoneNotices {
                sub: wire::done_subscriber(node)?,
                wake: wire::done_wake_listener(node)?,
                scratch: Vec::with_capacity(wire::DONE_BATCH),
                shutdown: Shutdown::new(),
                grace_ns: 0,
            },
            recorder,
            spec,
            tick: 0,
            timing: TickTiming::default(),
            fault: None,
            overrun_log: Vec::new(),
            incoming: None,
            switched: Switched::default(),
            state_text: String::with_capacity(128),
            held_before: None,
            tick_hash: 0,
            malformed_done: false,
            replay_log: ReplayLog::none(),
            successor: None,
            handovers: 0,
        })
    }

    /// Whether the gate holds the grid, and before which tick (see `tick_thread`): the
    /// ledger's state says so, for `modbot top`.
    pub fn set_held_before(&mut self, tick: Option<u64>) {
        self.held_before = tick;
    }

    /// Stops waiting for a due done notice when `shutdown` is requested (a lockstep grid waits
    /// for them without a limit of time otherwise).
    pub fn with_shutdown(mut self, shutdown: Shutdown) -> Self {
        self.notices.shutdown = shutdown;
        self
    }

    /// Writes the run's schedule for a replay to `out` (see [`replay_log`]).
    pub fn with_replay_log(mut self, out: Box<dyn Write + Send>) -> Self {
        self.replay_log = ReplayLog::to(out);
        self
    }

    /// Writes the grid's state hash into the trace every `every` ticks and after the last (0:
    /// never; default [`modbot_grid::trace::STATE_HASH_EVERY`]).
    pub fn with_state_hash_every(mut self, every: u64) -> Self {
        self.recorder = self.recorder.map(|r| r.with_state_hash_every(every));
        self
    }

    /// Waits up to `grace_ns` at a tick for a due component's done notice before counting an
    /// overrun.
    pub fn with_grace(mut self, grace_ns: u64) -> Self {
        self.notices.grace_ns = grace_ns;
        self
    }

    /// Before tick 0: sends every host `rounds` warm-up releases, one round at a time, and
    /// waits (up to `timeout`) for each round's answers. Returns the hosts that did not answer.
    pub fn warm_up(
        &mut self,
        rounds: u64,
        timeout: core::time::Duration,
    ) -> Result<usize, WarmUpError> {
        let until = std::time::Instant::now() + timeout;
        let mut silent = self.hosts.len();
        for round in 0..rounds {
            let ping = Release::new(round, 0, PING, &[])?;
            for h in &mut self.hosts {
                h.release.send_bytes(ping.as_bytes())?;
                if let Err(e) = h.wake.notify() {
                    tracing::debug!("wake-up not sent: {e:?}");
                }
            }
            let mut answered = 0;
            while answered < self.hosts.len() && std::time::Instant::now() < until {
                let received = self.notices.sub.receive(&mut |sample| {
                    if let Ok(batch) = Done::batch(sample) {
                        answered += batch
                            .filter(|d| d.component.get() == PING && d.tick.get() == round)
                            .count();
                    }
                });
                if !matches!(received, Ok(true)) {
                    std::thread::sleep(core::time::Duration::from_micros(100));
                }
            }
            silent = self.hosts.len() - answered;
        }
        Ok(silent)
    }

    /// Host `host` was restarted: the releases its components had running died with the old
    /// process and will never report done. They are dropped, so each component is released
    /// again at its next due tick (its outputs held meanwhile). Returns how many were dropped.
    pub fn host_restarted(&mut self, host: &str) -> usize {
        let Some(h) = self.hosts.iter().position(|x| x.name == host) else {
            return 0;
        };
        let mut dropped = 0;
        for (c, comp) in self
            .comps
            .iter_mut()
            .enumerate()
            .filter(|(_, c)| c.host == h)
        {
            if let Some(m) = comp.pending.take() {
                comp.failed += 1;
                dropped += 1;
                let name = &self.spec.components[c].name;
                self.replay_log.late(m, log_generation(&self.spec, c), name);
            }
        }
        self.replay_log.restart(self.tick, host);
        if dropped > 0 {
            tracing::warn!("host {host} restarted: {dropped} release(s) lost with it");
        }
        dropped
    }

    /// Ticks run so far.
    pub fn ticks(&self) -> u64 {
        self.tick
    }

    /// Why the grid faulted, if it did.
    pub fn fault(&self) -> Option<&str> {
        self.fault.as_deref()
    }

    /// Waits for the next tick of `source` and runs it.
    ///
    /// A late wake-up that finds several ticks elapsed runs one logical tick and counts the
    /// others as missed: the grid never runs ticks back to back to catch up, which would give
    /// the components no time. The tick error is the lateness of the wake-up.
    pub fn step(&mut self, source: &mut dyn TickSource) -> std::io::Result<()> {
        let elapsed = source.wait()?;
        let now = source.now_ns();
        self.timing
            .woke(self.tick, elapsed, now, |k| source.due_ns(k));
        self.run_tick(now)
    }

    /// Runs tick `self.tick` (the clock says `now_ns`).
    pub fn run_tick(&mut self, now_ns: u64) -> std::io::Result<()> {
        let n = self.tick;
        self.take_done(n);
        self.await_due(n);
        for (c, comp) in self.comps.iter_mut().enumerate() {
            comp.take_ready(n);
            self.versions[c] = comp.valid_from;
        }
        if let Some(inc) = self.incoming.as_mut() {
            inc.comps.iter_mut().for_each(|c| c.take_ready(n));
        }
        // Over the running assembly's versions valid at n, before a switch at n.
        self.tick_hash = tick_hash(&self.comps);
        if let Some(rec) = self.recorder.as_mut() {
            rec.tick(n, &self.versions, self.tick_hash)?;
        }
        if self
            .incoming
            .as_ref()
            .is_some_and(|i| i.failure.is_none() && i.schedule.is_some_and(|(_, at)| at == n))
        {
            self.switch(n);
        }
        self.release_due(n, now_ns);
        self.release_incoming(n, now_ns);
        self.hand_over_after_tick(n + 1);
        self.wake_hosts();
        self.tick += 1;
        Ok(())
    }

    /// Between ticks, while the grid waits (in lockstep, for an assembly being prepared):
    /// takes the done notices that arrived (warm-up answers, hosts ready) and wakes the hosts
    /// that were sent something.
    pub fn between_ticks(&mut self) {
        self.take_done(self.tick);
        self.hand_over_between_ticks();
        self.wake_hosts();
    }

    /// Sends every host the batch of releases it was given since, and wakes it: one sample
    /// and one wake-up per host and tick.
    fn wake_hosts(&mut self) {
        let incoming = self.incoming.as_mut().map(|i| i.hosts.iter_mut());
        for h in self.hosts.iter_mut().chain(incoming.into_iter().flatten()) {
            if h.batch.is_empty() {
                continue;
            }
            let sent = h.release.send_bytes(&h.batch);
            h.batch.clear();
            if let Err(e) = sent {
                tracing::warn!("releases not sent to host {}: {e}", h.name);
                continue;
            }
            if let Err(e) = h.wake.notify() {
                tracing::debug!("wake-up not sent: {e:?}");
            }
        }
    }

    fn take_done(&mut self, n: u64) {
        let base = self.base();
        let current = self.spec.generation();
        loop {
            // Copied out of the sample (no allocation: a sample holds at most
            // `wire::DONE_BATCH` notices), so the sample goes back before they are taken.
            let mut scratch = std::mem::take(&mut self.notices.scratch);
            scratch.clear();
            let mut malformed = None;
            let received = self
                .notices
                .sub
                .receive(&mut |sample| match Done::batch(sample) {
                    Ok(batch) => scratch.extend(batch.copied()),
                    Err(e) => malformed = Some(e),
                });
            if let Some(e) = malformed.filter(|_| !self.malformed_done) {
                // A host of another build (the notice's size changed): it looks like a hang
                // otherwise.
                self.malformed_done = true;
                tracing::warn!(
                    "a malformed done sample is dropped ({e}): is a host of another build running?"
                );
            }
            for done in &scratch {
                self.take_one_done(n, base, current, done);
            }
            self.notices.scratch = scratch;
            if !matches!(received, Ok(true)) {
                break;
            }
        }
    }

    /// Takes one done notice at tick `n`.
    fn take_one_done(&mut self, n: u64, base: usize, current: Generation, done: &Done) {
        let (c, g) = (done.component.get(), Generation(done.generation.get()));
        if c == SUCCESSOR {
            return self.successor_offered(done, current);
        }
        if c == UPGRADE {
            return self.upgrade_answered(done);
        }
        let inc = self.incoming.as_mut().filter(|i| i.spec.generation() == g);
        if c == PING || c == READY {
            if let Some(inc) = inc {
                if c == READY && done.status.get() == Done::OK {
                    inc.ready += 1;
                } else if c == READY {
                    inc.fail(
                        "a host of the system's components could not load it (see its log)".into(),
                    );
                } else if let Some(a) = inc.answered.get_mut(done.tick.get() as usize) {
                    *a = true;
                }
            }
            return;
        }
        let c = usize::from(c);
        let (comp, spec, incoming) = if c < base || g == current {
            match self.comps.get_mut(c) {
                Some(comp) => (comp, &self.spec, false),
                None => return,
            }
        } else if let Some(inc) = inc {
            match inc.comps.get_mut(c) {
                Some(comp) => (comp, &inc.spec, true),
                None => return,
            }
        } else {
            return; // a replaced assembly's
        };
        let m = done.tick.get();
        if comp.pending != Some(m) {
            return;
        }
        comp.pending = None;
        comp.holding = done.has(Done::HOLDING);
        let held_release = std::mem::take(&mut comp.held_release);
        comp.exec.record(done.exec_ns.get());
        comp.exec_min = comp.exec_min.min(done.exec_ns.get());
        comp.latency.record(done.latency_ns.get());
        let status = done.status.get();
        if status == Done::STALE {
            comp.stale += 1;
            if self.replay_log.on() {
                let name = &spec.components[c].name;
                self.replay_log.stale(m, log_generation(spec, c), name);
            }
            // Kept for the trace's end only: without a trace, nothing grows with the misses.
            if !incoming && self.recorder.is_some() && c < recorder::recorded(spec) {
                self.overrun_log.push((m, c, m, Miss::Stale));
            }
        } else if status != Done::OK && status != Done::UNSAFE {
            comp.failed += 1;
            if self.replay_log.on() {
                let name = &spec.components[c].name;
                self.replay_log.late(m, log_generation(spec, c), name);
            }
        } else if n <= m + comp.period {
            comp.ready = Some(m + comp.period);
            comp.ready_hash = done.hash();
        } else {
            comp.late += 1;
            if self.replay_log.on() {
                let name = &spec.components[c].name;
                self.replay_log.late(m, log_generation(spec, c), name);
            }
        }
        // A component that tracked while the robot was held does not fault its assembly:
        // the robot is stopped already, and what it saw was not the assembly's doing.
        if status == Done::UNSAFE && !held_release {
            let name = &spec.components[c].name;
            let why = format!("component {name} reports an unsafe state at tick {m}");
            if incoming {
                if let Some(inc) = self.incoming.as_mut() {
                    inc.fail(why);
                }
            } else if self.fault.is_none() {
                self.set_fault(why);
                self.replay_log.fault(n, 0);
            }
        }
    }

    fn set_fault(&mut self, why: String) {
        let why = match &self.spec.assembly {
            Some(a) => format!(
                "assembly {} faulted: {why}; the bus stops the drives",
                a.name
            ),
            None => format!("{why}; the grid stops releasing"),
        };
        tracing::error!("{why}");
        self.fault = Some(why);
    }

    /// The number of the system's own components, which run whatever the assembly (0 without
    /// assemblies: a fault then stops every component).
    fn base(&self) -> usize {
        self.spec.assembly.as_ref().map_or(0, |a| a.base)
    }

    /// No release is under way: every component released (the running assembly's and an
    /// incoming one's) has sent its done notice. A gated grid is held once it is quiet.
    pub fn quiet(&self) -> bool {
        let idle = |c: &Comp| c.pending.is_none();
        self.comps.iter().all(idle)
            && self
                .incoming
                .as_ref()
                .is_none_or(|i| i.comps.iter().all(idle))
    }

    /// Whether a component due at `n` (of the running assembly unless it faulted — it is not
    /// released then —, or of the incoming one once it runs alongside) still runs its
    /// previous release.
    fn due_pending(&self, n: u64) -> bool {
        let late = |c: &Comp| n.is_multiple_of(c.period) && c.pending.is_some();
        let awaited = if self.fault.is_some() {
            self.base()
        } else {
            self.comps.len()
        };
        self.comps[..awaited].iter().any(late)
            || self
                .incoming
                .as_ref()
                .is_some_and(|i| i.schedule.is_some() && i.comps.iter().any(late))
    }

    /// Waits for the done notices of components due at `n` whose release still runs: in real
    /// time for the grace (spinning for `spin_us` of it, then asleep on the done wake-up, never
    /// keeping a core from the hosts), in lockstep until they are done.
    fn await_due(&mut self, n: u64) {
        let lockstep = self.spec.timing.clock == GridClock::Lockstep;
        if (!lockstep && self.notices.grace_ns == 0) || !self.due_pending(n) {
            return;
        }
        let start = std::time::Instant::now();
        let budget = if lockstep {
            LOCKSTEP_STUCK
        } else {
            core::time::Duration::from_nanos(self.notices.grace_ns)
        };
        let spin = core::time::Duration::from_micros(self.spec.timing.spin_us).min(budget);
        while start.elapsed() < spin {
            core::hint::spin_loop();
            self.take_done(n);
            if !self.due_pending(n) {
                return;
            }
        }
        loop {
            // Taken before looking: a done notice sent after this wakes the wait below.
            self.notices.wake.drain();
            self.take_done(n);
            if !self.due_pending(n) {
                return;
            }
            let left = budget.saturating_sub(start.elapsed());
            if left.is_zero() || self.notices.shutdown.requested() {
                if lockstep && left.is_zero() {
                    tracing::error!(
                        "lockstep: a release due at tick {n} is not done after {} s (a host \
                         stopped or died): counted as an overrun",
                        LOCKSTEP_STUCK.as_secs()
                    );
                }
                return;
            }
            // In lockstep, look at the termination flag now and then.
            let slice = if lockstep {
                left.min(core::time::Duration::from_millis(100))
            } else {
                left
            };
            self.notices.wake.wait(Some(slice));
        }
    }

    fn release_due(&mut self, n: u64, now_ns: u64) {
        let base = self.base();
        let generation = self.spec.generation();
        let mut versions = [0u64; MAX_SOURCES];
        // The robot is held (the bus in safe stop or being reset): the running assembly's
        // components track, to take over from where the robot is when it follows again.
        let held = self.comps[..base.min(self.comps.len())]
            .iter()
            .any(|c| c.holding);
        self.replay_log.held(n, held);
        for c in 0..self.comps.len() {
            let comp = &self.comps[c];
            if !n.is_multiple_of(comp.period) || (self.fault.is_some() && c >= base) {
                continue;
            }
            if let Some(m) = comp.pending.filter(|_| !comp.queues) {
                let comp = &mut self.comps[c];
                comp.overruns += 1;
                comp.in_a_row += 1;
                if self.recorder.is_some() && c < recorder::recorded(&self.spec) {
                    self.overrun_log.push((n, c, m, Miss::Overrun));
                }
                if self.replay_log.on() {
                    let name = &self.spec.components[c].name;
                    let g = log_generation(&self.spec, c);
                    self.replay_log.overrun(n, g, name, m);
                }
                if comp.fault_policy && comp.in_a_row >= FAULT_AFTER && self.fault.is_none() {
                    let name = &self.spec.components[c].name;
                    let why = format!(
                        "component {name} overran its deadline at tick {n} (released at {m})"
                    );
                    self.set_fault(why);
                    self.replay_log.fault(n, c);
                    if base == 0 {
                        return;
                    }
                }
                continue;
            }
            self.comps[c].in_a_row = 0;
            for (slot, &s) in versions.iter_mut().zip(&self.comps[c].sources) {
                *slot = self.comps[s].valid_from;
            }
            let flags = if self.fault.is_some() {
                Release::SAFE_STOP
            } else if held && c >= base {
                Release::TRACK | Release::HELD
            } else {
                0
            };
            self.comps[c].held_release = flags & Release::HELD != 0;
            let at = ReleaseAt {
                n,
                now_ns,
                generation,
                flags,
                state_hash: self.tick_hash,
            };
            release(&mut self.comps[c], c, &at, &versions, &mut self.hosts);
        }
    }

    /// Tells every host the grid stops (a normal stop): no release follows. The bus then stops
    /// the drives without taking the silence for a lost coordinator.
    pub fn announce_stop(&mut self) {
        let Ok(notice) = Release::new(self.tick, 0, STOPPING, &[]) else {
            return;
        };
        for h in &mut self.hosts {
            send_release(h, &notice);
        }
        self.wake_hosts();
    }

    /// The grid as it runs now.
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Waits up to `timeout_ns` (by `now`) for the releases still running, then takes their
    /// done notices; returns how many are still pending.
    pub fn drain(&mut self, now: &dyn Fn() -> u64, timeout_ns: u64) -> usize {
        let until = now() + timeout_ns;
        loop {
            self.take_done(self.tick);
            let pending = self.comps.iter().filter(|c| c.pending.is_some()).count();
            if pending == 0 || now() >= until {
                return pending;
            }
            std::thread::sleep(core::time::Duration::from_micros(200));
        }
    }

    /// Encodes the ledger as it stands into `out` (cleared first), as [`ledger::encode`] does
    /// with [`Coordinator::ledger`]'s rows, without allocating once `out` and the state text
    /// have the room: the tick thread does this every few hundred milliseconds.
    pub fn encode_ledger(&mut self, done: bool, out: &mut Vec<u8>) {
        out.clear();
        let state = match (&self.fault, done) {
            (Some(_), _) => "faulted",
            (None, true) => "done",
            (None, false) => "running",
        };
        self.state_text.clear();
        self.state_text.push_str(state);
        if self.spec.timing.clock == GridClock::Lockstep {
            self.state_text.push_str(" in lockstep");
        }
        use std::fmt::Write as _;
        if let Some(a) = &self.spec.assembly {
            let _ = write!(
                self.state_text,
                " (assembly {}, generation {})",
                a.name, a.generation
            );
        }
        if let Some(tick) = self.held_before {
            let _ = write!(self.state_text, ", held by the gate before tick {tick}");
        }
        let (p50, p99, max) = ledger::p50_p99_max(self.timing.error());
        ledger::encode_grid(
            out,
            &self.state_text,
            self.fault.as_deref().unwrap_or_default(),
            [self.tick, self.timing.missed()],
            self.timing.rate(),
            [p50, p99, max],
        );
        for (c, s) in self.comps.iter().zip(&self.spec.components) {
            let (e50, e99, emax) = ledger::p50_p99_max(&c.exec);
            let (l50, l99, _) = ledger::p50_p99_max(&c.latency);
            ledger::encode_component(
                out,
                [&s.name, &s.host],
                c.period,
                if c.fault_policy { "fault" } else { "hold" },
                [
                    c.releases,
                    c.overruns,
                    c.late,
                    c.failed,
                    c.stale,
                    if c.exec.count() == 0 { 0 } else { c.exec_min },
                    e50,
                    e99,
                    emax,
                    l50,
                    l99,
                ],
            );
        }
    }

    /// The ledger as it stands, as rows (what [`Coordinator::encode_ledger`] encodes).
    pub fn ledger(&mut self, done: bool) -> (GridRow, Vec<ComponentRow>) {
        let mut bytes = Vec::new();
        self.encode_ledger(done, &mut bytes);
        // The encoding above is the decoder's own format: it always reads back.
        ledger::decode(&bytes).unwrap_or_default()
    }

    /// Ends the run: the recorder's trace is flushed, with a line per overrun at its end
    /// (`# overrun tick=T component=C release=M`), and the replay log; returns the versions
    /// the trace could not find.
    pub fn finish(mut self) -> std::io::Result<u64> {
        self.replay_log.end(self.tick);
        self.replay_log.finish();
        match self.recorder {
            Some(rec) => {
                let missing = rec.missing;
                let mut out = rec.finish()?;
                for &(t, c, m, miss) in &self.overrun_log {
                    let Some(name) = self.spec.components.get(c).map(|x| &x.name) else {
                        continue;
                    };
                    match miss {
                        Miss::Overrun => {
                            writeln!(out, "# overrun tick={t} component={name} release={m}")?
                        }
                        Miss::Stale => writeln!(out, "# stale tick={t} component={name}")?,
                    }
                }
                out.flush()?;
                Ok(missing)
            }
            None => Ok(0),
        }
    }
}

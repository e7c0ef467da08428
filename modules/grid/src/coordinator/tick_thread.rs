//! The tick thread: the only thread that keeps time. It runs the coordinator's tick and a
//! few commands from the service thread between ticks, each bounded to microseconds: it never
//! opens a port, loads a file, calls a module or reads the directory (that is the service
//! thread's work, see [`super::service`]).

use std::sync::mpsc::{Receiver, SyncSender, TryRecvError};
use std::time::{Duration, Instant};

use super::gate::Setting;
use super::{BeginSwitchError, Coordinator, HostLink, SwitchState};
use modbot_core::clock::{Clock, MonotonicClock};
use modbot_core::signals::Shutdown;
use modbot_grid::ledger;
use modbot_grid::tick::{FreeTicks, TickSource, TimerTicks};
use modbot_grid::{GridClock, GridSpec};

pub type Coord = Coordinator<modbot_grid::offload::Offload<std::fs::File>>;

/// Ticks between the announcement and the earliest switch, beyond two longest periods.
const SWITCH_LEAD: u64 = 5;
/// Commands taken between two ticks at most.
const COMMANDS_PER_TICK: usize = 4;

/// What the service thread asks of the tick thread.
pub enum ToTick {
    /// Prepare this assembly (a grid of a new generation): its links follow one by one.
    Begin(Box<GridSpec>),
    /// The link to the next host of the assembly being prepared.
    Link(Box<HostLink>),
    /// Send a warm-up release to the prepared hosts that have not answered one.
    Ping,
    /// The assembly is prepared: announce its switch.
    Announce,
    /// Give the assembly being prepared up.
    Abort,
    /// The host's process was restarted.
    HostRestarted(String),
    /// The scripted switch due now could not be asked for: go on.
    ScriptRefused,
    /// The scripted upgrade due now was refused: go on.
    UpgradeRefused,
    /// Hold the grid before this tick (lockstep), or run free; answered by
    /// [`FromTick::Held`].
    Gate(Setting),
}

/// What the tick thread tells the service thread.
pub enum FromTick {
    /// The tick count, every few milliseconds.
    Ticks(u64),
    /// The ledger, encoded, every 200 ms and at the end.
    Ledger(Vec<u8>),
    /// The switch's state changed (with why an incoming assembly fails, once known).
    State(SwitchState, Option<String>),
    /// The answer to [`ToTick::Begin`].
    Began(Result<(), BeginSwitchError>),
    /// The answer to [`ToTick::Announce`]: the tick of the switch.
    Announced(Option<u64>),
    /// An assembly took over: generation, announced tick, actual tick.
    Switched(u16, u64, u64),
    /// Host modules no longer served (the old assembly's, or an aborted one's).
    Retire(Vec<String>),
    /// Links no longer used, to be dropped off the tick thread (unmapping takes milliseconds).
    Drop(Vec<HostLink>),
    /// The hosts and their modules, at the start and after each switch.
    Hosts(Vec<(String, String)>),
    /// The running assembly: name and generation.
    Current(String, u16),
    /// The grid stopped: after the requested number of ticks (true), or on a signal; and
    /// why a run of `--ticks N` failed (the grid faulted, or it stopped before N).
    Ended(bool, Option<String>),
    /// The tick thread failed.
    Failed(String),
    /// A scripted switch to this assembly is due (`--switch TICK:NAME`).
    Script(String),
    /// A scripted live upgrade of this host is due (`--upgrade TICK:HOST`).
    Upgrade(String),
    /// The gate of setting `seq` holds the grid before tick `next`, every release done.
    Held { seq: u32, next: u64 },
}

/// How the tick thread runs.
pub struct Run {
    /// Ledger buffers the service thread is done with, to be filled again.
    pub spare: Receiver<Vec<u8>>,
    pub period_ns: u64,
    /// Stop after this many ticks.
    pub max_ticks: Option<u64>,
    /// Switches to ask for at ticks: (tick, assembly).
    pub script: Vec<(u64, String)>,
    /// Live upgrades of hosts to ask for at ticks: (tick, host).
    pub upgrades: Vec<(u64, String)>,
    /// The gate from the start (`--gate`).
    pub gate: Option<Setting>,
    /// Ends the run when requested.
    pub shutdown: Shutdown,
}

/// Runs the grid until a termination signal or `max_ticks`; tells `out` what happens.
pub fn run(mut coord: Coord, run: Run, commands: Receiver<ToTick>, out: SyncSender<FromTick>) {
    modbot_core::realtime::real_time_thread(coord.spec().priority, "tick thread");
    let shutdown = run.shutdown.clone();
    let wanted = run.max_ticks;
    if let Err(e) = tick(&mut coord, run, &commands, &out) {
        let _ = out.send(FromTick::Failed(e.to_string()));
        return;
    }
    let pending = coord.drain(&|| MonotonicClock.now_ns(), 200_000_000);
    coord.announce_stop();
    let _ = out.send(FromTick::Ledger(encoded_ledger(&mut coord, true)));
    let failed = wanted.and_then(|n| run_failure(n, coord.ticks(), coord.fault()));
    let (g, rows) = coord.ledger(true);
    println!("{}", ledger::render(&g, &rows));
    if pending > 0 {
        println!("{pending} release(s) still running at the end");
    }
    match coord.finish() {
        Ok(missing) if missing > 0 => {
            tracing::warn!("{missing} output version(s) were missing from the trace")
        }
        Ok(_) => {}
        Err(e) => {
            let _ = out.send(FromTick::Failed(format!("the trace: {e}")));
            return;
        }
    }
    let reached = !shutdown.requested();
    let _ = out.send(FromTick::Ended(reached, failed));
}

/// Why a run of `wanted` ticks failed, if it did: the grid faulted (`fault`), or it stopped
/// at tick `ran` before the `wanted` (a stop was asked for).
fn run_failure(wanted: u64, ran: u64, fault: Option<&str>) -> Option<String> {
    match fault {
        Some(why) => Some(format!(
            "the grid faulted, so the run of {wanted} ticks failed: {why}"
        )),
        None if ran < wanted => Some(format!(
            "the run stopped at tick {ran} of the {wanted} it was to run"
        )),
        None => None,
    }
}

#[cfg(test)]
mod tests {
    use super::run_failure;

    #[test]
    fn a_run_of_n_ticks_fails_when_the_grid_faulted_or_it_stopped_short() {
        assert_eq!(run_failure(120, 120, None), None);
        assert_eq!(
            run_failure(120, 90, None).as_deref(),
            Some("the run stopped at tick 90 of the 120 it was to run")
        );
        let faulted = run_failure(120, 120, Some("component stair failed at tick 90")).unwrap();
        assert!(faulted.starts_with("the grid faulted"), "{faulted}");
        assert!(
            faulted.ends_with("component stair failed at tick 90"),
            "{faulted}"
        );
    }
}

/// Where a scripted switch (or upgrade) stands on the tick thread.
#[derive(Default)]
struct Script {
    /// (tick, assembly or host), the next first.
    due: std::collections::VecDeque<(u64, String)>,
    /// A scripted switch was asked for and has not begun (an upgrade: its new process has not
    /// taken over): in lockstep the grid waits.
    awaiting: bool,
}

fn tick(
    coord: &mut Coord,
    run: Run,
    commands: &Receiver<ToTick>,
    out: &SyncSender<FromTick>,
) -> anyhow::Result<()> {
    let Run {
        spare,
        period_ns,
        max_ticks,
        mut script,
        mut upgrades,
        gate,
        shutdown,
    } = run;
    upgrades.sort_by_key(|u| u.0);
    let mut upgrade = Script {
        due: upgrades.into(),
        awaiting: false,
    };
    let mut handovers = coord.handovers();
    let mut gate = Gated {
        setting: gate,
        reported: None,
    };
    script.sort_by_key(|s| s.0);
    let mut script = Script {
        due: script.into(),
        awaiting: false,
    };
    let lockstep = coord.spec().timing.clock == GridClock::Lockstep;
    let silent = coord.warm_up(20, Duration::from_secs(10))?;
    anyhow::ensure!(
        silent == 0,
        "{silent} host(s) did not answer the warm-up releases"
    );
    if lockstep {
        tracing::info!(
            "{} host(s) ready: ticking in lockstep (base period {} us, as fast as they go)",
            coord.spec().hosts().len(),
            period_ns / 1000
        );
    } else {
        tracing::info!(
            "{} host(s) ready: ticking every {} us",
            coord.spec().hosts().len(),
            period_ns / 1000
        );
    }
    tell(out, hosts_of(coord));
    tell(out, current_of(coord));
    let mut ticks: Box<dyn TickSource> = if lockstep {
        Box::new(FreeTicks)
    } else {
        Box::new(TimerTicks::new(period_ns, shutdown.clone())?)
    };
    let mut reported = Reported::default();
    let mut last_ticks = Instant::now();
    let mut last_ledger = Instant::now();
    while !shutdown.requested() && max_ticks.is_none_or(|n| coord.ticks() < n) {
        if script.due.front().is_some_and(|s| s.0 <= coord.ticks()) && !script.awaiting {
            if let Some((_, name)) = script.due.pop_front() {
                script.awaiting = true;
                tell(out, FromTick::Script(name));
            }
        }
        if script.awaiting && coord.switch_state() != SwitchState::Idle {
            script.awaiting = false;
        }
        // A scripted upgrade: in lockstep the grid waits at its tick until the host's new
        // process has taken over (there, between ticks), so the run is reproducible.
        if upgrade.due.front().is_some_and(|u| u.0 <= coord.ticks()) && !upgrade.awaiting {
            if let Some((_, host)) = upgrade.due.pop_front() {
                upgrade.awaiting = true;
                handovers = coord.handovers();
                tell(out, FromTick::Upgrade(host));
            }
        }
        if upgrade.awaiting && coord.handovers() != handovers {
            upgrade.awaiting = false;
        }
        // In lockstep the grid waits while an assembly is prepared: the tick of the switch
        // then depends on the tick it was asked for alone.
        // And before the gate's tick, until its owner moves it (see `gate`).
        let gated = lockstep && gate.closed(coord.ticks());
        let hold = lockstep
            && (script.awaiting
                || upgrade.awaiting
                || gated
                || matches!(coord.switch_state(), SwitchState::Preparing { .. }));
        if gated {
            gate.report(coord, out);
        }
        if hold {
            coord.between_ticks();
            std::thread::sleep(Duration::from_micros(200));
        } else {
            match coord.step(ticks.as_mut()) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => break,
                Err(e) => return Err(e.into()),
            }
        }
        for _ in 0..COMMANDS_PER_TICK {
            match commands.try_recv() {
                Ok(ToTick::ScriptRefused) => script.awaiting = false,
                Ok(ToTick::UpgradeRefused) => upgrade.awaiting = false,
                Ok(ToTick::Gate(setting)) => {
                    gate.setting = Some(setting);
                    coord.set_held_before(None);
                }
                Ok(ToTick::Abort) => {
                    script.awaiting = false;
                    obey(coord, ToTick::Abort, out);
                }
                Ok(command) => obey(coord, command, out),
                Err(TryRecvError::Empty) => break,
                // The service thread is gone: the process is ending.
                Err(TryRecvError::Disconnected) => return Ok(()),
            }
        }
        reported.report(coord, out);
        if last_ticks.elapsed() >= Duration::from_millis(5) {
            last_ticks = Instant::now();
            tell(out, FromTick::Ticks(coord.ticks()));
        }
        if last_ledger.elapsed() >= Duration::from_millis(200) {
            last_ledger = Instant::now();
            tell(out, FromTick::Ledger(recycled_ledger(coord, &spare)));
        }
    }
    Ok(())
}

fn obey(coord: &mut Coord, command: ToTick, out: &SyncSender<FromTick>) {
    match command {
        ToTick::Begin(spec) => tell(out, FromTick::Began(coord.begin_switch(*spec))),
        ToTick::Link(link) => {
            if coord.add_incoming_link(link).is_err() {
                tracing::debug!("a link for an assembly no longer prepared is dropped");
            }
        }
        ToTick::Ping => coord.ping_incoming(),
        ToTick::Announce => tell(out, FromTick::Announced(coord.announce(SWITCH_LEAD))),
        ToTick::Abort => {
            let hosts = coord.abort_switch();
            if !hosts.is_empty() {
                tell(out, FromTick::Retire(hosts));
            }
            let links = coord.take_retired_links();
            if !links.is_empty() {
                tell(out, FromTick::Drop(links));
            }
        }
        ToTick::HostRestarted(host) => {
            coord.host_restarted(&host);
        }
        ToTick::ScriptRefused | ToTick::UpgradeRefused | ToTick::Gate(_) => {}
    }
}

/// The gate on the tick thread: its setting, and the setting it said was held.
struct Gated {
    setting: Option<Setting>,
    reported: Option<u32>,
}

impl Gated {
    /// Whether the grid must wait before tick `ticks`.
    fn closed(&self, ticks: u64) -> bool {
        self.setting
            .is_some_and(|s| s.until.is_some_and(|until| ticks >= until))
    }

    /// Says once per setting that the grid is held: every release before the gate done.
    fn report(&mut self, coord: &mut Coord, out: &SyncSender<FromTick>) {
        let Some(setting) = self.setting else {
            return;
        };
        if self.reported != Some(setting.seq) && coord.quiet() {
            self.reported = Some(setting.seq);
            coord.set_held_before(Some(coord.ticks()));
            tell(
                out,
                FromTick::Held {
                    seq: setting.seq,
                    next: coord.ticks(),
                },
            );
        }
    }
}

/// What the service thread was last told, so only changes are sent.
#[derive(Default)]
struct Reported {
    state: Option<SwitchState>,
    failure: Option<String>,
    switches: usize,
}

impl Reported {
    fn report(&mut self, coord: &mut Coord, out: &SyncSender<FromTick>) {
        let retired = coord.take_retired();
        if !retired.is_empty() {
            tell(out, FromTick::Retire(retired));
        }
        let links = coord.take_retired_links();
        if !links.is_empty() {
            tell(out, FromTick::Drop(links));
        }
        let state = coord.switch_state();
        if self.state.as_ref() != Some(&state) || self.failure.as_deref() != coord.switch_failure()
        {
            self.failure = coord.switch_failure().map(str::to_owned);
            self.state = Some(state.clone());
            tell(out, FromTick::State(state, self.failure.clone()));
        }
        if coord.switches().len() > self.switches {
            for (generation, _, announced, at) in &coord.switches()[self.switches..] {
                tell(out, FromTick::Switched(generation.0, *announced, *at));
            }
            self.switches = coord.switches().len();
            tell(out, hosts_of(coord));
            tell(out, current_of(coord));
        }
    }
}

fn hosts_of(coord: &Coord) -> FromTick {
    let spec = coord.spec();
    FromTick::Hosts(
        spec.hosts()
            .into_iter()
            .map(|h| {
                let module = spec.host_module(&h);
                (h, module)
            })
            .collect(),
    )
}

fn current_of(coord: &Coord) -> FromTick {
    match &coord.spec().assembly {
        Some(a) => FromTick::Current(a.name.clone(), a.generation.0),
        None => FromTick::Current("none".into(), 0),
    }
}

fn encoded_ledger(coord: &mut Coord, done: bool) -> Vec<u8> {
    let mut bytes = Vec::new();
    coord.encode_ledger(done, &mut bytes);
    bytes
}

/// Encodes the ledger into a buffer the service thread gave back (allocating only while it
/// has given none back yet, or when the ledger outgrew it).
fn recycled_ledger(coord: &mut Coord, spare: &Receiver<Vec<u8>>) -> Vec<u8> {
    let mut bytes = spare.try_recv().unwrap_or_default();
    coord.encode_ledger(false, &mut bytes);
    bytes
}

/// Sends without ever blocking the tick: the channel is bounded, and a full one (the service
/// thread stalled for a long time) loses the message, which is logged.
fn tell(out: &SyncSender<FromTick>, message: FromTick) {
    if let Err(std::sync::mpsc::TrySendError::Full(_)) = out.try_send(message) {
        tracing::warn!("the service thread is behind: a message from the tick thread was lost");
    }
}

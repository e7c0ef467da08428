//! The process `modbot-coordinator`: the time grid's clock — releases components, collects
//! their done notices, keeps the overrun ledger and, on request, a trace of every output.
//!
//! This is its service thread (back to normal scheduling once the grid runs): it serves the
//! module's methods, reads the directory, calls the supervisor and drives assembly switches
//! (`switch_job`); the tick thread (`tick_thread`) runs the grid.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use modbot_core::transport::channels::Channels;
use modbot_core::{
    signals, CallError, CallHandle, CallOptions, Ctx, MethodError, Module, ModuleBuilder, Reply,
};
use modbot_grid::offload::Offload;
use modbot_ipc_schema::{switch, Args, Value};
use modbot_modules::common::{init_logging, ModuleArgs};

use super::gate::{Gate, GateRefused, Owner};
use super::shared::Shared;
use super::switch_job::Switching;
use super::tick_thread::{self as ticker, FromTick, ToTick};
use super::upgrade_job::UpgradeJob;
use super::Coordinator;
use crate::grid_args::GridArgs;

/// The coordinator: the only process of a system that reads the clock. The supervisor starts it
/// when the system description has a grid.
///
/// Methods: `ledger()` → the overrun ledger (see `modbot top`); with assemblies,
/// `switch(name)` → the generation the assembly gets (prepared while the current one runs,
/// then switched at an announced tick), and `assembly()` → where the assemblies stand (see
/// `modbot assembly`; both answers are in the format of `modbot_ipc_schema::switch`). In
/// lockstep, `gate([until])` → `next` (i64), `held` (bool) and `ungate()`: the gate a robot
/// program steps the grid with (see `gate`).
#[derive(Debug, clap::Parser)]
#[command(name = "modbot-coordinator", version)]
pub struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    #[command(flatten)]
    grid: GridArgs,
    /// Run this many base ticks, then stop the system.
    #[arg(long)]
    ticks: Option<u64>,
    /// Write every output at every tick to this file.
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Write the grid's state hash into the trace every N ticks and after the last (0:
    /// never).
    #[arg(long, value_name = "N", default_value_t = modbot_grid::trace::STATE_HASH_EVERY)]
    state_hash_every: u64,
    /// Write the run's schedule for a replay to this file: switches, held ranges, faults,
    /// overruns and stale releases (`modbot up --replayable`).
    #[arg(long, value_name = "FILE")]
    replay_log: Option<PathBuf>,
    /// Switch to assembly NAME at tick TICK (`TICK:NAME`; repeatable). In lockstep the grid
    /// waits at that tick while the assembly is prepared, so the run is reproducible.
    #[arg(long = "switch", value_name = "TICK:NAME", value_parser = modbot_grid::switch::parse_scripted)]
    switches: Vec<(u64, String)>,
    /// Upgrade host HOST of the running assembly live at tick TICK (`TICK:HOST`; repeatable):
    /// a new process takes its components over, their state carried. In lockstep the grid
    /// waits at that tick until it has.
    #[arg(long = "upgrade", value_name = "TICK:HOST", value_parser = modbot_grid::switch::parse_scripted)]
    upgrades: Vec<(u64, String)>,
    /// In lockstep, hold the grid before tick TICK until a robot program takes the gate and
    /// steps it (`gate(until)`); lifted by itself after 20 s without one.
    #[arg(long, value_name = "TICK")]
    gate: Option<u64>,
}

fn switch_method(
    s: &mut Shared,
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let generation = request_switch(s, args.text(0)?)?;
    reply.push(switch::generation_value(generation));
    Ok(())
}

/// Asks for a switch to assembly `name` (the `switch` method, or a scripted `--switch`);
/// returns the generation it gets.
fn request_switch(s: &mut Shared, name: &str) -> Result<u16, MethodError> {
    if !s.assemblies {
        return Err(MethodError::Failed(
            "this grid has no assemblies: declare grid { assemblies = \"DIR\", assembly = \"NAME\" }".into(),
        ));
    }
    modbot_grid::switch::check_assembly_name(name)
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    if s.busy {
        return Err(MethodError::Busy(
            "an assembly is being prepared; switch again when it is done".into(),
        ));
    }
    let generation = s.next_generation;
    s.next_generation = s.next_generation.checked_add(1).ok_or_else(|| {
        MethodError::Failed("this run has used every assembly generation (65535)".into())
    })?;
    s.requested = Some((name.to_owned(), generation));
    s.busy = true;
    Ok(generation)
}

/// `gate([until [, pid]])` takes the gate (or asks where it stands) and, with `until` ≥ 0,
/// moves it: answers the tick the grid holds before and whether it is held there (every
/// release before it done). `pid`: the caller's process, from a caller the directory does not
/// list (a tool, as `modbot program run` is), so the gate lifts when that process ends.
fn gate_method(
    s: &mut Shared,
    ctx: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let refused = |e: GateRefused| match e {
        GateRefused::Owned { .. } => MethodError::Busy(e.to_string()),
        _ => MethodError::Failed(e.to_string()),
    };
    if !s.lockstep {
        return Err(refused(GateRefused::RealTime));
    }
    let until = match args.len() {
        0 => None,
        _ => u64::try_from(args.i64(0)?).ok(),
    };
    let declared = match args.len() {
        0 | 1 => None,
        _ => Some(u32::try_from(args.i64(1)?).map_err(|_| {
            MethodError::Failed("the caller's pid must be a positive 32-bit number".into())
        })?),
    };
    let caller = caller_of(ctx, declared);
    let now = ctx.now_ns();
    let book = ctx.phone_book();
    let (answer, changed) = s
        .gate
        .call(caller, until, s.ticks, now, |o| owner_name(book, o))
        .map_err(refused)?;
    let lifted = s.gate.take_lifted();
    if let Some(why) = &lifted {
        tracing::warn!("{why}; now taken again by address {}", caller.addr.0);
    }
    if changed.is_some() {
        s.gate_changed = changed;
    }
    reply.push(Value::I64(answer.next as i64));
    reply.push(Value::Bool(answer.held));
    // Its new owner is told the grid ran on by itself (a program that came after the lease
    // of `--gate`): its run is not the same as another.
    if let Some(why) = &lifted {
        reply.push(Value::Text(why));
    }
    Ok(())
}

/// `ungate()`: the gate's owner lets the grid run free.
fn ungate_method(
    s: &mut Shared,
    ctx: &mut Ctx,
    _: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    if !s.lockstep {
        return Err(MethodError::Failed(GateRefused::RealTime.to_string()));
    }
    s.gate_changed = Some(
        s.gate
            .lift(ctx.caller())
            .map_err(|e| MethodError::Failed(e.to_string()))?,
    );
    Ok(())
}

/// The caller as an owner of the gate: its address, and its process as it said (`declared`),
/// else as the directory has it. The caller's word comes first: this module's copy of the
/// directory may still hold a tool that had the address before the caller (a `modbot` command
/// that ended a moment ago), whose process is gone — the gate would be lifted under a live
/// program as soon as that was seen.
fn caller_of(ctx: &mut Ctx, declared: Option<u32>) -> Owner {
    let addr = ctx.caller();
    let pid = declared.or_else(|| ctx.caller_entry().map(|e| e.pid));
    Owner { addr, pid }
}

/// Who `owner` is, if it still lives: the directory's module at its address (the same
/// process), else its process if that still runs (or, its process unknown, "the caller at
/// address A": only the lease frees that gate).
fn owner_name(book: &modbot_core::phonebook::PhoneBook, owner: Owner) -> Option<String> {
    let listed = book
        .get(owner.addr)
        .filter(|e| e.alive && Some(e.pid) == owner.pid);
    if let Some(e) = listed {
        return Some(format!("{} (pid {})", e.name, e.pid));
    }
    match owner.pid {
        Some(pid) if modbot_grid::host::process_runs(pid) => {
            Some(format!("process {pid} (address {})", owner.addr.0))
        }
        Some(_) => None,
        None => Some(format!("the caller at address {}", owner.addr.0)),
    }
}

fn assembly_method(
    s: &mut Shared,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    reply.push(Value::Bytes(&s.status));
    Ok(())
}

fn ledger_method(
    s: &mut Shared,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    reply.push(Value::Bytes(&s.ledger));
    Ok(())
}

/// An answer to a call of the service thread's: the supervisor's `load_assembly` is kept for
/// the switch under way (the others, `spawn_host` and the like, fail loudly on the
/// supervisor's side).
fn on_done(s: &mut Shared, _: &mut Ctx, call: CallHandle, result: Result<&Args<'_>, &CallError>) {
    if s.loading == Some(call) {
        s.loading = None;
        s.loaded = Some(result.map(|_| ()).map_err(|e| e.to_string()));
    }
}

/// The coordinator's process, with its options parsed.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    init_logging();
    let grid = cli.grid.load(&cli.module.domain)?;
    let period_ns = grid.base_period.as_nanos() as u64;
    let hosts: Vec<String> = grid.hosts().iter().map(|h| grid.host_module(h)).collect();
    let assemblies = grid.assembly.is_some();
    let transport = cli.module.transport()?;
    let node: Arc<dyn Channels> = Arc::new(transport.channels("grid.coordinator")?);
    // The trace is written by a thread of normal priority: the tick thread does no file I/O.
    let trace = match &cli.trace {
        Some(p) => Some(Offload::new(std::fs::File::create(p).map_err(|e| {
            anyhow::anyhow!("cannot write the trace to {}: {e}", p.display())
        })?)?),
        None => None,
    };
    // A due component's done notice may be on its way: wait up to a quarter of a tick for it
    // (no longer: every release of the tick, the bus's among them, waits with it).
    let shutdown = signals::Shutdown::on_signals()?;
    let mut coord = Coordinator::new(&*node, grid.clone(), trace)?
        .with_grace(period_ns / 4)
        .with_shutdown(shutdown.clone())
        .with_state_hash_every(cli.state_hash_every);
    if let Some(p) = &cli.replay_log {
        let file = std::fs::File::create(p)
            .map_err(|e| anyhow::anyhow!("cannot write the replay log to {}: {e}", p.display()))?;
        coord = coord.with_replay_log(Box::new(Offload::new(file)?));
    }
    let lockstep = grid.timing.clock == modbot_grid::GridClock::Lockstep;
    if cli.gate.is_some() && !lockstep {
        anyhow::bail!("--gate holds a grid in lockstep; this grid runs in real time");
    }
    let started = modbot_core::clock::Clock::now_ns(&modbot_core::clock::MonotonicClock);
    let (gate, first_gate) = Gate::initial(cli.gate, started);
    let mut module = ModuleBuilder::new(
        cli.module.name.as_deref().unwrap_or("coordinator"),
        cli.module.addr.unwrap_or(250),
    )
    .mode(cli.module.receive_mode())
    .method("ledger", ledger_method)
    .method("switch", switch_method)
    .method("assembly", assembly_method)
    .method("gate", gate_method)
    .method("ungate", ungate_method)
    .on_done(on_done)
    .open(
        transport,
        Shared {
            assemblies,
            next_generation: coord.spec().generation().0.saturating_add(1),
            ledger: Vec::new(),
            requested: None,
            busy: false,
            loading: None,
            loaded: None,
            status: {
                let mut answer = Vec::new();
                switch::Status::default().encode(&mut answer);
                answer
            },
            lockstep,
            gate,
            gate_changed: None,
            ticks: 0,
        },
    )?;
    wait_for_hosts(&mut module, &hosts, &shutdown)?;

    // `ledger` answers from the start: the tick thread refreshes it every 200 ms.
    let mut coord = coord;
    coord.encode_ledger(false, &mut module.state_mut().ledger);
    let (to_tick, commands) = std::sync::mpsc::channel();
    let (tell, from_tick) = std::sync::mpsc::sync_channel(1024);
    let domain = modbot_core::Domain::new(&cli.module.domain)?;
    let mut switching = Switching::new(node.clone(), to_tick.clone(), assemblies, domain)?;
    let mut upgrading = UpgradeJob::default();
    // The tick thread puts itself under SCHED_FIFO (the grid's priority); this thread keeps
    // normal scheduling, so its work never delays a tick.
    // Ledger buffers go back to the tick thread, so it does not allocate a new one each time.
    let (give_back, spare) = std::sync::mpsc::sync_channel(2);
    let run = ticker::Run {
        spare,
        period_ns,
        max_ticks: cli.ticks,
        script: cli.switches.clone(),
        upgrades: cli.upgrades.clone(),
        gate: first_gate,
        shutdown: shutdown.clone(),
    };
    // `grid { mlock = true }`: locked before the tick thread starts.
    modbot_core::transport::launch::apply_mlockall();
    let ticker = std::thread::Builder::new()
        .name("tick".into())
        .spawn(move || ticker::run(coord, run, commands, tell))?;

    let mut host_pids = HashMap::new();
    let mut host_modules: Vec<(String, String)> = Vec::new();
    let mut last_look = Instant::now();
    let mut result = Ok(());
    let mut ended = None;
    // Why a run of `--ticks N` failed: the system still stops as after a run that succeeded,
    // and the coordinator then exits with it.
    let mut run_failed = None;
    while !shutdown.requested() {
        let mut busy = false;
        for _ in 0..16 {
            if !module.poll_once()? {
                break;
            }
            busy = true;
        }
        module.housekeeping();
        loop {
            let message = match from_tick.try_recv() {
                Ok(m) => m,
                Err(std::sync::mpsc::TryRecvError::Empty) => break,
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    if ended.is_none() {
                        result = Err(anyhow::anyhow!("the tick thread ended unexpectedly"));
                        ended = Some(false);
                    }
                    break;
                }
            };
            busy = true;
            match message {
                FromTick::Ticks(n) => {
                    module.state_mut().ticks = n;
                    switching.ticks(n)
                }
                FromTick::Held { seq, next } => module.state_mut().gate.held(seq, next),
                FromTick::Ledger(bytes) => {
                    let old = std::mem::replace(&mut module.state_mut().ledger, bytes);
                    let _ = give_back.try_send(old);
                }
                FromTick::State(state, failure) => switching.state(state, failure),
                // `Switching` keeps why a switch failed as text, for `assembly()`.
                FromTick::Began(r) => switching.began(&mut module, r.map_err(|e| e.to_string())),
                FromTick::Announced(at) => switching.announced(&mut module, at),
                FromTick::Switched(generation, announced, at) => {
                    switching.switched(&mut module, generation, announced, at)
                }
                FromTick::Retire(names) => names.iter().for_each(|n| retire(&mut module, n)),
                FromTick::Drop(links) => drop(links),
                FromTick::Hosts(list) => host_modules = list,
                FromTick::Current(name, generation) => {
                    switching.current(&mut module, name, generation)
                }
                FromTick::Ended(reached, failed) => {
                    ended = Some(reached);
                    if let Some(why) = failed {
                        tracing::error!("{why}");
                        run_failed = Some(why);
                    }
                }
                FromTick::Upgrade(host) => {
                    upgrading.start(&mut module, &host, &host_modules, &to_tick)
                }
                FromTick::Script(name) => {
                    if let Err(e) = request_switch(module.state_mut(), &name) {
                        tracing::error!("the scripted switch to {name} cannot be made: {e}");
                        let _ = to_tick.send(ToTick::ScriptRefused);
                    }
                }
                FromTick::Failed(why) => {
                    result = Err(anyhow::anyhow!("{why}"));
                    ended = Some(false);
                }
            }
        }
        if let Some(setting) = module.state_mut().gate_changed.take() {
            let _ = to_tick.send(ToTick::Gate(setting));
        }
        if result.is_err() {
            break;
        }
        if ended.is_none() {
            switching.step(&mut module);
            upgrading.step(&mut module, &to_tick);
        }
        if last_look.elapsed() >= Duration::from_millis(200) {
            last_look = Instant::now();
            for host in notice_restarts(&mut module, &mut host_pids, &host_modules) {
                let _ = to_tick.send(ToTick::HostRestarted(host));
            }
            if let Some(setting) = look_at_gate(&mut module) {
                let _ = to_tick.send(ToTick::Gate(setting));
            }
        }
        if ended == Some(true) {
            ended = Some(false);
            if let Err(e) = module.call_owned("supervisor", "down", &[], CallOptions::default()) {
                tracing::info!("no supervisor to stop the system: {e}");
            }
        }
        if !busy {
            // Woken by a call at once; the tick thread's news waits up to 2 ms while a switch
            // is under way, else up to 20 ms (fewer wake-ups of the coordinator's process
            // beside its real-time thread).
            let news = if switching.busy() || ended.is_some() {
                Duration::from_millis(2)
            } else {
                Duration::from_millis(20)
            };
            module.wait_for_frame(news)?;
        }
    }
    drop(to_tick);
    drop(switching);
    // The tick thread's last word (how a run of `--ticks N` ended) may come after the loop
    // ended on a stop; it is read while the thread finishes, so it never waits on a full
    // channel.
    let last_word = |run_failed: &mut Option<String>| {
        while let Ok(message) = from_tick.try_recv() {
            if let FromTick::Ended(_, Some(why)) = message {
                tracing::error!("{why}");
                *run_failed = Some(why);
            }
        }
    };
    while !ticker.is_finished() {
        last_word(&mut run_failed);
        std::thread::sleep(Duration::from_millis(1));
    }
    last_word(&mut run_failed);
    if ticker.join().is_err() {
        anyhow::bail!("the tick thread panicked");
    }
    match run_failed {
        Some(why) if result.is_ok() => Err(anyhow::anyhow!("{why}")),
        _ => result,
    }
}

/// Host modules whose process changed since the last look (the phone book, refreshed by the
/// module's housekeeping, has their pids): their hosts lost what they were released.
fn notice_restarts(
    module: &mut Module<Shared>,
    pids: &mut HashMap<String, (u32, u16)>,
    hosts: &[(String, String)],
) -> Vec<String> {
    let mut restarted = Vec::new();
    for (host, name) in hosts {
        let now = module
            .ctx()
            .phone_book()
            .entries()
            .find(|e| &e.name == name && e.alive)
            .map_or((0, 0), |e| (e.pid, e.upgrades));
        let seen = pids.entry(name.clone()).or_insert((0, 0));
        // A new process with a higher upgrade count took the host over (a live upgrade): it
        // has every release the old one had.
        if now.0 != 0 && seen.0 != 0 && now.0 != seen.0 && now.1 == seen.1 {
            restarted.push(host.clone());
        }
        if now.0 != 0 {
            *seen = now;
        }
    }
    restarted
}

/// Lifts the gate whose owner is gone or silent for its lease (see `gate`).
fn look_at_gate(module: &mut Module<Shared>) -> Option<super::gate::Setting> {
    let now = module.ctx().now_ns();
    let owner = module.state().gate.owner();
    let name = owner.and_then(|o| owner_name(module.ctx().phone_book(), o));
    let s = module.state_mut();
    let (setting, why) = s.gate.look(now, s.ticks, |_| name.clone())?;
    tracing::warn!("{why}");
    Some(setting)
}

/// Waits until every host module is up (they listen before they announce).
fn wait_for_hosts(
    module: &mut Module<Shared>,
    hosts: &[String],
    shutdown: &signals::Shutdown,
) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let up = module.list_modules()?;
        let missing: Vec<&String> = hosts
            .iter()
            .filter(|h| !up.iter().any(|m| m.alive && &m.name == *h))
            .collect();
        if missing.is_empty() {
            return Ok(());
        }
        if shutdown.requested() {
            anyhow::bail!("the system stops before host(s) {missing:?} came up");
        }
        if Instant::now() > deadline {
            anyhow::bail!("host(s) {missing:?} did not come up within 30 s");
        }
        module.housekeeping();
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Asks the supervisor to stop the host module `name` for good.
fn retire(module: &mut Module<Shared>, name: &str) {
    if let Err(e) = module
        .ctx()
        .call("supervisor", "retire", &[Value::Text(name)])
    {
        tracing::warn!("cannot ask the supervisor to stop {name}: {e}");
    }
}

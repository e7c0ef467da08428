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

use super::shared::Shared;
use super::switch_job::Switching;
use super::tick_thread::{self as ticker, FromTick, ToTick};
use super::Coordinator;
use crate::grid_args::GridArgs;

/// The coordinator: the only process of a system that reads the clock. The supervisor starts it
/// when the system description has a grid.
///
/// Methods: `ledger()` → the overrun ledger (see `modbot top`); with assemblies,
/// `switch(name)` → the generation the assembly gets (prepared while the current one runs,
/// then switched at an announced tick), and `assembly()` → where the assemblies stand (see
/// `modbot assembly`; both answers are in the format of `modbot_ipc_schema::switch`).
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
    /// Switch to assembly NAME at tick TICK (`TICK:NAME`; repeatable). In lockstep the grid
    /// waits at that tick while the assembly is prepared, so the run is reproducible.
    #[arg(long = "switch", value_name = "TICK:NAME", value_parser = modbot_grid::switch::parse_scripted)]
    switches: Vec<(u64, String)>,
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
    let coord = Coordinator::new(&*node, grid.clone(), trace)?
        .with_grace(period_ns / 4)
        .with_shutdown(shutdown.clone());
    let mut module = ModuleBuilder::new(
        cli.module.name.as_deref().unwrap_or("coordinator"),
        cli.module.addr.unwrap_or(250),
    )
    .mode(cli.module.receive_mode())
    .method("ledger", ledger_method)
    .method("switch", switch_method)
    .method("assembly", assembly_method)
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
    // The tick thread puts itself under SCHED_FIFO (the grid's priority); this thread keeps
    // normal scheduling, so its work never delays a tick.
    // Ledger buffers go back to the tick thread, so it does not allocate a new one each time.
    let (give_back, spare) = std::sync::mpsc::sync_channel(2);
    let run = ticker::Run {
        spare,
        period_ns,
        max_ticks: cli.ticks,
        script: cli.switches.clone(),
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
                FromTick::Ticks(n) => switching.ticks(n),
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
        if result.is_err() {
            break;
        }
        if ended.is_none() {
            switching.step(&mut module);
        }
        if last_look.elapsed() >= Duration::from_millis(200) {
            last_look = Instant::now();
            for host in notice_restarts(&mut module, &mut host_pids, &host_modules) {
                let _ = to_tick.send(ToTick::HostRestarted(host));
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
    pids: &mut HashMap<String, u32>,
    hosts: &[(String, String)],
) -> Vec<String> {
    let mut restarted = Vec::new();
    for (host, name) in hosts {
        let now = module
            .ctx()
            .phone_book()
            .entries()
            .find(|e| &e.name == name && e.alive)
            .map_or(0, |e| e.pid);
        let pid = pids.entry(name.clone()).or_insert(0);
        if now != 0 && *pid != 0 && now != *pid {
            restarted.push(host.clone());
        }
        if now != 0 {
            *pid = now;
        }
    }
    restarted
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

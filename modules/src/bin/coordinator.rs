//! `modbot-coordinator`: the time grid's clock — releases components, collects their done
//! notices, keeps the overrun ledger and, on request, a trace of every output.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Parser;
use modbot_ipc_schema::{Args, Value};
use modbot_modules::common::{init_logging, GridArgs, ModuleArgs};
use modbot_runtime::clock::{Clock, MonotonicClock};
use modbot_runtime::grid::coordinator::Coordinator;
use modbot_runtime::grid::ledger;
use modbot_runtime::grid::processes::host_module;
use modbot_runtime::grid::tick::TimerTicks;
use modbot_runtime::{signals, CallOptions, Ctx, MethodError, Module, ModuleBuilder, Reply};

/// The coordinator: the only process of a system that reads the clock. The supervisor starts it
/// when the system description has a grid.
///
/// Methods: `ledger()` → the overrun ledger (see `modbot top`).
#[derive(Debug, Parser)]
#[command(name = "modbot-coordinator", version)]
struct Cli {
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
}

/// The ledger as last encoded, for the `ledger` method.
#[derive(Default)]
struct Shared {
    ledger: Vec<u8>,
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

fn main() -> anyhow::Result<()> {
    init_logging();
    let cli = Cli::parse();
    let grid = cli.grid.load()?;
    let period_ns = grid.base_period.as_nanos() as u64;
    let grid_hosts = grid.hosts();
    let hosts: Vec<String> = grid_hosts.iter().map(|h| host_module(h)).collect();
    let transport = cli.module.transport()?;
    let node = transport.node("grid.coordinator")?;
    let trace = match &cli.trace {
        Some(p) => Some(std::io::BufWriter::new(std::fs::File::create(p).map_err(
            |e| anyhow::anyhow!("cannot write the trace to {}: {e}", p.display()),
        )?)),
        None => None,
    };
    // A due component's done notice may be on its way: wait up to half a tick for it.
    let mut coord = Coordinator::new(&node, grid, trace)?.with_grace(period_ns / 2);
    let mut module = ModuleBuilder::new(
        cli.module.name.as_deref().unwrap_or("coordinator"),
        cli.module.addr.unwrap_or(250),
    )
    .mode(cli.module.receive_mode())
    .method("ledger", ledger_method)
    .open(transport, Shared::default())?;
    signals::install_termination_handler()?;
    wait_for_hosts(&mut module, &hosts)?;
    let silent = coord.warm_up(20, Duration::from_secs(10))?;
    anyhow::ensure!(
        silent == 0,
        "{silent} host(s) did not answer the warm-up releases"
    );
    tracing::info!(
        "{} host(s) ready: ticking every {} us",
        hosts.len(),
        period_ns / 1000
    );
    let mut host_pids = vec![0u32; grid_hosts.len()];
    notice_restarts(&mut module, &grid_hosts, &mut host_pids, &mut coord);
    let mut ticks = TimerTicks::new(period_ns)?;
    let mut last_serve = Instant::now();
    let mut last_ledger = Instant::now();
    while !signals::termination_requested() && cli.ticks.is_none_or(|n| coord.ticks() < n) {
        match coord.step(&mut ticks) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => break,
            Err(e) => return Err(e.into()),
        }
        if last_serve.elapsed() >= Duration::from_millis(5) {
            last_serve = Instant::now();
            for _ in 0..8 {
                if !module.poll_once()? {
                    break;
                }
            }
            module.housekeeping();
        }
        if last_ledger.elapsed() >= Duration::from_millis(200) {
            last_ledger = Instant::now();
            notice_restarts(&mut module, &grid_hosts, &mut host_pids, &mut coord);
            publish_ledger(&coord, &mut module, false);
        }
    }
    let pending = coord.drain(&|| MonotonicClock.now_ns(), 200_000_000);
    publish_ledger(&coord, &mut module, true);
    let (g, rows) = coord.ledger(true);
    println!("{}", ledger::render(&g, &rows));
    if pending > 0 {
        println!("{pending} release(s) still running at the end");
    }
    let missing = coord.finish()?;
    if missing > 0 {
        tracing::warn!("{missing} output version(s) were missing from the trace");
    }
    if cli.ticks.is_some() && !signals::termination_requested() {
        if let Err(e) = module.call_owned("supervisor", "down", &[], CallOptions::default()) {
            tracing::info!("no supervisor to stop the system: {e}");
        }
    }
    while !signals::termination_requested() {
        if !module.poll_once()? {
            std::thread::sleep(Duration::from_millis(2));
        }
        module.housekeeping();
    }
    Ok(())
}

fn publish_ledger(
    coord: &Coordinator<std::io::BufWriter<std::fs::File>>,
    module: &mut Module<Shared>,
    done: bool,
) {
    let (g, rows) = coord.ledger(done);
    let shared = module.state_mut();
    shared.ledger.clear();
    ledger::encode(&g, &rows, &mut shared.ledger);
}

/// Tells the coordinator about hosts whose process changed since the last look (the phone
/// book, refreshed by the module's housekeeping, has their pids).
fn notice_restarts(
    module: &mut Module<Shared>,
    hosts: &[String],
    pids: &mut [u32],
    coord: &mut Coordinator<std::io::BufWriter<std::fs::File>>,
) {
    for (h, pid) in hosts.iter().zip(pids.iter_mut()) {
        let name = host_module(h);
        let now = module
            .ctx()
            .phone_book()
            .entries()
            .find(|e| e.name == name && e.alive)
            .map_or(0, |e| e.pid);
        if now != 0 && *pid != 0 && now != *pid {
            coord.host_restarted(h);
        }
        if now != 0 {
            *pid = now;
        }
    }
}

/// Waits until every host module is up (they listen before they announce).
fn wait_for_hosts(module: &mut Module<Shared>, hosts: &[String]) -> anyhow::Result<()> {
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
        if Instant::now() > deadline || signals::termination_requested() {
            anyhow::bail!("host(s) {missing:?} did not come up within 30 s");
        }
        module.housekeeping();
        std::thread::sleep(Duration::from_millis(10));
    }
}

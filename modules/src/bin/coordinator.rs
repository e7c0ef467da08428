//! `modbot-coordinator`: the time grid's clock — releases components, collects their done
//! notices, keeps the overrun ledger and, on request, a trace of every output.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Parser;
use modbot_ipc_schema::grid::Prepare;
use modbot_ipc_schema::{Args, Value};
use modbot_modules::common::{init_logging, GridArgs, ModuleArgs};
use modbot_runtime::clock::{Clock, MonotonicClock};
use modbot_runtime::grid::component::Registry;
use modbot_runtime::grid::coordinator::{Coordinator, SwitchState};
use modbot_runtime::grid::ledger;
use modbot_runtime::grid::tick::TimerTicks;
use modbot_runtime::grid::GridSpec;
use modbot_runtime::system;
use modbot_runtime::{signals, CallOptions, Ctx, MethodError, Module, ModuleBuilder, Reply};
use zerocopy::IntoBytes;

/// The coordinator: the only process of a system that reads the clock. The supervisor starts it
/// when the system description has a grid.
///
/// Methods: `ledger()` → the overrun ledger (see `modbot top`); with assemblies,
/// `switch(name)` → the generation the assembly gets (prepared while the current one runs,
/// then switched at an announced tick), and `assembly()` → where the assemblies stand (see
/// `modbot assembly`).
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

/// The ledger as last encoded, for the `ledger` method, and the assembly switches.
#[derive(Default)]
struct Shared {
    ledger: Vec<u8>,
    /// Whether the grid runs assemblies.
    assemblies: bool,
    /// A switch asked for and not begun yet: (assembly, generation).
    requested: Option<(String, u16)>,
    /// A switch is under way (asked for, or being prepared).
    busy: bool,
    /// The generation the next switch gets.
    next_generation: u16,
    /// `assembly()`'s answer, kept current by the main loop.
    status: String,
}

fn switch_method(
    s: &mut Shared,
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let name = args.text(0)?;
    if !s.assemblies {
        return Err(MethodError::Failed(
            "this grid has no assemblies: declare grid { assemblies = \"DIR\", assembly = \"NAME\" }".into(),
        ));
    }
    modbot_runtime::system::assembly::check_assembly_name(name).map_err(MethodError::Failed)?;
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
    reply.push(Value::I64(i64::from(generation)));
    Ok(())
}

fn assembly_method(
    s: &mut Shared,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    reply.push(Value::Text(&s.status));
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

fn main() -> anyhow::Result<()> {
    init_logging();
    let cli = Cli::parse();
    let grid = cli.grid.load()?;
    let period_ns = grid.base_period.as_nanos() as u64;
    let hosts: Vec<String> = grid.hosts().iter().map(|h| grid.host_module(h)).collect();
    let assemblies = grid.assembly.is_some();
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
    .method("switch", switch_method)
    .method("assembly", assembly_method)
    .open(
        transport,
        Shared {
            assemblies,
            next_generation: coord.spec().generation().saturating_add(1),
            ..Shared::default()
        },
    )?;
    let prepare = if assemblies {
        Some(modbot_runtime::grid::wire::prepare_publisher(&node)?)
    } else {
        None
    };
    let mut switching = Switching::default();
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
    let mut host_pids = std::collections::HashMap::new();
    notice_restarts(&mut module, &mut host_pids, &mut coord);
    switching.publish(&coord, &mut module);
    let mut ticks = TimerTicks::new(period_ns)?;
    let mut last_serve = Instant::now();
    let mut last_ledger = Instant::now();
    while !signals::termination_requested() && cli.ticks.is_none_or(|n| coord.ticks() < n) {
        match coord.step(&mut ticks) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => break,
            Err(e) => return Err(e.into()),
        }
        if let Err(e) = switching.step(&mut coord, &mut module, &node, prepare.as_ref()) {
            tracing::error!("assembly switch: {e}");
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
            notice_restarts(&mut module, &mut host_pids, &mut coord);
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
    pids: &mut std::collections::HashMap<String, u32>,
    coord: &mut Coordinator<std::io::BufWriter<std::fs::File>>,
) {
    let hosts = coord.spec().hosts();
    for h in &hosts {
        let name = coord.spec().host_module(h);
        let pid = pids.entry(name.clone()).or_insert(0);
        let now = module
            .ctx()
            .phone_book()
            .entries()
            .find(|e| e.name == name && e.alive)
            .map_or(0, |e| e.pid);
        if now != 0 && *pid != 0 && now != *pid {
            coord.host_restarted(h);
        }
        let pid = pids.entry(name).or_insert(0);
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

/// Where a switch asked for stands, between ticks.
#[derive(Default)]
enum Phase {
    #[default]
    Idle,
    /// The assembly file is being loaded on a thread.
    Loading(std::sync::mpsc::Receiver<Result<GridSpec, String>>),
    /// Its hosts start, the system's hosts load it, the links open.
    Preparing { last_ping: Instant },
    /// Its components track; it takes over at the tick.
    Announced(u64),
}

/// The switch under way, driven one bounded step after each tick.
#[derive(Default)]
struct Switching {
    phase: Phase,
    /// (assembly, generation, when asked).
    job: Option<(String, u16, Instant)>,
    /// The last outcome: generation, assembly, and the announced and actual ticks or why not.
    outcomes: Vec<(u16, String, Result<(u64, u64), String>)>,
}

/// How long a new assembly may take to be prepared.
const PREPARE_TIMEOUT: Duration = Duration::from_secs(20);
/// Ticks between the announcement and the earliest switch, beyond two longest periods.
const SWITCH_LEAD: u64 = 5;

impl Switching {
    fn step(
        &mut self,
        coord: &mut Coordinator<std::io::BufWriter<std::fs::File>>,
        module: &mut Module<Shared>,
        node: &iceoryx2::prelude::Node<iceoryx2::prelude::ipc::Service>,
        prepare: Option<&modbot_runtime::grid::wire::Pub>,
    ) -> anyhow::Result<()> {
        for name in coord.take_retired() {
            retire(module, &name);
        }
        if let Some((name, generation)) = module.state_mut().requested.take() {
            let (tx, rx) = std::sync::mpsc::channel();
            let system = coord.spec().clone();
            let loading = name.clone();
            std::thread::spawn(move || {
                let loaded =
                    system::load_assembly(&system, &loading, generation, &Registry::builtin())
                        .map_err(|e| e.to_string());
                let _ = tx.send(loaded);
            });
            tracing::info!("switch to assembly {name} (generation {generation}) asked for");
            self.job = Some((name, generation, Instant::now()));
            self.phase = Phase::Loading(rx);
            self.publish(coord, module);
        }
        let Some((name, generation, asked)) = self.job.clone() else {
            return Ok(());
        };
        if let Some(why) = coord.switch_failure().map(str::to_owned) {
            return self.fail(coord, module, why);
        }
        match &mut self.phase {
            Phase::Idle => {}
            Phase::Loading(rx) => match rx.try_recv() {
                Ok(Ok(spec)) => {
                    let hosts = spec.assembly_hosts();
                    if let Err(why) = coord.begin_switch(spec) {
                        return self.fail(coord, module, why);
                    }
                    if let Some(publisher) = prepare {
                        let notice = Prepare::new(generation, &name)?;
                        modbot_runtime::grid::wire::send(
                            publisher,
                            notice.as_bytes().len(),
                            |b| b.copy_from_slice(notice.as_bytes()),
                        )?;
                    }
                    for h in &hosts {
                        let args = [
                            Value::Text(h),
                            Value::Text(&name),
                            Value::I64(i64::from(generation)),
                        ];
                        if let Err(e) = module.ctx().call("supervisor", "spawn_host", &args) {
                            return self.fail(
                                coord,
                                module,
                                format!("the supervisor cannot start host {h}: {e}"),
                            );
                        }
                    }
                    self.phase = Phase::Preparing {
                        last_ping: Instant::now(),
                    };
                    self.publish(coord, module);
                }
                Ok(Err(why)) => return self.fail(coord, module, why),
                Err(std::sync::mpsc::TryRecvError::Empty) => {}
                Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    return self.fail(coord, module, "the assembly could not be loaded".into())
                }
            },
            Phase::Preparing { last_ping } => {
                coord.prepare_step(node)?;
                if let SwitchState::Preparing {
                    opened,
                    hosts,
                    ready,
                    system_hosts,
                    answered,
                } = coord.switch_state()
                {
                    if opened == hosts && ready >= system_hosts && answered == hosts {
                        if let Some(at) = coord.announce(SWITCH_LEAD) {
                            tracing::info!(
                                "assembly {name} (generation {generation}) prepared in {} ms: it takes over at tick {at}",
                                asked.elapsed().as_millis()
                            );
                            self.phase = Phase::Announced(at);
                            self.publish(coord, module);
                        }
                    } else if last_ping.elapsed() >= Duration::from_millis(10) && opened == hosts {
                        *last_ping = Instant::now();
                        coord.ping_incoming();
                    }
                    if asked.elapsed() > PREPARE_TIMEOUT {
                        let why = format!(
                            "not prepared within {} s: {opened}/{hosts} host links open, {answered}/{hosts} hosts answering, {ready}/{system_hosts} system hosts ready",
                            PREPARE_TIMEOUT.as_secs()
                        );
                        return self.fail(coord, module, why);
                    }
                }
            }
            Phase::Announced(at) => {
                let at = *at;
                if let Some(&(_, _, announced, took)) =
                    coord.switches().iter().find(|s| s.0 == generation)
                {
                    self.outcomes
                        .push((generation, name, Ok((announced, took))));
                    self.finish(coord, module);
                } else if coord.ticks() > at + 1 {
                    let why = format!("the switch announced for tick {at} did not happen");
                    return self.fail(coord, module, why);
                }
            }
        }
        Ok(())
    }

    fn fail(
        &mut self,
        coord: &mut Coordinator<std::io::BufWriter<std::fs::File>>,
        module: &mut Module<Shared>,
        why: String,
    ) -> anyhow::Result<()> {
        let (name, generation) = self
            .job
            .as_ref()
            .map_or((String::new(), 0), |j| (j.0.clone(), j.1));
        tracing::error!(
            "assembly {name} (generation {generation}) not switched to: {why}; the running one stays"
        );
        for host in coord.abort_switch() {
            retire(module, &host);
        }
        self.outcomes.push((generation, name, Err(why)));
        self.finish(coord, module);
        Ok(())
    }

    fn finish(
        &mut self,
        coord: &Coordinator<std::io::BufWriter<std::fs::File>>,
        module: &mut Module<Shared>,
    ) {
        self.job = None;
        self.phase = Phase::Idle;
        if self.outcomes.len() > 64 {
            let _ = self.outcomes.remove(0);
        }
        module.state_mut().busy = false;
        self.publish(coord, module);
    }

    /// Writes `assembly()`'s answer: `current NAME GENERATION`, `state ...`, then one line
    /// per outcome: `switched GEN NAME ANNOUNCED TOOK` or `failed GEN NAME REASON`.
    fn publish(
        &self,
        coord: &Coordinator<std::io::BufWriter<std::fs::File>>,
        module: &mut Module<Shared>,
    ) {
        let spec = coord.spec();
        let mut text = match &spec.assembly {
            Some(a) => format!("current {} {}\n", a.name, a.generation),
            None => "current none 0\n".to_owned(),
        };
        text.push_str(&match (&self.job, &self.phase) {
            (Some((name, g, _)), Phase::Announced(at)) => {
                format!("state announced {g} {name} {at}\n")
            }
            (Some((name, g, _)), _) => format!("state preparing {g} {name}\n"),
            _ => "state idle\n".to_owned(),
        });
        for (g, name, outcome) in &self.outcomes {
            text.push_str(&match outcome {
                Ok((announced, took)) => format!("switched {g} {name} {announced} {took}\n"),
                Err(why) => format!("failed {g} {name} {why}\n"),
            });
        }
        module.state_mut().status = text;
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

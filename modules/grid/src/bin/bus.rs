//! `modbot-bus`: the bus bridge — the component host of the grid's `bus` host, which owns the
//! drives, serves them every tick, and quick-stops them when the coordinator is lost.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use clap::Parser;
use modbot_bus::bridge::{self, Bridge, BusView};
use modbot_bus::{robot, Backend, DriveFault, DriveParams, SimBackend};
use modbot_core::clock::{Clock, MonotonicClock};
use modbot_core::{Ctx, MethodError, ModuleBuilder, Reply};
use modbot_ethercat::EthercatBackend;
use modbot_ethercat::EthercatConfig;
use modbot_grid::component::Generation;
use modbot_grid::spec::{host_module_of, BUS_HOST};
use modbot_grid_processes::grid_args::GridArgs;
use modbot_grid_processes::host_process::{HostArgs, HostProcess};
use modbot_grid_processes::watchdog_check::{self, Budget, Seen};
use modbot_ipc_schema::{Args, Value};
use modbot_modules::common::{init_logging, ModuleArgs};

/// The bus bridge. The supervisor starts it for the grid's host named `bus`; its `bus`
/// component is served every tick. Methods: `bus()` → the bus ledger (see `modbot bus`);
/// `switches()` → the record of assembly switches, one bytes value in the format of
/// `modbot_ipc_schema::bus` (the largest changes of commanded position and velocity within an
/// assembly, then per switch its generation, tick, the largest change of commanded position
/// at that cycle, rad, the cycles missed within five ticks of it, and the largest change of
/// commanded velocity, rad/s; see `modbot bus --switches`); `block(axis, on)` blocks or frees
/// an axis's link in the simulation; `robot()` → the robot's state (kind, since tick, faulted
/// drive or −1, error code, cause: `modbot_bus::robot_state`); `reset()` → the number of the
/// reset it asked for (an operator's reset, `modbot robot reset`), whose answer
/// `reset_answer(n)` gives once there is one (not ready until then): ok (bool) and what
/// happened or why it was refused; `inject(axis, fault, on)` injects a drive fault
/// (`following`, `torque`, `encoder`) in the simulation, or takes a lasting one away.
#[derive(Debug, Parser)]
#[command(name = "modbot-bus", version)]
struct Cli {
    #[command(flatten)]
    module: ModuleArgs,
    #[command(flatten)]
    grid: GridArgs,
    /// The host name (always `bus`).
    #[arg(long, default_value = BUS_HOST)]
    host: String,
}

/// The module's side of the bridge: a view the real-time thread refreshes, and the way to
/// ask it to block an axis. Nothing here is locked by the real-time thread but with `try_lock`.
struct Ledger {
    view: Arc<Mutex<BusView>>,
    ask: std::sync::mpsc::Sender<Ask>,
    axes: usize,
    resets: Arc<Mutex<Resets>>,
}

/// What the module asks the real-time thread to do to the drives.
enum Ask {
    Block(usize, bool),
    Inject(usize, DriveFault, bool),
}

/// Operators' resets: how many were asked for, how many the real-time thread took, and the
/// answer to the last it took.
#[derive(Default)]
struct Resets {
    asked: u64,
    taken: u64,
    answer: Option<(u64, Result<String, bridge::ResetRefused>)>,
}

/// Locks `m`, whether or not a thread panicked holding it (what it guards stays readable).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Ledger {
    fn view(&self) -> MutexGuard<'_, BusView> {
        lock(&self.view)
    }
}

fn bus_method(
    l: &mut Ledger,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let text = l.view().ledger();
    reply.push(Value::Text(&text));
    Ok(())
}

fn switches_method(
    l: &mut Ledger,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let mut record = Vec::new();
    l.view()
        .encode_switches(&mut record)
        .map_err(|e| MethodError::Failed(e.to_string()))?;
    reply.push(Value::Bytes(&record));
    Ok(())
}

/// Argument 0 as an axis of the bus.
fn axis_arg(l: &Ledger, args: &Args<'_>) -> Result<usize, MethodError> {
    let axis = args.i64(0)?;
    usize::try_from(axis)
        .ok()
        .filter(|a| *a < l.axes)
        .ok_or_else(|| {
            MethodError::Failed(format!(
                "axis {axis} does not exist: the bus has {} axes (0 to {})",
                l.axes,
                l.axes - 1
            ))
        })
}

fn send(l: &Ledger, ask: Ask) -> Result<(), MethodError> {
    l.ask
        .send(ask)
        .map_err(|_| MethodError::Failed("the bus bridge's cycle has ended".into()))
}

fn block_method(
    l: &mut Ledger,
    _: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let axis = axis_arg(l, args)?;
    let on = if args.len() > 1 { args.bool(1)? } else { true };
    send(l, Ask::Block(axis, on))
}

fn inject_method(
    l: &mut Ledger,
    _: &mut Ctx,
    args: &Args<'_>,
    _: &mut Reply,
) -> Result<(), MethodError> {
    let axis = axis_arg(l, args)?;
    let backend = l.view().backend();
    if backend != "sim" {
        return Err(MethodError::Failed(format!(
            "the {backend} backend's drives are real: a fault cannot be injected from here (the EtherCAT emulator takes `fault P KIND` on its standard input)"
        )));
    }
    let name = args.text(1)?;
    let fault = DriveFault::parse(name).ok_or_else(|| {
        let known: Vec<&str> = DriveFault::ALL.iter().map(|f| f.name()).collect();
        MethodError::Failed(format!(
            "no drive fault named '{name}' (known: {})",
            known.join(", ")
        ))
    })?;
    let on = if args.len() > 2 { args.bool(2)? } else { true };
    send(l, Ask::Inject(axis, fault, on))
}

fn robot_method(
    l: &mut Ledger,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let state = l.view().robot_state();
    for v in &state.to_values() {
        reply.push(v.as_value());
    }
    Ok(())
}

fn lock_resets(l: &Ledger) -> MutexGuard<'_, Resets> {
    lock(&l.resets)
}

fn reset_method(
    l: &mut Ledger,
    _: &mut Ctx,
    _: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let mut r = lock_resets(l);
    r.asked += 1;
    reply.push(Value::I64(r.asked as i64));
    Ok(())
}

fn reset_answer_method(
    l: &mut Ledger,
    _: &mut Ctx,
    args: &Args<'_>,
    reply: &mut Reply,
) -> Result<(), MethodError> {
    let n = u64::try_from(args.i64(0)?).unwrap_or(0);
    let r = lock_resets(l);
    match &r.answer {
        Some((m, answer)) if *m == n => {
            let (ok, text): (bool, std::borrow::Cow<'_, str>) = match answer {
                Ok(what) => (true, what.as_str().into()),
                Err(why) => (false, why.to_string().into()),
            };
            reply.push(Value::Bool(ok));
            reply.push(Value::Text(&text));
            Ok(())
        }
        _ if n >= 1 && n <= r.asked => {
            Err(MethodError::NotReady(format!("reset {n} is under way")))
        }
        _ => Err(MethodError::Failed(format!(
            "no reset number {n} was asked for (the last is {})",
            r.asked
        ))),
    }
}

/// Looks, on a thread of its own at the grid's priority, whether the machine gives the grid
/// what the watchdog's `budget` assumes, and warns if not (see `watchdog_check`).
fn check_watchdog(budget: Budget, priority: Option<u8>) {
    let looked = std::thread::Builder::new()
        .name("watchdog check".into())
        .spawn(move || {
            modbot_core::realtime::real_time_thread(priority, "watchdog check");
            let fifo = modbot_core::realtime::runs_fifo();
            let period = Duration::from_nanos(budget.period_ns);
            let (late_p99_ns, late_max_ns) =
                watchdog_check::measure(period, watchdog_check::SAMPLES);
            let seen = Seen {
                fifo,
                late_p99_ns,
                late_max_ns,
            };
            match watchdog_check::verdict(budget, seen) {
                Some(warning) => tracing::warn!("{warning}"),
                None => tracing::debug!("the machine keeps the watchdog's budget: {seen:?}"),
            }
        });
    if let Err(e) = looked {
        tracing::debug!("the watchdog check did not start: {e}");
    }
}

fn main() -> std::process::ExitCode {
    modbot_modules::common::finish("modbot-bus", run())
}

fn run() -> anyhow::Result<()> {
    init_logging();
    let cli = Cli::parse();
    let host_name = cli.host.clone();
    let args = HostArgs {
        module: cli.module,
        grid: cli.grid,
        host: cli.host,
    };
    let mut axes = 0;
    let mut shared = None;
    let mut watchdog_budget = None;
    // The drives are made first: the grid's `bus` component drives them.
    let mut p = HostProcess::start(args, |grid| {
        let bus = grid
            .components
            .iter()
            .find(|c| c.host == host_name && c.type_name == "bus")
            .ok_or_else(|| anyhow::anyhow!("host '{host_name}' has no component of type 'bus'"))?;
        anyhow::ensure!(
            bus.period == 1,
            "component '{}': the bus is served every tick: give it period 1",
            bus.name
        );
        axes = bus.params.i64("axes").unwrap_or(6).clamp(1, 16) as usize;
        let period_ns = grid.base_period.as_nanos() as u64;
        let lockstep = grid.timing.clock == modbot_grid::GridClock::Lockstep;
        let backend: Box<dyn Backend> =
            match robot::backend(&bus.params).map_err(anyhow::Error::msg)? {
                "ethercat" => {
                    let mut config = EthercatConfig::from_params(&bus.params, axes, period_ns)
                        .map_err(|e| anyhow::anyhow!("component '{}': {e}", bus.name))?;
                    config.watchdog = !lockstep;
                    // In lockstep a cycle waits for its frame as long as it takes; in real time a
                    // frame not back within ten periods (10 ms at least) is lost.
                    let pdu = if lockstep {
                        Duration::from_secs(2)
                    } else {
                        Duration::from_nanos(period_ns.saturating_mul(10))
                            .max(Duration::from_millis(10))
                    };
                    let started = std::time::Instant::now();
                    let backend = EthercatBackend::start(&config, pdu)?;
                    tracing::info!(
                        "EtherCAT segment on '{}' in OP: {} slave(s), {} drive(s), {:.0} ms",
                        config.interface,
                        backend.slaves().len(),
                        config.drives.len(),
                        started.elapsed().as_secs_f64() * 1e3
                    );
                    Box::new(backend)
                }
                _ => {
                    let joints = robot::joints(&bus.params, axes).map_err(anyhow::Error::msg)?;
                    Box::new(SimBackend::with_joints(&joints, DriveParams::default())?)
                }
            };
        let periods = robot::watchdog_periods(&bus.params).map_err(anyhow::Error::msg)?;
        if !lockstep {
            watchdog_budget = Some(Budget { periods, period_ns });
        }
        let bridge = Bridge::new(backend, period_ns).watchdog_periods(periods);
        let made = Arc::new(Mutex::new(if lockstep {
            bridge.lockstep()
        } else {
            bridge
        }));
        let mut registry = modbot_components::builtin();
        robot::register_bridge(&mut registry, made.clone());
        shared = Some(made);
        Ok(registry)
    })?;
    let shared = shared.ok_or_else(|| anyhow::anyhow!("no bus bridge was made"))?;
    // Its module (the ledger, switches and block methods) on a thread of its own, so a method
    // call never delays a cycle.
    let view = Arc::new(Mutex::new(BusView::default()));
    let (ask, asks) = std::sync::mpsc::channel();
    let resets = Arc::new(Mutex::new(Resets::default()));
    let ledger = Ledger {
        view: view.clone(),
        ask,
        axes,
        resets: resets.clone(),
    };
    let declare = |module: ModuleBuilder<Ledger>| {
        module
            .method("bus", bus_method)
            .method("switches", switches_method)
            .method("block", block_method)
            .method("inject", inject_method)
            .method("robot", robot_method)
            .method("reset", reset_method)
            .method("reset_answer", reset_answer_method)
    };
    let service = p.serve(
        host_module_of(p.host_name(), Generation::SYSTEM),
        199,
        declare,
        ledger,
    )?;
    if let Some(budget) = watchdog_budget {
        check_watchdog(budget, p.grid.host_priority());
    }
    let now = || MonotonicClock.now_ns();
    // The bus sleeps on its wake-up until released, or until its watchdog must look (the
    // silence reaching three periods; a deadline to the microsecond), whichever comes first.
    while HostProcess::running(&service) {
        if p.host.serve(&now)? == 0 {
            // Nothing waits to be served: only now may the watchdog judge the silence (after
            // a slow moment of this process, a release may be waiting that it has not seen).
            let next = {
                let mut b = bridge::lock(&shared);
                b.watch(now());
                // Published before a reset's answer is given: whoever reads the answer then
                // reads the robot state it brought about.
                b.publish_due(now(), &view);
                while let Ok(ask) = asks.try_recv() {
                    let done = match ask {
                        Ask::Block(axis, on) => b.block_axis(axis, on),
                        Ask::Inject(axis, fault, on) => {
                            tracing::warn!(
                                "drive fault '{}' {} on axis {axis} by command",
                                fault.name(),
                                if on { "injected" } else { "taken away" }
                            );
                            b.inject(axis, fault, on)
                        }
                    };
                    if let Err(e) = done {
                        tracing::warn!("{e}");
                    }
                }
                // Never waits for the module's thread: a reset asked for is seen next time.
                if let Ok(mut r) = resets.try_lock() {
                    if r.asked > r.taken {
                        r.taken = r.asked;
                        b.ask_reset(now());
                    }
                    if let Some(answer) = b.take_reset_answer(now()) {
                        r.answer = Some((r.taken, answer));
                    }
                }
                b.publish_due(now(), &view);
                b.next_look_ns(now())
            };
            // Idle: a bounded piece of an assembly's preparation, then sleep.
            p.prepare_step()?;
            // At most 5 ms at a time, to look at the termination flag.
            p.host
                .wait(Some(Duration::from_nanos(next.clamp(1_000, 5_000_000))));
        }
    }
    p.finish(service)
}

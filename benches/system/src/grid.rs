//! Benchmark 3, grid: a 1 kHz time grid of 10 components on 5 host processes under
//! `modbot up`, with and without SCHED_FIFO (the description's `grid { priority = 60 }`:
//! the coordinator at 60, the hosts at 59).
//!
//! What is measured, by a tap in this process that subscribes to the grid's own services:
//!
//! - **tick error**: each release notice carries the coordinator's clock reading right after
//!   its timerfd woke it (`released_ns`, CLOCK_MONOTONIC). As the coordinator counts it, the
//!   error is the lateness after the last timerfd expiration (a wake-up a period late is a
//!   missed tick), so it is `(released_ns − start) mod T`. Only the start's phase is invisible
//!   from outside: it is set so that the median error equals the coordinator's own ledger
//!   median (exact, over the whole run); the distribution's shape comes from the stamps. The
//!   ledger's p50/p99/max are reported in a note.
//! - **release to done**: each done notice carries the host's release latency (its clock at the
//!   start of the step minus `released_ns`) and the step's execution time; their sum is the
//!   time from the coordinator's wake-up to the end of the component's step. Every component
//!   of every tick is a sample.
//! - **coordinator CPU per tick**: the CPU time of every thread of the coordinator process
//!   (`/proc/PID/task/*/schedstat`, ns) over 100 ms windows, divided by the ticks in each; and
//!   of its tick thread alone (`grid.tick_thread_cpu`: the service thread's method calls and
//!   phone-book refreshes left out).
//!
//! **Baselines** (same run, same scheduling): a bare loop in two processes of this executable.
//! `grid-ticker` reads an absolute 1 ms timerfd (the runtime's `TimerTicks`, as the coordinator
//! does), stamps the wake-up, publishes the stamp and notifies an iceoryx2 Event each tick;
//! `grid-waker` sleeps on that Event, stamps its wake-up and answers with the difference. Its
//! tick error is the floor for the coordinator's (`grid.timerfd_baseline`), its wake-up the floor
//! for release-to-done (`grid.wakeup_baseline`), and its CPU per tick the floor for the
//! coordinator's (`grid.timerfd_cpu`). Both run under SCHED_FIFO 60/59 when the grid does.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use hdrhistogram::Histogram;
use iceoryx2::prelude::*;
use modbot_bench_kit::hogs::Hogs;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::supervised::Supervised;
use modbot_core::{CallOptions, Domain, IpcTransport};
use modbot_grid::ledger;
use modbot_grid::tick::{TickSource, TimerTicks};
use modbot_grid::wire;
use modbot_ipc_schema::grid::{Done, Release, PING, READY};

/// The base period: 1 kHz.
const PERIOD_NS: u64 = 1_000_000;
/// The coordinator's SCHED_FIFO priority (hosts get one less), as in the examples.
const PRIORITY: u8 = 60;
/// Width of a bucket of the tick-error distributions in the report.
const BUCKET_NS: u64 = 5_000;

/// Runs the grid benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    let plan = Plan {
        warm: Duration::from_millis(if opts.quick { 400 } else { 1000 }),
        span: Duration::from_secs(if opts.quick { 2 } else { 30 }),
    };
    let mut done_any = false;
    // Normal scheduling, SCHED_FIFO, and SCHED_FIFO beside two CPU hogs of normal priority
    // (one per core): baseline and grid each measured under the same conditions.
    for (fifo, hogs) in [(false, 0), (true, 0), (true, 2)] {
        let _hogs = match Hogs::start(opts, hogs) {
            Ok(h) => h,
            Err(e) => {
                report.note(format!("grid: {hogs} CPU hogs could not be started: {e:#}"));
                continue;
            }
        };
        let base = match measure_baseline(opts, fifo, &plan) {
            Ok(b) => b,
            Err(e) => {
                report.note(format!(
                    "grid: the timerfd baseline (fifo={fifo}) failed: {e:#}"
                ));
                continue;
            }
        };
        let grid = match measure_grid(opts, fifo, &plan) {
            Ok(g) => g,
            Err(e) => {
                report.note(format!("grid: the grid (fifo={fifo}) failed: {e:#}"));
                continue;
            }
        };
        push_rows(report, fifo, hogs, &base, &grid)?;
        done_any = true;
    }
    if let Err(e) = crate::lockstep::run(opts, report) {
        report.note(format!("grid: the lockstep runs failed: {e:#}"));
    }
    if !done_any {
        bail!("no grid measurement succeeded (see the notes)");
    }
    report.note(
        "grid: tick error = the coordinator's wake-up stamp in each release notice minus the \
         due time of the last timerfd expiration; the start's phase is set so that the median \
         equals the coordinator's own (exact) ledger median, the shape comes from the stamps; \
         the baseline's errors are exact (the ticker knows its start). release_to_done = the \
         host's release latency + step time from each done notice (from the coordinator's \
         wake-up to the end of the step), every component of every tick. coordinator_cpu = CPU \
         time of all coordinator threads per tick over 100 ms windows. Baselines: a bare 1 kHz \
         timerfd loop (the runtime's TimerTicks) that publishes a stamp and notifies an \
         iceoryx2 Event each tick, and a second process waking on it, under the same \
         scheduling: the least a coordinator and a host built on timerfd + iceoryx2 can do on \
         this machine.",
    );
    Ok(())
}

/// The child roles of this benchmark.
pub fn child(role: &str, args: &[String]) -> Option<anyhow::Result<()>> {
    match role {
        "grid-ticker" => Some(ticker(args)),
        "grid-waker" => Some(waker(args)),
        _ => None,
    }
}

/// How long to observe.
struct Plan {
    /// Observed and thrown away first (start-up, warm-up releases, page faults).
    warm: Duration,
    /// Observed and recorded.
    span: Duration,
}

/// What one run (the grid or its baseline) gave.
struct Measured {
    tick_error: Histogram<u64>,
    /// The tick errors in buckets of [`BUCKET_NS`], for the plot.
    buckets: Vec<(u64, u64)>,
    release_to_done: Histogram<u64>,
    cpu_per_tick: Histogram<u64>,
    /// Of the ticking thread alone (the coordinator's `tick` thread; the bare loop's only one).
    thread_cpu_per_tick: Histogram<u64>,
    ticks: u64,
    missed: u64,
    /// From the coordinator's ledger (the grid only): releases, overruns, stale releases.
    releases: u64,
    overruns: u64,
    stale: u64,
    /// What else to say about the run (the coordinator's ledger, warnings).
    remarks: Vec<String>,
}

fn push_rows(
    report: &mut Report,
    fifo: bool,
    hogs: usize,
    base: &Measured,
    grid: &Measured,
) -> anyhow::Result<()> {
    if base.cpu_per_tick.is_empty() || grid.cpu_per_tick.is_empty() {
        bail!("no CPU samples (fifo={fifo})");
    }
    let f = [
        ("fifo", serde_json::Value::Bool(fifo)),
        ("hogs", serde_json::Value::from(hogs)),
    ];
    let row = |name: &str, h: &Histogram<u64>| {
        Row::from_histogram(name, h)
            .param("fifo", fifo)
            .param("hogs", hogs)
    };
    let count = |name: &str, n: u64| {
        Row::single(name, n)
            .param("fifo", fifo)
            .param("hogs", hogs)
            .unit("count")
    };
    report.push(row("grid.timerfd_baseline", &base.tick_error).is_baseline());
    report.push(row("grid.tick_error", &grid.tick_error).against("grid.timerfd_baseline", &f));
    report.push(row("grid.wakeup_baseline", &base.release_to_done).is_baseline());
    report.push(
        row("grid.release_to_done", &grid.release_to_done).against("grid.wakeup_baseline", &f),
    );
    report.push(row("grid.timerfd_cpu", &base.cpu_per_tick).is_baseline());
    report.push(row("grid.coordinator_cpu", &grid.cpu_per_tick).against("grid.timerfd_cpu", &f));
    report.push(
        row("grid.tick_thread_cpu", &grid.thread_cpu_per_tick).against("grid.timerfd_cpu", &f),
    );
    // Ticks seen and missed over the recorded span, the grid's and the bare loop's.
    report.push(count("grid.timerfd_ticks", base.ticks + base.missed).is_baseline());
    report.push(count("grid.timerfd_missed", base.missed).is_baseline());
    report.push(count("grid.ticks", grid.ticks + grid.missed).against("grid.timerfd_ticks", &f));
    report.push(count("grid.missed_ticks", grid.missed).against("grid.timerfd_missed", &f));
    // Releases, overruns and stale releases over the whole run (the coordinator's ledger).
    report.push(count("grid.releases", grid.releases).is_baseline());
    report.push(count("grid.overruns", grid.overruns).against("grid.releases", &f));
    report.push(count("grid.stale", grid.stale).against("grid.releases", &f));
    let tag = match (fifo, hogs) {
        (false, _) => "nofifo".to_owned(),
        (true, 0) => "fifo".to_owned(),
        (true, n) => format!("fifo_{n}hogs"),
    };
    report
        .histograms
        .insert(format!("grid.tick_error.{tag}"), grid.buckets.clone());
    let us = |ns: u64| ns as f64 / 1e3;
    let mut text = format!(
        "grid (fifo={fifo}, {hogs} CPU hogs): {} ticks observed, {} missed (baseline: {} ticks, \
         {} missed); {} overruns and {} stale of {} releases; tick error p99 {:.1} µs vs {:.1} µs \
         bare; coordinator CPU p50 {:.2} µs/tick vs {:.2} µs bare",
        grid.ticks,
        grid.missed,
        base.ticks,
        base.missed,
        grid.overruns,
        grid.stale,
        grid.releases,
        us(grid.tick_error.value_at_quantile(0.99)),
        us(base.tick_error.value_at_quantile(0.99)),
        us(grid.cpu_per_tick.value_at_quantile(0.5)),
        us(base.cpu_per_tick.value_at_quantile(0.5)),
    );
    for r in base.remarks.iter().chain(&grid.remarks) {
        text.push_str("; ");
        text.push_str(r);
    }
    report.note(text);
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// The grid under `modbot up`.
// ---------------------------------------------------------------------------------------------

/// 10 cheap built-in components on 5 hosts, periods 1, 2, 5 and 10 base ticks, a chain through
/// every host. h1 has two components of period 1: its release service sees every tick.
fn description(domain: &Domain, fifo: bool, pin: bool) -> String {
    let mut grid = String::from("base_period = 0.001");
    if fifo {
        grid.push_str(&format!(", priority = {PRIORITY}"));
    }
    if pin {
        grid.push_str(", cpus = { 1 }");
    }
    format!(
        r#"-- modbot-benches grid: 10 components on 5 hosts at 1 kHz.
domain "{domain}"
supervision {{ heartbeat_timeout = 2.0 }}
grid {{ {grid} }}
component "A" {{ type = "ramp",       host = "h1", period = 1,  params = {{ slope = 1 }} }}
component "B" {{ type = "gain",       host = "h1", period = 1,  params = {{ k = 2 }} }}
component "C" {{ type = "integrator", host = "h2", period = 1 }}
component "D" {{ type = "sine",       host = "h2", period = 2,  params = {{ amplitude = 1, freq = 5 }} }}
component "E" {{ type = "sum",        host = "h3", period = 1 }}
component "F" {{ type = "delay",      host = "h3", period = 5 }}
component "G" {{ type = "ramp",       host = "h4", period = 1,  params = {{ slope = 2 }} }}
component "H" {{ type = "gain",       host = "h4", period = 2,  params = {{ k = 0.5 }} }}
component "I" {{ type = "sum",        host = "h5", period = 1 }}
component "J" {{ type = "integrator", host = "h5", period = 10 }}
connect "A.y -> B.u"
connect "B.y -> C.u"
connect "C.y -> E.a"
connect "D.y -> E.b"
connect "E.y -> F.u"
connect "G.y -> H.u"
connect "H.y -> I.a"
connect "F.y -> I.b"
connect "I.y -> J.u"
"#,
        domain = domain.name()
    )
}

fn measure_grid(opts: &Opts, fifo: bool, plan: &Plan) -> anyhow::Result<Measured> {
    let mut scratch = Scratch::new(if fifo { "grid_fifo" } else { "grid" }, None)?;
    let file = scratch.path("grid.lua");
    std::fs::write(&file, description(&scratch.domain, fifo, opts.pin))?;
    let mut sys = Supervised::start(opts, &scratch.domain, &file, &[], Duration::from_secs(10))?;
    sys.wait_up(Duration::from_secs(30))?;
    let coordinator = sys.pid_of("coordinator")?;
    let seen = {
        let channels = IpcTransport::new(&scratch.domain)?.channels("bench.tap")?;
        let releases = wire::release_subscriber(&channels, "grid.release.h1")?;
        let done = wire::done_subscriber(&channels)?;
        let poll = |seen: &mut Seen| -> anyhow::Result<()> {
            while releases.receive(&mut |s| {
                for r in Release::batch(s).into_iter().flatten() {
                    let t = r.tick.get();
                    if r.component.get() != PING && seen.releases.last().is_none_or(|l| l.0 != t) {
                        seen.releases.push((t, r.released_ns.get()));
                    }
                }
            })? {}
            while done.receive(&mut |s| {
                for d in Done::batch(s).into_iter().flatten() {
                    let c = d.component.get();
                    if c != PING && c != READY && d.status.get() == Done::OK {
                        seen.release_to_done
                            .push(d.latency_ns.get() + d.exec_ns.get());
                    }
                }
            })? {}
            Ok(())
        };
        observe(plan, coordinator, Some("tick"), poll, || {
            sys.check_running()
        })?
    };
    let ledger_bytes = sys.tool()?.call_blocking(
        "coordinator",
        "ledger",
        &[],
        CallOptions::timeout(Duration::from_secs(1)),
        |r| r.ok().and_then(|a| a.bytes(0).ok().map(<[u8]>::to_vec)),
    );
    let (g, rows) = ledger::decode(ledger_bytes.as_deref().unwrap_or_default())
        .map_err(|e| anyhow::anyhow!("the coordinator's ledger(): {e}"))?;
    let (errors, missed) = calibrated_errors(&seen.releases, g.tick_err_p50);
    let mut measured = seen.measured(&errors, missed)?;
    measured.releases = rows.iter().map(|r| r.releases).sum();
    measured.overruns = rows.iter().map(|r| r.overruns).sum();
    measured.stale = rows.iter().map(|r| r.stale).sum();
    measured.remarks.push(format!(
        "the coordinator's own ledger (whole run, exact start): {} ticks, {} missed, tick error \
         p50 {:.1} µs p99 {:.1} µs max {:.1} µs, {} overrun(s)",
        g.ticks,
        g.missed,
        g.tick_err_p50 as f64 / 1e3,
        g.tick_err_p99 as f64 / 1e3,
        g.tick_err_max as f64 / 1e3,
        rows.iter().map(|r| r.overruns).sum::<u64>()
    ));
    for w in sys.lines_with("not applied") {
        measured.remarks.push(format!("supervisor: {}", w.trim()));
    }
    let left = sys.stop()?;
    if !left.is_empty() {
        measured.remarks.push(format!(
            "{} file(s) of the domain were left after the stop and removed",
            left.len()
        ));
    }
    Ok(measured)
}

// ---------------------------------------------------------------------------------------------
// The baseline: a bare timerfd loop and a process woken by it.
// ---------------------------------------------------------------------------------------------

const TICK_SERVICE: &str = "bench.tick";
const DONE_SERVICE: &str = "bench.done";
const WAKE_SERVICE: &str = "bench.wake";
/// Values per stamp: the tick, a time in ns, and two more (the ticker's exact tick error and
/// the ticks it missed so far).
const STAMP: usize = 4;

type Factory =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, [u8], ()>;
type Pub = iceoryx2::port::publisher::Publisher<ipc::Service, [u8], ()>;
type Sub = iceoryx2::port::subscriber::Subscriber<ipc::Service, [u8], ()>;

fn ix<E: std::fmt::Debug>(what: &'static str) -> impl Fn(E) -> anyhow::Error {
    move |e| anyhow::anyhow!("{what}: {e:?}")
}

/// A stamp service of the baseline: samples of [`STAMP`] little-endian u64s, up to 256 kept per
/// subscriber.
fn stamps(node: &Node<ipc::Service>, name: &str) -> anyhow::Result<Factory> {
    node.service_builder(&ServiceName::new(name).map_err(ix("service name"))?)
        .publish_subscribe::<[u8]>()
        .max_publishers(2)
        .max_subscribers(4)
        .max_nodes(16)
        .history_size(0)
        .subscriber_max_buffer_size(256)
        .subscriber_max_borrowed_samples(2)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(ix("open a stamp service"))
}

fn stamp_pub(f: &Factory) -> anyhow::Result<Pub> {
    f.publisher_builder()
        .initial_max_slice_len(STAMP * 8)
        .max_loaned_samples(2)
        .create()
        .map_err(ix("stamp publisher"))
}

fn stamp_sub(f: &Factory) -> anyhow::Result<Sub> {
    f.subscriber_builder()
        .buffer_size(256)
        .create()
        .map_err(ix("stamp subscriber"))
}

fn send_stamp(p: &Pub, values: [u64; STAMP]) -> anyhow::Result<()> {
    let mut bytes = [0u8; STAMP * 8];
    for (chunk, v) in bytes.chunks_exact_mut(8).zip(values) {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    let s = p.loan_slice_uninit(bytes.len()).map_err(ix("loan"))?;
    s.write_from_slice(&bytes).send().map_err(ix("send"))?;
    Ok(())
}

fn read_stamp(bytes: &[u8]) -> Option<[u64; STAMP]> {
    let mut out = [0u64; STAMP];
    for (i, v) in out.iter_mut().enumerate() {
        *v = u64::from_le_bytes(bytes.get(i * 8..i * 8 + 8)?.try_into().ok()?);
    }
    Some(out)
}

fn wake_event(
    node: &Node<ipc::Service>,
) -> anyhow::Result<iceoryx2::service::port_factory::event::PortFactory<ipc::Service>> {
    node.service_builder(&ServiceName::new(WAKE_SERVICE).map_err(ix("service name"))?)
        .event()
        .max_nodes(16)
        .open_or_create()
        .map_err(ix("open the wake-up event"))
}

/// A priority argument: a number, or `-` for normal scheduling.
fn parse_prio(text: &str) -> anyhow::Result<Option<u8>> {
    if text == "-" {
        return Ok(None);
    }
    text.parse()
        .map(Some)
        .with_context(|| format!("priority '{text}': expected a number or -"))
}

fn prio_arg(fifo: bool, prio: u8) -> String {
    if fifo {
        prio.to_string()
    } else {
        "-".to_owned()
    }
}

/// The bare timerfd loop of [`measure_baseline`] observed for `span` (after a short warm-up):
/// the ticks it ran and missed.
pub(crate) fn bare_loop(opts: &Opts, fifo: bool, span: Duration) -> anyhow::Result<(u64, u64)> {
    let plan = Plan {
        warm: Duration::from_millis(400),
        span,
    };
    let m = measure_baseline(opts, fifo, &plan)?;
    Ok((m.ticks, m.missed))
}

fn measure_baseline(opts: &Opts, fifo: bool, plan: &Plan) -> anyhow::Result<Measured> {
    let scratch = Scratch::new(if fifo { "tick_fifo" } else { "tick" }, None)?;
    let domain = scratch.domain.name().to_owned();
    let node = IpcTransport::new(&scratch.domain)?.node("bench.tap")?;
    let ticks = stamp_sub(&stamps(&node, TICK_SERVICE)?)?;
    let done = stamp_sub(&stamps(&node, DONE_SERVICE)?)?;
    let _event = wake_event(&node)?;
    let core = procs::core_arg(opts.pin.then_some(1));
    let mut waker = procs::spawn_role(
        opts,
        "grid-waker",
        &[domain.clone(), prio_arg(fifo, PRIORITY - 1)],
    )?;
    // The waker subscribes before the first tick.
    std::thread::sleep(Duration::from_millis(100));
    let limit = (plan.warm + plan.span + Duration::from_secs(5)).as_millis() as u64;
    let mut ticker = procs::spawn_role(
        opts,
        "grid-ticker",
        &[domain, prio_arg(fifo, PRIORITY), core, limit.to_string()],
    )?;
    let pid = ticker.pid();
    let mut errors = Vec::new();
    let mut missed = (None, 0);
    let poll = |seen: &mut Seen| -> anyhow::Result<()> {
        while let Some(s) = ticks.receive().map_err(ix("receive a tick"))? {
            if let Some([n, released, error, missed_so_far]) = read_stamp(s.payload()) {
                seen.releases.push((n, released));
                if seen.recording {
                    errors.push(error);
                    missed.0.get_or_insert(missed_so_far);
                    missed.1 = missed_so_far;
                }
            }
        }
        while let Some(s) = done.receive().map_err(ix("receive a wake-up"))? {
            if let Some([_, latency, ..]) = read_stamp(s.payload()) {
                seen.release_to_done.push(latency);
            }
        }
        Ok(())
    };
    let seen = observe(plan, pid, None, poll, || {
        ticker.check_running()?;
        waker.check_running()
    })?;
    let measured = seen.measured(&errors, missed.1 - missed.0.unwrap_or(missed.1))?;
    drop(ticker);
    drop(waker);
    Ok(measured)
}

/// `grid-ticker DOMAIN PRIO CORE TICKS`: a bare absolute 1 ms timerfd loop (the runtime's
/// `TimerTicks`) that publishes (tick, wake-up time) and notifies the waker every tick.
fn ticker(args: &[String]) -> anyhow::Result<()> {
    let [domain, prio, core, limit] = args else {
        bail!("grid-ticker DOMAIN PRIO CORE TICKS");
    };
    let _pin = procs::pin(procs::parse_core(core)?)?;
    let node = IpcTransport::new(&Domain::new(domain)?)?.node("bench.ticker")?;
    let out = stamp_pub(&stamps(&node, TICK_SERVICE)?)?;
    let answers = stamp_sub(&stamps(&node, DONE_SERVICE)?)?;
    let wake = wake_event(&node)?
        .notifier_builder()
        .create()
        .map_err(ix("wake notifier"))?;
    let _fifo = procs::set_fifo(parse_prio(prio)?)?;
    let limit: u64 = limit.parse().context("TICKS")?;
    let mut timer = TimerTicks::new(PERIOD_NS, modbot_core::signals::Shutdown::on_signals()?)?;
    let (mut n, mut expirations) = (0, 0);
    while n < limit && !procs::interrupted() {
        match timer.wait() {
            Ok(k) => expirations += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => break,
            Err(e) => return Err(e.into()),
        }
        let now = timer.now_ns();
        // Exactly as the coordinator measures it: the lateness after the last expiration.
        let error = now.saturating_sub(timer.due_ns(expirations - 1));
        // What a coordinator does with its done notices: take them.
        while answers.receive().map_err(ix("receive"))?.is_some() {}
        send_stamp(&out, [n, now, error, expirations - 1 - n])?;
        wake.notify().map_err(ix("notify"))?;
        n += 1;
    }
    Ok(())
}

/// `grid-waker DOMAIN PRIO`: sleeps on the ticker's event like a blocking host, and answers
/// each tick with its wake-up latency.
fn waker(args: &[String]) -> anyhow::Result<()> {
    let [domain, prio] = args else {
        bail!("grid-waker DOMAIN PRIO");
    };
    let node = IpcTransport::new(&Domain::new(domain)?)?.node("bench.waker")?;
    let ticks = stamp_sub(&stamps(&node, TICK_SERVICE)?)?;
    let out = stamp_pub(&stamps(&node, DONE_SERVICE)?)?;
    let listener = wake_event(&node)?
        .listener_builder()
        .create()
        .map_err(ix("wake listener"))?;
    let _fifo = procs::set_fifo(parse_prio(prio)?)?;
    while !procs::interrupted() {
        if let Err(e) = listener.timed_wait(|_| {}, Duration::from_millis(5)) {
            let _ = e;
        }
        while let Some(s) = ticks.receive().map_err(ix("receive"))? {
            let now = modbot_bench_kit::sample::now_ns();
            let stamp = read_stamp(s.payload());
            drop(s);
            if let Some([n, released, ..]) = stamp {
                send_stamp(&out, [n, now.saturating_sub(released), 0, 0])?;
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Observing a grid (or the baseline) from outside.
// ---------------------------------------------------------------------------------------------

/// What the tap saw over the recorded span.
#[derive(Default)]
struct Seen {
    /// (tick, wake-up stamp) of every tick.
    releases: Vec<(u64, u64)>,
    /// Release to done of every done notice.
    release_to_done: Vec<u64>,
    /// CPU time per tick over 100 ms windows: of the process, and of its ticking thread.
    cpu: Vec<u64>,
    thread_cpu: Vec<u64>,
    /// Past the warm-up.
    recording: bool,
}

impl Seen {
    /// The measurement, with the tick errors and missed ticks worked out by the caller.
    fn measured(&self, errors: &[u64], missed: u64) -> anyhow::Result<Measured> {
        if self.release_to_done.is_empty() || errors.is_empty() || self.cpu.is_empty() {
            bail!(
                "too little seen: {} tick errors, {} done notices, {} CPU samples",
                errors.len(),
                self.release_to_done.len(),
                self.cpu.len()
            );
        }
        let hist = |values: &[u64]| {
            let mut h = modbot_bench_kit::sample::histogram();
            for &v in values {
                h.saturating_record(v.max(1));
            }
            h
        };
        let mut buckets = std::collections::BTreeMap::new();
        for &e in errors {
            *buckets.entry(e / BUCKET_NS * BUCKET_NS).or_insert(0u64) += 1;
        }
        Ok(Measured {
            tick_error: hist(errors),
            buckets: buckets.into_iter().collect(),
            release_to_done: hist(&self.release_to_done),
            cpu_per_tick: hist(&self.cpu),
            thread_cpu_per_tick: hist(&self.thread_cpu),
            ticks: self.releases.len() as u64,
            missed,
            releases: 0,
            overruns: 0,
            stale: 0,
            remarks: Vec::new(),
        })
    }
}

/// Polls the tap every 2 ms for `plan.warm` (thrown away) and `plan.span`, and samples the
/// CPU time of `cpu_pid` (all its threads, and those named `thread`) every 100 ms. `poll`
/// appends what arrived.
fn observe(
    plan: &Plan,
    cpu_pid: u32,
    thread: Option<&str>,
    mut poll: impl FnMut(&mut Seen) -> anyhow::Result<()>,
    mut alive: impl FnMut() -> anyhow::Result<()>,
) -> anyhow::Result<Seen> {
    let start = Instant::now();
    let mut seen = Seen::default();
    let mut window: Option<(Instant, (u64, u64), u64)> = None;
    let mut last_tick = None;
    loop {
        poll(&mut seen)?;
        if let Some(&(t, _)) = seen.releases.last() {
            last_tick = Some(t);
        }
        let now = Instant::now();
        if !seen.recording && now - start >= plan.warm {
            seen.recording = true;
            seen.releases.clear();
            seen.release_to_done.clear();
        }
        if seen.recording {
            let due = window.is_none_or(|(at, _, _)| now - at >= Duration::from_millis(100));
            if let (true, Some(tick)) = (due, last_tick) {
                let ns = cpu_ns(cpu_pid, thread).context("the CPU time of the ticking process")?;
                if let Some((_, ns0, tick0)) = window {
                    if tick > tick0 {
                        seen.cpu.push((ns.0 - ns0.0) / (tick - tick0));
                        seen.thread_cpu.push((ns.1 - ns0.1) / (tick - tick0));
                    }
                }
                window = Some((now, ns, tick));
            }
            if now - start >= plan.warm + plan.span {
                break;
            }
        }
        alive()?;
        procs::check_interrupted()?;
        std::thread::sleep(Duration::from_millis(2));
    }
    if seen.releases.len() < 100 {
        bail!(
            "only {} ticks seen in {:?}: the grid does not tick",
            seen.releases.len(),
            plan.span
        );
    }
    Ok(seen)
}

/// The tick errors of wake-up stamps `(tick, ns)` whose exact median is `median_ns`, and the
/// ticks missed between the first and the last.
///
/// Tick n is due at start + k·T (k ≥ n: k − n ticks were missed before it) and a wake-up is
/// never early nor a period late (then it is a missed tick), so its error is
/// (stamp − start) mod T. Only the start's phase is unknown outside the coordinator; it is set
/// so that the median error is the coordinator's own (its ledger): the distribution's shape
/// is from the stamps, its position from the ledger.
fn calibrated_errors(releases: &[(u64, u64)], median_ns: u64) -> (Vec<u64>, u64) {
    let p = PERIOD_NS;
    let x: Vec<u64> = releases.iter().map(|&(_, t)| t % p).collect();
    if x.is_empty() {
        return (Vec::new(), 0);
    }
    // The circular median: turn the circle so the densest 50 µs sit in the middle, take the
    // median there, turn back.
    let c = densest(&x, 50_000);
    let half = p / 2;
    let mut y: Vec<u64> = x.iter().map(|&v| (v + p + half - c) % p).collect();
    y.sort_unstable();
    let median_x = (y[y.len() / 2] + c + p - half) % p;
    let phase = (median_x + p - median_ns % p) % p;
    let errors: Vec<u64> = x.iter().map(|&v| (v + p - phase) % p).collect();
    // k − n at the first and the last tick.
    let behind = |i: usize| {
        let (n, t) = releases[i];
        let k = (t - errors[i] - phase) / p;
        k as i128 - i128::from(n)
    };
    let missed = (behind(releases.len() - 1) - behind(0)).max(0) as u64;
    (errors, missed)
}

/// The middle of the window of width `w` on the circle of one period that holds the most of
/// `x`.
fn densest(x: &[u64], w: u64) -> u64 {
    let p = PERIOD_NS;
    let mut v: Vec<u64> = x.to_vec();
    v.sort_unstable();
    let doubled: Vec<u64> = v.iter().copied().chain(v.iter().map(|a| a + p)).collect();
    let (mut best, mut at, mut j) = (0, v[0], 0);
    for i in 0..v.len() {
        j = j.max(i);
        while j < doubled.len() && doubled[j] < doubled[i] + w {
            j += 1;
        }
        if j - i > best {
            best = j - i;
            at = doubled[i];
        }
    }
    (at + w / 2) % p
}

/// CPU time of every thread of process `pid`, and of its threads named `thread` (all of them
/// when `None`), in ns (`/proc/PID/task/*/schedstat`, `comm`).
fn cpu_ns(pid: u32, thread: Option<&str>) -> Option<(u64, u64)> {
    let tasks = std::fs::read_dir(format!("/proc/{pid}/task")).ok()?;
    let (mut total, mut named) = (0, 0);
    for t in tasks.flatten() {
        let text = std::fs::read_to_string(t.path().join("schedstat")).unwrap_or_default();
        let ns = text
            .split_whitespace()
            .next()
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0);
        total += ns;
        let comm = std::fs::read_to_string(t.path().join("comm")).unwrap_or_default();
        if thread.is_none_or(|name| comm.trim() == name) {
            named += ns;
        }
    }
    Some((total, named))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_errors_take_their_median_from_the_ledger_and_a_late_wake_up_is_a_missed_tick() {
        let start = 5_000_000_000u64 + 999_990; // the phase sits at the end of the circle
        let releases = [
            (0, start + 10_000),
            (1, start + PERIOD_NS + 4_000),
            (2, start + 2 * PERIOD_NS + 50_000),
            // Woke 1.2 periods late: tick 3 is run at expiration 4, 200 µs after it.
            (3, start + 4 * PERIOD_NS + 200_000),
            (4, start + 5 * PERIOD_NS + 12_000),
        ];
        let (errors, missed) = calibrated_errors(&releases, 12_000);
        assert_eq!(errors, vec![10_000, 4_000, 50_000, 200_000, 12_000]);
        assert_eq!(missed, 1);
    }

    #[test]
    fn the_densest_window_is_found_across_the_end_of_the_period() {
        let x = [999_000, 999_500, 1_000, 2_000, 500_000];
        let c = densest(&x, 50_000);
        assert!(!(50_000..=950_000).contains(&c), "{c}");
    }

    #[test]
    fn the_grid_has_ten_components_on_five_hosts() {
        let d = Domain::new("bench_test_grid").unwrap();
        let text = description(&d, true, false);
        assert_eq!(text.matches("component \"").count(), 10);
        for h in ["h1", "h2", "h3", "h4", "h5"] {
            assert!(text.contains(&format!("host = \"{h}\"")));
        }
        assert!(text.contains("priority = 60"));
        assert!(!description(&d, false, false).contains("priority"));
    }

    #[test]
    fn stamps_read_back() {
        let mut b = [0u8; STAMP * 8];
        for (i, chunk) in b.chunks_exact_mut(8).enumerate() {
            chunk.copy_from_slice(&(i as u64 + 7).to_le_bytes());
        }
        assert_eq!(read_stamp(&b), Some([7, 8, 9, 10]));
        assert_eq!(read_stamp(&b[..10]), None);
    }
}

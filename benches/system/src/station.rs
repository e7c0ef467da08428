//! Benchmark 11, station: what watching a system costs it, and how often the station looks at a
//! full one.
//!
//! 1. **Watched against not watched.** `examples/arm.lua` holding (its grid at 1 kHz under
//!    SCHED_FIFO, as the example declares) and a busy call pair (the calls benchmark's echo
//!    module, 64 B, both sides busy-polling, in a domain of its own), measured in alternating
//!    blocks (ABC, then CBA) without anything attached, with `modbot-station` attached to the
//!    arm's domain, and with the station and two headless chromium pages open on it (started
//!    for their block, stopped after it). Each block:
//!    a span of the grid with the echo module stopped (SIGSTOP: it would spin a core), the missed
//!    ticks and the components' overruns counted from the coordinator's ledger at both ends; then
//!    the busy calls, the echo module continued. Rows (param `station`: `none`, the baseline,
//!    `no browser` or `2 browsers`): `station.grid_ticks`, `station.grid_missed`, `station.grid_overruns` (counts
//!    over all blocks of a side), `station.busy_call` (ns; its ratio the median of the blocks'
//!    ratios of medians).
//! 2. **Looks at a full system.** The station against `examples/fleet.lua` at 253 modules, and
//!    against the arm (3 modules: its two hosts and the coordinator) as the baseline, one page open: the intervals between its looks
//!    and how long each look took, from its `/api/state` polled every 5 ms. Row
//!    `station.look_interval` and `station.look_time` (param `modules`).
//!
//! The target: watching stays within noise (ratio ≤ 1.05) for missed ticks, overruns and the
//! busy call's p50; a count is within noise too when it grows by less than one in 10 000 ticks,
//! or by less per block than the unwatched blocks lie apart from each other (rows
//! `station.grid_missed_spread`, `station.grid_overruns_spread`: on a shared 2-core machine the
//! grid's misses move by tens from one 15-s span to the next with nothing attached). And the station looks ten
//! times a second at 253 modules (look interval p99 ≤ 150 ms).
//!
//! Needs Debian's chromium at `/usr/bin/chromium` (`./setup.sh --tests` installs it).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use hdrhistogram::Histogram;
use modbot_bench_ipc::paths::{ModbotPath, Path as CallPath, LOOK};
use modbot_bench_kit::arm_system::start_arm;
use modbot_bench_kit::interleave::Blocks;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row, Target};
use modbot_bench_kit::sample::{self, Plan};
use modbot_bench_kit::supervised::Supervised;
use modbot_core::ReceiveMode;
use modbot_ipc_schema::ledger;
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;
use serde_json::Value as Json;

/// Debian's chromium.
pub const CHROMIUM: &str = "/usr/bin/chromium";
/// The busy call's payload.
const PAYLOAD: usize = 64;
/// How many pages watch in the watched blocks.
const BROWSERS: usize = 2;
/// Watching is within noise up to this ratio.
pub const RATIO_LIMIT: f64 = 1.05;
/// A count that grows by less than this share of the ticks is within noise.
pub const COUNT_FLOOR: f64 = 1e-4;
/// The station's look interval at 253 modules: p99 at most this (ten looks a second).
pub const LOOK_P99_LIMIT_NS: u64 = 150_000_000;

/// The sides: nothing attached (the baseline), the station alone, the station and browsers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Alone,
    Station,
    Watched,
}

impl Side {
    const ALL: [Side; 3] = [Side::Alone, Side::Station, Side::Watched];

    fn label(self) -> &'static str {
        match self {
            Side::Alone => "none",
            Side::Station => "no browser",
            Side::Watched => "2 browsers",
        }
    }

    fn browsers(self) -> Option<usize> {
        match self {
            Side::Alone => None,
            Side::Station => Some(0),
            Side::Watched => Some(BROWSERS),
        }
    }
}

/// What one side measured over its blocks.
struct Totals {
    ticks: u64,
    missed: u64,
    overruns: u64,
    calls: Histogram<u64>,
    /// Each block's busy-call median.
    medians: Vec<u64>,
    /// Each block's missed ticks and overruns.
    blocks: Vec<(u64, u64)>,
}

/// How far apart a side's blocks lie: the largest minus the smallest count of `pick`.
fn spread(t: &Totals, pick: impl Fn(&(u64, u64)) -> u64) -> u64 {
    let counts: Vec<u64> = t.blocks.iter().map(pick).collect();
    counts.iter().max().unwrap_or(&0) - counts.iter().min().unwrap_or(&0)
}

impl Totals {
    fn new() -> Totals {
        Totals {
            ticks: 0,
            missed: 0,
            overruns: 0,
            calls: sample::histogram(),
            medians: Vec::new(),
            blocks: Vec::new(),
        }
    }
}

/// Runs the station benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    if !Path::new(CHROMIUM).exists() {
        bail!("needs Debian's chromium at {CHROMIUM} (./setup.sh --tests installs it)");
    }
    watched_against_alone(opts, report)?;
    looks_at_full_scale(opts, report)?;
    Ok(())
}

/// Part 1: the arm and a busy call, without and with a station and two browsers.
fn watched_against_alone(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    let blocks = if opts.quick { 2 } else { 4 };
    let span = Duration::from_secs(if opts.quick { 4 } else { 15 });
    let plan = Plan {
        warm: 2_000,
        n: if opts.quick { 5_000 } else { 20_000 },
        cap: Duration::from_secs(5),
    };
    let mut scratch = Scratch::new("station", None)?;
    let profiles: Vec<PathBuf> = (0..BROWSERS)
        .map(|i| scratch.path(&format!("chromium{i}")))
        .collect();
    let (mut sys, _) = start_arm(opts, &scratch, &[])?;
    let mut echo = ModbotPath::open(
        opts,
        ReceiveMode::BusyPoll,
        modbot_core::domain::DEFAULT_MAX_FRAME,
        None,
        LOOK,
    )?;
    let echo_pid = echo.server().pid();
    signal(echo_pid, Signal::SIGSTOP)?;
    let payload = vec![0x5a_u8; PAYLOAD];
    let mut totals = [Totals::new(), Totals::new(), Totals::new()];
    for block in 0..blocks {
        let mut order = Side::ALL;
        if block % 2 == 1 {
            order.reverse();
        }
        for side in order {
            let watching = match side.browsers() {
                None => None,
                Some(n) => Some(Watching::start(opts, &scratch.domain, &profiles, n)?),
            };
            sys.sleep(Duration::from_secs(1))?;
            let before = grid(&mut sys)?;
            sys.sleep(span)?;
            let after = grid(&mut sys)?;
            signal(echo_pid, Signal::SIGCONT)?;
            let calls = sample::record(&plan, || echo.one(&payload));
            signal(echo_pid, Signal::SIGSTOP)?;
            let calls = calls?;
            if let Some(w) = watching {
                w.stop()?;
            }
            let t = &mut totals[side as usize];
            let missed = after.missed.saturating_sub(before.missed);
            let overruns = after.overruns.saturating_sub(before.overruns);
            t.ticks += after.ticks.saturating_sub(before.ticks);
            t.missed += missed;
            t.overruns += overruns;
            t.blocks.push((missed, overruns));
            t.medians.push(calls.value_at_quantile(0.5));
            t.calls.add(&calls).context("merging the call samples")?;
        }
    }
    signal(echo_pid, Signal::SIGCONT)?;
    echo.close(report, &[PAYLOAD])?;
    let left = sys.stop()?;
    drop(scratch);

    let [alone, station, watched] = &totals;
    for (t, side) in [
        (alone, Side::Alone),
        (station, Side::Station),
        (watched, Side::Watched),
    ] {
        let count = |name: &str, n: u64| {
            let row = Row::single(name, n)
                .unit("count")
                .param("station", side.label());
            match side {
                Side::Alone => row.is_baseline(),
                _ => row.against(name, &[("station", "none".into())]),
            }
        };
        report.push(count("station.grid_ticks", t.ticks));
        report.push(count("station.grid_missed", t.missed));
        report.push(count("station.grid_overruns", t.overruns));
        if side == Side::Alone {
            // The noise of a count: how far the unwatched blocks lie apart.
            for (name, n) in [
                ("station.grid_missed_spread", spread(t, |b| b.0)),
                ("station.grid_overruns_spread", spread(t, |b| b.1)),
            ] {
                report.push(count(name, n));
            }
        }
        let call = Row::from_histogram("station.busy_call", &t.calls)
            .param("station", side.label())
            .param("bytes", PAYLOAD)
            .param("blocks", blocks);
        report.push(match side {
            Side::Alone => call.is_baseline(),
            _ => {
                let ratios: Vec<f64> = t
                    .medians
                    .iter()
                    .zip(&alone.medians)
                    .map(|(w, a)| *w as f64 / (*a).max(1) as f64)
                    .collect();
                call.against("station.busy_call", &[("station", "none".into())])
                    .blocks(Blocks::of(&ratios))
            }
        });
    }
    let three =
        |f: &dyn Fn(&Totals) -> u64| format!("{} / {} / {}", f(alone), f(station), f(watched));
    let mut note = format!(
        "station: examples/arm.lua holding, {blocks} blocks of {} s per side (ABC, then CBA), \
         without, with modbot-station alone, and with it and {BROWSERS} headless chromium pages \
         on it: grid ticks {}, missed {}, overruns {}; busy call ({PAYLOAD} B, both sides \
         busy-polling, a domain of its own) p50 {} ns (none / station / station and browsers)",
        span.as_secs(),
        three(&|t| t.ticks),
        three(&|t| t.missed),
        three(&|t| t.overruns),
        three(&|t| t.calls.value_at_quantile(0.5)),
    );
    if !left.is_empty() {
        note.push_str(&format!(
            "; {} file(s) of the arm's domain were left after the stop and removed",
            left.len()
        ));
    }
    report.note(note);
    Ok(())
}

/// Part 2: the station's looks at 253 modules against its looks at the arm's 3.
fn looks_at_full_scale(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    let span = Duration::from_secs(if opts.quick { 5 } else { 20 });
    let mut rows = Vec::new();
    for (what, modules) in [("arm", 3_u64), ("fleet", 253)] {
        let mut scratch = Scratch::new(&format!("station_{what}"), None)?;
        let profile = scratch.path("chromium");
        let mut sys = match what {
            "arm" => start_arm(opts, &scratch, &[])?.0,
            _ => start_fleet(opts, &scratch)?,
        };
        let watching = Watching::start(opts, &scratch.domain, &[profile], 1)?;
        // Wait until every module has been described once, then look.
        sys.sleep(Duration::from_secs(2))?;
        let (interval, took, seen) = watching.sample_looks(span)?;
        watching.stop()?;
        let left = sys.stop()?;
        drop(scratch);
        if seen != modules as usize {
            bail!("the station saw {seen} modules of {what}, not {modules}");
        }
        if !left.is_empty() {
            report.note(format!(
                "station: {} file(s) of the {what} domain were left after the stop and removed",
                left.len()
            ));
        }
        rows.push((modules, interval, took));
    }
    for (modules, interval, took) in rows {
        for (name, h) in [
            ("station.look_interval", &interval),
            ("station.look_time", &took),
        ] {
            let row = Row::from_histogram(name, h).param("modules", modules);
            report.push(if modules == 3 {
                row.is_baseline()
            } else {
                row.against(name, &[("modules", 3.into())])
            });
        }
    }
    Ok(())
}

/// `examples/fleet.lua` at 253 modules (249 sensors, 4 aggregators).
fn start_fleet(opts: &Opts, scratch: &Scratch) -> anyhow::Result<Supervised> {
    let file = modbot_bench_kit::checkout::existing_example("fleet.lua")?;
    let args = [
        "--var".to_owned(),
        format!("domain={}", scratch.domain.name()),
        "--var".to_owned(),
        "n=249".to_owned(),
    ];
    let mut sys = Supervised::start(opts, &scratch.domain, &file, &args, Duration::from_secs(30))?;
    sys.wait_up(Duration::from_secs(120))?;
    Ok(sys)
}

/// The grid's counters from the coordinator's ledger.
struct GridCounts {
    ticks: u64,
    missed: u64,
    overruns: u64,
}

fn grid(sys: &mut Supervised) -> anyhow::Result<GridCounts> {
    let bytes = sys.call_bytes("coordinator", "ledger")?;
    let (grid, components) = ledger::decode(&bytes).context("the coordinator's ledger")?;
    Ok(GridCounts {
        ticks: grid.ticks,
        missed: grid.missed,
        overruns: components.iter().map(|c| c.overruns).sum(),
    })
}

fn signal(pid: u32, sig: Signal) -> anyhow::Result<()> {
    let raw = i32::try_from(pid).context("pid out of range")?;
    kill(Pid::from_raw(raw), sig).with_context(|| format!("{sig} to {pid}"))
}

/// A station on a domain and the browsers open on its page; each in a process group of its
/// own, stopped (SIGTERM, then SIGKILL) when dropped.
struct Watching {
    station: Group,
    browsers: Vec<Group>,
    url: String,
}

impl Watching {
    /// Starts the station, then `n` browsers on its page with the profiles `profiles[..n]`;
    /// returns when the station counts them.
    fn start(
        opts: &Opts,
        domain: &modbot_core::Domain,
        profiles: &[PathBuf],
        n: usize,
    ) -> anyhow::Result<Watching> {
        let mut cmd = Command::new(procs::binary(opts, "modbot-station")?);
        cmd.args(["--domain", domain.name(), "--listen", "127.0.0.1:0"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        let mut station = Group::spawn(cmd, "modbot-station")?;
        let out = station
            .child
            .stdout
            .take()
            .context("the station's stdout")?;
        let url = station_url(out)?;
        let mut watching = Watching {
            station,
            browsers: Vec::new(),
            url,
        };
        for profile in &profiles[..n] {
            let mut cmd = Command::new(CHROMIUM);
            cmd.args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--no-first-run",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(&watching.url)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
            watching.browsers.push(Group::spawn(cmd, "chromium")?);
        }
        let end = Instant::now() + Duration::from_secs(60);
        loop {
            let state = watching.state()?;
            if state.get("pages").and_then(Json::as_u64) == Some(n as u64) {
                return Ok(watching);
            }
            watching.station.check_running()?;
            procs::check_interrupted()?;
            if Instant::now() > end {
                bail!("the station did not count {n} page(s) within 60 s");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// The station's state (`/api/state`).
    fn state(&self) -> anyhow::Result<Json> {
        let body = get(&self.url, "/api/state")?;
        serde_json::from_str(&body).context("the station's /api/state is not JSON")
    }

    /// Polls the state every 5 ms for `span`: the intervals between the looks (ns), how long
    /// each look took (ns), and how many modules the last look listed.
    fn sample_looks(
        &self,
        span: Duration,
    ) -> anyhow::Result<(Histogram<u64>, Histogram<u64>, usize)> {
        let (mut interval, mut took) = (sample::histogram(), sample::histogram());
        let mut last: Option<u64> = None;
        let mut modules = 0;
        let end = Instant::now() + span;
        while Instant::now() < end {
            let state = self.state()?;
            let t = state.get("t_ms").and_then(Json::as_u64).unwrap_or(0);
            if last.is_none_or(|l| t > l) {
                if let Some(l) = last {
                    interval.saturating_record((t - l) * 1_000_000);
                }
                let ms = state.get("look_ms").and_then(Json::as_u64).unwrap_or(0);
                took.saturating_record((ms * 1_000_000).max(1));
                modules = state
                    .get("modules")
                    .and_then(Json::as_array)
                    .map_or(0, Vec::len);
                last = Some(t);
            }
            procs::check_interrupted()?;
            std::thread::sleep(Duration::from_millis(5));
        }
        if interval.is_empty() {
            bail!("the station looked less than twice in {} s", span.as_secs());
        }
        Ok((interval, took, modules))
    }

    /// Stops the browsers, then the station, which must end cleanly.
    fn stop(mut self) -> anyhow::Result<()> {
        for b in self.browsers.drain(..) {
            drop(b);
        }
        let status = self.station.terminate()?;
        if !status.success() {
            bail!("the station ended with {status}");
        }
        Ok(())
    }
}

/// Reads the station's first lines until its address: `... at http://HOST:PORT/...`.
fn station_url(out: std::process::ChildStdout) -> anyhow::Result<String> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if let Some((_, rest)) = line.split_once(" at http://") {
                let end = rest
                    .find(|c: char| c.is_whitespace() || c == '?')
                    .unwrap_or(rest.len());
                let _ = tx.send(format!("http://{}", &rest[..end]));
            }
        }
    });
    rx.recv_timeout(Duration::from_secs(30))
        .context("the station did not print its address within 30 s")
}

/// A GET of `path` (HTTP/1.0, the whole answer's body).
fn get(url: &str, path: &str) -> anyhow::Result<String> {
    let host = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = TcpStream::connect(host).with_context(|| format!("connecting to {host}"))?;
    s.set_read_timeout(Some(Duration::from_secs(10)))?;
    write!(s, "GET {path} HTTP/1.0\r\nHost: {host}\r\n\r\n")?;
    let mut answer = String::new();
    s.read_to_string(&mut answer)?;
    match answer.split_once("\r\n\r\n") {
        Some((head, body)) if head.starts_with("HTTP/1.") && head.contains(" 200 ") => {
            Ok(body.to_owned())
        }
        _ => bail!(
            "GET {path}: {}",
            answer.lines().next().unwrap_or("no answer")
        ),
    }
}

/// A process leading a group of its own: signals go to the whole group (a browser's helpers).
struct Group {
    child: Child,
    label: &'static str,
    /// Its leader was reaped: the group id may be another's now.
    ended: Option<std::process::ExitStatus>,
}

impl Group {
    fn spawn(mut cmd: Command, label: &'static str) -> anyhow::Result<Group> {
        cmd.process_group(0);
        modbot_bench_kit::supervised::die_with_parent(&mut cmd);
        let child = cmd
            .spawn()
            .with_context(|| format!("cannot start {label} ({cmd:?})"))?;
        Ok(Group {
            child,
            label,
            ended: None,
        })
    }

    fn check_running(&mut self) -> anyhow::Result<()> {
        match self.child.try_wait()? {
            Some(status) => bail!("{} exited early ({status})", self.label),
            None => Ok(()),
        }
    }

    /// SIGTERM to the group, 10 s, then SIGKILL to the group; how the leader ended.
    fn terminate(&mut self) -> anyhow::Result<std::process::ExitStatus> {
        if let Some(status) = self.ended {
            return Ok(status);
        }
        let group = Pid::from_raw(-i32::try_from(self.child.id()).unwrap_or(i32::MAX));
        let _ = kill(group, Signal::SIGTERM);
        let end = Instant::now() + Duration::from_secs(10);
        let status = loop {
            if let Some(status) = self.child.try_wait()? {
                break status;
            }
            if Instant::now() > end {
                let _ = kill(group, Signal::SIGKILL);
                break self.child.wait()?;
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        // What is left of the group (a browser's helpers) goes too.
        let _ = kill(group, Signal::SIGKILL);
        self.ended = Some(status);
        Ok(status)
    }
}

impl Drop for Group {
    fn drop(&mut self) {
        if let Err(e) = self.terminate() {
            eprintln!("warning: stopping {}: {e}", self.label);
        }
    }
}

/// The station's targets.
pub fn targets(report: &Report) -> Vec<Target> {
    use modbot_bench_kit::targets::{rows_with, target};
    let side = |name: &str, label: &str| {
        rows_with(report, name, &[("station", Json::from(label))])
            .first()
            .map(|r| (r.p50_ns, r.ratio))
    };
    let mut out = Vec::new();
    let measure = "a station and two browsers attached: grid missed ticks, overruns, busy call p50";
    let goal = "within noise of none attached (ratio ≤ 1.05)";
    let ticks = side("station.grid_ticks", "none").map(|(n, _)| n);
    let blocks = rows_with(
        report,
        "station.busy_call",
        &[("station", Json::from("none"))],
    )
    .first()
    .and_then(|r| r.params.get("blocks").and_then(Json::as_u64))
    .unwrap_or(1)
    .max(1);
    let counts = ["station.grid_missed", "station.grid_overruns"].map(|name| {
        (
            name,
            side(name, "none").map(|(n, _)| n),
            side(name, "2 browsers").map(|(n, _)| n),
            side(&format!("{name}_spread"), "none").map_or(0, |(n, _)| n),
        )
    });
    let call = side("station.busy_call", "2 browsers").and_then(|(_, r)| r);
    out.push(match (ticks, call) {
        (Some(ticks), Some(call)) => watching_target(measure, goal, ticks, call, blocks, &counts),
        _ => target(
            measure,
            goal,
            "not measured in this run (`modbot-benches station`, with chromium)".to_owned(),
            None,
        ),
    });
    let look = rows_with(
        report,
        "station.look_interval",
        &[("modules", Json::from(253))],
    )
    .first()
    .map(|r| (r.p50_ns, r.p99_ns));
    out.push(match look {
        Some((p50, p99)) => target(
            "the station's looks at 253 modules",
            "ten a second: look interval p99 ≤ 150 ms",
            format!(
                "interval p50 {:.0} ms, p99 {:.0} ms",
                p50 as f64 / 1e6,
                p99 as f64 / 1e6
            ),
            Some(p99 <= LOOK_P99_LIMIT_NS),
        ),
        None => target(
            "the station's looks at 253 modules",
            "ten a second: look interval p99 ≤ 150 ms",
            "not measured in this run".to_owned(),
            None,
        ),
    });
    out
}

/// The first target: watching within noise, from the totals of both sides.
fn watching_target(
    measure: &str,
    goal: &str,
    ticks: u64,
    call: f64,
    blocks: u64,
    counts: &[(&str, Option<u64>, Option<u64>, u64)],
) -> Target {
    let mut met = call <= RATIO_LIMIT;
    let mut parts = vec![format!("busy call p50 ×{call:.3}")];
    for &(name, alone, watched, spread) in counts {
        let (Some(a), Some(w)) = (alone, watched) else {
            continue;
        };
        // Within noise: at most 5 % more, or less than one in 10 000 ticks more, or more by
        // less per block than the unwatched blocks lie apart from each other.
        let excess = w.saturating_sub(a);
        let ok = (w as f64) <= a as f64 * RATIO_LIMIT
            || (excess as f64) < COUNT_FLOOR * ticks as f64
            || excess / blocks <= spread;
        met &= ok;
        parts.push(format!(
            "{} {w} against {a} in ~{ticks} ticks ({} more per block; unwatched blocks {spread} apart)",
            name.trim_start_matches("station.grid_"),
            excess / blocks
        ));
    }
    modbot_bench_kit::targets::target(measure, goal, parts.join("; "), Some(met))
}

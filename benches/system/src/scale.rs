//! Benchmark 4, scale: systems of 2 to 253 modules under `modbot up`, each module talking to
//! four peers. At each size:
//!
//! - startup: from spawning `modbot up` to the supervisor's line "all N module(s) up" (every
//!   module announced itself and sent its first heartbeat);
//! - /dev/shm: the allocated blocks (`st_blocks` × 512) of the domain's files, once every
//!   module has reached its peers;
//! - memory per module process: Pss (shared pages divided among their users) and Rss, from
//!   `/proc/PID/smaps_rollup`, one sample per module;
//! - call round trip: module `m1` calls method `echo` (no arguments: a 5-byte EXEC, a 3-byte
//!   ACK) of module `m2`, both in busy-poll mode on cores 0 and 1, while every other module
//!   sleeps in blocking mode and keeps calling its peers. The same method at every size.
//!
//! "Talking to 4 peers": module `mI` calls `m(I+1)` and `m(I+2)` (wrapping around) and answers
//! `m(I-1)` and `m(I-2)`, so it opens publishers to exactly four peers' inboxes (fewer at two
//! modules) — the topology of the raw iceoryx2 measurement in `../shared/notes/iceoryx2-0.10.md`.
//! It calls each peer (once a second) until it answered once, then one of them every ten seconds.
//!
//! The module program is this executable (`child scale-module`), started by the supervisor
//! through a two-line `sh` wrapper (the supervisor puts `--domain`, `--name`, `--addr` and
//! `--mode` before a program's own arguments, and this executable expects `child ROLE` first).
//!
//! Addresses are 1..=254 and the supervisor takes one for itself, so a description holds at
//! most 253 modules; the largest size is 253 modules plus the supervisor: 254 endpoints.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use hdrhistogram::Histogram;
use modbot_bench_kit::memory::{memory_of, shm_bytes};
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::supervised::Supervised;
use modbot_core::{
    CallError, CallHandle, CallOptions, Ctx, Domain, IpcTransport, MethodError, Module,
    ModuleBuilder, ReceiveMode, Reply, RetryPolicy,
};
use modbot_ipc_schema::{Args, Value};

/// The most modules a description can hold: 254 addresses, one of them the supervisor's.
pub const MAX_MODULES: usize = 253;

/// Runs the scale benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    if procs::cores() < 2 {
        bail!("the call round trip needs two cores (two busy-poll modules)");
    }
    let sizes = sizes(opts)?;
    let calls = opts.samples(5_000, 50_000);
    // Quick runs share three minutes among six benchmarks: this one gets about a minute.
    let budget = if opts.quick {
        Duration::from_secs(60)
    } else {
        Duration::from_secs(1800)
    };
    let started = Instant::now();
    let mut measured: Vec<Measured> = Vec::new();
    for &n in &sizes {
        // A size's measurement is fixed waits (settling, idle CPU) plus what grows about
        // linearly with the module count (start-up, stop): skip a size whose measurement,
        // predicted in proportion to the count from the last size, would not fit in what is
        // left.
        let left = budget.saturating_sub(started.elapsed());
        // From 2 modules the fixed costs dominate: no prediction.
        if let Some(last) = measured.last().filter(|m| m.modules >= 16) {
            let k = n as f64 / last.modules as f64;
            let predicted = last.took.mul_f64(k);
            if predicted > left {
                report.note(format!(
                    "scale: {n} modules not measured in this {} run: from {} modules (up in {:.1} s, \
                     measured in {:.1} s) it would take about {:.0} s, and {:.0} s are left",
                    if opts.quick { "quick" } else { "full" },
                    last.modules,
                    last.startup.as_secs_f64(),
                    last.took.as_secs_f64(),
                    predicted.as_secs_f64(),
                    left.as_secs_f64()
                ));
                continue;
            }
        }
        let t = Instant::now();
        match measure(opts, n, calls, left) {
            Ok(m) => {
                eprintln!(
                    "scale: {n} modules measured in {:.1} s",
                    t.elapsed().as_secs_f64()
                );
                measured.push(m);
            }
            Err(e) if n == 2 => {
                return Err(e.context("scale: the 2-module baseline could not be measured"))
            }
            Err(e) => report.note(format!("scale: {n} modules: {e:#}")),
        }
    }
    for m in &measured {
        push_rows(report, m);
    }
    report.note(comparison(&measured));
    Ok(())
}

/// The module counts to measure: `MODBOT_BENCH_SCALE_SIZES` (comma-separated, e.g. `2,128`)
/// if set, else 2, 16 and 64 (quick) or 2, 16, 32, 64, 128 and 253. The first is the baseline
/// of the others.
fn sizes(opts: &Opts) -> anyhow::Result<Vec<usize>> {
    if let Ok(text) = std::env::var("MODBOT_BENCH_SCALE_SIZES") {
        let sizes = text
            .split(',')
            .map(|w| w.trim().parse::<usize>())
            .collect::<Result<Vec<_>, _>>()
            .with_context(|| format!("MODBOT_BENCH_SCALE_SIZES={text}: expected numbers"))?;
        if sizes.first() != Some(&2) || sizes.iter().any(|&n| !(2..=MAX_MODULES).contains(&n)) {
            bail!(
                "MODBOT_BENCH_SCALE_SIZES={text}: 2 first (the baseline), then up to {MAX_MODULES}"
            );
        }
        return Ok(sizes);
    }
    Ok(if opts.quick {
        vec![2, 16, 64]
    } else {
        vec![2, 16, 32, 64, 128, MAX_MODULES]
    })
}

/// The child roles of this benchmark.
pub fn child(role: &str, args: &[String]) -> Option<anyhow::Result<()>> {
    match role {
        "scale-module" => Some(scale_module(args)),
        _ => None,
    }
}

/// What one size gave.
struct Measured {
    /// What went wrong on the way (a slow stop, files left).
    remarks: Vec<String>,
    /// /dev/shm by kind of iceoryx2 file: (suffix, files, bytes), largest first.
    shm_kinds: Vec<(String, usize, u64)>,
    modules: usize,
    /// The whole measurement, start to stop.
    took: Duration,
    startup: Duration,
    /// CPU time of all module processes per second of wall time while they only talk to
    /// their peers (1.0 = one core).
    idle_cpu: f64,
    shm_bytes: u64,
    pss: Histogram<u64>,
    rss: Histogram<u64>,
    call: Histogram<u64>,
    /// `modbot ls`, start to exit, three times.
    ls: Histogram<u64>,
    /// Modules SIGKILLed (at 64 modules and more): from the kill to answering a call again.
    recovery: Histogram<u64>,
}

fn push_rows(report: &mut Report, m: &Measured) {
    let n = m.modules as u64;
    let base = |row: Row, name: &str| {
        if n == 2 {
            row.is_baseline()
        } else {
            row.against(name, &[("modules", 2.into())])
        }
    };
    report.push(base(
        Row::single("scale.startup", m.startup.as_nanos() as u64).param("modules", n),
        "scale.startup",
    ));
    report.push(base(
        Row::single("scale.shm_bytes", m.shm_bytes)
            .param("modules", n)
            .unit("bytes"),
        "scale.shm_bytes",
    ));
    for (measure, h) in [("pss", &m.pss), ("rss", &m.rss)] {
        report.push(base(
            Row::from_histogram("scale.rss_per_module", h)
                .param("modules", n)
                .param("measure", measure)
                .unit("bytes"),
            "scale.rss_per_module",
        ));
    }
    report.push(base(
        Row::from_histogram("scale.call", &m.call)
            .param("modules", n)
            .param("mode", "busy"),
        "scale.call",
    ));
    report.push(base(
        Row::single("scale.idle_cpu", (m.idle_cpu * 1000.0).round() as u64)
            .param("modules", n)
            .param("of", "supervisor and modules")
            .unit("permille of a core"),
        "scale.idle_cpu",
    ));
    report.push(base(
        Row::from_histogram("scale.ls", &m.ls).param("modules", n),
        "scale.ls",
    ));
    if !m.recovery.is_empty() {
        report.push(
            Row::from_histogram("scale.recovery", &m.recovery)
                .param("modules", n)
                .param("fault", "SIGKILL")
                .is_baseline(),
        );
    }
}

/// The report note: every size in one line each, next to the raw iceoryx2 figures.
fn comparison(measured: &[Measured]) -> String {
    let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
    let sizes: Vec<String> = measured
        .iter()
        .map(|m| {
            format!(
                "{} modules: up in {:.2} s, {:.1} MiB of /dev/shm, Pss p50 {:.1} MiB (Rss {:.1} MiB), \
                 the idle system (supervisor included) uses {:.1} % of one core, `modbot ls` p50 {:.0} ms, call p50 {:.2} µs p99 {:.1} µs ({} \
                 calls){}",
                m.modules,
                m.startup.as_secs_f64(),
                mib(m.shm_bytes),
                mib(m.pss.value_at_quantile(0.5)),
                mib(m.rss.value_at_quantile(0.5)),
                m.idle_cpu * 100.0,
                m.ls.value_at_quantile(0.5) as f64 / 1e6,
                m.call.value_at_quantile(0.5) as f64 / 1e3,
                m.call.value_at_quantile(0.99) as f64 / 1e3,
                m.call.len(),
                m.remarks
                    .iter()
                    .map(|r| format!(", {r}"))
                    .collect::<String>()
            )
        })
        .collect();
    let kinds = measured
        .iter()
        .max_by_key(|m| m.modules)
        .map(|m| {
            let parts: Vec<String> = m
                .shm_kinds
                .iter()
                .take(4)
                .map(|(k, n, b)| format!("{n} .{k} files {:.1} MiB", mib(*b)))
                .collect();
            format!(" /dev/shm at {} modules: {}.", m.modules, parts.join(", "))
        })
        .unwrap_or_default();
    format!(
        "scale: {}.{kinds} Each module calls two peers and answers two (4 peers); the round trip is \
         m1 → m2 in busy-poll mode on cores 0 and 1 while the others sleep (blocking). A \
         description holds at most {MAX_MODULES} modules: addresses are 1..=254 and the \
         supervisor takes one, so the largest system is {MAX_MODULES} modules + the supervisor \
         = 254 endpoints; `modbot ls` then holds no address and goes through the supervisor's \
         relay. Raw iceoryx2 on these machines (notes: 254 processes, one inbox each, publishers \
         to ~4 peers, dead-node cleanup on open turned off): 12–16 MiB, up in 2–3 s, RTT \
         1.1–2.3 µs, RSS 5 MiB per process. The supervisor publishes the directory (modules \
         never scan iceoryx2's node files), cleans up after dead processes, and assigns \
         addresses and names without claim services; iceoryx2's node and service files are on \
         tmpfs. What remains per module: its node, inbox, wake-up event, heartbeat publisher and \
         the links to its peers (a .connection and a .data file each); on tmpfs each small file \
         is a 4 KiB page. Idle CPU counts the supervisor and every module (heartbeats once a \
         second, a task once a second); m1 and m2 wake every 10 ms between measurements. \
         Recovery: SIGKILL of a random module (not m1, m2) until it answers a call again: the \
         supervisor sees the end at once (SIGCHLD), restarts it after its backoff (100 ms).",
        sizes.join("; ")
    )
}

/// One size: start, settle, measure, stop.
fn measure(opts: &Opts, n: usize, calls: u64, budget: Duration) -> anyhow::Result<Measured> {
    let took = Instant::now();
    let deadline = took + budget.max(Duration::from_secs(30));
    let left = || deadline.saturating_duration_since(Instant::now());
    let cap = Duration::from_secs(if opts.quick { 4 } else { 20 });
    let mut scratch = Scratch::new(&format!("scale{n}"), None)?;
    let script = scratch.path("module.sh");
    std::fs::write(
        &script,
        format!(
            "#!/bin/sh\nexec '{}' child scale-module \"$@\"\n",
            opts.exe.display()
        ),
    )?;
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755))?;
    }
    let go = scratch.path("go");
    let results = scratch.path("rtt");
    let file = scratch.path("system.lua");
    std::fs::write(
        &file,
        description(&scratch.domain, n, &script, &go, &results, calls, cap),
    )?;
    // A big system stops one module after the other: give it time (a quick run kills it
    // sooner: the modules die with the supervisor, the files are removed after).
    let grace = Duration::from_secs(if opts.quick { 10 } else { 60 + n as u64 });
    let mut sys = Supervised::start(opts, &scratch.domain, &file, &[], grace)?;
    let startup = sys.wait_up(left())?;
    // Every module calls its peers within a few 100 ms tasks of starting: let them connect,
    // and measure what the modules cost meanwhile.
    let modules = children_of(sys.up_pid());
    if modules.len() != n {
        bail!(
            "{} module processes found under modbot up, expected {n}",
            modules.len()
        );
    }
    // Every module reaches its peers within its first talks (one a second): then the system
    // is idle, and what it costs is measured, the supervisor included.
    sys.sleep(Duration::from_millis(2500))?;
    let mut everyone = modules.clone();
    everyone.push(sys.up_pid());
    let cpu0 = cpu_ticks(&everyone);
    let t0 = Instant::now();
    sys.sleep(Duration::from_secs(3))?;
    let idle_cpu = cpu_ticks(&everyone).saturating_sub(cpu0) as f64
        / clock_ticks_per_second()
        / t0.elapsed().as_secs_f64();
    let shm_bytes = shm_bytes(&scratch.domain);
    let shm_kinds = shm_by_kind(&scratch.domain);
    let mut pss = modbot_bench_kit::sample::histogram();
    let mut rss = modbot_bench_kit::sample::histogram();
    for pid in &modules {
        if let Some((p, r)) = memory_of(*pid) {
            pss.saturating_record(p.max(1));
            rss.saturating_record(r.max(1));
        }
    }
    std::fs::write(&go, b"go")?;
    let text = sys.wait_for(
        "the round-trip results of m1",
        left().max(cap + Duration::from_secs(10)),
        || Ok(std::fs::read_to_string(&results).ok()),
    )?;
    let call = parse_results(&text)?;
    let ls = time_ls(opts, &scratch.domain, n)?;
    let recovery = if n >= 64 {
        kill_and_recover(&scratch.domain, &modules, left())?
    } else {
        modbot_bench_kit::sample::histogram()
    };
    let (status, leftover) = sys.stop_with_status()?;
    let mut remarks = Vec::new();
    if !status.is_some_and(|s| s.success()) {
        remarks.push(format!("modbot up ended with {status:?} after SIGTERM"));
    }
    if !leftover.is_empty() {
        remarks.push(format!(
            "{} file(s) of the domain were left after the stop (removed)",
            leftover.len()
        ));
    }
    Ok(Measured {
        remarks,
        shm_kinds,
        modules: n,
        took: took.elapsed(),
        startup,
        idle_cpu,
        shm_bytes,
        pss,
        rss,
        call,
        ls,
        recovery,
    })
}

/// `modbot ls` three times, start to exit; every run must list all `n` modules.
fn time_ls(opts: &Opts, domain: &Domain, n: usize) -> anyhow::Result<Histogram<u64>> {
    let modbot = procs::binary(opts, "modbot")?;
    let mut h = modbot_bench_kit::sample::histogram();
    for _ in 0..3 {
        let t = Instant::now();
        let out = std::process::Command::new(&modbot)
            .args(["ls", "--tsv", "--domain", domain.name()])
            .output()?;
        h.saturating_record(t.elapsed().as_nanos() as u64);
        let listed = String::from_utf8_lossy(&out.stdout)
            .lines()
            .skip(1)
            .filter(|l| l.contains("running"))
            .count();
        if !out.status.success() || listed != n {
            bail!(
                "modbot ls listed {listed} running modules of {n}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
    Ok(h)
}

/// Ten modules (not m1 or m2), picked at random, SIGKILLed one after the other: each time, how
/// long from the kill until it answers `echo` again (the supervisor sees the end at once and
/// restarts it after its backoff, 100 ms).
fn kill_and_recover(
    domain: &Domain,
    modules: &[u32],
    budget: Duration,
) -> anyhow::Result<Histogram<u64>> {
    use modbot_core::tool::{Calls, Tool};
    let mut tool = Tool::open(domain, "bench").context("the benchmark cannot join the domain")?;
    let mut h = modbot_bench_kit::sample::histogram();
    let deadline = Instant::now() + budget.min(Duration::from_secs(120));
    let mut rng = modbot_bench_kit::sample::Pick::new(modbot_bench_kit::sample::clock_seed());
    let mut names: Vec<(String, u32)> = tool
        .list_modules()?
        .into_iter()
        .filter(|p| p.alive && p.name.starts_with('m') && p.name != "m1" && p.name != "m2")
        .filter(|p| modules.contains(&p.pid))
        .map(|p| (p.name, p.pid))
        .collect();
    for _ in 0..10.min(names.len()) {
        let (name, pid) = &names.swap_remove(rng.below(names.len()));
        let killed = Instant::now();
        nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(*pid as i32),
            nix::sys::signal::Signal::SIGKILL,
        )?;
        // The old process may still answer for a moment: wait until it is gone.
        while nix::sys::signal::kill(nix::unistd::Pid::from_raw(*pid as i32), None).is_ok()
            && killed.elapsed() < Duration::from_secs(1)
        {
            std::thread::sleep(Duration::from_millis(1));
        }
        loop {
            let answered = tool.call_blocking(
                name,
                "echo",
                &[],
                CallOptions::timeout(Duration::from_millis(100)).with_retry(RetryPolicy::NONE),
                |r| r.is_ok(),
            );
            if answered {
                h.saturating_record(killed.elapsed().as_nanos() as u64);
                break;
            }
            if Instant::now() > deadline {
                bail!("{name} did not answer again within the benchmark's time");
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    Ok(h)
}

/// User and system CPU time of processes `pids`, in clock ticks.
fn cpu_ticks(pids: &[u32]) -> u64 {
    pids.iter()
        .filter_map(|p| std::fs::read_to_string(format!("/proc/{p}/stat")).ok())
        .filter_map(|text| {
            let fields: Vec<u64> = text
                .rsplit_once(')')?
                .1
                .split_whitespace()
                .skip(11)
                .take(2)
                .filter_map(|f| f.parse().ok())
                .collect();
            Some(fields.iter().sum::<u64>())
        })
        .sum()
}

fn clock_ticks_per_second() -> f64 {
    // SAFETY: sysconf only reads a configuration value.
    let hz = unsafe { nix::libc::sysconf(nix::libc::_SC_CLK_TCK) };
    if hz > 0 {
        hz as f64
    } else {
        100.0
    }
}

/// The system description of `n` modules.
fn description(
    domain: &Domain,
    n: usize,
    script: &Path,
    go: &Path,
    results: &Path,
    calls: u64,
    cap: Duration,
) -> String {
    let mut s = format!(
        "-- modbot-benches scale: {n} modules, each calling two peers and answering two.\n\
         domain \"{}\"\n\
         supervision {{ start_timeout = 900, heartbeat_period = 1, heartbeat_timeout = 30, stop_grace = 5 }}\n",
        domain.name()
    );
    for i in 1..=n {
        let callees = callees(i, n)
            .iter()
            .map(|c| format!("m{c}"))
            .collect::<Vec<_>>()
            .join(",");
        let mut args = vec!["--callees".to_owned(), callees];
        let extra = match i {
            1 => {
                args.extend([
                    "--measure".to_owned(),
                    "m2".to_owned(),
                    "--go".to_owned(),
                    go.display().to_string(),
                    "--results".to_owned(),
                    results.display().to_string(),
                    "--calls".to_owned(),
                    calls.to_string(),
                    "--cap-ms".to_owned(),
                    cap.as_millis().to_string(),
                ]);
                ", mode = \"busy\", cpus = { 0 }"
            }
            2 => ", mode = \"busy\", cpus = { 1 }",
            _ => "",
        };
        let args: Vec<String> = args.iter().map(|a| format!("{a:?}")).collect();
        s.push_str(&format!(
            "module \"m{i}\" {{ addr = {i}, program = {:?}, args = {{ {} }}{extra} }}\n",
            script.display().to_string(),
            args.join(", ")
        ));
    }
    s
}

/// The modules `i` calls (1-based): the next two, wrapping around, never itself.
fn callees(i: usize, n: usize) -> Vec<usize> {
    let mut out = Vec::new();
    for k in 1..=2 {
        let c = (i - 1 + k) % n + 1;
        if c != i && !out.contains(&c) {
            out.push(c);
        }
    }
    out
}

/// The measurer's results: `value count` per line, or `error: ...`.
fn parse_results(text: &str) -> anyhow::Result<Histogram<u64>> {
    if let Some(e) = text.strip_prefix("error: ") {
        bail!("m1 could not measure: {}", e.trim());
    }
    let mut h = modbot_bench_kit::sample::histogram();
    for line in text.lines() {
        let mut w = line.split_whitespace();
        let (Some(v), Some(c)) = (w.next(), w.next()) else {
            continue;
        };
        h.record_n(v.parse()?, c.parse()?)?;
    }
    if h.is_empty() {
        bail!("m1 wrote no round trips");
    }
    Ok(h)
}

/// The domain's /dev/shm files by kind (the suffix iceoryx2 gives them: `.data`,
/// `.connection`, ...): (kind, files, allocated bytes), largest first.
fn shm_by_kind(domain: &Domain) -> Vec<(String, usize, u64)> {
    use std::os::unix::fs::MetadataExt;
    let mut kinds: std::collections::BTreeMap<String, (usize, u64)> = Default::default();
    for p in domain.files().iter().filter(|p| p.starts_with("/dev/shm")) {
        let Ok(m) = std::fs::symlink_metadata(p) else {
            continue;
        };
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let kind = name.rsplit('.').next().unwrap_or("?").to_owned();
        let e = kinds.entry(kind).or_default();
        e.0 += 1;
        e.1 += m.blocks() * 512;
    }
    let mut out: Vec<(String, usize, u64)> =
        kinds.into_iter().map(|(k, (n, b))| (k, n, b)).collect();
    out.sort_by_key(|k| std::cmp::Reverse(k.2));
    out
}

/// The children of process `pid`.
fn children_of(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return out;
    };
    for t in tasks.flatten() {
        let text = std::fs::read_to_string(t.path().join("children")).unwrap_or_default();
        out.extend(
            text.split_whitespace()
                .filter_map(|p| p.parse::<u32>().ok()),
        );
    }
    out.sort_unstable();
    out.dedup();
    out
}

// ---------------------------------------------------------------------------------------------
// The module program: `child scale-module --domain D --name N --addr A --mode M --callees ...`.
// ---------------------------------------------------------------------------------------------

/// A scale module's options: the supervisor's four, then its own.
#[derive(Debug, Default)]
struct ModuleOpts {
    domain: String,
    name: String,
    addr: u8,
    busy: bool,
    callees: Vec<String>,
    /// The measurer: the module it measures calls to, the file that starts it, where the
    /// results go and how many calls.
    measure: Option<String>,
    go: PathBuf,
    results: PathBuf,
    calls: u64,
    /// The measurement stops after this long with the samples it has.
    cap: Duration,
}

impl ModuleOpts {
    fn parse(args: &[String]) -> anyhow::Result<ModuleOpts> {
        let mut o = ModuleOpts::default();
        let mut it = args.iter();
        while let Some(key) = it.next() {
            let value = it
                .next()
                .with_context(|| format!("scale-module: {key} needs a value"))?;
            match key.as_str() {
                "--domain" => o.domain = value.clone(),
                "--name" => o.name = value.clone(),
                "--addr" => o.addr = value.parse().context("--addr")?,
                "--mode" => o.busy = value == "busy",
                "--callees" => {
                    o.callees = value
                        .split(',')
                        .filter(|s| !s.is_empty())
                        .map(str::to_owned)
                        .collect()
                }
                "--measure" => o.measure = Some(value.clone()),
                "--go" => o.go = value.into(),
                "--results" => o.results = value.into(),
                "--calls" => o.calls = value.parse().context("--calls")?,
                "--cap-ms" => o.cap = Duration::from_millis(value.parse().context("--cap-ms")?),
                other => bail!("scale-module: unknown option {other}"),
            }
        }
        if o.domain.is_empty() || o.name.is_empty() || o.addr == 0 {
            bail!("scale-module needs --domain, --name and --addr (it runs under modbot up)");
        }
        Ok(o)
    }
}

/// A scale module's state.
#[derive(Debug, Default)]
struct Peers {
    callees: Vec<String>,
    /// Whether each callee answered once.
    reached: Vec<bool>,
    /// The call to each callee still waiting for its answer.
    in_flight: Vec<Option<CallHandle>>,
    /// Tasks run.
    ticks: u64,
    /// Spin (busy mode) until then, instead of sleeping between polls.
    spin_until: Option<Instant>,
}

fn echo(_: &mut Peers, _: &mut Ctx, args: &Args<'_>, reply: &mut Reply) -> Result<(), MethodError> {
    for v in args.as_slice() {
        reply.push(*v);
    }
    Ok(())
}

/// `spin(seconds)`: poll without sleeping for that long (0: stop spinning).
fn spin(s: &mut Peers, _: &mut Ctx, args: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    let secs = args.f64(0)?.clamp(0.0, 60.0);
    s.spin_until = (secs > 0.0).then(|| Instant::now() + Duration::from_secs_f64(secs));
    Ok(())
}

/// Every second: a callee that never answered is called again; afterwards one callee every ten
/// seconds.
/// A callee the phone book does not know yet is not called (a call to an unknown name makes the
/// runtime re-read the whole directory); the module's own refresh finds it.
fn talk(s: &mut Peers, ctx: &mut Ctx) {
    s.ticks += 1;
    let n = s.callees.len() as u64;
    for i in 0..s.callees.len() {
        let due =
            !s.reached[i] || (s.ticks.is_multiple_of(10) && (s.ticks / 10) % n.max(1) == i as u64);
        let known = ctx
            .phone_book()
            .lookup(&s.callees[i])
            .is_ok_and(|e| e.alive);
        if due && known && s.in_flight[i].is_none() {
            let opts = CallOptions::timeout(Duration::from_secs(1)).with_retry(RetryPolicy::NONE);
            if let Ok(h) = ctx.call_with(&s.callees[i], "echo", &[], opts) {
                s.in_flight[i] = Some(h);
            }
        }
    }
}

fn on_done(s: &mut Peers, _: &mut Ctx, h: CallHandle, r: Result<&Args<'_>, &CallError>) {
    if let Some(i) = s.in_flight.iter().position(|f| *f == Some(h)) {
        s.in_flight[i] = None;
        if r.is_ok() {
            s.reached[i] = true;
        }
    }
}

fn scale_module(args: &[String]) -> anyhow::Result<()> {
    let o = ModuleOpts::parse(args)?;
    let domain = Domain::new(&o.domain)?;
    let peers = Peers {
        reached: vec![false; o.callees.len()],
        in_flight: vec![None; o.callees.len()],
        callees: o.callees.clone(),
        ..Peers::default()
    };
    let mode = if o.busy {
        ReceiveMode::BusyPoll
    } else {
        ReceiveMode::Blocking
    };
    let mut builder = ModuleBuilder::new(&o.name, o.addr).mode(mode);
    for c in &o.callees {
        builder = builder.peer(c);
    }
    let mut module = builder
        .method("echo", echo)
        .method("spin", spin)
        .on_done(on_done)
        .every(Duration::from_secs(1), talk)
        .open(IpcTransport::new(&domain)?, peers)?;
    if !o.busy {
        module.run()?;
        return Ok(());
    }
    // Busy mode, but spinning only while measured: the other modules start and run meanwhile.
    modbot_core::signals::install_termination_handler()?;
    let mut measured = false;
    while !modbot_core::signals::termination_requested() {
        let mut served = 0;
        while served < 64 && module.poll_once()? {
            served += 1;
        }
        module.housekeeping();
        if let (Some(target), false) = (&o.measure, measured) {
            if o.go.exists() {
                measured = true;
                let outcome = measure_calls(&mut module, target, o.calls, o.cap);
                write_results(&o.results, outcome)?;
            }
        }
        if served == 0 {
            if module
                .state()
                .spin_until
                .is_some_and(|t| Instant::now() < t)
            {
                std::hint::spin_loop();
            } else {
                // Idle between measurements: the spin request arrives within one sleep.
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    }
    Ok(())
}

/// `calls` round trips of `echo()` to `target`, after a tenth as many for warm-up, with the
/// target spinning meanwhile.
fn measure_calls(
    module: &mut Module<Peers>,
    target: &str,
    calls: u64,
    cap: Duration,
) -> anyhow::Result<Histogram<u64>> {
    let opts = CallOptions::timeout(Duration::from_secs(2));
    module
        .call_owned(target, "spin", &[Value::F64(30.0)], opts)
        .map_err(|e| anyhow::anyhow!("{target}.spin: {e}"))?;
    module.state_mut().spin_until = Some(Instant::now() + Duration::from_secs(30));
    let warm = (calls / 10).max(100);
    let mut h = modbot_bench_kit::sample::histogram();
    let quick = CallOptions::timeout(Duration::from_secs(5));
    let started = Instant::now();
    let mut warm_until = warm;
    let outcome = (|| {
        for i in 0..warm + calls {
            // A starved pair takes long per call: at most a tenth of the time cap warms up, and
            // the cap ends the measurement with the samples taken so far.
            if i < warm_until && started.elapsed() > cap / 10 {
                warm_until = i;
            }
            if i > warm_until && started.elapsed() > cap {
                break;
            }
            let t = Instant::now();
            module
                .call_blocking(target, "echo", &[], quick, |r| {
                    r.map(|_| ()).map_err(Clone::clone)
                })
                .map_err(|e| anyhow::anyhow!("{target}.echo: {e}"))?;
            if i >= warm_until {
                h.saturating_record(modbot_bench_kit::sample::since(t).max(1));
            }
        }
        Ok::<(), anyhow::Error>(())
    })();
    module.state_mut().spin_until = None;
    let _ = module.call_owned(target, "spin", &[Value::F64(0.0)], opts);
    outcome.map(|()| h)
}

/// Writes the histogram (or the error) where the benchmark waits for it, atomically.
fn write_results(path: &Path, outcome: anyhow::Result<Histogram<u64>>) -> anyhow::Result<()> {
    let mut text = String::new();
    match outcome {
        Ok(h) => {
            for v in h.iter_recorded() {
                text.push_str(&format!(
                    "{} {}\n",
                    v.value_iterated_to(),
                    v.count_at_value()
                ));
            }
        }
        Err(e) => text = format!("error: {e:#}\n"),
    }
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text)?;
    std::fs::rename(&tmp, path)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_module_calls_two_distinct_peers_and_is_called_by_two() {
        for n in [3usize, 16, 253] {
            let mut called = vec![0; n + 1];
            for i in 1..=n {
                let c = callees(i, n);
                assert_eq!(c.len(), 2, "module {i} of {n}");
                for x in c {
                    called[x] += 1;
                }
            }
            assert!(called[1..].iter().all(|&k| k == 2));
        }
        assert_eq!(callees(1, 2), vec![2]);
        assert_eq!(callees(2, 2), vec![1]);
    }

    #[test]
    fn a_description_of_253_modules_has_every_address_once() {
        let d = Domain::new("bench_test_scale").unwrap();
        let text = description(
            &d,
            MAX_MODULES,
            Path::new("/x/m.sh"),
            Path::new("/x/go"),
            Path::new("/x/r"),
            10,
            Duration::from_secs(1),
        );
        assert_eq!(text.matches("module \"m").count(), MAX_MODULES);
        assert!(text.contains("module \"m253\" { addr = 253,"));
        assert!(text.contains("cpus = { 0 }") && text.contains("cpus = { 1 }"));
    }

    #[test]
    fn results_read_back_and_errors_are_reported() {
        let h = parse_results("1000 3\n2000 1\n").unwrap();
        assert_eq!(h.len(), 4);
        assert!(parse_results("error: it broke\n").is_err());
        assert!(parse_results("").is_err());
    }
}

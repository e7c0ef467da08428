//! Benchmark 8, soak: MOSER and the arm run together, in one domain under one supervisor,
//! while a fault is injected every second into a module picked at random; `--minutes N` (10 by
//! default, 1 with `--quick`), `--seed S` to repeat a run's picks. Not part of `all`.
//!
//! - **The system** ([`system`]): `examples/moser.lua` (patrolling without end) and
//!   `examples/arm.lua` (six drives behind the bus bridge, holding), and the journal module.
//! - **Faults** ([`inject`]): once a second, SIGKILL; SIGSTOP for 2 s, then SIGCONT; a flood of
//!   garbage frames into the inbox; or a consumer that stops reading (SIGSTOP for 0.5 s while
//!   this process sends it REPORTs as fast as they go) — into any module but the supervisor
//!   (the coordinator takes floods only).
//! - **Exactly once** ([`driver`], [`journal`]): a tool endpoint of this process calls
//!   `journal.record(seq)` every 5 ms with its own sequence number, waiting for the module
//!   across its restarts and retransmitting; the module appends each number it executes to a
//!   file. At the end: calls acknowledged, lost (acknowledged, not in the journal) and
//!   duplicated (in the journal twice).
//! - **Memory** ([`samples`]): every second the Rss of every process of the system and the
//!   domain's /dev/shm files; growth over the last half; files left after the stop.
//! - **The arm** ([`arm`]): every second the bus ledger; the safe stops it went into.
//! - **The note** ([`notes`]): every count behind the rows, the restarts by cause as the
//!   supervisor printed them ([`ends`]), the memory windows, the arm's safe stops.
//!
//! Rows (`soak.*`, counts and bytes; each compared with the row it is a share of): faults by
//! kind, calls issued / acknowledged / executed / lost / duplicated, restarts, Rss and /dev/shm
//! at the middle and the end, files left, samples of the arm in a safe stop. `soak_faults.tsv`
//! (every fault), `soak_memory.tsv` (every sample), `soak_processes.tsv` (every process of
//! every sample), `soak_bus.tsv` (the bus ledger's first line every second) and
//! `soak_supervisor.log` (the supervisor's own lines) go next to the report.

mod arm;
mod driver;
mod ends;
mod inject;
mod journal;
mod notes;
mod samples;
mod system;
mod targets;

use std::fmt::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context;
use modbot_runtime::supervisor::status;

use crate::opts::Opts;
use crate::procs::{self, Scratch};
use crate::report::{Report, Row};
use crate::supervised::Supervised;

pub use targets::targets;

/// The soak's own options.
#[derive(Debug, Clone, Copy, Default)]
pub struct Plan {
    /// How long faults are injected [default: 10, 1 with --quick].
    pub minutes: Option<f64>,
    /// The seed of the picks [default: from the clock].
    pub seed: Option<u64>,
}

/// One fault and one sample this often.
const EVERY: Duration = Duration::from_secs(1);

/// Runs the soak.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    let minutes = opts
        .soak
        .minutes
        .unwrap_or(if opts.quick { 1.0 } else { 10.0 });
    if !(minutes > 0.0 && minutes <= 24.0 * 60.0) {
        anyhow::bail!("--minutes {minutes}: give more than 0 and at most a day");
    }
    let seed = opts.soak.seed.unwrap_or_else(crate::sample::clock_seed);
    eprintln!("soak: {minutes} minute(s), seed {seed} (the same picks again: --seed {seed})");
    let mut scratch = Scratch::new("soak", None)?;
    let file = scratch.path("soak.lua");
    let journal_file = scratch.path("journal");
    let examples = system::Examples::read()?;
    std::fs::write(&file, system::compose(&examples, &journal_file))
        .with_context(|| format!("cannot write {}", file.display()))?;
    let args: Vec<String> = [
        "--var".to_owned(),
        format!("domain={}", scratch.domain.name()),
        "--var".to_owned(),
        "endless=1".to_owned(),
    ]
    .into();
    let mut sys = Supervised::start(opts, &scratch.domain, &file, &args, Duration::from_secs(30))?;
    sys.wait_up(Duration::from_secs(120))?;
    let up_line = sys
        .lines_with("module(s) up in")
        .first()
        .map(|l| l.split(" | ").last().unwrap_or(l).trim().to_owned())
        .unwrap_or_default();
    crate::faults::wait_drives_enabled(&mut sys, Duration::from_secs(60))?;
    let first = sys.status()?;
    let targets = inject::targets(first.iter().map(|r| r.name.as_str()));
    let run = soak(
        &mut sys,
        Duration::from_secs_f64(minutes * 60.0),
        seed,
        targets,
    )?;
    let ledger = sys
        .call_text("host_bus", "bus")
        .unwrap_or_else(|e| format!("({e:#})"));
    let ends = ends::Ends::from_lines(&sys.lines_with(" ended ("), &sys.lines_with(" FAILED: "));
    let (up_status, left) = sys.stop_with_status()?;
    let supervisor_lines: Vec<String> = sys
        .lines_with("modbot | ")
        .into_iter()
        .filter(|l| crate::faults::is_supervisor_line(l))
        .collect();
    drop(sys);
    let text = std::fs::read_to_string(&journal_file)
        .with_context(|| format!("cannot read the journal {}", journal_file.display()))?;
    let (executed, unreadable) = journal::parse(&text);
    let tally = journal::tally(run.calls.issued, &run.calls.acknowledged, &executed);
    std::fs::create_dir_all(&opts.out)?;
    write_logs(&opts.out, &run)?;
    std::fs::write(
        opts.out.join("soak_supervisor.log"),
        supervisor_lines.join("\n") + "\n",
    )?;
    if !tally.lost.is_empty() || !tally.duplicated.is_empty() || !run.calls.misanswered.is_empty() {
        std::fs::write(opts.out.join("soak_journal.txt"), &text)?;
    }
    let params = [
        ("minutes", serde_json::Value::from(minutes)),
        ("seed", serde_json::Value::from(seed)),
    ];
    push_rows(report, &params, &run, &tally, &ends, left.len());
    report.note(notes::note(&notes::Facts {
        run: &run,
        tally: &tally,
        ends: &ends,
        unreadable,
        minutes,
        seed,
        up_line: &up_line,
        ledger: &ledger,
        up_status,
        left: &left,
    }));
    Ok(())
}

/// What one soak saw while it ran.
pub(crate) struct Run {
    targets: Vec<String>,
    injected: inject::Injected,
    calls: driver::Outcome,
    samples: Vec<samples::Sample>,
    /// The bus ledger, as sampled.
    bus: Vec<arm::Seen>,
    /// `supervisor.status` calls that failed (the table of the second before is used then).
    status_errors: Vec<String>,
}

/// Injects a fault and takes a sample every second for `span`, while the driver calls the
/// journal; then resumes what it stopped and collects the driver's calls.
fn soak(
    sys: &mut Supervised,
    span: Duration,
    seed: u64,
    targets: Vec<inject::Target>,
) -> anyhow::Result<Run> {
    let names = targets.iter().map(|t| t.name.clone()).collect();
    let mut injector = inject::Injector::new(seed, targets);
    let domain = sys.domain.clone();
    let driver = driver::Driver::start(&domain)?;
    let started = Instant::now();
    let mut next = started;
    let mut rows: Vec<status::Row> = Vec::new();
    let (mut samples, mut bus, mut status_errors) = (Vec::new(), Vec::new(), Vec::new());
    while started.elapsed() < span {
        injector.resume(false);
        if Instant::now() >= next {
            next += EVERY;
            match sys.status() {
                Ok(r) => rows = r,
                Err(e) => status_errors.push(format!("{e:#}")),
            }
            let at = started.elapsed();
            samples.push(samples::Sample::take(at, sys.up_pid(), &rows, &domain));
            bus.extend(arm::read(at, sys, &rows, |pid| injector.is_stopped(pid)));
            if at >= EVERY {
                injector.inject(sys, &rows)?;
            }
        }
        if driver.has_ended() {
            break;
        }
        sys.sleep(Duration::from_millis(10))?;
    }
    injector.resume(true);
    let calls = driver.finish().context("the soak's calls")?;
    Ok(Run {
        targets: names,
        injected: std::mem::take(&mut injector.injected),
        calls,
        samples,
        bus,
        status_errors,
    })
}

fn push_rows(
    report: &mut Report,
    params: &[(&str, serde_json::Value)],
    run: &Run,
    tally: &journal::Tally,
    ends: &ends::Ends,
    left: usize,
) {
    let row = |name: &str, value: u64, unit: &'static str| {
        let mut r = Row::single(name, value).unit(unit);
        for (k, v) in params {
            r = r.param(k, v.clone());
        }
        r
    };
    let count = |name: &str, value: u64| row(name, value, "count");
    let i = &run.injected;
    let faults: u64 = i.by_kind.values().sum();
    report.push(count("soak.picks", faults + i.skipped).is_baseline());
    report.push(count("soak.faults", faults).against("soak.picks", &[]));
    for kind in inject::Kind::ALL {
        let n = i.by_kind.get(&kind).copied().unwrap_or(0);
        let name = format!("soak.faults_{}", kind.name());
        report.push(count(&name, n).against("soak.faults", &[]));
    }
    report.push(count("soak.restarts", ends.total()).against("soak.faults", &[]));
    report.push(count("soak.calls_issued", tally.issued).is_baseline());
    for (name, n) in [
        ("soak.calls_acknowledged", tally.acknowledged),
        ("soak.calls_executed", tally.executed),
    ] {
        report.push(count(name, n).against("soak.calls_issued", &[]));
    }
    report.push(
        count("soak.calls_lost", tally.lost.len() as u64).against("soak.calls_acknowledged", &[]),
    );
    report.push(
        count("soak.calls_duplicated", tally.duplicated.len() as u64)
            .against("soak.calls_executed", &[]),
    );
    report.push(
        count("soak.calls_misanswered", run.calls.misanswered.len() as u64)
            .against("soak.calls_acknowledged", &[]),
    );
    let (Some(w), Some(end)) = (samples::windows(&run.samples), run.samples.last()) else {
        report.note("soak: too few samples for the memory rows");
        return;
    };
    for (what, g) in [
        ("rss", w.survivors()),
        ("rss_all", w.everyone()),
        ("shm", w.shm()),
    ] {
        let (mid_name, end_name) = (format!("soak.{what}_mid"), format!("soak.{what}_end"));
        report.push(row(&mid_name, g.mid, "bytes").is_baseline());
        report.push(row(&end_name, g.end, "bytes").against(&mid_name, &[]));
    }
    report.push(count("soak.files_end", end.shm_files as u64).is_baseline());
    report.push(count("soak.files_left", left as u64).against("soak.files_end", &[]));
    let arm = arm::summarize(&run.bus);
    report.push(count("soak.arm_samples", arm.answered as u64).is_baseline());
    report
        .push(count("soak.arm_in_safe_stop", arm.stopped as u64).against("soak.arm_samples", &[]));
}

/// `soak_faults.tsv`, `soak_memory.tsv`, `soak_processes.tsv` and `soak_bus.tsv` into `dir`.
fn write_logs(dir: &Path, run: &Run) -> anyhow::Result<()> {
    let mut faults = String::from("seconds\tkind\tmodule\tpid\n");
    for (at, kind, module, pid) in &run.injected.log {
        let _ = writeln!(
            faults,
            "{:.3}\t{}\t{module}\t{pid}",
            at.as_secs_f64(),
            kind.name()
        );
    }
    std::fs::write(dir.join("soak_faults.tsv"), faults)?;
    let mut memory = String::from("seconds\tprocesses\trss_bytes\tshm_files\tshm_bytes\n");
    for s in &run.samples {
        let _ = writeln!(
            memory,
            "{:.3}\t{}\t{}\t{}\t{}",
            s.at.as_secs_f64(),
            s.processes.len(),
            s.rss(),
            s.shm_files,
            s.shm_bytes
        );
    }
    std::fs::write(dir.join("soak_memory.tsv"), memory)?;
    let mut processes = String::from("seconds\tmodule\tpid\trss_bytes\n");
    for s in &run.samples {
        for p in &s.processes {
            let at = s.at.as_secs_f64();
            let _ = writeln!(processes, "{at:.3}\t{}\t{}\t{}", p.name, p.pid, p.rss);
        }
    }
    std::fs::write(dir.join("soak_processes.tsv"), processes)?;
    let mut bus = String::from("seconds\tpid\tledger\n");
    for s in &run.bus {
        let _ = writeln!(bus, "{:.3}\t{}\t{}", s.at.as_secs_f64(), s.pid, s.line);
    }
    std::fs::write(dir.join("soak_bus.tsv"), bus)?;
    Ok(())
}

/// No child roles: the system is the examples' programs and `modbot-faulty`.
pub fn child(_role: &str, _args: &[String]) -> Option<anyhow::Result<()>> {
    None
}

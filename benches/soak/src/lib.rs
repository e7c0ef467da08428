//! Benchmark 8, soak: MOSER and the arm run together, in one domain under one supervisor,
//! while a fault is injected every second into a module picked at random; `--minutes N` (10 by
//! default, 1 with `--quick`), `--seed S` to repeat a run's picks. Not part of `all`. The
//! `modbot-benches` binary runs it (`modbot-benches soak`) with its options in
//! [`modbot_bench_kit::opts::SoakPlan`]; the systems, the report and the samples are
//! `modbot-bench-kit`'s.
//!
//! # Layout
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
//! - **The robot** ([`robot`]): every second its state; after a safe stop or a fault the soak
//!   resets it, as an operator would, and keeps when each stop began and when the robot was
//!   operational again.
//! - **Motions** ([`motions`]): a robot program moves the arm back and forth without end,
//!   started again whenever a refused or failed motion ends it; at the end its runs in
//!   assembly data are judged, and an ok motion across a stop is a false ok.
//! - **The note** ([`notes`]): every count behind the rows, the restarts by cause as the
//!   supervisor printed them ([`ends`]), the memory windows, the arm's safe stops, the resets
//!   and the motions.
//!
//! Rows ([`rows`]: `soak.*`, counts and bytes, each compared with the row it is a share of):
//! faults by kind, calls issued / acknowledged / executed / lost / duplicated, restarts, Rss
//! and /dev/shm at the middle and the end, files left, samples of the arm in a safe stop, the
//! robot's stops / recoveries / resets refused, the grid time from a stop to operational again,
//! the motions by outcome. `soak_faults.tsv` (every fault), `soak_memory.tsv` (every sample),
//! `soak_processes.tsv` (every process of every sample), `soak_bus.tsv` (the bus ledger's first
//! line every second), `soak_stops.tsv` (every stop and how it ended), `soak_runs.tsv` (every
//! command run of the program), `soak_program.log` (its output) and `soak_supervisor.log` (the
//! supervisor's own lines) go next to the report.

mod arm;
mod driver;
mod ends;
mod inject;
mod journal;
mod motions;
mod notes;
mod robot;
mod rows;
mod samples;
mod system;
mod targets;

use std::fmt::Write as _;
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::Report;
use modbot_bench_kit::supervised::Supervised;
use modbot_supervisor::status;

pub use targets::targets;

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
    let seed = opts
        .soak
        .seed
        .unwrap_or_else(modbot_bench_kit::sample::clock_seed);
    eprintln!("soak: {minutes} minute(s), seed {seed} (the same picks again: --seed {seed})");
    let mut scratch = Scratch::new("soak", None)?;
    let file = scratch.path("soak.lua");
    let journal_file = scratch.path("journal");
    let examples = system::Examples::read()?;
    std::fs::write(&file, system::compose(&examples, &journal_file))
        .with_context(|| format!("cannot write {}", file.display()))?;
    let data_dir = scratch.path("data");
    std::fs::create_dir_all(&data_dir)
        .with_context(|| format!("cannot make {}", data_dir.display()))?;
    std::fs::create_dir_all(&opts.out)?;
    let mut program = motions::Program::new(
        opts,
        &scratch.path("program.lua"),
        scratch.domain.name(),
        &data_dir,
        &opts.out.join("soak_program.log"),
    )?;
    let args: Vec<String> = [
        "--var".to_owned(),
        format!("domain={}", scratch.domain.name()),
        "--var".to_owned(),
        "endless=1".to_owned(),
    ]
    .into();
    let env = [(modbot_data::DATA_DIR_ENV, data_dir.as_path())];
    let mut sys = Supervised::start_with_env(
        opts,
        &scratch.domain,
        &file,
        &args,
        Duration::from_secs(30),
        &env,
    )?;
    sys.wait_up(Duration::from_secs(120))?;
    let up_line = sys
        .lines_with("module(s) up in")
        .first()
        .map(|l| l.split(" | ").last().unwrap_or(l).trim().to_owned())
        .unwrap_or_default();
    modbot_bench_kit::arm_system::wait_drives_enabled(&mut sys, Duration::from_secs(60))?;
    let first = sys.status()?;
    let targets = inject::targets(first.iter().map(|r| r.name.as_str()));
    let run = soak(
        &mut sys,
        &mut program,
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
        .filter(|l| modbot_bench_kit::supervised::is_supervisor_line(l))
        .collect();
    drop(sys);
    let text = std::fs::read_to_string(&journal_file)
        .with_context(|| format!("cannot read the journal {}", journal_file.display()))?;
    let (executed, unreadable) = journal::parse(&text);
    let tally = journal::tally(run.calls.issued, &run.calls.acknowledged, &executed);
    let runs = program.runs().unwrap_or_else(|e| {
        report.note(format!("soak: the program's runs could not be read: {e:#}"));
        Vec::new()
    });
    let moves = motions::tally(&runs, &run.robot.spans());
    write_logs(&opts.out, &run)?;
    write_robot_logs(&opts.out, &run.robot, &runs)?;
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
    rows::push_rows(report, &params, &run, &tally, &ends, left.len(), &moves);
    report.note(notes::note(&notes::Facts {
        run: &run,
        tally: &tally,
        moves: &moves,
        program: &program,
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
    /// The robot's states, stops and resets.
    robot: robot::Watch,
}

/// Injects a fault and takes a sample every second for `span`, resets the robot after a stop
/// and keeps the program moving it, while the driver calls the journal; then stops the
/// program, resumes what it stopped and collects the driver's calls.
fn soak(
    sys: &mut Supervised,
    program: &mut motions::Program,
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
    let mut watch = robot::Watch::default();
    while started.elapsed() < span {
        injector.resume(false);
        let now = Instant::now();
        if now >= next {
            // A second that took longer (a reset waiting for the grid) is not made up for
            // with a burst of faults.
            next = (next + EVERY).max(now + EVERY / 2);
            match sys.status() {
                Ok(r) => rows = r,
                Err(e) => status_errors.push(format!("{e:#}")),
            }
            let at = started.elapsed();
            samples.push(samples::Sample::take(at, sys.up_pid(), &rows, &domain));
            bus.extend(arm::read(at, sys, &rows, |pid| injector.is_stopped(pid)));
            watch.second(sys, &rows, |pid| injector.is_stopped(pid))?;
            program.keep_running(at)?;
            if at >= EVERY {
                injector.inject(sys, &rows)?;
            }
        }
        if driver.has_ended() {
            break;
        }
        sys.sleep(Duration::from_millis(10))?;
    }
    program.stop()?;
    injector.resume(true);
    let calls = driver.finish().context("the soak's calls")?;
    Ok(Run {
        targets: names,
        injected: std::mem::take(&mut injector.injected),
        calls,
        samples,
        bus,
        status_errors,
        robot: watch,
    })
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

/// `soak_stops.tsv` (every stop the robot state showed, and how it ended) and `soak_runs.tsv`
/// (every command run of the program) into `dir`.
fn write_robot_logs(dir: &Path, w: &robot::Watch, runs: &[modbot_data::Run]) -> anyhow::Result<()> {
    let mut stops = String::from(
        "bridge_pid\tkind\tsince_tick\toperational_tick\tended_by\treset_ticks\tcause\n",
    );
    for s in &w.stops {
        let (tick, how) = match s.end {
            Some((t, robot::Ended::Reset)) => (t.to_string(), "reset"),
            Some((t, robot::Ended::Restart)) => (t.to_string(), "restart"),
            None => (String::new(), "still held"),
        };
        let _ = writeln!(
            stops,
            "{}\t{}\t{}\t{tick}\t{how}\t{}\t{}",
            s.pid,
            if s.fault { "fault" } else { "safe_stop" },
            s.since_tick,
            s.reset_ticks.map(|t| t.to_string()).unwrap_or_default(),
            s.cause
        );
    }
    std::fs::write(dir.join("soak_stops.tsv"), stops)?;
    let mut table = String::from("command\tassembly\tstart_tick\tend_tick\toutcome\n");
    for r in runs {
        let _ = writeln!(
            table,
            "{}\t{}\t{}\t{}\t{}",
            r.command,
            r.assembly,
            r.start_tick,
            r.end_tick,
            r.outcome.replace(['\t', '\n'], " ")
        );
    }
    std::fs::write(dir.join("soak_runs.tsv"), table)?;
    Ok(())
}

/// No child roles: the system is the examples' programs and `modbot-faulty`.
pub fn child(_role: &str, _args: &[String]) -> Option<anyhow::Result<()>> {
    None
}

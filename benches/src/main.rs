//! modbot's benchmarks: latency, zero copy, grid jitter, scale, faults, swaps and the arm, each measured
//! between separate processes and compared with a baseline measured in the same run.
//!
//! # Commands
//! - `modbot-benches all [--quick] [--pin] [--fifo] [--out DIR]`: every benchmark in order
//!   (calls, snapshots, grid, scale, faults, swaps, arm, fmu, ethercat, station; ethercat only as
//!   root, station only with chromium, else a note says it was skipped). A benchmark that fails leaves a note in
//!   the report and the run goes on. Writes `report.md`, `report.json` and the SVG plots into
//!   `target/bench-report/` (next to the `release` directory this executable is in) or `DIR`,
//!   and prints `report.md`. `--quick` finishes in under 3 minutes.
//!   From a checkout: `cargo run --release -p modbot-benches -- all --quick`.
//! - `modbot-benches calls|snapshots|grid|scale|faults|swaps|arm|fmu|ethercat|station [options]`: one
//!   benchmark, with the same report. `ethercat` needs root (a network namespace, raw sockets)
//!   and `modbot-ecat-sim` built next to this executable; without root it exits with one line.
//! - `modbot-benches soak [--minutes N] [--seed S] [options]`: MOSER and the arm under a fault a
//!   second for N minutes (10; 1 with `--quick`). Not part of `all`, which it would outlast.
//! - `modbot-benches child ROLE ARGS...` (hidden): one side of a benchmark, started by the
//!   benchmark itself.
//!
//! Options: `--pin` puts the two sides of a two-process benchmark on cores 0 and 1; `--fifo`
//! runs the blocking paths (and the grid) under SCHED_FIFO, which needs root or CAP_SYS_NICE.
//!
//! # Layout
//! - [`opts`]: the options of a run.
//! - [`report`]: rows, baselines and ratios, `report.json` and `report.md`.
//! - [`targets`]: the targets, checked against the rows (met, missed by how much, or
//!   not measured and why).
//! - [`plots`]: the SVG plots.
//! - [`machine`]: the date and the machine the run was made on.
//! - [`procs`]: child processes (stopped on drop, dying with their parent), pinning,
//!   SCHED_FIFO, isolated domains cleaned on drop, the modbot binaries the system benchmarks
//!   start.
//! - [`sample`]: warm-up, sample counts, histograms, the cross-process clock.
//! - [`raw`], [`uds`]: the baselines, raw iceoryx2 and Unix-domain sockets.
//! - [`work`]: part of benchmark 1, the CPU work of one call (both sides in one thread).
//! - [`hogs`]: CPU hogs of normal priority, for measurements on a busy machine.
//! - Benchmarks, one file each, each with `run` and its child roles in `child`: [`calls`] (1,
//!   method-call round trip), [`snapshots`] (2, blackboard snapshots), [`grid`] (3, tick error
//!   and coordinator CPU), [`scale`] (4, up to 254 modules), [`faults`] (5, detection and
//!   restart), [`swaps`] (6, assembly swaps), [`arm`] (7, the arm holding; the grid's
//!   [`lockstep`] runs belong to 3), [`soak`] (8, a fault a second for minutes: calls exactly
//!   once, memory, files, the robot reset after each stop, no motion ok across one), [`fmu`] (9, an FMU component against a built-in doing the same),
//!   [`ethercat`] (10, the EtherCAT bus cycle against a raw AF_PACKET ping-pong, and its jitter
//!   against a bare timerfd loop, on a veth pair against the slave emulator), [`station`] (11, the
//!   grid and a busy call with the control station and two browsers attached against none, and
//!   the station's looks at 253 modules).

mod arm;
mod calls;
mod ethercat;
mod faults;
mod fmu;
mod grid;
mod hogs;
mod interleave;
mod lockstep;
mod machine;
mod opts;
mod plots;
mod procs;
mod raw;
mod report;
mod sample;
mod scale;
mod snapshots;
mod soak;
mod station;
mod supervised;
mod swaps;
mod targets;
mod uds;
mod work;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::{Args, Parser, Subcommand};

use opts::Opts;
use report::Report;

#[derive(Debug, Parser)]
#[command(
    name = "modbot-benches",
    about = "modbot's benchmarks, each against a baseline of the same run"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

/// The options every benchmark command takes.
#[derive(Debug, Clone, Args)]
struct RunArgs {
    /// Fewer samples: `all --quick` finishes in under 3 minutes.
    #[arg(long)]
    quick: bool,
    /// Pin the two sides of a benchmark to cores 0 and 1.
    #[arg(long)]
    pin: bool,
    /// Run blocking paths and the grid under SCHED_FIFO (root or CAP_SYS_NICE).
    #[arg(long)]
    fifo: bool,
    /// Where report.md, report.json and the plots go [default: target/bench-report].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// The soak's options.
#[derive(Debug, Clone, Args)]
struct SoakArgs {
    #[command(flatten)]
    run: RunArgs,
    /// Minutes of faults [default: 10; 1 with --quick].
    #[arg(long, value_name = "N")]
    minutes: Option<f64>,
    /// Seed of the random picks of module and fault [default: from the clock; printed].
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
}

#[derive(Debug, Subcommand)]
enum Cmd {
    /// Every benchmark, in order, into one report.
    All(RunArgs),
    /// 1: method-call round trip against raw iceoryx2 and Unix sockets, 8 B to 1 MiB.
    Calls(RunArgs),
    /// 2: blackboard snapshot delivery, 8 B to 1 MiB, against Unix sockets.
    Snapshots(RunArgs),
    /// 3: grid tick error, release-to-done latency and coordinator CPU at 1 kHz.
    Grid(RunArgs),
    /// 4: start-up, /dev/shm, RSS and call round trip from 2 to 254 modules.
    Scale(RunArgs),
    /// 5: fault detection, restart and quick stop.
    Faults(RunArgs),
    /// 6: assembly swaps: preparation, switch tick error, missed bus cycles, command steps.
    Swaps(RunArgs),
    /// 7: the arm holding: bus cycles missed against a bare real-time loop.
    Arm(RunArgs),
    /// 8: MOSER and the arm under a fault a second: calls lost or doubled, restarts, memory,
    /// the robot's resets and the motions of a program.
    Soak(SoakArgs),
    /// 9: an FMU component's step and release to done against a built-in doing the same.
    Fmu(RunArgs),
    /// 10: EtherCAT bus cycle vs raw AF_PACKET ping-pong, and its jitter at 1 and 4 kHz (root).
    Ethercat(RunArgs),
    /// 11: the grid and a busy call with the control station and two browsers attached against
    /// none, and the station's looks at 253 modules (needs chromium).
    Station(RunArgs),
    /// One side of a benchmark (started by the benchmarks themselves).
    #[command(hide = true)]
    Child {
        role: String,
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

type RunFn = fn(&Opts, &mut Report) -> anyhow::Result<()>;

/// A benchmark: its name, its entry point, and whether it starts the modbot binaries.
struct Bench {
    name: &'static str,
    run: RunFn,
    needs_binaries: bool,
}

/// Every benchmark, in the order `all` runs them.
const BENCHES: [Bench; 10] = [
    Bench {
        name: "calls",
        run: calls::run,
        needs_binaries: false,
    },
    Bench {
        name: "snapshots",
        run: snapshots::run,
        needs_binaries: false,
    },
    Bench {
        name: "grid",
        run: grid::run,
        needs_binaries: true,
    },
    Bench {
        name: "scale",
        run: scale::run,
        needs_binaries: true,
    },
    Bench {
        name: "faults",
        run: faults::run,
        needs_binaries: true,
    },
    Bench {
        name: "swaps",
        run: swaps::run,
        needs_binaries: true,
    },
    Bench {
        name: "arm",
        run: arm::run,
        needs_binaries: true,
    },
    Bench {
        name: "fmu",
        run: fmu::run,
        needs_binaries: true,
    },
    // Needs only modbot-ecat-sim (and root: without it, a note in `all`).
    Bench {
        name: "ethercat",
        run: ethercat::run,
        needs_binaries: false,
    },
    Bench {
        name: "station",
        run: station::run,
        needs_binaries: true,
    },
];

/// The soak: not in `all` (it runs for minutes).
const SOAK: Bench = Bench {
    name: "soak",
    run: soak::run,
    needs_binaries: true,
};

/// Runs `role` with `args` if it is one of a benchmark's child roles.
type ChildFn = fn(&str, &[String]) -> Option<anyhow::Result<()>>;

/// The child roles of every benchmark; `None` from one means "not mine".
const CHILDREN: [ChildFn; 12] = [
    arm::child,
    hogs::child,
    calls::child,
    snapshots::child,
    raw::child,
    uds::child,
    grid::child,
    scale::child,
    faults::child,
    swaps::child,
    soak::child,
    ethercat::child,
];

fn opts_from(args: &RunArgs, soak: soak::Plan) -> anyhow::Result<Opts> {
    let exe = std::env::current_exe().context("cannot find this executable")?;
    let out = match &args.out {
        Some(dir) => dir.clone(),
        // <target>/release/modbot-benches → <target>/bench-report
        None => exe
            .parent()
            .and_then(|d| d.parent())
            .map(|t| t.join("bench-report"))
            .context("cannot place the report next to this executable: give --out DIR")?,
    };
    Ok(Opts {
        quick: args.quick,
        pin: args.pin,
        fifo: args.fifo,
        out,
        exe,
        soak,
    })
}

/// Runs `benches` into one report, writes it with its plots, and prints report.md.
fn run_benches(args: &RunArgs, benches: &[&Bench]) -> anyhow::Result<()> {
    run_with(opts_from(args, soak::Plan::default())?, benches)
}

/// [`run_benches`] with the options made already (the soak's carry its plan).
fn run_with(opts: Opts, benches: &[&Bench]) -> anyhow::Result<()> {
    if let Err(e) = modbot_core::signals::install_termination_handler() {
        eprintln!("warning: Ctrl-C will not stop the run cleanly: {e}");
    }
    let mut report = Report {
        date: machine::today_utc(),
        machine: machine::describe(),
        ..Report::default()
    };
    for (k, v) in [
        ("quick", opts.quick),
        ("pin", opts.pin),
        ("fifo", opts.fifo),
    ] {
        report.options.insert(k.to_owned(), v.into());
    }
    let binaries = if benches.iter().any(|b| b.needs_binaries) {
        procs::ensure_binaries(&opts).map_err(|e| format!("{e:#}"))
    } else {
        Ok(())
    };
    let mut timings = Vec::new();
    let started = Instant::now();
    for bench in benches {
        if procs::interrupted() {
            report.note(format!("{}: not run, the run was interrupted", bench.name));
            continue;
        }
        if let (true, Err(e)) = (bench.needs_binaries, &binaries) {
            report.note(format!("{}: not run: {e}", bench.name));
            continue;
        }
        eprintln!("running {} ...", bench.name);
        let t = Instant::now();
        if let Err(e) = (bench.run)(&opts, &mut report) {
            report.note(format!("{}: failed: {e:#}", bench.name));
        }
        timings.push(format!("{} {:.1} s", bench.name, t.elapsed().as_secs_f64()));
    }
    timings.push(format!("total {:.1} s", started.elapsed().as_secs_f64()));
    report.note(format!("run time: {}", timings.join(", ")));
    let left = leftovers();
    if !left.is_empty() {
        report.note(format!(
            "files of this run were left in /dev/shm or /tmp/iceoryx2 and are removed now: {}",
            left.iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ));
        remove(&left);
    }
    report.drop_rows_without_baseline();
    report.resolve()?;
    targets::evaluate(&mut report);
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("cannot create {}", opts.out.display()))?;
    let plots = plots::write_all(&mut report, &opts.out);
    report
        .write(&opts.out)
        .with_context(|| format!("cannot write the report into {}", opts.out.display()))?;
    println!("{}", report.markdown());
    eprintln!(
        "report: {} ({} plots)",
        opts.out.join("report.md").display(),
        plots.len()
    );
    if procs::interrupted() {
        bail!("interrupted: the report holds what was measured before");
    }
    Ok(())
}

/// Files of any domain of this run (`modbot_bench_{pid}_…`) still in /dev/shm or
/// /tmp/iceoryx2.
fn leftovers() -> Vec<PathBuf> {
    let prefix = format!("modbot_{}", procs::domain_name(""));
    let mut found = Vec::new();
    for dir in ["/dev/shm", "/tmp/iceoryx2"] {
        collect(std::path::Path::new(dir), &prefix, &mut found);
    }
    found
}

fn collect(dir: &std::path::Path, prefix: &str, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        if e.file_name().to_string_lossy().starts_with(prefix) {
            out.push(e.path());
        } else if e.file_type().is_ok_and(|t| t.is_dir()) {
            collect(&e.path(), prefix, out);
        }
    }
}

fn remove(paths: &[PathBuf]) {
    for p in paths {
        let _ = if p.is_dir() {
            std::fs::remove_dir_all(p)
        } else {
            std::fs::remove_file(p)
        };
    }
}

fn bench(name: &str) -> &'static Bench {
    BENCHES
        .iter()
        .find(|b| b.name == name)
        .expect("every subcommand names a benchmark")
}

/// An error is one line on stderr with its causes and exit status 1, never a backtrace,
/// whatever RUST_BACKTRACE says (a panic keeps its backtrace: that is a bug).
fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("modbot-benches: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}

fn run() -> anyhow::Result<()> {
    match Cli::parse().command {
        Cmd::All(args) => run_benches(&args, &BENCHES.iter().collect::<Vec<_>>()),
        Cmd::Calls(args) => run_benches(&args, &[bench("calls")]),
        Cmd::Snapshots(args) => run_benches(&args, &[bench("snapshots")]),
        Cmd::Grid(args) => run_benches(&args, &[bench("grid")]),
        Cmd::Scale(args) => run_benches(&args, &[bench("scale")]),
        Cmd::Faults(args) => run_benches(&args, &[bench("faults")]),
        Cmd::Swaps(args) => run_benches(&args, &[bench("swaps")]),
        Cmd::Arm(args) => run_benches(&args, &[bench("arm")]),
        Cmd::Fmu(args) => run_benches(&args, &[bench("fmu")]),
        Cmd::Station(args) => run_benches(&args, &[bench("station")]),
        Cmd::Ethercat(args) => {
            ethercat::require_root()?;
            run_benches(&args, &[bench("ethercat")])
        }
        Cmd::Soak(args) => {
            let plan = soak::Plan {
                minutes: args.minutes,
                seed: args.seed,
            };
            run_with(opts_from(&args.run, plan)?, &[&SOAK])
        }
        Cmd::Child { role, args } => {
            procs::child_setup();
            for child in CHILDREN {
                if let Some(result) = child(&role, &args) {
                    return result.with_context(|| format!("child {role}"));
                }
            }
            bail!("unknown child role '{role}'")
        }
    }
}

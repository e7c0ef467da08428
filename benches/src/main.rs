//! modbot's benchmarks: latency, zero copy, grid jitter, scale, faults, swaps and the arm, each measured
//! between separate processes and compared with a baseline measured in the same run.
//!
//! # Commands
//! - `modbot-benches all [--quick] [--pin] [--fifo] [--out DIR]`: every benchmark in order
//!   (calls, snapshots, grid, scale, faults, swaps, arm, fmu, ethercat, station, replay, remote; ethercat only as
//!   root, station only with chromium, else a note says it was skipped). A benchmark that fails leaves a note in
//!   the report and the run goes on. Writes `report.md`, `report.json` and the SVG plots into
//!   `target/bench-report/` (next to the `release` directory this executable is in) or `DIR`,
//!   and prints `report.md`. `--quick` finishes in under 3 minutes.
//!   From a checkout: `cargo run --release -p modbot-benches -- all --quick`.
//! - `modbot-benches calls|snapshots|grid|scale|faults|swaps|arm|fmu|ethercat|station|replay|remote [options]`: one
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
//! The benchmarks are library crates under `benches/`; this binary is their command line.
//! - `modbot-bench-kit` (`benches/kit/`): what every benchmark uses — the options of a run,
//!   rows and baselines, `report.md`/`report.json`, the plots, the targets, child
//!   processes, samples and histograms, CPU hogs, systems under `modbot up`, the arm system.
//! - `modbot-bench-ipc` (`benches/ipc/`): 1, calls (with the CPU work of a call), and 2,
//!   snapshots; their paths, the echo module and the baselines, raw iceoryx2 and Unix sockets.
//! - `modbot-bench-system` (`benches/system/`): 3, grid (with its lockstep runs), 4, scale, 5,
//!   faults, 6, swaps, 7, arm, 9, fmu, 10, ethercat, 11, station, 12, replay, 13, remote.
//! - `modbot-bench-soak` (`benches/soak/`): 8, the soak (a fault a second for minutes: calls
//!   exactly once, memory, files, the robot reset after each stop, no motion ok across one).
//!
//! Here:
//! - this file: the commands and their options;
//! - [`registry`]: every benchmark in the order `all` runs them, every child role, the targets
//!   the benchmarks keep themselves;
//! - [`runner`]: one run of benchmarks into one report, written with its plots and printed.

mod registry;
mod runner;

use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::{Args, Parser, Subcommand};
use modbot_bench_kit::opts::{Opts, SoakPlan};
use modbot_bench_kit::procs;
use modbot_bench_system::ethercat;

use registry::{bench, Bench, BENCHES, CHILDREN, SOAK};

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
    /// 12: `modbot replay` of a recorded arm against the lockstep run that recorded it.
    Replay(RunArgs),
    /// 13: a call through two Zenoh bridges over a veth link against a raw Zenoh query.
    Remote(RunArgs),
    /// 14: live upgrades of a module under 1 000 calls a second: the call latency they add
    /// against the same stream without one, and the handover.
    Upgrade(RunArgs),
    /// One side of a benchmark (started by the benchmarks themselves).
    #[command(hide = true)]
    Child {
        role: String,
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

impl RunArgs {
    /// The options of a run with these arguments (and the soak's `soak`).
    fn opts(&self, soak: SoakPlan) -> anyhow::Result<Opts> {
        let exe = std::env::current_exe().context("cannot find this executable")?;
        let out = match &self.out {
            Some(dir) => dir.clone(),
            // <target>/release/modbot-benches → <target>/bench-report
            None => exe
                .parent()
                .and_then(|d| d.parent())
                .map(|t| t.join("bench-report"))
                .context("cannot place the report next to this executable: give --out DIR")?,
        };
        Ok(Opts {
            quick: self.quick,
            pin: self.pin,
            fifo: self.fifo,
            out,
            exe,
            soak,
        })
    }
}

/// Runs `benches` into one report, writes it with its plots, and prints report.md.
fn run_benches(args: &RunArgs, benches: &[&Bench]) -> anyhow::Result<()> {
    runner::run_with(args.opts(SoakPlan::default())?, benches)
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
        Cmd::Replay(args) => run_benches(&args, &[bench("replay")]),
        Cmd::Remote(args) => run_benches(&args, &[bench("remote")]),
        Cmd::Upgrade(args) => run_benches(&args, &[bench("upgrade")]),
        Cmd::Ethercat(args) => {
            ethercat::require_root()?;
            run_benches(&args, &[bench("ethercat")])
        }
        Cmd::Soak(args) => {
            let plan = SoakPlan {
                minutes: args.minutes,
                seed: args.seed,
            };
            runner::run_with(args.run.opts(plan)?, &[&SOAK])
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

//! The lockstep clock (part of benchmark 3): `examples/grid_demo.lua` under `modbot up
//! --lockstep --ticks N --trace OUT`, twice, with and without two CPU hogs. Its traces must be
//! byte-identical and equal to the in-process reference run (LET computed in one thread); what
//! is measured is how fast it goes.
//!
//! `grid.lockstep_rate` (ticks per second) is the N ticks over the wall time of a run of N
//! ticks minus that of a run of 100 (start-up and shutdown cancel out). Its baseline,
//! `grid.event_round_trip_rate`, is measured in the same run, right before and right after the
//! lockstep runs: raw iceoryx2 round trips between two processes that sleep on an Event between
//! messages (what one lockstep tick is made of: the coordinator wakes the hosts, they answer),
//! per second at their median. The ratio is how many such round trips a lockstep tick costs,
//! inverted: it moves with the grid's overhead, not with the machine's speed. Also reported:
//! `grid.realtime_rate`, the real-time clock's 1000 ticks per second, as the speed-up over
//! real time.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_ipc::paths::{Path as _, RawPath};
use modbot_bench_ipc::raw::Wait;
use modbot_bench_kit::hogs::Hogs;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::sample::{self, Plan};
use modbot_grid::reference_trace;
use modbot_system::{self as system, DefaultResolver};

/// The demo grid of the examples.
fn demo() -> PathBuf {
    modbot_bench_kit::checkout::example("grid_demo.lua")
}

/// Runs the demo for `ticks` in lockstep in `scratch`'s domain; returns its trace and how long
/// `modbot up` took.
fn run_once(opts: &Opts, scratch: &mut Scratch, ticks: u64) -> anyhow::Result<(String, Duration)> {
    let trace = scratch.path("lockstep.trace");
    let started = Instant::now();
    let out = std::process::Command::new(procs::binary(opts, "modbot")?)
        .args(["up", &demo().display().to_string(), "--lockstep"])
        .args(["--var", &format!("domain={}", scratch.domain.name())])
        .args(["--ticks", &ticks.to_string()])
        .args(["--trace", &trace.display().to_string()])
        .output()
        .context("cannot run modbot up")?;
    let took = started.elapsed();
    if !out.status.success() {
        bail!(
            "modbot up --lockstep exited {}: {}",
            out.status,
            String::from_utf8_lossy(&out.stdout)
                .lines()
                .chain(String::from_utf8_lossy(&out.stderr).lines())
                .rev()
                .take(8)
                .collect::<Vec<_>>()
                .join(" | ")
        );
    }
    let text = std::fs::read_to_string(&trace)
        .with_context(|| format!("the trace {} was not written", trace.display()))?;
    let _ = std::fs::remove_file(&trace);
    Ok((text, took))
}

/// What LET predicts for the demo in `domain`.
fn reference(file: &Path, domain: &str, ticks: u64) -> anyhow::Result<String> {
    let vars = vec![("domain".to_owned(), domain.to_owned())];
    let spec = system::load_with_vars(file, &DefaultResolver::for_file(file), &vars)?;
    let grid = spec.grid.context("grid_demo.lua has no grid")?;
    Ok(reference_trace(&grid, &modbot_components::builtin(), ticks))
}

/// Measures the lockstep runs and adds their rows and a note.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    let ticks = if opts.quick { 5_000 } else { 20_000 };
    for hogs in [0usize, 2] {
        report.push(
            Row::single("grid.realtime_rate", 1000)
                .param("hogs", hogs)
                .unit("ticks/s")
                .is_baseline(),
        );
        let _hogs = Hogs::start(opts, hogs)?;
        let mut scratch = Scratch::new(&format!("lockstep{hogs}"), None)?;
        let mut raw = RawPath::open(opts, Wait::Event, 4096, &[8], None)?;
        let mut round_trips = sample::histogram();
        let mut measure_raw = |raw: &mut RawPath| -> anyhow::Result<()> {
            let plan = Plan::new(opts, opts.samples(2_000, 10_000));
            let h = sample::record(&plan, || raw.one(&[0x5a; 8]))?;
            round_trips.add(&h).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            Ok(())
        };
        measure_raw(&mut raw)?;
        // Start-up and shutdown are measured by the shortest of three runs of 100 ticks, the
        // long run by the shorter of two: a start-up slowed by the machine must not be taken
        // for ticks.
        let mut short = Duration::MAX;
        for _ in 0..3 {
            short = short.min(run_once(opts, &mut scratch, 100)?.1);
        }
        let (first, long1) = run_once(opts, &mut scratch, ticks)?;
        let (second, long2) = run_once(opts, &mut scratch, ticks)?;
        let long = long1.min(long2);
        if long <= short {
            bail!(
                "lockstep: {ticks} ticks took {long:?}, no longer than 100 ticks ({short:?}): \
                 the machine's start-up noise hides the ticks; measure without --quick"
            );
        }
        measure_raw(&mut raw)?;
        raw.close()?;
        let p50 = round_trips.value_at_quantile(0.5).max(1);
        let raw_rate = (1e9 / p50 as f64).round() as u64;
        report.push(
            Row::single("grid.event_round_trip_rate", raw_rate)
                .param("hogs", hogs)
                .unit("round trips/s")
                .is_baseline(),
        );
        let want = reference(&demo(), scratch.domain.name(), ticks)?;
        let identical = first == second;
        let equal = first == want;
        let seconds = (long - short).as_secs_f64();
        let rate = ((ticks - 100) as f64 / seconds).round() as u64;
        report.push(
            Row::single("grid.lockstep_rate", rate)
                .param("hogs", hogs)
                .unit("ticks/s")
                .against("grid.event_round_trip_rate", &[]),
        );
        report.note(format!(
            "grid lockstep ({hogs} CPU hogs): examples/grid_demo.lua, {ticks} ticks twice: traces \
             byte-identical: {identical}; equal to the in-process reference: {equal}; \
             {rate} ticks/s ({:.1}× real time at 1 kHz); raw iceoryx2 Event round trips in the \
             same run, before and after: {raw_rate}/s (p50 {:.1} µs), so a lockstep tick costs \
             {:.1} of them",
            rate as f64 / 1000.0,
            p50 as f64 / 1000.0,
            raw_rate as f64 / rate.max(1) as f64,
        ));
        if !identical || !equal {
            bail!("the lockstep traces ({hogs} hogs) are not identical or differ from LET");
        }
    }
    Ok(())
}

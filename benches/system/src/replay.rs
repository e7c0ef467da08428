//! Benchmark 12, replay: how fast `modbot replay` runs a recorded arm again against the
//! lockstep run that recorded it. The arm (`examples/arm.lua`, swapped to `ptp` at tick 300)
//! is recorded replayable in lockstep for N ticks and for 100; each recording is replayed (it
//! must replay identical, or the benchmark fails).
//!
//! `replay.lockstep_rate` (the baseline, measured in the same run): the N − 100 ticks over the
//! wall time of the N-tick `modbot up` minus that of the 100-tick one (start-up and shutdown
//! cancel out; the shortest of three short and of two long runs). `replay.rate`: the same for
//! `modbot replay` of the two recordings (reading the file included). Their ratio is the
//! speed-up of replaying a controller offline over running the system in lockstep.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};

/// Runs `modbot ARGS` to its end; its wall time, or why it failed.
fn timed(opts: &Opts, args: &[&str]) -> anyhow::Result<(String, Duration)> {
    let started = Instant::now();
    let out = std::process::Command::new(procs::binary(opts, "modbot")?)
        .args(args)
        .output()
        .context("cannot run modbot")?;
    let took = started.elapsed();
    let said = String::from_utf8_lossy(&out.stdout).into_owned();
    if !out.status.success() {
        bail!(
            "modbot {} exited {}: {}",
            args.first().copied().unwrap_or_default(),
            out.status,
            said.lines()
                .chain(String::from_utf8_lossy(&out.stderr).lines())
                .rev()
                .take(8)
                .collect::<Vec<_>>()
                .join(" | ")
        );
    }
    Ok((said, took))
}

/// Records the arm for `ticks` in lockstep to `file`: the wall time of `modbot up`.
fn record(opts: &Opts, scratch: &Scratch, ticks: u64, file: &Path) -> anyhow::Result<Duration> {
    let arm = modbot_bench_kit::checkout::existing_example("arm.lua")?;
    let domain = format!("domain={}", scratch.domain.name());
    let ticks = ticks.to_string();
    let args = [
        "up",
        arm.to_str().unwrap_or_default(),
        "--var",
        &domain,
        "--lockstep",
        "--ticks",
        &ticks,
        "--switch",
        "300:ptp",
        "--record",
        file.to_str().unwrap_or_default(),
        "--replayable",
    ];
    Ok(timed(opts, &args)?.1)
}

/// Replays `file`: its wall time; it must be identical.
fn replay(opts: &Opts, file: &Path) -> anyhow::Result<Duration> {
    let (said, took) = timed(opts, &["replay", file.to_str().unwrap_or_default()])?;
    if !said.contains(": identical") {
        bail!("the replay of {} is not identical: {said}", file.display());
    }
    Ok(took)
}

pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    let ticks: u64 = if opts.quick { 3_000 } else { 10_000 };
    let mut scratch = Scratch::new("replay", None)?;
    let (short_file, long_file) = (scratch.path("short.h5"), scratch.path("long.h5"));
    let mut short = Duration::MAX;
    for _ in 0..3 {
        short = short.min(record(opts, &scratch, 100, &short_file)?);
    }
    let mut long = Duration::MAX;
    for _ in 0..2 {
        long = long.min(record(opts, &scratch, ticks, &long_file)?);
    }
    let (mut replay_short, mut replay_long) = (Duration::MAX, Duration::MAX);
    for _ in 0..3 {
        replay_short = replay_short.min(replay(opts, &short_file)?);
        replay_long = replay_long.min(replay(opts, &long_file)?);
    }
    let _ = std::fs::remove_file(&short_file);
    let _ = std::fs::remove_file(&long_file);
    if long <= short || replay_long <= replay_short {
        bail!(
            "replay: {ticks} ticks took no longer than 100 (lockstep {long:?} vs {short:?}, \
             replay {replay_long:?} vs {replay_short:?}): measure without --quick"
        );
    }
    let n = (ticks - 100) as f64;
    let lockstep = (n / (long - short).as_secs_f64()).round() as u64;
    let rate = (n / (replay_long - replay_short).as_secs_f64()).round() as u64;
    report.push(
        Row::single("replay.lockstep_rate", lockstep)
            .unit("ticks/s")
            .is_baseline(),
    );
    report.push(
        Row::single("replay.rate", rate)
            .unit("ticks/s")
            .against("replay.lockstep_rate", &[]),
    );
    report.note(format!(
        "replay: the arm recorded replayable in lockstep ({ticks} ticks, swapped to ptp at 300) \
         replays identical; modbot replay {rate} ticks/s against the lockstep run that recorded \
         it, {lockstep} ticks/s ({:.1}×); start-up and shutdown taken out with runs of 100 ticks \
         (lockstep {:.2} s, replay {:.2} s)",
        rate as f64 / lockstep.max(1) as f64,
        short.as_secs_f64(),
        replay_short.as_secs_f64(),
    ));
    Ok(())
}

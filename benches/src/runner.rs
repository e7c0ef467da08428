//! One run of benchmarks: each into one report (a failing one leaves a note and the run goes
//! on), the files a run left removed, the ratios and the targets, the report written with its
//! plots and printed.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::report::Report;
use modbot_bench_kit::{machine, plots, procs, targets};

use crate::registry::{Bench, MORE_TARGETS};

/// Runs `benches` into one report with the options made already (the soak's carry its plan),
/// writes it with its plots, and prints report.md.
pub fn run_with(opts: Opts, benches: &[&Bench]) -> anyhow::Result<()> {
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
    targets::evaluate(&mut report, &MORE_TARGETS);
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

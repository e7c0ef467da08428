//! Benchmark 14's grid part: a host of the time grid upgraded live while the arm moves.
//!
//! `examples/arm.lua` with `dwell=0` (the trajectory never rests), switched to `ptp`; then
//! `modbot upgrade` replaces the `ptp` assembly's host process again and again, its components'
//! state handed over at a tick (docs/upgrade.md, "A host of the time grid"). Per window (one
//! upgrade: the command, then the coordinator's next ledger):
//! - `upgrade.grid_overruns`: the upgraded host's components' overruns (a release not done by
//!   its deadline: its readers held its last outputs), against `upgrade.grid_overruns_idle`,
//!   the same count over windows of the same lengths without an upgrade, after them;
//! - `upgrade.grid_missed`: the coordinator's missed ticks and the bus bridge's missed cycles,
//!   against the same windows without (`upgrade.grid_missed_idle`).
//!
//! The target is 0 for all of them: the grid steps on as if nothing happened.

use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_kit::arm_system::start_arm;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::supervised::Supervised;
use modbot_grid::switch;

use crate::swaps::ledger_number;

/// What one window counted.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Counts {
    /// Overruns of the upgraded host's components.
    overruns: u64,
    /// The coordinator's missed ticks plus the bus bridge's missed cycles.
    missed: u64,
}

/// One count of a window.
type Field = fn(&Counts) -> u64;

/// The rows, and which count of a window each one shows.
const FIELDS: [(&str, Field); 2] = [
    ("upgrade.grid_overruns", |c| c.overruns),
    ("upgrade.grid_missed", |c| c.missed),
];

/// The histogram of one count over `windows`.
fn histogram(windows: &[Counts], field: Field) -> hdrhistogram::Histogram<u64> {
    let mut h = modbot_bench_kit::sample::histogram();
    windows
        .iter()
        .map(field)
        .for_each(|v| h.saturating_record(v));
    h
}

/// Runs the grid part of the upgrade benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    let upgrades = opts.samples(5, 20) as usize;
    let scratch = Scratch::new("upgrade-grid", None)?;
    let (mut sys, _) = start_arm(opts, &scratch, &["dwell=0"])?;
    let switched = switch::switch(sys.tool()?, "ptp", Duration::from_secs(30))
        .map_err(|e| anyhow::anyhow!("the switch to ptp: {e}"))?;
    sys.sleep(Duration::from_millis(300))?;
    let (_, rows) = ledger(&mut sys)?;
    let host = rows
        .iter()
        .find(|r| r.host != "bus")
        .map(|r| r.host.clone())
        .context("the ptp assembly has no component off the bus")?;
    let module = modbot_grid::spec::host_module_of(
        &host,
        modbot_grid::component::Generation(switched.generation),
    );
    let modbot = procs::binary(opts, "modbot")?;
    let domain = scratch.domain.name().to_owned();
    let mut during = Vec::new();
    let mut windows = Vec::new();
    for i in 0..upgrades {
        let before = counts(&mut sys, &host)?;
        let began = Instant::now();
        let out = Command::new(&modbot)
            .args(["upgrade", &module, "--domain", &domain])
            .output()?;
        if !out.status.success() {
            bail!(
                "upgrade {} of {module}: {}{}",
                i + 1,
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        let after = counts(&mut sys, &host)?;
        windows.push(began.elapsed());
        during.push(difference(before, after));
    }
    let mut idle = Vec::new();
    for w in &windows {
        let before = counts(&mut sys, &host)?;
        sys.sleep(*w)?;
        idle.push(difference(before, counts(&mut sys, &host)?));
    }
    let left = sys.stop()?;
    for (name, field) in FIELDS {
        let base = format!("{name}_idle");
        report.push(
            Row::from_histogram(&base, &histogram(&idle, field))
                .unit("count")
                .is_baseline(),
        );
        report.push(
            Row::from_histogram(name, &histogram(&during, field))
                .unit("count")
                .against(&base, &[]),
        );
    }
    let total = |v: &[Counts], field: Field| v.iter().map(field).sum::<u64>();
    report.note(format!(
        "upgrade (grid): {upgrades} live upgrades of {module} (host {host}, the arm's ptp \
         assembly at 1 kHz, moving): {} overrun(s) of its components and {} missed tick(s) or \
         bus cycle(s) in all; over windows of the same lengths without an upgrade: {} and {}.{}",
        total(&during, |c| c.overruns),
        total(&during, |c| c.missed),
        total(&idle, |c| c.overruns),
        total(&idle, |c| c.missed),
        if left.is_empty() {
            String::new()
        } else {
            format!(
                " {} file(s) of the domain were left after the stop and removed.",
                left.len()
            )
        }
    ));
    Ok(())
}

/// The coordinator's ledger, once it is refreshed after now (every 200 ms).
fn ledger(
    sys: &mut Supervised,
) -> anyhow::Result<(
    modbot_grid::ledger::GridRow,
    Vec<modbot_grid::ledger::ComponentRow>,
)> {
    sys.sleep(Duration::from_millis(250))?;
    let bytes = sys.call_bytes("coordinator", "ledger")?;
    modbot_grid::ledger::decode(&bytes).context("coordinator.ledger")
}

/// The counts so far: `host`'s components' overruns, the grid's missed ticks and the bus's
/// missed cycles.
fn counts(sys: &mut Supervised, host: &str) -> anyhow::Result<Counts> {
    let (grid, rows) = ledger(sys)?;
    let bus = ledger_number(&sys.call_text("host_bus", "bus")?, "missed")?;
    Ok(Counts {
        overruns: rows
            .iter()
            .filter(|r| r.host == host)
            .map(|r| r.overruns)
            .sum(),
        missed: grid.missed + bus,
    })
}

fn difference(before: Counts, after: Counts) -> Counts {
    Counts {
        overruns: after.overruns.saturating_sub(before.overruns),
        missed: after.missed.saturating_sub(before.missed),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_counts_what_grew_in_it() {
        let before = Counts {
            overruns: 3,
            missed: 1,
        };
        let after = Counts {
            overruns: 5,
            missed: 1,
        };
        assert_eq!(
            difference(before, after),
            Counts {
                overruns: 2,
                missed: 0
            }
        );
        // A ledger that went back (a restarted coordinator) counts nothing, not a wrap.
        assert_eq!(difference(after, before), Counts::default());
    }
}

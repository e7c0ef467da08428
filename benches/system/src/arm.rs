//! Benchmark 7, arm: `examples/arm.lua` holding (the `hold` assembly, six simulated CiA 402
//! drives behind the bus bridge, SCHED_FIFO as the example declares) for a span: the bus
//! cycles it ran and missed, from the bus bridge's ledger (`modbot bus`) at the start and end
//! of the span.
//!
//! Baseline, same run: the bare 1 kHz timerfd loop of the grid benchmark under SCHED_FIFO,
//! observed for the same span: the ticks the machine let a bare real-time loop run and miss.
//! The bus may miss no more than that plus 0.5 % of its cycles.

use std::time::Duration;

use anyhow::bail;
use modbot_bench_kit::arm_system::start_arm;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};

use crate::swaps::ledger_number;

/// Runs the arm benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    let span = Duration::from_secs(if opts.quick { 5 } else { 30 });
    let (bare_ticks, bare_missed) = crate::grid::bare_loop(opts, true, span)?;
    let scratch = Scratch::new("arm", None)?;
    let (mut sys, _) = start_arm(opts, &scratch, &[])?;
    sys.sleep(Duration::from_millis(500))?;
    let before = sys.call_text("host_bus", "bus")?;
    sys.sleep(span)?;
    let after = sys.call_text("host_bus", "bus")?;
    let left = sys.stop()?;
    let cycles = ledger_number(&after, "cycles")? - ledger_number(&before, "cycles")?;
    let missed = ledger_number(&after, "missed")? - ledger_number(&before, "missed")?;
    if cycles == 0 {
        bail!("the bus ran no cycle in {} s", span.as_secs());
    }
    let count = |name: &str, n: u64| Row::single(name, n).unit("count");
    report.push(count("arm.timerfd_ticks", bare_ticks + bare_missed).is_baseline());
    report.push(count("arm.timerfd_missed", bare_missed).is_baseline());
    report.push(count("arm.bus_cycles", cycles + missed).against("arm.timerfd_ticks", &[]));
    report.push(count("arm.bus_missed", missed).against("arm.timerfd_missed", &[]));
    let pct = |m: u64, n: u64| 100.0 * m as f64 / n.max(1) as f64;
    let mut note = format!(
        "arm: examples/arm.lua holding for {} s: the bus ran {cycles} cycles and missed {missed} \
         ({:.2} %); the bare SCHED_FIFO timerfd loop over the same span ran {bare_ticks} ticks and \
         missed {bare_missed} ({:.2} %). Bus ledger after: {}",
        span.as_secs(),
        pct(missed, cycles + missed),
        pct(bare_missed, bare_ticks + bare_missed),
        after.lines().next().unwrap_or_default().trim()
    );
    if !left.is_empty() {
        note.push_str(&format!(
            "; {} file(s) of the domain were left after the stop and removed",
            left.len()
        ));
    }
    report.note(note);
    Ok(())
}

/// No child roles.
pub fn child(_role: &str, _args: &[String]) -> Option<anyhow::Result<()>> {
    None
}

//! Benchmark 6, swaps: assemblies swapped while the robot moves, on `examples/arm.lua` (six
//! simulated CiA 402 drives behind the bus bridge) with `dwell=0` (the trajectory never rests).
//!
//! After one switch to `ptp`, N swaps alternate `hold` and `ptp`, each through the
//! runtime's `grid::switch::switch` from a tool endpoint in this process (what
//! `modbot assembly switch` does):
//! - `swaps.prepare`: from the request to the coordinator's report that the new assembly took
//!   over (loading the file, starting its host process, subscribing, tracking, the switch tick);
//! - `swaps.tick_error` (ticks): the tick at which the bus bridge first served the new
//!   generation (`host_bus.switches`, the bus's own record) minus the tick the coordinator
//!   announced; it should be 0;
//! - `swaps.missed_cycles` (count): the bus ledger's missed cycles over each swap.
//!
//! Baselines: `swaps.startup`, the same system's start-up (spawning `modbot up` to every
//! process up): a swap prepares a part of a system while the rest runs; `swaps.missed_cycles_idle`,
//! missed cycles over windows of the same lengths without swaps, after them, with the robot
//! still moving; the tick error is its own baseline (the target is exactly 0).

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use modbot_bench_kit::arm_system::start_arm;
use modbot_bench_kit::opts::Opts;
use modbot_bench_kit::procs::{self, Scratch};
use modbot_bench_kit::report::{Report, Row};
use modbot_bench_kit::supervised::Supervised;
use modbot_grid::switch;
use modbot_ipc_schema::bus::Switches;

/// Runs the swaps benchmark.
pub fn run(opts: &Opts, report: &mut Report) -> anyhow::Result<()> {
    procs::ensure_binaries(opts)?;
    let n = opts.samples(10, 100) as usize;
    let scratch = Scratch::new("swaps", None)?;
    let (mut sys, startup) = start_arm(opts, &scratch, &["dwell=0"])?;
    let timeout = Duration::from_secs(30);
    switch::switch(sys.tool()?, "ptp", timeout)
        .map_err(|e| anyhow::anyhow!("the first switch, to ptp: {e}"))?;
    sys.sleep(Duration::from_millis(300))?;
    let coordinator_before = coordinator_missed(&mut sys);
    // Safe stops the bus ledger reported (the robot then stops moving until a switch to hold).
    let mut stops = Vec::new();
    let mut prepare = modbot_bench_kit::sample::histogram();
    let mut missed = modbot_bench_kit::sample::histogram();
    let mut windows = Vec::new();
    let mut switched = Vec::new();
    let mut failures = Vec::new();
    for i in 0..n {
        let name = if i % 2 == 0 { "hold" } else { "ptp" };
        let before = missed_cycles(&mut sys, &mut stops)?;
        let t = Instant::now();
        match switch::switch(sys.tool()?, name, timeout) {
            Ok(s) => {
                prepare.saturating_record(u64::try_from(s.took.as_nanos()).unwrap_or(u64::MAX));
                switched.push(s);
            }
            Err(e) => failures.push(format!("swap {i} to {name}: {e}")),
        }
        windows.push(t.elapsed());
        let after = missed_cycles(&mut sys, &mut stops)?;
        missed.saturating_record(after.saturating_sub(before));
        // Let it move a little between swaps.
        sys.sleep(Duration::from_millis(20))?;
    }
    let coordinator_swaps = coordinator_missed(&mut sys);
    let mut idle = modbot_bench_kit::sample::histogram();
    for w in &windows {
        let before = missed_cycles(&mut sys, &mut stops)?;
        sys.sleep(*w)?;
        let after = missed_cycles(&mut sys, &mut stops)?;
        idle.saturating_record(after.saturating_sub(before));
    }
    let coordinator_idle = coordinator_missed(&mut sys);
    let bus_record = modbot_ipc_schema::bus::decode(&sys.call_bytes("host_bus", "switches")?)
        .context("host_bus.switches")?;
    let ledger = sys.call_text("host_bus", "bus")?;
    let mut tick_error = modbot_bench_kit::sample::histogram();
    let mut position_step = modbot_bench_kit::sample::histogram();
    let mut velocity_step = modbot_bench_kit::sample::histogram();
    let mut not_seen = Vec::new();
    let mut early = 0;
    for s in &switched {
        match bus_switch(&bus_record, s.generation) {
            Some((t, step, vstep)) => {
                if t < s.announced {
                    early += 1;
                }
                tick_error.saturating_record(t.abs_diff(s.announced));
                position_step.saturating_record((step * 1e6).round() as u64);
                velocity_step.saturating_record((vstep * 1e6).round() as u64);
            }
            None => not_seen.push(s.generation),
        }
    }
    let left = sys.stop()?;
    if switched.is_empty() {
        bail!("no swap succeeded: {}", failures.join("; "));
    }
    report.push(
        Row::single(
            "swaps.startup",
            u64::try_from(startup.as_nanos()).unwrap_or(u64::MAX),
        )
        .is_baseline(),
    );
    report.push(Row::from_histogram("swaps.prepare", &prepare).against("swaps.startup", &[]));
    if !tick_error.is_empty() {
        report.push(
            Row::from_histogram("swaps.tick_error", &tick_error)
                .unit("ticks")
                .is_baseline(),
        );
    }
    report.push(
        Row::from_histogram("swaps.missed_cycles_idle", &idle)
            .unit("count")
            .is_baseline(),
    );
    report.push(
        Row::from_histogram("swaps.missed_cycles", &missed)
            .unit("count")
            .against("swaps.missed_cycles_idle", &[]),
    );
    report.push(
        Row::single("swaps.swaps", n as u64)
            .unit("count")
            .is_baseline(),
    );
    report.push(
        Row::single("swaps.failed", failures.len() as u64)
            .unit("count")
            .against("swaps.swaps", &[]),
    );
    // The command's continuity at each switch, as the bus saw it, against one tick's worth of
    // the trajectories' limits (v_max 1 rad/s, a_max 4 rad/s², base period 1 ms).
    report.push(
        Row::single("swaps.one_tick_motion", 1000)
            .unit("µrad")
            .is_baseline(),
    );
    report.push(
        Row::single("swaps.one_tick_acceleration", 4000)
            .unit("µrad/s")
            .is_baseline(),
    );
    if !position_step.is_empty() {
        report.push(
            Row::from_histogram("swaps.position_step", &position_step)
                .unit("µrad")
                .against("swaps.one_tick_motion", &[]),
        );
        report.push(
            Row::from_histogram("swaps.velocity_step", &velocity_step)
                .unit("µrad/s")
                .against("swaps.one_tick_acceleration", &[]),
        );
    }
    let mut note = format!(
        "swaps: {} of {n} swaps between hold and ptp while the arm moves (examples/arm.lua, \
         dwell=0), each switched at tick T announced for tick A by the coordinator; the bus saw \
         {} of them at the announced tick. Missed bus cycles: {} over the swaps, {} over idle \
         windows of the same lengths. Position and velocity steps are the largest change of \
         the commanded position (and of its change per tick over the base period) on any axis \
         at the switch, from the bus's own record. Bus ledger after: {}.",
        switched.len(),
        switched
            .iter()
            .filter(|s| bus_switch(&bus_record, s.generation).map(|b| b.0) == Some(s.announced))
            .count(),
        sum(&missed),
        sum(&idle),
        ledger.lines().next().unwrap_or_default().trim()
    );
    if let (Some(a), Some(b), Some(c)) = (coordinator_before, coordinator_swaps, coordinator_idle) {
        note.push_str(&format!(
            " The coordinator's own ledger counts {} missed ticks over the swaps and {} over the \
             idle windows (the bus counts a cycle missed when its process served the grid more \
             than 1.5 periods after the previous cycle, whoever was late).",
            b.saturating_sub(a),
            c.saturating_sub(b)
        ));
    }
    if !stops.is_empty() {
        note.push_str(&format!(
            " The bus bridge reported {} safe stop(s) during the run: {}.",
            stops.len(),
            stops.join("; ")
        ));
    }
    if early > 0 {
        note.push_str(&format!(
            " {early} switch(es) took over before the announced tick."
        ));
    }
    if !not_seen.is_empty() {
        note.push_str(&format!(" Generations the bus never served: {not_seen:?}."));
    }
    if !failures.is_empty() {
        note.push_str(&format!(" Failed: {}.", failures.join("; ")));
    }
    if !left.is_empty() {
        note.push_str(&format!(
            " {} file(s) of the domain were left after the stop and removed.",
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

/// The sum of the recorded values.
fn sum(h: &hdrhistogram::Histogram<u64>) -> u64 {
    h.iter_recorded()
        .map(|v| v.value_iterated_to() * v.count_at_value())
        .sum()
}

/// The coordinator's missed ticks (its ledger, published every 200 ms), if it answers.
fn coordinator_missed(sys: &mut Supervised) -> Option<u64> {
    // The ledger is refreshed every 200 ms: wait for the current one.
    sys.sleep(Duration::from_millis(250)).ok()?;
    let bytes = sys.tool().ok()?.call_blocking(
        "coordinator",
        "ledger",
        &[],
        modbot_core::CallOptions::timeout(Duration::from_secs(1)),
        |r| r.ok().and_then(|a| a.bytes(0).ok().map(<[u8]>::to_vec)),
    )?;
    modbot_grid::ledger::decode(&bytes)
        .ok()
        .map(|(g, _)| g.missed)
}

/// The missed cycles of the bus ledger's first line ("... missed M ...").
/// Also notes a safe stop the ledger reports that `stops` does not hold yet.
fn missed_cycles(sys: &mut Supervised, stops: &mut Vec<String>) -> anyhow::Result<u64> {
    let ledger = sys.call_text("host_bus", "bus")?;
    let first = ledger.lines().next().unwrap_or_default();
    if let Some(at) = first.find("SAFE STOP") {
        let stop = first[at..].trim().to_owned();
        if !stops.contains(&stop) {
            stops.push(stop);
        }
    }
    ledger_number(&ledger, "missed")
}

/// The number after `label` in the bus ledger's first line ("cycles 9000", "missed 2").
pub(crate) fn ledger_number(ledger: &str, label: &str) -> anyhow::Result<u64> {
    let first = ledger.lines().next().unwrap_or_default();
    let words: Vec<&str> = first.split_whitespace().collect();
    words
        .iter()
        .position(|w| *w == label)
        .and_then(|i| words.get(i + 1))
        .and_then(|w| w.parse().ok())
        .ok_or_else(|| anyhow::anyhow!("no '{label}' number in the bus ledger: {first}"))
}

/// The tick at which the bus first served `generation`, and the position and velocity steps
/// there (`host_bus.switches`, the bus's own record).
fn bus_switch(record: &Switches, generation: u16) -> Option<(u64, f64, f64)> {
    record
        .switches
        .iter()
        .find(|s| s.generation == generation)
        .map(|s| (s.tick, s.step, s.velocity_step))
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_ipc_schema::bus::Switch;

    #[test]
    fn the_bus_records_read_back() {
        let switch = |generation, tick, step, velocity_step| Switch {
            generation,
            tick,
            step,
            velocity_step,
            missed_near: 0,
        };
        let record = Switches {
            max_step: 1e-3,
            max_velocity_step: 4e-3,
            switches: vec![switch(2, 5114, 3e-4, 2e-3), switch(3, 5300, 1e-4, 3e-3)],
        };
        assert_eq!(bus_switch(&record, 3), Some((5300, 1e-4, 3e-3)));
        assert_eq!(bus_switch(&record, 4), None);
        let ledger = "bus sim  axes 6  cycles 9000  missed 2  running\nAXIS ...";
        assert_eq!(ledger_number(ledger, "missed").unwrap(), 2);
        assert_eq!(ledger_number(ledger, "cycles").unwrap(), 9000);
        assert!(ledger_number("nothing", "missed").is_err());
    }
}

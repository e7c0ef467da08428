//! The soak's rows (`soak.*`): counts and bytes, each compared with the row it is a share
//! of, and the robot's recoveries as grid time.

use modbot_bench_kit::report::{Report, Row};

use crate::{arm, ends, inject, journal, motions, samples, Run};

/// Every row of the soak into `report`; `params` go on each (its minutes and seed).
pub fn push_rows(
    report: &mut Report,
    params: &[(&str, serde_json::Value)],
    run: &Run,
    tally: &journal::Tally,
    ends: &ends::Ends,
    left: usize,
    moves: &motions::Tally,
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
    push_robot_rows(report, params, run, moves);
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

/// The robot's rows: its stops and how many a reset ended, the resets and how many were
/// refused, the time from a stop to operational again against the resets' own time, and the
/// motions by what became of them.
fn push_robot_rows(
    report: &mut Report,
    params: &[(&str, serde_json::Value)],
    run: &Run,
    moves: &motions::Tally,
) {
    let with_params = |mut r: Row| {
        for (k, v) in params {
            r = r.param(k, v.clone());
        }
        r
    };
    let count = |name: &str, value: u64| with_params(Row::single(name, value).unit("count"));
    let w = &run.robot;
    report.push(count("soak.arm_safe_stops", w.stops.len() as u64).is_baseline());
    report.push(
        count("soak.recoveries", w.recovered().count() as u64).against("soak.arm_safe_stops", &[]),
    );
    report.push(count("soak.resets", w.resets).is_baseline());
    let refused = w.refused.values().sum();
    report.push(count("soak.resets_refused", refused).against("soak.resets", &[]));
    let (recovery, reset) = w.histograms();
    if !reset.is_empty() {
        report.push(with_params(Row::from_histogram("soak.reset", &reset)).is_baseline());
    }
    if !recovery.is_empty() {
        let row = with_params(Row::from_histogram("soak.recovery", &recovery));
        report.push(if reset.is_empty() {
            row.is_baseline()
        } else {
            row.against("soak.reset", &[])
        });
    }
    report.push(count("soak.motions", moves.motions).is_baseline());
    for (name, n) in [
        ("soak.motions_ok", moves.ok),
        ("soak.motions_refused", moves.refused),
        (
            "soak.motions_failed_left_operational",
            moves.left_operational,
        ),
        ("soak.motions_failed_other", moves.failed.len() as u64),
    ] {
        report.push(count(name, n).against("soak.motions", &[]));
    }
    report.push(
        count("soak.motions_false_ok", moves.false_ok.len() as u64).against("soak.motions_ok", &[]),
    );
}

//! The targets, checked against the rows of a run. A target whose rows are missing is
//! "not measured" with the reason; a missed one says by how much.

use serde_json::Value as Json;

use crate::report::{format_value, Report, Row, Target};
use crate::sample::size_label;

/// The targets of one benchmark that keeps its own (the soak, EtherCAT, the station), checked
/// against the rows of a report.
pub type TargetsFn = fn(&Report) -> Vec<Target>;

/// Evaluates every target from the rows present (after [`Report::resolve`]) into
/// `report.targets`, replacing what was there: the targets of calls, snapshots, the
/// grid and scale, then those of `more`, in their order.
pub fn evaluate(report: &mut Report, more: &[TargetsFn]) {
    let targets = vec![
        per_payload(
            report,
            "busy-mode call round trip",
            "p50 ≤ 1.3× raw iceoryx2",
            ("calls.modbot_busy", "calls.raw_iceoryx2_busy"),
            1.3,
        ),
        snapshot_flatness(report),
        per_payload(
            report,
            "blocking-mode call",
            "p50 ≤ the Unix-socket blocking p50",
            ("calls.modbot_blocking", "calls.uds_blocking"),
            1.0,
        ),
        per_payload(
            report,
            "blocking-mode call, both sides asleep when it starts",
            "p50 ≤ the Unix-socket blocking p50",
            ("calls.modbot_blocking_paced", "calls.uds_blocking_paced"),
            1.0,
        ),
        absolute(
            report,
            "grid tick error at 1 kHz with SCHED_FIFO",
            "p99 ≤ 100 µs",
            (
                "grid.tick_error",
                &[("fifo", Json::Bool(true)), ("hogs", Json::from(0))],
            ),
            |r| r.p99_ns,
            "p99",
            100_000,
        ),
        absolute(
            report,
            "coordinator CPU per tick",
            "≤ 10 µs",
            (
                "grid.coordinator_cpu",
                &[("fifo", Json::Bool(true)), ("hogs", Json::from(0))],
            ),
            |r| r.p50_ns,
            "p50",
            10_000,
        ),
        at_full_scale(
            report,
            "254 modules: start-up",
            "up in ≤ 3 s",
            "scale.startup",
            |r, m| {
                absolute(
                    r,
                    "254 modules: start-up",
                    "up in ≤ 3 s",
                    ("scale.startup", &[("modules", m)]),
                    |r| r.p50_ns,
                    "",
                    3_000_000_000,
                )
            },
        ),
        scale_call(report),
        at_full_scale(
            report,
            "254 modules: /dev/shm",
            "≤ 32 MiB in all",
            "scale.shm_bytes",
            |r, m| {
                absolute(
                    r,
                    "254 modules: /dev/shm",
                    "≤ 32 MiB in all",
                    ("scale.shm_bytes", &[("modules", m)]),
                    |r| r.p50_ns,
                    "",
                    32 << 20,
                )
            },
        ),
        at_full_scale(
            report,
            "254 modules: idle system",
            "≤ 5 % of one core",
            "scale.idle_cpu",
            |r, m| {
                absolute(
                    r,
                    "254 modules: idle system",
                    "≤ 5 % of one core (50 ‰)",
                    ("scale.idle_cpu", &[("modules", m)]),
                    |r| r.p50_ns,
                    "",
                    50,
                )
            },
        ),
        at_full_scale(
            report,
            "254 modules: modbot ls",
            "answers in ≤ 200 ms",
            "scale.ls",
            |r, m| {
                absolute(
                    r,
                    "254 modules: modbot ls",
                    "answers in ≤ 200 ms (slowest of 3)",
                    ("scale.ls", &[("modules", m)]),
                    |r| r.max_ns,
                    "max",
                    200_000_000,
                )
            },
        ),
    ];
    let more: Vec<Target> = more.iter().flat_map(|targets| targets(report)).collect();
    report.targets = targets.into_iter().chain(more).collect();
}

/// Whether `have` matches `want`: equal, or equal as text (`true` and `"true"`).
fn same(have: &Json, want: &Json) -> bool {
    let text = |v: &Json| match v {
        Json::String(s) => s.clone(),
        other => other.to_string(),
    };
    have == want || text(have) == text(want)
}

/// The rows named `name` whose params include `params` (they may have more).
pub fn rows_with<'a>(report: &'a Report, name: &str, params: &[(&str, Json)]) -> Vec<&'a Row> {
    report
        .rows
        .iter()
        .filter(|r| {
            r.name == name
                && params
                    .iter()
                    .all(|(k, v)| r.params.get(*k).is_some_and(|h| same(h, v)))
        })
        .collect()
}

/// "1.52× (17 % over)" for a ratio against a limit, "1.10×" when within it.
pub fn ratio_text(ratio: f64, limit: f64) -> String {
    if ratio <= limit {
        format!("{ratio:.2}×")
    } else {
        format!("{ratio:.2}× ({})", over(ratio, limit))
    }
}

/// "17 % over" the limit.
fn over(value: f64, limit: f64) -> String {
    let pct = (value / limit - 1.0) * 100.0;
    if pct < 1.0 {
        format!("{pct:.1} % over")
    } else {
        format!("{pct:.0} % over")
    }
}

fn bytes_of(r: &Row) -> Option<u64> {
    r.params.get("bytes").and_then(Json::as_u64)
}

pub fn target(measure: &str, goal: &str, measured: String, met: Option<bool>) -> Target {
    Target {
        measure: measure.to_owned(),
        target: goal.to_owned(),
        measured,
        met,
    }
}

/// A ratio target checked at every payload of `rows.0` against `rows.1` of the same payload.
fn per_payload(
    report: &Report,
    measure: &str,
    goal: &str,
    (name, base): (&str, &str),
    limit: f64,
) -> Target {
    let mut parts = Vec::new();
    let mut worst: Option<(f64, u64)> = None;
    let mut missing = Vec::new();
    let mut sizes: Vec<u64> = rows_with(report, name, &[])
        .iter()
        .chain(rows_with(report, base, &[]).iter())
        .filter_map(|r| bytes_of(r))
        .collect();
    sizes.sort_unstable();
    sizes.dedup();
    for bytes in sizes {
        let p = [("bytes", Json::from(bytes))];
        let (Some(row), Some(b)) = (
            rows_with(report, name, &p).first().copied(),
            rows_with(report, base, &p).first().copied(),
        ) else {
            missing.push(size_label(bytes as usize));
            continue;
        };
        let ratio = row.p50_ns as f64 / b.p50_ns.max(1) as f64;
        parts.push(format!(
            "{} {}",
            size_label(bytes as usize),
            ratio_text(ratio, limit)
        ));
        if worst.is_none_or(|(w, _)| ratio > w) {
            worst = Some((ratio, bytes));
        }
    }
    let Some((w, at)) = worst else {
        return target(
            measure,
            goal,
            format!("no {name} and {base} rows of the same payload in this run"),
            None,
        );
    };
    let mut measured = parts.join(", ");
    measured.push_str(&format!(
        "; worst {} at {}",
        ratio_text(w, limit),
        size_label(at as usize)
    ));
    let met = if w > limit {
        Some(false)
    } else if !missing.is_empty() {
        measured.push_str(&format!("; not measured at {}", missing.join(", ")));
        None
    } else {
        Some(true)
    };
    target(measure, goal, measured, met)
}

/// 1 MiB snapshot p50 against the 8 B one.
fn snapshot_flatness(report: &Report) -> Target {
    let (measure, goal) = ("1 MiB snapshot", "p50 ≤ 1.5× the 8 B snapshot");
    let get = |b: u64| first_with(report, "snapshots.modbot", ("bytes", b));
    match (get(1 << 20), get(8)) {
        (Some(big), Some(small)) => {
            p50_ratio(measure, goal, 1.5, (big, "1 MiB".into()), (small, "8 B"))
        }
        (big, _) => target(
            measure,
            goal,
            format!(
                "no snapshots.modbot row at {} in this run",
                if big.is_none() { "1 MiB" } else { "8 B" }
            ),
            None,
        ),
    }
}

/// The first row named `name` whose param `key` is `value`.
fn first_with<'a>(report: &'a Report, name: &str, (key, value): (&str, u64)) -> Option<&'a Row> {
    rows_with(report, name, &[(key, Json::from(value))])
        .first()
        .copied()
}

/// A target on the p50 of `big` over that of `small`, two rows of one name told apart by what
/// they were measured at (`1 MiB`, `8 B`), against `limit`.
fn p50_ratio(
    measure: &str,
    goal: &str,
    limit: f64,
    (big, big_at): (&Row, String),
    (small, small_at): (&Row, &str),
) -> Target {
    let ratio = big.p50_ns as f64 / small.p50_ns.max(1) as f64;
    target(
        measure,
        goal,
        format!(
            "{} ({} at {big_at}, {} at {small_at})",
            ratio_text(ratio, limit),
            format_value(big.p50_ns, None),
            format_value(small.p50_ns, None)
        ),
        Some(ratio <= limit),
    )
}

/// A target on one value of every matching row, against an absolute limit (in the rows' unit).
pub fn absolute(
    report: &Report,
    measure: &str,
    goal: &str,
    (name, params): (&str, &[(&str, Json)]),
    value: fn(&Row) -> u64,
    what: &str,
    limit: u64,
) -> Target {
    let rows = rows_with(report, name, params);
    if rows.is_empty() {
        let p: Vec<String> = params.iter().map(|(k, v)| format!("{k}={v}")).collect();
        return target(
            measure,
            goal,
            format!("no {name} row{} in this run", {
                if p.is_empty() {
                    String::new()
                } else {
                    format!(" with {}", p.join(" "))
                }
            }),
            None,
        );
    }
    let mut parts = Vec::new();
    let mut met = true;
    for r in &rows {
        let v = value(r);
        let mut text = format_value(v, r.unit);
        if !what.is_empty() {
            text = format!("{what} {text}");
        }
        // Rows that differ only in params the target does not name are told apart.
        let extra: Vec<String> = r
            .params
            .iter()
            .filter(|(k, _)| !params.iter().any(|(p, _)| p == k))
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        if rows.len() > 1 && !extra.is_empty() {
            text = format!("{text} ({})", extra.join(" "));
        }
        if v > limit {
            met = false;
            text.push_str(&format!(" ({})", over(v as f64, limit as f64)));
        }
        parts.push(text);
    }
    target(measure, goal, parts.join(", "), Some(met))
}

/// The fewest modules that count as "254": a full system is 253 modules and the supervisor,
/// since the supervisor takes one of the 254 addresses.
const FULL_SCALE: u64 = 253;

/// The largest `modules` param of the rows named `name`.
fn largest_scale(report: &Report, name: &str) -> Option<u64> {
    rows_with(report, name, &[])
        .iter()
        .filter_map(|r| r.params.get("modules").and_then(Json::as_u64))
        .max()
}

/// Checks `check` on the rows of the largest system measured, if it is a full one (253 or
/// 254 modules); otherwise "not measured" with the largest size there is.
fn at_full_scale(
    report: &Report,
    measure: &str,
    goal: &str,
    name: &str,
    check: impl Fn(&Report, Json) -> Target,
) -> Target {
    match largest_scale(report, name) {
        Some(m) if m >= FULL_SCALE => {
            let mut t = check(report, Json::from(m));
            if m != 254 {
                t.measured = format!("{} (at {m} modules)", t.measured);
            }
            t
        }
        Some(m) => target(
            measure,
            goal,
            format!("no {name} row at 253 or 254 modules in this run (largest: {m})"),
            None,
        ),
        None => target(measure, goal, format!("no {name} row in this run"), None),
    }
}

/// Call p50 at the full scale against 2 modules.
fn scale_call(report: &Report) -> Target {
    let (measure, goal) = (
        "254 modules: call round trip",
        "p50 ≤ 1.2× the 2-module figure",
    );
    let get = |n: u64| first_with(report, "scale.call", ("modules", n));
    let full = largest_scale(report, "scale.call").filter(|&m| m >= FULL_SCALE);
    match (full.and_then(get), get(2)) {
        (Some(big), Some(small)) => p50_ratio(
            measure,
            goal,
            1.2,
            (big, full.unwrap_or(254).to_string()),
            (small, "2"),
        ),
        (big, _) => target(
            measure,
            goal,
            if big.is_none() {
                format!(
                    "no scale.call row at 253 or 254 modules in this run{}",
                    largest_scale(report, "scale.call")
                        .map(|m| format!(" (largest: {m})"))
                        .unwrap_or_default()
                )
            } else {
                "no scale.call row with modules=2 in this run".to_owned()
            },
            None,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn call_rows(report: &mut Report, bytes: u64, modbot: u64, raw: u64) {
        report.push(
            Row::single("calls.raw_iceoryx2_busy", raw)
                .param("bytes", bytes)
                .is_baseline(),
        );
        report.push(
            Row::single("calls.modbot_busy", modbot)
                .param("bytes", bytes)
                .against("calls.raw_iceoryx2_busy", &[]),
        );
    }

    fn find<'a>(report: &'a Report, measure: &str) -> &'a Target {
        report
            .targets
            .iter()
            .find(|t| t.measure == measure)
            .expect("target evaluated")
    }

    /// Evaluates `sut` and checks whether the target `measure` is met; returns what it says was
    /// measured.
    fn evaluated(sut: &mut Report, measure: &str, met: Option<bool>) -> String {
        evaluate(sut, &[]);
        let t = find(sut, measure);
        assert_eq!(t.met, met, "{}", t.measured);
        t.measured.clone()
    }

    /// [`evaluated`] for the busy call's target.
    fn busy_call(sut: &mut Report, met: Option<bool>) -> String {
        evaluated(sut, "busy-mode call round trip", met)
    }

    #[test]
    fn a_met_ratio_target_lists_every_payload() {
        let mut sut = Report::default();
        call_rows(&mut sut, 8, 1100, 1000);
        call_rows(&mut sut, 64, 1200, 1000);
        assert_eq!(
            busy_call(&mut sut, Some(true)),
            "8 B 1.10×, 64 B 1.20×; worst 1.20× at 64 B"
        );
    }

    #[test]
    fn a_missed_ratio_target_says_by_how_much() {
        let mut sut = Report::default();
        call_rows(&mut sut, 8, 1100, 1000);
        call_rows(&mut sut, 1 << 20, 1976, 1000);
        let measured = busy_call(&mut sut, Some(false));
        assert!(
            measured.ends_with("worst 1.98× (52 % over) at 1 MiB"),
            "{measured}"
        );
    }

    #[test]
    fn a_target_without_its_rows_is_not_measured_and_says_why() {
        let mut sut = Report::default();
        assert_eq!(
            evaluated(&mut sut, "grid tick error at 1 kHz with SCHED_FIFO", None),
            "no grid.tick_error row with fifo=true hogs=0 in this run"
        );
        // Those of calls, snapshots, the grid and scale (the binary's test counts the soak's,
        // EtherCAT's and the station's too).
        assert_eq!(sut.targets.len(), 11);
        assert!(sut.targets.iter().all(|t| t.met.is_none()));
    }

    #[test]
    fn a_payload_with_only_one_side_leaves_a_met_target_undecided() {
        let mut sut = Report::default();
        call_rows(&mut sut, 8, 1100, 1000);
        sut.push(
            Row::single("calls.raw_iceoryx2_busy", 1000)
                .param("bytes", 1 << 20)
                .is_baseline(),
        );
        let measured = busy_call(&mut sut, None);
        assert!(measured.ends_with("not measured at 1 MiB"), "{measured}");
    }

    #[test]
    fn absolute_targets_match_params_loosely_and_report_the_overshoot() {
        let mut sut = Report::default();
        sut.push(
            Row::single("grid.tick_error", 117_000)
                .param("fifo", "true")
                .param("hogs", 0)
                .param("rate_hz", 1000)
                .is_baseline(),
        );
        sut.push(
            Row::single("scale.shm_bytes", 14 << 20)
                .param("modules", 254)
                .unit("bytes")
                .is_baseline(),
        );
        evaluate(&mut sut, &[]);
        let tick = find(&sut, "grid tick error at 1 kHz with SCHED_FIFO");
        assert_eq!(tick.met, Some(false));
        assert_eq!(tick.measured, "p99 117.00 µs (17 % over)");
        let shm = find(&sut, "254 modules: /dev/shm");
        assert_eq!(shm.met, Some(true));
        assert_eq!(shm.measured, "14.0 MiB");
    }

    #[test]
    fn the_snapshot_and_scale_ratios_compare_two_rows_of_one_name() {
        let mut sut = Report::default();
        for (b, v) in [(8u64, 1000u64), (1 << 20, 1400)] {
            sut.push(
                Row::single("snapshots.modbot", v)
                    .param("bytes", b)
                    .is_baseline(),
            );
        }
        for (m, v) in [(2u64, 2000u64), (64, 2500), (253, 3000)] {
            sut.push(
                Row::single("scale.call", v)
                    .param("modules", m)
                    .param("mode", "busy")
                    .is_baseline(),
            );
        }
        evaluate(&mut sut, &[]);
        assert_eq!(find(&sut, "1 MiB snapshot").met, Some(true));
        let call = find(&sut, "254 modules: call round trip");
        assert_eq!(call.met, Some(false));
        assert_eq!(
            call.measured,
            "1.50× (25 % over) (3.00 µs at 253, 2.00 µs at 2)"
        );
    }

    #[test]
    fn a_scale_run_that_stopped_early_names_its_largest_system() {
        let mut sut = Report::default();
        for m in [2u64, 16] {
            sut.push(
                Row::single("scale.startup", 1_000_000_000)
                    .param("modules", m)
                    .is_baseline(),
            );
        }
        assert_eq!(
            evaluated(&mut sut, "254 modules: start-up", None),
            "no scale.startup row at 253 or 254 modules in this run (largest: 16)"
        );
    }

    #[test]
    fn a_full_system_of_253_modules_counts_for_the_254_target() {
        let mut sut = Report::default();
        sut.push(
            Row::single("scale.startup", 2_500_000_000)
                .param("modules", 253)
                .is_baseline(),
        );
        assert_eq!(
            evaluated(&mut sut, "254 modules: start-up", Some(true)),
            "2.50 s (at 253 modules)"
        );
    }
}

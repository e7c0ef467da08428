//! The soak's targets from the issue: no call lost, none duplicated, Rss over the last half
//! grows by 5 % at most, no file left after the stop, no motion reported ok across a stop of
//! the robot.

use modbot_bench_kit::report::{Report, Target};
use modbot_bench_kit::targets::{absolute, ratio_text, rows_with, target};

/// The soak's targets, checked against the `soak.*` rows of `report`.
pub fn targets(report: &Report) -> Vec<Target> {
    let zero = |measure: &str, name: &str| {
        absolute(report, measure, "0", (name, &[]), |r| r.p50_ns, "", 0)
    };
    vec![
        zero(
            "soak: calls lost (acknowledged, never executed)",
            "soak.calls_lost",
        ),
        zero(
            "soak: calls executed more than once",
            "soak.calls_duplicated",
        ),
        growth(report),
        zero(
            "soak: files of the domain left after the stop",
            "soak.files_left",
        ),
        zero(
            "soak: motions reported ok across a stop of the robot",
            "soak.motions_false_ok",
        ),
    ]
}

/// Rss at the end over Rss at the middle, of the processes that lived through the second half.
fn growth(report: &Report) -> Target {
    let (measure, goal) = (
        "soak: Rss growth over the last half",
        "≤ 5 % (processes alive through it)",
    );
    let first = |name: &str| rows_with(report, name, &[]).first().map(|r| r.p50_ns);
    match (first("soak.rss_mid"), first("soak.rss_end")) {
        (Some(mid), Some(end)) => {
            let ratio = end as f64 / mid.max(1) as f64;
            target(
                measure,
                goal,
                format!(
                    "{:+.1} % ({})",
                    (ratio - 1.0) * 100.0,
                    ratio_text(ratio, 1.05)
                ),
                Some(ratio <= 1.05),
            )
        }
        _ => target(
            measure,
            goal,
            "no soak.rss_mid and soak.rss_end rows in this run".to_owned(),
            None,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_bench_kit::report::Row;

    #[test]
    fn a_lost_call_misses_its_target_and_a_small_growth_and_no_false_ok_meet_theirs() {
        let mut r = Report::default();
        r.push(Row::single("soak.calls_lost", 1).unit("count"));
        r.push(Row::single("soak.calls_duplicated", 0).unit("count"));
        r.push(Row::single("soak.rss_mid", 100 << 20).unit("bytes"));
        r.push(Row::single("soak.rss_end", 103 << 20).unit("bytes"));
        r.push(Row::single("soak.motions_false_ok", 0).unit("count"));
        let sut = targets(&r);
        assert_eq!(sut[0].met, Some(false));
        assert_eq!(sut[1].met, Some(true));
        assert_eq!(sut[2].met, Some(true), "{}", sut[2].measured);
        assert!(sut[2].measured.starts_with("+3.0 %"), "{}", sut[2].measured);
        assert_eq!(sut[3].met, None);
        assert_eq!(sut[4].met, Some(true));
    }
}

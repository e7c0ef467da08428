//! The benchmark report: one row per measurement, each with the baseline it is compared with,
//! written as `report.json` (machine-readable) and `report.md` (for people).
//!
//! A row's `baseline` names another row of the same run; its `ratio` is this row's p50 divided
//! by the baseline's p50 (or, for rows marked [`Row::ratio_on`], another percentile). A row that
//! is itself a baseline has ratio 1. Targets from the issue are checked in [`Target`] and the
//! report says by how much a missed one is missed.

use std::collections::BTreeMap;
use std::path::Path;

use hdrhistogram::Histogram;
use serde::Serialize;

/// One measurement.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Which benchmark and path: `call.busy`, `raw_iceoryx2.busy`, `uds.blocking`, ...
    pub name: String,
    /// What was varied: payload bytes, module count, scheduling, ...
    pub params: BTreeMap<String, serde_json::Value>,
    /// How many samples.
    pub n: u64,
    pub p50_ns: u64,
    pub p99_ns: u64,
    pub p999_ns: u64,
    pub max_ns: u64,
    /// The name and params of the row this one is compared with (a row of the same run).
    pub baseline: Option<BaselineRef>,
    /// This row's p50 over the baseline's p50 (filled in by [`Report::resolve`]); for a row
    /// measured interleaved with its baseline, the median of the blocks' ratios.
    pub ratio: Option<f64>,
    /// Measured interleaved with its baseline: the ratios of the blocks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blocks: Option<crate::interleave::Blocks>,
    /// The unit of the four values when they are not nanoseconds ("bytes", "count").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<&'static str>,
}

/// Points at a row of the same run.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BaselineRef {
    pub name: String,
    pub params: BTreeMap<String, serde_json::Value>,
}

impl Row {
    /// A row from a histogram of nanoseconds.
    pub fn from_histogram(name: &str, h: &Histogram<u64>) -> Row {
        Row {
            name: name.to_owned(),
            params: BTreeMap::new(),
            n: h.len(),
            p50_ns: h.value_at_quantile(0.5),
            p99_ns: h.value_at_quantile(0.99),
            p999_ns: h.value_at_quantile(0.999),
            max_ns: h.max(),
            baseline: None,
            ratio: None,
            blocks: None,
            unit: None,
        }
    }

    /// A row of one value (a startup time, a byte count): every percentile is that value.
    pub fn single(name: &str, value: u64) -> Row {
        Row {
            name: name.to_owned(),
            params: BTreeMap::new(),
            n: 1,
            p50_ns: value,
            p99_ns: value,
            p999_ns: value,
            max_ns: value,
            baseline: None,
            ratio: None,
            blocks: None,
            unit: None,
        }
    }

    /// Adds a parameter.
    pub fn param(mut self, key: &str, value: impl Into<serde_json::Value>) -> Row {
        self.params.insert(key.to_owned(), value.into());
        self
    }

    /// Compares this row with the row `name` of the same params (plus `extra` overrides).
    pub fn against(mut self, name: &str, params: &[(&str, serde_json::Value)]) -> Row {
        let mut p = self.params.clone();
        for (k, v) in params {
            p.insert((*k).to_owned(), v.clone());
        }
        self.baseline = Some(BaselineRef {
            name: name.to_owned(),
            params: p,
        });
        self
    }

    /// The row was measured interleaved with its baseline: its ratio is the blocks' median.
    pub fn blocks(mut self, blocks: Option<crate::interleave::Blocks>) -> Row {
        self.blocks = blocks;
        self
    }

    /// Marks the row as its own baseline (ratio 1).
    // A builder step named as the report reads ("this row is a baseline"), not a predicate.
    #[allow(clippy::wrong_self_convention)]
    pub fn is_baseline(mut self) -> Row {
        self.baseline = Some(BaselineRef {
            name: self.name.clone(),
            params: self.params.clone(),
        });
        self
    }

    /// The values are in `unit`, not nanoseconds.
    pub fn unit(mut self, unit: &'static str) -> Row {
        self.unit = Some(unit);
        self
    }

    fn key(&self) -> BaselineRef {
        BaselineRef {
            name: self.name.clone(),
            params: self.params.clone(),
        }
    }
}

/// A target from the issue, checked against the report.
#[derive(Debug, Clone, Serialize)]
pub struct Target {
    /// What is measured, as the issue says it.
    pub measure: String,
    /// The target, as the issue says it.
    pub target: String,
    /// What this run measured.
    pub measured: String,
    /// Met or not; `None` when this run could not measure it.
    pub met: Option<bool>,
}

/// Everything one run measured.
#[derive(Debug, Default, Serialize)]
pub struct Report {
    /// When and where the run was made.
    pub date: String,
    pub machine: String,
    /// The options of the run (quick, pinning, SCHED_FIFO).
    pub options: BTreeMap<String, serde_json::Value>,
    pub rows: Vec<Row>,
    pub targets: Vec<Target>,
    /// Free-text remarks: what could not be measured and why, settings that matter.
    pub notes: Vec<String>,
    /// Distributions to plot, by name: (bucket lower edge in ns, count) pairs, ascending.
    pub histograms: BTreeMap<String, Vec<(u64, u64)>>,
}

impl Report {
    pub fn push(&mut self, row: Row) {
        self.rows.push(row);
    }

    pub fn note(&mut self, text: impl Into<String>) {
        self.notes.push(text.into());
    }

    /// Removes the rows whose baseline is not in the report (its measurement failed), each
    /// with a note: what stays can be resolved. Returns how many went.
    pub fn drop_rows_without_baseline(&mut self) -> usize {
        let keys: Vec<BaselineRef> = self.rows.iter().map(Row::key).collect();
        let (keep, gone): (Vec<Row>, Vec<Row>) = std::mem::take(&mut self.rows)
            .into_iter()
            .partition(|r| r.baseline.as_ref().is_some_and(|b| keys.contains(b)));
        self.rows = keep;
        for r in &gone {
            let why = match &r.baseline {
                Some(b) => format!(
                    "its baseline {} {} was not measured",
                    b.name,
                    params_text(&b.params)
                ),
                None => "it names no baseline".to_owned(),
            };
            self.notes.push(format!(
                "row {} {} left out of the report: {why}",
                r.name,
                params_text(&r.params)
            ));
        }
        gone.len()
    }

    /// Fills in every row's ratio from its baseline. A row whose baseline is not in the report
    /// is an error of the harness: every row must have its baseline from the same run.
    pub fn resolve(&mut self) -> anyhow::Result<()> {
        let index: Vec<(BaselineRef, u64)> =
            self.rows.iter().map(|r| (r.key(), r.p50_ns)).collect();
        for row in &mut self.rows {
            let Some(b) = &row.baseline else {
                anyhow::bail!("row {} {:?} has no baseline", row.name, row.params);
            };
            let Some((_, base)) = index.iter().find(|(k, _)| k == b) else {
                anyhow::bail!(
                    "row {} {:?}: its baseline {} {:?} is not in this run",
                    row.name,
                    row.params,
                    b.name,
                    b.params
                );
            };
            row.ratio = if let Some(blocks) = row.blocks {
                Some(blocks.median)
            } else if *b == row.key() || row.p50_ns == *base {
                Some(1.0)
            } else if *base == 0 {
                // Undefined against a zero baseline: left empty rather than made up.
                None
            } else {
                Some(row.p50_ns as f64 / *base as f64)
            };
        }
        Ok(())
    }

    /// Writes `report.json` and `report.md` into `dir`.
    pub fn write(&self, dir: &Path) -> anyhow::Result<()> {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join("report.json"), serde_json::to_string_pretty(self)?)?;
        std::fs::write(dir.join("report.md"), self.markdown())?;
        Ok(())
    }

    /// The report for people: targets first, then every row grouped by benchmark.
    pub fn markdown(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "# modbot benchmark report\n");
        let _ = writeln!(s, "Measured {} on {}.\n", self.date, self.machine);
        if !self.options.is_empty() {
            let opts: Vec<String> = self
                .options
                .iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            let _ = writeln!(s, "Options: {}.\n", opts.join(", "));
        }
        if !self.targets.is_empty() {
            let _ = writeln!(s, "## Targets\n");
            let _ = writeln!(s, "| measure | target | measured | met |");
            let _ = writeln!(s, "|---|---|---|---|");
            for t in &self.targets {
                let met = match t.met {
                    Some(true) => "yes",
                    Some(false) => "**no**",
                    None => "not measured",
                };
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {met} |",
                    t.measure, t.target, t.measured
                );
            }
            let _ = writeln!(s);
        }
        let mut groups: Vec<&str> = Vec::new();
        for r in &self.rows {
            let g = r.name.split('.').next().unwrap_or(&r.name);
            if !groups.contains(&g) {
                groups.push(g);
            }
        }
        for g in groups {
            let _ = writeln!(s, "## {g}\n");
            let _ = writeln!(
                s,
                "| row | params | n | p50 | p99 | p99.9 | max | baseline | ratio |"
            );
            let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
            // Rows of one name together (in the order names first appear), each name's rows
            // in the order they were measured.
            let mut rows: Vec<&Row> = self
                .rows
                .iter()
                .filter(|r| r.name.split('.').next() == Some(g))
                .collect();
            let first = |name: &str| self.rows.iter().position(|r| r.name == name);
            rows.sort_by_key(|r| first(&r.name));
            for r in rows {
                let fmt = |v: u64| format_value(v, r.unit);
                let base = r
                    .baseline
                    .as_ref()
                    .map(|b| {
                        if b.name == r.name && b.params == r.params {
                            "itself".to_owned()
                        } else if b.params == r.params {
                            b.name.clone()
                        } else {
                            format!("{} {}", b.name, params_text(&b.params))
                        }
                    })
                    .unwrap_or_default();
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    r.name,
                    params_text(&r.params),
                    r.n,
                    fmt(r.p50_ns),
                    fmt(r.p99_ns),
                    fmt(r.p999_ns),
                    fmt(r.max_ns),
                    base,
                    ratio_text(r)
                );
            }
            let _ = writeln!(s);
        }
        if !self.notes.is_empty() {
            let _ = writeln!(s, "## Notes\n");
            for n in &self.notes {
                let _ = writeln!(s, "- {n}");
            }
        }
        s
    }
}

/// The ratio cell: the ratio, and for an interleaved row the range over its blocks.
fn ratio_text(r: &Row) -> String {
    match (r.ratio, r.blocks) {
        (None, _) => "–".to_owned(),
        (Some(x), None) => format!("{x:.2}"),
        (Some(x), Some(b)) => format!("{x:.2} ({:.2}–{:.2}, {} blocks)", b.min, b.max, b.count),
    }
}

/// `bytes=8 fifo=true`, for notes and tables.
pub fn params_text(params: &BTreeMap<String, serde_json::Value>) -> String {
    params
        .iter()
        .map(|(k, v)| match v {
            serde_json::Value::String(s) => format!("{k}={s}"),
            other => format!("{k}={other}"),
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// A value for the markdown table: nanoseconds as µs, ms or s, bytes as KiB or MiB.
pub fn format_value(v: u64, unit: Option<&str>) -> String {
    match unit {
        Some("bytes") if v >= 1 << 20 => format!("{:.1} MiB", v as f64 / (1u64 << 20) as f64),
        Some("bytes") if v >= 1 << 10 => format!("{:.1} KiB", v as f64 / 1024.0),
        Some("bytes") => format!("{v} B"),
        Some("count") => v.to_string(),
        Some(u) => format!("{v} {u}"),
        None if v >= 1_000_000_000 => format!("{:.2} s", v as f64 / 1e9),
        None if v >= 10_000_000 => format!("{:.1} ms", v as f64 / 1e6),
        None => format!("{:.2} µs", v as f64 / 1e3),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row of one value with one parameter, its own baseline.
    fn base(name: &str, value: u64, (key, v): (&str, u64)) -> Row {
        Row::single(name, value).param(key, v).is_baseline()
    }

    /// A row of one value with one parameter, compared with the row `baseline` of that
    /// parameter.
    fn against(name: &str, value: u64, (key, v): (&str, u64), baseline: &str) -> Row {
        Row::single(name, value)
            .param(key, v)
            .against(baseline, &[])
    }

    #[test]
    fn a_row_gets_the_ratio_of_its_p50_to_its_baselines() {
        let mut r = Report::default();
        r.push(base("raw.busy", 1000, ("bytes", 8)));
        r.push(against("call.busy", 1300, ("bytes", 8), "raw.busy"));
        r.resolve().unwrap();
        assert_eq!(r.rows[1].ratio, Some(1.3));
        assert_eq!(r.rows[0].ratio, Some(1.0));
    }

    #[test]
    fn rows_whose_baseline_failed_are_left_out_with_a_note() {
        let mut r = Report::default();
        r.push(base("raw.busy", 1000, ("bytes", 8)));
        r.push(against("call.busy", 1300, ("bytes", 8), "raw.busy"));
        r.push(against("call.busy", 1300, ("bytes", 64), "raw.busy"));
        assert_eq!(r.drop_rows_without_baseline(), 1);
        assert_eq!(r.rows.len(), 2);
        assert!(r.notes[0].contains("call.busy bytes=64"), "{}", r.notes[0]);
        r.resolve().unwrap();
    }

    #[test]
    fn the_markdown_holds_every_row_and_every_target() {
        let mut r = Report {
            date: "2026-11-22".into(),
            machine: "test machine".into(),
            ..Report::default()
        };
        r.push(base("calls.raw", 900, ("bytes", 8)));
        r.push(against("calls.modbot", 1300, ("bytes", 8), "calls.raw"));
        r.push(base("scale.call", 2000, ("modules", 2)));
        r.push(
            Row::single("scale.call", 2400)
                .param("modules", 254)
                .against("scale.call", &[("modules", 2.into())]),
        );
        r.push(
            Row::single("scale.shm_bytes", 14 << 20)
                .param("modules", 254)
                .unit("bytes")
                .is_baseline(),
        );
        r.resolve().unwrap();
        r.targets.push(Target {
            measure: "busy call".into(),
            target: "p50 ≤ 1.3× raw".into(),
            measured: "1.44× (11 % over)".into(),
            met: Some(false),
        });
        r.note("a remark");
        let md = r.markdown();
        assert!(md.contains("Measured 2026-11-22 on test machine."));
        assert!(md.contains("| busy call | p50 ≤ 1.3× raw | 1.44× (11 % over) | **no** |"));
        assert!(md.contains("| calls.modbot | bytes=8 | 1 | 1.30 µs | 1.30 µs | 1.30 µs | 1.30 µs | calls.raw | 1.44 |"), "{md}");
        assert!(md.contains("| scale.call | modules=254 | 1 | 2.40 µs |"));
        assert!(md.contains("| scale.call modules=2 | 1.20 |"), "{md}");
        assert!(md.contains("| scale.shm_bytes | modules=254 | 1 | 14.0 MiB |"));
        assert!(md.contains("- a remark"));
        for row in &r.rows {
            assert!(md.contains(&format!("| {} | {} |", row.name, params_text(&row.params))));
        }
    }

    #[test]
    fn the_markdown_keeps_the_rows_of_one_name_together() {
        let mut r = Report::default();
        for (name, bytes) in [
            ("calls.a", 8),
            ("calls.b", 8),
            ("calls.a", 64),
            ("calls.b", 64),
        ] {
            r.push(base(name, 1, ("bytes", bytes)));
        }
        let md = r.markdown();
        let at = |text: &str| md.find(text).unwrap();
        assert!(at("| calls.a | bytes=64 |") < at("| calls.b | bytes=8 |"));
        assert!(at("| calls.b | bytes=8 |") < at("| calls.b | bytes=64 |"));
    }

    #[test]
    fn values_are_formatted_in_their_unit() {
        assert_eq!(format_value(950, None), "0.95 µs");
        assert_eq!(format_value(123_456, None), "123.46 µs");
        assert_eq!(format_value(25_000_000, None), "25.0 ms");
        assert_eq!(format_value(2_500_000_000, None), "2.50 s");
        assert_eq!(format_value(512, Some("bytes")), "512 B");
        assert_eq!(format_value(4096, Some("bytes")), "4.0 KiB");
        assert_eq!(format_value(3 << 20, Some("bytes")), "3.0 MiB");
        assert_eq!(format_value(7, Some("count")), "7");
        assert_eq!(format_value(3, Some("ticks")), "3 ticks");
    }

    #[test]
    fn a_zero_row_is_its_own_baseline_with_ratio_1_and_a_zero_baseline_gives_none() {
        let mut r = Report::default();
        r.push(Row::single("swaps.tick_error", 0).is_baseline());
        r.push(Row::single("x.idle", 0).is_baseline());
        r.push(Row::single("x.busy", 5).against("x.idle", &[]));
        r.resolve().unwrap();
        assert_eq!(r.rows[0].ratio, Some(1.0));
        assert_eq!(r.rows[2].ratio, None);
        assert!(r.markdown().contains("| x.idle | – |"));
    }

    #[test]
    fn a_row_whose_baseline_is_missing_is_refused() {
        let mut r = Report::default();
        r.push(against("call.busy", 1300, ("bytes", 8), "raw.busy"));
        assert!(r.resolve().is_err());
    }
}

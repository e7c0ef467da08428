//! The report's plots, as SVG (plotters, no system fonts needed):
//! - `latency_vs_payload.svg`: p50 (solid) and p99 (dashed) of every `calls.*` and
//!   `snapshots.*` row against its `bytes`, log-log;
//! - `latency_vs_modules.svg`: p50 and p99 of the `scale.call` rows against `modules`;
//! - `tick_error_histogram.svg`: the `grid.tick_error*` distributions of
//!   [`Report::histograms`].
//!
//! A plot without data is skipped, and the report says so.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crate::report::Report;

/// One line of a plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub label: String,
    /// (x, y) points, ascending x.
    pub points: Vec<(f64, f64)>,
    pub dashed: bool,
    /// Lines of one row share a colour.
    pub color: usize,
}

/// Draws one plot into a file.
type DrawFn<'a> = Box<dyn Fn(&Path) -> anyhow::Result<()> + 'a>;

/// Draws every plot that has data into `dir`; notes the ones skipped. Returns the files.
pub fn write_all(report: &mut Report, dir: &Path) -> Vec<PathBuf> {
    let mut written = Vec::new();
    let mut notes = Vec::new();
    let payload = payload_series(report);
    let modules = module_series(report);
    let histograms: Vec<(String, Vec<(u64, u64)>)> = report
        .histograms
        .iter()
        .filter(|(k, v)| k.starts_with("grid.tick_error") && !v.is_empty())
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let jobs: [(&str, bool, DrawFn<'_>); 3] = [
        (
            "latency_vs_payload.svg",
            !payload.is_empty(),
            Box::new(|p| {
                lines(
                    p,
                    "Round trip / delivery latency against payload",
                    ("payload (bytes)", "latency (µs)"),
                    true,
                    &payload,
                )
            }),
        ),
        (
            "latency_vs_modules.svg",
            !modules.is_empty(),
            Box::new(|p| {
                lines(
                    p,
                    "Call round trip against module count",
                    ("modules", "round trip (µs)"),
                    true,
                    &modules,
                )
            }),
        ),
        (
            "tick_error_histogram.svg",
            !histograms.is_empty(),
            Box::new(|p| tick_histogram(p, &histograms)),
        ),
    ];
    for (file, has_data, draw) in jobs {
        let path = dir.join(file);
        if !has_data {
            notes.push(format!("plot {file} skipped: no data in this run"));
            continue;
        }
        match draw(&path) {
            Ok(()) => written.push(path),
            Err(e) => notes.push(format!("plot {file} failed: {e:#}")),
        }
    }
    for n in notes {
        report.note(n);
    }
    written
}

/// p50 and p99 (µs) of every `calls.*`/`snapshots.*` row name, against `bytes`.
pub fn payload_series(report: &Report) -> Vec<Series> {
    series_by(
        report,
        |name| name.starts_with("calls.") || name.starts_with("snapshots."),
        "bytes",
    )
}

/// p50 and p99 (µs) of the `scale.call` rows, against `modules`.
pub fn module_series(report: &Report) -> Vec<Series> {
    series_by(report, |name| name == "scale.call", "modules")
}

fn series_by(report: &Report, pick: impl Fn(&str) -> bool, x: &str) -> Vec<Series> {
    // Rows with other params besides `x` (e.g. fifo) are separate lines.
    let mut groups: BTreeMap<String, Vec<(f64, f64, f64)>> = BTreeMap::new();
    let mut order: Vec<String> = Vec::new();
    for r in report
        .rows
        .iter()
        .filter(|r| pick(&r.name) && r.unit.is_none())
    {
        let Some(xv) = r.params.get(x).and_then(serde_json::Value::as_f64) else {
            continue;
        };
        if xv <= 0.0 {
            continue;
        }
        let extra: Vec<String> = r
            .params
            .iter()
            .filter(|(k, _)| k.as_str() != x)
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        let label = if extra.is_empty() {
            r.name.clone()
        } else {
            format!("{} {}", r.name, extra.join(" "))
        };
        if !order.contains(&label) {
            order.push(label.clone());
        }
        groups.entry(label).or_default().push((
            xv,
            r.p50_ns.max(1) as f64 / 1e3,
            r.p99_ns.max(1) as f64 / 1e3,
        ));
    }
    let mut out = Vec::new();
    for (color, label) in order.iter().enumerate() {
        let mut pts = groups.remove(label).unwrap_or_default();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        out.push(Series {
            label: format!("{label} p50"),
            points: pts.iter().map(|p| (p.0, p.1)).collect(),
            dashed: false,
            color,
        });
        out.push(Series {
            label: format!("{label} p99"),
            points: pts.iter().map(|p| (p.0, p.2)).collect(),
            dashed: true,
            color,
        });
    }
    out
}

fn err(e: impl std::fmt::Debug) -> anyhow::Error {
    anyhow::anyhow!("{e:?}")
}

/// The range of `v` (all > 0) widened by a factor on each side, for a log axis.
fn log_range(v: impl Iterator<Item = f64>, widen: f64) -> std::ops::Range<f64> {
    let (lo, hi) = v.fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)));
    if lo > hi {
        return 1.0..10.0;
    }
    let (lo, hi) = (lo / widen, hi * widen);
    if hi <= lo {
        lo..lo * 10.0
    } else {
        lo..hi
    }
}

fn color(i: usize) -> RGBColor {
    let c = Palette99::pick(i).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

/// Room right of a line plot for its legend, in pixels.
const LEGEND_WIDTH: u32 = 300;

/// A log-y line plot (log-x too when `log_x`).
fn lines(
    path: &Path,
    title: &str,
    (x_desc, y_desc): (&str, &str),
    log_x: bool,
    series: &[Series],
) -> anyhow::Result<()> {
    let all = || series.iter().flat_map(|s| s.points.iter());
    let xr = log_range(all().map(|p| p.0), if log_x { 1.5 } else { 1.0 });
    let yr = log_range(all().map(|p| p.1), 2.0);
    let root = SVGBackend::new(path, (1300, 720)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        // The legend goes to the right of the plot, where it hides no line.
        .margin_right(LEGEND_WIDTH)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(xr.log_scale(), yr.log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&|x| short(*x))
        .y_label_formatter(&|y| short(*y))
        .draw()
        .map_err(err)?;
    for s in series {
        let c = color(s.color);
        if s.dashed {
            chart
                .draw_series(DashedLineSeries::new(
                    s.points.iter().copied(),
                    6,
                    4,
                    c.stroke_width(1),
                ))
                .map_err(err)?;
        } else {
            chart
                .draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(2)))
                .map_err(err)?;
        }
        chart
            .draw_series(s.points.iter().map(|&p| Circle::new(p, 3, c.filled())))
            .map_err(err)?;
    }
    // Drawn on the whole canvas: plotters' own legend is clipped to the plotting area.
    let (width, _) = root.dim_in_pixel();
    let x = i32::try_from(width.saturating_sub(LEGEND_WIDTH)).unwrap_or(0) + 10;
    for (i, s) in series.iter().enumerate() {
        let y = 50 + 18 * i32::try_from(i).unwrap_or(0);
        let c = color(s.color);
        if s.dashed {
            for k in 0..3 {
                root.draw(&PathElement::new(
                    vec![(x + 8 * k, y), (x + 8 * k + 5, y)],
                    c.stroke_width(1),
                ))
                .map_err(err)?;
            }
        } else {
            root.draw(&PathElement::new(
                vec![(x, y), (x + 21, y)],
                c.stroke_width(2),
            ))
            .map_err(err)?;
        }
        root.draw(&Text::new(
            s.label.clone(),
            (x + 28, y - 6),
            ("sans-serif", 12).into_font(),
        ))
        .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// Axis labels, decimal as the log axes' ticks are: 8, 100, 10k, 1M, 0.5.
pub fn short(v: f64) -> String {
    let (v, suffix) = if v >= 1e6 {
        (v / 1e6, "M")
    } else if v >= 1e3 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    if v >= 10.0 || (v.fract()).abs() < 1e-9 {
        format!("{v:.0}{suffix}")
    } else {
        format!("{v:.1}{suffix}")
    }
}

/// The tick-error distributions, one translucent set of bars each.
fn tick_histogram(path: &Path, hists: &[(String, Vec<(u64, u64)>)]) -> anyhow::Result<()> {
    let to_us = |ns: u64| ns as f64 / 1e3;
    let mut bars: Vec<(usize, f64, f64, u64)> = Vec::new();
    for (i, (_, h)) in hists.iter().enumerate() {
        for (j, &(edge, count)) in h.iter().enumerate() {
            let next = h.get(j + 1).map(|n| n.0).unwrap_or_else(|| {
                let width = if j > 0 { edge - h[j - 1].0 } else { 1000 };
                edge + width.max(1)
            });
            bars.push((i, to_us(edge), to_us(next.max(edge + 1)), count));
        }
    }
    let x_max = bars.iter().map(|b| b.2).fold(1.0, f64::max);
    let x_min = bars.iter().map(|b| b.1).fold(x_max, f64::min);
    let y_max = bars.iter().map(|b| b.3).max().unwrap_or(1).max(1);
    let root = SVGBackend::new(path, (1100, 620)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption("Grid tick error", ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x_min..x_max, 0u64..y_max + y_max / 10 + 1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("tick error (µs)")
        .y_desc("ticks")
        .draw()
        .map_err(err)?;
    for (i, (name, _)) in hists.iter().enumerate() {
        let c = color(i);
        chart
            .draw_series(
                bars.iter()
                    .filter(|b| b.0 == i)
                    .map(|b| Rectangle::new([(b.1, 0), (b.2, b.3)], c.mix(0.45).filled())),
            )
            .map_err(err)?
            .label(name)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], c.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::Row;

    #[test]
    fn payload_series_pair_p50_and_p99_per_row_name_in_ascending_bytes() {
        let mut r = Report::default();
        for b in [4096u64, 8] {
            r.push(Row::single("calls.uds_blocking", b * 10).param("bytes", b));
        }
        r.push(Row::single("grid.tick_error", 5).param("fifo", true));
        let s = payload_series(&r);
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].label, "calls.uds_blocking p50");
        assert_eq!(s[0].points, vec![(8.0, 0.08), (4096.0, 40.96)]);
        assert!(s[1].dashed);
    }

    #[test]
    fn plots_without_data_are_skipped_with_a_note() {
        let mut r = Report::default();
        let dir = std::env::temp_dir().join(format!("bench_plots_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let written = write_all(&mut r, &dir);
        let _ = std::fs::remove_dir_all(&dir);
        assert!(written.is_empty());
        assert_eq!(r.notes.len(), 3);
        assert!(r.notes[0].contains("latency_vs_payload.svg skipped"));
    }

    #[test]
    fn plots_with_data_are_written_as_svg() {
        let mut r = Report::default();
        for b in [8u64, 4096, 1 << 20] {
            r.push(Row::single("calls.uds_blocking", b * 10).param("bytes", b));
        }
        for m in [2u64, 254] {
            r.push(Row::single("scale.call", 2000 * m).param("modules", m));
        }
        r.histograms.insert(
            "grid.tick_error.fifo".into(),
            vec![(0, 5), (1000, 20), (2000, 3)],
        );
        let dir = std::env::temp_dir().join(format!("bench_plots_svg_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let written = write_all(&mut r, &dir);
        let texts: Vec<String> = written
            .iter()
            .map(|p| std::fs::read_to_string(p).unwrap_or_default())
            .collect();
        let _ = std::fs::remove_dir_all(&dir);
        assert!(r.notes.is_empty(), "{:?}", r.notes);
        assert_eq!(written.len(), 3);
        assert!(texts.iter().all(|t| t.starts_with("<svg")));
        assert!(texts[0].contains("calls.uds_blocking p50"));
    }

    #[test]
    fn axis_labels_are_short() {
        assert_eq!(short(8.0), "8");
        assert_eq!(short(10_000.0), "10k");
        assert_eq!(short(1e6), "1M");
        assert_eq!(short(1_048_576.0), "1.0M");
        assert_eq!(short(0.5), "0.5");
    }
}

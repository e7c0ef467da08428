//! A line plot of a program's series, as SVG (plotters): what `plot { ... }` writes.

use std::path::Path;

use plotters::prelude::*;

use super::ScriptError;

/// One line: its name in the legend and its points.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// The plot's texts.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Labels {
    pub title: String,
    pub x: String,
    pub y: String,
}

/// `lo..hi` of `values` with a margin, never empty.
fn range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return 0.0..1.0;
    }
    let margin = ((hi - lo) * 0.05).max(1e-12);
    (lo - margin)..(hi + margin)
}

/// Writes `lines` to the SVG file at `path`.
pub fn svg(path: &Path, labels: &Labels, lines: &[Line]) -> Result<(), ScriptError> {
    let err = |e: DrawingAreaErrorKind<_>| ScriptError::Plot {
        path: path.to_path_buf(),
        why: e.to_string(),
    };
    let all = || lines.iter().flat_map(|l| l.points.iter());
    let (xr, yr) = (range(all().map(|p| p.0)), range(all().map(|p| p.1)));
    let root = SVGBackend::new(path, (1000, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(&labels.title, ("sans-serif", 22))
        .margin(14)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(xr, yr)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(labels.x.as_str())
        .y_desc(labels.y.as_str())
        .draw()
        .map_err(err)?;
    for (i, line) in lines.iter().enumerate() {
        let c = Palette99::pick(i).to_rgba();
        let color = RGBColor(c.0, c.1, c.2);
        chart
            .draw_series(LineSeries::new(
                line.points.iter().copied(),
                color.stroke_width(2),
            ))
            .map_err(err)?
            .label(line.name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_lines_make_an_svg_with_two_polylines_and_their_names() {
        let path = std::env::temp_dir().join(format!("modbot-plot-{}.svg", std::process::id()));
        let line = |name: &str, k: f64| Line {
            name: name.into(),
            points: (0..50)
                .map(|i| (i as f64 * 0.01, k * (i as f64 * 0.3).sin()))
                .collect(),
        };
        let labels = Labels {
            title: "residuals".into(),
            x: "s".into(),
            y: "mrad".into(),
        };
        svg(&path, &labels, &[line("rigid", 4.0), line("elastic", 0.2)]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let _ = std::fs::remove_file(&path);
        assert!(text.starts_with("<svg"), "{}", &text[..40.min(text.len())]);
        assert_eq!(long_polylines(&text), 2, "two lines of 50 points");
        assert!(
            text.contains("rigid") && text.contains("elastic"),
            "the legend"
        );
    }

    /// The polylines of `svg` with 10 points or more (the axes and legend marks have fewer).
    pub(crate) fn long_polylines(svg: &str) -> usize {
        svg.split("<polyline")
            .skip(1)
            .filter_map(|e| e.split("points=\"").nth(1)?.split('"').next())
            .filter(|points| points.split_whitespace().count() >= 10)
            .count()
    }
}

//! What every chart shares: a figure of stacked panels drawn as SVG with plotters, and the CSV
//! file of the numbers behind it.
//!
//! Log axes are drawn as linear axes over `log10` of the values, with ranges widened to whole
//! decades so that the tick labels fall on powers of ten. Non-positive or non-finite values on a
//! log axis, and non-finite values anywhere, are left out of the drawing (the CSV keeps them).

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;

/// One axis of a panel.
#[derive(Clone, Debug)]
pub struct Axis {
    /// The axis title, with units.
    pub label: String,
    /// Logarithmic (decades) or linear.
    pub log: bool,
    /// A fixed range in data units; `None` fits the data.
    pub range: Option<(f64, f64)>,
}

impl Axis {
    /// A linear axis fitted to the data.
    pub fn linear(label: &str) -> Axis {
        Axis {
            label: label.to_owned(),
            log: false,
            range: None,
        }
    }

    /// A logarithmic axis fitted to the data.
    pub fn log(label: &str) -> Axis {
        Axis {
            log: true,
            ..Axis::linear(label)
        }
    }

    /// This axis with the fixed range `[lo, hi]` (data units).
    pub fn with_range(self, lo: f64, hi: f64) -> Axis {
        Axis {
            range: Some((lo, hi)),
            ..self
        }
    }

    /// Where `value` goes on the drawing's coordinate (its `log10` on a log axis), if drawable.
    fn to_plot(&self, value: f64) -> Option<f64> {
        let plotted = if self.log { value.log10() } else { value };
        (value.is_finite() && (!self.log || value > 0.0)).then_some(plotted)
    }

    /// The drawing range over the plotted `values`: the fixed range, or the data's with a
    /// margin; whole decades on a log axis.
    fn plot_range(&self, values: impl Iterator<Item = f64>) -> (f64, f64) {
        let (lo, hi) = match self.range {
            Some((lo, hi)) => (
                self.to_plot(lo).unwrap_or(0.0),
                self.to_plot(hi).unwrap_or(1.0),
            ),
            None => {
                let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                });
                if lo > hi {
                    (0.0, 1.0)
                } else if self.log {
                    (lo, hi)
                } else {
                    let margin = 0.05 * (hi - lo).max(1e-12 * hi.abs().max(1.0));
                    (lo - margin, hi + margin)
                }
            }
        };
        if self.log {
            let (lo, hi) = (lo.floor(), hi.ceil());
            (lo, if hi > lo { hi } else { lo + 1.0 })
        } else if hi > lo {
            (lo, hi)
        } else {
            (lo - 0.5, hi + 0.5)
        }
    }

    /// The tick label of plotted coordinate `v`.
    fn tick(&self, v: f64) -> String {
        if self.log {
            let value = 10f64.powf(v);
            if (0.01..10_000.0).contains(&value) {
                format!("{}", round_to_3(value))
            } else {
                format!("1e{:.0}", v)
            }
        } else {
            format!("{}", round_to_3(v))
        }
    }
}

/// `v` rounded to 3 significant digits, for tick labels.
fn round_to_3(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let scale = 10f64.powi(2 - v.abs().log10().floor() as i32);
    (v * scale).round() / scale
}

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// Markers only.
    Points,
    /// A solid line with markers.
    LinePoints,
    /// A solid line.
    Line,
    /// A dashed line (references, bounds, fronts).
    Dashed,
}

/// A named set of points drawn in one colour.
#[derive(Clone, Debug)]
pub struct Series {
    /// The legend entry.
    pub name: String,
    /// `(x, y)` in data units.
    pub points: Vec<(f64, f64)>,
    /// An optional text next to each point (empty: none).
    pub labels: Vec<String>,
    /// How it is drawn.
    pub style: Style,
    /// Index into [`PALETTE`] (wraps).
    pub color: usize,
}

impl Series {
    /// A series of `points` without point labels.
    pub fn new(name: &str, style: Style, color: usize, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.to_owned(),
            points,
            labels: Vec::new(),
            style,
            color,
        }
    }

    /// This series with a label next to each point.
    pub fn with_labels(self, labels: Vec<String>) -> Series {
        Series { labels, ..self }
    }
}

/// Distinguishable colours (Okabe–Ito, readable by colour-blind viewers), then black.
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 120, 120),
    RGBColor(0, 0, 0),
];

/// One chart: axes and series.
#[derive(Clone)]
pub struct Panel {
    /// The panel's caption.
    pub title: String,
    /// The horizontal axis.
    pub x: Axis,
    /// The vertical axis.
    pub y: Axis,
    /// What is drawn, in order (later on top).
    pub series: Vec<Series>,
    /// Where the legend goes.
    pub legend: SeriesLabelPosition,
}

impl Panel {
    /// A panel with the legend in the upper right corner.
    pub fn new(title: &str, x: Axis, y: Axis, series: Vec<Series>) -> Panel {
        Panel {
            title: title.to_owned(),
            x,
            y,
            series,
            legend: SeriesLabelPosition::UpperRight,
        }
    }

    /// This panel with the legend at `legend`.
    pub fn with_legend(self, legend: SeriesLabelPosition) -> Panel {
        Panel { legend, ..self }
    }
}

/// Panels stacked vertically, with one title over them all.
#[derive(Clone)]
pub struct Figure {
    /// The figure's title.
    pub title: String,
    /// The panels, top to bottom.
    pub panels: Vec<Panel>,
}

/// Width of every figure and height of each panel (SVG pixels).
const WIDTH: u32 = 900;
const PANEL_HEIGHT: u32 = 520;
const TITLE_HEIGHT: u32 = 40;

impl Figure {
    /// The figure as an SVG document.
    pub fn to_svg(&self) -> Result<String, String> {
        let mut svg = String::new();
        let height = TITLE_HEIGHT + PANEL_HEIGHT * self.panels.len().max(1) as u32;
        {
            let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
            root.fill(&WHITE).map_err(plot_error)?;
            let root = root
                .titled(&self.title, ("sans-serif", 22))
                .map_err(plot_error)?;
            let areas = root.split_evenly((self.panels.len().max(1), 1));
            for (panel, area) in self.panels.iter().zip(&areas) {
                draw_panel(panel, area)?;
            }
            root.present().map_err(plot_error)?;
        }
        Ok(svg)
    }

    /// Writes the SVG to `path`.
    pub fn write(&self, path: &Path) -> Result<(), String> {
        let svg = self.to_svg()?;
        std::fs::write(path, svg).map_err(|e| format!("cannot write {}: {e}", path.display()))
    }
}

fn plot_error(error: impl std::fmt::Display) -> String {
    format!("drawing the chart: {error}")
}

fn draw_panel(
    panel: &Panel,
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
) -> Result<(), String> {
    let plotted = |axis: &Axis, pick: fn(&(f64, f64)) -> f64| {
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(pick))
            .filter_map(|v| axis.to_plot(v))
            .collect::<Vec<_>>()
    };
    let x_range = panel.x.plot_range(plotted(&panel.x, |p| p.0).into_iter());
    let y_range = panel.y.plot_range(plotted(&panel.y, |p| p.1).into_iter());
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 17))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)
        .map_err(plot_error)?;
    let labels = |axis: &Axis, (lo, hi): (f64, f64)| {
        if axis.log {
            // One label per decade, at most 12.
            ((hi - lo) as usize + 1).min(12)
        } else {
            8
        }
    };
    let x_ticks = |v: &f64| panel.x.tick(*v);
    let y_ticks = |v: &f64| panel.y.tick(*v);
    chart
        .configure_mesh()
        .x_desc(panel.x.label.as_str())
        .y_desc(panel.y.label.as_str())
        .x_labels(labels(&panel.x, x_range))
        .y_labels(labels(&panel.y, y_range))
        .x_label_formatter(&x_ticks)
        .y_label_formatter(&y_ticks)
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(plot_error)?;

    let inside = |(x, y): (f64, f64)| {
        (x_range.0..=x_range.1).contains(&x) && (y_range.0..=y_range.1).contains(&y)
    };
    for series in &panel.series {
        let color = PALETTE[series.color % PALETTE.len()];
        let points: Vec<(f64, f64)> = series
            .points
            .iter()
            .filter_map(|&(x, y)| Some((panel.x.to_plot(x)?, panel.y.to_plot(y)?)))
            .collect();
        let line = color.stroke_width(2);
        let legend_style = match series.style {
            Style::Points => color.filled(),
            _ => line,
        };
        let legend =
            move |(x, y): (i32, i32)| PathElement::new(vec![(x, y), (x + 22, y)], legend_style);
        let markers = points
            .iter()
            .filter(|p| inside(**p))
            .map(|&p| Circle::new(p, 4, color.filled()));
        match series.style {
            Style::Line | Style::LinePoints => {
                chart
                    .draw_series(LineSeries::new(points.clone(), line))
                    .map_err(plot_error)?
                    .label(series.name.as_str())
                    .legend(legend);
                if series.style == Style::LinePoints {
                    chart.draw_series(markers).map_err(plot_error)?;
                }
            }
            Style::Dashed => {
                chart
                    .draw_series(DashedLineSeries::new(points.clone(), 8, 5, line))
                    .map_err(plot_error)?
                    .label(series.name.as_str())
                    .legend(legend);
            }
            Style::Points => {
                chart
                    .draw_series(markers)
                    .map_err(plot_error)?
                    .label(series.name.as_str())
                    .legend(legend);
            }
        }
        if !series.labels.is_empty() {
            let texts = series
                .points
                .iter()
                .zip(&series.labels)
                .filter_map(|(&(x, y), text)| {
                    let p = (panel.x.to_plot(x)?, panel.y.to_plot(y)?);
                    inside(p).then(|| {
                        EmptyElement::at(p)
                            + Text::new(
                                text.clone(),
                                (6, -14),
                                ("sans-serif", 12).into_font().color(&color),
                            )
                    })
                });
            chart.draw_series(texts).map_err(plot_error)?;
        }
    }
    chart
        .configure_series_labels()
        .position(panel.legend.clone())
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(plot_error)?;
    Ok(())
}

/// A CSV table: a header and rows of already formatted cells.
#[derive(Clone, Debug, Default)]
pub struct Table {
    /// Column names.
    pub header: Vec<String>,
    /// One entry per row, as many cells as the header.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// An empty table with the given column names.
    pub fn new(header: &[&str]) -> Table {
        Table {
            header: header.iter().map(|h| (*h).to_owned()).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row (cells formatted by the caller; numbers with `{:e}` or `{}`).
    pub fn push(&mut self, row: Vec<String>) {
        debug_assert_eq!(row.len(), self.header.len());
        self.rows.push(row);
    }

    /// The table as CSV text; cells holding a comma or quote are quoted.
    pub fn to_csv(&self) -> String {
        let cell = |c: &String| {
            if c.contains([',', '"', '\n']) {
                format!("\"{}\"", c.replace('"', "\"\""))
            } else {
                c.clone()
            }
        };
        let mut out = String::new();
        for row in std::iter::once(&self.header).chain(&self.rows) {
            let cells: Vec<String> = row.iter().map(cell).collect();
            let _ = writeln!(out, "{}", cells.join(","));
        }
        out
    }

    /// Writes the CSV to `path`.
    pub fn write(&self, path: &Path) -> Result<(), String> {
        std::fs::write(path, self.to_csv())
            .map_err(|e| format!("cannot write {}: {e}", path.display()))
    }
}

/// A number for a CSV cell: 6 significant digits, `NaN`/`inf` spelled out.
pub fn num(v: f64) -> String {
    format!("{v:.6e}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_axes_round_to_decades_and_skip_what_they_cannot_show() {
        let axis = Axis::log("error");
        assert_eq!(axis.to_plot(1e-3), Some(-3.0));
        assert_eq!(axis.to_plot(0.0), None);
        assert_eq!(axis.to_plot(f64::NAN), None);
        let range = axis.plot_range([-3.2, -1.5].into_iter());
        assert_eq!(range, (-4.0, -1.0));
        assert_eq!(axis.tick(-6.0), "1e-6");
        assert_eq!(axis.tick(2.0), "100");
        let linear = Axis::linear("t").with_range(0.0, 2.0);
        assert_eq!(linear.plot_range([5.0].into_iter()), (0.0, 2.0));
    }

    #[test]
    fn csv_quotes_cells_with_commas() {
        let mut table = Table::new(&["name", "value"]);
        table.push(vec!["a, b".into(), num(0.5)]);
        assert_eq!(table.to_csv(), "name,value\n\"a, b\",5.000000e-1\n");
    }

    #[test]
    fn svg_has_the_title_labels_and_legend_as_text() {
        let figure = Figure {
            title: "Title here".into(),
            panels: vec![Panel::new(
                "panel",
                Axis::log("time (ns)"),
                Axis::linear("error"),
                vec![
                    Series::new(
                        "first",
                        Style::LinePoints,
                        0,
                        vec![(1.0, 0.5), (100.0, 0.25)],
                    )
                    .with_labels(vec!["a".into(), "b".into()]),
                    Series::new("bad", Style::Points, 1, vec![(-1.0, f64::NAN)]),
                ],
            )],
        };
        let svg = figure.to_svg().unwrap();
        // plotters writes each text on a line of its own inside <text>.
        let texts: Vec<&str> = svg.lines().map(str::trim).collect();
        for text in ["Title here", "time (ns)", "error", "first", "a", "100"] {
            assert!(texts.contains(&text), "{text} missing");
        }
    }
}

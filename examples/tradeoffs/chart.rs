//! What every chart shares: a figure of stacked panels drawn as SVG with plotters, and the CSV
//! file of the numbers behind it.
//!
//! Log axes are drawn as linear axes over `log10` of the values, with ranges widened to whole
//! decades so that the tick labels fall on powers of ten. Non-positive or non-finite values on a
//! log axis, and non-finite values anywhere, are left out of the drawing (the CSV keeps them).
//!
//! The legend shows each series as it is drawn (markers, a line, a line with markers, dashes) and
//! goes where it covers the least of the drawing: the panel's preferred corner if that is free,
//! else the freest of the other corners and edges ([`Layout`]). Point labels are placed one by
//! one around their point where they overlap no other label, the legend or a marker (and as few
//! line pixels as possible); labels of points of one series that coincide on the drawing are
//! joined into one (`4, 5, 6`).

use std::fmt::Write as _;
use std::path::Path;

use plotters::coord::CoordTranslate;
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
    /// Where the legend should go if it covers nothing there (else it moves, see [`Layout`]).
    pub legend: SeriesLabelPosition,
}

impl Panel {
    /// A panel with the legend preferably in the upper right corner.
    pub fn new(title: &str, x: Axis, y: Axis, series: Vec<Series>) -> Panel {
        Panel {
            title: title.to_owned(),
            x,
            y,
            series,
            legend: SeriesLabelPosition::UpperRight,
        }
    }

    /// This panel with the legend preferably at `legend`.
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
    // Pixel positions relative to the plotting area, where the legend and the labels are placed.
    let (x_pixels, y_pixels) = chart.plotting_area().get_pixel_range();
    let coordinates = chart.as_coord_spec().clone();
    let to_pixel = |p: (f64, f64)| {
        let (x, y) = coordinates.translate(&p);
        (x - x_pixels.start, y - y_pixels.start)
    };
    let mut layout = Layout::new(x_pixels.len() as i32, y_pixels.len() as i32);
    let mut labels = Vec::new();
    for series in &panel.series {
        let color = PALETTE[series.color % PALETTE.len()];
        let points: Vec<(f64, f64)> = series
            .points
            .iter()
            .filter_map(|&(x, y)| Some((panel.x.to_plot(x)?, panel.y.to_plot(y)?)))
            .collect();
        let has_markers = matches!(series.style, Style::Points | Style::LinePoints);
        let has_line = series.style != Style::Points;
        if has_markers {
            layout.add_markers(points.iter().filter(|p| inside(**p)).map(|&p| to_pixel(p)));
        }
        if has_line {
            let pixels: Vec<(i32, i32)> = points.iter().map(|&p| to_pixel(p)).collect();
            layout.add_line(&pixels);
        }
        let line = color.stroke_width(2);
        let markers = points
            .iter()
            .filter(|p| inside(**p))
            .map(|&p| Circle::new(p, MARKER_RADIUS, color.filled()));
        let name = series.name.as_str();
        match series.style {
            Style::Line => {
                chart
                    .draw_series(LineSeries::new(points.clone(), line))
                    .map_err(plot_error)?
                    .label(name)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + LEGEND_SAMPLE, y)], line)
                    });
            }
            Style::LinePoints => {
                chart
                    .draw_series(LineSeries::new(points.clone(), line))
                    .map_err(plot_error)?
                    .label(name)
                    .legend(move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (LEGEND_SAMPLE, 0)], line)
                            + Circle::new((LEGEND_SAMPLE / 2, 0), MARKER_RADIUS, color.filled())
                    });
                chart.draw_series(markers).map_err(plot_error)?;
            }
            Style::Dashed => {
                // The legend sample has the series' dash and gap: two dashes and a gap.
                chart
                    .draw_series(DashedLineSeries::new(points.clone(), DASH, GAP, line))
                    .map_err(plot_error)?
                    .label(name)
                    .legend(move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (DASH as i32, 0)], line)
                            + PathElement::new(
                                vec![((DASH + GAP) as i32, 0), (LEGEND_SAMPLE, 0)],
                                line,
                            )
                    });
            }
            Style::Points => {
                chart
                    .draw_series(markers)
                    .map_err(plot_error)?
                    .label(name)
                    .legend(move |(x, y)| {
                        Circle::new((x + LEGEND_SAMPLE / 2, y), MARKER_RADIUS, color.filled())
                    });
            }
        }
        if !series.labels.is_empty() {
            let labelled =
                series
                    .points
                    .iter()
                    .zip(&series.labels)
                    .filter_map(|(&(x, y), text)| {
                        let p = (panel.x.to_plot(x)?, panel.y.to_plot(y)?);
                        inside(p).then(|| (to_pixel(p), text.clone()))
                    });
            labels.extend(
                join_coincident(labelled.collect())
                    .into_iter()
                    .map(|(at, text)| (at, text, color)),
            );
        }
    }

    let names: Vec<&str> = panel.series.iter().map(|s| s.name.as_str()).collect();
    let legend = layout.place_legend(&panel.legend, legend_size(&names)?);
    let plot_area = chart.plotting_area().strip_coord_spec();
    for (at, text, color) in labels {
        let size = label_size(&text);
        let (x, y) = layout.place_label(at, size);
        plot_area
            .draw(&Text::new(
                text,
                (x, y),
                ("sans-serif", LABEL_FONT).into_font().color(&color),
            ))
            .map_err(plot_error)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::Coordinate(legend.x0, legend.y0))
        .legend_area_size(LEGEND_AREA)
        .margin(LEGEND_MARGIN)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .label_font(("sans-serif", LEGEND_FONT))
        .draw()
        .map_err(plot_error)?;
    Ok(())
}

/// Marker radius (pixels).
const MARKER_RADIUS: i32 = 4;
/// Dash and gap of dashed series (pixels).
const DASH: u32 = 8;
const GAP: u32 = 5;
/// Width of a legend entry's sample (pixels): two dashes and a gap.
const LEGEND_SAMPLE: i32 = 2 * DASH as i32 + GAP as i32;
/// plotters' legend layout: the space for the sample, the margin inside the box, the font size.
const LEGEND_AREA: u32 = 30;
const LEGEND_MARGIN: u32 = 10;
const LEGEND_FONT: u32 = 13;
/// Font size of point labels (plotters' units; SVG pixels are 1/1.24 of them).
const LABEL_FONT: u32 = 12;

/// A rectangle in pixels, `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
}

impl Rect {
    fn at((x, y): (i32, i32), (width, height): (i32, i32)) -> Rect {
        Rect {
            x0: x,
            y0: y,
            x1: x + width,
            y1: y + height,
        }
    }

    fn overlaps(&self, other: &Rect) -> bool {
        self.x0 < other.x1 && other.x0 < self.x1 && self.y0 < other.y1 && other.y0 < self.y1
    }

    fn contains(&self, (x, y): (i32, i32)) -> bool {
        (self.x0..self.x1).contains(&x) && (self.y0..self.y1).contains(&y)
    }

    fn grown(&self, by: i32) -> Rect {
        Rect {
            x0: self.x0 - by,
            y0: self.y0 - by,
            x1: self.x1 + by,
            y1: self.y1 + by,
        }
    }
}

/// The size plotters gives the legend box of entries `names` (its own text-size estimate, so
/// the rectangle is the one it draws).
fn legend_size(names: &[&str]) -> Result<(i32, i32), String> {
    let font = ("sans-serif", LEGEND_FONT).into_font();
    let line_height = f64::from(LEGEND_FONT) * 1.25;
    let (mut width, mut height) = (0, 0);
    for (i, name) in names.iter().enumerate() {
        let (w, h) = font.box_size(name).map_err(plot_error)?;
        width = width.max(w as i32);
        height = height.max((i as f64 * line_height).round() as i32 + h as i32);
    }
    let margin = LEGEND_MARGIN as i32;
    Ok((width + LEGEND_AREA as i32 + 2 * margin, height + 2 * margin))
}

/// The size of a point label as a browser draws it: plotters writes a font size of 1/1.24 of
/// its own, and sans-serif digits and letters average about 0.6 of the font size.
fn label_size(text: &str) -> (i32, i32) {
    let font_px = f64::from(LABEL_FONT) / 1.24;
    let width = (0.62 * font_px * text.chars().count() as f64).ceil() as i32;
    (width, font_px.ceil() as i32 + 2)
}

/// Labels of points closer than this (pixels) are joined: their markers overlap.
const COINCIDENT: i32 = 2 * MARKER_RADIUS;

/// `labels` (pixel position, text) with runs of coincident points joined into one label at the
/// run's first point (`"4, 5, 6"`), in order.
fn join_coincident(labels: Vec<((i32, i32), String)>) -> Vec<((i32, i32), String)> {
    let mut joined: Vec<((i32, i32), String)> = Vec::new();
    for (at, text) in labels {
        match joined.last_mut() {
            Some((first, texts))
                if (first.0 - at.0).abs() < COINCIDENT && (first.1 - at.1).abs() < COINCIDENT =>
            {
                if texts.split(", ").all(|t| t != text) {
                    texts.push_str(", ");
                    texts.push_str(&text);
                }
            }
            _ => joined.push((at, text)),
        }
    }
    joined
}

/// What is drawn on a panel's plotting area, in pixels relative to its top left corner, for
/// placing the legend and the point labels where they hide the least.
pub struct Layout {
    width: i32,
    height: i32,
    markers: Vec<(i32, i32)>,
    /// Points along every line, a few pixels apart.
    line_pixels: Vec<(i32, i32)>,
    /// The legend and the labels placed so far.
    taken: Vec<Rect>,
}

/// What covering one thing costs a candidate position: leaving the plotting area, hiding a
/// label or the legend, a marker, a line pixel.
const OUTSIDE_COST: i64 = 1_000_000;
const TAKEN_COST: i64 = 10_000;
const MARKER_COST: i64 = 100;
const LINE_COST: i64 = 1;

impl Layout {
    pub fn new(width: i32, height: i32) -> Layout {
        Layout {
            width,
            height,
            markers: Vec::new(),
            line_pixels: Vec::new(),
            taken: Vec::new(),
        }
    }

    pub fn add_markers(&mut self, markers: impl Iterator<Item = (i32, i32)>) {
        self.markers.extend(markers);
    }

    /// Adds the polyline through `pixels`, sampled every 3 pixels.
    pub fn add_line(&mut self, pixels: &[(i32, i32)]) {
        for pair in pixels.windows(2) {
            let ((x0, y0), (x1, y1)) = (pair[0], pair[1]);
            let length = f64::from(x1 - x0).hypot(f64::from(y1 - y0));
            let steps = (length / 3.0).ceil().max(1.0) as i32;
            for i in 0..=steps {
                let t = f64::from(i) / f64::from(steps);
                let p = (
                    (f64::from(x0) + t * f64::from(x1 - x0)).round() as i32,
                    (f64::from(y0) + t * f64::from(y1 - y0)).round() as i32,
                );
                if (0..self.width).contains(&p.0) && (0..self.height).contains(&p.1) {
                    self.line_pixels.push(p);
                }
            }
        }
    }

    /// What putting `rect` there would hide.
    fn cost(&self, rect: &Rect) -> i64 {
        let inside =
            rect.x0 >= 0 && rect.y0 >= 0 && rect.x1 <= self.width && rect.y1 <= self.height;
        let mut cost = if inside { 0 } else { OUTSIDE_COST };
        cost += TAKEN_COST * self.taken.iter().filter(|t| t.overlaps(rect)).count() as i64;
        let near = rect.grown(MARKER_RADIUS + 1);
        cost += MARKER_COST * self.markers.iter().filter(|&&m| near.contains(m)).count() as i64;
        cost += LINE_COST
            * self
                .line_pixels
                .iter()
                .filter(|&&p| rect.contains(p))
                .count() as i64;
        cost
    }

    /// Takes the cheapest of `candidates` (the first among equals) and returns it.
    fn take_cheapest(&mut self, candidates: impl Iterator<Item = Rect>) -> Rect {
        let mut best: Option<(i64, Rect)> = None;
        for rect in candidates {
            let cost = self.cost(&rect);
            if best.is_none_or(|(least, _)| cost < least) {
                best = Some((cost, rect));
            }
        }
        let rect = best.map(|(_, r)| r).unwrap_or(Rect::at((0, 0), (0, 0)));
        self.taken.push(rect);
        rect
    }

    /// The legend's box of `size`: at `preferred` if it hides nothing there, else at the
    /// corner or edge where it hides the least (corners first).
    pub fn place_legend(&mut self, preferred: &SeriesLabelPosition, size: (i32, i32)) -> Rect {
        use SeriesLabelPosition::*;
        let (w, h) = size;
        // plotters keeps 5 pixels from the plotting area's edges.
        let (left, right) = (5, self.width - w - 5);
        let (top, bottom) = (5, self.height - h - 5);
        let (centre_x, middle_y) = ((self.width - w) / 2, (self.height - h) / 2);
        let at = |position: &SeriesLabelPosition| {
            let corner = match position {
                UpperLeft => (left, top),
                MiddleLeft => (left, middle_y),
                LowerLeft => (left, bottom),
                UpperMiddle => (centre_x, top),
                MiddleMiddle => (centre_x, middle_y),
                LowerMiddle => (centre_x, bottom),
                UpperRight => (right, top),
                MiddleRight => (right, middle_y),
                LowerRight => (right, bottom),
                Coordinate(x, y) => (*x, *y),
            };
            Rect::at(corner, size)
        };
        let order = [
            preferred.clone(),
            UpperRight,
            UpperLeft,
            LowerRight,
            LowerLeft,
            UpperMiddle,
            LowerMiddle,
            MiddleRight,
            MiddleLeft,
        ];
        self.take_cheapest(order.iter().map(at))
    }

    /// The top left corner for a label of `size` next to the point at `at`: the first of the
    /// positions around it (up right, down right, up left, down left, right, left, above,
    /// below, then the same farther out) that hides the least.
    pub fn place_label(&mut self, at: (i32, i32), size: (i32, i32)) -> (i32, i32) {
        let (w, h) = size;
        let gap = MARKER_RADIUS + 2;
        let mut offsets = Vec::new();
        for far in [0, h + 2] {
            offsets.extend([
                (gap, -h - gap - far),
                (gap, gap + far),
                (-gap - w, -h - gap - far),
                (-gap - w, gap + far),
                (gap + 2 + far, -h / 2),
                (-gap - 2 - w - far, -h / 2),
                (-w / 2, -h - gap - 2 - far),
                (-w / 2, gap + 2 + far),
            ]);
        }
        let rect = self.take_cheapest(
            offsets
                .into_iter()
                .map(|(dx, dy)| Rect::at((at.0 + dx, at.1 + dy), size)),
        );
        (rect.x0, rect.y0)
    }
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

    /// The horizontal line segments `(x0, x1, y)` drawn in `color` (`#RRGGBB`) with stroke
    /// width 2, from plotters' SVG polylines.
    fn segments(svg: &str, color: &str) -> Vec<(i32, i32, i32)> {
        svg.split("<polyline")
            .skip(1)
            .filter(|p| p.contains(&format!("stroke=\"{color}\" stroke-width=\"2\"")))
            .filter_map(|p| {
                let points = p.split("points=\"").nth(1)?.split('"').next()?;
                let xy: Vec<(i32, i32)> = points
                    .split_whitespace()
                    .map(|pair| {
                        let (x, y) = pair.split_once(',').unwrap();
                        (x.parse().unwrap(), y.parse().unwrap())
                    })
                    .collect();
                (xy.len() == 2 && xy[0].1 == xy[1].1).then(|| (xy[0].0, xy[1].0, xy[0].1))
            })
            .collect()
    }

    #[test]
    fn the_legend_draws_each_series_as_it_is_drawn() {
        let along = |y: f64| vec![(1.0, y), (2.0, y), (3.0, y)];
        let figure = Figure {
            title: "styles".into(),
            panels: vec![Panel::new(
                "panel",
                Axis::linear("x"),
                Axis::linear("y").with_range(0.0, 10.0),
                vec![
                    Series::new("solid", Style::Line, 0, along(1.0)),
                    Series::new("dashed", Style::Dashed, 1, along(2.0)),
                    Series::new("points", Style::Points, 2, along(3.0)),
                    Series::new("both", Style::LinePoints, 3, along(4.0)),
                ],
            )],
        };
        let svg = figure.to_svg().unwrap();
        let hex = |c: usize| {
            let RGBColor(r, g, b) = PALETTE[c];
            format!("#{r:02X}{g:02X}{b:02X}")
        };
        let sample = LEGEND_SAMPLE;
        let (dash, gap) = (DASH as i32, GAP as i32);
        // The solid series' legend sample is one unbroken stroke of the sample's width.
        assert!(segments(&svg, &hex(0)).iter().any(|s| s.1 - s.0 == sample));
        // The dashed one is two dashes with the series' gap between them, on one line.
        let dashed = segments(&svg, &hex(1));
        assert!(
            dashed.iter().any(|a| a.1 - a.0 == dash
                && dashed
                    .iter()
                    .any(|b| b.2 == a.2 && b.0 == a.1 + gap && b.1 - b.0 == dash)),
            "no dashed legend sample in {dashed:?}"
        );
        assert!(
            !dashed.iter().any(|s| s.1 - s.0 == sample),
            "a solid sample for a dashed series"
        );
        // Points have no line at all, a line with points has both.
        assert!(segments(&svg, &hex(2)).is_empty());
        assert!(segments(&svg, &hex(3)).iter().any(|s| s.1 - s.0 == sample));
        let circles = |c: usize| svg.matches(&format!("fill=\"{}\"", hex(c))).count();
        assert_eq!(circles(2), 3 + 1, "three markers and the legend's");
        assert_eq!(circles(3), 3 + 1);
    }

    #[test]
    fn the_legend_keeps_its_corner_only_while_it_covers_nothing_there() {
        let size = (200, 80);
        let mut empty = Layout::new(800, 400);
        let upper_right = empty.place_legend(&SeriesLabelPosition::UpperRight, size);
        assert_eq!((upper_right.x0, upper_right.y0), (800 - 200 - 5, 5));
        // Markers under the upper right and lower right corners: it goes to the upper left.
        let mut busy = Layout::new(800, 400);
        busy.add_markers([(700, 40), (700, 360)].into_iter());
        let moved = busy.place_legend(&SeriesLabelPosition::LowerRight, size);
        assert_eq!((moved.x0, moved.y0), (5, 5));
        // A line through the upper half: the lower corners are free.
        let mut lined = Layout::new(800, 400);
        lined.add_line(&[(0, 50), (800, 50)]);
        let below = lined.place_legend(&SeriesLabelPosition::UpperRight, size);
        assert_eq!((below.x0, below.y0), (800 - 200 - 5, 400 - 80 - 5));
    }

    #[test]
    fn labels_of_nearby_points_do_not_overlap_each_other_markers_or_the_legend() {
        let mut layout = Layout::new(800, 400);
        let points = [(100, 200), (104, 203), (108, 198), (300, 100)];
        layout.add_markers(points.into_iter());
        let legend = layout.place_legend(&SeriesLabelPosition::UpperRight, (200, 80));
        let size = label_size("direct f64 (reference)");
        let placed: Vec<Rect> = points
            .iter()
            .map(|&p| Rect::at(layout.place_label(p, size), size))
            .collect();
        for (i, a) in placed.iter().enumerate() {
            assert!(!a.overlaps(&legend));
            assert!(a.x0 >= 0 && a.y0 >= 0 && a.x1 <= 800 && a.y1 <= 400);
            for (j, b) in placed.iter().enumerate() {
                assert!(
                    i == j || !a.overlaps(b),
                    "labels {i} and {j} overlap: {a:?} {b:?}"
                );
            }
            for &m in &points {
                assert!(
                    !a.grown(MARKER_RADIUS).contains(m),
                    "label {i} covers marker {m:?}"
                );
            }
        }
        // The first candidate, up and to the right, when nothing is in the way.
        let (x, y) = Layout::new(800, 400).place_label((300, 100), size);
        assert!(x > 300 && y + size.1 < 100);
    }

    #[test]
    fn labels_of_coincident_points_of_one_series_are_joined() {
        let labels = vec![
            ((100, 100), "3".to_owned()),
            ((103, 101), "4".to_owned()),
            ((105, 99), "5".to_owned()),
            ((140, 60), "6".to_owned()),
            ((140, 60), "6".to_owned()),
        ];
        assert_eq!(
            join_coincident(labels),
            vec![
                ((100, 100), "3, 4, 5".to_owned()),
                ((140, 60), "6".to_owned())
            ]
        );
    }
}

//! The map as an SVG chart (plotters): one panel per solver, the frame time across (longest on
//! the right), Young's modulus up, and in each (frame time, E) cell one small square per
//! Poisson ratio, left to right in the grid's order. A square's colour is the CPU cost per
//! frame on a log scale (the bar on the right); a black cross marks a cell that was unstable
//! (coloured by its cost until it failed, grey if it failed at once), a ring a stable cell where
//! some frames neither converged nor stopped at their rounding floor (the budget was spent or
//! the solve stalled above the floor), and a grey square with a dot a cell too costly to run.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::Grid;
use crate::measure::{CellResult, MAX_SUBSTEPS_PER_FRAME, Outcome, SolverKind};

const WIDTH: u32 = 1500;
const HEIGHT: u32 = 960;
const TITLE_HEIGHT: u32 = 50;
/// The column on the right: colour bar and legend.
const LEGEND_WIDTH: u32 = 250;
const GREY: RGBColor = RGBColor(215, 215, 215);
const DARK: RGBColor = RGBColor(60, 60, 60);

/// Viridis at eleven evenly spaced points (matplotlib's table): perceptually even, readable in
/// grey and by colour-blind viewers.
const VIRIDIS: [(u8, u8, u8); 11] = [
    (68, 1, 84),
    (72, 36, 117),
    (65, 68, 135),
    (53, 95, 141),
    (42, 120, 142),
    (33, 145, 140),
    (34, 168, 132),
    (68, 191, 112),
    (122, 209, 81),
    (189, 223, 38),
    (253, 231, 37),
];

/// The colour of `t` in [0, 1] (clamped), linearly between the table's points.
fn viridis(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let scaled = t * (VIRIDIS.len() - 1) as f64;
    let i = (scaled.floor() as usize).min(VIRIDIS.len() - 2);
    let f = scaled - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |x: u8, y: u8| (f64::from(x) + f * (f64::from(y) - f64::from(x))).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// The cost scale: whole decades (log10 of seconds) around every measured cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CostScale {
    pub lo: f64,
    pub hi: f64,
}

impl CostScale {
    pub fn of(results: &[CellResult]) -> CostScale {
        let (lo, hi) = results
            .iter()
            .filter(|r| r.frames_run > 0 && r.cost_per_frame > 0.0)
            .map(|r| r.cost_per_frame.log10())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                (lo.min(c), hi.max(c))
            });
        if lo > hi {
            return CostScale { lo: -6.0, hi: 0.0 };
        }
        let (lo, hi) = (lo.floor(), hi.ceil());
        CostScale {
            lo,
            hi: if hi > lo { hi } else { lo + 1.0 },
        }
    }

    /// Where `seconds` falls on the scale, 0 to 1.
    pub fn position(&self, seconds: f64) -> f64 {
        (seconds.log10() - self.lo) / (self.hi - self.lo)
    }
}

/// A cost (s) in the unit that reads best.
fn seconds_label(seconds: f64) -> String {
    if seconds >= 1.0 {
        format!("{seconds} s")
    } else if seconds >= 1e-3 {
        format!("{} ms", (seconds * 1e3).round())
    } else if seconds >= 1e-6 {
        format!("{} µs", (seconds * 1e6).round())
    } else {
        format!("{} ns", (seconds * 1e9).round())
    }
}

fn plot_error(error: impl std::fmt::Display) -> String {
    format!("drawing the map: {error}")
}

/// Writes the chart of `results` (cells of `grid`) to `path`.
pub fn write(grid: &Grid, results: &[CellResult], path: &Path) -> Result<(), String> {
    let svg = to_svg(grid, results)?;
    std::fs::write(path, svg).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The chart as an SVG document.
pub fn to_svg(grid: &Grid, results: &[CellResult]) -> Result<String, String> {
    let scale = CostScale::of(results);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let (title, body) = root.split_vertically(TITLE_HEIGHT);
        title
            .draw(&Text::new(
                format!(
                    "Tuning map: a 0.2 m jelly cube (320 tets, stable neo-Hookean, f32) dropped 0.1 m onto the ground ({}), {} s, one step a frame",
                    grid.ground.name(),
                    grid.duration
                ),
                (20, 16),
                ("sans-serif", 20).into_font(),
            ))
            .map_err(plot_error)?;
        let (panels, legend) = body.split_horizontally(WIDTH - LEGEND_WIDTH);
        // Five solvers: three panels a row (two rows); four or fewer: two.
        let columns = if grid.solvers.len() > 4 { 3 } else { 2 };
        let rows = grid.solvers.len().div_ceil(columns).max(1);
        let areas = panels.split_evenly((rows, columns));
        for (&solver, area) in grid.solvers.iter().zip(&areas) {
            let of: Vec<&CellResult> = results
                .iter()
                .filter(|r| r.input.solver == solver)
                .collect();
            draw_panel(grid, solver.name(), &of, scale, area)?;
        }
        // The automatic solver's check in the first free panel, where there is one.
        if grid.solvers.contains(&SolverKind::Auto)
            && let Some(area) = areas.get(grid.solvers.len())
        {
            draw_auto_check(&crate::auto_check(grid, results), area)?;
        }
        draw_legend(grid, scale, &legend)?;
        root.present().map_err(plot_error)?;
    }
    Ok(svg)
}

/// The automatic solver's check as text: the cells that meet the target, the worst ratios and
/// the cells that miss (each on two lines: where, and why).
fn draw_auto_check(
    check: &crate::AutoCheck,
    area: &DrawingArea<SVGBackend<'_>, Shift>,
) -> Result<(), String> {
    let text = |s: String, at: (i32, i32), size: u32| {
        area.draw(&Text::new(s, at, ("sans-serif", size).into_font()))
            .map_err(plot_error)
    };
    text("auto against the issue's target:".into(), (20, 30), 16)?;
    text(
        format!(
            "{} of {} cells stable, resolved and within {}x",
            check.met,
            check.cells,
            crate::AUTO_COST_TARGET
        ),
        (20, 54),
        14,
    )?;
    text("the cheapest other resolved solver".into(), (20, 72), 14)?;
    let worst = |label: &str, worst: &Option<(f64, String)>| {
        worst
            .as_ref()
            .map_or(format!("{label}: none"), |(ratio, at)| {
                format!("{label}: {ratio:.2}x at {at}")
            })
    };
    text(worst("worst", &check.worst), (20, 96), 13)?;
    text(
        worst("worst against explicit or newton", &check.worst_own),
        (20, 114),
        13,
    )?;
    let mut y = 142;
    for miss in &check.misses {
        text(format!("misses at {}:", miss.cell), (20, y), 12)?;
        text(format!("  {}", miss.why), (20, y + 15), 11)?;
        y += 34;
    }
    Ok(())
}

/// The frame rates left to right: the longest frame time on the right.
fn columns_of(grid: &Grid) -> Vec<u32> {
    let mut rates = grid.frame_rates.clone();
    rates.sort_unstable_by(|a, b| b.cmp(a));
    rates
}

fn draw_panel(
    grid: &Grid,
    name: &str,
    results: &[&CellResult],
    scale: CostScale,
    area: &DrawingArea<SVGBackend<'_>, Shift>,
) -> Result<(), String> {
    let rates = columns_of(grid);
    let youngs = &grid.youngs;
    let stable = results
        .iter()
        .filter(|r| r.outcome == Outcome::Stable)
        .count();
    let resolved = results
        .iter()
        .filter(|r| r.outcome == Outcome::Stable && r.resolved())
        .count();
    let caption = format!(
        "{name}: {stable} of {} stable, {resolved} resolved every frame",
        results.len()
    );
    let x_max = rates.len() as f64 - 0.5;
    let y_max = youngs.len() as f64 - 0.5;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(-0.5..x_max, -0.5..y_max)
        .map_err(plot_error)?;
    // Ticks only at the cells' centres (whole indices), labelled with the grid's values.
    let at_index = |v: f64, len: usize| {
        let i = v.round();
        ((v - i).abs() < 1e-9 && i >= 0.0 && (i as usize) < len).then_some(i as usize)
    };
    let x_label =
        |v: &f64| at_index(*v, rates.len()).map_or(String::new(), |i| format!("1/{}", rates[i]));
    let y_label = |v: &f64| {
        at_index(*v, youngs.len()).map_or(String::new(), |i| {
            format!("1e{:.0}", f64::from(youngs[i]).log10())
        })
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("frame time (s)")
        .y_desc("Young's modulus (Pa)")
        .x_labels(rates.len() * 2 + 1)
        .y_labels(youngs.len() * 2 + 1)
        .x_label_formatter(&x_label)
        .y_label_formatter(&y_label)
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .draw()
        .map_err(plot_error)?;

    let per_cell = grid.poissons.len().max(1) as f64;
    let slot = 0.84 / per_cell;
    let half_height = 0.32;
    for r in results {
        let (Some(xi), Some(yi), Some(ki)) = (
            rates
                .iter()
                .position(|&rate| (1.0 / r.input.frame_time).round() as u32 == rate),
            youngs.iter().position(|&e| e == r.input.young),
            grid.poissons.iter().position(|&nu| nu == r.input.poisson),
        ) else {
            continue;
        };
        let left = xi as f64 - 0.42 + ki as f64 * slot + 0.01;
        let right = left + slot - 0.02;
        let (bottom, top) = (yi as f64 - half_height, yi as f64 + half_height);
        let centre = (0.5 * (left + right), yi as f64);
        let fill = if r.frames_run > 0 && r.cost_per_frame > 0.0 {
            viridis(scale.position(r.cost_per_frame))
        } else {
            GREY
        };
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(left, bottom), (right, top)],
                fill.filled(),
            )))
            .map_err(plot_error)?;
        match &r.outcome {
            Outcome::Stable if !r.resolved() => {
                chart
                    .draw_series(std::iter::once(Circle::new(
                        centre,
                        7,
                        WHITE.stroke_width(4),
                    )))
                    .map_err(plot_error)?;
                chart
                    .draw_series(std::iter::once(Circle::new(
                        centre,
                        7,
                        BLACK.stroke_width(2),
                    )))
                    .map_err(plot_error)?;
            }
            Outcome::Stable => {}
            Outcome::Unstable { .. } => {
                for (width, colour) in [(5, WHITE), (2, BLACK)] {
                    let (dx, dy) = (0.3 * (right - left), 0.6 * half_height);
                    let style = colour.stroke_width(width);
                    chart
                        .draw_series([
                            PathElement::new(
                                vec![
                                    (centre.0 - dx, centre.1 - dy),
                                    (centre.0 + dx, centre.1 + dy),
                                ],
                                style,
                            ),
                            PathElement::new(
                                vec![
                                    (centre.0 - dx, centre.1 + dy),
                                    (centre.0 + dx, centre.1 - dy),
                                ],
                                style,
                            ),
                        ])
                        .map_err(plot_error)?;
                }
            }
            Outcome::TooCostly { .. } => {
                chart
                    .draw_series(std::iter::once(Circle::new(centre, 3, DARK.filled())))
                    .map_err(plot_error)?;
            }
        }
    }
    Ok(())
}

fn draw_legend(
    grid: &Grid,
    scale: CostScale,
    area: &DrawingArea<SVGBackend<'_>, Shift>,
) -> Result<(), String> {
    let text =
        |s: String, at: (i32, i32), size: u32| Text::new(s, at, ("sans-serif", size).into_font());
    area.draw(&text("CPU time per frame".into(), (10, 30), 15))
        .map_err(plot_error)?;
    area.draw(&text("(one thread, log scale)".into(), (10, 48), 13))
        .map_err(plot_error)?;
    // The colour bar: top = most costly.
    let (bar_left, bar_top, bar_width, bar_height) = (20, 66, 28, 300);
    for px in 0..bar_height {
        let t = 1.0 - f64::from(px) / f64::from(bar_height - 1);
        area.draw(&Rectangle::new(
            [
                (bar_left, bar_top + px),
                (bar_left + bar_width, bar_top + px + 1),
            ],
            viridis(t).filled(),
        ))
        .map_err(plot_error)?;
    }
    let decades = (scale.hi - scale.lo).round() as i32;
    for d in 0..=decades {
        let y = bar_top + bar_height - 1 - (d * (bar_height - 1)) / decades.max(1);
        area.draw(&PathElement::new(
            vec![(bar_left + bar_width, y), (bar_left + bar_width + 6, y)],
            BLACK.stroke_width(1),
        ))
        .map_err(plot_error)?;
        let seconds = 10f64.powf(scale.lo + f64::from(d));
        area.draw(&text(
            seconds_label(seconds),
            (bar_left + bar_width + 10, y - 7),
            13,
        ))
        .map_err(plot_error)?;
    }

    // The marks.
    let mut y = bar_top + bar_height + 40;
    let nus: Vec<String> = grid.poissons.iter().map(|nu| nu.to_string()).collect();
    area.draw(&text("In each cell, left to right:".into(), (10, y), 13))
        .map_err(plot_error)?;
    y += 18;
    area.draw(&text(format!("nu = {}", nus.join(", ")), (10, y), 13))
        .map_err(plot_error)?;
    y += 34;
    let sample =
        |y: i32, fill: RGBColor| Rectangle::new([(14, y - 10), (36, y + 10)], fill.filled());
    let mid = viridis(0.5);
    let entries: [(&str, &str); 4] = [
        ("stable, every frame converged", "or at its rounding floor"),
        ("stable, some frames spent", "the budget or stalled"),
        ("unstable: a step error", "or a blow-up"),
        ("too costly, not run", ""),
    ];
    for (k, (first, second)) in entries.iter().enumerate() {
        let fill = if k == 3 { GREY } else { mid };
        area.draw(&sample(y, fill)).map_err(plot_error)?;
        match k {
            1 => {
                area.draw(&Circle::new((25, y), 7, WHITE.stroke_width(4)))
                    .map_err(plot_error)?;
                area.draw(&Circle::new((25, y), 7, BLACK.stroke_width(2)))
                    .map_err(plot_error)?;
            }
            2 => {
                for (width, colour) in [(5, WHITE), (2, BLACK)] {
                    area.draw(&PathElement::new(
                        vec![(18, y - 7), (32, y + 7)],
                        colour.stroke_width(width),
                    ))
                    .map_err(plot_error)?;
                    area.draw(&PathElement::new(
                        vec![(18, y + 7), (32, y - 7)],
                        colour.stroke_width(width),
                    ))
                    .map_err(plot_error)?;
                }
            }
            3 => {
                area.draw(&Circle::new((25, y), 3, DARK.filled()))
                    .map_err(plot_error)?;
            }
            _ => {}
        }
        area.draw(&text((*first).to_owned(), (46, y - 12), 13))
            .map_err(plot_error)?;
        area.draw(&text((*second).to_owned(), (46, y + 4), 13))
            .map_err(plot_error)?;
        y += 44;
    }
    area.draw(&text(
        format!("(explicit: > {MAX_SUBSTEPS_PER_FRAME} substeps"),
        (46, y - 28),
        13,
    ))
    .map_err(plot_error)?;
    area.draw(&text("a frame)".into(), (46, y - 12), 13))
        .map_err(plot_error)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::{CellInput, Ground, SolverKind};

    /// A cell of one solver at 1e6 Pa, nu = 0.3, 1/60 s with `outcome`, 60 frames, costing 1 ms
    /// a frame.
    fn cell(outcome: Outcome, frames_converged: usize) -> CellResult {
        let ran = !matches!(outcome, Outcome::TooCostly { .. });
        CellResult {
            input: CellInput {
                solver: SolverKind::Newton,
                young: 1e6,
                poisson: 0.3,
                frame_time: 1.0 / 60.0,
                duration: 1.0,
                ground: Ground::Body,
            },
            outcome,
            frames: 60,
            frames_run: if ran { 60 } else { 0 },
            frames_converged: if ran { frames_converged } else { 0 },
            frames_at_floor: 0,
            frames_explicit: 0,
            frames_fallback: 0,
            cost_per_frame: if ran { 1e-3 } else { f64::NAN },
            stable_step: 1e-4,
            work_per_frame: 3.0,
            initial_energy: 15.7,
            energy_lost_per_second: 7.8,
            volume_error: 1e-3,
        }
    }

    fn count(svg: &str, element: &str) -> usize {
        svg.matches(&format!("<{element} ")).count()
    }

    /// Each mark adds exactly its elements to the chart of a resolved cell: the ring two
    /// circles (white under black), the cross four lines (two strokes, white under black),
    /// the too-costly dot one circle and the grey fill; the caption counts what is stable and
    /// resolved.
    /// With auto among five solvers the sixth panel holds its check: the count, the worst
    /// ratio, and a miss by name (auto at 2 ms against Newton's 1 ms: twice the cost).
    #[test]
    fn the_free_panel_shows_the_auto_check() {
        let grid = Grid {
            youngs: vec![1e6],
            poissons: vec![0.3],
            frame_rates: vec![60],
            solvers: vec![
                SolverKind::Explicit,
                SolverKind::Relax,
                SolverKind::Newton,
                SolverKind::Vbd,
                SolverKind::Auto,
            ],
            duration: 1.0,
            ground: Ground::Body,
        };
        let newton = cell(Outcome::Stable, 60);
        let mut auto = cell(Outcome::Stable, 60);
        auto.input.solver = SolverKind::Auto;
        auto.cost_per_frame = 2e-3;
        let svg = to_svg(&grid, &[newton, auto]).unwrap();
        assert!(svg.contains("auto against the issue"), "{svg}");
        assert!(svg.contains("0 of 1 cells stable, resolved and within 1.5x"));
        assert!(svg.contains("worst: 2.00x at E = 1e6 Pa, nu = 0.3, dt = 1/60"));
        assert!(svg.contains("misses at E = 1e6 Pa, nu = 0.3, dt = 1/60:"));
        assert!(svg.contains("2.00x the cheapest, newton"));
    }

    #[test]
    fn each_outcome_gets_its_mark() {
        let grid = Grid {
            youngs: vec![1e6],
            poissons: vec![0.3],
            frame_rates: vec![60],
            solvers: vec![SolverKind::Newton],
            duration: 1.0,
            ground: Ground::Body,
        };
        let svg = |r: CellResult| to_svg(&grid, &[r]).unwrap();
        let resolved = svg(cell(Outcome::Stable, 60));
        let unresolved = svg(cell(Outcome::Stable, 59));
        let unstable = svg(cell(
            Outcome::Unstable {
                frame: 10,
                reason: "EnergyGrew".into(),
            },
            60,
        ));
        let costly = svg(cell(Outcome::TooCostly { substeps: 30_000 }, 0));
        assert!(resolved.contains("newton: 1 of 1 stable, 1 resolved every frame"));
        assert!(unresolved.contains("newton: 1 of 1 stable, 0 resolved every frame"));
        assert!(unstable.contains("newton: 0 of 1 stable, 0 resolved every frame"));
        assert_eq!(count(&unresolved, "circle"), count(&resolved, "circle") + 2);
        assert_eq!(count(&unresolved, "polyline"), count(&resolved, "polyline"));
        assert_eq!(
            count(&unstable, "polyline"),
            count(&resolved, "polyline") + 4
        );
        assert_eq!(count(&unstable, "circle"), count(&resolved, "circle"));
        assert_eq!(count(&costly, "circle"), count(&resolved, "circle") + 1);
        // The grey of a cell not run appears once more than in the legend alone.
        let grey = "#D7D7D7";
        assert_eq!(
            costly.matches(grey).count(),
            resolved.matches(grey).count() + 1
        );
        // One cost: the scale is the decade around it, 1 ms to 10 ms.
        assert_eq!(
            CostScale::of(&[cell(Outcome::Stable, 60)]),
            CostScale { lo: -3.0, hi: -2.0 }
        );
    }

    #[test]
    fn the_colour_scale_runs_from_viridis_first_to_last() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(viridis(2.0), viridis(1.0));
        assert_eq!(viridis(0.05), RGBColor(70, 19, 101)); // halfway between the first two
        assert_eq!(seconds_label(1e-3), "1 ms");
        assert_eq!(seconds_label(1e-5), "10 µs");
    }
}

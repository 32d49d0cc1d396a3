//! Chart `integrators`: trajectory error against wall time per simulated second for a bar
//! clamped at one end and released from rest under gravity (it swings down, past its sag, and
//! back), stepped in f32 by explicit symplectic Euler at fractions of the stable bound and by
//! implicit Euler (the relaxation) at several steps and iteration budgets.
//!
//! The reference is the same scene in f64, explicit at a twentieth of the stable bound; its own
//! error is estimated from a run at a tenth (the two must agree far below the errors charted).
//! The error of a run is the largest distance of any vertex from the reference at any sample
//! (every 10 ms), relative to the largest displacement of the reference from rest.

use std::path::Path;

use crate::chart::{Axis, Figure, Panel, Series, Style, Table, num};
use crate::measure::{Run, progress};
use crate::{Findings, Size, double, single};

/// The bar (m): 0.4 long in x, 0.1 square, clamped at `x = 0`.
const LENGTH: f64 = 0.4;
const WIDTH: f64 = 0.1;
/// Stable neo-Hookean, E (Pa), nu, density (kg/m^3): sags about 8 cm, first period ~0.4 s.
const YOUNG: f64 = 5.0e5;
const POISSON: f64 = 0.3;
const DENSITY: f64 = 1000.0;
const G: f64 = 9.81;
/// The relaxation's first trial step (see `softfem::step`, "The relaxation") and relative
/// tolerance.
const STEP_LENGTH: f64 = 2.0;
const TOLERANCE: f64 = 1e-3;

/// The floating-point precision of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    F32,
    F64,
}

impl Precision {
    fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

/// One way to step the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// Explicit symplectic Euler at this fraction of the stable bound.
    Explicit { fraction: f64 },
    /// Implicit Euler by the relaxation: step (s) and iteration budget.
    Relax { dt: f64, budget: u32 },
}

/// The Chebyshev spectral radius estimate for a relaxation step `dt` (s): the best of 0.99,
/// 0.995 and 0.999 measured on this bar in f64 (a small step has more inertia, so a better
/// conditioned solve and a smaller spectral radius).
fn chebyshev_rho(dt: f64) -> f64 {
    if dt >= 1.0 / 240.0 { 0.999 } else { 0.99 }
}

/// Builds the bar in precision module `$p` and runs `$method` on it for `$duration` (s),
/// sampling at `$samples`: the run and the stable bound (s).
macro_rules! run_bar {
    ($p:ident, $method:expr, $cells:expr, $duration:expr, $samples:expr) => {{
        use $p::api::material::StableNeoHookean;
        use $p::api::step::{ExplicitSettings, RelaxSettings, Scene, TetElastic, stable_time_step};
        use $p::api::types::{Real, Vec3};
        let [n, m] = $cells;
        let size = Vec3::new(LENGTH as Real, WIDTH as Real, WIDTH as Real);
        let boxed = $p::body::BoxMesh::new(size, [n, m, m], $p::api::generate::BoxSplit::Kuhn6)?;
        let mut rest_data = Vec::new();
        let mesh = boxed.mesh(&mut rest_data)?;
        let masses = $p::body::masses(&mesh, DENSITY as Real)?;
        let pinned = boxed.flags(|x| x.x == 0.0);
        let material = StableNeoHookean::from_young_poisson(YOUNG as Real, POISSON as Real)
            .map_err(|e| e.to_string())?;
        let model = TetElastic::new(mesh, material);
        let mut stiffness = vec![0.0; masses.len()];
        let bound = stable_time_step(&model, &masses, &pinned, &mut stiffness)
            .map_err(|e| e.to_string())?;
        let gravity = Vec3::new(0.0, 0.0, -G as Real);
        let (mut x, mut v) = (boxed.rest.clone(), vec![Vec3::ZERO; boxed.rest.len()]);
        let run = match $method {
            Method::Explicit { fraction } => {
                let scene = Scene::new(fraction as Real * bound).with_gravity(gravity);
                let settings = ExplicitSettings::new();
                $p::body::run_explicit(
                    &model, &masses, &pinned, &scene, &settings, &mut x, &mut v, $duration,
                    $samples,
                )
            }
            Method::Relax { dt, budget } => {
                let scene = Scene::new(dt as Real).with_gravity(gravity);
                let settings = RelaxSettings::new()
                    .with_tolerance(TOLERANCE as Real, budget)
                    .with_chebyshev(chebyshev_rho(dt) as Real, STEP_LENGTH as Real, 0);
                $p::body::run_relax(
                    &model, &masses, &pinned, &scene, &settings, &mut x, &mut v, $duration,
                    $samples,
                )
            }
        };
        Ok::<_, String>((run, f64::from(bound)))
    }};
}

/// A run of `method` in `precision`: positions at the sample times, wall time, iterations,
/// failure; and the stable bound (s).
fn run_bar(
    method: Method,
    precision: Precision,
    cells: [usize; 2],
    duration: f64,
    samples: &[f64],
) -> Result<(Run, f64), String> {
    match precision {
        Precision::F32 => run_bar!(single, method, cells, duration, samples),
        Precision::F64 => run_bar!(double, method, cells, duration, samples),
    }
}

/// The f64 explicit reference at `fraction` of the stable bound.
fn reference(
    fraction: f64,
    cells: [usize; 2],
    duration: f64,
    samples: &[f64],
) -> Result<Run, String> {
    let (run, _) = run_bar(
        Method::Explicit { fraction },
        Precision::F64,
        cells,
        duration,
        samples,
    )?;
    match run.failure {
        Some((t, error)) => Err(format!("the f64 reference failed at t = {t} s: {error}")),
        None => Ok(run),
    }
}

/// The largest vertex distance (m) between two sampled trajectories, over the samples both have;
/// infinite if `run` has fewer samples (it failed).
pub fn trajectory_distance(run: &[Vec<[f64; 3]>], reference: &[Vec<[f64; 3]>]) -> f64 {
    if run.len() < reference.len() {
        return f64::INFINITY;
    }
    run.iter()
        .zip(reference)
        .flat_map(|(a, b)| a.iter().zip(b))
        .map(|(p, q)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .fold(0.0, f64::max)
}

/// The points no other point beats in both coordinates (lower is better in both), by cost.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut sorted: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|(c, e)| c.is_finite() && e.is_finite())
        .collect();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut front: Vec<(f64, f64)> = Vec::new();
    for p in sorted {
        if front.last().is_none_or(|last| p.1 < last.1) {
            front.push(p);
        }
    }
    front
}

/// One measured configuration.
struct Measured {
    method: Method,
    precision: Precision,
    /// The step (s).
    dt: f64,
    /// Wall time per simulated second (ms).
    cost: f64,
    /// Trajectory error relative to the largest displacement.
    error: f64,
    run: Run,
}

impl Measured {
    /// `name: error, cost, iterations, convergence`, for the progress output and the findings.
    fn summary(&self) -> String {
        format!(
            "{}: error {:.2e}, {:.1} ms/s, {:.1} iterations/step, {} of {} steps unconverged",
            self.name(),
            self.error,
            self.cost,
            self.run.iterations as f64 / self.run.steps.max(1) as f64,
            self.run.unconverged,
            self.run.steps
        )
    }

    fn name(&self) -> String {
        let precision = self.precision.name();
        match self.method {
            Method::Explicit { fraction } => format!(
                "explicit {precision} {fraction}x bound (dt {:.2e} s)",
                self.dt
            ),
            Method::Relax { dt, budget } => {
                format!("relax {precision} dt 1/{:.0} budget {budget}", 1.0 / dt)
            }
        }
    }
}

pub fn run(size: Size, out: &Path) -> Result<Findings, String> {
    use Precision::{F32, F64};
    let (cells, duration): ([usize; 2], f64) = match size {
        Size::Quick => ([6, 2], 0.5),
        Size::Full => ([12, 3], 1.0),
    };
    let (fractions, steps, budgets, f32_relax_steps): (&[f64], &[u32], &[u32], &[u32]) = match size
    {
        Size::Quick => (&[1.0], &[30, 120], &[10, 200], &[120]),
        Size::Full => (
            &[1.0, 0.5, 0.25, 0.125],
            &[30, 60, 120, 240, 480],
            &[10, 50, 200, 2000],
            &[30, 120, 480],
        ),
    };
    let samples: Vec<f64> = (0..=(duration * 100.0).round() as usize)
        .map(|i| i as f64 / 100.0)
        .collect();
    progress(
        "integrators",
        &format!(
            "f64 reference: bar {}x{}x{} cells, {duration} s at 1/20 and 1/10 of the stable bound",
            cells[0], cells[1], cells[1]
        ),
    );
    let fine = reference(0.05, cells, duration, &samples)?;
    let coarse = reference(0.1, cells, duration, &samples)?;
    let amplitude = fine
        .samples
        .iter()
        .flat_map(|s| s.iter().zip(&fine.samples[0]))
        .map(|(p, q)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
        })
        .fold(0.0, f64::max);
    let self_check = trajectory_distance(&coarse.samples, &fine.samples) / amplitude;
    progress(
        "integrators",
        &format!(
            "largest displacement {amplitude:.4} m; reference self-check (1/10 vs 1/20 of the bound) {self_check:.1e}"
        ),
    );

    let mut configs: Vec<(Method, Precision)> = Vec::new();
    configs.extend(
        fractions
            .iter()
            .map(|&fraction| (Method::Explicit { fraction }, F64)),
    );
    configs.extend(
        [fractions[0], fractions[fractions.len() - 1]]
            .map(|fraction| (Method::Explicit { fraction }, F32)),
    );
    configs.dedup();
    for &budget in budgets {
        configs.extend(steps.iter().map(|&n| {
            (
                Method::Relax {
                    dt: 1.0 / f64::from(n),
                    budget,
                },
                F64,
            )
        }));
    }
    configs.extend(f32_relax_steps.iter().map(|&n| {
        (
            Method::Relax {
                dt: 1.0 / f64::from(n),
                budget: 200,
            },
            F32,
        )
    }));

    let mut measured = Vec::new();
    for (method, precision) in configs {
        // The fastest of up to three runs (one when a run takes over a second): wall time on a
        // shared machine only ever errs upwards.
        let (mut run, bound) = run_bar(method, precision, cells, duration, &samples)?;
        let mut wall = run.wall;
        for _ in 0..2 {
            if wall.as_secs_f64() > 1.0 {
                break;
            }
            let (again, _) = run_bar(method, precision, cells, duration, &samples)?;
            wall = wall.min(again.wall);
            run = again;
        }
        let dt = match method {
            Method::Explicit { fraction } => fraction * bound,
            Method::Relax { dt, .. } => dt,
        };
        let m = Measured {
            method,
            precision,
            dt,
            cost: wall.as_secs_f64() * 1e3 / duration,
            error: trajectory_distance(&run.samples, &fine.samples) / amplitude,
            run,
        };
        let failure = m.run.failure.map_or(String::new(), |(t, e)| {
            format!(", failed at t = {t:.3} s: {e}")
        });
        progress("integrators", &format!("{}{failure}", m.summary()));
        measured.push(m);
    }

    let mut table = Table::new(&[
        "method",
        "precision",
        "dt_s",
        "budget",
        "steps",
        "iterations",
        "unconverged",
        "wall_ms_per_simulated_s",
        "relative_error",
        "failure",
    ]);
    for m in &measured {
        let (method, budget) = match m.method {
            Method::Explicit { fraction } => {
                (format!("explicit {fraction} x bound"), String::new())
            }
            Method::Relax { budget, .. } => ("relax".to_owned(), budget.to_string()),
        };
        table.push(vec![
            method,
            m.precision.name().into(),
            num(m.dt),
            budget,
            m.run.steps.to_string(),
            m.run.iterations.to_string(),
            m.run.unconverged.to_string(),
            num(m.cost),
            num(m.error),
            m.run
                .failure
                .map_or(String::new(), |(t, e)| format!("t = {t:.3} s: {e}")),
        ]);
    }
    table.write(&out.join("integrators.csv"))?;

    let pick =
        |keep: &dyn Fn(&Measured) -> bool| measured.iter().filter(|m| keep(m)).collect::<Vec<_>>();
    let series_of = |name: &str, style: Style, color: usize, chosen: Vec<&Measured>| {
        Series::new(
            name,
            style,
            color,
            chosen.iter().map(|m| (m.cost, m.error)).collect(),
        )
        .with_labels(
            chosen
                .iter()
                .map(|m| match m.method {
                    Method::Explicit { fraction } => format!("{fraction}x"),
                    Method::Relax { dt, .. } => format!("1/{:.0}", 1.0 / dt),
                })
                .collect(),
        )
    };
    let mut series = vec![
        series_of(
            "explicit f64, dt = fraction of the bound",
            Style::LinePoints,
            0,
            pick(&|m| m.precision == F64 && matches!(m.method, Method::Explicit { .. })),
        ),
        series_of(
            "explicit f32",
            Style::Points,
            5,
            pick(&|m| m.precision == F32 && matches!(m.method, Method::Explicit { .. })),
        ),
    ];
    for (i, &budget) in budgets.iter().enumerate() {
        series.push(series_of(
            &format!("relaxation f64, at most {budget} iterations/step"),
            Style::LinePoints,
            [1, 2, 3, 4][i % 4],
            pick(&|m| {
                m.precision == F64
                    && matches!(m.method, Method::Relax { budget: b, .. } if b == budget)
            }),
        ));
    }
    series.push(series_of(
        "relaxation f32, 200 iterations (stalls)",
        Style::Points,
        6,
        pick(&|m| m.precision == F32 && matches!(m.method, Method::Relax { .. })),
    ));
    let front = pareto_front(
        &measured
            .iter()
            .map(|m| (m.cost, m.error))
            .collect::<Vec<_>>(),
    );
    series.push(Series::new("Pareto front", Style::Dashed, 7, front.clone()));
    Figure {
        title: "Time integrators: trajectory error against cost".into(),
        panels: vec![Panel::new(
            &format!(
                "bar clamped at one end, released under gravity: {} tets, stable neo-Hookean E = {YOUNG:.0e} Pa, {duration} s",
                6 * cells[0] * cells[1] * cells[1]
            ),
            Axis::log("wall time per simulated second (ms, one thread)"),
            Axis::log("largest position error / largest displacement"),
            series,
        )],
    }
    .write(&out.join("integrators.svg"))?;

    let mut findings = Findings::new("integrators");
    findings.line(format!(
        "largest displacement {amplitude:.3} m; reference self-check {self_check:.1e}"
    ));
    for m in &measured {
        findings.line(m.summary());
    }
    findings.line(format!(
        "Pareto front (ms/s, error): {}",
        front
            .iter()
            .map(|(c, e)| format!("({c:.1}, {e:.1e})"))
            .collect::<Vec<_>>()
            .join(" ")
    ));
    Ok(findings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pareto_front_keeps_only_undominated_points() {
        let points = [
            (1.0, 0.5),
            (2.0, 0.6),
            (3.0, 0.1),
            (0.5, 0.9),
            (4.0, f64::INFINITY),
            (5.0, 0.01),
        ];
        assert_eq!(
            pareto_front(&points),
            vec![(0.5, 0.9), (1.0, 0.5), (3.0, 0.1), (5.0, 0.01)]
        );
    }

    #[test]
    fn trajectory_distance_is_the_worst_vertex_and_infinite_for_a_cut_run() {
        let a = vec![
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
        ];
        let mut b = a.clone();
        b[1][1] = [1.0, 3.0, 4.0];
        assert_eq!(trajectory_distance(&a, &b), 5.0);
        assert_eq!(trajectory_distance(&a[..1], &b), f64::INFINITY);
    }
}

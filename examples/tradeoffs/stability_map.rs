//! Chart `stability`: the largest explicit time step that stays stable, measured, against the
//! computed bound `stable_time_step`, across Young's modulus and Poisson ratio; and the
//! relaxation (implicit Euler) at steps where explicit stepping blows up.
//!
//! The scene is a free box of 96 tetrahedra (stable neo-Hookean, no gravity, no pins) started
//! from a small deterministic perturbation of its rest shape. The measured limit is the largest
//! `dt / bound` of an upward scan from 0.9 that was stable at every scanned step: a step is
//! stable if the run keeps every vertex within 100 times the perturbation for the whole run and
//! the stepper reports nothing. The independent reference
//! is the critical step of the linearised system, `2 / omega_max`, from the eigenvalues of
//! `M^-1 K` (`K` by central differences of the f64 forces, eigenvalues by nalgebra).

use std::path::Path;

use nalgebra::{DMatrix, SymmetricEigen};
use plotters::chart::SeriesLabelPosition;

use crate::chart::{Axis, Figure, Panel, Series, Style, Table, num};
use crate::measure::progress;
use crate::{Findings, Size, double, single};

/// The box (m) and its cells.
const SIZE: [f64; 3] = [0.1, 0.05, 0.05];
const CELLS: [usize; 3] = [4, 2, 2];
const DENSITY: f64 = 1000.0;
/// The perturbation, relative to a cell (2.5 cm): small, so the linearised limit applies.
const PERTURBATION: f64 = 1e-3;
const POISSON_RATIOS: [f64; 3] = [0.3, 0.45, 0.49];

/// The rest positions perturbed by `PERTURBATION` cells, deterministically.
fn perturbed(rest: &[softfem::glam::Vec3]) -> Vec<softfem::glam::Vec3> {
    use softfem::glam::Vec3;
    let amplitude = (PERTURBATION * SIZE[1] / CELLS[1] as f64) as f32;
    rest.iter()
        .enumerate()
        .map(|(i, &x)| {
            let t = i as f32;
            x + Vec3::new((t * 1.7).sin(), (t * 2.3).cos(), (t * 0.61).sin()) * amplitude
        })
        .collect()
}

/// The critical step `2 / omega_max` (s) of the stiffness `k` (N/m, `3n x 3n`) with lumped
/// `masses` (kg).
pub fn critical_step(k: &DMatrix<f64>, masses: &[f64]) -> f64 {
    let n = k.nrows();
    let scaled = DMatrix::from_fn(n, n, |i, j| {
        k[(i, j)] / (masses[i / 3] * masses[j / 3]).sqrt()
    });
    let largest = SymmetricEigen::new(scaled)
        .eigenvalues
        .iter()
        .copied()
        .fold(0.0, f64::max);
    2.0 / largest.sqrt()
}

/// What was measured for one material.
struct Cell {
    young: f64,
    poisson: f64,
    /// `stable_time_step` (s).
    bound: f64,
    /// The eigenvalue limit over the bound.
    eigen_ratio: f64,
    /// The scan's largest stable step over the bound.
    measured_ratio: f64,
    /// The explicit stepper's report at the first failing step of the scan.
    explicit_above: String,
    /// The relaxation at twice the measured limit and at 1/30 s: the step (s), the largest and
    /// the final energy over the starting energy, and the share of converged solves.
    relax: [(f64, f64, f64, f64); 2],
}

pub fn run(size: Size, out: &Path) -> Result<Findings, String> {
    let (youngs, steps, relax_steps, scan_step): (&[f64], usize, usize, f64) = match size {
        Size::Quick => (&[1e5, 1e7], 600, 5, 0.1),
        Size::Full => (&[1e4, 1e5, 1e6, 1e7, 1e8], 3000, 30, 0.02),
    };
    // dt / bound from 0.9 up in steps of `scan_step`, to 3.
    let scan: Vec<f64> = (0..)
        .map(|i| 0.9 + scan_step * f64::from(i))
        .take_while(|&r| r <= 3.0)
        .collect();
    let mut cells = Vec::new();
    for &poisson in &POISSON_RATIOS {
        for &young in youngs {
            let cell = measure(young, poisson, steps, relax_steps, &scan)?;
            progress(
                "stability",
                &format!(
                    "E = {young:.0e} Pa, nu = {poisson}: bound {:.3e} s, eigenvalue limit {:.3}x, measured {:.3}x; explicit just above: {}; relax at 2x: energy {:.3}, at 1/30 s: energy {:.3} ({:.0} % converged)",
                    cell.bound,
                    cell.eigen_ratio,
                    cell.measured_ratio,
                    cell.explicit_above,
                    cell.relax[0].1,
                    cell.relax[1].1,
                    100.0 * cell.relax[1].3
                ),
            );
            cells.push(cell);
        }
    }

    let mut table = Table::new(&[
        "young_pa",
        "poisson",
        "bound_s",
        "eigen_limit_over_bound",
        "measured_limit_over_bound",
        "explicit_at_first_failing_dt",
        "relax_dt_2x_s",
        "relax_2x_max_energy_ratio",
        "relax_2x_final_energy_ratio",
        "relax_2x_converged_share",
        "relax_dt_1_30_s",
        "relax_1_30_max_energy_ratio",
        "relax_1_30_final_energy_ratio",
        "relax_1_30_converged_share",
    ]);
    for c in &cells {
        let mut row = vec![
            num(c.young),
            num(c.poisson),
            num(c.bound),
            num(c.eigen_ratio),
            num(c.measured_ratio),
            c.explicit_above.clone(),
        ];
        for (dt, largest, last, converged) in c.relax {
            row.extend([num(dt), num(largest), num(last), num(converged)]);
        }
        table.push(row);
    }
    table.write(&out.join("stability.csv"))?;

    let of_nu = |nu: f64| cells.iter().filter(move |c| c.poisson == nu);
    let mut limits = vec![Series::new(
        "computed bound",
        Style::Dashed,
        7,
        youngs.iter().map(|&e| (e, 1.0)).collect(),
    )];
    let mut relax = Vec::new();
    // The eigenvalue limits are drawn after all measured ones: at nu = 0.3 it (1.67x) lies on the
    // measured line of nu = 0.45 (1.66x), and a dashed line hides less of a solid one than the
    // other way round.
    let mut eigen_limits = Vec::new();
    for (color, &nu) in POISSON_RATIOS.iter().enumerate() {
        limits.push(Series::new(
            &format!("measured, nu = {nu}"),
            Style::LinePoints,
            color,
            of_nu(nu).map(|c| (c.young, c.measured_ratio)).collect(),
        ));
        eigen_limits.push(Series::new(
            &format!("eigenvalues, nu = {nu}"),
            Style::Dashed,
            color,
            of_nu(nu).map(|c| (c.young, c.eigen_ratio)).collect(),
        ));
        relax.push(Series::new(
            &format!("dt = 2x explicit limit, nu = {nu}"),
            Style::LinePoints,
            color,
            of_nu(nu).map(|c| (c.young, c.relax[0].2)).collect(),
        ));
        relax.push(Series::new(
            &format!("dt = 1/30 s, nu = {nu}"),
            Style::Dashed,
            color,
            of_nu(nu).map(|c| (c.young, c.relax[1].2)).collect(),
        ));
    }
    limits.extend(eigen_limits);
    let largest_energy = cells
        .iter()
        .flat_map(|c| c.relax.map(|r| r.1))
        .fold(0.0, f64::max);
    Figure {
        title: "Explicit stability: largest stable step against the computed bound".into(),
        panels: vec![
            Panel::new(
                &format!("free box, 96 tets, stable neo-Hookean, f32; stable for {steps} steps at every dt up to the measured one (scan step {scan_step})"),
                Axis::log("Young's modulus (Pa)"),
                Axis::linear("largest stable dt / computed bound").with_range(0.0, 2.5),
                limits,
            )
            .with_legend(SeriesLabelPosition::LowerRight),
            Panel::new(
                &format!("relaxation (f64), {relax_steps} steps at 2x the measured explicit limit and at 1/30 s; largest energy over start in any run: {largest_energy:.4}"),
                Axis::log("Young's modulus (Pa)"),
                Axis::log("final energy / starting energy"),
                relax,
            )
            .with_legend(SeriesLabelPosition::LowerRight),
        ],
    }
    .write(&out.join("stability.svg"))?;

    let mut findings = Findings::new("stability");
    for &nu in &POISSON_RATIOS {
        let ratios: Vec<f64> = of_nu(nu).map(|c| c.measured_ratio).collect();
        let eigen: Vec<f64> = of_nu(nu).map(|c| c.eigen_ratio).collect();
        let range = |v: &[f64]| {
            (
                v.iter().copied().fold(f64::INFINITY, f64::min),
                v.iter().copied().fold(0.0, f64::max),
            )
        };
        let (lo, hi) = range(&ratios);
        let (elo, ehi) = range(&eigen);
        let relax_worst = of_nu(nu)
            .map(|c| c.relax[0].1.max(c.relax[1].1))
            .fold(0.0, f64::max);
        let converged = of_nu(nu).map(|c| c.relax[1].3).fold(1.0, f64::min);
        findings.line(format!(
            "nu = {nu}: measured limit {lo:.3}..{hi:.3}x bound, eigenvalue limit {elo:.3}..{ehi:.3}x; relax energy never above {relax_worst:.3}x start, at 1/30 s at least {:.0} % of solves converged",
            100.0 * converged
        ));
    }
    let blowups: Vec<&String> = cells.iter().map(|c| &c.explicit_above).collect();
    findings.line(format!(
        "explicit at the first failing scanned dt: {}",
        blowups
            .iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>()
            .join("; ")
    ));
    Ok(findings)
}

/// Measures one material: the explicit scan in f32 (the precision a game or firmware runs),
/// the eigenvalue limit and the relaxation in f64 (where its solves can converge: in f32 the
/// objective's rounding, about 1e-7 of the elastic energy's terms, stops the line search
/// long before a small perturbation is resolved).
fn measure(
    young: f64,
    poisson: f64,
    steps: usize,
    relax_steps: usize,
    scan: &[f64],
) -> Result<Cell, String> {
    use single::api::material::StableNeoHookean;
    use single::api::step::{ExplicitSettings, Scene, TetElastic, stable_time_step};
    use softfem::glam::Vec3;

    let size = Vec3::new(SIZE[0] as f32, SIZE[1] as f32, SIZE[2] as f32);
    let boxed = single::body::BoxMesh::new(size, CELLS, softfem::generate::BoxSplit::Kuhn6)?;
    let mut rest_data = Vec::new();
    let mesh = boxed.mesh(&mut rest_data)?;
    let masses = single::body::masses(&mesh, DENSITY as f32)?;
    let material = StableNeoHookean::from_young_poisson(young as f32, poisson as f32)
        .map_err(|e| e.to_string())?;
    let model = TetElastic::new(mesh, material);
    let mut stiffness = vec![0.0; masses.len()];
    let bound = f64::from(
        stable_time_step(&model, &masses, &[], &mut stiffness).map_err(|e| e.to_string())?,
    );

    let start = perturbed(&boxed.rest);
    let amplitude = start
        .iter()
        .zip(&boxed.rest)
        .map(|(a, b)| f64::from((*a - *b).length()))
        .fold(0.0, f64::max);
    let explicit = |ratio: f64| {
        let scene = Scene::new((ratio * bound) as f32);
        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; start.len()]);
        let run = single::body::run_explicit(
            &model,
            &masses,
            &[],
            &scene,
            &ExplicitSettings::new(),
            &mut x,
            &mut v,
            steps as f64 * ratio * bound,
            &[],
        );
        let drift = x
            .iter()
            .zip(&boxed.rest)
            .map(|(a, b)| f64::from((*a - *b).length()))
            .fold(0.0, f64::max);
        (run, drift)
    };
    let stable = |ratio: f64| {
        let (run, drift) = explicit(ratio);
        run.failure.is_none() && drift < 100.0 * amplitude
    };
    // Stability need not be monotone in dt (near the limit a nonlinear coupling can blow up a
    // step that a slightly larger one survives), so scan upwards and stop at the first failure:
    // every step below the reported limit was tried and was stable.
    let mut lo = 0.0;
    let mut hi = f64::INFINITY;
    for &ratio in scan {
        if stable(ratio) {
            lo = ratio;
        } else {
            hi = ratio;
            break;
        }
    }
    if lo == 0.0 {
        return Err(format!(
            "E = {young}, nu = {poisson}: unstable at {}x the bound",
            scan[0]
        ));
    }
    let (above, drift) = explicit(hi.min(3.0));
    let explicit_above = match above.failure {
        Some((t, error)) => format!("{error:?} after {} steps (t = {t:.2e} s)", above.steps),
        None => format!(
            "no report; drift {:.1e} of the perturbation",
            drift / amplitude
        ),
    };

    use double::api::material::StableNeoHookean as StableNeoHookean64;
    use double::api::step::{RelaxSettings, Scene as Scene64, TetElastic as TetElastic64};
    use softfem::glam::DVec3;
    let boxed = double::body::BoxMesh {
        rest: boxed.rest.iter().map(|p| p.as_dvec3()).collect(),
        tets: boxed.tets.clone(),
    };
    let mut rest_data = Vec::new();
    let mesh = boxed.mesh(&mut rest_data)?;
    let masses = double::body::masses(&mesh, DENSITY)?;
    let material =
        StableNeoHookean64::from_young_poisson(young, poisson).map_err(|e| e.to_string())?;
    let model = TetElastic64::new(mesh, material);
    let k = double::body::stiffness_matrix(&model, &boxed.rest, 1e-6 * SIZE[1])?;
    let eigen_limit = critical_step(&k, &masses);

    // The energy (J) of a state: kinetic plus elastic.
    let energy = |x: &[DVec3], v: &[DVec3]| -> f64 {
        let kinetic: f64 = v
            .iter()
            .zip(&masses)
            .map(|(v, m)| 0.5 * m * v.length_squared())
            .sum();
        kinetic + mesh.elastic_energy(&material, x).unwrap_or(f64::NAN)
    };
    let start: Vec<DVec3> = start.iter().map(|p| p.as_dvec3()).collect();
    let initial = energy(&start, &vec![DVec3::ZERO; start.len()]);
    let relax_at = |dt: f64| -> Result<(f64, f64, f64, f64), String> {
        let scene = Scene64::new(dt);
        let settings = RelaxSettings::new()
            .with_tolerance(1e-4, 500)
            .with_chebyshev(0.995, 2.0, 0);
        let (mut x, mut v) = (start.clone(), vec![DVec3::ZERO; start.len()]);
        let mut largest: f64 = 1.0;
        let mut converged = 0;
        for _ in 0..relax_steps {
            let run = double::body::run_relax(
                &model,
                &masses,
                &[],
                &scene,
                &settings,
                &mut x,
                &mut v,
                dt,
                &[],
            );
            if let Some((_, error)) = run.failure {
                return Err(format!("relaxation at dt = {dt} s failed: {error}"));
            }
            converged += usize::from(run.unconverged == 0);
            largest = largest.max(energy(&x, &v) / initial);
        }
        let last = energy(&x, &v) / initial;
        Ok((dt, largest, last, converged as f64 / relax_steps as f64))
    };
    let relax = [relax_at(2.0 * lo * bound)?, relax_at(1.0 / 30.0)?];
    Ok(Cell {
        young,
        poisson,
        bound,
        eigen_ratio: eigen_limit / bound,
        measured_ratio: lo,
        explicit_above,
        relax,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn critical_step_of_one_spring() {
        // Two unit masses joined along x by a spring k = 4 N/m: omega_max^2 = 2k/m = 8, so
        // dt_crit = 2 / sqrt(8). The other modes (y, z, translation) are zero.
        let mut k = DMatrix::zeros(6, 6);
        for (i, j, v) in [(0, 0, 4.0), (3, 3, 4.0), (0, 3, -4.0), (3, 0, -4.0)] {
            k[(i, j)] = v;
        }
        assert!((critical_step(&k, &[1.0, 1.0]) - 2.0 / 8f64.sqrt()).abs() < 1e-12);
    }
}

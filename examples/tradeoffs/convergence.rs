//! Chart `convergence`: a cantilever's tip deflection under a small end load against
//! Euler–Bernoulli beam theory, as the mesh is refined (5- and 6-tetrahedron splits), and what
//! each mesh costs to solve.
//!
//! The beam is `L = 1 m` long with a square `h = 0.1 m` section (`L / h = 10`), E = 1 MPa,
//! nu = 0.3, clamped (all vertices of the face `x = 0` pinned). The load `P` acts downwards on
//! the end face `x = L`, spread over its vertices by their bilinear tributary areas.
//!
//! Euler–Bernoulli: a slender beam's tip deflection is `delta = P L^3 / (3 E I)` with
//! `I = h^4 / 12`, assuming plane sections stay plane and normal to the axis (no shear strain),
//! small deflection, and a clamp that only fixes the axis' position and slope. Shear adds
//! Timoshenko's `P L / (kappa G A)` (`kappa = 5/6` for a rectangle, `G = E / (2 (1 + nu))`):
//! `3 E I / (kappa G A L^2) = (E / G) (h / L)^2 / (4 kappa) = 0.78 %` here. The fully clamped
//! face also stops the section's Poisson contraction there, which stiffens the root slightly:
//! a converged 3D solution sits near `1.0..1.008` of the closed form, not exactly at 1. The
//! load gives `delta / L = 1e-3`, small enough that geometric nonlinearity is below 1e-6.
//!
//! The FEM deflection is the equilibrium found by `relax_quasi_static` in f64 (stable
//! neo-Hookean, which is linear elasticity at this strain). The quasi-static solve has no load
//! argument but minimises `E(x) - sum m_i g . x_i`: the end load is given to it as the weight of
//! "masses" on the end face (`P_i / g` there, a negligible 1e-12 kg elsewhere so that every mass
//! is positive as the solver requires; the masses play no other role without inertia).
//!
//! Linear tetrahedra are too stiff in bending (shear locking: a linear element cannot bend
//! without shearing), so the deflection approaches the theory slowly from below.

use std::path::Path;

use plotters::chart::SeriesLabelPosition;
use softfem::f64::generate::BoxSplit;
use softfem::f64::material::StableNeoHookean;
use softfem::f64::step::{
    RelaxScratch, RelaxSettings, Scene, TetElastic, relax_quasi_static, scratch_len,
};
use softfem::glam::DVec3;

use crate::chart::{Axis, Figure, Panel, Series, Style, Table, num};
use crate::double::body::BoxMesh;
use crate::measure::{min_time, progress};
use crate::{Findings, Size};

const LENGTH: f64 = 1.0;
const HEIGHT: f64 = 0.1;
const YOUNG: f64 = 1.0e6;
const POISSON: f64 = 0.3;
/// The end load (N): Euler–Bernoulli gives `delta = 1e-3 L`.
const LOAD: f64 = 3.0 * YOUNG * HEIGHT * HEIGHT * HEIGHT * HEIGHT / 12.0 * 1e-3 / (LENGTH * LENGTH);
const G: f64 = 9.81;
/// The relaxation's relative tolerance (the deflection changes by under 2e-5 between 1e-5 and
/// 1e-7 on the meshes measured), Chebyshev estimate (0.9999 needed a third of the iterations of
/// 0.999 here) and budget.
const TOLERANCE: f64 = 1e-5;
pub const RHO: f64 = 0.9999;
const BUDGET: u32 = 400_000;

/// Euler–Bernoulli's tip deflection (m) for the end load `LOAD`.
pub fn euler_bernoulli() -> f64 {
    let inertia = HEIGHT.powi(4) / 12.0;
    LOAD * LENGTH.powi(3) / (3.0 * YOUNG * inertia)
}

/// Timoshenko's shear term over Euler–Bernoulli's deflection, `(E / G) (h / L)^2 / (4 kappa)`.
pub fn shear_correction() -> f64 {
    let kappa = 5.0 / 6.0;
    2.0 * (1.0 + POISSON) * (HEIGHT / LENGTH).powi(2) / (4.0 * kappa)
}

/// The tributary weight of grid line `i` of `n` cells (ends half), summing to 1 over `0..=n`.
fn tributary(i: usize, n: usize) -> f64 {
    if i == 0 || i == n {
        0.5 / n as f64
    } else {
        1.0 / n as f64
    }
}

/// One solved mesh.
struct Solved {
    split: BoxSplit,
    cells: usize,
    tets: usize,
    deflection: f64,
    iterations: u32,
    converged: bool,
    seconds: f64,
}

/// The cantilever with `n` cells through the thickness (`10 n` along), its end load given as
/// the weight of masses on the end face, clamped at `x = 0`.
pub struct Cantilever {
    pub mesh: BoxMesh,
    pub masses: Vec<f64>,
    pub pinned: Vec<bool>,
}

impl Cantilever {
    pub fn new(split: BoxSplit, n: usize) -> Result<Cantilever, String> {
        let along = 10 * n;
        let mesh = BoxMesh::new(DVec3::new(LENGTH, HEIGHT, HEIGHT), [along, n, n], split)?;
        let pinned = mesh.flags(|x| x.x == 0.0);
        // Vertex (i, j, k) has index i + (along + 1) (j + (n + 1) k): the end face is i = along.
        let mut masses = vec![1e-12; mesh.rest.len()];
        for k in 0..=n {
            for j in 0..=n {
                masses[along + (along + 1) * (j + (n + 1) * k)] =
                    LOAD * tributary(j, n) * tributary(k, n) / G;
            }
        }
        Ok(Cantilever {
            mesh,
            masses,
            pinned,
        })
    }
}

/// The beam's material: stable neo-Hookean, E = 1 MPa, nu = 0.3.
pub fn material() -> Result<StableNeoHookean, String> {
    StableNeoHookean::from_young_poisson(YOUNG, POISSON).map_err(|e| e.to_string())
}

fn solve(split: BoxSplit, n: usize, rho: f64, repeats: u32) -> Result<Solved, String> {
    let Cantilever {
        mesh: beam,
        masses,
        pinned,
    } = Cantilever::new(split, n)?;
    let mut rest_data = Vec::new();
    let mesh = beam.mesh(&mut rest_data)?;
    let model = TetElastic::new(mesh, material()?);
    let scene = Scene::new(1.0).with_gravity(DVec3::new(0.0, 0.0, -G));
    let settings = RelaxSettings::new()
        .with_tolerance(TOLERANCE, BUDGET)
        .with_chebyshev(rho, 2.0, 0);
    let count = beam.rest.len();
    let (mut vectors, mut scalars) = (
        vec![DVec3::ZERO; scratch_len::relax(count)],
        vec![0.0; count],
    );
    let mut x = beam.rest.clone();
    let mut outcome = Err(String::from("not run"));
    let seconds = min_time(repeats, || {
        x.copy_from_slice(&beam.rest);
        let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
        outcome = relax_quasi_static(
            &model,
            &masses,
            &pinned,
            &scene,
            &settings,
            &mut x,
            &mut scratch,
        )
        .map_err(|e| e.to_string());
    })
    .as_secs_f64();
    let report = outcome?;
    let end: Vec<usize> = (0..count).filter(|&i| beam.rest[i].x == LENGTH).collect();
    let deflection = -end.iter().map(|&i| x[i].z - beam.rest[i].z).sum::<f64>() / end.len() as f64;
    Ok(Solved {
        split,
        cells: n,
        tets: beam.tets.len(),
        deflection,
        iterations: report.iterations,
        converged: report.converged,
        seconds,
    })
}

fn split_name(split: BoxSplit) -> &'static str {
    match split {
        BoxSplit::Kuhn6 => "6-tet split",
        BoxSplit::Alternating5 => "5-tet split",
    }
}

pub fn run(size: Size, out: &Path) -> Result<Findings, String> {
    let (resolutions, repeats): (&[usize], u32) = match size {
        Size::Quick => (&[1], 1),
        // Iterations grow about as n^2 and the cost per iteration as n^3: n = 4 would take
        // about a minute per split with this solver.
        Size::Full => (&[1, 2, 3], 1),
    };
    let theory = euler_bernoulli();
    progress(
        "convergence",
        &format!(
            "Euler-Bernoulli tip deflection {theory:.4e} m (load {LOAD:.4e} N), Timoshenko shear adds {:.2} %",
            100.0 * shear_correction()
        ),
    );
    let mut solved = Vec::new();
    for split in [BoxSplit::Alternating5, BoxSplit::Kuhn6] {
        for &n in resolutions {
            let s = solve(split, n, RHO, repeats)?;
            progress(
                "convergence",
                &format!(
                    "{}, {n} cells through the thickness ({} tets): deflection {:.4}x theory, {} iterations{}, {:.2} s",
                    split_name(split),
                    s.tets,
                    s.deflection / theory,
                    s.iterations,
                    if s.converged { "" } else { " (NOT converged)" },
                    s.seconds
                ),
            );
            solved.push(s);
        }
    }
    let mut table = Table::new(&[
        "split",
        "cells_through_thickness",
        "tets",
        "tip_deflection_m",
        "euler_bernoulli_m",
        "ratio",
        "iterations",
        "converged",
        "solve_s",
    ]);
    for s in &solved {
        table.push(vec![
            split_name(s.split).into(),
            s.cells.to_string(),
            s.tets.to_string(),
            num(s.deflection),
            num(theory),
            num(s.deflection / theory),
            s.iterations.to_string(),
            s.converged.to_string(),
            num(s.seconds),
        ]);
    }
    table.write(&out.join("convergence.csv"))?;

    let mut accuracy = Vec::new();
    let mut cost = Vec::new();
    for (color, split) in [BoxSplit::Alternating5, BoxSplit::Kuhn6]
        .into_iter()
        .enumerate()
    {
        let of: Vec<&Solved> = solved.iter().filter(|s| s.split == split).collect();
        let labels: Vec<String> = of.iter().map(|s| format!("{}", s.cells)).collect();
        accuracy.push(
            Series::new(
                split_name(split),
                Style::LinePoints,
                color,
                of.iter()
                    .map(|s| (s.tets as f64, s.deflection / theory))
                    .collect(),
            )
            .with_labels(labels.clone()),
        );
        cost.push(
            Series::new(
                split_name(split),
                Style::LinePoints,
                color,
                of.iter().map(|s| (s.tets as f64, s.seconds)).collect(),
            )
            .with_labels(labels),
        );
    }
    let span = |f: fn(&Solved) -> f64| {
        let values = solved.iter().map(f);
        (
            values.clone().fold(f64::INFINITY, f64::min),
            values.fold(0.0, f64::max),
        )
    };
    let (lo, hi) = span(|s| s.tets as f64);
    accuracy.push(Series::new(
        "Euler-Bernoulli",
        Style::Dashed,
        7,
        vec![(lo, 1.0), (hi, 1.0)],
    ));
    accuracy.push(Series::new(
        "with Timoshenko shear",
        Style::Dashed,
        6,
        vec![
            (lo, 1.0 + shear_correction()),
            (hi, 1.0 + shear_correction()),
        ],
    ));
    Figure {
        title: "Cantilever under an end load: linear tetrahedra against beam theory".into(),
        panels: vec![
            Panel::new(
                "tip deflection / P L^3 / (3 E I); L/h = 10, nu = 0.3; labels: cells through the thickness",
                Axis::log("tetrahedra"),
                Axis::linear("tip deflection / Euler-Bernoulli").with_range(0.0, 1.1),
                accuracy,
            )
            .with_legend(SeriesLabelPosition::LowerRight),
            Panel::new(
                &format!("cost of the quasi-static solve (relax_quasi_static, f64, Chebyshev, tolerance {TOLERANCE:.0e})"),
                Axis::log("tetrahedra"),
                Axis::log("solve wall time (s, one thread)"),
                cost,
            )
            .with_legend(SeriesLabelPosition::LowerRight),
        ],
    }
    .write(&out.join("convergence.svg"))?;

    let mut findings = Findings::new("convergence");
    findings.line(format!(
        "Euler-Bernoulli {theory:.4e} m; Timoshenko shear +{:.2} %",
        100.0 * shear_correction()
    ));
    for s in &solved {
        findings.line(format!(
            "{}, {} cells thick, {} tets: {:.3}x theory, {} iterations ({}), {:.2} s",
            split_name(s.split),
            s.cells,
            s.tets,
            s.deflection / theory,
            s.iterations,
            if s.converged {
                "converged"
            } else {
                "NOT converged"
            },
            s.seconds
        ));
    }
    Ok(findings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closed_forms() {
        // P L^3 / (3 E I) with the load chosen for delta = 1e-3 L.
        assert!((euler_bernoulli() - 1e-3 * LENGTH).abs() < 1e-15);
        // (E / G) (h / L)^2 / (4 kappa) = 2.6 * 0.01 / (10/3) = 0.0078.
        assert!((shear_correction() - 0.0078).abs() < 1e-12);
        let total: f64 = (0..=4).map(|i| tributary(i, 4)).sum();
        assert!((total - 1.0).abs() < 1e-15);
    }
}

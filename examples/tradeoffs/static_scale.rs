//! `--static-scale`: the static-solve scale check. The convergence chart's quasi-static
//! cantilever (1 m x 0.1 m x 0.1 m, stable neo-Hookean E = 1 MPa, nu = 0.3, end load for a
//! deflection of 1e-3 m, clamped at x = 0) with 6 cells through the thickness, 5-tet split:
//! 60 x 6 x 6 cells, 10 800 tets (f64, one thread). Newton (`newton_quasi_static`, budget 50
//! Newton iterations) solves it from rest to relative residual 1e-8, once with its default CG
//! budget (automatic: `max(2000, 250 cbrt(free vertices))` CG iterations per Newton iteration
//! with block Jacobi) and once with 200; then, in the same run, the
//! relaxation (`relax_quasi_static`, Chebyshev with the convergence chart's `rho`) is given
//! the iterations that fit in the time of the faster converged Newton run (its cost per
//! iteration measured by a short run first) and its relative residual is reported beside.
//!
//! Times are the thread's CPU time (the machine may be loaded); wall times are in the CSV too.

use std::path::Path;
use std::time::Instant;

use softfem::f64::element::TetHessian;
use softfem::f64::generate::BoxSplit;
use softfem::f64::step::{
    NewtonScratch, NewtonSettings, RelaxScratch, RelaxSettings, Scene, TetElastic,
    newton_quasi_static, relax_quasi_static, scratch_len,
};
use softfem::glam::{DMat3, DVec3};

use crate::chart::{Table, num};
use crate::convergence::{Cantilever, RHO, material};
use crate::descent::{thread_cpu_seconds, weight};
use crate::measure::progress;
use crate::{Findings, Size};

/// Newton's tolerance (relative residual).
const NEWTON_TOLERANCE: f64 = 1e-8;
/// Newton's iteration budget.
const NEWTON_ITERATIONS: u32 = 50;
/// A CG budget per Newton iteration ten times smaller than `NewtonSettings`' default, tried
/// beside it (the slender 60-cell beam needs more than 200 for a good direction).
const SMALL_CG: u32 = 200;

/// One solve: what it reached and what it cost.
struct Solve {
    solver: &'static str,
    /// Newton's CG budget per Newton iteration; 0 for the relaxation.
    max_cg: u32,
    iterations: u32,
    cg_iterations: u32,
    relative_residual: f64,
    converged: bool,
    cpu_seconds: f64,
    wall_seconds: f64,
}

/// `work` timed by wall clock and by this thread's CPU time (NaN CPU time: the wall time).
fn timed<T>(work: impl FnOnce() -> T) -> (T, f64, f64) {
    let (started, cpu_started) = (Instant::now(), thread_cpu_seconds());
    let result = work();
    let wall = started.elapsed().as_secs_f64();
    let cpu = thread_cpu_seconds() - cpu_started;
    (result, if cpu.is_finite() { cpu } else { wall }, wall)
}

pub fn run(size: Size, out: &Path) -> Result<Findings, String> {
    let cells = match size {
        Size::Quick => 2,
        Size::Full => 6,
    };
    let beam = Cantilever::new(BoxSplit::Alternating5, cells)?;
    let mut rest_data = Vec::new();
    let mesh = beam.mesh.mesh(&mut rest_data)?;
    let model = TetElastic::new(mesh, material()?);
    let (n, elements) = (beam.mesh.rest.len(), mesh.element_count());
    let scene = Scene::new(1.0).with_gravity(DVec3::new(0.0, 0.0, -crate::descent::G));
    let scale = weight(&beam.masses, &beam.pinned);
    progress(
        "static-scale",
        &format!("cantilever: {elements} tets, {n} vertices; Newton to {NEWTON_TOLERANCE:.0e}"),
    );

    let len = scratch_len::newton(n, elements);
    let (mut vectors, mut blocks, mut hessians) = (
        vec![DVec3::ZERO; len.vectors],
        vec![DMat3::ZERO; len.blocks],
        vec![TetHessian::default(); len.hessians],
    );
    let mut newton = |max_cg: u32| -> Result<Solve, String> {
        let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
        let settings = NewtonSettings::new()
            .with_tolerance(NEWTON_TOLERANCE, NEWTON_ITERATIONS)
            .with_cg_iterations(max_cg);
        let mut x = beam.mesh.rest.clone();
        let (report, cpu, wall) = timed(|| {
            newton_quasi_static(
                &model,
                &beam.masses,
                &beam.pinned,
                &scene,
                &settings,
                &mut x,
                &mut scratch,
            )
        });
        let report = report.map_err(|e| e.to_string())?;
        let solve = Solve {
            solver: if max_cg == SMALL_CG {
                "newton_200_cg"
            } else {
                "newton"
            },
            // The budget the solve used (the default is the automatic one, chosen by size).
            max_cg: report.details.cg_budget,
            iterations: report.iterations,
            cg_iterations: report.details.cg_iterations,
            relative_residual: report.residual / report.initial_residual.max(scale),
            converged: report.converged,
            cpu_seconds: cpu,
            wall_seconds: wall,
        };
        progress(
            "static-scale",
            &format!(
                "Newton ({} CG a Newton iteration at most): {} in {} Newton and {} CG iterations, relative residual {:.2e}, {:.2} s CPU ({:.2} s wall)",
                solve.max_cg,
                if solve.converged {
                    "converged"
                } else {
                    "NOT converged"
                },
                solve.iterations,
                solve.cg_iterations,
                solve.relative_residual,
                solve.cpu_seconds,
                solve.wall_seconds
            ),
        );
        Ok(solve)
    };
    let default_cg = NewtonSettings::new().options.max_cg_iterations;
    let newtons = [newton(default_cg)?, newton(SMALL_CG)?];
    // The relaxation gets the time of the fastest converged Newton run (else the last one).
    let reference = newtons
        .iter()
        .filter(|s| s.converged)
        .min_by(|a, b| a.cpu_seconds.total_cmp(&b.cpu_seconds))
        .unwrap_or(&newtons[0]);
    let newton_seconds = reference.cpu_seconds;

    let (mut relax_vectors, mut relax_scalars) =
        (vec![DVec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
    let mut relax = |iterations: u32| -> Result<Solve, String> {
        let mut scratch = RelaxScratch::new(&mut relax_vectors, &mut relax_scalars);
        let settings = RelaxSettings::new()
            .with_tolerance(0.0, iterations)
            .with_chebyshev(RHO, 2.0, 0);
        let mut x = beam.mesh.rest.clone();
        let (report, cpu, wall) = timed(|| {
            relax_quasi_static(
                &model,
                &beam.masses,
                &beam.pinned,
                &scene,
                &settings,
                &mut x,
                &mut scratch,
            )
        });
        let report = report.map_err(|e| e.to_string())?;
        Ok(Solve {
            solver: "relax_chebyshev",
            max_cg: 0,
            iterations: report.iterations,
            cg_iterations: 0,
            relative_residual: report.residual / report.initial_residual.max(scale),
            converged: report.converged,
            cpu_seconds: cpu,
            wall_seconds: wall,
        })
    };
    let calibration = relax(200)?;
    let per_iteration = calibration.cpu_seconds / f64::from(calibration.iterations.max(1));
    let budget = ((newton_seconds / per_iteration).round() as u32).max(1);
    progress(
        "static-scale",
        &format!(
            "relaxation: {:.1} us an iteration, so {budget} iterations in Newton's time",
            per_iteration * 1e6
        ),
    );
    let matched = relax(budget)?;
    progress(
        "static-scale",
        &format!(
            "relaxation: {} iterations, relative residual {:.2e}, {:.2} s CPU ({:.2} s wall)",
            matched.iterations,
            matched.relative_residual,
            matched.cpu_seconds,
            matched.wall_seconds
        ),
    );

    let mut table = Table::new(&[
        "solver",
        "tets",
        "max_iterations",
        "max_cg_per_iteration",
        "iterations",
        "cg_iterations",
        "relative_residual",
        "converged",
        "cpu_s",
        "wall_s",
    ]);
    let rows = newtons
        .iter()
        .map(|s| (s, NEWTON_ITERATIONS))
        .chain([(&matched, budget)]);
    for (solve, max_iterations) in rows {
        table.push(vec![
            solve.solver.to_string(),
            elements.to_string(),
            max_iterations.to_string(),
            solve.max_cg.to_string(),
            solve.iterations.to_string(),
            solve.cg_iterations.to_string(),
            num(solve.relative_residual),
            solve.converged.to_string(),
            num(solve.cpu_seconds),
            num(solve.wall_seconds),
        ]);
    }
    table.write(&out.join("static_scale.csv"))?;

    let mut findings = Findings::new("static-scale");
    for newton in &newtons {
        findings.line(format!(
            "{elements}-tet cantilever, Newton to {NEWTON_TOLERANCE:.0e} with at most {} CG a Newton iteration: {} in {} Newton ({} CG) iterations, {:.2} s CPU, relative residual {:.2e}",
            newton.max_cg,
            if newton.converged { "converged" } else { "NOT converged" },
            newton.iterations,
            newton.cg_iterations,
            newton.cpu_seconds,
            newton.relative_residual
        ));
    }
    findings.line(format!(
        "relaxation (Chebyshev rho {RHO}) in the same time: {} iterations, {:.2} s CPU, relative residual {:.2e}",
        matched.iterations, matched.cpu_seconds, matched.relative_residual
    ));
    Ok(findings)
}

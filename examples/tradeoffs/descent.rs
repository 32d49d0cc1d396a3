//! Chart `descent`: one descent loop, five preconditioners `P`, measured against each other —
//! residual against wall time and against iterations on three scenes, with the cost of an
//! iteration in force evaluations measured in the same run.
//!
//! The solvers (all `softfem::f64::step`, one thread) minimise the same objective with the same
//! stopping test, `|grad Phi| <= tolerance * max(|grad Phi(x_0)|, |M g|)`, so their relative
//! residuals compare directly:
//! * GD (`P = c I`): `gradient_descent_step` / `gradient_descent_quasi_static`, `c` the
//!   largest entry of the diagonal bound, first trial step 2 (in units of `1 / c`), no
//!   acceleration: the baseline of the family. It is slow, so its budget is capped (the
//!   relaxation's budget on each scene); a run that does not reach the tolerance says so in
//!   the CSV (`converged` false) and in the legend;
//! * GD plain: `relax_step` / `relax_quasi_static` without acceleration, `P` the diagonal
//!   stiffness bound, first trial step 2 (the bound's safe step, `RelaxOptions::step_length`);
//! * GD + Chebyshev: the same with Chebyshev acceleration (`rho = 0.995` for time steps, the
//!   convergence chart's 0.9999 for the static solve);
//! * VBD: `vbd_step` / `vbd_quasi_static` without the per-vertex line search, Chebyshev with
//!   `rho = 0.95` after 2 plain sweeps (the bouncy example's settings; on the bouncy and stiff
//!   scenes 41 and 31 sweeps where the `rho` it estimates from 4 plain sweeps took 111 and 81),
//!   with the packed sweep layout (`VbdScratch::with_layout`);
//! * Newton: `newton_step` / `newton_quasi_static` with its defaults (block-Jacobi CG, forcing
//!   term, 200 CG iterations per Newton iteration).
//!
//! No solver exposes its residual history, so the history is measured from outside: each solver
//! runs from the same state with a budget of `k` iterations and tolerance 0, for a geometric
//! sequence of `k` (the runs are deterministic, so run `k` is the first `k` iterations of any
//! longer run), and each run's final relative residual and time is one point. The time of a
//! solve under 20 ms is the least wall time of six runs; a longer solve's is the thread's CPU
//! time, which a loaded machine does not inflate (the CSV gives its wall time too). A force
//! evaluation (`energy_and_add_forces`, the fused energy-and-force pass every solver uses) is
//! timed in the same run (least of 30), and every cost is also given in force evaluations.
//!
//! Scenes (f64):
//! * the bouncy cube: the example's default jelly cube (0.2 m, 6^3 cells of 5 tets, stable
//!   neo-Hookean E = 50 kPa, nu = 0.45, 1000 kg/m^3) dropped from 0.5 m onto the ground
//!   (friction 0.6) at 1/60 s; the step measured is the one whose initial residual is the
//!   largest of the first 0.7 s (the landing), reached by Newton steps at tolerance 1e-8;
//! * the stiff block: 0.1 x 0.05 x 0.05 m in 4 x 2 x 2 cubes of 6 tets (96), stable
//!   neo-Hookean E = 1e8 Pa, nu = 0.3, 1000 kg/m^3, clamped at x = 0, under gravity, the
//!   first 1/30 s step from rest with every free vertex moved by up to 1e-3 of a cell (a fixed
//!   pseudo-random pattern);
//! * the quasi-static cantilever of the convergence chart (1 m x 0.1 m x 0.1 m, 2 cells through
//!   the thickness, 5-tet split, 400 tets, E = 1 MPa, nu = 0.3, end load for a deflection of
//!   1e-3 m), solved from rest.

use std::path::Path;
use std::time::Instant;

use plotters::chart::SeriesLabelPosition;
use softfem::f64::element::TetHessian;
use softfem::f64::generate::BoxSplit;
use softfem::f64::material::StableNeoHookean;
use softfem::f64::step::{
    ElasticEnergy, HalfSpace, NewtonScratch, NewtonSettings, RelaxScratch, RelaxSettings,
    Scene as StepScene, TetElastic, VbdScratch, VbdSettings, gradient_descent_quasi_static,
    gradient_descent_step, newton_quasi_static, newton_step, relax_quasi_static, relax_step,
    scratch_len, vbd_quasi_static, vbd_step,
};
use softfem::glam::{DMat3, DVec3};

use crate::chart::{Axis, Figure, Panel, Series, Style, Table, num};
use crate::double::body::{BoxMesh, masses};
use crate::measure::{min_time, progress};
use crate::{Findings, Size};

pub const G: f64 = 9.81;

/// The four preconditioners, in the order they are drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Solver {
    GdIdentity,
    GdPlain,
    GdChebyshev,
    Vbd,
    Newton,
}

const SOLVERS: [Solver; 5] = [
    Solver::GdIdentity,
    Solver::GdPlain,
    Solver::GdChebyshev,
    Solver::Vbd,
    Solver::Newton,
];

impl Solver {
    fn name(self) -> &'static str {
        match self {
            Solver::GdIdentity => "GD (P = c I)",
            Solver::GdPlain => "GD plain (P = diagonal bound)",
            Solver::GdChebyshev => "GD + Chebyshev",
            Solver::Vbd => "VBD (Chebyshev 0.95)",
            Solver::Newton => "Newton-PCG",
        }
    }

    fn short(self) -> &'static str {
        match self {
            Solver::GdIdentity => "gd_identity",
            Solver::GdPlain => "gd_plain",
            Solver::GdChebyshev => "gd_chebyshev",
            Solver::Vbd => "vbd",
            Solver::Newton => "newton",
        }
    }
}

/// One scene: the body, its start state and how it is solved.
struct Scene<'a> {
    name: &'static str,
    model: TetElastic<'a, StableNeoHookean>,
    masses: &'a [f64],
    pinned: &'a [bool],
    ground: Option<HalfSpace<DVec3>>,
    /// The time step (s); `None`: the quasi-static solve.
    dt: Option<f64>,
    positions: &'a [DVec3],
    velocities: &'a [DVec3],
    /// Chebyshev's `rho` for GD + Chebyshev.
    rho: f64,
    /// The tolerance of the iterations-to-tolerance column.
    tolerance: f64,
    /// Per solver (in [`SOLVERS`] order): the largest `k` of the sweep and the budget of the
    /// run to tolerance.
    budgets: [u32; 5],
}

/// What one solve did.
#[derive(Clone, Copy, Debug)]
struct Outcome {
    iterations: u32,
    /// Newton's CG iterations; 0 for the others.
    cg_iterations: u32,
    energy_evaluations: u32,
    relative_residual: f64,
    converged: bool,
    /// The solve's time (s): the least wall time of six runs for a solve under 20 ms, else the
    /// thread's CPU time of its one run (see [`thread_cpu_seconds`]).
    seconds: f64,
    /// The wall time of the (first) run (s), load included.
    wall_seconds: f64,
}

/// The CPU time this thread has run (s): the first field of Linux's
/// `/proc/thread-self/schedstat` (ns), NaN where there is none. It is updated at the
/// scheduler's ticks and switches, so a reading can lag by a tick (a few ms): used only for
/// solves far longer than that, where the least wall time of a loaded machine (2 cores, load
/// average 8 to 10 when the committed chart was made) would count other processes' time.
pub fn thread_cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |ns| ns * 1e-9)
}

/// The norm of the gravity load on the free vertices (N): the solvers' scale for the tolerance.
pub fn weight(masses: &[f64], pinned: &[bool]) -> f64 {
    masses
        .iter()
        .enumerate()
        .filter(|(i, _)| !pinned.get(*i).copied().unwrap_or(false))
        .map(|(_, m)| (m * G).powi(2))
        .sum::<f64>()
        .sqrt()
}

impl Scene<'_> {
    /// Runs `solver` from the scene's state with `max_iterations` and `tolerance`; timed as the
    /// fastest of five more runs when one takes under 20 ms (the runs do identical work), by
    /// the thread's CPU time otherwise.
    fn solve(
        &self,
        solver: Solver,
        max_iterations: u32,
        tolerance: f64,
    ) -> Result<Outcome, String> {
        let n = self.positions.len();
        let gravity = DVec3::new(0.0, 0.0, -G);
        let scale = weight(self.masses, self.pinned);
        let (mut x, mut v) = (self.positions.to_vec(), self.velocities.to_vec());
        let dt = self.dt.unwrap_or(1.0);
        // What every solve acts on (the quasi-static solves ignore its `dt`).
        let mut step_scene = StepScene::new(dt).with_gravity(gravity);
        step_scene.ground = self.ground;
        // Scratch kept over the repeats, as a time loop keeps it: the relaxation's
        // preconditioner and VBD's colouring are built by the first run only.
        let elements = self.model.mesh.element_count();
        let (mut relax_vectors, mut relax_scalars) =
            (vec![DVec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
        let mut relax_scratch = RelaxScratch::new(&mut relax_vectors, &mut relax_scalars);
        let mut vbd_vectors = vec![DVec3::ZERO; scratch_len::vbd(n)];
        let mut vbd_indices = vec![0; scratch_len::vbd_indices(n, elements)];
        let mut vbd_values = vec![0.0; scratch_len::vbd_layout(elements)];
        let mut vbd_corners = vec![0; scratch_len::vbd_layout_corners(n, elements)];
        let mut vbd_scratch = VbdScratch::new(&mut vbd_vectors, &mut vbd_indices)
            .with_layout(&mut vbd_values, &mut vbd_corners);
        let len = scratch_len::newton(n, elements);
        let mut newton_vectors = vec![DVec3::ZERO; len.vectors];
        let mut blocks = vec![DMat3::ZERO; len.blocks];
        let mut hessians = vec![TetHessian::default(); len.hessians];
        let mut newton_scratch =
            NewtonScratch::new(&mut newton_vectors, &mut blocks, &mut hessians);
        let mut once = |x: &mut Vec<DVec3>, v: &mut Vec<DVec3>| -> Result<Outcome, String> {
            x.copy_from_slice(self.positions);
            v.copy_from_slice(self.velocities);
            let (started, cpu_started) = (Instant::now(), thread_cpu_seconds());
            let (model, m, pinned) = (&self.model, self.masses, self.pinned);
            let mut result = match solver {
                Solver::GdIdentity | Solver::GdPlain | Solver::GdChebyshev => {
                    let rho = if solver == Solver::GdChebyshev {
                        self.rho
                    } else {
                        0.0
                    };
                    let settings = RelaxSettings::new()
                        .with_tolerance(tolerance, max_iterations)
                        .with_chebyshev(rho, 2.0, 0);
                    let scratch = &mut relax_scratch;
                    let report = match (self.dt, solver) {
                        (Some(_), Solver::GdIdentity) => gradient_descent_step(
                            model,
                            m,
                            pinned,
                            &step_scene,
                            &settings,
                            x,
                            v,
                            scratch,
                        ),
                        (None, Solver::GdIdentity) => gradient_descent_quasi_static(
                            model,
                            m,
                            pinned,
                            &step_scene,
                            &settings,
                            x,
                            scratch,
                        ),
                        (Some(_), _) => {
                            relax_step(model, m, pinned, &step_scene, &settings, x, v, scratch)
                        }
                        (None, _) => {
                            relax_quasi_static(model, m, pinned, &step_scene, &settings, x, scratch)
                        }
                    }
                    .map_err(|e| e.to_string())?;
                    Outcome {
                        iterations: report.iterations,
                        cg_iterations: 0,
                        energy_evaluations: report.energy_evaluations,
                        relative_residual: report.residual / report.initial_residual.max(scale),
                        converged: report.converged,
                        seconds: 0.0,
                        wall_seconds: 0.0,
                    }
                }
                Solver::Vbd => {
                    let settings = VbdSettings::new()
                        .with_tolerance(tolerance, max_iterations)
                        .with_line_search(0)
                        .with_chebyshev(0.95, 2);
                    let scratch = &mut vbd_scratch;
                    let report = match self.dt {
                        Some(_) => {
                            vbd_step(model, m, pinned, &step_scene, &settings, x, v, scratch)
                        }
                        None => {
                            vbd_quasi_static(model, m, pinned, &step_scene, &settings, x, scratch)
                        }
                    }
                    .map_err(|e| e.to_string())?;
                    Outcome {
                        iterations: report.iterations,
                        cg_iterations: 0,
                        energy_evaluations: report.energy_evaluations,
                        relative_residual: report.residual / report.initial_residual.max(scale),
                        converged: report.converged,
                        seconds: 0.0,
                        wall_seconds: 0.0,
                    }
                }
                Solver::Newton => {
                    let settings = NewtonSettings::new().with_tolerance(tolerance, max_iterations);
                    let scratch = &mut newton_scratch;
                    let report = match self.dt {
                        Some(_) => {
                            newton_step(model, m, pinned, &step_scene, &settings, x, v, scratch)
                        }
                        None => newton_quasi_static(
                            model,
                            m,
                            pinned,
                            &step_scene,
                            &settings,
                            x,
                            scratch,
                        ),
                    }
                    .map_err(|e| e.to_string())?;
                    Outcome {
                        iterations: report.iterations,
                        cg_iterations: report.details.cg_iterations,
                        energy_evaluations: report.energy_evaluations,
                        relative_residual: report.residual / report.initial_residual.max(scale),
                        converged: report.converged,
                        seconds: 0.0,
                        wall_seconds: 0.0,
                    }
                }
            };
            result.wall_seconds = started.elapsed().as_secs_f64();
            let cpu = thread_cpu_seconds() - cpu_started;
            result.seconds = if result.wall_seconds < 0.02 || !cpu.is_finite() {
                result.wall_seconds
            } else {
                cpu
            };
            Ok(result)
        };
        let first = once(&mut x, &mut v)?;
        let mut best = first;
        if first.wall_seconds < 0.02 {
            for _ in 0..5 {
                let again = once(&mut x, &mut v)?;
                best.seconds = best.seconds.min(again.wall_seconds);
            }
        }
        Ok(best)
    }

    /// The fastest of 30 fused energy-and-force passes at the scene's start positions (s).
    fn force_evaluation_seconds(&self) -> Result<f64, String> {
        let mut forces = vec![DVec3::ZERO; self.positions.len()];
        let mut result = Ok(0.0);
        let seconds = min_time(30, || {
            forces.fill(DVec3::ZERO);
            result = self
                .model
                .energy_and_add_forces(self.positions, &mut forces);
        });
        result.map_err(|e| e.to_string())?;
        Ok(seconds.as_secs_f64())
    }
}

/// `1, 2, 3, 5, 8, 12, ...` (each at least 1.5 times the last, rounded up) up to `largest`,
/// which ends the sequence.
fn budgets(largest: u32) -> Vec<u32> {
    let mut ks = vec![1];
    while let Some(&k) = ks.last() {
        if k >= largest {
            break;
        }
        let next = ((f64::from(k) * 1.5).ceil() as u32).max(k + 1).min(largest);
        ks.push(next);
    }
    ks
}

/// One measured point of a residual history.
struct Point {
    scene: &'static str,
    solver: Solver,
    budget: u32,
    outcome: Outcome,
}

/// A scene's results.
struct Measured {
    scene: &'static str,
    force_seconds: f64,
    history: Vec<Point>,
    /// Per solver: its budget for the run to tolerance and what that run did.
    to_tolerance: Vec<(Solver, u32, Outcome)>,
    tolerance: f64,
}

impl Measured {
    /// The solver's legend entry: its name, and "NOT converged in N" when its run to the
    /// tolerance ran out of budget.
    fn legend(&self, solver: Solver) -> String {
        match self.to_tolerance.iter().find(|(s, _, _)| *s == solver) {
            Some((_, _, o)) if !o.converged => {
                format!("{} (NOT converged in {})", solver.name(), o.iterations)
            }
            _ => solver.name().to_string(),
        }
    }
}

/// The smallest relative residual the sweep goes for: f64's floor is far below it on every
/// scene, and nothing on the chart needs less.
const FLOOR: f64 = 1e-11;

fn measure(scene: &Scene<'_>, time_cap: f64) -> Result<Measured, String> {
    let force_seconds = scene.force_evaluation_seconds()?;
    progress(
        "descent",
        &format!(
            "{}: a force evaluation takes {:.1} us",
            scene.name,
            force_seconds * 1e6
        ),
    );
    let mut history = Vec::new();
    let mut to_tolerance = Vec::new();
    for (solver, &largest) in SOLVERS.iter().zip(&scene.budgets) {
        for k in budgets(largest) {
            let outcome = scene.solve(*solver, k, 0.0)?;
            history.push(Point {
                scene: scene.name,
                solver: *solver,
                budget: k,
                outcome,
            });
            // A solver that stopped before its budget (Newton at the rounding floor) has
            // nothing more to show; nor has one at the floor or past the time cap.
            if outcome.iterations < k
                || outcome.relative_residual <= FLOOR
                || outcome.seconds > time_cap
            {
                break;
            }
        }
        let outcome = scene.solve(*solver, largest, scene.tolerance)?;
        progress(
            "descent",
            &format!(
                "{}, {}: to {:.0e} in {} iterations{} ({}), {:.2e} s = {:.0} force evaluations",
                scene.name,
                solver.name(),
                scene.tolerance,
                outcome.iterations,
                if *solver == Solver::Newton {
                    format!(" and {} CG iterations", outcome.cg_iterations)
                } else {
                    String::new()
                },
                if outcome.converged {
                    "converged"
                } else {
                    "NOT converged"
                },
                outcome.seconds,
                outcome.seconds / force_seconds
            ),
        );
        to_tolerance.push((*solver, largest, outcome));
    }
    Ok(Measured {
        scene: scene.name,
        force_seconds,
        history,
        to_tolerance,
        tolerance: scene.tolerance,
    })
}

/// The bouncy cube at its landing step, measured.
fn bouncy(size: Size) -> Result<Measured, String> {
    let cells = match size {
        Size::Quick => 2,
        Size::Full => 6,
    };
    let mut cube = BoxMesh::new(DVec3::splat(0.2), [cells; 3], BoxSplit::Alternating5)?;
    for p in &mut cube.rest {
        *p += DVec3::new(-0.1, -0.1, 0.5);
    }
    let mut rest_data = Vec::new();
    let mesh = cube.mesh(&mut rest_data)?;
    let masses = masses(&mesh, 1000.0)?;
    let material = StableNeoHookean::from_young_poisson(5.0e4, 0.45).map_err(|e| e.to_string())?;
    let model = TetElastic::new(mesh, material);
    let ground = HalfSpace::new(DVec3::Z, 0.0).with_friction(0.6);
    let dt = 1.0 / 60.0;
    // Newton's trajectory to the landing: the state before the step with the largest initial
    // residual.
    let n = cube.rest.len();
    let step_scene = StepScene::new(dt)
        .with_gravity(DVec3::new(0.0, 0.0, -G))
        .with_ground(ground);
    let settings = NewtonSettings::new().with_tolerance(1e-8, 50);
    let len = scratch_len::newton(n, mesh.element_count());
    let (mut vectors, mut blocks, mut hessians) = (
        vec![DVec3::ZERO; len.vectors],
        vec![DMat3::ZERO; len.blocks],
        vec![TetHessian::default(); len.hessians],
    );
    let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
    let (mut x, mut v) = (cube.rest.clone(), vec![DVec3::ZERO; n]);
    let mut worst = (0.0, x.clone(), v.clone(), 0);
    let scale = weight(&masses, &[]);
    for step in 0..42 {
        let (x0, v0) = (x.clone(), v.clone());
        let report = newton_step(
            &model,
            &masses,
            &[],
            &step_scene,
            &settings,
            &mut x,
            &mut v,
            &mut scratch,
        )
        .map_err(|e| e.to_string())?;
        let relative = report.initial_residual / scale;
        if relative > worst.0 {
            worst = (relative, x0, v0, step);
        }
    }
    progress(
        "descent",
        &format!(
            "bouncy cube: step {} (t = {:.3} s) has the largest initial residual, {:.2} of the weight",
            worst.3 + 1,
            worst.3 as f64 * dt,
            worst.0
        ),
    );
    let scene = Scene {
        name: "bouncy cube",
        model,
        masses: &masses,
        pinned: &[],
        ground: Some(ground),
        dt: Some(dt),
        positions: &worst.1,
        velocities: &worst.2,
        rho: 0.995,
        tolerance: 1e-4,
        budgets: match size {
            Size::Quick => [300, 300, 300, 100, 30],
            Size::Full => [3000, 3000, 3000, 1000, 50],
        },
    };
    measure(&scene, time_cap(size))
}

/// The stiff block, clamped at x = 0, first step of 1/30 s from a perturbed rest.
fn stiff_block(size: Size) -> Result<Measured, String> {
    let block = BoxMesh::new(DVec3::new(0.1, 0.05, 0.05), [4, 2, 2], BoxSplit::Kuhn6)?;
    let mut rest_data = Vec::new();
    let mesh = block.mesh(&mut rest_data)?;
    let masses = masses(&mesh, 1000.0)?;
    let material = StableNeoHookean::from_young_poisson(1.0e8, 0.3).map_err(|e| e.to_string())?;
    let model = TetElastic::new(mesh, material);
    let pinned = block.flags(|p| p.x == 0.0);
    // A fixed pattern of offsets up to 1e-3 of the 2.5 cm cell (a linear congruential
    // generator: the same numbers on every machine).
    let mut seed: u64 = 3;
    let mut unit = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let amplitude = 2.0 * 1e-3 * 0.025;
    let x: Vec<DVec3> = block
        .rest
        .iter()
        .zip(&pinned)
        .map(|(&p, &fixed)| {
            let offset = DVec3::new(unit(), unit(), unit()) * amplitude;
            if fixed { p } else { p + offset }
        })
        .collect();
    let v = vec![DVec3::ZERO; x.len()];
    let scene = Scene {
        name: "stiff block",
        model,
        masses: &masses,
        pinned: &pinned,
        ground: None,
        dt: Some(1.0 / 30.0),
        positions: &x,
        velocities: &v,
        rho: 0.995,
        tolerance: 1e-4,
        budgets: match size {
            Size::Quick => [1000, 1000, 1000, 300, 30],
            Size::Full => [30000, 30000, 10000, 5000, 50],
        },
    };
    measure(&scene, time_cap(size))
}

/// The convergence chart's cantilever, solved quasi-statically from rest.
fn cantilever(size: Size) -> Result<Measured, String> {
    let cells = match size {
        Size::Quick => 1,
        Size::Full => 2,
    };
    let beam = crate::convergence::Cantilever::new(BoxSplit::Alternating5, cells)?;
    let mut rest_data = Vec::new();
    let mesh = beam.mesh.mesh(&mut rest_data)?;
    let material = crate::convergence::material()?;
    let model = TetElastic::new(mesh, material);
    let v = vec![DVec3::ZERO; beam.mesh.rest.len()];
    let scene = Scene {
        name: "cantilever (static)",
        model,
        masses: &beam.masses,
        pinned: &beam.pinned,
        ground: None,
        dt: None,
        positions: &beam.mesh.rest,
        velocities: &v,
        rho: crate::convergence::RHO,
        tolerance: 1e-6,
        budgets: match size {
            Size::Quick => [3000, 3000, 3000, 1000, 30],
            Size::Full => [300_000, 300_000, 200_000, 20_000, 50],
        },
    };
    measure(&scene, time_cap(size))
}

/// No single run of the sweep is allowed much longer than this (s): the sweep stops after it.
fn time_cap(size: Size) -> f64 {
    match size {
        Size::Quick => 0.2,
        Size::Full => 3.0,
    }
}

pub fn run(size: Size, out: &Path) -> Result<Findings, String> {
    let scenes = [bouncy(size)?, stiff_block(size)?, cantilever(size)?];

    let mut table = Table::new(&[
        "scene",
        "solver",
        "run",
        "max_iterations",
        "tolerance",
        "iterations",
        "cg_iterations",
        "energy_evaluations",
        "relative_residual",
        "converged",
        "time_s",
        "wall_s",
        "force_evaluation_s",
        "cost_force_evaluations",
        "cost_per_iteration_force_evaluations",
    ]);
    let row =
        |scene: &Measured, solver: Solver, run: &str, budget: u32, tolerance: f64, o: &Outcome| {
            vec![
                scene.scene.to_string(),
                solver.short().to_string(),
                run.to_string(),
                budget.to_string(),
                num(tolerance),
                o.iterations.to_string(),
                o.cg_iterations.to_string(),
                o.energy_evaluations.to_string(),
                num(o.relative_residual),
                o.converged.to_string(),
                num(o.seconds),
                num(o.wall_seconds),
                num(scene.force_seconds),
                num(o.seconds / scene.force_seconds),
                num(o.seconds / scene.force_seconds / f64::from(o.iterations.max(1))),
            ]
        };
    for scene in &scenes {
        for point in &scene.history {
            debug_assert_eq!(point.scene, scene.scene);
            table.push(row(
                scene,
                point.solver,
                "history",
                point.budget,
                0.0,
                &point.outcome,
            ));
        }
        for (solver, budget, outcome) in &scene.to_tolerance {
            table.push(row(
                scene,
                *solver,
                "to_tolerance",
                *budget,
                scene.tolerance,
                outcome,
            ));
        }
    }
    table.write(&out.join("descent.csv"))?;

    let mut panels = Vec::new();
    for scene in &scenes {
        let series = |x: fn(&Outcome, f64) -> f64| -> Vec<Series> {
            SOLVERS
                .iter()
                .enumerate()
                .map(|(color, solver)| {
                    let points = scene
                        .history
                        .iter()
                        .filter(|p| p.solver == *solver)
                        .map(|p| {
                            (
                                x(&p.outcome, scene.force_seconds),
                                p.outcome.relative_residual,
                            )
                        })
                        .collect();
                    Series::new(&scene.legend(*solver), Style::LinePoints, color, points)
                })
                .chain(std::iter::once(Series::new(
                    &format!("tolerance {:.0e}", scene.tolerance),
                    Style::Dashed,
                    6,
                    Vec::new(),
                )))
                .collect()
        };
        let with_tolerance_line = |mut series: Vec<Series>| {
            let xs = series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.0))
                .filter(|x| *x > 0.0);
            let (lo, hi) = xs.fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            });
            if let Some(line) = series.last_mut() {
                line.points = vec![(lo, scene.tolerance), (hi, scene.tolerance)];
            }
            series
        };
        panels.push(
            Panel::new(
                &format!(
                    "{}: residual against time (a force evaluation = {:.1} us)",
                    scene.scene,
                    scene.force_seconds * 1e6
                ),
                Axis::log("time of the solve (s, one thread; CPU time above 20 ms)"),
                Axis::log("relative residual |grad Phi| / max(|grad Phi_0|, |Mg|)"),
                with_tolerance_line(series(|o, _| o.seconds)),
            )
            .with_legend(SeriesLabelPosition::LowerLeft),
        );
        panels.push(
            Panel::new(
                &format!(
                    "{}: residual against iterations (Newton: Newton iterations)",
                    scene.scene
                ),
                Axis::log("iterations (sweeps for VBD)"),
                Axis::log("relative residual"),
                with_tolerance_line(series(|o, _| f64::from(o.iterations.max(1)))),
            )
            .with_legend(SeriesLabelPosition::LowerLeft),
        );
    }
    Figure {
        title: "One descent loop, five preconditioners: residual against cost (f64)".into(),
        panels,
    }
    .write(&out.join("descent.svg"))?;

    let mut findings = Findings::new("descent");
    for scene in &scenes {
        for (solver, _, o) in &scene.to_tolerance {
            findings.line(format!(
                "{}, {}: tolerance {:.0e} {} in {} iterations{}, {:.3e} s ({:.0} force evaluations, {:.1} per iteration)",
                scene.scene,
                solver.name(),
                scene.tolerance,
                if o.converged { "reached" } else { "NOT reached" },
                o.iterations,
                if *solver == Solver::Newton {
                    format!(" ({} CG)", o.cg_iterations)
                } else {
                    String::new()
                },
                o.seconds,
                o.seconds / scene.force_seconds,
                o.seconds / scene.force_seconds / f64::from(o.iterations.max(1))
            ));
        }
    }
    Ok(findings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_grow_geometrically_and_end_at_the_largest() {
        assert_eq!(budgets(1), [1]);
        assert_eq!(budgets(20), [1, 2, 3, 5, 8, 12, 18, 20]);
        let long = budgets(100_000);
        assert_eq!(long.last(), Some(&100_000));
        assert!(long.windows(2).all(|w| w[1] > w[0]));
        assert!(long.len() < 40, "{}", long.len());
    }

    #[test]
    fn the_weight_leaves_out_pinned_vertices() {
        let masses = [1.0, 2.0, 2.0];
        assert!((weight(&masses, &[]) - 3.0 * G).abs() < 1e-12);
        assert!((weight(&masses, &[false, true, false]) - G * 5f64.sqrt()).abs() < 1e-12);
    }
}

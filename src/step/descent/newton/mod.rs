//! Newton's method for implicit Euler and quasi-static equilibrium (`docs/math.md` section 7):
//! the settings, scratch and report. The loop is the shared descent loop (`descent/mod.rs`:
//! the relaxation's objective `Phi`, Armijo line search and stopping test), the direction from
//! the projected Hessian `step/descent/newton/cg.rs`, preconditioned by block Jacobi or (feature
//! `alloc`, `Preconditioner::Multilevel`) by smoothed-aggregation multigrid
//! (`step/descent/newton/amg/`, `docs/math.md` section 7.1.1).
//!
//! The algorithm and the stopping test are documented on [`newton_step`]; the exact Hessian
//! near the solution, the load steps (`step/descent/newton/continuation.rs`) and the longer
//! steps along a too-stiff model on [`newton_quasi_static`] (`docs/math.md` sections 7.1.2 to
//! 7.1.5).

#[cfg(feature = "alloc")]
mod amg;
mod cg;
mod continuation;

#[cfg(not(feature = "alloc"))]
use core::marker::PhantomData;

use super::super::super::element::TetHessian;
use super::super::super::types::{Mat3, Real, Vec3};
use super::super::super::math;
use super::super::descent::{self, LoopSettings, Problem, SolveInputs, Summary, Work};
use super::super::model::ElasticHessian;
use super::super::scene::Scene;
use super::super::scratch_len;
use super::super::state::check_length;
use super::settings::{DescentReport, DescentSettings};
use super::stopping::StallRule;
use crate::error::{StepBuffer, StepError};
use cg::{CgVectors, ExactSwitch, Newton};

#[cfg(feature = "alloc")]
pub use amg::{MAX_COARSE, Multilevel, REBUILD_FACTOR};

/// Scratch space of Newton's method over caller buffers of the lengths of
/// [`scratch_len::newton`] (checked by the solvers). Nothing in it survives between solves.
/// The load steps of [`newton_quasi_static`] need no more: each step starts from the loop's
/// copy of its start positions.
#[derive(Debug)]
pub struct NewtonScratch<'a> {
    vectors: &'a mut [Vec3],
    blocks: &'a mut [Mat3],
    hessians: &'a mut [TetHessian],
    #[cfg(feature = "alloc")]
    multilevel: Option<&'a mut Multilevel>,
}

impl<'a> NewtonScratch<'a> {
    /// Scratch over the caller's buffers.
    #[inline]
    #[must_use]
    pub fn new(
        vectors: &'a mut [Vec3],
        blocks: &'a mut [Mat3],
        hessians: &'a mut [TetHessian],
    ) -> Self {
        NewtonScratch {
            vectors,
            blocks,
            hessians,
            #[cfg(feature = "alloc")]
            multilevel: None,
        }
    }

    /// This scratch with a multilevel preconditioner kept by the caller (feature `alloc`): a
    /// solve with [`Preconditioner::Multilevel`] reuses its hierarchy and rebuilds it only
    /// under its [rebuild policy](Multilevel#rebuild-policy), so a sequence of time steps pays
    /// for the setup rarely. Without it, each solve builds its own.
    #[cfg(feature = "alloc")]
    #[inline]
    #[must_use]
    pub fn with_multilevel(self, multilevel: &'a mut Multilevel) -> Self {
        NewtonScratch {
            multilevel: Some(multilevel),
            ..self
        }
    }
}

/// The preconditioner of Newton's conjugate gradients.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Preconditioner {
    /// The inverse 3x3 diagonal blocks of the Hessian (the default, and the only one without
    /// `alloc`): no setup, nothing allocated, but the CG iterations grow with the resolution
    /// (with `1 / h`: 96 a Newton iteration on a 10k-tetrahedron static cantilever, 190 at
    /// 100k).
    #[default]
    BlockJacobi,
    /// Smoothed-aggregation algebraic multigrid with the rigid-body modes ([`Multilevel`],
    /// feature `alloc`): one V-cycle a CG iteration, whose count stays about flat with the
    /// resolution, for a setup that assembles the Hessian. For static solves and stiff or
    /// large bodies. A model without element Hessians
    /// ([`ElasticHessian::for_each_element_hessian`]) falls back to block Jacobi.
    #[cfg(feature = "alloc")]
    Multilevel,
}

/// What only Newton's method has: the conjugate-gradient budget of its linear solves, its
/// preconditioner and the budget of its load steps. The rest of [`NewtonSettings`] is shared
/// with every implicit solver ([`DescentSettings`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonOptions {
    /// The budget of conjugate-gradient iterations per Newton iteration (at least 1), or
    /// [`AUTOMATIC_CG`](Self::AUTOMATIC_CG) (the default) for a budget that follows the problem
    /// and the preconditioner ([`automatic_cg_budget`]). The forcing term ends CG long before
    /// it on most steps; the budget only bounds the rest. Too small a budget is costly: on a
    /// slender 10 800-tet static cantilever, 200 CG iterations a Newton iteration left Newton
    /// unconverged after 50 iterations (truncated directions), where 2000 converged in 9 (1216
    /// CG in all).
    pub max_cg_iterations: u32,
    /// The preconditioner of the linear solves ([`Preconditioner::BlockJacobi`] by default).
    pub preconditioner: Preconditioner,
    /// The most load steps a quasi-static solve ([`newton_quasi_static`]) tries after its
    /// full-load solve fails (accepted and rejected ones together; 0: none, the one solve
    /// answers). 32 by default; see [`newton_quasi_static`] for the continuation.
    pub max_load_steps: u32,
}

impl NewtonOptions {
    /// The value of [`max_cg_iterations`](Self::max_cg_iterations) that asks for the automatic
    /// budget ([`automatic_cg_budget`]).
    pub const AUTOMATIC_CG: u32 = u32::MAX;
}

/// The automatic conjugate-gradient budget per Newton iteration
/// ([`NewtonOptions::AUTOMATIC_CG`]) for a body of `free_vertices` vertices that are not
/// pinned: with block Jacobi, whose CG iterations grow with `1 / h`, that is with the cube root
/// of the vertex count, `max(2000, 250 cbrt(free_vertices))` (2000 up to 512 free vertices;
/// `docs/math.md` section 7.1.3 has the measurement that chose it); with the multilevel
/// preconditioner, whose count stays about flat, 200.
#[must_use]
pub fn automatic_cg_budget(preconditioner: Preconditioner, free_vertices: usize) -> u32 {
    match preconditioner {
        Preconditioner::BlockJacobi => {
            // `free_vertices` as a float is exact to 2^24 (f32); the cube root's rounding does
            // not matter to a budget.
            #[allow(clippy::cast_precision_loss)]
            let root = math::cbrt(free_vertices as Real);
            let scaled = BLOCK_JACOBI_CG_PER_ROOT * root;
            // Saturating: a budget beyond u32 is no budget.
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let scaled = if scaled < 4.0e9 { scaled as u32 } else { 4_000_000_000 };
            scaled.max(MIN_CG_BUDGET)
        }
        #[cfg(feature = "alloc")]
        Preconditioner::Multilevel => MULTILEVEL_CG_BUDGET,
    }
}

/// The smallest automatic block-Jacobi budget (the former fixed default).
const MIN_CG_BUDGET: u32 = 2000;
/// The automatic block-Jacobi budget per cube root of the free vertex count (`docs/math.md`
/// section 7.1.3).
const BLOCK_JACOBI_CG_PER_ROOT: Real = 250.0;
/// The automatic budget with the multilevel preconditioner (`docs/math.md` section 7.1.3).
#[cfg(feature = "alloc")]
const MULTILEVEL_CG_BUDGET: u32 = 200;

/// The settings of Newton's method ([`newton_step`], [`newton_quasi_static`]): the shared
/// [`DescentSettings`] with [`NewtonOptions`]. The tolerance is reachable to `1e-8` and below
/// in f64; in f32 to `1e-4` where a step starts far from its solution, about `1e-3` of the load
/// at best otherwise (the rounding floor, see [`newton_step`]). The budget counts Newton
/// iterations (Hessian evaluations).
pub type NewtonSettings = DescentSettings<NewtonOptions>;

impl DescentSettings<NewtonOptions> {
    /// Relative tolerance `1e-4`, 50 Newton iterations (per load step), the automatic CG
    /// budget, block Jacobi, at most 32 load steps, Armijo `c = 1e-4`, `beta = 0.5`, 30
    /// backtracks.
    #[inline]
    #[must_use]
    pub const fn new() -> Self {
        DescentSettings {
            tolerance: 1e-4,
            max_iterations: 50,
            armijo: 1e-4,
            backtrack: 0.5,
            max_backtracks: 30,
            options: NewtonOptions {
                max_cg_iterations: NewtonOptions::AUTOMATIC_CG,
                preconditioner: Preconditioner::BlockJacobi,
                max_load_steps: 32,
            },
        }
    }

    /// These settings with `max_cg_iterations` conjugate-gradient iterations per Newton step.
    #[inline]
    #[must_use]
    pub fn with_cg_iterations(self, max_cg_iterations: u32) -> Self {
        DescentSettings {
            options: NewtonOptions {
                max_cg_iterations,
                ..self.options
            },
            ..self
        }
    }

    /// These settings with at most `max_load_steps` load steps after a failed full-load
    /// quasi-static solve (0: none).
    #[inline]
    #[must_use]
    pub fn with_load_steps(self, max_load_steps: u32) -> Self {
        DescentSettings {
            options: NewtonOptions {
                max_load_steps,
                ..self.options
            },
            ..self
        }
    }

    /// These settings with `preconditioner` for the linear solves.
    #[inline]
    #[must_use]
    pub fn with_preconditioner(self, preconditioner: Preconditioner) -> Self {
        DescentSettings {
            options: NewtonOptions {
                preconditioner,
                ..self.options
            },
            ..self
        }
    }

    /// Checks the settings.
    ///
    /// # Errors
    /// [`StepError::NewtonSettings`] unless the shared part is in range and the CG budget is
    /// positive.
    fn check(&self) -> Result<(), StepError> {
        if !(self.shared_part_valid() && self.options.max_cg_iterations > 0) {
            return Err(StepError::NewtonSettings);
        }
        Ok(())
    }
}

/// What only Newton's method counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NewtonDetails {
    /// Conjugate-gradient iterations over all Newton iterations (each one Hessian product).
    pub cg_iterations: u32,
    /// Builds of the multilevel hierarchy during the solve (0 with block Jacobi, or where the
    /// model made it fall back to block Jacobi).
    pub multilevel_builds: u32,
    /// The CG budget per Newton iteration the solve ran with (the setting, or the automatic
    /// budget, [`automatic_cg_budget`]).
    pub cg_budget: u32,
    /// The most CG iterations one Newton iteration took.
    pub largest_linear_solve: u32,
    /// Linear solves that ended on the CG budget before their forcing term (truncated
    /// directions).
    pub truncated_solves: u32,
    /// Newton iterations whose direction came from the exact (unprojected) element Hessians
    /// (quasi-static solves only, `docs/math.md` section 7.1.2).
    pub exact_iterations: u32,
    /// Times the exact Hessian was given up for the projected one at an iterate (negative
    /// curvature, an indefinite preconditioner block, a rejected full step).
    pub exact_fallbacks: u32,
    /// Load steps that converged after the full-load quasi-static solve failed (0 where it
    /// converged at once; see [`newton_quasi_static`]).
    pub load_steps: u32,
    /// Load steps that did not converge (each halving the next increment).
    pub rejected_load_steps: u32,
    /// The load whose equilibrium `positions` hold, in units of `1 / LOAD_UNITS` of the full
    /// load ([`LOAD_UNITS`] where the full load converged or no solve was tried; less where the
    /// load steps ran out, `positions` then at that equilibrium).
    pub load_reached: u32,
}

/// The unit of [`NewtonDetails::load_reached`]: `1 / LOAD_UNITS` of the full load, the smallest
/// load step (`docs/math.md` section 7.1.4).
pub const LOAD_UNITS: u32 = 1024;

/// What a Newton solve did: the shared [`DescentReport`] with [`NewtonDetails`]. Its
/// [`converged`](DescentReport::converged) also counts a stop at the rounding floor when that
/// floor is below the initial residual (see [`newton_step`]).
pub type NewtonReport = DescentReport<NewtonDetails>;

/// One implicit Euler step of the scene's `dt` by Newton's method: minimises the incremental
/// potential `Phi(x) = sum m/(2 h^2) |x - y|^2 + E(x) - sum m g.(x - x_n)`, `y = x_n + h v_n`,
/// the relaxation's objective ([`relax_step`](super::super::relax_step)), from the better of `y`
/// and `y + h^2 g`; then `v = (x_{n+1} - x_n) / h` with Coulomb friction at the ground contacts.
/// Pinned vertices keep position and velocity. Not converging within the budget is not an error
/// ([`DescentReport::converged`]).
///
/// # Algorithm
/// At the iterate `x` with gradient `g = grad Phi(x)`:
/// 1. The element Hessians are projected onto the positive semi-definite matrices (analytic
///    eigensystems, `docs/math.md` section 6) and cached ([`TetHessian`], one SVD per element);
///    `A = M / h^2 + H` (without inertia in the quasi-static mode).
/// 2. Constraints are removed degrees of freedom, applied as a projection `S` per vertex:
///    pinned vertices lose all three, vertices on the ground whose gradient pushes into it (the
///    active set, the same test as the relaxation's residual) lose the normal one.
/// 3. `S A S d = -S g` is solved inexactly by matrix-free conjugate gradients with the
///    block-Jacobi preconditioner `S B_i^-1 S` (`B_i` the 3x3 diagonal blocks of `A`; a block
///    too ill-conditioned to invert is replaced by its diagonal), stopped at
///    `|r| <= eta |S g|` with Eisenstat and Walker's second forcing term: `eta_0 = 1/2`, then
///    `eta_k = 0.9 (|g_k| / |g_(k-1)|)^2`, raised to `0.9 eta_(k-1)^2` when that exceeds 0.1,
///    at most `1/2` and not below `target / (2 |g|)`, which no step needs: loose while the
///    residual falls slowly, tight once it falls fast. On the quasi-static cantilevers of
///    `benches/hessian.rs` it took 363 and 1733 CG iterations where `min(1/2, sqrt(|g| /
///    |g_0|))` took 396 and 2249, for the same residual. A forcing term that tends to zero keeps the local
///    convergence superlinear (Dembo, Eisenstat and Steihaug, "Inexact Newton methods", SIAM J.
///    Numer. Anal. 1982; Eisenstat and Walker, "Choosing the forcing terms in an inexact Newton
///    method", SIAM J. Sci. Comput. 1996). A non-positive curvature `p . A p` (only possible
///    without inertia, at vertices with no stiffness) ends the solve; at the first iteration the
///    preconditioned gradient is used instead. With `Preconditioner::Multilevel` (feature
///    `alloc`) the preconditioner is `S M^-1 S` instead, `M^-1` one V-cycle of
///    smoothed-aggregation multigrid on the assembled `S A S + (I - S)` (`Multilevel`): CG
///    iterations about flat in the resolution (4.7 and 4.1 a Newton iteration on the static
///    cantilever of issue #40 at 10 240 and 98 260 tetrahedra, where block Jacobi took 96 and
///    190), for a setup that is reused across Newton iterations (and solves, if kept).
/// 4. Armijo backtracking along `d` from the full step (the relaxation's test, with Hager and
///    Zhang's rounding-proof fallback), every trial point projected onto the ground.
///
/// # Stopping and the rounding floor
/// The solve stops when `|grad Phi| <= tolerance * max(|grad Phi(x_0)|, |M g|)` (the
/// relaxation's test, [`DescentSettings::tolerance`]). Below some level the residual is
/// rounding: every coordinate is only known to `eps |x| / 2`, and through the stiffness that
/// uncertainty is a force, so no representable `x` has a smaller residual than about
/// `|K| eps |x| / 2` (plus the rounding of the stresses, `eps mu A` per vertex, `A` a face).
/// Newton's method measures the estimate `eps/2 max|x| (sum_i |B_i|_F^2)^(1/2)`
/// ([`DescentReport::rounding_floor`], `B_i` the diagonal blocks of `A` at the free vertices;
/// from above, measured 1.5-5x the residual where solves stall) and, when two steps in a row
/// fail to halve the residual while it is within [`FLOOR_FACTOR`](DescentReport::FLOOR_FACTOR)
/// times that floor, stops there ([`DescentReport::stagnated`]). A failed line search or a
/// direction that is not downhill also stops the solve as stagnated. A tolerance below the
/// floor thus costs a few iterations and says so, instead of burning the budget.
///
/// What that means in practice (measured in `tests/steppers/newton.rs`): in f64 the floor is far
/// below any useful tolerance (`3e-12` of the load on the quasi-static cantilever, which reaches
/// `1e-8`); in f32 it is about `2e-3` of the load on that cantilever (E = 1 MPa, 10 cm cells; the
/// solve stalls at `4e-4`) and about `0.2` of the weight of a stiff block at rest (E = 1e8 Pa, 5 cm
/// cells; stalls at `0.05..0.1`): ask f32 for `1e-4` and steps that start far from their solution
/// reach it, steps that start near rest stop at the floor (11 of the block's 30 steps with the
/// floor above the initial residual: stagnated, not converged). Working in coordinates near the
/// origin (relative to the body's size) keeps `eps |x|` small.
///
/// # What `converged` guarantees
/// [`DescentReport::converged`] is true only with a finite residual and target, and then
/// either the residual meets the target, or the solve stagnated within `FLOOR_FACTOR` times a
/// finite floor that is below the initial residual: the residual fell to its rounding level,
/// and the answer is as close as the residual can resolve (within 0.3 % of the f64 answer on
/// the f32 cantilevers of `tests/steppers/stagnation.rs`, where the tolerance would ask for
/// about 0.01 %). A stop at a floor at or above the initial residual (a step that starts within
/// rounding of its solution, as far as the residual can tell, or a load below the rounding) is
/// stagnated and not converged: there the answer was measured 0.03 % to 11 % off in f32, and
/// wholly off where the load is below the rounding of the rest shape (issue #44). An overflowed
/// residual or target (a load whose square overflows, a collider that moves the body 1e30 m)
/// is never converged.
///
/// ```
/// use softfem::element::{TetHessian, TetRest};
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::{NewtonScratch, NewtonSettings, Scene, TetElastic, scratch_len, newton_step};
///
/// // A tetrahedron hanging from three pinned corners sags under gravity.
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Z, -Vec3::Y].map(|x| x * 0.1);
/// let tets = [[0, 1, 2, 3]];
/// let mut rest_data = [TetRest::default(); 1];
/// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
/// let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e4, 0.3)?);
/// let mut masses = [0.0; 4];
/// mesh.lumped_masses(1000.0, &mut masses)?;
/// let pinned = [true, true, true, false];
/// let scene = Scene::new(1.0 / 60.0).with_gravity(Vec3::new(0.0, -9.81, 0.0));
/// let settings = NewtonSettings::new();
/// let (mut x, mut v) = (rest, [Vec3::ZERO; 4]);
/// let len = scratch_len::newton(4, 1);
/// let mut vectors = [Vec3::ZERO; 36];
/// let mut blocks = [Mat3::ZERO; 4];
/// let mut hessians = [TetHessian::default(); 1];
/// assert_eq!((len.vectors, len.blocks, len.hessians), (36, 4, 1));
/// let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
/// let report = newton_step(&body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch)?;
/// assert!(report.converged && x[3].y < rest[3].y && v[3].y < 0.0);
/// assert!(report.iterations <= 5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// Before anything is touched: the scene's errors ([`Scene::validated`]: the time step, gravity,
/// colliders, the ground), [`StepError::NewtonSettings`], [`StepError::LengthMismatch`] (state,
/// scene and scratch buffers), [`StepError::Mass`], [`StepError::NonFiniteInput`], the loads'
/// errors.
/// [`StepError::NonFiniteState`] if `Phi` is not finite at the start or the result is not
/// finite; the state is then restored bit for bit.
#[allow(clippy::too_many_arguments)]
pub fn newton_step<F: ElasticHessian>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, Vec3>,
    settings: &NewtonSettings,
    positions: &mut [Vec3],
    velocities: &mut [Vec3],
    scratch: &mut NewtonScratch<'_>,
) -> Result<NewtonReport, StepError> {
    solve(
        (model, masses, pinned),
        scene,
        settings,
        positions,
        Some(velocities),
        scratch,
    )
}

/// Quasi-static equilibrium by Newton's method: minimises `E(x) - sum m g.(x - x_0)` from the
/// given `positions` (the loop of [`newton_step`] without inertia; the scene's `dt` and
/// previous velocities are ignored), reaching the state where elastic forces balance gravity
/// and the ground's reaction. The body must be held (pins or ground) against rigid motion, or
/// the Hessian is singular along it; vertices in no element do not move.
///
/// # One call
/// What [`newton_step`] does, and two things for static answers far from the start
/// (`docs/math.md` sections 7.1.2 to 7.1.5):
/// * near the solution the exact element Hessians replace the projected ones where they are
///   positive definite, so that the last iterations converge quadratically (the projected
///   Hessian again on negative curvature, an indefinite block or a rejected full step);
/// * **load steps**: where the full-load solve does not converge (its budget is spent, or it
///   stalls), `positions` are restored to the caller's and gravity and the external forces
///   are applied in increments, each solved from the last equilibrium: first half the load,
///   each increment halved after a step that fails and doubled after one that converges, at
///   most [`NewtonOptions::max_load_steps`] tries (32 by default; 0: the one solve answers),
///   none below `1 / LOAD_UNITS` of the load, each with four times the settings' Newton budget
///   (near a bifurcation one step took 102 Newton iterations on the Cook membrane). The report counts the iterations and CG
///   iterations of every solve, its residual, target and `phi` are the last step's, and
///   [`converged`](DescentReport::converged) means the full load converged
///   ([`NewtonDetails::load_steps`], [`NewtonDetails::load_reached`]: where the steps run out,
///   `positions` hold the equilibrium of that fraction of the load). Prescribed displacements (pins the caller
///   moved) are applied at once, not stepped.
///
/// # Errors
/// As [`newton_step`] (without the time-step errors); a load step that ends in a non-finite
/// state ([`StepError::NonFiniteState`]) is a step that failed, not an error.
pub fn newton_quasi_static<F: ElasticHessian>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, Vec3>,
    settings: &NewtonSettings,
    positions: &mut [Vec3],
    scratch: &mut NewtonScratch<'_>,
) -> Result<NewtonReport, StepError> {
    solve(
        (model, masses, pinned),
        scene,
        settings,
        positions,
        None,
        scratch,
    )
}

/// The shared solve of [`newton_step`] (`velocities` given) and [`newton_quasi_static`]: the
/// checks, then one solve at the full load and, for a quasi-static solve that fails, the load
/// steps (`continuation.rs`).
fn solve<F: ElasticHessian>(
    (model, masses, pinned): (&F, &[Real], &[bool]),
    scene: &Scene<'_, Vec3>,
    settings: &NewtonSettings,
    positions: &mut [Vec3],
    velocities: Option<&mut [Vec3]>,
    scratch: &mut NewtonScratch<'_>,
) -> Result<NewtonReport, StepError> {
    let n = model.vertex_count();
    let inputs = SolveInputs {
        body: (model, masses, pinned),
        scene,
        positions,
        velocities: velocities.as_deref(),
    };
    let checked = inputs.checked(settings.check(), || {
        let lengths = scratch_len::newton(n, model.element_count());
        let vectors = scratch.vectors.len();
        check_length(StepBuffer::Scratch, lengths.vectors, vectors)?;
        let blocks = scratch.blocks.len();
        check_length(StepBuffer::BlockScratch, lengths.blocks, blocks)?;
        let hessians = scratch.hessians.len();
        check_length(StepBuffer::HessianScratch, lengths.hessians, hessians)
    })?;
    let mut problem = checked.problem((model, masses, pinned), &[], scene);
    let cg_budget = match settings.options.max_cg_iterations {
        NewtonOptions::AUTOMATIC_CG => {
            let free = (0..n)
                .filter(|&i| !pinned.get(i).copied().unwrap_or(false))
                .count();
            automatic_cg_budget(settings.options.preconditioner, free)
        }
        budget => budget,
    };
    let quasi_static = velocities.is_none();
    let load_steps = if quasi_static {
        settings.options.max_load_steps
    } else {
        0
    };
    let NewtonScratch {
        vectors,
        blocks,
        hessians,
        #[cfg(feature = "alloc")]
        multilevel: kept,
    } = scratch;
    #[cfg(feature = "alloc")]
    let mut own = Multilevel::new();
    #[cfg(feature = "alloc")]
    let mut multilevel = if settings.options.preconditioner == Preconditioner::Multilevel {
        Some(match kept.as_deref_mut() {
            Some(kept) => kept,
            None => &mut own,
        })
    } else {
        None
    };
    #[cfg(not(feature = "alloc"))]
    let mut multilevel = PhantomData;
    let mut attempt = Attempt {
        settings,
        max_iterations: settings.max_iterations,
        quasi_static,
        cg_budget,
        restore_unconverged: load_steps > 0,
        vectors,
        blocks,
        hessians,
        multilevel: &mut multilevel,
        totals: NewtonDetails {
            cg_budget,
            load_reached: LOAD_UNITS,
            ..NewtonDetails::default()
        },
    };
    let first = attempt.run(&problem, positions, velocities)?;
    if first.converged || load_steps == 0 {
        return Ok(first.with_details(attempt.totals));
    }
    continuation::load_steps(
        (&mut problem, scene.gravity),
        load_steps,
        first,
        positions,
        &mut attempt,
    )
}

/// How many times Newton's line search may double a full step whose end is still steeply
/// downhill (`docs/math.md` section 7.1.5): up to `2^8` times the Newton step.
const MAX_EXPANSIONS: u32 = 8;

/// The multilevel preconditioner a solve keeps across its load steps (feature `alloc`).
#[cfg(feature = "alloc")]
type Kept<'b> = Option<&'b mut Multilevel>;

/// Nothing to keep without `alloc`.
#[cfg(not(feature = "alloc"))]
type Kept<'b> = PhantomData<&'b mut ()>;

/// One descent solve of Newton's method over the caller's scratch, with the counts of every
/// solve so far.
struct Attempt<'s, 'b> {
    settings: &'s NewtonSettings,
    /// The Newton iterations a solve may take (the settings' budget; more for a load step).
    max_iterations: u32,
    /// A quasi-static solve: the exact Hessian near the solution and the longer steps
    /// (`docs/math.md` sections 7.1.2 and 7.1.5) are for these only.
    quasi_static: bool,
    cg_budget: u32,
    /// Whether a solve that does not converge restores the start positions (the load steps).
    restore_unconverged: bool,
    vectors: &'s mut [Vec3],
    blocks: &'s mut [Mat3],
    hessians: &'s mut [TetHessian],
    #[cfg_attr(not(feature = "alloc"), allow(dead_code))]
    multilevel: &'s mut Kept<'b>,
    /// The counts of every solve so far.
    totals: NewtonDetails,
}

impl Attempt<'_, '_> {
    /// Runs `problem` from `positions`; adds its counts to the totals and returns its summary,
    /// with the iteration counts of every solve so far.
    ///
    /// # Errors
    /// The descent loop's.
    fn run<F: ElasticHessian>(
        &mut self,
        problem: &Problem<'_, F>,
        positions: &mut [Vec3],
        velocities: Option<&mut [Vec3]>,
    ) -> Result<Summary, StepError> {
        let n = problem.model.vertex_count();
        let (work, rest) = Work::split(self.vectors, n);
        let (residual, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
        let (preconditioned, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
        let (conjugate, product) = rest.split_at_mut_checked(n).unwrap_or_default();
        let cg = CgVectors {
            residual,
            preconditioned,
            conjugate,
            product,
        };
        let mut newton = Newton::new(
            (&mut *self.hessians, &mut *self.blocks, cg),
            self.cg_budget,
            problem.ground.as_ref().map(|g| g.normal),
        );
        if !self.quasi_static {
            newton.exact = ExactSwitch::off();
        }
        #[cfg(feature = "alloc")]
        let builds_before = {
            newton.multilevel = self.multilevel.as_deref_mut();
            newton.multilevel.as_ref().map_or(0, |m| m.builds())
        };
        let loop_settings = LoopSettings {
            restore_unconverged: self.restore_unconverged,
            max_expansions: if self.quasi_static {
                MAX_EXPANSIONS
            } else {
                0
            },
            max_iterations: self.max_iterations,
            ..LoopSettings::new(self.settings, StallRule::Halving)
        };
        let outcome = descent::solve(
            problem,
            &loop_settings,
            &mut newton,
            positions,
            velocities,
            work,
        );
        #[cfg(feature = "alloc")]
        let multilevel_builds = newton
            .multilevel
            .as_ref()
            .map_or(0, |m| m.builds() - builds_before);
        #[cfg(not(feature = "alloc"))]
        let multilevel_builds = 0;
        let totals = &mut self.totals;
        totals.cg_iterations += newton.cg_iterations;
        totals.multilevel_builds += multilevel_builds;
        totals.largest_linear_solve = totals.largest_linear_solve.max(newton.largest_linear_solve);
        totals.truncated_solves += newton.truncated_solves;
        totals.exact_iterations += newton.exact.iterations;
        totals.exact_fallbacks += newton.exact.fallbacks;
        outcome
    }
}

//! Newton's method for implicit Euler and quasi-static equilibrium (`docs/math.md` section 7):
//! the settings, scratch and report. The loop is the shared descent loop (`descent/mod.rs`:
//! the relaxation's objective `Phi`, Armijo line search and stopping test), the direction from
//! the projected Hessian `step/descent/newton/cg.rs`.
//!
//! The algorithm and the stopping test are documented on [`newton_step`].

use super::super::super::element::TetHessian;
use super::super::super::types::{Mat3, Real, Vec3};
use super::super::contact::collider::{Collider, check_colliders};
use super::chebyshev::AccelerationSettings;
mod cg;

use super::super::super::element::Vector;
use super::super::contact::Ground;
use super::super::descent::{self, LoopSettings, Problem, Work};
use super::super::loads::Loads;
use super::super::model::ElasticHessian;
use super::super::state::check_length;
use super::super::vertex_pass::passes::split_check_state;
use super::stopping::StallRule;
use crate::error::{StepBuffer, StepError};
use cg::{CgVectors, Newton};

pub use super::stopping::FLOOR_FACTOR;

/// The buffer lengths Newton's method needs ([`newton_scratch_len`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NewtonScratchLen {
    /// Vectors: `9 * vertex_count` (start positions, two gradients, a trial point, the
    /// direction and the four vectors of conjugate gradients).
    pub vectors: usize,
    /// 3x3 blocks: `vertex_count` (the inverted preconditioner blocks).
    pub blocks: usize,
    /// [`TetHessian`]s: `element_count` (180 bytes each in f32, 360 in f64).
    pub hessians: usize,
}

/// The scratch lengths of [`newton_step`] and [`newton_quasi_static`] for a body of
/// `vertex_count` vertices and `element_count` elements.
#[inline]
#[must_use]
pub const fn newton_scratch_len(vertex_count: usize, element_count: usize) -> NewtonScratchLen {
    NewtonScratchLen {
        vectors: 9 * vertex_count,
        blocks: vertex_count,
        hessians: element_count,
    }
}

/// Scratch space of Newton's method over caller buffers of the lengths of
/// [`newton_scratch_len`] (checked by the solvers). Nothing in it survives between solves.
#[derive(Debug)]
pub struct NewtonScratch<'a> {
    vectors: &'a mut [Vec3],
    blocks: &'a mut [Mat3],
    hessians: &'a mut [TetHessian],
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
        }
    }
}

/// The parameters of Newton's method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonSettings<'a, V> {
    /// The time step `h` (s) of [`newton_step`]; ignored by [`newton_quasi_static`]. Finite and
    /// positive.
    pub dt: Real,
    /// The gravitational acceleration (m/s^2).
    pub gravity: V,
    /// An optional ground half-space: an active set in the linear solves, projection of the
    /// trial points, friction on the velocity after the step or, opted in with a positive
    /// [`Ground::sticking_speed`], in the objective with its tangent blocks in the linear solves (as
    /// the relaxation, [`RelaxSettings::ground`](super::super::RelaxSettings::ground)).
    pub ground: Option<Ground<V>>,
    /// Rigid colliders (empty, the default, for none): projection and friction as the
    /// ground's, relative to each collider's surface velocity; see [`Collider`].
    pub colliders: &'a [Collider<'a>],
    /// Stop when `|grad Phi| <= tolerance * max(|grad Phi(x_0)|, |M g|)`, the relaxation's
    /// relative residual (in `[0, 1)`), or at the rounding floor (see the
    /// [`newton_step`] documentation). Reachable: `1e-8` and below in f64; in f32 `1e-4` where a
    /// step starts far from its solution, about `1e-3` of the load at best otherwise.
    pub tolerance: Real,
    /// The budget of Newton iterations (Hessian evaluations).
    pub max_iterations: u32,
    /// The budget of conjugate-gradient iterations per Newton iteration (at least 1). The
    /// forcing term ends CG long before it on most steps; the budget only bounds the rest. Too
    /// small a budget is costly: on a slender 10 800-tet static cantilever, 200 CG iterations a
    /// Newton iteration left Newton unconverged after 50 iterations (truncated directions),
    /// where the default 2000 converged in 9 (1216 CG in all).
    pub max_cg_iterations: u32,
    /// The Armijo constant `c` in `(0, 1)`.
    pub armijo: Real,
    /// The backtracking factor `beta` in `(0, 1)`.
    pub backtrack: Real,
    /// Rejections allowed per line search before the solve stops as stagnated.
    pub max_backtracks: u32,
    /// External forces (N), one per vertex, or empty (the default) for none: constant loads
    /// added to gravity (tip loads, pressure lumped to vertices); the objective gains
    /// `- sum f_ext . (x - x_n)`. Ignored at pinned vertices and along fixed axes. Checked
    /// finite ([`StepError::ExternalForce`](crate::error::StepError::ExternalForce)).
    pub external_forces: &'a [V],
    /// Per-vertex fixed-axis masks, one per vertex, or empty (the default) for none: bit 0
    /// ([`FIXED_X`](super::super::FIXED_X)) fixes x, bit 1 y, bit 2 z (3D only), for rollers and
    /// symmetry planes; `pinned` stays the way to fix all axes. A fixed coordinate keeps its
    /// bits.
    pub fixed_axes: &'a [u8],
}

impl<'a, V: Vector> NewtonSettings<'a, V> {
    /// Time step `dt` (s), no gravity or ground, relative tolerance `1e-4`, 50 Newton and 2000
    /// CG iterations, Armijo `c = 1e-4`, `beta = 0.5`, 30 backtracks.
    #[inline]
    #[must_use]
    pub fn new(dt: Real) -> Self {
        NewtonSettings {
            external_forces: &[],
            fixed_axes: &[],
            dt,
            gravity: V::ZERO,
            ground: None,
            colliders: &[],
            tolerance: 1e-4,
            max_iterations: 50,
            max_cg_iterations: 2000,
            armijo: 1e-4,
            backtrack: 0.5,
            max_backtracks: 30,
        }
    }

    /// These settings with gravity `gravity` (m/s^2).
    #[inline]
    #[must_use]
    pub fn with_gravity(self, gravity: V) -> Self {
        NewtonSettings { gravity, ..self }
    }

    /// These settings with `ground`.
    #[inline]
    #[must_use]
    pub fn with_ground(self, ground: Ground<V>) -> Self {
        NewtonSettings {
            ground: Some(ground),
            ..self
        }
    }

    /// These settings with `colliders` (see [`Collider`]; checked by the step).
    #[inline]
    #[must_use]
    pub fn with_colliders(self, colliders: &'a [Collider<'a>]) -> Self {
        NewtonSettings { colliders, ..self }
    }

    /// These settings with relative tolerance `tolerance` and `max_iterations` Newton
    /// iterations.
    #[inline]
    #[must_use]
    pub fn with_tolerance(self, tolerance: Real, max_iterations: u32) -> Self {
        NewtonSettings {
            tolerance,
            max_iterations,
            ..self
        }
    }

    /// These settings with `max_cg_iterations` conjugate-gradient iterations per Newton step.
    #[inline]
    #[must_use]
    pub fn with_cg_iterations(self, max_cg_iterations: u32) -> Self {
        NewtonSettings {
            max_cg_iterations,
            ..self
        }
    }

    /// These settings with external forces `forces` (N, one per vertex; see
    /// [`external_forces`](Self::external_forces)).
    #[inline]
    #[must_use]
    pub fn with_external_forces<'b>(self, forces: &'b [V]) -> NewtonSettings<'b, V>
    where
        'a: 'b,
    {
        let shorter: NewtonSettings<'b, V> = self;
        NewtonSettings {
            external_forces: forces,
            ..shorter
        }
    }

    /// These settings with per-vertex fixed-axis masks `fixed_axes` (see
    /// [`fixed_axes`](Self::fixed_axes)).
    #[inline]
    #[must_use]
    pub fn with_fixed_axes<'b>(self, fixed_axes: &'b [u8]) -> NewtonSettings<'b, V>
    where
        'a: 'b,
    {
        let shorter: NewtonSettings<'b, V> = self;
        NewtonSettings {
            fixed_axes,
            ..shorter
        }
    }
}

/// What a Newton solve did.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NewtonReport {
    /// Accepted Newton iterations (each one Hessian evaluation, one SVD per element).
    pub newton_iterations: u32,
    /// Conjugate-gradient iterations over all Newton iterations (each one Hessian product).
    pub cg_iterations: u32,
    /// Evaluations of `Phi` and its gradient (fused energy-and-force passes), the initial
    /// guess's included.
    pub energy_evaluations: u32,
    /// Line-search trials rejected by the Armijo test.
    pub backtracks: u32,
    /// `|grad Phi|` (N) at the initial guess, projected on the constraints.
    pub initial_residual: Real,
    /// `|grad Phi|` (N) at the result.
    pub residual: Real,
    /// The residual the tolerance asks for (N).
    pub target: Real,
    /// The estimated rounding floor of the residual (N) at the last Hessian evaluation (see
    /// the [`newton_step`] documentation); 0 if no Newton iteration ran.
    pub rounding_floor: Real,
    /// `Phi` (J) at the result, with the gravity potential measured from the start positions.
    pub phi: Real,
    /// Whether the residual reached its target, or stagnated within [`FLOOR_FACTOR`] times
    /// the estimated rounding floor.
    pub converged: bool,
    /// Whether the solve stopped because the residual stopped decreasing (rounding floor,
    /// failed line search) rather than on the target or the budget.
    pub stagnated: bool,
}

/// One implicit Euler step of `settings.dt` by Newton's method: minimises the incremental
/// potential `Phi(x) = sum m/(2 h^2) |x - y|^2 + E(x) - sum m g.(x - x_n)`, `y = x_n + h v_n`,
/// the relaxation's objective ([`relax_step`](super::super::relax_step)), from the better of `y` and
/// `y + h^2 g`; then `v = (x_{n+1} - x_n) / h` with Coulomb friction at the ground contacts.
/// Pinned vertices keep position and velocity. Not converging within the budget is not an
/// error ([`NewtonReport::converged`]).
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
///    method", SIAM J. Sci. Comput. 1996). A non-positive curvature `p . A p` (only possible without inertia, at
///    vertices with no stiffness) ends the solve; at the first iteration the preconditioned
///    gradient is used instead.
/// 4. Armijo backtracking along `d` from the full step (the relaxation's test, with Hager and
///    Zhang's rounding-proof fallback), every trial point projected onto the ground.
///
/// # Stopping and the rounding floor
/// The solve stops when `|grad Phi| <= tolerance * max(|grad Phi(x_0)|, |M g|)` (the
/// relaxation's test, [`NewtonSettings::tolerance`]). Below some level the residual is
/// rounding: every coordinate is only known to `eps |x| / 2`, and through the stiffness that
/// uncertainty is a force, so no representable `x` has a smaller residual than about
/// `|K| eps |x| / 2` (plus the rounding of the stresses, `eps mu A` per vertex, `A` a face).
/// Newton's method measures the estimate `eps/2 max|x| (sum_i |B_i|_F^2)^(1/2)`
/// ([`NewtonReport::rounding_floor`], `B_i` the diagonal blocks of `A` at the free vertices;
/// from above, measured 1.5-5x the residual where solves stall) and, when two steps in a row
/// fail to halve the residual while it is within [`FLOOR_FACTOR`] times that floor, stops
/// there ([`NewtonReport::stagnated`]) and counts the solve as converged: the answer is as good
/// as the precision allows. A failed line search or a direction that is not downhill also
/// stops the solve as stagnated, converged only within the same bound. A tolerance below the
/// floor thus costs a few iterations and says so, instead of burning the budget.
///
/// What that means in practice (measured in `tests/newton.rs`): in f64 the floor is far below
/// any useful tolerance (`3e-12` of the load on the quasi-static cantilever, which reaches
/// `1e-8`); in f32 it is about `2e-3` of the load on that cantilever (E = 1 MPa, 10 cm cells;
/// the solve stalls at `4e-4`) and about `0.2` of the weight of a stiff block at rest
/// (E = 1e8 Pa, 5 cm cells; stalls at `0.05..0.1`): ask f32 for `1e-4` and steps that start far
/// from their solution reach it, steps that start near rest stop at the floor. Working in
/// coordinates near the origin (relative to the body's size) keeps `eps |x|` small.
///
/// ```
/// use softfem::element::{TetHessian, TetRest};
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::{NewtonScratch, NewtonSettings, TetElastic, newton_scratch_len, newton_step};
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
/// let settings = NewtonSettings::new(1.0 / 60.0).with_gravity(Vec3::new(0.0, -9.81, 0.0));
/// let (mut x, mut v) = (rest, [Vec3::ZERO; 4]);
/// let len = newton_scratch_len(4, 1);
/// let mut vectors = [Vec3::ZERO; 36];
/// let mut blocks = [Mat3::ZERO; 4];
/// let mut hessians = [TetHessian::default(); 1];
/// assert_eq!((len.vectors, len.blocks, len.hessians), (36, 4, 1));
/// let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
/// let report = newton_step(&body, &masses, &pinned, &settings, &mut x, &mut v, &mut scratch)?;
/// assert!(report.converged && x[3].y < rest[3].y && v[3].y < 0.0);
/// assert!(report.newton_iterations <= 5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// Before anything is touched: [`StepError::TimeStep`], [`StepError::Gravity`],
/// [`StepError::NewtonSettings`], the ground's errors, [`StepError::LengthMismatch`] (state
/// and scratch buffers), [`StepError::Mass`], [`StepError::NonFiniteInput`].
/// [`StepError::NonFiniteState`] if `Phi` is not finite at the start or the result is not
/// finite; the state is then restored bit for bit.
pub fn newton_step<F: ElasticHessian>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    settings: &NewtonSettings<'_, Vec3>,
    positions: &mut [Vec3],
    velocities: &mut [Vec3],
    scratch: &mut NewtonScratch<'_>,
) -> Result<NewtonReport, StepError> {
    if !(settings.dt > 0.0 && settings.dt.is_finite()) {
        return Err(StepError::TimeStep);
    }
    solve(
        model,
        masses,
        pinned,
        settings,
        positions,
        Some(velocities),
        scratch,
    )
}

/// Quasi-static equilibrium by Newton's method: minimises `E(x) - sum m g.(x - x_0)` from the
/// given `positions` (the loop of [`newton_step`] without inertia; `settings.dt` is ignored),
/// reaching the state where elastic forces balance gravity and the ground's reaction. The
/// body must be held (pins or ground) against rigid motion, or the Hessian is singular along
/// it; vertices in no element do not move.
///
/// # Errors
/// As [`newton_step`] (without [`StepError::TimeStep`]).
pub fn newton_quasi_static<F: ElasticHessian>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    settings: &NewtonSettings<'_, Vec3>,
    positions: &mut [Vec3],
    scratch: &mut NewtonScratch<'_>,
) -> Result<NewtonReport, StepError> {
    solve(model, masses, pinned, settings, positions, None, scratch)
}

/// Checks the scalar settings; returns the ground with a unit normal.
fn validate(settings: &NewtonSettings<'_, Vec3>) -> Result<Option<Ground<Vec3>>, StepError> {
    if !settings.gravity.is_finite() {
        return Err(StepError::Gravity);
    }
    let in_open_unit = |x: Real| x > 0.0 && x < 1.0;
    if !((0.0..1.0).contains(&settings.tolerance)
        && in_open_unit(settings.armijo)
        && in_open_unit(settings.backtrack)
        && settings.max_cg_iterations > 0)
    {
        return Err(StepError::NewtonSettings);
    }
    check_colliders(settings.colliders, true)?;
    settings.ground.as_ref().map(Ground::validated).transpose()
}

/// The shared solve of [`newton_step`] (`velocities` given) and [`newton_quasi_static`].
fn solve<F: ElasticHessian>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    settings: &NewtonSettings<'_, Vec3>,
    positions: &mut [Vec3],
    velocities: Option<&mut [Vec3]>,
    scratch: &mut NewtonScratch<'_>,
) -> Result<NewtonReport, StepError> {
    let n = model.vertex_count();
    let ground = validate(settings)?;
    split_check_state(model, masses, pinned, positions, velocities.as_deref())?;
    let loads = Loads {
        forces: settings.external_forces,
        fixed_axes: settings.fixed_axes,
    };
    loads.check(n)?;
    let lengths = newton_scratch_len(n, model.element_count());
    check_length(StepBuffer::Scratch, lengths.vectors, scratch.vectors.len())?;
    check_length(
        StepBuffer::BlockScratch,
        lengths.blocks,
        scratch.blocks.len(),
    )?;
    check_length(
        StepBuffer::HessianScratch,
        lengths.hessians,
        scratch.hessians.len(),
    )?;

    let (start, rest) = scratch.vectors.split_at_mut_checked(n).unwrap_or_default();
    let (gradient, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (trial_gradient, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (trial, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (direction, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (residual, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (preconditioned, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (conjugate, product) = rest.split_at_mut_checked(n).unwrap_or_default();
    let dt = velocities.is_some().then_some(settings.dt);
    let inertia = dt.map_or(0.0, |dt| 1.0 / (dt * dt));
    let cg = CgVectors {
        residual,
        preconditioned,
        conjugate,
        product,
    };
    let mut newton = Newton::new(
        (&mut *scratch.hessians, &mut *scratch.blocks, cg),
        settings.max_cg_iterations,
        inertia,
        ground.as_ref().map(|g| g.normal),
    );
    let problem = Problem {
        model,
        masses,
        pinned,
        stiffness: &[],
        gravity: settings.gravity,
        ground,
        colliders: settings.colliders,
        loads,
        dt,
    };
    let loop_settings = LoopSettings {
        tolerance: settings.tolerance,
        max_iterations: settings.max_iterations,
        armijo: settings.armijo,
        backtrack: settings.backtrack,
        max_backtracks: settings.max_backtracks,
        step_length: 1.0,
        momentum: 0.0,
        acceleration: AccelerationSettings::NONE,
        stall: StallRule::Halving,
        rigid_guess: false,
    };
    let work = Work {
        start,
        gradient,
        trial_gradient,
        trial,
        direction,
    };
    let summary = descent::solve(
        &problem,
        &loop_settings,
        &mut newton,
        positions,
        velocities,
        work,
    )?;
    Ok(NewtonReport {
        newton_iterations: summary.iterations,
        cg_iterations: newton.cg_iterations,
        energy_evaluations: summary.energy_evaluations,
        backtracks: summary.backtracks,
        initial_residual: summary.initial_residual,
        residual: summary.residual,
        target: summary.target,
        rounding_floor: summary.rounding_floor,
        phi: summary.phi,
        converged: summary.converged,
        stagnated: summary.stagnated,
    })
}

//! Newton's method for implicit Euler and quasi-static equilibrium (`docs/math.md` section 7):
//! the same objective `Phi`, Armijo line search and stopping test as the relaxation
//! (`relax.rs`), with the search direction from the projected Hessian instead of a diagonal
//! bound.
//!
//! The algorithm and the stopping test are documented on [`newton_step`].

use core::mem::swap;

use super::super::element::TetHessian;
use super::super::math;
use super::super::types::{Mat3, Real, Vec3};
use super::collider::{Collider, check_colliders};
use super::line_search::{self, copy, downhill, slope_along, sufficient_decrease};
use super::loads::Loads;
use super::objective::{Evaluation, Objective, implicit_velocities};
use super::points::{Floor, Grouped};
use super::vertex_passes::{Frames, TrialPoint, Vertices, trial_pass};
use super::{
    ElasticHessian, Ground, Vector, check_length, check_state, first_non_finite, pinned_flags,
};
use crate::error::{StepBuffer, StepError};

/// A solve whose residual stagnated counts as converged when the residual is at most this
/// many times the estimated rounding floor ([`NewtonReport::rounding_floor`]).
pub const FLOOR_FACTOR: Real = 4.0;

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
    /// trial points, friction on the velocity after the step (as the relaxation).
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
    /// The budget of conjugate-gradient iterations per Newton iteration (at least 1).
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
    /// ([`FIXED_X`](super::FIXED_X)) fixes x, bit 1 y, bit 2 z (3D only), for rollers and
    /// symmetry planes; `pinned` stays the way to fix all axes. A fixed coordinate keeps its
    /// bits.
    pub fixed_axes: &'a [u8],
}

impl<'a, V: Vector> NewtonSettings<'a, V> {
    /// Time step `dt` (s), no gravity or ground, relative tolerance `1e-4`, 50 Newton and 200
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
            max_cg_iterations: 200,
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
/// the relaxation's objective ([`relax_step`](super::relax_step)), from the better of `y` and
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
///    `|r| <= eta |S g|` with the forcing term `eta = min(1/2, sqrt(|g| / |g_0|))` (but not
///    below `target / (2 |g|)`, which no step needs): loose far from the solution, tight near
///    it. A forcing term that tends to zero keeps the local
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
    check_state(n, masses, pinned, positions, velocities.as_deref())?;
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
    copy(start, positions);
    let start: &[Vec3] = start;
    let (h, inertia) = match velocities {
        Some(_) => (settings.dt, 1.0 / (settings.dt * settings.dt)),
        None => (0.0, 0.0),
    };
    let objective = Objective {
        model,
        vertices: Vertices {
            masses,
            pinned,
            stiffness: &[],
            start,
            velocities: velocities.as_deref().unwrap_or(&[]),
        },
        frames: Frames::new(h, inertia, settings.gravity, ground.as_ref())
            .with_colliders(settings.colliders),
        h,
        gravity: settings.gravity,
        loads,
    };
    let buffers = Buffers {
        gradient,
        trial_gradient,
        trial,
        direction,
        cg: CgVectors {
            residual,
            preconditioned,
            conjugate,
            product,
        },
        blocks: scratch.blocks,
        hessians: scratch.hessians,
    };
    let system = System {
        inertia,
        ground: ground.as_ref(),
    };
    let outcome = iterate(&objective, &system, settings, positions, buffers);
    let floor = Floor::new(ground.as_ref()).with_colliders(settings.colliders);
    let (report, gradient, backup) = match outcome {
        Ok(result) => result,
        Err(error) => {
            copy(positions, start);
            return Err(error);
        }
    };
    if let Some(vertex) = first_non_finite(positions, &[]) {
        copy(positions, start);
        return Err(StepError::NonFiniteState { vertex });
    }
    let Some(velocities) = velocities else {
        return Ok(report);
    };
    copy(backup, velocities);
    implicit_velocities(
        ground.as_ref(),
        &floor,
        h,
        (masses, pinned),
        (positions, start, gradient),
        velocities,
    );
    if let Some(vertex) = first_non_finite(velocities, &[]) {
        copy(positions, start);
        copy(velocities, backup);
        return Err(StepError::NonFiniteState { vertex });
    }
    Ok(report)
}

/// The mutable scratch of the Newton loop.
struct Buffers<'b> {
    gradient: &'b mut [Vec3],
    trial_gradient: &'b mut [Vec3],
    trial: &'b mut [Vec3],
    direction: &'b mut [Vec3],
    cg: CgVectors<'b>,
    blocks: &'b mut [Mat3],
    hessians: &'b mut [TetHessian],
}

/// The work vectors of conjugate gradients.
struct CgVectors<'b> {
    residual: &'b mut [Vec3],
    preconditioned: &'b mut [Vec3],
    conjugate: &'b mut [Vec3],
    product: &'b mut [Vec3],
}

/// What the linear systems need besides the Hessian: `1 / h^2` (0 without inertia) and the
/// validated ground.
struct System<'s> {
    inertia: Real,
    ground: Option<&'s Ground<Vec3>>,
}

/// The constraint projection `S` of one Newton iteration, fixed during its linear solve:
/// pinned vertices lose every component, vertices in contact with the ground whose gradient
/// pushes into it lose the normal one (the relaxation's residual projects the same way).
struct Constraints<'c> {
    pinned: &'c [bool],
    /// The fixed-axis masks (empty for none): those components are removed too.
    fixed_axes: &'c [u8],
    floor: &'c Floor<'c, Vec3>,
    normal: Option<Vec3>,
    x: &'c [Vec3],
    gradient: &'c [Vec3],
}

impl Constraints<'_> {
    /// `S_i v`.
    #[inline(always)]
    fn apply(&self, i: usize, v: Vec3) -> Vec3 {
        if self.pinned.get(i).copied().unwrap_or(false) {
            return Vec3::ZERO;
        }
        let fixed = self.fixed_axes.get(i).copied().unwrap_or(0);
        let mut v = v.axes_from(Vec3::ZERO, fixed);
        let at = |values: &[Vec3]| values.get(i).copied().unwrap_or(Vec3::ZERO);
        if let Some(n) = self.floor.collider_normal(at(self.x))
            && n.dot(at(self.gradient)) > 0.0
        {
            v = (v - n * n.dot(v)).axes_from(Vec3::ZERO, fixed);
        }
        let Some(normal) = self.normal else {
            return v;
        };
        let active =
            self.floor.contact(at(self.x)) == Some(true) && normal.dot(at(self.gradient)) > 0.0;
        if active {
            (v - normal * normal.dot(v)).axes_from(Vec3::ZERO, fixed)
        } else {
            v
        }
    }

    /// `S v` in place.
    fn project(&self, v: &mut [Vec3]) {
        for (i, value) in v.iter_mut().enumerate() {
            *value = self.apply(i, *value);
        }
    }
}

/// What the Newton loop hands back: the report, the final gradient, a free buffer.
type Outcome<'b> = (NewtonReport, &'b mut [Vec3], &'b mut [Vec3]);

/// The Newton loop from the initial guess, in `positions`.
fn iterate<'b, F: ElasticHessian>(
    objective: &Objective<'_, F>,
    system: &System<'_>,
    settings: &NewtonSettings<'_, Vec3>,
    positions: &mut [Vec3],
    buffers: Buffers<'b>,
) -> Result<Outcome<'b>, StepError> {
    let Buffers {
        mut gradient,
        mut trial_gradient,
        trial,
        direction,
        mut cg,
        blocks,
        hessians,
    } = buffers;
    let x = positions;
    let (mut evaluation, mut energy_evaluations) =
        initial_point(objective, x, &mut gradient, trial, &mut trial_gradient)?;
    let initial_residual = evaluation.residual;
    let target = settings.tolerance * initial_residual.max(objective.gravity_load());
    let mut residual = initial_residual;
    let mut phi = evaluation.phi;
    let (mut newton_iterations, mut cg_iterations, mut backtracks) = (0, 0, 0);
    let mut slow = 0;
    let mut stagnated = false;
    let mut rounding_floor: Real = 0.0;
    let model = objective.model;
    let (masses, pinned) = (objective.vertices.masses, objective.vertices.pinned);
    // Every coordinate is known to its rounding, half an ulp: `eps max |x| / 2` at most.
    let reach = x
        .iter()
        .fold(0.0, |a: Real, p| a.max(p.abs().max_element()));
    while residual > target && newton_iterations < settings.max_iterations {
        model.projected_hessians(x, hessians)?;
        let stiffness_squared =
            invert_blocks(model, hessians, (masses, pinned, system.inertia), blocks)?;
        rounding_floor = line_search::rounding_floor(reach, stiffness_squared);
        let constraints = Constraints {
            pinned: objective.vertices.pinned,
            fixed_axes: objective.loads.fixed_axes,
            floor: objective.frames.floor(),
            normal: system.ground.map(|g| g.normal),
            x,
            gradient,
        };
        // The forcing term, never asking the linear solve for more than the Newton step can use:
        // a linear residual below half the target.
        let eta = math::sqrt(residual / initial_residual)
            .max(0.5 * target / residual)
            .min(0.5);
        cg_iterations += conjugate_gradients(
            model,
            (hessians, blocks, masses, system.inertia),
            &constraints,
            (eta, settings.max_cg_iterations),
            direction,
            &mut cg,
        )?;
        let slope = slope_along(gradient, direction);
        if !downhill(slope) {
            stagnated = true;
            break;
        }
        let mut alpha = 1.0;
        let mut accepted = None;
        for _ in 0..=settings.max_backtracks {
            trial_pass(
                &objective.frames,
                objective.vertices.pinned,
                (x, direction),
                alpha,
                TrialPoint {
                    positions: trial,
                    gradient: trial_gradient,
                },
            );
            let trial_evaluation = objective.evaluate(trial, trial_gradient)?;
            energy_evaluations += 1;
            let trial_gradient: &[Vec3] = trial_gradient;
            if sufficient_decrease(
                (phi, trial_evaluation.phi, trial_evaluation.elastic),
                settings.armijo,
                alpha,
                slope,
                || slope_along(trial_gradient, direction),
            ) {
                accepted = Some(trial_evaluation);
                break;
            }
            alpha *= settings.backtrack;
            backtracks += 1;
        }
        let Some(accepted) = accepted else {
            stagnated = true;
            break;
        };
        copy(x, trial);
        swap(&mut gradient, &mut trial_gradient);
        newton_iterations += 1;
        // Newton's method at least halves the residual per step near the solution; a step that
        // does not, with the residual already within reach of its rounding floor, is moving
        // rounding around.
        let idle = accepted.residual > 0.5 * residual;
        slow = if idle { slow + 1 } else { 0 };
        evaluation = accepted;
        residual = evaluation.residual;
        phi = evaluation.phi;
        if slow >= 2 && residual <= FLOOR_FACTOR * rounding_floor {
            stagnated = true;
            break;
        }
    }
    let report = NewtonReport {
        newton_iterations,
        cg_iterations,
        energy_evaluations,
        backtracks,
        initial_residual,
        residual,
        target,
        rounding_floor,
        phi,
        converged: residual <= target || (stagnated && residual <= FLOOR_FACTOR * rounding_floor),
        stagnated,
    };
    Ok((report, gradient, trial))
}

/// Writes the initial guess into `x` and its gradient into `gradient`: the better (lower `Phi`)
/// of `y + h^2 g` and `y` (the relaxation's choice, see the `step` module documentation), or
/// `x_n` if neither is finite. Returns its evaluation and the number of evaluations.
fn initial_point<'g, F: ElasticHessian>(
    objective: &Objective<'_, F>,
    x: &mut [Vec3],
    gradient: &mut &'g mut [Vec3],
    other: &mut [Vec3],
    other_gradient: &mut &'g mut [Vec3],
) -> Result<(Evaluation, u32), StepError> {
    let drop = objective.gravity * (objective.h * objective.h);
    objective.initial_guess(
        TrialPoint {
            positions: x,
            gradient,
        },
        drop,
    );
    let mut evaluation = objective.evaluate(x, gradient)?;
    let mut evaluations = 1;
    if drop != Vec3::ZERO {
        objective.initial_guess(
            TrialPoint {
                positions: other,
                gradient: other_gradient,
            },
            Vec3::ZERO,
        );
        let inertial = objective.evaluate(other, other_gradient)?;
        evaluations += 1;
        if inertial.phi < evaluation.phi || !evaluation.phi.is_finite() {
            copy(x, other);
            swap(gradient, other_gradient);
            evaluation = inertial;
        }
    }
    if !evaluation.phi.is_finite() {
        copy(x, objective.vertices.start);
        gradient.fill(Vec3::ZERO);
        evaluation = objective.evaluate(x, gradient)?;
        evaluations += 1;
    }
    if !evaluation.phi.is_finite() {
        let vertex = first_non_finite(gradient, &[]).unwrap_or(0);
        return Err(StepError::NonFiniteState { vertex });
    }
    Ok((evaluation, evaluations))
}

/// Writes the inverted preconditioner blocks `(B_i + m_i / h^2 I)^-1` into `blocks`, `B_i` the
/// diagonal blocks of the projected Hessian. A block whose determinant is below
/// `eps max(diag)^3` (singular or nearly: a vertex with no stiffness and no inertia) is
/// replaced by the inverse of its diagonal, zero where a diagonal entry is not positive.
/// Returns `sum |B_i + m_i / h^2 I|_F^2` over the free vertices (N^2/m^2), for the rounding
/// floor.
fn invert_blocks<F: ElasticHessian>(
    model: &F,
    hessians: &[TetHessian],
    (masses, pinned, inertia): (&[Real], &[bool], Real),
    blocks: &mut [Mat3],
) -> Result<Real, StepError> {
    blocks.fill(Mat3::ZERO);
    model.add_vertex_hessian_blocks(hessians, blocks)?;
    let mut stiffness_squared = 0.0;
    for ((block, &m), pinned) in blocks.iter_mut().zip(masses).zip(pinned_flags(pinned)) {
        let b = *block + Mat3::from_diagonal(Vec3::splat(m * inertia));
        if !pinned {
            stiffness_squared +=
                b.x_axis.length_squared() + b.y_axis.length_squared() + b.z_axis.length_squared();
        }
        let diagonal = Vec3::new(b.x_axis.x, b.y_axis.y, b.z_axis.z);
        let largest = diagonal.max_element();
        let determinant = b.determinant();
        *block = if determinant > Real::EPSILON * largest * largest * largest
            && determinant.is_finite()
        {
            b.inverse()
        } else {
            let invert = |d: Real| if d > 0.0 { 1.0 / d } else { 0.0 };
            Mat3::from_diagonal(Vec3::new(
                invert(diagonal.x),
                invert(diagonal.y),
                invert(diagonal.z),
            ))
        };
    }
    Ok(stiffness_squared)
}

/// Whether `x > 0` (false for NaN).
#[inline(always)]
fn positive(x: Real) -> bool {
    x > 0.0
}

/// `sum a_i . b_i`.
fn dot(a: &[Vec3], b: &[Vec3]) -> Real {
    a.iter().zip(b).map(|(&x, &y)| x.dot(y)).sum()
}

/// Preconditioned conjugate gradients on `S A S d = -S g` from `d = 0` (Hestenes and Stiefel;
/// Saad, "Iterative Methods for Sparse Linear Systems", algorithm 9.1), `A = M / h^2 + H` with
/// `H` in `hessians` and the preconditioner `S B^-1 S` from the inverted `blocks`, until
/// `|r| <= eta |r_0|` or `max` iterations. Writes `d` into `direction`; returns the iterations.
fn conjugate_gradients<F: ElasticHessian>(
    model: &F,
    (hessians, blocks, masses, inertia): (&[TetHessian], &[Mat3], &[Real], Real),
    constraints: &Constraints<'_>,
    (eta, max): (Real, u32),
    direction: &mut [Vec3],
    cg: &mut CgVectors<'_>,
) -> Result<u32, StepError> {
    let CgVectors {
        residual,
        preconditioned,
        conjugate,
        product,
    } = cg;
    direction.fill(Vec3::ZERO);
    for (i, (r, &g)) in residual.iter_mut().zip(constraints.gradient).enumerate() {
        *r = constraints.apply(i, -g);
    }
    let precondition = |r: &[Vec3], z: &mut [Vec3]| {
        for (i, ((z, &r), block)) in z.iter_mut().zip(r).zip(blocks).enumerate() {
            *z = constraints.apply(i, *block * constraints.apply(i, r));
        }
    };
    precondition(residual, preconditioned);
    copy(conjugate, preconditioned);
    let mut rz = dot(residual, preconditioned);
    let stop = eta * math::sqrt(dot(residual, residual));
    let mut iterations = 0;
    while iterations < max {
        product.fill(Vec3::ZERO);
        model.add_hessian_product(hessians, conjugate, product)?;
        for ((q, &p), &m) in product.iter_mut().zip(&**conjugate).zip(masses) {
            *q += p * (m * inertia);
        }
        constraints.project(product);
        let curvature = dot(conjugate, product);
        if !positive(curvature) {
            if iterations == 0 {
                // No curvature along the preconditioned gradient (a body free to move rigidly
                // without inertia): take that descent direction for the line search.
                copy(direction, preconditioned);
            }
            break;
        }
        let step = rz / curvature;
        for (d, &p) in direction.iter_mut().zip(&**conjugate) {
            *d += p * step;
        }
        for (r, &q) in residual.iter_mut().zip(&**product) {
            *r -= q * step;
        }
        iterations += 1;
        if math::sqrt(dot(residual, residual)) <= stop {
            break;
        }
        precondition(residual, preconditioned);
        let rz_next = dot(residual, preconditioned);
        if !positive(rz_next) {
            break;
        }
        let beta = rz_next / rz;
        rz = rz_next;
        for (p, &z) in conjugate.iter_mut().zip(&**preconditioned) {
            *p = z + *p * beta;
        }
    }
    Ok(iterations)
}

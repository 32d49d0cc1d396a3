//! Implicit Euler as a minimisation, solved by Jacobi-preconditioned gradient descent with an
//! Armijo line search (`docs/math.md` section 4; Wang and Yang, "Descent Methods for Elastic Body
//! Simulation on the GPU", SIGGRAPH Asia 2016), and the same loop without inertia as a
//! quasi-static relaxation: the settings, scratch and report of the relaxation. The loop is the
//! shared descent loop (`descent/mod.rs`), the direction `step/descent/relax/jacobi.rs`; the
//! preconditioner is derived in the `step` module documentation.

mod gradient;
mod jacobi;

use super::super::super::element::Vector;
use super::super::super::types::Real;
use super::super::contact::Ground;
use super::super::contact::collider::{Collider, check_colliders};
use super::super::descent::{self, Direction, LoopSettings, Problem, Work};
use super::super::explicit::stability::vertex_stiffness;
use super::super::loads::Loads;
use super::super::model::ElasticEnergy;
use super::super::state::check_length;
use super::super::vertex_pass::passes::split_check_state;
use super::chebyshev::AccelerationSettings;
use super::stopping::StallRule;
use crate::error::{StepBuffer, StepError};
pub use gradient::{gradient_descent_quasi_static, gradient_descent_step};
use jacobi::Jacobi;

/// The length of the vector scratch buffer the relaxation needs for `vertex_count` vertices:
/// `5 * vertex_count` (the start positions, two gradients, a second point buffer that trades
/// places with `positions` as iterate and trial point, and the direction).
/// The scalar scratch buffer has one entry per vertex. Saturates at `usize::MAX` for counts
/// whose product does not fit (no such buffer can exist, so the length check refuses any).
#[inline]
#[must_use]
pub const fn relax_scratch_len(vertex_count: usize) -> usize {
    vertex_count.saturating_mul(5)
}

/// Scratch space of [`relax_step`] and [`relax_quasi_static`]: `vectors` of
/// [`relax_scratch_len`]`(vertex_count)` entries and `scalars` of `vertex_count` entries
/// (lengths checked by the solvers).
///
/// `scalars` keeps the preconditioner's stiffness part between calls: a per-vertex bound that
/// depends only on the rest shape and the material, computed by the first solve and reused by
/// every later solve with this scratch (it costs about one SVD per element, some ten force
/// evaluations). Keep one scratch alive across the steps of a simulation. After changing the
/// mesh or the material, call [`reset_preconditioner`](RelaxScratch::reset_preconditioner):
/// a stale preconditioner still gives correct solutions (any positive diagonal gives descent
/// directions, and the stopping test does not involve it) but may converge more slowly.
#[derive(Debug)]
pub struct RelaxScratch<'a, V> {
    vectors: &'a mut [V],
    scalars: &'a mut [Real],
    /// Whether `scalars` holds the per-vertex stiffness bounds.
    stiffness_ready: bool,
}

impl<'a, V: Vector> RelaxScratch<'a, V> {
    /// Scratch over the caller's buffers; the first solve computes the preconditioner.
    #[inline]
    #[must_use]
    pub fn new(vectors: &'a mut [V], scalars: &'a mut [Real]) -> Self {
        RelaxScratch {
            vectors,
            scalars,
            stiffness_ready: false,
        }
    }

    /// Makes the next solve recompute the preconditioner (after a change of mesh or material).
    #[inline]
    pub fn reset_preconditioner(&mut self) {
        self.stiffness_ready = false;
    }
}

impl<'a, V: Vector> RelaxScratch<'a, V> {
    /// Scratch over the caller's buffers (as [`new`](Self::new)) whose `scalars` already hold
    /// the preconditioner's stiffness part when `stiffness_ready`.
    #[inline]
    #[must_use]
    pub(crate) fn resume(
        vectors: &'a mut [V],
        scalars: &'a mut [Real],
        stiffness_ready: bool,
    ) -> Self {
        RelaxScratch {
            vectors,
            scalars,
            stiffness_ready,
        }
    }

    /// Whether `scalars` holds the preconditioner's stiffness part (for [`resume`](Self::resume)).
    #[inline]
    #[must_use]
    pub(crate) fn stiffness_ready(&self) -> bool {
        self.stiffness_ready
    }
}

/// The parameters of the relaxation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelaxSettings<'a, V> {
    /// The time step `h` (s) of [`relax_step`]; ignored by [`relax_quasi_static`]. Finite and
    /// positive; any size is stable (implicit Euler), larger steps damp more.
    pub dt: Real,
    /// The gravitational acceleration (m/s^2).
    pub gravity: V,
    /// An optional ground half-space, enforced by projection (a projected descent). Friction
    /// acts on the velocity after the solve, or, opted in with a positive
    /// [`Ground::sticking_speed`], is part of the step's objective (the lagged, smoothed Coulomb
    /// potential of `docs/math.md` section 4.6); restitution is ignored (implicit Euler does not
    /// bounce).
    pub ground: Option<Ground<V>>,
    /// Rigid colliders (empty, the default, for none): projection and friction as the
    /// ground's, relative to each collider's surface velocity; see [`Collider`].
    pub colliders: &'a [Collider<'a>],
    /// Stop when `|grad Phi| <= tolerance * max(|grad Phi(x_0)|, |M g|)` (relative residual, in
    /// `[0, 1)`; 0 runs the whole budget), `|M g|` the norm of the gravity load on the free
    /// vertices (N): a step that starts near equilibrium is measured against the load, not
    /// against its own rounding-level initial residual. After a step whose Coulomb friction
    /// acted on the velocity (a zero sticking speed), `|grad Phi(x_0)|` is the smaller of the
    /// residuals at `x_0` and at the rigid guess `x_n + h v_mean` (`v_mean` the mass-weighted
    /// mean velocity; one more energy evaluation, only where `|grad Phi(x_0)| > |M g|`, the one
    /// case where it can change the target): the friction impulses slowed only the
    /// contact vertices, and the elastic force of the shear they put into `x_0` (240 N against
    /// 11 to 21 N on the sliding block of `docs/math.md` section 4.4) would otherwise loosen the
    /// target twentyfold.
    pub tolerance: Real,
    /// The iteration budget.
    pub max_iterations: u32,
    /// The Armijo constant `c` in `(0, 1)`: accept `alpha` when
    /// `Phi(x + alpha d) <= Phi(x) + c alpha grad.d`.
    pub armijo: Real,
    /// The backtracking factor `beta` in `(0, 1)`: `alpha <- beta alpha` on rejection.
    pub backtrack: Real,
    /// Rejections allowed per iteration before the solve stops (not converged).
    pub max_backtracks: u32,
    /// The first trial step `alpha_0 > 0` along `d = -P^-1 grad Phi` (dimensionless; finite).
    /// `P` majorises the Hessian near rest, so any `alpha_0 < 2` converges on the linearised
    /// problem; `1` is the majorisation step that the Armijo test always accepts there, and
    /// larger steps converge faster because the bound is loose (see the
    /// [module documentation](super::super#the-relaxation)). Every line search starts from it; the
    /// Chebyshev trials use the step the last line search accepted.
    pub step_length: Real,
    /// Heavy-ball momentum in `[0, 1)`: `d = -P^-1 grad Phi + momentum * (last step)`, dropped
    /// for an iteration whenever it is not a descent direction. 0 is plain preconditioned
    /// descent. Exclusive with [`chebyshev`](Self::chebyshev).
    pub momentum: Real,
    /// Chebyshev semi-iterative acceleration (Wang and Yang 2016, section 4): `rho` in `[0, 1)`,
    /// the estimated spectral radius of the plain iteration `x <- x + alpha d`; 0 turns it off.
    /// See the [module documentation](super::super#the-relaxation) for how to choose it. Exclusive
    /// with [`momentum`](Self::momentum).
    pub chebyshev: Real,
    /// Plain iterations after each (re)start before the Chebyshev weights start (`S`).
    pub chebyshev_delay: u32,
    /// Estimate `rho` instead of taking [`chebyshev`](Self::chebyshev) (which must then be 0,
    /// with no momentum): the largest residual ratio `r_k / r_(k-1)` of the plain iterations
    /// `2..=chebyshev_delay` of the solve (`chebyshev_delay >= 2`), at most
    /// [`MAX_ESTIMATED_RELAX_RHO`], the estimator Vertex Block Descent uses
    /// ([`VbdSettings::estimate_chebyshev`](super::super::VbdSettings::estimate_chebyshev)).
    pub estimate_chebyshev: bool,
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

impl<'a, V: Vector> RelaxSettings<'a, V> {
    /// Time step `dt` (s), no gravity or ground, relative tolerance `2e-3`, 300 iterations,
    /// Chebyshev acceleration with `rho = 0.995` from the first iteration (delay 0) and first
    /// trial step `2`, Armijo `c = 1e-4`, `beta = 0.5`, 30 backtracks, no momentum.
    ///
    /// Why these: they are the fastest of the settings measured that converge on a dropped
    /// body, and the tolerance sits above the f32 rounding floor. Measured in f32 on a 0.2 m
    /// jelly cube (stable neo-Hookean, E = 50 kPa, `nu = 0.45`, 1000 kg/m^3) dropped from 0.5 m
    /// onto a ground with friction 0.6, every step from the drop to rest (steps unconverged,
    /// mean iterations per step, wall time on one core of a shared, loaded 2-core machine):
    ///
    /// | mesh, steps | these defaults | tolerance `1e-3`, 200 iterations, plain descent with `alpha = 1` (the old defaults) |
    /// |---|---|---|
    /// | 1080 tets, 300 x 1/60 s | 0, 12.9, 0.19 s | 282, 188, 2.3 s |
    /// | 1080 tets, 600 x 1/240 s | 12, 30.8, 1.0 s | 598, 199, 5.4 s |
    /// | 1296 tets (Kuhn split), 300 x 1/60 s | 0, 18.0, 0.41 s | 282, 188, 4.1 s |
    /// | 5000 tets, 300 x 1/60 s | 20, 47.5, 4.6 s | 282, 188, 16.7 s |
    /// | 5000 tets, 600 x 1/240 s | 81, 73.0, 4.5 s | 599, 200, 17.9 s |
    ///
    /// The acceleration does most of it: plain descent at tolerance `2e-3` still left 272 of
    /// the 300 steps of the first row unconverged, `alpha = 2` alone 83. The tolerance does the
    /// rest: at rest on the ground the relative residual of an f32 solve stops falling at about
    /// `7e-4` (1080 tets) to `1.7e-3` (5000 tets), rounding in the gradient, so `1e-3` cannot
    /// be reached there; with Chebyshev and `1e-3` the 5000-tet rows stayed unconverged on 282
    /// of 300 and 521 of 600 steps. Finer f32 meshes need a looser tolerance (`5e-3` leaves 13 of
    /// 300 unconverged at 5000 tets, 26.7 iterations); f64 solves can ask for far less. `rho`:
    /// `0.99` and `0.999` were each better on one row and worse on others (`0.999` left 259 of
    /// 300 unconverged at 5000 tets); quasi-static solves ([`relax_quasi_static`]) want `0.999`
    /// (see the [module documentation](super::super#acceleration)). Unconverged steps are those that
    /// used the whole budget, mostly on landing, not errors.
    #[inline]
    #[must_use]
    pub fn new(dt: Real) -> Self {
        RelaxSettings {
            external_forces: &[],
            fixed_axes: &[],
            dt,
            gravity: V::ZERO,
            ground: None,
            colliders: &[],
            tolerance: 2e-3,
            max_iterations: 300,
            armijo: 1e-4,
            backtrack: 0.5,
            max_backtracks: 30,
            step_length: 2.0,
            momentum: 0.0,
            chebyshev: 0.995,
            chebyshev_delay: 0,
            estimate_chebyshev: false,
        }
    }

    /// These settings with gravity `gravity` (m/s^2).
    #[inline]
    #[must_use]
    pub fn with_gravity(self, gravity: V) -> Self {
        RelaxSettings { gravity, ..self }
    }

    /// These settings with `ground`.
    #[inline]
    #[must_use]
    pub fn with_ground(self, ground: Ground<V>) -> Self {
        RelaxSettings {
            ground: Some(ground),
            ..self
        }
    }

    /// These settings with `colliders` (see [`Collider`]; checked by the step).
    #[inline]
    #[must_use]
    pub fn with_colliders(self, colliders: &'a [Collider<'a>]) -> Self {
        RelaxSettings { colliders, ..self }
    }

    /// These settings with relative tolerance `tolerance` and budget `max_iterations`.
    #[inline]
    #[must_use]
    pub fn with_tolerance(self, tolerance: Real, max_iterations: u32) -> Self {
        RelaxSettings {
            tolerance,
            max_iterations,
            ..self
        }
    }

    /// These settings with heavy-ball `momentum` (and no Chebyshev acceleration).
    #[inline]
    #[must_use]
    pub fn with_momentum(self, momentum: Real) -> Self {
        RelaxSettings {
            momentum,
            chebyshev: 0.0,
            ..self
        }
    }

    /// These settings with Chebyshev acceleration for a `rho` the solver estimates from the
    /// first `delay` plain iterations (`delay >= 2`; see
    /// [`estimate_chebyshev`](Self::estimate_chebyshev)), no momentum, and the first trial
    /// step `step_length`.
    #[inline]
    #[must_use]
    pub fn with_estimated_chebyshev(self, step_length: Real, delay: u32) -> Self {
        RelaxSettings {
            chebyshev: 0.0,
            step_length,
            chebyshev_delay: delay,
            estimate_chebyshev: true,
            momentum: 0.0,
            ..self
        }
    }

    /// These settings with Chebyshev acceleration for the spectral radius estimate `rho`
    /// (and no momentum), the first trial step `step_length` and a delay of `delay`
    /// iterations.
    #[inline]
    #[must_use]
    pub fn with_chebyshev(self, rho: Real, step_length: Real, delay: u32) -> Self {
        RelaxSettings {
            chebyshev: rho,
            step_length,
            chebyshev_delay: delay,
            estimate_chebyshev: false,
            momentum: 0.0,
            ..self
        }
    }

    /// These settings with external forces `forces` (N, one per vertex; see
    /// [`external_forces`](Self::external_forces)).
    #[inline]
    #[must_use]
    pub fn with_external_forces<'b>(self, forces: &'b [V]) -> RelaxSettings<'b, V>
    where
        'a: 'b,
    {
        let shorter: RelaxSettings<'b, V> = self;
        RelaxSettings {
            external_forces: forces,
            ..shorter
        }
    }

    /// These settings with per-vertex fixed-axis masks `fixed_axes` (see
    /// [`fixed_axes`](Self::fixed_axes)).
    #[inline]
    #[must_use]
    pub fn with_fixed_axes<'b>(self, fixed_axes: &'b [u8]) -> RelaxSettings<'b, V>
    where
        'a: 'b,
    {
        let shorter: RelaxSettings<'b, V> = self;
        RelaxSettings {
            fixed_axes,
            ..shorter
        }
    }
}

/// What a relaxation did. Total cost = `energy_evaluations` fused energy-and-force passes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RelaxReport {
    /// Accepted descent iterations.
    pub iterations: u32,
    /// Evaluations of `Phi` and its gradient (one per trial point, plus one to three for the
    /// initial guess: `y + h^2 g`, `y` (not where `y + h^2 g` wins by construction: a rigid
    /// translation of `y` touching no ground, see [`relax_step`]), and `x_n` if neither is
    /// finite; plus one for the
    /// rigid guess of the stopping test's scale after friction on the velocity where the
    /// initial residual exceeds the load, see [`RelaxSettings::tolerance`]).
    pub energy_evaluations: u32,
    /// `|grad Phi|` (N) at the initial guess (projected on the ground's constraint).
    pub initial_residual: Real,
    /// `|grad Phi|` (N) at the result.
    pub final_residual: Real,
    /// `Phi` (J) at the result, with the gravity potential measured from the start positions.
    pub phi: Real,
    /// Whether the residual reached the tolerance (see [`RelaxSettings::tolerance`]).
    pub converged: bool,
    /// Line-search trials rejected by the Armijo test (each shrinking the step by `beta`).
    pub backtracks: u32,
    /// Accelerated trials rejected because `Phi` increased, each followed by a restart of the
    /// acceleration with a plain step.
    pub restarts: u32,
    /// Whether the solve stopped because the residual stopped falling: its best value fell by
    /// less than 1 % over the last 100 iterations while within [`FLOOR_FACTOR`](super::super::FLOOR_FACTOR)
    /// times [`rounding_floor`](Self::rounding_floor) (the answer is as good as the precision
    /// allows), or did not fall at all over 1000 iterations (a plateau above the estimated
    /// floor). Either way the budget is not burnt; [`converged`](Self::converged) still says
    /// only whether the tolerance was reached (unlike Newton's method, which counts a stall at
    /// the floor as converged), and `final_residual` is the floor reached.
    pub stagnated: bool,
    /// The estimated rounding floor of the residual (N): `eps/2 max_i |x_i| (3 sum_i P_i^2)^(1/2)`
    /// over the free vertices, `P_i` the preconditioner (a bound on the diagonal block of the
    /// Hessian), the rule Newton's method uses ([`NewtonReport::rounding_floor`](super::super::NewtonReport::rounding_floor)).
    pub rounding_floor: Real,
    /// The Chebyshev `rho` used: the setting, the estimate, or 0 (none, or not yet estimated
    /// when the solve stopped).
    pub rho: Real,
}

/// The largest spectral radius [`RelaxSettings::estimate_chebyshev`] uses: `0.9999`.
pub const MAX_ESTIMATED_RELAX_RHO: Real = 0.9999;

/// One implicit Euler step of `settings.dt` as the minimisation of
/// `Phi(x) = sum m/(2 h^2) |x - y|^2 + E(x) - sum m g.(x - x_n)`, `y = x_n + h v_n`
/// (`docs/math.md` section 4), by preconditioned descent from the better (lower `Phi`) of `y` and
/// `y + h^2 g`, both projected onto the ground (where neither touches the ground, no collider,
/// pinned vertex, external load or fixed axis acts, `y + h^2 g` is `y` translated rigidly and
/// lower by `h^2 |g|^2 sum m / 2`: it is taken without evaluating `y`): `d = -P^-1 grad Phi` (see the
/// [module documentation](super::super)), optional momentum or Chebyshev acceleration, Armijo
/// backtracking, projection of every free trial point onto the ground. Then `v = (x_{n+1} - x_n) / h`, and at vertices resting on the
/// ground Coulomb friction removes up to `friction * h R / m` of the tangential velocity, `R`
/// the normal reaction (N, the gradient's normal component there).
///
/// Pinned vertices keep position and velocity. Not converging within the budget is not an
/// error: the best iterate is used and [`RelaxReport::converged`] is false.
///
/// ```
/// use softfem::element::TetRest;
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::{RelaxScratch, RelaxSettings, TetElastic, relax_scratch_len, relax_step};
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
/// let settings = RelaxSettings::new(1.0 / 60.0).with_gravity(Vec3::new(0.0, -9.81, 0.0));
/// let (mut x, mut v) = (rest, [Vec3::ZERO; 4]);
/// let (mut vectors, mut scalars) = ([Vec3::ZERO; relax_scratch_len(4)], [0.0; 4]);
/// let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
/// let report = relax_step(&body, &masses, &pinned, &settings, &mut x, &mut v, &mut scratch)?;
/// assert!(report.converged && x[3].y < rest[3].y && v[3].y < 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// Before anything is touched: [`StepError::TimeStep`], [`StepError::TimeStepTooSmall`] (a
/// step whose `1 / dt^2` overflows: below about `1e-19` s in f32, `1e-154` s in f64),
/// [`StepError::Gravity`],
/// [`StepError::RelaxSettings`], the ground's errors, [`StepError::LengthMismatch`],
/// [`StepError::Mass`], [`StepError::NonFiniteInput`]. [`StepError::NonFiniteState`] if `Phi`
/// is not finite at both `y` and `x_n` or the result is not finite; the state is then
/// restored.
pub fn relax_step<F: ElasticEnergy>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    settings: &RelaxSettings<'_, F::Vector>,
    positions: &mut [F::Vector],
    velocities: &mut [F::Vector],
    scratch: &mut RelaxScratch<'_, F::Vector>,
) -> Result<RelaxReport, StepError> {
    check_time_step(settings.dt)?;
    minimise(
        model,
        masses,
        pinned,
        settings,
        (positions, Some(velocities)),
        scratch,
        Jacobi::default(),
    )
}

/// Quasi-static relaxation: the loop of [`relax_step`] without the inertia term (`h` to
/// infinity), minimising `E(x) - sum m g.(x - x_0)` from the given `positions`: it moves the
/// body towards the equilibrium where elastic forces balance gravity (and the ground's
/// reaction). `settings.dt` is ignored. Vertices in no element have no preconditioner and do
/// not move.
///
/// # Errors
/// As [`relax_step`] (without [`StepError::TimeStep`]).
pub fn relax_quasi_static<F: ElasticEnergy>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    settings: &RelaxSettings<'_, F::Vector>,
    positions: &mut [F::Vector],
    scratch: &mut RelaxScratch<'_, F::Vector>,
) -> Result<RelaxReport, StepError> {
    minimise(
        model,
        masses,
        pinned,
        settings,
        (positions, None),
        scratch,
        Jacobi::default(),
    )
}

/// The shared solve of [`relax_step`] (`velocities` given), [`relax_quasi_static`] and the
/// gradient-descent solvers: checks, then the descent loop (`descent/mod.rs`) along `direction`.
pub(crate) fn minimise<F: ElasticEnergy, D: Direction<F>>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    settings: &RelaxSettings<'_, F::Vector>,
    (positions, velocities): (&mut [F::Vector], Option<&mut [F::Vector]>),
    scratch: &mut RelaxScratch<'_, F::Vector>,
    mut direction: D,
) -> Result<RelaxReport, StepError> {
    let n = model.vertex_count();
    let ground = validate(settings)?;
    split_check_state(model, masses, pinned, positions, velocities.as_deref())?;
    let loads = Loads {
        forces: settings.external_forces,
        fixed_axes: settings.fixed_axes,
    };
    loads.check(n)?;
    check_length(
        StepBuffer::Scratch,
        relax_scratch_len(n),
        scratch.vectors.len(),
    )?;
    check_length(StepBuffer::ScalarScratch, n, scratch.scalars.len())?;

    let (start, rest) = scratch.vectors.split_at_mut_checked(n).unwrap_or_default();
    let (gradient, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (trial_gradient, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (trial, direction_buffer) = rest.split_at_mut_checked(n).unwrap_or_default();
    if !scratch.stiffness_ready {
        vertex_stiffness(model, scratch.scalars);
        scratch.stiffness_ready = true;
    }
    let problem = Problem {
        model,
        masses,
        pinned,
        stiffness: scratch.scalars,
        gravity: settings.gravity,
        ground,
        colliders: settings.colliders,
        loads,
        dt: velocities.is_some().then_some(settings.dt),
    };
    let loop_settings = LoopSettings {
        tolerance: settings.tolerance,
        max_iterations: settings.max_iterations,
        armijo: settings.armijo,
        backtrack: settings.backtrack,
        max_backtracks: settings.max_backtracks,
        step_length: settings.step_length,
        momentum: settings.momentum,
        acceleration: AccelerationSettings {
            rho: settings.chebyshev,
            delay: settings.chebyshev_delay,
            estimate: settings.estimate_chebyshev,
            cap: MAX_ESTIMATED_RELAX_RHO,
        },
        stall: StallRule::Window,
        rigid_guess: false,
    };
    let work = Work {
        start,
        gradient,
        trial_gradient,
        trial,
        direction: direction_buffer,
    };
    let summary = descent::solve(
        &problem,
        &loop_settings,
        &mut direction,
        positions,
        velocities,
        work,
    )?;
    Ok(RelaxReport {
        iterations: summary.iterations,
        energy_evaluations: summary.energy_evaluations,
        initial_residual: summary.initial_residual,
        final_residual: summary.residual,
        phi: summary.phi,
        converged: summary.converged,
        backtracks: summary.backtracks,
        restarts: summary.restarts,
        stagnated: summary.stagnated,
        rounding_floor: summary.rounding_floor,
        rho: summary.rho,
    })
}

/// Checks the time step of an implicit Euler step: finite and positive, with a finite `1 / dt^2`.
pub(crate) fn check_time_step(dt: Real) -> Result<(), StepError> {
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(StepError::TimeStep);
    }
    // The inertia term `m / (2 h^2) |x - y|^2` needs `1 / h^2`: below about 1e-19 s (f32) or
    // 1e-154 s (f64) it overflows and every evaluation of Phi would be infinite.
    if !(1.0 / (dt * dt)).is_finite() {
        return Err(StepError::TimeStepTooSmall);
    }
    Ok(())
}

/// Checks the scalar settings; returns the ground with a unit normal.
fn validate<V: Vector>(settings: &RelaxSettings<'_, V>) -> Result<Option<Ground<V>>, StepError> {
    if !settings.gravity.is_finite() {
        return Err(StepError::Gravity);
    }
    let in_open_unit = |x: Real| x > 0.0 && x < 1.0;
    if !((0.0..1.0).contains(&settings.tolerance)
        && in_open_unit(settings.armijo)
        && in_open_unit(settings.backtrack)
        && (0.0..1.0).contains(&settings.momentum)
        && (0.0..1.0).contains(&settings.chebyshev)
        && !(settings.momentum > 0.0 && settings.chebyshev > 0.0)
        && !(settings.estimate_chebyshev
            && (settings.chebyshev > 0.0
                || settings.momentum > 0.0
                || settings.chebyshev_delay < 2))
        && settings.step_length > 0.0
        && settings.step_length.is_finite())
    {
        return Err(StepError::RelaxSettings);
    }
    check_colliders(settings.colliders, V::ALL_AXES == 0b111)?;
    settings.ground.as_ref().map(Ground::validated).transpose()
}

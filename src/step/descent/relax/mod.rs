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
use super::super::descent::{self, Direction, LoopSettings, SolveInputs, Work};
use super::super::explicit::stability::vertex_stiffness;
use super::super::model::ElasticEnergy;
use super::super::scene::Scene;
use super::super::scratch_len;
use super::super::state::check_length;
use super::chebyshev::AccelerationSettings;
use super::settings::{DescentReport, DescentSettings};
use super::stopping::StallRule;
use crate::error::{StepBuffer, StepError};
pub use gradient::{gradient_descent_quasi_static, gradient_descent_step};
use jacobi::Jacobi;

/// Scratch space of [`relax_step`] and [`relax_quasi_static`]: `vectors` of
/// [`scratch_len::relax`]`(vertex_count)` entries and `scalars` of `vertex_count` entries
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

/// What only the relaxation has: the first trial step and the acceleration (heavy-ball
/// momentum or the Chebyshev semi-iteration). The rest of [`RelaxSettings`] is shared with
/// every implicit solver ([`DescentSettings`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelaxOptions {
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
    /// [`MAX_ESTIMATED_RHO`](RelaxOptions::MAX_ESTIMATED_RHO), the estimator Vertex Block Descent
    /// uses ([`VbdOptions::estimate_chebyshev`](super::vbd::VbdOptions::estimate_chebyshev)).
    pub estimate_chebyshev: bool,
}

impl RelaxOptions {
    /// The largest spectral radius [`estimate_chebyshev`](Self::estimate_chebyshev) uses:
    /// 0.9999.
    pub const MAX_ESTIMATED_RHO: Real = MAX_ESTIMATED_RELAX_RHO;
}

/// The settings of the relaxation ([`relax_step`], [`relax_quasi_static`], and the gradient
/// descent solvers): the shared [`DescentSettings`] with [`RelaxOptions`].
pub type RelaxSettings = DescentSettings<RelaxOptions>;

impl DescentSettings<RelaxOptions> {
    /// Relative tolerance `2e-3`, 300 iterations,
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
    /// (see the [module documentation](super::super#acceleration)). Unconverged steps are those
    /// that used the whole budget, mostly on landing, not errors.
    #[inline]
    #[must_use]
    pub const fn new() -> Self {
        DescentSettings {
            tolerance: 2e-3,
            max_iterations: 300,
            armijo: 1e-4,
            backtrack: 0.5,
            max_backtracks: 30,
            options: RelaxOptions {
                step_length: 2.0,
                momentum: 0.0,
                chebyshev: 0.995,
                chebyshev_delay: 0,
                estimate_chebyshev: false,
            },
        }
    }

    /// These settings with heavy-ball `momentum` (and no Chebyshev acceleration).
    #[inline]
    #[must_use]
    pub fn with_momentum(self, momentum: Real) -> Self {
        let options = RelaxOptions {
            momentum,
            chebyshev: 0.0,
            ..self.options
        };
        DescentSettings { options, ..self }
    }

    /// These settings with Chebyshev acceleration for a `rho` the solver estimates from the
    /// first `delay` plain iterations (`delay >= 2`; see
    /// [`estimate_chebyshev`](RelaxOptions::estimate_chebyshev)), no momentum, and the first trial
    /// step `step_length`.
    #[inline]
    #[must_use]
    pub fn with_estimated_chebyshev(self, step_length: Real, delay: u32) -> Self {
        let options = RelaxOptions {
            chebyshev: 0.0,
            step_length,
            chebyshev_delay: delay,
            estimate_chebyshev: true,
            momentum: 0.0,
        };
        DescentSettings { options, ..self }
    }

    /// These settings with Chebyshev acceleration for the spectral radius estimate `rho`
    /// (and no momentum), the first trial step `step_length` and a delay of `delay`
    /// iterations.
    #[inline]
    #[must_use]
    pub fn with_chebyshev(self, rho: Real, step_length: Real, delay: u32) -> Self {
        let options = RelaxOptions {
            chebyshev: rho,
            step_length,
            chebyshev_delay: delay,
            estimate_chebyshev: false,
            momentum: 0.0,
        };
        DescentSettings { options, ..self }
    }

    /// Checks the settings.
    ///
    /// # Errors
    /// [`StepError::RelaxSettings`] unless the shared part is in range and so are the options:
    /// momentum and `rho` in `[0, 1)`, not both positive, an estimate only without either and
    /// with a delay of at least 2, a finite positive step length.
    fn check(&self) -> Result<(), StepError> {
        let o = &self.options;
        if !(self.shared_part_valid()
            && (0.0..1.0).contains(&o.momentum)
            && (0.0..1.0).contains(&o.chebyshev)
            && !(o.momentum > 0.0 && o.chebyshev > 0.0)
            && !(o.estimate_chebyshev
                && (o.chebyshev > 0.0 || o.momentum > 0.0 || o.chebyshev_delay < 2))
            && o.step_length > 0.0
            && o.step_length.is_finite())
        {
            return Err(StepError::RelaxSettings);
        }
        Ok(())
    }
}

/// What a relaxation did: the shared [`DescentReport`], nothing of its own. Total cost =
/// `energy_evaluations` fused energy-and-force passes. [`converged`](DescentReport::converged)
/// says only that the tolerance was reached, with a finite residual and target (a stall at the
/// rounding floor is reported by [`stagnated`](DescentReport::stagnated) and is not
/// converged; Newton's method counts one as converged where the floor is below the initial
/// residual).
pub type RelaxReport = DescentReport<()>;

/// The largest spectral radius [`RelaxOptions::estimate_chebyshev`] uses: `0.9999`.
pub(crate) const MAX_ESTIMATED_RELAX_RHO: Real = 0.9999;

/// One implicit Euler step of the scene's `dt` as the minimisation of
/// `Phi(x) = sum m/(2 h^2) |x - y|^2 + E(x) - sum m g.(x - x_n)`, `y = x_n + h v_n`
/// (`docs/math.md` section 4), by preconditioned descent from the better (lower `Phi`) of `y` and
/// `y + h^2 g`, both projected onto the ground (where neither touches the ground, no collider,
/// pinned vertex, external load or fixed axis acts, `y + h^2 g` is `y` translated rigidly and
/// lower by `h^2 |g|^2 sum m / 2`: it is taken without evaluating `y`): `d = -P^-1 grad Phi` (see
/// the [module documentation](super::super)), optional momentum or Chebyshev acceleration, Armijo
/// backtracking, projection of every free trial point onto the ground. Then `v = (x_{n+1} - x_n) /
/// h`, and at vertices resting on the ground Coulomb friction removes up to `friction * h R / m` of
/// the tangential velocity, `R` the normal reaction (N, the gradient's normal component there).
///
/// Pinned vertices keep position and velocity. Not converging within the budget is not an
/// error: the best iterate is used and [`DescentReport::converged`] is false.
/// [`DescentReport::converged`] is true exactly when the residual (`|grad Phi|` at the returned
/// state, projected on the contacts) is finite and at most a finite target (see
/// [`DescentSettings::tolerance`]); a stall ([`DescentReport::stagnated`]) or an overflowed
/// residual or target is never converged.
///
/// ```
/// use softfem::element::TetRest;
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::{RelaxScratch, RelaxSettings, Scene, TetElastic, scratch_len, relax_step};
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
/// let settings = RelaxSettings::new();
/// let (mut x, mut v) = (rest, [Vec3::ZERO; 4]);
/// let (mut vectors, mut scalars) = ([Vec3::ZERO; scratch_len::relax(4)], [0.0; 4]);
/// let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
/// let report = relax_step(&body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch)?;
/// assert!(report.converged && x[3].y < rest[3].y && v[3].y < 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// Before anything is touched: the scene's errors ([`Scene::validated`]: the time step, gravity,
/// colliders, the ground), [`StepError::RelaxSettings`], [`StepError::LengthMismatch`],
/// [`StepError::Mass`], [`StepError::NonFiniteInput`], the loads' errors.
/// [`StepError::NonFiniteState`] if `Phi` is not finite at both `y` and `x_n` or the result is not
/// finite; the state is then restored.
#[allow(clippy::too_many_arguments)]
pub fn relax_step<F: ElasticEnergy>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, F::Vector>,
    settings: &RelaxSettings,
    positions: &mut [F::Vector],
    velocities: &mut [F::Vector],
    scratch: &mut RelaxScratch<'_, F::Vector>,
) -> Result<RelaxReport, StepError> {
    minimise(
        (model, masses, pinned),
        scene,
        settings,
        (positions, Some(velocities)),
        scratch,
        Jacobi::default(),
    )
}

/// Quasi-static relaxation: the loop of [`relax_step`] without the inertia term (`h` to
/// infinity), minimising `E(x) - sum m g.(x - x_0)` from the given `positions`: it moves the
/// body towards the equilibrium where elastic forces balance gravity (and the ground's
/// reaction). The scene's `dt` and previous velocities are ignored. Vertices in no element have
/// no preconditioner and do not move.
///
/// # Errors
/// As [`relax_step`] (without the time-step errors).
pub fn relax_quasi_static<F: ElasticEnergy>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, F::Vector>,
    settings: &RelaxSettings,
    positions: &mut [F::Vector],
    scratch: &mut RelaxScratch<'_, F::Vector>,
) -> Result<RelaxReport, StepError> {
    minimise(
        (model, masses, pinned),
        scene,
        settings,
        (positions, None),
        scratch,
        Jacobi::default(),
    )
}

/// The shared solve of [`relax_step`] (`velocities` given), [`relax_quasi_static`] and the
/// gradient-descent solvers: checks, then the descent loop (`descent/mod.rs`) along `direction`.
pub(crate) fn minimise<F: ElasticEnergy, D: Direction<F>>(
    (model, masses, pinned): (&F, &[Real], &[bool]),
    scene: &Scene<'_, F::Vector>,
    settings: &RelaxSettings,
    (positions, velocities): (&mut [F::Vector], Option<&mut [F::Vector]>),
    scratch: &mut RelaxScratch<'_, F::Vector>,
    mut direction: D,
) -> Result<RelaxReport, StepError> {
    let n = model.vertex_count();
    let inputs = SolveInputs {
        body: (model, masses, pinned),
        scene,
        positions,
        velocities: velocities.as_deref(),
    };
    let checked = inputs.checked(settings.check(), || {
        let vectors = scratch.vectors.len();
        check_length(StepBuffer::Scratch, scratch_len::relax(n), vectors)?;
        check_length(StepBuffer::ScalarScratch, n, scratch.scalars.len())
    })?;

    let (work, _) = Work::split(scratch.vectors, n);
    if !scratch.stiffness_ready {
        vertex_stiffness(model, scratch.scalars);
        scratch.stiffness_ready = true;
    }
    let problem = checked.problem((model, masses, pinned), scratch.scalars, scene);
    let o = &settings.options;
    let loop_settings = LoopSettings {
        step_length: o.step_length,
        momentum: o.momentum,
        acceleration: AccelerationSettings {
            rho: o.chebyshev,
            delay: o.chebyshev_delay,
            estimate: o.estimate_chebyshev,
            cap: MAX_ESTIMATED_RELAX_RHO,
        },
        ..LoopSettings::new(settings, StallRule::Window)
    };
    let summary = descent::solve(
        &problem,
        &loop_settings,
        &mut direction,
        positions,
        velocities,
        work,
    )?;
    Ok(summary)
}

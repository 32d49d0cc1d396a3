//! The one descent loop every implicit solver here runs (`docs/math.md` section 7): minimise the
//! objective `Phi` (`objective.rs`: the incremental potential of an implicit Euler step, or the
//! static energy) from the better of two initial guesses, by steps along a search direction
//! `d = -P^-1 grad Phi` for some positive definite `P`, each step found by the Armijo
//! backtracking line search (`line_search.rs`), until the stopping test (`stopping.rs`: the
//! relative residual, the rounding floor, stagnation) ends it; then the velocity update, or, if
//! anything failed, the caller's state restored bit for bit. Friction at the contacts is part
//! of `Phi` (`objective.rs`, `step/contact/friction.rs`), lagged to the iterate each line search
//! starts from and re-lagged to every accepted point.
//!
//! The search direction is the only thing a solver adds, one folder each (with its settings,
//! report and entry points in the folder's `mod.rs`), behind [`Direction`]:
//! * `relax/jacobi.rs`: `P` the diagonal bound `m/h^2 + k_i` (the relaxation,
//!   [`relax_step`](super::relax_step)),
//! * `relax/gradient.rs`: `P = c I`, `c` the largest entry of that bound (plain gradient descent,
//!   [`gradient_descent_step`](super::gradient_descent_step)),
//! * `newton/cg.rs`: `P` the projected Hessian, solved by block-Jacobi PCG
//!   ([`newton_step`](super::newton_step)),
//! * `vbd/sweep.rs`: one block Gauss–Seidel sweep of 3x3 vertex Newton steps, `d = sweep(x) - x`
//!   (Vertex Block Descent, [`vbd_step`](super::vbd_step)).
//!
//! The loop also carries what the first-order directions share: heavy-ball momentum and the
//! Chebyshev semi-iteration (`chebyshev.rs`), each trial an extrapolation along the direction.
//!
//! # Displacements
//! The loop iterates in coordinates shifted by a reference point `c` of the start positions
//! ([`reference_point`]): along every axis on which the body does not straddle the origin (its
//! nearest coordinate farther from the origin than its extent), `c` takes the first vertex's
//! coordinate, so that the iterate holds displacements from the body rather than absolute
//! positions. The shift is exact (Sterbenz: every coordinate is within a factor 2 of `c`'s), so
//! pinned vertices and fixed coordinates keep their bits and a failed solve restores them; the
//! elastic energy, inertia and gravity terms depend on differences only, and the ground and
//! the colliders are shifted with them (`Colliders::shifted`: each collider queried relative to
//! its frame origin shifted by `-c`, a half-space's re-anchored at its point nearest `c`; the
//! surface velocities unchanged). A body 60 m (or 1e4 m) from the origin thus converges like
//! the same body at the origin, with a rounding floor relative to its size
//! (`tests/steppers/stagnation.rs`), on the ground or on a collider; and a block sliding metres
//! down an incline keeps its Newton steps of a micrometre (`tests/steppers/colliders`). A body
//! straddling the origin has `c = 0` and nothing changes.

pub(crate) mod chebyshev;
mod coordinates;
mod descend;
pub(crate) mod line_search;
pub(crate) mod newton;
pub(crate) mod objective;
pub(crate) mod relax;
pub(crate) mod settings;
pub(crate) mod stopping;
pub(crate) mod vbd;

use core::mem::swap;

use super::super::element::Vector;
use super::super::types::Real;
use super::contact::HalfSpace;
use super::contact::collider::{Collider, Colliders};
use super::contact::floor::Floor;
use super::contact::friction::{Friction, Lag};
use super::contact::vertex::shifted_colliders;
use super::loads::Loads;
use super::model::{ElasticEnergy, ElasticModel};
use super::scene::Scene;
use super::state::check_length;
use super::state::{first_non_finite, pinned_flags};
use super::vertex_pass::passes::{
    Frames, TrialPoint, Vertices, split_check_state, split_trial_pass,
};
use super::vertex_pass::point::Grouped;
use super::vertex_pass::{Blocks, Total};
use crate::error::{StepBuffer, StepError};
use chebyshev::{Acceleration, AccelerationSettings};
use line_search::{ROUNDING, copy, downhill, slope_along, sufficient_decrease};
use objective::{Evaluation, Objective, implicit_velocity};
use settings::{DescentReport, DescentSettings};
use stopping::{StallRule, Stopping};

pub(crate) use coordinates::reference_point;
use coordinates::{split_reference_point, split_translate, translate};
use descend::{Buffers, Descent, Finish, descend, velocity_friction};

/// The iterate a direction is computed at.
pub(crate) struct Iterate<'a, V> {
    /// The positions `x_k` (shifted, see the module documentation).
    pub x: &'a [V],
    /// `grad Phi(x_k)` (N, zero at pinned vertices and fixed coordinates).
    pub gradient: &'a [V],
    /// `|grad Phi(x_k)|` projected on the contacts (N).
    pub residual: Real,
    /// The residual the tolerance asks for (N).
    pub target: Real,
}

/// What [`Direction::search`] is given.
pub(crate) struct Search<'a, F: ElasticEnergy> {
    /// `Phi` and its gradient.
    pub objective: &'a Objective<'a, F>,
    /// The iterate `x` the direction is computed at.
    pub at: &'a Iterate<'a, F::Vector>,
    /// Where the direction `d` goes, plus `momentum` times the last step `x_k - x_{k-1}` when
    /// [`momentum`](Self::momentum) is given (one entry a vertex).
    pub direction: &'a mut [F::Vector],
    /// Heavy-ball momentum (dimensionless), with `x_{k-1}` read from `trial.positions`; `None`
    /// for none.
    pub momentum: Option<Real>,
    /// Where the first trial point `x + step d` goes (projected on the ground, `x` at pinned
    /// vertices), its gradient zeroed.
    pub trial: TrialPoint<'a, F::Vector>,
    /// The first trial step `alpha` along `d` (dimensionless).
    pub step: Real,
}

/// What [`Direction::extrapolate`] is given.
pub(crate) struct Extrapolation<'a, F: ElasticEnergy> {
    /// `Phi` and its gradient.
    pub objective: &'a Objective<'a, F>,
    /// The iterate `x` the trial is extrapolated from.
    pub at: &'a Iterate<'a, F::Vector>,
    /// Whether `trial.positions` hold `x_{k-1}` (the last step is zero otherwise).
    pub stepped: bool,
    /// Where the Chebyshev trial `x + step d + (omega - 1) (x - x_{k-1})` goes, its gradient
    /// zeroed.
    pub trial: TrialPoint<'a, F::Vector>,
    /// The step along `d`: `omega` times the step the last line search accepted
    /// (dimensionless).
    pub step: Real,
    /// The Chebyshev weight `omega` (dimensionless, in `[1, 2)`).
    pub omega: Real,
}

/// The relative change of friction's force factors `mu lambda` from one re-lag to the next
/// below which the directions that do not accelerate through re-lagging
/// ([`Direction::accelerates_with_friction`]) run the Chebyshev semi-iteration again. Measured
/// on the bouncy drop with VBD (ground friction 0.6, sticking speed 1 mm/s and 1 cm/s): 1e-3
/// took 24.5 and 19.8 sweeps per step on average with 89 and 90 of 90 steps converged, against
/// 32.4 and 27.3 sweeps, 88 and 90 converged, without acceleration in contact; 1e-2 and 1e-1
/// took fewer sweeps but each left one step more unconverged in one of the two runs.
const LAG_SETTLED: Real = 1e-3;

/// A search direction `d = -P^-1 grad Phi`: the one thing that distinguishes the solvers.
pub(crate) trait Direction<F: ElasticEnergy> {
    /// Called once at the initial guess `x`, before [`rounding_floor`](Self::rounding_floor) is
    /// first asked for.
    fn begin(&mut self, objective: &Objective<'_, F>, x: &[F::Vector]);

    /// Writes the direction at [`Search::at`] into [`Search::direction`] and the first trial
    /// point into [`Search::trial`] (see the fields). Returns the slope `grad.d` (not negative:
    /// no descent, the solve ends).
    ///
    /// # Errors
    /// The model's errors (a direction that evaluates the Hessian).
    fn search(&mut self, search: Search<'_, F>) -> Result<Real, StepError>;

    /// Writes the Chebyshev trial of [`Extrapolation::trial`] (see the fields). Only called when
    /// the settings ask for acceleration.
    ///
    /// # Errors
    /// The model's errors (a direction that evaluates the contact).
    fn extrapolate(&mut self, extrapolation: Extrapolation<'_, F>) -> Result<(), StepError>;

    /// The estimated rounding floor now (N; a direction may refine it as it goes).
    fn rounding_floor(&self) -> Real;

    /// The absolute rounding of `Phi` (J) the line search tolerates beyond its relative
    /// `sqrt(eps)`: where `Phi`'s change is below it, the line search takes Hager and Zhang's
    /// test from the slopes. 0 (the default) for none.
    fn phi_resolution(&self) -> Real {
        0.0
    }

    /// Whether the Chebyshev semi-iteration may run while a vertex is in a frictional contact
    /// (default `true`); `false` runs plain steps then.
    fn accelerates_with_friction(&self) -> bool {
        true
    }

    /// Called when a direction is not downhill or the first trial of its line search fails:
    /// `true` if the direction has a safer variant to search with from the same iterate
    /// instead (the loop then restarts the acceleration and searches again); `false` (the
    /// default) to backtrack, or to end the solve on a direction that is not downhill.
    fn fall_back(&mut self) -> bool {
        false
    }

    /// Whether, after Coulomb friction on the velocity, the relative target is measured against
    /// the smaller of the residuals at the initial guess and at [`Objective::rigid_guess`]
    /// (evaluated for it where the initial residual exceeds the load: one more energy
    /// evaluation) instead of the initial guess's alone; either way against the load too (the
    /// relaxation; see [`Start::try_rigid`]). `false` (the default) for the initial guess's.
    fn rigid_scale(&self) -> bool {
        false
    }

    /// After [`extrapolate`](Self::extrapolate): an estimate (N) of the residual at the iterate
    /// the trial was extrapolated from, formed by the trial's own work (VBD's Gauss–Seidel
    /// residual), or `None` (the default). With an estimate the loop may accept accelerated
    /// trials without evaluating `Phi` (see [`MAX_DEFERRED`]).
    fn residual_estimate(&self) -> Option<Real> {
        None
    }
}

/// The most accelerated trials in a row the loop accepts without evaluating `Phi`, for a
/// direction that estimates the residual itself ([`Direction::residual_estimate`], VBD) and
/// without friction in `Phi` (whose lag moves with every evaluated iterate). A trial is
/// evaluated as usual (the Chebyshev check on `Phi`, the true residual) while the semi-iteration
/// is young (see [`DEFER_AFTER`]), when the estimate rises, is not finite, or predicts that the
/// trial meets the target (the estimate times the ratio of the true residual to the estimate
/// at the last evaluated iterate, times the estimate's last contraction), or after this many
/// unevaluated ones; the check then
/// compares `Phi` with that of the last evaluated iterate, and a rise (beyond rounding) returns
/// to that iterate, restarts the weights and takes a plain, line-searched step from it, as a
/// rejected trial does. A solve that ends on unevaluated trials evaluates the last one (and
/// returns to the last evaluated iterate if `Phi` rose), so the residual and `Phi` reported
/// are always those of the returned state, and it converged only if that residual meets the
/// tolerance.
pub(crate) const MAX_DEFERRED: u32 = 8;

/// Accelerated trials the Chebyshev check must accept in a row after a (re)start before the
/// loop defers any (see [`MAX_DEFERRED`]); after that the trials deferred between two
/// evaluated ones double with every accepted check, 1, 2, 4, up to `MAX_DEFERRED`.
pub(crate) const DEFER_AFTER: u32 = 3;

/// The settings of the loop (validated by each solver).
#[derive(Clone, Copy)]
pub(crate) struct LoopSettings {
    /// The relative tolerance.
    pub tolerance: Real,
    /// The budget of accepted iterations.
    pub max_iterations: u32,
    /// The Armijo constant `c`.
    pub armijo: Real,
    /// The backtracking factor `beta`.
    pub backtrack: Real,
    /// Rejections allowed per line search.
    pub max_backtracks: u32,
    /// The first trial step of every line search.
    pub step_length: Real,
    /// Heavy-ball momentum (0 for none).
    pub momentum: Real,
    /// The Chebyshev semi-iteration (`rho = 0` and no estimate for none).
    pub acceleration: AccelerationSettings,
    /// The stagnation rule.
    pub stall: StallRule,
    /// Whether to also try [`Objective::rigid_guess`] after Coulomb friction on the velocity
    /// (VBD, see [`Start::try_rigid`]).
    pub rigid_guess: bool,
    /// Whether a quasi-static solve that did not converge restores the start positions, as a
    /// failed one does (Newton's load steps, `newton/continuation.rs`, retry from there).
    pub restore_unconverged: bool,
    /// How many times a full first step that passed the line search may be doubled while the
    /// slope stays steep (`descend.rs`, `Descender::expand`; 0 for never).
    pub max_expansions: u32,
}

impl LoopSettings {
    /// The loop settings of a solver's `settings` (their shared part: tolerance, budget, line
    /// search) with the stagnation rule `stall`, and the plain loop for the rest: every line
    /// search from the full step (`step_length` 1), no momentum, no acceleration, no rigid
    /// guess. A solver with more sets those fields by struct update.
    pub(crate) fn new<O>(settings: &DescentSettings<O>, stall: StallRule) -> Self {
        LoopSettings {
            tolerance: settings.tolerance,
            max_iterations: settings.max_iterations,
            armijo: settings.armijo,
            backtrack: settings.backtrack,
            max_backtracks: settings.max_backtracks,
            step_length: 1.0,
            momentum: 0.0,
            acceleration: AccelerationSettings::NONE,
            stall,
            rigid_guess: false,
            restore_unconverged: false,
            max_expansions: 0,
        }
    }
}

/// What the loop reports: the public report without a solver's details, which each solver
/// adds ([`DescentReport::with_details`]).
pub(crate) type Summary = DescentReport<()>;

/// The problem a solver hands the loop: the model, the per-vertex data and what acts on it.
pub(crate) struct Problem<'p, F: ElasticEnergy> {
    pub model: &'p F,
    pub masses: &'p [Real],
    pub pinned: &'p [bool],
    /// The relaxation's per-vertex stiffness bounds (N/m), or empty.
    pub stiffness: &'p [Real],
    pub gravity: F::Vector,
    /// The ground, with a unit normal.
    pub ground: Option<HalfSpace<F::Vector>>,
    /// The validated colliders (empty for none).
    pub colliders: &'p [Collider<'p>],
    pub loads: Loads<'p, F::Vector>,
    /// `h` (s), or `None` in the quasi-static mode.
    pub dt: Option<Real>,
    /// The previous step's velocities, checked, when the step has inertia and the scene gives
    /// them: the loop's second initial guess is then [`Objective::adaptive_guess`] instead of
    /// `y`.
    pub previous_velocities: Option<&'p [F::Vector]>,
}

impl<'p, F: ElasticEnergy> Problem<'p, F> {
    /// The problem of `model` in `scene` (validated: `ground` is its ground with a unit normal,
    /// `previous_velocities` its checked previous velocities, see [`checked_scene`]),
    /// with inertia (a step of the scene's `dt`) or without (`dynamic` false: quasi-static).
    pub fn new(
        (model, masses, pinned): (&'p F, &'p [Real], &'p [bool]),
        stiffness: &'p [Real],
        scene: &'p Scene<'p, F::Vector>,
        ground: Option<HalfSpace<F::Vector>>,
        previous_velocities: Option<&'p [F::Vector]>,
        dynamic: bool,
    ) -> Self {
        Problem {
            model,
            masses,
            pinned,
            stiffness,
            gravity: scene.gravity,
            ground,
            colliders: scene.colliders,
            loads: scene.loads(),
            dt: dynamic.then_some(scene.dt),
            previous_velocities,
        }
    }

    /// `h` (s) and the inertia weight `1 / h^2` (1/s^2), both 0 in the quasi-static mode: the
    /// one place they are computed, for the loop and for a direction that needs them first.
    #[inline]
    pub fn time_scales(&self) -> (Real, Real) {
        match self.dt {
            Some(dt) => (dt, 1.0 / (dt * dt)),
            None => (0.0, 0.0),
        }
    }
}

impl<'p, F: ElasticEnergy> Problem<'p, F> {
    /// The objective of this problem in the loop's coordinates: `start` the shifted start
    /// positions `x_n`, `velocities` `v_n` (empty without inertia), `ground` and `colliders`
    /// shifted (see the module documentation).
    fn objective<'o>(
        &self,
        start: &'o [F::Vector],
        velocities: &'o [F::Vector],
        ground: Option<&'o HalfSpace<F::Vector>>,
        colliders: Colliders<'o>,
    ) -> Objective<'o, F>
    where
        'p: 'o,
    {
        let (h, inertia) = self.time_scales();
        let friction = Friction::new(ground, colliders, h);
        Objective {
            model: self.model,
            vertices: Vertices {
                masses: self.masses,
                pinned: self.pinned,
                stiffness: self.stiffness,
                start,
                velocities,
            },
            frames: Frames::new(h, inertia, self.gravity, ground)
                .with_colliders(colliders)
                .with_friction(friction),
            h,
            inertia,
            gravity: self.gravity,
            loads: self.loads,
            friction,
            velocity_friction: velocity_friction(ground, colliders),
            previous_velocities: self.previous_velocities,
        }
    }
}

/// What a solver's entry checks ([`checked_solve`]) hand on to the solve.
pub(crate) struct Checked<'s, V> {
    /// The scene's ground, with a unit normal.
    pub ground: Option<HalfSpace<V>>,
    /// The scene's previous velocities, checked, when the step has inertia and gives them.
    pub previous: Option<&'s [V]>,
    /// Whether the solve has inertia (an implicit Euler step) or not (quasi-static).
    pub dynamic: bool,
}

impl<'s, V: Vector> Checked<'s, V> {
    /// The problem of `model` with `masses` and `pinned` in the checked `scene`, `stiffness` the
    /// relaxation's per-vertex bounds (or empty): [`Problem::new`] with what the checks found.
    pub fn problem<'p, F: ElasticEnergy<Vector = V>>(
        &self,
        body: (&'p F, &'p [Real], &'p [bool]),
        stiffness: &'p [Real],
        scene: &'p Scene<'p, V>,
    ) -> Problem<'p, F>
    where
        's: 'p,
    {
        Problem::new(
            body,
            stiffness,
            scene,
            self.ground,
            self.previous,
            self.dynamic,
        )
    }
}

/// The checks every implicit solver runs before it touches anything, in this order (the order
/// of the errors a caller sees): the scene ([`validated_scene`]: the time step only with
/// inertia, `dynamic`), the solver's `settings` (its own check's result), the `state` (masses,
/// positions and velocities: `check_state` or `split_check_state`, run here), the scene's
/// per-vertex buffers ([`checked_scene`]) and the solver's `scratch` lengths (run here).
///
/// # Errors
/// The first of those checks' errors.
pub(crate) fn checked_solve<'s, V: Vector>(
    scene: &Scene<'s, V>,
    vertex_count: usize,
    dynamic: bool,
    settings: Result<(), StepError>,
    state: impl FnOnce() -> Result<(), StepError>,
    scratch: impl FnOnce() -> Result<(), StepError>,
) -> Result<Checked<'s, V>, StepError> {
    let ground = validated_scene(scene, dynamic)?;
    settings?;
    state()?;
    let previous = checked_scene(scene, vertex_count, dynamic)?;
    scratch()?;
    Ok(Checked {
        ground,
        previous,
        dynamic,
    })
}

/// What the entry checks of a solver whose model scans the state in blocks (Newton's method,
/// the relaxation) read: the body (model, masses in kg, pinned flags), the scene, the positions
/// (m) and, for a step with inertia, the velocities (m/s; `None`: quasi-static).
pub(crate) struct SolveInputs<'a, 's, F: ElasticModel> {
    pub body: (&'a F, &'a [Real], &'a [bool]),
    pub scene: &'a Scene<'s, F::Vector>,
    pub positions: &'a [F::Vector],
    pub velocities: Option<&'a [F::Vector]>,
}

impl<'s, F: ElasticModel> SolveInputs<'_, 's, F> {
    /// [`checked_solve`] of these inputs, the state's scans run in blocks by the model
    /// (`split_check_state`), with the solver's own `settings` check and `scratch` lengths.
    ///
    /// # Errors
    /// The first of the checks' errors, in [`checked_solve`]'s order.
    pub fn checked(
        self,
        settings: Result<(), StepError>,
        scratch: impl FnOnce() -> Result<(), StepError>,
    ) -> Result<Checked<'s, F::Vector>, StepError> {
        let SolveInputs {
            body: (model, masses, pinned),
            scene,
            positions,
            velocities,
        } = self;
        checked_solve(
            scene,
            model.vertex_count(),
            velocities.is_some(),
            settings,
            || split_check_state(model, masses, pinned, positions, velocities),
            scratch,
        )
    }
}

/// The scene's checks for a solve of `vertex_count` vertices, the time step only with inertia
/// (`dynamic`): [`Scene::validated`] (or [`Scene::validated_static`]); returns the ground with
/// a unit normal.
pub(crate) fn validated_scene<V: Vector>(
    scene: &Scene<'_, V>,
    dynamic: bool,
) -> Result<Option<HalfSpace<V>>, StepError> {
    if dynamic {
        scene.validated()
    } else {
        scene.validated_static()
    }
}

/// The scene's per-vertex buffers against `vertex_count`: the loads, and with inertia
/// (`dynamic`; they matter nowhere else) the previous velocities, which it returns when given.
///
/// # Errors
/// [`StepError::LengthMismatch`], [`StepError::ExternalForce`], [`StepError::FixedAxes`],
/// and [`StepError::NonFiniteInput`] for the first non-finite previous velocity.
pub(crate) fn checked_scene<'s, V: Vector>(
    scene: &Scene<'s, V>,
    vertex_count: usize,
    dynamic: bool,
) -> Result<Option<&'s [V]>, StepError> {
    scene.loads().check(vertex_count)?;
    let previous = scene.previous_velocities;
    if !dynamic || previous.is_empty() {
        return Ok(None);
    }
    check_length(StepBuffer::PreviousVelocities, vertex_count, previous.len())?;
    match previous.iter().position(|v| !v.is_finite()) {
        Some(vertex) => Err(StepError::NonFiniteInput { vertex }),
        None => Ok(Some(previous)),
    }
}

/// The loop's vector scratch, one entry per vertex each (lengths checked by the solver).
pub(crate) struct Work<'b, V> {
    pub start: &'b mut [V],
    pub gradient: &'b mut [V],
    pub trial_gradient: &'b mut [V],
    pub trial: &'b mut [V],
    pub direction: &'b mut [V],
}

impl<'b, V> Work<'b, V> {
    /// The loop's scratch from the front of a solver's vector buffer, `vertex_count` entries
    /// each (start, gradient, trial gradient, trial point, direction), and the rest of the
    /// buffer. A buffer too short (the solver checked its length) gives empty slices.
    pub fn split(vectors: &'b mut [V], vertex_count: usize) -> (Self, &'b mut [V]) {
        let n = vertex_count;
        let (start, rest) = vectors.split_at_mut_checked(n).unwrap_or_default();
        let (gradient, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
        let (trial_gradient, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
        let (trial, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
        let (direction, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
        let work = Work {
            start,
            gradient,
            trial_gradient,
            trial,
            direction,
        };
        (work, rest)
    }
}

/// Runs one solve: shifts the state next to the body, descends from the initial guess along
/// `direction`, updates the velocities (if given) and shifts back; on any failure restores
/// `positions` and `velocities` bit for bit. Returns the loop's summary.
///
/// # Errors
/// The model's and the direction's errors, [`StepError::NonFiniteState`] (non-finite `Phi` at
/// every initial guess, or a non-finite result).
pub(crate) fn solve<F: ElasticEnergy, D: Direction<F>>(
    problem: &Problem<'_, F>,
    settings: &LoopSettings,
    direction_rule: &mut D,
    positions: &mut [F::Vector],
    velocities: Option<&mut [F::Vector]>,
    work: Work<'_, F::Vector>,
) -> Result<Summary, StepError> {
    let Work {
        start,
        gradient,
        trial_gradient,
        trial,
        direction,
    } = work;
    // The colliders are seen from the shifted coordinates too (`Colliders::shifted`).
    let origin = split_reference_point(problem.model, positions);
    let colliders = shifted_colliders(problem.colliders, origin);
    split_translate(problem.model, positions, -origin, start);
    let start: &[F::Vector] = start;
    let restore = |positions: &mut [F::Vector]| {
        copy(positions, start);
        translate(positions, origin);
    };
    let ground = problem.ground.map(|g| HalfSpace {
        offset: g.offset - g.normal.dot(origin),
        ..g
    });
    let velocities_at_start = velocities.as_deref().unwrap_or(&[]);
    let objective = problem.objective(start, velocities_at_start, ground.as_ref(), colliders);
    let h = objective.h;
    if let Err(error) = problem.model.begin_solve(start, h) {
        restore(positions);
        return Err(error.into());
    }
    let buffers = Buffers {
        gradient,
        trial_gradient,
        trial,
        direction,
    };
    let outcome = descend(&objective, settings, direction_rule, positions, buffers);
    // The ground of the solve, for the velocity update below.
    let floor = Floor::new(ground.as_ref()).with_colliders(colliders);
    let descent = match outcome {
        Ok(descent) => descent,
        Err(error) => {
            restore(positions);
            return Err(error);
        }
    };
    // One pass: the result into `positions` (where the loop left it in the scratch buffer),
    // v = (x_{n+1} - x_n) / h with Coulomb friction at the contacts whose friction did not act
    // in Phi (a zero sticking speed), the caller's velocities backed up into the free scratch
    // buffer, the shift back, and the check of the state the caller gets (the shift back can
    // overflow what was finite next to the body, a ground or collider near the largest float).
    let Descent {
        summary,
        gradient,
        spare,
        in_spare,
    } = descent;
    let finish = Finish {
        ground: ground.as_ref(),
        floor: &floor,
        h,
        origin,
        in_spare,
    };
    match velocities {
        Some(velocities) => {
            let state = (problem.masses, problem.pinned, start, &*gradient);
            let parts = (&mut *positions, &mut *velocities, &mut *spare);
            if let Some(vertex) = finish.implicit(problem.model, parts, state) {
                restore(positions);
                // `spare` holds the caller's velocities.
                copy(velocities, spare);
                return Err(StepError::NonFiniteState { vertex });
            }
        }
        None => {
            if let Some(vertex) = finish.quasi_static(problem.model, positions, spare) {
                restore(positions);
                return Err(StepError::NonFiniteState { vertex });
            }
            if settings.restore_unconverged && !summary.converged {
                restore(positions);
            }
        }
    }
    Ok(summary)
}

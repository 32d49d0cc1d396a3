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
use super::loads::Loads;
use super::model::{ElasticEnergy, ElasticModel};
use super::scene::Scene;
use super::state::check_length;
use super::state::{first_non_finite, pinned_flags};
use super::vertex_pass::passes::{Frames, TrialPoint, Vertices, split_trial_pass};
use super::vertex_pass::point::Grouped;
use super::vertex_pass::{Blocks, Total};
use crate::error::{StepBuffer, StepError};
use chebyshev::{Acceleration, AccelerationSettings};
use line_search::{ROUNDING, copy, downhill, slope_along, sufficient_decrease};
use objective::{Evaluation, Objective, implicit_velocity};
use settings::{DescentReport, DescentSettings};
use stopping::{StallRule, Stopping};

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
    fn extrapolate(&mut self, extrapolation: Extrapolation<'_, F>);

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

/// The reference point the loop's coordinates are measured from (see the module
/// documentation): along every axis on which `m = min_i |x_i| > e = max_i |x_i - x_0|`, the
/// first vertex's coordinate `c = x_0`; zero along the others.
///
/// Every `x_i - c` is then exact. Along such an axis every coordinate has `c`'s sign: one of
/// the other sign would be `|x_i| + |c| >= 2 m > e` from `c`. Say `c > 0` (the negative case is
/// its mirror image) and take any `y = x_i`. Then `y <= c + e < c + m <= 2c`, and `y >= c / 2`:
/// if `m >= c / 2` because `y >= m`, else because `y >= c - e > c - m > c / 2`. So
/// `c / 2 <= y <= 2c`, and `y - c` is exact by Sterbenz's lemma (Goldberg 1991, theorem 11; no
/// underflow: `m > 0`). A body straddling the origin along an axis (`m <= e`) has coordinates no
/// larger than its extent there already, and is not shifted along it.
pub(crate) fn reference_point<V: Vector>(positions: &[V]) -> V {
    positions.first().map_or(V::ZERO, |&first| {
        Extents::of(positions, first).reference_point(first)
    })
}

/// [`reference_point`] with the extents taken in blocks run by `model`: the same point (a
/// minimum and a maximum do not depend on how the vertices are grouped).
fn split_reference_point<V: Vector + Send + Sync>(model: &impl ElasticModel, positions: &[V]) -> V {
    let Some(&first) = positions.first() else {
        return V::ZERO;
    };
    let block = |_, positions: &[V]| Extents::of(positions, first);
    let extents = model.run_vertex_pass(Blocks::new(positions.len(), positions, &block));
    extents.reference_point(first)
}

/// Along each axis (x, y, z), the least `|x_i|` and the largest `|x_i - x_0|` over some
/// vertices (`INFINITY` and 0 over none).
#[derive(Clone, Copy)]
struct Extents([(Real, Real); 3]);

/// The bit of each axis in a fixed-axis mask.
const AXES: [u8; 3] = [1, 2, 4];

impl Extents {
    /// The extents of `positions` about `first`.
    fn of<V: Vector>(positions: &[V], first: V) -> Self {
        let along = |v: V, axis: u8| V::ZERO.axes_from(v, axis).abs_sum();
        let mut extents: [(Real, Real); 3] = [(Real::INFINITY, 0.0); 3];
        for &x in positions {
            for ((nearest, extent), axis) in extents.iter_mut().zip(AXES) {
                *nearest = nearest.min(along(x, axis));
                *extent = extent.max(along(x - first, axis));
            }
        }
        Extents(extents)
    }

    /// The reference point of vertices with these extents about the first vertex, `first`.
    fn reference_point<V: Vector>(self, first: V) -> V {
        let far = self
            .0
            .iter()
            .zip(AXES)
            .filter(|&(&(nearest, extent), axis)| axis & V::ALL_AXES != 0 && nearest > extent)
            .fold(0, |far, (_, axis)| far | axis);
        V::ZERO.axes_from(first, far)
    }
}

impl Total for Extents {
    #[inline(always)]
    fn combine(left: Self, right: Self) -> Self {
        let mut extents = left.0;
        for ((nearest, extent), &(right_nearest, right_extent)) in extents.iter_mut().zip(&right.0)
        {
            *nearest = nearest.min(right_nearest);
            *extent = extent.max(right_extent);
        }
        Extents(extents)
    }
}

/// Adds `shift` to every entry of `values` (`-c` into the loop's coordinates, `c` back).
fn translate<V: Vector>(values: &mut [V], shift: V) {
    if shift != V::ZERO {
        for value in values {
            *value += shift;
        }
    }
}

/// [`translate`] in blocks run by `model`, then (where `copy_to` is not empty) the result
/// copied into `copy_to`, in the same pass.
fn split_translate<V: Vector + Send + Sync>(
    model: &impl ElasticModel,
    values: &mut [V],
    shift: V,
    copy_to: &mut [V],
) {
    let block = |_, (values, copy_to): (&mut [V], &mut [V])| {
        translate(values, shift);
        copy(copy_to, values);
    };
    model.run_vertex_pass(Blocks::new(values.len(), (values, copy_to), &block));
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
    let colliders = F::Vector::shifted_colliders(problem.colliders, origin);
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
        }
    }
    Ok(summary)
}

/// The last pass of a solve, over the vertices in blocks run by the model (see `solve`): the
/// same bits as the passes it replaces (the copy of the result into `positions`, the backup of
/// the velocities, their update, the shift back and the two finiteness checks), in one read of
/// each buffer.
struct Finish<'f, V: Grouped> {
    /// The ground of the solve (shifted), with a unit normal.
    ground: Option<&'f HalfSpace<V>>,
    /// The ground and colliders of the solve (shifted).
    floor: &'f Floor<'f, V>,
    /// `h` (s; unused in the quasi-static mode).
    h: Real,
    /// The reference point of the shift (see [`reference_point`]).
    origin: V,
    /// Whether the result is in the scratch buffer (see [`Descent`]).
    in_spare: bool,
}

/// The mutable buffers of [`Finish::implicit`]: positions, velocities, the scratch buffer.
type FinishBuffers<'p, V> = (&'p mut [V], &'p mut [V], &'p mut [V]);

/// The per-vertex inputs of [`Finish::implicit`]: masses, pinned flags, `x_n` (shifted) and the
/// gradient at the result.
type FinishState<'p, V> = (&'p [Real], &'p [bool], &'p [V], &'p [V]);

impl<V: Vector + Send + Sync> Finish<'_, V> {
    /// `x` in the caller's coordinates: plus `origin` where there is a shift (`x + 0` would
    /// turn a `-0` into `+0`).
    #[inline(always)]
    fn shifted_back(&self, x: V) -> V {
        if self.origin == V::ZERO {
            x
        } else {
            x + self.origin
        }
    }

    /// After an implicit Euler step: per vertex, the result `x` (from the scratch buffer where
    /// it is there), the caller's velocity saved into the scratch buffer, the velocity update
    /// ([`implicit_velocity`]; pinned vertices keep theirs) and `x` shifted back into
    /// `positions`. Returns the first vertex whose position is not finite, or else the first
    /// whose velocity is not.
    fn implicit(
        &self,
        model: &impl ElasticModel,
        (positions, velocities, spare): FinishBuffers<'_, V>,
        (masses, pinned, start, gradient): FinishState<'_, V>,
    ) -> Option<usize> {
        let n = positions.len();
        let block = |first: usize,
                     ((positions, velocities, spare), (masses, pinned, start, gradient)): (
            FinishBuffers<'_, V>,
            FinishState<'_, V>,
        )| {
            let mut non_finite: (Option<usize>, Option<usize>) = (None, None);
            let rows = positions
                .iter_mut()
                .zip(velocities.iter_mut())
                .zip(spare.iter_mut())
                .zip(start.iter().zip(gradient))
                .zip(masses.iter().zip(pinned_flags(pinned)));
            for (i, ((((x, v), other), (&x0, &g)), (&m, pinned))) in rows.enumerate() {
                let result = if self.in_spare { *other } else { *x };
                *other = *v;
                if !pinned {
                    *v = implicit_velocity(self.ground, self.floor, (self.h, m), (result, x0, g));
                }
                *x = self.shifted_back(result);
                if non_finite.0.is_none() && !x.is_finite() {
                    non_finite.0 = Some(first + i);
                }
                if non_finite.1.is_none() && !v.is_finite() {
                    non_finite.1 = Some(first + i);
                }
            }
            non_finite
        };
        let parts = (
            (positions, velocities, spare),
            (masses, pinned, start, gradient),
        );
        let (position, velocity) = model.run_vertex_pass(Blocks::new(n, parts, &block));
        position.or(velocity)
    }

    /// After a quasi-static solve: the result shifted back into `positions`. Returns the first
    /// vertex whose position is not finite.
    fn quasi_static(
        &self,
        model: &impl ElasticModel,
        positions: &mut [V],
        spare: &[V],
    ) -> Option<usize> {
        let block = |first: usize, (positions, spare): (&mut [V], &[V])| {
            let mut non_finite = None;
            for (i, (x, &other)) in positions.iter_mut().zip(spare).enumerate() {
                let result = if self.in_spare { other } else { *x };
                *x = self.shifted_back(result);
                if non_finite.is_none() && !x.is_finite() {
                    non_finite = Some(first + i);
                }
            }
            non_finite
        };
        model.run_vertex_pass(Blocks::new(positions.len(), (positions, spare), &block))
    }
}

/// Whether the ground or a collider applies Coulomb friction to the velocity after the solve
/// (friction with a zero sticking speed, see `implicit_velocities`).
fn velocity_friction<V: Vector>(ground: Option<&HalfSpace<V>>, colliders: Colliders<'_>) -> bool {
    let at_velocity =
        |friction: Real, sticking_speed: Real| friction > 0.0 && sticking_speed <= 0.0;
    ground.is_some_and(|g| at_velocity(g.friction, g.sticking_speed))
        || colliders
            .iter()
            .any(|c| at_velocity(c.friction, c.sticking_speed))
}

/// The mutable scratch of the descent loop.
struct Buffers<'b, V> {
    gradient: &'b mut [V],
    trial_gradient: &'b mut [V],
    trial: &'b mut [V],
    direction: &'b mut [V],
}

/// What the descent loop hands back.
struct Descent<'b, V> {
    summary: Summary,
    /// The final (unprojected) gradient.
    gradient: &'b mut [V],
    /// The scratch point buffer: the result where `in_spare`, free otherwise.
    spare: &'b mut [V],
    /// Whether the result is in `spare` (an odd number of swaps) rather than in `positions`.
    in_spare: bool,
}

/// The descent loop from the initial guess. Returns the summary, the buffer holding the final
/// (unprojected) gradient and the scratch point buffer, which holds the result where the
/// loop ended on it (see [`Descent`]).
///
/// The iterate lives in `positions` or in `trial`, which trade places on every accepted step
/// instead of being copied ([`Points`]): after the swap the other buffer holds `x_{k-1}`, from
/// which the next direction takes the last step `x_k - x_{k-1}` (for momentum and Chebyshev)
/// before overwriting it with the next trial point. The caller's last pass (`finish`) moves the
/// result into `positions` where it is in `trial`.
///
/// The phases: the initial guess ([`Start`]), the target ([`Descender::new`]), then per
/// iteration the stall check, the accelerated trial ([`Descender::accelerated_trial`]) and,
/// where there is none or it is rejected, the plain line-searched step
/// ([`Descender::plain_step`]); last the finish ([`Descender::finish`]: deferred trials settled).
fn descend<'b, F: ElasticEnergy, D: Direction<F>>(
    objective: &Objective<'_, F>,
    settings: &LoopSettings,
    rule: &mut D,
    positions: &mut [F::Vector],
    buffers: Buffers<'b, F::Vector>,
) -> Result<Descent<'b, F::Vector>, StepError> {
    let Buffers {
        gradient,
        trial_gradient,
        trial,
        direction,
    } = buffers;
    let mut points = Points {
        current: &mut *positions,
        gradient,
        other: &mut *trial,
        trial_gradient,
        swapped: false,
    };
    let mut start = Start::inertial(objective, &mut points)?;
    start.try_rigid(objective, settings, &*rule, &mut points)?;
    start.or_start_positions(objective, &mut points)?;
    let mut descender = Descender::new(objective, settings, rule, points, direction, &start);
    descender.run()?;
    let (summary, gradient, in_spare) = descender.finish()?;
    Ok(Descent {
        summary,
        gradient,
        spare: trial,
        in_spare,
    })
}

/// The loop's two points and their gradients: the iterate `current` and `other` (`x_{k-1}`, or
/// a trial point), which trade places on every accepted step instead of being copied.
struct Points<'a, 'b, V> {
    /// The iterate `x_k`.
    current: &'a mut [V],
    /// `grad Phi(x_k)`.
    gradient: &'b mut [V],
    /// `x_{k-1}` where the last step is known, or the trial point.
    other: &'a mut [V],
    /// The gradient at the trial point.
    trial_gradient: &'b mut [V],
    /// Whether `current` is the scratch buffer (an odd number of swaps).
    swapped: bool,
}

impl<V> Points<'_, '_, V> {
    /// The trial point (`other`) becomes the iterate, and the iterate `x_{k-1}`; the gradients
    /// with them.
    fn take_trial(&mut self) {
        self.swap_points();
        swap(&mut self.gradient, &mut self.trial_gradient);
    }

    /// The points alone trade places (a deferred trial, whose gradient is not evaluated).
    fn swap_points(&mut self) {
        swap(&mut self.current, &mut self.other);
        self.swapped = !self.swapped;
    }
}

/// The initial guess's evaluation, what it cost, and what the target is measured against.
struct Start {
    /// `Phi`, `E` and the residual at the guess (in [`Points::current`]).
    evaluation: Evaluation,
    /// The evaluations of `Phi` the guesses took.
    energy_evaluations: u32,
    /// The gravity load `|M g|` (N) on the free vertices ([`Objective::gravity_load`]).
    load: Real,
    /// The smaller of the residuals at the guess and at the rigid guess, where the direction
    /// measures its target against it ([`Direction::rigid_scale`]).
    scale: Option<Real>,
}

impl Start {
    /// The first phase: the better (lower `Phi`) of `y + h^2 g` and `y` (or the adaptive guess)
    /// into `points.current`, evaluated.
    ///
    /// # Errors
    /// The model's.
    fn inertial<F: ElasticEnergy>(
        objective: &Objective<'_, F>,
        points: &mut Points<'_, '_, F::Vector>,
    ) -> Result<Self, StepError> {
        // Initial guess: the better (lower Phi) of the inertial target y and y + h^2 g, both
        // projected on the ground. The second is the predictor of projective dynamics (Bouaziz
        // et al. 2014) and the exact minimiser in free fall, a rigid translation: without it the
        // descent would have to find this lowest, slowest mode of the preconditioned system
        // itself. For a body resting on the ground it is a poor guess (the ground stops the
        // bottom layer and the drop compresses it): y wins there.
        //
        // Where no free vertex touches the ground at either guess (or there is none), and
        // nothing else holds a vertex or pushes it (`Objective::translation_invariant`),
        // y + h^2 g is y moved rigidly by t = h^2 g: the elastic energy is the same, the inertia
        // term grows by sum m |t|^2 / (2 h^2) and the gravity term falls by sum m g.t, twice
        // that, so Phi(y + h^2 g) = Phi(y) - h^2 |g|^2 sum m / 2 < Phi(y), and y is not
        // evaluated (one fused pass of the two a free body's step began with). The evaluated
        // comparison could only have differed where the rounding of the two evaluations
        // exceeded that margin.
        let drop = objective.gravity * (objective.h * objective.h);
        objective.initial_guess(
            TrialPoint {
                positions: points.current,
                gradient: points.gradient,
            },
            drop,
        );
        let mut evaluation = objective.evaluate(points.current, points.gradient, None)?;
        let mut energy_evaluations = 1;
        let translated = drop != F::Vector::ZERO
            && evaluation.phi.is_finite()
            && objective.previous_velocities.is_none()
            && objective.translation_invariant()
            && !objective.touches_ground(drop);
        if drop != F::Vector::ZERO && !translated {
            let second = TrialPoint {
                positions: points.other,
                gradient: points.trial_gradient,
            };
            // With the previous velocities, the adaptive guess (between y and y + h^2 g, vertex
            // by vertex) takes the place of y.
            match objective.previous_velocities {
                Some(previous) => objective.adaptive_guess(second, previous),
                None => objective.initial_guess(second, F::Vector::ZERO),
            }
            let inertial = objective.evaluate(points.other, points.trial_gradient, None)?;
            energy_evaluations += 1;
            // y also wins when y + h^2 g is not finite (NaN compares false).
            if inertial.phi < evaluation.phi || !evaluation.phi.is_finite() {
                points.take_trial();
                evaluation = inertial;
            }
        }
        Ok(Start {
            evaluation,
            energy_evaluations,
            load: objective.gravity_load(),
            scale: None,
        })
    }

    /// The second phase, after Coulomb friction on the velocity only: the rigid guess, as a
    /// start (`settings.rigid_guess`) or as the target's scale ([`Direction::rigid_scale`]).
    ///
    /// # Errors
    /// The model's.
    fn try_rigid<F: ElasticEnergy, D: Direction<F>>(
        &mut self,
        objective: &Objective<'_, F>,
        settings: &LoopSettings,
        rule: &D,
        points: &mut Points<'_, '_, F::Vector>,
    ) -> Result<(), StepError> {
        // After Coulomb friction on the velocity, VBD also tries the rigid guess (y without the
        // shear of the contact vertices' impulses), whose far smaller initial residual sets its
        // relative target; it stops close to it. Measured on the incline of
        // `tests/steppers/colliders` (200 steps at mu 0.1 and 0.3): VBD slid 4.7 % short without
        // it, within 1.8 % with it. Newton's method, which overshoots its target, does not: the
        // guess cost it 29 to 38 % more energy evaluations in f64 and 21 to 32 % more Newton
        // iterations in f32, for a slide within 0.03 % either way. The relaxation does not start
        // from it (starting there left 2 of the bouncy example's first 90 solves, the landing, at
        // their 300-iteration budget) but measures its target against it
        // ([`Direction::rigid_scale`]): against the smaller of the residuals at the start and at
        // the rigid guess (and the load), so that the shear of the friction impulses, an artefact
        // of the guess, does not loosen the target. Measured on the incline at mu 0.3: the f32
        // block slid 3.3 % fast against the start's residual, 0.22 % against this scale (f64
        // -0.56 and +0.05 %), for 50.6 -> 75.0 iterations per step. (Where the start's residual
        // is within the load, the target is the load's either way and the scale needs no rigid
        // guess.)
        if !(objective.velocity_friction
            && (settings.rigid_guess
                || (rule.rigid_scale() && self.evaluation.residual > self.load))
            && objective.h > 0.0
            && self.evaluation.phi.is_finite())
        {
            return Ok(());
        }
        let second = TrialPoint {
            positions: points.other,
            gradient: points.trial_gradient,
        };
        objective.rigid_guess(second);
        let rigid = objective.evaluate(points.other, points.trial_gradient, None)?;
        self.energy_evaluations += 1;
        if rule.rigid_scale() {
            self.scale = Some(rigid.residual.min(self.evaluation.residual));
        }
        if settings.rigid_guess && rigid.phi < self.evaluation.phi {
            points.take_trial();
            self.evaluation = rigid;
        }
        Ok(())
    }

    /// The last phase of the guess: `x_n` where `Phi` is not finite at the guess.
    ///
    /// # Errors
    /// The model's, and [`StepError::NonFiniteState`] where `Phi` is not finite at `x_n`
    /// either.
    fn or_start_positions<F: ElasticEnergy>(
        &mut self,
        objective: &Objective<'_, F>,
        points: &mut Points<'_, '_, F::Vector>,
    ) -> Result<(), StepError> {
        if !self.evaluation.phi.is_finite() {
            // y may invert an element of a barrier model: start from x_n instead.
            copy(points.current, objective.vertices.start);
            points.gradient.fill(F::Vector::ZERO);
            self.evaluation = objective.evaluate(points.current, points.gradient, None)?;
            self.energy_evaluations += 1;
        }
        if !self.evaluation.phi.is_finite() {
            let vertex = first_non_finite(points.gradient, &[]).unwrap_or(0);
            return Err(StepError::NonFiniteState { vertex });
        }
        Ok(())
    }
}

/// What the loop does after a phase of an iteration.
enum Flow {
    /// Go on: the next iteration, if the stopping test and the budget allow.
    Next,
    /// End the loop.
    Stop,
}

/// How a plain step's line search ended.
enum LineSearch {
    /// A trial passed the test, with this evaluation (in `Points::other`).
    Accepted(Evaluation),
    /// The first trial failed and the direction falls back to a safer variant
    /// ([`Direction::fall_back`]): search again from the same iterate.
    Redo,
    /// Every trial failed.
    Failed,
}

/// The descent loop's state from the initial guess on.
struct Descender<'a, 'p, 'b, F: ElasticEnergy, D> {
    objective: &'a Objective<'p, F>,
    settings: &'a LoopSettings,
    rule: &'a mut D,
    points: Points<'a, 'b, F::Vector>,
    /// The direction; while trials are deferred, the last evaluated iterate.
    direction: &'b mut [F::Vector],
    stopping: Stopping,
    /// The report so far: the counts, the initial residual and the target, and `Phi` and the
    /// residual at the last evaluated iterate.
    report: Summary,
    /// Whether `other` holds x_{k-1}, so that the last step is known (false at the start and
    /// after a restart, when it counts as zero).
    stepped: bool,
    /// The step length of the accelerated trials: the one the last plain line search accepted.
    alpha: Real,
    acceleration: Acceleration,
    /// Accelerated trials accepted since the last evaluated iterate (see `MAX_DEFERRED`), which
    /// `direction` then holds, with its gradient in `gradient` and its `Phi` and residual in
    /// `phi` and `residual`.
    deferred: u32,
    /// Evaluated trials the Chebyshev check accepted since the last restart.
    accepted_in_row: u32,
    /// The estimate of the last trial (N).
    last_estimate: Real,
    /// The ratio of the true residual to the estimate at the last evaluated iterate.
    calibration: Real,
    /// How far the last re-lag moved friction's force factors (relative; 1 until the first).
    lag_moved: Real,
}

impl<'a, 'p, 'b, F: ElasticEnergy, D: Direction<F>> Descender<'a, 'p, 'b, F, D> {
    /// The target phase: the stopping test from the residual at the initial guess (or the
    /// scale of [`Start`]) and the load; then the direction's [`begin`](Direction::begin).
    fn new(
        objective: &'a Objective<'p, F>,
        settings: &'a LoopSettings,
        rule: &'a mut D,
        points: Points<'a, 'b, F::Vector>,
        direction: &'b mut [F::Vector],
        start: &Start,
    ) -> Self {
        let initial_residual = start.evaluation.residual;
        let stopping = Stopping::new(
            settings.stall,
            settings.tolerance,
            initial_residual,
            start.scale.unwrap_or(initial_residual).max(start.load),
        );
        let target = stopping.target;
        rule.begin(objective, points.current);
        Descender {
            objective,
            settings,
            rule,
            points,
            direction,
            stopping,
            report: Summary {
                iterations: 0,
                energy_evaluations: start.energy_evaluations,
                backtracks: 0,
                restarts: 0,
                initial_residual,
                residual: initial_residual,
                target,
                rounding_floor: 0.0,
                phi: start.evaluation.phi,
                converged: false,
                stagnated: false,
                rho: 0.0,
                details: (),
            },
            stepped: false,
            alpha: settings.step_length,
            acceleration: Acceleration::new(settings.acceleration),
            deferred: 0,
            accepted_in_row: 0,
            last_estimate: Real::INFINITY,
            calibration: 1.0,
            lag_moved: if objective.friction.is_active() {
                1.0
            } else {
                0.0
            },
        }
    }

    /// The iterations, until the stopping test is met, the budget is spent, the residual
    /// stalls or a step fails.
    ///
    /// # Errors
    /// The model's and the direction's.
    fn run(&mut self) -> Result<(), StepError> {
        while self.stopping.unmet(self.report.residual)
            && self.report.iterations < self.settings.max_iterations
        {
            // Deferred trials count in the stall window as iterations without progress: the
            // window stays one of sweeps, its progress seen at the evaluated ones.
            let floor = self.rule.rounding_floor();
            if self
                .stopping
                .stalled_before(self.report.iterations, self.report.residual, floor)
            {
                break;
            }
            let omega = self.weight();
            if omega > 1.0 && self.accelerated_trial(omega)? {
                continue;
            }
            match self.plain_step()? {
                Flow::Next => {}
                Flow::Stop => break,
            }
        }
        Ok(())
    }

    /// The Chebyshev weight `omega` of this iteration (1 or less: a plain step), the
    /// semi-iteration restarted while friction's re-lagging still moves the contact forces for
    /// a direction that does not accelerate through it.
    fn weight(&mut self) -> Real {
        let omega = self
            .acceleration
            .next_weight(self.report.iterations, self.report.residual);
        if omega > 1.0 && !self.rule.accelerates_with_friction() && self.lag_moved > LAG_SETTLED {
            // The semi-iteration's weights assume one fixed linear iteration; friction's stiff
            // tangent springs and its re-lagging at every accepted point break that for VBD's
            // sweeps while the contact forces still change (measured: the bouncy drop, ground
            // friction 0.6, left 19 of 48 steps unconverged at 3x the load's residual with
            // acceleration throughout; 48 of 48 converged with plain sweeps while in contact).
            // Once the re-lagging stops moving the forces, the objective is one fixed function
            // again and the semi-iteration restarts on it.
            self.acceleration.restart();
            return 1.0;
        }
        omega
    }

    /// The accelerated trial `x + omega alpha d + (omega - 1) (x - x_{k-1})`: deferred (see
    /// [`MAX_DEFERRED`]), or evaluated and accepted where `Phi` did not rise beyond rounding,
    /// or rejected (the weights restarted, back to the last evaluated iterate). Returns whether
    /// the iteration is done (accepted or deferred); `false` asks for a plain step.
    ///
    /// # Errors
    /// The model's.
    fn accelerated_trial(&mut self, omega: Real) -> Result<bool, StepError> {
        let (objective, points) = (self.objective, &mut self.points);
        let at = Iterate {
            x: points.current,
            gradient: points.gradient,
            residual: self.report.residual,
            target: self.report.target,
        };
        let point = TrialPoint {
            positions: points.other,
            gradient: points.trial_gradient,
        };
        self.rule.extrapolate(Extrapolation {
            objective,
            at: &at,
            stepped: self.stepped,
            trial: point,
            step: omega * self.alpha,
            omega,
        });
        objective.loads.restore_fixed(points.current, points.other);
        if self.defers() {
            if self.deferred == 0 {
                copy(self.direction, self.points.current);
            }
            self.deferred += 1;
            self.points.swap_points();
            self.stepped = true;
            self.report.iterations += 1;
            return Ok(true);
        }
        let points = &mut self.points;
        let lag = Lag::new(points.current, points.gradient);
        let extrapolated = objective.evaluate(points.other, points.trial_gradient, Some(lag))?;
        self.report.energy_evaluations += 1;
        let Evaluation {
            phi: trial_phi,
            elastic: trial_elastic,
            ..
        } = extrapolated;
        // The semi-iteration is not monotone in Phi in general, but an increase (beyond
        // rounding) means the nonlinearity or the contacts broke the linear model it
        // relies on: restart from a plain, line-searched step (Wang and Yang's fallback).
        let noise = ROUNDING * (self.report.phi.abs() + trial_phi.abs() + trial_elastic.abs())
            + self.rule.phi_resolution();
        if trial_phi <= self.report.phi + noise {
            self.deferred = 0;
            self.accepted_in_row = self.accepted_in_row.saturating_add(1);
            self.take(extrapolated);
            return Ok(true);
        }
        self.report.restarts += 1;
        self.restart_weights();
        self.accepted_in_row = 0;
        if self.deferred > 0 {
            // Back to the last evaluated iterate.
            copy(self.points.current, self.direction);
            self.deferred = 0;
        }
        Ok(false)
    }

    /// Whether to accept the trial just extrapolated without evaluating `Phi` (see
    /// [`MAX_DEFERRED`]), from the direction's residual estimate; updates the calibration.
    fn defers(&mut self) -> bool {
        let estimate = self.rule.residual_estimate().unwrap_or(Real::NAN);
        if self.deferred == 0 {
            self.calibration = self.report.residual / estimate;
            self.last_estimate = estimate;
        }
        // The trial's residual predicted from the estimate: calibrated at the last evaluated
        // iterate, times the estimate's last contraction.
        let predicted = estimate * self.calibration * (estimate / self.last_estimate);
        let window = match self.accepted_in_row.checked_sub(DEFER_AFTER) {
            Some(doublings) => MAX_DEFERRED.min(1 << doublings.min(8)),
            None => 0,
        };
        let defer = self.deferred < window
            && !self.objective.friction.is_active()
            && predicted > self.report.target
            && estimate <= self.last_estimate;
        self.last_estimate = estimate;
        defer
    }

    /// The plain step: the direction, then the Armijo line search along it; the accepted
    /// point becomes the iterate, and the stall check follows.
    ///
    /// # Errors
    /// The model's and the direction's.
    fn plain_step(&mut self) -> Result<Flow, StepError> {
        // Trials are deferred only inside the accelerated branch above, and every way out of it
        // that falls through to here (a rejected trial) settles them first. Once a trial was
        // deferred the semi-iteration's weight stays above 1 until a restart (the Chebyshev
        // recurrence with rho > 0), friction is off (deferral needs it off, so `lag_moved` is
        // 0) and the next pass takes the accelerated branch again: a plain step never sees a
        // deferred iterate. Every debug-build test that runs accelerated descent checks it.
        debug_assert_eq!(
            self.deferred, 0,
            "a plain descent step on a deferred iterate"
        );
        let slope = self.search()?;
        if !downhill(slope) {
            if self.rule.fall_back() {
                self.restart_weights();
                return Ok(Flow::Next);
            }
            self.stopping.failed();
            return Ok(Flow::Stop); // stationary to rounding
        }
        let evaluation = match self.line_search(slope)? {
            LineSearch::Accepted(evaluation) => evaluation,
            LineSearch::Redo => {
                // The trial overwrote x_(k-1): the last step is unknown again.
                self.restart_weights();
                return Ok(Flow::Next);
            }
            LineSearch::Failed => {
                self.stopping.failed();
                return Ok(Flow::Stop);
            }
        };
        let previous = self.report.residual;
        self.take(evaluation);
        let floor = self.rule.rounding_floor();
        if self
            .stopping
            .stalled_after(previous, self.report.residual, floor)
        {
            return Ok(Flow::Stop);
        }
        Ok(Flow::Next)
    }

    /// The plain step's direction and first trial point: `d = -P^-1 g` (+ momentum * last
    /// step), projected; plain descent if that is not downhill. The same pass writes the first
    /// trial point, at the full step. Returns the slope `g.d`.
    ///
    /// # Errors
    /// The direction's.
    fn search(&mut self) -> Result<Real, StepError> {
        let settings = self.settings;
        self.alpha = settings.step_length;
        let momentum = (self.stepped && settings.momentum > 0.0).then_some(settings.momentum);
        let points = &mut self.points;
        let at = Iterate {
            x: points.current,
            gradient: points.gradient,
            residual: self.report.residual,
            target: self.report.target,
        };
        let (rule, direction, step) = (&mut *self.rule, &mut *self.direction, self.alpha);
        let mut search = |momentum| {
            rule.search(Search {
                objective: self.objective,
                at: &at,
                direction: &mut *direction,
                momentum,
                trial: TrialPoint {
                    positions: &mut *points.other,
                    gradient: &mut *points.trial_gradient,
                },
                step,
            })
        };
        let mut slope = search(momentum)?;
        if !downhill(slope) && momentum.is_some() {
            slope = search(None)?;
        }
        self.objective
            .loads
            .restore_fixed(points.current, points.other);
        Ok(slope)
    }

    /// The backtracking line search along the direction from the first trial point: each trial
    /// evaluated (friction lagged to the iterate) and tested.
    ///
    /// # Errors
    /// The model's.
    fn line_search(&mut self, slope: Real) -> Result<LineSearch, StepError> {
        let (objective, settings) = (self.objective, self.settings);
        let points = &mut self.points;
        for attempt in 0..=settings.max_backtracks {
            if attempt > 0 {
                split_trial_pass(
                    objective.model,
                    &objective.frames,
                    objective.vertices.pinned,
                    (points.current, self.direction),
                    self.alpha,
                    TrialPoint {
                        positions: points.other,
                        gradient: points.trial_gradient,
                    },
                );
                objective.loads.restore_fixed(points.current, points.other);
            }
            let lag = Lag::new(points.current, points.gradient);
            let evaluation = objective.evaluate(points.other, points.trial_gradient, Some(lag))?;
            self.report.energy_evaluations += 1;
            let (trial_phi, trial_elastic) = (evaluation.phi, evaluation.elastic);
            // Armijo on Phi, or, where Phi's change is below its rounding, Hager and Zhang's
            // approximate Armijo test (see `line_search.rs`).
            let trial_gradient: &[F::Vector] = points.trial_gradient;
            let direction: &[F::Vector] = self.direction;
            let sufficient = sufficient_decrease(
                (self.report.phi, trial_phi, trial_elastic),
                settings.armijo,
                self.alpha,
                slope,
                || slope_along(trial_gradient, direction),
            );
            let resolution = self.rule.phi_resolution();
            if sufficient
                || (resolution > 0.0
                    && trial_phi <= self.report.phi + resolution
                    && slope_along(trial_gradient, direction)
                        <= (2.0 * settings.armijo - 1.0) * slope)
            {
                return Ok(LineSearch::Accepted(evaluation));
            }
            if attempt == 0 && self.rule.fall_back() {
                return Ok(LineSearch::Redo);
            }
            self.alpha *= settings.backtrack;
            self.report.backtracks += 1;
        }
        Ok(LineSearch::Failed)
    }

    /// The evaluated trial point becomes the iterate: friction re-lagged to it, the points
    /// swapped, its `Phi` and residual taken.
    fn take(&mut self, mut evaluation: Evaluation) {
        let points = &mut self.points;
        self.lag_moved = self.objective.relag(
            points.other,
            points.trial_gradient,
            Lag::new(points.current, points.gradient),
            &mut evaluation,
        );
        points.take_trial();
        self.stepped = true;
        self.report.phi = evaluation.phi;
        self.report.iterations += 1;
        self.report.residual = evaluation.residual;
    }

    /// The acceleration restarts with a plain step, the last step unknown.
    fn restart_weights(&mut self) {
        self.acceleration.restart();
        self.stepped = false;
    }

    /// The finish: the deferred trials settled (see [`settle`]) and the summary. Returns it,
    /// the buffer holding the final gradient, and whether the result is in the scratch buffer.
    ///
    /// # Errors
    /// The model's.
    fn finish(mut self) -> Result<(Summary, &'b mut [F::Vector], bool), StepError> {
        if self.deferred > 0 {
            let points = &mut self.points;
            let settled = settle(
                self.objective,
                (&mut *points.current, &*self.direction),
                &mut points.gradient,
                &mut points.trial_gradient,
                (&mut self.report.phi, &mut self.report.residual),
                self.rule.phi_resolution(),
            )?;
            self.report.energy_evaluations += 1;
            self.report.restarts += u32::from(!settled);
        }
        let rounding_floor = self.rule.rounding_floor();
        let summary = Summary {
            rounding_floor,
            converged: self
                .stopping
                .converged(self.report.residual, rounding_floor),
            stagnated: self.stopping.stagnated,
            rho: self.acceleration.rho(),
            ..self.report
        };
        Ok((summary, self.points.gradient, self.points.swapped))
    }
}

/// Evaluates the last of the accelerated trials the loop accepted without evaluating `Phi`,
/// `current` (see [`MAX_DEFERRED`]): kept, with its gradient in `gradient` (swapped with the
/// free `spare`) and its `Phi` and residual in `phi` and `residual`, if its `Phi` is not above
/// the last evaluated iterate's (`checkpoint`, whose gradient, `Phi` and residual those hold)
/// beyond rounding; otherwise `current` is returned to `checkpoint`. Returns whether it was
/// kept. Only without friction in `Phi` (nothing to lag).
///
/// # Errors
/// The model's.
fn settle<'b, F: ElasticEnergy>(
    objective: &Objective<'_, F>,
    (current, checkpoint): (&mut [F::Vector], &[F::Vector]),
    gradient: &mut &'b mut [F::Vector],
    spare: &mut &'b mut [F::Vector],
    (phi, residual): (&mut Real, &mut Real),
    resolution: Real,
) -> Result<bool, StepError> {
    let evaluation = objective.evaluate(current, spare, None)?;
    let noise =
        ROUNDING * (phi.abs() + evaluation.phi.abs() + evaluation.elastic.abs()) + resolution;
    if evaluation.phi <= *phi + noise {
        swap(gradient, spare);
        *phi = evaluation.phi;
        *residual = evaluation.residual;
        Ok(true)
    } else {
        copy(current, checkpoint);
        Ok(false)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::super::super::types::{Real, Vec2, Vec3};
    use super::super::vertex_pass::{Total, VERTEX_BLOCK};
    use super::{Extents, reference_point};

    /// A 0.4 x 0.1 x 0.1 m grid of points, moved by `offset`.
    fn grid(offset: Vec3) -> Vec<Vec3> {
        let mut points = Vec::new();
        for i in 0..=8 {
            for j in 0..=3 {
                for k in 0..=3 {
                    let p = Vec3::new(0.05 * i as Real, j as Real / 30.0, k as Real / 30.0);
                    points.push(p + offset);
                }
            }
        }
        points
    }

    #[test]
    fn a_body_straddling_the_origin_is_not_shifted() {
        assert_eq!(reference_point(&grid(Vec3::ZERO)), Vec3::ZERO);
        // 0.35 m away along x is within the body's extent (0.4 m): not shifted along x; 0.05 m
        // along y and z, within 0.1 m: not shifted there either.
        let near = Vec3::new(0.35, 0.05, -0.15);
        assert_eq!(reference_point(&grid(near)), Vec3::ZERO);
        assert_eq!(reference_point::<Vec3>(&[]), Vec3::ZERO);
        // A coordinate of zero (or minus zero) everywhere is never shifted: `m > e` fails.
        let flat = [Vec3::new(0.0, -0.0, 1.0), Vec3::new(0.0, -0.0, 1.0)];
        assert_eq!(
            reference_point(&flat).to_array().map(Real::to_bits)[..2],
            [0, 0]
        );
    }

    #[test]
    fn far_axes_take_the_first_vertex_and_the_shift_is_exact() {
        for offset in [
            Vec3::new(0.45, 0.0, 0.0),
            Vec3::new(60.0, 0.0, 0.0),
            Vec3::new(-60.0, 0.0, 0.25),
            Vec3::new(1e4, -1e4, 1e4),
        ] {
            let points = grid(offset);
            let c = reference_point(&points);
            // Along x the body is 0.4 m wide, along y and z 0.1 m: far where |offset| > that.
            let expected = |far: bool, value: Real| if far { value } else { 0.0 };
            let first = points[0];
            assert_eq!(c.x, expected(offset.x.abs() > 0.4, first.x), "{offset}");
            assert_eq!(c.y, expected(offset.y.abs() > 0.1, first.y), "{offset}");
            assert_eq!(c.z, expected(offset.z.abs() > 0.1, first.z), "{offset}");
            for &p in &points {
                // Exact both ways (Sterbenz): the shifted point comes back bit for bit.
                assert_eq!((p - c) + c, p, "{offset}: {p}");
                assert!((p - c).abs().max_element() <= 0.41, "{offset}: {p}");
            }
        }
    }

    /// `a - b` is exact: the rounding error of the difference by Knuth's TwoSum (itself exact
    /// in round-to-nearest) is zero.
    fn exact_difference(a: Real, b: Real) -> bool {
        let (a, b) = (a, -b);
        let s = a + b;
        let b_part = s - a;
        let error = (a - (s - b_part)) + (b - b_part);
        error == 0.0
    }

    /// The proof in [`reference_point`]'s documentation, checked on point sets built at the edge
    /// of the rule: pseudo-random sets whose nearest coordinate lies just above, at or just
    /// below their extent, in both signs and over many magnitudes, with the first vertex
    /// anywhere in the set. Wherever the rule shifts, every difference from the reference point
    /// is exact; and it shifts the sets just above the edge.
    #[test]
    fn wherever_the_rule_shifts_every_difference_is_exact() {
        let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut shifted = 0;
        for set in 0..4000 {
            // The set spans [lo, hi] with lo = width * ratio, the ratio near 1 (the edge).
            let scale = libm::pow(10.0, 6.0 * next() - 3.0);
            let ratio = [1.0 + 1e-6, 1.0, 1.0 - 1e-6, 1.0 + next(), 0.5 + next()][set % 5];
            let sign = if next() < 0.5 { -1.0 } else { 1.0 };
            let width = scale;
            let lo = width * ratio;
            let values: Vec<Real> = (0..17)
                .map(|k| {
                    let t = match k {
                        0 => next(),
                        1 => 0.0,
                        2 => 1.0,
                        _ => next(),
                    };
                    (sign * (lo + width * t)) as Real
                })
                .collect();
            let points: Vec<Vec3> = values.iter().map(|&v| Vec3::new(v, 0.0, 0.0)).collect();
            let c = reference_point(&points).x;
            if c == 0.0 {
                continue;
            }
            shifted += 1;
            assert_eq!(c, values[0]);
            for &y in &values {
                assert!(exact_difference(y, c), "set {set}: {y} - {c}");
            }
        }
        // Every set whose rounded nearest coordinate exceeds its rounded extent shifts: most
        // of those above the edge, none of those well below it.
        assert!(shifted > 1500, "{shifted} of 4000");
    }

    #[test]
    fn two_dimensional_points_shift_along_their_two_axes() {
        let points = [
            Vec2::new(60.0, 0.0),
            Vec2::new(60.5, 0.1),
            Vec2::new(60.25, 0.05),
        ];
        assert_eq!(reference_point(&points), Vec2::new(60.0, 0.0));
    }

    /// The extents of a body taken in two parts and combined are those of the whole body, bit
    /// for bit, wherever it is cut (the split reference point is the one-pass one), on a body
    /// far from the origin whose points are not sorted along any axis.
    #[test]
    fn extents_combined_over_any_cut_are_the_whole_body_s() {
        let points: Vec<Vec3> = (0..3 * VERTEX_BLOCK + 5)
            .map(|i| {
                let t = i as Real;
                Vec3::new(
                    60.0 + (t * 0.37).sin(),
                    -1e3 + (t * 1.3).cos(),
                    0.25 * (t * 0.11).sin(),
                )
            })
            .collect();
        let first = points[0];
        let whole = Extents::of(&points, first);
        for cut in [0, 1, VERTEX_BLOCK, 2 * VERTEX_BLOCK + 3, points.len()] {
            let (left, right) = points.split_at(cut);
            let combined = Extents::combine(Extents::of(left, first), Extents::of(right, first));
            for ((a, b), (c, d)) in combined.0.iter().zip(&whole.0) {
                assert_eq!(
                    (a.to_bits(), b.to_bits()),
                    (c.to_bits(), d.to_bits()),
                    "cut {cut}"
                );
            }
            assert_eq!(combined.reference_point(first), reference_point(&points));
        }
        // Far along x (|x| >= 59 against an extent of at most 2) and y (|y| ~ 1e3, extent 2),
        // near along z (|z| down to 0), as the rule says.
        assert_eq!(reference_point(&points), Vec3::new(first.x, first.y, 0.0));
    }
}

//! The descent loop in named phases: [`Start`] picks the initial guess, [`Descender`] sets the
//! target and iterates (accelerated trials, plain line-searched steps, stall and stop checks)
//! and [`Finish`] writes the result back in one pass; [`settle`] takes a state that needs no
//! iteration.

use super::*;

/// The last pass of a solve, over the vertices in blocks run by the model (see `solve`): the
/// same bits as the passes it replaces (the copy of the result into `positions`, the backup of
/// the velocities, their update, the shift back and the two finiteness checks), in one read of
/// each buffer.
pub(super) struct Finish<'f, V: Grouped> {
    /// The ground of the solve (shifted), with a unit normal.
    pub(super) ground: Option<&'f HalfSpace<V>>,
    /// The ground and colliders of the solve (shifted).
    pub(super) floor: &'f Floor<'f, V>,
    /// `h` (s; unused in the quasi-static mode).
    pub(super) h: Real,
    /// The reference point of the shift (see [`reference_point`]).
    pub(super) origin: V,
    /// Whether the result is in the scratch buffer (see [`Descent`]).
    pub(super) in_spare: bool,
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
    pub(super) fn shifted_back(&self, x: V) -> V {
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
    pub(super) fn implicit(
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
    pub(super) fn quasi_static(
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
pub(super) fn velocity_friction<V: Vector>(
    ground: Option<&HalfSpace<V>>,
    colliders: Colliders<'_>,
) -> bool {
    let at_velocity =
        |friction: Real, sticking_speed: Real| friction > 0.0 && sticking_speed <= 0.0;
    ground.is_some_and(|g| at_velocity(g.friction, g.sticking_speed))
        || colliders
            .iter()
            .any(|c| at_velocity(c.friction, c.sticking_speed))
}

/// The mutable scratch of the descent loop.
pub(super) struct Buffers<'b, V> {
    pub(super) gradient: &'b mut [V],
    pub(super) trial_gradient: &'b mut [V],
    pub(super) trial: &'b mut [V],
    pub(super) direction: &'b mut [V],
}

/// What the descent loop hands back.
pub(super) struct Descent<'b, V> {
    pub(super) summary: Summary,
    /// The final (unprojected) gradient.
    pub(super) gradient: &'b mut [V],
    /// The scratch point buffer: the result where `in_spare`, free otherwise.
    pub(super) spare: &'b mut [V],
    /// Whether the result is in `spare` (an odd number of swaps) rather than in `positions`.
    pub(super) in_spare: bool,
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
pub(super) fn descend<'b, F: ElasticEnergy, D: Direction<F>>(
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
pub(super) struct Points<'a, 'b, V> {
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
pub(super) struct Start {
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
        let pulled_back = admit_guess(objective, points.current)?;
        let mut evaluation = objective.evaluate(points.current, points.gradient, None)?;
        let mut energy_evaluations = 1;
        let translated = drop != F::Vector::ZERO
            && !pulled_back
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
            admit_guess(objective, points.other)?;
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
        admit_guess(objective, points.other)?;
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

/// How many times [`admit_guess`] pulls a guess back before it falls back to the start.
const GUESS_PULLS: u32 = 4;

/// Pulls the initial guess in `positions` back toward the start positions `x_n` along the
/// straight line between them, to the fraction of it the model admits
/// ([`ElasticEnergy::admissible_step`]), so that the guess is reached from `x_n` without passing
/// a surface through another; after [`GUESS_PULLS`] pulls that leave it inadmissible (rounding
/// of the pulled positions), `x_n` itself. Pinned vertices and fixed coordinates hold `x_n`'s
/// values in both, and keep them. Returns whether the guess moved. A model without contact
/// admits every guess: one call, nothing written.
///
/// # Errors
/// The model's.
fn admit_guess<F: ElasticEnergy>(
    objective: &Objective<'_, F>,
    positions: &mut [F::Vector],
) -> Result<bool, StepError> {
    let start = objective.vertices.start;
    let mut admitted = objective.model.admissible_step(start, positions)?;
    if admitted >= 1.0 {
        return Ok(false);
    }
    for _ in 0..GUESS_PULLS {
        for (x, &x0) in positions.iter_mut().zip(start) {
            if *x != x0 {
                *x = x0 + (*x - x0) * admitted;
            }
        }
        admitted = objective.model.admissible_step(start, positions)?;
        if admitted >= 1.0 {
            return Ok(true);
        }
    }
    copy(positions, start);
    Ok(true)
}

/// The fraction of the iterate's slope `g.d` that the slope at an accepted full step must
/// still exceed in magnitude for the step to be doubled ([`Descender::expand`]): Wolfe's
/// curvature constant `c2` of a Newton line search is 0.9 ([NW06] section 3.1); 0.5 doubles
/// only where the step was clearly short.
const EXPAND_SLOPE: Real = 0.5;

/// A trial point's evaluation, or `None` where the model did not admit the step.
struct Trial(Option<Evaluation>);

impl Trial {
    /// The evaluation where `keep` holds and the step was admitted.
    fn filter(self, keep: bool) -> Option<Evaluation> {
        self.0.filter(|_| keep)
    }

    /// `Phi` at the trial (infinite where the step was not admitted).
    #[inline]
    fn phi(&self) -> Real {
        self.0.as_ref().map_or(Real::INFINITY, |e| e.phi)
    }
}

/// What the loop does after a phase of an iteration.
pub(super) enum Flow {
    /// Go on: the next iteration, if the stopping test and the budget allow.
    Next,
    /// End the loop.
    Stop,
}

/// How a plain step's line search ended.
pub(super) enum LineSearch {
    /// A trial passed the test, with this evaluation (in `Points::other`).
    Accepted(Evaluation),
    /// The first trial failed and the direction falls back to a safer variant
    /// ([`Direction::fall_back`]): search again from the same iterate.
    Redo,
    /// Every trial failed.
    Failed,
}

/// The descent loop's state from the initial guess on.
pub(super) struct Descender<'a, 'p, 'b, F: ElasticEnergy, D> {
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
        })?;
        objective.loads.restore_fixed(points.current, points.other);
        // A trial the model does not admit (it would pass a surface through another) is
        // rejected as one that raised Phi.
        let admitted = objective
            .model
            .admissible_step(points.current, points.other)?
            >= 1.0;
        if admitted && self.defers() {
            if self.deferred == 0 {
                copy(self.direction, self.points.current);
            }
            self.deferred += 1;
            self.points.swap_points();
            self.stepped = true;
            self.report.iterations += 1;
            return Ok(true);
        }
        if admitted {
            let points = &mut self.points;
            let lag = Lag::new(points.current, points.gradient);
            let extrapolated =
                objective.evaluate(points.other, points.trial_gradient, Some(lag))?;
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
        for attempt in 0..=settings.max_backtracks {
            if attempt > 0 {
                self.form_trial();
            }
            let points = &mut self.points;
            // A trial the model does not admit (contact: a surface would pass through another
            // on the way) is not evaluated: the step shrinks to the admitted fraction, and the
            // trial is formed again there.
            let admitted = objective
                .model
                .admissible_step(points.current, points.other)?;
            if admitted < 1.0 {
                self.alpha *= admitted;
                self.report.backtracks += 1;
                continue;
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
                if attempt == 0 && settings.max_expansions > 0 {
                    return self.expand(slope, evaluation);
                }
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

    /// After a full first step passed the line search: while the slope at the accepted point
    /// is still more than [`EXPAND_SLOPE`] times the slope at the iterate (the curvature test
    /// of Wolfe's conditions fails: the direction's model was too stiff along it, as the
    /// projected Hessian is along a buckling mode), the step is doubled, up to
    /// `max_expansions` times, and kept where `Phi` falls further and still passes the Armijo
    /// test; the first doubling that does not goes back to the last step kept (evaluated
    /// again: the trial buffer held the rejected point). Nocedal and Wright's bracketing phase
    /// of a Wolfe line search ([NW06] algorithm 3.5, `docs/math.md` section 7.1.5).
    ///
    /// # Errors
    /// The model's.
    fn expand(&mut self, slope: Real, accepted: Evaluation) -> Result<LineSearch, StepError> {
        let settings = self.settings;
        let mut best = accepted;
        for _ in 0..settings.max_expansions {
            let points = &mut self.points;
            let trial_slope = slope_along(&*points.trial_gradient, &*self.direction);
            let steep = trial_slope <= EXPAND_SLOPE * slope;
            if !steep {
                break;
            }
            let kept = self.alpha;
            self.alpha *= 2.0;
            let trial = self.evaluate_trial()?;
            let phi = trial.phi();
            let sufficient = phi.is_finite()
                && phi < best.phi
                && phi - self.report.phi <= settings.armijo * self.alpha * slope;
            if let Some(evaluation) = trial.filter(sufficient) {
                best = evaluation;
                continue;
            }
            self.alpha = kept;
            match self.evaluate_trial()?.filter(true) {
                Some(evaluation) => best = evaluation,
                None => break,
            }
            break;
        }
        Ok(LineSearch::Accepted(best))
    }

    /// Forms the trial point `x + alpha d` in the trial buffer (projected on the contacts, `x`
    /// at pinned vertices, fixed coordinates kept), its gradient zeroed.
    fn form_trial(&mut self) {
        let objective = self.objective;
        let points = &mut self.points;
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

    /// Forms the trial point at the step `alpha` along the direction and evaluates it
    /// (friction lagged to the iterate); `None` inside where the model does not admit the
    /// step (contact).
    ///
    /// # Errors
    /// The model's.
    fn evaluate_trial(&mut self) -> Result<Trial, StepError> {
        let objective = self.objective;
        self.form_trial();
        let points = &mut self.points;
        if objective
            .model
            .admissible_step(points.current, points.other)?
            < 1.0
        {
            return Ok(Trial(None));
        }
        let lag = Lag::new(points.current, points.gradient);
        let evaluation = objective.evaluate(points.other, points.trial_gradient, Some(lag))?;
        self.report.energy_evaluations += 1;
        Ok(Trial(Some(evaluation)))
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
pub(super) fn settle<'b, F: ElasticEnergy>(
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

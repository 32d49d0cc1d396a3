//! Dynamic rigid bodies solved with the soft bodies they touch (`docs/math.md` section 8.15): a
//! [`Collider`] given a mass and inertia ([`Collider::with_mass`]) whose end-of-step velocity is
//! an unknown of the same implicit Euler step as the soft body's positions.
//!
//! The step's equations are the soft body's (its objective at the collider's end-of-step pose,
//! whose contact holds it outside) and the rigid body's implicit Euler momentum balance with the
//! contact impulse the soft body applied:
//!
//! * `M (v - v0) = M g dt + J`, `p = p0 + dt v`,
//! * `I(R) w - I(R0) w0 = L`, `R = exp(dt w) R0`,
//!
//! `J` and `L` the impulse and its moment about the centre of mass `p` that the soft step
//! reports ([`Reaction`]), `I(R) = R diag(I) R^T`. [`couple`] solves them together by a
//! fixed-point iteration on the rigid velocities `u = (v, w)`: the soft step with each collider
//! at the pose `u` gives it, then the momentum balance gives `G(u)`, relaxed by Aitken's
//! dynamic factor (Irons and Tuck 1969; Küttler and Wall 2008) until `|G(u) - u|` meets the
//! tolerance. Its fixed point is the solution of the coupled step: the soft body's state and the
//! rigid bodies' velocities that satisfy both sets of equations at once, which the staggered
//! scheme of section 8.14 only approaches when `dt < 2 sqrt(M / k)`.

use super::super::super::math;
use super::super::super::types::{Real, Vec3};
use super::super::scene::{Scene, check_time_step};
use super::super::state::check_length;
use super::collider::{Collider, check_colliders, rotate, rotate_back};
use super::reaction::Reaction;
use crate::error::{StepBuffer, StepError};

/// How many dynamic colliders one coupled step takes: their start states and iterates sit on
/// the stack (about 200 bytes each in f32, 400 in f64): 16 on a host, 4 on bare metal
/// (`target_os = "none"`).
pub const MAX_DYNAMIC_COLLIDERS: usize = if cfg!(target_os = "none") { 4 } else { 16 };

/// How the coupled step ([`Body::step_with_rigid_bodies`](crate::body::Body::step_with_rigid_bodies))
/// iterates between the soft body and its dynamic colliders.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CouplingSettings {
    /// The relative tolerance (dimensionless, finite `> 0`; default `1e-3`): the iteration
    /// stops when, for every dynamic collider, `|G(u) - u|` is at most `tolerance` times the
    /// speeds that set its scale, `|v0| + |v| + |J| / M + rho (|w0| + |w|) + |g| dt` (`rho` the largest
    /// radius of gyration, m; velocities in m/s and rad/s), plus what the soft step's own
    /// tolerance leaves uncertain in the collider's velocity, `n dt r / M` (`r` the force the
    /// soft solve left unbalanced, its report's `residual`, N, at each of the `n` vertices
    /// touching the collider): the coupling cannot be solved more exactly than the soft step
    /// it iterates.
    pub tolerance: Real,
    /// The most soft steps one coupled step runs (`>= 1`; default 30).
    pub max_iterations: u32,
}

impl CouplingSettings {
    /// Tolerance `1e-3`, at most 30 soft steps. At rest, a soft step solved to Newton's
    /// default relative tolerance (`1e-4`) in f32 leaves the impulse it reports uncertain by a
    /// few `1e-4` of the speeds above: a tighter coupling tolerance needs a tighter soft one.
    pub const DEFAULT: CouplingSettings = CouplingSettings {
        tolerance: 1e-3,
        max_iterations: 30,
    };

    /// Whether the settings are in range.
    pub(crate) fn valid(&self) -> bool {
        self.tolerance > 0.0 && self.tolerance.is_finite() && self.max_iterations >= 1
    }
}

impl Default for CouplingSettings {
    #[inline]
    fn default() -> Self {
        CouplingSettings::DEFAULT
    }
}

/// What the coupling iteration of one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CouplingReport {
    /// The soft steps run (1 without a dynamic collider, or where none touched the body; one
    /// beyond the budget where it ran out and an earlier iterate was better).
    pub iterations: u32,
    /// Whether `|G(u) - u|` met the tolerance of [`CouplingSettings`] for every dynamic
    /// collider. `false` means the budget ran out: the iterate of the smallest residual is
    /// kept (the soft body's state and the colliders' poses of a soft step run there, the
    /// colliders' velocities from its momentum balance).
    pub converged: bool,
    /// The largest `|G(u) - u|` over the dynamic colliders at the last iterate, rotation
    /// scaled by the radius of gyration (m/s).
    pub residual: Real,
}

/// A dynamic collider's state at the step's start and its iterate.
#[derive(Clone, Copy)]
struct Rigid {
    /// Its index in the collider slice.
    index: usize,
    start: Collider<'static>,
    /// The velocities the soft step sees: `u = (v, w)`, the trial.
    velocity: Vec3,
    angular: Vec3,
    /// The iterate of the smallest residual so far.
    best: (Vec3, Vec3),
    /// The last accepted iterate, its residual `G(u) - u` (rotation scaled by `rho`) and
    /// whether the collider touched the body there.
    base: (Vec3, Vec3),
    residual: [Vec3; 2],
    touched: bool,
    /// The trial's momentum balance `G(u)`, its residual and contact.
    balance: (Vec3, Vec3),
    trial_residual: [Vec3; 2],
    trial_touched: bool,
    /// `sqrt(max I / M)` (m).
    gyration: Real,
}

/// The collider `start` (static shape data dropped: only its pose, velocities and mass
/// properties are kept, the shape is read from the caller's slice) with velocities `u`, moved
/// over `dt` with them: the pose the soft step sees.
fn trial_pose(start: &Collider<'_>, (velocity, angular): (Vec3, Vec3), dt: Real) -> (Vec3, [Real; 4]) {
    let moved = start.with_velocity(velocity, angular).advanced(dt);
    (moved.position, moved.unit_rotation())
}

/// `R diag(moments) R^T v` for the unit rotation `q`.
fn inertia_times(q: [Real; 4], moments: Vec3, v: Vec3) -> Vec3 {
    rotate(q, rotate_back(q, v) * moments)
}

/// `R diag(moments)^-1 R^T v`.
fn inertia_solve(q: [Real; 4], moments: Vec3, v: Vec3) -> Vec3 {
    rotate(q, rotate_back(q, v) / moments)
}

/// The implicit Euler momentum balance of a rigid body of `start` state at its trial pose
/// `(position, rotation)` given the reaction on it: its end velocities `G(u)` (m/s, rad/s).
/// `L` is about the trial position (the centre of mass at the step's end).
pub(crate) fn momentum_balance(
    start: &Collider<'_>,
    rotation: [Real; 4],
    reaction: &Reaction,
    (dt, gravity): (Real, Vec3),
) -> (Vec3, Vec3) {
    let mass = start.mass;
    let velocity = start.linear_velocity + gravity * dt + reaction.impulse / mass;
    let momentum = inertia_times(
        start.unit_rotation(),
        start.inertia,
        start.angular_velocity,
    ) + reaction.angular_impulse;
    let angular = inertia_solve(rotation, start.inertia, momentum);
    (velocity, angular)
}

/// The checks of an owner's coupled step (a body's or a world's) before anything moves: no
/// colliders in `scene` (they all go in `colliders`), one reaction per collider, every collider
/// in range, the time step, the coupling settings.
///
/// # Errors
/// [`StepError::SceneColliders`], [`StepError::LengthMismatch`] (buffer
/// [`StepBuffer::Reactions`]), [`StepError::Collider`], [`StepError::TimeStep`],
/// [`StepError::CouplingSettings`], in that order.
pub(crate) fn check_coupled_step(
    scene: &Scene<'_, Vec3>,
    colliders: &[Collider<'_>],
    reactions: &[Reaction],
    settings: &CouplingSettings,
) -> Result<(), StepError> {
    if !scene.colliders.is_empty() {
        return Err(StepError::SceneColliders);
    }
    check_length(StepBuffer::Reactions, colliders.len(), reactions.len())?;
    check_colliders(colliders, true)?;
    check_time_step(scene.dt)?;
    if !settings.valid() {
        return Err(StepError::CouplingSettings);
    }
    Ok(())
}

/// Aitken's factor is kept in `[MIN_RELAXATION, MAX_RELAXATION]`: a factor of the wrong sign or
/// far beyond one comes from a step where contact began or ended, not from a linear response.
const MIN_RELAXATION: Real = 1e-6;
const MAX_RELAXATION: Real = 2.0;

/// Solves one coupled step of `dt` (s) under `gravity` (m/s^2): `soft_step(colliders, reactions,
/// iteration)` runs the soft step with the colliders as they are (the dynamic ones at their
/// trial poses and velocities), writes each collider's reaction and returns its outcome and the
/// force (N) its solve left unbalanced (its final residual; zero for an explicit step;
/// infinite where the soft step did not converge: no floor is granted then), from the
/// soft state at the step's start whatever `iteration` (the caller restores it for every
/// iteration after the first). `vertex_mass` (kg) is the soft body's mean vertex mass, for the first relaxation
/// factor `M / (M + m_touching)` (the soft mass the collider meets resists it at least by its
/// inertia).
///
/// On success each dynamic collider is at the pose of the last soft step, with the velocities of
/// its momentum balance, and `reactions` holds that step's reactions. On failure every
/// collider is as it was and the soft step's error is returned (the caller restores the soft
/// state).
///
/// # Errors
/// [`StepError::TooManyDynamicColliders`] beyond [`MAX_DYNAMIC_COLLIDERS`], before any soft
/// step; otherwise `soft_step`'s.
///
/// The reactions passed in are the predictor: each dynamic collider's first trial velocity is
/// its momentum balance with them (the last step's reactions make a resting body's first trial
/// its answer; zeros, free flight). Non-finite entries count as zero.
pub(crate) fn couple<R>(
    colliders: &mut [Collider<'_>],
    (dt, gravity): (Real, Vec3),
    settings: &CouplingSettings,
    vertex_mass: Real,
    reactions: &mut [Reaction],
    mut soft_step: impl FnMut(&[Collider<'_>], &mut [Reaction], u32) -> Result<(R, Real), StepError>,
) -> Result<(R, CouplingReport), StepError> {
    let mut rigid: heapless::Vec<Rigid, MAX_DYNAMIC_COLLIDERS> = heapless::Vec::new();
    for (index, collider) in colliders.iter().enumerate() {
        if !collider.is_dynamic() {
            continue;
        }
        let moments = collider.inertia;
        let largest = moments.x.max(moments.y).max(moments.z);
        let start = Collider {
            shape: super::collider::Shape::HalfSpace,
            ..*collider
        };
        // The predictor: the momentum balance with the reaction the caller passed in (the
        // last step's, if kept; zero for free flight), at the start's orientation.
        let predictor = reactions
            .get(index)
            .filter(|r| r.impulse.is_finite() && r.angular_impulse.is_finite())
            .copied()
            .unwrap_or(Reaction::ZERO);
        let (velocity, angular) =
            momentum_balance(&start, start.unit_rotation(), &predictor, (dt, gravity));
        let entry = Rigid {
            index,
            start,
            velocity,
            angular,
            base: (velocity, angular),
            best: (velocity, angular),
            residual: [Vec3::ZERO; 2],
            touched: false,
            balance: (velocity, angular),
            trial_residual: [Vec3::ZERO; 2],
            trial_touched: false,
            gyration: math::sqrt(largest / collider.mass),
        };
        if rigid.push(entry).is_err() {
            return Err(StepError::TooManyDynamicColliders {
                limit: MAX_DYNAMIC_COLLIDERS,
            });
        }
    }
    let restore = |colliders: &mut [Collider<'_>], rigid: &[Rigid]| {
        for r in rigid {
            if let Some(c) = colliders.get_mut(r.index) {
                c.position = r.start.position;
                c.rotation = r.start.rotation;
                c.linear_velocity = r.start.linear_velocity;
                c.angular_velocity = r.start.angular_velocity;
            }
        }
    };
    let mut relaxation: Real = 1.0;
    let (mut iteration, mut rejected) = (0, 0);
    let (mut best, mut retried) = (Real::INFINITY, false);
    loop {
        for r in &rigid {
            if let Some(c) = colliders.get_mut(r.index) {
                let (position, q) = trial_pose(&r.start, (r.velocity, r.angular), dt);
                c.position = position;
                c.rotation = glam_quat(q);
                c.linear_velocity = r.velocity;
                c.angular_velocity = r.angular;
            }
        }
        let (outcome, soft_residual) = match soft_step(colliders, reactions, iteration) {
            Ok(outcome) => outcome,
            Err(error) => {
                restore(colliders, &rigid);
                return Err(error);
            }
        };
        iteration += 1;
        // The momentum balance at this trial, its residual and the convergence test.
        let (mut largest, mut converged, mut separated) = (0.0, true, false);
        let (mut dot, mut squared) = (0.0, 0.0);
        let (mut touching, mut mass): (Real, Real) = (0.0, 0.0);
        for r in rigid.iter_mut() {
            let (Some(c), Some(reaction)) = (colliders.get(r.index), reactions.get(r.index)) else {
                continue;
            };
            let (v, w) = momentum_balance(&r.start, c.unit_rotation(), reaction, (dt, gravity));
            let residual = [v - r.velocity, (w - r.angular) * r.gyration];
            let size = math::sqrt(residual[0].dot(residual[0]) + residual[1].dot(residual[1]));
            let speed = |x: Vec3| math::sqrt(x.dot(x));
            let scale = speed(r.start.linear_velocity)
                + speed(v)
                + speed(reaction.impulse) / r.start.mass
                + r.gyration * (speed(r.start.angular_velocity) + speed(w))
                + speed(gravity) * dt;
            // What the soft step's own residual leaves uncertain in the impulse: at each touching
            // vertex, `dt` times the force it did not balance.
            let floor = match soft_residual.is_finite() {
                true => soft_residual * dt * reaction.vertices as Real / r.start.mass,
                false => 0.0,
            };
            converged &= size <= settings.tolerance * scale + floor;
            largest = if size > largest { size } else { largest };
            for (now, before) in residual.iter().zip(&r.residual) {
                let change = *now - *before;
                dot += before.dot(change);
                squared += change.dot(change);
            }
            r.balance = (v, w);
            r.trial_residual = residual;
            separated |= r.touched && reaction.vertices == 0;
            r.trial_touched = reaction.vertices > 0;
            touching += reaction.vertices as Real;
            mass += r.start.mass;
        }
        let report = CouplingReport {
            iterations: iteration,
            converged,
            residual: largest,
        };
        if largest < best {
            best = largest;
            for r in rigid.iter_mut() {
                r.best = (r.velocity, r.angular);
            }
        }
        let out_of_budget = iteration >= settings.max_iterations;
        if out_of_budget && !converged && largest > best && !retried {
            // Unconverged, and an earlier iterate was closer: end there (one more soft step),
            // not wherever the last update went.
            retried = true;
            for r in rigid.iter_mut() {
                (r.velocity, r.angular) = r.best;
            }
            continue;
        }
        if converged || out_of_budget || retried {
            // Keep the poses the soft step saw; the velocities of the momentum balance.
            for r in &rigid {
                if let Some(c) = colliders.get_mut(r.index) {
                    (c.linear_velocity, c.angular_velocity) = r.balance;
                }
            }
            return Ok((outcome, report));
        }
        if iteration > 1 && separated && rejected < MAX_REJECTIONS {
            // A collider that touched the body at the last accepted iterate left it at this
            // trial: the update overshot the contact. Retry a tenth of it.
            rejected += 1;
            relaxation *= 0.1;
        } else {
            rejected = 0;
            relaxation = if iteration == 1 {
                // The soft mass the colliders meet resists them at least by its inertia.
                mass / (mass + touching * vertex_mass)
            } else if squared > 0.0 {
                let aitken = -relaxation * dot / squared;
                aitken
                    .min(MAX_GROWTH * relaxation)
                    .clamp(MIN_RELAXATION, MAX_RELAXATION)
            } else {
                relaxation
            };
            if !relaxation.is_finite() {
                relaxation = MIN_RELAXATION;
            }
            for r in rigid.iter_mut() {
                r.base = (r.velocity, r.angular);
                r.residual = r.trial_residual;
                r.touched = r.trial_touched;
            }
        }
        for r in rigid.iter_mut() {
            let (velocity, angular) = r.base;
            r.velocity = velocity + r.residual[0] * relaxation;
            r.angular = angular + r.residual[1] * (relaxation / r.gyration);
        }
    }
}

/// How much Aitken's factor may grow from one update to the next: where the soft step's
/// tolerance leaves the impulse noisy, two close iterates can suggest a factor far beyond the
/// response's, and the jump it makes lands far from the contact.
const MAX_GROWTH: Real = 4.0;

/// How many times in a row an update that separated a collider from the body is cut to a tenth
/// before it is taken as it is (the step may truly separate them).
const MAX_REJECTIONS: u32 = 3;

/// `[x, y, z, w]` as a quaternion.
fn glam_quat([x, y, z, w]: [Real; 4]) -> super::super::super::types::Quat {
    super::super::super::types::Quat::from_xyzw(x, y, z, w)
}

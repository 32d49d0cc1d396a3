//! What the colliders took from a body over a step: the contact impulse at each vertex and, summed
//! per collider, the impulse and its moment on the collider (`docs/math.md` section 8.14), for a
//! host engine that owns the colliders as rigid bodies and applies the reaction to them
//! (staggered coupling).
//!
//! * The explicit stepper records `m (v_after - v_before)` of every collider projection of every
//!   substep ([`ExplicitScratch::with_impulses`](super::super::ExplicitScratch::with_impulses)).
//! * After an implicit Euler step (Newton's method, the relaxation, Vertex Block Descent) the
//!   contact impulse at a free vertex touching a collider is what its momentum balance leaves
//!   once the elastic, external and gravity forces at the result are taken out,
//!   `J_i = m_i (v_i - v0_i) - h (f_i(x) + f_ext,i + m_i g)` ([`implicit_impulses`]): the
//!   projection's reaction, the velocity's approach removed and the friction, whichever way
//!   the solver applied them.
//! * [`add_collider_reactions`] gives each free vertex's impulse to the collider closest to it
//!   and sums, per collider, the opposite impulse and its moment about the collider's position.
//! * At pinned and kinematic vertices both give the pin's impulse, what held or moved the
//!   vertex; [`attachment_reaction`] sums it over the vertices attached to a rigid part.

use super::super::super::types::{Real, Vec3};
use super::super::model::ElasticModel;
use super::super::scene::Scene;
use super::super::state::check_length;
use super::collider::{Collider, Colliders};
use crate::error::{StepBuffer, StepError};

/// What one collider received from the bodies it touched over one step.
///
/// The impulse is the one *on the collider*: minus the sum of the contact impulses it applied to
/// the vertices. A host engine that owns the collider as a rigid body applies `impulse` at the
/// collider's position and `angular_impulse` as an angular impulse (or `impulse / dt` and
/// `angular_impulse / dt` as a force and a torque over the step).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reaction {
    /// The impulse on the collider (N s).
    pub impulse: Vec3,
    /// Its moment about the collider's [`position`](Collider::position) (N m s): the sum of
    /// `(x_i - position) x impulse_i` over the vertices, each at its position after the step.
    pub angular_impulse: Vec3,
    /// The vertices whose impulse went to this collider.
    pub vertices: u32,
}

impl Reaction {
    /// No impulse, no vertex.
    pub const ZERO: Reaction = Reaction {
        impulse: Vec3::ZERO,
        angular_impulse: Vec3::ZERO,
        vertices: 0,
    };

    /// The mean force (N) on the collider over a step of `dt` (s): `impulse / dt`.
    #[inline]
    #[must_use]
    pub fn force(&self, dt: Real) -> Vec3 {
        self.impulse / dt
    }

    /// The mean torque (N m) about the collider's position over a step of `dt` (s).
    #[inline]
    #[must_use]
    pub fn torque(&self, dt: Real) -> Vec3 {
        self.angular_impulse / dt
    }
}

/// The impulse (N s) the colliders and pins applied to each vertex over an implicit Euler step
/// of `scene.dt` from velocities `before` to `after`, the body at `positions` after it with
/// elastic forces `elastic_forces` there (N; e.g. [`ElasticModel::add_forces`](
/// crate::step::ElasticModel::add_forces) into zeros):
/// `m (after - before) - dt (elastic_force + external_force + m gravity)` at every pinned vertex
/// (what held it, or moved it where it is kinematic: pass the velocities before its move as
/// `before`) and at every free vertex that touches a collider (within the contact tolerance);
/// zero at every other vertex.
///
/// Exact for a step that solved its objective exactly; the solver's tolerance bounds the
/// error (the residual at a vertex is a force, times `dt`). A vertex touching the ground and a
/// collider, or another body in a world, gives the collider all of its balance.
///
/// # Errors
/// [`StepError::LengthMismatch`] unless `masses`, `positions`, `elastic_forces`, `before`,
/// `after` and `impulses` have one entry per vertex (`masses.len()`) and `pinned` is empty or
/// as long; the scene's external forces must be empty or as long.
pub fn implicit_impulses(
    scene: &Scene<'_, Vec3>,
    (masses, pinned): (&[Real], &[bool]),
    (positions, elastic_forces): (&[Vec3], &[Vec3]),
    (before, after): (&[Vec3], &[Vec3]),
    impulses: &mut [Vec3],
) -> Result<(), StepError> {
    let n = masses.len();
    check_length(StepBuffer::Positions, n, positions.len())?;
    check_length(StepBuffer::Scratch, n, elastic_forces.len())?;
    check_length(StepBuffer::Velocities, n, before.len())?;
    check_length(StepBuffer::Velocities, n, after.len())?;
    check_length(StepBuffer::Impulses, n, impulses.len())?;
    if !pinned.is_empty() {
        check_length(StepBuffer::Pinned, n, pinned.len())?;
    }
    let external = scene.external_forces;
    if !external.is_empty() {
        check_length(StepBuffer::ExternalForces, n, external.len())?;
    }
    let colliders = Colliders::new(scene.colliders);
    let dt = scene.dt;
    for (i, impulse) in impulses.iter_mut().enumerate() {
        *impulse = Vec3::ZERO;
        let (Some(&m), Some(&x), Some(&f), Some(&v0), Some(&v)) = (
            masses.get(i),
            positions.get(i),
            elastic_forces.get(i),
            before.get(i),
            after.get(i),
        ) else {
            continue;
        };
        let held = pinned.get(i).copied().unwrap_or(false);
        if !held && colliders.touching_index(x).is_none() {
            continue;
        }
        let load = f + external.get(i).copied().unwrap_or(Vec3::ZERO) + scene.gravity * m;
        *impulse = (v - v0) * m - load * dt;
    }
    Ok(())
}

/// What a rigid part received from the vertices attached to it over a step: minus the sum of
/// their impulses (N s, as [`implicit_impulses`] or the explicit stepper's record give them at
/// pinned and kinematic vertices) and its moment about `origin` (the part's centre of mass or
/// frame origin, m), each vertex at its position after the step; `vertices` the attached
/// vertices' count. For a host engine that moves attached vertices with its rigid body (as
/// kinematic targets) and applies the reaction back to it.
///
/// # Errors
/// [`StepError::LengthMismatch`] unless `impulses` has one entry per position;
/// [`StepError::AttachedVertex`] for the first entry of `vertices` at or beyond their count.
pub fn attachment_reaction(
    vertices: &[u32],
    positions: &[Vec3],
    impulses: &[Vec3],
    origin: Vec3,
) -> Result<Reaction, StepError> {
    check_length(StepBuffer::Impulses, positions.len(), impulses.len())?;
    let mut reaction = Reaction::ZERO;
    for (entry, &vertex) in vertices.iter().enumerate() {
        let index = usize::try_from(vertex).unwrap_or(usize::MAX);
        let (Some(&x), Some(&impulse)) = (positions.get(index), impulses.get(index)) else {
            return Err(StepError::AttachedVertex { entry, vertex });
        };
        reaction.impulse -= impulse;
        reaction.angular_impulse -= (x - origin).cross(impulse);
        reaction.vertices = reaction.vertices.saturating_add(1);
    }
    Ok(reaction)
}

/// Adds each vertex's contact impulse (`impulses`, N s, one per vertex, the body at `positions`)
/// to the collider whose signed distance at the vertex is the smallest (the one it touches;
/// the first of equals), as `reactions[k]` for `colliders[k]`: the impulse on the collider is
/// minus the vertex's, its moment is about the collider's position. Vertices with a zero
/// impulse and pinned vertices (whose impulse is their pin's, `pinned` empty for none) are
/// skipped. Adds, so the bodies of a world can go one after the other into the same
/// reactions; start from [`Reaction::ZERO`].
///
/// # Errors
/// [`StepError::LengthMismatch`] unless `impulses` has one entry per position, `pinned` is
/// empty or as long, and `reactions` has one per collider.
pub fn add_collider_reactions(
    colliders: &[Collider<'_>],
    (positions, pinned): (&[Vec3], &[bool]),
    impulses: &[Vec3],
    reactions: &mut [Reaction],
) -> Result<(), StepError> {
    check_length(StepBuffer::Impulses, positions.len(), impulses.len())?;
    if !pinned.is_empty() {
        check_length(StepBuffer::Pinned, positions.len(), pinned.len())?;
    }
    check_length(StepBuffer::Reactions, colliders.len(), reactions.len())?;
    for (i, (&x, &impulse)) in positions.iter().zip(impulses).enumerate() {
        if impulse == Vec3::ZERO || pinned.get(i).copied().unwrap_or(false) {
            continue;
        }
        let Some(k) = nearest_collider(colliders, x) else {
            continue;
        };
        let (Some(reaction), Some(collider)) = (reactions.get_mut(k), colliders.get(k)) else {
            continue;
        };
        reaction.impulse -= impulse;
        reaction.angular_impulse -= (x - collider.position).cross(impulse);
        reaction.vertices = reaction.vertices.saturating_add(1);
    }
    Ok(())
}

/// The collider a vertex at `x` (m) gives its contact impulse to: the one of the smallest signed
/// distance (the first of equals); `None` without colliders.
pub(crate) fn nearest_collider(colliders: &[Collider<'_>], x: Vec3) -> Option<usize> {
    let mut nearest: Option<(usize, Real)> = None;
    for (k, collider) in colliders.iter().enumerate() {
        let distance = collider.distance(x);
        if nearest.is_none_or(|(_, best)| distance < best) {
            nearest = Some((k, distance));
        }
    }
    nearest.map(|(k, _)| k)
}

/// An owner's vector scratch (a body's or a world's: `k` vectors per vertex for its solver, then
/// two) as a step recorded for reactions uses it: the first `n` vectors (the elastic forces
/// after an implicit step, free once it is done), then after the solver's `k` the contact
/// impulses and the velocities at the step's start. Empty slices where the scratch is shorter,
/// which the owners' sizing rules out.
pub(crate) fn recording_slots(
    vectors: &mut [Vec3],
    n: usize,
    k: usize,
) -> (&mut [Vec3], &mut [Vec3], &mut [Vec3]) {
    let (solver, recorded) = vectors
        .split_at_mut_checked(n.saturating_mul(k))
        .unwrap_or_default();
    let forces = solver.get_mut(..n).unwrap_or(&mut []);
    let (impulses, rest) = recorded.split_at_mut_checked(n).unwrap_or_default();
    let start_velocities = rest.get_mut(..n).unwrap_or(&mut []);
    (forces, impulses, start_velocities)
}

/// After a step recorded for reactions (by a body or a world): each vertex's impulse, then each
/// collider's reaction into `reactions`. After the explicit stepper (`explicit`) `impulses`
/// holds its record, to which the pinned vertices' velocity change at the step's start (the
/// kinematic move, zero for a plain pin) is added; after an implicit step they come from the
/// momentum balance ([`implicit_impulses`]) with `model`'s forces at `positions`, written into
/// `forces`. `start_velocities` are those before the step (and before any kinematic move).
///
/// # Errors
/// The model's force error (not expected: the step evaluated it there), and those of
/// [`implicit_impulses`] and [`add_collider_reactions`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn recorded_reactions<F: ElasticModel<Vector = Vec3>>(
    model: &F,
    scene: &Scene<'_, Vec3>,
    (masses, pinned): (&[Real], &[bool]),
    (positions, velocities): (&[Vec3], &[Vec3]),
    (forces, impulses, start_velocities): (&mut [Vec3], &mut [Vec3], &[Vec3]),
    explicit: bool,
    reactions: &mut [Reaction],
) -> Result<(), StepError> {
    if explicit {
        // The kinematic vertices' move at the step's start (the stepper saw them pinned).
        let rows = impulses.iter_mut().zip(velocities);
        let rows = rows.zip(start_velocities.iter().zip(masses).zip(pinned));
        for ((impulse, &v), ((&v0, &m), &pinned)) in rows {
            if pinned {
                *impulse += (v - v0) * m;
            }
        }
    } else {
        forces.fill(Vec3::ZERO);
        model.add_forces(positions, forces)?;
        let state = (positions, &*forces);
        let balance = (start_velocities, velocities);
        implicit_impulses(scene, (masses, pinned), state, balance, impulses)?;
    }
    reactions.fill(Reaction::ZERO);
    add_collider_reactions(scene.colliders, (positions, pinned), impulses, reactions)
}

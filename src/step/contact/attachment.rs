//! Body vertices held at points of a collider's frame, hard (moving with it exactly) or soft (a
//! spring and a damper to it), for the coupled step
//! ([`Body::step_with_rigid_bodies_and_attachments`](crate::body::Body::step_with_rigid_bodies_and_attachments)):
//! a hard-attached vertex is a kinematic vertex of the body whose target is its point on the
//! collider at the step's end, and what held it there (its pin's impulse, `step/contact/reaction.rs`)
//! goes into the collider's [`Reaction`]; a soft-attached vertex is pulled towards that point by a
//! spring and a damper, terms of the step's objective ([`SoftPull`]), whose impulse goes into the
//! collider's reaction the same way. A dynamic collider's momentum balance so carries the body
//! hanging from it (`docs/math.md` section 8.15).

use super::super::super::types::{Real, Vec3};
use super::collider::{Collider, rotate, rotate_back};
use super::reaction::{Reaction, nearest_collider};
use crate::error::StepError;

/// How many attachments one coupled step takes: the attached vertices' pins and targets before
/// the step sit on the stack, to be put back if it fails (16 bytes each in f32): 256 on a host,
/// 16 on bare metal (`target_os = "none"`).
pub const MAX_ATTACHMENTS: usize = if cfg!(target_os = "none") { 16 } else { 256 };

/// A body vertex held at a point of a collider's frame: hard (it moves with the collider
/// exactly; the default) or soft ([`with_spring`](Self::with_spring): a spring of `stiffness`
/// N/m and a damper of `damping` N s/m between the vertex and the point).
///
/// ```
/// use softfem::glam::{Quat, Vec3};
/// use softfem::step::{Attachment, Collider};
///
/// let lamp = Collider::sphere(Vec3::new(0.0, 2.0, 0.0), 0.1);
/// // Vertex 7, now at (0, 1.9, 0), hangs from the lamp's lowest point.
/// let hook = Attachment::at(7, 0, &lamp, Vec3::new(0.0, 1.9, 0.0));
/// assert!((hook.local - Vec3::new(0.0, -0.1, 0.0)).length() < 1e-6);
/// let moved = lamp.with_velocity(Vec3::X, Vec3::ZERO).advanced(0.5);
/// assert!((hook.anchor(&moved) - Vec3::new(0.5, 1.9, 0.0)).length() < 1e-6);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attachment {
    /// The body's vertex.
    pub vertex: u32,
    /// The collider it hangs from: its index in the step's collider slice.
    pub collider: u32,
    /// The point (m) in the collider's frame that holds the vertex.
    pub local: Vec3,
    /// The spring's stiffness (N/m, finite `>= 0`); with `damping`, both zero (the default)
    /// for a hard attachment.
    pub stiffness: Real,
    /// The damper's coefficient (N s/m, finite `>= 0`), on the vertex's velocity relative to
    /// the point's.
    pub damping: Real,
}

impl Attachment {
    /// `vertex` held at the point `local` (m) of the frame of collider number `collider`.
    #[inline]
    #[must_use]
    pub const fn new(vertex: u32, collider: u32, local: Vec3) -> Self {
        Attachment {
            vertex,
            collider,
            local,
            stiffness: 0.0,
            damping: 0.0,
        }
    }

    /// This attachment made soft: a spring of `stiffness` (N/m) and a damper of `damping`
    /// (N s/m) between the vertex and its point, instead of holding the vertex there.
    #[inline]
    #[must_use]
    pub const fn with_spring(self, stiffness: Real, damping: Real) -> Self {
        Attachment {
            stiffness,
            damping,
            ..self
        }
    }

    /// Whether the attachment is soft (a positive stiffness or damping).
    #[inline]
    #[must_use]
    pub fn is_soft(&self) -> bool {
        self.stiffness > 0.0 || self.damping > 0.0
    }

    /// `vertex`, now at the world point `x` (m), held where it is on `collider` (number
    /// `index` of the step's slice) in its current pose.
    #[must_use]
    pub fn at(vertex: u32, index: u32, collider: &Collider<'_>, x: Vec3) -> Self {
        let local = rotate_back(collider.unit_rotation(), x - collider.position);
        Attachment::new(vertex, index, local)
    }

    /// The world point (m) that holds the vertex when the collider is in the pose `collider`.
    #[inline]
    #[must_use]
    pub fn anchor(&self, collider: &Collider<'_>) -> Vec3 {
        collider.position + rotate(collider.unit_rotation(), self.local)
    }
}

/// Checks the attachments against a body of `vertices` vertices and a step of `colliders`
/// colliders.
///
/// # Errors
/// [`StepError::TooManyAttachments`] beyond [`MAX_ATTACHMENTS`];
/// [`StepError::AttachedVertex`] or [`StepError::AttachedCollider`] for the first entry out
/// of range, with a non-finite point, or with a stiffness or damping not finite and `>= 0`.
pub(crate) fn check_attachments(
    attachments: &[Attachment],
    vertices: usize,
    colliders: usize,
) -> Result<(), StepError> {
    if attachments.len() > MAX_ATTACHMENTS {
        return Err(StepError::TooManyAttachments {
            limit: MAX_ATTACHMENTS,
        });
    }
    for (entry, a) in attachments.iter().enumerate() {
        if a.vertex as usize >= vertices {
            let vertex = a.vertex;
            return Err(StepError::AttachedVertex { entry, vertex });
        }
        let spring = |c: Real| c >= 0.0 && c.is_finite();
        let valid = a.local.is_finite() && spring(a.stiffness) && spring(a.damping);
        if a.collider as usize >= colliders || !valid {
            let collider = a.collider;
            return Err(StepError::AttachedCollider { entry, collider });
        }
    }
    Ok(())
}

/// The anchor of `attachment` at the step's end: on a dynamic collider, which a coupled step
/// hands the soft step in its trial end pose, where it is; on any other, where its velocities
/// take it over `dt` (s).
pub(crate) fn end_anchor(attachment: &Attachment, collider: &Collider<'_>, dt: Real) -> Vec3 {
    match collider.is_dynamic() {
        true => attachment.anchor(collider),
        false => attachment.anchor(&collider.advanced(dt)),
    }
}

/// The surface velocity (m/s) of `collider` at the step's end at `anchor` (m, the
/// attachment's [`end_anchor`]): on a dynamic collider its trial velocities, on any other its
/// own.
fn anchor_velocity(anchor: Vec3, collider: &Collider<'_>, dt: Real) -> Vec3 {
    let centre = match collider.is_dynamic() {
        true => collider.position,
        false => collider.position + collider.linear_velocity * dt,
    };
    collider.linear_velocity + collider.angular_velocity.cross(anchor - centre)
}

/// A soft attachment's terms in the implicit Euler objective of the step of `h` (s): the spring
/// `k/2 |x - a|^2` to the anchor `a` at the step's end and the damper's dissipation
/// `c/(2h) |x - x_n - h v_a|^2` (`v_a` the anchor's velocity), together
/// `k'/2 |x - b|^2 + const` with `k' = k + c/h` and `b = (k a + (c/h)(x_n + h v_a)) / k'`.
/// Added to the vertex's inertia `m/(2h^2) |x - y|^2 - m g.(x - x_n)`, they are that term for
/// the mass `m' = m + h^2 k'` and the target `y' = (m y + h^2 k' b) / m' - h^2 (m' - m) g / m'`,
/// which is how the body hands them to every implicit solver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SoftPull {
    /// The anchor `a` at the step's end (m), where the pull acts on the collider.
    pub anchor: Vec3,
    /// `k'` (N/m).
    pub stiffness: Real,
    /// `b` (m).
    pub centre: Vec3,
}

impl SoftPull {
    /// The pull of `attachment` on its vertex starting at `start` (m), the collider in the
    /// pose and velocities the step sees, over `h` (s).
    pub fn new(attachment: &Attachment, collider: &Collider<'_>, start: Vec3, h: Real) -> Self {
        let anchor = end_anchor(attachment, collider, h);
        let (k, c) = (attachment.stiffness, attachment.damping / h);
        let stiffness = k + c;
        let moving = start + anchor_velocity(anchor, collider, h) * h;
        SoftPull {
            anchor,
            stiffness,
            centre: (anchor * k + moving * c) / stiffness,
        }
    }

    /// The mass (kg) and start velocity (m/s) that put these terms into the objective of a
    /// vertex of mass `m`, start `x_n` and velocity `v_n` under `gravity` (see the type).
    pub fn inertia(&self, (m, x_n, v_n): (Real, Vec3, Vec3), (h, gravity): (Real, Vec3)) -> (Real, Vec3) {
        let added = h * h * self.stiffness;
        let mass = m + added;
        let target = ((x_n + v_n * h) * m + self.centre * added) / mass - gravity * (h * h * added / mass);
        (mass, (target - x_n) / h)
    }

    /// The impulse (N s) the pull gave the vertex at `x` (m) over the step: `-h k' (x - b)`.
    pub fn impulse(&self, x: Vec3, h: Real) -> Vec3 {
        (x - self.centre) * (-h * self.stiffness)
    }
}

/// Adds to each collider's reaction what its attached vertices took from it over the step of
/// `h` (s), the body at `positions` (m) and `velocities` (m/s) after it and at `starts` before
/// it: at a hard attachment minus the vertex's pin impulse `impulses[vertex]` (N s), at a soft
/// one minus its pull's impulse ([`SoftPull::impulse`]; none at a pinned vertex, which the pull
/// does not move), with the moment about the collider's position of the impulse at the vertex
/// (hard) or at the anchor (soft). Entries out of range are skipped (checked before the step).
///
/// A soft-attached vertex that touched a collider had its contact impulse recorded with the
/// step's mass `m'` (see [`SoftPull`]): the velocity change the solver's contact applied after
/// the solve, `v - (x - x_n)/h`, weighed `m' - m = h^2 k'` too much. That share is taken back
/// from `impulses[vertex]` and from the reaction of the collider it went to.
pub(crate) fn add_attachment_reactions(
    attachments: &[Attachment],
    colliders: &[Collider<'_>],
    (positions, velocities, starts, pinned): (&[Vec3], &[Vec3], &[Vec3], &[bool]),
    (impulses, h): (&mut [Vec3], Real),
    reactions: &mut [Reaction],
) {
    for a in attachments {
        let (v, c) = (a.vertex as usize, a.collider as usize);
        let rows = (positions.get(v), velocities.get(v), starts.get(v));
        let ((Some(&x), Some(&velocity), Some(&x_n)), Some(held)) = (rows, impulses.get_mut(v))
        else {
            continue;
        };
        let Some(collider) = colliders.get(c) else {
            continue;
        };
        let (impulse, at) = match a.is_soft() {
            true if pinned.get(v).copied().unwrap_or(false) => continue,
            true => {
                let pull = SoftPull::new(a, collider, x_n, h);
                if *held != Vec3::ZERO {
                    let excess = (velocity - (x - x_n) / h) * (h * h * pull.stiffness);
                    *held -= excess;
                    if let Some(k) = nearest_collider(colliders, x)
                        && let (Some(r), Some(touched)) = (reactions.get_mut(k), colliders.get(k))
                    {
                        r.impulse += excess;
                        r.angular_impulse += (x - touched.position).cross(excess);
                    }
                }
                (pull.impulse(x, h), pull.anchor)
            }
            false => (*held, x),
        };
        let Some(reaction) = reactions.get_mut(c) else {
            continue;
        };
        reaction.impulse -= impulse;
        reaction.angular_impulse -= (at - collider.position).cross(impulse);
        reaction.vertices = reaction.vertices.saturating_add(1);
    }
}

//! Body vertices held at points of a collider's frame (hard attachments), for the coupled step
//! ([`Body::step_with_rigid_bodies_and_attachments`](crate::body::Body::step_with_rigid_bodies_and_attachments)):
//! each attached vertex is a kinematic vertex of the body whose target is its point on the
//! collider at the step's end, and what held it there (its pin's impulse, `step/contact/reaction.rs`)
//! goes into the collider's [`Reaction`], so that a dynamic collider's momentum balance carries
//! the body hanging from it (`docs/math.md` section 8.15).

use super::super::super::types::{Real, Vec3};
use super::collider::{Collider, rotate, rotate_back};
use super::reaction::Reaction;
use crate::error::StepError;

/// How many attachments one coupled step takes: the attached vertices' pins and targets before
/// the step sit on the stack, to be put back if it fails (16 bytes each in f32): 256 on a host,
/// 16 on bare metal (`target_os = "none"`).
pub const MAX_ATTACHMENTS: usize = if cfg!(target_os = "none") { 16 } else { 256 };

/// A body vertex held at a point of a collider's frame: it moves with the collider exactly.
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
        }
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
/// of range or with a non-finite point.
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
        if a.collider as usize >= colliders || !a.local.is_finite() {
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

/// Adds to each collider's reaction what its attached vertices took from it over the step:
/// minus each vertex's pin impulse `impulses[vertex]` (N s) and its moment about the collider's
/// position, the vertex at `positions[vertex]` (m). Entries out of range are skipped (checked
/// before the step).
pub(crate) fn add_attachment_reactions(
    attachments: &[Attachment],
    colliders: &[Collider<'_>],
    (positions, impulses): (&[Vec3], &[Vec3]),
    reactions: &mut [Reaction],
) {
    for a in attachments {
        let (v, c) = (a.vertex as usize, a.collider as usize);
        let (Some(&x), Some(&impulse)) = (positions.get(v), impulses.get(v)) else {
            continue;
        };
        let (Some(collider), Some(reaction)) = (colliders.get(c), reactions.get_mut(c)) else {
            continue;
        };
        reaction.impulse -= impulse;
        reaction.angular_impulse -= (x - collider.position).cross(impulse);
        reaction.vertices = reaction.vertices.saturating_add(1);
    }
}

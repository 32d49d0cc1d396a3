//! What a body touches and how contact acts on it: the [`HalfSpace`] half-space
//! (`step/contact/half_space.rs`), rigid [`Collider`]s (`step/contact/collider.rs`), the projection of
//! vertices and directions onto the admissible set that every stepper shares (`floor.rs`), Coulomb
//! friction inside the implicit objective (`step/contact/friction.rs`), the one record of a
//! contact at a vertex that they exchange ([`Contact`]), and what the colliders took from a body
//! over a step ([`reaction`]: contact impulses per vertex, reactions per collider), and the
//! colliders with a mass whose motion a step solves with the soft body's (`rigid.rs`).
//!
//! Body–body and self contact (Incremental Potential Contact, Li et al. 2020):
//! * [`boundary`]: a contact surface's primitives (vertices, edges, triangles) from its
//!   boundary triangles.
//! * [`broad_phase`]: the (vertex, triangle) and (edge, edge) pairs close enough to matter, at
//!   one configuration or over a motion, from a spatial hash in caller buffers.
//! * [`distance`]: point–triangle and edge–edge squared distances with exact gradients and
//!   Hessians, their closest-feature kinds, and the edge–edge mollifier (`contact/distance/`).
//! * [`barrier`]: the log barrier on squared distances and its derivatives (`barrier.rs`).
//! * [`ccd`]: continuous collision detection (additive CCD, Li et al. 2021): how far along a
//!   step a pair, or every candidate pair, can move without intersecting (`contact/ccd/`).
//! * [`potential`]: the contact energy over the candidate pairs, its gradient and projected
//!   Hessian, per pair and per vertex, and matrix-free Hessian products (`contact/potential/`).
//! * [`model`]: [`ContactModel`], an elastic model with that potential in its energy and
//!   continuous collision detection in its admissible steps, which the implicit solvers take
//!   as any model (`model.rs`).

pub(crate) mod attachment;
pub mod barrier;
pub mod boundary;
pub mod broad_phase;
pub mod ccd;
pub(crate) mod collider;
pub mod distance;
pub(crate) mod floor;
pub(crate) mod friction;
pub(crate) mod half_space;
pub mod model;
pub mod potential;
pub mod reaction;
pub(crate) mod rigid;
pub(crate) mod vertex;

use super::super::types::Real;

pub use attachment::{Attachment, MAX_ATTACHMENTS};
pub use collider::{Collider, Shape, SignedDistance};
pub use friction::SUGGESTED_STICKING_SPEED;
pub use half_space::HalfSpace;
pub use model::{ContactBuffers, ContactModel};
pub use reaction::{Reaction, add_collider_reactions, attachment_reaction, implicit_impulses};
pub use rigid::{CouplingReport, CouplingSettings, MAX_DYNAMIC_COLLIDERS};

/// What friction needs of one contact at a vertex.
#[derive(Clone, Copy, Debug)]
pub struct Contact<V> {
    /// The outward unit normal.
    pub normal: V,
    /// The surface's velocity at the vertex (m/s).
    pub surface_velocity: V,
    /// The Coulomb coefficient.
    pub friction: Real,
    /// `eps_v` (m/s).
    pub sticking_speed: Real,
}

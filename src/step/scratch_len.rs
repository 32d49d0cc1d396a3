//! How long each stepper's caller-owned scratch buffers must be, in one place: one function per
//! buffer, named after its solver (`scratch_len::relax(n)`, `scratch_len::newton(n, e)`, ...).
//! The solvers check every length before they touch anything and refuse a wrong one with
//! [`StepError::LengthMismatch`](crate::StepError::LengthMismatch) naming the buffer.
//!
//! Every length saturates at `usize::MAX` for counts whose product does not fit: no buffer can
//! have that length, so the solver's check then refuses any buffer given.
//!
//! ```
//! use softfem::glam::Vec3;
//! use softfem::step::{RelaxScratch, scratch_len};
//!
//! let vertex_count = 8;
//! let mut vectors = vec![Vec3::ZERO; scratch_len::relax(vertex_count)];
//! let mut scalars = vec![0.0; vertex_count];
//! let scratch = RelaxScratch::new(&mut vectors, &mut scalars);
//! assert_eq!(scratch_len::relax(vertex_count), 40);
//! assert_eq!(scratch_len::relax(usize::MAX), usize::MAX);
//! # let _ = scratch;
//! ```

use super::super::mesh::{adjacency_incident_len, adjacency_offsets_len};
use super::descent::vbd::layout;

/// The scratch buffer of [`explicit_step`](super::explicit_step) for `vertex_count` vertices:
/// `4 * vertex_count` vectors (the forces of this substep and of the one before, for the
/// blow-up detector, and a backup of the positions and velocities).
#[inline]
#[must_use]
pub const fn explicit(vertex_count: usize) -> usize {
    vertex_count.saturating_mul(4)
}

/// The scratch buffer of [`explicit_step`](super::explicit_step) for `vertex_count` vertices of
/// a model that [limits the motion](super::ElasticModel::limits_motion) (contact between
/// surfaces): `5 * vertex_count` vectors, [`explicit`]'s and each substep's start positions.
#[inline]
#[must_use]
pub const fn explicit_contact(vertex_count: usize) -> usize {
    vertex_count.saturating_mul(5)
}

/// The vector scratch of [`estimate_max_frequency`](super::explicit::estimate_max_frequency):
/// `2 * vertex_count` vectors (the iterate and its product).
#[inline]
#[must_use]
pub const fn frequency(vertex_count: usize) -> usize {
    vertex_count.saturating_mul(2)
}

/// The vector buffer of [`RelaxScratch`](super::RelaxScratch) (the relaxation and plain
/// gradient descent) for `vertex_count` vertices: `5 * vertex_count` vectors (the start
/// positions, two gradients, a second point buffer that trades places with `positions` as
/// iterate and trial point, and the direction). Its scalar buffer has `vertex_count` entries.
#[inline]
#[must_use]
pub const fn relax(vertex_count: usize) -> usize {
    vertex_count.saturating_mul(5)
}

/// The buffer lengths of [`NewtonScratch`](super::NewtonScratch) ([`newton`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NewtonScratchLen {
    /// Vectors: `9 * vertex_count` (start positions, two gradients, a trial point, the
    /// direction and the four vectors of conjugate gradients).
    pub vectors: usize,
    /// 3x3 blocks: `vertex_count` (the inverted preconditioner blocks).
    pub blocks: usize,
    /// [`TetHessian`](crate::element::TetHessian)s: `element_count` (180 bytes each in f32, 360
    /// in f64).
    pub hessians: usize,
}

/// The buffer lengths of [`NewtonScratch`](super::NewtonScratch) for [`newton_step`] and
/// [`newton_quasi_static`] on a body of `vertex_count` vertices and `element_count` elements.
///
/// [`newton_step`]: super::newton_step
/// [`newton_quasi_static`]: super::newton_quasi_static
#[inline]
#[must_use]
pub const fn newton(vertex_count: usize, element_count: usize) -> NewtonScratchLen {
    NewtonScratchLen {
        vectors: vertex_count.saturating_mul(9),
        blocks: vertex_count,
        hessians: element_count,
    }
}

/// The vector buffer of [`VbdScratch`](super::VbdScratch) for `vertex_count` vertices:
/// `5 * vertex_count` vectors (the descent loop's start positions, gradient, trial gradient,
/// trial point and direction).
#[inline]
#[must_use]
pub const fn vbd(vertex_count: usize) -> usize {
    vertex_count.saturating_mul(5)
}

/// The index buffer of [`VbdScratch`](super::VbdScratch) for `vertex_count` vertices and
/// `element_count` tetrahedra: `3 * vertex_count + 1 + 4 * element_count` indices (the vertex
/// adjacency of [`build_vertex_adjacency`](crate::mesh::build_vertex_adjacency), the colours
/// and the vertex order).
#[inline]
#[must_use]
pub const fn vbd_indices(vertex_count: usize, element_count: usize) -> usize {
    adjacency_offsets_len(vertex_count)
        .saturating_add(adjacency_incident_len(element_count))
        .saturating_add(vertex_count.saturating_mul(2))
}

/// The value buffer of VBD's packed sweep layout (see
/// [`VbdScratch::with_layout`](super::VbdScratch::with_layout)) for a mesh of `element_count`
/// tetrahedra: 13 values (`Dm^-1`, the rest volume and the corner's shape gradient) per element
/// visit and lane, for about one and a half times the `4 * element_count` visits of a sweep plus
/// a margin (78 values, 312 bytes, per tetrahedron in f32 beyond the margin, 624 in f64). A mesh
/// whose vertex valences are so uneven that its layout needs more is swept without it.
#[inline]
#[must_use]
pub const fn vbd_layout(element_count: usize) -> usize {
    layout::values_len(element_count)
}

/// The index buffer of VBD's packed sweep layout (see
/// [`VbdScratch::with_layout`](super::VbdScratch::with_layout)) for `vertex_count` vertices and
/// `element_count` tetrahedra: the blocks' first rows (`vertex_count + 1`) and the four corner
/// indices of every visit of [`vbd_layout`]'s room (24 indices, 96 bytes, per tetrahedron).
#[inline]
#[must_use]
pub const fn vbd_layout_corners(vertex_count: usize, element_count: usize) -> usize {
    layout::corners_len(vertex_count, element_count)
}

/// The edge buffer of [`boundary_edges`](super::contact::boundary::boundary_edges) for
/// `triangle_count` triangles: `3 * triangle_count` edges, every triangle's three before the
/// duplicates are removed (a closed surface keeps half of them).
#[inline]
#[must_use]
pub const fn boundary_edges(triangle_count: usize) -> usize {
    triangle_count.saturating_mul(3)
}

/// The vertex buffer of [`boundary_vertices`](super::contact::boundary::boundary_vertices) for
/// `triangle_count` triangles: `3 * triangle_count` indices, every corner before the duplicates
/// are removed.
#[inline]
#[must_use]
pub const fn boundary_vertices(triangle_count: usize) -> usize {
    triangle_count.saturating_mul(3)
}

/// The buffer lengths of [`BroadPhaseScratch`](super::contact::broad_phase::BroadPhaseScratch)
/// ([`broad_phase`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BroadPhaseScratchLen {
    /// Hash-table slots: `2 * primitives + 1` (a table of twice as many cells as primitives,
    /// and the end of the last cell). Any length of at least 2 works; fewer slots put more
    /// cells into one slot, which costs time, never correctness.
    pub slots: usize,
    /// Cell entries: `8 * primitives`, the most a grid whose cells are twice the largest
    /// primitive box needs (two cells per axis); the broad phase coarsens its grid until the
    /// entries fit. This is the least it accepts.
    pub entries: usize,
}

/// The buffer lengths of [`BroadPhaseScratch`](super::contact::broad_phase::BroadPhaseScratch)
/// for a surface of `vertex_count` vertices, `edge_count` edges and `triangle_count` triangles
/// (the lists' lengths, not the positions').
#[inline]
#[must_use]
pub const fn broad_phase(
    vertex_count: usize,
    edge_count: usize,
    triangle_count: usize,
) -> BroadPhaseScratchLen {
    let primitives = vertex_count
        .saturating_add(edge_count)
        .saturating_add(triangle_count);
    BroadPhaseScratchLen {
        slots: primitives.saturating_mul(2).saturating_add(1),
        entries: primitives.saturating_mul(8),
    }
}

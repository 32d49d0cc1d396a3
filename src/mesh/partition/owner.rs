//! The owner-computes form of the direct force pass: each vertex piece evaluates every element
//! incident to its vertices and adds, corner by corner, the forces at its own vertices straight
//! into its slice of the output, as the sequential scatter does. No element buffer and no
//! gather: an element whose corners lie in several vertex pieces (a *cut* element) is evaluated
//! by each of them, and since an element's forces do not depend on who evaluates them, every
//! vertex receives the sequential scatter's very additions, in the sequential order.
//!
//! Owner pieces evaluate the elements in the sequential kernel's groups of [`LANES`] (aligned
//! to multiples of [`LANES`] in element index) and the elements after the last whole group one
//! at a time, as it does; a group is skipped when none of its elements touches the piece.
//!
//! The work of an owner piece is the groups between the first and the last element incident to
//! its vertices: for meshes numbered with locality (the generators' boxes, any mesh reordered
//! along a space-filling curve or by layers) about its share of the mesh plus the cut layers,
//! which are evaluated twice. The fewer the vertex pieces, the fewer the cut elements: one piece
//! per thread for a uniform mesh. With one piece nothing is cut and the pass is the sequential
//! kernel with a range test per corner.

use core::ops::Range;

use super::super::super::lanes::LANES;
use super::super::super::material::Material;
use super::super::super::math::BATCH_FORCES;
use super::super::super::types::Vec3;
#[cfg(doc)]
use super::super::TetMesh;
use super::super::grouped::{GroupGradients, TetGroup, tet_groups};
use super::super::{check_length, gather};
use super::{ElementForces, TetPartition};
use crate::error::{Buffer, MeshError};

impl TetPartition<'_> {
    /// Owner piece `piece` of the owner-computes direct force pass: adds into `out` (vertex
    /// piece `piece`'s slice of the caller's forces, N) the forces at `positions` (m) of every
    /// element incident to its vertices, in increasing (element, corner) order, evaluating
    /// each of those elements here. The pieces are independent: run them on any threads in any
    /// order, no other phase; the result has the bits of [`TetMesh::add_elastic_forces`].
    /// Assumes [`check_forces`](Self::check_forces) passed (its element buffer is not used).
    ///
    /// # Errors
    /// [`MeshError::PieceIndex`] past the last vertex piece; [`MeshError::LengthMismatch`]
    /// naming [`Buffer::Forces`] if `out` is not as long as the piece, or [`Buffer::Positions`].
    /// Nothing is written on error.
    pub fn add_forces_owned<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        piece: usize,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        check_length(Buffer::Positions, self.mesh.vertex_count(), positions.len())?;
        let vertices =
            self.check_piece(piece, self.vertex_piece_count(), self.vertex_piece(piece))?;
        check_length(Buffer::Forces, vertices.len(), out.len())?;
        let Some(elements) = self.incident_elements(vertices.clone()) else {
            return Ok(()); // No element touches these vertices.
        };
        let (tets, rests) = (self.mesh.tets(), self.mesh.rest());
        let n = tets.len();
        let whole = if BATCH_FORCES { n - n % LANES } else { 0 };
        let mut owner = OwnerSlice {
            out,
            first: vertices.start,
        };
        // Whole groups from the one holding the first incident element, then single elements.
        let first_group = elements.start - elements.start % LANES;
        let grouped_end = whole.clamp(first_group, elements.end.next_multiple_of(LANES));
        let group_tets = tets.get(first_group..grouped_end).unwrap_or(&[]);
        let group_rests = rests.get(first_group..grouped_end).unwrap_or(&[]);
        for group in tet_groups(group_tets, group_rests) {
            if group.0.iter().any(|corners| owner.touches(corners)) {
                owner.add_group(material, positions, group);
            }
        }
        let single = grouped_end.max(elements.start)..elements.end;
        let single_tets = tets.get(single.clone()).unwrap_or(&[]);
        let single_rests = rests.get(single).unwrap_or(&[]);
        for (corners, rest) in single_tets.iter().zip(single_rests) {
            if owner.touches(corners) {
                let f = rest.deformation_gradient(gather(positions, corners));
                owner.add(corners, rest.nodal_forces(material.first_piola(f)));
            }
        }
        Ok(())
    }

    /// The elements from the first to the last one incident to any of `vertices`, or `None` if
    /// none is.
    fn incident_elements(&self, vertices: Range<usize>) -> Option<Range<usize>> {
        let (mut first, mut last) = (usize::MAX, 0);
        for vertex in vertices {
            let mut incident = self.incident_corners(vertex);
            if let Some((element, _)) = incident.next() {
                first = first.min(element);
                last = last.max(incident.last().map_or(element, |(e, _)| e));
            }
        }
        (first != usize::MAX).then(|| first..last + 1)
    }
}

/// A vertex piece's slice of the forces, indexed by global vertex.
struct OwnerSlice<'o> {
    out: &'o mut [Vec3],
    first: usize,
}

impl OwnerSlice<'_> {
    /// Whether some corner is one of this piece's vertices.
    #[inline]
    fn touches(&self, corners: &[u32; 4]) -> bool {
        corners.iter().any(|&v| {
            (v as usize)
                .checked_sub(self.first)
                .is_some_and(|i| i < self.out.len())
        })
    }

    /// Adds `values` at the corners that are this piece's vertices, corner by corner.
    #[inline(always)]
    fn add(&mut self, corners: &[u32; 4], values: ElementForces) {
        for (&v, value) in corners.iter().zip(values) {
            if let Some(slot) = (v as usize)
                .checked_sub(self.first)
                .and_then(|i| self.out.get_mut(i))
            {
                *slot += value;
            }
        }
    }

    /// Evaluates a group of [`LANES`] elements and adds their forces at this piece's vertices,
    /// element by element and corner by corner, as the sequential grouped kernel scatters them.
    #[inline(always)]
    fn add_group<M: Material>(&mut self, material: &M, positions: &[Vec3], group: TetGroup<'_>) {
        let gradients = GroupGradients::new(positions, group);
        let mut forces = [[Vec3::ZERO; 4]; LANES];
        gradients.write_forces(material.first_piola_lanes(gradients.f), &mut forces);
        for (corners, values) in group.0.iter().zip(forces) {
            self.add(corners, values);
        }
    }
}

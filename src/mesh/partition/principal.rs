//! The principal (SVD) and clamped force passes of a [`TetPartition`]: the element pieces of
//! [`TetMesh::add_elastic_forces_principal`] and [`TetMesh::add_elastic_forces_clamped`]; their
//! vertex pieces are [`gather_forces`](TetPartition::gather_forces), as for the direct pass.

use core::ops::Range;

use super::super::super::lanes::LANES;
use super::super::super::material::Material;
use super::super::super::math::BATCH_SVD;
use super::super::super::element::TetRest;
use super::super::super::svd::{Svd3, svd3, svd3_lanes};
use super::super::super::types::{Mat3, Real, Vec3};
#[cfg(doc)]
use super::super::TetMesh;
use super::super::grouped::{ClampedStress, PrincipalStress, SvdForces, SvdStress, tet_groups};
use super::super::{check_clamp_threshold, check_length, check_positions, gather};
use super::owner::{OwnerSlice, one_piece};
use super::{ElementForces, TetPartition, grouped_len};
use crate::error::{Buffer, MeshError};

impl TetPartition<'_> {
    /// The check of a partitioned principal force pass: the tests of
    /// [`TetMesh::add_elastic_forces_principal`] in its order (positions, deformation range,
    /// forces' length), then the element buffer's length.
    ///
    /// # Errors
    /// As [`TetMesh::add_elastic_forces_principal`]; then [`MeshError::LengthMismatch`] naming
    /// [`Buffer::ElementForces`] if `element_forces` does not have
    /// [`element_forces_len`](super::element_forces_len) entries.
    pub fn check_principal<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &[Vec3],
        element_forces: &[ElementForces],
    ) -> Result<(), MeshError> {
        let mesh = &self.mesh;
        check_positions(mesh.vertex_count(), positions)?;
        mesh.check_deformation(material, positions)?;
        check_length(Buffer::Forces, mesh.vertex_count(), forces.len())?;
        self.check_element_buffer(element_forces.len())
    }

    /// The check of a partitioned clamped force pass: `threshold` first, as
    /// [`TetMesh::add_elastic_forces_clamped`] checks it, then as
    /// [`check_principal`](Self::check_principal).
    ///
    /// # Errors
    /// [`MeshError::ClampThreshold`] if `threshold` is not in `(0, 1]`; then as
    /// [`check_principal`](Self::check_principal).
    pub fn check_clamped<M: Material>(
        &self,
        material: &M,
        threshold: Real,
        positions: &[Vec3],
        forces: &[Vec3],
        element_forces: &[ElementForces],
    ) -> Result<(), MeshError> {
        check_clamp_threshold(threshold)?;
        self.check_principal(material, positions, forces, element_forces)
    }

    /// Element piece `piece` of the principal force pass: writes the nodal forces (N) of the
    /// stress `U diag(dW/ds) V^T` ([`Material::first_piola_from_svd`]) of each of its elements
    /// at `positions` (m) into `out`, with the bits of
    /// [`TetMesh::add_elastic_forces_principal`]. Assumes
    /// [`check_principal`](Self::check_principal) passed.
    ///
    /// # Errors
    /// As [`element_forces`](Self::element_forces). Nothing is written on error.
    pub fn element_forces_principal<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        piece: usize,
        out: &mut [ElementForces],
    ) -> Result<(), MeshError> {
        self.element_svd_forces(positions, piece, out, PrincipalStress(material))
    }

    /// Element piece `piece` of the clamped force pass (**not an energy gradient: explicit
    /// stepping only**): as [`element_forces_principal`](Self::element_forces_principal) with
    /// the stretches clamped from below at `threshold`
    /// ([`Material::first_piola_clamped_from_svd`]), with the bits of
    /// [`TetMesh::add_elastic_forces_clamped`]. Assumes [`check_clamped`](Self::check_clamped)
    /// passed.
    ///
    /// # Errors
    /// [`MeshError::ClampThreshold`] if `threshold` is not in `(0, 1]`; then as
    /// [`element_forces`](Self::element_forces). Nothing is written on error.
    pub fn element_forces_clamped<M: Material>(
        &self,
        material: &M,
        threshold: Real,
        positions: &[Vec3],
        piece: usize,
        out: &mut [ElementForces],
    ) -> Result<(), MeshError> {
        check_clamp_threshold(threshold)?;
        let stress = ClampedStress {
            material,
            threshold,
        };
        self.element_svd_forces(positions, piece, out, stress)
    }

    /// Owner piece `piece` of the owner-computes principal force pass: adds into `out` (vertex
    /// piece `piece`'s slice of the forces, N) the principal-path forces
    /// ([`Material::first_piola_from_svd`]) at `positions` (m) of every element incident to its
    /// vertices, as [`add_forces_owned`](Self::add_forces_owned) does for the direct path: the
    /// bits of [`TetMesh::add_elastic_forces_principal`], no element buffer, no gather. Assumes
    /// [`check_principal`](Self::check_principal) passed.
    ///
    /// # Errors
    /// As [`add_forces_owned`](Self::add_forces_owned). Nothing is written on error.
    pub fn add_forces_principal_owned<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        piece: usize,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        self.add_forces_principal_span(material, positions, one_piece(piece), out)
    }

    /// [`add_forces_principal_owned`](Self::add_forces_principal_owned) for the consecutive
    /// vertex pieces `pieces` as one owner (`out` their slices, end to end).
    pub(crate) fn add_forces_principal_span<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        pieces: Range<usize>,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        self.owner_svd_forces(material, positions, pieces, out, PrincipalStress(material))
    }

    /// Owner piece `piece` of the owner-computes clamped force pass (**not an energy gradient:
    /// explicit stepping only**): as
    /// [`add_forces_principal_owned`](Self::add_forces_principal_owned) with the stretches
    /// clamped from below at `threshold`, with the bits of
    /// [`TetMesh::add_elastic_forces_clamped`]. Assumes [`check_clamped`](Self::check_clamped)
    /// passed.
    ///
    /// # Errors
    /// [`MeshError::ClampThreshold`] if `threshold` is not in `(0, 1]`; then as
    /// [`add_forces_owned`](Self::add_forces_owned). Nothing is written on error.
    pub fn add_forces_clamped_owned<M: Material>(
        &self,
        material: &M,
        threshold: Real,
        positions: &[Vec3],
        piece: usize,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        let pieces = one_piece(piece);
        self.add_forces_clamped_span(material, threshold, positions, pieces, out)
    }

    /// [`add_forces_clamped_owned`](Self::add_forces_clamped_owned) for the consecutive vertex
    /// pieces `pieces` as one owner (`out` their slices, end to end).
    pub(crate) fn add_forces_clamped_span<M: Material>(
        &self,
        material: &M,
        threshold: Real,
        positions: &[Vec3],
        pieces: Range<usize>,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        check_clamp_threshold(threshold)?;
        let stress = ClampedStress {
            material,
            threshold,
        };
        self.owner_svd_forces(material, positions, pieces, out, stress)
    }

    /// The owner span `pieces` of the principal-path passes, with `stress` mapping an SVD of
    /// `F` to `P`: the sequential loop ([`SvdForces`] at the SIMD width it runs at) over the
    /// elements incident to the span's vertices.
    fn owner_svd_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        pieces: Range<usize>,
        out: &mut [Vec3],
        stress: impl SvdStress,
    ) -> Result<(), MeshError> {
        let vertices = self.owner_vertices(positions, pieces.clone(), out.len())?;
        let Some(elements) = self.span_elements(pieces) else {
            return Ok(()); // No element touches these vertices.
        };
        let forces = OwnerSlice::new(out, vertices.start);
        let job = SvdForces { forces, stress };
        self.owner_pass(material, positions, elements, job, BATCH_SVD);
        Ok(())
    }

    /// The element loop of the principal-path pieces, with `stress` mapping an SVD of `F` to
    /// `P`: the SVDs [`LANES`] at a time where the sequential
    /// loop batches them ([`svd3_lanes`], the same bits as [`svd3`] either way), one at a time
    /// after the last whole group.
    fn element_svd_forces(
        &self,
        positions: &[Vec3],
        piece: usize,
        out: &mut [ElementForces],
        stress: impl SvdStress,
    ) -> Result<(), MeshError> {
        let (tets, rests) = self.element_inputs(piece, positions, out.len())?;
        let grouped = grouped_len(
            BATCH_SVD,
            self.mesh.element_count(),
            self.element_piece(piece),
        );
        piece_svd_loop(
            positions,
            (tets, rests, grouped),
            out,
            |rest, svd, slot| *slot = rest.nodal_forces(stress.stress(svd)),
            |corners, rest, slot| {
                let svd = svd3(rest.deformation_gradient(gather(positions, corners)));
                *slot = rest.nodal_forces(stress.stress(&svd));
            },
        );
        Ok(())
    }
}

/// The element loop of a piece whose elements need the SVD of `F` at `positions` (m), batched
/// where the sequential kernel batches: the first `grouped` elements of `(tets, rests)` (a
/// multiple of [`LANES`]) a group at a time, their SVDs by [`svd3_lanes`] (the bits of [`svd3`]),
/// each handed to `from_svd` with the element's rest data and its slot of `out`; the elements
/// after them handed one at a time to `single`, with their corners.
#[inline(always)]
pub(super) fn piece_svd_loop<T>(
    positions: &[Vec3],
    (tets, rests, grouped): (&[[u32; 4]], &[TetRest], usize),
    out: &mut [T],
    mut from_svd: impl FnMut(&TetRest, &Svd3, &mut T),
    mut single: impl FnMut(&[u32; 4], &TetRest, &mut T),
) {
    let (out_groups, out_tail) = out.split_at_mut(grouped.min(out.len()));
    let (tets_groups, tets_tail) = tets.split_at(grouped.min(tets.len()));
    let (rests_groups, rests_tail) = rests.split_at(grouped.min(rests.len()));
    let groups = tet_groups(tets_groups, rests_groups);
    for ((tets, rests), slots) in groups.zip(out_groups.chunks_exact_mut(LANES)) {
        let gradients = core::array::from_fn(|lane| match (tets.get(lane), rests.get(lane)) {
            (Some(corners), Some(rest)) => rest.deformation_gradient(gather(positions, corners)),
            _ => Mat3::ZERO,
        });
        let svds = svd3_lanes(&gradients);
        for ((rest, svd), slot) in rests.iter().zip(&svds).zip(slots) {
            from_svd(rest, svd, slot);
        }
    }
    for ((corners, rest), slot) in tets_tail.iter().zip(rests_tail).zip(out_tail) {
        single(corners, rest, slot);
    }
}

//! The tetrahedral force, energy, fused and Hessian passes split into independent pieces that a
//! caller can run on any threads, in any order, with the bits of the sequential pass.
//!
//! # Why a gather
//! The sequential kernels ([`TetMesh::add_elastic_forces`] and the others) add every element's
//! four nodal forces into `forces` element by element, corner by corner: the float sum of each
//! vertex follows element order. Adding from several threads at once (atomics, or any split of
//! the elements) would change that order, and so the bits, with the schedule. A
//! [`TetPartition`] instead runs a pass in two phases:
//!
//! 1. **Element pieces**: piece `k` covers the elements
//!    [`element_piece(k)`](TetPartition::element_piece) (consecutive ranges of
//!    [`element_chunk`](TetPartition::element_chunk) elements, a multiple of [`LANES`], the last
//!    one shorter) and writes each element's four nodal forces (and, for the energy passes, its
//!    energy) into the piece's slice of a caller buffer. Elements are evaluated exactly as the
//!    sequential kernel evaluates them — in groups of [`LANES`] where it groups them, one at a
//!    time where it does not — so every element's forces have the sequential bits.
//! 2. **Vertex pieces**: piece `k` covers the vertices
//!    [`vertex_piece(k)`](TetPartition::vertex_piece) (consecutive ranges of
//!    [`vertex_chunk`](TetPartition::vertex_chunk) vertices) and adds into `forces[v]`, for each
//!    of its vertices, the element forces at `v` in increasing (element, corner) order, through
//!    the vertex-to-element adjacency in compressed rows
//!    ([`build_vertex_adjacency`]): the very
//!    additions, in the very order, that the sequential scatter makes into `forces[v]`, starting
//!    from the caller's `forces[v]`.
//!
//! The pieces of one phase are independent (each writes only its own slice and reads only
//! inputs), so any schedule — any number of threads, any order, pieces stolen between threads —
//! gives the same bits, and so does any piece count: the bits are those of the sequential pass.
//! Run every element piece before any vertex piece. The total energy is then summed from the
//! per-element energies by one call in the sequential pass's order
//! ([`total_energy`](TetPartition::total_energy), [`fused_total_energy`](TetPartition::fused_total_energy)).
//!
//! The force passes, the fused energy-and-force pass and the Hessian product also have an
//! **owner-computes** form without element buffer or gather (the one `softfem::parallel` runs):
//! [`add_forces_owned`](TetPartition::add_forces_owned),
//! [`add_forces_principal_owned`](TetPartition::add_forces_principal_owned),
//! [`add_forces_clamped_owned`](TetPartition::add_forces_clamped_owned),
//! [`energy_and_add_forces_owned`](TetPartition::energy_and_add_forces_owned) and
//! [`add_hessian_product_owned`](TetPartition::add_hessian_product_owned). Each vertex piece runs
//! the sequential kernel's own loop (its SIMD groups, at the width [`simd`](crate::simd) picks)
//! over the elements at its vertices and adds their forces at its own vertices straight into its
//! slice, elements cut by a piece boundary evaluated by each piece they touch (see
//! `partition/owner.rs`); vertex piece `k` of the fused pass also writes the energies of
//! [`energy_piece(k)`](TetPartition::energy_piece), summed afterwards in the sequential order by
//! [`fused_total_energy`](TetPartition::fused_total_energy). On one thread the owner-computes
//! passes cost about the sequential pass plus the cut elements (one layer of a box cut in two);
//! the two-phase form writes and gathers 48 bytes per element.
//!
//! The passes: the direct forces ([`element_forces`](TetPartition::element_forces)), the
//! principal and clamped forces
//! ([`element_forces_principal`](TetPartition::element_forces_principal),
//! [`element_forces_clamped`](TetPartition::element_forces_clamped)), the energy, the fused
//! energy-and-force pass, the projected Hessians
//! ([`element_hessians`](TetPartition::element_hessians): element pieces only, each writes its
//! slice of the cache) and their products
//! ([`element_hessian_products`](TetPartition::element_hessian_products)), all gathered by
//! [`gather_forces`](TetPartition::gather_forces); and the Hessian's diagonal blocks
//! ([`gather_vertex_blocks`](TetPartition::gather_vertex_blocks): vertex pieces only, each sums
//! its vertices' blocks straight from the cache).
//!
//! Each pass starts with a check (`check_*`, sequential, one pass over the positions) that makes
//! the same tests in the same order as the sequential kernel and fails with the same error; the
//! pieces assume it passed. Nothing is allocated: the adjacency lives in caller buffers of
//! [`partition_offsets_len`] and [`partition_incident_len`] entries, the element results in
//! buffers of [`element_forces_len`] entries (and one energy per element).
//!
//! With the `rayon` feature, `softfem::parallel` runs these pieces on rayon's pool.
//!
//! ```
//! use softfem::generate::{BoxSplit, box_counts, fill_box};
//! use softfem::glam::Vec3;
//! use softfem::material::StableNeoHookean;
//! use softfem::element::TetRest;
//! use softfem::mesh::{TetMesh, TetPartition, element_forces_len};
//! use softfem::mesh::{partition_incident_len, partition_offsets_len};
//!
//! let (vertices, tets) = box_counts(3, 3, 3, BoxSplit::Kuhn6)?;
//! let (mut rest, mut elements) = (vec![Vec3::ZERO; vertices], vec![[0; 4]; tets]);
//! fill_box(Vec3::ZERO, Vec3::ONE, 3, 3, 3, BoxSplit::Kuhn6, &mut rest, &mut elements)?;
//! let mut rest_data = vec![TetRest::default(); tets];
//! let mesh = TetMesh::new(&rest, &elements, &mut rest_data)?;
//! let (mut offsets, mut incident) =
//!     (vec![0; partition_offsets_len(vertices)], vec![0; partition_incident_len(tets)]);
//! let partition = TetPartition::new(mesh, 4, &mut offsets, &mut incident)?;
//!
//! let material = StableNeoHookean::from_young_poisson(1.0e5, 0.4)?;
//! let x: Vec<Vec3> = rest.iter().map(|p| *p * Vec3::new(1.0, 1.0, 0.9)).collect();
//! let mut element_forces = vec![[Vec3::ZERO; 4]; element_forces_len(tets)];
//! let mut forces = vec![Vec3::ZERO; vertices];
//! partition.check_forces(&material, &x, &forces, &element_forces)?;
//! // Any order, any threads: here last piece first.
//! let chunk = partition.element_chunk();
//! for (piece, out) in element_forces.chunks_mut(chunk).enumerate().rev() {
//!     partition.element_forces(&material, &x, piece, out)?;
//! }
//! for (piece, out) in forces.chunks_mut(partition.vertex_chunk()).enumerate().rev() {
//!     partition.gather_forces(&element_forces, piece, out)?;
//! }
//!
//! let mut sequential = vec![Vec3::ZERO; vertices];
//! mesh.add_elastic_forces(&material, &x, &mut sequential)?;
//! assert!(forces.iter().zip(&sequential).all(|(a, b)| a.to_array().map(f32::to_bits)
//!     == b.to_array().map(f32::to_bits)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use core::ops::Range;

use super::super::element::TetRest;
use super::super::lanes::{LANES, Lane, Lanes};
use super::super::material::Material;
use super::super::math::BATCH_FORCES;
use super::super::types::{Real, Vec3};
use super::adjacency::{adjacency_incident_len, adjacency_offsets_len, build_vertex_adjacency};
use super::grouped::{GroupGradients, tet_groups};
use super::{TetMesh, check_length, check_positions, gather};
use crate::error::{Buffer, MeshError, StepBuffer, StepError};

mod hessian;
mod owner;
mod principal;

/// The nodal forces (N) of one tetrahedron at its four corners, in corner order: the entry of
/// the element buffer of a partitioned pass.
pub type ElementForces = [Vec3; 4];

/// The length of the adjacency `offsets` buffer of a [`TetPartition`] over `vertex_count`
/// vertices: `vertex_count + 1` (saturating).
#[inline]
#[must_use]
pub const fn partition_offsets_len(vertex_count: usize) -> usize {
    adjacency_offsets_len(vertex_count)
}

/// The length of the adjacency `incident` buffer of a [`TetPartition`] over `element_count`
/// tetrahedra: `4 * element_count` (saturating).
#[inline]
#[must_use]
pub const fn partition_incident_len(element_count: usize) -> usize {
    adjacency_incident_len(element_count)
}

/// The length of the element-forces buffer of a partitioned pass: one [`ElementForces`] per
/// tetrahedron (`12 * element_count` numbers). The energy passes take one `Real` per element
/// besides.
#[inline]
#[must_use]
pub const fn element_forces_len(element_count: usize) -> usize {
    element_count
}

/// A [`TetMesh`] with its vertex-to-element adjacency and a fixed split of its elements and of
/// its vertices into pieces: see the [module documentation](self) for the scheme and an example.
///
/// `element_chunk` is `ceil(elements / pieces)` rounded up to a multiple of [`LANES`], and
/// `vertex_chunk` is `ceil(vertices / pieces)` (both at least 1): piece `k` of each kind is the
/// `k`-th chunk of that length, as `slice.chunks_mut(chunk)` yields them, so a caller hands each
/// piece its slice with `chunks_mut` and its index with `enumerate`. The piece count changes the
/// work split, never the result.
#[derive(Clone, Copy, Debug)]
pub struct TetPartition<'a> {
    mesh: TetMesh<'a>,
    offsets: &'a [u32],
    incident: &'a [u32],
    element_chunk: usize,
    vertex_chunk: usize,
    /// The elements from the first to the last one incident to each of the first
    /// [`CACHED_PIECES`] vertex pieces (`start..end`, empty if none is), found once here rather
    /// than by a scan of the piece's adjacency rows at every owner-computes pass; then the
    /// longest run of consecutive elements among them that all touch the piece
    /// (`dense_start..dense_end`), which the owner-computes passes run without testing each
    /// group for whether it touches the piece.
    piece_elements: [[u32; 4]; CACHED_PIECES],
}

/// The vertex pieces whose incident element range a [`TetPartition`] keeps. The owner-computes
/// passes want about one piece per thread; pieces past this find their range at every pass from
/// their adjacency rows, a read that cost 5 % of a StVK force pass at 105k tets and 9 % at 998k
/// on one thread (measured on the development machine; `benches/parallel.rs`).
const CACHED_PIECES: usize = 64;

impl<'a> TetPartition<'a> {
    /// Splits `mesh` into about `pieces` element pieces and as many vertex pieces (`0` counts as
    /// 1), building its vertex-to-element adjacency into `offsets`
    /// ([`partition_offsets_len`]`(vertices)` entries) and `incident`
    /// ([`partition_incident_len`]`(elements)` entries), both overwritten. A few pieces per
    /// thread balance the load best.
    ///
    /// # Errors
    /// [`MeshError::TooManyElements`] beyond `u32::MAX / 4` elements;
    /// [`MeshError::LengthMismatch`] naming [`Buffer::AdjacencyOffsets`] or
    /// [`Buffer::AdjacencyIncident`]. Nothing is written on error.
    pub fn new(
        mesh: TetMesh<'a>,
        pieces: usize,
        offsets: &'a mut [u32],
        incident: &'a mut [u32],
    ) -> Result<Self, MeshError> {
        let (elements, vertices) = (mesh.element_count(), mesh.vertex_count());
        build_vertex_adjacency(mesh.tets(), vertices, offsets, incident).map_err(|error| {
            match error {
                StepError::LengthMismatch {
                    buffer,
                    expected,
                    actual,
                } => MeshError::LengthMismatch {
                    buffer: if buffer == StepBuffer::AdjacencyOffsets {
                        Buffer::AdjacencyOffsets
                    } else {
                        Buffer::AdjacencyIncident
                    },
                    expected,
                    actual,
                },
                // The mesh validated its indices: only the element count is left.
                _ => MeshError::TooManyElements,
            }
        })?;
        let pieces = pieces.max(1);
        let element_chunk = elements.div_ceil(pieces).div_ceil(LANES).max(1) * LANES;
        let mut partition = TetPartition {
            mesh,
            offsets,
            incident,
            element_chunk,
            vertex_chunk: vertices.div_ceil(pieces).max(1),
            piece_elements: [[0; 4]; CACHED_PIECES],
        };
        let mut piece_elements = [[0; 4]; CACHED_PIECES];
        for (piece, range) in piece_elements.iter_mut().enumerate() {
            let vertices = partition.vertex_piece(piece);
            if let Some(elements) = partition.scan_incident_elements(vertices.clone()) {
                let dense = partition.touching_run(vertices, elements.clone());
                // Below `u32::MAX / 4` elements (the adjacency's limit, checked above).
                *range = [elements.start, elements.end, dense.start, dense.end].map(|i| i as u32);
            }
        }
        partition.piece_elements = piece_elements;
        Ok(partition)
    }

    /// The mesh.
    #[inline]
    #[must_use]
    pub fn mesh(&self) -> TetMesh<'a> {
        self.mesh
    }

    /// The elements per element piece (a multiple of [`LANES`]; the last piece may be shorter).
    #[inline]
    #[must_use]
    pub fn element_chunk(&self) -> usize {
        self.element_chunk
    }

    /// The vertices per vertex piece (the last piece may be shorter).
    #[inline]
    #[must_use]
    pub fn vertex_chunk(&self) -> usize {
        self.vertex_chunk
    }

    /// The number of element pieces: `ceil(elements / element_chunk)`.
    #[inline]
    #[must_use]
    pub fn element_piece_count(&self) -> usize {
        self.mesh.element_count().div_ceil(self.element_chunk)
    }

    /// The number of vertex pieces: `ceil(vertices / vertex_chunk)`.
    #[inline]
    #[must_use]
    pub fn vertex_piece_count(&self) -> usize {
        self.mesh.vertex_count().div_ceil(self.vertex_chunk)
    }

    /// The elements of element piece `piece` (empty past the last piece).
    #[inline]
    #[must_use]
    pub fn element_piece(&self, piece: usize) -> Range<usize> {
        chunk_range(piece, self.element_chunk, self.mesh.element_count())
    }

    /// The vertices of vertex piece `piece` (empty past the last piece).
    #[inline]
    #[must_use]
    pub fn vertex_piece(&self, piece: usize) -> Range<usize> {
        chunk_range(piece, self.vertex_chunk, self.mesh.vertex_count())
    }

    /// The check of a partitioned force pass, the tests of
    /// [`TetMesh::add_elastic_forces`] in its order, and then the element buffer's length.
    ///
    /// # Errors
    /// As [`TetMesh::add_elastic_forces`]; then [`MeshError::LengthMismatch`] naming
    /// [`Buffer::ElementForces`] if `element_forces` does not have [`element_forces_len`]
    /// entries.
    pub fn check_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &[Vec3],
        element_forces: &[ElementForces],
    ) -> Result<(), MeshError> {
        let mesh = &self.mesh;
        check_positions(mesh.vertex_count(), positions)?;
        check_length(Buffer::Forces, mesh.vertex_count(), forces.len())?;
        mesh.check_deformation(material, positions)?;
        self.check_element_buffer(element_forces.len())
    }

    /// Element piece `piece` of the direct force pass: writes the nodal forces of its elements
    /// at `positions` into `out` (its slice of the element buffer). Assumes
    /// [`check_forces`](Self::check_forces) passed.
    ///
    /// # Errors
    /// [`MeshError::PieceIndex`] past the last piece; [`MeshError::LengthMismatch`] naming
    /// [`Buffer::ElementForces`] if `out` is not as long as the piece, or
    /// [`Buffer::Positions`]. Nothing is written on error.
    pub fn element_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        piece: usize,
        out: &mut [ElementForces],
    ) -> Result<(), MeshError> {
        let (tets, rests) = self.element_inputs(piece, positions, out.len())?;
        let grouped = self.grouped_len(piece);
        let (out_groups, out_tail) = out.split_at_mut(grouped.min(out.len()));
        let (tets_tail, rests_tail) = (tets.get(grouped..), rests.get(grouped..));
        for (group, slots) in tet_groups(tets, rests).zip(out_groups.chunks_exact_mut(LANES)) {
            let gradients = GroupGradients::new(positions, group);
            gradients.write_forces(material.first_piola_lanes(gradients.f), slots);
        }
        let tail = tets_tail
            .unwrap_or(&[])
            .iter()
            .zip(rests_tail.unwrap_or(&[]));
        for ((corners, rest), slot) in tail.zip(out_tail) {
            let f = rest.deformation_gradient(gather(positions, corners));
            *slot = rest.nodal_forces(material.first_piola(f));
        }
        Ok(())
    }

    /// Vertex piece `piece` of every force pass: adds into `out` (its slice of the caller's
    /// forces, N) the element forces at each of its vertices, in increasing (element, corner)
    /// order: the sequential scatter's additions. Run it after every element piece.
    ///
    /// # Errors
    /// [`MeshError::PieceIndex`] past the last piece; [`MeshError::LengthMismatch`] naming
    /// [`Buffer::Forces`] if `out` is not as long as the piece, or [`Buffer::ElementForces`].
    /// Nothing is written on error.
    pub fn gather_forces(
        &self,
        element_forces: &[ElementForces],
        piece: usize,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        self.check_element_buffer(element_forces.len())?;
        let vertices =
            self.check_piece(piece, self.vertex_piece_count(), self.vertex_piece(piece))?;
        check_length(Buffer::Forces, vertices.len(), out.len())?;
        for (vertex, slot) in vertices.zip(out) {
            for (element, corner) in self.incident_corners(vertex) {
                if let Some(force) = element_forces.get(element).and_then(|f| f.get(corner)) {
                    *slot += *force;
                }
            }
        }
        Ok(())
    }

    /// The (element, corner) pairs at `vertex`, in increasing order: the order in which the
    /// sequential scatter adds into it.
    #[inline]
    fn incident_corners(&self, vertex: usize) -> impl Iterator<Item = (usize, usize)> + 'a {
        let start = self.offsets.get(vertex).copied().unwrap_or(0) as usize;
        let end = self.offsets.get(vertex + 1).copied().unwrap_or(0) as usize;
        let incident: &'a [u32] = self.incident.get(start..end).unwrap_or(&[]);
        incident
            .iter()
            .map(|&packed| ((packed >> 2) as usize, (packed & 3) as usize))
    }

    /// The check of a partitioned energy pass, the tests of [`TetMesh::elastic_energy`] in its
    /// order, and then the energy buffer's length.
    ///
    /// # Errors
    /// As [`TetMesh::elastic_energy`]; then [`MeshError::LengthMismatch`] naming
    /// [`Buffer::Energies`] if `energies` does not have one entry per element.
    pub fn check_energy<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        energies: &[Real],
    ) -> Result<(), MeshError> {
        check_positions(self.mesh.vertex_count(), positions)?;
        self.mesh.check_deformation(material, positions)?;
        check_length(Buffer::Energies, self.mesh.element_count(), energies.len())
    }

    /// Element piece `piece` of the energy pass: writes the energy `V W(F)` (J) of each of its
    /// elements into `out` (its slice of the energy buffer), as [`TetMesh::elastic_energy`]
    /// computes it. Assumes [`check_energy`](Self::check_energy) passed.
    ///
    /// # Errors
    /// As [`element_forces`](Self::element_forces), for [`Buffer::Energies`].
    pub fn element_energies<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        piece: usize,
        out: &mut [Real],
    ) -> Result<(), MeshError> {
        let (tets, rests) = self.element_inputs(piece, positions, out.len())?;
        for ((corners, rest), slot) in tets.iter().zip(rests).zip(out) {
            *slot = rest.elastic_energy(material, gather(positions, corners));
        }
        Ok(())
    }

    /// The total energy (J) of the per-element `energies` of the energy pass, summed element by
    /// element in order as [`TetMesh::elastic_energy`] sums them (`Iterator::sum`).
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] naming [`Buffer::Energies`] if `energies` does not have
    /// one entry per element.
    pub fn total_energy(&self, energies: &[Real]) -> Result<Real, MeshError> {
        check_length(Buffer::Energies, self.mesh.element_count(), energies.len())?;
        Ok(energies.iter().copied().sum())
    }

    /// The check of a partitioned fused pass: the buffer lengths (positions, forces, element
    /// forces, energies), then whether the deformation is within the material's range. `false`
    /// means the sequential fused pass reports an infinite energy and leaves the forces alone:
    /// run no pieces then.
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] for the first buffer of the wrong length.
    pub fn check_fused<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &[Vec3],
        element_forces: &[ElementForces],
        energies: &[Real],
    ) -> Result<bool, MeshError> {
        let n = self.mesh.vertex_count();
        check_length(Buffer::Positions, n, positions.len())?;
        check_length(Buffer::Forces, n, forces.len())?;
        self.check_element_buffer(element_forces.len())?;
        check_length(Buffer::Energies, self.mesh.element_count(), energies.len())?;
        Ok(self.mesh.check_deformation(material, positions).is_ok())
    }

    /// Element piece `piece` of the fused energy-and-force pass of the energy-based steppers:
    /// writes each element's energy (J) into `energies` and its nodal forces (N) into `forces`
    /// (the piece's slices), both from one deformation gradient, as the sequential fused pass
    /// computes them. Assumes [`check_fused`](Self::check_fused) returned `true`.
    ///
    /// # Errors
    /// As [`element_forces`](Self::element_forces), for either buffer.
    pub fn element_energies_and_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        piece: usize,
        energies: &mut [Real],
        forces: &mut [ElementForces],
    ) -> Result<(), MeshError> {
        let (tets, rests) = self.element_inputs(piece, positions, forces.len())?;
        check_length(Buffer::Energies, forces.len(), energies.len())?;
        let grouped = self.grouped_len(piece);
        let (force_groups, force_tail) = forces.split_at_mut(grouped.min(forces.len()));
        let (energy_groups, energy_tail) = energies.split_at_mut(grouped.min(energies.len()));
        let (tets_tail, rests_tail) = (tets.get(grouped..), rests.get(grouped..));
        let slots = force_groups
            .chunks_exact_mut(LANES)
            .zip(energy_groups.chunks_exact_mut(LANES));
        for (group, (force_slots, energy_slots)) in tet_groups(tets, rests).zip(slots) {
            let gradients = GroupGradients::new(positions, group);
            let (density, p) = material.energy_and_first_piola_lanes(gradients.f);
            energy_slots.copy_from_slice(&(gradients.volume * density).to_array());
            gradients.write_forces(p, force_slots);
        }
        let tail = tets_tail
            .unwrap_or(&[])
            .iter()
            .zip(rests_tail.unwrap_or(&[]));
        for ((corners, rest), (force, energy)) in tail.zip(force_tail.iter_mut().zip(energy_tail)) {
            let f = rest.deformation_gradient(gather(positions, corners));
            let (density, stress) = material.energy_and_first_piola(f);
            *energy = rest.volume * density;
            *force = rest.nodal_forces(stress);
        }
        Ok(())
    }

    /// The total energy (J) of the per-element `energies` of the fused pass, in the fused pass's
    /// order (`LaneSum`): element `i` of the first `n - n % LANES` adds to partial sum
    /// `i % LANES` (each starting from zero), the partial sums are added as
    /// `(s0 + s1) + (s2 + s3)`, then the last `n % LANES` elements in order.
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] naming [`Buffer::Energies`] if `energies` does not have
    /// one entry per element.
    pub fn fused_total_energy(&self, energies: &[Real]) -> Result<Real, MeshError> {
        let n = self.mesh.element_count();
        check_length(Buffer::Energies, n, energies.len())?;
        let whole = n - n % LANES;
        let (grouped, tail) = energies.split_at(whole.min(energies.len()));
        let mut partial = Lanes::splat(0.0);
        for group in grouped.chunks_exact(LANES) {
            let mut terms = [0.0; LANES];
            terms.copy_from_slice(group);
            partial = partial + Lanes::from_array(terms);
        }
        // The sequential pass adds its other (zero) partial sums here.
        let [s0, s1, s2, s3] = (partial + Lanes::splat(0.0)).to_array();
        let last = tail.iter().fold(0.0, |sum: Real, &e| sum + e);
        Ok(((s0 + s1) + (s2 + s3)) + last)
    }

    /// The whole direct force pass on this thread, piece by piece in the owner-computes form
    /// ([`add_forces_owned`](Self::add_forces_owned)): the work, cut elements included, that the
    /// pieces of the scheme `softfem::parallel` runs on a pool of as many threads do
    /// (`element_forces` is checked, not used). Adds into `forces` as [`TetMesh::add_elastic_forces`] does,
    /// with the same bits.
    ///
    /// # Errors
    /// As [`check_forces`](Self::check_forces); on error, `forces` is unchanged.
    pub fn add_elastic_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &mut [Vec3],
        element_forces: &mut [ElementForces],
    ) -> Result<(), MeshError> {
        self.check_forces(material, positions, forces, element_forces)?;
        for (piece, out) in forces.chunks_mut(self.vertex_chunk).enumerate() {
            self.add_forces_owned(material, positions, piece, out)?;
        }
        Ok(())
    }

    /// `Ok(piece_range)` if `piece` is below `count`.
    fn check_piece(
        &self,
        piece: usize,
        count: usize,
        range: Range<usize>,
    ) -> Result<Range<usize>, MeshError> {
        if piece < count {
            Ok(range)
        } else {
            Err(MeshError::PieceIndex {
                piece,
                pieces: count,
            })
        }
    }

    /// `Ok` if the element buffer has one entry per element.
    fn check_element_buffer(&self, len: usize) -> Result<(), MeshError> {
        check_length(
            Buffer::ElementForces,
            element_forces_len(self.mesh.element_count()),
            len,
        )
    }

    /// The vertex indices and rest data of element piece `piece`, after checking the piece
    /// index, the output length `out_len` and the positions' length.
    #[allow(clippy::type_complexity)]
    fn element_inputs(
        &self,
        piece: usize,
        positions: &[Vec3],
        out_len: usize,
    ) -> Result<(&'a [[u32; 4]], &'a [TetRest]), MeshError> {
        let range =
            self.check_piece(piece, self.element_piece_count(), self.element_piece(piece))?;
        check_length(Buffer::ElementForces, range.len(), out_len)?;
        check_length(Buffer::Positions, self.mesh.vertex_count(), positions.len())?;
        let tets = self.mesh.tets().get(range.clone()).unwrap_or(&[]);
        let rests = self.mesh.rest().get(range).unwrap_or(&[]);
        Ok((tets, rests))
    }

    /// How many of element piece `piece`'s elements (from its start) the sequential kernel
    /// evaluates [`LANES`] at a time: those before the last whole group's end, where it batches.
    /// Pieces start at multiples of [`LANES`], so these are whole sequential groups.
    fn grouped_len(&self, piece: usize) -> usize {
        grouped_len(
            BATCH_FORCES,
            self.mesh.element_count(),
            self.element_piece(piece),
        )
    }
}

/// How many of the elements `range` (from its start, a multiple of [`LANES`]) of a mesh of
/// `elements` a sequential kernel that batches when `batch` evaluates [`LANES`] at a time.
fn grouped_len(batch: bool, elements: usize, range: Range<usize>) -> usize {
    if !batch {
        return 0;
    }
    (elements - elements % LANES).clamp(range.start, range.end) - range.start
}

/// Chunk `piece` of length `chunk` of `0..len` (empty past the end).
#[inline]
fn chunk_range(piece: usize, chunk: usize, len: usize) -> Range<usize> {
    let start = piece.saturating_mul(chunk).min(len);
    start..start.saturating_add(chunk).min(len)
}

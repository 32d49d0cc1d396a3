//! The owner-computes form of the direct force pass and of the fused energy-and-force pass (the
//! principal and clamped force passes in `principal.rs`, the Hessian product in `hessian.rs`):
//! each vertex piece evaluates every element incident to its vertices and adds, corner by
//! corner, the forces at its own vertices straight into its slice of the output, as the
//! sequential scatter does. No element buffer and no gather: an element whose corners lie in
//! several vertex pieces (a *cut* element) is evaluated by each of them, and since an element's
//! forces do not depend on who evaluates them, every vertex receives the sequential scatter's
//! very additions, in the sequential order.
//!
//! Owner pieces run the sequential kernel's own loop ([`Pass`], at the SIMD width
//! [`simd`](crate::simd) picks) over the elements from the first to the last one incident to
//! their vertices, and skip a group when none of its elements touches the piece. Every width
//! gives every element the bits of the one-at-a-time code, so where a group starts changes
//! nothing but the speed.
//!
//! The work of an owner piece is the groups between the first and the last element incident to
//! its vertices: for meshes numbered with locality (the generators' boxes, any mesh reordered
//! along a space-filling curve or by layers) about its share of the mesh plus the cut layers,
//! which are evaluated twice. The fewer the vertex pieces, the fewer the cut elements: one piece
//! per thread for a uniform mesh. With one piece nothing is cut and the pass is the sequential
//! kernel with a range test per group.
//!
//! The fused pass also writes each element's energy, once: vertex piece `k` writes those of
//! [`energy_piece(k)`](TetPartition::energy_piece) (consecutive elements, evaluated by that piece
//! whether or not they touch its vertices), and one sequential call then sums them in the
//! sequential pass's order ([`fused_total_energy`](TetPartition::fused_total_energy)).

use core::ops::Range;

use super::super::super::lanes::{LANES, LaneArray, LaneMat3};
use super::super::super::material::Material;
use super::super::super::math::BATCH_FORCES;
use super::super::super::types::{Real, Vec3};
#[cfg(doc)]
use super::super::TetMesh;
use super::super::check_length;
use super::super::grouped::{
    DirectForces, EnergyAndForces, EnergySink, ForceSink, Pass, PassJob, WideGradients,
};
use super::{ElementForces, TetPartition};
use crate::error::{Buffer, MeshError};
use crate::simd::{WidthKernel, dispatch};

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
        let vertices = self.owner_vertices(positions, piece, out.len())?;
        let Some(elements) = self.incident_elements(piece) else {
            return Ok(()); // No element touches these vertices.
        };
        let job = DirectForces(OwnerSlice {
            out,
            first: vertices.start,
        });
        self.owner_pass(material, positions, elements, job, BATCH_FORCES);
        Ok(())
    }

    /// The elements whose energies vertex piece `piece` writes in the owner-computes fused pass
    /// ([`energy_and_add_forces_owned`](Self::energy_and_add_forces_owned)): the `piece`-th chunk
    /// of [`energy_chunk`](Self::energy_chunk) elements (empty past the last one). Over all
    /// vertex pieces, every element exactly once.
    #[inline]
    #[must_use]
    pub fn energy_piece(&self, piece: usize) -> Range<usize> {
        super::chunk_range(piece, self.energy_chunk(), self.mesh.element_count())
    }

    /// The elements per [`energy_piece`](Self::energy_piece): `ceil(elements / vertex pieces)`
    /// rounded up to a multiple of [`LANES`] (at least [`LANES`]), so that a caller hands each
    /// vertex piece its slice of the energy buffer with `chunks_mut` (the last vertex pieces may
    /// get none: an empty slice).
    #[inline]
    #[must_use]
    pub fn energy_chunk(&self) -> usize {
        let pieces = self.vertex_piece_count().max(1);
        self.mesh
            .element_count()
            .div_ceil(pieces)
            .div_ceil(LANES)
            .max(1)
            * LANES
    }

    /// Owner piece `piece` of the owner-computes fused energy-and-force pass of the
    /// energy-based steppers: adds into `out` (vertex piece `piece`'s slice of the forces, N)
    /// the forces of every element incident to its vertices, as
    /// [`add_forces_owned`](Self::add_forces_owned) does, and writes into `energies` the energy
    /// `V W(F)` (J) of each element of [`energy_piece(piece)`](Self::energy_piece), both from
    /// one deformation gradient as the sequential fused pass computes them. Sum the energies
    /// with [`fused_total_energy`](Self::fused_total_energy) once every piece ran. Assumes
    /// [`check_fused`](Self::check_fused) returned `true` (its element buffer is not used).
    ///
    /// # Errors
    /// As [`add_forces_owned`](Self::add_forces_owned); [`MeshError::LengthMismatch`] naming
    /// [`Buffer::Energies`] if `energies` is not as long as the energy piece. Nothing is
    /// written on error.
    pub fn energy_and_add_forces_owned<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        piece: usize,
        out: &mut [Vec3],
        energies: &mut [Real],
    ) -> Result<(), MeshError> {
        let vertices = self.owner_vertices(positions, piece, out.len())?;
        let energy_elements = self.energy_piece(piece);
        check_length(Buffer::Energies, energy_elements.len(), energies.len())?;
        let elements = match self.incident_elements(piece) {
            Some(incident) if !energy_elements.is_empty() => {
                incident.start.min(energy_elements.start)..incident.end.max(energy_elements.end)
            }
            Some(incident) => incident,
            None => energy_elements.clone(),
        };
        let job = EnergyAndForces {
            forces: OwnerSlice {
                out,
                first: vertices.start,
            },
            energy: EnergySlots {
                energies,
                first: energy_elements.start,
                end: energy_elements.end,
                pass_first: elements.start,
            },
        };
        self.owner_pass(material, positions, elements, job, BATCH_FORCES);
        Ok(())
    }

    /// The whole fused pass on this thread, piece by piece in the owner-computes form
    /// ([`energy_and_add_forces_owned`](Self::energy_and_add_forces_owned)): the one-thread
    /// cost of the scheme that `softfem::parallel` runs. Returns the energy (J) and adds the
    /// forces (N) into `forces` with the bits of the sequential fused pass; beyond the
    /// material's range the energy is infinite and `forces` is left alone, as there.
    /// `element_forces` is checked, not used; `energies` (one per element) receives every
    /// element's energy.
    ///
    /// # Errors
    /// As [`check_fused`](Self::check_fused); on error, `forces` is unchanged.
    pub fn energy_and_add_forces<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        forces: &mut [Vec3],
        element_forces: &[ElementForces],
        energies: &mut [Real],
    ) -> Result<Real, MeshError> {
        if !self.check_fused(material, positions, forces, element_forces, energies)? {
            return Ok(Real::INFINITY);
        }
        let energy_slices = energies
            .chunks_mut(self.energy_chunk())
            .chain(core::iter::repeat_with(<&mut [Real]>::default));
        let pieces = forces.chunks_mut(self.vertex_chunk).zip(energy_slices);
        for (piece, (out, energies)) in pieces.enumerate() {
            self.energy_and_add_forces_owned(material, positions, piece, out, energies)?;
        }
        self.fused_total_energy(energies)
    }

    /// The vertices of owner piece `piece`, after checking the piece index, the output length
    /// `out_len` and the positions' length.
    pub(super) fn owner_vertices(
        &self,
        positions: &[Vec3],
        piece: usize,
        out_len: usize,
    ) -> Result<Range<usize>, MeshError> {
        check_length(Buffer::Positions, self.mesh.vertex_count(), positions.len())?;
        let vertices =
            self.check_piece(piece, self.vertex_piece_count(), self.vertex_piece(piece))?;
        check_length(Buffer::Forces, vertices.len(), out_len)?;
        Ok(vertices)
    }

    /// Runs `job` over `elements` at the width the sequential kernels run at where `batch`,
    /// else one element at a time.
    #[inline(always)]
    pub(super) fn owner_pass<M: Material, J: PassJob>(
        &self,
        material: &M,
        positions: &[Vec3],
        elements: Range<usize>,
        job: J,
        batch: bool,
    ) {
        let pass = Pass {
            material,
            positions,
            tets: self.mesh.tets().get(elements.clone()).unwrap_or(&[]),
            rests: self.mesh.rest().get(elements).unwrap_or(&[]),
            job,
        };
        if batch {
            dispatch(pass);
        } else {
            pass.scalar();
        }
    }

    /// The elements from the first to the last one incident to any vertex of vertex piece
    /// `piece`, or `None` if none is: kept by the partition for the first pieces, else found
    /// from the adjacency.
    pub(super) fn incident_elements(&self, piece: usize) -> Option<Range<usize>> {
        match self.piece_elements.get(piece) {
            Some(&[start, end]) => (start < end).then_some(start as usize..end as usize),
            None => self.scan_incident_elements(self.vertex_piece(piece)),
        }
    }

    /// The elements from the first to the last one incident to any of `vertices`, or `None` if
    /// none is: each vertex's first and last incident element (its adjacency row is sorted).
    pub(super) fn scan_incident_elements(&self, vertices: Range<usize>) -> Option<Range<usize>> {
        let (mut first, mut last) = (u32::MAX, 0);
        let rows = self
            .offsets
            .get(vertices.start..=vertices.end)
            .unwrap_or(&[]);
        for row in rows.windows(2) {
            let &[start, end] = row else { continue };
            let incident = self.incident.get(start as usize..end as usize);
            if let Some((&head, &tail)) = incident.and_then(|r| r.first().zip(r.last())) {
                first = first.min(head >> 2);
                last = last.max(tail >> 2);
            }
        }
        (first != u32::MAX).then(|| first as usize..last as usize + 1)
    }
}

/// A vertex piece's slice of the forces, indexed by global vertex.
pub(super) struct OwnerSlice<'o> {
    pub out: &'o mut [Vec3],
    pub first: usize,
}

impl OwnerSlice<'_> {
    /// Whether some corner is one of this piece's vertices.
    #[inline(always)]
    pub fn touches(&self, corners: &[u32; 4]) -> bool {
        // Below `first` the index wraps past any slice length.
        corners
            .iter()
            .any(|&v| (v as usize).wrapping_sub(self.first) < self.out.len())
    }
}

impl ForceSink for OwnerSlice<'_> {
    #[inline(always)]
    fn skips(&self, tets: &[[u32; 4]]) -> bool {
        !tets.iter().any(|corners| self.touches(corners))
    }

    #[inline(always)]
    fn add_group<L: LaneArray>(
        &mut self,
        gradients: &WideGradients<L>,
        tets: &[[u32; 4]],
        p: LaneMat3<L>,
    ) {
        gradients.scatter_forces_from(tets, p, self.out, self.first);
    }

    /// Adds `forces` at the corners that are this piece's vertices, corner by corner.
    #[inline(always)]
    fn add(&mut self, corners: &[u32; 4], forces: ElementForces) {
        for (&v, force) in corners.iter().zip(forces) {
            if let Some(slot) = self.out.get_mut((v as usize).wrapping_sub(self.first)) {
                *slot += force;
            }
        }
    }
}

/// The energies of one energy piece of the owner-computes fused pass, written element by
/// element.
struct EnergySlots<'o> {
    /// The energies of elements `first..end` (J).
    energies: &'o mut [Real],
    first: usize,
    end: usize,
    /// The element at the start of the pass's slice.
    pass_first: usize,
}

impl EnergySink for EnergySlots<'_> {
    #[inline(always)]
    fn owes(&self, i: usize, count: usize) -> bool {
        let start = self.pass_first + i;
        start < self.end && start + count > self.first
    }

    #[inline(always)]
    fn add_group<L: LaneArray>(&mut self, i: usize, terms: L) {
        let values = terms.to_lane_array();
        for lane in 0..L::WIDTH {
            self.add_single(i + lane, L::lane_value(&values, lane));
        }
    }

    #[inline(always)]
    fn add_single(&mut self, i: usize, term: Real) {
        // Below `first` the index wraps past any slice length.
        let slot = (self.pass_first + i).wrapping_sub(self.first);
        if let Some(energy) = self.energies.get_mut(slot) {
            *energy = term;
        }
    }
}

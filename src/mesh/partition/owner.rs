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
//! The partition keeps, for each of its first vertex pieces, the longest run of consecutive
//! elements in that range that all touch the piece (for a mesh numbered with locality, all of
//! them): the pass runs it without the per-group test, in a separate pass over the run (its
//! ends aligned to 16 elements from the range's start, so that no partial group falls before
//! its end), the elements before and after it with the test. A caller may also run several
//! consecutive pieces as one owner (a *span*, as `softfem::parallel` does on small pools): the
//! elements cut only between pieces of the span are then evaluated once.
//!
//! The fused pass also writes each element's energy, once: vertex piece `k` writes those of
//! [`energy_piece(k)`](TetPartition::energy_piece) (consecutive elements, evaluated by that piece
//! whether or not they touch its vertices), and one sequential call then sums them in the
//! sequential pass's order ([`fused_total_energy`](TetPartition::fused_total_energy)).

use core::ops::Range;

use super::super::super::lanes::{LANES, LaneArray};
use super::super::super::material::Material;
use super::super::super::math::BATCH_FORCES;
use super::super::super::types::{Real, Vec3};
#[cfg(doc)]
use super::super::TetMesh;
use super::super::check_length;
use super::super::grouped::{
    DirectForces, EnergyAndForces, EnergySink, ForceSink, Pass, PassJob, SvdForces, SvdStress,
};
use super::super::rest_blocks::{Rests, TetRestBlock};
use super::{CACHED_PIECES, ElementForces, TetPartition};
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
        self.add_forces_span(material, positions, one_piece(piece), out)
    }

    /// [`add_forces_owned`](Self::add_forces_owned) for the consecutive vertex pieces `pieces`
    /// as one owner (`out` their slices, end to end): the elements cut only between two of them
    /// are evaluated once.
    pub(crate) fn add_forces_span<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        pieces: Range<usize>,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        let vertices = self.owner_vertices(positions, pieces.clone(), out.len())?;
        let Some(elements) = self.span_elements(pieces) else {
            return Ok(()); // No element touches these vertices.
        };
        let job = DirectForces(OwnerSlice::new(out, vertices.start));
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
        self.energy_and_add_forces_span(material, positions, one_piece(piece), out, energies)
    }

    /// [`energy_and_add_forces_owned`](Self::energy_and_add_forces_owned) for the consecutive
    /// vertex pieces `pieces` as one owner: `out` and `energies` are their slices end to end.
    pub(crate) fn energy_and_add_forces_span<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        pieces: Range<usize>,
        out: &mut [Vec3],
        energies: &mut [Real],
    ) -> Result<(), MeshError> {
        let vertices = self.owner_vertices(positions, pieces.clone(), out.len())?;
        let energy_elements = chunk_span(&pieces, self.energy_chunk(), self.mesh.element_count());
        check_length(Buffer::Energies, energy_elements.len(), energies.len())?;
        let elements = match self.span_elements(pieces) {
            Some(incident) if !energy_elements.is_empty() => OwnerElements {
                all: incident.all.start.min(energy_elements.start)
                    ..incident.all.end.max(energy_elements.end),
                dense: incident.dense,
            },
            Some(incident) => incident,
            None => OwnerElements {
                all: energy_elements.clone(),
                dense: 0..0,
            },
        };
        let job = EnergyAndForces {
            forces: OwnerSlice::new(out, vertices.start),
            energy: EnergySlots {
                energies,
                first: energy_elements.start,
                end: energy_elements.end,
                pass_first: elements.all.start,
            },
        };
        self.owner_pass(material, positions, elements, job, BATCH_FORCES);
        Ok(())
    }

    /// The whole fused pass on this thread, piece by piece in the owner-computes form
    /// ([`energy_and_add_forces_owned`](Self::energy_and_add_forces_owned)): the work, cut
    /// elements included, that the pieces of the scheme `softfem::parallel` runs on a pool of as
    /// many threads do. Returns the energy (J) and adds the
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

    /// The vertices of the owner span `pieces`, after checking the piece indices, the output
    /// length `out_len` and the positions' length.
    pub(super) fn owner_vertices(
        &self,
        positions: &[Vec3],
        pieces: Range<usize>,
        out_len: usize,
    ) -> Result<Range<usize>, MeshError> {
        check_length(Buffer::Positions, self.mesh.vertex_count(), positions.len())?;
        let vertices = self.span_vertices(pieces)?;
        check_length(Buffer::Forces, vertices.len(), out_len)?;
        Ok(vertices)
    }

    /// The vertices of the consecutive vertex pieces `pieces` (not empty, all below
    /// [`vertex_piece_count`](Self::vertex_piece_count)), else [`MeshError::PieceIndex`] naming
    /// the first piece past the last one (or `pieces.start` for an empty span).
    pub(super) fn span_vertices(&self, pieces: Range<usize>) -> Result<Range<usize>, MeshError> {
        let count = self.vertex_piece_count();
        if pieces.is_empty() || pieces.start >= count {
            return Err(MeshError::PieceIndex {
                piece: pieces.start,
                pieces: count,
            });
        }
        if pieces.end > count {
            return Err(MeshError::PieceIndex {
                piece: count,
                pieces: count,
            });
        }
        Ok(chunk_span(
            &pieces,
            self.vertex_chunk,
            self.mesh.vertex_count(),
        ))
    }

    /// The elements from the first to the last one incident to any vertex of the vertex pieces
    /// `pieces`, or `None` if none is, with a run of them that all touch those vertices: the
    /// kept runs of the pieces, joined where they overlap or meet (else the longest), or none
    /// past the kept pieces.
    pub(super) fn span_elements(&self, pieces: Range<usize>) -> Option<OwnerElements> {
        if pieces.end <= CACHED_PIECES {
            pieces
                .filter_map(|piece| self.incident_elements(piece))
                .reduce(|a, b| OwnerElements {
                    all: a.all.start.min(b.all.start)..a.all.end.max(b.all.end),
                    dense: if !a.dense.is_empty()
                        && !b.dense.is_empty()
                        && b.dense.start <= a.dense.end
                        && a.dense.start <= b.dense.end
                    {
                        a.dense.start.min(b.dense.start)..a.dense.end.max(b.dense.end)
                    } else if b.dense.len() > a.dense.len() {
                        b.dense
                    } else {
                        a.dense
                    },
                })
        } else {
            let vertices = chunk_span(&pieces, self.vertex_chunk, self.mesh.vertex_count());
            let all = self.scan_incident_elements(vertices)?;
            Some(OwnerElements { all, dense: 0..0 })
        }
    }

    /// The longest run of consecutive elements of `elements` that all have a corner among
    /// `vertices` (the first of equally long ones; empty if none has).
    pub(super) fn touching_run(
        &self,
        vertices: Range<usize>,
        elements: Range<usize>,
    ) -> Range<usize> {
        let tets = self.mesh.tets().get(elements.clone()).unwrap_or(&[]);
        let touches =
            |corners: &[u32; 4]| corners.iter().any(|&v| vertices.contains(&(v as usize)));
        let (mut best, mut start) = (0..0, 0);
        for (i, corners) in tets
            .iter()
            .enumerate()
            .chain([(tets.len(), &[u32::MAX; 4])])
        {
            let inside = i < tets.len() && touches(corners);
            if !inside {
                if i - start > best.len() {
                    best = start..i;
                }
                start = i + 1;
            }
        }
        elements.start + best.start..elements.start + best.end
    }

    /// Runs `job` over `elements` at the width the sequential kernels run at where `batch`,
    /// else one element at a time: in order, the elements before the dense run, the dense run
    /// (no test of whether a group touches the owner) and the elements after it.
    #[inline(always)]
    pub(super) fn owner_pass<M: Material, J: OwnerJob>(
        &self,
        material: &M,
        positions: &[Vec3],
        elements: OwnerElements,
        mut job: J,
        batch: bool,
    ) {
        let blocks = self.mesh.rest_blocks();
        for (part, dense) in elements.parts() {
            // With rest blocks, a part that starts inside a block runs its head by itself, so
            // that the wide groups of the rest start at a block's first lane: the same elements
            // in the same order, so the same bits.
            let aligned = if blocks.is_empty() {
                part.start
            } else {
                part.start
                    .next_multiple_of(TetRestBlock::LANES)
                    .min(part.end)
            };
            for range in [part.start..aligned, aligned..part.end] {
                if range.is_empty() {
                    continue;
                }
                job.part(range.start, dense);
                let pass = Pass {
                    material,
                    positions,
                    tets: self.mesh.tets().get(range.clone()).unwrap_or(&[]),
                    rests: Rests::new(
                        self.mesh.rest().get(range.clone()).unwrap_or(&[]),
                        blocks,
                        range.start,
                    ),
                    job,
                };
                job = if batch { dispatch(pass) } else { pass.scalar() };
            }
        }
    }

    /// The elements from the first to the last one incident to any vertex of vertex piece
    /// `piece`, or `None` if none is: kept by the partition for the first pieces, else found
    /// from the adjacency.
    pub(super) fn incident_elements(&self, piece: usize) -> Option<OwnerElements> {
        match self.piece_elements.get(piece) {
            Some(&[start, end, dense_start, dense_end]) => (start < end).then_some(OwnerElements {
                all: start as usize..end as usize,
                dense: dense_start as usize..dense_end as usize,
            }),
            None => Some(OwnerElements {
                all: self.scan_incident_elements(self.vertex_piece(piece))?,
                dense: 0..0,
            }),
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

/// The elements an owner evaluates (`all`, from the first to the last one incident to its
/// vertices), and a run of them that all touch its vertices (`dense`, within `all`, maybe
/// empty).
#[derive(Clone, Debug)]
pub(super) struct OwnerElements {
    pub all: Range<usize>,
    pub dense: Range<usize>,
}

/// The alignment of the dense run's ends from the start of `all`: a multiple of the widest
/// group (16 f32 lanes), so that splitting the pass there leaves no partial group before the
/// run's end.
const DENSE_ALIGN: usize = 16;

impl OwnerElements {
    /// `all` in three consecutive parts, in order, with whether every element of the part
    /// touches the owner: before the dense run, the dense run shrunk to [`DENSE_ALIGN`] from
    /// the start of `all`, and after it.
    pub fn parts(&self) -> [(Range<usize>, bool); 3] {
        let (start, end) = (self.all.start, self.all.end.max(self.all.start));
        let dense_start = self.dense.start.clamp(start, end);
        let dense_end = self.dense.end.clamp(dense_start, end);
        let from = start + (dense_start - start).next_multiple_of(DENSE_ALIGN);
        if from >= dense_end {
            return [(start..end, false), (end..end, true), (end..end, false)];
        }
        let to = from + (dense_end - from) / DENSE_ALIGN * DENSE_ALIGN;
        [(start..from, false), (from..to, true), (to..end, false)]
    }
}

/// A [`PassJob`] of an owner: told before each part of [`OwnerElements::parts`] where the part
/// starts and whether all its elements touch the owner.
pub(super) trait OwnerJob: PassJob {
    /// The next pass starts at element `first`; `dense`: every element touches the owner.
    fn part(&mut self, first: usize, dense: bool);
}

impl OwnerJob for DirectForces<OwnerSlice<'_>> {
    #[inline(always)]
    fn part(&mut self, _first: usize, dense: bool) {
        self.0.dense = dense;
    }
}

impl OwnerJob for EnergyAndForces<OwnerSlice<'_>, EnergySlots<'_>> {
    #[inline(always)]
    fn part(&mut self, first: usize, dense: bool) {
        self.forces.dense = dense;
        self.energy.pass_first = first;
    }
}

impl<S: SvdStress> OwnerJob for SvdForces<OwnerSlice<'_>, S> {
    #[inline(always)]
    fn part(&mut self, _first: usize, dense: bool) {
        self.forces.dense = dense;
    }
}

/// A vertex piece's slice of the forces, indexed by global vertex.
pub(super) struct OwnerSlice<'o> {
    pub out: &'o mut [Vec3],
    pub first: usize,
    /// Every element of the current part touches the slice (no test needed).
    pub dense: bool,
}

impl<'o> OwnerSlice<'o> {
    /// `out`, the forces of the vertices from `first`.
    #[inline(always)]
    pub fn new(out: &'o mut [Vec3], first: usize) -> Self {
        OwnerSlice {
            out,
            first,
            dense: false,
        }
    }

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
        !self.dense && !tets.iter().any(|corners| self.touches(corners))
    }

    #[inline(always)]
    fn slots(&mut self) -> (&mut [Vec3], usize) {
        (self.out, self.first)
    }
}

/// The energies of one energy piece of the owner-computes fused pass, written element by
/// element.
pub(super) struct EnergySlots<'o> {
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

    /// A group wholly in the piece is stored four lanes at a time; one that straddles its
    /// ends lane by lane (each lane's slot is the same either way).
    #[inline(always)]
    fn add_group<L: LaneArray>(&mut self, i: usize, terms: L) {
        let values = terms.to_lane_array();
        // Below `first` the index wraps past any slice length.
        let start = (self.pass_first + i).wrapping_sub(self.first);
        let slots = self.energies.get_mut(start..).unwrap_or(&mut []);
        if slots.len() >= L::WIDTH {
            let quarters = slots.chunks_exact_mut(LANES).take(L::WIDTH / LANES);
            for (q, quarter) in quarters.enumerate() {
                quarter.copy_from_slice(&L::quarter(&values, q).to_array());
            }
        } else {
            for lane in 0..L::WIDTH {
                self.add_single(i + lane, L::lane_value(&values, lane));
            }
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

/// The span of the one vertex piece `piece` (empty, and so refused, for `usize::MAX`).
#[inline]
pub(super) fn one_piece(piece: usize) -> Range<usize> {
    piece..piece.saturating_add(1)
}

/// The union of chunks `pieces` of length `chunk` of `0..len` (empty past the end).
#[inline]
pub(super) fn chunk_span(pieces: &Range<usize>, chunk: usize, len: usize) -> Range<usize> {
    let start = pieces.start.saturating_mul(chunk).min(len);
    start..pieces.end.saturating_mul(chunk).clamp(start, len)
}

//! The partitioned passes of [`TetPartition`] on [rayon](https://docs.rs/rayon)'s thread pool
//! (feature `rayon`): the elastic forces (direct, principal and clamped paths), the energy, the
//! fused energy-and-force pass, the projected Hessians, their products and diagonal blocks, and,
//! through [`ParallelTetElastic`] and [`ParallelTetClamped`], the steppers (explicit,
//! relaxation, Newton, Vertex Block Descent), **bit for bit** the results of the sequential
//! code for any number of threads and any schedule (see [`TetPartition`] for why).
//!
//! The steppers' own passes over the vertices (the explicit update, the relaxation's gradient,
//! direction and trial points, with their sums) run on the pool too, in blocks of
//! [`VERTEX_BLOCK`](super::step::vertex_pass::VERTEX_BLOCK) vertices ([`RayonJoin`]) whose sums are combined
//! over a fixed tree, so their bits do not depend on the thread count either. Newton's
//! conjugate gradients run their vector passes the same way, and with the multilevel
//! preconditioner (feature `alloc`) each V-cycle runs on the pool as one pass: its
//! Gauss-Seidel sweeps one colour of nodes at a time, its residuals and transfers, in fixed
//! blocks of rows (`step::Multilevel`). VBD's sweeps run the vertex
//! updates of each colour in parallel ([`ParallelTetElastic`]'s [`VertexBlockModel`]).
//!
//! The owner-computes passes (forces, fused pass, Hessian products and blocks) run one task per
//! *span* of consecutive vertex pieces, evaluated as one owner: on a pool of one thread a single
//! span of every piece (nothing is cut: the sequential kernel's work), else spans of as few
//! pieces as keep the tasks to at most four per thread (so a partition made for many threads
//! does not evaluate its cut elements again and again on a small pool, and stealing still has
//! tasks to move). Spans change the work, never the bits.
//!
//! The functions run on the pool they are called from: the global pool, or a pool of your own
//! through [`rayon::ThreadPool::install`], which picks the thread count. [`ParallelTetElastic`]
//! takes an optional pool and installs it around every force evaluation and every pass over the
//! vertices. Called from outside the pool, each install hands the pass to the pool and wakes
//! the caller when it is done; a whole step run inside `pool.install(|| step(...))` starts every
//! pass on the pool's own threads instead (see the `parallel` bench for what that saves).
//!
//! ```
//! use softfem::element::TetRest;
//! use softfem::generate::{BoxSplit, box_counts, fill_box};
//! use softfem::glam::Vec3;
//! use softfem::material::StVK;
//! use softfem::mesh::{TetMesh, TetPartition, element_forces_len};
//! use softfem::mesh::{partition_incident_len, partition_offsets_len};
//!
//! let (vertices, tets) = box_counts(4, 4, 4, BoxSplit::Kuhn6)?;
//! let (mut rest, mut elements) = (vec![Vec3::ZERO; vertices], vec![[0; 4]; tets]);
//! fill_box(Vec3::ZERO, Vec3::ONE, 4, 4, 4, BoxSplit::Kuhn6, &mut rest, &mut elements)?;
//! let mut rest_data = vec![TetRest::default(); tets];
//! let mesh = TetMesh::new(&rest, &elements, &mut rest_data)?;
//! let (mut offsets, mut incident) =
//!     (vec![0; partition_offsets_len(vertices)], vec![0; partition_incident_len(tets)]);
//! let partition = TetPartition::new(mesh, 8, &mut offsets, &mut incident)?;
//! let material = StVK::from_young_poisson(1.0e6, 0.3)?;
//! let x: Vec<Vec3> = rest.iter().map(|p| *p * 1.1).collect();
//!
//! let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build()?;
//! let mut element_forces = vec![[Vec3::ZERO; 4]; element_forces_len(tets)];
//! let mut forces = vec![Vec3::ZERO; vertices];
//! pool.install(|| {
//!     softfem::parallel::add_elastic_forces(&partition, &material, &x, &mut forces,
//!         &mut element_forces)
//! })?;
//! let mut sequential = vec![Vec3::ZERO; vertices];
//! mesh.add_elastic_forces(&material, &x, &mut sequential)?;
//! assert_eq!(forces, sequential); // and bit for bit
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use core::ops::Range;
use std::sync::{Mutex, PoisonError};

use rayon::ThreadPool;
use rayon::prelude::*;

use super::element::{TetHessian, TetRest};
use super::material::Material;
use super::mesh::{ElementForces, TetMesh, TetPartition, element_forces_len};
use super::step::vertex_pass::{Join, VertexPass};
use super::step::{ElasticEnergy, ElasticHessian, ElasticModel, TetClamped, TetElastic};
use super::step::{SweepMesh, SweepRun, SweepSchedule, VertexBlockModel};
use super::types::{Mat3, Real, Vec3};
use crate::error::MeshError;

/// [`TetMesh::add_elastic_forces`] on the current rayon pool, through `partition`: adds the
/// elastic forces (N) of `material` at `positions` (m) into `forces`, with the sequential bits,
/// in the owner-computes form ([`TetPartition::add_forces_owned`]: one task per span of
/// consecutive vertex pieces, no gather; partition with about one piece per thread, see
/// [module documentation](self) for the spans). `element_forces`
/// ([`element_forces_len`] entries) is checked as by the other
/// force passes but not used. On a pool of two or more threads and from 32 768 vertices, the
/// tests of the positions (finite, within the material's deformation bound) run in a chunk per
/// thread too; where they do not pass at once, the sequential check decides.
///
/// # Errors
/// As [`TetPartition::check_forces`]; on error, `forces` is unchanged.
pub fn add_elastic_forces<M: Material + Sync>(
    partition: &TetPartition<'_>,
    material: &M,
    positions: &[Vec3],
    forces: &mut [Vec3],
    element_forces: &mut [ElementForces],
) -> Result<(), MeshError> {
    let (vertices, elements) = (
        partition.mesh().vertex_count(),
        partition.mesh().element_count(),
    );
    let lengths = positions.len() == vertices
        && forces.len() == vertices
        && element_forces.len() == element_forces_len(elements);
    if !(lengths && positions_pass(&partition.mesh(), material, positions)) {
        partition.check_forces(material, positions, forces, element_forces)?;
    }
    // The owner-computes form: each vertex piece evaluates the elements at its vertices, the
    // elements cut by a piece boundary once per piece (no element buffer, no gather).
    vertex_pieces(partition, forces, |pieces, out| {
        partition.add_forces_span(material, positions, pieces, out)
    })
}

/// [`TetMesh::elastic_energy`] on the current rayon pool, through `partition`: the total elastic
/// energy (J), with the sequential bits. `energies` is scratch of one entry per element (it
/// receives every element's energy).
///
/// # Errors
/// As [`TetPartition::check_energy`].
pub fn elastic_energy<M: Material + Sync>(
    partition: &TetPartition<'_>,
    material: &M,
    positions: &[Vec3],
    energies: &mut [Real],
) -> Result<Real, MeshError> {
    partition.check_energy(material, positions, energies)?;
    energies
        .par_chunks_mut(partition.element_chunk())
        .enumerate()
        .try_for_each(|(piece, out)| partition.element_energies(material, positions, piece, out))?;
    partition.total_energy(energies)
}

/// The fused energy-and-force pass of the energy-based steppers
/// ([`ElasticEnergy::energy_and_add_forces`] of a [`TetElastic`]) on the current rayon pool:
/// returns the energy (J) and adds the forces (N) into `forces`, with the sequential bits.
/// Beyond the material's range the energy is infinite and `forces` is left alone, as there.
///
/// The owner-computes form ([`TetPartition::energy_and_add_forces_owned`]: one task per vertex
/// piece, no gather), each piece writing the energies of its
/// [`energy_piece`](TetPartition::energy_piece) into `energies` (one per element), which are
/// then summed on the calling thread in the sequential order. `element_forces` is checked as
/// by the other passes but not used. The positions are tested in a chunk per thread as by
/// [`add_elastic_forces`].
///
/// # Errors
/// As [`TetPartition::check_fused`].
pub fn energy_and_add_forces<M: Material + Sync>(
    partition: &TetPartition<'_>,
    material: &M,
    positions: &[Vec3],
    forces: &mut [Vec3],
    element_forces: &mut [ElementForces],
    energies: &mut [Real],
) -> Result<Real, MeshError> {
    let (vertices, elements) = (
        partition.mesh().vertex_count(),
        partition.mesh().element_count(),
    );
    let lengths = positions.len() == vertices
        && forces.len() == vertices
        && element_forces.len() == element_forces_len(elements)
        && energies.len() == elements;
    // The sequential check only where the parallel one does not pass at once.
    let within = (lengths && positions_pass(&partition.mesh(), material, positions))
        || partition.check_fused(material, positions, forces, element_forces, energies)?;
    if !within {
        return Ok(Real::INFINITY);
    }
    let span = span_len(partition);
    let vertex_chunk = partition.vertex_chunk().saturating_mul(span);
    let energy_chunk = partition.energy_chunk().saturating_mul(span);
    // The last spans may have no energies: an empty slice each.
    let spans = partition.vertex_piece_count().div_ceil(span);
    let without = spans.saturating_sub(energies.len().div_ceil(energy_chunk));
    let energy_slices = energies.par_chunks_mut(energy_chunk).chain(
        (0..without)
            .into_par_iter()
            .map(|_| <&mut [Real]>::default()),
    );
    let pieces = partition.vertex_piece_count();
    forces
        .par_chunks_mut(vertex_chunk)
        .zip(energy_slices)
        .enumerate()
        .try_for_each(|(k, (out, energies))| {
            let pieces = span_pieces(k, span, pieces);
            partition.energy_and_add_forces_span(material, positions, pieces, out, energies)
        })?;
    partition.fused_total_energy(energies)
}

/// [`TetMesh::add_elastic_forces_principal`] on the current rayon pool, through `partition`:
/// adds the principal-path (SVD) forces (N) of `material` at `positions` (m) into `forces`,
/// with the sequential bits, in the owner-computes form
/// ([`TetPartition::add_forces_principal_owned`]: one task per span of vertex pieces, no
/// gather).
/// `element_forces` ([`element_forces_len`] entries) is
/// checked but not used.
///
/// # Errors
/// As [`TetPartition::check_principal`]; on error, `forces` is unchanged.
pub fn add_elastic_forces_principal<M: Material + Sync>(
    partition: &TetPartition<'_>,
    material: &M,
    positions: &[Vec3],
    forces: &mut [Vec3],
    element_forces: &mut [ElementForces],
) -> Result<(), MeshError> {
    partition.check_principal(material, positions, forces, element_forces)?;
    vertex_pieces(partition, forces, |pieces, out| {
        partition.add_forces_principal_span(material, positions, pieces, out)
    })
}

/// [`TetMesh::add_elastic_forces_clamped`] on the current rayon pool, through `partition`:
/// adds the clamped principal forces (N; **not an energy gradient, explicit stepping only**) of
/// `material` at `positions` (m), stretches clamped from below at `threshold`, into `forces`,
/// with the sequential bits, in the owner-computes form
/// ([`TetPartition::add_forces_clamped_owned`]). `element_forces`
/// ([`element_forces_len`] entries) is checked but not used.
///
/// # Errors
/// As [`TetPartition::check_clamped`]; on error, `forces` is unchanged.
pub fn add_elastic_forces_clamped<M: Material + Sync>(
    partition: &TetPartition<'_>,
    material: &M,
    threshold: Real,
    positions: &[Vec3],
    forces: &mut [Vec3],
    element_forces: &mut [ElementForces],
) -> Result<(), MeshError> {
    partition.check_clamped(material, threshold, positions, forces, element_forces)?;
    vertex_pieces(partition, forces, |pieces, out| {
        partition.add_forces_clamped_span(material, threshold, positions, pieces, out)
    })
}

/// [`TetMesh::projected_hessians`] on the current rayon pool, through `partition`: writes the
/// projected Hessian data of every element of `material` at `positions` (m) into `cache`, with
/// the sequential bits.
///
/// # Errors
/// As [`TetPartition::check_hessians`]; on error, `cache` is unchanged.
pub fn projected_hessians<M: Material + Sync>(
    partition: &TetPartition<'_>,
    material: &M,
    positions: &[Vec3],
    cache: &mut [TetHessian],
) -> Result<(), MeshError> {
    partition.check_hessians(positions, cache)?;
    cache
        .par_chunks_mut(partition.element_chunk())
        .enumerate()
        .try_for_each(|(piece, out)| partition.element_hessians(material, positions, piece, out))
}

/// [`TetMesh::add_hessian_product`] on the current rayon pool, through `partition`: adds `H d`
/// (N) for the Hessian in `cache` and the per-vertex `direction` (m) into `out`, with the
/// sequential bits, in the owner-computes form ([`TetPartition::add_hessian_product_owned`]).
/// `element_products` ([`element_forces_len`] entries) is
/// checked but not used.
///
/// # Errors
/// As [`TetPartition::check_hessian_product`]; on error, `out` is unchanged.
pub fn add_hessian_product(
    partition: &TetPartition<'_>,
    cache: &[TetHessian],
    direction: &[Vec3],
    out: &mut [Vec3],
    element_products: &mut [ElementForces],
) -> Result<(), MeshError> {
    partition.check_hessian_product(cache, direction, out, element_products)?;
    vertex_pieces(partition, out, |pieces, out| {
        partition.add_hessian_product_span(cache, direction, pieces, out)
    })
}

/// [`TetMesh::add_vertex_hessian_blocks`] on the current rayon pool, through `partition`: adds
/// the 3x3 diagonal blocks (N/m) of the Hessian in `cache` into `blocks`, one per vertex, with
/// the sequential bits (vertex pieces only: no scratch).
///
/// # Errors
/// As [`TetPartition::check_vertex_blocks`]; on error, `blocks` is unchanged.
pub fn add_vertex_hessian_blocks(
    partition: &TetPartition<'_>,
    cache: &[TetHessian],
    blocks: &mut [Mat3],
) -> Result<(), MeshError> {
    partition.check_vertex_blocks(cache, blocks)?;
    vertex_pieces(partition, blocks, |pieces, out| {
        partition.gather_vertex_blocks_span(cache, pieces, out)
    })
}

/// The fewest vertices per task of [`positions_pass`]: below twice this many the checks stay on
/// the calling thread.
const CHECK_CHUNK: usize = 1 << 14;

/// Whether `positions` pass the tests the checks of the force passes make on them
/// ([`TetPartition::check_forces`], [`TetPartition::check_fused`]): all finite and, for a
/// material with a [`deformation_limit`](Material::deformation_limit), within it by the
/// bounding-box test of the mesh's deformation check; computed in one pass over the positions,
/// in a chunk per thread of the current pool. `true` only where the sequential tests pass (the
/// finiteness test is theirs, summed by chunk; minimum and maximum are exact in any order, up
/// to the sign of a zero, which leaves the box's extent as it is). `false` (also on a pool of
/// one thread, or for fewer than `2 CHECK_CHUNK` vertices) decides nothing: the caller runs
/// the sequential check, which finds the error, or passes by its element-by-element test.
/// At 998k tets the sequential check is about 2 % of a one-thread StVK force pass.
fn positions_pass<M: Material>(mesh: &TetMesh<'_>, material: &M, positions: &[Vec3]) -> bool {
    let threads = rayon::current_num_threads();
    if threads <= 1 || positions.len() < 2 * CHECK_CHUNK {
        return false;
    }
    let chunk = positions.len().div_ceil(threads).max(CHECK_CHUNK);
    let bounds = positions
        .par_chunks(chunk)
        .map(|part| {
            let first = part.first().copied().unwrap_or(Vec3::ZERO);
            // `p * 0` is zero for a finite coordinate, NaN for NaN or an infinity.
            part.iter()
                .fold((Vec3::ZERO, first, first), |(zero, low, high), &p| {
                    (zero + p * 0.0, low.min(p), high.max(p))
                })
        })
        .reduce_with(|(zero_a, low_a, high_a), (zero_b, low_b, high_b)| {
            (zero_a + zero_b, low_a.min(low_b), high_a.max(high_b))
        });
    let Some((zero, low, high)) = bounds else {
        return false;
    };
    if !zero.is_finite() {
        return false;
    }
    mesh.extent_within(material.deformation_limit(), low, high)
}

/// `span(pieces, slice)` for every span of [`span_len`] consecutive vertex pieces of
/// `partition` and its slice of the per-vertex `buffer`, on the current pool.
fn vertex_pieces<T: Send>(
    partition: &TetPartition<'_>,
    buffer: &mut [T],
    span: impl Fn(Range<usize>, &mut [T]) -> Result<(), MeshError> + Sync,
) -> Result<(), MeshError> {
    let (len, pieces) = (span_len(partition), partition.vertex_piece_count());
    buffer
        .par_chunks_mut(partition.vertex_chunk().saturating_mul(len))
        .enumerate()
        .try_for_each(|(k, out)| span(span_pieces(k, len, pieces), out))
}

/// The most owner tasks per thread of the current pool: enough for work stealing to even out
/// threads that fall behind (the `parallel` example's four pieces per thread), few enough that
/// a partition made for many threads does not evaluate its cut elements again and again on a
/// smaller pool.
const SPANS_PER_THREAD: usize = 4;

/// The vertex pieces that one owner task of the current pool takes, end to end: all of them on
/// a pool of one thread (nothing is cut then: the sequential kernel's work), else as many as
/// keep the tasks to at most [`SPANS_PER_THREAD`] per thread. Consecutive pieces run as one
/// owner give the bits of each run alone, so this changes the work, never the result.
fn span_len(partition: &TetPartition<'_>) -> usize {
    let pieces = partition.vertex_piece_count().max(1);
    let threads = rayon::current_num_threads();
    let spans = if threads <= 1 {
        1
    } else {
        pieces.min(threads.saturating_mul(SPANS_PER_THREAD))
    };
    pieces.div_ceil(spans.max(1))
}

/// The vertex pieces of span `k` of `len` pieces each, of `pieces` in all.
fn span_pieces(k: usize, len: usize, pieces: usize) -> Range<usize> {
    let start = k.saturating_mul(len);
    start..start.saturating_add(len).min(pieces)
}

/// A [`TetElastic`] body whose force (and fused energy-and-force) passes run in parallel through
/// a [`TetPartition`], with the bits of the sequential body: hand it to
/// [`explicit_step`](super::step::explicit_step), [`relax_step`](super::step::relax_step),
/// [`newton_step`](super::step::newton_step), [`vbd_step`](super::step::vbd_step) (any stepper
/// taking an [`ElasticModel`], [`ElasticEnergy`], [`ElasticHessian`] or [`VertexBlockModel`])
/// for a parallel step whose result does not depend on
/// the thread count. The steppers' passes over the vertices run on the pool too
/// ([`ElasticModel::run_vertex_pass`]).
///
/// The scratch buffers sit behind a mutex (force evaluations of one body do not overlap); the
/// optional pool is installed around every evaluation and every pass over the vertices (else
/// the caller's current pool runs them).
///
/// ```
/// use softfem::element::TetRest;
/// use softfem::generate::{BoxSplit, box_counts, fill_box};
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::{TetMesh, TetPartition, element_forces_len};
/// use softfem::mesh::{partition_incident_len, partition_offsets_len};
/// use softfem::parallel::ParallelTetElastic;
/// use softfem::step::{ExplicitScratch, ExplicitSettings, Scene, TetElastic, scratch_len};
/// use softfem::step::explicit_step;
///
/// let (vertices, tets) = box_counts(3, 3, 3, BoxSplit::Kuhn6)?;
/// let (mut rest, mut elements) = (vec![Vec3::ZERO; vertices], vec![[0; 4]; tets]);
/// fill_box(Vec3::ZERO, Vec3::ONE * 0.1, 3, 3, 3, BoxSplit::Kuhn6, &mut rest, &mut elements)?;
/// let mut rest_data = vec![TetRest::default(); tets];
/// let mesh = TetMesh::new(&rest, &elements, &mut rest_data)?;
/// let (mut offsets, mut incident) =
///     (vec![0; partition_offsets_len(vertices)], vec![0; partition_incident_len(tets)]);
/// let partition = TetPartition::new(mesh, 8, &mut offsets, &mut incident)?;
/// let (mut element_forces, mut energies) =
///     (vec![[Vec3::ZERO; 4]; element_forces_len(tets)], vec![0.0; tets]);
/// let material = StableNeoHookean::from_young_poisson(1.0e5, 0.3)?;
/// let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build()?;
/// let body = ParallelTetElastic::new(
///     TetElastic::new(mesh, material), partition, &mut element_forces, &mut energies,
/// )?.with_pool(&pool);
///
/// let mut masses = vec![0.0; vertices];
/// mesh.lumped_masses(1000.0, &mut masses)?;
/// let scene = Scene::new(1.0e-4).with_gravity(Vec3::new(0.0, -9.81, 0.0));
/// let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; vertices]);
/// let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(vertices)];
/// let mut scratch = ExplicitScratch::new(&mut buffer);
/// let settings = ExplicitSettings::new();
/// explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch)?;
/// assert!(v.iter().all(|v| v.y < 0.0)); // falling
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct ParallelTetElastic<'a, M: Material> {
    body: TetElastic<'a, M>,
    partition: TetPartition<'a>,
    scratch: Mutex<(&'a mut [ElementForces], &'a mut [Real])>,
    pool: Option<&'a ThreadPool>,
}

impl<'a, M: Material + Sync> ParallelTetElastic<'a, M> {
    /// `body` evaluated through `partition` (of the same mesh), with scratch `element_forces`
    /// ([`element_forces_len`] entries) and `energies` (one
    /// per element), on the caller's current pool.
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] for a scratch buffer of the wrong length or a partition of
    /// another size of mesh ([`Buffer::RestData`](crate::Buffer::RestData)).
    pub fn new(
        body: TetElastic<'a, M>,
        partition: TetPartition<'a>,
        element_forces: &'a mut [ElementForces],
        energies: &'a mut [Real],
    ) -> Result<Self, MeshError> {
        let mesh = body.mesh;
        check_same_mesh(&mesh, &partition.mesh())?;
        let length = |buffer, actual| element_length(&mesh, buffer, actual);
        length(crate::Buffer::ElementForces, element_forces.len())?;
        length(crate::Buffer::Energies, energies.len())?;
        Ok(ParallelTetElastic {
            body,
            partition,
            scratch: Mutex::new((element_forces, energies)),
            pool: None,
        })
    }

    /// This body with its evaluations run on `pool` (its thread count).
    #[must_use]
    pub fn with_pool(self, pool: &'a ThreadPool) -> Self {
        ParallelTetElastic {
            pool: Some(pool),
            ..self
        }
    }

    /// The sequential body.
    #[must_use]
    pub fn body(&self) -> &TetElastic<'a, M> {
        &self.body
    }

    /// `run` with the scratch buffers, on the pool if one was given.
    fn run<T: Send>(&self, run: impl FnOnce(&mut [ElementForces], &mut [Real]) -> T + Send) -> T {
        let mut scratch = self.scratch.lock().unwrap_or_else(PoisonError::into_inner);
        let (element_forces, energies) = &mut *scratch;
        on_pool(self.pool, || run(element_forces, energies))
    }
}

/// [`Join`] by `rayon::join`, on the current pool: the steppers' passes over the vertices split
/// into blocks on the pool's threads.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayonJoin;

impl Join for RayonJoin {
    #[inline]
    fn join<A, B, RA, RB>(&self, a: A, b: B) -> (RA, RB)
    where
        A: FnOnce() -> RA + Send,
        B: FnOnce() -> RB + Send,
        RA: Send,
        RB: Send,
    {
        rayon::join(a, b)
    }
}

/// `run` on `pool` if there is one, else on the current pool.
pub(crate) fn on_pool<T: Send>(pool: Option<&ThreadPool>, run: impl FnOnce() -> T + Send) -> T {
    match pool {
        Some(pool) => pool.install(run),
        None => run(),
    }
}

/// `Ok` if `partition_mesh` is `mesh` (the same rest buffer and counts), else
/// [`MeshError::LengthMismatch`] naming [`Buffer::RestData`](crate::Buffer::RestData).
fn check_same_mesh(mesh: &TetMesh<'_>, partition_mesh: &TetMesh<'_>) -> Result<(), MeshError> {
    let same = mesh.element_count() == partition_mesh.element_count()
        && mesh.vertex_count() == partition_mesh.vertex_count()
        && same_rest(mesh.rest(), partition_mesh.rest());
    if same {
        Ok(())
    } else {
        Err(MeshError::LengthMismatch {
            buffer: crate::Buffer::RestData,
            expected: mesh.element_count(),
            actual: partition_mesh.element_count(),
        })
    }
}

/// `Ok` if a per-element scratch buffer (`buffer`) has one entry per element of `mesh`.
fn element_length(
    mesh: &TetMesh<'_>,
    buffer: crate::Buffer,
    actual: usize,
) -> Result<(), MeshError> {
    if actual == mesh.element_count() {
        Ok(())
    } else {
        Err(MeshError::LengthMismatch {
            buffer,
            expected: mesh.element_count(),
            actual,
        })
    }
}

/// Whether two rest buffers are the same memory (the same mesh).
fn same_rest(a: &[TetRest], b: &[TetRest]) -> bool {
    core::ptr::eq(a, b)
}

impl<M: Material + Sync> ElasticModel for ParallelTetElastic<'_, M> {
    type Vector = Vec3;
    #[inline]
    fn vertex_count(&self) -> usize {
        self.body.mesh.vertex_count()
    }
    fn add_forces(&self, positions: &[Vec3], forces: &mut [Vec3]) -> Result<(), MeshError> {
        let (partition, material) = (&self.partition, &self.body.material);
        self.run(|element_forces, _| {
            add_elastic_forces(partition, material, positions, forces, element_forces)
        })
    }
    fn for_each_element_stiffness(&self, visit: impl FnMut(&[u32], Real, Real)) {
        self.body.for_each_element_stiffness(visit);
    }
    fn run_vertex_pass<P: VertexPass>(&self, pass: P) -> P::Output {
        on_pool(self.pool, || pass.run_with(&RayonJoin))
    }
}

impl<M: Material + Sync> ElasticEnergy for ParallelTetElastic<'_, M> {
    fn energy_and_add_forces(
        &self,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, MeshError> {
        let (partition, material) = (&self.partition, &self.body.material);
        self.run(|element_forces, energies| {
            energy_and_add_forces(
                partition,
                material,
                positions,
                forces,
                element_forces,
                energies,
            )
        })
    }
}

impl<M: Material + Sync> ElasticHessian for ParallelTetElastic<'_, M> {
    #[inline]
    fn element_count(&self) -> usize {
        self.body.mesh.element_count()
    }
    fn projected_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        let (partition, material) = (&self.partition, &self.body.material);
        on_pool(self.pool, || {
            projected_hessians(partition, material, positions, cache)
        })
    }
    fn add_hessian_product(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        let partition = &self.partition;
        self.run(|element_products, _| {
            add_hessian_product(partition, cache, direction, out, element_products)
        })
    }
    fn add_vertex_hessian_blocks(
        &self,
        cache: &[TetHessian],
        blocks: &mut [Mat3],
    ) -> Result<(), MeshError> {
        let partition = &self.partition;
        on_pool(self.pool, || {
            add_vertex_hessian_blocks(partition, cache, blocks)
        })
    }
    fn for_each_element_hessian(
        &self,
        cache: &[TetHessian],
        visit: impl FnMut([u32; 4], &TetHessian),
    ) -> bool {
        self.body.for_each_element_hessian(cache, visit)
    }
    /// The sequential body's exact Hessians (one element at a time, the same bits; Newton
    /// takes them only in its last few iterations).
    fn exact_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<bool, MeshError> {
        self.body.exact_hessians(positions, cache)
    }
}

/// Vertex Block Descent's sweeps ([`vbd_step`](super::step::vbd_step)) run the updates of each
/// colour in parallel, on the model's pool if one was given, else on the current pool: the
/// sequential bits, since two vertices of one colour share no element.
impl<'a, M: Material + Sync> SweepSchedule for ParallelTetElastic<'a, M> {
    type Material = M;

    #[inline]
    fn sweep_mesh(&self) -> SweepMesh<'_, M> {
        SweepMesh::of(&self.body)
    }

    fn run_sweep(&self, run: SweepRun<'_, '_, M>) {
        on_pool(self.pool, || run.on_pool());
    }
}

impl<M: Material + Sync> VertexBlockModel for ParallelTetElastic<'_, M> {}

/// A [`TetClamped`] body (clamped principal stress, **explicit stepping only**) whose force
/// passes run in parallel through a [`TetPartition`], with the bits of the sequential body:
/// hand it to [`explicit_step`](super::step::explicit_step). As [`ParallelTetElastic`], the
/// scratch sits behind a mutex and the optional pool is installed around every evaluation.
///
/// ```
/// use softfem::element::TetRest;
/// use softfem::generate::{BoxSplit, box_counts, fill_box};
/// use softfem::glam::Vec3;
/// use softfem::material::NeoHookean;
/// use softfem::mesh::{TetMesh, TetPartition, element_forces_len};
/// use softfem::mesh::{partition_incident_len, partition_offsets_len};
/// use softfem::parallel::ParallelTetClamped;
/// use softfem::step::{ElasticModel, TetClamped};
///
/// let (vertices, tets) = box_counts(3, 3, 3, BoxSplit::Kuhn6)?;
/// let (mut rest, mut elements) = (vec![Vec3::ZERO; vertices], vec![[0; 4]; tets]);
/// fill_box(Vec3::ZERO, Vec3::ONE * 0.1, 3, 3, 3, BoxSplit::Kuhn6, &mut rest, &mut elements)?;
/// let mut rest_data = vec![TetRest::default(); tets];
/// let mesh = TetMesh::new(&rest, &elements, &mut rest_data)?;
/// let (mut offsets, mut incident) =
///     (vec![0; partition_offsets_len(vertices)], vec![0; partition_incident_len(tets)]);
/// let partition = TetPartition::new(mesh, 8, &mut offsets, &mut incident)?;
/// let mut element_forces = vec![[Vec3::ZERO; 4]; element_forces_len(tets)];
/// let clamped = TetClamped::checked(mesh, NeoHookean::from_young_poisson(1.0e5, 0.3)?, 0.3)?;
/// let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build()?;
/// let body = ParallelTetClamped::new(clamped, partition, &mut element_forces)?.with_pool(&pool);
///
/// // Flattened below the clamp: the clamped stress still pushes the body back up.
/// let x: Vec<Vec3> = rest.iter().map(|p| *p * Vec3::new(1.0, 0.1, 1.0)).collect();
/// let (mut parallel, mut sequential) = (vec![Vec3::ZERO; vertices], vec![Vec3::ZERO; vertices]);
/// body.add_forces(&x, &mut parallel)?;
/// clamped.add_forces(&x, &mut sequential)?;
/// assert_eq!(parallel, sequential); // and bit for bit
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct ParallelTetClamped<'a, M: Material> {
    body: TetClamped<'a, M>,
    partition: TetPartition<'a>,
    element_forces: Mutex<&'a mut [ElementForces]>,
    pool: Option<&'a ThreadPool>,
}

impl<'a, M: Material + Sync> ParallelTetClamped<'a, M> {
    /// `body` evaluated through `partition` (of the same mesh), with scratch `element_forces`
    /// ([`element_forces_len`] entries), on the caller's
    /// current pool.
    ///
    /// # Errors
    /// As [`ParallelTetElastic::new`].
    pub fn new(
        body: TetClamped<'a, M>,
        partition: TetPartition<'a>,
        element_forces: &'a mut [ElementForces],
    ) -> Result<Self, MeshError> {
        check_same_mesh(&body.mesh, &partition.mesh())?;
        element_length(
            &body.mesh,
            crate::Buffer::ElementForces,
            element_forces.len(),
        )?;
        Ok(ParallelTetClamped {
            body,
            partition,
            element_forces: Mutex::new(element_forces),
            pool: None,
        })
    }

    /// This body with its evaluations run on `pool` (its thread count).
    #[must_use]
    pub fn with_pool(self, pool: &'a ThreadPool) -> Self {
        ParallelTetClamped {
            pool: Some(pool),
            ..self
        }
    }

    /// The sequential body.
    #[must_use]
    pub fn body(&self) -> &TetClamped<'a, M> {
        &self.body
    }
}

impl<M: Material + Sync> ElasticModel for ParallelTetClamped<'_, M> {
    type Vector = Vec3;
    #[inline]
    fn vertex_count(&self) -> usize {
        self.body.mesh.vertex_count()
    }
    fn add_forces(&self, positions: &[Vec3], forces: &mut [Vec3]) -> Result<(), MeshError> {
        let (partition, material, threshold) =
            (&self.partition, &self.body.material, self.body.threshold);
        let mut element_forces = self
            .element_forces
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let element_forces: &mut [ElementForces] = &mut element_forces;
        on_pool(self.pool, || {
            add_elastic_forces_clamped(
                partition,
                material,
                threshold,
                positions,
                forces,
                element_forces,
            )
        })
    }
    fn for_each_element_stiffness(&self, visit: impl FnMut(&[u32], Real, Real)) {
        self.body.for_each_element_stiffness(visit);
    }
    fn run_vertex_pass<P: VertexPass>(&self, pass: P) -> P::Output {
        on_pool(self.pool, || pass.run_with(&RayonJoin))
    }
}

#[cfg(test)]
mod tests {
    use super::super::element::TetRest;
    use super::super::generate::{BoxSplit, box_counts, fill_box};
    use super::super::material::StVK;
    use super::super::mesh::TetMesh;
    use super::super::types::{Real, Vec3};
    use super::positions_pass;
    use std::vec;

    /// The parallel position check decides `true` (so the force passes skip the sequential
    /// check) exactly for finite positions within the deformation bound, on two or more threads
    /// and from `2 CHECK_CHUNK` vertices on; `tests/steppers/parallel.rs` checks that the passes
    /// then give the sequential bits and errors.
    #[test]
    fn positions_pass_only_for_finite_positions_in_range_on_several_threads() {
        let (cells, layers) = (127, 1);
        let (vertices, tets) = box_counts(cells, cells, layers, BoxSplit::Kuhn6).unwrap();
        assert!(vertices >= 2 * super::CHECK_CHUNK);
        let (mut rest, mut elements) = (vec![Vec3::ZERO; vertices], vec![[0; 4]; tets]);
        let high = Vec3::new(1.0, 1.0, 1.0 / cells as Real);
        let split = BoxSplit::Kuhn6;
        fill_box(
            Vec3::ZERO,
            high,
            cells,
            cells,
            layers,
            split,
            &mut rest,
            &mut elements,
        )
        .unwrap();
        let mut rest_data = vec![TetRest::default(); tets];
        let mesh = TetMesh::new(&rest, &elements, &mut rest_data).unwrap();
        let stvk = StVK::from_young_poisson(1.0e6, 0.45).unwrap();
        let stretched: vec::Vec<Vec3> = rest.iter().map(|p| *p * 1.2).collect();
        let pool = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
        };
        let (one, two) = (pool(1), pool(2));
        let pass =
            |pool: &rayon::ThreadPool, x: &[Vec3]| pool.install(|| positions_pass(&mesh, &stvk, x));
        assert!(pass(&two, &stretched));
        assert!(!pass(&one, &stretched), "one thread: the sequential check");
        let few = &stretched[..2 * super::CHECK_CHUNK - 1];
        assert!(!two.install(|| positions_pass(&mesh, &stvk, few)));
        for (value, axis) in [(Real::NAN, 0), (Real::INFINITY, 1), (Real::MAX.sqrt(), 2)] {
            let mut x = stretched.clone();
            if let Some(p) = x.last_mut() {
                p[axis] = value;
            }
            assert!(!pass(&two, &x), "{value} at the last vertex");
        }
    }
}

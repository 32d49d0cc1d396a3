//! The world's elastic passes on a rayon thread pool (feature `rayon`): one task per body, the
//! bodies split in halves by `rayon::join`, each task writing only its own range of the output
//! (its vertices' forces, products or blocks, its tetrahedra's Hessians) through disjoint
//! `split_at_mut` slices, so every entry receives the same terms in the same order as on one
//! thread: the same bits at every thread count.
//!
//! A body's kernel runs on its own vertices: the positions (or direction) sliced from its first
//! vertex, its tetrahedra in body-local indices ([`Threads::local_tets`], kept beside the world's
//! global ones). Gathering `x[first + i]` as `x_local[i]` reads the same numbers, so the
//! arithmetic is the sequential kernel's. The energies are kept one per body and summed in body
//! order afterwards, as the sequential model sums them.
//!
//! Errors: each pass first makes the sequential pass's global checks cheaply (lengths, and
//! finiteness where that pass checks it); where they do not pass at once, the sequential pass
//! runs instead and decides, so an error names the same buffer and vertex. What is left are the
//! bodies' own errors (an element beyond the material's range, named by its body-local index,
//! as the sequential pass names it), of which the first body's is returned. On an error the
//! output may hold the terms of other bodies than the sequential pass would have added (the
//! steppers restore the state on any error).
//!
//! The contact model's pair work (broad phase, barrier, friction, continuous collision
//! detection) stays on the calling thread.

use core::ops::Range;
use std::sync::{Arc, Mutex, PoisonError};
use std::vec::Vec;

use rayon::ThreadPool;

use super::super::element::TetHessian;
use super::super::material::Material;
use super::super::mesh::TetMesh;
use super::super::parallel::{RayonJoin, on_pool};
use super::super::step::vertex_pass::VertexPass;
use super::super::step::{ElasticEnergy, ElasticHessian, ElasticModel, SweepRun, TetElastic};
use super::super::types::{Mat3, Real, Vec3};
use super::Part;
use super::model::WorldElastic;
use crate::error::MeshError;

impl<M: Material> core::fmt::Debug for Threads<M> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Threads")
            .field("threads", &self.pool.current_num_threads())
            .field("local_tets", &self.local_tets.len())
            .finish_non_exhaustive()
    }
}

/// A world's thread pool and what its parallel passes keep: the bodies' tetrahedra in
/// body-local indices and one energy per body.
pub(crate) struct Threads<M: Material> {
    pool: Arc<ThreadPool>,
    passes: Passes<M>,
    /// Every body's tetrahedra, in the world's order, each body's indices counted from its
    /// first vertex.
    local_tets: Vec<[u32; 4]>,
    /// One energy per body, written by the bodies' tasks, summed in order afterwards.
    energies: Mutex<Vec<Real>>,
}

/// The parallel passes for the world's material, taken where the material is known to be
/// `Sync` ([`Threads::new`]): the model's trait methods, generic over every material, call
/// them through these pointers.
struct Passes<M: Material> {
    add_forces: PassFn<M, (), Vec3>,
    energy_and_add_forces: PassFn<M, Real, Vec3>,
    projected_hessians: PassFn<M, (), TetHessian>,
    add_hessian_product: ProductFn<M, Vec3>,
    add_vertex_hessian_blocks: BlocksFn<M>,
    run_sweep: fn(&ThreadPool, SweepRun<'_, '_, M>),
}

/// A pass reading positions and writing `out`.
type PassFn<M, T, X> =
    for<'a, 'b> fn(&'b WorldElastic<'a, M>, &Threads<M>, &[Vec3], &mut [X]) -> Result<T, MeshError>;
/// A pass reading the Hessian cache and a direction, writing `out`.
type ProductFn<M, X> = for<'a, 'b> fn(
    &'b WorldElastic<'a, M>,
    &Threads<M>,
    &[TetHessian],
    &[Vec3],
    &mut [X],
) -> Result<(), MeshError>;
/// A pass reading the Hessian cache, writing blocks.
type BlocksFn<M> = for<'a, 'b> fn(
    &'b WorldElastic<'a, M>,
    &Threads<M>,
    &[TetHessian],
    &mut [Mat3],
) -> Result<(), MeshError>;

impl<M: Material + Sync> Threads<M> {
    /// The passes on `pool`, fitted to no bodies yet ([`fit`](Self::fit)).
    pub(crate) fn new(pool: Arc<ThreadPool>) -> Self {
        Threads {
            pool,
            passes: Passes {
                add_forces: add_forces::<M>,
                energy_and_add_forces: energy_and_add_forces::<M>,
                projected_hessians: projected_hessians::<M>,
                add_hessian_product: add_hessian_product::<M>,
                add_vertex_hessian_blocks: add_vertex_hessian_blocks::<M>,
                run_sweep: run_sweep::<M>,
            },
            local_tets: Vec::new(),
            energies: Mutex::new(Vec::new()),
        }
    }
}

impl<M: Material> Threads<M> {
    /// The pool.
    pub(crate) fn pool(&self) -> &Arc<ThreadPool> {
        &self.pool
    }

    /// Refits the body-local tetrahedra and the energies to the bodies `parts` over the world's
    /// `tets`; `false` (nothing changed that the passes rely on: they fall back to the
    /// sequential passes) if the memory is refused.
    pub(crate) fn fit(&mut self, parts: &[Part<M>], tets: &[[u32; 4]]) -> bool {
        self.local_tets.clear();
        let energies = self
            .energies
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner);
        energies.clear();
        if self.local_tets.try_reserve(tets.len()).is_err()
            || energies.try_reserve(parts.len()).is_err()
        {
            return false;
        }
        energies.resize(parts.len(), 0.0);
        for part in parts {
            let first = part.first_vertex;
            let body = tets.get(part.tet_range()).unwrap_or(&[]);
            self.local_tets
                .extend(body.iter().map(|tet| tet.map(|v| v.wrapping_sub(first))));
        }
        true
    }

    /// Whether the kept lists fit a world of `bodies` bodies and `tets` tetrahedra (else the
    /// sequential passes run).
    fn fits(&self, bodies: usize, tets: usize) -> bool {
        let energies = self.energies.lock().map_or(0, |energies| energies.len());
        self.local_tets.len() == tets && energies == bodies
    }

    /// [`ElasticModel::add_forces`] of `world` on the pool.
    pub(crate) fn add_forces(
        &self,
        world: &WorldElastic<'_, M>,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<(), MeshError> {
        (self.passes.add_forces)(world, self, positions, forces)
    }

    /// [`ElasticEnergy::energy_and_add_forces`] of `world` on the pool.
    pub(crate) fn energy_and_add_forces(
        &self,
        world: &WorldElastic<'_, M>,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, MeshError> {
        (self.passes.energy_and_add_forces)(world, self, positions, forces)
    }

    /// [`ElasticHessian::projected_hessians`] of `world` on the pool.
    pub(crate) fn projected_hessians(
        &self,
        world: &WorldElastic<'_, M>,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        (self.passes.projected_hessians)(world, self, positions, cache)
    }

    /// [`ElasticHessian::add_hessian_product`] of `world` on the pool.
    pub(crate) fn add_hessian_product(
        &self,
        world: &WorldElastic<'_, M>,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        (self.passes.add_hessian_product)(world, self, cache, direction, out)
    }

    /// [`ElasticHessian::add_vertex_hessian_blocks`] of `world` on the pool.
    pub(crate) fn add_vertex_hessian_blocks(
        &self,
        world: &WorldElastic<'_, M>,
        cache: &[TetHessian],
        blocks: &mut [Mat3],
    ) -> Result<(), MeshError> {
        (self.passes.add_vertex_hessian_blocks)(world, self, cache, blocks)
    }

    /// One of the steppers' passes over the vertices, in blocks on the pool ([`RayonJoin`]:
    /// the same bits as on the calling thread).
    pub(crate) fn run_vertex_pass<P: VertexPass>(&self, pass: P) -> P::Output {
        on_pool(Some(&self.pool), || pass.run_with(&RayonJoin))
    }

    /// One sweep of Vertex Block Descent, each body's colours on the pool.
    pub(crate) fn run_sweep(&self, run: SweepRun<'_, '_, M>) {
        (self.passes.run_sweep)(&self.pool, run);
    }
}

/// Body `part`'s tetrahedra as a model over its own vertices (body-local indices).
fn local_body<'a, M: Material>(
    threads: &'a Threads<M>,
    world: &WorldElastic<'a, M>,
    part: &Part<M>,
) -> TetElastic<'a, M> {
    let range = part.tet_range();
    let tets = threads.local_tets.get(range.clone()).unwrap_or(&[]);
    let rest = world.rest.get(range).unwrap_or(&[]);
    let vertices = part.vertex_count as usize;
    let mesh = TetMesh::from_validated(tets, rest, vertices, part.gradient_gain);
    TetElastic::new(mesh, part.material)
}

/// Where a task writes: the body's range of an output, relative to the start of the slice
/// the task was given (`first` of the bodies before the slice).
type Ranges<M> = fn(usize, &Part<M>) -> (Range<usize>, Range<usize>);

/// Runs `task(body, part, a, b)` for every body of `parts` (the first is body `first`) in
/// parallel, `a` and `b` cut at the bodies' ranges `ranges(body, part)` (two ranges each,
/// relative to `a_base` and `b_base`; each body's ranges follow the previous body's). Returns
/// the first body's error, in body order.
fn for_bodies<M, A, B, F>(
    parts: &[Part<M>],
    first: usize,
    (a, a_base): (&mut [A], usize),
    (b, b_base): (&mut [B], usize),
    ranges: Ranges<M>,
    task: &F,
) -> Result<(), MeshError>
where
    M: Material + Sync,
    A: Send,
    B: Send,
    F: Fn(usize, &Part<M>, &mut [A], &mut [B]) -> Result<(), MeshError> + Sync,
{
    match parts {
        [] => Ok(()),
        [part] => {
            let (ra, rb) = ranges(first, part);
            let a = relative(ra, a_base).and_then(|range| a.get_mut(range));
            let b = relative(rb, b_base).and_then(|range| b.get_mut(range));
            match (a, b) {
                (Some(a), Some(b)) => task(first, part, a, b),
                _ => Err(outside()),
            }
        }
        _ => {
            let middle = parts.len() / 2;
            let (low, high) = parts.split_at(middle);
            let Some(split) = high.first() else {
                return Err(outside());
            };
            let (ra, rb) = ranges(first + middle, split);
            let a_split = ra.start.checked_sub(a_base);
            let b_split = rb.start.checked_sub(b_base);
            let (Some((a_low, a_high)), Some((b_low, b_high))) = (
                a_split.and_then(|at| a.split_at_mut_checked(at)),
                b_split.and_then(|at| b.split_at_mut_checked(at)),
            ) else {
                return Err(outside());
            };
            let (left, right) = rayon::join(
                || for_bodies(low, first, (a_low, a_base), (b_low, b_base), ranges, task),
                || {
                    for_bodies(
                        high,
                        first + middle,
                        (a_high, ra.start),
                        (b_high, rb.start),
                        ranges,
                        task,
                    )
                },
            );
            left.and(right)
        }
    }
}

/// `range` counted from `base`, if it starts there or later.
fn relative(range: Range<usize>, base: usize) -> Option<Range<usize>> {
    Some(range.start.checked_sub(base)?..range.end.checked_sub(base)?)
}

/// The error of a body range outside its buffer, which a world never builds (its bodies'
/// ranges follow each other and cover its lists; the callers check the lengths first).
fn outside() -> MeshError {
    MeshError::LengthMismatch {
        buffer: crate::Buffer::RestData,
        expected: 0,
        actual: 0,
    }
}

/// The body's vertex range, and nothing of the second output.
fn vertices_only<M>(_: usize, part: &Part<M>) -> (Range<usize>, Range<usize>) {
    (part.vertices(), 0..0)
}

/// The body's vertex range and its entry of a per-body list.
fn vertices_and_body<M>(body: usize, part: &Part<M>) -> (Range<usize>, Range<usize>) {
    (part.vertices(), body..body + 1)
}

/// The body's tetrahedron range, and nothing of the second output.
fn tets_only<M>(_: usize, part: &Part<M>) -> (Range<usize>, Range<usize>) {
    (part.tet_range(), 0..0)
}

/// Whether the parallel pass may run: the kept lists fit the world and every per-vertex buffer
/// has its `lengths` entry equal to the vertex count.
fn ready<M: Material>(threads: &Threads<M>, world: &WorldElastic<'_, M>, lengths: &[usize]) -> bool {
    threads.fits(world.parts.len(), world.tets.len())
        && lengths.iter().all(|&len| len == world.vertex_count)
}

/// Whether every entry is finite.
fn all_finite(values: &[Vec3]) -> bool {
    values.iter().all(|p| p.is_finite())
}

/// The empty second output of the single-output passes.
fn nothing() -> [(); 0] {
    []
}

fn add_forces<M: Material + Sync>(
    world: &WorldElastic<'_, M>,
    threads: &Threads<M>,
    positions: &[Vec3],
    forces: &mut [Vec3],
) -> Result<(), MeshError> {
    // The sequential pass checks the lengths and the finiteness of every position first.
    if !(ready(threads, world, &[positions.len(), forces.len()]) && all_finite(positions)) {
        return world.sequential_add_forces(positions, forces);
    }
    threads.pool.install(|| {
        for_bodies(
            world.parts,
            0,
            (forces, 0),
            (&mut nothing(), 0),
            vertices_only,
            &|_, part, out, _| {
                let x = positions.get(part.vertices()).unwrap_or(&[]);
                local_body(threads, world, part).add_forces(x, out)
            },
        )
    })
}

fn energy_and_add_forces<M: Material + Sync>(
    world: &WorldElastic<'_, M>,
    threads: &Threads<M>,
    positions: &[Vec3],
    forces: &mut [Vec3],
) -> Result<Real, MeshError> {
    // The sequential pass checks the lengths only (a position beyond the material's range
    // makes its body's energy infinite).
    if !ready(threads, world, &[positions.len(), forces.len()]) {
        return world.sequential_energy_and_add_forces(positions, forces);
    }
    let mut energies = threads
        .energies
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    let body_energies = energies.as_mut_slice();
    threads.pool.install(|| {
        for_bodies(
            world.parts,
            0,
            (forces, 0),
            (body_energies, 0),
            vertices_and_body,
            &|_, part, out, energy: &mut [Real]| {
                let x = positions.get(part.vertices()).unwrap_or(&[]);
                let body = local_body(threads, world, part).energy_and_add_forces(x, out)?;
                for slot in energy {
                    *slot = body;
                }
                Ok(())
            },
        )
    })?;
    // In body order from zero, as the sequential pass adds them.
    let mut total: Real = 0.0;
    for &energy in energies.iter() {
        total += energy;
    }
    Ok(total)
}

fn projected_hessians<M: Material + Sync>(
    world: &WorldElastic<'_, M>,
    threads: &Threads<M>,
    positions: &[Vec3],
    cache: &mut [TetHessian],
) -> Result<(), MeshError> {
    let cache_fits = cache.len() == world.tets.len();
    if !(ready(threads, world, &[positions.len()]) && cache_fits && all_finite(positions)) {
        return world.sequential_projected_hessians(positions, cache);
    }
    threads.pool.install(|| {
        for_bodies(
            world.parts,
            0,
            (cache, 0),
            (&mut nothing(), 0),
            tets_only,
            &|_, part, out, _| {
                let x = positions.get(part.vertices()).unwrap_or(&[]);
                local_body(threads, world, part).projected_hessians(x, out)
            },
        )
    })
}

fn add_hessian_product<M: Material + Sync>(
    world: &WorldElastic<'_, M>,
    threads: &Threads<M>,
    cache: &[TetHessian],
    direction: &[Vec3],
    out: &mut [Vec3],
) -> Result<(), MeshError> {
    let cache_fits = cache.len() == world.tets.len();
    if !(ready(threads, world, &[direction.len(), out.len()])
        && cache_fits
        && all_finite(direction))
    {
        return world.sequential_add_hessian_product(cache, direction, out);
    }
    threads.pool.install(|| {
        for_bodies(
            world.parts,
            0,
            (out, 0),
            (&mut nothing(), 0),
            vertices_only,
            &|_, part, out, _| {
                let d = direction.get(part.vertices()).unwrap_or(&[]);
                let cache = cache.get(part.tet_range()).unwrap_or(&[]);
                local_body(threads, world, part).add_hessian_product(cache, d, out)
            },
        )
    })
}

fn add_vertex_hessian_blocks<M: Material + Sync>(
    world: &WorldElastic<'_, M>,
    threads: &Threads<M>,
    cache: &[TetHessian],
    blocks: &mut [Mat3],
) -> Result<(), MeshError> {
    let cache_fits = cache.len() == world.tets.len();
    if !(ready(threads, world, &[blocks.len()]) && cache_fits) {
        return world.sequential_add_vertex_hessian_blocks(cache, blocks);
    }
    threads.pool.install(|| {
        for_bodies(
            world.parts,
            0,
            (blocks, 0),
            (&mut nothing(), 0),
            vertices_only,
            &|_, part, out, _| {
                let cache = cache.get(part.tet_range()).unwrap_or(&[]);
                local_body(threads, world, part).add_vertex_hessian_blocks(cache, out)
            },
        )
    })
}

/// The sweep's bodies one after the other, each body's colours on the pool: the contact's
/// terms were computed at the sweep's start and are only read during it, and two vertices of
/// one colour of one body share no element, so every update reads what it reads in order.
fn run_sweep<M: Material + Sync>(pool: &ThreadPool, run: SweepRun<'_, '_, M>) {
    pool.install(|| run.on_pool());
}

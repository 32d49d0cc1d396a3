//! Where a [`World`](super::World) keeps its buffers, chosen at the type level: fixed capacity
//! in place ([`FixedWorld`], no heap: `heapless` vectors and fixed arrays) or, with the `alloc`
//! feature, growable vectors (`VecStorage`, the body's storage type).
//!
//! Two kinds of buffer: a [`List`] keeps its entries when the world grows or shrinks (the
//! bodies' records, vertices and tetrahedra, appended when a body is added and closed up when
//! one is removed); a [`Slots`] buffer is refilled from scratch whenever it is resized (the
//! derived surface, the contact lists and the solvers' scratch).

use super::super::asset::surface::BoundaryFace;
use super::super::body::Fixed;
use super::super::body::Slots;
#[cfg(feature = "alloc")]
use super::super::body::VecStorage;
use super::super::element::{TetHessian, TetRest};
use super::super::material::Material;
use super::super::step::contact::model::FrictionPair;
use super::super::step::contact::potential::PairHessian;
use super::super::types::{Mat3, Real, Vec3};
use super::Part;

/// A list of `X` that keeps its entries as it grows, up to a capacity that is fixed
/// (`heapless::Vec`) or grows (`Vec`, feature `alloc`).
pub trait List<X: Copy> {
    /// A list of length zero.
    #[must_use]
    fn empty() -> Self;

    /// Appends `values`; returns `false` (and leaves the list as it was) if they do not fit:
    /// beyond a fixed capacity, or an allocation refused.
    #[must_use]
    fn extend(&mut self, values: &[X]) -> bool;

    /// Shortens the list to `len` entries (nothing if it is not longer).
    fn truncate(&mut self, len: usize);

    /// The entries.
    #[must_use]
    fn slice(&self) -> &[X];

    /// The entries, writable.
    #[must_use]
    fn slice_mut(&mut self) -> &mut [X];
}

/// Removes the entries `start..start + count` of `list`, closing up the gap (the later entries
/// keep their order). Does nothing for a range beyond the list.
pub(crate) fn remove_range<X: Copy, L: List<X>>(list: &mut L, start: usize, count: usize) {
    let len = list.slice().len();
    let Some(end) = start.checked_add(count).filter(|&end| end <= len) else {
        return;
    };
    list.slice_mut().copy_within(end.., start);
    list.truncate(len - count);
}

impl<X: Copy, const N: usize> List<X> for heapless::Vec<X, N> {
    #[inline]
    fn empty() -> Self {
        heapless::Vec::new()
    }

    fn extend(&mut self, values: &[X]) -> bool {
        self.extend_from_slice(values).is_ok()
    }

    #[inline]
    fn truncate(&mut self, len: usize) {
        heapless::Vec::truncate(self, len);
    }

    #[inline]
    fn slice(&self) -> &[X] {
        self.as_slice()
    }

    #[inline]
    fn slice_mut(&mut self) -> &mut [X] {
        self.as_mut_slice()
    }
}

#[cfg(feature = "alloc")]
impl<X: Copy> List<X> for alloc::vec::Vec<X> {
    #[inline]
    fn empty() -> Self {
        alloc::vec::Vec::new()
    }

    fn extend(&mut self, values: &[X]) -> bool {
        // Allocation failure is refused here, not left to abort the program.
        if self.try_reserve(values.len()).is_err() {
            return false;
        }
        self.extend_from_slice(values);
        true
    }

    #[inline]
    fn truncate(&mut self, len: usize) {
        alloc::vec::Vec::truncate(self, len);
    }

    #[inline]
    fn slice(&self) -> &[X] {
        self
    }

    #[inline]
    fn slice_mut(&mut self) -> &mut [X] {
        self
    }
}

/// The buffer types of a world. Implemented by [`FixedWorld`] and `VecStorage`; implement it to
/// place the buffers elsewhere.
///
/// Why not the body's [`Storage`](crate::body::Storage): a world's buffers differ in kind, not
/// only in size. Its vertex and tetrahedron lists are kept lists that bodies are appended to and
/// removed from ([`List`]), where a body's are sized once; it adds the body list, the contact
/// surface, the broad phase and the pair lists; and a fixed world sizes the contact lists by
/// their own capacity `C`, which no per-vertex or per-tetrahedron count gives. Sharing one trait
/// would give every fixed body contact buffers it never uses.
pub trait WorldStorage {
    /// One record per body (its ranges and material).
    type Parts<M: Material>: List<Part<M>>;
    /// One vector per vertex, kept (rest and current positions, velocities).
    type Vectors: List<Vec3>;
    /// One scalar per vertex, kept (masses).
    type Reals: List<Real>;
    /// One flag per vertex, kept (pinned).
    type Flags: List<bool>;
    /// One index quadruple per tetrahedron, kept (global vertex indices).
    type Tets: List<[u32; 4]>;
    /// One rest datum per tetrahedron, kept.
    type Rests: List<TetRest>;
    /// The solvers' vector scratch, per vertex: the solver's own vectors (Newton's method's
    /// nine at most) and four more, the impulses and start velocities of a step recorded for
    /// reactions and the start positions and velocities of a coupled step
    /// ([`World::step_with_rigid_bodies`](super::World::step_with_rigid_bodies)): thirteen at
    /// most.
    type Scratch: Slots<Vec3>;
    /// One scalar per vertex of scratch (the relaxation's preconditioner).
    type Scalars: Slots<Real>;
    /// One 3x3 block per vertex (Newton's preconditioner).
    type Blocks: Slots<Mat3>;
    /// One Hessian per tetrahedron (Newton's method).
    type Hessians: Slots<TetHessian>;
    /// The boundary triangles of every body: up to four per tetrahedron.
    type Triangles: Slots<[u32; 3]>;
    /// The boundary extraction's scratch: four faces per tetrahedron of the largest body.
    type Faces: Slots<BoundaryFace>;
    /// Index lists of the contact surface and its broad phase (surface vertices, hash slots,
    /// cell entries).
    type Indices: Slots<u32>;
    /// Index pairs of the contact surface and its broad phase (surface edges, candidate
    /// vertex–triangle and edge–edge pairs).
    type Pairs: Slots<[u32; 2]>;
    /// The active contact pairs' Hessians (Newton's method).
    type PairHessians: Slots<PairHessian>;
    /// The frictional pairs.
    type FrictionPairs: Slots<FrictionPair>;
    /// Two vectors per surface vertex (the boxes of candidate reuse).
    type Bounds: Slots<Vec3>;
    /// Vertex Block Descent's vertex adjacency offsets, colours and order: `3 n + 1` indices
    /// for `n` vertices.
    type VertexIndices: Slots<u32>;
    /// Vertex Block Descent's incident elements: four indices per tetrahedron.
    type TetIndices: Slots<u32>;
}

/// Fixed capacity, no heap: at most `B` bodies, `V` vertices and `T` tetrahedra in all, `C`
/// entries in each contact-surface list (surface vertices and edges, the broad phase's hash
/// slots and cell entries, candidate vertex–triangle and edge–edge pairs) and `P` active
/// contact pairs (their Hessians and friction). Every buffer is an array or a
/// `heapless::Vec` inside the world; what does not fit is an error naming the buffer and the
/// count needed, never a panic.
///
/// The largest contact-surface list is the broad phase's cell entries: 8 per surface
/// primitive (vertex, edge and triangle), so `C` must be at least `8 (v + e + f)` for a
/// surface of `v` vertices, `e` edges and `f` triangles (a closed surface has `e = 3 f / 2`
/// and `v = f / 2 + 2` per body): [`contact_capacity`](FixedWorld::contact_capacity) gives it
/// from the triangle count. Candidate pairs need one entry per pair within the gap; `P` one
/// per pair closer than the gap (a resting face of `f` triangles: about `2 f`).
///
/// A world of this storage is large (`core::mem::size_of` tells; 4 KB per hundred `C` and
/// 60 KB per hundred `P` in f32): keep it in a `static` or a `Box`, not on a small stack.
#[derive(Clone, Copy, Debug)]
pub struct FixedWorld<
    const B: usize,
    const V: usize,
    const T: usize,
    const C: usize,
    const P: usize,
>;

impl<const B: usize, const V: usize, const T: usize, const C: usize, const P: usize>
    FixedWorld<B, V, T, C, P>
{
    /// The contact-surface capacity `C` a world whose bodies have `triangles` boundary
    /// triangles in all needs (closed surfaces): `8 (v + e + f)` with `e = 3 f / 2` edges and
    /// at most `3 f` vertex slots, that is `44 f` (the surface-vertex list is first written with
    /// three entries per triangle, then deduplicated).
    #[inline]
    #[must_use]
    pub const fn contact_capacity(triangles: usize) -> usize {
        triangles.saturating_mul(44)
    }
}

impl<const B: usize, const V: usize, const T: usize, const C: usize, const P: usize> WorldStorage
    for FixedWorld<B, V, T, C, P>
{
    type Parts<M: Material> = heapless::Vec<Part<M>, B>;
    type Vectors = heapless::Vec<Vec3, V>;
    type Reals = heapless::Vec<Real, V>;
    type Flags = heapless::Vec<bool, V>;
    type Tets = heapless::Vec<[u32; 4], T>;
    type Rests = heapless::Vec<TetRest, T>;
    type Scratch = Fixed<Vec3, 13, V>;
    type Scalars = Fixed<Real, 1, V>;
    type Blocks = Fixed<Mat3, 1, V>;
    type Hessians = Fixed<TetHessian, 1, T>;
    type Triangles = Fixed<[u32; 3], 4, T>;
    type Faces = Fixed<BoundaryFace, 4, T>;
    type Indices = heapless::Vec<u32, C>;
    type Pairs = heapless::Vec<[u32; 2], C>;
    type PairHessians = heapless::Vec<PairHessian, P>;
    type FrictionPairs = heapless::Vec<FrictionPair, P>;
    type Bounds = Fixed<Vec3, 2, V>;
    type VertexIndices = Fixed<u32, 4, V>;
    type TetIndices = Fixed<u32, 4, T>;
}

#[cfg(feature = "alloc")]
impl WorldStorage for VecStorage {
    type Parts<M: Material> = alloc::vec::Vec<Part<M>>;
    type Vectors = alloc::vec::Vec<Vec3>;
    type Reals = alloc::vec::Vec<Real>;
    type Flags = alloc::vec::Vec<bool>;
    type Tets = alloc::vec::Vec<[u32; 4]>;
    type Rests = alloc::vec::Vec<TetRest>;
    type Scratch = alloc::vec::Vec<Vec3>;
    type Scalars = alloc::vec::Vec<Real>;
    type Blocks = alloc::vec::Vec<Mat3>;
    type Hessians = alloc::vec::Vec<TetHessian>;
    type Triangles = alloc::vec::Vec<[u32; 3]>;
    type Faces = alloc::vec::Vec<BoundaryFace>;
    type Indices = alloc::vec::Vec<u32>;
    type Pairs = alloc::vec::Vec<[u32; 2]>;
    type PairHessians = alloc::vec::Vec<PairHessian>;
    type FrictionPairs = alloc::vec::Vec<FrictionPair>;
    type Bounds = alloc::vec::Vec<Vec3>;
    type VertexIndices = alloc::vec::Vec<u32>;
    type TetIndices = alloc::vec::Vec<u32>;
}

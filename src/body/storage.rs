//! Where a [`Body`](super::Body) keeps its buffers, chosen at the type level: fixed arrays
//! ([`FixedStorage`], no heap) or, with the `alloc` feature, growable vectors (`VecStorage`).

use super::super::element::{TetHessian, TetRest};
use super::super::mesh::TetRestBlock;
use super::super::types::{Mat3, Real, Vec3};

/// A buffer of `X` with a length set by [`resize`](Slots::resize), up to a capacity that is
/// fixed ([`Fixed`]) or grows (`Vec`, feature `alloc`).
pub trait Slots<X: Copy> {
    /// A buffer of length zero.
    #[must_use]
    fn empty() -> Self;

    /// Sets the length to `len`, every entry to `fill`. Returns `false` (and leaves the buffer
    /// as it was) if `len` entries do not fit: beyond a fixed capacity, or an allocation refused.
    #[must_use]
    fn resize(&mut self, len: usize, fill: X) -> bool;

    /// The entries.
    #[must_use]
    fn slice(&self) -> &[X];

    /// The entries, writable.
    #[must_use]
    fn slice_mut(&mut self) -> &mut [X];
}

/// The buffer types of a body: per vertex, per tetrahedron and the solvers' scratch.
/// Implemented by [`FixedStorage`] and `VecStorage`; implement it to place the buffers
/// elsewhere.
pub trait Storage {
    /// One vector per vertex (positions, velocities, targets).
    type Vectors: Slots<Vec3>;
    /// One scalar per vertex (masses, the preconditioner's and stable step's stiffness).
    type Reals: Slots<Real>;
    /// One flag per vertex (pinned, kinematic).
    type Flags: Slots<bool>;
    /// One index quadruple per tetrahedron.
    type Tets: Slots<[u32; 4]>;
    /// One rest datum per tetrahedron.
    type Rests: Slots<TetRest>;
    /// The rest data again in blocks of 16 tetrahedra
    /// ([`TetMesh::with_rest_blocks`](crate::mesh::TetMesh::with_rest_blocks)): optional, a
    /// storage that cannot hold them runs the force passes without (the same bits, slower
    /// with wide SIMD).
    type RestBlocks: Slots<TetRestBlock>;
    /// The solvers' vector scratch: thirteen vectors per vertex, whatever the solver (the
    /// automatic solver's eleven: Newton's nine and a copy of the frame's start positions and
    /// velocities, where a step recorded for reactions keeps its contact impulses and start
    /// velocities; then a coupled step's copy of its start positions and velocities,
    /// [`Body::step_with_rigid_bodies`](super::Body::step_with_rigid_bodies)).
    type Scratch: Slots<Vec3>;
    /// One 3x3 block per vertex (Newton's preconditioner).
    type Blocks: Slots<Mat3>;
    /// One Hessian per tetrahedron (Newton's method).
    type Hessians: Slots<TetHessian>;
    /// Vertex Block Descent's index scratch: `3 V + 1 + 4 T` entries.
    type Indices: Slots<u32>;
    /// Vertex Block Descent's packed sweep layout, values
    /// ([`scratch_len::vbd_layout`](crate::step::scratch_len::vbd_layout)): optional, a storage that cannot
    /// hold it sweeps without it (the same bits, slower).
    type LayoutValues: Slots<Real>;
    /// Vertex Block Descent's packed sweep layout, corner indices
    /// ([`scratch_len::vbd_layout_corners`](crate::step::scratch_len::vbd_layout_corners)); as
    /// [`LayoutValues`](Self::LayoutValues).
    type LayoutCorners: Slots<u32>;
}

/// `ROWS` rows of `N` entries, used as one buffer of up to `ROWS * N` entries: a fixed
/// capacity in place, no heap.
#[derive(Clone, Debug)]
pub struct Fixed<X, const ROWS: usize, const N: usize> {
    rows: [[X; N]; ROWS],
    len: usize,
}

impl<X: Copy, const ROWS: usize, const N: usize> Fixed<X, ROWS, N> {
    /// A buffer of length zero whose whole capacity holds `fill`: a `const` initial value, so
    /// a fixed-capacity body can sit in a `static` (see [`Body::empty`](super::Body::empty)).
    #[inline]
    #[must_use]
    pub const fn filled(fill: X) -> Self {
        Fixed {
            rows: [[fill; N]; ROWS],
            len: 0,
        }
    }
}

impl<X: Copy + Default, const ROWS: usize, const N: usize> Slots<X> for Fixed<X, ROWS, N> {
    #[inline]
    fn empty() -> Self {
        Fixed {
            rows: [[X::default(); N]; ROWS],
            len: 0,
        }
    }

    fn resize(&mut self, len: usize, fill: X) -> bool {
        if len > ROWS.saturating_mul(N) {
            return false;
        }
        self.len = len;
        self.slice_mut().fill(fill);
        true
    }

    #[inline]
    fn slice(&self) -> &[X] {
        self.rows.as_flattened().get(..self.len).unwrap_or(&[])
    }

    #[inline]
    fn slice_mut(&mut self) -> &mut [X] {
        self.rows
            .as_flattened_mut()
            .get_mut(..self.len)
            .unwrap_or(&mut [])
    }
}

/// Fixed capacity, no heap (the firmware case): at most `V` vertices and `T` tetrahedra, every
/// buffer an array inside the body. A body that does not fit is a
/// [`BodyError::Capacity`](crate::BodyError::Capacity), never a panic.
///
/// Every buffer has room for every solver, so the solver can change without running out. In
/// f32 (twice in f64) that is, per vertex, 262 bytes: the rest and current positions, the
/// velocities, the targets and a velocity backup (5 vectors), the solvers' vector scratch (13:
/// Newton's method's 9, the automatic solver's copy of a frame's start and a coupled step's
/// copy of its start), the mass, a stiffness scalar, 2 flags and Newton's 3x3 block; and per
/// tetrahedron 304 bytes: the indices (16), the rest data (40), Newton's Hessian (180) and 17
/// entries of Vertex Block Descent's index scratch (68), whose `3 V + 1 + 4 T` entries fit in
/// `17 T` whenever `V <= 4 T` (every steppable body: a vertex in no tetrahedron has no mass).
/// `core::mem::size_of::<Body<FixedStorage<V, T>, M>>()` is the total (the bar of
/// `tests/steppers/body.rs`, 54 vertices and 120 tetrahedra, takes 50 KB). It has no room for
/// Vertex Block Descent's packed sweep layout (312 bytes per tetrahedron in f32), so its sweeps
/// gather the rest data element by element (the same bits; `VecStorage` keeps the layout), nor for
/// the rest data in blocks (40 bytes per tetrahedron), which serve only the wide SIMD lanes of a
/// host.
#[derive(Clone, Copy, Debug)]
pub struct FixedStorage<const V: usize, const T: usize>;

impl<const V: usize, const T: usize> Storage for FixedStorage<V, T> {
    type Vectors = Fixed<Vec3, 1, V>;
    type Reals = Fixed<Real, 1, V>;
    type Flags = Fixed<bool, 1, V>;
    type Tets = Fixed<[u32; 4], 1, T>;
    type Rests = Fixed<TetRest, 1, T>;
    type RestBlocks = Fixed<TetRestBlock, 0, 1>;
    type Scratch = Fixed<Vec3, 13, V>;
    type Blocks = Fixed<Mat3, 1, V>;
    type Hessians = Fixed<TetHessian, 1, T>;
    type Indices = Fixed<u32, 17, T>;
    type LayoutValues = Fixed<Real, 0, 1>;
    type LayoutCorners = Fixed<u32, 0, 1>;
}

/// A `heapless::Vec` as a fixed-capacity buffer (the world's contact lists,
/// [`FixedWorld`](crate::world::FixedWorld)).
impl<X: Copy, const N: usize> Slots<X> for heapless::Vec<X, N> {
    #[inline]
    fn empty() -> Self {
        heapless::Vec::new()
    }

    fn resize(&mut self, len: usize, fill: X) -> bool {
        if len > N {
            return false;
        }
        self.clear();
        heapless::Vec::resize(self, len, fill).is_ok()
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
impl<X: Copy> Slots<X> for alloc::vec::Vec<X> {
    #[inline]
    fn empty() -> Self {
        alloc::vec::Vec::new()
    }

    fn resize(&mut self, len: usize, fill: X) -> bool {
        // Allocation failure is refused here, not left to abort the program.
        if self
            .try_reserve_exact(len.saturating_sub(self.len()))
            .is_err()
        {
            return false;
        }
        self.clear();
        alloc::vec::Vec::resize(self, len, fill);
        true
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

/// Growable storage on the heap (feature `alloc`): any number of vertices and tetrahedra, each
/// solver's scratch allocated when it is chosen (for Vertex Block Descent with its packed sweep
/// layout, 312 bytes per tetrahedron in f32, when that allocation succeeds), and the rest data
/// also in blocks for the wide SIMD lanes (40 bytes per tetrahedron in f32, when that
/// allocation succeeds).
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
#[derive(Clone, Copy, Debug)]
pub struct VecStorage;

#[cfg(feature = "alloc")]
impl Storage for VecStorage {
    type Vectors = alloc::vec::Vec<Vec3>;
    type Reals = alloc::vec::Vec<Real>;
    type Flags = alloc::vec::Vec<bool>;
    type Tets = alloc::vec::Vec<[u32; 4]>;
    type Rests = alloc::vec::Vec<TetRest>;
    type RestBlocks = alloc::vec::Vec<TetRestBlock>;
    type Scratch = alloc::vec::Vec<Vec3>;
    type Blocks = alloc::vec::Vec<Mat3>;
    type Hessians = alloc::vec::Vec<TetHessian>;
    type Indices = alloc::vec::Vec<u32>;
    type LayoutValues = alloc::vec::Vec<Real>;
    type LayoutCorners = alloc::vec::Vec<u32>;
}

//! The mesh Hessian `d^2 E / dx^2` of a tetrahedral mesh (and of the triangle meshes),
//! matrix-free: a per-element cache of
//! projected stress derivatives ([`TetHessian`]) in a caller buffer, the product `H d` and the
//! per-vertex 3x3 diagonal blocks (`docs/math.md` section 6).
//!
//! The cache costs one SVD per element to build ([`TetMesh::projected_hessians`]) and 180
//! bytes per element in f32 (360 in f64); products and blocks then read it without any SVD.
//! Elements are visited in index order and their contributions added at their corners in corner
//! order, so results are the same bits on every target. The tetrahedral product takes the
//! elements in groups of the SIMD width's lanes (as the force passes, [`crate::simd`]), each
//! lane with one element's arithmetic in its order: the same bits at every width.

use super::super::element::HESSIAN_ENTRIES as ENTRIES;
use super::super::element::{MembraneHessian, TetHessian, TriHessian, TriangleStVK};
#[cfg(target_arch = "x86_64")]
use super::super::lanes::avx2::Avx2Lanes;
#[cfg(target_arch = "x86_64")]
use super::super::lanes::avx512::Avx512Lanes;
use super::super::lanes::{LANES, Lane, LaneArray, Lanes, transpose4};
use super::super::material::Material;
use super::super::math::BATCH_SVD;
use super::super::svd::svd3_lanes;
use super::super::types::{Mat2, Mat3, Real, Vec2, Vec3};
use super::grouped::{Positions, gather_corners, scatter_corners};
use super::prefetch;
use super::{
    MembraneMesh, TetMesh, TriMesh, check_finite, check_length, check_positions, gather,
    scatter_add,
};
use crate::error::{Buffer, MeshError};
use crate::simd::{WidthKernel, dispatch};

impl TetMesh<'_> {
    /// Writes the projected (SPD) Hessian data of every tetrahedron of `material` at deformed
    /// `positions` (m) into `cache` (one [`TetHessian`] per element, overwritten).
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] naming [`Buffer::Positions`] (one per vertex) or
    /// [`Buffer::Hessians`] (one per element); [`MeshError::NonFinitePosition`] naming the first
    /// non-finite vertex. On error, `cache` is unchanged.
    ///
    /// ```
    /// use softfem::element::{TetHessian, TetRest};
    /// use softfem::glam::{Mat3, Vec3};
    /// use softfem::material::StableNeoHookean;
    /// use softfem::mesh::TetMesh;
    ///
    /// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
    /// let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
    /// let mut rest_data = [TetRest::default(); 2];
    /// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
    /// let rubber = StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
    /// let mut cache = [TetHessian::default(); 2];
    /// mesh.projected_hessians(&rubber, &rest, &mut cache)?;
    /// // A rigid translation is in the kernel of the Hessian.
    /// let mut out = [Vec3::ZERO; 5];
    /// mesh.add_hessian_product(&cache, &[Vec3::Y; 5], &mut out)?;
    /// assert!(out.iter().all(|f| f.length() < 1e-1));
    /// let mut blocks = [Mat3::ZERO; 5];
    /// mesh.add_vertex_hessian_blocks(&cache, &mut blocks)?;
    /// assert!(blocks[1].x_axis.x > 0.0);
    /// # Ok::<(), softfem::MeshError>(())
    /// ```
    pub fn projected_hessians<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        check_positions(self.vertex_count(), positions)?;
        check_length(Buffer::Hessians, self.element_count(), cache.len())?;
        // The SVDs of consecutive tetrahedra LANES at a time where that is faster (the same
        // bits as one at a time, see `svd3_lanes`), as the principal force path does.
        let (groups, tail) = self.groups_and_tail(BATCH_SVD);
        let mut slots = cache.iter_mut();
        for (tets, rests) in groups {
            let gradients = core::array::from_fn(|lane| match (tets.get(lane), rests.get(lane)) {
                (Some(corners), Some(rest)) => {
                    rest.deformation_gradient(gather(positions, corners))
                }
                _ => Mat3::ZERO,
            });
            let svds = svd3_lanes(&gradients);
            for (rest, svd) in rests.iter().zip(&svds) {
                if let Some(slot) = slots.next() {
                    let derivative = material.projected_stress_derivative_from_svd(svd);
                    *slot = TetHessian::from_stress_derivative(&derivative, rest);
                }
            }
        }
        for ((corners, rest), slot) in tail.zip(slots) {
            *slot = TetHessian::new(material, rest, gather(positions, corners));
        }
        Ok(())
    }

    /// Writes the exact (unprojected, possibly indefinite) Hessian data of every tetrahedron of
    /// `material` at deformed `positions` (m) into `cache` ([`TetHessian::exact`], one SVD per
    /// element): what Newton's method takes near the solution, where the exact Hessian is
    /// positive definite and keeps its convergence quadratic (`docs/math.md` section 7.1.2).
    ///
    /// # Errors
    /// As [`projected_hessians`](TetMesh::projected_hessians); `cache` unchanged then.
    pub fn exact_hessians<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        check_positions(self.vertex_count(), positions)?;
        check_length(Buffer::Hessians, self.element_count(), cache.len())?;
        let elements = self.tets().iter().zip(self.rest());
        for ((corners, rest), slot) in elements.zip(cache.iter_mut()) {
            *slot = TetHessian::exact(material, rest, gather(positions, corners));
        }
        Ok(())
    }

    /// Adds `H d` (N) into `out`: the mesh Hessian represented by `cache` (from
    /// [`projected_hessians`](TetMesh::projected_hessians), or [`TetHessian::exact`] per element)
    /// times the per-vertex `direction` (m).
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] naming [`Buffer::Hessians`], [`Buffer::Direction`] or
    /// [`Buffer::Products`]; [`MeshError::NonFiniteDirection`] naming the first non-finite
    /// vertex of `direction`. On error, `out` is unchanged.
    pub fn add_hessian_product(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        check_length(Buffer::Hessians, self.element_count(), cache.len())?;
        check_length(Buffer::Direction, self.vertex_count(), direction.len())?;
        check_length(Buffer::Products, self.vertex_count(), out.len())?;
        check_finite(direction, |vertex| MeshError::NonFiniteDirection { vertex })?;
        dispatch(Product {
            tets: self.tets(),
            cache,
            direction,
            out,
            first: 0,
            dense: true,
        });
        Ok(())
    }

    /// Adds the 3x3 diagonal blocks of the mesh Hessian represented by `cache` (N/m; the sum of
    /// every element's block for the vertex, symmetric PSD for projected data) into `blocks`,
    /// one per vertex: the block-Jacobi preconditioner of Newton's method and the local systems
    /// of Vertex Block Descent.
    ///
    /// # Errors
    /// [`MeshError::LengthMismatch`] naming [`Buffer::Hessians`] or [`Buffer::Blocks`]. On
    /// error, `blocks` is unchanged.
    pub fn add_vertex_hessian_blocks(
        &self,
        cache: &[TetHessian],
        blocks: &mut [Mat3],
    ) -> Result<(), MeshError> {
        check_length(Buffer::Hessians, self.element_count(), cache.len())?;
        check_length(Buffer::Blocks, self.vertex_count(), blocks.len())?;
        let elements = self.tets().iter().zip(self.rest());
        for ((corners, rest), hessian) in elements.zip(cache) {
            for (corner, &vertex) in corners.iter().enumerate() {
                if let Some(block) = blocks.get_mut(vertex as usize) {
                    *block += hessian.vertex_block(rest, corner);
                }
            }
        }
        Ok(())
    }
}

/// How many groups ahead [`Product`] prefetches the cached entries (2 and 8 measured slower).
/// Measured at 105 456 tetrahedra on AMD Zen 4 (AVX-512), with the transposed gather: without
/// prefetch the product waits on the cache's loads, 35-36 ns per element in f64 (38 MB of
/// cache) against 20-22 with it, 13.8-14.9 against 13.1-13.5 in f32 (19 MB).
const PREFETCH_GROUPS: usize = 4;

/// How a lane type gathers the cached entries of a group of its width.
trait GatherEntries: LaneArray {
    /// The packed entries of the `Self::WIDTH` elements `group` (exactly that long), one group
    /// of lanes per entry: lane `i` of value `k` is entry `k` of `group[i]`. Value by value
    /// unless the lane type gathers blocks of entries ([`entry_block`](Self::entry_block)).
    #[inline(always)]
    fn gather_entries(group: &[TetHessian]) -> [Self; ENTRIES] {
        gather_by_lane(group)
    }

    /// Entries `start..start + 4` (`start <= 41`) of the `Self::WIDTH` elements whose packed
    /// entries are `flat` ([`flat_entries`]), for [`entries_by_block`]. Zeros here: only
    /// called by the lane types that override it.
    #[inline(always)]
    fn entry_block(flat: &[Real], start: usize) -> [Self; LANES] {
        let _ = (flat, start);
        [Self::splat(0.0); LANES]
    }
}

/// [`GatherEntries::gather_entries`] value by value.
#[inline(always)]
fn gather_by_lane<L: LaneArray>(group: &[TetHessian]) -> [L; ENTRIES] {
    core::array::from_fn(|k| {
        let mut values = L::ZEROS;
        for (lane, hessian) in group.iter().enumerate().take(L::WIDTH) {
            L::set_lane_value(&mut values, lane, hessian.packed_entry(k));
        }
        L::from_lane_array(values)
    })
}

/// [`gather_by_lane`] written out entry by entry, without a loop over the entries: fewer
/// instructions at 4 lanes (f64 AVX2: 243 per element against 308 under callgrind, 10 368
/// tetrahedra), but slower at 8 (f64 AVX-512: 22-23 ns per element against 18-20).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn gather_by_lane_unrolled<L: LaneArray>(group: &[TetHessian]) -> [L; ENTRIES] {
    let entry = |k: usize| {
        let mut values = L::ZEROS;
        for (lane, hessian) in group.iter().enumerate().take(L::WIDTH) {
            L::set_lane_value(&mut values, lane, hessian.packed_entry(k));
        }
        L::from_lane_array(values)
    };
    [
        entry(0),
        entry(1),
        entry(2),
        entry(3),
        entry(4),
        entry(5),
        entry(6),
        entry(7),
        entry(8),
        entry(9),
        entry(10),
        entry(11),
        entry(12),
        entry(13),
        entry(14),
        entry(15),
        entry(16),
        entry(17),
        entry(18),
        entry(19),
        entry(20),
        entry(21),
        entry(22),
        entry(23),
        entry(24),
        entry(25),
        entry(26),
        entry(27),
        entry(28),
        entry(29),
        entry(30),
        entry(31),
        entry(32),
        entry(33),
        entry(34),
        entry(35),
        entry(36),
        entry(37),
        entry(38),
        entry(39),
        entry(40),
        entry(41),
        entry(42),
        entry(43),
        entry(44),
    ]
}

/// The 45 entries of the elements whose packed entries are `flat`, from
/// [`GatherEntries::entry_block`] at 0, 4, ..., 40 and 41 (for entry 44): written out so that
/// the values stay in registers (a loop over the blocks measured slower: it went through a
/// buffer on the stack).
#[inline(always)]
fn entries_by_block<L: GatherEntries>(flat: &[Real]) -> [L; ENTRIES] {
    let [e0, e1, e2, e3] = L::entry_block(flat, 0);
    let [e4, e5, e6, e7] = L::entry_block(flat, 4);
    let [e8, e9, e10, e11] = L::entry_block(flat, 8);
    let [e12, e13, e14, e15] = L::entry_block(flat, 12);
    let [e16, e17, e18, e19] = L::entry_block(flat, 16);
    let [e20, e21, e22, e23] = L::entry_block(flat, 20);
    let [e24, e25, e26, e27] = L::entry_block(flat, 24);
    let [e28, e29, e30, e31] = L::entry_block(flat, 28);
    let [e32, e33, e34, e35] = L::entry_block(flat, 32);
    let [e36, e37, e38, e39] = L::entry_block(flat, 36);
    let [e40, e41, e42, e43] = L::entry_block(flat, 40);
    let [_, _, _, e44] = L::entry_block(flat, 41);
    [
        e0, e1, e2, e3, e4, e5, e6, e7, e8, e9, e10, e11, e12, e13, e14, e15, e16, e17, e18, e19,
        e20, e21, e22, e23, e24, e25, e26, e27, e28, e29, e30, e31, e32, e33, e34, e35, e36, e37,
        e38, e39, e40, e41, e42, e43, e44,
    ]
}

/// The packed entries of `group` as one flat slice, `ENTRIES` numbers per element.
#[inline(always)]
fn flat_entries(group: &[TetHessian]) -> &[Real] {
    // SAFETY: `TetHessian` is `repr(transparent)` over `StressDerivative`, itself transparent
    // over `[Real; ENTRIES]` (the size is asserted in element/hessian.rs), so a slice of them
    // is `ENTRIES` initialised numbers per element, contiguous, borrowed as long as `group`.
    unsafe { core::slice::from_raw_parts(group.as_ptr().cast::<Real>(), group.len() * ENTRIES) }
}

/// Entries `start..start + 4` of element `element` of `flat`, as [`Lanes`] (zeros out of
/// range, which the callers never ask for).
#[inline(always)]
fn entry_row(flat: &[Real], element: usize, start: usize) -> Lanes {
    let first = element * ENTRIES + start;
    flat.get(first..first + LANES)
        .and_then(|row| <[Real; LANES]>::try_from(row).ok())
        .map_or(Lanes::splat(0.0), Lanes::from_array)
}

/// Four elements: one 4x4 transpose per block of four entries.
impl GatherEntries for Lanes {
    #[inline(always)]
    fn gather_entries(group: &[TetHessian]) -> [Self; ENTRIES] {
        entries_by_block(flat_entries(group))
    }

    #[inline(always)]
    fn entry_block(flat: &[Real], start: usize) -> [Self; LANES] {
        transpose4([
            entry_row(flat, 0, start),
            entry_row(flat, 1, start),
            entry_row(flat, 2, start),
            entry_row(flat, 3, start),
        ])
    }
}

/// Entries `start..start + 4` of element `element` of `flat` as four f32 (16 bytes: in f64,
/// half of the four entries; never called there), zeros out of range (never).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn f32_row(flat: &[Real], element: usize, start: usize) -> core::arch::x86_64::__m128 {
    use core::arch::x86_64::{_mm_loadu_ps, _mm_setzero_ps};
    let first = element * ENTRIES + start;
    // SAFETY: SSE (always there on x86_64); the slice holds 16 bytes or more (four numbers).
    unsafe {
        match flat.get(first..first + LANES) {
            Some(row) => _mm_loadu_ps(row.as_ptr().cast::<f32>()),
            None => _mm_setzero_ps(),
        }
    }
}

/// The f32 AVX lanes gather four entries of four elements per 128-bit lane: one unaligned
/// 4-value load per element (the 128-bit lanes of a register hold rows of the group's
/// quarters), then a 4x4 transpose within the 128-bit lanes. In f64 they gather value by
/// value, through `$fallback` (the test of the size of `Real` is decided at compile time).
#[cfg(target_arch = "x86_64")]
macro_rules! avx_gather_entries {
    ($lanes:ty, $width:expr, $fallback:ident, $reg:ty, $rows:ident, $lo:ident, $hi:ident,
     $lo_pd:ident, $hi_pd:ident, $to_pd:ident, $from_pd:ident, $store:ident) => {
        impl GatherEntries for $lanes {
            #[inline(always)]
            fn gather_entries(group: &[TetHessian]) -> [Self; ENTRIES] {
                match group.first_chunk::<{ $width }>() {
                    Some(group) if core::mem::size_of::<Real>() == 4 => {
                        entries_by_block(flat_entries(group))
                    }
                    _ => $fallback(group),
                }
            }

            #[inline(always)]
            fn entry_block(flat: &[Real], start: usize) -> [Self; LANES] {
                use core::arch::x86_64::*;
                // SAFETY: AVX-512F / AVX intrinsics on register values, inlined into the
                // kernels that `simd::dispatch` runs after detecting them.
                let columns = unsafe {
                    let (r0, r1, r2, r3) = (
                        $rows(flat, 0, start),
                        $rows(flat, 1, start),
                        $rows(flat, 2, start),
                        $rows(flat, 3, start),
                    );
                    let t0 = $to_pd($lo(r0, r1));
                    let t1 = $to_pd($hi(r0, r1));
                    let t2 = $to_pd($lo(r2, r3));
                    let t3 = $to_pd($hi(r2, r3));
                    [
                        $from_pd($lo_pd(t0, t2)),
                        $from_pd($hi_pd(t0, t2)),
                        $from_pd($lo_pd(t1, t3)),
                        $from_pd($hi_pd(t1, t3)),
                    ]
                };
                let mut out = [Self::splat(0.0); LANES];
                for (slot, column) in out.iter_mut().zip(columns) {
                    let mut values = <$lanes as LaneArray>::ZEROS;
                    // SAFETY: as above; `values` is `$width` numbers: the register's size in
                    // f32 (half the array in f64, never called), in bounds either way.
                    unsafe { $store((&raw mut values).cast::<f32>(), column) };
                    *slot = <$lanes>::from_lane_array(values);
                }
                out
            }
        }
    };
}

/// The rows of elements `j` and `4 + j` (the 128-bit lanes of an AVX register) at `start`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn rows256(flat: &[Real], j: usize, start: usize) -> core::arch::x86_64::__m256 {
    use core::arch::x86_64::{_mm256_castps128_ps256, _mm256_insertf128_ps};
    // SAFETY: the caller runs with AVX.
    unsafe {
        let low = _mm256_castps128_ps256(f32_row(flat, j, start));
        _mm256_insertf128_ps::<1>(low, f32_row(flat, 4 + j, start))
    }
}

/// The rows of elements `j`, `4 + j`, `8 + j` and `12 + j` (the 128-bit lanes of an AVX-512
/// register) at `start`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn rows512(flat: &[Real], j: usize, start: usize) -> core::arch::x86_64::__m512 {
    use core::arch::x86_64::{_mm512_castps128_ps512, _mm512_insertf32x4};
    // SAFETY: the caller runs with AVX-512F.
    unsafe {
        let r = _mm512_castps128_ps512(f32_row(flat, j, start));
        let r = _mm512_insertf32x4::<1>(r, f32_row(flat, 4 + j, start));
        let r = _mm512_insertf32x4::<2>(r, f32_row(flat, 8 + j, start));
        _mm512_insertf32x4::<3>(r, f32_row(flat, 12 + j, start))
    }
}

#[cfg(target_arch = "x86_64")]
avx_gather_entries!(
    Avx2Lanes,
    8,
    gather_by_lane_unrolled,
    __m256,
    rows256,
    _mm256_unpacklo_ps,
    _mm256_unpackhi_ps,
    _mm256_unpacklo_pd,
    _mm256_unpackhi_pd,
    _mm256_castps_pd,
    _mm256_castpd_ps,
    _mm256_storeu_ps
);
#[cfg(target_arch = "x86_64")]
avx_gather_entries!(
    Avx512Lanes,
    16,
    gather_by_lane,
    __m512,
    rows512,
    _mm512_unpacklo_ps,
    _mm512_unpackhi_ps,
    _mm512_unpacklo_pd,
    _mm512_unpackhi_pd,
    _mm512_castps_pd,
    _mm512_castpd_ps,
    _mm512_storeu_ps
);

/// The element loop of [`TetMesh::add_hessian_product`] at the width [`dispatch`] picks: whole
/// groups of the widest lanes first, then narrower ones, then one element at a time (as the
/// force passes). A group gathers its direction as the force passes gather positions (SSE
/// transposes of four elements at a time) and its cached entries through register transposes
/// ([`GatherEntries`]; the entries of the groups ahead are prefetched), and every lane runs
/// [`TetHessian::product`]'s arithmetic in its order; the products are added at the corners
/// element by element and corner by corner in order, as the force passes scatter. So every
/// width gives the bits of the one-at-a-time loop.
///
/// `out` holds the products of the vertices from `first` on (0 for the whole mesh; an owner
/// piece's slice in a partition, `partition/hessian.rs`): corners outside it are skipped. Unless
/// `dense` (every element touches `out`), elements that touch none of its vertices are skipped
/// one at a time, and groups where none does.
pub(super) struct Product<'k> {
    pub tets: &'k [[u32; 4]],
    pub cache: &'k [TetHessian],
    pub direction: &'k [Vec3],
    pub out: &'k mut [Vec3],
    pub first: usize,
    pub dense: bool,
}

impl Product<'_> {
    /// Whether some corner is one of `out`'s vertices (below `first` the index wraps past any
    /// slice length).
    #[inline(always)]
    fn touches(&self, corners: &[u32; 4]) -> bool {
        corners
            .iter()
            .any(|&v| (v as usize).wrapping_sub(self.first) < self.out.len())
    }

    /// Adds `value` at vertex `vertex` if it is one of `out`'s.
    #[inline(always)]
    fn add(&mut self, vertex: u32, value: Vec3) {
        if let Some(slot) = self.out.get_mut((vertex as usize).wrapping_sub(self.first)) {
            *slot += value;
        }
    }

    /// The whole groups of `L::WIDTH` elements from element `first` on; returns the first
    /// element after them.
    #[inline(always)]
    fn groups<L: GatherEntries>(&mut self, first: usize) -> usize {
        let width = L::WIDTH;
        let tets = self.tets.get(first..).unwrap_or(&[]);
        let cache = self.cache.get(first..).unwrap_or(&[]);
        let whole = tets.len() - tets.len() % width;
        // Nothing to read without a direction (never: the mesh checked its length).
        let Some(direction) = Positions::new(self.direction) else {
            return first;
        };
        let groups = tets.get(..whole).unwrap_or(&[]).chunks_exact(width);
        for (group, corners) in groups.enumerate() {
            // Indexed rather than a second `chunks_exact` zipped in: no division check.
            let Some(hessians) = cache.get(group * width..(group + 1) * width) else {
                break;
            };
            prefetch(cache, (group + PREFETCH_GROUPS) * width, width);
            if !self.dense && !corners.iter().any(|tet| self.touches(tet)) {
                continue;
            }
            // The direction at the corners, `[corner][axis]`, one value per lane, through the
            // force passes' SSE transposes of four elements at a time.
            let v = gather_corners::<L>(direction, corners);
            let lanes = |[x, y, z]: [L::Array; 3]| {
                [
                    L::from_lane_array(x),
                    L::from_lane_array(y),
                    L::from_lane_array(z),
                ]
            };
            let [v0, v1, v2, v3] = v;
            let entries = L::gather_entries(hessians);
            let entry = |k: usize| entries.get(k).copied().unwrap_or(L::splat(0.0));
            let h = TetHessian::lanes_product(entry, [lanes(v0), lanes(v1), lanes(v2), lanes(v3)]);
            let arrays =
                |[x, y, z]: [L; 3]| [x.to_lane_array(), y.to_lane_array(), z.to_lane_array()];
            let [h0, h1, h2, h3] = h;
            let h = [arrays(h0), arrays(h1), arrays(h2), arrays(h3)];
            scatter_corners::<L>(&h, corners, |i, value| self.add(i, value));
        }
        first + whole
    }

    /// The elements from `first` on, one at a time.
    #[inline(always)]
    fn singles(&mut self, first: usize) {
        let tets = self.tets.get(first..).unwrap_or(&[]);
        let cache = self.cache.get(first..).unwrap_or(&[]);
        for (corners, hessian) in tets.iter().zip(cache) {
            if !self.dense && !self.touches(corners) {
                continue;
            }
            let v = gather(self.direction, corners);
            let [v0, v1, v2, v3] = v;
            let [h0, h1, h2, h3] = TetHessian::lanes_product(
                |k| hessian.packed_entry(k),
                [v0.to_array(), v1.to_array(), v2.to_array(), v3.to_array()],
            );
            let h = [
                Vec3::from_array(h0),
                Vec3::from_array(h1),
                Vec3::from_array(h2),
                Vec3::from_array(h3),
            ];
            for (&i, value) in corners.iter().zip(h) {
                self.add(i, value);
            }
        }
    }
}

impl WidthKernel for Product<'_> {
    type Output = ();

    #[inline(always)]
    fn scalar(mut self) {
        self.singles(0);
    }

    #[inline(always)]
    fn sse(mut self) {
        let first = self.groups::<Lanes>(0);
        self.singles(first);
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx2(mut self) {
        let first = self.groups::<Avx2Lanes>(0);
        let first = self.groups::<Lanes>(first);
        self.singles(first);
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx512(mut self) {
        let first = self.groups::<Avx512Lanes>(0);
        let first = self.groups::<Avx2Lanes>(first);
        let first = self.groups::<Lanes>(first);
        self.singles(first);
    }
}

/// Generates the Hessian kernels of a triangle mesh type.
macro_rules! triangle_mesh_hessian {
    ($mesh:ident, $vector:ident, $hessian:ident, $block:ident) => {
        impl $mesh<'_> {
            /// Writes the projected (SPD) Hessian data of every triangle of `material` at
            /// deformed `positions` (m) into `cache` (one per element, overwritten).
            ///
            /// # Errors
            /// As [`TetMesh::projected_hessians`]: lengths of `positions` and `cache`, non-finite
            /// positions; `cache` unchanged then.
            pub fn projected_hessians(
                &self,
                material: &TriangleStVK,
                positions: &[$vector],
                cache: &mut [$hessian],
            ) -> Result<(), MeshError> {
                check_positions(self.vertex_count(), positions)?;
                check_length(Buffer::Hessians, self.element_count(), cache.len())?;
                let elements = self.tris().iter().zip(self.rest());
                for ((corners, rest), slot) in elements.zip(cache.iter_mut()) {
                    *slot = $hessian::new(material, rest, gather(positions, corners));
                }
                Ok(())
            }

            /// Adds `H d` into `out` for the Hessian in `cache` and the per-vertex `direction`.
            ///
            /// # Errors
            /// As [`TetMesh::add_hessian_product`]; `out` unchanged then.
            pub fn add_hessian_product(
                &self,
                cache: &[$hessian],
                direction: &[$vector],
                out: &mut [$vector],
            ) -> Result<(), MeshError> {
                check_length(Buffer::Hessians, self.element_count(), cache.len())?;
                check_length(Buffer::Direction, self.vertex_count(), direction.len())?;
                check_length(Buffer::Products, self.vertex_count(), out.len())?;
                check_finite(direction, |vertex| MeshError::NonFiniteDirection { vertex })?;
                let elements = self.tris().iter().zip(cache);
                for (corners, hessian) in elements {
                    scatter_add(out, corners, hessian.product(gather(direction, corners)));
                }
                Ok(())
            }

            /// Adds the diagonal blocks of the Hessian in `cache` into `blocks`, one per vertex.
            ///
            /// # Errors
            /// As [`TetMesh::add_vertex_hessian_blocks`]; `blocks` unchanged then.
            pub fn add_vertex_hessian_blocks(
                &self,
                cache: &[$hessian],
                blocks: &mut [$block],
            ) -> Result<(), MeshError> {
                check_length(Buffer::Hessians, self.element_count(), cache.len())?;
                check_length(Buffer::Blocks, self.vertex_count(), blocks.len())?;
                for (corners, hessian) in self.tris().iter().zip(cache) {
                    for (corner, &vertex) in corners.iter().enumerate() {
                        if let Some(block) = blocks.get_mut(vertex as usize) {
                            *block += hessian.vertex_block(corner);
                        }
                    }
                }
                Ok(())
            }
        }
    };
}

triangle_mesh_hessian!(TriMesh, Vec2, TriHessian, Mat2);
triangle_mesh_hessian!(MembraneMesh, Vec3, MembraneHessian, Mat3);

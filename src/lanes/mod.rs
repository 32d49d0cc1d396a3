//! One numeric algorithm, run on one value or on several at once.
//!
//! The SVD (and later kernels) are written once against `Lane`: implemented by the plain scalar
//! [`Real`] and by [`Lanes`], a fixed group of independent values that the compiler maps onto
//! SIMD registers. Every operation is element-wise and IEEE-correctly rounded in both, so a value
//! computed in lane `i` is bit-for-bit the value the scalar code computes for the same input.
//! Comparisons give masks and conditionals are selects, so no lane ever branches.

use super::math;
use super::types::{Mat3, Real, Vec3};
use core::ops::{Add, Div, Mul, Neg, Sub};

pub(crate) use super::lane_repr::transpose4;
pub use super::lane_repr::{LaneMask, Lanes, transpose_vec3, untranspose_vec3};

/// One AVX register of values (x86_64, run with AVX2 by `simd::dispatch`).
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2;

/// One AVX-512 register of values (x86_64, run with AVX-512F by `simd::dispatch`).
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx512;

// The per-vertex arithmetic of one vertex and of a group (`Point`, `Grouped`, `Wide`): the
// hidden half of the sealed `element::Vector`.
pub(crate) mod point;

/// Number of values a [`Lanes`] holds: 4 in both precisions (one SSE register of f32, two of f64).
pub const LANES: usize = math::LANES;

/// `f` of each of the [`LANES`] values, in order. `<[T; N]>::map` is not always inlined (it
/// goes through a fallible helper), and a call in the middle of a force kernel costs more than
/// the kernel's arithmetic; this is.
#[inline(always)]
pub(crate) fn each_lane<T, U>(values: [T; LANES], mut f: impl FnMut(T) -> U) -> [U; LANES] {
    let [a, b, c, d] = values;
    [f(a), f(b), f(c), f(d)]
}

mod sealed {
    use super::{LaneArray, Real};

    /// Only this crate's number types implement [`Lane`](super::Lane). Lane-by-lane access
    /// lives here, out of reach of other crates, for the provided methods of
    /// [`Material`](super::super::material::Material) that fall back to one value at a time.
    pub trait Sealed: Sized {
        /// Values per group: 1 for a scalar.
        const WIDTH: usize;
        /// The value of lane `lane` (zero past the last lane).
        fn value_of_lane(self, lane: usize) -> Real;
        /// The group whose lane `i` holds `value(i)`.
        fn from_lane_fn(value: impl FnMut(usize) -> Real) -> Self;
    }

    impl Sealed for Real {
        const WIDTH: usize = 1;
        #[inline(always)]
        fn value_of_lane(self, lane: usize) -> Real {
            if lane == 0 { self } else { 0.0 }
        }
        #[inline(always)]
        fn from_lane_fn(mut value: impl FnMut(usize) -> Real) -> Self {
            value(0)
        }
    }

    /// [`Sealed`] of a [`LaneArray`] type, through its array of values.
    macro_rules! sealed_by_array {
        ($lanes:ty, $width:expr) => {
            impl Sealed for $lanes {
                const WIDTH: usize = $width;
                #[inline(always)]
                fn value_of_lane(self, lane: usize) -> Real {
                    <$lanes as LaneArray>::lane_value(&self.to_lane_array(), lane)
                }
                #[inline(always)]
                fn from_lane_fn(mut value: impl FnMut(usize) -> Real) -> Self {
                    let mut values = <$lanes as LaneArray>::ZEROS;
                    for lane in 0..$width {
                        <$lanes as LaneArray>::set_lane_value(&mut values, lane, value(lane));
                    }
                    <$lanes as LaneArray>::from_lane_array(values)
                }
            }
        };
    }
    sealed_by_array!(super::Lanes, super::LANES);
    #[cfg(target_arch = "x86_64")]
    sealed_by_array!(super::avx2::Avx2Lanes, super::super::wide_ops::AVX2_WIDTH);
    #[cfg(target_arch = "x86_64")]
    sealed_by_array!(
        super::avx512::Avx512Lanes,
        super::super::wide_ops::AVX512_WIDTH
    );

    impl<L: super::Lane> Sealed for super::LanePair<L> {
        const WIDTH: usize = 2 * L::WIDTH;
        #[inline(always)]
        fn value_of_lane(self, lane: usize) -> Real {
            match lane.checked_sub(L::WIDTH) {
                None => self.0.value_of_lane(lane),
                Some(upper) => self.1.value_of_lane(upper),
            }
        }
        #[inline(always)]
        fn from_lane_fn(mut value: impl FnMut(usize) -> Real) -> Self {
            let lower = L::from_lane_fn(&mut value);
            let upper = L::from_lane_fn(|lane| value(lane + L::WIDTH));
            super::LanePair(lower, upper)
        }
    }
}

/// The widest group any lane type has (32 f32 in a pair of AVX-512 registers).
pub(crate) const MAX_WIDTH: usize = 32;

/// The matrix in lane `lane` of `m`.
#[inline(always)]
pub(crate) fn lane_mat3<L: Lane>(m: &LaneMat3<L>, lane: usize) -> Mat3 {
    let v = |c: &LaneVec3<L>| {
        Vec3::new(
            c.x.value_of_lane(lane),
            c.y.value_of_lane(lane),
            c.z.value_of_lane(lane),
        )
    };
    Mat3::from_cols(v(&m.c0), v(&m.c1), v(&m.c2))
}

/// `each` of the matrix in every lane of `m`, one lane at a time, back in lanes: the provided
/// methods of [`Material`](super::material::Material) for lane groups of any width.
#[inline(always)]
pub(crate) fn map_lane_matrices<L: Lane>(
    m: LaneMat3<L>,
    mut each: impl FnMut(Mat3) -> (Real, Mat3),
) -> (L, LaneMat3<L>) {
    map_lanes(|lane| each(lane_mat3(&m, lane)))
}

/// `each(lane)` for every lane of `L`, one lane at a time, back in lanes.
#[inline(always)]
pub(crate) fn map_lanes<L: Lane>(mut each: impl FnMut(usize) -> (Real, Mat3)) -> (L, LaneMat3<L>) {
    let mut results = [(0.0, [0.0; 9]); MAX_WIDTH];
    for (lane, slot) in results.iter_mut().enumerate().take(L::WIDTH) {
        let (value, matrix) = each(lane);
        *slot = (value, matrix.to_cols_array());
    }
    let entry = |k: usize| {
        L::from_lane_fn(|lane| {
            results
                .get(lane)
                .and_then(|(_, entries)| entries.get(k))
                .copied()
                .unwrap_or(0.0)
        })
    };
    let column = |c: usize| LaneVec3::new(entry(3 * c), entry(3 * c + 1), entry(3 * c + 2));
    let values = L::from_lane_fn(|lane| results.get(lane).map_or(0.0, |(value, _)| *value));
    (
        values,
        LaneMat3 {
            c0: column(0),
            c1: column(1),
            c2: column(2),
        },
    )
}

/// The vector in lane `lane` of `v` (zero past the last lane).
#[inline(always)]
pub(crate) fn lane_vec3<L: Lane>(v: &LaneVec3<L>, lane: usize) -> Vec3 {
    Vec3::new(
        v.x.value_of_lane(lane),
        v.y.value_of_lane(lane),
        v.z.value_of_lane(lane),
    )
}

/// `each(lane)` for every lane of `L`, one lane at a time (each once), back in lanes: the
/// colliders' queries of groups of vertices of any width.
#[inline(always)]
pub(crate) fn map_lane_vectors<L: Lane>(mut each: impl FnMut(usize) -> Vec3) -> LaneVec3<L> {
    let mut results = [Vec3::ZERO; MAX_WIDTH];
    for (lane, slot) in results.iter_mut().enumerate().take(L::WIDTH) {
        *slot = each(lane);
    }
    let at = |lane: usize| results.get(lane).copied().unwrap_or(Vec3::ZERO);
    LaneVec3::new(
        L::from_lane_fn(|lane| at(lane).x),
        L::from_lane_fn(|lane| at(lane).y),
        L::from_lane_fn(|lane| at(lane).z),
    )
}

/// The SVDs of a group of matrices, one per lane, as [`svd3`](super::svd::svd3) returns them
/// ([`Svd3`](super::svd::Svd3)): lane `i` of each field is the field of lane `i`'s
/// decomposition. What the principal-path force kernels hand to
/// [`Material::first_piola_from_svd_wide`](super::material::Material::first_piola_from_svd_wide).
#[derive(Clone, Copy)]
pub struct LaneSvd3<L> {
    /// Left singular vectors as columns (a proper rotation in every lane).
    pub u: LaneMat3<L>,
    /// Signed singular values, `sigma.x >= sigma.y >= |sigma.z|` in every lane.
    pub sigma: LaneVec3<L>,
    /// Right singular vectors as columns (a proper rotation in every lane).
    pub v: LaneMat3<L>,
}

impl<L: Lane> LaneSvd3<L> {
    /// The decomposition in lane `lane`.
    #[inline(always)]
    #[must_use]
    pub fn lane(&self, lane: usize) -> super::svd::Svd3 {
        let sigma = &self.sigma;
        super::svd::Svd3 {
            u: lane_mat3(&self.u, lane),
            sigma: Vec3::new(
                sigma.x.value_of_lane(lane),
                sigma.y.value_of_lane(lane),
                sigma.z.value_of_lane(lane),
            ),
            v: lane_mat3(&self.v, lane),
        }
    }
}

/// `each` of the matrix and vector in every lane of `(m, v)`, one lane at a time, back in
/// lanes: the provided corner kernel of [`Material`](super::material::Material) for lane
/// groups of any width.
#[inline(always)]
pub(crate) fn map_lane_corners<L: Lane>(
    m: LaneMat3<L>,
    v: LaneVec3<L>,
    mut each: impl FnMut(Mat3, Vec3) -> (Vec3, Mat3),
) -> (LaneVec3<L>, LaneMat3<L>) {
    let mut results = [[0.0; 12]; MAX_WIDTH];
    for (lane, slot) in results.iter_mut().enumerate().take(L::WIDTH) {
        let vector = Vec3::new(
            v.x.value_of_lane(lane),
            v.y.value_of_lane(lane),
            v.z.value_of_lane(lane),
        );
        let (stress, matrix) = each(lane_mat3(&m, lane), vector);
        let [c0, c1, c2] = [matrix.x_axis, matrix.y_axis, matrix.z_axis];
        *slot = [
            stress.x, stress.y, stress.z, c0.x, c0.y, c0.z, c1.x, c1.y, c1.z, c2.x, c2.y, c2.z,
        ];
    }
    let entry = |k: usize| {
        L::from_lane_fn(|lane| {
            results
                .get(lane)
                .and_then(|entries| entries.get(k))
                .copied()
                .unwrap_or(0.0)
        })
    };
    let vector = |k: usize| LaneVec3::new(entry(k), entry(k + 1), entry(k + 2));
    (
        vector(0),
        LaneMat3 {
            c0: vector(3),
            c1: vector(6),
            c2: vector(9),
        },
    )
}

/// A sum over `n` items (vertices, elements) in a fixed order, grouped or not: item `i` of the
/// first `n - n % LANES` adds to partial sum `i % LANES`, the partial sums are added as
/// `(s0 + s1) + (s2 + s3)`, then the last `n % LANES` terms in order. Groups add one term per
/// lane to the partial sums (wider groups quarter by quarter), so a grouped pass and a
/// one-at-a-time pass give the same bits.
///
/// The partial sums are separate fields, not an array indexed by `i % LANES`, which would keep
/// the whole sum, the grouped loop's running sum included, in memory rather than in registers.
#[derive(Clone, Copy)]
pub(crate) struct LaneSum {
    /// The partial sums of the groups.
    lanes: Lanes,
    /// The partial sums of whole-group items taken one at a time, by lane.
    single: (Real, Real, Real, Real),
    /// The terms after the whole groups.
    tail: Real,
    /// `n - n % LANES`.
    whole: usize,
}

impl LaneSum {
    /// Zero, for a sum over `n` items.
    #[inline(always)]
    pub fn new(n: usize) -> Self {
        LaneSum {
            lanes: Lanes::splat(0.0),
            single: (0.0, 0.0, 0.0, 0.0),
            tail: 0.0,
            whole: n - n % LANES,
        }
    }

    /// Adds one term per lane of a group of `L::WIDTH` items (a multiple of [`LANES`]; the
    /// first item at a multiple of [`LANES`]): its quarters one after another, lanes `0..4`
    /// first, so that every partial sum still takes its items in order and the total has the
    /// bits of [`add_single`](Self::add_single) on each item.
    #[inline(always)]
    pub fn add_wide<L: LaneArray>(&mut self, terms: L) {
        const { assert!(L::WIDTH.is_multiple_of(LANES)) };
        let values = terms.to_lane_array();
        for q in 0..L::WIDTH / LANES {
            self.lanes = self.lanes + L::quarter(&values, q);
        }
    }

    /// Adds the term of item `i`, taken one at a time.
    #[inline(always)]
    pub fn add_single(&mut self, i: usize, term: Real) {
        if i >= self.whole {
            self.tail += term;
            return;
        }
        let single = &mut self.single;
        match i % LANES {
            0 => single.0 += term,
            1 => single.1 += term,
            2 => single.2 += term,
            _ => single.3 += term,
        }
    }

    /// The total.
    #[inline(always)]
    pub fn total(self) -> Real {
        // One of `lanes` and `single` holds the partial sums, the other zeros.
        let (s0, s1, s2, s3) = self.single;
        let [a, b, c, d] = (self.lanes + Lanes::from_array([s0, s1, s2, s3])).to_array();
        ((a + b) + (c + d)) + self.tail
    }
}

/// A scalar-like number type: [`Real`] itself or a group of [`Lanes`]. Sealed: implemented by
/// this crate's two types only.
pub trait Lane:
    sealed::Sealed
    + Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// The result of a comparison: `bool` for a scalar, one flag per lane otherwise.
    type Mask: Copy;
    /// Every lane equal to `x`.
    fn splat(x: Real) -> Self;
    /// Correctly rounded square root.
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// The larger of two values (`other` when `self` is NaN).
    fn max(self, other: Self) -> Self;
    /// `+1` or `-1` with the sign bit of `self`.
    fn sign(self) -> Self;
    /// `self > other`, per lane.
    fn gt(self, other: Self) -> Self::Mask;
    /// `self >= other`, per lane.
    fn ge(self, other: Self) -> Self::Mask;
    /// Whether no lane of `mask` is set.
    fn none(mask: Self::Mask) -> bool;
    /// `mask ? a : b`, per lane, without branching.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
    /// `f` of every lane, one at a time (for the few functions without a lane-wide form:
    /// logarithms, cube roots).
    fn map(self, f: impl Fn(Real) -> Real) -> Self;
}

impl Lane for Real {
    type Mask = bool;

    #[inline(always)]
    fn splat(x: Real) -> Self {
        x
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        math::sqrt(self)
    }

    #[inline(always)]
    fn abs(self) -> Self {
        Real::abs(self)
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        Real::max(self, other)
    }

    #[inline(always)]
    fn sign(self) -> Self {
        (1.0 as Real).copysign(self)
    }

    #[inline(always)]
    fn gt(self, other: Self) -> bool {
        self > other
    }

    #[inline(always)]
    fn ge(self, other: Self) -> bool {
        self >= other
    }

    #[inline(always)]
    fn none(mask: bool) -> bool {
        !mask
    }

    #[inline(always)]
    fn select(mask: bool, a: Self, b: Self) -> Self {
        math::select(mask, a, b)
    }

    #[inline(always)]
    fn map(self, f: impl Fn(Real) -> Real) -> Self {
        f(self)
    }
}

/// A [`Lane`] type as a fixed array of its values: how batched kernels load and store a group of
/// any width (4 for [`Lanes`], more for the AVX lanes of `simd`'s wider widths and for
/// [`LanePair`]s).
pub(crate) trait LaneArray: Lane {
    /// The values of a group, lane by lane.
    type Array: Copy;
    /// An array of zeros.
    const ZEROS: Self::Array;
    /// The group holding `values`.
    fn from_lane_array(values: Self::Array) -> Self;
    /// The values of the lanes.
    fn to_lane_array(self) -> Self::Array;
    /// The group holding the first `WIDTH` values of `values` (one load); `None` if there are
    /// fewer.
    fn from_slice(values: &[Real]) -> Option<Self>;
    /// The value of lane `lane` (zero past the last lane).
    fn lane_value(values: &Self::Array, lane: usize) -> Real;
    /// Sets the value of lane `lane` (nothing past the last lane).
    fn set_lane_value(values: &mut Self::Array, lane: usize, value: Real);
    /// `2^floor(log2 |x|)` of every lane `x` holding a normal number: its exponent field
    /// alone (sign and fraction bits cleared), exact.
    #[inline(always)]
    fn exponent_part(self) -> Self {
        self.map(|x| Real::from_bits(x.to_bits() & Real::INFINITY.to_bits()))
    }
    /// Lanes `4 q..4 q + 4` of `values` as a group of [`Lanes`] (zero past the last lane).
    #[inline(always)]
    fn quarter(values: &Self::Array, q: usize) -> Lanes {
        Lanes::from_array(core::array::from_fn(|j| {
            Self::lane_value(values, q * LANES + j)
        }))
    }
    /// Sets lanes `4 q..4 q + 4` of `values` to `quarter` (nothing past the last lane).
    #[inline(always)]
    fn set_quarter(values: &mut Self::Array, q: usize, quarter: Lanes) {
        for (j, value) in quarter.to_array().into_iter().enumerate() {
            Self::set_lane_value(values, q * LANES + j, value);
        }
    }
    /// The group whose lanes `4 q..4 q + 4` hold `quarters[q]` (quarters past the width are
    /// ignored): how the vertex passes build a wide group from 4-lane transposes, which the
    /// compiler keeps in registers (lane-by-lane stores measured slower than the SSE lanes).
    #[inline(always)]
    fn from_quarters(quarters: [[Real; LANES]; 4]) -> Self {
        let mut values = Self::ZEROS;
        for (q, quarter) in quarters.iter().enumerate().take(Self::WIDTH / LANES) {
            for (j, &value) in quarter.iter().enumerate() {
                Self::set_lane_value(&mut values, q * LANES + j, value);
            }
        }
        Self::from_lane_array(values)
    }
    /// Sets lanes `4 q..4 q + 4` of `values` to `quarter` (nothing past the last lane) as
    /// [`set_quarter`](Self::set_quarter) does, in one store of the quarter's register.
    #[inline(always)]
    fn store_quarter(values: &mut Self::Array, q: usize, quarter: Lanes) {
        Self::set_quarter(values, q, quarter);
    }
    /// The first `WIDTH` vectors of `chunk` as lanes of coordinates (lane `i` holds
    /// `chunk[i]`), where this lane type has a faster way than 4-lane transposes; `None` where
    /// it has not, or `chunk` is shorter. Moves bits only.
    #[inline(always)]
    fn load_vec3s(_chunk: &[Vec3]) -> Option<LaneVec3<Self>> {
        None
    }
    /// The inverse of [`load_vec3s`](Self::load_vec3s): writes lane `i` of `v` as `chunk[i]`
    /// for the first `WIDTH` vectors and returns `true`, or writes nothing and returns `false`.
    #[inline(always)]
    fn store_vec3s(_v: LaneVec3<Self>, _chunk: &mut [Vec3]) -> bool {
        false
    }
}

/// `f` of each lane of `lanes`, in order, through its array of values (the lane types held in
/// registers, whose intrinsics have no `map`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn map_lane_array<L: LaneArray<Array = [Real; N]>, const N: usize>(
    lanes: L,
    f: impl Fn(Real) -> Real,
) -> L {
    let mut values = lanes.to_lane_array();
    for value in &mut values {
        *value = f(*value);
    }
    L::from_lane_array(values)
}

/// The items every lane type held in one x86_64 register shares, written once: the arithmetic
/// operators from their packed intrinsics (`binary_ops`), the ordered comparisons of
/// [`Lane`] from a compare intrinsic taking the predicate as a const generic (`compare`), and
/// the [`LaneArray`] items of a register of `WIDTH` values (`array`). Each arm expands to
/// the items alone, for the `impl` blocks of `sse.rs`, `avx2.rs` and `avx512.rs`; every
/// `unsafe` block calls only intrinsics on register values, under the caller's module comment.
/// [`Lane::map`] through the lanes' array (`map`) serves the f64 lanes in two registers of
/// `sse2_f64.rs` too, and so do their operators (`pair_binary_ops`: the intrinsic on both
/// registers through that file's `pairwise`).
#[cfg(target_arch = "x86_64")]
macro_rules! register_lanes {
    (map) => {
        #[inline(always)]
        fn map(self, f: impl Fn(Real) -> Real) -> Self {
            map_lane_array(self, f)
        }
    };
    (pair_binary_ops $lanes:ident: $($trait:ident $method:ident $intrinsic:ident),*) => {
        $(
            impl $trait for $lanes {
                type Output = $lanes;
                #[inline(always)]
                fn $method(self, other: $lanes) -> $lanes {
                    // SAFETY: see the module comment.
                    $lanes(pairwise(self.0, other.0, |a, b| unsafe { $intrinsic(a, b) }))
                }
            }
        )*
    };
    (binary_ops $lanes:ident: $($trait:ident $method:ident $intrinsic:ident),*) => {
        $(
            impl $trait for $lanes {
                type Output = $lanes;
                #[inline(always)]
                fn $method(self, other: $lanes) -> $lanes {
                    // SAFETY: see the module comment.
                    $lanes(unsafe { $intrinsic(self.0, other.0) })
                }
            }
        )*
    };
    (compare $mask:ident: $cmp:ident) => {
        #[inline(always)]
        fn gt(self, other: Self) -> $mask {
            // SAFETY: see the module comment. Ordered: false where either lane is NaN.
            $mask(unsafe { $cmp::<_CMP_GT_OQ>(self.0, other.0) })
        }

        #[inline(always)]
        fn ge(self, other: Self) -> $mask {
            // SAFETY: see the module comment. Ordered: false where either lane is NaN.
            $mask(unsafe { $cmp::<_CMP_GE_OQ>(self.0, other.0) })
        }
    };
    (array $lanes:ident: $reg:ty, $width:expr) => {
        type Array = [Real; $width];
        const ZEROS: Self::Array = [0.0; $width];

        #[inline(always)]
        fn from_lane_array(values: Self::Array) -> Self {
            // SAFETY: the array and the register have the same size, and every bit pattern is
            // valid for both; element `i` is lane `i` (little-endian lane order).
            $lanes(unsafe { core::mem::transmute::<Self::Array, $reg>(values) })
        }

        #[inline(always)]
        fn to_lane_array(self) -> Self::Array {
            // SAFETY: as in `from_lane_array`.
            unsafe { core::mem::transmute::<$reg, Self::Array>(self.0) }
        }

        #[inline(always)]
        fn from_slice(values: &[Real]) -> Option<Self> {
            Some(Self::from_lane_array(*values.first_chunk()?))
        }

        #[inline(always)]
        fn lane_value(values: &Self::Array, lane: usize) -> Real {
            array_lane_value(values, lane)
        }

        #[inline(always)]
        fn quarter(values: &Self::Array, q: usize) -> Lanes {
            array_quarter(values, q)
        }

        #[inline(always)]
        fn set_quarter(values: &mut Self::Array, q: usize, quarter: Lanes) {
            set_array_quarter(values, q, quarter);
        }

        #[inline(always)]
        fn store_quarter(values: &mut Self::Array, q: usize, quarter: Lanes) {
            store_array_quarter(values, q, quarter);
        }

        #[inline(always)]
        fn set_lane_value(values: &mut Self::Array, lane: usize, value: Real) {
            set_array_lane_value(values, lane, value);
        }
    };
}
#[cfg(target_arch = "x86_64")]
pub(crate) use register_lanes;

/// [`LaneArray::lane_value`] for a plain array.
#[inline(always)]
pub(crate) fn array_lane_value(values: &[Real], lane: usize) -> Real {
    values.get(lane).copied().unwrap_or(0.0)
}

/// [`LaneArray::quarter`] for a plain array: one bounds check for the four values.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn array_quarter(values: &[Real], q: usize) -> Lanes {
    values
        .chunks_exact(LANES)
        .nth(q)
        .and_then(|quarter| <[Real; LANES]>::try_from(quarter).ok())
        .map_or(Lanes::splat(0.0), Lanes::from_array)
}

/// [`LaneArray::set_quarter`] for a plain array.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn set_array_quarter(values: &mut [Real], q: usize, quarter: Lanes) {
    if let Some(slots) = values.chunks_exact_mut(LANES).nth(q) {
        for (slot, value) in slots.iter_mut().zip(quarter.to_array()) {
            *slot = value;
        }
    }
}

/// [`LaneArray::store_quarter`] for a plain array: one store of the four values.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn store_array_quarter(values: &mut [Real], q: usize, quarter: Lanes) {
    let slots = values.get_mut(q * LANES..(q + 1) * LANES);
    if let Some(slots) = slots.and_then(|slots| <&mut [Real; LANES]>::try_from(slots).ok()) {
        *slots = quarter.to_array();
    }
}

/// [`LaneArray::set_lane_value`] for a plain array.
#[inline(always)]
pub(crate) fn set_array_lane_value(values: &mut [Real], lane: usize, value: Real) {
    if let Some(slot) = values.get_mut(lane) {
        *slot = value;
    }
}

impl LaneArray for Lanes {
    type Array = [Real; LANES];
    const ZEROS: Self::Array = [0.0; LANES];

    #[inline(always)]
    fn from_lane_array(values: Self::Array) -> Self {
        Lanes::from_array(values)
    }

    #[inline(always)]
    fn to_lane_array(self) -> Self::Array {
        self.to_array()
    }

    #[inline(always)]
    fn from_slice(values: &[Real]) -> Option<Self> {
        Some(Lanes::from_array(*values.first_chunk()?))
    }

    #[inline(always)]
    fn lane_value(values: &Self::Array, lane: usize) -> Real {
        array_lane_value(values, lane)
    }

    #[inline(always)]
    fn set_lane_value(values: &mut Self::Array, lane: usize, value: Real) {
        set_array_lane_value(values, lane, value);
    }

    #[inline(always)]
    fn store_quarter(values: &mut Self::Array, q: usize, quarter: Lanes) {
        if q == 0 {
            *values = quarter.to_array();
        }
    }

    /// The 4-lane transpose itself, in registers.
    #[inline(always)]
    fn load_vec3s(chunk: &[Vec3]) -> Option<LaneVec3<Self>> {
        Some(LaneVec3::from_vectors(*chunk.first_chunk()?))
    }

    #[inline(always)]
    fn store_vec3s(v: LaneVec3<Self>, chunk: &mut [Vec3]) -> bool {
        let Some(slots) = chunk.first_chunk_mut::<LANES>() else {
            return false;
        };
        *slots = v.to_vectors();
        true
    }
}

impl LaneArray for Real {
    type Array = [Real; 1];
    const ZEROS: Self::Array = [0.0];

    #[inline(always)]
    fn from_lane_array(values: Self::Array) -> Self {
        let [value] = values;
        value
    }

    #[inline(always)]
    fn from_slice(values: &[Real]) -> Option<Self> {
        values.first().copied()
    }

    #[inline(always)]
    fn to_lane_array(self) -> Self::Array {
        [self]
    }

    #[inline(always)]
    fn lane_value(&[value]: &Self::Array, lane: usize) -> Real {
        if lane == 0 { value } else { 0.0 }
    }

    #[inline(always)]
    fn set_lane_value(values: &mut Self::Array, lane: usize, value: Real) {
        if lane == 0 {
            *values = [value];
        }
    }
}

/// Two groups of lanes as one, twice as wide: lanes `0..L::WIDTH` in the first, the rest in the
/// second. Every operation applies to both halves, so each lane still gets the bits of the
/// scalar code; the point is speed: the two halves are independent chains of operations that
/// the processor overlaps, which hides the latency of a long dependent chain (the SVD's sweeps)
/// when one register's worth of lanes cannot.
// Unoptimised builds of the batched SVD use single registers (see src/svd_batch.rs).
#[cfg_attr(debug_assertions, allow(dead_code))]
#[derive(Clone, Copy, Debug)]
pub(crate) struct LanePair<L>(L, L);

impl<L: Lane> Add for LanePair<L> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        LanePair(self.0 + o.0, self.1 + o.1)
    }
}

impl<L: Lane> Sub for LanePair<L> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        LanePair(self.0 - o.0, self.1 - o.1)
    }
}

impl<L: Lane> Mul for LanePair<L> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        LanePair(self.0 * o.0, self.1 * o.1)
    }
}

impl<L: Lane> Div for LanePair<L> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        LanePair(self.0 / o.0, self.1 / o.1)
    }
}

impl<L: Lane> Neg for LanePair<L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        LanePair(-self.0, -self.1)
    }
}

impl<L: Lane> Lane for LanePair<L> {
    type Mask = (L::Mask, L::Mask);

    #[inline(always)]
    fn splat(x: Real) -> Self {
        LanePair(L::splat(x), L::splat(x))
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        LanePair(self.0.sqrt(), self.1.sqrt())
    }

    #[inline(always)]
    fn abs(self) -> Self {
        LanePair(self.0.abs(), self.1.abs())
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        LanePair(self.0.max(other.0), self.1.max(other.1))
    }

    #[inline(always)]
    fn sign(self) -> Self {
        LanePair(self.0.sign(), self.1.sign())
    }

    #[inline(always)]
    fn gt(self, other: Self) -> Self::Mask {
        (self.0.gt(other.0), self.1.gt(other.1))
    }

    #[inline(always)]
    fn ge(self, other: Self) -> Self::Mask {
        (self.0.ge(other.0), self.1.ge(other.1))
    }

    #[inline(always)]
    fn none(mask: Self::Mask) -> bool {
        L::none(mask.0) && L::none(mask.1)
    }

    #[inline(always)]
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self {
        LanePair(L::select(mask.0, a.0, b.0), L::select(mask.1, a.1, b.1))
    }

    #[inline(always)]
    fn map(self, f: impl Fn(Real) -> Real) -> Self {
        LanePair(self.0.map(&f), self.1.map(&f))
    }
}

impl<L: LaneArray> LaneArray for LanePair<L> {
    type Array = (L::Array, L::Array);
    const ZEROS: Self::Array = (L::ZEROS, L::ZEROS);

    #[inline(always)]
    fn from_lane_array(values: Self::Array) -> Self {
        LanePair(L::from_lane_array(values.0), L::from_lane_array(values.1))
    }

    #[inline(always)]
    fn to_lane_array(self) -> Self::Array {
        (self.0.to_lane_array(), self.1.to_lane_array())
    }

    #[inline(always)]
    fn from_slice(values: &[Real]) -> Option<Self> {
        Some(LanePair(
            L::from_slice(values)?,
            L::from_slice(values.get(L::WIDTH..)?)?,
        ))
    }

    #[inline(always)]
    fn lane_value(values: &Self::Array, lane: usize) -> Real {
        match lane.checked_sub(L::WIDTH) {
            None => L::lane_value(&values.0, lane),
            Some(upper) => L::lane_value(&values.1, upper),
        }
    }

    #[inline(always)]
    fn exponent_part(self) -> Self {
        LanePair(self.0.exponent_part(), self.1.exponent_part())
    }

    #[inline(always)]
    fn quarter(values: &Self::Array, q: usize) -> Lanes {
        match q.checked_sub(L::WIDTH / LANES) {
            None => L::quarter(&values.0, q),
            Some(upper) => L::quarter(&values.1, upper),
        }
    }

    #[inline(always)]
    fn set_quarter(values: &mut Self::Array, q: usize, quarter: Lanes) {
        match q.checked_sub(L::WIDTH / LANES) {
            None => L::set_quarter(&mut values.0, q, quarter),
            Some(upper) => L::set_quarter(&mut values.1, upper, quarter),
        }
    }

    #[inline(always)]
    fn store_quarter(values: &mut Self::Array, q: usize, quarter: Lanes) {
        match q.checked_sub(L::WIDTH / LANES) {
            None => L::store_quarter(&mut values.0, q, quarter),
            Some(upper) => L::store_quarter(&mut values.1, upper, quarter),
        }
    }

    #[inline(always)]
    fn set_lane_value(values: &mut Self::Array, lane: usize, value: Real) {
        match lane.checked_sub(L::WIDTH) {
            None => L::set_lane_value(&mut values.0, lane, value),
            Some(upper) => L::set_lane_value(&mut values.1, upper, value),
        }
    }
}

/// A 3-vector of lane values.
#[derive(Clone, Copy)]
pub struct LaneVec3<L> {
    /// The x coordinates.
    pub x: L,
    /// The y coordinates.
    pub y: L,
    /// The z coordinates.
    pub z: L,
}

impl<L: Lane> LaneVec3<L> {
    /// The vector `(x, y, z)`.
    #[inline(always)]
    pub fn new(x: L, y: L, z: L) -> Self {
        LaneVec3 { x, y, z }
    }

    /// `x x' + y y' + z z'`, summed in that order.
    #[inline(always)]
    pub fn dot(self, o: Self) -> L {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// The cross product, in the order of operations of glam's `Vec3::cross` (so that the
    /// scalar instantiation gives its bits).
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        LaneVec3::new(
            self.y * o.z - o.y * self.z,
            self.z * o.x - o.z * self.x,
            self.x * o.y - o.x * self.y,
        )
    }

    /// Every coordinate times `k`.
    #[inline(always)]
    pub fn scale(self, k: L) -> Self {
        LaneVec3::new(self.x * k, self.y * k, self.z * k)
    }

    /// `mask ? a : b` per lane.
    #[inline(always)]
    pub fn select(mask: L::Mask, a: Self, b: Self) -> Self {
        LaneVec3::new(
            L::select(mask, a.x, b.x),
            L::select(mask, a.y, b.y),
            L::select(mask, a.z, b.z),
        )
    }
}

impl<L: Lane> Add for LaneVec3<L> {
    type Output = Self;
    /// The sum.
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        LaneVec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl<L: Lane> Sub for LaneVec3<L> {
    type Output = Self;
    /// The difference.
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        LaneVec3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl<L: Lane> Neg for LaneVec3<L> {
    type Output = Self;
    /// The negation.
    #[inline(always)]
    fn neg(self) -> Self {
        LaneVec3::new(-self.x, -self.y, -self.z)
    }
}

/// A 3x3 matrix of lane values, stored as columns (like glam).
#[derive(Clone, Copy)]
pub struct LaneMat3<L> {
    /// The first column.
    pub c0: LaneVec3<L>,
    /// The second column.
    pub c1: LaneVec3<L>,
    /// The third column.
    pub c2: LaneVec3<L>,
}

impl<L: Lane> LaneMat3<L> {
    /// The identity in every lane.
    #[inline(always)]
    pub fn identity() -> Self {
        let (o, z) = (L::splat(1.0), L::splat(0.0));
        LaneMat3 {
            c0: LaneVec3::new(o, z, z),
            c1: LaneVec3::new(z, o, z),
            c2: LaneVec3::new(z, z, o),
        }
    }

    /// The transpose.
    #[inline(always)]
    pub fn transpose(self) -> Self {
        LaneMat3 {
            c0: LaneVec3::new(self.c0.x, self.c1.x, self.c2.x),
            c1: LaneVec3::new(self.c0.y, self.c1.y, self.c2.y),
            c2: LaneVec3::new(self.c0.z, self.c1.z, self.c2.z),
        }
    }

    /// `self * v`.
    #[inline(always)]
    pub fn mul_vec(self, v: LaneVec3<L>) -> LaneVec3<L> {
        self.c0.scale(v.x) + self.c1.scale(v.y) + self.c2.scale(v.z)
    }

    /// Every entry times `k`.
    #[inline(always)]
    pub fn scale(self, k: L) -> Self {
        LaneMat3 {
            c0: self.c0.scale(k),
            c1: self.c1.scale(k),
            c2: self.c2.scale(k),
        }
    }
}

impl<L: Lane> Mul for LaneMat3<L> {
    type Output = Self;
    /// The matrix product, each column `self * other.c_j` as in [`LaneMat3::mul_vec`].
    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        LaneMat3 {
            c0: self.mul_vec(other.c0),
            c1: self.mul_vec(other.c1),
            c2: self.mul_vec(other.c2),
        }
    }
}

impl<L: Lane> Add for LaneMat3<L> {
    type Output = Self;
    /// The sum.
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        LaneMat3 {
            c0: self.c0 + o.c0,
            c1: self.c1 + o.c1,
            c2: self.c2 + o.c2,
        }
    }
}

impl<L: Lane> Sub for LaneMat3<L> {
    type Output = Self;
    /// The difference.
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        LaneMat3 {
            c0: self.c0 - o.c0,
            c1: self.c1 - o.c1,
            c2: self.c2 - o.c2,
        }
    }
}

impl PartialEq for Lanes {
    /// Lane-wise IEEE equality of all lanes (so a NaN lane is unequal to itself).
    fn eq(&self, other: &Lanes) -> bool {
        self.to_array() == other.to_array()
    }
}

impl LaneVec3<Lanes> {
    /// The vectors as lanes: lane `i` holds `v[i]`.
    #[inline(always)]
    #[must_use]
    pub fn from_vectors(v: [Vec3; LANES]) -> Self {
        transpose_vec3(v)
    }

    /// The vector of every lane.
    #[inline(always)]
    #[must_use]
    pub fn to_vectors(self) -> [Vec3; LANES] {
        untranspose_vec3(self)
    }
}

impl LaneMat3<Lanes> {
    /// The matrices as lanes: entry `(r, c)` of lane `i` is entry `(r, c)` of `a[i]`.
    #[inline(always)]
    #[must_use]
    pub fn from_matrices(a: &[Mat3; LANES]) -> Self {
        LaneMat3 {
            c0: transpose_vec3(each_lane(*a, |m| m.x_axis)),
            c1: transpose_vec3(each_lane(*a, |m| m.y_axis)),
            c2: transpose_vec3(each_lane(*a, |m| m.z_axis)),
        }
    }

    /// The matrix of every lane.
    #[inline(always)]
    #[must_use]
    pub fn to_matrices(self) -> [Mat3; LANES] {
        let (c0, c1, c2) = (
            untranspose_vec3(self.c0),
            untranspose_vec3(self.c1),
            untranspose_vec3(self.c2),
        );
        core::array::from_fn(|i| match (c0.get(i), c1.get(i), c2.get(i)) {
            (Some(&x), Some(&y), Some(&z)) => Mat3::from_cols(x, y, z),
            _ => Mat3::ZERO,
        })
    }
}

impl From<Vec3> for LaneVec3<Real> {
    #[inline(always)]
    fn from(v: Vec3) -> Self {
        LaneVec3::new(v.x, v.y, v.z)
    }
}

impl From<LaneVec3<Real>> for Vec3 {
    #[inline(always)]
    fn from(v: LaneVec3<Real>) -> Self {
        Vec3::new(v.x, v.y, v.z)
    }
}

impl From<Mat3> for LaneMat3<Real> {
    #[inline(always)]
    fn from(m: Mat3) -> Self {
        LaneMat3 {
            c0: m.x_axis.into(),
            c1: m.y_axis.into(),
            c2: m.z_axis.into(),
        }
    }
}

impl From<LaneMat3<Real>> for Mat3 {
    #[inline(always)]
    fn from(m: LaneMat3<Real>) -> Self {
        Mat3::from_cols(m.c0.into(), m.c1.into(), m.c2.into())
    }
}

#[cfg(test)]
mod tests {
    use super::{LANES, LaneArray, LanePair, LaneSum, Lanes};

    /// Terms of very different magnitudes and both signs, whose rounded sum depends on the order.
    fn term(i: usize) -> super::Real {
        let k = i as super::Real;
        (1.0 + 0.37 * k)
            * if i.is_multiple_of(3) { 1.0e6 } else { 1.0e-3 }
            * if i.is_multiple_of(2) { 1.0 } else { -1.0 }
    }

    /// Groups plus a tail, and every item one at a time, give the same bits, and both follow the
    /// documented order, for every remainder.
    #[test]
    fn lane_sums_give_the_same_bits_grouped_or_not() {
        for n in [0, 1, 3, 4, 5, 8, 11, 13] {
            let whole = n - n % LANES;
            let mut grouped = LaneSum::new(n);
            for start in (0..whole).step_by(LANES) {
                grouped.add_wide(Lanes::from_array(core::array::from_fn(|j| term(start + j))));
            }
            for i in whole..n {
                grouped.add_single(i, term(i));
            }
            let mut single = LaneSum::new(n);
            for i in 0..n {
                single.add_single(i, term(i));
            }
            let mut partial = [0.0; LANES];
            let mut last = 0.0;
            for i in 0..n {
                if i < whole {
                    partial[i % LANES] += term(i);
                } else {
                    last += term(i);
                }
            }
            let expected = ((partial[0] + partial[1]) + (partial[2] + partial[3])) + last;
            assert_eq!(grouped.total().to_bits(), expected.to_bits(), "n = {n}");
            assert_eq!(single.total().to_bits(), expected.to_bits(), "n = {n}");
        }
    }

    /// Groups of 8 and 16 lanes (pairs of [`Lanes`], which every target has, standing in for
    /// the AVX lanes), then narrower groups, then single items, as the vertex passes take them
    /// at each width: the bits of every item added one at a time, for every `n` up to 70.
    #[test]
    fn wide_lane_sums_give_the_bits_of_single_items() {
        type Eight = LanePair<Lanes>;
        type Sixteen = LanePair<Eight>;
        /// The group of the `L::WIDTH` terms from item `start` on.
        fn group<L: LaneArray>(start: usize) -> L {
            let mut values = L::ZEROS;
            for lane in 0..L::WIDTH {
                L::set_lane_value(&mut values, lane, term(start + lane));
            }
            L::from_lane_array(values)
        }
        /// Whole groups of `L::WIDTH` items from `done` on: the items done.
        fn groups<L: LaneArray>(sum: &mut LaneSum, n: usize, mut done: usize) -> usize {
            while done + L::WIDTH <= n {
                sum.add_wide(group::<L>(done));
                done += L::WIDTH;
            }
            done
        }
        for n in 0..=70 {
            // The documented order, written out.
            let whole = n - n % LANES;
            let mut partial = [0.0; LANES];
            for i in 0..whole {
                partial[i % LANES] += term(i);
            }
            let last = (whole..n).fold(0.0, |sum, i| sum + term(i));
            let expected =
                (((partial[0] + partial[1]) + (partial[2] + partial[3])) + last).to_bits();
            let widths: [&dyn Fn(&mut LaneSum) -> usize; 3] = [
                &|sum| groups::<Lanes>(sum, n, 0),
                &|sum| {
                    let done = groups::<Eight>(sum, n, 0);
                    groups::<Lanes>(sum, n, done)
                },
                &|sum| {
                    let done = groups::<Sixteen>(sum, n, 0);
                    let done = groups::<Eight>(sum, n, done);
                    groups::<Lanes>(sum, n, done)
                },
            ];
            for (k, width) in widths.iter().enumerate() {
                let mut sum = LaneSum::new(n);
                let done = width(&mut sum);
                for i in done..n {
                    sum.add_single(i, term(i));
                }
                assert_eq!(sum.total().to_bits(), expected, "n = {n}, widths {k}");
            }
        }
    }
}

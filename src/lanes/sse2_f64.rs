//! [`Lanes`] of four f64 in two SSE2 registers (x86_64, whose baseline includes SSE2).
//!
//! Every operation is the packed form of the scalar one with the same IEEE rounding, so lane `i`
//! is bit for bit what the scalar code computes; `max` reproduces the exact instruction sequence
//! the compiler emits for `f64::max`. The f32 counterpart, `sse.rs`, says why a register
//! type rather than an array.

// SAFETY (for every `unsafe` block below that only calls SSE2 intrinsics on register values):
// these instructions are part of the x86_64 baseline, so they are always available, and they
// have no memory operands or other preconditions.

use super::lanes::{LANES, Lane, LaneVec3, map_lane_array, register_lanes};
use super::types::{Real, Vec3};
use core::arch::x86_64::{
    __m128d, _mm_add_pd, _mm_and_pd, _mm_andnot_pd, _mm_cmpge_pd, _mm_cmpgt_pd, _mm_cmpunord_pd,
    _mm_div_pd, _mm_max_pd, _mm_movemask_pd, _mm_mul_pd, _mm_or_pd, _mm_set1_pd, _mm_setr_pd,
    _mm_sqrt_pd, _mm_sub_pd, _mm_unpackhi_pd, _mm_unpacklo_pd, _mm_xor_pd,
};
use core::ops::{Add, Div, Mul, Neg, Sub};

/// [`LANES`] independent values processed together (structure of arrays), in two SSE2
/// registers: lanes 0 and 1 in the first, 2 and 3 in the second.
#[derive(Clone, Copy, Debug)]
pub struct Lanes([__m128d; 2]);

/// Per-lane comparison results: all bits set where true.
#[derive(Clone, Copy, Debug)]
pub struct LaneMask([__m128d; 2]);

/// `f` of both registers.
#[inline(always)]
fn both(a: [__m128d; 2], f: impl Fn(__m128d) -> __m128d) -> [__m128d; 2] {
    let [lo, hi] = a;
    [f(lo), f(hi)]
}

/// `f` of both registers of two groups, pairwise.
#[inline(always)]
fn pairwise(
    a: [__m128d; 2],
    b: [__m128d; 2],
    f: impl Fn(__m128d, __m128d) -> __m128d,
) -> [__m128d; 2] {
    let ([a_lo, a_hi], [b_lo, b_hi]) = (a, b);
    [f(a_lo, b_lo), f(a_hi, b_hi)]
}

impl Lanes {
    /// The group holding `values`, lane `i` = `values[i]`.
    #[inline(always)]
    #[must_use]
    pub fn from_array(values: [Real; LANES]) -> Lanes {
        let [a, b, c, d] = values;
        // SAFETY: see the module comment.
        Lanes(unsafe { [_mm_setr_pd(a, b), _mm_setr_pd(c, d)] })
    }

    /// The values of the lanes, in order.
    #[inline(always)]
    #[must_use]
    pub fn to_array(self) -> [Real; LANES] {
        // SAFETY: `[__m128d; 2]` and `[f64; 4]` have the same size, and every bit pattern is
        // valid for both; lane `i` of the registers is element `i` of the array (little-endian
        // order of the SSE2 lanes, as `_mm_setr_pd` writes them).
        unsafe { core::mem::transmute::<[__m128d; 2], [Real; LANES]>(self.0) }
    }
}

register_lanes!(pair_binary_ops Lanes:
    Add add _mm_add_pd, Sub sub _mm_sub_pd, Mul mul _mm_mul_pd, Div div _mm_div_pd);

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        // SAFETY: see the module comment. Flipping the sign bit is what scalar negation does.
        Lanes(both(self.0, |a| unsafe {
            _mm_xor_pd(a, _mm_set1_pd(-0.0))
        }))
    }
}

impl Lane for Lanes {
    type Mask = LaneMask;

    #[inline(always)]
    fn splat(x: Real) -> Self {
        // SAFETY: see the module comment.
        let register = unsafe { _mm_set1_pd(x) };
        Lanes([register, register])
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        // SAFETY: see the module comment. `sqrtpd` is correctly rounded, as `libm::sqrt`.
        Lanes(both(self.0, |a| unsafe { _mm_sqrt_pd(a) }))
    }

    #[inline(always)]
    fn abs(self) -> Self {
        // SAFETY: see the module comment. Clearing the sign bit is what `f64::abs` does.
        Lanes(both(self.0, |a| unsafe {
            _mm_andnot_pd(_mm_set1_pd(-0.0), a)
        }))
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        // `f64::max(a, b)` compiles to exactly this: `maxpd(b, a)` returns `a` when the two are
        // unordered or equal, and `b` replaces a NaN `a`.
        // SAFETY: see the module comment.
        Lanes(pairwise(self.0, other.0, |a, b| unsafe {
            let larger = _mm_max_pd(b, a);
            let a_is_nan = _mm_cmpunord_pd(a, a);
            _mm_or_pd(_mm_and_pd(a_is_nan, b), _mm_andnot_pd(a_is_nan, larger))
        }))
    }

    #[inline(always)]
    fn sign(self) -> Self {
        // `1.0.copysign(self)`: the sign bit of `self` on the bits of 1.0.
        // SAFETY: see the module comment.
        Lanes(both(self.0, |a| unsafe {
            _mm_or_pd(_mm_and_pd(_mm_set1_pd(-0.0), a), _mm_set1_pd(1.0))
        }))
    }

    #[inline(always)]
    fn gt(self, other: Self) -> LaneMask {
        // SAFETY: see the module comment. Ordered: false where either lane is NaN.
        LaneMask(pairwise(self.0, other.0, |a, b| unsafe {
            _mm_cmpgt_pd(a, b)
        }))
    }

    #[inline(always)]
    fn ge(self, other: Self) -> LaneMask {
        // SAFETY: see the module comment. Ordered: false where either lane is NaN.
        LaneMask(pairwise(self.0, other.0, |a, b| unsafe {
            _mm_cmpge_pd(a, b)
        }))
    }

    #[inline(always)]
    fn none(mask: LaneMask) -> bool {
        let [lo, hi] = mask.0;
        // SAFETY: see the module comment. The sign bit of each lane, as two bits per register.
        unsafe { _mm_movemask_pd(_mm_or_pd(lo, hi)) == 0 }
    }

    #[inline(always)]
    fn select(mask: LaneMask, a: Self, b: Self) -> Self {
        let ([m_lo, m_hi], [a_lo, a_hi], [b_lo, b_hi]) = (mask.0, a.0, b.0);
        // SAFETY: see the module comment.
        let pick = |m, a, b| unsafe { _mm_or_pd(_mm_and_pd(m, a), _mm_andnot_pd(m, b)) };
        Lanes([pick(m_lo, a_lo, b_lo), pick(m_hi, a_hi, b_hi)])
    }

    register_lanes!(map);
}

/// The 4x4 transpose of `rows`: lane `j` of result `i` is lane `i` of `rows[j]` (how the
/// batched SVD turns four groups of entries into four matrices' rows, in registers).
#[inline(always)]
#[must_use]
pub(crate) fn transpose4(rows: [Lanes; 4]) -> [Lanes; 4] {
    let [
        Lanes([a01, a23]),
        Lanes([b01, b23]),
        Lanes([c01, c23]),
        Lanes([d01, d23]),
    ] = rows;
    // SAFETY: see the module comment.
    unsafe {
        [
            Lanes([_mm_unpacklo_pd(a01, b01), _mm_unpacklo_pd(c01, d01)]),
            Lanes([_mm_unpackhi_pd(a01, b01), _mm_unpackhi_pd(c01, d01)]),
            Lanes([_mm_unpacklo_pd(a23, b23), _mm_unpacklo_pd(c23, d23)]),
            Lanes([_mm_unpackhi_pd(a23, b23), _mm_unpackhi_pd(c23, d23)]),
        ]
    }
}

/// The vectors of [`LANES`] elements as lanes of coordinates (lane `i` holds `v[i]`).
#[inline(always)]
#[must_use]
pub fn transpose_vec3(v: [Vec3; LANES]) -> LaneVec3<Lanes> {
    let [v0, v1, v2, v3] = v;
    LaneVec3::new(
        Lanes::from_array([v0.x, v1.x, v2.x, v3.x]),
        Lanes::from_array([v0.y, v1.y, v2.y, v3.y]),
        Lanes::from_array([v0.z, v1.z, v2.z, v3.z]),
    )
}

/// The inverse of [`transpose_vec3`]: lane `i` of the coordinates as `out[i]`.
#[inline(always)]
#[must_use]
pub fn untranspose_vec3(v: LaneVec3<Lanes>) -> [Vec3; LANES] {
    let ([x0, x1, x2, x3], [y0, y1, y2, y3], [z0, z1, z2, z3]) =
        (v.x.to_array(), v.y.to_array(), v.z.to_array());
    [
        Vec3::new(x0, y0, z0),
        Vec3::new(x1, y1, z1),
        Vec3::new(x2, y2, z2),
        Vec3::new(x3, y3, z3),
    ]
}

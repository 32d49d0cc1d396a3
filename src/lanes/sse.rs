//! [`Lanes`] of four f32 in one SSE register (x86_64, whose baseline includes SSE and SSE2).
//!
//! Every operation is the packed form of the scalar one with the same IEEE rounding, so lane `i`
//! is bit for bit what the scalar code computes; `max` reproduces the exact instruction sequence
//! the compiler emits for `f32::max`. Holding the group in a register type, rather than an array
//! the optimiser may or may not keep in registers, measured twice as fast in the force kernels.

// SAFETY (for every `unsafe` block below that only calls SSE/SSE2 intrinsics on register
// values): these instructions are part of the x86_64 baseline, so they are always available, and
// they have no memory operands or other preconditions.

use super::lanes::{LANES, Lane, LaneVec3, each_lane, map_lane_array, register_lanes};
use super::types::{Real, Vec3};
use core::arch::x86_64::{
    __m128, _mm_add_ps, _mm_and_ps, _mm_andnot_ps, _mm_cmpge_ps, _mm_cmpgt_ps, _mm_cmpunord_ps,
    _mm_div_ps, _mm_max_ps, _mm_movehl_ps, _mm_movelh_ps, _mm_movemask_ps, _mm_mul_ps, _mm_or_ps,
    _mm_set1_ps, _mm_setr_ps, _mm_sqrt_ps, _mm_sub_ps, _mm_unpackhi_ps, _mm_unpacklo_ps,
    _mm_xor_ps,
};
use core::ops::{Add, Div, Mul, Neg, Sub};

/// [`LANES`] independent values processed together (structure of arrays), in one SSE register.
#[derive(Clone, Copy, Debug)]
pub struct Lanes(__m128);

/// Per-lane comparison results: all bits set where true.
#[derive(Clone, Copy, Debug)]
pub struct LaneMask(__m128);

impl Lanes {
    /// The group holding `values`, lane `i` = `values[i]`.
    #[inline(always)]
    #[must_use]
    pub fn from_array(values: [Real; LANES]) -> Lanes {
        let [a, b, c, d] = values;
        // SAFETY: see the module comment.
        Lanes(unsafe { _mm_setr_ps(a, b, c, d) })
    }

    /// The values of the lanes, in order.
    #[inline(always)]
    #[must_use]
    pub fn to_array(self) -> [Real; LANES] {
        // SAFETY: `__m128` and `[f32; 4]` have the same size, and every bit pattern is valid
        // for both; lane `i` of the register is element `i` of the array (little-endian order of
        // the SSE lanes, as `_mm_setr_ps` writes them).
        unsafe { core::mem::transmute::<__m128, [Real; LANES]>(self.0) }
    }
}

register_lanes!(binary_ops Lanes:
    Add add _mm_add_ps, Sub sub _mm_sub_ps, Mul mul _mm_mul_ps, Div div _mm_div_ps);

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        // SAFETY: see the module comment. Flipping the sign bit is what scalar negation does.
        Lanes(unsafe { _mm_xor_ps(self.0, _mm_set1_ps(-0.0)) })
    }
}

impl Lane for Lanes {
    type Mask = LaneMask;

    #[inline(always)]
    fn splat(x: Real) -> Self {
        // SAFETY: see the module comment.
        Lanes(unsafe { _mm_set1_ps(x) })
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        // SAFETY: see the module comment. `sqrtps` is correctly rounded, as `libm::sqrtf`.
        Lanes(unsafe { _mm_sqrt_ps(self.0) })
    }

    #[inline(always)]
    fn abs(self) -> Self {
        // SAFETY: see the module comment. Clearing the sign bit is what `f32::abs` does.
        Lanes(unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), self.0) })
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        // `f32::max(a, b)` compiles to exactly this: `maxps(b, a)` returns `a` when the two are
        // unordered or equal, and `b` replaces a NaN `a`.
        // SAFETY: see the module comment.
        unsafe {
            let larger = _mm_max_ps(other.0, self.0);
            let self_is_nan = _mm_cmpunord_ps(self.0, self.0);
            Lanes(_mm_or_ps(
                _mm_and_ps(self_is_nan, other.0),
                _mm_andnot_ps(self_is_nan, larger),
            ))
        }
    }

    #[inline(always)]
    fn sign(self) -> Self {
        // `1.0.copysign(self)`: the sign bit of `self` on the bits of 1.0.
        // SAFETY: see the module comment.
        unsafe {
            let sign_bit = _mm_set1_ps(-0.0);
            Lanes(_mm_or_ps(_mm_and_ps(sign_bit, self.0), _mm_set1_ps(1.0)))
        }
    }

    #[inline(always)]
    fn gt(self, other: Self) -> LaneMask {
        // SAFETY: see the module comment. Ordered: false where either lane is NaN.
        LaneMask(unsafe { _mm_cmpgt_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn ge(self, other: Self) -> LaneMask {
        // SAFETY: see the module comment. Ordered: false where either lane is NaN.
        LaneMask(unsafe { _mm_cmpge_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn none(mask: LaneMask) -> bool {
        // SAFETY: see the module comment. The sign bit of each lane, as four bits.
        unsafe { _mm_movemask_ps(mask.0) == 0 }
    }

    #[inline(always)]
    fn select(mask: LaneMask, a: Self, b: Self) -> Self {
        // SAFETY: see the module comment.
        Lanes(unsafe { _mm_or_ps(_mm_and_ps(mask.0, a.0), _mm_andnot_ps(mask.0, b.0)) })
    }

    register_lanes!(map);
}

/// The 4x4 transpose of `rows`: lane `j` of result `i` is lane `i` of `rows[j]` (how the
/// batched SVD turns four groups of entries into four matrices' rows, in registers).
#[inline(always)]
#[must_use]
pub(crate) fn transpose4(rows: [Lanes; 4]) -> [Lanes; 4] {
    let [Lanes(r0), Lanes(r1), Lanes(r2), Lanes(r3)] = rows;
    // SAFETY: see the module comment.
    unsafe {
        let a0_b0_a1_b1 = _mm_unpacklo_ps(r0, r1);
        let c0_d0_c1_d1 = _mm_unpacklo_ps(r2, r3);
        let a2_b2_a3_b3 = _mm_unpackhi_ps(r0, r1);
        let c2_d2_c3_d3 = _mm_unpackhi_ps(r2, r3);
        [
            Lanes(_mm_movelh_ps(a0_b0_a1_b1, c0_d0_c1_d1)),
            Lanes(_mm_movehl_ps(c0_d0_c1_d1, a0_b0_a1_b1)),
            Lanes(_mm_movelh_ps(a2_b2_a3_b3, c2_d2_c3_d3)),
            Lanes(_mm_movehl_ps(c2_d2_c3_d3, a2_b2_a3_b3)),
        ]
    }
}

/// One vector as `[x, y, z, 0]`.
#[inline(always)]
fn packed(v: Vec3) -> __m128 {
    // SAFETY: see the module comment.
    unsafe { _mm_setr_ps(v.x, v.y, v.z, 0.0) }
}

/// The vectors of [`LANES`] elements as lanes of coordinates (lane `i` holds `v[i]`): a 4x4
/// transpose in registers.
#[inline(always)]
#[must_use]
pub fn transpose_vec3(v: [Vec3; LANES]) -> LaneVec3<Lanes> {
    let [v0, v1, v2, v3] = each_lane(v, packed);
    // SAFETY: see the module comment.
    unsafe {
        let x0_x1_y0_y1 = _mm_unpacklo_ps(v0, v1);
        let x2_x3_y2_y3 = _mm_unpacklo_ps(v2, v3);
        let z0_z1 = _mm_unpackhi_ps(v0, v1);
        let z2_z3 = _mm_unpackhi_ps(v2, v3);
        LaneVec3::new(
            Lanes(_mm_movelh_ps(x0_x1_y0_y1, x2_x3_y2_y3)),
            Lanes(_mm_movehl_ps(x2_x3_y2_y3, x0_x1_y0_y1)),
            Lanes(_mm_movelh_ps(z0_z1, z2_z3)),
        )
    }
}

/// The inverse of [`transpose_vec3`]: lane `i` of the coordinates as `out[i]`.
#[inline(always)]
#[must_use]
pub fn untranspose_vec3(v: LaneVec3<Lanes>) -> [Vec3; LANES] {
    let (x, y, z) = (v.x.0, v.y.0, v.z.0);
    // SAFETY: see the module comment.
    let rows = unsafe {
        let x0_y0_x1_y1 = _mm_unpacklo_ps(x, y);
        let x2_y2_x3_y3 = _mm_unpackhi_ps(x, y);
        let z0_z0_z1_z1 = _mm_unpacklo_ps(z, z);
        let z2_z2_z3_z3 = _mm_unpackhi_ps(z, z);
        [
            _mm_movelh_ps(x0_y0_x1_y1, z0_z0_z1_z1),
            _mm_movehl_ps(z0_z0_z1_z1, x0_y0_x1_y1),
            _mm_movelh_ps(x2_y2_x3_y3, z2_z2_z3_z3),
            _mm_movehl_ps(z2_z2_z3_z3, x2_y2_x3_y3),
        ]
    };
    // Each row as a `Vec3` by value: the caller's `+=` into a `Vec3` slot then loads and stores
    // the slot as 8 + 4 bytes, the same widths as the previous store to it, so store-to-load
    // forwarding works when consecutive elements share a vertex.
    each_lane(rows, |row| {
        let [x, y, z, _] = Lanes(row).to_array();
        Vec3::new(x, y, z)
    })
}

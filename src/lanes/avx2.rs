//! [`Avx2Lanes`]: one AVX register of this precision (8 f32 or 4 f64), for the batched kernels
//! that [`simd::dispatch`](crate::simd) runs with AVX2 enabled.
//!
//! Written once for both precisions against the precision-neutral names of `wide_ops` (in
//! `src/f32/wide_ops.rs` and `src/f64/wide_ops.rs`). Every operation is the packed form of the
//! scalar one with the same IEEE rounding (add, subtract, multiply, divide and square root are
//! correctly rounded; no fused multiply-add), `max` reproduces the instruction sequence the
//! compiler emits for the scalar `max`, and selects are bitwise blends, so lane `i` is bit for bit
//! what the scalar code computes.

// SAFETY (for every `unsafe` block below, which only calls AVX intrinsics on register values):
// the type is crate-private and only the batched kernels create it, inside the functions that
// `simd::dispatch` compiles with AVX2 enabled and calls only after `simd::detected_width` found
// AVX2 and the OS's support of the YMM state. The intrinsics have no memory operands or other
// preconditions.

use super::super::types::{Real, Vec3};
use super::super::wide_ops::{
    AVX2_WIDTH, Reg256, add256, and256, andnot256, blendv256, cmp256, div256, max256, movemask256,
    mul256, or256, set1_256, sqrt256, store_vec3s_256, sub256, vec3s_256, xor256,
};
use super::{
    Lane, LaneArray, LaneVec3, Lanes, array_lane_value, array_quarter, map_lane_array,
    register_lanes, set_array_lane_value, set_array_quarter, store_array_quarter,
};
use core::arch::x86_64::{_CMP_GE_OQ, _CMP_GT_OQ, _CMP_UNORD_Q};
use core::ops::{Add, Div, Mul, Neg, Sub};

/// [`AVX2_WIDTH`] independent values processed together (structure of arrays), in one AVX
/// register.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx2Lanes(Reg256);

/// Per-lane comparison results: all bits set where true.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx2Mask(Reg256);

register_lanes!(binary_ops Avx2Lanes:
    Add add add256, Sub sub sub256, Mul mul mul256, Div div div256);

impl Neg for Avx2Lanes {
    type Output = Avx2Lanes;
    #[inline(always)]
    fn neg(self) -> Avx2Lanes {
        // SAFETY: see the module comment. Flipping the sign bit is what scalar negation does.
        Avx2Lanes(unsafe { xor256(self.0, set1_256(-0.0)) })
    }
}

impl Lane for Avx2Lanes {
    type Mask = Avx2Mask;

    #[inline(always)]
    fn splat(x: Real) -> Self {
        // SAFETY: see the module comment.
        Avx2Lanes(unsafe { set1_256(x) })
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        // SAFETY: see the module comment. `vsqrtps`/`vsqrtpd` are correctly rounded, as the
        // scalar square root.
        Avx2Lanes(unsafe { sqrt256(self.0) })
    }

    #[inline(always)]
    fn abs(self) -> Self {
        // SAFETY: see the module comment. Clearing the sign bit is what scalar `abs` does.
        Avx2Lanes(unsafe { andnot256(set1_256(-0.0), self.0) })
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        // Scalar `max(a, b)` compiles to exactly this: `max(b, a)` returns `a` when the two
        // are unordered or equal, and `b` replaces a NaN `a`.
        // SAFETY: see the module comment.
        unsafe {
            let larger = max256(other.0, self.0);
            let self_is_nan = cmp256::<_CMP_UNORD_Q>(self.0, self.0);
            Avx2Lanes(blendv256(larger, other.0, self_is_nan))
        }
    }

    #[inline(always)]
    fn sign(self) -> Self {
        // `1.0.copysign(self)`: the sign bit of `self` on the bits of 1.0.
        // SAFETY: see the module comment.
        unsafe {
            let sign_bit = set1_256(-0.0);
            Avx2Lanes(or256(and256(sign_bit, self.0), set1_256(1.0)))
        }
    }

    register_lanes!(compare Avx2Mask: cmp256);

    #[inline(always)]
    fn none(mask: Avx2Mask) -> bool {
        // SAFETY: see the module comment. The sign bit of each lane, one bit per lane.
        unsafe { movemask256(mask.0) == 0 }
    }

    #[inline(always)]
    fn select(mask: Avx2Mask, a: Self, b: Self) -> Self {
        // SAFETY: see the module comment. A mask lane is all ones or all zeros, so blending
        // on its sign bit takes all of `a`'s bits or all of `b`'s.
        Avx2Lanes(unsafe { blendv256(b.0, a.0, mask.0) })
    }

    register_lanes!(map);
}

impl LaneArray for Avx2Lanes {
    register_lanes!(array Avx2Lanes: Reg256, AVX2_WIDTH);

    #[inline(always)]
    fn exponent_part(self) -> Self {
        // SAFETY: see the module comment. The bits of +inf are the exponent field's mask.
        Avx2Lanes(unsafe { and256(self.0, set1_256(Real::INFINITY)) })
    }

    #[inline(always)]
    fn load_vec3s(chunk: &[Vec3]) -> Option<LaneVec3<Self>> {
        let [x, y, z] = vec3s_256(chunk)?;
        Some(LaneVec3::new(Avx2Lanes(x), Avx2Lanes(y), Avx2Lanes(z)))
    }

    #[inline(always)]
    fn store_vec3s(v: LaneVec3<Self>, chunk: &mut [Vec3]) -> bool {
        store_vec3s_256([v.x.0, v.y.0, v.z.0], chunk)
    }
}

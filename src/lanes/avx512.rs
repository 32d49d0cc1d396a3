//! [`Avx512Lanes`]: one AVX-512 register of this precision (16 f32 or 8 f64), for the batched
//! kernels that [`simd::dispatch`](crate::simd) runs with AVX-512F enabled.
//!
//! Written once for both precisions against the precision-neutral names of `wide_ops` (in
//! `src/f32/wide_ops.rs` and `src/f64/wide_ops.rs`). Every operation is the packed form of the
//! scalar one with the same IEEE rounding (add, subtract, multiply, divide and square root are
//! correctly rounded; no fused multiply-add), `max` reproduces the result of the instruction
//! sequence the compiler emits for the scalar `max`, and selects are mask blends, so lane `i` is
//! bit for bit what the scalar code computes. Only AVX-512F is used: its bitwise operations are the
//! integer ones (the floating-point `and`/`or`/`xor` forms need AVX-512DQ).

// SAFETY (for every `unsafe` block below, which only calls AVX-512F intrinsics on register
// values): the type is crate-private and only the batched kernels create it, inside the
// functions that `simd::dispatch` compiles with AVX-512F enabled and calls only after
// `simd::detected_width` found AVX-512F and the OS's support of the ZMM and mask state. The
// intrinsics have no memory operands or other preconditions.

use super::super::types::{Real, Vec3};
use super::super::wide_ops::{
    AVX512_WIDTH, Mask512, Reg512, abs512, add512, blend512, cmp512, div512, from_bits512, max512,
    mul512, set1_512, sqrt512, store_vec3s_512, sub512, to_bits512, vec3s_512,
};
use super::{
    Lane, LaneArray, LaneVec3, Lanes, array_lane_value, array_quarter, map_lane_array,
    register_lanes, set_array_lane_value, set_array_quarter, store_array_quarter,
};
use core::arch::x86_64::{
    _CMP_GE_OQ, _CMP_GT_OQ, _CMP_UNORD_Q, _mm512_and_si512, _mm512_or_si512, _mm512_xor_si512,
};
use core::ops::{Add, Div, Mul, Neg, Sub};

/// [`AVX512_WIDTH`] independent values processed together (structure of arrays), in one
/// AVX-512 register.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx512Lanes(Reg512);

/// Per-lane comparison results: one bit per lane, in a mask register.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Avx512Mask(Mask512);

register_lanes!(binary_ops Avx512Lanes:
    Add add add512, Sub sub sub512, Mul mul mul512, Div div div512);

impl Neg for Avx512Lanes {
    type Output = Avx512Lanes;
    #[inline(always)]
    fn neg(self) -> Avx512Lanes {
        // SAFETY: see the module comment. Flipping the sign bit is what scalar negation does.
        Avx512Lanes(unsafe {
            from_bits512(_mm512_xor_si512(
                to_bits512(self.0),
                to_bits512(set1_512(-0.0)),
            ))
        })
    }
}

impl Lane for Avx512Lanes {
    type Mask = Avx512Mask;

    #[inline(always)]
    fn splat(x: Real) -> Self {
        // SAFETY: see the module comment.
        Avx512Lanes(unsafe { set1_512(x) })
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        // SAFETY: see the module comment. `vsqrtps`/`vsqrtpd` (default rounding mode) are
        // correctly rounded, as the scalar square root.
        Avx512Lanes(unsafe { sqrt512(self.0) })
    }

    #[inline(always)]
    fn abs(self) -> Self {
        // SAFETY: see the module comment. Clears the sign bit, as scalar `abs`.
        Avx512Lanes(unsafe { abs512(self.0) })
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        // As scalar `max(a, b)` on x86_64: `max(b, a)` returns `a` when the two are unordered
        // or equal, and `b` replaces a NaN `a`.
        // SAFETY: see the module comment.
        unsafe {
            let larger = max512(other.0, self.0);
            let self_is_nan = cmp512::<_CMP_UNORD_Q>(self.0, self.0);
            Avx512Lanes(blend512(self_is_nan, larger, other.0))
        }
    }

    #[inline(always)]
    fn sign(self) -> Self {
        // `1.0.copysign(self)`: the sign bit of `self` on the bits of 1.0.
        // SAFETY: see the module comment.
        unsafe {
            let sign_bit = to_bits512(set1_512(-0.0));
            let one = to_bits512(set1_512(1.0));
            Avx512Lanes(from_bits512(_mm512_or_si512(
                _mm512_and_si512(sign_bit, to_bits512(self.0)),
                one,
            )))
        }
    }

    register_lanes!(compare Avx512Mask: cmp512);

    #[inline(always)]
    fn none(mask: Avx512Mask) -> bool {
        mask.0 == 0
    }

    #[inline(always)]
    fn select(mask: Avx512Mask, a: Self, b: Self) -> Self {
        // SAFETY: see the module comment. Takes `a`'s lane where the mask bit is set.
        Avx512Lanes(unsafe { blend512(mask.0, b.0, a.0) })
    }

    register_lanes!(map);
}

impl LaneArray for Avx512Lanes {
    register_lanes!(array Avx512Lanes: Reg512, AVX512_WIDTH);

    #[inline(always)]
    fn exponent_part(self) -> Self {
        // SAFETY: see the module comment. The bits of +inf are the exponent field's mask.
        unsafe {
            let mask = to_bits512(set1_512(Real::INFINITY));
            Avx512Lanes(from_bits512(_mm512_and_si512(to_bits512(self.0), mask)))
        }
    }

    #[inline(always)]
    fn load_vec3s(chunk: &[Vec3]) -> Option<LaneVec3<Self>> {
        let [x, y, z] = vec3s_512(chunk)?;
        Some(LaneVec3::new(
            Avx512Lanes(x),
            Avx512Lanes(y),
            Avx512Lanes(z),
        ))
    }

    #[inline(always)]
    fn store_vec3s(v: LaneVec3<Self>, chunk: &mut [Vec3]) -> bool {
        store_vec3s_512([v.x.0, v.y.0, v.z.0], chunk)
    }
}

//! [`Lanes`] of four f32 in one WebAssembly `v128` (wasm32 built with `+simd128`).
//!
//! As `sse.rs` on x86_64: every operation is the packed form of the scalar one with the same
//! IEEE rounding (wasm's `f32x4` arithmetic and `sqrt` are correctly rounded, negation and
//! absolute value touch only the sign bit, comparisons are ordered), so lane `i` is bit for bit
//! what the scalar code computes. `max` alone runs lane by lane through `f32::max`: wasm's
//! `f32x4.max` propagates NaN where `f32::max` returns the other operand, and its pseudo-max
//! orders `-0` and `+0` by argument position, so the scalar operation is the only one certain to
//! give the scalar bits. Held in a register type rather than an array, which the compiler did not
//! vectorise here: a build with the 4-lane arrays of `portable.rs` stepped the web playground no
//! faster than the scalar path.
//!
//! The intrinsics are safe functions of `core::arch::wasm32`; this module is compiled only where
//! `simd128` is enabled for the whole crate, so calling them needs no `unsafe`.

use super::lanes::{LANES, Lane, LaneVec3, each_lane};
use super::types::{Real, Vec3};
use core::arch::wasm32::{
    f32x4, f32x4_abs, f32x4_add, f32x4_div, f32x4_extract_lane, f32x4_ge, f32x4_gt, f32x4_mul,
    f32x4_neg, f32x4_splat, f32x4_sqrt, f32x4_sub, i32x4_shuffle, v128, v128_and, v128_any_true,
    v128_bitselect, v128_or,
};
use core::ops::{Add, Div, Mul, Neg, Sub};

/// [`LANES`] independent values processed together (structure of arrays), in one `v128`.
#[derive(Clone, Copy, Debug)]
pub struct Lanes(v128);

/// Per-lane comparison results: all bits set where true.
#[derive(Clone, Copy, Debug)]
pub struct LaneMask(v128);

impl Lanes {
    /// The group holding `values`, lane `i` = `values[i]`.
    #[inline(always)]
    #[must_use]
    pub fn from_array(values: [Real; LANES]) -> Lanes {
        let [a, b, c, d] = values;
        Lanes(f32x4(a, b, c, d))
    }

    /// The values of the lanes, in order.
    #[inline(always)]
    #[must_use]
    pub fn to_array(self) -> [Real; LANES] {
        [
            f32x4_extract_lane::<0>(self.0),
            f32x4_extract_lane::<1>(self.0),
            f32x4_extract_lane::<2>(self.0),
            f32x4_extract_lane::<3>(self.0),
        ]
    }
}

macro_rules! binary_ops {
    ($($trait:ident $method:ident $intrinsic:ident),*) => {
        $(
            impl $trait for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn $method(self, other: Lanes) -> Lanes {
                    Lanes($intrinsic(self.0, other.0))
                }
            }
        )*
    };
}
binary_ops!(Add add f32x4_add, Sub sub f32x4_sub, Mul mul f32x4_mul, Div div f32x4_div);

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        // Flips the sign bit, as scalar negation does.
        Lanes(f32x4_neg(self.0))
    }
}

impl Lane for Lanes {
    type Mask = LaneMask;

    #[inline(always)]
    fn splat(x: Real) -> Self {
        Lanes(f32x4_splat(x))
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        // Correctly rounded, as `libm::sqrtf`.
        Lanes(f32x4_sqrt(self.0))
    }

    #[inline(always)]
    fn abs(self) -> Self {
        // Clears the sign bit, as `f32::abs` does.
        Lanes(f32x4_abs(self.0))
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        let (a, b) = (self.to_array(), other.to_array());
        Lanes::from_array([
            a[0].max(b[0]),
            a[1].max(b[1]),
            a[2].max(b[2]),
            a[3].max(b[3]),
        ])
    }

    #[inline(always)]
    fn sign(self) -> Self {
        // `1.0.copysign(self)`: the sign bit of `self` on the bits of 1.0.
        Lanes(v128_or(
            v128_and(self.0, f32x4_splat(-0.0)),
            f32x4_splat(1.0),
        ))
    }

    #[inline(always)]
    fn gt(self, other: Self) -> LaneMask {
        // Ordered: false where either lane is NaN.
        LaneMask(f32x4_gt(self.0, other.0))
    }

    #[inline(always)]
    fn ge(self, other: Self) -> LaneMask {
        // Ordered: false where either lane is NaN.
        LaneMask(f32x4_ge(self.0, other.0))
    }

    #[inline(always)]
    fn none(mask: LaneMask) -> bool {
        !v128_any_true(mask.0)
    }

    #[inline(always)]
    fn select(mask: LaneMask, a: Self, b: Self) -> Self {
        Lanes(v128_bitselect(a.0, b.0, mask.0))
    }

    #[inline(always)]
    fn map(self, f: impl Fn(Real) -> Real) -> Self {
        Lanes::from_array(each_lane(self.to_array(), f))
    }
}

/// The 4x4 transpose of `rows`: lane `j` of result `i` is lane `i` of `rows[j]` (how the
/// batched SVD turns four groups of entries into four matrices' rows, in registers).
#[inline(always)]
#[must_use]
pub(crate) fn transpose4(rows: [Lanes; 4]) -> [Lanes; 4] {
    let [Lanes(r0), Lanes(r1), Lanes(r2), Lanes(r3)] = rows;
    let a0_b0_a1_b1 = i32x4_shuffle::<0, 4, 1, 5>(r0, r1);
    let c0_d0_c1_d1 = i32x4_shuffle::<0, 4, 1, 5>(r2, r3);
    let a2_b2_a3_b3 = i32x4_shuffle::<2, 6, 3, 7>(r0, r1);
    let c2_d2_c3_d3 = i32x4_shuffle::<2, 6, 3, 7>(r2, r3);
    [
        Lanes(i32x4_shuffle::<0, 1, 4, 5>(a0_b0_a1_b1, c0_d0_c1_d1)),
        Lanes(i32x4_shuffle::<2, 3, 6, 7>(a0_b0_a1_b1, c0_d0_c1_d1)),
        Lanes(i32x4_shuffle::<0, 1, 4, 5>(a2_b2_a3_b3, c2_d2_c3_d3)),
        Lanes(i32x4_shuffle::<2, 3, 6, 7>(a2_b2_a3_b3, c2_d2_c3_d3)),
    ]
}

/// The vectors of [`LANES`] elements as lanes of coordinates (lane `i` holds `v[i]`): a 4x4
/// transpose of the rows `[x, y, z, 0]`.
#[inline(always)]
#[must_use]
pub fn transpose_vec3(v: [Vec3; LANES]) -> LaneVec3<Lanes> {
    let rows = each_lane(v, |p| Lanes(f32x4(p.x, p.y, p.z, 0.0)));
    let [x, y, z, _] = transpose4(rows);
    LaneVec3::new(x, y, z)
}

/// The inverse of [`transpose_vec3`]: lane `i` of the coordinates as `out[i]`.
#[inline(always)]
#[must_use]
pub fn untranspose_vec3(v: LaneVec3<Lanes>) -> [Vec3; LANES] {
    let rows = transpose4([v.x, v.y, v.z, Lanes::splat(0.0)]);
    each_lane(rows, |row| {
        Vec3::new(
            f32x4_extract_lane::<0>(row.0),
            f32x4_extract_lane::<1>(row.0),
            f32x4_extract_lane::<2>(row.0),
        )
    })
}

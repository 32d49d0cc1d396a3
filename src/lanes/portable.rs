//! [`Lanes`] as a plain array of [`LANES`] values, which the compiler vectorises as it can: the
//! representation for f64 and for targets without a hand-written one.

use super::lanes::{LANES, Lane, LaneVec3, each_lane};
use super::math;
use super::types::{Real, Vec3};
use core::ops::{Add, Div, Mul, Neg, Sub};

/// [`LANES`] independent values processed together (structure of arrays).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Lanes([Real; LANES]);

/// Per-lane comparison results: all bits set where true.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct LaneMask([math::Bits; LANES]);

impl Lanes {
    /// The group holding `values`, lane `i` = `values[i]`.
    #[inline(always)]
    #[must_use]
    pub fn from_array(values: [Real; LANES]) -> Lanes {
        Lanes(values)
    }

    /// The values of the lanes, in order.
    #[inline(always)]
    #[must_use]
    pub fn to_array(self) -> [Real; LANES] {
        self.0
    }

    /// Combines two groups lane by lane.
    #[inline(always)]
    #[must_use]
    pub(crate) fn zip(self, other: Lanes, f: impl Fn(Real, Real) -> Real) -> Lanes {
        let mut out = self;
        for (a, b) in out.0.iter_mut().zip(other.0) {
            *a = f(*a, b);
        }
        out
    }
}

macro_rules! lanes_binary_op {
    ($trait:ident, $method:ident, $op:tt) => {
        impl $trait for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, other: Lanes) -> Lanes {
                self.zip(other, |a, b| a $op b)
            }
        }
    };
}
lanes_binary_op!(Add, add, +);
lanes_binary_op!(Sub, sub, -);
lanes_binary_op!(Mul, mul, *);
lanes_binary_op!(Div, div, /);

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        Lanes(self.0.map(|a| -a))
    }
}

impl Lane for Lanes {
    type Mask = LaneMask;

    #[inline(always)]
    fn splat(x: Real) -> Self {
        Lanes([x; LANES])
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        Lanes(each_lane(self.0, math::sqrt))
    }

    #[inline(always)]
    fn abs(self) -> Self {
        Lanes(self.0.map(Real::abs))
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        self.zip(other, Real::max)
    }

    #[inline(always)]
    fn sign(self) -> Self {
        Lanes(self.0.map(|a| (1.0 as Real).copysign(a)))
    }

    #[inline(always)]
    fn gt(self, other: Self) -> LaneMask {
        let mut mask = LaneMask([0; LANES]);
        for ((m, a), b) in mask.0.iter_mut().zip(self.0).zip(other.0) {
            *m = if a > b { math::Bits::MAX } else { 0 };
        }
        mask
    }

    #[inline(always)]
    fn ge(self, other: Self) -> LaneMask {
        let mut mask = LaneMask([0; LANES]);
        for ((m, a), b) in mask.0.iter_mut().zip(self.0).zip(other.0) {
            *m = if a >= b { math::Bits::MAX } else { 0 };
        }
        mask
    }

    #[inline(always)]
    fn none(mask: LaneMask) -> bool {
        mask.0.iter().all(|&m| m == 0)
    }

    #[inline(always)]
    fn map(self, f: impl Fn(Real) -> Real) -> Self {
        Lanes(self.0.map(f))
    }

    #[inline(always)]
    fn select(mask: LaneMask, a: Self, b: Self) -> Self {
        let mut out = b;
        for ((o, m), a) in out.0.iter_mut().zip(mask.0).zip(a.0) {
            *o = Real::from_bits((a.to_bits() & m) | (o.to_bits() & !m));
        }
        out
    }
}

/// The 4x4 transpose of `rows`: lane `j` of result `i` is lane `i` of `rows[j]`.
#[inline(always)]
#[must_use]
pub(crate) fn transpose4(rows: [Lanes; 4]) -> [Lanes; 4] {
    core::array::from_fn(|i| {
        Lanes(core::array::from_fn(|j| {
            rows.get(j)
                .and_then(|row| row.0.get(i))
                .copied()
                .unwrap_or(0.0)
        }))
    })
}

/// The vectors of [`LANES`] elements as lanes of coordinates (lane `i` holds `v[i]`).
#[inline(always)]
#[must_use]
pub fn transpose_vec3(v: [Vec3; LANES]) -> LaneVec3<Lanes> {
    LaneVec3::new(
        Lanes(v.map(|p| p.x)),
        Lanes(v.map(|p| p.y)),
        Lanes(v.map(|p| p.z)),
    )
}

/// The inverse of [`transpose_vec3`]: lane `i` of the coordinates as `out[i]`.
#[inline(always)]
#[must_use]
pub fn untranspose_vec3(v: LaneVec3<Lanes>) -> [Vec3; LANES] {
    let (x, y, z) = (v.x.0, v.y.0, v.z.0);
    core::array::from_fn(|i| match (x.get(i), y.get(i), z.get(i)) {
        (Some(&x), Some(&y), Some(&z)) => Vec3::new(x, y, z),
        _ => Vec3::ZERO,
    })
}

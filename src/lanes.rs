//! One numeric algorithm, run on one value or on several at once.
//!
//! The SVD (and later kernels) are written once against `Lane`: implemented by the plain scalar
//! [`Real`] and by [`Lanes`], a fixed group of independent values that the compiler maps onto
//! SIMD registers. Every operation is element-wise and IEEE-correctly rounded in both, so a value
//! computed in lane `i` is bit-for-bit the value the scalar code computes for the same input.
//! Comparisons give masks and conditionals are selects, so no lane ever branches.

use super::math;
use super::types::Real;
use core::ops::{Add, Div, Mul, Neg, Sub};

/// Number of values a [`Lanes`] holds: 4 in both precisions (one SSE register of f32, two of f64).
pub const LANES: usize = math::LANES;

/// A scalar-like number type: [`Real`] itself or a group of [`Lanes`].
pub(crate) trait Lane:
    Copy
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
    /// `mask ? a : b`, per lane, without branching.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
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
    fn select(mask: bool, a: Self, b: Self) -> Self {
        math::select(mask, a, b)
    }
}

/// [`LANES`] independent values processed together (structure of arrays).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct Lanes(pub [Real; LANES]);

/// Per-lane comparison results: all bits set where true.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct LaneMask([math::Bits; LANES]);

impl Lanes {
    /// Applies `f` to every lane.
    #[inline(always)]
    #[must_use]
    pub fn map(self, f: impl Fn(Real) -> Real) -> Lanes {
        Lanes(self.0.map(f))
    }

    /// Combines two groups lane by lane.
    #[inline(always)]
    #[must_use]
    pub fn zip(self, other: Lanes, f: impl Fn(Real, Real) -> Real) -> Lanes {
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
        self.map(|a| -a)
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
        Lanes(math::sqrt_lanes(self.0))
    }

    #[inline(always)]
    fn abs(self) -> Self {
        self.map(Real::abs)
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        self.zip(other, Real::max)
    }

    #[inline(always)]
    fn sign(self) -> Self {
        self.map(|a| (1.0 as Real).copysign(a))
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
    fn select(mask: LaneMask, a: Self, b: Self) -> Self {
        let mut out = b;
        for ((o, m), a) in out.0.iter_mut().zip(mask.0).zip(a.0) {
            *o = Real::from_bits((a.to_bits() & m) | (o.to_bits() & !m));
        }
        out
    }
}

/// A 3-vector of lane values.
#[derive(Clone, Copy)]
pub(crate) struct V3<L> {
    pub x: L,
    pub y: L,
    pub z: L,
}

impl<L: Lane> V3<L> {
    #[inline(always)]
    pub fn new(x: L, y: L, z: L) -> Self {
        V3 { x, y, z }
    }

    #[inline(always)]
    pub fn dot(self, o: Self) -> L {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    pub fn scale(self, k: L) -> Self {
        V3::new(self.x * k, self.y * k, self.z * k)
    }

    #[inline(always)]
    pub fn add(self, o: Self) -> Self {
        V3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }

    #[inline(always)]
    pub fn sub(self, o: Self) -> Self {
        V3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }

    #[inline(always)]
    pub fn neg(self) -> Self {
        V3::new(-self.x, -self.y, -self.z)
    }

    /// `mask ? a : b` per lane.
    #[inline(always)]
    pub fn select(mask: L::Mask, a: Self, b: Self) -> Self {
        V3::new(
            L::select(mask, a.x, b.x),
            L::select(mask, a.y, b.y),
            L::select(mask, a.z, b.z),
        )
    }
}

/// A 3x3 matrix of lane values, stored as columns (like glam).
#[derive(Clone, Copy)]
pub(crate) struct M3<L> {
    pub c0: V3<L>,
    pub c1: V3<L>,
    pub c2: V3<L>,
}

impl<L: Lane> M3<L> {
    #[inline(always)]
    pub fn identity() -> Self {
        let (o, z) = (L::splat(1.0), L::splat(0.0));
        M3 {
            c0: V3::new(o, z, z),
            c1: V3::new(z, o, z),
            c2: V3::new(z, z, o),
        }
    }

    #[inline(always)]
    pub fn transpose(self) -> Self {
        M3 {
            c0: V3::new(self.c0.x, self.c1.x, self.c2.x),
            c1: V3::new(self.c0.y, self.c1.y, self.c2.y),
            c2: V3::new(self.c0.z, self.c1.z, self.c2.z),
        }
    }

    /// `self * v`.
    #[inline(always)]
    pub fn mul_vec(self, v: V3<L>) -> V3<L> {
        self.c0
            .scale(v.x)
            .add(self.c1.scale(v.y))
            .add(self.c2.scale(v.z))
    }

    /// `self * other`.
    #[inline(always)]
    pub fn mul(self, other: Self) -> Self {
        M3 {
            c0: self.mul_vec(other.c0),
            c1: self.mul_vec(other.c1),
            c2: self.mul_vec(other.c2),
        }
    }

    #[inline(always)]
    pub fn scale(self, k: L) -> Self {
        M3 {
            c0: self.c0.scale(k),
            c1: self.c1.scale(k),
            c2: self.c2.scale(k),
        }
    }

    #[inline(always)]
    pub fn sub(self, o: Self) -> Self {
        M3 {
            c0: self.c0.sub(o.c0),
            c1: self.c1.sub(o.c1),
            c2: self.c2.sub(o.c2),
        }
    }
}

//! Transcendental and bit-level helpers of this precision.
//!
//! This shim is the one place that decides where square roots and exponents come from: always
//! `libm`, so results do not depend on the platform's C library or on the `std` feature.

use super::types::Real;

/// Whether the mesh kernels batch their SVDs with `svd3_lanes` (see the f32 shim).
pub const BATCH_SVD: bool = cfg!(any(target_arch = "x86_64", target_arch = "aarch64"));

/// Whether the direct force kernels evaluate [`LANES`] elements at a time (see the f32
/// shim): where [`Lanes`](super::lanes::Lanes) are SSE2 registers (x86_64).
pub const BATCH_FORCES: bool = cfg!(target_arch = "x86_64");

/// Whether the relaxation's vertex passes run [`LANES`] vertices at a time (see the f32
/// shim).
pub const BATCH_VERTICES: bool = cfg!(target_arch = "x86_64");

/// Whether stable neo-Hookean's `ln(1 + y)` uses its own series (see the f32 shim): in f64
/// for `-0.3 <= y <= 1/2` (`|s| <= 1/5`, ten terms of `q` instead of f32's seven), where
/// `libm::log1p` lane by lane made the energy pass cost as much as the force pass (15.1
/// against 15.7 ns a tetrahedron, 10 368 tetrahedra, AVX-512).
pub const SERIES_LN_1P: bool = true;

/// The middle and half-width of the `y` range of the `ln(1 + y)` series: `[-0.3, 0.5]`,
/// where `|s| = |y / (2 + y)| <= 1/5`.
pub const LN_1P_SERIES_RANGE: (Real, Real) = (0.1, 0.4);

/// Whether `svd3_batch` at the SSE width runs pairs of [`Lanes`](super::lanes::Lanes): not in
/// f64, whose group is already two SSE2 registers; a pair (four) measured 1.1x slower than
/// single groups on an AMD EPYC.
#[cfg_attr(debug_assertions, allow(dead_code))] // Unoptimised builds use no pairs.
pub const SSE_PAIRS: bool = false;

/// Jacobi sweeps used by [`svd3`](super::svd::svd3) in this precision.
pub const DEFAULT_SVD_SWEEPS: u32 = 4;

/// Magnitudes below this are treated as zero inside the SVD, whose working scale is of
/// order one. Chosen so that the square of anything larger is still a normal number.
pub const TINY: Real = 1e-150;

/// Square root (correctly rounded, IEEE 754). Software on FPUs without double precision
/// (Cortex-M4F), like every f64 operation there.
#[inline(always)]
#[must_use]
pub fn sqrt(x: Real) -> Real {
    libm::sqrt(x)
}

/// The unsigned integer with the bit width of `Real` (the portable lanes' masks).
#[cfg(not(target_arch = "x86_64"))]
pub type Bits = u64;

/// Values per [`Lanes`](super::lanes::Lanes) group: two SSE2 registers of f64 (4 measured
/// faster than 2).
pub const LANES: usize = 4;

/// Real cube root (`cbrt(-8) = -2`).
#[inline(always)]
#[must_use]
pub fn cbrt(x: Real) -> Real {
    libm::cbrt(x)
}

/// The angle of `(x, y)` from the positive x axis, in `[-pi, pi]` (radians).
#[inline(always)]
#[must_use]
pub fn atan2(y: Real, x: Real) -> Real {
    libm::atan2(y, x)
}

/// The natural logarithm `ln(x)` (`-inf` at 0, NaN below).
#[inline(always)]
#[must_use]
pub fn ln(x: Real) -> Real {
    libm::log(x)
}

/// `ln(1 + x)`, accurate for small `x`.
#[inline(always)]
#[must_use]
pub fn ln_1p(x: Real) -> Real {
    libm::log1p(x)
}

/// The unbiased binary exponent of a finite non-zero `x`: `2^e <= |x| < 2^(e+1)`.
#[inline(always)]
#[must_use]
pub fn exponent(x: Real) -> i32 {
    let biased = ((x.to_bits() >> 52) & 2047) as i32;
    if biased == 0 {
        // Subnormal: rare, and the bit trick does not apply.
        libm::ilogb(x)
    } else {
        biased - 1023
    }
}

/// `2^n` for `n` in the normal range `[-1022, 1023]` (exact).
#[inline(always)]
#[must_use]
pub fn pow2(n: i32) -> Real {
    Real::from_bits((((n + 1023) as u64) & 2047) << 52)
}

/// `(sin x, cos x)` (x in radians).
#[inline(always)]
#[must_use]
pub fn sin_cos(x: Real) -> (Real, Real) {
    (libm::sin(x), libm::cos(x))
}

/// `if condition { a } else { b }` as bit masking, so that it never becomes a branch.
#[inline(always)]
#[must_use]
pub fn select(condition: bool, a: Real, b: Real) -> Real {
    let mask = (u64::from(condition)).wrapping_neg();
    Real::from_bits((a.to_bits() & mask) | (b.to_bits() & !mask))
}

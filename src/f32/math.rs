//! Transcendental and bit-level helpers of this precision.
//!
//! This shim is the one place that decides where square roots and exponents come from: `libm`
//! (or, for the square root, an instruction that rounds the same), so results do not depend on
//! the platform's C library or on the `std` feature.

use super::types::Real;

/// Whether the mesh kernels batch their SVDs with `svd3_lanes` (same bits as `svd3`): where
/// the [`Lanes`](super::lanes::Lanes) arithmetic has 128-bit SIMD registers to run in —
/// x86_64 (SSE, measured 3.3x faster per matrix) and aarch64 (NEON; not measured here).
/// Without SIMD the four interleaved chains only spill: on a Cortex-M4F `svd3_lanes`
/// measured 21 710 instructions per matrix against 3 360 for `svd3` (`tests/firmware.rs`).
pub const BATCH_SVD: bool = cfg!(any(target_arch = "x86_64", target_arch = "aarch64"));

/// Whether the direct force kernels evaluate [`LANES`] elements at a time through
/// [`Material::first_piola_lanes`](super::material::Material::first_piola_lanes) (same bits
/// as one at a time): where [`Lanes`](super::lanes::Lanes) is an SSE register (x86_64),
/// measured twice as fast as the scalar loop on a 105k-tet box.
pub const BATCH_FORCES: bool = cfg!(target_arch = "x86_64");

/// Whether the relaxation's vertex passes run [`LANES`] vertices at a time (same bits as one
/// at a time, and the same sums): on x86_64, where it made a relaxation iteration on a
/// 105k-tet box 1.42x -> 1.29x a force evaluation. Not on a Cortex-M4F: there the grouped
/// passes took 2.3x the instructions per vertex iteration (4 020 against 1 744), 3.5x the
/// code (50 258 against 14 340 B) and 3.8x the stack (4 144 against 1 104 B) of `relax_step`
/// (`tests/firmware.rs`).
pub const BATCH_VERTICES: bool = cfg!(target_arch = "x86_64");

/// Whether stable neo-Hookean's `ln(1 + y)` uses its own series for `|y| <= 1/2` (same code
/// for one value and for a group of lanes, so both give the same bits, within 2 ulp of the
/// correctly rounded result) instead of `libm` lane by lane.
pub const SERIES_LN_1P: bool = true;

/// The middle and half-width of the `y` range of the `ln(1 + y)` series: `[-1/2, 1/2]`,
/// where `|s| = |y / (2 + y)| <= 1/3`.
pub const LN_1P_SERIES_RANGE: (Real, Real) = (0.0, 0.5);

/// Whether `svd3_batch` at the SSE width runs pairs of [`Lanes`](super::lanes::Lanes)
/// (two registers, 8 matrices in flight): 1.25x faster than single groups on an AMD EPYC.
#[cfg_attr(debug_assertions, allow(dead_code))] // Unoptimised builds use no pairs.
pub const SSE_PAIRS: bool = true;

/// Jacobi sweeps used by [`svd3`](super::svd::svd3) in this precision.
pub const DEFAULT_SVD_SWEEPS: u32 = 4;

/// Magnitudes below this are treated as zero inside the SVD, whose working scale is of
/// order one. Chosen so that the square of anything larger is still a normal number.
pub const TINY: Real = 1e-18;

/// Square root (correctly rounded, IEEE 754).
///
/// On Arm targets with the hard-float ABI (`eabihf`: Cortex-M4F/M7, Cortex-A) the FPU's
/// `vsqrt.f32`, which every VFP version and the Cortex-M FPUs have; elsewhere `libm::sqrtf`
/// (itself `sqrtss` on x86_64). `libm::sqrtf` is a software routine on Arm: about 92
/// instructions a call on a Cortex-M4F against 4 (measured by `tests/firmware.rs`). Both are
/// correctly rounded, so the two give the same bits.
#[inline(always)]
#[must_use]
pub fn sqrt(x: Real) -> Real {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let root: Real;
        // SAFETY: `eabihf` implies a VFP/FPv4+ unit with `vsqrt.f32`. The value passes through
        // a core register (the `sreg` operand class needs the `vfp2` feature, which
        // single-precision-only FPUs such as the Cortex-M4F's do not report); `s0` is
        // declared clobbered; no memory or stack is touched.
        unsafe {
            core::arch::asm!(
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {x}, s0",
                x = inout(reg) x => root,
                out("s0") _,
                options(pure, nomem, nostack),
            );
        }
        root
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// The unsigned integer with the bit width of `Real` (the portable lanes' masks).
#[cfg(not(any(
    target_arch = "x86_64",
    all(target_arch = "wasm32", target_feature = "simd128")
)))]
pub type Bits = u32;

/// Values per [`Lanes`](super::lanes::Lanes) group: one SSE register of f32.
pub const LANES: usize = 4;

/// Real cube root (`cbrt(-8) = -2`).
#[inline(always)]
#[must_use]
pub fn cbrt(x: Real) -> Real {
    libm::cbrtf(x)
}

/// The angle of `(x, y)` from the positive x axis, in `[-pi, pi]` (radians).
#[inline(always)]
#[must_use]
pub fn atan2(y: Real, x: Real) -> Real {
    libm::atan2f(y, x)
}

/// The natural logarithm `ln(x)` (`-inf` at 0, NaN below).
#[inline(always)]
#[must_use]
pub fn ln(x: Real) -> Real {
    libm::logf(x)
}

/// `ln(1 + x)`, accurate for small `x`.
#[inline(always)]
#[must_use]
pub fn ln_1p(x: Real) -> Real {
    libm::log1pf(x)
}

/// The unbiased binary exponent of a finite non-zero `x`: `2^e <= |x| < 2^(e+1)`.
#[inline(always)]
#[must_use]
pub fn exponent(x: Real) -> i32 {
    let biased = ((x.to_bits() >> 23) & 255) as i32;
    if biased == 0 {
        // Subnormal: rare, and the bit trick does not apply.
        libm::ilogbf(x)
    } else {
        biased - 127
    }
}

/// `2^n` for `n` in the normal range `[-126, 127]` (exact).
#[inline(always)]
#[must_use]
pub fn pow2(n: i32) -> Real {
    Real::from_bits((((n + 127) as u32) & 255) << 23)
}

/// `(sin x, cos x)` (x in radians).
#[inline(always)]
#[must_use]
pub fn sin_cos(x: Real) -> (Real, Real) {
    (libm::sinf(x), libm::cosf(x))
}

/// `if condition { a } else { b }` as bit masking, so that it never becomes a branch.
#[inline(always)]
#[must_use]
pub fn select(condition: bool, a: Real, b: Real) -> Real {
    let mask = (u32::from(condition)).wrapping_neg();
    Real::from_bits((a.to_bits() & mask) | (b.to_bits() & !mask))
}

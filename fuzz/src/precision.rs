//! Float draws in this precision (`Real`), included once per precision by `lib.rs`.

use super::Bits;
use super::sf::types::Real;
use crate::Draw;
use crate::draw::FromDraw;

/// Values where floating-point code tends to break: zeros, units, the ends of the normal and
/// subnormal ranges, `eps`, the magnitudes of the known SVD defect, the non-finite values.
const SPECIAL: [Real; 22] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    2.0,
    -3.0,
    1e-3,
    1e3,
    1e19,
    -1e19,
    1e-20,
    Real::EPSILON,
    Real::MIN_POSITIVE,
    -Real::MIN_POSITIVE,
    Real::MAX,
    Real::MIN,
    1.0e-45,
    Real::INFINITY,
    Real::NEG_INFINITY,
    Real::NAN,
    1e30,
];

/// Any bit pattern.
pub fn raw(draw: &mut Draw<'_>) -> Real {
    Real::from_bits(Bits::raw(draw))
}

/// One of [`SPECIAL`].
pub fn special(draw: &mut Draw<'_>) -> Real {
    SPECIAL[draw.index(SPECIAL.len() - 1)]
}

/// Any value: a special one, a grid value (see [`grid`]) or any bit pattern.
pub fn wild(draw: &mut Draw<'_>) -> Real {
    match draw.up_to(3) {
        0 => special(draw),
        1 => grid(draw, 1.0),
        _ => raw(draw),
    }
}

/// A finite value drawn as [`wild`]: NaN and infinities have their top exponent bit cleared.
pub fn finite(draw: &mut Draw<'_>) -> Real {
    let x = wild(draw);
    if x.is_finite() {
        x
    } else {
        let top_exponent_bit: Bits = 1 << (Bits::BITS - 2);
        Real::from_bits(x.to_bits() & !top_exponent_bit)
    }
}

/// `scale` times a grid value in `[-8, 8)` with step `1/4096`: exact in both precisions, and
/// exactly repeating (coplanar, coincident) often enough to reach the degenerate cases.
pub fn grid(draw: &mut Draw<'_>, scale: Real) -> Real {
    Real::from(draw.i16()) / 4096.0 * scale
}

/// A coarse grid value in `[-8, 8)` with step `1/16` (coplanar points are common).
pub fn coarse(draw: &mut Draw<'_>) -> Real {
    Real::from(draw.i16() >> 8) / 16.0
}

/// `10^k` times a value in `[1, 2)`, `k` in `lo..=hi`: a modulus or density of the documented
/// (physical) range.
pub fn magnitude(draw: &mut Draw<'_>, lo: i32, hi: i32) -> Real {
    let span = u32::try_from(hi - lo).unwrap_or(0);
    let k = lo + i32::try_from(draw.up_to(span)).unwrap_or(0);
    let mantissa = 1.0 + Real::from(draw.up_to(15) as u8) / 16.0;
    mantissa * (10.0 as Real).powi(k)
}

/// A Poisson ratio in `[-0.9, 0.48]`, inside the valid `(-1, 1/2)`.
pub fn poisson(draw: &mut Draw<'_>) -> Real {
    Real::from(draw.up_to(138) as u8) / 100.0 - 0.9
}

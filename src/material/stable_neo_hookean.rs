//! Stable neo-Hookean (Smith, de Goes, Kim 2018): smooth through inversion.

use super::{
    Lame, Lane, LaneMat3, Lanes, Mat3, Material, MaterialError, Real, Vec3, cofactor,
    frobenius_squared, invariant_deviations, invariant_first_piola, math,
    principal_invariant_deviations,
};

/// Stable neo-Hookean: Smith, de Goes, Kim, "Stable Neo-Hookean Flesh Simulation" (ACM TOG
/// 2018), as in `docs/math.md` section 2. With `I_C = tr(F^T F)`, `J = det F` and the paper's
/// constants `m = 4 mu / 3`, `l = lambda + 5 mu / 6`, `a = 1 + 3 m / (4 l)` (chosen so that the
/// model linearises to `(lambda, mu)`),
/// `W = m/2 (I_C - 3) + l/2 (J - a)^2 - m/2 ln(I_C + 1) - W0`, where the constant
/// `W0 = l/2 (1 - a)^2 - m/2 ln 4` makes `W(I) = 0`, and
/// `P = m (1 - 1/(I_C + 1)) F + l (J - a) cof(F)`.
///
/// Finite and smooth for every `F` with `max |F_ij|` up to
/// [`deformation_limit`](Material::deformation_limit),
/// `((Real::MAX / 2^24) / (256 (|lambda| + mu)))^(1/6)` rounded down to a power of two (its
/// energy grows like `|F|^6`): `4096` in f32 and `5.8e48` in f64 for `E = 1 MPa`, `nu = 0.3`, including flat (`J = 0`) and inverted
/// (`J < 0`) elements, which it pushes back towards `J > 0`: the model to use whenever elements
/// may invert, and with energy-based solvers. Beyond the limit (`F = 1e20 I` in f32) the values
/// overflow, and the mesh kernels refuse such deformations with an error.
///
/// The energy is evaluated in the algebraically equal form
/// `W = 2 mu / 3 ((I_C - 3) - ln(1 + (I_C - 3) / 4)) + (J - 1) (l (J - 1) - 2 mu) / 2`
/// (using `l (a - 1) = mu`), which is exactly zero at rest and keeps its accuracy at small
/// strain instead of subtracting the constant `W0` from terms of order `lambda`. `I_C - 3` and
/// `J - 1` are formed from `F - I` rather than by subtraction (see `invariant_deviations` in
/// `material/mod.rs`), so that at a small strain `e` the energy's rounding error is of order
/// `eps mu e` (as StVK's), not `eps mu`: a line search comparing the energies of nearby states
/// of a large f32 mesh depends on it.
///
/// ```
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::material::{Material, StableNeoHookean};
///
/// let snh = StableNeoHookean::from_lame(2.0e6, 1.0e6)?;
/// // Flat and inverted elements have finite energy and a stress pushing them back (P_zz < 0
/// // lowers the energy as the z-stretch grows).
/// for t in [0.0, -0.5] {
///     let f = Mat3::from_diagonal(Vec3::new(1.0, 1.0, t));
///     assert!(snh.energy_density(f).is_finite());
///     assert!(snh.first_piola(f).z_axis.z < 0.0);
/// }
/// # Ok::<(), softfem::MaterialError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StableNeoHookean {
    lame: Lame,
    /// The paper's volume stiffness `l = lambda + 5 mu / 6` (Pa); at least `mu / 6 > 0` for
    /// valid [`Lame`] parameters.
    volume_stiffness: Real,
}

impl StableNeoHookean {
    /// The model with the given (already validated) Lamé parameters.
    #[inline]
    #[must_use]
    pub const fn new(lame: Lame) -> StableNeoHookean {
        StableNeoHookean {
            lame,
            volume_stiffness: lame.lambda() + 5.0 * lame.mu() / 6.0,
        }
    }

    /// `W` in the cancellation-free form of the type's documentation, from
    /// `(I_C - 3, J - 1)` ([`invariant_deviations`]).
    #[inline(always)]
    fn energy<L: Lane>(&self, ic_minus_3: L, j_minus_1: L) -> L {
        let mu = self.lame.mu();
        let logarithm = ln_1p(L::splat(0.25) * ic_minus_3);
        let shear = L::splat(2.0 * mu / 3.0) * (ic_minus_3 - logarithm);
        shear
            + L::splat(0.5)
                * j_minus_1
                * (L::splat(self.volume_stiffness) * j_minus_1 - L::splat(2.0 * mu))
    }

    /// `(2 dW/dI_C, dW/dJ) = (m I_C / (I_C + 1), l (J - a))`, with `l (J - a) = l (J - 1) - mu`.
    /// The stress does not need the cancellation-free invariants: its terms are of order `mu`
    /// and its rounding error of order `eps mu`, as every model's.
    #[inline(always)]
    fn stress_coefficients<L: Lane>(&self, ic: L, j: L) -> (L, L) {
        let mu = L::splat(self.lame.mu());
        // (4 I_C) / (3 (I_C + 1)) is exactly 1 at rest (12/12), so P(I) = mu I - mu I = 0.
        (
            mu * ((L::splat(4.0) * ic) / (L::splat(3.0) * (ic + L::splat(1.0)))),
            L::splat(self.volume_stiffness) * (j - L::splat(1.0)) - mu,
        )
    }

    /// `(W_II, W_IJ, W_JJ) = (m / (2 (I_C + 1)^2), 0, l)` with `m = 4 mu / 3`: the second
    /// derivatives of `W(I_C, J)` (`docs/math.md` section 6).
    #[inline(always)]
    fn hessian_coefficients<L: Lane>(&self, ic: L, _j: L) -> (L, L, L) {
        let shifted = ic + L::splat(1.0);
        (
            L::splat(2.0 * self.lame.mu() / 3.0) / (shifted * shifted),
            L::splat(0.0),
            L::splat(self.volume_stiffness),
        )
    }

    /// `(W, P)` from one cofactor matrix, for one value or a group of lanes.
    #[inline(always)]
    /// The operations of `invariant_energy_and_first_piola`, written out: its closures are not
    /// `inline(always)`, and one left out of line runs without the SIMD function's registers.
    fn energy_and_stress<L: Lane>(&self, f: LaneMat3<L>) -> (L, LaneMat3<L>) {
        let cof = cofactor(f);
        let (ic_minus_3, j_minus_1) = invariant_deviations(f, cof.c0);
        let energy = self.energy(ic_minus_3, j_minus_1);
        let j = f.c0.dot(cof.c0);
        let (a, b) = self.stress_coefficients(frobenius_squared(f), j);
        (energy, f.scale(a) + cof.scale(b))
    }
}

lame_constructors!(StableNeoHookean);

/// `ln(1 + y)` of every lane. Where [`math::SERIES_LN_1P`], lanes in the series range
/// [`math::LN_1P_SERIES_RANGE`] (`|y| <= 1/2` in f32, `-0.3 <= y <= 1/2` in f64: strains up to
/// about 40 and 25 %, the common case) take `2 atanh(s)`, `s = y / (2 + y)`, summed to the
/// `s^15` term in f32 (`|s| <= 1/3`, truncation below `2e-9` relative) and to the `s^21` term in
/// f64 (`|s| <= 1/5`, below `2e-17`), which vectorises; the others take `libm`'s `log1p`. Each
/// lane's result depends on its own value only, so one value and a group of lanes give the same
/// bits.
#[inline(always)]
fn ln_1p<L: Lane>(y: L) -> L {
    if !math::SERIES_LN_1P {
        return y.map(math::ln_1p);
    }
    let (middle, half_width) = math::LN_1P_SERIES_RANGE;
    let s = y / (L::splat(2.0) + y);
    // 2 atanh(s) = 2 s + 2 s^3 q(s^2), q = 1/3 + s^2/5 + s^4/7 + ..., with q by Estrin's scheme
    // (a dependency chain half as long as Horner's) and the leading term added last.
    // `s^2` is raised to at least eps/8: below that, 2 s^3 q is under half an ulp of 2 s, so
    // the result is 2 s either way, and `s^8` (f32) or `s^16` (f64) never becomes subnormal
    // (slow on x86).
    let s2 = (s * s).max(L::splat(Real::EPSILON / 8.0));
    let s4 = s2 * s2;
    let c = |k: Real| L::splat(1.0 / k);
    let q = if Real::MANTISSA_DIGITS <= 24 {
        (c(3.0) + c(5.0) * s2)
            + (c(7.0) + c(9.0) * s2) * s4
            + ((c(11.0) + c(13.0) * s2) + c(15.0) * s4) * (s4 * s4)
    } else {
        let s8 = s4 * s4;
        ((c(3.0) + c(5.0) * s2) + (c(7.0) + c(9.0) * s2) * s4)
            + ((c(11.0) + c(13.0) * s2) + (c(15.0) + c(17.0) * s2) * s4) * s8
            + (c(19.0) + c(21.0) * s2) * (s8 * s8)
    };
    let twice_s = L::splat(2.0) * s;
    let series = twice_s + (twice_s * s2) * q;
    // NaN is not outside: it stays on the series, which returns NaN. (In f32 the middle is 0,
    // and `y - 0` is `y`.)
    let outside = (y - L::splat(middle)).abs().gt(L::splat(half_width));
    if L::none(outside) {
        return series;
    }
    let exact = y.map(|y| {
        if (y - middle).abs() > half_width {
            math::ln_1p(y)
        } else {
            0.0
        }
    });
    L::select(outside, exact, series)
}

impl Material for StableNeoHookean {
    #[inline]
    fn deformation_limit(&self) -> Real {
        super::deformation_limit_for(self.lame.lambda().abs() + self.lame.mu(), 6)
    }

    #[inline]
    fn energy_density(&self, f: Mat3) -> Real {
        let f = LaneMat3::from(f);
        let (ic_minus_3, j_minus_1) = invariant_deviations(f, f.c1.cross(f.c2));
        self.energy(ic_minus_3, j_minus_1)
    }

    #[inline(always)]
    fn energy_density_wide<L: Lane>(&self, f: LaneMat3<L>) -> L {
        let (ic_minus_3, j_minus_1) = invariant_deviations(f, f.c1.cross(f.c2));
        self.energy(ic_minus_3, j_minus_1)
    }

    #[inline]
    fn principal_energy(&self, s: Vec3) -> Real {
        let (ic_minus_3, j_minus_1) = principal_invariant_deviations(s);
        self.energy(ic_minus_3, j_minus_1)
    }

    invariant_stress_methods!();
    invariant_hessian_methods!();
}

#[cfg(test)]
// Compiled for both precisions: the conversions to f64 are no-ops in the f64 instantiation.
#[allow(clippy::unnecessary_cast, clippy::useless_conversion)]
mod tests {
    use super::{Real, ln_1p, math};

    /// Units in the last place between `x` and the f64 value `exact`: the distance over the
    /// spacing of this precision's values just above `|exact|` rounded (the ulp of a power of
    /// two is the larger of its two neighbours' spacings, so the measure never exaggerates).
    fn ulps(x: Real, exact: f64) -> f64 {
        let rounded = (exact as Real).abs();
        let ulp = f64::from(rounded.next_up() - rounded);
        (f64::from(x) - exact).abs() / ulp
    }

    #[test]
    fn ln_1p_is_within_two_ulp_over_and_beyond_the_series_range() {
        let mut worst: f64 = 0.0;
        for i in 0..=200_000 {
            // -0.75 (I_C = 0) to 2.25, denser near zero.
            let t = f64::from(i) / 200_000.0;
            let y = (-0.75 + 3.0 * t * t) as Real;
            let exact = libm::log1p(f64::from(y));
            worst = worst.max(ulps(ln_1p(y), exact));
        }
        std::println!("ln_1p: worst {worst} ulp from libm's log1p");
        assert!(worst <= 2.0, "worst error {worst} ulp");
        for y in [
            0.0, -0.0, 1e-30, -1e-30, 1e-7, 0.5, -0.5, 0.500_001, -0.3, -0.300_001, 100.0,
        ] {
            let exact = libm::log1p(f64::from(y));
            assert!(ulps(ln_1p(y), exact) <= 2.0, "ln_1p({y}) = {}", ln_1p(y));
        }
        assert!(ln_1p(Real::NAN).is_nan());
        assert_eq!(ln_1p(Real::INFINITY), Real::INFINITY);
        assert_eq!(ln_1p(-1.0), Real::NEG_INFINITY);
    }

    /// The series range of the constants is the one `ln_1p`'s documentation states:
    /// `|y| <= 1/2` in f32, `-0.3 <= y <= 1/2` in f64, with the range test `ln_1p` applies.
    #[test]
    fn ln_1p_series_range_is_the_documented_one() {
        const { assert!(math::SERIES_LN_1P) };
        let (middle, half_width) = math::LN_1P_SERIES_RANGE;
        let inside = |y: Real| (y - middle).abs() <= half_width;
        let low: Real = if Real::MANTISSA_DIGITS <= 24 {
            -0.5
        } else {
            -0.3
        };
        assert!(
            inside(low) && inside(0.0) && inside(0.5),
            "{middle} +- {half_width}"
        );
        assert!(
            !inside(low - 1e-3) && !inside(0.5 + 1e-3),
            "{middle} +- {half_width}"
        );
        assert!(!inside((0.5 as Real).next_up()));
    }
}

//! The log barrier of Incremental Potential Contact on squared distances (`docs/math.md`
//! section 8.6).
//!
//! `b(d2) = -(d2 - dhat2)^2 ln(d2 / dhat2)` for `0 < d2 < dhat2`, 0 from `dhat2` on, as the IPC
//! Toolkit (Z. Ferguson et al., 2020) writes the barrier of M. Li et al., "Incremental
//! Potential Contact: Intersection- and Inversion-free, Large-Deformation Dynamics" (ACM
//! Transactions on Graphics 39(4), 2020) in terms of squared distances, which need no square
//! root. With `d2` and `dhat2` in m^2, `b` is in m^4, `db/dd2` in m^2 and `d2b/dd2^2`
//! dimensionless; the caller multiplies by a stiffness `kappa` (J/m^4) to make it an energy.
//!
//! The barrier is C2 at `dhat2` (value, slope and curvature all reach 0 there), positive and
//! decreasing inside, and grows without bound as `d2 -> 0`: at `d2 <= 0` (touching or
//! through) it is `+inf`, so that a line search refuses the step.

use super::super::super::math::{ln, ln_1p};
use super::super::super::types::Real;

/// The barrier and its first two derivatives with respect to the squared distance.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BarrierDerivatives {
    /// `b(d2)` (m^4): `+inf` at `d2 <= 0`, 0 from `dhat2` on.
    pub value: Real,
    /// `db/dd2` (m^2): `<= 0`; `-inf` at `d2 <= 0`.
    pub first: Real,
    /// `d2b/dd2^2` (dimensionless): `>= 0`; `+inf` at `d2 <= 0`.
    pub second: Real,
}

/// `ln(d2 / dhat2)` for `0 < d2 < dhat2`, accurate to a few ulp across the range: near
/// `dhat2`, where the barrier's value is decided, `ln_1p` of the exactly computed difference
/// (Sterbenz: `d2 - dhat2` is exact for `d2 >= dhat2 / 2`); below, the plain logarithm of the
/// ratio, whose magnitude is then at least `ln 2`.
#[inline]
fn log_ratio(d2: Real, dhat2: Real) -> Real {
    if d2 >= 0.5 * dhat2 {
        ln_1p((d2 - dhat2) / dhat2)
    } else {
        ln(d2 / dhat2)
    }
}

/// The barrier `b(d2) = -(d2 - dhat2)^2 ln(d2 / dhat2)` (m^4, see the [module docs](self)).
///
/// `squared_distance` `d2` and `squared_activation` `dhat2` in m^2. Returns `+inf` for
/// `d2 <= 0` (and NaN `d2`), 0 for `d2 >= dhat2` (so 0 everywhere above 0 when `dhat2 <= 0`),
/// never NaN.
///
/// ```
/// use softfem::step::contact::barrier::barrier;
///
/// let dhat2 = 1e-6; // activation distance 1 mm
/// assert_eq!(barrier(2e-6, dhat2), 0.0);
/// assert!(barrier(0.5e-6, dhat2) > 0.0);
/// assert_eq!(barrier(0.0, dhat2), f32::INFINITY);
/// ```
#[must_use]
pub fn barrier(squared_distance: Real, squared_activation: Real) -> Real {
    let (d2, dhat2) = (squared_distance, squared_activation);
    // Written so that a NaN `d2` takes the first branch and a NaN `dhat2` the second.
    if d2 > 0.0 {
        if d2 < dhat2 {
            let gap = d2 - dhat2;
            -(gap * gap) * log_ratio(d2, dhat2)
        } else {
            0.0
        }
    } else {
        Real::INFINITY
    }
}

/// The barrier with its first and second derivatives in `d2` (see [`barrier`] for the
/// arguments and the values at the ends):
///
/// `db/dd2 = -(d2 - dhat2) (2 ln(d2 / dhat2) + (d2 - dhat2) / d2)`,
/// `d2b/dd2^2 = -2 ln(d2 / dhat2) - 4 (d2 - dhat2) / d2 + ((d2 - dhat2) / d2)^2`.
///
/// ```
/// use softfem::step::contact::barrier::barrier_derivatives;
///
/// let b = barrier_derivatives(0.25, 1.0);
/// // Pushing apart lowers the barrier; its curvature is positive.
/// assert!(b.first < 0.0 && b.second > 0.0);
/// // At the activation distance all three vanish (the barrier is C2 there).
/// let edge = barrier_derivatives(1.0, 1.0);
/// assert_eq!((edge.value, edge.first, edge.second), (0.0, 0.0, 0.0));
/// ```
#[must_use]
pub fn barrier_derivatives(squared_distance: Real, squared_activation: Real) -> BarrierDerivatives {
    let (d2, dhat2) = (squared_distance, squared_activation);
    if d2 > 0.0 {
        if d2 >= dhat2 || dhat2.is_nan() {
            return BarrierDerivatives {
                value: 0.0,
                first: 0.0,
                second: 0.0,
            };
        }
    } else {
        return BarrierDerivatives {
            value: Real::INFINITY,
            first: Real::NEG_INFINITY,
            second: Real::INFINITY,
        };
    }
    let gap = d2 - dhat2;
    let log = log_ratio(d2, dhat2);
    // `gap / d2` rather than `gap^2 / d2^2`, which overflows to inf / inf = NaN for large d2.
    let relative_gap = gap / d2;
    BarrierDerivatives {
        value: -(gap * gap) * log,
        first: -gap * (2.0 * log + relative_gap),
        second: -2.0 * log - 4.0 * relative_gap + relative_gap * relative_gap,
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::super::types::Real;
    use super::{barrier, barrier_derivatives};

    /// Whether this copy runs in f64.
    fn double() -> bool {
        Real::EPSILON < 1e-10
    }

    /// Zero from the activation distance on, with both derivatives; C2 there: value, slope and
    /// curvature approach 0 like `delta^3`, `delta^2`, `delta` (times `dhat2^2`, `dhat2`, 1),
    /// their leading terms `delta^3 dhat2^2`, `-3 delta^2 dhat2`... from the Taylor series
    /// `-ln(1 - delta) = delta + delta^2 / 2 + ...`.
    #[test]
    fn zero_beyond_the_activation_distance_and_c2_there() {
        for dhat2 in [1e-6, 1.0, 25.0] {
            for d2 in [dhat2, 1.5 * dhat2, 1e3 * dhat2] {
                assert_eq!(barrier(d2, dhat2), 0.0);
                let b = barrier_derivatives(d2, dhat2);
                assert_eq!((b.value, b.first, b.second), (0.0, 0.0, 0.0));
            }
            let delta: Real = 1e-3;
            let b = barrier_derivatives(dhat2 * (1.0 - delta), dhat2);
            // b = delta^2 dhat2^2 (-ln(1 - delta)) = dhat2^2 (delta^3 + delta^4 / 2 + ...);
            // b' = -(-delta dhat2)(2 ln(1 - delta) - delta / (1 - delta)) = -3 delta^2 dhat2 + ...;
            // b'' = -2 ln(1 - delta) + 4 delta / (1 - delta) + ... = 6 delta + ....
            let relative = if double() { 1e-2 } else { 2e-2 };
            assert!((b.value / (dhat2 * dhat2 * delta.powi(3)) - 1.0).abs() < relative, "{b:?}");
            assert!((b.first / (-3.0 * delta * delta * dhat2) - 1.0).abs() < relative, "{b:?}");
            assert!((b.second / (6.0 * delta) - 1.0).abs() < relative, "{b:?}");
        }
    }

    /// Inside, the derivatives match central differences: of the value for the slope, of the
    /// slope for the curvature, on a logarithmic sweep of `d2 / dhat2`. Tolerances: f64 central
    /// differences at `h = 1e-6 d2` err by `h^2 b''' / 6` (relative ~1e-11) plus rounding
    /// `eps b / h` (~1e-10 relative to b'); f32 at `h = 1e-2 d2` by ~1e-4 and ~1e-5: loose.
    #[test]
    fn derivatives_match_finite_differences() {
        let (relative_step, tolerance) = if double() { (1e-6, 1e-7) } else { (1e-2, 1e-2) };
        let dhat2 = 4.0;
        let mut ratio: Real = 1e-4;
        while ratio < 0.95 {
            let d2 = ratio * dhat2;
            let h = relative_step * d2;
            let b = barrier_derivatives(d2, dhat2);
            let fd_first = (barrier(d2 + h, dhat2) - barrier(d2 - h, dhat2)) / (2.0 * h);
            let fd_second = (barrier_derivatives(d2 + h, dhat2).first
                - barrier_derivatives(d2 - h, dhat2).first)
                / (2.0 * h);
            assert!((fd_first - b.first).abs() <= tolerance * b.first.abs(), "{d2}: {b:?}");
            assert!((fd_second - b.second).abs() <= tolerance * b.second.abs(), "{d2}: {b:?}");
            assert_eq!(b.value.to_bits(), barrier(d2, dhat2).to_bits());
            assert!(b.value > 0.0 && b.first < 0.0 && b.second > 0.0);
            ratio *= 1.7;
        }
        // A closed form: at d2 = dhat2 / 4, ln(1/4) = -2 ln 2:
        // b = (3/4 dhat2)^2 2 ln 2, b' = (3/4 dhat2)(-4 ln 2 - 3), b'' = 4 ln 2 + 12 + 9.
        let ln2 = core::f64::consts::LN_2 as Real;
        let b = barrier_derivatives(1.0, 4.0);
        assert!((b.value - 9.0 * 2.0 * ln2).abs() < 1e-5 * b.value);
        assert!((b.first - 3.0 * (-4.0 * ln2 - 3.0)).abs() < 1e-5 * b.first.abs());
        assert!((b.second - (4.0 * ln2 + 21.0)).abs() < 1e-5 * b.second);
    }

    /// `+inf` at and below 0, never NaN for any finite input (including negative distances,
    /// a non-positive activation distance, tiny and huge values).
    #[test]
    fn infinite_at_contact_and_never_nan() {
        for dhat2 in [1e-6, 1.0] {
            for d2 in [0.0, -0.0, -1e-30, -1.0, Real::MIN] {
                assert_eq!(barrier(d2, dhat2), Real::INFINITY);
                let b = barrier_derivatives(d2, dhat2);
                let expected = (Real::INFINITY, Real::NEG_INFINITY, Real::INFINITY);
                assert_eq!((b.value, b.first, b.second), expected);
            }
        }
        let values = [
            -Real::MAX, -1.0, -Real::MIN_POSITIVE, 0.0, Real::MIN_POSITIVE / 4.0,
            Real::MIN_POSITIVE, Real::EPSILON, 1e-3, 0.5, 1.0 - Real::EPSILON, 1.0, 2.0, 1e20,
            Real::MAX,
        ];
        for d2 in values {
            for dhat2 in values {
                let b = barrier_derivatives(d2, dhat2);
                let any_nan = b.value.is_nan() || b.first.is_nan() || b.second.is_nan();
                assert!(!any_nan, "{d2} {dhat2}: {b:?}");
                assert!(!barrier(d2, dhat2).is_nan());
                assert!(b.value >= 0.0 && b.first <= 0.0 && b.second >= 0.0, "{d2} {dhat2}: {b:?}");
            }
        }
    }
}

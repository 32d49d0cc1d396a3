//! The pieces of the Armijo backtracking line search that every descent solver here shares
//! (the relaxation, gradient descent, Newton's method): the sufficient-decrease test with its rounding-aware
//! fallback, the slope, and a panic-free copy.

use super::super::super::element::Vector;
use super::super::super::types::Real;

/// The relative size of `Phi`'s rounding error the line search tolerates: `sqrt(eps)`
/// (`2.4e-4` in f32, `1.5e-8` in f64).
pub(crate) const ROUNDING: Real = 1.0 / (1u64 << (Real::MANTISSA_DIGITS / 2)) as Real;

/// `g . d` over all vertices.
pub(crate) fn slope_along<V: Vector>(gradient: &[V], direction: &[V]) -> Real {
    gradient
        .iter()
        .zip(direction)
        .map(|(&g, &d)| g.dot(d))
        .sum()
}

/// Whether a slope `grad.d` is negative (false for NaN).
#[inline(always)]
pub(crate) fn downhill(slope: Real) -> bool {
    slope < 0.0
}

/// Whether the trial step `alpha` along a direction of slope `slope = grad.d < 0` decreases
/// `Phi` enough: from `phi` to `trial_phi` (`trial_elastic` the trial's elastic energy, part of
/// its `Phi`), with Armijo constant `armijo`. Armijo on `Phi`, or, where `Phi`'s change is below
/// its rounding (the energy of a nearly undeformed element is a difference of `O(mu V)` terms),
/// Hager and Zhang's approximate Armijo test (SIAM J. Optim. 2005): the trapezoidal estimate of
/// the decrease from the two slopes, which has no cancellation. `trial_slope` gives
/// `grad Phi(trial) . d`, evaluated only when needed.
#[inline(always)]
pub(crate) fn sufficient_decrease(
    (phi, trial_phi, trial_elastic): (Real, Real, Real),
    armijo: Real,
    alpha: Real,
    slope: Real,
    trial_slope: impl FnOnce() -> Real,
) -> bool {
    let noise = ROUNDING * (phi.abs() + trial_phi.abs() + trial_elastic.abs());
    trial_phi <= phi + armijo * alpha * slope
        || (trial_phi <= phi + noise && trial_slope() <= (2.0 * armijo - 1.0) * slope)
}

/// Copies `source` into `target`, as far as the shorter goes. Every buffer here has one entry
/// per vertex (checked on entry), but the optimiser loses track of the lengths of those that
/// trade places in the descent loop, and `copy_from_slice` would keep a panic path for unequal
/// ones (which the firmware check rejects).
pub(crate) fn copy<V: Copy>(target: &mut [V], source: &[V]) {
    for (t, &s) in target.iter_mut().zip(source) {
        *t = s;
    }
}

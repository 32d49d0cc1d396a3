//! The pieces of the Armijo backtracking line search that every descent solver here shares
//! (the relaxation, Newton's method): the sufficient-decrease test with its rounding-aware
//! fallback, the slope, and a panic-free copy.

use super::super::math;
use super::super::types::Real;
use super::Vector;

/// The relative size of `Phi`'s rounding error the line search tolerates: `sqrt(eps)`
/// (`2.4e-4` in f32, `1.5e-8` in f64).
pub(super) const ROUNDING: Real = 1.0 / (1u64 << (Real::MANTISSA_DIGITS / 2)) as Real;

/// `g . d` over all vertices.
pub(super) fn slope_along<V: Vector>(gradient: &[V], direction: &[V]) -> Real {
    gradient
        .iter()
        .zip(direction)
        .map(|(&g, &d)| g.dot(d))
        .sum()
}

/// Whether a slope `grad.d` is negative (false for NaN).
#[inline(always)]
pub(super) fn downhill(slope: Real) -> bool {
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
pub(super) fn sufficient_decrease(
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
pub(super) fn copy<V: Copy>(target: &mut [V], source: &[V]) {
    for (t, &s) in target.iter_mut().zip(source) {
        *t = s;
    }
}

/// The estimated rounding floor of a residual (N): every coordinate is known to half an ulp,
/// `eps reach / 2` with `reach` the largest coordinate magnitude (m), and through the stiffness
/// that uncertainty is a force of about `eps/2 reach |K|`, `|K|` estimated by
/// `sqrt(stiffness_squared)` (N/m; the Frobenius norms of the per-vertex diagonal blocks or
/// their bounds). Newton's method and the relaxation share it (see
/// [`newton_step`](super::newton_step)).
#[inline]
pub(super) fn rounding_floor(reach: Real, stiffness_squared: Real) -> Real {
    0.5 * Real::EPSILON * reach * math::sqrt(stiffness_squared)
}

/// Iterations without a 1 % fall of the best residual, with the residual within the floor
/// bound, after which [`Stagnation`] calls a solve stalled; ten times as many without any new
/// best residual stall it wherever it is.
pub(super) const STAGNATION_WINDOW: u32 = 100;

/// The relaxation's stagnation test over a window of iterations (the relaxation's residual is
/// not monotone under Chebyshev acceleration, so it watches the best residual): stalled when
/// the best residual has not fallen by 1 % for [`STAGNATION_WINDOW`] iterations while within
/// the rounding-floor bound (the rule Newton's method applies per step), or has not fallen at
/// all for ten windows.
pub(super) struct Stagnation {
    best: Real,
    reference: Real,
    since_progress: u32,
    since_best: u32,
}

impl Stagnation {
    /// A tracker starting at the initial residual.
    pub fn new(residual: Real) -> Self {
        Stagnation {
            best: residual,
            reference: residual,
            since_progress: 0,
            since_best: 0,
        }
    }

    /// Records the residual of the latest iterate; whether the solve has stalled, given
    /// `floor_bound` (N, a multiple of the rounding floor).
    pub fn stalled(&mut self, residual: Real, floor_bound: Real) -> bool {
        if residual < self.best {
            self.best = residual;
            self.since_best = 0;
        } else {
            self.since_best = self.since_best.saturating_add(1);
        }
        if self.best <= 0.99 * self.reference {
            self.reference = self.best;
            self.since_progress = 0;
        } else {
            self.since_progress = self.since_progress.saturating_add(1);
        }
        (self.since_progress >= STAGNATION_WINDOW && self.best <= floor_bound)
            || self.since_best >= 10 * STAGNATION_WINDOW
    }
}

//! The Chebyshev semi-iteration's spectral radius estimated by the solver itself, shared by the
//! relaxation ([`RelaxSettings::with_estimated_chebyshev`](super::RelaxSettings::with_estimated_chebyshev))
//! and Vertex Block Descent ([`VbdSettings::with_estimated_chebyshev`](super::VbdSettings::with_estimated_chebyshev)):
//! the largest residual ratio `r_k / r_(k-1)` of the plain iterations `2..=delay` of a solve,
//! capped. A plain iteration contracts the slow modes by about `rho` per iteration once the
//! fast ones are gone (power iteration on the iteration matrix), so the ratios rise towards
//! `rho` from below; the largest is the best of them.

use super::super::types::Real;

/// The largest residual ratio of a window of plain iterations.
#[derive(Clone, Copy, Default)]
pub(super) struct RhoEstimate {
    largest_ratio: Real,
}

impl RhoEstimate {
    /// Records the plain iteration that took the residual from `previous` to `next` (N).
    #[inline]
    pub fn observe(&mut self, previous: Real, next: Real) {
        self.largest_ratio = self.largest_ratio.max(next / previous);
    }

    /// The estimate, at most `cap`; 0 (no acceleration) if no ratio was positive (NaN
    /// included).
    #[inline]
    pub fn rho(&self, cap: Real) -> Real {
        if self.largest_ratio > 0.0 {
            self.largest_ratio.min(cap)
        } else {
            0.0
        }
    }
}

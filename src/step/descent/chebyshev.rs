//! The Chebyshev semi-iteration's spectral radius estimated by the solver itself, shared by the
//! relaxation
//! ([`RelaxSettings::with_estimated_chebyshev`](super::super::DescentSettings::<super::super::RelaxOptions>::with_estimated_chebyshev))
//! and Vertex Block Descent
//! ([`VbdSettings::with_estimated_chebyshev`](super::super::VbdSettings::with_estimated_chebyshev)):
//! the largest residual ratio `r_k / r_(k-1)` of the plain iterations `2..=delay` of a solve,
//! capped. A plain iteration contracts the slow modes by about `rho` per iteration once the fast
//! ones are gone (power iteration on the iteration matrix), so the ratios rise towards `rho` from
//! below; the largest is the best of them.
//!
//! Also the weights of the semi-iteration itself ([`Acceleration`]), which the descent loop
//! (`descent/mod.rs`) applies to any first-order direction.

use super::super::super::types::Real;

/// The largest residual ratio of a window of plain iterations.
#[derive(Clone, Copy, Default)]
pub(crate) struct RhoEstimate {
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

/// The acceleration settings of a first-order solve: Chebyshev's `rho` (0 for none), the delay
/// `S` and whether to estimate `rho` (then `rho` is 0 and the estimate is capped at `cap`).
#[derive(Clone, Copy)]
pub(crate) struct AccelerationSettings {
    pub rho: Real,
    pub delay: u32,
    pub estimate: bool,
    pub cap: Real,
}

impl AccelerationSettings {
    /// No acceleration.
    pub const NONE: Self = AccelerationSettings {
        rho: 0.0,
        delay: 0,
        estimate: false,
        cap: 0.0,
    };
}

/// The Chebyshev semi-iteration's weights over a solve (Wang and Yang 2016, eq. 9-10), with
/// the optional estimate of `rho` from the first plain iterations.
pub(crate) struct Acceleration {
    settings: AccelerationSettings,
    rho: Real,
    rho_squared: Real,
    estimate: RhoEstimate,
    previous_residual: Real,
    /// Iterations since the last (re)start of the acceleration.
    since_restart: u32,
    omega: Real,
}

impl Acceleration {
    /// The weights of a solve with `settings`.
    pub fn new(settings: AccelerationSettings) -> Self {
        Acceleration {
            settings,
            rho: settings.rho,
            rho_squared: settings.rho * settings.rho,
            estimate: RhoEstimate::default(),
            previous_residual: 0.0,
            since_restart: 0,
            omega: 1.0,
        }
    }

    /// The weight `omega` of the iteration `iterations` starting at `residual` (N): 1 (a plain
    /// step) for the first `S` iterations after a (re)start, then `2 / (2 - rho^2)`, then
    /// `4 / (4 - rho^2 omega)`; 1 throughout without acceleration.
    pub fn next_weight(&mut self, iterations: u32, residual: Real) -> Real {
        let settings = self.settings;
        if settings.estimate && self.rho == 0.0 {
            if iterations >= 2 {
                self.estimate.observe(self.previous_residual, residual);
            }
            if iterations >= settings.delay {
                self.rho = self.estimate.rho(settings.cap);
                self.rho_squared = self.rho * self.rho;
            }
        }
        self.previous_residual = residual;
        self.since_restart = self.since_restart.saturating_add(1);
        if self.rho > 0.0 {
            self.omega = match self.since_restart.checked_sub(settings.delay) {
                None | Some(0) => 1.0,
                Some(1) => 2.0 / (2.0 - self.rho_squared),
                Some(_) => 4.0 / (4.0 - self.rho_squared * self.omega),
            };
        }
        self.omega
    }

    /// After a rejected accelerated trial: the plain step that follows is the restart's
    /// iteration 0, so the next semi-iteration takes the recurrence's first weight.
    pub fn restart(&mut self) {
        self.since_restart = 0;
        self.omega = 1.0;
    }

    /// The `rho` in use: the setting, the estimate, or 0.
    pub fn rho(&self) -> Real {
        self.rho
    }
}

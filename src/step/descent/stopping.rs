//! The stopping test every descent solver here shares: the relative residual target, the
//! estimated rounding floor of the residual, and the two stagnation rules (a window over the
//! best residual for the first-order directions, whose residual is not monotone under
//! acceleration; "two steps in a row that do not halve it" for Newton's method).

use super::super::super::element::Vector;
use super::super::super::math;
use super::super::super::types::Real;
use super::super::state::length;

/// A Newton solve whose residual stagnated counts as converged when the residual is at most
/// this many times the estimated rounding floor
/// ([`DescentReport::rounding_floor`](super::super::DescentReport::rounding_floor)) and that
/// floor is below the initial residual ([`Stopping::converged`]).
pub(crate) const FLOOR_FACTOR: Real = 4.0;

/// Whether `residual` meets `target`. Never for an overflowed (infinite) or NaN residual or
/// target: a measure that overflowed says nothing about convergence.
#[inline(always)]
pub(crate) fn reached(residual: Real, target: Real) -> bool {
    residual <= target && residual.is_finite() && target.is_finite()
}

/// The estimated rounding floor of a residual (N): every coordinate is known to half an ulp,
/// `eps reach / 2` with `reach` the largest coordinate magnitude (m), and through the stiffness
/// that uncertainty is a force of about `eps/2 reach |K|`, `|K|` estimated by
/// `sqrt(stiffness_squared)` (N/m; the Frobenius norms of the per-vertex diagonal blocks or
/// their bounds). Every direction estimates it this way (see
/// [`newton_step`](super::super::newton_step)); the loop iterates in coordinates shifted next to
/// the body (`docs/math.md` section 7), so `reach` is the body's size, not its distance from
/// the origin.
#[inline]
pub(crate) fn rounding_floor(reach: Real, stiffness_squared: Real) -> Real {
    0.5 * Real::EPSILON * reach * math::sqrt(stiffness_squared)
}

/// `max_i |x_i|` (m, Euclidean), the reach of [`rounding_floor`] for the diagonal estimates (the
/// relaxation's and gradient descent's).
pub(crate) fn reach<V: Vector>(x: &[V]) -> Real {
    x.iter().fold(0.0, |a: Real, p| a.max(length(*p)))
}

/// Iterations without a 1 % fall of the best residual, with the residual within the floor
/// bound, after which [`Stagnation`] calls a solve stalled; ten times as many without any new
/// best residual stall it wherever it is.
pub(crate) const STAGNATION_WINDOW: u32 = 100;

/// The window stagnation test (the residual of an accelerated first-order method is not
/// monotone, so it watches the best residual): stalled when the best residual has not fallen by
/// 1 % for [`STAGNATION_WINDOW`] iterations while within the rounding-floor bound, or has not
/// fallen at all for ten windows.
pub(crate) struct Stagnation {
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

/// Which stagnation rule a direction's solve stops on.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum StallRule {
    /// First-order directions (the relaxation, gradient descent, VBD): the [`Stagnation`]
    /// window before every iteration. A stall is reported but is not convergence, and a failed
    /// line search just ends the solve.
    Window,
    /// Newton's method: two accepted steps in a row that do not halve the residual, with the
    /// residual within [`FLOOR_FACTOR`] times the floor. A stall within that bound counts as
    /// converged where the floor is below the initial residual ([`Stopping::converged`]), and
    /// a failed line search or a direction that is not downhill is a stall.
    Halving,
}

/// The stopping test of one solve.
pub(crate) struct Stopping {
    rule: StallRule,
    /// The residual the tolerance asks for (N).
    pub target: Real,
    window: Stagnation,
    /// The residual at the initial guess (N), which a floor stop's floor must be below.
    initial_residual: Real,
    /// Accepted steps in a row that did not halve the residual ([`StallRule::Halving`]).
    slow: u32,
    /// Whether the solve stopped on a stall.
    pub stagnated: bool,
}

impl Stopping {
    /// The test for a solve starting at `initial_residual` (N) with relative `tolerance`
    /// against `scale` (N): the larger of the load and a residual of the start (the initial
    /// residual, or for the relaxation after friction on the velocity the smaller of it and the
    /// rigid guess's; see `Start::try_rigid` in `mod.rs`), so that a step that starts at (or
    /// near) equilibrium, whose initial residual is mostly rounding, is not asked to reduce it
    /// further.
    pub fn new(rule: StallRule, tolerance: Real, initial_residual: Real, scale: Real) -> Self {
        Stopping {
            rule,
            target: tolerance * scale,
            window: Stagnation::new(initial_residual),
            initial_residual,
            slow: 0,
            stagnated: false,
        }
    }

    /// Whether `residual` still asks for another iteration (the target is not met).
    #[inline]
    pub fn unmet(&self, residual: Real) -> bool {
        match self.rule {
            StallRule::Window => !reached(residual, self.target),
            StallRule::Halving => residual > self.target,
        }
    }

    /// Before iteration `iterations` at `residual` with the estimated `floor` (N): whether the
    /// solve has stalled (then [`stagnated`](Self::stagnated) is set).
    #[inline]
    pub fn stalled_before(&mut self, iterations: u32, residual: Real, floor: Real) -> bool {
        let stalled = self.rule == StallRule::Window
            && iterations > 0
            && self.window.stalled(residual, FLOOR_FACTOR * floor);
        self.stagnated |= stalled;
        stalled
    }

    /// After an accepted line-searched step from `previous` to `residual` (N) with the
    /// estimated `floor`: whether the solve has stalled.
    #[inline]
    pub fn stalled_after(&mut self, previous: Real, residual: Real, floor: Real) -> bool {
        if self.rule != StallRule::Halving {
            return false;
        }
        // Newton's method at least halves the residual per step near the solution; a step that
        // does not, with the residual already within reach of its rounding floor, is moving
        // rounding around.
        self.slow = if residual > 0.5 * previous {
            self.slow + 1
        } else {
            0
        };
        let stalled = self.slow >= 2 && residual <= FLOOR_FACTOR * floor;
        self.stagnated |= stalled;
        stalled
    }

    /// A failed line search or a direction that is not downhill ended the solve.
    #[inline]
    pub fn failed(&mut self) {
        self.stagnated |= self.rule == StallRule::Halving;
    }

    /// Whether the solve ending at `residual` with the estimated `floor` converged: the
    /// residual and the target are finite and the residual meets the target, or (Newton's
    /// method) the solve stalled with the residual within [`FLOOR_FACTOR`] times a finite floor
    /// that is below the initial residual. A floor at or above the initial residual says the
    /// start was already within rounding of the solution as far as the residual can tell, so a
    /// stall there proves nothing: measured on the f32 cantilever of
    /// `tests/steppers/stagnation.rs` (8x2x2 cells, 3e-2 m/s^2), a floor of 0.036 N against an
    /// initial residual of 0.015 N stopped after two steps 5.9 % from the answer (issue #44).
    #[inline]
    pub fn converged(&self, residual: Real, floor: Real) -> bool {
        match self.rule {
            StallRule::Window => reached(residual, self.target),
            StallRule::Halving => {
                reached(residual, self.target)
                    || (self.stagnated
                        && reached(residual, FLOOR_FACTOR * floor)
                        && floor < self.initial_residual)
            }
        }
    }
}

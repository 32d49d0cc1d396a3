//! What every implicit solver is configured with and reports, in one shape: the stopping rule,
//! the budget and the line search ([`DescentSettings`], with a small per-solver part
//! `options`), and what the solve did ([`DescentReport`], with a small per-solver part
//! `details`). What a step acts on (the time step, gravity, contact, loads) is not here: that is
//! the [`Scene`](super::super::Scene).

use super::super::super::types::Real;
use super::newton::NewtonOptions;
use super::relax::RelaxOptions;
use super::stopping::FLOOR_FACTOR;
use super::vbd::VbdOptions;

/// The settings of an implicit solver: the relative tolerance, the iteration budget and the
/// backtracking line search that every solver here shares, and `options`, what only one
/// solver has ([`RelaxOptions`](super::relax::RelaxOptions),
/// [`NewtonOptions`](super::newton::NewtonOptions), [`VbdOptions`](super::vbd::VbdOptions)).
/// Each solver's defaults come from its `new`, which `Default` calls
/// ([`RelaxSettings::new`](super::super::RelaxSettings),
/// [`NewtonSettings::new`](super::super::NewtonSettings),
/// [`VbdSettings::new`](super::super::VbdSettings)), and are documented there. The settings
/// borrow nothing, so a body keeps them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DescentSettings<O> {
    /// Stop when `|grad Phi| <= tolerance * max(|grad Phi(x_0)|, |M g|)` (relative residual, in
    /// `[0, 1)`; 0 runs the whole budget), `|M g|` the norm of the gravity load on the free
    /// vertices (N): a step that starts near equilibrium is measured against the load, not
    /// against its own rounding-level initial residual. After a step whose Coulomb friction
    /// acted on the velocity (a zero sticking speed), `|grad Phi(x_0)|` is the smaller of the
    /// residuals at `x_0` and at the rigid guess `x_n + h v_mean` (`v_mean` the mass-weighted
    /// mean velocity; one more energy evaluation, only where `|grad Phi(x_0)| > |M g|`, the one
    /// case where it can change the target): the friction impulses slowed only the
    /// contact vertices, and the elastic force of the shear they put into `x_0` (240 N against
    /// 11 to 21 N on the sliding block of `docs/math.md` section 4.4) would otherwise loosen the
    /// target twentyfold. Newton's method also stops at its rounding floor (see
    /// [`newton_step`](super::super::newton_step)).
    pub tolerance: Real,
    /// The budget of iterations: descent iterations of the relaxation, Newton iterations,
    /// sweeps of Vertex Block Descent.
    pub max_iterations: u32,
    /// The Armijo constant `c` in `(0, 1)`: accept `alpha` when
    /// `Phi(x + alpha d) <= Phi(x) + c alpha grad.d` (for Vertex Block Descent, the same test on
    /// each vertex's local energy, or a change below its rounding).
    pub armijo: Real,
    /// The backtracking factor `beta` in `(0, 1)`: `alpha <- beta alpha` on rejection.
    pub backtrack: Real,
    /// Rejections allowed per line search before the solve stops, not converged (for Vertex
    /// Block Descent: per vertex update before the update is skipped; 0 turns its line search
    /// off, every Newton step taken whole as the paper does).
    pub max_backtracks: u32,
    /// What only this solver has.
    pub options: O,
}

/// `Default` for each solver's settings (`settings: options` pairs): its `new`, whose doc
/// states the values.
macro_rules! default_is_new {
    ($($settings:ident: $options:ident),+) => {$(
        impl Default for DescentSettings<$options> {
            #[doc = concat!("As [`", stringify!($settings), "::new`](DescentSettings::<",
                stringify!($options), ">::new).")]
            #[inline]
            fn default() -> Self {
                Self::new()
            }
        }
    )+};
}

default_is_new!(RelaxSettings: RelaxOptions, NewtonSettings: NewtonOptions, VbdSettings: VbdOptions);

impl<O> DescentSettings<O> {
    /// These settings with relative tolerance `tolerance` and budget `max_iterations`.
    #[inline]
    #[must_use]
    pub fn with_tolerance(self, tolerance: Real, max_iterations: u32) -> Self {
        DescentSettings {
            tolerance,
            max_iterations,
            ..self
        }
    }

    /// Whether the shared part is in range: `tolerance` in `[0, 1)`, `armijo` and `backtrack`
    /// in `(0, 1)`.
    #[inline]
    pub(crate) fn shared_part_valid(&self) -> bool {
        let in_open_unit = |x: Real| x > 0.0 && x < 1.0;
        (0.0..1.0).contains(&self.tolerance)
            && in_open_unit(self.armijo)
            && in_open_unit(self.backtrack)
    }
}

/// What an implicit solve did, with the same fields for every solver, and `details`, what only
/// one solver counts (`()` for the relaxation, [`NewtonDetails`](super::newton::NewtonDetails),
/// [`VbdDetails`](super::vbd::VbdDetails)). Not converging within the budget is not an error:
/// the best iterate is used and [`converged`](Self::converged) is false.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DescentReport<D> {
    /// Accepted iterations: descent iterations of the relaxation, Newton iterations, sweeps of
    /// Vertex Block Descent.
    pub iterations: u32,
    /// Evaluations of `Phi` and its gradient (fused energy-and-force passes): one per trial
    /// point, plus one to three for the initial guess (`y + h^2 g`; `y`, not where
    /// `y + h^2 g` wins by construction: a rigid translation of `y` touching nothing; `x_n` if
    /// neither is finite), plus one for the rigid guess of the stopping test's scale after
    /// friction on the velocity where the initial residual exceeds the load (see
    /// [`DescentSettings::tolerance`]).
    pub energy_evaluations: u32,
    /// Line-search trials rejected by the Armijo test (each shrinking the step by `beta`).
    pub backtracks: u32,
    /// Accelerated trials rejected because `Phi` increased, each followed by a restart of the
    /// acceleration with a plain step.
    pub restarts: u32,
    /// `|grad Phi|` (N) at the initial guess, projected on the contacts.
    pub initial_residual: Real,
    /// `|grad Phi|` (N) at the result, projected on the contacts.
    pub residual: Real,
    /// The residual the tolerance asked for (N).
    pub target: Real,
    /// The estimated rounding floor of the residual (N): `eps/2 max_i |x_i| (3 sum_i P_i^2)^(1/2)`
    /// over the free vertices, `P_i` a bound on the diagonal block of the Hessian (the
    /// relaxation's preconditioner, Newton's block diagonal, VBD's vertex blocks).
    pub rounding_floor: Real,
    /// `Phi` (J) at the result, with the gravity potential measured from the start positions.
    pub phi: Real,
    /// Whether the solve converged. True only when [`residual`](Self::residual) and
    /// [`target`](Self::target) are finite and either
    /// * the residual is at most the target (every solver), or
    /// * (Newton's method only) the solve [`stagnated`](Self::stagnated) with the residual
    ///   within [`FLOOR_FACTOR`](Self::FLOOR_FACTOR) times a finite
    ///   [`rounding_floor`](Self::rounding_floor) that is below
    ///   [`initial_residual`](Self::initial_residual): the residual fell from above the floor
    ///   to its rounding level, and the answer is as close as the residual can resolve (on
    ///   the f32 cantilevers of `tests/steppers/stagnation.rs`, within 0.3 % of the f64
    ///   answer; the test asserts 1 %), though not always as close as the precision allows.
    ///
    /// False for a non-finite residual or target (an overflowed load or state: the measure
    /// says nothing), for a budget spent, and for a stop at a floor at or above the initial
    /// residual, where the residual cannot tell the start from the answer (measured 0.03 % to
    /// 11 % from the answer on those cantilevers, and the whole answer where the load is below
    /// the rounding of the rest shape; `stagnated` then says the solve stopped there, issue
    /// #44).
    pub converged: bool,
    /// Whether the solve stopped because the residual stopped falling, before the target.
    /// The relaxation, gradient descent and Vertex Block Descent: the best residual fell by
    /// less than 1 % over the last 100 iterations while within
    /// [`FLOOR_FACTOR`](Self::FLOOR_FACTOR) times the rounding floor (the residual is at its
    /// rounding level), or did not fall at all over 1000 iterations (a plateau above the
    /// estimated floor); never converged. Newton's method: two accepted steps in a row that did
    /// not halve the residual while within `FLOOR_FACTOR` times the floor, a failed line
    /// search, or a direction that is not downhill; converged only as
    /// [`converged`](Self::converged) says. Either way the budget is not burnt.
    pub stagnated: bool,
    /// The Chebyshev `rho` used: the setting, the estimate, or 0 (none, Newton's method, or not
    /// yet estimated when the solve stopped).
    pub rho: Real,
    /// What only this solver counts.
    pub details: D,
}

impl<D> DescentReport<D> {
    /// How close to the estimated rounding floor a stalled solve must be to count as converged:
    /// a residual of at most `FLOOR_FACTOR` times [`rounding_floor`](Self::rounding_floor)
    /// (4), for Newton's method with the floor below the initial residual (see
    /// [`converged`](Self::converged)). Name it through a solver's report, e.g.
    /// `NewtonReport::FLOOR_FACTOR`.
    pub const FLOOR_FACTOR: Real = FLOOR_FACTOR;

    /// This report with `details` in place of its own (the descent loop's report, whose details
    /// are `()`, with a solver's).
    #[inline]
    pub(crate) fn with_details<E>(self, details: E) -> DescentReport<E> {
        DescentReport {
            iterations: self.iterations,
            energy_evaluations: self.energy_evaluations,
            backtracks: self.backtracks,
            restarts: self.restarts,
            initial_residual: self.initial_residual,
            residual: self.residual,
            target: self.target,
            rounding_floor: self.rounding_floor,
            phi: self.phi,
            converged: self.converged,
            stagnated: self.stagnated,
            rho: self.rho,
            details,
        }
    }
}

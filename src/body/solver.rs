//! Which stepper a [`Body`](super::Body) runs, with its settings, and what a step reports.

#[allow(unused_imports)] // `Scene` is named by the documentation only.
use super::super::step::{
    CouplingReport, ExplicitReport, ExplicitSettings, NewtonReport, NewtonSettings, RelaxReport, RelaxSettings,
    Scene, VbdReport, VbdSettings,
};
use super::super::types::Real;
use super::auto::{AutoReport, AutoRun, AutoSettings};
use crate::error::BodyError;

/// The stepper of a [`Body`](super::Body) and its settings.
///
/// The settings say how a step is solved (damping, substeps, tolerances, budgets,
/// accelerations) and borrow nothing; what a step acts on is the [`Scene`] of each step: the
/// `dt` given to [`Body::step`](super::Body::step) with the body's
/// [`gravity`](super::Body::set_gravity) and [`ground`](super::Body::set_ground), or any scene
/// given to [`Body::step_with`](super::Body::step_with) (colliders, external forces, fixed
/// axes, borrowed for that step only).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum Solver {
    /// Explicit symplectic Euler ([`explicit_step`](super::super::step::explicit_step)).
    Explicit {
        /// Damping, growth limit and the substeps when `stable_fraction` is `None`.
        settings: ExplicitSettings,
        /// `Some(f)`: each step of `dt` takes the fewest substeps (at least
        /// `settings.substeps`) of at most `f` times the body's
        /// [`stable_time_step`](super::Body::stable_time_step), computed once and cached until
        /// the pins or the material change. `f` in `(0, 1)` leaves the margin the bound's
        /// documentation asks for; 0.5 is the default; `f` must be finite and in `(0, 1]`
        /// ([`Body::set_solver`](super::Body::set_solver) refuses anything else with
        /// [`BodyError::StableFraction`]). `None`: exactly `settings.substeps`.
        stable_fraction: Option<Real>,
    },
    /// Implicit Euler by preconditioned descent ([`relax_step`](super::super::step::relax_step));
    /// the preconditioner is kept across steps.
    Relax(RelaxSettings),
    /// Implicit Euler by Newton's method ([`newton_step`](super::super::step::newton_step)).
    Newton(NewtonSettings),
    /// Implicit Euler by Vertex Block Descent ([`vbd_step`](super::super::step::vbd_step)); the
    /// adjacency and colouring are kept across steps.
    Vbd(VbdSettings),
    /// The solver that chooses itself, a body's default: each frame, the explicit stepper
    /// where it needs few substeps of the stable step, Newton's method where it needs many,
    /// and on failure the next safer choice (explicit that blows up: Newton's method from the
    /// restored state; Newton's method that neither converges nor stops at its rounding floor:
    /// two half steps), every fallback in the frame's [`AutoReport`]. See [`AutoSettings`]
    /// for the rule and where its crossover was measured.
    Auto(AutoSettings),
}

impl Solver {
    /// The solver that chooses itself, with the defaults of [`AutoSettings::new`]: what a
    /// body starts with.
    #[inline]
    #[must_use]
    pub const fn auto() -> Solver {
        Solver::Auto(AutoSettings::new())
    }

    /// Explicit, undamped, one substep per half the stable time step.
    #[inline]
    #[must_use]
    pub const fn explicit() -> Solver {
        Solver::Explicit {
            settings: ExplicitSettings::new(),
            stable_fraction: Some(0.5),
        }
    }

    /// The relaxation with the defaults of [`RelaxSettings::new`].
    #[inline]
    #[must_use]
    pub fn relax() -> Solver {
        Solver::Relax(RelaxSettings::new())
    }

    /// Newton's method with the defaults of [`NewtonSettings::new`].
    #[inline]
    #[must_use]
    pub fn newton() -> Solver {
        Solver::Newton(NewtonSettings::new())
    }

    /// Vertex Block Descent with the defaults of [`VbdSettings::new`] but the setting the
    /// examples and charts use: Chebyshev acceleration at `rho` = 0.95 after two plain sweeps,
    /// and the per-vertex line search only in a sweep that raised the energy (which also
    /// restarts the acceleration), instead of in every sweep
    /// ([`VbdSettings::with_line_search_on_increase`]). Measured on a 10 000-tet soft box
    /// landing on the ground (60 steps of 1/60 s, one thread): 60 of 60 steps converged in
    /// 0.67 s (1346 sweeps, 0.50 ms a sweep with the evaluations between sweeps), where
    /// [`VbdSettings::new`]'s own defaults converged 37 in 15.5 s (4841 sweeps, 3.2 ms a sweep
    /// with the line search in every one). `Solver::Vbd(VbdSettings::new())` gives those
    /// defaults.
    #[inline]
    #[must_use]
    pub fn vbd() -> Solver {
        Solver::Vbd(
            VbdSettings::new()
                .with_chebyshev(0.95, 2)
                .with_line_search_on_increase(),
        )
    }

    /// Checks what the body checks when given this solver: an explicit or automatic
    /// `stable_fraction` must be finite and in `(0, 1]`.
    pub(crate) fn check(&self) -> Result<(), BodyError> {
        match *self {
            Solver::Explicit {
                stable_fraction: Some(fraction),
                ..
            } if !(fraction > 0.0 && fraction <= 1.0) => Err(BodyError::StableFraction),
            Solver::Auto(settings) => settings.check(),
            _ => Ok(()),
        }
    }

    /// Whether `self` and `other` run the same stepper (whatever their settings).
    #[inline]
    pub(crate) fn same_kind(&self, other: &Solver) -> bool {
        core::mem::discriminant(self) == core::mem::discriminant(other)
    }
}

/// What one [`Body::step`](super::Body::step) did: the report of the stepper that ran.
// The automatic solver's variant carries the reports of every solve of its frame (up to three
// Newton solves: 296 B in f64, 4x the next largest): returned once per step, a copy that costs
// nothing next to the step, and no heap to box it in.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StepReport {
    /// From [`Solver::Explicit`].
    Explicit(ExplicitReport),
    /// From [`Solver::Relax`].
    Relax(RelaxReport),
    /// From [`Solver::Newton`].
    Newton(NewtonReport),
    /// From [`Solver::Vbd`].
    Vbd(VbdReport),
    /// From [`Solver::Auto`]: what ran, and every fallback.
    Auto(AutoReport),
}

/// What a coupled step ([`Body::step_with_rigid_bodies`](super::Body::step_with_rigid_bodies))
/// did: the last soft step's report and the coupling iteration's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoupledReport {
    /// The report of the last soft step, the one whose state the body kept.
    pub step: StepReport,
    /// How the iteration between the body and its dynamic colliders ended.
    pub coupling: CouplingReport,
}

impl CoupledReport {
    /// Whether both the last soft step ([`StepReport::converged`]) and the coupling iteration
    /// ([`CouplingReport::converged`]) met their tolerances.
    #[inline]
    #[must_use]
    pub fn converged(&self) -> bool {
        self.step.converged() && self.coupling.converged
    }
}

impl StepReport {
    /// What a coupled step's iteration is told of this soft step (`step/contact/rigid.rs`,
    /// `couple`): its [`residual`](Self::residual) where it converged, else infinity (no
    /// floor granted).
    #[inline]
    pub(crate) fn coupling_residual(&self) -> Real {
        match self.converged() {
            true => self.residual(),
            false => Real::INFINITY,
        }
    }

    /// The force (N) the step's solve left unbalanced: its report's `residual` (the larger of
    /// two half steps'); zero for an explicit step, which solves no equation.
    #[inline]
    #[must_use]
    pub fn residual(&self) -> Real {
        match self {
            StepReport::Explicit(_) => 0.0,
            StepReport::Relax(report) => report.residual,
            StepReport::Newton(report) => report.residual,
            StepReport::Vbd(report) => report.residual,
            StepReport::Auto(report) => match &report.run {
                AutoRun::Explicit(_) => 0.0,
                AutoRun::Newton(newton) => newton.residual,
                AutoRun::NewtonHalves([first, second]) => first.residual.max(second.residual),
            },
        }
    }

    /// Whether the step reached its solver's tolerance (always `true` for an explicit step,
    /// which has none; for [`Solver::Auto`], [`AutoReport::converged`]: a stop at the
    /// rounding floor is not convergence). A step that did not still advanced the state:
    /// implicit Euler with the iterate the budget ended at.
    #[inline]
    #[must_use]
    pub fn converged(&self) -> bool {
        match self {
            StepReport::Explicit(_) => true,
            StepReport::Relax(report) => report.converged,
            StepReport::Newton(report) => report.converged,
            StepReport::Vbd(report) => report.converged,
            StepReport::Auto(report) => report.converged(),
        }
    }
}

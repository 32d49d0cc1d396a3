//! Plain gradient descent, `P = c I`: the direction `d = -grad Phi / c` with `c` the largest
//! entry `max_i (m_i / h^2 + k_i)` of the relaxation's diagonal bound over the free vertices, so
//! that `P` majorises the Hessian near rest as the relaxation's `P` does (`lambda_max(A) <=
//! max_i P_i`) and the step `alpha = 1` is the same safe majorisation step. It is the baseline
//! of the family: the relaxation differs only in scaling every vertex by its own bound, which on
//! a graded mesh or with very different masses is worth a factor of the spread of the bounds in
//! the condition number. One pass per vertex, one vertex at a time.

use super::super::super::super::types::Real;
use super::super::super::contact::floor::Floor;
use super::super::super::model::ElasticEnergy;
use super::super::super::scene::Scene;
use super::super::super::state::pinned_flags;
use super::super::super::vertex_pass::point::{Grouped, Point};
use super::super::objective::Objective;
use super::super::stopping::{reach, rounding_floor};
use super::super::{Direction, Extrapolation, Search};
use super::{RelaxReport, RelaxScratch, RelaxSettings, minimise};
use crate::error::StepError;

/// The direction `-grad Phi / c`, with `c` and the rounding floor set at the initial guess.
#[derive(Default)]
pub(crate) struct Gradient {
    /// `1 / c` (m/N), 0 if no free vertex has stiffness or inertia.
    inverse_scale: Real,
    floor: Real,
}

impl<F: ElasticEnergy> Direction<F> for Gradient {
    fn begin(&mut self, objective: &Objective<'_, F>, x: &[F::Vector]) {
        let scale = objective
            .free_diagonals()
            .fold(0.0, |c: Real, diagonal| c.max(diagonal));
        self.inverse_scale = if scale > 0.0 && scale.is_finite() {
            1.0 / scale
        } else {
            0.0
        };
        // The same estimate as the relaxation's with `P = c I`: `eps/2 max|x| (3 n c^2)^(1/2)`.
        let free = pinned_flags(objective.vertices.pinned)
            .take(x.len())
            .filter(|pinned| !pinned)
            .count() as Real;
        self.floor = rounding_floor(reach(x), 3.0 * free * scale * scale);
    }

    fn search(&mut self, search: Search<'_, F>) -> Result<Real, StepError> {
        let (objective, at, trial) = (search.objective, search.at, search.trial);
        let (momentum, step) = (search.momentum, search.step);
        let floor = objective.frames.floor();
        let pinned = objective.vertices.pinned;
        let mut slope = 0.0;
        let rows = search
            .direction
            .iter_mut()
            .zip(trial.positions.iter_mut().zip(trial.gradient.iter_mut()))
            .zip(at.x.iter().zip(at.gradient))
            .zip(pinned_flags(pinned));
        for (((d_slot, (t_slot, g_slot)), (&x, &g)), pinned) in rows {
            let (d, slope_term) = self.descent(floor, x, g, momentum.map(|m| (*t_slot, m)));
            *d_slot = d;
            *t_slot = moved(floor, pinned, x, x + d * step);
            *g_slot = <F::Vector as Point>::zero();
            slope += slope_term;
        }
        Ok(slope)
    }

    fn extrapolate(&mut self, extrapolation: Extrapolation<'_, F>) -> Result<(), StepError> {
        let (objective, at, trial) = (
            extrapolation.objective,
            extrapolation.at,
            extrapolation.trial,
        );
        let (stepped, step, omega) = (
            extrapolation.stepped,
            extrapolation.step,
            extrapolation.omega,
        );
        let floor = objective.frames.floor();
        let rows = trial
            .positions
            .iter_mut()
            .zip(trial.gradient.iter_mut())
            .zip(at.x.iter().zip(at.gradient))
            .zip(pinned_flags(objective.vertices.pinned));
        for (((t_slot, g_slot), (&x, &g)), pinned) in rows {
            let zero = <F::Vector as Point>::zero();
            let last_step = if stepped { x - *t_slot } else { zero };
            let (d, _) = self.descent(floor, x, g, None);
            let target = x + d * step + last_step * (omega - 1.0);
            *t_slot = moved(floor, pinned, x, target);
            *g_slot = zero;
        }
        Ok(())
    }

    fn rounding_floor(&self) -> Real {
        self.floor
    }
}

impl Gradient {
    /// The projected direction `-g / c` at a vertex at `x` (plus `momentum` times the last
    /// step `x - previous` when given) and its term of the slope, as the relaxation's pass
    /// projects: the gradient's component into the ground removed where in contact, then the
    /// direction's.
    #[inline]
    fn descent<V: Grouped>(
        &self,
        floor: &Floor<V>,
        x: V,
        g: V,
        heavy_ball: Option<(V, Real)>,
    ) -> (V, Real) {
        floor.descent(x, g, (-self.inverse_scale, None), heavy_ball)
    }
}

/// The trial point `target` projected on the ground, or `x` at a pinned vertex (the descent
/// loop restores the fixed coordinates after this pass, as after every direction's).
#[inline]
fn moved<V: Grouped>(floor: &Floor<V>, pinned: bool, x: V, target: V) -> V {
    if pinned { x } else { floor.project(target) }
}

/// One implicit Euler step by plain gradient descent: the loop of
/// [`relax_step`](super::super::super::relax_step) (same objective, initial guess, line search,
/// stopping test, momentum and Chebyshev options, friction) with `P = c I` instead of the
/// per-vertex bound (see this file): `settings` and `scratch` are the relaxation's, and so is the
/// report. `step_length` is in units of `1 / c` (`1` the majorisation step, `< 2` converges on the
/// linearised problem).
///
/// Pick it only to compare: it is never faster than the relaxation, which costs the same per
/// iteration and conditions the problem better wherever masses or element sizes vary.
///
/// # Errors
/// As [`relax_step`](super::super::super::relax_step).
#[allow(clippy::too_many_arguments)]
pub fn gradient_descent_step<F: ElasticEnergy>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, F::Vector>,
    settings: &RelaxSettings,
    positions: &mut [F::Vector],
    velocities: &mut [F::Vector],
    scratch: &mut RelaxScratch<'_, F::Vector>,
) -> Result<RelaxReport, StepError> {
    minimise(
        (model, masses, pinned),
        scene,
        settings,
        (positions, Some(velocities)),
        scratch,
        Gradient::default(),
    )
}

/// Quasi-static equilibrium by plain gradient descent: [`gradient_descent_step`] without
/// inertia, as [`relax_quasi_static`](super::super::super::relax_quasi_static) is to the
/// relaxation.
///
/// # Errors
/// As [`relax_quasi_static`](super::super::super::relax_quasi_static).
pub fn gradient_descent_quasi_static<F: ElasticEnergy>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, F::Vector>,
    settings: &RelaxSettings,
    positions: &mut [F::Vector],
    scratch: &mut RelaxScratch<'_, F::Vector>,
) -> Result<RelaxReport, StepError> {
    minimise(
        (model, masses, pinned),
        scene,
        settings,
        (positions, None),
        scratch,
        Gradient::default(),
    )
}

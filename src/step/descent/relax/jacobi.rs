//! The relaxation's direction: `d = -P^-1 grad Phi` with `P` the diagonal bound
//! `P_i = m_i / h^2 + k_i` (see the `step` module documentation), in the vertex passes of
//! `step/vertex_pass/passes.rs` (four vertices at a time on x86_64), and its Chebyshev trial in one
//! pass.

use super::super::super::super::types::Real;
use super::super::super::model::ElasticEnergy;
use super::super::super::vertex_pass::passes::{chebyshev_pass, direction_pass};
use super::super::objective::Objective;
use super::super::stopping::{reach, rounding_floor};
use super::super::{Direction, Extrapolation, Search};
use crate::error::StepError;

/// The Jacobi direction, with its rounding floor estimated once at the initial guess.
#[derive(Default)]
pub(crate) struct Jacobi {
    floor: Real,
}

impl<F: ElasticEnergy> Direction<F> for Jacobi {
    fn begin(&mut self, objective: &Objective<'_, F>, x: &[F::Vector]) {
        self.floor = diagonal_rounding_floor(objective, x);
    }

    fn search(&mut self, search: Search<'_, F>) -> Result<Real, StepError> {
        let (objective, at) = (search.objective, search.at);
        Ok(direction_pass(
            objective.model,
            &objective.frames,
            &objective.vertices,
            (at.x, at.gradient),
            search.direction,
            search.momentum,
            search.trial,
            search.step,
        ))
    }

    fn extrapolate(&mut self, extrapolation: Extrapolation<'_, F>) -> Result<(), StepError> {
        let (objective, at) = (extrapolation.objective, extrapolation.at);
        chebyshev_pass(
            objective.model,
            &objective.frames,
            &objective.vertices,
            (at.x, at.gradient),
            extrapolation.stepped,
            extrapolation.trial,
            extrapolation.step,
            extrapolation.omega,
        );
        Ok(())
    }

    fn rounding_floor(&self) -> Real {
        self.floor
    }

    fn rigid_scale(&self) -> bool {
        true
    }
}

/// The rounding floor of the residual at `x` estimated from the diagonal bound (see
/// [`DescentReport::rounding_floor`](super::super::super::DescentReport::rounding_floor)):
/// `eps/2 max_i |x_i| (3 sum_i P_i^2)^(1/2)` over the free vertices.
pub(crate) fn diagonal_rounding_floor<F: ElasticEnergy>(
    objective: &Objective<'_, F>,
    x: &[F::Vector],
) -> Real {
    let stiffness_squared: Real = objective
        .free_diagonals()
        .map(|diagonal| 3.0 * diagonal * diagonal)
        .sum();
    rounding_floor(reach(x), stiffness_squared)
}

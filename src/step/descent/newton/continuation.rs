//! Load steps (continuation) for a quasi-static Newton solve whose full-load solve failed
//! (`docs/math.md` section 7.1.4): gravity and the external forces applied in increments, each
//! solved from the previous increment's equilibrium, the increment halved on failure and doubled
//! on success, within [`NewtonOptions::max_load_steps`](super::NewtonOptions::max_load_steps)
//! tries and down to `1 / LOAD_UNITS` of the load.

use super::super::super::super::types::{Real, Vec3};
use super::super::Problem;
use super::super::Summary;
use super::{Attempt, LOAD_UNITS, NewtonReport};
use crate::error::StepError;
use super::super::super::model::ElasticHessian;

/// The Newton budget of a load step in units of the settings' budget: near a bifurcation a
/// step converges slowly until it has passed it (measured on the free-z Cook membrane at n =
/// 16 with 16 equal steps: 102 Newton iterations from 1/8 to 3/16 of the load, 54 and 33 for
/// the next two, 11 to 14 for the rest).
const STEP_BUDGET: u32 = 4;

/// The first increment after a failed full-load solve: half the load.
const FIRST_STEP: Real = 0.5;

/// Runs the load steps from `positions` (the caller's state: the failed full-load solve
/// restored it) after the `failed` full-load solve; `problem`'s gravity and force scale are set
/// per step from the scene's `gravity`. Returns the last step's report with the counts of every
/// solve: converged only where the full load converged; otherwise `positions` hold the
/// equilibrium of the last converged step ([`NewtonDetails::load_reached`](super::NewtonDetails::load_reached)).
///
/// # Errors
/// The model's errors and the loop's other than [`StepError::NonFiniteState`], which rejects
/// the step like a solve that does not converge (the loop restored its start).
pub(super) fn load_steps<F: ElasticHessian>(
    (problem, gravity): (&mut Problem<'_, F>, Vec3),
    max_steps: u32,
    failed: Summary,
    positions: &mut [Vec3],
    attempt: &mut Attempt<'_, '_>,
) -> Result<NewtonReport, StepError> {
    // Every load reached is a sum of increments `2^-k >= 1 / LOAD_UNITS`: exact in binary.
    let smallest = 1.0 / LOAD_UNITS as Real;
    let mut totals = failed;
    let mut last = failed;
    let (mut reached, mut step): (Real, Real) = (0.0, FIRST_STEP);
    attempt.totals.load_reached = 0;
    attempt.max_iterations = attempt.max_iterations.saturating_mul(STEP_BUDGET);
    for _ in 0..max_steps {
        let load = if reached + step >= 1.0 {
            1.0
        } else {
            reached + step
        };
        problem.gravity = gravity * load;
        problem.loads.scale = load;
        let converged = match attempt.run(problem, positions, None) {
            Ok(summary) => {
                add_counts(&mut totals, &summary);
                last = summary;
                summary.converged
            }
            Err(StepError::NonFiniteState { .. }) => false,
            Err(error) => return Err(error),
        };
        if converged {
            attempt.totals.load_steps += 1;
            reached = load;
            // `reached` is a multiple of `1 / LOAD_UNITS` at most 1: the product is exact.
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let units = (reached * LOAD_UNITS as Real) as u32;
            attempt.totals.load_reached = units;
            if load >= 1.0 {
                break;
            }
            step = (step * 2.0).min(1.0);
        } else {
            attempt.totals.rejected_load_steps += 1;
            step *= 0.5;
            if step < smallest {
                break;
            }
        }
    }
    let converged = reached >= 1.0 && last.converged;
    Ok(Summary {
        iterations: totals.iterations,
        energy_evaluations: totals.energy_evaluations,
        backtracks: totals.backtracks,
        restarts: totals.restarts,
        initial_residual: failed.initial_residual,
        converged,
        ..last
    }
    .with_details(attempt.totals))
}

/// Adds the counts of `summary` to `totals`.
fn add_counts(totals: &mut Summary, summary: &Summary) {
    totals.iterations = totals.iterations.saturating_add(summary.iterations);
    totals.energy_evaluations = totals
        .energy_evaluations
        .saturating_add(summary.energy_evaluations);
    totals.backtracks = totals.backtracks.saturating_add(summary.backtracks);
    totals.restarts = totals.restarts.saturating_add(summary.restarts);
}

//! Timing and progress output shared by the charts.
//!
//! Times are wall-clock (`std::time::Instant`). A measurement repeats the work and keeps the
//! minimum: the estimate least disturbed by other processes on a shared machine. The charts use
//! them for shape and ratios; absolute figures are for this machine only.

use std::hint::black_box;
use std::time::{Duration, Instant};

use softfem::StepError;

/// The smallest wall time of `repeats` runs of `work` (at least one run).
pub fn min_time<T>(repeats: u32, mut work: impl FnMut() -> T) -> Duration {
    (0..repeats.max(1))
        .map(|_| {
            let started = Instant::now();
            black_box(work());
            started.elapsed()
        })
        .min()
        .unwrap_or_default()
}

/// Nanoseconds per item of the fastest of `repeats` runs of `work`, which processes `items`
/// items per run, after one untimed warm-up run.
pub fn ns_per_item<T>(repeats: u32, items: usize, mut work: impl FnMut() -> T) -> f64 {
    black_box(work());
    min_time(repeats, work).as_secs_f64() * 1e9 / items.max(1) as f64
}

/// Prints one line of progress for the chart being measured, flushed at once.
pub fn progress(chart: &str, message: &str) {
    use std::io::Write;
    println!("  [{chart}] {message}");
    let _ = std::io::stdout().flush();
}

/// What one step of a stepper reports to `body::run`.
#[derive(Clone, Copy, Debug, Default)]
pub struct StepOutcome {
    /// Solver iterations (0 for explicit steps).
    pub iterations: u32,
    /// Whether the solve converged (always for explicit steps).
    pub converged: bool,
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct Run {
    /// Positions (m) at each requested sample time, linearly interpolated between steps; fewer
    /// than requested if the run failed.
    pub samples: Vec<Vec<[f64; 3]>>,
    /// Steps taken.
    pub steps: u64,
    /// Solver iterations over all steps.
    pub iterations: u64,
    /// Solves that did not converge.
    pub unconverged: u64,
    /// Wall time of the stepping (sampling included, negligible).
    pub wall: Duration,
    /// The stepper's error that stopped the run, with the simulated time (s) it was refused at.
    pub failure: Option<(f64, StepError)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timing_is_positive_and_per_item() {
        let ns = ns_per_item(3, 1000, || (0..1000u64).map(black_box).sum::<u64>());
        assert!(ns > 0.0 && ns < 1e6, "{ns}");
        assert!(min_time(0, || 1) >= Duration::ZERO);
    }
}

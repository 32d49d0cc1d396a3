//! Terminal output: a progress line for long runs and the end-of-run summary.

use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

use crate::scene::{Energies, SolveTotals};

/// A one-line progress bar on standard error, redrawn in place with `\r`.
///
/// It appears only on a terminal and only when the run is expected to take more than a second:
/// after [`Progress::GRACE`] of wall time it extrapolates the rate so far, and stays silent if
/// the whole run would be shorter than [`Progress::SHOW_ABOVE`].
#[derive(Debug)]
pub struct Progress {
    enabled: bool,
    started: Instant,
    last_draw: Option<Instant>,
    drawn: bool,
}

impl Progress {
    /// Wall time before the first estimate of the run's length.
    pub const GRACE: Duration = Duration::from_millis(250);
    /// Runs expected to be shorter than this get no bar.
    pub const SHOW_ABOVE: Duration = Duration::from_secs(1);
    /// The bar is redrawn at most this often.
    const REDRAW: Duration = Duration::from_millis(100);
    const WIDTH: usize = 30;

    /// A bar on standard error if it is a terminal and `quiet` is false.
    pub fn new(quiet: bool) -> Progress {
        Progress {
            enabled: !quiet && std::io::stderr().is_terminal(),
            ..Progress::hidden()
        }
    }

    /// A bar that never draws (tests, `--quiet`, output not a terminal).
    pub fn hidden() -> Progress {
        Progress {
            enabled: false,
            started: Instant::now(),
            last_draw: None,
            drawn: false,
        }
    }

    /// Reports that `done` of `total` steps are complete.
    pub fn update(&mut self, done: u64, total: u64) {
        if !self.enabled || total == 0 {
            return;
        }
        let now = Instant::now();
        let elapsed = now - self.started;
        if self.last_draw.is_some_and(|last| now - last < Self::REDRAW) || elapsed < Self::GRACE {
            return;
        }
        let fraction = done as f64 / total as f64;
        let expected = elapsed.as_secs_f64() / fraction.max(1e-9);
        if !self.drawn && expected < Self::SHOW_ABOVE.as_secs_f64() {
            return;
        }
        self.last_draw = Some(now);
        self.drawn = true;
        let line = bar_line(done, total, elapsed, Duration::from_secs_f64(expected));
        let mut err = std::io::stderr().lock();
        let _ = write!(err, "\r{line}");
        let _ = err.flush();
    }

    /// Clears the bar, if one was drawn.
    pub fn finish(&mut self) {
        if self.drawn {
            let mut err = std::io::stderr().lock();
            let _ = write!(err, "\r{:width$}\r", "", width = 80);
            let _ = err.flush();
            self.drawn = false;
        }
    }
}

/// `[#########---------]  45%  4500/10000 steps  1.2 s elapsed, 1.5 s left`
fn bar_line(done: u64, total: u64, elapsed: Duration, expected: Duration) -> String {
    let fraction = (done as f64 / total as f64).clamp(0.0, 1.0);
    let filled = (fraction * Progress::WIDTH as f64).round() as usize;
    let left = expected.saturating_sub(elapsed);
    format!(
        "[{}{}] {:3.0}%  {done}/{total} steps  {:.1} s elapsed, {:.1} s left",
        "#".repeat(filled),
        "-".repeat(Progress::WIDTH - filled),
        100.0 * fraction,
        elapsed.as_secs_f64(),
        left.as_secs_f64(),
    )
}

/// Everything the end-of-run summary reports.
#[derive(Clone, Debug)]
pub struct Summary {
    /// Simulated time (s).
    pub simulated: f64,
    /// Wall-clock time (s).
    pub wall: Duration,
    /// Steps taken.
    pub steps: u64,
    /// Smallest and largest current/rest volume ratio over the tetrahedra.
    pub volume_ratio: (f32, f32),
    /// Tetrahedra that end inverted (volume ratio <= 0).
    pub inverted: usize,
    /// Tetrahedra in all.
    pub tets: usize,
    /// Energies of the final state.
    pub energies: Energies,
    /// Energies of the initial state, for comparison.
    pub initial_energies: Energies,
    /// Statistics of the implicit solves, if any.
    pub solves: SolveTotals,
    /// What one iteration of the solver is called ("iterations", "Newton iterations",
    /// "sweeps").
    pub iteration_name: &'static str,
    /// How far the centre of mass moved from start to end (m, per axis).
    pub centre_shift: [f64; 3],
}

impl Summary {
    /// The summary as lines of text.
    pub fn lines(&self) -> Vec<String> {
        let wall = self.wall.as_secs_f64();
        let rate = if wall > 0.0 {
            format!("{:.0}", self.steps as f64 / wall)
        } else {
            "-".to_string()
        };
        let (min, max) = self.volume_ratio;
        let e = &self.energies;
        let e0 = &self.initial_energies;
        let mut lines = vec![
            format!(
                "simulated time   {:.3} s in {} steps",
                self.simulated, self.steps
            ),
            format!("wall time        {wall:.3} s ({rate} steps/s)"),
            format!("volume ratio     min {min:.4}, max {max:.4} (current / rest, per tet)"),
            match self.inverted {
                0 => "inverted         none".to_string(),
                n => format!(
                    "inverted         {n} of {} tetrahedra end inside out",
                    self.tets
                ),
            },
            format!(
                "energy           {:.4} J = kinetic {:.4} + gravity {:.4} + elastic {:.4} (start {:.4} J)",
                e.total(),
                e.kinetic,
                e.potential,
                e.elastic,
                e0.total()
            ),
            format!(
                "centre of mass   moved x {:+.4} m, y {:+.4} m sideways, z {:+.4} m",
                self.centre_shift[0], self.centre_shift[1], self.centre_shift[2]
            ),
        ];
        let s = &self.solves;
        if s.solves > 0 {
            lines.push(format!(
                "implicit solves  {} ({:.1} {} on average, at most {}; {} line-search reductions)",
                s.solves,
                s.iterations as f64 / s.solves as f64,
                self.iteration_name,
                s.max_iterations,
                s.line_search_steps
            ));
            if s.inner_iterations > 0 {
                lines.push(format!(
                    "                 {} CG iterations ({:.1} per solve, {:.1} per Newton iteration)",
                    s.inner_iterations,
                    s.inner_iterations as f64 / s.solves as f64,
                    s.inner_iterations as f64 / s.iterations.max(1) as f64
                ));
            }
            if s.at_floor > 0 {
                lines.push(format!(
                    "                 {} converged at the rounding floor, above the tolerance \
                     (the precision allows no smaller residual)",
                    s.at_floor
                ));
            }
            if s.within_floor > 0 {
                lines.push(format!(
                    "                 {} stopped at a rounding floor at or above their initial \
                     residual: f32 cannot tell those steps from solved, so they are not counted \
                     as converged (each starts within rounding of its equilibrium)",
                    s.within_floor
                ));
            }
            let converged = s.solves - s.not_converged - s.within_floor;
            lines.push(format!(
                "                 {converged} of {} converged ({:.1} %), {} did not; worst final \
                 relative residual {:.2e}; {:.2} ms of wall time per step",
                s.solves,
                100.0 * converged as f64 / s.solves as f64,
                s.not_converged,
                s.worst_residual,
                1e3 * wall / self.steps.max(1) as f64
            ));
        }
        lines
    }
}

/// The smallest and largest of `ratios` (`(1, 1)` if empty).
pub fn min_max(ratios: &[f32]) -> (f32, f32) {
    if ratios.is_empty() {
        return (1.0, 1.0);
    }
    ratios
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &r| {
            (lo.min(r), hi.max(r))
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SolveTotals;

    #[test]
    fn bar_line_shows_fraction_and_times() {
        let line = bar_line(
            450,
            1000,
            Duration::from_millis(1200),
            Duration::from_millis(2700),
        );
        assert!(
            line.starts_with(&format!("[{}{}]  45%", "#".repeat(14), "-".repeat(16))),
            "{line}"
        );
        assert!(
            line.ends_with("450/1000 steps  1.2 s elapsed, 1.5 s left"),
            "{line}"
        );
    }

    #[test]
    fn hidden_progress_never_draws() {
        let mut progress = Progress::hidden();
        progress.update(1, 2);
        progress.finish();
        assert!(!progress.drawn);
    }

    #[test]
    fn summary_lists_the_figures() {
        let energies = Energies {
            kinetic: 1.0,
            potential: 2.0,
            elastic: 0.5,
        };
        let mut summary = Summary {
            simulated: 3.0,
            wall: Duration::from_secs(2),
            steps: 3000,
            volume_ratio: (0.9, 1.1),
            inverted: 0,
            tets: 100,
            energies,
            initial_energies: energies,
            solves: SolveTotals::default(),
            iteration_name: "Newton iterations",
            centre_shift: [0.00004, -0.1, -0.5],
        };
        let text = summary.lines().join("\n");
        assert!(
            text.contains("x +0.0000 m, y -0.1000 m sideways, z -0.5000 m"),
            "{text}"
        );
        assert!(text.contains("3.000 s in 3000 steps"), "{text}");
        assert!(text.contains("(1500 steps/s)"), "{text}");
        assert!(text.contains("min 0.9000, max 1.1000"), "{text}");
        assert!(text.contains("3.5000 J = kinetic 1.0000"), "{text}");
        assert!(!text.contains("implicit"));
        assert!(text.contains("inverted         none"), "{text}");
        summary.inverted = 3;
        let text = summary.lines().join("\n");
        assert!(
            text.contains("3 of 100 tetrahedra end inside out"),
            "{text}"
        );
        summary.solves = SolveTotals {
            solves: 2,
            iterations: 30,
            max_iterations: 20,
            inner_iterations: 600,
            line_search_steps: 3,
            not_converged: 1,
            within_floor: 0,
            at_floor: 1,
            worst_residual: 0.01,
        };
        let text = summary.lines().join("\n");
        assert!(
            text.contains("implicit solves  2 (15.0 Newton iterations on average, at most 20"),
            "{text}"
        );
        assert!(
            text.contains("600 CG iterations (300.0 per solve, 20.0 per Newton iteration)"),
            "{text}"
        );
        assert!(
            text.contains("1 of 2 converged (50.0 %), 1 did not"),
            "{text}"
        );
        assert!(text.contains("0.67 ms of wall time per step"), "{text}");
        assert!(text.contains("1 converged at the rounding floor"), "{text}");
    }

    #[test]
    fn min_max_of_ratios() {
        assert_eq!(min_max(&[1.0, 0.5, 2.0]), (0.5, 2.0));
        assert_eq!(min_max(&[]), (1.0, 1.0));
    }
}

//! The solver that chooses itself ([`Solver::Auto`](super::Solver::Auto), a body's default):
//! its settings, the rule that picks a stepper for each frame, the fallbacks when that
//! stepper fails, and what a frame reports.
//!
//! The rule comes from the measured tuning map (`examples/tuning_map`, the guide's solver
//! chapter): the explicit stepper's cost is its substeps, `dt / (fraction * stable step)`, each
//! one force pass; Newton's cost per frame barely depends on the stiffness. So a frame that
//! needs few substeps goes explicit and one that needs many goes to Newton's method.

use super::super::element::TetHessian;
use super::super::material::Material;
use super::super::step::{
    ExplicitMemory, ExplicitReport, ExplicitScratch, ExplicitSettings, NewtonReport,
    NewtonScratch, NewtonSettings, Scene, TetElastic, explicit_step, newton_step,
};
use super::super::types::{Mat3, Real, Vec3};
use super::copy_into;
use crate::error::{BodyError, StepError};

/// The settings of [`Solver::Auto`](super::Solver::Auto): what each candidate runs with and
/// where the rule switches between them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoSettings {
    /// The explicit stepper's damping, growth limit and least substeps (its substeps are
    /// the fewest of at most `stable_fraction` of the stable step). The growth limit is
    /// [`AutoSettings::ENERGY_GROWTH`] by default, tighter than the explicit solver's.
    pub explicit: ExplicitSettings,
    /// The explicit substep's largest share of the body's
    /// [`stable_time_step`](super::Body::stable_time_step): finite, in `(0, 1]`; 0.5 by
    /// default, as [`Solver::explicit`](super::Solver::explicit).
    pub stable_fraction: Real,
    /// The most explicit substeps a frame may take; a frame that needs more runs Newton's
    /// method. See [`AutoSettings::CROSSOVER_SUBSTEPS`] for the default and where it comes from.
    pub crossover_substeps: u32,
    /// Newton's method's settings, for the frames the rule gives it and for the fallbacks.
    pub newton: NewtonSettings,
}

impl Default for AutoSettings {
    /// As [`AutoSettings::new`].
    #[inline]
    fn default() -> Self {
        Self::new()
    }
}

impl AutoSettings {
    /// The default crossover: 100 substeps a frame. Measured on the tuning map (a 0.2 m cube
    /// of 320 tetrahedra dropped on the ground, E 1e3 to 1e9 Pa, nu 0.3 to 0.49, 30 to 240 Hz;
    /// `docs/charts/tuning_map.csv`, Intel Xeon with AVX-512, KVM guest, 2 vCPUs): one
    /// explicit substep costs 4.5 us (median over the 81 stable explicit cells, 4.3 to 5.5 us)
    /// and one Newton frame 0.47 ms (median over the 84 cells, 0.32 to 1.5 ms), so Newton
    /// pays off beyond about 105 substeps a frame, rounded to 100. Both costs grow with the
    /// vertices; Newton's frame also with its conjugate-gradient iterations, which a finer mesh
    /// needs more of, so a large body's crossover likely lies higher (measured on this cube
    /// only): set it from a measurement of the body at hand where the cost matters
    /// ([`with_crossover`](Self::with_crossover)).
    pub const CROSSOVER_SUBSTEPS: u32 = 100;

    /// The default growth limit of the explicit stepper's blow-up detector
    /// ([`ExplicitSettings::max_energy_growth`]) under the automatic solver: 6, where the
    /// explicit solver's is [`ExplicitSettings::DEFAULT_ENERGY_GROWTH`] (100).
    ///
    /// Why: the stable step is proven for the body at rest, and a body squashed far from its
    /// rest shape can be stiffer. On the tuning map the jelly of E = 1e3 Pa, nu = 0.49 lands
    /// flattened (its weight, 2 kPa over its base, is twice its modulus) and its explicit steps
    /// at half the rest shape's stable step (substeps of 1.67 to 1.75 ms at 120 to 30 Hz) gain
    /// energy until it doubles, 0.23 to 0.27 s in, unseen by a limit of 100 (measured: 0.35
    /// and 0.25 of the stable step stay stable, and so do the 1.39 ms substeps at 240 Hz). A mode at `k` times its
    /// critical step multiplies the indicator by about `(4 k^2 - 2)^2` a substep once it
    /// dominates: a limit of 100 catches it only for `k > 1.73`, a limit of 6 for
    /// `k > 1.054`, while stable motion grows it by at most 4 in practice (a body starting from
    /// rest). Measured on those cells: 6 (and 4) catches the blow-up (2 to 4 frames of the 30
    /// to 120 fall back to Newton's method, the cells stay stable), 10 and 20 do not; on no
    /// other cell of the map did a frame fall back. A false alarm
    /// costs one frame of Newton's method, not a failure; the limit is tight for that reason.
    pub const ENERGY_GROWTH: Real = 6.0;

    /// Explicit undamped substeps of at most half the stable step up to
    /// [`CROSSOVER_SUBSTEPS`](Self::CROSSOVER_SUBSTEPS) a frame, with the growth limit
    /// [`ENERGY_GROWTH`](Self::ENERGY_GROWTH); Newton's method with the defaults of
    /// [`NewtonSettings::new`] beyond.
    #[inline]
    #[must_use]
    pub const fn new() -> Self {
        AutoSettings {
            explicit: ExplicitSettings {
                max_energy_growth: Self::ENERGY_GROWTH,
                ..ExplicitSettings::new()
            },
            stable_fraction: 0.5,
            crossover_substeps: Self::CROSSOVER_SUBSTEPS,
            newton: NewtonSettings::new(),
        }
    }

    /// These settings with the crossover at `substeps` explicit substeps a frame (0: Newton's
    /// method on every frame).
    #[inline]
    #[must_use]
    pub fn with_crossover(self, substeps: u32) -> Self {
        AutoSettings {
            crossover_substeps: substeps,
            ..self
        }
    }

    /// Checks what a body checks when given these settings: `stable_fraction` finite and in
    /// `(0, 1]`.
    pub(crate) fn check(&self) -> Result<(), BodyError> {
        if self.stable_fraction > 0.0 && self.stable_fraction <= 1.0 {
            Ok(())
        } else {
            Err(BodyError::StableFraction)
        }
    }

    /// What the rule picks for a frame that needs `substeps` explicit substeps: explicit up to
    /// the crossover (and the stepper's own bound), Newton's method beyond.
    #[inline]
    #[must_use]
    pub fn choose(&self, substeps: u32) -> AutoChoice {
        if substeps <= self.crossover_substeps && substeps <= ExplicitSettings::MAX_SUBSTEPS {
            AutoChoice::Explicit { substeps }
        } else {
            AutoChoice::Newton
        }
    }
}

/// What the rule of [`AutoSettings::choose`] picked for a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum AutoChoice {
    /// The explicit stepper with this many substeps.
    Explicit {
        /// The substeps of the frame.
        substeps: u32,
    },
    /// Newton's method, one implicit Euler step for the frame.
    Newton,
}

/// A retry of a frame on a safer choice, after the one before it failed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Fallback {
    /// The explicit stepper refused the frame with this error (a blow-up: the state was
    /// restored bit for bit); Newton's method stepped the frame from its start.
    ExplicitToNewton {
        /// [`StepError::EnergyBlowUp`] or [`StepError::NonFiniteState`].
        error: StepError,
    },
    /// Newton's step of the whole frame neither converged nor stopped at its rounding floor
    /// (this is its report); the frame was stepped again from its start as two half steps.
    NewtonToHalfSteps {
        /// The report of the whole step that was thrown away.
        report: NewtonReport,
    },
}

/// The run that produced a frame's state.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum AutoRun {
    /// The explicit stepper.
    Explicit(ExplicitReport),
    /// One Newton step of the frame.
    Newton(NewtonReport),
    /// Two Newton steps of half the frame each, in order.
    NewtonHalves([NewtonReport; 2]),
}

/// What one frame of [`Solver::Auto`](super::Solver::Auto) did: the choice, the fallbacks
/// taken (at most two: explicit to Newton, Newton to half steps), and the report of the run
/// that produced the state.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub struct AutoReport {
    /// What the rule picked before any fallback.
    pub chosen: AutoChoice,
    /// The fallbacks taken, in order; `None` after the last.
    pub fallbacks: [Option<Fallback>; 2],
    /// The run whose result the body now holds.
    pub run: AutoRun,
}

impl AutoReport {
    /// Whether the run reached its tolerance: always for an explicit run; for Newton's method
    /// its report's [`converged`](NewtonReport::converged) (of both halves after a fallback to
    /// half steps), nothing added: a stop at a rounding floor that Newton's report does not
    /// call converged (a floor at or above the starting residual) is not convergence here
    /// either (see [`resolved`](Self::resolved)).
    #[inline]
    #[must_use]
    pub fn converged(&self) -> bool {
        match &self.run {
            AutoRun::Explicit(_) => true,
            AutoRun::Newton(report) => report.converged,
            AutoRun::NewtonHalves([first, second]) => first.converged && second.converged,
        }
    }

    /// Whether every solve of the run converged or stopped at its rounding floor
    /// ([`stopped_at_floor`]): the state is as close as the precision resolves, though the
    /// residual cannot say it converged (in f32 a body near rest starts within its floor,
    /// issue #44). This is what the fallbacks test, and what the tuning map counts as resolved.
    #[inline]
    #[must_use]
    pub fn resolved(&self) -> bool {
        match &self.run {
            AutoRun::Explicit(_) => true,
            AutoRun::Newton(report) => resolved(report),
            AutoRun::NewtonHalves([first, second]) => resolved(first) && resolved(second),
        }
    }

    /// The number of fallbacks taken (0, 1 or 2).
    #[inline]
    #[must_use]
    pub fn fallback_count(&self) -> usize {
        self.fallbacks.iter().filter(|f| f.is_some()).count()
    }

    /// Solver iterations of the run: explicit substeps, or Newton iterations (of both halves),
    /// not counting the runs thrown away by the fallbacks.
    #[inline]
    #[must_use]
    pub fn iterations(&self) -> u32 {
        match &self.run {
            AutoRun::Explicit(report) => report.substeps,
            AutoRun::Newton(report) => report.iterations,
            AutoRun::NewtonHalves([first, second]) => {
                first.iterations.saturating_add(second.iterations)
            }
        }
    }
}

/// Whether a Newton solve that did not converge stopped at its rounding floor: it
/// [`stagnated`](NewtonReport::stagnated) with its residual within
/// [`FLOOR_FACTOR`](NewtonReport::FLOOR_FACTOR) times its finite
/// [`rounding_floor`](NewtonReport::rounding_floor). A converged solve is not "at the floor".
#[inline]
#[must_use]
pub fn stopped_at_floor(report: &NewtonReport) -> bool {
    !report.converged
        && report.stagnated
        && report.rounding_floor.is_finite()
        && report.residual <= NewtonReport::FLOOR_FACTOR * report.rounding_floor
}

/// Converged, or stopped at the rounding floor.
#[inline]
fn resolved(report: &NewtonReport) -> bool {
    report.converged || stopped_at_floor(report)
}

/// Whether an explicit error is a blow-up, after which the state is restored and Newton's
/// method may take the frame; other errors (the scene, the state given) would fail it too.
#[inline]
fn is_blow_up(error: &StepError) -> bool {
    matches!(
        error,
        StepError::EnergyBlowUp | StepError::NonFiniteState { .. }
    )
}

/// The vectors per vertex of the automatic solver's scratch: Newton's 9 and a copy of the
/// positions and velocities at the frame's start for the retry in half steps.
pub(crate) const AUTO_VECTORS: usize = 11;

/// Newton's vectors per vertex.
const NEWTON_VECTORS: usize = 9;

/// What one frame of the automatic solver works on: the body's state and scratch, borrowed
/// apart from its mesh (the model) so that both can be in use at once.
pub(super) struct AutoParts<'a> {
    pub(super) masses: &'a [Real],
    pub(super) pinned: &'a [bool],
    pub(super) positions: &'a mut [Vec3],
    pub(super) velocities: &'a mut [Vec3],
    /// [`AUTO_VECTORS`] vectors per vertex: Newton's (the explicit stepper's four first), then
    /// the frame's start positions and velocities.
    pub(super) vectors: &'a mut [Vec3],
    pub(super) blocks: &'a mut [Mat3],
    pub(super) hessians: &'a mut [TetHessian],
    /// The explicit stepper's blow-up history, kept across frames.
    pub(super) memory: &'a mut ExplicitMemory,
    /// Whether the explicit stepper records the contact impulses (see `Body::step_with_reactions`).
    pub(super) record: bool,
}

/// One frame of the automatic solver in `scene`: the run of `choice` and its fallbacks. On an
/// error the positions and velocities are those of the frame's start, bit for bit.
pub(super) fn run_auto<M: Material>(
    model: &TetElastic<'_, M>,
    scene: &Scene<'_, Vec3>,
    settings: &AutoSettings,
    choice: AutoChoice,
    parts: &mut AutoParts<'_>,
) -> Result<AutoReport, StepError> {
    let mut fallbacks = [None, None];
    if let AutoChoice::Explicit { substeps } = choice {
        let explicit = settings.explicit.with_substeps(substeps);
        match parts.explicit(model, scene, &explicit) {
            Ok(report) => {
                return Ok(AutoReport {
                    chosen: choice,
                    fallbacks,
                    run: AutoRun::Explicit(report),
                });
            }
            Err(error) if is_blow_up(&error) => {
                fallbacks[0] = Some(Fallback::ExplicitToNewton { error });
            }
            Err(error) => return Err(error),
        }
    }
    // Newton's frames are not explicit substeps: the next explicit frame must not compare its
    // forces with those of a frame before these.
    *parts.memory = ExplicitMemory::FRESH;
    parts.save_frame_start();
    let whole = parts.newton(model, scene, &settings.newton)?;
    if resolved(&whole) {
        return Ok(AutoReport {
            chosen: choice,
            fallbacks,
            run: AutoRun::Newton(whole),
        });
    }
    let slot = usize::from(fallbacks[0].is_some());
    if let Some(entry) = fallbacks.get_mut(slot) {
        *entry = Some(Fallback::NewtonToHalfSteps { report: whole });
    }
    parts.restore_frame_start();
    let half = Scene {
        dt: 0.5 * scene.dt,
        ..*scene
    };
    let halves = parts
        .newton(model, &half, &settings.newton)
        .and_then(|first| Ok([first, parts.newton(model, &half, &settings.newton)?]));
    match halves {
        Ok(halves) => Ok(AutoReport {
            chosen: choice,
            fallbacks,
            run: AutoRun::NewtonHalves(halves),
        }),
        Err(error) => {
            // A second half that fails leaves the middle of the frame: back to its start.
            parts.restore_frame_start();
            Err(error)
        }
    }
}

impl AutoParts<'_> {
    /// The explicit stepper over the first four vectors per vertex, with the blow-up history.
    fn explicit<M: Material>(
        &mut self,
        model: &TetElastic<'_, M>,
        scene: &Scene<'_, Vec3>,
        settings: &ExplicitSettings,
    ) -> Result<ExplicitReport, StepError> {
        let n = self.positions.len();
        let (buffer, impulses) = super::explicit_slots(self.vectors, n, self.record);
        let mut scratch = ExplicitScratch::resume(buffer, *self.memory).with_impulses(impulses);
        let outcome = explicit_step(
            model,
            self.masses,
            self.pinned,
            scene,
            settings,
            self.positions,
            self.velocities,
            &mut scratch,
        );
        *self.memory = scratch.memory();
        outcome
    }

    /// One Newton step over the first nine vectors per vertex.
    fn newton<M: Material>(
        &mut self,
        model: &TetElastic<'_, M>,
        scene: &Scene<'_, Vec3>,
        settings: &NewtonSettings,
    ) -> Result<NewtonReport, StepError> {
        let n = self.positions.len();
        let buffer = self
            .vectors
            .get_mut(..n.saturating_mul(NEWTON_VECTORS))
            .unwrap_or(&mut []);
        let mut scratch = NewtonScratch::new(buffer, self.blocks, self.hessians);
        newton_step(
            model,
            self.masses,
            self.pinned,
            scene,
            settings,
            self.positions,
            self.velocities,
            &mut scratch,
        )
    }

    /// The positions and velocities into the last two vectors per vertex.
    fn save_frame_start(&mut self) {
        let (saved_x, saved_v) = frame_start(self.vectors, self.positions.len());
        copy_into(saved_x, self.positions);
        copy_into(saved_v, self.velocities);
    }

    /// The positions and velocities back from [`save_frame_start`](Self::save_frame_start).
    fn restore_frame_start(&mut self) {
        let (saved_x, saved_v) = frame_start(self.vectors, self.positions.len());
        copy_into(self.positions, saved_x);
        copy_into(self.velocities, saved_v);
    }
}

/// The scratch's copy of the frame's start: positions and velocities, `n` vectors each after
/// Newton's nine per vertex (empty where the scratch is shorter, which the sizing rules out).
fn frame_start(vectors: &mut [Vec3], n: usize) -> (&mut [Vec3], &mut [Vec3]) {
    let start = n.saturating_mul(NEWTON_VECTORS);
    let saved = vectors
        .get_mut(start..start.saturating_add(n.saturating_mul(2)))
        .unwrap_or(&mut []);
    saved.split_at_mut(n.min(saved.len()))
}

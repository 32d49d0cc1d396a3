//! The explicit stepper and how large its time step may be: [`explicit_step`] (symplectic
//! Euler with damping, pinned vertices, contact, substeps and blow-up detection), the
//! guaranteed stability bounds [`stable_time_step`] and [`element_stable_time_step`] with the
//! small-strain moduli they rest on ([`linearised_moduli`]), and the measured highest frequency
//! [`estimate_max_frequency`] (a power iteration, [`FrequencyEstimate`]).
//!
//! The stepper's settings, report and scratch and [`stable_time_step`] are also at
//! [`softfem::step`](super); the rest is used by name from here, for example
//! `softfem::step::explicit::estimate_max_frequency`.

pub(crate) mod frequency;
pub(crate) mod stability;

use super::super::element::Vector;
#[cfg(target_arch = "x86_64")]
use super::super::lanes::avx2::Avx2Lanes;
#[cfg(target_arch = "x86_64")]
use super::super::lanes::avx512::Avx512Lanes;
use super::super::lanes::{LaneArray, Lanes};
use super::super::types::Real;
use super::contact::HalfSpace;
use super::contact::vertex::resolve_colliders;
use super::descent::line_search::copy;
use super::model::ElasticModel;
use super::scene::Scene;
use super::scratch_len;
use super::state::{check_length, pinned_flags};
use super::vertex_pass::Blocks;
use super::vertex_pass::passes::{free_lanes, load_scalars, split_check_state};
use super::vertex_pass::point::Wide;
use crate::error::{MeshError, StepBuffer, StepError};
use crate::simd::{WidthKernel, dispatch};
pub use frequency::{FrequencyEstimate, estimate_max_frequency};
pub use stability::{element_stable_time_step, linearised_moduli, stable_time_step};

/// The default [`ExplicitSettings::max_energy_growth`]: 100.
///
/// Why: for a linear system stepped below its stability limit, the indicator
/// `E = sum m |v|^2 / 2 + dt^2 sum |f|^2 / (8 m)` can grow by at most a factor 74 in one step
/// (`|dv| <= dt |f| / m` and `|df|` bounded by `omega_max^2 m |dx|` with `dt omega_max < 2`),
/// and in practice by at most 4 (a body starting from rest). A mode past the limit, at `k` times
/// the critical step, multiplies it by about `(4 k^2 - 2)^2` per step: 1156 at 3x.
pub(crate) const DEFAULT_ENERGY_GROWTH: Real = 100.0;

/// The most substeps one [`explicit_step`] call takes: `65536`. More is refused with
/// [`StepError::Substeps`] before anything runs (a call of `u32::MAX` substeps would otherwise
/// run for hours without a chance to stop it); take several calls instead.
pub(crate) const MAX_SUBSTEPS: u32 = 1 << 16;

/// The growth factor of the early blow-up test: a substep whose elastic forces `f_n` satisfy
/// `<f_n, f_(n-1)> < -FLIP_GROWTH |f_(n-1)|^2` (mass-weighted: reversed and at least this much
/// larger than the last substep's) counts as one step of the unstable mode; see
/// [`explicit_step`].
pub(crate) const FLIP_GROWTH: Real = 1.5;

/// The number of consecutive substeps that must pass the
/// [`FLIP_GROWTH`](ExplicitSettings::FLIP_GROWTH) test for [`explicit_step`] to report
/// [`StepError::EnergyBlowUp`].
pub(crate) const FLIP_STREAK: u32 = 3;

/// The growth factor of the early blow-up test's fast form: two substeps in a row whose forces
/// satisfy `<f_n, f_(n-1)> < -FAST_FLIP_GROWTH |f_(n-1)|^2` (mass-weighted) are a blow-up,
/// without waiting for [`FLIP_STREAK`](ExplicitSettings::FLIP_STREAK). A stable mode cannot do
/// this: after one reversal that grew (a force passing near its zero), the next ratio of a mode
/// with `|lambda| = 1` is at most `2 cos(delta) < 2` (`delta` the phase it turns per substep away
/// from a pure reversal); see [`explicit_step`].
pub(crate) const FAST_FLIP_GROWTH: Real = 4.0;

/// How [`explicit_step`] integrates a step: its substeps, damping and the blow-up detector's
/// limit. What the step acts on (the time step, gravity, the ground, colliders, loads) is the
/// [`Scene`]. Borrows nothing, so a body keeps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExplicitSettings {
    /// The number of equal substeps the scene's `dt` is split into (at least 1, at most
    /// [`MAX_SUBSTEPS`](ExplicitSettings::MAX_SUBSTEPS)); for stability each substep must stay
    /// below [`stable_time_step`].
    pub substeps: u32,
    /// Mass-proportional damping `c >= 0` (1/s): each substep, after the force update,
    /// `v <- v / (1 + c h)`, a backward-Euler drag `dv/dt = -c v` that is stable for every `c`
    /// and `h`. Velocities relax with time constant about `1/c`.
    pub damping: Real,
    /// The blow-up detector's limit (> 1): a substep whose energy indicator exceeds this factor
    /// times the previous substep's is refused with [`StepError::EnergyBlowUp`]. See
    /// [`DEFAULT_ENERGY_GROWTH`](ExplicitSettings::DEFAULT_ENERGY_GROWTH).
    pub max_energy_growth: Real,
}

impl Default for ExplicitSettings {
    /// As [`ExplicitSettings::new`].
    #[inline]
    fn default() -> Self {
        Self::new()
    }
}

impl ExplicitSettings {
    /// The default growth limit of the blow-up detector (see
    /// [`max_energy_growth`](Self::max_energy_growth)): 100.
    pub const DEFAULT_ENERGY_GROWTH: Real = DEFAULT_ENERGY_GROWTH;
    /// The most substeps a call takes: 65536 (`substeps` above it is refused).
    pub const MAX_SUBSTEPS: u32 = MAX_SUBSTEPS;
    /// The growth factor of the early blow-up test (see [`explicit_step`]): 1.5.
    pub const FLIP_GROWTH: Real = FLIP_GROWTH;
    /// The substeps in a row that must pass the early blow-up test for a blow-up: 3.
    pub const FLIP_STREAK: u32 = FLIP_STREAK;
    /// The growth factor of the early test's fast form (see [`explicit_step`]): 4, two
    /// substeps in a row.
    pub const FAST_FLIP_GROWTH: Real = FAST_FLIP_GROWTH;

    /// One substep, no damping, the default growth limit.
    #[inline]
    #[must_use]
    pub const fn new() -> Self {
        ExplicitSettings {
            substeps: 1,
            damping: 0.0,
            max_energy_growth: DEFAULT_ENERGY_GROWTH,
        }
    }

    /// These settings with damping `damping` (1/s).
    #[inline]
    #[must_use]
    pub fn with_damping(self, damping: Real) -> Self {
        ExplicitSettings { damping, ..self }
    }

    /// These settings with `substeps` substeps per call.
    #[inline]
    #[must_use]
    pub fn with_substeps(self, substeps: u32) -> Self {
        ExplicitSettings { substeps, ..self }
    }

    /// Checks the settings.
    ///
    /// # Errors
    /// [`StepError::Substeps`], [`StepError::Damping`], [`StepError::GrowthLimit`].
    fn check(&self) -> Result<(), StepError> {
        if self.substeps == 0 || self.substeps > MAX_SUBSTEPS {
            return Err(StepError::Substeps);
        }
        if !(self.damping >= 0.0 && self.damping.is_finite()) {
            return Err(StepError::Damping);
        }
        if self.max_energy_growth.is_nan() || self.max_energy_growth <= 1.0 {
            return Err(StepError::GrowthLimit);
        }
        Ok(())
    }
}

/// Scratch space of [`explicit_step`] over a caller buffer of
/// [`scratch_len::explicit`]`(vertex_count)` vectors, and the blow-up detector's memory of the
/// last substeps.
///
/// Keep one per body across calls: the detector compares each substep with the ones before,
/// including the last substeps of the previous call. After changing positions or velocities
/// yourself (a kick, a teleport), call [`forget_history`](Self::forget_history) so that the
/// change is not mistaken for a blow-up. (A body exactly at rest with no gravity leaves no
/// reference to compare with, so motion started from there is never taken for one.)
#[derive(Debug)]
pub struct ExplicitScratch<'a, V> {
    buffer: &'a mut [V],
    /// Where the colliders' contact impulses go (empty for nowhere), see
    /// [`with_impulses`](ExplicitScratch::with_impulses).
    impulses: &'a mut [V],
    /// The detector's memory of the last accepted substep.
    history: Option<History>,
    /// Whether the first quarter of `buffer` (rather than the second) holds the forces of the
    /// last substep; the other holds those of the substep before.
    latest_first: bool,
    /// The vertices of the last step (four or five vectors each in `buffer`).
    vertex_count: usize,
}

/// What the blow-up detector keeps of the last accepted substep.
#[derive(Clone, Copy, Debug)]
struct History {
    /// The substep length (s) it was taken with.
    h: Real,
    /// Its energy indicator (J).
    indicator: Real,
    /// `sum |f|^2 / m` over the free vertices (N^2/kg); its forces are the older of the two
    /// force buffers when the next substep runs.
    force_norm: Real,
    /// Consecutive substeps, up to and including it, that passed the
    /// [`FLIP_GROWTH`](ExplicitSettings::FLIP_GROWTH) test.
    streak: u32,
    fast: bool,
    /// The energy (J) its collider contacts may have added to the next substep's indicator
    /// (see [`contact_work`]); zero without colliders.
    contact_work: Real,
}

impl<'a, V: Vector> ExplicitScratch<'a, V> {
    /// Scratch over `buffer` (its length is checked by [`explicit_step`]).
    #[inline]
    #[must_use]
    pub fn new(buffer: &'a mut [V]) -> Self {
        ExplicitScratch {
            vertex_count: buffer.len() / 4,
            buffer,
            impulses: &mut [],
            history: None,
            latest_first: true,
        }
    }

    /// This scratch, recording into `impulses` (one per vertex, length checked by
    /// [`explicit_step`]) the impulse (N s) the colliders and pins applied to each vertex over
    /// a step: at a free vertex `m (v_after - v_before)` of every collider projection of every
    /// substep, summed (zero where no collider acted; the ground's projections are not
    /// counted); at a pinned vertex `-h (f + f_ext + m g)` summed over the substeps, what held
    /// it against its forces. A step sets every entry; after an error the entries are
    /// unspecified. Recording runs the update one vertex at a time (the same bits as the SIMD
    /// lanes).
    #[inline]
    #[must_use]
    pub fn with_impulses(self, impulses: &'a mut [V]) -> Self {
        ExplicitScratch { impulses, ..self }
    }

    /// Forgets the previous substeps: the next substep is not checked for energy growth (only
    /// for finiteness), and the reversal streak starts anew. Done automatically after a blow-up
    /// error and when the substep length changes.
    #[inline]
    pub fn forget_history(&mut self) {
        self.history = None;
    }

    /// The forces computed in the last substep (N; the elastic forces only), one per vertex.
    #[inline]
    #[must_use]
    pub fn forces(&self) -> &[V] {
        let n = self.vertex_count;
        let start = if self.latest_first { 0 } else { n };
        self.buffer.get(start..start + n).unwrap_or(&[])
    }
}

/// What an [`ExplicitScratch`] remembers between calls besides its buffer: kept by an owner of
/// the buffer (the [`Body`](super::super::body::Body)) while no scratch view is alive.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ExplicitMemory {
    history: Option<History>,
    latest_first: bool,
}

impl ExplicitMemory {
    /// The memory of a new scratch: no history.
    pub(crate) const FRESH: ExplicitMemory = ExplicitMemory {
        history: None,
        latest_first: true,
    };
}

impl<'a, V: Vector> ExplicitScratch<'a, V> {
    /// Scratch over `buffer` (as [`new`](Self::new)) that goes on from `memory`.
    #[inline]
    #[must_use]
    pub(crate) fn resume(buffer: &'a mut [V], memory: ExplicitMemory) -> Self {
        ExplicitScratch {
            vertex_count: buffer.len() / 4,
            buffer,
            impulses: &mut [],
            history: memory.history,
            latest_first: memory.latest_first,
        }
    }

    /// What [`resume`](Self::resume) needs to go on from here.
    #[inline]
    #[must_use]
    pub(crate) fn memory(&self) -> ExplicitMemory {
        ExplicitMemory {
            history: self.history,
            latest_first: self.latest_first,
        }
    }
}

/// What one [`explicit_step`] call did.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ExplicitReport {
    /// The substeps taken.
    pub substeps: u32,
    /// The kinetic energy `sum m |v|^2 / 2` (J) at the end of the call.
    pub kinetic_energy: Real,
    /// The vertices projected out of the ground in the last substep.
    pub ground_contacts: usize,
    /// The substeps whose whole motion a model that
    /// [limits the motion](super::ElasticModel::limits_motion) (contact between surfaces) had to
    /// shorten: in those substeps every vertex moved less than its velocity says (time ran
    /// slower for them). 0 for other models.
    pub motion_cuts: u32,
}

/// Advances `positions` (m) and `velocities` (m/s) by the scene's `dt` with symplectic Euler
/// (`docs/math.md` section 4), in `settings.substeps` substeps of `h = dt / substeps`, each:
///
/// 1. `f = ` the elastic forces of `model` at `x` (N);
/// 2. `v <- (v + h (f / m + g)) / (1 + c h)` (gravity `g`, damping `c`);
/// 3. `x <- x + h v`;
/// 4. contact with the scene's ground ([`HalfSpace`]) and colliders: projection, restitution,
///    friction.
///
/// Pinned vertices (`pinned[i]`; an empty slice pins nothing) keep their position and velocity
/// exactly. `masses` (kg) are lumped masses, one per vertex.
///
/// **Blow-up detection.** Two tests run before each substep's update, on the elastic forces
/// `f` at the current positions and the free vertices only:
///
/// * *Early: the unstable mode.* Past the critical step, symplectic Euler's step map has a real
///   eigenvalue `lambda < -1` (for a mode of frequency `omega` it solves
///   `lambda + 1/lambda = 2 - h^2 omega^2`, `lambda = -1.88` at 1.05 times the critical step,
///   `-23` at 2.5 times): that mode's forces reverse and grow by `|lambda|` every substep from
///   the rounding noise up. A substep whose forces satisfy
///   `sum f_n . f_(n-1) / m < -`[`FLIP_GROWTH`](ExplicitSettings::FLIP_GROWTH)` sum |f_(n-1)|^2 /
///   m` (reversed, and larger by at least that factor) counts;
///   [`FLIP_STREAK`](ExplicitSettings::FLIP_STREAK) such substeps in a row are an
///   [`StepError::EnergyBlowUp`], and so are two in a row that reversed and grew by
///   [`FAST_FLIP_GROWTH`](ExplicitSettings::FAST_FLIP_GROWTH) (`lambda = -6.9` at 1.5 times the
///   critical step: caught a substep sooner). Physical motion does not do this: rigid motion has no elastic
///   forces, a compression or impact keeps their direction (`<f_n, f_(n-1)> > 0`), and a stable
///   mode (`|lambda| = 1`) cannot grow by `1.5` per substep for three substeps in a row while
///   reversing each time. The forces weight the highest mode by `omega^2`, so it dominates them
///   (and is caught) while its displacement is still far below the other motion's. Measured on a
///   dropped jelly cube (`tests/steppers/step.rs`, `early_blow_up_detection_report`): at 1.05, 1.5
///   and 2.5 times the critical step the error comes after 2 to 9 accepted steps and the state
///   handed back lies within 3e-3 body sizes of a stable run (most of that is the coarser step's
///   own free-fall error), and no stable step (0.5 and 0.9 times the proven bound, 3 s of drop and
///   bounce) is refused. Released from a shape off rest (every coordinate moved by up to 1e-4 of
///   an edge, four seeds; `blow_up_from_a_perturbed_start_is_handed_back_early`), the state
///   handed back lies within 4.4e-3 and 1.8e-3 body sizes at 1.05 and 1.5 times, and 1.8e-2 at
///   2.5 times, where the mode grows 23-fold per substep and the test needs the first substep's
///   forces to compare with (two accepted steps). **What it cannot do:** a body already ringing
///   in its high modes (moved 1 % of an edge off rest) hides the unstable mode until that
///   dominates: at 1.05 times the critical step the error came only after 11 to 18 steps, the
///   body several times its size away. Keep the step below the limit
///   ([`FrequencyEstimate::time_step`](FrequencyEstimate::time_step), or the proven
///   [`stable_time_step`]); the detector is the net, not the rule.
/// * *Coarse: a jump.* The indicator
///   `E = sum m |v|^2 / 2 + h^2 sum |f|^2 / (8 m) + h^2 sum m |g|^2 / 2` (J) must not exceed
///   [`max_energy_growth`](ExplicitSettings::max_energy_growth) times the previous substep's.
///   (`h^2 |f|^2 / (8 m)` bounds the elastic energy from below when `h` is stable, so `E`
///   tracks the energy without a second pass over the elements.) It catches a sudden jump, such
///   as a caller's kick the detector was not told of. The work of the last substep's collider
///   contacts is added to the reference (`docs/math.md` section 4.3): a
///   fast collider's impact is not a blow-up. Without colliders the test is unchanged.
///
/// After the substep, any NaN or infinite position or velocity is a
/// [`StepError::NonFiniteState`]. On any error, positions and velocities are restored bit for
/// bit to their values before the call: the caller gets back the state at the start of the
/// call (the last state every test accepted) and can retry it with a smaller step. The
/// detector's memory is kept in `scratch` across calls; see [`ExplicitScratch`].
///
/// ```
/// use softfem::element::TetRest;
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::{
///     ExplicitScratch, ExplicitSettings, HalfSpace, Scene, TetElastic, scratch_len,
///     explicit_step, stable_time_step,
/// };
///
/// // One tetrahedron dropped from 1 cm onto the ground y = 0.
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z].map(|x| x * 0.1 + Vec3::Y * 0.01);
/// let tets = [[0, 1, 2, 3]];
/// let mut rest_data = [TetRest::default(); 1];
/// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
/// let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.3)?);
/// let mut masses = [0.0; 4];
/// mesh.lumped_masses(1000.0, &mut masses)?;
///
/// let mut stiffness = [0.0; 4];
/// let dt = 0.5 * stable_time_step(&body, &masses, &[], &mut stiffness)?;
/// let scene = Scene::new(dt)
///     .with_gravity(Vec3::new(0.0, -9.81, 0.0))
///     .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
/// let settings = ExplicitSettings::new().with_damping(5.0);
/// let (mut x, mut v) = (rest, [Vec3::ZERO; 4]);
/// let mut buffer = [Vec3::ZERO; scratch_len::explicit(4)];
/// let mut scratch = ExplicitScratch::new(&mut buffer);
/// for _ in 0..(0.5 / dt) as usize {
///     explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch)?;
/// }
/// assert!(x.iter().all(|p| p.y > -1e-6)); // on the ground, not in it
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// Before anything is touched: the scene's errors ([`Scene::validated`]: the time step, gravity,
/// colliders, the ground), then [`StepError::Substeps`], [`StepError::Damping`],
/// [`StepError::GrowthLimit`], then
/// [`StepError::LengthMismatch`] (positions, velocities, masses, pinned, scratch),
/// [`StepError::Mass`] and [`StepError::NonFiniteInput`] (first vertex). After a substep:
/// [`StepError::EnergyBlowUp`] (also for positions of its own making that the kernel finds
/// beyond the material's finite range, [`MeshError::DeformationRange`]),
/// [`StepError::NonFiniteState`] (first vertex), or a [`StepError::Mesh`] from the kernel (the
/// clamp threshold, the caller's positions beyond the material's range) or a custom model, with
/// the state restored.
#[allow(clippy::too_many_arguments)]
pub fn explicit_step<F: ElasticModel>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, F::Vector>,
    settings: &ExplicitSettings,
    positions: &mut [F::Vector],
    velocities: &mut [F::Vector],
    scratch: &mut ExplicitScratch<'_, F::Vector>,
) -> Result<ExplicitReport, StepError> {
    let n = model.vertex_count();
    let ground = scene.validated()?;
    settings.check()?;
    split_check_state(model, masses, pinned, positions, Some(velocities))?;
    scene.loads().check(n)?;
    let limits_motion = model.limits_motion();
    let scratch_needed = if limits_motion {
        scratch_len::explicit_contact(n)
    } else {
        scratch_len::explicit(n)
    };
    check_length(StepBuffer::Scratch, scratch_needed, scratch.buffer.len())?;
    if !scratch.impulses.is_empty() {
        check_length(StepBuffer::Impulses, n, scratch.impulses.len())?;
        scratch.impulses.fill(F::Vector::ZERO);
    }
    scratch.vertex_count = n;
    let (first_forces, rest) = scratch.buffer.split_at_mut_checked(n).unwrap_or_default();
    let (second_forces, backup) = rest.split_at_mut_checked(n).unwrap_or_default();
    let (backup_positions, rest) = backup.split_at_mut_checked(n).unwrap_or_default();
    let (backup_velocities, substep_start) = rest.split_at_mut_checked(n).unwrap_or_default();
    let mut substep_start = limits_motion.then_some(substep_start);
    // Entry by entry: the lengths were checked, but an out-of-line call (the body calls this
    // stepper too) hides them from the optimiser, and `copy_from_slice` would keep a panic path.
    let save = |_, ((backup_x, backup_v), (x, v)): (State<'_, F::Vector>, _)| {
        copy(backup_x, x);
        copy(backup_v, v);
    };
    let buffers = (
        (&mut *backup_positions, &mut *backup_velocities),
        (&*positions, &*velocities),
    );
    model.run_vertex_pass(Blocks::new(n, buffers, &save));

    let h = scene.dt / settings.substeps as Real;
    if scratch.history.is_some_and(|history| history.h != h) {
        scratch.history = None;
    }
    let (mut ground_contacts, mut kinetic_energy, mut motion_cuts) = (0, 0.0, 0u32);
    for _ in 0..settings.substeps {
        // The new forces go where the older of the two force buffers is.
        let (forces, previous_forces) = if scratch.latest_first {
            (&mut *second_forces, &*first_forces)
        } else {
            (&mut *first_forces, &*second_forces)
        };
        let outcome = substep(
            model,
            masses,
            pinned,
            (scene, settings),
            ground.as_ref(),
            h,
            (positions, velocities, &mut *scratch.impulses),
            (forces, previous_forces),
            substep_start.as_deref_mut(),
            &mut scratch.history,
        );
        scratch.latest_first = !scratch.latest_first;
        match outcome {
            Ok((contacts, kinetic, cut)) => {
                (ground_contacts, kinetic_energy) = (contacts, kinetic);
                motion_cuts += u32::from(cut);
            }
            Err(error) => {
                copy(positions, backup_positions);
                copy(velocities, backup_velocities);
                scratch.history = None;
                return Err(error);
            }
        }
    }
    Ok(ExplicitReport {
        substeps: settings.substeps,
        kinetic_energy,
        ground_contacts,
        motion_cuts,
    })
}

/// One substep; returns the number of ground contacts, the kinetic energy (J) after it and
/// whether the model cut its whole motion short. `forces` receives the new forces;
/// `previous_forces` holds those of the last accepted substep when `history` is `Some`;
/// `substep_start` (where the model limits the motion) receives the positions before the
/// update. On an error the state may be half updated: the caller restores it.
#[allow(clippy::too_many_arguments)]
fn substep<F: ElasticModel>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    (scene, settings): (&Scene<'_, F::Vector>, &ExplicitSettings),
    ground: Option<&HalfSpace<F::Vector>>,
    h: Real,
    (positions, velocities, impulses): Recorded<'_, F::Vector>,
    (forces, previous_forces): (&mut [F::Vector], &[F::Vector]),
    mut substep_start: Option<&mut [F::Vector]>,
    history: &mut Option<History>,
) -> Result<(usize, Real, bool), StepError> {
    let n = forces.len();
    let clear = |_, forces: &mut [F::Vector]| forces.fill(F::Vector::ZERO);
    model.run_vertex_pass(Blocks::new(n, &mut *forces, &clear));
    model
        .add_forces(positions, forces)
        .map_err(|error| match error {
            // Positions this stepper produced (its detector accepted the substep before) that are
            // beyond the material's range are the blow-up itself, caught before the stress
            // overflows; the caller's own positions keep the kernel's error.
            MeshError::DeformationRange { .. } if history.is_some() => StepError::EnergyBlowUp,
            other => StepError::Mesh(other),
        })?;

    // One pass over the vertices: the blow-up indicator's sums at the state before the update,
    // the update, and the kinetic energy and first non-finite vertex after it. The sums are
    // checked after the pass; a blow-up found then returns an error and the caller restores the
    // state, so updating first changes nothing the caller sees.
    let frame = Update {
        scene,
        damping: settings.damping,
        ground,
        h,
        gravity_squared: scene.gravity.dot(scene.gravity),
    };
    let update = |first, ((x, v), (f, previous, m, pinned), impulses): Rows<'_, F::Vector>| {
        frame.block(first, (x, v), (f, previous, m, pinned), impulses)
    };
    if let Some(start) = substep_start.as_deref_mut() {
        copy(start, positions);
    }
    let state = (&mut *positions, &mut *velocities);
    let inputs = (&*forces, previous_forces, masses, pinned);
    let (sums, contacts, kinetic_energy, non_finite) =
        model.run_vertex_pass(Blocks::new(n, (state, inputs, impulses), &update));
    // sum of the indicator terms, of |f|^2 / m, of f_n . f_(n-1) / m, and of the collider
    // contacts' work
    let (indicator, force_norm, reversal, contact_work) = sums;
    let mut streak = 0;
    let mut fast_flag = false;
    if let Some(previous) = *history {
        // A NaN indicator counts as growth. A zero previous indicator (exactly at rest, no
        // gravity) is no reference: any motion would be an "infinite" jump. The energy the last
        // substep's collider contacts put in is part of the reference (zero without colliders:
        // `x + 0` is `x`, the same test as before colliders counted).
        if indicator.is_nan()
            || (previous.indicator > 0.0
                && indicator
                    > settings.max_energy_growth * (previous.indicator + previous.contact_work))
        {
            return Err(StepError::EnergyBlowUp);
        }
        if reversal < -FLIP_GROWTH * previous.force_norm {
            streak = previous.streak.saturating_add(1);
        }
        let fast = reversal < -FAST_FLIP_GROWTH * previous.force_norm;
        if fast && previous.fast {
            return Err(StepError::EnergyBlowUp);
        }
        fast_flag = fast;
        if streak >= FLIP_STREAK {
            return Err(StepError::EnergyBlowUp);
        }
    }
    if let Some(vertex) = non_finite {
        return Err(StepError::NonFiniteState { vertex });
    }
    let cut = match substep_start {
        Some(start) => model
            .limit_motion(start, positions, velocities, (masses, pinned), h)
            .map_err(StepError::Mesh)?,
        None => false,
    };
    *history = Some(History {
        h,
        indicator,
        force_norm,
        streak,
        fast: fast_flag,
        contact_work,
    });
    Ok((contacts, kinetic_energy, cut))
}

/// A block's share of the positions and velocities.
type State<'r, V> = (&'r mut [V], &'r mut [V]);

/// The positions, the velocities and the contact impulses (empty for none) of a substep.
type Recorded<'r, V> = (&'r mut [V], &'r mut [V], &'r mut [V]);

/// A block's share of the substep's buffers: positions and velocities, then forces, previous
/// forces, masses and pinned flags, then the contact impulses (empty for none).
type Rows<'r, V> = (
    State<'r, V>,
    (&'r [V], &'r [V], &'r [Real], &'r [bool]),
    &'r mut [V],
);

/// What the update pass of a substep needs besides the buffers.
struct Update<'s, 'a, V: Vector> {
    scene: &'s Scene<'a, V>,
    /// The settings' damping (1/s).
    damping: Real,
    ground: Option<&'s HalfSpace<V>>,
    h: Real,
    gravity_squared: Real,
}

/// The update pass's results so far, added vertex by vertex in order: the blow-up indicator's
/// three sums (from the state before the update) and the collider contacts' work
/// ([`contact_work`]), the contacts, the kinetic energy (J) after it and the first vertex left
/// non-finite.
#[derive(Clone, Copy, Default)]
struct Tally {
    indicator: Real,
    force_norm: Real,
    reversal: Real,
    contact_work: Real,
    contacts: usize,
    kinetic_energy: Real,
    non_finite: Option<usize>,
}

impl<V: Vector> Update<'_, '_, V> {
    /// The update of the vertices from `first` on: returns the blow-up indicator's three sums
    /// (from the state before the update) and the collider contacts' work, the contacts, the
    /// kinetic energy (J) after it and the first vertex left non-finite.
    ///
    /// Without colliders and fixed axes, the vertices go in groups of the
    /// width [`dispatch`] picks (then narrower groups, then one at a time), each lane through
    /// the one-vertex arithmetic and the sums added vertex by vertex in order: the bits of the
    /// one-at-a-time loop, which runs the rest.
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    fn block(
        &self,
        first: usize,
        (positions, velocities): (&mut [V], &mut [V]),
        (forces, previous_forces, masses, pinned): (&[V], &[V], &[Real], &[bool]),
        impulses: &mut [V],
    ) -> ((Real, Real, Real, Real), usize, Real, Option<usize>) {
        let scene = self.scene;
        let kernel = UpdatePass {
            update: self,
            first,
            state: (positions, velocities),
            inputs: (forces, previous_forces, masses, pinned),
            impulses,
        };
        // Recording impulses takes the one-vertex path (the same bits as the lanes).
        let plain =
            scene.colliders.is_empty() && scene.fixed_axes.is_empty() && kernel.impulses.is_empty();
        let tally = if plain {
            dispatch(kernel)
        } else {
            kernel.scalar()
        };
        (
            (
                tally.indicator,
                tally.force_norm,
                tally.reversal,
                tally.contact_work,
            ),
            tally.contacts,
            tally.kinetic_energy,
            tally.non_finite,
        )
    }

    /// The update of vertex `i` (at `x` moving at `v`, force `f`, previous force `previous`,
    /// mass `m`), added to `tally`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn one(
        &self,
        i: usize,
        (x, v): (&mut V, &mut V),
        (f, previous): (&V, &V),
        (m, impulse): (Real, Option<&mut V>),
        pinned: bool,
        tally: &mut Tally,
    ) {
        let (scene, h) = (self.scene, self.h);
        let gravity = scene.gravity;
        let drag = 1.0 / (1.0 + self.damping * h);
        let resting_speed = 2.0 * h * super::super::math::sqrt(self.gravity_squared);
        let loads = scene.loads();
        if !pinned {
            let inverse_mass = 1.0 / m;
            let f_squared = f.dot(*f) * inverse_mass;
            tally.indicator +=
                0.5 * m * (v.dot(*v) + h * h * self.gravity_squared) + h * h * f_squared / 8.0;
            tally.force_norm += f_squared;
            tally.reversal += f.dot(*previous) * inverse_mass;

            let mut acceleration = *f * (1.0 / m) + gravity;
            if !loads.forces.is_empty() {
                acceleration += loads.force(i) * (1.0 / m);
            }
            // Fixed axes: no velocity along them, so the coordinate keeps its bits.
            *v = loads.free_part(i, (*v + acceleration * h) * drag);
            let before = *x;
            *x += *v * h;
            if let Some(ground) = self.ground {
                tally.contacts += usize::from(ground.resolve(x, v, resting_speed, h));
                *x = loads.keep_fixed(i, *x, before);
                *v = loads.free_part(i, *v);
            }
            if !scene.colliders.is_empty() {
                let (free_x, free_v) = (*x, *v);
                tally.contacts += resolve_colliders(scene.colliders, x, v, (resting_speed, h));
                *x = loads.keep_fixed(i, *x, before);
                *v = loads.free_part(i, *v);
                tally.contact_work += contact_work(m, h, (*x - free_x, free_v, *v));
                if let Some(impulse) = impulse {
                    *impulse += (*v - free_v) * m;
                }
            }
        } else if let Some(impulse) = impulse {
            // The pin holds the vertex against its forces: its impulse over the substep.
            let mut load = *f + gravity * m;
            if !loads.forces.is_empty() {
                load += loads.force(i);
            }
            *impulse -= load * h;
        }
        tally.kinetic_energy += 0.5 * m * v.dot(*v);
        if tally.non_finite.is_none() && !(x.is_finite() && v.is_finite()) {
            tally.non_finite = Some(i);
        }
    }

    /// [`one`](Self::one) for the `L::WIDTH` vertices from `i` on (at `x` moving at `v`,
    /// forces `f` and `previous`, masses `m`, pinned flags `pinned` or empty for none, each
    /// chunk `L::WIDTH` long but `pinned`), without colliders and fixed axes: every lane gets
    /// the one-vertex bits, and the sums take the lanes in order.
    #[inline(always)]
    fn group<L: LaneArray>(
        &self,
        i: usize,
        (x_slot, v_slot): (&mut [V], &mut [V]),
        (f, previous, m, pinned): (&[V], &[V], &[Real], &[bool]),
        tally: &mut Tally,
    ) {
        let (scene, h) = (self.scene, self.h);
        let splat = L::splat;
        let (zero, one) = (splat(0.0), splat(1.0));
        let drag = splat(1.0 / (1.0 + self.damping * h));
        let resting_speed = 2.0 * h * super::super::math::sqrt(self.gravity_squared);
        let (x, v) = (V::Wide::<L>::load(x_slot), V::Wide::<L>::load(v_slot));
        let (f, previous) = (V::Wide::<L>::load(f), V::Wide::<L>::load(previous));
        let m = load_scalars::<L>(m);
        let lanes_h = splat(h);

        let inverse_mass = one / m;
        let f_squared = f.wide_inner(f) * inverse_mass;
        let indicator = splat(0.5) * m * (v.wide_inner(v) + splat(h * h * self.gravity_squared))
            + splat(h * h) * f_squared / splat(8.0);
        let reversal = f.wide_inner(previous) * inverse_mass;

        let mut acceleration = f.wide_scale(one / m) + V::Wide::<L>::wide_splat(gravity_of(scene));
        let external = scene.external_forces.get(i..).filter(|f| !f.is_empty());
        if let Some(external) = external {
            acceleration = acceleration + V::Wide::<L>::load(external).wide_scale(one / m);
        }
        let new_v = (v + acceleration.wide_scale(lanes_h)).wide_scale(drag);
        let mut new_x = x + new_v.wide_scale(lanes_h);
        let mut new_v = new_v;
        let mut inside = zero;
        if let Some(ground) = self.ground {
            let normal = V::Wide::<L>::wide_splat(ground.normal);
            let depth = -(normal.wide_inner(new_x) - splat(ground.offset));
            let into = depth.gt(zero);
            // The common case, no lane inside, changes nothing (same result).
            if !L::none(into) {
                inside = L::select(into, one, zero);
                let projected = new_x + normal.wide_scale(depth);
                let vn = normal.wide_inner(new_v);
                let restitution = L::select(
                    (-vn).gt(splat(resting_speed)),
                    splat(ground.restitution),
                    zero,
                );
                let normal_change = (one + restitution) * -vn;
                let tangential = new_v - normal.wide_scale(vn);
                let speed = tangential.wide_inner(tangential).sqrt();
                let reduction = splat(ground.friction) * normal_change;
                let keep = L::select(speed.gt(reduction), one - reduction / speed, zero);
                let kept = tangential.wide_scale(keep);
                let slid = if ground.friction > 0.0 {
                    projected + (kept - tangential).wide_scale(lanes_h)
                } else {
                    projected
                };
                let bounced = kept + normal.wide_scale(-restitution * vn);
                let approaching = zero.gt(vn);
                new_x = V::Wide::<L>::wide_select(
                    into,
                    V::Wide::<L>::wide_select(approaching, slid, projected),
                    new_x,
                );
                new_v = V::Wide::<L>::wide_select(
                    into,
                    V::Wide::<L>::wide_select(approaching, bounced, new_v),
                    new_v,
                );
            }
        }
        let (x, v) = match free_lanes::<L>(pinned, 0) {
            Some(free) => (
                V::Wide::<L>::wide_select(free, new_x, x),
                V::Wide::<L>::wide_select(free, new_v, v),
            ),
            None => (new_x, new_v),
        };
        let kinetic_energy = splat(0.5) * m * v.wide_inner(v);
        x.store(x_slot);
        v.store(v_slot);

        let values = |l: L| l.to_lane_array();
        let (indicator, f_squared, reversal) =
            (values(indicator), values(f_squared), values(reversal));
        let (inside, kinetic_energy) = (values(inside), values(kinetic_energy));
        for k in 0..L::WIDTH {
            let lane = |values: &L::Array| L::lane_value(values, k);
            if !pinned.get(k).copied().unwrap_or(false) {
                tally.indicator += lane(&indicator);
                tally.force_norm += lane(&f_squared);
                tally.reversal += lane(&reversal);
                tally.contacts += usize::from(lane(&inside) > 0.0);
            }
            tally.kinetic_energy += lane(&kinetic_energy);
        }
        // Zero in every lane whose position and velocity are finite, NaN elsewhere.
        let finite = x.finite_zero() + v.finite_zero();
        if tally.non_finite.is_none() && !L::none(L::select(finite.ge(zero), zero, one).gt(zero)) {
            let mut bad = x_slot.iter().zip(v_slot.iter());
            tally.non_finite = bad
                .position(|(x, v)| !(x.is_finite() && v.is_finite()))
                .map(|k| i + k);
        }
    }
}

/// The energy (J) a collider contact may have put into the blow-up indicator of the next
/// substep at a vertex of mass `m` (kg) in a substep of `h` (s), from the contact's change of
/// its position `dx` (m) and velocity from `before` to `after` (m/s):
/// `max(0, m (|after|^2 - |before|^2) / 2) + 2 m |dx|^2 / h^2`.
///
/// A moving collider does work on the body: it sets a vertex's velocity to its own surface's
/// (200 m/s from rest is a jump of the kinetic energy far beyond any growth limit) and pushes
/// the vertex out by up to its speed times the step, which the forces of the next substep
/// feel. Neither is the unstable mode the detector looks for, so the indicator is compared
/// with the last one *plus* this work. The first term is the kinetic energy the contact added;
/// the second bounds what the push adds to the indicator's force term: a displacement `dx`
/// changes the forces by `K dx`, and `h^2 |K dx|^2_(M^-1) / 8 <= h^2 omega_max^4 |dx|^2_M / 8
/// < 2 |dx|^2_M / h^2` while `h omega_max < 2` (`docs/math.md` section 4.3). Energy a contact
/// takes out (a static collider stopping a vertex) is not subtracted: the reference only grows,
/// so no contact makes the test stricter than without colliders.
#[inline(always)]
fn contact_work<V: Vector>(m: Real, h: Real, (dx, before, after): (V, V, V)) -> Real {
    let kinetic = 0.5 * m * (after.dot(after) - before.dot(before));
    kinetic.max(0.0) + 2.0 * m * dx.dot(dx) / (h * h)
}

/// The gravity of `scene`.
#[inline(always)]
fn gravity_of<V: Vector>(scene: &Scene<'_, V>) -> V {
    scene.gravity
}

/// One block of the update pass, at the width [`dispatch`] picks: whole groups of the widest
/// lanes first, then narrower ones, then one vertex at a time, all in vertex order.
struct UpdatePass<'u, 's, 'a, 'r, V: Vector> {
    update: &'u Update<'s, 'a, V>,
    /// The block's first vertex.
    first: usize,
    state: State<'r, V>,
    inputs: (&'r [V], &'r [V], &'r [Real], &'r [bool]),
    /// The block's contact impulses (empty for none; only [`singles`](Self::singles) runs
    /// where colliders are).
    impulses: &'r mut [V],
}

impl<V: Vector> UpdatePass<'_, '_, '_, '_, V> {
    /// Groups of `L::WIDTH` vertices from block vertex `done` on, as far as whole groups go:
    /// returns the vertices done.
    #[inline(always)]
    fn groups<L: LaneArray>(&mut self, mut done: usize, tally: &mut Tally) -> usize {
        let (positions, velocities) = (&mut *self.state.0, &mut *self.state.1);
        let (forces, previous, masses, pinned) = self.inputs;
        let width = L::WIDTH;
        let rows = positions.len().min(velocities.len()).min(forces.len());
        let rows = rows.min(previous.len()).min(masses.len());
        while done + width <= rows {
            let range = done..done + width;
            let (Some(x), Some(v), Some(f), Some(p), Some(m)) = (
                positions.get_mut(range.clone()),
                velocities.get_mut(range.clone()),
                forces.get(range.clone()),
                previous.get(range.clone()),
                masses.get(range),
            ) else {
                break;
            };
            let flags = pinned.get(done..).unwrap_or(&[]);
            let flags = flags.get(..width).unwrap_or(flags);
            self.update
                .group::<L>(self.first + done, (x, v), (f, p, m, flags), tally);
            done += width;
        }
        done
    }

    /// The vertices from block vertex `done` on, one at a time.
    #[inline(always)]
    fn singles(self, done: usize, mut tally: Tally) -> Tally {
        let (positions, velocities) = self.state;
        let (forces, previous_forces, masses, pinned) = self.inputs;
        let state = positions.iter_mut().zip(velocities.iter_mut());
        let rows = state.zip(forces.iter().zip(previous_forces));
        let rows = rows.zip(masses).zip(pinned_flags(pinned)).enumerate();
        for (j, ((((x, v), (f, previous)), &m), pinned)) in rows.skip(done) {
            let i = self.first + j;
            let impulse = self.impulses.get_mut(j);
            self.update
                .one(i, (x, v), (f, previous), (m, impulse), pinned, &mut tally);
        }
        tally
    }
}

impl<V: Vector> WidthKernel for UpdatePass<'_, '_, '_, '_, V> {
    type Output = Tally;

    #[inline(always)]
    fn scalar(self) -> Tally {
        self.singles(0, Tally::default())
    }

    #[inline(always)]
    fn sse(mut self) -> Tally {
        let mut tally = Tally::default();
        let done = self.groups::<Lanes>(0, &mut tally);
        self.singles(done, tally)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx2(mut self) -> Tally {
        let mut tally = Tally::default();
        let done = self.groups::<Avx2Lanes>(0, &mut tally);
        let done = self.groups::<Lanes>(done, &mut tally);
        self.singles(done, tally)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx512(mut self) -> Tally {
        let mut tally = Tally::default();
        let done = self.groups::<Avx512Lanes>(0, &mut tally);
        let done = self.groups::<Avx2Lanes>(done, &mut tally);
        let done = self.groups::<Lanes>(done, &mut tally);
        self.singles(done, tally)
    }
}

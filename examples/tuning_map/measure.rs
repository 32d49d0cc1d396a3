//! One cell of the map: the standard scene stepped by one solver at one material and frame
//! time, and what was measured.
//!
//! The scene: a 0.2 m cube of 4 x 4 x 4 cells (125 vertices, 320 tetrahedra, five a cell),
//! 1000 kg/m^3, stable neo-Hookean, f32, its lowest face 0.1 m above the ground plane y = 0
//! (friction 0.5), under gravity, stepped one `Body::step` a frame for the simulated time. The
//! ground is the body's own (`Body::set_ground` with a `HalfSpace`, what the guide's examples
//! use) or, with `--ground collider`, a `Collider::half_space` given to every
//! `step_with_colliders`: the same plane through the collider path, which the implicit solvers
//! handle differently (measured: more iterations, each dearer; see the guide's solver chapter).
//! The solvers are the constructors of `softfem::body::Solver` with their defaults:
//! `explicit()` (substeps of half the stable step), `relax()`, `newton()`, `vbd()`, and
//! `auto()`, the body's default, which picks explicit or Newton each frame and falls back.

use softfem::StepError;
use softfem::body::{AutoRun, Body, Solver, StepReport, VecStorage};
use softfem::glam::Vec3;
use softfem::material::StableNeoHookean;
use softfem::step::{Collider, HalfSpace, RelaxReport};

/// Edge of the cube (m), its cells per axis, density (kg/m^3) and drop height (m).
pub const EDGE: f32 = 0.2;
pub const CELLS: usize = 4;
pub const DENSITY: f32 = 1000.0;
pub const DROP: f32 = 0.1;
/// Gravity (m/s^2), along -y; the ground is the plane y = 0.
pub const GRAVITY: f32 = 9.81;
/// An explicit cell whose frame needs more substeps than this is not run ("too costly").
pub const MAX_SUBSTEPS_PER_FRAME: u32 = 20_000;
/// A state is taken as blown up (unstable, though no step reported an error) when a vertex
/// leaves a box of this half-width (m) around the origin or the total energy exceeds this many
/// times the starting energy: nothing in the scene adds energy, so only the integrator can.
const ESCAPE: f32 = 10.0;
const ENERGY_GROWTH: f64 = 2.0;

/// The solvers of the map, in the order of its panels and rows: the four a user can name, and
/// the automatic one (`Solver::auto()`, the body's default) that picks between them per frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverKind {
    Explicit,
    Relax,
    Newton,
    Vbd,
    Auto,
}

impl SolverKind {
    pub const ALL: [SolverKind; 5] = [
        SolverKind::Explicit,
        SolverKind::Relax,
        SolverKind::Newton,
        SolverKind::Vbd,
        SolverKind::Auto,
    ];

    /// The name in the CSV and on the chart.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Explicit => "explicit",
            SolverKind::Relax => "relax",
            SolverKind::Newton => "newton",
            SolverKind::Vbd => "vbd",
            SolverKind::Auto => "auto",
        }
    }

    fn solver(self) -> Solver {
        match self {
            SolverKind::Explicit => Solver::explicit(),
            SolverKind::Relax => Solver::relax(),
            SolverKind::Newton => Solver::newton(),
            SolverKind::Vbd => Solver::vbd(),
            SolverKind::Auto => Solver::auto(),
        }
    }
}

/// Which ground the cube lands on: the same plane, friction 0.5, through one of two paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Ground {
    /// The body's ground, `Body::set_ground(Some(HalfSpace))`, stepped by `Body::step`.
    Body,
    /// A `Collider::half_space` given to every `Body::step_with_colliders`.
    Collider,
}

impl Ground {
    /// The name in the CSV and on the chart.
    pub fn name(self) -> &'static str {
        match self {
            Ground::Body => "body",
            Ground::Collider => "collider",
        }
    }
}

/// The ground's Coulomb friction coefficient.
const FRICTION: f32 = 0.5;

/// What a cell is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellInput {
    pub solver: SolverKind,
    /// Young's modulus (Pa).
    pub young: f32,
    /// Poisson's ratio.
    pub poisson: f32,
    /// Frame time (s): one step a frame.
    pub frame_time: f32,
    /// Simulated time (s).
    pub duration: f64,
    /// The ground's path.
    pub ground: Ground,
}

/// How a cell ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Every frame stepped without an error and the state stayed bounded.
    Stable,
    /// A step returned an error or the state blew up, at the frame given; the cell stopped there.
    Unstable { frame: usize, reason: String },
    /// Explicit only: a frame would need this many substeps (over the map's bound); not run.
    TooCostly { substeps: u32 },
}

impl Outcome {
    /// The CSV's `status` column.
    pub fn status(&self) -> &'static str {
        match self {
            Outcome::Stable => "stable",
            Outcome::Unstable { .. } => "unstable",
            Outcome::TooCostly { .. } => "too_costly",
        }
    }
}

/// What was measured in a cell. Averages are over the frames run (all of them when stable).
#[derive(Clone, Debug, PartialEq)]
pub struct CellResult {
    pub input: CellInput,
    pub outcome: Outcome,
    /// Frames the simulated time asks for, and frames stepped (with success).
    pub frames: usize,
    pub frames_run: usize,
    /// Frames run whose report says converged (explicit: every frame run).
    pub frames_converged: usize,
    /// Frames run whose solve did not converge but stopped with its residual at the rounding
    /// floor (`stagnated`, residual within `FLOOR_FACTOR` times `rounding_floor`): the state is
    /// as close as the precision resolves, though the report cannot say it converged (in f32,
    /// a body at rest starts within its floor; issue #44). The other frames run spent the
    /// budget or stalled above the floor.
    pub frames_at_floor: usize,
    /// Frames run by the explicit stepper in the end (the explicit solver: every frame run;
    /// the automatic one: its explicit choices that did not fall back).
    pub frames_explicit: usize,
    /// Frames of the automatic solver that took a fallback (explicit to Newton, Newton to half
    /// steps); 0 for the others.
    pub frames_fallback: usize,
    /// Thread CPU time (or wall time, see [`CLOCK`]) of the step calls per frame run (s).
    pub cost_per_frame: f64,
    /// The body's stable explicit step (s), for every solver (the scale of the stiffness).
    pub stable_step: f64,
    /// Explicit: substeps a frame; implicit: mean solver iterations a frame.
    pub work_per_frame: f64,
    /// Total energy (kinetic, elastic, gravity above the ground) at the start (J).
    pub initial_energy: f64,
    /// Energy at the start minus at the last frame run, over the simulated time run (J/s).
    pub energy_lost_per_second: f64,
    /// The largest `|V / V0 - 1|` over the frames run.
    pub volume_error: f64,
}

impl CellResult {
    /// Whether every frame run converged or stopped at its rounding floor (explicit: every
    /// frame), and at least one ran.
    pub fn resolved(&self) -> bool {
        self.frames_run > 0 && self.frames_converged + self.frames_at_floor == self.frames_run
    }

    /// [`frames_converged`](Self::frames_converged) over the frames run (NaN if none ran).
    pub fn converged_share(&self) -> f64 {
        self.frames_converged as f64 / self.frames_run as f64
    }

    /// [`frames_at_floor`](Self::frames_at_floor) over the frames run (NaN if none ran).
    pub fn floor_share(&self) -> f64 {
        self.frames_at_floor as f64 / self.frames_run as f64
    }

    /// [`energy_lost_per_second`](Self::energy_lost_per_second) over the starting energy (1/s).
    pub fn energy_lost_share_per_second(&self) -> f64 {
        self.energy_lost_per_second / self.initial_energy
    }
}

/// The clock the costs are measured with: `"thread_cpu"` (the stepping thread's CPU time,
/// `clock_gettime(CLOCK_THREAD_CPUTIME_ID)`, Linux) or `"wall"` (elsewhere).
#[cfg(target_os = "linux")]
pub const CLOCK: &str = "thread_cpu";
#[cfg(not(target_os = "linux"))]
pub const CLOCK: &str = "wall";

/// The calling thread's CPU time (s): what the cost column measures, free of the time other
/// processes on a shared machine take from it.
#[cfg(target_os = "linux")]
fn clock_seconds() -> f64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid, writable timespec for the duration of the call, which writes
    // nothing else; the clock id is a constant every Linux kernel since 2.6.12 knows.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut now) };
    if rc == 0 {
        now.tv_sec as f64 + now.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

/// Wall time (s) since the first call: the cost clock where no thread CPU clock is read.
#[cfg(not(target_os = "linux"))]
fn clock_seconds() -> f64 {
    use std::sync::OnceLock;
    use std::time::Instant;
    static START: OnceLock<Instant> = OnceLock::new();
    START.get_or_init(Instant::now).elapsed().as_secs_f64()
}

type JellyBody = Body<VecStorage, StableNeoHookean>;

/// The standard scene at rest, lowest face `DROP` above the ground, with `input`'s material and
/// solver.
pub fn scene(input: &CellInput) -> Result<JellyBody, String> {
    let material = StableNeoHookean::from_young_poisson(input.young, input.poisson)
        .map_err(|e| format!("material E = {}, nu = {}: {e}", input.young, input.poisson))?;
    let half = 0.5 * EDGE;
    let low = Vec3::new(-half, DROP, -half);
    let high = Vec3::new(half, DROP + EDGE, half);
    let mut body = JellyBody::from_box(low, high, [CELLS; 3], DENSITY, material)
        .map_err(|e| format!("the cube: {e}"))?;
    body.set_gravity(Vec3::new(0.0, -GRAVITY, 0.0));
    if input.ground == Ground::Body {
        body.set_ground(Some(HalfSpace::new(Vec3::Y, 0.0).with_friction(FRICTION)));
    }
    body.set_solver(input.solver.solver())
        .map_err(|e| format!("solver {}: {e}", input.solver.name()))?;
    Ok(body)
}

/// The colliders of a step: the ground as a collider, or none (the body's own ground).
fn colliders(ground: Ground) -> Vec<Collider<'static>> {
    match ground {
        Ground::Body => Vec::new(),
        Ground::Collider => {
            vec![Collider::half_space(Vec3::ZERO, Vec3::Y).with_friction(FRICTION)]
        }
    }
}

/// The total energy (J): kinetic, elastic and gravity's potential above the ground, in f64.
pub fn total_energy(body: &JellyBody) -> Result<f64, String> {
    let elastic = body
        .mesh()
        .elastic_energy(body.material(), body.positions())
        .map_err(|e| format!("elastic energy: {e}"))?;
    let mut energy = f64::from(elastic);
    for ((x, v), &m) in body
        .positions()
        .iter()
        .zip(body.velocities())
        .zip(body.masses())
    {
        let m = f64::from(m);
        energy += 0.5 * m * f64::from(v.length_squared()) + m * f64::from(GRAVITY) * f64::from(x.y);
    }
    Ok(energy)
}

/// The body's volume (m^3): the sum of its tetrahedra's signed volumes at `positions`.
pub fn volume(tets: &[[u32; 4]], positions: &[Vec3]) -> f64 {
    tets.iter()
        .map(|t| {
            let p = t.map(|i| positions[i as usize].as_dvec3());
            (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) / 6.0
        })
        .sum()
}

/// Runs one cell. `Err` only for a scene that cannot be built (a bug or a bad flag), never
/// for what the cell measures.
pub fn run_cell(input: &CellInput) -> Result<CellResult, String> {
    let mut body = scene(input)?;
    let frames = (input.duration / f64::from(input.frame_time))
        .round()
        .max(1.0) as usize;
    let stable_step = f64::from(
        body.stable_time_step()
            .map_err(|e| format!("stable time step: {e}"))?,
    );
    let initial_energy = total_energy(&body)?;
    let rest_volume = volume(body.tets(), body.rest_positions());
    let mut result = CellResult {
        input: *input,
        outcome: Outcome::Stable,
        frames,
        frames_run: 0,
        frames_converged: 0,
        frames_at_floor: 0,
        frames_explicit: 0,
        frames_fallback: 0,
        cost_per_frame: f64::NAN,
        stable_step,
        work_per_frame: f64::NAN,
        initial_energy,
        energy_lost_per_second: f64::NAN,
        volume_error: 0.0,
    };
    if let Solver::Explicit {
        stable_fraction: Some(fraction),
        ..
    } = input.solver.solver()
    {
        // The substeps `Body::step` will take: the fewest of at most `fraction` of the stable
        // step.
        let substeps = (f64::from(input.frame_time) / (f64::from(fraction) * stable_step)).ceil();
        if substeps > f64::from(MAX_SUBSTEPS_PER_FRAME) {
            result.outcome = Outcome::TooCostly {
                substeps: substeps.min(f64::from(u32::MAX)) as u32,
            };
            return Ok(result);
        }
    }
    let colliders = colliders(input.ground);
    let mut converged = 0usize;
    let mut at_floor = 0usize;
    let mut work = 0u64;
    let mut seconds = 0.0;
    let mut energy = initial_energy;
    for frame in 0..frames {
        let started = clock_seconds();
        let report = if colliders.is_empty() {
            body.step(input.frame_time)
        } else {
            body.step_with_colliders(input.frame_time, &colliders)
        };
        seconds += clock_seconds() - started;
        let report = match report {
            Ok(report) => report,
            Err(error) => {
                result.outcome = Outcome::Unstable {
                    frame,
                    reason: error_name(&error),
                };
                break;
            }
        };
        let escaped = body
            .positions()
            .iter()
            .any(|x| !x.is_finite() || x.abs().max_element() > ESCAPE);
        // An energy that cannot be evaluated (a non-finite state) is a blow-up too.
        let now = total_energy(&body).unwrap_or(f64::NAN);
        let blown_up = if escaped {
            Some("Escaped")
        } else if !now.is_finite() {
            Some("EnergyNotFinite")
        } else if now > ENERGY_GROWTH * initial_energy {
            Some("EnergyGrew")
        } else {
            None
        };
        if let Some(reason) = blown_up {
            result.outcome = Outcome::Unstable {
                frame,
                reason: reason.to_owned(),
            };
            break;
        }
        energy = now;
        converged += usize::from(report.converged());
        at_floor += usize::from(stopped_at_floor(&report));
        work += match report {
            StepReport::Explicit(r) => u64::from(r.substeps),
            StepReport::Relax(r) => u64::from(r.iterations),
            StepReport::Newton(r) => u64::from(r.iterations),
            StepReport::Vbd(r) => u64::from(r.iterations),
            StepReport::Auto(r) => u64::from(r.iterations()),
            _ => 0,
        };
        result.frames_explicit += usize::from(match report {
            StepReport::Explicit(_) => true,
            StepReport::Auto(r) => matches!(r.run, AutoRun::Explicit(_)),
            _ => false,
        });
        if let StepReport::Auto(r) = report {
            result.frames_fallback += usize::from(r.fallback_count() > 0);
        }
        let error = (volume(body.tets(), body.positions()) / rest_volume - 1.0).abs();
        result.volume_error = result.volume_error.max(error);
        result.frames_run += 1;
    }
    result.frames_converged = converged;
    result.frames_at_floor = at_floor;
    if result.frames_run > 0 {
        let run = result.frames_run as f64;
        result.cost_per_frame = seconds / run;
        result.work_per_frame = work as f64 / run;
        result.energy_lost_per_second =
            (initial_energy - energy) / (run * f64::from(input.frame_time));
    }
    Ok(result)
}

/// Whether an implicit solve that did not converge stopped at its rounding floor (the
/// automatic solver: its every Newton solve converged or stopped there, not all converged).
fn stopped_at_floor(report: &StepReport) -> bool {
    let (converged, stagnated, residual, floor) = match report {
        StepReport::Auto(r) => return !r.converged() && r.resolved(),
        StepReport::Relax(r) => (r.converged, r.stagnated, r.residual, r.rounding_floor),
        StepReport::Newton(r) => (r.converged, r.stagnated, r.residual, r.rounding_floor),
        StepReport::Vbd(r) => (r.converged, r.stagnated, r.residual, r.rounding_floor),
        _ => return false,
    };
    !converged && stagnated && residual <= RelaxReport::FLOOR_FACTOR * floor
}

/// The error's variant name (`EnergyBlowUp`, `Substeps`...): a plain CSV cell.
fn error_name(error: &StepError) -> String {
    let debug = format!("{error:?}");
    debug
        .split(|c: char| !c.is_alphanumeric())
        .next()
        .unwrap_or("StepError")
        .to_owned()
}

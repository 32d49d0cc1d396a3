//! The scene: the body (a generated jelly cube or a TetGen mesh) above the ground plane `z = 0`,
//! its material and masses, the energies and volume ratios the summary reports, and the
//! time loop that drives a stepper and hands output frames to the writers.
//!
//! Conventions: metres, seconds, kilograms; `z` points up, gravity is `(0, 0, -G)`, the ground
//! is the half-space `z >= 0`.

use std::path::Path;
use std::time::{Duration, Instant};

use softfem::asset::tetgen::read_tetgen_files;
use softfem::element::{TetRest, fix_orientation};
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::Vec3;
use softfem::material::{NeoHookean, StVK, StableNeoHookean};
use softfem::mesh::TetMesh;

use crate::cli::{Args, Model, Stepper};
use crate::progress::Progress;
use crate::surface::Surface;

/// Standard gravity (m/s^2).
pub const G: f32 = 9.81;
/// The gravity vector (m/s^2): `z` is up.
pub const GRAVITY: Vec3 = Vec3::new(0.0, 0.0, -G);
/// The explicit stepper's default time step as a fraction of the stable bound.
pub const EXPLICIT_SAFETY_FRACTION: f32 = 0.5;
/// The implicit steppers' default time step (s): one display frame at 60 Hz.
pub const RELAX_DEFAULT_DT: f32 = 1.0 / 60.0;

/// The rest shape of the body, already placed above the ground.
#[derive(Clone, Debug)]
pub struct Geometry {
    /// Where it came from, for the printout ("jelly cube 0.2 m, 6^3 cells", a path).
    pub source: String,
    /// Rest positions (m): centred on the `z` axis, lowest point at the drop height.
    pub rest_positions: Vec<Vec3>,
    /// Positively oriented tetrahedra.
    pub tets: Vec<[u32; 4]>,
    /// How many tetrahedra of the input had negative orientation and were reordered.
    pub reoriented: usize,
    /// How many vertices of the input belonged to no tetrahedron and were dropped.
    pub dropped_vertices: usize,
}

impl Geometry {
    /// The body the flags describe: `--mesh` if given, the jelly cube otherwise.
    pub fn from_args(args: &Args) -> Result<Geometry, String> {
        let geometry = match &args.mesh {
            Some(node) => Geometry::from_tetgen(node)?,
            None => {
                Geometry::jelly_cube(args.size, args.resolution as usize, args.split.box_split())?
            }
        };
        Ok(geometry.placed_above_ground(args.drop_height))
    }

    /// A cube of edge `size` (m) with `cells` cubes per axis, each split into tetrahedra by
    /// `split`, with its lowest face at `z = 0`.
    pub fn jelly_cube(size: f32, cells: usize, split: BoxSplit) -> Result<Geometry, String> {
        let (vertex_count, tet_count) =
            box_counts(cells, cells, cells, split).map_err(|e| format!("jelly cube: {e}"))?;
        let mut rest_positions = vec![Vec3::ZERO; vertex_count];
        let mut tets = vec![[0; 4]; tet_count];
        let half = Vec3::new(size / 2.0, size / 2.0, 0.0);
        let (min, max) = (-half, half + Vec3::new(0.0, 0.0, size));
        fill_box(
            min,
            max,
            cells,
            cells,
            cells,
            split,
            &mut rest_positions,
            &mut tets,
        )
        .map_err(|e| format!("jelly cube: {e}"))?;
        Ok(Geometry {
            source: format!(
                "jelly cube {size} m, {cells}^3 cells, {} tets each",
                split.tets_per_cell()
            ),
            rest_positions,
            tets,
            reoriented: 0,
            dropped_vertices: 0,
        })
    }

    /// The TetGen mesh `node` (a `.node` file) with the `.ele` file next to it; negatively
    /// oriented tetrahedra are reordered and vertices in no tetrahedron are dropped (they
    /// would have no mass).
    pub fn from_tetgen(node: &Path) -> Result<Geometry, String> {
        if node.extension().is_none_or(|ext| ext != "node") {
            return Err(format!(
                "--mesh {}: expected a TetGen .node file (with the .ele file next to it)",
                node.display()
            ));
        }
        let ele = node.with_extension("ele");
        let mesh = read_tetgen_files(node, &ele).map_err(|e| e.to_string())?;
        if mesh.tets.is_empty() {
            return Err(format!("{}: the mesh has no tetrahedra", ele.display()));
        }
        let mut reoriented = 0;
        let tets: Vec<[u32; 4]> = mesh
            .tets
            .iter()
            .map(|&tet| {
                let fixed = fix_orientation(tet, tet.map(|v| mesh.positions[v as usize]));
                reoriented += usize::from(fixed != tet);
                fixed
            })
            .collect();
        let (rest_positions, tets, dropped_vertices) = compact(&mesh.positions, &tets);
        Ok(Geometry {
            source: node.display().to_string(),
            rest_positions,
            tets,
            reoriented,
            dropped_vertices,
        })
    }

    /// The same shape translated so that it is centred on the `z` axis (bounding box) with its
    /// lowest point at `z = height`.
    pub fn placed_above_ground(mut self, height: f32) -> Geometry {
        let (min, max) = bounds(&self.rest_positions);
        let shift = Vec3::new(
            -(min.x + max.x) / 2.0,
            -(min.y + max.y) / 2.0,
            height - min.z,
        );
        for p in &mut self.rest_positions {
            *p += shift;
        }
        self
    }
}

/// Keeps only the vertices some tetrahedron uses, renumbered in their original order.
fn compact(positions: &[Vec3], tets: &[[u32; 4]]) -> (Vec<Vec3>, Vec<[u32; 4]>, usize) {
    let mut new_index = vec![u32::MAX; positions.len()];
    for &v in tets.iter().flatten() {
        new_index[v as usize] = 0;
    }
    let mut kept = Vec::with_capacity(positions.len());
    for (slot, &p) in new_index.iter_mut().zip(positions) {
        if *slot == 0 {
            *slot = kept.len() as u32;
            kept.push(p);
        }
    }
    let tets = tets
        .iter()
        .map(|tet| tet.map(|v| new_index[v as usize]))
        .collect();
    let dropped = positions.len() - kept.len();
    (kept, tets, dropped)
}

/// The axis-aligned bounding box `(min, max)` of `points` (zeros if empty).
pub fn bounds(points: &[Vec3]) -> (Vec3, Vec3) {
    match points.first() {
        None => (Vec3::ZERO, Vec3::ZERO),
        Some(&first) => points
            .iter()
            .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
    }
}

/// One of the three material models, chosen at run time.
///
/// The stepper is generic over `M: Material`; to call it, match once and hand the concrete
/// model to a generic function: `match material { AnyMaterial::StVK(m) => go(m), ... }`.
#[derive(Clone, Copy, Debug)]
pub enum AnyMaterial {
    /// Saint Venant–Kirchhoff.
    StVK(StVK),
    /// The isochoric neo-Hookean.
    NeoHookean(NeoHookean),
    /// Stable neo-Hookean.
    StableNeoHookean(StableNeoHookean),
}

impl AnyMaterial {
    /// `model` with Young's modulus `e` (Pa) and Poisson ratio `nu`.
    pub fn new(model: Model, e: f32, nu: f32) -> Result<AnyMaterial, String> {
        let material = match model {
            Model::StVK => StVK::from_young_poisson(e, nu).map(AnyMaterial::StVK),
            Model::NeoHookean => NeoHookean::from_young_poisson(e, nu).map(AnyMaterial::NeoHookean),
            Model::StableNeoHookean => {
                StableNeoHookean::from_young_poisson(e, nu).map(AnyMaterial::StableNeoHookean)
            }
        };
        material.map_err(|error| format!("material ({model}, E = {e} Pa, nu = {nu}): {error}"))
    }

    /// The elastic energy (J) of the mesh at `positions`.
    pub fn elastic_energy(&self, mesh: &TetMesh<'_>, positions: &[Vec3]) -> Result<f32, String> {
        let energy = match self {
            AnyMaterial::StVK(m) => mesh.elastic_energy(m, positions),
            AnyMaterial::NeoHookean(m) => mesh.elastic_energy(m, positions),
            AnyMaterial::StableNeoHookean(m) => mesh.elastic_energy(m, positions),
        };
        energy.map_err(|e| e.to_string())
    }

    /// The dilatational wave speed `sqrt((lambda + 2 mu) / rho)` (m/s) at density `rho`, the
    /// speed in the rule-of-thumb explicit stability bound (docs/math.md section 4).
    pub fn wave_speed(&self, density: f32) -> f32 {
        let lame = match self {
            AnyMaterial::StVK(m) => m.lame(),
            AnyMaterial::NeoHookean(m) => m.lame(),
            AnyMaterial::StableNeoHookean(m) => m.lame(),
        };
        ((lame.lambda() + 2.0 * lame.mu()) / density).sqrt()
    }
}

/// The validated body: mesh (borrowing the geometry and rest data), lumped masses, surface.
#[derive(Debug)]
pub struct Body<'a> {
    /// The validated mesh.
    pub mesh: TetMesh<'a>,
    /// Lumped masses (kg), one per vertex.
    pub masses: Vec<f32>,
    /// Boundary triangles, outward.
    pub surface: Surface,
}

impl<'a> Body<'a> {
    /// Validates `geometry` into a mesh whose rest data lives in `rest` (resized to one entry
    /// per tetrahedron) and computes the masses at `density` (kg/m^3).
    pub fn new(
        geometry: &'a Geometry,
        rest: &'a mut Vec<TetRest>,
        density: f32,
    ) -> Result<Body<'a>, String> {
        rest.clear();
        rest.resize(geometry.tets.len(), TetRest::default());
        let mesh = TetMesh::new(&geometry.rest_positions, &geometry.tets, rest)
            .map_err(|e| format!("{}: {e}", geometry.source))?;
        let mut masses = vec![0.0; mesh.vertex_count()];
        mesh.lumped_masses(density, &mut masses)
            .map_err(|e| format!("{}: {e}", geometry.source))?;
        Ok(Body {
            mesh,
            masses,
            surface: Surface::of_tets(&geometry.tets),
        })
    }

    /// Total mass (kg), summed in f64: an f32 running sum over a million vertices is off by
    /// about 1 % (8.068 kg for 8 kg at `--resolution 100`).
    pub fn total_mass(&self) -> f64 {
        self.masses.iter().map(|&m| f64::from(m)).sum()
    }

    /// The centre of mass (m) of the body at `positions`, summed in f64.
    pub fn centre_of_mass(&self, positions: &[Vec3]) -> [f64; 3] {
        let mut moment = [0.0f64; 3];
        for (&m, p) in self.masses.iter().zip(positions) {
            for (sum, coordinate) in moment.iter_mut().zip(p.to_array()) {
                *sum += f64::from(m) * f64::from(coordinate);
            }
        }
        let mass = self.total_mass();
        moment.map(|sum| sum / mass)
    }

    /// The shortest edge of any tetrahedron at rest (m).
    pub fn shortest_edge(&self, rest_positions: &[Vec3]) -> f32 {
        const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
        self.mesh
            .tets()
            .iter()
            .flat_map(|tet| {
                EDGES.map(|(a, b)| {
                    rest_positions[tet[a] as usize].distance(rest_positions[tet[b] as usize])
                })
            })
            .fold(f32::INFINITY, f32::min)
    }

    /// Current over rest volume of every tetrahedron at `positions`, into `ratios`.
    pub fn volume_ratios(&self, positions: &[Vec3], ratios: &mut Vec<f32>) {
        ratios.clear();
        ratios.extend(
            self.mesh
                .tets()
                .iter()
                .zip(self.mesh.rest())
                .map(|(tet, rest)| {
                    let [x0, x1, x2, x3] = tet.map(|v| positions[v as usize]);
                    (x1 - x0).cross(x2 - x0).dot(x3 - x0) / 6.0 / rest.volume
                }),
        );
    }

    /// Kinetic, gravitational and elastic energy (J) of the state `(positions, velocities)`.
    pub fn energies(
        &self,
        material: &AnyMaterial,
        positions: &[Vec3],
        velocities: &[Vec3],
    ) -> Result<Energies, String> {
        let kinetic = self
            .masses
            .iter()
            .zip(velocities)
            .map(|(m, v)| 0.5 * m * v.length_squared())
            .sum();
        let potential = self
            .masses
            .iter()
            .zip(positions)
            .map(|(m, p)| -m * GRAVITY.dot(*p))
            .sum();
        let elastic = material.elastic_energy(&self.mesh, positions)?;
        Ok(Energies {
            kinetic,
            potential,
            elastic,
        })
    }
}

/// The energies of a state (J); the potential is zero on the ground plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Energies {
    /// `sum m v^2 / 2`.
    pub kinetic: f32,
    /// `sum m G z`.
    pub potential: f32,
    /// The material's strain energy.
    pub elastic: f32,
}

impl Energies {
    /// The sum of the three.
    pub fn total(&self) -> f32 {
        self.kinetic + self.potential + self.elastic
    }
}

/// The positions (m) and velocities (m/s) the stepper advances.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Vertex velocities.
    pub velocities: Vec<Vec3>,
}

impl State {
    /// The body at rest in its placed rest shape.
    pub fn at_rest(geometry: &Geometry) -> State {
        State {
            positions: geometry.rest_positions.clone(),
            velocities: vec![Vec3::ZERO; geometry.rest_positions.len()],
        }
    }
}

/// The time step (s) for `args`: `--dt` if given; otherwise, for the explicit stepper,
/// [`EXPLICIT_SAFETY_FRACTION`] of `stable_bound` (the stepper's stable time step, s), and for
/// the implicit steppers [`RELAX_DEFAULT_DT`].
pub fn time_step(args: &Args, stable_bound: Option<f32>) -> Result<f32, String> {
    match (args.dt, args.stepper, stable_bound) {
        (Some(dt), _, _) => Ok(dt),
        (None, Stepper::Relax | Stepper::Newton | Stepper::Vbd, _) => Ok(RELAX_DEFAULT_DT),
        (None, Stepper::Explicit, Some(bound)) if bound.is_finite() && bound > 0.0 => {
            Ok(EXPLICIT_SAFETY_FRACTION * bound)
        }
        (None, Stepper::Explicit, Some(bound)) => Err(format!(
            "the explicit stable time step is {bound} s; give --dt explicitly"
        )),
        (None, Stepper::Explicit, None) => Err(
            "the explicit default time step needs softfem::step's stable bound; give --dt".into(),
        ),
    }
}

/// What one step of the stepper reports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepInfo {
    /// The implicit solve of this step (relax, newton, vbd); `None` for explicit steps.
    pub solve: Option<SolveInfo>,
}

/// The report of one implicit solve.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveInfo {
    /// Descent iterations (Newton iterations, VBD sweeps).
    pub iterations: u32,
    /// Inner iterations: Newton's conjugate-gradient iterations; 0 for the other steppers.
    pub inner_iterations: u32,
    /// Backtracking line-search reductions, over all iterations.
    pub line_search_steps: u32,
    /// Final residual relative to the solver's scale, the larger of the first residual and
    /// the body's weight (as in `softfem::step::RelaxSettings::tolerance`).
    pub relative_residual: f32,
    /// Whether the residual reached the tolerance.
    pub converged: bool,
    /// Whether the solve counted as converged at the rounding floor, above the tolerance
    /// (Newton's `NewtonReport::stagnated`); false for the other steppers.
    pub at_floor: bool,
    /// Whether the solve stopped at a rounding floor at or above its initial residual (Newton,
    /// not converged): the precision cannot tell that step's start from its solution, so the
    /// solve cannot show it converged; false for the other steppers.
    pub within_floor: bool,
}

/// Solver statistics over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveTotals {
    /// Steps that reported a solve.
    pub solves: u64,
    /// Iterations over all solves.
    pub iterations: u64,
    /// The most iterations of one solve.
    pub max_iterations: u32,
    /// Inner (conjugate-gradient) iterations over all solves.
    pub inner_iterations: u64,
    /// Line-search reductions over all solves.
    pub line_search_steps: u64,
    /// Solves that did not converge (those in [`within_floor`](Self::within_floor) apart).
    pub not_converged: u64,
    /// Solves that stopped at a rounding floor at or above their initial residual.
    pub within_floor: u64,
    /// Solves that converged at the rounding floor, above the tolerance.
    pub at_floor: u64,
    /// The largest final relative residual.
    pub worst_residual: f32,
}

impl SolveTotals {
    fn add(&mut self, solve: &SolveInfo) {
        self.solves += 1;
        self.iterations += u64::from(solve.iterations);
        self.max_iterations = self.max_iterations.max(solve.iterations);
        self.inner_iterations += u64::from(solve.inner_iterations);
        self.line_search_steps += u64::from(solve.line_search_steps);
        self.not_converged += u64::from(!solve.converged && !solve.within_floor);
        self.within_floor += u64::from(!solve.converged && solve.within_floor);
        self.at_floor += u64::from(solve.converged && solve.at_floor);
        self.worst_residual = self.worst_residual.max(solve.relative_residual);
    }
}

/// How long to run and how often to emit output frames.
///
/// The output times are `k / frame_rate` for `k = 0, 1, 2, ...` and `duration` itself (when it
/// is not one of them): each span between two output times is split into the fewest equal
/// steps no longer than `dt`, so that every frame lands exactly on its time and the run ends
/// exactly at `duration`. A `dt` of several frame intervals is kept (rounded down to a whole
/// number of them) and a frame written after each step: every `m`-th frame time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunConfig {
    /// The longest time step (s).
    pub dt: f32,
    /// Simulated time (s).
    pub duration: f64,
    /// Output frames per simulated second (1/s).
    pub frame_rate: f64,
}

/// `ratio` rounded up to a whole number, except that a ratio within f32 rounding of a whole
/// number is that number (`0.1f32 / 0.01f32` is 10.0000002: 10 steps, not 11).
fn whole_steps(ratio: f64) -> u64 {
    let nearest = ratio.round();
    if (ratio - nearest).abs() <= 1e-5 * nearest.max(1.0) {
        nearest as u64
    } else {
        ratio.ceil() as u64
    }
}

impl RunConfig {
    /// Frame intervals per output interval: 1, or as many as fit in a longer `dt`.
    fn frames_per_output(&self) -> u64 {
        let ratio = f64::from(self.dt) * self.frame_rate;
        let nearest = ratio.round();
        let whole = if (ratio - nearest).abs() <= 1e-5 * nearest.max(1.0) {
            nearest
        } else {
            ratio.floor()
        };
        (whole as u64).max(1)
    }

    /// The time between output frames (s), the last one excepted.
    pub fn output_interval(&self) -> f64 {
        self.frames_per_output() as f64 / self.frame_rate
    }

    /// The output times after `t = 0` (s), in order, each with the number of equal steps that
    /// lead to it from the previous one.
    pub fn spans(&self) -> impl Iterator<Item = (f64, u64)> + '_ {
        let (duration, rate) = (self.duration, self.frame_rate);
        let every = self.frames_per_output();
        // The frames strictly before the end (one within f32 rounding of it is the end).
        let full_frames = whole_steps(duration * rate / every as f64).saturating_sub(1);
        let times = (1..=full_frames)
            .map(move |k| (k * every) as f64 / rate)
            .chain(std::iter::once(duration));
        let mut previous = 0.0;
        times.map(move |time| {
            let steps = whole_steps((time - previous) / f64::from(self.dt)).max(1);
            previous = time;
            (time, steps)
        })
    }

    /// The number of steps the run takes.
    pub fn step_count(&self) -> u64 {
        self.spans().map(|(_, steps)| steps).sum()
    }

    /// The number of output frames, the one at `t = 0` included (`1 + spans().count()`).
    pub fn frame_count(&self) -> u64 {
        let every = self.frames_per_output() as f64;
        2 + whole_steps(self.duration * self.frame_rate / every).saturating_sub(1)
    }
}

/// A state handed to the frame writer.
#[derive(Clone, Copy, Debug)]
pub struct FrameView<'a> {
    /// Output frame number, from 0.
    pub index: usize,
    /// Steps taken so far.
    pub step: u64,
    /// Simulated time (s).
    pub time: f64,
    /// Positions (m).
    pub positions: &'a [Vec3],
    /// Velocities (m/s).
    pub velocities: &'a [Vec3],
}

/// What a completed run did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunStats {
    /// Steps taken.
    pub steps: u64,
    /// Simulated time reached (s).
    pub simulated: f64,
    /// Wall-clock time of the loop, output included.
    pub wall: Duration,
    /// Frames emitted.
    pub frames: usize,
    /// Statistics of the implicit solves (all zero for explicit steps).
    pub solves: SolveTotals,
}

/// Why a run stopped early.
#[derive(Clone, Debug, PartialEq)]
pub enum RunError {
    /// The stepper refused a step (blow-up, bad parameters...). The state is the one before
    /// that step.
    Step {
        /// Steps completed before the failing one.
        step: u64,
        /// Simulated time of the state (s).
        time: f64,
        /// The stepper's message.
        message: String,
        /// Statistics up to the failure (boxed: they would make every `Result` large).
        stats: Box<RunStats>,
    },
    /// Writing a frame failed.
    Output(String),
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RunError::Step {
                step,
                time,
                message,
                ..
            } => write!(f, "step {} (t = {time:.4} s) failed: {message}", step + 1),
            RunError::Output(message) => write!(f, "writing output: {message}"),
        }
    }
}

/// Advances `state` through the output times of `config` ([`RunConfig::spans`]), calling
/// `step(positions, velocities, h)` for every step of length `h` and `on_frame` at `t = 0` and
/// at every output time, and updating `progress` after every step.
///
/// `step` is the stepper: it advances the state by `h` in place (gravity, elasticity, ground
/// and all) and returns what it did, or an error message, in which case it must leave the
/// state as it was (as `softfem::step` guarantees) and the run stops with [`RunError::Step`].
pub fn run<S, F>(
    state: &mut State,
    config: &RunConfig,
    progress: &mut Progress,
    mut step: S,
    mut on_frame: F,
) -> Result<RunStats, RunError>
where
    S: FnMut(&mut [Vec3], &mut [Vec3], f32) -> Result<StepInfo, String>,
    F: FnMut(&FrameView<'_>) -> Result<(), String>,
{
    let started = Instant::now();
    let total_steps = config.step_count();
    let mut stats = RunStats {
        steps: 0,
        simulated: 0.0,
        wall: Duration::ZERO,
        frames: 0,
        solves: SolveTotals::default(),
    };
    let mut emit = |state: &State, stats: &mut RunStats| {
        let frame = FrameView {
            index: stats.frames,
            step: stats.steps,
            time: stats.simulated,
            positions: &state.positions,
            velocities: &state.velocities,
        };
        stats.frames += 1;
        on_frame(&frame).map_err(RunError::Output)
    };
    emit(state, &mut stats)?;
    let mut span_start = 0.0;
    for (frame_time, steps) in config.spans() {
        let h = (frame_time - span_start) / steps as f64;
        for j in 1..=steps {
            match step(&mut state.positions, &mut state.velocities, h as f32) {
                Ok(info) => {
                    if let Some(solve) = &info.solve {
                        stats.solves.add(solve);
                    }
                }
                Err(message) => {
                    progress.finish();
                    stats.wall = started.elapsed();
                    return Err(RunError::Step {
                        step: stats.steps,
                        time: stats.simulated,
                        message,
                        stats: Box::new(stats),
                    });
                }
            }
            stats.steps += 1;
            // The span's end time itself on its last step, so that frames land exactly.
            stats.simulated = if j == steps {
                frame_time
            } else {
                span_start + j as f64 * h
            };
            progress.update(stats.steps, total_steps);
        }
        emit(state, &mut stats)?;
        span_start = frame_time;
    }
    progress.finish();
    stats.wall = started.elapsed();
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    fn args(flags: &[&str]) -> Args {
        Args::try_parse_from(std::iter::once("bouncy").chain(flags.iter().copied())).unwrap()
    }

    /// Test-only stand-in for a stepper: free fall under gravity with no ground and no
    /// elasticity (symplectic Euler). It exists to exercise the loop, not to simulate anything.
    fn free_fall(
        positions: &mut [Vec3],
        velocities: &mut [Vec3],
        dt: f32,
    ) -> Result<StepInfo, String> {
        for (x, v) in positions.iter_mut().zip(velocities.iter_mut()) {
            *v += dt * GRAVITY;
            *x += dt * *v;
        }
        Ok(StepInfo::default())
    }

    #[test]
    fn jelly_cube_sits_centred_at_the_drop_height() {
        let geometry = Geometry::from_args(&args(&[])).unwrap();
        assert_eq!(geometry.rest_positions.len(), 7 * 7 * 7);
        assert_eq!(geometry.tets.len(), 6 * 6 * 6 * 5);
        let (min, max) = bounds(&geometry.rest_positions);
        assert!((min.z - 0.5).abs() < 1e-6 && (max.z - 0.7).abs() < 1e-6);
        assert!((min.x + max.x).abs() < 1e-6 && (min.y + max.y).abs() < 1e-6);
        assert!((max.x - min.x - 0.2).abs() < 1e-6);
    }

    #[test]
    fn body_has_the_mass_of_the_cube_and_a_closed_surface() {
        let geometry = Geometry::from_args(&args(&["--resolution", "3"])).unwrap();
        let mut rest = Vec::new();
        let body = Body::new(&geometry, &mut rest, 1000.0).unwrap();
        // 0.2^3 m^3 of water-dense jelly; f32 sums of 135 volumes: 1e-5 relative is loose.
        assert!((body.total_mass() - 8.0).abs() < 8.0 * 1e-5);
        // The cube is centred on the z axis with its base at the drop height 0.5 m.
        let [x, y, z] = body.centre_of_mass(&geometry.rest_positions);
        assert!(x.abs() < 1e-6 && y.abs() < 1e-6 && (z - 0.6).abs() < 1e-6);
        assert_eq!(body.surface.len(), 2 * 9 * 6);
        assert!((body.shortest_edge(&geometry.rest_positions) - 0.2 / 3.0).abs() < 1e-6);
        let mut ratios = Vec::new();
        body.volume_ratios(&geometry.rest_positions, &mut ratios);
        assert!(ratios.iter().all(|r| (r - 1.0).abs() < 1e-4));
    }

    #[test]
    fn energies_at_rest_and_under_a_rigid_drop() {
        let geometry = Geometry::from_args(&args(&["--resolution", "2"])).unwrap();
        let mut rest = Vec::new();
        let body = Body::new(&geometry, &mut rest, 1000.0).unwrap();
        let material = AnyMaterial::new(Model::StableNeoHookean, 5e4, 0.45).unwrap();
        let state = State::at_rest(&geometry);
        let energies = body
            .energies(&material, &state.positions, &state.velocities)
            .unwrap();
        assert_eq!(energies.kinetic, 0.0);
        assert!(energies.elastic.abs() < 1e-6);
        // m g z_centre = 8 kg * 9.81 * 0.6 m.
        assert!(
            (energies.potential - 8.0 * G * 0.6).abs() < 1e-3,
            "{energies:?}"
        );
    }

    #[test]
    fn tetgen_mesh_is_read_oriented_and_placed() {
        let node = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/meshes/cube.node");
        let geometry = Geometry::from_tetgen(&node)
            .unwrap()
            .placed_above_ground(1.0);
        assert_eq!(
            (geometry.rest_positions.len(), geometry.tets.len()),
            (27, 48)
        );
        let mut rest = Vec::new();
        Body::new(&geometry, &mut rest, 500.0).unwrap();
        let (min, _) = bounds(&geometry.rest_positions);
        assert!((min.z - 1.0).abs() < 1e-6);
    }

    #[test]
    fn tetgen_mesh_with_inverted_tets_and_unused_vertices_is_repaired() {
        let dir = std::env::temp_dir().join(format!("bouncy-scene-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let node = dir.join("flipped.node");
        // Point 2 is used by no tetrahedron; the tetrahedron is left-handed.
        std::fs::write(
            &node,
            "5 3 0 0\n1 0 0 0\n2 9 9 9\n3 0 1 0\n4 1 0 0\n5 0 0 1\n",
        )
        .unwrap();
        std::fs::write(dir.join("flipped.ele"), "1 4 0\n1 1 3 4 5\n").unwrap();
        let geometry = Geometry::from_tetgen(&node).unwrap();
        assert_eq!((geometry.reoriented, geometry.dropped_vertices), (1, 1));
        assert_eq!(geometry.rest_positions.len(), 4);
        let mut rest = Vec::new();
        assert!(Body::new(&geometry, &mut rest, 1000.0).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_mesh_paths_give_readable_errors() {
        let missing = Geometry::from_tetgen(Path::new("no/such/mesh.node")).unwrap_err();
        assert!(
            missing.contains("cannot read no/such/mesh.node"),
            "{missing}"
        );
        let wrong = Geometry::from_tetgen(Path::new("mesh.obj")).unwrap_err();
        assert!(wrong.contains("expected a TetGen .node file"), "{wrong}");
    }

    #[test]
    fn default_time_steps() {
        for stepper in ["relax", "newton", "vbd"] {
            assert_eq!(
                time_step(&args(&["--stepper", stepper]), None),
                Ok(RELAX_DEFAULT_DT)
            );
        }
        assert_eq!(time_step(&args(&["--dt", "0.002"]), None), Ok(0.002));
        assert_eq!(time_step(&args(&[]), Some(0.004)), Ok(0.002));
        assert!(time_step(&args(&[]), None).unwrap_err().contains("--dt"));
    }

    #[test]
    fn run_emits_frames_on_schedule_and_steps_the_state() {
        let geometry = Geometry::jelly_cube(0.2, 1, BoxSplit::Kuhn6)
            .unwrap()
            .placed_above_ground(0.5);
        let mut state = State::at_rest(&geometry);
        let config = RunConfig {
            dt: 0.01,
            duration: 1.0,
            frame_rate: 10.0,
        };
        assert_eq!((config.step_count(), config.frame_count()), (100, 11));
        // 0.1 s between frames in steps of at most 0.03 s: 4 steps of 0.025 s each.
        let odd = RunConfig { dt: 0.03, ..config };
        assert_eq!(odd.step_count(), 40);
        // A duration between frame times ends with a shorter span: 10 x 10 steps, then 5.
        let longer = RunConfig {
            duration: 1.05,
            ..config
        };
        assert_eq!((longer.step_count(), longer.frame_count()), (105, 12));
        let times: Vec<f64> = longer.spans().map(|(time, _)| time).collect();
        assert_eq!((times[0], times[9], times[10]), (0.1, 1.0, 1.05));
        // A step of three frame intervals is kept: frames at 0.3, 0.6, 0.9 and the end.
        let coarse = RunConfig { dt: 0.3, ..config };
        let spans: Vec<(f64, u64)> = coarse.spans().collect();
        assert_eq!(spans, [(0.3, 1), (0.6, 1), (0.9, 1), (1.0, 1)]);
        assert_eq!(coarse.frame_count(), 5);
        let mut times = Vec::new();
        let stats = run(
            &mut state,
            &config,
            &mut Progress::hidden(),
            free_fall,
            |frame| {
                times.push((frame.index, frame.step, frame.time));
                Ok(())
            },
        )
        .unwrap();
        assert_eq!((stats.steps, stats.frames), (100, 11));
        // Frames at exactly k / 10 s (the f64 quotient), the last at exactly the duration.
        assert_eq!(stats.simulated, 1.0);
        for (i, &(index, step, time)) in times.iter().enumerate() {
            assert_eq!((index, step, time), (i, 10 * i as u64, i as f64 / 10.0));
        }
        // Symplectic Euler free fall after n steps: v = -g n h, z drop = g h^2 n (n + 1) / 2.
        let drop = G * 0.01 * 0.01 * 100.0 * 101.0 / 2.0;
        assert!((state.positions[0].z - (0.5 - drop)).abs() < 1e-4);
        assert!((state.velocities[0].z + G).abs() < 1e-4);
    }

    #[test]
    fn run_ends_with_a_frame_and_stops_on_a_step_error() {
        let geometry = Geometry::jelly_cube(0.2, 1, BoxSplit::Kuhn6).unwrap();
        let mut state = State::at_rest(&geometry);
        let config = RunConfig {
            dt: 0.3,
            duration: 1.0,
            frame_rate: 2.0,
        };
        let mut frames = Vec::new();
        let mut step_lengths = Vec::new();
        let stats = run(
            &mut state,
            &config,
            &mut Progress::hidden(),
            |x, v, h| {
                step_lengths.push(h);
                free_fall(x, v, h)
            },
            |f| {
                frames.push((f.step, f.time));
                Ok(())
            },
        )
        .unwrap();
        // 0.5 s between frames, steps of at most 0.3 s: two steps of 0.25 s per frame, the
        // last frame at the duration, not one step past it.
        assert_eq!(frames, [(0, 0.0), (2, 0.5), (4, 1.0)]);
        assert_eq!(step_lengths, [0.25; 4]);
        assert_eq!((stats.steps, stats.simulated), (4, 1.0));

        let before = State::at_rest(&geometry);
        let mut state = before.clone();
        let mut calls = 0;
        let failing = |_: &mut [Vec3], _: &mut [Vec3], _: f32| {
            calls += 1;
            if calls == 3 {
                Err("energy grew 1e6-fold".to_string())
            } else {
                Ok(StepInfo::default())
            }
        };
        let error = run(
            &mut state,
            &config,
            &mut Progress::hidden(),
            failing,
            |_| Ok(()),
        )
        .unwrap_err();
        assert_eq!(
            error.to_string(),
            "step 3 (t = 0.5000 s) failed: energy grew 1e6-fold"
        );
        assert_eq!(state, before);
    }

    #[test]
    fn solve_reports_are_totalled() {
        let geometry = Geometry::jelly_cube(0.2, 1, BoxSplit::Kuhn6).unwrap();
        let mut state = State::at_rest(&geometry);
        let config = RunConfig {
            dt: 0.1,
            duration: 0.4,
            frame_rate: 1.0,
        };
        let mut n = 0;
        let relax_like = |_: &mut [Vec3], _: &mut [Vec3], _: f32| {
            n += 1;
            Ok(StepInfo {
                solve: Some(SolveInfo {
                    iterations: 10 * n,
                    inner_iterations: 100 * n,
                    line_search_steps: 1,
                    relative_residual: 1e-3 * n as f32,
                    converged: n != 2 && n != 4,
                    at_floor: n >= 2,
                    within_floor: n == 4,
                }),
            })
        };
        let stats = run(
            &mut state,
            &config,
            &mut Progress::hidden(),
            relax_like,
            |_| Ok(()),
        )
        .unwrap();
        let totals = stats.solves;
        assert_eq!(
            (totals.solves, totals.iterations, totals.max_iterations),
            (4, 100, 40)
        );
        assert_eq!((totals.line_search_steps, totals.not_converged), (4, 1));
        assert_eq!((totals.inner_iterations, totals.at_floor), (1000, 1));
        assert_eq!(totals.within_floor, 1);
        assert!((totals.worst_residual - 4e-3).abs() < 1e-9);
    }
}

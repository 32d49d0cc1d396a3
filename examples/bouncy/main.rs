//! `cargo run --release -p softfem-examples --bin bouncy`: a soft jelly cube (or any TetGen mesh,
//! `--mesh`) dropped onto the ground, bouncing and settling.
//!
//! Builds the scene from the flags, validates the mesh and material, steps it with
//! `softfem::step` (explicit symplectic Euler at half the computed stable time step, or implicit
//! Euler solved by preconditioned gradient descent, Newton's method or Vertex Block Descent),
//! and writes VTK frames (ParaView), a filmstrip SVG and
//! a summary. Bad flags or a bad mesh give a readable error and a non-zero exit status; so do
//! implicit solves that did not converge (after the output is written). Before building the
//! body and before the first step it prints an estimate of memory, output and wall time, and
//! refuses a run above the limits of [`estimate::LIMITS`] unless `--yes` is given.

mod cli;
mod console;
mod estimate;
mod filmstrip;
mod progress;
mod scene;
mod surface;
mod vtk;

use std::io::Write;
use std::process::ExitCode;

use clap::Parser;

use cli::{Args, Model, Stepper, VtkContent};
use console::Console;
use estimate::{Estimate, MeshSize};
use filmstrip::{Camera, Filmstrip, Recorder};
use progress::{Progress, Summary};
use scene::{
    AnyMaterial, Body, FrameView, Geometry, RunConfig, RunStats, SolveInfo, SolveTotals, State,
    StepInfo,
};
use softfem::element::{TetHessian, TetRest};
use softfem::glam::{Mat3, Vec3};
use softfem::material::Material;
use softfem::step::{
    ExplicitScratch, ExplicitSettings, HalfSpace, NewtonScratch, NewtonSettings, RelaxScratch,
    RelaxSettings, Scene, TetElastic, VbdScratch, VbdSettings, explicit_step, newton_step,
    relax_step, scratch_len, stable_time_step, vbd_step,
};

/// Mass-proportional damping (1/s) of the explicit stepper: a little, so the wobble settles
/// within the default three seconds the way real jelly does.
const DAMPING: f32 = 0.5;
/// Coulomb friction coefficient of the ground.
const FRICTION: f32 = 0.6;
/// The relative tolerance of the Newton and VBD solves: the relaxation's default, measured on
/// this scene (see `RelaxSettings::new`), so that the three implicit steppers solve to the
/// same residual and their iteration counts and wall times compare.
const TOLERANCE: f32 = 2e-3;
/// Newton's budgets: Newton iterations per step and CG iterations per Newton iteration.
const NEWTON_BUDGET: (u32, u32) = (30, 200);
/// VBD's budget of sweeps per step.
const VBD_BUDGET: u32 = 300;
/// VBD's Chebyshev `rho` and the plain sweeps before it (`VbdSettings::with_chebyshev`):
/// measured over this scene's 180 steps (f32, tolerance 2e-3, no line search), 4.5 sweeps a
/// step on average (at most 39) against 6.6 (at most 125) with the `rho` the solver estimates
/// from 4 plain sweeps, 4.2 and 6.6 with 0.96 and 0.9; and on both scenes of the descent chart
/// 0.95 after 2 plain sweeps took 41 and 31 sweeps where the estimate took 111 and 81.
const VBD_CHEBYSHEV: (f32, u32) = (0.95, 2);

fn main() -> ExitCode {
    let args = Args::parse(); // bad flags: clap prints the reason and exits with status 2
    match bouncy(&args, &mut Console::stdout()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn bouncy(args: &Args, console: &mut Console<impl Write>) -> Result<(), String> {
    let material = AnyMaterial::new(args.model, args.young_modulus, args.poisson_ratio)?;
    if args.mesh.is_none() {
        // Refuse a huge cube before building it (a TetGen mesh is checked once read).
        let size = MeshSize::jelly_cube(args.resolution as usize, args.split.box_split())?;
        Estimate::new(args, size, frame_count(args), None).check(args.yes, "")?;
    }
    let geometry = Geometry::from_args(args)?;
    let mut rest = Vec::<TetRest>::new();
    let body = Body::new(&geometry, &mut rest, args.density)?;
    let state = State::at_rest(&geometry);

    console.line(format_args!(
        "body      {}: {} vertices, {} tetrahedra, {} surface triangles",
        geometry.source,
        body.mesh.vertex_count(),
        body.mesh.element_count(),
        body.surface.len()
    ));
    if geometry.reoriented > 0 || geometry.dropped_vertices > 0 {
        console.line(format_args!(
            "          {} tetrahedra reoriented, {} unused vertices dropped",
            geometry.reoriented, geometry.dropped_vertices
        ));
    }
    console.line(format_args!(
        "material  {}, E = {} Pa, nu = {}, density {} kg/m^3, mass {:.3} kg",
        args.model,
        args.young_modulus,
        args.poisson_ratio,
        args.density,
        body.total_mass()
    ));
    let h_min = body.shortest_edge(&geometry.rest_positions);
    console.line(format_args!(
        "          shortest edge {h_min:.4} m, wave speed {:.1} m/s",
        material.wave_speed(args.density)
    ));
    console.line(format_args!(
        "drop      lowest point {} m above the ground, {} s simulated",
        args.drop_height, args.duration
    ));

    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let mut writer = FrameWriter::new(args, &body);
    let mut recorder = Recorder::new(args.panels as usize, args.duration, 1.0 / args.frame_rate);
    let mut state = state;
    let initial_energies = body.energies(&material, &state.positions, &state.velocities)?;
    let initial_centre = body.centre_of_mass(&state.positions);
    let outcome = match material {
        AnyMaterial::StVK(m) => simulate(
            args,
            &body,
            m,
            &mut state,
            &mut writer,
            &mut recorder,
            console,
        ),
        AnyMaterial::NeoHookean(m) => simulate(
            args,
            &body,
            m,
            &mut state,
            &mut writer,
            &mut recorder,
            console,
        ),
        AnyMaterial::StableNeoHookean(m) => simulate(
            args,
            &body,
            m,
            &mut state,
            &mut writer,
            &mut recorder,
            console,
        ),
    };
    let stats = match outcome {
        Ok(stats) => stats,
        // Refused before the first step: nothing was written.
        Err(Failure::Refused(message)) => return Err(message),
        Err(Failure::Run(message)) => {
            // The frames so far and the filmstrip are written, so that a failed run can still
            // be looked at.
            let stale = writer.finish()?;
            write_filmstrip(args, &geometry, &body, &recorder)?;
            console.line(format_args!(
                "wrote     {} VTK frames and {} up to the failure{}",
                writer.written.len(),
                args.out.join("filmstrip.svg").display(),
                removed_note(stale)
            ));
            return Err(message);
        }
    };
    let stale = writer.finish()?;
    write_filmstrip(args, &geometry, &body, &recorder)?;

    let mut ratios = Vec::new();
    body.volume_ratios(&state.positions, &mut ratios);
    let summary = Summary {
        simulated: stats.simulated,
        wall: stats.wall,
        steps: stats.steps,
        volume_ratio: progress::min_max(&ratios),
        inverted: ratios.iter().filter(|&&ratio| ratio <= 0.0).count(),
        tets: ratios.len(),
        energies: body.energies(&material, &state.positions, &state.velocities)?,
        initial_energies,
        solves: stats.solves,
        iteration_name: match args.stepper {
            Stepper::Newton => "Newton iterations",
            Stepper::Vbd => "sweeps",
            Stepper::Explicit | Stepper::Relax => "iterations",
        },
        centre_shift: {
            let end = body.centre_of_mass(&state.positions);
            [0, 1, 2].map(|axis| end[axis] - initial_centre[axis])
        },
    };
    for line in summary.lines() {
        console.line(line);
    }
    if writer.written.is_empty() {
        console.line(format_args!(
            "wrote     no VTK frames (--vtk-every 0) and {}{}",
            args.out.join("filmstrip.svg").display(),
            removed_note(stale)
        ));
    } else {
        console.line(format_args!(
            "wrote     {} VTK frames ({} ..., series in {}) and {}{}",
            writer.written.len(),
            args.out.join(&writer.written[0].0).display(),
            args.out.join("frames.vtk.series").display(),
            args.out.join("filmstrip.svg").display(),
            removed_note(stale)
        ));
    }
    if let Some(warning) = inversion_warning(args.model, summary.inverted, summary.tets) {
        eprintln!("warning: {warning}");
    }
    solves_verdict(&stats.solves)
}

/// The number of output frames of the run `args` describe (the one at `t = 0` included).
fn frame_count(args: &Args) -> u64 {
    let config = RunConfig {
        // Only a step longer than the frame interval changes the frame times; the default
        // steps are shorter.
        dt: args.dt.unwrap_or(f32::MIN_POSITIVE),
        duration: args.duration,
        frame_rate: args.frame_rate,
    };
    config.frame_count()
}

/// "; removed 30 stale frame files of an earlier run", or nothing.
fn removed_note(stale: usize) -> String {
    match stale {
        0 => String::new(),
        n => format!("; removed {n} frame files of an earlier run"),
    }
}

/// The warning for a run that ends with `inverted` of its `tets` tetrahedra inside out.
fn inversion_warning(model: Model, inverted: usize, tets: usize) -> Option<String> {
    if inverted == 0 {
        return None;
    }
    let why = match model {
        Model::StVK => {
            "StVK softens under strong compression and has no barrier against inversion; \
             --model stable-neo-hookean or neo-hookean keep elements right side out"
        }
        Model::NeoHookean | Model::StableNeoHookean => {
            "the time step or the material let elements collapse; try a smaller --dt"
        }
    };
    Some(format!(
        "{inverted} of {tets} tetrahedra end inverted (volume ratio <= 0): {why}"
    ))
}

/// `Ok` when every implicit solve converged; otherwise the error that makes the exit status
/// non-zero: the run's output is written, but its motion is not the implicit Euler solution.
fn solves_verdict(solves: &SolveTotals) -> Result<(), String> {
    match solves.not_converged {
        0 => Ok(()),
        failed => Err(format!(
            "{failed} of {} implicit solves did not converge (worst final relative residual \
             {:.2e}); the output is written, but those steps are not solved: try a smaller --dt",
            solves.solves, solves.worst_residual
        )),
    }
}

/// Why [`simulate`] stopped.
#[derive(Debug)]
enum Failure {
    /// The estimate exceeds the limits (and `--yes` was not given); nothing ran.
    Refused(String),
    /// A step or the output failed part-way.
    Run(String),
}

/// Runs the scene with the concrete material `M`: picks the time step, prints the estimate
/// (and refuses a run above the limits without `--yes`), builds the stepper's scratch space,
/// and drives [`scene::run`], writing frames as it goes. Returns the run's statistics.
fn simulate<M: Material>(
    args: &Args,
    body: &Body<'_>,
    material: M,
    state: &mut State,
    writer: &mut FrameWriter<'_>,
    recorder: &mut Recorder,
    console: &mut Console<impl Write>,
) -> Result<RunStats, Failure> {
    let model = TetElastic::new(body.mesh, material);
    let n = body.mesh.vertex_count();
    let mut stiffness = vec![0.0; n];
    let bound = stable_time_step(&model, &body.masses, &[], &mut stiffness)
        .map_err(|e| Failure::Refused(format!("stable time step: {e}")))?;
    let dt = scene::time_step(args, Some(bound)).map_err(Failure::Refused)?;
    let config = RunConfig {
        dt,
        duration: args.duration,
        frame_rate: args.frame_rate,
    };
    recorder.set_frame_interval(config.output_interval());
    let (steps, first_span) = (config.step_count(), config.spans().next());
    let step = first_span.map_or(f64::from(dt), |(time, steps)| time / steps as f64);
    console.line(format_args!(
        "stepper   {}, {steps} steps of {step:.3e} s (at most {dt:.3e} s; explicit stable \
         bound {bound:.3e} s)",
        args.stepper
    ));
    let size = MeshSize {
        vertices: n,
        tets: body.mesh.element_count(),
        surface_triangles: body.surface.len(),
    };
    let estimate = Estimate::new(args, size, config.frame_count(), Some(steps));
    console.line(format_args!("estimate  {}", estimate.describe()));
    let hint = match args.stepper {
        Stepper::Explicit if args.dt.is_none() => format!(
            " (the explicit step is {} of the stable bound, which shrinks with the mesh size \
             and as nu nears 0.5; --stepper relax, newton or vbd take 1/60 s steps)",
            scene::EXPLICIT_SAFETY_FRACTION
        ),
        _ => String::new(),
    };
    estimate.check(args.yes, &hint).map_err(Failure::Refused)?;
    let ground = HalfSpace::new(Vec3::Z, 0.0).with_friction(FRICTION);
    let ground = match args.sticking_speed {
        Some(speed) => ground.with_sticking_speed(speed),
        None => ground,
    };
    let scene = Scene::new(dt)
        .with_gravity(scene::GRAVITY)
        .with_ground(ground);
    // The implicit solvers' common scale for their tolerance: max(|grad Phi(x_0)|, |M g|) (N).
    let weight = body
        .masses
        .iter()
        .map(|m| (m * scene::G).powi(2))
        .sum::<f32>()
        .sqrt();
    let mut progress = Progress::new(args.quiet);
    let on_frame = |frame: &FrameView<'_>| {
        writer.write(frame)?;
        recorder.offer(frame.time, frame.positions);
        Ok(())
    };
    let stats = match args.stepper {
        Stepper::Explicit => {
            let settings = ExplicitSettings::new().with_damping(DAMPING);
            let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
            let mut scratch = ExplicitScratch::new(&mut buffer);
            scene::run(
                state,
                &config,
                &mut progress,
                |x, v, h| {
                    let scene = Scene { dt: h, ..scene };
                    explicit_step(
                        &model,
                        &body.masses,
                        &[],
                        &scene,
                        &settings,
                        x,
                        v,
                        &mut scratch,
                    )
                    .map(|_| StepInfo::default())
                    .map_err(|e| e.to_string())
                },
                on_frame,
            )
        }
        Stepper::Relax => {
            // The default solver settings (tolerance 2e-3 of the load, Chebyshev acceleration)
            // are the ones measured on this scene: see `RelaxSettings::new`.
            let settings = RelaxSettings::new();
            console.line(format_args!(
                "solver    gradient descent, P = diagonal bound, step {}, Chebyshev rho {}; \
                 tolerance {:.0e} of the load, at most {} iterations",
                settings.options.step_length,
                settings.options.chebyshev,
                settings.tolerance,
                settings.max_iterations
            ));
            let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
            let mut scalars = vec![0.0; n];
            let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
            scene::run(
                state,
                &config,
                &mut progress,
                |x, v, h| {
                    let scene = Scene { dt: h, ..scene };
                    relax_step(
                        &model,
                        &body.masses,
                        &[],
                        &scene,
                        &settings,
                        x,
                        v,
                        &mut scratch,
                    )
                    .map(|report| StepInfo {
                        solve: Some(SolveInfo {
                            iterations: report.iterations,
                            inner_iterations: 0,
                            line_search_steps: report.backtracks,
                            relative_residual: report.residual
                                / report.initial_residual.max(weight),
                            converged: report.converged,
                            at_floor: false,
                            within_floor: false,
                        }),
                    })
                    .map_err(|e| e.to_string())
                },
                on_frame,
            )
        }
        Stepper::Newton => {
            let settings = NewtonSettings::new()
                .with_tolerance(TOLERANCE, NEWTON_BUDGET.0)
                .with_cg_iterations(NEWTON_BUDGET.1);
            console.line(format_args!(
                "solver    Newton, P = projected Hessian, block-Jacobi CG; tolerance {:.0e} of \
                 the load (or the rounding floor), at most {} Newton and {} CG iterations each",
                settings.tolerance, settings.max_iterations, settings.options.max_cg_iterations
            ));
            let len = scratch_len::newton(n, body.mesh.element_count());
            let mut vectors = vec![Vec3::ZERO; len.vectors];
            let mut blocks = vec![Mat3::ZERO; len.blocks];
            let mut hessians = vec![TetHessian::default(); len.hessians];
            let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
            scene::run(
                state,
                &config,
                &mut progress,
                |x, v, h| {
                    let scene = Scene { dt: h, ..scene };
                    newton_step(
                        &model,
                        &body.masses,
                        &[],
                        &scene,
                        &settings,
                        x,
                        v,
                        &mut scratch,
                    )
                    .map(|report| StepInfo {
                        solve: Some(SolveInfo {
                            iterations: report.iterations,
                            inner_iterations: report.details.cg_iterations,
                            line_search_steps: report.backtracks,
                            relative_residual: report.residual
                                / report.initial_residual.max(weight),
                            converged: report.converged,
                            at_floor: report.stagnated && report.residual > report.target,
                            within_floor: !report.converged
                                && report.stagnated
                                && report.rounding_floor >= report.initial_residual,
                        }),
                    })
                    .map_err(|e| e.to_string())
                },
                on_frame,
            )
        }
        Stepper::Vbd => {
            // No per-vertex line search (the blocks of this soft cube are well behaved, and
            // it saves two energy densities per element and corner), Chebyshev with a fixed
            // rho: the faster variants measured (see `VBD_CHEBYSHEV`).
            let settings = VbdSettings::new()
                .with_tolerance(TOLERANCE, VBD_BUDGET)
                .with_line_search(0)
                .with_chebyshev(VBD_CHEBYSHEV.0, VBD_CHEBYSHEV.1);
            console.line(format_args!(
                "solver    Vertex Block Descent, no line search, Chebyshev rho {} after {} \
                 plain sweeps; tolerance {:.0e} of the load, at most {} sweeps",
                settings.options.chebyshev,
                settings.options.chebyshev_delay,
                settings.tolerance,
                settings.max_iterations
            ));
            let elements = body.mesh.element_count();
            let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(n)];
            let mut indices = vec![0; scratch_len::vbd_indices(n, elements)];
            // The packed sweep layout: the same steps, cheaper sweeps.
            let mut values = vec![0.0; scratch_len::vbd_layout(elements)];
            let mut corners = vec![0; scratch_len::vbd_layout_corners(n, elements)];
            let mut scratch =
                VbdScratch::new(&mut vectors, &mut indices).with_layout(&mut values, &mut corners);
            scene::run(
                state,
                &config,
                &mut progress,
                |x, v, h| {
                    let scene = Scene { dt: h, ..scene };
                    vbd_step(
                        &model,
                        &body.masses,
                        &[],
                        &scene,
                        &settings,
                        x,
                        v,
                        &mut scratch,
                    )
                    .map(|report| StepInfo {
                        solve: Some(SolveInfo {
                            iterations: report.iterations,
                            inner_iterations: 0,
                            line_search_steps: report.details.vertex_backtracks,
                            relative_residual: report.residual
                                / report.initial_residual.max(weight),
                            converged: report.converged,
                            at_floor: false,
                            within_floor: false,
                        }),
                    })
                    .map_err(|e| e.to_string())
                },
                on_frame,
            )
        }
    };
    stats.map_err(|e| Failure::Run(e.to_string()))
}

/// Writes the VTK frames (every `--vtk-every`-th output frame) and, at the end, the series file.
struct FrameWriter<'a> {
    args: &'a Args,
    body: &'a Body<'a>,
    written: Vec<(String, f64)>,
    ratios: Vec<f32>,
    surface_ratios: Vec<f32>,
}

impl<'a> FrameWriter<'a> {
    fn new(args: &'a Args, body: &'a Body<'a>) -> Self {
        FrameWriter {
            args,
            body,
            written: Vec::new(),
            ratios: Vec::new(),
            surface_ratios: Vec::new(),
        }
    }

    fn write(&mut self, frame: &FrameView<'_>) -> Result<(), String> {
        let every = self.args.vtk_every as usize;
        if every == 0 || !frame.index.is_multiple_of(every) {
            return Ok(());
        }
        self.body.volume_ratios(frame.positions, &mut self.ratios);
        let (cells, volume_ratios) = match self.args.vtk {
            VtkContent::Volume => (vtk::Cells::Tets(self.body.mesh.tets()), &self.ratios),
            VtkContent::Surface => {
                self.surface_ratios.clear();
                let owners = &self.body.surface.owners;
                self.surface_ratios
                    .extend(owners.iter().map(|&tet| self.ratios[tet as usize]));
                (
                    vtk::Cells::Triangles(&self.body.surface.triangles),
                    &self.surface_ratios,
                )
            }
        };
        let name = vtk::frame_file_name(self.written.len());
        let path = self.args.out.join(&name);
        let title = format!(
            "softfem bouncy, frame {}, step {}, t = {} s",
            frame.index, frame.step, frame.time
        );
        vtk::write_frame_file(
            &path,
            &vtk::Frame {
                title: &title,
                time: frame.time,
                positions: frame.positions,
                velocities: frame.velocities,
                cells,
                volume_ratios,
            },
        )
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        self.written.push((name, frame.time));
        Ok(())
    }

    /// Writes the series file of the frames written (removing a stale one if there are
    /// none) and removes frame files of an earlier run that this one did not write; returns
    /// how many were removed.
    fn finish(&self) -> Result<usize, String> {
        let out = &self.args.out;
        let series = out.join("frames.vtk.series");
        if self.written.is_empty() {
            if series.is_file() {
                std::fs::remove_file(&series)
                    .map_err(|e| format!("cannot remove {}: {e}", series.display()))?;
            }
        } else {
            vtk::write_series_file(&series, &self.written)
                .map_err(|e| format!("cannot write {}: {e}", series.display()))?;
        }
        let keep: Vec<&str> = self.written.iter().map(|(name, _)| name.as_str()).collect();
        vtk::remove_stale_frames(out, &keep)
            .map_err(|e| format!("cannot remove stale frames in {}: {e}", out.display()))
    }
}

/// Writes `filmstrip.svg` of the recorded snapshots into the output directory.
fn write_filmstrip(
    args: &Args,
    geometry: &Geometry,
    body: &Body<'_>,
    recorder: &Recorder,
) -> Result<(), String> {
    let title = format!(
        "softfem bouncy: {}, {} stepper, E = {} kPa, ν = {}",
        args.model,
        args.stepper,
        args.young_modulus / 1000.0,
        args.poisson_ratio
    );
    let subtitle = format!(
        "{}; {} tets; ρ = {} kg/m³",
        geometry.source,
        body.mesh.element_count(),
        args.density
    );
    let snapshots = recorder.snapshots();
    let svg = Filmstrip {
        title: &title,
        subtitle: &subtitle,
        triangles: &body.surface.triangles,
        snapshots: &snapshots,
        camera: Camera::default(),
    }
    .to_svg();
    let path = args.out.join("filmstrip.svg");
    std::fs::write(&path, svg).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// Runs the scene the flags describe (stable neo-Hookean, no files written) and returns
    /// how far the centre of mass moved sideways (m): `(dx, dy)`.
    fn lateral_drift(flags: &[&str]) -> (f64, f64) {
        let out = std::env::temp_dir().join(format!("bouncy-drift-{}", std::process::id()));
        let out = out.to_str().unwrap();
        let args = Args::try_parse_from(
            ["bouncy", "--quiet", "--vtk-every", "0", "--out", out]
                .iter()
                .chain(flags),
        )
        .unwrap();
        let geometry = Geometry::from_args(&args).unwrap();
        let mut rest = Vec::new();
        let body = Body::new(&geometry, &mut rest, args.density).unwrap();
        let AnyMaterial::StableNeoHookean(material) =
            AnyMaterial::new(args.model, args.young_modulus, args.poisson_ratio).unwrap()
        else {
            panic!("the default model is stable neo-Hookean");
        };
        let mut state = State::at_rest(&geometry);
        let start = body.centre_of_mass(&state.positions);
        let mut writer = FrameWriter::new(&args, &body);
        let mut recorder = Recorder::new(1, args.duration, 1.0);
        let mut console = Console::new(std::io::sink());
        simulate(
            &args,
            &body,
            material,
            &mut state,
            &mut writer,
            &mut recorder,
            &mut console,
        )
        .unwrap();
        assert!(writer.written.is_empty());
        let end = body.centre_of_mass(&state.positions);
        (end[0] - start[0], end[1] - start[1])
    }

    /// A cube dropped flat onto the ground, on a mesh with the cube's mirror symmetries
    /// (x -> -x, y -> -y; the default 5-tet split at an even resolution), must land where it
    /// fell: the forces on a mirror-symmetric state are mirror-symmetric, so the centre of mass
    /// moves sideways only through rounding, which breaks the symmetry (sums in different orders
    /// on the two sides) and which the contacts amplify. Measured over this 1 s run: 2.6e-6 m in
    /// f32; the same drop in f64 (`softfem::f64`) moves 1e-14 m, so the drift scales with the
    /// precision. The bound, 1e-5 m, is 1/7000 of what the Kuhn split does in the same run.
    ///
    /// The Kuhn 6-tet split is not mirror-symmetric (every cell leans along (1, 1, 1)): the
    /// same drop tips the cube and friction turns the rocking into a walk along (-1, -1):
    /// -0.08 m per axis by t = 1 s, the figure the README, `--help` and `BoxSplit::Kuhn6` quote,
    /// asserted here to those digits (by the default 3 s it is -0.1615 and -0.1614 m; a 3 s run
    /// in a debug test costs minutes, so the quotes name the first second).
    #[test]
    fn symmetric_drop_lands_where_it_fell_and_the_kuhn_split_walks() {
        let (dx, dy) = lateral_drift(&["--duration", "1"]);
        assert!(dx.abs() < 1e-5 && dy.abs() < 1e-5, "({dx}, {dy}) m");
        let centimetres = |d: f64| (d * 100.0).round();
        let (dx, dy) = lateral_drift(&["--duration", "1", "--split", "kuhn6"]);
        assert_eq!(
            (centimetres(dx), centimetres(dy)),
            (-8.0, -8.0),
            "({dx}, {dy}) m"
        );
    }

    /// Runs `bouncy` with `flags` into the directory `out`; returns its result and what it
    /// printed.
    fn bouncy_in(out: &Path, flags: &[&str]) -> (Result<(), String>, String) {
        let out = out.to_str().unwrap();
        let args =
            Args::try_parse_from(["bouncy", "--quiet", "--out", out].iter().chain(flags)).unwrap();
        let mut console = Console::new(Vec::new());
        let result = bouncy(&args, &mut console);
        (result, String::from_utf8(console.into_inner()).unwrap())
    }

    fn frame_files(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|entry| entry.unwrap().file_name().into_string().unwrap())
            .filter(|name| vtk::is_frame_file_name(name))
            .collect();
        names.sort();
        names
    }

    fn scratch_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("bouncy-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    /// A shorter run into the same directory leaves only its own frames; `--vtk-every 0`
    /// writes none and says so, and leaves no series file behind.
    #[test]
    fn reruns_leave_only_their_own_frames() {
        let dir = scratch_dir("rerun");
        let small = ["--resolution", "1", "--frame-rate", "10"];
        let (result, _) = bouncy_in(&dir, &[&small[..], &["--duration", "0.5"]].concat());
        assert_eq!((result, frame_files(&dir).len()), (Ok(()), 6));
        let (result, printed) = bouncy_in(&dir, &[&small[..], &["--duration", "0.2"]].concat());
        assert_eq!(result, Ok(()));
        assert_eq!(
            frame_files(&dir),
            ["frame_0000.vtk", "frame_0001.vtk", "frame_0002.vtk"]
        );
        assert!(
            printed.contains("removed 3 frame files of an earlier run"),
            "{printed}"
        );
        let series = std::fs::read_to_string(dir.join("frames.vtk.series")).unwrap();
        assert!(series.contains(r#""time": 0.2 }"#), "{series}");

        let flags = [&small[..], &["--duration", "0.2", "--vtk-every", "0"]].concat();
        let (result, printed) = bouncy_in(&dir, &flags);
        assert_eq!(result, Ok(()));
        assert!(
            printed.contains("wrote     no VTK frames (--vtk-every 0)"),
            "{printed}"
        );
        assert!(frame_files(&dir).is_empty() && !dir.join("frames.vtk.series").exists());
        assert!(dir.join("filmstrip.svg").is_file());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The run ends exactly at the duration, with frames at exact multiples of 1/30 s (a
    /// 3.7e-4 s stable step does not divide 1/30 s: 90 steps of 3.704e-4 s per frame).
    #[test]
    fn frames_land_on_their_times_and_the_run_ends_at_the_duration() {
        let dir = scratch_dir("times");
        let (result, printed) = bouncy_in(&dir, &["--resolution", "1", "--duration", "0.1"]);
        assert_eq!(result, Ok(()));
        assert!(printed.contains("simulated time   0.100 s"), "{printed}");
        let series = std::fs::read_to_string(dir.join("frames.vtk.series")).unwrap();
        let times: Vec<f64> = series
            .split("\"time\": ")
            .skip(1)
            .map(|rest| rest.split(' ').next().unwrap().parse().unwrap())
            .collect();
        let expected: Vec<f64> = (0..4).map(|k| k as f64 / 30.0).collect();
        assert_eq!(times[..3], expected[..3]);
        assert_eq!(times[3], 0.1, "the last frame is the duration itself");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Runs above the limits are refused with the estimate and the way to go ahead, before
    /// anything is built or written.
    #[test]
    fn huge_and_long_runs_are_refused_without_yes() {
        let dir = scratch_dir("refused");
        let (result, printed) = bouncy_in(&dir, &["--resolution", "200"]);
        let message = result.unwrap_err();
        assert!(
            message.contains("5.6 GB of memory") && message.contains("--yes"),
            "{message}"
        );
        assert!(printed.is_empty(), "refused before building: {printed}");
        // Nearly incompressible: the explicit stable step shrinks to 4e-7 s at 2 cells.
        let (result, printed) = bouncy_in(&dir, &["--resolution", "2", "--poisson", "0.4999999"]);
        let message = result.unwrap_err();
        assert!(message.contains("steps (limit 1000000)"), "{message}");
        assert!(message.contains("--stepper relax"), "{message}");
        assert!(printed.contains("estimate  about"), "{printed}");
        assert!(!dir.join("frame_0000.vtk").exists(), "nothing written");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Solves that do not converge make the run fail (non-zero exit status) after writing
    /// its output, and say how many.
    #[test]
    fn failed_relax_solves_fail_the_run() {
        let dir = scratch_dir("relax");
        let flags = [
            "--resolution",
            "2",
            "--stepper",
            "relax",
            "--dt",
            "0.5",
            "--duration",
            "1",
        ];
        let (result, printed) = bouncy_in(&dir, &flags);
        let message = result.unwrap_err();
        assert!(
            message.contains("of 2 implicit solves did not converge"),
            "{message}"
        );
        assert!(printed.contains("2 steps of 5.000e-1 s"), "{printed}");
        assert_eq!(frame_files(&dir).len(), 3, "the output is written");
        std::fs::remove_dir_all(&dir).unwrap();

        let none = SolveTotals::default();
        assert_eq!(solves_verdict(&none), Ok(()));
    }

    /// The vertical shift of the centre of mass that the summary `printed` reports (m).
    fn centre_drop(printed: &str) -> f64 {
        let line = printed
            .lines()
            .find(|line| line.starts_with("centre of mass"))
            .unwrap();
        line.rsplit("z ")
            .next()
            .unwrap()
            .trim_end_matches(" m")
            .parse()
            .unwrap()
    }

    /// Newton and VBD drop the cube onto the ground and every solve converges: the run succeeds
    /// (unconverged solves would fail it, as `failed_relax_solves_fail_the_run` shows), the
    /// summary says so, and the centre of mass ends where a resting cube's is. The cube's
    /// centre starts 0.6 m up and rests 0.1 m up (its half size) less the sag under its own
    /// weight: mg / (k A) ~ rho g size^2 / E = 1000 * 9.81 * 0.04 / 5e4 = 8e-3 of its size, so
    /// the drop is 0.500..0.502 m once the bounce has died out; after 0.8 s (landing at 0.32 s)
    /// the wobble is still a few mm.
    #[test]
    fn newton_and_vbd_runs_land_and_converge() {
        for (stepper, solver) in [("newton", "Newton"), ("vbd", "Vertex Block Descent")] {
            let dir = scratch_dir(stepper);
            let flags = [
                "--resolution",
                "2",
                "--stepper",
                stepper,
                "--duration",
                "0.8",
                "--vtk-every",
                "0",
            ];
            let (result, printed) = bouncy_in(&dir, &flags);
            assert_eq!(result, Ok(()), "{stepper}: {printed}");
            assert!(
                printed.contains(&format!("solver    {solver}")),
                "{printed}"
            );
            assert!(printed.contains("48 steps of 1.667e-2 s"), "{printed}");
            assert!(
                printed.contains("48 of 48 converged (100.0 %), 0 did not"),
                "{printed}"
            );
            let drop = centre_drop(&printed);
            assert!((-0.51..=-0.49).contains(&drop), "{stepper}: {drop} m");
            if stepper == "newton" {
                assert!(printed.contains("CG iterations"), "{printed}");
                assert!(
                    printed.contains("Newton iterations on average"),
                    "{printed}"
                );
            } else {
                assert!(printed.contains("sweeps on average"), "{printed}");
            }
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    /// Newton and VBD solve to the relaxation's default tolerance, so that the steppers compare.
    #[test]
    fn the_implicit_steppers_share_one_tolerance() {
        assert_eq!(RelaxSettings::new().tolerance, TOLERANCE);
    }

    #[test]
    fn frame_counts_for_the_estimate() {
        let parse =
            |flags: &[&str]| Args::try_parse_from(std::iter::once(&"bouncy").chain(flags)).unwrap();
        assert_eq!(frame_count(&parse(&[])), 91);
        assert_eq!(frame_count(&parse(&["--duration", "1.01"])), 32);
        assert_eq!(
            frame_count(&parse(&["--dt", "0.5", "--stepper", "relax"])),
            7
        );
    }

    #[test]
    fn inverted_elements_are_reported() {
        assert_eq!(inversion_warning(Model::StVK, 0, 1080), None);
        let warning = inversion_warning(Model::StVK, 180, 1080).unwrap();
        assert!(
            warning.starts_with("180 of 1080 tetrahedra end inverted"),
            "{warning}"
        );
        assert!(warning.contains("--model stable-neo-hookean"), "{warning}");
    }
}

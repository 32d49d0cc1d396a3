//! `cargo run --release --example bouncy`: a soft jelly cube (or any TetGen mesh, `--mesh`)
//! dropped onto the ground, bouncing and settling.
//!
//! Builds the scene from the flags, validates the mesh and material, steps it with
//! `softfem::step` (explicit symplectic Euler at half the computed stable time step, or implicit
//! Euler solved by preconditioned descent), and writes VTK frames (ParaView), a filmstrip SVG and
//! a summary. Bad flags or a bad mesh give a readable error and a non-zero exit status.

mod cli;
mod filmstrip;
mod progress;
mod scene;
mod surface;
mod vtk;

use std::path::Path;
use std::process::ExitCode;

use clap::Parser;

use cli::{Args, Stepper, VtkContent};
use filmstrip::{Camera, Filmstrip, Recorder};
use progress::{Progress, Summary};
use scene::{
    AnyMaterial, Body, FrameView, Geometry, RunConfig, RunStats, SolveInfo, State, StepInfo,
};
use softfem::element::TetRest;
use softfem::glam::Vec3;
use softfem::material::Material;
use softfem::step::{
    ExplicitScratch, ExplicitSettings, Ground, RelaxScratch, RelaxSettings, TetElastic,
    explicit_scratch_len, relax_scratch_len, relax_step, stable_time_step, step_explicit,
};

/// Mass-proportional damping (1/s) of the explicit stepper: a little, so the wobble settles
/// within the default three seconds the way real jelly does.
const DAMPING: f32 = 0.5;
/// Coulomb friction coefficient of the ground.
const FRICTION: f32 = 0.6;
/// Relative residual at which an implicit step counts as solved, and the iteration budget. At
/// rest on the ground f32 rounding leaves a residual near 1e-3 of the weight: ask for 2e-3.
const RELAX_TOLERANCE: (f32, u32) = (2e-3, 300);
/// Chebyshev acceleration of the implicit solves: spectral radius estimate and step length
/// (see `softfem::step`, "The relaxation").
const RELAX_CHEBYSHEV: (f32, f32) = (0.995, 2.0);

fn main() -> ExitCode {
    let args = Args::parse(); // bad flags: clap prints the reason and exits with status 2
    match bouncy(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn bouncy(args: &Args) -> Result<(), String> {
    let geometry = Geometry::from_args(args)?;
    let mut rest = Vec::<TetRest>::new();
    let body = Body::new(&geometry, &mut rest, args.density)?;
    let material = AnyMaterial::new(args.model, args.young_modulus, args.poisson_ratio)?;
    let state = State::at_rest(&geometry);

    println!(
        "body      {}: {} vertices, {} tetrahedra, {} surface triangles",
        geometry.source,
        body.mesh.vertex_count(),
        body.mesh.element_count(),
        body.surface.len()
    );
    if geometry.reoriented > 0 || geometry.dropped_vertices > 0 {
        println!(
            "          {} tetrahedra reoriented, {} unused vertices dropped",
            geometry.reoriented, geometry.dropped_vertices
        );
    }
    println!(
        "material  {}, E = {} Pa, nu = {}, density {} kg/m^3, mass {:.3} kg",
        args.model,
        args.young_modulus,
        args.poisson_ratio,
        args.density,
        body.total_mass()
    );
    let h_min = body.shortest_edge(&geometry.rest_positions);
    println!(
        "          shortest edge {h_min:.4} m, wave speed {:.1} m/s",
        material.wave_speed(args.density)
    );
    println!(
        "drop      lowest point {} m above the ground, {} s simulated",
        args.drop_height, args.duration
    );

    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let mut writer = FrameWriter::new(args, &body);
    let mut recorder = Recorder::new(
        args.panels as usize,
        f64::from(args.duration),
        1.0 / f64::from(args.frame_rate),
    );
    let mut state = state;
    let initial_energies = body.energies(&material, &state.positions, &state.velocities)?;
    let outcome = match material {
        AnyMaterial::StVK(m) => simulate(args, &body, m, &mut state, &mut writer, &mut recorder),
        AnyMaterial::NeoHookean(m) => {
            simulate(args, &body, m, &mut state, &mut writer, &mut recorder)
        }
        AnyMaterial::StableNeoHookean(m) => {
            simulate(args, &body, m, &mut state, &mut writer, &mut recorder)
        }
    };
    // Whatever happened, the frames so far and the filmstrip are written, so a failed run can
    // still be looked at.
    writer.finish()?;
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
    write_filmstrip(&args.out, &title, &subtitle, &body, &recorder)?;
    let (stats, dt) = match outcome {
        Ok(done) => done,
        Err(error) => {
            println!(
                "wrote     {} frames and {} up to the failure",
                writer.written.len(),
                args.out.join("filmstrip.svg").display()
            );
            return Err(error);
        }
    };

    let mut ratios = Vec::new();
    body.volume_ratios(&state.positions, &mut ratios);
    let summary = Summary {
        simulated: stats.simulated,
        wall: stats.wall,
        steps: stats.steps,
        volume_ratio: progress::min_max(&ratios),
        energies: body.energies(&material, &state.positions, &state.velocities)?,
        initial_energies,
        solves: stats.solves,
    };
    println!("time step {dt:.3e} s ({} steps)", stats.steps);
    for line in summary.lines() {
        println!("{line}");
    }
    println!(
        "wrote     {} VTK frames ({}, series in {}) and {}",
        writer.written.len(),
        args.out.join(vtk::frame_file_name(0)).display(),
        args.out.join("frames.vtk.series").display(),
        args.out.join("filmstrip.svg").display()
    );
    Ok(())
}

/// Runs the scene with the concrete material `M`: picks the time step, builds the stepper's
/// scratch space, and drives [`scene::run`], writing frames as it goes. Returns the run's
/// statistics and the time step used.
fn simulate<M: Material>(
    args: &Args,
    body: &Body<'_>,
    material: M,
    state: &mut State,
    writer: &mut FrameWriter<'_>,
    recorder: &mut Recorder,
) -> Result<(RunStats, f32), String> {
    let model = TetElastic::new(body.mesh, material);
    let n = body.mesh.vertex_count();
    let mut stiffness = vec![0.0; n];
    let bound = stable_time_step(&model, &body.masses, &[], &mut stiffness)
        .map_err(|e| format!("stable time step: {e}"))?;
    let dt = scene::time_step(args, Some(bound))?;
    println!(
        "stepper   {}, dt {dt:.3e} s (explicit stable bound {bound:.3e} s)",
        args.stepper
    );
    let config = RunConfig {
        dt,
        duration: args.duration,
        frame_interval: 1.0 / args.frame_rate,
    };
    let ground = Ground::new(Vec3::Z, 0.0).with_friction(FRICTION);
    let mut progress = Progress::new(args.quiet);
    let on_frame = |frame: &FrameView<'_>| {
        writer.write(frame)?;
        recorder.offer(frame.time, frame.positions);
        Ok(())
    };
    let stats = match args.stepper {
        Stepper::Explicit => {
            let settings = ExplicitSettings::new(dt)
                .with_gravity(scene::GRAVITY)
                .with_damping(DAMPING)
                .with_ground(ground);
            let mut buffer = vec![Vec3::ZERO; explicit_scratch_len(n)];
            let mut scratch = ExplicitScratch::new(&mut buffer);
            scene::run(
                state,
                &config,
                &mut progress,
                |x, v, _| {
                    step_explicit(&model, &body.masses, &[], &settings, x, v, &mut scratch)
                        .map(|_| StepInfo::default())
                        .map_err(|e| e.to_string())
                },
                on_frame,
            )
        }
        Stepper::Relax => {
            let (tolerance, iterations) = RELAX_TOLERANCE;
            let settings = RelaxSettings::new(dt)
                .with_gravity(scene::GRAVITY)
                .with_ground(ground)
                .with_tolerance(tolerance, iterations)
                .with_chebyshev(RELAX_CHEBYSHEV.0, RELAX_CHEBYSHEV.1, 0);
            // The solver's own scale for its tolerance: max(|grad Phi(x_0)|, |M g|) (N).
            let weight = body
                .masses
                .iter()
                .map(|m| (m * scene::G).powi(2))
                .sum::<f32>()
                .sqrt();
            let mut vectors = vec![Vec3::ZERO; relax_scratch_len(n)];
            let mut scalars = vec![0.0; n];
            let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
            scene::run(
                state,
                &config,
                &mut progress,
                |x, v, _| {
                    relax_step(&model, &body.masses, &[], &settings, x, v, &mut scratch)
                        .map(|report| StepInfo {
                            solve: Some(SolveInfo {
                                iterations: report.iterations,
                                line_search_steps: report.backtracks,
                                relative_residual: report.final_residual
                                    / report.initial_residual.max(weight),
                                converged: report.converged,
                            }),
                        })
                        .map_err(|e| e.to_string())
                },
                on_frame,
            )
        }
    };
    stats.map(|stats| (stats, dt)).map_err(|e| e.to_string())
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

    fn finish(&self) -> Result<(), String> {
        if self.written.is_empty() {
            return Ok(());
        }
        let path = self.args.out.join("frames.vtk.series");
        vtk::write_series_file(&path, &self.written)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))
    }
}

fn write_filmstrip(
    out: &Path,
    title: &str,
    subtitle: &str,
    body: &Body<'_>,
    recorder: &Recorder,
) -> Result<(), String> {
    let snapshots = recorder.snapshots();
    let svg = Filmstrip {
        title,
        subtitle,
        triangles: &body.surface.triangles,
        snapshots: &snapshots,
        camera: Camera::default(),
    }
    .to_svg();
    let path = out.join("filmstrip.svg");
    std::fs::write(&path, svg).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

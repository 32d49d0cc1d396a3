//! `cargo run --release -p softfem-examples --bin pile`: eight soft balls dropped into a box
//! (issue #39).
//!
//! Eight balls (radius 4 cm, stable neo-Hookean, E = 100 kPa, nu = 0.3, 1000 kg/m^3) start in
//! a spiral above a box (the ground and four wall colliders, 18 cm apart) and fall into it, onto
//! each other. The balls are the bodies of one `softfem::world::World`: one Newton solve of
//! 1/100 s over all their vertices per step, with the barrier of Incremental Potential Contact
//! (dhat = 1 mm) and friction 0.3 between their surfaces, every trial step cut by continuous
//! collision detection. After every step an exact triangle–triangle test
//! (`tests/common/exact_intersection.rs`, shared with the contact tests; not the barrier) counts
//! the pairs of boundary triangles that intersect. Writes VTK frames (`frame_0000.vtk`, ..., with
//! `frames.vtk.series` for ParaView) and `filmstrip.svg` into `target/pile/`, and prints a
//! summary: intersecting pairs, the smallest gap, the share of converged solves, the balls'
//! volume range and the wall time. Exits with failure if any pair intersected.
//!
//! The same scene, shorter and coarser, is the test `tests/steppers/pile.rs`.

#[path = "../../tests/common/ball_pile.rs"]
mod ball_pile;
#[path = "../../tests/common/exact_intersection.rs"]
mod exact;
// The bouncy scene's VTK writer and filmstrip drawing, shared as they are; this program uses
// part of each (no triangle cells, a fixed frame interval).
#[path = "../bouncy/filmstrip.rs"]
#[allow(dead_code)]
mod filmstrip;
#[path = "../bouncy/vtk.rs"]
#[allow(dead_code)]
mod vtk;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;

use filmstrip::{Camera, Filmstrip, Recorder};
use softfem::body::{Solver, StepReport, VecStorage};
use softfem::glam::{Quat, Vec3};
use softfem::material::StableNeoHookean;
use softfem::step::contact::potential::ContactBarrier;
use softfem::step::{Collider, HalfSpace, NewtonSettings};
use softfem::world::World;

/// Gravity (m/s^2) along -z.
const GRAVITY: Vec3 = Vec3::new(0.0, 0.0, -9.81);
/// Ball radius (m).
const RADIUS: f32 = 0.04;
/// Half the inner width of the box (m): a 2 x 2 layer of balls (16 cm) just fits.
const HALF_WIDTH: f32 = 0.09;
/// The balls' material and the friction everywhere (between balls, on the ground and walls).
const YOUNG_MODULUS: f32 = 1e5;
const POISSON_RATIO: f32 = 0.3;
const DENSITY: f32 = 1000.0;
const FRICTION: f32 = 0.3;
/// The barrier's gap (m) and the force (N) a pair at half of it holds.
const DHAT: f32 = 1e-3;
const HOLDING: f32 = 1.0;
/// The most time steps and VTK frames a run may take.
const MAX_STEPS: usize = 100_000;
const MAX_FRAMES: usize = 10_000;
/// Newton's relative tolerance and iteration budget.
const TOLERANCE: f32 = 1e-5;
const MAX_ITERATIONS: u32 = 100;

/// Drop eight soft balls into a box and check that their surfaces never intersect.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Args {
    /// Simulated time (s).
    #[arg(long, default_value_t = 2.0)]
    duration: f32,

    /// Time step (s).
    #[arg(long, default_value_t = 0.01)]
    step: f32,

    /// Cells along the side of the cube each ball is mapped from (cells^3 x 5 tetrahedra).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(2..=12))]
    cells: u32,

    /// Output frames per simulated second.
    #[arg(long, default_value_t = 30.0)]
    frame_rate: f32,

    /// Panels of the filmstrip.
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..=24))]
    panels: u32,

    /// Output directory (created if missing).
    #[arg(long, default_value = "target/pile")]
    out: PathBuf,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

/// The signed volume of a tetrahedron (m^3; positive for the library's orientation).
fn volume(x: &[Vec3], [a, b, c, d]: [u32; 4]) -> f32 {
    let [a, b, c, d] = [a, b, c, d].map(|i| x[i as usize]);
    (b - a).cross(c - a).dot(d - a) / 6.0
}

/// The four walls: the shared scene's boxes (`tests/common/ball_pile.rs`), inner faces at
/// `|x|, |y| = HALF_WIDTH`, with the pile's friction.
fn walls() -> Vec<Collider<'static>> {
    let vec3 = |p: [f64; 3]| Vec3::from_array(p.map(|c| c as f32));
    ball_pile::walls(f64::from(HALF_WIDTH))
        .into_iter()
        .map(|(centre, half)| {
            Collider::cuboid(vec3(centre), vec3(half), Quat::IDENTITY).with_friction(FRICTION)
        })
        .collect()
}

/// The eight balls as the bodies of a world, with the pile's material, contact, solver, gravity
/// and ground (the walls are colliders given to each step).
fn pile(cells: usize) -> Result<World<VecStorage, StableNeoHookean>, String> {
    let material = StableNeoHookean::from_young_poisson(YOUNG_MODULUS, POISSON_RATIO)
        .map_err(|e| e.to_string())?;
    let mut world = World::new();
    let vec3 = |p: &[f64; 3]| Vec3::from_array(p.map(|c| c as f32));
    for centre in ball_pile::centres(f64::from(RADIUS)) {
        let (x, tets) = ball_pile::ball(centre, f64::from(RADIUS), cells)?;
        let x: Vec<Vec3> = x.iter().map(vec3).collect();
        world
            .add_body(&x, &tets, DENSITY, material)
            .map_err(|e| e.to_string())?;
    }
    let barrier = ContactBarrier::holding(DHAT, HOLDING).map_err(|e| e.to_string())?;
    let settings = NewtonSettings::new().with_tolerance(TOLERANCE, MAX_ITERATIONS);
    world.set_barrier(barrier).map_err(|e| e.to_string())?;
    world.set_friction(FRICTION).map_err(|e| e.to_string())?;
    world
        .set_solver(Solver::Newton(settings))
        .map_err(|e| e.to_string())?;
    world.set_gravity(GRAVITY);
    world.set_ground(Some(HalfSpace::new(Vec3::Z, 0.0).with_friction(FRICTION)));
    Ok(world)
}

/// The pairs of boundary triangles (sharing no vertex) of `world` that intersect, decided
/// exactly.
fn intersecting_pairs(world: &World<VecStorage, StableNeoHookean>) -> usize {
    let x: Vec<[f64; 3]> = world
        .positions()
        .iter()
        .map(|p| p.to_array().map(f64::from))
        .collect();
    exact::intersecting_pairs(&x, world.triangles()).len()
}

/// Each ball's volume (m^3) now.
fn volumes(world: &World<VecStorage, StableNeoHookean>) -> Vec<f32> {
    let (x, tets) = (world.positions(), world.tets());
    world
        .bodies()
        .iter()
        .map(|ball| tets[ball.tets()].iter().map(|&t| volume(x, t)).sum())
        .collect()
}

/// What the run counts, for the summary.
#[derive(Debug, Default)]
struct Totals {
    steps: usize,
    converged: usize,
    /// Not converged, stopped at the f32 rounding floor (the report's `stagnated`).
    stagnated: usize,
    iterations: u32,
    /// The steps that neither converged nor stopped at the rounding floor: (step, residual N,
    /// target N).
    unconverged: Vec<(usize, f32, f32)>,
    /// Intersecting triangle pairs summed over the steps, and the steps with any.
    intersecting: usize,
    intersecting_steps: usize,
    smallest_gap: Option<f32>,
    volume_range: (f32, f32),
}

fn run(args: &Args) -> Result<(), String> {
    if !(args.duration > 0.0 && args.step > 0.0 && args.frame_rate > 0.0) {
        return Err("--duration, --step and --frame-rate must be positive".into());
    }
    // A bound on the work and the files a typo can ask for (the default run is 200 steps and
    // 61 frames).
    let (step_count, frame_count) = (
        f64::from(args.duration) / f64::from(args.step),
        f64::from(args.duration) * f64::from(args.frame_rate),
    );
    if !(step_count <= MAX_STEPS as f64 && frame_count <= MAX_FRAMES as f64) {
        return Err(format!(
            "--duration {} asks for {step_count:.3e} steps of {} s and {frame_count:.3e} frames; \
             at most {MAX_STEPS} steps and {MAX_FRAMES} frames",
            args.duration, args.step
        ));
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let mut world = pile(args.cells as usize)?;
    let n = world.vertex_count();
    let rest_volumes = volumes(&world);
    let rest_tet_volumes: Vec<f32> = world
        .tets()
        .iter()
        .map(|&t| volume(world.rest_positions(), t))
        .collect();
    println!(
        "balls     8 of radius {RADIUS} m, {} cells^3 each: {n} vertices, {} tetrahedra, {} boundary triangles",
        args.cells,
        world.tet_count(),
        world.triangles().len()
    );
    if intersecting_pairs(&world) != 0 {
        return Err("the balls intersect at the start".into());
    }
    println!(
        "material  stable neo-Hookean, E = {YOUNG_MODULUS} Pa, nu = {POISSON_RATIO}, {DENSITY} kg/m^3, {:.3} kg in all",
        world.masses().iter().sum::<f32>()
    );
    println!(
        "contact   barrier dhat = {DHAT} m holding {HOLDING} N at half of it, friction {FRICTION} between the balls, on the ground and the walls"
    );
    println!(
        "stepper   World, Newton, h = {} s, tolerance {TOLERANCE}, at most {MAX_ITERATIONS} iterations",
        args.step
    );
    let walls = walls();

    let frame_interval = 1.0 / f64::from(args.frame_rate);
    let mut recorder = Recorder::new(
        args.panels as usize,
        f64::from(args.duration),
        frame_interval,
    );
    let steps = (f64::from(args.duration) / f64::from(args.step))
        .round()
        .max(1.0) as usize;
    let mut totals = Totals {
        volume_range: (1.0, 1.0),
        ..Totals::default()
    };
    let mut written: Vec<(String, f64)> = Vec::new();
    let mut next_frame = 0.0f64;
    let mut next_progress = 0.0f64;
    let started = Instant::now();
    for step in 0..=steps {
        let time = step as f64 * f64::from(args.step);
        // A microsecond of slack: the frame times accumulate rounding (60 x 1/30 > 2).
        if time + 1e-6 >= next_frame {
            let x = world.positions();
            let ratios: Vec<f32> = world
                .tets()
                .iter()
                .zip(&rest_tet_volumes)
                .map(|(&tet, rest)| volume(x, tet) / rest)
                .collect();
            let name = vtk::frame_file_name(written.len());
            let path = args.out.join(&name);
            let title = format!("softfem pile, step {step}, t = {time} s");
            vtk::write_frame_file(
                &path,
                &vtk::Frame {
                    title: &title,
                    time,
                    positions: x,
                    velocities: world.velocities(),
                    cells: vtk::Cells::Tets(world.tets()),
                    volume_ratios: &ratios,
                },
            )
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            written.push((name, time));
            recorder.offer(time, x);
            next_frame += frame_interval;
        }
        if time + 1e-6 >= next_progress {
            println!(
                "t = {time:5.2} s  step {step:4}  {} Newton iterations, {} of {} converged, smallest gap {}",
                totals.iterations,
                totals.converged,
                totals.steps,
                gap_text(totals.smallest_gap)
            );
            next_progress += 0.25;
        }
        if step == steps {
            break;
        }
        let report = match world.step_with_colliders(args.step, &walls) {
            Ok(StepReport::Newton(report)) => report,
            Ok(other) => return Err(format!("step {step}: not a Newton report: {other:?}")),
            Err(e) => return Err(format!("step {step}: {e}")),
        };
        totals.steps += 1;
        totals.iterations += report.iterations;
        totals.converged += usize::from(report.converged);
        totals.stagnated += usize::from(!report.converged && report.stagnated);
        if !report.converged && !report.stagnated {
            totals
                .unconverged
                .push((step, report.residual, report.target));
        }
        let crossing = intersecting_pairs(&world);
        totals.intersecting += crossing;
        totals.intersecting_steps += usize::from(crossing > 0);
        let gap = world
            .smallest_gap(10.0 * DHAT)
            .map_err(|e| format!("step {step}: {e}"))?;
        if let Some(gap) = gap {
            totals.smallest_gap = Some(totals.smallest_gap.map_or(gap, |g| g.min(gap)));
        }
        for (volume, rest) in volumes(&world).iter().zip(&rest_volumes) {
            let ratio = volume / rest;
            totals.volume_range = (
                totals.volume_range.0.min(ratio),
                totals.volume_range.1.max(ratio),
            );
        }
    }
    let wall = started.elapsed().as_secs_f64();

    let series = args.out.join("frames.vtk.series");
    vtk::write_series_file(&series, &written)
        .map_err(|e| format!("cannot write {}: {e}", series.display()))?;
    let keep: Vec<&str> = written.iter().map(|(name, _)| name.as_str()).collect();
    vtk::remove_stale_frames(&args.out, &keep)
        .map_err(|e| format!("cannot remove stale frames in {}: {e}", args.out.display()))?;
    let snapshots = recorder.snapshots();
    let title = format!(
        "softfem pile: eight soft balls in a box, E = {} kPa, friction {FRICTION}, Newton h = {} s",
        YOUNG_MODULUS / 1000.0,
        args.step
    );
    let subtitle = format!(
        "{} tets, {} boundary triangles; {} intersecting triangle pairs (exact test), smallest gap {}",
        world.tet_count(),
        world.triangles().len(),
        totals.intersecting,
        gap_text(totals.smallest_gap)
    );
    let svg = Filmstrip {
        title: &title,
        subtitle: &subtitle,
        triangles: world.triangles(),
        snapshots: &snapshots,
        camera: Camera::default(),
    }
    .to_svg();
    let path = args.out.join("filmstrip.svg");
    std::fs::write(&path, svg).map_err(|e| format!("cannot write {}: {e}", path.display()))?;

    println!(
        "simulated {} s in {steps} steps, {wall:.2} s wall ({:.1} ms per step)",
        args.duration,
        wall * 1e3 / steps as f64
    );
    println!(
        "solves    {} of {} converged ({:.1} %), {} stopped at the f32 rounding floor, {} Newton iterations ({:.1} per step)",
        totals.converged,
        totals.steps,
        100.0 * totals.converged as f64 / totals.steps as f64,
        totals.stagnated,
        totals.iterations,
        f64::from(totals.iterations) / totals.steps as f64
    );
    for &(step, residual, target) in &totals.unconverged {
        println!(
            "          step {step} did not converge: residual {residual:.3e} N, target {target:.3e} N"
        );
    }
    println!(
        "contact   {} intersecting triangle pairs after the steps (exact test; {} steps with any), smallest gap {} (dhat {DHAT} m)",
        totals.intersecting,
        totals.intersecting_steps,
        gap_text(totals.smallest_gap)
    );
    println!(
        "volumes   each ball between {:.4} and {:.4} of its rest volume",
        totals.volume_range.0, totals.volume_range.1
    );
    println!(
        "wrote     {} VTK frames ({}, {}) and {}",
        written.len(),
        args.out.join("frame_0000.vtk").display(),
        series.display(),
        path.display()
    );
    if totals.intersecting > 0 {
        return Err(format!(
            "{} intersecting triangle pairs in {} steps",
            totals.intersecting, totals.intersecting_steps
        ));
    }
    Ok(())
}

/// The smallest gap in millimetres, or a note that no pair came within 10 dhat.
fn gap_text(gap: Option<f32>) -> String {
    gap.map_or_else(
        || format!("none within {:.0} mm", 10.0 * DHAT * 1e3),
        |g| format!("{:.3} mm", g * 1e3),
    )
}

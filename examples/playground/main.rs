//! The colliders' playground: a soft ball and a soft box (and a second, stiffer ball) fall onto
//! a kinematic paddle that rocks back and forth, a sphere and a capsule, all on the ground.
//!
//! `cargo run --release -p softfem-examples --bin playground -- [--duration S] [--out DIR]
//! [--stepper NAME]`
//!
//! Writes one legacy VTK file of all bodies per frame (`frame_0000.vtk` ...; open them in
//! ParaView; the `body` cell field tells the bodies apart) and `filmstrip.svg`, a side view of
//! the scene at six instants with the colliders drawn in grey, into the output directory. Each
//! body is a `softfem::body::Body` over fixed-capacity storage, stepped with
//! `step_with_colliders`; the paddle is a `step::Collider` box advanced between steps by
//! `Collider::advanced`. Bodies do not collide with each other, only with the colliders.

mod draw;
mod vtk;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, ValueEnum};
use softfem::body::{Body, FixedStorage, Solver};
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::{Quat, Vec3};
use softfem::material::StableNeoHookean;
use softfem::step::{Collider, ExplicitSettings};

/// Soft bodies falling onto a rocking paddle, a sphere and a capsule.
#[derive(Clone, Debug, Parser)]
#[command(name = "playground", version)]
struct Args {
    /// Simulated time (s).
    #[arg(long, default_value_t = 4.0, value_parser = positive)]
    duration: f64,
    /// Output directory (created if missing).
    #[arg(long, default_value = "out/playground")]
    out: PathBuf,
    /// Time stepper of every body.
    #[arg(long, value_enum, default_value_t = Stepper::Explicit)]
    stepper: Stepper,
    /// Output frames per simulated second.
    #[arg(long, default_value_t = 30.0, value_parser = positive)]
    frame_rate: f64,
    /// Print only the summary.
    #[arg(long)]
    quiet: bool,
}

/// The steppers a body can use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Stepper {
    /// Explicit symplectic Euler, substeps of half the stable step, damping 1/s.
    Explicit,
    /// Implicit Euler, Chebyshev-accelerated relaxation.
    Relax,
    /// Implicit Euler, Newton's method.
    Newton,
    /// Implicit Euler, Vertex Block Descent.
    Vbd,
}

impl Stepper {
    fn solver(self) -> Solver {
        match self {
            Stepper::Explicit => Solver::Explicit {
                settings: ExplicitSettings::new().with_damping(1.0),
                stable_fraction: Some(0.5),
            },
            Stepper::Relax => Solver::relax(),
            Stepper::Newton => Solver::newton(),
            Stepper::Vbd => Solver::vbd(),
        }
    }
}

fn positive(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x > 0.0 && x.is_finite() => Ok(x),
        _ => Err(format!("{text:?} is not a positive number")),
    }
}

/// The ball's mesh: 6 x 6 x 6 cells, 5 tetrahedra each (343 vertices, 1080 tets).
const BALL_CELLS: usize = 6;
type BallStorage = FixedStorage<343, 1080>;
/// The box's mesh: 6 x 4 x 3 cells (140 vertices, 360 tets).
type BoxStorage = FixedStorage<140, 360>;

/// A soft body of either mesh.
enum Soft {
    Ball(Box<Body<BallStorage, StableNeoHookean>>),
    Brick(Box<Body<BoxStorage, StableNeoHookean>>),
}

impl Soft {
    fn positions(&self) -> &[Vec3] {
        match self {
            Soft::Ball(b) => b.positions(),
            Soft::Brick(b) => b.positions(),
        }
    }
    fn tets(&self) -> &[[u32; 4]] {
        match self {
            Soft::Ball(b) => b.tets(),
            Soft::Brick(b) => b.tets(),
        }
    }
    fn step(&mut self, dt: f32, colliders: &[Collider<'_>]) -> Result<(), softfem::StepError> {
        match self {
            Soft::Ball(b) => b.step_with_colliders(dt, colliders).map(drop),
            Soft::Brick(b) => b.step_with_colliders(dt, colliders).map(drop),
        }
    }
}

/// A ball of `radius` (m) around `center`: the box generator's cube mapped radially onto the
/// ball (each point scaled by its max-norm over its 2-norm, a continuous bijection that keeps
/// every tetrahedron positively oriented on this mesh).
fn ball(center: Vec3, radius: f32, young: f32, solver: Solver) -> Result<Soft, String> {
    let n = BALL_CELLS;
    let (vertices, tets) =
        box_counts(n, n, n, BoxSplit::Alternating5).map_err(|e| e.to_string())?;
    let (mut rest, mut cells) = (vec![Vec3::ZERO; vertices], vec![[0u32; 4]; tets]);
    let r = Vec3::splat(radius);
    fill_box(
        -r,
        r,
        n,
        n,
        n,
        BoxSplit::Alternating5,
        &mut rest,
        &mut cells,
    )
    .map_err(|e| e.to_string())?;
    for x in &mut rest {
        let length = x.length();
        if length > 0.0 {
            *x *= x.abs().max_element() / length;
        }
        *x += center;
    }
    let material = StableNeoHookean::from_young_poisson(young, 0.4).map_err(|e| e.to_string())?;
    let mut body = Box::new(
        Body::<BallStorage, _>::from_arrays(&rest, &cells, 600.0, material)
            .map_err(|e| e.to_string())?,
    );
    body.set_solver(solver).map_err(|e| e.to_string())?;
    body.set_gravity(GRAVITY);
    Ok(Soft::Ball(body))
}

/// A box `[low, high]` (m) of 6 x 4 x 3 cells, turned by `turn` about its centre.
fn brick(low: Vec3, high: Vec3, turn: Quat, young: f32, solver: Solver) -> Result<Soft, String> {
    let material = StableNeoHookean::from_young_poisson(young, 0.4).map_err(|e| e.to_string())?;
    let mut body = Box::new(
        Body::<BoxStorage, _>::from_box(low, high, [6, 4, 3], 800.0, material)
            .map_err(|e| e.to_string())?,
    );
    let centre = (low + high) * 0.5;
    for x in body.positions_mut() {
        *x = centre + turn * (*x - centre);
    }
    body.set_solver(solver).map_err(|e| e.to_string())?;
    body.set_gravity(GRAVITY);
    Ok(Soft::Brick(body))
}

/// z up.
const GRAVITY: Vec3 = Vec3::new(0.0, 0.0, -9.81);

/// The paddle's tilt about y: `AMPLITUDE sin(RATE t)` (rad; rad/s).
const AMPLITUDE: f32 = 0.35;
const RATE: f32 = 2.5;

/// The static colliders and the paddle at `t = 0`.
fn colliders() -> [Collider<'static>; 4] {
    [
        Collider::half_space(Vec3::ZERO, Vec3::Z).with_friction(0.6),
        Collider::cuboid(
            Vec3::new(-0.55, 0.0, 0.55),
            Vec3::new(0.35, 0.3, 0.03),
            Quat::IDENTITY,
        )
        .with_friction(0.5)
        .with_restitution(0.3),
        Collider::sphere(Vec3::new(0.15, 0.0, 0.25), 0.25).with_friction(0.3),
        Collider::capsule(Vec3::new(0.6, 0.0, 0.15), Vec3::new(1.0, 0.0, 0.15), 0.15)
            .with_friction(0.3),
    ]
}

fn run(args: &Args) -> Result<(), String> {
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    let solver = args.stepper.solver();
    let mut bodies = [
        ball(Vec3::new(-0.6, 0.0, 1.0), 0.12, 3.0e4, solver)?,
        brick(
            Vec3::new(0.05, -0.08, 0.8),
            Vec3::new(0.35, 0.08, 1.0),
            Quat::from_rotation_y(0.3),
            5.0e4,
            solver,
        )?,
        ball(Vec3::new(0.75, 0.0, 0.9), 0.1, 1.5e5, solver)?,
    ];
    let mut scene = colliders();
    let dt = 1.0 / 120.0_f32; // s, a step of every body (the explicit ones substep inside)
    let steps = (args.duration / f64::from(dt)).round().max(1.0) as usize;
    let frame_every = ((1.0 / args.frame_rate) / f64::from(dt)).round().max(1.0) as usize;
    let surfaces: Vec<Vec<[u32; 3]>> = bodies.iter().map(|b| draw::boundary(b.tets())).collect();
    let mut film = draw::Recorder::new(6, steps);
    let started = Instant::now();
    let mut frames = 0;
    for step in 0..=steps {
        if step % frame_every == 0 {
            let positions: Vec<&[Vec3]> = bodies.iter().map(Soft::positions).collect();
            let tets: Vec<&[[u32; 4]]> = bodies.iter().map(Soft::tets).collect();
            let path = args.out.join(format!("frame_{frames:04}.vtk"));
            vtk::write(&path, step as f64 * f64::from(dt), &positions, &tets)
                .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            frames += 1;
        }
        film.offer(
            step,
            step as f32 * dt,
            &scene,
            &bodies
                .iter()
                .map(|b| b.positions().to_vec())
                .collect::<Vec<_>>(),
        );
        if step == steps {
            break;
        }
        // The paddle rocks: its angular velocity at mid-step, then its pose at the step's end.
        let t = (step as f32 + 0.5) * dt;
        let paddle = &mut scene[1];
        paddle.angular_velocity = Vec3::Y * (AMPLITUDE * RATE * (RATE * t).cos());
        *paddle = paddle.advanced(dt);
        for (k, body) in bodies.iter_mut().enumerate() {
            body.step(dt, &scene)
                .map_err(|e| format!("body {k}, step {step}: {e}"))?;
        }
        if !args.quiet && (step + 1) % 120 == 0 {
            println!("t = {:.2} s", (step + 1) as f32 * dt);
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    let svg = draw::filmstrip(&film, &surfaces);
    let strip = args.out.join("filmstrip.svg");
    std::fs::write(&strip, svg).map_err(|e| format!("cannot write {}: {e}", strip.display()))?;
    let deepest = bodies
        .iter()
        .flat_map(|b| b.positions().iter())
        .flat_map(|&x| scene.iter().map(move |c| -c.distance(x)))
        .fold(0.0_f32, f32::max);
    println!(
        "{} bodies, {steps} steps of {dt:.4} s ({:?}) in {elapsed:.2} s; {frames} VTK frames and \
         {} in {}; deepest vertex inside a collider at the end: {deepest:.1e} m",
        bodies.len(),
        args.stepper,
        strip.display(),
        args.out.display()
    );
    Ok(())
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("playground: {message}");
            ExitCode::FAILURE
        }
    }
}

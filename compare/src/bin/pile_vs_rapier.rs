//! `cargo run --release --manifest-path compare/Cargo.toml --bin pile_vs_rapier`: the eight-ball
//! pile (issue #39) in softfem and in rapier3d 0.36's FEM soft bodies, in the same run.
//!
//! The scene is the `pile` example's (`examples/pile/main.rs`, geometry in
//! `tests/common/ball_pile.rs`): eight balls of radius 4 cm (stable neo-Hookean, E = 100 kPa,
//! nu = 0.3, 1000 kg/m^3) dropped in a spiral into a box (the ground and four wall boxes, 18 cm
//! apart), friction 0.3 everywhere, time step 10 ms. Both engines get the same tetrahedra, the
//! same positions and the same lumped masses (softfem's, handed to rapier per particle).
//!
//! * softfem: `softfem::world::World` (f32, growable storage), one `add_body` per ball, Newton
//!   with the pile example's tolerance (1e-5 relative, at most 100 iterations), the barrier of
//!   Incremental Potential Contact (dhat 1 mm, the world's default), friction 0.3 between the
//!   balls, the ground a half-space, the walls box colliders (`step_with_colliders`). One
//!   thread: the world without a pool (the calling thread); all cores: `World::set_threads`
//!   with `--threads` threads (feature `rayon`: the balls' elastic passes in parallel, a task
//!   per ball, the contact's pair work on the calling thread; the same bits as one thread).
//! * rapier: `PhysicsWorld` with one `SoftBodyBuilder` body per ball (`SoftBodySolver::Fem`,
//!   `SoftBodyCellModel::NeoHookean`, the same Young's modulus and Poisson ratio, no material
//!   damping, self contacts on as softfem's world has them, contact skin `--skin`), the ground and
//!   walls fixed cuboid colliders, every friction 0.3, rapier's other settings at their defaults
//!   (4 solver iterations a step, bodies may sleep, length unit 1 m). One thread: a rayon pool of
//!   one worker (`configure_thread_pool(1)`); all cores: a pool of `--threads` workers (feature
//!   `parallel`). rapier reports no convergence of its linear solves.
//!
//! Each repetition runs softfem on one thread, softfem on all cores, rapier on one thread,
//! rapier on all cores, in that order
//! (interleaved, so that a change of the machine's load hits all alike). Timed: the step calls
//! alone, wall time and the process's CPU time (`CLOCK_PROCESS_CPUTIME_ID`, all threads), per
//! simulated second. After every step, untimed: the pairs of boundary triangles that intersect
//! (the exact test of `tests/common/exact_intersection.rs`, Shewchuk's predicates), the deepest
//! penetration of a ball's surface vertex into another ball (inside by the generalised winding
//! number, A. Jacobson, L. Kavan and O. Sorkine-Hornung, "Robust Inside-Outside Segmentation
//! using Generalized Winding Numbers", 2013; depth: its distance to that ball's surface) and into
//! the box (below the ground, beyond a wall's inner face), and each ball's volume against its
//! rest volume. Prints a table and writes every run and the summary into `--out` as CSV.

#[path = "../../../tests/common/ball_pile.rs"]
mod ball_pile;
#[path = "../../../tests/common/exact_intersection.rs"]
mod exact;

use std::fmt::Write as _;
use std::ops::Range;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use rapier3d::prelude as rp;
use softfem::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};
use softfem::body::{Solver, StepReport, VecStorage};
use softfem::glam::{DVec3, Quat, Vec3};
use softfem::material::StableNeoHookean;
use softfem::step::{Collider, HalfSpace, NewtonSettings};
use softfem::world::World;

/// Gravity (m/s^2) along -z.
const GRAVITY: f32 = -9.81;
/// Ball radius (m).
const RADIUS: f64 = 0.04;
/// Half the inner width of the box (m).
const HALF_WIDTH: f64 = 0.09;
/// The balls' material and the friction everywhere.
const YOUNG_MODULUS: f32 = 1e5;
const POISSON_RATIO: f32 = 0.3;
const DENSITY: f32 = 1000.0;
const FRICTION: f32 = 0.3;
/// softfem's Newton tolerance (relative) and iteration budget, as the pile example's.
const TOLERANCE: f32 = 1e-5;
const MAX_ITERATIONS: u32 = 100;
/// The most time steps a run may take.
const MAX_STEPS: usize = 100_000;

/// The eight-ball pile in softfem and in rapier3d 0.36's FEM soft bodies, interleaved.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Args {
    /// Simulated time of each run (s).
    #[arg(long, default_value_t = 2.0)]
    duration: f64,

    /// Repetitions (each: softfem and rapier, each on one thread and on all cores).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    repetitions: u32,

    /// Worker threads of the all-cores runs of both engines (default: the machine's available
    /// parallelism).
    #[arg(long)]
    threads: Option<usize>,

    /// Time step of both engines (s).
    #[arg(long, default_value_t = 0.01)]
    step: f64,

    /// Cells along the side of the cube each ball is mapped from (cells^3 x 5 tetrahedra).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(2..=12))]
    cells: u32,

    /// rapier's contact skin, the soft bodies' particle radius (m); softfem's contact gap dhat
    /// is 1 mm.
    #[arg(long, default_value_t = 1e-3)]
    skin: f32,

    /// Output directory for the CSV files (created if missing).
    #[arg(long, default_value = "target/compare")]
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

/// One ball: its vertices, tetrahedra and boundary triangles as ranges of the pile's lists, and
/// its surface vertices.
struct Ball {
    vertices: Range<usize>,
    tets: Range<usize>,
    triangles: Range<usize>,
    surface: Vec<u32>,
}

/// The pile's balls as one list of vertices (ball after ball), with what the checks need.
struct Pile {
    rest: Vec<Vec3>,
    /// Global vertex indices.
    tets: Vec<[u32; 4]>,
    /// Boundary triangles, global vertex indices, outward (counter-clockwise seen from outside).
    triangles: Vec<[u32; 3]>,
    masses: Vec<f32>,
    balls: Vec<Ball>,
    rest_volumes: Vec<f64>,
}

impl Pile {
    /// The balls of `cells^3` cells, their boundaries and lumped masses (from a softfem world
    /// built from them, so that rapier gets the very masses softfem steps).
    fn new(cells: usize) -> Result<Pile, String> {
        let (mut rest, mut tets, mut triangles, mut balls) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for centre in ball_pile::centres(RADIUS) {
            let (x, t) = ball_pile::ball(centre, RADIUS, cells)?;
            let x: Vec<Vec3> = x
                .iter()
                .map(|p| Vec3::from_array(p.map(|c| c as f32)))
                .collect();
            let mut faces = vec![BoundaryFace::default(); boundary_scratch_len(t.len())];
            let faces = boundary_faces(&t, x.len(), &mut faces).map_err(|e| e.to_string())?;
            let offset = rest.len() as u32;
            let first_triangle = triangles.len();
            triangles.extend(faces.iter().map(|f| f.triangle.map(|v| v + offset)));
            let mut surface: Vec<u32> = faces
                .iter()
                .flat_map(|f| f.triangle)
                .map(|v| v + offset)
                .collect();
            surface.sort_unstable();
            surface.dedup();
            balls.push(Ball {
                vertices: rest.len()..rest.len() + x.len(),
                tets: tets.len()..tets.len() + t.len(),
                triangles: first_triangle..triangles.len(),
                surface,
            });
            rest.extend(x);
            tets.extend(t.iter().map(|tet| tet.map(|v| v + offset)));
        }
        let mut pile = Pile {
            rest,
            tets,
            triangles,
            masses: Vec::new(),
            balls,
            rest_volumes: Vec::new(),
        };
        pile.rest_volumes = pile.volumes(&pile.rest);
        pile.masses = softfem_world(&pile)?.masses().to_vec();
        Ok(pile)
    }

    /// The positions of ball `ball`'s vertices in `rest`, and its tetrahedra (ball-local indices).
    fn ball_mesh(&self, ball: &Ball) -> (Vec<Vec3>, Vec<[u32; 4]>) {
        let first = ball.vertices.start as u32;
        (
            self.rest[ball.vertices.clone()].to_vec(),
            self.tets[ball.tets.clone()]
                .iter()
                .map(|t| t.map(|v| v - first))
                .collect(),
        )
    }

    /// Each ball's volume (m^3) at `x`.
    fn volumes(&self, x: &[Vec3]) -> Vec<f64> {
        let p = |i: u32| x[i as usize].as_dvec3();
        self.balls
            .iter()
            .map(|ball| {
                self.tets[ball.tets.clone()]
                    .iter()
                    .map(|&[a, b, c, d]| (p(b) - p(a)).cross(p(c) - p(a)).dot(p(d) - p(a)) / 6.0)
                    .sum()
            })
            .collect()
    }

    /// The deepest penetration (m) of a ball's surface vertex into another ball at `x`: the
    /// vertex inside that ball's closed surface (generalised winding number above 1/2), depth its
    /// distance to that surface. 0 if no vertex is inside another ball.
    fn deepest_between_balls(&self, x: &[Vec3]) -> f64 {
        let p = |i: u32| x[i as usize].as_dvec3();
        let mut deepest = 0.0f64;
        for (j, other) in self.balls.iter().enumerate() {
            let (low, high) = x[other.vertices.clone()]
                .iter()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), v| {
                    (l.min(v.as_dvec3()), h.max(v.as_dvec3()))
                });
            let triangles = &self.triangles[other.triangles.clone()];
            for (i, ball) in self.balls.iter().enumerate() {
                if i == j {
                    continue;
                }
                for &v in &ball.surface {
                    let q = p(v);
                    if q.cmplt(low).any() || q.cmpgt(high).any() {
                        continue;
                    }
                    let winding: f64 = triangles
                        .iter()
                        .map(|&[a, b, c]| solid_angle(p(a) - q, p(b) - q, p(c) - q))
                        .sum::<f64>()
                        / (4.0 * std::f64::consts::PI);
                    if winding > 0.5 {
                        let depth = triangles
                            .iter()
                            .map(|&[a, b, c]| point_triangle_distance(q, p(a), p(b), p(c)))
                            .fold(f64::INFINITY, f64::min);
                        deepest = deepest.max(depth);
                    }
                }
            }
        }
        deepest
    }
}

/// The deepest penetration (m) of any vertex at `x` into the box: below the ground `z = 0`, and
/// beyond a wall's inner face `|x|, |y| = HALF_WIDTH`; 0 if none.
fn deepest_into_box(x: &[Vec3]) -> (f64, f64) {
    x.iter().fold((0.0f64, 0.0f64), |(ground, walls), v| {
        let v = v.as_dvec3();
        let beyond = (v.x.abs() - HALF_WIDTH).max(v.y.abs() - HALF_WIDTH);
        (ground.max(-v.z), walls.max(beyond))
    })
}

/// The signed solid angle (sr) of the triangle `a b c` seen from the origin (A. van Oosterom and
/// J. Strackee, "The Solid Angle of a Plane Triangle", IEEE Trans. Biomed. Eng. 30(2), 1983):
/// positive when the triangle is clockwise seen from the origin, so that a point inside a closed
/// surface of outward (counter-clockwise from outside) triangles sees 4 pi in all.
fn solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let numerator = a.dot(b.cross(c));
    let denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * numerator.atan2(denominator)
}

/// The distance (m) from `p` to the triangle `a b c` (C. Ericson, "Real-Time Collision
/// Detection", 2005, section 5.1.5: the closest point by its Voronoi region).
fn point_triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return p.distance(a);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return p.distance(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return p.distance(a + ab * (d1 / (d1 - d3)));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return p.distance(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return p.distance(a + ac * (d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return p.distance(b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let denominator = 1.0 / (va + vb + vc);
    p.distance(a + ab * (vb * denominator) + ac * (vc * denominator))
}

/// The CPU time (s) this process's threads have used so far.
fn process_cpu_time() -> f64 {
    let mut time = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `time` is a valid, writable timespec; the clock id is a constant of the platform.
    let status = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut time) };
    if status != 0 {
        return f64::NAN;
    }
    time.tv_sec as f64 + time.tv_nsec as f64 * 1e-9
}

/// The softfem world of the pile: a body per ball, gravity, the ground, friction, Newton.
fn softfem_world(pile: &Pile) -> Result<World<VecStorage, StableNeoHookean>, String> {
    let material = StableNeoHookean::from_young_poisson(YOUNG_MODULUS, POISSON_RATIO)
        .map_err(|e| e.to_string())?;
    let mut world = World::<VecStorage, StableNeoHookean>::new();
    for ball in &pile.balls {
        let (x, tets) = pile.ball_mesh(ball);
        world
            .add_body(&x, &tets, DENSITY, material)
            .map_err(|e| e.to_string())?;
    }
    world.set_gravity(Vec3::new(0.0, 0.0, GRAVITY));
    world.set_ground(Some(HalfSpace::new(Vec3::Z, 0.0).with_friction(FRICTION)));
    world.set_friction(FRICTION).map_err(|e| e.to_string())?;
    world
        .set_solver(Solver::Newton(
            NewtonSettings::new().with_tolerance(TOLERANCE, MAX_ITERATIONS),
        ))
        .map_err(|e| e.to_string())?;
    Ok(world)
}

/// The box's four walls for softfem: the shared scene's boxes with the pile's friction.
fn softfem_walls() -> Vec<Collider<'static>> {
    let vec3 = |p: [f64; 3]| Vec3::from_array(p.map(|c| c as f32));
    ball_pile::walls(HALF_WIDTH)
        .into_iter()
        .map(|(centre, half)| {
            Collider::cuboid(vec3(centre), vec3(half), Quat::IDENTITY).with_friction(FRICTION)
        })
        .collect()
}

/// Which engine, on how many threads.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Engine {
    Softfem { threads: usize },
    Rapier { threads: usize },
}

impl Engine {
    fn name(self) -> &'static str {
        match self {
            Engine::Softfem { .. } => "softfem",
            Engine::Rapier { .. } => "rapier",
        }
    }

    fn threads(self) -> usize {
        match self {
            Engine::Softfem { threads } | Engine::Rapier { threads } => threads,
        }
    }
}

/// What one run measured.
#[derive(Clone, Debug, Default)]
struct Run {
    steps: usize,
    /// The step calls' wall time and the process's CPU time over them (s).
    wall: f64,
    cpu: f64,
    /// softfem's Newton solves: converged, stopped at the f32 rounding floor, iterations.
    converged: usize,
    stagnated: usize,
    iterations: u64,
    /// Intersecting triangle pairs summed over the steps, the steps with any, the most after one
    /// step.
    intersecting: usize,
    intersecting_steps: usize,
    most_intersecting: usize,
    /// The deepest penetrations (m) over the steps: ball into ball, into the ground, into a
    /// wall.
    deepest_balls: f64,
    deepest_ground: f64,
    deepest_walls: f64,
    /// The smallest and largest ball volume over rest volume over the steps.
    volume_low: f64,
    volume_high: f64,
}

impl Run {
    fn new() -> Run {
        Run {
            volume_low: f64::INFINITY,
            volume_high: f64::NEG_INFINITY,
            ..Run::default()
        }
    }

    /// Adds the untimed checks of the positions `x` after a step.
    fn check(&mut self, pile: &Pile, x: &[Vec3]) {
        let crossing = exact::intersecting_pairs_f32(x, &pile.triangles).len();
        self.intersecting += crossing;
        self.intersecting_steps += usize::from(crossing > 0);
        self.most_intersecting = self.most_intersecting.max(crossing);
        self.deepest_balls = self.deepest_balls.max(pile.deepest_between_balls(x));
        let (ground, walls) = deepest_into_box(x);
        self.deepest_ground = self.deepest_ground.max(ground);
        self.deepest_walls = self.deepest_walls.max(walls);
        for (volume, rest) in pile.volumes(x).iter().zip(&pile.rest_volumes) {
            let ratio = volume / rest;
            self.volume_low = self.volume_low.min(ratio);
            self.volume_high = self.volume_high.max(ratio);
        }
    }
}

/// `steps` steps of `dt` of the pile in softfem, on the calling thread (`threads` 1) or on a
/// pool of `threads` threads.
fn run_softfem(pile: &Pile, steps: usize, dt: f64, threads: usize) -> Result<Run, String> {
    let mut world = softfem_world(pile)?;
    if threads > 1 {
        world.set_threads(threads).map_err(|e| e.to_string())?;
    }
    let walls = softfem_walls();
    let mut run = Run::new();
    for step in 0..steps {
        let (wall, cpu) = (Instant::now(), process_cpu_time());
        let report = world.step_with_colliders(dt as f32, &walls);
        run.cpu += process_cpu_time() - cpu;
        run.wall += wall.elapsed().as_secs_f64();
        let report = report.map_err(|e| format!("softfem step {step}: {e}"))?;
        run.steps += 1;
        run.converged += usize::from(report.converged());
        if let StepReport::Newton(newton) = report {
            run.stagnated += usize::from(!newton.converged && newton.stagnated);
            run.iterations += u64::from(newton.iterations);
        }
        run.check(pile, world.positions());
    }
    Ok(run)
}

/// A rapier vector from an `[x, y, z]` array.
fn rapier_vector(p: [f32; 3]) -> rp::Vector {
    rp::Vector::new(p[0], p[1], p[2])
}

/// `steps` steps of `dt` of the pile in rapier on a pool of `threads` workers, its contact skin
/// `skin` (m).
fn run_rapier(
    pile: &Pile,
    steps: usize,
    dt: f64,
    threads: usize,
    skin: f32,
) -> Result<Run, String> {
    let mut world = rp::PhysicsWorld::new();
    world
        .configure_thread_pool(threads)
        .map_err(|e| format!("rapier's thread pool of {threads}: {e}"))?;
    world.gravity = rp::Vector::new(0.0, 0.0, GRAVITY);
    world.integration_parameters.dt = dt as f32;
    // The ground: a fixed box whose top face is z = 0, wider than the box of walls.
    world.insert(
        rp::RigidBodyBuilder::fixed().translation(rp::Vector::new(0.0, 0.0, -0.5)),
        rp::ColliderBuilder::cuboid(1.0, 1.0, 0.5).friction(FRICTION),
    );
    for (centre, half) in ball_pile::walls(HALF_WIDTH) {
        let (centre, half) = (centre.map(|c| c as f32), half.map(|c| c as f32));
        world.insert(
            rp::RigidBodyBuilder::fixed().translation(rapier_vector(centre)),
            rp::ColliderBuilder::cuboid(half[0], half[1], half[2]).friction(FRICTION),
        );
    }
    let material = rp::SoftBodyMaterial {
        young_modulus: YOUNG_MODULUS,
        poisson_ratio: POISSON_RATIO,
        elastic_damping_ratio: 0.0,
        ..Default::default()
    };
    let handles: Vec<rp::SoftBodyHandle> = pile
        .balls
        .iter()
        .map(|ball| {
            let (x, tets) = pile.ball_mesh(ball);
            let body =
                rp::SoftBodyBuilder::new(x.iter().map(|p| rapier_vector(p.to_array())).collect())
                    .cells(tets)
                    .masses(pile.masses[ball.vertices.clone()].to_vec())
                    .material(material)
                    .cell_model(rp::SoftBodyCellModel::NeoHookean)
                    .solver(rp::SoftBodySolver::Fem)
                    .self_contacts(true)
                    .particle_radius(skin)
                    // The collider of the body's boundary: only its friction is read (the shape is
                    // the boundary's, the mass the particles').
                    .surface_collider(
                        rp::ColliderBuilder::ball(0.05)
                            .density(0.0)
                            .friction(FRICTION),
                    );
            world.insert_soft_body(body)
        })
        .collect();
    let mut run = Run::new();
    let mut x = vec![Vec3::ZERO; pile.rest.len()];
    for _ in 0..steps {
        let (wall, cpu) = (Instant::now(), process_cpu_time());
        world.step();
        run.cpu += process_cpu_time() - cpu;
        run.wall += wall.elapsed().as_secs_f64();
        run.steps += 1;
        for (ball, &handle) in pile.balls.iter().zip(&handles) {
            let body = &world.soft_bodies[handle];
            if body.num_particles() != ball.vertices.len() {
                return Err(format!(
                    "rapier's ball {handle:?} has {} particles, not {}",
                    body.num_particles(),
                    ball.vertices.len()
                ));
            }
            for (slot, p) in x[ball.vertices.clone()]
                .iter_mut()
                .zip(body.particle_positions())
            {
                *slot = Vec3::new(p.x, p.y, p.z);
            }
        }
        if let Some(v) = x.iter().position(|p| !p.is_finite()) {
            return Err(format!(
                "rapier: vertex {v} is not finite after step {}",
                run.steps
            ));
        }
        run.check(pile, &x);
    }
    Ok(run)
}

/// The median of `values` (the mean of the middle two for an even count).
fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        sorted[n / 2]
    } else {
        (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0
    }
}

fn run(args: &Args) -> Result<(), String> {
    let positive = |value: f64| value.is_finite() && value > 0.0;
    if !(positive(args.duration) && positive(args.step) && positive(f64::from(args.skin))) {
        return Err("--duration, --step and --skin must be finite and positive".into());
    }
    let step_count = (args.duration / args.step).round().max(1.0);
    if step_count > MAX_STEPS as f64 {
        return Err(format!(
            "--duration {} asks for {step_count:.3e} steps of {} s; at most {MAX_STEPS}",
            args.duration, args.step
        ));
    }
    let steps = step_count as usize;
    let simulated = steps as f64 * args.step;
    let available = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = args.threads.unwrap_or(available);
    if threads == 0 {
        return Err("--threads must be at least 1".into());
    }
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;

    let pile = Pile::new(args.cells as usize)?;
    if !exact::intersecting_pairs_f32(&pile.rest, &pile.triangles).is_empty() {
        return Err("the balls intersect at the start".into());
    }
    println!(
        "pile      8 balls of radius {RADIUS} m, {} cells^3 each: {} vertices, {} tetrahedra, {} boundary triangles, {:.3} kg",
        args.cells,
        pile.rest.len(),
        pile.tets.len(),
        pile.triangles.len(),
        pile.masses.iter().map(|&m| f64::from(m)).sum::<f64>()
    );
    println!(
        "material  stable neo-Hookean, E = {YOUNG_MODULUS} Pa, nu = {POISSON_RATIO}, {DENSITY} kg/m^3; friction {FRICTION}; h = {} s, {steps} steps",
        args.step
    );
    println!(
        "softfem   World, f32, Newton (tolerance {TOLERANCE}, at most {MAX_ITERATIONS} iterations), dhat 1 mm; 1 and {threads} threads"
    );
    println!(
        "rapier    0.36 PhysicsWorld, SoftBodySolver::Fem, NeoHookean cells, skin {} m, 4 solver iterations; 1 and {threads} threads",
        args.skin
    );
    println!("machine   {available} logical CPUs");

    let engines = [
        Engine::Softfem { threads: 1 },
        Engine::Softfem { threads },
        Engine::Rapier { threads: 1 },
        Engine::Rapier { threads },
    ];
    let mut runs: Vec<(u32, Engine, Run)> = Vec::new();
    for repetition in 1..=args.repetitions {
        for &engine in &engines {
            let run = match engine {
                Engine::Softfem { threads } => run_softfem(&pile, steps, args.step, threads)?,
                Engine::Rapier { threads } => {
                    run_rapier(&pile, steps, args.step, threads, args.skin)?
                }
            };
            println!(
                "run {repetition}     {:<7} {} thread(s): {:7.2} s wall, {:7.2} s CPU per simulated s; {} intersecting pairs",
                engine.name(),
                engine.threads(),
                run.wall / simulated,
                run.cpu / simulated,
                run.intersecting
            );
            runs.push((repetition, engine, run));
        }
    }

    // One CSV row per run.
    let mut csv = String::from(
        "repetition,engine,threads,steps,simulated_s,wall_s,cpu_s,wall_per_simulated_s,cpu_per_simulated_s,converged,stagnated,newton_iterations,intersecting_pairs,steps_with_intersections,most_pairs_in_a_step,deepest_ball_into_ball_m,deepest_into_ground_m,deepest_into_wall_m,volume_ratio_min,volume_ratio_max\n",
    );
    for (repetition, engine, run) in &runs {
        let _ = writeln!(
            csv,
            "{repetition},{},{},{},{simulated},{:.6},{:.6},{:.6},{:.6},{},{},{},{},{},{},{:.6e},{:.6e},{:.6e},{:.6},{:.6}",
            engine.name(),
            engine.threads(),
            run.steps,
            run.wall,
            run.cpu,
            run.wall / simulated,
            run.cpu / simulated,
            run.converged,
            run.stagnated,
            run.iterations,
            run.intersecting,
            run.intersecting_steps,
            run.most_intersecting,
            run.deepest_balls,
            run.deepest_ground,
            run.deepest_walls,
            run.volume_low,
            run.volume_high
        );
    }
    let path = args.out.join("pile_vs_rapier.csv");
    std::fs::write(&path, csv).map_err(|e| format!("cannot write {}: {e}", path.display()))?;

    // The summary: per engine and thread count, min and median over the repetitions.
    println!();
    println!(
        "{:<8} {:>7} {:>21} {:>21} {:>10} {:>15} {:>8} {:>8} {:>8} {:>13}",
        "engine",
        "threads",
        "wall/sim s min, med",
        "CPU/sim s min, med",
        "converged",
        "pairs (steps)",
        "ball mm",
        "ground",
        "wall",
        "volume/rest"
    );
    for &engine in &engines {
        let of: Vec<&Run> = runs
            .iter()
            .filter(|(_, e, _)| *e == engine)
            .map(|(_, _, r)| r)
            .collect();
        let wall_times: Vec<f64> = of.iter().map(|r| r.wall / simulated).collect();
        let cpus: Vec<f64> = of.iter().map(|r| r.cpu / simulated).collect();
        let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        let converged = match engine {
            Engine::Softfem { .. } => format!(
                "{:.1} %",
                100.0 * of.iter().map(|r| r.converged).sum::<usize>() as f64
                    / of.iter().map(|r| r.steps).sum::<usize>() as f64
            ),
            Engine::Rapier { .. } => "n/a".into(),
        };
        let pairs = of.iter().map(|r| r.intersecting).max().unwrap_or(0);
        let pair_steps = of.iter().map(|r| r.intersecting_steps).max().unwrap_or(0);
        let ball = of.iter().map(|r| r.deepest_balls).fold(0.0, f64::max);
        let ground = of.iter().map(|r| r.deepest_ground).fold(0.0, f64::max);
        let walls = of.iter().map(|r| r.deepest_walls).fold(0.0, f64::max);
        let low = of
            .iter()
            .map(|r| r.volume_low)
            .fold(f64::INFINITY, f64::min);
        let high = of
            .iter()
            .map(|r| r.volume_high)
            .fold(f64::NEG_INFINITY, f64::max);
        println!(
            "{:<8} {:>7} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>10} {:>8} ({:>4}) {:>8.3} {:>8.3} {:>8.3} {:>6.3}-{:.3}",
            engine.name(),
            engine.threads(),
            min(&wall_times),
            median(&wall_times),
            min(&cpus),
            median(&cpus),
            converged,
            pairs,
            pair_steps,
            ball * 1e3,
            ground * 1e3,
            walls * 1e3,
            low,
            high
        );
    }
    println!(
        "(per simulated second of {} steps; pairs: intersecting boundary triangle pairs summed over the steps, the most over the repetitions, (steps with any); ball, ground, wall: deepest penetration (mm) of a vertex into another ball, below the ground, beyond a wall)",
        steps
    );
    println!("wrote     {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The eight outward triangles of the octahedron with corners `+-r` on the axes.
    fn octahedron(r: f64) -> Vec<[DVec3; 3]> {
        let mut faces = Vec::new();
        for sx in [1.0, -1.0] {
            for sy in [1.0, -1.0] {
                for sz in [1.0, -1.0] {
                    let (a, b, c) = (DVec3::X * sx * r, DVec3::Y * sy * r, DVec3::Z * sz * r);
                    // Counter-clockwise seen from outside: flip for an odd number of minus signs.
                    if sx * sy * sz > 0.0 {
                        faces.push([a, b, c]);
                    } else {
                        faces.push([a, c, b]);
                    }
                }
            }
        }
        faces
    }

    fn winding(faces: &[[DVec3; 3]], q: DVec3) -> f64 {
        faces
            .iter()
            .map(|[a, b, c]| solid_angle(*a - q, *b - q, *c - q))
            .sum::<f64>()
            / (4.0 * std::f64::consts::PI)
    }

    #[test]
    fn winding_number_is_one_inside_and_zero_outside() {
        let faces = octahedron(1.0);
        for q in [
            DVec3::ZERO,
            DVec3::new(0.2, -0.3, 0.1),
            DVec3::new(0.0, 0.0, 0.99),
        ] {
            assert!((winding(&faces, q) - 1.0).abs() < 1e-12, "{q}");
        }
        for q in [
            DVec3::splat(0.5),
            DVec3::new(0.0, 0.0, 1.01),
            DVec3::new(3.0, 0.0, 0.0),
        ] {
            assert!(winding(&faces, q).abs() < 1e-12, "{q}");
        }
        // One face seen from the centre: an eighth of the sphere.
        let [a, b, c] = faces[0];
        assert!((solid_angle(a, b, c) - std::f64::consts::PI / 2.0).abs() < 1e-12);
    }

    #[test]
    fn point_triangle_distance_in_every_region() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let cases = [
            // Above the face: the height.
            (DVec3::new(0.25, 0.25, 0.5), 0.5),
            // Beyond each corner.
            (DVec3::new(-1.0, -1.0, 0.0), 2f64.sqrt()),
            (DVec3::new(2.0, 0.0, 1.0), 2f64.sqrt()),
            (DVec3::new(0.0, 3.0, 0.0), 2.0),
            // Beyond each edge.
            (DVec3::new(0.5, -2.0, 0.0), 2.0),
            (DVec3::new(-0.5, 0.5, 0.0), 0.5),
            (DVec3::new(1.0, 1.0, 0.0), 0.5f64.sqrt()),
        ];
        for (p, expected) in cases {
            let d = point_triangle_distance(p, a, b, c);
            assert!((d - expected).abs() < 1e-12, "{p}: {d} against {expected}");
        }
    }

    #[test]
    fn a_vertex_pushed_into_another_ball_is_measured() {
        let pile = Pile::new(2).unwrap();
        let mut x = pile.rest.clone();
        assert_eq!(pile.deepest_between_balls(&x), 0.0);
        assert_eq!(deepest_into_box(&x), (0.0, 0.0));
        // Move the first surface vertex of ball 1 onto ball 0's centre: a radius deep.
        let centre = ball_pile::centres(RADIUS)[0];
        let v = pile.balls[1].surface[0] as usize;
        x[v] = Vec3::from_array(centre.map(|c| c as f32));
        let depth = pile.deepest_between_balls(&x);
        // The ball's surface is a polyhedron inscribed in the sphere: its nearest face is closer
        // than the radius but not by more than the flattening of a 2 x 2 cell face.
        assert!(depth < RADIUS && depth > 0.7 * RADIUS, "{depth}");
        x[v] = Vec3::new(0.095, 0.0, -0.002);
        let (ground, walls) = deepest_into_box(&x);
        let (below, beyond) = (f64::from(0.002f32), f64::from(0.095f32) - HALF_WIDTH);
        assert_eq!((ground, walls), (below, beyond));
    }
}

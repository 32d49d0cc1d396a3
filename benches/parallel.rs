//! Many cores, same bits: the partitioned passes (`mesh::TetPartition`) on rayon pools of 1, 2
//! and all cores' threads (`softfem::parallel`, feature `rayon`) against the sequential code, on
//! boxes of 105 456 and 998 250 tetrahedra (the unit cube in 26^3 and 55^3 Kuhn cells).
//!
//! Workloads (f32):
//! * `forces`: StVK direct forces (`TetMesh::add_elastic_forces`) at both sizes: the sequential
//!   kernel, the partitioned scheme run piece by piece on this thread
//!   (`TetPartition::add_elastic_forces`: the work the pieces of the largest pool do, cut
//!   elements included, on one thread), and `parallel::add_elastic_forces` on each pool (the
//!   one-thread pool runs all pieces as one span: nothing cut).
//! * `fused pass`: the relaxation's fused energy-and-force pass (stable neo-Hookean) at 105k
//!   tets: `ElasticEnergy::energy_and_add_forces` of `TetElastic`, the partitioned scheme piece
//!   by piece on this thread (`TetPartition::energy_and_add_forces`) and
//!   `parallel::energy_and_add_forces` on each pool.
//! * `explicit step`: one `explicit_step` of stable neo-Hookean (half the proven stable step, the
//!   box falling from rest) at 105k tets, on `TetElastic` and on `ParallelTetElastic` (called
//!   from the timing thread, and with the whole step inside the pool's `install`).
//! * `relaxation iteration`: `relax_step` (1/60 s, Chebyshev defaults, tolerance 0 so it runs its
//!   whole budget of 10 iterations) of the box resting on the ground under gravity, from the same
//!   state every run; the time per iteration (initial guess and end of step included, spread
//!   over the 10); the parallel body as for the explicit step, both ways.
//! * `Newton step`: `newton_step` (1/60 s, tolerance 0, 1 Newton iteration of at most 20 CG
//!   iterations) of the box resting on the ground, from the same state every run; the
//!   parallel body as for the explicit step, both ways (Hessians, products and CG vector
//!   operations on the pool).
//!
//! * `triad`: a STREAM-like triad (`a = b + s c`, f32, 3 x 64 MiB as in `benches/forces.rs`) on
//!   each pool, the arrays cut into one part per thread (each thread its own part, the same
//!   total bytes on every pool), and from it the force pass's bandwidth ceiling on each pool:
//!   triad GB/s over the bytes a pass must move per tet (16 of indices and 40 of `TetRest` per
//!   element evaluated, cut elements once per task; 36 per vertex for its position read and its
//!   force read and written back; the gathers and scatters at the corners hit cache beyond
//!   that), beside the measured rate, and the bound it puts on the speed-up (the ceiling of
//!   the pool over the one-thread rate).
//!
//! The steppers' own passes over the vertices run on the pool too (in blocks of
//! `step::vertex_pass::VERTEX_BLOCK` vertices through `ElasticModel::run_vertex_pass`); the
//! tables give their share of a sequential step (1 - element passes / step, from the stable
//! neo-Hookean force and fused-pass rows measured in the same run).
//!
//! Every row is timed by one round-robin pass over all variants of a workload (the minimum of
//! several rounds, a 20 ms pause before every timed block so that the pools' idle workers have
//! gone to sleep), so ratios come from one machine state. The force and fused workloads also
//! print the thread CPU time of the pieces run on the timing thread against the sequential pass:
//! the scheme's one-thread cost, robust to other processes taking the core (not to their cache
//! traffic). The force and fused workloads also give the speed-ups of the fastest single runs
//! (every run of a block timed on its own): on a shared machine another process taking either
//! core during a block slows a two-thread block, so a loaded run's block ratios fall well short
//! of what the cores do when both are free. The caption and the force tables give the load
//! average. `SOFTFEM_BENCH_CSV=<path>` appends
//! every row (`bench,workload,size,lanes,threads,value,unit`) plus the derived ratios (the
//! scheme's one-thread cost, the speed-ups, the vertex passes' share) to a CSV file.
//! `SOFTFEM_BENCH_THREADS=1,2,4,8,16` picks other pool sizes (default: 1, 2 and all cores).
//! `SOFTFEM_BENCH_QUICK=1` is a smoke test (the small box only, few repetitions).
//!
//! `cargo bench -p softfem-benches --features rayon --bench parallel` takes about a minute and a
//! half on two cores.

mod common;

use std::hint::black_box;
use std::time::Instant;

use common::{CsvRow, TablePass};
use softfem::element::TetHessian;
use softfem::element::TetRest;
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::{Mat3, Vec3};
use softfem::material::{StVK, StableNeoHookean};
use softfem::mesh::{
    ElementForces, TetMesh, TetPartition, element_forces_len, partition_incident_len,
    partition_offsets_len,
};
use softfem::parallel::ParallelTetElastic;
use softfem::step::{
    ElasticEnergy, ElasticHessian, ElasticModel, ExplicitScratch, ExplicitSettings, HalfSpace,
    NewtonScratch, NewtonSettings, RelaxScratch, RelaxSettings, Scene as StepScene, TetElastic,
    explicit_step, newton_step, relax_step, scratch_len, stable_time_step,
};

/// Cells per axis of the two boxes: 105 456 and 998 250 tetrahedra.
const CELLS: [usize; 2] = [26, 55];

/// Young's modulus (Pa) and Poisson ratio: a soft rubber.
const YOUNG: f32 = 1.0e6;
const POISSON: f32 = 0.45;

/// The relaxation's iteration budget per timed step.
const RELAX_ITERATIONS: u32 = 10;

/// Newton's iteration budget per timed step, and its CG budget per iteration.
const NEWTON_ITERATIONS: u32 = 1;
const NEWTON_CG_ITERATIONS: u32 = 20;

/// Element and vertex pieces per thread of the largest pool. One: the direct force pass
/// evaluates the elements cut by a vertex-piece boundary once per piece, so the fewer pieces the
/// less redundant work, and the box's load is uniform (the bits do not depend on it).
const PIECES_PER_THREAD: usize = 1;

/// The pool sizes: `SOFTFEM_BENCH_THREADS` (comma-separated) or 1, 2 and all cores.
fn thread_counts() -> Vec<usize> {
    if let Ok(list) = std::env::var("SOFTFEM_BENCH_THREADS") {
        return list
            .split(',')
            .map(|n| {
                n.trim()
                    .parse()
                    .expect("SOFTFEM_BENCH_THREADS: a list of counts")
            })
            .collect();
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut counts = vec![1, 2];
    if cores > 2 {
        counts.push(cores);
    }
    counts
}

/// A rayon pool of `threads` threads, alive for the whole run.
fn pool(threads: usize) -> &'static rayon::ThreadPool {
    Box::leak(Box::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap(),
    ))
}

/// A box of `cells^3` Kuhn cells (the unit cube), its mesh, a partition and a deformed state
/// (a general affine map plus jitter, as in `benches/forces.rs`), all leaked: they live for the
/// whole run.
struct Scene {
    rest_positions: &'static [Vec3],
    positions: &'static [Vec3],
    mesh: TetMesh<'static>,
    partition: TetPartition<'static>,
}

impl Scene {
    /// The lumped masses (kg) of the box at 1000 kg/m^3.
    fn masses(&self) -> Vec<f32> {
        let mut masses = vec![0.0; self.mesh.vertex_count()];
        self.mesh.lumped_masses(1000.0, &mut masses).unwrap();
        masses
    }

    fn new(cells: usize, pieces: usize) -> Self {
        let (vertices, tets) = box_counts(cells, cells, cells, BoxSplit::Kuhn6).unwrap();
        let rest_positions = vec![Vec3::ZERO; vertices].leak();
        let elements = vec![[0u32; 4]; tets].leak();
        fill_box(
            Vec3::ZERO,
            Vec3::ONE,
            cells,
            cells,
            cells,
            BoxSplit::Kuhn6,
            rest_positions,
            elements,
        )
        .unwrap();
        let affine = Mat3::from_cols(
            Vec3::new(1.10, -0.10, 0.05),
            Vec3::new(0.15, 0.95, -0.12),
            Vec3::new(-0.05, 0.20, 1.05),
        );
        let amplitude = 0.08 / cells as f32;
        let mut rng = common::XorShift64Star(0x5eed_f0ce_5b0c_2026);
        let mut jitter = || rng.next_signed_unit() * amplitude;
        let positions: Vec<Vec3> = rest_positions
            .iter()
            .map(|&x| affine * x + Vec3::new(jitter(), jitter(), jitter()))
            .collect();
        let rest = vec![TetRest::default(); tets].leak();
        let mesh = TetMesh::new(rest_positions, elements, rest).unwrap();
        let offsets = vec![0; partition_offsets_len(vertices)].leak();
        let incident = vec![0; partition_incident_len(tets)].leak();
        let partition = TetPartition::new(mesh, pieces, offsets, incident).unwrap();
        Scene {
            rest_positions,
            positions: positions.leak(),
            mesh,
            partition,
        }
    }

    /// A `TetElastic` of stable neo-Hookean on this mesh and its parallel form on `pool`.
    fn stable_bodies(
        &self,
        pool: Option<&'static rayon::ThreadPool>,
    ) -> (
        TetElastic<'static, StableNeoHookean>,
        Option<ParallelTetElastic<'static, StableNeoHookean>>,
    ) {
        let material = StableNeoHookean::from_young_poisson(YOUNG, POISSON).unwrap();
        let body = TetElastic::new(self.mesh, material);
        let parallel = pool.map(|pool| {
            let ne = self.mesh.element_count();
            let element_forces = vec![[Vec3::ZERO; 4]; element_forces_len(ne)].leak();
            let energies = vec![0.0; ne].leak();
            ParallelTetElastic::new(body, self.partition, element_forces, energies)
                .unwrap()
                .with_pool(pool)
        });
        (body, parallel)
    }
}

/// A timed variant: a label, its thread count (0: the sequential code) and one run.
struct Variant {
    label: String,
    threads: usize,
    run: Box<dyn FnMut() + Send>,
}

/// The label of a variant on `threads` (0: sequential).
fn on(threads: usize) -> String {
    match threads {
        0 => "sequential".to_owned(),
        1 => "rayon, 1 thread".to_owned(),
        n => format!("rayon, {n} threads"),
    }
}

/// The scratch of a partitioned pass: one element-forces entry and one energy per element.
struct Scratch {
    element_forces: Vec<ElementForces>,
    energies: Vec<f32>,
}

/// One run of a force-like pass: adds into the forces at the positions, with its scratch.
type PassRun = dyn Fn(&[Vec3], &mut [Vec3], &mut Scratch) + Send + Sync;

/// A pass on `scene` as variants: `sequential`, `scheme` (the partitioned pieces on this
/// thread), then `parallel` on each pool. Each variant has its own buffers and zeroes its forces
/// before every run.
fn pass_variants(
    scene: &Scene,
    pools: &[(usize, &'static rayon::ThreadPool)],
    sequential: Box<PassRun>,
    scheme: Box<PassRun>,
    parallel: Box<PassRun>,
) -> Vec<Variant> {
    let x = scene.positions;
    let (nv, ne) = (scene.mesh.vertex_count(), scene.mesh.element_count());
    let parallel: std::sync::Arc<PassRun> = parallel.into();
    let variant = |label: String, threads, pool: Option<&'static rayon::ThreadPool>, pass| {
        let pass: std::sync::Arc<PassRun> = pass;
        let mut forces = vec![Vec3::ZERO; nv];
        let mut scratch = Scratch {
            element_forces: vec![[Vec3::ZERO; 4]; ne],
            energies: vec![0.0; ne],
        };
        Variant {
            label,
            threads,
            run: Box::new(move || {
                forces.fill(Vec3::ZERO);
                let mut run = || pass(black_box(x), &mut forces, &mut scratch);
                match pool {
                    Some(pool) => pool.install(run),
                    None => run(),
                }
                black_box(&forces);
            }),
        }
    };
    let mut variants = vec![
        variant(on(0), 0, None, sequential.into()),
        variant(
            "partitioned, pieces on this thread".to_owned(),
            1,
            None,
            scheme.into(),
        ),
    ];
    for &(threads, pool) in pools {
        variants.push(variant(on(threads), threads, Some(pool), parallel.clone()));
    }
    variants
}

/// StVK direct forces on `scene`: sequential, pieces on this thread, then each pool.
fn force_variants(scene: &Scene, pools: &[(usize, &'static rayon::ThreadPool)]) -> Vec<Variant> {
    let stvk = StVK::from_young_poisson(YOUNG, POISSON).unwrap();
    let (mesh, partition) = (scene.mesh, scene.partition);
    pass_variants(
        scene,
        pools,
        Box::new(move |x, forces, _| mesh.add_elastic_forces(&stvk, x, forces).unwrap()),
        Box::new(move |x, forces, scratch| {
            partition
                .add_elastic_forces(&stvk, x, forces, &mut scratch.element_forces)
                .unwrap();
        }),
        Box::new(move |x, forces, scratch| {
            softfem::parallel::add_elastic_forces(
                &partition,
                &stvk,
                x,
                forces,
                &mut scratch.element_forces,
            )
            .unwrap();
        }),
    )
}

/// The fused energy-and-force pass of stable neo-Hookean (the relaxation's) on `scene`:
/// sequential, pieces on this thread, then each pool. Every variant checks its energy is finite
/// (beyond the material's range the pass computes nothing).
fn fused_variants(scene: &Scene, pools: &[(usize, &'static rayon::ThreadPool)]) -> Vec<Variant> {
    let (body, _) = scene.stable_bodies(None);
    let (material, partition) = (body.material, scene.partition);
    let finite = |energy: f32| assert!(energy.is_finite(), "the pass computed nothing");
    pass_variants(
        scene,
        pools,
        Box::new(move |x, forces, _| finite(body.energy_and_add_forces(x, forces).unwrap())),
        Box::new(move |x, forces, scratch| {
            let Scratch {
                element_forces,
                energies,
            } = scratch;
            let energy = partition
                .energy_and_add_forces(&material, x, forces, element_forces, energies)
                .unwrap();
            finite(energy);
        }),
        Box::new(move |x, forces, scratch| {
            let Scratch {
                element_forces,
                energies,
            } = scratch;
            let energy = softfem::parallel::energy_and_add_forces(
                &partition,
                &material,
                x,
                forces,
                element_forces,
                energies,
            )
            .unwrap();
            finite(energy);
        }),
    )
}

/// One explicit step of any model, falling from rest (the state carries on between runs).
fn explicit_variant<F: ElasticModel<Vector = Vec3> + Send + Sync + 'static>(
    label: String,
    threads: usize,
    model: F,
    scene: &Scene,
    installed: Option<&'static rayon::ThreadPool>,
) -> Variant {
    let (n, masses) = (scene.mesh.vertex_count(), scene.masses());
    let mut stiffness = vec![0.0; n];
    let dt = 0.5 * stable_time_step(&model, &masses, &[], &mut stiffness).unwrap();
    let step_scene = StepScene::new(dt).with_gravity(Vec3::new(0.0, -9.81, 0.0));
    let settings = ExplicitSettings::new();
    let (mut x, mut v) = (scene.rest_positions.to_vec(), vec![Vec3::ZERO; n]);
    let scratch = vec![Vec3::ZERO; scratch_len::explicit(n)].leak();
    let mut scratch = ExplicitScratch::new(scratch);
    Variant {
        label,
        threads,
        run: Box::new(move || {
            let step = || {
                explicit_step(
                    &model,
                    &masses,
                    &[],
                    &step_scene,
                    &settings,
                    &mut x,
                    &mut v,
                    &mut scratch,
                )
                .unwrap();
            };
            on_installed(installed, step);
        }),
    }
}

/// `run` inside `pool.install` if given (the whole step on the pool: its passes then start
/// there without crossing threads), else on the timing thread.
fn on_installed<T: Send>(
    pool: Option<&'static rayon::ThreadPool>,
    run: impl FnOnce() -> T + Send,
) -> T {
    match pool {
        Some(pool) => pool.install(run),
        None => run(),
    }
}

/// The label of a step variant run inside `pool.install`.
fn installed(threads: usize) -> String {
    format!("{}, step inside pool.install", on(threads))
}

/// The relaxation's step: from the box at rest on the ground, `RELAX_ITERATIONS` iterations;
/// the state is restored before every run. Returns the variant and its (iterations, energy
/// evaluations) per run.
fn relax_variant<F: ElasticEnergy<Vector = Vec3> + Send + Sync + 'static>(
    label: String,
    threads: usize,
    model: F,
    scene: &Scene,
    installed: Option<&'static rayon::ThreadPool>,
) -> (Variant, (u32, u32)) {
    let (n, masses) = (scene.mesh.vertex_count(), scene.masses());
    let step_scene = StepScene::new(1.0 / 60.0)
        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
        .with_ground(HalfSpace::new(Vec3::Y, 0.0));
    let settings = RelaxSettings::new().with_tolerance(0.0, RELAX_ITERATIONS);
    let vectors = vec![Vec3::ZERO; scratch_len::relax(n)].leak();
    let scalars = vec![0.0; n].leak();
    let mut scratch = RelaxScratch::new(vectors, scalars);
    let solve = move |x: &mut [Vec3], v: &mut [Vec3]| {
        let report = relax_step(
            &model,
            &masses,
            &[],
            &step_scene,
            &settings,
            x,
            v,
            &mut scratch,
        )
        .unwrap();
        (report.iterations, report.energy_evaluations)
    };
    // The first run computes the preconditioner (kept in the scratch, as in a simulation).
    repeated_solve(label, threads, scene.rest_positions, installed, solve)
}

/// Newton's step: from the box at rest on the ground, `NEWTON_ITERATIONS` Newton iterations of
/// at most `NEWTON_CG_ITERATIONS` CG iterations each; the state is restored before every run.
/// Returns the variant and its (Newton, CG) iterations per run.
fn newton_variant<F: ElasticHessian + Send + Sync + 'static>(
    label: String,
    threads: usize,
    model: F,
    scene: &Scene,
    installed: Option<&'static rayon::ThreadPool>,
) -> (Variant, (u32, u32)) {
    let (n, ne) = (scene.mesh.vertex_count(), scene.mesh.element_count());
    let masses = scene.masses();
    let step_scene = StepScene::new(1.0 / 60.0)
        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
        .with_ground(HalfSpace::new(Vec3::Y, 0.0));
    let settings = NewtonSettings::new()
        .with_tolerance(0.0, NEWTON_ITERATIONS)
        .with_cg_iterations(NEWTON_CG_ITERATIONS);
    let lengths = scratch_len::newton(n, ne);
    let vectors = vec![Vec3::ZERO; lengths.vectors].leak();
    let blocks = vec![Mat3::ZERO; lengths.blocks].leak();
    let hessians = vec![TetHessian::default(); lengths.hessians].leak();
    let mut scratch = NewtonScratch::new(vectors, blocks, hessians);
    let solve = move |x: &mut [Vec3], v: &mut [Vec3]| {
        let report = newton_step(
            &model,
            &masses,
            &[],
            &step_scene,
            &settings,
            x,
            v,
            &mut scratch,
        )
        .unwrap();
        (report.iterations, report.details.cg_iterations)
    };
    repeated_solve(label, threads, scene.rest_positions, installed, solve)
}

/// The variant that runs `solve` from `start` at rest (restored before every run), inside
/// `installed` if given, and its counts from a first run, which every later run must repeat
/// (the same path through the solver).
fn repeated_solve(
    label: String,
    threads: usize,
    start: &'static [Vec3],
    installed: Option<&'static rayon::ThreadPool>,
    mut solve: impl FnMut(&mut [Vec3], &mut [Vec3]) -> (u32, u32) + Send + 'static,
) -> (Variant, (u32, u32)) {
    let (mut x, mut v) = (start.to_vec(), vec![Vec3::ZERO; start.len()]);
    let mut step = move || {
        x.copy_from_slice(start);
        v.fill(Vec3::ZERO);
        on_installed(installed, || solve(&mut x, &mut v))
    };
    let counts = step();
    let run = Box::new(move || assert_eq!(step(), counts));
    (
        Variant {
            label,
            threads,
            run,
        },
        counts,
    )
}

/// A component of a sequential step, timed with the workload: stable neo-Hookean forces
/// (`fused: false`) or the fused energy-and-force pass.
fn component_variant(scene: &Scene, fused: bool) -> Variant {
    let (body, _) = scene.stable_bodies(None);
    let mut forces = vec![Vec3::ZERO; scene.mesh.vertex_count()];
    let x = scene.positions;
    Variant {
        label: if fused {
            "component: fused energy-and-force pass, sequential".to_owned()
        } else {
            "component: stable neo-Hookean forces, sequential".to_owned()
        },
        threads: 0,
        run: Box::new(move || {
            forces.fill(Vec3::ZERO);
            if fused {
                let energy = body
                    .energy_and_add_forces(black_box(x), &mut forces)
                    .unwrap();
                // Infinite beyond the material's range, where the pass computes nothing.
                assert!(
                    energy.is_finite(),
                    "the fused pass computed nothing: {energy}"
                );
            } else {
                body.add_forces(black_box(x), &mut forces).unwrap();
            }
            black_box(&forces);
        }),
    }
}

/// How long to time: round-robin rounds and the least time per timed block.
struct Plan {
    rounds: u32,
    block_seconds: f64,
}

/// Times `variants` round-robin; returns seconds per run, the minimum over the rounds, in wall
/// time and in the CPU time of the timing thread (which counts only the work done on that
/// thread, and none of the time another process held its core: on a loaded machine, the robust
/// measure of the rows that run on the calling thread), and the wall time of the fastest single
/// run of all blocks (each run of a block timed on its own: on a shared machine a block of a
/// pool of `n` threads is slowed whenever another process takes any of the `n` cores during it,
/// a single run only if it does so during that run).
fn time(variants: &mut [Variant], plan: &Plan) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    // Runs per block from one warm-up run each (the slowest variant sets it for all, so the
    // blocks are comparable).
    let slowest = variants
        .iter_mut()
        .map(|variant| {
            let start = Instant::now();
            (variant.run)();
            start.elapsed().as_secs_f64()
        })
        .fold(0.0, f64::max);
    let repetitions = ((plan.block_seconds / slowest).ceil() as u32).max(1);
    // Every block is timed on the worker of a one-thread pool, the sequential rows too: on the
    // loaded machine the main thread ran consistently slower than the pools' workers, which made
    // the sequential rows look slower than the (strictly costlier) one-thread pool rows.
    let timer = pool(1);
    let mut best = vec![f64::INFINITY; variants.len()];
    let mut best_cpu = vec![f64::INFINITY; variants.len()];
    let mut best_single = vec![f64::INFINITY; variants.len()];
    for _ in 0..plan.rounds {
        let bests = best.iter_mut().zip(&mut best_cpu).zip(&mut best_single);
        for (variant, ((best, best_cpu), best_single)) in variants.iter_mut().zip(bests) {
            // Rayon's idle workers spin a while before they sleep: without the pause they would
            // take the core from the variant timed next.
            std::thread::sleep(PAUSE);
            let run = &mut variant.run;
            let (seconds, cpu_seconds, single) = timer.install(|| {
                let (start, cpu_start) = (Instant::now(), thread_cpu_seconds());
                let mut single = f64::INFINITY;
                let mut run_start = start;
                for _ in 0..repetitions {
                    run();
                    let now = Instant::now();
                    single = single.min((now - run_start).as_secs_f64());
                    run_start = now;
                }
                (
                    start.elapsed().as_secs_f64(),
                    thread_cpu_seconds() - cpu_start,
                    single,
                )
            });
            *best = best.min(seconds / f64::from(repetitions));
            *best_cpu = best_cpu.min(cpu_seconds / f64::from(repetitions));
            *best_single = best_single.min(single);
        }
    }
    (best, best_cpu, best_single)
}

/// The CPU time (s) this thread has run, from `CLOCK_THREAD_CPUTIME_ID`; NaN where there is no
/// such clock here (then the CPU-time ratios read NaN).
fn thread_cpu_seconds() -> f64 {
    #[cfg(target_os = "linux")]
    {
        #[repr(C)]
        struct Timespec {
            seconds: i64,
            nanoseconds: i64,
        }
        unsafe extern "C" {
            fn clock_gettime(clock: i32, time: *mut Timespec) -> i32;
        }
        /// Linux's `CLOCK_THREAD_CPUTIME_ID`.
        const THREAD_CPU_CLOCK: i32 = 3;
        let mut time = Timespec {
            seconds: 0,
            nanoseconds: 0,
        };
        // SAFETY: `clock_gettime` writes one `struct timespec` (two 64-bit fields on x86_64
        // and aarch64 Linux) at a valid pointer; the bench has no other way to a thread's CPU
        // clock without a new dependency.
        if unsafe { clock_gettime(THREAD_CPU_CLOCK, &mut time) } == 0 {
            return time.seconds as f64 + time.nanoseconds as f64 * 1e-9;
        }
    }
    f64::NAN
}

/// Prints and returns as a CSV row the thread-CPU-time cost of the partitioned pieces run on the
/// timing thread against the sequential pass (`variants` from [`pass_variants`]: the sequential
/// pass first, the pieces second).
fn cpu_cost_row(workload: &str, tets: usize, cpu_seconds: &[f64]) -> CsvRow {
    let ratio = cpu_seconds[1] / cpu_seconds[0];
    println!(
        "Thread CPU time, pieces on this thread / sequential: {ratio:.3} ({:.3} ms / {:.3} ms).",
        cpu_seconds[1] * 1e3,
        cpu_seconds[0] * 1e3
    );
    CsvRow {
        bench: "parallel",
        workload: format!("{workload}, pieces on this thread / sequential, thread CPU time"),
        size: tets,
        lanes: softfem::lanes::LANES,
        threads: 1,
        value: ratio,
        unit: "ratio",
    }
}

/// The pause before every timed block.
const PAUSE: std::time::Duration = std::time::Duration::from_millis(20);

/// Prints a workload's table and returns its CSV rows. `per_run` is the item a run counts (a
/// force pass over `tets`, a step, `iterations` relaxation iterations).
fn report(
    workload: &str,
    tets: usize,
    variants: &[Variant],
    seconds: &[f64],
    per_run: PerRun,
) -> Vec<CsvRow> {
    let sequential = seconds[0];
    let one_thread = variants
        .iter()
        .zip(seconds)
        .find(|(v, _)| v.label == on(1))
        .map(|(_, &s)| s);
    println!();
    println!("{workload}, {tets} tets:");
    println!();
    let (value_name, unit) = per_run.unit();
    common::print_markdown_table(
        &["variant", value_name, "vs sequential", "vs rayon 1 thread"],
        variants
            .iter()
            .zip(seconds)
            .filter(|(variant, _)| !variant.label.starts_with("component"))
            .map(|(variant, &s)| {
                vec![
                    variant.label.clone(),
                    format!("{:.3}", per_run.value(s, tets)),
                    format!("{:.2}x", sequential / s),
                    one_thread.map_or("-".to_owned(), |one| format!("{:.2}x", one / s)),
                ]
            }),
    );
    for (variant, s) in variants.iter().zip(seconds) {
        if variant.label.starts_with("component") {
            println!("{}: {:.3} ms a pass.", variant.label, s * 1e3);
        }
    }
    let mut rows: Vec<CsvRow> = variants
        .iter()
        .zip(seconds)
        .filter(|(variant, _)| !variant.label.starts_with("component"))
        .map(|(variant, &s)| CsvRow {
            bench: "parallel",
            workload: format!("{workload}, {}", variant.label),
            size: tets,
            lanes: softfem::lanes::LANES,
            threads: variant.threads.max(1),
            value: per_run.value(s, tets),
            unit,
        })
        .collect();
    if let Some(one) = one_thread {
        rows.push(CsvRow {
            bench: "parallel",
            workload: format!("{workload}, scheme one-thread time / sequential time"),
            size: tets,
            lanes: softfem::lanes::LANES,
            threads: 1,
            value: one / sequential,
            unit: "ratio",
        });
        for (variant, &s) in variants.iter().zip(seconds) {
            if variant.label.starts_with("rayon") && variant.threads > 1 {
                rows.push(CsvRow {
                    bench: "parallel",
                    workload: format!(
                        "{workload}, speed-up {} threads / 1 thread",
                        variant.threads
                    ),
                    size: tets,
                    lanes: softfem::lanes::LANES,
                    threads: variant.threads,
                    value: one / s,
                    unit: "ratio",
                });
            }
        }
    }
    rows
}

/// What one run of a workload counts.
#[derive(Clone, Copy)]
enum PerRun {
    ForcePass,
    Step,
    Iterations(u32),
}

impl PerRun {
    fn unit(self) -> (&'static str, &'static str) {
        match self {
            PerRun::ForcePass => ("Mtets/s", "Mtets/s"),
            PerRun::Step => ("ms/step", "ms/step"),
            PerRun::Iterations(_) => ("ms/iteration", "ms/iteration"),
        }
    }

    fn value(self, seconds: f64, tets: usize) -> f64 {
        match self {
            PerRun::ForcePass => tets as f64 / seconds * 1e-6,
            PerRun::Step => seconds * 1e3,
            PerRun::Iterations(n) => seconds * 1e3 / f64::from(n),
        }
    }
}

fn main() {
    let plan = match common::table_pass() {
        TablePass::Skip => return,
        TablePass::Test => Plan {
            rounds: 1,
            block_seconds: 0.0,
        },
        TablePass::Full if common::quick() => Plan {
            rounds: 2,
            block_seconds: 0.02,
        },
        // Fifteen rounds: on a loaded machine the minimum needs many chances to find a quiet one.
        TablePass::Full => Plan {
            rounds: 15,
            block_seconds: 0.2,
        },
    };
    let short = common::quick() || matches!(common::table_pass(), TablePass::Test);
    let threads = thread_counts();
    let pools: Vec<_> = threads.iter().map(|&t| (t, pool(t))).collect();
    let pieces = PIECES_PER_THREAD * threads.iter().copied().max().unwrap_or(1);
    println!(
        "softfem parallel bench on {}, {} cores available; pools of {threads:?} threads; \
         partitions of {pieces} pieces; minimum of {} round-robin rounds; load average \
         (1, 5, 15 min) {}.",
        common::machine(),
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        plan.rounds,
        load_average(),
    );
    let sizes = if short { &CELLS[..1] } else { &CELLS[..] };
    let scenes: Vec<Scene> = sizes.iter().map(|&c| Scene::new(c, pieces)).collect();
    let mut rows = Vec::new();
    let triad_len = if short { TRIAD_LEN / 16 } else { TRIAD_LEN };
    let triads = triads(&pools, triad_len);
    println!();
    for &(threads, gb_per_s) in &triads {
        println!(
            "STREAM-like triad (f32, 3 x {} MiB, one part per thread), {}: {gb_per_s:.1} GB/s.",
            (triad_len * size_of::<f32>()) >> 20,
            on(threads)
        );
        rows.push(CsvRow {
            bench: "parallel",
            workload: "triad".to_owned(),
            size: triad_len,
            lanes: 1,
            threads,
            value: gb_per_s,
            unit: "GB/s",
        });
    }
    for scene in &scenes {
        let mut variants = force_variants(scene, &pools);
        let (seconds, cpu_seconds, single) = time(&mut variants, &plan);
        let tets = scene.mesh.element_count();
        rows.extend(report(
            "StVK direct forces",
            tets,
            &variants,
            &seconds,
            PerRun::ForcePass,
        ));
        rows.push(cpu_cost_row("StVK direct forces", tets, &cpu_seconds));
        rows.extend(single_run_rows(
            "StVK direct forces",
            tets,
            &variants,
            &single,
        ));
        rows.extend(ceiling_rows(scene, &triads, &variants, &seconds));
        println!("Load average (1, 5, 15 min): {}.", load_average());
    }
    let scene = &scenes[0];
    let tets = scene.mesh.element_count();
    let mut variants = fused_variants(scene, &pools);
    let (seconds, cpu_seconds, single) = time(&mut variants, &plan);
    rows.extend(report(
        "fused energy-and-force pass",
        tets,
        &variants,
        &seconds,
        PerRun::ForcePass,
    ));
    rows.push(cpu_cost_row(
        "fused energy-and-force pass",
        tets,
        &cpu_seconds,
    ));
    rows.extend(single_run_rows(
        "fused energy-and-force pass",
        tets,
        &variants,
        &single,
    ));

    let (body, _) = scene.stable_bodies(None);
    let mut variants = vec![explicit_variant(on(0), 0, body, scene, None)];
    for &(threads, pool) in &pools {
        for (label, installed) in [(on(threads), None), (installed(threads), Some(pool))] {
            let (_, parallel) = scene.stable_bodies(Some(pool));
            let parallel = parallel.unwrap();
            variants.push(explicit_variant(label, threads, parallel, scene, installed));
        }
    }
    variants.push(component_variant(scene, false));
    let (seconds, _, _) = time(&mut variants, &plan);
    rows.extend(report(
        "explicit step",
        tets,
        &variants,
        &seconds,
        PerRun::Step,
    ));
    let share = 1.0 - seconds[variants.len() - 1] / seconds[0];
    println!(
        "Vertex passes (integration, damping, checks): {:.1} % of a sequential step.",
        share * 100.0
    );
    rows.push(vertex_share_row("explicit step", tets, share));

    let (mut variants, counts) = solver_variants(
        scene,
        &pools,
        |body| relax_variant(on(0), 0, body, scene, None),
        |label, threads, body, installed| relax_variant(label, threads, body, scene, installed),
    );
    variants.push(component_variant(scene, true));
    let (seconds, _, _) = time(&mut variants, &plan);
    let (iterations, evaluations) = counts;
    rows.extend(report(
        "relaxation iteration",
        tets,
        &variants,
        &seconds,
        PerRun::Iterations(iterations),
    ));
    let element_passes = f64::from(evaluations) * seconds[variants.len() - 1];
    let share = 1.0 - element_passes / seconds[0];
    println!(
        "{iterations} iterations and {evaluations} energy-and-force evaluations a step; vertex \
         passes (preconditioner, directions, line search, Chebyshev): {:.1} % of a sequential step.",
        share * 100.0
    );
    rows.push(vertex_share_row("relaxation iteration", tets, share));

    let (mut variants, counts) = solver_variants(
        scene,
        &pools,
        |body| newton_variant(on(0), 0, body, scene, None),
        |label, threads, body, installed| newton_variant(label, threads, body, scene, installed),
    );
    let (seconds, _, _) = time(&mut variants, &plan);
    let (newton_iterations, cg_iterations) = counts;
    rows.extend(report(
        "Newton step",
        tets,
        &variants,
        &seconds,
        PerRun::Step,
    ));
    println!("{newton_iterations} Newton and {cg_iterations} CG iterations a step.");
    common::append_csv_rows(&rows);
}

/// The elements of the triad's arrays: 16 Mi f32 each, 3 x 64 MiB in all, as the forces bench's
/// one-thread triad (twice the last-level cache of the machine this was written on, so every
/// pass comes from DRAM).
const TRIAD_LEN: usize = 16 << 20;

/// The triad's passes per pool (interleaved over the pools; the best of them counts).
const TRIAD_ROUNDS: usize = 10;

/// Runs `op` on `threads` equal parts of the three buffers, part `i` on thread `i` of `pool`.
fn on_parts(
    pool: &rayon::ThreadPool,
    threads: usize,
    (a, b, c): (&mut [f32], &mut [f32], &mut [f32]),
    op: impl Fn(&mut [f32], &mut [f32], &mut [f32]) + Sync,
) {
    use std::sync::Mutex;
    let chunk = a.len().div_ceil(threads).max(1);
    let parts: Vec<Mutex<_>> = a
        .chunks_mut(chunk)
        .zip(b.chunks_mut(chunk))
        .zip(c.chunks_mut(chunk))
        .map(Mutex::new)
        .collect();
    pool.broadcast(|context| {
        if let Some(part) = parts.get(context.index()) {
            let ((a, b), c) = &mut *part.lock().unwrap();
            op(a, b, c);
        }
    });
}

/// A STREAM-like triad `a[i] = b[i] + s c[i]` over f32 arrays of `n` elements ([`TRIAD_LEN`],
/// fewer in a smoke test: then two rounds) on each pool: the arrays cut into one contiguous
/// part per thread, each thread of the pool running its own part (`ThreadPool::broadcast`:
/// every worker exactly once, none stolen), so the total bytes are those of the forces bench's
/// one-thread triad whatever the thread count. Each part of the largest pool is first written
/// by the thread that runs it there, and one untimed pass per pool precedes the timed ones.
/// Rounds interleave the pools (a [`PAUSE`] before each pass); the best pass per pool counts,
/// at STREAM's 12 bytes per element (two loads and a store, write-allocate traffic not
/// counted). Returns (threads, GB/s) per pool.
fn triads(pools: &[(usize, &'static rayon::ThreadPool)], n: usize) -> Vec<(usize, f64)> {
    // Zeroed allocations this large are fresh pages from the system (`calloc`): each part is
    // first written below by the thread of the largest pool that owns it (one NUMA node here,
    // so this only keeps page faults out of the timed passes).
    let (mut a, mut b, mut c) = (vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]);
    let &(threads_max, pool_max) = pools
        .iter()
        .max_by_key(|(threads, _)| *threads)
        .expect("at least one pool");
    on_parts(
        pool_max,
        threads_max,
        (&mut a, &mut b, &mut c),
        |a, b, c| {
            a.fill(0.0);
            b.fill(1.0);
            c.fill(2.0);
        },
    );
    let scale = black_box(3.0f32);
    let mut pass = |pool: &rayon::ThreadPool, threads: usize| {
        std::thread::sleep(PAUSE);
        // Splitting the buffers (a few mutexes) is timed too: nanoseconds against a pass of
        // milliseconds.
        let start = Instant::now();
        on_parts(pool, threads, (&mut a, &mut b, &mut c), |a, b, c| {
            for ((a, b), c) in a.iter_mut().zip(&*b).zip(&*c) {
                *a = b + scale * c;
            }
            black_box(a);
        });
        start.elapsed().as_secs_f64()
    };
    for &(threads, pool) in pools {
        pass(pool, threads);
    }
    let mut best = vec![f64::INFINITY; pools.len()];
    let rounds = if n < TRIAD_LEN { 2 } else { TRIAD_ROUNDS };
    for _ in 0..rounds {
        for (&(threads, pool), best) in pools.iter().zip(&mut best) {
            *best = best.min(pass(pool, threads));
        }
    }
    assert!(
        a.iter().all(|&x| x == 7.0),
        "the triad computed something else"
    );
    pools
        .iter()
        .zip(best)
        .map(|(&(threads, _), seconds)| (threads, (12 * n) as f64 / seconds / 1e9))
        .collect()
}

/// The elements the owner tasks of a pool of `threads` threads evaluate in one direct force
/// pass on `scene`, cut elements once per task: each task's elements from the first to the last
/// one incident to its vertices (the owner pass runs that range). The spans as
/// `softfem::parallel` makes them: one span of every piece on one thread, else
/// `min(pieces, 4 threads)` spans of consecutive pieces.
fn evaluated_elements(scene: &Scene, threads: usize) -> usize {
    let partition = &scene.partition;
    let pieces = partition.vertex_piece_count().max(1);
    let spans = if threads <= 1 {
        1
    } else {
        pieces.min(4 * threads)
    };
    let per_span = pieces.div_ceil(spans) * partition.vertex_chunk();
    let mut ranges = vec![(usize::MAX, 0); spans];
    for (element, corners) in scene.mesh.tets().iter().enumerate() {
        for &v in corners {
            let (first, last) = &mut ranges[v as usize / per_span];
            *first = (*first).min(element);
            *last = (*last).max(element);
        }
    }
    ranges
        .iter()
        .filter(|(first, _)| *first != usize::MAX)
        .map(|(first, last)| last - first + 1)
        .sum()
}

/// Bytes per element stream from memory in one f32 StVK direct force pass on `scene` on a
/// pool of `threads` threads, at best: the corner indices (16) and the `TetRest` (40) of every
/// element evaluated ([`evaluated_elements`], cut ones once per task), plus 36 bytes per
/// vertex: its position read once (12) and its force read and written back once (24; the
/// bench zeroes the forces before every pass, the pass then adds into them). The gathers of
/// positions and the scatters of forces at the corners are counted once per vertex: in these
/// boxes a task's active window of vertices (a few layers of cells, ~100 kB) stays in its L2.
fn pass_bytes_per_tet(scene: &Scene, threads: usize) -> f64 {
    let (tets, vertices) = (scene.mesh.element_count(), scene.mesh.vertex_count());
    let element_bytes = (size_of::<[u32; 4]>() + size_of::<TetRest>()) as f64;
    let evaluated = evaluated_elements(scene, threads) as f64;
    (element_bytes * evaluated + 36.0 * vertices as f64) / tets as f64
}

/// Prints and returns as CSV rows the bandwidth ceiling of the force pass on `scene` on each
/// pool (`triads`: the pool's triad GB/s, [`triads`]) at [`pass_bytes_per_tet`], beside the
/// rates the pools measured (`variants` and `seconds` of [`force_variants`]).
fn ceiling_rows(
    scene: &Scene,
    triads: &[(usize, f64)],
    variants: &[Variant],
    seconds: &[f64],
) -> Vec<CsvRow> {
    let tets = scene.mesh.element_count();
    let mut rows = Vec::new();
    let mut ceilings = Vec::new();
    for &(threads, gb_per_s) in triads {
        let bytes = pass_bytes_per_tet(scene, threads);
        let ceiling = gb_per_s * 1e3 / bytes;
        let measured = variants
            .iter()
            .zip(seconds)
            .find(|(variant, _)| variant.label == on(threads))
            .map(|(_, &s)| tets as f64 / s * 1e-6);
        let measured = measured.map_or(String::new(), |m| {
            format!(
                "; measured {m:.1} Mtets/s = {:.1} GB/s, {:.0} % of the ceiling",
                m * bytes * 1e-3,
                m / ceiling * 100.0
            )
        });
        println!(
            "Bandwidth ceiling, {}: triad {gb_per_s:.1} GB/s / {bytes:.1} bytes a tet = \
             {ceiling:.0} Mtets/s{measured}.",
            on(threads)
        );
        ceilings.push((threads, ceiling));
        rows.push(CsvRow {
            bench: "parallel",
            workload: "StVK direct forces, bytes streamed per tet".to_owned(),
            size: tets,
            lanes: softfem::lanes::LANES,
            threads,
            value: bytes,
            unit: "B/tet",
        });
        rows.push(CsvRow {
            bench: "parallel",
            workload: "StVK direct forces, bandwidth ceiling".to_owned(),
            size: tets,
            lanes: softfem::lanes::LANES,
            threads,
            value: ceiling,
            unit: "Mtets/s",
        });
    }
    // A pool of n threads can be at most its ceiling over the measured one-thread rate faster
    // than one thread: the bound bandwidth puts on the speed-up.
    let one_thread = variants
        .iter()
        .zip(seconds)
        .find(|(variant, _)| variant.label == on(1))
        .map(|(_, &s)| tets as f64 / s * 1e-6);
    if let Some(one) = one_thread {
        for &(threads, ceiling) in ceilings.iter().filter(|(threads, _)| *threads > 1) {
            println!(
                "Bound on the speed-up {threads} threads / 1 thread from bandwidth: {ceiling:.0} / \
                 {one:.1} Mtets/s = {:.2}x.",
                ceiling / one
            );
            rows.push(CsvRow {
                bench: "parallel",
                workload: format!(
                    "StVK direct forces, bandwidth bound on the speed-up {threads} threads / 1 thread"
                ),
                size: tets,
                lanes: softfem::lanes::LANES,
                threads,
                value: ceiling / one,
                unit: "ratio",
            });
        }
    }
    rows
}

/// Prints the speed-ups of the fastest single runs (`single`, from [`time`]) of a pass's
/// variants ([`pass_variants`]) and returns them as CSV rows: each pool against the one-thread
/// pool, and the one-thread pool against the sequential pass.
fn single_run_rows(
    workload: &str,
    tets: usize,
    variants: &[Variant],
    single: &[f64],
) -> Vec<CsvRow> {
    let rate = |s: f64| tets as f64 / s * 1e-6;
    let Some(one) = variants
        .iter()
        .zip(single)
        .find(|(variant, _)| variant.label == on(1))
        .map(|(_, &s)| s)
    else {
        return Vec::new();
    };
    let mut line = format!(
        "Fastest single runs: sequential {:.1}, rayon 1 thread {:.1} Mtets/s ({:.2}x sequential)",
        rate(single[0]),
        rate(one),
        single[0] / one
    );
    let mut rows = vec![CsvRow {
        bench: "parallel",
        workload: format!("{workload}, rayon 1 thread / sequential, fastest single runs"),
        size: tets,
        lanes: softfem::lanes::LANES,
        threads: 1,
        value: single[0] / one,
        unit: "ratio",
    }];
    for (variant, &s) in variants.iter().zip(single) {
        if variant.label.starts_with("rayon") && variant.threads > 1 {
            line.push_str(&format!(
                ", {} threads {:.1} Mtets/s ({:.2}x 1 thread)",
                variant.threads,
                rate(s),
                one / s
            ));
            rows.push(CsvRow {
                bench: "parallel",
                workload: format!(
                    "{workload}, speed-up {} threads / 1 thread, fastest single runs",
                    variant.threads
                ),
                size: tets,
                lanes: softfem::lanes::LANES,
                threads: variant.threads,
                value: one / s,
                unit: "ratio",
            });
        }
    }
    println!("{line}.");
    rows
}

/// The system's load averages over 1, 5 and 15 minutes (`/proc/loadavg`), for the captions: on a
/// shared machine the multi-thread rows depend on them.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|text| {
            text.split_whitespace()
                .take(3)
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_else(|| "unknown".to_owned())
}

/// The sequential variant of a solver (`sequential` on the sequential body) and the parallel
/// ones on every pool, called from the timing thread and inside the pool's `install`
/// (`parallel(label, threads, body, installed)`); checks that every run takes the sequential
/// run's path (its counts), which it returns.
fn solver_variants(
    scene: &Scene,
    pools: &[(usize, &'static rayon::ThreadPool)],
    sequential: impl FnOnce(TetElastic<'static, StableNeoHookean>) -> (Variant, (u32, u32)),
    parallel: impl Fn(
        String,
        usize,
        ParallelTetElastic<'static, StableNeoHookean>,
        Option<&'static rayon::ThreadPool>,
    ) -> (Variant, (u32, u32)),
) -> (Vec<Variant>, (u32, u32)) {
    let (body, _) = scene.stable_bodies(None);
    let (variant, counts) = sequential(body);
    let mut variants = vec![variant];
    for &(threads, pool) in pools {
        for (label, installed) in [(on(threads), None), (installed(threads), Some(pool))] {
            let (_, body) = scene.stable_bodies(Some(pool));
            let (variant, parallel_counts) = parallel(label, threads, body.unwrap(), installed);
            assert_eq!(
                parallel_counts, counts,
                "the parallel run must take the same path"
            );
            variants.push(variant);
        }
    }
    (variants, counts)
}

/// The CSV row of the vertex passes' share of a sequential step.
fn vertex_share_row(workload: &str, tets: usize, share: f64) -> CsvRow {
    CsvRow {
        bench: "parallel",
        workload: format!("{workload}, vertex passes' share of a sequential step"),
        size: tets,
        lanes: softfem::lanes::LANES,
        threads: 1,
        value: share,
        unit: "ratio",
    }
}

//! Many cores, same bits: a game loop that steps several small soft bodies and one large one in
//! parallel, and checks every frame against the sequential run, bit for bit.
//!
//! `cargo run --release -p softfem-examples --features rayon --bin parallel [-- --frames 30 --cells
//! 20 --bodies 8 --threads 2]`
//!
//! Every frame (1/60 s, implicit Euler by the Chebyshev relaxation) runs twice:
//! * in parallel: the small bodies spread over the pool's threads (`par_iter_mut`, one body per
//!   task, each body's step sequential inside) while the large body's element passes and its
//!   passes over the vertices (in blocks of `softfem::step::vertex_pass::VERTEX_BLOCK`) run on the same pool
//!   through a `softfem::parallel::ParallelTetElastic` (`rayon::join` of the two);
//! * sequentially: the same bodies one after another on this thread, with the plain
//!   `TetElastic`.
//!
//! The relaxation runs a game's fixed budget (at most 60 iterations, or a relative residual of
//! 1e-2). It prints both frame times, the speed-up and the large body's iterations, and stops
//! with an error at the first frame whose positions, velocities or reports differ in any bit
//! between the runs.

use std::error::Error;
use std::process::ExitCode;
use std::time::Instant;

use clap::Parser;
use rayon::prelude::*;
use softfem::element::TetRest;
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::Vec3;
use softfem::material::StableNeoHookean;
use softfem::mesh::{
    TetMesh, TetPartition, element_forces_len, partition_incident_len, partition_offsets_len,
};
use softfem::parallel::ParallelTetElastic;
use softfem::step::{
    ElasticEnergy, HalfSpace, RelaxReport, RelaxScratch, RelaxSettings, Scene, TetElastic,
    relax_step, scratch_len,
};

/// Command line.
#[derive(Parser)]
#[command(about = "Steps several soft bodies and one large one in parallel, checking the bits")]
struct Cli {
    /// Frames of 1/60 s to simulate.
    #[arg(long, default_value_t = 30)]
    frames: u32,
    /// Cells per axis of the large body (6 tetrahedra per cell).
    #[arg(long, default_value_t = 20)]
    cells: usize,
    /// Number of small bodies (4^3 cells, 384 tetrahedra each).
    #[arg(long, default_value_t = 8)]
    bodies: usize,
    /// Threads of the pool (default: every core).
    #[arg(long)]
    threads: Option<usize>,
}

/// The frame time (s).
const FRAME: f32 = 1.0 / 60.0;

/// Cells per axis of a small body.
const SMALL_CELLS: usize = 4;

/// A body's mesh data: rest positions, tetrahedra and the rest data its mesh borrows.
struct Shape {
    rest: Vec<Vec3>,
    tets: Vec<[u32; 4]>,
    rest_data: Vec<TetRest>,
}

impl Shape {
    /// A box of `cells^3` Kuhn cells from `low` to `low + size`.
    fn cube(cells: usize, low: Vec3, size: Vec3) -> Result<Self, Box<dyn Error>> {
        let (vertices, tets) = box_counts(cells, cells, cells, BoxSplit::Kuhn6)?;
        let (mut rest, mut elements) = (vec![Vec3::ZERO; vertices], vec![[0; 4]; tets]);
        fill_box(
            low,
            low + size,
            cells,
            cells,
            cells,
            BoxSplit::Kuhn6,
            &mut rest,
            &mut elements,
        )?;
        Ok(Shape {
            rest,
            tets: elements,
            rest_data: vec![TetRest::default(); tets],
        })
    }
}

/// The state of one body in one run, and the relaxation scratch it keeps between frames (the
/// preconditioner is computed by the first step only).
struct Run {
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    scratch: RelaxScratch<'static, Vec3>,
}

impl Run {
    /// At rest at `rest`. The scratch buffers live for the whole program.
    fn at_rest(rest: &[Vec3]) -> Self {
        let n = rest.len();
        let vectors = vec![Vec3::ZERO; scratch_len::relax(n)].leak();
        let scalars = vec![0.0; n].leak();
        Run {
            x: rest.to_vec(),
            v: vec![Vec3::ZERO; n],
            scratch: RelaxScratch::new(vectors, scalars),
        }
    }

    /// One step of a frame through `model`.
    fn step<F: ElasticEnergy<Vector = Vec3>>(
        &mut self,
        model: &F,
        masses: &[f32],
        scene: &Scene<'_, Vec3>,
        settings: &RelaxSettings,
    ) -> Result<RelaxReport, softfem::StepError> {
        relax_step(
            model,
            masses,
            &[],
            scene,
            settings,
            &mut self.x,
            &mut self.v,
            &mut self.scratch,
        )
    }

    /// Whether positions and velocities have the same bits as `other`'s.
    fn same_bits(&self, other: &Run) -> bool {
        let bits = |v: &[Vec3]| -> Vec<[u32; 3]> {
            v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
        };
        bits(&self.x) == bits(&other.x) && bits(&self.v) == bits(&other.v)
    }
}

fn main() -> ExitCode {
    match run(&Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: &Cli) -> Result<(), Box<dyn Error>> {
    let threads = cli
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;

    // The large body: a 40 cm cube of jelly resting on the ground; the small ones: 10 cm cubes
    // dropped beside it from different heights.
    let mut large = Shape::cube(cli.cells, Vec3::ZERO, Vec3::splat(0.4))?;
    let mut small: Vec<Shape> = (0..cli.bodies)
        .map(|i| {
            let low = Vec3::new(
                0.6 + 0.15 * (i % 4) as f32,
                0.05 + 0.15 * (i / 4) as f32,
                0.0,
            );
            Shape::cube(SMALL_CELLS, low, Vec3::splat(0.1))
        })
        .collect::<Result<_, _>>()?;

    // Two runs of the same world: [parallel, sequential].
    let [mut large_parallel, mut large_sequential] = [0, 1].map(|_| Run::at_rest(&large.rest));
    let [mut small_parallel, mut small_sequential]: [Vec<Run>; 2] = [0, 1].map(|_| {
        small
            .iter()
            .map(|shape| Run::at_rest(&shape.rest))
            .collect()
    });

    let material = StableNeoHookean::from_young_poisson(2.0e5, 0.4)?;
    let large_mesh = TetMesh::new(&large.rest, &large.tets, &mut large.rest_data)?;
    let small_meshes: Vec<TetMesh<'_>> = small
        .iter_mut()
        .map(|shape| TetMesh::new(&shape.rest, &shape.tets, &mut shape.rest_data))
        .collect::<Result<_, _>>()?;
    let masses = |mesh: &TetMesh<'_>| -> Result<Vec<f32>, softfem::MeshError> {
        let mut masses = vec![0.0; mesh.vertex_count()];
        mesh.lumped_masses(1000.0, &mut masses)?;
        Ok(masses)
    };
    let large_masses = masses(&large_mesh)?;
    let small_masses: Vec<Vec<f32>> = small_meshes.iter().map(masses).collect::<Result<_, _>>()?;

    // The large body's partition: four pieces per thread, so that stealing balances the load.
    let (nv, ne) = (large_mesh.vertex_count(), large_mesh.element_count());
    let (mut offsets, mut incident) = (
        vec![0; partition_offsets_len(nv)],
        vec![0; partition_incident_len(ne)],
    );
    let partition = TetPartition::new(large_mesh, 4 * threads, &mut offsets, &mut incident)?;
    let (mut element_forces, mut energies) =
        (vec![[Vec3::ZERO; 4]; element_forces_len(ne)], vec![0.0; ne]);
    let large_body = TetElastic::new(large_mesh, material);
    // No pool of its own: it runs on the pool of the thread that steps it (ours, below).
    let parallel_large =
        ParallelTetElastic::new(large_body, partition, &mut element_forces, &mut energies)?;
    let small_bodies: Vec<_> = small_meshes
        .iter()
        .map(|&mesh| TetElastic::new(mesh, material))
        .collect();

    let scene = Scene::new(FRAME)
        .with_gravity(Vec3::new(0.0, -9.81, 0.0))
        .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
    let settings = RelaxSettings::new().with_tolerance(1.0e-2, 60);

    println!(
        "{} small bodies of {} tets and one of {ne} tets ({nv} vertices), relaxation steps of \
         1/60 s; pool of {threads} threads; {} cores available.",
        cli.bodies,
        small_meshes.first().map_or(0, TetMesh::element_count),
        std::thread::available_parallelism().map_or(1, |n| n.get()),
    );
    let (mut parallel_total, mut sequential_total) = (0.0, 0.0);
    for frame in 1..=cli.frames {
        // Parallel: the small bodies across the pool's threads and the large body's element
        // passes on the same pool, both at once (work stealing mixes the two).
        let start = Instant::now();
        let (small_result, large_report) = pool.install(|| {
            rayon::join(
                || {
                    small_parallel
                        .par_iter_mut()
                        .zip(&small_bodies)
                        .zip(&small_masses)
                        .try_for_each(|((run, body), masses)| {
                            run.step(body, masses, &scene, &settings).map(|_| ())
                        })
                },
                || large_parallel.step(&parallel_large, &large_masses, &scene, &settings),
            )
        });
        small_result?;
        let large_report = large_report?;
        let parallel_time = start.elapsed().as_secs_f64();

        // Sequential: every body on this thread, through the plain `TetElastic`.
        let start = Instant::now();
        for ((run, body), masses) in small_sequential
            .iter_mut()
            .zip(&small_bodies)
            .zip(&small_masses)
        {
            run.step(body, masses, &scene, &settings)?;
        }
        let sequential_report =
            large_sequential.step(&large_body, &large_masses, &scene, &settings)?;
        let sequential_time = start.elapsed().as_secs_f64();
        parallel_total += parallel_time;
        sequential_total += sequential_time;

        let same = large_parallel.same_bits(&large_sequential)
            && small_parallel
                .iter()
                .zip(&small_sequential)
                .all(|(a, b)| a.same_bits(b))
            && large_report == sequential_report;
        println!(
            "frame {frame:3}: parallel {:7.2} ms, sequential {:7.2} ms ({:.2}x); large body {} \
             iterations, relative residual {:.1e}; {}",
            parallel_time * 1e3,
            sequential_time * 1e3,
            sequential_time / parallel_time,
            large_report.iterations,
            large_report.residual / large_report.initial_residual.max(f32::MIN_POSITIVE),
            if same { "same bits" } else { "BITS DIFFER" },
        );
        if !same {
            return Err(
                format!("frame {frame}: the parallel run differs from the sequential one").into(),
            );
        }
    }
    println!(
        "{} frames: parallel {:.1} ms, sequential {:.1} ms a frame on average ({:.2}x), every \
         frame bit-identical.",
        cli.frames,
        parallel_total * 1e3 / f64::from(cli.frames),
        sequential_total * 1e3 / f64::from(cli.frames),
        sequential_total / parallel_total,
    );
    Ok(())
}

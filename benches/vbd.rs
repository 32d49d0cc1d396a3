//! The cost of one Vertex Block Descent sweep against one force evaluation on the same mesh, at
//! about 10k and 100k tetrahedra, f32, in ns per tetrahedron, from one run.
//!
//! The body: a cube of edge 0.5 m in 12^3 and 26^3 cubes (Kuhn 6-tet split,
//! `softfem::generate::fill_box`: 10 368 and 105 456 tetrahedra), stable neo-Hookean rubber
//! (E = 1 MPa, nu = 0.45, 1000 kg/m^3, lumped masses), released from a stretch of 5 % in x and
//! -3 % in y, so that every element is deformed. Per mesh:
//!
//! * **force evaluation**: zero a force buffer, then `TetMesh::add_elastic_forces` (the
//!   reference);
//! * **energy + forces**: the same with `ElasticEnergy::energy_and_add_forces`, the fused pass
//!   VBD evaluates after every sweep for its stopping test;
//! * **VBD**: `vbd_step` (dt = 1/60 s, no gravity, no line search, no acceleration) from the
//!   stretched state, tolerance 0 so that it runs its whole budget of sweeps (1, and 3), the
//!   state reset before each call (two copies, included) and one `VbdScratch` kept across calls
//!   (the adjacency and colouring are built by the first, untimed call). A call costs one fused
//!   pass for the initial guess, then per sweep the sweep and one fused pass; the marginal
//!   iteration `(T_3 - T_1) / 2` minus the fused pass is the sweep alone;
//! * **VBD, packed layout**: the same with the scratch's packed sweep layout
//!   (`VbdScratch::with_layout`; the same bits, the visits' rest data loaded instead of
//!   gathered);
//! * with feature `rayon`, the same with the layout through `vbd_step` of a
//!   `softfem::parallel::ParallelTetElastic` (one piece per thread) on a pool of 2 threads,
//!   the whole call in `pool.install` (its result is the sequential one bit for bit; the sweeps
//!   and the fused passes are parallel), and the model's fused pass alone
//!   (**energy + forces, parallel**), which its row's sweep is measured against.
//!
//! `cargo bench -p softfem-benches --bench vbd [--features rayon]` runs criterion (one group per
//! mesh, flat sampling, 10 samples) and then a plain `Instant` pass that times every operation
//! round-robin, each timed block repeating one operation for about 50 ms, keeps the minimum per
//! operation and prints the markdown table (ratios from one run). `SOFTFEM_BENCH_QUICK=1` skips
//! criterion and the 100k mesh: a smoke test of seconds.

mod common;

use std::hint::black_box;
use std::time::{Duration, Instant};

use common::TablePass;
use criterion::{Criterion, SamplingMode, Throughput};
use softfem::element::TetRest;
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::Vec3;
use softfem::material::StableNeoHookean;
use softfem::mesh::TetMesh;
#[cfg(feature = "rayon")]
use softfem::mesh::{
    TetPartition, element_forces_len, partition_incident_len, partition_offsets_len,
};
#[cfg(feature = "rayon")]
use softfem::parallel::ParallelTetElastic;
use softfem::step::{
    ElasticEnergy, Scene as StepScene, TetElastic, VbdScratch, VbdSettings, scratch_len, vbd_step,
};

/// Cubes per axis of the two meshes: 10 368 and 105 456 tetrahedra.
const CELLS: [usize; 2] = [12, 26];

/// The sweep budgets of the two VBD calls whose difference is two iterations.
const BUDGETS: [u32; 2] = [1, 3];

/// Threads of the parallel rows.
#[cfg(feature = "rayon")]
const THREADS: usize = 2;

/// A mesh and what its operations read.
struct Scene {
    rest: Vec<Vec3>,
    tets: Vec<[u32; 4]>,
    stretched: Vec<Vec3>,
}

impl Scene {
    fn new(cells: usize) -> Scene {
        let (nv, nt) = box_counts(cells, cells, cells, BoxSplit::Kuhn6).unwrap();
        let mut rest = vec![Vec3::ZERO; nv];
        let mut tets = vec![[0; 4]; nt];
        let (nx, ny, nz) = (cells, cells, cells);
        fill_box(
            Vec3::ZERO,
            Vec3::splat(0.5),
            nx,
            ny,
            nz,
            BoxSplit::Kuhn6,
            &mut rest,
            &mut tets,
        )
        .unwrap();
        let stretched = rest
            .iter()
            .map(|p| *p * Vec3::new(1.05, 0.97, 1.0))
            .collect();
        Scene {
            rest,
            tets,
            stretched,
        }
    }
}

/// A named, repeatable operation.
struct Operation<'a> {
    id: &'static str,
    run: Box<dyn FnMut() + 'a>,
}

/// The operations of one mesh: force, fused, and the VBD calls (sequential, then parallel).
fn operations<'a>(
    body: &'a TetElastic<'a, StableNeoHookean>,
    masses: &'a [f32],
    x0: &'a [Vec3],
) -> Vec<Operation<'a>> {
    let n = x0.len();
    let t = body.mesh.element_count();
    let mut forces = vec![Vec3::ZERO; n];
    let mut fused_forces = vec![Vec3::ZERO; n];
    let mut operations = vec![
        Operation {
            id: "force_evaluation",
            run: Box::new(move || {
                forces.fill(Vec3::ZERO);
                body.mesh
                    .add_elastic_forces(&body.material, x0, &mut forces)
                    .unwrap();
                black_box(&forces);
            }),
        },
        Operation {
            id: "energy_and_forces",
            run: Box::new(move || {
                fused_forces.fill(Vec3::ZERO);
                black_box(body.energy_and_add_forces(x0, &mut fused_forces).unwrap());
            }),
        },
    ];
    let step_scene = StepScene::new(1.0 / 60.0);
    let settings = VbdSettings::new().with_line_search(0);
    #[cfg(feature = "rayon")]
    let (parallel_model, pool) = parallel_model(body);
    let vbd = |budget: u32, (parallel, layout): (bool, bool)| -> Box<dyn FnMut() + 'a> {
        let vectors: &'a mut [Vec3] =
            Box::leak(vec![Vec3::ZERO; scratch_len::vbd(n)].into_boxed_slice());
        let indices: &'a mut [u32] =
            Box::leak(vec![0; scratch_len::vbd_indices(n, t)].into_boxed_slice());
        let mut scratch = VbdScratch::new(vectors, indices);
        if layout {
            let values: &'a mut [f32] =
                Box::leak(vec![0.0; scratch_len::vbd_layout(t)].into_boxed_slice());
            let corners: &'a mut [u32] =
                Box::leak(vec![0; scratch_len::vbd_layout_corners(n, t)].into_boxed_slice());
            scratch = scratch.with_layout(values, corners);
        }
        let (mut x, mut v) = (x0.to_vec(), vec![Vec3::ZERO; n]);
        let settings = settings.with_tolerance(0.0, budget);
        let mut call = move || {
            x.copy_from_slice(x0);
            v.fill(Vec3::ZERO);
            let report = if parallel {
                #[cfg(feature = "rayon")]
                let report = pool.install(|| {
                    vbd_step(
                        parallel_model,
                        masses,
                        &[],
                        &step_scene,
                        &settings,
                        &mut x,
                        &mut v,
                        &mut scratch,
                    )
                });
                #[cfg(not(feature = "rayon"))]
                let report = vbd_step(
                    body,
                    masses,
                    &[],
                    &step_scene,
                    &settings,
                    &mut x,
                    &mut v,
                    &mut scratch,
                );
                report
            } else {
                vbd_step(
                    body,
                    masses,
                    &[],
                    &step_scene,
                    &settings,
                    &mut x,
                    &mut v,
                    &mut scratch,
                )
            };
            assert_eq!(report.unwrap().iterations, budget);
            assert_eq!(scratch.layout_in_use(), layout);
        };
        // The first call builds the topology (and the layout).
        call();
        Box::new(call)
    };
    for &(schedule, ids) in SCHEDULES {
        if schedule.0 && !cfg!(feature = "rayon") {
            continue;
        }
        for (&budget, id) in BUDGETS.iter().zip(ids) {
            operations.push(Operation {
                id,
                run: vbd(budget, schedule),
            });
        }
    }
    #[cfg(feature = "rayon")]
    {
        let mut forces = vec![Vec3::ZERO; n];
        operations.push(Operation {
            id: "energy_and_forces_parallel",
            run: Box::new(move || {
                forces.fill(Vec3::ZERO);
                let energy = pool.install(|| parallel_model.energy_and_add_forces(x0, &mut forces));
                black_box(energy.unwrap());
            }),
        });
    }
    operations
}

/// `body` partitioned into one piece per thread as a parallel model, and a pool of [`THREADS`]
/// threads (both leaked: they live as long as the bench).
#[cfg(feature = "rayon")]
fn parallel_model<'a>(
    body: &'a TetElastic<'a, StableNeoHookean>,
) -> (
    &'a ParallelTetElastic<'a, StableNeoHookean>,
    &'a rayon::ThreadPool,
) {
    let (n, t) = (body.mesh.vertex_count(), body.mesh.element_count());
    let offsets = vec![0; partition_offsets_len(n)].leak();
    let incident = vec![0; partition_incident_len(t)].leak();
    let partition = TetPartition::new(body.mesh, THREADS, offsets, incident).unwrap();
    let element_forces = vec![[Vec3::ZERO; 4]; element_forces_len(t)].leak();
    let energies = vec![0.0; t].leak();
    let model = ParallelTetElastic::new(*body, partition, element_forces, energies).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(THREADS)
        .build()
        .unwrap();
    (Box::leak(Box::new(model)), Box::leak(Box::new(pool)))
}

/// The VBD rows: (parallel, packed layout), and the ids of the calls of [`BUDGETS`] sweeps.
const SCHEDULES: &[((bool, bool), [&str; 2])] = &[
    ((false, false), ["vbd_1_sweep", "vbd_3_sweeps"]),
    ((false, true), ["vbd_layout_1_sweep", "vbd_layout_3_sweeps"]),
    (
        (true, true),
        ["vbd_parallel_1_sweep", "vbd_parallel_3_sweeps"],
    ),
];

fn criterion_group(c: &mut Criterion, tets: usize, operations: &mut [Operation<'_>]) {
    let mut group = c.benchmark_group(format!("vbd_{}k", (tets + 500) / 1000));
    group
        .sampling_mode(SamplingMode::Flat)
        .sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .throughput(Throughput::Elements(tets as u64));
    for operation in operations {
        group.bench_function(operation.id, |b| b.iter(&mut operation.run));
    }
    group.finish();
}

/// Times every operation round-robin (blocks of about `block`, the least of `rounds`) and
/// returns ns per call, in the order of `operations`.
fn table_pass(operations: &mut [Operation<'_>], block: Duration, rounds: u32) -> Vec<f64> {
    let mut calls = Vec::new();
    for operation in operations.iter_mut() {
        let start = Instant::now();
        (operation.run)();
        let once = start.elapsed().as_secs_f64().max(1e-9);
        calls.push((block.as_secs_f64() / once).ceil().clamp(1.0, 1e5) as u32);
    }
    let mut best = vec![f64::INFINITY; operations.len()];
    for _ in 0..rounds {
        for ((operation, best), &calls) in operations.iter_mut().zip(&mut best).zip(&calls) {
            let start = Instant::now();
            for _ in 0..calls {
                (operation.run)();
            }
            *best = best.min(start.elapsed().as_secs_f64() * 1e9 / f64::from(calls));
        }
    }
    best
}

/// One row per mesh (and schedule): ns per tetrahedron of the force pass, the fused pass (the
/// parallel model's in the parallel row), the VBD iteration and the sweep alone, and the sweep
/// in force passes.
fn rows(tets: usize, ns: &[f64]) -> Vec<Vec<String>> {
    let per_tet = |ns: f64| format!("{:.1}", ns / tets as f64);
    let force = ns[0];
    // The VBD calls, then (with feature `rayon`) the parallel model's fused pass.
    let vbd_end = (2 + 2 * SCHEDULES.len()).min(ns.len());
    let parallel_fused = ns.get(vbd_end).copied();
    let extra = f64::from(BUDGETS[1] - BUDGETS[0]);
    let mut rows = Vec::new();
    let names = [
        "sequential, gathered",
        "sequential, packed layout",
        "parallel, packed layout",
    ];
    let vbd = &ns[2..vbd_end];
    for ((schedule, pair), &((parallel, _), _)) in names.iter().zip(vbd.chunks(2)).zip(SCHEDULES) {
        let fused = match (parallel, parallel_fused) {
            (true, Some(fused)) => fused,
            _ => ns[1],
        };
        let iteration = (pair[1] - pair[0]) / extra;
        let sweep = iteration - fused;
        rows.push(vec![
            format!("{tets} tets, {schedule}"),
            per_tet(force),
            per_tet(fused),
            per_tet(iteration),
            per_tet(sweep),
            format!("{:.2}", sweep / force),
        ]);
    }
    rows
}

fn main() {
    let quick = common::quick();
    let plan = if quick {
        Some((Duration::from_millis(5), 3))
    } else {
        match common::table_pass() {
            TablePass::Skip => None,
            TablePass::Test => Some((Duration::ZERO, 1)),
            TablePass::Full => Some((Duration::from_millis(50), 7)),
        }
    };
    let cells: &[usize] = if quick { &CELLS[..1] } else { &CELLS };
    let mut criterion = Criterion::default()
        .without_plots()
        .warm_up_time(Duration::from_millis(300))
        .configure_from_args();
    let mut table = Vec::new();
    for &cells in cells {
        let scene = Scene::new(cells);
        let mut rest_data = vec![TetRest::default(); scene.tets.len()];
        let mesh = TetMesh::new(&scene.rest, &scene.tets, &mut rest_data).unwrap();
        let material = StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap();
        let body = TetElastic::new(mesh, material);
        let mut masses = vec![0.0; scene.rest.len()];
        mesh.lumped_masses(1000.0, &mut masses).unwrap();
        let mut operations = operations(&body, &masses, &scene.stretched);
        if !quick {
            criterion_group(&mut criterion, scene.tets.len(), &mut operations);
        }
        if let Some((block, rounds)) = plan {
            let ns = table_pass(&mut operations, block, rounds);
            // The raw minima, for comparing runs of two builds (the rows below are
            // differences of these).
            for (operation, ns) in operations.iter().zip(&ns) {
                eprintln!("raw {} {} {ns:.0} ns", scene.tets.len(), operation.id);
            }
            table.extend(rows(scene.tets.len(), &ns));
        }
    }
    if !quick {
        criterion.final_summary();
    }
    if table.is_empty() {
        return;
    }
    println!(
        "\nVBD sweep against one force evaluation, f32, {}:",
        common::machine()
    );
    common::print_markdown_table(
        &[
            "mesh",
            "force ns/tet",
            "energy+force ns/tet",
            "VBD iteration ns/tet",
            "sweep ns/tet",
            "sweep / force",
        ],
        table,
    );
}

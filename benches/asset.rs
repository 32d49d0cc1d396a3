//! Cost of the asset pipeline (issue 18): per render vertex, deforming an embedded render
//! surface each frame (`Embedding::deform`) and that plus its vertex normals
//! (`surface::vertex_normals`); the one-off costs of binding the render vertices
//! (`embed::embed_points_vec`) and of voxel-meshing the surface (`voxel::voxel_mesh`). Single
//! thread, f32.
//!
//! The render surface: an icosphere of radius 0.1 m subdivided 5 times (10 242 vertices, 20 480
//! triangles), the case of a detailed render mesh over a coarse body. The body: its voxel mesh
//! with 10 cells along the diameter (centre sampling), the render vertices bound within a margin
//! of one cell diagonal.
//!
//! `cargo bench -p softfem-benches --bench asset` runs criterion for the two per-frame operations
//! and then prints a table from a plain `Instant` pass (minimum over rounds).
//! `SOFTFEM_BENCH_QUICK=1` skips criterion and prints the table from a few repetitions: a smoke
//! test.

mod common;
// The tests' icosphere, so that the surface is written once.
#[path = "../tests/common/shapes.rs"]
mod shapes;

use std::hint::black_box;
use std::time::{Duration, Instant};

use common::TablePass;
use criterion::Criterion;
use softfem::asset::embed::{Embedded, Embedding, embed_points_vec};
use softfem::asset::surface::vertex_normals;
use softfem::asset::voxel::{VoxelGrid, VoxelMesh, VoxelOptions, voxel_mesh};
use softfem::glam::Vec3;

struct Inputs {
    surface: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    body: VoxelMesh,
    margin: f32,
    embedded: Vec<Embedded>,
    /// The body's vertices after a shear and a lift, standing in for a simulated frame.
    moved: Vec<Vec3>,
}

impl Inputs {
    fn new() -> Inputs {
        let (surface, triangles) = shapes::icosphere(Vec3::ZERO, 0.1, 5);
        let body = mesh(&surface, &triangles);
        let margin = body.grid.cell_size * 3f32.sqrt();
        let embedded = embed_points_vec(&body.positions, &body.tets, &surface, margin).unwrap();
        let moved = body
            .positions
            .iter()
            .map(|x| Vec3::new(x.x + 0.3 * x.z, x.y, 0.9 * x.z + 0.5))
            .collect();
        Inputs {
            surface,
            triangles,
            body,
            margin,
            embedded,
            moved,
        }
    }

    fn embedding(&self) -> Embedding<'_> {
        Embedding::new(&self.embedded, &self.body.tets, self.body.positions.len()).unwrap()
    }
}

fn mesh(surface: &[Vec3], triangles: &[[u32; 3]]) -> VoxelMesh {
    let grid = VoxelGrid::with_resolution(surface, 10).unwrap();
    voxel_mesh(surface, triangles, &grid, &VoxelOptions::default()).unwrap()
}

fn deform(inputs: &Inputs, embedding: &Embedding<'_>, render: &mut [Vec3]) {
    embedding.deform(black_box(&inputs.moved), render).unwrap();
    black_box(render);
}

fn deform_with_normals(
    inputs: &Inputs,
    embedding: &Embedding<'_>,
    render: &mut [Vec3],
    normals: &mut [Vec3],
) {
    embedding.deform(black_box(&inputs.moved), render).unwrap();
    vertex_normals(render, &inputs.triangles, normals).unwrap();
    black_box(normals);
}

fn print_table(inputs: &Inputs, repetitions: u32, rounds: u32) {
    let embedding = inputs.embedding();
    let n = inputs.surface.len();
    let mut render = vec![Vec3::ZERO; n];
    let mut normals = vec![Vec3::ZERO; n];
    let per_frame = common::round_robin_min_ns(
        &mut [0, 1],
        |which| {
            if *which == 0 {
                deform(inputs, &embedding, &mut render);
            } else {
                deform_with_normals(inputs, &embedding, &mut render, &mut normals);
            }
        },
        repetitions,
        n,
        rounds,
    );
    let one_off = |run: &mut dyn FnMut()| {
        (0..rounds.clamp(1, 3))
            .map(|_| {
                let started = Instant::now();
                run();
                started.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let bind = one_off(&mut || {
        black_box(
            embed_points_vec(
                &inputs.body.positions,
                &inputs.body.tets,
                &inputs.surface,
                inputs.margin,
            )
            .unwrap(),
        );
    });
    let voxelise = one_off(&mut || {
        black_box(mesh(&inputs.surface, &inputs.triangles));
    });
    println!();
    println!(
        "Render surface {} vertices / {} triangles over {} tetrahedra ({} vertices), {}:",
        n,
        inputs.triangles.len(),
        inputs.body.tets.len(),
        inputs.body.positions.len(),
        common::machine()
    );
    common::print_markdown_table(
        &["operation", "per render vertex", "total"],
        [
            ("deform (each frame)", per_frame[0] * 1e-9 * n as f64),
            (
                "deform + vertex normals (each frame)",
                per_frame[1] * 1e-9 * n as f64,
            ),
            ("bind render vertices (once)", bind),
            ("voxel mesh, 10 cells (once)", voxelise),
        ]
        .map(|(name, seconds)| {
            vec![
                name.to_string(),
                format!("{:.1} ns", seconds * 1e9 / n as f64),
                format!("{:.3} ms", seconds * 1e3),
            ]
        }),
    );
}

fn main() {
    let inputs = Inputs::new();
    if common::quick() {
        print_table(&inputs, 3, 2);
        return;
    }
    let mut criterion = Criterion::default()
        .without_plots()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30)
        .configure_from_args();
    {
        let embedding = inputs.embedding();
        let n = inputs.surface.len();
        let mut render = vec![Vec3::ZERO; n];
        let mut normals = vec![Vec3::ZERO; n];
        let mut group = criterion.benchmark_group("asset");
        group.throughput(criterion::Throughput::Elements(n as u64));
        group.bench_function("deform", |b| {
            b.iter(|| deform(&inputs, &embedding, &mut render))
        });
        group.bench_function("deform + normals", |b| {
            b.iter(|| deform_with_normals(&inputs, &embedding, &mut render, &mut normals))
        });
        group.finish();
    }
    criterion.final_summary();
    match common::table_pass() {
        TablePass::Skip => {}
        TablePass::Test => print_table(&inputs, 1, 1),
        TablePass::Full => print_table(&inputs, 200, 5),
    }
}

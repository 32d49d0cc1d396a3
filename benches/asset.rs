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
//! `cargo bench --bench asset` runs criterion for the two per-frame operations and then prints a
//! table from a plain `Instant` pass (minimum over rounds). `SOFTFEM_BENCH_QUICK=1` skips
//! criterion and prints the table from a few repetitions: a smoke test.

mod common;

use std::hint::black_box;
use std::time::{Duration, Instant};

use common::TablePass;
use criterion::Criterion;
use softfem::embed::{Embedded, Embedding, embed_points_vec};
use softfem::glam::Vec3;
use softfem::surface::vertex_normals;
use softfem::voxel::{VoxelGrid, VoxelMesh, VoxelOptions, voxel_mesh};

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
        let (surface, triangles) = icosphere(0.1, 5);
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

/// An icosahedron subdivided `levels` times on the sphere of `radius` about the origin.
fn icosphere(radius: f32, levels: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut points: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| Vec3::from_array(p).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut midpoints = std::collections::HashMap::new();
        let mut finer = Vec::with_capacity(triangles.len() * 4);
        for &[a, b, c] in &triangles {
            let mut midpoint = |u: u32, v: u32| {
                *midpoints.entry((u.min(v), u.max(v))).or_insert_with(|| {
                    points.push((points[u as usize] + points[v as usize]).normalize());
                    (points.len() - 1) as u32
                })
            };
            let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    (points.iter().map(|&p| p * radius).collect(), triangles)
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

//! Render-mesh embedding: affine motions are reproduced exactly (to rounding) for points inside
//! and just outside the simulation mesh, weights sum to 1 (and lie in [0, 1] inside), points
//! beyond the margin are named, and the cost per render vertex is printed by an ignored test.
#![cfg(feature = "std")]

use crate::common::shapes;

use softfem::EmbedError;
use softfem::asset::embed::{Embedded, Embedding, TetLookup, embed_points, embed_points_vec};
use softfem::asset::voxel::{VoxelGrid, VoxelOptions, voxel_mesh};
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::{Mat3, Vec3};

fn unit_box(cells: usize) -> (Vec<Vec3>, Vec<[u32; 4]>) {
    let (vertex_count, tet_count) =
        box_counts(cells, cells, cells, BoxSplit::Alternating5).unwrap();
    let mut positions = vec![Vec3::ZERO; vertex_count];
    let mut tets = vec![[0; 4]; tet_count];
    fill_box(
        Vec3::ZERO,
        Vec3::ONE,
        cells,
        cells,
        cells,
        BoxSplit::Alternating5,
        &mut positions,
        &mut tets,
    )
    .unwrap();
    (positions, tets)
}

/// Deterministic points in `[lo, hi]^3` (a Weyl sequence: no dependency, no repetition).
fn points(count: usize, lo: f32, hi: f32) -> Vec<Vec3> {
    let alpha = [0.754_877_7_f64, 0.569_840_3, 0.438_133_4];
    (1..=count)
        .map(|n| {
            let t = alpha.map(|a| (a * n as f64).fract() as f32);
            Vec3::new(t[0], t[1], t[2]) * (hi - lo) + Vec3::splat(lo)
        })
        .collect()
}

/// A shear, rotation and stretch with a translation: any affine map.
fn affine() -> (Mat3, Vec3) {
    let a = Mat3::from_cols(
        Vec3::new(1.2, 0.1, -0.3),
        Vec3::new(0.2, 0.8, 0.1),
        Vec3::new(-0.1, 0.4, 1.1),
    );
    (a, Vec3::new(0.3, -2.0, 5.0))
}

/// The rounding budget of one barycentric combination: weights carry a few ulp of relative
/// error each (from Dm^-1), times coordinates of order 5 m after the map; 1e-5 m is ~20 ulp.
const AFFINE_TOLERANCE: f32 = 1e-5;

#[test]
fn affine_motion_is_exact_inside_and_within_the_margin() {
    let (rest, tets) = unit_box(4);
    let margin = 0.1;
    // Points inside and in a shell up to 0.05 m outside each face (within the margin, also at
    // the corners: the corner distance is at most 0.05 sqrt 3 < 0.1).
    let render = points(2000, -0.05, 1.05);
    let embedded = embed_points_vec(&rest, &tets, &render, margin).unwrap();
    let embedding = Embedding::new(&embedded, &tets, rest.len()).unwrap();

    for (p, e) in render.iter().zip(&embedded) {
        let sum: f32 = e.weights.iter().sum();
        assert!((sum - 1.0).abs() < 1e-6, "{sum}");
        let inside = p.cmpge(Vec3::ZERO).all() && p.cmple(Vec3::ONE).all();
        if inside {
            assert!(
                e.weights.iter().all(|&w| (-1e-6..=1.0 + 1e-6).contains(&w)),
                "{p}: {e:?}"
            );
        }
    }

    let (a, t) = affine();
    let moved: Vec<Vec3> = rest.iter().map(|&x| a * x + t).collect();
    let mut out = vec![Vec3::ZERO; render.len()];
    embedding.deform(&moved, &mut out).unwrap();
    for (p, x) in render.iter().zip(&out) {
        let expected = a * *p + t;
        assert!(
            (*x - expected).length() < AFFINE_TOLERANCE,
            "{p}: {x} vs {expected}"
        );
    }
    // At rest, the embedding gives back the points.
    embedding.deform(&rest, &mut out).unwrap();
    for (p, x) in render.iter().zip(&out) {
        assert!((*x - *p).length() < 1e-6);
    }
}

#[test]
fn points_beyond_the_margin_are_named() {
    let (rest, tets) = unit_box(2);
    let mut render = points(10, 0.1, 0.9);
    render.insert(4, Vec3::new(0.5, 0.5, 1.2)); // 0.2 m above the top face
    assert_eq!(
        embed_points_vec(&rest, &tets, &render, 0.1),
        Err(EmbedError::Outside { point: 4 })
    );
    // With a margin that reaches it, it attaches, to a tetrahedron of the top layer.
    let embedded = embed_points_vec(&rest, &tets, &render, 0.25).unwrap();
    let top = tets[embedded[4].tet as usize].map(|v| rest[v as usize].z);
    assert!(top.contains(&1.0));
    let mut bad = render.clone();
    bad[2].x = f32::NAN;
    assert_eq!(
        embed_points_vec(&rest, &tets, &bad, 0.1),
        Err(EmbedError::NonFinitePoint { point: 2 })
    );
}

#[test]
fn buffers_and_indices_are_checked() {
    let (rest, tets) = unit_box(2);
    let plan = TetLookup::plan(&rest, &tets, Some(0.3), 0.0).unwrap();
    let mut starts = vec![0; plan.starts_len];
    let mut entries = vec![0; plan.entries_len + 1];
    assert!(matches!(
        TetLookup::build(&plan, &rest, &tets, &mut starts, &mut entries),
        Err(EmbedError::BufferLength { .. })
    ));
    let mut entries = vec![0; plan.entries_len];
    let lookup = TetLookup::build(&plan, &rest, &tets, &mut starts, &mut entries).unwrap();
    let (starts, entries) = (lookup.starts(), lookup.entries());
    // Every bucket lists its tetrahedra in increasing order, and every tetrahedron is listed.
    let mut listed = vec![false; tets.len()];
    for window in starts.windows(2) {
        let bucket = &entries[window[0] as usize..window[1] as usize];
        assert!(bucket.windows(2).all(|w| w[0] < w[1]));
        bucket.iter().for_each(|&t| listed[t as usize] = true);
    }
    assert!(listed.iter().all(|&l| l));
    let mut out = vec![Embedded::default(); 2];
    assert!(matches!(
        embed_points(&lookup, &rest, &tets, &[Vec3::splat(0.5)], &mut out),
        Err(EmbedError::BufferLength { .. })
    ));

    let bad = [Embedded {
        weights: [0.25; 4],
        tet: tets.len() as u32,
    }];
    assert!(matches!(
        Embedding::new(&bad, &tets, rest.len()),
        Err(EmbedError::IndexOutOfRange { .. })
    ));
    assert_eq!(
        TetLookup::plan(&rest, &tets, None, -1.0),
        Err(EmbedError::Settings)
    );
    let flat = [[0, 1, 2, 3]];
    let coplanar = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, 0.0)];
    assert_eq!(
        embed_points_vec(&coplanar, &flat, &[Vec3::splat(0.1)], 0.5),
        Err(EmbedError::DegenerateTet { tet: 0 })
    );
}

/// The realistic case: an asset's own surface embedded in its voxel mesh. Centre sampling puts
/// the surface up to about a cell diagonal outside the voxels, so the margin is one cell
/// diagonal.
#[test]
fn a_surface_embeds_in_its_own_voxel_mesh() {
    let (surface, triangles) = shapes::icosphere(Vec3::ZERO, 0.5, 3);
    let grid = VoxelGrid::with_resolution(&surface, 8).unwrap();
    let mesh = voxel_mesh(&surface, &triangles, &grid, &VoxelOptions::default()).unwrap();
    let margin = grid.cell_size * 3f32.sqrt();
    let embedded = embed_points_vec(&mesh.positions, &mesh.tets, &surface, margin).unwrap();
    let embedding = Embedding::new(&embedded, &mesh.tets, mesh.positions.len()).unwrap();
    let (a, t) = affine();
    let moved: Vec<Vec3> = mesh.positions.iter().map(|&x| a * x + t).collect();
    let mut out = vec![Vec3::ZERO; surface.len()];
    embedding.deform(&moved, &mut out).unwrap();
    for (p, x) in surface.iter().zip(&out) {
        assert!((*x - (a * *p + t)).length() < AFFINE_TOLERANCE);
    }
}

/// Cost per render vertex of `Embedding::deform`:
/// `cargo test --release --all-features --test assets embed:: -- --ignored --nocapture`.
#[test]
#[ignore]
fn print_deform_cost() {
    let (rest, tets) = unit_box(10); // 5 000 tetrahedra
    let render = points(100_000, 0.0, 1.0);
    let started = std::time::Instant::now();
    let embedded = embed_points_vec(&rest, &tets, &render, 0.0).unwrap();
    let build = started.elapsed();
    let embedding = Embedding::new(&embedded, &tets, rest.len()).unwrap();
    let (a, t) = affine();
    let moved: Vec<Vec3> = rest.iter().map(|&x| a * x + t).collect();
    let mut out = vec![Vec3::ZERO; render.len()];
    let frames = 200;
    let started = std::time::Instant::now();
    for _ in 0..frames {
        embedding
            .deform(std::hint::black_box(&moved), &mut out)
            .unwrap();
        std::hint::black_box(&out);
    }
    let per_vertex = started.elapsed().as_secs_f64() * 1e9 / (frames * render.len()) as f64;
    println!(
        "embed: {} render points in {} tets: binding {:.1} ms ({:.0} ns/point), deform {per_vertex:.2} ns per render vertex",
        render.len(),
        tets.len(),
        build.as_secs_f64() * 1e3,
        build.as_secs_f64() * 1e9 / render.len() as f64
    );
}

/// Nanson's formula: under an affine map `x -> A x + t` a normal becomes `A^-T n` (normalised),
/// whatever the tetrahedron; the render normals follow it to rounding.
#[test]
fn normals_follow_the_inverse_transpose_of_an_affine_map() {
    use softfem::element::TetRest;
    use softfem::mesh::TetMesh;
    let (rest, tets) = unit_box(3);
    let render = points(500, 0.0, 1.0);
    let normals: Vec<Vec3> = points(500, -1.0, 1.0)
        .iter()
        .map(|n| (*n + Vec3::new(0.01, 0.0, 0.0)).normalize())
        .collect();
    let embedded = embed_points_vec(&rest, &tets, &render, 0.0).unwrap();
    let embedding = Embedding::new(&embedded, &tets, rest.len()).unwrap();
    let mut rest_data = vec![TetRest::default(); tets.len()];
    TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
    let (a, t) = affine();
    let moved: Vec<Vec3> = rest.iter().map(|&x| a * x + t).collect();
    let mut out = vec![Vec3::ZERO; render.len()];
    embedding
        .deform_normals(&rest_data, &moved, &normals, &mut out)
        .unwrap();
    let inverse_transpose = a.inverse().transpose();
    for (n, deformed) in normals.iter().zip(&out) {
        let expected = (inverse_transpose * *n).normalize();
        // Unit vectors: a few ulp of F's rounding, amplified by A's condition number (~3).
        assert!(
            (*deformed - expected).length() < 1e-5,
            "{n}: {deformed} vs {expected}"
        );
    }
    assert!(matches!(
        embedding.deform_normals(&rest_data[1..], &moved, &normals, &mut out),
        Err(EmbedError::BufferLength { .. })
    ));
}

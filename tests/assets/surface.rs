//! Surface buffers: the boundary of a generated box and of a voxel mesh is closed, outward and
//! encloses the mesh volume (divergence theorem); vertex normals of a sphere are radial; the
//! render types cast to bytes with the `bytemuck` feature.
#![cfg(feature = "std")]

use crate::common::shapes;

use std::collections::HashMap;

use softfem::SurfaceError;
use softfem::asset::surface::{
    BoundaryFace, RenderVertex, boundary_faces, boundary_scratch_len, interleave, surface_area,
    vertex_normals,
};
use softfem::asset::voxel::{VoxelGrid, VoxelOptions, voxel_mesh};
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::Vec3;

fn boundary(tets: &[[u32; 4]], vertex_count: usize) -> Vec<BoundaryFace> {
    let mut scratch = vec![BoundaryFace::default(); boundary_scratch_len(tets.len())];
    boundary_faces(tets, vertex_count, &mut scratch)
        .unwrap()
        .to_vec()
}

/// Every directed edge once and its reverse once: closed and consistently oriented.
fn assert_closed(triangles: &[[u32; 3]]) {
    let mut edges = HashMap::new();
    for &[a, b, c] in triangles {
        for edge in [[a, b], [b, c], [c, a]] {
            *edges.entry(edge).or_insert(0) += 1;
        }
    }
    for (&[a, b], &count) in &edges {
        assert_eq!(count, 1);
        assert_eq!(edges.get(&[b, a]), Some(&1));
    }
}

#[test]
fn box_boundary_is_outward_closed_and_encloses_the_box() {
    for split in [BoxSplit::Kuhn6, BoxSplit::Alternating5] {
        let [nx, ny, nz] = [3, 2, 4];
        let max = Vec3::new(3.0, 2.0, 4.0);
        let (x, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, max, (nx, ny, nz), split);
        let faces = boundary(&tets, x.len());
        // Two triangles per unit square of the box's six sides.
        assert_eq!(faces.len(), 2 * 2 * (nx * ny + ny * nz + nz * nx));
        assert!(faces.windows(2).all(|w| w[0].tet <= w[1].tet));
        for face in &faces {
            let [a, b, c] = face.triangle.map(|v| x[v as usize]);
            let normal = (b - a).cross(c - a);
            let centre = (a + b + c) / 3.0;
            // Outward: the normal points away from the box centre (exact on integer corners).
            assert!(normal.dot(centre - max / 2.0) > 0.0, "{split:?} {face:?}");
            assert!(
                face.triangle
                    .iter()
                    .all(|v| tets[face.tet as usize].contains(v))
            );
        }
        let triangles: Vec<[u32; 3]> = faces.iter().map(|f| f.triangle).collect();
        assert_closed(&triangles);
        assert!((surface_area(&x, &triangles) - 52.0).abs() < 1e-4);
        assert!((shapes::enclosed_volume(&x, &triangles) - 24.0).abs() < 1e-9);
    }
}

#[test]
fn voxel_mesh_boundary_encloses_the_mesh_volume() {
    let (surface, triangles) = shapes::torus(1.0, 0.4, 32, 16);
    let grid = VoxelGrid::with_resolution(&surface, 12).unwrap();
    let mesh = voxel_mesh(&surface, &triangles, &grid, &VoxelOptions::default()).unwrap();
    let faces: Vec<[u32; 3]> = boundary(&mesh.tets, mesh.positions.len())
        .iter()
        .map(|f| f.triangle)
        .collect();
    assert_closed(&faces);
    let enclosed = shapes::enclosed_volume(&mesh.positions, &faces);
    let volume = shapes::tet_volume(&mesh.positions, &mesh.tets);
    assert!(
        (enclosed - volume).abs() < 1e-9 * volume.max(1.0),
        "{enclosed} {volume}"
    );
}

/// On a fine icosphere the area-weighted vertex normal is the radial direction to within the
/// angle between neighbouring vertices (~4 degrees at 3 subdivisions; checked to cos > 0.999).
#[test]
fn sphere_vertex_normals_are_radial_and_unit() {
    let centre = Vec3::new(1.0, 2.0, -3.0);
    let (positions, triangles) = shapes::icosphere(centre, 2.0, 3);
    let mut normals = vec![Vec3::ZERO; positions.len()];
    vertex_normals(&positions, &triangles, &mut normals).unwrap();
    for (x, n) in positions.iter().zip(&normals) {
        assert!((n.length() - 1.0).abs() < 1e-6);
        assert!(n.dot((*x - centre).normalize()) > 0.999);
    }
    let mut vertices = vec![RenderVertex::default(); positions.len()];
    interleave(&positions, &normals, &mut vertices).unwrap();
    assert_eq!(vertices[7].position, positions[7]);
    assert_eq!(vertices[7].normal, normals[7]);
}

#[test]
fn unused_vertices_get_zero_normals_and_bad_input_is_named() {
    let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::splat(9.0)];
    let mut normals = [Vec3::ONE; 4];
    vertex_normals(&positions, &[[0, 1, 2]], &mut normals).unwrap();
    assert_eq!(normals, [Vec3::Z, Vec3::Z, Vec3::Z, Vec3::ZERO]);
    assert_eq!(
        vertex_normals(&positions, &[[0, 1, 2], [0, 4, 1]], &mut normals),
        Err(SurfaceError::IndexOutOfRange {
            element: 1,
            index: 4
        })
    );
    let mut scratch = vec![BoundaryFace::default(); 3];
    assert_eq!(
        boundary_faces(&[[0, 1, 2, 3]], 4, &mut scratch),
        Err(SurfaceError::BufferLength {
            expected: 4,
            actual: 3
        })
    );
    let mut scratch = vec![BoundaryFace::default(); 4];
    assert_eq!(
        boundary_faces(&[[0, 1, 2, 7]], 4, &mut scratch),
        Err(SurfaceError::IndexOutOfRange {
            element: 0,
            index: 7
        })
    );
}

#[cfg(feature = "bytemuck")]
#[test]
fn render_types_cast_to_bytes() {
    let vertices = [RenderVertex {
        position: Vec3::new(1.0, 2.0, 3.0),
        normal: Vec3::Z,
    }];
    let bytes: &[u8] = bytemuck::cast_slice(&vertices);
    assert_eq!(bytes.len(), 24);
    let floats: &[f32] = bytemuck::cast_slice(&vertices);
    assert_eq!(floats, &[1.0, 2.0, 3.0, 0.0, 0.0, 1.0]);
    let faces = [BoundaryFace {
        triangle: [4, 5, 6],
        tet: 9,
    }];
    let words: &[u32] = bytemuck::cast_slice(&faces);
    assert_eq!(words, &[4, 5, 6, 9]);
}

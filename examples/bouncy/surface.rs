//! The boundary surface of a tetrahedral mesh: the faces used by exactly one tetrahedron
//! (computed by the library's `softfem::asset::surface::boundary_faces`).

use softfem::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};

/// Boundary triangles of a tetrahedral mesh.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Surface {
    /// Vertex indices, counter-clockwise seen from outside the body.
    pub triangles: Vec<[u32; 3]>,
    /// For each triangle, the tetrahedron it belongs to.
    pub owners: Vec<u32>,
}

impl Surface {
    /// The faces of `tets` that no other tetrahedron shares, oriented outward.
    ///
    /// Every tetrahedron must be positively oriented (as `TetMesh::new` requires), and the mesh
    /// conforming, so that an interior face is listed by exactly two tetrahedra. A face listed
    /// three or more times (a non-manifold mesh) is not boundary and is dropped. Triangles come
    /// in the order of their tetrahedra, so the result is deterministic.
    pub fn of_tets(tets: &[[u32; 4]]) -> Surface {
        let vertex_count = tets.iter().flatten().max().map_or(0, |&v| v as usize + 1);
        let mut scratch = vec![BoundaryFace::default(); boundary_scratch_len(tets.len())];
        let faces = boundary_faces(tets, vertex_count, &mut scratch)
            .expect("the scratch has the documented length and every index is below the count");
        Surface {
            triangles: faces.iter().map(|face| face.triangle).collect(),
            owners: faces.iter().map(|face| face.tet).collect(),
        }
    }

    /// The number of boundary triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use softfem::generate::{BoxSplit, box_counts, fill_box};
    use softfem::glam::Vec3;
    use std::collections::HashMap;

    fn generated_box(cells: [usize; 3], split: BoxSplit) -> (Vec<Vec3>, Vec<[u32; 4]>) {
        let [nx, ny, nz] = cells;
        let (vertex_count, tet_count) = box_counts(nx, ny, nz, split).unwrap();
        let mut positions = vec![Vec3::ZERO; vertex_count];
        let mut tets = vec![[0; 4]; tet_count];
        let max = Vec3::new(nx as f32, ny as f32, nz as f32);
        fill_box(
            Vec3::ZERO,
            max,
            nx,
            ny,
            nz,
            split,
            &mut positions,
            &mut tets,
        )
        .unwrap();
        (positions, tets)
    }

    #[test]
    fn a_single_tet_is_its_own_surface_and_faces_outward() {
        let x = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let surface = Surface::of_tets(&[[0, 1, 2, 3]]);
        assert_eq!(surface.len(), 4);
        let centroid = x.iter().sum::<Vec3>() / 4.0;
        for [a, b, c] in surface.triangles {
            let [xa, xb, xc] = [a, b, c].map(|v| x[v as usize]);
            let normal = (xb - xa).cross(xc - xa);
            assert!(normal.dot((xa + xb + xc) / 3.0 - centroid) > 0.0);
        }
    }

    /// A box of `nx x ny x nz` unit cubes has `2 (nx ny + ny nz + nz nx)` unit squares on its
    /// boundary, each cut into two triangles; each triangle lies in one side of the box and its
    /// normal is that side's outward axis, with area 1/2.
    #[test]
    fn box_surface_has_two_triangles_per_boundary_square_all_outward() {
        for split in [BoxSplit::Kuhn6, BoxSplit::Alternating5] {
            let cells = [3, 2, 4];
            let (x, tets) = generated_box(cells, split);
            let surface = Surface::of_tets(&tets);
            let [nx, ny, nz] = cells;
            assert_eq!(
                surface.len(),
                2 * 2 * (nx * ny + ny * nz + nz * nx),
                "{split:?}"
            );
            assert_eq!(surface.owners.len(), surface.len());
            let max = Vec3::new(nx as f32, ny as f32, nz as f32);
            for (&[a, b, c], &owner) in surface.triangles.iter().zip(&surface.owners) {
                assert!(tets[owner as usize].contains(&a));
                let [xa, xb, xc] = [a, b, c].map(|v| x[v as usize]);
                let normal = (xb - xa).cross(xc - xa);
                // Exact: the coordinates are small integers.
                assert_eq!(normal.length(), 1.0, "area 1/2");
                let on_side =
                    |axis: usize, value: f32| [xa, xb, xc].iter().all(|p| p[axis] == value);
                let expected = (0..3)
                    .find_map(|axis| {
                        if on_side(axis, 0.0) {
                            Some(-Vec3::AXES[axis])
                        } else if on_side(axis, max[axis]) {
                            Some(Vec3::AXES[axis])
                        } else {
                            None
                        }
                    })
                    .expect("every boundary triangle lies in a side of the box");
                assert_eq!(normal, expected, "{split:?}: [{a}, {b}, {c}]");
            }
        }
    }

    /// A closed, consistently oriented surface: every directed edge appears once and its
    /// reverse once, and the divergence theorem gives back the enclosed volume.
    #[test]
    fn box_surface_is_closed_and_encloses_the_box_volume() {
        let (x, tets) = generated_box([2, 3, 2], BoxSplit::Kuhn6);
        let surface = Surface::of_tets(&tets);
        let mut edges = HashMap::new();
        for [a, b, c] in &surface.triangles {
            for edge in [[*a, *b], [*b, *c], [*c, *a]] {
                *edges.entry(edge).or_insert(0) += 1;
            }
        }
        for (&[a, b], &count) in &edges {
            assert_eq!(count, 1);
            assert_eq!(edges.get(&[b, a]), Some(&1));
        }
        let volume: f32 = surface
            .triangles
            .iter()
            .map(|t| t.map(|v| x[v as usize]))
            .map(|[xa, xb, xc]| xa.dot(xb.cross(xc)) / 6.0)
            .sum();
        assert!((volume - 12.0).abs() < 1e-4, "{volume}");
    }
}

//! The mesh generators against the geometry and topology they promise, in both precisions.
//!
//! Tetrahedral boxes: counts, vertex numbering, positive volume of every tetrahedron in the
//! generator's own precision, the exact share of its cube each tetrahedron takes, volumes
//! summing to the box's, face conformity (every interior face shared by exactly two tetrahedra
//! with opposite orientations, boundary faces once), boundary faces lying on the box surface,
//! facing outwards and tiling each side, and the Euler characteristic of a ball. Rectangles:
//! the same in 2D with edges. Errors: every `GenerateError` variant, buffers untouched.
//!
//! The geometry checks run in f64 on the generated positions, so their only rounding is f64's;
//! the tolerances below are stated against that. The test code is written once, in
//! `generate_tests!`, and instantiated for the f32 API at the crate root and the f64 API under
//! `softfem::f64`.

use std::collections::{HashMap, HashSet};

type P3 = [f64; 3];

fn sub(a: P3, b: P3) -> P3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: P3, b: P3) -> P3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: P3, b: P3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: P3) -> f64 {
    dot(a, a).sqrt()
}

/// `det([x1 - x0, x2 - x0, x3 - x0]) / 6` in f64.
fn tet_volume(x: [P3; 4]) -> f64 {
    dot(cross(sub(x[1], x[0]), sub(x[2], x[0])), sub(x[3], x[0])) / 6.0
}

fn sorted<const N: usize>(mut indices: [u32; N]) -> [u32; N] {
    indices.sort_unstable();
    indices
}

/// The rotation of a cycle that starts at its smallest index, so that two orderings of the
/// same oriented polygon compare equal.
fn canonical_cycle(face: [u32; 3]) -> [u32; 3] {
    let start = (0..3).min_by_key(|&r| face[r]).unwrap();
    [face[start], face[(start + 1) % 3], face[(start + 2) % 3]]
}

/// The four faces of a positively oriented tetrahedron `[a, b, c, d]`, each ordered so that its
/// right-hand normal points out of the tetrahedron (checked on the unit tetrahedron: `[a, c, b]`
/// has normal `e2 x e1 = -e3`, away from `d`).
fn outward_faces([a, b, c, d]: [u32; 4]) -> [[u32; 3]; 4] {
    [[b, c, d], [a, d, c], [a, b, d], [a, c, b]]
}

/// Everything a conforming, positively oriented tetrahedralisation of the box `[min, max]` must
/// satisfy, checked on f64 copies of the generated positions. `cell_counts` is `[nx, ny, nz]`.
fn check_box_mesh(
    positions: &[P3],
    tets: &[[u32; 4]],
    min: P3,
    max: P3,
    cell_counts: [usize; 3],
    relative_eps: f64,
) {
    let box_volume = (max[0] - min[0]) * (max[1] - min[1]) * (max[2] - min[2]);

    // Every index is in range and every vertex is used.
    let mut used = vec![false; positions.len()];
    for tet in tets {
        for &v in tet {
            assert!((v as usize) < positions.len(), "index {v} out of range");
            used[v as usize] = true;
        }
    }
    assert!(
        used.iter().all(|&u| u),
        "a vertex belongs to no tetrahedron"
    );

    // The volumes add up to the box's. The vertices on the box surface are exactly at `min` or
    // `max` (the generator's endpoints are exact), so a conforming tiling has exactly the box's
    // volume whatever the rounding of interior grid points; what is left is f64 rounding of
    // each volume (a few 1e-16 relative) summed over at most a few hundred tetrahedra.
    let volume: f64 = tets
        .iter()
        .map(|t| tet_volume(t.map(|v| positions[v as usize])))
        .sum();
    assert!(
        (volume - box_volume).abs() <= 1e-12 * box_volume,
        "volumes sum to {volume}, box volume {box_volume}"
    );

    // Faces: each oriented face of each tetrahedron, keyed by its vertex set.
    let mut faces: HashMap<[u32; 3], Vec<[u32; 3]>> = HashMap::new();
    for &tet in tets {
        for face in outward_faces(tet) {
            faces.entry(sorted(face)).or_default().push(face);
        }
    }
    let mut boundary_area_per_side = [0.0f64; 6];
    let mut boundary_faces_per_side = [0usize; 6];
    for (key, uses) in &faces {
        match uses.as_slice() {
            [first, second] => {
                // Interior: the two tetrahedra lie on opposite sides of the face, so they
                // traverse it in opposite directions.
                let reversed = [second[0], second[2], second[1]];
                assert_eq!(
                    canonical_cycle(*first),
                    canonical_cycle(reversed),
                    "interior face {key:?} has the same orientation in both tetrahedra"
                );
            }
            [face] => {
                // Boundary: all three vertices on one side of the box, facing out of it.
                let x = face.map(|v| positions[v as usize]);
                let side = (0..6)
                    .find(|&side| {
                        let (axis, plane) = if side < 3 {
                            (side, min[side])
                        } else {
                            (side - 3, max[side - 3])
                        };
                        x.iter().all(|p| p[axis] == plane)
                    })
                    .unwrap_or_else(|| panic!("boundary face {face:?} is not on the box surface"));
                let normal = cross(sub(x[1], x[0]), sub(x[2], x[0]));
                let outward = if side < 3 {
                    -normal[side]
                } else {
                    normal[side - 3]
                };
                assert!(outward > 0.0, "boundary face {face:?} faces into the box");
                boundary_area_per_side[side] += norm(normal) / 2.0;
                boundary_faces_per_side[side] += 1;
            }
            _ => panic!("face {key:?} is shared by {} tetrahedra", uses.len()),
        }
    }

    // The boundary faces tile each side: they lie in it, all face outwards (so none overlaps
    // another with opposite orientation), and their areas add up to the side's. Each square on
    // a side is cut into two triangles.
    let [nx, ny, nz] = cell_counts;
    let extent = sub(max, min);
    for side in 0..6 {
        let axis = side % 3;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let side_area = extent[u] * extent[v];
        assert!(
            (boundary_area_per_side[side] - side_area).abs() <= 1e-12 * side_area,
            "side {side}: boundary faces cover {} of {side_area}",
            boundary_area_per_side[side]
        );
        let squares = [ny * nz, nz * nx, nx * ny][axis];
        assert_eq!(boundary_faces_per_side[side], 2 * squares, "side {side}");
    }

    // A tetrahedralised ball has Euler characteristic V - E + F - T = 1.
    let edges: HashSet<[u32; 2]> = tets
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b], [a, c], [a, d], [b, c], [b, d], [c, d]])
        .map(sorted)
        .collect();
    let euler =
        positions.len() as i64 - edges.len() as i64 + faces.len() as i64 - tets.len() as i64;
    assert_eq!(euler, 1, "Euler characteristic");

    // Each tetrahedron takes the share of its cube its split promises (Kuhn: 1/6 each;
    // alternating: the central 1/3 and four corners of 1/6). Interior grid coordinates carry a
    // rounding error of a few ulps of the largest coordinate, which relative to a cell width of
    // at least a tenth of it is below 64 eps per width; the volume multiplies three widths.
    let cell_volume = box_volume / (nx * ny * nz) as f64;
    for tet in tets {
        let share = tet_volume(tet.map(|v| positions[v as usize])) / cell_volume;
        let expected = if share > 0.25 { 1.0 / 3.0 } else { 1.0 / 6.0 };
        assert!(
            (share - expected).abs() <= 3.0 * 64.0 * relative_eps,
            "tetrahedron {tet:?} takes {share} of its cube"
        );
    }
}

/// Everything a conforming counter-clockwise triangulation of the rectangle `[min, max]` must
/// satisfy, on f64 copies of the generated positions.
fn check_rectangle_mesh(
    positions: &[[f64; 2]],
    triangles: &[[u32; 3]],
    min: [f64; 2],
    max: [f64; 2],
    cell_counts: [usize; 2],
) {
    let area_of = |t: [u32; 3]| {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) / 2.0
    };
    let mut used = vec![false; positions.len()];
    for t in triangles {
        for &v in t {
            assert!((v as usize) < positions.len());
            used[v as usize] = true;
        }
        assert!(area_of(*t) > 0.0, "triangle {t:?} is not counter-clockwise");
    }
    assert!(used.iter().all(|&u| u), "a vertex belongs to no triangle");

    // Same reasoning as for the box volume: exact boundary, f64 rounding only.
    let rectangle_area = (max[0] - min[0]) * (max[1] - min[1]);
    let area: f64 = triangles.iter().map(|&t| area_of(t)).sum();
    assert!((area - rectangle_area).abs() <= 1e-12 * rectangle_area);

    let mut edges: HashMap<[u32; 2], Vec<[u32; 2]>> = HashMap::new();
    for &[a, b, c] in triangles {
        for edge in [[a, b], [b, c], [c, a]] {
            edges.entry(sorted(edge)).or_default().push(edge);
        }
    }
    let mut perimeter = 0.0;
    let mut boundary_edges = 0;
    for (key, uses) in &edges {
        match uses.as_slice() {
            [first, second] => assert_eq!(*first, [second[1], second[0]], "edge {key:?}"),
            [[a, b]] => {
                let (p, q) = (positions[*a as usize], positions[*b as usize]);
                let d = [q[0] - p[0], q[1] - p[1]];
                // The outward normal of a counter-clockwise boundary edge is (d.y, -d.x).
                let outward = [d[1], -d[0]];
                let on_side = (p[0] == min[0] && q[0] == min[0] && outward[0] < 0.0)
                    || (p[0] == max[0] && q[0] == max[0] && outward[0] > 0.0)
                    || (p[1] == min[1] && q[1] == min[1] && outward[1] < 0.0)
                    || (p[1] == max[1] && q[1] == max[1] && outward[1] > 0.0);
                assert!(
                    on_side,
                    "boundary edge {a}-{b} is not on the rectangle, facing out"
                );
                perimeter += (d[0] * d[0] + d[1] * d[1]).sqrt();
                boundary_edges += 1;
            }
            _ => panic!("edge {key:?} is shared by {} triangles", uses.len()),
        }
    }
    let expected_perimeter = 2.0 * (max[0] - min[0] + max[1] - min[1]);
    assert!((perimeter - expected_perimeter).abs() <= 1e-12 * expected_perimeter);
    let [nx, ny] = cell_counts;
    assert_eq!(boundary_edges, 2 * (nx + ny));
    let euler = positions.len() as i64 - edges.len() as i64 + triangles.len() as i64;
    assert_eq!(euler, 1, "Euler characteristic of a disc");
}

macro_rules! generate_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use super::{check_box_mesh, check_rectangle_mesh};
            use $($api)::+::generate::{
                BoxSplit, box_counts, fill_box, fill_rectangle, fill_rectangle_3d,
                rectangle_counts,
            };
            use $($api)::+::types::{Mat3, Real, Vec2, Vec3};
            use $($api)::+::{GenerateBuffer, GenerateError};

            const SPLITS: [BoxSplit; 2] = [BoxSplit::Kuhn6, BoxSplit::Alternating5];

            /// Grids with odd and even counts (the alternating split changes with parity) and a
            /// box away from the origin with unequal sides, so that axis mix-ups show.
            const GRIDS: [[usize; 3]; 5] = [[1, 1, 1], [2, 1, 1], [1, 2, 3], [3, 2, 2], [4, 3, 5]];

            fn test_box() -> (Vec3, Vec3) {
                (Vec3::new(-1.0, 0.5, 2.0), Vec3::new(2.0, 1.5, 3.5))
            }

            fn p3(v: Vec3) -> [f64; 3] {
                [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
            }

            fn generate_box(cells: [usize; 3], split: BoxSplit) -> (Vec<Vec3>, Vec<[u32; 4]>) {
                let [nx, ny, nz] = cells;
                let (min, max) = test_box();
                let (vertex_count, tet_count) = box_counts(nx, ny, nz, split).unwrap();
                let mut positions = vec![Vec3::ZERO; vertex_count];
                let mut tets = vec![[0; 4]; tet_count];
                fill_box(min, max, nx, ny, nz, split, &mut positions, &mut tets).unwrap();
                (positions, tets)
            }

            #[test]
            fn box_counts_are_grid_points_and_tets_per_cube() {
                assert_eq!(box_counts(1, 1, 1, BoxSplit::Kuhn6), Ok((8, 6)));
                assert_eq!(box_counts(1, 1, 1, BoxSplit::Alternating5), Ok((8, 5)));
                assert_eq!(box_counts(2, 3, 4, BoxSplit::Kuhn6), Ok((3 * 4 * 5, 6 * 24)));
                assert_eq!(box_counts(2, 3, 4, BoxSplit::Alternating5), Ok((60, 5 * 24)));
                assert_eq!(BoxSplit::Kuhn6.tets_per_cell(), 6);
                assert_eq!(BoxSplit::Alternating5.tets_per_cell(), 5);
            }

            #[test]
            fn box_vertices_are_numbered_x_fastest_with_exact_corners() {
                let (min, max) = test_box();
                let [nx, ny, nz] = [4, 3, 5];
                let (positions, _) = generate_box([nx, ny, nz], BoxSplit::Kuhn6);
                let step = (max - min) / Vec3::new(nx as Real, ny as Real, nz as Real);
                for k in 0..=nz {
                    for j in 0..=ny {
                        for i in 0..=nx {
                            let p = positions[i + (nx + 1) * (j + (ny + 1) * k)];
                            let expected = min + step * Vec3::new(i as Real, j as Real, k as Real);
                            // Two ways of rounding the same grid point: a few ulps of the
                            // largest coordinate (3.5).
                            assert!(p.abs_diff_eq(expected, 8.0 * 3.5 * Real::EPSILON), "{p} vs {expected}");
                        }
                    }
                }
                assert_eq!(positions[0], min);
                assert_eq!(positions[positions.len() - 1], max);
            }

            #[test]
            fn every_box_tet_has_positive_volume_in_this_precision() {
                for split in SPLITS {
                    for cells in GRIDS {
                        let (positions, tets) = generate_box(cells, split);
                        for tet in &tets {
                            let [x0, x1, x2, x3] = tet.map(|v| positions[v as usize]);
                            let volume =
                                Mat3::from_cols(x1 - x0, x2 - x0, x3 - x0).determinant() / 6.0;
                            assert!(volume > 0.0, "{split:?} {cells:?}: {tet:?} has volume {volume}");
                        }
                    }
                }
            }

            #[test]
            fn box_meshes_tile_the_box_conformingly() {
                let (min, max) = test_box();
                for split in SPLITS {
                    for cells in GRIDS {
                        let (positions, tets) = generate_box(cells, split);
                        let positions: Vec<[f64; 3]> = positions.into_iter().map(p3).collect();
                        check_box_mesh(
                            &positions,
                            &tets,
                            p3(min),
                            p3(max),
                            cells,
                            f64::from(Real::EPSILON),
                        );
                    }
                }
            }

            #[test]
            fn alternating_split_has_one_central_tet_per_cube() {
                // Cube k's tetrahedra start at 5 k and the central one (a third of the cube)
                // comes first; it must use alternate corners, different in neighbouring cubes.
                let (_, tets) = generate_box([2, 1, 1], BoxSplit::Alternating5);
                let central = |cube: usize| super::sorted(tets[5 * cube]);
                // Vertices: i + 3 j + 6 k. Cube 0 (even) uses corners {0, 3, 5, 6} of its
                // own: (0,0,0), (1,1,0), (1,0,1), (0,1,1); cube 1 (odd) uses {1, 2, 4, 7}:
                // (2,0,0), (1,1,0), (1,0,1), (2,1,1).
                assert_eq!(central(0), [0, 4, 7, 9]);
                assert_eq!(central(1), [2, 4, 7, 11]);
            }

            #[test]
            fn box_errors_leave_the_buffers_unchanged() {
                let (min, max) = test_box();
                let sentinel_position = Vec3::splat(-7.0);
                let sentinel_tet = [9u32; 4];
                let mut positions = vec![sentinel_position; 8];
                let mut tets = vec![sentinel_tet; 6];
                let mut check = |min: Vec3, max: Vec3, cells: [usize; 3], vertices: usize, tet_count: usize, expected: GenerateError| {
                    positions.resize(vertices, sentinel_position);
                    tets.resize(tet_count, sentinel_tet);
                    let [nx, ny, nz] = cells;
                    let result = fill_box(min, max, nx, ny, nz, BoxSplit::Kuhn6, &mut positions, &mut tets);
                    assert_eq!(result, Err(expected));
                    assert!(positions.iter().all(|&p| p == sentinel_position));
                    assert!(tets.iter().all(|&t| t == sentinel_tet));
                };

                check(min, max, [0, 1, 1], 8, 6, GenerateError::ZeroCells);
                check(min, max, [1, 0, 1], 8, 6, GenerateError::ZeroCells);
                check(min, max, [1, 1, 0], 8, 6, GenerateError::ZeroCells);
                // 2001^3 > u32::MAX vertices; usize::MAX + 1 overflows usize itself.
                check(min, max, [2000, 2000, 2000], 8, 6, GenerateError::TooManyVertices);
                check(min, max, [usize::MAX, 1, 1], 8, 6, GenerateError::TooManyVertices);

                let nan = Vec3::new(0.0, Real::NAN, 0.0);
                check(nan, max, [1, 1, 1], 8, 6, GenerateError::NonFiniteBox);
                check(min, Vec3::splat(Real::INFINITY), [1, 1, 1], 8, 6, GenerateError::NonFiniteBox);
                check(min, Vec3::new(min.x, max.y, max.z), [1, 1, 1], 8, 6, GenerateError::EmptyBox);
                check(min, Vec3::new(max.x, max.y, min.z - 1.0), [1, 1, 1], 8, 6, GenerateError::EmptyBox);

                let wrong = |buffer, expected, actual| GenerateError::BufferLength { buffer, expected, actual };
                check(min, max, [1, 1, 1], 7, 6, wrong(GenerateBuffer::Positions, 8, 7));
                check(min, max, [1, 1, 1], 9, 6, wrong(GenerateBuffer::Positions, 8, 9));
                check(min, max, [1, 1, 1], 8, 5, wrong(GenerateBuffer::Tetrahedra, 6, 5));
                check(min, max, [2, 1, 1], 12, 6, wrong(GenerateBuffer::Tetrahedra, 12, 6));

                // 64 cells across 8 representable numbers: neighbouring grid points coincide.
                let narrow = Vec3::new(1.0 + 8.0 * Real::EPSILON, 2.0, 2.0);
                check(Vec3::ONE, narrow, [64, 1, 1], 65 * 4, 6 * 64, GenerateError::DegenerateCells);
                // Every coordinate finite, but the volume (and the widths) overflow.
                check(Vec3::splat(-Real::MAX), Vec3::splat(Real::MAX), [1, 1, 1], 8, 6, GenerateError::DegenerateCells);
            }

            #[test]
            fn box_counts_errors() {
                assert_eq!(box_counts(0, 1, 1, BoxSplit::Alternating5), Err(GenerateError::ZeroCells));
                assert_eq!(box_counts(2000, 2000, 2000, BoxSplit::Kuhn6), Err(GenerateError::TooManyVertices));
                // The limit is inclusive: u32::MAX = 3 * 5 * (17 * 257 * 65537) vertices is
                // allowed, one more layer of 15 is not.
                assert_eq!(
                    box_counts(2, 4, 17 * 257 * 65537 - 1, BoxSplit::Kuhn6).map(|(v, _)| v),
                    Ok(u32::MAX as usize)
                );
                assert_eq!(
                    box_counts(2, 4, 17 * 257 * 65537, BoxSplit::Kuhn6),
                    Err(GenerateError::TooManyVertices)
                );
            }

            fn test_rectangle() -> (Vec2, Vec2) {
                (Vec2::new(-0.5, 1.0), Vec2::new(1.5, 1.75))
            }

            fn generate_rectangle(nx: usize, ny: usize) -> (Vec<Vec2>, Vec<[u32; 3]>) {
                let (min, max) = test_rectangle();
                let (vertex_count, triangle_count) = rectangle_counts(nx, ny).unwrap();
                let mut positions = vec![Vec2::ZERO; vertex_count];
                let mut triangles = vec![[0; 3]; triangle_count];
                fill_rectangle(min, max, nx, ny, &mut positions, &mut triangles).unwrap();
                (positions, triangles)
            }

            #[test]
            fn rectangle_counts_are_grid_points_and_two_triangles_per_cell() {
                assert_eq!(rectangle_counts(1, 1), Ok((4, 2)));
                assert_eq!(rectangle_counts(3, 2), Ok((12, 12)));
                assert_eq!(rectangle_counts(0, 2), Err(GenerateError::ZeroCells));
                assert_eq!(rectangle_counts(70_000, 70_000), Err(GenerateError::TooManyVertices));
            }

            #[test]
            fn rectangles_are_counter_clockwise_and_conforming() {
                let (min, max) = test_rectangle();
                for [nx, ny] in [[1, 1], [2, 1], [1, 3], [4, 3], [5, 6]] {
                    let (positions, triangles) = generate_rectangle(nx, ny);
                    for t in &triangles {
                        let [x0, x1, x2] = t.map(|v| positions[v as usize]);
                        assert!((x1 - x0).perp_dot(x2 - x0) > 0.0, "{t:?}");
                    }
                    let positions: Vec<[f64; 2]> =
                        positions.iter().map(|p| [f64::from(p.x), f64::from(p.y)]).collect();
                    let to64 = |v: Vec2| [f64::from(v.x), f64::from(v.y)];
                    check_rectangle_mesh(&positions, &triangles, to64(min), to64(max), [nx, ny]);
                    assert_eq!(positions[0], to64(min));
                    assert_eq!(positions[positions.len() - 1], to64(max));
                }
            }

            #[test]
            fn rectangle_pattern_is_the_documented_union_jack() {
                // 2 x 1 cells, vertices i + 3 j: cell (0, 0) is cut along 0-4, cell (1, 0)
                // along 2-4 (its (i+1, j)-(i, j+1) diagonal).
                let (_, triangles) = generate_rectangle(2, 1);
                assert_eq!(triangles, vec![[0, 1, 4], [0, 4, 3], [1, 2, 4], [2, 5, 4]]);
            }

            #[test]
            fn rectangle_3d_is_the_2d_rectangle_mapped_onto_the_plane() {
                let origin = Vec3::new(0.5, -1.0, 2.0);
                let edge_u = Vec3::new(2.0, 0.0, 1.0);
                let edge_v = Vec3::new(-0.5, 1.5, 0.25);
                let normal = edge_u.cross(edge_v);
                let [nx, ny] = [4, 3];
                let (vertex_count, triangle_count) = rectangle_counts(nx, ny).unwrap();
                let mut positions = vec![Vec3::ZERO; vertex_count];
                let mut triangles = vec![[0; 3]; triangle_count];
                fill_rectangle_3d(origin, edge_u, edge_v, nx, ny, &mut positions, &mut triangles).unwrap();

                let (_, triangles_2d) = generate_rectangle(nx, ny);
                assert_eq!(triangles, triangles_2d);
                for j in 0..=ny {
                    for i in 0..=nx {
                        let expected = origin + edge_u * (i as Real / nx as Real) + edge_v * (j as Real / ny as Real);
                        // Coordinates up to ~4: a few ulps of that.
                        assert!(positions[i + (nx + 1) * j].abs_diff_eq(expected, 16.0 * Real::EPSILON));
                    }
                }
                let mut area = 0.0;
                for t in &triangles {
                    let [x0, x1, x2] = t.map(|v| positions[v as usize]);
                    let twice_area = (x1 - x0).cross(x2 - x0);
                    assert!(twice_area.dot(normal) > 0.0, "{t:?} is not counter-clockwise about the normal");
                    area += f64::from(twice_area.length()) / 2.0;
                }
                // Sum of a few dozen areas, each with a relative error of a few eps.
                let expected = f64::from(normal.length());
                assert!((area - expected).abs() <= 64.0 * f64::from(Real::EPSILON) * expected);
            }

            #[test]
            fn rectangle_errors_leave_the_buffers_unchanged() {
                let (min, max) = test_rectangle();
                let mut positions = vec![Vec2::splat(-7.0); 4];
                let mut triangles = vec![[9u32; 3]; 2];
                let untouched = |positions: &[Vec2], triangles: &[[u32; 3]]| {
                    positions.iter().all(|&p| p == Vec2::splat(-7.0)) && triangles.iter().all(|&t| t == [9; 3])
                };
                let mut run = |min: Vec2, max: Vec2, nx: usize, ny: usize| {
                    let result = fill_rectangle(min, max, nx, ny, &mut positions, &mut triangles);
                    assert!(untouched(&positions, &triangles));
                    result
                };
                assert_eq!(run(min, max, 1, 0), Err(GenerateError::ZeroCells));
                assert_eq!(run(Vec2::new(Real::NAN, 0.0), max, 1, 1), Err(GenerateError::NonFiniteBox));
                assert_eq!(run(min, Vec2::new(max.x, min.y), 1, 1), Err(GenerateError::EmptyBox));
                assert_eq!(
                    run(min, max, 2, 1),
                    Err(GenerateError::BufferLength { buffer: GenerateBuffer::Positions, expected: 6, actual: 4 })
                );
                let narrow = Vec2::new(1.0 + 4.0 * Real::EPSILON, 2.0);
                let mut positions = vec![Vec2::splat(-7.0); 65 * 2];
                let mut triangles = vec![[9u32; 3]; 128];
                assert_eq!(
                    fill_rectangle(Vec2::ONE, narrow, 64, 1, &mut positions, &mut triangles),
                    Err(GenerateError::DegenerateCells)
                );
                assert!(untouched(&positions, &triangles));
                let mut triangles = vec![[9u32; 3]; 3];
                let mut positions = vec![Vec2::splat(-7.0); 6];
                assert_eq!(
                    fill_rectangle(min, max, 2, 1, &mut positions, &mut triangles),
                    Err(GenerateError::BufferLength { buffer: GenerateBuffer::Triangles, expected: 4, actual: 3 })
                );
                assert!(untouched(&positions, &triangles));
            }

            #[test]
            fn rectangle_3d_errors_leave_the_buffers_unchanged() {
                let mut positions = vec![Vec3::splat(-7.0); 4];
                let mut triangles = vec![[9u32; 3]; 2];
                let mut run = |origin: Vec3, edge_u: Vec3, edge_v: Vec3| {
                    let result = fill_rectangle_3d(origin, edge_u, edge_v, 1, 1, &mut positions, &mut triangles);
                    assert!(positions.iter().all(|&p| p == Vec3::splat(-7.0)));
                    assert!(triangles.iter().all(|&t| t == [9; 3]));
                    result
                };
                assert_eq!(run(Vec3::splat(Real::INFINITY), Vec3::X, Vec3::Y), Err(GenerateError::NonFiniteBox));
                assert_eq!(run(Vec3::ZERO, Vec3::X, Vec3::new(0.0, Real::NAN, 0.0)), Err(GenerateError::NonFiniteBox));
                assert_eq!(run(Vec3::ZERO, Vec3::X, Vec3::X * 2.0), Err(GenerateError::EmptyBox));
                assert_eq!(run(Vec3::ZERO, Vec3::ZERO, Vec3::Y), Err(GenerateError::EmptyBox));
                // The normal (and area) overflow although every input is finite.
                assert_eq!(
                    run(Vec3::ZERO, Vec3::X * Real::MAX, Vec3::Y * Real::MAX),
                    Err(GenerateError::DegenerateCells)
                );
            }

            #[test]
            fn errors_display_what_is_wrong() {
                let error = GenerateError::BufferLength { buffer: GenerateBuffer::Tetrahedra, expected: 6, actual: 5 };
                assert_eq!(error.to_string(), "the tetrahedra buffer has length 5, but the mesh needs exactly 6");
                let _: &dyn core::error::Error = &error;
            }
        }
    };
}

generate_tests!(single, softfem);
generate_tests!(double, softfem::f64);

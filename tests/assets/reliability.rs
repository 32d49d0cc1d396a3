//! Issue #44, part A: no input makes the asset helpers abort, panic or hand back an empty
//! result as a success, in both precisions. Each test names the defect it pins:
//! * a grid whose cell count overflows is refused (`TooManyCells`) before anything is
//!   allocated, and grids or embeddings beyond the memory budget are refused with the bytes
//!   and the budget before anything is allocated;
//! * a Gmsh file with a second `$Nodes` section is refused on the line that opens it;
//! * a closed cube far from unit scale gets the right winding number, meshes where the
//!   precision can hold its cells and is refused (`CellScale`) where it cannot; an inside-out
//!   or flat surface is refused (`NoVolume`), and so is a grid with no cell inside;
//! * a degenerate tetrahedron in a TetGen mesh is named on its `.ele` line.
#![cfg(feature = "std")]

/// The unit cube `[0, 1]^3` as 12 outward triangles (positions as `[x, y, z]`, any precision).
fn unit_cube() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let (positions, triangles) = crate::common::shapes::cube();
    let positions = positions
        .iter()
        .map(|x| x.to_array().map(f64::from))
        .collect();
    (positions, triangles)
}

macro_rules! reliability_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use super::unit_cube;
            use $($api)::+::asset::MEMORY_BUDGET;
            use $($api)::+::asset::embed::{embed_points_vec, embed_points_vec_with_budget};
            use $($api)::+::asset::gmsh::read_gmsh;
            use $($api)::+::asset::tetgen::read_tetgen;
            use $($api)::+::asset::voxel::{
                VoxelGrid, VoxelOptions, voxel_mesh, voxel_mesh_with_budget, winding_number,
            };
            use $($api)::+::types::{Real, Vec3};
            use softfem::{EmbedError, GmshProblem, GmshSection, TetgenFile, TetgenProblem, VoxelError};

            /// The unit cube scaled by `scale` about the origin.
            fn cube(scale: Real) -> (Vec<Vec3>, Vec<[u32; 3]>) {
                let (positions, triangles) = unit_cube();
                let positions = positions
                    .iter()
                    .map(|&[x, y, z]| Vec3::new(x as Real, y as Real, z as Real) * scale)
                    .collect();
                (positions, triangles)
            }

            /// Was: `capacity overflow` (a panic) allocating `usize::MAX` occupancy flags.
            #[test]
            fn a_grid_whose_count_overflows_is_refused_before_allocating() {
                let (positions, triangles) = cube(1.0);
                let grid = VoxelGrid {
                    origin: Vec3::ZERO,
                    cell_size: 0.25,
                    cells: [usize::MAX, 1, 1],
                };
                let options = VoxelOptions::default();
                assert_eq!(
                    voxel_mesh(&positions, &triangles, &grid, &options),
                    Err(VoxelError::TooManyCells)
                );
            }

            /// Was: Ok, then about 20 GB of buffers (killed, or an abort on allocation).
            #[test]
            fn a_grid_beyond_the_memory_budget_is_refused_with_its_size() {
                let (positions, triangles) = cube(1.0);
                let grid = VoxelGrid::with_resolution(&positions, 1600).unwrap();
                assert_eq!(grid.cell_count(), 1600 * 1600 * 1600);
                let options = VoxelOptions::default();
                // The classification alone needs a byte a cell and 36 bytes a triangle.
                let bytes = 1600 * 1600 * 1600 + 36 * 12;
                let error = voxel_mesh(&positions, &triangles, &grid, &options).unwrap_err();
                assert_eq!(error, VoxelError::OverBudget { bytes, budget: MEMORY_BUDGET });
                assert_eq!(
                    error.to_string(),
                    "voxel meshing needs 4096000432 bytes of buffers, over its memory budget \
                     of 2147483648 bytes (use a coarser grid)"
                );
                // A budget below what the mesh itself needs is met after the classification:
                // 4^3 cells of 1 byte, 5^3 corners of 4 bytes, 125 positions, 320 tetrahedra.
                let grid = VoxelGrid::with_resolution(&positions, 4).unwrap();
                let mesh_bytes = 64 + 4 * 125 + 125 * core::mem::size_of::<Vec3>() + 16 * 320;
                assert_eq!(
                    voxel_mesh_with_budget(&positions, &triangles, &grid, &options, mesh_bytes - 1),
                    Err(VoxelError::OverBudget { bytes: mesh_bytes, budget: mesh_bytes - 1 })
                );
                let mesh =
                    voxel_mesh_with_budget(&positions, &triangles, &grid, &options, mesh_bytes);
                assert_eq!(mesh.unwrap().tets.len(), 320);
            }

            /// Was: 3.1e9 planned cells and an abort on a 12 GB allocation.
            #[test]
            fn an_embedding_beyond_the_memory_budget_is_refused_with_its_size() {
                let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
                let tets = [[0, 1, 2, 3]];
                let far = [Vec3::new(300.0, 0.0, 0.0)];
                match embed_points_vec(&rest, &tets, &far, 300.0) {
                    Err(EmbedError::OverBudget { bytes, budget }) => {
                        assert_eq!(budget, MEMORY_BUDGET);
                        assert!(bytes > 4_000_000_000, "{bytes}");
                    }
                    other => panic!("{other:?}"),
                }
                // Within a budget, the same call binds the point by extrapolation.
                let near = [Vec3::new(1.5, 0.0, 0.0)];
                let embedded = embed_points_vec_with_budget(&rest, &tets, &near, 1.0, 1 << 20);
                assert_eq!(embedded.unwrap().len(), 1);
                assert!(matches!(
                    embed_points_vec_with_budget(&rest, &tets, &near, 1.0, 16),
                    Err(EmbedError::OverBudget { budget: 16, .. })
                ));
            }

            /// Was: read without error, the elements taking the first section's coordinates.
            #[test]
            fn a_second_nodes_section_is_refused_on_its_line() {
                let nodes = "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n";
                let moved = nodes.replace("0 0 1\n$End", "0 0 7\n$End");
                let text = format!(
                    "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n{nodes}{moved}\
                     $Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n"
                );
                let error = read_gmsh(&text).unwrap_err();
                assert_eq!(error.line, 16);
                assert_eq!(error.problem, GmshProblem::RepeatedSection(GmshSection::Nodes));
                assert_eq!(
                    error.to_string(),
                    "line 16: a second $Nodes section (the file may have only one)"
                );
                // One section of each reads.
                let single = text.replacen(&moved, "", 1);
                assert_eq!(read_gmsh(&single).unwrap().tets, vec![[0, 1, 2, 3]]);
            }

            /// Was: the winding number NaN (overflow) or 0 (underflow) everywhere far from unit
            /// scale, hence an empty mesh. It is exact under power-of-two rescaling now.
            #[test]
            fn the_winding_number_does_not_depend_on_scale() {
                let inside = Vec3::new(0.3, 0.6, 0.45);
                let outside = Vec3::new(1.3, 0.6, 0.45);
                let (unit, triangles) = cube(1.0);
                let reference = winding_number(&unit, &triangles, inside);
                assert!((reference - 1.0).abs() < 1e-5, "{reference}");
                // Beyond the cube root of the largest and smallest normal numbers.
                let huge = Real::MAX.cbrt() * 4.0;
                let tiny = Real::MIN_POSITIVE.cbrt() / 4.0;
                for scale in [huge, tiny, 1e30, 1e-30] {
                    let (positions, _) = cube(scale);
                    let w = winding_number(&positions, &triangles, inside * scale);
                    assert!((w - 1.0).abs() < 1e-5, "{scale:e}: {w}");
                    let w = winding_number(&positions, &triangles, outside * scale);
                    assert!(w.abs() < 1e-5, "{scale:e}: {w}");
                }
            }

            /// Was: Ok with 0 tetrahedra for the f32 cube scaled by 1e30 or 1e-30. Now a cube
            /// whose cells the precision can hold meshes like the unit cube (at the cube root of
            /// the largest number the winding number needed the rescaling), and the others are
            /// refused by name.
            #[test]
            fn a_scaled_cube_meshes_or_is_refused_never_empty() {
                let options = VoxelOptions::default();
                let wide = core::mem::size_of::<Real>() == 8;
                let cases = [
                    (Real::MAX.cbrt(), true),
                    (Real::MIN_POSITIVE.cbrt() * 64.0, true),
                    (Real::MAX.cbrt() * 4.0, false),
                    (Real::MIN_POSITIVE.cbrt() / 4.0, false),
                    // f32 cannot hold cells of 2.5e29 m or 2.5e-31 m; f64 can.
                    (1e30, wide),
                    (1e-30, wide),
                ];
                for (scale, meshes) in cases {
                    let (positions, triangles) = cube(scale);
                    let grid = VoxelGrid::with_resolution(&positions, 4).unwrap();
                    let result = voxel_mesh(&positions, &triangles, &grid, &options);
                    if meshes {
                        let mesh = result.unwrap();
                        assert_eq!((mesh.positions.len(), mesh.tets.len()), (125, 320), "{scale:e}");
                    } else {
                        assert_eq!(result, Err(VoxelError::CellScale), "{scale:e}");
                    }
                }
            }

            /// Was: Ok with an empty mesh for an inside-out or a flat closed surface.
            #[test]
            fn inside_out_and_flat_surfaces_are_refused() {
                let options = VoxelOptions::default();
                let (positions, triangles) = cube(1.0);
                let grid = VoxelGrid::with_resolution(&positions, 4).unwrap();
                let inside_out: Vec<[u32; 3]> = triangles.iter().map(|&[a, b, c]| [a, c, b]).collect();
                assert_eq!(
                    voxel_mesh(&positions, &inside_out, &grid, &options),
                    Err(VoxelError::NoVolume)
                );
                // A closed surface of zero volume: the square z = 0 and its back face (split along the
                // other diagonal, so that every edge has one opposite).
                let flat = [[0, 1, 3], [0, 3, 2], [0, 2, 1], [1, 2, 3]];
                let square = &positions[..4];
                let grid = VoxelGrid::with_resolution(square, 4).unwrap();
                let error = voxel_mesh(square, &flat, &grid, &options).unwrap_err();
                assert_eq!(error, VoxelError::NoVolume);
                assert_eq!(
                    error.to_string(),
                    "the closed surface encloses no positive volume: it is inside out \
                     (clockwise triangles) or flat"
                );
            }

            /// Was: Ok with an empty mesh where the solid is thinner than the cells.
            #[test]
            fn a_grid_with_no_cell_inside_is_refused() {
                let (positions, triangles) = cube(1.0);
                // Cells of 4 m: the one sample, at the centre of a cell, is outside the cube.
                let grid = VoxelGrid {
                    origin: Vec3::splat(-1.0),
                    cell_size: 4.0,
                    cells: [1, 1, 1],
                };
                let options = VoxelOptions::default();
                assert_eq!(
                    voxel_mesh(&positions, &triangles, &grid, &options),
                    Err(VoxelError::NoCellsInside)
                );
            }

            /// Was: accepted by the reader, then reported by the body against the `.node` file
            /// with a 0-based index and no line.
            #[test]
            fn a_degenerate_tetrahedron_is_named_on_its_ele_line() {
                let node = "5 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 0\n";
                // Tetrahedron 2 lies in the plane z = 0; tetrahedron 1 is inverted, which the
                // reader accepts (orientation is the caller's to fix).
                let ele = "2 4 0\n# a comment line\n1 1 3 2 4\n2 1 2 3 5\n";
                let error = read_tetgen(node, ele).unwrap_err();
                assert_eq!(error.file, TetgenFile::Ele);
                assert_eq!(error.line, 4);
                assert_eq!(error.problem, TetgenProblem::DegenerateTet { index: 2 });
                assert_eq!(
                    error.to_string(),
                    ".ele file, line 4: tetrahedron 2 is degenerate (near-zero or non-finite \
                     rest volume)"
                );
                let fine = ele.replace("1 2 3 5", "1 2 3 4");
                assert_eq!(read_tetgen(node, &fine).unwrap().tets.len(), 2);
            }
        }
    };
}

reliability_tests!(single, softfem);
reliability_tests!(double, softfem::f64);

//! Voxel meshing and embedding on arbitrary surfaces, grids and points (included once per
//! precision by `lib.rs`).
//!
//! The input draws a small triangle surface (any floats, any indices; often a closed box so
//! that meshing gets past the checks), a grid (the enclosing one, one of a drawn resolution, or
//! any origin, cell size and cell counts up to `usize::MAX`), voxel options, render points and a
//! margin. Promises checked (`src/asset/voxel.rs`, `src/asset/embed.rs`): nothing panics or
//! aborts on allocation, whatever the sizes (the helpers run with a 1 MiB budget here, so a
//! huge grid must be refused, not allocated: the fuzzer's `-rss_limit_mb` catches an abort);
//! a voxel mesh that is returned is not empty, has every index in range, every vertex used and
//! every tetrahedron of positive finite volume; an embedding that is returned has one entry
//! per render point, each naming an existing tetrahedron with finite weights.

use super::NAME;
use super::precision;
use super::sf::asset::embed::embed_points_vec_with_budget;
use super::sf::asset::voxel::{VoxelGrid, VoxelOptions, voxel_mesh_with_budget};
use super::sf::types::{Mat3, Real, Vec3};
use crate::Draw;
use crate::cube_triangles::CUBE_TRIANGLES;

/// The budget (bytes) the helpers run with: small, so that refusals are exercised and the
/// work of an accepted input stays short.
const BUDGET: usize = 1 << 20;

fn coordinate(draw: &mut Draw<'_>) -> Real {
    match draw.up_to(3) {
        0 => precision::wild(draw),
        1 => precision::magnitude(draw, -40, 40),
        _ => precision::coarse(draw),
    }
}

fn point(draw: &mut Draw<'_>) -> Vec3 {
    Vec3::new(coordinate(draw), coordinate(draw), coordinate(draw))
}

/// Runs the voxel and embedding checks on one fuzzer input.
pub fn check(data: &[u8]) {
    let mut draw = Draw::new(data);
    // The surface: a box (scaled, moved, maybe a corner dragged or the winding flipped), or
    // free positions and triangles.
    let (positions, triangles): (Vec<Vec3>, Vec<[u32; 3]>) = if draw.chance(160) {
        let low = point(&mut draw);
        let size = Vec3::new(
            coordinate(&mut draw),
            coordinate(&mut draw),
            coordinate(&mut draw),
        );
        let mut positions: Vec<Vec3> = (0..8u32)
            .map(|c| {
                let unit = Vec3::new((c & 1) as Real, ((c >> 1) & 1) as Real, (c >> 2) as Real);
                low + unit * size
            })
            .collect();
        if draw.chance(60) {
            let corner = draw.index(7);
            positions[corner] = point(&mut draw);
        }
        let flip = draw.chance(30);
        let triangles = CUBE_TRIANGLES
            .iter()
            .map(|&[a, b, c]| if flip { [a, c, b] } else { [a, b, c] });
        (positions, triangles.collect())
    } else {
        let n = draw.index(12) + 1;
        let positions = (0..n).map(|_| point(&mut draw)).collect();
        let t = draw.index(24);
        let index = |draw: &mut Draw<'_>| {
            if draw.chance(10) {
                draw.u32()
            } else {
                draw.index(n + 1) as u32
            }
        };
        let triangles = (0..t)
            .map(|_| [index(&mut draw), index(&mut draw), index(&mut draw)])
            .collect();
        (positions, triangles)
    };
    let grid = match draw.up_to(3) {
        0 => VoxelGrid::enclosing(&positions, coordinate(&mut draw)),
        1 => VoxelGrid::with_resolution(&positions, draw.index(40)),
        _ => {
            let count = |draw: &mut Draw<'_>| match draw.up_to(3) {
                0 => usize::MAX - draw.index(2),
                1 => draw.u64() as usize,
                _ => draw.index(24),
            };
            Ok(VoxelGrid {
                origin: point(&mut draw),
                cell_size: coordinate(&mut draw),
                cells: [count(&mut draw), count(&mut draw), count(&mut draw)],
            })
        }
    };
    let samples_per_axis = draw.up_to(9);
    let options = VoxelOptions {
        samples_per_axis,
        min_coverage: if draw.chance(200) {
            (draw.up_to(8) as Real + 1.0) / 8.0
        } else {
            coordinate(&mut draw)
        },
        remove_hanging: draw.chance(128),
    };
    let mesh = grid.ok().and_then(|grid| {
        // Sampling is s^3 winding numbers a cell: keep the work of one input short.
        let work = grid
            .cell_count()
            .saturating_mul((samples_per_axis as usize).pow(3));
        if work > 1 << 18 {
            return None;
        }
        voxel_mesh_with_budget(&positions, &triangles, &grid, &options, BUDGET).ok()
    });
    if let Some(mesh) = &mesh {
        let n = mesh.positions.len();
        assert!(
            !mesh.tets.is_empty(),
            "{NAME}: voxel_mesh returned an empty mesh"
        );
        let mut used = vec![false; n];
        for tet in &mesh.tets {
            let corners = tet.map(|v| {
                assert!(
                    (v as usize) < n,
                    "{NAME}: voxel_mesh index {v} of {n} vertices"
                );
                used[v as usize] = true;
                mesh.positions[v as usize]
            });
            let [x0, x1, x2, x3] = corners;
            let volume = Mat3::from_cols(x1 - x0, x2 - x0, x3 - x0).determinant();
            assert!(
                volume > 0.0 && volume.is_finite(),
                "{NAME}: voxel_mesh returned a tetrahedron of volume {volume} ({corners:?})"
            );
        }
        assert!(
            used.iter().all(|&u| u),
            "{NAME}: voxel_mesh returned an unused vertex"
        );
    }

    // The embedding: into the voxel mesh, or into the drawn positions with drawn tetrahedra.
    let (rest, tets): (Vec<Vec3>, Vec<[u32; 4]>) = match mesh {
        Some(mesh) if draw.chance(128) => (mesh.positions, mesh.tets),
        _ => {
            let n = positions.len();
            let t = draw.index(6);
            let tets = draw.tets(t, n + 1);
            (positions, tets)
        }
    };
    let points: Vec<Vec3> = (0..draw.index(8)).map(|_| point(&mut draw)).collect();
    let margin = coordinate(&mut draw);
    if let Ok(embedded) = embed_points_vec_with_budget(&rest, &tets, &points, margin, BUDGET) {
        assert_eq!(
            embedded.len(),
            points.len(),
            "{NAME}: one embedding per point"
        );
        for entry in &embedded {
            assert!(
                (entry.tet as usize) < tets.len() && entry.weights.iter().all(|w| w.is_finite()),
                "{NAME}: embedding {entry:?} of {} tetrahedra",
                tets.len()
            );
        }
    }
}

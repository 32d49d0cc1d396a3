//! Closed, outward-oriented triangle surfaces for the asset tests: an icosphere, a torus and a
//! cube, with their exact polyhedral volumes (divergence theorem).
#![allow(dead_code)]

use std::collections::HashMap;

use softfem::glam::Vec3;

#[path = "cube_triangles.rs"]
mod cube_triangles;

use cube_triangles::CUBE_TRIANGLES;

/// The unit cube `[0, 1]^3` as 12 outward triangles; corner `c` is `(c & 1, c >> 1 & 1, c >> 2 & 1)`.
pub fn cube() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let positions = (0..8)
        .map(|c| Vec3::new((c & 1) as f32, ((c >> 1) & 1) as f32, ((c >> 2) & 1) as f32))
        .collect();
    (positions, CUBE_TRIANGLES.to_vec())
}

/// An icosahedron subdivided `levels` times (each triangle into four), projected onto the
/// sphere of `radius` about `centre`: `20 4^levels` triangles.
pub fn icosphere(centre: Vec3, radius: f32, levels: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut unit: Vec<[f64; 3]> = [
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
    .map(|&p| normalise(p))
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
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, unit: &mut Vec<[f64; 3]>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (pa, pb) = (unit[a as usize], unit[b as usize]);
                unit.push(normalise([pa[0] + pb[0], pa[1] + pb[1], pa[2] + pb[2]]));
                (unit.len() - 1) as u32
            })
        };
        let mut finer = Vec::with_capacity(triangles.len() * 4);
        for &[a, b, c] in &triangles {
            let ab = midpoint(a, b, &mut unit);
            let bc = midpoint(b, c, &mut unit);
            let ca = midpoint(c, a, &mut unit);
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    let positions = unit
        .iter()
        .map(|p| centre + Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) * radius)
        .collect();
    (positions, triangles)
}

fn normalise(p: [f64; 3]) -> [f64; 3] {
    let length = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    [p[0] / length, p[1] / length, p[2] / length]
}

/// The torus of major radius `major` and minor radius `minor` about the z axis, `segments_major
/// x segments_minor` quads of two triangles.
pub fn torus(
    major: f32,
    minor: f32,
    segments_major: u32,
    segments_minor: u32,
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let tau = std::f64::consts::TAU;
    let mut positions = Vec::new();
    for i in 0..segments_major {
        for j in 0..segments_minor {
            let u = tau * f64::from(i) / f64::from(segments_major);
            let v = tau * f64::from(j) / f64::from(segments_minor);
            let ring = f64::from(major) + f64::from(minor) * v.cos();
            positions.push(Vec3::new(
                (ring * u.cos()) as f32,
                (ring * u.sin()) as f32,
                (f64::from(minor) * v.sin()) as f32,
            ));
        }
    }
    let index = |i: u32, j: u32| (i % segments_major) * segments_minor + (j % segments_minor);
    let mut triangles = Vec::new();
    for i in 0..segments_major {
        for j in 0..segments_minor {
            // Counter-clockwise about d/du x d/dv, which points away from the tube's axis.
            let (a, b, c, d) = (
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    (positions, triangles)
}

/// The volume enclosed by a closed outward surface: `sum a . (b x c) / 6` (divergence theorem),
/// summed in f64.
pub fn enclosed_volume(positions: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| t.map(|v| positions[v as usize].as_dvec3()))
        .map(|[a, b, c]| a.dot(b.cross(c)) / 6.0)
        .sum()
}

/// The total signed volume of a tetrahedral mesh, summed in f64.
pub fn tet_volume(positions: &[Vec3], tets: &[[u32; 4]]) -> f64 {
    tets.iter()
        .map(|t| t.map(|v| positions[v as usize].as_dvec3()))
        .map(|[a, b, c, d]| (b - a).cross(c - a).dot(d - a) / 6.0)
        .sum()
}

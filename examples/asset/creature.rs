//! A small closed surface made procedurally: a four-legged, long-eared blob, built as an
//! icosphere whose radius varies with direction (so it stays closed, outward-oriented and free
//! of self-intersections: every ray from the centre crosses it once).

use std::collections::HashMap;

use softfem::glam::Vec3;

/// A bump of the radius: `amplitude * exp(-(1 - d . direction) / width)` for unit directions `d`.
struct Bump {
    direction: Vec3,
    amplitude: f32,
    width: f32,
}

/// The creature's surface (m): about 0.3 m long, 0.2 m tall, centred at the origin, with
/// `20 * 4^levels` triangles counter-clockwise seen from outside.
pub fn creature(levels: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let bump = |x: f32, y: f32, z: f32, amplitude: f32, width: f32| Bump {
        direction: Vec3::new(x, y, z).normalize(),
        amplitude,
        width,
    };
    let bumps = [
        bump(1.0, 0.0, 0.45, 0.05, 0.06),    // head
        bump(0.55, 0.22, 1.0, 0.08, 0.012),  // left ear
        bump(0.55, -0.22, 1.0, 0.08, 0.012), // right ear
        bump(-1.0, 0.0, 0.3, 0.04, 0.02),    // tail
        bump(0.6, 0.55, -0.7, 0.05, 0.03),   // legs
        bump(0.6, -0.55, -0.7, 0.05, 0.03),
        bump(-0.6, 0.55, -0.7, 0.05, 0.03),
        bump(-0.6, -0.55, -0.7, 0.05, 0.03),
    ];
    // The body: an ellipsoid with semi-axes 0.12, 0.08, 0.075 m.
    let semi_axes = Vec3::new(0.12, 0.08, 0.075);
    let (directions, triangles) = unit_icosphere(levels);
    let positions = directions
        .iter()
        .map(|&d| {
            let body = 1.0 / (d / semi_axes).length();
            let extra: f32 = bumps
                .iter()
                .map(|b| b.amplitude * (-(1.0 - d.dot(b.direction)) / b.width).exp())
                .sum();
            d * (body + extra)
        })
        .collect();
    (positions, triangles)
}

/// An icosahedron subdivided `levels` times, on the unit sphere.
fn unit_icosphere(levels: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
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
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, points: &mut Vec<Vec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                points.push((points[a as usize] + points[b as usize]).normalize());
                (points.len() - 1) as u32
            })
        };
        let mut finer = Vec::with_capacity(triangles.len() * 4);
        for &[a, b, c] in &triangles {
            let ab = midpoint(a, b, &mut points);
            let bc = midpoint(b, c, &mut points);
            let ca = midpoint(c, a, &mut points);
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    (points, triangles)
}

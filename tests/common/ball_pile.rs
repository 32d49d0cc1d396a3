//! The geometry of the eight-ball pile (issue #39), shared by the test `tests/steppers/pile.rs`
//! (both precisions) and the example `examples/pile` (f32), which include this file by `#[path]`:
//! the balls' meshes, their starting centres and the box's four walls. Computed in f64 and handed
//! out as `[x, y, z]` arrays, so that each caller converts to its own precision; no use of the
//! test suite's `common` module, so that a program outside the test suite can include it.
#![allow(dead_code)]

use softfem::f64::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::DVec3;

/// How many balls the pile drops.
pub const BALLS: usize = 8;

/// The signed volume of the tetrahedron `[a, b, c, d]` of `x` (m^3; positive for the library's
/// orientation).
fn volume(x: &[[f64; 3]], tet: [u32; 4]) -> f64 {
    let [a, b, c, d] = tet.map(|i| DVec3::from_array(x[i as usize]));
    (b - a).cross(c - a).dot(d - a) / 6.0
}

/// A tetrahedral mesh: positions (m) and tetrahedra (indices into them).
pub type Mesh = (Vec<[f64; 3]>, Vec<[u32; 4]>);

/// A ball of `radius` (m) around `centre`: positions and tetrahedra. The cube `[-1, 1]^3` of
/// `cells^3` cells is split into five tetrahedra each, every vertex mapped onto the unit ball by
/// the map that takes each face of the cube onto a sixth of the sphere (P. Nowell, "Mapping a
/// Cube to a Sphere", 2005: `x' = x sqrt(1 - y^2/2 - z^2/2 + y^2 z^2/3)` and cyclically), then
/// scaled and moved. The corner cells' tetrahedra are the flattest; an error names one the map
/// inverted (none does for 1 to 16 cells), or the generator's complaint about `cells`.
pub fn ball(centre: [f64; 3], radius: f64, cells: usize) -> Result<Mesh, String> {
    let split = BoxSplit::Alternating5;
    let (nv, nt) = box_counts(cells, cells, cells, split).map_err(|e| e.to_string())?;
    let (mut x, mut tets) = (vec![DVec3::ZERO; nv], vec![[0; 4]; nt]);
    fill_box(
        DVec3::splat(-1.0),
        DVec3::ONE,
        cells,
        cells,
        cells,
        split,
        &mut x,
        &mut tets,
    )
    .map_err(|e| e.to_string())?;
    let centre = DVec3::from_array(centre);
    let x: Vec<[f64; 3]> = x
        .iter()
        .map(|p| {
            let s = *p * *p;
            let mapped = DVec3::new(
                p.x * (1.0 - s.y / 2.0 - s.z / 2.0 + s.y * s.z / 3.0).sqrt(),
                p.y * (1.0 - s.z / 2.0 - s.x / 2.0 + s.z * s.x / 3.0).sqrt(),
                p.z * (1.0 - s.x / 2.0 - s.y / 2.0 + s.x * s.y / 3.0).sqrt(),
            );
            (centre + mapped * radius).to_array()
        })
        .collect();
    if let Some(tet) = tets.iter().find(|&&tet| volume(&x, tet) <= 0.0) {
        return Err(format!("the ball map inverted tetrahedron {tet:?}"));
    }
    Ok((x, tets))
}

/// The [`BALLS`] balls' centres for balls of `radius` (m): a spiral (135 degrees and 6 cm up from
/// one to the next, 3.5 cm from the box's axis), the lowest 5 mm above the ground. For the pile's
/// 4 cm balls every pair starts at least 8 mm apart, and each ball lands on those below it off
/// their tops.
pub fn centres(radius: f64) -> Vec<[f64; 3]> {
    (0..BALLS)
        .map(|k| {
            let angle = (135.0 * k as f64).to_radians();
            [
                0.035 * angle.cos(),
                0.035 * angle.sin(),
                radius + 0.005 + 0.06 * k as f64,
            ]
        })
        .collect()
}

/// The box's four walls as `(centre, half extents)` of axis-aligned boxes (m): 10 cm thick and
/// 1 m high, their inner faces at `|x|, |y| = half_width`, long enough to close the corners.
pub fn walls(half_width: f64) -> [([f64; 3], [f64; 3]); 4] {
    let (thick, high) = (0.05, 0.5);
    let along = half_width + 2.0 * thick;
    [DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y].map(|n| {
        let half = [
            if n.x != 0.0 { thick } else { along },
            if n.y != 0.0 { thick } else { along },
            high,
        ];
        (
            (n * (half_width + thick) + DVec3::Z * high).to_array(),
            half,
        )
    })
}

//! An exact triangle–triangle intersection test for the contact tests (issue #39): "no pair of
//! surface triangles intersects after a step" is checked here, in the test code, by exact
//! predicates, independently of the barrier that is meant to ensure it.
//!
//! Every decision is the sign of an orientation determinant, `orient3d` or `orient2d`, computed
//! exactly by the adaptive expansion arithmetic of J. R. Shewchuk, "Adaptive Precision
//! Floating-Point Arithmetic and Fast Robust Geometric Predicates" (Discrete & Computational
//! Geometry 18, 1997), as ported by the `robust` crate. The signs are exact as long as no
//! intermediate product underflows or overflows, which cannot happen for coordinates that are 0
//! or between 1e-30 and 1e30 in magnitude (every simulation's; the smallest difference of two
//! such coordinates is about 1e-46, the smallest expansion term about 1e-150), so the answers
//! are exact too; f32 positions convert to f64 exactly. Non-finite coordinates panic.
//!
//! The method is the one of P. Guigue and O. Devillers, "Fast and Robust Triangle–Triangle
//! Overlap Test Using Orientation Predicates" (Journal of Graphics Tools 8(1), 2003), written as
//! its equivalent: two closed triangles share a point if and only if an edge of one meets the
//! other closed triangle (see [`triangles_intersect`] for why), and each segment–triangle test
//! is decided by orientation signs, with the coplanar case in an exact 2D projection.
//!
//! Its tests run in the steppers binary: `cargo test --all-features --test steppers
//! intersection`. They use `crate::common::Rng`, so a binary including this file needs `common`.
#![allow(dead_code)]

#[path = "exact_intersection.rs"]
mod exact;
pub use exact::*;

// ---------------------------------------------------------------------------------------------
// Tests: constructions whose answer is known by geometry, an exact integer reference (separating
// axes) on random small-integer triangles, invariances, and two cubes' surfaces.
// ---------------------------------------------------------------------------------------------

use crate::common::Rng;
use softfem::glam::{DVec3, Vec3};

/// The triangle `t` translated by `offset`.
fn shifted(t: [Point; 3], offset: Point) -> [Point; 3] {
    t.map(|p| [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]])
}

/// Asserts the answer for `a, b` and that it does not change under swapping the two, cycling
/// either's corners or reversing either's orientation.
fn assert_intersect(a: [Point; 3], b: [Point; 3], expected: bool) {
    let cycles = |t: [Point; 3]| {
        [
            t,
            [t[1], t[2], t[0]],
            [t[2], t[0], t[1]],
            [t[0], t[2], t[1]],
            [t[2], t[1], t[0]],
            [t[1], t[0], t[2]],
        ]
    };
    for a in cycles(a) {
        for b in cycles(b) {
            assert_eq!(triangles_intersect(a, b), expected, "a = {a:?}, b = {b:?}");
            assert_eq!(triangles_intersect(b, a), expected, "a = {b:?}, b = {a:?}");
        }
    }
}

/// The answer "no intersecting pairs", typed.
const NO_PAIRS: &[[usize; 2]] = &[];

/// The unit right triangle in the plane z = 0.
const UNIT: [Point; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

#[test]
fn crossing_through_each_others_interiors() {
    // A vertical triangle in the plane y = 0.25 whose intersection with z = 0 is the segment
    // x in [0.1, 0.5], inside UNIT (x + y <= 0.75): interior points of both triangles.
    let vertical = [[0.1, 0.25, -1.0], [0.1, 0.25, 1.0], [0.5, 0.25, 0.0]];
    assert_intersect(UNIT, vertical, true);
    // In the plane y = 0.875 its left edge x = 0.125 meets UNIT's hypotenuse x + y = 1 exactly at
    // (0.125, 0.875, 0), the only common point (UNIT holds x <= 0.125 there, it x >= 0.125).
    let at_hypotenuse = [[0.125, 0.875, -1.0], [0.125, 0.875, 1.0], [0.5, 0.875, 0.0]];
    assert_intersect(UNIT, at_hypotenuse, true);
    // One ulp further in x: x + y > 1 on the whole triangle, no common point.
    let beyond = at_hypotenuse.map(|p| [p[0].next_up(), p[1], p[2]]);
    assert_intersect(UNIT, beyond, false);
    // One ulp back: the edge crosses UNIT's interior.
    let within = at_hypotenuse.map(|p| [p[0].next_down(), p[1], p[2]]);
    assert_intersect(UNIT, within, true);
}

#[test]
fn parallel_triangles_a_hair_apart_are_disjoint() {
    // Two triangles in parallel planes z = 1 and z = 1 + gap, overlapping when projected on xy.
    let low = [[0.1, 0.2, 1.0], [0.7, 0.3, 1.0], [0.3, 0.9, 1.0]];
    let high = |z: f64| [[0.2, 0.1, z], [0.9, 0.6, z], [0.15, 0.7, z]];
    assert_intersect(low, high(1.0 + 1e-12), false);
    assert_intersect(low, high(1.0f64.next_up()), false);
    assert_intersect(low, high(1.0f64.next_down()), false);
    // In the same plane they overlap (coplanar, (0.3, 0.5) is inside both).
    assert_intersect(low, high(1.0), true);
    // Tilted parallel planes z = (x + y) / 4 + h: exactly representable for these corners.
    let tilted = |t: [Point; 3], h: f64| t.map(|p| [p[0], p[1], (p[0] + p[1]) / 4.0 + h]);
    let a = [[0.125, 0.25, 0.0], [0.75, 0.375, 0.0], [0.25, 0.875, 0.0]];
    let b = [[0.25, 0.125, 0.0], [0.875, 0.5, 0.0], [0.125, 0.75, 0.0]];
    for t in [a, b] {
        for p in tilted(t, 0.5) {
            assert_eq!(
                (p[2] - 0.5) * 4.0,
                p[0] + p[1],
                "corner off the plane: {p:?}"
            );
        }
    }
    // With h = 0.5 + 2^-53 every z is in [0.5, 1) where the ulp is 2^-53: still exact.
    for p in tilted(b, 0.5f64.next_up()) {
        assert_eq!(
            (p[2] - 0.5f64.next_up()) * 4.0,
            p[0] + p[1],
            "corner off: {p:?}"
        );
    }
    assert_intersect(tilted(a, 0.5), tilted(b, 0.5), true);
    assert_intersect(tilted(a, 0.5), tilted(b, 0.5f64.next_up()), false);
    assert_intersect(tilted(a, 0.5), tilted(b, 0.5 + 1e-12), false);
}

#[test]
fn a_vertex_on_the_other_interior_touches() {
    // One corner exactly at (0.25, 0.25, 0), inside UNIT; the others above the plane.
    let above = [[0.25, 0.25, 0.0], [0.5, 0.0, 1.0], [0.0, 0.5, 2.0]];
    assert_intersect(UNIT, above, true);
    // At z = 1 (clear of subnormals), the corner one ulp above the plane: no contact.
    let unit_at_1 = shifted(UNIT, [0.0, 0.0, 1.0]);
    let on = shifted(above, [0.0, 0.0, 1.0]);
    assert_intersect(unit_at_1, on, true);
    let mut off = on;
    off[0][2] = 1.0f64.next_up();
    assert_intersect(unit_at_1, off, false);
    // The same through the corner one ulp below, the others still above: now it crosses.
    let mut through = on;
    through[0][2] = 1.0f64.next_down();
    assert_intersect(unit_at_1, through, true);
    // A tilted plane z = (x + 2 y) / 8, a corner exactly on it inside the triangle.
    let tilted = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.375], [0.0, 3.0, 0.75]];
    let apex = [0.5, 0.25, 0.125]; // (0.5 + 0.5) / 8 = 0.125: exactly on the plane, inside.
    let hanging = [apex, [0.5, 0.25, 2.0], [1.0, 1.0, 2.0]];
    assert_intersect(tilted, hanging, true);
    let mut lifted = hanging;
    lifted[0][2] = 0.125f64.next_up();
    assert_intersect(tilted, lifted, false);
}

#[test]
fn random_vertices_exactly_on_a_tilted_plane_touch() {
    // A triangle in the plane z = x and a corner of another exactly on it (z := x is exact for
    // any x), at random full-precision coordinates near 1000: a plain f64 orient3d rounds the
    // exactly-zero volume to either sign here, so this is where the exact predicates matter.
    // The corner is a convex combination with weights >= 0.2 of the first triangle's corners,
    // inside it by far more than rounding; the other two corners are strictly above (z > x).
    let mut rng = Rng::new(1997);
    for _ in 0..500 {
        let corner = |rng: &mut Rng| {
            let (x, y) = (1000.0 + rng.signed(), 1000.0 + rng.signed());
            [x, y, x]
        };
        let a = [corner(&mut rng), corner(&mut rng), corner(&mut rng)];
        let w0 = rng.uniform(0.2, 0.6);
        let w1 = rng.uniform(0.2, 0.8 - w0);
        let w2 = 1.0 - w0 - w1;
        let x = w0 * a[0][0] + w1 * a[1][0] + w2 * a[2][0];
        let y = w0 * a[0][1] + w1 * a[1][1] + w2 * a[2][1];
        let on = [[x, y, x], [x + 0.5, y, x + 1.0], [x, y + 0.5, x + 2.0]];
        assert!(triangles_intersect(a, on), "a = {a:?}, b = {on:?}");
        assert!(triangles_intersect(on, a), "a = {on:?}, b = {a:?}");
        // One ulp above the plane: all three corners strictly on one side.
        let mut above = on;
        above[0][2] = x.next_up();
        assert!(!triangles_intersect(a, above), "a = {a:?}, b = {above:?}");
        assert!(!triangles_intersect(above, a), "a = {above:?}, b = {a:?}");
    }
}

#[test]
fn coplanar_edges_crossing_intersect() {
    // A "star of David": two coplanar triangles, no vertex of either inside the other, each edge
    // of one crossing two edges of the other.
    let up = [[0.0, 0.0, 0.5], [6.0, 0.0, 0.5], [3.0, 6.0, 0.5]];
    let down = [[0.0, 4.0, 0.5], [3.0, -2.0, 0.5], [6.0, 4.0, 0.5]];
    assert_intersect(up, down, true);
    // Coplanar, touching at one point only: a vertex of one exactly on an edge of the other.
    let beside = [[3.0, 0.0, 0.5], [5.0, -3.0, 0.5], [1.0, -3.0, 0.5]];
    assert_intersect(up, beside, true);
    // Moved by -2^-40 in y (exact here): apart.
    assert_intersect(up, shifted(beside, [0.0, -2f64.powi(-40), 0.0]), false);
    // Two slivers whose long edges cross at (2, 2, 0.5), the only common point:
    // (0,0)-(4,4)-(4,4.5) lies on or above the line y = x, (0,4)-(4,0)-(4,-0.5) on or below
    // y = 4 - x, and (2, 2) is where those lines meet.
    let sliver_a = [[0.0, 0.0, 0.5], [4.0, 4.0, 0.5], [4.0, 4.5, 0.5]];
    let sliver_b = [[0.0, 4.0, 0.5], [4.0, 0.0, 0.5], [4.0, -0.5, 0.5]];
    assert_intersect(sliver_a, sliver_b, true);
}

#[test]
fn coplanar_near_collinear_grid_of_kettner_et_al() {
    // The configuration of L. Kettner, K. Mehlhorn, S. Pion, S. Schirra and C. Yap, "Classroom
    // examples of robustness problems in geometric computations" (Computational Geometry 40,
    // 2008), on which a plain f64 orient2d gets the sign wrong in patches: points
    // p = (0.5 + i u, 0.5 + j u), u = 2^-53 (exact: the ulp of 0.5), against the line y = x
    // through q = (-11.5, -11.5) and r = (12.5, 12.5). Triangle a = q r s with s = (12.5, -11.5)
    // lies on and below that line (y <= x) and holds p's neighbourhood up to the line; triangle
    // b has its corner at p and its other corners strictly above the line. So they meet (at p)
    // exactly when p is on or below the line: j <= i.
    let a = [[-11.5, -11.5, 0.0], [12.5, 12.5, 0.0], [12.5, -11.5, 0.0]];
    let u = 2f64.powi(-53);
    for i in 0..24 {
        for j in 0..24 {
            let p = [0.5 + f64::from(i) * u, 0.5 + f64::from(j) * u, 0.0];
            let b = [p, [-3.0, 3.0, 0.0], [0.0, 5.0, 0.0]];
            assert_intersect(a, b, j <= i);
        }
    }
}

#[test]
fn coplanar_disjoint_triangles_do_not_intersect() {
    let a = [[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]];
    // Across the hypotenuse x + y = 1, the nearest corner at x + y = 1 + ulp.
    let b = [
        [0.5f64.next_up(), 0.5, 2.0],
        [2.0, 0.5, 2.0],
        [1.0, 2.0, 2.0],
    ];
    assert_intersect(a, b, false);
    let touching = [[0.5, 0.5, 2.0], [2.0, 0.5, 2.0], [1.0, 2.0, 2.0]];
    assert_intersect(a, touching, true);
    // Far apart in the same plane.
    assert_intersect(a, shifted(a, [3.0, 0.0, 0.0]), false);
    // In the tilted plane x + y + z = 1: b has x + y >= 1.5, a has x + y <= 1.
    let tilted_a = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let tilted_b = [[1.0, 0.5, -0.5], [0.5, 1.0, -0.5], [1.0, 1.0, -1.0]];
    assert_intersect(tilted_a, tilted_b, false);
}

#[test]
fn coplanar_one_inside_the_other_intersect() {
    // No edges cross: only the edge-inside-triangle half of the test sees it.
    let outer = [[0.0, 0.0, 0.0], [8.0, 0.0, 4.0], [0.0, 8.0, 2.0]]; // plane z = x/2 + y/4
    let inner = [[1.0, 1.0, 0.75], [3.0, 1.0, 1.75], [1.0, 3.0, 1.25]];
    assert_intersect(outer, inner, true);
    // The same triangle twice, and a degenerate one (a point, a segment) inside.
    assert_intersect(outer, outer, true);
    let point = [[1.0, 1.0, 0.75]; 3];
    assert_intersect(outer, point, true);
    let segment = [[1.0, 1.0, 0.75], [3.0, 1.0, 1.75], [2.0, 1.0, 1.25]];
    assert_intersect(outer, segment, true);
    // The point lifted by one ulp, the segment moved off the plane.
    assert_intersect(outer, [[1.0, 1.0, 0.75f64.next_up()]; 3], false);
    assert_intersect(outer, shifted(segment, [0.0, 0.0, 1e-9]), false);
}

#[test]
fn a_triangle_piercing_an_edge_intersects() {
    // A triangle in the plane x = 0.5 whose edge from (0.5, -1, 1) to (0.5, 1, -1) passes
    // through (0.5, 0, 0), a point of UNIT's edge y = 0. In the plane z = 0 it covers
    // y in [-1.5, 0] at x = 0.5, so it meets UNIT at that single point.
    let piercing = [[0.5, -1.0, 1.0], [0.5, 1.0, -1.0], [0.5, -3.0, -3.0]];
    assert_intersect(UNIT, piercing, true);
    // Moved by -2^-40 in y (exact for these coordinates) it misses, by +2^-40 it cuts through.
    let delta = 2f64.powi(-40);
    assert_intersect(UNIT, shifted(piercing, [0.0, -delta, 0.0]), false);
    assert_intersect(UNIT, shifted(piercing, [0.0, delta, 0.0]), true);
    // A triangle in the plane y = 0, which holds UNIT's edge y = 0: its interior contains the
    // part x in [0.5, 1] of that edge. Moved off that plane by 2^-40 towards -y, it misses.
    let through_edge = [[0.5, 0.0, -1.0], [0.5, 0.0, 1.0], [3.0, 0.0, 0.0]];
    assert_intersect(UNIT, through_edge, true);
    assert_intersect(UNIT, shifted(through_edge, [0.0, -delta, 0.0]), false);
    // Non-coplanar edges crossing: the vertical edge at (0.5, 0.5) meets UNIT's hypotenuse at
    // its midpoint; the triangle (in the plane x = y) holds x = y >= 0.5 at z = 0, UNIT x = y
    // <= 0.5, so that point is the only common one.
    let across = [[0.5, 0.5, -1.0], [0.5, 0.5, 1.0], [2.0, 2.0, 0.0]];
    assert_intersect(UNIT, across, true);
    assert_intersect(UNIT, shifted(across, [delta, delta, 0.0]), false);
}

#[test]
fn segments_and_points_as_degenerate_triangles() {
    let segment = |p: Point, q: Point| [p, q, q];
    // Skew segments never meet; crossing ones do, collinear ones when they overlap.
    let x_axis = segment([0.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
    assert_intersect(x_axis, segment([1.0, -1.0, 1.0], [1.0, 1.0, 1.0]), false);
    assert_intersect(x_axis, segment([1.0, -1.0, 0.0], [1.0, 1.0, 0.0]), true);
    assert_intersect(x_axis, segment([2.0, 0.0, 0.0], [3.0, 0.0, 0.0]), true);
    assert_intersect(
        x_axis,
        segment([2.0f64.next_up(), 0.0, 0.0], [3.0, 0.0, 0.0]),
        false,
    );
    // A segment along z (only its z differs) overlapping another.
    let z_axis = segment([0.0, 0.0, 1.0], [0.0, 0.0, 3.0]);
    assert_intersect(z_axis, segment([0.0, 0.0, 2.0], [0.0, 0.0, 5.0]), true);
    assert_intersect(z_axis, segment([0.0, 0.0, 4.0], [0.0, 0.0, 5.0]), false);
    // A point and a point.
    assert_intersect([[1.0, 2.0, 3.0]; 3], [[1.0, 2.0, 3.0]; 3], true);
    assert_intersect(
        [[1.0, 2.0, 3.0]; 3],
        [[1.0, 2.0, 3.0f64.next_up()]; 3],
        false,
    );
}

/// The exact answer for triangles with small integer corners, by the separating-axis theorem on
/// the Minkowski difference `K = a - b` (the hull of the nine points `a_i - b_j`): the triangles
/// meet if and only if `0` is in `K`, and if it is not, a plane through `0` strictly separates
/// it from `K`, with a normal among: the normals of planes through three points of K (K's facets
/// when it is solid, its plane when it is flat), one such plane normal crossed with the
/// difference of two points (the edges' in-plane normals when K is flat), `(u x v) x (v - u)` and
/// `v - u` for two points (K a segment off or on a line through 0) and a point itself (K a
/// point). Any extra axis is harmless: strict separation on any axis is a proof. All in i64.
fn reference_intersect(a: [[i64; 3]; 3], b: [[i64; 3]; 3]) -> bool {
    type V = [i64; 3];
    let sub = |u: V, v: V| [u[0] - v[0], u[1] - v[1], u[2] - v[2]];
    let cross = |u: V, v: V| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let dot = |u: V, v: V| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let points: Vec<V> = a
        .iter()
        .flat_map(|&p| b.iter().map(move |&q| sub(p, q)))
        .collect();
    let mut axes: Vec<V> = points.clone();
    for (i, &u) in points.iter().enumerate() {
        for &v in &points[i + 1..] {
            axes.push(sub(v, u));
            axes.push(cross(cross(u, v), sub(v, u)));
        }
    }
    let mut plane_normal = None;
    for i in 0..points.len() {
        for j in i + 1..points.len() {
            for k in j + 1..points.len() {
                let n = cross(sub(points[j], points[i]), sub(points[k], points[i]));
                if n != [0; 3] {
                    axes.push(n);
                    plane_normal.get_or_insert(n);
                }
            }
        }
    }
    if let Some(n) = plane_normal {
        for (i, &u) in points.iter().enumerate() {
            for &v in &points[i + 1..] {
                axes.push(cross(n, sub(v, u)));
            }
        }
    }
    let separated = axes
        .iter()
        .any(|&w| points.iter().all(|&k| dot(w, k) > 0) || points.iter().all(|&k| dot(w, k) < 0));
    !separated
}

#[test]
fn agrees_with_an_integer_separating_axis_reference() {
    // Corners on the small grid {0..=range}^3: many coplanar, touching and degenerate pairs.
    let mut rng = Rng::new(39);
    let mut counts = [0usize; 2];
    for trial in 0..4000 {
        let range = [1, 2, 3, 5][trial % 4] as usize + 1;
        let mut corner = || -> [i64; 3] { core::array::from_fn(|_| rng.below(range) as i64) };
        let a = [corner(), corner(), corner()];
        let b = [corner(), corner(), corner()];
        let expected = reference_intersect(a, b);
        let as_f64 = |t: [[i64; 3]; 3]| t.map(|p| p.map(|x| x as f64));
        assert_eq!(
            triangles_intersect(as_f64(a), as_f64(b)),
            expected,
            "a = {a:?}, b = {b:?}"
        );
        // Scaled by 2^-30 and translated by 2^10 (both exact here), the answer stays.
        let moved = |t: [[i64; 3]; 3]| t.map(|p| p.map(|x| x as f64 * 2f64.powi(-30) + 1024.0));
        assert_eq!(triangles_intersect(moved(a), moved(b)), expected);
        counts[usize::from(expected)] += 1;
    }
    // Both answers well represented (the mix is what makes the comparison mean something).
    assert!(
        counts[0] > 500 && counts[1] > 500,
        "disjoint, intersecting: {counts:?}"
    );
}

#[test]
fn answers_do_not_change_under_swaps_cycles_and_powers_of_two() {
    // Corners on the grid of multiples of 2^-20 in [-1, 1], so translating by 2^k (k <= 30) and
    // scaling by 2^k are exact. Half the pairs are built to be near-touching: b's first corner
    // is a's corner or a point of a's edge (coordinates averaged, exact on this grid up to one
    // more bit), b's others random.
    let mut rng = Rng::new(2003);
    let grid = |rng: &mut Rng| (rng.signed() * 1048576.0).round() / 1048576.0;
    let mut counts = [0usize; 2];
    for trial in 0..1500 {
        let a: [Point; 3] = core::array::from_fn(|_| core::array::from_fn(|_| grid(&mut rng)));
        let mut b: [Point; 3] = core::array::from_fn(|_| core::array::from_fn(|_| grid(&mut rng)));
        if trial % 2 == 0 {
            let (i, j) = (rng.below(3), rng.below(3));
            b[0] = core::array::from_fn(|k| (a[i][k] + a[j][k]) / 2.0);
        }
        let expected = triangles_intersect(a, b);
        counts[usize::from(expected)] += 1;
        let cycle = |t: [Point; 3]| [t[1], t[2], t[0]];
        let reverse = |t: [Point; 3]| [t[0], t[2], t[1]];
        assert_eq!(
            triangles_intersect(b, a),
            expected,
            "swap: a = {a:?}, b = {b:?}"
        );
        assert_eq!(triangles_intersect(cycle(a), b), expected);
        assert_eq!(triangles_intersect(a, cycle(cycle(b))), expected);
        assert_eq!(triangles_intersect(reverse(a), reverse(b)), expected);
        let power = 2f64.powi(rng.below(31) as i32);
        let offset = [power, -power, 2.0 * power];
        assert_eq!(
            triangles_intersect(shifted(a, offset), shifted(b, offset)),
            expected,
            "translated by {offset:?}: a = {a:?}, b = {b:?}"
        );
        let scale = 2f64.powi(rng.below(81) as i32 - 40);
        let scaled = |t: [Point; 3]| t.map(|p| p.map(|x| x * scale));
        assert_eq!(triangles_intersect(scaled(a), scaled(b)), expected);
    }
    assert!(
        counts[0] > 150 && counts[1] > 150,
        "disjoint, intersecting: {counts:?}"
    );
}

/// The unit cube's 12 outward triangles (corner `c` at `(c & 1, c >> 1 & 1, c >> 2 & 1)`) and a
/// second cube translated by `offset`: 16 positions, 24 triangles (the second's indices + 8).
/// Triangles `2 f` and `2 f + 1` form face `f` of the first cube, `12 + 2 f`, `13 + 2 f` of the
/// second; faces: 0 z = 0, 1 z = 1, 2 y = 0, 3 y = 1, 4 x = 0, 5 x = 1 (before the offset).
fn two_cubes(offset: Point) -> (Vec<Point>, Vec<[u32; 3]>) {
    let cube = [
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
        [1, 7, 5],
    ];
    let corner = |c: u32| {
        [
            f64::from(c & 1),
            f64::from(c >> 1 & 1),
            f64::from(c >> 2 & 1),
        ]
    };
    let positions = (0..16)
        .map(|c| {
            let p = corner(c % 8);
            if c < 8 { p } else { shifted([p; 3], offset)[0] }
        })
        .collect();
    let triangles = cube
        .iter()
        .copied()
        .chain(cube.iter().map(|t: &[u32; 3]| t.map(|v| v + 8)))
        .collect();
    (positions, triangles)
}

#[test]
fn two_cubes_apart_have_no_pairs_and_overlapping_ones_do() {
    // The face of each triangle, as "first cube x+" etc., and the check that the face numbering
    // in two_cubes is right: every corner of a triangle of face f has the face's coordinate.
    let (positions, triangles) = two_cubes([0.0; 3]);
    for (t, triangle) in triangles[..12].iter().enumerate() {
        let (axis, side) = ([2, 2, 1, 1, 0, 0][t / 2], (t / 2 % 2) as f64);
        for &v in triangle {
            assert_eq!(positions[v as usize][axis], side, "triangle {t}");
        }
    }
    // One cube alone: a closed surface whose triangles meet only where they share vertices.
    assert_eq!(
        intersecting_pairs(&positions[..8], &triangles[..12]),
        NO_PAIRS
    );

    // 0.01 apart along x (and shifted in y and z so that no faces are coplanar): nothing.
    let (positions, triangles) = two_cubes([1.01, 0.25, 0.375]);
    assert_eq!(intersecting_pairs(&positions, &triangles), NO_PAIRS);
    // Exactly touching along x = 1 (faces coplanar, overlapping): pairs; one ulp apart: none.
    let (positions, triangles) = two_cubes([1.0, 0.25, 0.375]);
    // The surfaces touch on the rectangle x = 1, y in [0.25, 1], z in [0.375, 1]. It lies in the
    // first cube's x = 1 face and the second's x = 1 face (its x- face); its edge y = 1 in the
    // first's y = 1 face, z = 1 in the first's z = 1 face, y = 0.25 in the second's y- face,
    // z = 0.375 in the second's z- face. Every face pair holding a common point of it touches:
    // the three x = 1 pairs, (first y+, second x-), (first z+, second x-), and two pairs that meet
    // at a corner only: first z+ and second y- at (1, 0.25, 1), first y+ and second z- at
    // (1, 1, 0.375). The first's y = 0, z = 0 faces and the second's far faces miss it.
    let face = |t: usize| t / 2; // 0..6 first cube, 6..12 second
    let face_pairs = |pairs: &[[usize; 2]]| {
        let mut faces: Vec<[usize; 2]> = pairs.iter().map(|&[s, t]| [face(s), face(t)]).collect();
        faces.sort_unstable();
        faces.dedup();
        faces
    };
    let (x_low, x_high, y_low, y_high, z_low, z_high) = (4, 5, 2, 3, 0, 1);
    let touching = intersecting_pairs(&positions, &triangles);
    let mut expected = vec![
        [x_high, 6 + x_low],
        [x_high, 6 + y_low],
        [x_high, 6 + z_low],
        [y_high, 6 + x_low],
        [z_high, 6 + x_low],
        [z_high, 6 + y_low],
        [y_high, 6 + z_low],
    ];
    expected.sort_unstable();
    assert_eq!(face_pairs(&touching), expected, "pairs: {touching:?}");
    let (positions, triangles) = two_cubes([1.0f64.next_up(), 0.25, 0.375]);
    assert_eq!(intersecting_pairs(&positions, &triangles), NO_PAIRS);
    // Touching the same way across y = 1 and z = 1 (the broad phase's boxes then touch in y or
    // z, not in the sweep's x): the first's high face and the second's low face on that axis
    // touch; one ulp further apart, nothing does.
    for (axis, high, low) in [(1, y_high, y_low), (2, z_high, z_low)] {
        let mut offset = [0.25, 0.375, 0.125];
        offset[axis] = 1.0;
        let (positions, triangles) = two_cubes(offset);
        let touching = face_pairs(&intersecting_pairs(&positions, &triangles));
        assert!(
            touching.contains(&[high, 6 + low]),
            "axis {axis}: {touching:?}"
        );
        offset[axis] = 1.0f64.next_up();
        let (positions, triangles) = two_cubes(offset);
        assert_eq!(intersecting_pairs(&positions, &triangles), NO_PAIRS);
    }

    // Overlapping by 0.01 in x: the overlap box is [0.99, 1] x [0.25, 1] x [0.375, 1], and the
    // two surfaces cross along its six edges where a face of the first cube (x = 1, y = 1, z = 1)
    // meets a face of the second (its x = 0.99, y = 0.25, z = 0.375 faces) — no other faces meet
    // (the others are parallel and apart, or out of the other cube's range).
    let (positions, triangles) = two_cubes([0.99, 0.25, 0.375]);
    let pairs = intersecting_pairs(&positions, &triangles);
    let mut expected = vec![
        [x_high, 6 + y_low],
        [x_high, 6 + z_low],
        [y_high, 6 + x_low],
        [y_high, 6 + z_low],
        [z_high, 6 + x_low],
        [z_high, 6 + y_low],
    ];
    expected.sort_unstable();
    assert_eq!(face_pairs(&pairs), expected, "pairs: {pairs:?}");

    // The same through the f32 and DVec3 entry points (every coordinate here converts exactly
    // to f32 except 0.99, 1.99; the f32 cubes still overlap by about 0.01 and cross the same way).
    let as_f32: Vec<Vec3> = positions
        .iter()
        .map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
        .collect();
    assert_eq!(intersecting_pairs_f32(&as_f32, &triangles), pairs);
    let as_dvec: Vec<DVec3> = positions.iter().map(|&p| DVec3::from_array(p)).collect();
    assert_eq!(intersecting_pairs_f64(&as_dvec, &triangles), pairs);
}

#[test]
fn a_wavy_sheet_of_ten_thousand_triangles_and_one_piercing_it() {
    // A height field z = sin(x) cos(y) / 2 over a 71 x 71 grid (9800 triangles): a surface that
    // cannot cross itself. Every triangle's box touches its neighbours' (shared vertices,
    // skipped) and some boxes touch without shared vertices (tested exactly, disjoint).
    let n = 71;
    let positions: Vec<Point> = (0..n * n)
        .map(|v| {
            let (x, y) = ((v % n) as f64 * 0.1, (v / n) as f64 * 0.1);
            [x, y, x.sin() * y.cos() / 2.0]
        })
        .collect();
    let mut triangles = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = (j * n + i) as u32;
            let n = n as u32;
            triangles.push([v, v + 1, v + n + 1]);
            triangles.push([v, v + n + 1, v + n]);
        }
    }
    assert_eq!(triangles.len(), 9800);
    assert_eq!(intersecting_pairs(&positions, &triangles), NO_PAIRS);
    // A small vertical triangle in the plane y = 3.01 through the cell [3, 3.1] x [3, 3.1]
    // (i = j = 30): at the sheet's heights (|z| <= 0.5) it spans x in about [3.024, 3.036], right
    // of the cell's diagonal (x - 3 > y - 3 = 0.01), so it pierces the cell's first triangle,
    // number 2 (30 * 70 + 30) = 4260, and nothing else.
    let mut pierced = positions.clone();
    pierced.extend([[3.02, 3.01, -2.0], [3.04, 3.01, -2.0], [3.03, 3.01, 2.0]]);
    let first_new = (n * n) as u32;
    triangles.push([first_new, first_new + 1, first_new + 2]);
    assert_eq!(intersecting_pairs(&pierced, &triangles), vec![[4260, 9800]]);
}

//! The exact triangle–triangle intersection check shared by the contact tests
//! (`tests/common/intersection.rs`, whose module docs give the method and its tests) and the pile
//! example (`examples/pile`, which includes this file by `#[path]`): [`triangles_intersect`],
//! [`intersecting_pairs`] and its f32 and f64 forms. No tests and no use of the test suite's
//! `common` module here, so that a program outside the test suite can include it.
//!
//! Every decision is the sign of an orientation determinant, `orient3d` or `orient2d`, computed
//! exactly by the adaptive expansion arithmetic of J. R. Shewchuk, "Adaptive Precision
//! Floating-Point Arithmetic and Fast Robust Geometric Predicates" (Discrete & Computational
//! Geometry 18, 1997), as ported by the `robust` crate; the method is that of P. Guigue and
//! O. Devillers, "Fast and Robust Triangle–Triangle Overlap Test Using Orientation Predicates"
//! (Journal of Graphics Tools 8(1), 2003). Non-finite coordinates panic.
#![allow(dead_code)]

use robust::{Coord, Coord3D, orient2d, orient3d};
use softfem::glam::{DVec3, Vec3};

/// A point as three f64 coordinates `[x, y, z]`.
pub type Point = [f64; 3];

/// The exact sign (-1, 0 or +1) of `orient3d(a, b, c, d)`: the signed volume of the tetrahedron
/// `a b c d` (robust's convention: positive when `d` lies below the plane of `a b c`, "below"
/// being the side from which `a b c` appear clockwise). Only sign agreements matter here, never
/// which side is called positive.
fn orient3d_sign(a: Point, b: Point, c: Point, d: Point) -> i8 {
    let coord = |p: Point| Coord3D {
        x: p[0],
        y: p[1],
        z: p[2],
    };
    sign(orient3d(coord(a), coord(b), coord(c), coord(d)))
}

/// The exact sign of the 2D orientation of `a b c` projected onto the coordinate plane that drops
/// axis `dropped` (0: onto yz, 1: onto zx, 2: onto xy).
///
/// With `(u, v) = (dropped + 1, dropped + 2) mod 3`, this determinant is exactly component
/// `dropped` of the normal `(b - a) x (c - a)`: zero for every axis if and only if `a b c` are
/// collinear (or coincide).
fn orient2d_sign(dropped: usize, a: Point, b: Point, c: Point) -> i8 {
    let (u, v) = ((dropped + 1) % 3, (dropped + 2) % 3);
    let coord = |p: Point| Coord { x: p[u], y: p[v] };
    sign(orient2d(coord(a), coord(b), coord(c)))
}

/// The sign of an exactly signed value; robust's results are exact in sign, not in magnitude.
fn sign(value: f64) -> i8 {
    if value > 0.0 {
        1
    } else if value < 0.0 {
        -1
    } else {
        0
    }
}

/// The axis whose dropping projects the plane of the non-degenerate triangle `a b c` one to one
/// onto a coordinate plane, with the triangle's projected orientation (never 0); `None` when the
/// triangle is degenerate (its corners collinear or coincident).
///
/// Why the projection is exact: component `k` of the normal `n = (b - a) x (c - a)` is the 2D
/// orientation of the projection dropping axis `k` (the same determinant), so its sign is exact
/// (robust's orient2d; robust's orient3d of `a b c` and `a + e_k` would give the same sign but
/// `a + e_k` is not representable in general). `n_k != 0` means the plane is not perpendicular to
/// that coordinate plane, so the projection is an affine bijection from the plane onto it. A
/// bijection keeps intersections (`P(X ∩ Y) = P(X) ∩ P(Y)`), and an affine one multiplies every
/// orientation determinant of points in the plane by the same factor, whose sign is
/// `sign(n_k)`: all 2D orientation signs of coplanar points flip together or not at all, and the
/// tests below only compare such signs with each other.
fn projection_axis(a: Point, b: Point, c: Point) -> Option<(usize, i8)> {
    (0..3).find_map(|k| {
        let orientation = orient2d_sign(k, a, b, c);
        (orientation != 0).then_some((k, orientation))
    })
}

/// Whether the closed segments `p q` and `a b`, points of one coordinate plane (given in 3D,
/// projected by dropping axis `dropped`, which must be one to one on them), share a point.
///
/// The classic orientation test: a proper crossing has strictly opposite signs on both sides;
/// otherwise they meet only if an endpoint lies on the other segment, which for a point known to
/// be on the other segment's line is a coordinate-box check (exact comparisons). Degenerate
/// segments (`p == q`) are handled: all their orientations are 0 and the box is the point.
fn segments_intersect_2d(dropped: usize, p: Point, q: Point, a: Point, b: Point) -> bool {
    let o1 = orient2d_sign(dropped, p, q, a);
    let o2 = orient2d_sign(dropped, p, q, b);
    let o3 = orient2d_sign(dropped, a, b, p);
    let o4 = orient2d_sign(dropped, a, b, q);
    if o1 * o2 < 0 && o3 * o4 < 0 {
        return true;
    }
    (o1 == 0 && in_box(p, q, a))
        || (o2 == 0 && in_box(p, q, b))
        || (o3 == 0 && in_box(a, b, p))
        || (o4 == 0 && in_box(a, b, q))
}

/// Whether `r` lies in the closed axis-aligned box of `p` and `q` (every coordinate between
/// theirs). For `r` on the line of `p q` this is "r on the closed segment `p q`".
fn in_box(p: Point, q: Point, r: Point) -> bool {
    (0..3).all(|k| p[k].min(q[k]) <= r[k] && r[k] <= p[k].max(q[k]))
}

/// Whether the closed segments `p q` and `a b` in 3D share a point (any of them may be
/// degenerate).
fn segments_intersect_3d(p: Point, q: Point, a: Point, b: Point) -> bool {
    if orient3d_sign(p, q, a, b) != 0 {
        // Not coplanar: the two lines are skew (neither segment is a point, else the volume
        // would be 0), so they share no point.
        return false;
    }
    // Coplanar. If some three of the four points are not collinear they span the common plane,
    // and a projection in which that triple keeps a nonzero orientation is one to one on it.
    let points = [p, q, a, b];
    let triples = [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
    for dropped in 0..3 {
        let spans = triples
            .iter()
            .any(|&[i, j, k]| orient2d_sign(dropped, points[i], points[j], points[k]) != 0);
        if spans {
            return segments_intersect_2d(dropped, p, q, a, b);
        }
    }
    // All four collinear. Along a coordinate in which they differ, the line maps one to one and
    // monotonically onto the axis, so the segments meet if and only if their intervals do.
    for k in 0..3 {
        let differ = points.iter().any(|point| point[k] != p[k]);
        if differ {
            return p[k].min(q[k]) <= a[k].max(b[k]) && a[k].min(b[k]) <= p[k].max(q[k]);
        }
    }
    // All four are one point.
    true
}

/// Whether the closed segment `p q` and the closed triangle `t` share a point.
fn segment_meets_triangle(p: Point, q: Point, t: [Point; 3]) -> bool {
    let [a, b, c] = t;
    let Some((dropped, orientation)) = projection_axis(a, b, c) else {
        // A degenerate triangle (collinear corners) is the union of its three edges: the hull of
        // collinear points is the segment between the two extreme ones, which is one of them.
        return segments_intersect_3d(p, q, a, b)
            || segments_intersect_3d(p, q, b, c)
            || segments_intersect_3d(p, q, c, a);
    };
    let side_p = orient3d_sign(a, b, c, p);
    let side_q = orient3d_sign(a, b, c, q);
    if side_p * side_q > 0 {
        // Both endpoints strictly on the same side of the plane.
        return false;
    }
    if side_p == 0 && side_q == 0 {
        // The segment lies in the triangle's plane: in the projection (one to one on the plane),
        // it meets the closed triangle if an endpoint is inside it or it meets an edge.
        let inside = |r: Point| {
            [(a, b), (b, c), (c, a)]
                .iter()
                .all(|&(e0, e1)| orient2d_sign(dropped, e0, e1, r) * orientation >= 0)
        };
        return inside(p)
            || inside(q)
            || segments_intersect_2d(dropped, p, q, a, b)
            || segments_intersect_2d(dropped, p, q, b, c)
            || segments_intersect_2d(dropped, p, q, c, a);
    }
    // The segment crosses (or ends on) the plane at exactly one point X, and its line is not
    // parallel to the plane. X is in the closed triangle if and only if the line passes on the
    // same side of the three directed edges: the volumes `p q a b`, `p q b c`, `p q c a` have no
    // two strictly opposite signs (a zero means X is on that edge's line; they cannot all be
    // zero, as the three edge lines of a non-degenerate triangle have no common point).
    let around = [
        orient3d_sign(p, q, a, b),
        orient3d_sign(p, q, b, c),
        orient3d_sign(p, q, c, a),
    ];
    !(around.contains(&1) && around.contains(&-1))
}

/// Panics with a readable message if a coordinate is NaN or infinite: the predicates' signs are
/// meaningless there, and a non-finite position is a failed step anyway.
fn assert_finite(triangle: &[Point; 3], name: &str) {
    assert!(
        triangle.iter().flatten().all(|x| x.is_finite()),
        "triangle {name} has a non-finite coordinate: {triangle:?}"
    );
}

/// Whether the CLOSED triangles `a` and `b` (corners as `[x, y, z]`) share at least one point,
/// decided exactly (module docs): touching at a vertex, along an edge or in a coplanar overlap
/// counts as intersecting; a gap of one ulp does not.
///
/// Degenerate triangles (collinear or coincident corners) are treated as the segment or point
/// they are. Panics if a coordinate is not finite.
///
/// Why the six edge–triangle tests decide it: if the triangles meet, take an extreme point `x`
/// of the compact convex set `a ∩ b`. If `x` were in the relative interior of both, then, as the
/// affine hulls of two non-degenerate triangles meet in a line or a plane when they meet at all,
/// a small piece of that line or plane around `x` would lie in `a ∩ b`, and `x` would not be
/// extreme. So `x` is on an edge of `a` or of `b`, which then meets the other triangle. A
/// degenerate triangle is the union of its edges, so the claim holds for it trivially.
pub fn triangles_intersect(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> bool {
    assert_finite(&a, "a");
    assert_finite(&b, "b");
    // Guigue and Devillers' early exit: all corners of one strictly on one side of the other's
    // plane (for a degenerate triangle all signs are 0 and this never fires).
    let strictly_one_side = |t: &[Point; 3], s: &[Point; 3]| {
        let sides = s.map(|p| orient3d_sign(t[0], t[1], t[2], p));
        sides.iter().all(|&side| side > 0) || sides.iter().all(|&side| side < 0)
    };
    if strictly_one_side(&a, &b) || strictly_one_side(&b, &a) {
        return false;
    }
    let edges = |t: [Point; 3]| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])];
    edges(a)
        .iter()
        .any(|&(p, q)| segment_meets_triangle(p, q, b))
        || edges(b)
            .iter()
            .any(|&(p, q)| segment_meets_triangle(p, q, a))
}

/// Every pair `[i, j]` (`i < j`, indices into `triangles`) of triangles that share NO vertex index
/// and intersect ([`triangles_intersect`], exact, touching included), sorted.
///
/// Pairs sharing a vertex index are skipped, because neighbours on a surface always touch (at the
/// shared vertex or edge). What that misses: an intersection between such neighbours away from
/// what they share — a fold, where a triangle turns over onto its neighbour or passes through a
/// triangle of its own vertex star — and a degenerate triangle's self-overlap. Check those another
/// way (element inversion, the tetrahedra's signed volumes).
///
/// Broad phase: axis-aligned boxes (exact: min and max of the coordinates), sorted by their min
/// x and swept (sweep and prune); only pairs whose closed boxes overlap on all three axes get the
/// exact test. Panics if a triangle names a vertex out of range of `positions` or one with a
/// non-finite coordinate.
pub fn intersecting_pairs(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<[usize; 2]> {
    let corners = |t: usize| -> [Point; 3] {
        triangles[t].map(|vertex| {
            *positions.get(vertex as usize).unwrap_or_else(|| {
                panic!(
                    "triangle {t} names vertex {vertex}, but there are {} positions",
                    positions.len()
                )
            })
        })
    };
    let boxes: Vec<[Point; 2]> = (0..triangles.len())
        .map(|t| {
            let [p, q, r] = corners(t);
            assert_finite(&[p, q, r], &format!("{t}"));
            let low = core::array::from_fn(|k| p[k].min(q[k]).min(r[k]));
            let high = core::array::from_fn(|k| p[k].max(q[k]).max(r[k]));
            [low, high]
        })
        .collect();
    // (box, triangle) in sweep order, so that the inner loop reads consecutive memory.
    let mut sorted: Vec<([Point; 2], usize)> = boxes.into_iter().zip(0..).collect();
    sorted.sort_by(|(s, _), (t, _)| s[0][0].total_cmp(&t[0][0]));

    let mut pairs = Vec::new();
    for (rank, &([low_s, high_s], s)) in sorted.iter().enumerate() {
        for &([low_t, high_t], t) in &sorted[rank + 1..] {
            if low_t[0] > high_s[0] {
                // Sorted by min x: no later box reaches back to this one.
                break;
            }
            let overlap = low_t[1] <= high_s[1]
                && low_s[1] <= high_t[1]
                && low_t[2] <= high_s[2]
                && low_s[2] <= high_t[2];
            if overlap
                && !triangles[s].iter().any(|v| triangles[t].contains(v))
                && triangles_intersect(corners(s), corners(t))
            {
                pairs.push([s.min(t), s.max(t)]);
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// [`intersecting_pairs`] for f32 positions (converted to f64 exactly, so the answer is exact for
/// the f32 positions themselves).
pub fn intersecting_pairs_f32(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<[usize; 2]> {
    let positions: Vec<Point> = positions
        .iter()
        .map(|p| p.to_array().map(f64::from))
        .collect();
    intersecting_pairs(&positions, triangles)
}

/// [`intersecting_pairs`] for glam's f64 vectors.
pub fn intersecting_pairs_f64(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<[usize; 2]> {
    let positions: Vec<Point> = positions.iter().map(|p| p.to_array()).collect();
    intersecting_pairs(&positions, triangles)
}

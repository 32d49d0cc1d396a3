//! The squared distance between a point and a triangle (`docs/math.md` section 8.3).

use super::super::super::super::types::{Real, Vec3};
use super::point_edge::{EdgeFeature, point_edge};
use super::{PairDistance, PairDistanceGradient, Slot, Stationary, negligible, placed};

/// Which feature of a triangle `t0 t1 t2` is closest to a point, and so which smooth formula
/// gives the distance: point–point for a corner, point–line for an edge, point–plane for the
/// interior.
///
/// Ties (a point equally far from two features, e.g. on the bisector of two edges) go to the
/// first in the order `Face`, `Edge01`, `Edge12`, `Edge20`, and within an edge to its first end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PointTriangleKind {
    /// The corner `t0`.
    Vertex0,
    /// The corner `t1`.
    Vertex1,
    /// The corner `t2`.
    Vertex2,
    /// A point inside the edge `t0 t1`.
    Edge01,
    /// A point inside the edge `t1 t2`.
    Edge12,
    /// A point inside the edge `t2 t0`.
    Edge20,
    /// A point inside the triangle: the distance to its plane.
    Face,
}

/// Which feature of the triangle `t0 t1 t2` is closest to `p` (see [`PointTriangleKind`]; a
/// degenerate triangle is its edges, see the [module docs](super)).
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::{PointTriangleKind, point_triangle_kind};
///
/// let (t0, t1, t2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
/// let kind = |x, y, z| point_triangle_kind(Vec3::new(x, y, z), t0, t1, t2);
/// assert_eq!(kind(0.2, 0.2, 1.0), PointTriangleKind::Face);
/// assert_eq!(kind(0.5, -1.0, 0.0), PointTriangleKind::Edge01);
/// assert_eq!(kind(-1.0, -1.0, 0.0), PointTriangleKind::Vertex0);
/// ```
#[must_use]
pub fn point_triangle_kind(p: Vec3, t0: Vec3, t1: Vec3, t2: Vec3) -> PointTriangleKind {
    closest(p, t0, t1, t2).0
}

/// The squared distance (m^2) between the point `p` and the triangle `t0 t1 t2`, without
/// derivatives: the cheap filter before [`point_triangle_distance`] (the same value, bit for
/// bit).
#[must_use]
pub fn point_triangle_squared_distance(p: Vec3, t0: Vec3, t1: Vec3, t2: Vec3) -> Real {
    closest(p, t0, t1, t2).1.squared
}

/// The squared distance between the point `p` and the triangle `t0 t1 t2`, with its gradient
/// and exact Hessian with respect to the slots `[p, t0, t1, t2]` (m; see the
/// [module docs](super) for the conventions and degenerate triangles).
///
/// The closest feature is found first ([`point_triangle_kind`]), then its formula evaluated:
/// the distance to a corner, to the line through an edge, or to the plane.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::point_triangle_distance;
///
/// // Half a metre above the interior of a right triangle in the plane z = 0.
/// let p = Vec3::new(0.2, 0.3, 0.5);
/// let distance = point_triangle_distance(p, Vec3::ZERO, Vec3::X, Vec3::Y);
/// assert!((distance.squared - 0.25).abs() < 1e-6);
/// // Moving the point up by dz changes d^2 by 2 d dz = dz.
/// assert!((distance.gradient[0] - Vec3::Z).length() < 1e-6);
/// // The corner t0 carries half the triangle's share (its barycentric weight 0.5).
/// assert!((distance.gradient[1] + 0.5 * Vec3::Z).length() < 1e-6);
/// ```
#[must_use]
pub fn point_triangle_distance(p: Vec3, t0: Vec3, t1: Vec3, t2: Vec3) -> PairDistance {
    closest(p, t0, t1, t2).1.derivatives()
}

/// The squared distance between the point `p` and the triangle `t0 t1 t2` with its gradient
/// alone (slots `[p, t0, t1, t2]`, m): the same bits as [`point_triangle_distance`]'s
/// `squared` and `gradient`, from one closest-feature search and without the Hessian, for an
/// energy and gradient evaluation.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::{
///     point_triangle_distance, point_triangle_distance_gradient,
/// };
///
/// let (p, t0, t1, t2) = (Vec3::new(0.2, 0.3, 0.5), Vec3::ZERO, Vec3::X, Vec3::Y);
/// let gradient = point_triangle_distance_gradient(p, t0, t1, t2);
/// let full = point_triangle_distance(p, t0, t1, t2);
/// assert_eq!((gradient.squared, gradient.gradient), (full.squared, full.gradient));
/// ```
#[must_use]
pub fn point_triangle_distance_gradient(
    p: Vec3,
    t0: Vec3,
    t1: Vec3,
    t2: Vec3,
) -> PairDistanceGradient {
    closest(p, t0, t1, t2).1.gradient()
}

/// The closest feature and its smooth case.
///
/// The squared distance is a convex quadratic over the triangle's barycentric parameters: if
/// the plane's closest point lies strictly inside, it is the answer; otherwise the minimum
/// lies on the boundary, the nearest of the three edges (each a point–edge distance).
fn closest(p: Vec3, t0: Vec3, t1: Vec3, t2: Vec3) -> (PointTriangleKind, Stationary) {
    if let Some(face) = point_plane(p, t0, t1, t2) {
        return (PointTriangleKind::Face, face);
    }
    let edges = [
        ([t0, t1], [0, 1, 2], PointTriangleKind::Edge01),
        ([t1, t2], [0, 2, 3], PointTriangleKind::Edge12),
        ([t2, t0], [0, 3, 1], PointTriangleKind::Edge20),
    ];
    let mut best: Option<(PointTriangleKind, Stationary)> = None;
    for ([e0, e1], at, edge_kind) in edges {
        let (feature, case) = point_edge(p, e0, e1, at);
        if best.is_none_or(|(_, held)| case.squared < held.squared) {
            best = Some((kind_of(edge_kind, feature), case));
        }
    }
    best.unwrap_or((
        PointTriangleKind::Vertex0,
        Stationary::point_point(p, t0, [0, 1]),
    ))
}

/// The triangle kind of an edge's feature.
fn kind_of(edge: PointTriangleKind, feature: EdgeFeature) -> PointTriangleKind {
    use PointTriangleKind::{Edge01, Edge12, Edge20, Vertex0, Vertex1, Vertex2};
    match (edge, feature) {
        (_, EdgeFeature::Interior) => edge,
        (Edge01, EdgeFeature::Start) | (Edge20, EdgeFeature::End) => Vertex0,
        (Edge01, EdgeFeature::End) | (Edge12, EdgeFeature::Start) => Vertex1,
        _ => Vertex2,
    }
}

/// The distance from `p` to the plane of `t0 t1 t2` when its closest point lies strictly
/// inside the triangle and the triangle is not degenerate; `None` otherwise.
///
/// `r = p - t0 - s1 e1 - s2 e2` with `e1 = t1 - t0`, `e2 = t2 - t0` and `(s1, s2)` solving the
/// 2x2 normal equations; `r = n (n . (p - t0)) / |n|^2` with `n = e1 x e2`, which is
/// perpendicular by construction.
fn point_plane(p: Vec3, t0: Vec3, t1: Vec3, t2: Vec3) -> Option<Stationary> {
    let e1 = t1 - t0;
    let e2 = t2 - t0;
    let from_t0 = p - t0;
    let normal = e1.cross(e2);
    let det = normal.dot(normal);
    let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    if negligible(det, g11 * g22) {
        return None;
    }
    let (b1, b2) = (e1.dot(from_t0), e2.dot(from_t0));
    let s1 = (g22 * b1 - g12 * b2) / det;
    let s2 = (g11 * b2 - g12 * b1) / det;
    if !(s1 > 0.0 && s2 > 0.0 && s1 + s2 < 1.0) {
        return None;
    }
    let height = normal.dot(from_t0);
    let residual = normal * (height / det);
    let slot = |weight: Real, rates: [Real; 2]| Slot { weight, rates };
    Some(Stationary {
        squared: height * height / det,
        residual,
        slots: placed(
            [
                slot(1.0, [0.0, 0.0]),
                slot(s1 + s2 - 1.0, [1.0, 1.0]),
                slot(-s1, [-1.0, 0.0]),
                slot(-s2, [0.0, -1.0]),
            ],
            [0, 1, 2, 3],
        ),
        directions: [-e1, -e2],
        gram_inverse: [[g22 / det, -g12 / det], [-g12 / det, g11 / det]],
    })
}

#[cfg(test)]
mod tests {
    use super::super::super::super::super::types::{Real, Vec3};
    use super::super::test_support::{
        XorShift, double, fd_settings, gradient_error, hessian_error, moved,
    };
    use super::{
        PointTriangleKind, point_triangle_distance, point_triangle_distance_gradient,
        point_triangle_kind, point_triangle_squared_distance,
    };

    /// Rounding of O(1) values: a few ulp of the largest input's square.
    const TIGHT: Real = 64.0 * Real::EPSILON;

    fn value(points: [Vec3; 4]) -> Real {
        let [p, t0, t1, t2] = points;
        point_triangle_squared_distance(p, t0, t1, t2)
    }

    fn kind(points: [Vec3; 4]) -> PointTriangleKind {
        let [p, t0, t1, t2] = points;
        point_triangle_kind(p, t0, t1, t2)
    }

    /// Points around the right triangle (0,0,0), (1,0,0), (0,1,0), one per kind, with the
    /// squared distance and the closest point worked out by hand.
    #[test]
    fn closed_forms_of_every_kind() {
        use PointTriangleKind::*;
        let (t0, t1, t2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let cases = [
            // Above the interior: the plane distance.
            (Vec3::new(0.2, 0.3, 0.5), Face, 0.25, Vec3::new(0.2, 0.3, 0.0)),
            (Vec3::new(0.2, 0.3, -0.5), Face, 0.25, Vec3::new(0.2, 0.3, 0.0)),
            // Beyond an edge: to the foot on the edge.
            (Vec3::new(0.5, -0.3, 0.4), Edge01, 0.25, Vec3::new(0.5, 0.0, 0.0)),
            (Vec3::new(1.0, 1.0, 0.0), Edge12, 0.5, Vec3::new(0.5, 0.5, 0.0)),
            (Vec3::new(-0.6, 0.25, 0.8), Edge20, 1.0, Vec3::new(0.0, 0.25, 0.0)),
            // Beyond a corner.
            (Vec3::new(-0.3, -0.4, 1.2), Vertex0, 1.69, t0),
            (Vec3::new(2.0, -0.5, 0.0), Vertex1, 1.25, t1),
            (Vec3::new(-0.5, 2.0, 1.0), Vertex2, 2.25, t2),
        ];
        for (p, expected_kind, squared, foot) in cases {
            assert_eq!(point_triangle_kind(p, t0, t1, t2), expected_kind, "{p}");
            let distance = point_triangle_distance(p, t0, t1, t2);
            assert!((distance.squared - squared).abs() < TIGHT, "{p}: {}", distance.squared);
            // The point's gradient is 2 (p - closest point).
            assert!((distance.gradient[0] - 2.0 * (p - foot)).length() < TIGHT, "{p}");
        }
        // Above the interior the point's Hessian is 2 n n^T and the corners take the gradient
        // by their barycentric weights (0.5, 0.2, 0.3 at (0.2, 0.3)).
        let distance = point_triangle_distance(Vec3::new(0.2, 0.3, 0.5), t0, t1, t2);
        let expected_pp = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 2.0]];
        for (i, row) in expected_pp.iter().enumerate() {
            for (j, &entry) in row.iter().enumerate() {
                assert!((distance.hessian[0][0].col(j)[i] - entry).abs() < TIGHT);
            }
        }
        for (corner, weight) in [(1, 0.5), (2, 0.2), (3, 0.3)] {
            assert!((distance.gradient[corner] + Vec3::Z * weight).length() < TIGHT);
        }
    }

    /// Gradients and Hessians against central differences of the value, at random
    /// configurations of every kind, away from the kind boundaries (the stencil never crosses
    /// one) and from contact (`d >= 0.2`).
    #[test]
    fn derivatives_match_finite_differences_for_every_kind() {
        let (gradient_step, gradient_tolerance, hessian_step, hessian_tolerance) = fd_settings();
        let mut random = XorShift::new(0x5eed_0001);
        let mut seen = [0usize; 7];
        let mut tries = 0;
        while seen.iter().any(|&count| count < 4) {
            tries += 1;
            assert!(tries < 20_000, "kinds seen: {seen:?}");
            let points = random.points(2.0);
            let [_, t0, t1, t2] = points;
            let (e1, e2) = (t1 - t0, t2 - t0);
            if e1.cross(e2).length_squared() < 0.1 * e1.length_squared() * e2.length_squared()
                || value(points) < 0.04
            {
                continue;
            }
            let center = kind(points);
            let margin = 3.0 * hessian_step;
            let stable = (0..4).all(|k| {
                (0..3).all(|i| {
                    kind(moved(points, k, i, margin)) == center
                        && kind(moved(points, k, i, -margin)) == center
                })
            });
            if !stable {
                continue;
            }
            seen[center as usize] += 1;
            let distance = point_triangle_distance(points[0], t0, t1, t2);
            let gradient = gradient_error(value, points, distance.gradient, gradient_step);
            assert!(gradient < gradient_tolerance, "{center:?} {points:?}: {gradient}");
            let hessian = hessian_error(value, points, distance.hessian, hessian_step);
            assert!(hessian < hessian_tolerance, "{center:?} {points:?}: {hessian}");
        }
    }

    /// The distance does not change under a rigid motion of all four points; the gradients
    /// rotate with it, sum to zero, and every block row of the Hessian sums to zero.
    #[test]
    fn rigid_motions_and_translation_identities() {
        let mut random = XorShift::new(0x5eed_0002);
        for _ in 0..200 {
            let points = random.points(2.0);
            let rotation = random.rotation();
            let shift = random.point(3.0);
            let [p, t0, t1, t2] = points.map(|x| rotation * x + shift);
            let moved_distance = point_triangle_distance(p, t0, t1, t2);
            let distance = point_triangle_distance(points[0], points[1], points[2], points[3]);
            // Rounding of coordinates up to ~5 m: the squared distance errs by eps |x|^2.
            let tolerance = 256.0 * Real::EPSILON;
            assert!((moved_distance.squared - distance.squared).abs() < tolerance * 25.0);
            for (moved_gradient, gradient) in moved_distance.gradient.iter().zip(distance.gradient)
            {
                assert!((*moved_gradient - rotation * gradient).length() < tolerance * 50.0);
            }
            let sum: Vec3 = distance.gradient.iter().sum();
            assert!(sum.length() < tolerance * 10.0, "{sum}");
            for row in distance.hessian {
                let row_sum = row[0] + row[1] + row[2] + row[3];
                let largest = row
                    .iter()
                    .flat_map(|block| block.to_cols_array())
                    .fold(1.0, |m: Real, e| m.max(e.abs()));
                let bound = tolerance * 10.0 * largest;
                assert!(row_sum.to_cols_array().iter().all(|e| e.abs() < bound));
            }
        }
    }

    /// Along paths that cross every kind boundary, the value changes by no more than its
    /// Lipschitz bound `|grad d^2| |step| = 2 d |step|` between close samples.
    #[test]
    fn value_is_continuous_across_kinds() {
        let t0 = Vec3::new(0.1, -0.2, 0.05);
        let t1 = Vec3::new(1.3, 0.1, -0.2);
        let t2 = Vec3::new(0.2, 1.1, 0.3);
        let center = (t0 + t1 + t2) / 3.0;
        let normal = (t1 - t0).cross(t2 - t0).normalize();
        let mut visited = [false; 7];
        let samples = 20_000;
        let (across, along) = ((t1 - t0).normalize(), normal.cross((t1 - t0).normalize()));
        for height in [0.0, 0.05, 0.3] {
            let mut previous: Option<(Vec3, Real)> = None;
            for step in 0..=samples {
                // A spiral about the centroid, three turns out to radius 2: through the face,
                // then past every edge and corner.
                let fraction = step as Real / samples as Real;
                let angle = fraction * 3.0 * core::f64::consts::TAU as Real;
                let radius = 0.1 + 1.9 * fraction;
                let radial = across * angle.cos() + along * angle.sin();
                let p = center + radial * radius + normal * height;
                let d2 = point_triangle_squared_distance(p, t0, t1, t2);
                visited[point_triangle_kind(p, t0, t1, t2) as usize] = true;
                if let Some((q, previous_d2)) = previous {
                    let step = (p - q).length();
                    let bound = 2.0 * d2.max(previous_d2).sqrt() * step + step * step;
                    assert!((d2 - previous_d2).abs() <= bound * 1.01 + 64.0 * Real::EPSILON, "{p}");
                }
                previous = Some((p, d2));
            }
        }
        assert!(visited.iter().all(|&v| v), "{visited:?}");
    }

    /// A degenerate triangle is its edges: no NaN, and the distance is the nearest edge's.
    #[test]
    fn degenerate_triangles_fall_back_to_edges() {
        let p = Vec3::new(0.5, 0.7, 0.0);
        let collinear = [Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)];
        let zero_edge = [Vec3::ZERO, Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0)];
        let single_point = [Vec3::X, Vec3::X, Vec3::X];
        let cases = [(collinear, 0.49), (zero_edge, 0.49), (single_point, 0.74)];
        for ([t0, t1, t2], squared) in cases {
            let distance = point_triangle_distance(p, t0, t1, t2);
            assert!((distance.squared - squared).abs() < TIGHT, "{:?}", distance.squared);
            assert!(distance.gradient.iter().all(|g| g.is_finite()));
            assert!(distance.hessian.iter().flatten().all(|h| h.is_finite()));
            assert_ne!(point_triangle_kind(p, t0, t1, t2), PointTriangleKind::Face);
        }
        // The point on the degenerate triangle: zero distance, finite derivatives.
        let [t0, t1, t2] = collinear;
        let distance = point_triangle_distance(Vec3::new(1.5, 0.0, 0.0), t0, t1, t2);
        assert_eq!(distance.squared, 0.0);
        assert!(distance.hessian.iter().flatten().all(|h| h.is_finite()));
    }

    /// The value-only and gradient-only functions are the full one's value and gradient, bit
    /// for bit, for every kind (counted: each is reached).
    #[test]
    fn value_only_matches() {
        let mut random = XorShift::new(0x5eed_0003);
        let mut seen = [0usize; 7];
        for _ in 0..500 {
            let [p, t0, t1, t2] = random.points(2.0);
            let full = point_triangle_distance(p, t0, t1, t2);
            assert_eq!(
                point_triangle_squared_distance(p, t0, t1, t2).to_bits(),
                full.squared.to_bits()
            );
            let gradient = point_triangle_distance_gradient(p, t0, t1, t2);
            assert_eq!(gradient.squared.to_bits(), full.squared.to_bits());
            let bits = |g: [Vec3; 4]| g.map(|v| v.to_array().map(Real::to_bits));
            assert_eq!(bits(gradient.gradient), bits(full.gradient));
            seen[point_triangle_kind(p, t0, t1, t2) as usize] += 1;
        }
        assert!(seen.iter().all(|&count| count > 0), "{seen:?}");
        let _ = double;
    }
}

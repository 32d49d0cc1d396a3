//! The squared distance between two edges, and the mollifier that fades the edge–edge barrier
//! out as the edges turn parallel (`docs/math.md` sections 8.4 and 8.5).

use super::super::super::super::types::{Mat3, Real, Vec3};
use super::point_edge::{EdgeFeature, point_edge};
use super::{PairDistance, PairDistanceGradient, Slot, Stationary, negligible, outer, placed};

/// Which features of two edges `ea0 ea1` and `eb0 eb1` are closest, and so which smooth
/// formula gives their distance: line–line when both closest points lie inside the edges,
/// point–line when one is an end, point–point when both are.
///
/// Ties go to the first in the order `Interior`, `A0ToB`, `A1ToB`, `B0ToA`, `B1ToA` (and an
/// end–end tie to the first of those that reaches it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EdgeEdgeKind {
    /// Inside both edges: the distance between the two lines.
    Interior,
    /// The end `ea0` and a point inside edge b.
    A0ToB,
    /// The end `ea1` and a point inside edge b.
    A1ToB,
    /// The end `eb0` and a point inside edge a.
    B0ToA,
    /// The end `eb1` and a point inside edge a.
    B1ToA,
    /// The ends `ea0` and `eb0`.
    A0B0,
    /// The ends `ea0` and `eb1`.
    A0B1,
    /// The ends `ea1` and `eb0`.
    A1B0,
    /// The ends `ea1` and `eb1`.
    A1B1,
}

/// Which features of the edges `ea0 ea1` and `eb0 eb1` are closest (see [`EdgeEdgeKind`];
/// parallel edges take an end, see the [module docs](super)).
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::{EdgeEdgeKind, edge_edge_kind};
///
/// // Two crossing edges, one above the other.
/// let (ea0, ea1) = (Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0));
/// let (eb0, eb1) = (Vec3::new(0.0, -1.0, 0.5), Vec3::new(0.0, 1.0, 0.5));
/// assert_eq!(edge_edge_kind(ea0, ea1, eb0, eb1), EdgeEdgeKind::Interior);
/// ```
#[must_use]
pub fn edge_edge_kind(ea0: Vec3, ea1: Vec3, eb0: Vec3, eb1: Vec3) -> EdgeEdgeKind {
    closest(ea0, ea1, eb0, eb1).0
}

/// The squared distance (m^2) between the edges `ea0 ea1` and `eb0 eb1`, without derivatives:
/// the cheap filter before [`edge_edge_distance`] (the same value, bit for bit).
#[must_use]
pub fn edge_edge_squared_distance(ea0: Vec3, ea1: Vec3, eb0: Vec3, eb1: Vec3) -> Real {
    closest(ea0, ea1, eb0, eb1).1.squared
}

/// The squared distance between the edges `ea0 ea1` and `eb0 eb1`, with its gradient and exact
/// Hessian with respect to the slots `[ea0, ea1, eb0, eb1]` (m; see the [module docs](super)
/// for the conventions and for parallel edges).
///
/// The closest features are found first ([`edge_edge_kind`]), then their formula evaluated.
/// Near-parallel edges make the line–line Hessian large (of order `1 / sin^2` of their angle):
/// IPC multiplies the edge–edge barrier by [`edge_edge_mollifier`], which vanishes there.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::edge_edge_distance;
///
/// // Skew edges: along x at z = 0 and along y at z = 2.
/// let distance = edge_edge_distance(
///     Vec3::new(-1.0, 0.0, 0.0),
///     Vec3::new(1.0, 0.0, 0.0),
///     Vec3::new(0.0, -1.0, 2.0),
///     Vec3::new(0.0, 1.0, 2.0),
/// );
/// assert!((distance.squared - 4.0).abs() < 1e-5);
/// // Lifting edge b raises d^2 at 2 d = 4 per metre, shared by its two ends.
/// assert!((distance.gradient[2] - Vec3::new(0.0, 0.0, 2.0)).length() < 1e-5);
/// ```
#[must_use]
pub fn edge_edge_distance(ea0: Vec3, ea1: Vec3, eb0: Vec3, eb1: Vec3) -> PairDistance {
    closest(ea0, ea1, eb0, eb1).1.derivatives()
}

/// The squared distance between the edges `ea0 ea1` and `eb0 eb1` with its gradient alone
/// (slots `[ea0, ea1, eb0, eb1]`, m): the same bits as [`edge_edge_distance`]'s `squared` and
/// `gradient`, from one closest-feature search and without the Hessian, for an energy and
/// gradient evaluation.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::{edge_edge_distance, edge_edge_distance_gradient};
///
/// let (ea0, ea1) = (Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0));
/// let (eb0, eb1) = (Vec3::new(0.0, -1.0, 2.0), Vec3::new(0.0, 1.0, 2.0));
/// let gradient = edge_edge_distance_gradient(ea0, ea1, eb0, eb1);
/// let full = edge_edge_distance(ea0, ea1, eb0, eb1);
/// assert_eq!((gradient.squared, gradient.gradient), (full.squared, full.gradient));
/// ```
#[must_use]
pub fn edge_edge_distance_gradient(
    ea0: Vec3,
    ea1: Vec3,
    eb0: Vec3,
    eb1: Vec3,
) -> PairDistanceGradient {
    closest(ea0, ea1, eb0, eb1).1.gradient()
}

/// The closest features and their smooth case.
///
/// The squared distance is a convex quadratic over the two edge parameters: if the lines'
/// closest points lie strictly inside both edges, that is the answer; otherwise the minimum
/// lies on the boundary of the parameter square, the nearest of the four end–edge distances.
fn closest(ea0: Vec3, ea1: Vec3, eb0: Vec3, eb1: Vec3) -> (EdgeEdgeKind, Stationary) {
    if let Some(lines) = line_line(ea0, ea1, eb0, eb1) {
        return (EdgeEdgeKind::Interior, lines);
    }
    use EdgeEdgeKind::{A0B0, A0B1, A0ToB, A1B0, A1B1, A1ToB, B0ToA, B1ToA};
    // Each end against the other edge: (point, edge, slots, kinds at the edge's start, end,
    // interior).
    let ends = [
        (ea0, [eb0, eb1], [0, 2, 3], [A0B0, A0B1, A0ToB]),
        (ea1, [eb0, eb1], [1, 2, 3], [A1B0, A1B1, A1ToB]),
        (eb0, [ea0, ea1], [2, 0, 1], [A0B0, A1B0, B0ToA]),
        (eb1, [ea0, ea1], [3, 0, 1], [A0B1, A1B1, B1ToA]),
    ];
    let mut best: Option<(EdgeEdgeKind, Stationary)> = None;
    for (point, [e0, e1], at, [at_start, at_end, inside]) in ends {
        let (feature, case) = point_edge(point, e0, e1, at);
        if best.is_none_or(|(_, held)| case.squared < held.squared) {
            let kind = match feature {
                EdgeFeature::Start => at_start,
                EdgeFeature::End => at_end,
                EdgeFeature::Interior => inside,
            };
            best = Some((kind, case));
        }
    }
    best.unwrap_or((A0B0, Stationary::point_point(ea0, eb0, [0, 2])))
}

/// The distance between the lines through the edges when their closest points lie strictly
/// inside both edges and the edges are not parallel; `None` otherwise.
///
/// `r = w + s u - t v` with `u = ea1 - ea0`, `v = eb1 - eb0`, `w = ea0 - eb0` and `(s, t)`
/// solving the 2x2 normal equations; `r = n (n . w) / |n|^2` with `n = u x v`.
fn line_line(ea0: Vec3, ea1: Vec3, eb0: Vec3, eb1: Vec3) -> Option<Stationary> {
    let u = ea1 - ea0;
    let v = eb1 - eb0;
    let w = ea0 - eb0;
    let normal = u.cross(v);
    let det = normal.dot(normal);
    let (a, b, c) = (u.dot(u), u.dot(v), v.dot(v));
    if negligible(det, a * c) {
        return None;
    }
    let (d, e) = (u.dot(w), v.dot(w));
    let s = (b * e - c * d) / det;
    let t = (a * e - b * d) / det;
    if !(s > 0.0 && s < 1.0 && t > 0.0 && t < 1.0) {
        return None;
    }
    let height = normal.dot(w);
    let slot = |weight: Real, rates: [Real; 2]| Slot { weight, rates };
    Some(Stationary {
        squared: height * height / det,
        residual: normal * (height / det),
        slots: placed(
            [
                slot(1.0 - s, [-1.0, 0.0]),
                slot(s, [1.0, 0.0]),
                slot(t - 1.0, [0.0, 1.0]),
                slot(-t, [0.0, -1.0]),
            ],
            [0, 1, 2, 3],
        ),
        directions: [u, -v],
        gram_inverse: [[c / det, b / det], [b / det, a / det]],
    })
}

/// How much of the edge–edge barrier is kept (dimensionless, in `[0, 1]`), with its gradient
/// and Hessian with respect to `[ea0, ea1, eb0, eb1]` (see [`edge_edge_mollifier`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mollifier {
    /// `m(c)`: 0 for parallel edges, 1 from the threshold on.
    pub value: Real,
    /// `dm/dx_k` (1/m).
    pub gradient: [Vec3; 4],
    /// `d^2 m / (dx_k dx_l)` (1/m^2), blocks as in [`PairDistance::hessian`].
    pub hessian: [[Mat3; 4]; 4],
}

/// The mollifier's threshold `eps_x = 1e-3 |ea0 - ea1|^2 |eb0 - eb1|^2` (m^4) from the edges'
/// rest positions (Li et al. 2020, supplementary): where `c = |(ea1 - ea0) x (eb1 - eb0)|^2`
/// falls below it (the edges within about 1.8 degrees of parallel at their rest lengths) the
/// mollifier fades the barrier out.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::edge_edge_mollifier_threshold;
///
/// // Rest lengths 2 m and 3 m: 1e-3 * 4 * 9.
/// let (ea0, ea1) = (Vec3::ZERO, 2.0 * Vec3::X);
/// let (eb0, eb1) = (Vec3::Y, Vec3::new(0.0, 4.0, 0.0));
/// let eps_x = edge_edge_mollifier_threshold(ea0, ea1, eb0, eb1);
/// assert!((eps_x - 0.036).abs() < 1e-8);
/// ```
#[must_use]
pub fn edge_edge_mollifier_threshold(
    ea0_rest: Vec3,
    ea1_rest: Vec3,
    eb0_rest: Vec3,
    eb1_rest: Vec3,
) -> Real {
    let a = ea0_rest - ea1_rest;
    let b = eb0_rest - eb1_rest;
    1e-3 * a.dot(a) * b.dot(b)
}

/// The mollifier's value alone (dimensionless; the same bits as [`edge_edge_mollifier`]'s).
#[must_use]
pub fn edge_edge_mollifier_value(
    ea0: Vec3,
    ea1: Vec3,
    eb0: Vec3,
    eb1: Vec3,
    threshold: Real,
) -> Real {
    let normal = (ea1 - ea0).cross(eb1 - eb0);
    let c = normal.dot(normal);
    if c < threshold {
        let ratio = c / threshold;
        (2.0 - ratio) * ratio
    } else {
        1.0
    }
}

/// The edge–edge mollifier of Li et al. 2020 (section 4.3 and supplementary), with its gradient
/// and Hessian: with `c = |(ea1 - ea0) x (eb1 - eb0)|^2` (m^4) and `threshold` the `eps_x` of
/// [`edge_edge_mollifier_threshold`],
/// `m = -c^2 / eps_x^2 + 2 c / eps_x` for `c < eps_x`, else 1.
///
/// The edge–edge barrier is `m b(d^2)`: it fades out as the edges turn parallel, where the
/// line–line distance is ill-conditioned and the point–triangle and end–edge pairs hold the
/// contact instead. `m` is C1 at `eps_x` (value 1, slope 0), not C2. A threshold `<= 0` (or
/// NaN) gives 1 everywhere.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::edge_edge_mollifier;
///
/// // Parallel edges: no edge–edge barrier at all.
/// let (ea0, ea1) = (Vec3::ZERO, Vec3::X);
/// let (eb0, eb1) = (Vec3::new(0.0, 0.1, 0.0), Vec3::new(1.0, 0.1, 0.0));
/// assert_eq!(edge_edge_mollifier(ea0, ea1, eb0, eb1, 1e-3).value, 0.0);
/// // Crossing at right angles: all of it.
/// let (eb0, eb1) = (Vec3::new(0.5, -0.5, 0.1), Vec3::new(0.5, 0.5, 0.1));
/// assert_eq!(edge_edge_mollifier(ea0, ea1, eb0, eb1, 1e-3).value, 1.0);
/// ```
#[must_use]
pub fn edge_edge_mollifier(
    ea0: Vec3,
    ea1: Vec3,
    eb0: Vec3,
    eb1: Vec3,
    threshold: Real,
) -> Mollifier {
    let Some(fade) = Fade::new(ea0, ea1, eb0, eb1, threshold) else {
        return Mollifier {
            value: 1.0,
            gradient: [Vec3::ZERO; 4],
            hessian: [[Mat3::ZERO; 4]; 4],
        };
    };
    let Fade {
        u,
        v,
        uu,
        uv,
        vv,
        value,
        slope,
        gradient_c,
    } = fade;
    // m''(c) = -2 / eps_x^2.
    let curvature = -2.0 / (threshold * threshold);
    // The second derivatives of c = |u|^2 |v|^2 - (u.v)^2 (docs/math.md section 8.5).
    let identity = Mat3::IDENTITY;
    let hess_uu = (identity * vv - outer(v, v)) * 2.0;
    let hess_vv = (identity * uu - outer(u, u)) * 2.0;
    let hess_uv = outer(u, v) * 4.0 - outer(v, u) * 2.0 - identity * (2.0 * uv);
    let blocks_c = [
        [hess_uu, hess_uv],
        [hess_uv.transpose(), hess_vv],
    ];
    // The points enter as u = ea1 - ea0, v = eb1 - eb0: slot signs (-, +, -, +).
    let side = [(0, -1.0), (0, 1.0), (1, -1.0), (1, 1.0)];
    let rows = side.map(|(edge_k, sign_k): (usize, Real)| {
        side.map(|(edge_l, sign_l): (usize, Real)| {
            let block = blocks_c
                .get(edge_k)
                .and_then(|row| row.get(edge_l))
                .copied()
                .unwrap_or(Mat3::ZERO);
            block * (sign_k * sign_l * slope)
        })
    });
    let mut hessian = rows;
    for (row, g_k) in hessian.iter_mut().zip(gradient_c) {
        for (block, g_l) in row.iter_mut().zip(gradient_c) {
            *block += outer(g_k, g_l) * curvature;
        }
    }
    Mollifier {
        value,
        gradient: gradient_c.map(|g| g * slope),
        hessian,
    }
}

/// The edge–edge mollifier's value and gradient alone (see [`edge_edge_mollifier`], of which
/// these are the first two fields, the same bits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MollifierGradient {
    /// `m(c)`: 0 for parallel edges, 1 from the threshold on.
    pub value: Real,
    /// `dm/dx_k` (1/m).
    pub gradient: [Vec3; 4],
}

/// The edge–edge mollifier's value and gradient without its Hessian, the same bits as
/// [`edge_edge_mollifier`]'s (see there for the arguments): for an energy and gradient
/// evaluation.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::distance::{edge_edge_mollifier, edge_edge_mollifier_gradient};
///
/// // Edges 0.05 rad from parallel: c = sin^2(0.05) ~ 2.5e-3 below the threshold 1e-2.
/// let (ea0, ea1) = (Vec3::ZERO, Vec3::X);
/// let (eb0, eb1) = (Vec3::new(0.0, 0.0, 0.1), Vec3::new(1.0, 0.05, 0.1));
/// let gradient = edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, 1e-2);
/// let full = edge_edge_mollifier(ea0, ea1, eb0, eb1, 1e-2);
/// assert!(gradient.value > 0.0 && gradient.value < 1.0);
/// assert_eq!((gradient.value, gradient.gradient), (full.value, full.gradient));
/// ```
#[must_use]
pub fn edge_edge_mollifier_gradient(
    ea0: Vec3,
    ea1: Vec3,
    eb0: Vec3,
    eb1: Vec3,
    threshold: Real,
) -> MollifierGradient {
    match Fade::new(ea0, ea1, eb0, eb1, threshold) {
        Some(fade) => MollifierGradient {
            value: fade.value,
            gradient: fade.gradient_c.map(|g| g * fade.slope),
        },
        None => MollifierGradient {
            value: 1.0,
            gradient: [Vec3::ZERO; 4],
        },
    }
}

/// What the mollifier's value, gradient and Hessian share below the threshold.
#[derive(Clone, Copy, Debug)]
struct Fade {
    /// `u = ea1 - ea0` (m).
    u: Vec3,
    /// `v = eb1 - eb0` (m).
    v: Vec3,
    /// `u . u` (m^2).
    uu: Real,
    /// `u . v` (m^2).
    uv: Real,
    /// `v . v` (m^2).
    vv: Real,
    /// `m(c)`.
    value: Real,
    /// `m'(c) = 2 (eps_x - c) / eps_x^2` (1/m^4).
    slope: Real,
    /// `dc/dx_k` (m^3).
    gradient_c: [Vec3; 4],
}

impl Fade {
    /// The shared terms where `c < threshold` (the mollifier fading); `None` where it is 1.
    fn new(ea0: Vec3, ea1: Vec3, eb0: Vec3, eb1: Vec3, threshold: Real) -> Option<Fade> {
        let u = ea1 - ea0;
        let v = eb1 - eb0;
        let normal = u.cross(v);
        let c = normal.dot(normal);
        let fading = c < threshold;
        if !fading {
            return None;
        }
        let ratio = c / threshold;
        let value = (2.0 - ratio) * ratio;
        let slope = 2.0 * (1.0 - ratio) / threshold;
        // c = |u|^2 |v|^2 - (u.v)^2: its gradient in u and v (docs/math.md section 8.5).
        let (uu, uv, vv) = (u.dot(u), u.dot(v), v.dot(v));
        let grad_u = (u * vv - v * uv) * 2.0;
        let grad_v = (v * uu - u * uv) * 2.0;
        // The points enter as u = ea1 - ea0, v = eb1 - eb0: slot signs (-, +, -, +).
        Some(Fade {
            u,
            v,
            uu,
            uv,
            vv,
            value,
            slope,
            gradient_c: [-grad_u, grad_u, -grad_v, grad_v],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::super::super::types::{Real, Vec3};
    use super::super::test_support::{
        XorShift, fd_settings, gradient_error, hessian_error, moved,
    };
    use super::{
        EdgeEdgeKind, edge_edge_distance, edge_edge_distance_gradient, edge_edge_kind,
        edge_edge_mollifier, edge_edge_mollifier_gradient, edge_edge_mollifier_threshold,
        edge_edge_mollifier_value, edge_edge_squared_distance,
    };

    /// Rounding of O(1) values: a few ulp of the largest input's square.
    const TIGHT: Real = 64.0 * Real::EPSILON;

    fn value(points: [Vec3; 4]) -> Real {
        let [ea0, ea1, eb0, eb1] = points;
        edge_edge_squared_distance(ea0, ea1, eb0, eb1)
    }

    fn kind(points: [Vec3; 4]) -> EdgeEdgeKind {
        let [ea0, ea1, eb0, eb1] = points;
        edge_edge_kind(ea0, ea1, eb0, eb1)
    }

    fn distance(points: [Vec3; 4]) -> super::PairDistance {
        let [ea0, ea1, eb0, eb1] = points;
        edge_edge_distance(ea0, ea1, eb0, eb1)
    }

    /// Configurations worked out by hand: crossing, skew, end-to-edge, end-to-end, parallel.
    #[test]
    fn closed_forms_of_every_kind() {
        use EdgeEdgeKind::*;
        let v = |x: Real, y: Real, z: Real| Vec3::new(x, y, z);
        let a = [v(-1.0, 0.0, 0.0), v(1.0, 0.0, 0.0)];
        let cases = [
            // Crossing above: the lines' distance.
            ([a[0], a[1], v(0.0, -1.0, 0.3), v(0.0, 1.0, 0.3)], Interior, 0.09),
            // Skew, not at right angles: b along (1, 1, 0) at z = 2 through (0.5, 0, 2).
            ([a[0], a[1], v(-0.5, -1.0, 2.0), v(1.5, 1.0, 2.0)], Interior, 4.0),
            // Edge b ends short of a (in y): its end eb0 = (0.2, 0.5, 0.5) to a's interior.
            ([a[0], a[1], v(0.2, 0.5, 0.5), v(0.2, 2.0, 0.5)], B0ToA, 0.5),
            ([a[0], a[1], v(0.2, 2.0, 0.5), v(0.2, 0.5, 0.5)], B1ToA, 0.5),
            // Edge a ends short of b: b along y at x = 2; ends ea1 = (1, 0, 0) to (2, 0, 0.5).
            ([a[0], a[1], v(2.0, -1.0, 0.5), v(2.0, 1.0, 0.5)], A1ToB, 1.25),
            ([a[1], a[0], v(2.0, -1.0, 0.5), v(2.0, 1.0, 0.5)], A0ToB, 1.25),
            // End to end: b beyond a's end ea1, pointing away.
            ([a[0], a[1], v(2.0, 1.0, 0.0), v(3.0, 3.0, 0.0)], A1B0, 2.0),
            ([a[0], a[1], v(3.0, 3.0, 0.0), v(2.0, 1.0, 0.0)], A1B1, 2.0),
            ([a[1], a[0], v(3.0, 3.0, 0.0), v(2.0, 1.0, 0.0)], A0B1, 2.0),
            ([a[1], a[0], v(2.0, 1.0, 0.0), v(3.0, 3.0, 0.0)], A0B0, 2.0),
            // Parallel, not overlapping: the ends ea1 and eb0, at (1, 0, 0) and (2, 1, 0).
            ([a[0], a[1], v(2.0, 1.0, 0.0), v(3.0, 1.0, 0.0)], A1B0, 2.0),
        ];
        for (points, expected_kind, squared) in cases {
            assert_eq!(kind(points), expected_kind, "{points:?}");
            let result = distance(points);
            assert!((result.squared - squared).abs() < TIGHT, "{points:?}: {}", result.squared);
        }
        // Parallel and overlapping: every pair of overlapping points is 1 m apart; an end to
        // the other edge's interior.
        let parallel = [a[0], a[1], v(0.5, 1.0, 0.0), v(2.0, 1.0, 0.0)];
        assert!(matches!(kind(parallel), A1ToB | B0ToA));
        let result = distance(parallel);
        assert!((result.squared - 1.0).abs() < TIGHT);
        assert!(result.gradient.iter().all(|g| g.is_finite()));
        assert!(result.hessian.iter().flatten().all(|h| h.is_finite()));
        // The crossing pair's gradients: d^2 = 0.09 rises at 2 d = 0.6 per metre of lift of
        // b, split evenly between its ends (crossing at both edges' midpoints).
        let result = distance(cases[0].0);
        assert!((result.gradient[2] - v(0.0, 0.0, 0.3)).length() < TIGHT);
        assert!((result.gradient[0] + v(0.0, 0.0, 0.3)).length() < TIGHT);
    }

    /// Gradients and Hessians against central differences of the value, at random
    /// configurations of every kind, away from the kind boundaries and from contact.
    #[test]
    fn derivatives_match_finite_differences_for_every_kind() {
        let (gradient_step, gradient_tolerance, hessian_step, hessian_tolerance) = fd_settings();
        let mut random = XorShift::new(0x5eed_0011);
        let mut seen = [0usize; 9];
        let mut tries = 0;
        while seen.iter().any(|&count| count < 4) {
            tries += 1;
            assert!(tries < 50_000, "kinds seen: {seen:?}");
            let points = random.points(1.0);
            let (u, v) = (points[1] - points[0], points[3] - points[2]);
            if u.cross(v).length_squared() < 0.1 * u.length_squared() * v.length_squared()
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
            let result = distance(points);
            let gradient = gradient_error(value, points, result.gradient, gradient_step);
            assert!(gradient < gradient_tolerance, "{center:?} {points:?}: {gradient}");
            let hessian = hessian_error(value, points, result.hessian, hessian_step);
            assert!(hessian < hessian_tolerance, "{center:?} {points:?}: {hessian}");
        }
    }

    /// Invariance under rigid motions, swapping the edges, and reversing either edge; the
    /// gradients sum to zero and every block row of the Hessian sums to zero.
    #[test]
    fn rigid_motions_swaps_and_translation_identities() {
        let mut random = XorShift::new(0x5eed_0012);
        // Rounding of coordinates up to ~5 m: the squared distance errs by eps |x|^2.
        let tolerance = 256.0 * Real::EPSILON * 25.0;
        for _ in 0..300 {
            let points = random.points(1.0);
            let [ea0, ea1, eb0, eb1] = points;
            let reference = distance(points);
            let rotation = random.rotation();
            let shift = random.point(3.0);
            let moved_points = points.map(|x| rotation * x + shift);
            let moved_result = distance(moved_points);
            assert!((moved_result.squared - reference.squared).abs() < tolerance);
            for (g_moved, g) in moved_result.gradient.iter().zip(reference.gradient) {
                assert!((*g_moved - rotation * g).length() < tolerance);
            }
            for reordered in [[eb0, eb1, ea0, ea1], [ea1, ea0, eb0, eb1], [ea0, ea1, eb1, eb0]] {
                assert!((value(reordered) - reference.squared).abs() < TIGHT, "{points:?}");
            }
            let swapped = distance([eb0, eb1, ea0, ea1]);
            assert!((swapped.gradient[0] - reference.gradient[2]).length() < tolerance);
            let sum: Vec3 = reference.gradient.iter().sum();
            assert!(sum.length() < tolerance, "{sum}");
            for row in reference.hessian {
                let row_sum = row[0] + row[1] + row[2] + row[3];
                let largest = row
                    .iter()
                    .flat_map(|block| block.to_cols_array())
                    .fold(1.0, |m: Real, e| m.max(e.abs()));
                assert!(row_sum.to_cols_array().iter().all(|e| e.abs() < tolerance * largest));
            }
        }
    }

    /// Edge b sweeps past edge a in several directions; the value changes by no more than its
    /// Lipschitz bound between close samples, and every kind is visited.
    #[test]
    fn value_is_continuous_across_kinds() {
        let (ea0, ea1) = (Vec3::new(-1.0, 0.1, 0.0), Vec3::new(1.0, -0.1, 0.05));
        let mut visited = [false; 9];
        let samples = 20_000;
        let sweeps = [
            (Vec3::new(0.3, 1.0, 0.0), 0.2),
            (Vec3::new(1.0, 0.2, 0.1), 0.0),
            (Vec3::new(-1.0, 0.7, 0.2), 0.5),
        ];
        for (direction, height) in sweeps {
            let mut previous: Option<([Vec3; 4], Real)> = None;
            for step in 0..=samples {
                // Edge b turns about a moving centre along a spiral: its ends pass a's ends
                // and interior from every side.
                let fraction = step as Real / samples as Real;
                let angle = fraction * 4.0 * core::f64::consts::TAU as Real;
                let centre = Vec3::new(2.6 * (fraction - 0.5) * 2.0, 0.4 * angle.sin(), height);
                let half = direction.normalize() * 0.6;
                let (sin, cos) = (angle.sin(), angle.cos());
                let (x, y) = (cos * half.x - sin * half.y, sin * half.x + cos * half.y);
                let turn = Vec3::new(x, y, half.z);
                let points = [ea0, ea1, centre - turn, centre + turn + Vec3::new(0.0, 0.0, 0.1)];
                let d2 = value(points);
                visited[kind(points) as usize] = true;
                if let Some((before, previous_d2)) = previous {
                    // Each closest point moves at most `moved_by`, their difference twice that.
                    let moved_by = points
                        .iter()
                        .zip(before)
                        .map(|(x, y)| (*x - y).length())
                        .fold(0.0, Real::max);
                    let change = 2.0 * moved_by;
                    let bound = 2.0 * d2.max(previous_d2).sqrt() * change + change * change;
                    let tolerance = 64.0 * Real::EPSILON;
                    assert!((d2 - previous_d2).abs() <= bound * 1.01 + tolerance, "{points:?}");
                }
                previous = Some((points, d2));
            }
        }
        assert!(visited.iter().all(|&v| v), "{visited:?}");
    }

    /// Zero-length and parallel edges give finite results equal to the lower case's distance.
    #[test]
    fn degenerate_edges_fall_back() {
        let v = |x: Real, y: Real, z: Real| Vec3::new(x, y, z);
        let cases = [
            // Edge a a point, above the middle of b.
            ([v(0.5, 0.0, 1.0), v(0.5, 0.0, 1.0), v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0)], 1.0),
            // Both points.
            ([v(0.0, 0.0, 0.0), v(0.0, 0.0, 0.0), v(1.0, 2.0, 2.0), v(1.0, 2.0, 2.0)], 9.0),
            // Parallel and coincident lines, overlapping: they touch.
            ([v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.5, 0.0, 0.0), v(2.0, 0.0, 0.0)], 0.0),
            // Anti-parallel at a distance 0.5.
            ([v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.5, 0.0, 0.5), v(0.2, 0.0, 0.5)], 0.25),
        ];
        for (points, squared) in cases {
            let result = distance(points);
            assert!((result.squared - squared).abs() < TIGHT, "{points:?}: {}", result.squared);
            assert!(result.gradient.iter().all(|g| g.is_finite()), "{points:?}");
            assert!(result.hessian.iter().flatten().all(|h| h.is_finite()), "{points:?}");
            assert_ne!(kind(points), EdgeEdgeKind::Interior);
        }
    }

    /// The value-only and gradient-only functions are the full one's value and gradient, bit
    /// for bit, for every kind (counted: each is reached); so are the mollifier's, fading or
    /// not (both counted).
    #[test]
    fn value_only_matches() {
        let mut random = XorShift::new(0x5eed_0013);
        let bits = |g: [Vec3; 4]| g.map(|v| v.to_array().map(Real::to_bits));
        let (mut seen, mut fading) = ([0usize; 9], [0usize; 2]);
        for _ in 0..2000 {
            let points = random.points(1.0);
            let [ea0, ea1, eb0, eb1] = points;
            let full = distance(points);
            assert_eq!(value(points).to_bits(), full.squared.to_bits());
            let gradient = edge_edge_distance_gradient(ea0, ea1, eb0, eb1);
            assert_eq!(gradient.squared.to_bits(), full.squared.to_bits());
            assert_eq!(bits(gradient.gradient), bits(full.gradient));
            seen[kind(points) as usize] += 1;
            let threshold = random.uniform(0.0, 0.5);
            let mollifier = edge_edge_mollifier(ea0, ea1, eb0, eb1, threshold);
            assert_eq!(
                edge_edge_mollifier_value(ea0, ea1, eb0, eb1, threshold).to_bits(),
                mollifier.value.to_bits()
            );
            let mollifier_gradient = edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, threshold);
            assert_eq!(mollifier_gradient.value.to_bits(), mollifier.value.to_bits());
            assert_eq!(bits(mollifier_gradient.gradient), bits(mollifier.gradient));
            fading[usize::from(mollifier.value < 1.0)] += 1;
        }
        assert!(seen.iter().all(|&count| count > 0), "{seen:?}");
        assert!(fading.iter().all(|&count| count > 0), "{fading:?}");
    }

    fn mollifier_value(threshold: Real) -> impl Fn([Vec3; 4]) -> Real {
        move |[ea0, ea1, eb0, eb1]: [Vec3; 4]| {
            edge_edge_mollifier_value(ea0, ea1, eb0, eb1, threshold)
        }
    }

    fn cross_squared([ea0, ea1, eb0, eb1]: [Vec3; 4]) -> Real {
        (ea1 - ea0).cross(eb1 - eb0).length_squared()
    }

    /// The mollifier: the threshold's closed form, 1 at and above it (with zero
    /// derivatives), 0 for parallel edges, C1 at the threshold, and its gradient and Hessian
    /// against central differences below it.
    #[test]
    fn mollifier_values_continuity_and_derivatives() {
        let rest = [Vec3::ZERO, Vec3::X * 2.0, Vec3::Y, Vec3::Y * 4.0];
        let threshold = edge_edge_mollifier_threshold(rest[0], rest[1], rest[2], rest[3]);
        assert!((threshold - 1e-3 * 4.0 * 9.0).abs() < 1e-3 * TIGHT);
        let mut random = XorShift::new(0x5eed_0014);
        let (gradient_step, gradient_tolerance, hessian_step, hessian_tolerance) = fd_settings();
        for _ in 0..100 {
            let points = random.points(1.0);
            let [ea0, ea1, eb0, eb1] = points;
            let c = cross_squared(points);
            if c < 0.05 {
                continue;
            }
            // At and above the threshold: exactly 1, flat.
            for at_or_below_c in [c, 0.5 * c] {
                let above = edge_edge_mollifier(ea0, ea1, eb0, eb1, at_or_below_c);
                assert_eq!(above.value, 1.0);
                assert!(above.gradient.iter().all(|g| *g == Vec3::ZERO));
            }
            // Just below: the value is 1 - (1 - c/eps)^2 and the gradient m'(c) grad c
            // vanishes like (1 - c/eps): C1.
            let just_below = edge_edge_mollifier(ea0, ea1, eb0, eb1, c * (1.0 + 1e-3));
            assert!((1.0 - just_below.value) < 2e-6 + TIGHT);
            // Its gradient is m'(c) grad c with m'(c) = 2 (1 - c / eps) / eps: 2 (1 - 1 / 1.001)
            // / (1.001 c) at eps = 1.001 c against 0.5 / c at eps = 2 c, a ratio of 4.0e-3 that
            // goes to 0 at the threshold (f32 rounds the ratio to ~1e-4).
            let half_way = edge_edge_mollifier(ea0, ea1, eb0, eb1, 2.0 * c);
            let ratio = (2.0 * (1.0 - 1.0 / 1.001) / 1.001) / 0.5;
            for (g, g_half) in just_below.gradient.iter().zip(half_way.gradient) {
                assert!((*g - g_half * ratio).length() < 1e-3 * g_half.length() + TIGHT);
            }
            // Well below: derivatives by differences, relative to the largest entry.
            let threshold = 3.0 * c;
            let mollifier = edge_edge_mollifier(ea0, ea1, eb0, eb1, threshold);
            let value = mollifier_value(threshold);
            let gradient = gradient_error(&value, points, mollifier.gradient, gradient_step);
            assert!(gradient < gradient_tolerance, "{points:?}: {gradient}");
            let hessian = hessian_error(&value, points, mollifier.hessian, hessian_step);
            assert!(hessian < hessian_tolerance, "{points:?}: {hessian}");
        }
        // Parallel edges: 0 with zero gradient.
        let far_end = Vec3::new(3.0, 1.0, 0.0);
        let parallel = edge_edge_mollifier(Vec3::ZERO, Vec3::X, Vec3::Y, far_end, 0.1);
        assert_eq!(parallel.value, 0.0);
        assert!(parallel.gradient.iter().all(|g| g.length() < TIGHT));
        // No threshold (a zero-length rest edge): 1 everywhere.
        assert_eq!(edge_edge_mollifier_value(Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, 0.0), 1.0);
    }
}

//! The distance from a point to an edge: to one of its ends (point–point) or to the line
//! through it (point–line), the case every other falls back to (`docs/math.md` section 8.2).

use super::super::super::super::types::{Real, Vec3};
use super::{Slot, Stationary, placed};

/// Which feature of an edge `e0 e1` is closest to a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum EdgeFeature {
    /// The end `e0` (also for an edge negligibly short next to the distance).
    Start,
    /// The end `e1`.
    End,
    /// A point strictly between the ends: the distance to the line.
    Interior,
}

/// The closest feature of the edge `e0 e1` to `p` and the squared distance with what its
/// derivatives need, `p` in slot `at[0]` and the ends in `at[1]`, `at[2]`.
pub(super) fn point_edge(p: Vec3, e0: Vec3, e1: Vec3, at: [usize; 3]) -> (EdgeFeature, Stationary) {
    let [p_slot, e0_slot, e1_slot] = at;
    let edge = e1 - e0;
    let from_start = p - e0;
    let length2 = edge.dot(edge);
    let along = from_start.dot(edge);
    // `along / length2` is the line's closest parameter; comparing before dividing keeps a
    // zero-length edge out of the division.
    if along <= 0.0 || short(length2, from_start.dot(from_start)) {
        (
            EdgeFeature::Start,
            Stationary::point_point(p, e0, [p_slot, e0_slot]),
        )
    } else if along >= length2 {
        (
            EdgeFeature::End,
            Stationary::point_point(p, e1, [p_slot, e1_slot]),
        )
    } else {
        (EdgeFeature::Interior, point_line(p, e0, e1, at))
    }
}

/// Whether an edge of squared length `length2` is negligible next to the squared distance
/// `distance2` of a point from its start (or too short to invert at all): then the point–line
/// Hessian, of order `distance2 / length2`, would exceed `1 / EPSILON^2`.
#[inline]
fn short(length2: Real, distance2: Real) -> bool {
    !(length2 > Real::EPSILON * Real::EPSILON * distance2 && length2 >= Real::MIN_POSITIVE)
}

/// The squared distance from `p` to the line through `e0` and `e1` (not short: see
/// [`short`]): `r = (p - e0) - s (e1 - e0)` at `s* = (p - e0).(e1 - e0) / |e1 - e0|^2`.
fn point_line(p: Vec3, e0: Vec3, e1: Vec3, at: [usize; 3]) -> Stationary {
    let edge = e1 - e0;
    let length2 = edge.dot(edge);
    let from_start = p - e0;
    let s = from_start.dot(edge) / length2;
    let residual = from_start - edge * s;
    Stationary {
        squared: residual.dot(residual),
        residual,
        slots: placed(
            [
                Slot {
                    weight: 1.0,
                    rates: [0.0; 2],
                },
                Slot {
                    weight: s - 1.0,
                    rates: [1.0, 0.0],
                },
                Slot {
                    weight: -s,
                    rates: [-1.0, 0.0],
                },
            ],
            at,
        ),
        directions: [-edge, Vec3::ZERO],
        gram_inverse: [[1.0 / length2, 0.0], [0.0, 0.0]],
    }
}

//! Squared distances between the primitives of two surfaces, with their exact gradients and
//! Hessians: a point and a triangle, two edges (`docs/math.md` section 8).
//!
//! These are the geometric kernels of Incremental Potential Contact (M. Li et al., "Incremental
//! Potential Contact: Intersection- and Inversion-free, Large-Deformation Dynamics", ACM
//! Transactions on Graphics 39(4), 2020), written the way the IPC Toolkit (Z. Ferguson et al.,
//! 2020) evaluates them: first classify which features of the two primitives are closest (a
//! public kind: [`PointTriangleKind`], [`EdgeEdgeKind`]), then evaluate that case's smooth
//! formula, one of
//!
//! * point–point `|a - b|^2`,
//! * point–line, the distance to the infinite line through an edge,
//! * point–plane, the distance to the plane of a triangle,
//! * line–line, the distance between the infinite lines through two edges,
//!
//! with its gradient and Hessian scattered into four slots (the point and the triangle's
//! corners, or the two edges' ends) and zeros where a point is not involved. Each kind's
//! formula is smooth on its own; the classified distance is continuous everywhere, its
//! gradient wherever the closest points are unique, and its Hessian, exact within each kind,
//! jumps where the kind changes.
//!
//! # Conventions
//! * Lengths in m, squared distances in m^2, gradients in m, Hessians dimensionless.
//! * Slots: point–triangle `[p, t0, t1, t2]`; edge–edge `[ea0, ea1, eb0, eb1]`.
//!   [`PairDistance::gradient`]`[k]` is `d(d^2)/dx_k`; [`PairDistance::hessian`]`[k][l]` is the
//!   3x3 block `d^2(d^2) / (dx_k dx_l)`, row `i` and column `j` differentiating coordinate `i` of
//!   point `k` and coordinate `j` of point `l`, so that `hessian[l][k]` is the transpose of
//!   `hessian[k][l]`. Exact, not projected onto the positive semi-definite cone.
//! * Deterministic: a fixed order of operations, no fused multiply-add.
//!
//! # Degenerate input
//! A triangle whose area is negligible (`|e1 x e2|^2 <= Real::EPSILON |e1|^2 |e2|^2`, its
//! smallest angle's sine below `sqrt(Real::EPSILON)`: `3.5e-4` in f32, `1.5e-8` in f64) is
//! treated as its three edges; two edges that are parallel to the same tolerance as their four
//! endpoint–edge distances; an edge negligibly short next to the distance (`|e|^2 <=
//! Real::EPSILON^2 |p - e0|^2`) as its first end. Where a primitive crosses the tolerance the
//! distance changes by at most its own width (the sine above times the edge lengths). Finite
//! input whose squared coordinate differences are finite gives finite output, never NaN, and
//! nothing panics.

mod edge_edge;
mod point_edge;
mod point_triangle;

pub use edge_edge::{
    EdgeEdgeKind, Mollifier, MollifierGradient, edge_edge_distance, edge_edge_distance_gradient,
    edge_edge_kind, edge_edge_mollifier, edge_edge_mollifier_gradient,
    edge_edge_mollifier_threshold, edge_edge_mollifier_value, edge_edge_squared_distance,
};
pub use point_triangle::{
    PointTriangleKind, point_triangle_distance, point_triangle_distance_gradient,
    point_triangle_kind, point_triangle_squared_distance,
};

use super::super::super::types::{Mat3, Real, Vec3};

/// A squared distance between two primitives with its gradient and Hessian with respect to
/// their four points (see the [module docs](self) for the slots and conventions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairDistance {
    /// The squared distance `d^2` (m^2).
    pub squared: Real,
    /// `d(d^2)/dx_k` for each of the four points (m); they sum to zero (the distance does not
    /// change when both primitives move together).
    pub gradient: [Vec3; 4],
    /// `d^2(d^2)/(dx_k dx_l)`, 3x3 blocks (dimensionless), exact: not projected.
    pub hessian: [[Mat3; 4]; 4],
}

/// A squared distance with its gradient alone (see [`PairDistance`], of which these are the
/// first two fields, the same bits): what an energy and gradient evaluation needs, without the
/// Hessian's 16 blocks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairDistanceGradient {
    /// The squared distance `d^2` (m^2).
    pub squared: Real,
    /// `d(d^2)/dx_k` for each of the four points (m); they sum to zero.
    pub gradient: [Vec3; 4],
}

/// One point's share in the residual of a closest-point problem (see [`Stationary`]).
#[derive(Clone, Copy, Debug, Default)]
struct Slot {
    /// The point's weight `w_k(s*)` in the residual `r = sum_k w_k x_k`.
    weight: Real,
    /// `dw_k/ds_i` for the (at most two) parameters `s_i`.
    rates: [Real; 2],
}

/// The minimum over parameters `s` of `|r(s)|^2`, `r(s) = sum_k w_k(s) x_k` with weights affine
/// in `s` (a point on a line or plane minus a point on another): every smooth case of this
/// module. The derivatives follow from the stationarity of `s*` (`docs/math.md` section 8.1).
#[derive(Clone, Copy, Debug)]
struct Stationary {
    /// `|r(s*)|^2` (m^2), evaluated by the case's most accurate formula.
    squared: Real,
    /// `r(s*)` (m).
    residual: Vec3,
    /// The four points' weights and their rates.
    slots: [Slot; 4],
    /// `u_i = dr/ds_i = sum_k (dw_k/ds_i) x_k` (m; zero for an unused parameter).
    directions: [Vec3; 2],
    /// The inverse of the Gram matrix `G_ij = u_i . u_j` (1/m^2; zero rows and columns for an
    /// unused parameter).
    gram_inverse: [[Real; 2]; 2],
}

impl Stationary {
    /// `|a - b|^2`, with `a` in slot `slots[0]` and `b` in slot `slots[1]`.
    fn point_point(a: Vec3, b: Vec3, slots: [usize; 2]) -> Stationary {
        let residual = a - b;
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
                        weight: -1.0,
                        rates: [0.0; 2],
                    },
                ],
                slots,
            ),
            directions: [Vec3::ZERO; 2],
            gram_inverse: [[0.0; 2]; 2],
        }
    }

    /// The squared distance and its gradient `g_k = 2 w_k r` (`docs/math.md` section 8.1),
    /// the same bits as [`derivatives`](Self::derivatives)' (which calls this).
    fn gradient(&self) -> PairDistanceGradient {
        let r = self.residual;
        PairDistanceGradient {
            squared: self.squared,
            gradient: self.slots.map(|slot| r * (2.0 * slot.weight)),
        }
    }

    /// The squared distance's gradient and Hessian (`docs/math.md` section 8.1):
    /// `g_k = 2 w_k r` and `H_kl = 2 w_k w_l I - 2 sum_ij (G^-1)_ij q_ki q_lj^T` with
    /// `q_ki = (dw_k/ds_i) r + w_k u_i`.
    fn derivatives(&self) -> PairDistance {
        let r = self.residual;
        let [u0, u1] = self.directions;
        let [[g00, g01], [g10, g11]] = self.gram_inverse;
        let gradient = self.gradient().gradient;
        let mixed = self.slots.map(|slot| {
            let q0 = r * slot.rates[0] + u0 * slot.weight;
            let q1 = r * slot.rates[1] + u1 * slot.weight;
            let p0 = q0 * g00 + q1 * g01;
            let p1 = q0 * g10 + q1 * g11;
            (slot.weight, [q0, q1], [p0, p1])
        });
        let hessian = mixed.map(|(weight_k, [q0, q1], _)| {
            mixed.map(|(weight_l, _, [p0, p1])| {
                Mat3::from_diagonal(Vec3::splat(2.0 * weight_k * weight_l))
                    - (outer(q0, p0) + outer(q1, p1)) * 2.0
            })
        });
        PairDistance {
            squared: self.squared,
            gradient,
            hessian,
        }
    }
}

/// The outer product `a b^T` (row `i`, column `j`: `a_i b_j`).
#[inline]
fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Four slots holding `local[j]` at `at[j]` and zero weights elsewhere (an index beyond the
/// four is skipped; the callers pass constants below four).
fn placed<const N: usize>(local: [Slot; N], at: [usize; N]) -> [Slot; 4] {
    let mut slots = [Slot::default(); 4];
    for (slot, index) in local.into_iter().zip(at) {
        if let Some(target) = slots.get_mut(index) {
            *target = slot;
        }
    }
    slots
}

/// Whether the smooth formula's Gram determinant `det` (computed as a squared cross product,
/// accurate to rounding even when small) is too small against `scale` (the product of the two
/// squared lengths) to invert: the two directions are parallel to within `sqrt(EPSILON)`.
#[inline]
fn negligible(det: Real, scale: Real) -> bool {
    !(det > Real::EPSILON * scale && det >= Real::MIN_POSITIVE)
}

#[cfg(test)]
mod test_support;

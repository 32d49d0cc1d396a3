//! The contact potential of Incremental Potential Contact over the candidate pairs: its value,
//! gradient and projected Hessian, per pair and assembled per vertex (`docs/math.md` section
//! 8.9).
//!
//! With a barrier stiffness `kappa` (J/m^4) and a contact gap `dhat` (m) ([`ContactBarrier`]),
//! the energy of the active pairs is
//!
//! ```text
//! B(x) = kappa sum_k m_k(x) b(d_k^2(x), dhat^2)
//! ```
//!
//! with `d_k^2` the pair's squared distance ([`distance`](super::distance)), `b` the log barrier
//! ([`barrier`](super::barrier)) and `m_k` the edge–edge mollifier (1 for a point–triangle
//! pair), after M. Li et al., "Incremental Potential Contact: Intersection- and Inversion-free,
//! Large-Deformation Dynamics" (ACM Transactions on Graphics 39(4), 2020) and the IPC Toolkit
//! (Z. Ferguson et al., 2020).
//!
//! # Conventions
//! * Units: `B` in J, its gradient in N (J/m), its Hessian in N/m.
//! * Slots as in [`distance`](super::distance): point–triangle `[p, t0, t1, t2]`, edge–edge
//!   `[ea0, ea1, eb0, eb1]`; each pair carries the four global vertex indices of its slots.
//!   Hessian blocks `hessian[k][l]`: row `i`, column `j` differentiate coordinate `i` of slot `k`
//!   and coordinate `j` of slot `l`.
//! * A pair at `d^2 >= dhat^2` contributes exactly zero and is skipped. A pair at `d^2 <= 0`
//!   (touching or through) makes the energy `+inf`, with zero gradient and Hessian: the
//!   configuration is not admissible and a line search must refuse it. Where the chain rule
//!   overflows (a pair closer than about `1e-10 dhat` in f32, or a huge `kappa`), the pair's
//!   value is reported `+inf` the same way: by [`ContactPotential::add_gradient`] where the
//!   value or gradient overflows, by the functions that return Hessians where any of the three
//!   does. Nothing is ever NaN for finite input.
//! * The Hessian is the chain rule `kappa (m (b'' g g^T + b' H) + b' (g_m g^T + g g_m^T) + b
//!   H_m)` (`g`, `H` the squared distance's derivatives, `g_m`, `H_m` the mollifier's),
//!   projected as a whole 12x12 matrix onto the positive semi-definite cone, as IPC does: its
//!   negative eigenvalues, from cyclic Jacobi sweeps (Golub and Van Loan, "Matrix
//!   Computations", section 8.5) until the off-diagonal part is below rounding (at most ten),
//!   are set to zero. A Hessian that is already positive semi-definite is kept as it is.
//! * Deterministic: the pairs in a fixed order (every point–triangle pair in list order, then
//!   every edge–edge pair), a fixed order of operations, no fused multiply-add.
//!
//! # Cost
//! The value alone ([`ContactPotential::energy`]) costs a squared distance per candidate; the
//! gradient ([`ContactPotential::add_gradient`]) one closest-feature search per candidate and
//! the gradients alone (of the distance, the mollifier, the chain rule) of the active pairs;
//! the projected Hessians one Jacobi eigen-decomposition per active pair, of the 9x9 block left
//! once the translations (its null space) are split off (3 to 7 sweeps of 36 rotations of about
//! 120 floating-point operations each), which dominates. Nothing is allocated.

use crate::error::{ContactBuffer, ContactError};

use super::super::super::math;
use super::super::super::types::{Mat3, Real, Vec3};
use super::barrier::{self as log_barrier, BarrierDerivatives, barrier_derivatives};
use super::boundary::ContactSurface;
use super::broad_phase::CandidatePairs;
use super::distance::{
    Mollifier, MollifierGradient, PairDistance, PairDistanceGradient, edge_edge_distance,
    edge_edge_distance_gradient, edge_edge_mollifier, edge_edge_mollifier_gradient,
    edge_edge_mollifier_threshold, edge_edge_mollifier_value, edge_edge_squared_distance,
    point_triangle_distance, point_triangle_distance_gradient, point_triangle_squared_distance,
};

/// The barrier's stiffness and reach.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ContactBarrier {
    /// `kappa` (J/m^4): the energy is `kappa` times the barrier, which is in m^4. Finite and
    /// `>= 0`.
    pub stiffness: Real,
    /// `dhat` (m): pairs closer than this repel. Finite and `>= 0` (0 switches contact off).
    pub gap: Real,
}

impl ContactBarrier {
    /// `dhat^2` (m^2); 0 for a gap that is not positive (or NaN).
    #[inline]
    fn squared_gap(&self) -> Real {
        if self.gap > 0.0 {
            self.gap * self.gap
        } else {
            0.0
        }
    }

    /// The barrier of gap `gap` (m) whose stiffness makes a point–triangle pair at half the gap
    /// push with `force` (N): `kappa = force / (|b'(dhat^2 / 4)| dhat)`, `b'` the barrier's
    /// derivative in the squared distance ([`barrier_derivatives`]), since the pair's force is
    /// `kappa |b'(d^2)| 2 d`. A scale to reason in: the weight one contact vertex carries at
    /// rest. The force is 0 at the gap and grows without bound as the distance goes to 0, so a
    /// resting contact settles where it carries its load, nearer than `dhat / 2` for a larger
    /// load.
    ///
    /// ```
    /// use softfem::step::contact::potential::{ContactBarrier, point_triangle_potential};
    /// use softfem::glam::Vec3;
    ///
    /// let barrier = ContactBarrier::holding(1e-3, 2.0)?;
    /// // A point 0.5 mm above a triangle in the plane z = 0.
    /// let points = [Vec3::new(0.2, 0.2, 5e-4), Vec3::ZERO, Vec3::X, Vec3::Y];
    /// let pair = point_triangle_potential(&barrier, points, [0, 1, 2, 3]);
    /// // The gradient points down: the force, minus it, pushes the point up with 2 N.
    /// assert!((pair.gradient[0].z + 2.0).abs() < 1e-4);
    /// # Ok::<(), softfem::ContactError>(())
    /// ```
    ///
    /// # Errors
    /// [`ContactError::Gap`] for a gap that is not finite and positive;
    /// [`ContactError::Stiffness`] for a force that is not finite and `>= 0`, or one whose
    /// stiffness overflows.
    pub fn holding(gap: Real, force: Real) -> Result<ContactBarrier, ContactError> {
        if !(gap.is_finite() && gap > 0.0) {
            return Err(ContactError::Gap);
        }
        if !(force.is_finite() && force >= 0.0) {
            return Err(ContactError::Stiffness);
        }
        let squared_gap = gap * gap;
        let slope = barrier_derivatives(0.25 * squared_gap, squared_gap)
            .first
            .abs();
        let barrier = ContactBarrier {
            stiffness: force / (slope * gap),
            gap,
        };
        barrier.check()?;
        Ok(barrier)
    }

    /// [`ContactError::Gap`] or [`ContactError::Stiffness`] unless both are finite and `>= 0`.
    fn check(&self) -> Result<(), ContactError> {
        if !(self.gap.is_finite() && self.gap >= 0.0) {
            return Err(ContactError::Gap);
        }
        if !(self.stiffness.is_finite() && self.stiffness >= 0.0) {
            return Err(ContactError::Stiffness);
        }
        Ok(())
    }
}

/// One pair's share of the contact potential: value, gradient and projected Hessian with
/// respect to its four points (slots as in the [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairPotential {
    /// The global vertex indices of the four slots.
    pub vertices: [u32; 4],
    /// `kappa m b(d^2)` (J): 0 for an inactive pair, `+inf` at `d^2 <= 0`.
    pub value: Real,
    /// `dB/dx_k` (N) for each slot; they sum to zero.
    pub gradient: [Vec3; 4],
    /// `d^2 B / (dx_k dx_l)` (N/m), 3x3 blocks, projected onto the positive semi-definite
    /// cone as one symmetric 12x12 matrix.
    pub hessian: [[Mat3; 4]; 4],
}

/// One pair's projected Hessian and the vertices it couples, as stored for matrix-free
/// products ([`ContactPotential::pair_hessians`], [`add_hessian_product`]). `Default` is a
/// zero Hessian on vertex 0 (for sizing buffers).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairHessian {
    /// The global vertex indices of the four slots.
    pub vertices: [u32; 4],
    /// The projected Hessian (N/m), as [`PairPotential::hessian`].
    pub hessian: [[Mat3; 4]; 4],
}

impl PairHessian {
    /// No vertices and a zero Hessian (for filling buffers, also in a `const`).
    pub const ZERO: PairHessian = PairHessian {
        vertices: [0; 4],
        hessian: [[Mat3::ZERO; 4]; 4],
    };
}

impl Default for PairHessian {
    #[inline]
    fn default() -> Self {
        PairHessian::ZERO
    }
}

/// The exact (unprojected) terms of one pair.
#[derive(Clone, Copy, Debug)]
struct PairTerms {
    value: Real,
    gradient: [Vec3; 4],
    hessian: [[Mat3; 4]; 4],
    /// Whether `0 < d^2 < dhat^2` and everything came out finite: the only pairs with a
    /// Hessian worth projecting.
    active: bool,
}

impl PairTerms {
    /// An inactive pair: exactly zero.
    const INACTIVE: PairTerms = PairTerms {
        value: 0.0,
        gradient: [Vec3::ZERO; 4],
        hessian: [[Mat3::ZERO; 4]; 4],
        active: false,
    };

    /// A pair touching or through, or whose derivatives overflow: `+inf`, zero derivatives.
    const BLOCKED: PairTerms = PairTerms {
        value: Real::INFINITY,
        gradient: [Vec3::ZERO; 4],
        hessian: [[Mat3::ZERO; 4]; 4],
        active: false,
    };

    /// The pair's potential with the Hessian projected (only an active pair's is nonzero).
    fn projected(self, vertices: [u32; 4]) -> PairPotential {
        PairPotential {
            vertices,
            value: self.value,
            gradient: self.gradient,
            hessian: if self.active {
                project(&self.hessian)
            } else {
                self.hessian
            },
        }
    }
}

/// The outer product `a b^T` (row `i`, column `j`: `a_i b_j`).
#[inline]
fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The chain rule of `kappa m b(d^2)` (see the [module docs](self)).
fn chain(
    stiffness: Real,
    distance: &PairDistance,
    b: BarrierDerivatives,
    mollifier: &Mollifier,
) -> PairTerms {
    let m = mollifier.value;
    let value = stiffness * (m * b.value);
    let g = distance.gradient;
    let gm = mollifier.gradient;
    let mut gradient = [Vec3::ZERO; 4];
    for ((out, &g_k), &gm_k) in gradient.iter_mut().zip(&g).zip(&gm) {
        *out = (g_k * (m * b.first) + gm_k * b.value) * stiffness;
    }
    let mut hessian = [[Mat3::ZERO; 4]; 4];
    let rows = hessian
        .iter_mut()
        .zip(&distance.hessian)
        .zip(&mollifier.hessian)
        .zip(g.iter().zip(&gm));
    for (((out_row, h_row), hm_row), (&g_k, &gm_k)) in rows {
        let columns = out_row
            .iter_mut()
            .zip(h_row)
            .zip(hm_row)
            .zip(g.iter().zip(&gm));
        for (((out, &h_kl), &hm_kl), (&g_l, &gm_l)) in columns {
            let distance_term = (outer(g_k, g_l) * b.second + h_kl * b.first) * m;
            let product_term = (outer(gm_k, g_l) + outer(g_k, gm_l)) * b.first;
            *out = (distance_term + product_term + hm_kl * b.value) * stiffness;
        }
    }
    let finite = value.is_finite()
        && gradient.iter().all(|g| g.is_finite())
        && hessian.iter().flatten().all(|h| h.is_finite());
    if finite {
        PairTerms {
            value,
            gradient,
            hessian,
            active: true,
        }
    } else {
        PairTerms::BLOCKED
    }
}

/// The value and gradient of one pair (the first two of [`PairTerms`], the same bits), for
/// the energy and gradient evaluation.
#[derive(Clone, Copy, Debug)]
struct PairGradientTerms {
    value: Real,
    gradient: [Vec3; 4],
    /// Whether `0 < d^2 < dhat^2` and the value and gradient came out finite.
    active: bool,
}

impl PairGradientTerms {
    /// An inactive pair: exactly zero.
    const INACTIVE: PairGradientTerms = PairGradientTerms {
        value: 0.0,
        gradient: [Vec3::ZERO; 4],
        active: false,
    };

    /// A pair touching or through, or whose gradient overflows: `+inf`, zero gradient.
    const BLOCKED: PairGradientTerms = PairGradientTerms {
        value: Real::INFINITY,
        gradient: [Vec3::ZERO; 4],
        active: false,
    };
}

/// The value and gradient of the chain rule of [`chain`], the same operations (so the same
/// bits) without the Hessian.
fn chain_gradient(
    stiffness: Real,
    distance: &PairDistanceGradient,
    b: BarrierDerivatives,
    mollifier: &MollifierGradient,
) -> PairGradientTerms {
    let m = mollifier.value;
    let value = stiffness * (m * b.value);
    let mut gradient = [Vec3::ZERO; 4];
    let inputs = distance.gradient.iter().zip(&mollifier.gradient);
    for (out, (&g_k, &gm_k)) in gradient.iter_mut().zip(inputs) {
        *out = (g_k * (m * b.first) + gm_k * b.value) * stiffness;
    }
    if value.is_finite() && gradient.iter().all(|g| g.is_finite()) {
        PairGradientTerms {
            value,
            gradient,
            active: true,
        }
    } else {
        PairGradientTerms::BLOCKED
    }
}

/// The mollifier of a point–triangle pair, value and gradient: 1, flat.
const NO_MOLLIFIER_GRADIENT: MollifierGradient = MollifierGradient {
    value: 1.0,
    gradient: [Vec3::ZERO; 4],
};

/// The value and gradient of a point–triangle pair at `[p, t0, t1, t2]` (one closest-feature
/// search: the squared distance that decides activity is the gradient's own).
fn point_triangle_gradient_terms(barrier: &ContactBarrier, points: [Vec3; 4]) -> PairGradientTerms {
    let [p, t0, t1, t2] = points;
    let dhat2 = barrier.squared_gap();
    let distance = point_triangle_distance_gradient(p, t0, t1, t2);
    let d2 = distance.squared;
    if touching(d2) {
        return PairGradientTerms::BLOCKED;
    }
    if d2 >= dhat2 {
        return PairGradientTerms::INACTIVE;
    }
    let b = barrier_derivatives(d2, dhat2);
    chain_gradient(barrier.stiffness, &distance, b, &NO_MOLLIFIER_GRADIENT)
}

/// The value and gradient of an edge–edge pair at `[ea0, ea1, eb0, eb1]` with the mollifier's
/// threshold `eps_x` (m^4).
fn edge_edge_gradient_terms(
    barrier: &ContactBarrier,
    points: [Vec3; 4],
    threshold: Real,
) -> PairGradientTerms {
    let [ea0, ea1, eb0, eb1] = points;
    let dhat2 = barrier.squared_gap();
    let distance = edge_edge_distance_gradient(ea0, ea1, eb0, eb1);
    let d2 = distance.squared;
    if touching(d2) {
        return PairGradientTerms::BLOCKED;
    }
    if d2 >= dhat2 {
        return PairGradientTerms::INACTIVE;
    }
    let mollifier = edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, threshold);
    let b = barrier_derivatives(d2, dhat2);
    chain_gradient(barrier.stiffness, &distance, b, &mollifier)
}

/// The mollifier of a point–triangle pair: 1, flat.
const NO_MOLLIFIER: Mollifier = Mollifier {
    value: 1.0,
    gradient: [Vec3::ZERO; 4],
    hessian: [[Mat3::ZERO; 4]; 4],
};

/// Whether a squared distance means touching or through (`<= 0`, or NaN): the pair is `+inf`.
#[inline]
fn touching(d2: Real) -> bool {
    d2.is_nan() || d2 <= 0.0
}

/// The exact terms of a point–triangle pair at `[p, t0, t1, t2]`.
fn point_triangle_terms(barrier: &ContactBarrier, points: [Vec3; 4]) -> PairTerms {
    let [p, t0, t1, t2] = points;
    let dhat2 = barrier.squared_gap();
    let d2 = point_triangle_squared_distance(p, t0, t1, t2);
    if touching(d2) {
        return PairTerms::BLOCKED;
    }
    if d2 >= dhat2 {
        return PairTerms::INACTIVE;
    }
    let distance = point_triangle_distance(p, t0, t1, t2);
    let b = barrier_derivatives(distance.squared, dhat2);
    chain(barrier.stiffness, &distance, b, &NO_MOLLIFIER)
}

/// The exact terms of an edge–edge pair at `[ea0, ea1, eb0, eb1]` with the mollifier's
/// threshold `eps_x` (m^4).
fn edge_edge_terms(barrier: &ContactBarrier, points: [Vec3; 4], threshold: Real) -> PairTerms {
    let [ea0, ea1, eb0, eb1] = points;
    let dhat2 = barrier.squared_gap();
    let d2 = edge_edge_squared_distance(ea0, ea1, eb0, eb1);
    if touching(d2) {
        return PairTerms::BLOCKED;
    }
    if d2 >= dhat2 {
        return PairTerms::INACTIVE;
    }
    let distance = edge_edge_distance(ea0, ea1, eb0, eb1);
    let mollifier = edge_edge_mollifier(ea0, ea1, eb0, eb1, threshold);
    let b = barrier_derivatives(distance.squared, dhat2);
    chain(barrier.stiffness, &distance, b, &mollifier)
}

/// The potential of a point `p` and a triangle `t0 t1 t2`, `points = [p, t0, t1, t2]` (m),
/// labelled with their global `vertices`: `kappa b(d^2)` with its gradient and projected
/// Hessian (see the [module docs](self) for the conventions and the values at and beyond the
/// gap).
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::potential::{ContactBarrier, point_triangle_potential};
///
/// // A point 1 mm above the triangle z = 0, gap 1 cm.
/// let barrier = ContactBarrier { stiffness: 1e6, gap: 0.01 };
/// let [t0, t1, t2] = [Vec3::ZERO, Vec3::X, Vec3::Y];
/// let vertices = [7, 0, 1, 2];
/// let p = Vec3::new(0.25, 0.25, 0.001);
/// let pair = point_triangle_potential(&barrier, [p, t0, t1, t2], vertices);
/// assert!(pair.value > 0.0);
/// // The energy falls as the point rises: the force -gradient pushes it up, the triangle down.
/// assert!(pair.gradient[0].z < 0.0);
/// let on_triangle: Vec3 = pair.gradient[1..].iter().sum();
/// assert!((on_triangle + pair.gradient[0]).length() < 1e-3 * pair.gradient[0].length());
/// // Stiff along the normal, and the projected Hessian is positive semi-definite there.
/// assert!(pair.hessian[0][0].z_axis.z > 0.0);
///
/// // Beyond the gap: nothing at all. Touching: +inf.
/// let far = Vec3::new(0.25, 0.25, 0.02);
/// let none = point_triangle_potential(&barrier, [far, t0, t1, t2], vertices);
/// assert_eq!((none.value, none.gradient[0]), (0.0, Vec3::ZERO));
/// let on = Vec3::new(0.25, 0.25, 0.0);
/// let touching = point_triangle_potential(&barrier, [on, t0, t1, t2], vertices);
/// assert_eq!(touching.value, f32::INFINITY);
/// ```
#[must_use]
pub fn point_triangle_potential(
    barrier: &ContactBarrier,
    points: [Vec3; 4],
    vertices: [u32; 4],
) -> PairPotential {
    point_triangle_terms(barrier, points).projected(vertices)
}

/// The potential of the edges `ea0 ea1` and `eb0 eb1`, `points = [ea0, ea1, eb0, eb1]` (m),
/// labelled with their global `vertices`: `kappa m b(d^2)` with its gradient and projected
/// Hessian, `m` the mollifier of threshold `mollifier_threshold` (`eps_x`, m^4: see
/// [`edge_edge_mollifier_threshold`], from the edges' rest positions).
///
/// See the [module docs](self) for the conventions and the values at and beyond the gap. An
/// edge pair at `d^2 <= 0` is `+inf` even where the mollifier is 0 (parallel edges).
#[must_use]
pub fn edge_edge_potential(
    barrier: &ContactBarrier,
    points: [Vec3; 4],
    mollifier_threshold: Real,
    vertices: [u32; 4],
) -> PairPotential {
    edge_edge_terms(barrier, points, mollifier_threshold).projected(vertices)
}

/// The contact potential of a surface's candidate pairs (see the [module docs](self)): what the
/// barrier acts on, fixed for a step, evaluated at any positions.
///
/// ```
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::step::contact::boundary::ContactSurface;
/// use softfem::step::contact::broad_phase::CandidatePairs;
/// use softfem::step::contact::potential::{
///     ContactBarrier, ContactPotential, PairHessian, add_hessian_product,
/// };
///
/// // Vertex 3 is 1 mm above the triangle 0-1-2 (z = 0); gap 1 cm.
/// let positions = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.2, 0.2, 0.001)];
/// let surface = ContactSurface { vertices: &[3], edges: &[], triangles: &[[0, 1, 2]] };
/// let pairs = CandidatePairs { vertex_triangle: &[[0, 0]], edge_edge: &[] };
/// let potential = ContactPotential {
///     barrier: ContactBarrier { stiffness: 1e6, gap: 0.01 },
///     surface,
///     pairs,
///     rest_positions: &positions,
/// };
/// let energy = potential.energy(&positions)?;
/// assert!(energy > 0.0);
///
/// let mut gradient = [Vec3::ZERO; 4];
/// potential.add_gradient(&positions, &mut gradient)?;
/// assert!(gradient[3].z < 0.0); // the force -gradient lifts vertex 3
///
/// let mut diagonal = [Mat3::ZERO; 4];
/// potential.add_hessian_diagonal(&positions, &mut diagonal)?;
/// let mut stored = [PairHessian::default(); 1];
/// let hessians = potential.pair_hessians(&positions, &mut stored)?;
/// let mut product = [Vec3::ZERO; 4];
/// add_hessian_product(hessians, &[Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::Z], &mut product)?;
/// assert!((product[3] - diagonal[3] * Vec3::Z).length() <= 1e-6 * product[3].length());
/// # Ok::<(), softfem::ContactError>(())
/// ```
#[derive(Clone, Copy, Debug)]
pub struct ContactPotential<'a> {
    /// The stiffness `kappa` and the gap `dhat`.
    pub barrier: ContactBarrier,
    /// The surface the pairs index into (global vertex indices).
    pub surface: ContactSurface<'a>,
    /// The candidate pairs (from [`proximity_pairs`](super::broad_phase::proximity_pairs));
    /// a pair beyond the gap costs its distance and adds nothing.
    pub pairs: CandidatePairs<'a>,
    /// The rest positions (m), one per vertex: the edge–edge mollifier's thresholds
    /// ([`edge_edge_mollifier_threshold`]).
    pub rest_positions: &'a [Vec3],
}

/// One candidate pair, looked up: its slots' vertices and points, and for an edge pair the
/// mollifier's threshold.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Pair {
    PointTriangle([u32; 4], [Vec3; 4]),
    EdgeEdge([u32; 4], [Vec3; 4], Real),
}

impl Pair {
    /// The exact terms and the vertices.
    fn terms(&self, barrier: &ContactBarrier) -> (PairTerms, [u32; 4]) {
        match *self {
            Pair::PointTriangle(vertices, points) => {
                (point_triangle_terms(barrier, points), vertices)
            }
            Pair::EdgeEdge(vertices, points, threshold) => {
                (edge_edge_terms(barrier, points, threshold), vertices)
            }
        }
    }

    /// The value and gradient alone and the vertices: the same bits as
    /// [`terms`](Self::terms)' (except where that reports an overflowing Hessian as `+inf`).
    fn gradient_terms(&self, barrier: &ContactBarrier) -> (PairGradientTerms, [u32; 4]) {
        match *self {
            Pair::PointTriangle(vertices, points) => {
                (point_triangle_gradient_terms(barrier, points), vertices)
            }
            Pair::EdgeEdge(vertices, points, threshold) => (
                edge_edge_gradient_terms(barrier, points, threshold),
                vertices,
            ),
        }
    }

    /// The value alone, the same bits as [`terms`](Self::terms)' (except where that reports
    /// an overflowing derivative as `+inf`).
    fn value(&self, barrier: &ContactBarrier) -> Real {
        let dhat2 = barrier.squared_gap();
        let (d2, m) = match *self {
            Pair::PointTriangle(_, [p, t0, t1, t2]) => {
                (point_triangle_squared_distance(p, t0, t1, t2), 1.0)
            }
            Pair::EdgeEdge(_, [ea0, ea1, eb0, eb1], threshold) => {
                let d2 = edge_edge_squared_distance(ea0, ea1, eb0, eb1);
                // The mollifier only where the barrier acts.
                let active = d2 > 0.0 && d2 < dhat2;
                let m = if active {
                    edge_edge_mollifier_value(ea0, ea1, eb0, eb1, threshold)
                } else {
                    1.0
                };
                (d2, m)
            }
        };
        if touching(d2) {
            return Real::INFINITY;
        }
        if d2 >= dhat2 {
            return 0.0;
        }
        // `barrier` evaluates the same formula as `barrier_derivatives`, to the same bits.
        barrier.stiffness * (m * log_barrier::barrier(d2, dhat2))
    }
}

impl ContactPotential<'_> {
    /// Every check before anything is computed or written (see [`energy`](Self::energy)).
    fn check(&self, positions: &[Vec3]) -> Result<(), ContactError> {
        self.barrier.check()?;
        if self.rest_positions.len() != positions.len() {
            return Err(ContactError::BufferLength {
                buffer: ContactBuffer::RestPositions,
                expected: positions.len(),
                actual: self.rest_positions.len(),
            });
        }
        let count = positions.len();
        let in_range = |index: u32| (index as usize) < count;
        let surface = &self.surface;
        for (element, &index) in surface.vertices.iter().enumerate() {
            if !in_range(index) {
                return Err(out_of_range(ContactBuffer::Vertices, element, index));
            }
        }
        for (element, edge) in surface.edges.iter().enumerate() {
            if let Some(&index) = edge.iter().find(|&&index| !in_range(index)) {
                return Err(out_of_range(ContactBuffer::Edges, element, index));
            }
        }
        for (element, triangle) in surface.triangles.iter().enumerate() {
            if let Some(&index) = triangle.iter().find(|&&index| !in_range(index)) {
                return Err(out_of_range(ContactBuffer::Triangles, element, index));
            }
        }
        let lists = [surface.vertices.len(), surface.triangles.len()];
        for (element, pair) in self.pairs.vertex_triangle.iter().enumerate() {
            for (&index, &len) in pair.iter().zip(&lists) {
                if index as usize >= len {
                    return Err(out_of_range(
                        ContactBuffer::VertexTrianglePairs,
                        element,
                        index,
                    ));
                }
            }
        }
        for (element, pair) in self.pairs.edge_edge.iter().enumerate() {
            let beyond = |&&index: &&u32| index as usize >= surface.edges.len();
            if let Some(&index) = pair.iter().find(beyond) {
                return Err(out_of_range(ContactBuffer::EdgeEdgePairs, element, index));
            }
        }
        for (buffer, list) in [
            (ContactBuffer::Positions, positions),
            (ContactBuffer::RestPositions, self.rest_positions),
        ] {
            if let Some(vertex) = list.iter().position(|x| !x.is_finite()) {
                return Err(ContactError::NonFinitePosition { buffer, vertex });
            }
        }
        Ok(())
    }

    /// Calls `visit` on every candidate pair, point–triangle pairs first, each list in order
    /// (the indices checked by [`check`](Self::check); a pair that fails a look-up is skipped).
    pub(crate) fn for_each_pair(&self, positions: &[Vec3], mut visit: impl FnMut(Pair)) {
        let surface = &self.surface;
        let point = |index: u32| positions.get(index as usize).copied();
        let rest = |index: u32| self.rest_positions.get(index as usize).copied();
        for &[vertex, triangle] in self.pairs.vertex_triangle {
            let (Some(&p), Some(&[t0, t1, t2])) = (
                surface.vertices.get(vertex as usize),
                surface.triangles.get(triangle as usize),
            ) else {
                continue;
            };
            let vertices = [p, t0, t1, t2];
            if let [Some(a), Some(b), Some(c), Some(d)] = vertices.map(point) {
                visit(Pair::PointTriangle(vertices, [a, b, c, d]));
            }
        }
        for &[first, second] in self.pairs.edge_edge {
            let (Some(&[a0, a1]), Some(&[b0, b1])) = (
                surface.edges.get(first as usize),
                surface.edges.get(second as usize),
            ) else {
                continue;
            };
            let vertices = [a0, a1, b0, b1];
            let (
                [Some(p0), Some(p1), Some(p2), Some(p3)],
                [Some(r0), Some(r1), Some(r2), Some(r3)],
            ) = (vertices.map(point), vertices.map(rest))
            else {
                continue;
            };
            let threshold = edge_edge_mollifier_threshold(r0, r1, r2, r3);
            visit(Pair::EdgeEdge(vertices, [p0, p1, p2, p3], threshold));
        }
    }

    /// The contact energy `B` (J) at `positions` (m, one per vertex): the pairs' values summed
    /// in order (point–triangle pairs, then edge–edge pairs); `+inf` if a pair touches
    /// (`d^2 <= 0`), never NaN.
    ///
    /// # Errors
    /// All before anything is computed: [`ContactError::Gap`] or [`ContactError::Stiffness`]
    /// for a gap or stiffness that is not finite and `>= 0`; [`ContactError::BufferLength`]
    /// naming [`ContactBuffer::RestPositions`] if the rest positions and the positions differ
    /// in length; [`ContactError::IndexOutOfRange`] for the first surface vertex, edge or
    /// triangle (in that order) naming a vertex beyond the positions, then for the first
    /// vertex–triangle or edge–edge pair naming a primitive beyond the surface's lists;
    /// [`ContactError::NonFinitePosition`] for the first NaN or infinite position, then rest
    /// position.
    pub fn energy(&self, positions: &[Vec3]) -> Result<Real, ContactError> {
        self.check(positions)?;
        let mut total: Real = 0.0;
        self.for_each_pair(positions, |pair| total += pair.value(&self.barrier));
        Ok(total)
    }

    /// Adds the gradient `dB/dx` (N) at `positions` into `gradient` (one per vertex) and
    /// returns the energy (J, as [`energy`](Self::energy), up to a pair whose value or gradient
    /// overflows, which counts as `+inf`). A touching pair adds nothing to the gradient. Each
    /// pair's value and gradient are those of [`point_triangle_potential`] and
    /// [`edge_edge_potential`] to the bit, computed without the Hessian.
    ///
    /// # Errors
    /// Those of [`energy`](Self::energy), then [`ContactError::BufferLength`] naming
    /// [`ContactBuffer::Gradient`] if its length is not the positions'. Nothing is written
    /// then.
    pub fn add_gradient(
        &self,
        positions: &[Vec3],
        gradient: &mut [Vec3],
    ) -> Result<Real, ContactError> {
        self.check(positions)?;
        per_vertex_length(ContactBuffer::Gradient, gradient.len(), positions.len())?;
        let mut total: Real = 0.0;
        self.for_each_pair(positions, |pair| {
            let (terms, vertices) = pair.gradient_terms(&self.barrier);
            total += terms.value;
            if !terms.active {
                return;
            }
            for (&vertex, g) in vertices.iter().zip(terms.gradient) {
                if let Some(slot) = gradient.get_mut(vertex as usize) {
                    *slot += g;
                }
            }
        });
        Ok(total)
    }

    /// Adds each vertex's 3x3 diagonal block of the projected Hessian (N/m) at `positions`
    /// into `diagonal` (one per vertex): what a block-Jacobi or Vertex Block Descent solver
    /// needs. Each block is symmetric positive semi-definite.
    ///
    /// # Errors
    /// Those of [`energy`](Self::energy), then [`ContactError::BufferLength`] naming
    /// [`ContactBuffer::HessianDiagonal`] if its length is not the positions'. Nothing is
    /// written then.
    pub fn add_hessian_diagonal(
        &self,
        positions: &[Vec3],
        diagonal: &mut [Mat3],
    ) -> Result<(), ContactError> {
        self.check(positions)?;
        per_vertex_length(
            ContactBuffer::HessianDiagonal,
            diagonal.len(),
            positions.len(),
        )?;
        self.for_each_pair(positions, |pair| {
            let (terms, vertices) = pair.terms(&self.barrier);
            if !terms.active {
                return;
            }
            add_diagonal_blocks(&project(&terms.hessian), vertices, diagonal);
        });
        Ok(())
    }

    /// What a vertex of Vertex Block Descent takes of the contact at `positions`, in one pass
    /// over the pairs: adds each active pair's gradient (N) into `gradient` and the 3x3
    /// diagonal blocks of its projected Hessian (N/m) into `diagonal`, as
    /// [`add_gradient`](Self::add_gradient) and
    /// [`add_hessian_diagonal`](Self::add_hessian_diagonal) do, and lowers each vertex's entry
    /// of `nearest` to the distance (m) of every candidate pair it belongs to (active or not).
    ///
    /// # Errors
    /// Those of [`energy`](Self::energy); the three buffers must have one entry per position
    /// ([`ContactError::BufferLength`] naming [`ContactBuffer::Gradient`],
    /// [`ContactBuffer::HessianDiagonal`] or [`ContactBuffer::Positions`] otherwise). Nothing is
    /// written then.
    pub(crate) fn add_vertex_terms(
        &self,
        positions: &[Vec3],
        gradient: &mut [Vec3],
        diagonal: &mut [Mat3],
        nearest: &mut [Real],
    ) -> Result<(), ContactError> {
        self.check(positions)?;
        let count = positions.len();
        per_vertex_length(ContactBuffer::Gradient, gradient.len(), count)?;
        per_vertex_length(ContactBuffer::HessianDiagonal, diagonal.len(), count)?;
        per_vertex_length(ContactBuffer::Positions, nearest.len(), count)?;
        self.for_each_pair(positions, |pair| {
            let (squared, vertices) = match pair {
                Pair::PointTriangle(vertices, [p, a, b, c]) => {
                    (point_triangle_squared_distance(p, a, b, c), vertices)
                }
                Pair::EdgeEdge(vertices, [a0, a1, b0, b1], _) => {
                    (edge_edge_squared_distance(a0, a1, b0, b1), vertices)
                }
            };
            let distance = math::sqrt(squared.max(0.0));
            for &vertex in &vertices {
                if let Some(slot) = nearest.get_mut(vertex as usize) {
                    *slot = slot.min(distance);
                }
            }
            let (terms, vertices) = pair.terms(&self.barrier);
            if !terms.active {
                return;
            }
            for (&vertex, g) in vertices.iter().zip(terms.gradient) {
                if let Some(slot) = gradient.get_mut(vertex as usize) {
                    *slot += g;
                }
            }
            add_diagonal_blocks(&project(&terms.hessian), vertices, diagonal);
        });
        Ok(())
    }

    /// Writes the projected Hessian (N/m) of every active pair (`0 < d^2 < dhat^2`) at
    /// `positions` to the front of `hessians`, in pair order, and returns that prefix: what
    /// [`add_hessian_product`] multiplies matrix-free. Inactive and touching pairs are left out.
    ///
    /// `hessians` needs one entry per active pair (at most one per candidate pair,
    /// `vertex_triangle.len() + edge_edge.len()`, and in a resting contact far fewer: a fixed
    /// capacity can be sized to the contact expected); entries past the prefix are left as they
    /// were.
    ///
    /// # Errors
    /// Those of [`energy`](Self::energy), with nothing written; then [`ContactError::Capacity`]
    /// naming [`ContactBuffer::PairHessians`] with the number of active pairs if `hessians` is
    /// shorter, when its entries hold unspecified values.
    pub fn pair_hessians<'h>(
        &self,
        positions: &[Vec3],
        hessians: &'h mut [PairHessian],
    ) -> Result<&'h [PairHessian], ContactError> {
        self.check(positions)?;
        let mut active = 0;
        self.for_each_pair(positions, |pair| {
            let (terms, vertices) = pair.terms(&self.barrier);
            if !terms.active {
                return;
            }
            // Once the buffer is full the pairs are only counted (no projection).
            if let Some(slot) = hessians.get_mut(active) {
                *slot = PairHessian {
                    vertices,
                    hessian: project(&terms.hessian),
                };
            }
            active += 1;
        });
        if active > hessians.len() {
            return Err(ContactError::Capacity {
                buffer: ContactBuffer::PairHessians,
                needed: active,
                capacity: hessians.len(),
            });
        }
        let written = active;
        Ok(hessians.get(..written).unwrap_or_default())
    }
}

/// Adds the diagonal blocks of one pair's Hessian to its vertices' entries: block `(k, l)` for
/// every `k`, `l` naming the same vertex (only `k == l` for a pair of four distinct vertices).
fn add_diagonal_blocks(hessian: &[[Mat3; 4]; 4], vertices: [u32; 4], diagonal: &mut [Mat3]) {
    for (row, &vertex_k) in hessian.iter().zip(&vertices) {
        for (block, &vertex_l) in row.iter().zip(&vertices) {
            if vertex_k != vertex_l {
                continue;
            }
            if let Some(slot) = diagonal.get_mut(vertex_k as usize) {
                *slot += *block;
            }
        }
    }
}

/// Adds `H v` into `product`, `H` the sum of the stored pair Hessians `hessians` (N/m, from
/// [`ContactPotential::pair_hessians`]) and `direction` `v` one vector per vertex (so with `v`
/// in m the product is in N). The pairs in order, each slot's row `sum_l H_kl v_l` added to
/// its vertex.
///
/// # Errors
/// [`ContactError::BufferLength`] naming [`ContactBuffer::Product`] if `product` and
/// `direction` differ in length; [`ContactError::IndexOutOfRange`] naming
/// [`ContactBuffer::PairHessians`] for the first pair naming a vertex beyond `direction`.
/// Nothing is written then.
pub fn add_hessian_product(
    hessians: &[PairHessian],
    direction: &[Vec3],
    product: &mut [Vec3],
) -> Result<(), ContactError> {
    per_vertex_length(ContactBuffer::Product, product.len(), direction.len())?;
    for (element, pair) in hessians.iter().enumerate() {
        if let Some(&index) = pair
            .vertices
            .iter()
            .find(|&&index| index as usize >= direction.len())
        {
            return Err(out_of_range(ContactBuffer::PairHessians, element, index));
        }
    }
    for pair in hessians {
        let local = pair.vertices.map(|vertex| {
            direction
                .get(vertex as usize)
                .copied()
                .unwrap_or(Vec3::ZERO)
        });
        for (row, &vertex) in pair.hessian.iter().zip(&pair.vertices) {
            let mut sum = Vec3::ZERO;
            for (block, &v) in row.iter().zip(&local) {
                sum += *block * v;
            }
            if let Some(slot) = product.get_mut(vertex as usize) {
                *slot += sum;
            }
        }
    }
    Ok(())
}

/// [`ContactError::IndexOutOfRange`] of `buffer`'s entry `element`, holding `index`.
#[inline]
fn out_of_range(buffer: ContactBuffer, element: usize, index: u32) -> ContactError {
    ContactError::IndexOutOfRange {
        buffer,
        element,
        index,
    }
}

/// [`ContactError::BufferLength`] of `buffer` unless its length `actual` is `expected`.
#[inline]
fn per_vertex_length(
    buffer: ContactBuffer,
    actual: usize,
    expected: usize,
) -> Result<(), ContactError> {
    if actual == expected {
        Ok(())
    } else {
        Err(ContactError::BufferLength {
            buffer,
            expected,
            actual,
        })
    }
}

mod project;
#[cfg(test)]
mod tests;

use project::project;

//! Continuous collision detection for the contact line search: the largest fraction of a step
//! that a point–triangle or edge–edge pair, or a whole surface, can take without intersecting
//! (`docs/math.md` section 8.8).
//!
//! Additive CCD (Z. Li, D. M. Kaufman, C. Jiang, "Codimensional Incremental Potential
//! Contact", ACM Transactions on Graphics 40(4), 2021, supplementary document: "Additive CCD"):
//! every vertex moves on the straight line from its start to its end position, `x(t) = x0 +
//! t (x1 - x0)` for `t` in `[0, 1]`. The distance `d(t)` of a pair then changes no faster than
//! `l`, the largest relative speed of its primitives (the displacements less their mean: one
//! side's largest plus the other side's largest), so from a time `t` where the distance is `d`
//! the pair cannot touch before `t + d / l`. The pair advances by a fraction of that bound at
//! a time and stops at the first time its distance falls below the target gap `s d(0)`.
//!
//! # The guarantee
//! With `c0 = d(0) - xi` the pair's clearance at the start (`xi` the rounding floor below), the
//! time `t*` returned has, for the exact straight-line motion of the given (rounded) inputs
//! and as long as every computed distance errs by less than `xi`:
//! * the two primitives do not intersect at any `t` in `[0, t*]`: their distance stays above
//!   `(1 - STEP_FRACTION) s c0` (`0.01 c0` for the default `s = 0.1`): over each advance it
//!   falls by at most `STEP_FRACTION` of the clearance it started from (the first advance:
//!   `1 - s`), and every accepted time has a clearance of at least `s c0`;
//! * where the target gap stopped it (not `t* = 1`, not the iteration cap), `d(t*) >= s c0`;
//! * so `t*` is never after the first time of contact, and a line search that stays within it
//!   never lets a pair pass through another.
//!
//! Conditions: the start is intersection free (a pair touching at the start gets `t* = 0`),
//! and the motion is the straight line from start to end (the caller's step, as the line
//! search takes it: `start + t (end - start)`, evaluated as [`lerp`] does). The few-ulp
//! rounding of the speed bound is covered by the margins `1 - STEP_FRACTION` and `s`.
//!
//! # Rounding floor
//! Distances are computed from rounded positions: `x(t)` carries an error of a few ulp of the
//! largest coordinate, and the distance formulas add a few ulp of the primitives' size. The
//! pair's distance is therefore taken as `d - xi` with `xi = ROUNDING_FLOOR * EPSILON * scale`
//! (`scale` the largest absolute coordinate of the pair's eight start and end points), the
//! thickness `xi` of Additive CCD: the computed distance overestimates the true one by less
//! than `xi` (measured: at most `0.84 EPSILON * scale` in f32 and `0.70 EPSILON * scale` in f64
//! over random well-shaped pairs at up to 100 m from the origin, against `32 EPSILON * scale`;
//! the rounding of `x(t)` alone is bounded by about `9 EPSILON * scale`), so every advance is
//! bounded by the true distance. A pair at most `xi` apart counts as touching.
//!
//! In f32 at `scale = 10` m, `xi = 38` µm (3.8 µm at 1 m, 0.38 mm at 100 m): separations
//! below that are not resolved, and the guarantee (`d > 0` on `[0, t*]`, at least
//! `0.01 (d(0) - xi)`) holds for pairs that start more than `xi` apart. In f64, `xi = 7e-14` m
//! at 10 m. A sliver triangle (smallest angle `theta`) adds up to
//! `EPSILON * size / sin(theta)` to the distance's error, which the floor covers only for
//! `sin(theta)` above about `size / (ROUNDING_FLOOR * scale)`; keep boundary triangles well
//! shaped, as the elastic model does.
//!
//! # Failure modes
//! Non-finite positions, or coordinates so large that squared distances overflow: `t* = 0`
//! (refuse to move). No relative motion: `t* = 1`. A pair sliding along another at a distance
//! `d` much smaller than the step's length `l` needs about `l / (0.9 d)` iterations; after
//! [`MAX_ITERATIONS`] the time reached so far is returned, which is still conservative (never
//! past the impact), only smaller than necessary. Nothing panics, nothing allocates, and the
//! same input gives the same bits on every target (fixed order of operations, no fused
//! multiply-add, `sqrt` correctly rounded).

// The tests widen `Real` to f64 for their reference, a no-op cast in the f64 copy.
#[cfg(test)]
#[allow(clippy::unnecessary_cast)]
mod tests;

use crate::error::{ContactBuffer, ContactError};

use super::super::super::math::sqrt;
use super::super::super::types::{Real, Vec3};
use super::boundary::ContactSurface;
use super::broad_phase::CandidatePairs;
use super::distance::{edge_edge_squared_distance, point_triangle_squared_distance};

/// The most distance evaluations one pair makes after its first (the bound on the work of
/// [`point_triangle_ccd`] and [`edge_edge_ccd`]); at the cap the conservative time reached so
/// far is returned. 10 000 lets a pair slide about 9 000 times its distance within one step.
pub const MAX_ITERATIONS: u32 = 10_000;

/// The fraction of the Lipschitz bound `d / l` taken by every advance after the first
/// (Additive CCD's rescaling 0.9): the distance stays above `1 - 0.9 = 0.1` of its value at the
/// last accepted time.
pub const STEP_FRACTION: Real = 0.9;

/// The rounding floor `xi = ROUNDING_FLOOR * EPSILON * scale` (m) taken off every computed
/// distance, `scale` the pair's largest absolute coordinate (see the
/// [module docs](self#rounding-floor)).
pub const ROUNDING_FLOOR: Real = 32.0;

/// The fraction `s` of a pair's start distance it must keep at the time returned (Additive
/// CCD's minimum separation): strictly between 0 and 1.
///
/// The first advance takes `1 - s` of the distance bound, and a pair stops once its distance
/// falls below `s d(0)`. A small `s` lets pairs come closer (a longer step) in more iterations;
/// a large one stops them earlier.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Separation(Real);

impl Separation {
    /// `s = 0.1`, the value of Li et al. 2021.
    pub const DEFAULT: Separation = Separation(0.1);

    /// The separation `fraction`, or `None` unless `0 < fraction < 1`.
    #[inline]
    #[must_use]
    pub fn new(fraction: Real) -> Option<Separation> {
        (fraction > 0.0 && fraction < 1.0).then_some(Separation(fraction))
    }

    /// The fraction `s` (dimensionless).
    #[inline]
    #[must_use]
    pub fn fraction(self) -> Real {
        self.0
    }
}

impl Default for Separation {
    #[inline]
    fn default() -> Self {
        Separation::DEFAULT
    }
}

/// The candidate pair that limited a [`StepBound`]: the pair as the broad phase wrote it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LimitingPair {
    /// `[vertex, triangle]`: positions in the surface's vertex and triangle lists.
    VertexTriangle([u32; 2]),
    /// `[edge, other]`: positions in the surface's edge list.
    EdgeEdge([u32; 2]),
}

/// How far a whole surface can move along a step: what [`step_bound`] returns.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StepBound {
    /// The fraction of the step, in `[0, 1]`, within which no candidate pair intersects: the
    /// minimum of the pairs' times of impact.
    pub alpha: Real,
    /// The first pair (vertex–triangle pairs before edge–edge pairs, each in their sorted
    /// order) whose time of impact is `alpha`; `None` when `alpha = 1`.
    pub limited_by: Option<LimitingPair>,
}

/// The position at `t` of a vertex moving from `start` to `end`: `start + t (end - start)`,
/// the one formula every time here is evaluated with (use it for the step the line search
/// takes, so that its positions at `alpha` are those checked here).
#[inline]
#[must_use]
pub fn lerp(start: Vec3, end: Vec3, t: Real) -> Vec3 {
    start + (end - start) * t
}

/// The conservative time of impact, in `[0, 1]`, of the point `start[0]` and the triangle
/// `start[1..4]` moving linearly to `end` (slots `[p, t0, t1, t2]`, m), keeping the separation
/// `separation` (see the [module docs](self) for the guarantee, its conditions and the
/// rounding floor).
///
/// Returns 1 if they never come closer than the target gap during the step, 0 if they touch
/// at the start or an input is not finite.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::ccd::{Separation, lerp, point_triangle_ccd};
/// use softfem::step::contact::distance::point_triangle_squared_distance;
///
/// // A point falls from 1 m above a triangle's interior to 1 m below: impact at t = 0.5.
/// let triangle = [Vec3::ZERO, Vec3::X, Vec3::Y];
/// let start = [Vec3::new(0.2, 0.2, 1.0), triangle[0], triangle[1], triangle[2]];
/// let end = [Vec3::new(0.2, 0.2, -1.0), triangle[0], triangle[1], triangle[2]];
/// let t = point_triangle_ccd(start, end, Separation::DEFAULT);
/// assert!(t <= 0.5 && t > 0.44, "{t}");
///
/// // At t the point is still above the triangle, by about s d(0) = 0.1 m.
/// let p = lerp(start[0], end[0], t);
/// let d2 = point_triangle_squared_distance(p, triangle[0], triangle[1], triangle[2]);
/// assert!(d2 > 0.09 * 0.09);
/// ```
#[must_use]
pub fn point_triangle_ccd(start: [Vec3; 4], end: [Vec3; 4], separation: Separation) -> Real {
    time_of_impact(start, end, 1, point_triangle, separation, 1.0)
}

/// The conservative time of impact, in `[0, 1]`, of the edges `start[0] start[1]` and
/// `start[2] start[3]` moving linearly to `end` (slots `[ea0, ea1, eb0, eb1]`, m), keeping the
/// separation `separation`: as [`point_triangle_ccd`].
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::ccd::{Separation, edge_edge_ccd};
///
/// // An edge along x drops from z = 1 through an edge along y at z = 0: impact at t = 0.5.
/// let (a0, a1) = (Vec3::new(-1.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0));
/// let (b0, b1) = (Vec3::new(0.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
/// let drop = Vec3::new(0.0, 0.0, -2.0);
/// let t = edge_edge_ccd([a0, a1, b0, b1], [a0 + drop, a1 + drop, b0, b1], Separation::DEFAULT);
/// assert!(t <= 0.5 && t > 0.44, "{t}");
/// ```
#[must_use]
pub fn edge_edge_ccd(start: [Vec3; 4], end: [Vec3; 4], separation: Separation) -> Real {
    time_of_impact(start, end, 2, edge_edge, separation, 1.0)
}

/// The largest fraction `alpha` in `[0, 1]` of the step from `start` to `end` (m, one position
/// per vertex of every body) such that no candidate pair of `surface` in `pairs` (from
/// [`motion_pairs`](super::broad_phase::motion_pairs) over the same motion) intersects at any
/// time in `[0, alpha]`, with the pair that limited it.
///
/// `alpha` is the minimum of the pairs' [`point_triangle_ccd`] and [`edge_edge_ccd`] times,
/// taken over the vertex–triangle pairs and then the edge–edge pairs in the order given (the
/// broad phase's sorted order), so the result, and which pair is named, is the same on every
/// target. Each pair stops its iterations once it passes the smallest time found so far (the
/// result is the same as evaluating every pair to the end), and the scan stops at `alpha = 0`.
///
/// # Errors
/// Checked before any time is computed, in this order: [`ContactError::BufferLength`] naming
/// [`ContactBuffer::EndPositions`] if `end` and `start` differ in length;
/// [`ContactError::NonFinitePosition`] for the first NaN or infinite start, then end, position;
/// [`ContactError::IndexOutOfRange`] naming [`ContactBuffer::VertexTrianglePairs`] or
/// [`ContactBuffer::EdgeEdgePairs`] (the pair's position in that list as `element`, the
/// out-of-range list position as `index`) for the first pair that names a primitive the
/// surface does not have, and naming [`ContactBuffer::Vertices`], [`ContactBuffer::Edges`] or
/// [`ContactBuffer::Triangles`] for the first primitive a pair uses that names a vertex beyond
/// `start`.
pub fn step_bound(
    start: &[Vec3],
    end: &[Vec3],
    surface: &ContactSurface<'_>,
    pairs: &CandidatePairs<'_>,
    separation: Separation,
) -> Result<StepBound, ContactError> {
    if end.len() != start.len() {
        return Err(ContactError::BufferLength {
            buffer: ContactBuffer::EndPositions,
            expected: start.len(),
            actual: end.len(),
        });
    }
    for (positions, buffer) in [
        (start, ContactBuffer::Positions),
        (end, ContactBuffer::EndPositions),
    ] {
        if let Some(vertex) = positions.iter().position(|x| !x.is_finite()) {
            return Err(ContactError::NonFinitePosition { buffer, vertex });
        }
    }
    let motion = Motion {
        start,
        end,
        surface,
    };
    for (element, &pair) in pairs.vertex_triangle.iter().enumerate() {
        motion.vertex_triangle(element, pair)?;
    }
    for (element, &pair) in pairs.edge_edge.iter().enumerate() {
        motion.edge_edge(element, pair)?;
    }

    let mut bound = StepBound {
        alpha: 1.0,
        limited_by: None,
    };
    for (element, &pair) in pairs.vertex_triangle.iter().enumerate() {
        if bound.alpha <= 0.0 {
            return Ok(bound);
        }
        let (from, to) = motion.vertex_triangle(element, pair)?;
        let t = time_of_impact(from, to, 1, point_triangle, separation, bound.alpha);
        if t < bound.alpha {
            bound = StepBound {
                alpha: t,
                limited_by: Some(LimitingPair::VertexTriangle(pair)),
            };
        }
    }
    for (element, &pair) in pairs.edge_edge.iter().enumerate() {
        if bound.alpha <= 0.0 {
            return Ok(bound);
        }
        let (from, to) = motion.edge_edge(element, pair)?;
        let t = time_of_impact(from, to, 2, edge_edge, separation, bound.alpha);
        if t < bound.alpha {
            bound = StepBound {
                alpha: t,
                limited_by: Some(LimitingPair::EdgeEdge(pair)),
            };
        }
    }
    Ok(bound)
}

/// The start and end positions of a surface, for gathering a pair's four points.
struct Motion<'s> {
    start: &'s [Vec3],
    end: &'s [Vec3],
    surface: &'s ContactSurface<'s>,
}

impl Motion<'_> {
    /// The start and end positions of `corners`, or the error naming `buffer`'s `element`.
    fn points<const N: usize>(
        &self,
        corners: [u32; N],
        buffer: ContactBuffer,
        element: u32,
    ) -> Result<([Vec3; N], [Vec3; N]), ContactError> {
        let mut from = [Vec3::ZERO; N];
        let mut to = [Vec3::ZERO; N];
        for ((index, from), to) in corners.into_iter().zip(&mut from).zip(&mut to) {
            let (Some(&a), Some(&b)) = (
                self.start.get(index as usize),
                self.end.get(index as usize),
            ) else {
                return Err(ContactError::IndexOutOfRange {
                    buffer,
                    element: element as usize,
                    index,
                });
            };
            *from = a;
            *to = b;
        }
        Ok((from, to))
    }

    /// The four points of the `element`-th vertex–triangle pair `[vertex, triangle]`.
    fn vertex_triangle(
        &self,
        element: usize,
        [vertex, triangle]: [u32; 2],
    ) -> Result<([Vec3; 4], [Vec3; 4]), ContactError> {
        let missing = |index| ContactError::IndexOutOfRange {
            buffer: ContactBuffer::VertexTrianglePairs,
            element,
            index,
        };
        let &point = self
            .surface
            .vertices
            .get(vertex as usize)
            .ok_or(missing(vertex))?;
        let &corners = self
            .surface
            .triangles
            .get(triangle as usize)
            .ok_or(missing(triangle))?;
        let ([p0], [p1]) = self.points([point], ContactBuffer::Vertices, vertex)?;
        let ([a0, b0, c0], [a1, b1, c1]) =
            self.points(corners, ContactBuffer::Triangles, triangle)?;
        Ok(([p0, a0, b0, c0], [p1, a1, b1, c1]))
    }

    /// The four points of the `element`-th edge–edge pair `[edge, other]`.
    fn edge_edge(
        &self,
        element: usize,
        [edge, other]: [u32; 2],
    ) -> Result<([Vec3; 4], [Vec3; 4]), ContactError> {
        let missing = |index| ContactError::IndexOutOfRange {
            buffer: ContactBuffer::EdgeEdgePairs,
            element,
            index,
        };
        let &ends_a = self.surface.edges.get(edge as usize).ok_or(missing(edge))?;
        let &ends_b = self.surface.edges.get(other as usize).ok_or(missing(other))?;
        let ([a0, a1], [a2, a3]) = self.points(ends_a, ContactBuffer::Edges, edge)?;
        let ([b0, b1], [b2, b3]) = self.points(ends_b, ContactBuffer::Edges, other)?;
        Ok(([a0, a1, b0, b1], [a2, a3, b2, b3]))
    }
}

/// The point–triangle squared distance of slots `[p, t0, t1, t2]`.
fn point_triangle(x: [Vec3; 4]) -> Real {
    let [p, t0, t1, t2] = x;
    point_triangle_squared_distance(p, t0, t1, t2)
}

/// The edge–edge squared distance of slots `[ea0, ea1, eb0, eb1]`.
fn edge_edge(x: [Vec3; 4]) -> Real {
    let [ea0, ea1, eb0, eb1] = x;
    edge_edge_squared_distance(ea0, ea1, eb0, eb1)
}

/// The rounding floor `xi` (m) of a pair moving from `start` to `end`, or `None` if its
/// coordinates are not finite or so large that its squared distances could overflow.
fn rounding_floor(start: &[Vec3; 4], end: &[Vec3; 4]) -> Option<Real> {
    let mut scale: Real = 0.0;
    for x in start.iter().chain(end) {
        if !x.is_finite() {
            return None;
        }
        scale = scale.max(x.abs().max_element());
    }
    // Any two points of the pair's motion are at most `2 sqrt(3) scale` apart: their squared
    // distance (and the formulas' intermediate products, of the same order) stays finite.
    let reach = scale * 8.0;
    (reach * reach).is_finite().then_some(ROUNDING_FLOOR * Real::EPSILON * scale)
}

/// The bound `l` (m per unit of `t`) on the rate of change of the distance: the displacements
/// less their mean (a common translation changes no distance), the largest of the first
/// `split` slots plus the largest of the others.
fn relative_speed(start: &[Vec3; 4], end: &[Vec3; 4], split: usize) -> Real {
    let [d0, d1, d2, d3] = displacements(start, end);
    let mean = (d0 + d1 + d2 + d3) * 0.25;
    let (mut first, mut second): (Real, Real) = (0.0, 0.0);
    for (k, moved) in [d0, d1, d2, d3].into_iter().enumerate() {
        let relative = moved - mean;
        let side = if k < split { &mut first } else { &mut second };
        *side = side.max(relative.dot(relative));
    }
    sqrt(first) + sqrt(second)
}

/// `end - start` slot by slot.
fn displacements(start: &[Vec3; 4], end: &[Vec3; 4]) -> [Vec3; 4] {
    let [s0, s1, s2, s3] = *start;
    let [e0, e1, e2, e3] = *end;
    [e0 - s0, e1 - s1, e2 - s2, e3 - s3]
}

/// The four points at `t` of a pair moving from `start` to `end`.
fn positions_at(start: &[Vec3; 4], end: &[Vec3; 4], t: Real) -> [Vec3; 4] {
    let [s0, s1, s2, s3] = *start;
    let [e0, e1, e2, e3] = *end;
    [lerp(s0, e0, t), lerp(s1, e1, t), lerp(s2, e2, t), lerp(s3, e3, t)]
}

/// Additive CCD (Li et al. 2021, supplementary Algorithm 1) with the thickness `xi` of the
/// rounding floor, stopped at `t_max`: the returned time is `min(t_max, t*)`, `t*` the time
/// with `t_max = 1` (the iterations are the same up to `t_max`).
fn time_of_impact(
    start: [Vec3; 4],
    end: [Vec3; 4],
    split: usize,
    squared_distance: fn([Vec3; 4]) -> Real,
    separation: Separation,
    t_max: Real,
) -> Real {
    let Some(xi) = rounding_floor(&start, &end) else {
        return 0.0;
    };
    // `d - xi`: at most the true distance of the pair at `t`.
    let clearance = |t: Real| sqrt(squared_distance(positions_at(&start, &end, t))) - xi;
    let start_clearance = clearance(0.0);
    if start_clearance.is_nan() || start_clearance <= 0.0 {
        return 0.0;
    }
    let speed = relative_speed(&start, &end, split);
    if speed <= 0.0 {
        return t_max;
    }
    let s = separation.fraction();
    let gap = s * start_clearance;
    let mut t: Real = 0.0;
    // Over `[t, t + step]` the distance falls by at most `speed * step`, a fraction of the
    // clearance at `t`: the pair cannot touch before `next`.
    let mut step = (1.0 - s) * start_clearance / speed;
    for _ in 0..MAX_ITERATIONS {
        let next = t + step;
        if next.is_nan() || next >= 1.0 {
            return t_max;
        }
        let at_next = clearance(next);
        // Stop at the last accepted time once the pair is within the target gap. At `t = 0`
        // the first advance kept `s` of the clearance in exact arithmetic; a computed value
        // below the gap there is rounding, and below zero (or NaN) a contradiction: refuse.
        let within_gap = at_next.is_nan() || at_next < gap;
        if (t > 0.0 && within_gap) || at_next.is_nan() || at_next <= 0.0 {
            return t.min(t_max);
        }
        t = next;
        if t >= t_max {
            return t_max;
        }
        step = STEP_FRACTION * at_next / speed;
    }
    t.min(t_max)
}

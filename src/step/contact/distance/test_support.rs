//! What the distance tests share: a deterministic random source, rigid motions, and central
//! finite differences of a function of four points.

use super::super::super::super::types::{Mat3, Quat, Real, Vec3};

/// Marsaglia's xorshift64: deterministic, no dependency.
pub(super) struct XorShift(u64);

impl XorShift {
    pub(super) fn new(seed: u64) -> Self {
        XorShift(seed.max(1))
    }

    /// Uniform in `[lo, hi)`.
    pub(super) fn uniform(&mut self, lo: Real, hi: Real) -> Real {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        let unit = (self.0 >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * unit as Real
    }

    pub(super) fn point(&mut self, half_width: Real) -> Vec3 {
        Vec3::new(
            self.uniform(-half_width, half_width),
            self.uniform(-half_width, half_width),
            self.uniform(-half_width, half_width),
        )
    }

    /// Four points: the first in a cube of half-width `first`, the others of half-width 1.
    pub(super) fn points(&mut self, first: Real) -> [Vec3; 4] {
        [self.point(first), self.point(1.0), self.point(1.0), self.point(1.0)]
    }

    /// A rotation drawn from a random axis and angle.
    pub(super) fn rotation(&mut self) -> Quat {
        let axis = self.point(1.0) + Vec3::new(0.1, 0.2, 0.3);
        Quat::from_axis_angle(axis.normalize(), self.uniform(-3.0, 3.0))
    }
}

/// Whether this copy of the tests runs in f64 (finite differences tight) or f32 (loose).
pub(super) fn double() -> bool {
    Real::EPSILON < 1e-10
}

/// `points` with coordinate `coordinate` of point `point` moved by `step`.
pub(super) fn moved(
    mut points: [Vec3; 4],
    point: usize,
    coordinate: usize,
    step: Real,
) -> [Vec3; 4] {
    points[point][coordinate] += step;
    points
}

/// The largest absolute difference between `gradient` and the central differences of `value`
/// at `points`, over the largest gradient component (or 1 if larger).
pub(super) fn gradient_error(
    value: impl Fn([Vec3; 4]) -> Real,
    points: [Vec3; 4],
    gradient: [Vec3; 4],
    step: Real,
) -> Real {
    let mut error: Real = 0.0;
    let mut scale: Real = 1.0;
    for (k, exact) in gradient.iter().enumerate() {
        for i in 0..3 {
            let fd = (value(moved(points, k, i, step)) - value(moved(points, k, i, -step)))
                / (2.0 * step);
            error = error.max((fd - exact[i]).abs());
            scale = scale.max(exact[i].abs());
        }
    }
    error / scale
}

/// The largest absolute difference between `hessian` and the mixed central second differences
/// of `value` at `points`, over the largest Hessian entry (or 1 if larger).
pub(super) fn hessian_error(
    value: impl Fn([Vec3; 4]) -> Real,
    points: [Vec3; 4],
    hessian: [[Mat3; 4]; 4],
    step: Real,
) -> Real {
    let mut error: Real = 0.0;
    let mut scale: Real = 1.0;
    for (k, row) in hessian.iter().enumerate() {
        for (l, block) in row.iter().enumerate() {
            for i in 0..3 {
                for j in 0..3 {
                    let at = |sk: Real, sl: Real| value(moved(moved(points, k, i, sk), l, j, sl));
                    let fd = (at(step, step) - at(step, -step) - at(-step, step)
                        + at(-step, -step))
                        / (4.0 * step * step);
                    // Row i, column j of block (k, l).
                    let exact = block.col(j)[i];
                    error = error.max((fd - exact).abs());
                    scale = scale.max(exact.abs());
                }
            }
        }
    }
    error / scale
}

/// The FD steps and tolerances of this precision: `(gradient step, gradient tolerance, Hessian
/// step, Hessian tolerance)`, relative to the largest entry. Central differences err by `h^2`
/// times the function's third or fourth derivatives (truncation) plus `eps / h` (gradient) or
/// `eps / h^2` (Hessian) times its value (rounding). f64: `h = 1e-5` and `5e-5` keep both near
/// `1e-7` at the distances tested (`d >= 0.2`; measured at most 2e-9 and 2.6e-7 over all kinds
/// and the mollifier); tolerance `1e-6`. f32: only loose, `eps / h^2` is already `1e-3` at `h =
/// 1e-2` (measured at most 2.0e-3 and 4.1e-3); tolerance `2e-2` and `5e-2`.
pub(super) fn fd_settings() -> (Real, Real, Real, Real) {
    if double() {
        (1e-5, 1e-6, 5e-5, 1e-6)
    } else {
        (1e-2, 2e-2, 1e-2, 5e-2)
    }
}

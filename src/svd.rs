//! Rotation-variant singular value decomposition of 3x3 matrices (`SPEC.md` section 3).
//!
//! `a = u * diag(sigma) * v^T` with `u`, `v` proper rotations (`det = +1`) and the singular values
//! sorted `sigma.x >= sigma.y >= |sigma.z|`. An inverted `a` (`det a < 0`) carries its sign on the
//! smallest value: `sigma.z < 0` exactly when `det a < 0`. This is the convention elasticity needs:
//! the principal stretches of an inverted element stay continuous and the rotation stays a rotation.
//!
//! # Algorithm
//! 1. Scale `a` by a power of two so its largest entry lies in `[1, 2)` (exact; keeps `a^T a` clear
//!    of overflow and underflow for inputs from `1e-30` to `1e30` and beyond).
//! 2. Cyclic Jacobi sweeps with exact rotations on the symmetric `a^T a` give `v`.
//! 3. `b = a v`, columns sorted by decreasing norm (a swap negates one column so `det v` stays `+1`).
//! 4. Givens QR of `b` gives `u` and an upper-triangular `r` whose diagonal is the signed singular
//!    values.
//! 5. A last Jacobi step on the lower 2x2 block of `r`, computed from `r` itself rather than from
//!    `a^T a`, resolves the two smaller singular values when both are far below `||a||`: there
//!    `a^T a` has lost them to rounding (its entries carry only `eps ||a||^2`), and skipping this
//!    step is what limits Jacobi-on-`a^T a` codes to about `sqrt(eps)` relative accuracy.
//!
//! Every step is straight-line code on scalars apart from a few data-independent selects, so the
//! routine lifts to SIMD lanes unchanged.
//!
//! # Accuracy
//! For every finite input whose singular values stay below `Real::MAX`: no NaN or inf, `u` and `v`
//! orthonormal to a few `eps`, reconstruction error a small multiple of `eps * ||a||` (see the
//! README for the measured maxima per class of matrix). The number of sweeps trades accuracy for
//! speed: see [`svd3_sweeps`].

use super::math::{self, select};
use super::types::{Mat3, Real, Vec3};

/// Jacobi sweeps used by [`svd3`]: 4 in both precisions (each sweep is three rotations). With 3,
/// f32 reconstruction errors reach 1e-5 on some random matrices; with 4 the worst seen over
/// 300 000 matrices of six kinds is 5.4e-7 (f32) and 1.3e-15 (f64), and more sweeps change nothing.
pub const DEFAULT_SWEEPS: u32 = math::DEFAULT_SVD_SWEEPS;

/// A rotation-variant SVD: `a = u * diag(sigma) * v^T`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Svd3 {
    /// Left singular vectors as columns; a proper rotation (`det u = +1`).
    pub u: Mat3,
    /// Signed singular values, `sigma.x >= sigma.y >= |sigma.z|`; `sigma.z < 0` iff `det a < 0`.
    pub sigma: Vec3,
    /// Right singular vectors as columns; a proper rotation (`det v = +1`).
    pub v: Mat3,
}

impl Svd3 {
    /// The matrix `u * diag(sigma) * v^T` this decomposition represents.
    #[inline]
    #[must_use]
    pub fn to_mat3(&self) -> Mat3 {
        self.u * Mat3::from_diagonal(self.sigma) * self.v.transpose()
    }
}

/// The rotation-variant SVD of `a` with [`DEFAULT_SWEEPS`] Jacobi sweeps.
///
/// Never panics and always terminates. A non-finite `a` (any NaN or inf entry) returns
/// `u = v = identity` and `sigma = (NaN, NaN, NaN)`, so the failure propagates instead of
/// hiding. The zero matrix returns `u = v = identity`, `sigma = 0`.
///
/// ```
/// use softfem::glam::{Mat3, Vec3};
/// use softfem::svd::svd3;
///
/// // A reflection scaled by 2: inverted, so the smallest singular value is negative.
/// let a = Mat3::from_diagonal(Vec3::new(2.0, -2.0, 2.0));
/// let svd = svd3(a);
/// assert!((svd.sigma - Vec3::new(2.0, 2.0, -2.0)).abs().max_element() < 1e-6);
/// assert!((svd.u.determinant() - 1.0).abs() < 1e-6);
/// assert!((svd.v.determinant() - 1.0).abs() < 1e-6);
/// assert!(svd.to_mat3().abs_diff_eq(a, 1e-5));
/// ```
#[inline]
#[must_use]
pub fn svd3(a: Mat3) -> Svd3 {
    svd3_sweeps(a, DEFAULT_SWEEPS)
}

/// The rotation-variant SVD of `a` with `sweeps` cyclic Jacobi sweeps (the speed/accuracy knob).
///
/// The result always satisfies the structural contract (rotations with `det = +1`, sorted signed
/// values); only its accuracy depends on `sweeps`. `0` skips the Jacobi stage and amounts to a QR
/// decomposition with one 2x2 cleanup, accurate only for nearly diagonal-times-rotation input.
/// Non-finite and zero input behave as in [`svd3`].
#[must_use]
pub fn svd3_sweeps(a: Mat3, sweeps: u32) -> Svd3 {
    if !a.is_finite() {
        return Svd3 {
            u: Mat3::IDENTITY,
            sigma: Vec3::NAN,
            v: Mat3::IDENTITY,
        };
    }
    let max_abs = a
        .x_axis
        .abs()
        .max(a.y_axis.abs())
        .max(a.z_axis.abs())
        .max_element();
    if max_abs == 0.0 {
        return Svd3 {
            u: Mat3::IDENTITY,
            sigma: Vec3::ZERO,
            v: Mat3::IDENTITY,
        };
    }

    // Step 1: bring the largest entry into [1, 2). Two factors, because 2^-e alone leaves the
    // normal range for the extreme exponents of subnormal or huge inputs.
    let e = math::exponent(max_abs);
    let (e_lo, e_hi) = (e / 2, e - e / 2);
    let b = a * math::pow2(-e_lo) * math::pow2(-e_hi);

    let (u, sigma, v) = decompose_scaled(b, sweeps);
    let sigma = sigma * math::pow2(e_lo) * math::pow2(e_hi);
    Svd3 { u, sigma, v }
}

/// Steps 2-5 of the algorithm on a matrix whose largest entry lies in `[1, 2)`.
#[inline(always)]
fn decompose_scaled(a: Mat3, sweeps: u32) -> (Mat3, Vec3, Mat3) {
    // Step 2: Jacobi on the symmetric a^T a, accumulating v.
    let ata = a.transpose() * a;
    let mut s = SymmetricEntries {
        s00: ata.x_axis.x,
        s11: ata.y_axis.y,
        s22: ata.z_axis.z,
        s01: ata.y_axis.x,
        s02: ata.z_axis.x,
        s12: ata.z_axis.y,
    };
    let mut v = Mat3::IDENTITY;
    for _ in 0..sweeps {
        let r = jacobi_rotation(s.s00, s.s11, s.s01);
        r.apply_symmetric(&mut s.s00, &mut s.s11, &mut s.s01, &mut s.s02, &mut s.s12);
        r.rotate_columns(&mut v.x_axis, &mut v.y_axis);

        let r = jacobi_rotation(s.s00, s.s22, s.s02);
        r.apply_symmetric(&mut s.s00, &mut s.s22, &mut s.s02, &mut s.s01, &mut s.s12);
        r.rotate_columns(&mut v.x_axis, &mut v.z_axis);

        let r = jacobi_rotation(s.s11, s.s22, s.s12);
        r.apply_symmetric(&mut s.s11, &mut s.s22, &mut s.s12, &mut s.s01, &mut s.s02);
        r.rotate_columns(&mut v.y_axis, &mut v.z_axis);
    }

    // Rounding in the rotations leaves v orthonormal only to ~10 eps after four sweeps, and that
    // error passes straight into the reconstruction (a = b v^T needs v v^T = I). One
    // Newton-Schulz step, v <- v - v (v^T v - I) / 2, squares it away.
    let orthogonality_defect = v.transpose() * v - Mat3::IDENTITY;
    v -= v * orthogonality_defect * 0.5;

    // Step 3: b = a v with columns sorted by decreasing norm.
    let mut b = a * v;
    let mut norms = Vec3::new(
        b.x_axis.length_squared(),
        b.y_axis.length_squared(),
        b.z_axis.length_squared(),
    );
    sort_pair(
        &mut b.x_axis,
        &mut b.y_axis,
        &mut v.x_axis,
        &mut v.y_axis,
        &mut norms.x,
        &mut norms.y,
    );
    sort_pair(
        &mut b.x_axis,
        &mut b.z_axis,
        &mut v.x_axis,
        &mut v.z_axis,
        &mut norms.x,
        &mut norms.z,
    );
    sort_pair(
        &mut b.y_axis,
        &mut b.z_axis,
        &mut v.y_axis,
        &mut v.z_axis,
        &mut norms.y,
        &mut norms.z,
    );

    // Step 4: Givens QR of the first column, b = u r. Rows of r are kept as the columns of `rt`
    // so that every row operation is a column operation on glam vectors.
    let mut rt = b.transpose();
    let mut u = Mat3::IDENTITY;
    let g = Givens::zeroing(rt.x_axis.x, rt.y_axis.x);
    g.rotate_rows(&mut rt.x_axis, &mut rt.y_axis, &mut u.x_axis, &mut u.y_axis);
    let g = Givens::zeroing(rt.x_axis.x, rt.z_axis.x);
    g.rotate_rows(&mut rt.x_axis, &mut rt.z_axis, &mut u.x_axis, &mut u.z_axis);

    // Step 5: the remaining 2x2 block m = [[r11, r12], [r21, r22]] gets its own SVD: a Jacobi
    // rotation from the Gram matrix of m's columns (formed from m itself, scaled to order one,
    // not from a^T a), larger column first, then a Givens rotation that triangularises it. This
    // also completes the QR decomposition.
    let (r11, r12) = (rt.y_axis.y, rt.y_axis.z);
    let (r21, r22) = (rt.z_axis.y, rt.z_axis.z);
    let block_max = r11.abs().max(r12.abs()).max(r21.abs()).max(r22.abs());
    let inv_scale = 1.0 / block_max.max(math::TINY);
    let (m11, m12, m21, m22) = (
        r11 * inv_scale,
        r12 * inv_scale,
        r21 * inv_scale,
        r22 * inv_scale,
    );
    let g11 = m11 * m11 + m21 * m21;
    let g22 = m12 * m12 + m22 * m22;
    let g12 = m11 * m12 + m21 * m22;
    let rot = jacobi_rotation(g11, g22, g12).larger_first(g11, g22, g12);
    // Columns 1 and 2 of r are the y and z components of the row vectors in `rt`.
    let mut col1 = Vec3::new(rt.x_axis.y, r11, r21);
    let mut col2 = Vec3::new(rt.x_axis.z, r12, r22);
    rot.rotate_columns(&mut col1, &mut col2);
    rot.rotate_columns(&mut v.y_axis, &mut v.z_axis);
    let g = Givens::zeroing(col1.y, col1.z);
    let r11 = g.c * col1.y + g.s * col1.z;
    let r22 = g.c * col2.z - g.s * col2.y;
    g.rotate_basis(&mut u.y_axis, &mut u.z_axis);

    // Rounding (repeated singular values) or too few sweeps can leave the values slightly out of
    // order; a three-comparator sorting network restores the contract exactly.
    let mut sorted = Svd3 {
        u,
        sigma: Vec3::new(rt.x_axis.x, r11, r22),
        v,
    };
    sorted.order_first_pair();
    sorted.order_second_pair();
    sorted.order_first_pair();
    (sorted.u, sorted.sigma, sorted.v)
}

impl Svd3 {
    /// Ensures `sigma.x >= sigma.y` (both non-negative) by swapping the first two singular
    /// triplets; the third pair of vectors is negated so that both determinants stay `+1`.
    #[inline(always)]
    fn order_first_pair(&mut self) {
        let swap = self.sigma.y > self.sigma.x;
        let (u, v) = (self.u, self.v);
        self.u = Mat3::from_cols(
            select_vec(swap, u.y_axis, u.x_axis),
            select_vec(swap, u.x_axis, u.y_axis),
            select_vec(swap, -u.z_axis, u.z_axis),
        );
        self.v = Mat3::from_cols(
            select_vec(swap, v.y_axis, v.x_axis),
            select_vec(swap, v.x_axis, v.y_axis),
            select_vec(swap, -v.z_axis, v.z_axis),
        );
        let (s0, s1) = (self.sigma.x, self.sigma.y);
        self.sigma.x = select(swap, s1, s0);
        self.sigma.y = select(swap, s0, s1);
    }

    /// Ensures `sigma.y >= |sigma.z|` by swapping the last two singular triplets. The sign of
    /// `sigma.z` (the sign of `det a`) stays on the last value: with `k = sgn(sigma.z)` the new
    /// triplets are `(|s2|, u2, k v2)` and `(k s1, -u1, -k v1)`, whose products are the old ones
    /// and whose bases keep determinant `+1`.
    #[inline(always)]
    fn order_second_pair(&mut self) {
        let swap = self.sigma.z.abs() > self.sigma.y;
        let (u, v) = (self.u, self.v);
        let (s1, s2) = (self.sigma.y, self.sigma.z);
        let k = (1.0 as Real).copysign(s2);
        self.u.y_axis = select_vec(swap, u.z_axis, u.y_axis);
        self.u.z_axis = select_vec(swap, -u.y_axis, u.z_axis);
        self.v.y_axis = select_vec(swap, v.z_axis * k, v.y_axis);
        self.v.z_axis = select_vec(swap, -v.y_axis * k, v.z_axis);
        self.sigma.y = select(swap, s2.abs(), s1);
        self.sigma.z = select(swap, s1 * k, s2);
    }
}

/// `if condition { a } else { b }` on vectors, without a branch.
#[inline(always)]
fn select_vec(condition: bool, a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(
        select(condition, a.x, b.x),
        select(condition, a.y, b.y),
        select(condition, a.z, b.z),
    )
}

/// The six independent entries of a symmetric 3x3 matrix.
struct SymmetricEntries {
    s00: Real,
    s11: Real,
    s22: Real,
    s01: Real,
    s02: Real,
    s12: Real,
}

/// A plane rotation `[[c, s], [-s, c]]` acting on a pair of indices `(p, q)`.
#[derive(Clone, Copy)]
struct JacobiRotation {
    c: Real,
    s: Real,
    /// `s / c`, the tangent used to update the diagonal without cancellation.
    t: Real,
}

/// The rotation that zeroes the off-diagonal of the symmetric 2x2 block `[[app, apq], [apq, aqq]]`
/// (the smaller of the two angles that do, `|theta| <= pi/4`).
///
/// With `d = aqq - app`, `y = 2 apq sgn(d)`, `r = sqrt(d^2 + y^2)` and `den = |d| + r`, the tangent
/// is `t = y / den` (Rutishauser's stable form) and `(c, s) = (den, y) / sqrt(den^2 + y^2)`.
///
/// The inputs are expected on the normalised scale of [`decompose_scaled`] (largest entries of
/// order one). Off-diagonals below [`math::TINY`] are treated as zero: they are far below the
/// rounding of the diagonal, and keeping them would square into subnormals whose lost bits break
/// `c^2 + s^2 = 1`. Written without branches: the guards are selects.
#[inline(always)]
fn jacobi_rotation(app: Real, aqq: Real, apq: Real) -> JacobiRotation {
    let d = aqq - app;
    let y = 2.0 * apq * (1.0 as Real).copysign(d);
    let y = select(y.abs() > math::TINY, y, 0.0);
    let r = math::sqrt(d * d + y * y);
    // den >= TINY keeps d = y = 0 (nothing to rotate) at c = 1, s = 0 instead of 0/0.
    let den = (d.abs() + r).max(math::TINY);
    let inv_h = 1.0 / math::sqrt(den * den + y * y);
    JacobiRotation {
        c: den * inv_h,
        s: y * inv_h,
        t: y / den,
    }
}

impl JacobiRotation {
    /// Applies `J^T S J` to a symmetric matrix given by the entries touched by the pair `(p, q)`
    /// and the remaining index `r`; `apq` becomes zero.
    #[inline(always)]
    fn apply_symmetric(
        &self,
        app: &mut Real,
        aqq: &mut Real,
        apq: &mut Real,
        arp: &mut Real,
        arq: &mut Real,
    ) {
        let shift = self.t * *apq;
        *app -= shift;
        *aqq += shift;
        *apq = 0.0;
        let (rp, rq) = (*arp, *arq);
        *arp = self.c * rp - self.s * rq;
        *arq = self.s * rp + self.c * rq;
    }

    /// Right-multiplies a matrix by `J`, given its columns `p` and `q`.
    #[inline(always)]
    fn rotate_columns(&self, p: &mut Vec3, q: &mut Vec3) {
        let (old_p, old_q) = (*p, *q);
        *p = old_p * self.c - old_q * self.s;
        *q = old_p * self.s + old_q * self.c;
    }

    /// This rotation, followed by a quarter turn when that puts the larger diagonal entry of
    /// `J^T S J` (for `S = [[app, apq], [apq, aqq]]`) first. The quarter turn swaps the two
    /// columns and negates one, so the result is still a rotation.
    #[inline(always)]
    fn larger_first(self, app: Real, aqq: Real, apq: Real) -> Self {
        let shift = self.t * apq;
        let swap = app - shift < aqq + shift;
        JacobiRotation {
            c: select(swap, -self.s, self.c),
            s: select(swap, self.c, self.s),
            t: select(swap, -self.c / self.s, self.t),
        }
    }
}

/// A Givens rotation `[[c, s], [-s, c]]` applied to two rows.
#[derive(Clone, Copy)]
struct Givens {
    c: Real,
    s: Real,
}

impl Givens {
    /// The rotation that maps the pair `(a, b)` to `(sqrt(a^2 + b^2), 0)`.
    ///
    /// On the normalised scale of [`decompose_scaled`]: a pair whose length is below
    /// [`math::TINY`] is left alone (identity), since its squares would be subnormal.
    #[inline(always)]
    fn zeroing(a: Real, b: Real) -> Givens {
        let length = math::sqrt(a * a + b * b);
        let usable = length > math::TINY;
        let inv_length = 1.0 / length.max(math::TINY);
        Givens {
            c: select(usable, a * inv_length, 1.0),
            s: select(usable, b * inv_length, 0.0),
        }
    }

    /// Applies the rotation to rows `p` and `q` of `r` (stored as vectors) and the inverse to
    /// columns `p` and `q` of `u`, so that the product `u r` is unchanged.
    #[inline(always)]
    fn rotate_rows(&self, row_p: &mut Vec3, row_q: &mut Vec3, u_p: &mut Vec3, u_q: &mut Vec3) {
        let (p, q) = (*row_p, *row_q);
        *row_p = p * self.c + q * self.s;
        *row_q = q * self.c - p * self.s;
        self.rotate_basis(u_p, u_q);
    }

    /// Right-multiplies `u` by the transpose of this rotation, given its columns `p` and `q`.
    #[inline(always)]
    fn rotate_basis(&self, u_p: &mut Vec3, u_q: &mut Vec3) {
        let (p, q) = (*u_p, *u_q);
        *u_p = p * self.c + q * self.s;
        *u_q = q * self.c - p * self.s;
    }
}

/// Orders two columns of `b` (and the matching columns of `v`) by decreasing squared norm. A swap
/// negates the new second column so that `det v` stays `+1` and `b = a v` still holds.
#[inline(always)]
fn sort_pair(
    b_p: &mut Vec3,
    b_q: &mut Vec3,
    v_p: &mut Vec3,
    v_q: &mut Vec3,
    norm_p: &mut Real,
    norm_q: &mut Real,
) {
    let swap = *norm_p < *norm_q;
    let (bp, bq, vp, vq, np, nq) = (*b_p, *b_q, *v_p, *v_q, *norm_p, *norm_q);
    *b_p = select_vec(swap, bq, bp);
    *b_q = select_vec(swap, -bp, bq);
    *v_p = select_vec(swap, vq, vp);
    *v_q = select_vec(swap, -vp, vq);
    *norm_p = select(swap, nq, np);
    *norm_q = select(swap, np, nq);
}

//! Rotation-variant singular value decomposition of 3x3 matrices (`docs/math.md` section 3).
//!
//! `a = u * diag(sigma) * v^T` with `u`, `v` proper rotations (`det = +1`) and the singular values
//! sorted `sigma.x >= sigma.y >= |sigma.z|`. An inverted `a` (`det a < 0`) carries its sign on the
//! smallest value: `sigma.z < 0` when `det a < 0` and `sigma.z >= 0` when `det a > 0`, wherever
//! `|sigma.z|` exceeds the decomposition's rounding error (a few `eps * ||a||`); closer to a
//! singular matrix the sign of `sigma.z`, like `det a` computed in floating point, can come out
//! either way (an exactly singular f64 matrix can give `sigma.z = -6e-33`). This is the
//! convention elasticity needs: the principal stretches of an inverted element stay continuous and
//! the rotation stays a rotation.
//!
//! # Algorithm
//! 1. Scale `a` by a power of two so its largest entry lies in `[1, 2)` (exact; keeps `a^T a` clear
//!    of overflow and underflow for inputs from `1e-30` to `1e30` and beyond).
//! 2. Cyclic Jacobi sweeps with exact rotations on the symmetric `a^T a` give `v`, stopping early
//!    once every off-diagonal entry is at most `eps` times the geometric mean of its two diagonal
//!    entries (Demmel and Veselic's criterion; nearly undeformed elements, the common case of a
//!    simulation, often stop after two or three sweeps).
//! 3. `b = a v`, columns sorted by decreasing norm (a swap negates one column so `det v` stays `+1`).
//! 4. Givens QR of `b` gives `u` and an upper-triangular `r` whose diagonal is the signed singular
//!    values.
//! 5. A last Jacobi step on the lower 2x2 block of `r`, computed from `r` itself rather than from
//!    `a^T a`, resolves the two smaller singular values when both are far below `||a||`: there
//!    `a^T a` has lost them to rounding (its entries carry only `eps ||a||^2`), and skipping this
//!    step is what limits Jacobi-on-`a^T a` codes to about `sqrt(eps)` relative accuracy.
//!
//! Every step is straight-line code with selects instead of branches, written once against
//! `Lane`: [`svd3`] runs it on one matrix, [`svd3_lanes`] on [`LANES`] matrices at once in SIMD
//! registers, with bit-identical results per matrix.
//!
//! # Accuracy
//! For every finite input whose singular values stay below `Real::MAX`: no NaN or inf, `u` and `v`
//! orthonormal to a few `eps`, reconstruction error a small multiple of `eps * ||a||` (see the
//! docs/guide/10-performance.md for the measured maxima per class of matrix). Singular values in the subnormal range
//! are rounded to that range's grid, which adds up to one smallest subnormal of absolute error
//! (no format can do better). The number of sweeps trades accuracy for speed: see
//! [`svd3_sweeps`].
//!
//! The structural contract (rotations, `sigma.x >= sigma.y >= |sigma.z|`, only `sigma.z`
//! negative and then `det a < 0`) holds for every finite input, also when the two smaller
//! values lie far below `eps sigma.x` (`diag(1e19, 1, 0.5)` in f32): step 5 then works on the
//! block lifted by an exact power of two, and the QR steps never leave a negative diagonal.
//!
//! The sign of `det a` is carried by the sign bit of `sigma.z`; when `|det a|` is so small that
//! `sigma.z` rounds to zero, it is `-0.0` for an inverted `a`.

use super::lanes::{LANES, Lane, LaneMat3, LaneVec3};
use super::math;
use super::types::{Mat3, Real, Vec3};

#[path = "svd_batch.rs"]
mod batch;
pub(crate) use batch::svd3_of_lanes;
pub use batch::{svd3_batch, svd3_batch_sweeps};

/// The most Jacobi sweeps [`svd3`] runs: 4 in both precisions (each sweep is three rotations;
/// fewer run when the matrix has converged before, see the module documentation). With 3,
/// the worst error on the 3072 matrices of the guide's SVD chart (docs/guide/10-performance.md) is 8.3e-6 (`cargo run
/// --release -p softfem-examples --features charts --bin tradeoffs -- --only svd`); with 4, f32
/// reaches its rounding floor (4.0e-7 over the normal-range classes of `cargo test --release --test
/// kernels svd::report -- --nocapture`, 6.5e-16 in f64), and 5 to 8 sweeps give the same bits.
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

    /// The decomposition whose `u`, `sigma` and `v` are `values[0..9]`, `values[9..12]` and
    /// `values[12..21]` (the matrices columns first); later values are ignored.
    #[inline(always)]
    fn from_values(values: &[Real; 24]) -> Svd3 {
        let [
            u0,
            u1,
            u2,
            u3,
            u4,
            u5,
            u6,
            u7,
            u8,
            s0,
            s1,
            s2,
            v0,
            v1,
            v2,
            v3,
            v4,
            v5,
            v6,
            v7,
            v8,
            ..,
        ] = *values;
        Svd3 {
            u: Mat3::from_cols_array(&[u0, u1, u2, u3, u4, u5, u6, u7, u8]),
            sigma: Vec3::new(s0, s1, s2),
            v: Mat3::from_cols_array(&[v0, v1, v2, v3, v4, v5, v6, v7, v8]),
        }
    }

    /// What [`svd3`] returns for a non-finite input.
    const NON_FINITE: Svd3 = Svd3 {
        u: Mat3::IDENTITY,
        sigma: Vec3::NAN,
        v: Mat3::IDENTITY,
    };

    /// What [`svd3`] returns for the zero matrix.
    const ZERO: Svd3 = Svd3 {
        u: Mat3::IDENTITY,
        sigma: Vec3::ZERO,
        v: Mat3::IDENTITY,
    };

    /// The documented result for an input [`Prescale::of`] rejects: zero or non-finite.
    #[inline(always)]
    fn without_decomposition(a: Mat3) -> Svd3 {
        if a.is_finite() {
            Svd3::ZERO
        } else {
            Svd3::NON_FINITE
        }
    }
}

/// The rotation-variant SVD of `a` with [`DEFAULT_SWEEPS`] Jacobi sweeps.
///
/// Never panics and always terminates. A non-finite `a` (any NaN or inf entry) returns
/// `u = v = identity` and `sigma = (NaN, NaN, NaN)`, so the failure propagates instead of
/// hiding. The zero matrix returns `u = v = identity`, `sigma = 0`. Singular values beyond
/// `Real::MAX` (entries near the top of the range) saturate to infinity.
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

/// The rotation-variant SVD of `a` with at most `sweeps` cyclic Jacobi sweeps (the speed/accuracy
/// knob; sweeps stop early once converged, so a larger count costs nothing on matrices that do
/// not need it).
///
/// The result always satisfies the structural contract (rotations with `det = +1`, sorted signed
/// values); only its accuracy depends on `sweeps`. `0` skips the Jacobi stage and amounts to a QR
/// decomposition with one 2x2 cleanup, accurate only for nearly diagonal-times-rotation input.
/// Non-finite and zero input behave as in [`svd3`].
#[must_use]
pub fn svd3_sweeps(a: Mat3, sweeps: u32) -> Svd3 {
    let Some(prescale) = Prescale::of(a) else {
        return Svd3::without_decomposition(a);
    };
    let (u, sigma, v) = decompose_scaled(LaneMat3::from_mat3(prescale.apply(a)), sweeps);
    Svd3 {
        u: u.to_mat3(),
        sigma: prescale.undo(sigma.to_vec3()),
        v: v.to_mat3(),
    }
}

/// [`svd3`] of [`LANES`] (4) matrices at once, in SIMD registers.
///
/// Each result is bit-for-bit what [`svd3`] returns for the same matrix, including the
/// non-finite and zero cases; the batch only runs faster. Use it when the matrices come in
/// groups, e.g. the deformation gradients of consecutive elements.
///
/// ```
/// use softfem::glam::Mat3;
/// use softfem::lanes::LANES;
/// use softfem::svd::{svd3, svd3_lanes};
///
/// let batch: [Mat3; LANES] =
///     core::array::from_fn(|i| Mat3::from_rotation_x(i as f32) * (1.0 + i as f32));
/// let results = svd3_lanes(&batch);
/// for (a, svd) in batch.iter().zip(&results) {
///     assert_eq!(*svd, svd3(*a));
/// }
/// ```
#[inline]
#[must_use]
pub fn svd3_lanes(a: &[Mat3; LANES]) -> [Svd3; LANES] {
    svd3_lanes_sweeps(a, DEFAULT_SWEEPS)
}

/// [`svd3_sweeps`] of [`LANES`] matrices at once; see [`svd3_lanes`].
#[must_use]
pub fn svd3_lanes_sweeps(a: &[Mat3; LANES], sweeps: u32) -> [Svd3; LANES] {
    let prescales = a.map(Prescale::of);
    // Lanes without a decomposition (zero or non-finite input) run on the identity, which keeps
    // every lane finite, and are replaced afterwards.
    let scaled = core::array::from_fn(|i| match (prescales.get(i), a.get(i)) {
        (Some(Some(prescale)), Some(m)) => prescale.apply(*m),
        _ => Mat3::IDENTITY,
    });
    let (u, sigma, v) = decompose_scaled(LaneMat3::from_matrices(&scaled), sweeps);
    let (u, sigma, v) = (u.to_matrices(), sigma.to_vectors(), v.to_matrices());
    core::array::from_fn(|i| match (prescales.get(i), a.get(i)) {
        (Some(Some(prescale)), _) => Svd3 {
            u: u.get(i).copied().unwrap_or(Mat3::ZERO),
            sigma: prescale.undo(sigma.get(i).copied().unwrap_or(Vec3::ZERO)),
            v: v.get(i).copied().unwrap_or(Mat3::ZERO),
        },
        (_, Some(m)) => Svd3::without_decomposition(*m),
        _ => Svd3::NON_FINITE,
    })
}

/// Step 1: the exact power-of-two scaling that brings the largest entry into `[1, 2)`, as two
/// factors, because `2^-e` alone leaves the normal range for the extreme exponents of subnormal
/// or huge inputs.
#[derive(Clone, Copy)]
struct Prescale {
    e_lo: i32,
    e_hi: i32,
}

impl Prescale {
    /// `None` for the zero matrix and for non-finite input, which have no decomposition to run.
    #[inline(always)]
    fn of(a: Mat3) -> Option<Prescale> {
        let max_abs = a
            .x_axis
            .abs()
            .max(a.y_axis.abs())
            .max(a.z_axis.abs())
            .max_element();
        Prescale::of_max_abs(max_abs, a.is_finite())
    }

    /// [`Prescale::of`] a matrix whose largest entry magnitude is `max_abs`, and which is
    /// `finite` or not (the batched SVD finds both in lanes).
    #[inline(always)]
    fn of_max_abs(max_abs: Real, finite: bool) -> Option<Prescale> {
        if !finite || max_abs == 0.0 {
            return None;
        }
        let e = math::exponent(max_abs);
        Some(Prescale {
            e_lo: e / 2,
            e_hi: e - e / 2,
        })
    }

    #[inline(always)]
    fn apply(self, a: Mat3) -> Mat3 {
        a * math::pow2(-self.e_lo) * math::pow2(-self.e_hi)
    }

    #[inline(always)]
    fn undo(self, sigma: Vec3) -> Vec3 {
        sigma * math::pow2(self.e_lo) * math::pow2(self.e_hi)
    }
}

impl LaneMat3<Real> {
    #[inline(always)]
    fn from_mat3(m: Mat3) -> Self {
        LaneMat3 {
            c0: LaneVec3::new(m.x_axis.x, m.x_axis.y, m.x_axis.z),
            c1: LaneVec3::new(m.y_axis.x, m.y_axis.y, m.y_axis.z),
            c2: LaneVec3::new(m.z_axis.x, m.z_axis.y, m.z_axis.z),
        }
    }

    #[inline(always)]
    fn to_mat3(self) -> Mat3 {
        Mat3::from_cols(self.c0.to_vec3(), self.c1.to_vec3(), self.c2.to_vec3())
    }
}

impl LaneVec3<Real> {
    #[inline(always)]
    fn to_vec3(self) -> Vec3 {
        Vec3::new(self.x, self.y, self.z)
    }
}

/// Steps 2-5 of the algorithm on matrices whose largest entry lies in `[1, 2)`. Returns
/// `(u, sigma, v)` with `sigma` still on that scale.
#[inline(always)]
fn decompose_scaled<L: Lane>(
    a: LaneMat3<L>,
    sweeps: u32,
) -> (LaneMat3<L>, LaneVec3<L>, LaneMat3<L>) {
    // Step 2: Jacobi on the symmetric a^T a, accumulating v.
    let ata = a.transpose() * a;
    let mut s = SymmetricEntries {
        s00: ata.c0.x,
        s11: ata.c1.y,
        s22: ata.c2.z,
        s01: ata.c1.x,
        s02: ata.c2.x,
        s12: ata.c2.y,
    };
    let mut v = LaneMat3::identity();
    for _ in 0..sweeps {
        // Stop once every off-diagonal entry is at most eps times the geometric mean of its two
        // diagonal entries (Demmel and Veselic's relative criterion): no rotation could then
        // change the decomposition beyond rounding. One value stops; a lane that has converged
        // keeps its values through the sweeps the others still need (the select below), which
        // gives it the bits of the one-value run.
        let excess = s.convergence_excess();
        let zero = L::splat(0.0);
        let active = excess.gt(zero);
        if L::none(active) {
            break;
        }
        // Whether some lane has converged and must keep its values (never for one value).
        let mixed = !L::none(zero.ge(excess));
        let (s_before, v_before) = (s, v);
        // The rotations of a converged lane are computed and then discarded (the select below).
        // Its off-diagonal entries are tiny there (quadratic convergence takes them to 1e-20 and
        // below in f32), and the rotations square them into subnormal numbers, which Intel
        // cores handle by a microcode assist (about 12 ns per instruction on an Intel Xeon,
        // where a normal result takes under 1): with some lanes converged, that made the
        // 16-lane batch 2.1x slower there (docs/guide/10-performance.md, "The SVD"). Zero entries give rotations
        // without subnormals; the results are still discarded, so every lane keeps its bits.
        if mixed {
            s.s01 = L::select(active, s.s01, zero);
            s.s02 = L::select(active, s.s02, zero);
            s.s12 = L::select(active, s.s12, zero);
        }
        let r = jacobi_rotation(s.s00, s.s11, s.s01);
        r.apply_symmetric(&mut s.s00, &mut s.s11, &mut s.s01, &mut s.s02, &mut s.s12);
        r.rotate_columns(&mut v.c0, &mut v.c1);

        let r = jacobi_rotation(s.s00, s.s22, s.s02);
        r.apply_symmetric(&mut s.s00, &mut s.s22, &mut s.s02, &mut s.s01, &mut s.s12);
        r.rotate_columns(&mut v.c0, &mut v.c2);

        let r = jacobi_rotation(s.s11, s.s22, s.s12);
        r.apply_symmetric(&mut s.s11, &mut s.s22, &mut s.s12, &mut s.s01, &mut s.s02);
        r.rotate_columns(&mut v.c1, &mut v.c2);

        if mixed {
            s = SymmetricEntries::select(active, s, s_before);
            v = LaneMat3 {
                c0: LaneVec3::select(active, v.c0, v_before.c0),
                c1: LaneVec3::select(active, v.c1, v_before.c1),
                c2: LaneVec3::select(active, v.c2, v_before.c2),
            };
        }
    }

    // Rounding in the rotations leaves v orthonormal only to ~10 eps after four sweeps, and that
    // error passes straight into the reconstruction (a = b v^T needs v v^T = I). One
    // Newton-Schulz step, v <- v - v (v^T v - I) / 2, squares it away.
    let orthogonality_defect = v.transpose() * v - LaneMat3::identity();
    v = v - (v * orthogonality_defect).scale(L::splat(0.5));

    // Step 3: b = a v with columns sorted by decreasing norm.
    let mut b = a * v;
    let mut norms = [b.c0.dot(b.c0), b.c1.dot(b.c1), b.c2.dot(b.c2)];
    let [n0, n1, n2] = &mut norms;
    sort_pair(&mut b.c0, &mut b.c1, &mut v.c0, &mut v.c1, n0, n1);
    sort_pair(&mut b.c0, &mut b.c2, &mut v.c0, &mut v.c2, n0, n2);
    sort_pair(&mut b.c1, &mut b.c2, &mut v.c1, &mut v.c2, n1, n2);

    // Step 4: Givens QR of the first column, b = u r. Rows of r are kept as the columns of `rt`
    // so that every row operation is a column operation.
    let mut rt = b.transpose();
    let mut u = LaneMat3::identity();
    let g = Givens::zeroing(rt.c0.x, rt.c1.x);
    g.rotate_rows(&mut rt.c0, &mut rt.c1, &mut u.c0, &mut u.c1);
    let g = Givens::zeroing(rt.c0.x, rt.c2.x);
    g.rotate_rows(&mut rt.c0, &mut rt.c2, &mut u.c0, &mut u.c2);

    // Step 5: the remaining 2x2 block m = [[r11, r12], [r21, r22]] gets its own SVD: a Jacobi
    // rotation from the Gram matrix of m's columns (formed from m itself, scaled to order one,
    // not from a^T a), larger column first, then a Givens rotation that triangularises it. This
    // also completes the QR decomposition.
    //
    // The block is first lifted by an exact power of two when its entries lie below `TINY`
    // (two smaller values far below `eps ||a||`, as in `diag(1e19, 1, 0.5)`): on the unit scale
    // the rotations below would treat them as zero and lose their order and sign. `lift` is 1
    // otherwise, so ordinary blocks keep their bits.
    let (r11, r12) = (rt.c1.y, rt.c1.z);
    let (r21, r22) = (rt.c2.y, rt.c2.z);
    let raw_max = r11.abs().max(r12.abs()).max(r21.abs()).max(r22.abs());
    let lift = lift_above_tiny(raw_max);
    let block_max = raw_max * lift;
    let inv_scale = L::splat(1.0) / block_max.max(L::splat(math::TINY));
    let (m11, m12) = (r11 * lift * inv_scale, r12 * lift * inv_scale);
    let (m21, m22) = (r21 * lift * inv_scale, r22 * lift * inv_scale);
    let g11 = m11 * m11 + m21 * m21;
    let g22 = m12 * m12 + m22 * m22;
    let g12 = m11 * m12 + m21 * m22;
    let rot = jacobi_rotation(g11, g22, g12).larger_first(g11, g22, g12);
    // Columns 1 and 2 of r are the y and z components of the row vectors in `rt`.
    let mut col1 = LaneVec3::new(rt.c0.y, r11, r21);
    let mut col2 = LaneVec3::new(rt.c0.z, r12, r22);
    rot.rotate_columns(&mut col1, &mut col2);
    rot.rotate_columns(&mut v.c1, &mut v.c2);
    // Scaling both entries by the power of two `lift` leaves `(c, s)` bit for bit unchanged
    // wherever the unlifted pair was usable.
    let g = Givens::zeroing(col1.y * lift, col1.z * lift);
    let r11 = g.c * col1.y + g.s * col1.z;
    let r22 = g.c * col2.z - g.s * col2.y;
    g.rotate_basis(&mut u.c1, &mut u.c2);

    // Rounding (repeated singular values) or too few sweeps can leave the values slightly out of
    // order; a three-comparator sorting network restores the contract exactly.
    let mut sorted = Triplets {
        u,
        sigma: LaneVec3::new(rt.c0.x, r11, r22),
        v,
    };
    sorted.order_first_pair();
    sorted.order_second_pair();
    sorted.order_first_pair();
    (sorted.u, sorted.sigma, sorted.v)
}

/// The power of two (1, `2^k` or `2^2k`, `2^-k` about `TINY`) that brings `magnitude` to at
/// least [`math::TINY`] whenever it is non-zero: two steps of `2^k` cover the whole range down to
/// the smallest subnormal, since `TINY^2` is still a normal number. Exact to multiply by.
#[inline(always)]
fn lift_above_tiny<L: Lane>(magnitude: L) -> L {
    let tiny = math::TINY;
    let step = L::splat(math::pow2(-math::exponent(tiny)));
    let one = L::splat(1.0);
    let first = L::select(L::splat(tiny).gt(magnitude), step, one);
    let second = L::select(L::splat(tiny * tiny).gt(magnitude), step, one);
    first * second
}

/// A decomposition in progress: `u diag(sigma) v^T`.
struct Triplets<L> {
    u: LaneMat3<L>,
    sigma: LaneVec3<L>,
    v: LaneMat3<L>,
}

impl<L: Lane> Triplets<L> {
    /// Ensures `sigma.x >= sigma.y` (both non-negative) by swapping the first two singular
    /// triplets; the third pair of vectors is negated so that both determinants stay `+1`.
    #[inline(always)]
    fn order_first_pair(&mut self) {
        let swap = self.sigma.y.gt(self.sigma.x);
        for m in [&mut self.u, &mut self.v] {
            let old = *m;
            m.c0 = LaneVec3::select(swap, old.c1, old.c0);
            m.c1 = LaneVec3::select(swap, old.c0, old.c1);
            m.c2 = LaneVec3::select(swap, -old.c2, old.c2);
        }
        let (s0, s1) = (self.sigma.x, self.sigma.y);
        self.sigma.x = L::select(swap, s1, s0);
        self.sigma.y = L::select(swap, s0, s1);
    }

    /// Ensures `sigma.y >= |sigma.z|` by swapping the last two singular triplets. The sign of
    /// `sigma.z` (the sign of `det a`) stays on the last value: with `k = sgn(sigma.z)` the new
    /// triplets are `(|s2|, u2, k v2)` and `(k s1, -u1, -k v1)`, whose products are the old ones
    /// and whose bases keep determinant `+1`.
    #[inline(always)]
    fn order_second_pair(&mut self) {
        let (s1, s2) = (self.sigma.y, self.sigma.z);
        let swap = s2.abs().gt(s1);
        let k = s2.sign();
        let (u, v) = (self.u, self.v);
        self.u.c1 = LaneVec3::select(swap, u.c2, u.c1);
        self.u.c2 = LaneVec3::select(swap, -u.c1, u.c2);
        self.v.c1 = LaneVec3::select(swap, v.c2.scale(k), v.c1);
        self.v.c2 = LaneVec3::select(swap, (-v.c1).scale(k), v.c2);
        self.sigma.y = L::select(swap, s2.abs(), s1);
        self.sigma.z = L::select(swap, s1 * k, s2);
    }
}

/// The six independent entries of a symmetric 3x3 matrix.
#[derive(Clone, Copy)]
struct SymmetricEntries<L> {
    s00: L,
    s11: L,
    s22: L,
    s01: L,
    s02: L,
    s12: L,
}

impl<L: Lane> SymmetricEntries<L> {
    /// `max over pairs of |s_pq| - eps sqrt|s_pp| sqrt|s_qq|`: positive where some off-diagonal
    /// entry exceeds `eps sqrt(s_pp s_qq)` (the lane has not converged). Formed from square
    /// roots rather than squared, so that it cannot underflow for the tiny entries of a nearly
    /// rank-deficient matrix (whose fourth powers would).
    #[inline(always)]
    fn convergence_excess(&self) -> L {
        let eps = L::splat(Real::EPSILON);
        let (r0, r1, r2) = (
            self.s00.abs().sqrt(),
            self.s11.abs().sqrt(),
            self.s22.abs().sqrt(),
        );
        off_diagonal_excess(self.s01, r0, r1, eps)
            .max(off_diagonal_excess(self.s02, r0, r2, eps))
            .max(off_diagonal_excess(self.s12, r1, r2, eps))
    }

    /// `mask ? a : b`, per lane.
    #[inline(always)]
    fn select(mask: L::Mask, a: Self, b: Self) -> Self {
        SymmetricEntries {
            s00: L::select(mask, a.s00, b.s00),
            s11: L::select(mask, a.s11, b.s11),
            s22: L::select(mask, a.s22, b.s22),
            s01: L::select(mask, a.s01, b.s01),
            s02: L::select(mask, a.s02, b.s02),
            s12: L::select(mask, a.s12, b.s12),
        }
    }
}

/// `|spq| - eps (rp rq)`: one term of [`SymmetricEntries::convergence_excess`]. A function
/// rather than a closure so that it is always inlined: a closure left out of line is compiled
/// without the CPU features of the wide kernels that call it, and so are its lane operations.
#[inline(always)]
fn off_diagonal_excess<L: Lane>(spq: L, rp: L, rq: L, eps: L) -> L {
    spq.abs() - eps * (rp * rq)
}

/// A plane rotation `[[c, s], [-s, c]]` acting on a pair of indices `(p, q)`, with
/// `(c, s) = (den, y) / h`.
#[derive(Clone, Copy)]
struct JacobiRotation<L> {
    c: L,
    s: L,
    /// `s / c`, the tangent used to update the diagonal without cancellation.
    t: L,
    /// `den = c h` and `h` themselves, so that the updates on the critical path of the sweep
    /// need one division by `h` instead of waiting for `1 / h` and then multiplying by `c`.
    den: L,
    h: L,
}

/// The rotation that zeroes the off-diagonal of the symmetric 2x2 block `[[app, apq], [apq, aqq]]`
/// (the smaller of the two angles that do, `|theta| <= pi/4`).
///
/// With `d = aqq - app`, `y = 2 apq sgn(d)`, `r = sqrt(d^2 + y^2)` and `den = |d| + r`, the tangent
/// is `t = y / den` (Rutishauser's stable form) and `(c, s) = (den, y) / h`,
/// `h = sqrt(den^2 + y^2)`.
///
/// The inputs are expected on the normalised scale of [`decompose_scaled`] (largest entries of
/// order one), where anything below [`math::TINY`] is far below the rounding of the diagonal.
#[inline(always)]
fn jacobi_rotation<L: Lane>(app: L, aqq: L, apq: L) -> JacobiRotation<L> {
    let tiny = L::splat(math::TINY);
    let d = aqq - app;
    let two_apq = apq + apq;
    let r = (d * d + two_apq * two_apq).sqrt();
    // den >= TINY keeps d = y = 0 (nothing to rotate) at c = 1, s = 0 instead of 0/0, and keeps
    // den^2 a normal number, so h = sqrt(den^2 + y^2) is accurate even when y^2 is subnormal
    // (its absolute error, at most the smallest subnormal, is then far below eps den^2): that is
    // what makes c^2 + s^2 = 1 hold to rounding for every input.
    let den = (d.abs() + r).max(tiny);
    let y = two_apq * d.sign();
    let h = (den * den + y * y).sqrt();
    let inv_h = L::splat(1.0) / h;
    JacobiRotation {
        c: den * inv_h,
        s: y * inv_h,
        t: y / den,
        den,
        h,
    }
}

impl<L: Lane> JacobiRotation<L> {
    /// Applies `J^T S J` to a symmetric matrix given by the entries touched by the pair `(p, q)`
    /// and the remaining index `r`; `apq` becomes zero.
    ///
    /// `c rp - s rq` is evaluated as `den (rp - t rq) / h` (and likewise for `arq`): the same
    /// value, but everything except the final division is ready before `h` is, which shortens
    /// the sweep's chain of dependent operations.
    #[inline(always)]
    fn apply_symmetric(&self, app: &mut L, aqq: &mut L, apq: &mut L, arp: &mut L, arq: &mut L) {
        let shift = self.t * *apq;
        *app = *app - shift;
        *aqq = *aqq + shift;
        *apq = L::splat(0.0);
        let (rp, rq) = (*arp, *arq);
        *arp = self.den * (rp - self.t * rq) / self.h;
        *arq = self.den * (rq + self.t * rp) / self.h;
    }

    /// Right-multiplies a matrix by `J`, given its columns `p` and `q`.
    #[inline(always)]
    fn rotate_columns(&self, p: &mut LaneVec3<L>, q: &mut LaneVec3<L>) {
        let (old_p, old_q) = (*p, *q);
        *p = old_p.scale(self.c) - old_q.scale(self.s);
        *q = old_p.scale(self.s) + old_q.scale(self.c);
    }

    /// This rotation, followed by a quarter turn when that puts the larger diagonal entry of
    /// `J^T S J` (for `S = [[app, apq], [apq, aqq]]`) first. The quarter turn swaps the two
    /// columns and negates one, so the result is still a rotation; only `c` and `s` are updated,
    /// as nothing uses the other fields afterwards.
    #[inline(always)]
    fn larger_first(self, app: L, aqq: L, apq: L) -> Self {
        let shift = self.t * apq;
        let swap = (aqq + shift).gt(app - shift);
        JacobiRotation {
            c: L::select(swap, -self.s, self.c),
            s: L::select(swap, self.c, self.s),
            ..self
        }
    }
}

/// A Givens rotation `[[c, s], [-s, c]]` applied to two rows.
#[derive(Clone, Copy)]
struct Givens<L> {
    c: L,
    s: L,
}

impl<L: Lane> Givens<L> {
    /// The rotation that maps the pair `(a, b)` to `(sqrt(a^2 + b^2), 0)`.
    ///
    /// On the normalised scale of [`decompose_scaled`]: a pair whose length is below
    /// [`math::TINY`] (whose squares would be subnormal) is not rotated but only given a
    /// non-negative first entry, by the half turn `c = -1, s = 0` where `a < 0` (identity otherwise) (a rotation of the
    /// plane, so `det u` stays `+1`). Either way the new first entry `c a + s b` is `>= 0`: the
    /// diagonal of `r` that becomes `sigma.x` and `sigma.y` is never negative, which is what
    /// the sorting network at the end relies on (a negative middle value there was sorted by
    /// its sign rather than its size and came out as a negative `sigma.z` of a singular
    /// matrix). The `b` left in place is below `TINY` of the unit scale, far below rounding.
    #[inline(always)]
    fn zeroing(a: L, b: L) -> Self {
        let tiny = L::splat(math::TINY);
        let length = (a * a + b * b).sqrt();
        let usable = length.gt(tiny);
        let safe_length = length.max(tiny);
        Givens {
            c: L::select(
                usable,
                a / safe_length,
                L::select(L::splat(0.0).gt(a), L::splat(-1.0), L::splat(1.0)),
            ),
            s: L::select(usable, b / safe_length, L::splat(0.0)),
        }
    }

    /// Applies the rotation to rows `p` and `q` of `r` (stored as vectors) and the inverse to
    /// columns `p` and `q` of `u`, so that the product `u r` is unchanged.
    #[inline(always)]
    fn rotate_rows(
        &self,
        row_p: &mut LaneVec3<L>,
        row_q: &mut LaneVec3<L>,
        u_p: &mut LaneVec3<L>,
        u_q: &mut LaneVec3<L>,
    ) {
        self.rotate_basis(row_p, row_q);
        self.rotate_basis(u_p, u_q);
    }

    /// `(p, q) <- (c p + s q, c q - s p)`: the rotation applied to two rows, or equivalently
    /// the right-multiplication of `u` by its transpose, given columns `p` and `q`.
    #[inline(always)]
    fn rotate_basis(&self, p: &mut LaneVec3<L>, q: &mut LaneVec3<L>) {
        let (old_p, old_q) = (*p, *q);
        *p = old_p.scale(self.c) + old_q.scale(self.s);
        *q = old_q.scale(self.c) - old_p.scale(self.s);
    }
}

/// Orders two columns of `b` (and the matching columns of `v`) by decreasing squared norm. A swap
/// negates the new second column so that `det v` stays `+1` and `b = a v` still holds.
#[inline(always)]
fn sort_pair<L: Lane>(
    b_p: &mut LaneVec3<L>,
    b_q: &mut LaneVec3<L>,
    v_p: &mut LaneVec3<L>,
    v_q: &mut LaneVec3<L>,
    norm_p: &mut L,
    norm_q: &mut L,
) {
    let swap = norm_q.gt(*norm_p);
    let (bp, bq, vp, vq, np, nq) = (*b_p, *b_q, *v_p, *v_q, *norm_p, *norm_q);
    *b_p = LaneVec3::select(swap, bq, bp);
    *b_q = LaneVec3::select(swap, -bp, bq);
    *v_p = LaneVec3::select(swap, vq, vp);
    *v_q = LaneVec3::select(swap, -vp, vq);
    *norm_p = L::select(swap, nq, np);
    *norm_q = L::select(swap, np, nq);
}

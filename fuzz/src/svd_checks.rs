//! The SVD contract on arbitrary matrices (included once per precision by `lib.rs`).
//!
//! Promises checked (`src/svd.rs`), for `svd3`, `svd3_sweeps`, `svd3_lanes` and
//! `svd3_lanes_sweeps`:
//! * structure, for every finite input and every sweep count: `u` and `v` orthonormal with
//!   `det = +1` (to `32 eps`), `sigma.x >= sigma.y >= |sigma.z|` exactly;
//! * accuracy, with at least `DEFAULT_SWEEPS` sweeps: `|u diag(sigma) v^T - a|_F <= 64 eps |a|_F`
//!   (plus 16 of the smallest subnormals, the documented subnormal rounding);
//! * the sign rule: `sigma.z < 0` only when `det a < 0`, and `sigma.z > 0` only when
//!   `det a > 0`, wherever `|sigma.z|` exceeds the accuracy bound (the sign of a value
//!   below it is rounding); a clearly positive or negative `det a` gives `sigma.z` its sign;
//! * finite output when the singular values are below `Real::MAX` (`|a|_F <= Real::MAX / 2`);
//! * the documented results for the zero matrix (`u = v = I`, `sigma = 0`) and for non-finite
//!   input (`u = v = I`, `sigma = NaN`);
//! * every lane of the batched SVD bit for bit the scalar result.
//!
//! The reference arithmetic is f64 on the input scaled by a power of two (exact) so that its
//! largest entry is in `[1, 2)`.

use super::NAME;
use super::precision as draw_real;
use super::sf::lanes::LANES;
use super::sf::svd::{DEFAULT_SWEEPS, Svd3, svd3, svd3_lanes, svd3_lanes_sweeps, svd3_sweeps};
use super::sf::types::{Mat3, Real, Vec3};
use crate::Draw;

/// Orthonormality and `det = +1` of `u` and `v`, in units of `Real::EPSILON`.
const ORTHONORMAL_TOLERANCE: f64 = 32.0;
/// Reconstruction error relative to `|a|_F`, in units of `Real::EPSILON`.
const RECONSTRUCTION_TOLERANCE: f64 = 64.0;

/// Runs the SVD checks on one fuzzer input.
pub fn check(data: &[u8]) {
    let mut draw = Draw::new(data);
    let matrices: [Mat3; LANES] = core::array::from_fn(|_| draw_matrix(&mut draw));
    let sweeps = draw.up_to(DEFAULT_SWEEPS + 2);

    let batch = svd3_lanes(&matrices);
    let batch_sweeps = svd3_lanes_sweeps(&matrices, sweeps);
    for (lane, a) in matrices.iter().enumerate() {
        let svd = svd3(*a);
        check_decomposition(*a, &svd, true, "svd3", DEFAULT_SWEEPS);
        assert_eq!(
            svd_bits(&batch[lane]),
            svd_bits(&svd),
            "{NAME}: svd3_lanes lane {lane} differs from svd3 for {a:?}"
        );
        let with_sweeps = svd3_sweeps(*a, sweeps);
        check_decomposition(
            *a,
            &with_sweeps,
            sweeps >= DEFAULT_SWEEPS,
            "svd3_sweeps",
            sweeps,
        );
        assert_eq!(
            svd_bits(&batch_sweeps[lane]),
            svd_bits(&with_sweeps),
            "{NAME}: svd3_lanes_sweeps({sweeps}) lane {lane} differs from svd3_sweeps for {a:?}"
        );
    }
}

fn svd_bits(svd: &Svd3) -> Vec<u64> {
    svd.u
        .to_cols_array()
        .iter()
        .chain(&svd.sigma.to_array())
        .chain(&svd.v.to_cols_array())
        .map(|x| x.to_bits().into())
        .collect()
}

/// A matrix of one of several kinds: any finite entries; columns that are scaled axes or zero
/// (the shape of the known extreme-range defect); rotation times widely spread singular values
/// times rotation; small integers (exactly singular and inverted ones are common); a grid matrix
/// with rows and columns scaled by powers of two; a sparse matrix; and now and then a
/// non-finite entry.
fn draw_matrix(draw: &mut Draw<'_>) -> Mat3 {
    let mut cols = [[0.0 as Real; 3]; 3];
    match draw.up_to(6) {
        0 => {
            for entry in cols.iter_mut().flatten() {
                *entry = draw_real::finite(draw);
            }
        }
        1 => {
            for column in &mut cols {
                if !draw.chance(48) {
                    let axis = draw.index(2);
                    column[axis] = draw_real::finite(draw);
                    if draw.chance(64) {
                        column[draw.index(2)] = draw_real::finite(draw);
                    }
                }
            }
        }
        2 => {
            let angle = |draw: &mut Draw<'_>| Real::from(draw.i16()) / 4096.0;
            let u = Mat3::from_euler(
                softfem::glam::EulerRot::XYZ,
                angle(draw),
                angle(draw),
                angle(draw),
            );
            let v = Mat3::from_euler(
                softfem::glam::EulerRot::ZXY,
                angle(draw),
                angle(draw),
                angle(draw),
            );
            let range = Real::MAX_EXP;
            let spread = |draw: &mut Draw<'_>| {
                let exponent = i32::from(draw.i16()) % range;
                let sign = if draw.chance(32) { -1.0 } else { 1.0 };
                sign * pow2(exponent)
            };
            let sigma = Vec3::new(spread(draw), spread(draw), spread(draw));
            let m = u * Mat3::from_diagonal(sigma) * v.transpose();
            return if m.is_finite() {
                m
            } else {
                Mat3::from_diagonal(sigma)
            };
        }
        3 => {
            for entry in cols.iter_mut().flatten() {
                *entry = Real::from(draw.i16() >> 13);
            }
        }
        4 => {
            let range = Real::MAX_EXP / 2 - 2;
            let rows: [Real; 3] = core::array::from_fn(|_| pow2(i32::from(draw.i16()) % range));
            for column in &mut cols {
                let scale = pow2(i32::from(draw.i16()) % range);
                for (entry, row) in column.iter_mut().zip(rows) {
                    *entry = draw_real::grid(draw, 1.0) * row * scale;
                }
            }
        }
        5 => {
            for _ in 0..=draw.up_to(3) {
                let (c, r) = (draw.index(2), draw.index(2));
                cols[c][r] = draw_real::finite(draw);
            }
        }
        _ => {
            for entry in cols.iter_mut().flatten() {
                *entry = if draw.chance(24) {
                    draw_real::wild(draw)
                } else {
                    draw_real::grid(draw, 1.0)
                };
            }
        }
    }
    Mat3::from_cols(cols[0].into(), cols[1].into(), cols[2].into())
}

/// `2^exponent` in this precision (0 or infinity beyond its range).
fn pow2(exponent: i32) -> Real {
    (2.0 as Real).powi(exponent)
}

/// `x * 2^k` in f64 in two steps, so that `2^k` itself never overflows.
fn scale_by_pow2(x: f64, k: i32) -> f64 {
    let half = k / 2;
    x * 2f64.powi(half) * 2f64.powi(k - half)
}

type Wide = [[f64; 3]; 3];

fn wide(m: Mat3) -> Wide {
    let c = m.to_cols_array();
    [
        [c[0] as f64, c[1] as f64, c[2] as f64],
        [c[3] as f64, c[4] as f64, c[5] as f64],
        [c[6] as f64, c[7] as f64, c[8] as f64],
    ]
}

/// `m[c][r]` is row `r` of column `c`. `a^T b`.
fn transpose_times(a: &Wide, b: &Wide) -> Wide {
    let mut out = [[0.0; 3]; 3];
    for (j, column) in out.iter_mut().enumerate() {
        for (i, entry) in column.iter_mut().enumerate() {
            *entry = (0..3).map(|k| a[i][k] * b[j][k]).sum();
        }
    }
    out
}

/// `(s, e)` with `s + e = a + b` exactly (Knuth's two-sum).
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let b_virtual = s - a;
    let a_virtual = s - b_virtual;
    (s, (a - a_virtual) + (b - b_virtual))
}

/// `(p, e)` with `p + e = a * b` exactly (no underflow assumed; the harness may fuse, the
/// library may not).
fn two_product(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

/// The exact sign of `det m` for a matrix whose entries are below 2 in magnitude, with entries
/// below `2^-200` taken as zero (which moves `det` by less than `1e-59`; callers only ask where
/// `|det| > 1e-42`). Each of the six triple products is split exactly into four doubles and all
/// of them are summed exactly into an expansion (Shewchuk, "Adaptive Precision Floating-Point
/// Arithmetic and Fast Robust Geometric Predicates", Discrete Comput. Geom. 1997): with every
/// product above `2^-600` nothing underflows.
fn exact_determinant_sign(m: &Wide) -> core::cmp::Ordering {
    let flushed = m.map(|column| column.map(|e| if e.abs() < 2f64.powi(-200) { 0.0 } else { e }));
    let entry = |column: usize, row: usize| flushed[column][row];
    // det = sum over permutations of sign * m[0][p0] m[1][p1] m[2][p2] (column c, row p_c).
    let terms: [(f64, [usize; 3]); 6] = [
        (1.0, [0, 1, 2]),
        (1.0, [1, 2, 0]),
        (1.0, [2, 0, 1]),
        (-1.0, [2, 1, 0]),
        (-1.0, [0, 2, 1]),
        (-1.0, [1, 0, 2]),
    ];
    let mut expansion: Vec<f64> = Vec::new();
    let mut grow = |value: f64| {
        let mut q = value;
        for component in expansion.iter_mut() {
            let (sum, error) = two_sum(q, *component);
            *component = error;
            q = sum;
        }
        expansion.push(q);
    };
    for (sign, rows) in terms {
        let (p1, e1) = two_product(sign * entry(0, rows[0]), entry(1, rows[1]));
        let c = entry(2, rows[2]);
        let (p2, e2) = two_product(p1, c);
        let (p3, e3) = two_product(e1, c);
        for part in [p2, e2, p3, e3] {
            grow(part);
        }
    }
    // The expansion is non-overlapping with magnitudes increasing: its sign is that of its
    // last non-zero component.
    match expansion.iter().rev().find(|&&c| c != 0.0) {
        Some(&c) if c > 0.0 => core::cmp::Ordering::Greater,
        Some(_) => core::cmp::Ordering::Less,
        None => core::cmp::Ordering::Equal,
    }
}

/// `det m` in f64 (for `det u`, `det v` of near-rotations: accurate to a few eps64).
fn determinant(m: &Wide) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[2][1] * m[1][2])
        - m[1][0] * (m[0][1] * m[2][2] - m[2][1] * m[0][2])
        + m[2][0] * (m[0][1] * m[1][2] - m[1][1] * m[0][2])
}

/// `|u^T u - I|_max` and `|det u - 1|`.
fn orthonormality(u: &Wide) -> (f64, f64) {
    let gram = transpose_times(u, u);
    let mut worst: f64 = 0.0;
    for (j, column) in gram.iter().enumerate() {
        for (i, entry) in column.iter().enumerate() {
            let identity = if i == j { 1.0 } else { 0.0 };
            worst = worst.max((entry - identity).abs());
        }
    }
    (worst, (determinant(u) - 1.0).abs())
}

/// Checks one decomposition `svd` of `a`; the accuracy and sign rule only when `accurate`.
fn check_decomposition(a: Mat3, svd: &Svd3, accurate: bool, function: &str, sweeps: u32) {
    let context = || format!("{NAME}: {function} ({sweeps} sweeps) of {a:?} gave {svd:?}");
    if !a.is_finite() {
        assert!(
            svd.u == Mat3::IDENTITY && svd.v == Mat3::IDENTITY && svd.sigma.is_nan_mask().all(),
            "{}: non-finite input must give u = v = I, sigma = NaN",
            context()
        );
        return;
    }
    let entries = wide(a);
    let largest = entries.iter().flatten().fold(0.0f64, |m, e| m.max(e.abs()));
    if largest == 0.0 {
        assert!(
            svd.u == Mat3::IDENTITY && svd.v == Mat3::IDENTITY && svd.sigma == Vec3::ZERO,
            "{}: the zero matrix must give u = v = I, sigma = 0",
            context()
        );
        return;
    }
    // Scaled so that the largest entry is in [1, 2): k = -floor(log2(largest)).
    let k = -(largest.log2().floor() as i32);
    let scaled = entries.map(|column| column.map(|e| scale_by_pow2(e, k)));
    let frobenius = scaled.iter().flatten().map(|e| e * e).sum::<f64>().sqrt();
    // |a|_F = frobenius * 2^-k; singular values stay below Real::MAX when it is below MAX / 2.
    let representable = (frobenius.log2() - k as f64) < (Real::MAX as f64).log2() - 1.0;
    if !representable {
        return;
    }
    let finite = svd.u.is_finite() && svd.v.is_finite() && svd.sigma.is_finite();
    assert!(
        finite,
        "{}: finite input with representable singular values gave a non-finite result",
        context()
    );

    let eps = Real::EPSILON as f64;
    let (u, v) = (wide(svd.u), wide(svd.v));
    for (name, m) in [("u", &u), ("v", &v)] {
        let (off, det) = orthonormality(m);
        assert!(
            off <= ORTHONORMAL_TOLERANCE * eps && det <= ORTHONORMAL_TOLERANCE * eps,
            "{}: {name} is not a rotation: |{name}^T {name} - I| = {off:e}, |det {name} - 1| = {det:e}",
            context()
        );
    }
    let sigma = svd.sigma;
    assert!(
        sigma.x >= sigma.y && sigma.y >= sigma.z.abs(),
        "{}: singular values not sorted s0 >= s1 >= |s2|",
        context()
    );
    if !accurate {
        return;
    }

    let sigma_scaled = sigma.to_array().map(|s| scale_by_pow2(s as f64, k));
    // u diag(sigma) v^T, column j, row i: sum_m u[m][i] sigma_m v[m][j].
    let mut error_squared = 0.0;
    for j in 0..3 {
        for i in 0..3 {
            let r: f64 = (0..3).map(|m| u[m][i] * sigma_scaled[m] * v[m][j]).sum();
            error_squared += (r - scaled[j][i]).powi(2);
        }
    }
    let subnormal_slack = scale_by_pow2(16.0 * Real::from_bits(1) as f64, k);
    let bound = RECONSTRUCTION_TOLERANCE * eps * frobenius + subnormal_slack;
    let error = error_squared.sqrt();
    assert!(
        error <= bound,
        "{}: reconstruction error {:e} |a|_F exceeds {RECONSTRUCTION_TOLERANCE} eps",
        context(),
        error / frobenius
    );

    // The sign rule, where |sigma.z| is beyond twice the accuracy bound: there the computed
    // sigma.z is within the bound of the true signed value, so its sign is the sign of det a
    // (u and v being rotations), and |det a| >= |sigma.z|^3 > 1e-42 in the scaled units.
    // (Below it the sign is rounding, and it is not checked.)
    let s2 = sigma_scaled[2];
    if s2.abs() > 2.0 * bound {
        let det_sign = exact_determinant_sign(&scaled);
        let s2_sign = if s2 > 0.0 {
            core::cmp::Ordering::Greater
        } else {
            core::cmp::Ordering::Less
        };
        assert!(
            det_sign == s2_sign,
            "{}: sigma.z has the sign {s2_sign:?} but det a has the sign {det_sign:?} (the sign rule)",
            context()
        );
    }
}

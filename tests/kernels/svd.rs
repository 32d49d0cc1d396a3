//! The contract of the rotation-variant 3x3 SVD (`docs/math.md` section 3), in both precisions.
//!
//! For every class of input (random, ill-conditioned, near-singular, exactly rank 1 and 2,
//! repeated singular values, reflections, zero, scales from `1e-30` to `1e30`, subnormal and the
//! largest safe magnitudes) the decomposition `a = u diag(sigma) v^T` must have
//! * no NaN or inf, `u` and `v` orthonormal with `det = +1`;
//! * `sigma.x >= sigma.y >= |sigma.z|` exactly, and `sigma.z < 0` exactly when `det a < 0`;
//! * a reconstruction error of a few `eps ||a||`;
//! * singular values within a few `eps * s0` of an independent reference (nalgebra's f64 SVD).
//!
//! Every check is written once against the [`Svd`] trait and run for `f32` (crate root) and
//! `f64` (`softfem::f64`). All error measures are computed in f64 from the outputs widened
//! exactly, on the input as the decomposition saw it (rounded to its precision).
//!
//! `cargo test --release --test kernels svd::report -- --nocapture` prints the table of maximum
//! errors per class quoted in the README.

use std::sync::OnceLock;

use crate::common::{F32, F64, Precision, Rng, frobenius};
use nalgebra::DMatrix;
use proptest::prelude::*;
use softfem::glam::{DMat3, DVec3};

/// Matrices per `svd3_lanes` call; the same in both precisions.
const LANES: usize = softfem::lanes::LANES;
const _: () = assert!(softfem::f64::lanes::LANES == LANES);

// ---------------------------------------------------------------------------------------------
// The two precisions behind one interface.
// ---------------------------------------------------------------------------------------------

/// A decomposition widened to f64 (exact for f32 outputs).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Wide {
    u: DMat3,
    sigma: DVec3,
    v: DMat3,
}

/// Magnitudes at the edges of a precision's range.
struct Extremes {
    /// A scale that makes entries of `[-1, 1]` subnormal.
    subnormal: f64,
    /// The smallest positive subnormal number.
    tiniest: f64,
    /// A scale for entries that are large but keep every singular value below `MAX`.
    huge: f64,
    /// The largest finite number.
    max: f64,
}

/// One precision of softfem's SVD, with the tolerances its contract promises (the orthonormality
/// and reconstruction ones in [`Precision`]).
trait Svd: Precision {
    /// `max_i |sigma_i - ref_i| / s0`. By Weyl's inequality a backward error `e ||a||` moves
    /// every singular value by at most `e ||a||_2 = e s0`, so absolute accuracy relative to `s0`
    /// is what a backward-stable SVD (ours and the reference alike) can promise, even for tiny
    /// values.
    const SIGMA_TOL: f64;
    const EXTREMES: Extremes;

    fn svd(a: DMat3) -> Wide;
    fn svd_sweeps(a: DMat3, sweeps: u32) -> Wide;
    /// `svd3_lanes` on a group of [`LANES`] matrices.
    fn svd_lanes(a: [DMat3; LANES]) -> [Wide; LANES];
    fn default_sweeps() -> u32;
    /// Per-class results, computed once whichever test asks first.
    fn cache() -> &'static [OnceLock<MaxErrors>; CLASSES.len()];
}

impl Svd for F32 {
    const SIGMA_TOL: f64 = 2e-6;
    const EXTREMES: Extremes = Extremes {
        subnormal: 1e-39,
        tiniest: f32::from_bits(1) as f64,
        huge: 1e37,
        max: f32::MAX as f64,
    };

    fn svd(a: DMat3) -> Wide {
        let svd = softfem::svd::svd3(a.as_mat3());
        Wide {
            u: svd.u.as_dmat3(),
            sigma: svd.sigma.as_dvec3(),
            v: svd.v.as_dmat3(),
        }
    }

    fn svd_sweeps(a: DMat3, sweeps: u32) -> Wide {
        let svd = softfem::svd::svd3_sweeps(a.as_mat3(), sweeps);
        Wide {
            u: svd.u.as_dmat3(),
            sigma: svd.sigma.as_dvec3(),
            v: svd.v.as_dmat3(),
        }
    }

    fn svd_lanes(a: [DMat3; LANES]) -> [Wide; LANES] {
        softfem::svd::svd3_lanes(&a.map(|m| m.as_mat3())).map(|svd| Wide {
            u: svd.u.as_dmat3(),
            sigma: svd.sigma.as_dvec3(),
            v: svd.v.as_dmat3(),
        })
    }

    fn default_sweeps() -> u32 {
        softfem::svd::DEFAULT_SWEEPS
    }

    fn cache() -> &'static [OnceLock<MaxErrors>; CLASSES.len()] {
        static CACHE: [OnceLock<MaxErrors>; CLASSES.len()] =
            [const { OnceLock::new() }; CLASSES.len()];
        &CACHE
    }
}

impl Svd for F64 {
    const SIGMA_TOL: f64 = 1e-13;
    const EXTREMES: Extremes = Extremes {
        subnormal: 1e-310,
        tiniest: f64::from_bits(1),
        huge: 1e307,
        max: f64::MAX,
    };

    fn svd(a: DMat3) -> Wide {
        let svd = softfem::f64::svd::svd3(a);
        Wide {
            u: svd.u,
            sigma: svd.sigma,
            v: svd.v,
        }
    }

    fn svd_sweeps(a: DMat3, sweeps: u32) -> Wide {
        let svd = softfem::f64::svd::svd3_sweeps(a, sweeps);
        Wide {
            u: svd.u,
            sigma: svd.sigma,
            v: svd.v,
        }
    }

    fn svd_lanes(a: [DMat3; LANES]) -> [Wide; LANES] {
        softfem::f64::svd::svd3_lanes(&a).map(|svd| Wide {
            u: svd.u,
            sigma: svd.sigma,
            v: svd.v,
        })
    }

    fn default_sweeps() -> u32 {
        softfem::f64::svd::DEFAULT_SWEEPS
    }

    fn cache() -> &'static [OnceLock<MaxErrors>; CLASSES.len()] {
        static CACHE: [OnceLock<MaxErrors>; CLASSES.len()] =
            [const { OnceLock::new() }; CLASSES.len()];
        &CACHE
    }
}

// ---------------------------------------------------------------------------------------------
// The classes of input. Generators build f64 matrices; each precision rounds them.
// ---------------------------------------------------------------------------------------------

/// Matrices per class and precision.
const PER_CLASS: usize = 3000;

struct Class {
    label: &'static str,
    generate: fn(&mut Rng, &Extremes) -> DMat3,
    /// Singular values below the normal range, where their rounding to the subnormal grid
    /// dominates the error (see [`Reference::quantum_n`]); left out of the summary figures.
    subnormal: bool,
}

fn random_entries(rng: &mut Rng, _: &Extremes) -> DMat3 {
    rng.entries()
}

/// `u diag(1, m, ±1/cond) v^T`, `m` log-uniform in between; either sign of the determinant.
fn conditioned(rng: &mut Rng, cond: f64) -> DMat3 {
    let middle = rng.log_uniform(1.0 / cond, 1.0);
    let smallest = rng.sign() / cond;
    rng.rotated(DVec3::new(1.0, middle, smallest))
}

fn condition_1e3(rng: &mut Rng, _: &Extremes) -> DMat3 {
    conditioned(rng, 1e3)
}

fn condition_1e6(rng: &mut Rng, _: &Extremes) -> DMat3 {
    conditioned(rng, 1e6)
}

fn near_singular(rng: &mut Rng, _: &Extremes) -> DMat3 {
    let smallest = rng.sign() * 1e-9;
    rng.rotated(DVec3::new(1.0, 0.5, smallest))
}

/// Exactly rank 2 in both precisions: sums of two outer products of short-mantissa vectors (every
/// product and sum exact), or a matrix with a zero column (row) rotated on the left (right) only,
/// which keeps that column (row) exactly zero.
fn rank_2(rng: &mut Rng, _: &Extremes) -> DMat3 {
    match rng.below(3) {
        0 => {
            let mut outer = || {
                let x = DVec3::new(rng.short(8), rng.short(8), rng.short(8));
                let y = DVec3::new(rng.short(8), rng.short(8), rng.short(8));
                DMat3::from_cols(x * y.x, x * y.y, x * y.z)
            };
            outer() + outer()
        }
        1 => {
            let mut m = rng.entries();
            *m.col_mut(rng.below(3)) = DVec3::ZERO;
            rng.rotation() * m
        }
        _ => {
            let mut m = rng.entries();
            *m.col_mut(rng.below(3)) = DVec3::ZERO;
            m.transpose() * rng.rotation()
        }
    }
}

/// Exactly rank 1 in both precisions (see [`rank_2`]).
fn rank_1(rng: &mut Rng, _: &Extremes) -> DMat3 {
    if rng.below(2) == 0 {
        let x = DVec3::new(rng.short(12), rng.short(12), rng.short(12));
        let y = DVec3::new(rng.short(12), rng.short(12), rng.short(12));
        DMat3::from_cols(x * y.x, x * y.y, x * y.z)
    } else {
        let mut m = DMat3::ZERO;
        *m.col_mut(rng.below(3)) = rng.vector();
        rng.rotation() * m
    }
}

/// `u diag(1, 0, 0) v^T` and `u diag(1, 1, 0) v^T`: rank-deficient up to rounding.
fn rotated_rank_deficient(rng: &mut Rng, _: &Extremes) -> DMat3 {
    let middle = if rng.below(2) == 0 { 0.0 } else { 1.0 };
    rng.rotated(DVec3::new(1.0, middle, 0.0))
}

/// Identity, `diag(2, 1, 1)`, `diag(1, 1, 0.5)`, plain, rotated on one side, on both sides, and
/// conjugated (`r d r^T`); and signed permutations with `det = +1`.
fn repeated(rng: &mut Rng, _: &Extremes) -> DMat3 {
    let d = DMat3::from_diagonal(
        [
            DVec3::ONE,
            DVec3::new(2.0, 1.0, 1.0),
            DVec3::new(1.0, 1.0, 0.5),
        ][rng.below(3)],
    );
    match rng.below(6) {
        0 => d,
        1 => rng.rotation() * d,
        2 => d * rng.rotation(),
        3 => {
            let r = rng.rotation();
            r * d * r.transpose()
        }
        4 => rng.rotation() * d * rng.rotation().transpose(),
        _ => loop {
            let p = signed_permutation(rng);
            if p.determinant() > 0.0 {
                break p;
            }
        },
    }
}

fn signed_permutation(rng: &mut Rng) -> DMat3 {
    let order = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ][rng.below(6)];
    DMat3::from_cols_array_2d(&core::array::from_fn(|col| {
        let mut column = [0.0; 3];
        column[order[col]] = rng.sign();
        column
    }))
}

/// Clustered (not exactly repeated) singular values, where Jacobi needs its sweeps.
fn clustered(rng: &mut Rng, _: &Extremes) -> DMat3 {
    if rng.below(2) == 0 {
        let delta = rng.log_uniform(1e-8, 1e-2);
        let s = DVec3::new(1.0, 1.0 - delta * rng.unit(), 1.0 - delta) * rng.sign();
        rng.rotated(s)
    } else {
        DMat3::IDENTITY + rng.entries() * rng.log_uniform(1e-8, 1e-3)
    }
}

/// `det < 0`: `-I`, `diag(2, -2, 2)`, Householder reflections, rotated diagonals with an odd
/// number of negative entries, signed permutations, random matrices with a column flipped.
fn inverted(rng: &mut Rng, _: &Extremes) -> DMat3 {
    match rng.below(6) {
        0 => -DMat3::IDENTITY,
        1 => DMat3::from_diagonal(DVec3::new(2.0, -2.0, 2.0)),
        2 => {
            let n = rng.vector().normalize_or(DVec3::X);
            let nnt = DMat3::from_cols(n * n.x, n * n.y, n * n.z);
            DMat3::IDENTITY - nnt * 2.0
        }
        3 => {
            let mut s = DVec3::new(rng.unit(), rng.unit(), rng.unit()) + 0.01;
            s *= [DVec3::new(-1.0, 1.0, 1.0), DVec3::NEG_ONE][rng.below(2)];
            rng.rotated(s)
        }
        4 => loop {
            let p = signed_permutation(rng);
            if p.determinant() < 0.0 {
                break p;
            }
        },
        _ => {
            let mut m = rng.entries();
            if m.determinant() > 0.0 {
                m.x_axis = -m.x_axis;
            }
            m
        }
    }
}

/// All-zero matrices, with every mix of `+0.0` and `-0.0`.
fn zero(rng: &mut Rng, _: &Extremes) -> DMat3 {
    DMat3::from_cols_array(&core::array::from_fn(|_| 0.0 * rng.sign()))
}

/// Random or ill-conditioned matrices times `scale`.
fn scaled(rng: &mut Rng, scale: f64) -> DMat3 {
    let m = if rng.below(2) == 0 {
        rng.entries()
    } else {
        conditioned(rng, 1e3)
    };
    m * scale
}

fn scale_1e_minus_30(rng: &mut Rng, _: &Extremes) -> DMat3 {
    scaled(rng, 1e-30)
}

fn scale_1e30(rng: &mut Rng, _: &Extremes) -> DMat3 {
    scaled(rng, 1e30)
}

/// Random subnormal entries (about 20 significant bits in f32, 40 in f64).
fn subnormal(rng: &mut Rng, extremes: &Extremes) -> DMat3 {
    rng.entries() * extremes.subnormal
}

/// Small multiples of the smallest subnormal, down to a single bit.
fn smallest_subnormals(rng: &mut Rng, extremes: &Extremes) -> DMat3 {
    DMat3::from_cols_array(&core::array::from_fn(|_| {
        (rng.below(9) as f64 - 4.0) * extremes.tiniest
    }))
}

/// Entries near the top of the range: random ones times `huge`, and `±max / 4` everywhere (the
/// largest singular value, at most `||a||_F = 3 max / 4`, stays finite).
fn largest_safe(rng: &mut Rng, extremes: &Extremes) -> DMat3 {
    if rng.below(4) == 0 {
        DMat3::from_cols_array(&core::array::from_fn(|_| rng.sign() * extremes.max / 4.0))
    } else {
        rng.entries() * extremes.huge
    }
}

macro_rules! classes {
    (@subnormal) => { false };
    (@subnormal subnormal) => { true };
    ($($test:ident => $label:literal, $generate:path $(, $flag:ident)?;)*) => {
        const CLASSES: [Class; [$($label),*].len()] = [$(Class {
            label: $label,
            generate: $generate,
            subnormal: classes!(@subnormal $($flag)?),
        }),*];

        $(
            #[test]
            fn $test() {
                let index = CLASSES.iter().position(|c| c.label == $label).unwrap();
                class_errors::<F32>(index);
                class_errors::<F64>(index);
            }
        )*
    };
}

classes! {
    class_random_entries => "random entries in [-1, 1]", random_entries;
    class_condition_1e3 => "condition 1e3", condition_1e3;
    class_condition_1e6 => "condition 1e6", condition_1e6;
    class_near_singular => "near-singular (1, 0.5, 1e-9)", near_singular;
    class_rank_2 => "exactly rank 2", rank_2;
    class_rank_1 => "exactly rank 1", rank_1;
    class_rotated_rank_deficient => "u diag(1,0,0)/(1,1,0) v^T", rotated_rank_deficient;
    class_repeated => "repeated singular values", repeated;
    class_clustered => "clustered singular values", clustered;
    class_inverted => "reflections, det < 0", inverted;
    class_zero => "zero matrix", zero;
    class_scale_1e_minus_30 => "random * 1e-30", scale_1e_minus_30;
    class_scale_1e30 => "random * 1e30", scale_1e30;
    class_subnormal => "subnormal (1e-39 / 1e-310) *", subnormal, subnormal;
    class_smallest_subnormals => "k * smallest subnormal *", smallest_subnormals, subnormal;
    class_largest_safe => "largest safe (1e37 / 1e307)", largest_safe;
}

/// The first `count` matrices of class `class`, rounded to `P`: the same stream for every test
/// that asks.
fn class_matrices<P: Svd>(class: usize, count: usize) -> impl Iterator<Item = DMat3> {
    let mut rng = Rng::new(0x50f7_fe11 + class as u64);
    (0..count).map(move |_| P::round((CLASSES[class].generate)(&mut rng, &P::EXTREMES)))
}

/// The maximum errors over [`PER_CLASS`] matrices of one class, asserting the contract on each.
fn class_errors<P: Svd>(class: usize) -> MaxErrors {
    *P::cache()[class].get_or_init(|| {
        let mut max = MaxErrors::default();
        for a in class_matrices::<P>(class, PER_CLASS) {
            max.absorb(check_decomposition::<P>(a, CLASSES[class].label));
        }
        max
    })
}

// ---------------------------------------------------------------------------------------------
// The checks.
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, Default)]
struct MaxErrors {
    recon: f64,
    orth: f64,
    sigma: f64,
}

impl MaxErrors {
    fn absorb(&mut self, other: MaxErrors) {
        self.recon = self.recon.max(other.recon);
        self.orth = self.orth.max(other.orth);
        self.sigma = self.sigma.max(other.sigma);
    }
}

fn orthonormality_error(q: DMat3) -> f64 {
    frobenius(q.transpose() * q - DMat3::IDENTITY).max((q.determinant() - 1.0).abs())
}

/// `2^n` for `n` in f64's normal exponent range (exact).
fn pow2(n: i32) -> f64 {
    assert!((-1022..=1023).contains(&n));
    f64::from_bits(((n + 1023) as u64) << 52)
}

/// `x * 2^n` in two exact steps, so that `n` may exceed the range of a single factor.
fn times_pow2(x: f64, n: i32) -> f64 {
    x * pow2(n / 2) * pow2(n - n / 2)
}

/// An input brought to order one by an exact power of two, with its independent reference.
///
/// All relative error measures are scale-invariant, and working at order one keeps squares,
/// determinants and nalgebra's absolute convergence threshold (which fails on `1e±30` inputs)
/// clear of overflow and underflow in both precisions.
struct Reference {
    /// The exponent `e` with `a = a_n 2^e`.
    exponent: i32,
    a_n: DMat3,
    /// Singular values of `a_n` by nalgebra's f64 SVD, sorted, the smallest carrying the sign of
    /// `det a_n`.
    ///
    /// The reference is nalgebra's general SVD (Householder bidiagonalisation and implicit-shift
    /// QR, Golub-Kahan) on a dynamically sized matrix, which is backward stable. Its `Matrix3`
    /// specialisation takes the eigenvectors of `a^T a` instead, and that loses the smallest values
    /// of ill-conditioned matrices to the squared condition number: on the condition-1e6 class
    /// it is off by up to 6.4e-14 s0 (290 eps), where softfem and Golub-Kahan agree to 1e-16 s0.
    sigma_n: DVec3,
    det_n: f64,
    /// The spacing of the precision's subnormal numbers (its smallest positive value) at the
    /// scale of `a_n`: singular values below the normal range are rounded to multiples of it, an
    /// absolute error no algorithm can avoid. Negligible unless `a` itself is near subnormal.
    quantum_n: f64,
}

impl Reference {
    fn new<P: Svd>(a: DMat3) -> Self {
        let max_abs = a.abs().to_cols_array().into_iter().fold(0.0, f64::max);
        let exponent = if max_abs == 0.0 {
            0
        } else {
            max_abs.log2().round() as i32
        };
        let a_n = DMat3::from_cols_array(&a.to_cols_array().map(|x| times_pow2(x, -exponent)));
        let mut values: Vec<f64> = DMatrix::from_column_slice(3, 3, &a_n.to_cols_array())
            .svd(false, false)
            .singular_values
            .iter()
            .copied()
            .collect();
        values.sort_by(|x, y| y.total_cmp(x));
        let det_n = a_n.determinant();
        if det_n < 0.0 {
            values[2] = -values[2];
        }
        Reference {
            exponent,
            a_n,
            sigma_n: DVec3::from_slice(&values),
            det_n,
            quantum_n: times_pow2(P::EXTREMES.tiniest, -exponent),
        }
    }

    /// Computed singular values brought to the scale of `a_n` (exact).
    fn normalise(&self, sigma: DVec3) -> DVec3 {
        DVec3::from_array(sigma.to_array().map(|s| times_pow2(s, -self.exponent)))
    }
}

/// Fails with everything needed to reproduce: precision, input as source code, output.
fn fail<P: Svd>(a: DMat3, svd: &Wide, context: &str, what: String) -> ! {
    panic!(
        "{} svd3 ({context}): {what}\n  input:  {}\n  output: {svd:?}",
        P::NAME,
        P::show(a)
    );
}

/// The structural contract, which holds for any number of sweeps: finite output, rotations with
/// `det = +1`, sorted values, and `sigma.z < 0` exactly when `det a < 0` (wherever the determinant
/// is clear of rounding: `|det a| > 1e-3 s0^3` forces `|s2| >= |det a| / s0^2 > 1e-3 s0`, far above
/// any rounding of the smallest value). The sign is read from the sign bit: when `s2` underflows
/// to zero (subnormal inputs) it must still be `-0.0` for `det a < 0` and `+0.0` otherwise.
/// Returns the orthonormality error.
fn check_structure<P: Svd>(a: DMat3, svd: &Wide, reference: &Reference, context: &str) -> f64 {
    if !(svd.u.is_finite() && svd.sigma.is_finite() && svd.v.is_finite()) {
        fail::<P>(a, svd, context, "non-finite output".into());
    }
    let s = svd.sigma;
    if !(s.x >= s.y && s.y >= s.z.abs()) {
        fail::<P>(a, svd, context, "singular values out of order".into());
    }
    let orth = orthonormality_error(svd.u).max(orthonormality_error(svd.v));
    if orth > P::ORTH_TOL {
        fail::<P>(a, svd, context, format!("u or v not a rotation: {orth:e}"));
    }
    let s0 = reference.sigma_n.x;
    if reference.det_n.abs() > 1e-3 * s0 * s0 * s0
        && s.z.is_sign_negative() != (reference.det_n < 0.0)
    {
        fail::<P>(
            a,
            svd,
            context,
            format!(
                "sign of sigma.z disagrees with det a = {:e}",
                reference.det_n
            ),
        );
    }
    orth
}

/// The full contract of [`svd3`](softfem::svd::svd3) on one input (already rounded to `P`).
fn check_decomposition<P: Svd>(a: DMat3, context: &str) -> MaxErrors {
    let svd = P::svd(a);
    let reference = Reference::new::<P>(a);
    let orth = check_structure::<P>(a, &svd, &reference, context);

    if a == DMat3::ZERO {
        if svd.u != DMat3::IDENTITY || svd.v != DMat3::IDENTITY || svd.sigma != DVec3::ZERO {
            fail::<P>(
                a,
                &svd,
                context,
                "zero input must give u = v = I, sigma = 0".into(),
            );
        }
        return MaxErrors::default();
    }

    let sigma_n = reference.normalise(svd.sigma);
    let recon_n = svd.u * DMat3::from_diagonal(sigma_n) * svd.v.transpose();
    let norm_n = frobenius(reference.a_n);
    let recon = frobenius(recon_n - reference.a_n) / norm_n;
    // Rounding the three values to the subnormal grid moves the product by at most
    // `sqrt(3) / 2 quantum` (u and v are order one, unaffected).
    if recon.is_nan() || recon > P::RECON_TOL + reference.quantum_n / norm_n {
        fail::<P>(a, &svd, context, format!("reconstruction error {recon:e}"));
    }
    let s0 = reference.sigma_n.x;
    let sigma = (sigma_n - reference.sigma_n).abs().max_element() / s0;
    if sigma.is_nan() || sigma > P::SIGMA_TOL + reference.quantum_n / s0 {
        fail::<P>(
            a,
            &svd,
            context,
            format!(
                "singular values off by {sigma:e} s0 (reference {:?} * 2^{})",
                reference.sigma_n, reference.exponent
            ),
        );
    }
    MaxErrors { recon, orth, sigma }
}

// ---------------------------------------------------------------------------------------------
// Sweeps, special inputs, invariance.
// ---------------------------------------------------------------------------------------------

/// Matrices per class for the sweep-count and default-sweep checks.
const PER_CLASS_SWEEPS: usize = 150;

fn sweeps_keep_structure<P: Svd>() {
    for (class_index, class) in CLASSES.iter().enumerate() {
        for a in class_matrices::<P>(class_index, PER_CLASS_SWEEPS) {
            let reference = Reference::new::<P>(a);
            for sweeps in 0..=8 {
                let context = format!("{}, {sweeps} sweeps", class.label);
                check_structure::<P>(a, &P::svd_sweeps(a, sweeps), &reference, &context);
            }
        }
    }
}

#[test]
fn sweeps_0_to_8_keep_the_structural_contract() {
    sweeps_keep_structure::<F32>();
    sweeps_keep_structure::<F64>();
}

/// `svd3` is `svd3_sweeps(DEFAULT_SWEEPS)`, so the class tests prove the accuracy of the default.
fn default_is_default_sweeps<P: Svd>() {
    for class in 0..CLASSES.len() {
        for a in class_matrices::<P>(class, PER_CLASS_SWEEPS) {
            assert_eq!(
                P::svd(a),
                P::svd_sweeps(a, P::default_sweeps()),
                "{}: {}",
                P::NAME,
                P::show(a)
            );
        }
    }
}

#[test]
fn svd3_is_svd3_sweeps_with_default_sweeps() {
    default_is_default_sweeps::<F32>();
    default_is_default_sweeps::<F64>();
}

/// The sweeps stop once converged: a nearly diagonal matrix needs none, a nearly undeformed element
/// (`I + 1e-3 noise`, whose singular values are clustered within 1e-3) at most `near_identity`,
/// and extra sweeps then change no bit; general matrices still use the default count, so the
/// knob keeps its meaning.
fn sweeps_stop_once_converged<P: Svd>(near_identity: u32, tiny: f64) {
    let mut rng = Rng::new(0x5eed_c0de);
    // Diagonal up to off-diagonal entries `tiny`, far below the criterion (about 1e-4 eps of
    // the diagonal): converged before the first sweep. A sweep would still rotate by angles of
    // that size and change bits, so this tells stopping from running.
    let noise = DMat3::from_cols_array(&[0.0, 1.0, -1.0, 0.5, 0.0, 1.0, -0.5, 1.0, 0.0]);
    for diagonal in [DVec3::new(3.0, 2.0, 1.0), DVec3::new(2.0, -1.0, 0.5)] {
        let a = P::round(DMat3::from_diagonal(diagonal) + noise * tiny);
        assert_eq!(
            P::svd_sweeps(a, 0),
            P::svd_sweeps(a, 8),
            "{}: {}",
            P::NAME,
            P::show(a)
        );
    }
    for _ in 0..200 {
        let a = DMat3::IDENTITY + rng.entries() * 1e-3;
        let early = P::svd_sweeps(a, near_identity);
        assert_eq!(early, P::svd_sweeps(a, 8), "{}: {}", P::NAME, P::show(a));
    }
    let needing_all = (0..200)
        .map(|_| rng.entries())
        .filter(|&a| P::svd_sweeps(a, P::default_sweeps() - 1) != P::svd(a))
        .count();
    assert!(
        needing_all > 0,
        "{}: no random matrix used all sweeps",
        P::NAME
    );
}

#[test]
fn jacobi_sweeps_stop_once_converged() {
    // f64's criterion (eps = 2.2e-16) takes one sweep more than f32's.
    sweeps_stop_once_converged::<F32>(3, 1e-11);
    sweeps_stop_once_converged::<F64>(4, 1e-20);
}

/// The bits of a decomposition, so that NaN outputs compare equal to themselves.
fn bits(svd: &Wide) -> [u64; 21] {
    let mut out = [0; 21];
    let values = svd
        .u
        .to_cols_array()
        .into_iter()
        .chain(svd.sigma.to_array())
        .chain(svd.v.to_cols_array());
    for (bit, value) in out.iter_mut().zip(values) {
        *bit = value.to_bits();
    }
    out
}

/// `svd3_lanes` gives, lane by lane, exactly the bits `svd3` gives for the same matrix: over every
/// class, and in groups that mix ordinary, zero, non-finite, subnormal and huge matrices so that
/// the special cases of one lane cannot leak into another.
fn lanes_match_scalar<P: Svd>() {
    let mut groups: Vec<[DMat3; LANES]> = Vec::new();
    let all: Vec<DMat3> = (0..CLASSES.len())
        .flat_map(|class| class_matrices::<P>(class, PER_CLASS_SWEEPS))
        .collect();
    // Consecutive matrices of one class, then a shuffle across classes.
    groups.extend(
        all.chunks_exact(LANES)
            .map(|c| core::array::from_fn(|i| c[i])),
    );
    let mut rng = Rng::new(99);
    for _ in 0..all.len() / LANES {
        groups.push(core::array::from_fn(|_| all[rng.below(all.len())]));
    }
    let mut nan = DMat3::IDENTITY;
    nan.y_axis.z = f64::NAN;
    let specials = [
        DMat3::ZERO,
        nan,
        DMat3::from_diagonal(DVec3::splat(f64::INFINITY)),
    ];
    for (k, special) in specials.into_iter().enumerate() {
        for lane in 0..LANES {
            let mut group: [DMat3; LANES] =
                core::array::from_fn(|i| all[(k * 31 + i * 7) % all.len()]);
            group[lane] = P::round(special);
            groups.push(group);
        }
    }
    for group in &groups {
        let lanes = P::svd_lanes(*group);
        for (a, from_lanes) in group.iter().zip(&lanes) {
            let scalar = P::svd(*a);
            if bits(&scalar) != bits(from_lanes) {
                fail::<P>(
                    *a,
                    from_lanes,
                    "svd3_lanes",
                    format!("scalar svd3 gave {scalar:?}"),
                );
            }
        }
    }
}

#[test]
fn svd3_lanes_is_bitwise_svd3_per_matrix() {
    lanes_match_scalar::<F32>();
    lanes_match_scalar::<F64>();
}

/// Any NaN or infinite entry gives `u = v = I` and `sigma = (NaN, NaN, NaN)`, for any sweeps.
fn non_finite_input<P: Svd>() {
    let mut rng = Rng::new(7);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for entry in 0..9 {
            let mut entries = rng.entries().to_cols_array();
            entries[entry] = bad;
            let a = P::round(DMat3::from_cols_array(&entries));
            let outputs = [0, P::default_sweeps(), 8].map(|sweeps| P::svd_sweeps(a, sweeps));
            for svd in outputs.into_iter().chain([P::svd(a)]) {
                let documented = svd.u == DMat3::IDENTITY
                    && svd.v == DMat3::IDENTITY
                    && svd.sigma.is_nan_mask().all();
                if !documented {
                    fail::<P>(a, &svd, "non-finite input", "not (I, NaN, I)".into());
                }
            }
        }
    }
    let all_nan = P::svd(DMat3::NAN);
    assert!(all_nan.sigma.is_nan_mask().all() && all_nan.u == DMat3::IDENTITY);
}

#[test]
fn non_finite_input_gives_identity_and_nan() {
    non_finite_input::<F32>();
    non_finite_input::<F64>();
}

/// At the edge of the range, singular values equal to `MAX` are still exact; beyond it
/// (singular values above `MAX`) the routine still returns: the documented guarantee there is only
/// that it never panics and always terminates.
fn overflowing_input<P: Svd>() {
    let max = P::EXTREMES.max;
    for diagonal in [[max, -max, max], [max, max / 2.0, -max / 4.0]] {
        check_decomposition::<P>(DMat3::from_diagonal(DVec3::from_array(diagonal)), "edge");
    }
    for a in [
        DMat3::from_cols_array(&[max; 9]),
        DMat3::from_cols_array(&[max, -max, max, max, max, -max, -max, max, max]),
    ] {
        for sweeps in 0..=8 {
            std::hint::black_box(P::svd_sweeps(a, sweeps));
        }
    }
}

#[test]
fn range_edge_is_exact_and_overflow_returns() {
    overflowing_input::<F32>();
    overflowing_input::<F64>();
}

/// The zero matrix (either sign of zero), for every sweep count: `u = v = I`, `sigma = 0`.
fn zero_input<P: Svd>() {
    for a in [DMat3::ZERO, -DMat3::ZERO] {
        for sweeps in 0..=8 {
            let svd = P::svd_sweeps(a, sweeps);
            assert_eq!(svd.u, DMat3::IDENTITY, "{}", P::NAME);
            assert_eq!(svd.v, DMat3::IDENTITY, "{}", P::NAME);
            assert_eq!(svd.sigma, DVec3::ZERO, "{}", P::NAME);
        }
    }
}

#[test]
fn zero_input_gives_identity_and_zero() {
    zero_input::<F32>();
    zero_input::<F64>();
}

/// Closed forms a reader can check by hand: diagonal matrices with any signs and order have
/// `|entries|` sorted as singular values, the sign of the determinant on the last.
fn diagonal_closed_forms<P: Svd>() {
    let cases = [
        ([1.0, 1.0, 1.0], [1.0, 1.0, 1.0]),
        ([-1.0, -1.0, -1.0], [1.0, 1.0, -1.0]),
        ([2.0, -2.0, 2.0], [2.0, 2.0, -2.0]),
        ([3.0, 1.0, 2.0], [3.0, 2.0, 1.0]),
        ([0.5, -4.0, -2.0], [4.0, 2.0, 0.5]),
        ([0.0, 5.0, 0.0], [5.0, 0.0, 0.0]),
        ([-1e-3, 7.0, 2.0], [7.0, 2.0, -1e-3]),
    ];
    for (diagonal, expected) in cases {
        let a = P::round(DMat3::from_diagonal(DVec3::from_array(diagonal)));
        let svd = P::svd(a);
        let expected = P::round(DMat3::from_diagonal(DVec3::from_array(expected))).diagonal();
        let error = (svd.sigma - expected).abs().max_element() / expected.x;
        if error > P::SIGMA_TOL {
            fail::<P>(a, &svd, "diagonal", format!("expected {expected:?}"));
        }
        check_decomposition::<P>(a, "diagonal");
    }
}

#[test]
fn diagonal_matrices_give_sorted_signed_entries() {
    diagonal_closed_forms::<F32>();
    diagonal_closed_forms::<F64>();
}

/// `sigma(r a) = sigma(a) = sigma(a r^T)` for rotations `r`, and for well-separated singular
/// values the singular vectors rotate with `r` (up to the sign of each pair `u_i, v_i`).
///
/// Tolerances: each decomposition is within `SIGMA_TOL s0` of the exact values of its own input,
/// and rounding `r a` to the precision moves those by at most `||delta||_2 <= 3 eps s0`, so the
/// two agree within `3 SIGMA_TOL s0`. Singular vectors move by at most backward error / gap
/// (Wedin): with gaps `>= 0.3 s0` and backward errors below `RECON_TOL`, `20 RECON_TOL` is a safe
/// bound.
fn rotation_invariance<P: Svd>() {
    let mut rng = Rng::new(11);
    for i in 0..1000 {
        let a = P::round(match i % 4 {
            0 => rng.entries(),
            1 => conditioned(&mut rng, 1e3),
            2 => inverted(&mut rng, &P::EXTREMES),
            _ => rank_2(&mut rng, &P::EXTREMES),
        });
        let base = P::svd(a);
        let s0 = base.sigma.x;
        let r = rng.rotation();
        for rotated in [r * a, a * r.transpose(), r * a * rng.rotation()] {
            let rotated = P::round(rotated);
            let svd = P::svd(rotated);
            let error = (svd.sigma - base.sigma).abs().max_element();
            if error > 3.0 * P::SIGMA_TOL * s0 {
                fail::<P>(
                    rotated,
                    &svd,
                    "rotation invariance",
                    format!(
                        "sigma differs by {error:e} from {:?} of {}",
                        base.sigma,
                        P::show(a)
                    ),
                );
            }
        }
    }

    for _ in 0..500 {
        let s = DVec3::new(1.0, 0.6, 0.3 * rng.sign());
        let a = P::round(rng.rotated(s));
        let r = rng.rotation();
        let ra = P::round(r * a);
        let (base, svd) = (P::svd(a), P::svd(ra));
        for i in 0..3 {
            let expected_u = r * base.u.col(i);
            let sign = svd.u.col(i).dot(expected_u).signum();
            let error = (svd.u.col(i) - expected_u * sign)
                .length()
                .max((svd.v.col(i) - base.v.col(i) * sign).length());
            if error > 20.0 * P::RECON_TOL {
                fail::<P>(
                    ra,
                    &svd,
                    "rotation equivariance",
                    format!("singular vector {i} off by {error:e} (base {base:?})"),
                );
            }
        }
    }
}

#[test]
fn singular_values_are_rotation_invariant() {
    rotation_invariance::<F32>();
    rotation_invariance::<F64>();
}

/// The exact-rank generators really are exact: rounding to f32 changes nothing in the
/// short-mantissa constructions and the zero columns stay zero, so `det = 0` exactly.
#[test]
fn exact_rank_generators_are_exact() {
    let mut rng = Rng::new(5);
    for _ in 0..1000 {
        for a in [
            rank_1(&mut rng, &F32::EXTREMES),
            rank_2(&mut rng, &F32::EXTREMES),
        ] {
            let rounded = F32::round(a);
            assert_eq!(rounded.determinant(), 0.0, "{a:?}");
            let has_zero_column = (0..3).any(|i| rounded.col(i) == DVec3::ZERO)
                || (0..3).any(|i| rounded.row(i) == DVec3::ZERO);
            assert!(has_zero_column || rounded == a, "{a:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Property tests.
// ---------------------------------------------------------------------------------------------

/// An entry in `[-1, 1]`, exactly zero one time in five.
fn entry() -> impl Strategy<Value = f64> {
    prop_oneof![4 => -1.0f64..=1.0, 1 => Just(0.0)]
}

/// Decimal exponents of the overall scale: order one, moderate, the `1e±30` ends, anything that
/// keeps f32 entries finite.
fn decimal_exponent() -> impl Strategy<Value = i32> {
    prop_oneof![Just(0), -6i32..=6, Just(-30), Just(30), -36i32..=36]
}

/// `entries * 10^exponent`, with one column (0-2), one row (3-5) or one entry (6) scaled by
/// `1e-6` relative to the rest, or nothing (7).
fn mixed_scale_matrix(entries: [f64; 9], exponent: i32, mixing: usize) -> DMat3 {
    let mut a = DMat3::from_cols_array(&entries) * 10f64.powi(exponent);
    match mixing {
        0..=2 => *a.col_mut(mixing) *= 1e-6,
        3..=5 => {
            for col in 0..3 {
                a.col_mut(col)[mixing - 3] *= 1e-6;
            }
        }
        6 => a.x_axis.y *= 1e-6,
        _ => {}
    }
    a
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 400,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn prop_contract_on_mixed_scales(
        entries in prop::array::uniform9(entry()),
        exponent in decimal_exponent(),
        mixing in 0usize..8,
    ) {
        let a = mixed_scale_matrix(entries, exponent, mixing);
        check_decomposition::<F32>(F32::round(a), "proptest");
        check_decomposition::<F64>(a, "proptest");
    }

    #[test]
    fn prop_structure_for_any_sweeps(
        entries in prop::array::uniform9(entry()),
        exponent in decimal_exponent(),
        mixing in 0usize..8,
        sweeps in 0u32..=8,
    ) {
        let a = mixed_scale_matrix(entries, exponent, mixing);
        let a32 = F32::round(a);
        let (svd32, svd64) = (F32::svd_sweeps(a32, sweeps), F64::svd_sweeps(a, sweeps));
        check_structure::<F32>(a32, &svd32, &Reference::new::<F32>(a32), "proptest");
        check_structure::<F64>(a, &svd64, &Reference::new::<F64>(a), "proptest");
    }
}

// ---------------------------------------------------------------------------------------------
// The README table.
// ---------------------------------------------------------------------------------------------

/// Max recon and sigma errors per sweep count, over the normal-range classes.
fn sweep_errors<P: Svd>(sweeps: u32) -> MaxErrors {
    let mut max = MaxErrors::default();
    for (class_index, class) in CLASSES.iter().enumerate() {
        if class.subnormal {
            continue;
        }
        for a in class_matrices::<P>(class_index, PER_CLASS_SWEEPS) {
            if a == DMat3::ZERO {
                continue;
            }
            let svd = P::svd_sweeps(a, sweeps);
            let reference = Reference::new::<P>(a);
            let sigma_n = reference.normalise(svd.sigma);
            let recon_n = svd.u * DMat3::from_diagonal(sigma_n) * svd.v.transpose();
            max.absorb(MaxErrors {
                recon: frobenius(recon_n - reference.a_n) / frobenius(reference.a_n),
                orth: orthonormality_error(svd.u).max(orthonormality_error(svd.v)),
                sigma: (sigma_n - reference.sigma_n).abs().max_element() / reference.sigma_n.x,
            });
        }
    }
    max
}

/// Prints the maximum errors per class for both precisions (asserting the contract on every
/// matrix on the way, through the class checks), then the accuracy per sweep count. Run alone
/// with `cargo test --release --test kernels svd::report -- --nocapture`.
#[test]
fn report() {
    let (eps32, eps64) = (f64::from(f32::EPSILON), f64::EPSILON);
    let rule = |widths: &[usize]| {
        let cells: Vec<String> = widths.iter().map(|w| "-".repeat(w + 2)).collect();
        println!("|{}|", cells.join("|"));
    };
    println!();
    println!(
        "svd3 maximum errors, {PER_CLASS} matrices per class and precision \
         (f32: {} sweeps, eps = {eps32:.2e}; f64: {} sweeps, eps = {eps64:.2e})",
        F32::default_sweeps(),
        F64::default_sweeps()
    );
    println!("  recon = ||u diag(sigma) v^T - a||_F / ||a||_F");
    println!("  orth  = max over q = u, v of ||q^T q - I||_F and |det q - 1|");
    println!(
        "  sigma = max_i |sigma_i - reference_i| / s0 (reference: nalgebra f64 Golub-Kahan SVD)"
    );
    println!();
    println!(
        "| {:<31} | {:>9} | {:>9} | {:>9} | {:>9} | {:>9} | {:>9} |",
        "class", "f32 recon", "f32 orth", "f32 sigma", "f64 recon", "f64 orth", "f64 sigma"
    );
    rule(&[31, 9, 9, 9, 9, 9, 9]);
    let (mut all32, mut all64) = (MaxErrors::default(), MaxErrors::default());
    for (index, class) in CLASSES.iter().enumerate() {
        let (e32, e64) = (class_errors::<F32>(index), class_errors::<F64>(index));
        if !class.subnormal {
            all32.absorb(e32);
            all64.absorb(e64);
        }
        println!(
            "| {:<31} | {:>9.1e} | {:>9.1e} | {:>9.1e} | {:>9.1e} | {:>9.1e} | {:>9.1e} |",
            class.label, e32.recon, e32.orth, e32.sigma, e64.recon, e64.orth, e64.sigma
        );
    }
    println!(
        "| {:<31} | {:>9.1} | {:>9.1} | {:>9.1} | {:>9.1} | {:>9.1} | {:>9.1} |",
        "normal-range classes, in eps",
        all32.recon / eps32,
        all32.orth / eps32,
        all32.sigma / eps32,
        all64.recon / eps64,
        all64.orth / eps64,
        all64.sigma / eps64
    );
    println!();
    println!(
        "* singular values in the subnormal range are rounded to multiples of the smallest \
         subnormal ({:.1e} / {:.1e}); the error is that rounding, asserted as an absolute term",
        F32::EXTREMES.tiniest,
        F64::EXTREMES.tiniest
    );

    println!();
    println!(
        "svd3_sweeps maximum errors per sweep count \
         ({PER_CLASS_SWEEPS} matrices from each normal-range class)"
    );
    println!();
    println!(
        "| {:>6} | {:>9} | {:>9} | {:>9} | {:>9} |",
        "sweeps", "f32 recon", "f32 sigma", "f64 recon", "f64 sigma"
    );
    rule(&[6, 9, 9, 9, 9]);
    for sweeps in 0..=8 {
        let (e32, e64) = (sweep_errors::<F32>(sweeps), sweep_errors::<F64>(sweeps));
        let mark = |default: u32| if sweeps == default { "*" } else { " " };
        let (mark32, mark64) = (mark(F32::default_sweeps()), mark(F64::default_sweeps()));
        let cell = |value: f64, mark: &str| format!("{value:>8.1e}{mark}");
        println!(
            "| {sweeps:>6} | {} | {} | {} | {} |",
            cell(e32.recon, mark32),
            cell(e32.sigma, mark32),
            cell(e64.recon, mark64),
            cell(e64.sigma, mark64)
        );
    }
    println!();
    println!("* the default sweep count of that precision");
}

// ---------------------------------------------------------------------------------------------
// Extreme dynamic range (issue 16, D1).
// ---------------------------------------------------------------------------------------------

/// Signed permutations of `diag(big, 1, small)` (and with a zero column) for `big` up to the top
/// of the range: the two smaller values lie far below `eps big`, where the QR and 2x2 steps work
/// on entries under their rounding threshold. The structural contract must still hold exactly:
/// sorted, only `sigma.z` negative and only for `det a < 0` (exact here: a signed permutation of
/// a diagonal has determinant `±` the product, computed exactly from the f64 entries), for every
/// sweep count, and `svd3_lanes` must give the scalar bits.
fn extreme_dynamic_range<P: Svd>() {
    let mut rng = Rng::new(16);
    let top = P::EXTREMES.huge.log10() as i32;
    let mut cases = Vec::new();
    // The reported probes: columns (Y, big X, 0), and rows [[0, big, 0], [1, 0, 0], [0, 0, -0.5]].
    for e in 10..=top {
        let big = 10f64.powi(e);
        cases.push(DMat3::from_cols(DVec3::Y, DVec3::X * big, DVec3::ZERO));
        cases.push(DMat3::from_cols(DVec3::Y, DVec3::X * big, DVec3::Z * -0.5));
        for _ in 0..20 {
            let small = [0.0, 0.5, -0.5, 1e-3, -2.0][rng.below(5)];
            let p = signed_permutation(&mut rng);
            let q = signed_permutation(&mut rng);
            cases.push(p * DMat3::from_diagonal(DVec3::new(big, 1.0, small)) * q);
        }
    }
    for a in cases.into_iter().map(P::round) {
        let det = a.determinant();
        for sweeps in 0..=8 {
            let svd = P::svd_sweeps(a, sweeps);
            let s = svd.sigma;
            let sorted = s.x >= s.y && s.y >= s.z.abs();
            let signs_ok = s.x >= 0.0 && s.y >= 0.0 && (s.z >= 0.0 || det < 0.0);
            let sign_rule = det == 0.0 || (s.z < 0.0) == (det < 0.0);
            if !(sorted && signs_ok && sign_rule) {
                fail::<P>(
                    a,
                    &svd,
                    &format!("{sweeps} sweeps, det {det:e}"),
                    "contract".into(),
                );
            }
            let orth = orthonormality_error(svd.u).max(orthonormality_error(svd.v));
            if orth > P::ORTH_TOL {
                fail::<P>(
                    a,
                    &svd,
                    "extreme range",
                    format!("not a rotation: {orth:e}"),
                );
            }
        }
        // The largest value is exact to rounding; the reconstruction holds to eps ||a||.
        let svd = P::svd(a);
        let norm = frobenius(a);
        let recon = frobenius(svd.u * DMat3::from_diagonal(svd.sigma) * svd.v.transpose() - a);
        if recon > P::RECON_TOL * norm {
            fail::<P>(
                a,
                &svd,
                "extreme range",
                format!("reconstruction {recon:e}"),
            );
        }
        let lanes = P::svd_lanes([a, DMat3::IDENTITY, a.transpose(), -a]);
        if bits(&lanes[0]) != bits(&svd) || bits(&lanes[2]) != bits(&P::svd(a.transpose())) {
            fail::<P>(a, &lanes[0], "svd3_lanes", format!("scalar gave {svd:?}"));
        }
    }
}

#[test]
fn extreme_dynamic_range_keeps_the_structural_contract() {
    extreme_dynamic_range::<F32>();
    extreme_dynamic_range::<F64>();
}

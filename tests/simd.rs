//! `svd3_batch` gives, matrix by matrix, exactly the bits of `svd3`, at every SIMD width this
//! machine has and with each narrower width forced (`softfem::simd::set_max_width`), in both
//! precisions: for thousands of matrices of every class of tests/svd.rs (random, ill-conditioned,
//! near-singular, exactly rank 1 and 2, repeated and clustered singular values, reflections,
//! zero, scales from 1e-30 to 1e30, subnormal, the largest safe magnitudes) mixed with NaN and
//! infinite ones, for every batch length from 0 to 40 (so every tail of every group width), and
//! for every sweep count from 0 to 6. An output of the wrong length is an error that names both
//! lengths and leaves the output untouched.
//!
//! The reference is the scalar `svd3` itself: the claim under test is bit-identity, and the
//! accuracy of `svd3` is tests/svd.rs's business.
//!
//! `SOFTFEM_MAX_WIDTH=sse` (or `scalar`, `avx2`) caps the widest width these tests try.

mod common;

use std::sync::{Mutex, MutexGuard};

use common::Rng;
use softfem::glam::{DMat3, DVec3};
use softfem::simd::{self, Width};

/// The width cap is process-wide; tests that set it take turns.
static WIDTH_LOCK: Mutex<()> = Mutex::new(());

fn lock_width() -> MutexGuard<'static, ()> {
    WIDTH_LOCK
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The widths to test: every one this machine has, up to `SOFTFEM_MAX_WIDTH` if set.
fn widths() -> Vec<Width> {
    let cap = std::env::var("SOFTFEM_MAX_WIDTH")
        .ok()
        .map(|name| {
            Width::from_name(&name).expect("SOFTFEM_MAX_WIDTH: scalar, sse, avx2 or avx512")
        })
        .unwrap_or(Width::Avx512);
    let detected = simd::detected_width();
    Width::ALL
        .into_iter()
        .filter(|&width| width <= detected && width <= cap)
        .collect()
}

/// Matrices per class.
const PER_CLASS: usize = 400;

/// Magnitudes at the edges of a precision's range (as in tests/svd.rs).
struct Extremes {
    subnormal: f64,
    tiniest: f64,
    huge: f64,
    max: f64,
}

const F32_EXTREMES: Extremes = Extremes {
    subnormal: 1e-39,
    tiniest: 1.401298464324817e-45,
    huge: 1e37,
    max: f32::MAX as f64,
};

const F64_EXTREMES: Extremes = Extremes {
    subnormal: 1e-310,
    tiniest: 5e-324,
    huge: 1e307,
    max: f64::MAX,
};

/// `u diag(1, m, ±1/cond) v^T`.
fn conditioned(rng: &mut Rng, cond: f64) -> DMat3 {
    let middle = rng.log_uniform(1.0 / cond, 1.0);
    let smallest = rng.sign() / cond;
    rng.rotated(DVec3::new(1.0, middle, smallest))
}

fn outer(x: DVec3, y: DVec3) -> DMat3 {
    DMat3::from_cols(x * y.x, x * y.y, x * y.z)
}

/// One matrix of class `class` (the classes of tests/svd.rs, in its order, then non-finite).
fn class_matrix(class: usize, rng: &mut Rng, extremes: &Extremes) -> DMat3 {
    let short = |rng: &mut Rng, bits| DVec3::new(rng.short(bits), rng.short(bits), rng.short(bits));
    match class {
        0 => rng.entries(),
        1 => conditioned(rng, 1e3),
        2 => conditioned(rng, 1e6),
        3 => {
            let smallest = rng.sign() * 1e-9;
            rng.rotated(DVec3::new(1.0, 0.5, smallest))
        }
        // Exactly rank 2 and rank 1 (products of short mantissas are exact).
        4 => outer(short(rng, 8), short(rng, 8)) + outer(short(rng, 8), short(rng, 8)),
        5 => outer(short(rng, 12), short(rng, 12)),
        6 => {
            let middle = if rng.below(2) == 0 { 0.0 } else { 1.0 };
            rng.rotated(DVec3::new(1.0, middle, 0.0))
        }
        // Repeated singular values, plain and rotated.
        7 => {
            let d = DMat3::from_diagonal(
                [
                    DVec3::ONE,
                    DVec3::new(2.0, 1.0, 1.0),
                    DVec3::new(1.0, 1.0, 0.5),
                ][rng.below(3)],
            );
            match rng.below(3) {
                0 => d,
                1 => rng.rotation() * d,
                _ => {
                    let r = rng.rotation();
                    r * d * r.transpose()
                }
            }
        }
        8 => {
            if rng.below(2) == 0 {
                let delta = rng.log_uniform(1e-8, 1e-2);
                let middle = 1.0 - delta * rng.unit();
                rng.rotated(DVec3::new(1.0, middle, 1.0 - delta))
            } else {
                DMat3::IDENTITY + rng.entries() * rng.log_uniform(1e-8, 1e-3)
            }
        }
        // Reflections: det < 0.
        9 => match rng.below(3) {
            0 => -DMat3::IDENTITY,
            1 => DMat3::from_diagonal(DVec3::new(2.0, -2.0, 2.0)),
            _ => {
                let mut m = rng.entries();
                if m.determinant() > 0.0 {
                    m.x_axis = -m.x_axis;
                }
                m
            }
        },
        10 => DMat3::from_cols_array(&core::array::from_fn(|_| 0.0 * rng.sign())),
        11 => rng.entries() * 1e-30,
        12 => conditioned(rng, 1e3) * 1e30,
        13 => rng.entries() * extremes.subnormal,
        14 => DMat3::from_cols_array(&core::array::from_fn(|_| {
            (rng.below(9) as f64 - 4.0) * extremes.tiniest
        })),
        15 => {
            if rng.below(4) == 0 {
                DMat3::from_cols_array(&core::array::from_fn(|_| rng.sign() * extremes.max / 4.0))
            } else {
                rng.entries() * extremes.huge
            }
        }
        // Non-finite: one NaN or infinite entry, or entries beyond the range.
        _ => {
            let mut entries = rng.entries().to_cols_array();
            entries[rng.below(9)] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][rng.below(3)];
            DMat3::from_cols_array(&entries)
        }
    }
}

const CLASSES: usize = 17;

/// [`PER_CLASS`] matrices of every class, shuffled so that every group of lanes mixes classes,
/// then the same matrices class by class (groups of one class).
fn test_matrices(extremes: &Extremes) -> Vec<DMat3> {
    let mut rng = Rng::new(0x513d_2026);
    let by_class: Vec<DMat3> = (0..CLASSES)
        .flat_map(|class| {
            (0..PER_CLASS)
                .map(|_| class_matrix(class, &mut rng, extremes))
                .collect::<Vec<_>>()
        })
        .collect();
    let mut shuffled = by_class.clone();
    for i in (1..shuffled.len()).rev() {
        shuffled.swap(i, rng.below(i + 1));
    }
    shuffled.extend(by_class);
    shuffled
}

macro_rules! precision_tests {
    ($name:ident, $($svd:ident)::+, $mat:ty, $round:expr, $extremes:expr, $lanes:ident) => {
        mod $name {
            use super::*;
            use $($svd)::+::{Svd3, svd3, svd3_batch, svd3_batch_sweeps, svd3_sweeps};

            type Mat = $mat;

            fn inputs() -> Vec<Mat> {
                test_matrices(&$extremes).into_iter().map($round).collect()
            }

            /// Every float of a decomposition as bits (NaN outputs compare equal to themselves).
            fn bits(svd: &Svd3) -> Vec<u64> {
                svd.u
                    .to_cols_array()
                    .into_iter()
                    .chain(svd.sigma.to_array())
                    .chain(svd.v.to_cols_array())
                    .map(|x| f64::from(x).to_bits())
                    .collect()
            }

            /// `svd3_batch_sweeps` of `matrices` gives `svd3_sweeps`'s bits for each.
            fn assert_batch_is_scalar(matrices: &[Mat], sweeps: u32, width: Width) {
                let placeholder = svd3_sweeps(Mat::IDENTITY, 0);
                let mut out = vec![placeholder; matrices.len()];
                svd3_batch_sweeps(matrices, &mut out, sweeps).unwrap();
                for (i, (a, from_batch)) in matrices.iter().zip(&out).enumerate() {
                    let scalar = svd3_sweeps(*a, sweeps);
                    assert_eq!(
                        bits(from_batch),
                        bits(&scalar),
                        "width {width:?}, {} lanes, sweeps {sweeps}, length {}, matrix {i} \
                         = {:?}:\n batch  {from_batch:?}\n scalar {scalar:?}",
                        width.$lanes(),
                        matrices.len(),
                        a.to_cols_array(),
                    );
                }
            }

            #[test]
            fn batch_is_bitwise_svd3_at_every_width() {
                let inputs = inputs();
                let _guard = lock_width();
                for width in widths() {
                    simd::set_max_width(width);
                    assert_eq!(simd::active_width(), width);
                    // The whole set in one call (long runs of full groups, then a tail).
                    assert_batch_is_scalar(&inputs, softfem::svd::DEFAULT_SWEEPS, width);
                    // Every length from 0 to 40, at varying offsets into the set.
                    for len in 0..=40 {
                        for start in [0, 7 * len + 1, inputs.len() / 2 + 13 * len] {
                            assert_batch_is_scalar(
                                &inputs[start..start + len],
                                softfem::svd::DEFAULT_SWEEPS,
                                width,
                            );
                        }
                    }
                }
                simd::set_max_width(Width::Avx512);
            }

            #[test]
            fn batch_sweeps_are_bitwise_svd3_sweeps_at_every_width() {
                let inputs = inputs();
                let sample: Vec<Mat> = inputs.iter().step_by(7).copied().collect();
                let _guard = lock_width();
                for width in widths() {
                    simd::set_max_width(width);
                    for sweeps in 0..=6 {
                        assert_batch_is_scalar(&sample, sweeps, width);
                    }
                }
                simd::set_max_width(Width::Avx512);
            }

            #[test]
            fn default_batch_is_default_sweeps() {
                let inputs = inputs();
                let mut out = vec![svd3_sweeps(Mat::IDENTITY, 0); 37];
                svd3_batch(&inputs[..37], &mut out).unwrap();
                for (a, svd) in inputs.iter().zip(&out) {
                    assert_eq!(bits(svd), bits(&svd3(*a)));
                }
            }

            #[test]
            fn mismatched_lengths_are_an_error_and_leave_the_output_alone() {
                let inputs = inputs();
                let marker = svd3_sweeps(Mat::from_diagonal([3.0, 2.0, 1.0].into()), 4);
                for (n_in, n_out) in [(0, 1), (1, 0), (5, 4), (16, 17), (40, 39)] {
                    let mut out = vec![marker; n_out];
                    assert_eq!(
                        svd3_batch(&inputs[..n_in], &mut out),
                        Err(softfem::SvdBatchError::OutputLength {
                            expected: n_in,
                            actual: n_out
                        })
                    );
                    assert!(out.iter().all(|svd| bits(svd) == bits(&marker)));
                }
                let message = softfem::SvdBatchError::OutputLength {
                    expected: 5,
                    actual: 4,
                }
                .to_string();
                assert!(message.contains('5') && message.contains('4'), "{message}");
            }
        }
    };
}

precision_tests!(
    f32,
    softfem::svd,
    softfem::glam::Mat3,
    |m: DMat3| m.as_mat3(),
    F32_EXTREMES,
    lanes_f32
);
precision_tests!(
    f64,
    softfem::f64::svd,
    softfem::glam::DMat3,
    |m: DMat3| m,
    F64_EXTREMES,
    lanes_f64
);

/// The detected width is consistent with what the standard library detects (an independent
/// implementation of the same CPUID and XCR0 checks), and the cap works and is undone.
#[test]
fn detection_agrees_with_std_and_the_cap_applies() {
    #[cfg(target_arch = "x86_64")]
    {
        let expected = if std::arch::is_x86_feature_detected!("avx512f") {
            Width::Avx512
        } else if std::arch::is_x86_feature_detected!("avx2") {
            Width::Avx2
        } else {
            Width::Sse
        };
        assert_eq!(simd::detected_width(), expected);
    }
    let _guard = lock_width();
    for width in Width::ALL {
        simd::set_max_width(width);
        assert_eq!(simd::max_width(), width);
        assert_eq!(simd::active_width(), width.min(simd::detected_width()));
    }
    simd::set_max_width(Width::Avx512);
    assert_eq!(simd::active_width(), simd::detected_width());
}

#[test]
fn width_names_round_trip() {
    for width in Width::ALL {
        assert_eq!(Width::from_name(width.name()), Some(width));
        assert_eq!(Width::from_name(&width.name().to_uppercase()), Some(width));
    }
    assert_eq!(Width::from_name("avx"), None);
    assert_eq!(Width::ALL.map(Width::lanes_f32), [1, 4, 8, 16],);
    assert_eq!(Width::ALL.map(Width::lanes_f64), [1, 4, 4, 8]);
}

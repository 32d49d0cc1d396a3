//! Chart `svd`: the Jacobi SVD's error against its cost as the sweep count goes 1..6, in f32
//! and f64, scalar (`svd3_sweeps`) and four at a time (`svd3_lanes_sweeps`), with nalgebra's
//! `Matrix3::svd` in both precisions as reference points.
//!
//! The error of one decomposition is the larger of the singular-value error relative to the
//! largest singular value, against nalgebra's f64 `DMatrix` SVD of the same (already rounded)
//! input, and the reconstruction error `|u diag(s) v^T - a|_F / |a|_F` computed in f64. The
//! chart shows the worst over the batch.

use std::path::Path;

use nalgebra::{DMatrix, Matrix3};
use plotters::chart::SeriesLabelPosition;
use softfem::glam::{DMat3, DQuat, DVec3, Mat3};

use crate::chart::{Axis, Figure, Panel, Series, Style, Table, num};
use crate::measure::{ns_per_item, progress};
use crate::{Findings, Size};

/// The input batch: random entries in [-1, 1], deformation gradients near the identity, and
/// rotated matrices with singular values (1, 1e-3, 1e-6) (condition 1e6, the case that costs
/// Jacobi-on-`a^T a` codes their digits), a third each, a quarter of them mirrored.
pub fn batch(len: usize, seed: u64) -> Vec<DMat3> {
    let mut rng = Rng(seed | 1);
    (0..len)
        .map(|i| {
            let m = match i % 3 {
                0 => DMat3::from_cols_array(&std::array::from_fn(|_| rng.signed())),
                1 => {
                    DMat3::IDENTITY
                        + DMat3::from_cols_array(&std::array::from_fn(|_| rng.signed())) * 0.2
                }
                _ => {
                    let (u, v) = (rng.rotation(), rng.rotation());
                    u * DMat3::from_diagonal(DVec3::new(1.0, 1e-3, 1e-6)) * v.transpose()
                }
            };
            if i % 4 == 3 {
                m * DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0))
            } else {
                m
            }
        })
        .collect()
}

/// xorshift64*: deterministic inputs, no dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in [-1, 1).
    fn signed(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// A random rotation (normalised random quaternion).
    fn rotation(&mut self) -> DMat3 {
        let q = DQuat::from_xyzw(self.signed(), self.signed(), self.signed(), self.signed());
        DMat3::from_quat(q.normalize())
    }
}

/// The error of a decomposition `(u, sigma, v)` of `a` (all in f64): the larger of the
/// singular-value error relative to `s0` against `reference` (descending, non-negative) and the
/// relative reconstruction error.
pub fn error(a: DMat3, u: DMat3, sigma: DVec3, v: DMat3, reference: [f64; 3]) -> f64 {
    let scale = reference[0].max(f64::MIN_POSITIVE);
    let mut magnitudes = sigma.abs().to_array();
    magnitudes.sort_by(|x, y| y.total_cmp(x));
    let sigma_error = magnitudes
        .iter()
        .zip(reference)
        .map(|(s, r)| (s - r).abs() / scale)
        .fold(0.0, f64::max);
    let residual = u * DMat3::from_diagonal(sigma) * v.transpose() - a;
    let norm = |m: DMat3| m.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt();
    let reconstruction = norm(residual) / norm(a).max(f64::MIN_POSITIVE);
    // NaN (a failed decomposition) must not vanish in the max.
    if sigma_error.is_nan() || reconstruction.is_nan() {
        f64::NAN
    } else {
        sigma_error.max(reconstruction)
    }
}

/// The f64 reference singular values (descending) of `a`, from nalgebra's general `DMatrix`
/// SVD (its `Matrix3` SVD is itself off by up to 6e-14 `s0` at condition 1e6).
fn reference(a: DMat3) -> [f64; 3] {
    let m = DMatrix::from_column_slice(3, 3, &a.to_cols_array());
    let mut s: Vec<f64> = m.singular_values().iter().copied().collect();
    s.sort_by(|x, y| y.total_cmp(x));
    [s[0], s[1], s[2]]
}

/// One measured variant.
struct Point {
    variant: &'static str,
    precision: &'static str,
    sweeps: Option<u32>,
    ns: f64,
    worst_error: f64,
}

pub fn run(size: Size, out: &Path) -> Result<Findings, String> {
    let (len, repeats) = match size {
        Size::Quick => (384, 3),
        Size::Full => (3072, 25),
    };
    let inputs = batch(len, 0x5eed_2026);
    let inputs_f32: Vec<Mat3> = inputs.iter().map(DMat3::as_mat3).collect();
    // Each precision is measured against the reference of the matrix it actually receives.
    let rounded: Vec<DMat3> = inputs_f32.iter().map(Mat3::as_dmat3).collect();
    let refs_f64: Vec<[f64; 3]> = inputs.iter().map(|&a| reference(a)).collect();
    let refs_f32: Vec<[f64; 3]> = rounded.iter().map(|&a| reference(a)).collect();
    let worst = |errors: &mut dyn Iterator<Item = f64>| {
        errors.fold(0.0f64, |w, e| {
            if e.is_nan() || w.is_nan() {
                f64::NAN
            } else {
                w.max(e)
            }
        })
    };

    let mut points = Vec::new();
    progress(
        "svd",
        &format!("{len} matrices, sweeps 1..6, f32 and f64, scalar and 4-lane"),
    );
    for sweeps in 1..=6u32 {
        let scalar32 = |a: &Mat3| softfem::svd::svd3_sweeps(*a, sweeps);
        let scalar64 = |a: &DMat3| softfem::f64::svd::svd3_sweeps(*a, sweeps);
        let e32 = worst(&mut inputs_f32.iter().zip(&rounded).zip(&refs_f32).map(
            |((a, &a64), r)| {
                let s = scalar32(a);
                error(a64, s.u.as_dmat3(), s.sigma.as_dvec3(), s.v.as_dmat3(), *r)
            },
        ));
        let e64 = worst(&mut inputs.iter().zip(&refs_f64).map(|(a, r)| {
            let s = scalar64(a);
            error(*a, s.u, s.sigma, s.v, *r)
        }));
        let ns32 = ns_per_item(repeats, len, || {
            inputs_f32.iter().map(|a| scalar32(a).sigma.x).sum::<f32>()
        });
        let ns64 = ns_per_item(repeats, len, || {
            inputs.iter().map(|a| scalar64(a).sigma.x).sum::<f64>()
        });
        let lanes32 = ns_per_item(repeats, len, || {
            inputs_f32
                .chunks_exact(4)
                .map(|c| {
                    softfem::svd::svd3_lanes_sweeps(&[c[0], c[1], c[2], c[3]], sweeps)[0]
                        .sigma
                        .x
                })
                .sum::<f32>()
        });
        let lanes64 = ns_per_item(repeats, len, || {
            inputs
                .chunks_exact(4)
                .map(|c| {
                    softfem::f64::svd::svd3_lanes_sweeps(&[c[0], c[1], c[2], c[3]], sweeps)[0]
                        .sigma
                        .x
                })
                .sum::<f64>()
        });
        // svd3_lanes returns per lane the bits svd3 returns (tested in tests/kernels/svd.rs), so
        // the lanes share the scalar errors.
        for (variant, precision, ns, worst_error) in [
            ("softfem svd3_sweeps", "f32", ns32, e32),
            ("softfem svd3_sweeps", "f64", ns64, e64),
            ("softfem svd3_lanes_sweeps", "f32", lanes32, e32),
            ("softfem svd3_lanes_sweeps", "f64", lanes64, e64),
        ] {
            points.push(Point {
                variant,
                precision,
                sweeps: Some(sweeps),
                ns,
                worst_error,
            });
        }
        progress(
            "svd",
            &format!(
                "{sweeps} sweeps: f32 {ns32:.0} ns, error {e32:.1e}; f64 {ns64:.0} ns, error {e64:.1e}"
            ),
        );
    }
    let na32: Vec<Matrix3<f32>> = inputs_f32
        .iter()
        .map(|m| Matrix3::from_column_slice(&m.to_cols_array()))
        .collect();
    let na64: Vec<Matrix3<f64>> = inputs
        .iter()
        .map(|m| Matrix3::from_column_slice(&m.to_cols_array()))
        .collect();
    let to_dmat3 = |m: Matrix3<f64>| DMat3::from_cols_slice(m.as_slice());
    let e_na32 = worst(
        &mut na32
            .iter()
            .zip(&rounded)
            .zip(&refs_f32)
            .map(|((m, &a), r)| {
                let svd = m.svd(true, true);
                let (u, vt) = (svd.u.unwrap().cast::<f64>(), svd.v_t.unwrap().cast::<f64>());
                let s = svd.singular_values.cast::<f64>();
                error(
                    a,
                    to_dmat3(u),
                    DVec3::new(s[0], s[1], s[2]),
                    to_dmat3(vt.transpose()),
                    *r,
                )
            }),
    );
    let e_na64 = worst(
        &mut na64.iter().zip(&inputs).zip(&refs_f64).map(|((m, &a), r)| {
            let svd = m.svd(true, true);
            let s = svd.singular_values;
            error(
                a,
                to_dmat3(svd.u.unwrap()),
                DVec3::new(s[0], s[1], s[2]),
                to_dmat3(svd.v_t.unwrap().transpose()),
                *r,
            )
        }),
    );
    let ns_na32 = ns_per_item(repeats, len, || {
        na32.iter()
            .map(|m| m.svd(true, true).singular_values[0])
            .sum::<f32>()
    });
    let ns_na64 = ns_per_item(repeats, len, || {
        na64.iter()
            .map(|m| m.svd(true, true).singular_values[0])
            .sum::<f64>()
    });
    points.push(Point {
        variant: "nalgebra Matrix3::svd",
        precision: "f32",
        sweeps: None,
        ns: ns_na32,
        worst_error: e_na32,
    });
    points.push(Point {
        variant: "nalgebra Matrix3::svd",
        precision: "f64",
        sweeps: None,
        ns: ns_na64,
        worst_error: e_na64,
    });

    let mut table = Table::new(&[
        "variant",
        "precision",
        "sweeps",
        "ns_per_decomposition",
        "worst_error",
        "matrices",
    ]);
    for p in &points {
        table.push(vec![
            p.variant.into(),
            p.precision.into(),
            p.sweeps.map_or(String::new(), |s| s.to_string()),
            num(p.ns),
            num(p.worst_error),
            len.to_string(),
        ]);
    }
    table.write(&out.join("svd.csv"))?;

    let series_of = |variant: &str, precision: &str, style: Style, color: usize| {
        let chosen: Vec<&Point> = points
            .iter()
            .filter(|p| p.variant == variant && p.precision == precision)
            .collect();
        Series::new(
            &format!("{variant} {precision}"),
            style,
            color,
            chosen.iter().map(|p| (p.ns, p.worst_error)).collect(),
        )
        .with_labels(
            chosen
                .iter()
                .map(|p| p.sweeps.map_or(String::new(), |s| format!("{s}")))
                .collect(),
        )
    };
    let figure = Figure {
        title: "3x3 SVD: worst error against cost, 1..6 Jacobi sweeps (labels: sweeps)".into(),
        panels: vec![
            Panel::new(
                &format!(
                    "{len} matrices: random, near identity, condition 1e6; a quarter mirrored"
                ),
                Axis::log("ns per decomposition (this machine, one thread)"),
                Axis::log("worst error (singular values / s0, reconstruction)"),
                vec![
                    series_of("softfem svd3_sweeps", "f32", Style::LinePoints, 0),
                    series_of("softfem svd3_sweeps", "f64", Style::LinePoints, 1),
                    series_of("softfem svd3_lanes_sweeps", "f32", Style::LinePoints, 5),
                    series_of("softfem svd3_lanes_sweeps", "f64", Style::LinePoints, 4),
                    series_of("nalgebra Matrix3::svd", "f32", Style::Points, 6)
                        .with_labels(vec!["nalgebra f32".into()]),
                    series_of("nalgebra Matrix3::svd", "f64", Style::Points, 7)
                        .with_labels(vec!["nalgebra f64".into()]),
                ],
            )
            .with_legend(SeriesLabelPosition::LowerLeft),
        ],
    };
    figure.write(&out.join("svd.svg"))?;

    let at = |variant: &str, precision: &str, sweeps: Option<u32>| {
        points
            .iter()
            .find(|p| p.variant == variant && p.precision == precision && p.sweeps == sweeps)
            .map_or((f64::NAN, f64::NAN), |p| (p.ns, p.worst_error))
    };
    let mut findings = Findings::new("svd");
    for sweeps in [1, 2, 3, 4, 6] {
        let (ns32, e32) = at("softfem svd3_sweeps", "f32", Some(sweeps));
        let (ns64, e64) = at("softfem svd3_sweeps", "f64", Some(sweeps));
        let (lanes, _) = at("softfem svd3_lanes_sweeps", "f32", Some(sweeps));
        findings.line(format!("{sweeps} sweeps: f32 {ns32:.0} ns (lanes {lanes:.0} ns) error {e32:.1e}; f64 {ns64:.0} ns error {e64:.1e}"));
    }
    findings.line(format!("nalgebra Matrix3::svd: f32 {ns_na32:.0} ns error {e_na32:.1e}; f64 {ns_na64:.0} ns error {e_na64:.1e}"));
    Ok(findings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_error_measure_is_zero_for_an_exact_decomposition_and_sees_a_wrong_one() {
        let a = DMat3::from_diagonal(DVec3::new(3.0, 2.0, -1.0));
        let exact = error(
            a,
            DMat3::IDENTITY,
            DVec3::new(3.0, 2.0, -1.0),
            DMat3::IDENTITY,
            [3.0, 2.0, 1.0],
        );
        assert_eq!(exact, 0.0);
        let off = error(
            a,
            DMat3::IDENTITY,
            DVec3::new(3.0, 2.0, -1.3),
            DMat3::IDENTITY,
            [3.0, 2.0, 1.0],
        );
        assert!((off - 0.1).abs() < 1e-12, "{off}");
        assert!(
            error(
                a,
                DMat3::IDENTITY,
                DVec3::NAN,
                DMat3::IDENTITY,
                [3.0, 2.0, 1.0]
            )
            .is_nan()
        );
    }

    #[test]
    fn the_batch_mixes_its_classes_and_the_reference_is_nalgebras() {
        let inputs = batch(12, 7);
        assert_eq!(inputs.len(), 12);
        assert!(inputs.iter().filter(|a| a.determinant() < 0.0).count() >= 3);
        let graded = reference(inputs[2]);
        assert!(
            (graded[0] - 1.0).abs() < 1e-12 && (graded[2] - 1e-6).abs() < 1e-15,
            "{graded:?}"
        );
    }
}

//! The polar decomposition `a = rotation * stretch` built on the rotation-variant SVD, in both
//! precisions: `rotation` a proper rotation, `stretch` symmetric, the product reconstructing `a`,
//! and an inverted `a` showing up as one negative principal stretch instead of a reflection.
//!
//! Checks are written once against the [`Polar`] trait and run for `f32` (crate root) and
//! `f64` (`softfem::f64`); errors are measured in f64 from the outputs widened exactly.

use crate::common::{F32, F64, Precision, Rng, frobenius};
use nalgebra::{Matrix3, SymmetricEigen};
use softfem::glam::{DMat3, DVec3};

/// A polar decomposition widened to f64 (exact for f32 outputs).
#[derive(Clone, Copy, Debug)]
struct Wide {
    rotation: DMat3,
    stretch: DMat3,
}

/// One precision of softfem's polar decomposition, with the tolerances of its SVD
/// ([`Precision`]; `tests/kernels/svd.rs` checks them: about 80 / 450 eps for orthonormality, 17 /
/// 450 eps for the reconstruction). Forming `u v^T` and `v diag(sigma) v^T` adds a few more
/// roundings, each far below those margins.
trait Polar: Precision {
    fn polar(a: DMat3) -> Wide;
    /// Whether `Polar3::from_svd(&svd3(a))` equals `polar3(a)` exactly.
    fn from_svd_is_polar3(a: DMat3) -> bool;
}

impl Polar for F32 {
    fn polar(a: DMat3) -> Wide {
        let polar = softfem::polar::polar3(a.as_mat3());
        Wide {
            rotation: polar.rotation.as_dmat3(),
            stretch: polar.stretch.as_dmat3(),
        }
    }

    fn from_svd_is_polar3(a: DMat3) -> bool {
        let a = a.as_mat3();
        softfem::polar::Polar3::from_svd(&softfem::svd::svd3(a)) == softfem::polar::polar3(a)
    }
}

impl Polar for F64 {
    fn polar(a: DMat3) -> Wide {
        let polar = softfem::f64::polar::polar3(a);
        Wide {
            rotation: polar.rotation,
            stretch: polar.stretch,
        }
    }

    fn from_svd_is_polar3(a: DMat3) -> bool {
        softfem::f64::polar::Polar3::from_svd(&softfem::f64::svd::svd3(a))
            == softfem::f64::polar::polar3(a)
    }
}

/// Eigenvalues of the symmetric part of `m`, ascending (nalgebra, f64).
fn eigenvalues(m: DMat3) -> [f64; 3] {
    let symmetric = (m + m.transpose()) * 0.5;
    let eigen = SymmetricEigen::new(Matrix3::from_column_slice(&symmetric.to_cols_array()));
    let mut values = [
        eigen.eigenvalues[0],
        eigen.eigenvalues[1],
        eigen.eigenvalues[2],
    ];
    values.sort_by(f64::total_cmp);
    values
}

fn fail<P: Polar>(a: DMat3, polar: &Wide, what: String) -> ! {
    panic!(
        "{} polar3: {what}\n  input:  {}\n  output: {polar:?}",
        P::NAME,
        P::show(a)
    );
}

/// The contract on one input (already rounded to `P`): proper rotation, symmetric stretch,
/// reconstruction, and, where `det a` is clear of rounding (`|det a| > 1e-3 ||a||_F^3`, so the
/// smallest principal stretch is at least `1e-3 s0` in magnitude), the sign pattern of the
/// stretch: positive definite for `det a > 0`, exactly one negative eigenvalue for `det a < 0`.
fn check_polar<P: Polar>(a: DMat3) -> Wide {
    let polar = P::polar(a);
    let Wide { rotation, stretch } = polar;
    if !(rotation.is_finite() && stretch.is_finite()) {
        fail::<P>(a, &polar, "non-finite output".into());
    }
    let orth = frobenius(rotation.transpose() * rotation - DMat3::IDENTITY)
        .max((rotation.determinant() - 1.0).abs());
    if orth > P::ORTH_TOL {
        fail::<P>(a, &polar, format!("rotation not a rotation: {orth:e}"));
    }
    let norm = frobenius(a);
    // `stretch = v diag(sigma) v^T` is symmetric up to the different rounding of its two
    // triangles: a few eps ||stretch||, and ||stretch||_F = ||a||_F.
    let asymmetry = frobenius(stretch - stretch.transpose());
    if asymmetry > P::RECON_TOL * norm {
        fail::<P>(a, &polar, format!("stretch not symmetric: {asymmetry:e}"));
    }
    let recon = frobenius(rotation * stretch - a);
    if recon > P::RECON_TOL * norm {
        fail::<P>(
            a,
            &polar,
            format!("reconstruction error {:e}", recon / norm),
        );
    }
    let det = a.determinant();
    if det.abs() > 1e-3 * norm * norm * norm {
        let values = eigenvalues(stretch);
        let negative = values.iter().filter(|&&x| x < 0.0).count();
        let expected = if det < 0.0 { 1 } else { 0 };
        if negative != expected || (stretch.determinant() < 0.0) != (det < 0.0) {
            fail::<P>(
                a,
                &polar,
                format!("stretch eigenvalues {values:?} for det a = {det:e}"),
            );
        }
    }
    polar
}

/// A mix of the SVD test classes: random, ill-conditioned, inverted, rank-deficient, scaled.
fn sample(rng: &mut Rng, i: usize) -> DMat3 {
    match i % 7 {
        0 => rng.entries(),
        1 => {
            let s = DVec3::new(1.0, rng.uniform(1e-3, 1.0), 1e-3);
            rng.rotated(s)
        }
        2 => {
            let s = DVec3::new(1.0, rng.uniform(0.2, 1.0), -rng.uniform(0.01, 0.2));
            rng.rotated(s)
        }
        3 => {
            let mut m = rng.entries();
            m.z_axis = DVec3::ZERO;
            rng.rotation() * m
        }
        4 => rng.rotated(DVec3::new(1.0, 1.0, -1.0)),
        5 => rng.entries() * 1e-30,
        _ => rng.entries() * 1e30,
    }
}

fn contract<P: Polar>() {
    let mut rng = Rng::new(3);
    for i in 0..3000 {
        check_polar::<P>(P::round(sample(&mut rng, i)));
    }
}

#[test]
fn rotation_is_proper_stretch_symmetric_product_reconstructs() {
    contract::<F32>();
    contract::<F64>();
}

/// Inverted inputs, including `-I` and a plain reflection: the rotation stays proper and the
/// stretch takes the inversion as exactly one negative eigenvalue, the smallest in magnitude.
fn inverted<P: Polar>() {
    let mut rng = Rng::new(5);
    let mut inputs = vec![
        -DMat3::IDENTITY,
        DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0)),
        DMat3::from_diagonal(DVec3::new(2.0, -2.0, 2.0)),
    ];
    for _ in 0..1000 {
        let mut m = rng.entries();
        if m.determinant() > 0.0 {
            m.y_axis = -m.y_axis;
        }
        inputs.push(m);
    }
    for a in inputs {
        let a = P::round(a);
        if a.determinant().abs() <= 1e-3 * frobenius(a).powi(3) {
            continue;
        }
        let polar = check_polar::<P>(a);
        let values = eigenvalues(polar.stretch);
        // Ascending, one negative: it must also be the smallest in magnitude (the rotation-variant
        // convention puts the sign on the smallest singular value).
        if !(values[0] < 0.0 && -values[0] <= values[1] + P::RECON_TOL * frobenius(a)) {
            fail::<P>(a, &polar, format!("stretch eigenvalues {values:?}"));
        }
    }
}

#[test]
fn inverted_input_gives_one_negative_stretch_and_a_proper_rotation() {
    inverted::<F32>();
    inverted::<F64>();
}

fn from_svd<P: Polar>() {
    let mut rng = Rng::new(7);
    for i in 0..1000 {
        let a = P::round(sample(&mut rng, i));
        assert!(P::from_svd_is_polar3(a), "{}: {}", P::NAME, P::show(a));
    }
}

#[test]
fn from_svd_equals_polar3() {
    from_svd::<F32>();
    from_svd::<F64>();
}

/// Closed forms `a = r s` with a known rotation `r` and symmetric `s` whose eigenvalues are
/// distinct in magnitude (so the factors are unique), recovered within
/// `10 RECON_TOL`: the polar factors of `a + delta` move by at most `2 ||delta|| / (s_i + s_j)`
/// (Higham, *Functions of Matrices*, 8.1), here with `s_i + s_j >= 1` for the positive cases and
/// `|s_i| - |s_j| >= 0.5` for the inverted one, and `||delta||` is the input rounding plus the
/// decomposition's backward error, both below `2 RECON_TOL ||a||` with `||a|| <= 4`.
fn closed_forms<P: Polar>() {
    let about_z = DMat3::from_rotation_z(0.7);
    let axis = DVec3::new(1.0, -2.0, 0.5).normalize();
    let about_axis = DMat3::from_axis_angle(axis, -2.1);
    let symmetric = {
        let q = DMat3::from_rotation_x(0.3) * DMat3::from_rotation_y(1.1);
        q * DMat3::from_diagonal(DVec3::new(2.5, 1.5, 0.75)) * q.transpose()
    };
    let cases = [
        (about_z, DMat3::from_diagonal(DVec3::new(3.0, 2.0, 0.5))),
        (
            DMat3::from_rotation_z(core::f64::consts::FRAC_PI_2),
            DMat3::from_diagonal(DVec3::new(3.0, 1.0, 1.0)),
        ),
        (about_axis, symmetric),
        (about_axis, DMat3::IDENTITY),
        (DMat3::IDENTITY, symmetric),
        (about_z, DMat3::from_diagonal(DVec3::new(2.0, 1.0, -0.5))),
        // The inversion moves to the smallest stretch: `r diag(1, -3, 2)` is
        // `(r diag(-1, -1, 1)) diag(-1, 3, 2)`.
        (
            about_axis * DMat3::from_diagonal(DVec3::new(-1.0, -1.0, 1.0)),
            DMat3::from_diagonal(DVec3::new(-1.0, 3.0, 2.0)),
        ),
    ];
    let inputs = cases.map(|(rotation, stretch)| rotation * stretch);
    assert_eq!(
        inputs[6],
        about_axis * DMat3::from_diagonal(DVec3::new(1.0, -3.0, 2.0))
    );
    for ((rotation, stretch), a) in cases.into_iter().zip(inputs) {
        let a = P::round(a);
        let polar = check_polar::<P>(a);
        let rotation_error = frobenius(polar.rotation - rotation);
        let stretch_error = frobenius(polar.stretch - stretch) / frobenius(stretch);
        if rotation_error > 10.0 * P::RECON_TOL || stretch_error > 10.0 * P::RECON_TOL {
            fail::<P>(
                a,
                &polar,
                format!(
                    "expected rotation {rotation:?}, stretch {stretch:?}: errors \
                     {rotation_error:e}, {stretch_error:e}"
                ),
            );
        }
    }
}

#[test]
fn closed_form_rotation_times_stretch_is_recovered() {
    closed_forms::<F32>();
    closed_forms::<F64>();
}

/// `polar(q a) = (q rotation, stretch)` for rotations `q`: the stretch is frame-indifferent and
/// the rotation is equivariant. Inputs have well-separated singular values (`s_i + s_j >= 1.2`, and
/// `s1 - |s2| >= 0.4` when inverted), so by the same perturbation bound as [`closed_forms`] both
/// factors move by well under `10 RECON_TOL`.
fn equivariance<P: Polar>() {
    let mut rng = Rng::new(11);
    for _ in 0..1000 {
        let sign = if rng.unit() < 0.5 { 1.0 } else { -1.0 };
        let s = DVec3::new(
            rng.uniform(1.5, 2.0),
            rng.uniform(0.8, 1.2),
            sign * rng.uniform(0.2, 0.4),
        );
        let a = P::round(rng.rotated(s));
        let q = rng.rotation();
        let qa = P::round(q * a);
        let (base, turned) = (P::polar(a), P::polar(qa));
        let rotation_error = frobenius(turned.rotation - q * base.rotation);
        let stretch_error = frobenius(turned.stretch - base.stretch) / frobenius(a);
        if rotation_error > 10.0 * P::RECON_TOL || stretch_error > 10.0 * P::RECON_TOL {
            fail::<P>(
                qa,
                &turned,
                format!(
                    "not equivariant: errors {rotation_error:e}, {stretch_error:e} \
                     (q a for a = {})",
                    P::show(a)
                ),
            );
        }
    }
}

#[test]
fn rotation_equivariance() {
    equivariance::<F32>();
    equivariance::<F64>();
}

/// Documented special inputs: non-finite gives the identity rotation and a NaN stretch, zero
/// gives the identity rotation and a zero stretch.
fn special_inputs<P: Polar>() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for entry in 0..9 {
            let mut entries = [0.5; 9];
            entries[entry] = bad;
            let a = P::round(DMat3::from_cols_array(&entries));
            let polar = P::polar(a);
            let all_nan = polar.stretch.to_cols_array().iter().all(|x| x.is_nan());
            if polar.rotation != DMat3::IDENTITY || !all_nan {
                fail::<P>(a, &polar, "expected (I, NaN)".into());
            }
        }
    }
    for a in [DMat3::ZERO, -DMat3::ZERO] {
        let polar = P::polar(a);
        assert_eq!(polar.rotation, DMat3::IDENTITY, "{}", P::NAME);
        assert_eq!(polar.stretch, DMat3::ZERO, "{}", P::NAME);
    }
}

#[test]
fn non_finite_and_zero_input() {
    special_inputs::<F32>();
    special_inputs::<F64>();
}

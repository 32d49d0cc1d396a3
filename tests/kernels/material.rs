//! The material models against the identities of `docs/math.md` sections 2 and 5, hand-derived closed
//! forms, and the failure modes each model is documented to have, in both precisions.
//!
//! The test code is written once, in `material_tests!`, and instantiated for the `f32` API at
//! the crate root and the `f64` API under `softfem::f64`. Tolerances are expressed in the
//! machine epsilon of the precision (`EPS`), each with the reasoning that sizes it.

macro_rules! material_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use crate::common::{Rng, for_each_model, material_helpers};
            use $($api)::+::MaterialError;
            use $($api)::+::material::{Lame, Material, NeoHookean, StVK, StableNeoHookean};
            use $($api)::+::svd::svd3;
            use $($api)::+::types::{Mat3, Real, Vec3};

            material_helpers!();

            fn diag(x: Real, y: Real, z: Real) -> Mat3 {
                Mat3::from_diagonal(Vec3::new(x, y, z))
            }

            fn random_rotation(rng: &mut Rng) -> Mat3 {
                loop {
                    let axis = Vec3::new(
                        uniform(rng, -1.0, 1.0),
                        uniform(rng, -1.0, 1.0),
                        uniform(rng, -1.0, 1.0),
                    );
                    if axis.length() > 0.1 {
                        let angle = uniform(rng, 0.0, 2.0 * core::f64::consts::PI as Real);
                        return Mat3::from_axis_angle(axis.normalize(), angle);
                    }
                }
            }

            /// `R1 diag(s) R2^T` with stretches in `[0.6, 1.6]`, far enough from rest that the
            /// stress is of order `modulus`, and from `J = 0` that every model is smooth. With
            /// `inverted`, the last stretch is negated (`J < 0`).
            fn random_deformation(rng: &mut Rng, inverted: bool) -> Mat3 {
                let sign = if inverted { -1.0 } else { 1.0 };
                let s = Vec3::new(
                    uniform(rng, 0.6, 1.6),
                    uniform(rng, 0.6, 1.6),
                    sign * uniform(rng, 0.6, 1.6),
                );
                random_rotation(rng) * Mat3::from_diagonal(s) * random_rotation(rng).transpose()
            }

            /// Random deformations, half of them inverted. The isochoric neo-Hookean is included in
            /// the inverted half too: its real-cube-root branch is defined and smooth there.
            fn deformations(count: usize) -> impl Iterator<Item = Mat3> {
                let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
                (0..count).map(move |i| random_deformation(&mut rng, i % 2 == 1))
            }

            fn name<M>() -> &'static str {
                core::any::type_name::<M>().rsplit("::").next().unwrap()
            }

            // ---- Parameters -----------------------------------------------------------------

            #[test]
            fn young_poisson_converts_to_lame() {
                let (e, nu) = (3.0e6, 0.25);
                // lambda = E nu / ((1 + nu)(1 - 2 nu)) = 0.75e6 / (1.25 * 0.5) = 1.2e6,
                // mu = E / (2 (1 + nu)) = 3e6 / 2.5 = 1.2e6.
                let lame = Lame::from_young_poisson(e, nu).unwrap();
                assert!((lame.lambda() - 1.2e6).abs() <= 4.0 * EPS * 1.2e6);
                assert!((lame.mu() - 1.2e6).abs() <= 4.0 * EPS * 1.2e6);
                assert!((lame.bulk_modulus() - 2.0e6).abs() <= 4.0 * EPS * 2.0e6);
                let stvk = StVK::from_young_poisson(e, nu).unwrap();
                let nh = NeoHookean::from_young_poisson(e, nu).unwrap();
                let snh = StableNeoHookean::from_young_poisson(e, nu).unwrap();
                for (lambda, mu) in [
                    (stvk.lambda(), stvk.mu()),
                    (nh.lambda(), nh.mu()),
                    (snh.lambda(), snh.mu()),
                ] {
                    assert_eq!((lambda, mu), (lame.lambda(), lame.mu()));
                }
                assert_eq!(StVK::from_lame(1.0, 2.0).unwrap().lame(), Lame::new(1.0, 2.0).unwrap());
            }

            #[test]
            fn invalid_parameters_are_rejected() {
                use MaterialError::*;
                let nan = Real::NAN;
                let inf = Real::INFINITY;
                for (lambda, mu, error) in [
                    (nan, 1.0, Lambda),
                    (inf, 1.0, Lambda),
                    (-inf, 1.0, Lambda),
                    (1.0, 0.0, Mu),
                    (1.0, -1.0, Mu),
                    (1.0, nan, Mu),
                    (1.0, inf, Mu),
                    // K = lambda + 2 mu / 3 = -1 + 1 = 0 exactly: no resistance to compression.
                    (-1.0, 1.5, BulkModulus),
                    (-2.0, 1.0, BulkModulus),
                ] {
                    assert_eq!(Lame::new(lambda, mu), Err(error), "lambda {lambda}, mu {mu}");
                    assert_eq!(StVK::from_lame(lambda, mu), Err(error));
                    assert_eq!(NeoHookean::from_lame(lambda, mu), Err(error));
                    assert_eq!(StableNeoHookean::from_lame(lambda, mu), Err(error));
                }
                // Negative lambda with K > 0 (auxetic) is a valid material.
                assert!(Lame::new(-0.5, 1.0).is_ok());
                for (e, nu, error) in [
                    (0.0, 0.3, YoungModulus),
                    (-1.0, 0.3, YoungModulus),
                    (nan, 0.3, YoungModulus),
                    (inf, 0.3, YoungModulus),
                    (1.0, 0.5, PoissonRatio),
                    (1.0, -1.0, PoissonRatio),
                    (1.0, 0.7, PoissonRatio),
                    (1.0, nan, PoissonRatio),
                ] {
                    assert_eq!(Lame::from_young_poisson(e, nu), Err(error), "E {e}, nu {nu}");
                    assert_eq!(StVK::from_young_poisson(e, nu), Err(error));
                    assert_eq!(NeoHookean::from_young_poisson(e, nu), Err(error));
                    assert_eq!(StableNeoHookean::from_young_poisson(e, nu), Err(error));
                }
            }

            #[test]
            fn errors_display_and_are_the_same_type_in_both_precisions() {
                use MaterialError::*;
                let all = [Lambda, Mu, BulkModulus, YoungModulus, PoissonRatio];
                for (i, a) in all.iter().enumerate() {
                    let error: &dyn core::error::Error = a;
                    assert!(!error.to_string().is_empty());
                    for b in &all[i + 1..] {
                        assert_ne!(a.to_string(), b.to_string());
                    }
                }
                let _: softfem::MaterialError = softfem::f64::MaterialError::Mu;
            }

            // ---- Identities (`docs/math.md` section 5) -----------------------------------------------

            /// The energy at small strain against linear elasticity's
            /// `W = mu |eps|^2 + lambda/2 (tr eps)^2`, `eps = sym(H)` for `F = I + H`. The
            /// model error is of order `|H|` relative; a rounding error of order `eps mu` (from
            /// forming `I_C - 3` or `J - 1` by subtraction) would be `eps / |H|^2` relative:
            /// 12 in f32 at `|H| = 1e-4`.
            fn small_strain_energy_is_accurate<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng(0x2545_f491_4f6c_dd1d);
                for size in [1e-3, 1e-4] {
                    for _ in 0..50 {
                        let mut entry = || uniform(&mut rng, -size, size);
                        let h = Mat3::from_cols_array(&core::array::from_fn(|_| entry()));
                        let strain = (h + h.transpose()) * 0.5;
                        let trace = strain.x_axis.x + strain.y_axis.y + strain.z_axis.z;
                        let linear = lame.mu() * norm(strain).powi(2)
                            + 0.5 * lame.lambda() * trace * trace;
                        let energy = model.energy_density(Mat3::IDENTITY + h);
                        let tolerance = 20.0 * size + 100.0 * EPS / size;
                        assert!(
                            (energy - linear).abs() <= tolerance * linear,
                            "{}: |H| ~ {size}: W = {energy}, linear {linear}",
                            name::<M>()
                        );
                    }
                }
            }

            #[test]
            fn small_strain_energy_has_no_cancellation_error() {
                // The isochoric neo-Hookean is left out: its isochoric term `J^(-2/3) I_C - 3`
                // cancels terms of order one, so its energy carries an error of order `eps mu`
                // (documented on the type).
                for lame in parameter_sets() {
                    small_strain_energy_is_accurate(lame, StVK::new(lame));
                    small_strain_energy_is_accurate(lame, StableNeoHookean::new(lame));
                }
            }

            fn fused_energy_and_stress_match<M: Material>(_lame: Lame, model: M) {
                // The fused call must give the separate calls' values bit for bit, at rest, on
                // random and inverted deformations, on flat ones and on a singular one.
                let flat = [diag(1.0, 1.0, 0.0), diag(1.2, 0.0, 0.0), Mat3::ZERO];
                for f in deformations(200).chain(flat).chain([Mat3::IDENTITY]) {
                    let (energy, stress) = model.energy_and_first_piola(f);
                    let (expected_energy, expected_stress) =
                        (model.energy_density(f), model.first_piola(f));
                    assert_eq!(
                        energy.to_bits(),
                        expected_energy.to_bits(),
                        "{}: F = {f}",
                        name::<M>()
                    );
                    let bits = |m: Mat3| m.to_cols_array().map(Real::to_bits);
                    assert_eq!(bits(stress), bits(expected_stress), "{}: F = {f}", name::<M>());
                }
            }

            #[test]
            fn fused_energy_and_stress_equal_the_separate_calls() {
                for_each_model!(fused_energy_and_stress_match);
            }

            fn zero_at_rest<M: Material>(lame: Lame, model: M) {
                // StVK's Green strain is exactly zero at F = I, and the neo-Hookean forms are
                // grouped so that their two stress terms cancel exactly (see their sources).
                assert_eq!(model.energy_density(Mat3::IDENTITY), 0.0, "{}", name::<M>());
                assert_eq!(model.first_piola(Mat3::IDENTITY), Mat3::ZERO, "{}", name::<M>());
                assert_eq!(model.principal_energy(Vec3::ONE), 0.0, "{}", name::<M>());
                assert_eq!(model.principal_stress(Vec3::ONE), Vec3::ZERO, "{}", name::<M>());
                // The SVD of I may carry rounding of a few eps into the stretches.
                let p = model.first_piola_principal(Mat3::IDENTITY);
                assert!(norm(p) <= 16.0 * EPS * modulus(lame), "{}: {p}", name::<M>());
            }

            #[test]
            fn rest_state_has_zero_energy_and_stress() {
                for_each_model!(zero_at_rest);
            }

            fn rigid_motion_is_free<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng(7);
                for _ in 0..50 {
                    let r = random_rotation(&mut rng);
                    // A rotation from from_axis_angle is orthonormal to a few eps, so its strain
                    // is a few eps: |P| = O(eps modulus), and W = O(eps modulus) (the
                    // neo-Hookean energies are differences of O(modulus) terms).
                    let tol = 64.0 * EPS * modulus(lame);
                    assert!(model.energy_density(r).abs() <= tol, "{}", name::<M>());
                    assert!(norm(model.first_piola(r)) <= tol, "{}", name::<M>());
                    assert!(norm(model.first_piola_principal(r)) <= tol, "{}", name::<M>());
                }
            }

            #[test]
            fn rigid_rotations_have_zero_energy_and_stress() {
                for_each_model!(rigid_motion_is_free);
            }

            /// Central differences with step `h = EPS^(1/3)` on quantities of order one have
            /// truncation error `h^2 |W'''| / 6` and rounding error `EPS |W| / h`, both of order
            /// `EPS^(2/3)` times the size of the terms `W` is made of (which the `modulus`-
            /// relative comparison absorbs). 100 covers the third derivatives of the models at
            /// stretches in `[0.6, 1.6]` and the cancellation between terms of order `lambda`.
            fn finite_difference_tolerance() -> Real {
                100.0 * EPS.powf(2.0 / 3.0)
            }

            fn stress_is_energy_gradient<M: Material>(lame: Lame, model: M) {
                let h = EPS.cbrt();
                for f in deformations(20) {
                    let p = model.first_piola(f);
                    let mut fd = [[0.0; 3]; 3];
                    for (col, fd_col) in fd.iter_mut().enumerate() {
                        for (row, entry) in fd_col.iter_mut().enumerate() {
                            let (mut plus, mut minus) = (f, f);
                            plus.col_mut(col)[row] += h;
                            minus.col_mut(col)[row] -= h;
                            *entry = (model.energy_density(plus) - model.energy_density(minus))
                                / (2.0 * h);
                        }
                    }
                    let error = norm(Mat3::from_cols_array_2d(&fd) - p);
                    assert!(
                        error <= finite_difference_tolerance() * modulus(lame),
                        "{}: |P - fd| = {error:e}, |P| = {:e}, F = {f}",
                        name::<M>(),
                        norm(p)
                    );
                }
            }

            #[test]
            fn first_piola_is_the_gradient_of_the_energy() {
                for_each_model!(stress_is_energy_gradient);
            }

            fn principal_stress_is_principal_energy_gradient<M: Material>(lame: Lame, model: M) {
                let h = EPS.cbrt();
                for f in deformations(20) {
                    let s = svd3(f).sigma;
                    let ds = model.principal_stress(s);
                    let mut fd = Vec3::ZERO;
                    for axis in 0..3 {
                        let mut step = Vec3::ZERO;
                        step[axis] = h;
                        fd[axis] = (model.principal_energy(s + step)
                            - model.principal_energy(s - step))
                            / (2.0 * h);
                    }
                    let error = (fd - ds).length();
                    assert!(
                        error <= finite_difference_tolerance() * modulus(lame),
                        "{}: |dW/ds - fd| = {error:e}, s = {s}",
                        name::<M>()
                    );
                }
            }

            #[test]
            fn principal_stress_is_the_gradient_of_the_principal_energy() {
                for_each_model!(principal_stress_is_principal_energy_gradient);
            }

            fn principal_energy_agrees<M: Material>(lame: Lame, model: M) {
                for f in deformations(40) {
                    let w = model.energy_density(f);
                    let w_principal = model.principal_energy(svd3(f).sigma);
                    // Both evaluate terms of order modulus at strains of order one; the SVD's
                    // stretches carry a few eps of error, amplified by the cancellation between
                    // the terms (at most lambda/mu ~ 10 for the rubber set).
                    let tol = 256.0 * EPS * modulus(lame);
                    assert!(
                        (w - w_principal).abs() <= tol,
                        "{}: W = {w:e}, W(s) = {w_principal:e}",
                        name::<M>()
                    );
                }
            }

            #[test]
            fn principal_energy_of_the_singular_values_is_the_energy_density() {
                for_each_model!(principal_energy_agrees);
            }

            fn principal_path_agrees<M: Material>(lame: Lame, model: M) {
                for f in deformations(40) {
                    let p = model.first_piola(f);
                    let svd = svd3(f);
                    let p_principal = model.first_piola_principal(f);
                    // The SVD reconstructs F to a few eps, and both paths then evaluate
                    // O(modulus) terms whose rounding the models amplify by up to lambda/mu
                    // (observed: up to ~70 eps of the modulus, in both precisions).
                    let tol = 256.0 * EPS * modulus(lame);
                    assert!(
                        norm(p - p_principal) <= tol,
                        "{}: |P - P_principal| = {:e}, |P| = {:e}",
                        name::<M>(),
                        norm(p - p_principal),
                        norm(p)
                    );
                    assert_eq!(model.first_piola_from_svd(&svd), p_principal);
                    // Clamping below every stretch changes nothing.
                    let below = svd.sigma.min_element() - 0.1;
                    assert_eq!(model.first_piola_principal_clamped(f, below), p_principal);
                    assert_eq!(model.first_piola_clamped_from_svd(&svd, below), p_principal);
                }
            }

            #[test]
            fn principal_path_matches_the_direct_path() {
                for_each_model!(principal_path_agrees);
            }

            fn rotation_invariant<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng(11);
                for f in deformations(20) {
                    let (r, q) = (random_rotation(&mut rng), random_rotation(&mut rng));
                    let p = model.first_piola(f);
                    // Rotating by r, q (orthonormal to a few eps) perturbs F by a few eps, which
                    // the models amplify as in principal_path_agrees (observed: up to ~60 eps).
                    let tol = 256.0 * EPS * modulus(lame);
                    // Frame indifference: P(R F) = R P(F), W(R F) = W(F).
                    assert!(norm(model.first_piola(r * f) - r * p) <= tol, "{}", name::<M>());
                    let w = model.energy_density(f);
                    assert!((model.energy_density(r * f) - w).abs() <= tol, "{}", name::<M>());
                    // Isotropy: P(F Q) = P(F) Q.
                    assert!(norm(model.first_piola(f * q) - p * q) <= tol, "{}", name::<M>());
                }
            }

            #[test]
            fn stress_rotates_with_the_deformation() {
                for_each_model!(rotation_invariant);
            }

            /// `|P(I + e H) - (lambda tr(eps) I + 2 mu eps)|` with `eps = e (H + H^T) / 2`.
            fn linearisation_error<M: Material>(lame: Lame, model: M, e: Real, h: Mat3) -> Real {
                let eps = (h + h.transpose()) * (0.5 * e);
                let trace = eps.diagonal().element_sum();
                let linear = Mat3::from_diagonal(Vec3::splat(lame.lambda() * trace))
                    + eps * (2.0 * lame.mu());
                norm(model.first_piola(Mat3::IDENTITY + h * e) - linear)
            }

            fn linearises_to_lame<M: Material>(lame: Lame, model: M) {
                let mut rng = Rng(13);
                // e = EPS^(1/4): the O(e^2) = O(sqrt(EPS)) nonlinear remainder is far above
                // the O(EPS / e) rounding of P relative to its O(e) size.
                let e = EPS.sqrt().sqrt();
                for _ in 0..20 {
                    let h = Mat3::from_cols_array(&core::array::from_fn(|_| {
                        uniform(&mut rng, -1.0, 1.0)
                    }));
                    let scale = modulus(lame) * norm(h) * norm(h);
                    let error = linearisation_error(lame, model, e, h);
                    // The remainder is (1/2) d^2P[eH, eH]; its constant for these models at
                    // F = I is a few moduli (StVK: <= 3 (lambda + 2 mu) |H|^2, the
                    // neo-Hookean ones a few times that from J^(-5/3) and 1/(I_C + 1)).
                    assert!(error <= 10.0 * e * e * scale, "{}: {error:e}", name::<M>());
                    // Second order: halving e quarters the remainder.
                    let ratio = error / linearisation_error(lame, model, 0.5 * e, h);
                    assert!((3.0..5.0).contains(&ratio), "{}: ratio {ratio}", name::<M>());
                }
            }

            #[test]
            fn small_strain_limit_is_linear_elasticity() {
                for_each_model!(linearises_to_lame);
            }

            // ---- Closed forms (`docs/math.md` section 5, homogeneous deformations) --------------------

            /// Absolute tolerance (Pa) for a closed form evaluated in the same precision: the
            /// models and the formulas round differently, by a few eps of the moduli.
            fn closed_form_tolerance(lame: Lame) -> Real {
                64.0 * EPS * modulus(lame)
            }

            #[test]
            fn stvk_uniaxial_strain() {
                // F = diag(s, 1, 1): G = diag(g, 0, 0) with g = (s^2 - 1)/2, tr G = g,
                // S = 2 mu G + lambda g I = diag((lambda + 2 mu) g, lambda g, lambda g),
                // P = F S = diag(s (lambda + 2 mu)(s^2 - 1)/2, lambda g, lambda g),
                // W = lambda/2 g^2 + mu g^2.
                for lame in parameter_sets() {
                    let model = StVK::new(lame);
                    let (lambda, mu) = (lame.lambda(), lame.mu());
                    for s in [0.3, 0.8, 1.0, 1.1, 2.0] {
                        let g = (s * s - 1.0) / 2.0;
                        let f = diag(s, 1.0, 1.0);
                        let p = diag(s * (lambda + 2.0 * mu) * g, lambda * g, lambda * g);
                        let tol = closed_form_tolerance(lame);
                        assert!(norm(model.first_piola(f) - p) <= tol, "s = {s}");
                        let w = (0.5 * lambda + mu) * g * g;
                        assert!((model.energy_density(f) - w).abs() <= tol, "s = {s}");
                    }
                }
            }

            #[test]
            fn stvk_uniaxial_stress() {
                // F = diag(s, t, t) with free lateral faces, P_yy = P_zz = 0: with g = (s^2-1)/2
                // and g_t = (t^2-1)/2, P_yy = t (lambda (g + 2 g_t) + 2 mu g_t) = 0 gives
                // g_t = -lambda g / (2 (lambda + mu)). Then
                // P_xx = s (lambda (g + 2 g_t) + 2 mu g) = s g mu (3 lambda + 2 mu)/(lambda + mu)
                //      = E s (s^2 - 1) / 2 with Young's modulus E: the same shape as uniaxial
                // strain, so its compressive peak is at s = 1/sqrt(3) as well.
                let (e, nu) = (1.0e5, 0.3);
                let model = StVK::from_young_poisson(e, nu).unwrap();
                let (lambda, mu) = (model.lambda(), model.mu());
                for s in [0.5, 0.9, 1.2, 1.5] {
                    let g = (s * s - 1.0) / 2.0;
                    let t = (1.0 - lambda * g / (lambda + mu)).sqrt();
                    let p = model.first_piola(diag(s, t, t));
                    let tol = closed_form_tolerance(model.lame());
                    assert!(p.y_axis.y.abs() <= tol && p.z_axis.z.abs() <= tol, "s = {s}");
                    assert!((p.x_axis.x - e * s * g).abs() <= tol, "s = {s}");
                }
            }

            #[test]
            fn volumetric_deformation() {
                // F = a I: I_C = 3 a^2, J = a^3, cof(F) = a^2 I.
                for lame in parameter_sets() {
                    let (lambda, mu) = (lame.lambda(), lame.mu());
                    let tol = closed_form_tolerance(lame);
                    for a in [0.5, 0.8, 1.0, 1.25, 2.0] {
                        let f = Mat3::from_diagonal(Vec3::splat(a));
                        let (ic, j) = (3.0 * a * a, a * a * a);
                        let check = |label: &str, w: Real, p: Real, model_w: Real, model_p: Mat3| {
                            let scale = 1.0 + a.powi(5); // stresses grow like a^5 at large a
                            assert!((model_w - w).abs() <= tol * scale, "{label}, a = {a}");
                            let p = Mat3::from_diagonal(Vec3::splat(p));
                            assert!(norm(model_p - p) <= tol * scale, "{label}, a = {a}");
                        };
                        // StVK: G = g I with g = (a^2 - 1)/2, W = 9 lambda/2 g^2 + 3 mu g^2,
                        // P = a (3 lambda + 2 mu) g I.
                        let g = (a * a - 1.0) / 2.0;
                        let stvk = StVK::new(lame);
                        check(
                            "StVK",
                            (4.5 * lambda + 3.0 * mu) * g * g,
                            a * (3.0 * lambda + 2.0 * mu) * g,
                            stvk.energy_density(f),
                            stvk.first_piola(f),
                        );
                        // Seed neo-Hookean: J^(-2/3) I_C = 3, so the shear term vanishes:
                        // W = K/2 (a^3 - 1)^2; P = mu a^-2 a - (mu/3) a^-5 (3 a^2) a^2
                        // + K (a^3 - 1) a^2 = K a^2 (a^3 - 1).
                        let k = lambda + 2.0 * mu / 3.0;
                        let nh = NeoHookean::new(lame);
                        check(
                            "NeoHookean",
                            0.5 * k * (j - 1.0) * (j - 1.0),
                            k * a * a * (j - 1.0),
                            nh.energy_density(f),
                            nh.first_piola(f),
                        );
                        // Stable neo-Hookean in the constants of Smith, de Goes and Kim (independent of the
                        // implementation's rearranged form):
                        // W = m/2 (I_C - 3) + l/2 (J - alpha)^2 - m/2 ln(I_C + 1) - W(I),
                        // P = [m (1 - 1/(I_C + 1)) a + l (J - alpha) a^2] I.
                        let m = 4.0 * mu / 3.0;
                        let l = lambda + 5.0 * mu / 6.0;
                        let alpha = 1.0 + 3.0 * m / (4.0 * l);
                        let w_rest = l / 2.0 * (1.0 - alpha).powi(2) - m / 2.0 * (4.0 as Real).ln();
                        let snh = StableNeoHookean::new(lame);
                        check(
                            "StableNeoHookean",
                            m / 2.0 * (ic - 3.0) + l / 2.0 * (j - alpha).powi(2)
                                - m / 2.0 * (ic + 1.0).ln()
                                - w_rest,
                            m * (1.0 - 1.0 / (ic + 1.0)) * a + l * (j - alpha) * a * a,
                            snh.energy_density(f),
                            snh.first_piola(f),
                        );
                    }
                }
            }

            // ---- Failure modes (`docs/math.md` section 2) -------------------------------------------

            #[test]
            fn stvk_reflections_are_stress_free() {
                let mut rng = Rng(17);
                for lame in parameter_sets() {
                    let model = StVK::new(lame);
                    // Exactly: G = (F^T F - I)/2 = 0 for F = diag(-1, 1, 1).
                    let mirror = diag(-1.0, 1.0, 1.0);
                    assert_eq!(model.energy_density(mirror), 0.0);
                    assert_eq!(model.first_piola(mirror), Mat3::ZERO);
                    for _ in 0..20 {
                        // Any improper orthogonal matrix: an inverted element at equilibrium.
                        let f = random_rotation(&mut rng) * mirror * random_rotation(&mut rng);
                        assert!(svd3(f).sigma.z < 0.0);
                        let tol = 64.0 * EPS * modulus(lame);
                        assert!(norm(model.first_piola(f)) <= tol);
                        assert!(norm(model.first_piola_principal(f)) <= tol);
                    }
                }
            }

            #[test]
            fn stvk_compressive_stress_peaks_at_one_over_sqrt_3() {
                // P_xx(s) = (lambda + 2 mu) s (s^2 - 1)/2 for F = diag(s, 1, 1) (see
                // stvk_uniaxial_strain); dP_xx/ds = (lambda + 2 mu)(3 s^2 - 1)/2 = 0 at
                // s = 1/sqrt(3), where |P_xx| = (lambda + 2 mu)/(3 sqrt(3)). Below it the
                // resistance collapses, to zero at s = 0.
                let model = StVK::new(parameter_sets()[0]);
                let p_xx = |s: Real| model.first_piola(diag(s, 1.0, 1.0)).x_axis.x;
                let step = 1.0e-3;
                let (s_peak, p_peak) = (1..1000)
                    .map(|i| i as Real * step)
                    .map(|s| (s, p_xx(s)))
                    .fold((1.0, 0.0), |best, (s, p)| if p < best.1 { (s, p) } else { best });
                let expected = 1.0 / (3.0 as Real).sqrt();
                assert!((s_peak - expected).abs() <= step, "peak at {s_peak}");
                let magnitude = modulus(model.lame()) / (3.0 * (3.0 as Real).sqrt());
                assert!((p_peak.abs() - magnitude).abs() <= 1e-3 * magnitude);
                assert_eq!(p_xx(0.0), 0.0);
                // Past s = 0 the stress pushes further into inversion (P_xx > 0: the force
                // -P_xx on the stretch points to s = -1, the mirrored equilibrium).
                for s in [-0.2, -0.5, -0.9] {
                    assert!(p_xx(s) > 0.0, "s = {s}");
                }
            }

            #[test]
            fn neo_hookean_has_a_barrier_at_zero_volume() {
                let lame = parameter_sets()[0];
                let model = NeoHookean::new(lame);
                let mu = lame.mu();
                let flat = |t: Real| diag(1.0, 1.0, t);
                // F = diag(1, 1, t): W = mu/2 (t^(-2/3) (2 + t^2) - 3) + K/2 (t - 1)^2
                // >= mu (t^(-2/3) - 3/2), so W -> inf as t -> 0+.
                let mut previous = (0.0, 0.0);
                for k in 1..=6 {
                    let t = (10.0 as Real).powi(-k);
                    let w = model.energy_density(flat(t));
                    let p_zz = model.first_piola(flat(t)).z_axis.z;
                    assert!(w >= mu * (t.powf(-2.0 / 3.0) - 1.5), "t = {t}");
                    // The energy and the restoring stress (P_zz < 0: the force -P_zz on the
                    // z-stretch pushes it back up) both grow without bound.
                    assert!(w > previous.0 && p_zz < previous.1, "t = {t}");
                    previous = (w, p_zz);
                }
                assert!(previous.0 > 50.0 * mu);
                // J = 0 itself: infinite energy and a non-finite stress, no panic.
                assert_eq!(model.energy_density(flat(0.0)), Real::INFINITY);
                assert!(!model.first_piola(flat(0.0)).is_finite());
                assert!(!model.first_piola_principal(flat(0.0)).is_finite());
                // Just past J = 0 the barrier holds the element inverted: P_zz > 0 pushes t
                // further negative, so an element pushed through cannot come back.
                for t in [-1.0e-3, -1.0e-2, -0.1] {
                    let w = model.energy_density(flat(t));
                    assert!(w.is_finite() && w > model.energy_density(flat(-t)));
                    assert!(model.first_piola(flat(t)).z_axis.z > 0.0, "t = {t}");
                }
            }

            #[test]
            fn stable_neo_hookean_is_smooth_through_inversion() {
                for lame in parameter_sets() {
                    let model = StableNeoHookean::new(lame);
                    let tol = closed_form_tolerance(lame);
                    let steps = 1000;
                    let dt = 1.0 / steps as Real;
                    let at = |i: i32| {
                        let t = 0.5 - i as Real * dt;
                        let f = diag(1.0, 1.0, t);
                        (t, model.energy_density(f), model.first_piola(f))
                    };
                    for i in 0..steps {
                        let ((t, w0, p0), (_, w1, p1)) = (at(i), at(i + 1));
                        assert!(w0.is_finite() && p0.is_finite(), "t = {t}");
                        // With P = A F + B cof(F), A = m I_C/(I_C + 1), B = l (t - 1) - mu,
                        // I_C = 2 + t^2 and cof(F) = diag(t, t, 1): P_zz = A t + B = dW/dt and
                        // P_xx = P_yy = A + B t. The trapezoid rule relates consecutive energies
                        // to the stresses with error dt^3 |W'''| / 12, where |W'''| =
                        // |2 A' + A'' t| <= m / 2. And |dP_zz/dt| <= A + |A'| + l,
                        // |dP_xx/dt| = |A' + l (2t - 1) - mu| <= |A'| + 2 l + mu for |t| <= 1/2,
                        // so |dP/dt| <= 4 (lambda + 2 mu) with l = lambda + 5 mu / 6, m = 4 mu / 3:
                        // energy and stress are continuous, with no jump at t = 0.
                        let trapezoid = -dt * 0.5 * (p0.z_axis.z + p1.z_axis.z);
                        let error = (w1 - w0 - trapezoid).abs();
                        assert!(error <= modulus(lame) * dt * dt * dt + tol, "t = {t}");
                        assert!(norm(p1 - p0) <= 4.0 * modulus(lame) * dt + tol, "t = {t}");
                        if t <= 0.0 {
                            // Restoring: the force -P_zz on the z-stretch pushes it back up.
                            assert!(p0.z_axis.z < 0.0, "t = {t}");
                        }
                    }
                }
            }

            #[test]
            fn clamped_principal_path_restores_inverted_elements() {
                // F = diag(1, 1, -0.3): the SVD gives s = (1, 1, -0.3) with the third columns
                // of U and V equal to +-e_z and U_zz V_zz = +1 (since U_zz s_z V_zz = F_zz), so
                // P_zz = dW/ds_z at the clamped stretches. The force conjugate to the z-stretch
                // is -P_zz (a tet with Dm = I gets f3 = -V P e_z), so restoring <=> P_zz < 0.
                // Clamped to s' = (1, 1, threshold), every model is in uninverted compression
                // along z, where dW/ds_z < 0.
                let inverted = diag(1.0, 1.0, -0.3);
                let mut rng = Rng(19);
                for lame in parameter_sets() {
                    let stvk = StVK::new(lame);
                    // Without clamping StVK pushes the element towards the mirror image.
                    assert!(stvk.first_piola_principal(inverted).z_axis.z > 0.0);
                    let tol = 64.0 * EPS * modulus(lame);
                    for threshold in [0.2, 0.5] {
                        let nh = NeoHookean::new(lame);
                        let snh = StableNeoHookean::new(lame);
                        let clamped = [
                            stvk.first_piola_principal_clamped(inverted, threshold),
                            nh.first_piola_principal_clamped(inverted, threshold),
                            snh.first_piola_principal_clamped(inverted, threshold),
                        ];
                        for p in clamped {
                            assert!(p.is_finite() && p.z_axis.z < 0.0, "threshold {threshold}");
                        }
                        // The clamped stress of a rotated element is the rotated stress.
                        let (r, q) = (random_rotation(&mut rng), random_rotation(&mut rng));
                        let rotated =
                            stvk.first_piola_principal_clamped(r * inverted * q, threshold);
                        assert!(norm(rotated - r * clamped[0] * q) <= tol);
                    }
                    // The flat isochoric neo-Hookean element: non-finite as a model, finite clamped.
                    let flat = diag(1.0, 1.0, 0.0);
                    let p = NeoHookean::new(lame).first_piola_principal_clamped(flat, 0.2);
                    assert!(p.is_finite() && p.z_axis.z < 0.0);
                    // NaN input is not hidden behind the threshold.
                    let nan = Mat3::from_diagonal(Vec3::new(1.0, 1.0, Real::NAN));
                    assert!(stvk.first_piola_principal_clamped(nan, 0.2).is_nan());
                }
            }
        }
    };
}

material_tests!(single, softfem);
material_tests!(double, softfem::f64);

//! The relaxation (implicit Euler as minimisation, and its quasi-static mode) on a cantilever:
//! a 0.4 m bar pinned at one end sags under gravity. The quasi-static solve reaches the
//! equilibrium where elastic forces balance gravity at every free vertex; implicit Euler steps
//! settle to the same shape; bad settings are refused before anything is touched.

macro_rules! relax_tests {
    ($precision:ident, $($api:ident)::+, $tolerance:expr) => {
        mod $precision {
            use softfem::StepError;
            use $($api)::+::element::TetRest;
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::StableNeoHookean;
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::{
                RelaxOptions, RelaxScratch, RelaxSettings, Scene, TetElastic,
                gradient_descent_quasi_static, gradient_descent_step, relax_quasi_static,
                scratch_len, relax_step,
            };
            use $($api)::+::types::{Real, Vec3};

            /// Relative residual asked of the solver in this precision.
            const TOLERANCE: Real = $tolerance;
            /// Chebyshev's spectral radius estimates for implicit Euler steps of 1/60 s and for
            /// the quasi-static solve (no inertia: worse conditioned, closer to 1).
            const DYNAMIC_RHO: Real = 0.995;
            const QUASI_STATIC_RHO: Real = 0.999;
            const GRAVITY: Vec3 = Vec3::new(0.0, -9.81, 0.0);

            struct Bar {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
                pinned: Vec<bool>,
            }

            fn bar() -> Bar {
                let max = Vec3::new(0.4, 0.1, 0.1);
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, max, (4, 1, 1), BoxSplit::Kuhn6);
                let pinned = rest.iter().map(|p| p.x == 0.0).collect();
                Bar { rest, tets, pinned }
            }

            /// The largest `|f_elastic + m g|` (N) over free vertices.
            fn imbalance(mesh: &TetMesh, material: &StableNeoHookean, x: &[Vec3], masses: &[Real], pinned: &[bool]) -> Real {
                let mut f = vec![Vec3::ZERO; x.len()];
                mesh.add_elastic_forces(material, x, &mut f).unwrap();
                f.iter()
                    .zip(masses)
                    .zip(pinned)
                    .filter(|(_, p)| !**p)
                    .map(|((f, m), _)| (*f + GRAVITY * *m).length())
                    .fold(0.0, Real::max)
            }

            #[test]
            fn a_kept_scratch_reuses_its_preconditioner_until_reset() {
                let bar = bar();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let soft = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.3).unwrap());
                let stiff = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e7, 0.3).unwrap());
                let n = bar.rest.len();
                // A fixed budget (tolerance 0), so that results depend on every iterate.
                let scene = Scene::new(1.0 / 60.0).with_gravity(GRAVITY);
                let settings = RelaxSettings::new().with_tolerance(0.0, 30);
                let bits = |x: &[Vec3]| -> Vec<[u64; 3]> {
                    x.iter().map(|p| p.to_array().map(|c| f64::from(c).to_bits())).collect()
                };
                // Two steps of `body` from rest, each with a fresh scratch.
                let fresh = |body: &TetElastic<StableNeoHookean>| {
                    let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                    for _ in 0..2 {
                        let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
                        let mut scalars = vec![0.0; n];
                        let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                        relax_step(body, &masses, &bar.pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    }
                    bits(&x)
                };
                let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                let mut kept = RelaxScratch::new(&mut vectors, &mut scalars);
                let kept_steps = |body: &TetElastic<StableNeoHookean>, scratch: &mut RelaxScratch<Vec3>| {
                    let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                    for _ in 0..2 {
                        relax_step(body, &masses, &bar.pinned, &scene, &settings, &mut x, &mut v, scratch).unwrap();
                    }
                    bits(&x)
                };
                // Same body: reusing the preconditioner changes nothing.
                assert_eq!(kept_steps(&soft, &mut kept), fresh(&soft));
                // Another material without a reset: the soft body's preconditioner is used, so
                // the iterates (not the problem) differ from a fresh solve ...
                assert_ne!(kept_steps(&stiff, &mut kept), fresh(&stiff));
                // ... and after a reset they are the fresh solve's again.
                kept.reset_preconditioner();
                assert_eq!(kept_steps(&stiff, &mut kept), fresh(&stiff));
            }

            #[test]
            fn quasi_static_and_implicit_euler_reach_the_same_equilibrium() {
                let bar = bar();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let material = StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
                let body = TetElastic::new(mesh, material);
                let n = bar.rest.len();
                let weight = masses.iter().fold(0.0 as Real, |a, &m| a.max(m)) * 9.81;
                let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
                let mut scalars = vec![0.0; n];

                // Quasi-static, from rest.
                let scene = Scene::new(1.0 / 60.0).with_gravity(GRAVITY);
                let settings = RelaxSettings::new()
                    .with_tolerance(TOLERANCE, 50_000)
                    .with_chebyshev(QUASI_STATIC_RHO, 2.0, 0);
                let mut x_static = bar.rest.clone();
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let report = relax_quasi_static(&body, &masses, &bar.pinned, &scene, &settings, &mut x_static, &mut scratch).unwrap();
                let static_imbalance = imbalance(&mesh, &material, &x_static, &masses, &bar.pinned);
                let sag = bar.rest.iter().zip(&x_static).map(|(r, x)| r.y - x.y).fold(0.0, Real::max);
                // Without inertia the preconditioned system's condition number is about 1100
                // here: plain descent (or the momentum 0.9 used before Chebyshev) needed 4650
                // iterations in f64; Chebyshev needs about 850.
                assert!(report.iterations <= 1_500, "{report:?}");
                println!("{}: quasi-static {report:?}; tip sag {sag:.4} m, imbalance {:.1e} of the largest vertex weight",
                    stringify!($precision), static_imbalance / weight);
                assert!(report.converged);
                assert!(sag > 0.005 && sag < 0.1);
                // The residual is the force imbalance at free vertices.
                assert!(static_imbalance < 20.0 * TOLERANCE * weight);

                // Implicit Euler from rest, 1/60 s steps, until it settles.
                // Each step only needs to be accurate relative to the gravity load, not to the
                // end state: 1e-4 in f64 (the f32 floor is the one above).
                let dynamic = settings
                    .with_tolerance(TOLERANCE.max(1e-4), 2_000)
                    .with_chebyshev(DYNAMIC_RHO, 2.0, 0);
                let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                let (mut iterations, mut evaluations, mut unconverged) = (0, 0, 0);
                let steps = 300;
                for _ in 0..steps {
                    let report = relax_step(&body, &masses, &bar.pinned, &scene, &dynamic, &mut x, &mut v, &mut scratch).unwrap();
                    iterations += report.iterations;
                    evaluations += report.energy_evaluations;
                    unconverged += u32::from(!report.converged);
                }
                let difference = x.iter().zip(&x_static).map(|(a, b)| (*a - *b).length()).fold(0.0, Real::max);
                let speed = v.iter().map(|v| v.length()).fold(0.0, Real::max);
                println!(
                    "{}: implicit Euler, {steps} steps: {:.1} iterations/step, {:.2} evaluations/iteration, \
                     {unconverged} unconverged; |x - x_static| {difference:.1e} m, max speed {speed:.1e} m/s",
                    stringify!($precision),
                    iterations as f64 / steps as f64,
                    evaluations as f64 / iterations as f64,
                );
                // Momentum 0.5 with the unit step needed 293 iterations per step (141 in f32) and
                // left 22 of 300 steps unconverged after 2000 iterations; Chebyshev with the
                // step 2 needs about 30 and converges (f32 stalls once or twice on rounding).
                assert!(unconverged <= 3);
                assert!(iterations <= 50 * steps);
                assert!(difference < 0.02 * sag);
                assert!(speed < 1e-2);
                for (i, pinned) in bar.pinned.iter().enumerate() {
                    if *pinned {
                        assert_eq!(x[i], bar.rest[i]);
                        assert_eq!(v[i], Vec3::ZERO);
                    }
                }
            }

            #[test]
            fn gradient_descent_reaches_the_relaxations_equilibrium_on_the_same_loop() {
                // P = c I instead of the per-vertex bound, otherwise the relaxation's loop: the
                // same equilibrium (both checked against the force kernel), in more iterations
                // wherever the bounds differ between vertices (here the clamped end's and the
                // free tip's vertices have fewer elements).
                let bar = bar();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let material = StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
                let body = TetElastic::new(mesh, material);
                let n = bar.rest.len();
                let weight = masses.iter().fold(0.0 as Real, |a, &m| a.max(m)) * 9.81;
                let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                let scene = Scene::new(1.0 / 60.0).with_gravity(GRAVITY);
                let settings = RelaxSettings::new()
                    .with_tolerance(TOLERANCE, 50_000)
                    .with_chebyshev(QUASI_STATIC_RHO, 2.0, 0);
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let mut relaxed = bar.rest.clone();
                let relax = relax_quasi_static(&body, &masses, &bar.pinned, &scene, &settings, &mut relaxed, &mut scratch).unwrap();
                let mut descended = bar.rest.clone();
                let descent = gradient_descent_quasi_static(&body, &masses, &bar.pinned, &scene, &settings, &mut descended, &mut scratch).unwrap();
                println!("{}: relaxation {relax:?}\ngradient descent {descent:?}", stringify!($precision));
                assert!(relax.converged && descent.converged, "{descent:?}");
                assert!(imbalance(&mesh, &material, &descended, &masses, &bar.pinned) < 20.0 * TOLERANCE * weight);
                let sag = bar.rest.iter().zip(&relaxed).map(|(r, x)| r.y - x.y).fold(0.0, Real::max);
                let difference = relaxed.iter().zip(&descended).map(|(a, b)| (*a - *b).length()).fold(0.0, Real::max);
                // Both stop within the tolerance of the load; in f32 that is its floor, 3e-3.
                assert!(difference < 0.02 * sag, "{difference:e} m against a sag of {sag} m");
                for (i, pinned) in bar.pinned.iter().enumerate() {
                    assert!(!pinned || descended[i] == bar.rest[i]);
                }

                // One implicit Euler step from rest: the same step as the relaxation's.
                let dynamic = settings.with_tolerance(TOLERANCE.max(1e-4), 5_000).with_chebyshev(DYNAMIC_RHO, 2.0, 0);
                let (mut x_relax, mut v_relax) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                let (mut x_descent, mut v_descent) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                let relax = relax_step(&body, &masses, &bar.pinned, &scene, &dynamic, &mut x_relax, &mut v_relax, &mut scratch).unwrap();
                let descent = gradient_descent_step(&body, &masses, &bar.pinned, &scene, &dynamic, &mut x_descent, &mut v_descent, &mut scratch).unwrap();
                println!("{}: one step, relaxation {} and gradient descent {} iterations", stringify!($precision), relax.iterations, descent.iterations);
                assert!(relax.converged && descent.converged, "{descent:?}");
                let moved = bar.rest.iter().zip(&x_relax).map(|(r, x)| (*r - *x).length()).fold(0.0, Real::max);
                let difference = x_relax.iter().zip(&x_descent).map(|(a, b)| (*a - *b).length()).fold(0.0, Real::max);
                assert!(difference < 0.05 * moved, "{difference:e} m against a step of {moved} m");
            }

            #[test]
            fn chebyshev_reaches_the_unaccelerated_answer_in_a_fraction_of_the_iterations() {
                if core::mem::size_of::<Real>() == 4 {
                    // f32 stalls on this first step well above 1e-2 of the load, accelerated or
                    // not (the line search runs out of resolution in Phi): nothing to compare.
                    return;
                }
                let bar = bar();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = bar.rest.len();
                let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
                let mut scalars = vec![0.0; n];
                // The first 1/60 s step of the pinned bar released from rest: the bar starts to
                // sag, a bending (slow) mode. Plain preconditioned descent needs 7951 iterations
                // to 1e-5 of the load, Chebyshev 332.
                let scene = Scene::new(1.0 / 60.0).with_gravity(GRAVITY);
                let solve = |settings: RelaxSettings, vectors: &mut [Vec3], scalars: &mut [Real]| {
                    let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                    let mut scratch = RelaxScratch::new(vectors, scalars);
                    let report = relax_step(&body, &masses, &bar.pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    (report, x)
                };
                // Plain descent with the first trial step 1 (no Chebyshev), set explicitly since
                // `RelaxSettings::new` accelerates by default.
                let base = RelaxSettings::new().with_chebyshev(0.0, 1.0, 0);
                let tolerance = TOLERANCE.max(1e-5);
                let budget = 400;
                let (plain, _) = solve(base.with_tolerance(tolerance, budget), &mut vectors, &mut scalars);
                let (reference, x_reference) = solve(base.with_tolerance(tolerance, 100_000), &mut vectors, &mut scalars);
                let accelerated_settings = base.with_tolerance(tolerance, budget).with_chebyshev(DYNAMIC_RHO, 2.0, 0);
                let (accelerated, x) = solve(accelerated_settings, &mut vectors, &mut scalars);
                println!("plain {plain:?}\nreference {reference:?}\nChebyshev {accelerated:?}");
                assert!(!plain.converged, "the unaccelerated solve needs more than {budget} iterations");
                assert!(reference.converged);
                assert!(accelerated.converged && accelerated.iterations <= budget);
                // Both stop on the force residual; Phi is strictly convex near rest (Hessian
                // >= M/h^2), so |x - x*| <= |grad Phi| h^2 / m_min: a residual of tolerance
                // times the load bounds the distance by tolerance * |g| h^2 * sqrt(n) - about
                // 1e-7 m against a 2.6e-3 m drop in this step.
                let drop = bar.rest.iter().zip(&x_reference).map(|(a, b)| (*a - *b).length()).fold(0.0, Real::max);
                let difference = x.iter().zip(&x_reference).map(|(a, b)| (*a - *b).length()).fold(0.0, Real::max);
                println!("drop {drop:.2e} m, difference {difference:.2e} m");
                assert!(drop > 1e-4);
                assert!(difference < 10.0 * tolerance * 9.81 / 3600.0 * (n as Real).sqrt(), "{difference}");
            }

            #[test]
            fn free_fall_is_solved_by_the_initial_guess() {
                let bar = bar();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = bar.rest.len();
                let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
                let mut scalars = vec![0.0; n];
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let h: Real = 1.0 / 60.0;
                let scene = Scene::new(h).with_gravity(GRAVITY);
                let settings = RelaxSettings::new();
                let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::new(1.0, 2.0, 0.0); n]);
                let report = relax_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                // The exact minimiser is the rigid translation x_n + h v_n + h^2 g, which is the
                // initial guess: no descent iteration is needed.
                assert!(report.converged && report.iterations == 0, "{report:?}");
                // Nothing touches or holds the bar: y + h^2 g is y moved rigidly, lower in Phi
                // by construction, and y is not evaluated.
                assert_eq!(report.energy_evaluations, 1, "{report:?}");
                let expected = Vec3::new(1.0, 2.0, 0.0) + GRAVITY * h;
                assert!(v.iter().all(|v| (*v - expected).length() < 1e-3 * expected.length()));
            }

            /// A deformed, spinning bar in free fall starts from y + h^2 g without evaluating y
            /// (the rigid translation wins by `h^2 |g|^2 sum m / 2`), and that is the start the
            /// evaluated comparison of both guesses picks: with a collider far from the bar
            /// (which rules out the shortcut and touches nothing) every step has the same bits,
            /// for one more evaluation per step.
            #[test]
            fn a_free_body_skips_the_losing_guess_with_the_same_bits() {
                use $($api)::+::step::Collider;
                let bar = bar();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.3).unwrap());
                let n = bar.rest.len();
                // Stretched 20 % along x, sheared, spinning about z and moving up.
                let start: Vec<Vec3> = bar
                    .rest
                    .iter()
                    .map(|p| Vec3::new(1.2 * p.x + 0.1 * p.y, p.y, p.z + 0.05 * p.x))
                    .collect();
                let spin: Vec<Vec3> = start
                    .iter()
                    .map(|p| Vec3::new(-3.0 * p.y, 3.0 * p.x + 1.0, 0.0))
                    .collect();
                let far = [Collider::sphere(Vec3::new(0.0, 100.0, 0.0), 1.0)];
                let bits = |x: &[Vec3]| -> Vec<[u64; 3]> {
                    x.iter().map(|p| p.to_array().map(|c| f64::from(c).to_bits())).collect()
                };
                for (h, budget) in [(1.0 / 60.0, 30), (1.0 / 240.0, 5), (1e-3, 100)] {
                    let scene = Scene::new(h).with_gravity(GRAVITY);
                    let settings = RelaxSettings::new().with_tolerance(1e-4, budget);
                    let run = |scene: &Scene<Vec3>| {
                        let (mut x, mut v) = (start.clone(), spin.clone());
                        let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                        let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                        let mut evaluations = Vec::new();
                        for _ in 0..5 {
                            let report = relax_step(&body, &masses, &[], scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                            evaluations.push(report.energy_evaluations);
                        }
                        (bits(&x), bits(&v), evaluations)
                    };
                    let (x, v, evaluations) = run(&scene);
                    let (x_far, v_far, evaluations_far) = run(&scene.with_colliders(&far));
                    assert!(x == x_far && v == v_far, "h = {h}");
                    let fewer: Vec<u32> = evaluations_far.iter().map(|e| e - 1).collect();
                    assert_eq!(evaluations, fewer, "h = {h}");
                }
            }

            /// Pinned vertices are never projected onto the ground, even when they sit inside it:
            /// the bar is clamped at its left end 0.05 m below a ground whose plane cuts through
            /// it, and the solve must keep the clamp exactly where it is and still converge (when
            /// every trial point moved the clamp, Armijo rejected them all and nothing converged).
            #[test]
            fn pinned_vertices_inside_the_ground_stay_put() {
                use $($api)::+::step::HalfSpace;
                let bar = bar();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = bar.rest.len();
                // Ground y = 0.05 with normal +y: the bar (y in [0, 0.1]) is half inside it, the
                // clamp included.
                let ground = HalfSpace::new(Vec3::Y, 0.05);
                let scene = Scene::new(1.0 / 60.0).with_gravity(GRAVITY).with_ground(ground);
                let settings = RelaxSettings::new()
                    .with_tolerance(TOLERANCE.max(1e-3), 400)
                    .with_chebyshev(DYNAMIC_RHO, 2.0, 0);
                let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
                let mut scalars = vec![0.0; n];
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                let report = relax_step(&body, &masses, &bar.pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                assert!(report.converged, "{report:?}");
                for ((x, x0), pinned) in x.iter().zip(&bar.rest).zip(&bar.pinned) {
                    if *pinned {
                        assert_eq!(x, x0);
                    } else {
                        assert!(x.y >= 0.05 - 1e-6, "free vertex inside the ground: {x}");
                    }
                }
            }

            #[test]
            fn bad_settings_are_refused_before_anything_is_touched() {
                let bar = bar();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = bar.rest.len();
                let scene = Scene::new(0.01).with_gravity(GRAVITY);
                let good = RelaxSettings::new();
                let accelerated = good.with_chebyshev(0.99, 2.0, 0);
                let cases = [
                    (Scene { dt: 0.0, ..scene }, good, StepError::TimeStep),
                    (Scene { dt: Real::NAN, ..scene }, good, StepError::TimeStep),
                    (scene.with_gravity(Vec3::splat(Real::INFINITY)), good, StepError::Gravity),
                    (scene, good.with_tolerance(1.0, 10), StepError::RelaxSettings),
                    (scene, good.with_tolerance(-0.1, 10), StepError::RelaxSettings),
                    (scene, RelaxSettings { armijo: 0.0, ..good }, StepError::RelaxSettings),
                    (scene, RelaxSettings { backtrack: 1.0, ..good }, StepError::RelaxSettings),
                    (scene, good.with_momentum(1.0), StepError::RelaxSettings),
                    (scene, good.with_chebyshev(1.0, 2.0, 0), StepError::RelaxSettings),
                    (scene, good.with_chebyshev(0.99, 0.0, 0), StepError::RelaxSettings),
                    (scene, good.with_chebyshev(0.99, Real::INFINITY, 0), StepError::RelaxSettings),
                    (scene, RelaxSettings { options: RelaxOptions { momentum: 0.5, ..accelerated.options }, ..accelerated }, StepError::RelaxSettings),
                ];
                let mut vectors = vec![Vec3::ZERO; scratch_len::relax(n)];
                let mut scalars = vec![0.0; n];
                for (scene, settings, expected) in cases {
                    let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::X; n]);
                    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                    let error = relax_step(&body, &masses, &bar.pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap_err();
                    assert_eq!(error, expected);
                    assert_eq!((x, v), (bar.rest.clone(), vec![Vec3::X; n]));
                }
                let mut bad = masses.clone();
                bad[2] = -1.0;
                let mut x = bar.rest.clone();
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let error = relax_quasi_static(&body, &bad, &[], &scene, &good, &mut x, &mut scratch).unwrap_err();
                assert_eq!(error, StepError::Mass { vertex: 2 });
                assert_eq!(x, bar.rest);
            }
        }
    };
}

// f32: the force balance stalls near 2e-3 of a vertex weight (forces of ~1e2 N cancelling).
relax_tests!(single, softfem, 3e-3);
relax_tests!(double, softfem::f64, 1e-7);

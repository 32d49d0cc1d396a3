//! The explicit stability bound against the true critical step, in both precisions: the true
//! limit `2 / omega_max` comes from the eigenvalues of `M^-1 K` (K assembled by central
//! differences of the force kernel, eigenvalues by nalgebra in f64). The bound must never exceed
//! it; explicit stepping at 0.9x the bound stays bounded for 1e4 steps on a stiff box; at 3x the
//! true limit the stepper reports the blow-up and leaves the state bit for bit as it was.
//!
//! Then what the charts of `examples/tradeoffs` show (`docs/charts/`), on cases small enough to
//! run in seconds: where explicit stepping stops being stable relative to the bound for
//! nu = 0.3, 0.45 and 0.49; each model's behaviour through inversion (`docs/math.md` section 2); the
//! relaxation stable at 1/30 s where explicit stepping blows up and says so; a near-incompressible
//! relaxation whose report is checked against the force balance; and a sweep of models, states
//! and steppers in which no NaN ever comes back silently.

macro_rules! stability_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use crate::common::modes::squared_frequencies;
            squared_frequencies!();
            use $($api)::+::element::TetRest;
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::StVK;
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::{
                ElasticModel, ExplicitScratch, ExplicitSettings, Scene, TetElastic,
                scratch_len, explicit_step, stable_time_step,
            };
            use $($api)::+::step::explicit::element_stable_time_step;
            use $($api)::+::types::{Real, Vec3};
            use softfem::StepError;

            /// A stiff 2 x 1 x 1 box of 5 cm cubes: E = 1e8 Pa, nu = 0.3, rho = 1000 kg/m^3.
            struct Box_ {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
            }

            fn stiff_box() -> Box_ {
                let max = Vec3::new(0.1, 0.05, 0.05);
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, max, (2, 1, 1), BoxSplit::Kuhn6);
                Box_ { rest, tets }
            }

            const DENSITY: Real = 1000.0;

            /// The true critical step `2 / omega_max` of `body` about its rest shape.
            fn true_limit(body: &impl ElasticModel<Vector = Vec3>, rest: &[Vec3], masses: &[Real]) -> f64 {
                let omega_max = squared_frequencies(body, rest, masses, 1e-4 * 0.05).last().unwrap().sqrt();
                2.0 / omega_max
            }

            /// A deterministic perturbation of the rest shape of relative size `amplitude`.
            fn perturbed(rest: &[Vec3], amplitude: Real) -> Vec<Vec3> {
                rest.iter()
                    .enumerate()
                    .map(|(i, &x)| {
                        let s = (i as Real * 1.7).sin();
                        let c = (i as Real * 2.3).cos();
                        x + Vec3::new(s, c, s * c) * (amplitude * 0.05)
                    })
                    .collect()
            }

            #[test]
            fn bound_never_exceeds_the_true_limit() {
                let mesh_data = stiff_box();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &mesh_data.rest, &mesh_data.tets, DENSITY);
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e8, 0.3).unwrap());
                let n = mesh.vertex_count();
                let mut stiffness = vec![0.0; n];
                let vertex_bound = stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                let element_bound = element_stable_time_step(&body, DENSITY).unwrap();
                let limit = true_limit(&body, &mesh_data.rest, &masses);
                println!(
                    "{}: true limit {limit:.3e} s, vertex bound {vertex_bound:.3e} s ({:.2}x), \
                     element bound {element_bound:.3e} s ({:.2}x)",
                    stringify!($precision),
                    vertex_bound as f64 / limit,
                    element_bound as f64 / limit,
                );
                // Both are proven lower bounds; 1e-4 covers the finite-difference K.
                assert!((vertex_bound as f64) <= limit * (1.0 + 1e-4));
                assert!(element_bound <= vertex_bound * (1.0 + 1e-5));
                // ...and not uselessly pessimistic.
                assert!((vertex_bound as f64) > 0.3 * limit);
            }

            #[test]
            fn explicit_at_nine_tenths_of_the_bound_stays_bounded() {
                let mesh_data = stiff_box();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &mesh_data.rest, &mesh_data.tets, DENSITY);
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e8, 0.3).unwrap());
                let n = mesh.vertex_count();
                let mut stiffness = vec![0.0; n];
                let dt = 0.9 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                let scene = Scene::new(dt);
                let settings = ExplicitSettings::new();
                let amplitude = 1e-3;
                let mut x = perturbed(&mesh_data.rest, amplitude);
                let mut v = vec![Vec3::ZERO; n];
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                let mut largest: Real = 0.0;
                for _ in 0..10_000 {
                    explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    for (p, r) in x.iter().zip(&mesh_data.rest) {
                        largest = largest.max((*p - *r).length());
                    }
                }
                println!("{}: max displacement {largest:.3e} m over 1e4 steps", stringify!($precision));
                // The perturbation is at most sqrt(3) * amplitude * 5 cm; the motion (with any
                // drift of the free body) stays within a few times that.
                assert!(largest < 10.0 * amplitude * 0.05);
            }

            #[test]
            fn above_the_limit_the_blow_up_is_reported_and_the_state_kept() {
                let mesh_data = stiff_box();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &mesh_data.rest, &mesh_data.tets, DENSITY);
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e8, 0.3).unwrap());
                let n = mesh.vertex_count();
                let limit = true_limit(&body, &mesh_data.rest, &masses);
                let scene = Scene::new((3.0 * limit) as Real);
                let settings = ExplicitSettings::new();
                let mut x = perturbed(&mesh_data.rest, 1e-4);
                let mut v = vec![Vec3::ZERO; n];
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                for step in 0..200 {
                    let (x_before, v_before) = (x.clone(), v.clone());
                    match explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch) {
                        Ok(_) => {}
                        Err(error) => {
                            println!("{}: {error} at step {step}", stringify!($precision));
                            assert!(matches!(
                                error,
                                StepError::EnergyBlowUp | StepError::NonFiniteState { .. }
                            ));
                            let bits = |s: &[Vec3]| s.iter().flat_map(|p| p.to_array().map(Real::to_bits)).collect::<Vec<_>>();
                            assert_eq!(bits(&x), bits(&x_before));
                            assert_eq!(bits(&v), bits(&v_before));
                            // Detected while the state is still sane (finite, growth caught early).
                            assert!(x.iter().all(|p| p.is_finite()));
                            return;
                        }
                    }
                }
                panic!("no blow-up reported in 200 steps at 3x the critical step");
            }

            use $($api)::+::material::{Material, NeoHookean, StableNeoHookean};
            use $($api)::+::step::{
                RelaxScratch, RelaxSettings, TetClamped, relax_quasi_static,
                relax_step,
            };

            /// Lumped masses of `mesh` at `DENSITY`.
            fn masses_of(mesh: &TetMesh) -> Vec<Real> {
                let mut masses = vec![0.0; mesh.vertex_count()];
                mesh.lumped_masses(DENSITY, &mut masses).unwrap();
                masses
            }

            /// Runs explicit steps in `scene` from `x` (at rest) for `steps` steps; returns the
            /// error that stopped it, if any, and the largest displacement from `rest`.
            #[allow(clippy::too_many_arguments)]
            fn explicit_run(
                body: &impl ElasticModel<Vector = Vec3>,
                masses: &[Real],
                pinned: &[bool],
                scene: &Scene<Vec3>,
                settings: &ExplicitSettings,
                x: &mut [Vec3],
                rest: &[Vec3],
                steps: usize,
            ) -> (Option<StepError>, Real) {
                let mut v = vec![Vec3::ZERO; x.len()];
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(x.len())];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                let mut largest: Real = 0.0;
                for _ in 0..steps {
                    let (x_before, v_before) = (x.to_vec(), v.clone());
                    if let Err(error) = explicit_step(body, masses, pinned, scene, settings, x, &mut v, &mut scratch) {
                        // Reported, and the state is the one before the step, finite.
                        assert_eq!(x, &x_before[..]);
                        assert_eq!(v, v_before);
                        assert!(x.iter().chain(&v).all(|p| p.is_finite()));
                        return (Some(error), largest);
                    }
                    assert!(x.iter().chain(&v).all(|p| p.is_finite()), "a NaN came back silently");
                    for (p, r) in x.iter().zip(rest) {
                        largest = largest.max((*p - *r).length());
                    }
                }
                (None, largest)
            }

            /// Explicit stepping of stable neo-Hookean is stable at 0.95x the computed bound and
            /// blows up (reported) at 1.1x the linearised critical step, for nu = 0.3, 0.45 and
            /// 0.49; the bound stays below the critical step for all three. The chart
            /// `stability.svg` maps the same across E on a larger box.
            #[test]
            fn explicit_stops_being_stable_between_the_bound_and_the_critical_step() {
                let mesh_data = stiff_box();
                let mut rest_data = vec![TetRest::default(); mesh_data.tets.len()];
                let mesh = TetMesh::new(&mesh_data.rest, &mesh_data.tets, &mut rest_data).unwrap();
                let masses = masses_of(&mesh);
                let amplitude = 1e-3;
                for nu in [0.3, 0.45, 0.49] {
                    let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e8, nu).unwrap());
                    let mut stiffness = vec![0.0; masses.len()];
                    let bound = stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                    let limit = true_limit(&body, &mesh_data.rest, &masses);
                    println!("{}: nu = {nu}: bound {:.3} of the critical step", stringify!($precision), bound as f64 / limit);
                    assert!((bound as f64) <= limit * (1.0 + 1e-4));

                    let mut x = perturbed(&mesh_data.rest, amplitude);
                    let (error, largest) = explicit_run(&body, &masses, &[], &Scene::new(0.95 * bound), &ExplicitSettings::new(), &mut x, &mesh_data.rest, 2000);
                    assert_eq!(error, None, "nu = {nu}: unstable at 0.95x the bound");
                    assert!(largest < 10.0 * amplitude * 0.05, "nu = {nu}: {largest}");

                    let mut x = perturbed(&mesh_data.rest, amplitude);
                    let above = Scene::new((1.1 * limit) as Real);
                    let (error, _) = explicit_run(&body, &masses, &[], &above, &ExplicitSettings::new(), &mut x, &mesh_data.rest, 2000);
                    assert!(
                        matches!(error, Some(StepError::EnergyBlowUp | StepError::NonFiniteState { .. })),
                        "nu = {nu}: no blow-up reported at 1.1x the critical step: {error:?}"
                    );
                }
            }

            /// One tetrahedron of edge `L` on its pinned base, with the apex at height `z` (so
            /// the volume ratio is `z / L`).
            fn tet_with_apex_at(z: Real) -> ([Vec3; 4], [Vec3; 4]) {
                let l = 0.1;
                let rest = [Vec3::ZERO, Vec3::X * l, Vec3::Y * l, Vec3::Z * l];
                let mut x = rest;
                x[3] = Vec3::new(0.0, 0.0, z);
                (rest, x)
            }

            const BASE_PINNED: [bool; 4] = [true, true, true, false];

            /// The volume ratio of the single tetrahedron after releasing it at `J = -0.5` and
            /// stepping explicitly (damping 10/s, half the stable bound) for 1 s.
            fn released_from_inversion(body: &impl ElasticModel<Vector = Vec3>, mesh: &TetMesh) -> Real {
                let (rest, mut x) = tet_with_apex_at(-0.05);
                let masses = masses_of(mesh);
                let mut stiffness = vec![0.0; 4];
                let dt = 0.5 * stable_time_step(body, &masses, &BASE_PINNED, &mut stiffness).unwrap();
                let settings = ExplicitSettings::new().with_damping(10.0);
                let (error, _) = explicit_run(body, &masses, &BASE_PINNED, &Scene::new(dt), &settings, &mut x, &rest, (1.0 / dt) as usize);
                assert_eq!(error, None);
                x[3].z / rest[3].z
            }

            /// `docs/math.md` section 2, one model at a time, on a tetrahedron pushed through its
            /// pinned base to `J = -0.5` and released: StVK settles at the mirror image
            /// (`F` a reflection, `J = -1`, stress-free), the isochoric neo-Hookean stays on the
            /// inverted side of its `J = 0` barrier, stable neo-Hookean comes back to `J = 1`,
            /// and the Irving–Teran–Fedkiw clamp brings StVK and neo-Hookean back.
            #[test]
            fn each_model_does_what_math_section_2_says_through_inversion() {
                let (rest, _) = tet_with_apex_at(0.1);
                let tets = [[0, 1, 2, 3]];
                let mut rest_data = [TetRest::default(); 1];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let (e, nu) = (1.0e5, 0.3);
                let stvk = StVK::from_young_poisson(e, nu).unwrap();
                let nh = NeoHookean::from_young_poisson(e, nu).unwrap();
                let snh = StableNeoHookean::from_young_poisson(e, nu).unwrap();
                let j = [
                    released_from_inversion(&TetElastic::new(mesh, stvk), &mesh),
                    released_from_inversion(&TetElastic::new(mesh, nh), &mesh),
                    released_from_inversion(&TetElastic::new(mesh, snh), &mesh),
                    released_from_inversion(&TetClamped::new(mesh, stvk, 0.3), &mesh),
                    released_from_inversion(&TetClamped::new(mesh, nh, 0.3), &mesh),
                ];
                println!("{}: J after release: StVK {:.3}, NH {:.3}, SNH {:.3}, StVK+clamp {:.3}, NH+clamp {:.3}", stringify!($precision), j[0], j[1], j[2], j[3], j[4]);
                // The apex moves only along z (the base is pinned, the forces are symmetric
                // about it), so J = -1 is exactly the reflection F = diag(1, 1, -1).
                assert!((j[0] + 1.0).abs() < 0.05, "StVK: {}", j[0]);
                assert!(j[1] < 0.0, "neo-Hookean came back through its barrier: {}", j[1]);
                for (name, value) in [("stable neo-Hookean", j[2]), ("StVK + clamp", j[3]), ("neo-Hookean + clamp", j[4])] {
                    assert!((value - 1.0).abs() < 0.05, "{name}: {value}");
                }
            }

            /// The isochoric neo-Hookean at `J = 0` (the apex in the base plane) has an infinite
            /// energy and a non-finite stress: the explicit stepper and the relaxation both refuse
            /// the step and leave the state as it was; nothing comes back as NaN.
            #[test]
            fn a_flat_neo_hookean_element_is_reported_not_returned_as_nan() {
                let (rest, x0) = tet_with_apex_at(0.0);
                let tets = [[0, 1, 2, 3]];
                let mut rest_data = [TetRest::default(); 1];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, NeoHookean::from_young_poisson(1.0e5, 0.3).unwrap());
                assert!(!body.material.first_piola(softfem_f(x0[3].z)).is_finite());
                let masses = masses_of(&mesh);
                let mut x = x0;
                let (error, _) = explicit_run(&body, &masses, &BASE_PINNED, &Scene::new(1e-4), &ExplicitSettings::new(), &mut x, &rest, 1);
                assert!(matches!(error, Some(StepError::NonFiniteState { vertex: 3 })), "{error:?}");
                assert_eq!(x, x0);

                let mut v = [Vec3::ZERO; 4];
                let (mut vectors, mut scalars) = ([Vec3::ZERO; scratch_len::relax(4)], [0.0; 4]);
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let settings = RelaxSettings::new();
                let error = relax_step(&body, &masses, &BASE_PINNED, &Scene::new(1.0 / 30.0), &settings, &mut x, &mut v, &mut scratch).unwrap_err();
                assert!(matches!(error, StepError::NonFiniteState { .. }), "{error:?}");
                assert_eq!((x, v), (x0, [Vec3::ZERO; 4]));
            }

            /// `F = diag(1, 1, z / L)` of the single tetrahedron with its apex at height `z`.
            fn softfem_f(z: Real) -> $($api)::+::types::Mat3 {
                $($api)::+::types::Mat3::from_diagonal(Vec3::new(1.0, 1.0, z / 0.1))
            }

            /// The kinetic plus elastic energy (J) of a state.
            fn energy<M: Material>(mesh: &TetMesh, material: &M, masses: &[Real], x: &[Vec3], v: &[Vec3]) -> f64 {
                let kinetic: f64 = v.iter().zip(masses).map(|(v, m)| 0.5 * (*m as f64) * (v.length_squared() as f64)).sum();
                kinetic + mesh.elastic_energy(material, x).unwrap() as f64
            }

            /// At dt = 1/30 s the stiff box (E = 1e8 Pa, critical step ~1e-4 s) is hundreds of
            /// times past the explicit limit: the explicit stepper reports the blow-up within a
            /// few steps. Implicit Euler by the relaxation stays finite and never gains energy
            /// (up to its tolerance) over a second of steps.
            #[test]
            fn relaxation_is_stable_at_a_thirtieth_of_a_second_where_explicit_blows_up() {
                let mesh_data = stiff_box();
                let mut rest_data = vec![TetRest::default(); mesh_data.tets.len()];
                let mesh = TetMesh::new(&mesh_data.rest, &mesh_data.tets, &mut rest_data).unwrap();
                let masses = masses_of(&mesh);
                let material = StableNeoHookean::from_young_poisson(1.0e8, 0.3).unwrap();
                let body = TetElastic::new(mesh, material);
                let dt: Real = 1.0 / 30.0;
                let limit = true_limit(&body, &mesh_data.rest, &masses);
                assert!((dt as f64) > 300.0 * limit, "{limit}");

                let mut x = perturbed(&mesh_data.rest, 1e-2);
                let (error, _) = explicit_run(&body, &masses, &[], &Scene::new(dt), &ExplicitSettings::new(), &mut x, &mesh_data.rest, 5);
                assert!(matches!(error, Some(StepError::EnergyBlowUp | StepError::NonFiniteState { .. })), "{error:?}");

                let mut x = perturbed(&mesh_data.rest, 1e-2);
                let mut v = vec![Vec3::ZERO; x.len()];
                let start = energy(&mesh, &material, &masses, &x, &v);
                let n = x.len();
                let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let scene = Scene::new(dt);
                let settings = RelaxSettings::new().with_tolerance(1e-3, 500).with_chebyshev(0.995, 2.0, 0);
                for step in 0..30 {
                    relax_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    assert!(x.iter().chain(&v).all(|p| p.is_finite()));
                    let now = energy(&mesh, &material, &masses, &x, &v);
                    assert!(now <= start * 1.001, "step {step}: energy {now} > {start}");
                }
            }

            /// nu = 0.49 on the 24-tet cantilever of tests/steppers/relax.rs: the quasi-static
            /// solve either converges or says it did not, and its reported residual is the force
            /// imbalance recomputed from the force kernel (`|f + m g|` over free vertices), so a
            /// caller can trust what it is told. The sag is positive and finite.
            #[test]
            fn near_incompressible_relaxation_reports_its_true_residual() {
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, Vec3::new(0.4, 0.1, 0.1), (4, 1, 1), BoxSplit::Kuhn6);
                let (nv, nt) = (rest.len(), tets.len());
                let mut rest_data = vec![TetRest::default(); nt];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let pinned: Vec<bool> = rest.iter().map(|p| p.x == 0.0).collect();
                let masses = masses_of(&mesh);
                let material = StableNeoHookean::from_young_poisson(1.0e6, 0.49).unwrap();
                let body = TetElastic::new(mesh, material);
                let gravity = Vec3::new(0.0, -9.81, 0.0);
                let scene = Scene::new(1.0).with_gravity(gravity);
                let settings = RelaxSettings::new().with_tolerance(1e-4, 20_000).with_chebyshev(0.999, 2.0, 0);
                let mut x = rest.clone();
                let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(nv)], vec![0.0; nv]);
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let report = relax_quasi_static(&body, &masses, &pinned, &scene, &settings, &mut x, &mut scratch).unwrap();
                let mut f = vec![Vec3::ZERO; nv];
                mesh.add_elastic_forces(&material, &x, &mut f).unwrap();
                let imbalance = f.iter().zip(&masses).zip(&pinned).filter(|(_, p)| !**p)
                    .map(|((f, m), _)| (*f + gravity * *m).length_squared() as f64).sum::<f64>().sqrt();
                let sag = rest.iter().zip(&x).map(|(r, x)| r.y - x.y).fold(0.0, Real::max);
                println!("{}: nu = 0.49: {report:?}; recomputed imbalance {imbalance:.3e} N; sag {sag:.4} m", stringify!($precision));
                assert!(x.iter().all(|p| p.is_finite()));
                assert!(sag > 0.0 && sag < 0.1);
                let reported = report.residual as f64;
                // The two differ by the rounding of forces of about the body's weight (64 eps of
                // it), and by 1e-3 of the residual at most.
                let weight = masses.iter().sum::<Real>() as f64 * 9.81;
                let floor = 64.0 * f64::from(Real::EPSILON) * weight;
                assert!((reported - imbalance).abs() <= 1e-3 * imbalance + floor, "{reported} vs {imbalance}");
                let target = settings.tolerance as f64 * (report.initial_residual as f64).max(masses.iter().map(|m| (*m as f64 * 9.81).powi(2)).sum::<f64>().sqrt());
                assert_eq!(report.converged, reported <= target);
            }

            /// Every model, every state from rest to flat and inverted, every stepper at a safe
            /// and at an unsafe step: each call either returns a finite state or an error with
            /// the state untouched (`explicit_run` and the relaxation loop check both). The flat
            /// neo-Hookean cases must be among the errors, so the sweep does reach the failures.
            #[test]
            fn no_case_produces_nan_silently() {
                let (rest, _) = tet_with_apex_at(0.1);
                let tets = [[0, 1, 2, 3]];
                let mut rest_data = [TetRest::default(); 1];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let masses = masses_of(&mesh);
                let (e, nu) = (1.0e5, 0.45);
                let mut errors = Vec::new();
                fn relax_checked<M: Material>(body: &TetElastic<M>, masses: &[Real], x: &mut [Vec3; 4], dt: Real) -> Option<StepError> {
                    let mut v = [Vec3::ZERO; 4];
                    let (mut vectors, mut scalars) = ([Vec3::ZERO; scratch_len::relax(4)], [0.0; 4]);
                    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                    let scene = Scene::new(dt);
                    let settings = RelaxSettings::new().with_tolerance(1e-3, 200);
                    for _ in 0..10 {
                        let before = (*x, v);
                        match relax_step(body, masses, &BASE_PINNED, &scene, &settings, x, &mut v, &mut scratch) {
                            Ok(_) => assert!(x.iter().chain(&v).all(|p| p.is_finite()), "a NaN came back silently"),
                            Err(error) => {
                                assert_eq!((*x, v), before);
                                return Some(error);
                            }
                        }
                    }
                    None
                }
                for z in [0.1, 0.05, 1e-6, 0.0, -1e-6, -0.05] {
                    let (_, x0) = tet_with_apex_at(z);
                    let stvk = StVK::from_young_poisson(e, nu).unwrap();
                    let nh = NeoHookean::from_young_poisson(e, nu).unwrap();
                    let snh = StableNeoHookean::from_young_poisson(e, nu).unwrap();
                    let mut stiffness = [0.0; 4];
                    let bound = stable_time_step(&TetElastic::new(mesh, snh), &masses, &BASE_PINNED, &mut stiffness).unwrap();
                    for dt in [0.5 * bound, 20.0 * bound] {
                        let (scene, settings) = (Scene::new(dt), ExplicitSettings::new());
                        let runs: [(&str, Option<StepError>); 5] = [
                            ("StVK", explicit_run(&TetElastic::new(mesh, stvk), &masses, &BASE_PINNED, &scene, &settings, &mut x0.clone(), &rest, 200).0),
                            ("NH", explicit_run(&TetElastic::new(mesh, nh), &masses, &BASE_PINNED, &scene, &settings, &mut x0.clone(), &rest, 200).0),
                            ("SNH", explicit_run(&TetElastic::new(mesh, snh), &masses, &BASE_PINNED, &scene, &settings, &mut x0.clone(), &rest, 200).0),
                            ("StVK clamp", explicit_run(&TetClamped::new(mesh, stvk, 0.3), &masses, &BASE_PINNED, &scene, &settings, &mut x0.clone(), &rest, 200).0),
                            ("NH clamp", explicit_run(&TetClamped::new(mesh, nh, 0.3), &masses, &BASE_PINNED, &scene, &settings, &mut x0.clone(), &rest, 200).0),
                        ];
                        errors.extend(runs.iter().filter_map(|(name, e)| e.map(|e| (format!("explicit {name} z = {z} dt = {dt:.1e}"), e))));
                    }
                    for (name, error) in [
                        ("StVK", relax_checked(&TetElastic::new(mesh, stvk), &masses, &mut x0.clone(), 1.0 / 30.0)),
                        ("NH", relax_checked(&TetElastic::new(mesh, nh), &masses, &mut x0.clone(), 1.0 / 30.0)),
                        ("SNH", relax_checked(&TetElastic::new(mesh, snh), &masses, &mut x0.clone(), 1.0 / 30.0)),
                    ] {
                        errors.extend(error.map(|e| (format!("relax {name} z = {z}"), e)));
                    }
                }
                for (case, error) in &errors {
                    println!("{}: {case}: {error}", stringify!($precision));
                }
                assert!(errors.iter().any(|(case, _)| case.starts_with("explicit NH z = 0 ")));
                assert!(errors.iter().any(|(case, _)| case == "relax NH z = 0"));
            }
        }
    };
}

stability_tests!(single, softfem);
stability_tests!(double, softfem::f64);

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
                RelaxScratch, RelaxSettings, TetElastic, relax_quasi_static, relax_scratch_len,
                relax_step,
            };
            use $($api)::+::types::{Real, Vec3};

            /// Relative residual asked of the solver in this precision.
            const TOLERANCE: Real = $tolerance;
            const GRAVITY: Vec3 = Vec3::new(0.0, -9.81, 0.0);

            struct Bar {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
                pinned: Vec<bool>,
            }

            fn bar() -> Bar {
                let (nv, nt) = box_counts(4, 1, 1, BoxSplit::Kuhn6).unwrap();
                let mut rest = vec![Vec3::ZERO; nv];
                let mut tets = vec![[0; 4]; nt];
                let max = Vec3::new(0.4, 0.1, 0.1);
                fill_box(Vec3::ZERO, max, 4, 1, 1, BoxSplit::Kuhn6, &mut rest, &mut tets).unwrap();
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
            fn quasi_static_and_implicit_euler_reach_the_same_equilibrium() {
                let bar = bar();
                let mut rest_data = vec![TetRest::default(); bar.tets.len()];
                let mesh = TetMesh::new(&bar.rest, &bar.tets, &mut rest_data).unwrap();
                let material = StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
                let body = TetElastic::new(mesh, material);
                let n = bar.rest.len();
                let mut masses = vec![0.0; n];
                mesh.lumped_masses(1000.0, &mut masses).unwrap();
                let weight = masses.iter().fold(0.0 as Real, |a, &m| a.max(m)) * 9.81;
                let mut vectors = vec![Vec3::ZERO; relax_scratch_len(n)];
                let mut scalars = vec![0.0; n];

                // Quasi-static, from rest.
                let settings = RelaxSettings::new(1.0 / 60.0)
                    .with_gravity(GRAVITY)
                    .with_tolerance(TOLERANCE, 50_000)
                    .with_momentum(0.9);
                let mut x_static = bar.rest.clone();
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let report = relax_quasi_static(&body, &masses, &bar.pinned, &settings, &mut x_static, &mut scratch).unwrap();
                let static_imbalance = imbalance(&mesh, &material, &x_static, &masses, &bar.pinned);
                let sag = bar.rest.iter().zip(&x_static).map(|(r, x)| r.y - x.y).fold(0.0, Real::max);
                println!("{}: quasi-static {report:?}; tip sag {sag:.4} m, imbalance {:.1e} of the largest vertex weight",
                    stringify!($precision), static_imbalance / weight);
                assert!(report.converged);
                assert!(sag > 0.005 && sag < 0.1);
                // The residual is the force imbalance at free vertices.
                assert!(static_imbalance < 20.0 * TOLERANCE * weight);

                // Implicit Euler from rest, 1/60 s steps, until it settles.
                // Each step only needs to be accurate relative to the gravity load, not to the
                // end state: 1e-4 in f64 (the f32 floor is the one above).
                let dynamic = settings.with_tolerance(TOLERANCE.max(1e-4), 2_000).with_momentum(0.5);
                let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                let (mut iterations, mut evaluations, mut unconverged) = (0, 0, 0);
                let steps = 300;
                for _ in 0..steps {
                    let report = relax_step(&body, &masses, &bar.pinned, &dynamic, &mut x, &mut v, &mut scratch).unwrap();
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
                // Preconditioned descent is slow on a stiff bar (hundreds of iterations per step):
                // a few steps exhaust the 2000-iteration budget, and the state still settles.
                assert!(unconverged <= steps / 10);
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
            fn bad_settings_are_refused_before_anything_is_touched() {
                let bar = bar();
                let mut rest_data = vec![TetRest::default(); bar.tets.len()];
                let mesh = TetMesh::new(&bar.rest, &bar.tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = bar.rest.len();
                let mut masses = vec![0.0; n];
                mesh.lumped_masses(1000.0, &mut masses).unwrap();
                let good = RelaxSettings::new(0.01).with_gravity(GRAVITY);
                let cases = [
                    (RelaxSettings { dt: 0.0, ..good }, StepError::TimeStep),
                    (RelaxSettings { dt: Real::NAN, ..good }, StepError::TimeStep),
                    (good.with_gravity(Vec3::splat(Real::INFINITY)), StepError::Gravity),
                    (good.with_tolerance(1.0, 10), StepError::RelaxSettings),
                    (good.with_tolerance(-0.1, 10), StepError::RelaxSettings),
                    (RelaxSettings { armijo: 0.0, ..good }, StepError::RelaxSettings),
                    (RelaxSettings { backtrack: 1.0, ..good }, StepError::RelaxSettings),
                    (good.with_momentum(1.0), StepError::RelaxSettings),
                ];
                let mut vectors = vec![Vec3::ZERO; relax_scratch_len(n)];
                let mut scalars = vec![0.0; n];
                for (settings, expected) in cases {
                    let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::X; n]);
                    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                    let error = relax_step(&body, &masses, &bar.pinned, &settings, &mut x, &mut v, &mut scratch).unwrap_err();
                    assert_eq!(error, expected);
                    assert_eq!((x, v), (bar.rest.clone(), vec![Vec3::X; n]));
                }
                let mut bad = masses.clone();
                bad[2] = -1.0;
                let mut x = bar.rest.clone();
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let error = relax_quasi_static(&body, &bad, &[], &good, &mut x, &mut scratch).unwrap_err();
                assert_eq!(error, StepError::Mass { vertex: 2 });
                assert_eq!(x, bar.rest);
            }
        }
    };
}

// f32: the force balance stalls near 2e-3 of a vertex weight (forces of ~1e2 N cancelling).
relax_tests!(single, softfem, 3e-3);
relax_tests!(double, softfem::f64, 1e-7);

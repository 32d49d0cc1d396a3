//! The explicit stepper's physics and contract, in both precisions: undamped energy does not
//! drift over 1000 periods of the lowest mode; a dropped block lands and comes to rest on the
//! ground without penetrating; pinned vertices never move; a 2D body works through the same
//! stepper; every bad parameter gives its error and touches nothing.

macro_rules! step_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use crate::common::modes::squared_frequencies;
            squared_frequencies!();
            use softfem::{StepBuffer, StepError};
            use $($api)::+::element::{TetRest, TriRest, TriangleStVK};
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box, fill_rectangle, rectangle_counts};
            use $($api)::+::material::{StVK, StableNeoHookean};
            use $($api)::+::mesh::{TetMesh, TriMesh};
            use $($api)::+::step::{
                ElasticModel, ExplicitScratch, ExplicitSettings, HalfSpace, TetClamped, TetElastic,
                Scene, TriElastic, scratch_len, explicit_step, stable_time_step,
            };
            use $($api)::+::types::{Real, Vec2, Vec3};

            fn block(n: [usize; 3], min: Vec3, max: Vec3) -> (Vec<Vec3>, Vec<[u32; 4]>) {
                let (rest, tets) = crate::common::scenes::generated_box!(min, max, (n[0], n[1], n[2]), BoxSplit::Kuhn6);
                (rest, tets)
            }

            /// Bit patterns, so that NaN compares equal to itself.
            fn bits<V: Copy + Into<[Real; N]>, const N: usize>(s: &[V]) -> Vec<[u64; N]> {
                s.iter().map(|&v| v.into().map(|r: Real| r.to_bits() as u64)).collect()
            }

            /// A body exactly at rest with no gravity has a zero energy indicator; moving it
            /// afterwards (a kick, a dragged vertex) is not a blow-up. From a non-zero indicator,
            /// the same stepper still refuses a hundredfold jump.
            #[test]
            fn motion_after_exact_rest_is_not_a_blow_up() {
                let (rest, tets) = block([1, 1, 1], Vec3::ZERO, Vec3::splat(0.1));
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = rest.len();
                let mut stiffness = vec![0.0; n];
                let dt = 0.5 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                let (scene, settings) = (Scene::new(dt), ExplicitSettings::new());
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; n]);
                explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                v[3] = Vec3::new(0.0, 0.0, 0.5); // kick one vertex, without forget_history
                explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                for vertex in &mut v {
                    *vertex *= 1000.0; // now a millionfold jump in kinetic energy
                }
                let error = explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch);
                assert_eq!(error.unwrap_err(), StepError::EnergyBlowUp);
            }

            /// The bouncy-like scene of the blow-up tests: a 0.2 m jelly cube (4^3 cells, stable
            /// neo-Hookean, E = 50 kPa, nu = 0.45, 1000 kg/m^3) dropped from 0.3 m onto the ground
            /// z = 0 with friction 0.6, restitution 0.3 and damping 0.5 /s.
            struct Drop {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
                masses: Vec<Real>,
            }

            const DROP_SIZE: Real = 0.2;

            impl Drop {
                fn new() -> Drop {
                    let h = 0.5 * DROP_SIZE;
                    let (rest, tets) = block([4, 4, 4], Vec3::new(-h, -h, 0.3), Vec3::new(h, h, 0.3 + DROP_SIZE));
                    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                    Drop { rest, tets, masses }
                }

                fn material() -> StableNeoHookean {
                    StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap()
                }

                fn settings(dt: Real, substeps: u32) -> (Scene<'static, Vec3>, ExplicitSettings) {
                    let scene = Scene::new(dt)
                        .with_gravity(Vec3::new(0.0, 0.0, -9.81))
                        .with_ground(HalfSpace::new(Vec3::Z, 0.0).with_friction(0.6).with_restitution(0.3));
                    (scene, ExplicitSettings::new().with_substeps(substeps).with_damping(0.5))
                }

                /// `(critical step from the largest eigenvalue of M^-1 K at rest, proven bound)`.
                fn steps(&self) -> (Real, Real) {
                    let mut rest_data = vec![TetRest::default(); self.tets.len()];
                    let mesh = TetMesh::new(&self.rest, &self.tets, &mut rest_data).unwrap();
                    let body = TetElastic::new(mesh, Drop::material());
                    let omega_max = squared_frequencies(&body, &self.rest, &self.masses, 1e-5).last().unwrap().sqrt();
                    let mut stiffness = vec![0.0; self.rest.len()];
                    let bound = stable_time_step(&body, &self.masses, &[], &mut stiffness).unwrap();
                    ((2.0 / omega_max) as Real, bound)
                }

                /// Steps `calls` calls of `dt` in `substeps` substeps, for at most `duration` s;
                /// returns the positions after each accepted call and the first error.
                fn run(&self, dt: Real, substeps: u32, duration: Real) -> (Vec<Vec<Vec3>>, Option<StepError>) {
                    self.run_from(&self.rest, dt, substeps, duration)
                }

                /// [`run`](Self::run) released from `start` (at rest velocity) instead of the
                /// rest shape.
                fn run_from(&self, start: &[Vec3], dt: Real, substeps: u32, duration: Real) -> (Vec<Vec<Vec3>>, Option<StepError>) {
                    let mut rest_data = vec![TetRest::default(); self.tets.len()];
                    let mesh = TetMesh::new(&self.rest, &self.tets, &mut rest_data).unwrap();
                    let body = TetElastic::new(mesh, Drop::material());
                    let n = self.rest.len();
                    let (scene, settings) = Drop::settings(dt, substeps);
                    let (mut x, mut v) = (start.to_vec(), vec![Vec3::ZERO; n]);
                    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                    let mut scratch = ExplicitScratch::new(&mut buffer);
                    let mut states = vec![x.clone()];
                    for _ in 0..(duration / dt) as usize {
                        let before = (bits(&x), bits(&v));
                        match explicit_step(&body, &self.masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch) {
                            Ok(_) => states.push(x.clone()),
                            Err(error) => {
                                // The state handed back is the one before the call, bit for bit.
                                assert_eq!((bits(&x), bits(&v)), before);
                                return (states, Some(error));
                            }
                        }
                    }
                    (states, None)
                }
            }

            /// The largest distance between corresponding vertices, over the body's size.
            fn distance(a: &[Vec3], b: &[Vec3]) -> f64 {
                let worst = a.iter().zip(b).map(|(p, q)| (*p - *q).length()).fold(0.0, Real::max);
                (worst / DROP_SIZE) as f64
            }

            /// For steps above the critical one (the largest eigenvalue of `M^-1 K` at rest), the
            /// stepper must report a blow-up, and the state it hands back must lie within 1 % of
            /// the body's size of a stable run (the same calls in substeps of at most 0.45 times
            /// the critical step). At 0.5 and 0.9 times the proven bound it must never report one
            /// over 3 s of drop, bounce and rest. Prints the table quoted in the report.
            #[test]
            fn early_blow_up_detection_report() {
                let scene = Drop::new();
                let (critical, bound) = scene.steps();
                println!("{}: critical step {critical:.4e} s, proven bound {bound:.4e} s", stringify!($precision));
                assert!(bound <= critical);
                for factor in [1.05, 1.5, 2.5] {
                    let dt = factor * critical;
                    let (states, error) = scene.run(dt, 1, 3.0);
                    let error = error.expect("no blow-up reported above the critical step");
                    let accepted = states.len() - 1;
                    let substeps = (factor / 0.45).ceil() as u32;
                    let (reference, reference_error) = scene.run(dt, substeps, accepted as Real * dt);
                    assert_eq!(reference_error, None);
                    let handed_back = &states[accepted];
                    let away = distance(handed_back, &reference[accepted.min(reference.len() - 1)]);
                    println!(
                        "{}: {factor:.2} x critical: {error:?} after {accepted} accepted steps ({:.3} s), \
                         handed-back state {away:.2e} body sizes from the stable run",
                        stringify!($precision),
                        accepted as Real * dt
                    );
                    assert_eq!(error, StepError::EnergyBlowUp);
                    assert!(away < 0.01);
                }
                for fraction in [0.5, 0.9] {
                    let dt = fraction * bound;
                    let (states, error) = scene.run(dt, 1, 3.0);
                    let lowest = states.last().unwrap().iter().map(|p| p.z).fold(Real::INFINITY, Real::min);
                    println!(
                        "{}: {fraction} x bound: {} steps, error {error:?}, lowest z at the end {lowest:.2e}",
                        stringify!($precision),
                        states.len() - 1
                    );
                    assert_eq!(error, None, "false alarm at {fraction} x the bound");
                }
            }

            /// The same hand-back from a start that is not the rest shape: every rest position moved
            /// by up to 1e-4 of an edge (0.05 m) in each coordinate, four seeds, released without
            /// velocity under gravity. A blow-up must be reported at 1.05, 1.5 and 2.5 times the
            /// critical step, with the state restored, and the state handed back must lie within 1 %
            /// of the body's size of the stable run from the same start (substeps of at most 0.45
            /// times the critical step) at 1.05 and 1.5 times, 2 % at 2.5 times. (At 1 % of an edge
            /// the coarse step's own error against that run is 2e-2 at 0.95 times the critical step,
            /// too large for the comparison to mean anything; at 1e-4 it is 6.6e-3, printed.)
            #[test]
            fn blow_up_from_a_perturbed_start_is_handed_back_early() {
                let scene = Drop::new();
                let (critical, _) = scene.steps();
                let edge = DROP_SIZE / 4.0;
                let mut worst: [f64; 3] = [0.0; 3];
                for seed in 1..=4_u64 {
                    // xorshift64: a fixed sequence, the same in both precisions.
                    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15);
                    let mut uniform = move || {
                        state ^= state << 13;
                        state ^= state >> 7;
                        state ^= state << 17;
                        (state >> 11) as f64 / (1_u64 << 53) as f64 * 2.0 - 1.0
                    };
                    let start: Vec<Vec3> = scene
                        .rest
                        .iter()
                        .map(|&p| {
                            let shift = Vec3::new(uniform() as Real, uniform() as Real, uniform() as Real);
                            p + shift * (1e-4 * edge)
                        })
                        .collect();
                    {
                        let dt = 0.95 * critical;
                        let (states, error) = scene.run_from(&start, dt, 1, 0.2);
                        let (reference, _) = scene.run_from(&start, dt, 3, 0.2);
                        let worst_stable = states.iter().zip(&reference).map(|(a, b)| distance(a, b)).fold(0.0, f64::max);
                        assert_eq!(error, None);
                        println!(
                            "{}: seed {seed}: stable at 0.95 x critical for 0.2 s, {worst_stable:.2e} body sizes from the substepped run",
                            stringify!($precision)
                        );
                    }
                    for (slot, factor) in [1.05, 1.5, 2.5].into_iter().enumerate() {
                        let dt = factor * critical;
                        let (states, error) = scene.run_from(&start, dt, 1, 3.0);
                        let error = error.expect("no blow-up reported above the critical step");
                        assert_eq!(error, StepError::EnergyBlowUp);
                        let accepted = states.len() - 1;
                        let substeps = (factor / 0.45).ceil() as u32;
                        let (reference, reference_error) = scene.run_from(&start, dt, substeps, accepted as Real * dt);
                        assert_eq!(reference_error, None);
                        let away = distance(&states[accepted], &reference[accepted.min(reference.len() - 1)]);
                        println!(
                            "{}: seed {seed}, {factor:.2} x critical: blow-up after {accepted} accepted steps \
                             ({:.3} s), handed-back state {away:.2e} body sizes from the stable run",
                            stringify!($precision),
                            accepted as Real * dt
                        );
                        worst[slot] = worst[slot].max(away);
                    }
                }
                println!("{}: worst over the seeds at 1.05, 1.5, 2.5 x critical: {:.2e} {:.2e} {:.2e}", stringify!($precision), worst[0], worst[1], worst[2]);
                // Measured 4.4e-3, 1.7e-3 and 1.8e-2 in both precisions. At 2.5 times the mode
                // grows 23-fold per substep and the first test needs two substeps of forces, so
                // two steps are accepted: 1e-2 is met at 1.05 and 1.5 times, not at 2.5.
                assert!(worst[0] < 0.01 && worst[1] < 0.01, "{worst:?}");
                assert!(worst[2] < 0.02, "{worst:?}");
            }

            /// No false alarm on a different kind of motion: an undamped StVK cantilever (clamped
            /// stress, one end pinned) released under gravity swings and vibrates for 3 s at 0.5 and
            /// 0.9 times the proven bound, in one and in four substeps per call.
            #[test]
            fn swinging_cantilever_is_never_taken_for_a_blow_up() {
                let (rest, tets) = block([6, 1, 1], Vec3::ZERO, Vec3::new(0.6, 0.1, 0.1));
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                let material = StVK::from_young_poisson(1.0e5, 0.3).unwrap();
                let body = TetClamped::checked(mesh, material, 0.3).unwrap();
                let n = rest.len();
                let pinned: Vec<bool> = rest.iter().map(|p| p.x == 0.0).collect();
                let mut stiffness = vec![0.0; n];
                let bound = stable_time_step(&body, &masses, &pinned, &mut stiffness).unwrap();
                for (fraction, substeps) in [(0.5, 1), (0.9, 1), (0.9, 4)] {
                    let dt = fraction * bound * substeps as Real;
                    let scene = Scene::new(dt).with_gravity(Vec3::new(0.0, -9.81, 0.0));
                    let settings = ExplicitSettings::new().with_substeps(substeps);
                    let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; n]);
                    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                    let mut scratch = ExplicitScratch::new(&mut buffer);
                    let calls = (3.0 / dt) as usize;
                    let mut lowest: Real = 0.0;
                    for call in 0..calls {
                        let result = explicit_step(&body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch);
                        assert!(result.is_ok(), "{fraction} x bound, {substeps} substeps: {result:?} at call {call}");
                        lowest = lowest.min(x.iter().map(|p| p.y).fold(Real::INFINITY, Real::min));
                    }
                    // It did swing: the free end fell well below its rest height.
                    assert!(lowest < -0.05, "{lowest}");
                }
            }

            #[test]
            fn undamped_energy_does_not_drift_over_1000_periods() {
                let (rest, tets) = block([1, 1, 1], Vec3::ZERO, Vec3::splat(0.1));
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                let material = StVK::from_young_poisson(1.0e6, 0.3).unwrap();
                let body = TetElastic::new(mesh, material);
                let n = rest.len();

                // The lowest non-rigid frequency from K (central differences, f64 eigenvalues).
                let omegas = squared_frequencies(&body, &rest, &masses, 1e-5);
                let omega_max = omegas.last().unwrap().sqrt();
                let omega_min = omegas.iter().find(|&&w| w > 1e-6 * omega_max * omega_max).unwrap().sqrt();
                let period = 2.0 * std::f64::consts::PI / omega_min;

                let mut stiffness = vec![0.0; n];
                // A tenth of the bound keeps the energy's O(dt omega) oscillation small next to
                // the drift being measured.
                let dt = 0.1 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                let steps_per_period = (period / dt as f64).round() as usize;
                let steps = 1000 * steps_per_period;
                // Small amplitude: 1% strain, a shear plus a stretch (large enough that f32
                // rounding of the 0.1 m positions stays far below the tolerance).
                let mut x: Vec<Vec3> = rest.iter().map(|&p| p + Vec3::new(p.y, 0.0, 0.5 * p.z) * 1e-2).collect();
                let mut v = vec![Vec3::ZERO; n];
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                let (scene, settings) = (Scene::new(dt), ExplicitSettings::new());
                let energy = |x: &[Vec3], v: &[Vec3]| -> f64 {
                    let kinetic: Real = v.iter().zip(&masses).map(|(v, m)| 0.5 * m * v.length_squared()).sum();
                    (kinetic + mesh.elastic_energy(&material, x).unwrap()) as f64
                };
                let e0 = energy(&x, &v);
                let window = 50 * steps_per_period;
                let (mut first, mut last, mut worst) = (0.0, 0.0, 0.0f64);
                for i in 0..steps {
                    explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    let e = energy(&x, &v);
                    worst = worst.max((e - e0).abs() / e0);
                    if i < window { first += e; }
                    if i >= steps - window { last += e; }
                }
                let drift = (last - first).abs() / (window as f64 * e0);
                println!(
                    "{}: omega {omega_min:.1}..{omega_max:.1} rad/s, {steps_per_period} steps/period, \
                     {steps} steps; drift of the 50-period mean {drift:.2e}, max oscillation {worst:.2e}",
                    stringify!($precision)
                );
                // Symplectic Euler conserves a modified energy: the true energy oscillates (by
                // O(dt omega)) but its mean must not drift.
                assert!(drift < 1e-3);
            }

            #[test]
            fn dropped_block_lands_and_rests_on_the_ground() {
                let (rest, tets) = block([2, 2, 2], Vec3::new(0.0, 0.2, 0.0), Vec3::new(0.1, 0.3, 0.1));
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.3).unwrap());
                let n = rest.len();
                let mut stiffness = vec![0.0; n];
                let dt = 0.9 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                let scene = Scene::new(dt)
                    .with_gravity(Vec3::new(0.0, -9.81, 0.0))
                    .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
                let settings = ExplicitSettings::new().with_damping(5.0);
                let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; n]);
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                let steps = (3.0 / dt) as usize;
                let mut lowest: Real = Real::INFINITY;
                let mut contacts = 0;
                for _ in 0..steps {
                    let report = explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    lowest = lowest.min(x.iter().map(|p| p.y).fold(Real::INFINITY, Real::min));
                    contacts = report.ground_contacts;
                }
                let speed = v.iter().map(|v| v.length()).fold(0.0, Real::max);
                let top = x.iter().map(|p| p.y).fold(Real::NEG_INFINITY, Real::max);
                println!(
                    "{}: {steps} steps of {dt:.2e} s; lowest y ever {lowest:.2e} m, final top {top:.4} m, \
                     max speed {speed:.2e} m/s, {contacts} vertices in contact",
                    stringify!($precision)
                );
                // Projection puts a vertex exactly on the plane, to rounding of 0.3 m coordinates.
                assert!(lowest > -1e-6);
                assert_eq!(contacts, 9); // the bottom face's 3 x 3 vertices
                assert!(speed < 1e-2);
                // Sagged under its weight, but not flattened: rho g h / E ~ 1% strain.
                assert!(top > 0.095 && top < 0.1);
            }

            #[test]
            fn pinned_vertices_never_move() {
                let (rest, tets) = block([2, 1, 1], Vec3::ZERO, Vec3::new(0.2, 0.1, 0.1));
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e5, 0.3).unwrap());
                let n = rest.len();
                let pinned: Vec<bool> = rest.iter().map(|p| p.x == 0.0).collect();
                let mut stiffness = vec![0.0; n];
                let dt = 0.5 * stable_time_step(&body, &masses, &pinned, &mut stiffness).unwrap();
                let scene = Scene::new(dt).with_gravity(Vec3::new(0.0, -9.81, 0.0));
                let settings = ExplicitSettings::new().with_substeps(3);
                let mut x = rest.clone();
                let mut v: Vec<Vec3> = (0..n).map(|i| Vec3::new(0.0, 0.0, i as Real * 1e-3)).collect();
                let v0 = v.clone();
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                for _ in 0..200 {
                    explicit_step(&body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                }
                for i in 0..n {
                    if pinned[i] {
                        assert_eq!(<[Real; 3]>::from(x[i]), <[Real; 3]>::from(rest[i]));
                        assert_eq!(<[Real; 3]>::from(v[i]), <[Real; 3]>::from(v0[i]));
                    } else {
                        assert!(x[i].y < rest[i].y); // the free end sags
                    }
                }
            }

            #[test]
            fn a_2d_square_falls_onto_the_ground() {
                let (nv, nt) = rectangle_counts(2, 2).unwrap();
                let mut rest = vec![Vec2::ZERO; nv];
                let mut tris = vec![[0; 3]; nt];
                fill_rectangle(Vec2::new(0.0, 0.05), Vec2::new(0.1, 0.15), 2, 2, &mut rest, &mut tris).unwrap();
                let mut rest_data = vec![TriRest::default(); nt];
                let mesh = TriMesh::new(&rest, &tris, &mut rest_data).unwrap();
                let body = TriElastic { mesh, material: TriangleStVK::new(&StVK::from_young_poisson(1.0e5, 0.3).unwrap()) };
                let mut masses = vec![0.0; nv];
                mesh.lumped_masses(1000.0, &mut masses).unwrap();
                let mut stiffness = vec![0.0; nv];
                let dt = 0.9 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                let scene = Scene::new(dt)
                    .with_gravity(Vec2::new(0.0, -9.81))
                    .with_ground(HalfSpace::new(Vec2::Y, 0.0).with_restitution(0.0).with_friction(0.5));
                let settings = ExplicitSettings::new().with_damping(5.0);
                let (mut x, mut v) = (rest.clone(), vec![Vec2::ZERO; nv]);
                let mut buffer = vec![Vec2::ZERO; scratch_len::explicit(nv)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                for _ in 0..(2.0 / dt) as usize {
                    explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                }
                let speed = v.iter().map(|v| v.length()).fold(0.0, Real::max);
                println!("{}: 2D square, max speed {speed:.2e} m/s", stringify!($precision));
                assert!(x.iter().all(|p| p.y > -1e-6));
                assert!(x.iter().any(|p| p.y < 1e-6));
                // Restitution 0 (with 0.3 the bottom vertices keep chattering at ~3 cm/s).
                assert!(speed < 1e-2);
            }

            #[test]
            fn every_bad_parameter_gives_its_error_and_touches_nothing() {
                let (rest, tets) = block([1, 1, 1], Vec3::ZERO, Vec3::splat(0.1));
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e5, 0.3).unwrap());
                let n = rest.len();
                let good = (Scene::new(1e-4).with_ground(HalfSpace::new(Vec3::Y, -1.0)), ExplicitSettings::new());
                let x0: Vec<Vec3> = rest.iter().map(|&p| p * 1.01).collect();
                let v0 = vec![Vec3::new(0.1, 0.2, 0.3); n];
                let mut buffer = vec![Vec3::splat(7.0); scratch_len::explicit(n)];
                let nan = Real::NAN;
                let (scene, settings) = good;
                let ground = |g: HalfSpace<Vec3>| (scene.with_ground(g), settings);
                let dt = |dt: Real| (Scene { dt, ..scene }, settings);
                let cases: Vec<((Scene<Vec3>, ExplicitSettings), StepError)> = vec![
                    (dt(0.0), StepError::TimeStep),
                    (dt(-1e-3), StepError::TimeStep),
                    (dt(nan), StepError::TimeStep),
                    (dt(Real::INFINITY), StepError::TimeStep),
                    ((scene, settings.with_substeps(0)), StepError::Substeps),
                    // Issue 16 D7: u32::MAX substeps would run for hours.
                    ((scene, settings.with_substeps(u32::MAX)), StepError::Substeps),
                    ((scene, settings.with_substeps(ExplicitSettings::MAX_SUBSTEPS + 1)), StepError::Substeps),
                    ((scene.with_gravity(Vec3::new(0.0, nan, 0.0)), settings), StepError::Gravity),
                    ((scene, settings.with_damping(-1.0)), StepError::Damping),
                    ((scene, settings.with_damping(nan)), StepError::Damping),
                    ((scene, ExplicitSettings { max_energy_growth: 1.0, ..settings }), StepError::GrowthLimit),
                    ((scene, ExplicitSettings { max_energy_growth: nan, ..settings }), StepError::GrowthLimit),
                    (ground(HalfSpace::new(Vec3::ZERO, 0.0)), StepError::Ground),
                    (ground(HalfSpace::new(Vec3::Y, nan)), StepError::Ground),
                    (ground(HalfSpace::new(Vec3::Y, 0.0).with_restitution(1.5)), StepError::Restitution),
                    (ground(HalfSpace::new(Vec3::Y, 0.0).with_restitution(-0.1)), StepError::Restitution),
                    (ground(HalfSpace::new(Vec3::Y, 0.0).with_restitution(nan)), StepError::Restitution),
                    (ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(-0.1)), StepError::Friction),
                    (ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(nan)), StepError::Friction),
                ];
                let check = |(scene, settings): &(Scene<Vec3>, ExplicitSettings), masses: &[Real], pinned: &[bool], x: &mut Vec<Vec3>, v: &mut Vec<Vec3>, buffer: &mut Vec<Vec3>, expected: StepError| {
                    let (xb, vb, bb) = (bits(x), bits(v), bits(buffer));
                    let mut scratch = ExplicitScratch::new(buffer);
                    let error = explicit_step(&body, masses, pinned, scene, settings, x, v, &mut scratch).unwrap_err();
                    assert_eq!(error, expected);
                    assert!(!error.to_string().is_empty());
                    assert_eq!((bits(x), bits(v), bits(buffer)), (xb, vb, bb));
                };
                for (case, expected) in cases {
                    check(&case, &masses, &[], &mut x0.clone(), &mut v0.clone(), &mut buffer, expected);
                }
                // Buffers and masses.
                let mut bad_masses = masses.clone();
                // Issue 16 D8: a subnormal mass (1e-39 kg in f32) has an infinite reciprocal.
                bad_masses[3] = Real::MIN_POSITIVE / 2.0;
                check(&good, &bad_masses, &[], &mut x0.clone(), &mut v0.clone(), &mut buffer, StepError::Mass { vertex: 3 });
                bad_masses[3] = 0.0;
                check(&good, &bad_masses, &[], &mut x0.clone(), &mut v0.clone(), &mut buffer, StepError::Mass { vertex: 3 });
                bad_masses[3] = nan;
                check(&good, &bad_masses, &[], &mut x0.clone(), &mut v0.clone(), &mut buffer, StepError::Mass { vertex: 3 });
                let short = StepError::LengthMismatch { buffer: StepBuffer::Masses, expected: n, actual: n - 1 };
                check(&good, &masses[1..], &[], &mut x0.clone(), &mut v0.clone(), &mut buffer, short);
                let pins = StepError::LengthMismatch { buffer: StepBuffer::Pinned, expected: n, actual: 2 };
                check(&good, &masses, &[true, false], &mut x0.clone(), &mut v0.clone(), &mut buffer, pins);
                let mut v_short = v0[1..].to_vec();
                let vel = StepError::LengthMismatch { buffer: StepBuffer::Velocities, expected: n, actual: n - 1 };
                check(&good, &masses, &[], &mut x0.clone(), &mut v_short, &mut buffer, vel);
                let mut small = vec![Vec3::ZERO; 2 * n];
                let scr = StepError::LengthMismatch { buffer: StepBuffer::Scratch, expected: 4 * n, actual: 2 * n };
                check(&good, &masses, &[], &mut x0.clone(), &mut v0.clone(), &mut small, scr);
                let mut x_nan = x0.clone();
                x_nan[5].z = nan;
                check(&good, &masses, &[], &mut x_nan, &mut v0.clone(), &mut buffer, StepError::NonFiniteInput { vertex: 5 });
                let mut v_inf = v0.clone();
                v_inf[6].x = Real::INFINITY;
                check(&good, &masses, &[], &mut x0.clone(), &mut v_inf, &mut buffer, StepError::NonFiniteInput { vertex: 6 });
            }
        }
    };
}

step_tests!(single, softfem);
step_tests!(double, softfem::f64);

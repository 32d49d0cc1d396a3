//! Newton's method (`src/step/descent/newton/`) on the cantilever of tests/steppers/relax.rs
//! (quasi-static) and on a stiff block (implicit Euler at 1/30 s), in both precisions: residuals
//! recomputed from the force kernel, agreement with the relaxation's converged answer, pins, the
//! ground, and refused input with the state left as it was.

macro_rules! newton_tests {
    ($precision:ident, $($api:ident)::+, $tolerance:expr, $relax_tolerance:expr) => {
        mod $precision {
            use softfem::StepError;
            use $($api)::+::element::{TetHessian, TetRest};
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::{Material, NeoHookean, StVK, StableNeoHookean};
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::{
                HalfSpace, NewtonOptions, NewtonReport, NewtonScratch, NewtonSettings, RelaxScratch,
                RelaxSettings, Scene, TetElastic, newton_quasi_static, scratch_len,
                newton_step, relax_quasi_static,
            };
            use $($api)::+::types::{Mat3, Real, Vec3};

            /// The relative residual asked of Newton's method in this precision.
            const TOLERANCE: Real = $tolerance;
            /// The relaxation's reference tolerance (tests/steppers/relax.rs).
            const RELAX_TOLERANCE: Real = $relax_tolerance;
            const GRAVITY: Vec3 = Vec3::new(0.0, -9.81, 0.0);

            struct Body {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
            }

            /// A box of `cells` Kuhn-split cubes from the origin to `max`.
            fn body(cells: (usize, usize, usize), max: Vec3) -> Body {
                let (nx, ny, nz) = cells;
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, max, (nx, ny, nz), BoxSplit::Kuhn6);
                Body { rest, tets }
            }

            crate::common::scenes::newton_buffers!();

            /// `|f_elastic + m g|` over the free vertices (N), from the force kernel.
            fn imbalance<M: Material>(mesh: &TetMesh, material: &M, x: &[Vec3], masses: &[Real], pinned: &[bool]) -> f64 {
                let mut f = vec![Vec3::ZERO; x.len()];
                mesh.add_elastic_forces(material, x, &mut f).unwrap();
                f.iter()
                    .zip(masses)
                    .zip(pinned)
                    .filter(|(_, p)| !**p)
                    .map(|((f, m), _)| (*f + GRAVITY * *m).length_squared() as f64)
                    .sum::<f64>()
                    .sqrt()
            }

            /// Asserts that a reported residual (N) is the recomputed imbalance (no contact): to
            /// 1e-3 of itself, plus the rounding of element forces of about the load (64 eps of
            /// it).
            fn assert_reports_imbalance(reported: Real, recomputed: f64, load: f64) {
                let floor = 64.0 * f64::from(Real::EPSILON) * load;
                let reported = reported as f64;
                println!("reported {reported:.6e}, recomputed {recomputed:.6e}, floor {floor:.1e} (N)");
                assert!((reported - recomputed).abs() <= 1e-3 * recomputed + floor, "{reported} reported, {recomputed} recomputed");
            }

            fn weight(masses: &[Real], pinned: &[bool]) -> f64 {
                masses.iter().zip(pinned).filter(|(_, p)| !**p)
                    .map(|(m, _)| (*m as f64 * 9.81).powi(2)).sum::<f64>().sqrt()
            }

            #[test]
            fn quasi_static_cantilever_converges_in_few_iterations_to_the_relaxed_answer() {
                let bar = body((4, 1, 1), Vec3::new(0.4, 0.1, 0.1));
                let pinned: Vec<bool> = bar.rest.iter().map(|p| p.x == 0.0).collect();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let material = StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
                let model = TetElastic::new(mesh, material);
                let n = bar.rest.len();

                let scene = Scene::new(1.0).with_gravity(GRAVITY);
                let settings = NewtonSettings::new().with_tolerance(TOLERANCE, 25);
                let mut buffers = Buffers::new(n, bar.tets.len());
                let mut x = bar.rest.clone();
                let report = newton_quasi_static(&model, &masses, &pinned, &scene, &settings, &mut x, &mut buffers.scratch()).unwrap();
                let recomputed = imbalance(&mesh, &material, &x, &masses, &pinned);
                let load = weight(&masses, &pinned);
                println!("{}: Newton {report:?}; recomputed imbalance {:.2e} of the load", stringify!($precision), recomputed / load);
                assert!(report.converged && report.iterations <= 25, "{report:?}");
                assert_reports_imbalance(report.residual, recomputed, load);
                // The tolerance is honoured, or (f32) the floor it stopped at is reported.
                assert!(recomputed <= (TOLERANCE as f64 * load).max(2.0 * report.residual as f64));
                for (i, &p) in pinned.iter().enumerate() {
                    if p {
                        assert_eq!(x[i], bar.rest[i]);
                    }
                }

                // The relaxation's converged answer (tests/steppers/relax.rs settings).
                let relax_settings = RelaxSettings::new()
                    .with_tolerance(RELAX_TOLERANCE, 50_000)
                    .with_chebyshev(0.999, 2.0, 0);
                let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                let mut relaxed = bar.rest.clone();
                let relax_report = relax_quasi_static(&model, &masses, &pinned, &scene, &relax_settings, &mut relaxed, &mut RelaxScratch::new(&mut vectors, &mut scalars)).unwrap();
                assert!(relax_report.converged);
                let sag = bar.rest.iter().zip(&x).map(|(r, x)| r.y - x.y).fold(0.0, Real::max);
                let difference = x.iter().zip(&relaxed).map(|(a, b)| (*a - *b).length()).fold(0.0, Real::max);
                println!("sag {sag:.4e} m, |x_newton - x_relax| {difference:.2e} m");
                assert!(sag > 0.005 && sag < 0.1);
                // Both residuals are at most tolerance times the load; the softest mode of the
                // pinned bar (bending, stiffness ~ load / sag) turns that into a distance of
                // about tolerance * sag, with a factor 20 of margin for the mode mixing.
                assert!(difference <= 20.0 * RELAX_TOLERANCE.max(TOLERANCE) * sag, "{difference}");
            }

            /// Large deformation: a soft (E = 10 kPa) 8 x 2 x 2 cantilever 0.4 m long droops by
            /// more than its length (it hangs and stretches), through compression on its lower side (where the projection clamps) for
            /// every model; Newton's method still reaches the tolerance, and the residual it
            /// reports is the imbalance the force kernel computes.
            fn large_sag<M: Material>(material: M) {
                let bar = body((8, 2, 2), Vec3::new(0.4, 0.1, 0.1));
                let pinned: Vec<bool> = bar.rest.iter().map(|p| p.x == 0.0).collect();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let model = TetElastic::new(mesh, material);
                let n = bar.rest.len();
                let scene = Scene::new(1.0).with_gravity(GRAVITY);
                let settings = NewtonSettings::new().with_tolerance(TOLERANCE, 60).with_cg_iterations(1000);
                let mut buffers = Buffers::new(n, bar.tets.len());
                let mut x = bar.rest.clone();
                let report = newton_quasi_static(&model, &masses, &pinned, &scene, &settings, &mut x, &mut buffers.scratch()).unwrap();
                let sag = bar.rest.iter().zip(&x).map(|(r, x)| r.y - x.y).fold(0.0, Real::max);
                let recomputed = imbalance(&mesh, &material, &x, &masses, &pinned);
                let load = weight(&masses, &pinned);
                println!("{} {material:?}: sag {sag:.3} m, {report:?}", stringify!($precision));
                assert!(report.converged && report.iterations <= 60, "{report:?}");
                assert!(sag > 0.2 && sag < 1.0, "{sag}");
                assert_reports_imbalance(report.residual, recomputed, load);
            }

            #[test]
            fn large_deformation_equilibrium_for_every_model() {
                large_sag(StableNeoHookean::from_young_poisson(1.0e4, 0.3).unwrap());
                large_sag(NeoHookean::from_young_poisson(1.0e4, 0.3).unwrap());
                large_sag(StVK::from_young_poisson(1.0e4, 0.3).unwrap());
            }

            /// A stiff 2 x 1 x 1 box of 5 cm cubes (tests/steppers/stability.rs): E = 1e8 Pa, nu =
            /// 0.3, started from a perturbation of its rest shape 1 cm above the ground, falling
            /// under gravity for 1 s of 1/30 s steps: hundreds of times past the explicit stability
            /// limit, the regime where the relaxation converges on 7-43 % of its solves.
            pub(crate) fn stiff_block_run(tolerance: Real) -> (Vec<NewtonReport>, Vec<Vec3>, Vec<Vec3>, Vec<Real>) {
                let block = body((2, 1, 1), Vec3::new(0.1, 0.05, 0.05));
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &block.rest, &block.tets, 1000.0);
                let model = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e8, 0.3).unwrap());
                let n = block.rest.len();
                let mut x: Vec<Vec3> = block.rest.iter().enumerate().map(|(i, &p)| {
                    let (s, c) = ((i as Real * 1.7).sin(), (i as Real * 2.3).cos());
                    p + Vec3::new(s, c, s * c) * 5e-4 + Vec3::new(0.0, 0.01, 0.0)
                }).collect();
                let mut v = vec![Vec3::ZERO; n];
                let scene = Scene::new(1.0 / 30.0)
                    .with_gravity(GRAVITY)
                    .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5));
                let settings = NewtonSettings::new().with_tolerance(tolerance, 50);
                let mut buffers = Buffers::new(n, block.tets.len());
                let reports = (0..30)
                    .map(|_| newton_step(&model, &masses, &[], &scene, &settings, &mut x, &mut v, &mut buffers.scratch()).unwrap())
                    .collect();
                (reports, x, v, masses)
            }

            #[test]
            fn implicit_euler_on_a_stiff_block_converges_on_every_step() {
                let (reports, x, v, masses) = stiff_block_run(1e-4);
                let at_floor = reports.iter().filter(|r| r.residual > r.target).count();
                let unconverged = reports.iter().filter(|r| !r.converged).count();
                let newton: u32 = reports.iter().map(|r| r.iterations).sum();
                let cg: u32 = reports.iter().map(|r| r.details.cg_iterations).sum();
                println!(
                    "{}: {} steps, {newton} Newton and {cg} CG iterations, {at_floor} stopped at the rounding floor, {unconverged} of them with the floor above the initial residual; last {:?}",
                    stringify!($precision), reports.len(), reports.last().unwrap()
                );
                for (step, report) in reports.iter().enumerate() {
                    // A floor-limited solve must be within FLOOR_FACTOR of a measured floor.
                    if report.residual > report.target {
                        assert!(report.stagnated && report.rounding_floor > 0.0, "step {step}: {report:?}");
                        assert!(report.residual <= NewtonReport::FLOOR_FACTOR * report.rounding_floor, "step {step}: {report:?}");
                    }
                    // Converged, or (f32, the block resting on the ground) started within its
                    // rounding floor, where the residual cannot tell the answer (issue #44):
                    // stagnated, not converged. `stiff_block_in_f32_ends_where_f64_ends`
                    // checks that those answers are answers.
                    let floor_above_start = report.rounding_floor >= report.initial_residual;
                    assert!(report.converged || (report.stagnated && floor_above_start), "step {step}: {report:?}");
                }
                // Settled on the ground after 1 s: no vertex below it beyond rounding, at rest.
                assert!(x.iter().all(|p| p.y >= -1e-6), "{x:?}");
                let speed = v.iter().map(|v| v.length()).fold(0.0, Real::max);
                assert!(speed < 1e-2, "{speed}");
                // Resting: the bottom carries the weight (the lowest vertices touch the ground).
                let lowest = x.iter().map(|p| p.y).fold(Real::INFINITY, Real::min);
                assert!(lowest.abs() < 1e-4, "{lowest}");
                assert!(masses.iter().all(|m| *m > 0.0));
            }

            #[test]
            fn pins_hold_and_bad_input_is_refused_with_the_state_untouched() {
                let bar = body((2, 1, 1), Vec3::new(0.2, 0.1, 0.1));
                let pinned: Vec<bool> = bar.rest.iter().map(|p| p.x == 0.0).collect();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                let model = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = bar.rest.len();
                let scene = Scene::new(1.0 / 60.0).with_gravity(GRAVITY);
                let settings = NewtonSettings::new().with_tolerance(TOLERANCE.max(1e-6), 20);
                let mut buffers = Buffers::new(n, bar.tets.len());

                // Pins: a few steps, pinned vertices keep position and velocity exactly.
                let (mut x, mut v) = (bar.rest.clone(), vec![Vec3::ZERO; n]);
                for i in 0..n {
                    if pinned[i] {
                        v[i] = Vec3::new(0.5, 0.0, 0.0); // ignored: pinned means fixed
                    }
                }
                let v0 = v.clone();
                for _ in 0..5 {
                    let report = newton_step(&model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut buffers.scratch()).unwrap();
                    assert!(report.converged, "{report:?}");
                }
                for i in 0..n {
                    if pinned[i] {
                        assert_eq!(x[i], bar.rest[i]);
                        assert_eq!(v[i], v0[i]);
                    } else {
                        assert!(x[i].y < bar.rest[i].y || bar.rest[i].x == 0.0);
                    }
                }

                // Refused input: nothing touched.
                let bits = |a: &[Vec3]| a.iter().map(|p| p.to_array().map(|c| f64::from(c).to_bits())).collect::<Vec<_>>();
                let (x0, v0) = (bits(&x), bits(&v));
                let mut bad = x.clone();
                bad[4].z = Real::NAN;
                assert_eq!(
                    newton_step(&model, &masses, &pinned, &scene, &settings, &mut bad, &mut v, &mut buffers.scratch()),
                    Err(StepError::NonFiniteInput { vertex: 4 })
                );
                let mut short = Buffers::new(n - 1, bar.tets.len());
                assert!(matches!(
                    newton_step(&model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut short.scratch()),
                    Err(StepError::LengthMismatch { .. })
                ));
                let mut few = Buffers::new(n, bar.tets.len() - 1);
                assert!(matches!(
                    newton_step(&model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut few.scratch()),
                    Err(StepError::LengthMismatch { .. })
                ));
                for broken in [
                    NewtonSettings { tolerance: 1.0, ..settings },
                    NewtonSettings { armijo: 0.0, ..settings },
                    NewtonSettings { backtrack: 1.0, ..settings },
                    NewtonSettings { options: NewtonOptions { max_cg_iterations: 0, ..settings.options }, ..settings },
                ] {
                    assert_eq!(
                        newton_step(&model, &masses, &pinned, &scene, &broken, &mut x, &mut v, &mut buffers.scratch()),
                        Err(StepError::NewtonSettings)
                    );
                }
                assert_eq!(
                    newton_step(&model, &masses, &pinned, &Scene { dt: 0.0, ..scene }, &settings, &mut x, &mut v, &mut buffers.scratch()),
                    Err(StepError::TimeStep)
                );
                assert_eq!(
                    newton_step(&model, &masses, &pinned, &scene.with_ground(HalfSpace::new(Vec3::ZERO, 0.0)), &settings, &mut x, &mut v, &mut buffers.scratch()),
                    Err(StepError::Ground)
                );
                assert_eq!((bits(&x), bits(&v)), (x0, v0));

                // A failure after the start (Phi not finite anywhere: a neo-Hookean element
                // flattened to J = 0 at x_n and at y) restores the state bit for bit.
                let barrier = TetElastic::new(mesh, NeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let mut flat = x.clone();
                let corners = bar.tets[0].map(|c| c as usize);
                flat[corners[3]] = flat[corners[0]];
                let moving: Vec<bool> = vec![false; n];
                let still = vec![Vec3::ZERO; n];
                let (mut xf, mut vf) = (flat.clone(), still.clone());
                let result = newton_step(&barrier, &masses, &moving, &Scene::new(1.0 / 60.0), &NewtonSettings::new(), &mut xf, &mut vf, &mut buffers.scratch());
                assert!(matches!(result, Err(StepError::NonFiniteState { .. })), "{result:?}");
                assert_eq!((bits(&xf), bits(&vf)), (bits(&flat), bits(&still)));
            }

            /// Wall time of Newton against the relaxation on the quasi-static cantilever to 1e-6
            /// (measurement for the closing report, no assertion on time):
            /// `cargo test --release --test steppers newton:: -- --ignored --nocapture`.
            #[test]
            #[ignore]
            fn wall_time_against_the_relaxation() {
                for cells in [(4usize, 1usize, 1usize), (8, 2, 2), (12, 3, 3)] {
                    let bar = body(cells, Vec3::new(0.4, 0.1, 0.1));
                    let pinned: Vec<bool> = bar.rest.iter().map(|p| p.x == 0.0).collect();
                    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &bar.rest, &bar.tets, 1000.0);
                    let material = StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
                    let model = TetElastic::new(mesh, material);
                    let n = bar.rest.len();
                    let tolerance = 1e-6;
                    let mut buffers = Buffers::new(n, bar.tets.len());
                    let scene = Scene::new(1.0).with_gravity(GRAVITY);
                    let settings = NewtonSettings::new().with_tolerance(tolerance, 50);
                    // The fastest of several runs: the machine is shared, and the minimum is the
                    // run least disturbed.
                    let mut newton_time = f64::INFINITY;
                    let mut newton = None;
                    for _ in 0..7 {
                        let mut x = bar.rest.clone();
                        let clock = std::time::Instant::now();
                        let report = newton_quasi_static(&model, &masses, &pinned, &scene, &settings, &mut x, &mut buffers.scratch()).unwrap();
                        newton_time = newton_time.min(clock.elapsed().as_secs_f64());
                        newton = Some(report);
                    }
                    let newton = newton.unwrap();
                    // f32 cannot reach 1e-6 by relaxation (its floor is about 1e-3): a capped budget.
                    let budget = if core::mem::size_of::<Real>() == 4 { 100_000 } else { 2_000_000 };
                    let relax_settings = RelaxSettings::new()
                        .with_tolerance(tolerance, budget)
                        .with_chebyshev(0.999, 2.0, 0);
                    let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                    let mut relax_time = f64::INFINITY;
                    let mut relax = None;
                    for _ in 0..3 {
                        let mut y = bar.rest.clone();
                        let clock = std::time::Instant::now();
                        let report = relax_quasi_static(&model, &masses, &pinned, &scene, &relax_settings, &mut y, &mut RelaxScratch::new(&mut vectors, &mut scalars)).unwrap();
                        relax_time = relax_time.min(clock.elapsed().as_secs_f64());
                        relax = Some(report);
                    }
                    let relax = relax.unwrap();
                    println!(
                        "{} {cells:?}, {} tets, tolerance {tolerance:e}: Newton {} iterations ({} CG) {:.4} s, converged {}, residual {:.2e}; \
                         relax {} iterations {:.4} s, converged {}; ratio {:.1}x",
                        stringify!($precision), bar.tets.len(), newton.iterations, newton.details.cg_iterations, newton_time,
                        newton.converged, newton.residual, relax.iterations, relax_time, relax.converged, relax_time / newton_time
                    );
                }
            }
        }
    };
}

newton_tests!(single, softfem, 1e-4, 3e-3);
newton_tests!(double, softfem::f64, 1e-8, 1e-7);

/// The f32 run of the stiff block, many of whose steps stop at the rounding floor, ends where
/// the f64 run at the same tolerance (every step at its target) ends, closer than the tolerance
/// itself moves the end state: the floor-limited answers are answers.
#[test]
fn stiff_block_in_f32_ends_where_f64_ends() {
    let (_, x32, _, _) = single::stiff_block_run(1e-4);
    let (_, x64, _, _) = double::stiff_block_run(1e-4);
    let (_, tight, _, _) = double::stiff_block_run(1e-10);
    let distance = |a: &[softfem::glam::DVec3], b: &[softfem::glam::DVec3]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max)
    };
    let x32: Vec<_> = x32.iter().map(|p| p.as_dvec3()).collect();
    let precision = distance(&x32, &x64);
    let tolerance = distance(&x64, &tight);
    println!(
        "stiff block after 1 s: |x_f32 - x_f64| = {precision:.2e} m at tolerance 1e-4, which moves the f64 end state by {tolerance:.2e} m against 1e-10"
    );
    // The landing with friction amplifies every difference (the tolerance's: 2e-3 m); f32's
    // rounding-floor stops add less than a tenth of that.
    assert!(
        precision < 0.1 * tolerance,
        "{precision} against {tolerance}"
    );
    assert!(precision < 1e-4, "{precision}");
}

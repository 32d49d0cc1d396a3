//! The highest-frequency estimate (`src/step/explicit/frequency.rs`) against the exact largest
//! eigenvalue of `M^-1 K` of small meshes, `K` assembled densely by central differences of the
//! f64 force kernel and diagonalised by nalgebra; and against the proven bound of
//! `stable_time_step`, whose step it must never undercut.

use nalgebra::{DMatrix, SymmetricEigen};

/// `omega_max^2` (1/s^2) of the f64 body `rest`, `tets` (stable neo-Hookean, E = 1e5 Pa,
/// nu = 0.3, 1000 kg/m^3) with the vertices flagged in `pinned` removed: the largest eigenvalue
/// of `M^-1/2 K M^-1/2`, `K = -df/dx` by central differences (step 1e-7 m; the forces are
/// smooth, the error O(1e-14) relative).
fn exact_omega_squared(
    rest: &[softfem::f64::types::Vec3],
    tets: &[[u32; 4]],
    pinned: &[bool],
) -> f64 {
    use softfem::f64 as d;
    let mut rest_data = vec![d::element::TetRest::default(); tets.len()];
    let mesh = d::mesh::TetMesh::new(rest, tets, &mut rest_data).unwrap();
    let material = d::material::StableNeoHookean::from_young_poisson(1.0e5, 0.3).unwrap();
    let mut masses = vec![0.0; rest.len()];
    mesh.lumped_masses(1000.0, &mut masses).unwrap();
    let free: Vec<usize> = (0..rest.len()).filter(|&i| !pinned[i]).collect();
    let dofs: Vec<(usize, usize)> = free
        .iter()
        .flat_map(|&i| (0..3).map(move |a| (i, a)))
        .collect();
    let delta = 1e-7;
    let mut k = DMatrix::zeros(dofs.len(), dofs.len());
    for (col, &(i, a)) in dofs.iter().enumerate() {
        let force = |sign: f64| {
            let mut x = rest.to_vec();
            x[i][a] += sign * delta;
            let mut f = vec![d::types::Vec3::ZERO; rest.len()];
            mesh.add_elastic_forces(&material, &x, &mut f).unwrap();
            f
        };
        let (plus, minus) = (force(1.0), force(-1.0));
        for (row, &(j, b)) in dofs.iter().enumerate() {
            k[(row, col)] = -(plus[j][b] - minus[j][b]) / (2.0 * delta);
        }
    }
    let scaled = DMatrix::from_fn(dofs.len(), dofs.len(), |r, c| {
        let symmetric = 0.5 * (k[(r, c)] + k[(c, r)]);
        symmetric / (masses[dofs[r].0] * masses[dofs[c].0]).sqrt()
    });
    SymmetricEigen::new(scaled)
        .eigenvalues
        .iter()
        .copied()
        .fold(f64::MIN, f64::max)
}

macro_rules! frequency_tests {
    ($precision:ident, $($api:ident)::+, $tolerance:expr, $accuracy:expr) => {
        mod $precision {
            use super::exact_omega_squared;
            use $($api)::+::element::{TetHessian, TetRest};
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::{Material, StVK, StableNeoHookean};
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::explicit::{
                FrequencyEstimate, estimate_max_frequency,
            };
            use $($api)::+::step::{
                ElasticHessian, ExplicitScratch, ExplicitSettings, Scene, TetElastic, explicit_step, scratch_len,
                stable_time_step,
            };
            use softfem::StepError;
            use $($api)::+::types::{Real, Vec3};

            /// A Kuhn box of `cells` with cell edge 0.05 m.
            fn block(cells: (usize, usize, usize)) -> (Vec<Vec3>, Vec<[u32; 4]>) {
                let (nx, ny, nz) = cells;
                let max = Vec3::new(nx as Real, ny as Real, nz as Real) * 0.05;
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, max, (nx, ny, nz), BoxSplit::Kuhn6);
                (rest, tets)
            }

            fn check(cells: (usize, usize, usize), pin_left_face: bool) {
                let (rest, tets) = block(cells);
                let pinned: Vec<bool> = rest.iter().map(|x| pin_left_face && x.x == 0.0).collect();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.3).unwrap());
                let mut hessians = vec![TetHessian::default(); tets.len()];
                let mut vectors = vec![Vec3::ZERO; scratch_len::frequency(rest.len())];
                let estimate = estimate_max_frequency(&body, &masses, &pinned, &rest, (20_000, $tolerance), &mut hessians, &mut vectors).unwrap();
                let rest64: Vec<softfem::f64::types::Vec3> = rest.iter().map(|x| softfem::f64::types::Vec3::new(x.x as f64, x.y as f64, x.z as f64)).collect();
                let exact = exact_omega_squared(&rest64, &tets, &pinned);
                let estimated = (estimate.omega_max as f64).powi(2);
                let error = (estimated - exact) / exact;
                // The Rayleigh quotient approaches the largest eigenvalue from below (up to
                // this precision's rounding of the products).
                assert!(error.abs() < $accuracy && error < 4.0 * Real::EPSILON as f64, "{cells:?}: {estimated:e} against {exact:e} ({error:e}, {estimate:?})");
                // The proven bound is a bound: its step never exceeds the true limit, and the
                // estimate's (without margin) never falls below it.
                let proven = stable_time_step(&body, &masses, &pinned, &mut vec![0.0; rest.len()]).unwrap() as f64;
                let limit = 2.0 / exact.sqrt();
                assert!(proven <= limit * (1.0 + 1e-6), "{proven:e} against the limit {limit:e}");
                assert!(estimate.time_step_with_margin(1.0) as f64 >= proven, "{estimate:?} against {proven:e}");
                assert_eq!(estimate.time_step(), estimate.time_step_with_margin(FrequencyEstimate::MARGIN));
                println!("{cells:?} pinned {pin_left_face}: proven step {proven:e} s = {:.3} of the limit {limit:e} s; estimate {:e} s after {} iterations", proven / limit, 2.0 / estimate.omega_max, estimate.iterations);
            }

            #[test]
            fn the_estimate_matches_the_largest_eigenvalue_of_a_free_cube() {
                check((1, 1, 1), false);
            }

            #[test]
            fn the_estimate_matches_the_largest_eigenvalue_of_a_pinned_bar() {
                check((3, 2, 2), true);
            }

            /// `estimate_max_frequency` of `body` at `positions` with `(max_iterations, tolerance)`.
            fn estimate<M: Material>(body: &TetElastic<'_, M>, masses: &[Real], positions: &[Vec3], limits: (u32, Real)) -> FrequencyEstimate {
                let mut hessians = vec![TetHessian::default(); body.element_count()];
                let mut vectors = vec![Vec3::ZERO; scratch_len::frequency(positions.len())];
                estimate_max_frequency(body, masses, &[], positions, limits, &mut hessians, &mut vectors).unwrap()
            }

            /// Steps `body` (free, no gravity, no damping) from rest at `start` with `dt`, one
            /// substep a call, `steps` calls: the first call that failed and its error.
            fn first_failure<M: Material>(body: &TetElastic<'_, M>, masses: &[Real], start: &[Vec3], dt: Real, steps: usize) -> Option<(usize, StepError)> {
                let n = start.len();
                let (scene, settings) = (Scene::new(dt), ExplicitSettings::new());
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                let (mut x, mut v) = (start.to_vec(), vec![Vec3::ZERO; n]);
                (0..steps).find_map(|call| explicit_step(body, masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).err().map(|e| (call, e)))
            }

            /// `rest` with every coordinate moved by a uniform draw in `[-amplitude, amplitude]`
            /// (m) of a xorshift64* generator seeded with `seed`.
            fn perturbed(rest: &[Vec3], amplitude: Real, seed: u64) -> Vec<Vec3> {
                let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
                let mut draw = || {
                    state ^= state >> 12;
                    state ^= state << 25;
                    state ^= state >> 27;
                    let bits = state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40;
                    (bits as Real / (1u64 << 24) as Real * 2.0 - 1.0) * amplitude
                };
                rest.iter().map(|&x| x + Vec3::new(draw(), draw(), draw())).collect()
            }

            /// What `FrequencyEstimate::MARGIN` covers (issue #44): a free 3x3x3 Kuhn box (edge
            /// 0.05 m, E = 1e5 Pa, nu = 0.3, 1000 kg/m^3), StVK and stable neo-Hookean, its rest
            /// positions moved by a seeded uniform 1 % of the edge per coordinate, released from
            /// there with no velocity, gravity or damping and stepped 200 times at margins 0.9 to
            /// 0.5 of the limit `2 / omega_max` estimated at rest and at the perturbed state.
            /// Prints the power iteration's shortfall (the doc example's `(200, 1e-6)` against a
            /// converged estimate), the perturbed state's `omega_max` over the rest one, and the
            /// seeds that blew up at each margin. Run with
            /// `cargo test --release --all-features --test steppers -- frequency:: --ignored --nocapture`.
            #[test]
            #[ignore = "a measurement; run in release with --ignored --nocapture"]
            fn margin_report() {
                const MARGINS: [Real; 5] = [0.9, 0.8, 0.7, 0.6, 0.5];
                const SEEDS: u64 = 16;
                let edge: Real = 0.05;
                let (rest, tets) = block((3, 3, 3));
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                let stvk = TetElastic::new(mesh, StVK::from_young_poisson(1.0e5, 0.3).unwrap());
                let snh = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.3).unwrap());
                fn report<M: Material>(name: &str, body: &TetElastic<'_, M>, masses: &[Real], rest: &[Vec3], edge: Real) {
                    let converged = (20_000, $tolerance);
                    let at_rest = estimate(body, masses, rest, converged);
                    let loose = estimate(body, masses, rest, (200, 1e-6));
                    println!("{name}: omega_max at rest {:.6e} rad/s ({} iterations); (200, 1e-6) gives {:.6} of it ({} iterations)", at_rest.omega_max, at_rest.iterations, loose.omega_max / at_rest.omega_max, loose.iterations);
                    let mut ratios = Vec::new();
                    let mut blown = [[0usize; MARGINS.len()]; 2];
                    for seed in 0..SEEDS {
                        let start = perturbed(rest, 0.01 * edge, seed);
                        let here = estimate(body, masses, &start, converged);
                        ratios.push(here.omega_max / at_rest.omega_max);
                        let mut line = format!("  seed {seed:2}: omega_max perturbed / rest {:.4};", here.omega_max / at_rest.omega_max);
                        for (which, basis) in [at_rest, here].iter().enumerate() {
                            line += if which == 0 { " rest estimate" } else { " | perturbed estimate" };
                            for (k, &margin) in MARGINS.iter().enumerate() {
                                match first_failure(body, masses, &start, basis.time_step_with_margin(margin), 200) {
                                    None => line += &format!(" {margin}:ok"),
                                    Some((call, error)) => {
                                        assert_eq!(error, StepError::EnergyBlowUp, "{name} seed {seed} margin {margin}");
                                        blown[which][k] += 1;
                                        line += &format!(" {margin}:blew@{call}");
                                    }
                                }
                            }
                        }
                        println!("{line}");
                    }
                    let (low, high) = ratios.iter().fold((Real::INFINITY, 0.0 as Real), |(l, h), &r| (l.min(r), h.max(r)));
                    println!("{name}: perturbed / rest omega_max in [{low:.4}, {high:.4}]");
                    for (which, label) in ["rest", "perturbed"].iter().enumerate() {
                        let counts: Vec<String> = MARGINS.iter().zip(blown[which]).map(|(m, b)| format!("{m}: {b}/{SEEDS}")).collect();
                        println!("{name}, {label} estimate: blow-ups within 200 steps at margin {}", counts.join(", "));
                    }
                }
                report("StVK", &stvk, &masses, &rest, edge);
                report("stable neo-Hookean", &snh, &masses, &rest, edge);
            }
        }
    };
}

frequency_tests!(single, softfem, 1e-7, 1e-3);
frequency_tests!(double, softfem::f64, 1e-13, 1e-6);

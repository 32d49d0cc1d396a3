//! The explicit stability bound against the true critical step, in both precisions: the true
//! limit `2 / omega_max` comes from the eigenvalues of `M^-1 K` (K assembled by central
//! differences of the force kernel, eigenvalues by nalgebra in f64). The bound must never exceed
//! it; explicit stepping at 0.9x the bound stays bounded for 1e4 steps on a stiff box; at 3x the
//! true limit the stepper reports the blow-up and leaves the state bit for bit as it was.

use nalgebra::{DMatrix, SymmetricEigen};

/// The eigenvalues (ascending, 1/s^2) of `M^-1/2 K M^-1/2` for a stiffness matrix given as
/// dense rows in f64 and lumped masses.
fn frequencies_squared(k: &DMatrix<f64>, masses: &[f64]) -> Vec<f64> {
    let n = k.nrows();
    let scaled = DMatrix::from_fn(n, n, |i, j| {
        let (a, b) = (k[(i, j)], k[(j, i)]);
        0.5 * (a + b) / (masses[i / 3] * masses[j / 3]).sqrt()
    });
    let mut values: Vec<f64> = SymmetricEigen::new(scaled)
        .eigenvalues
        .iter()
        .copied()
        .collect();
    values.sort_by(f64::total_cmp);
    values
}

macro_rules! stability_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use super::frequencies_squared;
            use nalgebra::DMatrix;
            use $($api)::+::element::TetRest;
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::StVK;
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::{
                ElasticModel, ExplicitScratch, ExplicitSettings, TetElastic,
                element_stable_time_step, explicit_scratch_len, stable_time_step, step_explicit,
            };
            use $($api)::+::types::{Real, Vec3};
            use softfem::StepError;

            /// A stiff 2 x 1 x 1 box of 5 cm cubes: E = 1e8 Pa, nu = 0.3, rho = 1000 kg/m^3.
            struct Box_ {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
            }

            fn stiff_box() -> Box_ {
                let (nv, nt) = box_counts(2, 1, 1, BoxSplit::Kuhn6).unwrap();
                let mut rest = vec![Vec3::ZERO; nv];
                let mut tets = vec![[0; 4]; nt];
                let max = Vec3::new(0.1, 0.05, 0.05);
                fill_box(Vec3::ZERO, max, 2, 1, 1, BoxSplit::Kuhn6, &mut rest, &mut tets).unwrap();
                Box_ { rest, tets }
            }

            const DENSITY: Real = 1000.0;

            /// The true critical step `2 / omega_max` of `body` about its rest shape.
            fn true_limit(body: &impl ElasticModel<Vector = Vec3>, rest: &[Vec3], masses: &[Real]) -> f64 {
                let n = rest.len();
                let step = 1e-4 * 0.05;
                let mut k = DMatrix::<f64>::zeros(3 * n, 3 * n);
                for col in 0..3 * n {
                    let mut forces = [vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]];
                    for (sign, f) in [1.0, -1.0].into_iter().zip(forces.iter_mut()) {
                        let mut x = rest.to_vec();
                        x[col / 3][col % 3] += sign * step;
                        body.add_forces(&x, f).unwrap();
                    }
                    for row in 0..3 * n {
                        let df = forces[0][row / 3][row % 3] - forces[1][row / 3][row % 3];
                        k[(row, col)] = -(df as f64) / (2.0 * step as f64);
                    }
                }
                let masses: Vec<f64> = masses.iter().map(|&m| m as f64).collect();
                let omega_max = frequencies_squared(&k, &masses).last().unwrap().sqrt();
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
                let mut rest_data = vec![TetRest::default(); mesh_data.tets.len()];
                let mesh = TetMesh::new(&mesh_data.rest, &mesh_data.tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e8, 0.3).unwrap());
                let n = mesh.vertex_count();
                let mut masses = vec![0.0; n];
                mesh.lumped_masses(DENSITY, &mut masses).unwrap();
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
                let mut rest_data = vec![TetRest::default(); mesh_data.tets.len()];
                let mesh = TetMesh::new(&mesh_data.rest, &mesh_data.tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e8, 0.3).unwrap());
                let n = mesh.vertex_count();
                let mut masses = vec![0.0; n];
                mesh.lumped_masses(DENSITY, &mut masses).unwrap();
                let mut stiffness = vec![0.0; n];
                let dt = 0.9 * stable_time_step(&body, &masses, &[], &mut stiffness).unwrap();
                let settings = ExplicitSettings::new(dt);
                let amplitude = 1e-3;
                let mut x = perturbed(&mesh_data.rest, amplitude);
                let mut v = vec![Vec3::ZERO; n];
                let mut buffer = vec![Vec3::ZERO; explicit_scratch_len(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                let mut largest: Real = 0.0;
                for _ in 0..10_000 {
                    step_explicit(&body, &masses, &[], &settings, &mut x, &mut v, &mut scratch).unwrap();
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
                let mut rest_data = vec![TetRest::default(); mesh_data.tets.len()];
                let mesh = TetMesh::new(&mesh_data.rest, &mesh_data.tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e8, 0.3).unwrap());
                let n = mesh.vertex_count();
                let mut masses = vec![0.0; n];
                mesh.lumped_masses(DENSITY, &mut masses).unwrap();
                let limit = true_limit(&body, &mesh_data.rest, &masses);
                let settings = ExplicitSettings::new((3.0 * limit) as Real);
                let mut x = perturbed(&mesh_data.rest, 1e-4);
                let mut v = vec![Vec3::ZERO; n];
                let mut buffer = vec![Vec3::ZERO; explicit_scratch_len(n)];
                let mut scratch = ExplicitScratch::new(&mut buffer);
                for step in 0..200 {
                    let (x_before, v_before) = (x.clone(), v.clone());
                    match step_explicit(&body, &masses, &[], &settings, &mut x, &mut v, &mut scratch) {
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
        }
    };
}

stability_tests!(single, softfem);
stability_tests!(double, softfem::f64);

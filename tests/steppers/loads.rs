//! External forces and per-axis constraints (`src/step/loads.rs`) in every solver, both
//! precisions, against independent references: the linear stiffness of one tetrahedron from
//! central differences of the force kernel, the patch-test solution of a block in uniaxial
//! tension (homogeneous strain, which linear tetrahedra reproduce exactly), rigid translation
//! under a uniform load, and gravity written as a force buffer.

macro_rules! load_tests {
    ($precision:ident, $($api:ident)::+, $tolerances:expr, $beam_tolerances:expr, $beam_accuracy:expr, $strain:expr, $beam_strain:expr, $accuracy:expr) => {
        mod $precision {
            use softfem::StepError;
            use softfem::error::StepBuffer;
            use $($api)::+::element::{TetHessian, TetRest};
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::StVK;
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::{
                ExplicitScratch, ExplicitSettings, FIXED_X, FIXED_Y, FIXED_Z, NewtonScratch,
                NewtonSettings, RelaxScratch, RelaxSettings, Scene, TetElastic, VbdScratch,
                VbdSettings, scratch_len, explicit_step,
                newton_quasi_static, relax_quasi_static, vbd_quasi_static,
            };
            use $($api)::+::types::{Mat3, Real, Vec3};

            const YOUNG: Real = 1.0e5;
            const POISSON: Real = 0.3;
            /// The strain the loads below produce: small, so that the linear references hold to
            /// `O(strain)` relative, and large enough to stand above this precision's rounding.
            const STRAIN: f64 = $strain;
            /// The cantilever's tip deflection over its length: larger in f32, whose rounding
            /// floor (the residual of positions known to half an ulp) would otherwise be a tenth
            /// of the small load. Every solver solves the same nonlinear problem, so their
            /// agreement does not depend on it.
            const BEAM_STRAIN: f64 = $beam_strain;
            /// Relative agreement asked of a displacement: a few times the strain (the
            /// neglected nonlinear terms) plus the solver tolerance.
            const ACCURACY: f64 = $accuracy;

            /// The relative residuals asked of Newton, the relaxation and VBD.
            const TOLERANCES: [Real; 3] = $tolerances;
            /// The same for the cantilever, whose f32 rounding floor is higher (a long, thin
            /// body: larger positions against smaller forces).
            const BEAM_TOLERANCES: [Real; 3] = $beam_tolerances;
            /// The relative agreement of the tip deflections with Newton's: in f32 the
            /// relaxation stops at its rounding floor (a relative residual of about 1e-2 here)
            /// and is within 2 % of Newton's deflection.
            const BEAM_ACCURACY: [f64; 3] = $beam_accuracy;

            /// Which solver.
            #[derive(Clone, Copy, Debug)]
            enum Solver {
                Newton,
                Relax,
                Vbd,
            }
            const SOLVERS: [Solver; 3] = [Solver::Newton, Solver::Relax, Solver::Vbd];

            /// Quasi-static equilibrium by `solver` with gravity `gravity`, external forces
            /// `forces` and fixed axes `fixed` (either may be empty), from the rest positions.
            fn solve(
                solver: Solver,
                (rest, tets): (&[Vec3], &[[u32; 4]]),
                pinned: &[bool],
                (gravity, forces, fixed): (Vec3, &[Vec3], &[u8]),
                tolerances: [Real; 3],
            ) -> Vec<Vec3> {
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; rest, tets, 1000.0);
                let body = TetElastic::new(mesh, StVK::from_young_poisson(YOUNG, POISSON).unwrap());
                let (n, t) = (rest.len(), tets.len());
                let mut x = rest.to_vec();
                let scene = Scene::new(1.0)
                    .with_gravity(gravity)
                    .with_external_forces(forces)
                    .with_fixed_axes(fixed);
                match solver {
                    Solver::Newton => {
                        let len = scratch_len::newton(n, t);
                        let (mut v, mut b, mut h) = (
                            vec![Vec3::ZERO; len.vectors],
                            vec![Mat3::ZERO; len.blocks],
                            vec![TetHessian::default(); len.hessians],
                        );
                        let settings = NewtonSettings::new().with_tolerance(tolerances[0], 50);
                        let mut scratch = NewtonScratch::new(&mut v, &mut b, &mut h);
                        let report = newton_quasi_static(&body, &masses, pinned, &scene, &settings, &mut x, &mut scratch).unwrap();
                        assert!(report.converged, "{report:?}");
                    }
                    Solver::Relax => {
                        let (mut v, mut s) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                        let settings = RelaxSettings::new()
                            .with_tolerance(tolerances[1], 400_000)
                            .with_chebyshev(0.999, 2.0, 0);
                        let mut scratch = RelaxScratch::new(&mut v, &mut s);
                        let report = relax_quasi_static(&body, &masses, pinned, &scene, &settings, &mut x, &mut scratch).unwrap();
                        assert!(report.converged, "{report:?}");
                    }
                    Solver::Vbd => {
                        let (mut v, mut i) = (vec![Vec3::ZERO; scratch_len::vbd(n)], vec![0; scratch_len::vbd_indices(n, t)]);
                        let settings = VbdSettings::new().with_tolerance(tolerances[2], 100_000);
                        let mut scratch = VbdScratch::new(&mut v, &mut i);
                        let report = vbd_quasi_static(&body, &masses, pinned, &scene, &settings, &mut x, &mut scratch).unwrap();
                        assert!(report.converged, "{report:?}");
                    }
                }
                x
            }

            /// The corner tetrahedron of edge 0.1 m.
            fn tetrahedron() -> (Vec<Vec3>, Vec<[u32; 4]>) {
                let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z].map(|x| x * 0.1);
                (rest.to_vec(), vec![[0, 1, 2, 3]])
            }

            /// The 3x3 stiffness block of vertex 3 of [`tetrahedron`] at rest, by central
            /// differences of the f64 force kernel (exact for the quadratic-in-`u` part up to
            /// `O(delta^2)`): `K e_j = -(f(+delta e_j) - f(-delta e_j)) / (2 delta)`.
            fn tip_stiffness() -> [[f64; 3]; 3] {
                use softfem::f64 as d;
                let rest = [d::types::Vec3::ZERO, d::types::Vec3::X, d::types::Vec3::Y, d::types::Vec3::Z].map(|x| x * 0.1);
                let tets = [[0, 1, 2, 3]];
                let mut rest_data = [d::element::TetRest::default()];
                let mesh = d::mesh::TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let material = d::material::StVK::from_young_poisson(YOUNG as f64, POISSON as f64).unwrap();
                let delta = 1e-7;
                let mut k = [[0.0; 3]; 3];
                for j in 0..3 {
                    let force = |sign: f64| {
                        let mut x = rest;
                        x[3][j] += sign * delta;
                        let mut f = [d::types::Vec3::ZERO; 4];
                        mesh.add_elastic_forces(&material, &x, &mut f).unwrap();
                        f[3]
                    };
                    let column = (force(1.0) - force(-1.0)) * (-0.5 / delta);
                    for (i, row) in k.iter_mut().enumerate() {
                        row[j] = column[i];
                    }
                }
                k
            }

            fn solve3(k: [[f64; 3]; 3], f: [f64; 3]) -> [f64; 3] {
                let m = nalgebra::Matrix3::from_fn(|i, j| k[i][j]);
                let u = m.lu().solve(&nalgebra::Vector3::from(f)).unwrap();
                [u[0], u[1], u[2]]
            }

            fn relative(a: Vec3, b: Vec3, scale: f64) -> f64 {
                ((a - b).length() as f64) / scale
            }

            #[test]
            fn one_tetrahedron_under_a_tip_load_moves_by_the_inverse_stiffness() {
                let (rest, tets) = tetrahedron();
                let pinned = [true, true, true, false];
                let k = tip_stiffness();
                // A load whose displacement is STRAIN times the edge.
                let direction = [0.3, -0.5, 0.8];
                let unit = solve3(k, direction);
                let magnitude = STRAIN * 0.1 / unit.iter().map(|u| u * u).sum::<f64>().sqrt();
                let f = direction.map(|d| d * magnitude);
                let u = solve3(k, f);
                let expected = Vec3::new(u[0] as Real, u[1] as Real, u[2] as Real);
                let forces = [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::new(f[0] as Real, f[1] as Real, f[2] as Real)];
                for solver in SOLVERS {
                    let x = solve(solver, (&rest, &tets), &pinned, (Vec3::ZERO, &forces, &[]), TOLERANCES);
                    let moved = x[3] - rest[3];
                    let error = relative(moved, expected, expected.length() as f64);
                    assert!(error < ACCURACY, "{solver:?}: {moved} against {expected}, {error:e}");
                    assert_eq!(&x[..3], &rest[..3], "{solver:?}: pins moved");
                }
            }

            /// A box of Kuhn-split cubes from the origin to `max`.
            fn block(cells: (usize, usize, usize), max: Vec3) -> (Vec<Vec3>, Vec<[u32; 4]>) {
                let (nx, ny, nz) = cells;
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, max, (nx, ny, nz), BoxSplit::Kuhn6);
                (rest, tets)
            }

            /// The lumped masses of `rest`, `tets` at 1000 kg/m^3.
            fn masses(rest: &[Vec3], tets: &[[u32; 4]]) -> Vec<Real> {
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, m; rest, tets, 1000.0);
                m
            }

            #[test]
            fn gravity_as_a_force_buffer_gives_the_gravity_solution() {
                let (rest, tets) = block((4, 1, 1), Vec3::new(0.4, 0.1, 0.1));
                let pinned: Vec<bool> = rest.iter().map(|x| x.x == 0.0).collect();
                let gravity = Vec3::new(0.0, 0.0, -9.81);
                let weights: Vec<Vec3> = masses(&rest, &tets).iter().map(|&m| gravity * m).collect();
                for solver in SOLVERS {
                    let by_gravity = solve(solver, (&rest, &tets), &pinned, (gravity, &[], &[]), TOLERANCES);
                    let by_forces = solve(solver, (&rest, &tets), &pinned, (Vec3::ZERO, &weights, &[]), TOLERANCES);
                    let deflection = by_gravity.iter().zip(&rest).map(|(x, r)| (*x - *r).length()).fold(0.0, Real::max) as f64;
                    for (a, b) in by_gravity.iter().zip(&by_forces) {
                        let error = relative(*a, *b, deflection);
                        assert!(error < ACCURACY, "{solver:?}: {a} against {b} ({error:e} of {deflection:e} m)");
                    }
                }
            }

            #[test]
            fn a_tip_loaded_cantilever_deflects_the_same_with_every_solver() {
                let (rest, tets) = block((4, 1, 1), Vec3::new(0.4, 0.1, 0.1));
                let pinned: Vec<bool> = rest.iter().map(|x| x.x == 0.0).collect();
                let tip: Vec<usize> = (0..rest.len()).filter(|&i| rest[i].x > 0.399).collect();
                // Beam theory, for scale only: w = F L^3 / (3 E I) = STRAIN * L.
                let inertia = 0.1f64.powi(4) / 12.0;
                let total = BEAM_STRAIN * 0.4 * 3.0 * YOUNG as f64 * inertia / 0.4f64.powi(3);
                let mut forces = vec![Vec3::ZERO; rest.len()];
                for &i in &tip {
                    forces[i] = Vec3::new(0.0, 0.0, -(total / tip.len() as f64) as Real);
                }
                let results: Vec<Vec<Vec3>> = SOLVERS
                    .iter()
                    .map(|&solver| solve(solver, (&rest, &tets), &pinned, (Vec3::ZERO, &forces, &[]), BEAM_TOLERANCES))
                    .collect();
                let deflection = |x: &[Vec3]| tip.iter().map(|&i| (rest[i].z - x[i].z) as f64).sum::<f64>() / tip.len() as f64;
                let reference = deflection(&results[0]);
                // One cell through the thickness of linear tets locks: the mesh is stiffer than
                // the beam, between a tenth and all of the Euler-Bernoulli value.
                let beam = BEAM_STRAIN * 0.4;
                assert!(reference > beam / 10.0 && reference < beam, "{reference:e} against the beam's {beam:e}");
                for ((solver, x), accuracy) in SOLVERS.iter().zip(&results).zip(BEAM_ACCURACY) {
                    let w = deflection(x);
                    assert!(((w - reference) / reference).abs() < accuracy, "{solver:?}: {w:e} against Newton's {reference:e}");
                }
            }

            /// An eighth of a block in uniaxial tension: rollers on the three symmetry planes
            /// (x = 0 fixed in x, y = 0 in y, z = 0 in z), the top face pulled by a uniform
            /// traction lumped consistently (a third of each face triangle's share per corner).
            fn uniaxial_tension() -> (Vec<Vec3>, Vec<[u32; 4]>, Vec<Vec3>, Vec<u8>, f64) {
                let (rest, tets) = block((2, 2, 2), Vec3::ONE);
                let traction = STRAIN * YOUNG as f64;
                let mut forces = vec![Vec3::ZERO; rest.len()];
                let top = |i: u32| rest[i as usize].z == 1.0;
                for t in &tets {
                    for skip in 0..4 {
                        let face: Vec<u32> = (0..4).filter(|&c| c != skip).map(|c| t[c]).collect();
                        if face.iter().all(|&i| top(i)) {
                            let [a, b, c] = [0, 1, 2].map(|k| rest[face[k] as usize]);
                            let area = 0.5 * (b - a).cross(c - a).length() as f64;
                            for &i in &face {
                                forces[i as usize].z += (traction * area / 3.0) as Real;
                            }
                        }
                    }
                }
                let fixed = rest
                    .iter()
                    .map(|x| {
                        (if x.x == 0.0 { FIXED_X } else { 0 })
                            | (if x.y == 0.0 { FIXED_Y } else { 0 })
                            | (if x.z == 0.0 { FIXED_Z } else { 0 })
                    })
                    .collect();
                (rest, tets, forces, fixed, traction)
            }

            #[test]
            fn a_block_on_three_symmetry_planes_takes_the_uniaxial_solution() {
                let (rest, tets, forces, fixed, traction) = uniaxial_tension();
                let strain = traction / YOUNG as f64;
                for solver in SOLVERS {
                    let x = solve(solver, (&rest, &tets), &[], (Vec3::ZERO, &forces, &fixed), TOLERANCES);
                    for ((x, r), &mask) in x.iter().zip(&rest).zip(&fixed) {
                        // u = eps (-nu x, -nu y, z), the homogeneous linear solution.
                        let lateral = -(POISSON as f64) * strain;
                        let expected = *r + Vec3::new((lateral * r.x as f64) as Real, (lateral * r.y as f64) as Real, (strain * r.z as f64) as Real);
                        let error = relative(*x, expected, strain);
                        assert!(error < ACCURACY, "{solver:?}: vertex at {r}: {x} against {expected} ({error:e})");
                        // Rollers keep their fixed coordinate bit for bit.
                        for (axis, bit) in [FIXED_X, FIXED_Y, FIXED_Z].into_iter().enumerate() {
                            if mask & bit != 0 {
                                assert_eq!(x[axis].to_bits(), r[axis].to_bits(), "{solver:?}: axis {axis} of {r}");
                            }
                        }
                    }
                }
            }

            #[test]
            fn explicit_steps_follow_a_uniform_load_and_keep_fixed_axes() {
                let (rest, tets) = tetrahedron();
                let mut rest_data = vec![TetRest::default(); 1];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StVK::from_young_poisson(YOUNG, POISSON).unwrap());
                let m = masses(&rest, &tets);
                let acceleration = Vec3::new(0.5, -2.0, 1.0);
                let forces: Vec<Vec3> = m.iter().map(|&m| acceleration * m).collect();
                let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(4)];
                let (h, steps) = (1e-3, 10u32);
                let settings = ExplicitSettings::new();
                let run = |scene: &Scene<Vec3>, buffer: &mut Vec<Vec3>| {
                    let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; 4]);
                    let mut scratch = ExplicitScratch::new(buffer);
                    for _ in 0..steps {
                        explicit_step(&body, &m, &[], scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    }
                    (x, v)
                };
                let (x, v) = run(&Scene::new(h).with_external_forces(&forces), &mut buffer);
                // A rigid translation (no strain, no elastic force): v = n h a and
                // x = x_0 + h^2 a n (n + 1) / 2 for symplectic Euler.
                let n = steps as Real;
                for (x, r) in x.iter().zip(&rest) {
                    let expected = *r + acceleration * (h * h * n * (n + 1.0) / 2.0);
                    // Positions known to half an ulp strain the body by ~eps: elastic forces of
                    // ~eps E A against the load, sqrt(eps) relative with room to spare.
                    let allowed = 4.0 * Real::EPSILON.sqrt() * (expected - *r).length();
                    assert!((*x - expected).length() < allowed, "{x} against {expected}");
                }
                for v in &v {
                    let allowed = 4.0 * Real::EPSILON.sqrt() * acceleration.length() * n * h;
                    assert!((*v - acceleration * (n * h)).length() < allowed, "{v}");
                }
                // Vertex 0 on a roller in y and z: it moves only along x, by the same law.
                let fixed = [FIXED_Y | FIXED_Z, 0, 0, 0];
                let (x, v) = run(&Scene::new(h).with_external_forces(&forces).with_fixed_axes(&fixed), &mut buffer);
                assert_eq!((x[0].y.to_bits(), x[0].z.to_bits()), (rest[0].y.to_bits(), rest[0].z.to_bits()));
                assert_eq!((v[0].y, v[0].z), (0.0, 0.0));
                assert!(x[0].x > rest[0].x);
            }

            /// One implicit Euler step of 1/60 s by `solver` from rest, with gravity `gravity` and
            /// external forces `forces`; returns positions and velocities.
            fn implicit_step(solver: Solver, (rest, tets): (&[Vec3], &[[u32; 4]]), pinned: &[bool], (gravity, forces): (Vec3, &[Vec3])) -> (Vec<Vec3>, Vec<Vec3>) {
                use $($api)::+::step::{newton_step, relax_step, vbd_step};
                let mut rest_data = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(rest, tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StVK::from_young_poisson(YOUNG, POISSON).unwrap());
                let m = masses(rest, tets);
                let (n, t, dt) = (rest.len(), tets.len(), 1.0 / 60.0);
                let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; n]);
                let scene = Scene::new(dt).with_gravity(gravity).with_external_forces(forces);
                match solver {
                    Solver::Newton => {
                        let len = scratch_len::newton(n, t);
                        let (mut a, mut b, mut h) = (vec![Vec3::ZERO; len.vectors], vec![Mat3::ZERO; len.blocks], vec![TetHessian::default(); len.hessians]);
                        let settings = NewtonSettings::new().with_tolerance(TOLERANCES[0], 50);
                        let report = newton_step(&body, &m, pinned, &scene, &settings, &mut x, &mut v, &mut NewtonScratch::new(&mut a, &mut b, &mut h)).unwrap();
                        assert!(report.converged, "{report:?}");
                    }
                    Solver::Relax => {
                        let (mut a, mut s) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                        let settings = RelaxSettings::new().with_tolerance(TOLERANCES[1], 100_000);
                        let report = relax_step(&body, &m, pinned, &scene, &settings, &mut x, &mut v, &mut RelaxScratch::new(&mut a, &mut s)).unwrap();
                        assert!(report.converged, "{report:?}");
                    }
                    Solver::Vbd => {
                        let (mut a, mut i) = (vec![Vec3::ZERO; scratch_len::vbd(n)], vec![0; scratch_len::vbd_indices(n, t)]);
                        let settings = VbdSettings::new().with_tolerance(TOLERANCES[2], 100_000);
                        let report = vbd_step(&body, &m, pinned, &scene, &settings, &mut x, &mut v, &mut VbdScratch::new(&mut a, &mut i)).unwrap();
                        assert!(report.converged, "{report:?}");
                    }
                }
                (x, v)
            }

            #[test]
            fn an_implicit_step_under_a_force_buffer_of_weights_equals_the_gravity_step() {
                let (rest, tets) = block((4, 1, 1), Vec3::new(0.4, 0.1, 0.1));
                let pinned: Vec<bool> = rest.iter().map(|x| x.x == 0.0).collect();
                // Heavier than gravity so that the step moves well above rounding.
                let gravity = Vec3::new(0.0, 0.0, -200.0);
                let weights: Vec<Vec3> = masses(&rest, &tets).iter().map(|&m| gravity * m).collect();
                for solver in SOLVERS {
                    let (x_gravity, v_gravity) = implicit_step(solver, (&rest, &tets), &pinned, (gravity, &[]));
                    let (x_forces, v_forces) = implicit_step(solver, (&rest, &tets), &pinned, (Vec3::ZERO, &weights));
                    let speed = v_gravity.iter().map(|v| v.length()).fold(0.0, Real::max) as f64;
                    assert!(speed > 0.0);
                    for (a, b) in v_gravity.iter().zip(&v_forces) {
                        assert!(relative(*a, *b, speed) < ACCURACY, "{solver:?}: {a} against {b}");
                    }
                    for (a, b) in x_gravity.iter().zip(&x_forces) {
                        assert!(relative(*a, *b, speed / 60.0) < ACCURACY, "{solver:?}: {a} against {b}");
                    }
                }
            }

            /// A fixed coordinate keeps its bits when the ground pushes the vertex: a block
            /// thrown onto a slanted ground (its normal has x, y and z components), with one
            /// vertex fixed in x and another in y and z, under every implicit solver and the
            /// explicit step. The ground's projection moves a vertex along the normal, which
            /// would change the fixed coordinates; the promise is that those never move (the
            /// constraint wins over the contact for them).
            #[test]
            fn fixed_axes_keep_their_bits_against_a_slanted_ground() {
                use $($api)::+::step::{HalfSpace, gradient_descent_step, newton_step, relax_step, vbd_step};
                let (rest, tets) = block((2, 1, 1), Vec3::new(0.2, 0.1, 0.1));
                let mut rest_data = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StVK::from_young_poisson(YOUNG, POISSON).unwrap());
                let m = masses(&rest, &tets);
                let (n, t, dt) = (rest.len(), tets.len(), 1.0 / 30.0);
                // Two vertices of the face that lands (y = 0 before the shear): the first, fixed
                // in x, and the last, fixed in y and z. Every implicit step below starts from
                // y = x_n + h v_n, which for both lies 7 to 8 cm below the ground, so their
                // first guesses are projected.
                let last = (0..n).rev().find(|&i| rest[i].y == 0.0).unwrap();
                let mut fixed = vec![0u8; n];
                fixed[0] = FIXED_X;
                fixed[last] = FIXED_Y | FIXED_Z;
                let normal = Vec3::new(-0.7, 1.0, -0.7);
                let (ground, unit) = (HalfSpace::new(normal, 0.0), normal.normalize());
                let gravity = Vec3::new(0.0, -9.81, 0.0);
                // Resting on the plane through the origin, thrown into it at 3 m/s.
                let start: Vec<Vec3> = rest.iter().map(|&p| p + Vec3::new(0.0, 0.7 * (p.x + p.z) + 1e-3, 0.0)).collect();
                let throw = vec![Vec3::new(0.5, -3.0, 0.2); n];
                let scene = Scene::new(dt).with_gravity(gravity).with_ground(ground).with_fixed_axes(&fixed);
                let failures = core::cell::RefCell::new(Vec::new());
                let keeps = |name: &str, start: &[Vec3], x: &[Vec3]| {
                    let mut failures = failures.borrow_mut();
                    if x[0].x.to_bits() != start[0].x.to_bits() {
                        failures.push(format!("{name}: fixed x of vertex 0 moved from {} to {}", start[0].x, x[0].x));
                    }
                    if x[last].y.to_bits() != start[last].y.to_bits() || x[last].z.to_bits() != start[last].z.to_bits() {
                        failures.push(format!("{name}: fixed y, z of vertex {last} moved from {} to {}", start[last], x[last]));
                    }
                    // Every other vertex is on or above the ground (to its contact tolerance).
                    for (i, p) in x.iter().enumerate().filter(|&(i, _)| fixed[i] == 0) {
                        if unit.dot(*p) < -1e-3 {
                            failures.push(format!("{name}: vertex {i} at {p} is below the ground"));
                        }
                    }
                };
                {
                    let (mut x, mut v) = (start.clone(), throw.clone());
                    let len = scratch_len::newton(n, t);
                    let (mut a, mut b, mut h) = (vec![Vec3::ZERO; len.vectors], vec![Mat3::ZERO; len.blocks], vec![TetHessian::default(); len.hessians]);
                    let settings = NewtonSettings::new();
                    for _ in 0..3 {
                        newton_step(&body, &m, &[], &scene, &settings, &mut x, &mut v, &mut NewtonScratch::new(&mut a, &mut b, &mut h)).unwrap();
                    }
                    keeps("newton_step", &start, &x);
                }
                {
                    let (mut x, mut v) = (start.clone(), throw.clone());
                    let (mut a, mut s) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                    let settings = RelaxSettings::new().with_tolerance(1e-3, 2000);
                    for _ in 0..3 {
                        relax_step(&body, &m, &[], &scene, &settings, &mut x, &mut v, &mut RelaxScratch::new(&mut a, &mut s)).unwrap();
                    }
                    keeps("relax_step", &start, &x);
                    let (mut x, mut v) = (start.clone(), throw.clone());
                    let settings = settings.with_chebyshev(0.9, 1.0, 2);
                    for _ in 0..3 {
                        relax_step(&body, &m, &[], &scene, &settings, &mut x, &mut v, &mut RelaxScratch::new(&mut a, &mut s)).unwrap();
                    }
                    keeps("relax_step (Chebyshev)", &start, &x);
                    let (mut x, mut v) = (start.clone(), throw.clone());
                    for _ in 0..3 {
                        gradient_descent_step(&body, &m, &[], &scene, &settings, &mut x, &mut v, &mut RelaxScratch::new(&mut a, &mut s)).unwrap();
                    }
                    keeps("gradient_descent_step", &start, &x);
                }
                {
                    let (mut x, mut v) = (start.clone(), throw.clone());
                    let (mut a, mut i) = (vec![Vec3::ZERO; scratch_len::vbd(n)], vec![0; scratch_len::vbd_indices(n, t)]);
                    let settings = VbdSettings::new();
                    for _ in 0..3 {
                        vbd_step(&body, &m, &[], &scene, &settings, &mut x, &mut v, &mut VbdScratch::new(&mut a, &mut i)).unwrap();
                    }
                    keeps("vbd_step", &start, &x);
                    // With Chebyshev: the extrapolated trial points too.
                    let (mut x, mut v) = (start.clone(), throw.clone());
                    let settings = settings.with_chebyshev(0.95, 2);
                    for _ in 0..3 {
                        vbd_step(&body, &m, &[], &scene, &settings, &mut x, &mut v, &mut VbdScratch::new(&mut a, &mut i)).unwrap();
                    }
                    keeps("vbd_step (Chebyshev)", &start, &x);
                }
                {
                    // Explicit steps of 1e-5 s move a vertex far less than a step of 1/30 s: the
                    // block starts 3 mm lower, its landing face 1.4 mm into the ground, so that
                    // the first step already projects both fixed vertices.
                    let low: Vec<Vec3> = start.iter().map(|&p| p - Vec3::new(0.0, 3e-3, 0.0)).collect();
                    assert!(unit.dot(low[0]) < -1e-3 && unit.dot(low[last]) < -1e-3);
                    let (mut x, mut v) = (low.clone(), throw.clone());
                    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(n)];
                    let scene = Scene::new(1e-5).with_gravity(gravity).with_ground(ground).with_fixed_axes(&fixed);
                    let settings = ExplicitSettings::new();
                    for _ in 0..30 {
                        explicit_step(&body, &m, &[], &scene, &settings, &mut x, &mut v, &mut ExplicitScratch::new(&mut buffer)).unwrap();
                    }
                    keeps("explicit_step", &low, &x);
                }
                let failures = failures.into_inner();
                assert!(failures.is_empty(), "{}", failures.join("\n"));
            }

            #[test]
            fn loads_are_validated_and_name_the_buffer_and_vertex() {
                let (rest, tets) = tetrahedron();
                let mut rest_data = vec![TetRest::default(); 1];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StVK::from_young_poisson(YOUNG, POISSON).unwrap());
                let m = masses(&rest, &tets);
                let (mut v, mut s) = (vec![Vec3::ZERO; scratch_len::relax(4)], vec![0.0; 4]);
                let mut x = rest.clone();
                let bad_forces = [Vec3::ZERO, Vec3::new(0.0, Real::NAN, 0.0), Vec3::ZERO, Vec3::ZERO];
                let settings = RelaxSettings::new();
                let cases: [(Scene<Vec3>, StepError); 3] = [
                    (Scene::new(0.01).with_external_forces(&bad_forces[..3]), StepError::LengthMismatch { buffer: StepBuffer::ExternalForces, expected: 4, actual: 3 }),
                    (Scene::new(0.01).with_external_forces(&bad_forces), StepError::ExternalForce { vertex: 1 }),
                    (Scene::new(0.01).with_fixed_axes(&[0, 0, 8, 0]), StepError::FixedAxes { vertex: 2 }),
                ];
                for (scene, expected) in cases {
                    let mut scratch = RelaxScratch::new(&mut v, &mut s);
                    assert_eq!(relax_quasi_static(&body, &m, &[], &scene, &settings, &mut x, &mut scratch), Err(expected));
                    assert_eq!(x, rest);
                }
            }
        }
    };
}

load_tests!(
    single,
    softfem,
    [1e-4, 3e-3, 1e-3],
    [1e-4, 2e-2, 2e-3],
    [1e-2, 3e-2, 1e-2],
    1e-3,
    2e-2,
    1e-2
);
load_tests!(
    double,
    softfem::f64,
    [1e-9, 1e-7, 1e-7],
    [1e-9, 1e-7, 1e-7],
    [2e-3, 2e-3, 2e-3],
    1e-4,
    1e-4,
    2e-3
);

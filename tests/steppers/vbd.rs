//! Vertex Block Descent: one sweep on a single free vertex is the exact Newton step for it
//! (against finite differences of the force kernel); the quasi-static cantilever of
//! tests/steppers/relax.rs reaches the relaxation's equilibrium; implicit Euler on a stiff block at
//! 1/30 s converges without gaining energy; the colouring is valid and greedy; results do not
//! depend on the scratch's previous contents; bad input is refused with the state untouched.
//! The `#[ignore]`d `measure_*` tests print the timings of the report (run them in release).

use softfem::StepError;
use softfem::mesh::{
    adjacency_incident_len, adjacency_offsets_len, build_vertex_adjacency, colour_vertices,
    vertex_order,
};

macro_rules! vbd_tests {
    ($precision:ident, $($api:ident)::+, $newton_tolerance:expr) => {
        mod $precision {
            use softfem::StepError;
            use $($api)::+::element::TetRest;
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::{Material, StVK, StableNeoHookean};
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::{
                HalfSpace, Scene, TetElastic, VbdOptions, VbdScratch, VbdSettings, scratch_len, vbd_quasi_static, vbd_step,
            };
            use $($api)::+::types::{Mat3, Real, Vec3};

            const GRAVITY: Vec3 = Vec3::new(0.0, -9.81, 0.0);

            struct Boxed {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
            }

            fn boxed(max: Vec3, cells: [usize; 3]) -> Boxed {
                let [nx, ny, nz] = cells;
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, max, (nx, ny, nz), BoxSplit::Kuhn6);
                Boxed { rest, tets }
            }

            fn bits(x: &[Vec3]) -> Vec<[u64; 3]> {
                x.iter().map(|p| p.to_array().map(|c| f64::from(c).to_bits())).collect()
            }

            /// The tetrahedron of the single-vertex tests: three corners pinned, the fourth
            /// free, 0.1 m edges.
            const HANGING: [Vec3; 4] = [
                Vec3::ZERO,
                Vec3::new(0.1, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 0.1),
                Vec3::new(0.0, -0.1, 0.0),
            ];
            const HANGING_PINNED: [bool; 4] = [true, true, true, false];
            const HANGING_STEP: Real = 1.0 / 60.0;
            /// The free corner's velocity.
            const HANGING_VELOCITY: Vec3 = Vec3::new(0.3, -0.5, 0.2);

            /// Runs `test` on [`HANGING`] made of stable neo-Hookean with Young's modulus
            /// `young` (Pa, Poisson 0.3, 1000 kg/m^3), with its lumped masses.
            fn with_hanging_tetrahedron(young: Real, test: impl FnOnce(&TetElastic<'_, StableNeoHookean>, [Real; 4])) {
                let tets = [[0, 1, 2, 3]];
                let mut rest_data = [TetRest::default(); 1];
                let mesh = TetMesh::new(&HANGING, &tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(young, 0.3).unwrap());
                let mut masses = [0.0; 4];
                mesh.lumped_masses(1000.0, &mut masses).unwrap();
                test(&body, masses);
            }

            /// Scratch buffers for `n` vertices and `t` tetrahedra.
            fn buffers(n: usize, t: usize) -> (Vec<Vec3>, Vec<u32>) {
                (vec![Vec3::ZERO; scratch_len::vbd(n)], vec![0; scratch_len::vbd_indices(n, t)])
            }

            /// Packed-layout buffers for `n` vertices and `t` tetrahedra, full of garbage (NaN
            /// values, arbitrary indices): the layout overwrites what it reads.
            fn layout_buffers(n: usize, t: usize) -> (Vec<Real>, Vec<u32>) {
                let corners = (0..scratch_len::vbd_layout_corners(n, t) as u32).map(|i| i.wrapping_mul(2_654_435_761)).collect();
                (vec![Real::NAN; scratch_len::vbd_layout(t)], corners)
            }

            /// The scene of the layout and parallel tests: a block (12 x 10 x 3 cubes: 8
            /// colours of 43 or more vertices) pinned at one end, pressed sideways by external
            /// loads, with a roller axis, thrown onto a frictional ground, with the line search
            /// and Chebyshev on (StVK, which is projected where compressed).
            struct Pressed {
                cube: Boxed,
                masses: Vec<Real>,
                pinned: Vec<bool>,
                loads: Vec<Vec3>,
                fixed: Vec<u8>,
            }

            fn pressed() -> Pressed {
                let cube = boxed(Vec3::new(0.24, 0.06, 0.2), [12, 3, 10]);
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &cube.rest, &cube.tets, 1000.0);
                let pinned = cube.rest.iter().map(|p| p.x < 1e-6).collect();
                let loads = cube.rest.iter().map(|p| Vec3::new(0.0, 0.0, -0.05 * p.x)).collect();
                let fixed = cube.rest.iter().map(|p| u8::from(p.z < 1e-6) * 4).collect();
                Pressed { cube, masses, pinned, loads, fixed }
            }

            /// The bits and reports of three steps and a quasi-static sag of the [`pressed`]
            /// scene, through `step` and `sag` (sequential or parallel), with the packed
            /// layout in buffers of `layout` lengths (values, corners) or without one.
            #[allow(clippy::type_complexity)]
            fn pressed_run(
                pressed: &Pressed,
                layout: Option<(usize, usize)>,
                step: &dyn Fn(&TetElastic<'_, StVK>, &Pressed, &Scene<'_, Vec3>, &VbdSettings, &mut [Vec3], &mut [Vec3], &mut VbdScratch<'_>) -> String,
                sag: &dyn Fn(&TetElastic<'_, StVK>, &Pressed, &Scene<'_, Vec3>, &VbdSettings, &mut [Vec3], &mut VbdScratch<'_>) -> String,
            ) -> (Vec<[u64; 3]>, Vec<[u64; 3]>, Vec<String>, bool) {
                let cube = &pressed.cube;
                let mut rest_data = vec![TetRest::default(); cube.tets.len()];
                let mesh = TetMesh::new(&cube.rest, &cube.tets, &mut rest_data).unwrap();
                let body = TetElastic::new(mesh, StVK::from_young_poisson(2.0e5, 0.4).unwrap());
                let (n, t) = (cube.rest.len(), cube.tets.len());
                let ground = HalfSpace::new(Vec3::Y, -2e-3).with_friction(0.5);
                let scene = Scene::new(1.0 / 60.0)
                    .with_gravity(GRAVITY)
                    .with_ground(ground)
                    .with_external_forces(&pressed.loads)
                    .with_fixed_axes(&pressed.fixed);
                let settings = VbdSettings::new().with_tolerance(0.0, 8).with_chebyshev(0.9, 2);
                let (mut x, mut v) = (cube.rest.clone(), vec![Vec3::new(0.5, -1.0, 0.2); n]);
                let (mut vectors, mut indices) = buffers(n, t);
                let (mut values, mut corners) = layout_buffers(n, t);
                let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                if let Some((values_len, corners_len)) = layout {
                    values.truncate(values_len);
                    corners.truncate(corners_len);
                    scratch = scratch.with_layout(&mut values, &mut corners);
                }
                let mut reports = Vec::new();
                for _ in 0..3 {
                    reports.push(step(&body, pressed, &scene, &settings, &mut x, &mut v, &mut scratch));
                }
                let still = settings.with_tolerance(1e-6, 6);
                reports.push(sag(&body, pressed, &scene, &still, &mut x, &mut scratch));
                (bits(&x), bits(&v), reports, scratch.layout_in_use())
            }

            /// [`pressed_run`] through the sequential solvers.
            fn pressed_sequential(scene: &Pressed, layout: Option<(usize, usize)>) -> (Vec<[u64; 3]>, Vec<[u64; 3]>, Vec<String>, bool) {
                pressed_run(
                    scene,
                    layout,
                    &|body, pressed, scene, settings, x, v, scratch| {
                        format!("{:?}", vbd_step(body, &pressed.masses, &pressed.pinned, scene, settings, x, v, scratch).unwrap())
                    },
                    &|body, pressed, scene, settings, x, scratch| {
                        format!("{:?}", vbd_quasi_static(body, &pressed.masses, &pressed.pinned, scene, settings, x, scratch).unwrap())
                    },
                )
            }

            /// The packed layout fits its documented lengths on the generator's boxes, both
            /// splits, from one cell to thin and flat bars (where the vertex valences vary
            /// most): vertices ordered by valence within each colour leave few masked lanes.
            #[test]
            fn packed_layout_fits_the_generators_boxes() {
                for split in [BoxSplit::Kuhn6, BoxSplit::Alternating5] {
                    for [nx, ny, nz] in [[1, 1, 1], [2, 2, 2], [6, 6, 6], [4, 2, 2], [20, 1, 1], [12, 3, 10], [10, 10, 1]] {
                        let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, Vec3::splat(0.1), (nx, ny, nz), split);
                        let (nv, nt) = (rest.len(), tets.len());
                        crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
                        let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap());
                        let (mut vectors, mut indices) = buffers(nv, nt);
                        let (mut values, mut corners) = layout_buffers(nv, nt);
                        let mut scratch = VbdScratch::new(&mut vectors, &mut indices).with_layout(&mut values, &mut corners);
                        let scene = Scene::new(1.0 / 60.0).with_gravity(GRAVITY);
                        let settings = VbdSettings::new().with_tolerance(0.0, 1);
                        let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; nv]);
                        vbd_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                        assert!(scratch.layout_in_use(), "{split:?} {nx} x {ny} x {nz}");
                    }
                }
            }

            /// The packed sweep layout changes no bit: positions, velocities and reports of
            /// steps with contact, friction, loads, fixed axes, pinned vertices, the line search
            /// and Chebyshev, and of a quasi-static sag, are those of the gathered sweep, from
            /// layout buffers full of garbage; buffers one entry too short leave the layout
            /// unused, with the same results.
            #[test]
            fn packed_layout_gives_the_gathered_bits() {
                let scene = pressed();
                let (n, t) = (scene.cube.rest.len(), scene.cube.tets.len());
                let gathered = pressed_sequential(&scene, None);
                assert!(!gathered.3);
                // The scene exercises the contact, the line search and the projection.
                assert!(gathered.2.iter().any(|r| !r.contains("vertex_backtracks: 0,")), "{:?}", gathered.2);
                let full = (scratch_len::vbd_layout(t), scratch_len::vbd_layout_corners(n, t));
                let packed = pressed_sequential(&scene, Some(full));
                assert!(packed.3, "the layout fits its documented length");
                assert!(packed.0 == gathered.0 && packed.1 == gathered.1, "{:?} vs {:?}", packed.2, gathered.2);
                assert_eq!(packed.2, gathered.2);
                for short in [(0, full.1), (full.0, n)] {
                    let unused = pressed_sequential(&scene, Some(short));
                    assert!(!unused.3, "{short:?}");
                    assert_eq!((&unused.0, &unused.1, &unused.2), (&gathered.0, &gathered.1, &gathered.2));
                }
            }

            /// The packed sweep gives the gathered bits where a lane group's longest row is
            /// longer than all its others, whose last visits the sweep sums for that lane
            /// alone: the descent chart's stiff block (4 x 2 x 2 cubes of 6 tetrahedra, clamped
            /// at x = 0, E = 1e8 Pa, 1/30 s, gravity, a perturbed start), where an interior
            /// vertex of 24 elements shares its colour with vertices of at most 12 (checked
            /// here on the colouring), with and without the line search, Chebyshev on.
            #[test]
            fn packed_layout_gives_the_gathered_bits_where_one_lane_runs_alone() {
                let cube = boxed(Vec3::new(0.1, 0.05, 0.05), [4, 2, 2]);
                let (n, t) = (cube.rest.len(), cube.tets.len());
                let mut offsets = vec![0; softfem::mesh::adjacency_offsets_len(n)];
                let mut incident = vec![0; softfem::mesh::adjacency_incident_len(t)];
                softfem::mesh::build_vertex_adjacency(&cube.tets, n, &mut offsets, &mut incident).unwrap();
                let mut colours = vec![0; n];
                let count = softfem::mesh::colour_vertices(&cube.tets, &offsets, &incident, &mut colours).unwrap();
                let degree = |v: usize| offsets[v + 1] - offsets[v];
                let alone = (0..count).any(|c| {
                    let mut rows: Vec<u32> = (0..n).filter(|&v| colours[v] == c).map(degree).collect();
                    rows.sort_unstable();
                    matches!(rows.as_slice(), [.., a, b] if b > a) || rows.len() == 1 && rows[0] > 1
                });
                assert!(alone, "no colour with a single longest row");
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &cube.rest, &cube.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e8, 0.3).unwrap());
                let pinned: Vec<bool> = cube.rest.iter().map(|p| p.x == 0.0).collect();
                let mut rng = crate::common::Rng::new(3);
                let start: Vec<Vec3> = cube.rest.iter().zip(&pinned).map(|(&p, &fixed)| {
                    let mut unit = || (rng.unit() - 0.5) as Real;
                    let offset = Vec3::new(unit(), unit(), unit()) * (2.0 * 1e-3 * 0.025);
                    if fixed { p } else { p + offset }
                }).collect();
                for backtracks in [0, 8] {
                    let scene = Scene::new(1.0 / 30.0).with_gravity(GRAVITY);
                    let settings = VbdSettings::new()
                        .with_tolerance(0.0, 12)
                        .with_line_search(backtracks)
                        .with_chebyshev(0.95, 2);
                    let run = |packed: bool| {
                        let (mut vectors, mut indices) = buffers(n, t);
                        let (mut values, mut corners) = layout_buffers(n, t);
                        let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                        if packed {
                            scratch = scratch.with_layout(&mut values, &mut corners);
                        }
                        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; n]);
                        let report = vbd_step(&body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                        assert_eq!(scratch.layout_in_use(), packed);
                        (bits(&x), bits(&v), format!("{report:?}"))
                    };
                    let (gathered, packed) = (run(false), run(true));
                    assert!(gathered == packed, "{backtracks} backtracks: {} vs {}", gathered.2, packed.2);
                }
            }

            /// One sweep on a tetrahedron with one free vertex is one Newton step on `Phi` in
            /// that vertex: `x = y - H^-1 g`, `g = -f(y)` (the inertia term vanishes at the
            /// initial guess `y`, without gravity) and `H = m / h^2 I + K`, `K` the 3x3
            /// stiffness block, here by central differences of the force kernel (step 1e-6 of
            /// the edge: truncation ~1e-12 and rounding ~1e-10 relative in f64; in f32 the
            /// rounding of the differences dominates). At 10 % strain the exact block is
            /// positive definite, so the projected block the solver uses is the exact one.
            #[test]
            fn one_sweep_on_a_single_free_vertex_is_its_newton_step() {
                with_hanging_tetrahedron(1.0e5, |body, masses| {
                    let (rest, mesh, material) = (HANGING, body.mesh, body.material);
                    let (pinned, h, velocity) = (HANGING_PINNED, HANGING_STEP, HANGING_VELOCITY);
                    let (mut x, mut v) = (rest, [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, velocity]);
                    let y = rest[3] + velocity * h;

                    // The reference Newton step, in f64 whatever the precision under test.
                    let force_at = |p: Vec3| {
                        let mut corners = rest;
                        corners[3] = p;
                        let mut f = [Vec3::ZERO; 4];
                        mesh.add_elastic_forces(&material, &corners, &mut f).unwrap();
                        f[3]
                    };
                    let epsilon: Real = 1e-7;
                    let column = |axis: Vec3| {
                        (force_at(y + axis * epsilon) - force_at(y - axis * epsilon)) * (-0.5 / epsilon)
                    };
                    let stiffness = Mat3::from_cols(column(Vec3::X), column(Vec3::Y), column(Vec3::Z));
                    let hessian = Mat3::from_diagonal(Vec3::splat(masses[3] / (h * h))) + stiffness;
                    let step = hessian.inverse() * force_at(y);
                    let expected = y + step;

                    let scene = Scene::new(h);
                    let settings = VbdSettings::new().with_tolerance(0.0, 1);
                    let (mut vectors, mut indices) = buffers(4, 1);
                    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                    let report = vbd_step(body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    println!("{}: {report:?}; step {step}, VBD - Newton {}", stringify!($precision), x[3] - expected);
                    assert_eq!((report.iterations, report.details.vertex_backtracks, report.details.skipped), (1, 0, 0));
                    assert!(step.length() > 1e-3 * 0.1, "a real step: {step}");
                    assert!((x[3] - expected).length() <= $newton_tolerance * step.length(), "{} vs {}", x[3], expected);
                    assert_eq!(&x[..3], &rest[..3]);
                });
            }

            /// The adaptive initial guess: with a budget of no sweeps the step returns its
            /// initial guess, which is the lower-`Phi` (computed here from its definition) of
            /// `y + h^2 g` and `y + h^2 a~`, `a~` the previous acceleration's component along
            /// `g`, clamped to `[0, |g|]`; with `v_(n-1) = v_n` (no acceleration) the solve is
            /// the default's, bit for bit.
            #[test]
            fn adaptive_initial_guess_is_the_clamped_previous_acceleration() {
                use $($api)::+::step::ElasticEnergy;
                // Soft enough that the minimiser of `Phi` along `g` from `y` lies between `y`
                // and `y + h^2 g`.
                with_hanging_tetrahedron(2.0e3, |body, masses| {
                    let rest = HANGING;
                    let (pinned, h, velocity) = (HANGING_PINNED, HANGING_STEP, HANGING_VELOCITY);
                    let y = rest[3] + velocity * h;
                    let phi = |p: Vec3| {
                        let mut corners = rest;
                        corners[3] = p;
                        let mut forces = [Vec3::ZERO; 4];
                        let elastic = body.energy_and_add_forces(&corners, &mut forces).unwrap();
                        let m = masses[3];
                        m / (2.0 * h * h) * (p - y).length_squared() - m * GRAVITY.dot(p - rest[3]) + elastic
                    };
                    let drop = y + GRAVITY * (h * h);
                    let sideways = Vec3::new(4.0, 0.0, -3.0);
                    let mut adaptive_won = 0;
                    // (previous acceleration along g in units of g, the clamped fraction).
                    for (along, clamped) in [(0.5, 0.5), (0.3, 0.3), (2.0, 1.0), (-1.0, 0.0), (0.0, 0.0)] {
                        let acceleration = GRAVITY * along + sideways;
                        let previous = [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, velocity - acceleration * h];
                        let scene = Scene::new(h).with_gravity(GRAVITY).with_previous_velocities(&previous);
                        let settings = VbdSettings::new().with_tolerance(0.0, 0);
                        let (mut x, mut v) = (rest, [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, velocity]);
                        let (mut vectors, mut indices) = buffers(4, 1);
                        let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                        let report = vbd_step(body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                        assert_eq!(report.iterations, 0);
                        let adaptive = y + GRAVITY * (clamped * h * h);
                        let expected = if phi(adaptive) < phi(drop) { adaptive } else { drop };
                        adaptive_won += usize::from(phi(adaptive) < phi(drop));
                        // The guess's rounding: a few eps of the step h^2 |g| (2.7 mm).
                        assert!((x[3] - expected).length() <= 1e-5 * h * h * 9.81, "{along}: {} vs {expected}", x[3]);
                        assert_eq!(&x[..3], &rest[..3]);
                    }
                    // The scene tells the candidates apart: the halfway guesses, and y, beat y + h^2 g.
                    assert!(adaptive_won >= 3, "{adaptive_won}");

                    // No acceleration: the adaptive guess is y, the default's second candidate.
                    let run = |previous: &[Vec3]| {
                        let scene = Scene::new(h).with_gravity(GRAVITY).with_previous_velocities(previous);
                        let settings = VbdSettings::new().with_tolerance(1e-6, 50);
                        let (mut x, mut v) = (rest, [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, velocity]);
                        let (mut vectors, mut indices) = buffers(4, 1);
                        let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                        let report = vbd_step(body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                        (report, bits(&x), bits(&v))
                    };
                    let still = [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, velocity];
                    assert_eq!(run(&still), run(&[]));
                });
            }

            /// The stiff block of tests/steppers/stability.rs (2 x 1 x 1 cubes of 5 cm, E = 1e8 Pa,
            /// nu = 0.3, 300 times past the explicit limit at this step), perturbed: implicit
            /// Euler at 1/30 s converges to 1e-4 on every step (f32: or reaches the rounding floor of its
/// force sums) and never gains energy.
            #[test]
            fn implicit_euler_on_a_stiff_block_converges_at_a_thirtieth_of_a_second() {
                let block = boxed(Vec3::new(0.1, 0.05, 0.05), [2, 1, 1]);
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &block.rest, &block.tets, 1000.0);
                let n = block.rest.len();
                let material = StableNeoHookean::from_young_poisson(1.0e8, 0.3).unwrap();
                let body = TetElastic::new(mesh, material);
                let mut x: Vec<Vec3> = block.rest.iter().enumerate().map(|(i, &p)| {
                    let (s, c) = ((i as Real * 1.7).sin(), (i as Real * 2.3).cos());
                    p + Vec3::new(s, c, s * c) * 5e-4
                }).collect();
                let mut v = vec![Vec3::ZERO; n];
                let energy = |x: &[Vec3], v: &[Vec3]| -> f64 {
                    let kinetic: f64 = v.iter().zip(&masses).map(|(v, m)| 0.5 * f64::from(*m) * f64::from(v.length_squared())).sum();
                    kinetic + f64::from(mesh.elastic_energy(&material, x).unwrap())
                };
                let start = energy(&x, &v);
                let scene = Scene::new(1.0 / 30.0);
                let settings = VbdSettings::new().with_tolerance(1e-4, 200);
                let (mut vectors, mut indices) = buffers(n, block.tets.len());
                let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                let mut sweeps = 0;
                for step in 0..30 {
                    let report = vbd_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    sweeps += report.iterations;
                    // Converged, or at the rounding floor of the force sums: element forces of
                    // E L^2 ~ 2.5e5 N cancel to a few eps E L^2 per vertex (0.2 N in f32, above
                    // 1e-4 of the initial residual once the block has settled; 4e-10 N in f64,
                    // never reached).
                    let floor = 2.0 * Real::EPSILON * 1.0e8 * 0.05 * 0.05 * (n as Real).sqrt();
                    assert!(report.converged || report.residual <= floor, "step {step}: {report:?}");
                    let now = energy(&x, &v);
                    // Implicit Euler dissipates; the tolerance allows 1e-3 of the start.
                    assert!(now <= start * 1.001, "step {step}: energy {now} > {start}");
                }
                println!("{}: stiff block, 30 steps of 1/30 s: {sweeps} sweeps, energy {start:.3e} -> {:.3e} J",
                    stringify!($precision), energy(&x, &v));
            }

            /// Accelerated sweeps accepted without evaluating `Phi` (the loop's deferred
            /// checks, `docs/math.md` section 7.2) leave the report honest: on the descent
            /// chart's clamped stiff block (4 x 2 x 2 cubes, E = 1e8 Pa, first step of 1/30 s
            /// from a perturbed rest, Chebyshev 0.95 after 2 sweeps, no line search), for every
            /// budget of 1 to 45 sweeps at tolerance 0 (the solve then ends on deferred sweeps)
            /// and for the solve to 1e-4, the reported residual and `Phi` are those of the
            /// returned positions, recomputed here from the force kernel and the closed form of
            /// `Phi`, and `converged` says whether that residual meets the tolerance. The solve
            /// to 1e-4 converges (f64; f32 reaches its rounding floor) and evaluates fewer times
            /// than it sweeps (the deferral is in use: before it, 28 sweeps and 32 evaluations
            /// in f64, 183 and 185 in f32).
            #[test]
            fn deferred_sweeps_report_the_residual_and_phi_of_the_returned_state() {
                use $($api)::+::step::ElasticEnergy;
                let block = boxed(Vec3::new(0.1, 0.05, 0.05), [4, 2, 2]);
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &block.rest, &block.tets, 1000.0);
                let n = block.rest.len();
                let material = StableNeoHookean::from_young_poisson(1.0e8, 0.3).unwrap();
                let body = TetElastic::new(mesh, material);
                let pinned: Vec<bool> = block.rest.iter().map(|p| p.x == 0.0).collect();
                let start: Vec<Vec3> = block.rest.iter().enumerate().map(|(i, &p)| {
                    let (s, c) = ((i as Real * 1.7).sin(), (i as Real * 2.3).cos());
                    if pinned[i] { p } else { p + Vec3::new(s, c, s * c) * 2.5e-5 }
                }).collect();
                let h: Real = 1.0 / 30.0;
                // |grad Phi| over the free vertices and Phi at x (from rest: y = x_n), in f64.
                let reference = |x: &[Vec3]| -> (f64, f64) {
                    let mut forces = vec![Vec3::ZERO; n];
                    let elastic = body.energy_and_add_forces(x, &mut forces).unwrap();
                    let (mut squared, mut phi) = (0.0, f64::from(elastic));
                    for i in 0..n {
                        let (m, d) = (f64::from(masses[i]), (x[i] - start[i]).to_array().map(f64::from));
                        let g = [0.0, f64::from(GRAVITY.y), 0.0];
                        let inertia = m / f64::from(h * h);
                        for k in 0..3 {
                            phi += 0.5 * inertia * d[k] * d[k] - m * g[k] * d[k];
                            let gradient = inertia * d[k] - m * g[k] - f64::from(forces[i].to_array()[k]);
                            if !pinned[i] {
                                squared += gradient * gradient;
                            }
                        }
                    }
                    (squared.sqrt(), phi)
                };
                // Rounding: the residual sums element forces of E L^2 ~ 6e4 N per vertex, each
                // to a few eps (f32: ~0.05 N over the block; f64: ~1e-10 N); Phi to sqrt(eps).
                let floor = 16.0 * f64::from(Real::EPSILON) * 1.0e8 * 0.025 * 0.025 * (n as f64).sqrt();
                let weight = masses.iter().zip(&pinned).filter(|(_, p)| !**p)
                    .map(|(m, _)| (f64::from(*m) * 9.81).powi(2)).sum::<f64>().sqrt();
                let scene = Scene::new(h).with_gravity(GRAVITY);
                let settings = VbdSettings::new().with_line_search(0).with_chebyshev(0.95, 2);
                let (mut vectors, mut indices) = buffers(n, block.tets.len());
                let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                let mut check = |tolerance: Real, budget: u32| {
                    let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; n]);
                    let report = vbd_step(&body, &masses, &pinned, &scene, &settings.with_tolerance(tolerance, budget), &mut x, &mut v, &mut scratch).unwrap();
                    let (residual, phi) = reference(&x);
                    let reported = f64::from(report.residual);
                    assert!((reported - residual).abs() <= 1e-3 * residual + floor,
                        "budget {budget}: residual {reported} reported, {residual} recomputed: {report:?}");
                    let rounding = f64::from(Real::EPSILON).sqrt() * (phi.abs() + f64::from(mesh.elastic_energy(&material, &x).unwrap()).abs());
                    assert!((f64::from(report.phi) - phi).abs() <= rounding + 1e-12,
                        "budget {budget}: Phi {} reported, {phi} recomputed", report.phi);
                    let target = f64::from(tolerance) * f64::from(report.initial_residual).max(weight);
                    assert_eq!(report.converged, reported <= target, "budget {budget}: {report:?}");
                    report
                };
                for budget in 1..=45 {
                    check(0.0, budget);
                }
                let report = check(1e-4, 200);
                // f32 stops at the rounding floor of its force sums (0.25 N here).
                assert!(report.converged || f64::from(report.residual) <= floor, "{report:?}");
                assert!(report.energy_evaluations < report.iterations, "{report:?}");
                println!("{}: deferred checks on the stiff block: {} sweeps, {} evaluations, {} restarts",
                    stringify!($precision), report.iterations, report.energy_evaluations, report.restarts);
            }

            /// With full steps and the line search only in sweeps that raised `Phi`, sweeps are
            /// still monotone: `Phi` after `k < 30` sweeps (each solve rerun from the same start with
            /// a budget of `k`, tolerance 0, no acceleration) never rises with `k` beyond the
            /// solver's own rounding bound (`sqrt(eps)` of `|Phi|` twice and of the elastic
            /// energy), from a start stretched to three times its height and twisted (stable
            /// neo-Hookean) and one squashed to 0.4 of it (StVK, whose compressed blocks are
            /// indefinite), at a step of 1 s (little inertia), where whole Newton steps can
            /// overshoot; and the solves converge.
            #[test]
            fn line_search_on_increase_keeps_sweeps_monotone() {
                fn check<M: Material>(material: M, height: Real, twist: Real) -> u32 {
                    let cube = boxed(Vec3::splat(0.1), [2, 2, 2]);
                    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &cube.rest, &cube.tets, 1000.0);
                    let n = cube.rest.len();
                    let body = TetElastic::new(mesh, material);
                    let start: Vec<Vec3> = cube.rest.iter().map(|p| {
                        let (s, c) = ((twist * p.z).sin(), (twist * p.z).cos());
                        Vec3::new(c * p.x - s * p.y, s * p.x + c * p.y, height * p.z)
                    }).collect();
                    let scene = Scene::new(1.0);
                    let settings = VbdSettings::new().with_line_search_on_increase();
                    let (mut vectors, mut indices) = buffers(n, cube.tets.len());
                    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                    let mut last = Real::INFINITY;
                    let mut redone = 0;
                    // 30 sweeps: in f32 the stretched cube reaches its rounding floor after
                    // about 35, where the per-vertex line search accepts changes within each
                    // vertex's energy resolution, whose sum can exceed the global bound.
                    for k in 0..30 {
                        let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; n]);
                        let report = vbd_step(&body, &masses, &[], &scene, &settings.with_tolerance(0.0, k), &mut x, &mut v, &mut scratch).unwrap();
                        let elastic = mesh.elastic_energy(&material, &x).unwrap();
                        let rounding = Real::EPSILON.sqrt() * (2.0 * report.phi.abs() + elastic.abs());
                        assert!(report.phi <= last + rounding, "{material:?} sweep {k}: {} after {last}", report.phi);
                        last = report.phi;
                        redone = redone.max(report.details.redone_sweeps);
                    }
                    let (mut x, mut v) = (start.clone(), vec![Vec3::ZERO; n]);
                    let report = vbd_step(&body, &masses, &[], &scene, &settings.with_tolerance(1e-3, 400), &mut x, &mut v, &mut scratch).unwrap();
                    assert!(report.converged, "{material:?}: {report:?}");
                    redone
                }
                let stretched = check(StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap(), 3.0, 30.0);
                let squashed = check(StVK::from_young_poisson(1.0e6, 0.3).unwrap(), 0.4, 10.0);
                println!("{}: line search on increase: {stretched} and {squashed} of 30 sweeps redone", stringify!($precision));
            }

            /// The result is a function of the input alone: the same bits from a fresh scratch,
            /// from a scratch full of garbage (NaN vectors, arbitrary indices) and from a scratch
            /// kept across steps, with the line search, contacts and Chebyshev all active.
            #[test]
            fn results_do_not_depend_on_the_scratch_contents() {
                let cube = boxed(Vec3::splat(0.1), [2, 2, 2]);
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &cube.rest, &cube.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap());
                let n = cube.rest.len();
                let t = cube.tets.len();
                // Falling onto a ground 1 mm below, at 1 m/s, sideways too (friction acts).
                let ground = HalfSpace::new(Vec3::Y, -1e-3).with_friction(0.5);
                let scene = Scene::new(1.0 / 60.0).with_gravity(GRAVITY).with_ground(ground);
                let settings = VbdSettings::new().with_tolerance(0.0, 12).with_chebyshev(0.9, 2);
                let run = |vectors: &mut [Vec3], indices: &mut [u32], steps: usize| {
                    let (mut x, mut v) = (cube.rest.clone(), vec![Vec3::new(0.3, -1.0, 0.0); n]);
                    let mut scratch = VbdScratch::new(vectors, indices);
                    for _ in 0..steps {
                        vbd_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                    }
                    (bits(&x), bits(&v))
                };
                let (mut vectors, mut indices) = buffers(n, t);
                let fresh = run(&mut vectors, &mut indices, 2);
                assert_eq!(run(&mut vectors, &mut indices, 2), fresh);
                let mut garbage = vec![Vec3::splat(Real::NAN); scratch_len::vbd(n)];
                let mut noise: Vec<u32> = (0..scratch_len::vbd_indices(n, t) as u32).map(|i| i.wrapping_mul(2_654_435_761)).collect();
                assert_eq!(run(&mut garbage, &mut noise, 2), fresh);
                // One step at a time with fresh scratch each, against two with one scratch.
                let (mut x, mut v) = (cube.rest.clone(), vec![Vec3::new(0.3, -1.0, 0.0); n]);
                for _ in 0..2 {
                    let (mut vectors, mut indices) = buffers(n, t);
                    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                    vbd_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap();
                }
                assert_eq!((bits(&x), bits(&v)), fresh);
                assert!(x.iter().all(|p| p.y >= -1e-3 - 1e-6), "inside the ground");
            }

            #[test]
            fn bad_input_is_refused_with_the_state_untouched() {
                let cube = boxed(Vec3::splat(0.1), [1, 1, 1]);
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &cube.rest, &cube.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = cube.rest.len();
                let t = cube.tets.len();
                let scene = Scene::new(0.01).with_gravity(GRAVITY);
                let good = VbdSettings::new();
                let estimated = good.with_estimated_chebyshev(4);
                let short_previous = vec![Vec3::ZERO; n - 1];
                let mut bad_previous = vec![Vec3::ZERO; n];
                bad_previous[2].y = Real::INFINITY;
                let cases = [
                    (scene.with_previous_velocities(&short_previous), good,
                        StepError::LengthMismatch { buffer: softfem::StepBuffer::PreviousVelocities, expected: n, actual: n - 1 }),
                    (scene.with_previous_velocities(&bad_previous), good, StepError::NonFiniteInput { vertex: 2 }),
                    (Scene { dt: 0.0, ..scene }, good, StepError::TimeStep),
                    (Scene { dt: Real::INFINITY, ..scene }, good, StepError::TimeStep),
                    (scene.with_gravity(Vec3::splat(Real::NAN)), good, StepError::Gravity),
                    (scene, good.with_tolerance(1.0, 10), StepError::VbdSettings),
                    (scene, good.with_tolerance(Real::NAN, 10), StepError::VbdSettings),
                    (scene, VbdSettings { armijo: 1.0, ..good }, StepError::VbdSettings),
                    (scene, VbdSettings { backtrack: 0.0, ..good }, StepError::VbdSettings),
                    (scene, good.with_chebyshev(1.0, 0), StepError::VbdSettings),
                    (scene, good.with_chebyshev(-0.5, 0), StepError::VbdSettings),
                    (scene, good.with_estimated_chebyshev(1), StepError::VbdSettings),
                    (scene, VbdSettings { options: VbdOptions { chebyshev: 0.5, ..estimated.options }, ..estimated },
                        StepError::VbdSettings),
                    (scene.with_ground(HalfSpace::new(Vec3::ZERO, 0.0)), good, StepError::Ground),
                    (scene.with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(-1.0)), good, StepError::Friction),
                ];
                let (mut vectors, mut indices) = buffers(n, t);
                let v0 = vec![Vec3::X; n];
                for (scene, settings, expected) in cases {
                    let (mut x, mut v) = (cube.rest.clone(), v0.clone());
                    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                    let error = vbd_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch).unwrap_err();
                    assert_eq!(error, expected);
                    assert_eq!((bits(&x), bits(&v)), (bits(&cube.rest), bits(&v0)));
                }
                // Buffers and state.
                let mut bad_masses = masses.clone();
                bad_masses[3] = 0.0;
                let mut bad_x = cube.rest.clone();
                bad_x[5].z = Real::NAN;
                let mut short = vec![Vec3::ZERO; scratch_len::vbd(n) - 1];
                let mut short_indices = vec![0; scratch_len::vbd_indices(n, t) + 1];
                let cases: [(&[Real], &[bool], &[Vec3], bool, bool, StepError); 5] = [
                    (&bad_masses, &[], &cube.rest, false, false, StepError::Mass { vertex: 3 }),
                    (&masses, &[true], &cube.rest, false, false,
                        StepError::LengthMismatch { buffer: softfem::StepBuffer::Pinned, expected: n, actual: 1 }),
                    (&masses, &[], &bad_x, false, false, StepError::NonFiniteInput { vertex: 5 }),
                    (&masses, &[], &cube.rest, true, false,
                        StepError::LengthMismatch { buffer: softfem::StepBuffer::Scratch, expected: 5 * n, actual: 5 * n - 1 }),
                    (&masses, &[], &cube.rest, false, true,
                        StepError::LengthMismatch { buffer: softfem::StepBuffer::IndexScratch, expected: 3 * n + 1 + 4 * t, actual: 3 * n + 2 + 4 * t }),
                ];
                for (masses, pinned, x0, short_vectors, long_indices, expected) in cases {
                    let (mut x, mut v) = (x0.to_vec(), v0.clone());
                    let vector_buffer: &mut [Vec3] = if short_vectors { &mut short } else { &mut vectors };
                    let index_buffer: &mut [u32] = if long_indices { &mut short_indices } else { &mut indices };
                    let mut scratch = VbdScratch::new(vector_buffer, index_buffer);
                    let error = vbd_step(&body, masses, pinned, &scene, &good, &mut x, &mut v, &mut scratch).unwrap_err();
                    assert_eq!(error, expected);
                    assert_eq!((bits(&x), bits(&v)), (bits(x0), bits(&v0)));
                    let error = vbd_quasi_static(&body, masses, pinned, &scene, &good, &mut x, &mut scratch).unwrap_err();
                    assert_eq!(error, expected);
                    assert_eq!(bits(&x), bits(x0));
                }
            }

            /// The quasi-static solve without gravity from the rest shape is at equilibrium at
            /// once (zero sweeps), and pinned vertices never move.
            #[test]
            fn rest_is_an_equilibrium_without_load() {
                let cube = boxed(Vec3::splat(0.1), [1, 1, 1]);
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &cube.rest, &cube.tets, 1000.0);
                let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap());
                let n = cube.rest.len();
                let (mut vectors, mut indices) = buffers(n, cube.tets.len());
                let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                let mut x = cube.rest.clone();
                let report = vbd_quasi_static(&body, &masses, &[], &Scene::new(1.0), &VbdSettings::new(), &mut x, &mut scratch).unwrap();
                assert!(report.converged && report.iterations == 0, "{report:?}");
                assert_eq!(x, cube.rest);
                let _ = Material::energy_density(&body.material, Mat3::IDENTITY);
            }

            /// The colour-parallel sweeps of a `ParallelTetElastic` model give the sequential
            /// solver's bits, positions, velocities and reports, on pools of 1, 2, 3 and 8
            /// threads (the model's own, `with_pool`, and the current one, `install`), with and
            /// without the packed layout: the [`pressed`] scene (8 colours of 43 or more
            /// vertices, over the 32 a task takes, so every colour is split), three steps and
            /// a quasi-static sag.
            #[cfg(feature = "rayon")]
            #[test]
            fn parallel_sweeps_give_the_sequential_bits_for_any_thread_count() {
                use $($api)::+::mesh::{TetPartition, partition_incident_len, partition_offsets_len};
                use $($api)::+::parallel::ParallelTetElastic;
                /// `run` of `body` made parallel (8 pieces), on `pool` if given.
                fn on_parallel<R>(
                    body: &TetElastic<'_, StVK>,
                    pool: Option<&rayon::ThreadPool>,
                    run: impl FnOnce(&ParallelTetElastic<'_, StVK>) -> R,
                ) -> R {
                    let (n, t) = (body.mesh.vertex_count(), body.mesh.element_count());
                    let (mut offsets, mut incident) = (vec![0; partition_offsets_len(n)], vec![0; partition_incident_len(t)]);
                    let partition = TetPartition::new(body.mesh, 8, &mut offsets, &mut incident).unwrap();
                    let (mut element_forces, mut energies) = (vec![[Vec3::ZERO; 4]; t], vec![0.0; t]);
                    let model = ParallelTetElastic::new(*body, partition, &mut element_forces, &mut energies).unwrap();
                    match pool {
                        Some(pool) => run(&model.with_pool(pool)),
                        None => run(&model),
                    }
                }
                let scene = pressed();
                let cube = &scene.cube;
                let (n, t) = (cube.rest.len(), cube.tets.len());
                // The colouring splits every colour over several tasks.
                let (mut offsets, mut incident) = (vec![0; n + 1], vec![0; 4 * t]);
                softfem::mesh::build_vertex_adjacency(&cube.tets, n, &mut offsets, &mut incident).unwrap();
                let mut colours = vec![0; n];
                let count = softfem::mesh::colour_vertices(&cube.tets, &offsets, &incident, &mut colours).unwrap();
                let smallest = (0..count).map(|c| colours.iter().filter(|&&k| k == c).count()).min().unwrap();
                assert!(smallest > 32, "{count} colours, the smallest of {smallest} vertices");
                let sequential = pressed_sequential(&scene, None);
                let full = (scratch_len::vbd_layout(t), scratch_len::vbd_layout_corners(n, t));
                for threads in [1, 2, 3, 8] {
                    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                    for (layout, own_pool) in [(None, false), (Some(full), false), (None, true), (Some(full), true)] {
                        let model_pool = own_pool.then_some(&pool);
                        let run = || {
                            pressed_run(
                                &scene,
                                layout,
                                &|body, pressed, scene, settings, x, v, scratch| {
                                    on_parallel(body, model_pool, |model| {
                                        format!("{:?}", vbd_step(model, &pressed.masses, &pressed.pinned, scene, settings, x, v, scratch).unwrap())
                                    })
                                },
                                &|body, pressed, scene, settings, x, scratch| {
                                    on_parallel(body, model_pool, |model| {
                                        format!("{:?}", vbd_quasi_static(model, &pressed.masses, &pressed.pinned, scene, settings, x, scratch).unwrap())
                                    })
                                },
                            )
                        };
                        let parallel = if own_pool { run() } else { pool.install(run) };
                        assert_eq!(parallel.3, layout.is_some());
                        assert!(
                            (&parallel.0, &parallel.1, &parallel.2) == (&sequential.0, &sequential.1, &sequential.2),
                            "{threads} threads (the model's pool: {own_pool}), layout {}: {:?} vs {:?}",
                            layout.is_some(),
                            parallel.2,
                            sequential.2
                        );
                    }
                }
            }
        }
    };
}

// f32: the differences of the reference Hessian lose ~1e-3 of the step to rounding.
vbd_tests!(single, softfem, 2e-2);
vbd_tests!(double, softfem::f64, 1e-6);

/// The adjacency lists each vertex's (element, corner) pairs in element order, exactly those of
/// a brute-force scan; the colouring gives the four corners of every element four different
/// colours and is the greedy one (each vertex's colour is the smallest its earlier neighbours
/// leave free: every smaller colour is held by one of them); the order lists every vertex once,
/// by colour, then index.
#[test]
fn adjacency_and_colouring_are_valid_and_greedy() {
    use softfem::generate::{BoxSplit, box_counts, fill_box};
    use softfem::glam::Vec3;
    for (cells, split) in [
        ([3, 2, 2], BoxSplit::Kuhn6),
        ([4, 3, 2], BoxSplit::Alternating5),
    ] {
        let [nx, ny, nz] = cells;
        let (rest, mut tets) =
            crate::common::scenes::generated_box!(Vec3::ZERO, Vec3::ONE, (nx, ny, nz), split);
        let (nv, nt) = (rest.len(), tets.len());
        // Shuffle the elements (deterministically) so that the order is not the generator's.
        let mut rng = crate::common::Rng::new(7);
        for i in (1..nt).rev() {
            let j = (rng.next_u64() % (i as u64 + 1)) as usize;
            tets.swap(i, j);
        }
        let mut offsets = vec![u32::MAX; adjacency_offsets_len(nv)];
        let mut incident = vec![u32::MAX; adjacency_incident_len(nt)];
        build_vertex_adjacency(&tets, nv, &mut offsets, &mut incident).unwrap();
        for v in 0..nv {
            let expected: Vec<u32> = (0..nt)
                .flat_map(|e| (0..4).map(move |c| (e, c)))
                .filter(|&(e, c)| tets[e][c] as usize == v)
                .map(|(e, c)| (4 * e + c) as u32)
                .collect();
            let row = &incident[offsets[v] as usize..offsets[v + 1] as usize];
            assert_eq!(row, &expected[..], "vertex {v}");
        }
        let mut colours = vec![u32::MAX; nv];
        let count = colour_vertices(&tets, &offsets, &incident, &mut colours).unwrap();
        for (e, corners) in tets.iter().enumerate() {
            for a in 0..4 {
                for b in a + 1..4 {
                    assert_ne!(
                        colours[corners[a] as usize], colours[corners[b] as usize],
                        "element {e}"
                    );
                }
            }
        }
        let neighbours = |v: usize| -> Vec<usize> {
            let mut all: Vec<usize> = tets
                .iter()
                .filter(|t| t.contains(&(v as u32)))
                .flatten()
                .map(|&u| u as usize)
                .filter(|&u| u != v)
                .collect();
            all.sort_unstable();
            all.dedup();
            all
        };
        let mut most = 0;
        for v in 0..nv {
            let earlier: Vec<u32> = neighbours(v)
                .into_iter()
                .filter(|&u| u < v)
                .map(|u| colours[u])
                .collect();
            for smaller in 0..colours[v] {
                assert!(
                    earlier.contains(&smaller),
                    "vertex {v}: colour {} but {smaller} is free",
                    colours[v]
                );
            }
            most = most.max(neighbours(v).len());
        }
        assert_eq!(count, colours.iter().max().unwrap() + 1);
        assert!(count as usize <= most + 1);
        let mut order = vec![u32::MAX; nv];
        vertex_order(&colours, count, &mut order).unwrap();
        let keys: Vec<(u32, u32)> = order.iter().map(|&v| (colours[v as usize], v)).collect();
        let mut sorted = keys.clone();
        sorted.sort_unstable();
        assert_eq!(keys, sorted);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..nv as u32).collect::<Vec<_>>());
        println!("{cells:?} {split:?}: {count} colours, at most {most} neighbours");
    }
    // Refusals: wrong lengths and an index beyond the vertex count; nothing written.
    let tets = [[0, 1, 2, 3], [1, 2, 3, 9]];
    let (mut offsets, mut incident) = (vec![7; 6], vec![7; 8]);
    assert_eq!(
        build_vertex_adjacency(&tets, 5, &mut offsets, &mut incident),
        Err(StepError::VertexIndex {
            element: 1,
            index: 9
        })
    );
    assert_eq!((offsets[0], incident[0]), (7, 7));
    assert!(matches!(
        build_vertex_adjacency(&tets, 5, &mut offsets[..5], &mut incident),
        Err(StepError::LengthMismatch { .. })
    ));
    let mut colours = [0; 4];
    assert!(matches!(
        colour_vertices(&tets, &offsets, &incident, &mut colours),
        Err(StepError::LengthMismatch { .. })
    ));
}

/// The quasi-static cantilever of tests/steppers/relax.rs (0.4 m bar, 4 x 1 x 1 cubes, stable
/// neo-Hookean E = 1 MPa, nu = 0.3, pinned at x = 0, f64): VBD and the relaxation, both to 1e-8 of
/// the gravity load, reach the same equilibrium. Both stop at `|grad Phi| <= r = 1e-8 |M g|`; with
/// `K >= k_min I` near the solution `|x - x*| <= r / k_min` for each, and k_min, the bending
/// stiffness of the slowest mode (~|M g| / sag), makes this ~1e-8 sag per vertex: 1e-6 sag
/// leaves a factor 100 for sqrt(n) and the mode shapes.
#[test]
fn quasi_static_cantilever_reaches_the_relaxations_equilibrium() {
    use softfem::f64::element::TetRest;
    use softfem::f64::generate::{BoxSplit, box_counts, fill_box};
    use softfem::f64::material::StableNeoHookean;
    use softfem::f64::mesh::TetMesh;
    use softfem::f64::step::{
        RelaxScratch, RelaxSettings, Scene, TetElastic, VbdScratch, VbdSettings,
        relax_quasi_static, scratch_len, vbd_quasi_static,
    };
    use softfem::glam::DVec3 as Vec3;
    let max = Vec3::new(0.4, 0.1, 0.1);
    let (rest, tets) =
        crate::common::scenes::generated_box!(Vec3::ZERO, max, (4, 1, 1), BoxSplit::Kuhn6);
    let (nv, nt) = (rest.len(), tets.len());
    let pinned: Vec<bool> = rest.iter().map(|p| p.x == 0.0).collect();
    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
    let body = TetElastic::new(
        mesh,
        StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap(),
    );
    let gravity = Vec3::new(0.0, -9.81, 0.0);
    let tolerance = 1e-8;

    let scene = Scene::new(1.0).with_gravity(gravity);
    let settings = RelaxSettings::new()
        .with_tolerance(tolerance, 200_000)
        .with_chebyshev(0.999, 2.0, 0);
    let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(nv)], vec![0.0; nv]);
    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
    let mut x_relax = rest.clone();
    let relax = relax_quasi_static(
        &body,
        &masses,
        &pinned,
        &scene,
        &settings,
        &mut x_relax,
        &mut scratch,
    )
    .unwrap();

    let settings = VbdSettings::new().with_tolerance(tolerance, 20_000);
    let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(nv)];
    let mut indices = vec![0; scratch_len::vbd_indices(nv, nt)];
    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
    let mut x_vbd = rest.clone();
    let vbd = vbd_quasi_static(
        &body,
        &masses,
        &pinned,
        &scene,
        &settings,
        &mut x_vbd,
        &mut scratch,
    )
    .unwrap();

    let sag = rest
        .iter()
        .zip(&x_relax)
        .map(|(r, x)| r.y - x.y)
        .fold(0.0, f64::max);
    let difference = x_vbd
        .iter()
        .zip(&x_relax)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0, f64::max);
    println!("relax {relax:?}\nvbd {vbd:?}\nsag {sag:.4e} m, |x_vbd - x_relax| {difference:.2e} m");
    assert!(relax.converged && vbd.converged);
    assert!(sag > 0.005 && sag < 0.1);
    assert!(difference <= 1e-6 * sag, "{difference}");
    for ((x, r), p) in x_vbd.iter().zip(&rest).zip(&pinned) {
        if *p {
            assert_eq!(x, r);
        }
    }
}

/// Wall time and iterations of VBD against the relaxation with the bouncy example's GD +
/// Chebyshev settings, each stepper running its own trajectory to the same relative residual
/// (the two share the stopping test), and the cost of a sweep in force evaluations. Timings,
/// so not checks: run `cargo test --release --all-features --test steppers vbd::measure --
/// --ignored --nocapture --test-threads 1`. Columns: scene | solver | steps | converged steps |
/// iterations | fused energy-and-force evaluations | wall s | s per step.
#[test]
#[ignore]
fn measure_bouncy_cube() {
    measure::bouncy_cube();
}

/// See [`measure_bouncy_cube`].
#[test]
#[ignore]
fn measure_stiff_block() {
    measure::stiff_block(false);
    measure::stiff_block(true);
}

/// See [`measure_bouncy_cube`].
#[test]
#[ignore]
fn measure_sweep_cost() {
    measure::sweep_cost();
}

/// The scenes of the `measure_*` tests.
mod measure {
    use std::time::Instant;

    /// One row of the table.
    pub fn row(
        scene: &str,
        solver: &str,
        steps: usize,
        converged: usize,
        iterations: u64,
        evaluations: u64,
        seconds: f64,
    ) {
        println!(
            "{scene} | {solver} | {steps} | {converged} | {iterations} | {evaluations} | {seconds:.3} | {:.2e}",
            seconds / steps as f64
        );
    }

    /// What one step of a solver reports.
    pub struct Outcome {
        pub converged: bool,
        pub iterations: u32,
        pub evaluations: u32,
        pub rho: f64,
    }

    /// A solver of a scene: its name and one step (`step(k)` runs step `k`, resetting the state
    /// at `k = 0`).
    pub type Solver<'a> = (String, Box<dyn FnMut(usize) -> Outcome + 'a>);

    /// Runs every solver's trajectory `repeats` times, interleaved step by step (step `k` of
    /// every solver, then step `k + 1`), so that all see the same machine load, and prints one
    /// row per solver with the sum over steps of each step's least time over the repeats (the
    /// trajectories are deterministic, so every repeat does the same work, and interference
    /// only adds time), and the ratio to the first solver's.
    ///
    /// A step longer than a time slice of a loaded machine is preempted in every repeat, so the
    /// least wall time still counts other processes' time, the more the longer the step. The
    /// rows therefore also give the thread's CPU time (Linux: the first field of
    /// `/proc/thread-self/schedstat`, updated at the scheduler's ticks and switches, so one
    /// reading can lag by a tick, which averages out over the steps), summed over the steps and
    /// divided by the repeats.
    pub fn interleaved(scene: &str, steps: usize, repeats: usize, solvers: &mut [Solver<'_>]) {
        let cpu = || {
            std::fs::read_to_string("/proc/thread-self/schedstat")
                .ok()
                .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
                .map_or(f64::NAN, |ns| ns * 1e-9)
        };
        let mut least = vec![vec![f64::MAX; steps]; solvers.len()];
        let mut cpu_time = vec![0.0; solvers.len()];
        let mut counts = vec![(0usize, 0u64, 0u64, 0.0f64); solvers.len()];
        for _ in 0..repeats {
            counts.iter_mut().for_each(|c| *c = (0, 0, 0, 0.0));
            for k in 0..steps {
                for (((_, step), (least, count)), cpu_time) in solvers
                    .iter_mut()
                    .zip(least.iter_mut().zip(&mut counts))
                    .zip(&mut cpu_time)
                {
                    let (start, cpu_start) = (Instant::now(), cpu());
                    let outcome = step(k);
                    least[k] = least[k].min(start.elapsed().as_secs_f64());
                    *cpu_time += (cpu() - cpu_start) / repeats as f64;
                    count.0 += usize::from(outcome.converged);
                    count.1 += u64::from(outcome.iterations);
                    count.2 += u64::from(outcome.evaluations);
                    count.3 = count.3.max(outcome.rho);
                }
            }
        }
        let totals: Vec<f64> = least.iter().map(|l| l.iter().sum()).collect();
        let cpu_time_first = cpu_time[0];
        let rows = solvers.iter().zip(&totals).zip(&counts).zip(&cpu_time);
        for ((((name, _), total), count), cpu_time) in rows {
            row(
                scene,
                &format!(
                    "{name} (largest rho {:.3}; {:.2}x the first's wall time; CPU {:.3} s, \
                     {:.2}x the first's)",
                    count.3,
                    total / totals[0],
                    cpu_time,
                    cpu_time / cpu_time_first
                ),
                steps,
                count.0,
                count.1,
                count.2,
                *total,
            );
        }
    }

    /// The bouncy example's jelly cube (0.2 m, 6^3 cells, 1296 tets, stable neo-Hookean
    /// E = 5e4 Pa, nu = 0.45, 1000 kg/m^3) dropped from 0.5 m onto z = 0 with friction 0.6,
    /// 180 steps of 1/60 s, f32; relaxation: tolerance 2e-3, 300 iterations, Chebyshev 0.995,
    /// step 2 (examples/bouncy/main.rs).
    pub fn bouncy_cube() {
        use softfem::element::TetRest;
        use softfem::generate::{BoxSplit, box_counts, fill_box};
        use softfem::glam::Vec3;
        use softfem::material::StableNeoHookean;
        use softfem::mesh::TetMesh;
        use softfem::step::*;
        let (min, max) = (Vec3::new(-0.1, -0.1, 0.5), Vec3::new(0.1, 0.1, 0.7));
        let (rest, tets) =
            crate::common::scenes::generated_box!(min, max, (6, 6, 6), BoxSplit::Kuhn6);
        let (nv, nt) = (rest.len(), tets.len());
        crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
        let body = TetElastic::new(
            mesh,
            StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap(),
        );
        let gravity = Vec3::new(0.0, 0.0, -9.81);
        let ground = HalfSpace::new(Vec3::Z, 0.0).with_friction(0.6);
        let (dt, tolerance, steps) = (1.0 / 60.0, 2e-3, 180);
        let title = format!("bouncy cube {nt} tets 1/60 s f32");

        let scene = Scene::new(dt).with_gravity(gravity).with_ground(ground);
        let settings = RelaxSettings::new()
            .with_tolerance(tolerance, 300)
            .with_chebyshev(0.995, 2.0, 0);
        let (body, masses, rest) = (&body, &masses, &rest);
        let mut solvers: Vec<Solver<'_>> = Vec::new();
        {
            let (mut vectors, mut scalars) =
                (vec![Vec3::ZERO; scratch_len::relax(nv)], vec![0.0; nv]);
            let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; nv]);
            solvers.push((
                "GD+Chebyshev 0.995".into(),
                Box::new(move |k| {
                    if k == 0 {
                        x.copy_from_slice(rest);
                        v.fill(Vec3::ZERO);
                    }
                    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                    let r = relax_step(
                        body,
                        masses,
                        &[],
                        &scene,
                        &settings,
                        &mut x,
                        &mut v,
                        &mut scratch,
                    )
                    .unwrap();
                    if k + 1 == steps {
                        assert!(x.iter().all(|p| p.z >= -1e-5));
                    }
                    Outcome {
                        converged: r.converged,
                        iterations: r.iterations,
                        evaluations: r.energy_evaluations,
                        rho: 0.0,
                    }
                }),
            ));
        }
        for (name, vbd) in variants(VbdSettings::new().with_tolerance(tolerance, 300)) {
            let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(nv)];
            let mut indices = vec![0; scratch_len::vbd_indices(nv, nt)];
            let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; nv]);
            solvers.push((
                format!("VBD {name}"),
                Box::new(move |k| {
                    if k == 0 {
                        x.copy_from_slice(rest);
                        v.fill(Vec3::ZERO);
                    }
                    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                    let r = vbd_step(
                        body,
                        masses,
                        &[],
                        &scene,
                        &vbd,
                        &mut x,
                        &mut v,
                        &mut scratch,
                    )
                    .unwrap();
                    if k + 1 == steps {
                        assert!(x.iter().all(|p| p.z >= -1e-5));
                    }
                    Outcome {
                        converged: r.converged,
                        iterations: r.iterations,
                        evaluations: r.energy_evaluations,
                        rho: f64::from(r.rho),
                    }
                }),
            ));
        }
        interleaved(&title, steps, 3, &mut solvers);
    }

    /// The VBD settings measured.
    fn variants<S: Copy + VbdLike>(base: S) -> Vec<(&'static str, S)> {
        vec![
            ("line search", base),
            ("no line search", base.line_search(0)),
            (
                "no line search + Chebyshev 0.9",
                base.line_search(0).chebyshev(0.9),
            ),
            (
                "no line search + Chebyshev 0.95",
                base.line_search(0).chebyshev(0.95),
            ),
            (
                "no line search + estimated rho",
                base.line_search(0).estimated(),
            ),
            ("line search + estimated rho", base.estimated()),
            (
                "full steps, line search on increase + Chebyshev 0.95",
                base.guarded().chebyshev(0.95),
            ),
            (
                "full steps, line search on increase + estimated rho",
                base.guarded().estimated(),
            ),
        ]
    }

    /// The two precisions' settings, for [`variants`].
    pub trait VbdLike: Sized {
        fn line_search(self, backtracks: u32) -> Self;
        fn chebyshev(self, rho: f64) -> Self;
        fn estimated(self) -> Self;
        fn guarded(self) -> Self;
    }
    impl VbdLike for softfem::step::VbdSettings {
        fn line_search(self, backtracks: u32) -> Self {
            self.with_line_search(backtracks)
        }
        fn chebyshev(self, rho: f64) -> Self {
            self.with_chebyshev(rho as f32, 2)
        }
        fn estimated(self) -> Self {
            self.with_estimated_chebyshev(4)
        }
        fn guarded(self) -> Self {
            self.with_line_search_on_increase()
        }
    }
    impl VbdLike for softfem::f64::step::VbdSettings {
        fn line_search(self, backtracks: u32) -> Self {
            self.with_line_search(backtracks)
        }
        fn chebyshev(self, rho: f64) -> Self {
            self.with_chebyshev(rho, 2)
        }
        fn estimated(self) -> Self {
            self.with_estimated_chebyshev(4)
        }
        fn guarded(self) -> Self {
            self.with_line_search_on_increase()
        }
    }

    /// The stability chart's stiff block (0.1 x 0.05 x 0.05 m, 4 x 2 x 2 cubes, 96 tets, stable
    /// neo-Hookean E = 1e8 Pa, nu = 0.3), perturbed by 1e-3 of a cell, 30 steps of 1/30 s, f64;
    /// relaxation: tolerance 1e-4, 500 iterations, Chebyshev 0.995, step 2
    /// (examples/tradeoffs/stability_map.rs). `loaded: false` is the chart's scene, free and
    /// without gravity: once it has settled (two steps), every step starts at the rounding
    /// floor and 1e-4 of that is out of reach for both solvers, which then use their whole
    /// budget. `loaded: true` clamps the end x = 0 and adds gravity, so that the target,
    /// 1e-4 of the load, stays above the floor.
    pub fn stiff_block(loaded: bool) {
        use softfem::f64::element::TetRest;
        use softfem::f64::generate::{BoxSplit, box_counts, fill_box};
        use softfem::f64::material::StableNeoHookean;
        use softfem::f64::mesh::TetMesh;
        use softfem::f64::step::*;
        use softfem::glam::DVec3 as Vec3;
        let (rest, tets) = crate::common::scenes::generated_box!(
            Vec3::ZERO,
            Vec3::new(0.1, 0.05, 0.05),
            (4, 2, 2),
            BoxSplit::Kuhn6
        );
        let (nv, nt) = (rest.len(), tets.len());
        crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
        let body = TetElastic::new(
            mesh,
            StableNeoHookean::from_young_poisson(1.0e8, 0.3).unwrap(),
        );
        let mut rng = crate::common::Rng::new(3);
        let amplitude = 1e-3 * 0.025;
        let start_x: Vec<Vec3> = rest
            .iter()
            .map(|&p| {
                p + Vec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5)
                    * (2.0 * amplitude)
            })
            .collect();
        let (dt, tolerance, steps) = (1.0 / 30.0, 1e-4, 30);
        let (pinned, gravity): (Vec<bool>, Vec3) = if loaded {
            (
                rest.iter().map(|p| p.x == 0.0).collect(),
                Vec3::new(0.0, -9.81, 0.0),
            )
        } else {
            (Vec::new(), Vec3::ZERO)
        };
        let start_x: Vec<Vec3> = start_x
            .iter()
            .zip(&rest)
            .enumerate()
            .map(|(i, (x, r))| if pinned.get(i) == Some(&true) { *r } else { *x })
            .collect();
        let title = format!(
            "stiff block {nt} tets 1/30 s f64{}",
            if loaded {
                ", clamped, gravity"
            } else {
                ", free"
            }
        );

        let scene = Scene::new(dt).with_gravity(gravity);
        let settings = RelaxSettings::new()
            .with_tolerance(tolerance, 500)
            .with_chebyshev(0.995, 2.0, 0);
        let (body, masses, pinned, start_x) = (&body, &masses, &pinned, &start_x);
        let trace = std::env::var("VBD_TRACE").is_ok();
        let mut solvers: Vec<Solver<'_>> = Vec::new();
        {
            let (mut vectors, mut scalars) =
                (vec![Vec3::ZERO; scratch_len::relax(nv)], vec![0.0; nv]);
            let (mut x, mut v) = (start_x.clone(), vec![Vec3::ZERO; nv]);
            solvers.push((
                "GD+Chebyshev 0.995".into(),
                Box::new(move |k| {
                    if k == 0 {
                        x.copy_from_slice(start_x);
                        v.fill(Vec3::ZERO);
                    }
                    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                    let r = relax_step(
                        body,
                        masses,
                        pinned,
                        &scene,
                        &settings,
                        &mut x,
                        &mut v,
                        &mut scratch,
                    )
                    .unwrap();
                    if trace {
                        println!(
                            "  relax: {} iterations, residual {:.3e} -> {:.3e}",
                            r.iterations, r.initial_residual, r.residual
                        );
                    }
                    Outcome {
                        converged: r.converged,
                        iterations: r.iterations,
                        evaluations: r.energy_evaluations,
                        rho: 0.0,
                    }
                }),
            ));
        }
        for (name, vbd) in variants(VbdSettings::new().with_tolerance(tolerance, 500)) {
            let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(nv)];
            let mut indices = vec![0; scratch_len::vbd_indices(nv, nt)];
            let (mut x, mut v) = (start_x.clone(), vec![Vec3::ZERO; nv]);
            solvers.push((
                format!("VBD {name}"),
                Box::new(move |k| {
                    if k == 0 {
                        x.copy_from_slice(start_x);
                        v.fill(Vec3::ZERO);
                    }
                    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                    let r = vbd_step(body, masses, pinned, &scene, &vbd, &mut x, &mut v, &mut scratch)
                        .unwrap();
                    if trace {
                        println!(
                            "  {name}: {} sweeps, residual {:.3e} -> {:.3e}, rho {:.3}, {} restarts",
                            r.iterations, r.initial_residual, r.residual, r.rho, r.restarts
                        );
                    }
                    Outcome {
                        converged: r.converged,
                        iterations: r.iterations,
                        evaluations: r.energy_evaluations,
                        rho: r.rho,
                    }
                }),
            ));
        }
        interleaved(&title, steps, 3, &mut solvers);
    }

    /// A sweep's cost in force evaluations on the bouncy cube's mesh (f32), released from a
    /// stretch of 5 % / -3 %: 20 VBD iterations at tolerance 0 (one sweep and one fused
    /// energy-and-force pass each; 20, so that the iterates stay above the rounding floor,
    /// where the line search needs the trial gradient too) against 20 fused passes and 20
    /// force-only passes, each the least of 5 repeats.
    pub fn sweep_cost() {
        use softfem::element::TetRest;
        use softfem::generate::{BoxSplit, box_counts, fill_box};
        use softfem::glam::Vec3;
        use softfem::material::StableNeoHookean;
        use softfem::mesh::TetMesh;
        use softfem::step::*;
        let (rest, tets) = crate::common::scenes::generated_box!(
            Vec3::splat(-0.1),
            Vec3::splat(0.1),
            (6, 6, 6),
            BoxSplit::Kuhn6
        );
        let (nv, nt) = (rest.len(), tets.len());
        crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
        let material = StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap();
        let body = TetElastic::new(mesh, material);
        let x: Vec<Vec3> = rest
            .iter()
            .map(|p| *p * Vec3::new(1.05, 0.97, 1.0))
            .collect();
        let rounds = 20;
        // The least of five repeats: the machine is shared, and interference only adds time.
        let least = |run: &mut dyn FnMut()| {
            (0..5)
                .map(|_| {
                    let start = Instant::now();
                    run();
                    start.elapsed().as_secs_f64()
                })
                .fold(f64::MAX, f64::min)
        };
        let mut forces = vec![Vec3::ZERO; nv];
        let force = least(&mut || {
            for _ in 0..rounds {
                forces.fill(Vec3::ZERO);
                mesh.add_elastic_forces(&material, &x, &mut forces).unwrap();
            }
        }) / rounds as f64;
        let fused = least(&mut || {
            for _ in 0..rounds {
                forces.fill(Vec3::ZERO);
                std::hint::black_box(body.energy_and_add_forces(&x, &mut forces).unwrap());
            }
        }) / rounds as f64;
        let scene = Scene::new(1.0 / 60.0);
        let line_search = VbdSettings::new().with_tolerance(0.0, rounds);
        let plain = line_search.with_line_search(0);
        for (name, settings, packed) in [
            ("line search", line_search, false),
            ("line search, packed layout", line_search, true),
            ("no line search", plain, false),
            ("no line search, packed layout", plain, true),
        ] {
            let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(nv)];
            let mut indices = vec![0; scratch_len::vbd_indices(nv, nt)];
            let mut values = vec![0.0; scratch_len::vbd_layout(nt)];
            let mut corners = vec![0; scratch_len::vbd_layout_corners(nv, nt)];
            let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
            if packed {
                scratch = scratch.with_layout(&mut values, &mut corners);
            }
            // Build the topology outside the timing.
            vbd_step(
                &body,
                &masses,
                &[],
                &scene,
                &settings.with_tolerance(0.0, 0),
                &mut x.clone(),
                &mut vec![Vec3::ZERO; nv],
                &mut scratch,
            )
            .unwrap();
            let mut iterations = 0;
            let total = least(&mut || {
                let (mut y, mut v) = (x.clone(), vec![Vec3::ZERO; nv]);
                iterations = vbd_step(
                    &body,
                    &masses,
                    &[],
                    &scene,
                    &settings,
                    &mut y,
                    &mut v,
                    &mut scratch,
                )
                .unwrap()
                .iterations;
            });
            // The initial guess costs one fused pass (no gravity: one candidate).
            let per_iteration = (total - fused) / f64::from(iterations);
            let sweep = per_iteration - fused;
            println!(
                "sweep cost ({nt} tets, f32, {name}): force pass {:.1} us, fused energy+force {:.1} us, \
                 VBD iteration {:.1} us = sweep {:.1} us + fused pass; sweep = {:.2} force passes",
                force * 1e6,
                fused * 1e6,
                per_iteration * 1e6,
                sweep * 1e6,
                sweep / force
            );
            // The same from short blocks, interleaved, the least of many: a block of about a
            // millisecond fits in one time slice of a loaded machine, where the 20-iteration
            // blocks above are often preempted. The marginal iteration `T(3) - T(1)` over two
            // sweeps drops the call's fixed cost.
            let mut single = |budget: u32| {
                let (mut y, mut v) = (x.clone(), vec![Vec3::ZERO; nv]);
                let start = Instant::now();
                let r = vbd_step(
                    &body,
                    &masses,
                    &[],
                    &scene,
                    &settings.with_tolerance(0.0, budget),
                    &mut y,
                    &mut v,
                    &mut scratch,
                )
                .unwrap();
                assert_eq!(r.iterations, budget);
                start.elapsed().as_secs_f64()
            };
            let (mut one, mut three, mut pass, mut fused_pass) =
                (f64::MAX, f64::MAX, f64::MAX, f64::MAX);
            for _ in 0..60 {
                one = one.min(single(1));
                three = three.min(single(3));
                let start = Instant::now();
                forces.fill(Vec3::ZERO);
                mesh.add_elastic_forces(&material, &x, &mut forces).unwrap();
                pass = pass.min(start.elapsed().as_secs_f64());
                let start = Instant::now();
                forces.fill(Vec3::ZERO);
                std::hint::black_box(body.energy_and_add_forces(&x, &mut forces).unwrap());
                fused_pass = fused_pass.min(start.elapsed().as_secs_f64());
            }
            let sweep = (three - one) / 2.0 - fused_pass;
            println!(
                "sweep cost, short blocks ({nt} tets, f32, {name}): force pass {:.1} us, fused {:.1} us, \
                 sweep {:.1} us = {:.2} force passes ({:.0} ns per element visit)",
                pass * 1e6,
                fused_pass * 1e6,
                sweep * 1e6,
                sweep / pass,
                sweep * 1e9 / (4 * nt) as f64
            );
        }
    }
}

/// One implicit Euler step of a cube landing on a frictional ground (f64): VBD's exact local
/// contact solve and the relaxation's projected descent reach the same constrained minimiser
/// (`Phi` is strictly convex near rest, its Hessian at least `M / h^2`, so the minimiser on the
/// half-space is unique), and the friction pass gives the same velocities. Both stop at
/// `|grad Phi| <= r = 1e-9 |M g|`, so each is within `r h^2 / m_min` of the minimiser: 1e-9 of
/// the one-step drop, well below the 1e-6 of it asserted.
#[test]
fn landing_step_matches_the_relaxation_with_contact_and_friction() {
    use softfem::f64::element::TetRest;
    use softfem::f64::generate::{BoxSplit, box_counts, fill_box};
    use softfem::f64::material::StableNeoHookean;
    use softfem::f64::mesh::TetMesh;
    use softfem::f64::step::{
        HalfSpace, RelaxScratch, RelaxSettings, Scene, TetElastic, VbdScratch, VbdSettings,
        relax_step, scratch_len, vbd_step,
    };
    use softfem::glam::DVec3 as Vec3;
    let (nv, nt) = box_counts(2, 2, 2, BoxSplit::Kuhn6).unwrap();
    let mut rest = vec![Vec3::ZERO; nv];
    let mut tets = vec![[0; 4]; nt];
    // 2 mm above the ground, falling at 0.5 m/s and sliding at 0.3 m/s: the bottom reaches
    // the ground within the 1/60 s step.
    let (min, max) = (Vec3::new(0.0, 0.0, 0.002), Vec3::new(0.1, 0.1, 0.102));
    fill_box(min, max, 2, 2, 2, BoxSplit::Kuhn6, &mut rest, &mut tets).unwrap();
    crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &rest, &tets, 1000.0);
    let body = TetElastic::new(
        mesh,
        StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap(),
    );
    let gravity = Vec3::new(0.0, 0.0, -9.81);
    let ground = HalfSpace::new(Vec3::Z, 0.0).with_friction(0.6);
    let (h, tolerance) = (1.0 / 60.0, 1e-9);
    let v0 = vec![Vec3::new(0.3, 0.0, -0.5); nv];

    let scene = Scene::new(h).with_gravity(gravity).with_ground(ground);
    let settings = RelaxSettings::new()
        .with_tolerance(tolerance, 100_000)
        .with_chebyshev(0.995, 2.0, 0);
    let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(nv)], vec![0.0; nv]);
    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
    let (mut x_relax, mut v_relax) = (rest.clone(), v0.clone());
    let relax = relax_step(
        &body,
        &masses,
        &[],
        &scene,
        &settings,
        &mut x_relax,
        &mut v_relax,
        &mut scratch,
    )
    .unwrap();

    let settings = VbdSettings::new().with_tolerance(tolerance, 10_000);
    let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(nv)];
    let mut indices = vec![0; scratch_len::vbd_indices(nv, nt)];
    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
    let (mut x_vbd, mut v_vbd) = (rest.clone(), v0.clone());
    let vbd = vbd_step(
        &body,
        &masses,
        &[],
        &scene,
        &settings,
        &mut x_vbd,
        &mut v_vbd,
        &mut scratch,
    )
    .unwrap();

    let contacts = x_vbd.iter().filter(|p| p.z <= 1e-12).count();
    let drop = rest
        .iter()
        .zip(&x_relax)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0, f64::max);
    let dx = x_vbd
        .iter()
        .zip(&x_relax)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0, f64::max);
    let dv = v_vbd
        .iter()
        .zip(&v_relax)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0, f64::max);
    println!(
        "relax {relax:?}\nvbd {vbd:?}\n{contacts} vertices on the ground; drop {drop:.3e} m, |dx| {dx:.2e} m, |dv| {dv:.2e} m/s"
    );
    assert!(relax.converged && vbd.converged);
    assert!(contacts >= 9, "the bottom face lands: {contacts}");
    assert!(x_vbd.iter().all(|p| p.z >= 0.0));
    assert!(dx <= 1e-6 * drop, "{dx}");
    assert!(dv <= 1e-6 * drop / h, "{dv}");
    // Friction slowed the sliding bottom.
    let bottom_speed = v_vbd
        .iter()
        .zip(&x_vbd)
        .filter(|(_, p)| p.z <= 1e-12)
        .map(|(v, _)| v.x)
        .fold(f64::MAX, f64::min);
    assert!(bottom_speed < 0.3, "{bottom_speed}");
}

/// A step that fails after validation restores the state bit for bit: a tetrahedron stretched
/// 1e12-fold (finite positions, so the input checks pass) has an StVK energy density of order
/// `mu |F|^4 ~ 1e5 * 1e52`, infinite in f32, so `Phi` is finite neither at `y` nor at `x_n`.
#[test]
fn a_failed_step_restores_the_state() {
    use softfem::element::TetRest;
    use softfem::glam::Vec3;
    use softfem::material::StVK;
    use softfem::mesh::TetMesh;
    use softfem::step::{Scene, TetElastic, VbdScratch, VbdSettings, scratch_len, vbd_step};
    let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z].map(|p| p * 0.1);
    let tets = [[0, 1, 2, 3]];
    let mut rest_data = [TetRest::default(); 1];
    let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
    let body = TetElastic::new(mesh, StVK::from_young_poisson(1.0e5, 0.3).unwrap());
    let mut masses = [0.0; 4];
    mesh.lumped_masses(1000.0, &mut masses).unwrap();
    let stretched = rest.map(|p| p * 1e12);
    let velocities = [Vec3::new(0.1, 0.2, 0.3); 4];
    let (mut x, mut v) = (stretched, velocities);
    let mut vectors = [Vec3::splat(7.0); scratch_len::vbd(4)];
    let mut indices = [3; scratch_len::vbd_indices(4, 1)];
    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
    let scene = Scene::new(0.01).with_gravity(Vec3::new(0.0, 0.0, -9.81));
    let settings = VbdSettings::new();
    let error = vbd_step(
        &body,
        &masses,
        &[],
        &scene,
        &settings,
        &mut x,
        &mut v,
        &mut scratch,
    )
    .unwrap_err();
    assert!(
        matches!(error, StepError::NonFiniteState { .. }),
        "{error:?}"
    );
    let bits = |a: &[Vec3]| {
        a.iter()
            .map(|p| p.to_array().map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&x), bits(&stretched));
    assert_eq!(bits(&v), bits(&velocities));
}

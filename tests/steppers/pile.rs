//! Issue #39, deliverable 4, in both precisions: eight soft balls dropped into a box (the
//! ground and four wall colliders) pile up on each other, with body–body contact and friction
//! between them (`src/step/contact/model.rs`) and Newton steps of 1/100 s. After every step: no
//! pair of boundary triangles intersects, by the exact triangle–triangle test of
//! `tests/common/intersection.rs` (not by the barrier that is meant to ensure it); every solve
//! converged (f32: or stopped at its rounding floor, which the report says); every ball's volume
//! stays within `[0.95, 1.01]` of its rest volume (measured 0.964 (f64), 0.966 (f32) to 1.001).
//! The smallest gap, the Newton iterations and the converged share are printed.
//!
//! Coarse balls (2^3 cells, 27 vertices each) and 0.3 s (30 steps), for the debug build CI
//! runs: 520 to 580 Newton iterations, 35 to 40 s of CPU per precision there
//! (measured: f64 30 of 30 converged, 519 iterations; f32 28 converged, 2 at the rounding floor,
//! 538 iterations; smallest gap 30 um, dhat 1 mm). The balls come from
//! `tests/common/ball_pile.rs`, shared with the example.
//!
//! The `pile` example (`examples/pile/`) runs the same scene longer and finer, f32.

macro_rules! pile_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use $($api)::+::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};
            use $($api)::+::element::{TetHessian, TetRest};
            use $($api)::+::material::StableNeoHookean;
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::contact::boundary::ContactSurface;
            use $($api)::+::step::contact::model::{CandidateReuse, FrictionPair};
            use $($api)::+::step::contact::potential::{ContactBarrier, PairHessian};
            use $($api)::+::step::contact::{ContactBuffers, ContactModel, SUGGESTED_STICKING_SPEED};
            use $($api)::+::step::{
                Collider, HalfSpace, NewtonScratch, NewtonSettings, Scene, TetElastic, newton_step,
                scratch_len,
            };
            use $($api)::+::types::{Mat3, Quat, Real, Vec3};

            /// Ball radius (m), cells along the side of the cube mapped onto each ball.
            const RADIUS: Real = 0.04;
            const CELLS: usize = 2;
            /// Half the inner width of the box (m): a 2 x 2 layer of balls (16 cm) just fits.
            const HALF_WIDTH: Real = 0.09;
            /// Young's modulus (Pa), Poisson ratio, density (kg/m^3), friction everywhere.
            const YOUNG: Real = 1e5;
            const POISSON: Real = 0.3;
            const DENSITY: Real = 1000.0;
            const FRICTION: Real = 0.3;
            /// The barrier's gap (m) and the force (N) a pair at half of it holds.
            const DHAT: Real = 1e-3;
            const HOLDING: Real = 1.0;
            /// Time step (s) and steps: 0.3 s, by which the top ball has landed on the others.
            const H: Real = 0.01;
            const STEPS: usize = 30;
            /// The range asserted for every ball's volume over its rest volume.
            const VOLUME_RANGE: (Real, Real) = (0.95, 1.01);

            /// The signed volume of a tetrahedron (m^3; positive for the library's orientation).
            fn volume(x: &[Vec3], [a, b, c, d]: [u32; 4]) -> Real {
                let [a, b, c, d] = [a, b, c, d].map(|i| x[i as usize]);
                (b - a).cross(c - a).dot(d - a) / 6.0
            }

            /// The four walls: the shared scene's boxes (`tests/common/ball_pile.rs`), inner
            /// faces at `|x|, |y| = HALF_WIDTH`, with the pile's friction.
            fn walls() -> Vec<Collider<'static>> {
                crate::ball_pile::walls(HALF_WIDTH as f64)
                    .into_iter()
                    .map(|(centre, half)| {
                        Collider::cuboid(vec3(centre), vec3(half), Quat::IDENTITY).with_friction(FRICTION)
                    })
                    .collect()
            }

            /// A point of the shared scene in this precision.
            fn vec3(p: [f64; 3]) -> Vec3 {
                Vec3::new(p[0] as Real, p[1] as Real, p[2] as Real)
            }

            #[test]
            fn eight_soft_balls_dropped_into_a_box_never_intersect() {
                // The balls, one mesh of eight parts.
                let (mut rest, mut tets, mut ranges) = (Vec::new(), Vec::new(), Vec::new());
                for centre in crate::ball_pile::centres(RADIUS as f64) {
                    let (x, t) = crate::ball_pile::ball(centre, RADIUS as f64, CELLS).unwrap();
                    let x: Vec<Vec3> = x.into_iter().map(vec3).collect();
                    let offset = rest.len() as u32;
                    ranges.push(tets.len()..tets.len() + t.len());
                    rest.extend(x);
                    tets.extend(t.iter().map(|tet| tet.map(|v| v + offset)));
                }
                let n = rest.len();
                let rest_volumes: Vec<Real> =
                    ranges.iter().map(|r| tets[r.clone()].iter().map(|&t| volume(&rest, t)).sum()).collect();
                let mut faces = vec![BoundaryFace::default(); boundary_scratch_len(tets.len())];
                let triangles: Vec<[u32; 3]> =
                    boundary_faces(&tets, n, &mut faces).unwrap().iter().map(|f| f.triangle).collect();
                let exact = |x: &[Vec3]| {
                    let x: Vec<[f64; 3]> = x.iter().map(|p| [p.x as f64, p.y as f64, p.z as f64]).collect();
                    crate::intersection::intersecting_pairs(&x, &triangles).len()
                };
                assert_eq!(exact(&rest), 0, "the balls intersect at the start");

                // The contact model's buffers.
                let (mut vertices, mut edges) = (
                    vec![0; scratch_len::boundary_vertices(triangles.len())],
                    vec![[0; 2]; scratch_len::boundary_edges(triangles.len())],
                );
                let (v, e) = {
                    let surface = ContactSurface::from_triangles(&triangles, n, &mut vertices, &mut edges).unwrap();
                    (surface.vertices.len(), surface.edges.len())
                };
                vertices.truncate(v);
                edges.truncate(e);
                let lengths = scratch_len::broad_phase(v, e, triangles.len());
                let (mut slots, mut entries) = (vec![0; lengths.slots], vec![0; lengths.entries]);
                let (mut vertex_triangle, mut edge_edge) = (vec![[0; 2]; 32 * v], vec![[0; 2]; 32 * e]);
                let mut pair_hessians = vec![PairHessian::default(); 8192];
                let mut friction = vec![FrictionPair::default(); 8192];
                let mut reuse_bounds = vec![Vec3::ZERO; 2 * v];
                let (mut reuse_vertex_triangle, mut reuse_edge_edge) = (vec![[0; 2]; 64 * v], vec![[0; 2]; 64 * e]);
                let mut rest_data = vec![TetRest::default(); tets.len()];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let mut masses = vec![0.0; n];
                mesh.lumped_masses(DENSITY, &mut masses).unwrap();
                let elastic =
                    TetElastic::new(mesh, StableNeoHookean::from_young_poisson(YOUNG, POISSON).unwrap());
                let surface = ContactSurface { vertices: &vertices, edges: &edges, triangles: &triangles };
                let buffers = ContactBuffers {
                    slots: &mut slots,
                    entries: &mut entries,
                    vertex_triangle: &mut vertex_triangle,
                    edge_edge: &mut edge_edge,
                    hessians: &mut pair_hessians,
                    friction: &mut friction,
                    reuse: CandidateReuse {
                        bounds: &mut reuse_bounds,
                        vertex_triangle: &mut reuse_vertex_triangle,
                        edge_edge: &mut reuse_edge_edge,
                    },
                };
                let barrier = ContactBarrier::holding(DHAT, HOLDING).unwrap();
                let model = ContactModel::new(elastic, surface, &rest, barrier, buffers)
                    .unwrap()
                    .with_friction(FRICTION, SUGGESTED_STICKING_SPEED)
                    .unwrap();
                let newton = scratch_len::newton(n, tets.len());
                let (mut vectors, mut blocks, mut hessians) = (
                    vec![Vec3::ZERO; newton.vectors],
                    vec![Mat3::ZERO; newton.blocks],
                    vec![TetHessian::default(); newton.hessians],
                );
                let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
                let walls = walls();
                let scene = Scene::new(H)
                    .with_gravity(Vec3::new(0.0, 0.0, -9.81))
                    .with_ground(HalfSpace::new(Vec3::Z, 0.0).with_friction(FRICTION))
                    .with_colliders(&walls);
                let settings = NewtonSettings::new().with_tolerance(1e-5, 100);

                let (mut x, mut velocity) = (rest.clone(), vec![Vec3::ZERO; n]);
                let (mut iterations, mut converged, mut at_floor) = (0, 0, 0);
                let mut smallest = Real::INFINITY;
                let (mut lowest, mut highest) = (Real::INFINITY, Real::NEG_INFINITY);
                let mut touching_steps = 0;
                for step in 0..STEPS {
                    let report = newton_step(&model, &masses, &[], &scene, &settings, &mut x, &mut velocity, &mut scratch)
                        .unwrap_or_else(|e| panic!("step {step}: {e}"));
                    // No two boundary triangles (sharing no vertex) intersect, decided exactly.
                    assert_eq!(exact(&x), 0, "step {step}: intersecting triangle pairs");
                    // Converged, or (f32 only) stopped at the rounding floor, as the report says.
                    iterations += report.iterations;
                    converged += usize::from(report.converged);
                    let floor = !report.converged && report.stagnated && Real::EPSILON > 1e-10;
                    at_floor += usize::from(floor);
                    assert!(report.converged || floor, "step {step}: {report:?}");
                    // Each ball's volume within the stated range of its rest volume.
                    for (k, range) in ranges.iter().enumerate() {
                        let ratio =
                            tets[range.clone()].iter().map(|&t| volume(&x, t)).sum::<Real>() / rest_volumes[k];
                        lowest = lowest.min(ratio);
                        highest = highest.max(ratio);
                        assert!(
                            (VOLUME_RANGE.0..=VOLUME_RANGE.1).contains(&ratio),
                            "step {step}: ball {k} at {ratio} of its rest volume"
                        );
                    }
                    if let Some(gap) = model.smallest_distance(&x, 10.0 * DHAT).unwrap() {
                        assert!(gap > 0.0, "step {step}: surfaces touch");
                        smallest = smallest.min(gap);
                        touching_steps += usize::from(gap <= DHAT);
                    }
                }
                println!(
                    "{}: {STEPS} steps of {n} vertices, {} tets, {} triangles: {converged} converged \
                     ({:.0} %), {at_floor} at the f32 rounding floor, {iterations} Newton iterations; \
                     smallest gap {smallest:.3e} m (dhat {DHAT:.0e}), within dhat after {touching_steps} \
                     steps; ball volumes {lowest:.4} to {highest:.4} of rest",
                    stringify!($precision),
                    tets.len(),
                    triangles.len(),
                    100.0 * converged as f64 / STEPS as f64,
                );
                // The balls did meet each other: pairs came within the barrier's gap.
                assert!(touching_steps > 0, "no pair came within dhat");
                // And they all landed: every vertex below 25 cm (the top ball started at 46 cm).
                let top = x.iter().map(|p| p.z).fold(Real::MIN, Real::max);
                println!("{}: highest vertex at {top:.3} m", stringify!($precision));
                assert!(top < 0.25, "{top}");
            }
        }
    };
}

pile_tests!(single, softfem);
pile_tests!(double, softfem::f64);

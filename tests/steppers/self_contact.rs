//! Self contact in the implicit solvers (`src/step/contact/model.rs`, issue #39), in both
//! precisions: a soft bar twisted two full turns from both ends coils onto itself without
//! intersecting, every step checked by the exact triangle–triangle test of
//! `tests/common/intersection.rs`.
//!
//! The scene: a 30 x 1 x 1 cm bar of 30 Kuhn-split cubes along x, centred at the origin,
//! StableNeoHookean E = 1e5 Pa, nu = 0.3, 1000 kg/m^3, no gravity, Newton's method with the
//! contact model (dhat = 1 mm, a tenth of the cross-section; a pair at half of it holding 1 N).
//! Each end's four vertices are pinned and, before each of 60 steps of 3 ms, turned about the
//! bar's axis by 1/30 of a turn, the left end one way and the right end the other (two full
//! turns each, four relative, in 0.18 s), and moved 5/6 mm inward: 5 cm each in all, a third
//! of the length, the slack a twisted rubber band takes up as it coils. Twist alone does not
//! coil this bar: measured without the slack, no pair more than 3 cells apart at rest came
//! within dhat in either precision.

macro_rules! self_contact_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use std::time::Instant;

            use $($api)::+::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};
            use $($api)::+::element::{TetHessian, TetRest};
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::StableNeoHookean;
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::contact::boundary::ContactSurface;
            use $($api)::+::step::contact::distance::{
                edge_edge_squared_distance, point_triangle_squared_distance,
            };
            use $($api)::+::step::contact::potential::{ContactBarrier, PairHessian};
            use $($api)::+::step::contact::model::CandidateReuse;
            use $($api)::+::step::contact::{ContactBuffers, ContactModel};
            use $($api)::+::step::{
                NewtonScratch, NewtonSettings, Scene, TetElastic, newton_step, scratch_len,
            };
            use $($api)::+::types::{Mat3, Real, Vec3};

            /// The pairs of surface primitives (point–triangle and edge–edge) within `gap` (m)
            /// of each other at `x` whose vertices were all more than `apart` (m) from each
            /// other along the bar (x) at rest.
            fn far_pairs_within(
                surface: &ContactSurface<'_>,
                (rest, x): (&[Vec3], &[Vec3]),
                gap: Real,
                apart: Real,
            ) -> usize {
                let p = |i: u32| x[i as usize];
                let far = |a: &[u32], b: &[u32]| {
                    let along = |i: u32, j: u32| (rest[i as usize].x - rest[j as usize].x).abs();
                    a.iter().all(|&i| b.iter().all(|&j| along(i, j) > apart))
                };
                // Boxes widened by the gap: the distance only for pairs that may be within it.
                let near = |a: &[u32], b: &[u32]| {
                    let low = |v: &[u32]| v.iter().fold(Vec3::MAX, |m, &i| m.min(p(i)));
                    let high = |v: &[u32]| v.iter().fold(Vec3::MIN, |m, &i| m.max(p(i)));
                    let g = Vec3::splat(gap);
                    (low(a) - g).cmple(high(b)).all() && (low(b) - g).cmple(high(a)).all()
                };
                let mut count = 0;
                for &vertex in surface.vertices {
                    for triangle @ &[a, b, c] in surface.triangles {
                        let pair = far(&[vertex], triangle) && near(&[vertex], triangle);
                        let squared =
                            || point_triangle_squared_distance(p(vertex), p(a), p(b), p(c));
                        count += usize::from(pair && squared() <= gap * gap);
                    }
                }
                for (k, first @ &[a0, a1]) in surface.edges.iter().enumerate() {
                    for second @ &[b0, b1] in &surface.edges[k + 1..] {
                        let pair = far(first, second) && near(first, second);
                        let squared = || edge_edge_squared_distance(p(a0), p(a1), p(b0), p(b1));
                        count += usize::from(pair && squared() <= gap * gap);
                    }
                }
                count
            }

            #[test]
            fn a_bar_twisted_two_turns_from_both_ends_coils_onto_itself_without_intersecting() {
                // The scene of the module docs. The 3 ms step is for Newton's method: the
                // twisted, compressed bar is near buckling, where the projected Hessian misses
                // the negative curvature and the iterations add up. Measured in f64 (a pair at
                // half dhat holding 0.5 N), 60 steps of 10 ms took 1722 Newton iterations; here
                // 634, at most 45 in one solve (in either precision).
                let started = Instant::now();
                let (length, side, cells) = (0.3 as Real, 0.01 as Real, 30);
                let (steps, turns, slack) = (60, 2.0 as Real, 0.05 as Real);
                let dhat = 0.1 * side;
                let cell = length / cells as Real;
                let split = BoxSplit::Kuhn6;
                let (nv, nt) = box_counts(cells, 1, 1, split).unwrap();
                let (mut rest, mut tets) = (vec![Vec3::ZERO; nv], vec![[0; 4]; nt]);
                let half = Vec3::new(0.5 * length, 0.5 * side, 0.5 * side);
                fill_box(-half, half, cells, 1, 1, split, &mut rest, &mut tets).unwrap();
                let mut faces = vec![BoundaryFace::default(); boundary_scratch_len(nt)];
                let triangles: Vec<[u32; 3]> = boundary_faces(&tets, nv, &mut faces)
                    .unwrap()
                    .iter()
                    .map(|face| face.triangle)
                    .collect();
                let f = triangles.len();
                let mut vertices = vec![0; scratch_len::boundary_vertices(f)];
                let mut edges = vec![[0; 2]; scratch_len::boundary_edges(f)];
                let surface =
                    ContactSurface::from_triangles(&triangles, nv, &mut vertices, &mut edges)
                        .unwrap();
                let (sv, se) = (surface.vertices.len(), surface.edges.len());
                let lengths = scratch_len::broad_phase(sv, se, f);
                let (mut slots, mut entries) = (vec![0; lengths.slots], vec![0; lengths.entries]);
                let mut vertex_triangle = vec![[0; 2]; 64 * sv];
                let mut edge_edge = vec![[0; 2]; 64 * se];
                let mut pair_hessians = vec![PairHessian::default(); 16384];
                let mut reuse_bounds = vec![Vec3::ZERO; 2 * sv];
                let (mut reuse_vertex_triangle, mut reuse_edge_edge) = (vec![[0; 2]; 128 * sv], vec![[0; 2]; 128 * se]);
                let mut rest_data = vec![TetRest::default(); nt];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let mut masses = vec![0.0; nv];
                mesh.lumped_masses(1000.0, &mut masses).unwrap();
                let material = StableNeoHookean::from_young_poisson(1e5, 0.3).unwrap();
                let buffers = ContactBuffers {
                    slots: &mut slots,
                    entries: &mut entries,
                    vertex_triangle: &mut vertex_triangle,
                    edge_edge: &mut edge_edge,
                    hessians: &mut pair_hessians,
                    friction: &mut [],
                    reuse: CandidateReuse {
                        bounds: &mut reuse_bounds,
                        vertex_triangle: &mut reuse_vertex_triangle,
                        edge_edge: &mut reuse_edge_edge,
                    },
                };
                let barrier = ContactBarrier::holding(dhat, 1.0).unwrap();
                let elastic = TetElastic::new(mesh, material);
                let model = ContactModel::new(elastic, surface, &rest, barrier, buffers).unwrap();
                let newton = scratch_len::newton(nv, nt);
                let mut vectors = vec![Vec3::ZERO; newton.vectors];
                let mut blocks = vec![Mat3::ZERO; newton.blocks];
                let mut hessians = vec![TetHessian::default(); newton.hessians];
                let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
                let settings = NewtonSettings::new().with_tolerance(1e-4, 100);
                let scene = Scene::new(0.003);

                let pinned: Vec<bool> = rest.iter().map(|p| p.x.abs() == 0.5 * length).collect();
                assert_eq!(pinned.iter().filter(|&&p| p).count(), 8);
                let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; nv]);
                let (mut iterations, mut converged, mut smallest) = (0, 0, Real::MAX);
                let (mut most_far, mut first_far) = (0, None);
                for step in 1..=steps {
                    let progress = step as Real / steps as Real;
                    let angle = turns * core::f64::consts::TAU as Real * progress;
                    for (i, p) in rest.iter().enumerate().filter(|&(i, _)| pinned[i]) {
                        // The left end (x < 0) turns by +angle about x, the right by -angle.
                        let sign = p.x.signum();
                        let (sin, cos) = (-sign * angle).sin_cos();
                        let along = p.x - sign * slack * progress;
                        x[i] = Vec3::new(along, p.y * cos - p.z * sin, p.y * sin + p.z * cos);
                    }
                    let report = newton_step(
                        &model, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch,
                    )
                    .unwrap_or_else(|e| panic!("step {step}: {e}"));
                    iterations += report.iterations;
                    converged += usize::from(report.converged);
                    let exact: Vec<[f64; 3]> =
                        x.iter().map(|p| [p.x as f64, p.y as f64, p.z as f64]).collect();
                    let crossing = crate::intersection::intersecting_pairs(&exact, &triangles);
                    assert!(crossing.is_empty(), "step {step}: intersecting pairs {crossing:?}");
                    // f64 converges; f32 may stop at its rounding floor (stagnated, as the
                    // report says). Measured, every solve converged in both.
                    let at_floor = report.stagnated && Real::EPSILON > 1e-10;
                    assert!(report.converged || at_floor, "step {step}: {report:?}");
                    if let Some(d) = model.smallest_distance(&x, 10.0 * dhat).unwrap() {
                        assert!(d > 0.0, "step {step}: smallest distance {d}");
                        smallest = smallest.min(d);
                    }
                    // Self contact: pairs more than 3 cells apart along the bar at rest.
                    let far = far_pairs_within(model.surface(), (&rest, &x), dhat, 3.5 * cell);
                    if far > 0 && first_far.is_none() {
                        first_far = Some(step);
                    }
                    most_far = most_far.max(far);
                }
                println!(
                    "{}: {steps} steps, {iterations} Newton iterations, {converged} converged, \
                     smallest distance {smallest:.3e} m (dhat {dhat:.0e}), at most {most_far} \
                     pairs more than 3 cells apart at rest within dhat (first at step \
                     {first_far:?}), {:.1} s",
                    stringify!($precision),
                    started.elapsed().as_secs_f64()
                );
                assert!(most_far > 0, "no pair more than 3 cells apart at rest came within dhat");
            }
        }
    };
}

self_contact_tests!(single, softfem);
self_contact_tests!(double, softfem::f64);

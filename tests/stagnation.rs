//! The relaxation's honest stop (`src/step/line_search.rs`, `Stagnation`): a tolerance below
//! the rounding floor stops early as stagnated instead of burning the budget, with the floor
//! reached reported, in both precisions; the residual it stops at is recomputed from the force
//! kernel.

macro_rules! stagnation_tests {
    ($precision:ident, $($api:ident)::+) => {
        mod $precision {
            use $($api)::+::element::TetRest;
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::StableNeoHookean;
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::{FLOOR_FACTOR, RelaxScratch, RelaxSettings, TetElastic, relax_quasi_static, relax_scratch_len};
            use $($api)::+::types::{Real, Vec3};

            const GRAVITY: Vec3 = Vec3::new(0.0, -9.81, 0.0);

            /// The cantilever of tests/relax.rs (4x1x1 Kuhn cells, 0.4 x 0.1 x 0.1 m, E = 1 MPa,
            /// clamped at x = 0) moved by `offset`, relaxed at `tolerance` with `budget`
            /// iterations; returns the report and `|f + m g|` over the free vertices recomputed
            /// from the force kernel.
            fn cantilever(offset: Vec3, tolerance: Real, budget: u32) -> ($($api)::+::step::RelaxReport, f64) {
                let (nv, nt) = box_counts(4, 1, 1, BoxSplit::Kuhn6).unwrap();
                let (mut rest, mut tets) = (vec![Vec3::ZERO; nv], vec![[0; 4]; nt]);
                fill_box(offset, offset + Vec3::new(0.4, 0.1, 0.1), 4, 1, 1, BoxSplit::Kuhn6, &mut rest, &mut tets).unwrap();
                let mut rest_data = vec![TetRest::default(); nt];
                let mesh = TetMesh::new(&rest, &tets, &mut rest_data).unwrap();
                let material = StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap();
                let body = TetElastic::new(mesh, material);
                let mut masses = vec![0.0; nv];
                mesh.lumped_masses(1000.0, &mut masses).unwrap();
                let pinned: Vec<bool> = rest.iter().map(|x| x.x == offset.x).collect();
                let settings = RelaxSettings::new(1.0)
                    .with_gravity(GRAVITY)
                    .with_tolerance(tolerance, budget)
                    .with_chebyshev(0.999, 2.0, 0);
                let (mut vectors, mut scalars) = (vec![Vec3::ZERO; relax_scratch_len(nv)], vec![0.0; nv]);
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let mut x = rest.clone();
                let report = relax_quasi_static(&body, &masses, &pinned, &settings, &mut x, &mut scratch).unwrap();
                let mut f = vec![Vec3::ZERO; nv];
                mesh.add_elastic_forces(&material, &x, &mut f).unwrap();
                let imbalance = f.iter().zip(&masses).zip(&pinned).filter(|(_, p)| !**p)
                    .map(|((f, m), _)| (*f + GRAVITY * *m).length_squared() as f64).sum::<f64>().sqrt();
                (report, imbalance)
            }

            #[test]
            fn a_tolerance_below_the_floor_stops_early_as_stagnated() {
                let budget = 2_000_000;
                let (report, imbalance) = cantilever(Vec3::ZERO, 0.0, budget);
                println!("{report:?}, recomputed imbalance {imbalance:e} N");
                assert!(report.stagnated, "{report:?}");
                assert!(report.iterations < budget / 20, "{report:?}");
                // The reported residual is the true imbalance (to rounding of the sum).
                assert!((imbalance - report.final_residual as f64).abs() <= 1e-3 * imbalance + 1e-6 * report.initial_residual as f64, "{imbalance:e} against {report:?}");
                // The floor is an estimate from above: the stall happens within its bound. A
                // tolerance of 0 is never reached, and the report says so.
                assert!(report.rounding_floor > 0.0 && report.final_residual <= FLOOR_FACTOR * report.rounding_floor, "{report:?}");
                assert!(!report.converged);
            }

            #[test]
            fn far_from_the_origin_the_floor_rises_but_the_stop_stays_early() {
                // Positions 60 m from the origin are known to eps 60 m / 2, not eps 0.4 m / 2:
                // the elastic kernel sees the absolute positions, so the floor grows with the
                // offset. The stop must still come early and report it.
                let budget = 2_000_000;
                let (near, _) = cantilever(Vec3::ZERO, 0.0, budget);
                let (far, imbalance) = cantilever(Vec3::new(60.0, 0.0, 0.0), 0.0, budget);
                println!("at the origin {near:?}\nat 60 m {far:?}, recomputed {imbalance:e} N");
                assert!(far.stagnated && far.iterations < budget / 20, "{far:?}");
                assert!(far.rounding_floor > 10.0 * near.rounding_floor, "{far:?} against {near:?}");
            }
        }
    };
}

stagnation_tests!(single, softfem);
stagnation_tests!(double, softfem::f64);

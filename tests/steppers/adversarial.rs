//! Hostile inputs and the behaviour each must get, in both precisions: one table row per probe
//! (the defects of issue 16, D1 and D3 to D9, and the general promises of docs/guide/09-reliability-and-errors.md: NaN and
//! infinite positions, out-of-range indices, mismatched buffers, non-positive masses and steps,
//! absurd sizes). Every row that expects an error also checks that the caller's buffers are
//! bit for bit what they were. D2 (early blow-up detection) is measured in
//! `tests/steppers/step.rs`.
//!
//! Each row is a closure returning `Err(what went wrong)`; the test runs the whole table and
//! reports every failing row by name, so that one regression does not hide the others.

/// A row's verdict: `Ok` when the input got its promised behaviour.
type Verdict = Result<(), String>;

/// A table row: what the input is and what it must get, and the probe.
type Row = (&'static str, Box<dyn Fn() -> Verdict>);

/// Runs every row and fails with the list of rows that did not get their behaviour.
fn run_table(precision: &str, rows: Vec<Row>) {
    let count = rows.len();
    let failures: Vec<String> = rows
        .into_iter()
        .filter_map(|(name, row)| row().err().map(|why| format!("  {name}: {why}")))
        .collect();
    println!(
        "{precision}: {count} hostile inputs, {} failed",
        failures.len()
    );
    assert!(failures.is_empty(), "{precision}:\n{}", failures.join("\n"));
}

/// `Ok` if `actual == expected`, else a description of both.
fn same<T: PartialEq + std::fmt::Debug>(actual: T, expected: T) -> Verdict {
    if actual == expected {
        Ok(())
    } else {
        Err(format!("got {actual:?}, expected {expected:?}"))
    }
}

/// `Ok` if `condition`, else `Err(what)`.
fn ensure(condition: bool, what: impl FnOnce() -> String) -> Verdict {
    if condition { Ok(()) } else { Err(what()) }
}

macro_rules! adversarial_tests {
    ($precision:ident, $($api:ident)::+, $tiny_step:expr, $huge_scale:expr, $big:expr, $normal_lengths:expr, $heavy:expr, $stiff:expr) => {
        mod $precision {
            use super::{Row, Verdict, ensure, run_table, same};
            use softfem::{MeshError, StepBuffer, StepError};
            use $($api)::+::element::{TetHessian, TetRest};
            use $($api)::+::generate::{BoxSplit, box_counts, fill_box};
            use $($api)::+::material::{Material, StVK, StableNeoHookean};
            use $($api)::+::mesh::TetMesh;
            use $($api)::+::step::{
                ElasticModel, ExplicitScratch, ExplicitSettings, HalfSpace, NewtonScratch,
                NewtonSettings, RelaxScratch, RelaxSettings, Scene, TetClamped, TetElastic,
                VbdScratch, VbdSettings, scratch_len, explicit_step,
                newton_step, relax_step, stable_time_step, vbd_step,
            };
            use $($api)::+::svd::{svd3, svd3_lanes};
            use $($api)::+::types::{Mat3, Real, Vec3};

            /// A step `dt` whose `1 / dt^2` overflows this precision (1e-20 s in f32).
            const TINY_STEP: Real = $tiny_step;
            /// A scale beyond every model's finite range in this precision (`F = 1e20 I` in f32).
            const HUGE: Real = $huge_scale;
            /// A singular value far beyond `1 / eps` times the others (1e19 in f32).
            const BIG: Real = $big;
            /// Ground normal lengths whose squares under- and overflow (1e-30 and 1e30 in f32).
            const NORMAL_LENGTHS: [Real; 2] = $normal_lengths;
            /// A vertex mass (kg) whose gravity load squared overflows (1e19 in f32).
            const HEAVY: Real = $heavy;
            /// A Young's modulus (Pa) whose elastic forces dwarf that load (1e22 in f32).
            const STIFF: Real = $stiff;

            /// A 0.2 m x 0.1 m x 0.1 m block, 2 x 1 x 1 cells.
            struct Block {
                rest: Vec<Vec3>,
                tets: Vec<[u32; 4]>,
            }

            fn block() -> Block {
                let max = Vec3::new(0.2, 0.1, 0.1);
                let (rest, tets) = crate::common::scenes::generated_box!(Vec3::ZERO, max, (2, 1, 1), BoxSplit::Kuhn6);
                Block { rest, tets }
            }

            fn stvk() -> StVK {
                StVK::from_young_poisson(1.0e6, 0.3).unwrap()
            }

            fn snh() -> StableNeoHookean {
                StableNeoHookean::from_young_poisson(1.0e6, 0.3).unwrap()
            }

            /// Bit patterns, so that NaN compares equal to itself.
            fn bits(v: &[Vec3]) -> Vec<[u64; 3]> {
                v.iter().map(|p| p.to_array().map(|c| c.to_bits() as u64)).collect()
            }

            /// Runs `f` on a mesh of the block with lumped masses (1000 kg/m^3).
            fn with_mesh<T>(f: impl FnOnce(TetMesh<'_>, &[Vec3], Vec<Real>) -> T) -> T {
                let b = block();
                crate::common::scenes::mesh_and_masses!(rest_data, mesh, masses; &b.rest, &b.tets, 1000.0);
                f(mesh, &b.rest, masses)
            }

            /// One explicit step; the error (if any) and whether positions, velocities and
            /// scratch are bit for bit unchanged afterwards.
            fn explicit_outcome(
                body: &impl ElasticModel<Vector = Vec3>,
                masses: &[Real],
                scene: &Scene<Vec3>,
                settings: &ExplicitSettings,
                x: &mut [Vec3],
                v: &mut [Vec3],
            ) -> (Result<(), StepError>, bool) {
                let n = x.len();
                let mut buffer = vec![Vec3::splat(3.0); scratch_len::explicit(n)];
                let before = (bits(x), bits(v));
                let mut scratch = ExplicitScratch::new(&mut buffer);
                let result = explicit_step(body, masses, &[], scene, settings, x, v, &mut scratch).map(|_| ());
                (result, (bits(x), bits(v)) == before)
            }

            /// `Ok` if the step failed with `expected` and left the state as it was.
            fn refused_untouched(outcome: (Result<(), StepError>, bool), expected: StepError) -> Verdict {
                same(outcome.0, Err(expected))?;
                ensure(outcome.1, || "the state changed".into())
            }

            /// One relaxation step from rest with velocities `v`.
            fn relax_outcome(
                body: &TetElastic<'_, impl Material>,
                masses: &[Real],
                scene: &Scene<Vec3>,
                settings: &RelaxSettings,
                x: &mut [Vec3],
                v: &mut [Vec3],
            ) -> (Result<crate::adversarial::softfem_report::Report, StepError>, bool) {
                let n = x.len();
                let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(n)], vec![0.0; n]);
                let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
                let before = (bits(x), bits(v));
                let result = relax_step(body, masses, &[], scene, settings, x, v, &mut scratch).map(|r| crate::adversarial::softfem_report::Report {
                    converged: r.converged,
                    iterations: r.iterations,
                    final_residual: r.residual as f64,
                    initial_residual: r.initial_residual as f64,
                });
                (result, (bits(x), bits(v)) == before)
            }

            /// `Ok` unless `report` claims convergence without a finite residual within the
            /// default tolerance of [`RelaxSettings::new`] of the larger of its initial residual
            /// and `load` (N, the gravity load computed in f64), with 1e-3 relative slack for the
            /// f32 rounding of the solver's own target.
            fn claim_holds(report: &crate::adversarial::softfem_report::Report, load: f64) -> Verdict {
                let tolerance = RelaxSettings::new().tolerance as f64;
                let target = tolerance * report.initial_residual.max(load) * (1.0 + 1e-3);
                ensure(!report.converged || (report.final_residual.is_finite() && report.final_residual <= target), || {
                    format!("{report:?} claims convergence against a target of {target:e} N")
                })
            }

            /// A custom model that reports a NaN stiffness bound (D8).
            struct NanStiffness<'a>(TetElastic<'a, StVK>);

            impl ElasticModel for NanStiffness<'_> {
                type Vector = Vec3;
                fn vertex_count(&self) -> usize {
                    self.0.vertex_count()
                }
                fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) -> Result<(), MeshError> {
                    self.0.add_forces(x, f)
                }
                fn for_each_element_stiffness(&self, mut visit: impl FnMut(&[u32], Real, Real)) {
                    self.0.for_each_element_stiffness(|corners, _, measure| visit(corners, Real::NAN, measure));
                }
            }

            fn svd_rows() -> Vec<Row> {
                let big = BIG;
                vec![
                    ("D1 svd of (Y, big X, 0): sorted, no negative value for det = 0", Box::new(move || {
                        let a = Mat3::from_cols(Vec3::Y, Vec3::X * big, Vec3::ZERO);
                        let s = svd3(a).sigma;
                        ensure(s.x >= s.y && s.y >= s.z.abs() && s.y >= 0.0 && s.z >= 0.0, || format!("{s:?}"))
                    })),
                    ("D1 svd of rows [[0, big, 0], [1, 0, 0], [0, 0, -0.5]]: (big, 1, 0.5)", Box::new(move || {
                        let a = Mat3::from_cols(Vec3::Y, Vec3::X * big, Vec3::Z * -0.5);
                        let s = svd3(a).sigma;
                        // det = big / 2 > 0 and the two small values are exact entries.
                        let expected = Vec3::new(big, 1.0, 0.5);
                        ensure((s - expected).abs().max_element() <= 1e-6 * big && s.y == 1.0 && s.z == 0.5, || format!("{s:?}"))
                    })),
                    ("D1 svd3_lanes of the same matrices: the scalar bits", Box::new(move || {
                        let a = Mat3::from_cols(Vec3::Y, Vec3::X * big, Vec3::ZERO);
                        let batch = [a, Mat3::IDENTITY, a.transpose(), -a];
                        let lanes = svd3_lanes(&batch);
                        ensure(batch.iter().zip(&lanes).all(|(m, l)| *l == svd3(*m)), || "lanes differ".into())
                    })),
                    ("svd of NaN: identity and NaN values", Box::new(|| {
                        let s = svd3(Mat3::from_diagonal(Vec3::new(1.0, Real::NAN, 1.0)));
                        ensure(s.sigma.is_nan() && s.u == Mat3::IDENTITY, || format!("{s:?}"))
                    })),
                ]
            }

            /// Every stepper refuses a step whose `1 / dt^2` overflows with the same error, and
            /// leaves the state as it was (one time-step check for all of them).
            fn time_step_rows() -> Vec<Row> {
                vec![
                    ("D3 explicit_step with dt = 1e-20 (f32) / 1e-200 (f64): TimeStepTooSmall", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                        let outcome = explicit_outcome(&body, &masses, &Scene::new(TINY_STEP), &ExplicitSettings::new(), &mut x, &mut v);
                        refused_untouched(outcome, StepError::TimeStepTooSmall)
                    }))),
                    ("D3 newton_step with dt = 1e-20 (f32) / 1e-200 (f64): TimeStepTooSmall", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        let (n, e) = (rest.len(), mesh.element_count());
                        let len = scratch_len::newton(n, e);
                        let mut vectors = vec![Vec3::ZERO; len.vectors];
                        let mut blocks = vec![Mat3::ZERO; len.blocks];
                        let mut hessians = vec![TetHessian::default(); len.hessians];
                        let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; n]);
                        let before = (bits(&x), bits(&v));
                        let result = newton_step(&body, &masses, &[], &Scene::new(TINY_STEP), &NewtonSettings::new(), &mut x, &mut v, &mut scratch).map(|_| ());
                        refused_untouched((result, (bits(&x), bits(&v)) == before), StepError::TimeStepTooSmall)
                    }))),
                    ("D3 vbd_step with dt = 1e-20 (f32) / 1e-200 (f64): TimeStepTooSmall", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        let (n, e) = (rest.len(), mesh.element_count());
                        let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(n)];
                        let mut indices = vec![0u32; scratch_len::vbd_indices(n, e)];
                        let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; n]);
                        let before = (bits(&x), bits(&v));
                        let result = vbd_step(&body, &masses, &[], &Scene::new(TINY_STEP), &VbdSettings::new(), &mut x, &mut v, &mut scratch).map(|_| ());
                        refused_untouched((result, (bits(&x), bits(&v)) == before), StepError::TimeStepTooSmall)
                    }))),
                ]
            }

            fn relax_rows() -> Vec<Row> {
                vec![
                    ("D3 relax_step with dt = 1e-20 (f32) / 1e-200 (f64): a settings error", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                        let outcome = relax_outcome(&body, &masses, &Scene::new(TINY_STEP), &RelaxSettings::new(), &mut x, &mut v);
                        same(outcome.0.err(), Some(StepError::TimeStepTooSmall))?;
                        ensure(outcome.1, || "the state changed".into())
                    }))),
                    ("D3 relax_step with a step just above the limit (10 / sqrt(Real::MAX)): runs", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                        let scene = Scene::new(10.0 / Real::MAX.sqrt()).with_gravity(Vec3::new(0.0, -9.81, 0.0));
                        let outcome = relax_outcome(&body, &masses, &scene, &RelaxSettings::new(), &mut x, &mut v);
                        ensure(outcome.0.is_ok(), || format!("{:?}", outcome.0.err()))
                    }))),
                    ("D4 relax_step at a speed of 1e15 m/s: a convergence claim must hold", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::new(1e15, 0.0, 0.0); rest.len()]);
                        v[0].x = -1e15;
                        match relax_outcome(&body, &masses, &Scene::new(1.0 / 60.0), &RelaxSettings::new(), &mut x, &mut v).0 {
                            Ok(r) => claim_holds(&r, 0.0),
                            Err(_) => Ok(()), // an error is honest too
                        }
                    }))),
                    ("D4 relax_step where |M g|^2 overflows and the elastic residual is far above tolerance: no convergence claimed at 0 iterations", Box::new(|| with_mesh(|mesh, rest, masses| {
                        // 1e19 kg per vertex (1e160 in f64): sum (m g)^2 overflows, and a material
                        // of E = 1e22 Pa (1e163) stretched by 10 % leaves an elastic residual far
                        // above 1e-3 of the gravity load.
                        let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(STIFF, 0.3).unwrap());
                        let heavy = vec![HEAVY; masses.len()];
                        let (mut x, mut v) = (rest.iter().map(|&p| p * 1.1).collect::<Vec<_>>(), vec![Vec3::ZERO; rest.len()]);
                        let g = 9.81;
                        let scene = Scene::new(1.0 / 60.0).with_gravity(Vec3::new(0.0, -g, 0.0));
                        let load = (HEAVY as f64) * (g as f64) * (masses.len() as f64).sqrt();
                        match relax_outcome(&body, &heavy, &scene, &RelaxSettings::new(), &mut x, &mut v).0 {
                            Ok(r) => claim_holds(&r, load),
                            Err(_) => Ok(()),
                        }
                    }))),
                    ("relax_step with dt = 0, -1, NaN: TimeStep, untouched", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        for dt in [0.0, -1.0, Real::NAN, Real::INFINITY] {
                            let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                            let outcome = relax_outcome(&body, &masses, &Scene::new(dt), &RelaxSettings::new(), &mut x, &mut v);
                            same(outcome.0.err(), Some(StepError::TimeStep))?;
                            ensure(outcome.1, || "the state changed".into())?;
                        }
                        Ok(())
                    }))),
                    ("relax_step with a NaN position: NonFiniteInput, untouched", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                        x[4].y = Real::NAN;
                        let outcome = relax_outcome(&body, &masses, &Scene::new(0.01), &RelaxSettings::new(), &mut x, &mut v);
                        same(outcome.0.err(), Some(StepError::NonFiniteInput { vertex: 4 }))?;
                        ensure(outcome.1, || "the state changed".into())
                    }))),
                    ("D6 scratch_len::relax(usize::MAX) saturates", Box::new(|| same(scratch_len::relax(usize::MAX), usize::MAX))),
                ]
            }

            fn explicit_rows() -> Vec<Row> {
                let gravity = Vec3::new(0.0, -9.81, 0.0);
                vec![
                    ("D5 TetClamped::checked with inf, 1e30, NaN, 0, -1, 1.5: ClampThreshold", Box::new(|| with_mesh(|mesh, _, _| {
                        for t in [Real::INFINITY, 1e30, Real::NAN, 0.0, -1.0, 1.5] {
                            same(TetClamped::checked(mesh, stvk(), t).err(), Some(MeshError::ClampThreshold))?;
                        }
                        ensure(TetClamped::checked(mesh, stvk(), 0.3).is_ok(), || "0.3 refused".into())
                    }))),
                    ("D5 clamped forces with threshold inf / NaN: ClampThreshold, forces untouched", Box::new(|| with_mesh(|mesh, rest, _| {
                        for t in [Real::INFINITY, 1e30, Real::NAN] {
                            let mut forces = vec![Vec3::splat(2.0); rest.len()];
                            let before = bits(&forces);
                            same(mesh.add_elastic_forces_clamped(&stvk(), t, rest, &mut forces), Err(MeshError::ClampThreshold))?;
                            ensure(bits(&forces) == before, || "forces changed".into())?;
                        }
                        Ok(())
                    }))),
                    ("D5 a step with TetClamped::new(.., NaN): Mesh(ClampThreshold), untouched", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetClamped::new(mesh, stvk(), Real::NAN);
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                        let scene = Scene::new(1e-4).with_gravity(gravity);
                        refused_untouched(explicit_outcome(&body, &masses, &scene, &ExplicitSettings::new(), &mut x, &mut v), StepError::Mesh(MeshError::ClampThreshold))
                    }))),
                    ("D6 scratch_len::explicit(usize::MAX) saturates", Box::new(|| {
                        same(scratch_len::explicit(usize::MAX), usize::MAX)?;
                        same(scratch_len::explicit(usize::MAX / 2 + 1), usize::MAX)
                    })),
                    ("D7 with_substeps(u32::MAX): Substeps at once, untouched", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, stvk());
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                        let settings = ExplicitSettings::new().with_substeps(u32::MAX);
                        refused_untouched(explicit_outcome(&body, &masses, &Scene::new(1e-4), &settings, &mut x, &mut v), StepError::Substeps)
                    }))),
                    ("D8 a subnormal mass (1e-39 kg in f32): Mass, untouched", Box::new(move || with_mesh(|mesh, rest, mut masses| {
                        let body = TetElastic::new(mesh, stvk());
                        masses[2] = Real::MIN_POSITIVE / 4.0;
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                        let scene = Scene::new(1e-4).with_gravity(gravity);
                        refused_untouched(explicit_outcome(&body, &masses, &scene, &ExplicitSettings::new(), &mut x, &mut v), StepError::Mass { vertex: 2 })?;
                        let mut stiffness = vec![0.0; rest.len()];
                        same(stable_time_step(&body, &masses, &[], &mut stiffness), Err(StepError::Mass { vertex: 2 }))
                    }))),
                    ("D8 ground normals of length 1e-30 and 1e30 (f32; 1e-300, 1e300 in f64), and subnormal: as the unit normal", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, stvk());
                        let run = |normal: Vec3| {
                            let (mut x, mut v) = (rest.to_vec(), vec![Vec3::new(0.0, -1.0, 0.0); rest.len()]);
                            let scene = Scene::new(1e-4).with_gravity(gravity).with_ground(HalfSpace::new(normal, 0.01));
                            explicit_outcome(&body, &masses, &scene, &ExplicitSettings::new(), &mut x, &mut v).0.map(|()| x)
                        };
                        let unit = run(Vec3::Y).map_err(|e| format!("{e:?}"))?;
                        let [small, large] = NORMAL_LENGTHS;
                        for scale in [small, large, Real::MIN_POSITIVE / 8.0, Real::MAX / 2.0] {
                            let x = run(Vec3::Y * scale).map_err(|e| format!("length {scale:e}: {e:?}"))?;
                            // The normal is the unit normal to rounding (its reciprocal length
                            // rounds), so the projected positions agree to a few eps.
                            let apart = x.iter().zip(&unit).map(|(a, b)| (*a - *b).length()).fold(0.0, Real::max);
                            ensure(apart <= 8.0 * Real::EPSILON, || format!("length {scale:e}: {apart:e} m apart"))?;
                        }
                        Ok(())
                    }))),
                    ("D8 stable_time_step for E near Real::MAX: Stiffness, not Ok(0)", Box::new(|| with_mesh(|mesh, rest, masses| {
                        // E = 0.9 Real::MAX (3e38 in f32): the element bound overflows.
                        let stiff = StVK::from_young_poisson(Real::MAX * 0.9, 0.3).unwrap();
                        let body = TetElastic::new(mesh, stiff);
                        let mut stiffness = vec![0.0; rest.len()];
                        let result = stable_time_step(&body, &masses, &[], &mut stiffness);
                        ensure(matches!(result, Err(StepError::Stiffness { .. })), || format!("{result:?}"))?;
                        // E = Real::MAX / 4 still has a representable bound: a tiny positive step.
                        let body = TetElastic::new(mesh, StVK::from_young_poisson(Real::MAX / 4.0, 0.3).unwrap());
                        let dt = stable_time_step(&body, &masses, &[], &mut stiffness).map_err(|e| format!("{e:?}"))?;
                        ensure(dt > 0.0 && dt.is_finite(), || format!("{dt:e}"))
                    }))),
                    ("D8 stable_time_step of a model with NaN stiffness: Stiffness, not Ok(inf)", Box::new(|| with_mesh(|mesh, rest, masses| {
                        let body = NanStiffness(TetElastic::new(mesh, stvk()));
                        let mut stiffness = vec![0.0; rest.len()];
                        same(stable_time_step(&body, &masses, &[], &mut stiffness), Err(StepError::Stiffness { vertex: 0 }))
                    }))),
                    ("D8 lumped_masses(1e-45) and (Real::MIN_POSITIVE): MassRange, masses untouched", Box::new(|| with_mesh(|mesh, rest, _| {
                        for density in [Real::from_bits(1), Real::MIN_POSITIVE] {
                            let mut masses = vec![7.0; rest.len()];
                            same(mesh.lumped_masses(density, &mut masses), Err(MeshError::MassRange { element: 0 }))?;
                            ensure(masses.iter().all(|&m| m == 7.0), || "masses changed".into())?;
                        }
                        Ok(())
                    }))),
                    ("D9 StVK and stable neo-Hookean at F = 1e20 I (f32): DeformationRange, forces untouched", Box::new(|| with_mesh(|mesh, rest, _| {
                        let x: Vec<Vec3> = rest.iter().map(|&p| p * HUGE).collect();
                        for result in [
                            { let mut f = vec![Vec3::ONE; rest.len()]; let r = mesh.add_elastic_forces(&stvk(), &x, &mut f); (r, bits(&f)) },
                            { let mut f = vec![Vec3::ONE; rest.len()]; let r = mesh.add_elastic_forces(&snh(), &x, &mut f); (r, bits(&f)) },
                            { let mut f = vec![Vec3::ONE; rest.len()]; let r = mesh.add_elastic_forces_principal(&snh(), &x, &mut f); (r, bits(&f)) },
                            { let mut f = vec![Vec3::ONE; rest.len()]; let r = mesh.add_elastic_forces_clamped(&stvk(), 0.3, &x, &mut f); (r, bits(&f)) },
                        ] {
                            same(result.0, Err(MeshError::DeformationRange { element: 0 }))?;
                            ensure(result.1 == bits(&vec![Vec3::ONE; rest.len()]), || "forces changed".into())?;
                        }
                        same(mesh.elastic_energy(&snh(), &x).err(), Some(MeshError::DeformationRange { element: 0 }))
                    }))),
                    ("D9 one element far beyond the range: named", Box::new(|| with_mesh(|mesh, rest, _| {
                        let mut x = rest.to_vec();
                        let last = x.len() - 1;
                        x[last] *= HUGE;
                        let first_with_last = mesh.tets().iter().position(|t| t.contains(&(last as u32))).unwrap();
                        let mut f = vec![Vec3::ZERO; rest.len()];
                        same(mesh.add_elastic_forces(&stvk(), &x, &mut f), Err(MeshError::DeformationRange { element: first_with_last }))
                    }))),
                    ("D9 a modulus with no headroom (limit below 1): even a body collapsed to a point (F = 0) is refused", Box::new(|| with_mesh(|mesh, rest, _| {
                        // lambda + mu = 2 Real::MAX / 3 overflows the limit's formula: the
                        // limit is below 1, and F = 0 (energy density of the order of the
                        // modulus, times a volume) must not come back as an infinite energy.
                        let huge = StVK::from_lame(Real::MAX / 3.0, Real::MAX / 3.0).map_err(|e| format!("{e:?}"))?;
                        ensure(huge.deformation_limit() < 1.0, || format!("limit {}", huge.deformation_limit()))?;
                        let collapsed = vec![Vec3::ZERO; rest.len()];
                        let mut energies = vec![1.0; mesh.element_count()];
                        same(mesh.element_energies(&huge, &collapsed, &mut energies), Err(MeshError::DeformationRange { element: 0 }))?;
                        ensure(energies.iter().all(|&e| e == 1.0), || "energies changed".into())?;
                        same(mesh.elastic_energy(&huge, rest).err(), Some(MeshError::DeformationRange { element: 0 }))
                    }))),
                    ("D9 at the documented limit, every entry +-limit: energy and stress finite", Box::new(|| {
                        let mut worst = Vec::new();
                        for (name, energy, stress, limit) in [
                            ("StVK", stvk().energy_density(Mat3::IDENTITY), Mat3::ZERO, stvk().deformation_limit()),
                            ("stable neo-Hookean", snh().energy_density(Mat3::IDENTITY), Mat3::ZERO, snh().deformation_limit()),
                        ] {
                            let _ = (energy, stress);
                            let signs = Mat3::from_cols_array(&[1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0]);
                            for f in [Mat3::IDENTITY * limit, signs * limit, Mat3::from_cols_array(&[1.0; 9]) * limit] {
                                let finite = if name == "StVK" {
                                    stvk().energy_density(f).is_finite() && stvk().first_piola(f).is_finite() && stvk().first_piola_principal(f).is_finite()
                                } else {
                                    snh().energy_density(f).is_finite() && snh().first_piola(f).is_finite() && snh().first_piola_principal(f).is_finite()
                                };
                                if !finite {
                                    worst.push(format!("{name} at {limit:e}"));
                                }
                            }
                        }
                        ensure(worst.is_empty(), || worst.join(", "))
                    })),
                    ("D9 a step at positions scaled by 1e13 (f32): Mesh(DeformationRange), untouched", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, snh());
                        let (mut x, mut v): (Vec<Vec3>, Vec<Vec3>) = (rest.iter().map(|&p| p * HUGE).collect(), vec![Vec3::ZERO; rest.len()]);
                        let scene = Scene::new(1e-4);
                        refused_untouched(explicit_outcome(&body, &masses, &scene, &ExplicitSettings::new(), &mut x, &mut v), StepError::Mesh(MeshError::DeformationRange { element: 0 }))
                    }))),
                    ("NaN and infinite positions and velocities: NonFiniteInput, untouched", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, stvk());
                        let scene = Scene::new(1e-4).with_gravity(gravity);
                        for (vertex, value, in_velocity) in [(1, Real::NAN, false), (3, Real::INFINITY, false), (5, Real::NEG_INFINITY, true)] {
                            let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                            if in_velocity { v[vertex].z = value } else { x[vertex].x = value }
                            refused_untouched(explicit_outcome(&body, &masses, &scene, &ExplicitSettings::new(), &mut x, &mut v), StepError::NonFiniteInput { vertex })?;
                        }
                        Ok(())
                    }))),
                    ("non-positive, NaN and infinite masses: Mass, untouched", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, stvk());
                        for bad in [0.0, -1.0, Real::NAN, Real::INFINITY] {
                            let mut m = masses.clone();
                            m[7] = bad;
                            let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                            refused_untouched(explicit_outcome(&body, &m, &Scene::new(1e-4), &ExplicitSettings::new(), &mut x, &mut v), StepError::Mass { vertex: 7 })?;
                        }
                        Ok(())
                    }))),
                    ("non-positive and non-finite steps: TimeStep, untouched", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, stvk());
                        for dt in [0.0, -1e-3, Real::NAN, Real::INFINITY, -0.0] {
                            let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; rest.len()]);
                            refused_untouched(explicit_outcome(&body, &masses, &Scene::new(dt), &ExplicitSettings::new(), &mut x, &mut v), StepError::TimeStep)?;
                        }
                        Ok(())
                    }))),
                    ("mismatched buffers: LengthMismatch naming the buffer, untouched", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, stvk());
                        let n = rest.len();
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; n - 1]);
                        refused_untouched(
                            explicit_outcome(&body, &masses, &Scene::new(1e-4), &ExplicitSettings::new(), &mut x, &mut v),
                            StepError::LengthMismatch { buffer: StepBuffer::Velocities, expected: n, actual: n - 1 },
                        )?;
                        let mut forces = vec![Vec3::ZERO; n + 1];
                        same(
                            mesh.add_elastic_forces(&stvk(), rest, &mut forces),
                            Err(MeshError::LengthMismatch { buffer: softfem::Buffer::Forces, expected: n, actual: n + 1 }),
                        )
                    }))),
                    ("a scratch of the wrong length: refused by length", Box::new(move || with_mesh(|mesh, rest, masses| {
                        let body = TetElastic::new(mesh, stvk());
                        let n = rest.len();
                        let mut buffer = vec![Vec3::ZERO; 1];
                        let (mut x, mut v) = (rest.to_vec(), vec![Vec3::ZERO; n]);
                        let mut scratch = ExplicitScratch::new(&mut buffer);
                        same(
                            explicit_step(&body, &masses, &[], &Scene::new(1e-4), &ExplicitSettings::new(), &mut x, &mut v, &mut scratch).map(|_| ()),
                            Err(StepError::LengthMismatch { buffer: StepBuffer::Scratch, expected: scratch_len::explicit(n), actual: 1 }),
                        )
                    }))),
                    ("an index out of range: IndexOutOfRange naming element and corner", Box::new(|| {
                        let b = block();
                        let mut tets = b.tets.clone();
                        tets[3][2] = 99;
                        let mut rest_data = vec![TetRest::default(); tets.len()];
                        same(
                            TetMesh::new(&b.rest, &tets, &mut rest_data).err(),
                            Some(MeshError::IndexOutOfRange { element: 3, corner: 2, index: 99, vertex_count: b.rest.len() }),
                        )
                    })),
                    ("a NaN rest position: NonFiniteRestPosition", Box::new(|| {
                        let b = block();
                        let mut rest = b.rest.clone();
                        rest[6].y = Real::NAN;
                        let mut rest_data = vec![TetRest::default(); b.tets.len()];
                        same(TetMesh::new(&rest, &b.tets, &mut rest_data).err(), Some(MeshError::NonFiniteRestPosition { vertex: 6 }))
                    })),
                    ("a NaN deformed position in a kernel: NonFinitePosition, forces untouched", Box::new(|| with_mesh(|mesh, rest, _| {
                        let mut x = rest.to_vec();
                        x[2].z = Real::NAN;
                        let mut forces = vec![Vec3::ONE; rest.len()];
                        same(mesh.add_elastic_forces(&snh(), &x, &mut forces), Err(MeshError::NonFinitePosition { vertex: 2 }))?;
                        ensure(forces.iter().all(|&f| f == Vec3::ONE), || "forces changed".into())
                    }))),
                    ("densities 0, -1, NaN, inf: Density", Box::new(|| with_mesh(|mesh, rest, _| {
                        for density in [0.0, -1.0, Real::NAN, Real::INFINITY] {
                            let mut masses = vec![0.0; rest.len()];
                            same(mesh.lumped_masses(density, &mut masses), Err(MeshError::Density))?;
                        }
                        Ok(())
                    }))),
                ]
            }

            #[test]
            fn every_hostile_input_gets_its_promised_behaviour() {
                let mut rows = svd_rows();
                rows.extend(relax_rows());
                rows.extend(time_step_rows());
                rows.extend(explicit_rows());
                run_table(stringify!($precision), rows);
            }
        }
    };
}

/// What the relaxation rows keep of a report (the same fields in both precisions).
mod softfem_report {
    #[derive(Debug)]
    pub struct Report {
        pub converged: bool,
        #[allow(dead_code)]
        pub iterations: u32,
        pub final_residual: f64,
        pub initial_residual: f64,
    }
}

adversarial_tests!(
    single,
    softfem,
    1e-20,
    1e13,
    1e19,
    [1e-30, 1e30],
    1e19,
    1e22
);
adversarial_tests!(
    double,
    softfem::f64,
    1e-200,
    1e100,
    1e160,
    [1e-300, 1e300],
    1e160,
    1e163
);

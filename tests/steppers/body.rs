//! The owning body (`softfem::body`): the same bits as the low-level calls it wraps, for every
//! solver and many steps; fixed capacity that runs out is an error; pins and kinematic targets
//! do what they say; a failed step hands back the state it started from. Everything but the
//! `alloc` module runs without the `alloc` feature (`cargo test --no-default-features --test
//! body`).

use softfem::body::{
    AutoChoice, AutoReport, AutoRun, AutoSettings, Body, Fallback, FixedStorage, Solver, StepReport,
};
use softfem::element::TetRest;
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::Vec3;
use softfem::material::StableNeoHookean;
use softfem::mesh::TetMesh;
use softfem::step::{
    ExplicitScratch, ExplicitSettings, FIXED_X, HalfSpace, NewtonScratch, NewtonSettings,
    RelaxScratch, RelaxSettings, Scene, TetElastic, VbdScratch, VbdSettings, explicit_step,
    newton_step, relax_step, scratch_len, stable_time_step, vbd_step,
};
use softfem::{BodyBuffer, BodyError, StepError};

/// A 3 x 2 x 2-cell box (0.3 x 0.2 x 0.2 m), 5 tets a cell: 36 vertices, 60 tets.
const CELLS: [usize; 3] = [3, 2, 2];
type Small = FixedStorage<36, 60>;
const LOW: Vec3 = Vec3::new(0.0, 0.02, 0.0);
const HIGH: Vec3 = Vec3::new(0.3, 0.22, 0.2);
const DENSITY: f32 = 1000.0;
const GRAVITY: Vec3 = Vec3::new(0.0, -9.81, 0.0);

fn jelly() -> StableNeoHookean {
    StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap()
}

fn ground() -> HalfSpace<Vec3> {
    HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5)
}

/// The low-level pieces the body replaces, written out as a caller would (the mesh buffers
/// leaked, a few kilobytes per test, so that the model can sit next to the state).
struct Reference {
    model: TetElastic<'static, StableNeoHookean>,
    rest: &'static [Vec3],
    masses: Vec<f32>,
    pinned: Vec<bool>,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
}

impl Reference {
    fn new() -> Reference {
        Reference::of(jelly())
    }

    /// The pieces of the box of [`small_body`] in `material`.
    fn of(material: StableNeoHookean) -> Reference {
        let (n, t) = box_counts(CELLS[0], CELLS[1], CELLS[2], BoxSplit::Alternating5).unwrap();
        let (mut rest, mut tets) = (vec![Vec3::ZERO; n], vec![[0; 4]; t]);
        let [nx, ny, nz] = CELLS;
        fill_box(
            LOW,
            HIGH,
            nx,
            ny,
            nz,
            BoxSplit::Alternating5,
            &mut rest,
            &mut tets,
        )
        .unwrap();
        let rest: &'static [Vec3] = Box::leak(rest.into_boxed_slice());
        let tets: &'static [[u32; 4]] = Box::leak(tets.into_boxed_slice());
        let rest_data = Box::leak(vec![TetRest::default(); t].into_boxed_slice());
        let mesh = TetMesh::new(rest, tets, rest_data).unwrap();
        let mut masses = vec![0.0; n];
        mesh.lumped_masses(DENSITY, &mut masses).unwrap();
        Reference {
            model: TetElastic::new(mesh, material),
            x: rest.to_vec(),
            v: vec![Vec3::ZERO; n],
            pinned: vec![false; n],
            rest,
            masses,
        }
    }
}

fn bits(vectors: &[Vec3]) -> Vec<[u32; 3]> {
    vectors
        .iter()
        .map(|v| v.to_array().map(f32::to_bits))
        .collect()
}

fn small_body() -> Body<Small, StableNeoHookean> {
    let mut body = Body::<Small, _>::from_box(LOW, HIGH, CELLS, DENSITY, jelly()).unwrap();
    body.set_gravity(GRAVITY);
    body.set_ground(Some(ground()));
    body
}

/// Pins the vertices on the plane x = 0 of both.
fn pin_wall(body: &mut Body<Small, StableNeoHookean>, reference: &mut Reference) {
    for (i, x) in reference.rest.iter().enumerate() {
        if x.x == 0.0 {
            reference.pinned[i] = true;
            body.set_pinned(i, true).unwrap();
        }
    }
}

/// Steps `body` and the low-level `explicit_step` of `reference` in `scene` with `settings` side
/// by side for `steps` steps of `scene.dt`, asserting the same report and bits each step; then that
/// the body moved by more than `moved` (m) somewhere, so the comparison is not of two bodies at
/// rest.
fn assert_explicit_matches(
    body: &mut Body<Small, StableNeoHookean>,
    reference: &mut Reference,
    scene: &Scene<'_, Vec3>,
    settings: &ExplicitSettings,
    steps: usize,
    moved: f32,
) {
    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(36)];
    let mut scratch = ExplicitScratch::new(&mut buffer);
    for step in 0..steps {
        let expected = explicit_step(
            &reference.model,
            &reference.masses,
            &reference.pinned,
            scene,
            settings,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        )
        .unwrap();
        let report = body.step(scene.dt).unwrap();
        assert_eq!(report, StepReport::Explicit(expected), "step {step}");
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
        assert_eq!(bits(body.velocities()), bits(&reference.v), "step {step}");
    }
    assert!(
        reference
            .x
            .iter()
            .zip(reference.rest)
            .any(|(x, r)| (*x - *r).length() > moved)
    );
}

#[test]
fn explicit_body_matches_the_low_level_calls_bit_for_bit() {
    let mut reference = Reference::new();
    let mut body = small_body();
    assert_eq!(body.masses(), &reference.masses[..]);
    assert_eq!(body.rest_positions(), reference.rest);
    pin_wall(&mut body, &mut reference);
    let model = reference.model;
    let stable =
        stable_time_step(&model, &reference.masses, &reference.pinned, &mut [0.0; 36]).unwrap();
    assert_eq!(body.stable_time_step().unwrap().to_bits(), stable.to_bits());

    // With the stable fraction: the fewest substeps of at most 0.5 * stable, counted here.
    let dt = 1.0 / 120.0;
    let substeps = (1..).find(|&k| dt / k as f32 <= 0.5 * stable).unwrap();
    assert!(substeps > 1, "the step must need substeps: {substeps}");
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let settings = ExplicitSettings::new()
        .with_damping(2.0)
        .with_substeps(substeps);
    body.set_solver(Solver::Explicit {
        settings: ExplicitSettings::new().with_damping(2.0),
        stable_fraction: Some(0.5),
    })
    .unwrap();
    assert_explicit_matches(&mut body, &mut reference, &scene, &settings, 60, 1e-3);
}

#[test]
fn explicit_body_with_fixed_substeps_matches_too() {
    let mut reference = Reference::new();
    let mut body = small_body();
    let model = reference.model;
    let dt = 0.5 * stable_time_step(&model, &reference.masses, &[], &mut [0.0; 36]).unwrap();
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let settings = ExplicitSettings::new();
    body.set_solver(Solver::Explicit {
        settings: ExplicitSettings::new(),
        stable_fraction: None,
    })
    .unwrap();
    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(36)];
    let mut scratch = ExplicitScratch::new(&mut buffer);
    for _ in 0..400 {
        let expected = explicit_step(
            &model,
            &reference.masses,
            &[],
            &scene,
            &settings,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        );
        assert_eq!(body.step(dt), expected.map(StepReport::Explicit));
    }
    assert_eq!(bits(body.positions()), bits(&reference.x));
    assert_eq!(bits(body.velocities()), bits(&reference.v));
    // It landed: the ground was involved.
    let lowest = reference
        .x
        .iter()
        .map(|x| x.y)
        .fold(f32::INFINITY, f32::min);
    assert!(lowest.abs() < 2e-3, "{lowest}");
}

#[test]
fn relax_body_matches_the_low_level_calls_bit_for_bit() {
    let mut reference = Reference::new();
    let mut body = small_body();
    pin_wall(&mut body, &mut reference);
    let model = reference.model;
    let settings = RelaxSettings::new()
        .with_tolerance(1e-3, 200)
        .with_chebyshev(0.995, 2.0, 10);
    body.set_solver(Solver::Relax(settings)).unwrap();
    let dt = 1.0 / 60.0;
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let (mut vectors, mut scalars) = (vec![Vec3::ZERO; scratch_len::relax(36)], vec![0.0; 36]);
    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
    for step in 0..30 {
        let expected = relax_step(
            &model,
            &reference.masses,
            &reference.pinned,
            &scene,
            &settings,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        )
        .unwrap();
        assert_eq!(
            body.step(dt).unwrap(),
            StepReport::Relax(expected),
            "step {step}"
        );
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
        assert_eq!(bits(body.velocities()), bits(&reference.v), "step {step}");
    }
    assert!(
        reference
            .x
            .iter()
            .zip(reference.rest)
            .any(|(x, r)| (*x - *r).length() > 1e-3)
    );
}

#[test]
fn newton_and_vbd_bodies_match_the_low_level_calls_bit_for_bit() {
    let dt = 1.0 / 60.0;
    // Newton.
    let mut reference = Reference::new();
    let mut body = small_body();
    pin_wall(&mut body, &mut reference);
    let model = reference.model;
    let newton = NewtonSettings::new().with_tolerance(1e-3, 20);
    body.set_solver(Solver::Newton(newton)).unwrap();
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let lengths = scratch_len::newton(36, 60);
    let mut vectors = vec![Vec3::ZERO; lengths.vectors];
    let mut blocks = vec![Default::default(); lengths.blocks];
    let mut hessians = vec![Default::default(); lengths.hessians];
    let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
    for step in 0..10 {
        let expected = newton_step(
            &model,
            &reference.masses,
            &reference.pinned,
            &scene,
            &newton,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        )
        .unwrap();
        assert_eq!(
            body.step(dt).unwrap(),
            StepReport::Newton(expected),
            "step {step}"
        );
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
        assert_eq!(bits(body.velocities()), bits(&reference.v), "step {step}");
    }

    // Vertex Block Descent, on the same body switched over (its state carries on).
    let vbd = VbdSettings::new().with_tolerance(1e-3, 100);
    body.set_solver(Solver::Vbd(vbd)).unwrap();
    let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(36)];
    let mut indices = vec![0; scratch_len::vbd_indices(36, 60)];
    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
    for step in 0..10 {
        let expected = vbd_step(
            &model,
            &reference.masses,
            &reference.pinned,
            &scene,
            &vbd,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        )
        .unwrap();
        assert_eq!(
            body.step(dt).unwrap(),
            StepReport::Vbd(expected),
            "step {step}"
        );
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
        assert_eq!(bits(body.velocities()), bits(&reference.v), "step {step}");
    }
    assert!(
        reference
            .x
            .iter()
            .zip(reference.rest)
            .any(|(x, r)| (*x - *r).length() > 1e-3)
    );
}

#[test]
fn running_out_of_fixed_capacity_is_an_error() {
    let too_few_vertices =
        Body::<FixedStorage<35, 60>, _>::from_box(LOW, HIGH, CELLS, DENSITY, jelly());
    assert_eq!(
        too_few_vertices.unwrap_err(),
        BodyError::Capacity {
            buffer: BodyBuffer::Vertices,
            needed: 36
        }
    );
    let too_few_tets =
        Body::<FixedStorage<36, 59>, _>::from_box(LOW, HIGH, CELLS, DENSITY, jelly());
    assert_eq!(
        too_few_tets.unwrap_err(),
        BodyError::Capacity {
            buffer: BodyBuffer::Tetrahedra,
            needed: 60
        }
    );
    // One tetrahedron and a vertex in none: refused when built (issue #44). It was accepted,
    // and then every step failed on the vertex's zero mass (and VBD's index scratch, 3 * 5 + 1
    // + 4 = 20 entries, did not fit 17 per tetrahedron: with every vertex in a tetrahedron it
    // always fits now).
    let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
    let unused =
        Body::<FixedStorage<5, 1>, _>::from_arrays(&rest, &[[0, 1, 2, 3]], DENSITY, jelly());
    assert_eq!(unused.err(), Some(BodyError::UnusedVertex { vertex: 4 }));
    let mut body =
        Body::<FixedStorage<5, 1>, _>::from_arrays(&rest[..4], &[[0, 1, 2, 3]], DENSITY, jelly())
            .unwrap();
    body.set_solver(Solver::vbd()).unwrap();
    body.step(0.01).unwrap();
    // Bad input is named.
    assert_eq!(
        body.set_pinned(5, true),
        Err(BodyError::Vertex { vertex: 5 })
    );
    assert_eq!(
        body.set_target(0, Vec3::NAN),
        Err(BodyError::Vertex { vertex: 0 })
    );
    let inverted =
        Body::<FixedStorage<4, 1>, _>::from_arrays(&rest[..4], &[[0, 2, 1, 3]], DENSITY, jelly());
    assert!(matches!(inverted, Err(BodyError::Mesh(_))), "{inverted:?}");
}

#[test]
fn pinned_vertices_stay_put_under_every_solver() {
    for solver in [
        Solver::explicit(),
        Solver::relax(),
        Solver::newton(),
        Solver::vbd(),
        Solver::auto(),
        Solver::Auto(AutoSettings::new().with_crossover(0)),
    ] {
        let mut body = small_body();
        body.set_solver(solver).unwrap();
        let pinned: Vec<usize> = (0..36)
            .filter(|&i| body.rest_positions()[i].x == 0.0)
            .collect();
        for &i in &pinned {
            body.set_pinned(i, true).unwrap();
        }
        // A pinned vertex keeps its velocity too: give one a (fictitious) velocity.
        body.velocities_mut()[pinned[0]] = Vec3::new(0.5, 0.0, 0.0);
        let before = bits(body.positions());
        for _ in 0..10 {
            body.step(1.0 / 60.0).unwrap();
        }
        let after = bits(body.positions());
        for &i in &pinned {
            assert_eq!(after[i], before[i], "{solver:?}: vertex {i}");
        }
        assert_eq!(body.velocities()[pinned[0]], Vec3::new(0.5, 0.0, 0.0));
        // The rest moved (fell, hanging from the wall).
        assert!((0..36).any(|i| after[i] != before[i]), "{solver:?}");
    }
}

#[test]
fn kinematic_vertices_follow_their_targets() {
    for solver in [
        Solver::explicit(),
        Solver::relax(),
        Solver::newton(),
        Solver::vbd(),
        Solver::auto(),
        Solver::Auto(AutoSettings::new().with_crossover(0)),
    ] {
        let mut body = small_body();
        body.set_ground(None);
        body.set_gravity(Vec3::ZERO);
        body.set_solver(solver).unwrap();
        let wall: Vec<usize> = (0..36)
            .filter(|&i| body.rest_positions()[i].x == 0.0)
            .collect();
        let dt = 1.0 / 60.0;
        let speed = Vec3::new(-0.3, 0.0, 0.0); // m/s: the wall pulls the box along -x
        for step in 1..=20 {
            for &i in &wall {
                let target = body.rest_positions()[i] + speed * (step as f32 * dt);
                body.set_target(i, target).unwrap();
            }
            let before: Vec<Vec3> = body.positions().to_vec();
            body.step(dt).unwrap();
            for &i in &wall {
                let target = body.target(i).unwrap();
                assert_eq!(body.positions()[i], target, "{solver:?} step {step}");
                assert!(body.pinned()[i]);
                // The velocity that took it there, as computed by the body: (target - x) / dt.
                assert_eq!(body.velocities()[i], (target - before[i]) / dt);
            }
        }
        // The far end was dragged along: it moved in -x by a good part of the wall's 0.1 m.
        let far: Vec<usize> = (0..36)
            .filter(|&i| body.rest_positions()[i].x > 0.29)
            .collect();
        let moved = far
            .iter()
            .map(|&i| body.rest_positions()[i].x - body.positions()[i].x)
            .sum::<f32>()
            / far.len() as f32;
        assert!(moved > 0.02 && moved < 0.15, "{solver:?}: {moved}");
        // A cleared target leaves the vertex pinned where it is.
        body.clear_target(wall[0]).unwrap();
        let held = body.positions()[wall[0]];
        body.step(dt).unwrap();
        assert_eq!(body.positions()[wall[0]], held);
        assert_eq!(body.target(wall[0]), None);
    }
}

#[test]
fn a_failed_step_restores_positions_velocities_and_targets() {
    // A non-finite input the stepper refuses, with a kinematic vertex moved before the call.
    for solver in [
        Solver::explicit(),
        Solver::relax(),
        Solver::newton(),
        Solver::vbd(),
        Solver::auto(),
    ] {
        let mut body = small_body();
        body.set_solver(solver).unwrap();
        body.step(1.0 / 60.0).unwrap();
        body.set_target(0, Vec3::new(-0.1, 0.0, 0.0)).unwrap();
        body.positions_mut()[35].x = f32::NAN;
        let (x, v) = (bits(body.positions()), bits(body.velocities()));
        assert_eq!(
            body.step(1.0 / 60.0),
            Err(StepError::NonFiniteInput { vertex: 35 })
        );
        assert_eq!(bits(body.positions()), x, "{solver:?}");
        assert_eq!(bits(body.velocities()), v, "{solver:?}");
        assert_eq!(body.target(0), Some(Vec3::new(-0.1, 0.0, 0.0)));
        // A bad time step touches nothing either.
        assert_eq!(body.step(f32::NAN), Err(StepError::TimeStep));
        assert_eq!(body.step(0.0), Err(StepError::TimeStep));
        assert_eq!(bits(body.positions()), x);
    }

    // A stable fraction that is no fraction: refused when the solver is set (issue #44: it
    // was accepted, and refused only by the step, or for infinity not at all), the body
    // keeping its solver and its state.
    let mut body = small_body();
    body.set_target(0, Vec3::new(-0.1, 0.0, 0.0)).unwrap();
    let (x, v) = (bits(body.positions()), bits(body.velocities()));
    for fraction in [0.0, -1.0, f32::NAN, f32::INFINITY, 1.5] {
        let solver = Solver::Explicit {
            settings: ExplicitSettings::new(),
            stable_fraction: Some(fraction),
        };
        assert_eq!(
            body.set_solver(solver),
            Err(BodyError::StableFraction),
            "{fraction}"
        );
        assert_eq!(body.solver(), &Solver::auto());
        assert_eq!(bits(body.positions()), x);
        assert_eq!(bits(body.velocities()), v);
    }

    // An explicit step far past the stability limit blows up; the state handed back is the one
    // the failing call started from.
    let mut body = small_body();
    let dt = 3.0 * body.stable_time_step().unwrap();
    body.set_solver(Solver::Explicit {
        settings: ExplicitSettings::new(),
        stable_fraction: None,
    })
    .unwrap();
    body.set_target(0, body.rest_positions()[0] + Vec3::new(0.0, 0.01, 0.0))
        .unwrap();
    let mut failed = false;
    for _ in 0..200 {
        let (x, v) = (bits(body.positions()), bits(body.velocities()));
        let target = body.target(0);
        match body.step(dt) {
            Ok(_) => {}
            Err(error) => {
                assert_eq!(error, StepError::EnergyBlowUp);
                assert_eq!(bits(body.positions()), x);
                assert_eq!(bits(body.velocities()), v);
                assert_eq!(body.target(0), target);
                failed = true;
                break;
            }
        }
    }
    assert!(failed, "3x the stable step must blow up within 200 steps");
}

/// Newton's scratch over fresh buffers for the box of [`small_body`], for the reference calls.
struct NewtonBuffers {
    vectors: Vec<Vec3>,
    blocks: Vec<softfem::glam::Mat3>,
    hessians: Vec<softfem::element::TetHessian>,
}

impl NewtonBuffers {
    fn new() -> NewtonBuffers {
        let lengths = scratch_len::newton(36, 60);
        NewtonBuffers {
            vectors: vec![Vec3::ZERO; lengths.vectors],
            blocks: vec![Default::default(); lengths.blocks],
            hessians: vec![Default::default(); lengths.hessians],
        }
    }

    /// One low-level `newton_step` of `reference` in `scene`.
    fn step(
        &mut self,
        reference: &mut Reference,
        scene: &Scene<'_, Vec3>,
        settings: &NewtonSettings,
    ) -> softfem::step::NewtonReport {
        let mut scratch =
            NewtonScratch::new(&mut self.vectors, &mut self.blocks, &mut self.hessians);
        newton_step(
            &reference.model,
            &reference.masses,
            &reference.pinned,
            scene,
            settings,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        )
        .unwrap()
    }
}

/// The automatic solver's report of `report`, or a failure naming what came instead.
fn auto_report(report: StepReport) -> AutoReport {
    match report {
        StepReport::Auto(report) => report,
        other => panic!("not the automatic solver's report: {other:?}"),
    }
}

#[test]
fn the_automatic_solver_is_the_default_and_picks_explicit_for_a_soft_body() {
    // The soft jelly (50 kPa) at 60 Hz: the substeps of half the stable step, counted here
    // from the low-level stable step, are few (under the crossover of 100): explicit, with
    // exactly those substeps, bit for bit the low-level explicit stepper's.
    let mut reference = Reference::new();
    let mut body = small_body();
    assert_eq!(body.solver(), &Solver::auto());
    let stable = stable_time_step(
        &reference.model,
        &reference.masses,
        &reference.pinned,
        &mut [0.0; 36],
    )
    .unwrap();
    let dt = 1.0 / 60.0;
    let substeps = (1..).find(|&k| dt / k as f32 <= 0.5 * stable).unwrap();
    assert!(
        substeps > 1 && substeps <= AutoSettings::CROSSOVER_SUBSTEPS,
        "{substeps}"
    );
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let settings = ExplicitSettings::new().with_substeps(substeps);
    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(36)];
    let mut scratch = ExplicitScratch::new(&mut buffer);
    for step in 0..30 {
        let expected = explicit_step(
            &reference.model,
            &reference.masses,
            &reference.pinned,
            &scene,
            &settings,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        )
        .unwrap();
        let report = auto_report(body.step(dt).unwrap());
        assert_eq!(
            report.chosen,
            AutoChoice::Explicit { substeps },
            "step {step}"
        );
        assert_eq!(report.fallbacks, [None, None], "step {step}");
        assert_eq!(report.run, AutoRun::Explicit(expected), "step {step}");
        assert!(report.converged() && report.resolved());
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
        assert_eq!(bits(body.velocities()), bits(&reference.v), "step {step}");
    }
    assert!(
        body.positions()
            .iter()
            .zip(reference.rest)
            .any(|(x, r)| (*x - *r).length() > 1e-3)
    );
}

#[test]
fn the_automatic_solver_picks_newton_for_a_stiff_body_and_switches_at_the_crossover() {
    // 100 MPa (a hard rubber or a plastic) at 60 Hz: 10 000 times the jelly's stiffness,
    // 100 times the substeps, far over the crossover: Newton's method, bit for bit the
    // low-level step with the automatic solver's Newton settings.
    let stiff = StableNeoHookean::from_young_poisson(1.0e8, 0.45).unwrap();
    let mut reference = Reference::of(stiff);
    let mut body = Body::<Small, _>::from_box(LOW, HIGH, CELLS, DENSITY, stiff).unwrap();
    body.set_gravity(GRAVITY);
    body.set_ground(Some(ground()));
    let stable = stable_time_step(
        &reference.model,
        &reference.masses,
        &reference.pinned,
        &mut [0.0; 36],
    )
    .unwrap();
    let dt = 1.0 / 60.0;
    let substeps = (1..).find(|&k| dt / k as f32 <= 0.5 * stable).unwrap();
    assert!(substeps > AutoSettings::CROSSOVER_SUBSTEPS, "{substeps}");
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let mut newton = NewtonBuffers::new();
    for step in 0..10 {
        let expected = newton.step(&mut reference, &scene, &NewtonSettings::new());
        let report = auto_report(body.step(dt).unwrap());
        assert_eq!(report.chosen, AutoChoice::Newton, "step {step}");
        assert_eq!(report.fallbacks, [None, None], "step {step}");
        assert_eq!(report.run, AutoRun::Newton(expected), "step {step}");
        assert_eq!(report.converged(), expected.converged);
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
        assert_eq!(bits(body.velocities()), bits(&reference.v), "step {step}");
    }
    // The rule's edge: a crossover at exactly the substeps goes explicit, one below goes Newton.
    for (crossover, choice) in [
        (substeps, AutoChoice::Explicit { substeps }),
        (substeps - 1, AutoChoice::Newton),
    ] {
        let settings = AutoSettings::new().with_crossover(crossover);
        assert_eq!(settings.choose(substeps), choice);
        body.set_solver(Solver::Auto(settings)).unwrap();
        assert_eq!(auto_report(body.step(dt).unwrap()).chosen, choice);
    }
    // A fraction that is no fraction is refused, as the explicit solver's.
    let bad = AutoSettings {
        stable_fraction: 0.0,
        ..AutoSettings::new()
    };
    assert_eq!(
        body.set_solver(Solver::Auto(bad)),
        Err(BodyError::StableFraction)
    );
}

#[test]
fn an_explicit_blow_up_falls_back_to_newton_from_the_restored_state() {
    // A growth limit of 1.0001 makes the blow-up detector trip on a body merely falling (its
    // kinetic energy grows by far more than 0.01 % a substep): the explicit stepper refuses
    // the frame and restores the state, and Newton's method steps the frame from that state,
    // bit for bit the low-level Newton step from the same start.
    let mut reference = Reference::new();
    let mut body = small_body();
    let touchy = AutoSettings {
        explicit: ExplicitSettings {
            max_energy_growth: 1.0001,
            ..ExplicitSettings::new()
        },
        ..AutoSettings::new()
    };
    body.set_solver(Solver::Auto(touchy)).unwrap();
    let dt = 1.0 / 60.0;
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let mut newton = NewtonBuffers::new();
    // Three frames of free fall: the box starts 2 cm above the ground, reached after
    // sqrt(2 * 0.02 / 9.81) = 64 ms, in the fourth frame.
    for step in 0..3 {
        let expected = newton.step(&mut reference, &scene, &touchy.newton);
        let report = auto_report(body.step(dt).unwrap());
        assert!(
            matches!(report.chosen, AutoChoice::Explicit { .. }),
            "{report:?}"
        );
        assert_eq!(
            report.fallbacks,
            [
                Some(Fallback::ExplicitToNewton {
                    error: StepError::EnergyBlowUp
                }),
                None
            ],
            "step {step}"
        );
        assert_eq!(report.fallback_count(), 1);
        assert_eq!(report.run, AutoRun::Newton(expected), "step {step}");
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
        assert_eq!(bits(body.velocities()), bits(&reference.v), "step {step}");
    }
    assert!(
        body.positions()
            .iter()
            .zip(reference.rest)
            .any(|(x, r)| (*x - *r).length() > 1e-3)
    );
}

#[test]
fn newton_that_does_not_converge_is_retried_in_two_half_steps_and_reported() {
    // Newton's method with one iteration and a tolerance no step of a falling body meets in
    // one: the whole step spends its budget above the floor, so the frame is stepped again
    // from its start as two half steps. The thrown-away step's report, the halves' reports and
    // the state are those of the low-level calls, bit for bit; the report says not converged.
    let mut reference = Reference::new();
    let mut body = small_body();
    let starved = AutoSettings {
        newton: NewtonSettings::new().with_tolerance(1e-7, 1),
        ..AutoSettings::new().with_crossover(0)
    };
    body.set_solver(Solver::Auto(starved)).unwrap();
    let dt = 1.0 / 60.0;
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let half = Scene::new(0.5 * dt)
        .with_gravity(GRAVITY)
        .with_ground(ground());
    let mut newton = NewtonBuffers::new();
    for step in 0..3 {
        let (x, v) = (reference.x.clone(), reference.v.clone());
        let whole = newton.step(&mut reference, &scene, &starved.newton);
        assert!(
            !whole.converged && !softfem::body::stopped_at_floor(&whole),
            "{whole:?}"
        );
        (reference.x, reference.v) = (x, v);
        let first = newton.step(&mut reference, &half, &starved.newton);
        let second = newton.step(&mut reference, &half, &starved.newton);
        let report = auto_report(body.step(dt).unwrap());
        assert_eq!(report.chosen, AutoChoice::Newton);
        assert_eq!(
            report.fallbacks,
            [Some(Fallback::NewtonToHalfSteps { report: whole }), None],
            "step {step}"
        );
        assert_eq!(
            report.run,
            AutoRun::NewtonHalves([first, second]),
            "step {step}"
        );
        assert_eq!(report.converged(), first.converged && second.converged);
        assert!(
            !report.converged(),
            "a one-iteration Newton step at 1e-7 of the load"
        );
        assert_eq!(report.iterations(), first.iterations + second.iterations);
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
        assert_eq!(bits(body.velocities()), bits(&reference.v), "step {step}");
    }
}

#[test]
fn a_failed_automatic_step_leaves_the_state_and_a_world_refuses_the_automatic_solver() {
    // A wrong-length load is refused by whichever stepper the rule picked (explicit here,
    // Newton's method with the crossover at 0), before anything runs: no fallback hides it,
    // and the state and a kinematic target are as they were.
    for settings in [AutoSettings::new(), AutoSettings::new().with_crossover(0)] {
        let mut body = small_body();
        body.set_solver(Solver::Auto(settings)).unwrap();
        body.step(1.0 / 60.0).unwrap();
        body.set_target(0, Vec3::new(-0.1, 0.0, 0.0)).unwrap();
        let (x, v) = (bits(body.positions()), bits(body.velocities()));
        let forces = [Vec3::Y; 3];
        let scene = body.scene(1.0 / 60.0).with_external_forces(&forces);
        assert!(body.step_with(&scene).is_err());
        assert_eq!(bits(body.positions()), x, "{settings:?}");
        assert_eq!(bits(body.velocities()), v, "{settings:?}");
        assert_eq!(body.target(0), Some(Vec3::new(-0.1, 0.0, 0.0)));
    }
}

/// `FixedStorage<36, 60>` but for the vector scratch, with room for Newton's nine vectors a
/// vertex and not the automatic solver's eleven.
struct NineVectors;

impl softfem::body::Storage for NineVectors {
    type Vectors = softfem::body::Fixed<Vec3, 1, 36>;
    type Reals = softfem::body::Fixed<f32, 1, 36>;
    type Flags = softfem::body::Fixed<bool, 1, 36>;
    type Tets = softfem::body::Fixed<[u32; 4], 1, 60>;
    type Rests = softfem::body::Fixed<TetRest, 1, 60>;
    type RestBlocks = softfem::body::Fixed<softfem::mesh::TetRestBlock, 0, 1>;
    type Scratch = softfem::body::Fixed<Vec3, 9, 36>;
    type Blocks = softfem::body::Fixed<softfem::glam::Mat3, 1, 36>;
    type Hessians = softfem::body::Fixed<softfem::element::TetHessian, 1, 60>;
    type Indices = softfem::body::Fixed<u32, 17, 60>;
    type LayoutValues = softfem::body::Fixed<f32, 0, 1>;
    type LayoutCorners = softfem::body::Fixed<u32, 0, 1>;
}

#[test]
fn a_storage_without_room_for_the_automatic_solver_says_which_buffer() {
    // A body needs 13 vectors a vertex (Newton's 9, the frame's start for the retry in half
    // steps, and a coupled step's start): a storage with 9 is refused when the body is built,
    // naming the vector scratch and the 13 x 36 entries it needs, not at the first fallback.
    let refused = Body::<NineVectors, _>::from_box(LOW, HIGH, CELLS, DENSITY, jelly());
    assert_eq!(
        refused.err(),
        Some(BodyError::Capacity {
            buffer: BodyBuffer::Scratch,
            needed: 13 * 36
        })
    );
}

#[test]
fn double_precision_body_steps() {
    use softfem::f64::body::{Body, FixedStorage};
    use softfem::f64::material::StableNeoHookean;
    use softfem::glam::DVec3;
    let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap();
    let mut body = Body::<FixedStorage<36, 60>, _>::from_box(
        DVec3::ZERO,
        DVec3::new(0.3, 0.2, 0.2),
        CELLS,
        1000.0,
        jelly,
    )
    .unwrap();
    body.set_gravity(DVec3::new(0.0, -9.81, 0.0));
    let dt = 0.01;
    for _ in 0..10 {
        body.step(dt).unwrap();
    }
    // Free fall from rest for 0.1 s, a rigid translation: every vertex dropped g t^2 / 2 in
    // the limit of small substeps; symplectic Euler with k substeps of h drops
    // g h^2 k (k + 1) / 2, within h / t = 1/k of it.
    let drop = body.rest_positions()[0].y - body.positions()[0].y;
    let exact = 0.5 * 9.81 * 0.1 * 0.1;
    assert!((drop - exact).abs() < 0.05 * exact, "{drop} vs {exact}");
    // That was the automatic solver's explicit choice (few substeps for the jelly); a stiff
    // body's frames go to Newton's method in f64 as in f32.
    use softfem::f64::body::{AutoChoice, StepReport};
    let report = body.step(dt).unwrap();
    assert!(
        matches!(report, StepReport::Auto(r) if matches!(r.chosen, AutoChoice::Explicit { .. })),
        "{report:?}"
    );
    let stiff = StableNeoHookean::from_young_poisson(1.0e8, 0.45).unwrap();
    body.set_material(stiff);
    let report = body.step(1.0 / 60.0).unwrap();
    assert!(
        matches!(report, StepReport::Auto(r) if r.chosen == AutoChoice::Newton && r.resolved()),
        "{report:?}"
    );
}

#[cfg(feature = "alloc")]
mod alloc_storage {
    use super::*;
    use softfem::body::VecStorage;

    #[test]
    fn growable_storage_gives_the_bits_of_fixed_storage() {
        let mut fixed = small_body();
        let mut growing =
            Body::<VecStorage, _>::from_box(LOW, HIGH, CELLS, DENSITY, jelly()).unwrap();
        growing.set_gravity(GRAVITY);
        growing.set_ground(Some(ground()));
        // The growable body keeps its rest data in blocks too (60 tets: 4 blocks), the fixed
        // one has no room for them: the same bits either way.
        assert_eq!(growing.mesh().rest_blocks().len(), 4);
        assert!(fixed.mesh().rest_blocks().is_empty());
        for solver in [
            Solver::explicit(),
            Solver::relax(),
            Solver::newton(),
            Solver::vbd(),
        ] {
            fixed.set_solver(solver).unwrap();
            growing.set_solver(solver).unwrap();
            for _ in 0..5 {
                assert_eq!(fixed.step(1.0 / 60.0), growing.step(1.0 / 60.0));
            }
        }
        assert_eq!(bits(fixed.positions()), bits(growing.positions()));
        assert_eq!(bits(fixed.velocities()), bits(growing.velocities()));
        // 40 000 vertices: no fixed capacity to run out of.
        let big =
            Body::<VecStorage, _>::from_box(Vec3::ZERO, Vec3::ONE, [40, 40, 24], DENSITY, jelly());
        assert_eq!(big.unwrap().vertex_count(), 41 * 41 * 25);
    }

    #[test]
    fn a_tetgen_mesh_is_oriented_and_stepped() {
        // Two tetrahedra sharing a face, the second written negatively oriented.
        let node = "5 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n4 1 1 1\n";
        let ele = "2 4 0\n0 0 1 2 3\n1 1 3 2 4\n";
        let mesh = softfem::asset::tetgen::read_tetgen(node, ele).unwrap();
        let mut body = Body::<VecStorage, _>::from_tetgen(&mesh, DENSITY, jelly()).unwrap();
        let volume = body.mesh().rest_volume();
        // 1/6 for the corner tet; the second has edges (-1,0,1), (-1,1,0), (0,1,1) from (1,0,0):
        // |det| / 6 = 2 / 6.
        assert!((volume - 0.5).abs() < 1e-6, "{volume}");
        body.set_gravity(GRAVITY);
        body.step(0.001).unwrap();
        assert!(body.positions().iter().all(|x| x.is_finite()));
    }
}

#[test]
fn fixed_storage_takes_the_memory_its_documentation_states() {
    // 262 bytes per vertex and 304 per tetrahedron in f32 (see `FixedStorage`), plus the
    // lengths, the material, the solver settings and the caches: under 1 KB.
    type Bar = Body<FixedStorage<54, 120>, StableNeoHookean>;
    let size = core::mem::size_of::<Bar>();
    let buffers = 54 * 262 + 120 * 304;
    println!("Body<FixedStorage<54, 120>, StableNeoHookean>: {size} bytes");
    assert!(
        size >= buffers && size < buffers + 1024,
        "{size} against {buffers}"
    );
}

/// The material of [`jelly`], as a `const` for the static body.
const JELLY: StableNeoHookean = match softfem::material::Lame::from_young_poisson(5.0e4, 0.45) {
    Ok(lame) => StableNeoHookean::new(lame),
    Err(_) => panic!("the jelly's parameters are valid"),
};

/// A fixed-capacity body in a `static` (the firmware's way: built in place, never on the stack).
static STATIC_BODY: std::sync::Mutex<Body<Small, StableNeoHookean>> =
    std::sync::Mutex::new(Body::empty(JELLY));

#[test]
fn a_static_body_rebuilt_in_place_matches_the_low_level_calls_bit_for_bit() {
    assert_eq!(JELLY, jelly());
    let mut body = STATIC_BODY.lock().unwrap();
    // Nothing built yet: stepping is an error, not a panic, and changes nothing.
    assert_eq!((body.vertex_count(), body.tet_count()), (0, 0));
    assert_eq!(body.step(0.01), Err(StepError::EmptyBody));
    body.set_gravity(GRAVITY);
    body.set_ground(Some(ground()));
    body.rebuild_from_box(LOW, HIGH, CELLS, DENSITY).unwrap();

    let mut reference = Reference::new();
    assert_eq!(body.masses(), &reference.masses[..]);
    assert_eq!(body.rest_positions(), reference.rest);
    assert_eq!(body.positions(), reference.rest);
    pin_wall(&mut body, &mut reference);
    let dt = 0.5 * body.stable_time_step().unwrap();
    let scene = Scene::new(dt).with_gravity(GRAVITY).with_ground(ground());
    let settings = ExplicitSettings::new();
    body.set_solver(Solver::Explicit {
        settings,
        stable_fraction: None,
    })
    .unwrap();
    assert_explicit_matches(&mut body, &mut reference, &scene, &settings, 40, 1e-4);
}

#[test]
fn rebuilding_keeps_the_settings_and_replaces_geometry_state_pins_and_history() {
    let relax = Solver::Relax(
        RelaxSettings::new()
            .with_tolerance(1e-3, 200)
            .with_chebyshev(0.995, 2.0, 10),
    );
    // A used body: relaxation, pins, a few steps taken (history and preconditioner cached).
    let mut used = small_body();
    used.set_solver(relax).unwrap();
    used.set_pinned(0, true).unwrap();
    used.set_target(0, LOW + Vec3::X * 0.01).unwrap();
    for _ in 0..5 {
        used.step(1.0 / 60.0).unwrap();
    }
    // Rebuilt as a smaller box of arrays: 2 x 1 x 1 cells.
    let (rest, tets) =
        crate::common::scenes::generated_box!(LOW, HIGH, (2, 1, 1), BoxSplit::Alternating5);
    let (n, t) = (rest.len(), tets.len());
    used.rebuild_from_arrays(&rest, &tets, DENSITY).unwrap();
    assert_eq!((used.vertex_count(), used.tet_count()), (n, t));
    assert_eq!(used.positions(), &rest[..]);
    assert!(used.velocities().iter().all(|v| *v == Vec3::ZERO));
    assert!(used.pinned().iter().all(|p| !p) && used.target(0).is_none());
    assert_eq!(used.solver(), &relax);
    assert_eq!(used.gravity(), GRAVITY);
    assert_eq!(used.ground(), Some(ground()));

    // It steps as a body built fresh with the same settings, bit for bit (nothing of the old
    // body's history or cached preconditioner is used).
    let mut fresh = Body::<Small, _>::from_arrays(&rest, &tets, DENSITY, jelly()).unwrap();
    fresh.set_gravity(GRAVITY);
    fresh.set_ground(Some(ground()));
    fresh.set_solver(relax).unwrap();
    for step in 0..20 {
        assert_eq!(
            used.step(1.0 / 60.0).unwrap(),
            fresh.step(1.0 / 60.0).unwrap()
        );
        assert_eq!(
            bits(used.positions()),
            bits(fresh.positions()),
            "step {step}"
        );
        assert_eq!(
            bits(used.velocities()),
            bits(fresh.velocities()),
            "step {step}"
        );
    }
    assert!(fresh.positions()[5].y < rest[5].y - 1e-4, "it fell");
}

#[test]
fn a_failed_rebuild_leaves_an_empty_body_that_refuses_to_step() {
    let mut body = small_body();
    let too_big = body.rebuild_from_box(LOW, HIGH, [4, 2, 2], DENSITY);
    assert_eq!(
        too_big,
        Err(BodyError::Capacity {
            buffer: BodyBuffer::Vertices,
            needed: 45
        })
    );
    assert_eq!((body.vertex_count(), body.tet_count()), (0, 0));
    assert_eq!(body.step(0.01), Err(StepError::EmptyBody));

    let mut rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    rest[2].y = f32::NAN;
    let nan = body.rebuild_from_arrays(&rest, &[[0, 1, 2, 3]], DENSITY);
    assert!(matches!(nan, Err(BodyError::Mesh(_))), "{nan:?}");
    assert_eq!((body.vertex_count(), body.tet_count()), (0, 0));
    let out_of_range = body.rebuild_from_arrays(&rest, &[[0, 1, 2, 4]], DENSITY);
    assert!(matches!(out_of_range, Err(BodyError::Mesh(_))));
    assert_eq!(body.step(0.01), Err(StepError::EmptyBody));

    // And it can be built again.
    body.rebuild_from_box(LOW, HIGH, CELLS, DENSITY).unwrap();
    assert_eq!(body.masses(), &Reference::new().masses[..]);
    body.step(0.01).unwrap();
}

/// A body stepped in a scene with borrowed external forces and fixed axes (`Body::step_with`)
/// gives the bits of the low-level call in the same scene, for the explicit stepper and Newton;
/// and the loads act: the loaded, x-fixed vertices moved, but never along x.
#[test]
fn a_body_steps_with_borrowed_loads_as_the_low_level_calls() {
    let mut reference = Reference::new();
    let mut body = small_body();
    pin_wall(&mut body, &mut reference);
    let model = reference.model;
    let dt = 1.0 / 60.0;
    // A push of 0.2 N along +z on every vertex of the far end, rollers in x there.
    let far = reference
        .rest
        .iter()
        .map(|x| x.x)
        .fold(f32::NEG_INFINITY, f32::max);
    let loaded: Vec<bool> = reference.rest.iter().map(|x| x.x == far).collect();
    let forces: Vec<Vec3> = loaded
        .iter()
        .map(|&l| if l { Vec3::Z * 0.2 } else { Vec3::ZERO })
        .collect();
    let axes: Vec<u8> = loaded
        .iter()
        .map(|&l| if l { FIXED_X } else { 0 })
        .collect();
    let scene = Scene::new(dt)
        .with_gravity(GRAVITY)
        .with_ground(ground())
        .with_external_forces(&forces)
        .with_fixed_axes(&axes);
    let newton = NewtonSettings::new().with_tolerance(1e-3, 20);
    body.set_solver(Solver::Newton(newton)).unwrap();
    let lengths = scratch_len::newton(36, 60);
    let mut vectors = vec![Vec3::ZERO; lengths.vectors];
    let mut blocks = vec![Default::default(); lengths.blocks];
    let mut hessians = vec![Default::default(); lengths.hessians];
    let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
    for step in 0..10 {
        let expected = newton_step(
            &model,
            &reference.masses,
            &reference.pinned,
            &scene,
            &newton,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        )
        .unwrap();
        let report = body.step_with(&scene).unwrap();
        assert_eq!(report, StepReport::Newton(expected), "step {step}");
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
    }
    let rows = || reference.x.iter().zip(reference.rest).zip(&loaded);
    for ((x, r), _) in rows().filter(|(_, l)| **l) {
        assert_eq!(
            x.x.to_bits(),
            r.x.to_bits(),
            "a fixed x moved: {x} from {r}"
        );
    }
    assert!(
        rows().any(|((x, r), &l)| l && x.z - r.z > 1e-4),
        "the push moved nothing along z"
    );
    // The same scene with the explicit stepper, fixed substeps.
    let settings = ExplicitSettings::new().with_substeps(40);
    body.set_solver(Solver::Explicit {
        settings,
        stable_fraction: None,
    })
    .unwrap();
    let mut buffer = vec![Vec3::ZERO; scratch_len::explicit(36)];
    let mut scratch = ExplicitScratch::new(&mut buffer);
    for step in 0..5 {
        let expected = explicit_step(
            &model,
            &reference.masses,
            &reference.pinned,
            &scene,
            &settings,
            &mut reference.x,
            &mut reference.v,
            &mut scratch,
        );
        assert_eq!(
            body.step_with(&scene),
            expected.map(StepReport::Explicit),
            "step {step}"
        );
        assert_eq!(bits(body.positions()), bits(&reference.x), "step {step}");
    }
}

/// Issue #44, part A, in both precisions: a body refuses at construction what every step would
/// refuse later (a vertex in no tetrahedron, which has no mass) and a `stable_fraction` that is
/// no fraction of the stable step (infinity was accepted).
mod input_checks {
    macro_rules! input_tests {
        ($precision:ident, $($api:ident)::+) => {
            mod $precision {
                use $($api)::+::body::{Body, FixedStorage, Solver};
                use $($api)::+::material::StableNeoHookean;
                use $($api)::+::step::ExplicitSettings;
                use $($api)::+::types::{Real, Vec3};
                use softfem::BodyError;

                fn jelly() -> StableNeoHookean {
                    StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap()
                }

                /// Was: Ok, then every step failed with `StepError::Mass { vertex: 4 }`.
                #[test]
                fn a_vertex_in_no_tetrahedron_is_refused_by_name() {
                    let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::splat(2.0)];
                    let tets = [[0, 1, 2, 3]];
                    type Storage = FixedStorage<5, 1>;
                    let built = Body::<Storage, _>::from_arrays(&rest, &tets, 1000.0, jelly());
                    let error = built.err().unwrap();
                    assert_eq!(error, BodyError::UnusedVertex { vertex: 4 });
                    assert_eq!(
                        error.to_string(),
                        "vertex 4 is in no tetrahedron (it would have no mass)"
                    );
                    // The same through a rebuild, which leaves the body empty.
                    let mut body =
                        Body::<Storage, _>::from_arrays(&rest[..4], &tets, 1000.0, jelly()).unwrap();
                    assert_eq!(
                        body.rebuild_from_arrays(&rest, &tets, 1000.0),
                        Err(BodyError::UnusedVertex { vertex: 4 })
                    );
                    assert_eq!(body.vertex_count(), 0);
                }

                /// Was: infinity accepted (every step then one substep, whatever `dt`).
                #[test]
                fn a_stable_fraction_outside_zero_to_one_is_refused() {
                    let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
                    let mut body =
                        Body::<FixedStorage<4, 1>, _>::from_arrays(&rest, &[[0, 1, 2, 3]], 1000.0, jelly())
                            .unwrap();
                    let explicit = |fraction: Real| Solver::Explicit {
                        settings: ExplicitSettings::new(),
                        stable_fraction: Some(fraction),
                    };
                    for fraction in [Real::INFINITY, Real::NEG_INFINITY, Real::NAN, 0.0, -0.5, 1.0 + Real::EPSILON] {
                        let error = body.set_solver(explicit(fraction)).unwrap_err();
                        assert_eq!(error, BodyError::StableFraction, "{fraction}");
                        assert_eq!(
                            error.to_string(),
                            "the explicit solver's stable_fraction must be a finite fraction in \
                             (0, 1] of the stable time step"
                        );
                    }
                    for fraction in [0.25, 0.5, 1.0] {
                        body.set_solver(explicit(fraction)).unwrap();
                        body.step(0.01).unwrap();
                    }
                }
            }
        };
    }

    input_tests!(single, softfem);
    input_tests!(double, softfem::f64);
}

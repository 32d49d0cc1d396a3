//! A whole simulation the way firmware would run it: no heap at all. A fixed-capacity body
//! (const generics, plain arrays) holds a 5 x 2 x 2-cell bar generated in place, pinned at one
//! end, stepped first with the explicit stepper and then with implicit Euler relaxation; the
//! memory it needs is `size_of::<Body<54, 120>>()`, printed. The first test writes that body by
//! hand over the low-level kernels; the second uses the crate's owning
//! `softfem::body::Body<FixedStorage<54, 120>, _>` in a static, with a capsule under the bar's
//! tip for it to rest on.

use softfem::element::TetRest;
use softfem::generate::{BoxSplit, fill_box};
use softfem::glam::Vec3;
use softfem::material::StableNeoHookean;
use softfem::mesh::TetMesh;
use softfem::step::{
    ExplicitScratch, ExplicitSettings, RelaxScratch, RelaxSettings, Scene, TetElastic,
    explicit_step, relax_step, stable_time_step,
};

/// Everything one body needs, with capacity fixed at compile time: `V` vertices, `T` tets.
struct Body<const V: usize, const T: usize> {
    rest: [Vec3; V],
    tets: [[u32; 4]; T],
    rest_data: [TetRest; T],
    positions: [Vec3; V],
    velocities: [Vec3; V],
    masses: [f32; V],
    pinned: [bool; V],
    /// Explicit scratch: forces of two substeps, position backup, velocity backup.
    explicit_scratch: [[Vec3; V]; 4],
    /// Relaxation scratch: five vectors and one scalar per vertex.
    relax_vectors: [[Vec3; V]; 5],
    relax_scalars: [f32; V],
}

impl<const V: usize, const T: usize> Body<V, T> {
    const fn empty() -> Self {
        Body {
            rest: [Vec3::ZERO; V],
            tets: [[0; 4]; T],
            rest_data: [TetRest {
                dm_inv: softfem::glam::Mat3::ZERO,
                volume: 0.0,
            }; T],
            positions: [Vec3::ZERO; V],
            velocities: [Vec3::ZERO; V],
            masses: [0.0; V],
            pinned: [false; V],
            explicit_scratch: [[Vec3::ZERO; V]; 4],
            relax_vectors: [[Vec3::ZERO; V]; 5],
            relax_scalars: [0.0; V],
        }
    }
}

/// The 5 x 2 x 2-cell bar: 6 * 3 * 3 vertices, 5 * 2 * 2 * 6 tetrahedra.
type Bar = Body<54, 120>;

/// In a static, as firmware would place it (no stack or heap for the buffers).
static mut BAR: Bar = Bar::empty();

#[test]
fn a_pinned_bar_sags_and_settles_without_allocating() {
    println!("Body<54, 120>: {} bytes", core::mem::size_of::<Bar>());
    // The test owns the static for its whole run (this is the only test touching it).
    let body: &mut Bar = unsafe { &mut *core::ptr::addr_of_mut!(BAR) };
    let (length, side) = (0.5f32, 0.1f32);
    fill_box(
        Vec3::ZERO,
        Vec3::new(length, side, side),
        5,
        2,
        2,
        BoxSplit::Kuhn6,
        &mut body.rest,
        &mut body.tets,
    )
    .unwrap();
    let mesh = TetMesh::new(&body.rest, &body.tets, &mut body.rest_data).unwrap();
    let material = StableNeoHookean::from_young_poisson(2.0e6, 0.4).unwrap();
    let model = TetElastic::new(mesh, material);
    mesh.lumped_masses(1100.0, &mut body.masses).unwrap();
    for (pin, x) in body.pinned.iter_mut().zip(&body.rest) {
        *pin = x.x == 0.0;
    }
    body.positions = body.rest;
    let gravity = Vec3::new(0.0, -9.81, 0.0);

    // Explicit: 0.3 s at 0.9 of the stable bound, damped.
    let dt = 0.9
        * stable_time_step(&model, &body.masses, &body.pinned, &mut body.relax_scalars).unwrap();
    let scene = Scene::new(dt).with_gravity(gravity);
    let settings = ExplicitSettings::new().with_damping(20.0);
    let mut scratch = ExplicitScratch::new(body.explicit_scratch.as_flattened_mut());
    let steps = (0.3 / dt) as usize;
    for _ in 0..steps {
        explicit_step(
            &model,
            &body.masses,
            &body.pinned,
            &scene,
            &settings,
            &mut body.positions,
            &mut body.velocities,
            &mut scratch,
        )
        .unwrap();
    }
    let tip = |positions: &[Vec3; 54]| {
        positions
            .iter()
            .zip(&body.rest)
            .filter(|(_, r)| r.x == length)
            .map(|(p, r)| r.y - p.y)
            .sum::<f32>()
            / 9.0
    };
    let explicit_sag = tip(&body.positions);

    // Then implicit Euler at 60 Hz for 1 s from that state.
    let scene = Scene::new(1.0 / 60.0).with_gravity(gravity);
    let relax = RelaxSettings::new()
        .with_tolerance(1e-3, 500)
        .with_momentum(0.5);
    let mut scratch = RelaxScratch::new(
        body.relax_vectors.as_flattened_mut(),
        &mut body.relax_scalars,
    );
    let mut iterations = 0;
    for _ in 0..60 {
        let report = relax_step(
            &model,
            &body.masses,
            &body.pinned,
            &scene,
            &relax,
            &mut body.positions,
            &mut body.velocities,
            &mut scratch,
        )
        .unwrap();
        iterations += report.iterations;
    }
    let relaxed_sag = tip(&body.positions);
    println!(
        "explicit: {steps} steps of {dt:.2e} s, tip sag {explicit_sag:.5} m; \
         implicit: 60 steps, {iterations} iterations, tip sag {relaxed_sag:.5} m"
    );

    // Euler-Bernoulli cantilever under its own weight: q L^4 / (8 E I) with q = rho g A and
    // I = a^4 / 12: 0.5^4 * 1100 * 9.81 * 0.01 / (8 * 2e6 * 8.33e-6) = 5.1 cm. Two linear
    // tetrahedra across the section lock in bending (nu = 0.4 too), so the sag is a fraction of
    // that: about 1.8 cm here.
    assert!(relaxed_sag > 0.005 && relaxed_sag < 0.051, "{relaxed_sag}");
    // The explicit run (0.3 s, damped) is near the same shape, still settling.
    assert!((relaxed_sag - explicit_sag).abs() < 0.2 * relaxed_sag);
    assert!(body.velocities.iter().all(|v| v.length() < 2e-2));
    for ((x, r), pinned) in body.positions.iter().zip(&body.rest).zip(&body.pinned) {
        if *pinned {
            assert_eq!(x, r);
        }
    }
}

/// The crate's owning body of the same bar, in a static as firmware would place it (`None` until
/// built: the body has no `const` constructor).
type OwnedBar = softfem::body::Body<softfem::body::FixedStorage<54, 120>, StableNeoHookean>;
static mut OWNED_BAR: Option<OwnedBar> = None;

/// The same pinned bar, built and stepped by `softfem::body::Body` with a capsule 1 cm under it
/// near its free end: it sags onto the capsule and rests there (explicit, then relaxation), never inside
/// it, and its tip sags less than the 1.8 cm it does hanging free (the test above) but touches.
#[test]
fn the_owning_body_rests_on_a_capsule_without_allocating() {
    use softfem::body::{Solver, StepReport};
    use softfem::step::Collider;
    println!(
        "softfem::body::Body<FixedStorage<54, 120>, _>: {} bytes",
        core::mem::size_of::<OwnedBar>()
    );
    let (length, side) = (0.5f32, 0.1f32);
    let material = StableNeoHookean::from_young_poisson(2.0e6, 0.4).unwrap();
    let built = OwnedBar::from_box_split(
        Vec3::ZERO,
        Vec3::new(length, side, side),
        [5, 2, 2],
        BoxSplit::Kuhn6,
        1100.0,
        material,
    )
    .unwrap();
    // The test owns the static for its whole run (this is the only test touching it).
    let body = unsafe { (*core::ptr::addr_of_mut!(OWNED_BAR)).insert(built) };
    for vertex in 0..body.vertex_count() {
        if body.rest_positions()[vertex].x == 0.0 {
            body.set_pinned(vertex, true).unwrap();
        }
    }
    body.set_gravity(Vec3::new(0.0, -9.81, 0.0));
    // A capsule across the bar (along z), its top 1 cm under the bar's bottom at x = 0.4 m,
    // right under a row of vertices (contact is tested at the vertices: a capsule between two
    // rows would pass through the bottom face unseen).
    let radius = 0.02;
    let capsule = Collider::capsule(
        Vec3::new(0.4, -0.01 - radius, -0.1),
        Vec3::new(0.4, -0.01 - radius, 0.2),
        radius,
    )
    .with_friction(0.5);
    let colliders = [capsule];
    body.set_solver(Solver::Explicit {
        settings: ExplicitSettings::new().with_damping(20.0),
        stable_fraction: Some(0.9),
    })
    .unwrap();
    let mut deepest: f32 = 0.0;
    let inside = |body: &OwnedBar| {
        body.positions()
            .iter()
            .map(|&x| -capsule.distance(x))
            .fold(0.0f32, f32::max)
    };
    for _ in 0..18 {
        body.step_with_colliders(1.0 / 60.0, &colliders).unwrap(); // 0.3 s
        deepest = deepest.max(inside(body));
    }
    body.set_solver(Solver::Relax(
        RelaxSettings::new()
            .with_tolerance(1e-3, 500)
            .with_momentum(0.5),
    ))
    .unwrap();
    let mut iterations = 0;
    for _ in 0..60 {
        match body.step_with_colliders(1.0 / 60.0, &colliders).unwrap() {
            StepReport::Relax(report) => iterations += report.iterations,
            other => panic!("{other:?}"),
        }
        deepest = deepest.max(inside(body));
    }
    let tip_sag = body
        .positions()
        .iter()
        .zip(body.rest_positions())
        .filter(|(_, r)| r.x == length)
        .map(|(p, r)| r.y - p.y)
        .sum::<f32>()
        / 9.0;
    let closest = body
        .positions()
        .iter()
        .map(|&x| capsule.distance(x))
        .fold(f32::INFINITY, f32::min);
    println!(
        "owning body: tip sag {tip_sag:.5} m, closest to the capsule {closest:.2e} m, deepest \
         inside {deepest:.2e} m, {iterations} relaxation iterations"
    );
    // The projection's rounding: 64 eps on metre-sized coordinates.
    assert!(deepest <= 64.0 * f32::EPSILON, "{deepest}");
    assert!(closest < 1e-4, "{closest}"); // resting on it
    assert!(tip_sag > 0.008 && tip_sag < 0.015, "{tip_sag}");
    assert!(body.velocities().iter().all(|v| v.length() < 2e-2));
}

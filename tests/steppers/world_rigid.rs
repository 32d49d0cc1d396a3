//! Dynamic rigid bodies solved with a world of soft bodies in one implicit Euler step
//! ([`World::step_with_rigid_bodies`], issue #42 item 1), against references the coupling does
//! not compute: a rigid lid lying across two soft cubes, and one on a stack of two, is carried
//! by its weight and the ground by every weight (statics); a free box thrown at two jellies
//! touching each other conserves the total momentum of the three (no gravity); a world of one
//! body steps with its lid as the single `Body` does, to the bit (the same iterations from the
//! same restored start); bad inputs are refused with nothing moved; jellies hanging from a bar
//! by hard and soft attachments move with it conserving momentum, and a static bar carries
//! their weight.

use softfem::f64::body::{Body, CoupledReport, Solver, VecStorage};
use softfem::f64::material::StableNeoHookean;
use softfem::f64::step::contact::potential::ContactBarrier;
use softfem::f64::step::{Collider, CouplingSettings, HalfSpace, NewtonSettings, Reaction};
use softfem::f64::types::{Quat, Real, Vec3};
use softfem::f64::world::World;
use softfem::{StepBuffer, StepError};

type Jellies = World<VecStorage, StableNeoHookean>;

const GRAVITY: Real = 9.81;
/// The cubes' edge (m), Young's modulus (Pa) and density (kg/m^3).
const EDGE: Real = 0.2;
const YOUNG: Real = 1.0e5;
const DENSITY: Real = 10.0;

/// A solid box's principal moments of inertia (kg m^2) about its centre.
fn box_inertia(mass: Real, half: Vec3) -> Vec3 {
    let s = half * half;
    Vec3::new(s.y + s.z, s.x + s.z, s.x + s.y) * (mass / 3.0)
}

/// Newton's method to `1e-10` relative: the reactions' impulse is the soft step's momentum
/// balance, whose error is the residual times `dt` at each touching vertex.
fn newton() -> Solver {
    Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50))
}

/// A world of frictionless 20 cm jelly cubes of `cells` per edge with their lowest corners at
/// `corners`, Newton's method, gravity along -y and no ground (the tests that need one pass it
/// as a static collider, whose reaction they read).
fn jellies(corners: &[Vec3], cells: usize) -> Jellies {
    let material = StableNeoHookean::from_young_poisson(YOUNG, 0.3).unwrap();
    let mut world = Jellies::new();
    for &low in corners {
        world
            .add_box(low, low + Vec3::splat(EDGE), [cells; 3], DENSITY, material)
            .unwrap();
    }
    world.set_solver(newton()).unwrap();
    world.set_gravity(Vec3::new(0.0, -GRAVITY, 0.0));
    world
}

/// A free lid of `mass` (kg) and half extents `half` resting with its bottom face at `y`.
fn lid(mass: Real, half: Vec3, y: Real) -> Collider<'static> {
    Collider::cuboid(Vec3::new(0.0, y + half.y, 0.0), half, Quat::IDENTITY)
        .with_mass(mass, box_inertia(mass, half))
}

/// Steps `world` with `colliders` (`frames` of `dt`): the mean force (N) along y on each
/// collider and the last collider's mean height (m) over the last `averaged` frames, the most
/// coupling iterations a step took, and whether every step converged.
fn settle(
    world: &mut Jellies,
    colliders: &mut [Collider<'_>],
    dt: Real,
    (frames, averaged): (usize, usize),
) -> (Vec<Real>, Real, u32, bool) {
    let mut reactions = vec![Reaction::ZERO; colliders.len()];
    let mut forces = vec![0.0; colliders.len()];
    let (mut height, mut most, mut converged) = (0.0, 0, true);
    for frame in 0..frames {
        let scene = world.scene(dt);
        let report = world
            .step_with_rigid_bodies(&scene, colliders, &mut reactions)
            .unwrap();
        most = most.max(report.coupling.iterations);
        converged &= report.converged();
        if frame >= frames - averaged {
            for (force, reaction) in forces.iter_mut().zip(&reactions) {
                *force += reaction.impulse.y / dt / averaged as Real;
            }
            height += colliders.last().map_or(0.0, |c| c.position.y) / averaged as Real;
        }
    }
    (forces, height, most, converged)
}

/// The ground `y = 0` as a static collider, so that its reaction is reported.
fn ground() -> Collider<'static> {
    Collider::half_space(Vec3::ZERO, Vec3::Y)
}

/// Whether the coupling converged and the soft step met its tolerance or left at most
/// `unbalanced` (N) unbalanced: without gravity the solver's target is relative to the step's
/// initial residual, which for bodies near rest under the barrier falls below the barrier's
/// rounding (a few 1e-10 N, where Newton's line search stalls).
fn balanced(report: &CoupledReport, unbalanced: Real) -> bool {
    report.coupling.converged && (report.step.converged() || report.step.residual() <= unbalanced)
}

/// The uniaxial compression (m) of a cube under `load` (N) on its top and its own weight,
/// linear elasticity: `load L / (E A) + rho g L^2 / (2 E)`. Exact for a homogeneous
/// deformation, which linear tetrahedra represent, between frictionless faces.
fn uniaxial(load: Real) -> Real {
    load * EDGE / (YOUNG * EDGE * EDGE) + DENSITY * GRAVITY * EDGE * EDGE / (2.0 * YOUNG)
}

#[test]
fn a_lid_across_two_cubes_is_carried_by_its_weight_and_the_ground_by_every_weight() {
    // Two cubes 4 cm apart (no pair within the contact gap) and a 2 kg lid 50 cm wide lying on
    // both, everything frictionless. At rest the lid's momentum balance says the cubes push it
    // up by its weight, the whole world's that the ground pushes up by every weight, and by
    // symmetry each cube is compressed uniaxially by half the lid's weight. Bound 1 % on the
    // forces: the weights are closed forms, the reactions the momentum balances of steps
    // solved to 1e-10 and a coupling tolerance of 1e-3, averaged over the last third of a
    // second of the settling; 1 % on the compression (0.5 mm), where the stretch of 0.25 %
    // leaves the linear closed form within a few 1e-3 of the neo-Hookean answer.
    let mut world = jellies(
        &[
            Vec3::new(-0.02 - EDGE, 0.0, -0.5 * EDGE),
            Vec3::new(0.02, 0.0, -0.5 * EDGE),
        ],
        2,
    );
    let (mass, half) = (2.0, Vec3::new(0.25, 0.05, 0.15));
    let mut colliders = [ground(), lid(mass, half, EDGE)];
    let (forces, height, most, converged) =
        settle(&mut world, &mut colliders, 1.0 / 60.0, (45, 15));
    let (ground_force, lid_force) = (-forces[0], forces[1]);
    let weight = mass * GRAVITY;
    let cubes: Real = world.masses().iter().sum::<Real>() * GRAVITY;
    assert!((cubes - 2.0 * DENSITY * EDGE.powi(3) * GRAVITY).abs() < 1e-9);
    assert!(
        converged,
        "a step did not converge ({most} coupling iterations at most)"
    );
    assert!(most <= 10, "{most} coupling iterations");
    assert!(
        (lid_force - weight).abs() < 0.01 * weight,
        "the cubes carry {lid_force} N of the lid's {weight} N"
    );
    assert!(
        (ground_force - weight - cubes).abs() < 0.01 * (weight + cubes),
        "the ground carries {ground_force} N of {} N",
        weight + cubes
    );
    let (compression, expected) = (EDGE + half.y - height, uniaxial(0.5 * weight));
    assert!(
        (compression - expected).abs() < 0.01 * expected,
        "compressed by {compression} m, uniaxial stress under half the lid gives {expected} m"
    );
}

#[test]
fn a_lid_on_a_stack_of_two_cubes_is_carried_by_its_weight() {
    // One cube on another (0.5 mm apart, within the barrier's 1 mm gap) and a 1 kg lid on
    // top: the lid's support is its weight; the ground carries the lid and both cubes, through
    // the barrier between the cubes (made to hold 10 N at half the gap: the stack's weight,
    // 11.4 N, then rests on the upper cube's four corners at about half the gap). Friction
    // (0.5) between the cubes: without it the upper cube has no restoring force against
    // sliding, and the meshes' asymmetry slides and tips the stack. Bound 1 % as above; the
    // solves to 1e-8, which leaves an impulse below 1e-7 of the weights' unbalanced.
    let below = Vec3::new(-0.5 * EDGE, 0.0, -0.5 * EDGE);
    let above = below + Vec3::new(0.0, EDGE + 5e-4, 0.0);
    let mut world = jellies(&[below, above], 1);
    world
        .set_solver(Solver::Newton(
            NewtonSettings::new().with_tolerance(1e-8, 50),
        ))
        .unwrap();
    world
        .set_barrier(ContactBarrier::holding(1e-3, 10.0).unwrap())
        .unwrap();
    world.set_friction(0.5).unwrap();
    let mass = 1.0;
    let top = above.y + EDGE;
    let mut colliders = [ground(), lid(mass, Vec3::new(0.15, 0.05, 0.15), top)];
    let (forces, _, most, converged) = settle(&mut world, &mut colliders, 1.0 / 60.0, (30, 10));
    let (ground_force, lid_force) = (-forces[0], forces[1]);
    let weight = mass * GRAVITY;
    let cubes: Real = world.masses().iter().sum::<Real>() * GRAVITY;
    assert!(
        converged,
        "a step did not converge ({most} coupling iterations at most)"
    );
    assert!(
        (lid_force - weight).abs() < 0.01 * weight,
        "the stack carries {lid_force} N of the lid's {weight} N"
    );
    assert!(
        (ground_force - weight - cubes).abs() < 0.01 * (weight + cubes),
        "the ground carries {ground_force} N of {} N",
        weight + cubes
    );
    // The upper cube rests on the lower one: above it, within the barrier's gap.
    let lowest_above = world.body_positions(1).unwrap().iter().map(|x| x.y);
    let highest_below = world.body_positions(0).unwrap().iter().map(|x| x.y);
    let gap = lowest_above.fold(1.0, Real::min) - highest_below.fold(0.0, Real::max);
    assert!(gap > 0.0 && gap < 1e-3, "gap {gap} m");
}

#[test]
fn a_free_box_thrown_at_two_touching_jellies_conserves_the_momentum_of_the_three() {
    // Without gravity or ground: two jellies of 0.08 kg side by side (0.5 mm apart, within the
    // barrier's gap) and a 0.2 kg box thrown at the left one at 2 m/s. The box pushes the left
    // jelly, the barrier the right one; the total linear momentum is the box's, to 1e-6
    // relative: every contact force has its opposite (the box's momentum balance takes the
    // impulse the jelly received, the barrier acts on both jellies), so what remains is the
    // force the solves leave unbalanced, at most 1e-8 relative to the impact's (60 N) times
    // dt on 16 vertices over 20 steps: about 1e-9 of the box's momentum.
    let left = Vec3::new(-EDGE - 2.5e-4, 0.0, -0.5 * EDGE);
    let right = Vec3::new(2.5e-4, 0.0, -0.5 * EDGE);
    let mut world = jellies(&[left, right], 1);
    world.set_gravity(Vec3::ZERO);
    world
        .set_solver(Solver::Newton(
            NewtonSettings::new().with_tolerance(1e-8, 50),
        ))
        .unwrap();
    let (mass, half) = (0.2, Vec3::new(0.05, 0.15, 0.15));
    let x = left.x - half.x - 0.01;
    let mut colliders = [
        Collider::cuboid(Vec3::new(x, 0.1, 0.0), half, Quat::IDENTITY)
            .with_mass(mass, box_inertia(mass, half))
            .with_velocity(Vec3::new(2.0, 0.0, 0.0), Vec3::ZERO),
    ];
    let before = Vec3::new(mass * 2.0, 0.0, 0.0);
    let mut reactions = [Reaction::ZERO];
    for _ in 0..20 {
        let scene = world.scene(1.0 / 120.0);
        let report = world
            .step_with_rigid_bodies(&scene, &mut colliders, &mut reactions)
            .unwrap();
        assert!(balanced(&report, 1e-8), "{report:?}");
    }
    let momentum = |body: usize| -> Vec3 {
        let part = world.bodies()[body].vertices();
        let rows = world.velocities()[part.clone()]
            .iter()
            .zip(&world.masses()[part]);
        rows.map(|(&v, &m)| v * m).sum()
    };
    let (pushed, passed_on) = (momentum(0), momentum(1));
    let after = pushed + passed_on + colliders[0].linear_velocity * mass;
    assert!(
        passed_on.x > 0.05 * before.x,
        "the right jelly took {passed_on} of {before}"
    );
    assert!(
        (after - before).length() <= 1e-6 * before.length(),
        "momentum {after} after, {before} before"
    );
}

#[test]
fn a_world_of_one_body_steps_with_its_lid_as_the_body_does_to_the_bit() {
    // The same cube and lid stepped by the single `Body` and by a world holding only that
    // cube (no pair of its own surface within the gap: the world's contact adds nothing). The
    // world's Newton step is the body's (tests/steppers/world.rs), so every coupling
    // iteration agrees only if each starts from the same restored state.
    let low = Vec3::new(-0.5 * EDGE, 0.0, -0.5 * EDGE);
    let material = StableNeoHookean::from_young_poisson(YOUNG, 0.3).unwrap();
    let mut body =
        Body::<VecStorage, _>::from_box(low, low + Vec3::splat(EDGE), [2; 3], DENSITY, material)
            .unwrap();
    body.set_solver(Solver::newton()).unwrap();
    let mut world = jellies(&[low], 2);
    world.set_solver(Solver::newton()).unwrap();
    let gravity = Vec3::new(0.0, -GRAVITY, 0.0);
    let floor = Some(HalfSpace::new(Vec3::Y, 0.0));
    body.set_gravity(gravity);
    body.set_ground(floor);
    world.set_ground(floor);
    let start = lid(1.0, Vec3::new(0.15, 0.05, 0.15), EDGE + 0.005);
    let (mut alone, mut together) = ([start], [start]);
    let (mut a, mut b) = ([Reaction::ZERO], [Reaction::ZERO]);
    let mut iterations = 0;
    for step in 0..20 {
        let dt = 1.0 / 60.0;
        let one = body
            .step_with_rigid_bodies(&body.scene(dt), &mut alone, &mut a)
            .unwrap();
        let two = world
            .step_with_rigid_bodies(&world.scene(dt), &mut together, &mut b)
            .unwrap();
        assert_eq!(one.coupling, two.coupling, "step {step}");
        assert_eq!(body.positions(), world.positions(), "step {step}");
        assert_eq!(body.velocities(), world.velocities(), "step {step}");
        assert_eq!(alone, together, "step {step}");
        assert_eq!(a, b, "step {step}");
        iterations += one.coupling.iterations;
    }
    // The lid landed and was iterated with the cube (more than one soft step a frame).
    assert!(iterations > 30, "{iterations} soft steps in 20 frames");
    assert!(b[0].vertices > 0);
}

#[test]
fn bad_coupled_world_steps_are_refused_with_the_bodies_and_the_colliders_untouched() {
    let mut world = jellies(&[Vec3::new(-0.1, 0.0, -0.1)], 1);
    let top = lid(1.0, Vec3::splat(0.05), EDGE);
    let positions = world.positions().to_vec();
    let velocities = world.velocities().to_vec();
    let mut reactions = [Reaction::ZERO; 2];
    // `in_scene`: a collider put in the scene besides.
    let mut refused = |world: &mut Jellies,
                       colliders: &mut [Collider<'_>],
                       n: usize,
                       in_scene: Option<Collider<'static>>| {
        let before = colliders.to_vec();
        let still: Vec<Collider<'_>> = in_scene.into_iter().collect();
        let scene = world.scene(0.01).with_colliders(&still);
        let error = world
            .step_with_rigid_bodies(&scene, colliders, &mut reactions[..n])
            .unwrap_err();
        assert_eq!(world.positions(), &positions[..]);
        assert_eq!(world.velocities(), &velocities[..]);
        assert_eq!(colliders, &before[..]);
        error
    };
    // A collider in the scene (a static ground): every collider goes in `colliders`.
    assert_eq!(
        refused(&mut world, &mut [top], 1, Some(ground())),
        StepError::SceneColliders
    );
    assert_eq!(
        refused(&mut world, &mut [top], 2, None),
        StepError::LengthMismatch {
            buffer: StepBuffer::Reactions,
            expected: 1,
            actual: 2
        }
    );
    world.set_coupling(CouplingSettings {
        max_iterations: 0,
        ..CouplingSettings::DEFAULT
    });
    assert_eq!(
        refused(&mut world, &mut [top], 1, None),
        StepError::CouplingSettings
    );
    assert_eq!(world.coupling().max_iterations, 0);
    world.set_coupling(CouplingSettings::DEFAULT);
    let mut empty = Jellies::new();
    assert_eq!(
        empty.step_with_rigid_bodies(&empty.scene(0.01), &mut [top], &mut [Reaction::ZERO]),
        Err(StepError::EmptyBody)
    );
    // With good input the same call steps.
    let scene = world.scene(0.01);
    assert!(
        world
            .step_with_rigid_bodies(&scene, &mut [top], &mut reactions[..1])
            .is_ok()
    );
}

/// Two jellies hanging from a free 1 kg bar without gravity, the left one by hard attachments
/// of its top face, the right one by springs and dampers, the bar thrown sideways at 0.5 m/s:
/// the bar drags both (each body's mean velocity above 0.1 m/s) and the total momentum of the
/// three is what the bar brought, to 1e-6 relative; the hard-attached vertices stay on the bar.
/// With gravity and a static bar instead, the bar carries both weights (within 2 % after 1 s).
#[test]
fn jellies_hanging_from_a_bar_by_hard_and_soft_attachments() {
    use softfem::f64::step::Attachment;
    for gravity in [0.0, GRAVITY] {
        let mut world = jellies(
            &[Vec3::new(-0.3, -EDGE, -0.1), Vec3::new(0.1, -EDGE, -0.1)],
            1,
        );
        world.set_gravity(Vec3::new(0.0, -gravity, 0.0));
        let half = Vec3::new(0.4, 0.05, 0.15);
        let mut bar = Collider::cuboid(Vec3::new(0.0, 0.05, 0.0), half, Quat::IDENTITY);
        if gravity == 0.0 {
            bar = bar
                .with_mass(1.0, box_inertia(1.0, half))
                .with_velocity(Vec3::new(0.5, 0.0, 0.0), Vec3::ZERO);
        }
        let x = world.positions().to_vec();
        let top: Vec<Attachment> = (0..x.len() as u32)
            .filter(|&i| x[i as usize].y == 0.0)
            .map(|i| {
                let hold = Attachment::at(i, 0, &bar, x[i as usize]);
                match x[i as usize].x > 0.0 {
                    true => hold.with_spring(500.0, 2.0),
                    false => hold,
                }
            })
            .collect();
        let (mut colliders, mut reactions) = ([bar], [Reaction::ZERO]);
        let dt = 1.0 / 60.0;
        let mut force = 0.0;
        for frame in 0..60 {
            let scene = world.scene(dt);
            let report = world
                .step_with_rigid_bodies_and_attachments(
                    &scene,
                    &mut colliders,
                    &top,
                    &mut reactions,
                )
                .unwrap();
            assert!(report.coupling.converged, "{report:?}");
            if frame >= 40 {
                force += -reactions[0].impulse.y / dt / 20.0;
            }
        }
        let masses = world.masses().to_vec();
        let momentum = |range: core::ops::Range<usize>| -> Vec3 {
            range.map(|i| world.velocities()[i] * masses[i]).sum()
        };
        let bodies: Vec<_> = world.bodies().iter().map(|b| b.vertices()).collect();
        if gravity == 0.0 {
            let before = Vec3::new(0.5, 0.0, 0.0);
            let after = momentum(0..masses.len()) + colliders[0].linear_velocity;
            println!(
                "world attachments: momentum error {}",
                (after - before).length() / before.length()
            );
            for range in &bodies {
                let mass: Real = masses[range.clone()].iter().sum();
                assert!(
                    momentum(range.clone()).x / mass > 0.1,
                    "a jelly stays behind"
                );
            }
            assert!(
                (after - before).length() <= 1e-6 * before.length(),
                "{after}"
            );
            let on_bar = top.iter().filter(|a| !a.is_soft()).all(|a| {
                (world.positions()[a.vertex as usize] - a.anchor(&colliders[0])).length() < 1e-9
            });
            assert!(on_bar);
        } else {
            let weight = masses.iter().sum::<Real>() * GRAVITY;
            println!("world attachments: the bar carries {force} N of {weight} N");
            assert!(
                (force - weight).abs() < 0.02 * weight,
                "{force} N of {weight} N"
            );
        }
    }
}

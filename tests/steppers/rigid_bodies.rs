//! Dynamic rigid bodies solved with the soft body in one implicit Euler step
//! ([`Body::step_with_rigid_bodies`], issue #42 item 1), against references the coupling does
//! not compute: a rigid box resting on a soft block is carried by its weight and compresses the
//! block as uniaxial stress (the closed form `M g L / (E A)`), with every implicit solver, also
//! where the box is so light that the staggered coupling of `reactions.rs` blows up; a jelly
//! squeezed between two free plates without gravity, and a jelly thrown at a free box, conserve
//! the total momentum; bad inputs are refused with nothing moved.

use softfem::StepError;
use softfem::f64::body::{Body, CoupledReport, FixedStorage, Solver, StepReport, stopped_at_floor};
use softfem::f64::material::StableNeoHookean;
use softfem::f64::step::{
    Attachment, Collider, CouplingSettings, HalfSpace, NewtonSettings, Reaction, RelaxSettings,
    VbdSettings,
};
use softfem::f64::types::{Quat, Real, Vec3};
use softfem::{ColliderProblem, StepBuffer};

/// 27 vertices and up to 40 tetrahedra: a cube of 2 x 2 x 2 cells.
type Block = Body<FixedStorage<27, 40>, StableNeoHookean>;

const GRAVITY: Real = 9.81;

/// A solid box's principal moments of inertia (kg m^2) about its centre.
fn box_inertia(mass: Real, half: Vec3) -> Vec3 {
    let s = half * half;
    Vec3::new(s.y + s.z, s.x + s.z, s.x + s.y) * (mass / 3.0)
}

/// Whether the coupling converged and the soft step converged or stopped at its rounding floor
/// (a body at rest without gravity starts there).
fn settled(report: &CoupledReport) -> bool {
    let step = match &report.step {
        StepReport::Newton(newton) => newton.converged || stopped_at_floor(newton),
        other => other.converged(),
    };
    report.coupling.converged && step
}

/// A frictionless cube of edge `edge` (m) on the frictionless ground `y = 0` (E, nu 0.3,
/// 10 kg/m^3: light, its own weight's share of the compression small), under gravity.
fn soft_cube(young: Real, edge: Real, solver: Solver) -> Block {
    let material = StableNeoHookean::from_young_poisson(young, 0.3).unwrap();
    let half = Vec3::splat(0.5 * edge);
    let mut block =
        Block::from_box(-half.with_y(0.0), half.with_y(edge), [2; 3], 10.0, material).unwrap();
    block.set_solver(solver).unwrap();
    block.set_gravity(Vec3::new(0.0, -GRAVITY, 0.0));
    block.set_ground(Some(HalfSpace::new(Vec3::Y, 0.0)));
    block
}

/// Drops a box of `mass` wider than the block onto it from rest, touching, and steps
/// `frames` of `dt`: the mean force the block puts on the box over the last `averaged`
/// frames (N), the box's mean height there (m), the most coupling iterations a step took,
/// and whether every step converged.
fn rest_a_box(
    block: &mut Block,
    (mass, dt): (Real, Real),
    (frames, averaged): (usize, usize),
) -> (Real, Real, u32, bool) {
    let edge = block
        .rest_positions()
        .iter()
        .map(|x| x.y)
        .fold(0.0, Real::max);
    let half = Vec3::new(0.15, 0.05, 0.15);
    let lid = Collider::cuboid(Vec3::new(0.0, edge + half.y, 0.0), half, Quat::IDENTITY)
        .with_mass(mass, box_inertia(mass, half));
    let (mut colliders, mut reactions) = ([lid], [Reaction::ZERO]);
    let (mut force, mut height, mut most, mut converged) = (0.0, 0.0, 0, true);
    for frame in 0..frames {
        let scene = block.scene(dt);
        let report = block
            .step_with_rigid_bodies(&scene, &mut colliders, &mut reactions)
            .unwrap();
        most = most.max(report.coupling.iterations);
        converged &= report.converged();
        if frame >= frames - averaged {
            force += reactions[0].impulse.y / dt;
            height += colliders[0].position.y;
        }
    }
    let n = averaged as Real;
    (force / n, height / n, most, converged)
}

/// The uniaxial compression (m) of a block of edge `edge` under the weight `weight` (N) on its
/// top and its own weight (10 kg/m^3), linear elasticity.
fn uniaxial(weight: Real, young: Real, edge: Real) -> Real {
    weight * edge / (young * edge * edge) + 10.0 * GRAVITY * edge * edge / (2.0 * young)
}

#[test]
fn a_rigid_box_rests_on_a_soft_block_carried_by_its_weight_with_every_implicit_solver() {
    let (young, edge, mass) = (1.0e5, 0.2, 2.0);
    let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));
    let relax = Solver::Relax(RelaxSettings::new().with_tolerance(1e-7, 4000));
    let vbd = Solver::Vbd(VbdSettings::new().with_tolerance(1e-4, 1000));
    for (name, solver) in [("newton", newton), ("relax", relax), ("vbd", vbd)] {
        let mut block = soft_cube(young, edge, solver);
        let (force, height, most, converged) = rest_a_box(&mut block, (mass, 1.0 / 60.0), (60, 20));
        let weight = mass * GRAVITY;
        let compression = edge + 0.05 - height;
        let expected = uniaxial(weight, young, edge);
        println!(
            "{name}: support {force} N of {weight} N, compression {compression} m against {expected} m, at most {most} coupling iterations"
        );
        assert!(converged, "{name}: a step did not converge");
        assert!(most <= 10, "{name}: {most} coupling iterations");
        assert!(
            (force - weight).abs() < 0.01 * weight,
            "{name}: the block carries {force} N of the box's {weight} N"
        );
        assert!(
            (compression - expected).abs() < 0.01 * expected,
            "{name}: compressed by {compression} m, uniaxial stress gives {expected} m"
        );
    }
}

/// A box so light that the staggered coupling is unstable at this step (`dt > 2 sqrt(M / k)`,
/// the block's stiffness `k = E A / L`): stepped staggered as a host engine would, it is
/// thrown off; solved with the block, it rests on it, carried by its weight.
#[test]
fn a_light_box_the_staggered_coupling_throws_off_rests_when_solved_with_the_block() {
    let (young, edge, mass, dt): (Real, Real, Real, Real) = (1.0e5, 0.2, 0.05, 1.0 / 60.0);
    let stiffness = young * edge * edge / edge;
    assert!(dt > 2.0 * (mass / stiffness).sqrt());
    let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));

    let mut block = soft_cube(young, edge, newton);
    let (force, _, most, converged) = rest_a_box(&mut block, (mass, dt), (60, 20));
    let weight = mass * GRAVITY;
    assert!(converged, "{most} coupling iterations");
    assert!(
        (force - weight).abs() < 0.01 * weight,
        "the block carries {force} N of the box's {weight} N"
    );

    // Staggered: the box integrated from the reaction of a step that saw it where it was.
    let mut block = soft_cube(young, edge, newton);
    let half = Vec3::new(0.15, 0.05, 0.15);
    let (mut y, mut v, mut reactions) = (edge + half.y, 0.0, [Reaction::ZERO]);
    let mut fastest: Real = 0.0;
    for _ in 0..60 {
        let lid = [
            Collider::cuboid(Vec3::new(0.0, y, 0.0), half, Quat::IDENTITY)
                .with_velocity(Vec3::new(0.0, v, 0.0), Vec3::ZERO),
        ];
        let scene = block.scene(dt).with_colliders(&lid);
        block.step_with_reactions(&scene, &mut reactions).unwrap();
        v += reactions[0].impulse.y / mass - GRAVITY * dt;
        y += v * dt;
        fastest = fastest.max(v.abs());
    }
    println!(
        "light box: support {force} N of {weight} N, at most {most} coupling iterations; staggered: {fastest} m/s"
    );
    assert!(
        fastest > 1.0,
        "the staggered box stayed below {fastest} m/s"
    );
}

/// Two free plates without gravity, the right one at rest and the left one thrown at a floating
/// jelly between them at 1 m/s: the jelly passes the push on, and the total momentum of the
/// three bodies is what the left plate brought, to 1e-6 relative.
#[test]
fn a_jelly_squeezed_between_two_free_plates_conserves_the_momentum_of_the_three() {
    let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));
    let mut jelly = soft_cube(1.0e5, 0.2, newton);
    jelly.set_gravity(Vec3::ZERO);
    jelly.set_ground(None);
    let (mass, half) = (1.0, Vec3::new(0.02, 0.15, 0.15));
    let plate = |x: Real| {
        Collider::cuboid(Vec3::new(x, 0.1, 0.0), half, Quat::IDENTITY)
            .with_mass(mass, box_inertia(mass, half))
    };
    let mut colliders = [
        plate(-0.1 - half.x - 0.01).with_velocity(Vec3::new(1.0, 0.0, 0.0), Vec3::ZERO),
        plate(0.1 + half.x),
    ];
    let before = Vec3::new(mass, 0.0, 0.0);
    let mut reactions = [Reaction::ZERO; 2];
    for _ in 0..20 {
        let scene = jelly.scene(1.0 / 120.0);
        let report = jelly
            .step_with_rigid_bodies(&scene, &mut colliders, &mut reactions)
            .unwrap();
        assert!(settled(&report), "{report:?}");
    }
    let soft: Vec3 = jelly
        .velocities()
        .iter()
        .zip(jelly.masses())
        .map(|(&v, &m)| v * m)
        .sum();
    let after = soft + (colliders[0].linear_velocity + colliders[1].linear_velocity) * mass;
    println!(
        "plates: momentum error {}",
        (after - before).length() / before.length()
    );
    assert!(
        colliders[1].linear_velocity.x > 0.05,
        "the right plate moves at {}",
        colliders[1].linear_velocity
    );
    assert!(
        (after - before).length() <= 1e-6 * before.length(),
        "momentum {after} after, {before} before"
    );
}

/// A jelly thrown at a free box off its centre without gravity: the box is pushed and spun,
/// and the total linear momentum is conserved to 1e-6 relative.
#[test]
fn a_jelly_thrown_at_a_free_box_off_centre_pushes_and_spins_it_conserving_momentum() {
    let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));
    let mut jelly = soft_cube(1.0e5, 0.2, newton);
    jelly.set_gravity(Vec3::ZERO);
    jelly.set_ground(None);
    for v in jelly.velocities_mut() {
        *v = Vec3::new(1.0, 0.0, 0.0);
    }
    let (mass, half) = (0.2, Vec3::splat(0.1));
    let mut colliders = [
        Collider::cuboid(Vec3::new(0.21, 0.2, 0.0), half, Quat::IDENTITY)
            .with_mass(mass, box_inertia(mass, half)),
    ];
    let momentum = |jelly: &Block| -> Vec3 {
        let rows = jelly.velocities().iter().zip(jelly.masses());
        rows.map(|(&v, &m)| v * m).sum()
    };
    let before = momentum(&jelly);
    let mut reactions = [Reaction::ZERO];
    for _ in 0..20 {
        let scene = jelly.scene(1.0 / 120.0);
        let report = jelly
            .step_with_rigid_bodies(&scene, &mut colliders, &mut reactions)
            .unwrap();
        assert!(settled(&report), "{report:?}");
    }
    let after = momentum(&jelly) + colliders[0].linear_velocity * mass;
    let spin = colliders[0].angular_velocity;
    println!(
        "thrown: momentum error {}, spin {spin}",
        (after - before).length() / before.length()
    );
    assert!(
        colliders[0].linear_velocity.x > 0.1 && spin.z.abs() > 0.1,
        "{spin}"
    );
    assert!(
        (after - before).length() <= 1e-6 * before.length(),
        "momentum {after} after, {before} before"
    );
}

/// Bad input is refused before anything moves: colliders in the scene, a reactions buffer of
/// the wrong length, a negative mass, a dynamic collider without inertia, too many dynamic
/// colliders, a zero coupling tolerance.
#[test]
fn bad_coupled_steps_are_refused_with_the_body_and_the_colliders_untouched() {
    let mut block = soft_cube(1.0e5, 0.2, Solver::newton());
    let half = Vec3::splat(0.05);
    let lid = Collider::cuboid(Vec3::new(0.0, 0.25, 0.0), half, Quat::IDENTITY)
        .with_mass(1.0, box_inertia(1.0, half));
    let positions = block.positions().to_vec();
    let mut reactions = [Reaction::ZERO; 17];
    let mut refused =
        |block: &mut Block, colliders: &mut [Collider<'_>], n: usize, scene_has: bool| {
            let before = colliders.to_vec();
            let still = [lid];
            let scene = match scene_has {
                true => block.scene(0.01).with_colliders(&still),
                false => block.scene(0.01),
            };
            let error = block
                .step_with_rigid_bodies(&scene, colliders, &mut reactions[..n])
                .unwrap_err();
            assert_eq!(block.positions(), &positions[..]);
            assert_eq!(colliders, &before[..]);
            error
        };
    assert_eq!(
        refused(&mut block, &mut [lid], 1, true),
        StepError::SceneColliders
    );
    assert_eq!(
        refused(&mut block, &mut [lid], 2, false),
        StepError::LengthMismatch {
            buffer: StepBuffer::Reactions,
            expected: 1,
            actual: 2
        }
    );
    let mass_problem = StepError::Collider {
        collider: 1,
        problem: ColliderProblem::Mass,
    };
    let negative = lid.with_mass(-1.0, Vec3::ONE);
    assert_eq!(
        refused(&mut block, &mut [lid, negative], 2, false),
        mass_problem
    );
    let flat = lid.with_mass(1.0, Vec3::new(1.0, 0.0, 1.0));
    assert_eq!(
        refused(&mut block, &mut [lid, flat], 2, false),
        mass_problem
    );
    assert_eq!(
        refused(&mut block, &mut [lid; 17], 17, false),
        StepError::TooManyDynamicColliders { limit: 16 }
    );
    block.set_coupling(CouplingSettings {
        tolerance: 0.0,
        ..CouplingSettings::DEFAULT
    });
    assert_eq!(
        refused(&mut block, &mut [lid], 1, false),
        StepError::CouplingSettings
    );
}

/// The top face of `body` (its highest vertices) held where it is on collider `index`.
fn top_attachments(body: &Block, index: u32, collider: &Collider<'_>) -> Vec<Attachment> {
    let x = body.positions();
    let top = x.iter().map(|x| x.y).fold(Real::MIN, Real::max);
    (0..x.len() as u32)
        .filter(|&i| x[i as usize].y == top)
        .map(|i| Attachment::at(i, index, collider, x[i as usize]))
        .collect()
}

fn body_momentum(body: &Block) -> Vec3 {
    let rows = body.velocities().iter().zip(body.masses());
    rows.map(|(&v, &m)| v * m).sum()
}

/// A jelly hanging by its top face from a static hook collider: at rest the hook carries its
/// weight (within 1 %), and what held each attached vertex is in the hook's reaction.
#[test]
fn a_hook_carries_the_weight_of_the_jelly_hanging_from_it() {
    let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));
    let mut jelly = soft_cube(2.0e4, 0.2, newton);
    jelly.set_ground(None);
    jelly.set_gravity(Vec3::ZERO);
    let hook = Collider::cuboid(Vec3::new(0.0, 0.25, 0.0), Vec3::splat(0.05), Quat::IDENTITY);
    let attachments = top_attachments(&jelly, 0, &hook);
    jelly.set_gravity(Vec3::new(0.0, -GRAVITY, 0.0));
    let (mut colliders, mut reactions) = ([hook], [Reaction::ZERO]);
    let dt = 1.0 / 60.0;
    let mut force = 0.0;
    for frame in 0..120 {
        let scene = jelly.scene(dt);
        jelly
            .step_with_rigid_bodies_and_attachments(
                &scene,
                &mut colliders,
                &attachments,
                &mut reactions,
            )
            .unwrap();
        if frame >= 90 {
            force += reactions[0].impulse.y / dt / 30.0;
        }
    }
    let weight = jelly.masses().iter().sum::<Real>() * GRAVITY;
    println!("hook: {force} N of {weight} N");
    assert_eq!(colliders[0], hook, "a static collider is not moved");
    assert_eq!(reactions[0].vertices as usize, attachments.len());
    assert!(
        (force + weight).abs() < 0.01 * weight,
        "the hook carries {force} N of the jelly's {weight} N"
    );
}

/// A jelly hanging from a free rigid box: under gravity the pair falls together, its total
/// momentum growing by the total weight's impulse exactly (to 1e-6 relative); without gravity,
/// the box thrown sideways drags the jelly along and the momentum is what it brought.
#[test]
fn a_jelly_hanging_from_a_free_box_moves_with_it_conserving_momentum() {
    for gravity in [Vec3::new(0.0, -GRAVITY, 0.0), Vec3::ZERO] {
        let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));
        let mut jelly = soft_cube(2.0e4, 0.2, newton);
        jelly.set_ground(None);
        jelly.set_gravity(gravity);
        let (mass, half) = (1.0, Vec3::new(0.1, 0.05, 0.1));
        let crate_ = Collider::cuboid(Vec3::new(0.0, 0.25, 0.0), half, Quat::IDENTITY)
            .with_mass(mass, box_inertia(mass, half))
            .with_velocity(Vec3::new(0.5, 0.0, 0.0), Vec3::ZERO);
        let attachments = top_attachments(&jelly, 0, &crate_);
        let (mut colliders, mut reactions) = ([crate_], [Reaction::ZERO]);
        let total_mass = mass + jelly.masses().iter().sum::<Real>();
        let before = Vec3::new(0.5 * mass, 0.0, 0.0);
        let (dt, frames) = (1.0 / 60.0, 30);
        for _ in 0..frames {
            let scene = jelly.scene(dt);
            let report = jelly
                .step_with_rigid_bodies_and_attachments(
                    &scene,
                    &mut colliders,
                    &attachments,
                    &mut reactions,
                )
                .unwrap();
            assert!(settled(&report), "{report:?}");
        }
        let after = body_momentum(&jelly) + colliders[0].linear_velocity * mass;
        let expected = before + gravity * (total_mass * dt * frames as Real);
        println!(
            "hanging: momentum error {}",
            (after - expected).length() / expected.length()
        );
        assert!(
            (after - expected).length() <= 1e-6 * expected.length(),
            "momentum {after}, expected {expected}"
        );
        // The jelly went with the box: its top face is still on it.
        let on_box = attachments.iter().all(|a| {
            (jelly.positions()[a.vertex as usize] - a.anchor(&colliders[0])).length() < 1e-9
        });
        assert!(
            on_box && colliders[0].position.x > 0.1,
            "{}",
            colliders[0].position
        );
    }
}

/// Attachments out of range are refused before anything moves, and a refused call leaves
/// the pins as they were.
#[test]
fn bad_attachments_are_refused_with_the_body_untouched() {
    let mut jelly = soft_cube(2.0e4, 0.2, Solver::newton());
    let hook = Collider::sphere(Vec3::new(0.0, 0.3, 0.0), 0.05);
    let positions = jelly.positions().to_vec();
    let mut reactions = [Reaction::ZERO];
    let scene = jelly.scene(0.01);
    for (attachment, error) in [
        (
            Attachment::new(27, 0, Vec3::ZERO),
            StepError::AttachedVertex {
                entry: 0,
                vertex: 27,
            },
        ),
        (
            Attachment::new(0, 1, Vec3::ZERO),
            StepError::AttachedCollider {
                entry: 0,
                collider: 1,
            },
        ),
        (
            Attachment::new(0, 0, Vec3::NAN),
            StepError::AttachedCollider {
                entry: 0,
                collider: 0,
            },
        ),
    ] {
        let refused = jelly.step_with_rigid_bodies_and_attachments(
            &scene,
            &mut [hook],
            &[attachment],
            &mut reactions,
        );
        assert_eq!(refused.unwrap_err(), error);
        assert_eq!(jelly.positions(), &positions[..]);
        assert!(jelly.pinned().iter().all(|&p| !p));
    }
}

/// A stiff jelly hanging by soft attachments (springs of `k` each, with dampers) from a static
/// hook: at rest the springs carry its weight, `k sum (a_i - x_i).y = m g` (the static balance of
/// the springs, within 1 %), and so does the hook's reaction.
#[test]
fn springs_carry_the_weight_of_a_jelly_hanging_softly_from_a_hook() {
    let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));
    let mut jelly = soft_cube(1.0e6, 0.2, newton);
    jelly.set_ground(None);
    let hook = Collider::cuboid(Vec3::new(0.0, 0.25, 0.0), Vec3::splat(0.05), Quat::IDENTITY);
    let stiffness = 50.0; // N/m per vertex
    let springs: Vec<Attachment> = top_attachments(&jelly, 0, &hook)
        .into_iter()
        .map(|a| a.with_spring(stiffness, 2.0))
        .collect();
    let (mut colliders, mut reactions) = ([hook], [Reaction::ZERO]);
    let dt = 1.0 / 60.0;
    for _ in 0..240 {
        let scene = jelly.scene(dt);
        jelly
            .step_with_rigid_bodies_and_attachments(
                &scene,
                &mut colliders,
                &springs,
                &mut reactions,
            )
            .unwrap();
    }
    let weight = jelly.masses().iter().sum::<Real>() * GRAVITY;
    let stretch: Real = springs
        .iter()
        .map(|a| (a.anchor(&hook) - jelly.positions()[a.vertex as usize]).y)
        .sum();
    let carried = stiffness * stretch;
    let force = -reactions[0].impulse.y / dt;
    println!("soft hook: springs {carried} N, hook {force} N, weight {weight} N");
    assert!(
        (carried - weight).abs() < 0.01 * weight,
        "{carried} N of {weight} N"
    );
    assert!(
        (force - weight).abs() < 0.01 * weight,
        "{force} N of {weight} N"
    );
    assert!(
        jelly.pinned().iter().all(|&p| !p),
        "soft attachments pin nothing"
    );
}

/// A jelly tied by springs and dampers to a free box, without gravity, the box thrown sideways:
/// the springs pull the jelly along and the total momentum is what the box brought (1e-6
/// relative); the explicit stepper is refused with nothing moved.
#[test]
fn a_jelly_on_springs_behind_a_free_box_conserves_momentum() {
    let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));
    let mut jelly = soft_cube(1.0e5, 0.2, newton);
    jelly.set_ground(None);
    jelly.set_gravity(Vec3::ZERO);
    let (mass, half) = (1.0, Vec3::new(0.1, 0.05, 0.1));
    let crate_ = Collider::cuboid(Vec3::new(0.0, 0.25, 0.0), half, Quat::IDENTITY)
        .with_mass(mass, box_inertia(mass, half))
        .with_velocity(Vec3::new(0.5, 0.0, 0.0), Vec3::ZERO);
    let springs: Vec<Attachment> = top_attachments(&jelly, 0, &crate_)
        .into_iter()
        .map(|a| a.with_spring(200.0, 1.0))
        .collect();
    let (mut colliders, mut reactions) = ([crate_], [Reaction::ZERO]);
    let before = Vec3::new(0.5 * mass, 0.0, 0.0);
    for _ in 0..30 {
        let scene = jelly.scene(1.0 / 60.0);
        let report = jelly
            .step_with_rigid_bodies_and_attachments(
                &scene,
                &mut colliders,
                &springs,
                &mut reactions,
            )
            .unwrap();
        assert!(settled(&report), "{report:?}");
    }
    let after = body_momentum(&jelly) + colliders[0].linear_velocity * mass;
    println!(
        "springs behind a box: momentum error {}",
        (after - before).length() / before.length()
    );
    let jelly_speed = body_momentum(&jelly).x / jelly.masses().iter().sum::<Real>();
    assert!(
        jelly_speed > 0.1,
        "the jelly stays behind: {jelly_speed} m/s"
    );
    assert!(
        (after - before).length() <= 1e-6 * before.length(),
        "{after} against {before}"
    );

    let explicit = Solver::Explicit {
        settings: softfem::f64::step::ExplicitSettings::new(),
        stable_fraction: Some(0.5),
    };
    jelly.set_solver(explicit).unwrap();
    let positions = jelly.positions().to_vec();
    let scene = jelly.scene(1.0 / 60.0);
    let refused = jelly.step_with_rigid_bodies_and_attachments(
        &scene,
        &mut colliders,
        &springs,
        &mut reactions,
    );
    assert_eq!(refused.unwrap_err(), StepError::SoftAttachmentSolver);
    assert_eq!(jelly.positions(), &positions[..]);
}

/// A nearly rigid jelly of mass `M` on the springs of its top face (total stiffness `K = n k`,
/// no gravity), released 1 cm above its rest on them. Without dampers it oscillates with
/// implicit Euler's period of the oscillator `w = sqrt(K / M)` at this step,
/// `2 pi h / atan(h w)` (the phase of one step of `z' = z / (1 - i h w)`), within 1 %. With
/// dampers of total `C = n c` its amplitude falls over a period by implicit Euler's factor for
/// `z'' + (C/M) z' + w^2 z = 0`, `|r|^(T/h)` with `|r|^2 = 1 / (1 + h C/M + h^2 w^2)` (the
/// product of the roots of its two-step recurrence), within 2 %.
#[test]
fn a_jelly_on_springs_oscillates_and_decays_as_implicit_euler_s_oscillator() {
    let (k, h) = (50.0, 1.0 / 600.0);
    for damping in [0.0, 0.1] {
        let newton = Solver::Newton(NewtonSettings::new().with_tolerance(1e-10, 50));
        let mut jelly = soft_cube(1.0e7, 0.2, newton);
        jelly.set_ground(None);
        jelly.set_gravity(Vec3::ZERO);
        let hook = Collider::cuboid(Vec3::new(0.0, 0.26, 0.0), Vec3::splat(0.05), Quat::IDENTITY);
        let springs: Vec<Attachment> = top_attachments(&jelly, 0, &hook)
            .into_iter()
            .map(|a| {
                let lower = a.local - Vec3::new(0.0, 0.01, 0.0);
                Attachment { local: lower, ..a }.with_spring(k, damping)
            })
            .collect();
        let mass: Real = jelly.masses().iter().sum();
        let n = springs.len() as Real;
        let omega = (n * k / mass).sqrt();
        let period = 2.0 * core::f64::consts::PI * h / (h * omega).atan();
        let (mut colliders, mut reactions) = ([hook], [Reaction::ZERO]);
        let centre = |jelly: &Block| {
            let rows = jelly.positions().iter().zip(jelly.masses());
            rows.map(|(&x, &m)| x.y * m).sum::<Real>() / mass
        };
        let rest = centre(&jelly) - 0.01;
        let (mut crossings, mut before) = (Vec::new(), centre(&jelly) - rest);
        let mut peaks = [0.0 as Real; 4];
        let steps = (3.2 * period / h) as usize;
        for step in 0..steps {
            let scene = jelly.scene(h);
            jelly
                .step_with_rigid_bodies_and_attachments(
                    &scene,
                    &mut colliders,
                    &springs,
                    &mut reactions,
                )
                .unwrap();
            let now = centre(&jelly) - rest;
            if before < 0.0 && now >= 0.0 {
                crossings.push((step as Real + before / (before - now)) * h);
            }
            // The largest excursion in each of the first periods after the release.
            if let Some(peak) = peaks.get_mut(((step + 1) as Real * h / period) as usize) {
                *peak = peak.max(now.abs());
            }
            before = now;
        }
        if damping == 0.0 {
            assert!(crossings.len() >= 3, "{crossings:?}");
            let last = crossings.len() - 1;
            let measured = (crossings[last] - crossings[0]) / last as Real;
            println!("springs: period {measured} s, implicit Euler's {period} s");
            assert!(
                (measured - period).abs() < 0.01 * period,
                "{measured} s against {period} s"
            );
        } else {
            let gamma = n * damping / mass;
            let per_step = 1.0 / (1.0 + h * gamma + h * h * omega * omega).sqrt();
            let expected = per_step.powf(period / h);
            let measured = peaks[2] / peaks[1];
            println!("dampers: decay over a period {measured}, implicit Euler's {expected}");
            assert!(
                (measured - expected).abs() < 0.02 * expected,
                "{measured} against {expected}"
            );
        }
    }
}

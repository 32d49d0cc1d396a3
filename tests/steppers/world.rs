//! Issue #39, deliverable 1: the world of bodies (`src/world/`). Each test checks the world
//! against something it does not share code with: the single `Body` stepping the same mesh
//! (the same bits, one body and no pair within the gap), the conservation of momentum, two
//! separate bodies (per-body materials), the exact triangle–triangle test (no intersection),
//! and the bookkeeping of adding, removing and refusing bodies by hand.

use softfem::f64::body::{Body, Solver, VecStorage};
use softfem::f64::material::StableNeoHookean;
use softfem::f64::step::contact::potential::ContactBarrier;
use softfem::f64::step::{HalfSpace, NewtonSettings};
use softfem::f64::world::{FixedWorld, World};
use softfem::glam::DVec3;
use softfem::{BodyBuffer, BodyError, ContactBuffer, ContactError, MeshError, StepError};

type Material = StableNeoHookean;

fn material(young: f64) -> Material {
    StableNeoHookean::from_young_poisson(young, 0.3).unwrap()
}

/// The intersecting pairs of boundary triangles (sharing no vertex) of `world`, exactly.
fn intersections<S: softfem::f64::world::WorldStorage>(world: &World<S, Material>) -> usize {
    crate::intersection::intersecting_pairs_f64(world.positions(), world.triangles()).len()
}

#[test]
fn one_body_in_a_world_steps_as_the_body_to_the_bit() {
    // A 10 cm cube of 2^3 cells falling onto the ground: no pair of its own surface comes
    // within the gap, so the world's contact adds exactly nothing and its Newton solve is the
    // body's.
    let (low, high) = (DVec3::new(0.0, 0.0, 0.01), DVec3::new(0.1, 0.1, 0.11));
    let mut body =
        Body::<VecStorage, _>::from_box(low, high, [2; 3], 1000.0, material(1e5)).unwrap();
    let mut world = World::<VecStorage, _>::new();
    world
        .add_box(low, high, [2; 3], 1000.0, material(1e5))
        .unwrap();
    body.set_solver(Solver::newton()).unwrap();
    let gravity = DVec3::new(0.0, 0.0, -9.81);
    let ground = Some(HalfSpace::new(DVec3::Z, 0.0).with_friction(0.4));
    body.set_gravity(gravity);
    body.set_ground(ground);
    world.set_gravity(gravity);
    world.set_ground(ground);
    for step in 0..30 {
        let a = body.step(0.01).unwrap();
        let b = world.step(0.01).unwrap();
        assert_eq!(a.converged(), b.converged(), "step {step}");
        assert_eq!(body.positions(), world.positions(), "step {step}");
        assert_eq!(body.velocities(), world.velocities(), "step {step}");
    }
    assert_eq!(world.contact_counts().hessians, 0);
    // Landed on the ground, not through it.
    assert!(world.positions().iter().all(|x| x.z > -1e-3 && x.z < 0.1));
}

#[test]
fn each_body_keeps_its_own_material() {
    // A stiff and a soft cantilever, 1 m apart, pinned at x = 0, sagging under gravity for
    // 0.2 s: in one world (one Newton solve over both) each moves as it does alone.
    let (low, high) = (DVec3::ZERO, DVec3::new(0.4, 0.1, 0.1));
    let away = DVec3::new(0.0, 1.0, 0.0);
    let materials = [material(2e6), material(2e5)];
    let gravity = DVec3::new(0.0, 0.0, -9.81);
    let tolerance = 1e-9;
    let settings = NewtonSettings::new().with_tolerance(tolerance, 100);
    let mut world = World::<VecStorage, _>::new();
    world.set_solver(Solver::Newton(settings)).unwrap();
    world.set_gravity(gravity);
    let mut alone = Vec::new();
    for (k, &m) in materials.iter().enumerate() {
        let shift = away * k as f64;
        let index = world
            .add_box(low + shift, high + shift, [4, 1, 1], 1000.0, m)
            .unwrap();
        assert_eq!(index, k);
        let mut body =
            Body::<VecStorage, _>::from_box(low + shift, high + shift, [4, 1, 1], 1000.0, m)
                .unwrap();
        body.set_solver(Solver::Newton(settings)).unwrap();
        body.set_gravity(gravity);
        for i in 0..body.vertex_count() {
            let clamped = body.rest_positions()[i].x == 0.0;
            body.set_pinned(i, clamped).unwrap();
            world.set_pinned(k, i, clamped).unwrap();
        }
        alone.push(body);
    }
    for _ in 0..20 {
        assert!(world.step(0.01).unwrap().converged());
        for body in &mut alone {
            assert!(body.step(0.01).unwrap().converged());
        }
    }
    let sag = |x: &[DVec3]| x.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    let mut sags = Vec::new();
    for (k, body) in alone.iter().enumerate() {
        let in_world = world.body_positions(k).unwrap();
        let worst = in_world
            .iter()
            .zip(body.positions())
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        println!(
            "body {k}: tip {:.4e} m in the world, {:.4e} m alone; largest difference {worst:.2e} m",
            sag(in_world),
            sag(body.positions())
        );
        // Both solves stop at a residual of `tolerance` (N) on a stiffness of at least
        // 1e4 N/m: positions agree to well under a micrometre.
        assert!(worst < 1e-6, "body {k}: {worst}");
        sags.push(sag(in_world));
    }
    // The soft one sags more (an independent sanity check that the materials differ).
    assert!(sags[1] < 2.0 * sags[0], "{sags:?}");
}

#[test]
fn a_soft_box_dropped_on_a_stiff_one_rests_on_it_without_intersecting() {
    let mut world = World::<VecStorage, _>::new();
    let stiff = world
        .add_box(
            DVec3::ZERO,
            DVec3::splat(0.1),
            [2; 3],
            1000.0,
            material(1e6),
        )
        .unwrap();
    let soft = world
        .add_box(
            DVec3::new(0.02, 0.03, 0.13),
            DVec3::new(0.08, 0.09, 0.19),
            [2; 3],
            1000.0,
            material(5e4),
        )
        .unwrap();
    world.set_gravity(DVec3::new(0.0, 0.0, -9.81));
    world.set_ground(Some(HalfSpace::new(DVec3::Z, 0.0)));
    world.set_friction(0.5).unwrap();
    let dhat = world.barrier().gap;
    for step in 0..100 {
        let report = world.step(0.01).unwrap();
        assert!(report.converged(), "step {step}: {report:?}");
        assert_eq!(intersections(&world), 0, "step {step}");
    }
    let top = world
        .body_positions(stiff)
        .unwrap()
        .iter()
        .map(|x| x.z)
        .fold(0.0, f64::max);
    let bottom = world
        .body_positions(soft)
        .unwrap()
        .iter()
        .map(|x| x.z)
        .fold(1.0, f64::min);
    let gap = world.smallest_gap(dhat).unwrap().unwrap();
    println!(
        "after 1 s: gap {:.3e} m between the faces, smallest primitive distance {gap:.3e} m",
        bottom - top
    );
    assert!(bottom - top > 0.0 && bottom - top < dhat);
    assert!(gap > 0.0 && gap < dhat);
    // At rest: the upper box's velocities have decayed.
    let speed = world
        .body_velocities(soft)
        .unwrap()
        .iter()
        .map(|v| v.length())
        .fold(0.0, f64::max);
    assert!(speed < 1e-2, "{speed}");
    assert!(world.contact_counts().friction > 0);
}

#[test]
fn a_collision_without_gravity_conserves_momentum() {
    let mut world = World::<VecStorage, _>::new();
    world
        .set_solver(Solver::Newton(
            NewtonSettings::new().with_tolerance(1e-10, 100),
        ))
        .unwrap();
    world
        .set_barrier(ContactBarrier::holding(1e-3, 5.0).unwrap())
        .unwrap();
    let a = world
        .add_box(
            DVec3::ZERO,
            DVec3::splat(0.1),
            [2; 3],
            1000.0,
            material(1e5),
        )
        .unwrap();
    let b = world
        .add_box(
            DVec3::new(0.03, 0.104, 0.02),
            DVec3::new(0.13, 0.204, 0.12),
            [2; 3],
            500.0,
            material(3e5),
        )
        .unwrap();
    world
        .body_velocities_mut(a)
        .unwrap()
        .fill(DVec3::new(0.0, 0.5, 0.0));
    world
        .body_velocities_mut(b)
        .unwrap()
        .fill(DVec3::new(0.1, -1.0, 0.0));
    let momentum = |world: &World<VecStorage, Material>| {
        world
            .velocities()
            .iter()
            .zip(world.masses())
            .fold(DVec3::ZERO, |p, (v, m)| p + *v * *m)
    };
    let scale: f64 = world
        .velocities()
        .iter()
        .zip(world.masses())
        .map(|(v, m)| v.length() * m)
        .sum();
    let p0 = momentum(&world);
    let mut worst: f64 = 0.0;
    let mut touched = 0;
    for _ in 0..40 {
        assert!(world.step(0.005).unwrap().converged());
        worst = worst.max((momentum(&world) - p0).length() / scale);
        touched += usize::from(world.smallest_gap(1e-3).unwrap().is_some());
        assert_eq!(intersections(&world), 0);
    }
    println!("momentum error {worst:.3e} of {scale:.3e} kg m/s; {touched} steps within dhat");
    assert!(touched > 0);
    assert!(worst <= 1e-6, "{worst}");
}

#[test]
fn bodies_are_added_removed_and_refused_with_the_world_unchanged() {
    let mut world = World::<VecStorage, _>::new();
    let boxes = [0.0, 0.2, 0.4].map(|x| DVec3::new(x, 0.0, 0.0));
    for (k, &low) in boxes.iter().enumerate() {
        let cells = [1 + k, 1, 1];
        assert_eq!(
            world
                .add_box(low, low + DVec3::splat(0.1), cells, 1000.0, material(1e5))
                .unwrap(),
            k
        );
    }
    // Box k has 2(k+2)*2 = 4(k+2) vertices and 5(k+1) tetrahedra, 4(k+1)+... triangles.
    assert_eq!(world.body_count(), 3);
    assert_eq!(world.vertex_count(), 8 + 12 + 16);
    assert_eq!(world.tet_count(), 5 + 10 + 15);
    let triangles: Vec<usize> = world.bodies().iter().map(|p| p.triangles().len()).collect();
    assert_eq!(triangles, [12, 20, 28]); // 2 (2 + 4 k) + 4 ... each face of the box split in two
    let last_before = world.body_positions(2).unwrap().to_vec();
    world.remove_body(1).unwrap();
    assert_eq!(world.body_count(), 2);
    assert_eq!(world.vertex_count(), 8 + 16);
    assert_eq!(world.tet_count(), 5 + 15);
    assert_eq!(world.triangles().len(), 12 + 28);
    assert_eq!(world.body_positions(1).unwrap(), &last_before[..]);
    // Every index of the closed-up lists lies in its own body's range.
    for part in world.bodies() {
        for tet in &world.tets()[part.tets()] {
            assert!(
                tet.iter().all(|&v| part.vertices().contains(&(v as usize))),
                "{tet:?}"
            );
        }
        for t in &world.triangles()[part.triangles()] {
            assert!(
                t.iter().all(|&v| part.vertices().contains(&(v as usize))),
                "{t:?}"
            );
        }
    }
    assert_eq!(
        world.remove_body(2),
        Err(BodyError::NoSuchBody { body: 2, count: 2 })
    );
    // Refused additions leave everything as it was.
    let before = (
        world.positions().to_vec(),
        world.tets().to_vec(),
        world.triangles().to_vec(),
    );
    let inverted = [DVec3::ZERO, DVec3::Y, DVec3::X, DVec3::Z];
    assert!(matches!(
        world.add_body(&inverted, &[[0, 1, 2, 3]], 1000.0, material(1e5)),
        Err(BodyError::Mesh(_))
    ));
    let unused = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE];
    assert_eq!(
        world.add_body(&unused, &[[0, 1, 2, 3]], 1000.0, material(1e5)),
        Err(BodyError::UnusedVertex { vertex: 4 })
    );
    assert_eq!(
        before,
        (
            world.positions().to_vec(),
            world.tets().to_vec(),
            world.triangles().to_vec()
        )
    );
    // Settings refused.
    // The automatic solver: its explicit choice and fallbacks are the body's, not the world's.
    assert_eq!(world.set_solver(Solver::auto()), Err(BodyError::Solver));
    let too_large = Solver::Explicit {
        settings: softfem::f64::step::ExplicitSettings::new(),
        stable_fraction: Some(2.0),
    };
    assert_eq!(world.set_solver(too_large), Err(BodyError::StableFraction));
    assert_eq!(
        world.set_friction(-1.0),
        Err(BodyError::Contact(ContactError::Friction))
    );
    assert!(
        world
            .set_barrier(ContactBarrier {
                stiffness: 1.0,
                gap: 0.0
            })
            .is_err()
    );
    assert_eq!(
        world.set_pinned(0, 8, true),
        Err(BodyError::Vertex { vertex: 8 })
    );
    // An empty world refuses to step.
    let mut empty = World::<VecStorage, Material>::new();
    assert_eq!(empty.step(0.01).unwrap_err(), StepError::EmptyBody);
}

/// Two boxes, the upper 0.5 mm above the lower, settling for `steps` steps.
fn settle<S: softfem::f64::world::WorldStorage>(
    world: &mut World<S, Material>,
    steps: usize,
) -> Result<(), StepError> {
    world.set_gravity(DVec3::new(0.0, 0.0, -9.81));
    world.set_ground(Some(HalfSpace::new(DVec3::Z, 0.0)));
    for _ in 0..steps {
        world.step(0.01)?;
    }
    Ok(())
}

fn two_boxes<S: softfem::f64::world::WorldStorage>(
    world: &mut World<S, Material>,
) -> Result<(), BodyError> {
    world.add_box(
        DVec3::ZERO,
        DVec3::splat(0.1),
        [2; 3],
        1000.0,
        material(1e6),
    )?;
    world.add_box(
        DVec3::new(0.0, 0.0, 0.1005),
        DVec3::new(0.1, 0.1, 0.2005),
        [2; 3],
        1000.0,
        material(1e5),
    )?;
    Ok(())
}

#[test]
fn a_fixed_capacity_world_gives_the_bits_of_a_growable_one_and_names_what_does_not_fit() {
    // Two boxes of 27 vertices, 40 tetrahedra and 48 triangles each.
    type Roomy = FixedWorld<2, 54, 80, { FixedWorld::<0, 0, 0, 0, 0>::contact_capacity(96) }, 512>;
    // Built in place (`empty` is const): `new` would return it through a debug build's stack.
    static FIXED: std::sync::Mutex<World<Roomy, Material>> = std::sync::Mutex::new(World::empty());
    let mut fixed = FIXED.lock().unwrap();
    let mut growing = World::<VecStorage, Material>::new();
    two_boxes(&mut *fixed).unwrap();
    two_boxes(&mut growing).unwrap();
    settle(&mut *fixed, 10).unwrap();
    settle(&mut growing, 10).unwrap();
    assert_eq!(fixed.positions(), growing.positions());
    assert_eq!(fixed.velocities(), growing.velocities());
    assert!(
        fixed.contact_counts().hessians > 8,
        "{:?}",
        fixed.contact_counts()
    );

    // One body too many, one vertex too few: refused, nothing changed.
    static ONE: std::sync::Mutex<World<FixedWorld<1, 54, 80, 4224, 512>, Material>> =
        std::sync::Mutex::new(World::empty());
    let mut one = ONE.lock().unwrap();
    one.add_box(
        DVec3::ZERO,
        DVec3::splat(0.1),
        [2; 3],
        1000.0,
        material(1e6),
    )
    .unwrap();
    let error = one.add_box(
        DVec3::splat(0.2),
        DVec3::splat(0.3),
        [1; 3],
        1000.0,
        material(1e6),
    );
    assert_eq!(
        error,
        Err(BodyError::Capacity {
            buffer: BodyBuffer::Bodies,
            needed: 2
        })
    );
    assert_eq!(
        (one.body_count(), one.vertex_count(), one.tet_count()),
        (1, 27, 40)
    );
    static SMALL: std::sync::Mutex<World<FixedWorld<2, 30, 80, 4224, 512>, Material>> =
        std::sync::Mutex::new(World::empty());
    let mut small = SMALL.lock().unwrap();
    small
        .add_box(
            DVec3::ZERO,
            DVec3::splat(0.1),
            [2; 3],
            1000.0,
            material(1e6),
        )
        .unwrap();
    let error = small.add_box(
        DVec3::splat(0.2),
        DVec3::splat(0.3),
        [1; 3],
        1000.0,
        material(1e6),
    );
    assert_eq!(
        error,
        Err(BodyError::Capacity {
            buffer: BodyBuffer::Vertices,
            needed: 35
        })
    );
    assert_eq!(
        (
            small.body_count(),
            small.vertex_count(),
            small.triangles().len()
        ),
        (1, 27, 48)
    );

    // Room for 4 pair Hessians: the resting faces need more; the step fails and keeps the state.
    static TIGHT: std::sync::Mutex<World<FixedWorld<2, 54, 80, 4224, 4>, Material>> =
        std::sync::Mutex::new(World::empty());
    let mut tight = TIGHT.lock().unwrap();
    two_boxes(&mut *tight).unwrap();
    let (x, v) = (tight.positions().to_vec(), tight.velocities().to_vec());
    let error = settle(&mut *tight, 1).unwrap_err();
    match error {
        StepError::Mesh(MeshError::Contact(ContactError::Capacity {
            buffer,
            capacity,
            needed,
        })) => {
            assert_eq!(buffer, ContactBuffer::PairHessians);
            assert_eq!(capacity, 4);
            assert!(needed > 4, "{needed}");
        }
        other => panic!("{other:?}"),
    }
    println!("{error}");
    assert_eq!((tight.positions(), tight.velocities()), (&x[..], &v[..]));
}

/// The lowest and highest `z` of body `body`.
fn z_range<S: softfem::f64::world::WorldStorage>(
    world: &World<S, Material>,
    body: usize,
) -> (f64, f64) {
    let z = world.body_positions(body).unwrap().iter().map(|x| x.z);
    (
        z.clone().fold(f64::INFINITY, f64::min),
        z.fold(f64::NEG_INFINITY, f64::max),
    )
}

#[test]
fn the_explicit_stepper_stops_a_plate_at_20_m_per_s_without_tunnelling() {
    // A plate one cell (1 cm) thick falls at 20 m/s onto a block resting on the ground, no
    // gravity; frames of 1/240 s, each in substeps of half the stable step (about 50 of
    // them, the plate moving 1.7 mm, more than the 1 mm gap, per substep). The exact test
    // finds no intersecting pair after any frame, and the plate ends above the block.
    let mut world = World::<VecStorage, _>::new();
    world.set_solver(Solver::explicit()).unwrap();
    world.set_ground(Some(HalfSpace::new(DVec3::Z, 0.0)));
    let block = world
        .add_box(
            DVec3::ZERO,
            DVec3::splat(0.1),
            [2; 3],
            1000.0,
            material(1e6),
        )
        .unwrap();
    let plate = world
        .add_box(
            DVec3::new(0.01, 0.01, 0.13),
            DVec3::new(0.09, 0.09, 0.14),
            [2, 2, 1],
            1000.0,
            material(1e6),
        )
        .unwrap();
    world
        .body_velocities_mut(plate)
        .unwrap()
        .fill(DVec3::new(0.0, 0.0, -20.0));
    let dt = 1.0 / 240.0;
    println!(
        "stable step {:.3e} s, {:.0} substeps a frame",
        world.stable_time_step().unwrap(),
        dt / (0.5 * world.stable_time_step().unwrap())
    );
    let mut cuts = 0;
    for frame in 0..24 {
        let report = world
            .step(dt)
            .unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        if let softfem::f64::body::StepReport::Explicit(report) = report {
            cuts += report.motion_cuts;
        }
        assert_eq!(intersections(&world), 0, "frame {frame}");
        let (plate_low, _) = z_range(&world, plate);
        let (_, block_high) = z_range(&world, block);
        assert!(
            plate_low > block_high,
            "frame {frame}: plate at {plate_low}, block top {block_high}"
        );
    }
    let speed = world
        .body_velocities(plate)
        .unwrap()
        .iter()
        .map(|v| v.z)
        .sum::<f64>()
        / 18.0;
    println!(
        "after 0.1 s: plate's mean vertical speed {speed:.3} m/s, {cuts} substeps cut by the failsafe"
    );
    // The impact stopped it (inelastic: it does not bounce back at 20 m/s).
    assert!(speed > -1.0 && speed < 5.0, "{speed}");
}

#[test]
fn explicitly_stepped_boxes_come_to_rest_on_each_other() {
    // A soft box dropped 5 mm onto a stiffer one under gravity, explicit substeps with
    // damping: after 1 s no pair intersects and the upper box rests within the gap.
    let mut world = World::<VecStorage, _>::new();
    let settings = softfem::f64::step::ExplicitSettings::new().with_damping(5.0);
    world
        .set_solver(Solver::Explicit {
            settings,
            stable_fraction: Some(0.5),
        })
        .unwrap();
    world.set_gravity(DVec3::new(0.0, 0.0, -9.81));
    world.set_ground(Some(HalfSpace::new(DVec3::Z, 0.0)));
    let lower = world
        .add_box(
            DVec3::ZERO,
            DVec3::splat(0.1),
            [2; 3],
            1000.0,
            material(1e6),
        )
        .unwrap();
    let upper = world
        .add_box(
            DVec3::new(0.02, 0.02, 0.105),
            DVec3::new(0.08, 0.08, 0.165),
            [2; 3],
            1000.0,
            material(2e5),
        )
        .unwrap();
    for frame in 0..60 {
        world
            .step(1.0 / 60.0)
            .unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        assert_eq!(intersections(&world), 0, "frame {frame}");
    }
    let (upper_low, _) = z_range(&world, upper);
    let (_, lower_high) = z_range(&world, lower);
    let gap = world.smallest_gap(1e-2).unwrap();
    println!(
        "after 1 s: {:.3e} m between the faces, smallest distance {gap:?}",
        upper_low - lower_high
    );
    assert!(
        gap.is_some_and(|d| d > 0.0 && d <= world.barrier().gap),
        "{gap:?}"
    );
}

#[test]
fn in_f32_too_the_plate_at_20_m_per_s_stops_without_tunnelling() {
    use softfem::glam::Vec3;
    let mut world = softfem::world::World::<softfem::body::VecStorage, _>::new();
    world.set_solver(softfem::body::Solver::explicit()).unwrap();
    world.set_ground(Some(softfem::step::HalfSpace::new(Vec3::Z, 0.0)));
    let stiff = softfem::material::StableNeoHookean::from_young_poisson(1e6, 0.3).unwrap();
    world
        .add_box(Vec3::ZERO, Vec3::splat(0.1), [2; 3], 1000.0, stiff)
        .unwrap();
    let plate = world
        .add_box(
            Vec3::new(0.01, 0.01, 0.13),
            Vec3::new(0.09, 0.09, 0.14),
            [2, 2, 1],
            1000.0,
            stiff,
        )
        .unwrap();
    world
        .body_velocities_mut(plate)
        .unwrap()
        .fill(Vec3::new(0.0, 0.0, -20.0));
    for frame in 0..24 {
        world
            .step(1.0 / 240.0)
            .unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        let crossing =
            crate::intersection::intersecting_pairs_f32(world.positions(), world.triangles());
        assert_eq!(crossing.len(), 0, "frame {frame}");
    }
    let speed = world
        .body_velocities(plate)
        .unwrap()
        .iter()
        .map(|v| v.z)
        .sum::<f32>()
        / 18.0;
    println!("f32: after 0.1 s the plate's mean vertical speed is {speed:.3} m/s");
    assert!(speed > -1.0 && speed < 5.0, "{speed}");
}

#[test]
fn hostile_input_is_refused_and_the_world_keeps_its_state() {
    let mut world = World::<VecStorage, _>::new();
    world
        .add_box(
            DVec3::ZERO,
            DVec3::splat(0.1),
            [1; 3],
            1000.0,
            material(1e5),
        )
        .unwrap();
    // Bodies the mesh check refuses: a NaN rest position, an index out of range, a density
    // that is not positive, an absurd box.
    let nan = [
        DVec3::ZERO,
        DVec3::X,
        DVec3::Y,
        DVec3::new(0.0, 0.0, f64::NAN),
    ];
    let tet = [[0, 1, 2, 3]];
    assert!(matches!(
        world.add_body(&nan, &tet, 1000.0, material(1e5)),
        Err(BodyError::Mesh(_))
    ));
    let corners = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
    assert!(matches!(
        world.add_body(&corners, &[[0, 1, 2, 9]], 1000.0, material(1e5)),
        Err(BodyError::Mesh(_))
    ));
    assert!(matches!(
        world.add_body(&corners, &tet, -1.0, material(1e5)),
        Err(BodyError::Mesh(_))
    ));
    assert!(
        world
            .add_box(
                DVec3::ZERO,
                DVec3::ONE,
                [usize::MAX, 1, 1],
                1000.0,
                material(1e5)
            )
            .is_err()
    );
    assert_eq!(
        (
            world.body_count(),
            world.vertex_count(),
            world.triangles().len()
        ),
        (1, 8, 12)
    );
    // A NaN position moved in by hand: the step refuses it and restores the state; a
    // non-positive step too.
    world.body_positions_mut(0).unwrap()[3].x = f64::NAN;
    let (x, v) = (world.positions().to_vec(), world.velocities().to_vec());
    assert!(world.step(0.01).is_err());
    assert!(world.step(0.0).is_err());
    assert!(world.step(-1.0).is_err());
    let same = |a: &[DVec3], b: &[DVec3]| {
        a.iter()
            .zip(b)
            .all(|(p, q)| p.to_array().map(f64::to_bits) == q.to_array().map(f64::to_bits))
    };
    assert!(same(world.positions(), &x) && same(world.velocities(), &v));
    assert!(world.body_positions(1).is_none() && world.body_velocities_mut(7).is_none());
}

/// The world on a thread pool (`World::set_threads`, feature `rayon`): bodies in parallel,
/// the same bits as on the calling thread.
#[cfg(feature = "rayon")]
mod threads {
    use super::{Material, material};
    use softfem::f64::body::{Solver, StepReport, VecStorage};
    use softfem::f64::step::HalfSpace;
    use softfem::f64::world::World;
    use softfem::glam::DVec3;

    /// Four boxes of three materials in contact from the start (gaps of 0.5 mm, half the
    /// default contact gap): two side by side on the ground, a third across both, a fourth on
    /// the third, with friction between them; stepped by `solver` on `threads` threads (0: the
    /// calling thread, the world's default).
    fn stack(solver: Solver, threads: usize) -> World<VecStorage, Material> {
        let mut world = World::new();
        let boxes = [
            (DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.1, 0.1, 0.1), 1e6),
            (
                DVec3::new(0.1005, 0.0, 0.0),
                DVec3::new(0.2005, 0.1, 0.1),
                3e5,
            ),
            (
                DVec3::new(0.05, 0.02, 0.1005),
                DVec3::new(0.15, 0.08, 0.1505),
                1e5,
            ),
            (
                DVec3::new(0.07, 0.03, 0.151),
                DVec3::new(0.13, 0.07, 0.191),
                5e4,
            ),
        ];
        for (low, high, young) in boxes {
            world
                .add_box(low, high, [2; 3], 1000.0, material(young))
                .unwrap();
        }
        world.set_gravity(DVec3::new(0.0, 0.0, -9.81));
        world.set_ground(Some(HalfSpace::new(DVec3::Z, 0.0)));
        world.set_friction(0.3).unwrap();
        world.set_solver(solver).unwrap();
        world.set_threads(threads).unwrap();
        assert_eq!(world.threads(), threads);
        world
    }

    /// Every coordinate's bits.
    fn bits(vectors: &[DVec3]) -> Vec<[u64; 3]> {
        vectors
            .iter()
            .map(|v| v.to_array().map(f64::to_bits))
            .collect()
    }

    /// `steps` steps of `dt` on the calling thread and on 1, 2 and 3 threads: the same
    /// positions, velocities and reports, bit for bit, after every step; returns the
    /// sequential world's reports.
    fn same_bits_on_every_pool(solver: Solver, steps: usize, dt: f64) -> Vec<StepReport> {
        let mut sequential = stack(solver, 0);
        let mut pooled: Vec<_> = [1, 2, 3].map(|n| stack(solver, n)).into();
        let mut reports = Vec::new();
        for step in 0..steps {
            let report = sequential.step(dt).unwrap();
            for world in &mut pooled {
                let threads = world.threads();
                let other = world.step(dt).unwrap();
                assert_eq!(report, other, "step {step}, {threads} threads");
                assert_eq!(
                    bits(sequential.positions()),
                    bits(world.positions()),
                    "step {step}, {threads} threads"
                );
                assert_eq!(
                    bits(sequential.velocities()),
                    bits(world.velocities()),
                    "step {step}, {threads} threads"
                );
            }
            reports.push(report);
        }
        // In contact: pairs within the gap between the bodies.
        let counts = sequential.contact_counts();
        assert!(counts.vertex_triangle + counts.edge_edge > 0, "{counts:?}");
        reports
    }

    #[test]
    fn newton_gives_the_bits_of_one_thread_on_every_pool() {
        let reports = same_bits_on_every_pool(Solver::newton(), 12, 0.01);
        assert!(reports.iter().all(StepReport::converged), "{reports:?}");
    }

    #[test]
    fn the_relaxation_gives_the_bits_of_one_thread_on_every_pool() {
        same_bits_on_every_pool(Solver::relax(), 6, 0.01);
    }

    #[test]
    fn vbd_gives_the_bits_of_one_thread_on_every_pool() {
        let reports = same_bits_on_every_pool(Solver::vbd(), 12, 0.01);
        assert!(reports.iter().any(StepReport::converged), "{reports:?}");
    }

    #[test]
    fn the_explicit_stepper_gives_the_bits_of_one_thread_on_every_pool() {
        same_bits_on_every_pool(Solver::explicit(), 2, 0.002);
    }

    #[test]
    fn bodies_added_and_removed_on_a_pool_keep_the_bits() {
        // The body-local tetrahedra are refitted when bodies change.
        let mut sequential = stack(Solver::newton(), 0);
        let mut pooled = stack(Solver::newton(), 2);
        for world in [&mut sequential, &mut pooled] {
            world.step(0.01).unwrap();
            world.remove_body(1).unwrap();
            let (low, high) = (DVec3::new(0.3, 0.0, 0.0), DVec3::new(0.4, 0.1, 0.1));
            world
                .add_box(low, high, [3, 2, 2], 1000.0, material(2e5))
                .unwrap();
            world.step(0.01).unwrap();
        }
        assert_eq!(bits(sequential.positions()), bits(pooled.positions()));
        assert_eq!(bits(sequential.velocities()), bits(pooled.velocities()));
    }

    #[test]
    fn a_bad_position_gives_the_error_of_one_thread_and_the_state_back() {
        let mut sequential = stack(Solver::newton(), 0);
        let mut pooled = stack(Solver::newton(), 3);
        let mut errors = Vec::new();
        for world in [&mut sequential, &mut pooled] {
            world.step(0.01).unwrap();
            world.body_positions_mut(2).unwrap()[5].z = f64::NAN;
            let before = bits(world.positions());
            errors.push(world.step(0.01).unwrap_err());
            assert_eq!(bits(world.positions()), before);
        }
        assert_eq!(errors[0], errors[1]);
    }
}

//! The owning body on arbitrary arrays, pins, targets, colliders, solvers and steps (included
//! once per precision by `lib.rs`).
//!
//! The input draws a body (a small box, or arbitrary positions and tetrahedra), a material,
//! pins and kinematic targets, a solver (the explicit one with any `stable_fraction`), gravity,
//! a ground, colliders, and a few steps of any `dt`. Promises checked (`src/body/mod.rs`):
//! nothing panics or aborts; a body built from arrays has no vertex outside every tetrahedron
//! (issue #44: such a vertex has no mass and is refused by name), so no step fails with
//! `StepError::Mass`; `set_solver` accepts an explicit `stable_fraction` exactly when it is in
//! `(0, 1]`; a step that fails hands back positions and velocities bit for bit.

use super::NAME;
use super::precision;
use super::sf::body::{Body, Solver, VecStorage};
use super::sf::material::StableNeoHookean;
use super::sf::step::{Collider, ExplicitSettings, HalfSpace};
use super::sf::types::{Real, Vec3};
use super::sf::{BodyError, StepError};
use crate::Draw;

fn coordinate(draw: &mut Draw<'_>) -> Real {
    match draw.up_to(5) {
        0 => precision::wild(draw),
        _ => precision::coarse(draw),
    }
}

fn point(draw: &mut Draw<'_>) -> Vec3 {
    Vec3::new(coordinate(draw), coordinate(draw), coordinate(draw))
}

fn bits(x: &[Vec3]) -> Vec<[u64; 3]> {
    x.iter()
        .map(|x| x.to_array().map(|c| c.to_bits() as u64))
        .collect()
}

/// Runs the body checks on one fuzzer input.
pub fn check(data: &[u8]) {
    let mut draw = Draw::new(data);
    let young = precision::magnitude(&mut draw, 2, 9);
    let Ok(material) = StableNeoHookean::from_young_poisson(young, precision::poisson(&mut draw))
    else {
        return;
    };
    let density = if draw.chance(20) {
        coordinate(&mut draw)
    } else {
        1000.0
    };
    let built = if draw.chance(100) {
        let cells = [draw.index(3), draw.index(3), draw.index(3)];
        Body::<VecStorage, _>::from_box(
            point(&mut draw),
            point(&mut draw),
            cells,
            density,
            material,
        )
    } else {
        let n = draw.index(10);
        let positions: Vec<Vec3> = (0..n).map(|_| point(&mut draw)).collect();
        let t = draw.index(6);
        let tets = draw.tets(t, n);
        let built = Body::<VecStorage, _>::from_arrays(&positions, &tets, density, material);
        if built.is_ok() {
            let unused = (0..n).find(|&v| !tets.iter().flatten().any(|&i| i as usize == v));
            assert!(
                unused.is_none(),
                "{NAME}: from_arrays accepted vertex {unused:?} in no tetrahedron"
            );
        }
        if let Err(BodyError::UnusedVertex { vertex }) = built {
            assert!(
                !tets.iter().flatten().any(|&i| i as usize == vertex),
                "{NAME}: from_arrays refused vertex {vertex}, which a tetrahedron uses"
            );
        }
        built
    };
    let Ok(mut body) = built else {
        return;
    };
    let n = body.vertex_count();
    for _ in 0..draw.index(3) {
        let vertex = draw.index(n);
        let _ = body.set_pinned(vertex, true);
        if draw.chance(100) {
            let _ = body.set_target(vertex, point(&mut draw));
        }
    }
    let solver = match draw.up_to(4) {
        0 => Solver::relax(),
        1 => Solver::newton(),
        2 => Solver::vbd(),
        3 => Solver::explicit(),
        _ => {
            let fraction = precision::wild(&mut draw);
            let solver = Solver::Explicit {
                settings: ExplicitSettings::new(),
                stable_fraction: Some(fraction),
            };
            let accepted = body.set_solver(solver).is_ok();
            assert_eq!(
                accepted,
                fraction > 0.0 && fraction <= 1.0,
                "{NAME}: set_solver with stable_fraction {fraction}"
            );
            solver
        }
    };
    let _ = body.set_solver(solver);
    body.set_gravity(Vec3::new(0.0, -9.81, 0.0));
    if draw.chance(128) {
        body.set_ground(Some(
            HalfSpace::new(Vec3::Y, coordinate(&mut draw)).with_friction(0.5),
        ));
    }
    let colliders: Vec<Collider<'static>> = (0..draw.index(2))
        .map(|_| {
            let collider = match draw.up_to(2) {
                0 => Collider::sphere(point(&mut draw), coordinate(&mut draw)),
                1 => Collider::capsule(point(&mut draw), point(&mut draw), coordinate(&mut draw)),
                _ => Collider::half_space(point(&mut draw), point(&mut draw)),
            };
            collider.with_velocity(point(&mut draw), point(&mut draw))
        })
        .collect();
    for _ in 0..draw.index(3) {
        let dt = if draw.chance(200) {
            (draw.up_to(4) + 1) as Real / 240.0
        } else {
            precision::wild(&mut draw)
        };
        let (x, v) = (bits(body.positions()), bits(body.velocities()));
        let scene = body.scene(dt).with_colliders(&colliders);
        match body.step_with(&scene) {
            Ok(_) => {}
            Err(StepError::Mass { vertex }) => {
                panic!("{NAME}: a step failed on vertex {vertex}'s mass: the body accepted it")
            }
            Err(error) => {
                assert!(
                    bits(body.positions()) == x && bits(body.velocities()) == v,
                    "{NAME}: the failed step ({error}) did not hand back the state"
                );
            }
        }
    }
}

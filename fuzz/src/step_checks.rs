//! One to three steps of each stepper on arbitrary state (included once per precision by
//! `lib.rs`): `explicit_step` with `TetElastic` and `TetClamped`; `relax_step`,
//! `relax_quasi_static`, `newton_step`, `newton_quasi_static`, `vbd_step` and
//! `vbd_quasi_static` with `TetElastic`, the implicit solvers with external forces and
//! fixed-axis masks in their scene some of the time; each with all three materials.
//!
//! Promises checked (`src/step/mod.rs`, `src/error.rs`): nothing panics; every call returns
//! either `Ok`, with every position and velocity finite, every pinned vertex bit-for-bit where
//! it was and every fixed coordinate of a position bit-for-bit as it was, or `Err`, with
//! positions and velocities bit-for-bit as they were before the call (refused before anything
//! is touched, or restored after a failed step).
//!
//! The body is a single tetrahedron or a cube of five (one group of four, as the batched
//! kernels take them, and one more), scaled and perturbed; masses, pinned flags, positions,
//! velocities, the scene and every setting are drawn from a documented range most of the time
//! and anything otherwise. Iteration budgets and substeps are bounded (at most 40 and 4) to keep
//! each input fast; `ExplicitSettings::substeps` beyond that only repeats the same substep.

use super::NAME;
use super::precision as draw_real;
use super::sf::element::TetHessian;
use super::sf::element::TetRest;
use super::sf::material::{Material, NeoHookean, StVK, StableNeoHookean};
use super::sf::mesh::TetMesh;
use super::sf::step::{
    ElasticHessian, ElasticModel, ExplicitScratch, ExplicitSettings, HalfSpace, NewtonScratch,
    NewtonSettings, RelaxScratch, RelaxSettings, Scene, TetClamped, TetElastic, VbdScratch,
    VbdSettings, explicit_step, newton_quasi_static, newton_step, relax_quasi_static, relax_step,
    scratch_len, stable_time_step, vbd_quasi_static, vbd_step,
};
use super::sf::types::{Mat3, Real, Vec3};
use crate::Draw;

/// The unit cube in five tetrahedra (positively oriented).
const CUBE: [[Real; 3]; 8] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [1.0, 1.0, 1.0],
    [0.0, 1.0, 1.0],
];
const CUBE_TETS: [[u32; 4]; 5] = [
    [0, 1, 3, 4],
    [1, 2, 3, 6],
    [1, 4, 5, 6],
    [3, 4, 6, 7],
    [1, 3, 4, 6],
];
/// A corner tetrahedron of the cube, alone.
const TET: [[Real; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
];
const TET_TETS: [[u32; 4]; 1] = [[0, 1, 2, 3]];

/// Runs the stepper checks on one fuzzer input.
pub fn check(data: &[u8]) {
    let mut draw = Draw::new(data);
    let (corners, tets): (&[[Real; 3]], &[[u32; 4]]) = if draw.chance(64) {
        (&TET, &TET_TETS)
    } else {
        (&CUBE, &CUBE_TETS)
    };
    let size = draw_real::magnitude(&mut draw, -2, 1);
    let wobble = [0.0, 0.01, 0.2][draw.index(2)];
    let mut rest: Vec<Vec3> = corners
        .iter()
        .map(|&c| {
            let p = Vec3::from(c);
            (p + Vec3::new(
                draw_real::grid(&mut draw, wobble / 8.0),
                draw_real::grid(&mut draw, wobble / 8.0),
                draw_real::grid(&mut draw, wobble / 8.0),
            )) * size
        })
        .collect();
    let mut rest_data = vec![TetRest::default(); tets.len()];
    if TetMesh::new(&rest, tets, &mut rest_data).is_err() {
        rest = corners.iter().map(|&c| Vec3::from(c) * size).collect();
    }
    let mesh = match TetMesh::new(&rest, tets, &mut rest_data) {
        Ok(mesh) => mesh,
        Err(error) => panic!("{NAME}: the scaled unit cube was refused: {error:?}"),
    };

    let (lambda, mu) = if draw.chance(24) {
        (draw_real::wild(&mut draw), draw_real::wild(&mut draw))
    } else {
        let e = draw_real::magnitude(&mut draw, 3, 8);
        let nu = draw_real::poisson(&mut draw);
        (
            e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            e / (2.0 * (1.0 + nu)),
        )
    };
    match draw.up_to(2) {
        0 => {
            if let Ok(m) = StVK::from_lame(lambda, mu) {
                with_material(&mut draw, mesh, m, &rest, "StVK");
            }
        }
        1 => {
            if let Ok(m) = NeoHookean::from_lame(lambda, mu) {
                with_material(&mut draw, mesh, m, &rest, "NeoHookean");
            }
        }
        _ => {
            if let Ok(m) = StableNeoHookean::from_lame(lambda, mu) {
                with_material(&mut draw, mesh, m, &rest, "StableNeoHookean");
            }
        }
    }
}

/// The caller-owned state of one body.
struct State {
    masses: Vec<Real>,
    pinned: Vec<bool>,
    positions: Vec<Vec3>,
    velocities: Vec<Vec3>,
}

fn bits(values: &[Vec3]) -> Vec<[u64; 3]> {
    values
        .iter()
        .map(|v| v.to_array().map(|x| x.to_bits().into()))
        .collect()
}

/// A length near `len`: usually `len`, rarely one off.
fn length_near(draw: &mut Draw<'_>, len: usize) -> usize {
    match draw.up_to(127) {
        0 => len + 1,
        1 => len.saturating_sub(1),
        _ => len,
    }
}

fn draw_vector(draw: &mut Draw<'_>, scale: Real, wild: bool) -> Vec3 {
    if wild && draw.chance(48) {
        Vec3::new(
            draw_real::wild(draw),
            draw_real::wild(draw),
            draw_real::wild(draw),
        )
    } else {
        Vec3::new(
            draw_real::grid(draw, scale / 8.0),
            draw_real::grid(draw, scale / 8.0),
            draw_real::grid(draw, scale / 8.0),
        )
    }
}

fn draw_state(draw: &mut Draw<'_>, mesh: &TetMesh<'_>, rest: &[Vec3]) -> State {
    let n = mesh.vertex_count();
    let density = if draw.chance(16) {
        draw_real::wild(draw)
    } else {
        draw_real::magnitude(draw, 1, 4)
    };
    let mut masses = vec![1.0; n];
    if mesh.lumped_masses(density, &mut masses).is_err() {
        masses.fill(1.0);
    }
    if draw.chance(16) {
        let vertex = draw.index(n - 1);
        masses[vertex] = draw_real::wild(draw);
    }
    masses.truncate(length_near(draw, n));
    let pinned = match draw.up_to(3) {
        0 | 1 => Vec::new(),
        2 => (0..n).map(|_| draw.chance(64)).collect(),
        _ => (0..length_near(draw, n))
            .map(|_| draw.chance(128))
            .collect(),
    };
    let size = rest
        .iter()
        .map(|p| p.length())
        .fold(0.0, Real::max)
        .max(Real::MIN_POSITIVE);
    let amplitude = [0.0, 0.01, 0.3, 1.5][draw.index(3)] * size;
    let wild = draw.chance(32);
    let positions = rest
        .iter()
        .take(length_near(draw, n))
        .map(|&p| p + draw_vector(draw, amplitude, wild))
        .collect();
    let speed = [0.0, 0.1, 10.0, 1e3][draw.index(3)];
    let velocities = (0..length_near(draw, n))
        .map(|_| draw_vector(draw, speed, wild))
        .collect();
    State {
        masses,
        pinned,
        positions,
        velocities,
    }
}

/// A ground below the body most of the time (a plane through its lower part), anything
/// otherwise.
fn draw_ground(draw: &mut Draw<'_>, size: Real) -> Option<HalfSpace<Vec3>> {
    if draw.chance(128) {
        return None;
    }
    let normal = if draw.chance(32) {
        Vec3::new(
            draw_real::wild(draw),
            draw_real::wild(draw),
            draw_real::wild(draw),
        )
    } else {
        Vec3::new(draw_real::grid(draw, 0.1), 1.0, draw_real::grid(draw, 0.1))
    };
    let offset = if draw.chance(32) {
        draw_real::wild(draw)
    } else {
        draw_real::grid(draw, size / 16.0)
    };
    let restitution = if draw.chance(32) {
        draw_real::wild(draw)
    } else {
        Real::from(draw.up_to(4) as u8) / 4.0
    };
    let friction = if draw.chance(32) {
        draw_real::wild(draw)
    } else {
        Real::from(draw.up_to(8) as u8) / 8.0
    };
    Some(
        HalfSpace::new(normal, offset)
            .with_restitution(restitution)
            .with_friction(friction),
    )
}

fn draw_gravity(draw: &mut Draw<'_>) -> Vec3 {
    match draw.up_to(7) {
        0 => Vec3::new(
            draw_real::wild(draw),
            draw_real::wild(draw),
            draw_real::wild(draw),
        ),
        1 => Vec3::ZERO,
        2 => draw_vector(draw, 100.0, false),
        _ => Vec3::new(0.0, -9.81, 0.0),
    }
}

/// A time step: a fraction or multiple of the stable step of the body (when it has one), or
/// anything.
fn draw_dt<F: ElasticModel<Vector = Vec3>>(
    draw: &mut Draw<'_>,
    model: &F,
    masses: &[Real],
) -> Real {
    if draw.chance(32) {
        return draw_real::wild(draw);
    }
    let mut stiffness = vec![0.0; model.vertex_count()];
    let stable = stable_time_step(model, masses, &[], &mut stiffness)
        .ok()
        .filter(|dt| dt.is_finite() && *dt > 0.0)
        .unwrap_or(1e-3);
    let factor: Real = [0.1, 0.5, 0.9, 1.05, 1.5, 2.5, 10.0, 1e3][draw.index(7)];
    stable * factor
}

fn with_material<M: Material>(
    draw: &mut Draw<'_>,
    mesh: TetMesh<'_>,
    material: M,
    rest: &[Vec3],
    model_name: &str,
) {
    let mut state = draw_state(draw, &mesh, rest);
    let size = rest.iter().map(|p| p.length()).fold(0.0, Real::max);
    let elastic = TetElastic::new(mesh, material);
    match draw.up_to(7) {
        0 => explicit(draw, &elastic, &mut state, size, "TetElastic", model_name),
        1 => {
            let threshold = if draw.chance(32) {
                draw_real::wild(draw)
            } else {
                0.05 + Real::from(draw.up_to(19) as u8) / 20.0
            };
            let clamped = TetClamped::new(mesh, material, threshold);
            explicit(draw, &clamped, &mut state, size, "TetClamped", model_name);
        }
        solver => {
            let solve = Solve {
                model: &elastic,
                size,
                dynamic: solver % 2 == 0,
                model_name,
            };
            match solver {
                2 | 3 => relax(draw, &solve, &mut state),
                4 | 5 => newton(draw, &solve, &mut state),
                _ => vbd(draw, &solve, &mut state),
            }
        }
    }
}

/// Loads and constraints of the implicit solvers, drawn at the end of their settings (so that
/// an input that ends earlier has none): external forces (N) and fixed-axis masks, each empty
/// most of the time, of about the vertex count otherwise, sometimes wild.
struct Extras {
    external_forces: Vec<Vec3>,
    fixed_axes: Vec<u8>,
}

fn draw_extras(draw: &mut Draw<'_>, n: usize, scale: Real) -> Extras {
    let external_forces = if draw.byte() >= 160 {
        let wild = draw.chance(32);
        (0..length_near(draw, n))
            .map(|_| draw_vector(draw, scale, wild))
            .collect()
    } else {
        Vec::new()
    };
    let fixed_axes = if draw.byte() >= 160 {
        (0..length_near(draw, n))
            .map(|_| {
                if draw.chance(16) {
                    draw.byte()
                } else {
                    draw.up_to(7) as u8
                }
            })
            .collect()
    } else {
        Vec::new()
    };
    Extras {
        external_forces,
        fixed_axes,
    }
}

/// On `Ok`, every fixed coordinate of a position (a set bit `k` of `fixed_axes[i]`, where the
/// masks were accepted) is bit-for-bit what it was.
fn check_fixed_axes<R: core::fmt::Debug, E: core::fmt::Debug>(
    call: impl Fn() -> String,
    result: &Result<R, E>,
    state: &State,
    before: &(Vec<[u64; 3]>, Vec<[u64; 3]>),
    fixed_axes: &[u8],
) {
    if result.is_err() || fixed_axes.len() != state.positions.len() {
        return;
    }
    let after = bits(&state.positions);
    let rows = fixed_axes
        .iter()
        .zip(after.iter().zip(&before.0))
        .enumerate();
    for (i, (&mask, (now, then))) in rows {
        for (axis, (now, then)) in now.iter().zip(then).enumerate() {
            if mask & (1 << axis) != 0 {
                assert!(
                    now == then,
                    "{NAME}: {} returned {result:?} and moved fixed axis {axis} of vertex {i}",
                    call()
                );
            }
        }
    }
}

/// Checks the outcome of one call: `Ok` with a finite state and pinned vertices untouched, or
/// `Err` with the state exactly as before.
fn check_outcome<R: core::fmt::Debug, E: core::fmt::Debug>(
    call: impl Fn() -> String,
    result: &Result<R, E>,
    state: &State,
    before: &(Vec<[u64; 3]>, Vec<[u64; 3]>),
    with_velocities: bool,
) {
    let after = (bits(&state.positions), bits(&state.velocities));
    crate::trace(|| {
        let call = call();
        let name = call.split('(').next().unwrap_or("");
        match result {
            Ok(_) => format!("{NAME} {name} Ok"),
            Err(error) => {
                let error = format!("{error:?}");
                format!(
                    "{NAME} {name} Err {}",
                    error.split([' ', '{', '(']).next().unwrap_or("")
                )
            }
        }
    });
    match result {
        Ok(_) => {
            let positions_finite = state.positions.iter().all(|p| p.is_finite());
            let velocities_finite =
                !with_velocities || state.velocities.iter().all(|v| v.is_finite());
            assert!(
                positions_finite && velocities_finite,
                "{NAME}: {} returned {result:?} with a non-finite state",
                call()
            );
            if state.pinned.len() == state.positions.len() {
                for (i, &pinned) in state.pinned.iter().enumerate() {
                    if pinned {
                        assert!(
                            after.0[i] == before.0[i]
                                && (!with_velocities || after.1[i] == before.1[i]),
                            "{NAME}: {} moved pinned vertex {i}",
                            call()
                        );
                    }
                }
            }
        }
        Err(_) => assert!(
            after == *before,
            "{NAME}: {} returned {result:?} and changed the caller's state",
            call()
        ),
    }
}

fn explicit<F: ElasticModel<Vector = Vec3>>(
    draw: &mut Draw<'_>,
    model: &F,
    state: &mut State,
    size: Real,
    body: &str,
    model_name: &str,
) {
    let dt = draw_dt(draw, model, &state.masses);
    let mut scene = Scene::new(dt).with_gravity(draw_gravity(draw));
    let mut settings = ExplicitSettings::new().with_substeps(draw.up_to(4));
    settings.damping = match draw.up_to(7) {
        0 => draw_real::wild(draw),
        1 | 2 => 0.0,
        _ => draw_real::grid(draw, 10.0).abs(),
    };
    scene.ground = draw_ground(draw, size);
    settings.max_energy_growth = match draw.up_to(7) {
        0 => draw_real::wild(draw),
        1 => 1.5,
        _ => settings.max_energy_growth,
    };
    let n = model.vertex_count();
    let mut buffer = vec![Vec3::ZERO; length_near(draw, scratch_len::explicit(n))];
    let mut scratch = ExplicitScratch::new(&mut buffer);
    for call in 0..=draw.up_to(2) {
        if call > 0 && draw.chance(32) {
            scratch.forget_history();
        }
        let before = (bits(&state.positions), bits(&state.velocities));
        let result = explicit_step(
            model,
            &state.masses,
            &state.pinned,
            &scene,
            &settings,
            &mut state.positions,
            &mut state.velocities,
            &mut scratch,
        );
        check_outcome(
            || format!("explicit_step({body}<{model_name}>, {scene:?}, {settings:?}), call {call}"),
            &result,
            state,
            &before,
            true,
        );
    }
}

/// One implicit solver's body and mode: the model, its size (m), whether the solve is a
/// dynamic step (with velocities) or quasi-static, and the material's name for messages.
struct Solve<'s, 'm, M: Material> {
    model: &'s TetElastic<'m, M>,
    size: Real,
    dynamic: bool,
    model_name: &'s str,
}

/// Calls the dynamic solver `$step` (with velocities) or the quasi-static `$quasi_static` of
/// `$solve` on the `State` `$state`, with `$scene`, `$settings` and `$scratch`.
macro_rules! implicit_call {
    ($solve:expr, $state:expr, $scene:expr, $settings:expr, $scratch:expr, $step:ident, $quasi_static:ident) => {{
        let (solve, state): (&Solve<'_, '_, _>, &mut State) = ($solve, $state);
        let (masses, pinned) = (&state.masses, &state.pinned);
        if solve.dynamic {
            $step(
                solve.model,
                masses,
                pinned,
                $scene,
                $settings,
                &mut state.positions,
                &mut state.velocities,
                $scratch,
            )
        } else {
            $quasi_static(
                solve.model,
                masses,
                pinned,
                $scene,
                $settings,
                &mut state.positions,
                $scratch,
            )
        }
    }};
}

/// Draws the number of calls (1 to 3) and the `Extras` (external forces, fixed axes) of the
/// solver whose `$scene` lacks them, then runs the calls of [`implicit_call!`] with `$settings`,
/// each checked by [`Solve::check_calls`] against those fixed axes.
macro_rules! check_implicit_calls {
    ($draw:expr, $solve:expr, $state:expr, $scene:expr, $settings:expr, $scratch:expr, $step:ident, $quasi_static:ident) => {{
        let (draw, solve): (&mut Draw<'_>, &Solve<'_, '_, _>) = ($draw, $solve);
        let calls = draw.up_to(2);
        let extras = draw_extras(draw, solve.model.vertex_count(), solve.size * 1e3);
        let scene = $scene
            .with_external_forces(&extras.external_forces)
            .with_fixed_axes(&extras.fixed_axes);
        let settings = $settings;
        let name = solve.name(stringify!($step), stringify!($quasi_static));
        let describe = |_| {
            format!(
                "{name}(TetElastic<{}>, {scene:?}, {settings:?})",
                solve.model_name
            )
        };
        solve.check_calls($state, calls, &extras.fixed_axes, describe, |state, _| {
            implicit_call!(
                solve,
                state,
                &scene,
                &settings,
                $scratch,
                $step,
                $quasi_static
            )
        });
    }};
}

impl<M: Material> Solve<'_, '_, M> {
    /// `step` for a dynamic solve, `quasi_static` otherwise.
    fn name<'n>(&self, step: &'n str, quasi_static: &'n str) -> &'n str {
        if self.dynamic { step } else { quasi_static }
    }

    /// A time step of an implicit solver: `draw_dt`'s, or 10 or 1000 times it.
    fn draw_dt(&self, draw: &mut Draw<'_>, masses: &[Real]) -> Real {
        draw_dt(draw, self.model, masses) * [1.0, 10.0, 1e3][draw.index(2)]
    }

    /// Runs `calls + 1` solves (`solve`, given the state and the call's number) and checks each
    /// outcome: `check_outcome`, and the fixed coordinates of `fixed_axes`.
    fn check_calls<R: core::fmt::Debug, E: core::fmt::Debug>(
        &self,
        state: &mut State,
        calls: u32,
        fixed_axes: &[u8],
        describe: impl Fn(u32) -> String,
        mut solve: impl FnMut(&mut State, u32) -> Result<R, E>,
    ) {
        for call in 0..=calls {
            let before = (bits(&state.positions), bits(&state.velocities));
            let result = solve(state, call);
            let name = || format!("{}, call {call}", describe(call));
            check_outcome(name, &result, state, &before, self.dynamic);
            check_fixed_axes(name, &result, state, &before, fixed_axes);
        }
    }
}

/// The line search's constants, sometimes wild: `(armijo, backtrack)` overrides.
fn draw_search_constants(draw: &mut Draw<'_>) -> (Option<Real>, Option<Real>) {
    let armijo = draw.chance(24).then(|| draw_real::wild(draw));
    let backtrack = draw.chance(24).then(|| draw_real::wild(draw));
    (armijo, backtrack)
}

fn relax<M: Material>(draw: &mut Draw<'_>, solve: &Solve<'_, '_, M>, state: &mut State) {
    let dt = solve.draw_dt(draw, &state.masses);
    let mut scene = Scene::new(dt).with_gravity(draw_gravity(draw));
    scene.ground = draw_ground(draw, solve.size);
    let mut settings = RelaxSettings::new();
    let tolerance = match draw.up_to(7) {
        0 => draw_real::wild(draw),
        1 => 0.0,
        _ => 1e-3,
    };
    settings = settings.with_tolerance(tolerance, draw.up_to(40));
    let (armijo, backtrack) = draw_search_constants(draw);
    settings.armijo = armijo.unwrap_or(settings.armijo);
    settings.backtrack = backtrack.unwrap_or(settings.backtrack);
    settings.max_backtracks = draw.up_to(30);
    match draw.up_to(3) {
        0 => {}
        1 => {
            settings = settings.with_momentum(if draw.chance(32) {
                draw_real::wild(draw)
            } else {
                0.5
            })
        }
        _ => {
            let rho = if draw.chance(32) {
                draw_real::wild(draw)
            } else {
                0.99
            };
            let step = [1.0, 2.0, 4.0][draw.index(2)];
            settings = settings.with_chebyshev(rho, step, draw.up_to(8));
        }
    }
    if draw.chance(16) {
        settings.options.step_length = draw_real::wild(draw);
    }
    let n = solve.model.vertex_count();
    let mut vectors = vec![Vec3::ZERO; length_near(draw, scratch_len::relax(n))];
    let mut scalars = vec![0.0; length_near(draw, n)];
    let mut scratch = RelaxScratch::new(&mut vectors, &mut scalars);
    check_implicit_calls!(
        draw,
        solve,
        state,
        scene,
        settings,
        &mut scratch,
        relax_step,
        relax_quasi_static
    );
}

/// A tolerance: the solvers' usual `1e-3`, `1e-6`, zero (run the budget out), or anything.
fn draw_tolerance(draw: &mut Draw<'_>) -> Real {
    match draw.up_to(7) {
        0 => draw_real::wild(draw),
        1 => 0.0,
        2 => 1e-6,
        _ => 1e-3,
    }
}

fn newton<M: Material>(draw: &mut Draw<'_>, solve: &Solve<'_, '_, M>, state: &mut State) {
    let dt = solve.draw_dt(draw, &state.masses);
    let mut scene = Scene::new(dt).with_gravity(draw_gravity(draw));
    scene.ground = draw_ground(draw, solve.size);
    let mut settings = NewtonSettings::new()
        .with_tolerance(draw_tolerance(draw), draw.up_to(12))
        .with_cg_iterations(draw.up_to(60));
    let (armijo, backtrack) = draw_search_constants(draw);
    settings.armijo = armijo.unwrap_or(settings.armijo);
    settings.backtrack = backtrack.unwrap_or(settings.backtrack);
    settings.max_backtracks = draw.up_to(30);
    let n = solve.model.vertex_count();
    let lengths = scratch_len::newton(n, solve.model.element_count());
    let mut vectors = vec![Vec3::ZERO; length_near(draw, lengths.vectors)];
    let mut blocks = vec![Mat3::ZERO; length_near(draw, lengths.blocks)];
    let mut hessians = vec![TetHessian::ZERO; length_near(draw, lengths.hessians)];
    let mut scratch = NewtonScratch::new(&mut vectors, &mut blocks, &mut hessians);
    check_implicit_calls!(
        draw,
        solve,
        state,
        scene,
        settings,
        &mut scratch,
        newton_step,
        newton_quasi_static
    );
}

fn vbd<M: Material>(draw: &mut Draw<'_>, solve: &Solve<'_, '_, M>, state: &mut State) {
    let dt = solve.draw_dt(draw, &state.masses);
    let mut scene = Scene::new(dt).with_gravity(draw_gravity(draw));
    scene.ground = draw_ground(draw, solve.size);
    let mut settings = VbdSettings::new().with_tolerance(draw_tolerance(draw), draw.up_to(40));
    let (armijo, backtrack) = draw_search_constants(draw);
    settings.armijo = armijo.unwrap_or(settings.armijo);
    settings.backtrack = backtrack.unwrap_or(settings.backtrack);
    match draw.up_to(3) {
        0 => {}
        1 => settings = settings.with_line_search(draw.up_to(12)),
        2 => settings = settings.with_line_search_on_increase(),
        _ => settings.max_backtracks = 0,
    }
    match draw.up_to(3) {
        0 | 1 => {}
        2 => {
            let rho = if draw.chance(32) {
                draw_real::wild(draw)
            } else {
                0.9
            };
            settings = settings.with_chebyshev(rho, draw.up_to(8));
        }
        _ => settings = settings.with_estimated_chebyshev(draw.up_to(8)),
    }
    let n = solve.model.vertex_count();
    let elements = solve.model.element_count();
    let mut vectors = vec![Vec3::ZERO; length_near(draw, scratch_len::vbd(n))];
    let mut indices = vec![0u32; length_near(draw, scratch_len::vbd_indices(n, elements))];
    let mut values = vec![0.0 as Real; length_near(draw, scratch_len::vbd_layout(elements))];
    let mut corners = vec![0u32; length_near(draw, scratch_len::vbd_layout_corners(n, elements))];
    let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
    if draw.chance(128) {
        scratch = scratch.with_layout(&mut values, &mut corners);
    }
    let calls = draw.up_to(2);
    let extras = draw_extras(draw, n, solve.size * 1e3);
    let previous_velocities: Vec<Vec3> = if draw.byte() >= 192 {
        let wild = draw.chance(32);
        (0..length_near(draw, n))
            .map(|_| draw_vector(draw, 10.0, wild))
            .collect()
    } else {
        Vec::new()
    };
    let scene = scene
        .with_external_forces(&extras.external_forces)
        .with_fixed_axes(&extras.fixed_axes)
        .with_previous_velocities(&previous_velocities);
    let name = solve.name("vbd_step", "vbd_quasi_static");
    let describe = |_| {
        format!(
            "{name}(TetElastic<{}>, {scene:?}, {settings:?})",
            solve.model_name
        )
    };
    solve.check_calls(state, calls, &extras.fixed_axes, describe, |state, call| {
        if call > 0 && draw.chance(32) {
            scratch.reset_topology();
        }
        implicit_call!(
            solve,
            state,
            &scene,
            &settings,
            &mut scratch,
            vbd_step,
            vbd_quasi_static
        )
    });
}

//! The page's second scene (issue #43, "when bodies can touch each other, the page shows a
//! pile"): [`BALLS`] soft balls dropped in a spiral into a box of four low walls on the ground,
//! as `examples/pile` drops its eight (z up, metres, seconds). The balls are the bodies of one
//! `softfem::world::World` over growable storage, stepped with one implicit solve over all their
//! vertices per frame, with the barrier of Incremental Potential Contact between every pair of
//! boundary primitives (between balls and within one) and friction between their surfaces; the
//! walls are colliders given to each step, the ground is the world's.
//!
//! A pointer grab cannot make vertices kinematic as the playground does (`Body::set_target`
//! moves them to their targets before the solve, so a patch moved into another ball would start
//! the step with surfaces crossing, which the world's guarantee excludes). Here the grab pulls:
//! each held vertex gets an external force, constant over the step, that drives it toward where
//! the pointer wants it ([`PULL`]), so every motion goes through the solve and its continuous
//! collision detection and a dragged ball is pressed against the others, never into them.

use softfem::asset::surface::{RenderVertex, interleave, vertex_normals};
use softfem::body::{Solver, StepReport, VecStorage};
use softfem::element::TetRest;
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::{Quat, Vec3};
use softfem::material::{Material, NeoHookean, StVK, StableNeoHookean};
use softfem::step::contact::potential::ContactBarrier;
use softfem::step::{Collider, ExplicitSettings, HalfSpace, NewtonSettings, RelaxSettings, Scene};
use softfem::world::World;
use softfem::{BodyError, MaterialError, StepError};

use crate::scene::{
    DRAG_SPEED, Energy, GRAVITY, Model, PICK_RADIUS, SceneError, Settings, Stepper,
    check_frame_time, fnv1a,
};

/// How many balls fall into the box.
pub const BALLS: usize = 6;
/// The balls' radius (m), as in `examples/pile`.
pub const RADIUS: f32 = 0.04;
/// Cells along the side of the cube each ball is mapped from: `2^3` cells, five tetrahedra
/// each, 27 vertices and 40 tetrahedra a ball. `examples/pile` takes 4; a finer ball costs more
/// than a browser frame allows (3 cells: 22 ms a step natively here, against 12 ms for 2).
pub const CELLS: usize = 2;
/// The balls' density (kg/m^3).
pub const DENSITY: f32 = 1000.0;
/// The balls' Young's modulus relative to the settings' one (1e5 Pa at the page's default
/// 5e4 Pa, `examples/pile`'s).
pub const STIFFNESS: f32 = 2.0;
/// Half the inner width of the box (m): a 2 x 2 layer of balls (16 cm) just fits.
pub const HALF_WIDTH: f32 = 0.09;
/// The walls' height (m): two and a half ball radii, above the first layer's top and low
/// enough for the page's camera to look over.
pub const WALL_HEIGHT: f32 = 0.1;
/// Half the walls' thickness (m): 5 cm walls, thicker than a frame's motion (a vertex is pushed
/// out of a collider through its nearest face).
pub const WALL_HALF_THICKNESS: f32 = 0.025;
/// The Coulomb coefficient between the balls, on the ground and on the walls.
pub const FRICTION: f32 = 0.3;
/// The barrier's gap `dhat` (m) and the force (N) a pair at half of it holds.
pub const DHAT: f32 = 1e-3;
/// See [`DHAT`].
pub const HOLDING: f32 = 1.0;
/// Newton's relative tolerance and budget in the pile. The playground's `1e-4` is below the
/// f32 rounding floor of a resting pile (the solves stop there as stagnated after five
/// iterations or more, 16 ms a frame of the settled pile natively here against 5 ms at
/// `1e-2`); `3e-2` of the load (the larger of the first residual and the weight) takes the
/// first second, the landing, from 18.5 to 12.6 ms a frame natively (load 4).
pub const NEWTON_TOLERANCE: f32 = 3e-2;
/// See [`NEWTON_TOLERANCE`].
pub const NEWTON_ITERATIONS: u32 = 50;
/// The relaxation's tolerance and budget in the pile: its default 300 iterations take about
/// 200 ms a frame here natively, 100 take 122 ms over the first second and 60 take 80 ms (load
/// 4); most solves then stop unconverged, which the page's converged share shows.
pub const RELAX_TOLERANCE: f32 = 1e-2;
/// See [`RELAX_TOLERANCE`].
pub const RELAX_ITERATIONS: u32 = 60;
/// Vertices within this distance (m) of the picked vertex are pulled by a grab (less than the
/// playground's 5 cm: a ball is 8 cm across).
pub const GRAB_RADIUS: f32 = 0.045;
/// The pull of a grab, `h^2 omega^2` of a held vertex's spring (`omega` its angular
/// frequency, `h` the frame time): the force on a held vertex of mass `m` at `x` with velocity
/// `v` is `m (PULL (target - x) / h^2 - v / h)`, the spring plus the damping `2 zeta omega` with
/// `2 zeta omega h = 1`. Alone on a vertex, one step of it takes `v` to `PULL (target - x) / h`
/// and leaves `1 - PULL` of the distance: 0.51 here, no overshoot (damping ratio 0.71).
pub const PULL: f32 = 0.49;
/// The farthest (m) a held vertex's target counts from it: a ball pinned by the others feels at
/// most this stretch of the spring, not the whole way to the pointer.
pub const PULL_REACH: f32 = 0.05;

/// The four walls, axis-aligned boxes with inner faces at `|x|, |y| = HALF_WIDTH`, long enough
/// to close the corners, standing on the ground.
#[must_use]
pub fn walls() -> [Collider<'static>; 4] {
    let along = HALF_WIDTH + 2.0 * WALL_HALF_THICKNESS;
    let half_height = 0.5 * WALL_HEIGHT;
    [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y].map(|n| {
        let half = Vec3::new(
            if n.x == 0.0 {
                along
            } else {
                WALL_HALF_THICKNESS
            },
            if n.y == 0.0 {
                along
            } else {
                WALL_HALF_THICKNESS
            },
            half_height,
        );
        let centre = n * (HALF_WIDTH + WALL_HALF_THICKNESS) + Vec3::Z * half_height;
        Collider::cuboid(centre, half, Quat::IDENTITY).with_friction(FRICTION)
    })
}

/// The ground and the walls, as the page draws them (the ground is the world's, not a
/// collider of the step).
fn drawn_colliders() -> [Collider<'static>; 5] {
    let [a, b, c, d] = walls();
    [
        Collider::half_space(Vec3::ZERO, Vec3::Z).with_friction(FRICTION),
        a,
        b,
        c,
        d,
    ]
}

/// Ball `k`'s centre (m): a spiral, 135 degrees and 3 cm up from one ball to the next, 4.5 cm
/// from the box's axis, the lowest 5 mm above the ground: every pair starts at least 7.4 mm
/// apart, each ball 5 mm from the walls. `tests/common/ball_pile.rs` climbs 6 cm a ball at
/// 3.5 cm; half that height halves the fall, and the landing's first second costs 17 ms a frame
/// natively here instead of 26 (Newton iterates longer after a harder impact).
#[must_use]
pub fn centre(k: usize) -> Vec3 {
    let angle = (135.0 * k as f32).to_radians();
    Vec3::new(
        0.045 * angle.cos(),
        0.045 * angle.sin(),
        RADIUS + 0.005 + 0.03 * k as f32,
    )
}

/// A ball of [`RADIUS`] around `centre`: the cube `[-1, 1]^3` of [`CELLS`]`^3` cells mapped onto
/// the unit ball by the map that takes each face of the cube onto a sixth of the sphere
/// (P. Nowell, "Mapping a Cube to a Sphere", 2005: `x' = x sqrt(1 - y^2/2 - z^2/2 + y^2 z^2/3)`
/// and cyclically, as `tests/common/ball_pile.rs` in f64), then scaled and moved. Empty if the
/// generator refuses the counts (it does not for these); the world then refuses the body.
fn ball(centre: Vec3) -> (Vec<Vec3>, Vec<[u32; 4]>) {
    let n = CELLS;
    let split = BoxSplit::Alternating5;
    let (vertices, tets) = box_counts(n, n, n, split).unwrap_or((0, 0));
    let (mut x, mut cells) = (vec![Vec3::ZERO; vertices], vec![[0u32; 4]; tets]);
    if fill_box(-Vec3::ONE, Vec3::ONE, n, n, n, split, &mut x, &mut cells).is_err() {
        x.clear();
        cells.clear();
    }
    for p in &mut x {
        let s = *p * *p;
        let mapped = Vec3::new(
            p.x * (1.0 - s.y / 2.0 - s.z / 2.0 + s.y * s.z / 3.0).sqrt(),
            p.y * (1.0 - s.z / 2.0 - s.x / 2.0 + s.z * s.x / 3.0).sqrt(),
            p.z * (1.0 - s.x / 2.0 - s.y / 2.0 + s.x * s.y / 3.0).sqrt(),
        );
        *p = centre + mapped * RADIUS;
    }
    (x, cells)
}

/// The world's solver for the page's stepper: Newton and the relaxation with the pile's
/// tolerances, the explicit stepper as the playground's. Vertex Block Descent has none: the
/// world refuses it ([`BodyError::Solver`]).
///
/// # Errors
/// [`BodyError::Solver`] for [`Stepper::Vbd`].
pub fn solver(stepper: Stepper) -> Result<Solver, BodyError> {
    match stepper {
        Stepper::Explicit => Ok(Solver::Explicit {
            settings: ExplicitSettings::new().with_damping(1.0),
            stable_fraction: Some(0.5),
        }),
        Stepper::Relax => Ok(Solver::Relax(
            RelaxSettings::new().with_tolerance(RELAX_TOLERANCE, RELAX_ITERATIONS),
        )),
        Stepper::Newton => Ok(Solver::Newton(
            NewtonSettings::new().with_tolerance(NEWTON_TOLERANCE, NEWTON_ITERATIONS),
        )),
        Stepper::Vbd => Err(BodyError::Solver),
    }
}

/// A material model the page can choose, built from Young's modulus and Poisson's ratio.
trait Model3: Material + 'static {
    fn from_young_poisson(young: f32, poisson: f32) -> Result<Self, MaterialError>;
}

macro_rules! model3 {
    ($($model:ident),*) => {$(
        impl Model3 for $model {
            fn from_young_poisson(young: f32, poisson: f32) -> Result<Self, MaterialError> {
                $model::from_young_poisson(young, poisson)
            }
        }
    )*};
}
model3!(StVK, NeoHookean, StableNeoHookean);

/// A world of any of the three models, as the pile drives it.
trait SoftWorld {
    fn world_positions(&self) -> &[Vec3];
    fn world_velocities(&self) -> &[Vec3];
    fn world_masses(&self) -> &[f32];
    fn world_tets(&self) -> &[[u32; 4]];
    fn world_triangles(&self) -> &[[u32; 3]];
    /// Per body: its vertex range, tetrahedron range and triangle range.
    fn parts(&self) -> Vec<[core::ops::Range<usize>; 3]>;
    /// Copies `positions` and `velocities` (every vertex, body after body) into the world.
    fn set_state(&mut self, positions: &[Vec3], velocities: &[Vec3]);
    /// The elastic energy (J) of every body, from the rest data `rests` (one per tetrahedron;
    /// NaN for a missing one).
    fn elastic_energy(&self, rests: &[Option<TetRest>]) -> f32;
    fn set_young_poisson(&mut self, young: f32, poisson: f32) -> Result<(), MaterialError>;
    fn set_world_solver(&mut self, solver: Solver) -> Result<(), BodyError>;
    fn step(&mut self, scene: &Scene<'_, Vec3>) -> Result<StepReport, StepError>;
    /// The pairs in contact at the start of the last step (see [`Pile::contact_pairs`]).
    fn contact_pairs(&self) -> usize;
}

impl<M: Model3> SoftWorld for World<VecStorage, M> {
    fn world_positions(&self) -> &[Vec3] {
        self.positions()
    }
    fn world_velocities(&self) -> &[Vec3] {
        self.velocities()
    }
    fn world_masses(&self) -> &[f32] {
        self.masses()
    }
    fn world_tets(&self) -> &[[u32; 4]] {
        self.tets()
    }
    fn world_triangles(&self) -> &[[u32; 3]] {
        self.triangles()
    }
    fn parts(&self) -> Vec<[core::ops::Range<usize>; 3]> {
        self.bodies()
            .iter()
            .map(|part| [part.vertices(), part.tets(), part.triangles()])
            .collect()
    }
    fn set_state(&mut self, positions: &[Vec3], velocities: &[Vec3]) {
        for body in 0..self.body_count() {
            let Some(range) = self.bodies().get(body).map(|part| part.vertices()) else {
                continue;
            };
            let from = positions.get(range.clone()).unwrap_or(&[]);
            for (to, &from) in self
                .body_positions_mut(body)
                .unwrap_or_default()
                .iter_mut()
                .zip(from)
            {
                *to = from;
            }
            let from = velocities.get(range).unwrap_or(&[]);
            for (to, &from) in self
                .body_velocities_mut(body)
                .unwrap_or_default()
                .iter_mut()
                .zip(from)
            {
                *to = from;
            }
        }
    }
    fn elastic_energy(&self, rests: &[Option<TetRest>]) -> f32 {
        let x = self.positions();
        let mut total = 0.0;
        for part in self.bodies() {
            let tets = self.tets().get(part.tets()).unwrap_or(&[]);
            let rests = rests.get(part.tets()).unwrap_or(&[]);
            for (tet, rest) in tets.iter().zip(rests) {
                let corners = tet.map(|v| x.get(v as usize).copied().unwrap_or(Vec3::NAN));
                total += rest.map_or(f32::NAN, |rest| {
                    rest.elastic_energy(part.material(), corners)
                });
            }
        }
        total
    }
    fn set_young_poisson(&mut self, young: f32, poisson: f32) -> Result<(), MaterialError> {
        let material = M::from_young_poisson(young, poisson)?;
        for body in 0..self.body_count() {
            // In range: every index below the count.
            self.set_material(body, material).ok();
        }
        Ok(())
    }
    fn set_world_solver(&mut self, solver: Solver) -> Result<(), BodyError> {
        self.set_solver(solver)
    }
    fn step(&mut self, scene: &Scene<'_, Vec3>) -> Result<StepReport, StepError> {
        self.step_with(scene)
    }
    fn contact_pairs(&self) -> usize {
        self.contact_counts().friction
    }
}

/// The world of `model` with the balls at their starting centres, at rest, and the pile's
/// material, barrier, friction and solver for `settings`.
fn build(settings: &Settings) -> Result<Box<dyn SoftWorld>, SceneError> {
    fn typed<M: Model3>(settings: &Settings) -> Result<Box<dyn SoftWorld>, SceneError> {
        let material = M::from_young_poisson(settings.young * STIFFNESS, settings.poisson)?;
        let mut world = World::<VecStorage, M>::new();
        for k in 0..BALLS {
            let (x, tets) = ball(centre(k));
            world.add_body(&x, &tets, DENSITY, material)?;
        }
        let barrier = ContactBarrier::holding(DHAT, HOLDING)
            .map_err(|error| SceneError::Body(BodyError::Contact(error)))?;
        world.set_barrier(barrier)?;
        world.set_friction(FRICTION)?;
        world.set_solver(solver(settings.stepper)?)?;
        world.set_gravity(GRAVITY);
        world.set_ground(Some(ground()));
        Ok(Box::new(world))
    }
    match settings.model {
        Model::StVK => typed::<StVK>(settings),
        Model::NeoHookean => typed::<NeoHookean>(settings),
        Model::StableNeoHookean => typed::<StableNeoHookean>(settings),
    }
}

/// The ground, with the pile's friction.
fn ground() -> HalfSpace<Vec3> {
    HalfSpace::new(Vec3::Z, 0.0).with_friction(FRICTION)
}

/// The held patch of a grab.
#[derive(Clone, Debug)]
struct Grab {
    /// The ball.
    body: usize,
    /// Where the patch's anchor (the picked vertex) is wanted now (m).
    anchor: Vec3,
    /// Where the pointer wants it (m).
    pointer: Vec3,
    /// The held vertices (world indices) and their offsets from the anchor.
    held: Vec<(usize, Vec3)>,
    /// The ball's mass over the held vertices' mass: the weight each held vertex carries,
    /// per kilogram of its own.
    carry: f32,
}

/// The pile: the world, the walls, the clock, the grab and the render buffers.
pub struct Pile {
    settings: Settings,
    world: Box<dyn SoftWorld>,
    walls: [Collider<'static>; 4],
    drawn: [Collider<'static>; 5],
    /// Every tetrahedron's rest data, for the elastic energy (`None` for one the element code
    /// refuses, which the world has not admitted).
    rests: Vec<Option<TetRest>>,
    steps: u64,
    converged: u64,
    /// Contact pairs of the last step.
    pairs: usize,
    grab: Option<Grab>,
    /// The grab's forces (N), one per vertex; empty without a grab.
    forces: Vec<Vec3>,
    indices: Vec<u32>,
    layout: Vec<[u32; 4]>,
    normals: Vec<Vec3>,
    render: Vec<RenderVertex>,
}

impl Pile {
    /// The pile at `t = 0` with `settings`: the balls at rest in their spiral above the box.
    ///
    /// # Errors
    /// [`SceneError::Material`] for a Young's modulus or Poisson's ratio out of range,
    /// [`SceneError::FrameTime`] for a frame time that is not finite and positive,
    /// [`SceneError::Body`] with [`BodyError::Solver`] for Vertex Block Descent.
    pub fn new(settings: Settings) -> Result<Pile, SceneError> {
        check_frame_time(settings.frame_time)?;
        let world = build(&settings)?;
        let rest = world.world_positions();
        let rests = world
            .world_tets()
            .iter()
            .map(|tet| {
                let corners = tet.map(|v| rest.get(v as usize).copied().unwrap_or(Vec3::NAN));
                // The world accepted these tetrahedra, so none is degenerate.
                TetRest::new(corners).ok()
            })
            .collect();
        let indices: Vec<u32> = world.world_triangles().iter().flatten().copied().collect();
        let layout = world
            .parts()
            .iter()
            .map(|[vertices, _, triangles]| {
                [
                    vertices.start as u32,
                    vertices.len() as u32,
                    3 * triangles.start as u32,
                    3 * triangles.len() as u32,
                ]
            })
            .collect();
        let vertex_count = world.world_positions().len();
        let mut pile = Pile {
            settings,
            world,
            walls: walls(),
            drawn: drawn_colliders(),
            rests,
            steps: 0,
            converged: 0,
            pairs: 0,
            grab: None,
            forces: Vec::new(),
            indices,
            layout,
            normals: vec![Vec3::ZERO; vertex_count],
            render: vec![RenderVertex::default(); vertex_count],
        };
        pile.update_render();
        Ok(pile)
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> Settings {
        self.settings
    }

    /// Applies `settings` to the running pile: the material and the solver change in place; a
    /// new model rebuilds the world with the balls' current positions and velocities. A grab
    /// is dropped. Nothing changes on error.
    ///
    /// # Errors
    /// As [`Pile::new`].
    pub fn configure(&mut self, settings: Settings) -> Result<(), SceneError> {
        check_frame_time(settings.frame_time)?;
        let solver = solver(settings.stepper)?;
        StVK::from_young_poisson(settings.young * STIFFNESS, settings.poisson)?;
        self.release();
        if settings.model != self.settings.model {
            let mut world = build(&settings)?;
            world.set_state(self.world.world_positions(), self.world.world_velocities());
            self.world = world;
        } else {
            self.world
                .set_young_poisson(settings.young * STIFFNESS, settings.poisson)?;
            self.world.set_world_solver(solver)?;
        }
        self.settings = settings;
        Ok(())
    }

    /// Advances the pile by one step of the frame time: a held patch's pull, then one solve of
    /// the world with the walls.
    ///
    /// # Errors
    /// [`SceneError::Step`] (body 0: the world is one solve) with the world's error; the balls
    /// are as before the step.
    pub fn step(&mut self) -> Result<(), SceneError> {
        let dt = self.settings.frame_time;
        self.pull(dt);
        let scene = Scene::new(dt)
            .with_gravity(GRAVITY)
            .with_ground(ground())
            .with_colliders(&self.walls)
            .with_external_forces(&self.forces);
        let report = self
            .world
            .step(&scene)
            .map_err(|error| SceneError::Step { body: 0, error })?;
        self.steps += 1;
        self.converged += u64::from(report.converged());
        self.pairs = self.world.contact_pairs();
        Ok(())
    }

    /// Sets the grab's forces: the anchor moved toward the pointer by at most
    /// `DRAG_SPEED dt`, then each held vertex pulled toward its place beside it ([`PULL`]).
    fn pull(&mut self, dt: f32) {
        let Some(grab) = self.grab.as_mut() else {
            self.forces.clear();
            return;
        };
        let reach = grab.pointer - grab.anchor;
        let most = DRAG_SPEED * dt;
        let length = reach.length();
        grab.anchor += if length > most {
            reach * (most / length)
        } else {
            reach
        };
        let (x, v, m) = (
            self.world.world_positions(),
            self.world.world_velocities(),
            self.world.world_masses(),
        );
        self.forces.clear();
        self.forces.resize(x.len(), Vec3::ZERO);
        for &(vertex, offset) in &grab.held {
            let (Some(force), Some(&x), Some(&v), Some(&m)) = (
                self.forces.get_mut(vertex),
                x.get(vertex),
                v.get(vertex),
                m.get(vertex),
            ) else {
                continue;
            };
            let stretch = (grab.anchor + offset - x).clamp_length_max(PULL_REACH);
            *force = m * (stretch * (PULL / (dt * dt)) - v / dt - GRAVITY * grab.carry);
        }
    }

    /// Picks the vertex nearest the camera among those within [`PICK_RADIUS`] of the ray from
    /// `origin` along `direction` (any non-zero length) and pulls the vertices of its ball
    /// within [`GRAB_RADIUS`] of it toward where they are. Returns the picked vertex's
    /// position, or `None` (nothing grabbed) if no vertex is near the ray or the ray is
    /// degenerate.
    pub fn grab(&mut self, origin: Vec3, direction: Vec3) -> Option<Vec3> {
        self.release();
        let direction = direction.try_normalize()?;
        if !origin.is_finite() {
            return None;
        }
        let x = self.world.world_positions();
        let mut best: Option<(f32, usize)> = None;
        for (i, &p) in x.iter().enumerate() {
            let along = (p - origin).dot(direction);
            let off = (p - origin - direction * along).length();
            if along > 0.0 && off < PICK_RADIUS && best.is_none_or(|(b, _)| along < b) {
                best = Some((along, i));
            }
        }
        let (_, picked) = best?;
        let anchor = *x.get(picked)?;
        let parts = self.world.parts();
        let body = parts.iter().position(|[v, ..]| v.contains(&picked))?;
        let vertices = parts.get(body)?[0].clone();
        let masses = self.world.world_masses();
        let ball: f32 = masses.get(vertices.clone()).unwrap_or(&[]).iter().sum();
        let held: Vec<(usize, Vec3)> = vertices
            .filter_map(|i| Some((i, *x.get(i)?)))
            .filter(|(_, p)| p.distance(anchor) < GRAB_RADIUS)
            .map(|(i, p)| (i, p - anchor))
            .collect();
        let patch: f32 = held.iter().filter_map(|&(i, _)| masses.get(i)).sum();
        self.grab = Some(Grab {
            body,
            anchor,
            pointer: anchor,
            held,
            // The picked vertex is held, and every vertex has a positive lumped mass.
            carry: if patch > 0.0 { ball / patch } else { 0.0 },
        });
        Some(anchor)
    }

    /// Where the pointer wants the held patch's anchor (m); ignored without a grab or for a
    /// point that is not finite.
    pub fn drag(&mut self, pointer: Vec3) {
        if let Some(grab) = self.grab.as_mut()
            && pointer.is_finite()
        {
            grab.pointer = pointer;
        }
    }

    /// Lets go: no more pull (the balls keep the velocity the drag gave them).
    pub fn release(&mut self) {
        self.grab = None;
        self.forces.clear();
    }

    /// Whether a patch is held.
    #[must_use]
    pub fn grabbing(&self) -> bool {
        self.grab.is_some()
    }

    /// The ball a grab holds, if any.
    #[must_use]
    pub fn grabbed_body(&self) -> Option<usize> {
        self.grab.as_ref().map(|grab| grab.body)
    }

    /// Recomputes the render buffer: every ball's positions and area-weighted vertex normals of
    /// the world's boundary surface (`softfem::asset::surface`).
    pub fn update_render(&mut self) {
        let positions = self.world.world_positions();
        self.normals.resize(positions.len(), Vec3::ZERO);
        if vertex_normals(positions, self.world.world_triangles(), &mut self.normals).is_err() {
            self.normals.fill(Vec3::ZERO);
        }
        // The lengths agree (sized from the same world); on a mismatch nothing is written.
        interleave(positions, &self.normals, &mut self.render).ok();
    }

    /// The render buffer: every vertex of every ball, position and unit normal.
    #[must_use]
    pub fn render(&self) -> &[RenderVertex] {
        &self.render
    }

    /// The boundary triangles of every ball, indices into [`render`](Self::render).
    #[must_use]
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// Per ball: its first render vertex, vertex count, first index and index count.
    #[must_use]
    pub fn layout(&self) -> &[[u32; 4]] {
        &self.layout
    }

    /// The ground and the four walls.
    #[must_use]
    pub fn colliders(&self) -> &[Collider<'static>] {
        &self.drawn
    }

    /// Steps taken since the start.
    #[must_use]
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The simulated time (s) since the start, at the settings' frame time.
    #[must_use]
    pub fn time(&self) -> f64 {
        self.steps as f64 * f64::from(self.settings.frame_time)
    }

    /// The number of tetrahedra of all balls.
    #[must_use]
    pub fn tet_count(&self) -> usize {
        self.world.world_tets().len()
    }

    /// The number of vertices of all balls.
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.world.world_positions().len()
    }

    /// The boundary triangles of all balls (world vertex indices).
    #[must_use]
    pub fn triangles(&self) -> &[[u32; 3]] {
        self.world.world_triangles()
    }

    /// The share of steps whose solve converged (1 before any step).
    #[must_use]
    pub fn converged_share(&self) -> f64 {
        if self.steps == 0 {
            1.0
        } else {
            self.converged as f64 / self.steps as f64
        }
    }

    /// The contact pairs of the last step: the vertex–triangle and edge–edge pairs of the
    /// balls' surfaces closer than the barrier's gap [`DHAT`] at its start, those friction acts
    /// on (the world's `contact_counts().friction`; 0 before any step). Not the broad phase's
    /// candidates, whose boxes also overlap between primitives of one ball far apart.
    #[must_use]
    pub fn contact_pairs(&self) -> usize {
        self.pairs
    }

    /// Whether every position and velocity is finite.
    #[must_use]
    pub fn finite(&self) -> bool {
        self.world.world_positions().iter().all(|x| x.is_finite())
            && self.world.world_velocities().iter().all(|v| v.is_finite())
    }

    /// The energies (J), summed in f64 vertex by vertex; the elastic one in f32 tetrahedron by
    /// tetrahedron.
    #[must_use]
    pub fn energy(&self) -> Energy {
        let mut energy = Energy::default();
        let (x, v, m) = (
            self.world.world_positions(),
            self.world.world_velocities(),
            self.world.world_masses(),
        );
        for ((x, v), &m) in x.iter().zip(v).zip(m) {
            energy.kinetic += 0.5 * f64::from(m) * f64::from(v.length_squared());
            energy.gravity -= f64::from(m) * f64::from(GRAVITY.dot(*x));
        }
        energy.elastic = f64::from(self.world.elastic_energy(&self.rests));
        energy
    }

    /// FNV-1a (64 bits) of every position, their f32 bits in little-endian bytes in vertex
    /// order (as [`Playground::position_digest`](crate::scene::Playground::position_digest)).
    #[must_use]
    pub fn position_digest(&self) -> u64 {
        fnv1a(self.world.world_positions())
    }

    /// Every position (m), ball after ball.
    #[must_use]
    pub fn positions(&self) -> &[Vec3] {
        self.world.world_positions()
    }

    /// Every velocity (m/s), ball after ball.
    #[must_use]
    pub fn velocities(&self) -> &[Vec3] {
        self.world.world_velocities()
    }
}

// The exact triangle–triangle test the library's contact tests and `examples/pile` share.
#[cfg(test)]
#[path = "../../tests/common/exact_intersection.rs"]
mod exact;

#[cfg(test)]
mod tests {
    use super::*;

    /// The pairs of boundary triangles (sharing no vertex) that intersect, decided exactly.
    fn intersecting(pile: &Pile) -> usize {
        exact::intersecting_pairs_f32(pile.positions(), pile.triangles()).len()
    }

    /// Each ball's centroid (m), the mean of its vertices.
    fn centroids(pile: &Pile) -> Vec<Vec3> {
        pile.layout()
            .iter()
            .map(|&[first, count, ..]| {
                let x = &pile.positions()[first as usize..][..count as usize];
                x.iter().sum::<Vec3>() / count as f32
            })
            .collect()
    }

    /// The page's default settings as the pile admits them (Newton for VBD).
    fn newton() -> Settings {
        Settings {
            stepper: Stepper::Newton,
            ..Settings::default()
        }
    }

    /// One scenario rather than three tests, since each step costs about a quarter of a second
    /// in a debug build: the balls fall into the box (40 frames of 1/60 s), the top ball is
    /// pulled 10 cm up (12 frames) and let go (25 frames). After every step no two boundary
    /// triangles of the balls intersect (the exact test, independent of the barrier that keeps
    /// them apart) and every position and velocity is finite; the pile comes to rest twice.
    #[test]
    fn the_pile_lands_takes_a_drag_and_settles_with_no_surfaces_crossing() {
        let mut pile = Pile::new(newton()).unwrap();
        assert_eq!(intersecting(&pile), 0);
        assert_eq!(pile.contact_pairs(), 0);
        let start = pile.energy();
        let check = |pile: &mut Pile, steps: usize| {
            let mut peak: f64 = 0.0;
            for _ in 0..steps {
                pile.step().unwrap();
                let crossing = intersecting(pile);
                assert_eq!(crossing, 0, "step {}", pile.steps());
                assert!(pile.finite(), "step {}", pile.steps());
                peak = peak.max(pile.energy().kinetic);
            }
            peak
        };

        // Landing: the fall turns 0.8 J of gravitational energy into motion (0.30 J kinetic at
        // the peak) and strain, and implicit Euler with friction takes it out: 2/3 s later
        // 7e-5 J of kinetic energy is left.
        let fall = check(&mut pile, 40);
        let landed = pile.energy();
        assert!(fall > 0.1, "{fall}");
        assert!(landed.kinetic < 1e-3 * fall, "{} {fall}", landed.kinetic);
        assert!(landed.total() < start.total() - 0.5, "{landed:?} {start:?}");
        assert!(pile.contact_pairs() > 0);
        // A pile, not a row: a 2 x 2 layer fills the floor, so at most four balls lie on it
        // (centre below one radius plus the gap), the others on them, every centre below the
        // second layer's top, all inside the walls.
        let centres = centroids(&pile);
        let floor = centres.iter().filter(|c| c.z < RADIUS + DHAT).count();
        assert!((3..=4).contains(&floor), "{centres:?}");
        for c in &centres {
            assert!(c.z < 3.0 * RADIUS, "{centres:?}");
            assert!(
                c.x.abs().max(c.y.abs()) < HALF_WIDTH - 0.5 * RADIUS,
                "{centres:?}"
            );
        }

        // The drag: grabbed from straight above its highest vertex, the top ball follows the
        // pointer up, pressed against the others but not through them.
        let (_, &top) = pile
            .positions()
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
            .unwrap();
        assert_eq!(pile.grab(top + Vec3::Z, -Vec3::Z), Some(top));
        let body = pile.grabbed_body().unwrap();
        let before = centroids(&pile)[body];
        pile.drag(top + Vec3::Z * 0.1);
        check(&mut pile, 12);
        let lift = centroids(&pile)[body].z - before.z;
        assert!(lift > 0.05, "{lift}");
        pile.release();
        assert!(!pile.grabbing());

        // Dropped back onto the pile, it comes to rest again (the peak 0.13 J, the last
        // 8e-7 J).
        let drop = check(&mut pile, 25);
        assert!(
            pile.energy().kinetic < 1e-3 * drop,
            "{:?} {drop}",
            pile.energy()
        );
    }

    /// The balls start at rest and unstrained; each ball's mesh is symmetric about its centre
    /// (the cube's grid and Nowell's map are), so its lumped masses' first moment is its
    /// centre and the gravitational energy is `sum M g z_centre`.
    #[test]
    fn the_pile_starts_at_rest_with_the_closed_form_gravitational_energy() {
        let pile = Pile::new(newton()).unwrap();
        assert_eq!(pile.layout().len(), BALLS);
        assert_eq!((pile.vertex_count(), pile.tet_count()), (6 * 27, 6 * 40));
        let energy = pile.energy();
        assert_eq!(energy.kinetic, 0.0);
        assert!(energy.elastic.abs() < 1e-9, "{}", energy.elastic);
        let masses = pile.world.world_masses();
        let expected: f64 = pile
            .layout()
            .iter()
            .enumerate()
            .map(|(k, &[first, count, ..])| {
                let mass: f32 = masses[first as usize..][..count as usize].iter().sum();
                f64::from(mass) * 9.81 * f64::from(centre(k).z)
            })
            .sum();
        // f32 masses and positions, ~160 terms of ~0.01 J.
        assert!(
            (energy.gravity - expected).abs() < 1e-5,
            "{energy:?} {expected}"
        );
    }

    /// The world refuses Vertex Block Descent, and so does the pile; a new model keeps the
    /// state; a refused setting changes nothing.
    #[test]
    fn configure_refuses_vbd_and_keeps_the_state() {
        assert_eq!(
            Pile::new(Settings::default()).err(),
            Some(SceneError::Body(BodyError::Solver))
        );
        let mut pile = Pile::new(newton()).unwrap();
        pile.step().unwrap();
        let before = pile.positions().to_vec();
        let neo = Settings {
            model: Model::NeoHookean,
            ..newton()
        };
        pile.configure(neo).unwrap();
        assert_eq!(pile.positions(), &before[..]);
        assert_eq!(pile.settings(), neo);
        let vbd = Settings {
            stepper: Stepper::Vbd,
            ..neo
        };
        assert_eq!(
            pile.configure(vbd),
            Err(SceneError::Body(BodyError::Solver))
        );
        let soft = Settings {
            poisson: 0.5,
            ..neo
        };
        assert!(matches!(pile.configure(soft), Err(SceneError::Material(_))));
        assert_eq!(pile.settings(), neo);
        for stepper in [Stepper::Explicit, Stepper::Relax] {
            pile.configure(Settings { stepper, ..neo }).unwrap();
            pile.step().unwrap();
            assert!(pile.finite());
        }
    }
}

//! The colliders' playground of `examples/playground` as one value the page and the native timing
//! run both step: a soft ball and a soft box (and a second, stiffer ball) fall onto a kinematic
//! paddle that rocks back and forth, a sphere and a capsule, all on the ground (z up, metres,
//! seconds). Each body is a `softfem::body::Body` over growable storage (`VecStorage`), stepped
//! with `step_with_colliders`; bodies do not touch each other, only the colliders.
//!
//! Besides the example, a pointer can grab a body: the vertices within [`GRAB_RADIUS`] of the
//! picked one become kinematic (`Body::set_target`) and follow the pointer at most
//! [`DRAG_SPEED`] fast; releasing frees them with the velocity the drag gave them.

use softfem::asset::surface::{
    BoundaryFace, RenderVertex, boundary_faces, boundary_scratch_len, interleave, vertex_normals,
};
use softfem::body::{Body, Solver, StepReport, VecStorage};
use softfem::generate::{BoxSplit, box_counts, fill_box};
use softfem::glam::{Quat, Vec3};
use softfem::material::{Material, NeoHookean, StVK, StableNeoHookean};
use softfem::step::{Collider, ExplicitSettings, Shape};
use softfem::{BodyError, MaterialError, StepError};

/// z up (m/s^2).
pub const GRAVITY: Vec3 = Vec3::new(0.0, 0.0, -9.81);
/// The paddle's tilt about y is `AMPLITUDE sin(RATE t)` (rad).
pub const AMPLITUDE: f32 = 0.35;
/// The paddle's angular rate in that tilt (rad/s).
pub const RATE: f32 = 2.5;
/// Vertices within this distance (m) of the picked vertex are held by a grab.
pub const GRAB_RADIUS: f32 = 0.05;
/// A picked vertex lies within this distance (m) of the pointer's ray.
pub const PICK_RADIUS: f32 = 0.04;
/// The fastest a held patch follows the pointer (m/s): a pointer that jumps would otherwise
/// move the held vertices a long way in one step and crush the elements next to them.
pub const DRAG_SPEED: f32 = 4.0;

/// The hyperelastic model of every body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// Saint Venant–Kirchhoff.
    StVK,
    /// Neo-Hookean (infinite energy for inverted elements).
    NeoHookean,
    /// Stable Neo-Hookean (Smith, de Goes, Kim, "Stable Neo-Hookean Flesh Simulation", 2018).
    StableNeoHookean,
}

impl Model {
    /// The model numbered `code` as the page numbers them (0, 1, 2 in the order above).
    #[must_use]
    pub fn from_code(code: u32) -> Option<Model> {
        [Model::StVK, Model::NeoHookean, Model::StableNeoHookean]
            .get(code as usize)
            .copied()
    }
}

/// The stepper of every body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stepper {
    /// Explicit symplectic Euler, substeps of half the stable step, damping 1/s.
    Explicit,
    /// Implicit Euler, Chebyshev-accelerated relaxation.
    Relax,
    /// Implicit Euler, Newton's method.
    Newton,
    /// Implicit Euler, Vertex Block Descent.
    Vbd,
}

impl Stepper {
    /// The stepper numbered `code` as the page numbers them (0 to 3 in the order above).
    #[must_use]
    pub fn from_code(code: u32) -> Option<Stepper> {
        [
            Stepper::Explicit,
            Stepper::Relax,
            Stepper::Newton,
            Stepper::Vbd,
        ]
        .get(code as usize)
        .copied()
    }

    /// The body's solver, with the settings of `examples/playground`.
    #[must_use]
    pub fn solver(self) -> Solver {
        match self {
            Stepper::Explicit => Solver::Explicit {
                settings: ExplicitSettings::new().with_damping(1.0),
                stable_fraction: Some(0.5),
            },
            Stepper::Relax => Solver::relax(),
            Stepper::Newton => Solver::newton(),
            Stepper::Vbd => Solver::vbd(),
        }
    }
}

/// What the page's controls set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// The material model.
    pub model: Model,
    /// Young's modulus of the box (Pa); the first ball has 0.6 and the second 3 times this, as
    /// in `examples/playground` (3e4, 5e4 and 1.5e5 Pa at the default).
    pub young: f32,
    /// Poisson's ratio of every body, in `(-1, 1/2)`.
    pub poisson: f32,
    /// The stepper.
    pub stepper: Stepper,
    /// The simulated time of one frame, taken as one step (s), finite and positive.
    pub frame_time: f32,
}

impl Default for Settings {
    /// Stable Neo-Hookean, 5e4 Pa, 0.4, Vertex Block Descent, 1/60 s. VBD rather than the
    /// example's explicit stepper: a step of this scene takes about half the time (13 against
    /// 29 ms natively here), and implicit Euler damps the ringing a dragged body gets.
    fn default() -> Settings {
        Settings {
            model: Model::StableNeoHookean,
            young: 5.0e4,
            poisson: 0.4,
            stepper: Stepper::Vbd,
            frame_time: 1.0 / 60.0,
        }
    }
}

/// Why the scene could not be built, changed or stepped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SceneError {
    /// A material parameter was refused (Young's modulus or Poisson's ratio out of range).
    Material(MaterialError),
    /// A body refused its mesh, solver or a vertex.
    Body(BodyError),
    /// Body `body` could not be stepped; its state is as before the step.
    Step {
        /// The body (0: first ball, 1: box, 2: second ball).
        body: usize,
        /// The stepper's error.
        error: StepError,
    },
    /// The frame time is not finite and positive (s).
    FrameTime(f32),
    /// A model or stepper code out of range.
    Code(u32),
}

impl core::fmt::Display for SceneError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SceneError::Material(error) => write!(f, "material: {error}"),
            SceneError::Body(error) => write!(f, "body: {error}"),
            SceneError::Step { body, error } => write!(f, "body {body}: {error}"),
            SceneError::FrameTime(dt) => write!(f, "frame time {dt} s is not finite and positive"),
            SceneError::Code(code) => write!(f, "no model, stepper or scene numbered {code}"),
        }
    }
}

impl From<MaterialError> for SceneError {
    fn from(error: MaterialError) -> SceneError {
        SceneError::Material(error)
    }
}

impl From<BodyError> for SceneError {
    fn from(error: BodyError) -> SceneError {
        SceneError::Body(error)
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

/// A body of any of the three models, as the scene drives it.
trait SoftBody {
    fn positions(&self) -> &[Vec3];
    fn positions_mut(&mut self) -> &mut [Vec3];
    fn velocities(&self) -> &[Vec3];
    fn velocities_mut(&mut self) -> &mut [Vec3];
    fn masses(&self) -> &[f32];
    fn tets(&self) -> &[[u32; 4]];
    fn rest_positions(&self) -> &[Vec3];
    fn elastic_energy(&self) -> f32;
    fn set_young_poisson(&mut self, young: f32, poisson: f32) -> Result<(), MaterialError>;
    fn set_solver(&mut self, solver: Solver) -> Result<(), BodyError>;
    fn set_target(&mut self, vertex: usize, target: Vec3) -> Result<(), BodyError>;
    fn free(&mut self, vertex: usize) -> Result<(), BodyError>;
    fn step(&mut self, dt: f32, colliders: &[Collider<'_>]) -> Result<StepReport, StepError>;
}

impl<M: Model3> SoftBody for Body<VecStorage, M> {
    fn positions(&self) -> &[Vec3] {
        Body::positions(self)
    }
    fn positions_mut(&mut self) -> &mut [Vec3] {
        Body::positions_mut(self)
    }
    fn velocities(&self) -> &[Vec3] {
        Body::velocities(self)
    }
    fn velocities_mut(&mut self) -> &mut [Vec3] {
        Body::velocities_mut(self)
    }
    fn masses(&self) -> &[f32] {
        Body::masses(self)
    }
    fn tets(&self) -> &[[u32; 4]] {
        Body::tets(self)
    }
    fn rest_positions(&self) -> &[Vec3] {
        Body::rest_positions(self)
    }
    fn elastic_energy(&self) -> f32 {
        self.mesh()
            .elastic_energy(self.material(), Body::positions(self))
            .unwrap_or(f32::NAN)
    }
    fn set_young_poisson(&mut self, young: f32, poisson: f32) -> Result<(), MaterialError> {
        self.set_material(M::from_young_poisson(young, poisson)?);
        Ok(())
    }
    fn set_solver(&mut self, solver: Solver) -> Result<(), BodyError> {
        Body::set_solver(self, solver)
    }
    fn set_target(&mut self, vertex: usize, target: Vec3) -> Result<(), BodyError> {
        Body::set_target(self, vertex, target)
    }
    fn free(&mut self, vertex: usize) -> Result<(), BodyError> {
        self.set_pinned(vertex, false)
    }
    fn step(&mut self, dt: f32, colliders: &[Collider<'_>]) -> Result<StepReport, StepError> {
        self.step_with_colliders(dt, colliders)
    }
}

/// The three bodies' meshes and where each starts.
struct Start {
    rest: Vec<Vec3>,
    tets: Vec<[u32; 4]>,
    /// Where the body starts: its rest positions moved by this map.
    placed: Vec<Vec3>,
    density: f32,
    /// Young's modulus relative to the settings' one.
    stiffness: f32,
}

/// The ball's mesh: 6 x 6 x 6 cells, 5 tetrahedra each (343 vertices, 1080 tets).
const BALL_CELLS: usize = 6;

/// A ball of `radius` (m) around `center`: the box generator's cube mapped radially onto the
/// ball (each point scaled by its max-norm over its 2-norm, a continuous bijection that keeps
/// every tetrahedron positively oriented on this mesh), as in `examples/playground`.
fn ball(center: Vec3, radius: f32, stiffness: f32) -> Start {
    let n = BALL_CELLS;
    let (vertices, tets) = box_counts(n, n, n, BoxSplit::Alternating5).unwrap_or((0, 0));
    let (mut rest, mut cells) = (vec![Vec3::ZERO; vertices], vec![[0u32; 4]; tets]);
    let r = Vec3::splat(radius);
    let filled = fill_box(
        -r,
        r,
        n,
        n,
        n,
        BoxSplit::Alternating5,
        &mut rest,
        &mut cells,
    );
    if filled.is_err() {
        // Unreachable with these counts; an empty body is then refused by `from_arrays`.
        rest.clear();
        cells.clear();
    }
    for x in &mut rest {
        let length = x.length();
        if length > 0.0 {
            *x *= x.abs().max_element() / length;
        }
        *x += center;
    }
    Start {
        placed: rest.clone(),
        rest,
        tets: cells,
        density: 600.0,
        stiffness,
    }
}

/// A box `[low, high]` (m) of 6 x 4 x 3 cells (140 vertices, 360 tets), turned by `turn` about
/// its centre.
fn brick(low: Vec3, high: Vec3, turn: Quat, stiffness: f32) -> Start {
    let [nx, ny, nz] = [6, 4, 3];
    let (vertices, tets) = box_counts(nx, ny, nz, BoxSplit::Alternating5).unwrap_or((0, 0));
    let (mut rest, mut cells) = (vec![Vec3::ZERO; vertices], vec![[0u32; 4]; tets]);
    let filled = fill_box(
        low,
        high,
        nx,
        ny,
        nz,
        BoxSplit::Alternating5,
        &mut rest,
        &mut cells,
    );
    if filled.is_err() {
        rest.clear();
        cells.clear();
    }
    let centre = (low + high) * 0.5;
    let placed = rest.iter().map(|&x| centre + turn * (x - centre)).collect();
    Start {
        rest,
        tets: cells,
        placed,
        density: 800.0,
        stiffness,
    }
}

/// The bodies of `examples/playground`.
fn starts() -> [Start; 3] {
    [
        ball(Vec3::new(-0.6, 0.0, 1.0), 0.12, 0.6),
        brick(
            Vec3::new(0.05, -0.08, 0.8),
            Vec3::new(0.35, 0.08, 1.0),
            Quat::from_rotation_y(0.3),
            1.0,
        ),
        ball(Vec3::new(0.75, 0.0, 0.9), 0.1, 3.0),
    ]
}

/// The ground, the paddle (at `t = 0`), the sphere and the capsule, as in
/// `examples/playground`.
#[must_use]
pub fn colliders() -> [Collider<'static>; 4] {
    [
        Collider::half_space(Vec3::ZERO, Vec3::Z).with_friction(0.6),
        Collider::cuboid(
            Vec3::new(-0.55, 0.0, 0.55),
            Vec3::new(0.35, 0.3, 0.03),
            Quat::IDENTITY,
        )
        .with_friction(0.5)
        .with_restitution(0.3),
        Collider::sphere(Vec3::new(0.15, 0.0, 0.25), 0.25).with_friction(0.3),
        Collider::capsule(Vec3::new(0.6, 0.0, 0.15), Vec3::new(1.0, 0.0, 0.15), 0.15)
            .with_friction(0.3),
    ]
}

/// A body of `model` from `start` with the settings' material and stepper.
fn build(start: &Start, settings: &Settings) -> Result<Box<dyn SoftBody>, SceneError> {
    fn typed<M: Model3>(
        start: &Start,
        settings: &Settings,
    ) -> Result<Box<dyn SoftBody>, SceneError> {
        let material = M::from_young_poisson(settings.young * start.stiffness, settings.poisson)?;
        let mut body =
            Body::<VecStorage, M>::from_arrays(&start.rest, &start.tets, start.density, material)?;
        for (x, &placed) in body.positions_mut().iter_mut().zip(&start.placed) {
            *x = placed;
        }
        body.set_solver(settings.stepper.solver())?;
        body.set_gravity(GRAVITY);
        Ok(Box::new(body))
    }
    match settings.model {
        Model::StVK => typed::<StVK>(start, settings),
        Model::NeoHookean => typed::<NeoHookean>(start, settings),
        Model::StableNeoHookean => typed::<StableNeoHookean>(start, settings),
    }
}

/// The held patch of a grab.
#[derive(Clone, Debug)]
struct Grab {
    body: usize,
    /// Where the patch's anchor (the picked vertex) is held now (m).
    anchor: Vec3,
    /// Where the pointer wants it (m).
    pointer: Vec3,
    /// The held vertices and their offsets from the anchor.
    held: Vec<(usize, Vec3)>,
}

/// The energies of the scene (J): kinetic, gravitational (from z = 0) and elastic.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// `sum m |v|^2 / 2`.
    pub kinetic: f64,
    /// `-sum m g . x`: zero at z = 0.
    pub gravity: f64,
    /// The elastic energy of every body (infinite or NaN for a Neo-Hookean inverted element).
    pub elastic: f64,
}

impl Energy {
    /// The sum of the three.
    #[must_use]
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravity + self.elastic
    }
}

/// The scene: bodies, colliders, clock, grab and render buffers.
pub struct Playground {
    settings: Settings,
    bodies: Vec<Box<dyn SoftBody>>,
    scene: [Collider<'static>; 4],
    /// Steps taken since the start.
    steps: u64,
    /// Body-steps taken and how many of them converged.
    body_steps: u64,
    converged: u64,
    grab: Option<Grab>,
    /// Each body's boundary triangles (its own vertex indices).
    surfaces: Vec<Vec<[u32; 3]>>,
    /// All bodies' boundary triangles, indices into `render` (each body's vertices follow the
    /// previous body's).
    indices: Vec<u32>,
    /// Per body: first render vertex, vertex count, first index, index count.
    layout: Vec<[u32; 4]>,
    normals: Vec<Vec3>,
    render: Vec<RenderVertex>,
}

impl Playground {
    /// The scene at `t = 0` with `settings`.
    ///
    /// # Errors
    /// [`SceneError::Material`] for a Young's modulus or Poisson's ratio out of range,
    /// [`SceneError::FrameTime`] for a frame time that is not finite and positive.
    pub fn new(settings: Settings) -> Result<Playground, SceneError> {
        check_frame_time(settings.frame_time)?;
        let starts = starts();
        let bodies = starts
            .iter()
            .map(|start| build(start, &settings))
            .collect::<Result<Vec<_>, _>>()?;
        let mut surfaces = Vec::with_capacity(bodies.len());
        for start in &starts {
            let mut scratch = vec![BoundaryFace::default(); boundary_scratch_len(start.tets.len())];
            let faces = boundary_faces(&start.tets, start.rest.len(), &mut scratch)
                .map_or(&[][..], |faces| faces);
            surfaces.push(faces.iter().map(|face| face.triangle).collect::<Vec<_>>());
        }
        let (mut indices, mut layout) = (Vec::new(), Vec::new());
        let mut first_vertex = 0u32;
        for (surface, start) in surfaces.iter().zip(&starts) {
            let first_index = indices.len() as u32;
            indices.extend(surface.iter().flatten().map(|&v| v + first_vertex));
            let count = start.rest.len() as u32;
            layout.push([
                first_vertex,
                count,
                first_index,
                indices.len() as u32 - first_index,
            ]);
            first_vertex += count;
        }
        let vertex_count = first_vertex as usize;
        let mut playground = Playground {
            settings,
            bodies,
            scene: colliders(),
            steps: 0,
            body_steps: 0,
            converged: 0,
            grab: None,
            surfaces,
            indices,
            layout,
            normals: Vec::new(),
            render: vec![RenderVertex::default(); vertex_count],
        };
        playground.update_render();
        Ok(playground)
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> Settings {
        self.settings
    }

    /// Applies `settings` to the running scene: the material and the stepper change in place;
    /// a new model rebuilds the bodies at their current positions and velocities. A grab is
    /// dropped. Nothing changes on error.
    ///
    /// # Errors
    /// As [`Playground::new`].
    pub fn configure(&mut self, settings: Settings) -> Result<(), SceneError> {
        check_frame_time(settings.frame_time)?;
        let starts = starts();
        for start in &starts {
            // Checked for every body before anything changes.
            let young = settings.young * start.stiffness;
            StVK::from_young_poisson(young, settings.poisson)?;
        }
        self.release();
        if settings.model != self.settings.model {
            let mut bodies = starts
                .iter()
                .map(|start| build(start, &settings))
                .collect::<Result<Vec<_>, _>>()?;
            for (new, old) in bodies.iter_mut().zip(&self.bodies) {
                // The same meshes, so the same lengths.
                for (x, &old) in new.positions_mut().iter_mut().zip(old.positions()) {
                    *x = old;
                }
                for (v, &old) in new.velocities_mut().iter_mut().zip(old.velocities()) {
                    *v = old;
                }
            }
            self.bodies = bodies;
        } else {
            for (body, start) in self.bodies.iter_mut().zip(&starts) {
                body.set_young_poisson(settings.young * start.stiffness, settings.poisson)?;
                body.set_solver(settings.stepper.solver())?;
            }
        }
        self.settings = settings;
        Ok(())
    }

    /// Advances every body by one step of the frame time: the paddle's angular velocity at
    /// mid-step, its pose at the step's end, a held patch moved toward the pointer, then each
    /// body in turn (the order and arithmetic of `examples/playground`).
    ///
    /// # Errors
    /// [`SceneError::Step`] for the first body whose step failed; the bodies before it have
    /// stepped, it and the ones after have not.
    pub fn step(&mut self) -> Result<(), SceneError> {
        let dt = self.settings.frame_time;
        let t = (self.steps as f32 + 0.5) * dt;
        if let Some(paddle) = self.scene.get_mut(1) {
            paddle.angular_velocity = Vec3::Y * (AMPLITUDE * RATE * (RATE * t).cos());
            *paddle = paddle.advanced(dt);
        }
        self.hold(dt)?;
        for (k, body) in self.bodies.iter_mut().enumerate() {
            let report = body
                .step(dt, &self.scene)
                .map_err(|error| SceneError::Step { body: k, error })?;
            self.body_steps += 1;
            self.converged += u64::from(report.converged());
        }
        self.steps += 1;
        Ok(())
    }

    /// Moves the held patch's targets toward the pointer by at most `DRAG_SPEED dt`.
    fn hold(&mut self, dt: f32) -> Result<(), SceneError> {
        let Some(grab) = self.grab.as_mut() else {
            return Ok(());
        };
        let Some(body) = self.bodies.get_mut(grab.body) else {
            return Ok(());
        };
        let reach = grab.pointer - grab.anchor;
        let most = DRAG_SPEED * dt;
        let length = reach.length();
        grab.anchor += if length > most {
            reach * (most / length)
        } else {
            reach
        };
        for &(vertex, offset) in &grab.held {
            body.set_target(vertex, grab.anchor + offset)?;
        }
        Ok(())
    }

    /// Picks the vertex nearest the camera among those within [`PICK_RADIUS`] of the ray from
    /// `origin` along `direction` (any non-zero length), and holds the vertices of its body
    /// within [`GRAB_RADIUS`] of it where they are. Returns the picked vertex's position, or
    /// `None` (nothing grabbed) if no vertex is near the ray or the ray is degenerate.
    pub fn grab(&mut self, origin: Vec3, direction: Vec3) -> Option<Vec3> {
        self.release();
        let direction = direction.try_normalize()?;
        if !origin.is_finite() {
            return None;
        }
        let mut best: Option<(f32, usize, usize)> = None;
        for (k, body) in self.bodies.iter().enumerate() {
            for (i, &x) in body.positions().iter().enumerate() {
                let along = (x - origin).dot(direction);
                let off = (x - origin - direction * along).length();
                if along > 0.0 && off < PICK_RADIUS && best.is_none_or(|(b, _, _)| along < b) {
                    best = Some((along, k, i));
                }
            }
        }
        let (_, k, picked) = best?;
        let body = self.bodies.get(k)?;
        let anchor = *body.positions().get(picked)?;
        let held = body
            .positions()
            .iter()
            .enumerate()
            .filter(|(_, x)| x.distance(anchor) < GRAB_RADIUS)
            .map(|(i, &x)| (i, x - anchor))
            .collect();
        self.grab = Some(Grab {
            body: k,
            anchor,
            pointer: anchor,
            held,
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

    /// Frees the held vertices (they keep the velocity the drag gave them).
    pub fn release(&mut self) {
        if let Some(grab) = self.grab.take()
            && let Some(body) = self.bodies.get_mut(grab.body)
        {
            for (vertex, _) in grab.held {
                // In range: the vertices were taken from this body.
                body.free(vertex).ok();
            }
        }
    }

    /// Whether a patch is held.
    #[must_use]
    pub fn grabbing(&self) -> bool {
        self.grab.is_some()
    }

    /// Recomputes the render buffer: every body's positions and area-weighted vertex normals
    /// of its boundary surface (`softfem::asset::surface`).
    pub fn update_render(&mut self) {
        let mut slots = self.render.as_mut_slice();
        for (body, surface) in self.bodies.iter().zip(&self.surfaces) {
            let positions = body.positions();
            let (part, rest) = slots
                .split_at_mut_checked(positions.len())
                .unwrap_or_default();
            slots = rest;
            self.normals.resize(positions.len(), Vec3::ZERO);
            let normals = self.normals.as_mut_slice();
            if vertex_normals(positions, surface, normals).is_err() {
                normals.fill(Vec3::ZERO);
            }
            // The lengths agree (sized from the same bodies); on a mismatch nothing is written.
            interleave(positions, normals, part).ok();
        }
    }

    /// The render buffer: every vertex of every body, position and unit normal.
    #[must_use]
    pub fn render(&self) -> &[RenderVertex] {
        &self.render
    }

    /// The boundary triangles of every body, indices into [`render`](Self::render).
    #[must_use]
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// Per body: its first render vertex, vertex count, first index and index count.
    #[must_use]
    pub fn layout(&self) -> &[[u32; 4]] {
        &self.layout
    }

    /// The colliders as they are now: the ground, the paddle, the sphere, the capsule.
    #[must_use]
    pub fn colliders(&self) -> &[Collider<'static>] {
        &self.scene
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

    /// The number of tetrahedra of all bodies.
    #[must_use]
    pub fn tet_count(&self) -> usize {
        self.bodies.iter().map(|b| b.tets().len()).sum()
    }

    /// The number of vertices of all bodies.
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.bodies.iter().map(|b| b.positions().len()).sum()
    }

    /// The share of body-steps whose solver converged (1 before any step; always 1 for the
    /// explicit stepper).
    #[must_use]
    pub fn converged_share(&self) -> f64 {
        if self.body_steps == 0 {
            1.0
        } else {
            self.converged as f64 / self.body_steps as f64
        }
    }

    /// Whether every position and velocity of every body is finite.
    #[must_use]
    pub fn finite(&self) -> bool {
        self.bodies.iter().all(|b| {
            b.positions().iter().all(|x| x.is_finite())
                && b.velocities().iter().all(|v| v.is_finite())
        })
    }

    /// The energies (J), summed in f64 body by body, vertex by vertex.
    #[must_use]
    pub fn energy(&self) -> Energy {
        let mut energy = Energy::default();
        for body in &self.bodies {
            for ((x, v), &m) in body
                .positions()
                .iter()
                .zip(body.velocities())
                .zip(body.masses())
            {
                energy.kinetic += 0.5 * f64::from(m) * f64::from(v.length_squared());
                energy.gravity -= f64::from(m) * f64::from(GRAVITY.dot(*x));
            }
            energy.elastic += f64::from(body.elastic_energy());
        }
        energy
    }

    /// FNV-1a (64 bits) of every body's positions, their f32 bits in little-endian bytes in body
    /// and vertex order: equal digests from two builds (wasm with and without SIMD128, native)
    /// mean the same positions bit for bit.
    #[must_use]
    pub fn position_digest(&self) -> u64 {
        fnv1a(self.bodies.iter().flat_map(|b| b.positions().iter()))
    }

    /// The rest positions of body `k` (m), for tests.
    #[must_use]
    pub fn rest_positions(&self, k: usize) -> Option<&[Vec3]> {
        self.bodies.get(k).map(|b| b.rest_positions())
    }

    /// The positions of body `k` (m).
    #[must_use]
    pub fn positions(&self, k: usize) -> Option<&[Vec3]> {
        self.bodies.get(k).map(|b| b.positions())
    }
}

/// FNV-1a (64 bits) of `positions`, their f32 bits in little-endian bytes in order.
pub(crate) fn fnv1a<'a>(positions: impl IntoIterator<Item = &'a Vec3>) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let bytes = positions
        .into_iter()
        .flat_map(|x| x.to_array())
        .flat_map(|c| c.to_bits().to_le_bytes());
    for byte in bytes {
        hash = (hash ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3);
    }
    hash
}

/// Refuses a frame time that is not finite and positive (s).
pub(crate) fn check_frame_time(dt: f32) -> Result<(), SceneError> {
    if dt > 0.0 && dt.is_finite() {
        Ok(())
    } else {
        Err(SceneError::FrameTime(dt))
    }
}

/// The numbers the page draws a collider from: kind (0 half-space, 1 sphere, 2 capsule,
/// 3 box), position (m), rotation (x, y, z, w) and the shape's sizes (radius; half length and
/// radius; half extents), 11 numbers.
#[must_use]
pub fn collider_record(collider: &Collider<'_>) -> [f32; 11] {
    let (kind, sizes) = match collider.shape {
        Shape::HalfSpace => (0.0, [0.0; 3]),
        Shape::Sphere { radius } => (1.0, [radius, 0.0, 0.0]),
        Shape::Capsule {
            half_length,
            radius,
        } => (2.0, [half_length, radius, 0.0]),
        Shape::Cuboid { half_extents } => (3.0, half_extents.to_array()),
        _ => (-1.0, [0.0; 3]),
    };
    let [x, y, z] = collider.position.to_array();
    let [qx, qy, qz, qw] = collider.rotation.to_array();
    let [a, b, c] = sizes;
    [kind, x, y, z, qx, qy, qz, qw, a, b, c]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn playground() -> Playground {
        Playground::new(Settings::default()).unwrap()
    }

    /// The volume of the positively oriented tetrahedron `[a, b, c, d]`.
    fn tet_volume(x: &[Vec3], tet: [u32; 4]) -> f32 {
        let [a, b, c, d] = tet.map(|v| x[v as usize]);
        (b - a).dot((c - a).cross(d - a)) / 6.0
    }

    /// Each body's render surface is closed and outward: every directed edge once and its
    /// reverse once, and the divergence theorem over its triangles gives the summed volume of
    /// its tetrahedra (an identity independent of how the boundary was found).
    #[test]
    fn every_body_surface_is_closed_and_encloses_its_tets() {
        let p = playground();
        assert_eq!(p.layout().len(), 3);
        for (k, &[first_vertex, vertex_count, first_index, index_count]) in
            p.layout().iter().enumerate()
        {
            let x = p.positions(k).unwrap();
            assert_eq!(x.len(), vertex_count as usize);
            let indices = &p.indices()[first_index as usize..][..index_count as usize];
            let triangles: Vec<[u32; 3]> = indices
                .chunks(3)
                .map(|t| [t[0], t[1], t[2]].map(|v| v - first_vertex))
                .collect();
            let mut edges = HashMap::new();
            for &[a, b, c] in &triangles {
                for edge in [[a, b], [b, c], [c, a]] {
                    *edges.entry(edge).or_insert(0) += 1;
                }
            }
            for (&[a, b], &count) in &edges {
                assert_eq!((count, edges.get(&[b, a])), (1, Some(&1)), "body {k}");
            }
            let enclosed: f32 = triangles
                .iter()
                .map(|t| t.map(|v| x[v as usize]))
                .map(|[a, b, c]| a.dot(b.cross(c)) / 6.0)
                .sum();
            let tets: f32 = p.bodies[k].tets().iter().map(|&t| tet_volume(x, t)).sum();
            // f32 sums of ~1000 terms of size ~1e-6 m^3 at coordinates ~1 m.
            assert!(
                (enclosed - tets).abs() < 1e-4 * tets,
                "body {k}: {enclosed} {tets}"
            );
        }
    }

    /// The box (body 1): 0.3 x 0.16 x 0.2 m at 800 kg/m^3 is 7.68 kg; lumped masses keep the
    /// first moment exact, so its gravitational energy is `M g z_centre` with the centre at
    /// z = 0.9 m (it is turned about it), and it starts at rest.
    #[test]
    fn the_box_starts_at_rest_with_the_closed_form_gravitational_energy() {
        let p = playground();
        let body = &p.bodies[1];
        let mass: f32 = body.masses().iter().sum();
        assert!((mass - 7.68).abs() < 1e-4, "{mass}");
        let gravity: f64 = body
            .positions()
            .iter()
            .zip(body.masses())
            .map(|(x, &m)| f64::from(m) * 9.81 * f64::from(x.z))
            .sum();
        assert!((gravity - 7.68 * 9.81 * 0.9).abs() < 1e-3, "{gravity}");
        assert_eq!(p.energy().kinetic, 0.0);
        // Rest: the turn is rigid, so no strain energy beyond rounding.
        assert!(p.energy().elastic.abs() < 1e-6, "{}", p.energy().elastic);
    }

    /// Render normals are unit vectors on the surface and point away from the body's centre
    /// (the balls are convex); positions are the bodies' positions.
    #[test]
    fn render_buffer_holds_positions_and_outward_unit_normals() {
        let p = playground();
        for (k, &[first, count, ..]) in p.layout().iter().enumerate() {
            let x = p.positions(k).unwrap();
            let centre = x.iter().sum::<Vec3>() / x.len() as f32;
            let part = &p.render()[first as usize..][..count as usize];
            let mut on_surface = 0;
            for (vertex, &position) in part.iter().zip(x) {
                assert_eq!(vertex.position, position);
                if vertex.normal != Vec3::ZERO {
                    on_surface += 1;
                    assert!((vertex.normal.length() - 1.0).abs() < 1e-5);
                    assert!(vertex.normal.dot(position - centre) > 0.0, "body {k}");
                }
            }
            // The grid vertices on the boundary of a 7 x 7 x 7 (balls) or 7 x 5 x 4 (box) grid
            // are the grid's less its interior.
            let boundary = if k == 1 {
                7 * 5 * 4 - 5 * 3 * 2
            } else {
                7 * 7 * 7 - 5 * 5 * 5
            };
            assert_eq!(on_surface, boundary, "body {k}");
        }
    }

    /// A grab from straight above the box's highest vertex holds the vertices within the grab
    /// radius; each step moves them toward the pointer by `DRAG_SPEED dt` exactly (a kinematic
    /// vertex lands on its target), and a release frees them.
    #[test]
    fn a_grab_follows_the_pointer_at_the_drag_speed() {
        let mut p = playground();
        let x = p.positions(1).unwrap().to_vec();
        let (top, &point) = x
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
            .unwrap();
        let expected = x.iter().filter(|y| y.distance(point) < GRAB_RADIUS).count();
        let grabbed = p.grab(point + Vec3::Z * 2.0, -Vec3::Z * 3.0).unwrap();
        assert_eq!(grabbed, point);
        assert_eq!(p.grab.as_ref().unwrap().held.len(), expected);
        p.drag(point + Vec3::Z);
        p.step().unwrap();
        let dt = p.settings().frame_time;
        let moved = p.positions(1).unwrap()[top];
        let lift = DRAG_SPEED * dt;
        assert!(
            (moved - (point + Vec3::Z * lift)).length() < 1e-6,
            "{moved} {point}"
        );
        p.release();
        assert!(!p.grabbing());
        // A ray that passes nowhere near a body grabs nothing.
        assert_eq!(p.grab(Vec3::new(5.0, 5.0, 5.0), Vec3::Z), None);
        assert_eq!(p.grab(Vec3::ZERO, Vec3::ZERO), None);
    }

    /// A new model keeps the state; a refused Poisson's ratio or frame time changes nothing.
    #[test]
    fn configure_keeps_the_state_and_refuses_out_of_range_settings() {
        let mut p = playground();
        p.step().unwrap();
        let before: Vec<Vec3> = p.positions(0).unwrap().to_vec();
        let neo = Settings {
            model: Model::NeoHookean,
            stepper: Stepper::Vbd,
            ..Settings::default()
        };
        p.configure(neo).unwrap();
        assert_eq!(p.positions(0).unwrap(), &before[..]);
        assert_eq!(p.settings(), neo);
        let bad = Settings {
            poisson: 0.5,
            ..neo
        };
        assert!(matches!(p.configure(bad), Err(SceneError::Material(_))));
        let bad = Settings {
            frame_time: 0.0,
            ..neo
        };
        assert_eq!(p.configure(bad), Err(SceneError::FrameTime(0.0)));
        assert_eq!(p.settings(), neo);
        assert_eq!(Model::from_code(3), None);
        assert_eq!(Stepper::from_code(4), None);
    }

    /// The capsule's record: its rotation takes the frame's z axis to the segment's direction
    /// and its half length is half the segment (0.6 to 1.0 m along x).
    #[test]
    fn collider_records_describe_the_shapes() {
        let records = colliders().map(|c| collider_record(&c));
        assert_eq!(records.map(|r| r[0]), [0.0, 3.0, 1.0, 2.0]);
        let [_, x, y, z, qx, qy, qz, qw, half_length, radius, _] = records[3];
        assert_eq!([x, y, z], [0.8, 0.0, 0.15]);
        let axis = Quat::from_xyzw(qx, qy, qz, qw) * Vec3::Z;
        assert!((axis - Vec3::X).length() < 1e-6, "{axis}");
        assert!((half_length - 0.2).abs() < 1e-6 && radius == 0.15);
    }
}

//! What the page shows: the playground ([`Playground`], separate bodies on the colliders) or the
//! pile ([`Pile`], balls in one world in contact), behind one face for the exports and the
//! timing program.

use softfem::asset::surface::RenderVertex;
use softfem::glam::Vec3;
use softfem::step::Collider;

use crate::pile::Pile;
use crate::scene::{Energy, Playground, SceneError, Settings, Stepper};

/// Which scene: the page numbers them 0 (playground) and 1 (pile).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Kind {
    /// The colliders' playground (the page's default).
    #[default]
    Playground,
    /// The pile of balls in a box.
    Pile,
}

impl Kind {
    /// The scene numbered `code` as the page numbers them.
    #[must_use]
    pub fn from_code(code: u32) -> Option<Kind> {
        [Kind::Playground, Kind::Pile].get(code as usize).copied()
    }

    /// The settings a scene of this kind starts from when asked for `settings`: the pile's
    /// world refuses Vertex Block Descent, so the pile takes Newton's method instead.
    #[must_use]
    pub fn admitted(self, settings: Settings) -> Settings {
        match (self, settings.stepper) {
            (Kind::Pile, Stepper::Vbd) => Settings {
                stepper: Stepper::Newton,
                ..settings
            },
            _ => settings,
        }
    }
}

/// The scene the page steps and draws (each boxed: both hold their colliders and settings
/// inline, several hundred bytes).
pub enum Stage {
    /// The playground.
    Playground(Box<Playground>),
    /// The pile.
    Pile(Box<Pile>),
}

/// `$body` with `$s` bound to the scene, whichever it is.
macro_rules! each {
    ($stage:expr, $s:ident => $body:expr) => {
        match $stage {
            Stage::Playground($s) => $body,
            Stage::Pile($s) => $body,
        }
    };
}

impl Stage {
    /// A scene of `kind` at `t = 0` with `settings` (see [`Kind::admitted`] for the pile).
    ///
    /// # Errors
    /// As [`Playground::new`] and [`Pile::new`].
    pub fn new(kind: Kind, settings: Settings) -> Result<Stage, SceneError> {
        match kind {
            Kind::Playground => Playground::new(settings).map(|p| Stage::Playground(Box::new(p))),
            Kind::Pile => {
                Pile::new(kind.admitted(settings)).map(|pile| Stage::Pile(Box::new(pile)))
            }
        }
    }

    /// Which scene this is.
    #[must_use]
    pub fn kind(&self) -> Kind {
        match self {
            Stage::Playground(_) => Kind::Playground,
            Stage::Pile(_) => Kind::Pile,
        }
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> Settings {
        each!(self, s => s.settings())
    }

    /// Applies `settings` to the running scene.
    ///
    /// # Errors
    /// As [`Playground::configure`] and [`Pile::configure`]; nothing changes then.
    pub fn configure(&mut self, settings: Settings) -> Result<(), SceneError> {
        each!(self, s => s.configure(settings))
    }

    /// One step of the frame time.
    ///
    /// # Errors
    /// As [`Playground::step`] and [`Pile::step`].
    pub fn step(&mut self) -> Result<(), SceneError> {
        each!(self, s => s.step())
    }

    /// Grabs the vertex nearest the camera near the ray from `origin` along `direction`.
    pub fn grab(&mut self, origin: Vec3, direction: Vec3) -> Option<Vec3> {
        each!(self, s => s.grab(origin, direction))
    }

    /// Where the pointer wants the grabbed point (m).
    pub fn drag(&mut self, pointer: Vec3) {
        each!(self, s => s.drag(pointer));
    }

    /// Lets go of the grabbed body.
    pub fn release(&mut self) {
        each!(self, s => s.release());
    }

    /// Whether a body is grabbed.
    #[must_use]
    pub fn grabbing(&self) -> bool {
        each!(self, s => s.grabbing())
    }

    /// Recomputes the render buffer.
    pub fn update_render(&mut self) {
        each!(self, s => s.update_render());
    }

    /// Every vertex of every body, position and unit normal.
    #[must_use]
    pub fn render(&self) -> &[RenderVertex] {
        each!(self, s => s.render())
    }

    /// The boundary triangles, indices into [`render`](Self::render).
    #[must_use]
    pub fn indices(&self) -> &[u32] {
        each!(self, s => s.indices())
    }

    /// Per body: first render vertex, vertex count, first index, index count.
    #[must_use]
    pub fn layout(&self) -> &[[u32; 4]] {
        each!(self, s => s.layout())
    }

    /// The colliders as they are now, ground first.
    #[must_use]
    pub fn colliders(&self) -> &[Collider<'static>] {
        each!(self, s => s.colliders())
    }

    /// Steps taken since the start.
    #[must_use]
    pub fn steps(&self) -> u64 {
        each!(self, s => s.steps())
    }

    /// The simulated time (s).
    #[must_use]
    pub fn time(&self) -> f64 {
        each!(self, s => s.time())
    }

    /// The number of tetrahedra.
    #[must_use]
    pub fn tet_count(&self) -> usize {
        each!(self, s => s.tet_count())
    }

    /// The number of vertices.
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        each!(self, s => s.vertex_count())
    }

    /// The share of solves that converged.
    #[must_use]
    pub fn converged_share(&self) -> f64 {
        each!(self, s => s.converged_share())
    }

    /// The contact pairs between surfaces in the last step (the playground's bodies do not
    /// touch each other: 0).
    #[must_use]
    pub fn contact_pairs(&self) -> usize {
        match self {
            Stage::Playground(_) => 0,
            Stage::Pile(pile) => pile.contact_pairs(),
        }
    }

    /// Whether every position and velocity is finite.
    #[must_use]
    pub fn finite(&self) -> bool {
        each!(self, s => s.finite())
    }

    /// The energies (J).
    #[must_use]
    pub fn energy(&self) -> Energy {
        each!(self, s => s.energy())
    }

    /// FNV-1a of every position's bits, in order.
    #[must_use]
    pub fn position_digest(&self) -> u64 {
        each!(self, s => s.position_digest())
    }
}

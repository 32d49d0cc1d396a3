//! An owning soft body: rest shape, tetrahedra, rest data, masses, pins, state, material, the
//! chosen solver and its scratch, in one value an engine can hold, stepped by
//! [`Body::step`]. The storage is chosen at the type level: [`FixedStorage`] (fixed capacity,
//! no heap: firmware) or `VecStorage` (feature `alloc`).
//!
//! The mesh is validated once, when the body is built; each step rebuilds the borrowed views of
//! the low-level kernels ([`TetMesh`], [`TetElastic`], the scratch types) from that data without
//! a second validation pass, and keeps what the solvers remember between steps (the explicit
//! stepper's blow-up history, the relaxation's preconditioner, Vertex Block Descent's
//! colouring). The results are those of the low-level calls, bit for bit.
//!
//! The constructors (`from_box`, `from_arrays`, `from_tetgen`) return the body by value, which
//! for a large fixed-capacity body costs stack several times its size while it is built and
//! moved. Where the stack is small (firmware), start from the `const` [`Body::empty`] in a
//! `static` and build in place with [`Body::rebuild_from_box`] or
//! [`Body::rebuild_from_arrays`]; the same methods reuse a body's storage for a new mesh.
//!
//! A jelly cube dropped onto the ground and stepped for a second (y up), no heap, by the
//! default [`Solver::auto`] (here explicit substeps: a soft body at 60 Hz needs few):
//! ```
//! use softfem::body::{Body, FixedStorage};
//! use softfem::{glam::Vec3, material::StableNeoHookean, step::HalfSpace};
//!
//! let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.45)?; // Pa
//! let (low, high) = (Vec3::new(-0.1, 0.1, -0.1), Vec3::new(0.1, 0.3, 0.1)); // m
//! // 4 x 4 x 4 cells: 125 vertices, 320 tetrahedra, 1000 kg/m^3.
//! let mut body = Body::<FixedStorage<125, 320>, _>::from_box(low, high, [4; 3], 1000.0, jelly)?;
//! body.set_gravity(Vec3::new(0.0, -9.81, 0.0)); // m/s^2
//! body.set_ground(Some(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5))); // the plane y = 0
//! for _ in 0..60 {
//!     let report = body.step(1.0 / 60.0)?; // substeps of half the stable step, computed once
//!     assert!(report.converged());
//! }
//! assert!(body.positions().iter().all(|x| x.y > -1e-3 && x.y < 0.25)); // landed
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A cantilever pinned at one end, stepped by implicit Euler at 60 Hz (Newton's method),
//! growable storage:
//! ```
//! # #[cfg(feature = "alloc")] {
//! use softfem::body::{Body, Solver, VecStorage};
//! use softfem::{glam::Vec3, material::StableNeoHookean};
//!
//! let rubber = StableNeoHookean::from_young_poisson(1.0e6, 0.4)?; // Pa
//! let high = Vec3::new(0.5, 0.1, 0.1); // m
//! let mut body = Body::<VecStorage, _>::from_box(Vec3::ZERO, high, [5, 1, 1], 1100.0, rubber)?;
//! body.set_solver(Solver::newton())?;
//! body.set_gravity(Vec3::new(0.0, -9.81, 0.0));
//! let wall: Vec<usize> = (0..body.vertex_count()).filter(|&i| body.rest_positions()[i].x == 0.0).collect();
//! for &vertex in &wall { body.set_pinned(vertex, true)?; }
//! for _ in 0..60 { body.step(1.0 / 60.0)?; }
//! let tip = body.positions().iter().map(|x| x.y).fold(f32::INFINITY, f32::min);
//! assert!(tip < -0.001 && tip > -0.1, "{tip}"); // sagged, not fallen
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod auto;
mod solver;
mod storage;

pub use auto::{AutoChoice, AutoReport, AutoRun, AutoSettings, Fallback, stopped_at_floor};
pub use solver::{CoupledReport, Solver, StepReport};
#[cfg(feature = "alloc")]
pub use storage::VecStorage;
pub use storage::{Fixed, FixedStorage, Slots, Storage};

use core::fmt;

use super::element::{TetHessian, TetRest};
use super::generate::{BoxSplit, box_counts, fill_box};
use super::material::Material;
use super::mesh::{TetMesh, TetRestBlock, rest_block_count};
use super::step::contact::reaction::{recorded_reactions, recording_slots};
use super::step::contact::attachment::{
    MAX_ATTACHMENTS, SoftPull, add_attachment_reactions, check_attachments, end_anchor,
};
use super::step::contact::rigid::{check_coupled_step, couple};
use super::step::state::check_length;
use super::step::{
    Attachment, Collider, CouplingSettings, ExplicitMemory, ExplicitScratch, HalfSpace, NewtonScratch, Reaction,
    RelaxScratch, Scene, TetElastic, VbdScratch, VbdTopology, 
    attachment_reaction, check_time_step, explicit_step,  newton_step, relax_step, scratch_len,
    stable_time_step, vbd_step,
};
use super::types::{Mat3, Real, Vec3};
use crate::error::{BodyBuffer, BodyError, StepBuffer, StepError};

/// An elastic tetrahedral body that owns everything a step needs; see the
/// [module documentation](self).
///
/// `S` is the [`Storage`] ([`FixedStorage<V, T>`](FixedStorage) or
/// `VecStorage`), `M` the [`Material`]. Built by [`from_box`](Self::from_box),
/// [`from_arrays`](Self::from_arrays) or (feature `std`) `from_tetgen`; then
/// [`step`](Self::step) with the [`Solver`] chosen by [`set_solver`](Self::set_solver)
/// (by default [`Solver::auto`], which picks the explicit stepper or Newton's method each
/// frame).
///
/// * Pinned vertices ([`set_pinned`](Self::set_pinned)) keep their position and velocity.
/// * A kinematic vertex ([`set_target`](Self::set_target)) is pinned and moved to its target at
///   the start of every step, with the velocity `(target - x) / dt` that takes it there; the
///   step then sees it at its end-of-step position (the boundary condition of implicit Euler).
/// * A failed step returns the [`StepError`] with positions, velocities and targets as they
///   were before the call, bit for bit.
///
/// One tetrahedron from the caller's arrays, its base pinned and its apex pulled up 1 cm,
/// relaxed by implicit Euler steps:
/// ```
/// use softfem::body::{Body, FixedStorage, Solver};
/// use softfem::{glam::Vec3, material::NeoHookean};
///
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z].map(|x| x * 0.1); // m
/// let rubber = NeoHookean::from_young_poisson(1.0e6, 0.3)?; // Pa
/// let mut body = Body::<FixedStorage<4, 1>, _>::from_arrays(&rest, &[[0, 1, 2, 3]], 1100.0, rubber)?;
/// body.set_solver(Solver::relax())?;
/// (0..3).try_for_each(|vertex| body.set_pinned(vertex, true))?;
/// body.set_target(3, rest[3] + Vec3::new(0.0, 0.0, 0.01))?; // the apex follows its target
/// for _ in 0..10 {
///     body.step(0.01)?;
/// }
/// assert_eq!(body.positions()[3], body.target(3).unwrap()); // rest[3] + 1 cm, exactly
/// assert_eq!(&body.positions()[..3], &rest[..3]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Body<S: Storage, M: Material> {
    rest_positions: S::Vectors,
    tets: S::Tets,
    rest_data: S::Rests,
    /// The rest data in blocks of 16 (empty where the storage cannot hold them).
    rest_blocks: S::RestBlocks,
    /// From the validating [`TetMesh::new`], for the views rebuilt every step.
    gradient_gain: Real,
    masses: S::Reals,
    pinned: S::Flags,
    /// Which pinned vertices move to `targets` at each step.
    kinematic: S::Flags,
    targets: S::Vectors,
    /// The kinematic vertices' velocities before the step, restored if it fails.
    held_velocities: S::Vectors,
    positions: S::Vectors,
    velocities: S::Vectors,
    /// Vector scratch of the solvers and of a coupled step (13 vectors per vertex).
    vectors: S::Scratch,
    /// The relaxation's preconditioner stiffness, or the stable step's stiffness buffer.
    scalars: S::Reals,
    blocks: S::Blocks,
    hessians: S::Hessians,
    indices: S::Indices,
    /// Vertex Block Descent's packed layout (empty where the storage cannot hold it) and
    /// whether it is built for `topology`.
    layout_values: S::LayoutValues,
    layout_corners: S::LayoutCorners,
    layout_built: Option<bool>,
    material: M,
    solver: Solver,
    coupling: CouplingSettings,
    gravity: Vec3,
    ground: Option<HalfSpace<Vec3>>,
    explicit_memory: ExplicitMemory,
    preconditioner_ready: bool,
    topology: VbdTopology,
    stable_step: Option<Real>,
}

/// The literal of a [`Body`] with no vertices, no tetrahedra and no history: `$material`, the
/// automatic solver, no gravity or ground, every buffer `$buffer(zero)` for the zero of its
/// entries (`Fixed::filled` in the `const` [`Body::empty`], [`no_entries`] for any storage).
macro_rules! unbuilt_body {
    ($material:expr, $buffer:path) => {
        Body {
            rest_positions: $buffer(Vec3::ZERO),
            tets: $buffer([0; 4]),
            rest_data: $buffer(TetRest::ZERO),
            rest_blocks: $buffer(TetRestBlock::ZERO),
            gradient_gain: 0.0,
            masses: $buffer(0.0),
            pinned: $buffer(false),
            kinematic: $buffer(false),
            targets: $buffer(Vec3::ZERO),
            held_velocities: $buffer(Vec3::ZERO),
            positions: $buffer(Vec3::ZERO),
            velocities: $buffer(Vec3::ZERO),
            vectors: $buffer(Vec3::ZERO),
            scalars: $buffer(0.0),
            blocks: $buffer(Mat3::ZERO),
            hessians: $buffer(TetHessian::ZERO),
            indices: $buffer(0),
            layout_values: $buffer(0.0),
            layout_corners: $buffer(0),
            layout_built: None,
            material: $material,
            solver: Solver::auto(),
            coupling: CouplingSettings::DEFAULT,
            gravity: Vec3::ZERO,
            ground: None,
            explicit_memory: ExplicitMemory::FRESH,
            preconditioner_ready: false,
            topology: None,
            stable_step: None,
        }
    };
}

/// An empty buffer of any storage: `unbuilt_body!`'s buffer for [`Body::unbuilt`] (`_zero`
/// names the entry type only).
fn no_entries<X: Copy, B: Slots<X>>(_zero: X) -> B {
    B::empty()
}

impl<S: Storage, M: Material> Body<S, M> {
    /// A box `[min, max]` (m) of `cells[0] x cells[1] x cells[2]` cubes, five tetrahedra each
    /// ([`BoxSplit::Alternating5`]), of `material` with `density` (kg/m^3), at rest at its rest
    /// shape, nothing pinned, no gravity or ground, the automatic [`Solver::auto`].
    ///
    /// # Errors
    /// [`BodyError::Generate`] for the box (see [`fill_box`]), [`BodyError::Capacity`] if the
    /// storage cannot hold it, [`BodyError::Mesh`] for the density.
    pub fn from_box(
        min: Vec3,
        max: Vec3,
        cells: [usize; 3],
        density: Real,
        material: M,
    ) -> Result<Self, BodyError> {
        Self::from_box_split(min, max, cells, BoxSplit::Alternating5, density, material)
    }

    /// As [`from_box`](Self::from_box), each cube split by `split`.
    ///
    /// # Errors
    /// As [`from_box`](Self::from_box).
    pub fn from_box_split(
        min: Vec3,
        max: Vec3,
        cells: [usize; 3],
        split: BoxSplit,
        density: Real,
        material: M,
    ) -> Result<Self, BodyError> {
        let mut body = Self::unbuilt(material);
        body.rebuild_from_box_split(min, max, cells, split, density)?;
        Ok(body)
    }

    /// A body of the caller's rest positions (m) and tetrahedra (positively oriented: see
    /// [`fix_orientation`](super::element::fix_orientation)), otherwise as [`from_box`](Self::from_box).
    ///
    /// # Errors
    /// [`BodyError::Capacity`] if the storage cannot hold it; [`BodyError::Mesh`] for the mesh
    /// ([`TetMesh::new`]) or the density; [`BodyError::UnusedVertex`] for the first vertex in
    /// no tetrahedron (it would have no mass).
    pub fn from_arrays(
        rest_positions: &[Vec3],
        tets: &[[u32; 4]],
        density: Real,
        material: M,
    ) -> Result<Self, BodyError> {
        let mut body = Self::unbuilt(material);
        body.rebuild_from_arrays(rest_positions, tets, density)?;
        Ok(body)
    }

    /// A body of a TetGen mesh, each negatively oriented tetrahedron flipped
    /// ([`fix_orientation`](super::element::fix_orientation); TetGen files may hold either orientation), otherwise as
    /// [`from_arrays`](Self::from_arrays).
    ///
    /// # Errors
    /// As [`from_arrays`](Self::from_arrays).
    #[cfg(feature = "std")]
    #[cfg_attr(docsrs, doc(cfg(feature = "std")))]
    pub fn from_tetgen(
        mesh: &super::asset::tetgen::TetgenMesh,
        density: Real,
        material: M,
    ) -> Result<Self, BodyError> {
        let mut body = Self::unbuilt(material);
        body.reshape(mesh.positions.len(), mesh.tets.len())?;
        copy_into(body.rest_positions.slice_mut(), &mesh.positions);
        for (slot, &tet) in body.tets.slice_mut().iter_mut().zip(&mesh.tets) {
            let corner = |i: u32| mesh.positions.get(i as usize).copied();
            *slot = match tet.map(corner) {
                [Some(a), Some(b), Some(c), Some(d)] => {
                    super::element::fix_orientation(tet, [a, b, c, d])
                }
                // Out of range: left for the validation to name.
                _ => tet,
            };
        }
        body.validate(density)?;
        Ok(body)
    }

    /// Rebuilds the body in place as the box of [`from_box`](Self::from_box): no second
    /// body on the stack, which matters for a large fixed-capacity body (see
    /// [`Body::empty`]). The material, the solver, gravity and the ground are kept; the
    /// geometry, the state (at rest at the rest shape), the pins, the targets and the
    /// solvers' history are replaced.
    ///
    /// # Errors
    /// As [`from_box`](Self::from_box); the body is then left with no vertices and no
    /// tetrahedra (stepping it is [`StepError::EmptyBody`]) until rebuilt.
    pub fn rebuild_from_box(
        &mut self,
        min: Vec3,
        max: Vec3,
        cells: [usize; 3],
        density: Real,
    ) -> Result<(), BodyError> {
        self.rebuild_from_box_split(min, max, cells, BoxSplit::Alternating5, density)
    }

    /// As [`rebuild_from_box`](Self::rebuild_from_box), each cube split by `split`.
    ///
    /// # Errors
    /// As [`rebuild_from_box`](Self::rebuild_from_box).
    pub fn rebuild_from_box_split(
        &mut self,
        min: Vec3,
        max: Vec3,
        cells: [usize; 3],
        split: BoxSplit,
        density: Real,
    ) -> Result<(), BodyError> {
        let built = self.fill_from_box((min, max), cells, split, density);
        self.emptied_on_error(built)
    }

    /// Rebuilds the body in place from the caller's rest positions (m) and tetrahedra, as
    /// [`from_arrays`](Self::from_arrays) builds a new one; what is kept and replaced is as
    /// in [`rebuild_from_box`](Self::rebuild_from_box).
    ///
    /// # Errors
    /// As [`from_arrays`](Self::from_arrays); the body is then left with no vertices and no
    /// tetrahedra until rebuilt.
    pub fn rebuild_from_arrays(
        &mut self,
        rest_positions: &[Vec3],
        tets: &[[u32; 4]],
        density: Real,
    ) -> Result<(), BodyError> {
        let built = self.fill_from_arrays(rest_positions, tets, density);
        self.emptied_on_error(built)
    }

    /// The box between the corners `(min, max)` (m), as [`rebuild_from_box_split`] takes it.
    ///
    /// [`rebuild_from_box_split`]: Self::rebuild_from_box_split
    fn fill_from_box(
        &mut self,
        (min, max): (Vec3, Vec3),
        cells: [usize; 3],
        split: BoxSplit,
        density: Real,
    ) -> Result<(), BodyError> {
        let [nx, ny, nz] = cells;
        let (vertices, tets) = box_counts(nx, ny, nz, split)?;
        self.reshape(vertices, tets)?;
        fill_box(
            min,
            max,
            nx,
            ny,
            nz,
            split,
            self.rest_positions.slice_mut(),
            self.tets.slice_mut(),
        )?;
        self.validate(density)
    }

    fn fill_from_arrays(
        &mut self,
        rest_positions: &[Vec3],
        tets: &[[u32; 4]],
        density: Real,
    ) -> Result<(), BodyError> {
        self.reshape(rest_positions.len(), tets.len())?;
        copy_into(self.rest_positions.slice_mut(), rest_positions);
        copy_into(self.tets.slice_mut(), tets);
        self.validate(density)
    }

    /// Empties the body if `built` failed, so that no half-built geometry is ever stepped.
    fn emptied_on_error(&mut self, built: Result<(), BodyError>) -> Result<(), BodyError> {
        if built.is_err() {
            // Length zero always fits.
            let _ = self.reshape(0, 0);
        }
        built
    }

    /// A body with no vertices and no tetrahedra, the automatic solver, no gravity or ground.
    fn unbuilt(material: M) -> Self {
        unbuilt_body!(material, no_entries)
    }

    /// Sets every buffer to `vertices` and `tets` zeroed entries (unvalidated) and forgets the
    /// solvers' history; sizes the scratch of the current solver.
    fn reshape(&mut self, vertices: usize, tets: usize) -> Result<(), BodyError> {
        self.gradient_gain = 0.0;
        self.explicit_memory = ExplicitMemory::FRESH;
        self.preconditioner_ready = false;
        self.topology = None;
        self.layout_built = None;
        self.stable_step = None;
        let fits = self.rest_positions.resize(vertices, Vec3::ZERO)
            && self.masses.resize(vertices, 0.0)
            && self.pinned.resize(vertices, false)
            && self.kinematic.resize(vertices, false)
            && self.targets.resize(vertices, Vec3::ZERO)
            && self.held_velocities.resize(vertices, Vec3::ZERO)
            && self.positions.resize(vertices, Vec3::ZERO)
            && self.velocities.resize(vertices, Vec3::ZERO)
            && self.scalars.resize(vertices, 0.0);
        capacity(fits, BodyBuffer::Vertices, vertices)?;
        let fits =
            self.tets.resize(tets, [0; 4]) && self.rest_data.resize(tets, TetRest::default());
        capacity(fits, BodyBuffer::Tetrahedra, tets)?;
        // The blocks where the storage holds them; without them the passes transpose (the same
        // bits).
        if !self
            .rest_blocks
            .resize(rest_block_count(tets), TetRestBlock::ZERO)
        {
            // An empty buffer always fits.
            let _ = self.rest_blocks.resize(0, TetRestBlock::ZERO);
        }
        let solver = self.solver;
        self.size_scratch(&solver)
    }

    /// Validates the mesh once ([`TetMesh::new`]) and computes the masses; a vertex in no
    /// tetrahedron (mass zero) is refused.
    fn validate(&mut self, density: Real) -> Result<(), BodyError> {
        let mesh = TetMesh::new(
            self.rest_positions.slice(),
            self.tets.slice(),
            self.rest_data.slice_mut(),
        )?;
        mesh.lumped_masses(density, self.masses.slice_mut())?;
        // Every tetrahedron's share of the mass is a positive normal number (`lumped_masses`
        // checks it), so a vertex has mass zero exactly when no tetrahedron uses it.
        if let Some(vertex) = self.masses.slice().iter().position(|&mass| mass <= 0.0) {
            return Err(BodyError::UnusedVertex { vertex });
        }
        self.gradient_gain = mesh.gradient_gain();
        if !self.rest_blocks.slice().is_empty() {
            mesh.with_rest_blocks(self.rest_blocks.slice_mut())?;
        }
        copy_into(self.positions.slice_mut(), self.rest_positions.slice());
        Ok(())
    }

    /// Sizes the scratch `solver` needs. The buffers of the solver in use are left as they
    /// were if this fails: Newton's and VBD's own buffers come first, and the shared vector
    /// scratch, last, is unchanged when it does not fit.
    fn size_scratch(&mut self, solver: &Solver) -> Result<(), BodyError> {
        let (n, t) = (self.vertex_count(), self.tet_count());
        // The automatic solver holds Newton's buffers from the start: a fallback in the middle
        // of a frame cannot stop to grow them.
        if let Solver::Newton(_) | Solver::Auto(_) = solver {
            let fits = self.blocks.resize(n, super::types::Mat3::ZERO)
                && self.hessians.resize(t, Default::default());
            capacity(fits, BodyBuffer::Tetrahedra, t)?;
        }
        if let Solver::Vbd(_) = solver {
            let needed = super::step::scratch_len::vbd_indices(n, t);
            capacity(
                self.indices.resize(needed, 0),
                BodyBuffer::IndexScratch,
                needed,
            )?;
            // The packed layout where the storage holds it; without it the sweeps gather (the
            // same bits).
            let (values, corners) = (
                scratch_len::vbd_layout(t),
                scratch_len::vbd_layout_corners(n, t),
            );
            if !(self.layout_values.resize(values, 0.0) && self.layout_corners.resize(corners, 0)) {
                // Empty buffers always fit.
                let _ = self.layout_values.resize(0, 0.0) && self.layout_corners.resize(0, 0);
            }
            self.layout_built = None;
        }
        // Every solver's scratch has the automatic solver's eleven vectors per vertex and two
        // more: the explicit stepper uses four, the relaxation and VBD five, Newton's method
        // nine, a step recorded for reactions keeps its impulses and start velocities in the
        // tenth and eleventh (see `recording_slots`), and a coupled step its start in the last
        // two (`coupling_slots`).
        let _ = solver;
        let needed = n.saturating_mul(BODY_VECTORS);
        capacity(
            self.vectors.resize(needed, Vec3::ZERO),
            BodyBuffer::Scratch,
            needed,
        )
    }

    /// The number of vertices.
    #[inline]
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.positions.slice().len()
    }

    /// The number of tetrahedra.
    #[inline]
    #[must_use]
    pub fn tet_count(&self) -> usize {
        self.tets.slice().len()
    }

    /// The validated mesh over the body's own buffers, for the low-level kernels (energies,
    /// stresses). Built without validating again.
    #[inline]
    #[must_use]
    pub fn mesh(&self) -> TetMesh<'_> {
        mesh_over(
            self.tets.slice(),
            self.rest_data.slice(),
            self.rest_blocks.slice(),
            self.gradient_gain,
            self.vertex_count(),
        )
    }

    /// The rest positions (m).
    #[inline]
    #[must_use]
    pub fn rest_positions(&self) -> &[Vec3] {
        self.rest_positions.slice()
    }

    /// The tetrahedra's vertex indices.
    #[inline]
    #[must_use]
    pub fn tets(&self) -> &[[u32; 4]] {
        self.tets.slice()
    }

    /// The lumped masses (kg), one per vertex.
    #[inline]
    #[must_use]
    pub fn masses(&self) -> &[Real] {
        self.masses.slice()
    }

    /// The positions (m), one per vertex.
    #[inline]
    #[must_use]
    pub fn positions(&self) -> &[Vec3] {
        self.positions.slice()
    }

    /// The positions (m), writable. Forgets the explicit stepper's blow-up history
    /// ([`forget_history`](Self::forget_history)), so that a teleport is not taken for a
    /// blow-up. A non-finite entry makes the next step fail with
    /// [`StepError::NonFiniteInput`]; a kinematic vertex goes back to its target at the next
    /// step.
    #[inline]
    #[must_use]
    pub fn positions_mut(&mut self) -> &mut [Vec3] {
        self.forget_history();
        self.positions.slice_mut()
    }

    /// The velocities (m/s), one per vertex.
    #[inline]
    #[must_use]
    pub fn velocities(&self) -> &[Vec3] {
        self.velocities.slice()
    }

    /// The velocities (m/s), writable; forgets the blow-up history as
    /// [`positions_mut`](Self::positions_mut).
    #[inline]
    #[must_use]
    pub fn velocities_mut(&mut self) -> &mut [Vec3] {
        self.forget_history();
        self.velocities.slice_mut()
    }

    /// The pinned flags, one per vertex (kinematic vertices are pinned).
    #[inline]
    #[must_use]
    pub fn pinned(&self) -> &[bool] {
        self.pinned.slice()
    }

    /// Pins (`true`) or frees `vertex`. Freeing also drops its target.
    ///
    /// # Errors
    /// [`BodyError::Vertex`] if `vertex` is not below [`vertex_count`](Self::vertex_count).
    pub fn set_pinned(&mut self, vertex: usize, pinned: bool) -> Result<(), BodyError> {
        let flag = self
            .pinned
            .slice_mut()
            .get_mut(vertex)
            .ok_or(BodyError::Vertex { vertex })?;
        if *flag != pinned {
            *flag = pinned;
            // The stable step is taken over the free vertices.
            self.stable_step = None;
        }
        if !pinned && let Some(kinematic) = self.kinematic.slice_mut().get_mut(vertex) {
            *kinematic = false;
        }
        Ok(())
    }

    /// Makes `vertex` kinematic: pinned, and moved to `target` (m) at the start of every step
    /// until the target changes or is cleared.
    ///
    /// # Errors
    /// [`BodyError::Vertex`] if `vertex` is not below [`vertex_count`](Self::vertex_count) or
    /// `target` is not finite.
    pub fn set_target(&mut self, vertex: usize, target: Vec3) -> Result<(), BodyError> {
        let slot = self.targets.slice_mut().get_mut(vertex);
        match slot {
            Some(slot) if target.is_finite() => *slot = target,
            _ => return Err(BodyError::Vertex { vertex }),
        }
        if let Some(kinematic) = self.kinematic.slice_mut().get_mut(vertex) {
            *kinematic = true;
        }
        self.set_pinned(vertex, true)
    }

    /// The target of a kinematic `vertex` (m); `None` if it has none or is out of range.
    #[inline]
    #[must_use]
    pub fn target(&self, vertex: usize) -> Option<Vec3> {
        match self.kinematic.slice().get(vertex) {
            Some(true) => self.targets.slice().get(vertex).copied(),
            _ => None,
        }
    }

    /// Drops the target of `vertex`: it stays pinned where it is (free it with
    /// [`set_pinned`](Self::set_pinned)).
    ///
    /// # Errors
    /// [`BodyError::Vertex`] if `vertex` is not below [`vertex_count`](Self::vertex_count).
    pub fn clear_target(&mut self, vertex: usize) -> Result<(), BodyError> {
        let kinematic = self
            .kinematic
            .slice_mut()
            .get_mut(vertex)
            .ok_or(BodyError::Vertex { vertex })?;
        *kinematic = false;
        Ok(())
    }

    /// The gravitational acceleration (m/s^2).
    #[inline]
    #[must_use]
    pub fn gravity(&self) -> Vec3 {
        self.gravity
    }

    /// Sets the gravitational acceleration (m/s^2), e.g. `(0, -9.81, 0)`; checked by the step.
    #[inline]
    pub fn set_gravity(&mut self, gravity: Vec3) {
        self.gravity = gravity;
    }

    /// The ground half-space, if any.
    #[inline]
    #[must_use]
    pub fn ground(&self) -> Option<HalfSpace<Vec3>> {
        self.ground
    }

    /// Sets (or, with `None`, removes) the ground half-space; checked by the step.
    #[inline]
    pub fn set_ground(&mut self, ground: Option<HalfSpace<Vec3>>) {
        self.ground = ground;
    }

    /// The material.
    #[inline]
    #[must_use]
    pub fn material(&self) -> &M {
        &self.material
    }

    /// Replaces the material; the stable step and the relaxation's preconditioner are computed
    /// again at the next step that needs them.
    #[inline]
    pub fn set_material(&mut self, material: M) {
        self.material = material;
        self.stable_step = None;
        self.preconditioner_ready = false;
    }

    /// The solver and its settings.
    #[inline]
    #[must_use]
    pub fn solver(&self) -> &Solver {
        &self.solver
    }

    /// Chooses the solver and its settings. Changing only the settings keeps what the solver
    /// remembers; changing the solver sizes its scratch and starts it afresh.
    ///
    /// # Errors
    /// [`BodyError::StableFraction`] for an explicit `stable_fraction` that is not finite and in
    /// `(0, 1]`; [`BodyError::Capacity`] if the storage cannot hold the new solver's scratch (the
    /// body keeps its solver in both cases).
    pub fn set_solver(&mut self, solver: Solver) -> Result<(), BodyError> {
        solver.check()?;
        if !solver.same_kind(&self.solver) {
            self.size_scratch(&solver)?;
            self.forget_history();
            self.preconditioner_ready = false;
            self.topology = None;
            self.layout_built = None;
        }
        self.solver = solver;
        Ok(())
    }

    /// Forgets the explicit stepper's blow-up history: the next step is not compared with the
    /// ones before (see [`ExplicitScratch::forget_history`]).
    #[inline]
    pub fn forget_history(&mut self) {
        self.explicit_memory = ExplicitMemory::FRESH;
    }

    /// The stable explicit time step (s) of the body at rest ([`stable_time_step`] over the
    /// free vertices), computed once and cached until the pins or the material change.
    ///
    /// # Errors
    /// [`StepError::EmptyBody`] for a body with no vertices, otherwise as [`stable_time_step`].
    pub fn stable_time_step(&mut self) -> Result<Real, StepError> {
        if let Some(dt) = self.stable_step {
            return Ok(dt);
        }
        if self.vertex_count() == 0 {
            return Err(StepError::EmptyBody);
        }
        let mesh = mesh_over(
            self.tets.slice(),
            self.rest_data.slice(),
            self.rest_blocks.slice(),
            self.gradient_gain,
            self.vertex_count(),
        );
        let model = TetElastic::new(mesh, self.material);
        let dt = stable_time_step(
            &model,
            self.masses.slice(),
            self.pinned.slice(),
            self.scalars.slice_mut(),
        )?;
        // The buffer it used holds the relaxation's preconditioner otherwise.
        self.preconditioner_ready = false;
        self.stable_step = Some(dt);
        Ok(dt)
    }

    /// The scene of a step of `dt` (s) under the body's gravity and ground: what
    /// [`step`](Self::step) runs, and where [`step_with`](Self::step_with) starts from to add
    /// colliders, external forces or fixed axes for one step.
    #[inline]
    #[must_use]
    pub fn scene(&self, dt: Real) -> Scene<'static, Vec3> {
        let scene = Scene::new(dt).with_gravity(self.gravity);
        match self.ground {
            Some(ground) => scene.with_ground(ground),
            None => scene,
        }
    }

    /// Advances the body by `dt` (s) with its [`Solver`] under its gravity and ground:
    /// [`step_with`](Self::step_with) of [`scene`](Self::scene)`(dt)`.
    ///
    /// # Errors
    /// As [`step_with`](Self::step_with).
    pub fn step(&mut self, dt: Real) -> Result<StepReport, StepError> {
        self.step_with(&self.scene(dt))
    }

    /// [`step`](Self::step) with rigid `colliders` besides the ground (see [`Collider`]): the
    /// step sees each where it is; move kinematic ones between accepted steps with
    /// [`Collider::advanced`] (or let
    /// [`step_with_moving_colliders`](Self::step_with_moving_colliders) do it): after a refused
    /// step the body is where it was, and so must they be.
    ///
    /// ```
    /// use softfem::body::{Body, FixedStorage};
    /// use softfem::{glam::Vec3, material::StableNeoHookean, step::Collider};
    ///
    /// let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.45)?; // Pa
    /// let (low, high) = (Vec3::new(-0.1, 0.5, -0.1), Vec3::new(0.1, 0.7, 0.1)); // m
    /// let mut body = Body::<FixedStorage<27, 40>, _>::from_box(low, high, [2; 3], 1000.0, jelly)?;
    /// body.set_gravity(Vec3::new(0.0, -9.81, 0.0));
    /// let ball = [Collider::sphere(Vec3::ZERO, 0.4).with_friction(0.5)]; // 0.4 m under the box
    /// for _ in 0..60 {
    ///     body.step_with_colliders(1.0 / 60.0, &ball)?;
    /// }
    /// assert!(body.positions().iter().all(|&x| ball[0].distance(x) > -1e-3)); // on it, not in it
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`step_with`](Self::step_with).
    pub fn step_with_colliders(
        &mut self,
        dt: Real,
        colliders: &[Collider<'_>],
    ) -> Result<StepReport, StepError> {
        self.step_with(&self.scene(dt).with_colliders(colliders))
    }

    /// [`step_with_colliders`](Self::step_with_colliders), then, if the step was accepted, each
    /// collider [`advanced`](Collider::advanced) by `dt`: the step sees each collider where it
    /// is, and a kinematic one moves on only with the body.
    ///
    /// A refused step leaves the body's state as it was before the call (every error restores
    /// it bit for bit) and so the colliders must stay too: advanced regardless, a fast one
    /// would move into the vertices the failed step left behind (a 0.05 m ball at 20 m/s, 3 cm
    /// deep after one frame), and the next step would meet it as a jump. Here a refused step
    /// leaves the colliders untouched, no vertex inside one (within the rounding of the last
    /// accepted projection), ready to retry with a smaller step
    /// (`tests/steppers/explicit_colliders.rs`).
    ///
    /// # Errors
    /// As [`step_with`](Self::step_with); the colliders are then left as they were.
    pub fn step_with_moving_colliders(
        &mut self,
        dt: Real,
        colliders: &mut [Collider<'_>],
    ) -> Result<StepReport, StepError> {
        let report = self.step_with_colliders(dt, colliders)?;
        for collider in colliders.iter_mut() {
            *collider = collider.advanced(dt);
        }
        Ok(report)
    }

    /// Advances the body by the scene's `dt` with its [`Solver`] in `scene`: kinematic vertices
    /// are moved to their targets, then one call of the solver's stepper. The scene replaces
    /// the body's gravity and ground for this step, and brings whatever else the step should
    /// see, borrowed for this call only: colliders, external forces (N, one per vertex), fixed
    /// axes, previous velocities.
    ///
    /// ```
    /// use softfem::body::{Body, FixedStorage, Solver};
    /// use softfem::{glam::Vec3, material::StableNeoHookean};
    ///
    /// let rubber = StableNeoHookean::from_young_poisson(1.0e6, 0.45)?; // Pa
    /// let (low, high) = (Vec3::ZERO, Vec3::new(0.4, 0.1, 0.1)); // m
    /// let mut body = Body::<FixedStorage<81, 160>, _>::from_box(low, high, [8, 2, 2], 1000.0, rubber)?;
    /// body.set_solver(Solver::newton())?;
    /// for (i, x) in body.rest_positions().to_vec().iter().enumerate() {
    ///     body.set_pinned(i, x.x == 0.0)?; // clamp the end x = 0
    /// }
    /// // A tip load of 5 N in -y, spread over the vertices of the free end.
    /// let tip: Vec<bool> = body.rest_positions().iter().map(|x| x.x > 0.39).collect();
    /// let share = 5.0 / tip.iter().filter(|&&t| t).count() as f32;
    /// let forces: Vec<Vec3> = tip.iter().map(|&t| if t { -Vec3::Y * share } else { Vec3::ZERO }).collect();
    /// for _ in 0..30 {
    ///     body.step_with(&body.scene(1.0 / 60.0).with_external_forces(&forces))?;
    /// }
    /// let sag = body.positions().iter().zip(body.rest_positions()).zip(&tip);
    /// assert!(sag.filter(|(_, t)| **t).all(|((x, r), _)| x.y < r.y - 5e-3)); // the tip went down
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`StepError::TimeStep`] if the scene's `dt` is not finite and positive,
    /// [`StepError::TimeStepTooSmall`] if its `1 / dt^2` overflows (as every stepper),
    /// [`StepError::EmptyBody`] if the body has no vertices (never built, or its last rebuild
    /// failed), [`StepError::Substeps`] if the explicit solver's `stable_fraction` is not
    /// positive or asks for more than [`MAX_SUBSTEPS`](super::step::ExplicitSettings::MAX_SUBSTEPS)
    /// substeps (nothing touched in these cases), or the stepper's error (a scene out of range
    /// included), with positions, velocities and targets restored bit for bit. The automatic
    /// solver returns an error only where its fallbacks could not take the frame: an explicit
    /// error that is not a blow-up, or Newton's method's error.
    pub fn step_with(&mut self, scene: &Scene<'_, Vec3>) -> Result<StepReport, StepError> {
        self.step_recording(scene, None)
    }

    /// [`step_with`](Self::step_with), and what each of the scene's colliders received from the
    /// body over the step into `reactions` (one per collider, in the scene's order; see
    /// [`Reaction`]): the impulse on the collider and its moment about the collider's position,
    /// for a host engine that owns the colliders as rigid bodies and applies the reaction to
    /// them (`docs/math.md` section 8.14, with the stability condition of that staggered
    /// coupling). Every solver reports it: the explicit stepper sums the impulses of its
    /// collider projections over the substeps; after an implicit step each touching vertex's
    /// momentum balance gives its impulse (one more force pass). The automatic solver's
    /// fallback to two half steps reports the balance of the whole frame with the forces at
    /// its end (first order in the step). The ground's reaction is not reported: pass the
    /// ground as a half-space [`Collider`] to get it.
    ///
    /// ```
    /// use softfem::body::{Body, FixedStorage, Solver};
    /// use softfem::step::{Collider, Reaction};
    /// use softfem::{glam::Vec3, material::StableNeoHookean};
    ///
    /// let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.45)?; // Pa
    /// let (low, high) = (Vec3::new(-0.1, 0.0, -0.1), Vec3::new(0.1, 0.2, 0.1)); // m
    /// let mut body = Body::<FixedStorage<27, 40>, _>::from_box(low, high, [2; 3], 1000.0, jelly)?;
    /// body.set_solver(Solver::newton())?;
    /// let floor = [Collider::half_space(Vec3::ZERO, Vec3::Y)];
    /// let mut reactions = [Reaction::ZERO];
    /// for _ in 0..120 {
    ///     let scene = body.scene(1.0 / 60.0).with_gravity(Vec3::new(0.0, -9.81, 0.0));
    ///     body.step_with_reactions(&scene.with_colliders(&floor), &mut reactions)?;
    /// }
    /// // At rest the floor carries the weight: 8 kg, 78.5 N down.
    /// let weight = body.masses().iter().sum::<f32>() * 9.81;
    /// assert!((reactions[0].force(1.0 / 60.0).y + weight).abs() < 0.01 * weight);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`StepError::LengthMismatch`] (buffer [`StepBuffer::Reactions`])
    /// unless `reactions` has one entry per collider, before anything is touched; otherwise as
    /// [`step_with`](Self::step_with), `reactions` then unspecified.
    pub fn step_with_reactions(
        &mut self,
        scene: &Scene<'_, Vec3>,
        reactions: &mut [Reaction],
    ) -> Result<StepReport, StepError> {
        check_length(
            StepBuffer::Reactions,
            scene.colliders.len(),
            reactions.len(),
        )?;
        self.step_recording(scene, Some(reactions))
    }

    /// One step of `scene` with the dynamic colliders among `colliders` (those given a mass,
    /// [`Collider::with_mass`]) solved with the body: a crate resting on the body, a body
    /// squeezed between two plates, a ball thrown at it (`docs/math.md` section 8.15). Each
    /// dynamic collider's end-of-step velocity is an unknown of the same implicit Euler step:
    /// the body steps with the collider at the pose that velocity gives it, the collider's
    /// momentum balance with the impulse the body applied gives its velocity again, and the
    /// two are iterated (with Aitken's relaxation) until they agree within the body's
    /// [`coupling`](Self::coupling) tolerance. Unlike the staggered coupling of
    /// [`step_with_reactions`](Self::step_with_reactions), it is stable whatever the masses,
    /// stiffness and step. Each iteration is one step of the body's solver from the same
    /// start (the report counts them); a collider that does not touch the body costs none
    /// beyond the first.
    ///
    /// On return every dynamic collider has its new pose and velocities (its `position` is its
    /// centre of mass), and `reactions` what every collider received over the step, as in
    /// [`step_with_reactions`](Self::step_with_reactions). Static and kinematic colliders are
    /// not changed: advance kinematic ones between steps yourself. The scene's own colliders
    /// must be empty: every collider goes in `colliders`. Contact between colliders is not
    /// solved (a host engine's job); gravity is the scene's.
    ///
    /// ```
    /// use softfem::body::{Body, FixedStorage, Solver};
    /// use softfem::step::{Collider, HalfSpace, Reaction};
    /// use softfem::{glam::{Quat, Vec3}, material::StableNeoHookean};
    ///
    /// let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.45)?; // Pa
    /// let (low, high) = (Vec3::new(-0.1, 0.0, -0.1), Vec3::new(0.1, 0.2, 0.1)); // m
    /// let mut body = Body::<FixedStorage<27, 40>, _>::from_box(low, high, [2; 3], 1000.0, jelly)?;
    /// body.set_solver(Solver::newton())?;
    /// body.set_ground(Some(HalfSpace::new(Vec3::Y, 0.0)));
    /// // A 2 kg lid of 30 x 10 x 30 cm with friction, dropped onto the jelly from 1 cm above.
    /// let half = Vec3::new(0.15, 0.05, 0.15);
    /// let inertia = Vec3::new(0.017, 0.03, 0.017); // kg m^2: m/3 (b^2 + c^2), ...
    /// let box_ = Collider::cuboid(Vec3::new(0.0, 0.26, 0.0), half, Quat::IDENTITY)
    ///     .with_mass(2.0, inertia)
    ///     .with_friction(0.5);
    /// let mut colliders = [box_];
    /// let mut reactions = [Reaction::ZERO];
    /// let g = Vec3::new(0.0, -9.81, 0.0);
    /// for _ in 0..120 {
    ///     let scene = body.scene(1.0 / 60.0).with_gravity(g);
    ///     let report = body.step_with_rigid_bodies(&scene, &mut colliders, &mut reactions)?;
    ///     assert!(report.coupling.iterations <= 30);
    /// }
    /// // At rest the box pushes on the jelly with its weight, 19.6 N.
    /// assert!((reactions[0].force(1.0 / 60.0).y - 2.0 * 9.81).abs() < 0.02 * 2.0 * 9.81);
    /// assert!(colliders[0].linear_velocity.length() < 1e-2);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// Before anything is moved: [`StepError::SceneColliders`] if the scene has colliders,
    /// [`StepError::LengthMismatch`] (buffer [`StepBuffer::Reactions`]) unless `reactions`
    /// has one entry per collider, [`StepError::Collider`] for a collider out of range,
    /// [`StepError::TooManyDynamicColliders`] beyond
    /// [`MAX_DYNAMIC_COLLIDERS`](super::step::MAX_DYNAMIC_COLLIDERS), and the errors of
    /// [`step_with`](Self::step_with)'s checks. A soft step that fails returns its error with
    /// the body's state and every collider as they were before the call.
    pub fn step_with_rigid_bodies(
        &mut self,
        scene: &Scene<'_, Vec3>,
        colliders: &mut [Collider<'_>],
        reactions: &mut [Reaction],
    ) -> Result<CoupledReport, StepError> {
        self.step_with_rigid_bodies_and_attachments(scene, colliders, &[], reactions)
    }

    /// [`step_with_rigid_bodies`](Self::step_with_rigid_bodies) with body vertices held at
    /// points of the colliders' frames (hard attachments: a jelly hanging from a crate, a
    /// lamp, a gripper). Each attached vertex is made kinematic
    /// ([`set_target`](Self::set_target)) with its target on its collider at the step's end:
    /// a dynamic collider's solved pose, any other collider's pose moved over the step by its
    /// velocities. What held the vertex there joins the collider's reaction, so a dynamic
    /// collider carries the body hanging from it; [`last_impulses`](Self::last_impulses) has
    /// each attached vertex's share. The vertices stay kinematic after the step (at their new
    /// positions: free them with [`set_pinned`](Self::set_pinned)); list each vertex once.
    ///
    /// ```
    /// use softfem::body::{Body, FixedStorage, Solver};
    /// use softfem::step::{Attachment, Collider, Reaction};
    /// use softfem::{glam::{Quat, Vec3}, material::StableNeoHookean};
    ///
    /// // Without gravity, a 1 kg box thrown at 1 m/s drags the jelly hanging from it.
    /// let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.45)?; // Pa
    /// let (low, high) = (Vec3::new(-0.1, -0.2, -0.1), Vec3::new(0.1, 0.0, 0.1)); // m
    /// let mut body = Body::<FixedStorage<27, 40>, _>::from_box(low, high, [2; 3], 100.0, jelly)?;
    /// body.set_solver(Solver::newton())?;
    /// let half = Vec3::new(0.1, 0.05, 0.1);
    /// let box_ = Collider::cuboid(Vec3::new(0.0, 0.05, 0.0), half, Quat::IDENTITY)
    ///     .with_mass(1.0, Vec3::new(0.004, 0.007, 0.004))
    ///     .with_velocity(Vec3::X, Vec3::ZERO);
    /// let top: Vec<Attachment> = (0..27u32)
    ///     .filter(|&i| body.positions()[i as usize].y == 0.0)
    ///     .map(|i| Attachment::at(i, 0, &box_, body.positions()[i as usize]))
    ///     .collect();
    /// let (mut colliders, mut reactions) = ([box_], [Reaction::ZERO]);
    /// for _ in 0..30 {
    ///     let scene = body.scene(1.0 / 60.0);
    ///     body.step_with_rigid_bodies_and_attachments(&scene, &mut colliders, &top, &mut reactions)?;
    /// }
    /// // The momentum of box and jelly is what the box brought: 1 kg m/s.
    /// let jelly_momentum: Vec3 = body.velocities().iter().zip(body.masses()).map(|(&v, &m)| v * m).sum();
    /// let total = jelly_momentum + colliders[0].linear_velocity * 1.0;
    /// assert!((total - Vec3::X).length() < 1e-3);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`step_with_rigid_bodies`](Self::step_with_rigid_bodies), and before anything is
    /// moved [`StepError::TooManyAttachments`] beyond
    /// [`MAX_ATTACHMENTS`], [`StepError::AttachedVertex`] or
    /// [`StepError::AttachedCollider`] for an entry out of range. A failed step also puts
    /// back the attached vertices' pins and targets.
    pub fn step_with_rigid_bodies_and_attachments(
        &mut self,
        scene: &Scene<'_, Vec3>,
        colliders: &mut [Collider<'_>],
        attachments: &[Attachment],
        reactions: &mut [Reaction],
    ) -> Result<CoupledReport, StepError> {
        check_coupled_step(scene, colliders, reactions, &self.coupling)?;
        let n = self.vertex_count();
        if n == 0 {
            return Err(StepError::EmptyBody);
        }
        check_attachments(attachments, n, colliders.len())?;
        // The attached vertices' pins and masses before the call, put back if it fails (the
        // masses after every soft step).
        let mut pins: heapless::Vec<(bool, bool, Vec3, Real), MAX_ATTACHMENTS> =
            heapless::Vec::new();
        for a in attachments {
            let v = a.vertex as usize;
            let pin = (
                self.pinned.slice().get(v).copied().unwrap_or(false),
                self.kinematic.slice().get(v).copied().unwrap_or(false),
                self.targets.slice().get(v).copied().unwrap_or(Vec3::ZERO),
                self.masses.slice().get(v).copied().unwrap_or(0.0),
            );
            if pins.push(pin).is_err() {
                return Err(StepError::TooManyAttachments {
                    limit: MAX_ATTACHMENTS,
                });
            }
        }
        // Soft attachments are terms of the implicit objective: the explicit stepper has none,
        // and the automatic solver takes Newton's method for the step.
        let solver = self.solver;
        if attachments.iter().any(Attachment::is_soft) {
            match solver {
                Solver::Explicit { .. } => return Err(StepError::SoftAttachmentSolver),
                Solver::Auto(settings) => self.solver = Solver::Newton(settings.newton),
                _ => {}
            }
        }
        let mass: Real = self.masses.slice().iter().sum();
        let vertex_mass = mass / n as Real;
        // The step's start, for every iteration after the first and for a failure.
        let memory = self.explicit_memory;
        let (start_positions, start_velocities) = coupling_slots(self.vectors.slice_mut(), n);
        copy_into(start_positions, self.positions.slice());
        copy_into(start_velocities, self.velocities.slice());
        let settings = self.coupling;
        let (dt, gravity) = (scene.dt, scene.gravity);
        let soft_step = |colliders: &[Collider<'_>], reactions: &mut [Reaction], iteration| {
            if iteration > 0 {
                self.restore_coupling_start(memory);
            }
            for (entry, a) in attachments.iter().enumerate() {
                let Some(collider) = colliders.get(a.collider as usize) else {
                    continue;
                };
                let v = a.vertex as usize;
                if a.is_soft() {
                    self.pull_softly(a, collider, (dt, gravity));
                } else {
                    // Refused only for a non-finite anchor (the vertex is in range).
                    let target = end_anchor(a, collider, dt);
                    let collider = a.collider;
                    self.set_target(v, target)
                        .map_err(|_| StepError::AttachedCollider { entry, collider })?;
                }
            }
            let stepped = scene.with_colliders(colliders);
            let report = self.step_recording(&stepped, Some(reactions));
            for (a, &(.., mass)) in attachments.iter().zip(&pins) {
                if let Some(m) = self.masses.slice_mut().get_mut(a.vertex as usize) {
                    *m = mass;
                }
            }
            let report = report?;
            // The recorded impulses and the coupled step's start, from one scratch.
            let (head, tail) = self
                .vectors
                .slice_mut()
                .split_at_mut_checked(n.saturating_mul(auto::AUTO_VECTORS))
                .unwrap_or_default();
            let first = n.saturating_mul(RECORDED_IMPULSES);
            let impulses = head.get_mut(first..first.saturating_add(n)).unwrap_or(&mut []);
            let starts = tail.get(..n).unwrap_or(&[]);
            let (x, v) = (self.positions.slice(), self.velocities.slice());
            let state = (x, v, starts, self.pinned.slice());
            add_attachment_reactions(attachments, colliders, state, (impulses, dt), reactions);
            Ok((report, report.coupling_residual()))
        };
        let outcome = couple(
            colliders,
            (dt, gravity),
            &settings,
            vertex_mass,
            reactions,
            soft_step,
        );
        self.solver = solver;
        match outcome {
            Ok((step, coupling)) => Ok(CoupledReport { step, coupling }),
            Err(error) => {
                self.restore_coupling_start(memory);
                for (a, &(pinned, kinematic, target, mass)) in attachments.iter().zip(&pins) {
                    let v = a.vertex as usize;
                    if let (Some(p), Some(k), Some(t), Some(m)) = (
                        self.pinned.slice_mut().get_mut(v),
                        self.kinematic.slice_mut().get_mut(v),
                        self.targets.slice_mut().get_mut(v),
                        self.masses.slice_mut().get_mut(v),
                    ) {
                        (*p, *k, *t, *m) = (pinned, kinematic, target, mass);
                    }
                }
                self.stable_step = None;
                Err(error)
            }
        }
    }

    /// The coupling iteration's settings (see [`step_with_rigid_bodies`](Self::step_with_rigid_bodies)).
    #[inline]
    #[must_use]
    pub fn coupling(&self) -> &CouplingSettings {
        &self.coupling
    }

    /// Sets the coupling iteration's settings; checked by the step
    /// ([`StepError::CouplingSettings`]).
    #[inline]
    pub fn set_coupling(&mut self, settings: CouplingSettings) {
        self.coupling = settings;
    }

    /// Hands the soft attachment `a` to the collider `collider` (as the step sees it) to the
    /// solver for a step of `h` (s) under `gravity`: its vertex's mass and start velocity become
    /// those whose inertia term carries the spring and the damper (`SoftPull::inertia`). A
    /// pinned vertex is left as it is. The caller puts the mass back after the step.
    fn pull_softly(&mut self, a: &Attachment, collider: &Collider<'_>, (h, gravity): (Real, Vec3)) {
        let v = a.vertex as usize;
        if self.pinned.slice().get(v).copied().unwrap_or(true) {
            return;
        }
        let (Some(m), Some(&x_n), Some(velocity)) = (
            self.masses.slice_mut().get_mut(v),
            self.positions.slice().get(v),
            self.velocities.slice_mut().get_mut(v),
        ) else {
            return;
        };
        let pull = SoftPull::new(a, collider, x_n, h);
        (*m, *velocity) = pull.inertia((*m, x_n, *velocity), (h, gravity));
    }

    /// Puts back the positions and velocities kept at the start of a coupled step, and the
    /// explicit stepper's `memory` of then.
    fn restore_coupling_start(&mut self, memory: ExplicitMemory) {
        let n = self.vertex_count();
        let (start_positions, start_velocities) = coupling_slots(self.vectors.slice_mut(), n);
        copy_into(self.positions.slice_mut(), start_positions);
        copy_into(self.velocities.slice_mut(), start_velocities);
        self.explicit_memory = memory;
    }

    /// [`step_with`](Self::step_with), recording the colliders' reactions where `reactions` is
    /// given (its length checked).
    fn step_recording(
        &mut self,
        scene: &Scene<'_, Vec3>,
        reactions: Option<&mut [Reaction]>,
    ) -> Result<StepReport, StepError> {
        let dt = scene.dt;
        check_time_step(dt)?;
        if self.vertex_count() == 0 {
            return Err(StepError::EmptyBody);
        }
        let substeps = match self.solver {
            Solver::Explicit {
                settings,
                stable_fraction: Some(fraction),
            } => substeps(dt, fraction * self.stable_time_step()?, settings.substeps),
            Solver::Explicit { settings, .. } => settings.substeps,
            // The substeps the explicit stepper would need; a body whose stable step cannot be
            // computed gets Newton's method (u32::MAX substeps), which reports its own errors.
            Solver::Auto(settings) => match self.stable_time_step() {
                Ok(stable) => substeps(
                    dt,
                    settings.stable_fraction * stable,
                    settings.explicit.substeps,
                ),
                Err(_) => u32::MAX,
            },
            _ => 1,
        };
        // The velocities before the kinematic vertices are moved: their change is the
        // attachment's impulse too.
        if reactions.is_some() {
            let n = self.vertex_count();
            let slots = recording_slots(self.vectors.slice_mut(), n, RECORDED_IMPULSES);
            let (_, _, start_velocities) = slots;
            copy_into(start_velocities, self.velocities.slice());
        }
        self.move_kinematic(dt);
        let record = reactions.is_some();
        let outcome = self.run_solver(scene, substeps, record);
        self.settle_kinematic(outcome.is_ok());
        let report = outcome?;
        if let Some(reactions) = reactions {
            self.collider_reactions(scene, &report, reactions)?;
        }
        Ok(report)
    }

    /// After a step recorded for reactions ([`step_with_reactions`](Self::step_with_reactions)):
    /// the contact impulse at each vertex (the explicit stepper's record, or the implicit
    /// momentum balance from the start velocities), then each collider's reaction.
    fn collider_reactions(
        &mut self,
        scene: &Scene<'_, Vec3>,
        report: &StepReport,
        reactions: &mut [Reaction],
    ) -> Result<(), StepError> {
        let n = self.vertex_count();
        let explicit = match report {
            StepReport::Explicit(_) => true,
            StepReport::Auto(auto) => matches!(auto.run, AutoRun::Explicit(_)),
            _ => false,
        };
        let mesh = mesh_over(
            self.tets.slice(),
            self.rest_data.slice(),
            self.rest_blocks.slice(),
            self.gradient_gain,
            n,
        );
        let model = TetElastic::new(mesh, self.material);
        let slots = recording_slots(self.vectors.slice_mut(), n, RECORDED_IMPULSES);
        let (forces, impulses, start_velocities) = slots;
        recorded_reactions(
            &model,
            scene,
            (self.masses.slice(), self.pinned.slice()),
            (self.positions.slice(), self.velocities.slice()),
            (forces, impulses, start_velocities),
            explicit,
            reactions,
        )
    }

    /// The impulse (N s) each vertex received over the last step of
    /// [`step_with_reactions`](Self::step_with_reactions): from the colliders at the free
    /// vertices that touched one, from its pin at each pinned or kinematic vertex (what held
    /// it against its forces, and moved it to its target), zero elsewhere (`docs/math.md`
    /// section 8.14). Valid until the next step or change of the body; sum it over the
    /// vertices attached to a rigid part with [`attachment_reaction`](Self::attachment_reaction).
    #[must_use]
    pub fn last_impulses(&self) -> &[Vec3] {
        let n = self.vertex_count();
        let start = n.saturating_mul(RECORDED_IMPULSES);
        let vectors = self.vectors.slice();
        vectors.get(start..start.saturating_add(n)).unwrap_or(&[])
    }

    /// What a rigid part received over the last step of
    /// [`step_with_reactions`](Self::step_with_reactions) from the body's `vertices` attached
    /// to it (kinematic vertices whose targets the part moves, see
    /// [`set_target`](Self::set_target)): the impulse on the part and its moment about `origin`
    /// (m), to apply to the part in the host engine ([`step::attachment_reaction`](
    /// super::step::attachment_reaction) of [`last_impulses`](Self::last_impulses)).
    ///
    /// # Errors
    /// [`StepError::AttachedVertex`] for the first entry of `vertices` beyond the vertex count.
    pub fn attachment_reaction(
        &self,
        vertices: &[u32],
        origin: Vec3,
    ) -> Result<Reaction, StepError> {
        attachment_reaction(vertices, self.positions.slice(), self.last_impulses(), origin)
    }

    /// Moves the kinematic vertices to their targets with the velocity that takes them there;
    /// `targets` then holds their positions before, `held_velocities` their velocities.
    fn move_kinematic(&mut self, dt: Real) {
        self.each_kinematic(|x, v, target, held| {
            *held = *v;
            *v = (*target - *x) / dt;
            core::mem::swap(x, target);
        });
    }

    /// After the step: on success the targets are the kinematic vertices' positions again; on
    /// failure (the stepper restored the state of after [`move_kinematic`]) the vertices go
    /// back.
    fn settle_kinematic(&mut self, succeeded: bool) {
        self.each_kinematic(|x, v, target, held| {
            if succeeded {
                *target = *x;
            } else {
                core::mem::swap(x, target);
                *v = *held;
            }
        });
    }

    /// `each(x, v, target, held)` of every kinematic vertex in order: its position, velocity,
    /// target and held velocity.
    fn each_kinematic(&mut self, mut each: impl FnMut(&mut Vec3, &mut Vec3, &mut Vec3, &mut Vec3)) {
        let rows = self
            .positions
            .slice_mut()
            .iter_mut()
            .zip(self.velocities.slice_mut())
            .zip(self.targets.slice_mut())
            .zip(self.held_velocities.slice_mut())
            .zip(self.kinematic.slice());
        for ((((x, v), target), held), &kinematic) in rows {
            if kinematic {
                each(x, v, target, held);
            }
        }
    }

    /// One call of the solver's stepper in `scene` (the explicit one in `substeps` substeps;
    /// the automatic solver's choice for a frame of `substeps` explicit substeps).
    fn run_solver(
        &mut self,
        scene: &Scene<'_, Vec3>,
        substeps: u32,
        record: bool,
    ) -> Result<StepReport, StepError> {
        let n = self.vertex_count();
        let mesh = mesh_over(
            self.tets.slice(),
            self.rest_data.slice(),
            self.rest_blocks.slice(),
            self.gradient_gain,
            n,
        );
        let model = TetElastic::new(mesh, self.material);
        let (masses, pinned) = (self.masses.slice(), self.pinned.slice());
        let (x, v) = (self.positions.slice_mut(), self.velocities.slice_mut());
        let vectors = self.vectors.slice_mut();
        match self.solver {
            Solver::Explicit { settings, .. } => {
                let settings = settings.with_substeps(substeps);
                let (buffer, impulses) = explicit_slots(vectors, n, record);
                let mut scratch =
                    ExplicitScratch::resume(buffer, self.explicit_memory).with_impulses(impulses);
                let outcome =
                    explicit_step(&model, masses, pinned, scene, &settings, x, v, &mut scratch);
                self.explicit_memory = scratch.memory();
                outcome.map(StepReport::Explicit)
            }
            Solver::Relax(settings) => {
                let buffer = vectors.get_mut(..n.saturating_mul(5)).unwrap_or(&mut []);
                let mut scratch = RelaxScratch::resume(
                    buffer,
                    self.scalars.slice_mut(),
                    self.preconditioner_ready,
                );
                let outcome =
                    relax_step(&model, masses, pinned, scene, &settings, x, v, &mut scratch);
                self.preconditioner_ready = scratch.stiffness_ready();
                outcome.map(StepReport::Relax)
            }
            Solver::Newton(settings) => {
                let buffer = vectors.get_mut(..n.saturating_mul(9)).unwrap_or(&mut []);
                let mut scratch =
                    NewtonScratch::new(buffer, self.blocks.slice_mut(), self.hessians.slice_mut());
                newton_step(&model, masses, pinned, scene, &settings, x, v, &mut scratch)
                    .map(StepReport::Newton)
            }
            Solver::Vbd(settings) => {
                let buffer = vectors.get_mut(..n.saturating_mul(5)).unwrap_or(&mut []);
                let mut scratch =
                    VbdScratch::resume(buffer, self.indices.slice_mut(), self.topology);
                let values = self.layout_values.slice_mut();
                if !values.is_empty() {
                    let corners = self.layout_corners.slice_mut();
                    scratch = scratch.resume_layout(values, corners, self.layout_built);
                }
                let outcome =
                    vbd_step(&model, masses, pinned, scene, &settings, x, v, &mut scratch);
                self.topology = scratch.topology();
                self.layout_built = scratch.layout_built();
                outcome.map(StepReport::Vbd)
            }
            Solver::Auto(settings) => {
                let mut parts = auto::AutoParts {
                    masses,
                    pinned,
                    positions: x,
                    velocities: v,
                    vectors,
                    blocks: self.blocks.slice_mut(),
                    hessians: self.hessians.slice_mut(),
                    memory: &mut self.explicit_memory,
                    record,
                };
                let choice = settings.choose(substeps);
                auto::run_auto(&model, scene, &settings, choice, &mut parts).map(StepReport::Auto)
            }
        }
    }
}

/// The explicit stepper's scratch (four vectors per vertex) and, where the step is `record`ed,
/// the contact impulses' slot (see `recording_slots`; else empty), both from the solvers' vector
/// scratch.
pub(super) fn explicit_slots(
    vectors: &mut [Vec3],
    n: usize,
    record: bool,
) -> (&mut [Vec3], &mut [Vec3]) {
    let (buffer, rest) = vectors
        .split_at_mut_checked(n.saturating_mul(4))
        .unwrap_or_default();
    let start = n.saturating_mul(RECORDED_IMPULSES - 4);
    let impulses = match record {
        true => rest.get_mut(start..start.saturating_add(n)).unwrap_or(&mut []),
        false => &mut [],
    };
    (buffer, impulses)
}

/// The vectors per vertex of a body's scratch: the automatic solver's eleven and a coupled
/// step's copy of its start positions and velocities.
const BODY_VECTORS: usize = auto::AUTO_VECTORS + 2;

/// The vectors of the scratch where a coupled step keeps the positions and velocities of its
/// start: after the automatic solver's (and the recorded impulses and start velocities).
fn coupling_slots(vectors: &mut [Vec3], n: usize) -> (&mut [Vec3], &mut [Vec3]) {
    let start = n.saturating_mul(auto::AUTO_VECTORS);
    let rest = vectors.get_mut(start..).unwrap_or(&mut []);
    let (positions, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    (positions, rest.get_mut(..n).unwrap_or(&mut []))
}

/// The vector (counted per vertex from 0) of the scratch where a recorded step keeps the contact
/// impulses, then the start velocities: after Newton's nine (`recording_slots` with `k` = 9).
const RECORDED_IMPULSES: usize = 9;

/// `source` into `target`, entry by entry: the storage sized both alike, but `copy_from_slice`
/// would keep a panic path for lengths the optimiser cannot prove equal (the firmware's link
/// check found it).
fn copy_into<X: Copy>(target: &mut [X], source: &[X]) {
    for (slot, &value) in target.iter_mut().zip(source) {
        *slot = value;
    }
}

impl<const V: usize, const T: usize, M: Material> Body<FixedStorage<V, T>, M> {
    /// A fixed-capacity body with no vertices and no tetrahedra, the automatic solver, no
    /// gravity or ground: a `const` value, so the body can be a `static` (in `.bss`, never on
    /// the stack), then built in place with [`rebuild_from_box`](Body::rebuild_from_box) or
    /// [`rebuild_from_arrays`](Body::rebuild_from_arrays). This is the firmware way: the
    /// constructors that return a body by value ([`from_box`](Body::from_box) and the others)
    /// need stack for the body several times over while it is built and moved (about five
    /// times its size in the Cortex-M4F check), while the in-place rebuild needs none of it.
    /// Stepping the empty body is an error ([`StepError::EmptyBody`]).
    ///
    /// ```
    /// use softfem::body::{Body, FixedStorage};
    /// use softfem::material::{Lame, StableNeoHookean};
    /// use softfem::{StepError, glam::Vec3};
    ///
    /// type Ball = Body<FixedStorage<27, 40>, StableNeoHookean>;
    /// const RUBBER: StableNeoHookean = match Lame::from_young_poisson(1e6, 0.45) {
    ///     Ok(lame) => StableNeoHookean::new(lame),
    ///     Err(_) => panic!("invalid material"),
    /// };
    /// static BODY: std::sync::Mutex<Ball> = std::sync::Mutex::new(Ball::empty(RUBBER));
    ///
    /// let mut body = BODY.lock().unwrap();
    /// assert_eq!(body.step(0.01), Err(StepError::EmptyBody)); // nothing built yet
    /// body.rebuild_from_box(Vec3::ZERO, Vec3::splat(0.1), [2, 2, 1], 1000.0)?;
    /// body.set_gravity(Vec3::new(0.0, 0.0, -9.81));
    /// body.step(0.01)?;
    /// assert_eq!((body.vertex_count(), body.tet_count()), (18, 20));
    /// assert!(body.velocities().iter().all(|v| v.z < 0.0));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    #[must_use]
    pub const fn empty(material: M) -> Self {
        unbuilt_body!(material, Fixed::filled)
    }
}

impl<S: Storage, M: Material> fmt::Debug for Body<S, M> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Body")
            .field("vertices", &self.vertex_count())
            .field("tets", &self.tet_count())
            .field("material", &self.material)
            .field("solver", &self.solver)
            .field("gravity", &self.gravity)
            .field("ground", &self.ground)
            .field("stable_step", &self.stable_step)
            .finish_non_exhaustive()
    }
}

/// `Ok` if `fits`, else the capacity error for `needed` entries of `buffer`.
#[inline]
fn capacity(fits: bool, buffer: BodyBuffer, needed: usize) -> Result<(), BodyError> {
    if fits {
        Ok(())
    } else {
        Err(BodyError::Capacity { buffer, needed })
    }
}

/// The fewest substeps, at least `minimum` (and 1), that split `dt` into steps of at most
/// `limit` (s); above [`MAX_SUBSTEPS`](super::step::ExplicitSettings::MAX_SUBSTEPS) (the stepper
/// then refuses it) when `limit` is too small (zero or NaN included).
pub(crate) fn substeps(dt: Real, limit: Real, minimum: u32) -> u32 {
    // `as` saturates: a zero or NaN limit gives u32::MAX or 0, both refused or raised below.
    if limit.is_nan() || limit <= 0.0 {
        return u32::MAX;
    }
    let mut count = (dt / limit) as u32;
    if count < u32::MAX && dt / count as Real > limit {
        count += 1;
    }
    count.max(minimum).max(1)
}

/// The validated mesh over a body's buffers (the rest blocks may be empty), built without
/// validating again. A free function, so that a caller can still borrow the body's other
/// buffers mutably while the mesh lives.
fn mesh_over<'a>(
    tets: &'a [[u32; 4]],
    rest: &'a [TetRest],
    blocks: &'a [TetRestBlock],
    gradient_gain: Real,
    vertex_count: usize,
) -> TetMesh<'a> {
    TetMesh::from_validated(tets, rest, vertex_count, gradient_gain).with_filled_blocks(blocks)
}

#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::super::material::StableNeoHookean;
    use super::super::types::{Real, Vec3};
    use super::{Body, FixedStorage, Slots, Solver, VecStorage};

    /// A growable body sweeps VBD with the packed layout, built on the first step and kept
    /// for the next ones (until the solver or the mesh changes); a fixed-capacity one has no
    /// room for it and sweeps without. (That both give the same bits is
    /// `growable_storage_gives_the_bits_of_fixed_storage` in `tests/steppers/body.rs`.)
    #[test]
    fn a_growable_body_keeps_the_packed_vbd_layout_between_steps() {
        let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.45).unwrap();
        let (low, high) = (Vec3::ZERO, Vec3::new(0.3, 0.1, 0.1));
        let mut growing =
            Body::<VecStorage, _>::from_box(low, high, [6, 2, 2], 1000.0, jelly).unwrap();
        let mut fixed =
            Body::<FixedStorage<63, 120>, _>::from_box(low, high, [6, 2, 2], 1000.0, jelly)
                .unwrap();
        let gravity = Vec3::new(0.0, 0.0, -9.81);
        growing.set_gravity(gravity);
        fixed.set_gravity(gravity);
        growing.set_solver(Solver::vbd()).unwrap();
        fixed.set_solver(Solver::vbd()).unwrap();
        assert_eq!(growing.layout_built, None);
        for body_step in 0..3 {
            let dt: Real = 1.0 / 60.0;
            assert_eq!(growing.step(dt), fixed.step(dt));
            assert_eq!(growing.layout_built, Some(true), "step {body_step}");
            assert!(fixed.layout_values.slice().is_empty());
            assert_eq!(fixed.layout_built, None);
        }
        growing.set_solver(Solver::relax()).unwrap();
        assert_eq!(growing.layout_built, None);
    }
}

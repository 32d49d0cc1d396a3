//! A world of soft bodies that touch each other and themselves: several bodies (each with its
//! own mesh, material and pins) and the colliders, stepped together by one implicit solve over
//! all their vertices with intersection-free contact between every pair of boundary primitives
//! (issue #39). The storage is chosen at the type level: [`FixedWorld`] (fixed capacity, no
//! heap; its lists are `heapless` vectors) or `VecStorage` (feature `alloc`, growable; a
//! contact list that fills up is grown and the step retried).
//!
//! One step is one solve of implicit Euler over every vertex of every body: the bodies'
//! elastic energies (each with its own material, summed in body order), gravity, the ground and
//! the colliders, and the barrier of Incremental Potential Contact between the boundary
//! triangles, edges and vertices of all bodies, within one body as between two, with lagged
//! Coulomb friction between surfaces ([`set_friction`](World::set_friction)). Every trial point
//! of the solve is cut by continuous collision detection, so a step that starts with no two
//! surfaces crossing ends with none crossing (`docs/math.md` sections 8.10 and 8.11 give the
//! conditions: the start free of intersections, the gap `dhat`, the distance floor in f32).
//! Newton's method ([`Solver::Newton`], the default) and the relaxation ([`Solver::Relax`])
//! run it. The explicit stepper ([`Solver::Explicit`], substeps of a fraction of the world's
//! [stable step](World::stable_time_step)) takes the barrier's forces, inelastic impulses where
//! a substep's motion would carry surfaces into each other, and a failsafe that shortens the
//! whole substep where they do not suffice: no substep ends with surfaces crossing
//! (`docs/math.md` section 8.12). Vertex Block Descent ([`Solver::Vbd`]) takes the barrier and
//! the friction between surfaces in its vertex updates, body after body, each contact vertex's
//! step cut to a fraction of its nearest pair's distance (`docs/math.md` section 8.13): the same
//! guarantee, with fewer converged steps than Newton's method where many bodies press on each
//! other.
//!
//! With the `rayon` feature, [`set_threads`](World::set_threads) (or
//! [`set_pool`](World::set_pool)) runs the world's elastic passes on a rayon pool, the bodies in
//! parallel: one task per body writes only its own vertices' forces, products and Hessian blocks
//! (and its own tetrahedra's Hessians) through disjoint slices, its kernel running on its own
//! vertices with body-local indices, the energies added in body order afterwards; the steppers'
//! passes over the vertices run in blocks on the pool and Vertex Block Descent runs each body's
//! colours in parallel. Every step gives the bits of the world on the calling thread, at any
//! thread count. The contact model's pair work (broad phase, barrier, friction, continuous
//! collision detection) and Newton's conjugate gradients stay on the calling thread, so a pile
//! whose steps are mostly contact gains less than its bodies' share.
//!
//! Bodies are added ([`add_box`](World::add_box), [`add_body`](World::add_body)), removed
//! ([`remove_body`](World::remove_body)) and moved
//! ([`body_positions_mut`](World::body_positions_mut)) between steps. A body is named by its
//! index, in the order of addition; removing one moves the later ones down by one (as
//! `Vec::remove`). Placing a body so that its surface crosses
//! another's is the caller's to avoid: the guarantee starts from a state free of intersections.
//!
//! A soft cube dropped onto a stiffer one resting on the ground (z up), growable storage:
//! ```
//! # #[cfg(feature = "alloc")] {
//! use softfem::body::VecStorage;
//! use softfem::world::World;
//! use softfem::{glam::Vec3, material::StableNeoHookean, step::HalfSpace};
//!
//! let stiff = StableNeoHookean::from_young_poisson(1.0e6, 0.3)?; // Pa
//! let soft = StableNeoHookean::from_young_poisson(5.0e4, 0.3)?;
//! let mut world = World::<VecStorage, _>::new();
//! let below = world.add_box(Vec3::ZERO, Vec3::splat(0.1), [2; 3], 1000.0, stiff)?;
//! let (low, high) = (Vec3::new(0.02, 0.02, 0.12), Vec3::new(0.08, 0.08, 0.18));
//! let above = world.add_box(low, high, [2; 3], 1000.0, soft)?;
//! world.set_gravity(Vec3::new(0.0, 0.0, -9.81)); // m/s^2
//! world.set_ground(Some(HalfSpace::new(Vec3::Z, 0.0)));
//! for _ in 0..40 {
//!     assert!(world.step(0.01)?.converged()); // 0.4 s
//! }
//! let heights = |body| world.body_positions(body).unwrap().iter().map(|x| x.z);
//! let top_of_below = heights(below).fold(0.0, f32::max);
//! let bottom_of_above = heights(above).fold(1.0, f32::min);
//! let gap = bottom_of_above - top_of_below;
//! assert!(gap > 0.0 && gap < 1e-3, "{gap}"); // resting on it, within the contact gap of 1 mm
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod model;
mod storage;
#[cfg(feature = "rayon")]
mod threads;

pub use storage::{FixedWorld, List, WorldStorage};

use core::ops::Range;

use super::asset::surface::{BoundaryFace, boundary_faces};
use super::body::{CoupledReport, Fixed, Slots, Solver, StepReport, substeps};
use super::element::{TetHessian, TetRest};
use super::generate::{BoxSplit, box_counts, fill_box};
use super::material::Material;
use super::mesh::TetMesh;
use super::step::contact::boundary::ContactSurface;
use super::step::contact::model::CandidateReuse;
use super::step::contact::model::{ContactCounts, FrictionPair};
use super::step::contact::potential::{ContactBarrier, PairHessian};
use super::step::contact::{ContactBuffers, ContactModel, SUGGESTED_STICKING_SPEED};
use super::step::contact::reaction::{recorded_reactions, recording_slots};
use super::step::contact::attachment::{
    MAX_ATTACHMENTS, SoftPull, add_attachment_reactions, check_attachments, end_anchor,
};
use super::step::contact::rigid::{check_coupled_step, couple};
use super::step::state::check_length;
use super::step::{
    Attachment, Collider, ContactBuffersVbd, CouplingSettings, ExplicitMemory, ExplicitScratch, HalfSpace,
    NewtonScratch, NewtonSettings, Reaction, RelaxScratch, Scene, VbdScratch, VbdTopology,
     check_time_step, explicit_step,  newton_step,
    relax_step, scratch_len, stable_time_step, vbd_step,
};
use super::types::{Mat3, Real, Vec3};
use crate::error::{
    BodyBuffer, BodyError, ContactBuffer, ContactError, MeshError, StepBuffer, StepError,
};
use model::WorldElastic;
use storage::remove_range;

/// Where one body of a [`World`] lies in the world's lists, and its material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Part<M> {
    first_vertex: u32,
    vertex_count: u32,
    first_tet: u32,
    tet_count: u32,
    first_triangle: u32,
    triangle_count: u32,
    /// From the validating [`TetMesh::new`], for the views rebuilt every step.
    gradient_gain: Real,
    material: M,
}

impl<M> Part<M> {
    /// The body's vertices: a range of the world's vertex indices.
    #[inline]
    #[must_use]
    pub fn vertices(&self) -> Range<usize> {
        range(self.first_vertex, self.vertex_count)
    }

    /// The body's tetrahedra: a range of the world's tetrahedra.
    #[inline]
    #[must_use]
    pub fn tets(&self) -> Range<usize> {
        self.tet_range()
    }

    /// The body's boundary triangles: a range of [`World::triangles`].
    #[inline]
    #[must_use]
    pub fn triangles(&self) -> Range<usize> {
        range(self.first_triangle, self.triangle_count)
    }

    /// The body's material.
    #[inline]
    #[must_use]
    pub fn material(&self) -> &M {
        &self.material
    }

    #[inline]
    fn tet_range(&self) -> Range<usize> {
        range(self.first_tet, self.tet_count)
    }
}

/// `first..first + count` as indices.
#[inline]
fn range(first: u32, count: u32) -> Range<usize> {
    let first = first as usize;
    first..first.saturating_add(count as usize)
}

/// A world of soft bodies in contact; see the [module documentation](self).
///
/// `S` is the [`WorldStorage`] ([`FixedWorld`] or `VecStorage`), `M` the [`Material`] type
/// of every body (each body has its own value: a stiff body and a soft one of the same model
/// share a solve).
///
/// * Pinned vertices ([`set_pinned`](Self::set_pinned)) keep their position and velocity.
/// * A failed step returns the [`StepError`] with every position and velocity as it was before
///   the call, bit for bit; a failed change (adding a body that does not fit, say) leaves the
///   world as it was.
pub struct World<S: WorldStorage, M: Material> {
    parts: S::Parts<M>,
    rest_positions: S::Vectors,
    positions: S::Vectors,
    velocities: S::Vectors,
    masses: S::Reals,
    pinned: S::Flags,
    tets: S::Tets,
    rest_data: S::Rests,
    /// Every body's boundary triangles (global vertex indices), body after body.
    triangles: S::Triangles,
    faces: S::Faces,
    /// The contact surface: its unique vertices and edges (the first `surface_vertices` and
    /// `surface_edges` entries).
    surface_vertex_list: S::Indices,
    surface_edge_list: S::Pairs,
    surface_vertices: usize,
    surface_edges: usize,
    slots: S::Indices,
    entries: S::Indices,
    vertex_triangle: S::Pairs,
    edge_edge: S::Pairs,
    pair_hessians: S::PairHessians,
    friction_pairs: S::FrictionPairs,
    /// Candidate reuse: the kept motion's boxes and pairs ([`CandidateReuse`]).
    reuse_bounds: S::Bounds,
    reuse_vertex_triangle: S::Pairs,
    reuse_edge_edge: S::Pairs,
    vectors: S::Scratch,
    scalars: S::Scalars,
    blocks: S::Blocks,
    hessians: S::Hessians,
    /// Vertex Block Descent's adjacency, colouring and order, and what they hold.
    vertex_indices: S::VertexIndices,
    tet_indices: S::TetIndices,
    topology: VbdTopology,
    solver: Solver,
    coupling: CouplingSettings,
    gravity: Vec3,
    ground: Option<HalfSpace<Vec3>>,
    /// `None`: the default, [`ContactBarrier::holding`]`(DEFAULT_GAP, DEFAULT_HOLDING_FORCE)`.
    barrier: Option<ContactBarrier>,
    friction: Real,
    preconditioner_ready: bool,
    /// The explicit stepper's stable time step, once computed.
    stable_step: Option<Real>,
    explicit_memory: ExplicitMemory,
    counts: ContactCounts,
    /// The thread pool of the elastic passes and what they keep ([`set_threads`](Self::set_threads)).
    #[cfg(feature = "rayon")]
    threads: Option<threads::Threads<M>>,
}

/// The barrier of a world that was given none.
fn default_barrier() -> ContactBarrier {
    ContactBarrier::holding(DEFAULT_GAP, DEFAULT_HOLDING_FORCE).unwrap_or(ContactBarrier {
        stiffness: 0.0,
        gap: DEFAULT_GAP,
    })
}

/// The contact gap `dhat` (m) of a new world.
pub const DEFAULT_GAP: Real = 1e-3;

/// The force (N) with which a pair at half the gap pushes in a new world
/// ([`ContactBarrier::holding`]).
pub const DEFAULT_HOLDING_FORCE: Real = 1.0;

/// The literal of a [`World`] with no bodies: the body list `$parts`, every kept list
/// `$list(zero)`, every contact list `$contact(zero)` and every other buffer `$slots(zero)` for
/// the zero of its entries (`heapless::Vec::new` and `Fixed::filled` in the `const`
/// [`World::empty`], the storage's own empty buffers in [`World::new`]).
macro_rules! unbuilt_world {
    ($parts:expr, $list:path, $slots:path, $contact:path) => {
        World {
            parts: $parts,
            rest_positions: $list(Vec3::ZERO),
            positions: $list(Vec3::ZERO),
            velocities: $list(Vec3::ZERO),
            masses: $list(0.0),
            pinned: $list(false),
            tets: $list([0; 4]),
            rest_data: $list(TetRest::ZERO),
            triangles: $slots([0; 3]),
            faces: $slots(BoundaryFace {
                triangle: [0; 3],
                tet: 0,
            }),
            surface_vertex_list: $contact(0),
            surface_edge_list: $contact([0; 2]),
            surface_vertices: 0,
            surface_edges: 0,
            slots: $contact(0),
            entries: $contact(0),
            vertex_triangle: $contact([0; 2]),
            edge_edge: $contact([0; 2]),
            pair_hessians: $contact(PairHessian::ZERO),
            friction_pairs: $contact(FrictionPair::ZERO),
            reuse_bounds: $slots(Vec3::ZERO),
            reuse_vertex_triangle: $contact([0; 2]),
            reuse_edge_edge: $contact([0; 2]),
            vectors: $slots(Vec3::ZERO),
            scalars: $slots(0.0),
            blocks: $slots(Mat3::ZERO),
            hessians: $slots(TetHessian::ZERO),
            vertex_indices: $slots(0),
            tet_indices: $slots(0),
            topology: None,
            solver: Solver::Newton(NewtonSettings::new()),
            coupling: CouplingSettings::DEFAULT,
            gravity: Vec3::ZERO,
            ground: None,
            barrier: None,
            friction: 0.0,
            preconditioner_ready: false,
            stable_step: None,
            explicit_memory: ExplicitMemory::FRESH,
            counts: ContactCounts {
                vertex_triangle: 0,
                edge_edge: 0,
                hessians: 0,
                friction: 0,
                grid_queries: 0,
                reused_queries: 0,
            },
            #[cfg(feature = "rayon")]
            threads: None,
        }
    };
}

/// An empty kept list of any storage (`_zero` names the entry type only).
fn empty_list<X: Copy, L: List<X>>(_zero: X) -> L {
    L::empty()
}

/// An empty buffer of any storage (`_zero` names the entry type only).
fn empty_slots<X: Copy, B: Slots<X>>(_zero: X) -> B {
    B::empty()
}

/// A `heapless::Vec` of no entries, for the `const` [`World::empty`] (`_zero` names the entry
/// type only).
const fn heapless_empty<X: Copy, const N: usize>(_zero: X) -> heapless::Vec<X, N> {
    heapless::Vec::new()
}

impl<S: WorldStorage, M: Material> Default for World<S, M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<S: WorldStorage, M: Material> World<S, M> {
    /// An empty world: no bodies, Newton's method ([`Solver::newton`]), no gravity or ground,
    /// the barrier [`ContactBarrier::holding`]`(`[`DEFAULT_GAP`]`, `[`DEFAULT_HOLDING_FORCE`]`)`,
    /// no friction between surfaces.
    #[must_use]
    pub fn new() -> Self {
        unbuilt_world!(List::empty(), empty_list, empty_slots, empty_slots)
    }

    /// Adds a box `[min, max]` (m) of `cells[0] x cells[1] x cells[2]` cubes, five tetrahedra
    /// each ([`BoxSplit::Alternating5`]), of `material` with `density` (kg/m^3), at rest, and
    /// returns its index.
    ///
    /// # Errors
    /// As [`add_body`](Self::add_body), and [`BodyError::Generate`] for a box the generator
    /// refuses; the world is unchanged then.
    pub fn add_box(
        &mut self,
        min: Vec3,
        max: Vec3,
        cells: [usize; 3],
        density: Real,
        material: M,
    ) -> Result<usize, BodyError> {
        let [nx, ny, nz] = cells;
        let split = BoxSplit::Alternating5;
        let (vertices, tets) = box_counts(nx, ny, nz, split)?;
        self.admit(vertices, tets, density, material, |x, t| {
            fill_box(min, max, nx, ny, nz, split, x, t).map_err(BodyError::from)
        })
    }

    /// Adds a body of `rest_positions` (m) and `tets` (indices into them, positively oriented
    /// as [`TetMesh::new`] requires) of `material` with `density` (kg/m^3), at rest at its rest
    /// shape, nothing pinned, and returns its index. Its boundary triangles join the contact
    /// surface.
    ///
    /// # Errors
    /// [`BodyError::Mesh`] for a mesh [`TetMesh::new`] refuses (or a density
    /// [`TetMesh::lumped_masses`] refuses), [`BodyError::UnusedVertex`] for a vertex in no
    /// tetrahedron, [`BodyError::Capacity`] naming the buffer that cannot hold the world with
    /// the body ([`BodyBuffer::Bodies`], [`BodyBuffer::Vertices`], [`BodyBuffer::Tetrahedra`],
    /// [`BodyBuffer::Surface`], [`BodyBuffer::Scratch`]) and [`BodyError::Contact`] for a
    /// surface the contact model refuses; the world is unchanged then.
    pub fn add_body(
        &mut self,
        rest_positions: &[Vec3],
        tets: &[[u32; 4]],
        density: Real,
        material: M,
    ) -> Result<usize, BodyError> {
        self.admit(
            rest_positions.len(),
            tets.len(),
            density,
            material,
            |x, t| {
                copy_into(x, rest_positions);
                copy_into(t, tets);
                Ok(())
            },
        )
    }

    /// Appends a body of `vertices` and `tets` whose rest positions and (body-local)
    /// tetrahedra `fill` writes, validates it, joins its surface to the contact surface; on
    /// any error the world is put back as it was.
    fn admit(
        &mut self,
        vertices: usize,
        tets: usize,
        density: Real,
        material: M,
        fill: impl FnOnce(&mut [Vec3], &mut [[u32; 4]]) -> Result<(), BodyError>,
    ) -> Result<usize, BodyError> {
        let lengths = self.lengths();
        let added = self.append(vertices, tets, density, material, fill);
        let added = added.and_then(|body| self.rebuild_surface().map(|()| body));
        if added.is_err() {
            self.truncate_to(lengths);
            // The world as it was fitted before; its surface fits again.
            let _ = self.rebuild_surface();
        }
        added
    }

    /// The lengths of the kept lists: bodies, vertices, tetrahedra.
    fn lengths(&self) -> [usize; 3] {
        [
            self.parts.slice().len(),
            self.positions.slice().len(),
            self.tets.slice().len(),
        ]
    }

    /// Shortens the kept lists to `lengths` (from [`lengths`](Self::lengths)).
    fn truncate_to(&mut self, [parts, vertices, tets]: [usize; 3]) {
        self.parts.truncate(parts);
        self.rest_positions.truncate(vertices);
        self.positions.truncate(vertices);
        self.velocities.truncate(vertices);
        self.masses.truncate(vertices);
        self.pinned.truncate(vertices);
        self.tets.truncate(tets);
        self.rest_data.truncate(tets);
    }

    /// The appending half of [`admit`](Self::admit): the lists grown, the body validated
    /// (body-local indices, then shifted to global ones), its record pushed.
    fn append(
        &mut self,
        vertices: usize,
        tets: usize,
        density: Real,
        material: M,
        fill: impl FnOnce(&mut [Vec3], &mut [[u32; 4]]) -> Result<(), BodyError>,
    ) -> Result<usize, BodyError> {
        let [body, first_vertex, first_tet] = self.lengths();
        let too_many = |buffer, needed| BodyError::Capacity { buffer, needed };
        let vertex_total = first_vertex.saturating_add(vertices);
        let tet_total = first_tet.saturating_add(tets);
        // Indices are u32 throughout the kernels.
        if u32::try_from(vertex_total).is_err() {
            return Err(too_many(BodyBuffer::Vertices, vertex_total));
        }
        if u32::try_from(tet_total.saturating_mul(4)).is_err() {
            return Err(too_many(BodyBuffer::Tetrahedra, tet_total));
        }
        let grown = extend_by(&mut self.rest_positions, vertices, Vec3::ZERO)
            && extend_by(&mut self.positions, vertices, Vec3::ZERO)
            && extend_by(&mut self.velocities, vertices, Vec3::ZERO)
            && extend_by(&mut self.masses, vertices, 0.0)
            && extend_by(&mut self.pinned, vertices, false);
        if !grown {
            return Err(too_many(BodyBuffer::Vertices, vertex_total));
        }
        let grown = extend_by(&mut self.tets, tets, [0; 4])
            && extend_by(&mut self.rest_data, tets, TetRest::ZERO);
        if !grown {
            return Err(too_many(BodyBuffer::Tetrahedra, tet_total));
        }
        let rest = self
            .rest_positions
            .slice_mut()
            .get_mut(first_vertex..)
            .unwrap_or(&mut []);
        let local_tets = self
            .tets
            .slice_mut()
            .get_mut(first_tet..)
            .unwrap_or(&mut []);
        fill(rest, local_tets)?;
        let rest = self
            .rest_positions
            .slice()
            .get(first_vertex..)
            .unwrap_or(&[]);
        let local_tets = self.tets.slice().get(first_tet..).unwrap_or(&[]);
        let rest_data = self
            .rest_data
            .slice_mut()
            .get_mut(first_tet..)
            .unwrap_or(&mut []);
        let mesh = TetMesh::new(rest, local_tets, rest_data)?;
        let masses = self
            .masses
            .slice_mut()
            .get_mut(first_vertex..)
            .unwrap_or(&mut []);
        mesh.lumped_masses(density, masses)?;
        // Every tetrahedron's share of the mass is a positive normal number, so a vertex has
        // mass zero exactly when no tetrahedron uses it.
        if let Some(vertex) = masses.iter().position(|&mass| mass <= 0.0) {
            return Err(BodyError::UnusedVertex { vertex });
        }
        let gradient_gain = mesh.gradient_gain();
        // The body's boundary, in body-local indices, then everything shifted to global ones.
        let faces_needed = tets.saturating_mul(4);
        if !self.faces.resize(faces_needed, Default::default()) {
            return Err(too_many(BodyBuffer::Surface, faces_needed));
        }
        let faces = boundary_faces(local_tets, vertices, self.faces.slice_mut())
            .map_err(|_| too_many(BodyBuffer::Surface, faces_needed))?;
        let triangle_count = faces.len();
        let first_triangle = self.parts.slice().last().map_or(0, |part| {
            part.first_triangle.saturating_add(part.triangle_count)
        });
        let offset = first_vertex as u32;
        for tet in self
            .tets
            .slice_mut()
            .get_mut(first_tet..)
            .unwrap_or(&mut [])
        {
            *tet = tet.map(|v| v + offset);
        }
        copy_into(
            self.positions
                .slice_mut()
                .get_mut(first_vertex..)
                .unwrap_or(&mut []),
            self.rest_positions
                .slice()
                .get(first_vertex..)
                .unwrap_or(&[]),
        );
        let part = Part {
            first_vertex: offset,
            vertex_count: vertices as u32,
            first_tet: first_tet as u32,
            tet_count: tets as u32,
            first_triangle,
            triangle_count: triangle_count as u32,
            gradient_gain,
            material,
        };
        if !self.parts.extend(&[part]) {
            return Err(too_many(BodyBuffer::Bodies, body.saturating_add(1)));
        }
        Ok(body)
    }

    /// Removes body `body`; the later bodies move down by one index, their vertices and
    /// tetrahedra close up the gap.
    ///
    /// # Errors
    /// [`BodyError::NoSuchBody`] if there is no body `body`; the world is unchanged then.
    pub fn remove_body(&mut self, body: usize) -> Result<(), BodyError> {
        let part = self.part(body)?;
        let (vertices, tets) = (part.vertices(), part.tet_range());
        for list in [
            &mut self.rest_positions,
            &mut self.positions,
            &mut self.velocities,
        ] {
            remove_range(list, vertices.start, vertices.len());
        }
        remove_range(&mut self.masses, vertices.start, vertices.len());
        remove_range(&mut self.pinned, vertices.start, vertices.len());
        remove_range(&mut self.tets, tets.start, tets.len());
        remove_range(&mut self.rest_data, tets.start, tets.len());
        remove_range(&mut self.parts, body, 1);
        let later_tets = self
            .tets
            .slice_mut()
            .get_mut(tets.start..)
            .unwrap_or(&mut []);
        for tet in later_tets {
            *tet = tet.map(|v| v - part.vertex_count);
        }
        for later in self.parts.slice_mut().get_mut(body..).unwrap_or(&mut []) {
            later.first_vertex -= part.vertex_count;
            later.first_tet -= part.tet_count;
            later.first_triangle -= part.triangle_count;
        }
        // A smaller world's surface always fits where the larger one did.
        let _ = self.rebuild_surface();
        self.forget_history();
        Ok(())
    }

    /// Rebuilds the boundary triangles of every body (global indices), the contact surface's
    /// vertices and edges, and sizes the broad phase, the contact lists and the solver's
    /// scratch for them.
    fn rebuild_surface(&mut self) -> Result<(), BodyError> {
        self.forget_history();
        #[cfg(feature = "rayon")]
        self.fit_threads();
        let too_many = |buffer, needed| BodyError::Capacity { buffer, needed };
        let n = self.positions.slice().len();
        let triangle_total = self.parts.slice().last().map_or(0, |part| {
            (part.first_triangle as usize).saturating_add(part.triangle_count as usize)
        });
        if !self.triangles.resize(triangle_total, [0; 3]) {
            return Err(too_many(BodyBuffer::Surface, triangle_total));
        }
        for part in self.parts.slice() {
            let faces = part.tet_range().len().saturating_mul(4);
            if !self.faces.resize(faces, Default::default()) {
                return Err(too_many(BodyBuffer::Surface, faces));
            }
            let tets = self.tets.slice().get(part.tet_range()).unwrap_or(&[]);
            let written = boundary_faces(tets, n, self.faces.slice_mut())
                .map_err(|_| too_many(BodyBuffer::Surface, faces))?;
            let triangles = self
                .triangles
                .slice_mut()
                .get_mut(part.triangles())
                .unwrap_or(&mut []);
            for (slot, face) in triangles.iter_mut().zip(written) {
                *slot = face.triangle;
            }
        }
        let f = triangle_total;
        let (vertex_slots, edge_slots) = (
            scratch_len::boundary_vertices(f),
            scratch_len::boundary_edges(f),
        );
        if !(self.surface_vertex_list.resize(vertex_slots, 0)
            && self.surface_edge_list.resize(edge_slots, [0; 2]))
        {
            return Err(too_many(BodyBuffer::Surface, vertex_slots));
        }
        let surface = ContactSurface::from_triangles(
            self.triangles.slice(),
            n,
            self.surface_vertex_list.slice_mut(),
            self.surface_edge_list.slice_mut(),
        )
        .map_err(BodyError::Contact)?;
        let (v, e) = (surface.vertices.len(), surface.edges.len());
        self.surface_vertices = v;
        self.surface_edges = e;
        let lengths = scratch_len::broad_phase(v, e, f);
        if !(self.slots.resize(lengths.slots, 0) && self.entries.resize(lengths.entries, 0)) {
            return Err(too_many(BodyBuffer::Surface, lengths.entries));
        }
        // Room for 32 candidates per surface vertex and edge and a pair Hessian per triangle
        // to start with; a growable world grows them when a step needs more.
        resize_up_to(&mut self.vertex_triangle, v.saturating_mul(32), [0; 2]);
        resize_up_to(&mut self.edge_edge, e.saturating_mul(32), [0; 2]);
        resize_up_to(&mut self.pair_hessians, f.max(64), PairHessian::ZERO);
        resize_up_to(&mut self.friction_pairs, f.max(64), FrictionPair::ZERO);
        // Candidate reuse keeps a motion's pairs (more than a configuration's): twice the room.
        if !self.reuse_bounds.resize(2 * v, Vec3::ZERO) {
            return Err(too_many(BodyBuffer::Surface, 2 * v));
        }
        resize_up_to(
            &mut self.reuse_vertex_triangle,
            v.saturating_mul(64),
            [0; 2],
        );
        resize_up_to(&mut self.reuse_edge_edge, e.saturating_mul(64), [0; 2]);
        self.size_scratch(&self.solver.clone())
    }

    /// Sizes the scratch `solver` needs for the world's vertices and tetrahedra.
    fn size_scratch(&mut self, solver: &Solver) -> Result<(), BodyError> {
        let (n, t) = (self.vertex_count(), self.tet_count());
        let too_many = |buffer, needed| BodyError::Capacity { buffer, needed };
        if let Solver::Auto(_) = solver {
            return Err(BodyError::Solver);
        }
        // The solver's, the two of a step recorded for reactions (see `recording_slots`) and
        // the two of a coupled step's start (see `coupling_slots`).
        let vectors = solver_vectors(solver) + EXTRA_VECTORS;
        self.topology = None;
        if let Solver::Vbd(_) = solver {
            let vertex_len = scratch_len::vbd_indices(n, 0);
            let tet_len = t.saturating_mul(4);
            if !(self.blocks.resize(n, Mat3::ZERO)
                && self.vertex_indices.resize(vertex_len, 0)
                && self.tet_indices.resize(tet_len, 0))
            {
                return Err(too_many(BodyBuffer::Tetrahedra, t));
            }
        }
        if let Solver::Explicit {
            stable_fraction: Some(fraction),
            ..
        } = *solver
            && !(fraction.is_finite() && fraction > 0.0 && fraction <= 1.0)
        {
            return Err(BodyError::StableFraction);
        }
        if let Solver::Newton(_) = solver
            && !(self.blocks.resize(n, Mat3::ZERO) && self.hessians.resize(t, TetHessian::ZERO))
        {
            return Err(too_many(BodyBuffer::Tetrahedra, t));
        }
        if !self.scalars.resize(n, 0.0) {
            return Err(too_many(BodyBuffer::Vertices, n));
        }
        let needed = n.saturating_mul(vectors);
        if !self.vectors.resize(needed, Vec3::ZERO) {
            return Err(too_many(BodyBuffer::Scratch, needed));
        }
        Ok(())
    }

    /// Forgets what the solvers remember between steps (the relaxation's preconditioner, the
    /// stable time step, the explicit stepper's blow-up history): the bodies, pins or
    /// materials changed.
    fn forget_history(&mut self) {
        self.preconditioner_ready = false;
        self.stable_step = None;
        self.explicit_memory = ExplicitMemory::FRESH;
    }

    /// The explicit stepper's proven stable time step (s) of the world's elastic model (the
    /// bodies' elements and masses; the contact barrier's stiffness is not in it), computed
    /// once and kept until the bodies, pins or materials change.
    ///
    /// # Errors
    /// [`StepError::EmptyBody`] for a world without bodies, or those of
    /// [`stable_time_step`].
    pub fn stable_time_step(&mut self) -> Result<Real, StepError> {
        if let Some(dt) = self.stable_step {
            return Ok(dt);
        }
        if self.vertex_count() == 0 {
            return Err(StepError::EmptyBody);
        }
        let elastic = WorldElastic {
            tets: self.tets.slice(),
            rest: self.rest_data.slice(),
            parts: self.parts.slice(),
            vertex_count: self.positions.slice().len(),
            #[cfg(feature = "rayon")]
            threads: None,
        };
        let dt = stable_time_step(
            &elastic,
            self.masses.slice(),
            self.pinned.slice(),
            self.scalars.slice_mut(),
        )?;
        // The buffer it used holds the relaxation's preconditioner otherwise.
        self.preconditioner_ready = false;
        self.stable_step = Some(dt);
        Ok(dt)
    }

    /// The record of body `body`.
    fn part(&self, body: usize) -> Result<Part<M>, BodyError> {
        self.parts
            .slice()
            .get(body)
            .copied()
            .ok_or(BodyError::NoSuchBody {
                body,
                count: self.body_count(),
            })
    }

    /// The number of bodies.
    #[inline]
    #[must_use]
    pub fn body_count(&self) -> usize {
        self.parts.slice().len()
    }

    /// The bodies' records, in index order: where each lies in the world's lists, and its
    /// material.
    #[inline]
    #[must_use]
    pub fn bodies(&self) -> &[Part<M>] {
        self.parts.slice()
    }

    /// The number of vertices of all bodies.
    #[inline]
    #[must_use]
    pub fn vertex_count(&self) -> usize {
        self.positions.slice().len()
    }

    /// The number of tetrahedra of all bodies.
    #[inline]
    #[must_use]
    pub fn tet_count(&self) -> usize {
        self.tets.slice().len()
    }

    /// Every body's vertices' positions (m), body after body ([`Part::vertices`] gives each
    /// body's range).
    #[inline]
    #[must_use]
    pub fn positions(&self) -> &[Vec3] {
        self.positions.slice()
    }

    /// Every body's vertices' velocities (m/s), body after body.
    #[inline]
    #[must_use]
    pub fn velocities(&self) -> &[Vec3] {
        self.velocities.slice()
    }

    /// Every body's vertices' rest positions (m), body after body.
    #[inline]
    #[must_use]
    pub fn rest_positions(&self) -> &[Vec3] {
        self.rest_positions.slice()
    }

    /// Every body's tetrahedra (global vertex indices), body after body.
    #[inline]
    #[must_use]
    pub fn tets(&self) -> &[[u32; 4]] {
        self.tets.slice()
    }

    /// Every body's boundary triangles (global vertex indices, counter-clockwise seen from
    /// outside), body after body: the contact surface, and what a renderer draws.
    #[inline]
    #[must_use]
    pub fn triangles(&self) -> &[[u32; 3]] {
        self.triangles.slice()
    }

    /// The lumped masses (kg), one per vertex.
    #[inline]
    #[must_use]
    pub fn masses(&self) -> &[Real] {
        self.masses.slice()
    }

    /// Body `body`'s positions (m), or `None` if there is no such body.
    #[must_use]
    pub fn body_positions(&self, body: usize) -> Option<&[Vec3]> {
        let part = self.parts.slice().get(body)?;
        self.positions.slice().get(part.vertices())
    }

    /// Body `body`'s positions, writable (to move it between steps), or `None`. The step
    /// assumes no two surfaces cross at its start: a body moved into another is not pushed
    /// out.
    #[must_use]
    pub fn body_positions_mut(&mut self, body: usize) -> Option<&mut [Vec3]> {
        let part = *self.parts.slice().get(body)?;
        self.positions.slice_mut().get_mut(part.vertices())
    }

    /// Body `body`'s velocities (m/s), or `None`.
    #[must_use]
    pub fn body_velocities(&self, body: usize) -> Option<&[Vec3]> {
        let part = self.parts.slice().get(body)?;
        self.velocities.slice().get(part.vertices())
    }

    /// Body `body`'s velocities, writable, or `None`.
    #[must_use]
    pub fn body_velocities_mut(&mut self, body: usize) -> Option<&mut [Vec3]> {
        let part = *self.parts.slice().get(body)?;
        self.velocities.slice_mut().get_mut(part.vertices())
    }

    /// Pins (or frees) vertex `vertex` of body `body` (a body-local index): a pinned vertex
    /// keeps its position and velocity.
    ///
    /// # Errors
    /// [`BodyError::NoSuchBody`], or [`BodyError::Vertex`] if the body has no such vertex.
    pub fn set_pinned(
        &mut self,
        body: usize,
        vertex: usize,
        pinned: bool,
    ) -> Result<(), BodyError> {
        let part = self.part(body)?;
        let slot = part
            .vertices()
            .nth(vertex)
            .and_then(|global| self.pinned.slice_mut().get_mut(global))
            .ok_or(BodyError::Vertex { vertex })?;
        *slot = pinned;
        self.forget_history();
        Ok(())
    }

    /// Whether each vertex is pinned, body after body.
    #[inline]
    #[must_use]
    pub fn pinned(&self) -> &[bool] {
        self.pinned.slice()
    }

    /// Sets body `body`'s material (the next step uses it).
    ///
    /// # Errors
    /// [`BodyError::NoSuchBody`].
    pub fn set_material(&mut self, body: usize, material: M) -> Result<(), BodyError> {
        self.part(body)?;
        if let Some(part) = self.parts.slice_mut().get_mut(body) {
            part.material = material;
        }
        self.forget_history();
        Ok(())
    }

    /// The gravity (m/s^2) of [`step`](Self::step).
    #[inline]
    #[must_use]
    pub fn gravity(&self) -> Vec3 {
        self.gravity
    }

    /// Sets the gravity (m/s^2) of [`step`](Self::step).
    #[inline]
    pub fn set_gravity(&mut self, gravity: Vec3) {
        self.gravity = gravity;
    }

    /// Sets the ground of [`step`](Self::step) (or none).
    #[inline]
    pub fn set_ground(&mut self, ground: Option<HalfSpace<Vec3>>) {
        self.ground = ground;
    }

    /// The solver.
    #[inline]
    #[must_use]
    pub fn solver(&self) -> &Solver {
        &self.solver
    }

    /// Sets the solver: [`Solver::Newton`], [`Solver::Relax`], [`Solver::Vbd`] or
    /// [`Solver::Explicit`].
    ///
    /// # Errors
    /// [`BodyError::Solver`] for [`Solver::Auto`] (its rule and fallbacks are a
    /// [`Body`](crate::body::Body)'s; a world's solver is chosen by name),
    /// [`BodyError::StableFraction`] for an explicit `stable_fraction` outside `(0, 1]`,
    /// [`BodyError::Capacity`] if its scratch does not fit; the solver is unchanged then.
    pub fn set_solver(&mut self, solver: Solver) -> Result<(), BodyError> {
        self.size_scratch(&solver)?;
        self.solver = solver;
        self.forget_history();
        Ok(())
    }

    /// The contact barrier: its gap `dhat` (m) and stiffness `kappa`.
    #[inline]
    #[must_use]
    pub fn barrier(&self) -> ContactBarrier {
        self.barrier.unwrap_or_else(default_barrier)
    }

    /// Sets the contact barrier (see [`ContactBarrier::holding`] to choose the stiffness by
    /// the force a pair at half the gap holds).
    ///
    /// # Errors
    /// [`BodyError::Contact`] with [`ContactError::Gap`] or [`ContactError::Stiffness`] for a
    /// gap that is not finite and positive or a stiffness that is not finite and `>= 0`.
    pub fn set_barrier(&mut self, barrier: ContactBarrier) -> Result<(), BodyError> {
        if !(barrier.gap.is_finite() && barrier.gap > 0.0) {
            return Err(BodyError::Contact(ContactError::Gap));
        }
        if !(barrier.stiffness.is_finite() && barrier.stiffness >= 0.0) {
            return Err(BodyError::Contact(ContactError::Stiffness));
        }
        self.barrier = Some(barrier);
        Ok(())
    }

    /// The Coulomb coefficient between the bodies' surfaces (0: frictionless, the default).
    #[inline]
    #[must_use]
    pub fn friction(&self) -> Real {
        self.friction
    }

    /// Sets the Coulomb coefficient between the bodies' surfaces (within one body too),
    /// smoothed below [`SUGGESTED_STICKING_SPEED`]: IPC's lagged friction
    /// ([`ContactModel::with_friction`]).
    ///
    /// # Errors
    /// [`BodyError::Contact`] with [`ContactError::Friction`] for a coefficient that is not
    /// finite and `>= 0`.
    pub fn set_friction(&mut self, coefficient: Real) -> Result<(), BodyError> {
        if !(coefficient.is_finite() && coefficient >= 0.0) {
            return Err(BodyError::Contact(ContactError::Friction));
        }
        self.friction = coefficient;
        Ok(())
    }

    /// What the contact model counted in the last step: candidate pairs, pair Hessians and
    /// frictional pairs.
    #[inline]
    #[must_use]
    pub fn contact_counts(&self) -> ContactCounts {
        self.counts
    }

    /// The smallest distance (m) between two primitives of the contact surface within
    /// `reach` (m) of each other now, or `None` if no pair is that close (0: touching).
    ///
    /// # Errors
    /// Those of [`ContactModel::smallest_distance`].
    pub fn smallest_gap(&mut self, reach: Real) -> Result<Option<Real>, ContactError> {
        let (model, parts) = self.contact_parts();
        model?.smallest_distance(parts.positions, reach)
    }

    /// The scene of a step of `dt` (s) under the world's gravity and ground.
    #[inline]
    #[must_use]
    pub fn scene(&self, dt: Real) -> Scene<'static, Vec3> {
        let scene = Scene::new(dt).with_gravity(self.gravity);
        match self.ground {
            Some(ground) => scene.with_ground(ground),
            None => scene,
        }
    }

    /// Advances every body by `dt` (s) under the world's gravity and ground, in contact with
    /// each other: [`step_with`](Self::step_with) of [`scene`](Self::scene)`(dt)`.
    ///
    /// # Errors
    /// As [`step_with`](Self::step_with).
    pub fn step(&mut self, dt: Real) -> Result<StepReport, StepError> {
        self.step_with(&self.scene(dt))
    }

    /// [`step`](Self::step) with rigid `colliders` besides the ground (see [`Collider`]).
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

    /// Advances every body by the scene's `dt` with the world's solver in `scene` (which
    /// replaces the world's gravity and ground for this step: colliders, external forces,
    /// fixed axes), one solve over every vertex with contact between all surfaces. A
    /// growable world whose contact lists fill up grows them and solves again from the same
    /// start.
    ///
    /// # Errors
    /// [`StepError::TimeStep`] or [`StepError::TimeStepTooSmall`] for a `dt` the steppers
    /// refuse, [`StepError::EmptyBody`] for a world without bodies, or the stepper's error (a
    /// contact list too small for a fixed-capacity world is
    /// [`MeshError::Contact`] with [`ContactError::Capacity`]), with every position and
    /// velocity restored bit for bit.
    pub fn step_with(&mut self, scene: &Scene<'_, Vec3>) -> Result<StepReport, StepError> {
        self.step_recording(scene, None)
    }

    /// [`step_with`](Self::step_with), and what each of the scene's colliders received from the
    /// world's bodies over the step into `reactions` (one per collider, in the scene's order):
    /// the impulse on it and its moment about its position, as
    /// [`Body::step_with_reactions`](crate::body::Body::step_with_reactions) reports them (the
    /// explicit stepper's record of its collider projections, or after an implicit step the
    /// momentum balance of each vertex touching a collider, the contact between the bodies
    /// taken out with the elastic forces; `docs/math.md` section 8.14). Friction between two
    /// bodies at a vertex that also touches a collider goes to the collider.
    ///
    /// # Errors
    /// [`StepError::LengthMismatch`] (buffer [`StepBuffer::Reactions`]) unless `reactions` has
    /// one entry per collider, before anything is touched; otherwise as
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
    /// [`Collider::with_mass`]) solved with every body of the world: a crate lying across two
    /// bodies, a lid on a stack, a box thrown into a pile (`docs/math.md` section 8.15). As
    /// [`Body::step_with_rigid_bodies`](crate::body::Body::step_with_rigid_bodies): each
    /// dynamic collider's end-of-step velocity is an unknown of the same implicit Euler step,
    /// the world steps with the collider at the pose that velocity gives it (one solve over
    /// every body, with their contact), the collider's momentum balance with the impulse the
    /// bodies applied gives its velocity again, and the two are iterated (Aitken's relaxation)
    /// until they agree within the world's [`coupling`](Self::coupling) tolerance. Every
    /// iteration is one step of the world's solver from the same start: the positions and
    /// velocities of every body and the explicit stepper's memory are put back before each
    /// iteration after the first (what else the world keeps between steps, the relaxation's
    /// preconditioner and Vertex Block Descent's colouring, depends on the meshes only).
    ///
    /// On return every dynamic collider has its new pose and velocities (its `position` is its
    /// centre of mass), and `reactions` what every collider received over the step, as in
    /// [`step_with_reactions`](Self::step_with_reactions). Static and kinematic colliders are
    /// not changed. The scene's own colliders must be empty: every collider goes in
    /// `colliders`. Contact between colliders is not solved; gravity is the scene's.
    ///
    /// ```
    /// # #[cfg(feature = "alloc")] {
    /// use softfem::body::VecStorage;
    /// use softfem::step::{Collider, HalfSpace, Reaction};
    /// use softfem::world::World;
    /// use softfem::{glam::{Quat, Vec3}, material::StableNeoHookean};
    ///
    /// // Two jelly cubes side by side on the ground and a 1 kg plank lying across both.
    /// let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.3)?; // Pa
    /// let mut world = World::<VecStorage, _>::new();
    /// world.add_box(Vec3::new(-0.22, 0.0, -0.1), Vec3::new(-0.02, 0.2, 0.1), [1; 3], 100.0, jelly)?;
    /// world.add_box(Vec3::new(0.02, 0.0, -0.1), Vec3::new(0.22, 0.2, 0.1), [1; 3], 100.0, jelly)?;
    /// world.set_gravity(Vec3::new(0.0, -9.81, 0.0));
    /// world.set_ground(Some(HalfSpace::new(Vec3::Y, 0.0)));
    /// // Wider than the cubes: collider contact is tested at the cubes' vertices.
    /// let half = Vec3::new(0.25, 0.02, 0.15); // m
    /// let inertia = Vec3::new(0.0076, 0.028, 0.021); // kg m^2: m/3 (b^2 + c^2), ...
    /// let plank = Collider::cuboid(Vec3::new(0.0, 0.22, 0.0), half, Quat::IDENTITY);
    /// let mut colliders = [plank.with_mass(1.0, inertia)];
    /// let mut reactions = [Reaction::ZERO];
    /// for _ in 0..30 {
    ///     let scene = world.scene(1.0 / 60.0);
    ///     world.step_with_rigid_bodies(&scene, &mut colliders, &mut reactions)?;
    /// }
    /// // The cubes carry the plank's weight, 9.81 N.
    /// assert!((reactions[0].force(1.0 / 60.0).y - 9.81).abs() < 0.02 * 9.81);
    /// # }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// Before anything is moved: [`StepError::SceneColliders`] if the scene has colliders,
    /// [`StepError::LengthMismatch`] (buffer [`StepBuffer::Reactions`]) unless `reactions`
    /// has one entry per collider, [`StepError::Collider`] for a collider out of range,
    /// [`StepError::TimeStep`] or [`StepError::TimeStepTooSmall`] for the scene's `dt`,
    /// [`StepError::CouplingSettings`] for coupling settings out of range,
    /// [`StepError::EmptyBody`] for a world without bodies and
    /// [`StepError::TooManyDynamicColliders`] beyond
    /// [`MAX_DYNAMIC_COLLIDERS`](crate::step::MAX_DYNAMIC_COLLIDERS). A soft step that fails
    /// returns its error (as [`step_with`](Self::step_with)'s) with every body's positions and
    /// velocities and every collider as they were before the call.
    pub fn step_with_rigid_bodies(
        &mut self,
        scene: &Scene<'_, Vec3>,
        colliders: &mut [Collider<'_>],
        reactions: &mut [Reaction],
    ) -> Result<CoupledReport, StepError> {
        self.step_with_rigid_bodies_and_attachments(scene, colliders, &[], reactions)
    }

    /// [`step_with_rigid_bodies`](Self::step_with_rigid_bodies) with vertices held at points of
    /// the colliders' frames, as
    /// [`Body::step_with_rigid_bodies_and_attachments`](crate::body::Body::step_with_rigid_bodies_and_attachments),
    /// each [`Attachment::vertex`] a vertex index of the world (body after body: add a body's
    /// first index, [`Part::vertices`]). A hard attachment pins its vertex (it stays pinned
    /// after the step: free it with [`set_pinned`](Self::set_pinned)) and moves it to its
    /// point on the collider at the step's end; a soft one pulls it there by a spring and a
    /// damper, terms of the implicit step (the explicit stepper refuses them). What holds each
    /// vertex joins its collider's reaction.
    ///
    /// ```
    /// # #[cfg(feature = "alloc")] {
    /// use softfem::body::VecStorage;
    /// use softfem::step::{Attachment, Collider, Reaction};
    /// use softfem::world::World;
    /// use softfem::{glam::{Quat, Vec3}, material::StableNeoHookean};
    ///
    /// // Two jellies hanging side by side from a static bar, one on springs and dampers.
    /// let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.3)?; // Pa
    /// let mut world = World::<VecStorage, _>::new();
    /// world.add_box(Vec3::new(-0.3, -0.2, -0.1), Vec3::new(-0.1, 0.0, 0.1), [1; 3], 100.0, jelly)?;
    /// world.add_box(Vec3::new(0.1, -0.2, -0.1), Vec3::new(0.3, 0.0, 0.1), [1; 3], 100.0, jelly)?;
    /// world.set_gravity(Vec3::new(0.0, -9.81, 0.0));
    /// let bar = Collider::cuboid(Vec3::new(0.0, 0.05, 0.0), Vec3::new(0.4, 0.05, 0.15), Quat::IDENTITY);
    /// let top: Vec<Attachment> = (0..world.vertex_count() as u32)
    ///     .filter(|&i| world.positions()[i as usize].y == 0.0)
    ///     .map(|i| {
    ///         let hold = Attachment::at(i, 0, &bar, world.positions()[i as usize]);
    ///         if world.positions()[i as usize].x > 0.0 { hold.with_spring(500.0, 5.0) } else { hold }
    ///     })
    ///     .collect();
    /// let (mut colliders, mut reactions) = ([bar], [Reaction::ZERO]);
    /// for _ in 0..60 {
    ///     let scene = world.scene(1.0 / 60.0);
    ///     world.step_with_rigid_bodies_and_attachments(&scene, &mut colliders, &top, &mut reactions)?;
    /// }
    /// // The bar carries both jellies: 2 x 0.8 kg.
    /// let weight = world.masses().iter().sum::<f32>() * 9.81;
    /// assert!((reactions[0].force(1.0 / 60.0).y + weight).abs() < 0.05 * weight);
    /// # }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`step_with_rigid_bodies`](Self::step_with_rigid_bodies), and before anything is
    /// moved [`StepError::TooManyAttachments`], [`StepError::AttachedVertex`] or
    /// [`StepError::AttachedCollider`] for an entry out of range, and
    /// [`StepError::SoftAttachmentSolver`] for a soft attachment with the explicit stepper. A
    /// failed step also puts back the attached vertices' pins.
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
        let soft = attachments.iter().any(Attachment::is_soft);
        if soft && matches!(self.solver, Solver::Explicit { .. }) {
            return Err(StepError::SoftAttachmentSolver);
        }
        // The attached vertices' pins and masses before the call, put back if it fails (the
        // masses after every soft step).
        let mut pins: heapless::Vec<(bool, Real), MAX_ATTACHMENTS> = heapless::Vec::new();
        for a in attachments {
            let v = a.vertex as usize;
            let pin = (
                self.pinned.slice().get(v).copied().unwrap_or(false),
                self.masses.slice().get(v).copied().unwrap_or(0.0),
            );
            if pins.push(pin).is_err() {
                return Err(StepError::TooManyAttachments {
                    limit: MAX_ATTACHMENTS,
                });
            }
        }
        let mass: Real = self.masses.slice().iter().sum();
        let vertex_mass = mass / n as Real;
        // The step's start, for every iteration after the first and for a failure.
        let memory = self.explicit_memory;
        let k = solver_vectors(&self.solver);
        let (start_positions, start_velocities) = coupling_slots(self.vectors.slice_mut(), n, k);
        copy_into(start_positions, self.positions.slice());
        copy_into(start_velocities, self.velocities.slice());
        let settings = self.coupling;
        let (dt, gravity) = (scene.dt, scene.gravity);
        let outcome = couple(
            colliders,
            (dt, gravity),
            &settings,
            vertex_mass,
            reactions,
            |colliders, reactions, iteration| {
                if iteration > 0 {
                    self.restore_coupling_start(memory);
                }
                self.hold_attached(attachments, colliders, (dt, gravity));
                let report = self.step_recording(&scene.with_colliders(colliders), Some(reactions));
                for (a, &(_, mass)) in attachments.iter().zip(&pins) {
                    if let Some(m) = self.masses.slice_mut().get_mut(a.vertex as usize) {
                        *m = mass;
                    }
                }
                let report = report?;
                self.add_attachment_reactions(attachments, colliders, dt, reactions);
                Ok((report, report.coupling_residual()))
            },
        );
        match outcome {
            Ok((step, coupling)) => Ok(CoupledReport { step, coupling }),
            Err(error) => {
                self.restore_coupling_start(memory);
                for (a, &(pinned, mass)) in attachments.iter().zip(&pins) {
                    let v = a.vertex as usize;
                    if let (Some(p), Some(m)) = (
                        self.pinned.slice_mut().get_mut(v),
                        self.masses.slice_mut().get_mut(v),
                    ) {
                        (*p, *m) = (pinned, mass);
                    }
                }
                self.stable_step = None;
                Err(error)
            }
        }
    }

    /// Before a soft step of a coupled step of `h` (s) under `gravity`: each hard-attached
    /// vertex pinned at its anchor at the step's end with the velocity that takes it there
    /// from its start, each free soft-attached one given the mass and start velocity that put
    /// its spring and damper into the step's objective (`SoftPull::inertia`).
    fn hold_attached(
        &mut self,
        attachments: &[Attachment],
        colliders: &[Collider<'_>],
        (h, gravity): (Real, Vec3),
    ) {
        for a in attachments {
            let v = a.vertex as usize;
            let Some(collider) = colliders.get(a.collider as usize) else {
                continue;
            };
            let (Some(pinned), Some(m), Some(x), Some(velocity)) = (
                self.pinned.slice_mut().get_mut(v),
                self.masses.slice_mut().get_mut(v),
                self.positions.slice_mut().get_mut(v),
                self.velocities.slice_mut().get_mut(v),
            ) else {
                continue;
            };
            if a.is_soft() {
                if !*pinned {
                    let pull = SoftPull::new(a, collider, *x, h);
                    (*m, *velocity) = pull.inertia((*m, *x, *velocity), (h, gravity));
                }
            } else {
                let anchor = end_anchor(a, collider, h);
                if !*pinned {
                    *pinned = true;
                    self.stable_step = None;
                }
                *velocity = (anchor - *x) / h;
                *x = anchor;
            }
        }
    }

    /// After a soft step of a coupled step: each hard-attached vertex's recorded impulse
    /// completed with its move at the step's start (`m (v - v0)`, `v0` its velocity at the
    /// coupled step's start: the soft step saw it pinned at its new velocity), then every
    /// attachment's share of its collider's reaction.
    fn add_attachment_reactions(
        &mut self,
        attachments: &[Attachment],
        colliders: &[Collider<'_>],
        h: Real,
        reactions: &mut [Reaction],
    ) {
        let n = self.vertex_count();
        let k = solver_vectors(&self.solver);
        let vectors = self.vectors.slice_mut();
        let (recorded, coupling) = vectors
            .split_at_mut_checked(n.saturating_mul(k.saturating_add(2)))
            .unwrap_or_default();
        let impulses = recorded
            .get_mut(n.saturating_mul(k)..n.saturating_mul(k.saturating_add(1)))
            .unwrap_or(&mut []);
        let (starts, start_velocities) = coupling.split_at_checked(n).unwrap_or_default();
        for a in attachments.iter().filter(|a| !a.is_soft()) {
            let v = a.vertex as usize;
            let masses = self.masses.slice();
            let velocities = self.velocities.slice();
            let rows = (masses.get(v), velocities.get(v), start_velocities.get(v));
            if let ((Some(&m), Some(&now), Some(&before)), Some(impulse)) = (rows, impulses.get_mut(v))
            {
                *impulse += (now - before) * m;
            }
        }
        let starts = starts.get(..n).unwrap_or(&[]);
        let (x, v) = (self.positions.slice(), self.velocities.slice());
        let state = (x, v, starts, self.pinned.slice());
        add_attachment_reactions(attachments, colliders, state, (impulses, h), reactions);
    }

    /// The coupling iteration's settings (see
    /// [`step_with_rigid_bodies`](Self::step_with_rigid_bodies)).
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

    /// Puts back the positions and velocities kept at the start of a coupled step, and the
    /// explicit stepper's `memory` of then.
    fn restore_coupling_start(&mut self, memory: ExplicitMemory) {
        let n = self.vertex_count();
        let k = solver_vectors(&self.solver);
        let (start_positions, start_velocities) = coupling_slots(self.vectors.slice_mut(), n, k);
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
            _ => 1,
        };
        let record = reactions.is_some();
        if record {
            let n = self.vertex_count();
            let k = solver_vectors(&self.solver);
            let (_, _, start_velocities) = recording_slots(self.vectors.slice_mut(), n, k);
            copy_into(start_velocities, self.velocities.slice());
        }
        loop {
            let outcome = self.solve(scene, substeps, record);
            if let Err(StepError::Mesh(MeshError::Contact(ContactError::Capacity {
                buffer,
                needed,
                ..
            }))) = outcome
                && self.grow(buffer, needed)
            {
                continue;
            }
            let report = outcome?;
            if let Some(reactions) = reactions {
                self.collider_reactions(scene, &report, reactions)?;
            }
            return Ok(report);
        }
    }

    /// After a step recorded for reactions: the contact impulse at each vertex (the explicit
    /// stepper's record, or the implicit momentum balance from the start velocities with the
    /// elastic and contact forces of the world's model at the result), then each collider's
    /// reaction.
    fn collider_reactions(
        &mut self,
        scene: &Scene<'_, Vec3>,
        report: &StepReport,
        reactions: &mut [Reaction],
    ) -> Result<(), StepError> {
        let n = self.vertex_count();
        let k = solver_vectors(&self.solver);
        let explicit = matches!(report, StepReport::Explicit(_));
        let (model, parts) = self.contact_parts();
        let model = model.map_err(|error| StepError::Mesh(MeshError::Contact(error)))?;
        let (forces, impulses, start_velocities) = recording_slots(parts.vectors, n, k);
        recorded_reactions(
            &model,
            scene,
            (parts.masses, parts.pinned),
            (&*parts.positions, &*parts.velocities),
            (forces, impulses, start_velocities),
            explicit,
            reactions,
        )
    }

    /// Grows the contact list `buffer` to hold `needed` entries with room to spare; `false`
    /// if it cannot (a fixed capacity, an allocation refused, a buffer that is not a list).
    fn grow(&mut self, buffer: ContactBuffer, needed: usize) -> bool {
        // Half again as many, or exactly as many where a fixed capacity has no more room.
        let room = needed.saturating_add(needed / 2);
        match buffer {
            ContactBuffer::VertexTrianglePairs => {
                grow_to(&mut self.vertex_triangle, room, needed, [0; 2])
            }
            ContactBuffer::EdgeEdgePairs => grow_to(&mut self.edge_edge, room, needed, [0; 2]),
            ContactBuffer::PairHessians => {
                grow_to(&mut self.pair_hessians, room, needed, PairHessian::ZERO)
            }
            ContactBuffer::FrictionPairs => {
                grow_to(&mut self.friction_pairs, room, needed, FrictionPair::ZERO)
            }
            _ => false,
        }
    }

    /// The contact model over the world's bodies and buffers (or the contact surface's
    /// complaint) and what the solvers take beside it.
    #[allow(clippy::type_complexity)]
    fn contact_parts(
        &mut self,
    ) -> (
        Result<ContactModel<'_, WorldElastic<'_, M>>, ContactError>,
        SolverParts<'_>,
    ) {
        let n = self.positions.slice().len();
        let barrier = self.barrier();
        let elastic = WorldElastic {
            tets: self.tets.slice(),
            rest: self.rest_data.slice(),
            parts: self.parts.slice(),
            vertex_count: n,
            #[cfg(feature = "rayon")]
            threads: self.threads.as_ref(),
        };
        let surface = ContactSurface {
            vertices: self
                .surface_vertex_list
                .slice()
                .get(..self.surface_vertices)
                .unwrap_or(&[]),
            edges: self
                .surface_edge_list
                .slice()
                .get(..self.surface_edges)
                .unwrap_or(&[]),
            triangles: self.triangles.slice(),
        };
        let buffers = ContactBuffers {
            slots: self.slots.slice_mut(),
            entries: self.entries.slice_mut(),
            vertex_triangle: self.vertex_triangle.slice_mut(),
            edge_edge: self.edge_edge.slice_mut(),
            hessians: self.pair_hessians.slice_mut(),
            friction: self.friction_pairs.slice_mut(),
            reuse: CandidateReuse {
                bounds: self.reuse_bounds.slice_mut(),
                vertex_triangle: self.reuse_vertex_triangle.slice_mut(),
                edge_edge: self.reuse_edge_edge.slice_mut(),
            },
        };
        let mut model = ContactModel::new(
            elastic,
            surface,
            self.rest_positions.slice(),
            barrier,
            buffers,
        );
        if self.friction > 0.0 {
            model = model.and_then(|m| m.with_friction(self.friction, SUGGESTED_STICKING_SPEED));
        }
        let parts = SolverParts {
            masses: self.masses.slice(),
            pinned: self.pinned.slice(),
            positions: self.positions.slice_mut(),
            velocities: self.velocities.slice_mut(),
            vectors: self.vectors.slice_mut(),
            scalars: self.scalars.slice_mut(),
            blocks: self.blocks.slice_mut(),
            hessians: self.hessians.slice_mut(),
            indices: (
                self.vertex_indices.slice_mut(),
                self.tet_indices.slice_mut(),
            ),
        };
        (model, parts)
    }

    /// One solve of the world's solver in `scene`.
    fn solve(
        &mut self,
        scene: &Scene<'_, Vec3>,
        substeps: u32,
        record: bool,
    ) -> Result<StepReport, StepError> {
        let solver = self.solver;
        let solver_vectors = solver_vectors(&solver);
        let ready = self.preconditioner_ready;
        let memory = self.explicit_memory;
        let mut topology = self.topology;
        let (model, parts) = self.contact_parts();
        let model = model.map_err(|error| StepError::Mesh(MeshError::Contact(error)))?;
        let SolverParts {
            masses,
            pinned,
            positions: x,
            velocities: v,
            vectors,
            scalars,
            blocks,
            hessians,
            indices,
        } = parts;
        let n = masses.len();
        let (vectors, recorded) = vectors
            .split_at_mut_checked(n.saturating_mul(solver_vectors))
            .unwrap_or_default();
        let impulses = match record {
            true => recorded.get_mut(..n).unwrap_or(&mut []),
            false => &mut [],
        };
        let (outcome, ready, memory) = match solver {
            Solver::Newton(settings) => {
                let mut scratch = NewtonScratch::new(vectors, blocks, hessians);
                let outcome =
                    newton_step(&model, masses, pinned, scene, &settings, x, v, &mut scratch);
                (outcome.map(StepReport::Newton), ready, memory)
            }
            Solver::Explicit { settings, .. } => {
                let settings = settings.with_substeps(substeps);
                let mut scratch = ExplicitScratch::resume(vectors, memory).with_impulses(impulses);
                let outcome =
                    explicit_step(&model, masses, pinned, scene, &settings, x, v, &mut scratch);
                (outcome.map(StepReport::Explicit), ready, scratch.memory())
            }
            Solver::Vbd(settings) => {
                let (sweeps, gradient) =
                    vectors.split_at_mut(scratch_len::vbd(n).min(vectors.len()));
                let contact = ContactBuffersVbd {
                    gradient,
                    blocks,
                    nearest: scalars,
                };
                let mut scratch = VbdScratch::split(sweeps, indices, contact, topology);
                let outcome =
                    vbd_step(&model, masses, pinned, scene, &settings, x, v, &mut scratch);
                topology = scratch.topology();
                (outcome.map(StepReport::Vbd), ready, memory)
            }
            Solver::Relax(settings) => {
                let mut scratch = RelaxScratch::resume(vectors, scalars, ready);
                let outcome =
                    relax_step(&model, masses, pinned, scene, &settings, x, v, &mut scratch);
                let ready = scratch.stiffness_ready();
                (outcome.map(StepReport::Relax), ready, memory)
            }
            // `set_solver` refuses it: the world never holds it.
            Solver::Auto(_) => return Err(StepError::Mesh(MeshError::Contact(
                ContactError::BuffersInUse,
            ))),
        };
        let counts = model.counts();
        let reuse_needed = model.reuse_needed();
        self.counts = counts;
        // A reuse list too short for a motion's pairs made that step run the grid for every
        // query (the same results, slower): grown for the next step where the storage can.
        match reuse_needed {
            Some((ContactBuffer::VertexTrianglePairs, needed)) => {
                let room = needed.saturating_add(needed / 2);
                let _ = grow_to(&mut self.reuse_vertex_triangle, room, needed, [0; 2]);
            }
            Some((ContactBuffer::EdgeEdgePairs, needed)) => {
                let room = needed.saturating_add(needed / 2);
                let _ = grow_to(&mut self.reuse_edge_edge, room, needed, [0; 2]);
            }
            _ => {}
        }
        self.preconditioner_ready = ready;
        self.explicit_memory = memory;
        self.topology = topology;
        outcome
    }
}

#[cfg(feature = "rayon")]
impl<S: WorldStorage, M: Material> World<S, M> {
    /// Refits what the parallel passes keep to the world's bodies (after a body was added or
    /// removed). Where the memory is refused they are dropped, and the passes run on the
    /// calling thread until the next refit (the same bits).
    fn fit_threads(&mut self) {
        if let Some(threads) = &mut self.threads {
            let _ = threads.fit(self.parts.slice(), self.tets.slice());
        }
    }

    /// The number of threads of the world's pool ([`set_threads`](Self::set_threads)), or 0
    /// for none (the passes on the calling thread).
    #[must_use]
    pub fn threads(&self) -> usize {
        self.threads
            .as_ref()
            .map_or(0, |threads| threads.pool().current_num_threads())
    }
}

/// The world on all cores (feature `rayon`).
#[cfg(feature = "rayon")]
impl<S: WorldStorage, M: Material + Sync> World<S, M> {
    /// Runs the elastic passes of every step on a rayon pool of `threads` threads of the
    /// world's own, or on the calling thread for `0` (the default).
    ///
    /// On the pool the bodies run in parallel, one task per body: the forces, the fused
    /// energy-and-force pass, the projected Hessians, their products and diagonal blocks, each
    /// body writing only its own range of vertices (or of Hessians), the energies added in body
    /// order afterwards; the steppers' passes over the vertices run in blocks on the pool
    /// (as [`ParallelTetElastic`](crate::parallel::ParallelTetElastic)'s), and Vertex Block
    /// Descent runs each body's colours in parallel. Every position and velocity is **bit for
    /// bit** that of the world on one thread, at any thread count. The contact model's work
    /// (broad phase, barrier, friction, continuous collision detection) and Newton's
    /// conjugate gradients stay on the calling thread; a world of one body gains only from
    /// the vertex passes and VBD's colours.
    ///
    /// ```
    /// # #[cfg(feature = "alloc")] {
    /// use softfem::body::VecStorage;
    /// use softfem::world::World;
    /// use softfem::{glam::Vec3, material::NeoHookean};
    ///
    /// let rubber = NeoHookean::from_young_poisson(1e6, 0.4)?;
    /// let mut one = World::<VecStorage, _>::new();
    /// one.add_box(Vec3::ZERO, Vec3::splat(0.1), [2; 3], 1000.0, rubber)?;
    /// one.add_box(Vec3::new(0.0, 0.0, 0.1005), Vec3::new(0.1, 0.1, 0.2), [2; 3], 1000.0, rubber)?;
    /// one.set_gravity(Vec3::new(0.0, 0.0, -9.81));
    /// let mut two = World::<VecStorage, _>::new();
    /// two.add_box(Vec3::ZERO, Vec3::splat(0.1), [2; 3], 1000.0, rubber)?;
    /// two.add_box(Vec3::new(0.0, 0.0, 0.1005), Vec3::new(0.1, 0.1, 0.2), [2; 3], 1000.0, rubber)?;
    /// two.set_gravity(Vec3::new(0.0, 0.0, -9.81));
    /// two.set_threads(2)?;
    /// for _ in 0..3 {
    ///     one.step(0.01)?;
    ///     two.step(0.01)?;
    /// }
    /// assert_eq!(one.positions(), two.positions()); // and bit for bit
    /// # }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// rayon's, if the pool cannot be built; the world keeps its pool (or none) then.
    pub fn set_threads(&mut self, threads: usize) -> Result<(), rayon::ThreadPoolBuildError> {
        if threads == 0 {
            self.set_pool(None);
            return Ok(());
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        self.set_pool(Some(std::sync::Arc::new(pool)));
        Ok(())
    }

    /// As [`set_threads`](Self::set_threads), on `pool` (shared with other worlds or work:
    /// its thread count), or on the calling thread for `None`.
    pub fn set_pool(&mut self, pool: Option<std::sync::Arc<rayon::ThreadPool>>) {
        self.threads = pool.map(threads::Threads::new);
        self.fit_threads();
    }
}

impl<const B: usize, const V: usize, const T: usize, const C: usize, const P: usize, M: Material>
    World<FixedWorld<B, V, T, C, P>, M>
{
    /// A fixed-capacity world with no bodies, as [`new`](World::new): a `const` value, so the
    /// world can be a `static` (in `.bss`, never on the stack) and built in place with
    /// [`add_box`](World::add_box) and [`add_body`](World::add_body). This is the firmware way,
    /// and the way to hold a large fixed world anywhere: [`new`](World::new) returns the world
    /// by value, through the stack.
    ///
    /// ```
    /// use softfem::world::{FixedWorld, World};
    /// use softfem::{glam::Vec3, material::NeoHookean};
    ///
    /// // At most 2 bodies, 64 vertices, 100 tetrahedra, 4224 surface entries, 64 active pairs.
    /// type Small = World<FixedWorld<2, 64, 100, 4224, 64>, NeoHookean>;
    /// static WORLD: std::sync::Mutex<Small> = std::sync::Mutex::new(Small::empty());
    ///
    /// let mut world = WORLD.lock().unwrap();
    /// let rubber = NeoHookean::from_young_poisson(1e6, 0.4)?;
    /// world.add_box(Vec3::ZERO, Vec3::splat(0.1), [2; 3], 1000.0, rubber)?;
    /// let (low, high) = (Vec3::new(0.0, 0.0, 0.11), Vec3::new(0.1, 0.1, 0.21));
    /// world.add_box(low, high, [1; 3], 1000.0, rubber)?;
    /// world.set_gravity(Vec3::new(0.0, 0.0, -9.81));
    /// world.step(0.01)?;
    /// assert_eq!((world.body_count(), world.vertex_count()), (2, 35));
    /// assert!(world.velocities().iter().all(|v| v.z < 0.0)); // both falling
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    #[must_use]
    pub const fn empty() -> Self {
        unbuilt_world!(
            heapless::Vec::new(),
            heapless_empty,
            Fixed::filled,
            heapless_empty
        )
    }
}

/// The per-vertex arrays and scratch a solve takes beside the model.
struct SolverParts<'a> {
    masses: &'a [Real],
    pinned: &'a [bool],
    positions: &'a mut [Vec3],
    velocities: &'a mut [Vec3],
    vectors: &'a mut [Vec3],
    scalars: &'a mut [Real],
    blocks: &'a mut [Mat3],
    hessians: &'a mut [TetHessian],
    /// Vertex Block Descent's index buffers: per vertex, per tetrahedron.
    indices: (&'a mut [u32], &'a mut [u32]),
}

/// Grows `list` by `count` entries of `fill`; `false` (the list unchanged) if they do not fit.
fn extend_by<X: Copy, L: List<X>>(list: &mut L, count: usize, fill: X) -> bool {
    let start = list.slice().len();
    for _ in 0..count {
        if !list.extend(&[fill]) {
            list.truncate(start);
            return false;
        }
    }
    true
}

/// The vectors per vertex of `solver`'s scratch in a world (a world never holds the automatic
/// solver: 0).
fn solver_vectors(solver: &Solver) -> usize {
    match solver {
        Solver::Newton(_) => 9,
        Solver::Relax(_) | Solver::Explicit { .. } => 5,
        // The sweeps' five and the contact's gradient.
        Solver::Vbd(_) => 6,
        Solver::Auto(_) => 0,
    }
}

/// The vectors per vertex of a world's scratch beyond its solver's: the impulses and start
/// velocities of a step recorded for reactions (`recording_slots`), then a coupled step's
/// start positions and velocities (`coupling_slots`).
const EXTRA_VECTORS: usize = 4;

/// The vectors of the scratch where a coupled step keeps the positions and velocities of its
/// start: after the `k` of the solver and the two of a recorded step.
fn coupling_slots(vectors: &mut [Vec3], n: usize, k: usize) -> (&mut [Vec3], &mut [Vec3]) {
    let start = n.saturating_mul(k.saturating_add(2));
    let rest = vectors.get_mut(start..).unwrap_or(&mut []);
    let (positions, rest) = rest.split_at_mut_checked(n).unwrap_or_default();
    (positions, rest.get_mut(..n).unwrap_or(&mut []))
}

/// Sizes `buffer` to `room` entries of `fill`, or else to `needed`; `false` if neither fits.
fn grow_to<X: Copy, B: Slots<X>>(buffer: &mut B, room: usize, needed: usize, fill: X) -> bool {
    buffer.resize(room, fill) || buffer.resize(needed, fill)
}

/// Sizes `buffer` to `wanted` entries of `fill`, or to the most a fixed capacity below that
/// holds (found by bisection); returns the length.
fn resize_up_to<X: Copy, B: Slots<X>>(buffer: &mut B, wanted: usize, fill: X) -> usize {
    if buffer.resize(wanted, fill) {
        return wanted;
    }
    // `fits` fits (length zero always does), `fails` does not.
    let (mut fits, mut fails) = (0, wanted);
    while fails - fits > 1 {
        let middle = fits + (fails - fits) / 2;
        if buffer.resize(middle, fill) {
            fits = middle;
        } else {
            fails = middle;
        }
    }
    let _ = buffer.resize(fits, fill);
    fits
}

/// `source` into `target`, entry by entry (no panic path for lengths the optimiser cannot
/// prove equal).
fn copy_into<X: Copy>(target: &mut [X], source: &[X]) {
    for (slot, &value) in target.iter_mut().zip(source) {
        *slot = value;
    }
}

//! Body–body and self contact inside the implicit solvers: [`ContactModel`] wraps an elastic
//! model so that its energy gains the contact potential of Incremental Potential Contact and its
//! admissible steps end before any two surface primitives meet (`docs/math.md` section 8.10).
//!
//! The descent solvers minimise the wrapped model's energy as they minimise any other: the
//! relaxation and gradient descent through [`ElasticEnergy`], Newton's method through
//! [`ElasticHessian`], whose pair Hessians ride along with the elements'. What the wrapper adds
//! beyond an energy is [`ElasticEnergy::admissible_step`]: continuous collision detection over
//! the straight motion from an iterate to a trial point, which the descent loop consults before
//! it evaluates any trial point or initial guess (`step/descent/descend.rs`).
//!
//! # The guarantee
//! If the start positions of a step are free of intersections, no point the solver accepts is
//! reached through an intersection: every iterate, initial guesses included, is joined to the
//! one before by a straight motion that [`ccd::step_bound`] found free of contact, for the pairs
//! [`motion_pairs`] finds (every pair whose boxes over the motion overlap). The result of a step
//! is one of those iterates, so surfaces that started apart end apart, with every distance
//! positive. The conditions are those of [`ccd`](super::ccd#the-guarantee): pairs must start
//! more than the rounding floor `xi` apart (about `4e-6 m` at 1 m from the origin in f32), and
//! the boundary triangles must be well shaped. Where no admissible step can be found (a pair
//! touching at the start), the line search fails and the report says the step did not converge;
//! a contact buffer that is too small fails the step with [`MeshError::Contact`] naming the
//! buffer and the count it needs, and the caller's state is restored.
//!
//! # Cost
//! Every evaluation of the energy needs the pairs within the gap and the barrier's gradient;
//! every trial point the pairs of its motion and the CCD; every Newton iteration the pairs'
//! projected Hessians. Without [`CandidateReuse`] buffers each of those queries runs the grid
//! of the broad phase; with them, a line search runs it once, for its motion with the gap, and
//! answers the other queries inside that motion's boxes from the kept pairs, with the same
//! results to the bit (measured on the pile of eight balls, `examples/pile`, 0.3 s: 9.9 s of
//! CPU time without, 6.0 s with, Intel Xeon with AVX-512, 2 vCPUs, load 6). `benches/contact.rs`
//! measures the parts against a force pass.

use core::cell::{Cell, Ref, RefCell, RefMut};

use crate::error::{ContactBuffer, ContactError, MeshError};

use super::super::super::element::TetHessian;
use super::super::super::math::sqrt;
use super::super::super::types::{Mat3, Real, Vec3};
use super::super::model::{ElasticEnergy, ElasticHessian, ElasticModel};
use super::super::vertex_pass::VertexPass;
use super::Contact;
use super::barrier::barrier_derivatives;
use super::boundary::ContactSurface;
use super::broad_phase::{
    BroadPhaseScratch, CandidatePairs, filter_pairs, motion_pairs, proximity_pairs,
};
use super::ccd::{self, Separation};
use super::distance::{
    PairDistanceGradient, edge_edge_distance_gradient, edge_edge_mollifier_value,
    edge_edge_squared_distance, point_triangle_distance_gradient, point_triangle_squared_distance,
};
use super::friction::Slip;
use super::potential::{ContactBarrier, ContactPotential, Pair, PairHessian, add_hessian_product};

/// The caller-owned buffers of a [`ContactModel`]: the broad phase's hash table, the candidate
/// pairs it finds and the active pairs' projected Hessians.
///
/// Sizes: `slots` and `entries` as [`scratch_len::broad_phase`] gives them for the surface;
/// `vertex_triangle` and `edge_edge` hold the candidate pairs of one query (a few per surface
/// vertex and edge for a resting contact; a query that finds more fails with
/// [`ContactError::Capacity`] naming the list and the exact count); `hessians` one entry per
/// active pair (closer than the gap) at an iterate (Newton's method only; empty for the other
/// solvers); `friction` one per active pair at the start of a step (with friction only).
///
/// `reuse` lets a line search find its pairs with one grid query ([`CandidateReuse`]; empty,
/// the default, runs the grid for every query). `Default` is every buffer empty, to fill the
/// fields a model does not need with `..Default::default()`.
///
/// [`scratch_len::broad_phase`]: super::super::scratch_len::broad_phase
#[derive(Debug, Default)]
pub struct ContactBuffers<'a> {
    /// The hash table's slots.
    pub slots: &'a mut [u32],
    /// The hash table's entries.
    pub entries: &'a mut [u32],
    /// The (vertex, triangle) candidate pairs.
    pub vertex_triangle: &'a mut [[u32; 2]],
    /// The (edge, edge) candidate pairs.
    pub edge_edge: &'a mut [[u32; 2]],
    /// The projected Hessians of the active pairs.
    pub hessians: &'a mut [PairHessian],
    /// The frictional pairs lagged at the start of a step (one per active pair then; empty
    /// without friction).
    pub friction: &'a mut [FrictionPair],
    /// The pairs of the last motion, kept for the queries of its line search.
    pub reuse: CandidateReuse<'a>,
}

/// The caller-owned buffers with which a [`ContactModel`] answers the broad-phase queries of a
/// line search from one grid query: candidate reuse. All empty (the default), every query
/// runs the grid.
///
/// When a solver asks whether the motion `x -> y` is admissible
/// ([`ElasticEnergy::admissible_step`]), the model finds the pairs of that motion with the
/// barrier's gap into these lists and keeps each surface vertex's box over the motion in
/// `bounds`. A later query whose positions all lie in those boxes (the trial point's energy
/// and gradient, the Hessian where it is accepted, a backtracked motion, the next iteration's
/// start) takes its pairs from the kept lists by the boxes' overlap alone, which gives exactly
/// the pairs a grid query finds, in the same order, so every result has the same bits with and
/// without reuse. A motion that leaves the boxes runs the grid again and keeps its pairs.
///
/// Sizes: `bounds` two per surface vertex (shorter: no reuse); the lists as many pairs as a
/// motion finds with the gap, more than one configuration's. Where a motion's pairs do not fit,
/// every query runs the grid until the next solve, and [`ContactModel::reuse_needed`] names the
/// list and the count it needed.
#[derive(Debug, Default)]
pub struct CandidateReuse<'a> {
    /// Per surface vertex (in the surface's vertex order), the lower and upper corners of its
    /// box over the kept motion (m).
    pub bounds: &'a mut [Vec3],
    /// The kept (vertex, triangle) pairs.
    pub vertex_triangle: &'a mut [[u32; 2]],
    /// The kept (edge, edge) pairs.
    pub edge_edge: &'a mut [[u32; 2]],
}

/// Whether every surface vertex lies at `positions` inside its box in `bounds`; `false` where
/// `bounds` is too short, a vertex is missing or a position is NaN.
fn within_bounds(surface: &ContactSurface<'_>, bounds: &[Vec3], positions: &[Vec3]) -> bool {
    bounds.len() >= 2 * surface.vertices.len()
        && surface
            .vertices
            .iter()
            .zip(bounds.chunks_exact(2))
            .all(
                |(&vertex, corners)| match (positions.get(vertex as usize), corners) {
                    (Some(&x), &[lo, hi]) => lo.cmple(x).all() && x.cmple(hi).all(),
                    _ => false,
                },
            )
}

/// The state of a [`ContactModel`]'s candidate reuse.
#[derive(Clone, Copy, Debug, Default)]
struct ReuseState {
    /// The lengths of the kept lists while they hold a motion's pairs and `bounds` its boxes.
    kept: Option<[usize; 2]>,
    /// A motion's pairs did not fit (until the next solve): every query runs the grid.
    overflowed: bool,
}

/// One frictional pair of a [`ContactModel`], lagged at the start of a step (`docs/math.md`
/// section 8.11): the pair's four vertices and the weights `w_k` of its closest points
/// (`r = sum_k w_k x_k` is the vector between them: `[1, -b0, -b1, -b2]` for a point and a
/// triangle with barycentric `b`, `[1 - s, s, -(1 - t), -t]` for two edges), the unit normal
/// `r / |r|`, `r` itself at the start and the friction force factor `mu lambda` (N). `Default`
/// is an empty pair (for sizing buffers).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrictionPair {
    vertices: [u32; 4],
    weights: [Real; 4],
    normal: Vec3,
    anchor: Vec3,
    force: Real,
    /// The tangent block `mu lambda H` (N/m) Newton's method takes at the last Hessian
    /// evaluation (see [`friction_block`]).
    block: Mat3,
}

impl FrictionPair {
    /// An empty pair (for filling buffers, also in a `const`): as `Default`.
    pub const ZERO: FrictionPair = FrictionPair {
        vertices: [0; 4],
        weights: [0.0; 4],
        normal: Vec3::ZERO,
        anchor: Vec3::ZERO,
        force: 0.0,
        block: Mat3::ZERO,
    };

    /// The four vertices.
    #[inline]
    pub fn vertices(&self) -> [u32; 4] {
        self.vertices
    }

    /// The friction force factor `mu lambda` (N): the force the pair resists sliding with.
    #[inline]
    pub fn force(&self) -> Real {
        self.force
    }

    /// The relative position `r = sum_k w_k x_k` (m) of the pair's closest points at `x`.
    #[inline]
    fn relative(&self, positions: &[Vec3]) -> Vec3 {
        let mut r = Vec3::ZERO;
        for (&vertex, &weight) in self.vertices.iter().zip(&self.weights) {
            if let Some(&x) = positions.get(vertex as usize) {
                r += x * weight;
            }
        }
        r
    }
}

/// What the contact of the last evaluation found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ContactCounts {
    /// Candidate (vertex, triangle) pairs of the last energy evaluation.
    pub vertex_triangle: usize,
    /// Candidate (edge, edge) pairs of the last energy evaluation.
    pub edge_edge: usize,
    /// Pair Hessians stored by the last [`ElasticHessian::projected_hessians`] call.
    pub hessians: usize,
    /// Frictional pairs lagged at the start of the last step.
    pub friction: usize,
    /// Broad-phase grid queries run by the model since it was made.
    pub grid_queries: usize,
    /// Queries answered from the pairs kept by candidate reuse ([`CandidateReuse`]) since the
    /// model was made.
    pub reused_queries: usize,
}

/// The most passes of impulses the explicit stepper's contact makes in one substep before its
/// failsafe ([`ContactModel`]'s `limit_motion`).
pub const IMPACT_PASSES: usize = 4;

/// An elastic model with body–body and self contact between the primitives of `surface`: the
/// energy `E(x) + B(x)`, `B` the barrier potential of [`ContactPotential`] over the pairs
/// within the gap, and the steps admitted by continuous collision detection (see the
/// [module docs](self)).
///
/// `M` is any model over all bodies' vertices (one position array); the surface names their
/// boundary triangles, edges and vertices by the same indices. Several bodies in one model are
/// one mesh of several disconnected parts; a body folding onto itself is self contact, found
/// the same way (primitives sharing a vertex are never paired).
///
/// The buffers are borrowed for the model's life and used through a [`RefCell`]: the model is
/// not `Sync` (the solvers that need a `Sync` model, VBD's parallel sweep, do not take it), and
/// a method called from within another (never by the solvers) fails with
/// [`ContactError::BuffersInUse`].
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::generate::{BoxSplit, box_counts, fill_box};
/// use softfem::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};
/// use softfem::element::TetRest;
/// use softfem::material::NeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::contact::boundary::ContactSurface;
/// use softfem::step::contact::model::{ContactBuffers, ContactModel};
/// use softfem::step::contact::potential::{ContactBarrier, PairHessian};
/// use softfem::step::{ElasticEnergy, TetElastic, scratch_len};
///
/// // Two 1 cm cubes, the second 1 mm above the first.
/// let (nv, nt) = box_counts(1, 1, 1, BoxSplit::Kuhn6)?;
/// let mut positions = vec![Vec3::ZERO; 2 * nv];
/// let mut tets = vec![[0u32; 4]; 2 * nt];
/// for (k, z) in [0.0, 0.011].into_iter().enumerate() {
///     let min = Vec3::new(0.0, 0.0, z);
///     let (x, t) = (&mut positions[k * nv..][..nv], &mut tets[k * nt..][..nt]);
///     fill_box(min, min + Vec3::splat(0.01), 1, 1, 1, BoxSplit::Kuhn6, x, t)?;
///     t.iter_mut().for_each(|tet| tet.iter_mut().for_each(|v| *v += (k * nv) as u32));
/// }
/// let mut faces = vec![BoundaryFace::default(); boundary_scratch_len(tets.len())];
/// let triangles: Vec<[u32; 3]> = boundary_faces(&tets, positions.len(), &mut faces)?
///     .iter()
///     .map(|face| face.triangle)
///     .collect();
/// let (mut vertices, mut edges) = (
///     vec![0; scratch_len::boundary_vertices(triangles.len())],
///     vec![[0; 2]; scratch_len::boundary_edges(triangles.len())],
/// );
/// let surface =
///     ContactSurface::from_triangles(&triangles, positions.len(), &mut vertices, &mut edges)?;
/// let lengths =
///     scratch_len::broad_phase(surface.vertices.len(), surface.edges.len(), triangles.len());
/// let (mut slots, mut entries) = (vec![0; lengths.slots], vec![0; lengths.entries]);
/// let (mut vt, mut ee) = (vec![[0; 2]; 256], vec![[0; 2]; 256]);
/// let mut hessians = vec![PairHessian::default(); 512];
///
/// let mut rest_data = vec![TetRest::default(); tets.len()];
/// let mesh = TetMesh::new(&positions, &tets, &mut rest_data)?;
/// let elastic = TetElastic::new(mesh, NeoHookean::from_young_poisson(1e5, 0.3)?);
/// let barrier = ContactBarrier { stiffness: 1e6, gap: 2e-3 };
/// let buffers = ContactBuffers {
///     slots: &mut slots,
///     entries: &mut entries,
///     vertex_triangle: &mut vt,
///     edge_edge: &mut ee,
///     hessians: &mut hessians,
///     ..Default::default() // no friction, no candidate reuse
/// };
/// let model = ContactModel::new(elastic, surface, &positions, barrier, buffers)?;
///
/// // The faces 1 mm apart are within the 2 mm gap: the barrier pushes them apart.
/// let mut forces = vec![Vec3::ZERO; positions.len()];
/// let energy = model.energy_and_add_forces(&positions, &mut forces)?;
/// assert!(energy > 0.0);
/// assert!(forces[nv].z > 0.0 && forces[nv - 1].z < 0.0);
/// // Moving the upper cube 2 mm down would pass through: the step is cut before contact.
/// let moved: Vec<Vec3> = positions
///     .iter()
///     .enumerate()
///     .map(|(i, &p)| if i >= nv { p - Vec3::Z * 0.002 } else { p })
///     .collect();
/// let t = model.admissible_step(&positions, &moved)?;
/// assert!(t > 0.0 && t < 0.5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct ContactModel<'a, M> {
    model: M,
    surface: ContactSurface<'a>,
    rest_positions: &'a [Vec3],
    barrier: ContactBarrier,
    separation: Separation,
    buffers: RefCell<ContactBuffers<'a>>,
    counts: Cell<ContactCounts>,
    /// The Coulomb coefficient between surfaces (0: frictionless).
    friction: Real,
    /// `eps_v` (m/s).
    sticking_speed: Real,
    /// The step `h` (s) of the solve under way (0 quasi-static).
    h: Cell<Real>,
    reuse: Cell<ReuseState>,
    /// The reuse list that was too short for a motion's pairs, and the count it needed.
    reuse_needed: Cell<Option<(ContactBuffer, usize)>>,
}

impl<'a, M: ElasticModel<Vector = Vec3>> ContactModel<'a, M> {
    /// `model` with contact between the primitives of `surface` (global vertex indices into
    /// `model`'s vertices), the edge–edge mollifier measured at `rest_positions` (m, one per
    /// vertex), the barrier `barrier` and the caller's `buffers`. The CCD keeps
    /// [`Separation::DEFAULT`].
    ///
    /// # Errors
    /// [`ContactError::Gap`] or [`ContactError::Stiffness`] for a barrier that is not finite
    /// and `>= 0`; [`ContactError::BufferLength`] naming [`ContactBuffer::RestPositions`] if
    /// `rest_positions` does not have one entry per vertex of `model`;
    /// [`ContactError::IndexOutOfRange`] for the first surface primitive naming a vertex beyond
    /// them; [`ContactError::NonFinitePosition`] for a rest position that is not finite.
    pub fn new(
        model: M,
        surface: ContactSurface<'a>,
        rest_positions: &'a [Vec3],
        barrier: ContactBarrier,
        buffers: ContactBuffers<'a>,
    ) -> Result<Self, ContactError> {
        let vertex_count = model.vertex_count();
        if rest_positions.len() != vertex_count {
            return Err(ContactError::BufferLength {
                buffer: ContactBuffer::RestPositions,
                expected: vertex_count,
                actual: rest_positions.len(),
            });
        }
        // Every check of the potential (barrier, indices, finite rest positions), on no pairs.
        ContactPotential {
            barrier,
            surface,
            pairs: CandidatePairs::default(),
            rest_positions,
        }
        .energy(rest_positions)?;
        Ok(ContactModel {
            model,
            surface,
            rest_positions,
            barrier,
            separation: Separation::DEFAULT,
            buffers: RefCell::new(buffers),
            counts: Cell::new(ContactCounts::default()),
            friction: 0.0,
            sticking_speed: 0.0,
            h: Cell::new(0.0),
            reuse: Cell::new(ReuseState::default()),
            reuse_needed: Cell::new(None),
        })
    }

    /// With Coulomb friction of coefficient `coefficient` between the surfaces, smoothed below
    /// the sticking speed `sticking_speed` (m/s; a stuck pair creeps at most this fast,
    /// [`SUGGESTED_STICKING_SPEED`](super::SUGGESTED_STICKING_SPEED) to start from): IPC's
    /// lagged friction, its pairs and normal forces found at the start of every implicit step
    /// (`docs/math.md` section 8.11). The friction buffer needs one entry per pair active then.
    /// Without it (the default) the contact is frictionless. The explicit stepper ignores it.
    ///
    /// # Errors
    /// [`ContactError::Friction`] if `coefficient` is not finite and `>= 0` or
    /// `sticking_speed` not finite and `> 0`.
    pub fn with_friction(
        mut self,
        coefficient: Real,
        sticking_speed: Real,
    ) -> Result<Self, ContactError> {
        if !(coefficient.is_finite()
            && coefficient >= 0.0
            && sticking_speed.is_finite()
            && sticking_speed > 0.0)
        {
            return Err(ContactError::Friction);
        }
        self.friction = coefficient;
        self.sticking_speed = sticking_speed;
        Ok(self)
    }

    /// The wrapped elastic model.
    #[inline]
    pub fn model(&self) -> &M {
        &self.model
    }

    /// The contact surface.
    #[inline]
    pub fn surface(&self) -> &ContactSurface<'a> {
        &self.surface
    }

    /// The barrier's stiffness and gap.
    #[inline]
    pub fn barrier(&self) -> ContactBarrier {
        self.barrier
    }

    /// Sets the barrier between steps (for example a stiffer `kappa` where pairs came closer
    /// than wanted).
    ///
    /// # Errors
    /// [`ContactError::Gap`] or [`ContactError::Stiffness`] for a barrier that is not finite and
    /// `>= 0`; the barrier is then unchanged.
    pub fn set_barrier(&mut self, barrier: ContactBarrier) -> Result<(), ContactError> {
        ContactPotential {
            barrier,
            surface: ContactSurface::default(),
            pairs: CandidatePairs::default(),
            rest_positions: &[],
        }
        .energy(&[])?;
        self.barrier = barrier;
        // The kept pairs were found with the old gap.
        self.reuse.set(ReuseState::default());
        Ok(())
    }

    /// The pair counts of the last evaluation (see [`ContactCounts`]).
    #[inline]
    pub fn counts(&self) -> ContactCounts {
        self.counts.get()
    }

    /// The candidate-reuse list ([`CandidateReuse`]) that was last too short for a motion's
    /// pairs, and the number of pairs it needed (`None` if none was): what a caller grows it to.
    #[inline]
    pub fn reuse_needed(&self) -> Option<(ContactBuffer, usize)> {
        self.reuse_needed.get()
    }

    /// Gives the caller's buffers back.
    #[inline]
    pub fn into_buffers(self) -> ContactBuffers<'a> {
        self.buffers.into_inner()
    }

    /// The smallest distance (m) between two primitives of the surface at `positions` among the
    /// pairs within `reach` (m) of each other (point–triangle and edge–edge distances, exact
    /// closest features), or `None` if no pair is that close. What a test or a summary reports
    /// as the smallest gap; 0 means touching.
    ///
    /// # Errors
    /// Those of [`proximity_pairs`] (with `reach` as the gap).
    pub fn smallest_distance(
        &self,
        positions: &[Vec3],
        reach: Real,
    ) -> Result<Option<Real>, ContactError> {
        let mut guard = self.buffers_mut()?;
        let buffers = &mut *guard;
        let mut scratch = BroadPhaseScratch::new(buffers.slots, buffers.entries);
        let pairs = proximity_pairs(
            positions,
            reach,
            &self.surface,
            &mut scratch,
            buffers.vertex_triangle,
            buffers.edge_edge,
        )?;
        let mut smallest: Option<Real> = None;
        self.potential(pairs).for_each_pair(positions, |pair| {
            let squared = match pair {
                Pair::PointTriangle(_, [p, a, b, c]) => point_triangle_squared_distance(p, a, b, c),
                Pair::EdgeEdge(_, [a0, a1, b0, b1], _) => {
                    edge_edge_squared_distance(a0, a1, b0, b1)
                }
            };
            let distance = sqrt(squared.max(0.0));
            if distance <= reach && smallest.is_none_or(|s| distance < s) {
                smallest = Some(distance);
            }
        });
        Ok(smallest)
    }

    /// Runs the proximity broad phase at `positions` and calls `with` on the potential over the
    /// pairs found; records the counts.
    fn with_potential<R>(
        &self,
        positions: &[Vec3],
        with: impl FnOnce(&ContactPotential<'_>, &mut [PairHessian]) -> Result<R, ContactError>,
    ) -> Result<R, ContactError> {
        self.with_pairs(
            (positions, positions),
            self.barrier.gap,
            |pairs, hessians, _| {
                let mut counts = self.counts.get();
                counts.vertex_triangle = pairs.vertex_triangle.len();
                counts.edge_edge = pairs.edge_edge.len();
                self.counts.set(counts);
                with(&self.potential(pairs), hessians)
            },
        )
    }

    /// The candidate pairs of the motion `start -> end` (one array as both: of a
    /// configuration) for the gap `dhat` (the barrier's or 0), in the model's pair lists, and
    /// `with` called on them and the pair Hessians' buffer. The pairs come from the kept lists
    /// of candidate reuse where `start` and `end` lie in their boxes (see [`CandidateReuse`]),
    /// else from a grid query; a motion with reuse buffers first finds and keeps its pairs for
    /// the barrier's gap.
    fn with_pairs<R>(
        &self,
        (start, end): (&[Vec3], &[Vec3]),
        dhat: Real,
        with: impl FnOnce(
            CandidatePairs<'_>,
            &mut [PairHessian],
            &mut [FrictionPair],
        ) -> Result<R, ContactError>,
    ) -> Result<R, ContactError> {
        let mut guard = self.buffers_mut()?;
        let ContactBuffers {
            slots,
            entries,
            vertex_triangle,
            edge_edge,
            hessians,
            friction,
            reuse,
        } = &mut *guard;
        let surface = &self.surface;
        let mut state = self.reuse.get();
        let mut counts = self.counts.get();
        let inside = |bounds: &[Vec3]| {
            within_bounds(surface, bounds, start)
                && (core::ptr::eq(start, end) || within_bounds(surface, bounds, end))
        };
        // The kept pairs hold every pair within the barrier's gap of each other, none farther.
        let mut kept = state
            .kept
            .filter(|_| dhat <= self.barrier.gap && inside(reuse.bounds));
        let motion = !core::ptr::eq(start, end);
        if kept.is_none()
            && motion
            && !state.overflowed
            && reuse.bounds.len() >= 2 * surface.vertices.len()
            && dhat <= self.barrier.gap
        {
            state.kept = None;
            counts.grid_queries += 1;
            let mut scratch = BroadPhaseScratch::new(slots, entries);
            match motion_pairs(
                start,
                end,
                self.barrier.gap,
                surface,
                &mut scratch,
                reuse.vertex_triangle,
                reuse.edge_edge,
            ) {
                Ok(pairs) => {
                    let lengths = [pairs.vertex_triangle.len(), pairs.edge_edge.len()];
                    for (corners, &vertex) in reuse.bounds.chunks_exact_mut(2).zip(surface.vertices)
                    {
                        let i = vertex as usize;
                        if let (Some(&a), Some(&b), [lo, hi]) = (start.get(i), end.get(i), corners)
                        {
                            (*lo, *hi) = (a.min(b), a.max(b));
                        }
                    }
                    state.kept = Some(lengths);
                    kept = Some(lengths);
                }
                Err(ContactError::Capacity {
                    buffer:
                        buffer @ (ContactBuffer::VertexTrianglePairs | ContactBuffer::EdgeEdgePairs),
                    needed,
                    ..
                }) => {
                    state.overflowed = true;
                    self.reuse_needed.set(Some((buffer, needed)));
                }
                Err(error) => return Err(error),
            }
        }
        self.reuse.set(state);
        let pairs = if let Some([vt, ee]) = kept {
            counts.reused_queries += 1;
            self.counts.set(counts);
            let superset = CandidatePairs {
                vertex_triangle: reuse.vertex_triangle.get(..vt).unwrap_or_default(),
                edge_edge: reuse.edge_edge.get(..ee).unwrap_or_default(),
            };
            filter_pairs(
                (start, end),
                dhat,
                surface,
                superset,
                vertex_triangle,
                edge_edge,
            )?
        } else {
            counts.grid_queries += 1;
            self.counts.set(counts);
            let mut scratch = BroadPhaseScratch::new(slots, entries);
            motion_pairs(
                start,
                end,
                dhat,
                surface,
                &mut scratch,
                vertex_triangle,
                edge_edge,
            )?
        };
        with(pairs, hessians, friction)
    }

    /// The barrier potential over the candidate `pairs` of this model's surface.
    fn potential<'p>(&'p self, pairs: CandidatePairs<'p>) -> ContactPotential<'p> {
        ContactPotential {
            barrier: self.barrier,
            surface: self.surface,
            pairs,
            rest_positions: self.rest_positions,
        }
    }

    /// Adds the contact forces `-grad B` (N) at `positions` into `forces` and returns `B` (J).
    fn add_contact_forces(
        &self,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, MeshError> {
        if self.barrier.gap <= 0.0 || self.barrier.stiffness <= 0.0 {
            return Ok(0.0);
        }
        // As every energy: NaN or infinite positions give a non-finite energy, not an error (a
        // line search rejects such a trial point and backtracks).
        if positions.iter().any(|x| !x.is_finite()) {
            return Ok(Real::NAN);
        }
        // `-(-f + g)` is `f - g` to the bit (negation is exact and rounding symmetric).
        let negate = |forces: &mut [Vec3]| forces.iter_mut().for_each(|f| *f = -*f);
        negate(forces);
        let energy = self.with_potential(positions, |potential, _| {
            potential.add_gradient(positions, forces)
        });
        negate(forces);
        Ok(energy?)
    }

    /// The contact's terms for Vertex Block Descent's vertex updates at `positions`: writes
    /// each vertex's gradient of the barrier and of the lagged friction (N) into `gradient`,
    /// the diagonal blocks of their projected Hessians (N/m) into `blocks`, and into `nearest`
    /// the smallest distance (m) of a candidate pair within the barrier's gap the vertex
    /// belongs to (`+inf` for none). Every entry is overwritten.
    ///
    /// # Errors
    /// The broad phase's and the potential's (a buffer too short, a position not finite).
    pub(crate) fn vertex_terms(
        &self,
        positions: &[Vec3],
        gradient: &mut [Vec3],
        blocks: &mut [Mat3],
        nearest: &mut [Real],
    ) -> Result<(), ContactError> {
        gradient.fill(Vec3::ZERO);
        blocks.fill(Mat3::ZERO);
        nearest.fill(Real::INFINITY);
        let active = self.barrier.gap > 0.0 && self.barrier.stiffness > 0.0;
        if !active || self.surface.triangles.is_empty() {
            return Ok(());
        }
        self.with_potential(positions, |potential, _| {
            potential.add_vertex_terms(positions, gradient, blocks, nearest)
        })?;
        let count = self.counts.get().friction;
        if count == 0 {
            return Ok(());
        }
        let guard = self.buffers_ref()?;
        for pair in guard.friction.get(..count).unwrap_or_default() {
            let Some(slip) = self.slip(pair, positions) else {
                continue;
            };
            let along = slip.gradient() * pair.force;
            let block = friction_block(&slip) * pair.force;
            for (&vertex, &weight) in pair.vertices.iter().zip(&pair.weights) {
                if let (Some(g), Some(b)) = (
                    gradient.get_mut(vertex as usize),
                    blocks.get_mut(vertex as usize),
                ) {
                    *g += along * weight;
                    *b += block * (weight * weight);
                }
            }
        }
        Ok(())
    }

    /// Finds the frictional pairs at the start positions `start` (the active pairs of the
    /// barrier there) and writes them to the friction buffer; returns their number.
    fn lag_friction(&self, start: &[Vec3]) -> Result<usize, ContactError> {
        self.with_pairs((start, start), self.barrier.gap, |pairs, _, friction| {
            self.lag_pairs(start, pairs, friction)
        })
    }

    /// The frictional pairs among the candidate `pairs` at `start`, written to `friction`
    /// while room lasts; their number, or the capacity error naming the friction buffer.
    fn lag_pairs(
        &self,
        start: &[Vec3],
        pairs: CandidatePairs<'_>,
        friction: &mut [FrictionPair],
    ) -> Result<usize, ContactError> {
        let mut needed = 0;
        self.potential(pairs).for_each_pair(start, |pair| {
            let found = match pair {
                Pair::PointTriangle(vertices, [x0, x1, x2, x3]) => {
                    let distance = point_triangle_distance_gradient(x0, x1, x2, x3);
                    self.friction_pair(vertices, [x0, x1, x2, x3], &distance, 1.0, 1)
                }
                Pair::EdgeEdge(vertices, [x0, x1, x2, x3], threshold) => {
                    let distance = edge_edge_distance_gradient(x0, x1, x2, x3);
                    let mollifier = edge_edge_mollifier_value(x0, x1, x2, x3, threshold);
                    self.friction_pair(vertices, [x0, x1, x2, x3], &distance, mollifier, 2)
                }
            };
            if let Some(pair) = found {
                if let Some(slot) = friction.get_mut(needed) {
                    *slot = pair;
                }
                needed += 1;
            }
        });
        if needed > friction.len() {
            return Err(ContactError::Capacity {
                buffer: ContactBuffer::FrictionPairs,
                needed,
                capacity: friction.len(),
            });
        }
        Ok(needed)
    }

    /// The contact's part of [`admissible_step`](ElasticEnergy::admissible_step):
    /// [`ccd::step_bound`] over the pairs [`motion_pairs`] finds for the motion (gap 0); 1
    /// without a surface or where `to` has a NaN or infinite position (whose energy is not
    /// finite: the line search rejects such a point there).
    fn contact_step_bound(&self, from: &[Vec3], to: &[Vec3]) -> Result<Real, ContactError> {
        if self.surface.triangles.is_empty() || to.iter().any(|x| !x.is_finite()) {
            return Ok(1.0);
        }
        self.with_pairs((from, to), 0.0, |pairs, _, _| {
            let bound = ccd::step_bound(from, to, &self.surface, &pairs, self.separation)?;
            Ok(bound.alpha)
        })
    }

    /// One pass of the explicit stepper's impacts (see
    /// [`limit_motion`](ElasticModel::limit_motion)): every candidate pair of the motion
    /// `from -> to` whose time of impact is below 1 takes its impulse, in the broad phase's
    /// order; returns how many did.
    fn impacts(
        &self,
        from: &[Vec3],
        to: &mut [Vec3],
        velocities: &mut [Vec3],
        (masses, pinned): (&[Real], &[bool]),
        h: Real,
    ) -> Result<usize, ContactError> {
        let mut guard = self.buffers_mut()?;
        let ContactBuffers {
            slots,
            entries,
            vertex_triangle,
            edge_edge,
            ..
        } = &mut *guard;
        let mut scratch = BroadPhaseScratch::new(slots, entries);
        let pairs = motion_pairs(
            from,
            to,
            0.0,
            &self.surface,
            &mut scratch,
            vertex_triangle,
            edge_edge,
        )?;
        let surface = &self.surface;
        let inverse_mass = |vertex: u32| {
            let i = vertex as usize;
            let mass = masses.get(i).copied().unwrap_or(0.0);
            if mass > 0.0 && !pinned.get(i).copied().unwrap_or(false) {
                1.0 / mass
            } else {
                0.0
            }
        };
        let mut impacts = 0;
        let mut impact = |vertices: [u32; 4], first: usize, to: &mut [Vec3], v: &mut [Vec3]| {
            let gather = |list: &[Vec3]| {
                vertices.map(|i| list.get(i as usize).copied().unwrap_or(Vec3::NAN))
            };
            let (start, end) = (gather(from), gather(to));
            let toi = if first == 1 {
                ccd::point_triangle_ccd(start, end, self.separation)
            } else {
                ccd::edge_edge_ccd(start, end, self.separation)
            };
            if toi.is_nan() || toi >= 1.0 {
                return;
            }
            let [a, b, c, d] = [0, 1, 2, 3].map(|k| {
                let (Some(&x0), Some(&x1)) = (start.get(k), end.get(k)) else {
                    return Vec3::NAN;
                };
                ccd::lerp(x0, x1, toi)
            });
            let distance = if first == 1 {
                point_triangle_distance_gradient(a, b, c, d)
            } else {
                edge_edge_distance_gradient(a, b, c, d)
            };
            // d(d^2)/dx_k = 2 w_k r, r = sum_k w_k x_k from the second side to the first.
            let r = distance
                .gradient
                .iter()
                .take(first)
                .fold(Vec3::ZERO, |sum, &g| sum + g)
                * 0.5;
            let rr = r.dot(r);
            if !(rr > 0.0 && rr.is_finite()) {
                return;
            }
            let normal = r * (1.0 / sqrt(rr));
            let weights = distance.gradient.map(|g| g.dot(r) / (2.0 * rr));
            let speeds = gather(v);
            let mut approach: Real = 0.0;
            let mut resistance: Real = 0.0;
            for ((&weight, speed), &vertex) in weights.iter().zip(speeds).zip(&vertices) {
                approach += weight * speed.dot(normal);
                resistance += weight * weight * inverse_mass(vertex);
            }
            if !(approach < 0.0 && resistance > 0.0) {
                return;
            }
            let impulse = -approach / resistance;
            for (&weight, &vertex) in weights.iter().zip(&vertices) {
                let change = normal * (weight * impulse * inverse_mass(vertex));
                if let (Some(x), Some(speed)) =
                    (to.get_mut(vertex as usize), v.get_mut(vertex as usize))
                {
                    *speed += change;
                    *x += change * h;
                }
            }
            impacts += 1;
        };
        for &[vertex, triangle] in pairs.vertex_triangle.iter() {
            if let (Some(&p), Some(&[a, b, c])) = (
                surface.vertices.get(vertex as usize),
                surface.triangles.get(triangle as usize),
            ) {
                impact([p, a, b, c], 1, to, velocities);
            }
        }
        for &[first, second] in pairs.edge_edge.iter() {
            if let (Some(&[a0, a1]), Some(&[b0, b1])) = (
                surface.edges.get(first as usize),
                surface.edges.get(second as usize),
            ) {
                impact([a0, a1, b0, b1], 2, to, velocities);
            }
        }
        Ok(impacts)
    }

    /// The frictional pair of the primitives `vertices` at `points` with the squared distance
    /// and gradient `distance`, the mollifier `mollifier` (1 for a point and a triangle) and
    /// `first` slots on the first side; `None` if the barrier does not act on it.
    fn friction_pair(
        &self,
        vertices: [u32; 4],
        points: [Vec3; 4],
        distance: &PairDistanceGradient,
        mollifier: Real,
        first: usize,
    ) -> Option<FrictionPair> {
        let dhat2 = self.barrier.gap * self.barrier.gap;
        let d2 = distance.squared;
        if !(d2 > 0.0 && d2 < dhat2) {
            return None;
        }
        // lambda = |dB/dd| = kappa m |b'(d^2)| 2 d, the pair's normal force.
        let slope = barrier_derivatives(d2, dhat2).first.abs();
        let lambda = self.barrier.stiffness * (mollifier * slope) * (2.0 * sqrt(d2));
        // d(d^2)/dx_k = 2 w_k r: the first side's weights sum to 1, so r is half the sum of
        // its gradients.
        let r = distance
            .gradient
            .iter()
            .take(first)
            .fold(Vec3::ZERO, |sum, &g| sum + g)
            * 0.5;
        let rr = r.dot(r);
        let force = self.friction * lambda;
        if !(rr > 0.0 && force.is_finite() && force > 0.0) {
            return None;
        }
        let weights = distance.gradient.map(|g| g.dot(r) / (2.0 * rr));
        let mut anchor = Vec3::ZERO;
        for (&x, &w) in points.iter().zip(&weights) {
            anchor += x * w;
        }
        Some(FrictionPair {
            vertices,
            weights,
            normal: r * (1.0 / sqrt(rr)),
            anchor,
            force,
            block: Mat3::ZERO,
        })
    }

    /// The slip of `pair` at `positions` over the step under way.
    fn slip(&self, pair: &FrictionPair, positions: &[Vec3]) -> Option<Slip<Vec3>> {
        let contact = Contact {
            normal: pair.normal,
            surface_velocity: Vec3::ZERO,
            friction: self.friction,
            sticking_speed: self.sticking_speed,
        };
        Slip::new(
            &contact,
            pair.relative(positions),
            pair.anchor,
            self.h.get(),
        )
    }

    /// Adds the friction forces `-grad D` (N) at `positions` into `forces` and returns `D` (J),
    /// `D = sum_k mu lambda_k f0(|u_k|)` over the lagged pairs.
    fn add_friction_forces(
        &self,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, ContactError> {
        let count = self.counts.get().friction;
        if count == 0 {
            return Ok(0.0);
        }
        let guard = self.buffers_ref()?;
        let mut energy = 0.0;
        for pair in guard.friction.get(..count).unwrap_or_default() {
            let Some(slip) = self.slip(pair, positions) else {
                continue;
            };
            energy += pair.force * slip.potential();
            let along = slip.gradient() * pair.force;
            for (&vertex, &weight) in pair.vertices.iter().zip(&pair.weights) {
                if let Some(f) = forces.get_mut(vertex as usize) {
                    *f -= along * weight;
                }
            }
        }
        Ok(energy)
    }

    /// The pair Hessians stored by the last [`ElasticHessian::projected_hessians`] call.
    fn stored_hessians<R>(
        &self,
        with: impl FnOnce(&[PairHessian]) -> R,
    ) -> Result<R, ContactError> {
        let guard = self.buffers_ref()?;
        let stored = self.counts.get().hessians;
        Ok(with(guard.hessians.get(..stored).unwrap_or_default()))
    }

    /// The buffers, mutably, or [`ContactError::BuffersInUse`] if a call of this model is
    /// using them already (one of its methods called from within another: never by the
    /// solvers). No panic path, as `RefCell::borrow_mut` would have.
    fn buffers_mut(&self) -> Result<RefMut<'_, ContactBuffers<'a>>, ContactError> {
        self.buffers
            .try_borrow_mut()
            .map_err(|_| ContactError::BuffersInUse)
    }

    /// The buffers, shared (see [`buffers_mut`](Self::buffers_mut)).
    fn buffers_ref(&self) -> Result<Ref<'_, ContactBuffers<'a>>, ContactError> {
        self.buffers
            .try_borrow()
            .map_err(|_| ContactError::BuffersInUse)
    }
}

impl<M: ElasticModel<Vector = Vec3>> ElasticModel for ContactModel<'_, M> {
    type Vector = Vec3;

    #[inline]
    fn vertex_count(&self) -> usize {
        self.model.vertex_count()
    }

    /// The model's forces and the contact forces: the barrier's, which the explicit stepper
    /// takes as any force ([`limit_motion`](Self::limit_motion) keeps its surfaces apart).
    fn add_forces(&self, positions: &[Vec3], forces: &mut [Vec3]) -> Result<(), MeshError> {
        self.model.add_forces(positions, forces)?;
        self.add_contact_forces(positions, forces).map(|_| ())
    }

    #[inline]
    fn limits_motion(&self) -> bool {
        self.model.limits_motion() || !self.surface.triangles.is_empty()
    }

    /// The explicit stepper's contact (`docs/math.md` section 8.12): the model's own limit,
    /// then up to [`IMPACT_PASSES`] passes over the pairs whose straight motion from `from` to
    /// `to` meets ([`ccd`]: each pair's conservative time of impact below 1), each taking an
    /// inelastic impulse at its time of impact that removes the primitives' approaching
    /// velocity along the pair's normal (no friction, no bounce; shared by the four vertices by
    /// their closest-point weights and inverse masses, a pinned vertex taking none) and moving
    /// its vertices' end positions by `h` times their velocity change. Then the failsafe: if
    /// the motion still meets, every vertex's motion is shortened to the fraction `alpha` that
    /// continuous collision detection admits (`to = from + alpha (to - from)`, velocities
    /// kept), and `true` is returned.
    ///
    /// The guarantee: a substep that starts with no two primitives of the surface closer than
    /// the CCD's rounding floor ends that way, whatever the velocities. What it costs: the
    /// failsafe slows the whole substep (every body, not only the pair), and the impulses
    /// take out kinetic energy where surfaces meet at speed.
    fn limit_motion(
        &self,
        from: &[Vec3],
        to: &mut [Vec3],
        velocities: &mut [Vec3],
        (masses, pinned): (&[Real], &[bool]),
        h: Real,
    ) -> Result<bool, MeshError> {
        let inner = self
            .model
            .limit_motion(from, to, velocities, (masses, pinned), h)?;
        if self.surface.triangles.is_empty() || to.iter().any(|x| !x.is_finite()) {
            return Ok(inner);
        }
        for _ in 0..IMPACT_PASSES {
            let impacts = self.impacts(from, to, velocities, (masses, pinned), h)?;
            if impacts == 0 {
                break;
            }
        }
        let alpha = self.contact_step_bound(from, to)?;
        if alpha >= 1.0 {
            return Ok(inner);
        }
        for (x, &start) in to.iter_mut().zip(from) {
            *x = ccd::lerp(start, *x, alpha);
        }
        Ok(true)
    }

    fn for_each_element_stiffness(&self, visit: impl FnMut(&[u32], Real, Real)) {
        self.model.for_each_element_stiffness(visit);
    }

    #[inline]
    fn run_vertex_pass<P: VertexPass>(&self, pass: P) -> P::Output {
        self.model.run_vertex_pass(pass)
    }
}

impl<M: ElasticEnergy<Vector = Vec3>> ElasticEnergy for ContactModel<'_, M> {
    /// `E(x) + B(x) + D(x)`, `D` the friction potential of the pairs lagged at the start of
    /// the last solve ([`begin_solve`](Self::begin_solve); none without friction); `+inf`
    /// where two primitives touch; not finite (not an error) where a position is not.
    fn energy_and_add_forces(
        &self,
        positions: &[Vec3],
        forces: &mut [Vec3],
    ) -> Result<Real, MeshError> {
        let elastic = self.model.energy_and_add_forces(positions, forces)?;
        let contact = self.add_contact_forces(positions, forces)?;
        let friction = self.add_friction_forces(positions, forces)?;
        Ok(elastic + contact + friction)
    }

    /// The model's, then the frictional pairs at `start` where the contact has friction and
    /// `h > 0` (none otherwise).
    fn begin_solve(&self, start: &[Vec3], h: Real) -> Result<(), MeshError> {
        self.model.begin_solve(start, h)?;
        self.h.set(h);
        let mut reuse = self.reuse.get();
        reuse.overflowed = false;
        self.reuse.set(reuse);
        let mut counts = self.counts.get();
        counts.friction = 0;
        self.counts.set(counts);
        let active = self.barrier.gap > 0.0 && self.barrier.stiffness > 0.0;
        if !(self.friction > 0.0 && h > 0.0 && active) {
            return Ok(());
        }
        let found = self.lag_friction(start)?;
        let mut counts = self.counts.get();
        counts.friction = found;
        self.counts.set(counts);
        Ok(())
    }

    /// The model's bound, then [`ccd::step_bound`] over the pairs [`motion_pairs`] finds for
    /// the motion (gap 0); the model's bound alone where `to` has a NaN or infinite position
    /// (whose energy is not finite, see
    /// [`energy_and_add_forces`](Self::energy_and_add_forces)).
    fn admissible_step(&self, from: &[Vec3], to: &[Vec3]) -> Result<Real, MeshError> {
        let elastic = self.model.admissible_step(from, to)?;
        if elastic <= 0.0 {
            return Ok(elastic);
        }
        Ok(elastic.min(self.contact_step_bound(from, to)?))
    }
}

impl<M: ElasticHessian> ElasticHessian for ContactModel<'_, M> {
    #[inline]
    fn element_count(&self) -> usize {
        self.model.element_count()
    }

    /// The elements' Hessians into `cache`, and the active pairs' projected Hessians into the
    /// contact buffers (which [`add_hessian_product`](Self::add_hessian_product) and
    /// [`add_vertex_hessian_blocks`](Self::add_vertex_hessian_blocks) add, whatever `cache`
    /// they are given).
    fn projected_hessians(
        &self,
        positions: &[Vec3],
        cache: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        self.model.projected_hessians(positions, cache)?;
        let mut counts = self.counts.get();
        counts.hessians = 0;
        self.counts.set(counts);
        if self.barrier.gap <= 0.0 || self.barrier.stiffness <= 0.0 {
            return Ok(());
        }
        let stored = self.with_potential(positions, |potential, hessians| {
            potential
                .pair_hessians(positions, hessians)
                .map(|stored| stored.len())
        })?;
        let mut counts = self.counts.get();
        counts.hessians = stored;
        self.counts.set(counts);
        let mut guard = self.buffers_mut()?;
        for pair in guard
            .friction
            .get_mut(..counts.friction)
            .unwrap_or_default()
        {
            pair.block = self
                .slip(pair, positions)
                .map_or(Mat3::ZERO, |slip| friction_block(&slip) * pair.force);
        }
        Ok(())
    }

    fn add_hessian_product(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        self.model.add_hessian_product(cache, direction, out)?;
        self.stored_hessians(|hessians| add_hessian_product(hessians, direction, out))??;
        let guard = self.buffers_ref()?;
        for pair in guard
            .friction
            .get(..self.counts.get().friction)
            .unwrap_or_default()
        {
            let along = pair.block * pair.relative(direction);
            for (&vertex, &weight) in pair.vertices.iter().zip(&pair.weights) {
                if let Some(slot) = out.get_mut(vertex as usize) {
                    *slot += along * weight;
                }
            }
        }
        Ok(())
    }

    fn add_vertex_hessian_blocks(
        &self,
        cache: &[TetHessian],
        blocks: &mut [Mat3],
    ) -> Result<(), MeshError> {
        self.model.add_vertex_hessian_blocks(cache, blocks)?;
        self.stored_hessians(|hessians| {
            for pair in hessians {
                for (row, &vertex) in pair.hessian.iter().zip(&pair.vertices) {
                    // Every slot's block on the diagonal, and the off-diagonal blocks of slots
                    // naming the same vertex (none for a pair of four distinct vertices).
                    for (block, &other) in row.iter().zip(&pair.vertices) {
                        if other == vertex
                            && let Some(slot) = blocks.get_mut(vertex as usize)
                        {
                            *slot += *block;
                        }
                    }
                }
            }
        })?;
        let guard = self.buffers_ref()?;
        for pair in guard
            .friction
            .get(..self.counts.get().friction)
            .unwrap_or_default()
        {
            for (&vertex, &weight) in pair.vertices.iter().zip(&pair.weights) {
                if let Some(slot) = blocks.get_mut(vertex as usize) {
                    *slot += pair.block * (weight * weight);
                }
            }
        }
        Ok(())
    }
}

/// The curvature of a pair's friction potential per unit of `mu lambda` (1/m) that Newton's
/// method takes: the exact Hessian of `f0(|u|)` in the tangent plane, positive semi-definite
/// (`step/contact/friction.rs`). Measured on the blocks of `tests/steppers/contact.rs` (f64, 30
/// degrees): sticking (mu 0.8), its 25 steps converged in 100 Newton iterations in all; with
/// the isotropic majoriser `(f1/y) T` that the vertex friction takes where a step shortens the
/// slip, the third step ran 100 iterations to 2.0e-3 N against a target of 8.5e-6 N, zigzagging.
/// Sliding (mu 0.2): 173 iterations exact, 195 isotropic.
fn friction_block(slip: &Slip<Vec3>) -> Mat3 {
    slip.hessian()
}

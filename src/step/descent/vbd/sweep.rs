//! Vertex Block Descent's direction (Chen, Liu, Yang and Yuksel, "Vertex Block Descent", ACM
//! Transactions on Graphics 43(4), SIGGRAPH 2024; `docs/math.md` section 7): one block
//! Gauss–Seidel sweep over the vertices in colour order, a 3x3 Newton step per vertex, from the
//! iterate `x`; the direction is `d = sweep(x) - x`, and the loop's Armijo search runs on the
//! whole sweep. The Chebyshev trial sweeps again and extrapolates (Wang 2015). The sweep itself,
//! its vertex updates and its colour-parallel schedule are documented on
//! [`vbd_step`](super::super::super::vbd_step).

use super::super::super::super::element::TetRest;
use super::super::super::super::lanes::LaneArray;
use super::super::super::super::material::Material;
use super::super::super::super::math;
use super::super::super::super::mesh::adjacency::incident_elements;
use super::super::super::super::types::{Mat3, Real, Vec3};
use super::super::super::super::world::Part;
use super::super::super::contact::HalfSpace;
use super::super::super::contact::collider::Colliders;
use super::super::super::contact::floor::Floor;
use super::super::super::contact::friction::{Friction, Lag, Slip};
use super::super::super::loads::Loads;
use super::super::super::model::{ElasticEnergy, TetElastic};
use super::super::super::vertex_pass::passes::{TrialPoint, trial_pass};
use super::super::super::vertex_pass::point::{Grouped, Point};
use super::super::line_search::{copy, slope_along};
use super::super::objective::Objective;
use super::super::stopping::rounding_floor;
use super::super::{Direction, Extrapolation, Search};
use super::VertexBlockModel;
use super::block::{VertexFactor, shape_gradient};
use super::lanes::LaneUpdate;
#[cfg(feature = "rayon")]
use super::layout::BLOCK;
use super::layout::{Layout, Run, colour_runs};
use super::sums::{
    Elements, Extras, SummedGroup, SumsPass, VertexSums, VertexVisitor, sum_vertices,
};
use crate::error::StepError;

/// The relative size of `Phi`'s rounding error the tests on `Phi` tolerate: `sqrt(eps)`, as
/// in the relaxation.
const ROUNDING: Real = 1.0 / (1u64 << (Real::MANTISSA_DIGITS / 2)) as Real;

/// The energy resolution's factor: `64 eps`.
const RESOLUTION: Real = 64.0 * Real::EPSILON;

/// What a sweep's sums need besides the gradient and the block: the energy and its scale for
/// the vertex line search, nothing without it.
#[inline]
fn line_search_extras(line_search: bool) -> Extras {
    if line_search {
        Extras::EnergyAndScale
    } else {
        Extras::Nothing
    }
}

/// Everything a sweep reads besides the positions.
pub(crate) struct Sweep<'s, M: Material> {
    pub tets: &'s [[u32; 4]],
    pub rest: &'s [TetRest],
    pub material: &'s M,
    pub offsets: &'s [u32],
    pub incident: &'s [u32],
    /// The colour of every vertex.
    pub colours: &'s [u32],
    pub order: &'s [u32],
    /// The packed visits of `step/descent/vbd/layout.rs`, if built (the same sums either way).
    pub layout: Option<Layout<'s>>,
    pub masses: &'s [Real],
    pub pinned: &'s [bool],
    pub start: &'s [Vec3],
    /// `v_n`, empty without inertia.
    pub velocities: &'s [Vec3],
    pub h: Real,
    pub inertia: Real,
    pub gravity: Vec3,
    /// External forces and fixed axes (both empty for none).
    pub loads: Loads<'s, Vec3>,
    pub ground: Option<HalfSpace<Vec3>>,
    /// The colliders, in the sweep's (shifted) coordinates.
    pub colliders: Colliders<'s>,
    /// Friction and the iterate it is lagged to (`None` for none: set per sweep).
    pub friction: Option<(Friction<'s, Vec3>, Lag<'s, Vec3>)>,
    /// The bodies the sweep visits one after the other.
    pub bodies: Bodies<'s, M>,
    /// Contact between surfaces: each vertex's terms at the sweep's start (`None` for none: set
    /// per sweep).
    pub contact: Option<ContactTerms<'s>>,
    pub armijo: Real,
    pub backtrack: Real,
    pub max_backtracks: u32,
}

/// The bodies a sweep visits: the whole mesh with the sweep's material, or the bodies of a
/// world one after the other, each with its own material over its range of vertices (which
/// is its range of the vertex order: the order sorts the vertices body by body, then by colour).
pub(crate) enum Bodies<'s, M> {
    One,
    World(&'s [Part<M>]),
}

impl<M> Clone for Bodies<'_, M> {
    #[inline]
    fn clone(&self) -> Self {
        *self
    }
}

impl<M> Copy for Bodies<'_, M> {}

/// How far a vertex in a contact pair may move in one sweep: this fraction of its nearest
/// pair's distance. Every vertex of a pair then moves less than half the pair's distance, so
/// the pair cannot close, whatever the others do in the same sweep.
const CONTACT_REACH: Real = 0.4;

/// The contact's terms of a sweep's vertex updates, computed at the sweep's start positions
/// ([`SweepSchedule::vertex_contact`]): the barrier's and the lagged friction's gradient and
/// diagonal Hessian blocks, and how far each vertex may move in this sweep.
#[derive(Clone, Copy)]
pub(crate) struct ContactTerms<'s> {
    /// N, one per vertex.
    pub gradient: &'s [Vec3],
    /// N/m, one per vertex.
    pub blocks: &'s [Mat3],
    /// The smallest distance (m) of a contact pair of each vertex (`+inf` for none).
    pub nearest: &'s [Real],
}

impl ContactTerms<'_> {
    /// Whether vertex `i` is in a contact pair or takes friction between surfaces.
    #[inline(always)]
    pub(crate) fn touches(&self, i: usize) -> bool {
        self.nearest.get(i).is_some_and(|d| d.is_finite())
            || self.gradient.get(i).is_some_and(|g| *g != Vec3::ZERO)
    }
}

/// The caller's buffers of the contact terms ([`ContactTerms`]), one entry per vertex each.
/// Public in name only, for the sealed trait's signature.
#[derive(Debug)]
pub struct ContactBuffersVbd<'a> {
    pub(crate) gradient: &'a mut [Vec3],
    pub(crate) blocks: &'a mut [Mat3],
    pub(crate) nearest: &'a mut [Real],
}

/// What a sweep counts.
#[derive(Clone, Copy, Default)]
pub(crate) struct SweepCounts {
    pub backtracks: u32,
    pub skipped: u32,
    pub projected: u32,
}

impl SweepCounts {
    /// Both counts added (integers: the same in any grouping).
    #[cfg(feature = "rayon")]
    fn plus(self, other: SweepCounts) -> SweepCounts {
        SweepCounts {
            backtracks: self.backtracks.saturating_add(other.backtracks),
            skipped: self.skipped.saturating_add(other.skipped),
            projected: self.projected.saturating_add(other.projected),
        }
    }
}

/// One sweep a model's schedule runs
/// ([`SweepSchedule::run_sweep`](super::SweepSchedule::run_sweep)): `sweep` over `positions` in
/// place, its vertex updates one after the other ([`in_order`](Self::in_order)) or colour by
/// colour on a thread pool ([`on_pool`](Self::on_pool)), the same bits either way. Public in
/// name only, for the sealed trait's signature: nothing outside the crate can reach it.
pub struct SweepRun<'a, 's, M: Material> {
    pub(crate) sweep: &'a Sweep<'s, M>,
    pub(crate) positions: &'a mut [Vec3],
    /// One vector per vertex, free to use (the parallel schedule stages there).
    #[cfg_attr(not(feature = "rayon"), allow(dead_code))]
    pub(crate) staging: &'a mut [Vec3],
    pub(crate) counts: &'a mut SweepCounts,
    pub(crate) line_search: bool,
}

impl<M: Material> SweepRun<'_, '_, M> {
    /// The vertex updates one after the other in the vertex order, on the calling thread.
    #[inline]
    pub(crate) fn in_order(self) {
        self.sweep
            .run(self.positions, self.counts, self.line_search);
    }

    /// The vertex updates of each colour in parallel on the current rayon pool.
    #[cfg(feature = "rayon")]
    #[inline]
    pub(crate) fn on_pool(self)
    where
        M: Sync,
    {
        self.sweep
            .run_on_pool(self.positions, self.staging, self.counts, self.line_search);
    }
}

/// What Vertex Block Descent needs of a model besides its energy: the tetrahedral body the
/// sweeps visit and the schedule of their vertex updates. The supertrait of
/// [`VertexBlockModel`]; public in name only, so that no model outside the crate implements
/// it (sealed).
pub trait SweepSchedule {
    /// The material of the body.
    type Material: Material;

    /// The tetrahedra the sweeps visit, their materials and the vertex count: their energy is
    /// the model's ([`ElasticEnergy::energy_and_add_forces`]), which the descent loop
    /// evaluates.
    fn sweep_mesh(&self) -> SweepMesh<'_, Self::Material>;

    /// Writes the contact's terms of the vertex updates at `positions` into `buffers` and
    /// returns `true`, or `false` for a model without contact between surfaces (the default).
    ///
    /// # Errors
    /// The model's (a contact buffer too small).
    #[inline]
    fn vertex_contact(
        &self,
        positions: &[Vec3],
        buffers: &mut ContactBuffersVbd<'_>,
    ) -> Result<bool, StepError> {
        let _ = (positions, buffers);
        Ok(false)
    }

    /// Runs one sweep: [`SweepRun::in_order`], or [`SweepRun::on_pool`] on the model's pool
    /// (the same bits).
    fn run_sweep(&self, run: SweepRun<'_, '_, Self::Material>);
}

/// The tetrahedra a sweep visits: those of one body and its material, or a world's bodies
/// (tetrahedra and rest data over all of them, `material` the first body's, unused; `None`
/// without bodies). Public in name only, for the sealed trait's signature.
pub struct SweepMesh<'a, M> {
    pub(crate) tets: &'a [[u32; 4]],
    pub(crate) rest: &'a [TetRest],
    pub(crate) vertex_count: usize,
    pub(crate) material: Option<&'a M>,
    pub(crate) bodies: Bodies<'a, M>,
}

impl<'a, M: Material> SweepMesh<'a, M> {
    /// The sweep mesh of one body.
    #[inline]
    pub(crate) fn of(body: &'a TetElastic<'a, M>) -> Self {
        SweepMesh {
            tets: body.mesh.tets(),
            rest: body.mesh.rest(),
            vertex_count: body.mesh.vertex_count(),
            material: Some(&body.material),
            bodies: Bodies::One,
        }
    }
}

/// The vertices a task of a parallel sweep updates: small enough to split the colours of
/// small meshes over the threads, large enough to pay for a task.
/// A multiple of the layout's blocks, so that every task starts at a block.
#[cfg(feature = "rayon")]
const VERTEX_CHUNK: usize = 32;

#[cfg(feature = "rayon")]
const _: () = assert!(VERTEX_CHUNK.is_multiple_of(BLOCK));

/// The corner positions of `corners`.
#[inline(always)]
fn gather(positions: &[Vec3], corners: [u32; 4]) -> [Vec3; 4] {
    corners.map(|i| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO))
}

impl<'s, M: Material> Sweep<'s, M> {
    /// One Gauss–Seidel sweep over the free vertices in colour order, in place: each colour's
    /// vertices summed a lane group at a time (`step/descent/vbd/sums.rs`), each group's updates
    /// applied after its sums. Returns the sweep's Gauss–Seidel residual (N): the norm of the
    /// vertex gradients `g_i` each update started from (projected as the loop's residual is, see
    /// [`updated`](Self::updated)), summed in the sweep's order.
    fn run(&self, positions: &mut [Vec3], counts: &mut SweepCounts, line_search: bool) -> Real {
        let mut residual_squared = 0.0;
        self.for_each_body(|body| {
            residual_squared += body.run_body(positions, counts, line_search);
        });
        math::sqrt(residual_squared)
    }

    /// Calls `visit` with the sweep of every body in order (the sweep itself for one body).
    #[inline]
    fn for_each_body(&self, mut visit: impl FnMut(&Sweep<'s, M>)) {
        for k in 0..self.body_count() {
            if let Some(body) = self.body(k) {
                visit(&body);
            }
        }
    }

    /// The number of bodies the sweep visits.
    #[inline]
    fn body_count(&self) -> usize {
        match self.bodies {
            Bodies::One => 1,
            Bodies::World(parts) => parts.len(),
        }
    }

    /// The sweep of body `k` alone: its material and its vertices' order.
    #[inline]
    fn body(&self, k: usize) -> Option<Sweep<'s, M>> {
        match self.bodies {
            Bodies::One => (k == 0).then_some(*self),
            Bodies::World(parts) => {
                let part = parts.get(k)?;
                Some(Sweep {
                    material: part.material(),
                    order: self.order.get(part.vertices()).unwrap_or_default(),
                    bodies: Bodies::One,
                    layout: None,
                    ..*self
                })
            }
        }
    }

    /// [`run`](Self::run) over one body's vertices: the squared residual of its vertices.
    fn run_body(
        &self,
        positions: &mut [Vec3],
        counts: &mut SweepCounts,
        line_search: bool,
    ) -> Real {
        let line_search = line_search && self.max_backtracks > 0;
        let visitor = sum_vertices(SumsPass {
            elements: &self.mesh(),
            skip: self.pinned,
            runs: self.colour_runs(),
            extras: line_search_extras(line_search),
            visitor: Updates {
                sweep: self,
                target: InPlace {
                    positions,
                    residual_squared: 0.0,
                },
                counts: *counts,
                line_search,
            },
        });
        *counts = visitor.counts;
        visitor.target.residual_squared
    }

    /// One sweep colour by colour on the current rayon pool: the updates of a colour, which
    /// read only positions of other colours, are computed into `staging` in chunks of
    /// [`VERTEX_CHUNK`] vertices, then written back; the same bits as [`run`](Self::run).
    #[cfg(feature = "rayon")]
    fn run_on_pool(
        &self,
        positions: &mut [Vec3],
        staging: &mut [Vec3],
        counts: &mut SweepCounts,
        line_search: bool,
    ) where
        M: Sync,
    {
        self.for_each_body(|body| body.run_body_on_pool(positions, staging, counts, line_search));
    }

    /// [`run_on_pool`](Self::run_on_pool) over one body's vertices.
    #[cfg(feature = "rayon")]
    fn run_body_on_pool(
        &self,
        positions: &mut [Vec3],
        staging: &mut [Vec3],
        counts: &mut SweepCounts,
        line_search: bool,
    ) where
        M: Sync,
    {
        use rayon::prelude::*;
        let line_search = line_search && self.max_backtracks > 0;
        let elements = self.mesh();
        for run in self.colour_runs() {
            let members = run.vertices;
            let staged = staging.get_mut(..members.len()).unwrap_or_default();
            let read: &[Vec3] = positions;
            let counted = staged
                .par_chunks_mut(VERTEX_CHUNK)
                .zip(members.par_chunks(VERTEX_CHUNK))
                .enumerate()
                .map(|(task, (out, chunk))| {
                    let chunk = Run {
                        vertices: chunk,
                        block: run.block + task * (VERTEX_CHUNK / BLOCK),
                    };
                    // Pinned vertices are not visited: they keep their positions.
                    for (slot, &vertex) in out.iter_mut().zip(chunk.vertices) {
                        *slot = read.get(vertex as usize).copied().unwrap_or(Vec3::ZERO);
                    }
                    let visitor = sum_vertices(SumsPass {
                        elements: &elements,
                        skip: self.pinned,
                        runs: core::iter::once(chunk),
                        extras: line_search_extras(line_search),
                        visitor: Updates {
                            sweep: self,
                            target: Staged { read, out },
                            counts: SweepCounts::default(),
                            line_search,
                        },
                    });
                    visitor.counts
                })
                .reduce(SweepCounts::default, SweepCounts::plus);
            *counts = counts.plus(counted);
            for (&vertex, &x) in members.iter().zip(&*staged) {
                if let Some(slot) = positions.get_mut(vertex as usize) {
                    *slot = x;
                }
            }
        }
    }

    /// The mesh and adjacency the sums visit.
    #[inline]
    fn mesh(&self) -> Elements<'_, M> {
        Elements {
            tets: self.tets,
            rest: self.rest,
            material: self.material,
            offsets: self.offsets,
            incident: self.incident,
            layout: self.layout,
        }
    }

    /// The colour runs of the vertex order: each colour's vertices, in order.
    fn colour_runs(&self) -> impl Iterator<Item = Run<'_>> + '_ {
        colour_runs(self.colours, self.order)
    }

    /// The elements around `i`: index, corner, corner indices and rest data.
    #[inline(always)]
    fn elements(&self, i: usize) -> impl Iterator<Item = ([u32; 4], usize, &TetRest)> + '_ {
        incident_elements(self.offsets, self.incident, i).filter_map(|(element, corner)| {
            let corners = *self.tets.get(element)?;
            Some((corners, corner, self.rest.get(element)?))
        })
    }

    /// The local Newton update of vertex `i` (see [`vbd_step`]) given the sums of its elements
    /// at `positions` (with the energy where `line_search`): its new position, or `None` where
    /// it stays (skipped, stationary). Reads the positions of `i` and of the vertices sharing an
    /// element with it, which have other colours. Adds to `residual_squared`, where given, the
    /// squared norm of the vertex's gradient `g_i` at `positions`, without its fixed components
    /// and projected on the contacts as the loop's residual is (`Frame::gradient`): the term of
    /// `|grad Phi|^2` of vertex `i` at the positions the sweep has reached.
    fn updated(
        &self,
        positions: &[Vec3],
        i: usize,
        sums: &VertexSums,
        (counts, residual_squared): (&mut SweepCounts, Option<&mut Real>),
        line_search: bool,
    ) -> Option<Vec3> {
        let x = *positions.get(i)?;
        let m = self.masses.get(i).copied().unwrap_or(0.0);
        let x0 = self.start.get(i).copied().unwrap_or(x);
        let y = match self.velocities.get(i) {
            Some(&v) => x0 + v * self.h,
            None => x0,
        };
        let weight = m * self.inertia;
        let external = self.loads.force(i);
        let fixed = self.loads.fixed(i);
        let mut gradient = (x - y) * weight - self.gravity * m - external + sums.gradient;
        let mut hessian = sums.hessian;
        let elastic = sums.elastic;
        // What the local energy can resolve: 64 eps sum_e V_e W_e-scale, the scale from the
        // element block, tr(K_e) / |g_a|^2 ~ V_e times the elastic modulus (J).
        let resolution = sums.resolution;
        // Friction lagged to the loop's iterate (`step/contact/friction.rs`): its gradient and
        // tangent block.
        let rough = self.rough(i, x, x0);
        if let Some((slip, force)) = &rough {
            gradient += slip.gradient() * *force;
            hessian += slip.hessian() * *force;
        }
        // Contact between surfaces, at the sweep's start: its vertex takes a whole Newton step
        // (the vertex line search's energy has no barrier) cut to its reach.
        let contact = self.contact.filter(|terms| terms.touches(i));
        if let Some(terms) = &contact {
            gradient += terms.gradient.get(i).copied().unwrap_or(Vec3::ZERO);
            hessian += terms.blocks.get(i).copied().unwrap_or(Mat3::ZERO);
        }
        if fixed != 0 {
            // The step on the free subspace exactly: the reduced system, its fixed rows and
            // columns replaced by the identity and its fixed gradient components by zero.
            gradient = gradient.axes_from(Vec3::ZERO, fixed);
            let keep = Vec3::ONE.axes_from(Vec3::ZERO, fixed);
            let unit = Vec3::ONE - keep;
            // Rows, then columns.
            hessian = Mat3::from_cols(
                hessian.x_axis * keep,
                hessian.y_axis * keep,
                hessian.z_axis * keep,
            );
            hessian = Mat3::from_cols(
                hessian.x_axis * keep.x + Vec3::X * unit.x,
                hessian.y_axis * keep.y + Vec3::Y * unit.y,
                hessian.z_axis * keep.z + Vec3::Z * unit.z,
            );
        }
        if let Some(residual_squared) = residual_squared {
            let floor = Floor::<Vec3>::new(self.ground.as_ref()).with_colliders(self.colliders);
            let projected_gradient = floor.constrain(floor.contact(x), x, gradient, 1.0);
            *residual_squared += projected_gradient.dot(projected_gradient);
        }
        let Some(VertexFactor { factor, projected }) = VertexFactor::new(weight, &hessian) else {
            counts.skipped += 1;
            return None;
        };
        counts.projected += u32::from(projected);
        let mut step = factor.solve(-gradient);
        if let Some(ground) = &self.ground
            && ground.height(x + step) < 0.0
        {
            // The minimiser of the quadratic model on the plane n.(x + d) = offset:
            // d = d0 - H^-1 n (n.d0 + height(x)) / (n.H^-1 n).
            let towards = factor.solve(ground.normal);
            let curvature = ground.normal.dot(towards);
            let excess = ground.normal.dot(step) + ground.height(x);
            step -= towards * (excess / curvature);
        }
        if let Some((height, normal)) = self.colliders.entered(x, x + step) {
            // The same minimiser on the collider's tangent plane at x (exact for a half-space,
            // to first order on a curved surface, where the projection below finishes): the
            // vertex slides along the surface instead of being pushed back out of it.
            let towards = factor.solve(normal);
            let curvature = normal.dot(towards);
            if curvature > 0.0 {
                step -= towards * ((normal.dot(step) + height) / curvature);
            }
        }
        let mut step = step.axes_from(Vec3::ZERO, fixed);
        if let Some(terms) = &contact {
            let reach = CONTACT_REACH * terms.nearest.get(i).copied().unwrap_or(0.0);
            let length = math::sqrt(step.dot(step));
            if length > reach {
                step *= reach / length;
            }
        }
        let slope = gradient.dot(step);
        if !(slope < 0.0 && step.is_finite()) {
            // Stationary (g = 0) or no descent: nothing to gain here this sweep.
            counts.skipped += u32::from(slope != 0.0);
            return None;
        }
        let project = |p: Vec3| {
            let mut p = p;
            if let Some(ground) = &self.ground {
                ground.project(&mut p);
            }
            // (Without colliders, not even the call: it is not inlined.)
            if !self.colliders.is_empty() {
                p = Point::pushed_out(p, self.colliders);
            }
            p.axes_from(x, fixed)
        };
        if !line_search || contact.is_some() {
            return Some(project(x + step));
        }
        let resolution = RESOLUTION * resolution;
        let mut alpha = 1.0;
        for _ in 0..=self.max_backtracks {
            let trial = project(x + step * alpha);
            let moved = trial - x;
            let mut trial_elastic = 0.0;
            self.for_each_trial_element(positions, i, trial, |_, rest, f| {
                trial_elastic += rest.volume * self.material.energy_density(f);
            });
            let trial_rough = rough.and_then(|_| self.rough(i, trial, x0));
            let potential = |term: &Option<(Slip<Vec3>, Real)>| {
                term.as_ref()
                    .map_or(0.0, |(slip, force)| force * slip.potential())
            };
            // The inertia and gravity change in a form without cancellation.
            let change = 0.5 * weight * moved.dot(moved + (x - y) * 2.0)
                - m * self.gravity.dot(moved)
                - external.dot(moved)
                + (trial_elastic - elastic)
                + (potential(&trial_rough) - potential(&rough));
            // Armijo where the energy resolves the predicted decrease; below that, Hager and
            // Zhang's approximate Armijo test from the two slopes (SIAM J. Optim. 2005), as
            // the relaxation's line search does, with the trial's gradient computed only then.
            let noise = resolution + ROUNDING * (elastic.abs() + trial_elastic.abs());
            let sufficient = change <= self.armijo * alpha * slope
                || (-alpha * slope <= noise && change <= noise && {
                    let mut trial_gradient = (trial - y) * weight - self.gravity * m - external;
                    self.for_each_trial_element(positions, i, trial, |corner, rest, f| {
                        let g = shape_gradient(rest, corner);
                        trial_gradient += self.material.first_piola(f) * g * rest.volume;
                    });
                    if let Some((slip, force)) = &trial_rough {
                        trial_gradient += slip.gradient() * *force;
                    }
                    trial_gradient.dot(step) <= (2.0 * self.armijo - 1.0) * slope
                });
            if sufficient {
                return Some(trial);
            }
            alpha *= self.backtrack;
            counts.backtracks += 1;
        }
        counts.skipped += 1;
        None
    }

    /// Friction's slip and force factor at vertex `i` moved from `x0` to `x`, lagged to the
    /// loop's iterate; `None` without friction there.
    #[inline(always)]
    pub(crate) fn rough(&self, i: usize, x: Vec3, x0: Vec3) -> Option<(Slip<Vec3>, Real)> {
        let (friction, lag) = self.friction.as_ref()?;
        if !friction.is_active() {
            return None;
        }
        let reference = (*lag.x.get(i)?, *lag.gradient.get(i)?);
        friction.lagged_slip((x, x0), reference)
    }

    /// Calls `visit(corner, rest, f)` for every element around `i` with vertex `i` moved to
    /// `trial`: its corner, rest data and deformation gradient there.
    #[inline(always)]
    fn for_each_trial_element(
        &self,
        positions: &[Vec3],
        i: usize,
        trial: Vec3,
        mut visit: impl FnMut(usize, &TetRest, Mat3),
    ) {
        for (corners, corner, rest) in self.elements(i) {
            let mut xs = gather(positions, corners);
            if let Some(slot) = xs.get_mut(corner) {
                *slot = trial;
            }
            visit(corner, rest, rest.deformation_gradient(xs));
        }
    }
}

/// Where a sweep's visitor reads the positions its updates start from, writes each update, and
/// sums the sweep's Gauss–Seidel residual if it keeps one (a target without one spares the
/// sweep its terms: the projection of each vertex gradient on the contacts and its norm).
trait UpdateTarget {
    /// The positions the updates read.
    fn read(&self) -> &[Vec3];

    /// The positions the updates read and the squared residual summed so far (N^2), `None`
    /// where the target keeps none.
    fn read_and_residual(&mut self) -> (&[Vec3], Option<&mut Real>);

    /// Writes `to`, the new position of `vertex`, the `index`-th vertex of the visited run.
    fn write(&mut self, index: usize, vertex: u32, to: Vec3);

    /// Adds `term` to the squared residual, if the target keeps one.
    #[inline]
    fn add_residual(&mut self, term: Real) {
        if let (_, Some(residual_squared)) = self.read_and_residual() {
            *residual_squared += term;
        }
    }
}

/// The sequential sweep's target: each update applied in place, the residual summed in visit
/// order.
struct InPlace<'a> {
    positions: &'a mut [Vec3],
    /// The Gauss–Seidel residual's square so far (N^2).
    residual_squared: Real,
}

impl UpdateTarget for InPlace<'_> {
    #[inline]
    fn read(&self) -> &[Vec3] {
        self.positions
    }

    #[inline]
    fn read_and_residual(&mut self) -> (&[Vec3], Option<&mut Real>) {
        (self.positions, Some(&mut self.residual_squared))
    }

    #[inline]
    fn write(&mut self, _index: usize, vertex: u32, to: Vec3) {
        if let Some(slot) = self.positions.get_mut(vertex as usize) {
            *slot = to;
        }
    }
}

/// The parallel sweep's target: the positions before the colour are read, each update is
/// written to the staging entry of its vertex. It keeps no residual: nothing reads the
/// parallel sweep's, whose sum would depend on the tasks.
#[cfg(feature = "rayon")]
struct Staged<'a> {
    read: &'a [Vec3],
    out: &'a mut [Vec3],
}

#[cfg(feature = "rayon")]
impl UpdateTarget for Staged<'_> {
    #[inline]
    fn read(&self) -> &[Vec3] {
        self.read
    }

    #[inline]
    fn read_and_residual(&mut self) -> (&[Vec3], Option<&mut Real>) {
        (self.read, None)
    }

    #[inline]
    fn write(&mut self, index: usize, _vertex: u32, to: Vec3) {
        if let Some(slot) = self.out.get_mut(index) {
            *slot = to;
        }
    }
}

/// A sweep's visitor: each vertex's update from its sums, read from and written to `target`,
/// its residual term summed there if the target keeps the residual.
struct Updates<'a, 's, M: Material, T> {
    sweep: &'a Sweep<'s, M>,
    target: T,
    counts: SweepCounts,
    line_search: bool,
}

impl<M: Material, T: UpdateTarget> VertexVisitor for Updates<'_, '_, M, T> {
    #[inline]
    fn positions(&self) -> &[Vec3] {
        self.target.read()
    }

    #[inline]
    fn visit(&mut self, index: usize, vertex: u32, sums: &VertexSums) {
        let (positions, residual_squared) = self.target.read_and_residual();
        let update = self.sweep.updated(
            positions,
            vertex as usize,
            sums,
            (&mut self.counts, residual_squared),
            self.line_search,
        );
        if let Some(x) = update {
            self.target.write(index, vertex, x);
        }
    }

    #[inline(always)]
    fn visit_group<L: LaneArray>(&mut self, group: &SummedGroup<'_>) {
        let (positions, residual_squared) = self.target.read_and_residual();
        let sum_residual = residual_squared.is_some();
        let updates =
            self.sweep
                .lane_updates::<L>(positions, group, self.line_search, sum_residual);
        // In lane order, as the one-vertex visits: the residual's sum keeps its order.
        for (j, index, vertex, sums) in group.visits() {
            match updates.get(j) {
                Some(&LaneUpdate::Stays { residual, skipped }) => {
                    self.target.add_residual(residual);
                    self.counts.skipped += u32::from(skipped);
                }
                Some(&LaneUpdate::Moves { residual, to }) => {
                    self.target.add_residual(residual);
                    self.target.write(index, vertex, to);
                }
                _ => self.visit(index, vertex, sums),
            }
        }
    }
}

/// The visitor of [`VbdSweep::begin`]: `sum_i |m_i/h^2 I + sum_e V_e K_e,ii|_F^2` and the
/// elements' energy scale.
struct BlockNorms<'a> {
    masses: &'a [Real],
    inertia: Real,
    positions: &'a [Vec3],
    stiffness_squared: Real,
    resolution: Real,
}

impl VertexVisitor for BlockNorms<'_> {
    #[inline]
    fn positions(&self) -> &[Vec3] {
        self.positions
    }

    #[inline]
    fn visit(&mut self, _index: usize, vertex: u32, sums: &VertexSums) {
        let m = self.masses.get(vertex as usize).copied().unwrap_or(0.0);
        let block = sums.hessian + Mat3::from_diagonal(Vec3::splat(m * self.inertia));
        let columns = [block.x_axis, block.y_axis, block.z_axis];
        self.stiffness_squared += columns.iter().map(|c| c.dot(*c)).sum::<Real>();
        self.resolution += sums.resolution;
    }
}

impl<M: Material> Clone for Sweep<'_, M> {
    #[inline]
    fn clone(&self) -> Self {
        *self
    }
}

impl<M: Material> Copy for Sweep<'_, M> {}

/// The sweep as a direction of the descent loop, run by the model's schedule
/// ([`SweepSchedule::run_sweep`]), with the counts of its vertex updates and its rounding floor.
pub(crate) struct VbdSweep<'s, M: Material> {
    /// The mesh, topology and settings of the sweeps; the start positions, velocities and time
    /// step come from the objective of each call (the loop's shifted coordinates), the ground
    /// is given already shifted.
    sweep: Sweep<'s, M>,
    /// Whether every vertex update runs its line search (otherwise only the sweep after one
    /// whose full steps the loop rejected).
    line_search: bool,
    /// Whether the next sweep runs the line search although `line_search` is false.
    redo: bool,
    /// Whether the last search's sweep ran the line search.
    searched_safely: bool,
    /// Sweeps redone with the line search.
    pub redone: u32,
    /// The rounding of the elastic energy, `64 eps sum V_e tr(K_e) / |g|^2` over the element
    /// corners at the initial guess (J).
    resolution: Real,
    /// What the sweeps counted so far.
    pub counts: SweepCounts,
    floor: Real,
    /// The Gauss–Seidel residual (N) of the last accelerated trial's sweep: an estimate of
    /// `|grad Phi|` at the iterate it started from (see [`Direction::residual_estimate`]).
    estimate: Real,
    /// Where the contact's terms are written before each sweep (`None`: the sweeps take no
    /// contact between surfaces).
    contact: Option<ContactBuffersVbd<'s>>,
}

impl<'s, M: Material> VbdSweep<'s, M> {
    /// The direction of the sweeps of `sweep` (its `start`, `velocities`, `h` and `inertia`
    /// are ignored), each vertex update line-searched where `line_search`, the contact's terms
    /// written to `contact` before each sweep where the model has contact.
    pub fn new(
        sweep: Sweep<'s, M>,
        line_search: bool,
        contact: Option<ContactBuffersVbd<'s>>,
    ) -> Self {
        VbdSweep {
            contact,
            sweep,
            line_search,
            redo: false,
            searched_safely: false,
            redone: 0,
            resolution: 0.0,
            counts: SweepCounts::default(),
            floor: 0.0,
            estimate: Real::NAN,
        }
    }

    /// The sweep at the objective's start positions, velocities and time step, with its
    /// friction lagged to `lag` (none if `None`).
    fn at<'o, F: ElasticEnergy<Vector = Vec3>>(
        &'o self,
        objective: &'o Objective<'_, F>,
        lag: Option<Lag<'o, Vec3>>,
    ) -> Sweep<'o, M> {
        let h = objective.h;
        Sweep {
            start: objective.vertices.start,
            velocities: objective.vertices.velocities,
            h,
            inertia: if h > 0.0 { 1.0 / (h * h) } else { 0.0 },
            friction: lag.map(|lag| (objective.friction, lag)),
            contact: None,
            ..self.sweep
        }
    }

    /// Writes the contact's terms at `x` where the model has contact; whether it has.
    fn fill_contact<F: VertexBlockModel<Material = M>>(
        &mut self,
        model: &F,
        x: &[Vec3],
    ) -> Result<bool, StepError> {
        match &mut self.contact {
            Some(buffers) => model.vertex_contact(x, buffers),
            None => Ok(false),
        }
    }

    /// The contact's terms last written (see [`fill_contact`](Self::fill_contact)).
    fn contact_terms(&self) -> Option<ContactTerms<'_>> {
        self.contact.as_ref().map(|buffers| ContactTerms {
            gradient: buffers.gradient,
            blocks: buffers.blocks,
            nearest: buffers.nearest,
        })
    }
}

impl<F: VertexBlockModel> Direction<F> for VbdSweep<'_, F::Material> {
    fn begin(&mut self, objective: &Objective<'_, F>, x: &[Vec3]) {
        // The relaxation's estimate with the exact vertex blocks in place of the diagonal
        // bounds: `eps/2 max |x| (sum_i |m_i/h^2 I + sum_e V_e K_e,ii|_F^2)^(1/2)`.
        let sweep = self.at(objective, None);
        let reach = x
            .iter()
            .fold(0.0, |a: Real, p| a.max(p.abs().max_element()));
        let (mut stiffness_squared, mut resolution) = (0.0, 0.0);
        sweep.for_each_body(|body| {
            let blocks = sum_vertices(SumsPass {
                elements: &body.mesh(),
                skip: body.pinned,
                runs: body.colour_runs(),
                // The scale, not the energy: the norms and the resolution read no energy.
                extras: Extras::Scale,
                visitor: BlockNorms {
                    masses: body.masses,
                    inertia: body.inertia,
                    positions: x,
                    stiffness_squared,
                    resolution,
                },
            });
            (stiffness_squared, resolution) = (blocks.stiffness_squared, blocks.resolution);
        });
        // The contact's blocks stiffen the vertices they act on as the elements' do (an error
        // here recurs in the first sweep, which reports it).
        if let Ok(true) = self.fill_contact(objective.model, x)
            && let Some(terms) = self.contact_terms()
        {
            for block in terms.blocks {
                let columns = [block.x_axis, block.y_axis, block.z_axis];
                stiffness_squared += columns.iter().map(|c| c.dot(*c)).sum::<Real>();
            }
        }
        self.floor = rounding_floor(reach, stiffness_squared);
        // The energy of a nearly undeformed element is a difference of `O(mu V)` terms: its
        // rounding, which the relative `sqrt(eps) |Phi|` of the loop misses when `Phi` is
        // small, as the vertex line search estimates it.
        self.resolution = RESOLUTION * resolution;
    }

    fn phi_resolution(&self) -> Real {
        self.resolution
    }

    fn accelerates_with_friction(&self) -> bool {
        false
    }

    fn fall_back(&mut self) -> bool {
        // The full steps did not lower `Phi` enough: redo the sweep with the line search.
        let redo = !self.searched_safely && self.sweep.max_backtracks > 0;
        if redo {
            self.redo = true;
            self.redone = self.redone.saturating_add(1);
        }
        redo
    }

    fn search(&mut self, search: Search<'_, F>) -> Result<Real, StepError> {
        let (objective, at, direction) = (search.objective, search.at, search.direction);
        let (trial, step) = (search.trial, search.step);
        let lag = Lag::new(at.x, at.gradient);
        let TrialPoint {
            positions: swept,
            gradient,
        } = trial;
        copy(swept, at.x);
        // `direction` is free until the sweep is done: the parallel schedule stages there.
        let mut counts = self.counts;
        let line_search = self.line_search || self.redo;
        // Body by body, each with the contact's terms where the bodies before it left the
        // positions (block Gauss–Seidel over the bodies).
        for k in 0..self.sweep.body_count() {
            let touching = self.fill_contact(objective.model, swept)?;
            let Some(body) = self.at(objective, Some(lag)).body(k) else {
                continue;
            };
            let sweep = Sweep {
                contact: self.contact_terms().filter(|_| touching),
                ..body
            };
            objective.model.run_sweep(SweepRun {
                sweep: &sweep,
                positions: swept,
                staging: direction,
                counts: &mut counts,
                line_search,
            });
        }
        self.counts = counts;
        self.redo = false;
        self.searched_safely = line_search;
        for (d, (&s, &x)) in direction.iter_mut().zip(swept.iter().zip(at.x)) {
            *d = s - x;
        }
        if step == 1.0 {
            // The trial is the sweep's result itself (not `x + (s - x)`, which may round).
            gradient.fill(Vec3::ZERO);
        } else {
            trial_pass(
                &objective.frames,
                objective.vertices.pinned,
                (at.x, direction),
                step,
                TrialPoint {
                    positions: swept,
                    gradient,
                },
            );
        }
        Ok(slope_along(at.gradient, direction))
    }

    fn extrapolate(&mut self, extrapolation: Extrapolation<'_, F>) -> Result<(), StepError> {
        let Extrapolation {
            objective,
            at,
            stepped,
            trial,
            step,
            omega,
        } = extrapolation;
        let lag = Lag::new(at.x, at.gradient);
        let TrialPoint {
            positions: older,
            gradient: swept,
        } = trial;
        copy(swept, at.x);
        // No buffer is free for the parallel schedule's staging here: the sequential sweep,
        // which gives the same bits; body by body as in `search`.
        let mut counts = self.counts;
        let mut residual_squared = 0.0;
        for k in 0..self.sweep.body_count() {
            let touching = self.fill_contact(objective.model, swept)?;
            let Some(body) = self.at(objective, Some(lag)).body(k) else {
                continue;
            };
            let sweep = Sweep {
                contact: self.contact_terms().filter(|_| touching),
                ..body
            };
            residual_squared += sweep.run_body(swept, &mut counts, self.line_search);
        }
        let estimate = math::sqrt(residual_squared);
        let sweep = self.at(objective, Some(lag));
        let floor = objective.frames.floor();
        let rows = older.iter_mut().zip(swept.iter()).zip(at.x);
        for (i, ((older, &s), &x)) in rows.enumerate() {
            if sweep.pinned.get(i).copied().unwrap_or(false) {
                *older = x;
                continue;
            }
            let last_step = if stepped { x - *older } else { Vec3::ZERO };
            let target = x + (s - x) * step + last_step * (omega - 1.0);
            // The descent loop restores the fixed coordinates after this pass.
            *older = floor.project(target);
        }
        swept.fill(Vec3::ZERO);
        self.counts = counts;
        self.estimate = estimate;
        Ok(())
    }

    fn rounding_floor(&self) -> Real {
        self.floor
    }

    fn residual_estimate(&self) -> Option<Real> {
        Some(self.estimate)
    }
}

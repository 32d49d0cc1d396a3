//! Smoothed-aggregation algebraic multigrid (feature `alloc`): the multilevel preconditioner
//! of Newton's linear solves (`docs/math.md` section 7.1.1), after Vaněk, Mandel and Brezina,
//! "Algebraic multigrid by smoothed aggregation for second and fourth order elliptic
//! problems" (Computing 56, 1996).
//!
//! Setup ([`Multilevel::build`]): the projected Hessian assembled with its constraints
//! (`assemble.rs`); per level, the strong connections and aggregates (`aggregate.rs`), the
//! tentative prolongator from the six rigid-body modes orthonormalised per aggregate and its
//! Jacobi smoothing (`prolong.rs`), the Galerkin product `P^T A P` (`csr.rs`); until a level
//! has at most [`MAX_COARSE`] unknowns, whose matrix is factored by dense Cholesky; then every
//! level renumbered colour by colour (`colour.rs`). The application is one V-cycle
//! (`cycle.rs`), a symmetric positive definite operator.
//!
//! The setup runs in a fixed order on one thread (no hash maps, sorted columns, sums in row
//! order), so the bits depend on the input only; every allocation is fallible. The V-cycle's
//! passes (the sweeps one colour at a time, the residual, restriction and prolongation) run
//! in fixed blocks of rows on the model's thread pool where it has one
//! (`parallel::ParallelTetElastic`, feature `rayon`: a Newton
//! solve through it runs its V-cycles there, one pool entry per cycle), every row's sum in its
//! column order, so the bits do not depend on the thread count either.

mod aggregate;
mod assemble;
mod colour;
mod csr;
mod cycle;
mod prolong;
#[cfg(test)]
mod tests;

use alloc::vec::Vec;

use super::super::super::super::element::TetHessian;
use super::super::super::super::types::{Mat3, Real, Vec3};
use super::super::super::model::{ElasticHessian, ElasticModel};
use super::super::super::state::check_length;
use super::super::super::vertex_pass::sealed::Sealed;
use super::super::super::vertex_pass::{Blocks, InOrder, Join, VertexPass};
use crate::error::{StepBuffer, StepError};
use colour::{Colouring, renumbered};
use csr::Multiply;
use cycle::{Coarsest, Level, ROW_BLOCK, v_cycle};

pub(crate) use assemble::projection_matrix;

/// The near-null space's size: three translations and three rotations.
pub(crate) const MODES: usize = 6;

/// A level with at most this many unknowns is the coarsest.
pub const MAX_COARSE: usize = 300;

/// At most this many levels.
const MAX_LEVELS: usize = 12;

/// An allocation failed.
#[derive(Debug)]
pub(crate) struct OutOfMemory;

/// Why a hierarchy was not built.
#[derive(Debug)]
pub(crate) enum SetupError {
    /// An allocation failed.
    OutOfMemory,
    /// The model does not expose its element Hessians.
    Unsupported,
    /// An element (first) names a vertex (second) at or beyond the vertex count.
    VertexIndex(usize, u32),
}

impl From<OutOfMemory> for SetupError {
    fn from(_: OutOfMemory) -> SetupError {
        SetupError::OutOfMemory
    }
}

/// A vector of `len` copies of `value`, or [`OutOfMemory`].
pub(crate) fn filled<T: Clone>(len: usize, value: T) -> Result<Vec<T>, OutOfMemory> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| OutOfMemory)?;
    v.resize(len, value);
    Ok(v)
}

/// Pushes `value`, or [`OutOfMemory`].
#[inline]
pub(crate) fn push<T>(v: &mut Vec<T>, value: T) -> Result<(), OutOfMemory> {
    v.try_reserve(1).map_err(|_| OutOfMemory)?;
    v.push(value);
    Ok(())
}

/// The levels and the coarsest solve.
#[derive(Debug, Default)]
struct Hierarchy {
    levels: Vec<Level>,
    coarsest: Coarsest,
    /// The vertex count of the finest level.
    vertices: usize,
    /// The finest level's renumbering: `order[k]` is the vertex at node `k`, `position` the
    /// inverse.
    order: Vec<u32>,
    position: Vec<u32>,
}

impl Hierarchy {
    /// The hierarchy of the matrix of `assemble.rs` at `positions`.
    fn new<F: ElasticHessian>(
        model: &F,
        hessians: &[TetHessian],
        positions: &[Vec3],
        diagonal: &dyn Fn(usize) -> Mat3,
        projection: &dyn Fn(usize) -> Mat3,
    ) -> Result<Hierarchy, SetupError> {
        let n = positions.len();
        let fine = assemble::assemble(model, hessians, n, diagonal, projection)?;
        let modes = rigid_modes(positions, projection)?;
        let mut levels: Vec<Level> = Vec::new();
        push(&mut levels, Level::new(fine)?)?;
        let mut modes = modes;
        let mut block = 3;
        while levels.len() < MAX_LEVELS {
            let Some(level) = levels.last_mut() else {
                break;
            };
            let rows = level.matrix.rows;
            if rows <= MAX_COARSE {
                break;
            }
            let strength = aggregate::strength(&level.matrix, block)?;
            let (aggregates, count) = aggregate::aggregates(&strength)?;
            let coarse_rows = count as usize * MODES;
            // No coarsening to speak of (isolated nodes): stop here.
            if count == 0 || 5 * coarse_rows > 4 * rows {
                break;
            }
            let (tentative, coarse_modes) =
                prolong::tentative((block, &aggregates, count), &modes)?;
            let prolongator =
                prolong::smoothed(model, &level.matrix, &level.inverse_diagonal, &tentative)?;
            drop(tentative);
            let restriction = prolongator.transpose()?;
            let product = model.run_vertex_pass(Multiply {
                left: &level.matrix,
                right: &prolongator,
            })?;
            let mut coarse = model.run_vertex_pass(Multiply {
                left: &restriction,
                right: &product,
            })?;
            drop(product);
            coarse.symmetrize()?;
            level.prolongator = prolongator;
            level.restriction = restriction;
            push(&mut levels, Level::new(coarse)?)?;
            modes = coarse_modes;
            block = MODES;
        }
        let fine = colour_levels(&mut levels)?;
        let coarsest = match levels.last() {
            Some(level) => Coarsest::new(&level.matrix)?,
            None => Coarsest::default(),
        };
        Ok(Hierarchy {
            levels,
            coarsest,
            vertices: n,
            order: fine.order,
            position: fine.position,
        })
    }

    /// `z = M^-1 r` by one V-cycle, its passes given to `join`.
    fn apply<J: Join + Sync>(&mut self, join: &J, r: &[Vec3], z: &mut [Vec3]) {
        let Some(fine) = self.levels.first_mut() else {
            z.fill(Vec3::ZERO);
            return;
        };
        let order = &self.order;
        let gather = |first: usize, b: &mut [Real]| {
            for (j, b) in b.iter_mut().enumerate() {
                let row = first + j;
                let vertex = order.get(row / 3).copied().unwrap_or(0) as usize;
                *b = r.get(vertex).map_or(0.0, |v| v[row % 3]);
            }
        };
        Blocks::of_len(ROW_BLOCK, fine.b.len(), &mut fine.b[..], &gather).run_with(join);
        v_cycle(join, &mut self.levels, &self.coarsest);
        let (Some(fine), position) = (self.levels.first(), &self.position) else {
            return;
        };
        let scatter = |first: usize, z: &mut [Vec3]| {
            for (j, z) in z.iter_mut().enumerate() {
                let node = position.get(first + j).copied().unwrap_or(0) as usize;
                let x = |a: usize| fine.x.get(3 * node + a).copied().unwrap_or(0.0);
                *z = Vec3::new(x(0), x(1), x(2));
            }
        };
        Blocks::new(z.len(), z, &scatter).run_with(join);
    }
}

/// The vertices of a group of the finest level's colouring (`colour.rs`): a task of its sweeps,
/// run in the mesh's order.
const FINE_GROUP: usize = 64;

/// The aggregates of a group of a coarser level's colouring: fewer, since a coarse node has
/// many more neighbours (fewer groups would share a colour).
const COARSE_GROUP: usize = 8;

/// Renumbers every level colour by colour (`colour.rs`): its matrix on both sides, its
/// prolongator's rows by its own renumbering and columns by the next level's, the restriction
/// transposed again; returns the finest level's renumbering.
fn colour_levels(levels: &mut [Level]) -> Result<Colouring, OutOfMemory> {
    let mut colourings: Vec<Colouring> = Vec::new();
    colourings
        .try_reserve_exact(levels.len())
        .map_err(|_| OutOfMemory)?;
    for (l, level) in levels.iter().enumerate() {
        let (width, group) = if l == 0 {
            (3, FINE_GROUP)
        } else {
            (MODES, COARSE_GROUP)
        };
        colourings.push(Colouring::new(&level.matrix, width, group)?);
    }
    for (l, level) in levels.iter_mut().enumerate() {
        let (Some(own), next) = (colourings.get(l), colourings.get(l + 1)) else {
            continue;
        };
        let matrix = renumbered(&level.matrix, own, own)?;
        if let Some(next) = next {
            level.prolongator = renumbered(&level.prolongator, own, next)?;
            level.restriction = level.prolongator.transpose()?;
        }
        let prolongator = core::mem::take(&mut level.prolongator);
        let restriction = core::mem::take(&mut level.restriction);
        *level = Level::new(matrix)?;
        level.prolongator = prolongator;
        level.restriction = restriction;
        level.colours = own.row_starts()?;
        level.group_rows = own.group_rows();
    }
    let fine = match colourings.first_mut() {
        Some(fine) => core::mem::take(fine),
        None => Colouring::default(),
    };
    Ok(fine)
}

/// One V-cycle as one pass for a model's thread pool ([`ElasticModel::run_vertex_pass`]): the
/// model installs its pool once, and the cycle's passes split on it.
struct Cycle<'c> {
    hierarchy: &'c mut Hierarchy,
    residual: &'c [Vec3],
    out: &'c mut [Vec3],
}

impl Sealed for Cycle<'_> {}

impl VertexPass for Cycle<'_> {
    type Output = ();

    fn run_with<J: Join + Sync>(self, join: &J) {
        self.hierarchy.apply(join, self.residual, self.out);
    }
}

/// The six rigid-body modes at `positions` (about their mean), each vertex's rows projected
/// by its `S_i`: row-major, [`MODES`] numbers a row, three rows a vertex.
fn rigid_modes(
    positions: &[Vec3],
    projection: &dyn Fn(usize) -> Mat3,
) -> Result<Vec<Real>, OutOfMemory> {
    let n = positions.len();
    let mean = positions.iter().fold(Vec3::ZERO, |a, &p| a + p) / (n.max(1) as Real);
    let mut modes = filled(3 * n * MODES, 0.0)?;
    for (i, (&x, rows)) in positions
        .iter()
        .zip(modes.chunks_exact_mut(3 * MODES))
        .enumerate()
    {
        let p = x - mean;
        let s = projection(i);
        let columns = [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(0.0, -p.z, p.y),
            Vec3::new(p.z, 0.0, -p.x),
            Vec3::new(-p.y, p.x, 0.0),
        ];
        for (c, column) in columns.into_iter().enumerate() {
            let v = (s * column).to_array();
            for (r, value) in v.into_iter().enumerate() {
                if let Some(slot) = rows.get_mut(r * MODES + c) {
                    *slot = value;
                }
            }
        }
    }
    Ok(modes)
}

/// The CG iterations per `e`-fold reduction of the linear residual beyond which a solve
/// counts as slow for the rebuild policy: [`REBUILD_FACTOR`] times the first solve's after a
/// build.
pub const REBUILD_FACTOR: Real = 2.0;

/// Smoothed-aggregation multigrid for Newton's linear solves (feature `alloc`): the
/// hierarchy and the policy that decides when to rebuild it. Give one to
/// [`NewtonScratch::with_multilevel`](super::NewtonScratch::with_multilevel) to keep it across
/// solves (time steps); without one, a solve that asks for
/// [`Preconditioner::Multilevel`](super::Preconditioner::Multilevel) builds its own.
///
/// # Rebuild policy
/// The hierarchy is built at the first Newton iteration that needs it and then reused, across
/// Newton iterations and across solves, while the Hessian drifts from the one it was built
/// for. A linear solve's cost is measured as CG iterations per `e`-fold reduction of its
/// residual, `k / ln(|r_0| / |r_k|)` (the forcing term asks for a different reduction every
/// iteration, so raw counts would not compare); when a solve costs more than
/// [`REBUILD_FACTOR`] times the first solve after the build (and more than 4 iterations),
/// the next Newton iteration rebuilds. [`invalidate`](Self::invalidate) asks for a rebuild
/// (after a remesh or a change of material, say).
///
/// ```
/// use softfem::element::{TetHessian, TetRest};
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::{Multilevel, TetElastic};
///
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
/// let tets = [[0, 1, 2, 3]];
/// let mut rest_data = [TetRest::default(); 1];
/// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
/// let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e4, 0.3)?);
/// let mut hessians = [TetHessian::default(); 1];
/// mesh.projected_hessians(&body.material, &rest, &mut hessians)?;
/// let mut multilevel = Multilevel::new();
/// // Vertex 0 pinned, unit masses, a step of 0.1 s (inertia 1 / h^2).
/// multilevel.build(&body, &hessians, &[1.0; 4], 100.0, &[true, false, false, false], &rest)?;
/// let mut z = [Vec3::ZERO; 4];
/// multilevel.apply(&[Vec3::X; 4], &mut z)?;
/// assert!(z[1].x > 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Default)]
pub struct Multilevel {
    hierarchy: Option<Hierarchy>,
    /// The cost (CG iterations per e-fold) of the first solve after the build.
    first_cost: Option<Real>,
    /// Whether the next Newton iteration rebuilds.
    stale: bool,
    /// Builds so far.
    builds: u32,
}

impl Multilevel {
    /// No hierarchy yet: built at first use.
    #[inline]
    #[must_use]
    pub const fn new() -> Self {
        Multilevel {
            hierarchy: None,
            first_cost: None,
            stale: false,
            builds: 0,
        }
    }

    /// Builds the hierarchy of `A = masses * inertia + H` (`H` the element Hessians in
    /// `hessians`, N/m; `inertia` 1/s^2: `1 / h^2` for a step of `h`, 0 for a static solve),
    /// pinned vertices removed, with the rigid-body modes at `positions` (m).
    ///
    /// # Errors
    /// [`StepError::LengthMismatch`] for a buffer of the wrong length,
    /// [`StepError::NewtonSettings`] for a model without element Hessians
    /// ([`ElasticHessian::for_each_element_hessian`]), [`StepError::VertexIndex`],
    /// [`StepError::OutOfMemory`].
    pub fn build<F: ElasticHessian>(
        &mut self,
        model: &F,
        hessians: &[TetHessian],
        masses: &[Real],
        inertia: Real,
        pinned: &[bool],
        positions: &[Vec3],
    ) -> Result<(), StepError> {
        let n = model.vertex_count();
        check_length(StepBuffer::Positions, n, positions.len())?;
        check_length(StepBuffer::Masses, n, masses.len())?;
        if !pinned.is_empty() {
            check_length(StepBuffer::Pinned, n, pinned.len())?;
        }
        let elements = model.element_count();
        check_length(StepBuffer::HessianScratch, elements, hessians.len())?;
        let diagonal = |i: usize| {
            Mat3::from_diagonal(Vec3::splat(
                masses.get(i).copied().unwrap_or(0.0) * inertia,
            ))
        };
        let projection = |i: usize| {
            if pinned.get(i).copied().unwrap_or(false) {
                Mat3::ZERO
            } else {
                Mat3::IDENTITY
            }
        };
        if self.rebuild(model, hessians, positions, &diagonal, &projection)? {
            Ok(())
        } else {
            Err(StepError::NewtonSettings)
        }
    }

    /// `out = M^-1 residual`, one V-cycle (zero where nothing is built), on the calling thread.
    ///
    /// # Errors
    /// [`StepError::LengthMismatch`] unless both buffers have one entry per vertex of the build.
    pub fn apply(&mut self, residual: &[Vec3], out: &mut [Vec3]) -> Result<(), StepError> {
        self.check_apply(residual, out)?;
        match self.hierarchy.as_mut() {
            Some(hierarchy) => hierarchy.apply(&InOrder, residual, out),
            None => out.fill(Vec3::ZERO),
        }
        Ok(())
    }

    /// [`apply`](Self::apply) with the cycle's passes run as `model` runs its passes over the
    /// vertices ([`ElasticModel::run_vertex_pass`]): on the pool of a
    /// `parallel::ParallelTetElastic` (feature `rayon`), with the bits of
    /// [`apply`](Self::apply) on any number of threads.
    ///
    /// # Errors
    /// As [`apply`](Self::apply).
    pub fn apply_with<F: ElasticModel>(
        &mut self,
        model: &F,
        residual: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), StepError> {
        self.check_apply(residual, out)?;
        self.apply_unchecked(model, residual, out);
        Ok(())
    }

    /// `Ok` where both buffers have one entry per vertex of the build.
    fn check_apply(&self, residual: &[Vec3], out: &[Vec3]) -> Result<(), StepError> {
        let n = self.hierarchy.as_ref().map_or(0, |h| h.vertices);
        for (buffer, actual) in [
            (StepBuffer::Scratch, residual.len()),
            (StepBuffer::Scratch, out.len()),
        ] {
            if actual != n {
                return Err(StepError::LengthMismatch {
                    buffer,
                    expected: n,
                    actual,
                });
            }
        }
        Ok(())
    }

    /// [`apply_with`](Self::apply_with) without the length check (the solver's buffers are
    /// checked).
    pub(crate) fn apply_unchecked<F: ElasticModel>(
        &mut self,
        model: &F,
        residual: &[Vec3],
        out: &mut [Vec3],
    ) {
        match self.hierarchy.as_mut() {
            Some(hierarchy) => model.run_vertex_pass(Cycle {
                hierarchy,
                residual,
                out,
            }),
            None => out.fill(Vec3::ZERO),
        }
    }

    /// Asks for a rebuild at the next Newton iteration that uses it.
    #[inline]
    pub fn invalidate(&mut self) {
        self.stale = true;
    }

    /// Whether a hierarchy is built.
    #[inline]
    #[must_use]
    pub fn is_built(&self) -> bool {
        self.hierarchy.is_some()
    }

    /// How many times the hierarchy was built.
    #[inline]
    #[must_use]
    pub fn builds(&self) -> u32 {
        self.builds
    }

    /// The unknowns of each level, finest first (empty before the first build), and the
    /// stored entries of its matrix.
    pub fn level_sizes(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.hierarchy
            .iter()
            .flat_map(|h| h.levels.iter())
            .map(|level| (level.matrix.rows, level.matrix.entries()))
    }

    /// Whether the next Newton iteration must build.
    pub(crate) fn needs_build(&self, vertices: usize) -> bool {
        self.stale || self.hierarchy.as_ref().is_none_or(|h| h.vertices != vertices)
    }

    /// Builds from the solver's own diagonal additions and projections; `false` (nothing
    /// built) for a model without element Hessians.
    pub(crate) fn rebuild<F: ElasticHessian>(
        &mut self,
        model: &F,
        hessians: &[TetHessian],
        positions: &[Vec3],
        diagonal: &dyn Fn(usize) -> Mat3,
        projection: &dyn Fn(usize) -> Mat3,
    ) -> Result<bool, StepError> {
        self.hierarchy = None;
        let hierarchy = match Hierarchy::new(model, hessians, positions, diagonal, projection) {
            Ok(hierarchy) => hierarchy,
            Err(SetupError::Unsupported) => return Ok(false),
            Err(SetupError::OutOfMemory) => return Err(StepError::OutOfMemory),
            Err(SetupError::VertexIndex(element, index)) => {
                return Err(StepError::VertexIndex { element, index });
            }
        };
        self.hierarchy = Some(hierarchy);
        self.first_cost = None;
        self.stale = false;
        self.builds += 1;
        Ok(true)
    }

    /// Records a linear solve of `iterations` that reduced its residual by `reduction`
    /// (`|r_k| / |r_0|`), for the rebuild policy.
    pub(crate) fn record(&mut self, iterations: u32, reduction: Real) {
        let folds = -libm_ln(reduction);
        if !(folds > 0.0 && folds.is_finite()) {
            return;
        }
        let cost = iterations as Real / folds;
        match self.first_cost {
            None => self.first_cost = Some(cost),
            Some(first) => {
                if iterations > 4 && cost > REBUILD_FACTOR * first {
                    self.stale = true;
                }
            }
        }
    }
}

/// The natural logarithm from the precision's math shim.
#[inline]
fn libm_ln(x: Real) -> Real {
    super::super::super::super::math::ln(x)
}

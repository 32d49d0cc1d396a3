//! Vertex Block Descent (Chen, Liu, Yang and Yuksel, "Vertex Block Descent", ACM Transactions on
//! Graphics 43(4), SIGGRAPH 2024): implicit Euler, and the quasi-static equilibrium, as the
//! minimisation of the same `Phi` as [`relax_step`](super::super::relax_step), by block
//! Gauss–Seidel over the vertices with one 3x3 Newton step per vertex (`docs/math.md` section 7).
//!
//! The method, its safeguards, contact handling and measured cost are documented on
//! [`vbd_step`].

mod block;
mod lanes;
pub(crate) mod layout;
mod sums;
mod sweep;

use super::super::super::material::Material;
use super::super::super::mesh::adjacency::{
    adjacency_incident_len, adjacency_offsets_len, build_vertex_adjacency, colour_vertices,
    vertex_order_by_degree,
};
use super::super::super::types::{Real, Vec3};
use super::super::contact::HalfSpace;
use super::super::contact::collider::Colliders;
use super::super::descent::{self, LoopSettings, Work};
use super::super::model::{ElasticEnergy, TetElastic};
use super::super::scene::Scene;
use super::super::scratch_len;
use super::super::state::{check_length, check_state};
use super::chebyshev::AccelerationSettings;
use super::settings::{DescentReport, DescentSettings};
use super::stopping::StallRule;
use crate::error::{StepBuffer, StepError};
use layout::{Layout, LayoutSource, build_layout};
pub(crate) use sweep::{Bodies, ContactBuffersVbd, SweepMesh, SweepRun, SweepSchedule};
use sweep::{Sweep, VbdSweep};

/// Scratch space of [`vbd_step`] and [`vbd_quasi_static`]: `vectors` of
/// [`scratch_len::vbd`]`(vertex_count)` entries and `indices` of
/// [`scratch_len::vbd_indices`]`(vertex_count, element_count)` (lengths checked by the solvers).
///
/// `indices` keeps the mesh's vertex adjacency, colouring and vertex order between calls: built
/// by the first solve with this scratch (or the first after a change of the mesh's vertex or
/// element count) and reused after. After changing the mesh's connectivity at equal counts, call
/// [`reset_topology`](VbdScratch::reset_topology). The previous contents of both buffers never
/// matter.
///
/// Optionally ([`with_layout`](VbdScratch::with_layout)) two more buffers hold the packed
/// element visits of the sweep, which make a sweep cheaper at the same results.
#[derive(Debug)]
pub struct VbdScratch<'a> {
    vectors: &'a mut [Vec3],
    indices: &'a mut [u32],
    /// Where given, the incident elements of the adjacency, which `indices` then leaves out
    /// (see [`split`](Self::split)).
    incident: Option<&'a mut [u32]>,
    /// Where given, the buffers of the contact's terms (see [`with_contact`](Self::with_contact)).
    contact: Option<ContactBuffersVbd<'a>>,
    /// The vertex count, element count and colour count of the topology in `indices`.
    topology: Option<(usize, usize, u32)>,
    layout: Option<LayoutBuffers<'a>>,
}

/// The caller's buffers of the packed sweep layout, and whether they hold the layout of the
/// current topology.
#[derive(Debug)]
struct LayoutBuffers<'a> {
    values: &'a mut [Real],
    corners: &'a mut [u32],
    /// `Some(true)`: built for the topology; `Some(false)`: it did not fit; `None`: not built.
    built: Option<bool>,
}

impl<'a> VbdScratch<'a> {
    /// Scratch over the caller's buffers; the first solve builds the topology.
    #[inline]
    #[must_use]
    pub fn new(vectors: &'a mut [Vec3], indices: &'a mut [u32]) -> Self {
        VbdScratch {
            vectors,
            indices,
            incident: None,
            contact: None,
            topology: None,
            layout: None,
        }
    }

    /// This scratch with room for the packed sweep layout: `values` of
    /// [`scratch_len::vbd_layout`](super::super::scratch_len::vbd_layout)`(element_count)` entries and `corners` of
    /// [`scratch_len::vbd_layout_corners`](super::super::scratch_len::vbd_layout_corners)`(vertex_count,
    /// element_count)` (longer buffers are fine, shorter ones leave the layout unused).
    ///
    /// The first solve (after a change of topology) stores there, for every element visit of a
    /// sweep in sweep order, the element's corner indices, `Dm^-1`, volume and the corner's
    /// shape gradient, already laid out for the SIMD lanes, so that the sweeps load them
    /// instead of gathering them element by element. The results are the same bits with or
    /// without it, at every SIMD width and thread count (`tests/steppers/vbd.rs`,
    /// `tests/kernels/simd.rs`); only the time differs: measured on one thread, a sweep costs
    /// 0.6-0.9 of the gathered one (see [`vbd_step`](vbd_step#when-to-pick-it)). A mesh whose
    /// vertex valences are so uneven that its layout does not fit is swept without it (see
    /// [`layout_in_use`](Self::layout_in_use)). The layout copies the mesh's rest data: after
    /// changing the mesh call [`reset_topology`](Self::reset_topology).
    #[inline]
    #[must_use]
    pub fn with_layout(self, values: &'a mut [Real], corners: &'a mut [u32]) -> Self {
        VbdScratch {
            layout: Some(LayoutBuffers {
                values,
                corners,
                built: None,
            }),
            ..self
        }
    }

    /// Whether the last solve swept with the packed layout of
    /// [`with_layout`](VbdScratch::with_layout) (`false` without one, before the first solve, or
    /// where it did not fit the buffers).
    #[inline]
    #[must_use]
    pub fn layout_in_use(&self) -> bool {
        self.layout
            .as_ref()
            .is_some_and(|layout| layout.built == Some(true))
    }

    /// Makes the next solve rebuild the adjacency and colouring (after a change of the mesh).
    #[inline]
    pub fn reset_topology(&mut self) {
        self.topology = None;
        if let Some(layout) = &mut self.layout {
            layout.built = None;
        }
    }
}

/// The vertex, element and colour counts of the topology a [`VbdScratch`] holds in `indices`.
pub(crate) type VbdTopology = Option<(usize, usize, u32)>;

impl<'a> VbdScratch<'a> {
    /// Scratch over the caller's buffers (as [`new`](Self::new)) whose `indices` already hold
    /// `topology`, as [`topology`](Self::topology) reported it.
    #[inline]
    #[must_use]
    pub(crate) fn resume(
        vectors: &'a mut [Vec3],
        indices: &'a mut [u32],
        topology: VbdTopology,
    ) -> Self {
        VbdScratch {
            vectors,
            indices,
            incident: None,
            contact: None,
            topology,
            layout: None,
        }
    }

    /// Scratch whose index buffer comes in two parts, as a world's fixed storage holds it:
    /// `indices` the per-vertex part (`3 n + 1` entries: the adjacency's offsets, the colours
    /// and the order) and `incident` the adjacency's incident elements (`4 t`), holding
    /// `topology`. With the contact's buffers (one entry per vertex each).
    #[inline]
    #[must_use]
    pub(crate) fn split(
        vectors: &'a mut [Vec3],
        (indices, incident): (&'a mut [u32], &'a mut [u32]),
        contact: ContactBuffersVbd<'a>,
        topology: VbdTopology,
    ) -> Self {
        VbdScratch {
            vectors,
            indices,
            incident: Some(incident),
            contact: Some(contact),
            topology,
            layout: None,
        }
    }

    /// The topology in `indices` (for [`resume`](Self::resume)).
    #[inline]
    #[must_use]
    pub(crate) fn topology(&self) -> VbdTopology {
        self.topology
    }

    /// This scratch with the packed layout of [`with_layout`](Self::with_layout) over buffers
    /// whose state for the topology is `built`, as [`layout_built`](Self::layout_built)
    /// reported it after the last solve over them.
    #[inline]
    #[must_use]
    pub(crate) fn resume_layout(
        self,
        values: &'a mut [Real],
        corners: &'a mut [u32],
        built: Option<bool>,
    ) -> Self {
        VbdScratch {
            layout: Some(LayoutBuffers {
                values,
                corners,
                built,
            }),
            ..self
        }
    }

    /// The state of the packed layout's buffers (for [`resume_layout`](Self::resume_layout)):
    /// `None` without a layout or before it is built.
    #[inline]
    #[must_use]
    pub(crate) fn layout_built(&self) -> Option<bool> {
        self.layout.as_ref().and_then(|layout| layout.built)
    }
}

/// What only Vertex Block Descent has: when its per-vertex line search runs and its Chebyshev
/// acceleration over sweeps. The rest of [`VbdSettings`] is shared with every implicit solver
/// ([`DescentSettings`]; its Armijo constant, backtracking factor and backtrack budget are those
/// of the per-vertex line search, and a budget of 0 turns it off).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VbdOptions {
    /// Take every Newton step whole and run the line search only in a sweep whose full steps
    /// did not lower `Phi` enough: the evaluation after each sweep (which the stopping test
    /// needs anyway) detects it (the first trial of the descent loop's Armijo search fails),
    /// and the sweep is then redone from its start with the line search
    /// ([`max_backtracks`](DescentSettings::max_backtracks) > 0), and the Chebyshev weights
    /// restart. Iterates stay monotone at the cost of the plain sweep where the full steps are
    /// safe. Ignored when `max_backtracks` is 0.
    pub line_search_on_increase: bool,
    /// Chebyshev acceleration over sweeps: `rho` in `[0, 1)`, the estimated spectral radius of
    /// the plain sweep; 0 turns it off (see [`vbd_step`](vbd_step#acceleration)).
    pub chebyshev: Real,
    /// Plain sweeps after each (re)start before the Chebyshev weights start.
    pub chebyshev_delay: u32,
    /// Estimate `rho` instead of taking [`chebyshev`](Self::chebyshev) (which must then be 0):
    /// the largest residual ratio `r_k / r_(k-1)` of plain sweeps `2..=chebyshev_delay` of the
    /// solve (`chebyshev_delay >= 2`), at most
    /// [`MAX_ESTIMATED_RHO`](VbdOptions::MAX_ESTIMATED_RHO). Plain Gauss–Seidel contracts the slow
    /// modes by about a fixed rate a sweep once the fast ones are gone, which the largest early
    /// ratio measures; it errs high, which Chebyshev tolerates better than low, up to the cap (see
    /// [`MAX_ESTIMATED_RHO`](VbdOptions::MAX_ESTIMATED_RHO)).
    pub estimate_chebyshev: bool,
}

impl VbdOptions {
    /// The largest spectral radius [`estimate_chebyshev`](Self::estimate_chebyshev) uses: 0.98.
    ///
    /// The Chebyshev weights are those of a real spectrum in `[-rho, rho]`, and the iteration
    /// matrix of a Gauss–Seidel sweep has complex eigenvalues, so `rho` at the plain sweeps' own
    /// rate can diverge where that rate is close to 1. Measured on the clamped stiff block of
    /// `tests/steppers/vbd.rs` (`measure_stiff_block`): in its third step the plain sweeps contract
    /// the residual by 0.988 each (the first seven ratios all 0.988), the accelerated sweeps
    /// diverge with any `rho` from 0.985 up (at the estimate 0.988: three rejected trials, 500
    /// sweeps, not converged) and converge up to 0.98 (227 sweeps at 0.98, 295 at 0.95). The cap
    /// was 0.99 until then, which let that step fail (29 of 30 steps converged, 1093 sweeps); with
    /// 0.98 all 30 do in 663 sweeps.
    pub const MAX_ESTIMATED_RHO: Real = MAX_ESTIMATED_RHO;
}

/// The settings of Vertex Block Descent ([`vbd_step`], [`vbd_quasi_static`]): the shared
/// [`DescentSettings`] with [`VbdOptions`]. The budget counts sweeps.
pub type VbdSettings = DescentSettings<VbdOptions>;

/// See [`VbdOptions::MAX_ESTIMATED_RHO`].
pub(crate) const MAX_ESTIMATED_RHO: Real = 0.98;

impl DescentSettings<VbdOptions> {
    /// Relative tolerance `1e-3`, 100 sweeps, line search with `c = 1e-4`, `beta = 0.5` and 8
    /// backtracks, no acceleration.
    #[inline]
    #[must_use]
    pub const fn new() -> Self {
        DescentSettings {
            tolerance: 1e-3,
            max_iterations: 100,
            armijo: 1e-4,
            backtrack: 0.5,
            max_backtracks: 8,
            options: VbdOptions {
                line_search_on_increase: false,
                chebyshev: 0.0,
                chebyshev_delay: 0,
                estimate_chebyshev: false,
            },
        }
    }

    /// These settings with Chebyshev acceleration for the spectral radius estimate `rho`,
    /// starting after `delay` plain sweeps.
    #[inline]
    #[must_use]
    pub fn with_chebyshev(self, rho: Real, delay: u32) -> Self {
        let options = VbdOptions {
            chebyshev: rho,
            chebyshev_delay: delay,
            estimate_chebyshev: false,
            ..self.options
        };
        DescentSettings { options, ..self }
    }

    /// These settings with Chebyshev acceleration for a `rho` the solver estimates from the
    /// first `delay` plain sweeps (`delay >= 2`; see
    /// [`estimate_chebyshev`](VbdOptions::estimate_chebyshev)).
    #[inline]
    #[must_use]
    pub fn with_estimated_chebyshev(self, delay: u32) -> Self {
        let options = VbdOptions {
            chebyshev: 0.0,
            chebyshev_delay: delay,
            estimate_chebyshev: true,
            ..self.options
        };
        DescentSettings { options, ..self }
    }

    /// These settings with the line search only in sweeps that raised `Phi` (see
    /// [`line_search_on_increase`](VbdOptions::line_search_on_increase)).
    #[inline]
    #[must_use]
    pub fn with_line_search_on_increase(self) -> Self {
        let options = VbdOptions {
            line_search_on_increase: true,
            ..self.options
        };
        DescentSettings { options, ..self }
    }

    /// These settings with at most `max_backtracks` backtracks per vertex update (0: no line
    /// search).
    #[inline]
    #[must_use]
    pub fn with_line_search(self, max_backtracks: u32) -> Self {
        DescentSettings {
            max_backtracks,
            ..self
        }
    }

    /// Checks the settings.
    ///
    /// # Errors
    /// [`StepError::VbdSettings`] unless the shared part is in range and so are the options:
    /// `rho` in `[0, 1)`, an estimate only without a fixed `rho` and with a delay of at least 2.
    fn check(&self) -> Result<(), StepError> {
        let o = &self.options;
        if !(self.shared_part_valid()
            && (0.0..1.0).contains(&o.chebyshev)
            && !(o.estimate_chebyshev && (o.chebyshev != 0.0 || o.chebyshev_delay < 2)))
        {
            return Err(StepError::VbdSettings);
        }
        Ok(())
    }
}

/// What only Vertex Block Descent counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VbdDetails {
    /// The number of colours of the vertex colouring (the sweep's parallel stages).
    pub colours: u32,
    /// Per-vertex line-search trials rejected (the loop's own, along whole sweeps, are the
    /// report's [`backtracks`](DescentReport::backtracks)).
    pub vertex_backtracks: u32,
    /// Sweeps redone with the line search because the full steps did not lower `Phi` enough
    /// (with [`VbdOptions::line_search_on_increase`]).
    pub redone_sweeps: u32,
    /// Vertex updates skipped: block not positive definite (after regularisation), not finite,
    /// no descent, or no acceptable step within the backtracks.
    pub skipped: u32,
    /// Vertex updates whose exact block (inertia plus the exact element blocks) was not
    /// positive definite and was replaced by the inertia plus the positive part of its elastic
    /// sum (see [`vbd_step`](vbd_step#one-sweep)).
    pub projected: u32,
}

/// What a Vertex Block Descent solve did: the shared [`DescentReport`] with [`VbdDetails`].
/// Total cost = `iterations` sweeps (accepted iterations of the descent loop; a rejected
/// Chebyshev trial, counted in `restarts`, costs one sweep more; accelerated sweeps accepted
/// without evaluation and later returned from count too, see
/// [`vbd_step`](vbd_step#stopping-test-and-cost)) plus `energy_evaluations` fused
/// energy-and-force passes (one or two for the initial guess, one per plain sweep, one per
/// accelerated sweep that is not deferred, one after a solve that ends on a deferred one, and
/// one per shortened sweep step).
pub type VbdReport = DescentReport<VbdDetails>;

/// A model Vertex Block Descent solves ([`vbd_step`], [`vbd_quasi_static`]): a tetrahedral body
/// whose energy ([`ElasticEnergy`]) the descent loop evaluates and whose vertices the sweeps
/// update, each sweep's updates run in the model's schedule. Sealed: implemented by
/// [`TetElastic`] (every sweep on the calling thread, the vertices one after the other) and,
/// with feature `rayon`, by `softfem::parallel::ParallelTetElastic` (the updates of each colour
/// in parallel, on the model's pool if `with_pool` gave one, else on the current pool, and the
/// energy evaluations and vertex passes on that pool as for the other solvers): the same
/// result, bit for bit, for any number of threads (see [`vbd_step`](vbd_step#parallel-sweeps)).
///
/// ```
/// # #[cfg(feature = "rayon")] {
/// use softfem::element::TetRest;
/// use softfem::generate::{BoxSplit, box_counts, fill_box};
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::{TetMesh, TetPartition, element_forces_len};
/// use softfem::mesh::{partition_incident_len, partition_offsets_len};
/// use softfem::parallel::ParallelTetElastic;
/// use softfem::step::{Scene, TetElastic, VbdScratch, VbdSettings, vbd_step};
/// use softfem::step::{scratch_len};
///
/// let (n, t) = box_counts(3, 3, 3, BoxSplit::Kuhn6)?;
/// let (mut rest, mut tets) = (vec![Vec3::ZERO; n], vec![[0; 4]; t]);
/// fill_box(Vec3::ZERO, Vec3::splat(0.1), 3, 3, 3, BoxSplit::Kuhn6, &mut rest, &mut tets)?;
/// let mut rest_data = vec![TetRest::default(); t];
/// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
/// let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e5, 0.3)?);
/// let mut masses = vec![0.0; n];
/// mesh.lumped_masses(1000.0, &mut masses)?;
/// let pinned: Vec<bool> = rest.iter().map(|p| p.y == 0.0).collect();
/// let scene = Scene::new(1.0 / 60.0).with_gravity(Vec3::new(0.0, -9.81, 0.0));
/// let settings = VbdSettings::new();
/// let mut vectors = vec![Vec3::ZERO; scratch_len::vbd(n)];
/// let mut indices = vec![0; scratch_len::vbd_indices(n, t)];
/// let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
/// let (mut x, mut v) = (rest.clone(), vec![Vec3::ZERO; n]);
/// vbd_step(&body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch)?;
///
/// // The same step with the sweeps and evaluations on a pool of two threads.
/// let mut offsets = vec![0; partition_offsets_len(n)];
/// let mut incident = vec![0; partition_incident_len(t)];
/// let partition = TetPartition::new(mesh, 2, &mut offsets, &mut incident)?;
/// let mut element_forces = vec![[Vec3::ZERO; 4]; element_forces_len(t)];
/// let mut energies = vec![0.0; t];
/// let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build()?;
/// let threaded = ParallelTetElastic::new(body, partition, &mut element_forces, &mut energies)?
///     .with_pool(&pool);
/// let (mut x2, mut v2) = (rest.clone(), vec![Vec3::ZERO; n]);
/// vbd_step(&threaded, &masses, &pinned, &scene, &settings, &mut x2, &mut v2, &mut scratch)?;
/// assert_eq!((x2, v2), (x, v)); // and bit for bit
/// # }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub trait VertexBlockModel: ElasticEnergy<Vector = Vec3> + SweepSchedule {}

impl<M: Material> SweepSchedule for TetElastic<'_, M> {
    type Material = M;

    #[inline]
    fn sweep_mesh(&self) -> SweepMesh<'_, M> {
        SweepMesh::of(self)
    }

    #[inline]
    fn run_sweep(&self, run: SweepRun<'_, '_, M>) {
        run.in_order();
    }
}

impl<M: Material> VertexBlockModel for TetElastic<'_, M> {}

/// One implicit Euler step of the scene's `dt` by Vertex Block Descent (Chen, Liu, Yang and
/// Yuksel, "Vertex Block Descent", ACM Transactions on Graphics 43(4), SIGGRAPH 2024):
/// minimises
/// `Phi(x) = sum m/(2 h^2) |x - y|^2 + E(x) - sum m g.(x - x_n)`, `y = x_n + h v_n`, the
/// objective of [`relax_step`](super::super::relax_step), from the same initial guess (the
/// lower-`Phi` of `y` and `y + h^2 g`, both projected on the ground), then sets `v = (x_{n+1} -
/// x_n) / h` and applies the relaxation's Coulomb friction at the contacts.
///
/// Pinned vertices keep position and velocity. Not converging within the budget is not an
/// error: the last iterate is used and [`DescentReport::converged`] is false.
/// [`DescentReport::converged`] is true exactly when the residual of the returned state is
/// finite and at most a finite target (see [Stopping test and cost](#stopping-test-and-cost)); a
/// stall ([`DescentReport::stagnated`]), a sweep that is not downhill or an overflowed residual
/// or target is never converged. The result does not depend on the previous contents of the
/// scratch buffers, and is the same on every target.
///
/// # Initial guess
/// The relaxation's lower-`Phi` of `y` and `y + h^2 g` by default. Given the velocities
/// `v_(n-1)` before the previous step ([`Scene::with_previous_velocities`]), the paper's
/// adaptive guess replaces `y`: `y_i + h^2 a~_i`, `a~_i` the previous step's acceleration
/// `(v_n - v_(n-1)) / h` projected on the direction of gravity and clamped to `[0, |g|]` along
/// it (`docs/math.md` section 7.2), still compared with `y + h^2 g`. A time loop keeps
/// `v_(n-1)` by copying the velocities before each step. Measured on the bouncy example
/// (180 steps of 1/60 s, tolerance 2e-3, Chebyshev 0.95 after 2 sweeps) it did not pay: 5.0
/// sweeps a step on average against 4.5 without it (4.5 and 5.3 where it replaced
/// `y + h^2 g` instead); the default two candidates already hold the free fall and the rest.
///
/// # One sweep
/// For every free vertex `i`, colour by colour (the colouring of
/// [`colour_vertices`](super::super::super::mesh::colour_vertices); within a colour by decreasing number of
/// incident elements, then by index, an order that changes no iterate, since no two vertices of
/// a colour share an element; only the rounding of the sweep's residual estimate, summed in
/// sweep order, depends on it), with every other vertex held where it is: the gradient and
/// Hessian of the terms of `Phi` that depend on `x_i`,
/// `g_i = m_i / h^2 (x_i - y_i) - m_i g - sum_e f_e,i(x)` and
/// `H_i = m_i / h^2 I + sum_e H_e,ii(x)` over the elements `e` around `i`, `f_e,i` the elastic
/// force of `e` on `i` and `H_e,ii` the exact 3x3 diagonal block of its Hessian, both from
/// one deformation gradient per element by
/// [`Material::corner_stress_and_stiffness`] (closed forms, no SVD; `docs/math.md` section
/// 7.2). These sums are formed for several vertices of a colour at once, one vertex per SIMD
/// lane at the width [`simd`](crate::simd) picks
/// ([`Material::corner_stress_and_stiffness_wide`]), each lane over its own vertex's elements
/// in their adjacency order: every width gives the same bits. `H_i` is factored as `L D L^T`
/// (Cholesky without square roots: three divisions, and a solve of multiplications only) where
/// it is positive definite (always for
/// [`StableNeoHookean`](super::super::super::material::StableNeoHookean), whose element blocks all
/// are); elsewhere the elastic sum is replaced by its positive semi-definite part (one 3x3
/// eigen-decomposition for that vertex, counted in [`VbdDetails::projected`]) and regularised
/// where singular, so the matrix solved with is always symmetric positive definite and the step
/// `d = -H_i^-1 g_i` a descent direction of the local energy (see [`VbdSettings`] for the
/// guards). Then a backtracking line search on the vertex's local energy
/// `m_i / (2 h^2) |x_i - y_i|^2 - m_i g.x_i + sum_e V_e W(F_e)`, and the update. Each accepted
/// update lowers `Phi` (every term of `Phi` that depends on `x_i` is in the local energy), so a
/// sweep is monotone.
///
/// # Contact
/// A step that would end inside the [`HalfSpace`] is replaced by the minimiser of the vertex's
/// local quadratic model on the ground plane (one more 3x3 solve with the same factor; the
/// multiplier is the contact reaction), then projected onto the plane for rounding: the exact
/// solution of the local contact problem for the quadratic model, where the relaxation only
/// projects; a step into a [`Collider`](super::super::Collider) is replaced the same way on its
/// tangent plane at the vertex. Friction acts on the velocity after the solve, or, opted in with a
/// positive [`HalfSpace::sticking_speed`], is part of the objective (`docs/math.md` section 4.6): its
/// gradient and tangent block join the vertex's, lagged to the loop's iterate.
///
/// # The descent loop
/// The sweeps run in the descent loop every implicit solver here shares (`docs/math.md`
/// section 7.0): a sweep from the iterate `x` is the direction `d = sweep(x) - x`, whose first
/// trial is the sweep's result itself, and the loop's Armijo line search (constant
/// [`DescentSettings::armijo`], factor [`DescentSettings::backtrack`], at most 8 halvings) accepts
/// it or shortens it, with the rounding of the elastic energy (`64 eps sum V_e tr(K_e) / |g_a|^2`
/// over the element corners, as in the vertex line search) tolerated where `Phi`'s change is below
/// it; a sweep that is not downhill, or not acceptable after 8 halvings, ends the solve (not
/// converged).
///
/// # Acceleration
/// The paper's Chebyshev semi-iteration over whole sweeps: `x^(n) = omega_n (xbar^(n) -
/// x^(n-2)) + x^(n-2)`, `xbar^(n)` the result of sweep `n`, with `omega_1 = 1`,
/// `omega_2 = 2 / (2 - rho^2)` and `omega_n = 4 / (4 - rho^2 omega_(n-1))` (Wang, "A
/// Chebyshev semi-iterative approach for accelerating projective and position-based dynamics",
/// SIGGRAPH Asia 2015), applied per free vertex and projected onto the ground: the loop's
/// Chebyshev trial. An evaluated accelerated iterate whose `Phi` is higher (beyond rounding)
/// than the last evaluated one is rejected (with the unevaluated ones since, see below) and the
/// weights restart with a plain, line-searched sweep, as in the relaxation.
///
/// # Stopping test and cost
/// `Phi` and its gradient are evaluated with the relaxation's own passes, so the residual
/// (`|grad Phi|` projected on the contacts) and the test
/// `|grad Phi| <= tolerance * max(|grad Phi(x_0)|, |M g|)` are exactly the relaxation's, and
/// so is the stall window (the rounding floor estimated from the exact vertex blocks at the
/// initial guess). They are evaluated after every plain sweep. Accelerated sweeps are
/// evaluated too until three in a row since the last (re)start of the weights have passed
/// the check on `Phi`; after that (without friction in `Phi`) the loop accepts up to 1, 2, 4,
/// then 8 of them in a row unevaluated, and evaluates one early when the sweep's own
/// Gauss–Seidel residual (the norm of the projected vertex gradients its updates start from),
/// calibrated against the true residual at the last evaluated iterate, predicts that it meets
/// the target, or rises. An evaluated sweep is checked against `Phi` at the last evaluated
/// iterate, and a rise returns there (the sweeps since count in
/// [`DescentReport::iterations`]) and restarts the weights; a solve that ends on an unevaluated
/// sweep evaluates it (returning to the last evaluated iterate if `Phi` rose). So the
/// residual and `Phi` reported are always those of the returned state, and
/// [`DescentReport::converged`] only if that residual meets the tolerance (`docs/math.md`
/// section 7.2). A plain iteration costs a sweep (per element and corner one deformation
/// gradient, `P g` and the exact block, and with the line search one or two energy densities
/// per trial) plus one fused energy-and-force pass; a deferred one, the sweep. On the single
/// solves of the descent chart (f64, `with_chebyshev(0.95, 2)`, no line search) the landing
/// step of the bouncy cube took the same 40 sweeps with 18 evaluations instead of 44, and the
/// stiff block the same 31 sweeps with 20 instead of 35, the same final residuals.
///
/// # Parallel sweeps
/// Given a `softfem::parallel::ParallelTetElastic` (feature `rayon`; see
/// [`VertexBlockModel`]), the solve runs each colour's updates on the model's pool (the
/// current rayon pool unless `with_pool` gave one), and the energy evaluations and passes over
/// the vertices between sweeps there too, as the other solvers do with that model; it returns
/// the result of the sequential [`TetElastic`] bit for bit, for any number of threads: two
/// vertices of one colour share no element, so a colour's updates are computed from the
/// positions before the colour and written back after it, which is what the sequential sweep
/// computes in place (`docs/math.md` section 7.2), and the model's passes have the sequential
/// bits (see `softfem::parallel`). The sweep of an accelerated trial runs in order (the loop
/// has no vector left over for the parallel schedule's staging there): the same bits, on one
/// thread.
///
/// # When to pick it
/// Measured with `cargo test --release --all-features --test vbd measure_ -- --ignored
/// --nocapture --test-threads 1` (x86_64 with AVX-512, one thread, a shared 2-core machine at a
/// load of 3 to 5; the solvers interleaved step by step, each step's least wall time over three
/// repeats, and the thread's CPU time). On the bouncy cube's 1296 tetrahedra (f32) a sweep cost
/// 6.9-7.0 force passes without the line search (17 ns per element visit: `F`, `P g` and the
/// exact 3x3 block, no SVD, sixteen vertices per AVX-512 group) and 27-28 with it (the trial
/// energies are evaluated one vertex at a time); the scalar sweep before the lanes cost 14.0
/// and 39 on the same machine. Each element is still visited once per corner, and a visit
/// gathers its corners' positions and rest data lane by lane, which is now most of its time,
/// where a force pass gathers once per element. `cargo bench -p softfem-benches --features rayon
/// --bench vbd` (load 3) gave 6.3 force passes at 10 368 tetrahedra and 7.9 at 105 456, where the
/// gather runs from the last-level cache (the scalar sweep, built and run right after: 15.5 and
/// 17.0). With the packed layout of [`VbdScratch::with_layout`] a visit loads its rest data
/// instead of gathering it: `measure_sweep_cost` (load 5-8) gave 5.9-6.4 force passes on the
/// bouncy cube where the gathered sweep gave 6.7-7.5 in the same run, and the criterion medians
/// of `cargo bench -p softfem-benches --features rayon --bench vbd` (load 5-7, one run) 4.7 force
/// passes at 10 368 tetrahedra (gathered: 6.2) and 6.7 at 105 456 (gathered: 11.7), the same bits.
/// With the vertex block factored as `L D L^T` without square roots, one run of `cargo bench -p
/// softfem-benches --features rayon --bench vbd -- zzz` on a quiet machine (Intel Xeon with
/// AVX-512, load below 1) gave 2.86 force passes per sweep at 10 368 tetrahedra and 2.91 at 105 456
/// with the packed layout (gathered: 4.65 and 5.75). The packed sweep gathers its corners'
/// positions four lanes at a time through the force passes' SSE transposes (it set them lane by
/// lane before): in three interleaved runs of that bench on an AMD EPYC with AVX2 (2026-12-03,
/// 22:00 UTC) its sweep took 0.81-0.91 of the time it took before, 3.44-3.68 force passes
/// at 10 368 tetrahedra (4.05-4.27 before) and 4.33-4.49 at 105 456 (4.90-5.26), the same
/// bits. A sweep computes `F`, `P g` and the 3x3 block once per element and corner, where a
/// force pass computes `F` and `P` once per element. In
/// iterations VBD gains only with acceleration: over the bouncy cube's 180 steps of 1/60 s
/// (tolerance 2e-3) 2239 sweeps with Chebyshev 0.95 (all 180 steps converge) against the
/// relaxation's 5351 iterations, 2.0 times the relaxation's wall time (1.96 times its CPU
/// time). On the clamped stiff block (E = 1e8 Pa, 1/30 s, tolerance 1e-4) 663 sweeps with the
/// estimated `rho` (30 of 30 steps converge; see
/// [`MAX_ESTIMATED_RHO`](VbdOptions::MAX_ESTIMATED_RHO)) or 724 with Chebyshev 0.95 (30 of 30)
/// against 1798 iterations (28 of 30), 1.7-1.8 times its wall time (the relaxation's whole run
/// there is about 6 ms, so these ratios vary most). On the free stiff block, where both sit at the
/// rounding floor and use their budget (6 and 4 of 30 steps converge), VBD took 0.22-0.37 of the
/// relaxation's wall time. So the target of half the relaxation's wall time at the same residual is
/// not met on the bouncy cube or the clamped block; only on the free block, where neither reaches
/// the tolerance. Pick it for what the count of iterations cannot show: every accepted vertex
/// update lowers `Phi` (sweeps are monotone, accelerated ones checked), so a small fixed budget of
/// sweeps is always safe, and its per-vertex Newton steps (with the exact local Hessian) resolve
/// stiff local modes the diagonal preconditioner of the relaxation does not; and for threads: the
/// colour-parallel sweep keeps the bits. For speed take the full steps with the line search only in
/// sweeps that raised `Phi`
/// ([`VbdSettings::with_line_search_on_increase`](DescentSettings::<VbdOptions>::with_line_search_on_increase):
/// the cost of no line search, and still monotone) or no line search at all
/// ([`VbdSettings::with_line_search`](DescentSettings::<VbdOptions>::with_line_search)`(0)`), with
/// Chebyshev acceleration
/// ([`VbdSettings::with_chebyshev`](DescentSettings::<VbdOptions>::with_chebyshev)`(0.95, 2)` was
/// best on the bouncy cube, the estimate
/// [`VbdSettings::with_estimated_chebyshev`](DescentSettings::<VbdOptions>::with_estimated_chebyshev)
/// on the 30 steps of the clamped stiff block). On the single solves of the descent chart (`cargo
/// run --release -p softfem-examples --features charts --bin tradeoffs -- --only descent`, f64, no
/// line search) `(0.95, 2)` took 41 sweeps on the bouncy cube's landing and 31 on the stiff block's
/// first step, where the estimate from 4 plain sweeps took 111 and 81 (0.9: 65 and 42; 0.98: 40 and
/// 41); in wall time, back to back at a load of 4 to 6, 0.5 to 0.9 of GD + Chebyshev's on the
/// landing (the estimate: 1.6 to 2.3) and 2.1 to 3.3 of it on the stiff block (the estimate: 3.4 to
/// 5.5); after the `L D L^T` solve, one quiet run: 40 and 31 sweeps, 0.62 and 2.0 times GD +
/// Chebyshev's time. With the deferred evaluations of accelerated sweeps (see [the stopping
/// test](#stopping-test-and-cost)), one run of the chart at a load of 4 to 5: the same 40 and 31
/// sweeps and final residuals with 18 and 20 evaluations (44 and 35 before), 2.7 and 5.2 force
/// passes an iteration (3.3 and 5.6 before), 0.47 and 1.9 times GD + Chebyshev's time. On the stiff
/// block's 96 tetrahedra a sweep alone costs about 4.4 force passes (8 colours of at most 6
/// vertices, so the 8 f64 lanes of a group are partly idle, and every element is visited once per
/// corner), against GD + Chebyshev's 1.3 an iteration for 64 iterations (85 force passes in all):
/// half its time, after VBD's start of about 7 force passes (the initial guesses and the block
/// norms of the rounding floor), would leave 31 sweeps about 1.15 force passes each, or far fewer
/// sweeps.
///
/// ```
/// use softfem::element::TetRest;
/// use softfem::glam::Vec3;
/// use softfem::material::StableNeoHookean;
/// use softfem::mesh::TetMesh;
/// use softfem::step::{
///     Scene, TetElastic, VbdScratch, VbdSettings, scratch_len,
///     vbd_step,
/// };
///
/// // A tetrahedron hanging from three pinned corners sags under gravity.
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Z, -Vec3::Y].map(|x| x * 0.1);
/// let tets = [[0, 1, 2, 3]];
/// let mut rest_data = [TetRest::default(); 1];
/// let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
/// let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(1.0e4, 0.3)?);
/// let mut masses = [0.0; 4];
/// mesh.lumped_masses(1000.0, &mut masses)?;
/// let pinned = [true, true, true, false];
/// let scene = Scene::new(1.0 / 60.0).with_gravity(Vec3::new(0.0, -9.81, 0.0));
/// let settings = VbdSettings::new();
/// let (mut x, mut v) = (rest, [Vec3::ZERO; 4]);
/// let mut vectors = [Vec3::ZERO; scratch_len::vbd(4)];
/// let mut indices = [0; scratch_len::vbd_indices(4, 1)];
/// let mut scratch = VbdScratch::new(&mut vectors, &mut indices);
/// let report = vbd_step(&body, &masses, &pinned, &scene, &settings, &mut x, &mut v, &mut scratch)?;
/// // One free vertex: each sweep is a Newton step on Phi.
/// assert!(report.converged && report.iterations <= 5, "{report:?}");
/// assert!(x[3].y < rest[3].y && v[3].y < 0.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// Before anything is touched: the scene's errors ([`Scene::validated`]: the time step, gravity,
/// colliders, the ground), [`StepError::VbdSettings`], [`StepError::LengthMismatch`] (also for
/// the scene's and the scratch buffers), [`StepError::Mass`], [`StepError::NonFiniteInput`]
/// (also for the previous velocities), the loads' errors, [`StepError::TooManyElements`].
/// [`StepError::NonFiniteState`] if `Phi` is not finite at both `y` and `x_n` or the result is not
/// finite; the state is then restored bit for bit.
#[allow(clippy::too_many_arguments)]
pub fn vbd_step<F: VertexBlockModel>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, Vec3>,
    settings: &VbdSettings,
    positions: &mut [Vec3],
    velocities: &mut [Vec3],
    scratch: &mut VbdScratch<'_>,
) -> Result<VbdReport, StepError> {
    minimise(
        (model, masses, pinned),
        scene,
        settings,
        positions,
        Some(velocities),
        scratch,
    )
}

/// Quasi-static equilibrium by Vertex Block Descent: the loop of [`vbd_step`] without the
/// inertia term, minimising `E(x) - sum m g.(x - x_0)` from the given `positions`, as
/// [`relax_quasi_static`](super::super::relax_quasi_static). The scene's `dt` and previous
/// velocities are ignored.
///
/// Without inertia a vertex block is only as definite as its elements' exact blocks (which
/// may be indefinite or singular, and a vertex in no element has none): a block whose `L D L^T`
/// factorisation finds a pivot at or below `64 eps tr(H)` is replaced by its positive
/// semi-definite part, which is regularised once by `sqrt(eps) tr(H) / 3` on the diagonal
/// where that is singular too (a Levenberg–Marquardt step, still a descent direction), and the
/// vertex is skipped for this sweep if that fails too or `tr(H)` is not positive. Vertices in
/// no element therefore never move.
///
/// # Errors
/// As [`vbd_step`] (without the time-step errors).
pub fn vbd_quasi_static<F: VertexBlockModel>(
    model: &F,
    masses: &[Real],
    pinned: &[bool],
    scene: &Scene<'_, Vec3>,
    settings: &VbdSettings,
    positions: &mut [Vec3],
    scratch: &mut VbdScratch<'_>,
) -> Result<VbdReport, StepError> {
    minimise(
        (model, masses, pinned),
        scene,
        settings,
        positions,
        None,
        scratch,
    )
}

/// Builds the adjacency, colouring and order into `indices` unless they are there for this
/// mesh's counts; returns the colour count.
fn ensure_topology<M>(
    scratch: &mut VbdScratch<'_>,
    tets: &[[u32; 4]],
    vertex_count: usize,
    bodies: Bodies<'_, M>,
) -> Result<u32, StepError> {
    if let Some((vertices, elements, colours)) = scratch.topology
        && vertices == vertex_count
        && elements == tets.len()
    {
        return Ok(colours);
    }
    let [offsets, incident, colours, order] = index_parts(
        scratch.indices,
        scratch.incident.as_deref_mut(),
        vertex_count,
        tets.len(),
    );
    build_vertex_adjacency(tets, vertex_count, offsets, incident)?;
    let count = colour_vertices(tets, offsets, incident, colours)?;
    match bodies {
        Bodies::One => vertex_order_by_degree(colours, count, offsets, order)?,
        Bodies::World(parts) => {
            // Body by body, each body's vertices by colour and degree: the offsets' windows
            // of a range are its vertices' degrees, its order written in local indices first.
            for part in parts {
                let range = part.vertices();
                let (first, end) = (range.start, range.end);
                let (Some(colours), Some(offsets), Some(order)) = (
                    colours.get(first..end),
                    offsets.get(first..=end),
                    order.get_mut(first..end),
                ) else {
                    continue;
                };
                vertex_order_by_degree(colours, count, offsets, order)?;
                for slot in order {
                    *slot = slot.saturating_add(first as u32);
                }
            }
        }
    }
    scratch.topology = Some((vertex_count, tets.len(), count));
    if let Some(layout) = &mut scratch.layout {
        layout.built = None;
    }
    Ok(count)
}

/// The adjacency's offsets, incident elements, the colours and the order in the scratch's
/// index buffer (or its two parts), for `n` vertices and `t` tetrahedra; empty where short
/// (the solvers check the lengths first).
fn index_parts<'b>(
    indices: &'b mut [u32],
    incident: Option<&'b mut [u32]>,
    n: usize,
    t: usize,
) -> [&'b mut [u32]; 4] {
    let (offsets, rest) = indices
        .split_at_mut_checked(adjacency_offsets_len(n))
        .unwrap_or_default();
    let (incident, rest) = match incident {
        Some(incident) => (incident, rest),
        None => rest
            .split_at_mut_checked(adjacency_incident_len(t))
            .unwrap_or_default(),
    };
    let (colours, order) = rest.split_at_mut_checked(n).unwrap_or_default();
    [offsets, incident, colours, order]
}

/// Whole-sweep steps the descent loop's Armijo search may shorten before the solve stops.
const SWEEP_BACKTRACKS: u32 = 8;

/// The shared solve of [`vbd_step`] (`velocities` given) and [`vbd_quasi_static`], their
/// sweeps run by the model's schedule: checks, then the descent loop (`descent/mod.rs`) along
/// the sweep direction (`step/descent/vbd/sweep.rs`).
fn minimise<F: VertexBlockModel>(
    (model, masses, pinned): (&F, &[Real], &[bool]),
    scene: &Scene<'_, Vec3>,
    settings: &VbdSettings,
    positions: &mut [Vec3],
    velocities: Option<&mut [Vec3]>,
    scratch: &mut VbdScratch<'_>,
) -> Result<VbdReport, StepError> {
    let mesh = model.sweep_mesh();
    let (n, tets) = (mesh.vertex_count, mesh.tets);
    let material = mesh.material.ok_or(StepError::EmptyBody)?;
    let checked = descent::checked_solve(
        scene,
        n,
        velocities.is_some(),
        settings.check(),
        || check_state(n, masses, pinned, positions, velocities.as_deref()),
        || {
            let vectors = scratch.vectors.len();
            check_length(StepBuffer::Scratch, scratch_len::vbd(n), vectors)?;
            let indices = scratch.indices.len();
            match &scratch.incident {
                None => {
                    let index_len = scratch_len::vbd_indices(n, tets.len());
                    check_length(StepBuffer::IndexScratch, index_len, indices)
                }
                Some(incident) => {
                    let vertex_len = scratch_len::vbd_indices(n, 0);
                    check_length(StepBuffer::IndexScratch, vertex_len, indices)?;
                    let incident_len = adjacency_incident_len(tets.len());
                    check_length(StepBuffer::IndexScratch, incident_len, incident.len())
                }
            }?;
            match &scratch.contact {
                Some(contact) => {
                    check_length(StepBuffer::Scratch, n, contact.gradient.len())?;
                    check_length(StepBuffer::Scratch, n, contact.blocks.len())?;
                    check_length(StepBuffer::Scratch, n, contact.nearest.len())
                }
                None => Ok(()),
            }
        },
    )?;
    let loads = scene.loads();
    let colours = ensure_topology(scratch, tets, n, mesh.bodies)?;
    let VbdScratch {
        vectors,
        indices,
        incident,
        contact,
        layout: layout_buffers,
        ..
    } = scratch;
    let [offsets, incident, colours_of, order] =
        index_parts(indices, incident.as_deref_mut(), n, tets.len());
    let (offsets, incident, colours_of, order) = (&*offsets, &*incident, &*colours_of, &*order);
    if let Some(buffers) = layout_buffers
        && buffers.built.is_none()
        && matches!(mesh.bodies, Bodies::One)
    {
        let source = LayoutSource {
            tets,
            rest: mesh.rest,
            offsets,
            incident,
            colours: colours_of,
            order,
        };
        buffers.built = Some(build_layout(&source, buffers.corners, buffers.values).is_some());
    }
    let layout = layout_buffers.as_ref().and_then(|buffers| {
        if buffers.built != Some(true) {
            return None;
        }
        let (starts, corners) = buffers.corners.split_at_checked(n + 1)?;
        Some(Layout {
            starts,
            corners,
            values: buffers.values,
        })
    });

    let (work, _) = Work::split(vectors, n);

    // The sweeps see the ground and the colliders in the loop's coordinates, shifted as the
    // loop shifts them.
    let origin = descent::reference_point(positions);
    let sweep = Sweep {
        tets,
        rest: mesh.rest,
        material,
        offsets,
        incident,
        colours: colours_of,
        order,
        layout,
        masses,
        pinned,
        start: &[],
        velocities: &[],
        h: 0.0,
        inertia: 0.0,
        gravity: scene.gravity,
        loads,
        ground: checked.ground.map(|g| HalfSpace {
            offset: g.offset - g.normal.dot(origin),
            ..g
        }),
        colliders: Colliders::new(scene.colliders).shifted(origin),
        friction: None,
        bodies: mesh.bodies,
        contact: None,
        armijo: settings.armijo,
        backtrack: settings.backtrack,
        max_backtracks: settings.max_backtracks,
    };
    let lazy = settings.options.line_search_on_increase && settings.max_backtracks > 0;
    let contact = contact.as_mut().map(|buffers| ContactBuffersVbd {
        gradient: &mut *buffers.gradient,
        blocks: &mut *buffers.blocks,
        nearest: &mut *buffers.nearest,
    });
    let mut direction = VbdSweep::new(sweep, !lazy, contact);
    let problem = checked.problem((model, masses, pinned), &[], scene);
    let loop_settings = LoopSettings {
        max_backtracks: SWEEP_BACKTRACKS,
        acceleration: AccelerationSettings {
            rho: settings.options.chebyshev,
            delay: settings.options.chebyshev_delay,
            estimate: settings.options.estimate_chebyshev,
            cap: MAX_ESTIMATED_RHO,
        },
        rigid_guess: true,
        ..LoopSettings::new(settings, StallRule::Window)
    };
    let summary = descent::solve(
        &problem,
        &loop_settings,
        &mut direction,
        positions,
        velocities,
        work,
    )?;
    let counts = direction.counts;
    Ok(summary.with_details(VbdDetails {
        colours,
        vertex_backtracks: counts.backtracks,
        redone_sweeps: direction.redone,
        skipped: counts.skipped,
        projected: counts.projected,
    }))
}

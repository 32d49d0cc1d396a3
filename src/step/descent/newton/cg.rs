//! Newton's direction (`docs/math.md` section 7): `P` the projected Hessian `A = M / h^2 + H`
//! at the iterate (element Hessians projected onto the SPD matrices and cached, one SVD per
//! element), the constraints as removed degrees of freedom, and `A d = -g` solved inexactly by
//! matrix-free preconditioned conjugate gradients (block-Jacobi) with an Eisenstat-Walker
//! forcing term.

use super::super::super::super::element::TetHessian;
use super::super::super::super::math;
use super::super::super::super::types::{Mat3, Real, Vec3};
use super::super::super::contact::floor::Floor;
use super::super::super::model::ElasticHessian;
use super::super::super::vertex_pass::Blocks;
use super::super::super::vertex_pass::passes::{slope_and_trial_pass, split_copy};
use super::super::super::vertex_pass::point::Grouped;
use super::super::objective::Objective;
use super::super::stopping::rounding_floor;
use super::super::{Direction, Extrapolation, Iterate, Search};
use crate::error::StepError;
#[cfg(feature = "alloc")]
use super::amg::{Multilevel, projection_matrix};

/// Newton's direction over its scratch: the Hessian cache, the inverted preconditioner blocks
/// and the vectors of conjugate gradients.
pub(crate) struct Newton<'b> {
    pub hessians: &'b mut [TetHessian],
    pub blocks: &'b mut [Mat3],
    pub cg: CgVectors<'b>,
    /// The budget of CG iterations per Newton iteration.
    pub max_cg_iterations: u32,
    /// The ground's unit normal, if there is a ground.
    pub normal: Option<Vec3>,
    /// CG iterations so far.
    pub cg_iterations: u32,
    /// The most CG iterations of one linear solve so far.
    pub largest_linear_solve: u32,
    /// Linear solves that ended on the budget (truncated) so far.
    pub truncated_solves: u32,
    /// When to take the exact Hessian instead of the projected one.
    pub exact: ExactSwitch,
    /// The multilevel preconditioner, where the settings ask for it.
    #[cfg(feature = "alloc")]
    pub multilevel: Option<&'b mut Multilevel>,
    /// Whether a model without element Hessians made the multilevel preconditioner fall back
    /// to block Jacobi.
    #[cfg(feature = "alloc")]
    pub multilevel_unsupported: bool,
    /// `max |x|_inf` at the initial guess (m).
    reach: Real,
    /// The estimated rounding floor at the last Hessian evaluation (0 before it).
    floor: Real,
    forcing: Forcing,
}

impl<'b> Newton<'b> {
    /// The direction over its scratch.
    pub fn new(
        (hessians, blocks, cg): (&'b mut [TetHessian], &'b mut [Mat3], CgVectors<'b>),
        max_cg_iterations: u32,
        normal: Option<Vec3>,
    ) -> Self {
        Newton {
            hessians,
            blocks,
            cg,
            max_cg_iterations,
            normal,
            cg_iterations: 0,
            largest_linear_solve: 0,
            truncated_solves: 0,
            exact: ExactSwitch::default(),
            #[cfg(feature = "alloc")]
            multilevel: None,
            #[cfg(feature = "alloc")]
            multilevel_unsupported: false,
            reach: 0.0,
            floor: 0.0,
            forcing: Forcing::default(),
        }
    }
}

/// The largest forcing term: the first linear solve (and any far from the solution) stops
/// at half its initial residual.
const ETA_MAX: Real = 0.5;

/// Eisenstat and Walker's second forcing term ([EW96] in `docs/math.md`, choice 2 with
/// `gamma = 0.9`, `q = 2`): `eta_k = gamma (|g_k| / |g_(k-1)|)^2`, safeguarded by
/// `max(eta_k, gamma eta_(k-1)^2)` when that exceeds 0.1 (a sudden drop of the residual is
/// not trusted at once), at most [`ETA_MAX`], and never below `target / (2 |g_k|)`: no Newton
/// step needs a linear residual below half the target.
#[derive(Default)]
struct Forcing {
    /// `|g_(k-1)|` and `eta_(k-1)`, after the first solve.
    last: Option<(Real, Real)>,
}

impl Forcing {
    const GAMMA: Real = 0.9;

    /// The forcing term of the linear solve at `at`.
    fn next(&mut self, at: &Iterate<'_, Vec3>) -> Real {
        let eta = match self.last {
            None => ETA_MAX,
            Some((previous, last_eta)) => {
                let ratio = at.residual / previous;
                let eta = Self::GAMMA * ratio * ratio;
                let safeguard = Self::GAMMA * last_eta * last_eta;
                if safeguard > 0.1 {
                    eta.max(safeguard)
                } else {
                    eta
                }
            }
        };
        let eta = eta
            .min(ETA_MAX)
            .max(0.5 * at.target / at.residual)
            .min(ETA_MAX);
        self.last = Some((at.residual, eta));
        eta
    }
}

/// The fraction of the residual at a failed exact-Hessian iteration below which the exact
/// Hessian is tried again: a failure (negative curvature, an indefinite diagonal block, a
/// rejected full step) says the iterate is outside the region where the exact Hessian is
/// positive definite, and Newton's projected steps must first bring the residual down by this
/// factor (`docs/math.md` section 7.1.2).
pub(crate) const EXACT_RETRY: Real = 1.0 / 64.0;

/// The switch from the projected to the exact element Hessians near the solution (`docs/math.md`
/// section 7.1.2): the exact Hessian is taken at an iterate whose residual is at most half the
/// previous iterate's (the projected steps converge there: a full Newton step was as good as
/// the model predicts) and below [`EXACT_RETRY`] times the residual of the last failure; a
/// linear solve that meets non-positive curvature or an indefinite preconditioner block, and a
/// first trial step the line search rejects, fall back to the projected Hessian at the same
/// iterate.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ExactSwitch {
    /// The model has no exact Hessians (it answered `false`).
    unsupported: bool,
    /// The residual at the previous iterate (N).
    previous: Option<Real>,
    /// Exact Hessians are tried only below this residual (N).
    retry_below: Real,
    /// Whether the direction just computed came from the exact Hessian.
    in_use: bool,
    /// Whether the next search is at the iterate of the last one (after a fallback).
    redo: bool,
    /// The Newton iterations whose direction came from the exact Hessian.
    pub iterations: u32,
    /// The fallbacks to the projected Hessian.
    pub fallbacks: u32,
}

impl Default for ExactSwitch {
    fn default() -> Self {
        ExactSwitch {
            unsupported: false,
            previous: None,
            retry_below: Real::INFINITY,
            in_use: false,
            redo: false,
            iterations: 0,
            fallbacks: 0,
        }
    }
}

impl ExactSwitch {
    /// A switch that never takes the exact Hessian (implicit Euler steps: the mass term keeps
    /// the projected Hessian close, and their bits stay those of every model alike).
    pub(crate) fn off() -> Self {
        ExactSwitch {
            unsupported: true,
            ..ExactSwitch::default()
        }
    }

    /// Whether to try the exact Hessian at an iterate of residual `residual`; records it.
    fn wanted(&mut self, residual: Real) -> bool {
        let halved = self.previous.is_some_and(|previous| residual <= 0.5 * previous);
        self.previous = Some(residual);
        !self.unsupported && halved && residual < self.retry_below
    }

    /// The exact Hessian failed at an iterate of residual `residual`.
    fn failed(&mut self, residual: Real) {
        self.in_use = false;
        self.fallbacks += 1;
        self.retry_below = residual * EXACT_RETRY;
    }
}

impl<F: ElasticHessian> Direction<F> for Newton<'_> {
    fn begin(&mut self, _objective: &Objective<'_, F>, x: &[Vec3]) {
        // Every coordinate is known to its rounding, half an ulp: `eps max |x| / 2` at most.
        self.reach = x
            .iter()
            .fold(0.0, |a: Real, p| a.max(p.abs().max_element()));
    }

    fn search(&mut self, search: Search<'_, F>) -> Result<Real, StepError> {
        let (objective, at, direction) = (search.objective, search.at, search.direction);
        let model = objective.model;
        let (masses, pinned) = (objective.vertices.masses, objective.vertices.pinned);
        let mut exact = self.exact.wanted(at.residual);
        // A multilevel hierarchy is built from the projected Hessians only (its coarse
        // Cholesky factors need them semi-definite): an iteration that rebuilds keeps them.
        #[cfg(feature = "alloc")]
        if exact
            && !self.multilevel_unsupported
            && let Some(multilevel) = self.multilevel.as_deref()
            && multilevel.needs_build(at.x.len())
        {
            exact = false;
        }
        if exact {
            exact = model.exact_hessians(at.x, self.hessians)?;
            self.exact.unsupported = !exact;
        }
        if !exact {
            model.projected_hessians(at.x, self.hessians)?;
        }
        // Friction's tangent blocks at the iterate, with its own normal forces
        // (`step/contact/friction.rs`).
        let friction = &objective.friction;
        let start = objective.vertices.start;
        let rough = |i: usize| -> Option<Mat3> {
            if !friction.is_active() {
                return None;
            }
            let at_vertex = |values: &[Vec3]| values.get(i).copied();
            let (x, x0, g) = (at_vertex(at.x)?, at_vertex(start)?, at_vertex(at.gradient)?);
            friction.block(x, x0, g)
        };
        let constraints = Constraints {
            pinned,
            fixed_axes: objective.loads.fixed_axes,
            floor: objective.frames.floor(),
            normal: self.normal,
            x: at.x,
            gradient: at.gradient,
        };
        // A second search at the same iterate (after `fall_back`) keeps its forcing term.
        let eta = match (self.exact.redo, self.forcing.last) {
            (true, Some((_, eta))) => eta,
            _ => self.forcing.next(at),
        };
        self.exact.redo = false;
        loop {
            let (stiffness_squared, indefinite) = invert_blocks(
                model,
                self.hessians,
                (masses, pinned, objective.inertia),
                &rough,
                self.blocks,
            )?;
            if exact && indefinite > 0 {
                // Block Jacobi needs positive definite blocks: not near enough yet.
                exact = false;
                self.exact.failed(at.residual);
                model.projected_hessians(at.x, self.hessians)?;
                continue;
            }
            self.floor = rounding_floor(self.reach, stiffness_squared);
            #[cfg(feature = "alloc")]
            let multilevel = match self.multilevel.as_deref_mut() {
                Some(multilevel) if !self.multilevel_unsupported => {
                    if multilevel.needs_build(at.x.len()) {
                        let inertia = objective.inertia;
                        let diagonal = |i: usize| {
                            let m = masses.get(i).copied().unwrap_or(0.0);
                            let block = Mat3::from_diagonal(Vec3::splat(m * inertia));
                            rough(i).map_or(block, |friction| block + friction)
                        };
                        let projection =
                            |i: usize| projection_matrix(|v| constraints.apply(i, v));
                        let built = multilevel.rebuild(
                            model,
                            self.hessians,
                            at.x,
                            &diagonal,
                            &projection,
                        )?;
                        self.multilevel_unsupported = !built;
                    }
                    if self.multilevel_unsupported {
                        None
                    } else {
                        Some(multilevel)
                    }
                }
                _ => None,
            };
            #[cfg(not(feature = "alloc"))]
            let multilevel: Option<&mut GlobalPreconditioner> = None;
            let outcome = conjugate_gradients(
                model,
                (self.hessians, self.blocks, masses, objective.inertia),
                &rough,
                &constraints,
                (eta, self.max_cg_iterations),
                direction,
                (&mut self.cg, multilevel),
            )?;
            self.cg_iterations += outcome.iterations;
            self.largest_linear_solve = self.largest_linear_solve.max(outcome.iterations);
            if exact && outcome.negative_curvature {
                // The exact Hessian is indefinite here: the projected one at the same iterate.
                exact = false;
                self.exact.failed(at.residual);
                model.projected_hessians(at.x, self.hessians)?;
                continue;
            }
            if outcome.truncated {
                self.truncated_solves += 1;
            }
            break;
        }
        self.exact.in_use = exact;
        self.exact.iterations += u32::from(exact);
        Ok(slope_and_trial_pass(
            model,
            &objective.frames,
            pinned,
            (at.x, at.gradient, direction),
            search.step,
            search.trial,
        ))
    }

    fn extrapolate(&mut self, _: Extrapolation<'_, F>) -> Result<(), StepError> {
        // Newton's method is not accelerated: its settings never ask for this.
        Ok(())
    }

    fn rounding_floor(&self) -> Real {
        self.floor
    }

    fn fall_back(&mut self) -> bool {
        // A direction from the exact Hessian that is not downhill, or whose full step the line
        // search rejects: the projected Hessian at the same iterate instead (7.1.2).
        if !self.exact.in_use {
            return false;
        }
        let residual = self.exact.previous.unwrap_or(Real::INFINITY);
        self.exact.failed(residual);
        self.exact.redo = true;
        true
    }
}

/// The work vectors of conjugate gradients.
pub(crate) struct CgVectors<'b> {
    pub residual: &'b mut [Vec3],
    pub preconditioned: &'b mut [Vec3],
    pub conjugate: &'b mut [Vec3],
    pub product: &'b mut [Vec3],
}

/// The constraint projection `S` of one Newton iteration, fixed during its linear solve:
/// pinned vertices lose every component, vertices in contact with the ground whose gradient
/// pushes into it lose the normal one (the relaxation's residual projects the same way).
struct Constraints<'c> {
    pinned: &'c [bool],
    /// The fixed-axis masks (empty for none): those components are removed too.
    fixed_axes: &'c [u8],
    floor: &'c Floor<'c, Vec3>,
    normal: Option<Vec3>,
    x: &'c [Vec3],
    gradient: &'c [Vec3],
}

impl Constraints<'_> {
    /// `S_i v`.
    #[inline(always)]
    fn apply(&self, i: usize, v: Vec3) -> Vec3 {
        if self.pinned.get(i).copied().unwrap_or(false) {
            return Vec3::ZERO;
        }
        let fixed = self.fixed_axes.get(i).copied().unwrap_or(0);
        let mut v = v.axes_from(Vec3::ZERO, fixed);
        let at = |values: &[Vec3]| values.get(i).copied().unwrap_or(Vec3::ZERO);
        if let Some(n) = self.floor.collider_normal(at(self.x))
            && n.dot(at(self.gradient)) > 0.0
        {
            v = (v - n * n.dot(v)).axes_from(Vec3::ZERO, fixed);
        }
        let Some(normal) = self.normal else {
            return v;
        };
        let active =
            self.floor.contact(at(self.x)) == Some(true) && normal.dot(at(self.gradient)) > 0.0;
        if active {
            (v - normal * normal.dot(v)).axes_from(Vec3::ZERO, fixed)
        } else {
            v
        }
    }
}

/// Writes the inverted preconditioner blocks `(B_i + m_i / h^2 I + F_i)^-1` into `blocks`, `B_i`
/// the diagonal blocks of the projected Hessian, `F_i` friction's tangent block (`rough`). A block
/// whose determinant is below `eps max(diag)^3` (singular or nearly: a vertex with no stiffness and
/// no inertia) is replaced by the inverse of its diagonal, zero where a diagonal entry is not
/// positive. Returns `sum |B_i + m_i / h^2 I|_F^2` over the free vertices (N^2/m^2), for the
/// rounding floor: a sum over vertex blocks (`step/vertex_pass/mod.rs`), as every sum of this file;
/// and the number of free vertices whose block is not positive definite (Sylvester's test),
/// which only the exact Hessian can have.
fn invert_blocks<F: ElasticHessian>(
    model: &F,
    hessians: &[TetHessian],
    (masses, pinned, inertia): (&[Real], &[bool], Real),
    rough: &(impl Fn(usize) -> Option<Mat3> + Sync),
    blocks: &mut [Mat3],
) -> Result<(Real, usize), StepError> {
    let clear = |_, blocks: &mut [Mat3]| blocks.fill(Mat3::ZERO);
    model.run_vertex_pass(Blocks::new(blocks.len(), &mut *blocks, &clear));
    model.add_vertex_hessian_blocks(hessians, blocks)?;
    let invert = |first: usize, (blocks, masses): (&mut [Mat3], &[Real])| {
        let (mut stiffness_squared, mut indefinite) = (0.0, 0);
        for (j, (block, &m)) in blocks.iter_mut().zip(masses).enumerate() {
            let i = first + j;
            let mut b = *block + Mat3::from_diagonal(Vec3::splat(m * inertia));
            if let Some(friction) = rough(i) {
                b += friction;
            }
            if !pinned.get(i).copied().unwrap_or(false) {
                stiffness_squared += b.x_axis.length_squared()
                    + b.y_axis.length_squared()
                    + b.z_axis.length_squared();
                indefinite += usize::from(!positive_definite(b));
            }
            *block = inverted(b);
        }
        (stiffness_squared, indefinite)
    };
    Ok(model.run_vertex_pass(Blocks::new(blocks.len(), (blocks, masses), &invert)))
}

/// `b^-1`, or the inverse of its diagonal (zero where a diagonal entry is not positive) where
/// its determinant is below `eps max(diag)^3` or not finite.
#[inline(always)]
fn inverted(b: Mat3) -> Mat3 {
    let diagonal = Vec3::new(b.x_axis.x, b.y_axis.y, b.z_axis.z);
    let largest = diagonal.max_element();
    let determinant = b.determinant();
    if determinant > Real::EPSILON * largest * largest * largest && determinant.is_finite() {
        b.inverse()
    } else {
        let invert = |d: Real| if d > 0.0 { 1.0 / d } else { 0.0 };
        Mat3::from_diagonal(Vec3::new(
            invert(diagonal.x),
            invert(diagonal.y),
            invert(diagonal.z),
        ))
    }
}

/// Whether `x > 0` (false for NaN).
#[inline(always)]
fn positive(x: Real) -> bool {
    x > 0.0
}

/// Whether the symmetric `b` is positive definite: its leading principal minors are positive
/// (Sylvester's criterion; false for NaN).
#[inline(always)]
fn positive_definite(b: Mat3) -> bool {
    let minor = b.x_axis.x * b.y_axis.y - b.x_axis.y * b.y_axis.x;
    positive(b.x_axis.x) && positive(minor) && positive(b.determinant())
}

/// How a linear solve ended.
pub(crate) struct CgOutcome {
    /// The CG iterations it took.
    pub iterations: u32,
    /// Whether it met a direction of non-positive curvature `p . A p <= 0`.
    pub negative_curvature: bool,
    /// Whether it ended on the budget before the forcing term's residual.
    pub truncated: bool,
}

/// A block's share of conjugate gradients' five vectors.
type CgParts<'p> = (
    &'p mut [Vec3],
    &'p mut [Vec3],
    &'p mut [Vec3],
    &'p mut [Vec3],
    &'p mut [Vec3],
);

/// Preconditioned conjugate gradients on `S A S d = -S g` from `d = 0` (Hestenes and Stiefel;
/// Saad, "Iterative Methods for Sparse Linear Systems", algorithm 9.1), `A = M / h^2 + H` with
/// `H` in `hessians` and the preconditioner `S B^-1 S` from the inverted `blocks`, until
/// `|r| <= eta |r_0|` or `max` iterations; friction's blocks (`rough`) are part of `A`. Writes `d`
/// into `direction`; returns the iterations.
///
/// Besides the Hessian product, an iteration is three passes over the vertices in blocks run by
/// `model` (`step/vertex_pass/mod.rs`): the product's vertex terms with its projection and
/// curvature `p.q`; the updates of `d` and `r` with `|r|^2`, the preconditioned residual `z` and
/// `r.z`; the next conjugate direction with the product cleared. Every sum is a sum of block sums
/// over the fixed tree, so `d` has the same bits on any number of threads.
fn conjugate_gradients<F: ElasticHessian>(
    model: &F,
    (hessians, blocks, masses, inertia): (&[TetHessian], &[Mat3], &[Real], Real),
    rough: &(impl Fn(usize) -> Option<Mat3> + Sync),
    constraints: &Constraints<'_>,
    (eta, max): (Real, u32),
    direction: &mut [Vec3],
    (cg, mut multilevel): (&mut CgVectors<'_>, Option<&mut GlobalPreconditioner>),
) -> Result<CgOutcome, StepError> {
    let local = multilevel.is_none();
    let CgVectors {
        residual,
        preconditioned,
        conjugate,
        product,
    } = cg;
    let n = direction.len();
    // `S B^-1 S r` at vertex `i`.
    let precondition = |i: usize, r: Vec3| {
        let block = blocks.get(i).copied().unwrap_or(Mat3::ZERO);
        constraints.apply(i, block * constraints.apply(i, r))
    };
    // r = -S g, d = 0, z = p = S B^-1 S r, q = 0; |r|^2 and r.z.
    let start =
        |first: usize, (residual, direction, preconditioned, conjugate, product): CgParts| {
            let (mut rr, mut rz) = (-0.0, -0.0);
            let rows = residual
                .iter_mut()
                .zip(direction)
                .zip(preconditioned.iter_mut().zip(conjugate).zip(product));
            for (j, ((r, d), ((z, p), q))) in rows.enumerate() {
                let i = first + j;
                let g = constraints.gradient.get(i).copied().unwrap_or(Vec3::ZERO);
                *r = constraints.apply(i, -g);
                *d = Vec3::ZERO;
                *q = Vec3::ZERO;
                rr += r.dot(*r);
                if local {
                    *z = precondition(i, *r);
                    *p = *z;
                    rz += r.dot(*z);
                }
            }
            (rr, rz)
        };
    let parts = (
        &mut **residual,
        &mut *direction,
        &mut **preconditioned,
        &mut **conjugate,
        &mut **product,
    );
    let (rr, mut rz) = model.run_vertex_pass(Blocks::new(n, parts, &start));
    // The global preconditioner: `z = S M^-1 S r` (`r` is already projected) and `r.z`.
    let project = |first: usize, (preconditioned, residual): (&mut [Vec3], &[Vec3])| {
        let mut rz = -0.0;
        for (j, (z, r)) in preconditioned.iter_mut().zip(residual).enumerate() {
            *z = constraints.apply(first + j, *z);
            rz += r.dot(*z);
        }
        rz
    };
    if let Some(global) = multilevel.as_deref_mut() {
        apply_global(global, model, residual, preconditioned);
        let parts = (&mut **preconditioned, &**residual);
        rz = model.run_vertex_pass(Blocks::new(n, parts, &project));
        split_copy(model, conjugate, preconditioned);
    }
    let initial = math::sqrt(rr);
    let stop = eta * initial;
    let mut last = initial;
    let mut iterations = 0;
    let mut negative_curvature = false;
    // q = S (H p + M / h^2 p + F p) from q = H p; the curvature p.q.
    let complete = |first: usize, (product, conjugate): (&mut [Vec3], &[Vec3])| {
        let mut curvature = -0.0;
        for (j, (q, &p)) in product.iter_mut().zip(conjugate).enumerate() {
            let i = first + j;
            let m = masses.get(i).copied().unwrap_or(0.0);
            *q += p * (m * inertia);
            if let Some(friction) = rough(i) {
                *q += friction * p;
            }
            *q = constraints.apply(i, *q);
            curvature += p.dot(*q);
        }
        curvature
    };
    while iterations < max {
        model.add_hessian_product(hessians, conjugate, product)?;
        let parts = (&mut **product, &**conjugate);
        let curvature = model.run_vertex_pass(Blocks::new(n, parts, &complete));
        if !positive(curvature) {
            negative_curvature = true;
            if iterations == 0 {
                // No curvature along the preconditioned gradient (a body free to move rigidly
                // without inertia): take that descent direction for the line search.
                split_copy(model, direction, preconditioned);
            }
            break;
        }
        let step = rz / curvature;
        // d += step p, r -= step q, z = S B^-1 S r; |r|^2 and r.z. The last iteration's `z`
        // is not used.
        let update =
            |first: usize,
             (direction, residual, preconditioned, conjugate, product): UpdateParts| {
                let (mut rr, mut rz) = (-0.0, -0.0);
                let rows = direction
                    .iter_mut()
                    .zip(residual.iter_mut().zip(preconditioned))
                    .zip(conjugate.iter().zip(product));
                for (j, ((d, (r, z)), (&p, &q))) in rows.enumerate() {
                    *d += p * step;
                    *r -= q * step;
                    rr += r.dot(*r);
                    if local {
                        *z = precondition(first + j, *r);
                        rz += r.dot(*z);
                    }
                }
                (rr, rz)
            };
        let parts = (
            &mut *direction,
            &mut **residual,
            &mut **preconditioned,
            &**conjugate,
            &**product,
        );
        let (rr, mut rz_next) = model.run_vertex_pass(Blocks::new(n, parts, &update));
        iterations += 1;
        last = math::sqrt(rr);
        if last <= stop {
            break;
        }
        if let Some(global) = multilevel.as_deref_mut() {
            apply_global(global, model, residual, preconditioned);
            let parts = (&mut **preconditioned, &**residual);
            rz_next = model.run_vertex_pass(Blocks::new(n, parts, &project));
        }
        if !positive(rz_next) {
            break;
        }
        let beta = rz_next / rz;
        rz = rz_next;
        // p = z + beta p, q = 0.
        let next = |_, (conjugate, product, preconditioned): NextParts| {
            for ((p, q), &z) in conjugate.iter_mut().zip(product).zip(preconditioned) {
                *p = z + *p * beta;
                *q = Vec3::ZERO;
            }
        };
        let parts = (&mut **conjugate, &mut **product, &**preconditioned);
        model.run_vertex_pass(Blocks::new(n, parts, &next));
    }
    #[cfg(feature = "alloc")]
    if let Some(global) = multilevel {
        let reduction = if initial > 0.0 { last / initial } else { 1.0 };
        global.record(iterations, reduction);
    }
    Ok(CgOutcome {
        iterations,
        negative_curvature,
        truncated: iterations >= max && last > stop,
    })
}

/// A preconditioner applied to the whole residual at once (not vertex by vertex).
#[cfg(feature = "alloc")]
type GlobalPreconditioner = Multilevel;

/// Without `alloc` there is none.
#[cfg(not(feature = "alloc"))]
pub(crate) enum GlobalPreconditioner {}

/// `z = M^-1 r`, the cycle's passes on `model`'s pool (`amg/cycle.rs`).
#[cfg(feature = "alloc")]
#[inline]
fn apply_global<F: ElasticHessian>(
    global: &mut GlobalPreconditioner,
    model: &F,
    r: &[Vec3],
    z: &mut [Vec3],
) {
    global.apply_unchecked(model, r, z);
}

/// Never called: there is no global preconditioner without `alloc`.
#[cfg(not(feature = "alloc"))]
#[inline]
fn apply_global<F>(global: &mut GlobalPreconditioner, _: &F, _: &[Vec3], _: &mut [Vec3]) {
    match *global {}
}

/// A block's share of the update pass's buffers.
type UpdateParts<'p> = (
    &'p mut [Vec3],
    &'p mut [Vec3],
    &'p mut [Vec3],
    &'p [Vec3],
    &'p [Vec3],
);

/// A block's share of the next-direction pass's buffers.
type NextParts<'p> = (&'p mut [Vec3], &'p mut [Vec3], &'p [Vec3]);

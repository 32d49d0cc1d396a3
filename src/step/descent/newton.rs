//! Newton's direction (`docs/math.md` section 7): `P` the projected Hessian `A = M / h^2 + H`
//! at the iterate (element Hessians projected onto the SPD matrices and cached, one SVD per
//! element), the constraints as removed degrees of freedom, and `A d = -g` solved inexactly by
//! matrix-free preconditioned conjugate gradients (block-Jacobi) with an Eisenstat-Walker
//! forcing term.

use super::super::super::element::TetHessian;
use super::super::super::math;
use super::super::super::types::{Mat3, Real, Vec3};
use super::super::points::{Floor, Grouped};
use super::super::vertex_passes::{TrialPoint, trial_pass};
use super::super::{ElasticHessian, pinned_flags};
use super::line_search::{copy, slope_along};
use super::objective::Objective;
use super::stopping::rounding_floor;
use super::{Direction, Iterate};
use crate::error::StepError;

/// Newton's direction over its scratch: the Hessian cache, the inverted preconditioner blocks
/// and the vectors of conjugate gradients.
pub(in super::super) struct Newton<'b> {
    pub hessians: &'b mut [TetHessian],
    pub blocks: &'b mut [Mat3],
    pub cg: CgVectors<'b>,
    /// The budget of CG iterations per Newton iteration.
    pub max_cg_iterations: u32,
    /// `1 / h^2` (0 without inertia).
    pub inertia: Real,
    /// The ground's unit normal, if there is a ground.
    pub normal: Option<Vec3>,
    /// CG iterations so far.
    pub cg_iterations: u32,
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
        inertia: Real,
        normal: Option<Vec3>,
    ) -> Self {
        Newton {
            hessians,
            blocks,
            cg,
            max_cg_iterations,
            inertia,
            normal,
            cg_iterations: 0,
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

impl<F: ElasticHessian> Direction<F> for Newton<'_> {
    fn begin(&mut self, _objective: &Objective<'_, F>, x: &[Vec3]) {
        // Every coordinate is known to its rounding, half an ulp: `eps max |x| / 2` at most.
        self.reach = x
            .iter()
            .fold(0.0, |a: Real, p| a.max(p.abs().max_element()));
    }

    fn search(
        &mut self,
        objective: &Objective<'_, F>,
        at: &Iterate<'_, Vec3>,
        direction: &mut [Vec3],
        _momentum: Option<Real>,
        trial: TrialPoint<'_, Vec3>,
        step: Real,
    ) -> Result<Real, StepError> {
        let model = objective.model;
        let (masses, pinned) = (objective.vertices.masses, objective.vertices.pinned);
        model.projected_hessians(at.x, self.hessians)?;
        // Friction's tangent blocks at the iterate, with its own normal forces (`friction.rs`).
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
        let stiffness_squared = invert_blocks(
            model,
            self.hessians,
            (masses, pinned, self.inertia),
            &rough,
            self.blocks,
        )?;
        self.floor = rounding_floor(self.reach, stiffness_squared);
        let constraints = Constraints {
            pinned,
            fixed_axes: objective.loads.fixed_axes,
            floor: objective.frames.floor(),
            normal: self.normal,
            x: at.x,
            gradient: at.gradient,
        };
        let eta = self.forcing.next(at);
        self.cg_iterations += conjugate_gradients(
            model,
            (self.hessians, self.blocks, masses, self.inertia),
            &rough,
            &constraints,
            (eta, self.max_cg_iterations),
            direction,
            &mut self.cg,
        )?;
        let slope = slope_along(at.gradient, direction);
        trial_pass(&objective.frames, pinned, (at.x, direction), step, trial);
        Ok(slope)
    }

    fn extrapolate(
        &mut self,
        _objective: &Objective<'_, F>,
        _at: &Iterate<'_, Vec3>,
        _stepped: bool,
        _trial: TrialPoint<'_, Vec3>,
        _weights: (Real, Real),
    ) {
        // Newton's method is not accelerated: its settings never ask for this.
    }

    fn rounding_floor(&self) -> Real {
        self.floor
    }
}

/// The work vectors of conjugate gradients.
pub(in super::super) struct CgVectors<'b> {
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

    /// `S v` in place.
    fn project(&self, v: &mut [Vec3]) {
        for (i, value) in v.iter_mut().enumerate() {
            *value = self.apply(i, *value);
        }
    }
}

/// Writes the inverted preconditioner blocks `(B_i + m_i / h^2 I + F_i)^-1` into `blocks`, `B_i`
/// the diagonal blocks of the projected Hessian, `F_i` friction's tangent block (`rough`). A block whose determinant is below
/// `eps max(diag)^3` (singular or nearly: a vertex with no stiffness and no inertia) is
/// replaced by the inverse of its diagonal, zero where a diagonal entry is not positive.
/// Returns `sum |B_i + m_i / h^2 I|_F^2` over the free vertices (N^2/m^2), for the rounding
/// floor.
fn invert_blocks<F: ElasticHessian>(
    model: &F,
    hessians: &[TetHessian],
    (masses, pinned, inertia): (&[Real], &[bool], Real),
    rough: &impl Fn(usize) -> Option<Mat3>,
    blocks: &mut [Mat3],
) -> Result<Real, StepError> {
    blocks.fill(Mat3::ZERO);
    model.add_vertex_hessian_blocks(hessians, blocks)?;
    let mut stiffness_squared = 0.0;
    let rows = blocks.iter_mut().zip(masses).zip(pinned_flags(pinned));
    for (i, ((block, &m), pinned)) in rows.enumerate() {
        let mut b = *block + Mat3::from_diagonal(Vec3::splat(m * inertia));
        if let Some(friction) = rough(i) {
            b += friction;
        }
        if !pinned {
            stiffness_squared +=
                b.x_axis.length_squared() + b.y_axis.length_squared() + b.z_axis.length_squared();
        }
        let diagonal = Vec3::new(b.x_axis.x, b.y_axis.y, b.z_axis.z);
        let largest = diagonal.max_element();
        let determinant = b.determinant();
        *block = if determinant > Real::EPSILON * largest * largest * largest
            && determinant.is_finite()
        {
            b.inverse()
        } else {
            let invert = |d: Real| if d > 0.0 { 1.0 / d } else { 0.0 };
            Mat3::from_diagonal(Vec3::new(
                invert(diagonal.x),
                invert(diagonal.y),
                invert(diagonal.z),
            ))
        };
    }
    Ok(stiffness_squared)
}

/// Whether `x > 0` (false for NaN).
#[inline(always)]
fn positive(x: Real) -> bool {
    x > 0.0
}

/// `sum a_i . b_i`.
fn dot(a: &[Vec3], b: &[Vec3]) -> Real {
    a.iter().zip(b).map(|(&x, &y)| x.dot(y)).sum()
}

/// Preconditioned conjugate gradients on `S A S d = -S g` from `d = 0` (Hestenes and Stiefel;
/// Saad, "Iterative Methods for Sparse Linear Systems", algorithm 9.1), `A = M / h^2 + H` with
/// `H` in `hessians` and the preconditioner `S B^-1 S` from the inverted `blocks`, until
/// `|r| <= eta |r_0|` or `max` iterations; friction's blocks (`rough`) are part of `A`. Writes `d` into `direction`; returns the iterations.
fn conjugate_gradients<F: ElasticHessian>(
    model: &F,
    (hessians, blocks, masses, inertia): (&[TetHessian], &[Mat3], &[Real], Real),
    rough: &impl Fn(usize) -> Option<Mat3>,
    constraints: &Constraints<'_>,
    (eta, max): (Real, u32),
    direction: &mut [Vec3],
    cg: &mut CgVectors<'_>,
) -> Result<u32, StepError> {
    let CgVectors {
        residual,
        preconditioned,
        conjugate,
        product,
    } = cg;
    for (i, (r, &g)) in residual.iter_mut().zip(constraints.gradient).enumerate() {
        *r = constraints.apply(i, -g);
    }
    let stop = eta * math::sqrt(dot(residual, residual));
    let mut iterations = 0;
    direction.fill(Vec3::ZERO);
    let precondition = |r: &[Vec3], z: &mut [Vec3]| {
        for (i, ((z, &r), block)) in z.iter_mut().zip(r).zip(blocks).enumerate() {
            *z = constraints.apply(i, *block * constraints.apply(i, r));
        }
    };
    precondition(residual, preconditioned);
    copy(conjugate, preconditioned);
    let mut rz = dot(residual, preconditioned);
    while iterations < max {
        product.fill(Vec3::ZERO);
        model.add_hessian_product(hessians, conjugate, product)?;
        for (i, ((q, &p), &m)) in product.iter_mut().zip(&**conjugate).zip(masses).enumerate() {
            *q += p * (m * inertia);
            if let Some(friction) = rough(i) {
                *q += friction * p;
            }
        }
        constraints.project(product);
        let curvature = dot(conjugate, product);
        if !positive(curvature) {
            if iterations == 0 {
                // No curvature along the preconditioned gradient (a body free to move rigidly
                // without inertia): take that descent direction for the line search.
                copy(direction, preconditioned);
            }
            break;
        }
        let step = rz / curvature;
        for (d, &p) in direction.iter_mut().zip(&**conjugate) {
            *d += p * step;
        }
        for (r, &q) in residual.iter_mut().zip(&**product) {
            *r -= q * step;
        }
        iterations += 1;
        if math::sqrt(dot(residual, residual)) <= stop {
            break;
        }
        precondition(residual, preconditioned);
        let rz_next = dot(residual, preconditioned);
        if !positive(rz_next) {
            break;
        }
        let beta = rz_next / rz;
        rz = rz_next;
        for (p, &z) in conjugate.iter_mut().zip(&**preconditioned) {
            *p = z + *p * beta;
        }
    }
    Ok(iterations)
}

//! The application: one V-cycle from a zero guess, Gauss-Seidel forward before the coarse
//! correction and backward after it (each other's adjoint, so the cycle is a symmetric
//! operator and conjugate gradients stay valid), and at the coarsest level a dense Cholesky
//! factorisation (or, for a coarsest level too large to factor, symmetric Gauss-Seidel
//! sweeps).

use alloc::vec::Vec;

use super::super::super::super::super::math;
use super::super::super::super::super::types::Real;
use super::csr::Csr;
use super::{OutOfMemory, filled};

/// One level of the hierarchy: its matrix, the inverse of its diagonal (zero on frozen rows,
/// whose diagonal is not positive: those unknowns stay zero) and, above the coarsest, the
/// prolongator to it from the next coarser level and its transpose.
#[derive(Debug, Default)]
pub(crate) struct Level {
    pub matrix: Csr,
    pub inverse_diagonal: Vec<Real>,
    pub prolongator: Csr,
    pub restriction: Csr,
    /// The level's vectors: solution, right-hand side, residual.
    pub x: Vec<Real>,
    pub b: Vec<Real>,
    pub r: Vec<Real>,
}

impl Level {
    /// A level of `matrix` (the transfer operators empty until set).
    pub fn new(matrix: Csr) -> Result<Level, OutOfMemory> {
        let n = matrix.rows;
        let mut inverse_diagonal = matrix.diagonal()?;
        for d in inverse_diagonal.iter_mut() {
            *d = if *d > 0.0 && d.is_finite() {
                1.0 / *d
            } else {
                0.0
            };
        }
        Ok(Level {
            matrix,
            inverse_diagonal,
            prolongator: Csr::default(),
            restriction: Csr::default(),
            x: filled(n, 0.0)?,
            b: filled(n, 0.0)?,
            r: filled(n, 0.0)?,
        })
    }

    /// One Gauss-Seidel sweep on `A x = b`, rows ascending (`forward`) or descending.
    pub fn gauss_seidel(&mut self, forward: bool) {
        let n = self.matrix.rows;
        let mut sweep = |i: usize| {
            let inverse = self.inverse_diagonal.get(i).copied().unwrap_or(0.0);
            if inverse == 0.0 {
                return;
            }
            let (columns, values) = self.matrix.row(i);
            let mut sum = self.b.get(i).copied().unwrap_or(0.0);
            for (&c, &a) in columns.iter().zip(values) {
                sum -= a * self.x.get(c as usize).copied().unwrap_or(0.0);
            }
            if let Some(x) = self.x.get_mut(i) {
                *x += inverse * sum;
            }
        };
        if forward {
            (0..n).for_each(&mut sweep);
        } else {
            (0..n).rev().for_each(&mut sweep);
        }
    }

    /// `r = b - A x` right after a forward sweep from `x = 0`: the sweep left `(D + L) x = b`
    /// on every row it updated (to rounding), so there `r = -U x` and only the entries right of
    /// the diagonal are read (half the stream); frozen rows take the whole row.
    pub fn residual_after_forward_sweep(&mut self) {
        for (i, r) in self.r.iter_mut().enumerate() {
            let (columns, values) = self.matrix.row(i);
            let frozen = self.inverse_diagonal.get(i).is_none_or(|&d| d == 0.0);
            let (start, mut sum) = if frozen {
                (0, self.b.get(i).copied().unwrap_or(0.0))
            } else {
                (columns.partition_point(|&c| c as usize <= i), 0.0)
            };
            let upper = columns.get(start..).unwrap_or(&[]);
            for (&c, &a) in upper.iter().zip(values.get(start..).unwrap_or(&[])) {
                sum -= a * self.x.get(c as usize).copied().unwrap_or(0.0);
            }
            *r = sum;
        }
    }
}

/// The largest coarsest level factored densely (unknowns): its factor takes `n^2` numbers.
pub(crate) const DENSE_LIMIT: usize = 1500;

/// Symmetric Gauss-Seidel sweeps (forward then backward) at a coarsest level too large to
/// factor.
const COARSE_SWEEPS: usize = 4;

/// The coarsest level's solve: a dense Cholesky factor `L` (row-major, lower), or none.
#[derive(Debug, Default)]
pub(crate) struct Coarsest {
    factor: Vec<Real>,
    n: usize,
}

impl Coarsest {
    /// The Cholesky factor of `matrix` where it has at most [`DENSE_LIMIT`] rows. A pivot at
    /// or below `n eps` times the largest diagonal entry (a direction the near-null space gave
    /// that the matrix does not see, or rounding) freezes its unknown: its column of `L` is
    /// zero and the solve leaves it zero, which keeps the solve symmetric and semi-definite.
    pub fn new(matrix: &Csr) -> Result<Coarsest, OutOfMemory> {
        let n = matrix.rows;
        if n > DENSE_LIMIT {
            return Ok(Coarsest::default());
        }
        let mut factor = filled(n * n, 0.0)?;
        for i in 0..n {
            let (columns, values) = matrix.row(i);
            for (&c, &a) in columns.iter().zip(values) {
                if let Some(slot) = factor.get_mut(i * n + c as usize) {
                    *slot = a;
                }
            }
        }
        let largest = (0..n)
            .map(|i| factor.get(i * n + i).copied().unwrap_or(0.0))
            .fold(0.0, Real::max);
        let tolerance = n as Real * Real::EPSILON * largest;
        for j in 0..n {
            let mut pivot = factor.get(j * n + j).copied().unwrap_or(0.0);
            for k in 0..j {
                let l = factor.get(j * n + k).copied().unwrap_or(0.0);
                pivot -= l * l;
            }
            let keep = pivot > tolerance && pivot.is_finite();
            let diagonal = if keep { math::sqrt(pivot) } else { 0.0 };
            if let Some(slot) = factor.get_mut(j * n + j) {
                *slot = diagonal;
            }
            for i in j + 1..n {
                let mut sum = factor.get(i * n + j).copied().unwrap_or(0.0);
                for k in 0..j {
                    let a = factor.get(i * n + k).copied().unwrap_or(0.0);
                    let b = factor.get(j * n + k).copied().unwrap_or(0.0);
                    sum -= a * b;
                }
                if let Some(slot) = factor.get_mut(i * n + j) {
                    *slot = if keep { sum / diagonal } else { 0.0 };
                }
            }
        }
        Ok(Coarsest { factor, n })
    }

    /// Whether the level was factored.
    pub fn factored(&self) -> bool {
        self.n > 0
    }

    /// `x = L^-T L^-1 b` (frozen unknowns zero).
    pub fn solve(&self, b: &[Real], x: &mut [Real]) {
        let n = self.n;
        let l = |i: usize, j: usize| self.factor.get(i * n + j).copied().unwrap_or(0.0);
        for i in 0..n {
            let mut sum = b.get(i).copied().unwrap_or(0.0);
            for k in 0..i {
                sum -= l(i, k) * x.get(k).copied().unwrap_or(0.0);
            }
            let d = l(i, i);
            if let Some(x) = x.get_mut(i) {
                *x = if d > 0.0 { sum / d } else { 0.0 };
            }
        }
        for i in (0..n).rev() {
            let mut sum = x.get(i).copied().unwrap_or(0.0);
            for k in i + 1..n {
                sum -= l(k, i) * x.get(k).copied().unwrap_or(0.0);
            }
            let d = l(i, i);
            if let Some(x) = x.get_mut(i) {
                *x = if d > 0.0 { sum / d } else { 0.0 };
            }
        }
    }
}

/// One V-cycle on `levels[0]`'s system from `x = 0` with right-hand side `levels[0].b`; the
/// answer in `levels[0].x`.
pub(crate) fn v_cycle(levels: &mut [Level], coarsest: &Coarsest) {
    let depth = levels.len();
    for l in 0..depth {
        let (this, rest) = match levels.get_mut(l..) {
            Some([this, rest @ ..]) => (this, rest),
            _ => return,
        };
        this.x.fill(0.0);
        let Some(next) = rest.first_mut() else {
            // The coarsest level.
            if coarsest.factored() {
                coarsest.solve(&this.b, &mut this.x);
            } else {
                for _ in 0..COARSE_SWEEPS {
                    this.gauss_seidel(true);
                    this.gauss_seidel(false);
                }
            }
            break;
        };
        this.gauss_seidel(true);
        this.residual_after_forward_sweep();
        this.restriction.product(&this.r, &mut next.b);
    }
    for l in (0..depth.saturating_sub(1)).rev() {
        let (this, rest) = match levels.get_mut(l..) {
            Some([this, rest @ ..]) => (this, rest),
            _ => return,
        };
        if let Some(next) = rest.first() {
            this.prolongator.add_product(&next.x, &mut this.x);
        }
        this.gauss_seidel(false);
    }
}

//! The application: one V-cycle from a zero guess, Gauss-Seidel forward before the coarse
//! correction and backward after it (each other's adjoint, so the cycle is a symmetric
//! operator and conjugate gradients stay valid), and at the coarsest level a dense Cholesky
//! factorisation (or, for a coarsest level too large to factor, symmetric Gauss-Seidel
//! sweeps). The levels are numbered colour by colour (`colour.rs`), so a sweep updates the
//! groups of nodes of one colour at a time, independently; the sweeps (a group a block), the
//! residuals and transfers (blocks of [`ROW_BLOCK`] rows) run on the caller's [`Join`] (a
//! model's thread pool), every row summed in its column order, so the cycle has the same bits
//! on any number of threads.

use alloc::vec::Vec;

use super::super::super::super::super::math;
use super::super::super::super::super::types::Real;
use super::super::super::super::vertex_pass::{Blocks, Join, VertexPass};
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
    /// The first row of every colour and the row count last (`colour.rs`; empty until the
    /// hierarchy colours the level, and a sweep does nothing before).
    pub colours: Vec<usize>,
    /// The rows of a group of the colouring: a colour's groups start this many rows apart.
    pub group_rows: usize,
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
            colours: Vec::new(),
            group_rows: 1,
        })
    }

    /// One Gauss-Seidel sweep on `A x = b`: rows ascending (`forward`), colour by colour, or
    /// descending. The groups of one colour share no entry, so their updates are independent:
    /// they run one group a block given to `join`, each group's rows in the sweep's order, with
    /// the bits of the plain sweep in the new row order for any `join`.
    pub fn gauss_seidel<J: Join + Sync>(&mut self, join: &J, forward: bool) {
        let colours = self.colours.len().saturating_sub(1);
        for k in 0..colours {
            let c = if forward { k } else { colours - 1 - k };
            let (Some(&start), Some(&end)) = (self.colours.get(c), self.colours.get(c + 1)) else {
                continue;
            };
            let Some((before, rest)) = self.x.split_at_mut_checked(start) else {
                continue;
            };
            let Some((own, after)) = rest.split_at_mut_checked(end.saturating_sub(start)) else {
                continue;
            };
            let (before, after): (&[Real], &[Real]) = (before, after);
            let (matrix, b, inverse_diagonal) = (&self.matrix, &self.b, &self.inverse_diagonal);
            let block = |first: usize, own: &mut [Real]| {
                let rows = own.len();
                let offset = start + first;
                let mut update = |j: usize| {
                    let i = offset + j;
                    let inverse = inverse_diagonal.get(i).copied().unwrap_or(0.0);
                    if inverse == 0.0 {
                        return;
                    }
                    let (columns, values) = matrix.row(i);
                    // Columns ascend: before this colour, this block's own group, after it.
                    let low = columns.partition_point(|&c| (c as usize) < start);
                    let high = columns.partition_point(|&c| (c as usize) < end);
                    let mut sum = b.get(i).copied().unwrap_or(0.0);
                    for (&c, &a) in columns.iter().zip(values).take(low) {
                        sum -= a * before.get(c as usize).copied().unwrap_or(0.0);
                    }
                    let middle = columns.get(low..high).unwrap_or(&[]);
                    for (&c, &a) in middle.iter().zip(values.get(low..high).unwrap_or(&[])) {
                        let local = (c as usize).wrapping_sub(offset);
                        sum -= a * own.get(local).copied().unwrap_or(0.0);
                    }
                    let upper = columns.get(high..).unwrap_or(&[]);
                    for (&c, &a) in upper.iter().zip(values.get(high..).unwrap_or(&[])) {
                        let index = (c as usize).wrapping_sub(end);
                        sum -= a * after.get(index).copied().unwrap_or(0.0);
                    }
                    if let Some(x) = own.get_mut(j) {
                        *x += inverse * sum;
                    }
                };
                if forward {
                    (0..rows).for_each(&mut update);
                } else {
                    (0..rows).rev().for_each(&mut update);
                }
            };
            Blocks::of_len(self.group_rows, own.len(), own, &block).run_with(join);
        }
    }

    /// `r = b - A x` right after a forward sweep from `x = 0`: the sweep left `(D + L) x = b`
    /// on every row it updated (to rounding), so there `r = -U x` and only the entries right of
    /// the diagonal are read (half the stream); frozen rows take the whole row. In blocks of
    /// [`ROW_BLOCK`] rows given to `join`.
    pub fn residual_after_forward_sweep<J: Join + Sync>(&mut self, join: &J) {
        let (matrix, b, x, inverse_diagonal) =
            (&self.matrix, &self.b, &self.x, &self.inverse_diagonal);
        let block = |first: usize, r: &mut [Real]| {
            for (j, r) in r.iter_mut().enumerate() {
                let i = first + j;
                let (columns, values) = matrix.row(i);
                let frozen = inverse_diagonal.get(i).is_none_or(|&d| d == 0.0);
                let (start, mut sum) = if frozen {
                    (0, b.get(i).copied().unwrap_or(0.0))
                } else {
                    (columns.partition_point(|&c| c as usize <= i), 0.0)
                };
                let upper = columns.get(start..).unwrap_or(&[]);
                for (&c, &a) in upper.iter().zip(values.get(start..).unwrap_or(&[])) {
                    sum -= a * x.get(c as usize).copied().unwrap_or(0.0);
                }
                *r = sum;
            }
        };
        Blocks::of_len(ROW_BLOCK, self.r.len(), &mut self.r[..], &block).run_with(join);
    }
}

/// The rows per block of the cycle's passes but the sweeps (residual, transfers, the finest
/// level's gather).
pub(crate) const ROW_BLOCK: usize = 192;

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
/// answer in `levels[0].x`. Every pass but the coarsest level's dense solve runs in blocks of
/// rows given to `join`, each row's sum in its column order: the same bits for any `join`.
pub(crate) fn v_cycle<J: Join + Sync>(join: &J, levels: &mut [Level], coarsest: &Coarsest) {
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
                    this.gauss_seidel(join, true);
                    this.gauss_seidel(join, false);
                }
            }
            break;
        };
        this.gauss_seidel(join, true);
        this.residual_after_forward_sweep(join);
        this.restriction.product_with(join, &this.r, &mut next.b, false);
    }
    for l in (0..depth.saturating_sub(1)).rev() {
        let (this, rest) = match levels.get_mut(l..) {
            Some([this, rest @ ..]) => (this, rest),
            _ => return,
        };
        if let Some(next) = rest.first() {
            this.prolongator.product_with(join, &next.x, &mut this.x, true);
        }
        this.gauss_seidel(join, false);
    }
}

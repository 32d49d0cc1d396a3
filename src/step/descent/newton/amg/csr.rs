//! Compressed sparse rows: the matrices of every level of the hierarchy, their products
//! (Gustavson's row-by-row product with a dense accumulator), transposes and matrix-vector
//! products. Columns are sorted within each row and every sum runs in a fixed order (the row's
//! column order, or the order of the factor's rows), so the bits depend on nothing but the
//! input.

use alloc::vec::Vec;
use core::ops::Range;

use super::super::super::super::super::types::Real;
use super::super::super::super::vertex_pass::sealed::Sealed;
use super::super::super::super::vertex_pass::{Blocks, Join, VertexPass};
use super::cycle::ROW_BLOCK;
use super::{OutOfMemory, filled, push};

/// The rows of a product's chunk ([`Csr::multiply_with`]): each chunk has its own dense
/// accumulator of the right factor's columns.
const MULTIPLY_ROWS: usize = 2048;

/// A sparse matrix in compressed sparse rows: row `i`'s entries are `starts[i]..starts[i + 1]`
/// of `columns` (ascending) and `values`.
#[derive(Debug, Default)]
pub(crate) struct Csr {
    pub rows: usize,
    pub cols: usize,
    pub starts: Vec<usize>,
    pub columns: Vec<u32>,
    pub values: Vec<Real>,
}

impl Csr {
    /// Row `i`'s columns and values (empty out of range).
    #[inline(always)]
    pub fn row(&self, i: usize) -> (&[u32], &[Real]) {
        let start = self.starts.get(i).copied().unwrap_or(0);
        let end = self.starts.get(i + 1).copied().unwrap_or(start);
        let columns = self.columns.get(start..end).unwrap_or(&[]);
        let values = self.values.get(start..end).unwrap_or(&[]);
        (columns, values)
    }

    /// Stored entries.
    #[inline]
    pub fn entries(&self) -> usize {
        self.columns.len()
    }

    /// Rows `first..first + y.len()` of `A x` into `y`, or added to it (`add`); missing
    /// entries of `x` read as zero, each row summed in its column order.
    pub fn product_rows(&self, first: usize, x: &[Real], y: &mut [Real], add: bool) {
        for (j, out) in y.iter_mut().enumerate() {
            let (columns, values) = self.row(first + j);
            let mut sum = 0.0;
            for (&c, &a) in columns.iter().zip(values) {
                sum += a * x.get(c as usize).copied().unwrap_or(0.0);
            }
            *out = if add { *out + sum } else { sum };
        }
    }

    /// Entry `(i, i)` of every row (0 where none is stored).
    pub fn diagonal(&self) -> Result<Vec<Real>, OutOfMemory> {
        let mut diagonal = filled(self.rows, 0.0)?;
        for (i, d) in diagonal.iter_mut().enumerate() {
            let (columns, values) = self.row(i);
            if let Ok(k) = columns.binary_search(&(i as u32)) {
                *d = values.get(k).copied().unwrap_or(0.0);
            }
        }
        Ok(diagonal)
    }

    /// The transpose, by a counting sort of the entries on their column (stable, so each row
    /// of the transpose keeps ascending columns).
    pub fn transpose(&self) -> Result<Csr, OutOfMemory> {
        let mut starts = filled(self.cols + 1, 0usize)?;
        for &c in &self.columns {
            if let Some(count) = starts.get_mut((c as usize).saturating_add(1)) {
                *count += 1;
            }
        }
        for k in 1..starts.len() {
            let previous = starts.get(k - 1).copied().unwrap_or(0);
            if let Some(s) = starts.get_mut(k) {
                *s += previous;
            }
        }
        let mut next = starts.clone();
        let mut columns = filled(self.entries(), 0u32)?;
        let mut values = filled(self.entries(), 0.0)?;
        for i in 0..self.rows {
            let (row_columns, row_values) = self.row(i);
            for (&c, &a) in row_columns.iter().zip(row_values) {
                let Some(at) = next.get_mut(c as usize) else {
                    continue;
                };
                if let (Some(column), Some(value)) = (columns.get_mut(*at), values.get_mut(*at)) {
                    *column = i as u32;
                    *value = a;
                }
                *at += 1;
            }
        }
        Ok(Csr {
            rows: self.cols,
            cols: self.rows,
            starts,
            columns,
            values,
        })
    }

    /// `A B` by Gustavson's algorithm: row `i` of the product accumulates `a_ik` times row `k`
    /// of `B` over row `i`'s entries in column order, in a dense accumulator; its touched
    /// columns are then sorted. Every product entry is stored that some pair touched (even if
    /// it sums to zero), so block structure survives. The rows run in fixed chunks of
    /// [`MULTIPLY_ROWS`] given to `join`, each with its own accumulator, then joined end to
    /// end: the same bits for any `join`.
    pub fn multiply_with<J: Join + Sync>(
        &self,
        join: &J,
        other: &Csr,
    ) -> Result<Csr, OutOfMemory> {
        let chunks = self.rows.div_ceil(MULTIPLY_ROWS);
        let mut parts: Vec<Option<Result<Csr, OutOfMemory>>> = Vec::new();
        parts.try_reserve_exact(chunks).map_err(|_| OutOfMemory)?;
        parts.resize_with(chunks, || None);
        let block = |first: usize, slots: &mut [Option<Result<Csr, OutOfMemory>>]| {
            for (k, slot) in slots.iter_mut().enumerate() {
                let start = (first + k) * MULTIPLY_ROWS;
                let end = (start + MULTIPLY_ROWS).min(self.rows);
                *slot = Some(self.multiply_rows(other, start..end));
            }
        };
        Blocks::of_len(1, chunks, &mut parts[..], &block).run_with(join);
        let mut entries = 0;
        for part in &parts {
            match part {
                Some(Ok(part)) => entries += part.entries(),
                _ => return Err(OutOfMemory),
            }
        }
        let mut starts = filled(self.rows + 1, 0usize)?;
        let mut columns = filled(entries, 0u32)?;
        let mut values = filled(entries, 0.0)?;
        let (mut row, mut at) = (0, 0);
        for part in parts.into_iter().flatten().flatten() {
            let range = at..at + part.entries();
            if let (Some(c), Some(v)) = (columns.get_mut(range.clone()), values.get_mut(range)) {
                c.copy_from_slice(&part.columns);
                v.copy_from_slice(&part.values);
            }
            for (s, &p) in starts
                .get_mut(row + 1..)
                .unwrap_or(&mut [])
                .iter_mut()
                .zip(part.starts.get(1..).unwrap_or(&[]))
            {
                *s = at + p;
            }
            row += part.rows;
            at += part.entries();
        }
        Ok(Csr {
            rows: self.rows,
            cols: other.cols,
            starts,
            columns,
            values,
        })
    }

    /// Rows `rows` of `A B` as a matrix of their own (Gustavson's algorithm, as
    /// [`multiply_with`](Self::multiply_with)).
    fn multiply_rows(&self, other: &Csr, rows: Range<usize>) -> Result<Csr, OutOfMemory> {
        let mut accumulator = filled(other.cols, 0.0)?;
        let mut touched_flag = filled(other.cols, false)?;
        let mut touched: Vec<u32> = Vec::new();
        let mut starts = filled(rows.len() + 1, 0usize)?;
        let mut columns: Vec<u32> = Vec::new();
        let mut values: Vec<Real> = Vec::new();
        for (local, i) in rows.clone().enumerate() {
            touched.clear();
            let (a_columns, a_values) = self.row(i);
            for (&k, &a) in a_columns.iter().zip(a_values) {
                let (b_columns, b_values) = other.row(k as usize);
                for (&j, &b) in b_columns.iter().zip(b_values) {
                    let (Some(sum), Some(flag)) = (
                        accumulator.get_mut(j as usize),
                        touched_flag.get_mut(j as usize),
                    ) else {
                        continue;
                    };
                    if !*flag {
                        *flag = true;
                        push(&mut touched, j)?;
                    }
                    *sum += a * b;
                }
            }
            touched.sort_unstable();
            columns
                .try_reserve(touched.len())
                .map_err(|_| OutOfMemory)?;
            values.try_reserve(touched.len()).map_err(|_| OutOfMemory)?;
            for &j in &touched {
                let (Some(sum), Some(flag)) = (
                    accumulator.get_mut(j as usize),
                    touched_flag.get_mut(j as usize),
                ) else {
                    continue;
                };
                columns.push(j);
                values.push(*sum);
                *sum = 0.0;
                *flag = false;
            }
            if let Some(s) = starts.get_mut(local + 1) {
                *s = columns.len();
            }
        }
        Ok(Csr {
            rows: rows.len(),
            cols: other.cols,
            starts,
            columns,
            values,
        })
    }

    /// `y = A x`, or `y += A x` (`add`), in blocks of [`ROW_BLOCK`] rows of `y` given to
    /// `join`.
    pub fn product_with<J: Join + Sync>(&self, join: &J, x: &[Real], y: &mut [Real], add: bool) {
        let block = |first: usize, y: &mut [Real]| self.product_rows(first, x, y, add);
        Blocks::of_len(ROW_BLOCK, y.len(), y, &block).run_with(join);
    }

    /// Makes the matrix exactly symmetric, `(A + A^T) / 2`, where its pattern is symmetric (a
    /// Galerkin product `P^T A P` is symmetric up to rounding); unchanged otherwise.
    pub fn symmetrize(&mut self) -> Result<(), OutOfMemory> {
        let transpose = self.transpose()?;
        if transpose.starts != self.starts || transpose.columns != self.columns {
            return Ok(());
        }
        for (a, &b) in self.values.iter_mut().zip(&transpose.values) {
            *a = 0.5 * (*a + b);
        }
        Ok(())
    }
}

/// `left * right` as one pass for a model's thread pool ([`Csr::multiply_with`]).
pub(crate) struct Multiply<'m> {
    pub left: &'m Csr,
    pub right: &'m Csr,
}

impl Sealed for Multiply<'_> {}

impl VertexPass for Multiply<'_> {
    type Output = Result<Csr, OutOfMemory>;

    fn run_with<J: Join + Sync>(self, join: &J) -> Self::Output {
        self.left.multiply_with(join, self.right)
    }
}

/// `y = matrix x` as one pass for a model's thread pool ([`Csr::product_with`]).
pub(crate) struct Product<'m> {
    pub matrix: &'m Csr,
    pub x: &'m [Real],
    pub y: &'m mut [Real],
}

impl Sealed for Product<'_> {}

impl VertexPass for Product<'_> {
    type Output = ();

    fn run_with<J: Join + Sync>(self, join: &J) {
        self.matrix.product_with(join, self.x, self.y, false);
    }
}

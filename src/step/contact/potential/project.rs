//! The projection of a pair's 12x12 contact Hessian onto the positive semi-definite cone, by
//! the Jacobi eigen-solver of [`SymmetricMatrix`] (`docs/math.md` section 8.9).

use super::super::super::super::element::SymmetricMatrix;
use super::super::super::super::types::{Mat3, Real};

/// The 12x12 matrix of the blocks (row `3 k + i`, column `3 l + j`), symmetrised: each
/// off-diagonal pair of entries replaced by their mean.
pub(super) fn to_rows(hessian: &[[Mat3; 4]; 4]) -> [[Real; 12]; 12] {
    let mut rows = [[0.0; 12]; 12];
    for (k, block_row) in hessian.iter().enumerate() {
        for (l, block) in block_row.iter().enumerate() {
            for (j, column) in block.to_cols_array_2d().iter().enumerate() {
                for (i, &entry) in column.iter().enumerate() {
                    if let Some(slot) = rows.get_mut(3 * k + i).and_then(|r| r.get_mut(3 * l + j)) {
                        *slot = entry;
                    }
                }
            }
        }
    }
    symmetrise(&mut rows);
    rows
}

/// Replaces `a_ij` and `a_ji` by their mean.
fn symmetrise(rows: &mut [[Real; 12]; 12]) {
    for i in 0..12 {
        for j in (i + 1)..12 {
            let upper = rows.get(i).and_then(|r| r.get(j)).copied().unwrap_or(0.0);
            let lower = rows.get(j).and_then(|r| r.get(i)).copied().unwrap_or(0.0);
            let mean = 0.5 * (upper + lower);
            if let Some(slot) = rows.get_mut(i).and_then(|r| r.get_mut(j)) {
                *slot = mean;
            }
            if let Some(slot) = rows.get_mut(j).and_then(|r| r.get_mut(i)) {
                *slot = mean;
            }
        }
    }
}

/// The 3x3 blocks of a 12x12 matrix (the inverse of [`to_rows`] without the symmetrisation).
fn to_blocks(matrix: &SymmetricMatrix<12>) -> [[Mat3; 4]; 4] {
    core::array::from_fn(|k| {
        core::array::from_fn(|l| {
            let columns: [[Real; 3]; 3] =
                core::array::from_fn(|j| column(matrix, 3 * k, 3 * l + j));
            Mat3::from_cols_array_2d(&columns)
        })
    })
}

/// Rows `first..first + 3` of column `column` of `matrix`.
fn column(matrix: &SymmetricMatrix<12>, first: usize, column: usize) -> [Real; 3] {
    core::array::from_fn(|i| matrix.entry(first + i, column))
}

/// The positive semi-definite part of a pair Hessian, as one symmetric 12x12 matrix (the Jacobi
/// eigen-solver of [`SymmetricMatrix`]); exactly symmetric, and the symmetrised input itself
/// when that has no negative Jacobi eigenvalue.
pub(super) fn project(hessian: &[[Mat3; 4]; 4]) -> [[Mat3; 4]; 4] {
    let exact = SymmetricMatrix::from_rows(to_rows(hessian));
    let positive = exact.positive_part();
    if positive == exact {
        return to_blocks(&exact);
    }
    // `Q max(Lambda, 0) Q^T` is symmetric only up to rounding: the mean makes it exact and keeps
    // it semi-definite (the quadratic form is unchanged).
    let mut rows: [[Real; 12]; 12] =
        core::array::from_fn(|i| core::array::from_fn(|j| positive.entry(i, j)));
    symmetrise(&mut rows);
    to_blocks(&SymmetricMatrix::from_rows(rows))
}

//! The projection of a pair's 12x12 contact Hessian onto the positive semi-definite cone
//! (`docs/math.md` section 8.9): cyclic Jacobi rotations (G. H. Golub and C. F. Van Loan,
//! "Matrix Computations", 4th ed., 2013, section 8.5) on a fixed-size array, stopped as soon as
//! the off-diagonal part is below rounding, then the eigenvalues clamped at zero. A pair's
//! Hessian has the translations in its null space, so only its 9x9 block of relative motions
//! (in a Hadamard basis) is diagonalised.

use super::super::super::super::material::hessian::JacobiAngle;
use super::super::super::super::types::{Mat3, Real};

/// The dimension: four points of three coordinates.
const N: usize = 12;

/// The most sweeps (each rotates every off-diagonal pair once). Jacobi converges
/// quadratically: pair Hessians reach the stopping test in 3 to 7 (mostly 4 or 5).
const MAX_SWEEPS: usize = 10;

/// The 12x12 matrix of the blocks (row `3 k + i`, column `3 l + j`), symmetrised: each
/// off-diagonal pair of entries replaced by their mean.
pub(super) fn to_rows(hessian: &[[Mat3; 4]; 4]) -> [[Real; N]; N] {
    let mut rows = [[0.0; N]; N];
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
fn symmetrise(rows: &mut [[Real; N]; N]) {
    for i in 0..N {
        for j in (i + 1)..N {
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
fn to_blocks(rows: &[[Real; N]; N]) -> [[Mat3; 4]; 4] {
    let entry = |i: usize, j: usize| rows.get(i).and_then(|r| r.get(j)).copied().unwrap_or(0.0);
    core::array::from_fn(|k| {
        core::array::from_fn(|l| {
            let columns: [[Real; 3]; 3] =
                core::array::from_fn(|j| core::array::from_fn(|i| entry(3 * k + i, 3 * l + j)));
            Mat3::from_cols_array_2d(&columns)
        })
    })
}

/// The sum of the squares of the strictly upper entries (the off-diagonal part, halved) and of
/// all entries.
fn off_and_total<const M: usize>(a: &[[Real; M]; M]) -> (Real, Real) {
    let (mut off, mut total): (Real, Real) = (0.0, 0.0);
    for (i, row) in a.iter().enumerate() {
        for (j, &x) in row.iter().enumerate() {
            let square = x * x;
            total += square;
            if j > i {
                off += square;
            }
        }
    }
    (off, total)
}

/// One Jacobi rotation zeroing `a[p][r]` (`p < r < N`) of the symmetric `a`, accumulated into
/// the rows `p` and `r` of `vectors` (row `i` the eigenvector of `a[i][i]`). The rows `p` and
/// `r` are rotated, then copied into the columns, so `a` stays exactly symmetric.
fn rotate<const M: usize>(
    a: &mut [[Real; M]; M],
    vectors: &mut [[Real; M]; M],
    p: usize,
    r: usize,
) {
    let entry = |a: &[[Real; M]; M], i: usize, j: usize| {
        a.get(i).and_then(|row| row.get(j)).copied().unwrap_or(0.0)
    };
    let apr = entry(a, p, r);
    if apr == 0.0 {
        return;
    }
    let (app, arr) = (entry(a, p, p), entry(a, r, r));
    let JacobiAngle { t, cos, sin } = JacobiAngle::zeroing(app, arr, apr);
    let rotate_rows = |rows: &mut [[Real; M]; M]| {
        let (head, tail) = rows.split_at_mut(r);
        if let (Some(row_p), Some(row_r)) = (head.get_mut(p), tail.first_mut()) {
            for (x, y) in row_p.iter_mut().zip(row_r.iter_mut()) {
                let (xp, xr) = (*x, *y);
                *x = cos * xp - sin * xr;
                *y = sin * xp + cos * xr;
            }
        }
    };
    rotate_rows(a);
    rotate_rows(vectors);
    // The 2x2 block in closed form (exactly diagonal), then the rows mirrored into the columns.
    let (row_p, row_r) = (
        a.get(p).copied().unwrap_or([0.0; M]),
        a.get(r).copied().unwrap_or([0.0; M]),
    );
    for ((row, &xp), &xr) in a.iter_mut().zip(&row_p).zip(&row_r) {
        if let Some(v) = row.get_mut(p) {
            *v = xp;
        }
        if let Some(v) = row.get_mut(r) {
            *v = xr;
        }
    }
    let set = |a: &mut [[Real; M]; M], i: usize, j: usize, value: Real| {
        if let Some(v) = a.get_mut(i).and_then(|row| row.get_mut(j)) {
            *v = value;
        }
    };
    set(a, p, p, app - t * apr);
    set(a, r, r, arr + t * apr);
    set(a, p, r, 0.0);
    set(a, r, p, 0.0);
}

/// The eigenvalues (`values[i]`) and orthonormal eigenvectors (`vectors[i]`, a row) of the
/// symmetric `a`, by cyclic Jacobi sweeps until the off-diagonal part's squared norm is at
/// most `EPSILON^2` times the matrix's (then every eigenvalue is within rounding of the
/// diagonal, by Weyl's inequality), at most [`MAX_SWEEPS`].
fn eigen<const M: usize>(mut a: [[Real; M]; M]) -> ([Real; M], [[Real; M]; M]) {
    let mut vectors = [[0.0; M]; M];
    for (i, row) in vectors.iter_mut().enumerate() {
        if let Some(x) = row.get_mut(i) {
            *x = 1.0;
        }
    }
    for _ in 0..MAX_SWEEPS {
        let (off, total) = off_and_total(&a);
        if off <= Real::EPSILON * Real::EPSILON * total {
            break;
        }
        for p in 0..M {
            for r in (p + 1)..M {
                rotate(&mut a, &mut vectors, p, r);
            }
        }
    }
    let values: [Real; M] =
        core::array::from_fn(|i| a.get(i).and_then(|row| row.get(i)).copied().unwrap_or(0.0));
    (values, vectors)
}

/// `sum_{l_i > 0} l_i q_i q_i^T` of the eigenpairs `values[i]`, `vectors[i]` (a row), each upper
/// entry once, mirrored: exactly symmetric.
fn positive_sum<const M: usize>(values: &[Real; M], vectors: &[[Real; M]; M]) -> [[Real; M]; M] {
    let mut rows = [[0.0; M]; M];
    for (value, vector) in values.iter().zip(vectors) {
        if *value <= 0.0 {
            continue;
        }
        for (i, row) in rows.iter_mut().enumerate() {
            let scaled = vector.get(i).copied().unwrap_or(0.0) * value;
            for (out, &x) in row.iter_mut().zip(vector).skip(i) {
                *out += scaled * x;
            }
        }
    }
    mirror_upper(&mut rows);
    rows
}

/// Copies each upper entry onto its mirror below the diagonal.
fn mirror_upper<const M: usize>(rows: &mut [[Real; M]; M]) {
    for i in 0..M {
        for j in (i + 1)..M {
            let upper = rows.get(i).and_then(|r| r.get(j)).copied().unwrap_or(0.0);
            if let Some(slot) = rows.get_mut(j).and_then(|r| r.get_mut(i)) {
                *slot = upper;
            }
        }
    }
}

/// The 4x4 Hadamard matrix over 2 (symmetric, orthogonal, its own inverse, entries exact): row 0
/// the uniform translation of the four points, rows 1 to 3 the motions orthogonal to it.
const HADAMARD: [[Real; 4]; 4] = [
    [0.5, 0.5, 0.5, 0.5],
    [0.5, -0.5, 0.5, -0.5],
    [0.5, 0.5, -0.5, -0.5],
    [0.5, -0.5, -0.5, 0.5],
];

/// `T a T` with `T = HADAMARD (x) I_3` (symmetric and orthogonal): `a` in the basis of the
/// translations (rows and columns 0 to 2) and the three relative motions (3 to 11).
fn hadamard_congruence(a: &[[Real; N]; N]) -> [[Real; N]; N] {
    let h = |x: usize, y: usize| {
        HADAMARD
            .get(x)
            .and_then(|r| r.get(y))
            .copied()
            .unwrap_or(0.0)
    };
    let entry = |m: &[[Real; N]; N], i: usize, j: usize| {
        m.get(i).and_then(|r| r.get(j)).copied().unwrap_or(0.0)
    };
    // Rows first (T a), then columns ((T a) T).
    let left: [[Real; N]; N] = core::array::from_fn(|row| {
        let (block, i) = (row / 3, row % 3);
        core::array::from_fn(|column| {
            (0..4).fold(0.0, |sum, k| {
                sum + h(block, k) * entry(a, 3 * k + i, column)
            })
        })
    });
    core::array::from_fn(|row| {
        core::array::from_fn(|column| {
            let (block, j) = (column / 3, column % 3);
            (0..4).fold(0.0, |sum, l| {
                sum + entry(&left, row, 3 * l + j) * h(l, block)
            })
        })
    })
}

/// The positive semi-definite part of a pair Hessian, as one symmetric 12x12 matrix: the
/// symmetrised input itself when it has no negative Jacobi eigenvalue, else `sum_{l_i > 0}
/// l_i q_i q_i^T` (exactly symmetric).
///
/// A pair's Hessian does not change under a translation of its four points, so it has the
/// three translations in its null space: in the Hadamard basis ([`hadamard_congruence`]) only
/// its 9x9 block of relative motions is nonzero, and that block is diagonalised instead (36
/// rotations a sweep of 9-vectors rather than 66 of 12-vectors). Where the translation rows
/// are not within rounding of zero (a matrix from elsewhere), the whole 12x12 is.
pub(super) fn project(hessian: &[[Mat3; 4]; 4]) -> [[Mat3; 4]; 4] {
    let exact = to_rows(hessian);
    let largest = exact
        .iter()
        .flatten()
        .fold(0.0, |m: Real, x| m.max(x.abs()));
    let rotated = hadamard_congruence(&exact);
    // Rounding of the congruence: sums of 16 entries over 4; anything larger is a real
    // coupling to translations.
    let tolerance = 64.0 * Real::EPSILON * largest;
    let translation = rotated
        .iter()
        .take(3)
        .flatten()
        .all(|x| x.abs() <= tolerance);
    if !translation {
        let (values, vectors) = eigen(exact);
        if values.iter().all(|&l| l >= 0.0) {
            return to_blocks(&exact);
        }
        return to_blocks(&positive_sum(&values, &vectors));
    }
    let relative: [[Real; 9]; 9] = core::array::from_fn(|i| {
        core::array::from_fn(|j| {
            rotated
                .get(i + 3)
                .and_then(|r| r.get(j + 3))
                .copied()
                .unwrap_or(0.0)
        })
    });
    let (values, vectors) = eigen(relative);
    if values.iter().all(|&l| l >= 0.0) {
        return to_blocks(&exact);
    }
    let positive = positive_sum(&values, &vectors);
    let mut embedded = [[0.0; N]; N];
    for (row, source) in embedded.iter_mut().skip(3).zip(&positive) {
        for (out, &x) in row.iter_mut().skip(3).zip(source) {
            *out = x;
        }
    }
    let mut rows = hadamard_congruence(&embedded);
    mirror_upper(&mut rows);
    to_blocks(&rows)
}

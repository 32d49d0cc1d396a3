//! The colouring and the colour-by-colour sweeps: no two nodes of a colour share an entry, the
//! renumbering is a symmetric permutation of the matrix, and the sweeps and residual run in
//! blocks on any join give the bits of the plain Gauss-Seidel sweep in the new row order.

extern crate std;
use std::vec::Vec;

use super::super::super::super::super::types::Real;
use super::super::super::super::vertex_pass::{InOrder, Join};
use super::colour::{Colouring, renumbered};
use super::csr::Csr;
use super::cycle::Level;

/// A [`Join`] that runs `b` before `a`: any order gives the same bits.
struct Reversed;

impl Join for Reversed {
    fn join<A, B, RA, RB>(&self, a: A, b: B) -> (RA, RB)
    where
        A: FnOnce() -> RA + Send,
        B: FnOnce() -> RB + Send,
        RA: Send,
        RB: Send,
    {
        let b = b();
        (a(), b)
    }
}

/// A symmetric, diagonally dominant matrix on a `side x side` grid of nodes of `width` rows:
/// each node coupled to its eight grid neighbours (a nine-point stencil: four colours at
/// least) and within itself, entries of different sizes so that the order of a sum shows.
fn grid(side: usize, width: usize) -> Csr {
    let nodes = side * side;
    let rows = nodes * width;
    let mut starts = std::vec![0];
    let (mut columns, mut values) = (Vec::new(), Vec::new());
    // Symmetric: the value of (i, j) depends on the unordered pair.
    let coupling = |i: usize, j: usize| {
        let (a, b) = (i.min(j), i.max(j));
        -0.1 - 0.013 * ((a * 7 + b * 3) % 11) as Real
    };
    for i in 0..rows {
        let (node, _) = (i / width, i % width);
        let (gx, gy) = ((node % side) as isize, (node / side) as isize);
        let mut row = Vec::new();
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (x, y) = (gx + dx, gy + dy);
                if x < 0 || y < 0 || x >= side as isize || y >= side as isize {
                    continue;
                }
                let other = y as usize * side + x as usize;
                for k in 0..width {
                    let j = other * width + k;
                    row.push((j as u32, if j == i { 0.0 } else { coupling(i, j) }));
                }
            }
        }
        let off: Real = row.iter().map(|&(_, a): &(u32, Real)| a.abs()).sum();
        for entry in &mut row {
            if entry.0 as usize == i {
                entry.1 = off + 1.0 + 0.01 * (i % 5) as Real;
            }
        }
        row.sort_by_key(|&(j, _)| j);
        for (j, a) in row {
            columns.push(j);
            values.push(a);
        }
        starts.push(columns.len());
    }
    Csr {
        rows,
        cols: rows,
        starts,
        columns,
        values,
    }
}

/// The (width, group) pairs of the tests: single nodes and groups, a last group cut short
/// (5 does not divide the grids' node counts).
const SHAPES: [(usize, usize); 4] = [(3, 1), (3, 4), (6, 2), (6, 5)];

/// Every colour's groups share no entry (each row's columns inside its own colour are its own
/// group's rows), the renumbering is a permutation with its inverse, and the renumbered matrix
/// holds the same entries at the renumbered places.
#[test]
fn colours_are_independent_sets_and_renumbering_permutes() {
    for (width, group) in SHAPES {
        let matrix = grid(12, width);
        let colouring = Colouring::new(&matrix, width, group).unwrap();
        let nodes = matrix.rows / width;
        let rows = colouring.group_rows();
        assert_eq!(rows, width * group);
        if group == 1 {
            assert!(colouring.starts.len() >= 5, "a nine-point stencil: four colours at least");
        }
        assert_eq!(colouring.starts.last().copied(), Some(nodes));
        for (k, &node) in colouring.order.iter().enumerate() {
            assert_eq!(colouring.position[node as usize] as usize, k);
        }
        let renumbered = renumbered(&matrix, &colouring, &colouring).unwrap();
        assert_eq!(renumbered.entries(), matrix.entries());
        let row_starts = colouring.row_starts().unwrap();
        for c in 0..row_starts.len() - 1 {
            let (start, end) = (row_starts[c], row_starts[c + 1]);
            for i in start..end {
                let (columns, values) = renumbered.row(i);
                assert!(columns.windows(2).all(|w| w[0] < w[1]), "sorted");
                for (&j, &a) in columns.iter().zip(values) {
                    let j = j as usize;
                    if (start..end).contains(&j) {
                        let same = (j - start) / rows == (i - start) / rows;
                        assert!(same, "colour {c}: rows {i} and {j}, groups of {group}");
                    }
                    // The same entry as the old matrix's at the old places.
                    let (old_i, old_j) = (colouring.old_row(i), colouring.old_row(j));
                    let (old_columns, old_values) = matrix.row(old_i);
                    let at = old_columns.binary_search(&(old_j as u32)).unwrap();
                    assert_eq!(old_values[at].to_bits(), a.to_bits());
                }
            }
        }
    }
}

/// The plain forward (or backward) Gauss-Seidel sweep over all rows of `matrix`.
fn plain_sweep(matrix: &Csr, b: &[Real], x: &mut [Real], forward: bool) {
    let n = matrix.rows;
    let mut update = |i: usize| {
        let (columns, values) = matrix.row(i);
        let diagonal = values[columns.binary_search(&(i as u32)).unwrap()];
        let mut sum = b[i];
        for (&c, &a) in columns.iter().zip(values) {
            sum -= a * x[c as usize];
        }
        x[i] += (1.0 / diagonal) * sum;
    };
    if forward {
        (0..n).for_each(&mut update);
    } else {
        (0..n).rev().for_each(&mut update);
    }
}

/// On a coloured level, the colour-by-colour sweeps a group a block (in order, and with every
/// join's halves swapped) give the plain sweeps' bits, forward from zero then
/// backward; the residual after the forward sweep is `b - A x` to rounding (the skipped lower
/// part cancels `b` but for a few ulps of the row's terms).
#[test]
fn coloured_sweeps_give_the_plain_sweeps_bits_on_any_join() {
    for (width, group) in SHAPES {
        let matrix = grid(24, width);
        let colouring = Colouring::new(&matrix, width, group).unwrap();
        let matrix = renumbered(&matrix, &colouring, &colouring).unwrap();
        let rows = matrix.rows;
        let row_starts = colouring.row_starts().unwrap();
        let widest = row_starts.windows(2).map(|w| w[1] - w[0]).max().unwrap();
        let group_rows = colouring.group_rows();
        assert!(widest > 2 * group_rows, "colours of several groups: {widest} rows");
        let b: Vec<Real> = (0..rows)
            .map(|i| 1.0 + ((i * 37) % 19) as Real * 0.25 - 2.0)
            .collect();

        let mut expected = std::vec![0.0; rows];
        plain_sweep(&matrix, &b, &mut expected, true);
        let mut expected_residual = std::vec![0.0; rows];
        matrix.product_rows(0, &expected, &mut expected_residual, false);
        for (r, &b) in expected_residual.iter_mut().zip(&b) {
            *r = b - *r;
        }
        let mut expected_backward = expected.clone();
        plain_sweep(&matrix, &b, &mut expected_backward, false);

        let bits = |v: &[Real]| v.iter().map(|a| a.to_bits()).collect::<Vec<_>>();
        for reversed in [false, true] {
            let mut level = Level::new(Csr {
                rows,
                cols: rows,
                starts: matrix.starts.clone(),
                columns: matrix.columns.clone(),
                values: matrix.values.clone(),
            })
            .unwrap();
            level.colours = row_starts.clone();
            level.group_rows = group_rows;
            level.b.copy_from_slice(&b);
            let forward = |level: &mut Level| {
                if reversed {
                    level.gauss_seidel(&Reversed, true);
                    level.residual_after_forward_sweep(&Reversed);
                } else {
                    level.gauss_seidel(&InOrder, true);
                    level.residual_after_forward_sweep(&InOrder);
                }
            };
            forward(&mut level);
            assert_eq!(bits(&level.x), bits(&expected), "forward, width {width}");
            let scale = b.iter().fold(0.0, |m: Real, v| m.max(v.abs()));
            // About 50 terms a row, each within a few times `|b|`: 256 eps of `|b|` is wide.
            for (r, e) in level.r.iter().zip(&expected_residual) {
                assert!((r - e).abs() <= 256.0 * Real::EPSILON * scale, "{r} {e}");
            }
            if reversed {
                level.gauss_seidel(&Reversed, false);
            } else {
                level.gauss_seidel(&InOrder, false);
            }
            assert_eq!(bits(&level.x), bits(&expected_backward), "backward, width {width}");
        }
    }
}

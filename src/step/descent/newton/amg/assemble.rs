//! The projected Hessian of one Newton iteration assembled as a sparse matrix with 3x3 vertex
//! blocks (stored as scalar rows, three per vertex, each row's columns in vertex order):
//! `S (M / h^2 + H + F) S + (I - S)`, `H` from the cached element Hessians, `M / h^2` and
//! friction's `F` on the diagonal blocks, `S_i` the constraint projection of vertex `i`. The
//! `I - S` part keeps the matrix positive definite on the removed components, which
//! decouple from the rest (the preconditioner is applied between two projections by `S`).

use alloc::vec::Vec;

use super::super::super::super::super::element::TetHessian;
use super::super::super::super::super::types::{Mat3, Vec3};
use super::super::super::super::model::ElasticHessian;
use super::csr::Csr;
use super::{OutOfMemory, SetupError, filled};

/// The vertex graph: vertex `i`'s neighbours (itself included, ascending) are
/// `neighbours[starts[i]..starts[i + 1]]`.
struct Graph {
    starts: Vec<usize>,
    neighbours: Vec<u32>,
}

impl Graph {
    /// The neighbours of vertex `i`.
    fn of(&self, i: usize) -> &[u32] {
        let start = self.starts.get(i).copied().unwrap_or(0);
        let end = self.starts.get(i + 1).copied().unwrap_or(start);
        self.neighbours.get(start..end).unwrap_or(&[])
    }
}

/// The vertex graph of the model's tetrahedra over `n` vertices: every pair of corners of an
/// element, and every vertex with itself.
fn graph<F: ElasticHessian>(
    model: &F,
    hessians: &[TetHessian],
    n: usize,
) -> Result<Graph, SetupError> {
    // Counts with repetition (each element adds its four corners to each corner's list).
    let mut counts = filled(n + 1, 0usize)?;
    let mut bad = None;
    let mut element = 0;
    let supported = model.for_each_element_hessian(hessians, |corners, _| {
        for &c in &corners {
            match counts.get_mut((c as usize).saturating_add(1)) {
                Some(count) => *count += 4,
                None => bad = bad.or(Some((element, c))),
            }
        }
        element += 1;
    });
    if !supported {
        return Err(SetupError::Unsupported);
    }
    if let Some((element, index)) = bad {
        return Err(SetupError::VertexIndex(element, index));
    }
    // Room for the vertex itself.
    for count in counts.iter_mut().skip(1) {
        *count += 1;
    }
    for k in 1..counts.len() {
        let previous = counts.get(k - 1).copied().unwrap_or(0);
        if let Some(c) = counts.get_mut(k) {
            *c += previous;
        }
    }
    let total = counts.last().copied().unwrap_or(0);
    let mut lists = filled(total, 0u32)?;
    let mut next = counts.clone();
    for (i, at) in next.iter_mut().take(n).enumerate() {
        if let Some(slot) = lists.get_mut(*at) {
            *slot = i as u32;
        }
        *at += 1;
    }
    model.for_each_element_hessian(hessians, |corners, _| {
        for &a in &corners {
            let Some(at) = next.get_mut(a as usize) else {
                continue;
            };
            for &b in &corners {
                if let Some(slot) = lists.get_mut(*at) {
                    *slot = b;
                }
                *at += 1;
            }
        }
    });
    // Sort and deduplicate each list in place, compacting as we go.
    let mut starts = filled(n + 1, 0usize)?;
    let mut write = 0;
    for i in 0..n {
        let (start, end) = (
            counts.get(i).copied().unwrap_or(0),
            counts.get(i + 1).copied().unwrap_or(0),
        );
        if let Some(list) = lists.get_mut(start..end) {
            list.sort_unstable();
        }
        let mut last = None;
        for k in start..end {
            let Some(v) = lists.get(k).copied() else {
                continue;
            };
            if last != Some(v) {
                if let Some(slot) = lists.get_mut(write) {
                    *slot = v;
                }
                write += 1;
                last = Some(v);
            }
        }
        if let Some(s) = starts.get_mut(i + 1) {
            *s = write;
        }
    }
    lists.truncate(write);
    Ok(Graph {
        starts,
        neighbours: lists,
    })
}

/// Adds the 3x3 `block` at block row `i`, block column position `k` (the index of the column
/// vertex in `i`'s neighbour list, `degree` of them) of the scalar rows of `matrix`.
#[inline(always)]
fn add_block(matrix: &mut Csr, i: usize, (k, degree): (usize, usize), block: Mat3) {
    for r in 0..3 {
        let start = matrix.starts.get(3 * i + r).copied().unwrap_or(0);
        let end = matrix.starts.get(3 * i + r + 1).copied().unwrap_or(start);
        if end.saturating_sub(start) != 3 * degree {
            continue;
        }
        let row = block.row(r);
        for (s, value) in row.to_array().into_iter().enumerate() {
            if let Some(a) = matrix.values.get_mut(start + 3 * k + s) {
                *a += value;
            }
        }
    }
}

/// Reads the 3x3 block at block row `i`, block column position `k`.
#[inline(always)]
fn block_at(matrix: &Csr, i: usize, k: usize) -> Mat3 {
    let entry = |r: usize, s: usize| {
        let start = matrix.starts.get(3 * i + r).copied().unwrap_or(0);
        matrix.values.get(start + 3 * k + s).copied().unwrap_or(0.0)
    };
    Mat3::from_cols_array_2d(&[
        [entry(0, 0), entry(1, 0), entry(2, 0)],
        [entry(0, 1), entry(1, 1), entry(2, 1)],
        [entry(0, 2), entry(1, 2), entry(2, 2)],
    ])
}

/// Writes the 3x3 block at block row `i`, block column position `k`.
#[inline(always)]
fn set_block(matrix: &mut Csr, i: usize, k: usize, block: Mat3) {
    for r in 0..3 {
        let start = matrix.starts.get(3 * i + r).copied().unwrap_or(0);
        for (s, value) in block.row(r).to_array().into_iter().enumerate() {
            if let Some(a) = matrix.values.get_mut(start + 3 * k + s) {
                *a = value;
            }
        }
    }
}

/// The assembled matrix of the module docs over `n` vertices: `diagonal(i)` is vertex `i`'s
/// diagonal addition (`m_i / h^2 I + F_i`), `projection(i)` its `S_i` (symmetric, eigenvalues
/// in `[0, 1]`).
pub(crate) fn assemble<F: ElasticHessian>(
    model: &F,
    hessians: &[TetHessian],
    n: usize,
    diagonal: &dyn Fn(usize) -> Mat3,
    projection: &dyn Fn(usize) -> Mat3,
) -> Result<Csr, SetupError> {
    if n.checked_mul(3).is_none_or(|rows| rows > u32::MAX as usize) {
        return Err(SetupError::OutOfMemory);
    }
    let graph = graph(model, hessians, n)?;
    let rows = 3 * n;
    let mut starts = filled(rows + 1, 0usize)?;
    let mut columns: Vec<u32> = Vec::new();
    let entries = graph
        .neighbours
        .len()
        .checked_mul(9)
        .ok_or(OutOfMemory)?;
    columns.try_reserve_exact(entries).map_err(|_| OutOfMemory)?;
    for i in 0..n {
        for r in 0..3 {
            for &j in graph.of(i) {
                for s in 0..3 {
                    columns.push(3 * j + s);
                }
            }
            if let Some(start) = starts.get_mut(3 * i + r + 1) {
                *start = columns.len();
            }
        }
    }
    let values = filled(columns.len(), 0.0)?;
    let mut matrix = Csr {
        rows,
        cols: rows,
        starts,
        columns,
        values,
    };
    model.for_each_element_hessian(hessians, |corners, hessian| {
        for (a, &ca) in corners.iter().enumerate() {
            let neighbours = graph.of(ca as usize);
            for (b, &cb) in corners.iter().enumerate() {
                if let Ok(k) = neighbours.binary_search(&cb) {
                    let block = hessian.corner_block(a, b);
                    add_block(&mut matrix, ca as usize, (k, neighbours.len()), block);
                }
            }
        }
    });
    for i in 0..n {
        let neighbours = graph.of(i);
        let Ok(self_position) = neighbours.binary_search(&(i as u32)) else {
            continue;
        };
        add_block(
            &mut matrix,
            i,
            (self_position, neighbours.len()),
            diagonal(i),
        );
    }
    // S A S + (I - S): only the blocks of constrained vertices change.
    let constrained = |i: usize| projection(i) != Mat3::IDENTITY;
    for i in 0..n {
        let neighbours = graph.of(i);
        let s_i = projection(i);
        let row_constrained = s_i != Mat3::IDENTITY;
        for (k, &j) in neighbours.iter().enumerate() {
            let j = j as usize;
            if !(row_constrained || constrained(j)) {
                continue;
            }
            let s_j = projection(j);
            let mut block = s_i * block_at(&matrix, i, k) * s_j;
            if i == j {
                block += Mat3::IDENTITY - s_i;
            }
            set_block(&mut matrix, i, k, block);
        }
    }
    Ok(matrix)
}

/// Vertex `i`'s projection `S_i` as a matrix, from the linear map `apply` (its three columns).
#[inline]
pub(crate) fn projection_matrix(apply: impl Fn(Vec3) -> Vec3) -> Mat3 {
    Mat3::from_cols(apply(Vec3::X), apply(Vec3::Y), apply(Vec3::Z))
}

//! Aggregation: the nodes of a level (a vertex's 3 rows on the finest, an aggregate's 6 on the
//! coarser ones) grouped into aggregates over their strong connections (Vaněk, Mandel and
//! Brezina, "Algebraic multigrid by smoothed aggregation for second and fourth order elliptic
//! problems", Computing 56, 1996, section 3; the three passes of PyAMG's
//! `standard_aggregation`). Nodes are visited in index order, so the aggregates depend on the
//! matrix only.

use alloc::vec::Vec;

use super::super::super::super::super::types::Real;
use super::csr::Csr;
use super::{OutOfMemory, filled, push};

/// No aggregate (an isolated node: no strong connection, left to the smoother).
pub(crate) const NONE: u32 = u32::MAX;

/// The strength threshold `theta`: nodes `i != j` are strongly connected where
/// `|A_ij|_F^2 > theta^2 |A_ii|_F |A_jj|_F`. Zero takes every non-zero block, PyAMG's default
/// for smoothed aggregation; blocks the constraints removed (zero) are never strong.
const THETA: Real = 0.0;

/// The strong neighbours of every node, as a node graph (without the node itself).
pub(crate) struct Strength {
    pub starts: Vec<usize>,
    pub neighbours: Vec<u32>,
}

impl Strength {
    /// The strong neighbours of node `i`.
    pub fn of(&self, i: usize) -> &[u32] {
        let start = self.starts.get(i).copied().unwrap_or(0);
        let end = self.starts.get(i + 1).copied().unwrap_or(start);
        self.neighbours.get(start..end).unwrap_or(&[])
    }
}

/// The strong connections of `matrix` over nodes of `block` rows each.
pub(crate) fn strength(matrix: &Csr, block: usize) -> Result<Strength, OutOfMemory> {
    let nodes = matrix.rows / block.max(1);
    let block = block.max(1);
    // |A_ij|_F^2 per node pair, node row by node row, in a dense accumulator.
    let mut squares = filled(nodes, 0.0)?;
    let mut flag = filled(nodes, false)?;
    let mut touched: Vec<u32> = Vec::new();
    let mut diagonal = filled(nodes, 0.0)?;
    let mut rows_of_pairs: Vec<(u32, Real)> = Vec::new();
    let mut row_starts = filled(nodes + 1, 0usize)?;
    for i in 0..nodes {
        touched.clear();
        for r in 0..block {
            let (columns, values) = matrix.row(block * i + r);
            for (&c, &a) in columns.iter().zip(values) {
                let j = c as usize / block;
                let (Some(sum), Some(seen)) = (squares.get_mut(j), flag.get_mut(j)) else {
                    continue;
                };
                if !*seen {
                    *seen = true;
                    push(&mut touched, j as u32)?;
                }
                *sum += a * a;
            }
        }
        touched.sort_unstable();
        for &j in &touched {
            let (Some(sum), Some(seen)) = (squares.get_mut(j as usize), flag.get_mut(j as usize))
            else {
                continue;
            };
            if j as usize == i {
                if let Some(d) = diagonal.get_mut(i) {
                    *d = super::super::super::super::super::math::sqrt(*sum);
                }
            } else {
                push(&mut rows_of_pairs, (j, *sum))?;
            }
            *sum = 0.0;
            *seen = false;
        }
        if let Some(s) = row_starts.get_mut(i + 1) {
            *s = rows_of_pairs.len();
        }
    }
    let mut starts = filled(nodes + 1, 0usize)?;
    let mut neighbours: Vec<u32> = Vec::new();
    for i in 0..nodes {
        let (start, end) = (
            row_starts.get(i).copied().unwrap_or(0),
            row_starts.get(i + 1).copied().unwrap_or(0),
        );
        let d_i = diagonal.get(i).copied().unwrap_or(0.0);
        for &(j, square) in rows_of_pairs.get(start..end).unwrap_or(&[]) {
            let d_j = diagonal.get(j as usize).copied().unwrap_or(0.0);
            if square > THETA * THETA * d_i * d_j && square > 0.0 {
                push(&mut neighbours, j)?;
            }
        }
        if let Some(s) = starts.get_mut(i + 1) {
            *s = neighbours.len();
        }
    }
    Ok(Strength { starts, neighbours })
}

/// The aggregate of every node ([`NONE`] for an isolated node) and the number of aggregates:
/// pass 1 makes an aggregate of every node whose strong neighbours are all free, with them;
/// pass 2 adds each remaining node to the first pass-1 aggregate among its strong neighbours;
/// pass 3 makes aggregates of what is left, each node with its free strong neighbours.
pub(crate) fn aggregates(strength: &Strength) -> Result<(Vec<u32>, u32), OutOfMemory> {
    let nodes = strength.starts.len().saturating_sub(1);
    let mut aggregate = filled(nodes, NONE)?;
    let mut count: u32 = 0;
    let agg = |aggregate: &[u32], j: u32| aggregate.get(j as usize).copied().unwrap_or(NONE);
    for i in 0..nodes {
        let neighbours = strength.of(i);
        if neighbours.is_empty() || agg(&aggregate, i as u32) != NONE {
            continue;
        }
        if neighbours.iter().any(|&j| agg(&aggregate, j) != NONE) {
            continue;
        }
        if let Some(a) = aggregate.get_mut(i) {
            *a = count;
        }
        for &j in neighbours {
            if let Some(a) = aggregate.get_mut(j as usize) {
                *a = count;
            }
        }
        count += 1;
    }
    let first_pass = count;
    for i in 0..nodes {
        if agg(&aggregate, i as u32) != NONE {
            continue;
        }
        let joined = strength
            .of(i)
            .iter()
            .map(|&j| agg(&aggregate, j))
            .find(|&a| a < first_pass);
        if let (Some(joined), Some(a)) = (joined, aggregate.get_mut(i)) {
            *a = joined;
        }
    }
    for i in 0..nodes {
        let neighbours = strength.of(i);
        if neighbours.is_empty() || agg(&aggregate, i as u32) != NONE {
            continue;
        }
        if let Some(a) = aggregate.get_mut(i) {
            *a = count;
        }
        for &j in neighbours {
            if let Some(a) = aggregate.get_mut(j as usize)
                && *a == NONE
            {
                *a = count;
            }
        }
        count += 1;
    }
    Ok((aggregate, count))
}

//! The order the cycle's Gauss-Seidel sweeps run in: every level's nodes (a vertex's three
//! rows on the finest level, an aggregate's six on the coarser ones) taken in groups of
//! consecutive nodes, the groups coloured greedily so that no two groups of one colour share a
//! stored entry, then the level renumbered colour by colour, group by group, keeping the node
//! order inside each group (the matrix on both sides, the transfer operators on theirs). A
//! sweep in the new row order updates the groups of one colour independently of each other,
//! so it runs them on any number of threads with the bits of the plain sweep (`cycle.rs`);
//! inside a group it is the plain sweep in the mesh's own order, whose neighbours are near in
//! memory. The colouring depends on the matrix's pattern only.

use alloc::vec::Vec;

use super::super::super::super::super::types::Real;
use super::csr::Csr;
use super::{OutOfMemory, filled, push};

/// A level's renumbering: `order[k]` is the node that becomes node `k` (colour by colour, in
/// node order within a colour), `position` its inverse, `starts[c]..starts[c + 1]` the new
/// nodes of colour `c`, `width` the rows per node and `group` the nodes per group. Every group
/// but the level's last is whole, and the last is last in its colour, so a colour's groups
/// start `group` nodes apart from the colour's first node.
#[derive(Debug, Default)]
pub(crate) struct Colouring {
    pub order: Vec<u32>,
    pub position: Vec<u32>,
    pub starts: Vec<usize>,
    pub width: usize,
    pub group: usize,
}

impl Colouring {
    /// The greedy colouring of the groups of `group` consecutive nodes of `matrix` (`width`
    /// rows each) in group order: each group takes the smallest colour no neighbour took
    /// before it (a neighbour shares a stored entry with one of its rows).
    pub fn new(matrix: &Csr, width: usize, group: usize) -> Result<Colouring, OutOfMemory> {
        let (width, group) = (width.max(1), group.max(1));
        let nodes = matrix.rows.div_ceil(width);
        let groups = nodes.div_ceil(group);
        let rows = group * width;
        let mut colour = filled(groups, u32::MAX)?;
        // `seen[c] == g` marks colour `c` as taken by a neighbour of group `g`.
        let mut seen: Vec<usize> = Vec::new();
        let mut counts: Vec<usize> = Vec::new();
        for g in 0..groups {
            for row in g * rows..((g + 1) * rows).min(matrix.rows) {
                for &c in matrix.row(row).0 {
                    let neighbour = colour.get(c as usize / rows).copied().unwrap_or(u32::MAX);
                    if let Some(slot) = seen.get_mut(neighbour as usize) {
                        *slot = g;
                    }
                }
            }
            let free = seen.iter().position(|&s| s != g).unwrap_or(seen.len());
            if free == seen.len() {
                push(&mut seen, g)?;
                push(&mut counts, 0)?;
            }
            if let Some(count) = counts.get_mut(free) {
                *count += group.min(nodes - g * group);
            }
            if let Some(slot) = colour.get_mut(g) {
                *slot = free as u32;
            }
        }
        // A counting sort of the nodes on their group's colour (stable: group, then node
        // order within a colour; the last, partial group last in its colour).
        let mut starts = filled(counts.len() + 1, 0usize)?;
        for (c, &count) in counts.iter().enumerate() {
            let previous = starts.get(c).copied().unwrap_or(0);
            if let Some(s) = starts.get_mut(c + 1) {
                *s = previous + count;
            }
        }
        let mut next = starts.clone();
        let mut order = filled(nodes, 0u32)?;
        let mut position = filled(nodes, 0u32)?;
        for node in 0..nodes {
            let c = colour.get(node / group).copied().unwrap_or(0);
            let Some(at) = next.get_mut(c as usize) else {
                continue;
            };
            if let Some(slot) = order.get_mut(*at) {
                *slot = node as u32;
            }
            if let Some(slot) = position.get_mut(node) {
                *slot = *at as u32;
            }
            *at += 1;
        }
        Ok(Colouring {
            order,
            position,
            starts,
            width,
            group,
        })
    }

    /// The rows of a whole group.
    #[inline]
    pub fn group_rows(&self) -> usize {
        self.group * self.width
    }

    /// The new row of old row `row`.
    #[inline(always)]
    fn new_row(&self, row: usize) -> u32 {
        let node = self.position.get(row / self.width).copied().unwrap_or(0) as usize;
        (node * self.width + row % self.width) as u32
    }

    /// The old row that becomes row `row`.
    #[inline(always)]
    pub fn old_row(&self, row: usize) -> usize {
        let node = self.order.get(row / self.width).copied().unwrap_or(0) as usize;
        node * self.width + row % self.width
    }

    /// The first row of every colour, and the row count last.
    pub fn row_starts(&self) -> Result<Vec<usize>, OutOfMemory> {
        let mut rows = filled(self.starts.len(), 0usize)?;
        for (r, &s) in rows.iter_mut().zip(&self.starts) {
            *r = s * self.width;
        }
        Ok(rows)
    }
}

/// `matrix` renumbered: its rows by `rows` (new row `k` is old row `rows.old_row(k)`), its
/// columns by `columns` (old column `c` becomes `columns.new_row(c)`), each row's columns
/// sorted again.
pub(crate) fn renumbered(
    matrix: &Csr,
    rows: &Colouring,
    columns: &Colouring,
) -> Result<Csr, OutOfMemory> {
    let mut starts = filled(matrix.rows + 1, 0usize)?;
    let mut new_columns = filled(matrix.entries(), 0u32)?;
    let mut values = filled(matrix.entries(), 0.0)?;
    let mut row_entries: Vec<(u32, Real)> = Vec::new();
    let mut at = 0;
    for k in 0..matrix.rows {
        let (old_columns, old_values) = matrix.row(rows.old_row(k));
        row_entries.clear();
        row_entries
            .try_reserve(old_columns.len())
            .map_err(|_| OutOfMemory)?;
        row_entries.extend(
            old_columns
                .iter()
                .zip(old_values)
                .map(|(&c, &a)| (columns.new_row(c as usize), a)),
        );
        row_entries.sort_unstable_by_key(|&(c, _)| c);
        for &(c, a) in &row_entries {
            if let (Some(column), Some(value)) = (new_columns.get_mut(at), values.get_mut(at)) {
                *column = c;
                *value = a;
            }
            at += 1;
        }
        if let Some(s) = starts.get_mut(k + 1) {
            *s = at;
        }
    }
    Ok(Csr {
        rows: matrix.rows,
        cols: matrix.cols,
        starts,
        columns: new_columns,
        values,
    })
}

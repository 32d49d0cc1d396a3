//! The packed element visits of a Vertex Block Descent sweep, in sweep order.
//!
//! A sweep visits every element once per corner (`step/descent/vbd/sums.rs`), several vertices of
//! one colour at a time, one per SIMD lane. Without this layout a visit gathers, lane by lane, the
//! element's corner indices from the adjacency, its rest data and its corner's shape gradient, and
//! stores them into the lane groups one value at a time: most of a visit's time. The layout stores
//! those values once, when the topology is built, already transposed: for each block of [`BLOCK`]
//! consecutive vertices of a colour (the sweep order of
//! [`vertex_order_by_degree`](super::super::super::super::mesh::adjacency::vertex_order_by_degree))
//! and each of the block's element visits `t` (the longest row of the block), the [`LAYOUT_VALUES`]
//! values of the visit of every lane side by side, so that a lane group loads each with one load;
//! only the corner positions, which the sweep changes, are still gathered. Lanes past the end of
//! their vertex's row hold zeros and are masked by the sweep.
//!
//! The values are those the gather computes, bit for bit (`Dm^-1` by columns, the rest volume
//! and the corner's shape gradient of
//! [`shape_gradient`](super::block::shape_gradient)), so a sweep with the layout gives the
//! bits of one without it, at every SIMD width: the widths (1, 4, 8, 16 values in f32; 1, 4, 8
//! in f64) all divide [`BLOCK`], and a narrower width walks a block's lanes in groups of its
//! own width.
//!
//! The layout fills the caller's buffers of
//! [`scratch_len::vbd_layout`](crate::step::scratch_len::vbd_layout) values and
//! [`scratch_len::vbd_layout_corners`](crate::step::scratch_len::vbd_layout_corners) indices (see
//! [`VbdScratch::with_layout`](super::super::super::VbdScratch::with_layout)). The corner buffer
//! starts with the blocks' first visit rows (one per block and one more; blocks are at most one per
//! vertex), then the corner indices of the visits.

use super::super::super::super::element::TetRest;
use super::super::super::super::types::Real;
use super::block::shape_gradient;

/// The vertices of a layout block: the widest lane group of either precision's SIMD widths
/// (16 f32 or 8 f64 in an AVX-512 register), which every narrower width divides.
pub(crate) const BLOCK: usize = 64 / core::mem::size_of::<Real>();

/// The values stored per element visit and lane: `Dm^-1` by columns (0..9), the rest volume
/// ([`VOLUME`]) and the corner's shape gradient ([`GRADIENT`]..).
pub(crate) const LAYOUT_VALUES: usize = 13;

/// Where the rest volume is among a visit's [`LAYOUT_VALUES`].
pub(crate) const VOLUME: usize = 9;

/// Where the shape gradient starts among a visit's [`LAYOUT_VALUES`].
pub(crate) const GRADIENT: usize = 10;

/// The visit rows (of [`BLOCK`] lanes each) the layout of a mesh of `element_count`
/// tetrahedra has room for: `ceil(6 * element_count / BLOCK) + 8 * 64`, room for half the element
/// visits (`4 * element_count`, one per element and corner) again in masked lanes, plus 64
/// visits of every lane of eight blocks. Vertices are ordered by their number of elements
/// within each colour, so a block's lanes have rows of about equal length; a mesh with very
/// uneven vertex valences that needs more does not use the layout (same results, slower).
#[inline]
#[must_use]
const fn layout_rows(element_count: usize) -> usize {
    // 4 E visits, times 1.5, over BLOCK lanes, rounded up generously.
    element_count
        .saturating_mul(6)
        .div_ceil(BLOCK)
        .saturating_add(8 * 64)
}

/// The length of the value buffer of the packed layout for `element_count` tetrahedra
/// ([`scratch_len::vbd_layout`](crate::step::scratch_len::vbd_layout) documents it).
#[inline]
#[must_use]
pub(crate) const fn values_len(element_count: usize) -> usize {
    layout_rows(element_count)
        .saturating_mul(BLOCK)
        .saturating_mul(LAYOUT_VALUES)
}

/// The length of the index buffer of the packed layout for `vertex_count` vertices and
/// `element_count` tetrahedra
/// ([`scratch_len::vbd_layout_corners`](crate::step::scratch_len::vbd_layout_corners) documents
/// it).
#[inline]
#[must_use]
pub(crate) const fn corners_len(vertex_count: usize, element_count: usize) -> usize {
    vertex_count
        .saturating_add(1)
        .saturating_add(layout_rows(element_count).saturating_mul(BLOCK * 4))
}

/// A run of the sweep: vertices of one colour, and the layout block of its first vertex.
#[derive(Clone, Copy)]
pub(crate) struct Run<'r> {
    pub vertices: &'r [u32],
    /// The block index of `vertices[0]` (blocks of [`BLOCK`] vertices from each colour's first).
    pub block: usize,
}

/// The colour runs of `order`: each colour's vertices in order, with their first block.
pub(crate) fn colour_runs<'r>(
    colours: &'r [u32],
    order: &'r [u32],
) -> impl Iterator<Item = Run<'r>> + 'r {
    let colour = |v: u32| colours.get(v as usize).copied();
    let mut rest = order;
    let mut block = 0;
    core::iter::from_fn(move || {
        let first = colour(*rest.first()?);
        let len = rest
            .iter()
            .position(|&v| colour(v) != first)
            .unwrap_or(rest.len());
        let (vertices, tail) = rest.split_at(len);
        rest = tail;
        let run = Run { vertices, block };
        block += vertices.len().div_ceil(BLOCK);
        Some(run)
    })
}

/// A built layout, read by the sweep.
#[derive(Clone, Copy)]
pub(crate) struct Layout<'s> {
    /// The first visit row of every block, and the end.
    pub starts: &'s [u32],
    /// `(row * 4 + corner) * BLOCK + lane`: the vertex at `corner` of the lane's element.
    pub corners: &'s [u32],
    /// `(row * LAYOUT_VALUES + value) * BLOCK + lane`.
    pub values: &'s [Real],
}

impl Layout<'_> {
    /// The visit rows of block `block`: first and end.
    #[inline(always)]
    pub fn rows(&self, block: usize) -> (usize, usize) {
        let first = self.starts.get(block).copied().unwrap_or(0) as usize;
        let end = self.starts.get(block + 1).copied().unwrap_or(0) as usize;
        (first, end.max(first))
    }
}

/// What the layout is built from: the mesh and its adjacency.
pub(crate) struct LayoutSource<'s> {
    pub tets: &'s [[u32; 4]],
    pub rest: &'s [TetRest],
    pub offsets: &'s [u32],
    pub incident: &'s [u32],
    pub colours: &'s [u32],
    pub order: &'s [u32],
}

/// Builds the layout of `source` into `corners` and `values`; `None` if it does not fit (the
/// buffers' contents are then meaningless).
pub(crate) fn build_layout(
    source: &LayoutSource<'_>,
    corners: &mut [u32],
    values: &mut [Real],
) -> Option<()> {
    let vertex_count = source.colours.len();
    let (starts, corner_rows) = corners.split_at_mut_checked(vertex_count.checked_add(1)?)?;
    let row_of = |vertex: u32| {
        let start = source.offsets.get(vertex as usize).copied().unwrap_or(0) as usize;
        let end = source
            .offsets
            .get(vertex as usize + 1)
            .copied()
            .unwrap_or(0) as usize;
        source.incident.get(start..end).unwrap_or(&[])
    };
    let mut first_row = 0usize;
    let mut block = 0usize;
    for run in colour_runs(source.colours, source.order) {
        for members in run.vertices.chunks(BLOCK) {
            *starts.get_mut(block)? = u32::try_from(first_row).ok()?;
            let rows = members.iter().map(|&v| row_of(v).len()).max().unwrap_or(0);
            for t in 0..rows {
                let row = first_row + t;
                let corner_row = corner_rows.get_mut(row * 4 * BLOCK..(row + 1) * 4 * BLOCK)?;
                let value_row = values
                    .get_mut(row * LAYOUT_VALUES * BLOCK..(row + 1) * LAYOUT_VALUES * BLOCK)?;
                corner_row.fill(0);
                value_row.fill(0.0);
                for (lane, &vertex) in members.iter().enumerate() {
                    let Some(&packed) = row_of(vertex).get(t) else {
                        continue;
                    };
                    let (element, corner) = ((packed >> 2) as usize, (packed & 3) as usize);
                    let (Some(tet), Some(rest)) =
                        (source.tets.get(element), source.rest.get(element))
                    else {
                        continue;
                    };
                    for (c, &index) in tet.iter().enumerate() {
                        *corner_row.get_mut(c * BLOCK + lane)? = index;
                    }
                    let g = shape_gradient(rest, corner);
                    let dm_inv = rest.dm_inv.to_cols_array();
                    let tail = [rest.volume, g.x, g.y, g.z];
                    for (k, &value) in dm_inv.iter().chain(&tail).enumerate() {
                        *value_row.get_mut(k * BLOCK + lane)? = value;
                    }
                }
            }
            first_row = first_row.checked_add(rows)?;
            block += 1;
        }
    }
    *starts.get_mut(block)? = u32::try_from(first_row).ok()?;
    Some(())
}

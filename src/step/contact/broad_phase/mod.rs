//! The broad phase of body–body and self contact: which (vertex, triangle) and (edge, edge)
//! pairs of a [`ContactSurface`] are close enough to need the exact distances of Incremental
//! Potential Contact (Li et al., "Incremental Potential Contact: Intersection- and
//! Inversion-free, Large-Deformation Dynamics", SIGGRAPH 2020), written into caller buffers.
//! See `docs/math.md` section 8.7.
//!
//! # What is a candidate
//! Every primitive has an axis-aligned box: the smallest one holding its corners (for a motion
//! query, its corners at the start and at the end of the step), grown by `dhat / 2` on every
//! side, `dhat` (m) the contact gap. A pair is a candidate when its two boxes overlap as closed
//! boxes, so that every pair closer than `dhat` is one (a pair whose gap along some axis is
//! within a rounding of `dhat` may fall either way; the barrier vanishes there with its
//! derivative, so it contributes nothing either way). Pairs that share a vertex are never
//! candidates: a vertex and a triangle it is a corner of, two edges with a common end. Nothing
//! else is filtered, so pairs within one body (self contact) and between bodies are found
//! alike, with all bodies' vertices in one position array.
//!
//! - [`proximity_pairs`]: the candidates at one configuration (the barrier's active set).
//! - [`motion_pairs`]: the candidates of a motion from start to end positions, for continuous
//!   collision detection (`dhat` may then be 0).
//!
//! # How
//! A uniform grid hashed into a table the caller sizes (Teschner et al., "Optimized Spatial
//! Hashing for Collision Detection of Deformable Objects", VMV 2003), filled by a counting sort:
//! every edge and triangle is entered in each cell its box covers, then each vertex looks for
//! triangles, and each edge for later edges, in its cells' slots. A pair is reported only from the cell
//! holding the lower corner of the two boxes' intersection, which both boxes cover, so it is
//! reported once however many cells the boxes share.
//!
//! The cell edge is the mean of the primitives' largest box extents, at least `1 / 2^20` of the
//! whole scene's (so that cell coordinates fit 20 bits even for points `1e30` m apart). If the
//! boxes then cover more cells than the caller's entries buffer holds
//! ([`scratch_len::broad_phase`]: eight per primitive), the cell edge is doubled until they fit;
//! that ends by the time the cells are twice the largest box (two cells per axis at most), after
//! at most `log2(primitives) + 2` doublings since the mean is at least `1 / primitives` of the
//! largest. If no doubling can get there (extents that overflow, near `Real::MAX`), the grid
//! falls back to one cell, correct but quadratic.
//!
//! # Cost
//! Linear in the number of primitives for a surface of bounded density (a bounded number of
//! primitive boxes per cell and cells per box): one pass for the scene's box, one per grid tried
//! to count the entries (each box's cell count is a product, not a loop), two for the counting
//! sort, one over the entries for the queries, each scanning one slot's entries, plus sorting the
//! pairs found. Densely packed boxes (a crumpled cloth, a collapsed body) cost the square of the
//! primitives per cell. Nothing is allocated.
//!
//! # Determinism
//! The pairs returned are exactly the candidates defined above, a function of the positions,
//! `dhat` and the lists alone (the grid only decides how fast they are found), each sorted and
//! free of duplicates, so the same input gives the same pairs in the same order on every target
//! and in both precisions' own rounding.
//!
//! [`scratch_len::broad_phase`]: super::super::scratch_len::broad_phase

use crate::error::{ContactBuffer, ContactError};

use super::super::super::types::{Real, Vec3};
use super::super::scratch_len;
use super::boundary::ContactSurface;
use grid::{Boxes, Cell, Grid, choose_grid, fill_table, for_each_cell};

mod grid;
#[cfg(test)]
mod tests;

/// The caller-owned scratch of the broad phase: a hash table of cell slots and the entries it
/// indexes, of [`scratch_len::broad_phase`] lengths at least.
///
/// [`scratch_len::broad_phase`]: super::super::scratch_len::broad_phase
#[derive(Debug)]
pub struct BroadPhaseScratch<'a> {
    slots: &'a mut [u32],
    entries: &'a mut [u32],
}

impl<'a> BroadPhaseScratch<'a> {
    /// Wraps the slots (at least 2 when there is a primitive; more make fewer cells share a
    /// slot) and the entries (at least eight per primitive). The lengths are checked by the
    /// queries.
    #[inline]
    #[must_use]
    pub fn new(slots: &'a mut [u32], entries: &'a mut [u32]) -> Self {
        BroadPhaseScratch { slots, entries }
    }
}

/// The candidate pairs a broad-phase query found: prefixes of the caller's output buffers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CandidatePairs<'a> {
    /// `[vertex, triangle]`: positions in the surface's vertex and triangle lists, sorted.
    pub vertex_triangle: &'a [[u32; 2]],
    /// `[edge, other]`: positions in the surface's edge list with `edge < other`, sorted.
    pub edge_edge: &'a [[u32; 2]],
}

/// The candidate pairs of `surface` at `positions` (m) for the contact gap `dhat` (m): the
/// (vertex, triangle) and (edge, edge) pairs whose boxes grown by `dhat / 2` overlap and that
/// share no vertex (see the [module documentation](self)), written sorted to the front of
/// `vertex_triangle` and `edge_edge`.
///
/// `positions` holds every vertex the surface names (all bodies' vertices in one array).
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::contact::boundary::ContactSurface;
/// use softfem::step::contact::broad_phase::{BroadPhaseScratch, proximity_pairs};
/// use softfem::step::scratch_len;
///
/// // Two tetrahedra: B's apex (vertex 7) 1 mm below A's bottom face, gap 1 cm.
/// let positions = [
///     Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0),
///     Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, 1.0),
///     Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0),
///     Vec3::new(0.0, 1.0, -1.0), Vec3::new(0.25, 0.25, -0.001),
/// ];
/// // Outward faces of [0, 1, 2, 3] and [4, 5, 6, 7]; face 0 is A's bottom (z = 0).
/// let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
/// let triangles: Vec<[u32; 3]> =
///     faces.iter().chain(&faces).enumerate().map(|(i, f)| f.map(|v| v + 4 * (i as u32 / 4))).collect();
/// let mut vertices = vec![0; scratch_len::boundary_vertices(8)];
/// let mut edges = vec![[0; 2]; scratch_len::boundary_edges(8)];
/// let surface = ContactSurface::from_triangles(&triangles, 8, &mut vertices, &mut edges)?;
///
/// let len = scratch_len::broad_phase(surface.vertices.len(), surface.edges.len(), 8);
/// let (mut slots, mut entries) = (vec![0; len.slots], vec![0; len.entries]);
/// let mut scratch = BroadPhaseScratch::new(&mut slots, &mut entries);
/// let (mut vt, mut ee) = ([[0; 2]; 64], [[0; 2]; 64]);
/// let pairs = proximity_pairs(&positions, 0.01, &surface, &mut scratch, &mut vt, &mut ee)?;
///
/// assert!(pairs.vertex_triangle.contains(&[7, 0])); // the apex and A's bottom face
/// assert!(pairs.vertex_triangle.windows(2).all(|w| w[0] < w[1]));
/// // No vertex is paired with a triangle it is a corner of.
/// assert!(pairs.vertex_triangle.iter().all(|&[v, t]| !triangles[t as usize].contains(&v)));
/// # Ok::<(), softfem::ContactError>(())
/// ```
///
/// # Errors
/// [`ContactError::Gap`] if `dhat` is NaN, infinite or negative;
/// [`ContactError::TooManyPrimitives`] if a list, or the three together, hold more than
/// `u32::MAX` entries; [`ContactError::IndexOutOfRange`] for the first vertex, edge or triangle
/// (in that order) naming a vertex at or beyond `positions.len()`;
/// [`ContactError::NonFinitePosition`] for the first NaN or infinite position;
/// [`ContactError::Capacity`] naming [`ContactBuffer::Slots`] (fewer than 2) or
/// [`ContactBuffer::Entries`] (fewer than [`scratch_len::broad_phase`]'s): all before anything
/// is written. [`ContactError::Capacity`] naming [`ContactBuffer::VertexTrianglePairs`] (checked
/// first) or [`ContactBuffer::EdgeEdgePairs`] with the exact number of pairs found if an output
/// buffer is too short; the scratch and the output buffers then hold unspecified values.
///
/// [`scratch_len::broad_phase`]: super::super::scratch_len::broad_phase
pub fn proximity_pairs<'a>(
    positions: &[Vec3],
    dhat: Real,
    surface: &ContactSurface<'_>,
    scratch: &mut BroadPhaseScratch<'_>,
    vertex_triangle: &'a mut [[u32; 2]],
    edge_edge: &'a mut [[u32; 2]],
) -> Result<CandidatePairs<'a>, ContactError> {
    candidate_pairs(
        positions,
        positions,
        dhat,
        surface,
        scratch,
        vertex_triangle,
        edge_edge,
    )
}

/// The candidate pairs of `surface` moving from `start` to `end` (m, one per vertex each) for
/// the contact gap `dhat` (m, may be 0): as [`proximity_pairs`], with each primitive's box
/// holding its corners at both ends, so that every pair that can meet (come within `dhat`) while
/// each vertex moves on the straight line from its start to its end is a candidate.
///
/// # Errors
/// Those of [`proximity_pairs`]; also [`ContactError::BufferLength`] naming
/// [`ContactBuffer::EndPositions`] if `end` and `start` differ in length, and
/// [`ContactError::NonFinitePosition`] naming [`ContactBuffer::EndPositions`] for the first NaN
/// or infinite end position (the start positions are checked first).
pub fn motion_pairs<'a>(
    start: &[Vec3],
    end: &[Vec3],
    dhat: Real,
    surface: &ContactSurface<'_>,
    scratch: &mut BroadPhaseScratch<'_>,
    vertex_triangle: &'a mut [[u32; 2]],
    edge_edge: &'a mut [[u32; 2]],
) -> Result<CandidatePairs<'a>, ContactError> {
    candidate_pairs(
        start,
        end,
        dhat,
        surface,
        scratch,
        vertex_triangle,
        edge_edge,
    )
}

/// The pairs of `superset` that are candidates of the motion `start -> end` (one array as both
/// for a configuration) for the gap `dhat` (m): those whose grown boxes overlap, in `superset`'s
/// order, written to the front of the output buffers.
///
/// Where `superset` holds every candidate of this query (it was found by [`motion_pairs`] for
/// a motion with a gap of at least `dhat`, and every surface vertex of `start` and `end` lies in
/// the box of its own start and end in that motion), the result is exactly the list
/// [`motion_pairs`] (or [`proximity_pairs`]) returns for this query: the same pairs (a box of
/// corners inside those boxes lies inside the motion's box, rounding included, as both are the
/// corners' extremes minus and plus the same half gap), in the same sorted order. That is how a
/// line search finds its pairs with one grid query (`ContactModel`'s candidate reuse).
///
/// The caller checks the positions (indices and finite values: the boxes' containment does
/// both). Errors: [`ContactError::Capacity`] naming [`ContactBuffer::VertexTrianglePairs`]
/// (checked first) or [`ContactBuffer::EdgeEdgePairs`] with the exact number of pairs found,
/// as the queries give it.
pub(crate) fn filter_pairs<'a>(
    (start, end): (&[Vec3], &[Vec3]),
    dhat: Real,
    surface: &ContactSurface<'_>,
    superset: CandidatePairs<'_>,
    vertex_triangle: &'a mut [[u32; 2]],
    edge_edge: &'a mut [[u32; 2]],
) -> Result<CandidatePairs<'a>, ContactError> {
    let boxes = Boxes {
        start,
        end,
        half_gap: dhat * 0.5,
        surface,
    };
    let mut found_vt = 0;
    for &[vertex, triangle] in superset.vertex_triangle {
        if boxes
            .vertex(vertex as usize)
            .overlaps(&boxes.triangle(triangle as usize))
        {
            record(vertex_triangle, &mut found_vt, [vertex, triangle]);
        }
    }
    let mut found_ee = 0;
    for &[first, second] in superset.edge_edge {
        if boxes
            .edge(first as usize)
            .overlaps(&boxes.edge(second as usize))
        {
            record(edge_edge, &mut found_ee, [first, second]);
        }
    }
    let (vertex_triangle, edge_edge) =
        finish_pairs(found_vt, found_ee, vertex_triangle, edge_edge)?;
    Ok(CandidatePairs {
        vertex_triangle,
        edge_edge,
    })
}

/// The (vertex, triangle) and (edge, edge) pairs found, writable.
type PairLists<'a> = (&'a mut [[u32; 2]], &'a mut [[u32; 2]]);

/// The first `found_vt` and `found_ee` entries of the output buffers as the pairs found, or
/// the capacity error of the first buffer too short for them.
fn finish_pairs<'a>(
    found_vt: usize,
    found_ee: usize,
    vertex_triangle: &'a mut [[u32; 2]],
    edge_edge: &'a mut [[u32; 2]],
) -> Result<PairLists<'a>, ContactError> {
    for (found, buffer, name) in [
        (
            found_vt,
            vertex_triangle.len(),
            ContactBuffer::VertexTrianglePairs,
        ),
        (found_ee, edge_edge.len(), ContactBuffer::EdgeEdgePairs),
    ] {
        if found > buffer {
            return Err(ContactError::Capacity {
                buffer: name,
                needed: found,
                capacity: buffer,
            });
        }
    }
    Ok((
        vertex_triangle.get_mut(..found_vt).unwrap_or_default(),
        edge_edge.get_mut(..found_ee).unwrap_or_default(),
    ))
}

/// Both queries: `start == end` for the proximity query.
fn candidate_pairs<'a>(
    start: &[Vec3],
    end: &[Vec3],
    dhat: Real,
    surface: &ContactSurface<'_>,
    scratch: &mut BroadPhaseScratch<'_>,
    vertex_triangle: &'a mut [[u32; 2]],
    edge_edge: &'a mut [[u32; 2]],
) -> Result<CandidatePairs<'a>, ContactError> {
    let primitives = check_inputs(start, end, dhat, surface, scratch)?;
    if primitives == 0 {
        return Ok(CandidatePairs::default());
    }
    let boxes = Boxes {
        start,
        end,
        half_gap: dhat * 0.5,
        surface,
    };
    let slot_count = scratch.slots.len() - 1;
    let capacity = scratch.entries.len().min(u32::MAX as usize);
    let grid = choose_grid(&boxes, primitives, slot_count, capacity);
    fill_table(&boxes, primitives, &grid, scratch);

    let found_vt = vertex_triangle_pairs(&boxes, &grid, scratch, vertex_triangle);
    let found_ee = edge_edge_pairs(&boxes, &grid, scratch, edge_edge);
    let (vertex_triangle, edge_edge) =
        finish_pairs(found_vt, found_ee, vertex_triangle, edge_edge)?;
    // The pairs are unique, so any sort gives the one sorted order.
    // `crate::sort`: no panic path, as the firmware check requires.
    crate::sort::sort_by_key(vertex_triangle, |&[a, b]| {
        (u64::from(a) << 32) | u64::from(b)
    });
    crate::sort::sort_by_key(edge_edge, |&[a, b]| (u64::from(a) << 32) | u64::from(b));
    Ok(CandidatePairs {
        vertex_triangle,
        edge_edge,
    })
}

/// Every check before anything is written; the number of primitives.
fn check_inputs(
    start: &[Vec3],
    end: &[Vec3],
    dhat: Real,
    surface: &ContactSurface<'_>,
    scratch: &BroadPhaseScratch<'_>,
) -> Result<usize, ContactError> {
    if !(dhat.is_finite() && dhat >= 0.0) {
        return Err(ContactError::Gap);
    }
    if end.len() != start.len() {
        return Err(ContactError::BufferLength {
            buffer: ContactBuffer::EndPositions,
            expected: start.len(),
            actual: end.len(),
        });
    }
    let max = u32::MAX as usize;
    for (len, buffer) in [
        (surface.vertices.len(), ContactBuffer::Vertices),
        (surface.edges.len(), ContactBuffer::Edges),
        (surface.triangles.len(), ContactBuffer::Triangles),
    ] {
        if len > max {
            return Err(ContactError::TooManyPrimitives { buffer });
        }
    }
    let primitives = surface.vertices.len() + surface.edges.len() + surface.triangles.len();
    if primitives > max {
        return Err(ContactError::TooManyPrimitives {
            buffer: ContactBuffer::Entries,
        });
    }
    let vertex_count = start.len();
    let out_of_range = |buffer, element, index: u32| {
        (index as usize >= vertex_count).then_some(ContactError::IndexOutOfRange {
            buffer,
            element,
            index,
        })
    };
    let vertices = surface
        .vertices
        .iter()
        .enumerate()
        .flat_map(|(element, &v)| out_of_range(ContactBuffer::Vertices, element, v));
    let edges = surface
        .edges
        .iter()
        .enumerate()
        .flat_map(|(element, edge)| {
            edge.iter()
                .find_map(|&v| out_of_range(ContactBuffer::Edges, element, v))
        });
    let triangles = surface
        .triangles
        .iter()
        .enumerate()
        .flat_map(|(element, triangle)| {
            triangle
                .iter()
                .find_map(|&v| out_of_range(ContactBuffer::Triangles, element, v))
        });
    if let Some(error) = vertices.chain(edges).chain(triangles).next() {
        return Err(error);
    }
    for (positions, buffer) in [
        (start, ContactBuffer::Positions),
        (end, ContactBuffer::EndPositions),
    ] {
        if let Some(vertex) = positions.iter().position(|x| !x.is_finite()) {
            return Err(ContactError::NonFinitePosition { buffer, vertex });
        }
    }
    if primitives == 0 {
        return Ok(0);
    }
    let needed = scratch_len::broad_phase(
        surface.vertices.len(),
        surface.edges.len(),
        surface.triangles.len(),
    );
    for (len, needed, buffer) in [
        (scratch.slots.len(), 2, ContactBuffer::Slots),
        (
            scratch.entries.len(),
            needed.entries,
            ContactBuffer::Entries,
        ),
    ] {
        if len < needed {
            return Err(ContactError::Capacity {
                buffer,
                needed,
                capacity: len,
            });
        }
    }
    Ok(primitives)
}

/// The entries of a cell's slot.
#[inline]
fn slot_entries<'e>(grid: &Grid, scratch: &'e BroadPhaseScratch<'_>, cell: Cell) -> &'e [u32] {
    let slot = grid.slot(cell);
    let begin = scratch.slots.get(slot).copied().unwrap_or(0) as usize;
    let end = scratch.slots.get(slot + 1).copied().unwrap_or(0) as usize;
    scratch.entries.get(begin..end).unwrap_or_default()
}

/// Writes `pair` as the `found`-th pair if there is room, and counts it either way.
#[inline]
fn record(out: &mut [[u32; 2]], found: &mut usize, pair: [u32; 2]) {
    if let Some(slot) = out.get_mut(*found) {
        *slot = pair;
    }
    *found += 1;
}

/// The (vertex, triangle) candidates; returns how many (written while room lasts).
fn vertex_triangle_pairs(
    boxes: &Boxes<'_>,
    grid: &Grid,
    scratch: &BroadPhaseScratch<'_>,
    out: &mut [[u32; 2]],
) -> usize {
    let surface = boxes.surface;
    let first_triangle = (surface.vertices.len() + surface.edges.len()) as u32;
    let mut found = 0;
    for (vertex_index, &vertex) in surface.vertices.iter().enumerate() {
        let vertex_box = boxes.vertex(vertex_index);
        for_each_cell(grid.range(&vertex_box), false, |cell| {
            let entries = slot_entries(grid, scratch, cell);
            let triangles = entries
                .get(entries.partition_point(|&id| id < first_triangle)..)
                .unwrap_or_default();
            let mut previous = None;
            for &id in triangles {
                if previous.replace(id) == Some(id) {
                    continue;
                }
                let triangle_index = (id - first_triangle) as usize;
                let triangle_box = boxes.triangle(triangle_index);
                let corners = surface.triangles.get(triangle_index);
                if vertex_box.overlaps(&triangle_box)
                    && grid.cell_of(vertex_box.lo.max(triangle_box.lo)) == cell
                    && corners.is_some_and(|corners| !corners.contains(&vertex))
                {
                    // Fits: positions in lists of at most u32::MAX entries.
                    record(
                        out,
                        &mut found,
                        [vertex_index as u32, triangle_index as u32],
                    );
                }
            }
        });
    }
    found
}

/// The (edge, edge) candidates, smaller edge first; returns how many (written while room
/// lasts).
fn edge_edge_pairs(
    boxes: &Boxes<'_>,
    grid: &Grid,
    scratch: &BroadPhaseScratch<'_>,
    out: &mut [[u32; 2]],
) -> usize {
    let surface = boxes.surface;
    let first_edge = surface.vertices.len() as u32;
    let first_triangle = first_edge + surface.edges.len() as u32;
    let mut found = 0;
    for (edge_index, &[a, b]) in surface.edges.iter().enumerate() {
        let edge_box = boxes.edge(edge_index);
        let id = first_edge + edge_index as u32;
        for_each_cell(grid.range(&edge_box), false, |cell| {
            let entries = slot_entries(grid, scratch, cell);
            // Only later edges: each pair once, smaller first.
            let later = entries.partition_point(|&other| other <= id);
            let end = entries.partition_point(|&other| other < first_triangle);
            let mut previous = None;
            for &other in entries.get(later..end).unwrap_or_default() {
                if previous.replace(other) == Some(other) {
                    continue;
                }
                let other_index = (other - first_edge) as usize;
                let other_box = boxes.edge(other_index);
                let other_ends = surface.edges.get(other_index);
                if edge_box.overlaps(&other_box)
                    && grid.cell_of(edge_box.lo.max(other_box.lo)) == cell
                    && other_ends.is_some_and(|ends| !ends.contains(&a) && !ends.contains(&b))
                {
                    record(out, &mut found, [edge_index as u32, other_index as u32]);
                }
            }
        });
    }
    found
}

//! Vertex-to-element adjacency in compressed rows, and a greedy vertex colouring: what a
//! vertex-by-vertex solver ([`vbd_step`](super::super::step::vbd_step)) needs to visit the elements
//! around a vertex and to order its updates so that a parallel version gives the same bits.
//!
//! # Layout
//! The elements around vertex `i` are `incident[offsets[i]..offsets[i + 1]]`, each entry packing
//! an element index and the vertex's corner in it as `4 * element + corner`, in increasing
//! element order. `offsets` has [`adjacency_offsets_len`] entries, `incident`
//! [`adjacency_incident_len`].
//!
//! # Colouring
//! [`colour_vertices`] gives every vertex the smallest colour (0, 1, ...) that no vertex sharing
//! an element with it and coming earlier in index order has: the greedy colouring in index
//! order (Welsh and Powell's greedy scheme without their degree ordering), deterministic and the
//! same on every target. Two vertices of one colour never share an element, so the updates of
//! one colour read only positions of other colours and can run in any order, or in parallel,
//! with the same result. [`vertex_order`] lists the vertices colour by colour, by index within a
//! colour; the solver's Gauss–Seidel sweep orders each colour by decreasing number of incident
//! elements instead (`vertex_order_by_degree`), with the same iterates.

use crate::error::{StepBuffer, StepError};

/// The length of the `offsets` buffer of a vertex adjacency: `vertex_count + 1`.
#[inline]
#[must_use]
pub const fn adjacency_offsets_len(vertex_count: usize) -> usize {
    vertex_count.saturating_add(1)
}

/// The length of the `incident` buffer of a vertex adjacency: four entries per tetrahedron.
#[inline]
#[must_use]
pub const fn adjacency_incident_len(element_count: usize) -> usize {
    element_count.saturating_mul(4)
}

/// `Ok` if `actual == expected`, else [`StepError::LengthMismatch`] for `buffer`.
fn check(buffer: StepBuffer, expected: usize, actual: usize) -> Result<(), StepError> {
    super::super::step::state::check_length(buffer, expected, actual)
}

/// The lengths of an adjacency's buffers for `vertex_count` vertices and `element_count`
/// elements: the offsets first, then the incident elements.
fn check_adjacency(
    vertex_count: usize,
    element_count: usize,
    offsets: usize,
    incident: usize,
) -> Result<(), StepError> {
    check(
        StepBuffer::AdjacencyOffsets,
        adjacency_offsets_len(vertex_count),
        offsets,
    )?;
    check(
        StepBuffer::AdjacencyIncident,
        adjacency_incident_len(element_count),
        incident,
    )
}

/// Builds the vertex-to-element adjacency of the tetrahedra `tets` over `vertex_count`
/// vertices into `offsets` ([`adjacency_offsets_len`]`(vertex_count)` entries) and `incident`
/// ([`adjacency_incident_len`]`(tets.len())` entries) in compressed rows: the elements
/// around vertex `i` are `incident[offsets[i]..offsets[i + 1]]`, each entry packing an
/// element index and the vertex's corner in it as `4 * element + corner`, in increasing element
/// order. Both buffers are overwritten; their previous contents do not matter.
///
/// ```
/// use softfem::mesh::{adjacency_incident_len, adjacency_offsets_len, build_vertex_adjacency};
///
/// // Two tetrahedra sharing the face 1 2 3.
/// let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
/// let mut offsets = [0; adjacency_offsets_len(5)];
/// let mut incident = [0; adjacency_incident_len(2)];
/// build_vertex_adjacency(&tets, 5, &mut offsets, &mut incident)?;
/// assert_eq!(offsets, [0, 1, 3, 5, 7, 8]);
/// // Vertex 2 is corner 2 of element 0 and corner 1 of element 1.
/// assert_eq!(&incident[3..5], &[4 * 0 + 2, 4 * 1 + 1]);
/// # Ok::<(), softfem::StepError>(())
/// ```
///
/// # Errors
/// [`StepError::TooManyElements`] if `tets.len() > u32::MAX / 4`;
/// [`StepError::LengthMismatch`] naming [`StepBuffer::AdjacencyOffsets`] or
/// [`StepBuffer::AdjacencyIncident`]; [`StepError::VertexIndex`] for the first corner at or
/// beyond `vertex_count`. Nothing is written on error.
pub fn build_vertex_adjacency(
    tets: &[[u32; 4]],
    vertex_count: usize,
    offsets: &mut [u32],
    incident: &mut [u32],
) -> Result<(), StepError> {
    if tets.len() > (u32::MAX / 4) as usize {
        return Err(StepError::TooManyElements);
    }
    check_adjacency(vertex_count, tets.len(), offsets.len(), incident.len())?;
    for (element, corners) in tets.iter().enumerate() {
        if let Some(&index) = corners.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(StepError::VertexIndex { element, index });
        }
    }
    // Counting sort by vertex. The count of vertex v goes to offsets[v + 2], so that after the
    // prefix sum offsets[v + 1] is the start of v's row, the cursor the fill below advances to
    // the row's end, which is the start of row v + 1: the final layout, with offsets[0] = 0.
    offsets.fill(0);
    for &v in tets.iter().flatten() {
        if let Some(count) = offsets.get_mut(v as usize + 2) {
            *count += 1;
        }
    }
    let mut total = 0;
    for slot in offsets.iter_mut().skip(2) {
        total += *slot;
        *slot = total;
    }
    for (element, corners) in (0u32..).zip(tets) {
        for (corner, &v) in (0u32..).zip(corners) {
            let Some(cursor) = offsets.get_mut(v as usize + 1) else {
                continue;
            };
            if let Some(entry) = incident.get_mut(*cursor as usize) {
                *entry = 4 * element + corner;
            }
            *cursor += 1;
        }
    }
    Ok(())
}

/// The elements around vertex `vertex` of an adjacency: `(element, corner)` pairs in increasing
/// element order (empty for an out-of-range vertex or inconsistent buffers).
#[inline]
pub(crate) fn incident_elements<'a>(
    offsets: &[u32],
    incident: &'a [u32],
    vertex: usize,
) -> impl Iterator<Item = (usize, usize)> + 'a {
    let start = offsets.get(vertex).copied().unwrap_or(0) as usize;
    let end = offsets.get(vertex + 1).copied().unwrap_or(0) as usize;
    incident
        .get(start..end)
        .unwrap_or(&[])
        .iter()
        .map(|&packed| ((packed >> 2) as usize, (packed & 3) as usize))
}

/// Colours the vertices of the tetrahedra `tets` into `colours` (one per vertex, overwritten),
/// given their adjacency from [`build_vertex_adjacency`]; returns the number of colours (0
/// without vertices). Every vertex gets the smallest colour (0, 1, ...) that no vertex sharing
/// an element with it and coming earlier in index order has: the greedy colouring in index
/// order, deterministic and the same on every target. Vertices in no element get colour 0.
///
/// Two vertices of one colour never share an element, so the updates of one colour read only
/// positions of other colours and can run in any order, or in parallel, with the same result:
/// [`vbd_step`](super::super::step::vbd_step) visits the vertices in the order of [`vertex_order`].
///
/// ```
/// use softfem::mesh::{build_vertex_adjacency, colour_vertices};
///
/// let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
/// let (mut offsets, mut incident) = ([0; 6], [0; 8]);
/// build_vertex_adjacency(&tets, 5, &mut offsets, &mut incident)?;
/// let mut colours = [0; 5];
/// let count = colour_vertices(&tets, &offsets, &incident, &mut colours)?;
/// // 0 1 2 3 need four colours; 4 shares no element with 0 and takes its colour.
/// assert_eq!((count, colours), (4, [0, 1, 2, 3, 0]));
/// # Ok::<(), softfem::StepError>(())
/// ```
///
/// # Errors
/// [`StepError::LengthMismatch`] naming [`StepBuffer::Colours`] if `colours` does not have
/// `offsets.len() - 1` entries, or naming the adjacency buffers if they do not fit `tets`.
/// Nothing is written on error.
pub fn colour_vertices(
    tets: &[[u32; 4]],
    offsets: &[u32],
    incident: &[u32],
    colours: &mut [u32],
) -> Result<u32, StepError> {
    let vertex_count = offsets.len().saturating_sub(1);
    check_adjacency(colours.len(), tets.len(), offsets.len(), incident.len())?;
    let mut count = 0;
    for vertex in 0..vertex_count {
        // The colours of the earlier neighbours below 64 as bits; the rare vertex with all 64
        // taken scans on from 64.
        let earlier = |colours: &[u32], visit: &mut dyn FnMut(u32)| {
            for (element, _) in incident_elements(offsets, incident, vertex) {
                let corners = tets.get(element).copied().unwrap_or([0; 4]);
                for &other in corners.iter().filter(|&&j| (j as usize) < vertex) {
                    if let Some(&colour) = colours.get(other as usize) {
                        visit(colour);
                    }
                }
            }
        };
        let mut taken: u64 = 0;
        earlier(colours, &mut |colour| {
            if colour < 64 {
                taken |= 1 << colour;
            }
        });
        let mut colour = (!taken).trailing_zeros();
        while colour >= 64 {
            let mut used = false;
            earlier(colours, &mut |c| used |= c == colour);
            if !used {
                break;
            }
            colour += 1;
        }
        if let Some(slot) = colours.get_mut(vertex) {
            *slot = colour;
        }
        count = count.max(colour + 1);
    }
    Ok(count)
}

/// Writes the vertices into `order` (one per vertex) colour by colour, each colour's in
/// increasing index order: the update order of the solver. `colours` and `count` are those of
/// [`colour_vertices`].
///
/// # Errors
/// [`StepError::LengthMismatch`] naming [`StepBuffer::VertexOrder`] if `order` does not have
/// one entry per vertex; nothing is written then.
pub fn vertex_order(colours: &[u32], count: u32, order: &mut [u32]) -> Result<(), StepError> {
    check(StepBuffer::VertexOrder, colours.len(), order.len())?;
    let mut slots = order.iter_mut();
    for colour in 0..count {
        for (vertex, _) in (0u32..).zip(colours).filter(|&(_, &c)| c == colour) {
            if let Some(slot) = slots.next() {
                *slot = vertex;
            }
        }
    }
    Ok(())
}

/// Writes the vertices into `order` (one per vertex) colour by colour, as [`vertex_order`],
/// but within each colour by decreasing number of incident elements (`offsets` of
/// [`build_vertex_adjacency`]), then by index: the sweep's order. Within a colour the order
/// changes no iterate (no two of its vertices share an element); grouping vertices with rows of
/// equal length lets a lane group of the sweep (`step/descent/vbd/sums.rs`) finish together, with
/// few masked lanes, and the most elements first leaves a colour's last, partly filled lane group
/// to the vertices with the fewest (the group runs as long as its longest row): on the bouncy
/// cube's 1080 tetrahedra the f64 sweep went from 632 visit rows of 8 lanes to 608, on the 96 of
/// the stiff block of the descent chart from 152 to 124. One scan of the vertices per colour and
/// distinct row length.
///
/// # Errors
/// As [`vertex_order`]; [`StepError::LengthMismatch`] naming [`StepBuffer::AdjacencyOffsets`]
/// if `offsets` does not have one entry more than `colours`.
pub(crate) fn vertex_order_by_degree(
    colours: &[u32],
    count: u32,
    offsets: &[u32],
    order: &mut [u32],
) -> Result<(), StepError> {
    check(StepBuffer::VertexOrder, colours.len(), order.len())?;
    check(
        StepBuffer::AdjacencyOffsets,
        adjacency_offsets_len(colours.len()),
        offsets.len(),
    )?;
    let degrees = offsets.windows(2).map(|w| match w {
        [start, end] => end.saturating_sub(*start),
        _ => 0,
    });
    let members = |colour: u32| {
        (0u32..)
            .zip(colours)
            .zip(degrees.clone())
            .filter(move |&((_, &c), _)| c == colour)
            .map(|((vertex, _), degree)| (vertex, degree))
    };
    let mut slots = order.iter_mut();
    for colour in 0..count {
        let mut most = u32::MAX;
        while let Some(degree) = members(colour).map(|(_, d)| d).filter(|&d| d <= most).max() {
            for (vertex, _) in members(colour).filter(|&(_, d)| d == degree) {
                if let Some(slot) = slots.next() {
                    *slot = vertex;
                }
            }
            match degree.checked_sub(1) {
                Some(next) => most = next,
                None => break,
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::vertex_order_by_degree;

    /// Colour by colour; within a colour by decreasing element count, then by index.
    #[test]
    fn order_by_degree_is_colour_then_decreasing_degree_then_index() {
        // Seven vertices in two colours; element counts (offsets' differences) 2, 5, 1, 5, 0,
        // 2, 3.
        let colours = [0, 1, 0, 0, 1, 0, 1];
        let offsets = [0, 2, 7, 8, 13, 13, 15, 18];
        let mut order = [u32::MAX; 7];
        vertex_order_by_degree(&colours, 2, &offsets, &mut order).unwrap();
        // Colour 0: vertices 0 (2), 2 (1), 3 (5), 5 (2); colour 1: 1 (5), 4 (0), 6 (3).
        assert_eq!(order, [3, 0, 5, 2, 1, 6, 4]);
    }
}

//! A body's contact surface: the primitives of Incremental Potential Contact (Li et al.,
//! "Incremental Potential Contact: Intersection- and Inversion-free, Large-Deformation
//! Dynamics", SIGGRAPH 2020) taken from its boundary triangles: the triangles themselves, their
//! unique edges and their unique vertices. A vertex meets a triangle and an edge meets an edge
//! ([`broad_phase`](super::broad_phase)); nothing else of a closed surface can touch first.
//!
//! The triangles are what `softfem::asset::surface::boundary_faces` returns (outward oriented,
//! one per boundary face), or any triangle surface: this module only reads their indices. Several
//! bodies make one surface by offsetting each body's indices by the vertices before it, so that
//! all indices name rows of one position array.
//!
//! Both lists are written sorted and free of duplicates into caller buffers of
//! [`scratch_len::boundary_edges`] and [`scratch_len::boundary_vertices`] entries (`3 F` for `F`
//! triangles, an upper bound: a closed surface has `3 F / 2` edges and `F / 2 + 2` vertices per
//! connected sphere-like component), and returned as the used prefix. Cost: one pass to write
//! `3 F` entries, an in-place unstable sort (`O(F log F)`, no allocation) and a pass to compact;
//! the output is a function of the set of triangles alone, so it is the same on every target.
//!
//! [`scratch_len::boundary_edges`]: super::super::scratch_len::boundary_edges
//! [`scratch_len::boundary_vertices`]: super::super::scratch_len::boundary_vertices

use crate::error::{ContactBuffer, ContactError};

use super::super::scratch_len;

/// The primitives of a contact surface, as global vertex indices into one position array: what
/// the [`broad_phase`](super::broad_phase) queries read.
///
/// Built by [`ContactSurface::from_triangles`], or by hand from any three lists (the broad phase
/// checks the indices against the positions it is given).
#[derive(Clone, Copy, Debug, Default)]
pub struct ContactSurface<'a> {
    /// The vertices that can touch a triangle (sorted, unique for a built surface).
    pub vertices: &'a [u32],
    /// The edges `[a, b]` that can touch an edge (`a < b`, sorted, unique for a built surface).
    pub edges: &'a [[u32; 2]],
    /// The triangles a vertex can touch.
    pub triangles: &'a [[u32; 3]],
}

impl<'a> ContactSurface<'a> {
    /// The surface of `triangles` over `vertex_count` vertices: its unique edges written into
    /// `edges` ([`scratch_len::boundary_edges`] entries at least) and its unique vertices into
    /// `vertices` ([`scratch_len::boundary_vertices`] entries at least), as [`boundary_edges`]
    /// and [`boundary_vertices`] write them.
    ///
    /// # Errors
    /// Those of [`boundary_edges`] and [`boundary_vertices`]; the edges are checked first.
    ///
    /// [`scratch_len::boundary_edges`]: super::super::scratch_len::boundary_edges
    /// [`scratch_len::boundary_vertices`]: super::super::scratch_len::boundary_vertices
    pub fn from_triangles(
        triangles: &'a [[u32; 3]],
        vertex_count: usize,
        vertices: &'a mut [u32],
        edges: &'a mut [[u32; 2]],
    ) -> Result<Self, ContactError> {
        let edges = boundary_edges(triangles, vertex_count, edges)?;
        let vertices = boundary_vertices(triangles, vertex_count, vertices)?;
        Ok(ContactSurface {
            vertices,
            edges,
            triangles,
        })
    }
}

/// The unique edges of `triangles`, each `[a, b]` with `a < b`, sorted, written to the front of
/// `edges` and returned as that prefix.
///
/// `edges` needs at least [`scratch_len::boundary_edges`]`(triangles.len())` entries (`3 F`,
/// each triangle's three edges before duplicates are removed); entries past the returned prefix
/// are left with unspecified values.
///
/// ```
/// use softfem::step::contact::boundary::boundary_edges;
/// use softfem::step::scratch_len;
///
/// // The four outward faces of the tetrahedron 0-1-2-3: six edges.
/// let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
/// let mut scratch = [[0u32; 2]; scratch_len::boundary_edges(4)];
/// let edges = boundary_edges(&faces, 4, &mut scratch)?;
/// assert_eq!(edges, [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]);
/// # Ok::<(), softfem::ContactError>(())
/// ```
///
/// # Errors
/// [`ContactError::Capacity`] naming [`ContactBuffer::Edges`] if `edges` is shorter than
/// `3 F`; [`ContactError::IndexOutOfRange`] for the first triangle naming a vertex at or beyond
/// `vertex_count`; [`ContactError::DegenerateTriangle`] for the first triangle naming a vertex
/// twice. Nothing is written then.
///
/// [`scratch_len::boundary_edges`]: super::super::scratch_len::boundary_edges
pub fn boundary_edges<'a>(
    triangles: &[[u32; 3]],
    vertex_count: usize,
    edges: &'a mut [[u32; 2]],
) -> Result<&'a [[u32; 2]], ContactError> {
    let needed = scratch_len::boundary_edges(triangles.len());
    check_triangles(triangles, vertex_count)?;
    let scratch = front(edges, needed, ContactBuffer::Edges)?;
    let mut slots = scratch.iter_mut();
    for &[a, b, c] in triangles {
        for (p, q) in [(a, b), (b, c), (c, a)] {
            if let Some(slot) = slots.next() {
                *slot = [p.min(q), p.max(q)];
            }
        }
    }
    // Sorting puts the two copies of an interior edge of a closed surface next to each other
    // (`crate::sort`: no panic path).
    crate::sort::sort_by_key(scratch, |&edge| edge);
    let kept = dedup_sorted(scratch);
    Ok(scratch.get(..kept).unwrap_or_default())
}

/// The unique vertices of `triangles`, sorted, written to the front of `vertices` and returned
/// as that prefix.
///
/// `vertices` needs at least [`scratch_len::boundary_vertices`]`(triangles.len())` entries
/// (`3 F`, every corner before duplicates are removed); entries past the returned prefix are
/// left with unspecified values.
///
/// # Errors
/// [`ContactError::Capacity`] naming [`ContactBuffer::Vertices`] if `vertices` is shorter than
/// `3 F`; [`ContactError::IndexOutOfRange`] and [`ContactError::DegenerateTriangle`] as
/// [`boundary_edges`]. Nothing is written then.
///
/// [`scratch_len::boundary_vertices`]: super::super::scratch_len::boundary_vertices
pub fn boundary_vertices<'a>(
    triangles: &[[u32; 3]],
    vertex_count: usize,
    vertices: &'a mut [u32],
) -> Result<&'a [u32], ContactError> {
    let needed = scratch_len::boundary_vertices(triangles.len());
    check_triangles(triangles, vertex_count)?;
    let scratch = front(vertices, needed, ContactBuffer::Vertices)?;
    for (slot, &corner) in scratch.iter_mut().zip(triangles.iter().flatten()) {
        *slot = corner;
    }
    crate::sort::sort_by_key(scratch, |&vertex| vertex);
    let kept = dedup_sorted(scratch);
    Ok(scratch.get(..kept).unwrap_or_default())
}

/// The first triangle with an index out of range or a repeated vertex.
fn check_triangles(triangles: &[[u32; 3]], vertex_count: usize) -> Result<(), ContactError> {
    for (triangle, &[a, b, c]) in triangles.iter().enumerate() {
        if let Some(&index) = [a, b, c].iter().find(|&&v| v as usize >= vertex_count) {
            return Err(ContactError::IndexOutOfRange {
                buffer: ContactBuffer::Triangles,
                element: triangle,
                index,
            });
        }
        if a == b || b == c || c == a {
            return Err(ContactError::DegenerateTriangle { triangle });
        }
    }
    Ok(())
}

/// The first `needed` entries of `buffer`, or the capacity error naming it.
fn front<T>(
    buffer: &mut [T],
    needed: usize,
    name: ContactBuffer,
) -> Result<&mut [T], ContactError> {
    let capacity = buffer.len();
    buffer.get_mut(..needed).ok_or(ContactError::Capacity {
        buffer: name,
        needed,
        capacity,
    })
}

/// Moves the distinct values of the sorted `values` to its front, returning how many there are.
fn dedup_sorted<T: Copy + PartialEq>(values: &mut [T]) -> usize {
    let mut kept: usize = 0;
    for read in 0..values.len() {
        let Some(&value) = values.get(read) else {
            break;
        };
        let is_new = match kept.checked_sub(1).and_then(|last| values.get(last)) {
            Some(&last) => last != value,
            None => true,
        };
        if is_new {
            if let Some(slot) = values.get_mut(kept) {
                *slot = value;
            }
            kept += 1;
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::{vec, vec::Vec};

    use super::super::super::super::asset::surface::{
        BoundaryFace, boundary_faces, boundary_scratch_len,
    };
    use super::super::super::super::generate::{BoxSplit, box_counts, fill_box};
    use super::super::super::super::types::Vec3;
    use super::*;

    /// The outward faces of the positively oriented tetrahedron `[a, b, c, d]`, offset by
    /// `offset`.
    fn tet_faces(offset: u32) -> [[u32; 3]; 4] {
        [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]].map(|f| f.map(|v| v + offset))
    }

    #[test]
    fn single_tet_has_six_edges_and_four_vertices() {
        let faces = tet_faces(0);
        let mut edges = [[0; 2]; 12];
        let mut vertices = [0; 12];
        let surface = ContactSurface::from_triangles(&faces, 4, &mut vertices, &mut edges).unwrap();
        // Every pair of the four corners is an edge of a tetrahedron: C(4, 2) = 6.
        assert_eq!(
            surface.edges,
            [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
        );
        assert_eq!(surface.vertices, [0, 1, 2, 3]);
        assert_eq!(surface.triangles.len(), 4);
    }

    #[test]
    fn box_surface_is_closed_with_euler_characteristic_two() {
        let (vertex_count, tet_count) = box_counts(2, 2, 2, BoxSplit::Kuhn6).unwrap();
        let mut positions = vec![Vec3::ZERO; vertex_count];
        let mut tets = vec![[0u32; 4]; tet_count];
        fill_box(
            Vec3::ZERO,
            Vec3::ONE,
            2,
            2,
            2,
            BoxSplit::Kuhn6,
            &mut positions,
            &mut tets,
        )
        .unwrap();
        let mut scratch = vec![BoundaryFace::default(); boundary_scratch_len(tet_count)];
        let faces = boundary_faces(&tets, vertex_count, &mut scratch).unwrap();
        let triangles: Vec<[u32; 3]> = faces.iter().map(|face| face.triangle).collect();
        // Six sides of 2x2 squares, two triangles each.
        assert_eq!(triangles.len(), 6 * 4 * 2);
        let mut edges = vec![[0; 2]; scratch_len::boundary_edges(triangles.len())];
        let mut vertices = vec![0; scratch_len::boundary_vertices(triangles.len())];
        let surface =
            ContactSurface::from_triangles(&triangles, vertex_count, &mut vertices, &mut edges)
                .unwrap();
        let (v, e, f) = (
            surface.vertices.len(),
            surface.edges.len(),
            surface.triangles.len(),
        );
        // A closed triangle surface: every edge in exactly two triangles, so 2 E = 3 F.
        assert_eq!(2 * e, 3 * f);
        // A sphere: V - E + F = 2.
        assert_eq!(v as i64 - e as i64 + f as i64, 2);
        // The 3x3x3 lattice less its one interior point.
        assert_eq!(v, 27 - 1);
        assert!(!surface.vertices.contains(&13));
        assert!(surface.vertices.windows(2).all(|w| w[0] < w[1]));
        assert!(surface.edges.windows(2).all(|w| w[0] < w[1]));
        assert!(surface.edges.iter().all(|&[a, b]| a < b));
        // Every edge is in exactly two triangles (checked against the triangles directly).
        for &[a, b] in surface.edges {
            let count = triangles
                .iter()
                .filter(|t| t.contains(&a) && t.contains(&b))
                .count();
            assert_eq!(count, 2, "edge {a}-{b}");
        }
    }

    #[test]
    fn two_disjoint_tets_make_two_components() {
        let mut faces = [[0; 3]; 8];
        faces[..4].copy_from_slice(&tet_faces(0));
        faces[4..].copy_from_slice(&tet_faces(5));
        let mut edges = [[0; 2]; 24];
        let mut vertices = [0; 24];
        let surface = ContactSurface::from_triangles(&faces, 9, &mut vertices, &mut edges).unwrap();
        assert_eq!(surface.vertices, [0, 1, 2, 3, 5, 6, 7, 8]);
        assert_eq!(surface.edges.len(), 12);
        // Two spheres: V - E + F = 2 * 2.
        let (v, e, f) = (
            surface.vertices.len(),
            surface.edges.len(),
            surface.triangles.len(),
        );
        assert_eq!(v as i64 - e as i64 + f as i64, 4);
        assert!(
            surface
                .edges
                .iter()
                .all(|&[a, b]| (a < 4 && b < 4) || (a >= 5 && b >= 5))
        );
    }

    #[test]
    fn refusals_name_the_buffer_and_the_triangle() {
        let faces = tet_faces(0);
        let mut short = [[0; 2]; 11];
        assert_eq!(
            boundary_edges(&faces, 4, &mut short),
            Err(ContactError::Capacity {
                buffer: ContactBuffer::Edges,
                needed: 12,
                capacity: 11
            })
        );
        let mut vertices = [0; 3];
        assert_eq!(
            boundary_vertices(&faces, 4, &mut vertices),
            Err(ContactError::Capacity {
                buffer: ContactBuffer::Vertices,
                needed: 12,
                capacity: 3
            })
        );
        let mut edges = [[7; 2]; 12];
        assert_eq!(
            boundary_edges(&faces, 3, &mut edges),
            Err(ContactError::IndexOutOfRange {
                buffer: ContactBuffer::Triangles,
                element: 1,
                index: 3
            })
        );
        assert_eq!(
            boundary_edges(&[[0, 1, 2], [1, 1, 2]], 3, &mut edges),
            Err(ContactError::DegenerateTriangle { triangle: 1 })
        );
        assert!(edges.iter().all(|&e| e == [7, 7]), "nothing written");
        // A longer buffer than needed is accepted; the surplus is untouched.
        let mut long = [[9; 2]; 20];
        assert_eq!(boundary_edges(&faces, 4, &mut long).unwrap().len(), 6);
        assert_eq!(long[12..], [[9; 2]; 8]);
        assert_eq!(boundary_edges(&[], 0, &mut []).unwrap(), &[] as &[[u32; 2]]);
    }
}

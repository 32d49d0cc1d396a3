//! Render buffers of a body's surface: the boundary triangles of a tetrahedral mesh, oriented
//! outward, and area-weighted vertex normals, in flat caller buffers a renderer can upload.
//!
//! With the `bytemuck` feature, [`BoundaryFace`] and [`RenderVertex`] are `bytemuck::Pod`, so a
//! slice of them casts to bytes (`bytemuck::cast_slice`) for a GPU upload without copying.

use super::super::math::sqrt;
use super::super::types::{Real, Vec3};
use crate::error::SurfaceError;

/// The faces of a positively oriented tetrahedron `[a, b, c, d]` (`det(b - a, c - a, d - a) > 0`),
/// each counter-clockwise seen from outside, so that `(x1 - x0) x (x2 - x0)` points out of the
/// tetrahedron. Face `k` is the one opposite corner `3 - k`.
const OUTWARD_FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

/// A boundary triangle of a tetrahedral mesh and the tetrahedron it belongs to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "bytemuck", derive(bytemuck::Pod, bytemuck::Zeroable))]
#[repr(C)]
pub struct BoundaryFace {
    /// Vertex indices, counter-clockwise seen from outside the body.
    pub triangle: [u32; 3],
    /// The tetrahedron whose face it is.
    pub tet: u32,
}

/// A vertex as a renderer reads it: position (m) and unit normal, interleaved.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "bytemuck", derive(bytemuck::Pod, bytemuck::Zeroable))]
#[repr(C)]
pub struct RenderVertex {
    /// The position (m).
    pub position: Vec3,
    /// The unit normal (zero where no triangle uses the vertex or all its triangles are
    /// degenerate).
    pub normal: Vec3,
}

/// The length of the scratch buffer [`boundary_faces`] needs: four faces per tetrahedron.
#[inline]
#[must_use]
pub const fn boundary_scratch_len(tet_count: usize) -> usize {
    tet_count.saturating_mul(4)
}

/// The faces of `tets` that no other tetrahedron shares, oriented outward, written to the front
/// of `scratch` ([`boundary_scratch_len`] entries) and returned as that prefix, ordered by
/// tetrahedron and then by vertex indices (deterministic).
///
/// Every tetrahedron must be positively oriented (as `TetMesh::new` requires) for the faces to
/// point outward, and the mesh conforming, so that an interior face is listed by exactly two
/// tetrahedra. A face listed three or more times (a non-manifold mesh) is not boundary and is
/// dropped. No allocation: the faces are sorted in `scratch`.
///
/// ```
/// use softfem::asset::surface::{BoundaryFace, boundary_faces, boundary_scratch_len};
///
/// // Two tetrahedra sharing the face 1-2-3: six boundary faces, the shared one is gone.
/// let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
/// let mut scratch = [BoundaryFace::default(); boundary_scratch_len(2)];
/// let faces = boundary_faces(&tets, 5, &mut scratch)?;
/// assert_eq!(faces.len(), 6);
/// assert!(faces.iter().all(|f| !(f.triangle.contains(&1) && f.triangle.contains(&2) && f.triangle.contains(&3))));
/// # Ok::<(), softfem::SurfaceError>(())
/// ```
///
/// # Errors
/// [`SurfaceError::BufferLength`] if `scratch` has the wrong length,
/// [`SurfaceError::IndexOutOfRange`] for the first tetrahedron using a vertex index at or above
/// `vertex_count`.
pub fn boundary_faces<'a>(
    tets: &[[u32; 4]],
    vertex_count: usize,
    scratch: &'a mut [BoundaryFace],
) -> Result<&'a [BoundaryFace], SurfaceError> {
    let expected = boundary_scratch_len(tets.len());
    if scratch.len() != expected {
        return Err(SurfaceError::BufferLength {
            expected,
            actual: scratch.len(),
        });
    }
    for (element, tet) in tets.iter().enumerate() {
        if let Some(&index) = tet.iter().find(|&&v| v as usize >= vertex_count) {
            return Err(SurfaceError::IndexOutOfRange { element, index });
        }
    }
    let mut slots = scratch.iter_mut();
    for (owner, tet) in tets.iter().enumerate() {
        for face in OUTWARD_FACES {
            if let Some(slot) = slots.next() {
                *slot = BoundaryFace {
                    triangle: face.map(|corner| tet.get(corner).copied().unwrap_or_default()),
                    // Fits: a mesh with u32 vertex indices has far fewer than 2^32 elements in
                    // practice, and the value only orders the output.
                    tet: owner as u32,
                };
            }
        }
    }
    crate::sort::sort_by_key(scratch, |face| (sorted(face.triangle), face.tet));
    // Keep the faces whose sorted vertices appear once, compacting them to the front.
    let mut kept = 0;
    let mut start = 0;
    while start < scratch.len() {
        let key = scratch.get(start).map(|face| sorted(face.triangle));
        let mut end = start + 1;
        while end < scratch.len() && scratch.get(end).map(|face| sorted(face.triangle)) == key {
            end += 1;
        }
        if end == start + 1
            && let Some(&face) = scratch.get(start)
        {
            if let Some(slot) = scratch.get_mut(kept) {
                *slot = face;
            }
            kept += 1;
        }
        start = end;
    }
    let boundary = scratch.get_mut(..kept).unwrap_or_default();
    crate::sort::sort_by_key(boundary, |face| (face.tet, face.triangle));
    Ok(boundary)
}

/// Writes area-weighted unit vertex normals of the triangle surface `triangles` over
/// `positions` (m) into `normals` (one per position): each vertex gets the normalised sum of
/// `(x1 - x0) x (x2 - x0)` (twice the area times the unit normal) of the triangles using it.
/// Vertices no triangle uses, or whose triangles are all degenerate, get the zero vector.
///
/// # Errors
/// [`SurfaceError::BufferLength`] if `normals` does not have `positions.len()` entries,
/// [`SurfaceError::IndexOutOfRange`] for the first triangle with an index out of range. On error
/// nothing is written.
pub fn vertex_normals(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    normals: &mut [Vec3],
) -> Result<(), SurfaceError> {
    if normals.len() != positions.len() {
        return Err(SurfaceError::BufferLength {
            expected: positions.len(),
            actual: normals.len(),
        });
    }
    for (element, triangle) in triangles.iter().enumerate() {
        if let Some(&index) = triangle.iter().find(|&&v| v as usize >= positions.len()) {
            return Err(SurfaceError::IndexOutOfRange { element, index });
        }
    }
    normals.fill(Vec3::ZERO);
    for &[a, b, c] in triangles {
        let corner = |v: u32| positions.get(v as usize).copied().unwrap_or_default();
        let (xa, xb, xc) = (corner(a), corner(b), corner(c));
        let weighted = (xb - xa).cross(xc - xa);
        for v in [a, b, c] {
            if let Some(normal) = normals.get_mut(v as usize) {
                *normal += weighted;
            }
        }
    }
    for normal in normals.iter_mut() {
        let length = sqrt(normal.dot(*normal));
        *normal = if length > 0.0 && length.is_finite() {
            *normal * (1.0 / length)
        } else {
            Vec3::ZERO
        };
    }
    Ok(())
}

/// Interleaves `positions` (m) and `normals` into `out` (all three the same length) for a
/// vertex buffer.
///
/// # Errors
/// [`SurfaceError::BufferLength`] if the lengths differ; nothing is written then.
pub fn interleave(
    positions: &[Vec3],
    normals: &[Vec3],
    out: &mut [RenderVertex],
) -> Result<(), SurfaceError> {
    for actual in [normals.len(), out.len()] {
        if actual != positions.len() {
            return Err(SurfaceError::BufferLength {
                expected: positions.len(),
                actual,
            });
        }
    }
    for ((slot, &position), &normal) in out.iter_mut().zip(positions).zip(normals) {
        *slot = RenderVertex { position, normal };
    }
    Ok(())
}

/// The total area (m^2) of a triangle surface, for checks: half the summed cross-product
/// lengths. Triangles with an index out of range count as zero.
#[must_use]
pub fn surface_area(positions: &[Vec3], triangles: &[[u32; 3]]) -> Real {
    triangles
        .iter()
        .map(|t| t.map(|v| positions.get(v as usize).copied()))
        .map(|corners| match corners {
            [Some(a), Some(b), Some(c)] => {
                let cross = (b - a).cross(c - a);
                sqrt(cross.dot(cross)) * 0.5
            }
            _ => 0.0,
        })
        .sum()
}

#[inline]
fn sorted([a, b, c]: [u32; 3]) -> [u32; 3] {
    // A three-element sorting network (no panic path, unlike `sort_unstable`).
    let (a, b) = (a.min(b), a.max(b));
    let (b, c) = (b.min(c), b.max(c));
    let (a, b) = (a.min(b), a.max(b));
    [a, b, c]
}

//! Structured meshes written into caller buffers: a box of tetrahedra and a rectangle of triangles.
//!
//! Each generator comes as a pair: a `*_counts` function that says how long the buffers must be,
//! and a `fill_*` function that checks its arguments and then writes positions (metres) and
//! element indices into the caller's slices. Nothing is allocated; on any error nothing is written.
//!
//! Conventions shared by every generator:
//! * Vertices are numbered with x fastest, then y, then z: vertex `(i, j, k)` of a box of
//!   `nx * ny * nz` cells has index `i + (nx + 1) * (j + (ny + 1) * k)`, and vertex `(i, j)` of a
//!   rectangle has index `i + (nx + 1) * j`. Grid coordinates are spaced uniformly, and the first
//!   and last are exactly `min` and `max`.
//! * Elements are grouped by cell, cells in the same x-fastest order: the elements of cell
//!   `(i, j, k)` occupy `tets_per_cell` consecutive entries starting at
//!   `(i + nx * (j + ny * k)) * tets_per_cell`.
//! * Orientation is positive: every tetrahedron `[a, b, c, d]` has
//!   `det([xb - xa, xc - xa, xd - xa]) / 6 > 0`, and every triangle `[a, b, c]` is
//!   counter-clockwise (`(xb - xa).perp_dot(xc - xa) > 0` in 2D, or positive about the normal
//!   `edge_u x edge_v` in 3D). This is checked in floating point for every element before
//!   anything is written, so it holds for the numbers actually returned.
//! * The meshes are conforming: two elements that touch share a whole face (edge), so every
//!   interior face is used by exactly two elements and the boundary faces tile the surface.

use super::types::{Mat3, Real, Vec2, Vec3};
use crate::error::{GenerateBuffer, GenerateError};

/// How [`fill_box`] splits each cube of the grid into tetrahedra.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BoxSplit {
    /// Six tetrahedra per cube, all sharing the cube's main diagonal from corner `(0, 0, 0)` to
    /// corner `(1, 1, 1)` (Kuhn's triangulation). Every cube is split the same way and the faces
    /// still conform, because each square face is cut along the diagonal through its lowest
    /// corner. Elements of one cube have equal volume but are anisotropic (they all lean along
    /// the main diagonal).
    ///
    /// **The mesh is not mirror-symmetric**: reflecting it in a coordinate plane gives the split
    /// around another diagonal. Its response is exact for uniform strains but not for the
    /// non-uniform ones of an impact, and it is most lopsided for nearly incompressible
    /// materials (linear tetrahedra lock, and this mesh locks unevenly). Measured with the
    /// bouncy example (a 0.2 m cube of 6^3 cells dropped flat from 0.5 m, stable neo-Hookean,
    /// E = 50 kPa, ground friction 0.6, explicit steps): the impact leaves the body spinning
    /// about a horizontal axis even without friction, and with friction the cube walks along
    /// `(-1, -1)`: by 0.08 m per axis in the first second at Poisson ratio 0.45 (asserted by the
    /// example's test). [`Alternating5`](BoxSplit::Alternating5) does not drift (1e-5 m,
    /// rounding). Use
    /// `Kuhn6` where the directional bias does not matter (uniform loads, convergence studies).
    Kuhn6,
    /// Five tetrahedra per cube: a central regular-shaped tetrahedron with a third of the
    /// cube's volume and four corner tetrahedra of a sixth each. The central tetrahedron uses
    /// the corners with an even number of unit offsets in cubes where `i + j + k` is even and
    /// the other four corners where it is odd, so the diagonals of shared faces agree. A box of
    /// `n^3` cells is symmetric under a half turn about each axis through its centre and under
    /// swapping two axes, and for even `n` also under the mirrors `x -> -x` (and `y`, `z`): a
    /// flat drop keeps its centre of mass on the vertical axis.
    Alternating5,
}

impl BoxSplit {
    /// The number of tetrahedra each cube is split into (6 or 5).
    #[inline]
    #[must_use]
    pub const fn tets_per_cell(self) -> usize {
        match self {
            BoxSplit::Kuhn6 => 6,
            BoxSplit::Alternating5 => 5,
        }
    }
}

/// Corners of a unit cube are numbered `x + 2 y + 4 z` for `x, y, z` in `{0, 1}`.
///
/// Kuhn's six tetrahedra: one monotone path from corner 0 to corner 7 per ordering of the axes,
/// with the two middle vertices swapped for odd orderings so that every volume is `+1/6`.
const KUHN6: [[u8; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 5, 1, 7],
    [0, 3, 2, 7],
    [0, 6, 4, 7],
];

/// Five tetrahedra around the central tetrahedron `{0, 3, 5, 6}` (for even `i + j + k`).
const ALTERNATING5_EVEN: [[u8; 4]; 5] = [
    [0, 3, 6, 5],
    [1, 0, 5, 3],
    [2, 0, 3, 6],
    [4, 0, 6, 5],
    [7, 3, 5, 6],
];

/// Five tetrahedra around the central tetrahedron `{1, 2, 4, 7}` (for odd `i + j + k`).
const ALTERNATING5_ODD: [[u8; 4]; 5] = [
    [1, 2, 4, 7],
    [0, 1, 2, 4],
    [3, 1, 7, 2],
    [5, 1, 4, 7],
    [6, 2, 7, 4],
];

/// Corners of a unit square are numbered `x + 2 y`. Two counter-clockwise triangles per square,
/// cut along the diagonal 0-3 when `i + j` is even and 1-2 when it is odd.
const SQUARE_EVEN: [[u8; 3]; 2] = [[0, 1, 3], [0, 3, 2]];
/// See [`SQUARE_EVEN`].
const SQUARE_ODD: [[u8; 3]; 2] = [[0, 1, 2], [1, 3, 2]];

/// The vertex and tetrahedron counts of a box of `nx * ny * nz` cubes split by `split`:
/// `((nx + 1) (ny + 1) (nz + 1), nx ny nz * split.tets_per_cell())`.
///
/// # Errors
/// [`GenerateError::ZeroCells`] if a count is zero, [`GenerateError::TooManyVertices`] if there
/// would be more than `u32::MAX` vertices, [`GenerateError::TooManyElements`] if the tetrahedron
/// count overflows `usize`.
pub fn box_counts(
    nx: usize,
    ny: usize,
    nz: usize,
    split: BoxSplit,
) -> Result<(usize, usize), GenerateError> {
    let vertices = vertex_count(&[nx, ny, nz])?;
    let tets = nx
        .checked_mul(ny)
        .and_then(|n| n.checked_mul(nz))
        .and_then(|n| n.checked_mul(split.tets_per_cell()))
        .ok_or(GenerateError::TooManyElements)?;
    Ok((vertices, tets))
}

/// Fills `positions` and `tets` with the box `[min, max]` (metres) divided into
/// `nx * ny * nz` equal cubes (boxes), each split into tetrahedra by `split`.
///
/// The buffers must have exactly the lengths [`box_counts`] reports. Vertex `(i, j, k)` is at
/// `min + (max - min) * (i / nx, j / ny, k / nz)` and has index `i + (nx + 1) * (j + (ny + 1) * k)`;
/// the tetrahedra of cube `(i, j, k)` start at index `(i + nx * (j + ny * k)) * split.tets_per_cell()`.
/// Every tetrahedron has positive rest volume, `Mat3::from_cols(x1 - x0, x2 - x0, x3 - x0)
/// .determinant() / 6 > 0`, the volumes add up to the box's, and the faces conform (see the
/// [module documentation](self)).
///
/// # Errors
/// Those of [`box_counts`]; [`GenerateError::NonFiniteBox`] if a coordinate of `min` or `max` is
/// not finite; [`GenerateError::EmptyBox`] if `min >= max` on some axis;
/// [`GenerateError::BufferLength`] if a buffer has the wrong length;
/// [`GenerateError::DegenerateCells`] if, after rounding, some tetrahedron's volume would not be
/// positive and finite. On error the buffers are left unchanged.
///
/// ```
/// use softfem::generate::{BoxSplit, box_counts, fill_box};
/// use softfem::glam::Vec3;
///
/// // A 1 m x 1 m x 2 m column of 1 x 1 x 2 cubes, 6 tetrahedra each.
/// let (vertex_count, tet_count) = box_counts(1, 1, 2, BoxSplit::Kuhn6)?;
/// assert_eq!((vertex_count, tet_count), (12, 12));
///
/// let mut positions = [Vec3::ZERO; 12];
/// let mut tets = [[0u32; 4]; 12];
/// let (min, max) = (Vec3::ZERO, Vec3::new(1.0, 1.0, 2.0));
/// fill_box(min, max, 1, 1, 2, BoxSplit::Kuhn6, &mut positions, &mut tets)?;
///
/// assert_eq!(positions[11], max); // the last vertex is the far corner (x fastest)
/// let volume: f32 = tets
///     .iter()
///     .map(|t| t.map(|v| positions[v as usize]))
///     .map(|[x0, x1, x2, x3]| (x1 - x0).cross(x2 - x0).dot(x3 - x0) / 6.0)
///     .inspect(|&v| assert!(v > 0.0))
///     .sum();
/// assert!((volume - 2.0).abs() < 1e-6);
/// # Ok::<(), softfem::GenerateError>(())
/// ```
// Eight arguments: the cell counts mirror `box_counts`, so that the two calls read alike.
#[allow(clippy::too_many_arguments)]
pub fn fill_box(
    min: Vec3,
    max: Vec3,
    nx: usize,
    ny: usize,
    nz: usize,
    split: BoxSplit,
    positions: &mut [Vec3],
    tets: &mut [[u32; 4]],
) -> Result<(), GenerateError> {
    let (vertex_total, tet_total) = box_counts(nx, ny, nz, split)?;
    if !(min.is_finite() && max.is_finite()) {
        return Err(GenerateError::NonFiniteBox);
    }
    if !min.cmplt(max).all() {
        return Err(GenerateError::EmptyBox);
    }
    check_length(GenerateBuffer::Positions, vertex_total, positions.len())?;
    check_length(GenerateBuffer::Tetrahedra, tet_total, tets.len())?;

    let grid = BoxGrid {
        min,
        max,
        cells: [nx, ny, nz],
    };
    // A first pass proves every element valid, so that an error leaves the buffers untouched.
    let valid = cells_3d(grid.cells).all(|cell| {
        box_cell_tets(split, cell).iter().all(|tet| {
            let [x0, x1, x2, x3] = tet.map(|corner| grid.corner_position(cell, corner));
            let volume = Mat3::from_cols(x1 - x0, x2 - x0, x3 - x0).determinant() / 6.0;
            volume > 0.0 && volume.is_finite()
        })
    });
    if !valid {
        return Err(GenerateError::DegenerateCells);
    }

    for (slot, vertex) in positions.iter_mut().zip(vertices_3d(grid.cells)) {
        *slot = grid.position(vertex);
    }
    let per_cell = split.tets_per_cell();
    for (cell_tets, cell) in tets.chunks_exact_mut(per_cell).zip(cells_3d(grid.cells)) {
        for (slot, tet) in cell_tets.iter_mut().zip(box_cell_tets(split, cell)) {
            *slot = tet.map(|corner| grid.corner_index(cell, corner));
        }
    }
    Ok(())
}

/// The vertex and triangle counts of a rectangle of `nx * ny` cells, two triangles each:
/// `((nx + 1) (ny + 1), 2 nx ny)`.
///
/// # Errors
/// [`GenerateError::ZeroCells`] if a count is zero, [`GenerateError::TooManyVertices`] if there
/// would be more than `u32::MAX` vertices, [`GenerateError::TooManyElements`] if the triangle
/// count overflows `usize`.
pub fn rectangle_counts(nx: usize, ny: usize) -> Result<(usize, usize), GenerateError> {
    let vertices = vertex_count(&[nx, ny])?;
    let triangles = nx
        .checked_mul(ny)
        .and_then(|n| n.checked_mul(2))
        .ok_or(GenerateError::TooManyElements)?;
    Ok((vertices, triangles))
}

/// Fills `positions` and `triangles` with the rectangle `[min, max]` (metres) in the plane,
/// divided into `nx * ny` equal cells of two counter-clockwise triangles each.
///
/// The buffers must have exactly the lengths [`rectangle_counts`] reports. Vertex `(i, j)` is at
/// `min + (max - min) * (i / nx, j / ny)` and has index `i + (nx + 1) * j`. The two triangles of
/// cell `(i, j)` are at indices `2 (i + nx j)` and `2 (i + nx j) + 1`; the cell is cut along its
/// diagonal from `(i, j)` to `(i + 1, j + 1)` when `i + j` is even and along the other diagonal
/// when it is odd (a "union jack" pattern, which has no preferred shear direction). Every
/// triangle has positive area `(x1 - x0).perp_dot(x2 - x0) / 2 > 0`.
///
/// # Errors
/// Those of [`rectangle_counts`]; [`GenerateError::NonFiniteBox`] if a coordinate of `min` or
/// `max` is not finite; [`GenerateError::EmptyBox`] if `min >= max` on some axis;
/// [`GenerateError::BufferLength`] if a buffer has the wrong length;
/// [`GenerateError::DegenerateCells`] if, after rounding, some triangle's area would not be
/// positive and finite. On error the buffers are left unchanged.
pub fn fill_rectangle(
    min: Vec2,
    max: Vec2,
    nx: usize,
    ny: usize,
    positions: &mut [Vec2],
    triangles: &mut [[u32; 3]],
) -> Result<(), GenerateError> {
    let (vertex_total, triangle_total) = rectangle_counts(nx, ny)?;
    if !(min.is_finite() && max.is_finite()) {
        return Err(GenerateError::NonFiniteBox);
    }
    if !min.cmplt(max).all() {
        return Err(GenerateError::EmptyBox);
    }
    check_length(GenerateBuffer::Positions, vertex_total, positions.len())?;
    check_length(GenerateBuffer::Triangles, triangle_total, triangles.len())?;

    let grid = RectangleGrid { cells: [nx, ny] };
    let position = |[i, j]: [usize; 2]| {
        Vec2::new(
            grid_coordinate(min.x, max.x, nx, i),
            grid_coordinate(min.y, max.y, ny, j),
        )
    };
    let valid = cells_2d(grid.cells).all(|cell| {
        square_cell_triangles(cell).iter().all(|triangle| {
            let [x0, x1, x2] = triangle.map(|corner| position(RectangleGrid::corner(cell, corner)));
            let area = (x1 - x0).perp_dot(x2 - x0) / 2.0;
            area > 0.0 && area.is_finite()
        })
    });
    if !valid {
        return Err(GenerateError::DegenerateCells);
    }

    for (slot, vertex) in positions.iter_mut().zip(vertices_2d(grid.cells)) {
        *slot = position(vertex);
    }
    grid.write_triangles(triangles);
    Ok(())
}

/// Fills `positions` and `triangles` with a flat rectangular membrane in 3D (metres): the
/// parallelogram `origin + s edge_u + t edge_v` for `s, t` in `[0, 1]`, divided into `nx * ny`
/// cells of two triangles each, for cloth and membrane elements.
///
/// The mesh is [`fill_rectangle`]'s with `(s, t)` in place of `(x, y)`: vertex `(i, j)` is at
/// `origin + edge_u * (i / nx) + edge_v * (j / ny)` with index `i + (nx + 1) * j`, triangles in
/// the same order and pattern. Triangles are counter-clockwise about the normal
/// `edge_u.cross(edge_v)`: `(x1 - x0).cross(x2 - x0)` points the same way.
///
/// # Errors
/// Those of [`rectangle_counts`]; [`GenerateError::NonFiniteBox`] if `origin`, `edge_u` or
/// `edge_v` is not finite; [`GenerateError::EmptyBox`] if `edge_u` and `edge_v` are zero or
/// parallel (their cross product is zero); [`GenerateError::BufferLength`] if a buffer has the
/// wrong length; [`GenerateError::DegenerateCells`] if, after rounding, some triangle would be
/// degenerate, flipped or not finite. On error the buffers are left unchanged.
pub fn fill_rectangle_3d(
    origin: Vec3,
    edge_u: Vec3,
    edge_v: Vec3,
    nx: usize,
    ny: usize,
    positions: &mut [Vec3],
    triangles: &mut [[u32; 3]],
) -> Result<(), GenerateError> {
    let (vertex_total, triangle_total) = rectangle_counts(nx, ny)?;
    if !(origin.is_finite() && edge_u.is_finite() && edge_v.is_finite()) {
        return Err(GenerateError::NonFiniteBox);
    }
    let normal = edge_u.cross(edge_v);
    if normal == Vec3::ZERO {
        return Err(GenerateError::EmptyBox);
    }
    check_length(GenerateBuffer::Positions, vertex_total, positions.len())?;
    check_length(GenerateBuffer::Triangles, triangle_total, triangles.len())?;

    let grid = RectangleGrid { cells: [nx, ny] };
    let position = |[i, j]: [usize; 2]| {
        origin
            + edge_u * grid_coordinate(0.0, 1.0, nx, i)
            + edge_v * grid_coordinate(0.0, 1.0, ny, j)
    };
    let valid = normal.is_finite()
        && cells_2d(grid.cells).all(|cell| {
            square_cell_triangles(cell).iter().all(|triangle| {
                let [x0, x1, x2] =
                    triangle.map(|corner| position(RectangleGrid::corner(cell, corner)));
                let twice_area = (x1 - x0).cross(x2 - x0);
                // The sign against the normal is what matters; `+inf` still has the right sign,
                // but a non-finite cross product means the positions overflowed.
                twice_area.is_finite() && twice_area.dot(normal) > 0.0
            })
        });
    if !valid {
        return Err(GenerateError::DegenerateCells);
    }

    for (slot, vertex) in positions.iter_mut().zip(vertices_2d(grid.cells)) {
        *slot = position(vertex);
    }
    grid.write_triangles(triangles);
    Ok(())
}

/// `(n0 + 1) (n1 + 1) ...` if every count is positive and the product is at most `u32::MAX`.
fn vertex_count(cells: &[usize]) -> Result<usize, GenerateError> {
    if cells.contains(&0) {
        return Err(GenerateError::ZeroCells);
    }
    let count = cells.iter().try_fold(1usize, |product, &n| {
        n.checked_add(1)
            .and_then(|points| product.checked_mul(points))
    });
    match count {
        Some(count) if u32::try_from(count).is_ok() => Ok(count),
        _ => Err(GenerateError::TooManyVertices),
    }
}

fn check_length(
    buffer: GenerateBuffer,
    expected: usize,
    actual: usize,
) -> Result<(), GenerateError> {
    if expected == actual {
        Ok(())
    } else {
        Err(GenerateError::BufferLength {
            buffer,
            expected,
            actual,
        })
    }
}

/// Grid coordinate `i` of `cells` equal intervals of `[min, max]`.
///
/// Written as `min (1 - t) + max t` rather than `min + (max - min) t` so that the ends are exactly
/// `min` and `max` (`t` is exactly 0 and 1 there) and `max - min` cannot overflow.
#[inline]
fn grid_coordinate(min: Real, max: Real, cells: usize, i: usize) -> Real {
    let t = i as Real / cells as Real;
    min * (1.0 - t) + max * t
}

/// Every cell `[i, j, k]` of a box, x fastest.
fn cells_3d([nx, ny, nz]: [usize; 3]) -> impl Iterator<Item = [usize; 3]> {
    (0..nz).flat_map(move |k| (0..ny).flat_map(move |j| (0..nx).map(move |i| [i, j, k])))
}

/// Every vertex `[i, j, k]` of a box of `cells`, x fastest (the vertex numbering).
fn vertices_3d([nx, ny, nz]: [usize; 3]) -> impl Iterator<Item = [usize; 3]> {
    cells_3d([nx + 1, ny + 1, nz + 1])
}

/// Every cell `[i, j]` of a rectangle, x fastest.
fn cells_2d([nx, ny]: [usize; 2]) -> impl Iterator<Item = [usize; 2]> {
    (0..ny).flat_map(move |j| (0..nx).map(move |i| [i, j]))
}

/// Every vertex `[i, j]` of a rectangle of `cells`, x fastest (the vertex numbering).
fn vertices_2d([nx, ny]: [usize; 2]) -> impl Iterator<Item = [usize; 2]> {
    cells_2d([nx + 1, ny + 1])
}

/// The local tetrahedra of cube `cell` (corners numbered `x + 2 y + 4 z`); also the voxel
/// mesher's split, so that both produce the same conforming tetrahedra.
pub(crate) fn box_cell_tets(split: BoxSplit, [i, j, k]: [usize; 3]) -> &'static [[u8; 4]] {
    match split {
        BoxSplit::Kuhn6 => &KUHN6,
        BoxSplit::Alternating5 if (i + j + k) % 2 == 0 => &ALTERNATING5_EVEN,
        BoxSplit::Alternating5 => &ALTERNATING5_ODD,
    }
}

/// The local triangles of square `cell` (corners numbered `x + 2 y`).
fn square_cell_triangles([i, j]: [usize; 2]) -> &'static [[u8; 3]; 2] {
    if (i + j) % 2 == 0 {
        &SQUARE_EVEN
    } else {
        &SQUARE_ODD
    }
}

/// A validated box grid: positive cell counts and at most `u32::MAX` vertices.
struct BoxGrid {
    min: Vec3,
    max: Vec3,
    cells: [usize; 3],
}

impl BoxGrid {
    /// The grid vertex `[i, j, k]` of `corner` (numbered `x + 2 y + 4 z`) of `cell`.
    #[inline]
    fn corner(cell: [usize; 3], corner: u8) -> [usize; 3] {
        let [i, j, k] = cell;
        let bit = |shift: u8| usize::from((corner >> shift) & 1);
        [i + bit(0), j + bit(1), k + bit(2)]
    }

    #[inline]
    fn position(&self, [i, j, k]: [usize; 3]) -> Vec3 {
        let [nx, ny, nz] = self.cells;
        Vec3::new(
            grid_coordinate(self.min.x, self.max.x, nx, i),
            grid_coordinate(self.min.y, self.max.y, ny, j),
            grid_coordinate(self.min.z, self.max.z, nz, k),
        )
    }

    #[inline]
    fn corner_position(&self, cell: [usize; 3], corner: u8) -> Vec3 {
        self.position(Self::corner(cell, corner))
    }

    #[inline]
    fn corner_index(&self, cell: [usize; 3], corner: u8) -> u32 {
        let [nx, ny, _] = self.cells;
        let [i, j, k] = Self::corner(cell, corner);
        // In range: `box_counts` checked that the vertex count fits in u32.
        (i + (nx + 1) * (j + (ny + 1) * k)) as u32
    }
}

/// A validated rectangle grid: positive cell counts and at most `u32::MAX` vertices.
struct RectangleGrid {
    cells: [usize; 2],
}

impl RectangleGrid {
    /// The grid vertex `[i, j]` of `corner` (numbered `x + 2 y`) of `cell`.
    #[inline]
    fn corner([i, j]: [usize; 2], corner: u8) -> [usize; 2] {
        let bit = |shift: u8| usize::from((corner >> shift) & 1);
        [i + bit(0), j + bit(1)]
    }

    #[inline]
    fn index(&self, [i, j]: [usize; 2]) -> u32 {
        let [nx, _] = self.cells;
        // In range: `rectangle_counts` checked that the vertex count fits in u32.
        (i + (nx + 1) * j) as u32
    }

    /// Writes the triangles of every cell; `triangles` has the length `rectangle_counts` gives.
    fn write_triangles(&self, triangles: &mut [[u32; 3]]) {
        for (cell_triangles, cell) in triangles.chunks_exact_mut(2).zip(cells_2d(self.cells)) {
            for (slot, triangle) in cell_triangles.iter_mut().zip(square_cell_triangles(cell)) {
                *slot = triangle.map(|corner| self.index(Self::corner(cell, corner)));
            }
        }
    }
}

//! Voxel tetrahedral meshing of a closed triangle surface, into caller buffers.
//!
//! A game or robotics asset is a triangle surface; a soft body needs tetrahedra. This module
//! covers the surface's bounding box with a regular grid of cubes ([`VoxelGrid`]), keeps the
//! cubes that lie inside, and splits each kept cube into the five tetrahedra of
//! [`BoxSplit::Alternating5`] (the same tables as
//! [`fill_box`](super::super::generate::fill_box), so the faces of neighbouring cubes
//! conform). Grid corners shared by kept cubes become one vertex, numbered through the grid's
//! own indexing, so no search or hash map is needed.
//!
//! The pipeline, every step into buffers the caller sized:
//! 1. [`classify_cells`] checks that the surface is closed and consistently oriented (every
//!    edge used by exactly two triangles in opposite directions; the first offending edge is
//!    named in the error) and marks the cells whose coverage by the solid reaches the chosen
//!    fraction, optionally dropping cells that hang by an edge or a vertex.
//! 2. [`voxel_counts`] counts the vertices and tetrahedra of the kept cells.
//! 3. [`fill_voxel_mesh`] writes the positions (metres, as the surface) and the tetrahedra, all
//!    positively oriented.
//!
//! With `std`, [`voxel_mesh`] does the three steps and returns `Vec`s.
//!
//! # The inside test: the generalised winding number
//! A sample point `p` is inside when the generalised winding number of the surface around it,
//! `w(p) = (1 / 4 pi) sum_t Omega_t(p)`, exceeds `1/2`, where `Omega_t` is the signed solid
//! angle of triangle `t` seen from `p` (Jacobson, Kavan and Sorkine-Hornung, "Robust
//! inside-outside segmentation using generalized winding numbers", ACM SIGGRAPH 2013), computed
//! with the formula of Van Oosterom and Strackee ("The solid angle of a plane triangle", IEEE
//! Transactions on Biomedical Engineering, 1983):
//! `tan(Omega / 2) = a . (b x c) / (|a||b||c| + (a . b)|c| + (b . c)|a| + (c . a)|b|)` with
//! `a, b, c` the corners relative to `p`. It was chosen over ray parity because it has no
//! special cases: a ray that grazes an edge or passes through a vertex (which happens all the
//! time when grid samples line up with an asset's axis-aligned faces) needs exact predicates
//! and symbolic perturbation to count correctly, while the winding number is a sum of smooth
//! terms that is `1` inside and `0` outside up to rounding, so the threshold `1/2` leaves a
//! margin of `1/2` against accumulated rounding. Degenerate triangles are harmless: a triangle
//! with a repeated vertex index is skipped, and a zero-area triangle with three distinct
//! vertices subtends zero solid angle.
//!
//! Cost: a full evaluation is one `atan2` per triangle. Sample points are visited along lines
//! parallel to x; where no triangle's bounding box meets the segment between two consecutive
//! samples (or whose two ends lie on the same side of the plane of every triangle whose box it
//! meets), the segment does not cross the surface, and because the winding number of a closed
//! surface is constant off the surface, the second sample takes the first one's answer. Samples
//! outside the surface's bounding box are outside. The triangles that can meet a row of cells are
//! listed once per row (in the edge scratch, free after the closedness check), so only samples
//! next to the surface pay the full sum, and the rest cost one bounding-box test per triangle
//! near their row.
//!
//! # Degenerate and dangling cells
//! With [`VoxelOptions::remove_hanging`], a kept cell that shares no face with another kept cell
//! (it touches the rest only along edges or at corners, or not at all) is dropped: such a cell
//! would be joined to the body through a single edge or vertex, a hinge with no stiffness.
//! Dropping such a cell never changes another cell's face neighbours, so one pass suffices.

use super::super::generate::{BoxSplit, box_cell_tets};
use super::super::math::{atan2, exponent, pow2, sqrt};
use super::super::types::{Mat3, Real, Vec3};
use crate::error::{VoxelBuffer, VoxelError};

/// A regular grid of cubes: cell `(i, j, k)` spans `origin + cell_size * ([i, j, k], [i, j, k]
/// + 1)` (metres).
///
/// Cells are numbered x fastest, `i + nx (j + ny k)`, and grid corners likewise,
/// `i + (nx + 1) (j + (ny + 1) k)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelGrid {
    /// The corner of cell `(0, 0, 0)` with the smallest coordinates (m).
    pub origin: Vec3,
    /// The edge length of every cell (m).
    pub cell_size: Real,
    /// The number of cells along x, y and z.
    pub cells: [usize; 3],
}

impl VoxelGrid {
    /// The grid of cubes of edge `cell_size` (m) that covers the bounding box of `positions`,
    /// centred on it: `ceil(extent / cell_size)` cells per axis (at least one).
    ///
    /// # Errors
    /// [`VoxelError::EmptySurface`] without positions, [`VoxelError::NonFinitePosition`],
    /// [`VoxelError::CellSize`] unless `cell_size` is finite and positive,
    /// [`VoxelError::TooManyCells`] if the corners would not fit in `u32`.
    pub fn enclosing(positions: &[Vec3], cell_size: Real) -> Result<VoxelGrid, VoxelError> {
        let (min, max) = bounding_box(positions)?;
        if !(cell_size.is_finite() && cell_size > 0.0) {
            return Err(VoxelError::CellSize);
        }
        let extent = max - min;
        let count = |length: Real| -> usize {
            let cells = ceil_small(length / cell_size);
            if cells >= 1.0 { cells as usize } else { 1 }
        };
        let cells = [count(extent.x), count(extent.y), count(extent.z)];
        let span = Vec3::new(cells[0] as Real, cells[1] as Real, cells[2] as Real) * cell_size;
        let grid = VoxelGrid {
            origin: (min + max) * 0.5 - span * 0.5,
            cell_size,
            cells,
        };
        grid.corner_count()?;
        Ok(grid)
    }

    /// [`enclosing`](Self::enclosing) with the cell size that puts `cells_along_longest` cells
    /// along the longest side of the bounding box.
    ///
    /// # Errors
    /// Those of [`enclosing`](Self::enclosing); [`VoxelError::CellSize`] if
    /// `cells_along_longest` is zero or the bounding box is a single point.
    pub fn with_resolution(
        positions: &[Vec3],
        cells_along_longest: usize,
    ) -> Result<VoxelGrid, VoxelError> {
        let (min, max) = bounding_box(positions)?;
        if cells_along_longest == 0 {
            return Err(VoxelError::CellSize);
        }
        let longest = (max - min).max_element();
        VoxelGrid::enclosing(positions, longest / cells_along_longest as Real)
    }

    /// The number of cells, `nx ny nz` (the length of the occupancy buffer).
    #[inline]
    #[must_use]
    pub fn cell_count(&self) -> usize {
        let [nx, ny, nz] = self.cells;
        nx.saturating_mul(ny).saturating_mul(nz)
    }

    /// The number of grid corners, `(nx + 1) (ny + 1) (nz + 1)` (the length of the corner map).
    ///
    /// # Errors
    /// [`VoxelError::TooManyCells`] if it exceeds `u32::MAX` (or a count is zero).
    pub fn corner_count(&self) -> Result<usize, VoxelError> {
        let count = self.cells.iter().try_fold(1usize, |product, &n| {
            if n == 0 {
                return None;
            }
            n.checked_add(1).and_then(|n| product.checked_mul(n))
        });
        match count {
            Some(count) if u32::try_from(count).is_ok() => Ok(count),
            _ => Err(VoxelError::TooManyCells),
        }
    }

    /// The position (m) of grid corner `(i, j, k)`.
    #[inline]
    #[must_use]
    pub fn corner_position(&self, [i, j, k]: [usize; 3]) -> Vec3 {
        self.origin + Vec3::new(i as Real, j as Real, k as Real) * self.cell_size
    }

    #[inline]
    fn cell_index(&self, [i, j, k]: [usize; 3]) -> usize {
        let [nx, ny, _] = self.cells;
        i + nx * (j + ny * k)
    }

    #[inline]
    fn corner_index(&self, [i, j, k]: [usize; 3]) -> usize {
        let [nx, ny, _] = self.cells;
        i + (nx + 1) * (j + (ny + 1) * k)
    }
}

/// How much of a cell must lie inside the surface for the cell to be kept.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelOptions {
    /// Sample points per cell along each axis, `1..=8`: the cell is sampled at the centres of
    /// its `s^3` sub-cubes. `1` samples the cell centre only.
    pub samples_per_axis: u32,
    /// The fraction of samples that must be inside, in `(0, 1]` (rounded up to whole samples).
    pub min_coverage: Real,
    /// Drop kept cells that share no face with another kept cell (see the
    /// [module documentation](self)).
    pub remove_hanging: bool,
}

impl Default for VoxelOptions {
    /// The cell centre decides (`samples_per_axis = 1`, `min_coverage = 1`), and hanging cells
    /// are removed.
    fn default() -> VoxelOptions {
        VoxelOptions {
            samples_per_axis: 1,
            min_coverage: 1.0,
            remove_hanging: true,
        }
    }
}

impl VoxelOptions {
    /// The number of inside samples a cell needs: `ceil(min_coverage s^3)`, at least 1.
    fn threshold(&self) -> Result<u32, VoxelError> {
        let s = self.samples_per_axis;
        if !((1..=8).contains(&s) && self.min_coverage > 0.0 && self.min_coverage <= 1.0) {
            return Err(VoxelError::Coverage);
        }
        let total = s * s * s;
        let needed = ceil_small(self.min_coverage * total as Real) as u32;
        Ok(needed.clamp(1, total))
    }
}

/// The length of the edge scratch buffer [`classify_cells`] needs: three entries per triangle.
#[inline]
#[must_use]
pub const fn closed_check_scratch_len(triangle_count: usize) -> usize {
    triangle_count.saturating_mul(3)
}

/// Checks that `triangles` form a closed, consistently oriented surface over `vertex_count`
/// vertices: every directed edge `a -> b` of a triangle is used by no other triangle, and
/// `b -> a` by exactly one. Triangles with a repeated vertex index are skipped (they enclose
/// nothing).
///
/// `scratch` must have [`closed_check_scratch_len`] entries; it is overwritten (directed edges
/// with their triangle, sorted).
///
/// # Errors
/// [`VoxelError::BufferLength`], [`VoxelError::EmptySurface`], [`VoxelError::IndexOutOfRange`]
/// (first such triangle), and for the first offending edge in sorted order
/// [`VoxelError::RepeatedEdge`] or [`VoxelError::OpenEdge`].
pub fn check_closed(
    triangles: &[[u32; 3]],
    vertex_count: usize,
    scratch: &mut [[u32; 3]],
) -> Result<(), VoxelError> {
    check_length(
        VoxelBuffer::EdgeScratch,
        closed_check_scratch_len(triangles.len()),
        scratch.len(),
    )?;
    if triangles.is_empty() || vertex_count == 0 {
        return Err(VoxelError::EmptySurface);
    }
    let mut used = 0;
    for (triangle, &[a, b, c]) in triangles.iter().enumerate() {
        if let Some(&index) = [a, b, c].iter().find(|&&v| v as usize >= vertex_count) {
            return Err(VoxelError::IndexOutOfRange { triangle, index });
        }
        if a == b || b == c || c == a {
            continue;
        }
        // Triangle indices above u32::MAX are saturated: the slices could not hold them anyway
        // on any target with 32-bit vertex indices, and the value is only used in messages.
        let owner = u32::try_from(triangle).unwrap_or(u32::MAX);
        for edge in [[a, b, owner], [b, c, owner], [c, a, owner]] {
            if let Some(slot) = scratch.get_mut(used) {
                *slot = edge;
                used += 1;
            }
        }
    }
    let edges = scratch.get_mut(..used).unwrap_or_default();
    edges.sort_unstable();
    let edges: &[[u32; 3]] = edges;
    for pair in edges.windows(2) {
        if let [[a0, b0, _], [a1, b1, t1]] = *pair
            && a0 == a1
            && b0 == b1
        {
            return Err(VoxelError::RepeatedEdge {
                triangle: t1 as usize,
                from: a1,
                to: b1,
            });
        }
    }
    for &[from, to, triangle] in edges {
        let opposite = edges.binary_search_by(|probe| [probe[0], probe[1]].cmp(&[to, from]));
        if opposite.is_err() {
            return Err(VoxelError::OpenEdge {
                triangle: triangle as usize,
                from,
                to,
            });
        }
    }
    Ok(())
}

/// The generalised winding number of the surface around `point`: about 1 inside a closed,
/// outward-oriented surface and 0 outside (see the [module documentation](self)). On the surface
/// itself the value is not meaningful (a triangle seen edge-on from its own plane contributes
/// `+-2 pi` or 0 depending on the sign of a rounded zero).
///
/// Triangles with an index out of range, or a repeated index, contribute nothing.
#[must_use]
pub fn winding_number(positions: &[Vec3], triangles: &[[u32; 3]], point: Vec3) -> Real {
    let mut total = 0.0;
    for &[a, b, c] in triangles {
        if a == b || b == c || c == a {
            continue;
        }
        if let (Some(&xa), Some(&xb), Some(&xc)) = (
            positions.get(a as usize),
            positions.get(b as usize),
            positions.get(c as usize),
        ) {
            total += half_solid_angle(xa - point, xb - point, xc - point);
        }
    }
    // sum(Omega) / 4 pi = sum(Omega / 2) / 2 pi.
    total / (2.0 * core::f64::consts::PI as Real)
}

/// Half the signed solid angle of the triangle `a, b, c` (corners relative to the viewpoint):
/// Van Oosterom and Strackee's formula.
///
/// Both terms of the quotient are cubic in the corners, so far from unit scale they overflow
/// (f32: a surface of 1e13 m) or underflow (1e-13 m) and the angle comes out NaN or 0. The solid
/// angle does not depend on scale, so corners whose largest coordinate is outside
/// `2^-SCALE_FREE ..= 2^SCALE_FREE` are first multiplied by a power of two that brings it to
/// `[1, 2)`: exact, so the quotient (and the angle) is what it would be at unit scale, and
/// corners inside that range are used as they are (the same bits as without the rescaling).
#[inline]
fn half_solid_angle(a: Vec3, b: Vec3, c: Vec3) -> Real {
    /// The binary exponents of the largest coordinate used without rescaling: cubes of
    /// `2^+-25` and sums of a few are normal numbers in f32.
    const SCALE_FREE: i32 = 24;
    let largest = a.abs().max(b.abs()).max(c.abs()).max_element();
    let e = if largest > 0.0 && largest.is_finite() {
        exponent(largest)
    } else {
        0
    };
    let (a, b, c) = if (-SCALE_FREE..=SCALE_FREE).contains(&e) {
        (a, b, c)
    } else {
        // In two factors, each a normal power of two even where `2^-e` is not (subnormal
        // corners); the first product is normal, so both multiplications are exact.
        let (first, second) = (pow2(-e / 2), pow2(-e - (-e / 2)));
        (a * first * second, b * first * second, c * first * second)
    };
    let (la, lb, lc) = (sqrt(a.dot(a)), sqrt(b.dot(b)), sqrt(c.dot(c)));
    let numerator = a.dot(b.cross(c));
    let denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    atan2(numerator, denominator)
}

/// Marks in `occupied` (one entry per cell of `grid`, x fastest) the cells whose coverage by the
/// solid bounded by the surface reaches `options`, and returns how many there are.
///
/// The surface (`positions` in metres, `triangles` counter-clockwise seen from outside) must be
/// closed; this is checked first with [`check_closed`], using `edge_scratch`
/// ([`closed_check_scratch_len`] entries), which afterwards holds the triangles near each row of
/// cells and is overwritten.
///
/// # Errors
/// [`VoxelError::Coverage`] for bad options; those of [`check_closed`];
/// [`VoxelError::NonFinitePosition`]; [`VoxelError::BufferLength`] if `occupied` does not have
/// [`VoxelGrid::cell_count`] entries; [`VoxelError::TooManyCells`] for an invalid grid;
/// [`VoxelError::CellScale`] if a cell's volume is not a normal number in this precision;
/// [`VoxelError::NoVolume`] if the surface is inside out or flat (its signed enclosed volume is
/// not positive beyond rounding). On error `occupied` is unchanged.
pub fn classify_cells(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    grid: &VoxelGrid,
    options: &VoxelOptions,
    edge_scratch: &mut [[u32; 3]],
    occupied: &mut [bool],
) -> Result<usize, VoxelError> {
    let threshold = options.threshold()?;
    grid.corner_count()?;
    if !(grid.cell_size.is_finite() && grid.cell_size > 0.0 && grid.origin.is_finite()) {
        return Err(VoxelError::CellSize);
    }
    // A cell's tetrahedra have volumes `h^3 / 6` and `h^3 / 3`, from determinants of up to
    // `2 h^3` summed from terms of up to that size: if `8 h^3` overflows or `h^3 / 6` is not a
    // normal number, `fill_voxel_mesh` could not build them in this precision, so the
    // classification (whose winding numbers would be wasted) is not started.
    let cell_cube = grid.cell_size * grid.cell_size * grid.cell_size;
    if !((cell_cube * 8.0).is_finite() && cell_cube / 6.0 >= Real::MIN_POSITIVE) {
        return Err(VoxelError::CellScale);
    }
    check_length(VoxelBuffer::Occupancy, grid.cell_count(), occupied.len())?;
    let (surface_min, surface_max) = bounding_box(positions)?;
    check_closed(triangles, positions.len(), edge_scratch)?;
    if !encloses_volume(positions, triangles, surface_min, surface_max) {
        return Err(VoxelError::NoVolume);
    }

    let s = options.samples_per_axis as usize;
    // Bounding boxes are padded by a small fraction of the cell so that rounding in the sample
    // coordinates can never hide a triangle that touches a segment.
    let pad = grid.cell_size * 1.0e-3;
    let (box_min, box_max) = (
        surface_min - Vec3::splat(pad),
        surface_max + Vec3::splat(pad),
    );
    let sub = grid.cell_size / s as Real;
    let [nx, ny, nz] = grid.cells;
    let mut kept = 0;
    for k in 0..nz {
        for j in 0..ny {
            // The triangles whose padded bounding box meets this row of cells, listed in the
            // (now free) edge scratch: only they can cross a segment between two of its samples.
            let row_min_y = grid.origin.y + j as Real * grid.cell_size - pad;
            let row_min_z = grid.origin.z + k as Real * grid.cell_size - pad;
            let (row_max_y, row_max_z) = (
                row_min_y + grid.cell_size + 2.0 * pad,
                row_min_z + grid.cell_size + 2.0 * pad,
            );
            let mut candidates = 0;
            for (triangle, bounds) in triangle_boxes(positions, triangles, pad).enumerate() {
                let (min, max) = bounds;
                let meets = min.y <= row_max_y
                    && max.y >= row_min_y
                    && min.z <= row_max_z
                    && max.z >= row_min_z;
                if meets && let Some(slot) = edge_scratch.get_mut(candidates) {
                    // Triangle counts fit in u32: `check_closed` indexed them that way.
                    slot[0] = triangle as u32;
                    candidates += 1;
                }
            }
            let row_triangles = edge_scratch.get(..candidates).unwrap_or_default();
            // For each of the s^2 lines of samples through this row of cells: the x and the
            // answer of the last sample visited.
            let mut last: [Option<(Real, bool)>; 64] = [None; 64];
            for i in 0..nx {
                let mut inside_samples = 0u32;
                for (line_index, line) in last.iter_mut().take(s * s).enumerate() {
                    let (b, c) = (line_index % s, line_index / s);
                    let y = grid.origin.y + (j as Real * grid.cell_size) + (b as Real + 0.5) * sub;
                    let z = grid.origin.z + (k as Real * grid.cell_size) + (c as Real + 0.5) * sub;
                    for a in 0..s {
                        let x =
                            grid.origin.x + (i as Real * grid.cell_size) + (a as Real + 0.5) * sub;
                        let point = Vec3::new(x, y, z);
                        let outside_box = point.cmplt(box_min).any() || point.cmpgt(box_max).any();
                        let inside = if outside_box {
                            false
                        } else {
                            match *line {
                                Some((previous_x, previous_inside))
                                    if !segment_meets_a_triangle(
                                        positions,
                                        triangles,
                                        row_triangles,
                                        [previous_x, x],
                                        y,
                                        z,
                                        pad,
                                    ) =>
                                {
                                    previous_inside
                                }
                                _ => winding_number(positions, triangles, point) > 0.5,
                            }
                        };
                        *line = Some((x, inside));
                        inside_samples += u32::from(inside);
                    }
                }
                if let Some(slot) = occupied.get_mut(grid.cell_index([i, j, k])) {
                    *slot = inside_samples >= threshold;
                    kept += usize::from(*slot);
                }
            }
        }
    }
    if options.remove_hanging {
        kept -= remove_hanging_cells(grid, occupied);
    }
    Ok(kept)
}

/// Whether the closed surface encloses a positive volume beyond rounding: the signed volume
/// `sum_t a . (b x c) / 6` (divergence theorem; corners relative to the bounding box's centre)
/// exceeds `64 eps` times the sum of the terms' magnitudes, which is what rounding can make of
/// a flat surface. An inside-out surface gives a negative volume. The corners are scaled by a
/// power of two that brings the box's extent to `[1, 2)`, so that the cubic terms neither
/// overflow nor underflow.
fn encloses_volume(positions: &[Vec3], triangles: &[[u32; 3]], min: Vec3, max: Vec3) -> bool {
    let extent = (max - min).max_element();
    if !(extent > 0.0 && extent.is_finite()) {
        return false;
    }
    let e = exponent(extent);
    let (first, second) = (pow2(-e / 2), pow2(-e - (-e / 2)));
    let centre = (min + max) * 0.5;
    let local = |v: u32| {
        positions
            .get(v as usize)
            .map(|&x| (x - centre) * first * second)
    };
    let (mut volume, mut magnitude) = (0.0, 0.0);
    for &[a, b, c] in triangles {
        if let (Some(xa), Some(xb), Some(xc)) = (local(a), local(b), local(c)) {
            let term = xa.dot(xb.cross(xc));
            volume += term;
            magnitude += term.abs();
        }
    }
    volume > 64.0 * Real::EPSILON * magnitude
}

/// The bounding box of every triangle, padded by `pad` (an empty box for a triangle with an index
/// out of range, which `check_closed` has already ruled out).
fn triangle_boxes<'a>(
    positions: &'a [Vec3],
    triangles: &'a [[u32; 3]],
    pad: Real,
) -> impl Iterator<Item = (Vec3, Vec3)> + 'a {
    triangles.iter().map(move |&[a, b, c]| {
        match (
            positions.get(a as usize),
            positions.get(b as usize),
            positions.get(c as usize),
        ) {
            (Some(&xa), Some(&xb), Some(&xc)) => (
                xa.min(xb).min(xc) - Vec3::splat(pad),
                xa.max(xb).max(xc) + Vec3::splat(pad),
            ),
            _ => (Vec3::splat(Real::INFINITY), Vec3::splat(Real::NEG_INFINITY)),
        }
    })
}

/// Whether the segment `[x0, x1] x {y} x {z}` may meet one of the `candidates` (triangle indices
/// in the first entry): their padded bounding box meets it, and its ends are not both on the same
/// side of the triangle's plane (conservative: a zero-area triangle always counts).
fn segment_meets_a_triangle(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    candidates: &[[u32; 3]],
    [x0, x1]: [Real; 2],
    y: Real,
    z: Real,
    pad: Real,
) -> bool {
    candidates.iter().any(|&[triangle, _, _]| {
        let corners = triangles
            .get(triangle as usize)
            .map(|t| t.map(|v| positions.get(v as usize).copied()));
        match corners {
            Some([Some(xa), Some(xb), Some(xc)]) => {
                let min = xa.min(xb).min(xc) - Vec3::splat(pad);
                let max = xa.max(xb).max(xc) + Vec3::splat(pad);
                let box_meets = min.x <= x1
                    && max.x >= x0
                    && min.y <= y
                    && max.y >= y
                    && min.z <= z
                    && max.z >= z;
                // A segment whose two ends lie on the same side of the triangle's plane, farther
                // than `pad` from it, cannot cross the triangle.
                box_meets && {
                    let normal = (xb - xa).cross(xc - xa);
                    let reach = pad * sqrt(normal.dot(normal));
                    let side = |x: Real| normal.dot(Vec3::new(x, y, z) - xa);
                    let (d0, d1) = (side(x0), side(x1));
                    !((d0 > reach && d1 > reach) || (d0 < -reach && d1 < -reach))
                }
            }
            // Unreachable after `check_closed`; counting it as a hit only costs time.
            _ => true,
        }
    })
}

/// Clears kept cells without a kept face neighbour; returns how many were cleared.
fn remove_hanging_cells(grid: &VoxelGrid, occupied: &mut [bool]) -> usize {
    let [nx, ny, nz] = grid.cells;
    let mut removed = 0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let index = grid.cell_index([i, j, k]);
                if occupied.get(index) != Some(&true) {
                    continue;
                }
                let kept = |cell: Option<[usize; 3]>| {
                    cell.filter(|&[a, b, c]| a < nx && b < ny && c < nz)
                        .and_then(|cell| occupied.get(grid.cell_index(cell)).copied())
                        .unwrap_or(false)
                };
                let neighbours = [
                    i.checked_sub(1).map(|a| [a, j, k]),
                    Some([i + 1, j, k]),
                    j.checked_sub(1).map(|b| [i, b, k]),
                    Some([i, j + 1, k]),
                    k.checked_sub(1).map(|c| [i, j, c]),
                    Some([i, j, k + 1]),
                ];
                if !neighbours.into_iter().any(kept)
                    && let Some(slot) = occupied.get_mut(index)
                {
                    *slot = false;
                    removed += 1;
                }
            }
        }
    }
    removed
}

/// The vertex and tetrahedron counts of the voxel mesh of the kept cells: the distinct grid
/// corners of kept cells, and five tetrahedra per kept cell.
///
/// # Errors
/// [`VoxelError::TooManyCells`] for an invalid grid, [`VoxelError::BufferLength`] if `occupied`
/// does not have [`VoxelGrid::cell_count`] entries, [`VoxelError::NoCellsInside`] if no cell is
/// kept (so that an empty mesh is never made).
pub fn voxel_counts(grid: &VoxelGrid, occupied: &[bool]) -> Result<(usize, usize), VoxelError> {
    grid.corner_count()?;
    check_length(VoxelBuffer::Occupancy, grid.cell_count(), occupied.len())?;
    let cells = occupied.iter().filter(|&&kept| kept).count();
    if cells == 0 {
        return Err(VoxelError::NoCellsInside);
    }
    let vertices = corners(grid)
        .filter(|&corner| corner_is_used(grid, occupied, corner))
        .count();
    Ok((vertices, cells * BoxSplit::Alternating5.tets_per_cell()))
}

/// Writes the voxel mesh of the kept cells: `positions` (m) of the used grid corners in corner
/// order (x fastest), and five positively oriented tetrahedra per kept cell, cells in x-fastest
/// order, split as [`BoxSplit::Alternating5`] with the parity of the cell's grid position (so the
/// faces between kept cells conform exactly as in [`fill_box`](super::super::generate::fill_box)).
///
/// `corner_map` ([`VoxelGrid::corner_count`] entries) is scratch: afterwards it holds each
/// corner's vertex index, or `u32::MAX` for unused corners. `positions` and `tets` must have the
/// lengths [`voxel_counts`] reports.
///
/// # Errors
/// Those of [`voxel_counts`]; [`VoxelError::BufferLength`] for any buffer of the wrong length;
/// [`VoxelError::DegenerateCells`] if some tetrahedron's volume would round to a non-positive or
/// non-finite value. On error `positions` and `tets` are unchanged.
pub fn fill_voxel_mesh(
    grid: &VoxelGrid,
    occupied: &[bool],
    corner_map: &mut [u32],
    positions: &mut [Vec3],
    tets: &mut [[u32; 4]],
) -> Result<(), VoxelError> {
    let (vertex_count, tet_count) = voxel_counts(grid, occupied)?;
    check_length(
        VoxelBuffer::CornerMap,
        grid.corner_count()?,
        corner_map.len(),
    )?;
    check_length(VoxelBuffer::Positions, vertex_count, positions.len())?;
    check_length(VoxelBuffer::Tetrahedra, tet_count, tets.len())?;

    let valid = kept_cells(grid, occupied).all(|cell| {
        box_cell_tets(BoxSplit::Alternating5, cell)
            .iter()
            .all(|tet| {
                let [x0, x1, x2, x3] =
                    tet.map(|corner| grid.corner_position(cell_corner(cell, corner)));
                let volume = Mat3::from_cols(x1 - x0, x2 - x0, x3 - x0).determinant() / 6.0;
                volume > 0.0 && volume.is_finite()
            })
    });
    if !valid {
        return Err(VoxelError::DegenerateCells);
    }

    let mut next = 0u32;
    let mut slots = positions.iter_mut();
    for (map, corner) in corner_map.iter_mut().zip(corners(grid)) {
        *map = if corner_is_used(grid, occupied, corner) {
            if let Some(slot) = slots.next() {
                *slot = grid.corner_position(corner);
            }
            next += 1;
            next - 1
        } else {
            u32::MAX
        };
    }
    let corner_map: &[u32] = corner_map;
    let mut slots = tets.iter_mut();
    for cell in kept_cells(grid, occupied) {
        for tet in box_cell_tets(BoxSplit::Alternating5, cell) {
            if let Some(slot) = slots.next() {
                *slot = tet.map(|corner| {
                    let index = grid.corner_index(cell_corner(cell, corner));
                    corner_map.get(index).copied().unwrap_or(u32::MAX)
                });
            }
        }
    }
    Ok(())
}

/// A tetrahedral mesh made by [`voxel_mesh`] (feature `std`).
#[cfg(feature = "std")]
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelMesh {
    /// Vertex positions (m).
    pub positions: std::vec::Vec<Vec3>,
    /// Positively oriented tetrahedra.
    pub tets: std::vec::Vec<[u32; 4]>,
    /// The grid the cells came from.
    pub grid: VoxelGrid,
}

/// Voxel-meshes a closed surface with [`classify_cells`], [`voxel_counts`] and
/// [`fill_voxel_mesh`], allocating the buffers (feature `std`) within the memory budget
/// [`MEMORY_BUDGET`](super::MEMORY_BUDGET) (2 GiB): see [`voxel_mesh_with_budget`].
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::asset::voxel::{VoxelGrid, VoxelOptions, voxel_mesh};
///
/// // The unit cube as 12 outward triangles.
/// let positions: Vec<Vec3> = (0..8)
///     .map(|c| Vec3::new((c & 1) as f32, ((c >> 1) & 1) as f32, ((c >> 2) & 1) as f32))
///     .collect();
/// let triangles = [
///     [0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
///     [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5],
/// ];
/// let grid = VoxelGrid::with_resolution(&positions, 4)?;
/// let mesh = voxel_mesh(&positions, &triangles, &grid, &VoxelOptions::default())?;
/// assert_eq!(mesh.tets.len(), 4 * 4 * 4 * 5); // every cell centre is inside
/// assert_eq!(mesh.positions.len(), 5 * 5 * 5);
///
/// let open = &triangles[1..];
/// let error = voxel_mesh(&positions, open, &grid, &VoxelOptions::default()).unwrap_err();
/// assert_eq!(
///     error.to_string(),
///     "the surface is not closed: edge 0 -> 3 of triangle 0 has no opposite triangle"
/// );
/// # Ok::<(), softfem::VoxelError>(())
/// ```
///
/// # Errors
/// Those of [`voxel_mesh_with_budget`] with the budget [`MEMORY_BUDGET`](super::MEMORY_BUDGET).
#[cfg(feature = "std")]
pub fn voxel_mesh(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    grid: &VoxelGrid,
    options: &VoxelOptions,
) -> Result<VoxelMesh, VoxelError> {
    voxel_mesh_with_budget(positions, triangles, grid, options, super::MEMORY_BUDGET)
}

/// [`voxel_mesh`] with a memory budget of `budget` bytes (feature `std`).
///
/// The grid is checked first ([`VoxelGrid::corner_count`]), then the bytes of the buffers held
/// at once are added up and compared with `budget` before they are allocated: for the
/// classification the edge scratch (36 bytes a triangle) and the occupancy (a byte a cell), for
/// the mesh the occupancy, the corner map (4 bytes a grid corner), the positions and the
/// tetrahedra (16 bytes each). The buffers are allocated fallibly.
///
/// # Errors
/// [`VoxelError::TooManyCells`] for a grid whose corners `u32` cannot index (checked before
/// any size is computed); [`VoxelError::OverBudget`] with the bytes and the budget;
/// [`VoxelError::Allocation`] with the bytes the allocator refused; those of the three steps
/// (an inside-out or flat surface, a cell size this precision cannot mesh, no cell inside).
#[cfg(feature = "std")]
pub fn voxel_mesh_with_budget(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    grid: &VoxelGrid,
    options: &VoxelOptions,
    budget: usize,
) -> Result<VoxelMesh, VoxelError> {
    use super::{bytes_of, filled};
    let corner_count = grid.corner_count()?;
    let cell_count = grid.cell_count();
    let scratch_len = closed_check_scratch_len(triangles.len());
    within_budget(
        bytes_of::<[u32; 3]>(scratch_len).saturating_add(bytes_of::<bool>(cell_count)),
        budget,
    )?;
    let allocation = |bytes| VoxelError::Allocation { bytes };
    let mut edge_scratch = filled(scratch_len, [0u32; 3]).map_err(allocation)?;
    let mut occupied = filled(cell_count, false).map_err(allocation)?;
    classify_cells(
        positions,
        triangles,
        grid,
        options,
        &mut edge_scratch,
        &mut occupied,
    )?;
    drop(edge_scratch);
    let (vertex_count, tet_count) = voxel_counts(grid, &occupied)?;
    within_budget(
        [
            bytes_of::<bool>(cell_count),
            bytes_of::<u32>(corner_count),
            bytes_of::<Vec3>(vertex_count),
            bytes_of::<[u32; 4]>(tet_count),
        ]
        .into_iter()
        .fold(0, usize::saturating_add),
        budget,
    )?;
    let mut corner_map = filled(corner_count, 0u32).map_err(allocation)?;
    let mut mesh_positions = filled(vertex_count, Vec3::ZERO).map_err(allocation)?;
    let mut tets = filled(tet_count, [0u32; 4]).map_err(allocation)?;
    fill_voxel_mesh(
        grid,
        &occupied,
        &mut corner_map,
        &mut mesh_positions,
        &mut tets,
    )?;
    Ok(VoxelMesh {
        positions: mesh_positions,
        tets,
        grid: *grid,
    })
}

/// `Ok` if `bytes` is within `budget`.
#[cfg(feature = "std")]
fn within_budget(bytes: usize, budget: usize) -> Result<(), VoxelError> {
    if bytes <= budget {
        Ok(())
    } else {
        Err(VoxelError::OverBudget { bytes, budget })
    }
}

/// The grid corner of local `corner` (numbered `x + 2 y + 4 z`) of `cell`.
#[inline]
fn cell_corner([i, j, k]: [usize; 3], corner: u8) -> [usize; 3] {
    let bit = |shift: u8| usize::from((corner >> shift) & 1);
    [i + bit(0), j + bit(1), k + bit(2)]
}

/// Every grid corner, x fastest.
fn corners(grid: &VoxelGrid) -> impl Iterator<Item = [usize; 3]> {
    let [nx, ny, nz] = grid.cells;
    (0..=nz).flat_map(move |k| (0..=ny).flat_map(move |j| (0..=nx).map(move |i| [i, j, k])))
}

/// Every kept cell, x fastest.
fn kept_cells<'a>(
    grid: &'a VoxelGrid,
    occupied: &'a [bool],
) -> impl Iterator<Item = [usize; 3]> + 'a {
    let [nx, ny, nz] = grid.cells;
    (0..nz)
        .flat_map(move |k| (0..ny).flat_map(move |j| (0..nx).map(move |i| [i, j, k])))
        .filter(move |&cell| occupied.get(grid.cell_index(cell)) == Some(&true))
}

/// Whether some kept cell has `corner` as one of its eight corners.
fn corner_is_used(grid: &VoxelGrid, occupied: &[bool], [i, j, k]: [usize; 3]) -> bool {
    let [nx, ny, nz] = grid.cells;
    (0..8u8).any(|offset| {
        let back = |value: usize, shift: u8| value.checked_sub(usize::from((offset >> shift) & 1));
        match (back(i, 0), back(j, 1), back(k, 2)) {
            (Some(a), Some(b), Some(c)) if a < nx && b < ny && c < nz => {
                occupied.get(grid.cell_index([a, b, c])) == Some(&true)
            }
            _ => false,
        }
    })
}

/// The bounding box of `positions`, which must be non-empty and finite.
fn bounding_box(positions: &[Vec3]) -> Result<(Vec3, Vec3), VoxelError> {
    let first = *positions.first().ok_or(VoxelError::EmptySurface)?;
    let mut min = first;
    let mut max = first;
    for (vertex, &x) in positions.iter().enumerate() {
        if !x.is_finite() {
            return Err(VoxelError::NonFinitePosition { vertex });
        }
        min = min.min(x);
        max = max.max(x);
    }
    Ok((min, max))
}

/// `ceil` for the cell counts (exact for the values involved; no transcendental needed).
#[inline]
fn ceil_small(x: Real) -> Real {
    let truncated = x as i64 as Real;
    if truncated < x {
        truncated + 1.0
    } else {
        truncated
    }
}

fn check_length(buffer: VoxelBuffer, expected: usize, actual: usize) -> Result<(), VoxelError> {
    if expected == actual {
        Ok(())
    } else {
        Err(VoxelError::BufferLength {
            buffer,
            expected,
            actual,
        })
    }
}

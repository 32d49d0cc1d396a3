//! Embedding a detailed render mesh in a coarse simulation mesh, and deforming it every frame.
//!
//! Each render point is bound once to one tetrahedron of the simulation mesh, with the
//! barycentric weights of its rest position in that tetrahedron ([`Embedded`]); afterwards its
//! deformed position is the same combination of the tetrahedron's simulated corners
//! ([`Embedding::deform`]). Because the weights are affine coordinates, every affine motion of
//! the body (translation, rotation, uniform or shear strain) moves the render points exactly as
//! it moves the material around them. This is the linear-interpolation embedding used by
//! PhysX, Bullet, Vega and others.
//!
//! Points just outside the mesh (a render surface is rarely exactly inside a voxel mesh) are
//! bound to the nearest tetrahedron within a margin, with the barycentric weights of the point
//! itself: they are then extrapolated affinely (some weights negative, the sum still 1), which
//! keeps the exactness for affine motions. Farther points are an error naming the point.
//!
//! The one-time search uses a uniform grid ([`TetLookup`]) whose buckets live in caller buffers:
//! [`TetLookup::plan`] sizes them, [`TetLookup::build`] fills them, [`embed_points`] queries it.
//! Each frame, [`Embedding::deform`] is a loop of four multiply-adds per render point, with no
//! search and no allocation. Normals of the deformed render surface come from its triangles
//! (see the `surface` module's `vertex_normals`), or, without a pass over the triangles, from the
//! rest normals carried by each tetrahedron's deformation gradient
//! ([`Embedding::deform_normals`]).

use super::super::element::TetRest;
use super::super::math::{cbrt, sqrt};
use super::super::types::{Mat3, Real, Vec3};
use crate::error::{EmbedBuffer, EmbedError};

/// A render point bound to a tetrahedron: `x = sum_k weights[k] * positions[tets[tet][k]]`.
///
/// The weights sum to 1 (to rounding); all are in `[0, 1]` for a point inside its tetrahedron.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Embedded {
    /// The barycentric weights of the tetrahedron's four corners.
    pub weights: [Real; 4],
    /// The tetrahedron.
    pub tet: u32,
}

/// The size of a [`TetLookup`]: its grid and the lengths of its two buffers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookupPlan {
    /// The corner of the grid with the smallest coordinates (m).
    pub origin: Vec3,
    /// The edge length of a cell (m).
    pub cell_size: Real,
    /// Cells along x, y and z.
    pub cells: [usize; 3],
    /// The length of the bucket-start buffer: one more than the number of cells.
    pub starts_len: usize,
    /// The length of the bucket-entry buffer: the number of (cell, tetrahedron) pairs.
    pub entries_len: usize,
    /// The margin (m) the grid was planned for: every tetrahedron is listed in the cells its
    /// bounding box, grown by the margin, overlaps.
    pub margin: Real,
}

/// A uniform grid over a tetrahedral mesh listing, per cell, the tetrahedra whose bounding box
/// (grown by the margin) overlaps it; buckets in caller buffers (compressed rows: bucket `c` is
/// `entries[starts[c]..starts[c + 1]]`, tetrahedra in increasing order).
#[derive(Clone, Copy, Debug)]
pub struct TetLookup<'a> {
    plan: LookupPlan,
    starts: &'a [u32],
    entries: &'a [u32],
}

impl<'a> TetLookup<'a> {
    /// Plans the grid over `positions` (m) and `tets` with cells of `cell_size` (m; `None`
    /// picks the edge of a cube of the mean tetrahedron volume, a cell holding a few
    /// tetrahedra), for points up to `margin` (m) outside the mesh.
    ///
    /// # Errors
    /// [`EmbedError::EmptyMesh`], [`EmbedError::NonFinitePoint`] (a rest position),
    /// [`EmbedError::IndexOutOfRange`], [`EmbedError::DegenerateTet`] (zero or non-finite rest
    /// volume), [`EmbedError::Settings`] (negative or non-finite margin,
    /// non-positive cell size), [`EmbedError::TooLarge`].
    pub fn plan(
        positions: &[Vec3],
        tets: &[[u32; 4]],
        cell_size: Option<Real>,
        margin: Real,
    ) -> Result<LookupPlan, EmbedError> {
        if tets.is_empty() {
            return Err(EmbedError::EmptyMesh);
        }
        if !(margin.is_finite() && margin >= 0.0) {
            return Err(EmbedError::Settings);
        }
        if let Some(point) = positions.iter().position(|x| !x.is_finite()) {
            return Err(EmbedError::NonFinitePoint { point });
        }
        let mut min = Vec3::splat(Real::INFINITY);
        let mut max = Vec3::splat(Real::NEG_INFINITY);
        let mut total_volume = 0.0;
        for tet in 0..tets.len() {
            let corners = corners(positions, tets, tet)?;
            for x in corners {
                min = min.min(x);
                max = max.max(x);
            }
            let [x0, x1, x2, x3] = corners;
            let det = Mat3::from_cols(x1 - x0, x2 - x0, x3 - x0).determinant();
            if det == 0.0 || !det.is_finite() {
                return Err(EmbedError::DegenerateTet { tet });
            }
            total_volume += det.abs() / 6.0;
        }
        let cell_size = cell_size.unwrap_or_else(|| cbrt(total_volume / tets.len() as Real));
        if !(cell_size.is_finite() && cell_size > 0.0) {
            return Err(EmbedError::Settings);
        }
        let origin = min - Vec3::splat(margin);
        let extent = (max - min) + Vec3::splat(2.0 * margin);
        let count = |length: Real| -> Option<usize> {
            let cells = length / cell_size;
            // Also rejects NaN.
            if cells.partial_cmp(&(u32::MAX as Real)) != Some(core::cmp::Ordering::Less) {
                return None;
            }
            Some((cells as usize).saturating_add(1))
        };
        let cells = match (count(extent.x), count(extent.y), count(extent.z)) {
            (Some(x), Some(y), Some(z)) => [x, y, z],
            _ => return Err(EmbedError::TooLarge),
        };
        let cell_count = cells
            .iter()
            .try_fold(1usize, |product, &n| product.checked_mul(n))
            .filter(|&n| n < u32::MAX as usize)
            .ok_or(EmbedError::TooLarge)?;
        let mut plan = LookupPlan {
            origin,
            cell_size,
            cells,
            starts_len: cell_count + 1,
            entries_len: 0,
            margin,
        };
        let mut entries = 0usize;
        for tet in 0..tets.len() {
            let [[x0, y0, z0], [x1, y1, z1]] = plan.cell_range(corners(positions, tets, tet)?);
            let listed = (x1 - x0 + 1) * (y1 - y0 + 1) * (z1 - z0 + 1);
            entries = entries.checked_add(listed).ok_or(EmbedError::TooLarge)?;
        }
        if u32::try_from(entries).is_err() {
            return Err(EmbedError::TooLarge);
        }
        plan.entries_len = entries;
        Ok(plan)
    }

    /// Fills the buckets of `plan` (from [`plan`](Self::plan) with the same mesh) into `starts`
    /// and `entries`, which must have the planned lengths.
    ///
    /// # Errors
    /// [`EmbedError::BufferLength`]; those of [`plan`](Self::plan) if the mesh changed.
    pub fn build(
        plan: &LookupPlan,
        positions: &[Vec3],
        tets: &[[u32; 4]],
        starts: &'a mut [u32],
        entries: &'a mut [u32],
    ) -> Result<TetLookup<'a>, EmbedError> {
        check_length(EmbedBuffer::BucketStarts, plan.starts_len, starts.len())?;
        check_length(EmbedBuffer::BucketEntries, plan.entries_len, entries.len())?;
        starts.fill(0);
        let mut total = 0usize;
        for tet in 0..tets.len() {
            let range = plan.cell_range(corners(positions, tets, tet)?);
            for cell in plan.cells_in(range) {
                if let Some(count) = starts.get_mut(cell) {
                    *count += 1;
                    total += 1;
                }
            }
        }
        if total != plan.entries_len {
            return Err(EmbedError::BufferLength {
                buffer: EmbedBuffer::BucketEntries,
                expected: total,
                actual: plan.entries_len,
            });
        }
        // Prefix sums: starts[c] becomes the end of bucket c. Filling from the last tetrahedron
        // down, each entry decrements its bucket's end, so afterwards starts[c] is the bucket's
        // start and each bucket lists its tetrahedra in increasing order.
        let mut running = 0u32;
        for slot in starts.iter_mut() {
            running += *slot;
            *slot = running;
        }
        for tet in (0..tets.len()).rev() {
            let range = plan.cell_range(corners(positions, tets, tet)?);
            for cell in plan.cells_in(range) {
                if let Some(end) = starts.get_mut(cell) {
                    *end -= 1;
                    if let Some(entry) = entries.get_mut(*end as usize) {
                        // Fits: `plan` checked the counts against u32.
                        *entry = tet as u32;
                    }
                }
            }
        }
        Ok(TetLookup {
            plan: *plan,
            starts,
            entries,
        })
    }

    /// The tetrahedra listed in the cell that contains `point` (empty outside the grid).
    #[must_use]
    pub fn candidates(&self, point: Vec3) -> &'a [u32] {
        let relative = (point - self.plan.origin) / self.plan.cell_size;
        let [nx, ny, nz] = self.plan.cells;
        let inside = relative.cmpge(Vec3::ZERO).all()
            && relative.x < nx as Real
            && relative.y < ny as Real
            && relative.z < nz as Real;
        if !inside {
            return &[];
        }
        let [i, j, k] = [relative.x, relative.y, relative.z].map(|r| r as usize);
        let cell = i + nx * (j + ny * k);
        match (self.starts.get(cell), self.starts.get(cell + 1)) {
            (Some(&start), Some(&end)) => self
                .entries
                .get(start as usize..end as usize)
                .unwrap_or_default(),
            _ => &[],
        }
    }

    /// The bucket starts: bucket `c` is `entries()[starts()[c]..starts()[c + 1]]`.
    #[inline]
    #[must_use]
    pub fn starts(&self) -> &'a [u32] {
        self.starts
    }

    /// The bucket entries (tetrahedron indices).
    #[inline]
    #[must_use]
    pub fn entries(&self) -> &'a [u32] {
        self.entries
    }

    /// The plan this lookup was built from.
    #[inline]
    #[must_use]
    pub fn layout(&self) -> &LookupPlan {
        &self.plan
    }
}

impl LookupPlan {
    /// The inclusive cell ranges overlapped by the bounding box of `corners` grown by the margin.
    fn cell_range(&self, corners: [Vec3; 4]) -> [[usize; 3]; 2] {
        let [a, b, c, d] = corners;
        let min = a.min(b).min(c).min(d) - Vec3::splat(self.margin);
        let max = a.max(b).max(c).max(d) + Vec3::splat(self.margin);
        let to_cell = |x: Vec3| {
            let relative = (x - self.origin) / self.cell_size;
            let [nx, ny, nz] = self.cells;
            let clamp = |r: Real, n: usize| {
                if r > 0.0 {
                    (r as usize).min(n.saturating_sub(1))
                } else {
                    0
                }
            };
            [
                clamp(relative.x, nx),
                clamp(relative.y, ny),
                clamp(relative.z, nz),
            ]
        };
        [to_cell(min), to_cell(max)]
    }

    /// The cell indices of an inclusive range, x fastest.
    fn cells_in(&self, [low, high]: [[usize; 3]; 2]) -> impl Iterator<Item = usize> {
        let [nx, ny, _] = self.cells;
        (low[2]..=high[2]).flat_map(move |k| {
            (low[1]..=high[1])
                .flat_map(move |j| (low[0]..=high[0]).map(move |i| i + nx * (j + ny * k)))
        })
    }
}

/// Binds every render point (rest positions `points`, m) to a tetrahedron of the mesh
/// (`positions`, `tets`, the same the `lookup` was built from), writing `out` (one entry per
/// point).
///
/// A point inside the mesh gets a containing tetrahedron (the first listed with every weight
/// positive, or where it lies on a shared face or edge, the one where its smallest weight is
/// largest) and weights in `[0, 1]`; a point outside gets
/// the nearest tetrahedron, if it is within the lookup's margin, and its (extrapolating)
/// barycentric coordinates there.
///
/// # Errors
/// [`EmbedError::BufferLength`] (`out`); [`EmbedError::NonFinitePoint`] (a render point);
/// [`EmbedError::DegenerateTet`] (a candidate with zero or non-finite volume);
/// [`EmbedError::IndexOutOfRange`]; [`EmbedError::Outside`] (first point farther than the margin
/// from every tetrahedron). On error the entries before the failing point are written.
pub fn embed_points(
    lookup: &TetLookup<'_>,
    positions: &[Vec3],
    tets: &[[u32; 4]],
    points: &[Vec3],
    out: &mut [Embedded],
) -> Result<(), EmbedError> {
    check_length(EmbedBuffer::Embedding, points.len(), out.len())?;
    let margin = lookup.plan.margin;
    for (point, (&x, slot)) in points.iter().zip(out.iter_mut()).enumerate() {
        if !x.is_finite() {
            return Err(EmbedError::NonFinitePoint { point });
        }
        // The best candidate so far: (distance, smallest weight, tet, weights).
        let mut best: Option<(Real, Real, u32, [Real; 4])> = None;
        for &tet in lookup.candidates(x) {
            let corners = corners(positions, tets, tet as usize)?;
            // The distance to the tetrahedron's bounding box is a cheap lower bound of the
            // distance to the tetrahedron: skip candidates that cannot beat the best so far or
            // that lie beyond the margin.
            let [a, b, c, d] = corners;
            let (low, high) = (a.min(b).min(c).min(d), a.max(b).max(c).max(d));
            let box_distance = (low - x).max(x - high).max(Vec3::ZERO).length();
            let best_distance = best.map_or(margin, |(distance, ..)| distance.min(margin));
            if box_distance > best_distance {
                continue;
            }
            let weights =
                barycentric(corners, x).ok_or(EmbedError::DegenerateTet { tet: tet as usize })?;
            let smallest = weights.iter().copied().fold(Real::INFINITY, Real::min);
            let distance = if smallest >= 0.0 {
                0.0
            } else {
                distance_to_tet(corners, x)
            };
            let better = match best {
                None => true,
                Some((best_distance, best_smallest, _, _)) => {
                    distance < best_distance
                        || (distance == best_distance && smallest > best_smallest)
                }
            };
            if better {
                best = Some((distance, smallest, tet, weights));
            }
            // Strictly inside: no other tetrahedron of a conforming mesh contains the point.
            if smallest > 0.0 {
                break;
            }
        }
        match best {
            Some((distance, _, tet, weights)) if distance <= margin => {
                *slot = Embedded { weights, tet };
            }
            _ => return Err(EmbedError::Outside { point }),
        }
    }
    Ok(())
}

/// A validated embedding: every entry names an existing tetrahedron whose corners are below the
/// simulation mesh's vertex count, so [`deform`](Self::deform) needs no checks per point.
#[derive(Clone, Copy, Debug)]
pub struct Embedding<'a> {
    embedded: &'a [Embedded],
    tets: &'a [[u32; 4]],
    vertex_count: usize,
}

impl<'a> Embedding<'a> {
    /// Checks `embedded` against `tets` and a simulation mesh of `vertex_count` vertices.
    ///
    /// # Errors
    /// [`EmbedError::IndexOutOfRange`] (as tetrahedron `usize::MAX` for an entry naming a
    /// tetrahedron that does not exist, else the tetrahedron and the bad vertex index).
    pub fn new(
        embedded: &'a [Embedded],
        tets: &'a [[u32; 4]],
        vertex_count: usize,
    ) -> Result<Embedding<'a>, EmbedError> {
        for entry in embedded {
            let tet = tets
                .get(entry.tet as usize)
                .ok_or(EmbedError::IndexOutOfRange {
                    tet: usize::MAX,
                    index: entry.tet,
                })?;
            if let Some(&index) = tet.iter().find(|&&v| v as usize >= vertex_count) {
                return Err(EmbedError::IndexOutOfRange {
                    tet: entry.tet as usize,
                    index,
                });
            }
        }
        Ok(Embedding {
            embedded,
            tets,
            vertex_count,
        })
    }

    /// The number of render points.
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.embedded.len()
    }

    /// Whether there are no render points.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.embedded.is_empty()
    }

    /// Writes the deformed render positions (m) for the simulated `positions` (m) into `out`
    /// (one per render point). No allocation, no search.
    ///
    /// # Errors
    /// [`EmbedError::BufferLength`] if `positions` does not have the mesh's vertex count or
    /// `out` the number of render points; nothing is written then.
    pub fn deform(&self, positions: &[Vec3], out: &mut [Vec3]) -> Result<(), EmbedError> {
        check_length(EmbedBuffer::Positions, self.vertex_count, positions.len())?;
        check_length(EmbedBuffer::Output, self.embedded.len(), out.len())?;
        for (slot, entry) in out.iter_mut().zip(self.embedded) {
            let tet = self
                .tets
                .get(entry.tet as usize)
                .copied()
                .unwrap_or_default();
            let corner = |k: usize| {
                tet.get(k)
                    .and_then(|&v| positions.get(v as usize))
                    .copied()
                    .unwrap_or_default()
            };
            let [w0, w1, w2, w3] = entry.weights;
            *slot = corner(0) * w0 + corner(1) * w1 + corner(2) * w2 + corner(3) * w3;
        }
        Ok(())
    }
}

impl Embedding<'_> {
    /// Writes deformed unit normals for render points with rest normals `rest_normals` (one per
    /// render point) into `out`: each normal is carried by the deformation gradient `F` of its
    /// point's tetrahedron (`rest` is that mesh's rest data, one entry per tetrahedron, for
    /// example from `TetMesh::new`) as `cof(F) n = det(F) F^-T n`, normalised (Nanson's
    /// formula: how an area element's normal deforms). Exact for affine motions; a cheaper
    /// alternative to recomputing normals from the deformed triangles
    /// (`surface::vertex_normals`), at the price of being piecewise constant per tetrahedron.
    /// A normal that maps to zero (a collapsed tetrahedron) is written as zero.
    ///
    /// # Errors
    /// [`EmbedError::BufferLength`] if `positions`, `rest` (one per tetrahedron), `rest_normals`
    /// or `out` has the wrong length; nothing is written then.
    pub fn deform_normals(
        &self,
        rest: &[TetRest],
        positions: &[Vec3],
        rest_normals: &[Vec3],
        out: &mut [Vec3],
    ) -> Result<(), EmbedError> {
        check_length(EmbedBuffer::Positions, self.vertex_count, positions.len())?;
        check_length(EmbedBuffer::Embedding, self.tets.len(), rest.len())?;
        check_length(EmbedBuffer::Output, self.embedded.len(), rest_normals.len())?;
        check_length(EmbedBuffer::Output, self.embedded.len(), out.len())?;
        for ((slot, entry), &normal) in out.iter_mut().zip(self.embedded).zip(rest_normals) {
            let tet = self
                .tets
                .get(entry.tet as usize)
                .copied()
                .unwrap_or_default();
            let x = tet.map(|v| positions.get(v as usize).copied().unwrap_or_default());
            let f = rest
                .get(entry.tet as usize)
                .map_or(Mat3::IDENTITY, |r| r.deformation_gradient(x));
            // cof(F) = [f1 x f2, f2 x f0, f0 x f1] as rows, so cof(F) n = sum_i n_i (f_j x f_k).
            let (f0, f1, f2) = (f.x_axis, f.y_axis, f.z_axis);
            let mapped =
                f1.cross(f2) * normal.x + f2.cross(f0) * normal.y + f0.cross(f1) * normal.z;
            let length = sqrt(mapped.dot(mapped));
            *slot = if length > 0.0 && length.is_finite() {
                mapped * (1.0 / length)
            } else {
                Vec3::ZERO
            };
        }
        Ok(())
    }
}

/// Binds render points in one call, allocating the lookup grid and the result (feature `std`):
/// [`TetLookup::plan`] with the default cell size, [`TetLookup::build`], [`embed_points`],
/// within the memory budget [`MEMORY_BUDGET`](super::MEMORY_BUDGET) (2 GiB): see
/// [`embed_points_vec_with_budget`]. The grid spans the mesh's bounding box grown by the
/// margin, in cells the size of a mean tetrahedron, so a margin far larger than the mesh asks
/// for a large grid.
///
/// ```
/// use softfem::asset::embed::{Embedding, embed_points_vec};
/// use softfem::glam::Vec3;
///
/// let rest = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
/// let tets = [[0, 1, 2, 3]];
/// let render = [Vec3::splat(0.2), Vec3::new(0.5, 0.5, 0.01)];
/// let embedded = embed_points_vec(&rest, &tets, &render, 0.01)?;
/// let embedding = Embedding::new(&embedded, &tets, rest.len())?;
///
/// let moved = rest.map(|x| x * 2.0 + Vec3::Z); // scale by 2, lift by 1 m
/// let mut out = [Vec3::ZERO; 2];
/// embedding.deform(&moved, &mut out)?;
/// assert!(out[0].abs_diff_eq(Vec3::new(0.4, 0.4, 1.4), 1e-6));
/// # Ok::<(), softfem::EmbedError>(())
/// ```
///
/// # Errors
/// Those of [`embed_points_vec_with_budget`] with the budget
/// [`MEMORY_BUDGET`](super::MEMORY_BUDGET).
#[cfg(feature = "std")]
pub fn embed_points_vec(
    positions: &[Vec3],
    tets: &[[u32; 4]],
    points: &[Vec3],
    margin: Real,
) -> Result<std::vec::Vec<Embedded>, EmbedError> {
    embed_points_vec_with_budget(positions, tets, points, margin, super::MEMORY_BUDGET)
}

/// [`embed_points_vec`] with a memory budget of `budget` bytes (feature `std`): the bytes of
/// the planned bucket starts and entries (4 bytes each) and of the result (one [`Embedded`] a
/// render point) are added up and compared with `budget` before anything is allocated, and the
/// buffers are allocated fallibly.
///
/// # Errors
/// Those of the three steps; [`EmbedError::OverBudget`] with the bytes and the budget;
/// [`EmbedError::Allocation`] with the bytes the allocator refused.
#[cfg(feature = "std")]
pub fn embed_points_vec_with_budget(
    positions: &[Vec3],
    tets: &[[u32; 4]],
    points: &[Vec3],
    margin: Real,
    budget: usize,
) -> Result<std::vec::Vec<Embedded>, EmbedError> {
    use super::{bytes_of, filled};
    let plan = TetLookup::plan(positions, tets, None, margin)?;
    let bytes = [
        bytes_of::<u32>(plan.starts_len),
        bytes_of::<u32>(plan.entries_len),
        bytes_of::<Embedded>(points.len()),
    ]
    .into_iter()
    .fold(0, usize::saturating_add);
    if bytes > budget {
        return Err(EmbedError::OverBudget { bytes, budget });
    }
    let allocation = |bytes| EmbedError::Allocation { bytes };
    let mut starts = filled(plan.starts_len, 0u32).map_err(allocation)?;
    let mut entries = filled(plan.entries_len, 0u32).map_err(allocation)?;
    let lookup = TetLookup::build(&plan, positions, tets, &mut starts, &mut entries)?;
    let mut out = filled(points.len(), Embedded::default()).map_err(allocation)?;
    embed_points(&lookup, positions, tets, points, &mut out)?;
    Ok(out)
}

/// The corners of tetrahedron `tet`.
fn corners(positions: &[Vec3], tets: &[[u32; 4]], tet: usize) -> Result<[Vec3; 4], EmbedError> {
    let indices = tets.get(tet).ok_or(EmbedError::IndexOutOfRange {
        tet,
        index: u32::MAX,
    })?;
    let mut corners = [Vec3::ZERO; 4];
    for (corner, &index) in corners.iter_mut().zip(indices) {
        *corner = *positions
            .get(index as usize)
            .ok_or(EmbedError::IndexOutOfRange { tet, index })?;
    }
    Ok(corners)
}

/// The barycentric coordinates of `x` in the tetrahedron `corners`, or `None` if it is
/// degenerate: `(w1, w2, w3) = Dm^-1 (x - x0)`, `w0 = 1 - w1 - w2 - w3`.
fn barycentric([x0, x1, x2, x3]: [Vec3; 4], x: Vec3) -> Option<[Real; 4]> {
    let dm = Mat3::from_cols(x1 - x0, x2 - x0, x3 - x0);
    let det = dm.determinant();
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let local = dm.inverse() * (x - x0);
    let w = [1.0 - local.x - local.y - local.z, local.x, local.y, local.z];
    w.iter().all(|w| w.is_finite()).then_some(w)
}

/// The distance from `x` to the tetrahedron `corners` when `x` is outside it: the smallest
/// distance to its four faces.
fn distance_to_tet([a, b, c, d]: [Vec3; 4], x: Vec3) -> Real {
    [[a, b, c], [a, b, d], [a, c, d], [b, c, d]]
        .iter()
        .map(|&face| (closest_point_on_triangle(face, x) - x).length())
        .fold(Real::INFINITY, Real::min)
}

/// The point of triangle `[a, b, c]` nearest to `p` (Ericson, "Real-Time Collision Detection",
/// Morgan Kaufmann 2005, section 5.1.5: Voronoi regions of the vertices, edges and face).
fn closest_point_on_triangle([a, b, c]: [Vec3; 3], p: Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denominator = va + vb + vc;
    if denominator == 0.0 || !denominator.is_finite() {
        // A degenerate face: its vertices are the nearest candidates worth reporting.
        return [a, b, c].into_iter().fold(a, |best, q| {
            if (q - p).length_squared() < (best - p).length_squared() {
                q
            } else {
                best
            }
        });
    }
    a + ab * (vb / denominator) + ac * (vc / denominator)
}

fn check_length(buffer: EmbedBuffer, expected: usize, actual: usize) -> Result<(), EmbedError> {
    if expected == actual {
        Ok(())
    } else {
        Err(EmbedError::BufferLength {
            buffer,
            expected,
            actual,
        })
    }
}

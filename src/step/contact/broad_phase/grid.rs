//! The broad phase's grid: primitive boxes, the cell size and the hashed table filled by a
//! counting sort (see the module documentation of `broad_phase`).

use super::super::super::super::types::{Real, Vec3};
use super::super::boundary::ContactSurface;
use super::BroadPhaseScratch;

/// The most cells along one axis: cell coordinates fit 20 bits.
pub(super) const AXIS_CELLS: u32 = 1 << 20;
/// The most doublings of the cell edge tried before the one-cell fallback (22 reach twice the
/// scene from the finest cell allowed, `2^-20` of it).
pub(super) const MAX_COARSENINGS: u32 = 64;
/// The multipliers of the cell hash (Teschner et al. 2003).
pub(super) const HASH: [u64; 3] = [73_856_093, 19_349_663, 83_492_791];
/// `2^64` over the golden ratio, odd: the multiplier of Fibonacci hashing (D. E. Knuth, "The Art
/// of Computer Programming", vol. 3, section 6.4).
const FIBONACCI: u64 = 0x9E37_79B9_7F4A_7C15;

/// An axis-aligned box (m), closed.
#[derive(Clone, Copy, Debug)]
pub(super) struct Aabb {
    pub(super) lo: Vec3,
    pub(super) hi: Vec3,
}

impl Aabb {
    /// Whether the closed boxes share a point.
    #[inline]
    pub(super) fn overlaps(&self, other: &Aabb) -> bool {
        self.lo.cmple(other.hi).all() && other.lo.cmple(self.hi).all()
    }

    /// The largest edge (m).
    #[inline]
    pub(super) fn largest_extent(&self) -> Real {
        (self.hi - self.lo).max_element()
    }
}

/// The grown boxes of a surface's primitives, by primitive id: vertices first, then edges,
/// then triangles.
pub(super) struct Boxes<'s> {
    pub(super) start: &'s [Vec3],
    pub(super) end: &'s [Vec3],
    pub(super) half_gap: Real,
    pub(super) surface: &'s ContactSurface<'s>,
}

impl Boxes<'_> {
    /// The grown box of the given corners at both ends of the motion.
    #[inline]
    pub(super) fn of_corners(&self, corners: &[u32]) -> Aabb {
        let mut lo = Vec3::splat(Real::INFINITY);
        let mut hi = Vec3::splat(Real::NEG_INFINITY);
        // Indices were checked on entry; a missing one cannot occur.
        for &corner in corners {
            let x = self.start.get(corner as usize).copied().unwrap_or_default();
            lo = lo.min(x);
            hi = hi.max(x);
        }
        // A proximity query passes one array as both ends: its corners once (the box of every
        // primitive is built again for each pair tested, the broad phase's inner loop).
        if !core::ptr::eq(self.start, self.end) {
            for &corner in corners {
                let x = self.end.get(corner as usize).copied().unwrap_or_default();
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
        Aabb {
            lo: lo - Vec3::splat(self.half_gap),
            hi: hi + Vec3::splat(self.half_gap),
        }
    }

    #[inline]
    pub(super) fn vertex(&self, index: usize) -> Aabb {
        let vertex = self
            .surface
            .vertices
            .get(index)
            .copied()
            .unwrap_or_default();
        self.of_corners(&[vertex])
    }

    #[inline]
    pub(super) fn edge(&self, index: usize) -> Aabb {
        let edge = self.surface.edges.get(index).copied().unwrap_or_default();
        self.of_corners(&edge)
    }

    #[inline]
    pub(super) fn triangle(&self, index: usize) -> Aabb {
        let triangle = self
            .surface
            .triangles
            .get(index)
            .copied()
            .unwrap_or_default();
        self.of_corners(&triangle)
    }

    /// The box of primitive `id` (vertices, then edges, then triangles).
    #[inline]
    pub(super) fn primitive(&self, id: usize) -> Aabb {
        let vertices = self.surface.vertices.len();
        let edges = self.surface.edges.len();
        if id < vertices {
            self.vertex(id)
        } else if id < vertices + edges {
            self.edge(id - vertices)
        } else {
            self.triangle(id - vertices - edges)
        }
    }
}

/// A uniform grid hashed into `slot_count` slots.
#[derive(Clone, Copy, Debug)]
pub(super) struct Grid {
    pub(super) origin: Vec3,
    pub(super) cell: Real,
    /// `1 / cell` (1/m): a cell coordinate is a product, not a quotient (a division in each
    /// of the three axes of every box corner and every pair's report test).
    pub(super) inverse_cell: Real,
    pub(super) axis_cells: u32,
    pub(super) slot_count: u64,
}

/// A cell's integer coordinates.
pub(super) type Cell = [u32; 3];

impl Grid {
    /// The cell holding `point`: monotone in each coordinate (a rounded difference, a rounded
    /// product with the positive `inverse_cell`, a saturating cast, a clamp), so a box's cells
    /// are those from its low corner's to its high corner's.
    #[inline]
    pub(super) fn cell_of(&self, point: Vec3) -> Cell {
        let last = self.axis_cells - 1;
        // Non-negative for points in the scene's box (`origin` is its low corner); the cast
        // truncates, saturates, and sends NaN to 0.
        let coordinate = |x: Real, o: Real| (((x - o) * self.inverse_cell) as u32).min(last);
        [
            coordinate(point.x, self.origin.x),
            coordinate(point.y, self.origin.y),
            coordinate(point.z, self.origin.z),
        ]
    }

    /// The cells a box covers, low and high corner inclusive.
    #[inline]
    pub(super) fn range(&self, aabb: &Aabb) -> (Cell, Cell) {
        (self.cell_of(aabb.lo), self.cell_of(aabb.hi))
    }

    /// The number of cells in a range (at most `2^60`).
    #[inline]
    pub(super) fn cell_count((lo, hi): (Cell, Cell)) -> u64 {
        let span = |axis: usize| {
            let (l, h) = (lo.get(axis).copied(), hi.get(axis).copied());
            u64::from(h.unwrap_or(0).saturating_sub(l.unwrap_or(0))) + 1
        };
        span(0) * span(1) * span(2)
    }

    /// The hash-table slot of a cell.
    #[inline]
    pub(super) fn slot(&self, [i, j, k]: Cell) -> usize {
        let [a, b, c] = HASH;
        let hash = u64::from(i).wrapping_mul(a)
            ^ u64::from(j).wrapping_mul(b)
            ^ u64::from(k).wrapping_mul(c);
        // Onto `0..slot_count` by a multiplication instead of a 64-bit division (dozens of
        // cycles, and this runs once per covered cell in every pass): Fibonacci hashing spreads
        // the hash over all 64 bits, then the high word of the product with `slot_count` is
        // below it (D. Lemire, "Fast Random Integer Generation in an Interval", ACM TOMACS 29(1),
        // 2019). Below `slot_count`, itself a slice length: fits usize.
        let spread = hash.wrapping_mul(FIBONACCI);
        ((u128::from(spread) * u128::from(self.slot_count)) >> 64) as usize
    }
}

/// Calls `visit` on every cell of a range, `k` slowest, `i` fastest; reversed if `reverse`.
#[inline]
pub(super) fn for_each_cell((lo, hi): (Cell, Cell), reverse: bool, mut visit: impl FnMut(Cell)) {
    let [i0, j0, k0] = lo;
    let [i1, j1, k1] = hi;
    if reverse {
        for k in (k0..=k1).rev() {
            for j in (j0..=j1).rev() {
                for i in (i0..=i1).rev() {
                    visit([i, j, k]);
                }
            }
        }
    } else {
        for k in k0..=k1 {
            for j in j0..=j1 {
                for i in i0..=i1 {
                    visit([i, j, k]);
                }
            }
        }
    }
}

/// The grid: the scene's box, the mean box extent for the cell, doubled until the entries fit
/// `capacity` (at least `8 * primitives`, see the module documentation).
pub(super) fn choose_grid(
    boxes: &Boxes<'_>,
    primitives: usize,
    slot_count: usize,
    capacity: usize,
) -> Grid {
    let mut lo = Vec3::splat(Real::INFINITY);
    let mut hi = Vec3::splat(Real::NEG_INFINITY);
    let mut extent_sum: Real = 0.0;
    for id in 0..primitives {
        let aabb = boxes.primitive(id);
        lo = lo.min(aabb.lo);
        hi = hi.max(aabb.hi);
        extent_sum += aabb.largest_extent();
    }
    let scene = (hi - lo).max_element();
    let mean = extent_sum / primitives as Real;
    let finest = scene / AXIS_CELLS as Real;
    let usable = |h: Real| h.is_finite() && h >= Real::MIN_POSITIVE;
    let cell = if usable(mean.max(finest)) {
        mean.max(finest)
    } else if usable(finest) {
        finest
    } else if scene > 0.0 {
        Real::MAX
    } else {
        // A scene of one point: every coordinate is in cell 0 whatever the edge.
        1.0
    };
    let mut grid = Grid {
        origin: lo,
        cell,
        inverse_cell: 1.0 / cell,
        axis_cells: AXIS_CELLS,
        slot_count: slot_count as u64,
    };
    let capacity = capacity as u64;
    for _ in 0..MAX_COARSENINGS {
        let entries = (0..primitives).fold(0u64, |sum, id| {
            sum.saturating_add(Grid::cell_count(grid.range(&boxes.primitive(id))))
        });
        if entries <= capacity {
            return grid;
        }
        let doubled = grid.cell * 2.0;
        grid.cell = if doubled.is_finite() {
            doubled
        } else {
            Real::MAX
        };
        grid.inverse_cell = 1.0 / grid.cell;
    }
    // One cell: one entry per primitive, within the capacity checked on entry.
    grid.axis_cells = 1;
    grid
}

/// Counting sort of the edges' and triangles' (primitive, cell) entries by slot: afterwards the
/// entries of slot `s` are `entries[slots[s]..slots[s + 1]]`, in increasing primitive id (so
/// that a primitive entered in several cells of one slot appears in one run). Vertices are
/// left out: the queries look up edges and triangles only.
pub(super) fn fill_table(
    boxes: &Boxes<'_>,
    primitives: usize,
    grid: &Grid,
    scratch: &mut BroadPhaseScratch<'_>,
) {
    let BroadPhaseScratch { slots, entries } = scratch;
    let first_edge = boxes.surface.vertices.len();
    slots.fill(0);
    for id in first_edge..primitives {
        for_each_cell(grid.range(&boxes.primitive(id)), false, |cell| {
            if let Some(count) = slots.get_mut(grid.slot(cell)) {
                *count += 1;
            }
        });
    }
    // Inclusive prefix sums: `slots[s]` is the end of slot `s`, the last entry the total (the
    // table's one extra slot counts nothing). Totals fit u32: they are at most the capacity.
    let mut total = 0u32;
    for count in slots.iter_mut() {
        total = total.saturating_add(*count);
        *count = total;
    }
    // Filled backwards, each slot's end moving down to its start.
    for id in (first_edge..primitives).rev() {
        for_each_cell(grid.range(&boxes.primitive(id)), true, |cell| {
            if let Some(end) = slots.get_mut(grid.slot(cell)) {
                *end = end.saturating_sub(1);
                if let Some(entry) = entries.get_mut(*end as usize) {
                    // Fits: at most u32::MAX primitives (checked on entry).
                    *entry = id as u32;
                }
            }
        });
    }
}

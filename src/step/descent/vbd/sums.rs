//! The per-vertex sums of a Vertex Block Descent sweep (`docs/math.md` section 7): for each
//! vertex, the elastic gradient `sum_e V_e P_e g_e` and the exact block `sum_e V_e K_e(g_e)` of
//! the elements around it ([`Material::corner_stress_and_stiffness_wide`]), and, for the line
//! search, their energy and its rounding scale.
//!
//! # Lanes
//! Several vertices of one colour are summed at once, one per SIMD lane, at the width
//! [`simd`](crate::simd) picks (1, 4, 8 or 16 values): lane `j` walks the elements around its
//! own vertex in adjacency order (increasing element index), so every lane performs exactly the
//! operations of the one-vertex-at-a-time code, in its order, and the sums are the same bits at
//! every width. A lane whose vertex has fewer elements than the group's longest row is masked
//! (its sums are selected, never added to), so it changes nothing either. Two vertices of one
//! colour share no element, so the updates of a group's vertices, applied after the group is
//! summed, give the sequential sweep's result.
//!
//! With the packed layout, the visits of a group's longest row past the end of all its other
//! rows are summed for that one lane alone, by the scalar code (the same operations in the same
//! order, so the same bits): on a small mesh a colour often holds one vertex of many elements
//! among a few of fewer (on the descent chart's stiff block, 96 tetrahedra, 48 of the 124
//! group visits of a sweep by 8 f64 lanes have one lane active, counted from its colouring and
//! the sweep's order; 76 of 152 before the order put the most elements first), and a visit of
//! one lane costs less than one of the whole group.

use super::super::super::super::element::TetRest;
#[cfg(target_arch = "x86_64")]
use super::super::super::super::lanes::avx2::Avx2Lanes;
#[cfg(target_arch = "x86_64")]
use super::super::super::super::lanes::avx512::Avx512Lanes;
use super::super::super::super::lanes::{
    LANES, Lane, LaneArray, LaneMat3, LaneVec3, Lanes, MAX_WIDTH, each_lane,
};
use super::super::super::super::material::Material;
use super::super::super::super::mesh::Positions;
use super::super::super::super::types::{Mat3, Real, Vec3};
use super::block::shape_gradient;
use super::layout::{self, BLOCK, LAYOUT_VALUES, Layout, Run};
use crate::simd::{WidthKernel, dispatch};

/// What the elements around one vertex add to its Newton system at the current positions.
#[derive(Clone, Copy)]
pub(crate) struct VertexSums {
    /// `sum_e V_e P_e g_e` (N): the elastic part of the gradient.
    pub gradient: Vec3,
    /// `sum_e V_e K_e(g_e)` (N/m): the exact elastic block.
    pub hessian: Mat3,
    /// `sum_e V_e W_e` (J), with [`Extras::EnergyAndScale`] only (else 0).
    pub elastic: Real,
    /// `sum_e |V_e tr K_e| / |g_e|^2` (J), the energy scale of the elements, with
    /// [`Extras::Scale`] or [`Extras::EnergyAndScale`] only (else 0).
    pub resolution: Real,
}

/// What a [`SumsPass`] sums besides the gradient and the block.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Extras {
    /// Nothing more (a sweep without the line search).
    Nothing,
    /// The energy scale only: no energy density (whose logarithms, one per lane, cost more
    /// than the rest of a visit).
    Scale,
    /// The energy and its scale (a sweep with the line search).
    EnergyAndScale,
}

/// Sums of a vertex in no element.
const EMPTY: VertexSums = VertexSums {
    gradient: Vec3::ZERO,
    hessian: Mat3::ZERO,
    elastic: 0.0,
    resolution: 0.0,
};

/// The mesh a sweep visits: elements, rest data, material and vertex adjacency
/// (`mesh/adjacency.rs`), and the packed visits of `step/descent/vbd/layout.rs` where the caller
/// gave room for them (the same sums, bit for bit, without the gather of the rest data).
pub(crate) struct Elements<'s, M> {
    pub tets: &'s [[u32; 4]],
    pub rest: &'s [TetRest],
    pub material: &'s M,
    pub offsets: &'s [u32],
    pub incident: &'s [u32],
    pub layout: Option<Layout<'s>>,
}

impl<M> Clone for Elements<'_, M> {
    #[inline]
    fn clone(&self) -> Self {
        *self
    }
}

impl<M> Copy for Elements<'_, M> {}

impl<M> Elements<'_, M> {
    /// The packed `4 * element + corner` entries of vertex `vertex` (empty out of range).
    #[inline(always)]
    fn row(&self, vertex: usize) -> &[u32] {
        let start = self.offsets.get(vertex).copied().unwrap_or(0) as usize;
        let end = self.offsets.get(vertex + 1).copied().unwrap_or(0) as usize;
        self.incident.get(start..end).unwrap_or(&[])
    }
}

/// A lane group of a [`SumsPass`] once summed: lane `j` holds vertex `members[j].1`, entry
/// `members[j].0` of its run, with sums `sums[j]`, and is visited where bit `j` of `visited` is
/// set (skipped vertices are not).
pub(crate) struct SummedGroup<'g> {
    pub members: &'g [(usize, u32)],
    pub visited: u32,
    pub sums: &'g [VertexSums; MAX_WIDTH],
}

impl SummedGroup<'_> {
    /// The visited lanes in order: `(lane, index, vertex, sums)`.
    #[inline(always)]
    pub fn visits(&self) -> impl Iterator<Item = (usize, usize, u32, &VertexSums)> + '_ {
        self.members
            .iter()
            .zip(self.sums)
            .enumerate()
            .filter(|&(j, _)| self.visited >> j & 1 != 0)
            .map(|(j, (&(index, vertex), sums))| (j, index, vertex, sums))
    }
}

/// What receives the sums of a [`SumsPass`], vertex by vertex.
pub(crate) trait VertexVisitor {
    /// The positions the next group is summed at.
    fn positions(&self) -> &[Vec3];
    /// The sums of `vertex`, entry `index` of its run.
    fn visit(&mut self, index: usize, vertex: u32, sums: &VertexSums);
    /// The sums of a lane group of `L::WIDTH` vertices, each visited lane in order: by
    /// default [`visit`](Self::visit) one lane at a time; a visitor may work on the lanes
    /// together where that gives the same result.
    #[inline(always)]
    fn visit_group<L: LaneArray>(&mut self, group: &SummedGroup<'_>) {
        for (_, index, vertex, sums) in group.visits() {
            self.visit(index, vertex, sums);
        }
    }
}

/// One pass over runs of vertices, each run of one colour: the vertices not `skip`ped are
/// summed a lane group at a time and handed to the visitor in run order, each group after it
/// is summed whole (so the visitor may move a group's vertices, never their neighbours').
/// With the layout, a run starts at a layout block (a colour's first vertex, or a multiple of
/// [`BLOCK`] after it) and its groups are the lanes of the blocks, skipped vertices masked.
pub(crate) struct SumsPass<'a, 's, M, R, V> {
    pub elements: &'a Elements<'s, M>,
    /// Vertices left out (pinned), indexed by vertex; empty for none.
    pub skip: &'a [bool],
    pub runs: R,
    /// What to sum besides the gradient and the block.
    pub extras: Extras,
    pub visitor: V,
}

/// Runs `pass` at the active SIMD width and returns its visitor.
#[inline]
pub(crate) fn sum_vertices<'r, M: Material, R: Iterator<Item = Run<'r>>, V: VertexVisitor>(
    pass: SumsPass<'_, '_, M, R, V>,
) -> V {
    dispatch(pass)
}

impl<'r, M: Material, R: Iterator<Item = Run<'r>>, V: VertexVisitor> SumsPass<'_, '_, M, R, V> {
    /// The pass with groups of `L::WIDTH` vertices.
    ///
    /// Inlined on x86_64, where it must be compiled inside [`dispatch`]'s AVX2 and AVX-512
    /// functions to use their lanes; elsewhere a function of its own per width, so that the
    /// caller's frame does not hold the buffers of both widths' passes (the scalar and the
    /// 4-lane one), each gathered and packed. Measured by the firmware check on thumbv7em,
    /// `vbd_step`'s stack: f32 7 888 B with both inlined, 6 168 B so (f64 11 348 and
    /// 11 452 B); with only the packed pass out of line 6 496 and 15 924 B; 3 408 B in f32
    /// before the packed layout.
    #[cfg_attr(target_arch = "x86_64", inline(always))]
    #[cfg_attr(not(target_arch = "x86_64"), inline(never))]
    fn run<L: LaneArray>(self) -> V
    where
        L::Array: for<'a> TryFrom<&'a [Real]>,
    {
        let SumsPass {
            elements,
            skip,
            runs,
            extras,
            mut visitor,
        } = self;
        // Every width divides the layout's blocks (see `step/descent/vbd/layout.rs`); one that did
        // not would take the gather path, with the same results.
        if let Some(layout) = elements.layout
            && BLOCK.is_multiple_of(L::WIDTH)
        {
            return run_packed::<L, M, R, V>((elements, &layout), skip, runs, extras, visitor);
        }
        let mut batch = [(0usize, 0u32); MAX_WIDTH];
        let mut sums = [EMPTY; MAX_WIDTH];
        for run in runs {
            let mut filled = 0;
            let mut members = run.vertices.iter().enumerate();
            loop {
                let next = members.next();
                if let Some((index, &vertex)) = next {
                    if skip.get(vertex as usize).copied().unwrap_or(false) {
                        continue;
                    }
                    if let Some(slot) = batch.get_mut(filled) {
                        *slot = (index, vertex);
                        filled += 1;
                    }
                }
                if filled > 0 && (filled >= L::WIDTH || next.is_none()) {
                    let group = batch.get(..filled).unwrap_or(&[]);
                    sum_group::<L, M>(elements, visitor.positions(), group, extras, &mut sums);
                    visitor.visit_group::<L>(&SummedGroup {
                        members: group,
                        visited: u32::MAX,
                        sums: &sums,
                    });
                    filled = 0;
                }
                if next.is_none() {
                    break;
                }
            }
        }
        visitor
    }
}

/// The pass over the layout's blocks, `L::WIDTH` lanes of a block at a time.
#[inline(always)]
fn run_packed<'r, L: LaneArray, M: Material, R: Iterator<Item = Run<'r>>, V: VertexVisitor>(
    (elements, layout): (&Elements<'_, M>, &Layout<'_>),
    skip: &[bool],
    runs: R,
    extras: Extras,
    mut visitor: V,
) -> V
where
    L::Array: for<'a> TryFrom<&'a [Real]>,
{
    let mut sums = [EMPTY; MAX_WIDTH];
    // The gathered corner positions, initialised once per pass rather than per group.
    let mut buffer = [[L::ZEROS; 12]; STEPS];
    for run in runs {
        for (b, block) in run.vertices.chunks(BLOCK).enumerate() {
            let rows = layout.rows(run.block + b);
            for (s, vertices) in block.chunks(L::WIDTH).enumerate() {
                let lane = s * L::WIDTH;
                let group = PackedGroup {
                    vertices,
                    lane,
                    rows,
                };
                let at = visitor.positions();
                sum_packed_group::<L, M>(
                    elements,
                    layout,
                    at,
                    (group, skip),
                    extras,
                    (&mut sums, &mut buffer),
                );
                let mut members = [(0, 0); MAX_WIDTH];
                let mut visited = 0;
                for (j, (member, &vertex)) in members.iter_mut().zip(vertices).enumerate() {
                    *member = (b * BLOCK + lane + j, vertex);
                    if !skip.get(vertex as usize).copied().unwrap_or(false) {
                        visited |= 1 << j;
                    }
                }
                visitor.visit_group::<L>(&SummedGroup {
                    members: members.get(..vertices.len()).unwrap_or_default(),
                    visited,
                    sums: &sums,
                });
            }
        }
    }
    visitor
}

impl<'r, M: Material, R: Iterator<Item = Run<'r>>, V: VertexVisitor> WidthKernel
    for SumsPass<'_, '_, M, R, V>
{
    type Output = V;

    #[inline(always)]
    fn scalar(self) -> V {
        self.run::<Real>()
    }

    #[inline(always)]
    fn sse(self) -> V {
        self.run::<Lanes>()
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx2(self) -> V {
        self.run::<Avx2Lanes>()
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx512(self) -> V {
        self.run::<Avx512Lanes>()
    }
}

/// Where [`gather_visit`] puts the values of one element visit, per lane: the four corner
/// positions (0..12), `Dm^-1` by columns (12..21), the rest volume, the corner's shape
/// gradient (22..25), and 1 for a lane that has an element at this step (0 for a masked lane,
/// whose other values are left as they were: never used).
const VOLUME: usize = 21;
const GRADIENT: usize = 22;
const ACTIVE: usize = 25;
const VISIT_VALUES: usize = 26;

/// Element visits per lane gathered before they are computed on.
const STEPS: usize = 4;

/// Writes the values of the visit `packed` (`4 * element + corner`; `None` past the end of the
/// lane's row) into lane `lane` of `values`.
#[inline(always)]
fn gather_visit<L: LaneArray, M>(
    elements: &Elements<'_, M>,
    positions: &[Vec3],
    packed: Option<&u32>,
    lane: usize,
    values: &mut [L::Array; VISIT_VALUES],
) {
    let mut put = |slot: usize, value: Real| {
        if let Some(array) = values.get_mut(slot) {
            L::set_lane_value(array, lane, value);
        }
    };
    let visit = packed.and_then(|&packed| {
        let (element, corner) = ((packed >> 2) as usize, (packed & 3) as usize);
        Some((
            elements.tets.get(element)?,
            elements.rest.get(element)?,
            corner,
        ))
    });
    let Some((tet, rest, corner)) = visit else {
        put(ACTIVE, 0.0);
        return;
    };
    for (c, &i) in tet.iter().enumerate() {
        let x = positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
        put(3 * c, x.x);
        put(3 * c + 1, x.y);
        put(3 * c + 2, x.z);
    }
    for (k, &entry) in rest.dm_inv.to_cols_array().iter().enumerate() {
        put(12 + k, entry);
    }
    put(VOLUME, rest.volume);
    let g = shape_gradient(rest, corner);
    put(GRADIENT, g.x);
    put(GRADIENT + 1, g.y);
    put(GRADIENT + 2, g.z);
    put(ACTIVE, 1.0);
}

/// The running sums of a lane group: each lane's vertex's, in its row order.
struct Accumulator<L> {
    gradient: LaneVec3<L>,
    /// xx, yy, zz, xy, xz, yz.
    hessian: [L; 6],
    elastic: L,
    resolution: L,
}

/// One element visit per lane: the four corner positions, `Dm^-1`, the rest volume, the
/// corner's shape gradient, and which lanes have an element at this step.
struct Visit<L: Lane> {
    corners: [LaneVec3<L>; 4],
    dm_inv: LaneMat3<L>,
    volume: L,
    gradient: LaneVec3<L>,
    active: L::Mask,
}

impl<L: Lane> Visit<L> {
    /// The visit with corner `c` at `corner(3 c)`, `Dm^-1` by columns at `rest(dm_inv)`,
    /// `rest(dm_inv + 3)` and `rest(dm_inv + 6)`, and the shape gradient at `rest(gradient)`.
    #[inline(always)]
    fn new(
        corner: impl Fn(usize) -> LaneVec3<L>,
        rest: impl Fn(usize) -> LaneVec3<L>,
        (dm_inv, gradient): (usize, usize),
        volume: L,
        active: L::Mask,
    ) -> Self {
        Visit {
            corners: [corner(0), corner(3), corner(6), corner(9)],
            dm_inv: LaneMat3 {
                c0: rest(dm_inv),
                c1: rest(dm_inv + 3),
                c2: rest(dm_inv + 6),
            },
            volume,
            gradient: rest(gradient),
            active,
        }
    }
}

impl<L: LaneArray> Accumulator<L> {
    #[inline(always)]
    fn new() -> Self {
        let zero = L::splat(0.0);
        Accumulator {
            gradient: LaneVec3::new(zero, zero, zero),
            hessian: [zero; 6],
            elastic: zero,
            resolution: zero,
        }
    }

    /// Adds the visit's terms to its active lanes.
    #[inline(always)]
    fn add<M: Material>(&mut self, material: &M, visit: &Visit<L>, extras: Extras) {
        let [x0, x1, x2, x3] = visit.corners;
        // F = Ds Dm^-1 as `TetRest::deformation_gradient` forms it.
        let edges = LaneMat3 {
            c0: x1 - x0,
            c1: x2 - x0,
            c2: x3 - x0,
        };
        let f = edges * visit.dm_inv;
        let (volume, g, active) = (visit.volume, visit.gradient, visit.active);
        let (stress, k) = material.corner_stress_and_stiffness_wide(f, g);
        self.gradient =
            LaneVec3::select(active, self.gradient + stress.scale(volume), self.gradient);
        let entries = [k.c0.x, k.c1.y, k.c2.z, k.c1.x, k.c2.x, k.c2.y];
        for (sum, entry) in self.hessian.iter_mut().zip(entries) {
            *sum = L::select(active, *sum + entry * volume, *sum);
        }
        if extras == Extras::EnergyAndScale {
            let density = material.energy_density_wide(f);
            self.elastic = L::select(active, self.elastic + volume * density, self.elastic);
        }
        if extras != Extras::Nothing {
            let trace = k.c0.x + k.c1.y + k.c2.z;
            let scale = (trace * volume).abs() / g.dot(g);
            self.resolution = L::select(active, self.resolution + scale, self.resolution);
        }
    }

    /// The sums of the first `count` lanes into `out`.
    #[inline(always)]
    fn write(self, count: usize, out: &mut [VertexSums; MAX_WIDTH]) {
        let [xx, yy, zz, xy, xz, yz] = self.hessian;
        // Written out rather than `<[T; N]>::map`, which is not always inlined.
        let sums = [
            self.gradient.x.to_lane_array(),
            self.gradient.y.to_lane_array(),
            self.gradient.z.to_lane_array(),
            xx.to_lane_array(),
            yy.to_lane_array(),
            zz.to_lane_array(),
            xy.to_lane_array(),
            xz.to_lane_array(),
            yz.to_lane_array(),
            self.elastic.to_lane_array(),
            self.resolution.to_lane_array(),
        ];
        // The lane index is hidden from the optimiser, which would otherwise turn the loop's
        // reads of one lane from every sum into scatter instructions across the slots (one
        // per value, slow on current AMD processors), as in `svd3_batch`.
        for (lane, slot) in out.iter_mut().enumerate().take(count) {
            let lane = core::hint::black_box(lane);
            let at = |k: usize| {
                sums.get(k)
                    .map_or(0.0, |values| L::lane_value(values, lane))
            };
            let (xy, xz, yz) = (at(6), at(7), at(8));
            *slot = VertexSums {
                gradient: Vec3::new(at(0), at(1), at(2)),
                hessian: Mat3::from_cols(
                    Vec3::new(at(3), xy, xz),
                    Vec3::new(xy, at(4), yz),
                    Vec3::new(xz, yz, at(5)),
                ),
                elastic: at(9),
                resolution: at(10),
            };
        }
    }
}

/// The lane group of vector `k` of `values` (three consecutive arrays).
#[inline(always)]
fn lane_vector<L: LaneArray>(values: &[L::Array], k: usize) -> LaneVec3<L> {
    let value = |k: usize| L::from_lane_array(values.get(k).copied().unwrap_or(L::ZEROS));
    LaneVec3::new(value(k), value(k + 1), value(k + 2))
}

/// The sums of the vertices `group` (at most `L::WIDTH`, one colour) into `out`, in order.
#[inline(always)]
fn sum_group<L: LaneArray, M: Material>(
    elements: &Elements<'_, M>,
    positions: &[Vec3],
    group: &[(usize, u32)],
    extras: Extras,
    out: &mut [VertexSums; MAX_WIDTH],
) {
    let mut rows: [&[u32]; MAX_WIDTH] = [&[]; MAX_WIDTH];
    let mut longest = 0;
    for (row, &(_, vertex)) in rows.iter_mut().zip(group).take(L::WIDTH) {
        *row = elements.row(vertex as usize);
        longest = longest.max(row.len());
    }
    let mut sums = Accumulator::<L>::new();
    // The values of `STEPS` element visits per lane are gathered first, lane by lane, then
    // computed on: a lane group loaded right after its lanes were stored one by one would wait
    // for the stores (no store-to-load forwarding from several stores into one wide load).
    let mut buffer = [[L::ZEROS; VISIT_VALUES]; STEPS];
    for first in (0..longest).step_by(STEPS) {
        for (lane, row) in rows.iter().enumerate().take(L::WIDTH) {
            for (offset, values) in buffer.iter_mut().enumerate() {
                gather_visit::<L, M>(elements, positions, row.get(first + offset), lane, values);
            }
        }
        for values in buffer.iter().take(longest - first) {
            let vector = |k: usize| lane_vector::<L>(values, k);
            let value = |k: usize| L::from_lane_array(values.get(k).copied().unwrap_or(L::ZEROS));
            let visit = Visit::new(
                vector,
                vector,
                (12, GRADIENT),
                value(VOLUME),
                value(ACTIVE).gt(L::splat(0.0)),
            );
            sums.add(elements.material, &visit, extras);
        }
    }
    sums.write(group.len(), out);
}

/// A lane group of a layout block: its vertices, the lane of the first, and the block's
/// visit rows (first, end).
struct PackedGroup<'g> {
    vertices: &'g [u32],
    lane: usize,
    rows: (usize, usize),
}

/// The sums of the vertices of `group` from the layout (skipped vertices masked) into `out`,
/// in order: the bits of [`sum_group`] for every vertex not skipped.
#[inline(always)]
fn sum_packed_group<L: LaneArray, M: Material>(
    elements: &Elements<'_, M>,
    layout: &Layout<'_>,
    positions: &[Vec3],
    (group, skip): (PackedGroup<'_>, &[bool]),
    extras: Extras,
    (out, buffer): (&mut [VertexSums; MAX_WIDTH], &mut [[L::Array; 12]; STEPS]),
) where
    L::Array: for<'a> TryFrom<&'a [Real]>,
{
    // Each lane's row length (0 for a skipped vertex): a lane is active at visit `t` while
    // `t < length`, as in `sum_group`.
    let mut lengths = L::ZEROS;
    // The longest row, its lane, and the longest of the other lanes' rows.
    let (mut longest, mut last_lane, mut second) = (0, 0, 0);
    for (lane, &vertex) in group.vertices.iter().enumerate().take(L::WIDTH) {
        let length = if skip.get(vertex as usize).copied().unwrap_or(false) {
            0
        } else {
            elements.row(vertex as usize).len()
        };
        L::set_lane_value(&mut lengths, lane, length as Real);
        if length > longest {
            (second, longest, last_lane) = (longest, length, lane);
        } else {
            second = second.max(length);
        }
    }
    let (first_row, end_row) = group.rows;
    let rows = end_row - first_row;
    let (longest, second) = (longest.min(rows), second.min(rows));
    // The visits where only the longest row's lane is active are summed on their own, one
    // lane's operations in place of a group's (the same bits: every width gives the scalar
    // code's): on small meshes a colour often has one vertex of many elements among few.
    let (tail, longest) = if L::WIDTH > 1 && longest > second {
        (Some(second..longest), second)
    } else {
        (None, longest)
    };
    let lengths = L::from_lane_array(lengths);
    let load = |at: usize| {
        layout
            .values
            .get(at..at + L::WIDTH)
            .and_then(|values| L::Array::try_from(values).ok())
            .map_or(L::splat(0.0), L::from_lane_array)
    };
    let mut sums = Accumulator::<L>::new();
    // Built once per group (the visitor moves vertices between groups), not once per row.
    let read = Positions::new(positions);
    // Corner positions gathered `STEPS` visits ahead, as in `sum_group` (lanes of masked
    // visits hold earlier values or vertex 0's: never used).
    for first in (0..longest).step_by(STEPS) {
        for (offset, values) in buffer.iter_mut().enumerate().take(longest - first) {
            let row = first_row + first + offset;
            let Some(read) = read else {
                break;
            };
            gather_row_corners::<L>(
                layout,
                read,
                (row, group.lane, group.vertices.len()),
                values,
            );
        }
        for (offset, values) in buffer.iter().enumerate().take(longest - first) {
            let t = first + offset;
            let base = (first_row + t) * LAYOUT_VALUES * BLOCK + group.lane;
            let value = |k: usize| load(base + k * BLOCK);
            let vector = |k: usize| LaneVec3::new(value(k), value(k + 1), value(k + 2));
            let corner = |k: usize| lane_vector::<L>(values, k);
            let visit = Visit::new(
                corner,
                vector,
                (0, layout::GRADIENT),
                value(layout::VOLUME),
                lengths.gt(L::splat(t as Real)),
            );
            sums.add(elements.material, &visit, extras);
        }
    }
    sums.write(group.vertices.len(), out);
    if let Some(tail) = tail
        && let Some(slot) = out.get_mut(last_lane)
    {
        *slot = sum_packed_tail(
            elements,
            layout,
            positions,
            (first_row, group.lane + last_lane),
            tail,
            (extras, *slot),
        );
    }
}

/// The corner positions of the visits of layout row `row` in lanes `lane..lane + count` of its
/// block (`count` at most `L::WIDTH`) into `values`, `[3 corner + axis]`, one value per lane
/// (lanes past `count` of a quarter are filled too, from the layout's zero indices: masked).
///
/// At a width of four lanes or more, four lanes at a time: each corner's four positions are
/// transposed into `[x], [y], [z]` registers (the SSE transposes of the force passes) and
/// stored a quarter at a time, where setting the twelve values of every lane one by one took
/// three stores a position (moves only either way: the same bits).
#[inline(always)]
fn gather_row_corners<L: LaneArray>(
    layout: &Layout<'_>,
    positions: Positions<'_>,
    (row, lane, count): (usize, usize, usize),
    values: &mut [L::Array; 12],
) {
    // Read without a bounds test per corner (the indices were validated).
    let position = |i: u32| positions.get(i);
    if L::WIDTH >= LANES {
        for q in 0..count.div_ceil(LANES).min(L::WIDTH / LANES) {
            for c in 0..4 {
                let at = (row * 4 + c) * BLOCK + lane + q * LANES;
                let Some(&indices) = layout
                    .corners
                    .get(at..)
                    .and_then(<[u32]>::first_chunk::<LANES>)
                else {
                    continue;
                };
                let x = LaneVec3::<Lanes>::from_vectors(each_lane(indices, position));
                for (axis, value) in [x.x, x.y, x.z].into_iter().enumerate() {
                    if let Some(array) = values.get_mut(3 * c + axis) {
                        L::store_quarter(array, q, value);
                    }
                }
            }
        }
        return;
    }
    for j in 0..count.min(L::WIDTH) {
        for c in 0..4 {
            let at = (row * 4 + c) * BLOCK + lane + j;
            let x = position(layout.corners.get(at).copied().unwrap_or(0));
            for (axis, value) in [x.x, x.y, x.z].into_iter().enumerate() {
                if let Some(array) = values.get_mut(3 * c + axis) {
                    L::set_lane_value(array, j, value);
                }
            }
        }
    }
}

/// The sums `partial` of one lane (`lane` of the layout's block whose rows start at
/// `first_row`) continued over its visits `visits`, one at a time: the operations the lane
/// group would run for that lane, in its order.
#[inline(always)]
fn sum_packed_tail<M: Material>(
    elements: &Elements<'_, M>,
    layout: &Layout<'_>,
    positions: &[Vec3],
    (first_row, lane): (usize, usize),
    visits: core::ops::Range<usize>,
    (extras, partial): (Extras, VertexSums),
) -> VertexSums {
    let h = partial.hessian;
    let mut sums = Accumulator::<Real> {
        gradient: LaneVec3::new(partial.gradient.x, partial.gradient.y, partial.gradient.z),
        hessian: [
            h.x_axis.x, h.y_axis.y, h.z_axis.z, h.x_axis.y, h.x_axis.z, h.y_axis.z,
        ],
        elastic: partial.elastic,
        resolution: partial.resolution,
    };
    for t in visits {
        let row = first_row + t;
        let base = row * LAYOUT_VALUES * BLOCK + lane;
        let value = |k: usize| layout.values.get(base + k * BLOCK).copied().unwrap_or(0.0);
        let vector = |k: usize| LaneVec3::new(value(k), value(k + 1), value(k + 2));
        let corner = |k: usize| {
            let at = (row * 4 + k / 3) * BLOCK + lane;
            let index = layout.corners.get(at).copied().unwrap_or(0);
            let x = positions.get(index as usize).copied().unwrap_or(Vec3::ZERO);
            LaneVec3::new(x.x, x.y, x.z)
        };
        let visit = Visit::new(
            corner,
            vector,
            (0, layout::GRADIENT),
            value(layout::VOLUME),
            true,
        );
        sums.add(elements.material, &visit, extras);
    }
    // What `write` gives for one lane, without its buffer of `MAX_WIDTH` sums on the stack.
    let [xx, yy, zz, xy, xz, yz] = sums.hessian;
    VertexSums {
        gradient: Vec3::new(sums.gradient.x, sums.gradient.y, sums.gradient.z),
        hessian: Mat3::from_cols(
            Vec3::new(xx, xy, xz),
            Vec3::new(xy, yy, yz),
            Vec3::new(xz, yz, zz),
        ),
        elastic: sums.elastic,
        resolution: sums.resolution,
    }
}

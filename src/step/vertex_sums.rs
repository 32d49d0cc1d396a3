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

use super::super::element::TetRest;
use super::super::lanes::{LaneArray, LaneMat3, LaneVec3, Lanes, MAX_WIDTH};
#[cfg(target_arch = "x86_64")]
use super::super::lanes_avx2::Avx2Lanes;
#[cfg(target_arch = "x86_64")]
use super::super::lanes_avx512::Avx512Lanes;
use super::super::material::Material;
use super::super::types::{Mat3, Real, Vec3};
use super::vertex_block::shape_gradient;
use crate::simd::{WidthKernel, dispatch};

/// What the elements around one vertex add to its Newton system at the current positions.
#[derive(Clone, Copy)]
pub(super) struct VertexSums {
    /// `sum_e V_e P_e g_e` (N): the elastic part of the gradient.
    pub gradient: Vec3,
    /// `sum_e V_e K_e(g_e)` (N/m): the exact elastic block.
    pub hessian: Mat3,
    /// `sum_e V_e W_e` (J), with the energy only (else 0).
    pub elastic: Real,
    /// `sum_e |V_e tr K_e| / |g_e|^2` (J), the energy scale of the elements, with the energy
    /// only (else 0).
    pub resolution: Real,
}

/// Sums of a vertex in no element.
const EMPTY: VertexSums = VertexSums {
    gradient: Vec3::ZERO,
    hessian: Mat3::ZERO,
    elastic: 0.0,
    resolution: 0.0,
};

/// The mesh a sweep visits: elements, rest data, material and vertex adjacency
/// (`adjacency.rs`).
pub(super) struct Elements<'s, M> {
    pub tets: &'s [[u32; 4]],
    pub rest: &'s [TetRest],
    pub material: &'s M,
    pub offsets: &'s [u32],
    pub incident: &'s [u32],
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

/// What receives the sums of a [`SumsPass`], vertex by vertex.
pub(super) trait VertexVisitor {
    /// The positions the next group is summed at.
    fn positions(&self) -> &[Vec3];
    /// The sums of `vertex`, entry `index` of its run.
    fn visit(&mut self, index: usize, vertex: u32, sums: &VertexSums);
}

/// One pass over runs of vertices, each run of one colour: the vertices not `skip`ped are
/// summed a lane group at a time and handed to the visitor in run order, each group after it
/// is summed whole (so the visitor may move a group's vertices, never their neighbours').
pub(super) struct SumsPass<'a, 's, M, R, V> {
    pub elements: &'a Elements<'s, M>,
    /// Vertices left out (pinned), indexed by vertex; empty for none.
    pub skip: &'a [bool],
    pub runs: R,
    /// Whether to sum the energy and its scale too.
    pub energy: bool,
    pub visitor: V,
}

/// Runs `pass` at the active SIMD width and returns its visitor.
#[inline]
pub(super) fn sum_vertices<'r, M: Material, R: Iterator<Item = &'r [u32]>, V: VertexVisitor>(
    pass: SumsPass<'_, '_, M, R, V>,
) -> V {
    dispatch(pass)
}

impl<'r, M: Material, R: Iterator<Item = &'r [u32]>, V: VertexVisitor> SumsPass<'_, '_, M, R, V> {
    /// The pass with groups of `L::WIDTH` vertices.
    #[inline(always)]
    fn run<L: LaneArray>(self) -> V {
        let SumsPass {
            elements,
            skip,
            runs,
            energy,
            mut visitor,
        } = self;
        let mut batch = [(0usize, 0u32); MAX_WIDTH];
        let mut sums = [EMPTY; MAX_WIDTH];
        for run in runs {
            let mut filled = 0;
            let mut members = run.iter().enumerate();
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
                    sum_group::<L, M>(elements, visitor.positions(), group, energy, &mut sums);
                    for (&(index, vertex), sums) in group.iter().zip(&sums) {
                        visitor.visit(index, vertex, sums);
                    }
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

impl<'r, M: Material, R: Iterator<Item = &'r [u32]>, V: VertexVisitor> WidthKernel
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

/// The sums of the vertices `group` (at most `L::WIDTH`, one colour) into `out`, in order.
#[inline(always)]
fn sum_group<L: LaneArray, M: Material>(
    elements: &Elements<'_, M>,
    positions: &[Vec3],
    group: &[(usize, u32)],
    energy: bool,
    out: &mut [VertexSums; MAX_WIDTH],
) {
    let mut rows: [&[u32]; MAX_WIDTH] = [&[]; MAX_WIDTH];
    let mut longest = 0;
    for (row, &(_, vertex)) in rows.iter_mut().zip(group).take(L::WIDTH) {
        *row = elements.row(vertex as usize);
        longest = longest.max(row.len());
    }
    let zero = L::splat(0.0);
    let mut gradient = LaneVec3::new(zero, zero, zero);
    // xx, yy, zz, xy, xz, yz.
    let mut hessian = [zero; 6];
    let (mut elastic, mut resolution) = (zero, zero);
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
            let value = |k: usize| L::from_lane_array(values.get(k).copied().unwrap_or(L::ZEROS));
            let vector = |k: usize| LaneVec3::new(value(k), value(k + 1), value(k + 2));
            // F = Ds Dm^-1 as `TetRest::deformation_gradient` forms it.
            let x0 = vector(0);
            let edges = LaneMat3 {
                c0: vector(3) - x0,
                c1: vector(6) - x0,
                c2: vector(9) - x0,
            };
            let dm_inv = LaneMat3 {
                c0: vector(12),
                c1: vector(15),
                c2: vector(18),
            };
            let f = edges * dm_inv;
            let (volume, g) = (value(VOLUME), vector(GRADIENT));
            let active = value(ACTIVE).gt(L::splat(0.0));
            let (stress, k) = elements.material.corner_stress_and_stiffness_wide(f, g);
            gradient = LaneVec3::select(active, gradient + stress.scale(volume), gradient);
            let entries = [k.c0.x, k.c1.y, k.c2.z, k.c1.x, k.c2.x, k.c2.y];
            for (sum, entry) in hessian.iter_mut().zip(entries) {
                *sum = L::select(active, *sum + entry * volume, *sum);
            }
            if energy {
                let density = elements.material.energy_density_wide(f);
                elastic = L::select(active, elastic + volume * density, elastic);
                let trace = k.c0.x + k.c1.y + k.c2.z;
                let scale = (trace * volume).abs() / g.dot(g);
                resolution = L::select(active, resolution + scale, resolution);
            }
        }
    }
    let [xx, yy, zz, xy, xz, yz] = hessian;
    // Written out rather than `<[T; N]>::map`, which is not always inlined.
    let sums = [
        gradient.x.to_lane_array(),
        gradient.y.to_lane_array(),
        gradient.z.to_lane_array(),
        xx.to_lane_array(),
        yy.to_lane_array(),
        zz.to_lane_array(),
        xy.to_lane_array(),
        xz.to_lane_array(),
        yz.to_lane_array(),
        elastic.to_lane_array(),
        resolution.to_lane_array(),
    ];
    for (lane, slot) in out.iter_mut().enumerate().take(group.len()) {
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

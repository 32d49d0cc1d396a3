//! The direct force loop over groups of [`LANES`] tetrahedra, held as [`Lanes`] (structure of
//! arrays): the same arithmetic as one element at a time, in the same order, so the forces and
//! energies are bit for bit those of the scalar loop.

use super::super::element::TetRest;
#[cfg(target_arch = "x86_64")]
use super::super::lanes::avx2::Avx2Lanes;
#[cfg(target_arch = "x86_64")]
use super::super::lanes::avx512::Avx512Lanes;
use super::super::lanes::{
    LANES, Lane, LaneArray, LaneMat3, LaneSvd3, LaneVec3, Lanes, each_lane, transpose4,
};
use super::super::material::Material;
use super::super::svd::{Svd3, svd3, svd3_of_lanes};
use super::super::types::{Mat3, Real, Vec3};
use super::rest_blocks::{BlockRun, Rests};
use super::gather;
use crate::simd::WidthKernel;

/// A group of [`LANES`] consecutive tetrahedra: vertex indices and rest data.
pub(crate) type TetGroup<'a> = (&'a [[u32; 4]; LANES], &'a [TetRest; LANES]);

/// The elements of `tets` (with their `rest` data) in whole groups of [`LANES`], in order; a
/// last partial group is left out (the caller splits it off first).
///
/// Indexing `rest` by group (rather than zipping two `chunks_exact`) keeps the loop free of the
/// division-by-chunk-size check that `Zip` of two chunk iterators carries, which the optimiser
/// cannot always remove: a panic path in a firmware build.
pub(crate) fn tet_groups<'a>(
    tets: &'a [[u32; 4]],
    rest: &'a [TetRest],
) -> impl Iterator<Item = TetGroup<'a>> {
    tets.chunks_exact(LANES)
        .enumerate()
        .filter_map(move |(group, tets)| {
            let start = group * LANES;
            let rests = rest.get(start..start + LANES)?;
            // chunks_exact and the range: always LANES long.
            Some((tets.try_into().ok()?, rests.try_into().ok()?))
        })
}

/// The deformation gradients of a group and the rest data their forces need.
pub(super) struct GroupGradients {
    /// `F = Ds Dm^-1` of every element.
    pub f: LaneMat3<Lanes>,
    dm_inv: LaneMat3<Lanes>,
    /// The rest volumes (m^3).
    pub volume: Lanes,
}

impl GroupGradients {
    /// `F` of every element of `(tets, rests)` at `positions` (indices validated by the mesh;
    /// the zero fallback only keeps the loop free of panics), as
    /// [`TetRest::deformation_gradient`] forms it.
    #[inline(always)]
    pub fn new(positions: &[Vec3], (tets, rests): TetGroup<'_>) -> Self {
        let corner = |k: usize| {
            LaneVec3::from_vectors(each_lane(*tets, |tet| {
                tet.get(k)
                    .and_then(|&i| positions.get(i as usize))
                    .copied()
                    .unwrap_or(Vec3::ZERO)
            }))
        };
        let x0 = corner(0);
        let edges = LaneMat3 {
            c0: corner(1) - x0,
            c1: corner(2) - x0,
            c2: corner(3) - x0,
        };
        let dm_inv = LaneMat3::from_matrices(&each_lane(*rests, |rest| rest.dm_inv));
        GroupGradients {
            f: edges * dm_inv,
            dm_inv,
            volume: Lanes::from_array(each_lane(*rests, |rest| rest.volume)),
        }
    }

    /// Writes the nodal forces (N) of the stresses `p` (Pa) into `out`, one entry per lane,
    /// corner by corner: the vectors [`scatter_forces_from`](Self::scatter_forces_from) adds,
    /// as [`TetRest::nodal_forces`] forms them.
    #[inline(always)]
    pub fn write_forces(&self, p: LaneMat3<Lanes>, out: &mut [[Vec3; 4]]) {
        let h = p.scale(-self.volume) * self.dm_inv.transpose();
        let corners = each_lane(
            [-(h.c0 + h.c1 + h.c2), h.c0, h.c1, h.c2],
            LaneVec3::to_vectors,
        );
        for (lane, slot) in out.iter_mut().enumerate() {
            for (value, corner) in slot.iter_mut().zip(&corners) {
                if let Some(&force) = corner.get(lane) {
                    *value = force;
                }
            }
        }
    }
}

/// The deformation gradients of a group of `L::WIDTH` consecutive tetrahedra, for a lane type of
/// any width ([`simd`](crate::simd) picks it at run time), and the rest data their forces need:
/// the arithmetic of [`GroupGradients`] (and of [`TetRest::deformation_gradient`] and
/// [`TetRest::nodal_forces`]) in the same order, so every lane gets the scalar code's bits.
pub(super) struct WideGradients<L> {
    /// `F = Ds Dm^-1` of every element.
    pub f: LaneMat3<L>,
    dm_inv: LaneMat3<L>,
    /// The rest volumes (m^3).
    pub volume: L,
}

/// The positions of a group's corners, coordinate by coordinate: `[corner][axis]`, one value per
/// lane.
pub(super) type CornerArrays<L> = [[<L as LaneArray>::Array; 3]; 4];

/// The deformed positions a grouped pass reads, at least one: read without a bounds test per
/// corner.
#[derive(Clone, Copy)]
pub(crate) struct Positions<'a> {
    /// Every position but the last.
    init: &'a [Vec3],
    /// The last position.
    last: &'a Vec3,
}

impl<'a> Positions<'a> {
    /// `all`, unless it is empty.
    #[inline(always)]
    pub(crate) fn new(all: &'a [Vec3]) -> Option<Self> {
        let (last, init) = all.split_last()?;
        Some(Positions { init, last })
    }

    /// The position of vertex `i`. An index past the end (never, for the indices the mesh
    /// validated) reads the last position. Which of the two to read is a select of addresses,
    /// not a bounds test: the loop stays free of panics and of a branch per corner wherever
    /// the compiler places the `Positions` (a clamp `all[min(i, len - 1)]` kept its bounds test
    /// in the Vertex Block Descent sweep, whose loops lost the compiler's knowledge that
    /// `len - 1 < len`).
    #[inline(always)]
    pub(crate) fn get(self, i: u32) -> Vec3 {
        *self.init.get(i as usize).unwrap_or(self.last)
    }
}

/// Elements `4 q..4 q + 4` of a group's `items` (a quarter of the group), if it has them.
#[inline(always)]
fn quarter<T>(items: &[T], q: usize) -> Option<&[T; LANES]> {
    items
        .get(q * LANES..(q + 1) * LANES)
        .and_then(|items| items.try_into().ok())
}

/// Stores the corner positions of the quarter `q` of a group, elements `tets`, into its lanes
/// of `corners` (through the SSE transposes of `GroupGradients`).
#[inline(always)]
fn store_corner_quarter<L: LaneArray>(
    positions: Positions<'_>,
    tets: &[[u32; 4]; LANES],
    q: usize,
    corners: &mut CornerArrays<L>,
) {
    for (k, corner) in corners.iter_mut().enumerate() {
        let x = LaneVec3::from_vectors(each_lane(*tets, |tet| {
            tet.get(k).map_or(Vec3::ZERO, |&i| positions.get(i))
        }));
        for (axis, value) in corner.iter_mut().zip([x.x, x.y, x.z]) {
            L::store_quarter(axis, q, value);
        }
    }
}

/// The corner positions of a group of `L::WIDTH` elements `tets`, `[corner][axis]`, one value
/// per lane, through [`store_corner_quarter`] four elements at a time.
#[inline(always)]
pub(super) fn gather_corners<L: LaneArray>(
    positions: Positions<'_>,
    tets: &[[u32; 4]],
) -> CornerArrays<L> {
    let mut corners: CornerArrays<L> = [[L::ZEROS; 3]; 4];
    for q in 0..L::WIDTH / LANES {
        if let Some(quarter_tets) = quarter(tets, q) {
            store_corner_quarter::<L>(positions, quarter_tets, q, &mut corners);
        }
    }
    corners
}

/// The lanes `4 q..4 q + 4` of one corner's coordinates `[x, y, z]` as one register per
/// element, `[x, y, z, 0]` (moves only).
#[inline(always)]
fn corner_by_element<L: LaneArray>([x, y, z]: &[L::Array; 3], q: usize) -> [Lanes; LANES] {
    transpose4([
        L::quarter(x, q),
        L::quarter(y, q),
        L::quarter(z, q),
        Lanes::splat(0.0),
    ])
}

/// Hands `add` the vector of every corner of every element of a group, `(vertex, value)`,
/// element by element and corner by corner in order (the order of the scalar loop, which
/// matters where elements share vertices); `corners[c]` holds corner `c`'s values `[x, y, z]`,
/// one lane per element of `tets`.
///
/// Four elements at a time, each corner's values are transposed into one register per element,
/// `[x, y, z, 0]`, from which an add takes x and y together and z alone: 10 instructions a
/// corner with AVX-512 where picking the three lanes out of memory one by one took 13 (the StVK
/// force pass at 105k tetrahedra ran 1.14-1.16x faster with AVX-512 and 1.06x with AVX2,
/// interleaved runs).
#[inline(always)]
pub(super) fn scatter_corners<L: LaneArray>(
    corners: &CornerArrays<L>,
    tets: &[[u32; 4]],
    mut add: impl FnMut(u32, Vec3),
) {
    let [c0, c1, c2, c3] = corners;
    for q in 0..L::WIDTH / LANES {
        let Some(quarter_tets) = quarter(tets, q) else {
            continue;
        };
        let by_element = [
            corner_by_element::<L>(c0, q),
            corner_by_element::<L>(c1, q),
            corner_by_element::<L>(c2, q),
            corner_by_element::<L>(c3, q),
        ];
        for (j, tet) in quarter_tets.iter().enumerate() {
            for (corner, &i) in by_element.iter().zip(tet) {
                if let Some(value) = corner.get(j) {
                    let [x, y, z, _] = value.to_array();
                    add(i, Vec3::new(x, y, z));
                }
            }
        }
    }
}

/// The vectors whose coordinates are the lanes `[x, y, z]`.
#[inline(always)]
fn lane_vector<L: LaneArray>([x, y, z]: [L::Array; 3]) -> LaneVec3<L> {
    LaneVec3::new(
        L::from_lane_array(x),
        L::from_lane_array(y),
        L::from_lane_array(z),
    )
}

/// The edge matrices `[x1 - x0, x2 - x0, x3 - x0]` of a group's corners.
#[inline(always)]
fn edges_of<L: LaneArray>([c0, c1, c2, c3]: CornerArrays<L>) -> LaneMat3<L> {
    let x0 = lane_vector(c0);
    LaneMat3 {
        c0: lane_vector(c1) - x0,
        c1: lane_vector(c2) - x0,
        c2: lane_vector(c3) - x0,
    }
}

impl<L: LaneArray> WideGradients<L> {
    /// `F` of the `L::WIDTH` elements `tets` (with rest data `rests`, both exactly `L::WIDTH`
    /// long) at `positions`. The indices were validated by the mesh; the fallbacks only keep
    /// the loop free of panics.
    #[inline(always)]
    pub fn new(positions: Positions<'_>, tets: &[[u32; 4]], rests: &[TetRest]) -> Self {
        // Four elements at a time through the SSE transposes of `GroupGradients`, each quarter
        // stored straight into its lanes of the wide values (no buffer of four quarters, which
        // the narrower widths would zero in full for nothing).
        let mut corners: CornerArrays<L> = [[L::ZEROS; 3]; 4];
        let mut rest_values = [L::ZEROS; 10];
        for q in 0..L::WIDTH / LANES {
            let (Some(tets), Some(rests)) = (quarter(tets, q), quarter(rests, q)) else {
                continue;
            };
            store_corner_quarter::<L>(positions, tets, q, &mut corners);
            let m = LaneMat3::from_matrices(&each_lane(*rests, |rest| rest.dm_inv));
            let volume = Lanes::from_array(each_lane(*rests, |rest| rest.volume));
            let values = [
                m.c0.x, m.c0.y, m.c0.z, m.c1.x, m.c1.y, m.c1.z, m.c2.x, m.c2.y, m.c2.z, volume,
            ];
            for (slot, value) in rest_values.iter_mut().zip(values) {
                L::store_quarter(slot, q, value);
            }
        }
        let edges = edges_of::<L>(corners);
        let [m00, m10, m20, m01, m11, m21, m02, m12, m22, volume] = rest_values;
        let dm_inv = LaneMat3 {
            c0: lane_vector([m00, m10, m20]),
            c1: lane_vector([m01, m11, m21]),
            c2: lane_vector([m02, m12, m22]),
        };
        WideGradients {
            f: edges * dm_inv,
            dm_inv,
            volume: L::from_lane_array(volume),
        }
    }

    /// As [`new`](Self::new), with the rest data given as lanes (the nine entries of `Dm^-1`,
    /// column-major, and the volume: [`TetRestBlock`](super::TetRestBlock)'s fields), so only
    /// the corners are transposed.
    #[inline(always)]
    pub fn with_rest(positions: Positions<'_>, tets: &[[u32; 4]], rest: [L; 10]) -> Self {
        let edges = edges_of::<L>(gather_corners::<L>(positions, tets));
        let [m00, m10, m20, m01, m11, m21, m02, m12, m22, volume] = rest;
        let dm_inv = LaneMat3 {
            c0: LaneVec3::new(m00, m10, m20),
            c1: LaneVec3::new(m01, m11, m21),
            c2: LaneVec3::new(m02, m12, m22),
        };
        WideGradients {
            f: edges * dm_inv,
            dm_inv,
            volume,
        }
    }

    /// Adds the nodal forces of the stresses `p` (Pa) into `forces`, element by element and
    /// corner by corner in order (the order of the scalar loop, which matters where elements
    /// share vertices), as [`TetRest::nodal_forces`] forms them. `forces` is the slice of a
    /// force buffer that starts at vertex `first` (0 for the whole buffer): corners outside it
    /// are skipped (the owner-computes pieces of a partition, `partition/owner.rs`). One bounds
    /// test per corner, whatever `first`.
    #[inline(always)]
    pub fn scatter_forces_from(
        &self,
        tets: &[[u32; 4]],
        p: LaneMat3<L>,
        forces: &mut [Vec3],
        first: usize,
    ) {
        let h = p.scale(-self.volume) * self.dm_inv.transpose();
        let arrays = |v: LaneVec3<L>| {
            [
                v.x.to_lane_array(),
                v.y.to_lane_array(),
                v.z.to_lane_array(),
            ]
        };
        let corners: CornerArrays<L> = [
            arrays(-(h.c0 + h.c1 + h.c2)),
            arrays(h.c0),
            arrays(h.c1),
            arrays(h.c2),
        ];
        scatter_corners::<L>(&corners, tets, |i, force| {
            // Below `first` the index wraps past any slice length.
            if let Some(slot) = forces.get_mut((i as usize).wrapping_sub(first)) {
                *slot += force;
            }
        });
    }
}

/// Where the groups of a run take their rest data from: the per-element records
/// (`&[TetRest]`, transposed with the corners) or the mesh's blocks ([`BlockRun`], loaded as
/// they are). Either gives the same bits.
pub(super) trait GroupRests: Copy {
    /// `F` and the rest data of the `group`-th group of `L::WIDTH` elements of the run, whose
    /// indices are `tets`; `None` past the run's end.
    fn gradients<L: LaneArray>(
        self,
        positions: Positions<'_>,
        tets: &[[u32; 4]],
        group: usize,
    ) -> Option<WideGradients<L>>;
}

impl GroupRests for &[TetRest] {
    #[inline(always)]
    fn gradients<L: LaneArray>(
        self,
        positions: Positions<'_>,
        tets: &[[u32; 4]],
        group: usize,
    ) -> Option<WideGradients<L>> {
        let rests = self.get(group * L::WIDTH..(group + 1) * L::WIDTH)?;
        Some(WideGradients::new(positions, tets, rests))
    }
}

impl GroupRests for BlockRun<'_> {
    #[inline(always)]
    fn gradients<L: LaneArray>(
        self,
        positions: Positions<'_>,
        tets: &[[u32; 4]],
        group: usize,
    ) -> Option<WideGradients<L>> {
        let rest = self.lanes::<L>(group)?;
        Some(WideGradients::with_rest(positions, tets, rest))
    }
}

/// The elements of `tets` (and `rests`, as long) in whole groups of `width`, and the rest.
#[inline(always)]
#[allow(clippy::type_complexity)]
fn split_groups<'a>(
    tets: &'a [[u32; 4]],
    rests: Rests<'a>,
    width: usize,
) -> ((&'a [[u32; 4]], Rests<'a>), (&'a [[u32; 4]], Rests<'a>)) {
    let whole = tets.len() - tets.len() % width.max(1);
    match (tets.split_at_checked(whole), rests.split_at(whole)) {
        (Some((group_tets, tail_tets)), Some((group_rests, tail_rests))) => {
            ((group_tets, group_rests), (tail_tets, tail_rests))
        }
        _ => ((&[], rests.empty()), (tets, rests)),
    }
}

/// The four interleaved partial sums of the fused energy pass (the order of `LaneSum` in
/// lanes/mod.rs): element `i < whole` adds to partial sum `i % 4`, the rest to `last`, whether it
/// comes in a group or alone.
pub(super) struct FusedEnergy {
    partial: [Real; LANES],
    last: Real,
    whole: usize,
}

impl FusedEnergy {
    /// Zero, for `n` elements.
    #[inline(always)]
    pub fn new(n: usize) -> Self {
        FusedEnergy {
            partial: [0.0; LANES],
            last: 0.0,
            whole: n - n % LANES,
        }
    }

    /// The total.
    #[inline(always)]
    pub fn total(self) -> Real {
        let [s0, s1, s2, s3] = self.partial;
        ((s0 + s1) + (s2 + s3)) + self.last
    }
}

impl EnergySink for FusedEnergy {
    /// The energy asks for no element by itself: the pass evaluates them all.
    #[inline(always)]
    fn owes(&self, _i: usize, _count: usize) -> bool {
        false
    }

    /// Adds the terms of a group of `L::WIDTH` consecutive elements, the first of them at a
    /// multiple of [`LANES`], all below `whole`: [`LANES`] at a time, in order.
    #[inline(always)]
    fn add_group<L: LaneArray>(&mut self, _i: usize, terms: L) {
        const { assert!(L::WIDTH.is_multiple_of(LANES)) };
        let values = terms.to_lane_array();
        for chunk in 0..L::WIDTH / LANES {
            for (j, partial) in self.partial.iter_mut().enumerate() {
                *partial += L::lane_value(&values, chunk * LANES + j);
            }
        }
    }

    /// Adds the term of element `i`, taken one at a time.
    #[inline(always)]
    fn add_single(&mut self, i: usize, term: Real) {
        match self.partial.get_mut(i % LANES) {
            Some(partial) if i < self.whole => *partial += term,
            _ => self.last += term,
        }
    }
}

/// Where a pass's nodal forces go: the whole force buffer (`&mut [Vec3]`), or the slice of one
/// owner piece of a partition (`partition/owner.rs`), which skips the elements that add
/// nothing to it.
pub(super) trait ForceSink {
    /// Whether no element of `tets` adds a force here, so that they need not be evaluated.
    fn skips(&self, tets: &[[u32; 4]]) -> bool;
    /// The forces (N) this sink adds into and the vertex its first entry belongs to.
    fn slots(&mut self) -> (&mut [Vec3], usize);
    /// Adds the nodal forces of the stresses `p` (Pa) of a group of elements `tets`, at the
    /// corners that are vertices of [`slots`](Self::slots).
    #[inline(always)]
    fn add_group<L: LaneArray>(
        &mut self,
        gradients: &WideGradients<L>,
        tets: &[[u32; 4]],
        p: LaneMat3<L>,
    ) {
        let (out, first) = self.slots();
        gradients.scatter_forces_from(tets, p, out, first);
    }
    /// Adds one element's nodal `forces` (N) at its `corners` that are vertices of
    /// [`slots`](Self::slots), corner by corner.
    #[inline(always)]
    fn add(&mut self, corners: &[u32; 4], forces: [Vec3; 4]) {
        let (out, first) = self.slots();
        for (&v, force) in corners.iter().zip(forces) {
            // Below `first` the index wraps past any slice length.
            if let Some(slot) = out.get_mut((v as usize).wrapping_sub(first)) {
                *slot += force;
            }
        }
    }
}

impl ForceSink for &mut [Vec3] {
    #[inline(always)]
    fn skips(&self, _tets: &[[u32; 4]]) -> bool {
        false
    }

    #[inline(always)]
    fn slots(&mut self) -> (&mut [Vec3], usize) {
        (self, 0)
    }
}

/// What a fused pass does with the elements' energies: sums them in a fixed order
/// ([`FusedEnergy`]), or writes those of one piece of a partition (`partition/owner.rs`).
pub(super) trait EnergySink {
    /// Whether any of the `count` elements from pass element `i` needs its energy here (then
    /// it is evaluated even if its forces go elsewhere).
    fn owes(&self, i: usize, count: usize) -> bool;
    /// Takes the energies `terms` (J) of the group of pass elements from `i`.
    fn add_group<L: LaneArray>(&mut self, i: usize, terms: L);
    /// Takes the energy `term` (J) of pass element `i`, evaluated alone.
    fn add_single(&mut self, i: usize, term: Real);
}

/// One pass of a mesh kernel over the elements of `(tets, rests)` at deformed `positions`, run
/// at the width [`dispatch`](crate::simd) picks: whole groups of the widest lanes first, then
/// narrower ones, then one element at a time. Every group gives the bits of the one-at-a-time
/// code, so the width changes nothing but the speed.
pub(super) struct Pass<'k, M, J> {
    pub material: &'k M,
    pub positions: &'k [Vec3],
    pub tets: &'k [[u32; 4]],
    pub rests: Rests<'k>,
    pub job: J,
}

/// What a [`Pass`] does with each group and each single element. Element indices count from
/// the start of the pass's elements (for per-element outputs and the energy order).
pub(super) trait PassJob {
    /// Whether the elements `tets`, from element `first` on, need nothing from this job, so
    /// that they need not be evaluated.
    #[inline(always)]
    fn skips(&self, _first: usize, _tets: &[[u32; 4]]) -> bool {
        false
    }
    /// The group of elements `tets` from element `first` on, with their `F` and rest data.
    fn group<L: LaneArray, M: Material>(
        &mut self,
        material: &M,
        first: usize,
        tets: &[[u32; 4]],
        gradients: &WideGradients<L>,
    );
    /// Element `i` alone, with its `corners` at deformed positions `x` (m).
    fn single<M: Material>(
        &mut self,
        material: &M,
        i: usize,
        corners: &[u32; 4],
        rest: &TetRest,
        x: [Vec3; 4],
    );
}

/// The whole groups of `L::WIDTH` elements of `tets` (from pass element `first` on) for `job`,
/// their rest data from `rests`.
#[inline(always)]
fn job_groups<L: LaneArray, M: Material, R: GroupRests>(
    job: &mut impl PassJob,
    material: &M,
    positions: &[Vec3],
    first: usize,
    tets: &[[u32; 4]],
    rests: R,
) {
    // Nothing to read without positions (never: the mesh checked their number).
    let Some(all) = Positions::new(positions) else {
        return;
    };
    for (group, tets) in tets.chunks_exact(L::WIDTH).enumerate() {
        let start = first + group * L::WIDTH;
        if job.skips(start, tets) {
            continue;
        }
        let Some(gradients) = rests.gradients::<L>(all, tets, group) else {
            continue;
        };
        job.group(material, start, tets, &gradients);
    }
}

impl<M: Material, J: PassJob> Pass<'_, M, J> {
    /// Groups of `L` and then, recursively, narrower widths: returns the elements left and the
    /// index of the first of them.
    #[inline(always)]
    fn groups_of<'t, L: LaneArray>(
        &mut self,
        first: usize,
        tets: &'t [[u32; 4]],
        rests: Rests<'t>,
    ) -> (usize, &'t [[u32; 4]], Rests<'t>) {
        let ((group_tets, group_rests), (tail_tets, tail_rests)) =
            split_groups(tets, rests, L::WIDTH);
        // The blocks where the run has them, aligned to its groups; else the records. Chosen
        // once per run, so each loop is the one of its layout alone. Unoptimised builds take
        // the records only: both loops inlined in one function overflowed a test thread's stack
        // there (the release tests check the blocks: tests/kernels/simd.rs,
        // tests/steppers/parallel.rs).
        #[cfg(not(debug_assertions))]
        if let Some(blocks) = group_rests.block_run(L::WIDTH) {
            let (material, positions) = (self.material, self.positions);
            job_groups::<L, M, _>(&mut self.job, material, positions, first, group_tets, blocks);
            return (first + group_tets.len(), tail_tets, tail_rests);
        }
        job_groups::<L, M, _>(
            &mut self.job,
            self.material,
            self.positions,
            first,
            group_tets,
            group_rests.elements,
        );
        (first + group_tets.len(), tail_tets, tail_rests)
    }

    /// The elements from `first` on one at a time.
    #[inline(always)]
    fn singles(&mut self, first: usize, tets: &[[u32; 4]], rests: Rests<'_>) {
        for (i, (corners, rest)) in (first..).zip(tets.iter().zip(rests.elements)) {
            if self.job.skips(i, core::slice::from_ref(corners)) {
                continue;
            }
            let x = gather(self.positions, corners);
            self.job.single(self.material, i, corners, rest, x);
        }
    }
}

/// The body of a [`Pass`]'s width kernel: groups of `$widest`, then (in optimised builds) of
/// each `$narrower` width in turn, then the elements left one at a time; returns the job.
///
/// Unoptimised builds run the widest lanes and then one element at a time, as the batched SVD
/// does (src/svd_batch.rs): there the inlined SVD of every lane type keeps its own stack slots,
/// and three of them in one function overflowed a test thread's stack.
macro_rules! groups_then_singles {
    ($pass:ident: $widest:ty $(, $narrower:ty)*) => {{
        let (first, tets, rests) = $pass.groups_of::<$widest>(0, $pass.tets, $pass.rests);
        $(
            #[cfg(not(debug_assertions))]
            let (first, tets, rests) = $pass.groups_of::<$narrower>(first, tets, rests);
        )*
        $pass.singles(first, tets, rests);
        $pass.job
    }};
}

impl<M: Material, J: PassJob> WidthKernel for Pass<'_, M, J> {
    type Output = J;

    #[inline(always)]
    fn scalar(mut self) -> J {
        let (tets, rests) = (self.tets, self.rests);
        self.singles(0, tets, rests);
        self.job
    }

    #[inline(always)]
    fn sse(mut self) -> J {
        groups_then_singles!(self: Lanes)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx2(mut self) -> J {
        groups_then_singles!(self: Avx2Lanes, Lanes)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx512(mut self) -> J {
        groups_then_singles!(self: Avx512Lanes, Avx2Lanes, Lanes)
    }
}

/// Adds the direct-stress forces into a [`ForceSink`].
pub(super) struct DirectForces<S>(pub S);

impl<S: ForceSink> PassJob for DirectForces<S> {
    #[inline(always)]
    fn skips(&self, _first: usize, tets: &[[u32; 4]]) -> bool {
        self.0.skips(tets)
    }

    #[inline(always)]
    fn group<L: LaneArray, M: Material>(
        &mut self,
        material: &M,
        _first: usize,
        tets: &[[u32; 4]],
        gradients: &WideGradients<L>,
    ) {
        self.0
            .add_group(gradients, tets, material.first_piola_wide(gradients.f));
    }

    #[inline(always)]
    fn single<M: Material>(
        &mut self,
        material: &M,
        _i: usize,
        corners: &[u32; 4],
        rest: &TetRest,
        x: [Vec3; 4],
    ) {
        let f = rest.deformation_gradient(x);
        self.0
            .add(corners, rest.nodal_forces(material.first_piola(f)));
    }
}

/// The fused energy and force pass: the forces into a [`ForceSink`], the energies into an
/// [`EnergySink`] (summed in [`FusedEnergy`]'s order by the sequential pass).
pub(super) struct EnergyAndForces<S, E> {
    pub forces: S,
    pub energy: E,
}

impl<S: ForceSink, E: EnergySink> PassJob for EnergyAndForces<S, E> {
    #[inline(always)]
    fn skips(&self, first: usize, tets: &[[u32; 4]]) -> bool {
        !self.energy.owes(first, tets.len()) && self.forces.skips(tets)
    }

    #[inline(always)]
    fn group<L: LaneArray, M: Material>(
        &mut self,
        material: &M,
        first: usize,
        tets: &[[u32; 4]],
        gradients: &WideGradients<L>,
    ) {
        let (density, p) = material.energy_and_first_piola_wide(gradients.f);
        self.energy.add_group(first, gradients.volume * density);
        self.forces.add_group(gradients, tets, p);
    }

    #[inline(always)]
    fn single<M: Material>(
        &mut self,
        material: &M,
        i: usize,
        corners: &[u32; 4],
        rest: &TetRest,
        x: [Vec3; 4],
    ) {
        let f = rest.deformation_gradient(x);
        let (density, stress) = material.energy_and_first_piola(f);
        self.energy.add_single(i, rest.volume * density);
        self.forces.add(corners, rest.nodal_forces(stress));
    }
}

/// The energy `V W(F)` (J) of every element, handed to `each(i, energy)` in element order.
pub(super) struct Energies<E>(pub E);

impl<E: FnMut(usize, Real)> PassJob for Energies<E> {
    #[inline(always)]
    fn group<L: LaneArray, M: Material>(
        &mut self,
        material: &M,
        first: usize,
        _tets: &[[u32; 4]],
        gradients: &WideGradients<L>,
    ) {
        let energies =
            (gradients.volume * material.energy_density_wide(gradients.f)).to_lane_array();
        for lane in 0..L::WIDTH {
            (self.0)(first + lane, L::lane_value(&energies, lane));
        }
    }

    #[inline(always)]
    fn single<M: Material>(
        &mut self,
        material: &M,
        i: usize,
        _corners: &[u32; 4],
        rest: &TetRest,
        x: [Vec3; 4],
    ) {
        (self.0)(i, rest.elastic_energy(material, x));
    }
}

/// The stress a principal-path pass forms from the SVD of `F`, for one element and, with the
/// same bits, for a group in lanes: [`PrincipalStress`] or [`ClampedStress`].
pub(super) trait SvdStress {
    /// `P` (Pa) of one element from the SVD of its `F`.
    fn stress(&self, svd: &Svd3) -> Mat3;
    /// `P` (Pa) of every lane from the SVDs of their `F`, lane by lane the bits of
    /// [`stress`](Self::stress).
    fn stress_wide<L: Lane>(&self, svd: &LaneSvd3<L>) -> LaneMat3<L>;
}

/// `U diag(dW/ds) V^T`: [`Material::first_piola_from_svd`].
pub(super) struct PrincipalStress<'m, M>(pub &'m M);

impl<M: Material> SvdStress for PrincipalStress<'_, M> {
    #[inline(always)]
    fn stress(&self, svd: &Svd3) -> Mat3 {
        self.0.first_piola_from_svd(svd)
    }

    #[inline(always)]
    fn stress_wide<L: Lane>(&self, svd: &LaneSvd3<L>) -> LaneMat3<L> {
        self.0.first_piola_from_svd_wide(svd)
    }
}

/// The stress with the stretches clamped from below at `threshold`:
/// [`Material::first_piola_clamped_from_svd`] (not an energy gradient).
pub(super) struct ClampedStress<'m, M> {
    pub material: &'m M,
    pub threshold: Real,
}

impl<M: Material> SvdStress for ClampedStress<'_, M> {
    #[inline(always)]
    fn stress(&self, svd: &Svd3) -> Mat3 {
        self.material
            .first_piola_clamped_from_svd(svd, self.threshold)
    }

    #[inline(always)]
    fn stress_wide<L: Lane>(&self, svd: &LaneSvd3<L>) -> LaneMat3<L> {
        self.material
            .first_piola_clamped_from_svd_wide(svd, self.threshold)
    }
}

/// Adds the principal-path forces (`stress` maps the SVD of `F` to `P`) into a [`ForceSink`]:
/// a group at a time, all in lanes (the SVDs by [`svd3_of_lanes`], the bits of `svd3`; the
/// stresses by [`SvdStress::stress_wide`]; the nodal forces as in the direct pass), the
/// forces added element by element in order.
pub(super) struct SvdForces<F, S> {
    pub forces: F,
    pub stress: S,
}

impl<F: ForceSink, S: SvdStress> PassJob for SvdForces<F, S> {
    #[inline(always)]
    fn skips(&self, _first: usize, tets: &[[u32; 4]]) -> bool {
        self.forces.skips(tets)
    }

    #[inline(always)]
    fn group<L: LaneArray, M: Material>(
        &mut self,
        _material: &M,
        _first: usize,
        tets: &[[u32; 4]],
        gradients: &WideGradients<L>,
    ) {
        let svd = svd3_of_lanes(&gradients.f);
        self.forces
            .add_group(gradients, tets, self.stress.stress_wide(&svd));
    }

    #[inline(always)]
    fn single<M: Material>(
        &mut self,
        _material: &M,
        _i: usize,
        corners: &[u32; 4],
        rest: &TetRest,
        x: [Vec3; 4],
    ) {
        let svd = svd3(rest.deformation_gradient(x));
        self.forces
            .add(corners, rest.nodal_forces(self.stress.stress(&svd)));
    }
}

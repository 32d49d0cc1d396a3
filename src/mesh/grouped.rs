//! The direct force loop over groups of [`LANES`] tetrahedra, held as [`Lanes`] (structure of
//! arrays): the same arithmetic as one element at a time, in the same order, so the forces and
//! energies are bit for bit those of the scalar loop.

use super::super::element::TetRest;
use super::super::lanes::{LANES, LaneMat3, LaneVec3, Lanes, each_lane};
use super::super::types::Vec3;

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
    /// corner by corner: the vectors [`scatter_forces`](Self::scatter_forces) adds, as
    /// [`TetRest::nodal_forces`] forms them.
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

    /// Adds the nodal forces of the stresses `p` (Pa) into `forces`, element by element and
    /// corner by corner in order, as [`TetRest::nodal_forces`] forms them.
    #[inline(always)]
    pub fn scatter_forces(
        &self,
        tets: &[[u32; 4]; LANES],
        p: LaneMat3<Lanes>,
        forces: &mut [Vec3],
    ) {
        let h = p.scale(-self.volume) * self.dm_inv.transpose();
        let corners = each_lane(
            [-(h.c0 + h.c1 + h.c2), h.c0, h.c1, h.c2],
            LaneVec3::to_vectors,
        );
        for (lane, tet) in tets.iter().enumerate() {
            for (corner, &i) in corners.iter().zip(tet) {
                if let (Some(slot), Some(&force)) = (forces.get_mut(i as usize), corner.get(lane)) {
                    *slot += force;
                }
            }
        }
    }
}

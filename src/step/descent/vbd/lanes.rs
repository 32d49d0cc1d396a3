//! The vertex updates of a Vertex Block Descent sweep's lane group in lanes: the common case
//! of the one-vertex update `Sweep::updated` (`sweep.rs`: no line search, no colliders, no
//! friction at the vertex, no fixed axes, a definite block, a step that stays above the
//! ground) for `L::WIDTH` vertices at once, each lane by the operations of the one-vertex
//! update in its order, so every lane's result has the one-vertex bits (`tests/kernels/simd.rs`
//! compares whole runs at every width with the scalar run). A lane outside that case is left
//! to the one-vertex update.
//!
//! Why: the one-vertex update, one call per vertex with every branch of the general case, was
//! about a fifth of a sweep's time on the vbd bench's box (10 368 tetrahedra, AVX-512), as
//! much as the summing of several element visits.

use super::super::super::super::lanes::{LaneArray, LaneVec3, MAX_WIDTH};
use super::super::super::super::material::Material;
use super::super::super::super::types::{Real, Vec3};
use super::super::super::contact::floor::Floor;
use super::super::super::vertex_pass::point::{Point, Wide};
use super::block::{LaneLdlt, PIVOT_FLOOR};
use super::sums::SummedGroup;
use super::sweep::Sweep;

/// What became of one lane of a group.
#[derive(Clone, Copy)]
pub(crate) enum LaneUpdate {
    /// Left to the one-vertex update (outside the common case, or not visited).
    Single,
    /// The vertex stays: no descent step (`skipped` counts it, as the one-vertex update
    /// does where the slope is not zero). `residual` is its term of the squared residual
    /// (0 where the residual is not summed).
    Stays { residual: Real, skipped: bool },
    /// The vertex moves to `to`.
    Moves { residual: Real, to: Vec3 },
}

/// Inputs of a group's updates, one array of lane values each.
struct Gathered<L: LaneArray> {
    x: [L::Array; 3],
    y: [L::Array; 3],
    mass: L::Array,
    external: [L::Array; 3],
    gradient: [L::Array; 3],
    /// The elastic block's xx, xy, xz, yy, yz, zz.
    hessian: [L::Array; 6],
    /// 1 in the lanes updated here, 0 in the others.
    here: L::Array,
}

/// The lanes of vector values `v`.
#[inline(always)]
fn vector<L: LaneArray>(v: &[L::Array; 3]) -> LaneVec3<L> {
    LaneVec3::new(
        L::from_lane_array(v[0]),
        L::from_lane_array(v[1]),
        L::from_lane_array(v[2]),
    )
}

/// Sets lane `j` of vector values `v` to `value`.
#[inline(always)]
fn set_vector<L: LaneArray>(v: &mut [L::Array; 3], j: usize, value: Vec3) {
    for (axis, value) in v.iter_mut().zip([value.x, value.y, value.z]) {
        L::set_lane_value(axis, j, value);
    }
}

impl<M: Material> Sweep<'_, M> {
    /// The updates of `group`'s lanes at `positions`, with their residual terms where
    /// `sum_residual` (else 0): every lane [`LaneUpdate::Single`] where the sweep itself is
    /// outside the common case (one lane, the line search, colliders).
    #[inline(always)]
    pub(crate) fn lane_updates<L: LaneArray>(
        &self,
        positions: &[Vec3],
        group: &SummedGroup<'_>,
        line_search: bool,
        sum_residual: bool,
    ) -> [LaneUpdate; MAX_WIDTH] {
        let mut updates = [LaneUpdate::Single; MAX_WIDTH];
        if L::WIDTH == 1 || line_search || !self.colliders.is_empty() {
            return updates;
        }
        let Some(gathered) = self.gather::<L>(positions, group) else {
            return updates;
        };
        let here = L::from_lane_array(gathered.here).gt(L::splat(0.0));
        let x = vector::<L>(&gathered.x);
        let y = vector::<L>(&gathered.y);
        let mass = L::from_lane_array(gathered.mass);
        let weight = mass * L::splat(self.inertia);
        let gravity = LaneVec3::<L>::splat(self.gravity);
        // (x - y) w - g m - f + sum_e V_e P_e g_e, term by term as `updated`.
        let gradient =
            (x - y).scale(weight) - gravity.scale(mass) - vector::<L>(&gathered.external)
                + vector::<L>(&gathered.gradient);
        let residual = if sum_residual {
            let floor = Floor::<Vec3>::new(self.ground.as_ref()).widened::<LaneVec3<L>>();
            let projected = floor.constrain(floor.contact(x), x, gradient, 1.0);
            projected.inner(projected).to_lane_array()
        } else {
            L::ZEROS
        };
        // The block m/h^2 I + sum_e V_e K_e as `VertexFactor::new` adds it (zeros added off the
        // diagonal too), its trace, and its factor where definite.
        let zero = L::splat(0.0);
        let h = gathered.hessian.map(L::from_lane_array);
        let lower = [
            h[0] + weight,
            h[1] + zero,
            h[2] + zero,
            h[3] + weight,
            h[4] + zero,
            h[5] + weight,
        ];
        let trace = lower[0] + lower[3] + lower[5];
        let (factor, factored) = LaneLdlt::new(lower, L::splat(PIVOT_FLOOR) * trace);
        let step = factor.solve(-gradient);
        let to = x + step;
        let above = match &self.ground {
            Some(ground) => {
                let height =
                    LaneVec3::<L>::splat(ground.normal).inner(to) - L::splat(ground.offset);
                height.ge(zero)
            }
            None => zero.ge(zero),
        };
        let finite = step.finite_zero();
        let slope = gradient.inner(step);
        // The lanes updated here: a definite block with a finite trace (`0 trace` is zero
        // exactly where it is finite), a step that stays above the ground.
        let kept = L::select(factored.gt(zero), L::splat(1.0), zero);
        let kept = L::select((trace * zero).ge(zero), kept, zero);
        let kept = L::select(above, kept, zero);
        let kept = L::select(here, kept, zero);
        let descends = L::select(zero.gt(slope), L::splat(1.0), zero);
        let descends = L::select(finite.ge(zero), descends, zero);
        let (kept, descends) = (kept.to_lane_array(), descends.to_lane_array());
        let slope = slope.to_lane_array();
        let to = [
            to.x.to_lane_array(),
            to.y.to_lane_array(),
            to.z.to_lane_array(),
        ];
        for (j, update) in updates.iter_mut().enumerate().take(L::WIDTH) {
            if L::lane_value(&kept, j) == 0.0 {
                continue;
            }
            let residual = L::lane_value(&residual, j);
            *update = if L::lane_value(&descends, j) != 0.0 {
                let at = |axis: &L::Array| L::lane_value(axis, j);
                LaneUpdate::Moves {
                    residual,
                    to: Vec3::new(at(&to[0]), at(&to[1]), at(&to[2])),
                }
            } else {
                LaneUpdate::Stays {
                    residual,
                    skipped: L::lane_value(&slope, j) != 0.0,
                }
            };
        }
        updates
    }

    /// The inputs of the group's lanes that the common case may update (a visited vertex in
    /// range with no fixed axis and no friction: out of contact, or in a frictionless one), as
    /// `updated` reads them; `None` if there is none.
    #[inline(always)]
    fn gather<L: LaneArray>(
        &self,
        positions: &[Vec3],
        group: &SummedGroup<'_>,
    ) -> Option<Gathered<L>> {
        let mut gathered = Gathered::<L> {
            x: [L::ZEROS; 3],
            y: [L::ZEROS; 3],
            mass: L::ZEROS,
            external: [L::ZEROS; 3],
            gradient: [L::ZEROS; 3],
            hessian: [L::ZEROS; 6],
            here: L::ZEROS,
        };
        let mut any = false;
        for (j, _, vertex, sums) in group.visits() {
            let i = vertex as usize;
            let Some(&x) = positions.get(i) else {
                continue;
            };
            if self.loads.fixed(i) != 0 {
                continue;
            }
            if self.contact.is_some_and(|terms| terms.touches(i)) {
                continue;
            }
            let m = self.masses.get(i).copied().unwrap_or(0.0);
            let x0 = self.start.get(i).copied().unwrap_or(x);
            if self.rough(i, x, x0).is_some() {
                continue;
            }
            let y = match self.velocities.get(i) {
                Some(&v) => x0 + v * self.h,
                None => x0,
            };
            set_vector::<L>(&mut gathered.x, j, x);
            set_vector::<L>(&mut gathered.y, j, y);
            L::set_lane_value(&mut gathered.mass, j, m);
            set_vector::<L>(&mut gathered.external, j, self.loads.force(i));
            set_vector::<L>(&mut gathered.gradient, j, sums.gradient);
            let k = sums.hessian;
            let entries = [
                k.x_axis.x, k.x_axis.y, k.x_axis.z, k.y_axis.y, k.y_axis.z, k.z_axis.z,
            ];
            for (entry, value) in gathered.hessian.iter_mut().zip(entries) {
                L::set_lane_value(entry, j, value);
            }
            L::set_lane_value(&mut gathered.here, j, 1.0);
            any = true;
        }
        any.then_some(gathered)
    }
}

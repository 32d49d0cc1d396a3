//! What a user applies to a body besides gravity, for every solver: external forces (N, one per
//! vertex) and per-axis constraints (a vertex fixed along some coordinate axes only: rollers and
//! symmetry planes). The objective of `docs/math.md` section 4 gains `- sum f_ext . (x - x_n)`
//! (a constant force is minus the gradient of a linear potential, measured from the start
//! positions as gravity's is), and the fixed coordinates are removed degrees of freedom: the gradient, every
//! step and every velocity lose those components, so a fixed coordinate keeps its bits.

use super::super::element::Vector;
use super::super::types::Real;
use super::contact::floor::Floor;
use super::state::{check_length, pinned_flags};
use crate::error::{StepBuffer, StepError};

/// Bit of a fixed-axis mask: the x coordinate is fixed.
pub const FIXED_X: u8 = 1;
/// Bit of a fixed-axis mask: the y coordinate is fixed.
pub const FIXED_Y: u8 = 2;
/// Bit of a fixed-axis mask: the z coordinate is fixed (3D only).
pub const FIXED_Z: u8 = 4;

/// The loads and partial constraints of a solve, borrowed from its settings.
#[derive(Clone, Copy)]
pub(crate) struct Loads<'a, V> {
    /// Empty or one force (N) per vertex.
    pub forces: &'a [V],
    /// Empty or one mask per vertex (bit 0 x, 1 y, 2 z).
    pub fixed_axes: &'a [u8],
    /// The fraction of `forces` applied (1 but in the load steps of Newton's continuation,
    /// `step/descent/newton/continuation.rs`; `f * 1` is `f`, bit for bit).
    pub scale: Real,
}

impl<V: Vector> Loads<'_, V> {
    /// Whether there is nothing to apply (then every solver takes its unloaded path, bit for bit).
    #[inline(always)]
    pub fn is_none(&self) -> bool {
        self.forces.is_empty() && self.fixed_axes.is_empty()
    }

    /// Checks the lengths (empty or `vertex_count`), that every force is finite and that every
    /// mask names axes of this space.
    pub fn check(&self, vertex_count: usize) -> Result<(), StepError> {
        if !self.forces.is_empty() {
            check_length(StepBuffer::ExternalForces, vertex_count, self.forces.len())?;
        }
        if !self.fixed_axes.is_empty() {
            check_length(StepBuffer::FixedAxes, vertex_count, self.fixed_axes.len())?;
        }
        if let Some(vertex) = self.forces.iter().position(|f| !f.is_finite()) {
            return Err(StepError::ExternalForce { vertex });
        }
        if let Some(vertex) = self.fixed_axes.iter().position(|&m| m & !V::ALL_AXES != 0) {
            return Err(StepError::FixedAxes { vertex });
        }
        Ok(())
    }

    /// The fixed-axis mask of vertex `i` (0 past the end).
    #[inline(always)]
    pub fn fixed(&self, i: usize) -> u8 {
        self.fixed_axes.get(i).copied().unwrap_or(0)
    }

    /// The external force on vertex `i` (zero past the end).
    #[inline(always)]
    pub fn force(&self, i: usize) -> V {
        self.forces
            .get(i)
            .map_or(V::zero(), |force| force.scale(self.scale))
    }

    /// `v` without its fixed components at vertex `i`.
    #[inline(always)]
    pub fn free_part(&self, i: usize, v: V) -> V {
        v.axes_from(V::zero(), self.fixed(i))
    }

    /// `v` with its fixed components at vertex `i` taken from `reference` (bit for bit).
    #[inline(always)]
    pub fn keep_fixed(&self, i: usize, v: V, reference: V) -> V {
        v.axes_from(reference, self.fixed(i))
    }

    /// Restores in `trial` the fixed coordinates of `from`, bit for bit, at every vertex with a
    /// fixed axis. The passes that write trial points step along a direction whose fixed
    /// components are zero, but then project the point on the ground and the colliders, which
    /// moves a vertex along the contact normal, fixed axes included (a normal that is not a
    /// coordinate axis); as everywhere else, the projection comes first and the fixed
    /// coordinates are restored after it. Nothing to do without fixed axes.
    pub fn restore_fixed(&self, from: &[V], trial: &mut [V]) {
        let rows = self.fixed_axes.iter().zip(trial.iter_mut().zip(from));
        for (&mask, (t, &x)) in rows.filter(|(mask, _)| **mask != 0) {
            *t = t.axes_from(x, mask);
        }
    }

    /// The sum `|M g + f_ext|` over the free components of the free vertices (N): the load
    /// scale of the stopping tests.
    pub fn load(&self, masses: &[Real], pinned: &[bool], gravity: V) -> Real {
        let squared: Real = masses
            .iter()
            .zip(pinned_flags(pinned))
            .enumerate()
            .filter(|(_, (_, pinned))| !pinned)
            .map(|(i, (&m, _))| {
                let load = self.free_part(i, gravity.scale(m) + self.force(i));
                load.inner(load)
            })
            .sum();
        super::super::math::sqrt(squared)
    }

    /// Adds the loads to a gradient of `Phi` at `x` that the vertex passes wrote (zero at pinned
    /// vertices): `g - f_ext` with the fixed components removed, at free vertices. Returns the
    /// loads' term of `Phi`, `- sum f_ext . (x - x_n)` (J), and the squared residual of the
    /// result projected on the contact constraints (N^2), which replaces the passes' one.
    pub fn apply(
        &self,
        floor: &Floor<V>,
        (pinned, start): (&[bool], &[V]),
        x: &[V],
        gradient: &mut [V],
    ) -> (Real, Real) {
        let (mut phi, mut residual) = (0.0, 0.0);
        let rows = gradient
            .iter_mut()
            .zip(x)
            .zip(start)
            .zip(pinned_flags(pinned));
        for (i, (((g, &x), &x0), pinned)) in rows.enumerate() {
            if pinned {
                continue;
            }
            let force = self.force(i);
            phi -= force.inner(x - x0);
            *g = self.free_part(i, *g - force);
            let projected = floor.constrain(floor.contact(x), x, *g, 1.0);
            residual += projected.inner(projected);
        }
        (phi, residual)
    }
}

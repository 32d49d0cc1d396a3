//! The ground half-space: position projection, restitution and Coulomb friction.

use super::super::math;
use super::super::types::Real;
use super::{Vector, length};
use crate::error::StepError;

/// A ground half-space: the solid side is `{x : n . x < offset}` with `n = normal / |normal|`,
/// so the ground's surface is the plane `n . x = offset` (metres along `n`) and `n` points out
/// of the ground, into the free space.
///
/// A vertex found inside the ground after a step is projected onto the plane along `n`. If it
/// was moving into the ground (`v_n = n . v < 0`), its normal velocity becomes `-e v_n`
/// (restitution `e` in `[0, 1]`: 0 stops it, 1 reflects it; impacts slower than `2 h |g|`,
/// what gravity adds in two steps, count as resting contact and do not bounce, so that a
/// resting body does not jitter), and the normal velocity change
/// `dv_n = (1 + e) |v_n|` bounds the friction: the tangential speed is reduced by
/// `min(|v_t|, friction * dv_n)` (Coulomb's law for an impulse, friction coefficient `>= 0`, no
/// distinction between static and kinetic). The position projection does no work on the
/// velocity: a resting body loses each step exactly the velocity gravity gave it.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::Ground;
///
/// // The plane y = 0, bouncy and slippery.
/// let ground = Ground::new(Vec3::Y, 0.0).with_restitution(0.5).with_friction(0.1);
/// assert_eq!(ground.restitution, 0.5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground<V> {
    /// The outward normal (need not be unit length: any non-zero finite vector, of any length
    /// the precision can represent).
    pub normal: V,
    /// The plane's signed distance from the origin along the unit normal (m).
    pub offset: Real,
    /// The restitution coefficient `e` in `[0, 1]` (dimensionless).
    pub restitution: Real,
    /// The Coulomb friction coefficient `>= 0` (dimensionless).
    pub friction: Real,
}

impl<V: Vector> Ground<V> {
    /// The plane `normal . x = offset` (normalised), without restitution or friction.
    #[inline]
    #[must_use]
    pub fn new(normal: V, offset: Real) -> Self {
        Ground {
            normal,
            offset,
            restitution: 0.0,
            friction: 0.0,
        }
    }

    /// This ground with restitution coefficient `restitution` (in `[0, 1]`).
    #[inline]
    #[must_use]
    pub fn with_restitution(self, restitution: Real) -> Self {
        Ground {
            restitution,
            ..self
        }
    }

    /// This ground with Coulomb friction coefficient `friction` (`>= 0`).
    #[inline]
    #[must_use]
    pub fn with_friction(self, friction: Real) -> Self {
        Ground { friction, ..self }
    }

    /// Checks the parameters and normalises the normal.
    pub(super) fn validated(&self) -> Result<Ground<V>, StepError> {
        // Every finite non-zero normal is valid, also one whose squared length under- or
        // overflows (`1e-30` or `1e30` in f32): it is first brought near unit length by an exact
        // power of two, `2^(3/4 MAX_EXP)` up or down, which maps both ends of the range into
        // lengths whose squares are normal numbers.
        let squared = self.normal.dot(self.normal);
        let exponent = 3 * Real::MAX_EXP / 4;
        let scale = if squared < Real::MIN_POSITIVE {
            math::pow2(exponent)
        } else if squared.is_infinite() {
            math::pow2(-exponent)
        } else {
            1.0
        };
        let normal = self.normal * scale;
        let norm = length(normal);
        if !(norm > 0.0 && norm.is_finite() && self.offset.is_finite()) {
            return Err(StepError::Ground);
        }
        if !(0.0..=1.0).contains(&self.restitution) {
            return Err(StepError::Restitution);
        }
        if !(self.friction >= 0.0 && self.friction.is_finite()) {
            return Err(StepError::Friction);
        }
        Ok(Ground {
            normal: normal * (1.0 / norm),
            ..*self
        })
    }

    /// How far `x` is above the plane (m; negative inside the ground). Needs a validated ground.
    #[inline(always)]
    pub(super) fn height(&self, x: V) -> Real {
        self.normal.dot(x) - self.offset
    }

    /// Projects `x` onto the plane if it is inside the ground, returning whether it was.
    #[inline(always)]
    pub(super) fn project(&self, x: &mut V) -> bool {
        let depth = -self.height(*x);
        if depth > 0.0 {
            *x += self.normal * depth;
            true
        } else {
            false
        }
    }

    /// Projects `x` and applies restitution and friction to `v` if `x` was inside the ground;
    /// returns whether it was. Approach speeds up to `resting_speed` (m/s) do not bounce.
    #[inline(always)]
    pub(super) fn resolve(&self, x: &mut V, v: &mut V, resting_speed: Real) -> bool {
        if !self.project(x) {
            return false;
        }
        let vn = self.normal.dot(*v);
        if vn < 0.0 {
            let restitution = math::select(-vn > resting_speed, self.restitution, 0.0);
            let normal_change = (1.0 + restitution) * -vn;
            let tangential = *v - self.normal * vn;
            *v = self.friction_applied(tangential, normal_change)
                + self.normal * (-restitution * vn);
        }
        true
    }

    /// The tangential velocity `tangential` reduced by Coulomb friction for a normal velocity
    /// change `normal_change >= 0` (m/s).
    #[inline(always)]
    pub(super) fn friction_applied(&self, tangential: V, normal_change: Real) -> V {
        let speed = length(tangential);
        let reduction = self.friction * normal_change;
        // Stops the vertex when friction can absorb all its tangential speed (also when the
        // speed is zero, where the ratio below would be 0/0).
        let keep = math::select(speed > reduction, 1.0 - reduction / speed, 0.0);
        tangential * keep
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::types::Vec3;
    use super::Ground;

    /// Restitution applies to real impacts; an approach at or below the resting speed leaves the
    /// vertex on the plane with zero normal velocity (no jitter at rest), even with restitution 1.
    #[test]
    fn slow_impacts_do_not_bounce_and_fast_ones_do() {
        let ground = Ground::new(Vec3::Z, 0.0)
            .with_restitution(1.0)
            .validated()
            .unwrap();
        let resting_speed = 0.02;

        let (mut x, mut v) = (Vec3::new(0.0, 0.0, -1e-4), Vec3::new(0.0, 0.0, -0.015));
        assert!(ground.resolve(&mut x, &mut v, resting_speed));
        assert_eq!(x.z, 0.0);
        assert_eq!(v.z, 0.0);

        let (mut x, mut v) = (Vec3::new(0.0, 0.0, -1e-4), Vec3::new(0.0, 0.0, -1.5));
        assert!(ground.resolve(&mut x, &mut v, resting_speed));
        assert_eq!(v.z, 1.5);
    }
}

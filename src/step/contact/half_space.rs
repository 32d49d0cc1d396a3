//! The half-space, the crate's one plane: the scene's ground ([`Scene::with_ground`]), with its
//! position projection, restitution and Coulomb friction. A moving or rotating plane among the
//! colliders is a [`Collider::half_space`](super::Collider::half_space) of the same shape.
//!
//! [`Scene::with_ground`]: super::super::Scene::with_ground

use super::super::super::element::Vector;
use super::super::super::math;
use super::super::super::types::Real;
use super::super::state::length;
use crate::error::StepError;

/// A half-space, used as the scene's ground: the solid side is `{x : n . x < offset}` with `n = normal / |normal|`,
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
/// distinction between static and kinetic), and the substep's move along the plane changes with
/// the velocity. The position projection does no work on the velocity: a resting body loses
/// each step exactly the velocity gravity gave it. That is the explicit stepper's contact; the
/// implicit solvers keep the projection, drop restitution and minimise friction with the step
/// (see [`sticking_speed`](Self::sticking_speed)).
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::HalfSpace;
///
/// // The plane y = 0, bouncy and slippery.
/// let ground = HalfSpace::new(Vec3::Y, 0.0).with_restitution(0.5).with_friction(0.1);
/// assert_eq!(ground.restitution, 0.5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfSpace<V> {
    /// The outward normal (need not be unit length: any non-zero finite vector, of any length
    /// the precision can represent).
    pub normal: V,
    /// The plane's signed distance from the origin along the unit normal (m).
    pub offset: Real,
    /// The restitution coefficient `e` in `[0, 1]` (dimensionless).
    pub restitution: Real,
    /// The Coulomb friction coefficient `>= 0` (dimensionless).
    pub friction: Real,
    /// The implicit solvers' sticking speed `eps_v` (m/s, finite `>= 0`; default 0, off).
    ///
    /// **0 (the default):** the implicit solvers apply Coulomb's law to the velocity after the
    /// solve, `v = (x_{n+1} - x_n) / h` with the normal impulse of the contact force. Cheap, but
    /// the positions of the step were found without friction, so a body held by friction on a
    /// slope creeps (a block on a 30 degree incline at 100 Hz, Newton: 0.33 m/s for mu 0.7).
    ///
    /// **Positive (opt-in,** [`SUGGESTED_STICKING_SPEED`](super::super::SUGGESTED_STICKING_SPEED)
    /// **to start):** friction is part of the step's objective, the lagged, smoothed Coulomb
    /// potential of Li et al. 2020 (`docs/math.md` section 4.6), and `eps_v` is the tangential
    /// speed relative to the surface below which friction acts as a stiff spring rather than
    /// the full Coulomb force `mu lambda`. A contact held by less than the Coulomb limit
    /// creeps at most this fast; smaller values stick tighter but make the step stiffer, and
    /// `eps_v h` must stay well above the rounding of the positions (in f32, `1e-3` m/s at
    /// 100 Hz is 1e-5 m, 80 ulp at 1 m). The stiffness `2 mu lambda / (eps_v h)` of a stuck
    /// contact turns that rounding into a residual floor: on a 2205-vertex slab (1 x 0.2 x 1 m,
    /// 441 vertices on the ground, mu 0.5, 60 Hz) in f32 the relaxation stalled at 0.17 N
    /// against its 0.08 N target on every step, VBD on 11 of 20 (Newton converged, and so did
    /// every solver in f64, or the relaxation in f32 with `eps_v = 1e-2` m/s). Ignored by the
    /// explicit stepper.
    pub sticking_speed: Real,
}

impl<V: Vector> HalfSpace<V> {
    /// The plane `normal . x = offset` (normalised), without restitution or friction.
    #[inline]
    #[must_use]
    pub fn new(normal: V, offset: Real) -> Self {
        HalfSpace {
            normal,
            offset,
            restitution: 0.0,
            friction: 0.0,
            sticking_speed: 0.0,
        }
    }

    /// This ground with restitution coefficient `restitution` (in `[0, 1]`).
    #[inline]
    #[must_use]
    pub fn with_restitution(self, restitution: Real) -> Self {
        HalfSpace {
            restitution,
            ..self
        }
    }

    /// This ground with Coulomb friction coefficient `friction` (`>= 0`).
    #[inline]
    #[must_use]
    pub fn with_friction(self, friction: Real) -> Self {
        HalfSpace { friction, ..self }
    }

    /// This ground with the implicit solvers' sticking speed `sticking_speed` (m/s, finite
    /// `>= 0`, positive for friction in the objective; see
    /// [`sticking_speed`](Self::sticking_speed)).
    #[inline]
    #[must_use]
    pub fn with_sticking_speed(self, sticking_speed: Real) -> Self {
        HalfSpace {
            sticking_speed,
            ..self
        }
    }

    /// Checks the parameters and normalises the normal.
    pub(crate) fn validated(&self) -> Result<HalfSpace<V>, StepError> {
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
        let speed = self.sticking_speed;
        if !(self.friction >= 0.0 && self.friction.is_finite() && speed >= 0.0 && speed.is_finite())
        {
            return Err(StepError::Friction);
        }
        Ok(HalfSpace {
            normal: normal * (1.0 / norm),
            ..*self
        })
    }

    /// How far `x` is above the plane (m; negative inside the ground). Needs a validated ground.
    #[inline(always)]
    pub(crate) fn height(&self, x: V) -> Real {
        self.normal.dot(x) - self.offset
    }

    /// Projects `x` onto the plane if it is inside the ground, returning whether it was.
    #[inline(always)]
    pub(crate) fn project(&self, x: &mut V) -> bool {
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
    ///
    /// `x` has just moved by `h v` (s, the substep): the tangential change friction makes to `v`
    /// is applied to that move too, `x += h (v_t' - v_t)`, as if the friction impulse had acted
    /// before the position update. Without it a stuck vertex would still slide by `h v_t`, the
    /// tangential velocity the substep's forces gave it, every substep: the creep at `a_t h`
    /// this stepper showed on an incline before (1 to 1.7 cm/s).
    #[inline(always)]
    pub(crate) fn resolve(&self, x: &mut V, v: &mut V, resting_speed: Real, h: Real) -> bool {
        if !self.project(x) {
            return false;
        }
        let vn = self.normal.dot(*v);
        if vn < 0.0 {
            let restitution = math::select(-vn > resting_speed, self.restitution, 0.0);
            let normal_change = (1.0 + restitution) * -vn;
            let tangential = *v - self.normal * vn;
            let kept = self.friction_applied(tangential, normal_change);
            if self.friction > 0.0 {
                *x += (kept - tangential) * h;
            }
            *v = kept + self.normal * (-restitution * vn);
        }
        true
    }

    /// Whether the implicit solvers minimise this ground's friction with the step (a positive
    /// friction coefficient and sticking speed) rather than apply it to the velocity after it.
    #[inline(always)]
    pub(crate) fn friction_in_objective(&self) -> bool {
        super::friction::in_objective(self.friction, self.sticking_speed)
    }

    /// The tangential velocity `tangential` reduced by Coulomb friction for a normal velocity
    /// change `normal_change >= 0` (m/s).
    #[inline(always)]
    pub(crate) fn friction_applied(&self, tangential: V, normal_change: Real) -> V {
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
    use super::super::super::super::types::Vec3;
    use super::HalfSpace;

    /// Restitution applies to real impacts; an approach at or below the resting speed leaves the
    /// vertex on the plane with zero normal velocity (no jitter at rest), even with restitution 1.
    #[test]
    fn slow_impacts_do_not_bounce_and_fast_ones_do() {
        let ground = HalfSpace::new(Vec3::Z, 0.0)
            .with_restitution(1.0)
            .validated()
            .unwrap();
        let resting_speed = 0.02;

        let (mut x, mut v) = (Vec3::new(0.0, 0.0, -1e-4), Vec3::new(0.0, 0.0, -0.015));
        assert!(ground.resolve(&mut x, &mut v, resting_speed, 0.01));
        assert_eq!(x.z, 0.0);
        assert_eq!(v.z, 0.0);

        let (mut x, mut v) = (Vec3::new(0.0, 0.0, -1e-4), Vec3::new(0.0, 0.0, -1.5));
        assert!(ground.resolve(&mut x, &mut v, resting_speed, 0.01));
        assert_eq!(v.z, 1.5);
    }

    /// The sticking speed is 0 (off) by default, any finite value `>= 0` is valid, and friction
    /// moves into the implicit objective only with both a positive coefficient and a positive
    /// sticking speed.
    #[test]
    fn sticking_speed_is_opt_in_and_validated() {
        use super::{Real, StepError};
        let ground = HalfSpace::new(Vec3::Z, 0.0).with_friction(0.5);
        assert_eq!(ground.sticking_speed, 0.0);
        assert!(!ground.validated().unwrap().friction_in_objective());
        let rough = ground.with_sticking_speed(1e-3).validated().unwrap();
        assert!(rough.friction_in_objective());
        let smooth = rough.with_friction(0.0);
        assert!(!smooth.friction_in_objective());
        for bad in [-1e-3, Real::NAN, Real::INFINITY] {
            let error = ground.with_sticking_speed(bad).validated().unwrap_err();
            assert_eq!(error, StepError::Friction, "{bad}");
        }
    }
}

//! What a step is given, apart from how it is solved: the time step, gravity, the ground, the
//! colliders, external forces, fixed axes and the previous step's velocities, in one
//! [`Scene`] that every stepper takes and validates the same way ([`Scene::validated`]).
//!
//! A scene borrows its per-step data (colliders, forces, masks), so it is built each frame from
//! whatever the caller holds; the solver settings ([`ExplicitSettings`](super::ExplicitSettings),
//! [`DescentSettings`](super::DescentSettings)) hold no borrowed data and can be kept in a body.

use super::super::element::Vector;
use super::super::types::Real;
use super::contact::collider::check_colliders;
use super::contact::{Collider, HalfSpace};
use super::loads::Loads;
use crate::error::StepError;

/// What one step acts on besides the body itself: the time step `dt` (s), gravity (m/s^2), an
/// optional ground, rigid colliders, external forces (N) and fixed-axis masks per vertex, and,
/// where the caller has them, the previous step's velocities (m/s).
///
/// Built with [`Scene::new`] and the `with_*` builders; every stepper checks it with
/// [`validated`](Self::validated) before it touches anything. The quasi-static solves ignore
/// `dt` and the previous velocities.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::{FIXED_X, HalfSpace, Scene};
///
/// let forces = [Vec3::ZERO, Vec3::new(0.0, -2.0, 0.0)]; // N, one per vertex
/// let rollers = [FIXED_X, 0];
/// let scene = Scene::new(1.0 / 60.0)
///     .with_gravity(Vec3::new(0.0, -9.81, 0.0))
///     .with_ground(HalfSpace::new(Vec3::Y, 0.0))
///     .with_external_forces(&forces)
///     .with_fixed_axes(&rollers);
/// assert_eq!(scene.external_forces.len(), 2);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scene<'a, V> {
    /// The time step `h` (s): finite, positive, with `1 / h^2` finite (`h >~ 1e-19` s in f32,
    /// `1e-154` s in f64), for every stepper. The explicit stepper splits it into its settings'
    /// substeps; the quasi-static solves ignore it.
    pub dt: Real,
    /// The gravitational acceleration (m/s^2), e.g. `(0, -9.81, 0)`. Finite.
    pub gravity: V,
    /// An optional ground half-space (see [`HalfSpace`]).
    pub ground: Option<HalfSpace<V>>,
    /// Rigid colliders (empty, the default, for none; 3D bodies only): projection and friction
    /// as the ground's, relative to each collider's surface velocity; see [`Collider`].
    pub colliders: &'a [Collider<'a>],
    /// External forces (N), one per vertex, or empty (the default) for none: constant loads
    /// added to gravity (tip loads, pressure lumped to vertices); the implicit objective gains
    /// `- sum f_ext . (x - x_n)`. Ignored at pinned vertices and along fixed axes. Checked
    /// finite ([`StepError::ExternalForce`]).
    pub external_forces: &'a [V],
    /// Per-vertex fixed-axis masks, one per vertex, or empty (the default) for none: bit 0
    /// ([`FIXED_X`](super::FIXED_X)) fixes x, bit 1 y, bit 2 z (3D only), for rollers and
    /// symmetry planes; `pinned` stays the way to fix all axes. A fixed coordinate keeps its
    /// bits (its velocity component is zeroed).
    pub fixed_axes: &'a [u8],
    /// The previous step's velocities `v_(n-1)` (m/s), one per vertex, or empty (the default):
    /// given, the implicit solvers' second initial guess is the adaptive one of Chen et al.
    /// (Vertex Block Descent, 2024, section 3.6) instead of `y + h^2 g`: the acceleration of
    /// the last step, projected on gravity, clamped to `[0, |g|]`. The explicit stepper and the
    /// quasi-static solves ignore them.
    pub previous_velocities: &'a [V],
}

impl<'a, V: Vector> Scene<'a, V> {
    /// A step of `dt` (s) with no gravity, ground, colliders, loads or previous velocities.
    #[inline]
    #[must_use]
    pub const fn new(dt: Real) -> Self {
        Scene {
            dt,
            gravity: V::ZERO,
            ground: None,
            colliders: &[],
            external_forces: &[],
            fixed_axes: &[],
            previous_velocities: &[],
        }
    }

    /// This scene with gravity `gravity` (m/s^2).
    #[inline]
    #[must_use]
    pub fn with_gravity(self, gravity: V) -> Self {
        Scene { gravity, ..self }
    }

    /// This scene with `ground`.
    #[inline]
    #[must_use]
    pub fn with_ground(self, ground: HalfSpace<V>) -> Self {
        Scene {
            ground: Some(ground),
            ..self
        }
    }

    /// This scene with `colliders` (see [`Collider`]; checked by the step).
    #[inline]
    #[must_use]
    pub fn with_colliders<'b>(self, colliders: &'b [Collider<'b>]) -> Scene<'b, V>
    where
        'a: 'b,
    {
        let shorter: Scene<'b, V> = self;
        Scene {
            colliders,
            ..shorter
        }
    }

    /// This scene with external forces `forces` (N, one per vertex; see
    /// [`external_forces`](Self::external_forces)).
    #[inline]
    #[must_use]
    pub fn with_external_forces<'b>(self, forces: &'b [V]) -> Scene<'b, V>
    where
        'a: 'b,
    {
        let shorter: Scene<'b, V> = self;
        Scene {
            external_forces: forces,
            ..shorter
        }
    }

    /// This scene with per-vertex fixed-axis masks `fixed_axes` (see
    /// [`fixed_axes`](Self::fixed_axes)).
    #[inline]
    #[must_use]
    pub fn with_fixed_axes<'b>(self, fixed_axes: &'b [u8]) -> Scene<'b, V>
    where
        'a: 'b,
    {
        let shorter: Scene<'b, V> = self;
        Scene {
            fixed_axes,
            ..shorter
        }
    }

    /// This scene with the previous step's velocities (m/s, one per vertex; see
    /// [`previous_velocities`](Self::previous_velocities)).
    #[inline]
    #[must_use]
    pub fn with_previous_velocities<'b>(self, previous: &'b [V]) -> Scene<'b, V>
    where
        'a: 'b,
    {
        let shorter: Scene<'b, V> = self;
        Scene {
            previous_velocities: previous,
            ..shorter
        }
    }

    /// Checks everything but the buffers' lengths (those are checked against the body by each
    /// stepper): the time step (finite, positive, with a finite `1 / dt^2`), gravity, the
    /// colliders (only 3D bodies take any) and the ground; returns the ground with a unit
    /// normal.
    ///
    /// # Errors
    /// [`StepError::TimeStep`], [`StepError::TimeStepTooSmall`], [`StepError::Gravity`],
    /// [`StepError::Collider`], [`StepError::Ground`] (and the ground's restitution and
    /// friction errors), in that order.
    pub fn validated(&self) -> Result<Option<HalfSpace<V>>, StepError> {
        check_time_step(self.dt)?;
        self.validated_static()
    }

    /// [`validated`](Self::validated) without the time step: what a quasi-static solve checks.
    ///
    /// # Errors
    /// As [`validated`](Self::validated), less the time-step errors.
    pub fn validated_static(&self) -> Result<Option<HalfSpace<V>>, StepError> {
        if !self.gravity.is_finite() {
            return Err(StepError::Gravity);
        }
        check_colliders(self.colliders, V::ALL_AXES == 0b111)?;
        self.ground.as_ref().map(HalfSpace::validated).transpose()
    }

    /// The external forces and fixed axes, as the solvers apply them.
    #[inline]
    pub(crate) fn loads(&self) -> Loads<'a, V> {
        Loads {
            forces: self.external_forces,
            fixed_axes: self.fixed_axes,
            scale: 1.0,
        }
    }
}

/// `Ok` if `dt` (s) is a time step every stepper accepts: finite and positive
/// ([`StepError::TimeStep`] otherwise) with `1 / dt^2` finite ([`StepError::TimeStepTooSmall`]
/// otherwise): the implicit objective's inertia term `m / (2 h^2) |x - y|^2` needs `1 / h^2`,
/// which overflows below about `1e-19` s in f32 and `1e-154` s in f64, where every evaluation
/// of it would be infinite. The explicit stepper takes the same range, so that every stepper
/// accepts the same steps.
///
/// # Errors
/// As above.
pub(crate) fn check_time_step(dt: Real) -> Result<(), StepError> {
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(StepError::TimeStep);
    }
    if !(1.0 / (dt * dt)).is_finite() {
        return Err(StepError::TimeStepTooSmall);
    }
    Ok(())
}

//! Rigid colliders a soft body touches: half-spaces, spheres, capsules, oriented boxes and any
//! user shape with a signed distance, each static or kinematic (moving with a linear and an
//! angular velocity), with restitution and Coulomb friction relative to the collider's surface
//! velocity.
//!
//! Every stepper treats a collider as it treats the [`HalfSpace`](super::super::HalfSpace): a vertex
//! found inside is projected onto the surface along the outward normal (the gradient of the signed
//! distance), the implicit solvers project every iterate onto the admissible set and drop the
//! gradient and direction components into the surface at the vertices in contact. Friction acts on
//! the motion *relative to the surface*, `v - (v_c + w_c x (x - p_c))`: in the explicit stepper on
//! the velocity (and the substep's move) after each substep, in the implicit solvers on the
//! velocity after the solve or, opted in with a positive
//! [`sticking_speed`](Collider::sticking_speed), inside the step's objective
//! (`step/contact/friction.rs`: the smoothed, lagged dissipation potential of Li et al. 2020).

use super::super::super::math;
use super::super::super::types::{Quat, Real, Vec3};
use super::Contact;
use crate::error::{ColliderProblem, StepError};

/// A shape given by its signed distance, for anything the built-in [`Shape`]s do not cover
/// (a terrain, a mesh's distance field, a union of primitives).
///
/// Both functions take points in the collider's own frame (the world point moved by
/// `-position` and rotated by the inverse rotation). Negative distances are inside. The gradient
/// need not have unit length (it is normalised; a zero or non-finite gradient means "no
/// direction here", and the vertex is left where it is). A vertex inside is moved by
/// `-distance` along the normalised gradient: exact for a true distance field, one Newton step
/// towards the surface for any other implicit function.
///
/// ```
/// use softfem::glam::Vec3;
/// use softfem::step::{Collider, SignedDistance};
///
/// /// A torus around the z axis: major radius 1 m, tube radius 0.25 m.
/// struct Torus;
/// impl SignedDistance for Torus {
///     fn distance(&self, x: Vec3) -> f32 {
///         let ring = (x.x * x.x + x.y * x.y).sqrt() - 1.0;
///         (ring * ring + x.z * x.z).sqrt() - 0.25
///     }
///     fn gradient(&self, x: Vec3) -> Vec3 {
///         let radial = (x.x * x.x + x.y * x.y).sqrt();
///         let ring = radial - 1.0;
///         Vec3::new(ring * x.x / radial, ring * x.y / radial, x.z)
///     }
/// }
/// let torus = Collider::custom(&Torus, Vec3::ZERO);
/// assert!((torus.distance(Vec3::new(1.0, 0.0, 0.0)) + 0.25).abs() < 1e-6);
/// ```
pub trait SignedDistance: Sync {
    /// The signed distance (m) of the local point `x` (m): negative inside.
    fn distance(&self, x: Vec3) -> Real;
    /// The gradient of [`distance`](Self::distance) at the local point `x` (outward).
    fn gradient(&self, x: Vec3) -> Vec3;
}

/// The geometry of a [`Collider`] in its own frame (m).
#[derive(Clone, Copy)]
pub enum Shape<'a> {
    /// The half-space `z < 0`: its surface is the plane `z = 0`, its outward normal `+z`.
    HalfSpace,
    /// The ball `|x| < radius`.
    Sphere {
        /// The radius (m), finite and `> 0`.
        radius: Real,
    },
    /// The points closer than `radius` to the segment from `(0, 0, -half_length)` to
    /// `(0, 0, half_length)`.
    Capsule {
        /// Half the length of the axis segment (m), finite and `> 0`.
        half_length: Real,
        /// The radius (m), finite and `> 0`.
        radius: Real,
    },
    /// The box `|x| < half_extents.x`, `|y| < half_extents.y`, `|z| < half_extents.z`.
    Cuboid {
        /// Half the edge lengths (m), each finite and `> 0`.
        half_extents: Vec3,
    },
    /// A user shape.
    Custom(&'a dyn SignedDistance),
}

impl core::fmt::Debug for Shape<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Shape::HalfSpace => f.write_str("HalfSpace"),
            Shape::Sphere { radius } => f.debug_struct("Sphere").field("radius", radius).finish(),
            Shape::Capsule {
                half_length,
                radius,
            } => f
                .debug_struct("Capsule")
                .field("half_length", half_length)
                .field("radius", radius)
                .finish(),
            Shape::Cuboid { half_extents } => f
                .debug_struct("Cuboid")
                .field("half_extents", half_extents)
                .finish(),
            Shape::Custom(_) => f.write_str("Custom(..)"),
        }
    }
}

/// Equal shapes: the same kind and dimensions; custom shapes are equal when they are the same
/// object.
impl PartialEq for Shape<'_> {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Shape::HalfSpace, Shape::HalfSpace) => true,
            (Shape::Sphere { radius: a }, Shape::Sphere { radius: b }) => a == b,
            (
                Shape::Capsule {
                    half_length: la,
                    radius: ra,
                },
                Shape::Capsule {
                    half_length: lb,
                    radius: rb,
                },
            ) => la == lb && ra == rb,
            (Shape::Cuboid { half_extents: a }, Shape::Cuboid { half_extents: b }) => a == b,
            (Shape::Custom(a), Shape::Custom(b)) => core::ptr::addr_eq(*a, *b),
            _ => false,
        }
    }
}

/// A rigid obstacle: a [`Shape`] placed by a position and a rotation, optionally moving.
///
/// * Pose: a local point `l` is at `position + rotation * l` in the world (m). The rotation is a
///   unit quaternion (checked to `1e-3`, used normalised).
/// * Motion: the velocity of the collider's material at a world point `x` is
///   `linear_velocity + angular_velocity x (x - position)` (m/s; rad/s). A step sees the
///   collider where it is (its pose does not change during a step, substeps included);
///   between steps move it with [`advanced`](Self::advanced). A static collider has zero
///   velocities.
/// * Contact: restitution `e` in `[0, 1]` and Coulomb friction `>= 0`, exactly as the
///   [`HalfSpace`](super::super::HalfSpace)'s, applied to the velocity relative to the collider's
///   surface. Restitution is applied by the explicit stepper only (implicit Euler dissipates the
///   normal velocity at an impact).
/// * Several colliders are resolved one after the other in slice order (a vertex pushed out of
///   one into the next ends outside the later one).
/// * Contact is tested at the vertices only: a collider smaller than the mesh spacing (a thin
///   capsule between two rows of vertices) can pass through a face unseen.
///
/// ```
/// use softfem::glam::{Quat, Vec3};
/// use softfem::step::Collider;
///
/// let ball = Collider::sphere(Vec3::new(0.0, 1.0, 0.0), 0.5);
/// assert!((ball.distance(Vec3::ZERO) - 0.5).abs() < 1e-6);
/// // A paddle 0.1 m x 1 m x 1 m turning about y at 1 rad/s.
/// let paddle = Collider::cuboid(Vec3::ZERO, Vec3::new(0.05, 0.5, 0.5), Quat::IDENTITY)
///     .with_velocity(Vec3::ZERO, Vec3::Y)
///     .with_friction(0.5);
/// assert!(paddle.distance(Vec3::new(0.0, 0.0, 0.5)).abs() < 1e-6); // on its edge
/// let later = paddle.advanced(core::f32::consts::FRAC_PI_2); // a quarter turn later
/// assert!((later.distance(Vec3::new(0.0, 0.0, 0.5)) - 0.45).abs() < 1e-5); // thin along z now
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collider<'a> {
    /// The geometry, in the collider's frame.
    pub shape: Shape<'a>,
    /// The origin of the collider's frame in the world (m).
    pub position: Vec3,
    /// The rotation from the collider's frame to the world (a unit quaternion).
    pub rotation: Quat,
    /// The velocity of the frame's origin (m/s).
    pub linear_velocity: Vec3,
    /// The angular velocity (rad/s, world axes).
    pub angular_velocity: Vec3,
    /// The restitution coefficient `e` in `[0, 1]` (dimensionless; explicit stepper only).
    pub restitution: Real,
    /// The Coulomb friction coefficient `>= 0` (dimensionless).
    pub friction: Real,
    /// The implicit solvers' sticking speed `eps_v` (m/s, finite `>= 0`; default 0: friction on
    /// the velocity after the solve; positive: friction in the step's objective), as the
    /// [`HalfSpace`](super::super::HalfSpace)'s [`sticking_speed`](super::super::HalfSpace::sticking_speed),
    /// relative to the collider's surface velocity.
    pub sticking_speed: Real,
    /// The mass (kg, finite `>= 0`; default 0). A collider with a positive mass is a dynamic
    /// rigid body where the step solves its motion with the soft body's
    /// ([`Body::step_with_rigid_bodies`](crate::body::Body::step_with_rigid_bodies),
    /// `docs/math.md` section 8.15): `position` is then its centre of mass. Every other step
    /// moves it as a kinematic collider, with its velocities.
    pub mass: Real,
    /// The principal moments of inertia (kg m^2) about `position`, along the collider's own
    /// axes: each finite and `> 0` for a dynamic collider (`mass > 0`), unused otherwise.
    pub inertia: Vec3,
}

/// The contact tolerance's factor: a vertex projected onto a curved surface lands within a few
/// roundings of `|x| + |position| + size` of it.
const CONTACT_EPS: Real = 64.0 * Real::EPSILON;

/// How many colliders of a list [`Colliders`] poses once per solve (the first ones, in slice
/// order): their normalised rotations, frame origins and half-space normals are formed when
/// the view is made instead of at every contact query. Later colliders are posed at a query
/// that the broad phase does not settle, with the same bits and more work. Four on a host,
/// one on bare metal (`target_os = "none"`): every cached pose adds 40 bytes (f32) to each
/// copy of the view that the solvers' passes hold, which with four cached poses cost the f32
/// relaxation 1.9 KB of stack on the Cortex-M4F, where the first collider is typically the
/// ground-like half-space every vertex is tested against. On a host the pile example's four
/// wall boxes, inside whose bounding spheres every ball vertex lies, cost 14 % less CPU
/// posed once (0.5 s of the pile: 16.3 s against 18.9 s, the same VTK frames to the byte).
const POSED: usize = if cfg!(target_os = "none") { 1 } else { 4 };

/// A collider's pose as its contact queries use it, in the coordinates of the query: the
/// normalised rotation, the frame origin (see [`Collider::frame`]), for a half-space its
/// outward normal (`rotation * z`; `+z` for other shapes, unused), and the half extents of a
/// box about the frame origin, aligned with the query's axes, that holds the shape (infinite
/// where unbounded or not formed: the poses formed at every query leave it so, as its three
/// rotations would cost more than they spare).
#[derive(Clone, Copy)]
struct Pose {
    rotation: [Real; 4],
    frame: Vec3,
    normal: Vec3,
    reach: Vec3,
}

/// The unit quaternion whose rotation takes `+z` to the unit vector `to`.
fn rotation_from_z(to: Vec3) -> Quat {
    // The half-way quaternion (1 + z.to, z x to), normalised; for `to = -z` any half turn.
    let w = 1.0 + to.z;
    if w <= Real::EPSILON {
        return Quat::from_xyzw(1.0, 0.0, 0.0, 0.0);
    }
    let (x, y) = (-to.y, to.x);
    let norm = math::sqrt(x * x + y * y + w * w);
    Quat::from_xyzw(x / norm, y / norm, 0.0, w / norm)
}

/// `v` rotated by the unit quaternion `(x, y, z, w)` = `q`, in plain scalar arithmetic (same
/// bits on every target): `v + w t + q_v x t` with `t = 2 q_v x v`.
#[inline(always)]
pub(super) fn rotate(q: [Real; 4], v: Vec3) -> Vec3 {
    let [x, y, z, w] = q;
    let axis = Vec3::new(x, y, z);
    let t = axis.cross(v) * 2.0;
    v + t * w + axis.cross(t)
}

/// `v` rotated by the inverse of the unit quaternion `q`.
#[inline(always)]
pub(super) fn rotate_back(q: [Real; 4], v: Vec3) -> Vec3 {
    let [x, y, z, w] = q;
    rotate([-x, -y, -z, w], v)
}

/// `x / |x|`, or `None` if that is not a finite unit vector.
#[inline(always)]
fn unit(x: Vec3) -> Option<Vec3> {
    let length = math::sqrt(x.dot(x));
    let unit = x * (1.0 / length);
    (length > 0.0 && unit.is_finite()).then_some(unit)
}

/// `-1` for negative `c`, else `1`.
#[inline(always)]
fn sign(c: Real) -> Real {
    if c < 0.0 { -1.0 } else { 1.0 }
}

impl<'a> Collider<'a> {
    /// `shape` at `position` (m) rotated by `rotation`, static, without restitution or friction.
    #[inline]
    #[must_use]
    pub fn new(shape: Shape<'a>, position: Vec3, rotation: Quat) -> Self {
        Collider {
            shape,
            position,
            rotation,
            linear_velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            restitution: 0.0,
            friction: 0.0,
            sticking_speed: 0.0,
            mass: 0.0,
            inertia: Vec3::ZERO,
        }
    }

    /// The half-space below the plane through `point` (m) with outward normal `normal` (any
    /// non-zero finite length; a zero or non-finite one gives a non-finite rotation, refused by
    /// the step).
    #[must_use]
    pub fn half_space(point: Vec3, normal: Vec3) -> Self {
        let rotation = match unit(normal) {
            Some(n) => rotation_from_z(n),
            None => Quat::from_xyzw(Real::NAN, 0.0, 0.0, 0.0),
        };
        Collider::new(Shape::HalfSpace, point, rotation)
    }

    /// The ball of `radius` (m) around `center` (m).
    #[inline]
    #[must_use]
    pub fn sphere(center: Vec3, radius: Real) -> Self {
        Collider::new(Shape::Sphere { radius }, center, Quat::IDENTITY)
    }

    /// The capsule of `radius` (m) around the segment from `a` to `b` (m), which must not
    /// coincide (a zero-length capsule is refused by the step: use a sphere).
    #[must_use]
    pub fn capsule(a: Vec3, b: Vec3, radius: Real) -> Self {
        let axis = b - a;
        let half_length = 0.5 * math::sqrt(axis.dot(axis));
        let rotation = unit(axis).map_or(Quat::IDENTITY, rotation_from_z);
        let shape = Shape::Capsule {
            half_length,
            radius,
        };
        Collider::new(shape, (a + b) * 0.5, rotation)
    }

    /// The box with half edge lengths `half_extents` (m) centred at `center` (m), its edges along
    /// `rotation`'s axes.
    #[inline]
    #[must_use]
    pub fn cuboid(center: Vec3, half_extents: Vec3, rotation: Quat) -> Self {
        Collider::new(Shape::Cuboid { half_extents }, center, rotation)
    }

    /// The user shape `shape` with its frame's origin at `position` (m), not rotated.
    #[inline]
    #[must_use]
    pub fn custom(shape: &'a dyn SignedDistance, position: Vec3) -> Self {
        Collider::new(Shape::Custom(shape), position, Quat::IDENTITY)
    }

    /// This collider moving with `linear` (m/s) and `angular` (rad/s) velocity.
    #[inline]
    #[must_use]
    pub fn with_velocity(self, linear: Vec3, angular: Vec3) -> Self {
        Collider {
            linear_velocity: linear,
            angular_velocity: angular,
            ..self
        }
    }

    /// This collider with restitution coefficient `restitution` (in `[0, 1]`).
    #[inline]
    #[must_use]
    pub fn with_restitution(self, restitution: Real) -> Self {
        Collider {
            restitution,
            ..self
        }
    }

    /// This collider with Coulomb friction coefficient `friction` (`>= 0`).
    #[inline]
    #[must_use]
    pub fn with_friction(self, friction: Real) -> Self {
        Collider { friction, ..self }
    }

    /// This collider as a dynamic rigid body of `mass` (kg, finite `> 0`) with the principal
    /// moments of inertia `inertia` (kg m^2, each finite `> 0`) about its position (its centre
    /// of mass) along its own axes. A solid box of half extents `(a, b, c)` has
    /// `inertia = mass / 3 (b^2 + c^2, a^2 + c^2, a^2 + b^2)`; a solid ball of radius `r`,
    /// `2/5 mass r^2` about every axis.
    ///
    /// ```
    /// use softfem::glam::{Quat, Vec3};
    /// use softfem::step::Collider;
    ///
    /// let (mass, half) = (5.0, Vec3::splat(0.1)); // kg, m
    /// let inertia = Vec3::splat(mass / 3.0 * 2.0 * 0.1 * 0.1);
    /// let crate_ = Collider::cuboid(Vec3::new(0.0, 0.5, 0.0), half, Quat::IDENTITY)
    ///     .with_mass(mass, inertia);
    /// assert!(crate_.is_dynamic() && crate_.check().is_ok());
    /// ```
    #[inline]
    #[must_use]
    pub fn with_mass(self, mass: Real, inertia: Vec3) -> Self {
        Collider {
            mass,
            inertia,
            ..self
        }
    }

    /// Whether the collider is a dynamic rigid body (a positive [`mass`](Self::mass)).
    #[inline]
    #[must_use]
    pub fn is_dynamic(&self) -> bool {
        self.mass > 0.0
    }

    /// This collider with the implicit solvers' sticking speed `sticking_speed` (m/s, finite
    /// `>= 0`; see [`HalfSpace::sticking_speed`](super::super::HalfSpace::sticking_speed)).
    #[inline]
    #[must_use]
    pub fn with_sticking_speed(self, sticking_speed: Real) -> Self {
        Collider {
            sticking_speed,
            ..self
        }
    }

    /// Whether the implicit solvers minimise this collider's friction with the step (a positive
    /// friction coefficient and sticking speed) rather than apply it to the velocity after it.
    #[inline(always)]
    pub(crate) fn friction_in_objective(&self) -> bool {
        super::friction::in_objective(self.friction, self.sticking_speed)
    }

    /// This collider `dt` (s) later: moved by `linear_velocity dt` and turned by the angle
    /// `|angular_velocity| dt` about `angular_velocity` (exactly, not to first order); the
    /// velocities are kept.
    #[must_use]
    pub fn advanced(&self, dt: Real) -> Self {
        let turn = self.angular_velocity * dt;
        let angle = math::sqrt(turn.dot(turn));
        let rotation = match unit(turn) {
            Some(axis) => {
                let (sin, cos) = math::sin_cos(0.5 * angle);
                let [x, y, z, w] = self.unit_rotation();
                let (a, s) = (axis * sin, cos);
                // The Hamilton product (s, a) (w, v): s w - a.v, s v + w a + a x v.
                let v = Vec3::new(x, y, z);
                let vector = v * s + a * w + a.cross(v);
                Quat::from_xyzw(vector.x, vector.y, vector.z, s * w - a.dot(v))
            }
            None => self.rotation,
        };
        Collider {
            position: self.position + self.linear_velocity * dt,
            rotation,
            ..*self
        }
    }

    /// The signed distance (m) of the world point `x` (m) from the surface: negative inside.
    /// NaN for a collider the step would refuse.
    #[must_use]
    pub fn distance(&self, x: Vec3) -> Real {
        self.probe(x).0
    }

    /// The velocity (m/s) of the collider's material at the world point `x` (m).
    #[inline]
    #[must_use]
    pub fn surface_velocity(&self, x: Vec3) -> Vec3 {
        self.surface_velocity_from(x, self.position)
    }

    /// [`surface_velocity`](Self::surface_velocity) at `x` in coordinates in which the
    /// collider's frame origin is at `position` (its own, or shifted by `-origin`).
    #[inline(always)]
    fn surface_velocity_from(&self, x: Vec3, position: Vec3) -> Vec3 {
        self.linear_velocity + self.angular_velocity.cross(x - position)
    }

    /// Checks the parameters (see [`ColliderProblem`]).
    ///
    /// # Errors
    /// The first problem found, in the order shape, position, rotation, velocity, restitution,
    /// friction, mass.
    pub fn check(&self) -> Result<(), ColliderProblem> {
        let positive = |r: Real| r > 0.0 && r.is_finite();
        let non_negative = |r: Real| r >= 0.0 && r.is_finite();
        let shape = match self.shape {
            Shape::HalfSpace | Shape::Custom(_) => true,
            Shape::Sphere { radius } => positive(radius),
            Shape::Capsule {
                half_length,
                radius,
            } => positive(half_length) && positive(radius),
            Shape::Cuboid { half_extents: h } => positive(h.x) && positive(h.y) && positive(h.z),
        };
        if !shape {
            return Err(ColliderProblem::Shape);
        }
        if !self.position.is_finite() {
            return Err(ColliderProblem::Position);
        }
        let q = self.rotation;
        let squared = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
        // NaN fails the test too.
        let unit_length = (squared - 1.0).abs() <= 1e-3;
        if !unit_length {
            return Err(ColliderProblem::Rotation);
        }
        if !(self.linear_velocity.is_finite() && self.angular_velocity.is_finite()) {
            return Err(ColliderProblem::Velocity);
        }
        if !(0.0..=1.0).contains(&self.restitution) {
            return Err(ColliderProblem::Restitution);
        }
        if !(self.friction >= 0.0 && self.friction.is_finite() && non_negative(self.sticking_speed))
        {
            return Err(ColliderProblem::Friction);
        }
        let i = self.inertia;
        let mass = non_negative(self.mass)
            && (self.mass == 0.0 || (positive(i.x) && positive(i.y) && positive(i.z)));
        if !mass {
            return Err(ColliderProblem::Mass);
        }
        Ok(())
    }

    /// The rotation normalised, as `[x, y, z, w]`.
    #[inline(always)]
    pub(super) fn unit_rotation(&self) -> [Real; 4] {
        let q = self.rotation;
        let norm = math::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
        let inverse = 1.0 / norm;
        [q.x * inverse, q.y * inverse, q.z * inverse, q.w * inverse]
    }

    /// The signed distance of `x` and the outward unit normal there (world frame); `None` for
    /// the normal where the shape gives no direction.
    #[inline]
    fn probe(&self, x: Vec3) -> (Real, Option<Vec3>) {
        self.probe_from(x, self.position)
    }

    /// The pose of this collider with its frame origin at `frame` (see [`Pose`]).
    #[inline]
    fn posed_at(&self, frame: Vec3) -> Pose {
        let rotation = self.unit_rotation();
        let normal = match self.shape {
            Shape::HalfSpace => rotate(rotation, Vec3::Z),
            _ => Vec3::Z,
        };
        Pose {
            rotation,
            frame,
            normal,
            reach: Vec3::splat(Real::INFINITY),
        }
    }

    /// [`posed_at`](Self::posed_at) with the pose's `reach`: the box of the bounded shapes
    /// turned into the query's axes (a sphere's radius; the capsule's turned half segment plus
    /// its radius; the box's turned edges, `|R| h`).
    #[inline]
    fn posed_with_reach(&self, frame: Vec3) -> Pose {
        let mut pose = self.posed_at(frame);
        let q = pose.rotation;
        pose.reach = match self.shape {
            Shape::HalfSpace | Shape::Custom(_) => return pose,
            Shape::Sphere { radius } => Vec3::splat(radius),
            Shape::Capsule {
                half_length,
                radius,
            } => (rotate(q, Vec3::Z) * half_length).abs() + Vec3::splat(radius),
            Shape::Cuboid { half_extents: h } => {
                (rotate(q, Vec3::X) * h.x).abs()
                    + (rotate(q, Vec3::Y) * h.y).abs()
                    + (rotate(q, Vec3::Z) * h.z).abs()
            }
        };
        pose
    }

    /// Where the collider's frame origin lies in coordinates shifted by `-origin` (m), for its
    /// geometry: `position - origin`, except for a half-space, whose frame origin may be any
    /// point of its plane: there the point of the plane nearest `origin` (shifted), so that the
    /// difference a query takes, `x - frame`, is as small as the shifted `x` and keeps its
    /// digits (`position - origin` can be metres long when the plane passes through the world
    /// origin and the body slides far along it). The plane moves by the rounding of that point
    /// only, once per solve (a few ulp of `|position - origin|` along the normal). `origin`
    /// zero: `position`, bit for bit.
    #[inline]
    fn frame(&self, origin: Vec3) -> Vec3 {
        if origin == Vec3::ZERO {
            return self.position;
        }
        let relative = self.position - origin;
        match self.shape {
            Shape::HalfSpace => {
                let normal = rotate(self.unit_rotation(), Vec3::Z);
                normal * normal.dot(relative)
            }
            _ => relative,
        }
    }

    /// [`probe`](Self::probe) with the collider's frame origin at `frame` (see
    /// [`frame`](Self::frame)).
    #[inline]
    fn probe_from(&self, x: Vec3, frame: Vec3) -> (Real, Option<Vec3>) {
        self.probe_posed(x, &self.posed_at(frame))
    }

    /// [`probe`](Self::probe) with the collider posed by `pose`.
    #[inline]
    fn probe_posed(&self, x: Vec3, pose: &Pose) -> (Real, Option<Vec3>) {
        let q = pose.rotation;
        let local = rotate_back(q, x - pose.frame);
        let (distance, gradient) = match self.shape {
            // The normal `rotate(q, z)`, formed with the pose.
            Shape::HalfSpace => return (local.z, Some(pose.normal)),
            Shape::Sphere { radius } => {
                let r = math::sqrt(local.dot(local));
                (r - radius, Some(unit(local).unwrap_or(Vec3::Z)))
            }
            Shape::Capsule {
                half_length,
                radius,
            } => {
                // max then min, not `clamp`, which has a panic path for bounds the optimiser cannot
                // order.
                let axis = Vec3::new(0.0, 0.0, local.z.max(-half_length).min(half_length));
                let off = local - axis;
                let r = math::sqrt(off.dot(off));
                (r - radius, Some(unit(off).unwrap_or(Vec3::X)))
            }
            Shape::Cuboid { half_extents } => cuboid_distance(local, half_extents),
            Shape::Custom(shape) => (shape.distance(local), unit(shape.gradient(local))),
        };
        (distance, gradient.map(|g| rotate(q, g)))
    }

    /// A size of the shape (m) for the contact tolerance.
    #[inline(always)]
    fn size(&self) -> Real {
        match self.shape {
            Shape::HalfSpace | Shape::Custom(_) => 0.0,
            Shape::Sphere { radius } => radius,
            Shape::Capsule {
                half_length,
                radius,
            } => half_length + radius,
            Shape::Cuboid { half_extents: h } => h.x + h.y + h.z,
        }
    }

    /// The contact tolerance at `x` (m): `64 eps (|x|_1 + |frame|_1 + size)`.
    #[inline(always)]
    fn tolerance(&self, x: Vec3, frame: Vec3) -> Real {
        let l1 = |v: Vec3| v.x.abs() + v.y.abs() + v.z.abs();
        CONTACT_EPS * (l1(x) + l1(frame) + self.size())
    }

    /// Whether `x` is certainly farther than `margin` (m, `>= 0`) outside a bounded shape (a
    /// sphere, capsule or box), from its distance to the frame origin alone: the broad phase
    /// that spares the rotations and square roots of [`probe_from`](Self::probe_from) for the
    /// many vertices nowhere near a collider. `false` for a half-space or a user shape (no
    /// bound), for a non-finite `x` and whenever it cannot be sure.
    ///
    /// Every point of a bounded shape lies within `size` of its frame origin (the radius; half
    /// the length plus the radius; the box's `|h|_1 >= |h|`), so the signed distance of a point
    /// `r = |x - frame|` away is at least `r - size` (for the box, by the triangle inequality
    /// through the nearest point of the box). `probe_from` computes that distance after a
    /// rotation and a square root, within a relative `1e-5` of `r` even in f32; the test asks
    /// for `r >= 1.01 (size + margin)` (compared squared), so the computed distance exceeds
    /// `margin` by about `0.01 size` and the answers that skip `probe_from` are its own:
    /// not touching, not inside (`broad_phase_answers_as_the_exact_probe` checks it at the
    /// bound).
    #[inline(always)]
    fn certainly_outside(&self, x: Vec3, frame: Vec3, margin: Real) -> bool {
        let size = match self.shape {
            Shape::HalfSpace | Shape::Custom(_) => return false,
            _ => self.size(),
        };
        let p = x - frame;
        let bound = 1.01 * (size + margin);
        p.dot(p) > bound * bound
    }

    /// Whether `x` is certainly farther than `margin` (m, `>= 0`) outside the shape, from the
    /// box of `pose.reach` about its frame origin: the test that settles the vertices near a
    /// large shape's frame origin (a wall's) but away from the shape, where the sphere of
    /// [`certainly_outside`](Self::certainly_outside) cannot. The shape lies in the box, so
    /// its distance from `x` is at least how far `x` lies beyond the box along any axis; the
    /// test asks for `1.01 margin + size / 100` beyond it, far above the rounding of the box
    /// and of the exact probe (`broad_phase_answers_as_the_exact_probe` checks it next to a
    /// turned box's faces, edges and corners). `false` for an infinite reach or a NaN `x`.
    #[inline(always)]
    fn outside_reach(&self, x: Vec3, pose: &Pose, margin: Real) -> bool {
        let beyond = (x - pose.frame).abs() - pose.reach;
        beyond.max_element() > 1.01 * margin + 0.01 * self.size()
    }

    /// The signed distance of `x` from a half-space posed by `pose`: the local `z`, exactly as
    /// [`probe_posed`](Self::probe_posed) forms it, without its call and its match.
    #[inline(always)]
    fn half_space_distance(x: Vec3, pose: &Pose) -> Real {
        rotate_back(pose.rotation, x - pose.frame).z
    }

    /// The outward normal at `x` if `x` touches the surface within rounding of the projection
    /// (signed distance at most `64 eps (|x|_1 + |frame|_1 + size)`), the collider posed by
    /// `pose` (see [`Pose`]).
    #[inline(always)]
    fn touching(&self, x: Vec3, pose: &Pose) -> Option<Vec3> {
        let tolerance = self.tolerance(x, pose.frame);
        if let Shape::HalfSpace = self.shape {
            let distance = Self::half_space_distance(x, pose);
            return (distance <= tolerance).then_some(pose.normal);
        }
        if self.certainly_outside(x, pose.frame, tolerance)
            || self.outside_reach(x, pose, tolerance)
        {
            return None;
        }
        let (distance, normal) = self.probe_posed(x, pose);
        if distance <= tolerance { normal } else { None }
    }

    /// `x` moved onto the surface along the normal if it is inside, the collider posed by
    /// `pose` (see [`Pose`]); whether it was.
    #[inline(always)]
    fn push_out(&self, x: &mut Vec3, pose: &Pose) -> bool {
        if let Shape::HalfSpace = self.shape {
            let distance = Self::half_space_distance(*x, pose);
            if distance < 0.0 {
                *x -= pose.normal * distance;
            }
            return distance < 0.0;
        }
        if self.certainly_outside(*x, pose.frame, 0.0) || self.outside_reach(*x, pose, 0.0) {
            return false;
        }
        let (distance, normal) = self.probe_posed(*x, pose);
        match normal {
            Some(normal) if distance < 0.0 => {
                *x -= normal * distance;
                true
            }
            _ => false,
        }
    }
}

/// The signed distance of the local point `p` from the box of `half` extents and its outward
/// unit normal (the nearest face's inside).
#[inline]
fn cuboid_distance(p: Vec3, half: Vec3) -> (Real, Option<Vec3>) {
    let excess = p.abs() - half;
    let outside = excess.max(Vec3::ZERO);
    if excess.x > 0.0 || excess.y > 0.0 || excess.z > 0.0 {
        let distance = math::sqrt(outside.dot(outside));
        let direction = Vec3::new(
            outside.x * sign(p.x),
            outside.y * sign(p.y),
            outside.z * sign(p.z),
        );
        return (distance, unit(direction));
    }
    // Inside: the nearest face is the one with the largest (least negative) excess; ties go to
    // x, then y.
    let (distance, normal) = if excess.x >= excess.y && excess.x >= excess.z {
        (excess.x, Vec3::new(sign(p.x), 0.0, 0.0))
    } else if excess.y >= excess.z {
        (excess.y, Vec3::new(0.0, sign(p.y), 0.0))
    } else {
        (excess.z, Vec3::new(0.0, 0.0, sign(p.z)))
    };
    (distance, Some(normal))
}

/// Checks every collider; `three_d` is false for 2D bodies, which take none.
pub(crate) fn check_colliders(colliders: &[Collider<'_>], three_d: bool) -> Result<(), StepError> {
    for (collider, c) in colliders.iter().enumerate() {
        let problem = if three_d {
            c.check().err()
        } else {
            Some(ColliderProblem::Dimension)
        };
        if let Some(problem) = problem {
            return Err(StepError::Collider { collider, problem });
        }
    }
    Ok(())
}

/// The validated colliders as a solve sees them: in its coordinates, shifted by `-origin`
/// (the reference point the descent loop iterates next to, `descent/mod.rs`; zero for world
/// coordinates). Every contact query here takes a point in those coordinates and answers in
/// them: the geometry is queried relative to the collider's frame origin shifted with the
/// point (see [`Collider::frame`]), so a body far from the world origin is tested with the
/// digits of its shifted coordinates, and the surface velocity is unchanged (it depends on
/// `x - position` only). With a zero origin every query is bit for bit the world one.
#[derive(Clone, Copy)]
pub struct Colliders<'a> {
    list: &'a [Collider<'a>],
    origin: Vec3,
    /// The poses of the first [`POSED`] colliders in these coordinates.
    poses: [Pose; POSED],
}

impl<'a> Colliders<'a> {
    /// `list` in world coordinates.
    #[inline(always)]
    pub fn new(list: &'a [Collider<'a>]) -> Self {
        Colliders::posed(list, Vec3::ZERO)
    }

    /// These colliders seen from coordinates shifted by `-origin` (m).
    #[inline]
    #[must_use]
    pub fn shifted(self, origin: Vec3) -> Self {
        Colliders::posed(self.list, origin)
    }

    /// `list` seen from coordinates shifted by `-origin`, the first [`POSED`] posed.
    #[inline]
    fn posed(list: &'a [Collider<'a>], origin: Vec3) -> Self {
        let unused = Pose {
            rotation: [0.0, 0.0, 0.0, 1.0],
            frame: Vec3::ZERO,
            normal: Vec3::Z,
            reach: Vec3::splat(Real::INFINITY),
        };
        let mut poses = [unused; POSED];
        for (pose, collider) in poses.iter_mut().zip(list) {
            *pose = collider.posed_with_reach(collider.frame(origin));
        }
        Colliders {
            list,
            origin,
            poses,
        }
    }

    /// Whether the broad phase settles, before posing it, that `x` is farther than `margin`
    /// (the contact tolerance where `tolerance`, else 0) outside `collider`, the `index`-th of
    /// the list, when its pose is not cached: a bounded shape's frame origin needs no rotation.
    /// The collider's own query would run the same test on the same frame origin.
    #[inline(always)]
    fn settled_outside(
        &self,
        index: usize,
        collider: &Collider<'_>,
        x: Vec3,
        tolerance: bool,
    ) -> bool {
        if index < POSED || matches!(collider.shape, Shape::HalfSpace | Shape::Custom(_)) {
            return false;
        }
        let frame = collider.frame(self.origin);
        let margin = if tolerance {
            collider.tolerance(x, frame)
        } else {
            0.0
        };
        collider.certainly_outside(x, frame, margin)
    }

    /// The pose of `collider`, the `index`-th of the list: its cached one, or one formed now
    /// in `slot`.
    #[inline(always)]
    fn pose<'p>(
        &'p self,
        index: usize,
        collider: &Collider<'_>,
        slot: &'p mut Option<Pose>,
    ) -> &'p Pose {
        match self.poses.get(index) {
            Some(pose) => pose,
            None => slot.insert(collider.posed_at(collider.frame(self.origin))),
        }
    }

    /// Whether there are none.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The colliders, in slice order.
    #[inline(always)]
    pub fn iter(&self) -> core::slice::Iter<'a, Collider<'a>> {
        self.list.iter()
    }

    /// `x` pushed out of every collider, in order.
    #[inline]
    pub fn pushed_out(&self, x: Vec3) -> Vec3 {
        let mut x = x;
        for (index, collider) in self.list.iter().enumerate() {
            if self.settled_outside(index, collider, x, false) {
                continue;
            }
            let mut slot = None;
            collider.push_out(&mut x, self.pose(index, collider, &mut slot));
        }
        x
    }

    /// The first collider `x` touches and its outward normal there.
    #[inline]
    pub fn touching(&self, x: Vec3) -> Option<(&'a Collider<'a>, Vec3)> {
        let (index, normal) = self.touching_index(x)?;
        Some((self.list.get(index)?, normal))
    }

    /// The index in the list of the first collider `x` touches, and its outward normal there.
    #[inline]
    pub fn touching_index(&self, x: Vec3) -> Option<(usize, Vec3)> {
        for (index, c) in self.list.iter().enumerate() {
            if self.settled_outside(index, c, x, true) {
                continue;
            }
            let mut slot = None;
            if let Some(normal) = c.touching(x, self.pose(index, c, &mut slot)) {
                return Some((index, normal));
            }
        }
        None
    }

    /// The velocity of `collider`'s material at `x` (m/s).
    #[inline(always)]
    fn surface_velocity(&self, collider: &Collider<'_>, x: Vec3) -> Vec3 {
        collider.surface_velocity_from(x, collider.position - self.origin)
    }

    /// `v` without its component into the first collider `x` touches: `sign` +1 for a gradient
    /// (whose descent is `-v`), -1 for a direction.
    #[inline]
    pub fn constrained(&self, x: Vec3, v: Vec3, sign: Real) -> Vec3 {
        match self.touching(x) {
            Some((_, normal)) => {
                let along = normal.dot(v);
                if along * sign > 0.0 {
                    v - normal * along
                } else {
                    v
                }
            }
            None => v,
        }
    }
}

/// The tangential velocity `tangential` (m/s) reduced by Coulomb friction: by
/// `min(|tangential|, reduction)`.
#[inline(always)]
fn coulomb(tangential: Vec3, reduction: Real) -> Vec3 {
    let speed = math::sqrt(tangential.dot(tangential));
    // Stops the vertex when friction can absorb all its tangential speed (also at zero speed,
    // where the ratio below would be 0/0).
    let keep = math::select(speed > reduction, 1.0 - reduction / speed, 0.0);
    tangential * keep
}

/// The explicit stepper's contact response at one vertex: pushed out of every collider it is
/// inside, in order, and for each the velocity relative to the surface gets restitution (for
/// approaches faster than `resting_speed`, m/s) and Coulomb friction as at the ground, whose
/// tangential change also corrects the substep's move `h v` (`h` in s, see `HalfSpace::resolve`).
/// Returns the number of colliders the vertex was inside.
#[inline]
pub(crate) fn resolve(
    colliders: &[Collider<'_>],
    x: &mut Vec3,
    v: &mut Vec3,
    (resting_speed, h): (Real, Real),
) -> usize {
    let mut contacts = 0;
    for collider in colliders {
        // World coordinates: the collider's own frame origin. The broad phase first: posing
        // takes a square root and a division (`push_out` would run the same test).
        if collider.certainly_outside(*x, collider.position, 0.0) {
            continue;
        }
        let pose = collider.posed_at(collider.position);
        if !collider.push_out(x, &pose) {
            continue;
        }
        contacts += 1;
        let Some(normal) = collider.probe(*x).1 else {
            continue;
        };
        let surface = collider.surface_velocity(*x);
        let relative = *v - surface;
        let vn = normal.dot(relative);
        if vn < 0.0 {
            let restitution = math::select(-vn > resting_speed, collider.restitution, 0.0);
            let normal_change = (1.0 + restitution) * -vn;
            let tangential = relative - normal * vn;
            let kept = coulomb(tangential, collider.friction * normal_change);
            *v = surface + kept + normal * (-restitution * vn);
            if collider.friction > 0.0 {
                // Along the tangent plane: back onto a curved surface by the projection.
                *x += (kept - tangential) * h;
                collider.push_out(x, &pose);
            }
        }
    }
    contacts
}

impl Colliders<'_> {
    /// The implicit solvers' velocity at a vertex at `x` touching a collider, after
    /// `v = (x_{n+1} - x_n) / h`: relative to the surface, the normal approach removed and,
    /// unless the collider's friction was part of the step's objective (a positive
    /// [`sticking_speed`](Collider::sticking_speed), `step/contact/friction.rs`), Coulomb friction
    /// with the normal impulse `h R` (`R` the reaction: the normal component of the gradient `g` of
    /// `Phi`, N; `m` the mass, kg). `v` unchanged away from every collider.
    #[inline]
    pub fn implicit_velocity(&self, (x, g, m, h): (Vec3, Vec3, Real, Real), v: Vec3) -> Vec3 {
        let Some((collider, normal)) = self.touching(x) else {
            return v;
        };
        let surface = self.surface_velocity(collider, x);
        let relative = v - surface;
        let along = normal.dot(relative);
        let reaction = normal.dot(g).max(0.0);
        let normal_change = h * reaction / m + (-along).max(0.0);
        let tangential = relative - normal * along;
        let friction = if collider.friction_in_objective() {
            0.0
        } else {
            collider.friction
        };
        surface + coulomb(tangential, friction * normal_change) + normal * along.max(0.0)
    }

    /// The first collider the move from `x` to `target` ends inside, as a plane for a local
    /// step: the signed distance of `x` (m) and the outward normal there (at `target` where `x`
    /// gives none). `None` if `target` is inside none.
    #[inline]
    pub fn entered(&self, x: Vec3, target: Vec3) -> Option<(Real, Vec3)> {
        self.list.iter().enumerate().find_map(|(index, c)| {
            if self.settled_outside(index, c, target, false) {
                return None;
            }
            let mut slot = None;
            let pose = self.pose(index, c, &mut slot);
            if c.certainly_outside(target, pose.frame, 0.0) || c.outside_reach(target, pose, 0.0) {
                return None;
            }
            let (inside, normal_inside) = c.probe_posed(target, pose);
            if inside >= 0.0 {
                return None;
            }
            let (distance, normal) = c.probe_posed(x, pose);
            Some((distance, normal.or(normal_inside)?))
        })
    }

    /// The friction data of the first collider `x` touches: its normal there, its surface
    /// velocity, friction coefficient and sticking speed.
    #[inline]
    pub fn contact(&self, x: Vec3) -> Option<Contact<Vec3>> {
        self.touching(x).map(|(collider, normal)| Contact {
            normal,
            surface_velocity: self.surface_velocity(collider, x),
            friction: collider.friction,
            sticking_speed: collider.sticking_speed,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::super::math::sqrt;
    use super::super::super::super::types::{Quat, Real, Vec3};
    use super::{Collider, Colliders, SignedDistance};
    use crate::error::ColliderProblem;

    /// Distances of each shape at points whose answer is known by hand.
    #[test]
    fn distances_of_every_shape_match_closed_forms() {
        let close = |a: Real, b: Real| (a - b).abs() < 1e-5;
        let plane = Collider::half_space(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, 2.0));
        assert!(close(plane.distance(Vec3::new(3.0, -4.0, 1.5)), 0.5));
        let tilted = Collider::half_space(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0));
        assert!(close(tilted.distance(Vec3::new(1.0, 0.0, 0.0)), sqrt(0.5)));
        let ball = Collider::sphere(Vec3::new(1.0, 2.0, 3.0), 0.5);
        assert!(close(ball.distance(Vec3::new(1.0, 2.0, 5.0)), 1.5));
        assert!(close(ball.distance(Vec3::new(1.0, 2.0, 3.0)), -0.5));
        let capsule = Collider::capsule(Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), 0.25);
        assert!(close(capsule.distance(Vec3::new(1.0, 1.0, 0.0)), 0.75));
        assert!(close(capsule.distance(Vec3::new(3.0, 0.0, 0.0)), 0.75));
        assert!(close(capsule.distance(Vec3::new(-1.0, 0.0, 0.0)), 0.75));
        let turned = Quat::from_rotation_z(core::f32::consts::FRAC_PI_4 as Real);
        let cube = Collider::cuboid(Vec3::ZERO, Vec3::splat(1.0), turned);
        // The corner (1, 1, 0) of the unrotated cube now lies on the y axis at sqrt(2).
        assert!(close(
            cube.distance(Vec3::new(0.0, 3.0, 0.0)),
            3.0 - sqrt(2.0)
        ));
        assert!(close(cube.distance(Vec3::new(0.0, 0.0, 0.25)), -0.75));
        assert!(close(cube.distance(Vec3::new(0.0, 0.0, 3.0)), 2.0));
    }

    /// A point inside each shape is moved onto its surface (distance 0 within rounding).
    #[test]
    fn projection_lands_on_the_surface() {
        struct Ball;
        impl SignedDistance for Ball {
            fn distance(&self, x: Vec3) -> Real {
                x.length() - 1.0
            }
            fn gradient(&self, x: Vec3) -> Vec3 {
                x * 3.0
            }
        }
        let turned = Quat::from_rotation_x(0.3);
        let shapes = [
            Collider::half_space(Vec3::ZERO, Vec3::new(0.0, 1.0, 1.0)),
            Collider::sphere(Vec3::ONE, 1.0),
            Collider::capsule(Vec3::ZERO, Vec3::new(0.0, 1.0, 1.0), 0.5),
            Collider::cuboid(Vec3::ONE, Vec3::new(0.5, 1.0, 2.0), turned),
            Collider::custom(&Ball, Vec3::ZERO),
        ];
        for (k, shape) in shapes.iter().enumerate() {
            let inside = shape.position + Vec3::new(0.1, -0.2, -0.15);
            assert!(shape.distance(inside) < 0.0, "shape {k}");
            let out = Colliders::new(core::slice::from_ref(shape)).pushed_out(inside);
            assert!(shape.distance(out).abs() < 1e-5, "shape {k}");
            assert!(
                shape
                    .touching(out, &shape.posed_at(shape.position))
                    .is_some(),
                "shape {k}"
            );
        }
    }

    /// Every parameter out of range is named.
    #[test]
    fn checks_name_the_problem() {
        let ball = Collider::sphere(Vec3::ZERO, 1.0);
        assert_eq!(ball.check(), Ok(()));
        let cases = [
            (
                Collider::sphere(Vec3::ZERO, Real::NAN),
                ColliderProblem::Shape,
            ),
            (
                Collider::capsule(Vec3::ONE, Vec3::ONE, 1.0),
                ColliderProblem::Shape,
            ),
            (
                Collider::sphere(Vec3::splat(Real::INFINITY), 1.0),
                ColliderProblem::Position,
            ),
            (
                Collider::cuboid(Vec3::ZERO, Vec3::ONE, Quat::from_xyzw(0.0, 0.0, 0.0, 2.0)),
                ColliderProblem::Rotation,
            ),
            (
                Collider::half_space(Vec3::ZERO, Vec3::ZERO),
                ColliderProblem::Rotation,
            ),
            (
                ball.with_velocity(Vec3::ZERO, Vec3::splat(Real::NAN)),
                ColliderProblem::Velocity,
            ),
            (ball.with_restitution(1.5), ColliderProblem::Restitution),
            (ball.with_friction(-0.1), ColliderProblem::Friction),
        ];
        for (collider, problem) in cases {
            assert_eq!(collider.check(), Err(problem));
        }
    }

    /// `advanced` turns by the exact angle: a quarter turn about z takes x to y.
    #[test]
    fn advancing_turns_by_the_exact_angle() {
        let spun = Collider::cuboid(Vec3::ZERO, Vec3::new(2.0, 0.5, 0.5), Quat::IDENTITY)
            .with_velocity(Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0));
        let later = spun.advanced(core::f32::consts::FRAC_PI_4 as Real);
        // Now centred at (pi/4, 0, 0) with its long axis along y.
        let centre = Vec3::new(core::f32::consts::FRAC_PI_4 as Real, 0.0, 0.0);
        assert!((later.distance(centre + Vec3::new(0.0, 2.5, 0.0)) - 0.5).abs() < 1e-5);
        assert!((later.distance(centre + Vec3::new(2.5, 0.0, 0.0)) - 2.0).abs() < 1e-5);
        assert!(
            (later.surface_velocity(centre + Vec3::new(0.0, 1.0, 0.0)) - Vec3::new(-1.0, 0.0, 0.0))
                .length()
                < 1e-6
        );
    }

    /// The broad phase never changes an answer: at points on rays from every bounded shape's
    /// frame origin, just past and well past its bound and inside it, wherever
    /// `certainly_outside` holds the exact probe finds the point farther than the margin
    /// (with room to spare: a hundredth of the shape's size, less rounding), so `touching`,
    /// `push_out` and `entered` answer as without it; and the test does skip points (the
    /// shapes 8 m out, turned, as in `far_shapes`, and at the origin).
    #[test]
    fn broad_phase_answers_as_the_exact_probe() {
        let (far_list, far) = far_shapes();
        let turned = Quat::from_rotation_y(1.1) * Quat::from_rotation_x(-0.4);
        let near_list = [
            Collider::sphere(Vec3::ZERO, 1e-3),
            Collider::capsule(Vec3::new(-2.0, 0.0, 0.0), Vec3::new(2.0, 0.5, 0.0), 0.05),
            Collider::cuboid(Vec3::new(0.1, 0.2, 0.3), Vec3::new(3.0, 0.01, 0.2), turned),
        ];
        let mut seed = 0x2545_f491_u32;
        let mut unit_random = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as Real / (1u32 << 24) as Real * 2.0 - 1.0
        };
        let (mut skipped, mut probed) = (0, 0);
        for c in far_list[1..].iter().chain(near_list.iter()) {
            let frame = c.position;
            let size = c.size();
            for _ in 0..200 {
                let direction = Vec3::new(unit_random(), unit_random(), unit_random());
                let Some(direction) = super::unit(direction) else {
                    continue;
                };
                for factor in [
                    0.5, 0.98, 0.99, 0.9995, 1.0, 1.0099, 1.0101, 1.0105, 1.02, 2.0, 1e3,
                ] {
                    let x = frame + direction * (1.01 * size * factor);
                    let tolerance = c.tolerance(x, frame);
                    let (distance, _) = c.probe_from(x, frame);
                    for margin in [0.0, tolerance] {
                        if c.certainly_outside(x, frame, margin) {
                            skipped += 1;
                            assert!(
                                distance > margin + 0.009 * size,
                                "{:?} at {x}: {distance:e} against {margin:e}",
                                c.shape
                            );
                        } else {
                            probed += 1;
                        }
                    }
                    let exact = (distance <= tolerance)
                        .then_some(())
                        .and(c.probe_from(x, frame).1);
                    let pose = c.posed_with_reach(frame);
                    assert_eq!(c.touching(x, &pose), exact);
                    let mut pushed = x;
                    assert_eq!(c.push_out(&mut pushed, &pose), distance < 0.0);
                }
            }
        }
        assert!(skipped > 1000 && probed > 1000, "{skipped} {probed}");
        // Unbounded shapes are always probed; so is a non-finite point.
        let plane = far_list[0];
        assert!(!plane.certainly_outside(far * 100.0, Vec3::ZERO, 0.0));
        let ball = far_list[1];
        assert!(!ball.certainly_outside(Vec3::NAN, ball.position, 0.0));
    }

    /// The box of a cached pose's reach never changes an answer either: next to a turned
    /// box's faces, edges and corners (local points on the box grown by a hundredth of its
    /// size and the tolerance, scaled by factors around 1), wherever `outside_reach` holds the
    /// exact probe finds the point farther than the margin, and `touching`, `push_out` and
    /// `entered` answer as with the reach unknown; and it does settle points the sphere test
    /// cannot (a thin wall's).
    #[test]
    fn reach_box_answers_as_the_exact_probe() {
        let turned = Quat::from_rotation_z(0.3) * Quat::from_rotation_x(-0.7);
        let walls = [
            Collider::cuboid(Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.01, 0.5, 0.2), turned),
            Collider::cuboid(
                Vec3::new(-1.0, 0.0, 2.0),
                Vec3::new(0.3, 0.3, 0.01),
                Quat::IDENTITY,
            ),
            Collider::capsule(Vec3::new(-2.0, 0.0, 0.0), Vec3::new(2.0, 0.5, 0.0), 0.05),
        ];
        let mut seed = 0x1234_5678_u32;
        let mut unit_random = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as Real / (1u32 << 24) as Real * 2.0 - 1.0
        };
        let (mut settled, mut sphere_settled) = (0, 0);
        for c in &walls {
            let frame = c.position;
            let (cached, unknown) = (c.posed_with_reach(frame), c.posed_at(frame));
            let size = c.size();
            let grown = cached.reach + Vec3::splat(0.0101 * size);
            for _ in 0..400 {
                let corner = Vec3::new(unit_random(), unit_random(), unit_random());
                // Pushed onto the grown box's surface along its largest coordinate, then scaled.
                let axis = corner.abs().max_element();
                for factor in [0.9, 0.999, 1.0, 1.001, 1.01, 1.05, 1.5] {
                    let x = frame + corner / axis * grown * factor;
                    let tolerance = c.tolerance(x, frame);
                    let (distance, _) = c.probe_posed(x, &unknown);
                    for margin in [0.0, tolerance] {
                        if c.outside_reach(x, &cached, margin) {
                            settled += 1;
                            sphere_settled += usize::from(c.certainly_outside(x, frame, margin));
                            assert!(
                                distance > margin + 0.009 * size,
                                "{:?} at {x}: {distance:e} against {margin:e}",
                                c.shape
                            );
                        }
                    }
                    assert_eq!(c.touching(x, &cached), c.touching(x, &unknown));
                    let (mut a, mut b) = (x, x);
                    assert_eq!(c.push_out(&mut a, &cached), c.push_out(&mut b, &unknown));
                    assert_eq!(a, b);
                }
            }
        }
        assert!(
            settled > 1000 && sphere_settled < settled / 2,
            "{settled} {sphere_settled}"
        );
    }

    /// The poses cached for the first [`POSED`](super::super::POSED) colliders and those formed at
    /// every query for the rest give the answers of the collider-by-collider probe: a list of
    /// ten (the four far shapes twice, then two more), shifted, at points inside and next to
    /// each, against loops that pose every collider at the query.
    #[test]
    fn cached_and_per_query_poses_answer_as_the_probe() {
        let (shapes, far) = far_shapes();
        let extra = [
            Collider::sphere(far + Vec3::new(3.0, 0.0, 0.0), 0.5),
            Collider::cuboid(
                far - Vec3::new(3.0, 0.0, 0.0),
                Vec3::splat(0.4),
                Quat::IDENTITY,
            ),
        ];
        let mut list = [extra[0]; 10];
        for (k, c) in shapes.iter().chain(&shapes).chain(&extra).enumerate() {
            list[k] = *c;
        }
        let origin = far + Vec3::new(0.25, 0.5, -0.125);
        let view = Colliders::new(&list).shifted(origin);
        let pose = |c: &Collider<'_>| c.posed_at(c.frame(origin));
        let mut touched = 0;
        for c in &list[1..] {
            for offset in [Vec3::new(0.01, -0.02, 0.015), Vec3::new(0.3, 0.45, -0.2)] {
                let x = c.position + offset - origin;
                let mut expected = x;
                for d in &list {
                    d.push_out(&mut expected, &pose(d));
                }
                assert_eq!(view.pushed_out(x), expected);
                for y in [x, expected] {
                    let first = list.iter().find_map(|d| d.touching(y, &pose(d)));
                    assert_eq!(view.touching(y).map(|(_, n)| n), first);
                    touched += usize::from(first.is_some());
                }
                let target = x - Vec3::Z;
                let entered = list.iter().find_map(|d| {
                    let (inside, normal_inside) = d.probe_posed(target, &pose(d));
                    let (distance, normal) = d.probe_posed(x, &pose(d));
                    (inside < 0.0).then(|| (distance, normal.or(normal_inside).unwrap()))
                });
                assert_eq!(view.entered(x, target), entered);
            }
        }
        assert!(touched >= 9, "{touched}");
    }

    /// Shapes placed 8 m from the origin, kinematic (turning at 2 rad/s), at points next to
    /// their surfaces.
    fn far_shapes() -> ([Collider<'static>; 4], Vec3) {
        let far = Vec3::new(6.0, -5.0, 2.5);
        let turned = Quat::from_rotation_x(0.3);
        let spin = |c: Collider<'static>| {
            c.with_velocity(Vec3::new(0.5, 0.0, -0.25), Vec3::new(0.0, 2.0, 1.0))
        };
        let shapes = [
            spin(Collider::half_space(Vec3::ZERO, Vec3::new(0.3, 1.0, 0.2))),
            spin(Collider::sphere(far + Vec3::new(0.0, -1.0, 0.0), 0.9)),
            spin(Collider::capsule(far, far + Vec3::new(0.0, 0.5, 0.5), 0.3)),
            spin(Collider::cuboid(far, Vec3::new(0.5, 1.0, 0.2), turned)),
        ];
        (shapes, far)
    }

    /// The shifted view answers as the world one: a point inside pushed out lands at the same
    /// place (to the rounding of world coordinates 8 m out), on the same contact with the same
    /// normal and surface velocity (the kinematic collider's motion is unchanged by the
    /// shift), for every shape; a zero origin gives the world answers bit for bit.
    #[test]
    fn shifted_colliders_answer_as_in_the_world() {
        let (shapes, far) = far_shapes();
        let close = |a: Vec3, b: Vec3, scale: Real| {
            (a - b).abs().max_element() <= 64.0 * Real::EPSILON * scale
        };
        for (k, shape) in shapes.iter().enumerate() {
            let list = core::slice::from_ref(shape);
            let world = Colliders::new(list);
            // Nearest the body: the reference point a solve would take is one of its vertices.
            let inside = if k == 0 {
                far - shape.rotation
                    * Vec3::Z
                    * (far - shape.position).dot(shape.rotation * Vec3::Z)
                    - shape.rotation * Vec3::Z * 0.01
            } else {
                shape.position + Vec3::new(0.05, -0.1, 0.02)
            };
            assert!(shape.distance(inside) < 0.0, "shape {k}");
            let origin = inside + Vec3::new(0.125, 0.25, -0.125);
            let view = world.shifted(origin);
            let out = world.pushed_out(inside);
            let shifted_out = view.pushed_out(inside - origin);
            assert!(
                close(shifted_out + origin, out, 8.0),
                "shape {k}: {shifted_out} {out}"
            );
            let (a, b) = (
                world.contact(out).unwrap(),
                view.contact(shifted_out).unwrap(),
            );
            assert!(close(a.normal, b.normal, 8.0), "shape {k}");
            assert!(
                close(a.surface_velocity, b.surface_velocity, 8.0 * 3.0),
                "shape {k}"
            );
            assert_eq!(a.friction, b.friction);
            // The surface velocity is the collider's motion at the world point.
            let expected =
                shape.linear_velocity + shape.angular_velocity.cross(out - shape.position);
            assert!(close(b.surface_velocity, expected, 8.0 * 3.0), "shape {k}");
            // Zero origin: the world's bits.
            let zero = world.shifted(Vec3::ZERO);
            assert_eq!(zero.pushed_out(inside), out);
            assert_eq!(
                zero.contact(out).map(|c| c.surface_velocity),
                Some(a.surface_velocity)
            );
        }
    }

    /// The point of the shift: next to a body 8 m out on a tilted half-space through the world
    /// origin, the shifted view resolves a move of one `eps` m along the normal (the distance
    /// changes by it within 1 %), where world coordinates (ulp of 8 m: `8 eps`) cannot; the
    /// half-space's frame is re-anchored next to the body for this (measured from its own
    /// frame origin the difference would be 8 m long and lose those digits).
    #[test]
    fn a_shifted_half_space_resolves_moves_below_the_ulp_of_world_coordinates() {
        let (shapes, far) = far_shapes();
        let plane = shapes[0];
        let normal = plane.rotation * Vec3::Z;
        let on_plane = far - normal * (far - plane.position).dot(normal);
        let view = Colliders::new(core::slice::from_ref(&plane)).shifted(on_plane);
        let step = Real::EPSILON;
        for (k, x) in [Vec3::new(1e-4, 2e-4, -3e-4), Vec3::new(-1e-3, 5e-4, 2e-3)]
            .into_iter()
            .enumerate()
        {
            let deep = |x: Vec3| view.entered(x, x - normal).unwrap();
            let (d0, n0) = deep(x);
            let (d1, _) = deep(x + normal * step);
            assert!(
                ((d1 - d0) / step - 1.0).abs() < 0.01,
                "point {k}: {d0:e} -> {d1:e}"
            );
            assert!((n0 - normal).length() < 1e-6, "point {k}");
        }
        // In world coordinates the same move is below the resolution of the point itself.
        let world = on_plane + Vec3::new(1e-4, 2e-4, -3e-4);
        assert_eq!(world + normal * step, world);
    }
}

//! Coulomb friction inside the objective of the implicit solvers (`docs/math.md` section 4.6):
//! the lagged, smoothed dissipation potential of the friction model of Li et al., "Incremental
//! Potential Contact" (SIGGRAPH 2020). Opt-in per contact: it applies to the ground and the
//! colliders whose sticking speed is positive (the others get Coulomb's law on the velocity
//! after the solve, `descent/objective.rs`).
//!
//! At a vertex in contact (with the ground, or else with the first collider it touches) with
//! outward unit normal `n`, the tangential displacement over the step relative to the surface is
//! `u = (I - n n^T) (x - x_n - h v_s)`, `v_s` the surface's velocity there. The step's
//! objective gains `D = mu lambda f0(|u|)` with `lambda >= 0` the normal force (N); the contact
//! and `lambda` are lagged to the iterate a line search starts from and re-lagged to every
//! accepted point (`descent/objective.rs`), and `f0` is the C1 smoothing of `|u|` with
//! the threshold `eps = eps_v h` (m), `eps_v` the contact's
//! [`sticking_speed`](super::super::HalfSpace::sticking_speed) (m/s):
//!
//! * `f0(y) = y^2 / eps - y^3 / (3 eps^2)` for `y < eps`, `y - eps / 3` beyond (so `f0(0) = 0`),
//! * `f1(y) = f0'(y) = 2 y / eps - y^2 / eps^2` for `y < eps`, `1` beyond.
//!
//! The friction force `-grad D = -mu lambda f1(|u|) u / |u|` has the magnitude `mu lambda`
//! of Coulomb's law once the vertex slips faster than `eps_v` relative to the surface, and
//! below that grows from zero like a stiff spring: a vertex held by a tangential load `F`
//! below `mu lambda` settles at the slip `y` with `f1(y) = F / (mu lambda)`, a creep speed
//! `y / h = eps_v (1 - sqrt(1 - F / (mu lambda)))`, at most `eps_v`.
//!
//! The Hessian in the tangent plane is `mu lambda [(f1/y) (T - u_hat u_hat^T) + f1'(y) u_hat
//! u_hat^T]` with `T = I - n n^T`; both curvatures are non-negative (`f1' = 2/eps - 2y/eps^2`
//! below `eps`, 0 beyond), so the block is positive semi-definite without projection, and its
//! largest eigenvalue is `mu lambda f1(y)/y <= 2 mu lambda / eps`. Newton's method takes the
//! isotropic `mu lambda (f1/y) T` instead where its descent shortens the slip
//! ([`Slip::newton_hessian`]).

use super::super::super::element::Vector;
use super::super::super::math;
use super::super::super::types::{Mat3, Real, Vec3};
use super::super::vertex_pass::point::Grouped;
use super::collider::{Collider, Colliders};
use super::floor::Floor;
use super::vertex::collider_contact;
use super::{Contact, HalfSpace};

/// A [`sticking_speed`](super::super::HalfSpace::sticking_speed) `eps_v` to start from (m/s): a stuck
/// contact creeps at most this fast (IPC's default, 1 mm/s). Friction in the implicit
/// objective is opt-in: the default sticking speed is 0 (Coulomb's law on the velocity after
/// the solve, which lets a loaded contact creep, see the field's documentation).
pub const SUGGESTED_STICKING_SPEED: Real = 1e-3;

/// Whether a contact with Coulomb coefficient `friction` and sticking speed `sticking_speed`
/// (m/s) has its friction in the implicit objective (both positive) rather than on the velocity
/// after the solve: the one test behind `HalfSpace`'s, `Collider`'s and [`Contact`]'s.
#[inline(always)]
pub(crate) fn in_objective(friction: Real, sticking_speed: Real) -> bool {
    friction > 0.0 && sticking_speed > 0.0
}

/// The slip of one contact over a step: the tangential displacement `u`, its length `y` and the
/// threshold `eps = eps_v h`, with the smoothing functions of the module documentation per unit
/// of `mu lambda`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slip<V> {
    /// The contact's unit normal.
    normal: V,
    /// `u = T (x - x_n - h v_s)` (m).
    tangential: V,
    /// `|u|` (m).
    length: Real,
    /// `eps_v h` (m).
    threshold: Real,
}

impl<V: Vector> Slip<V> {
    /// The slip of a vertex moved from `start` to `x` over a step `h` at `contact`; `None` if
    /// the threshold is not a positive finite length.
    #[inline]
    pub fn new(contact: &Contact<V>, x: V, start: V, h: Real) -> Option<Self> {
        let threshold = contact.sticking_speed * h;
        if !(threshold > 0.0 && threshold.is_finite()) {
            return None;
        }
        let moved = x - start - contact.surface_velocity * h;
        let tangential = moved - contact.normal * contact.normal.dot(moved);
        Some(Slip {
            normal: contact.normal,
            tangential,
            length: math::sqrt(tangential.dot(tangential)),
            threshold,
        })
    }

    /// `f0(|u|)` (m): `D / (mu lambda)`.
    #[inline]
    pub fn potential(&self) -> Real {
        let (y, eps) = (self.length, self.threshold);
        if y < eps {
            y * y / eps - y * y * y / (3.0 * eps * eps)
        } else {
            y - eps / 3.0
        }
    }

    /// `f1(|u|) / |u|` (1/m): the tangent curvature across the slip, the largest eigenvalue of
    /// the tangent block per unit of `mu lambda`.
    #[inline]
    pub fn curvature(&self) -> Real {
        let (y, eps) = (self.length, self.threshold);
        if y < eps {
            2.0 / eps - y / (eps * eps)
        } else {
            1.0 / y
        }
    }

    /// The contact's unit normal.
    #[inline]
    pub fn normal(&self) -> V {
        self.normal
    }

    /// `f1(|u|) u / |u|` (dimensionless): `grad D / (mu lambda)`.
    #[inline]
    pub fn gradient(&self) -> V {
        self.tangential * self.curvature()
    }
}

impl Slip<Vec3> {
    /// The Hessian of `f0(|u|)` in the tangent plane (1/m): `(f1/y) (T - u_hat u_hat^T) +
    /// f1'(y) u_hat u_hat^T`, positive semi-definite.
    #[inline]
    pub fn hessian(&self) -> Mat3 {
        let n = self.normal;
        let across = self.curvature();
        let tangent_plane = Mat3::IDENTITY - outer(n, n);
        let (y, eps) = (self.length, self.threshold);
        // f1' - f1/y: -y/eps^2 below the threshold, -1/y beyond; times u_hat u_hat^T =
        // u u^T / y^2.
        let along_minus_across = if y < eps {
            -1.0 / (eps * eps * y)
        } else {
            -1.0 / (y * y * y)
        };
        let slip = if y > 0.0 && along_minus_across.is_finite() {
            outer(self.tangential, self.tangential) * along_minus_across
        } else {
            Mat3::ZERO
        };
        tangent_plane * across + slip
    }

    /// The curvature of `f0(|u|)` Newton's method takes at a vertex where the gradient of
    /// `Phi` is `g` (1/m): the exact [`hessian`](Self::hessian) where the descent `-g`
    /// lengthens the slip (`g.u <= 0`), and the isotropic `(f1/y) T` where it shortens it.
    ///
    /// Beyond the threshold the exact curvature along the slip is `f1' = 0`, so the Newton
    /// model of a vertex that friction decelerates has only inertia and elasticity along the
    /// slip and overshoots into the sticking zone, where the curvature is up to `2/eps`: the
    /// line search then cuts the whole step, on every iteration of a landing. `(f1/y) T`
    /// majorises `f0(|u|)` in the tangent plane (`f1(y)/y` does not increase with `y`, so `f0`
    /// is a concave function of `y^2`: the bound behind Weiszfeld's iteration), and the model
    /// never promises a decrease the friction term does not deliver. Both are positive
    /// semi-definite.
    #[inline]
    pub fn newton_hessian(&self, g: Vec3) -> Mat3 {
        if self.tangential.dot(g) > 0.0 {
            let n = self.normal;
            (Mat3::IDENTITY - outer(n, n)) * self.curvature()
        } else {
            self.hessian()
        }
    }
}

/// `a b^T`.
#[inline(always)]
fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The normal force `max(0, n . g)` (N) a gradient `g` of `Phi` presses into a contact with
/// unit normal `n` (0 for NaN).
#[inline(always)]
pub(crate) fn normal_force<V: Vector>(normal: V, gradient: V) -> Real {
    let pressing = normal.dot(gradient);
    if pressing > 0.0 { pressing } else { 0.0 }
}

/// The frictional contacts of a solve: the ground (shifted into the loop's coordinates, with a
/// unit normal) and the colliders, for a step of `h`.
#[derive(Clone, Copy)]
pub(crate) struct Friction<'a, V: Grouped> {
    floor: Floor<'a, V>,
    ground: Option<HalfSpace<V>>,
    h: Real,
    active: bool,
}

impl<V: Grouped> Friction<'_, V> {
    /// Whether any contact of this solve has friction (else nothing here applies, and every
    /// solver keeps its frictionless path bit for bit).
    #[inline(always)]
    pub fn is_active(&self) -> bool {
        self.active
    }
}

impl<'a, V: Grouped + Vector> Friction<'a, V> {
    /// The friction of a step of `h` (0 for the quasi-static mode, which has none) on `ground`
    /// (unit normal) and the validated `colliders`, both in the solve's coordinates.
    pub fn new(ground: Option<&HalfSpace<V>>, colliders: Colliders<'a>, h: Real) -> Self {
        let rough_ground = ground.is_some_and(HalfSpace::friction_in_objective);
        let rough_collider = colliders.iter().any(Collider::friction_in_objective);
        Friction {
            floor: Floor::new(ground).with_colliders(colliders),
            ground: ground.copied(),
            h,
            active: h > 0.0 && (rough_ground || rough_collider),
        }
    }

    /// The contact at a vertex at `x`: the ground if `x` touches it, else the first collider it
    /// touches; `None` without contact or friction. Inlined into every pass over the vertices,
    /// most of which are in no contact: those take the ground's height test only.
    #[inline(always)]
    pub fn contact(&self, x: V) -> Option<Contact<V>> {
        if !self.active {
            return None;
        }
        if let (Some(ground), Some(true)) = (&self.ground, self.floor.contact(x)) {
            return ground.friction_in_objective().then_some(Contact {
                normal: ground.normal,
                surface_velocity: V::ZERO,
                friction: ground.friction,
                sticking_speed: ground.sticking_speed,
            });
        }
        let colliders = self.floor.colliders();
        if colliders.is_empty() {
            return None;
        }
        collider_contact(colliders, x)
            .filter(|contact| in_objective(contact.friction, contact.sticking_speed))
    }

    /// The slip at a vertex moved from `start` to `x` and the force factor `mu lambda` (N),
    /// with the contact and the normal force `lambda` lagged to the vertex at `lagged_x` with
    /// gradient `lagged` (its contact normal, surface velocity and coefficients; `lambda` the
    /// normal force of `lagged` there). `None` without contact or normal force there.
    #[inline(always)]
    pub fn lagged_slip(
        &self,
        (x, start): (V, V),
        (lagged_x, lagged): (V, V),
    ) -> Option<(Slip<V>, Real)> {
        let contact = self.contact(lagged_x)?;
        let force = contact.friction * normal_force(contact.normal, lagged);
        if !(force > 0.0 && force.is_finite()) {
            return None;
        }
        Some((Slip::new(&contact, x, start, self.h)?, force))
    }

    /// [`lagged_slip`](Self::lagged_slip) lagged to the vertex itself, at `x` with gradient `g`.
    #[inline(always)]
    pub fn slip(&self, x: V, start: V, g: V) -> Option<(Slip<V>, Real)> {
        self.lagged_slip((x, start), (x, g))
    }
}

/// The iterate friction is lagged to: its positions and the gradient of `Phi` there.
#[derive(Clone, Copy)]
pub(crate) struct Lag<'a, V> {
    pub x: &'a [V],
    pub gradient: &'a [V],
}

impl<'a, V> Lag<'a, V> {
    /// Friction lagged to the iterate at `x` with `gradient`.
    #[inline(always)]
    pub fn new(x: &'a [V], gradient: &'a [V]) -> Self {
        Lag { x, gradient }
    }
}

impl Friction<'_, Vec3> {
    /// Newton's tangent block of `D` (N/m, [`Slip::newton_hessian`]) at a vertex moved from
    /// `start` to `x` with gradient `g` of `Phi`, `lambda` from `g` too; `None` without a
    /// frictional contact.
    #[inline]
    pub fn block(&self, x: Vec3, start: Vec3, g: Vec3) -> Option<Mat3> {
        self.slip(x, start, g)
            .map(|(slip, force)| slip.newton_hessian(g) * force)
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::super::types::{Real, Vec3};
    use super::super::Contact;
    use super::Slip;

    /// A contact on the plane y = 0 with `eps_v = 1e-3` m/s, at rest or moving at 0.5 m/s
    /// along x.
    fn contact(moving: bool) -> Contact<Vec3> {
        Contact {
            normal: Vec3::Y,
            surface_velocity: Vec3::new(if moving { 0.5 } else { 0.0 }, 0.0, 0.0),
            friction: 0.5,
            sticking_speed: 1e-3,
        }
    }

    /// The slip is measured relative to the surface: a vertex carried along at the surface's
    /// speed does not slip, one standing still slips backwards by `v_s h`; the normal part of
    /// the move does not count.
    #[test]
    fn slip_is_relative_to_the_surface_and_tangential() {
        let h = 0.01;
        let carried = Slip::new(&contact(true), Vec3::new(0.005, 0.3, 0.0), Vec3::ZERO, h);
        assert!(carried.unwrap().potential().abs() < 1e-12);
        let still = Slip::new(&contact(true), Vec3::new(0.0, 0.3, 0.0), Vec3::ZERO, h).unwrap();
        assert!((still.gradient() - Vec3::new(-1.0, 0.0, 0.0)).length() < 1e-6);
        // 5 mm of slip, far beyond eps = 1e-5 m: f0 = y - eps/3.
        assert!((still.potential() - (0.005 - 1e-5 / 3.0)).abs() < 1e-8);
    }

    /// `f0` is continuous with its derivative `f1` at the threshold, the gradient is the
    /// central finite difference of `f0` and the Hessian that of the gradient, below and beyond
    /// the threshold. With `h = 1` s, so that `eps = 1e-3` m resolves in f32.
    #[test]
    fn smoothing_is_c1_and_derivatives_match_finite_differences() {
        let h = 1.0;
        let eps: Real = 1e-3;
        let at = |y: Real| Slip::new(&contact(false), Vec3::new(y, 0.0, 0.0), Vec3::ZERO, h);
        let (below, above) = (
            at(eps * (1.0 - 1e-3)).unwrap(),
            at(eps * (1.0 + 1e-3)).unwrap(),
        );
        // f0 and f1 change by O(1e-3 eps) and O(1e-3) across y = eps.
        assert!((below.potential() - above.potential()).abs() < 1e-2 * eps);
        let f1 = |s: &Slip<Vec3>| s.gradient().length();
        assert!((f1(&below) - f1(&above)).abs() < 1e-2);
        assert!((f1(&above) - 1.0).abs() < 1e-6);
        // A move off the slip's direction, with a normal part that must not count.
        for (y, z) in [(0.3 * eps, 0.2 * eps), (5.0 * eps, -3.0 * eps)] {
            let x = Vec3::new(y, 0.01, z);
            let slip = Slip::new(&contact(false), x, Vec3::ZERO, h).unwrap();
            let step = 1e-3 * eps;
            // Rounding of f0 (~eps) over 2 step, and the second-order error of the central
            // difference: 1e-2 of the gradient's size 1 and of the Hessian's 2/eps.
            for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
                let plus = Slip::new(&contact(false), x + axis * step, Vec3::ZERO, h).unwrap();
                let minus = Slip::new(&contact(false), x - axis * step, Vec3::ZERO, h).unwrap();
                let difference = (plus.potential() - minus.potential()) / (2.0 * step);
                let analytic = slip.gradient().dot(axis);
                assert!(
                    (difference - analytic).abs() < 1e-2,
                    "y {y}: {difference} against {analytic}"
                );
                let hessian = slip.hessian() * axis;
                let fd = (plus.gradient() - minus.gradient()) / (2.0 * step);
                assert!(
                    (fd - hessian).length() < 1e-2 * 2.0 / eps,
                    "y {y}: {fd} against {hessian}"
                );
            }
            // The Hessian is positive semi-definite: its eigenvalues in the tangent plane are
            // f1/y across the slip and f1' >= 0 along it.
            let u = slip.gradient() / slip.gradient().length();
            let across = Vec3::Y.cross(u);
            assert!(u.dot(slip.hessian() * u) >= -1e-6 / eps, "y {y}");
            assert!((across.dot(slip.hessian() * across) - slip.curvature()).abs() < 1e-3 / eps);
            assert!(
                Vec3::Y.dot(slip.hessian() * Vec3::Y).abs() < 1e-6 / eps,
                "y {y}"
            );
        }
    }

    /// Newton's block is the exact Hessian where the descent lengthens the slip, and where it
    /// shortens it a quadratic bound above `f0` in the tangent plane: `f0(|u + s|) <= f0(y) +
    /// f1 u_hat.s + (f1/y) |s|^2 / 2` for tangential moves `s` of every size, including ones
    /// through the sticking zone and past `u = 0`, where the exact model (no curvature along
    /// a fast slip) would promise a decrease that never comes. `h = 1` s, `eps = 1e-3` m.
    #[test]
    fn newton_block_is_exact_when_slipping_on_and_a_majoriser_when_slowing() {
        let h = 1.0;
        let eps: Real = 1e-3;
        let at = |x: Vec3| Slip::new(&contact(false), x, Vec3::ZERO, h).unwrap();
        for (y, z) in [
            (0.3 * eps, 0.2 * eps),
            (5.0 * eps, -3.0 * eps),
            (40.0 * eps, eps),
        ] {
            let x = Vec3::new(y, 0.01, z);
            let slip = at(x);
            let u = slip.gradient() / slip.gradient().length();
            // Lengthening: the exact Hessian, bit for bit.
            let lengthening = slip.newton_hessian(-u + Vec3::Y);
            assert_eq!(lengthening, slip.hessian(), "y {y}");
            // Shortening: (f1/y) T, the bound.
            let shortening = slip.newton_hessian(u + Vec3::Y);
            let across = Vec3::Y.cross(u);
            for direction in [u, across] {
                assert!(
                    (direction.dot(shortening * direction) - slip.curvature()).abs()
                        < 1e-5 * slip.curvature()
                );
            }
            assert!(Vec3::Y.dot(shortening * Vec3::Y).abs() < 1e-6 / eps);
            let length = (x - Vec3::Y * 0.01).length();
            for scale in [-2.5, -1.0, -0.99, -0.5, -0.1, 0.3, 2.0] {
                for turn in [0.0, 0.4, 1.0] {
                    let s = (u + across * turn) * (scale * length);
                    let model =
                        slip.potential() + slip.gradient().dot(s) + 0.5 * s.dot(shortening * s);
                    let moved = at(x + s).potential();
                    // Rounding of f0 and of the model's terms (~1e-6 of eps-sized values).
                    assert!(
                        moved <= model + 1e-6 * (eps + length),
                        "y {y}, s {s}: {moved} above {model}"
                    );
                }
            }
        }
    }
}

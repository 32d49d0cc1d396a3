//! The colliders' queries at one vertex of either dimension, for the steppers' generic code:
//! colliders act on 3D points only, so a 2D vertex ([`Grouped::SPACE_DIM`] 2) touches none (the
//! identity, no contact, nothing shifted) and a 3D one asks [`Colliders`] directly
//! ([`Grouped::to_vec3`] and [`Grouped::from_vec3`] are the identity there: the same bits). Also
//! [`Obstacles`] for [`Colliders`]: the queries [`Point`](super::super::vertex_pass::point::Point)
//! makes, lane by lane for groups.

use super::super::super::types::{Real, Vec3};
use super::super::vertex_pass::point::{Grouped, Obstacles};
use super::Contact;
use super::collider::{self, Collider, Colliders};

impl Obstacles for Colliders<'_> {
    #[inline(always)]
    fn pushed_out(&self, x: Vec3) -> Vec3 {
        Colliders::pushed_out(self, x)
    }
    #[inline(always)]
    fn constrained(&self, x: Vec3, v: Vec3, sign: Real) -> Vec3 {
        Colliders::constrained(self, x, v, sign)
    }
    #[inline(always)]
    fn touching_normal(&self, x: Vec3) -> Option<Vec3> {
        self.touching(x).map(|(_, normal)| normal)
    }
}

/// The explicit stepper's response to the colliders at a vertex at `x` moving at `v` (see
/// `collider::resolve`); the number of colliders it was inside (none in 2D).
#[inline(always)]
pub(crate) fn resolve_colliders<V: Grouped>(
    colliders: &[Collider<'_>],
    x: &mut V,
    v: &mut V,
    resting_speed_and_step: (Real, Real),
) -> usize {
    if V::SPACE_DIM != 3 {
        return 0;
    }
    let (mut x3, mut v3) = (x.to_vec3(), v.to_vec3());
    let contacts = collider::resolve(colliders, &mut x3, &mut v3, resting_speed_and_step);
    *x = V::from_vec3(x3);
    *v = V::from_vec3(v3);
    contacts
}

/// The implicit solvers' velocity `v` at a vertex at `x` with gradient `g`, mass `m` and step `h`
/// after the colliders' friction (see `Colliders::implicit_velocity`; `v` in 2D).
#[inline(always)]
pub(crate) fn collider_velocity<V: Grouped>(
    colliders: Colliders<'_>,
    (x, g, m, h): (V, V, Real, Real),
    v: V,
) -> V {
    if V::SPACE_DIM != 3 {
        return v;
    }
    let state = (x.to_vec3(), g.to_vec3(), m, h);
    V::from_vec3(colliders.implicit_velocity(state, v.to_vec3()))
}

/// The friction data of the first collider `x` touches (see `Colliders::contact`; none in 2D).
#[inline(always)]
pub(crate) fn collider_contact<V: Grouped>(colliders: Colliders<'_>, x: V) -> Option<Contact<V>> {
    if V::SPACE_DIM != 3 {
        return None;
    }
    colliders.contact(x.to_vec3()).map(|contact| Contact {
        normal: V::from_vec3(contact.normal),
        surface_velocity: V::from_vec3(contact.surface_velocity),
        friction: contact.friction,
        sticking_speed: contact.sticking_speed,
    })
}

/// `colliders` seen from coordinates shifted by `-origin` (see `Colliders::shifted`; 2D bodies
/// take no colliders: unshifted).
#[inline(always)]
pub(crate) fn shifted_colliders<'a, V: Grouped>(
    colliders: &'a [Collider<'a>],
    origin: V,
) -> Colliders<'a> {
    let colliders = Colliders::new(colliders);
    if V::SPACE_DIM != 3 {
        return colliders;
    }
    colliders.shifted(origin.to_vec3())
}

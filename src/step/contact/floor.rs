//! The ground and the colliders as every stepper sees them at a vertex or a group of vertices
//! ([`Floor`]): the contact test, the projection of a position onto the admissible set, and the
//! constraint of a velocity or a descent direction at a contact, written once over
//! [`Point`](super::super::super::vertex_pass::point::Point) so that one vertex and a SIMD lane get
//! the same bits.

use super::super::super::lanes::Lane;
use super::super::super::types::{Real, Vec3};
use super::super::vertex_pass::point::{Grouped, Point};
use super::HalfSpace;
use super::collider::Colliders;

/// The ground and the colliders as seen by [`Point`]s (or neither): contact tests and
/// projections, the same bits for one vertex and for a lane. Without colliders the ground path
/// is all there is (bit for bit what it was before colliders existed); with colliders, groups
/// fall back to lane-by-lane work for them.
#[derive(Clone, Copy)]
pub(crate) struct Floor<'a, P: Point> {
    /// `None` without a ground.
    plane: Option<(P, P::Scalar)>,
    /// `16 eps |offset|`, the part of the contact tolerance that does not depend on `x`.
    slack: P::Scalar,
    /// The validated colliders, in the floor's coordinates (empty for none).
    colliders: Colliders<'a>,
}

/// A point's contacts, queried once ([`Floor::touch`]) for several constraints there.
#[derive(Clone, Copy)]
pub(crate) struct Touch<P: Point> {
    /// The ground contact ([`Floor::contact`]).
    ground: Option<<P::Scalar as Lane>::Mask>,
    /// The colliders' normals, `None` without colliders.
    colliders: Option<P::Touch>,
}

/// The contact tolerance's factor: `16 eps`.
const CONTACT_EPS: Real = 16.0 * Real::EPSILON;

impl<'a, P: Point> Floor<'a, P> {
    /// `ground` (with a unit normal) for points of type `P`, no colliders.
    #[inline(always)]
    pub fn new(ground: Option<&HalfSpace<P::Vector>>) -> Self {
        Floor {
            plane: ground.map(|g| (P::splat(g.normal), P::Scalar::splat(g.offset))),
            slack: P::Scalar::splat(ground.map_or(0.0, |g| CONTACT_EPS * g.offset.abs())),
            colliders: Colliders::new(&[]),
        }
    }

    /// This floor with the (validated) `colliders` too, seen from the floor's coordinates.
    #[inline(always)]
    pub fn with_colliders(self, colliders: Colliders<'a>) -> Self {
        Floor { colliders, ..self }
    }

    /// The colliders (empty for none).
    #[inline(always)]
    pub fn colliders(&self) -> Colliders<'a> {
        self.colliders
    }

    /// The same ground and colliders for groups of vectors `W` (of any width).
    #[inline(always)]
    pub fn widened<W: Point<Vector = P>>(&self) -> Floor<'a, W>
    where
        P: Grouped,
    {
        Floor {
            plane: self
                .plane
                .map(|(normal, offset)| (W::splat(normal), W::Scalar::splat(offset))),
            slack: W::Scalar::splat(self.slack),
            colliders: self.colliders,
        }
    }

    /// Whether `x` touches the ground within rounding of the projection: height at most
    /// `16 eps (|offset| + |x|_1)`. `None` without a ground. (The colliders' contacts are
    /// tested by [`constrain`](Self::constrain) itself.)
    #[inline(always)]
    pub fn contact(&self, x: P) -> Option<<P::Scalar as Lane>::Mask> {
        let (normal, offset) = self.plane?;
        let height = normal.inner(x) - offset;
        let tolerance = self.slack + P::Scalar::splat(CONTACT_EPS) * x.abs_sum();
        Some(tolerance.ge(height))
    }

    /// `x` projected onto the ground if it is inside, then pushed out of every collider.
    #[inline(always)]
    pub fn project(&self, x: P) -> P {
        let x = self.project_ground(x);
        if self.colliders.is_empty() {
            x
        } else {
            x.pushed_out(self.colliders)
        }
    }

    /// `x` projected onto the ground if it is inside.
    #[inline(always)]
    fn project_ground(&self, x: P) -> P {
        let Some((normal, offset)) = self.plane else {
            return x;
        };
        let depth = -(normal.inner(x) - offset);
        let inside = depth.gt(P::Scalar::splat(0.0));
        // The common case, no lane inside, skips the projection (same result).
        if P::Scalar::none(inside) {
            return x;
        }
        P::select(inside, x + normal.scale(depth), x)
    }

    /// `v` at a vertex at `x` without its component into the ground where `contact` (from
    /// [`contact`](Self::contact) at `x`) is set, then without its component into the first
    /// collider `x` touches: `sign` +1 for a gradient, whose descent is `-g`, -1 for a
    /// direction.
    #[inline(always)]
    pub fn constrain(
        &self,
        contact: Option<<P::Scalar as Lane>::Mask>,
        x: P,
        v: P,
        sign: Real,
    ) -> P {
        let v = self.constrain_ground(contact, v, sign);
        if self.colliders.is_empty() {
            v
        } else {
            x.constrained_by(self.colliders, v, sign)
        }
    }

    /// What [`constrain_at`](Self::constrain_at) needs of `x`: its ground contact (as
    /// [`contact`](Self::contact)) and the normal of the collider it touches, each queried
    /// once for any number of constraints at `x`.
    #[inline(always)]
    pub fn touch(&self, x: P) -> Touch<P> {
        Touch {
            ground: self.contact(x),
            colliders: (!self.colliders.is_empty()).then(|| x.touch(self.colliders)),
        }
    }

    /// [`constrain`](Self::constrain) at the point `touch` was taken at: the same bits, without
    /// querying the colliders again.
    #[inline(always)]
    pub fn constrain_at(&self, touch: &Touch<P>, v: P, sign: Real) -> P {
        let v = self.constrain_ground(touch.ground, v, sign);
        match touch.colliders {
            Some(colliders) => P::constrained_at(colliders, v, sign),
            None => v,
        }
    }

    /// The projected descent direction at a vertex at `x` with gradient `g`, and its term of
    /// the slope `g.d`: `g` constrained as a gradient, the plain step `factor g` (zero where
    /// `positive` is given and not set), plus `momentum` times the last step `x - previous` when
    /// `heavy_ball` is given, constrained as a direction. With colliders one contact query
    /// serves both constraints ([`touch`](Self::touch)); without, the ground's test alone (the
    /// two monomorphised apart, so the frictionless loop carries no collider state). The one
    /// sequence of the relaxation's preconditioned direction and plain gradient descent.
    #[inline(always)]
    pub fn descent(
        &self,
        x: P,
        g: P,
        (factor, positive): (P::Scalar, Option<<P::Scalar as Lane>::Mask>),
        heavy_ball: Option<(P, P::Scalar)>,
    ) -> (P, P::Scalar) {
        if self.colliders.is_empty() {
            let contact = OnGround(self.contact(x));
            return self.descent_along(&contact, x, g, (factor, positive), heavy_ball);
        }
        let touch = self.touch(x);
        self.descent_along(&touch, x, g, (factor, positive), heavy_ball)
    }

    /// [`descent`](Self::descent) with the contacts at `x` in `at`.
    #[inline(always)]
    fn descent_along(
        &self,
        at: &impl Contacts<P>,
        x: P,
        g: P,
        (factor, positive): (P::Scalar, Option<<P::Scalar as Lane>::Mask>),
        heavy_ball: Option<(P, P::Scalar)>,
    ) -> (P, P::Scalar) {
        let g = at.constrain(self, g, 1.0);
        let plain = g.scale(factor);
        let plain = match positive {
            Some(positive) => P::select(positive, plain, P::zero()),
            None => plain,
        };
        let direction = match heavy_ball {
            Some((previous, momentum)) => plain + (x - previous).scale(momentum),
            None => plain,
        };
        let d = at.constrain(self, direction, -1.0);
        (d, g.inner(d))
    }

    /// The ground's part of [`constrain`](Self::constrain).
    #[inline(always)]
    fn constrain_ground(&self, contact: Option<<P::Scalar as Lane>::Mask>, v: P, sign: Real) -> P {
        let (Some((normal, _)), Some(contact)) = (self.plane, contact) else {
            return v;
        };
        // The common case, no lane in contact, skips the projection (same result).
        if P::Scalar::none(contact) {
            return v;
        }
        let along = normal.inner(v);
        let into = (along * P::Scalar::splat(sign)).gt(P::Scalar::splat(0.0));
        P::select(contact, P::select(into, v - normal.scale(along), v), v)
    }
}

/// The contacts of a point, queried once, for the constraints there ([`Floor::descent`]).
trait Contacts<P: Point> {
    /// [`Floor::constrain`] at the point.
    fn constrain(&self, floor: &Floor<'_, P>, v: P, sign: Real) -> P;
}

/// The ground contact of a point on a floor without colliders ([`Floor::contact`]).
struct OnGround<M>(Option<M>);

impl<P: Point> Contacts<P> for OnGround<<P::Scalar as Lane>::Mask> {
    /// Without colliders, [`Floor::constrain`] is its ground part.
    #[inline(always)]
    fn constrain(&self, floor: &Floor<'_, P>, v: P, sign: Real) -> P {
        floor.constrain_ground(self.0, v, sign)
    }
}

impl<P: Point> Contacts<P> for Touch<P> {
    #[inline(always)]
    fn constrain(&self, floor: &Floor<'_, P>, v: P, sign: Real) -> P {
        floor.constrain_at(self, v, sign)
    }
}

impl Floor<'_, Vec3> {
    /// The outward normal of the first collider `x` touches (Newton's active set).
    #[inline(always)]
    pub fn collider_normal(&self, x: Vec3) -> Option<Vec3> {
        self.colliders.touching(x).map(|(_, normal)| normal)
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::super::lanes::{LANES, Lane, LaneVec3, Lanes};
    use super::super::super::super::types::{Real, Vec3};
    use super::super::super::vertex_pass::point::Grouped;
    use super::super::HalfSpace;
    use super::Floor;

    /// The contact test holds at equality: a vertex exactly at the origin, on a ground plane
    /// through it, has height 0 and tolerance 0, and is in contact (one at a time and in every
    /// lane); just above the tolerance it is not, and a NaN position never is.
    #[test]
    fn contact_holds_at_equality_in_every_representation() {
        let ground = HalfSpace::new(Vec3::Z, 0.0);
        let one = Floor::<Vec3>::new(Some(&ground));
        let lanes = Floor::<LaneVec3<Lanes>>::new(Some(&ground));
        let above = Vec3::new(1.0, 0.0, 1e-3);
        let cases = [
            Vec3::ZERO,
            Vec3::new(0.5, -0.25, 0.0),
            above,
            Vec3::splat(Real::NAN),
        ];
        let expected = [true, true, false, false];
        for (x, &contact) in cases.iter().zip(&expected) {
            assert_eq!(one.contact(*x), Some(contact), "{x}");
        }
        let mut group = [Vec3::ZERO; LANES];
        group.copy_from_slice(&cases[..LANES]);
        let mask = lanes.contact(Vec3::group(group)).unwrap();
        let flags = Lanes::select(mask, Lanes::splat(1.0), Lanes::splat(0.0)).to_array();
        assert_eq!(flags.map(|f| f == 1.0), expected);
        // Projection moves only the vertices inside.
        let inside = Vec3::new(0.0, 0.0, -0.5);
        assert_eq!(one.project(inside), Vec3::ZERO);
        assert_eq!(one.project(above), above);
        let projected = Vec3::ungroup(lanes.project(Vec3::group([inside, above, inside, above])));
        assert_eq!(projected, [Vec3::ZERO, above, Vec3::ZERO, above]);
        // Without a ground nothing is in contact or moved.
        let none = Floor::<Vec3>::new(None);
        assert_eq!(none.contact(Vec3::ZERO), None);
        assert_eq!(none.project(inside), inside);
    }

    /// One contact query for several constraints at a point gives the bits of querying for
    /// each: a ground and four kinds of collider, points on, just off, inside and far from
    /// their surfaces, gradients and directions into and out of them, one vertex at a time and
    /// in groups (whose colliders are queried lane by lane).
    #[test]
    fn one_touch_constrains_as_a_query_per_constraint() {
        use super::super::super::super::types::Quat;
        use super::super::collider::{Collider, Colliders};
        let ground = HalfSpace::new(Vec3::Z, -0.5);
        let list = [
            Collider::sphere(Vec3::new(0.0, 0.0, 1.0), 0.5),
            Collider::capsule(Vec3::new(-1.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 0.5), 0.25),
            Collider::cuboid(
                Vec3::new(1.0, -1.0, 0.25),
                Vec3::new(0.5, 0.25, 0.5),
                Quat::from_rotation_z(0.3),
            ),
            Collider::half_space(Vec3::new(0.0, 0.0, 3.0), Vec3::new(0.1, 0.0, -1.0)),
        ];
        let colliders = Colliders::new(&list);
        let one = Floor::<Vec3>::new(Some(&ground)).with_colliders(colliders);
        let lanes = one.widened::<LaneVec3<Lanes>>();
        let mut state: u32 = 12345;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as Real / (1u32 << 24) as Real * 2.0 - 1.0
        };
        let surface = [
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::new(0.0, 1.25, 0.25),
            Vec3::new(0.0, 0.0, -0.5),
            Vec3::new(0.0, 0.0, 3.0),
        ];
        let bits = |v: Vec3| v.to_array().map(Real::to_bits);
        let mut touched = 0;
        for k in 0..400 {
            // On a surface, within rounding of it, a little inside or off, or anywhere.
            let base = surface
                .get(k % surface.len())
                .copied()
                .unwrap_or(Vec3::ZERO);
            let scale = [0.0, 1e-7, 1e-3, 0.05, 2.0][k % 5];
            let mut points = [Vec3::ZERO; LANES];
            let mut vectors = [Vec3::ZERO; LANES];
            for (x, v) in points.iter_mut().zip(&mut vectors) {
                *x = base + Vec3::new(next(), next(), next()) * scale;
                *v = Vec3::new(next(), next(), next());
            }
            for sign in [1.0, -1.0] {
                for (&x, &v) in points.iter().zip(&vectors) {
                    let touch = one.touch(x);
                    let expected = one.constrain(one.contact(x), x, v, sign);
                    assert_eq!(
                        bits(one.constrain_at(&touch, v, sign)),
                        bits(expected),
                        "{x} {v}"
                    );
                    touched += usize::from(expected != v);
                }
                let (x, v) = (Vec3::group(points), Vec3::group(vectors));
                let expected = lanes.constrain(lanes.contact(x), x, v, sign);
                let got = lanes.constrain_at(&lanes.touch(x), v, sign);
                let [expected, got] = [expected, got].map(|g| Vec3::ungroup(g).map(bits));
                assert_eq!(got, expected);
            }
        }
        // The constraints acted on many of the points.
        assert!(touched > 200, "{touched}");
    }
}

//! Per-vertex arithmetic written once for one vertex and for a group of vertices.
//!
//! The relaxation's vertex passes (gradient, direction, trial points; `vertex_passes.rs`) run on
//! x86_64 in groups of the width `simd::dispatch` picks (16 f32 lanes on AVX-512, 8 on AVX2,
//! then narrower groups down to [`LANES`]) as [`Point`]s with lane coordinates
//! ([`Grouped::Wide`]) and the rest one at a time with the plain vector, elsewhere every vertex
//! one at a time, through the same generic code: element-wise IEEE operations and selects
//! instead of branches, so every vertex gets the same bits either way. Sums over vertices follow one fixed order on every target (`LaneSum` in
//! `lanes.rs`). `LaneVec2` lives here rather than next to `LaneVec3`: only the steppers need 2D
//! lanes.

use core::ops::{Add, Neg, Sub};

use super::super::lanes::{
    LANES, Lane, LaneArray, LaneVec3, Lanes, each_lane, lane_vec3, map_lane_vectors,
};
use super::super::types::{Real, Vec2, Vec3};
use super::Ground;
use super::collider::{self, Collider, Colliders};
use super::friction::Contact;

/// One vertex vector, or [`LANES`] of them. Public in a private module: the hidden half of the
/// sealed [`Vector`](super::Vector) trait.
pub trait Point: Copy + Add<Output = Self> + Sub<Output = Self> + Neg<Output = Self> {
    /// [`Real`] or [`Lanes`].
    type Scalar: Lane;
    /// The vector type of one vertex.
    type Vector: Copy;
    /// `v` in every lane.
    fn splat(v: Self::Vector) -> Self;
    /// The zero vector.
    fn zero() -> Self;
    /// The dot product, summed in coordinate order (named apart from `Vector::dot`).
    fn inner(self, other: Self) -> Self::Scalar;
    /// Every coordinate times `k`.
    fn scale(self, k: Self::Scalar) -> Self;
    /// `|x| + |y| (+ |z|)`.
    fn abs_sum(self) -> Self::Scalar;
    /// `mask ? a : b`, per lane.
    fn select(mask: <Self::Scalar as Lane>::Mask, a: Self, b: Self) -> Self;
    /// `self` pushed out of every collider, in order (colliders act on 3D points only: the
    /// identity in 2D). Lane by lane for groups.
    fn pushed_out(self, colliders: Colliders<'_>) -> Self;
    /// `v` without its component into the first collider touching `self`, `sign` as in
    /// [`Floor::constrain`] (the identity in 2D). Lane by lane for groups.
    fn constrained_by(self, colliders: Colliders<'_>, v: Self, sign: Real) -> Self;
    /// The outward normal of the first collider touching `self` (per lane for groups; nothing
    /// in 2D), for several constraints at one point with one query ([`Floor::touch`]).
    type Touch: Copy;
    /// [`Touch`](Self::Touch) at `self`.
    fn touch(self, colliders: Colliders<'_>) -> Self::Touch;
    /// [`constrained_by`](Self::constrained_by) at the point `touch` was queried at: the same
    /// bits.
    fn constrained_at(touch: Self::Touch, v: Self, sign: Real) -> Self;
}

/// `v` without its component into `normal` (the outward normal of the collider a point touches,
/// or `None`) where `sign` times that component is positive: the arithmetic of
/// `Colliders::constrained`, given the normal its query finds.
#[inline(always)]
fn constrained_along(normal: Option<Vec3>, v: Vec3, sign: Real) -> Vec3 {
    match normal {
        Some(normal) => {
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

/// A vector type that also comes in groups of [`LANES`]: `Vec2` and `Vec3`.
pub trait Grouped: Point<Scalar = Real, Vector = Self> {
    /// [`LANES`] vectors, coordinate by coordinate.
    type Group: Point<Scalar = Lanes, Vector = Self>;
    /// The group of `v`: lane `i` holds `v[i]`.
    fn group(v: [Self; LANES]) -> Self::Group;
    /// The vectors of a group, lane by lane.
    fn ungroup(group: Self::Group) -> [Self; LANES];
    /// Groups of `L::WIDTH` vectors (a multiple of [`LANES`]), coordinate by coordinate: the
    /// explicit step's update and the relaxation's vertex passes at the width
    /// `simd::dispatch` picks.
    type Wide<L: Lane>: Wide<L, Vector = Self> + Point<Scalar = L, Vector = Self>;
    /// The mask of every axis: `0b11` in 2D, `0b111` in 3D.
    const ALL_AXES: u8;
    /// `self` with the coordinates whose bit is set in `fixed` (bit 0 x, 1 y, 2 z) taken from
    /// `source`: a select, so they keep `source`'s bits exactly.
    fn axes_from(self, source: Self, fixed: u8) -> Self;
    /// The explicit stepper's response to the colliders at a vertex at `x` moving at `v` (see
    /// `collider::resolve`); the number of colliders it was inside (none in 2D).
    fn resolve_colliders(
        colliders: &[Collider<'_>],
        x: &mut Self,
        v: &mut Self,
        resting_speed_and_step: (Real, Real),
    ) -> usize;
    /// The implicit solvers' velocity `v` at a vertex at `x` with gradient `g`, mass `m` and
    /// step `h` after the colliders' friction (see `Colliders::implicit_velocity`; `v` in 2D).
    fn collider_velocity(
        colliders: Colliders<'_>,
        x: Self,
        g: Self,
        m: Real,
        h: Real,
        v: Self,
    ) -> Self;
    /// The friction data of the first collider `x` touches (see `Colliders::contact`; none in
    /// 2D).
    fn collider_contact(colliders: Colliders<'_>, x: Self) -> Option<Contact<Self>>;
    /// `colliders` seen from coordinates shifted by `-origin` (see `Colliders::shifted`; 2D
    /// bodies take no colliders: unshifted).
    fn shifted_colliders<'a>(colliders: &'a [Collider<'a>], origin: Self) -> Colliders<'a>;
}

/// A group of `L::WIDTH` vertex vectors ([`Grouped::Wide`]): element-wise IEEE arithmetic in
/// the order of the one-vertex code, so that every lane gets its bits.
#[allow(private_bounds)]
pub trait Wide<L: Lane>:
    Copy + Add<Output = Self> + Sub<Output = Self> + Neg<Output = Self>
{
    /// The vector type of one vertex.
    type Vector: Copy;
    /// `v` in every lane.
    fn wide_splat(v: Self::Vector) -> Self;
    /// The dot product, summed in coordinate order.
    fn wide_inner(self, other: Self) -> L;
    /// Every coordinate times `k`.
    fn wide_scale(self, k: L) -> Self;
    /// `mask ? a : b`, per lane.
    fn wide_select(mask: L::Mask, a: Self, b: Self) -> Self;
    /// The sum of every coordinate times zero: zero in the lanes whose vector is finite, NaN
    /// in the others.
    fn finite_zero(self) -> L;
    /// The group of the first `L::WIDTH` vectors of `chunk` (zeros past its end).
    fn load(chunk: &[Self::Vector]) -> Self
    where
        L: LaneArray;
    /// Writes the group into the first `L::WIDTH` vectors of `chunk` (as far as it goes).
    fn store(self, chunk: &mut [Self::Vector])
    where
        L: LaneArray;
}

/// Lanes `4 q..4 q + 4` of `values` as [`LANES`] values (zeros past the end of the slice).
#[inline(always)]
fn quarter_of<T: Copy>(values: &[T], q: usize, zero: T) -> [T; LANES] {
    values
        .get(q * LANES..)
        .and_then(<[T]>::first_chunk::<LANES>)
        .copied()
        .unwrap_or([zero; LANES])
}

// `LaneArray` is crate-private, and so is every use of these groups (the trait is public only
// as the hidden half of the sealed `Vector`).
#[allow(private_bounds)]
impl<L: Lane> Wide<L> for LaneVec3<L> {
    type Vector = Vec3;
    #[inline(always)]
    fn wide_splat(v: Vec3) -> Self {
        LaneVec3::new(L::splat(v.x), L::splat(v.y), L::splat(v.z))
    }
    #[inline(always)]
    fn wide_inner(self, o: Self) -> L {
        LaneVec3::dot(self, o)
    }
    #[inline(always)]
    fn wide_scale(self, k: L) -> Self {
        LaneVec3::scale(self, k)
    }
    #[inline(always)]
    fn wide_select(mask: L::Mask, a: Self, b: Self) -> Self {
        LaneVec3::select(mask, a, b)
    }
    #[inline(always)]
    fn finite_zero(self) -> L {
        let zero = L::splat(0.0);
        self.x * zero + self.y * zero + self.z * zero
    }
    #[inline(always)]
    fn load(chunk: &[Vec3]) -> Self
    where
        L: LaneArray,
    {
        if let Some(group) = L::load_vec3s(chunk) {
            return group;
        }
        // Four vectors at a time through the SSE transposes, each quarter stored whole.
        let (mut x, mut y, mut z) = (L::ZEROS, L::ZEROS, L::ZEROS);
        for q in 0..L::WIDTH / LANES {
            let group = LaneVec3::from_vectors(quarter_of(chunk, q, Vec3::ZERO));
            L::store_quarter(&mut x, q, group.x);
            L::store_quarter(&mut y, q, group.y);
            L::store_quarter(&mut z, q, group.z);
        }
        LaneVec3::new(
            L::from_lane_array(x),
            L::from_lane_array(y),
            L::from_lane_array(z),
        )
    }
    #[inline(always)]
    fn store(self, chunk: &mut [Vec3])
    where
        L: LaneArray,
    {
        if L::store_vec3s(self, chunk) {
            return;
        }
        let (x, y, z) = (
            self.x.to_lane_array(),
            self.y.to_lane_array(),
            self.z.to_lane_array(),
        );
        let slots = chunk.chunks_exact_mut(LANES).take(L::WIDTH / LANES);
        for (q, slot) in slots.enumerate() {
            let quarter = LaneVec3::new(L::quarter(&x, q), L::quarter(&y, q), L::quarter(&z, q));
            slot.copy_from_slice(&quarter.to_vectors());
        }
    }
}

// `LaneArray` is crate-private, and so is every use of these groups (the trait is public only
// as the hidden half of the sealed `Vector`).
#[allow(private_bounds)]
impl<L: Lane> Wide<L> for LaneVec2<L> {
    type Vector = Vec2;
    #[inline(always)]
    fn wide_splat(v: Vec2) -> Self {
        LaneVec2 {
            x: L::splat(v.x),
            y: L::splat(v.y),
        }
    }
    #[inline(always)]
    fn wide_inner(self, o: Self) -> L {
        self.x * o.x + self.y * o.y
    }
    #[inline(always)]
    fn wide_scale(self, k: L) -> Self {
        LaneVec2 {
            x: self.x * k,
            y: self.y * k,
        }
    }
    #[inline(always)]
    fn wide_select(mask: L::Mask, a: Self, b: Self) -> Self {
        LaneVec2 {
            x: L::select(mask, a.x, b.x),
            y: L::select(mask, a.y, b.y),
        }
    }
    #[inline(always)]
    fn finite_zero(self) -> L {
        let zero = L::splat(0.0);
        self.x * zero + self.y * zero
    }
    #[inline(always)]
    fn load(chunk: &[Vec2]) -> Self
    where
        L: LaneArray,
    {
        let mut quarters = [[[0.0; LANES]; 4]; 2];
        for q in 0..L::WIDTH / LANES {
            let vectors = quarter_of(chunk, q, Vec2::ZERO);
            let [x, y] = &mut quarters;
            if let (Some(x), Some(y)) = (x.get_mut(q), y.get_mut(q)) {
                *x = each_lane(vectors, |v| v.x);
                *y = each_lane(vectors, |v| v.y);
            }
        }
        let [x, y] = quarters;
        LaneVec2 {
            x: L::from_quarters(x),
            y: L::from_quarters(y),
        }
    }
    #[inline(always)]
    fn store(self, chunk: &mut [Vec2])
    where
        L: LaneArray,
    {
        let (x, y) = (self.x.to_lane_array(), self.y.to_lane_array());
        let slots = chunk.chunks_exact_mut(LANES).take(L::WIDTH / LANES);
        for (q, slot) in slots.enumerate() {
            let (x, y) = (L::quarter(&x, q).to_array(), L::quarter(&y, q).to_array());
            for ((slot, x), y) in slot.iter_mut().zip(x).zip(y) {
                *slot = Vec2::new(x, y);
            }
        }
    }
}

/// `source`'s coordinate where `bit` is set in `fixed`, else `own`.
#[inline(always)]
fn pick(own: Real, source: Real, fixed: u8, bit: u8) -> Real {
    if fixed & bit != 0 { source } else { own }
}

/// A group of 2D vectors, coordinate by coordinate ([`LANES`] of them by default).
#[derive(Clone, Copy)]
pub struct LaneVec2<L = Lanes> {
    x: L,
    y: L,
}

impl<L: Lane> Add for LaneVec2<L> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        LaneVec2 {
            x: self.x + o.x,
            y: self.y + o.y,
        }
    }
}

impl<L: Lane> Sub for LaneVec2<L> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        LaneVec2 {
            x: self.x - o.x,
            y: self.y - o.y,
        }
    }
}

impl<L: Lane> Neg for LaneVec2<L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        LaneVec2 {
            x: -self.x,
            y: -self.y,
        }
    }
}

impl Point for Vec2 {
    type Scalar = Real;
    type Vector = Vec2;
    #[inline(always)]
    fn splat(v: Vec2) -> Self {
        v
    }
    #[inline(always)]
    fn zero() -> Self {
        Vec2::ZERO
    }
    #[inline(always)]
    fn inner(self, o: Self) -> Real {
        Vec2::dot(self, o)
    }
    #[inline(always)]
    fn scale(self, k: Real) -> Self {
        self * k
    }
    #[inline(always)]
    fn abs_sum(self) -> Real {
        self.x.abs() + self.y.abs()
    }
    #[inline(always)]
    fn select(mask: bool, a: Self, b: Self) -> Self {
        if mask { a } else { b }
    }
    #[inline(always)]
    fn pushed_out(self, _: Colliders<'_>) -> Self {
        self
    }
    #[inline(always)]
    fn constrained_by(self, _: Colliders<'_>, v: Self, _: Real) -> Self {
        v
    }
    type Touch = ();
    #[inline(always)]
    fn touch(self, _: Colliders<'_>) {}
    #[inline(always)]
    fn constrained_at((): (), v: Self, _: Real) -> Self {
        v
    }
}

impl<L: Lane> Point for LaneVec2<L> {
    type Scalar = L;
    type Vector = Vec2;
    #[inline(always)]
    fn splat(v: Vec2) -> Self {
        LaneVec2 {
            x: L::splat(v.x),
            y: L::splat(v.y),
        }
    }
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(Vec2::ZERO)
    }
    #[inline(always)]
    fn inner(self, o: Self) -> L {
        self.x * o.x + self.y * o.y
    }
    #[inline(always)]
    fn scale(self, k: L) -> Self {
        LaneVec2 {
            x: self.x * k,
            y: self.y * k,
        }
    }
    #[inline(always)]
    fn abs_sum(self) -> L {
        self.x.abs() + self.y.abs()
    }
    #[inline(always)]
    fn select(mask: L::Mask, a: Self, b: Self) -> Self {
        LaneVec2 {
            x: L::select(mask, a.x, b.x),
            y: L::select(mask, a.y, b.y),
        }
    }
    #[inline(always)]
    fn pushed_out(self, _: Colliders<'_>) -> Self {
        self
    }
    #[inline(always)]
    fn constrained_by(self, _: Colliders<'_>, v: Self, _: Real) -> Self {
        v
    }
    type Touch = ();
    #[inline(always)]
    fn touch(self, _: Colliders<'_>) {}
    #[inline(always)]
    fn constrained_at((): (), v: Self, _: Real) -> Self {
        v
    }
}

impl Grouped for Vec2 {
    type Group = LaneVec2;
    type Wide<L: Lane> = LaneVec2<L>;
    #[inline(always)]
    fn group(v: [Vec2; LANES]) -> LaneVec2 {
        LaneVec2 {
            x: Lanes::from_array(each_lane(v, |v| v.x)),
            y: Lanes::from_array(each_lane(v, |v| v.y)),
        }
    }
    const ALL_AXES: u8 = 0b11;
    #[inline(always)]
    fn resolve_colliders(_: &[Collider<'_>], _: &mut Self, _: &mut Self, _: (Real, Real)) -> usize {
        0
    }
    #[inline(always)]
    fn collider_velocity(_: Colliders<'_>, _: Self, _: Self, _: Real, _: Real, v: Self) -> Self {
        v
    }
    #[inline(always)]
    fn collider_contact(_: Colliders<'_>, _: Self) -> Option<Contact<Self>> {
        None
    }
    #[inline(always)]
    fn shifted_colliders<'a>(colliders: &'a [Collider<'a>], _: Self) -> Colliders<'a> {
        Colliders::new(colliders)
    }
    #[inline(always)]
    fn axes_from(self, source: Vec2, fixed: u8) -> Vec2 {
        Vec2::new(
            pick(self.x, source.x, fixed, 1),
            pick(self.y, source.y, fixed, 2),
        )
    }
    #[inline(always)]
    fn ungroup(group: LaneVec2) -> [Vec2; LANES] {
        let ([x0, x1, x2, x3], [y0, y1, y2, y3]) = (group.x.to_array(), group.y.to_array());
        [
            Vec2::new(x0, y0),
            Vec2::new(x1, y1),
            Vec2::new(x2, y2),
            Vec2::new(x3, y3),
        ]
    }
}

impl Point for Vec3 {
    type Scalar = Real;
    type Vector = Vec3;
    #[inline(always)]
    fn splat(v: Vec3) -> Self {
        v
    }
    #[inline(always)]
    fn zero() -> Self {
        Vec3::ZERO
    }
    #[inline(always)]
    fn inner(self, o: Self) -> Real {
        Vec3::dot(self, o)
    }
    #[inline(always)]
    fn scale(self, k: Real) -> Self {
        self * k
    }
    #[inline(always)]
    fn abs_sum(self) -> Real {
        self.x.abs() + self.y.abs() + self.z.abs()
    }
    #[inline(always)]
    fn select(mask: bool, a: Self, b: Self) -> Self {
        if mask { a } else { b }
    }
    #[inline(always)]
    fn pushed_out(self, colliders: Colliders<'_>) -> Self {
        colliders.pushed_out(self)
    }
    #[inline(always)]
    fn constrained_by(self, colliders: Colliders<'_>, v: Self, sign: Real) -> Self {
        colliders.constrained(self, v, sign)
    }
    type Touch = Option<Vec3>;
    #[inline(always)]
    fn touch(self, colliders: Colliders<'_>) -> Option<Vec3> {
        colliders.touching(self).map(|(_, normal)| normal)
    }
    #[inline(always)]
    fn constrained_at(touch: Option<Vec3>, v: Self, sign: Real) -> Self {
        constrained_along(touch, v, sign)
    }
}

// Groups of any width: the colliders' queries go lane by lane, each lane through the one-vertex
// query; the arithmetic that follows a query is element-wise, in the one-vertex code's order.
impl<L: Lane> Point for LaneVec3<L> {
    type Scalar = L;
    type Vector = Vec3;
    #[inline(always)]
    fn splat(v: Vec3) -> Self {
        LaneVec3::new(L::splat(v.x), L::splat(v.y), L::splat(v.z))
    }
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(Vec3::ZERO)
    }
    #[inline(always)]
    fn inner(self, o: Self) -> L {
        LaneVec3::dot(self, o)
    }
    #[inline(always)]
    fn scale(self, k: L) -> Self {
        LaneVec3::scale(self, k)
    }
    #[inline(always)]
    fn abs_sum(self) -> L {
        self.x.abs() + self.y.abs() + self.z.abs()
    }
    #[inline(always)]
    fn select(mask: L::Mask, a: Self, b: Self) -> Self {
        LaneVec3::select(mask, a, b)
    }
    #[inline(always)]
    fn pushed_out(self, colliders: Colliders<'_>) -> Self {
        map_lane_vectors(|lane| colliders.pushed_out(lane_vec3(&self, lane)))
    }
    #[inline(always)]
    fn constrained_by(self, colliders: Colliders<'_>, v: Self, sign: Real) -> Self {
        map_lane_vectors(|lane| {
            colliders.constrained(lane_vec3(&self, lane), lane_vec3(&v, lane), sign)
        })
    }
    /// The normal of the collider each lane touches, zero in the lanes that touch none.
    type Touch = LaneVec3<L>;
    #[inline(always)]
    fn touch(self, colliders: Colliders<'_>) -> Self::Touch {
        map_lane_vectors(|lane| {
            lane_vec3(&self, lane)
                .touch(colliders)
                .unwrap_or(Vec3::ZERO)
        })
    }
    /// `constrained_along` in every lane: a lane without a normal (zero) has a zero or NaN
    /// component, never positive, and keeps `v`; the others take the one-vertex arithmetic.
    #[inline(always)]
    fn constrained_at(normal: Self::Touch, v: Self, sign: Real) -> Self {
        let along = normal.dot(v);
        let into = (along * L::splat(sign)).gt(L::splat(0.0));
        LaneVec3::select(into, v - normal.scale(along), v)
    }
}

impl Grouped for Vec3 {
    type Group = LaneVec3<Lanes>;
    type Wide<L: Lane> = LaneVec3<L>;
    #[inline(always)]
    fn group(v: [Vec3; LANES]) -> LaneVec3<Lanes> {
        LaneVec3::from_vectors(v)
    }
    const ALL_AXES: u8 = 0b111;
    #[inline(always)]
    fn resolve_colliders(
        colliders: &[Collider<'_>],
        x: &mut Self,
        v: &mut Self,
        resting_speed_and_step: (Real, Real),
    ) -> usize {
        collider::resolve(colliders, x, v, resting_speed_and_step)
    }
    #[inline(always)]
    fn collider_velocity(
        colliders: Colliders<'_>,
        x: Self,
        g: Self,
        m: Real,
        h: Real,
        v: Self,
    ) -> Self {
        colliders.implicit_velocity((x, g, m, h), v)
    }
    #[inline(always)]
    fn collider_contact(colliders: Colliders<'_>, x: Self) -> Option<Contact<Self>> {
        colliders.contact(x)
    }
    #[inline(always)]
    fn shifted_colliders<'a>(colliders: &'a [Collider<'a>], origin: Self) -> Colliders<'a> {
        Colliders::new(colliders).shifted(origin)
    }
    #[inline(always)]
    fn axes_from(self, source: Vec3, fixed: u8) -> Vec3 {
        Vec3::new(
            pick(self.x, source.x, fixed, 1),
            pick(self.y, source.y, fixed, 2),
            pick(self.z, source.z, fixed, 4),
        )
    }
    #[inline(always)]
    fn ungroup(group: LaneVec3<Lanes>) -> [Vec3; LANES] {
        group.to_vectors()
    }
}

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
    pub fn new(ground: Option<&Ground<P::Vector>>) -> Self {
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
    use super::super::super::lanes::{LANES, Lane, LaneVec3, Lanes};
    use super::super::super::types::{Real, Vec3};
    use super::super::Ground;
    use super::{Floor, Grouped};

    /// The contact test holds at equality: a vertex exactly at the origin, on a ground plane
    /// through it, has height 0 and tolerance 0, and is in contact (one at a time and in every
    /// lane); just above the tolerance it is not, and a NaN position never is.
    #[test]
    fn contact_holds_at_equality_in_every_representation() {
        let ground = Ground::new(Vec3::Z, 0.0);
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
        use super::super::super::types::Quat;
        use super::super::collider::{Collider, Colliders};
        let ground = Ground::new(Vec3::Z, -0.5);
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

//! Per-vertex arithmetic written once for one vertex and for a group of vertices: the hidden half
//! of the sealed `element::Vector` (every `V: Vector` is [`Grouped`]), here below `element` and
//! `step` so that neither imports it from a layer above. The colliders' queries enter through
//! [`Obstacles`], implemented by `step/contact`'s `Colliders`; the queries of the steppers that
//! return contact records are generic functions there (`step/contact/vertex.rs`), dispatching on
//! [`Grouped::SPACE_DIM`].
//!
//! The relaxation's vertex passes (gradient, direction, trial points; `step/vertex_pass/passes.rs`)
//! run on x86_64 in groups of the width `simd::dispatch` picks (16 f32 lanes on AVX-512, 8 on AVX2,
//! then narrower groups down to [`LANES`]) as [`Point`]s with lane coordinates ([`Grouped::Wide`])
//! and the rest one at a time with the plain vector, elsewhere every vertex one at a time, through
//! the same generic code: element-wise IEEE operations and selects instead of branches, so every
//! vertex gets the same bits either way. Sums over vertices follow one fixed order on every target
//! (`LaneSum` in `lanes/mod.rs`). `LaneVec2` lives here rather than next to `LaneVec3`: only the
//! steppers' vertex arithmetic needs 2D lanes.

use core::ops::{Add, Neg, Sub};

use super::super::types::{Real, Vec2, Vec3};
use super::{LANES, Lane, LaneArray, LaneVec3, Lanes, each_lane, lane_vec3, map_lane_vectors};

/// The 3D obstacles a point may be pushed out of or constrained by: the queries of
/// `step/contact`'s `Colliders`, named here so that [`Point`] can ask them without knowing the
/// type. Public in a private module, like [`Point`].
pub trait Obstacles: Copy {
    /// `x` pushed out of every obstacle, in order (m).
    fn pushed_out(&self, x: Vec3) -> Vec3;
    /// `v` without its component into the first obstacle touching `x` where `sign` times that
    /// component is positive.
    fn constrained(&self, x: Vec3, v: Vec3, sign: Real) -> Vec3;
    /// The outward unit normal of the first obstacle touching `x`, if any.
    fn touching_normal(&self, x: Vec3) -> Option<Vec3>;
}

/// One vertex vector, or [`LANES`] of them. Public in a private module: the hidden half of the
/// sealed `element::Vector` trait.
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
    fn pushed_out<O: Obstacles>(self, colliders: O) -> Self;
    /// `v` without its component into the first collider touching `self`, `sign` as in
    /// `Floor::constrain` (the identity in 2D). Lane by lane for groups.
    fn constrained_by<O: Obstacles>(self, colliders: O, v: Self, sign: Real) -> Self;
    /// The outward normal of the first collider touching `self` (per lane for groups; nothing
    /// in 2D), for several constraints at one point with one query (`Floor::touch`).
    type Touch: Copy;
    /// [`Touch`](Self::Touch) at `self`.
    fn touch<O: Obstacles>(self, colliders: O) -> Self::Touch;
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
    /// The number of coordinates: 2 or 3. The colliders act on 3D points only
    /// (`step/contact/vertex.rs` dispatches on it).
    const SPACE_DIM: usize;
    /// `self` as a 3D vector: itself in 3D, `z = 0` in 2D.
    fn to_vec3(self) -> Vec3;
    /// The vector of `v`: itself in 3D, its `x` and `y` in 2D.
    fn from_vec3(v: Vec3) -> Self;
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

/// The [`Point`] arithmetic of one vertex's plain vector `$vector` (coordinates `$first`,
/// `$axis`...): glam's, `abs_sum` added in coordinate order.
macro_rules! one_vertex_point {
    ($vector:ident: $first:ident $(, $axis:ident)*) => {
        type Scalar = Real;
        type Vector = $vector;
        #[inline(always)]
        fn splat(v: $vector) -> Self {
            v
        }
        #[inline(always)]
        fn zero() -> Self {
            $vector::ZERO
        }
        #[inline(always)]
        fn inner(self, o: Self) -> Real {
            $vector::dot(self, o)
        }
        #[inline(always)]
        fn scale(self, k: Real) -> Self {
            self * k
        }
        #[inline(always)]
        fn abs_sum(self) -> Real {
            self.$first.abs() $(+ self.$axis.abs())*
        }
        #[inline(always)]
        fn select(mask: bool, a: Self, b: Self) -> Self {
            if mask { a } else { b }
        }
    };
}

/// The [`Point`] arithmetic of a group of `L` lanes of `$vector` (coordinates `$first`,
/// `$axis`...): that of its [`Wide`] impl, `abs_sum` added in coordinate order.
macro_rules! wide_point {
    ($vector:ident: $first:ident $(, $axis:ident)*) => {
        type Scalar = L;
        type Vector = $vector;
        #[inline(always)]
        fn splat(v: $vector) -> Self {
            Self::wide_splat(v)
        }
        #[inline(always)]
        fn zero() -> Self {
            Self::splat($vector::ZERO)
        }
        #[inline(always)]
        fn inner(self, o: Self) -> L {
            self.wide_inner(o)
        }
        #[inline(always)]
        fn scale(self, k: L) -> Self {
            self.wide_scale(k)
        }
        #[inline(always)]
        fn abs_sum(self) -> L {
            self.$first.abs() $(+ self.$axis.abs())*
        }
        #[inline(always)]
        fn select(mask: L::Mask, a: Self, b: Self) -> Self {
            Self::wide_select(mask, a, b)
        }
    };
}

/// The [`Point`] items of a 2D point, plain or in lanes, about colliders: they act on 3D
/// points only, so every query is the identity and touches nothing.
macro_rules! no_colliders_point {
    () => {
        #[inline(always)]
        fn pushed_out<O: Obstacles>(self, _: O) -> Self {
            self
        }
        #[inline(always)]
        fn constrained_by<O: Obstacles>(self, _: O, v: Self, _: Real) -> Self {
            v
        }
        type Touch = ();
        #[inline(always)]
        fn touch<O: Obstacles>(self, _: O) {}
        #[inline(always)]
        fn constrained_at((): (), v: Self, _: Real) -> Self {
            v
        }
    };
}

impl Point for Vec2 {
    one_vertex_point!(Vec2: x, y);
    no_colliders_point!();
}

impl<L: Lane> Point for LaneVec2<L> {
    wide_point!(Vec2: x, y);
    no_colliders_point!();
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
    const SPACE_DIM: usize = 2;
    #[inline(always)]
    fn to_vec3(self) -> Vec3 {
        self.extend(0.0)
    }
    #[inline(always)]
    fn from_vec3(v: Vec3) -> Vec2 {
        v.truncate()
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
    one_vertex_point!(Vec3: x, y, z);
    #[inline(always)]
    fn pushed_out<O: Obstacles>(self, colliders: O) -> Self {
        colliders.pushed_out(self)
    }
    #[inline(always)]
    fn constrained_by<O: Obstacles>(self, colliders: O, v: Self, sign: Real) -> Self {
        colliders.constrained(self, v, sign)
    }
    type Touch = Option<Vec3>;
    #[inline(always)]
    fn touch<O: Obstacles>(self, colliders: O) -> Option<Vec3> {
        colliders.touching_normal(self)
    }
    #[inline(always)]
    fn constrained_at(touch: Option<Vec3>, v: Self, sign: Real) -> Self {
        constrained_along(touch, v, sign)
    }
}

// Groups of any width: the colliders' queries go lane by lane, each lane through the one-vertex
// query; the arithmetic that follows a query is element-wise, in the one-vertex code's order.
impl<L: Lane> Point for LaneVec3<L> {
    wide_point!(Vec3: x, y, z);
    #[inline(always)]
    fn pushed_out<O: Obstacles>(self, colliders: O) -> Self {
        map_lane_vectors(|lane| colliders.pushed_out(lane_vec3(&self, lane)))
    }
    #[inline(always)]
    fn constrained_by<O: Obstacles>(self, colliders: O, v: Self, sign: Real) -> Self {
        map_lane_vectors(|lane| {
            colliders.constrained(lane_vec3(&self, lane), lane_vec3(&v, lane), sign)
        })
    }
    /// The normal of the collider each lane touches, zero in the lanes that touch none.
    type Touch = LaneVec3<L>;
    #[inline(always)]
    fn touch<O: Obstacles>(self, colliders: O) -> Self::Touch {
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
    const SPACE_DIM: usize = 3;
    #[inline(always)]
    fn to_vec3(self) -> Vec3 {
        self
    }
    #[inline(always)]
    fn from_vec3(v: Vec3) -> Vec3 {
        v
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

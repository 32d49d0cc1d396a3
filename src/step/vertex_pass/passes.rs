//! The relaxation's passes over the vertices: the gradient of `Phi` from the elastic forces, the
//! preconditioned descent direction and the trial points. On x86_64 (`math::BATCH_VERTICES`)
//! each runs in groups of the width `simd::dispatch` picks (16 f32 lanes on AVX-512, 8 on AVX2,
//! 4 on SSE and at the scalar width; [`Grouped::Wide`], see `lanes/point.rs`), then
//! narrower groups down to [`LANES`], then the rest one at a time (every vertex one at a time
//! elsewhere), through the same generic per-vertex code, so that every vertex gets the same bits
//! either way and every target and width the same sums ([`LaneSum`]).

use super::super::super::element::Vector;
#[cfg(target_arch = "x86_64")]
use super::super::super::lanes::avx2::Avx2Lanes;
#[cfg(target_arch = "x86_64")]
use super::super::super::lanes::avx512::Avx512Lanes;
use super::super::super::lanes::{LANES, Lane, LaneArray, LaneSum, Lanes, MAX_WIDTH};
use super::super::super::math::BATCH_VERTICES;
use super::super::super::types::Real;
use super::super::contact::HalfSpace;
use super::super::contact::collider::Colliders;
use super::super::contact::floor::Floor;
use super::super::contact::friction::Friction;
use super::super::descent::line_search::{copy, slope_along};
use super::super::model::ElasticModel;
use super::super::state::{check_state_lengths, first_bad_mass, first_non_finite};
use super::point::{Grouped, Point, Wide};
use super::{Blocks, Split};
use crate::error::StepError;
use crate::simd::{WidthKernel, dispatch};

/// What every vertex pass needs besides the buffers, for points of type `P`.
#[derive(Clone, Copy)]
struct Frame<'a, P: Point> {
    /// The time step `h` (0 without inertia).
    h: P::Scalar,
    /// `1 / h^2`, or 0 without inertia.
    inertia: P::Scalar,
    gravity: P,
    floor: Floor<'a, P>,
}

impl<P: Point> Frame<'_, P> {
    #[inline(always)]
    fn new(
        h: Real,
        inertia: Real,
        gravity: P::Vector,
        ground: Option<&HalfSpace<P::Vector>>,
    ) -> Self {
        Frame {
            h: P::Scalar::splat(h),
            inertia: P::Scalar::splat(inertia),
            gravity: P::splat(gravity),
            floor: Floor::new(ground),
        }
    }

    /// The gradient of `Phi` at a free vertex at `x` (`force` the elastic force there, `start`
    /// its `x_n`, `velocity` its `v_n`, `m` its mass), its term of `Phi` (inertia and gravity;
    /// the elastic energy is summed by the force kernel) and its term of the squared residual
    /// `|grad Phi|^2`, projected on the contact constraint. All zero where `free` is not set
    /// (`None`: every lane free).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn gradient(
        &self,
        x: P,
        force: P,
        start: P,
        velocity: P,
        m: P::Scalar,
        free: Option<<P::Scalar as Lane>::Mask>,
    ) -> (P, P::Scalar, P::Scalar) {
        let offset = x - (start + velocity.scale(self.h));
        let weight = m * self.inertia;
        let phi = P::Scalar::splat(0.5) * weight * offset.inner(offset)
            - m * self.gravity.inner(x - start);
        // The kernel added the forces, -dE/dx: flip them into dE/dx.
        let gradient = offset.scale(weight) - force - self.gravity.scale(m);
        let projected = self
            .floor
            .constrain(self.floor.contact(x), x, gradient, 1.0);
        let residual = projected.inner(projected);
        let Some(free) = free else {
            return (gradient, phi, residual);
        };
        let zero = P::Scalar::splat(0.0);
        (
            P::select(free, gradient, P::zero()),
            P::Scalar::select(free, phi, zero),
            P::Scalar::select(free, residual, zero),
        )
    }

    /// The projected preconditioned descent direction `-P^-1 g` at a vertex at `x` with gradient
    /// `g` and preconditioner `p` (zero where `p` is not positive), plus `momentum` times the
    /// last step `x - previous` when given, and its term of the slope `g.d`
    /// ([`Floor::descent`]).
    #[inline(always)]
    fn direction(
        &self,
        x: P,
        g: P,
        p: P::Scalar,
        heavy_ball: Option<(P, P::Scalar)>,
    ) -> (P, P::Scalar) {
        let zero = P::Scalar::splat(0.0);
        let plain = (P::Scalar::splat(-1.0) / p, Some(p.gt(zero)));
        self.floor.descent(x, g, plain, heavy_ball)
    }

    /// `target`, projected on the ground, where `free` (everywhere if `None`); `x` elsewhere.
    #[inline(always)]
    fn moved(&self, x: P, target: P, free: Option<<P::Scalar as Lane>::Mask>) -> P {
        let moved = self.floor.project(target);
        match free {
            Some(free) => P::select(free, moved, x),
            None => moved,
        }
    }
}

/// The [`Frame`] of a solve, for single vertices; [`wide`](Frames::wide) gives the same for
/// groups of any width, built only where the passes group (`math::BATCH_VERTICES`).
#[derive(Clone, Copy)]
pub(crate) struct Frames<'a, V: Grouped> {
    single: Frame<'a, V>,
    /// Friction, whose tangent curvature the relaxation's direction adds to its bound at the
    /// vertices in contact (`None` for none).
    friction: Option<Friction<'a, V>>,
}

impl<'a, V: Grouped> Frames<'a, V> {
    /// The frames of a solve: time step `h` and `inertia = 1 / h^2` (both 0 without inertia),
    /// `gravity`, and `ground` with a unit normal.
    pub fn new(h: Real, inertia: Real, gravity: V, ground: Option<&HalfSpace<V>>) -> Self {
        Frames {
            single: Frame::new(h, inertia, gravity, ground),
            friction: None,
        }
    }

    /// These frames with `friction` (ignored if it is inactive): the direction passes then
    /// scale the tangential direction at the vertices in contact.
    pub fn with_friction(self, friction: Friction<'a, V>) -> Self {
        Frames {
            friction: friction.is_active().then_some(friction),
            ..self
        }
    }

    /// These frames with the (validated) `colliders` (in the frames' coordinates), which every
    /// pass then applies after the ground.
    pub fn with_colliders(self, colliders: Colliders<'a>) -> Self {
        let mut single = self.single;
        single.floor = single.floor.with_colliders(colliders);
        Frames { single, ..self }
    }

    /// The frame for groups of `L::WIDTH` vertices: every value in every lane.
    #[inline(always)]
    fn wide<L: Lane>(&self) -> Frame<'a, V::Wide<L>> {
        let single = &self.single;
        Frame {
            h: L::splat(single.h),
            inertia: L::splat(single.inertia),
            gravity: <V::Wide<L> as Point>::splat(single.gravity),
            floor: single.floor.widened(),
        }
    }

    /// The ground and the colliders, for one vertex.
    pub fn floor(&self) -> &Floor<'a, V> {
        &self.single.floor
    }

    /// The direction `d` (slope term `slope`) of a vertex at `x` moved from `start`, with
    /// gradient `g` and isotropic bound `p`, with friction's tangent curvature `b` added to the
    /// bound across the contact: `d - b / (p + b) d_t`, `d_t` the tangential part
    /// (`step/contact/friction.rs`: `b = mu lambda f1(y) / y` bounds the tangent block). Unchanged
    /// without a frictional contact.
    #[inline(always)]
    fn damped(&self, (x, start, g): (V, V, V), p: Real, (d, slope): (V, Real)) -> (V, Real)
    where
        V: Vector,
    {
        let Some((slip, force)) = self.friction.and_then(|f| f.slip(x, start, g)) else {
            return (d, slope);
        };
        let curvature = force * slip.curvature();
        let share = curvature / (p + curvature);
        if !(share > 0.0 && share <= 1.0) {
            return (d, slope);
        }
        let normal = slip.normal();
        let tangential = d - normal * normal.dot(d);
        let floor = &self.single.floor;
        let g = floor.constrain(floor.contact(x), x, g, 1.0);
        (d - tangential * share, slope - share * g.dot(tangential))
    }

    /// The direction and slope term of vertex `i` alone, at `x` with gradient `g` (plus the
    /// heavy-ball term when given), through [`damped`](Self::damped): the one-vertex code of
    /// the direction and Chebyshev passes, whose groups take
    /// [`damped_wide`](Self::damped_wide).
    #[inline(always)]
    fn damped_one(
        &self,
        vertices: &Vertices<'_, V>,
        i: usize,
        (x, g): (V, V),
        heavy_ball: Option<(V, Real)>,
    ) -> (V, Real)
    where
        V: Vector,
    {
        let frame = &self.single;
        let p = vertices.diagonal_one(frame.inertia, i);
        let direction = frame.direction(x, g, p, heavy_ball);
        let start = vertices.start.get(i).copied().unwrap_or(x);
        self.damped((x, start, g), p, direction)
    }

    /// [`damped`](Self::damped) for the group of `L::WIDTH` vertices from vertex `first` on, at
    /// `x` (a chunk) moved from `start` (every vertex's `x_n`; `x` where it runs out) with
    /// gradients `g` (a chunk) and bounds `p`: the grouped direction `d` and slope terms `slope`
    /// are unchanged unless a vertex of the group has a frictional contact, and then go through
    /// the one-vertex code lane by lane, so that every vertex gets the bits it gets alone. Most
    /// groups touch nothing and pay only the contact test.
    #[inline(always)]
    fn damped_wide<L: LaneArray>(
        &self,
        (x, start, g): (&[V], &[V], &[V]),
        first: usize,
        p: L,
        (d, slope): (V::Wide<L>, L),
    ) -> (V::Wide<L>, L)
    where
        V: Vector,
    {
        let Some(friction) = &self.friction else {
            return (d, slope);
        };
        if !x.iter().any(|&x| friction.contact(x).is_some()) {
            return (d, slope);
        }
        let start = start.get(first..).unwrap_or(&[]);
        let mut directions = [V::zero(); MAX_WIDTH];
        d.store(&mut directions);
        let (p, mut slopes) = (p.to_lane_array(), slope.to_lane_array());
        for (lane, d) in directions.iter_mut().enumerate().take(L::WIDTH) {
            let (Some(&x), Some(&g)) = (x.get(lane), g.get(lane)) else {
                continue;
            };
            let start = start.get(lane).copied().unwrap_or(x);
            let slope = L::lane_value(&slopes, lane);
            let (damped, slope) = self.damped((x, start, g), L::lane_value(&p, lane), (*d, slope));
            *d = damped;
            L::set_lane_value(&mut slopes, lane, slope);
        }
        (V::Wide::<L>::load(&directions), L::from_lane_array(slopes))
    }
}

/// The per-vertex inputs every pass shares.
#[derive(Clone, Copy)]
pub(crate) struct Vertices<'a, V> {
    /// Lumped masses (kg).
    pub masses: &'a [Real],
    /// Pinned flags, or empty for none.
    pub pinned: &'a [bool],
    /// The preconditioner's stiffness bounds (N/m).
    pub stiffness: &'a [Real],
    /// `x_n`.
    pub start: &'a [V],
    /// `v_n`, or empty without inertia.
    pub velocities: &'a [V],
}

/// The first `L::WIDTH` values of `values` as a group (zeros past its end). The explicit
/// step's update loads its masses here too.
#[inline(always)]
pub(crate) fn load_scalars<L: LaneArray>(values: &[Real]) -> L {
    let mut quarters = [[0.0; LANES]; 4];
    for (q, quarter) in quarters.iter_mut().enumerate().take(L::WIDTH / LANES) {
        if let Some(chunk) = values.get(q * LANES..).and_then(<[Real]>::first_chunk) {
            *quarter = *chunk;
        }
    }
    L::from_quarters(quarters)
}

/// Zeroes `chunk`.
#[inline(always)]
fn clear<V: Grouped>(chunk: &mut [V]) {
    chunk.fill(V::zero());
}

/// The mask of the free (not pinned) vertices of the group of `L::WIDTH` vertices from vertex
/// `first` on; `None` if no vertex is pinned (`pinned` empty). The explicit step's update
/// takes its groups' masks here too.
#[inline(always)]
pub(crate) fn free_lanes<L: LaneArray>(pinned: &[bool], first: usize) -> Option<L::Mask> {
    if pinned.is_empty() {
        return None;
    }
    let flags = pinned.get(first..).unwrap_or(&[]);
    let mut quarters = [[0.0; LANES]; 4];
    for (q, quarter) in quarters.iter_mut().enumerate().take(L::WIDTH / LANES) {
        for (j, value) in quarter.iter_mut().enumerate() {
            *value = match flags.get(q * LANES + j) {
                Some(true) => 1.0,
                _ => 0.0,
            };
        }
    }
    Some(L::splat(0.5).gt(L::from_quarters(quarters)))
}

/// Whether vertex `i` is free, as the one-vertex code takes it.
#[inline(always)]
fn free_one(pinned: &[bool], i: usize) -> Option<bool> {
    Some(!pinned.get(i).copied().unwrap_or(false))
}

impl<'a, V: Grouped> Vertices<'a, V> {
    /// `v_n`, or (without inertia, when `h = 0`) `x_n` standing in for it: a full-length buffer
    /// either way, so that the passes need not branch on it.
    #[inline(always)]
    fn velocities(&self) -> &'a [V] {
        if self.velocities.is_empty() {
            self.start
        } else {
            self.velocities
        }
    }

    /// The preconditioners `P_i = k_i + m_i / h^2` of the `L::WIDTH` vertices from vertex
    /// `first` on (zero past the end).
    #[inline(always)]
    fn diagonal_group<L: LaneArray>(&self, inertia: L, first: usize) -> L {
        let at = |values: &'a [Real]| load_scalars::<L>(values.get(first..).unwrap_or(&[]));
        at(self.stiffness) + at(self.masses) * inertia
    }

    /// The preconditioner of vertex `i`.
    #[inline(always)]
    fn diagonal_one(&self, inertia: Real, i: usize) -> Real {
        let at = |values: &[Real]| values.get(i).copied().unwrap_or(0.0);
        at(self.stiffness) + at(self.masses) * inertia
    }
}

/// A vertex pass over whole groups of vertices of any width; [`run_groups`] runs it at the
/// width [`dispatch`] picks.
trait GroupPass {
    /// The whole groups of `L::WIDTH` vertices from the block's vertex `done` (a multiple of
    /// [`LANES`]) on, in order: returns the vertices done.
    fn groups<L: LaneArray>(&mut self, done: usize) -> usize;
}

/// A [`GroupPass`] at the width [`dispatch`] picks: whole groups of the widest lanes first,
/// then of narrower ones down to [`LANES`]. Returns the vertices done; the caller takes the
/// rest one at a time. The scalar width keeps the groups of [`LANES`] the passes ran at every
/// width before they ran wider (one vertex at a time they cost 0.09 force passes more per
/// relaxation iteration; the same bits either way).
struct Widths<G>(G);

impl<G: GroupPass> WidthKernel for Widths<G> {
    type Output = usize;

    #[inline(always)]
    fn scalar(mut self) -> usize {
        self.0.groups::<Lanes>(0)
    }

    #[inline(always)]
    fn sse(mut self) -> usize {
        self.0.groups::<Lanes>(0)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx2(mut self) -> usize {
        let done = self.0.groups::<Avx2Lanes>(0);
        self.0.groups::<Lanes>(done)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx512(mut self) -> usize {
        let done = self.0.groups::<Avx512Lanes>(0);
        let done = self.0.groups::<Avx2Lanes>(done);
        self.0.groups::<Lanes>(done)
    }
}

/// `pass` over the whole groups at the width [`dispatch`] picks where the passes group
/// (`math::BATCH_VERTICES`): returns the vertices done (none elsewhere).
#[inline(always)]
fn run_groups(pass: impl GroupPass) -> usize {
    if BATCH_VERTICES {
        dispatch(Widths(pass))
    } else {
        0
    }
}

/// The gradient pass's whole groups (see `gradient_block`), its two sums added lane by lane.
struct GradientGroups<'p, 'a, V: Grouped> {
    frames: &'p Frames<'a, V>,
    vertices: Vertices<'p, V>,
    x: &'p [V],
    gradient: &'p mut [V],
    sums: &'p mut (LaneSum, LaneSum),
}

impl<V: Grouped> GroupPass for GradientGroups<'_, '_, V> {
    #[inline(always)]
    fn groups<L: LaneArray>(&mut self, mut done: usize) -> usize {
        let frame = &self.frames.wide::<L>();
        let vertices = &self.vertices;
        let velocities = vertices.velocities();
        let (phi, residual) = &mut *self.sums;
        let width = L::WIDTH;
        while done + width <= self.x.len() {
            let range = done..done + width;
            let (Some(g), Some(x), Some(start), Some(velocity), Some(m)) = (
                self.gradient.get_mut(range.clone()),
                self.x.get(range.clone()),
                vertices.start.get(range.clone()),
                velocities.get(range.clone()),
                vertices.masses.get(range),
            ) else {
                break;
            };
            let (gradient, phi_term, residual_term) = frame.gradient(
                V::Wide::<L>::load(x),
                V::Wide::<L>::load(g),
                V::Wide::<L>::load(start),
                V::Wide::<L>::load(velocity),
                load_scalars::<L>(m),
                free_lanes::<L>(vertices.pinned, done),
            );
            gradient.store(g);
            phi.add_wide(phi_term);
            residual.add_wide(residual_term);
            done += width;
        }
        done
    }
}

/// Turns the elastic forces in `gradient` (N, added by the kernel at `x`) into the gradient of
/// `Phi` (zero at pinned vertices). Returns the inertia and gravity part of `Phi` (J) and the
/// squared residual `|grad Phi|^2` (N^2) projected on the contact constraints.
fn gradient_block<V: Grouped>(
    frames: &Frames<V>,
    vertices: &Vertices<'_, V>,
    x: &[V],
    gradient: &mut [V],
) -> (Real, Real) {
    let mut sums = (LaneSum::new(x.len()), LaneSum::new(x.len()));
    let done = run_groups(GradientGroups {
        frames,
        vertices: *vertices,
        x,
        gradient: &mut *gradient,
        sums: &mut sums,
    });
    let (phi, residual) = &mut sums;
    let velocities = vertices.velocities();
    let frame = &frames.single;
    let zero = V::zero();
    let rows = gradient.iter_mut().zip(x).enumerate();
    for (i, (g, &x)) in rows.skip(done) {
        let at = |values: &[V]| values.get(i).copied().unwrap_or(zero);
        let (gradient, phi_term, residual_term) = frame.gradient(
            x,
            *g,
            at(vertices.start),
            at(velocities),
            vertices.masses.get(i).copied().unwrap_or(0.0),
            free_one(vertices.pinned, i),
        );
        *g = gradient;
        phi.add_single(i, phi_term);
        residual.add_single(i, residual_term);
    }
    (phi.total(), residual.total())
}

/// A trial point buffer and the gradient buffer of its evaluation, which the pass writing the
/// point zeroes for the force kernel to add into.
pub(crate) struct TrialPoint<'t, V> {
    pub positions: &'t mut [V],
    pub gradient: &'t mut [V],
}

impl<V> TrialPoint<'_, V> {
    /// The point and gradient entries of every vertex.
    #[inline(always)]
    fn rows(&mut self) -> impl Iterator<Item = (&mut V, &mut V)> {
        self.positions.iter_mut().zip(self.gradient.iter_mut())
    }
}

/// Writes the projected preconditioned direction at `x` (with gradient `gradient`; plus
/// `momentum` times the last step `x_k - x_{k-1}`, `x_{k-1}` read from `trial.positions`, when
/// given) into `direction`, and in the same pass the trial point `x + alpha d` (projected on the
/// ground; `x` at pinned vertices) into `trial`, zeroing its gradient buffer. Returns the slope
/// `grad.d`.
fn direction_block<V: Grouped + Vector>(
    frames: &Frames<V>,
    vertices: &Vertices<'_, V>,
    (x, gradient): (&[V], &[V]),
    direction: &mut [V],
    momentum: Option<Real>,
    mut trial: TrialPoint<'_, V>,
    alpha: Real,
) -> Real {
    let mut slope = LaneSum::new(x.len());
    let done = run_groups(DampedGroups {
        frames,
        vertices: *vertices,
        x,
        gradient,
        trial: &mut trial,
        target: DescentTarget {
            direction: &mut *direction,
            momentum,
            alpha,
            slope: &mut slope,
        },
    });
    let frame = &frames.single;
    let rows = direction
        .iter_mut()
        .zip(trial.rows())
        .zip(x.iter().zip(gradient))
        .enumerate();
    for (i, ((d_slot, (t_slot, g_slot)), (&x, &g))) in rows.skip(done) {
        let heavy_ball = momentum.map(|m| (*t_slot, m));
        let (d, slope_term) = frames.damped_one(vertices, i, (x, g), heavy_ball);
        *d_slot = d;
        *t_slot = frame.moved(x, x + d.scale(alpha), free_one(vertices.pinned, i));
        *g_slot = V::zero();
        slope.add_single(i, slope_term);
    }
    slope.total()
}

/// What the direction and Chebyshev passes do with a group's damped direction, the only part
/// in which their whole groups ([`DampedGroups`]) differ.
trait GroupTarget<V: Grouped> {
    /// Whether the pass's own buffers hold the group of vertices ending before `end`.
    fn holds(&self, end: usize) -> bool;
    /// The heavy-ball term of the group's direction, `(x_{k-1}, momentum)` with `x_{k-1}` read
    /// from the group's trial slots `previous`, if the pass has one.
    fn heavy_ball<L: LaneArray>(&self, previous: &[V]) -> Option<(V::Wide<L>, L)>;
    /// The unprojected trial point of the group of vertices from `first` at `position`, along
    /// its damped direction `d` with slope terms `slope`; `previous` is the group's trial slots
    /// before the pass overwrites them.
    fn target<L: LaneArray>(
        &mut self,
        first: usize,
        position: V::Wide<L>,
        previous: &[V],
        d: (V::Wide<L>, L),
    ) -> V::Wide<L>;
}

/// The whole groups of the direction pass (`direction_block`, with [`DescentTarget`]) and of the
/// Chebyshev pass (`chebyshev_block`, with [`ChebyshevTarget`]): per group, the preconditioned
/// direction at `x` (damped by friction where a vertex has a frictional contact), the trial
/// point `target` makes of it, projected on the ground (`x` at pinned vertices), and the trial
/// gradient zeroed.
struct DampedGroups<'p, 'a, 't, V: Grouped, T> {
    frames: &'p Frames<'a, V>,
    vertices: Vertices<'p, V>,
    x: &'p [V],
    gradient: &'p [V],
    trial: &'p mut TrialPoint<'t, V>,
    target: T,
}

impl<V: Grouped + Vector, T: GroupTarget<V>> GroupPass for DampedGroups<'_, '_, '_, V, T> {
    #[inline(always)]
    fn groups<L: LaneArray>(&mut self, done: usize) -> usize {
        // Monomorphised twice, so that the frictionless loop carries no friction test.
        match self.frames.friction {
            None => self.damped_groups::<L, false>(done),
            Some(_) => self.damped_groups::<L, true>(done),
        }
    }
}

impl<V: Grouped + Vector, T: GroupTarget<V>> DampedGroups<'_, '_, '_, V, T> {
    /// [`GroupPass::groups`], each direction through [`Frames::damped_wide`] if `FRICTION`.
    #[inline(always)]
    fn damped_groups<L: LaneArray, const FRICTION: bool>(&mut self, mut done: usize) -> usize {
        let frames = self.frames;
        let frame = &frames.wide::<L>();
        let vertices = &self.vertices;
        let trial = &mut *self.trial;
        let width = L::WIDTH;
        while done + width <= self.x.len() && self.target.holds(done + width) {
            let range = done..done + width;
            let (Some(t_slot), Some(g_slot), Some(x), Some(g)) = (
                trial.positions.get_mut(range.clone()),
                trial.gradient.get_mut(range.clone()),
                self.x.get(range.clone()),
                self.gradient.get(range),
            ) else {
                break;
            };
            let p = vertices.diagonal_group(frame.inertia, done);
            let position = V::Wide::<L>::load(x);
            let heavy_ball = self.target.heavy_ball::<L>(t_slot);
            let direction = frame.direction(position, V::Wide::<L>::load(g), p, heavy_ball);
            let damped = if FRICTION {
                frames.damped_wide((x, vertices.start, g), done, p, direction)
            } else {
                direction
            };
            let target = self.target.target(done, position, t_slot, damped);
            let free = free_lanes::<L>(vertices.pinned, done);
            frame.moved(position, target, free).store(t_slot);
            clear(g_slot);
            done += width;
        }
        done
    }
}

/// The direction pass's use of a group's direction (see `direction_block`): stored in
/// `direction`, its slope added lane by lane, the trial point at step `alpha`.
struct DescentTarget<'p, V> {
    direction: &'p mut [V],
    momentum: Option<Real>,
    alpha: Real,
    slope: &'p mut LaneSum,
}

impl<V: Grouped> GroupTarget<V> for DescentTarget<'_, V> {
    #[inline(always)]
    fn holds(&self, end: usize) -> bool {
        end <= self.direction.len()
    }

    #[inline(always)]
    fn heavy_ball<L: LaneArray>(&self, previous: &[V]) -> Option<(V::Wide<L>, L)> {
        self.momentum
            .map(|m| (V::Wide::<L>::load(previous), L::splat(m)))
    }

    #[inline(always)]
    fn target<L: LaneArray>(
        &mut self,
        first: usize,
        position: V::Wide<L>,
        _previous: &[V],
        (d, slope): (V::Wide<L>, L),
    ) -> V::Wide<L> {
        if let Some(slots) = self.direction.get_mut(first..first + L::WIDTH) {
            d.store(slots);
        }
        self.slope.add_wide(slope);
        position + d.scale(L::splat(self.alpha))
    }
}

/// The trial pass's whole groups (see [`trial_pass`]).
struct TrialGroups<'p, 'a, 't, V: Grouped> {
    frames: &'p Frames<'a, V>,
    pinned: &'p [bool],
    x: &'p [V],
    direction: &'p [V],
    trial: &'p mut TrialPoint<'t, V>,
    alpha: Real,
}

impl<V: Grouped> GroupPass for TrialGroups<'_, '_, '_, V> {
    #[inline(always)]
    fn groups<L: LaneArray>(&mut self, mut done: usize) -> usize {
        let frame = &self.frames.wide::<L>();
        let alpha = L::splat(self.alpha);
        let trial = &mut *self.trial;
        let width = L::WIDTH;
        while done + width <= self.x.len() {
            let range = done..done + width;
            let (Some(t_slot), Some(g_slot), Some(x), Some(d)) = (
                trial.positions.get_mut(range.clone()),
                trial.gradient.get_mut(range.clone()),
                self.x.get(range.clone()),
                self.direction.get(range),
            ) else {
                break;
            };
            let position = V::Wide::<L>::load(x);
            let target = position + V::Wide::<L>::load(d).scale(alpha);
            let free = free_lanes::<L>(self.pinned, done);
            frame.moved(position, target, free).store(t_slot);
            clear(g_slot);
            done += width;
        }
        done
    }
}

/// Writes the trial point `x + alpha d` (projected on the ground; `x` at pinned vertices) into
/// `trial`, zeroing its gradient buffer: a backtracking step of the line search.
pub(crate) fn trial_pass<V: Grouped>(
    frames: &Frames<V>,
    pinned: &[bool],
    (x, direction): (&[V], &[V]),
    alpha: Real,
    mut trial: TrialPoint<'_, V>,
) {
    let done = run_groups(TrialGroups {
        frames,
        pinned,
        x,
        direction,
        trial: &mut trial,
        alpha,
    });
    let frame = &frames.single;
    let rows = trial.rows().zip(x.iter().zip(direction)).enumerate();
    for (i, ((t_slot, g_slot), (&x, &d))) in rows.skip(done) {
        *t_slot = frame.moved(x, x + d.scale(alpha), free_one(pinned, i));
        *g_slot = V::zero();
    }
}

/// Writes the Chebyshev trial `x_k + omega alpha d + (omega - 1) (x_k - x_{k-1})` (Wang and
/// Yang 2016), `d` the projected preconditioned direction at `x_k` = `x` with `gradient`, into
/// `trial` (whose positions hold `x_{k-1}` if `stepped`; the last step is zero otherwise),
/// zeroing its gradient buffer. `step` is `omega alpha`.
#[allow(clippy::too_many_arguments)]
fn chebyshev_block<V: Grouped + Vector>(
    frames: &Frames<V>,
    vertices: &Vertices<'_, V>,
    (x, gradient): (&[V], &[V]),
    stepped: bool,
    mut trial: TrialPoint<'_, V>,
    step: Real,
    omega: Real,
) {
    let done = run_groups(DampedGroups {
        frames,
        vertices: *vertices,
        x,
        gradient,
        trial: &mut trial,
        target: ChebyshevTarget {
            stepped,
            step,
            omega,
        },
    });
    let frame = &frames.single;
    let rows = trial.rows().zip(x.iter().zip(gradient)).enumerate();
    for (i, ((t_slot, g_slot), (&x, &g))) in rows.skip(done) {
        let last_step = if stepped { x - *t_slot } else { V::zero() };
        let (d, _) = frames.damped_one(vertices, i, (x, g), None);
        let target = x + d.scale(step) + last_step.scale(omega - 1.0);
        *t_slot = frame.moved(x, target, free_one(vertices.pinned, i));
        *g_slot = V::zero();
    }
}

/// The Chebyshev pass's use of a group's direction (see `chebyshev_block`): the trial
/// `x + step d + (omega - 1) (x - x_{k-1})`, the last step zero unless `stepped`.
struct ChebyshevTarget {
    stepped: bool,
    step: Real,
    omega: Real,
}

impl<V: Grouped> GroupTarget<V> for ChebyshevTarget {
    #[inline(always)]
    fn holds(&self, _end: usize) -> bool {
        true
    }

    #[inline(always)]
    fn heavy_ball<L: LaneArray>(&self, _previous: &[V]) -> Option<(V::Wide<L>, L)> {
        None
    }

    #[inline(always)]
    fn target<L: LaneArray>(
        &mut self,
        _first: usize,
        position: V::Wide<L>,
        previous: &[V],
        (d, _): (V::Wide<L>, L),
    ) -> V::Wide<L> {
        let last_step = if self.stepped {
            position - V::Wide::<L>::load(previous)
        } else {
            <V::Wide<L> as Point>::zero()
        };
        position + d.scale(L::splat(self.step)) + last_step.scale(L::splat(self.omega - 1.0))
    }
}

/// A vector type the blocked passes can share between threads.
pub(crate) trait Shared: Grouped + Send + Sync {}
impl<V: Grouped + Send + Sync> Shared for V {}

impl<V: Shared> Split for Vertices<'_, V> {
    #[inline(always)]
    fn split(self, at: usize) -> (Self, Self) {
        let parts = (self.masses, self.pinned, self.stiffness);
        let ((masses, pinned, stiffness), (masses_after, pinned_after, stiffness_after)) =
            parts.split(at);
        let ((start, velocities), (start_after, velocities_after)) =
            (self.start, self.velocities).split(at);
        (
            Vertices {
                masses,
                pinned,
                stiffness,
                start,
                velocities,
            },
            Vertices {
                masses: masses_after,
                pinned: pinned_after,
                stiffness: stiffness_after,
                start: start_after,
                velocities: velocities_after,
            },
        )
    }
}

impl<'t, V: Send> Split for TrialPoint<'t, V> {
    #[inline(always)]
    fn split(self, at: usize) -> (Self, Self) {
        let ((positions, gradient), (positions_after, gradient_after)) =
            (self.positions, self.gradient).split(at);
        (
            TrialPoint {
                positions,
                gradient,
            },
            TrialPoint {
                positions: positions_after,
                gradient: gradient_after,
            },
        )
    }
}

/// The gradient pass (see `gradient_block`) in blocks of
/// [`VERTEX_BLOCK`](super::super::VERTEX_BLOCK) vertices run by `model`
/// ([`ElasticModel::run_vertex_pass`]): the sums are block sums added over the fixed tree.
pub(crate) fn gradient_pass<V: Shared>(
    model: &impl ElasticModel,
    frames: &Frames<V>,
    vertices: &Vertices<'_, V>,
    x: &[V],
    gradient: &mut [V],
) -> (Real, Real) {
    let block = |_, (vertices, x, gradient): (Vertices<'_, V>, &[V], &mut [V])| {
        gradient_block(frames, &vertices, x, gradient)
    };
    model.run_vertex_pass(Blocks::new(x.len(), (*vertices, x, gradient), &block))
}

/// The direction pass (see `direction_block`) in blocks run by `model`: the slope is a block
/// sum added over the fixed tree.
#[allow(clippy::too_many_arguments)]
pub(crate) fn direction_pass<V: Shared + Vector>(
    model: &impl ElasticModel,
    frames: &Frames<V>,
    vertices: &Vertices<'_, V>,
    (x, gradient): (&[V], &[V]),
    direction: &mut [V],
    momentum: Option<Real>,
    trial: TrialPoint<'_, V>,
    alpha: Real,
) -> Real {
    let block = |_, ((vertices, x, gradient), direction, trial): DirectionParts<'_, V>| {
        direction_block(
            frames,
            &vertices,
            (x, gradient),
            direction,
            momentum,
            trial,
            alpha,
        )
    };
    let parts = ((*vertices, x, gradient), direction, trial);
    model.run_vertex_pass(Blocks::new(x.len(), parts, &block))
}

/// A block's share of the direction pass's buffers.
type DirectionParts<'p, V> = (
    (Vertices<'p, V>, &'p [V], &'p [V]),
    &'p mut [V],
    TrialPoint<'p, V>,
);

/// A block's share of the Chebyshev pass's buffers.
type ChebyshevParts<'p, V> = ((Vertices<'p, V>, &'p [V], &'p [V]), TrialPoint<'p, V>);

/// The trial pass (see `trial_block`) in blocks run by `model`.
pub(crate) fn split_trial_pass<V: Shared>(
    model: &impl ElasticModel,
    frames: &Frames<V>,
    pinned: &[bool],
    (x, direction): (&[V], &[V]),
    alpha: Real,
    trial: TrialPoint<'_, V>,
) {
    let block = |_, (pinned, x, direction, trial): (&[bool], &[V], &[V], TrialPoint<'_, V>)| {
        trial_pass(frames, pinned, (x, direction), alpha, trial);
    };
    model.run_vertex_pass(Blocks::new(x.len(), (pinned, x, direction, trial), &block));
}

/// Copies `source` into `target` (as far as the shorter goes) in blocks run by `model`.
pub(crate) fn split_copy<V: Copy + Send + Sync>(
    model: &impl ElasticModel,
    target: &mut [V],
    source: &[V],
) {
    let block = |_, (target, source): (&mut [V], &[V])| copy(target, source);
    model.run_vertex_pass(Blocks::new(target.len(), (target, source), &block));
}

/// The Chebyshev pass (see `chebyshev_block`) in blocks run by `model`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn chebyshev_pass<V: Shared + Vector>(
    model: &impl ElasticModel,
    frames: &Frames<V>,
    vertices: &Vertices<'_, V>,
    (x, gradient): (&[V], &[V]),
    stepped: bool,
    trial: TrialPoint<'_, V>,
    step: Real,
    omega: Real,
) {
    let block = |_, ((vertices, x, gradient), trial): ChebyshevParts<'_, V>| {
        chebyshev_block(
            frames,
            &vertices,
            (x, gradient),
            stepped,
            trial,
            step,
            omega,
        );
    };
    let parts = ((*vertices, x, gradient), trial);
    model.run_vertex_pass(Blocks::new(x.len(), parts, &block));
}

/// [`check_state`](super::super::check_state) with its scans (masses in range, finite positions and
/// velocities) in blocks run by `model`: the same error, naming the same first vertex.
pub(crate) fn split_check_state<V: Vector + Send + Sync>(
    model: &impl ElasticModel,
    masses: &[Real],
    pinned: &[bool],
    positions: &[V],
    velocities: Option<&[V]>,
) -> Result<(), StepError> {
    let n = model.vertex_count();
    check_state_lengths(n, masses, pinned, positions, velocities)?;
    let block = |first: usize, (masses, positions, velocities): (&[Real], &[V], &[V])| {
        let at = |vertex: usize| first + vertex;
        (
            first_bad_mass(masses).map(at),
            first_non_finite(positions, velocities).map(at),
        )
    };
    let parts = (masses, positions, velocities.unwrap_or(&[]));
    match model.run_vertex_pass(Blocks::new(n, parts, &block)) {
        (Some(vertex), _) => Err(StepError::Mass { vertex }),
        (None, Some(vertex)) => Err(StepError::NonFiniteInput { vertex }),
        (None, None) => Ok(()),
    }
}

/// The slope `g.d` (each block's sum in vertex order, the block sums added over the fixed tree)
/// and the trial points `x + alpha d` (as
/// [`split_trial_pass`]) in one pass of blocks run by `model`.
pub(crate) fn slope_and_trial_pass<V: Shared + Vector>(
    model: &impl ElasticModel,
    frames: &Frames<V>,
    pinned: &[bool],
    (x, gradient, direction): (&[V], &[V], &[V]),
    alpha: Real,
    trial: TrialPoint<'_, V>,
) -> Real {
    let block = |_, (pinned, x, gradient, direction, trial): SlopeParts<'_, V>| {
        trial_pass(frames, pinned, (x, direction), alpha, trial);
        slope_along(gradient, direction)
    };
    let parts = (pinned, x, gradient, direction, trial);
    model.run_vertex_pass(Blocks::new(x.len(), parts, &block))
}

/// A block's share of the slope-and-trial pass's buffers.
type SlopeParts<'p, V> = (&'p [bool], &'p [V], &'p [V], &'p [V], TrialPoint<'p, V>);

#[cfg(test)]
// Compiled for both precisions: the conversions are no-ops in one of them.
#[allow(clippy::unnecessary_cast)]
mod tests {
    extern crate std;
    use std::format;
    use std::vec;
    use std::vec::Vec;

    use super::super::super::super::types::{Real, Vec2, Vec3};
    use super::super::super::contact::HalfSpace;
    use super::super::super::contact::collider::Colliders;
    use super::super::super::contact::friction::Friction;
    use super::super::point::{Grouped, Point};
    use super::{
        Frame, Frames, TrialPoint, Vertices, chebyshev_block, direction_block, gradient_block,
        trial_pass,
    };

    /// A repeatable value in `[-1, 1)` for index `i` and stream `s`.
    fn noise(i: usize, s: usize) -> Real {
        let h = ((i * 7919 + s * 104_729) as u32).wrapping_mul(2_654_435_761);
        (h >> 8) as Real / (1u32 << 23) as Real - 1.0
    }

    /// Every pass, run on `n` vertices (at the width this machine runs: `n = 11` two groups of
    /// 4 and a tail; `n = 61` on AVX-512 in f32 three groups of 16, one of 8, one of 4 and a
    /// tail), against the one-vertex arithmetic applied to each vertex alone: the same bits,
    /// and sums in the documented order.
    fn passes_match_one_vertex_at_a_time<
        V: Grouped + super::super::super::super::element::Vector,
    >(
        n: usize,
        make: impl Fn(usize, usize) -> V,
        up: V,
    ) {
        let zero = <V as Point>::zero();
        let masses: Vec<Real> = (0..n).map(|i| 1.0 + noise(i, 1).abs()).collect();
        let stiffness: Vec<Real> = (0..n)
            .map(|i| if i == 4 { 0.0 } else { 50.0 + noise(i, 2) })
            .collect();
        let pinned: Vec<bool> = (0..n).map(|i| i % 5 == 2).collect();
        // Every third vertex sits on (or just inside) the ground plane `up . x = 0`.
        let start: Vec<V> = (0..n).map(|i| make(i, 3)).collect();
        let x: Vec<V> = (0..n)
            .map(|i| {
                let p = make(i, 4);
                if i % 3 == 0 {
                    p - up.scale(up.inner(p)) - up.scale(1e-3 * (i % 2) as Real)
                } else {
                    p
                }
            })
            .collect();
        let velocities: Vec<V> = (0..n).map(|i| make(i, 5)).collect();
        let forces: Vec<V> = (0..n).map(|i| make(i, 6).scale(10.0)).collect();
        let (h, inertia, gravity) = (0.01, 1.0e4, up.scale(-9.81));
        // Rough: friction in the objective, which damps the direction at the vertices in
        // contact whose gradient presses into the ground.
        let mut damped = 0;
        for (rough, pinned) in [
            (false, &pinned[..]),
            (false, &[]),
            (true, &pinned),
            (true, &[]),
        ] {
            let ground = match rough {
                true => HalfSpace::new(up, 0.0)
                    .with_friction(0.5)
                    .with_sticking_speed(1e-3),
                false => HalfSpace::new(up, 0.0),
            };
            let frames = Frames::new(h, inertia, gravity, Some(&ground));
            let frames = match rough {
                true => frames.with_friction(Friction::new(Some(&ground), Colliders::new(&[]), h)),
                false => frames,
            };
            let one = Frame::<V>::new(h, inertia, gravity, Some(&ground));
            let vertices = Vertices {
                masses: &masses,
                pinned,
                stiffness: &stiffness,
                start: &start,
                velocities: &velocities,
            };
            let free = |i: usize| !pinned.get(i).copied().unwrap_or(false);
            let order = |terms: &[Real]| {
                let whole = n - n % 4;
                let mut partial = [0.0; 4];
                for (i, t) in terms.iter().take(whole).enumerate() {
                    partial[i % 4] += t;
                }
                let tail = terms[whole..].iter().fold(0.0, |sum, t| sum + t);
                ((partial[0] + partial[1]) + (partial[2] + partial[3])) + tail
            };
            let bits = |v: &[V]| format!("{v:?}");

            let mut gradient = forces.clone();
            let (phi, residual) = gradient_block(&frames, &vertices, &x, &mut gradient);
            let expected: Vec<_> = (0..n)
                .map(|i| {
                    one.gradient(
                        x[i],
                        forces[i],
                        start[i],
                        velocities[i],
                        masses[i],
                        Some(free(i)),
                    )
                })
                .collect();
            assert_eq!(
                bits(&gradient),
                bits(&expected.iter().map(|e| e.0).collect::<Vec<_>>())
            );
            assert_eq!(
                phi.to_bits(),
                order(&expected.iter().map(|e| e.1).collect::<Vec<_>>()).to_bits()
            );
            assert_eq!(
                residual.to_bits(),
                order(&expected.iter().map(|e| e.2).collect::<Vec<_>>()).to_bits()
            );

            let diagonal = |i: usize| stiffness[i] + masses[i] * inertia;
            for momentum in [None, Some(0.3)] {
                let mut direction = vec![zero; n];
                let mut trial = start.clone();
                let mut next_gradient = forces.clone();
                let slope = direction_block(
                    &frames,
                    &vertices,
                    (&x, &gradient),
                    &mut direction,
                    momentum,
                    TrialPoint {
                        positions: &mut trial,
                        gradient: &mut next_gradient,
                    },
                    0.7,
                );
                let expected: Vec<_> = (0..n)
                    .map(|i| {
                        let plain = one.direction(
                            x[i],
                            gradient[i],
                            diagonal(i),
                            momentum.map(|m| (start[i], m)),
                        );
                        let friction =
                            frames.damped((x[i], start[i], gradient[i]), diagonal(i), plain);
                        damped += usize::from(format!("{friction:?}") != format!("{plain:?}"));
                        assert!(rough || format!("{friction:?}") == format!("{plain:?}"));
                        friction
                    })
                    .collect();
                let expected_trial: Vec<V> = (0..n)
                    .map(|i| one.moved(x[i], x[i] + expected[i].0.scale(0.7), Some(free(i))))
                    .collect();
                assert_eq!(
                    bits(&direction),
                    bits(&expected.iter().map(|e| e.0).collect::<Vec<_>>())
                );
                assert_eq!(
                    slope.to_bits(),
                    order(&expected.iter().map(|e| e.1).collect::<Vec<_>>()).to_bits()
                );
                assert_eq!(bits(&trial), bits(&expected_trial));
                assert_eq!(bits(&next_gradient), bits(&vec![zero; n]));
                // Pinned vertices stay; free ones never end inside the ground.
                for i in 0..n {
                    assert!(free(i) || trial[i] == x[i]);
                    assert!(!free(i) || up.inner(trial[i]) >= 0.0, "vertex {i}");
                }

                let mut backtracked = start.clone();
                let mut next_gradient = forces.clone();
                trial_pass(
                    &frames,
                    pinned,
                    (&x, &direction),
                    0.25,
                    TrialPoint {
                        positions: &mut backtracked,
                        gradient: &mut next_gradient,
                    },
                );
                let expected: Vec<V> = (0..n)
                    .map(|i| one.moved(x[i], x[i] + direction[i].scale(0.25), Some(free(i))))
                    .collect();
                assert_eq!(bits(&backtracked), bits(&expected));
                assert_eq!(bits(&next_gradient), bits(&vec![zero; n]));
            }

            for stepped in [false, true] {
                let mut trial = start.clone();
                let mut next_gradient = forces.clone();
                chebyshev_block(
                    &frames,
                    &vertices,
                    (&x, &gradient),
                    stepped,
                    TrialPoint {
                        positions: &mut trial,
                        gradient: &mut next_gradient,
                    },
                    1.5,
                    1.2,
                );
                let expected: Vec<V> = (0..n)
                    .map(|i| {
                        let last = if stepped { x[i] - start[i] } else { zero };
                        let plain = one.direction(x[i], gradient[i], diagonal(i), None);
                        let (d, _) =
                            frames.damped((x[i], start[i], gradient[i]), diagonal(i), plain);
                        one.moved(
                            x[i],
                            x[i] + d.scale(1.5) + last.scale(1.2 - 1.0),
                            Some(free(i)),
                        )
                    })
                    .collect();
                assert_eq!(bits(&trial), bits(&expected));
                assert_eq!(bits(&next_gradient), bits(&vec![zero; n]));
            }
        }
        // Friction changed some directions (else the rough runs would prove nothing).
        assert!(damped > 0);
    }

    #[test]
    fn vertex_passes_give_each_vertex_the_bits_of_the_one_vertex_code() {
        for n in [11, 61] {
            passes_match_one_vertex_at_a_time(
                n,
                |i, s| Vec3::new(noise(i, s), noise(i, s + 10), noise(i, s + 20)),
                Vec3::Z,
            );
            passes_match_one_vertex_at_a_time(
                n,
                |i, s| Vec2::new(noise(i, s), noise(i, s + 10)),
                Vec2::Y,
            );
        }
    }
}

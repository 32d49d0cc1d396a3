//! The relaxation's passes over the vertices: the gradient of `Phi` from the elastic forces, the
//! preconditioned descent direction and the trial points. On x86_64 (`math::BATCH_VERTICES`)
//! each runs [`LANES`] vertices at a time (`Vector::Group`, see `points.rs`) and the rest one at
//! a time, elsewhere every vertex one at a time, through the same generic per-vertex code, so
//! that every vertex gets the same bits either way and every target the same sums.

use super::super::lanes::{LANES, Lane, LaneSum, Lanes, each_lane};
use super::super::math::BATCH_VERTICES;
use super::super::types::Real;
use super::collider::Colliders;
use super::descent::line_search::{copy, slope_along};
use super::friction::Friction;
use super::points::{Floor, Grouped, Point};
use super::split::{Blocks, Split};
use super::{ElasticModel, Ground, Vector, check_state_lengths, first_bad_mass, first_non_finite};
use crate::error::StepError;

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
    fn new(h: Real, inertia: Real, gravity: P::Vector, ground: Option<&Ground<P::Vector>>) -> Self {
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

/// The [`Frame`] of a solve, for single vertices; [`group`](Frames::group) gives the same for
/// groups, built only where the passes group (`math::BATCH_VERTICES`).
#[derive(Clone, Copy)]
pub(super) struct Frames<'a, V: Grouped> {
    single: Frame<'a, V>,
    /// Friction, whose tangent curvature the relaxation's direction adds to its bound at the
    /// vertices in contact (`None` for none).
    friction: Option<Friction<'a, V>>,
}

impl<'a, V: Grouped> Frames<'a, V> {
    /// The frames of a solve: time step `h` and `inertia = 1 / h^2` (both 0 without inertia),
    /// `gravity`, and `ground` with a unit normal.
    pub fn new(h: Real, inertia: Real, gravity: V, ground: Option<&Ground<V>>) -> Self {
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

    /// The frame for groups of [`LANES`] vertices: every value in every lane.
    #[inline(always)]
    fn group(&self) -> Frame<'a, V::Group> {
        let single = &self.single;
        Frame {
            h: Lanes::splat(single.h),
            inertia: Lanes::splat(single.inertia),
            gravity: V::Group::splat(single.gravity),
            floor: single.floor.grouped(),
        }
    }

    /// The ground and the colliders, for one vertex.
    pub fn floor(&self) -> &Floor<'a, V> {
        &self.single.floor
    }

    /// Whether the passes group vertices: on `math::BATCH_VERTICES` targets.
    #[inline(always)]
    fn batched(&self) -> bool {
        BATCH_VERTICES
    }

    /// The direction `d` (slope term `slope`) of a vertex at `x` moved from `start`, with
    /// gradient `g` and isotropic bound `p`, with friction's tangent curvature `b` added to the
    /// bound across the contact: `d - b / (p + b) d_t`, `d_t` the tangential part (`friction.rs`:
    /// `b = mu lambda f1(y) / y` bounds the tangent block). Unchanged without a frictional
    /// contact.
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

    /// [`damped`](Self::damped) for the group of [`LANES`] vertices from vertex `first` on, at
    /// `x` (a chunk) moved from `start` (every vertex's `x_n`; `x` where it runs out) with
    /// gradients `g` (a chunk) and bounds `p`: the grouped direction `d` and slope terms `slope`
    /// are unchanged unless a vertex of the group has a frictional contact, and then go through
    /// the one-vertex code lane by lane, so that every vertex gets the bits it gets alone. Most
    /// groups touch nothing and pay only the contact test.
    #[inline(always)]
    fn damped_group(
        &self,
        (x, start, g): (&[V], &[V], &[V]),
        first: usize,
        p: Lanes,
        (d, slope): (V::Group, Lanes),
    ) -> (V::Group, Lanes)
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
        let (mut d, mut slope) = (V::ungroup(d), slope.to_array());
        let lanes = d.iter_mut().zip(slope.iter_mut()).zip(p.to_array());
        for (lane, ((d, slope), p)) in lanes.enumerate() {
            let (Some(&x), Some(&g)) = (x.get(lane), g.get(lane)) else {
                continue;
            };
            let start = start.get(lane).copied().unwrap_or(x);
            (*d, *slope) = self.damped((x, start, g), p, (*d, *slope));
        }
        (V::group(d), Lanes::from_array(slope))
    }
}

/// The per-vertex inputs every pass shares.
#[derive(Clone, Copy)]
pub(super) struct Vertices<'a, V> {
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

/// The group held by `chunk` (a [`LANES`]-long chunk of `chunks_exact`).
#[inline(always)]
fn load<V: Grouped>(chunk: &[V]) -> V::Group {
    V::group(chunk.first_chunk().copied().unwrap_or([V::zero(); LANES]))
}

/// The scalars held by `chunk` (a [`LANES`]-long chunk of `chunks_exact`).
#[inline(always)]
fn load_scalars(chunk: &[Real]) -> Lanes {
    Lanes::from_array(chunk.first_chunk().copied().unwrap_or([0.0; LANES]))
}

/// Writes `group` into `chunk` (a [`LANES`]-long chunk of `chunks_exact_mut`).
#[inline(always)]
fn store<V: Grouped>(chunk: &mut [V], group: V::Group) {
    if let Some(slot) = chunk.first_chunk_mut() {
        *slot = V::ungroup(group);
    }
}

/// Zeroes `chunk`.
#[inline(always)]
fn clear<V: Grouped>(chunk: &mut [V]) {
    chunk.fill(V::zero());
}

/// The mask of the free (not pinned) vertices of group `k`; `None` if no vertex is pinned.
#[inline(always)]
fn free_lanes(pinned: &[bool], k: usize) -> Option<<Lanes as Lane>::Mask> {
    (!pinned.is_empty()).then(|| free_group(pinned, k))
}

/// The mask of the free (not pinned) vertices of group `k`.
#[inline(always)]
fn free_group(pinned: &[bool], k: usize) -> <Lanes as Lane>::Mask {
    let flags = pinned
        .get(k * LANES..)
        .and_then(<[bool]>::first_chunk::<LANES>)
        .copied()
        .unwrap_or([false; LANES]);
    Lanes::splat(0.5).gt(Lanes::from_array(each_lane(flags, |pinned| {
        if pinned { 1.0 } else { 0.0 }
    })))
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

    /// The preconditioners `P_i = k_i + m_i / h^2` of the whole groups, in order.
    #[inline(always)]
    fn diagonal_groups(&self, inertia: Lanes) -> impl Iterator<Item = Lanes> + 'a {
        let stiffness = self.stiffness.chunks_exact(LANES);
        stiffness
            .zip(self.masses.chunks_exact(LANES))
            .map(move |(k, m)| load_scalars(k) + load_scalars(m) * inertia)
    }

    /// The preconditioner of vertex `i`.
    #[inline(always)]
    fn diagonal_one(&self, inertia: Real, i: usize) -> Real {
        let at = |values: &[Real]| values.get(i).copied().unwrap_or(0.0);
        at(self.stiffness) + at(self.masses) * inertia
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
    let (mut phi, mut residual) = (LaneSum::new(x.len()), LaneSum::new(x.len()));
    let velocities = vertices.velocities();
    let mut done = 0;
    if BATCH_VERTICES {
        let frame = &frames.group();
        let groups = gradient
            .chunks_exact_mut(LANES)
            .zip(x.chunks_exact(LANES))
            .zip(vertices.start.chunks_exact(LANES))
            .zip(velocities.chunks_exact(LANES))
            .zip(vertices.masses.chunks_exact(LANES));
        for (k, ((((g, x), start), velocity), m)) in groups.enumerate() {
            let (gradient, phi_term, residual_term) = frame.gradient(
                load(x),
                load(g),
                load(start),
                load(velocity),
                load_scalars(m),
                free_lanes(vertices.pinned, k),
            );
            store(g, gradient);
            phi.add_group(phi_term);
            residual.add_group(residual_term);
            done = (k + 1) * LANES;
        }
    }
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
pub(super) struct TrialPoint<'t, V> {
    pub positions: &'t mut [V],
    pub gradient: &'t mut [V],
}

impl<V> TrialPoint<'_, V> {
    /// The point and gradient chunks of the whole groups.
    #[inline(always)]
    fn groups(&mut self) -> impl Iterator<Item = (&mut [V], &mut [V])> {
        let points = self.positions.chunks_exact_mut(LANES);
        points.zip(self.gradient.chunks_exact_mut(LANES))
    }

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
    let mut done = 0;
    if frames.batched() {
        let buffers = ((x, gradient), &mut *direction, &mut trial);
        // Monomorphised twice, so that the frictionless loop carries no friction test.
        done = match frames.friction {
            None => direction_groups(
                frames,
                vertices,
                buffers,
                (momentum, alpha),
                &mut slope,
                |_, _, _, direction| direction,
            ),
            Some(_) => direction_groups(
                frames,
                vertices,
                buffers,
                (momentum, alpha),
                &mut slope,
                |chunks, first, p, direction| frames.damped_group(chunks, first, p, direction),
            ),
        };
    }
    let frame = &frames.single;
    let rows = direction
        .iter_mut()
        .zip(trial.rows())
        .zip(x.iter().zip(gradient))
        .enumerate();
    for (i, ((d_slot, (t_slot, g_slot)), (&x, &g))) in rows.skip(done) {
        let p = vertices.diagonal_one(frame.inertia, i);
        let heavy_ball = momentum.map(|m| (*t_slot, m));
        let (d, slope_term) = frame.direction(x, g, p, heavy_ball);
        let start = vertices.start.get(i).copied().unwrap_or(x);
        let (d, slope_term) = frames.damped((x, start, g), p, (d, slope_term));
        *d_slot = d;
        *t_slot = frame.moved(x, x + d.scale(alpha), free_one(vertices.pinned, i));
        *g_slot = V::zero();
        slope.add_single(i, slope_term);
    }
    slope.total()
}

/// `direction_block`'s buffers: the iterate and its gradient, the direction, the trial point.
type DirectionBuffers<'a, 't, V> = ((&'a [V], &'a [V]), &'a mut [V], &'a mut TrialPoint<'t, V>);

/// The direction pass of `direction_block` over the whole groups, the direction of each
/// through `damp` (`(x, x_n, g)` chunks, first vertex, bound, direction and slope terms):
/// returns the vertices done.
#[inline(always)]
fn direction_groups<V: Grouped + Vector>(
    frames: &Frames<V>,
    vertices: &Vertices<'_, V>,
    ((x, gradient), direction, trial): DirectionBuffers<'_, '_, V>,
    (momentum, alpha): (Option<Real>, Real),
    slope: &mut LaneSum,
    damp: impl Fn((&[V], &[V], &[V]), usize, Lanes, (V::Group, Lanes)) -> (V::Group, Lanes),
) -> usize {
    let mut done = 0;
    let frame = &frames.group();
    let (lanes_alpha, lanes_momentum) = (Lanes::splat(alpha), momentum.map(Lanes::splat));
    let groups = direction
        .chunks_exact_mut(LANES)
        .zip(trial.groups())
        .zip(x.chunks_exact(LANES).zip(gradient.chunks_exact(LANES)))
        .zip(vertices.diagonal_groups(frame.inertia));
    for (k, (((d_slot, (t_slot, g_slot)), (x, g)), p)) in groups.enumerate() {
        let position = load(x);
        let heavy_ball = lanes_momentum.map(|m| (load(t_slot), m));
        let direction = frame.direction(position, load(g), p, heavy_ball);
        let (d, slope_term) = damp((x, vertices.start, g), k * LANES, p, direction);
        store(d_slot, d);
        let free = free_lanes(vertices.pinned, k);
        store(
            t_slot,
            frame.moved(position, position + d.scale(lanes_alpha), free),
        );
        clear(g_slot);
        slope.add_group(slope_term);
        done = (k + 1) * LANES;
    }
    done
}

/// Writes the trial point `x + alpha d` (projected on the ground; `x` at pinned vertices) into
/// `trial`, zeroing its gradient buffer: a backtracking step of the line search.
pub(super) fn trial_pass<V: Grouped>(
    frames: &Frames<V>,
    pinned: &[bool],
    (x, direction): (&[V], &[V]),
    alpha: Real,
    mut trial: TrialPoint<'_, V>,
) {
    let mut done = 0;
    if BATCH_VERTICES {
        let frame = &frames.group();
        let lanes_alpha = Lanes::splat(alpha);
        let groups = trial
            .groups()
            .zip(x.chunks_exact(LANES).zip(direction.chunks_exact(LANES)));
        for (k, ((t_slot, g_slot), (x, d))) in groups.enumerate() {
            let position = load(x);
            let target = position + load(d).scale(lanes_alpha);
            store(t_slot, frame.moved(position, target, free_lanes(pinned, k)));
            clear(g_slot);
            done = (k + 1) * LANES;
        }
    }
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
    let mut done = 0;
    if frames.batched() {
        let buffers = ((x, gradient), &mut trial);
        let weights = (stepped, step, omega);
        // Monomorphised twice, so that the frictionless loop carries no friction test.
        done = match frames.friction {
            None => chebyshev_groups(frames, vertices, buffers, weights, |_, _, _, d| d),
            Some(_) => chebyshev_groups(frames, vertices, buffers, weights, |c, first, p, d| {
                frames.damped_group(c, first, p, d)
            }),
        };
    }
    let frame = &frames.single;
    let rows = trial.rows().zip(x.iter().zip(gradient)).enumerate();
    for (i, ((t_slot, g_slot), (&x, &g))) in rows.skip(done) {
        let last_step = if stepped { x - *t_slot } else { V::zero() };
        let p = vertices.diagonal_one(frame.inertia, i);
        let direction = frame.direction(x, g, p, None);
        let start = vertices.start.get(i).copied().unwrap_or(x);
        let (d, _) = frames.damped((x, start, g), p, direction);
        let target = x + d.scale(step) + last_step.scale(omega - 1.0);
        *t_slot = frame.moved(x, target, free_one(vertices.pinned, i));
        *g_slot = V::zero();
    }
}

/// The Chebyshev pass of `chebyshev_block` over the whole groups, the direction of each
/// through `damp` (as [`direction_groups`]): returns the vertices done.
#[inline(always)]
fn chebyshev_groups<V: Grouped + Vector>(
    frames: &Frames<V>,
    vertices: &Vertices<'_, V>,
    ((x, gradient), trial): ((&[V], &[V]), &mut TrialPoint<'_, V>),
    (stepped, step, omega): (bool, Real, Real),
    damp: impl Fn((&[V], &[V], &[V]), usize, Lanes, (V::Group, Lanes)) -> (V::Group, Lanes),
) -> usize {
    let mut done = 0;
    let frame = &frames.group();
    let (lanes_step, lanes_weight) = (Lanes::splat(step), Lanes::splat(omega - 1.0));
    let groups = trial
        .groups()
        .zip(x.chunks_exact(LANES).zip(gradient.chunks_exact(LANES)))
        .zip(vertices.diagonal_groups(frame.inertia));
    for (k, (((t_slot, g_slot), (x, g)), p)) in groups.enumerate() {
        let position = load(x);
        let last_step = if stepped {
            position - load(t_slot)
        } else {
            V::Group::zero()
        };
        let direction = frame.direction(position, load(g), p, None);
        let (d, _) = damp((x, vertices.start, g), k * LANES, p, direction);
        let target = position + d.scale(lanes_step) + last_step.scale(lanes_weight);
        store(
            t_slot,
            frame.moved(position, target, free_lanes(vertices.pinned, k)),
        );
        clear(g_slot);
        done = (k + 1) * LANES;
    }
    done
}

/// A vector type the blocked passes can share between threads.
pub(super) trait Shared: Grouped + Send + Sync {}
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
/// [`VERTEX_BLOCK`](super::VERTEX_BLOCK) vertices run by `model`
/// ([`ElasticModel::run_vertex_pass`]): the sums are block sums added over the fixed tree.
pub(super) fn gradient_pass<V: Shared>(
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
pub(super) fn direction_pass<V: Shared + Vector>(
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
pub(super) fn split_trial_pass<V: Shared>(
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
pub(super) fn split_copy<V: Copy + Send + Sync>(
    model: &impl ElasticModel,
    target: &mut [V],
    source: &[V],
) {
    let block = |_, (target, source): (&mut [V], &[V])| copy(target, source);
    model.run_vertex_pass(Blocks::new(target.len(), (target, source), &block));
}

/// The Chebyshev pass (see `chebyshev_block`) in blocks run by `model`.
#[allow(clippy::too_many_arguments)]
pub(super) fn chebyshev_pass<V: Shared + Vector>(
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

/// [`check_state`](super::check_state) with its scans (masses in range, finite positions and
/// velocities) in blocks run by `model`: the same error, naming the same first vertex.
pub(super) fn split_check_state<V: Vector + Send + Sync>(
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
pub(super) fn slope_and_trial_pass<V: Shared + Vector>(
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

    use super::super::super::types::{Real, Vec2, Vec3};
    use super::super::Ground;
    use super::super::collider::Colliders;
    use super::super::friction::Friction;
    use super::super::points::{Grouped, Point};
    use super::{
        Frame, Frames, TrialPoint, Vertices, chebyshev_block, direction_block, gradient_block,
        trial_pass,
    };

    /// A repeatable value in `[-1, 1)` for index `i` and stream `s`.
    fn noise(i: usize, s: usize) -> Real {
        let h = ((i * 7919 + s * 104_729) as u32).wrapping_mul(2_654_435_761);
        (h >> 8) as Real / (1u32 << 23) as Real - 1.0
    }

    /// Every pass, run on `n` vertices (two groups and a tail when `n = 11`), against the
    /// one-vertex arithmetic applied to each vertex alone: the same bits, and sums in the
    /// documented order.
    fn passes_match_one_vertex_at_a_time<V: Grouped + super::super::Vector>(
        make: impl Fn(usize, usize) -> V,
        up: V,
    ) {
        let n = 11;
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
                true => Ground::new(up, 0.0)
                    .with_friction(0.5)
                    .with_sticking_speed(1e-3),
                false => Ground::new(up, 0.0),
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
                let mut partial = [0.0; 4];
                for (i, t) in terms.iter().take(8).enumerate() {
                    partial[i % 4] += t;
                }
                ((partial[0] + partial[1]) + (partial[2] + partial[3]))
                    + (terms[8] + terms[9] + terms[10])
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
        passes_match_one_vertex_at_a_time(
            |i, s| Vec3::new(noise(i, s), noise(i, s + 10), noise(i, s + 20)),
            Vec3::Z,
        );
        passes_match_one_vertex_at_a_time(|i, s| Vec2::new(noise(i, s), noise(i, s + 10)), Vec2::Y);
    }
}

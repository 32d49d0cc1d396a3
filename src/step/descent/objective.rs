//! The objective every implicit solver here minimises (`docs/math.md` section 4): the incremental
//! potential `Phi(x) = sum m/(2 h^2) |x - y|^2 + E(x) - sum m g.(x - x_n)` of an implicit Euler
//! step (`y = x_n + h v_n`), or without inertia the static energy `E(x) - sum m g.(x - x_0)`;
//! its evaluation with the residual every solver stops on, and the velocity update after a step.
//! With friction at the contacts of a step, `Phi` gains the lagged dissipation potential
//! `sum mu lambda_i f0(|u_i|)` of `step/contact/friction.rs`, `lambda_i` the normal force of a
//! lagging gradient (see [`Objective::evaluate`] and [`Objective::relag`]). Shared by every
//! direction of the descent loop (`mod.rs`): the relaxation, gradient descent, Newton's method and
//! VBD.

use super::super::super::element::Vector;
use super::super::super::math;
use super::super::super::types::Real;
use super::super::contact::HalfSpace;
use super::super::contact::floor::Floor;
use super::super::contact::friction::{Friction, Lag};
use super::super::contact::vertex::collider_velocity;
use super::super::loads::Loads;
use super::super::model::ElasticEnergy;
use super::super::state::pinned_flags;
use super::super::vertex_pass::Blocks;
use super::super::vertex_pass::passes::{Frames, TrialPoint, Vertices, gradient_pass};
use super::super::vertex_pass::point::{Grouped, Point};
use crate::error::StepError;

/// A block's share of the initial guess's buffers: the point, `x_n`, `v_n` and pinned flags.
type GuessParts<'p, V> = (TrialPoint<'p, V>, &'p [V], &'p [V], &'p [bool]);

/// `Phi` and its gradient, without the buffers that change.
pub(crate) struct Objective<'p, F: ElasticEnergy> {
    pub model: &'p F,
    /// Masses, pinned flags, the preconditioner's stiffness (the relaxation's; empty for
    /// solvers that do not use it), `x_n` and `v_n` (empty in the quasi-static mode).
    pub vertices: Vertices<'p, F::Vector>,
    /// `h`, `1 / h^2` (both 0 in the quasi-static mode), gravity and the ground, for the
    /// vertex passes.
    pub frames: Frames<'p, F::Vector>,
    /// `h` (unused in the quasi-static mode).
    pub h: Real,
    /// `1 / h^2` (1/s^2; 0 in the quasi-static mode), [`Problem::time_scales`](super::Problem::time_scales).
    pub inertia: Real,
    pub gravity: F::Vector,
    /// External forces and fixed axes (both empty for none).
    pub loads: Loads<'p, F::Vector>,
    /// The frictional contacts (inactive for none, and in the quasi-static mode).
    pub friction: Friction<'p, F::Vector>,
    /// Whether a contact applies Coulomb friction to the velocity after the solve (friction
    /// with a zero sticking speed): the loop then also evaluates
    /// [`rigid_guess`](Self::rigid_guess) where the solver asks for it, as a start (VBD) or
    /// as the scale of the relative residual target (the relaxation).
    pub velocity_friction: bool,
    /// The previous step's velocities, when given: the loop's second initial guess is then
    /// [`adaptive_guess`](Self::adaptive_guess) instead of `y`.
    pub previous_velocities: Option<&'p [F::Vector]>,
}

impl<F: ElasticEnergy> Objective<'_, F> {
    /// The relaxation's diagonal bound `P_i = k_i + m_i / h^2` (N/m) at each free vertex, in
    /// vertex order (`k_i` the per-vertex stiffness bounds, none where they are empty).
    pub fn free_diagonals(&self) -> impl Iterator<Item = Real> + '_ {
        let vertices = &self.vertices;
        vertices
            .stiffness
            .iter()
            .zip(vertices.masses)
            .zip(pinned_flags(vertices.pinned))
            .filter(|(_, pinned)| !pinned)
            .map(|((&k, &m), _)| k + m * self.inertia)
    }

    /// Writes `y + offset` (`x_n + offset` without inertia) projected on the ground into
    /// `point.positions` at free vertices, `x_n` at pinned ones, and zeroes `point.gradient`.
    pub fn initial_guess(&self, point: TrialPoint<'_, F::Vector>, offset: F::Vector) {
        self.guess(point, |_| offset);
    }

    /// Whether a free vertex touches the ground (within the contact tolerance) at
    /// [`initial_guess`](Self::initial_guess)`(offset)` or at `y` itself, stopping at the first
    /// that does; never without a ground (no pass then). Where none does, neither was projected
    /// and that guess is `y` moved by `offset` at every free vertex. The guess's arithmetic,
    /// vertex by vertex: the same points.
    pub fn touches_ground(&self, offset: F::Vector) -> bool {
        let floor = self.frames.floor();
        if floor.contact(F::Vector::ZERO).is_none() {
            return false;
        }
        let Vertices {
            start,
            velocities,
            pinned,
            ..
        } = self.vertices;
        let h = self.h;
        let touches = |p| floor.contact(p) == Some(true);
        start
            .iter()
            .zip(pinned_flags(pinned))
            .enumerate()
            .any(|(i, (&x0, pinned))| {
                let target = match velocities.get(i) {
                    Some(&v) => x0 + v * h,
                    None => x0,
                };
                !pinned && (touches(floor.project(target + offset)) || touches(target))
            })
    }

    /// Whether `Phi` changes along a rigid translation of the free vertices only through its
    /// inertia and gravity terms: no pinned vertex (which would not move with them), no
    /// external load or fixed axis, no collider (whose contacts the ground's test in
    /// [`initial_guess`](Self::initial_guess) does not see), and an elastic energy that, as
    /// every energy of a deformation gradient, does not change under translation.
    pub fn translation_invariant(&self) -> bool {
        self.loads.is_none()
            && self.frames.floor().colliders().is_empty()
            && !self.vertices.pinned.contains(&true)
    }

    /// The adaptive initial guess of Vertex Block Descent (Chen et al. 2024, its adaptive
    /// initialisation; `docs/math.md` section 7.2): `y_i + h^2 a~_i`, where
    /// `a~_i = g clamp(a_i.g / |g|^2, 0, 1)` is the previous step's acceleration
    /// `a_i = (v_n - v_(n-1)) / h` projected on the gravity direction and clamped to `[0, |g|]`
    /// along it, `v_(n-1)` from `previous`: `y + h^2 g` in free fall, `y` where the fall was
    /// stopped. Without inertia (or gravity) it is [`initial_guess`](Self::initial_guess)`(0)`,
    /// and it is written as that is.
    pub fn adaptive_guess(&self, point: TrialPoint<'_, F::Vector>, previous: &[F::Vector]) {
        let (h, g, velocities) = (self.h, self.gravity, self.vertices.velocities);
        let weight = g.dot(g);
        let offset = |i: usize| match (velocities.get(i), previous.get(i)) {
            (Some(&v), Some(&before)) if weight > 0.0 && h > 0.0 => {
                // a.g / |g|^2 = (v - v_(n-1)).g / (h |g|^2), clamped to [0, 1]; a NaN (0 / 0
                // where h |g|^2 underflows) to 0.
                let along = (v - before).dot(g) / (h * weight);
                let fraction = if along > 0.0 { along.min(1.0) } else { 0.0 };
                g * (fraction * (h * h))
            }
            _ => F::Vector::ZERO,
        };
        self.guess(point, offset);
    }

    /// The rigid initial guess `x_n + h v_mean` (projected, `x_n` at pinned vertices),
    /// `v_mean` the mass-weighted mean velocity of the free vertices (summed in vertex order):
    /// `y` with every vertex moving at the body's mean velocity. After a step whose Coulomb
    /// friction acted on the velocity (`implicit_velocities`), only the contact vertices were
    /// slowed, so `y` shears the body by `h` times their velocity changes; for a stiff body that
    /// shear's elastic force is many times the friction force, and the relative tolerance
    /// against that initial residual ends the solve early. Measured on a block sliding down a
    /// 30 degree incline (`tests/steppers/colliders`, `E = 1e6` Pa, 100 Hz): the initial residual
    /// at `y` was 60 N at `mu = 0.1` and 240 N at 0.3 (13 N without friction), at this guess 11 to
    /// 21 N; VBD had stopped at 0.23 N (0.04 N without friction) and slid 4.7 % short. Without
    /// gravity's drop `h^2 g`, which would compress a resting body (208 N measured there). Without
    /// inertia (or velocities) it is [`initial_guess`](Self::initial_guess)`(0)`.
    pub fn rigid_guess(&self, point: TrialPoint<'_, F::Vector>) {
        let (h, velocities) = (self.h, self.vertices.velocities);
        let free = self
            .vertices
            .masses
            .iter()
            .zip(velocities)
            .zip(pinned_flags(self.vertices.pinned))
            .filter(|(_, pinned)| !pinned);
        let (mass, momentum) = free
            .fold((0.0, F::Vector::ZERO), |(mass, momentum), ((&m, &v), _)| {
                (mass + m, momentum + v * m)
            });
        let mean = if mass > 0.0 {
            momentum * (1.0 / mass)
        } else {
            F::Vector::ZERO
        };
        let offset = |i: usize| match velocities.get(i) {
            Some(&v) => (mean - v) * h,
            None => F::Vector::ZERO,
        };
        self.guess(point, offset);
    }

    /// [`initial_guess`](Self::initial_guess) with the offset of vertex `i` `offset(i)`.
    #[inline(always)]
    fn guess(&self, point: TrialPoint<'_, F::Vector>, offset: impl Fn(usize) -> F::Vector + Sync) {
        let Vertices {
            start,
            velocities,
            pinned,
            ..
        } = self.vertices;
        // In blocks run by the model (`step/vertex_pass/mod.rs`): every vertex on its own.
        let (h, floor, loads) = (self.h, self.frames.floor(), &self.loads);
        let block =
            |first: usize, (point, start, velocities, pinned): GuessParts<'_, F::Vector>| {
                let rows = point.positions.iter_mut().zip(point.gradient.iter_mut());
                for (j, (((x, g), &x0), pinned)) in
                    rows.zip(start).zip(pinned_flags(pinned)).enumerate()
                {
                    *g = F::Vector::ZERO;
                    let target = match velocities.get(j) {
                        Some(&v) => x0 + v * h,
                        None => x0,
                    };
                    *x = if pinned {
                        x0
                    } else {
                        let guess = floor.project(target + offset(first + j));
                        loads.keep_fixed(first + j, guess, x0)
                    };
                }
            };
        let n = point.positions.len();
        let parts = (point, start, velocities, pinned);
        self.model.run_vertex_pass(Blocks::new(n, parts, &block));
    }

    /// `Phi(x)`, `E(x)` and the residual at `x`, writing the unprojected gradient (N, zero at
    /// pinned vertices) into `gradient`, which must be zero on entry (the pass that writes a
    /// trial point zeroes it, saving a pass of its own). Non-finite if `x` is.
    ///
    /// Friction's contacts and normal forces `lambda_i` are lagged to `lagged` (the iterate a
    /// trial is taken from), or without it to `x` itself (its gradient before friction, which
    /// is tangential and does not change it): within one line search `Phi` is then one smooth
    /// function, whose contact set does not change when a trial point lands on a surface.
    /// Lagged to another iterate, the residual is that of the gradient before friction: a trial
    /// point's residual is only read once it is accepted, after [`relag`](Self::relag) has
    /// replaced it, so the pass that sums it with friction is saved.
    pub fn evaluate(
        &self,
        x: &[F::Vector],
        gradient: &mut [F::Vector],
        lagged: Option<Lag<'_, F::Vector>>,
    ) -> Result<Evaluation, StepError> {
        let elastic = self.model.energy_and_add_forces(x, gradient)?;
        let (mut inertia_and_gravity, mut residual_squared) =
            gradient_pass(self.model, &self.frames, &self.vertices, x, gradient);
        if !self.loads.is_none() {
            let vertices = &self.vertices;
            let (loads_phi, loaded_residual) = self.loads.apply(
                self.frames.floor(),
                (vertices.pinned, vertices.start),
                x,
                gradient,
            );
            inertia_and_gravity += loads_phi;
            residual_squared = loaded_residual;
        }
        if let Some(rough) = self.add_friction(x, gradient, lagged, None) {
            inertia_and_gravity += rough.phi;
            if lagged.is_none() {
                residual_squared = rough.residual_squared;
            }
        }
        Ok(Evaluation {
            phi: elastic + inertia_and_gravity,
            elastic,
            residual: math::sqrt(residual_squared),
        })
    }

    /// Re-lags an accepted point `x` whose `gradient` and `evaluation` were computed with
    /// friction lagged to `lagged` (the previous iterate): afterwards they hold `Phi`, its
    /// gradient and residual with friction lagged to `x` itself, so that the next line search
    /// minimises the friction potential of the new iterate (the fixed point is the lagged
    /// model's solution with its own contact forces). Returns how far the lag moved: the
    /// largest relative change of a vertex's force factor `mu lambda` (1 where a vertex entered
    /// or left a frictional contact), 0 without friction.
    pub fn relag(
        &self,
        x: &[F::Vector],
        gradient: &mut [F::Vector],
        lagged: Lag<'_, F::Vector>,
        evaluation: &mut Evaluation,
    ) -> Real {
        match self.add_friction(x, gradient, None, Some(lagged)) {
            Some(Relagged {
                phi,
                residual_squared,
                moved,
            }) => {
                evaluation.phi += phi;
                evaluation.residual = math::sqrt(residual_squared);
                moved
            }
            None => 0.0,
        }
    }

    /// Adds friction to `gradient` at `x`: at every free vertex, the potential and gradient of
    /// `step/contact/friction.rs` lagged to `lagged` (or to `x` and `gradient` itself if `None`),
    /// minus those lagged to `included` (whose friction `gradient` holds already; nothing if
    /// `None`). Returns friction's change of `Phi` (J), the squared residual of the result
    /// projected on the contact constraints (N^2; 0, not summed, with `lagged` given), which
    /// replaces the passes' one, and how far the lag moved between `included` and `lagged` (see
    /// [`relag`](Self::relag)); `None` (and nothing changed) if no vertex got a term. One pass: a
    /// vertex's residual depends on its own gradient only, so it is summed as soon as that is final
    /// (in vertex order, as a second pass would).
    fn add_friction(
        &self,
        x: &[F::Vector],
        gradient: &mut [F::Vector],
        lagged: Option<Lag<'_, F::Vector>>,
        included: Option<Lag<'_, F::Vector>>,
    ) -> Option<Relagged> {
        let friction = &self.friction;
        if !friction.is_active() {
            return None;
        }
        let Vertices { pinned, start, .. } = self.vertices;
        let floor = self.frames.floor();
        let mut phi = 0.0;
        let mut residual_squared = 0.0;
        let mut moved: Real = 0.0;
        let mut changed = false;
        // Lagged to another iterate (a trial point), the residual is not read (see `evaluate`).
        let summed = lagged.is_none();
        // Without colliders, a vertex off the ground at `x` and at the lag points gets no term,
        // and its residual term is `|g|^2` (the constraint acts only on the ground): most
        // vertices take this path, the same bits as the general one.
        let plain = floor.colliders().is_empty();
        let off = |i: usize, lag: Option<Lag<'_, F::Vector>>| {
            lag.is_none_or(|lag| {
                lag.x
                    .get(i)
                    .is_some_and(|&p| floor.contact(p) != Some(true))
            })
        };
        let rows = gradient.iter_mut().zip(x).zip(start);
        for (i, ((g, &x), &x0)) in rows.enumerate() {
            if pinned.get(i).copied().unwrap_or(false) {
                continue;
            }
            if plain && floor.contact(x) != Some(true) && off(i, lagged) && off(i, included) {
                if summed {
                    residual_squared += g.inner(*g);
                }
                continue;
            }
            let added = friction_term(friction, i, (x, x0, *g), lagged);
            let removed =
                included.and_then(|lag| friction_term(friction, i, (x, x0, *g), Some(lag)));
            if included.is_some() {
                moved = moved.max(match (added, removed) {
                    (Some((new, ..)), Some((old, ..))) => (new - old).abs() / new.max(old),
                    (None, None) => 0.0,
                    _ => 1.0,
                });
            }
            for (force, sign) in [(added, 1.0), (removed, -1.0)] {
                if let Some((force, potential, direction)) = force {
                    let force = sign * force;
                    phi += force * potential;
                    *g += self.loads.free_part(i, direction * force);
                    changed = true;
                }
            }
            if summed {
                let projected = floor.constrain(floor.contact(x), x, *g, 1.0);
                residual_squared += projected.inner(projected);
            }
        }
        changed.then_some(Relagged {
            phi,
            residual_squared,
            moved,
        })
    }

    /// `|M g|` (N), the norm of the gravity load on the free vertices (`|M g + f_ext|` over the
    /// free components with external loads or fixed axes): the scale the stopping
    /// test measures a residual against when the initial residual is smaller.
    pub fn gravity_load(&self) -> Real {
        if !self.loads.is_none() {
            let vertices = &self.vertices;
            return self
                .loads
                .load(vertices.masses, vertices.pinned, self.gravity);
        }
        // Formed relative to the largest free mass, so that heavy bodies (masses of 1e19 kg in
        // f32) do not overflow the squares.
        let free_masses = || {
            let vertices = &self.vertices;
            vertices
                .masses
                .iter()
                .zip(pinned_flags(vertices.pinned))
                .filter(|(_, pinned)| !pinned)
                .map(|(&m, _)| m)
        };
        let heaviest = free_masses().fold(0.0, Real::max);
        if heaviest <= 0.0 {
            return 0.0;
        }
        let relative_squared: Real = free_masses().map(|m| (m / heaviest) * (m / heaviest)).sum();
        heaviest * math::sqrt(relative_squared) * math::sqrt(self.gravity.dot(self.gravity))
    }
}

/// Friction's term at vertex `i` at `x` moved from `x0`, lagged to `lag` (or to `x` with its
/// gradient `g` if `None`): the force factor `mu lambda` (N), `f0(|u|)` (m) and `grad f0`;
/// `None` without a frictional contact or normal force there. Inlined into the one pass over
/// the vertices, where most vertices leave at the contact test.
#[inline(always)]
fn friction_term<V: Grouped + Vector>(
    friction: &Friction<'_, V>,
    i: usize,
    (x, x0, g): (V, V, V),
    lag: Option<Lag<'_, V>>,
) -> Option<(Real, Real, V)> {
    let reference = match lag {
        Some(lag) => (lag.x.get(i).copied()?, lag.gradient.get(i).copied()?),
        None => (x, g),
    };
    let (slip, force) = friction.lagged_slip((x, x0), reference)?;
    Some((force, slip.potential(), slip.gradient()))
}

/// What adding (or re-lagging) friction changed: see `Objective::add_friction`.
struct Relagged {
    /// Friction's change of `Phi` (J).
    phi: Real,
    /// The squared residual with friction (N^2).
    residual_squared: Real,
    /// The largest relative change of a force factor `mu lambda` between the two lags.
    moved: Real,
}

/// What one evaluation of `Phi` gives.
#[derive(Clone, Copy)]
pub(crate) struct Evaluation {
    /// `Phi(x)` (J).
    pub phi: Real,
    /// The elastic energy `E(x)` (J), part of `phi`.
    pub elastic: Real,
    /// `|grad Phi(x)|` (N) projected on the contact constraints.
    pub residual: Real,
}

/// The velocity after an implicit Euler step of a free vertex of mass `m` from `x0` to `x`:
/// `v = (x - x0) / h`, then, resting on the ground or a collider, the approach along the normal
/// removed and, where the contact's friction was not part of the objective (a zero sticking
/// speed), Coulomb friction with the normal impulse `h R`, `R` the reaction (the normal
/// component of `g`, the gradient of `Phi` at the result). Pinned vertices keep their velocity
/// (the caller's).
#[inline(always)]
pub(crate) fn implicit_velocity<V: Vector>(
    ground: Option<&HalfSpace<V>>,
    floor: &Floor<V>,
    (h, m): (Real, Real),
    (x, x0, g): (V, V, V),
) -> V {
    let mut v = (x - x0) * (1.0 / h);
    if let (Some(ground), Some(true)) = (ground, floor.contact(x)) {
        let normal = ground.normal.dot(v);
        let reaction = ground.normal.dot(g).max(0.0);
        // No impulse (friction keeps the tangential velocity) where it acted in Phi.
        let normal_change = if ground.friction_in_objective() {
            0.0
        } else {
            h * reaction / m + (-normal).max(0.0)
        };
        let tangential = v - ground.normal * normal;
        v = ground.friction_applied(tangential, normal_change) + ground.normal * normal.max(0.0);
    }
    if !floor.colliders().is_empty() {
        v = collider_velocity(floor.colliders(), (x, g, m, h), v);
    }
    v
}

//! Time stepping on caller-owned state (`docs/math.md` section 4): explicit symplectic Euler with
//! its stability bound and blow-up detection, and implicit Euler as a minimisation solved by
//! preconditioned gradient descent (also a quasi-static relaxation to equilibrium).
//!
//! # Conventions
//! * SI units: positions m, velocities m/s, masses kg (lumped, one per vertex, e.g. from
//!   [`TetMesh::lumped_masses`](super::mesh::TetMesh::lumped_masses)),
//!   forces N, energies J, time s, gravity m/s^2, damping 1/s. 2D meshes work per unit thickness
//!   (N/m, J/m, kg/m) and membranes with moduli in N/m and densities in kg/m^2, exactly as in
//!   [`mesh`](super::mesh).
//! * The body is described by an [`ElasticModel`]: a validated mesh plus a material, and which
//!   force path to use. [`TetElastic`] (direct stress, any [`Material`](super::material::Material))
//!   also implements [`ElasticEnergy`] and so works with the relaxation; [`TetClamped`]
//!   (inversion-robust clamped principal stress, not an energy gradient) is for the explicit
//!   stepper only, and so are the triangle models [`TriElastic`] (2D) and [`MembraneElastic`].
//! * `pinned` is a slice of flags, empty (nothing pinned) or one per vertex: a pinned vertex's
//!   position and velocity are never changed by any stepper.
//! * What a step acts on is its [`Scene`], the same for every stepper: the time step, gravity,
//!   the ground, colliders, external loads and partial constraints, borrowed for the step; how
//!   it is solved is the solver's settings ([`ExplicitSettings`], or the implicit solvers'
//!   [`DescentSettings`] with their own options), which borrow nothing.
//! * External loads and partial constraints ([`Scene::with_external_forces`],
//!   [`Scene::with_fixed_axes`], see `step/loads.rs`): a force (N) per vertex added
//!   to gravity, and a mask per vertex fixing some coordinate axes ([`FIXED_X`], [`FIXED_Y`],
//!   [`FIXED_Z`]; rollers, symmetry planes). A fixed coordinate keeps its bits exactly (with a
//!   ground whose normal is not a coordinate axis, the contact projection is applied first and
//!   the fixed coordinates restored after it).
//! * The ground is a half-space, see [`HalfSpace`].
//! * Friction: the explicit stepper applies Coulomb's law to the velocity (and the substep's
//!   move) at each contact. The implicit solvers apply it to the velocity after the solve by
//!   default, or, opted in with a positive [`sticking_speed`](HalfSpace::sticking_speed) `eps_v`
//!   (m/s, [`SUGGESTED_STICKING_SPEED`] 1 mm/s) on the ground or a collider, minimise it with
//!   the step as the lagged, smoothed dissipation potential of Incremental Potential Contact
//!   (`docs/math.md` section 4.6): a contact held below the Coulomb limit then creeps at most at
//!   `eps_v`, one sliding faster has the Coulomb force.
//! * Rigid colliders (half-spaces, spheres, capsules, oriented boxes, any [`SignedDistance`];
//!   static or kinematic) act on 3D bodies in every stepper as the ground does, see [`Collider`]
//!   and each settings type's `with_colliders`.
//! * No axis is special: gravity is a vector in the scene and the ground a plane given by its
//!   normal, so y up, z up or any other convention works. The examples in these docs use y up
//!   (gravity `(0, -9.81, 0)`, `HalfSpace::new(Vec3::Y, 0.0)`); the `bouncy` scene and the
//!   `tradeoffs` charts use z up (gravity `(0, 0, -9.81)`, `HalfSpace::new(Vec3::Z, 0.0)`).
//! * Nothing is allocated: scratch space is caller buffers sized by the functions of
//!   [`scratch_len`], one per buffer (`scratch_len::relax(n)`, `scratch_len::newton(n, e)`, ...).
//! * Every stepper validates all parameters and buffers **before** touching anything, and
//!   restores positions and velocities bit for bit when a step fails
//!   ([`StepError`](crate::StepError)).
//!
//! # Accepted ranges
//! Everything outside these is refused with the error named, before anything is written:
//!
//! | input | accepted | error |
//! |---|---|---|
//! | `dt` (both steppers) | finite, `> 0` | [`StepError::TimeStep`](crate::StepError::TimeStep) |
//! | `dt` (every stepper; not the quasi-static solves) | `1 / dt^2` finite: `dt >~ 1e-19` s (f32), `1e-154` s (f64) | [`StepError::TimeStepTooSmall`](crate::StepError::TimeStepTooSmall) |
//! | substeps | `1..=`[`MAX_SUBSTEPS`](ExplicitSettings::MAX_SUBSTEPS) (65536) | [`StepError::Substeps`](crate::StepError::Substeps) |
//! | masses | finite normal numbers `>= Real::MIN_POSITIVE` | [`StepError::Mass`](crate::StepError::Mass) |
//! | positions, velocities | finite | [`StepError::NonFiniteInput`](crate::StepError::NonFiniteInput) |
//! | gravity / damping | finite / finite `>= 0` | [`StepError::Gravity`](crate::StepError::Gravity) / [`StepError::Damping`](crate::StepError::Damping) |
//! | ground normal, offset | any finite non-zero vector (any length), finite offset | [`StepError::Ground`](crate::StepError::Ground) |
//! | restitution / friction | `[0, 1]` / finite `>= 0` | [`StepError::Restitution`](crate::StepError::Restitution) / [`StepError::Friction`](crate::StepError::Friction) |
//! | colliders ([`Collider`]) | sizes finite `> 0`, finite position and velocities, unit rotation (to `1e-3`), restitution `[0, 1]`, friction finite `>= 0`; 3D bodies only | [`StepError::Collider`](crate::StepError::Collider) (index and [`ColliderProblem`](crate::ColliderProblem)) |
//! | clamp threshold ([`TetClamped`]) | `(0, 1]` | [`MeshError::ClampThreshold`](crate::MeshError::ClampThreshold) |
//! | deformation (tet kernels) | `max(1, largest entry)` of each `F` at most [`Material::deformation_limit`](super::material::Material::deformation_limit) (a limit below 1 refuses every `F`) | [`MeshError::DeformationRange`](crate::MeshError::DeformationRange) |
//! | density ([`TetMesh::lumped_masses`](super::mesh::TetMesh::lumped_masses)) | finite `> 0`, each element's share `density V / 4` normal and `<= Real::MAX / elements` | [`MeshError::Density`](crate::MeshError::Density), [`MeshError::MassRange`](crate::MeshError::MassRange) |
//! | stiffness bounds ([`stable_time_step`]) | finite `k_i`, finite `k_i / m_i` | [`StepError::Stiffness`](crate::StepError::Stiffness) |
//!
//! Scratch lengths ([`scratch_len::explicit`], [`scratch_len::relax`]) saturate at `usize::MAX`,
//! which no buffer can match.
//!
//! # The stability bound
//!
//! ## What is computed
//! Symplectic Euler on `M a = -K u` is stable when `dt < 2 / omega_max`, `omega_max^2` the
//! largest eigenvalue of `M^-1 K` (`docs/math.md` section 4). Two upper bounds on `omega_max^2`,
//! both from per-element bounds `k_e >= lambda_max(K_e)`:
//!
//! * Element stiffness. With `g_j = grad N_j` the shape-function gradients (rows of `Dm^-1`,
//!   `g_0 = -(g_1 + g_2 + g_3)`) and `U` the nodal displacements as columns, the displacement
//!   gradient is `U G^T` with `G = [g_0 .. g_3]`, so `|eps|_F <= |grad u|_F <= |U|_F
//!   sigma_max(G)`. The small-strain energy density `eps : C : eps` is at most
//!   `c_max |eps|^2` with `c_max = max(3 lambda + 2 mu, 2 mu)` in 3D (the bulk and shear
//!   eigenvalues of `C`) and `max(2 lambda + 2 mu, 2 mu)` for triangles. Hence
//!   `u^T K_e u <= V c_max lambda_max(G G^T) |U|^2`: `k_e = V c_max lambda_max(G G^T)` (N/m),
//!   with `lambda_max(G G^T)` from the SVD of the 3x3 (closed form for 2x2) matrix.
//! * Vertex bound ([`stable_time_step`]): `u^T K u = sum_e u_e^T K_e u_e <= sum_i |u_i|^2
//!   k_i` with `k_i = sum_{e owns i} k_e`, so `omega_max^2 <= max_i k_i / m_i` over free
//!   vertices (pinned ones are removed degrees of freedom) for **any** positive masses, and
//!   `dt = min_i 2 sqrt(m_i / k_i)`. With lumped masses this is never smaller than the element
//!   bound below (a mass-weighted average of it).
//! * Element bound ([`element_stable_time_step`](explicit::element_stable_time_step)): with each
//!   element's own lumped share `rho V / N` per corner, `omega_e^2 <= N k_e / (rho V)` and
//!   `omega_max <= max_e omega_e` (Irons' element eigenvalue inequality), so `dt = min_e 2 sqrt(rho
//!   V / (N k_e))`. For a regular tetrahedron with `nu = 0.3` this is `0.52 a / c_d` (edge `a`,
//!   `c_d = sqrt((lambda + 2 mu) / rho)`), the rule of thumb `0.45..0.5 h / c_d`.
//!
//! ## What it guarantees
//! Both are guaranteed lower bounds on the critical step **of the linearised system at
//! rest**: small strains about the rest shape, with `lambda` and `mu` the material's
//! small-strain moduli ([`linearised_moduli`](explicit::linearised_moduli), measured from the
//! material by central differences and enlarged by 0.1% to cover their error). A body strongly
//! compressed (a stiffening model) or rotated far from rest with a non-rotation-invariant force
//! path has higher frequencies: leave a margin (0.5..0.8 of the bound; see
//! [`FrequencyEstimate::MARGIN`](explicit::FrequencyEstimate::MARGIN) for why not 0.9), and rely
//! on the stepper's blow-up detection for the rest. Damping (mass-proportional, applied as `v / (1 + c dt)`) only
//! lowers the amplification and needs no margin.
//!
//! # The relaxation
//!
//! ## Preconditioner
//! `P_i = m_i / h^2 + k_i` with `k_i` the sum of the stiffness bounds of the elements around
//! vertex `i` (see [the stability bound](#the-stability-bound)): `u^T K u <= sum_i k_i |u_i|^2`
//! for the small-strain stiffness `K`, so `diag(P)` majorises the Hessian `A` of `Phi` near rest:
//! the eigenvalues of `P^-1 A` lie in `(0, 1]`. The step `alpha = 1` along `d = -P^-1 grad Phi`
//! therefore decreases `Phi` by at least `grad.d / 2` (the Armijo test with `c <= 1/2` accepts it
//! at the first try) and any `alpha < 2` converges on the linearised problem. The bound is loose:
//! measured on the bouncy jelly cube (1296 tets, `nu = 0.45`, `h = 1/60 s`) the eigenvalues of
//! `P^-1 A` span `[5.8e-4, 0.27]`, on the 24-tet cantilever of `tests/steppers/relax.rs` `[1.4e-3,
//! 0.39]` (`[3.3e-4, 0.39]` without inertia). Hence [`RelaxOptions::step_length`]: `2` is still
//! safe for any mesh and twice as fast; larger steps are faster still on these meshes and the line
//! search catches them where they are not. The exact Hessian diagonal (Wang and Yang's choice) was
//! measured too: the same condition number (385..400 against 458 for the cube), only a different
//! scale (its largest eigenvalue is 3.4, so it needs `alpha < 0.6` and has no guarantee), so the
//! bound stays.
//!
//! ## Initial guess
//! The lower-`Phi` of `y = x_n + h v_n` and `y + h^2 g` (both projected on the ground): the
//! second is exact in free fall (a rigid translation, the slowest mode of `P^-1 A`, solved in zero
//! iterations); the first wins for a body resting on the ground, where the drop would crush the
//! bottom layer into the ground. One extra evaluation per step.
//!
//! ## Acceleration
//! The condition number of `P^-1 A` (`~1/lambda_min`: hundreds to thousands) sets the cost of
//! plain descent: about `kappa / (2 alpha) ln(1/tol)` iterations. Two accelerations, exclusive:
//! * Chebyshev semi-iteration
//!   ([`RelaxSettings::with_chebyshev`](DescentSettings::<RelaxOptions>::with_chebyshev); Wang and
//!   Yang 2016, section 4): `x_{k+1} = omega_{k+1} (x_k + alpha d_k - x_{k-1}) + x_{k-1}` with
//!   `omega = 1` for the first `S` iterations after a (re)start, then `omega = 2 / (2 - rho^2)`,
//!   then `omega_{k+1} = 4 / (4 - rho^2 omega_k)`, which tends to `2 / (1 + sqrt(1 - rho^2))`. Cost
//!   `~sqrt(kappa)` instead of `kappa` iterations, still one energy-and-force pass each. `rho`
//!   estimates the spectral radius of `I - alpha P^-1 A`, `1 - alpha lambda_min` at best: too small
//!   and the slowest modes converge at the plain rate, too close to 1 and everything converges at
//!   the rate the estimate allows. Measured (see `tests/steppers/relax.rs`): `0.995` for steps of
//!   1/60 s, `0.999` for quasi-static solves, with `alpha = 2`. A trial that raises `Phi` beyond
//!   rounding (contacts, nonlinearity) is discarded: the acceleration restarts with a plain Armijo
//!   step ([`DescentReport::restarts`] counts these). Or let the solver estimate `rho`
//!   ([`RelaxSettings::with_estimated_chebyshev`](DescentSettings::<RelaxOptions>::with_estimated_chebyshev)):
//!   the largest residual ratio of its first `delay` plain iterations (the estimator Vertex Block
//!   Descent uses, `descent/chebyshev.rs`), a lower bound that rises with the window. Measured on
//!   two quasi-static cantilevers (`tests/steppers/chebyshev_estimate.rs`, f64, `1e-6`): delay 200
//!   needs 911 and 22 376 iterations where the best hand-tuned `rho` of the grid needed 435 and 15
//!   647, and a fixed `0.999` 727 and 50 844.
//! * Heavy-ball momentum
//!   ([`RelaxSettings::with_momentum`](DescentSettings::<RelaxOptions>::with_momentum)): `d +
//!   momentum * (last step)`, line searched as a whole. Kept for comparison; Chebyshev is faster at
//!   the same cost.
//!
//! On the bouncy jelly cube (3 s, 180 steps of 1/60 s, tolerance `2e-3`) Chebyshev with
//! `rho = 0.995, alpha = 2` averages 29 iterations per step (at most ~270 on landing) and
//! converges on every step; plain descent with `alpha = 1` used its whole 300-iteration budget
//! on every step after landing.
//!
//! # Where each piece lives
//! One job per file or folder (the whole crate's tree is drawn in `docs/layout.md`):
//! * `model.rs`: the traits a body implements ([`ElasticModel`], [`ElasticEnergy`],
//!   [`ElasticHessian`]) and the shipped models; `state.rs`: the checks of the state every
//!   stepper makes first; `scene.rs`: what a step acts on ([`Scene`]) and its one validation;
//!   `loads.rs`: how external forces and fixed axes enter a step.
//! * `contact/`: the [`HalfSpace`] and [`Collider`]s, the one contact record (`contact::Contact`),
//!   the projection onto the admissible set every stepper shares (`floor.rs`) and friction in
//!   the implicit objective (`friction.rs`); and, public in [`contact`], the kernels of
//!   body–body and self contact (`docs/math.md` chapter 8): a surface's primitives
//!   (`boundary.rs`), the candidate pairs (`broad_phase/`), their distances (`distance/`), the
//!   barrier (`barrier.rs`), continuous collision detection (`ccd/`) and the contact energy
//!   with its derivatives (`potential/`). No stepper calls these yet (issue #39).
//! * `vertex_pass/`: the passes over the vertices (integration, projection, trial points,
//!   residuals) in blocks of [`VERTEX_BLOCK`](vertex_pass::VERTEX_BLOCK) (`mod.rs`), their bodies
//!   four to sixteen vertices at a time on x86_64 (`passes.rs`), on the per-vertex arithmetic
//!   written once for one vertex and a lane group (`point.rs`).
//! * `explicit/`: [`explicit_step`], its [stability bound](stable_time_step) (`stability.rs`)
//!   and the [frequency estimate](explicit::estimate_max_frequency) (`frequency.rs`).
//! * `descent/`: the implicit solvers on one loop (`docs/math.md` section 7.0): `mod.rs` the
//!   direction each solver gives, the shared entry checks and the solve (velocity update, restore
//!   on failure), `descend.rs` the loop's phases (initial guess, Chebyshev and momentum trials,
//!   line search), `coordinates.rs` the shift next to the body, `objective.rs` the objective `Phi`,
//!   `line_search.rs` the Armijo test, `stopping.rs` the stopping test with the rounding floor
//!   and stagnation, `chebyshev.rs` the semi-iteration's weights and estimate; and one folder per
//!   solver, each with its settings, report and entry points in `mod.rs`: `relax/` (the
//!   [relax](relax_step)ation's Jacobi direction `jacobi.rs`, and plain
//!   [gradient descent](gradient_descent_step) `gradient.rs`, `P = c I`, for comparison),
//!   `newton/` ([`newton`](newton_step)'s method: projected Hessian and block-Jacobi PCG in
//!   `cg.rs`, `docs/math.md` section 7) and `vbd/` ([Vertex Block Descent](vbd_step): the
//!   Gauss–Seidel sweep `sweep.rs` and its SIMD lanes `lanes.rs`, the per-vertex sums
//!   `sums.rs`, the per-element block `block.rs` and the packed element layout `layout.rs`,
//!   over the vertex [adjacency and colouring](super::mesh::build_vertex_adjacency) of
//!   `mesh/adjacency.rs`).
//!
//! # Which solver to pick
//! Measured by the `tradeoffs` example's `descent` chart (f64, one thread; relative residual
//! `1e-4`, `1e-6` for the static solve) and the `bouncy` example:
//! * [`explicit_step`]: soft bodies and small steps (one force pass a step, the least work per
//!   simulated second while the step stays under [`stable_time_step`]); no solve to converge.
//! * [`gradient_descent_step`] / [`gradient_descent_quasi_static`]: only to compare. The same
//!   loop and cost per iteration as the relaxation with `P = c I`; on the cantilever of
//!   `tests/steppers/relax.rs` it needed 2.1 to 2.2 times the relaxation's iterations.
//! * [`relax_step`] with Chebyshev (the defaults): soft bodies at display-rate steps. Its
//!   iterations are the cheapest (1 to 4 force evaluations each): over the whole bouncy run it
//!   is the fastest implicit stepper (21.5 iterations a step in f32), and on a small stiff block
//!   one step to `1e-4` took 0.31 ms against Newton's 0.74 ms. Without acceleration it needs
//!   about 10 times the iterations; avoid that.
//! * [`newton_step`] / [`newton_quasi_static`]: stiff bodies, large steps and static solves,
//!   and whenever the answer must converge. The static cantilever (400 tets) reached `1e-6` in
//!   9 Newton iterations (265 CG), 7.5 ms, where Chebyshev relaxation needed 73 000 iterations
//!   (1.06 s); on a stiff cube (E = 1e8 Pa) dropped at 1/30 s in f32 it converged on 30 of 30
//!   steps (26 of them stopped at its rounding floor, up to 0.29 of the weight: see
//!   [`newton_step`]) where the relaxation converged on 2 and VBD on 3. An
//!   iteration costs 40 to 60 force evaluations (element Hessians and CG).
//! * [`vbd_step`]: fewer iterations than the relaxation (111 sweeps on the bouncy cube's
//!   landing step against Chebyshev's 183) and monotone sweeps, so a small fixed budget of
//!   sweeps is safe; but a sweep costs 6 to 9 force evaluations, so it was 1.5 to 5.6 times
//!   slower than the relaxation on one core, and it stalls on slender static problems (not
//!   `1e-6` in 20 000 sweeps on the cantilever). Pick it for a fixed per-frame budget, or where
//!   a parallel, colour-by-colour sweep pays.

pub mod contact;
mod descent;
pub mod explicit;
mod loads;
mod model;
mod scene;
pub mod scratch_len;
pub(crate) mod state;
pub mod vertex_pass;

pub use contact::{
    Attachment, Collider, CouplingReport, CouplingSettings, HalfSpace, MAX_ATTACHMENTS, MAX_DYNAMIC_COLLIDERS, Reaction,
    SUGGESTED_STICKING_SPEED, Shape, SignedDistance, add_collider_reactions, attachment_reaction,
    implicit_impulses,
};
#[cfg(feature = "alloc")]
pub use descent::newton::{MAX_COARSE, Multilevel, REBUILD_FACTOR};
pub use descent::newton::{
    LOAD_UNITS, NewtonDetails, NewtonOptions, NewtonReport, NewtonScratch, NewtonSettings,
    Preconditioner, automatic_cg_budget, newton_quasi_static, newton_step,
};
pub use descent::relax::{
    RelaxOptions, RelaxReport, RelaxScratch, RelaxSettings, gradient_descent_quasi_static,
    gradient_descent_step, relax_quasi_static, relax_step,
};
pub use descent::settings::{DescentReport, DescentSettings};
pub(crate) use descent::vbd::{Bodies, ContactBuffersVbd, SweepMesh, SweepRun, SweepSchedule};
pub use descent::vbd::{
    VbdDetails, VbdOptions, VbdReport, VbdScratch, VbdSettings, VertexBlockModel, vbd_quasi_static,
    vbd_step,
};
pub use explicit::{
    ExplicitReport, ExplicitScratch, ExplicitSettings, explicit_step, stable_time_step,
};
pub use loads::{FIXED_X, FIXED_Y, FIXED_Z};
pub use model::{
    ElasticEnergy, ElasticHessian, ElasticModel, MembraneElastic, TetClamped, TetElastic,
    TriElastic,
};
pub use scene::Scene;

// The owning body checks a step's time step as the steppers do, and keeps what the scratch
// views remember between steps.
pub(crate) use descent::vbd::VbdTopology;
pub(crate) use explicit::ExplicitMemory;
pub(crate) use scene::check_time_step;

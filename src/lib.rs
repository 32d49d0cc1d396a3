//! # softfem
//!
//! Elastic soft bodies for firmware and game engines: linear FEM/FVM kernels on tetrahedra and
//! triangles, `#![no_std]` and allocation-free, on buffers the caller owns.
//!
//! ## Stepping a body
//!
//! A body an engine can hold ([`Body`](body::Body)): a jelly cube dropped onto a ball resting
//! on the ground, stepped for a second at 60 Hz, once explicitly (substeps of half the stable
//! step, chosen by the body) and once by implicit Euler (Newton's method). The body owns its
//! mesh, masses, state and scratch in fixed-capacity arrays: no heap (y up here; see
//! [Axes](#axes)).
//!
//! ```
//! use softfem::body::{Body, FixedStorage, Solver};
//! use softfem::{glam::Vec3, material::StableNeoHookean, step::Collider};
//!
//! let jelly = StableNeoHookean::from_young_poisson(5.0e4, 0.45)?; // Pa
//! let ground = Collider::half_space(Vec3::ZERO, Vec3::Y).with_friction(0.5); // the plane y = 0
//! let colliders = [ground, Collider::sphere(Vec3::new(0.0, 0.15, 0.0), 0.15)]; // m
//! let (low, high) = (Vec3::new(-0.1, 0.35, -0.1), Vec3::new(0.1, 0.55, 0.1)); // a 0.2 m cube
//! for solver in [Solver::explicit(), Solver::newton()] {
//!     // 2 x 2 x 2 cells of 5 tetrahedra: 27 vertices, 40 tets, 1000 kg/m^3.
//!     let mut body = Body::<FixedStorage<27, 40>, _>::from_box(low, high, [2; 3], 1000.0, jelly)?;
//!     body.set_solver(solver)?;
//!     body.set_gravity(Vec3::new(0.0, -9.81, 0.0)); // m/s^2
//!     for _ in 0..60 {
//!         body.step_with_colliders(1.0 / 60.0, &colliders)?; // a failed step restores the state
//!     }
//!     assert!(body.positions().iter().all(|&x| colliders.iter().all(|c| c.distance(x) > -1e-4)));
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A failed step ([`StepError`], e.g. `EnergyBlowUp` above the stable step) leaves the body's
//! state as it was. The explicit solver is stable below a computed bound; the implicit ones
//! ([`Solver::relax`](body::Solver::relax), [`Solver::newton`](body::Solver::newton),
//! [`Solver::vbd`](body::Solver::vbd)) at any step, at the price of numerical damping.
//!
//! ## The user guide
//!
//! The guide is in the repository under `docs/guide/` (its table of contents is
//! `docs/guide/README.md`), in chapters to read in order: bodies and meshes; materials and which
//! one a scene needs; solvers and time steps; colliders and contact; assets and rendering; many
//! cores and SIMD; firmware; the web page; reliability and errors; performance beside the peers;
//! the mathematics (`docs/math.md`, which the code cites by section). Every example in it runs
//! as a doc test.
//!
//! ## What is in it
//!
//! * `f32` at the crate root, the same API in `f64` under [`softfem::f64`](mod@f64) (default
//!   feature `f64`), compiled from one source.
//! * [`svd`]: a rotation-variant 3x3 Jacobi SVD (`det u = det v = +1`, inversion carried by the
//!   smallest singular value), accurate to a few `eps` on every class of input from `1e-30` to
//!   `1e30`, with the sweep count as a speed/accuracy knob.
//! * [`polar`]: polar decomposition on top of it.
//! * [`material`]: hyperelastic models (StVK, the isochoric neo-Hookean, stable neo-Hookean) behind
//!   one [`Material`](material::Material) trait, with energy density, first Piola–Kirchhoff
//!   stress and their principal-stretch forms, and second derivatives with their SPD projection
//!   ([`StressDerivative`](material::StressDerivative)); constructors validate parameters
//!   ([`MaterialError`]).
//! * [`generate`]: structured meshes written into caller buffers — a box of tetrahedra
//!   ([`fill_box`](generate::fill_box)) and a rectangle of triangles in 2D or 3D — positively
//!   oriented and conforming ([`GenerateError`]).
//! * [`element`]: rest data, deformation gradient, nodal forces and energy of one tetrahedron or
//!   triangle (2D solid or membrane).
//! * [`mesh`]: validated meshes borrowing the caller's buffers ([`MeshError`] names the first bad
//!   element or vertex), with the mesh-level kernels: elastic forces (direct, principal, clamped),
//!   energies, stresses and lumped masses.
//! * [`body`]: one owning [`Body`](body::Body) (rest shape, state, masses, pins, solver and its
//!   scratch) over fixed-capacity or (feature `alloc`) growable storage, stepped by `body.step(dt)`.
//! * [`step`]: time stepping on caller-owned state — explicit symplectic Euler with a stable time
//!   step proven for the linearised system and blow-up detection that restores the state, and implicit Euler as energy
//!   minimisation by preconditioned descent (also quasi-static relaxation) or by Newton's method
//!   with the projected Hessian ([`newton_step`](step::newton_step)) ([`StepError`]).
//! * [`svd3_lanes`](svd::svd3_lanes) on [`lanes`]: the SVD of 4 matrices at once, bit-identical to
//!   `svd3`.
//! * [`svd3_batch`](svd::svd3_batch): the SVDs of a whole slice at the widest SIMD width the CPU
//!   has (AVX-512F, AVX2, SSE, chosen at run time by [`simd`]), bit-identical to `svd3`.
//! * [`asset`]: from a game asset to a soft body and back: [`voxel`](asset::voxel) tet meshing of
//!   a closed triangle surface (generalised winding number), [`embed`](asset::embed) to drive a
//!   detailed render mesh by the simulated one, [`surface`](asset::surface) buffers (outward
//!   boundary triangles, vertex normals), and with `std` the TetGen (`tetgen`), Gmsh 4.1
//!   (`gmsh`) and OBJ (`obj`) readers and a per-frame OBJ writer.
//!
//! Vectors and matrices are [glam](https://docs.rs/glam/0.34)'s `Vec3` and `Mat3` (`DVec3`,
//! `DMat3` in f64); the crate re-exports it as `softfem::glam`, so that callers use the exact
//! version the kernels are built against.
//!
//! ## Axes
//!
//! The library has no preferred "up": gravity is a vector in the step's [`Scene`](step::Scene)
//! and the ground a plane given by its normal
//! ([`HalfSpace::new(normal, offset)`](step::HalfSpace::new)), so any axis convention works. The
//! examples in these docs and the README use **y up** (gravity `(0, -9.81, 0)`, ground normal
//! `Vec3::Y`); the `bouncy` scene and the `tradeoffs` charts use **z up** (gravity
//! `(0, 0, -9.81)`, ground normal `Vec3::Z`), as ParaView shows it.
//!
//! ## The kernels on their own
//!
//! The same drop with the low-level kernels: a jelly cube from the box generator, stable
//! neo-Hookean, dropped 0.1 m onto the ground and stepped explicitly for a second. Every buffer
//! is the caller's: nothing is allocated.
//!
//! ```
//! use softfem::{element::TetRest, generate::{BoxSplit, fill_box}, glam::Vec3, mesh::TetMesh};
//! use softfem::material::StableNeoHookean;
//! use softfem::step::{ExplicitScratch, ExplicitSettings, HalfSpace, TetElastic};
//! use softfem::step::{Scene, scratch_len, explicit_step, stable_time_step};
//!
//! // A 0.2 m cube of 4 x 4 x 4 cells, 5 tets each (`generate::box_counts` gives these counts).
//! const VERTICES: usize = 5 * 5 * 5;
//! const TETS: usize = 4 * 4 * 4 * 5;
//! let (mut rest, mut tets) = ([Vec3::ZERO; VERTICES], [[0u32; 4]; TETS]);
//! let (low, high) = (Vec3::new(-0.1, 0.1, -0.1), Vec3::new(0.1, 0.3, 0.1)); // m
//! fill_box(low, high, 4, 4, 4, BoxSplit::Alternating5, &mut rest, &mut tets)?;
//! let mut rest_data = [TetRest::default(); TETS];
//! let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?; // checks indices and volumes
//! let mut masses = [0.0; VERTICES];
//! mesh.lumped_masses(1000.0, &mut masses)?; // kg/m^3 in, kg per vertex out
//! let body = TetElastic::new(mesh, StableNeoHookean::from_young_poisson(5.0e4, 0.45)?); // Pa
//!
//! let mut stiffness = [0.0; VERTICES];
//! let dt = 0.5 * stable_time_step(&body, &masses, &[], &mut stiffness)?; // s, half the bound
//! let scene = Scene::new(dt) // what the step acts on
//!     .with_gravity(Vec3::new(0.0, -9.81, 0.0)) // m/s^2
//!     .with_ground(HalfSpace::new(Vec3::Y, 0.0).with_friction(0.5)); // the plane y = 0
//! let settings = ExplicitSettings::new().with_damping(2.0); // how it is solved; 1/s
//! let (mut x, mut v) = (rest, [Vec3::ZERO; VERTICES]);
//! let mut buffer = [Vec3::ZERO; scratch_len::explicit(VERTICES)];
//! let mut scratch = ExplicitScratch::new(&mut buffer);
//! let steps = (1.0 / dt) as usize; // one second
//! for _ in 0..steps {
//!     explicit_step(&body, &masses, &[], &scene, &settings, &mut x, &mut v, &mut scratch)?;
//! }
//! let lowest = x.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
//! let highest = x.iter().map(|p| p.y).fold(f32::NEG_INFINITY, f32::max);
//! println!("{steps} steps of {dt:.2e} s: the cube spans y = {lowest:.4}..{highest:.4} m");
//! assert!(lowest.abs() < 1e-3 && (highest - 0.2).abs() < 0.01); // landed, rests, kept its shape
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! For steps far above the explicit bound (1/60 s on a stiff body),
//! [`relax_step`](step::relax_step), [`newton_step`](step::newton_step) and
//! [`vbd_step`](step::vbd_step) take implicit Euler steps by minimising an energy.
//!
//! A unit cube in five tetrahedra, squashed by 10%, pushes back:
//! ```
//! use softfem::{element::TetRest, glam::Vec3, material::StableNeoHookean, mesh::TetMesh};
//!
//! let corners = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]];
//! let rest = corners.map(|[x, y, z]| Vec3::new(x as f32, y as f32, z as f32)); // m
//! let tets = [[0, 1, 3, 4], [1, 2, 3, 6], [1, 4, 5, 6], [3, 4, 6, 7], [1, 3, 4, 6]];
//! let mut rest_data = [TetRest::default(); 5];
//! let mesh = TetMesh::new(&rest, &tets, &mut rest_data)?;
//!
//! let rubber = StableNeoHookean::from_young_poisson(1.0e6, 0.45).unwrap(); // Pa
//! let squashed = rest.map(|x| x * Vec3::new(1.0, 1.0, 0.9));
//! let mut forces = [Vec3::ZERO; 8]; // N; the kernels add into it
//! mesh.add_elastic_forces(&rubber, &squashed, &mut forces)?;
//! assert!(forces[4..].iter().all(|f| f.z > 0.0)); // the top face is pushed back up
//! assert!(forces.iter().sum::<Vec3>().length() < 1.0); // and the forces balance
//! println!("energy: {} J", mesh.elastic_energy(&rubber, &squashed)?);
//! # Ok::<(), softfem::MeshError>(())
//! ```
//!
//! ```
//! use softfem::glam::Mat3;
//! use softfem::svd::svd3;
//!
//! let f = Mat3::from_cols_array(&[1.2, 0.1, 0.0, 0.3, 0.9, 0.0, 0.0, 0.2, 1.1]);
//! let svd = svd3(f);
//! assert!(svd.to_mat3().abs_diff_eq(f, 1e-6));
//! assert!(svd.sigma.x >= svd.sigma.y && svd.sigma.y >= svd.sigma.z.abs());
//! ```
//!
//! ## Features
//! * `f64` (default): [`softfem::f64`](mod@f64), the same API in double precision. Without it
//!   the numeric modules are compiled once, for `f32` only.
//! * `std`: host-only conveniences; the kernels never need it. Enables the file readers and
//!   writers of [`asset`]: `asset::tetgen` (TetGen `.node` / `.ele` meshes), `asset::gmsh` and
//!   `asset::obj` (docs.rs builds with every feature, so they are shown there, marked as needing
//!   `std`).
//! * `alloc`: the growable storage of [`body`] (`body::VecStorage`).
//! * `defmt`: derives `defmt::Format` on every public error and report type.
//! * `bytemuck`: derives `bytemuck::Pod` on the render-buffer types of [`asset::surface`] (and
//!   enables glam's `bytemuck`), so vertex and index buffers cast to bytes for a GPU upload.
//! * `rayon` (implies `std`): `parallel`, the partitioned passes of
//!   [`TetPartition`](mesh::TetPartition) run on rayon's pool, bit-identical to the sequential
//!   code for any thread count.
#![no_std]
// docs.rs builds with `--cfg docsrs` (Cargo.toml's `[package.metadata.docs.rs]`), on nightly:
// items behind a feature are then labelled with it.
#![cfg_attr(docsrs, feature(doc_cfg))]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]
#![warn(missing_docs)]
// One source, two precisions: `src/f32/` and `src/f64/` each include the shared numeric
// modules (`svd.rs`, `polar.rs`, ..., listed once in `src/precision.rs`) against their own
// `Real`/`Vec3`/`Mat3` aliases.
#![allow(clippy::duplicate_mod)]

#[cfg(feature = "alloc")]
extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

pub use glam;

pub mod error;
pub use error::SvdBatchError;
pub use error::{
    Buffer, ElementError, GenerateBuffer, GenerateError, MaterialError, MeshError, StepBuffer,
    StepError,
};

// The run-time SIMD dispatch lives with the lane types it picks between (`src/lanes/`), but is
// compiled once, for both precisions: one detected width and one cap.
#[path = "lanes/dispatch.rs"]
pub mod simd;

mod precision;

// One panic-free sort for both precisions (`sort.rs`).
mod sort;

#[path = "f32/mod.rs"]
mod single;
pub use error::ColliderProblem;
pub use error::{BodyBuffer, BodyError};
pub use error::{ContactBuffer, ContactError};
pub use single::{
    asset, body, element, generate, lanes, material, mesh, polar, step, svd, types, world,
};
// The asset pipeline's errors (also in `asset` and `error`).
#[cfg(feature = "std")]
pub use error::{
    AssetFileError, GmshFormatError, GmshProblem, GmshSection, ObjFormatError, ObjProblem,
    TetgenError, TetgenFile, TetgenFormatError, TetgenProblem,
};
pub use error::{EmbedBuffer, EmbedError, SurfaceError, VoxelBuffer, VoxelError};

#[cfg(feature = "rayon")]
#[cfg_attr(docsrs, doc(cfg(feature = "rayon")))]
pub use single::parallel;

#[cfg(feature = "f64")]
#[cfg_attr(docsrs, doc(cfg(feature = "f64")))]
pub mod f64;

// The README's Rust examples run as doc tests, so the README cannot drift from the API.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

// Every chapter of the user guide (`docs/guide/`) runs its Rust examples as doc tests the same
// way, one hidden item per chapter (`tests/assets/front_page.rs` checks that none is missing).
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/01-bodies-and-meshes.md")]
struct GuideBodiesAndMeshes;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/02-materials.md")]
struct GuideMaterials;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/03-solvers-and-time-steps.md")]
struct GuideSolversAndTimeSteps;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/04-colliders-and-contact.md")]
struct GuideCollidersAndContact;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/05-assets-and-rendering.md")]
struct GuideAssetsAndRendering;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/06-many-cores-and-simd.md")]
struct GuideManyCoresAndSimd;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/07-firmware.md")]
struct GuideFirmware;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/08-web-browser.md")]
struct GuideWebBrowser;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/09-reliability-and-errors.md")]
struct GuideReliabilityAndErrors;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/10-performance.md")]
struct GuidePerformance;
#[cfg(doctest)]
#[doc = include_str!("../docs/guide/11-mathematics.md")]
struct GuideMathematics;

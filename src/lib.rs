//! # softfem
//!
//! Elastic soft bodies for firmware and game engines: linear FEM/FVM kernels on tetrahedra and
//! triangles, `#![no_std]` and allocation-free, on buffers the caller owns.
//!
//! * `f32` at the crate root, the same API in `f64` under [`softfem::f64`](mod@f64), compiled from one
//!   source.
//! * [`svd`]: a rotation-variant 3x3 Jacobi SVD (`det u = det v = +1`, inversion carried by the
//!   smallest singular value), accurate to a few `eps` on every class of input from `1e-30` to
//!   `1e30`, with the sweep count as a speed/accuracy knob.
//! * [`polar`]: polar decomposition on top of it.
//! * [`material`]: hyperelastic models (StVK, the isochoric neo-Hookean, stable neo-Hookean) behind
//!   one [`Material`](material::Material) trait, with energy density, first Piola–Kirchhoff
//!   stress and their principal-stretch forms; constructors validate parameters
//!   ([`MaterialError`]).
//! * [`generate`]: structured meshes written into caller buffers — a box of tetrahedra
//!   ([`fill_box`](generate::fill_box)) and a rectangle of triangles in 2D or 3D — positively
//!   oriented and conforming ([`GenerateError`]).
//! * [`element`]: rest data, deformation gradient, nodal forces and energy of one tetrahedron or
//!   triangle (2D solid or membrane).
//! * [`mesh`]: validated meshes borrowing the caller's buffers ([`MeshError`] names the first bad
//!   element or vertex), with the mesh-level kernels: elastic forces (direct, principal, clamped),
//!   energies, stresses and lumped masses.
//! * [`step`]: time stepping on caller-owned state — explicit symplectic Euler with a stable time
//!   step proven for the linearised system and blow-up detection that restores the state, and implicit Euler as energy
//!   minimisation by preconditioned descent (also quasi-static relaxation) ([`StepError`]).
//! * [`svd3_lanes`](svd::svd3_lanes) on [`lanes`]: the SVD of 4 matrices at once, bit-identical to
//!   `svd3`.
//! * From a game asset to a soft body and back: [`voxel`] tet meshing of a closed triangle surface
//!   (generalised winding number), [`embed`] to drive a detailed render mesh by the simulated one,
//!   [`surface`] buffers (outward boundary triangles, vertex normals), and with `std` the Gmsh 4.1
//!   (`gmsh`) and OBJ (`obj`) readers and a per-frame OBJ writer.
//!
//! glam is re-exported as [`glam`] so that callers use the exact version the kernels
//! are built against.
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
//! * `std`: host-only conveniences; the kernels never need it. Enables the `tetgen` module, a reader for
//!   TetGen `.node` / `.ele` meshes.
//! * `defmt`: derives `defmt::Format` on every public error and report type.
//! * `bytemuck`: derives `bytemuck::Pod` on the render-buffer types of [`surface`] (and enables
//!   glam's `bytemuck`), so vertex and index buffers cast to bytes for a GPU upload.
#![no_std]
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
// One source, two precisions: `src/f32.rs` and `src/f64.rs` each include the shared numeric
// modules (`svd.rs`, `polar.rs`, ...) against their own `Real`/`Vec3`/`Mat3` aliases.
#![allow(clippy::duplicate_mod)]

#[cfg(feature = "std")]
extern crate std;

pub use glam;

pub mod error;
pub use error::{
    Buffer, ElementError, GenerateBuffer, GenerateError, MaterialError, MeshError, StepBuffer,
    StepError,
};

#[path = "f32.rs"]
mod single;
#[cfg(feature = "std")]
pub use error::{TetgenError, TetgenFile, TetgenFormatError, TetgenProblem};
#[cfg(feature = "std")]
pub use single::tetgen;
pub use single::{element, generate, lanes, material, mesh, polar, step, svd, types};
// The asset pipeline: a triangle surface to a soft body and back.
#[cfg(feature = "std")]
pub use error::{
    AssetFileError, GmshFormatError, GmshProblem, GmshSection, ObjFormatError, ObjProblem,
};
pub use error::{EmbedBuffer, EmbedError, SurfaceError, VoxelBuffer, VoxelError};
pub use single::embed;
pub use single::surface;
pub use single::voxel;
#[cfg(feature = "std")]
pub use single::{gmsh, obj};

pub mod f64;

// The README's Rust examples run as doc tests, so the README cannot drift from the API.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

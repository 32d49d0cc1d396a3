//! The kernels against closed forms, identities and other libraries, in both precisions: the
//! SVD and the polar decomposition, the material models, second derivatives, the mesh kernels
//! and their validation, the mesh generators, and the batched SIMD paths bit for bit against the
//! scalar ones. One test binary (one link) for what were separate files; each module is one of
//! them, its docs say what it proves. `cargo test --test kernels svd::` runs one of them.

#[path = "../common/mod.rs"]
mod common;

mod generate;
mod hessian;
mod identities;
mod material;
mod mesh;
mod polar;
mod simd;
mod svd;

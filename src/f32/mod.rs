//! The single-precision instantiation of softfem's numeric modules.
//!
//! Everything here is re-exported at the crate root; `softfem::f64` holds the same items in
//! double precision, compiled from the same source files (see `src/f64/mod.rs`).

pub mod types;

pub(crate) mod math;

#[cfg(target_arch = "x86_64")]
mod wide_ops;

/// How a group of [`lanes::Lanes`] is held: one SSE register on x86_64, one `v128` on wasm32
/// built with SIMD128, an array elsewhere.
#[cfg(target_arch = "x86_64")]
#[path = "../lanes/sse.rs"]
mod lane_repr;
#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
#[path = "../lanes/simd128.rs"]
mod lane_repr;
#[cfg(not(any(
    target_arch = "x86_64",
    all(target_arch = "wasm32", target_feature = "simd128")
)))]
#[path = "../lanes/portable.rs"]
mod lane_repr;

crate::precision::numeric_modules!();

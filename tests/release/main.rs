//! The tests that must also run optimised, in one small binary: the bit identity of every SIMD
//! width (`svd3_batch` runs pairs of registers per group only in optimised builds,
//! `src/svd_batch.rs`), and the collider, partition and rest-block tests whose numeric runs
//! unoptimised builds skip or would take minutes over. The same modules are compiled into the
//! `kernels` and `steppers` binaries for the debug run; here only they are compiled, so that the
//! release build of the tests does not optimise every other suite too. An unoptimised build of
//! this binary is empty: `cargo test --release --all-features --test release` runs it.
#![cfg(not(debug_assertions))]

#[path = "../common/mod.rs"]
mod common;

#[path = "../steppers/body.rs"]
mod body;
#[path = "../steppers/colliders.rs"]
mod colliders;
#[path = "../steppers/one_call.rs"]
mod one_call;
#[path = "../steppers/parallel.rs"]
mod parallel;
#[path = "../kernels/simd.rs"]
mod simd;

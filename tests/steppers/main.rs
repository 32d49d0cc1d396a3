//! The steppers (explicit, relaxation, Newton, VBD) and what they are given, in both precisions:
//! stability and frequency estimates, loads and constraints, colliders, stopping and Chebyshev
//! acceleration, hostile inputs, the owning body (on the heap and in fixed-size statics) and
//! the partitioned and threaded passes. One test binary (one link) for what were separate files;
//! each module is one of them, its docs say what it proves. `cargo test --test steppers relax::`
//! runs one of them.

#[path = "../common/ball_pile.rs"]
mod ball_pile;
#[path = "../common/mod.rs"]
mod common;
#[path = "../common/intersection.rs"]
mod intersection;

mod adversarial;
mod body;
mod chebyshev_estimate;
mod colliders;
mod contact;
mod explicit_colliders;
mod firmware_body;
mod frequency;
mod loads;
// The multilevel preconditioner needs the package's `alloc` feature.
#[cfg(feature = "alloc")]
mod multilevel;
mod newton;
mod one_call;
mod parallel;
mod pile;
mod reactions;
mod relax;
mod rigid_bodies;
mod self_contact;
mod stability;
mod stagnation;
mod step;
mod vbd;
// The growable world (`VecStorage`) needs the package's `alloc` feature, as body.rs's tests.
#[cfg(feature = "alloc")]
mod world;
#[cfg(feature = "alloc")]
mod world_rigid;
#[cfg(feature = "alloc")]
mod world_vbd;

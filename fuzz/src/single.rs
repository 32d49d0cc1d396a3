//! The checks against the `f32` API at the crate root.

pub use softfem as sf;
/// The bit pattern of this precision's float.
pub type Bits = u32;
/// The precision's name, for messages.
pub const NAME: &str = "f32";

#[path = "body_checks.rs"]
pub mod body;
#[path = "mesh_checks.rs"]
pub mod mesh;
#[path = "precision.rs"]
pub mod precision;
#[path = "reader_checks.rs"]
pub mod readers;
#[path = "step_checks.rs"]
pub mod step;
#[path = "svd_checks.rs"]
pub mod svd;
#[path = "tetgen_checks.rs"]
pub mod tetgen;
#[path = "voxel_checks.rs"]
pub mod voxel;

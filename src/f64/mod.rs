//! The double-precision instantiation of softfem's numeric modules.
//!
//! The same items as at the crate root, in double precision, compiled from the same source files
//! (see `src/f32/mod.rs`). The error types do not depend on the precision and are the crate
//! root's.

pub use crate::error::ColliderProblem;
pub use crate::error::SvdBatchError;
pub use crate::error::{BodyBuffer, BodyError};
pub use crate::error::{
    Buffer, ElementError, GenerateBuffer, GenerateError, MaterialError, MeshError, StepBuffer,
    StepError,
};
pub use crate::error::{ContactBuffer, ContactError};
#[cfg(feature = "std")]
pub use crate::error::{TetgenError, TetgenFile, TetgenFormatError, TetgenProblem};

pub mod types;

pub(crate) mod math;

#[cfg(target_arch = "x86_64")]
mod wide_ops;

/// How a group of [`lanes::Lanes`] is held: two SSE2 registers on x86_64, an array elsewhere.
#[cfg(target_arch = "x86_64")]
#[path = "../lanes/sse2_f64.rs"]
mod lane_repr;
#[cfg(not(target_arch = "x86_64"))]
#[path = "../lanes/portable.rs"]
mod lane_repr;

crate::precision::numeric_modules!();

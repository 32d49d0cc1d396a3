//! The scalar, vector and matrix types this precision is written against.

/// The floating-point scalar of this precision.
pub type Real = f32;
pub use glam::Quat;
pub use glam::{Mat2, Mat3, Vec2, Vec3};

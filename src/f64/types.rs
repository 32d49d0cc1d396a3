//! The scalar, vector and matrix types this precision is written against.

/// The floating-point scalar of this precision.
pub type Real = f64;
pub use glam::DQuat as Quat;
pub use glam::{DMat2 as Mat2, DMat3 as Mat3, DVec2 as Vec2, DVec3 as Vec3};

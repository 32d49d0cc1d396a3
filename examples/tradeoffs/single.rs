//! The single-precision (`softfem`, f32) instantiation of [`body`](self::body).

pub use softfem as api;

#[path = "body.rs"]
pub mod body;

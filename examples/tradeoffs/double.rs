//! The double-precision (`softfem::f64`) instantiation of [`body`](self::body).

pub use softfem::f64 as api;

#[path = "body.rs"]
pub mod body;

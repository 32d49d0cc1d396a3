//! Errors of softfem's constructors, shared by both precisions.
//!
//! The types here carry no floating-point values, so one definition serves the `f32` API at the
//! crate root and the `f64` API under [`softfem::f64`](mod@crate::f64) (both re-export them).

use core::fmt;

/// An elastic material was given parameters for which it is not a stable solid.
///
/// Returned by the `from_lame` and `from_young_poisson` constructors of every model in
/// [`material`](crate::material). Each variant names the parameter at fault; the valid ranges are
/// those of isotropic linear elasticity: shear modulus `mu > 0` and bulk modulus
/// `K = lambda + 2 mu / 3 > 0`, or equivalently Young's modulus `E > 0` and Poisson ratio
/// `-1 < nu < 1/2`. Every parameter must also be finite.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum MaterialError {
    /// The first Lamé parameter `lambda` (Pa) is NaN or infinite.
    Lambda,
    /// The shear modulus `mu` (Pa) is NaN, infinite, zero or negative.
    Mu,
    /// The bulk modulus `K = lambda + 2 mu / 3` (Pa) is not positive (`lambda <= -2 mu / 3`), or
    /// not finite: the material would not resist compression.
    BulkModulus,
    /// Young's modulus `E` (Pa) is NaN, infinite, zero or negative.
    YoungModulus,
    /// The Poisson ratio `nu` (dimensionless) is NaN or outside the open interval `(-1, 1/2)`.
    PoissonRatio,
}

impl fmt::Display for MaterialError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            MaterialError::Lambda => "the Lame parameter lambda must be finite",
            MaterialError::Mu => "the shear modulus mu must be finite and positive",
            MaterialError::BulkModulus => {
                "the bulk modulus lambda + 2 mu / 3 must be finite and positive"
            }
            MaterialError::YoungModulus => "Young's modulus must be finite and positive",
            MaterialError::PoissonRatio => "the Poisson ratio must lie strictly between -1 and 1/2",
        })
    }
}

impl core::error::Error for MaterialError {}

/// One of the caller-owned output buffers of a mesh generator (see [`GenerateError::BufferLength`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum GenerateBuffer {
    /// The vertex positions (`&mut [Vec3]` or `&mut [Vec2]`).
    Positions,
    /// The tetrahedron index buffer (`&mut [[u32; 4]]`).
    Tetrahedra,
    /// The triangle index buffer (`&mut [[u32; 3]]`).
    Triangles,
}

impl fmt::Display for GenerateBuffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            GenerateBuffer::Positions => "positions",
            GenerateBuffer::Tetrahedra => "tetrahedra",
            GenerateBuffer::Triangles => "triangles",
        })
    }
}

/// A mesh generator in [`generate`](crate::generate) was asked for a mesh it cannot produce.
///
/// The generators check their arguments in this order and write nothing when they fail: the cell
/// counts ([`ZeroCells`](Self::ZeroCells), [`TooManyVertices`](Self::TooManyVertices),
/// [`TooManyElements`](Self::TooManyElements)), the geometry ([`NonFiniteBox`](Self::NonFiniteBox),
/// [`EmptyBox`](Self::EmptyBox)), the buffer lengths ([`BufferLength`](Self::BufferLength)), and
/// last the elements themselves ([`DegenerateCells`](Self::DegenerateCells)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum GenerateError {
    /// A cell count (`nx`, `ny` or `nz`) is zero.
    ZeroCells,
    /// The mesh would have more than `u32::MAX` vertices, so its indices would not fit in `u32`.
    TooManyVertices,
    /// The number of elements does not fit in `usize` (only possible where `usize` is 32 bits).
    TooManyElements,
    /// An output buffer does not have exactly the length the counts function reports.
    BufferLength {
        /// The buffer at fault.
        buffer: GenerateBuffer,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        actual: usize,
    },
    /// A corner of the box (or the origin or an edge vector of a 3D rectangle) is NaN or infinite.
    NonFiniteBox,
    /// The box is empty: `min >= max` on some axis (or the two edge vectors of a 3D rectangle are
    /// zero or parallel).
    EmptyBox,
    /// The cells are too small or too large for this precision: after rounding, some element would
    /// have a rest volume (area) that is not a positive finite number, for example because
    /// neighbouring grid coordinates round to the same value or the volume underflows or
    /// overflows.
    DegenerateCells,
}

impl fmt::Display for GenerateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GenerateError::ZeroCells => f.write_str("every cell count must be at least 1"),
            GenerateError::TooManyVertices => {
                f.write_str("the mesh would have more vertices than u32 indices can address")
            }
            GenerateError::TooManyElements => {
                f.write_str("the number of elements does not fit in usize")
            }
            GenerateError::BufferLength {
                buffer,
                expected,
                actual,
            } => write!(
                f,
                "the {buffer} buffer has length {actual}, but the mesh needs exactly {expected}"
            ),
            GenerateError::NonFiniteBox => f.write_str("the box geometry must be finite"),
            GenerateError::EmptyBox => {
                f.write_str("the box is empty (min >= max on an axis, or parallel edge vectors)")
            }
            GenerateError::DegenerateCells => f.write_str(
                "the cells are too small or too large for this precision: \
                 an element would not have a positive finite rest volume",
            ),
        }
    }
}

impl core::error::Error for GenerateError {}

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

/// A single element's rest shape cannot be simulated.
///
/// Returned by the rest-data constructors of [`element`](crate::element)
/// (`TetRest::new`, `TriRest::new`, `TriRest::membrane`). A mesh reports the same conditions as a
/// [`MeshError`] that names the element.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ElementError {
    /// A rest position has a NaN or infinite coordinate.
    NonFiniteRestPosition,
    /// The signed rest volume (tetrahedron) or area (2D triangle) is negative: the vertices are
    /// in the wrong order (see `element::fix_orientation`).
    Inverted,
    /// The rest volume or area is zero, too small relative to the element's edge lengths to be
    /// resolved in this precision, or not representable (see `element::DEGENERACY_RATIO`).
    Degenerate,
}

impl fmt::Display for ElementError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ElementError::NonFiniteRestPosition => "a rest position is not finite",
            ElementError::Inverted => "the rest element is inverted (negative volume or area)",
            ElementError::Degenerate => "the rest element is degenerate (near-zero volume or area)",
        })
    }
}

impl core::error::Error for ElementError {}

/// A caller-owned buffer passed to a mesh constructor or kernel, named in
/// [`MeshError::LengthMismatch`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Buffer {
    /// The precomputed rest data, one entry per element.
    RestData,
    /// The deformed positions, one per vertex.
    Positions,
    /// The forces, one per vertex.
    Forces,
    /// The lumped masses, one per vertex.
    Masses,
    /// The per-element energies, one per element.
    Energies,
    /// The per-element stresses, one per element.
    Stresses,
}

impl fmt::Display for Buffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Buffer::RestData => "rest data",
            Buffer::Positions => "positions",
            Buffer::Forces => "forces",
            Buffer::Masses => "masses",
            Buffer::Energies => "energies",
            Buffer::Stresses => "stresses",
        })
    }
}

/// A mesh could not be built, or a mesh kernel was given unusable input.
///
/// Returned by the constructors and kernels of [`mesh`](crate::mesh). Every variant names the
/// first offending element (index into the element buffer) or vertex (index into the position
/// buffer). Kernels check their input before writing anything, so on error their output buffers
/// are unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum MeshError {
    /// A buffer does not have the length the mesh requires.
    LengthMismatch {
        /// Which buffer.
        buffer: Buffer,
        /// The length the mesh requires (its vertex or element count).
        expected: usize,
        /// The length given.
        actual: usize,
    },
    /// A rest position has a NaN or infinite coordinate.
    NonFiniteRestPosition {
        /// The vertex index.
        vertex: usize,
    },
    /// An element refers to a vertex that does not exist.
    IndexOutOfRange {
        /// The element index.
        element: usize,
        /// Which corner of the element (0-based).
        corner: u8,
        /// The vertex index found there.
        index: u32,
        /// The number of vertices of the mesh.
        vertex_count: usize,
    },
    /// An element's rest volume (or 2D area) is negative: its vertices are in the wrong order.
    InvertedElement {
        /// The element index.
        element: usize,
    },
    /// An element's rest volume or area is (near) zero relative to its edge lengths.
    DegenerateElement {
        /// The element index.
        element: usize,
    },
    /// A deformed position has a NaN or infinite coordinate.
    NonFinitePosition {
        /// The vertex index.
        vertex: usize,
    },
    /// The mass density is NaN, infinite, zero or negative.
    Density,
}

impl MeshError {
    /// The mesh-level error for `error` in element number `element`, whose corner vertices are
    /// `corners`. Mesh constructors check every rest position before any element, so
    /// `NonFiniteRestPosition` does not reach this point in practice; it names the first corner.
    pub(crate) fn in_element(error: ElementError, element: usize, corners: &[u32]) -> MeshError {
        match error {
            ElementError::NonFiniteRestPosition => MeshError::NonFiniteRestPosition {
                vertex: corners.first().map_or(0, |&i| i as usize),
            },
            ElementError::Inverted => MeshError::InvertedElement { element },
            ElementError::Degenerate => MeshError::DegenerateElement { element },
        }
    }
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            MeshError::LengthMismatch {
                buffer,
                expected,
                actual,
            } => write!(
                f,
                "the {buffer} buffer has length {actual}, expected {expected}"
            ),
            MeshError::NonFiniteRestPosition { vertex } => {
                write!(f, "rest position of vertex {vertex} is not finite")
            }
            MeshError::IndexOutOfRange {
                element,
                corner,
                index,
                vertex_count,
            } => write!(
                f,
                "element {element}, corner {corner}: vertex index {index} out of range \
                 (the mesh has {vertex_count} vertices)"
            ),
            MeshError::InvertedElement { element } => {
                write!(
                    f,
                    "element {element} is inverted at rest (negative volume or area)"
                )
            }
            MeshError::DegenerateElement { element } => {
                write!(
                    f,
                    "element {element} is degenerate at rest (near-zero volume or area)"
                )
            }
            MeshError::NonFinitePosition { vertex } => {
                write!(f, "position of vertex {vertex} is not finite")
            }
            MeshError::Density => f.write_str("the density must be finite and positive"),
        }
    }
}

impl core::error::Error for MeshError {}

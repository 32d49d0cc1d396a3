//! Errors of the asset pipeline: voxel meshing, embedding, surface buffers and (feature `std`)
//! the Gmsh and OBJ readers. Shared by both precisions, like the rest of [`error`](crate::error).

use core::fmt;

/// One of the caller-owned buffers of the voxel mesher (see [`VoxelError::BufferLength`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum VoxelBuffer {
    /// The directed-edge scratch of the closedness check (`closed_check_scratch_len`).
    EdgeScratch,
    /// The per-cell occupancy (`VoxelGrid::cell_count`).
    Occupancy,
    /// The grid-corner to vertex map (`VoxelGrid::corner_count`).
    CornerMap,
    /// The output vertex positions.
    Positions,
    /// The output tetrahedra.
    Tetrahedra,
}

impl fmt::Display for VoxelBuffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            VoxelBuffer::EdgeScratch => "edge scratch",
            VoxelBuffer::Occupancy => "occupancy",
            VoxelBuffer::CornerMap => "corner map",
            VoxelBuffer::Positions => "positions",
            VoxelBuffer::Tetrahedra => "tetrahedra",
        })
    }
}

/// The voxel mesher (module `voxel`) cannot mesh the given surface or grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum VoxelError {
    /// A buffer does not have the length its `*_len` function (or the grid) gives.
    BufferLength {
        /// The buffer at fault.
        buffer: VoxelBuffer,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        actual: usize,
    },
    /// The surface has no vertices or no triangles.
    EmptySurface,
    /// A surface vertex has a NaN or infinite coordinate.
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    IndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The vertex index it uses.
        index: u32,
    },
    /// The surface is not closed: the directed edge `from -> to` of `triangle` has no triangle on
    /// the other side using it as `to -> from`.
    OpenEdge {
        /// The triangle.
        triangle: usize,
        /// The edge's first vertex.
        from: u32,
        /// The edge's second vertex.
        to: u32,
    },
    /// The directed edge `from -> to` is used by two triangles (`triangle` is the second): the
    /// triangles around it are not consistently oriented, or more than two triangles meet there.
    RepeatedEdge {
        /// The triangle.
        triangle: usize,
        /// The edge's first vertex.
        from: u32,
        /// The edge's second vertex.
        to: u32,
    },
    /// The cell size (or resolution) is not a positive finite number.
    CellSize,
    /// The grid would have more corners than `u32` indices can address.
    TooManyCells,
    /// The coverage settings are out of range (samples per axis in `1..=8`, coverage in `(0, 1]`).
    Coverage,
    /// After rounding, some tetrahedron would not have a positive finite volume (cells too small
    /// for this precision so far from the origin).
    DegenerateCells,
}

impl fmt::Display for VoxelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            VoxelError::BufferLength {
                buffer,
                expected,
                actual,
            } => write!(
                f,
                "the {buffer} buffer has length {actual}, but it needs exactly {expected}"
            ),
            VoxelError::EmptySurface => f.write_str("the surface has no vertices or no triangles"),
            VoxelError::NonFinitePosition { vertex } => {
                write!(f, "surface vertex {vertex} is not finite")
            }
            VoxelError::IndexOutOfRange { triangle, index } => {
                write!(
                    f,
                    "triangle {triangle} uses vertex {index}, which does not exist"
                )
            }
            VoxelError::OpenEdge { triangle, from, to } => write!(
                f,
                "the surface is not closed: edge {from} -> {to} of triangle {triangle} has no \
                 opposite triangle"
            ),
            VoxelError::RepeatedEdge { triangle, from, to } => write!(
                f,
                "edge {from} -> {to} is used twice in the same direction (again by triangle \
                 {triangle}): inconsistent orientation or a non-manifold edge"
            ),
            VoxelError::CellSize => f.write_str("the cell size must be finite and positive"),
            VoxelError::TooManyCells => {
                f.write_str("the grid would have more corners than u32 indices can address")
            }
            VoxelError::Coverage => {
                f.write_str("samples per axis must be in 1..=8 and the coverage fraction in (0, 1]")
            }
            VoxelError::DegenerateCells => f.write_str(
                "the cells are too small for this precision: a tetrahedron would not have a \
                 positive finite volume",
            ),
        }
    }
}

impl core::error::Error for VoxelError {}

/// One of the caller-owned buffers of the embedding (see [`EmbedError::BufferLength`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EmbedBuffer {
    /// The lookup grid's bucket starts (`TetLookup::starts_len`).
    BucketStarts,
    /// The lookup grid's bucket entries (`TetLookup::entries_len`).
    BucketEntries,
    /// The embedding of the render points (one per point).
    Embedding,
    /// The simulated positions (one per simulation vertex).
    Positions,
    /// The output render positions or normals (one per render point).
    Output,
}

impl fmt::Display for EmbedBuffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            EmbedBuffer::BucketStarts => "bucket starts",
            EmbedBuffer::BucketEntries => "bucket entries",
            EmbedBuffer::Embedding => "embedding",
            EmbedBuffer::Positions => "positions",
            EmbedBuffer::Output => "output",
        })
    }
}

/// Embedding render points in a tetrahedral mesh (module `embed`) failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EmbedError {
    /// A buffer has the wrong length.
    BufferLength {
        /// The buffer at fault.
        buffer: EmbedBuffer,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        actual: usize,
    },
    /// The mesh has no tetrahedra.
    EmptyMesh,
    /// A tetrahedron refers to a vertex that does not exist.
    IndexOutOfRange {
        /// The tetrahedron.
        tet: usize,
        /// The vertex index it uses.
        index: u32,
    },
    /// A rest position or a render point is NaN or infinite.
    NonFinitePoint {
        /// The simulation vertex or render point.
        point: usize,
    },
    /// A tetrahedron has zero (or non-finite) rest volume, so barycentric weights are undefined.
    DegenerateTet {
        /// The tetrahedron.
        tet: usize,
    },
    /// The margin or the lookup cell size is negative, zero (cell size) or not finite.
    Settings,
    /// The lookup grid would have more cells or entries than `u32` can count.
    TooLarge,
    /// Render point `point` is farther than the margin from every tetrahedron.
    Outside {
        /// The render point.
        point: usize,
    },
}

impl fmt::Display for EmbedError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EmbedError::BufferLength {
                buffer,
                expected,
                actual,
            } => write!(
                f,
                "the {buffer} buffer has length {actual}, but it needs exactly {expected}"
            ),
            EmbedError::EmptyMesh => f.write_str("the mesh has no tetrahedra"),
            EmbedError::IndexOutOfRange { tet, index } => {
                write!(
                    f,
                    "tetrahedron {tet} uses vertex {index}, which does not exist"
                )
            }
            EmbedError::NonFinitePoint { point } => write!(f, "point {point} is not finite"),
            EmbedError::DegenerateTet { tet } => {
                write!(f, "tetrahedron {tet} has no positive finite rest volume")
            }
            EmbedError::Settings => f.write_str(
                "the margin must be finite and >= 0 and the lookup cell size finite and > 0",
            ),
            EmbedError::TooLarge => {
                f.write_str("the lookup grid would have more cells or entries than u32 counts")
            }
            EmbedError::Outside { point } => write!(
                f,
                "render point {point} is farther than the margin from every tetrahedron"
            ),
        }
    }
}

impl core::error::Error for EmbedError {}

/// A surface-buffer function (module `surface`) was given inconsistent buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SurfaceError {
    /// A buffer has the wrong length.
    BufferLength {
        /// The length it must have.
        expected: usize,
        /// The length it has.
        actual: usize,
    },
    /// An element refers to a vertex that does not exist.
    IndexOutOfRange {
        /// The element (tetrahedron or triangle).
        element: usize,
        /// The vertex index it uses.
        index: u32,
    },
}

impl fmt::Display for SurfaceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SurfaceError::BufferLength { expected, actual } => write!(
                f,
                "a surface buffer has length {actual}, but it needs exactly {expected}"
            ),
            SurfaceError::IndexOutOfRange { element, index } => {
                write!(
                    f,
                    "element {element} uses vertex {index}, which does not exist"
                )
            }
        }
    }
}

impl core::error::Error for SurfaceError {}

//! Errors of the asset pipeline: voxel meshing, embedding, surface buffers and (feature `std`)
//! the TetGen, Gmsh and OBJ readers. Shared by both precisions, like the rest of
//! [`error`](crate::error), which re-exports them (as do the crate root and every `asset`).

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
    /// The buffers a `std` helper would allocate, `bytes` in all, exceed its memory budget
    /// (`budget` bytes; `asset::MEMORY_BUDGET` unless the caller gave one). Checked before
    /// anything is allocated.
    OverBudget {
        /// The bytes the buffers need.
        bytes: usize,
        /// The budget (bytes).
        budget: usize,
    },
    /// The allocator refused `bytes` bytes for a buffer (a `std` helper allocates fallibly).
    Allocation {
        /// The bytes asked for.
        bytes: usize,
    },
    /// The cell size `h` is too large or too small for this precision: `8 h^3` (a bound on a
    /// cell's volume determinants) overflows, or `h^3 / 6` (m^3, its smallest tetrahedron) is
    /// not a normal number, so no tetrahedron could be built (for example a 1 m asset scaled by
    /// `1e30` or `1e-30` in f32).
    CellScale,
    /// The closed surface encloses no positive volume: it is inside out (its triangles are
    /// clockwise seen from outside) or flat (it encloses nothing), so no cell can be inside.
    NoVolume,
    /// No cell of the grid is kept: the solid is thinner than the cells (or, with coverage
    /// options, than the fraction asked for). Refine the grid; an empty mesh is never returned.
    NoCellsInside,
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
            VoxelError::OverBudget { bytes, budget } => write!(
                f,
                "voxel meshing needs {bytes} bytes of buffers, over its memory budget of \
                 {budget} bytes (use a coarser grid)"
            ),
            VoxelError::Allocation { bytes } => {
                write!(f, "the allocator refused {bytes} bytes for a voxel buffer")
            }
            VoxelError::CellScale => f.write_str(
                "the cell size is too large or too small for this precision: a cell's volume \
                 would overflow or underflow (rescale the surface to metres)",
            ),
            VoxelError::NoVolume => f.write_str(
                "the closed surface encloses no positive volume: it is inside out (clockwise \
                 triangles) or flat",
            ),
            VoxelError::NoCellsInside => f.write_str(
                "no cell of the grid is inside the surface: the grid is too coarse for the solid",
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
    /// The buffers a `std` helper would allocate, `bytes` in all, exceed its memory budget
    /// (`budget` bytes; `asset::MEMORY_BUDGET` unless the caller gave one). Checked before
    /// anything is allocated.
    OverBudget {
        /// The bytes the buffers need.
        bytes: usize,
        /// The budget (bytes).
        budget: usize,
    },
    /// The allocator refused `bytes` bytes for a buffer (a `std` helper allocates fallibly).
    Allocation {
        /// The bytes asked for.
        bytes: usize,
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
            EmbedError::OverBudget { bytes, budget } => write!(
                f,
                "embedding needs {bytes} bytes of buffers, over its memory budget of {budget} \
                 bytes (a smaller margin, or render points closer to the mesh)"
            ),
            EmbedError::Allocation { bytes } => {
                write!(
                    f,
                    "the allocator refused {bytes} bytes for an embedding buffer"
                )
            }
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

/// What is wrong with a line of a Wavefront OBJ file (see [`ObjFormatError`]).
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ObjProblem {
    /// A `v` line has fewer than three coordinates.
    MissingCoordinates,
    /// Field `field` (counting from 1 after the keyword) is not a number or not a vertex
    /// reference.
    BadField {
        /// The field.
        field: usize,
    },
    /// A coordinate is NaN or infinite.
    NonFiniteCoordinate,
    /// A face has fewer than three vertices.
    FaceTooSmall {
        /// How many it has.
        vertices: usize,
    },
    /// A face uses vertex index 0 (OBJ numbers vertices from 1; negative indices count back).
    ZeroIndex,
    /// A face refers to a vertex that does not exist.
    IndexOutOfRange {
        /// The index as written.
        index: i64,
        /// The number of vertices (defined so far, for a negative index).
        vertices: usize,
    },
    /// The file has no faces.
    NoFaces,
}

#[cfg(feature = "std")]
impl fmt::Display for ObjProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ObjProblem::MissingCoordinates => f.write_str("a vertex needs three coordinates"),
            ObjProblem::BadField { field } => write!(f, "field {field} is not valid"),
            ObjProblem::NonFiniteCoordinate => f.write_str("a coordinate is not finite"),
            ObjProblem::FaceTooSmall { vertices } => {
                write!(
                    f,
                    "a face needs at least 3 vertices, this one has {vertices}"
                )
            }
            ObjProblem::ZeroIndex => f.write_str("vertex index 0 (OBJ numbers vertices from 1)"),
            ObjProblem::IndexOutOfRange { index, vertices } => {
                write!(
                    f,
                    "vertex index {index} is out of range ({vertices} vertices)"
                )
            }
            ObjProblem::NoFaces => f.write_str("the file has no faces"),
        }
    }
}

/// A Wavefront OBJ text is malformed: the line (1-based) and the problem.
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ObjFormatError {
    /// The line, counting from 1 (the last line for [`ObjProblem::NoFaces`]).
    pub line: usize,
    /// What is wrong.
    pub problem: ObjProblem,
}

#[cfg(feature = "std")]
impl fmt::Display for ObjFormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.line, self.problem)
    }
}

#[cfg(feature = "std")]
impl core::error::Error for ObjFormatError {}

/// A section of a Gmsh `.msh` file (see [`GmshProblem`]).
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum GmshSection {
    /// `$MeshFormat`.
    MeshFormat,
    /// `$Nodes`.
    Nodes,
    /// `$Elements`.
    Elements,
}

#[cfg(feature = "std")]
impl fmt::Display for GmshSection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            GmshSection::MeshFormat => "$MeshFormat",
            GmshSection::Nodes => "$Nodes",
            GmshSection::Elements => "$Elements",
        })
    }
}

/// What is wrong with a line of a Gmsh `.msh` file (see [`GmshFormatError`]).
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum GmshProblem {
    /// A required section is missing (or the file ended inside it).
    MissingSection(GmshSection),
    /// The file ended before a section's `$End...` line.
    UnterminatedSection(GmshSection),
    /// The format version is not 4.1.
    UnsupportedVersion,
    /// The file is binary (`file-type` 1); only ASCII is read.
    Binary,
    /// The line has the wrong number of fields.
    FieldCount {
        /// How many it must have.
        expected: usize,
        /// How many it has.
        found: usize,
    },
    /// Field `field` (counting from 1) is not a number of the expected kind.
    BadField {
        /// The field.
        field: usize,
    },
    /// A coordinate is NaN or infinite.
    NonFiniteCoordinate,
    /// A node tag appears twice.
    DuplicateNode {
        /// The tag.
        tag: u64,
    },
    /// An element refers to a node tag that no node has.
    UnknownNode {
        /// The tag.
        tag: u64,
    },
    /// A count in a header does not match the records that follow.
    CountMismatch {
        /// The count the header gives.
        expected: usize,
        /// The count found.
        found: usize,
    },
    /// An element type this reader does not convert (higher-order or non-simplex surface and
    /// volume elements; points and lines are skipped, 3-node triangles and 4-node tetrahedra
    /// read).
    UnsupportedElement {
        /// The Gmsh element type number.
        element_type: u32,
    },
    /// A line other than the expected `$End...` closes a section.
    ExpectedEnd(GmshSection),
    /// A section this reader needs appears a second time (on the reported line): which of
    /// the two the elements refer to would be a guess.
    RepeatedSection(GmshSection),
}

#[cfg(feature = "std")]
impl fmt::Display for GmshProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GmshProblem::MissingSection(section) => write!(f, "the {section} section is missing"),
            GmshProblem::UnterminatedSection(section) => {
                write!(f, "the file ends inside the {section} section")
            }
            GmshProblem::UnsupportedVersion => f.write_str("only MSH version 4.1 is read"),
            GmshProblem::Binary => f.write_str("binary MSH files are not read (save as ASCII)"),
            GmshProblem::FieldCount { expected, found } => {
                write!(f, "expected {expected} fields, found {found}")
            }
            GmshProblem::BadField { field } => write!(f, "field {field} is not a valid number"),
            GmshProblem::NonFiniteCoordinate => f.write_str("a coordinate is not finite"),
            GmshProblem::DuplicateNode { tag } => write!(f, "node tag {tag} appears twice"),
            GmshProblem::UnknownNode { tag } => write!(f, "node tag {tag} does not exist"),
            GmshProblem::CountMismatch { expected, found } => {
                write!(f, "the header announces {expected} records, found {found}")
            }
            GmshProblem::UnsupportedElement { element_type } => write!(
                f,
                "element type {element_type} is not read (only 3-node triangles and 4-node \
                 tetrahedra; points and lines are skipped)"
            ),
            GmshProblem::ExpectedEnd(section) => write!(f, "expected the end of {section}"),
            GmshProblem::RepeatedSection(section) => {
                write!(f, "a second {section} section (the file may have only one)")
            }
        }
    }
}

/// A Gmsh `.msh` text is malformed: the line (1-based) and the problem.
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GmshFormatError {
    /// The line, counting from 1 (one past the last line when the file ends too early).
    pub line: usize,
    /// What is wrong.
    pub problem: GmshProblem,
}

#[cfg(feature = "std")]
impl fmt::Display for GmshFormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}: {}", self.line, self.problem)
    }
}

#[cfg(feature = "std")]
impl core::error::Error for GmshFormatError {}

/// Reading or writing an asset file failed: which file, and why (`path:line: problem` when
/// displayed).
#[cfg(feature = "std")]
#[derive(Debug)]
#[non_exhaustive]
pub enum AssetFileError {
    /// The file could not be read or written.
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// An OBJ file is malformed.
    Obj {
        /// The file.
        path: std::path::PathBuf,
        /// Where and what.
        error: ObjFormatError,
    },
    /// A Gmsh file is malformed.
    Gmsh {
        /// The file.
        path: std::path::PathBuf,
        /// Where and what.
        error: GmshFormatError,
    },
}

#[cfg(feature = "std")]
impl fmt::Display for AssetFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AssetFileError::Io { path, source } => write!(f, "{}: {source}", path.display()),
            AssetFileError::Obj { path, error } => {
                write!(f, "{}:{}: {}", path.display(), error.line, error.problem)
            }
            AssetFileError::Gmsh { path, error } => {
                write!(f, "{}:{}: {}", path.display(), error.line, error.problem)
            }
        }
    }
}

#[cfg(feature = "std")]
impl core::error::Error for AssetFileError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            AssetFileError::Io { source, .. } => Some(source),
            AssetFileError::Obj { error, .. } => Some(error),
            AssetFileError::Gmsh { error, .. } => Some(error),
        }
    }
}

/// Which file of a TetGen mesh a [`TetgenFormatError`] is in.
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum TetgenFile {
    /// The `.node` file (vertex positions).
    Node,
    /// The `.ele` file (tetrahedra).
    Ele,
}

#[cfg(feature = "std")]
impl fmt::Display for TetgenFile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TetgenFile::Node => ".node",
            TetgenFile::Ele => ".ele",
        })
    }
}

/// What is wrong with one line of a TetGen file (see [`TetgenFormatError`]).
///
/// Field numbers count from 1 within the line, after comments (`#` to the end of the line) are
/// removed.
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum TetgenProblem {
    /// The file has no header line (it is empty, or only comments and blank lines).
    MissingHeader,
    /// A header field has a value this reader does not accept.
    BadHeader {
        /// The field (1-based).
        field: usize,
        /// What the field must be, for example `"the dimension 3"`.
        expected: &'static str,
    },
    /// The `.ele` header declares 10-node (quadratic, `-o2`) tetrahedra; only 4-node linear
    /// tetrahedra are supported.
    UnsupportedElement {
        /// The declared number of nodes per tetrahedron.
        nodes_per_tet: usize,
    },
    /// The `.node` header declares more points than `u32` indices can address.
    TooManyNodes,
    /// The file has a different number of records than its header declares. Reported on the
    /// header line when records are missing, and on the first extra record otherwise.
    WrongCount {
        /// The count in the header.
        declared: usize,
        /// The number of records in the file.
        found: usize,
    },
    /// A line has too few (or too many) fields for what the header declares.
    FieldCount {
        /// Fields the header implies: index, coordinates or nodes, attributes, marker.
        expected: usize,
        /// Fields on the line.
        found: usize,
    },
    /// A field is not a number (or not an integer where an index or count is expected).
    NonNumeric {
        /// The field (1-based).
        field: usize,
    },
    /// A coordinate is NaN or infinite, or overflows this precision.
    NonFinite {
        /// The field (1-based).
        field: usize,
    },
    /// The first point's index is neither 0 nor 1.
    FirstIndex {
        /// The index found.
        found: i64,
    },
    /// A record's index is not one more than the previous record's (a duplicate, a gap, or, for
    /// the first tetrahedron, not the numbering base of the points).
    NonConsecutiveIndex {
        /// The index the record must have.
        expected: u64,
        /// The index found.
        found: i64,
    },
    /// A tetrahedron refers to a point that the `.node` file does not have.
    IndexOutOfRange {
        /// The point index found.
        index: i64,
        /// The number of points in the `.node` file.
        points: usize,
        /// The index of the first point (0 or 1).
        first: u32,
    },
    /// A tetrahedron's rest volume is (near) zero relative to its edge lengths (the element
    /// module's degeneracy test, `DEGENERACY_RATIO`), or not finite: it cannot be simulated.
    DegenerateTet {
        /// The tetrahedron's index as written in the file.
        index: i64,
    },
}

#[cfg(feature = "std")]
impl fmt::Display for TetgenProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            TetgenProblem::MissingHeader => f.write_str("missing header line"),
            TetgenProblem::BadHeader { field, expected } => {
                write!(f, "header field {field} must be {expected}")
            }
            TetgenProblem::UnsupportedElement { nodes_per_tet } => write!(
                f,
                "{nodes_per_tet}-node tetrahedra are not supported (only 4-node linear ones)"
            ),
            TetgenProblem::TooManyNodes => f.write_str("more points than u32 indices can address"),
            TetgenProblem::WrongCount { declared, found } => {
                write!(
                    f,
                    "the header declares {declared} records, the file has {found}"
                )
            }
            TetgenProblem::FieldCount { expected, found } => {
                write!(f, "expected {expected} fields, found {found}")
            }
            TetgenProblem::NonNumeric { field } => write!(f, "field {field} is not a valid number"),
            TetgenProblem::NonFinite { field } => {
                write!(
                    f,
                    "coordinate in field {field} is not finite in this precision"
                )
            }
            TetgenProblem::FirstIndex { found } => {
                write!(
                    f,
                    "the first point has index {found}; indices must start at 0 or 1"
                )
            }
            TetgenProblem::NonConsecutiveIndex { expected, found } => write!(
                f,
                "record index {found} where {expected} was expected (indices must be consecutive)"
            ),
            TetgenProblem::IndexOutOfRange {
                index,
                points,
                first,
            } => write!(
                f,
                "point index {index} is out of range ({points} points numbered from {first})"
            ),
            TetgenProblem::DegenerateTet { index } => write!(
                f,
                "tetrahedron {index} is degenerate (near-zero or non-finite rest volume)"
            ),
        }
    }
}

/// A TetGen `.node` or `.ele` text is malformed: which file, which line (1-based) and what is
/// wrong with it.
#[cfg(feature = "std")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TetgenFormatError {
    /// The file the problem is in.
    pub file: TetgenFile,
    /// The line, counting from 1 (past the last line for a missing header).
    pub line: usize,
    /// What is wrong.
    pub problem: TetgenProblem,
}

#[cfg(feature = "std")]
impl fmt::Display for TetgenFormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} file, line {}: {}",
            self.file, self.line, self.problem
        )
    }
}

#[cfg(feature = "std")]
impl core::error::Error for TetgenFormatError {}

/// Reading a TetGen mesh from files failed (see `read_tetgen_files` in the `tetgen` module).
#[cfg(feature = "std")]
#[derive(Debug)]
#[non_exhaustive]
pub enum TetgenError {
    /// A file could not be read.
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file was read but is malformed.
    Format {
        /// The file.
        path: std::path::PathBuf,
        /// Where and what.
        error: TetgenFormatError,
    },
}

#[cfg(feature = "std")]
impl fmt::Display for TetgenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TetgenError::Io { path, source } => {
                write!(f, "cannot read {}: {source}", path.display())
            }
            TetgenError::Format { path, error } => {
                write!(f, "{}:{}: {}", path.display(), error.line, error.problem)
            }
        }
    }
}

#[cfg(feature = "std")]
impl core::error::Error for TetgenError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            TetgenError::Io { source, .. } => Some(source),
            TetgenError::Format { error, .. } => Some(error),
        }
    }
}

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
    /// The per-element Hessian cache (`TetHessian`), one per element.
    Hessians,
    /// A direction (displacement) the Hessian is applied to, one per vertex.
    Direction,
    /// The output of a Hessian product, one per vertex.
    Products,
    /// The per-vertex 3x3 Hessian blocks, one per vertex.
    Blocks,
    /// The vertex-to-element adjacency offsets of a `TetPartition`, one per vertex plus one.
    AdjacencyOffsets,
    /// The vertex-to-element adjacency entries of a `TetPartition`, four per element.
    AdjacencyIncident,
    /// The per-element nodal forces of a partitioned pass, one entry (four vectors) per element
    /// (or per element of the piece).
    ElementForces,
    /// The rest data in blocks of 16 elements (`TetRestBlock`), one per 16 elements or part.
    RestBlocks,
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
            Buffer::Hessians => "Hessian cache",
            Buffer::Direction => "direction",
            Buffer::Products => "Hessian product",
            Buffer::Blocks => "Hessian blocks",
            Buffer::AdjacencyOffsets => "adjacency offsets",
            Buffer::AdjacencyIncident => "adjacency entries",
            Buffer::ElementForces => "element forces",
            Buffer::RestBlocks => "rest blocks",
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
    /// A direction given to a Hessian product has a NaN or infinite coordinate.
    NonFiniteDirection {
        /// The vertex index.
        vertex: usize,
    },
    /// The stretch threshold of the clamped stress is not in `(0, 1]` (NaN, infinite, zero,
    /// negative, or above the rest stretch 1, where even an undeformed element would be
    /// clamped).
    ClampThreshold,
    /// An element's deformation gradient has an entry beyond the material's
    /// `Material::deformation_limit`, where its energy or stress would overflow this precision
    /// (for example positions scaled by `1e13` in f32).
    DeformationRange {
        /// The element index.
        element: usize,
    },
    /// An element's share of the lumped mass, `density * measure / corners` (kg), is not a
    /// normal floating-point number, or is so large that a vertex's sum could overflow: the
    /// density does not suit the element sizes in this precision.
    MassRange {
        /// The element index.
        element: usize,
    },
    /// A `TetPartition` was asked for on a mesh with more than `u32::MAX / 4` elements, which
    /// its vertex-to-element adjacency (packed `u32` entries) cannot index.
    TooManyElements,
    /// A piece index of a `TetPartition` at or beyond its piece count.
    PieceIndex {
        /// The piece asked for.
        piece: usize,
        /// The number of pieces of that kind.
        pieces: usize,
    },
    /// The body–body contact of a model with contact
    /// ([`step::contact::ContactModel`](crate::step::contact::ContactModel)) refused the input or
    /// ran out of a caller buffer (the error names the buffer and the count needed).
    Contact(ContactError),
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
            MeshError::NonFiniteDirection { vertex } => {
                write!(f, "direction at vertex {vertex} is not finite")
            }
            MeshError::ClampThreshold => {
                f.write_str("the clamp threshold must be a stretch in (0, 1]")
            }
            MeshError::DeformationRange { element } => write!(
                f,
                "element {element} is deformed beyond the range in which the material's stress \
                 is finite in this precision"
            ),
            MeshError::MassRange { element } => write!(
                f,
                "element {element}: density times volume gives a mass this precision cannot \
                 represent (underflow or overflow)"
            ),
            MeshError::TooManyElements => write!(
                f,
                "a partition's adjacency indexes at most u32::MAX / 4 elements"
            ),
            MeshError::PieceIndex { piece, pieces } => {
                write!(f, "piece {piece} asked for, the partition has {pieces}")
            }
            MeshError::Contact(error) => write!(f, "contact: {error}"),
        }
    }
}

impl core::error::Error for MeshError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            MeshError::Contact(error) => Some(error),
            _ => None,
        }
    }
}

impl From<ContactError> for MeshError {
    #[inline]
    fn from(error: ContactError) -> Self {
        MeshError::Contact(error)
    }
}

/// A caller-owned buffer passed to a time stepper in [`step`](crate::step), named in
/// [`StepError::LengthMismatch`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StepBuffer {
    /// The positions, one per vertex.
    Positions,
    /// The velocities, one per vertex.
    Velocities,
    /// The lumped masses, one per vertex.
    Masses,
    /// The pinned-vertex flags: empty (nothing pinned) or one per vertex.
    Pinned,
    /// The vector scratch buffer (see `scratch_len::explicit` / `scratch_len::relax`).
    Scratch,
    /// The scalar scratch buffer of the relaxation (one per vertex).
    ScalarScratch,
    /// The index scratch buffer of Vertex Block Descent (see `scratch_len::vbd_indices`).
    IndexScratch,
    /// The offsets of a vertex adjacency, `vertex_count + 1` (see `adjacency_offsets_len`).
    AdjacencyOffsets,
    /// The incident (element, corner) entries of a vertex adjacency, four per element (see
    /// `adjacency_incident_len`).
    AdjacencyIncident,
    /// The per-vertex colours of a vertex colouring, one per vertex.
    Colours,
    /// The vertex order of a colouring, one per vertex.
    VertexOrder,
    /// The 3x3 block scratch buffer of Newton's method (one per vertex).
    BlockScratch,
    /// The per-element Hessian cache of Newton's method (one per element).
    HessianScratch,
    /// The external forces of a solver's settings: empty (no loads) or one per vertex.
    ExternalForces,
    /// The per-vertex fixed-axis masks of a solver's settings: empty (none) or one per vertex.
    FixedAxes,
    /// The previous step's velocities of Vertex Block Descent's settings: empty (none) or one
    /// per vertex.
    PreviousVelocities,
    /// The colliders' contact impulses of a step, one per vertex (see
    /// `ExplicitScratch::with_impulses`).
    Impulses,
    /// The colliders' reactions of a step, one per collider (see `Body::step_with_reactions`).
    Reactions,
}

impl fmt::Display for StepBuffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            StepBuffer::Positions => "positions",
            StepBuffer::Velocities => "velocities",
            StepBuffer::Masses => "masses",
            StepBuffer::Pinned => "pinned flags",
            StepBuffer::Scratch => "scratch",
            StepBuffer::ScalarScratch => "scalar scratch",
            StepBuffer::IndexScratch => "index scratch",
            StepBuffer::AdjacencyOffsets => "adjacency offsets",
            StepBuffer::AdjacencyIncident => "adjacency incidences",
            StepBuffer::Colours => "colours",
            StepBuffer::VertexOrder => "vertex order",
            StepBuffer::BlockScratch => "block scratch",
            StepBuffer::HessianScratch => "Hessian scratch",
            StepBuffer::ExternalForces => "external forces",
            StepBuffer::FixedAxes => "fixed axes",
            StepBuffer::PreviousVelocities => "previous velocities",
            StepBuffer::Impulses => "contact impulses",
            StepBuffer::Reactions => "collider reactions",
        })
    }
}

/// A time step was refused (bad parameters or input, nothing touched) or failed (blow-up, the
/// caller's state restored to exactly what it was before the call).
///
/// Returned by the steppers of [`step`](crate::step). Parameter and input errors are found before
/// anything is written; [`NonFiniteState`](Self::NonFiniteState) and
/// [`EnergyBlowUp`](Self::EnergyBlowUp) are found after the step, and the stepper then restores
/// positions and velocities bit for bit from its scratch backup.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StepError {
    /// The time step `dt` (s) is NaN, infinite, zero or negative.
    TimeStep,
    /// The number of substeps is zero or above `step::ExplicitSettings::MAX_SUBSTEPS` (65536).
    Substeps,
    /// A buffer does not have the length the model needs.
    LengthMismatch {
        /// The buffer at fault.
        buffer: StepBuffer,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        actual: usize,
    },
    /// A lumped mass is NaN, infinite, zero, negative or subnormal (below `Real::MIN_POSITIVE`,
    /// whose reciprocal overflows).
    Mass {
        /// The vertex index.
        vertex: usize,
    },
    /// Gravity has a NaN or infinite component.
    Gravity,
    /// The damping coefficient (1/s) is NaN, infinite or negative.
    Damping,
    /// The ground normal is zero, NaN or infinite, or its offset is not finite.
    Ground,
    /// The restitution coefficient is NaN or outside `[0, 1]`.
    Restitution,
    /// The friction coefficient is NaN, infinite or negative, or the sticking speed is not
    /// finite and `>= 0`.
    Friction,
    /// The blow-up growth limit is NaN or not greater than 1.
    GrowthLimit,
    /// A relaxation setting is out of range: tolerance not in `[0, 1)`, Armijo constant not in
    /// `(0, 1)`, backtracking factor not in `(0, 1)`, momentum not in `[0, 1)`, Chebyshev
    /// spectral radius not in `[0, 1)`, step length not finite and positive, or momentum and
    /// Chebyshev acceleration both set.
    RelaxSettings,
    /// A Vertex Block Descent setting is out of range: tolerance not in `[0, 1)`, Armijo
    /// constant not in `(0, 1)`, backtracking factor not in `(0, 1)`, Chebyshev spectral
    /// radius not in `[0, 1)`, or an estimated radius asked for with a given one or with a
    /// delay below 2.
    VbdSettings,
    /// The mesh has more than `u32::MAX / 4` elements, too many for a vertex adjacency's packed
    /// `(element, corner)` entries.
    TooManyElements,
    /// A mesh element names a vertex at or beyond the vertex count.
    VertexIndex {
        /// The element.
        element: usize,
        /// The vertex index found there.
        index: u32,
    },
    /// A Newton setting is out of range: tolerance not in `[0, 1)`, Armijo constant not in
    /// `(0, 1)`, backtracking factor not in `(0, 1)`, or zero Newton or CG iterations allowed.
    NewtonSettings,
    /// A given position or velocity is NaN or infinite (before the step).
    NonFiniteInput {
        /// The first such vertex.
        vertex: usize,
    },
    /// The step produced a NaN or infinite position or velocity; the state was restored.
    NonFiniteState {
        /// The first such vertex.
        vertex: usize,
    },
    /// The explicit step is past its stability limit: the elastic forces reversed and grew for
    /// `step::ExplicitSettings::FLIP_STREAK` substeps in a row, or reversed and grew fourfold
    /// for two (the unstable mode of symplectic Euler, caught early), or the energy indicator grew by more than the allowed factor in one
    /// substep. The state was restored to what it was before the call.
    EnergyBlowUp,
    /// The force or energy kernel refused the input.
    Mesh(MeshError),
    /// The stability bound of a vertex is NaN or infinite: the material is too stiff for this
    /// precision (a modulus near `Real::MAX`), or a custom model reported a NaN stiffness.
    Stiffness {
        /// The vertex index.
        vertex: usize,
    },
    /// The relaxation's time step is so small that `1 / dt^2` overflows this precision (below
    /// about `1e-19` s in f32, `1e-154` s in f64).
    TimeStepTooSmall,
    /// An external force (N) has a NaN or infinite component.
    ExternalForce {
        /// The vertex index.
        vertex: usize,
    },
    /// A fixed-axis mask sets a bit beyond the space's axes (bit 0 x, 1 y, 2 z; only bits 0
    /// and 1 for 2D bodies).
    FixedAxes {
        /// The vertex index.
        vertex: usize,
    },
    /// An attachment names a vertex at or beyond the vertex count.
    AttachedVertex {
        /// The entry of the attachment's vertex list.
        entry: usize,
        /// The vertex index found there.
        vertex: u32,
    },
    /// A collider of the settings (or of the body's step) is out of range.
    Collider {
        /// Its index in the collider slice.
        collider: usize,
        /// What is wrong with it.
        problem: ColliderProblem,
    },
    /// The owning body has no vertices: it was never built ([`Body::empty`]) or its last
    /// rebuild failed ([`Body::rebuild_from_box`]).
    ///
    /// [`Body::empty`]: crate::body::Body::empty
    /// [`Body::rebuild_from_box`]: crate::body::Body::rebuild_from_box
    EmptyBody,
    /// An allocation of Newton's multilevel preconditioner (feature `alloc`) failed: its
    /// hierarchy of sparse matrices did not fit in memory. Nothing was moved.
    OutOfMemory,
    /// A coupled step ([`Body::step_with_rigid_bodies`]) was given more dynamic colliders than
    /// it takes. Nothing was moved.
    ///
    /// [`Body::step_with_rigid_bodies`]: crate::body::Body::step_with_rigid_bodies
    TooManyDynamicColliders {
        /// The most it takes ([`MAX_DYNAMIC_COLLIDERS`](crate::step::MAX_DYNAMIC_COLLIDERS)).
        limit: usize,
    },
    /// An attachment names a collider at or beyond the step's collider count, or its point is
    /// not finite.
    AttachedCollider {
        /// The entry of the attachment list.
        entry: usize,
        /// The collider index found there.
        collider: u32,
    },
    /// A coupled step with a soft attachment was asked of the explicit stepper: the spring and
    /// the damper are terms of the implicit objective. Use an implicit solver (the automatic
    /// one takes Newton's method for such steps). Nothing was moved.
    SoftAttachmentSolver,
    /// A coupled step was given more attachments than it takes. Nothing was moved.
    TooManyAttachments {
        /// The most it takes ([`MAX_ATTACHMENTS`](crate::step::MAX_ATTACHMENTS)).
        limit: usize,
    },
    /// A coupled step was given a scene with colliders of its own: it takes every collider,
    /// static, kinematic and dynamic, in its `colliders` argument. Nothing was moved.
    SceneColliders,
    /// The coupling settings are out of range: the tolerance not finite and `> 0`, or no
    /// iteration allowed ([`CouplingSettings`](crate::step::CouplingSettings)).
    CouplingSettings,
}

/// What is wrong with a collider ([`StepError::Collider`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ColliderProblem {
    /// A radius, half length or half extent is NaN, infinite, zero or negative.
    Shape,
    /// The position is not finite.
    Position,
    /// The rotation quaternion is not finite or not of unit length (within `1e-3`).
    Rotation,
    /// The linear or angular velocity is not finite.
    Velocity,
    /// The restitution lies outside `[0, 1]`.
    Restitution,
    /// The friction coefficient is NaN, infinite or negative, or the sticking speed is not
    /// finite and `>= 0`.
    Friction,
    /// Colliders were given to a 2D body: they act on 3D bodies only.
    Dimension,
    /// The mass is NaN, infinite or negative, or the collider is dynamic (a positive mass)
    /// and a moment of inertia is not finite and `> 0`.
    Mass,
}

impl fmt::Display for ColliderProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ColliderProblem::Shape => "a radius, half length or half extent is not finite and > 0",
            ColliderProblem::Position => "its position is not finite",
            ColliderProblem::Rotation => "its rotation is not a finite unit quaternion",
            ColliderProblem::Velocity => "its linear or angular velocity is not finite",
            ColliderProblem::Restitution => "its restitution is outside [0, 1]",
            ColliderProblem::Friction => "its friction coefficient is not finite and >= 0, or its sticking speed not finite and >= 0",
            ColliderProblem::Dimension => "colliders act on 3D bodies only",
            ColliderProblem::Mass => "its mass is not finite and >= 0, or it is dynamic and a moment of inertia is not finite and > 0",
        })
    }
}

impl From<MeshError> for StepError {
    fn from(error: MeshError) -> StepError {
        StepError::Mesh(error)
    }
}

impl fmt::Display for StepError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            StepError::TimeStep => f.write_str("the time step must be finite and positive"),
            StepError::EmptyBody => f.write_str(
                "the body has no vertices: build it first (a failed rebuild leaves it empty)",
            ),
            StepError::Substeps => {
                f.write_str("the number of substeps must be at least 1 and at most 65536")
            }
            StepError::LengthMismatch {
                buffer,
                expected,
                actual,
            } => write!(
                f,
                "the {buffer} buffer has length {actual}, expected {expected}"
            ),
            StepError::Mass { vertex } => {
                write!(
                    f,
                    "the mass of vertex {vertex} must be a finite normal positive number"
                )
            }
            StepError::Gravity => f.write_str("gravity must be finite"),
            StepError::Damping => f.write_str("the damping coefficient must be finite and >= 0"),
            StepError::Ground => {
                f.write_str("the ground needs a finite non-zero normal and a finite offset")
            }
            StepError::Restitution => f.write_str("the restitution must lie in [0, 1]"),
            StepError::Friction => f.write_str("the friction coefficient must be finite and >= 0, the sticking speed finite and >= 0"),
            StepError::GrowthLimit => {
                f.write_str("the blow-up growth limit must be a number greater than 1")
            }
            StepError::RelaxSettings => f.write_str("a relaxation setting is out of range"),
            StepError::VbdSettings => f.write_str("a Vertex Block Descent setting is out of range"),
            StepError::TooManyElements => {
                f.write_str("more than u32::MAX / 4 elements: the adjacency cannot index them")
            }
            StepError::VertexIndex { element, index } => write!(
                f,
                "element {element} names vertex {index}, beyond the vertex count"
            ),
            StepError::NewtonSettings => f.write_str("a Newton setting is out of range"),
            StepError::OutOfMemory => {
                f.write_str("Newton's multilevel preconditioner could not allocate its hierarchy")
            }
            StepError::NonFiniteInput { vertex } => {
                write!(f, "position or velocity of vertex {vertex} is not finite")
            }
            StepError::NonFiniteState { vertex } => write!(
                f,
                "the step made vertex {vertex} non-finite (blow-up); the state was restored"
            ),
            StepError::EnergyBlowUp => f.write_str(
                "the step blew up (time step above the stability limit: an unstable mode or an \
                 energy jump); the state was restored",
            ),
            StepError::Mesh(error) => write!(f, "{error}"),
            StepError::Stiffness { vertex } => write!(
                f,
                "the stability bound of vertex {vertex} is not finite (material too stiff for \
                 this precision, or a NaN stiffness)"
            ),
            StepError::TimeStepTooSmall => {
                f.write_str("the time step is so small that 1 / dt^2 overflows this precision")
            }
            StepError::ExternalForce { vertex } => {
                write!(f, "the external force on vertex {vertex} is not finite")
            }
            StepError::AttachedVertex { entry, vertex } => write!(
                f,
                "entry {entry} of the attachment names vertex {vertex}, beyond the vertex count"
            ),
            StepError::FixedAxes { vertex } => write!(
                f,
                "the fixed-axis mask of vertex {vertex} names an axis this space does not have"
            ),
            StepError::Collider { collider, problem } => {
                write!(f, "collider {collider}: {problem}")
            }
            StepError::TooManyDynamicColliders { limit } => write!(
                f,
                "a coupled step takes at most {limit} dynamic colliders (a positive mass)"
            ),
            StepError::AttachedCollider { entry, collider } => write!(
                f,
                "attachment {entry} names collider {collider}, beyond the collider count, or its point is not finite"
            ),
            StepError::SoftAttachmentSolver => f.write_str(
                "soft attachments need an implicit solver (Newton, the relaxation, VBD or the automatic one)",
            ),
            StepError::TooManyAttachments { limit } => {
                write!(f, "a coupled step takes at most {limit} attachments")
            }
            StepError::SceneColliders => f.write_str(
                "a coupled step takes its colliders in its own argument: the scene must have none",
            ),
            StepError::CouplingSettings => f.write_str(
                "the coupling tolerance is not finite and > 0, or no iteration is allowed",
            ),
        }
    }
}

impl core::error::Error for StepError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            StepError::Mesh(error) => Some(error),
            _ => None,
        }
    }
}

/// A buffer of the body–body contact queries in
/// [`step::contact`](crate::step::contact), named in [`ContactError`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ContactBuffer {
    /// The positions (m), one per vertex of every body.
    Positions,
    /// The end positions of a motion query (m), one per vertex like the positions.
    EndPositions,
    /// The boundary triangles (vertex indices).
    Triangles,
    /// The boundary edges (vertex indices): input of the broad phase, output of
    /// `boundary::boundary_edges`.
    Edges,
    /// The boundary vertices (vertex indices): input of the broad phase, output of
    /// `boundary::boundary_vertices`.
    Vertices,
    /// The broad phase's hash-table slots (see `scratch_len::broad_phase`).
    Slots,
    /// The broad phase's cell entries (see `scratch_len::broad_phase`).
    Entries,
    /// The output (vertex, triangle) candidate pairs.
    VertexTrianglePairs,
    /// The output (edge, edge) candidate pairs.
    EdgeEdgePairs,
    /// The rest positions (m), one per vertex like the positions: the edge–edge mollifier's
    /// thresholds.
    RestPositions,
    /// The gradient the contact potential is added into (N), one per vertex.
    Gradient,
    /// The per-vertex 3x3 diagonal blocks of the contact Hessian (N/m), one per vertex.
    HessianDiagonal,
    /// The per-pair projected contact Hessians, one per candidate pair.
    PairHessians,
    /// The frictional pairs a contact model lags at the start of a step.
    FrictionPairs,
    /// The output of a contact Hessian product (one per vertex, like the direction it
    /// multiplies).
    Product,
}

impl fmt::Display for ContactBuffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ContactBuffer::Positions => "positions",
            ContactBuffer::EndPositions => "end positions",
            ContactBuffer::Triangles => "triangles",
            ContactBuffer::Edges => "edges",
            ContactBuffer::Vertices => "vertices",
            ContactBuffer::Slots => "hash-table slots",
            ContactBuffer::Entries => "cell entries",
            ContactBuffer::VertexTrianglePairs => "vertex-triangle pairs",
            ContactBuffer::EdgeEdgePairs => "edge-edge pairs",
            ContactBuffer::RestPositions => "rest positions",
            ContactBuffer::Gradient => "gradient",
            ContactBuffer::HessianDiagonal => "Hessian diagonal blocks",
            ContactBuffer::PairHessians => "pair Hessians",
            ContactBuffer::FrictionPairs => "friction pairs",
            ContactBuffer::Product => "product",
        })
    }
}

/// A body–body contact query ([`step::contact`](crate::step::contact): the boundary primitives,
/// the broad phase) was refused. Every input error is found before anything is written; a
/// [`Capacity`](Self::Capacity) error of an output buffer is found at the end, after the query
/// has counted every pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ContactError {
    /// A buffer does not have the length the query needs.
    BufferLength {
        /// The buffer at fault.
        buffer: ContactBuffer,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        actual: usize,
    },
    /// A buffer is too short for what the query has to write into it.
    Capacity {
        /// The buffer at fault.
        buffer: ContactBuffer,
        /// The entries it needs (the exact count of pairs for an output pair buffer).
        needed: usize,
        /// The entries it has.
        capacity: usize,
    },
    /// An index buffer names a vertex at or beyond the vertex count, or a pair buffer a
    /// primitive beyond its list.
    IndexOutOfRange {
        /// The index buffer ([`Triangles`](ContactBuffer::Triangles),
        /// [`Edges`](ContactBuffer::Edges), [`Vertices`](ContactBuffer::Vertices) or
        /// [`PairHessians`](ContactBuffer::PairHessians)), or the pair buffer
        /// ([`VertexTrianglePairs`](ContactBuffer::VertexTrianglePairs),
        /// [`EdgeEdgePairs`](ContactBuffer::EdgeEdgePairs)).
        buffer: ContactBuffer,
        /// The entry of that buffer.
        element: usize,
        /// The vertex index found there (for a pair buffer: the position in the surface's
        /// vertex, triangle or edge list).
        index: u32,
    },
    /// A boundary triangle names the same vertex twice.
    DegenerateTriangle {
        /// The triangle.
        triangle: usize,
    },
    /// More primitives than the `u32` pair indices can name (`u32::MAX` in one list, or in the
    /// three lists together for the broad phase's table).
    TooManyPrimitives {
        /// The list at fault (for the three together: [`Entries`](ContactBuffer::Entries)).
        buffer: ContactBuffer,
    },
    /// A position is NaN or infinite.
    NonFinitePosition {
        /// [`Positions`](ContactBuffer::Positions) or [`EndPositions`](ContactBuffer::EndPositions).
        buffer: ContactBuffer,
        /// The first such vertex.
        vertex: usize,
    },
    /// The contact gap `dhat` (m) is NaN, infinite or negative.
    Gap,
    /// The barrier stiffness `kappa` (J/m^4) is NaN, infinite or negative.
    Stiffness,
    /// The friction coefficient is NaN, infinite or negative, or the sticking speed is not
    /// finite and positive.
    Friction,
    /// A contact model's buffers were in use by another of its calls (one of its methods
    /// called from within another; the solvers never do).
    BuffersInUse,
}

impl fmt::Display for ContactError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ContactError::BufferLength {
                buffer,
                expected,
                actual,
            } => write!(
                f,
                "the {buffer} buffer has length {actual}, expected {expected}"
            ),
            ContactError::Capacity {
                buffer,
                needed,
                capacity,
            } => write!(
                f,
                "the {buffer} buffer holds {capacity} entries, {needed} are needed"
            ),
            ContactError::IndexOutOfRange {
                buffer,
                element,
                index,
            } => write!(
                f,
                "entry {element} of the {buffer} names vertex {index}, beyond the vertex count"
            ),
            ContactError::DegenerateTriangle { triangle } => {
                write!(f, "triangle {triangle} names the same vertex twice")
            }
            ContactError::TooManyPrimitives { buffer } => {
                write!(f, "too many primitives in the {buffer} for u32 indices")
            }
            ContactError::NonFinitePosition { buffer, vertex } => {
                write!(f, "vertex {vertex} of the {buffer} is not finite")
            }
            ContactError::Gap => f.write_str("the contact gap must be finite and >= 0"),
            ContactError::Stiffness => f.write_str("the barrier stiffness must be finite and >= 0"),
            ContactError::BuffersInUse => {
                f.write_str("the contact model's buffers are in use by another of its calls")
            }
            ContactError::Friction => f.write_str(
                "the friction coefficient must be finite and >= 0, the sticking speed finite and > 0",
            ),
        }
    }
}

impl core::error::Error for ContactError {}

/// [`svd3_batch`](crate::svd::svd3_batch) (either precision) was given an output slice whose
/// length differs from the input's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SvdBatchError {
    /// The output buffer `out` does not have one decomposition per input matrix.
    OutputLength {
        /// The length required: the number of input matrices.
        expected: usize,
        /// The length of `out`.
        actual: usize,
    },
}

impl fmt::Display for SvdBatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SvdBatchError::OutputLength { expected, actual } => write!(
                f,
                "the SVD output buffer holds {actual} decompositions, but there are {expected} \
                 matrices"
            ),
        }
    }
}

impl core::error::Error for SvdBatchError {}

// The asset pipeline's errors (voxel meshing, embedding, surface buffers, TetGen, Gmsh and OBJ
// files) live with the pipeline, in `src/asset/error.rs`; like every type here they carry no
// floats, so they are compiled once, here, and serve both precisions.
#[path = "asset/error.rs"]
pub(crate) mod asset;
pub use asset::*;

/// A buffer of an owning [`Body`](crate::body::Body), named in [`BodyError::Capacity`] and
/// [`BodyError::Length`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum BodyBuffer {
    /// A per-vertex buffer (rest and current positions, velocities, masses, pins, targets).
    Vertices,
    /// A per-tetrahedron buffer (indices, rest data, Newton's Hessian cache).
    Tetrahedra,
    /// The solvers' vector scratch, nine vectors per vertex.
    Scratch,
    /// Vertex Block Descent's index scratch (adjacency, colours, order).
    IndexScratch,
    /// A world's list of bodies.
    Bodies,
    /// A world's contact surface: boundary triangles, their extraction's scratch, the surface's
    /// vertices and edges, the broad phase's hash slots and cell entries.
    Surface,
}

impl fmt::Display for BodyBuffer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BodyBuffer::Vertices => "per-vertex",
            BodyBuffer::Tetrahedra => "per-tetrahedron",
            BodyBuffer::Scratch => "solver scratch",
            BodyBuffer::IndexScratch => "index scratch",
            BodyBuffer::Bodies => "body list",
            BodyBuffer::Surface => "contact surface",
        })
    }
}

/// An owning [`Body`](crate::body::Body) could not be built or changed; the body (if any) is
/// unchanged. Errors of a step are [`StepError`]s.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum BodyError {
    /// The storage cannot hold the body: a fixed capacity too small, or an allocation refused.
    Capacity {
        /// The buffer that does not fit.
        buffer: BodyBuffer,
        /// The entries it needs.
        needed: usize,
    },
    /// A slice given to replace the body's state does not have one entry per vertex.
    Length {
        /// The buffer replaced.
        buffer: BodyBuffer,
        /// The length it must have (the vertex count).
        expected: usize,
        /// The length given.
        actual: usize,
    },
    /// A vertex index at or beyond the vertex count, or a NaN or infinite position, velocity
    /// or target given for it.
    Vertex {
        /// The vertex index.
        vertex: usize,
    },
    /// The box generator refused the box.
    Generate(GenerateError),
    /// The mesh or its masses were refused (indices, volumes, density).
    Mesh(MeshError),
    /// The masses or the stable time step were refused.
    Step(StepError),
    /// A vertex is in no tetrahedron: it would have no mass, and every step would refuse it
    /// ([`StepError::Mass`]). Drop unused vertices (and renumber) before building the body.
    UnusedVertex {
        /// The vertex index.
        vertex: usize,
    },
    /// The explicit solver's `stable_fraction` is NaN, infinite, or outside `(0, 1]` (a fraction
    /// of the stable time step: above 1 the steps are not proven stable).
    StableFraction,
    /// A [`World`](crate::world::World) has no body of this index.
    NoSuchBody {
        /// The index asked for.
        body: usize,
        /// The number of bodies.
        count: usize,
    },
    /// A [`World`](crate::world::World)'s contact settings or surface were refused.
    Contact(ContactError),
    /// A [`World`](crate::world::World) steps with Newton's method, the relaxation or the
    /// explicit stepper: Vertex Block Descent does not take body–body contact yet, and the
    /// automatic solver ([`Solver::Auto`](crate::body::Solver::Auto)) is a body's only.
    Solver,
}

impl From<GenerateError> for BodyError {
    fn from(error: GenerateError) -> BodyError {
        BodyError::Generate(error)
    }
}

impl From<MeshError> for BodyError {
    fn from(error: MeshError) -> BodyError {
        BodyError::Mesh(error)
    }
}

impl From<StepError> for BodyError {
    fn from(error: StepError) -> BodyError {
        BodyError::Step(error)
    }
}

impl fmt::Display for BodyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            BodyError::Capacity { buffer, needed } => write!(
                f,
                "the body's {buffer} storage cannot hold {needed} entries"
            ),
            BodyError::Length {
                buffer,
                expected,
                actual,
            } => write!(
                f,
                "a {buffer} slice of length {actual} was given, expected {expected}"
            ),
            BodyError::Vertex { vertex } => write!(
                f,
                "vertex {vertex} is beyond the vertex count, or its value is not finite"
            ),
            BodyError::Generate(error) => write!(f, "{error}"),
            BodyError::Mesh(error) => write!(f, "{error}"),
            BodyError::Step(error) => write!(f, "{error}"),
            BodyError::UnusedVertex { vertex } => write!(
                f,
                "vertex {vertex} is in no tetrahedron (it would have no mass)"
            ),
            BodyError::StableFraction => f.write_str(
                "the explicit solver's stable_fraction must be a finite fraction in (0, 1] of the \
                 stable time step",
            ),
            BodyError::NoSuchBody { body, count } => {
                write!(f, "there is no body {body}: the world has {count}")
            }
            BodyError::Contact(error) => write!(f, "{error}"),
            BodyError::Solver => f.write_str(
                "a world steps with Newton's method, the relaxation or the explicit stepper (VBD \
                 does not take body-body contact yet; the automatic solver is a body's only)",
            ),
        }
    }
}

impl core::error::Error for BodyError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            BodyError::Generate(error) => Some(error),
            BodyError::Mesh(error) => Some(error),
            BodyError::Step(error) => Some(error),
            BodyError::Contact(error) => Some(error),
            _ => None,
        }
    }
}

//! From a game asset to a soft body and back: tetrahedra from a triangle surface, a detailed
//! render mesh driven by the simulated one, render buffers of a body's surface, and (feature
//! `std`) readers and writers of the usual mesh files.
//!
//! * [`voxel`]: voxel tetrahedral meshing of a closed triangle surface (generalised winding
//!   number), into caller buffers.
//! * [`embed`]: a render mesh bound to the simulation mesh's tetrahedra and deformed every frame.
//! * [`surface`]: outward boundary triangles, vertex normals and interleaved render vertices.
//! * `tetgen`, `gmsh`, `obj` (feature `std`): TetGen `.node` / `.ele` and Gmsh 4.1 ASCII
//!   readers, and an OBJ reader and per-frame writer.
//!
//! Their errors carry no floats and are shared by both precisions: they are re-exported here,
//! in [`error`](crate::error) and at the crate root.

pub use crate::error::asset::*;

pub mod embed;
pub mod surface;
pub mod voxel;

#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod gmsh;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod obj;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod tetgen;

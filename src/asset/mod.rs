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

/// The memory budget of the `std` helpers that size their own buffers from their input,
/// [`voxel::voxel_mesh`] and [`embed::embed_points_vec`]: 2 GiB (bytes), the same limit as the
/// `bouncy` example's refusal of a scene. Each helper adds up the bytes of the buffers it would
/// hold at once, from the grid and mesh sizes, and refuses (`VoxelError::OverBudget`,
/// `EmbedError::OverBudget`, naming the bytes and the budget) before allocating anything when
/// they exceed it; what it does allocate, it allocates fallibly (`Vec::try_reserve_exact`),
/// so a refused allocation is an error naming its size, never an abort. The `_with_budget`
/// variants take another budget; the buffer-level functions allocate nothing and take any size.
pub const MEMORY_BUDGET: usize = 1 << 31;

/// The bytes of `len` values of `T` (saturating: a size that overflows is over any budget).
#[cfg(feature = "std")]
fn bytes_of<T>(len: usize) -> usize {
    core::mem::size_of::<T>().saturating_mul(len)
}

/// A vector of `len` copies of `value`, allocated fallibly: `Err(bytes)` with the bytes asked
/// for if the allocator refuses.
#[cfg(feature = "std")]
fn filled<T: Clone>(len: usize, value: T) -> Result<std::vec::Vec<T>, usize> {
    let mut buffer = std::vec::Vec::new();
    buffer
        .try_reserve_exact(len)
        .map_err(|_| bytes_of::<T>(len))?;
    buffer.resize(len, value);
    Ok(buffer)
}

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

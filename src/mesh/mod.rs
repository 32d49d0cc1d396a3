//! Validated meshes and the mesh-level kernels: elastic forces, energies, stresses and lumped
//! masses over buffers the caller owns.
//!
//! A mesh borrows the caller's element index buffer and a caller-provided buffer for the
//! precomputed rest data ([`TetRest`](super::element::TetRest) or
//! [`TriRest`](super::element::TriRest)), which its constructor fills. Construction validates
//! everything that can be checked once — buffer lengths, vertex indices, finite rest positions,
//! positive non-degenerate rest volumes — and reports the first offending element or vertex as a
//! [`MeshError`]. Nothing is allocated.
//!
//! The kernels then check only what changes between calls: the lengths of the buffers they are
//! given and the finiteness of the deformed positions (one pass, before anything is written).
//! **On error, output buffers are unchanged.** Kernels named `add_*` add into their output, so
//! that gravity or contact forces can be accumulated in the same buffer; the others overwrite.
//!
//! * [`TetMesh`]: tetrahedra with any [`Material`](super::material::Material); optionally with
//!   its rest data also in [`TetRestBlock`]s ([`TetMesh::with_rest_blocks`]), which the wide
//!   SIMD lanes load without transposing (the same bits, faster force passes).
//! * [`TriMesh`]: 2D triangles (positions `Vec2`), [`MembraneMesh`]: triangles in space
//!   (positions `Vec3`), both with [`TriangleStVK`](super::element::TriangleStVK).

use super::element::Vector;
use crate::error::{Buffer, ElementError, MeshError};

pub(crate) mod adjacency;
pub use adjacency::{
    adjacency_incident_len, adjacency_offsets_len, build_vertex_adjacency, colour_vertices,
    vertex_order,
};
mod grouped;
mod hessian;
pub mod partition;
mod rest_blocks;
mod tet;
mod triangle;

pub(crate) use grouped::Positions;
pub use partition::{
    ElementForces, TetPartition, element_forces_len, partition_incident_len, partition_offsets_len,
};
pub use rest_blocks::{TetRestBlock, rest_block_count};
pub use tet::TetMesh;
pub(crate) use tet::check_clamp_threshold;
pub use triangle::{MembraneMesh, TriMesh};

/// `Ok` if `actual == expected`, else [`MeshError::LengthMismatch`] naming `buffer`.
#[inline]
fn check_length(buffer: Buffer, expected: usize, actual: usize) -> Result<(), MeshError> {
    if actual == expected {
        Ok(())
    } else {
        Err(MeshError::LengthMismatch {
            buffer,
            expected,
            actual,
        })
    }
}

/// `Ok` if every position is finite, else `error` of the first vertex that is not.
#[inline]
fn check_finite<V: Vector>(
    positions: &[V],
    error: fn(usize) -> MeshError,
) -> Result<(), MeshError> {
    // `p * 0` is zero for a finite coordinate and NaN for NaN or infinity, so a sum of them is
    // finite exactly when every position is, in any order: one branch-free pass in the common
    // case, and a search for the culprit only on failure. `LANES` sums side by side, not one:
    // a single running sum is a chain of dependent additions, one per position, which took
    // about 2 % of the StVK force pass at 105k tetrahedra (perf).
    const LANES: usize = 8;
    let mut sums = [V::default(); LANES];
    let mut chunks = positions.chunks_exact(LANES);
    for chunk in &mut chunks {
        for (sum, &p) in sums.iter_mut().zip(chunk) {
            *sum += p * 0.0;
        }
    }
    let tail = chunks
        .remainder()
        .iter()
        .fold(V::default(), |acc, &p| acc + p * 0.0);
    let sum = sums.iter().fold(tail, |acc, &s| acc + s);
    if sum.is_finite() {
        return Ok(());
    }
    positions
        .iter()
        .position(|p| !p.is_finite())
        .map_or(Ok(()), |vertex| Err(error(vertex)))
}

/// The construction shared by every mesh type: checks the rest buffer's length, finite rest
/// positions and indices in range, then fills `rest` with `rest_data` of each element's corner
/// positions, naming the first element that fails. Returns the vertex count.
fn validate<V: Vector, R, const N: usize>(
    rest_positions: &[V],
    elements: &[[u32; N]],
    rest: &mut [R],
    rest_data: impl Fn([V; N]) -> Result<R, ElementError>,
) -> Result<usize, MeshError> {
    check_length(Buffer::RestData, elements.len(), rest.len())?;
    check_finite(rest_positions, |vertex| MeshError::NonFiniteRestPosition {
        vertex,
    })?;
    let vertex_count = rest_positions.len();
    check_indices(elements, vertex_count)?;
    for (element, (corners, slot)) in elements.iter().zip(rest.iter_mut()).enumerate() {
        *slot = rest_data(gather(rest_positions, corners))
            .map_err(|error| MeshError::in_element(error, element, corners))?;
    }
    Ok(vertex_count)
}

/// `Ok` if `positions` has one finite entry per vertex, else the length or the first
/// non-finite vertex.
fn check_positions<V: Vector>(vertex_count: usize, positions: &[V]) -> Result<(), MeshError> {
    check_length(Buffer::Positions, vertex_count, positions.len())?;
    check_finite(positions, |vertex| MeshError::NonFinitePosition { vertex })
}

/// `Ok` if every corner of every element is below `vertex_count`, else the first offender.
fn check_indices<const N: usize>(
    elements: &[[u32; N]],
    vertex_count: usize,
) -> Result<(), MeshError> {
    for (element, corners) in elements.iter().enumerate() {
        for (corner, &index) in (0u8..).zip(corners) {
            if index as usize >= vertex_count {
                return Err(MeshError::IndexOutOfRange {
                    element,
                    corner,
                    index,
                    vertex_count,
                });
            }
        }
    }
    Ok(())
}

/// The positions of an element's corners. Indices were validated at construction and the
/// buffer length checked by the caller, so the fallback never happens; it only keeps the
/// loop free of panics.
#[inline(always)]
fn gather<V: Copy + Default, const N: usize>(positions: &[V], corners: &[u32; N]) -> [V; N] {
    corners.map(|i| positions.get(i as usize).copied().unwrap_or_default())
}

/// Adds an element's nodal `values` into `buffer` at its corners.
#[inline(always)]
fn scatter_add<V: Vector, const N: usize>(buffer: &mut [V], corners: &[u32; N], values: [V; N]) {
    for (&i, value) in corners.iter().zip(values) {
        if let Some(slot) = buffer.get_mut(i as usize) {
            *slot += value;
        }
    }
}

/// Asks the processor to start loading `items[first..first + count]` into its caches (x86_64;
/// nothing elsewhere). A hint only: it changes nothing the program can observe and cannot fault,
/// past the end of `items` included (the addresses are computed with wrapping arithmetic, never
/// dereferenced).
#[inline(always)]
fn prefetch<T>(items: &[T], first: usize, count: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let start = items.as_ptr().wrapping_add(first).cast::<i8>();
        let bytes = count * core::mem::size_of::<T>();
        for offset in (0..bytes).step_by(64) {
            // SAFETY: `prefetch` has no preconditions: it never faults and changes no state
            // that the program can observe (SSE, always present on x86_64).
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (items, first, count);
}

/// Lumped masses: `density * measure / N` to each of the `N` corners of every element, into
/// `masses` zeroed first. `density` must be finite and positive.
fn lumped_masses<const N: usize>(
    elements: &[[u32; N]],
    measures: impl Iterator<Item = super::types::Real> + Clone,
    density: super::types::Real,
    masses: &mut [super::types::Real],
    vertex_count: usize,
) -> Result<(), MeshError> {
    if !(density > 0.0 && density.is_finite()) {
        return Err(MeshError::Density);
    }
    check_length(Buffer::Masses, vertex_count, masses.len())?;
    let share = density / N as super::types::Real;
    // Every element's share must be a normal number (a subnormal or zero mass makes `1 / m`
    // overflow in the steppers) and small enough that no vertex sum, over at most as many
    // elements as the mesh has, can overflow. Checked before anything is written.
    let largest = super::types::Real::MAX / elements.len().max(1) as super::types::Real;
    let in_range = |m: super::types::Real| m >= super::types::Real::MIN_POSITIVE && m <= largest;
    if let Some(element) = measures
        .clone()
        .position(|measure| !in_range(share * measure))
    {
        return Err(MeshError::MassRange { element });
    }
    masses.fill(0.0);
    for (corners, measure) in elements.iter().zip(measures) {
        for &i in corners {
            if let Some(mass) = masses.get_mut(i as usize) {
                *mass += share * measure;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::types::{Real, Vec3};
    use super::{MeshError, check_finite};

    /// Every length around the sums' chunk of 8, with a NaN or an infinity planted at each
    /// vertex in turn (and both at two vertices): the error names the first planted vertex,
    /// and finite positions pass.
    #[test]
    fn check_finite_names_the_first_non_finite_position_at_every_length_and_place() {
        let error = |vertex| MeshError::NonFinitePosition { vertex };
        let all: [Vec3; 26] = core::array::from_fn(|i| Vec3::new(i as Real, -(i as Real), 1e30));
        for length in 0..=all.len() {
            let positions = &all[..length];
            assert_eq!(check_finite(positions, error), Ok(()));
            for bad in [Real::NAN, Real::INFINITY, Real::NEG_INFINITY] {
                for first in 0..length {
                    for axis in 0..3 {
                        let mut copy = all;
                        let planted = &mut copy[..length];
                        planted[first][axis] = bad;
                        if let Some(later) = planted.get_mut(first + 5) {
                            later.x = Real::NAN;
                        }
                        assert_eq!(
                            check_finite(planted, error),
                            Err(MeshError::NonFinitePosition { vertex: first }),
                            "length {length}, vertex {first}, axis {axis}, value {bad}"
                        );
                    }
                }
            }
        }
    }
}

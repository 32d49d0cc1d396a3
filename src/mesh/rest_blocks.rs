//! The rest data of a tetrahedral mesh in blocks of [`TetRestBlock::LANES`] elements, field by
//! field (structure of arrays): what the wide SIMD lanes load with one instruction per field,
//! where the per-element [`TetRest`] records need a transpose per group.
//!
//! A mesh takes blocks with [`TetMesh::with_rest_blocks`](super::TetMesh::with_rest_blocks),
//! which fills the caller's buffer from its own rest data, so the two copies cannot disagree.
//! Every kernel gives the same bits with or without them; they only change the speed of the
//! passes that form deformation gradients a group at a time (forces, energies, the fused
//! energy and force pass, the principal and clamped forces).

use super::super::element::TetRest;
use super::super::lanes::LaneArray;
use super::super::types::Real;
use super::prefetch;
use crate::error::{Buffer, MeshError};

/// The rest data of [`LANES`](Self::LANES) consecutive tetrahedra, field by field: entry
/// `(row, column)` of `Dm^-1` (m^-1) and the rest volume (m^3) of element `lane` of the block.
///
/// 640 bytes in f32 (1280 in f64): the 40 (80) bytes per element of [`TetRest`] again, as
/// [`rest_block_count`] blocks per mesh. Aligned to 64 bytes, so that a group's load of a field
/// never straddles two cache lines. `Default` (zero) exists only to size buffers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(64))]
pub struct TetRestBlock {
    /// `Dm^-1` entry by entry, column-major (`dm_inv[3 c + r][lane]` is row `r` of column `c`).
    dm_inv: [[Real; TetRestBlock::LANES]; 9],
    /// The rest volumes.
    volume: [Real; TetRestBlock::LANES],
}

impl TetRestBlock {
    /// Elements per block: the widest lanes of either precision divide it (16 f32 with
    /// AVX-512, 8 f64).
    pub const LANES: usize = 16;

    /// Zero, as `Default`: only a buffer's initial value.
    pub const ZERO: TetRestBlock = TetRestBlock {
        dm_inv: [[0.0; TetRestBlock::LANES]; 9],
        volume: [0.0; TetRestBlock::LANES],
    };

    /// Sets element `lane` of the block to `rest` (nothing past the last lane).
    fn set(&mut self, lane: usize, rest: &TetRest) {
        let m = rest.dm_inv.to_cols_array();
        for (row, value) in self.dm_inv.iter_mut().zip(m) {
            if let Some(slot) = row.get_mut(lane) {
                *slot = value;
            }
        }
        if let Some(slot) = self.volume.get_mut(lane) {
            *slot = rest.volume;
        }
    }

    /// Elements `lane..lane + L::WIDTH` as lanes: the nine entries of `Dm^-1` (column-major)
    /// and the volume, one load each; `None` if they run past the block.
    #[inline(always)]
    pub(crate) fn lanes<L: LaneArray>(&self, lane: usize) -> Option<[L; 10]> {
        let row = |values: &[Real; TetRestBlock::LANES]| L::from_slice(values.get(lane..)?);
        let [m00, m10, m20, m01, m11, m21, m02, m12, m22] = &self.dm_inv;
        Some([
            row(m00)?,
            row(m10)?,
            row(m20)?,
            row(m01)?,
            row(m11)?,
            row(m21)?,
            row(m02)?,
            row(m12)?,
            row(m22)?,
            row(&self.volume)?,
        ])
    }
}

/// The number of [`TetRestBlock`]s a mesh of `elements` tetrahedra takes: `ceil(elements /
/// 16)`.
#[must_use]
pub const fn rest_block_count(elements: usize) -> usize {
    elements.div_ceil(TetRestBlock::LANES)
}

/// Fills `blocks` with `rest`, element `i` as lane `i % 16` of block `i / 16` (lanes past the
/// last element zero).
///
/// # Errors
/// [`MeshError::LengthMismatch`] naming [`Buffer::RestBlocks`] unless `blocks` has
/// [`rest_block_count`] entries; `blocks` is then unchanged.
pub(super) fn fill_rest_blocks(
    rest: &[TetRest],
    blocks: &mut [TetRestBlock],
) -> Result<(), MeshError> {
    super::check_length(
        Buffer::RestBlocks,
        rest_block_count(rest.len()),
        blocks.len(),
    )?;
    for (block, rests) in blocks.iter_mut().zip(rest.chunks(TetRestBlock::LANES)) {
        *block = TetRestBlock::ZERO;
        for (lane, rest) in rests.iter().enumerate() {
            block.set(lane, rest);
        }
    }
    Ok(())
}

/// The rest data of the consecutive elements `start..start + elements.len()` of a mesh: their
/// records and the mesh's blocks (empty where it has none).
#[derive(Clone, Copy)]
pub(super) struct Rests<'a> {
    pub elements: &'a [TetRest],
    blocks: &'a [TetRestBlock],
    start: usize,
}

/// How many blocks ahead of the current one a pass asks the processor to load: on a mesh that
/// does not fit the caches (1M tetrahedra), the loads of a block's fields otherwise wait on
/// memory at the start of every group (the blocks ran 0.8x the records there without it).
const PREFETCH_BLOCKS: usize = 4;

/// The blocks of a run of elements whose first element starts a group of the run's width
/// within a block (so that every group of that width lies within one block).
#[derive(Clone, Copy)]
pub(super) struct BlockRun<'a> {
    blocks: &'a [TetRestBlock],
    /// The mesh index of the run's first element.
    start: usize,
}

impl BlockRun<'_> {
    /// The rest data of the `group`-th group of `L::WIDTH` elements of the run, as lanes
    /// ([`TetRestBlock::lanes`]); `None` past the blocks.
    #[inline(always)]
    pub fn lanes<L: LaneArray>(self, group: usize) -> Option<[L; 10]> {
        let index = self.start + group * L::WIDTH;
        let (block_index, lane) = (index / TetRestBlock::LANES, index % TetRestBlock::LANES);
        if lane == 0 {
            prefetch(self.blocks, block_index + PREFETCH_BLOCKS, 1);
        }
        self.blocks.get(block_index)?.lanes::<L>(lane)
    }
}

impl<'a> Rests<'a> {
    /// Elements `start..` of a mesh with records `elements` (from `start`) and `blocks` (all
    /// of the mesh's, or none).
    #[inline(always)]
    pub fn new(elements: &'a [TetRest], blocks: &'a [TetRestBlock], start: usize) -> Self {
        Rests {
            elements,
            blocks,
            start,
        }
    }

    /// No elements.
    #[inline(always)]
    pub fn empty(self) -> Self {
        Rests::new(&[], self.blocks, self.start)
    }

    /// The first `mid` elements and the rest; `None` if there are fewer.
    #[inline(always)]
    pub fn split_at(self, mid: usize) -> Option<(Self, Self)> {
        let (head, tail) = self.elements.split_at_checked(mid)?;
        Some((
            Rests::new(head, self.blocks, self.start),
            Rests::new(tail, self.blocks, self.start + mid),
        ))
    }

    /// The blocks for groups of `width` elements from the first, if the mesh has blocks and
    /// every such group lies within one (`width` divides 16 and the run starts at a multiple of
    /// it).
    #[inline(always)]
    #[cfg_attr(debug_assertions, allow(dead_code))]
    pub fn block_run(self, width: usize) -> Option<BlockRun<'a>> {
        let aligned = width > 0
            && TetRestBlock::LANES.is_multiple_of(width)
            && self.start.is_multiple_of(width);
        (aligned && !self.blocks.is_empty()).then_some(BlockRun {
            blocks: self.blocks,
            start: self.start,
        })
    }
}

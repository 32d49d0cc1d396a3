//! The Hessian passes of a [`TetPartition`]: the element pieces of
//! [`TetMesh::projected_hessians`] (each writes its slice of the cache) and of
//! [`TetMesh::add_hessian_product`] (each writes its elements' products into the element buffer,
//! which [`gather_forces`](TetPartition::gather_forces) then adds up per vertex; or, in the
//! owner-computes form, each vertex piece adds those of the elements at its vertices), and the
//! vertex pieces of [`TetMesh::add_vertex_hessian_blocks`] (each sums its vertices' blocks
//! straight from the cache, in increasing (element, corner) order: no element phase).

use core::ops::Range;

use super::super::super::element::{TetHessian, TetRest};
use super::super::super::material::Material;
use super::super::super::math::BATCH_SVD;
use super::super::super::types::{Mat3, Vec3};
#[cfg(doc)]
use super::super::TetMesh;
use super::super::hessian::Product;
use super::super::{check_finite, check_length, check_positions, gather};
use super::owner::one_piece;
use super::principal::piece_svd_loop;
use super::{ElementForces, TetPartition, grouped_len};
use crate::error::{Buffer, MeshError};
use crate::simd::dispatch;

impl<'a> TetPartition<'a> {
    /// The check of a partitioned [`TetMesh::projected_hessians`], its tests in its order.
    ///
    /// # Errors
    /// As [`TetMesh::projected_hessians`]: [`MeshError::LengthMismatch`] naming
    /// [`Buffer::Positions`] or [`Buffer::Hessians`], [`MeshError::NonFinitePosition`].
    pub fn check_hessians(
        &self,
        positions: &[Vec3],
        cache: &[TetHessian],
    ) -> Result<(), MeshError> {
        check_positions(self.mesh.vertex_count(), positions)?;
        check_length(Buffer::Hessians, self.mesh.element_count(), cache.len())
    }

    /// Element piece `piece` of [`TetMesh::projected_hessians`]: writes the projected Hessian
    /// data of `material` at `positions` (m) of each of its elements into `out` (its slice of
    /// the cache), with the sequential bits. Assumes [`check_hessians`](Self::check_hessians)
    /// passed.
    ///
    /// # Errors
    /// [`MeshError::PieceIndex`] past the last piece; [`MeshError::LengthMismatch`] naming
    /// [`Buffer::Hessians`] if `out` is not as long as the piece, or [`Buffer::Positions`].
    /// Nothing is written on error.
    pub fn element_hessians<M: Material>(
        &self,
        material: &M,
        positions: &[Vec3],
        piece: usize,
        out: &mut [TetHessian],
    ) -> Result<(), MeshError> {
        let (tets, rests, range) = self.piece_elements(piece, Buffer::Hessians, out.len())?;
        check_length(Buffer::Positions, self.mesh.vertex_count(), positions.len())?;
        let grouped = grouped_len(BATCH_SVD, self.mesh.element_count(), range);
        piece_svd_loop(
            positions,
            (tets, rests, grouped),
            out,
            |rest, svd, slot| {
                let derivative = material.projected_stress_derivative_from_svd(svd);
                *slot = TetHessian::from_stress_derivative(&derivative, rest);
            },
            |corners, rest, slot| {
                *slot = TetHessian::new(material, rest, gather(positions, corners));
            },
        );
        Ok(())
    }

    /// The check of a partitioned [`TetMesh::add_hessian_product`]: its tests in its order,
    /// then the element buffer's length.
    ///
    /// # Errors
    /// As [`TetMesh::add_hessian_product`]: [`MeshError::LengthMismatch`] naming
    /// [`Buffer::Hessians`], [`Buffer::Direction`] or [`Buffer::Products`],
    /// [`MeshError::NonFiniteDirection`]; then [`MeshError::LengthMismatch`] naming
    /// [`Buffer::ElementForces`] if `element_products` does not have
    /// [`element_forces_len`](super::element_forces_len) entries.
    pub fn check_hessian_product(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        out: &[Vec3],
        element_products: &[ElementForces],
    ) -> Result<(), MeshError> {
        let (elements, vertices) = (self.mesh.element_count(), self.mesh.vertex_count());
        check_length(Buffer::Hessians, elements, cache.len())?;
        check_length(Buffer::Direction, vertices, direction.len())?;
        check_length(Buffer::Products, vertices, out.len())?;
        check_finite(direction, |vertex| MeshError::NonFiniteDirection { vertex })?;
        self.check_element_buffer(element_products.len())
    }

    /// Element piece `piece` of [`TetMesh::add_hessian_product`]: writes `H_e d_e` (N), the
    /// product of each of its elements' Hessian in `cache` (the whole cache) with the element's
    /// corners of `direction` (m), into `out` (its slice of the element buffer). Then
    /// [`gather_forces`](Self::gather_forces) adds the products into the caller's output with
    /// the sequential bits. Assumes [`check_hessian_product`](Self::check_hessian_product)
    /// passed.
    ///
    /// # Errors
    /// [`MeshError::PieceIndex`] past the last piece; [`MeshError::LengthMismatch`] naming
    /// [`Buffer::ElementForces`] if `out` is not as long as the piece, [`Buffer::Hessians`] or
    /// [`Buffer::Direction`]. Nothing is written on error.
    pub fn element_hessian_products(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        piece: usize,
        out: &mut [ElementForces],
    ) -> Result<(), MeshError> {
        let (tets, rests, range) = self.piece_elements(piece, Buffer::ElementForces, out.len())?;
        check_length(Buffer::Hessians, self.mesh.element_count(), cache.len())?;
        check_length(Buffer::Direction, self.mesh.vertex_count(), direction.len())?;
        let hessians = cache.get(range).unwrap_or(&[]);
        let elements = tets.iter().zip(rests).zip(hessians);
        for (((corners, rest), hessian), slot) in elements.zip(out) {
            *slot = hessian.product(rest, gather(direction, corners));
        }
        Ok(())
    }

    /// Owner piece `piece` of the owner-computes [`TetMesh::add_hessian_product`]: adds into
    /// `out` (vertex piece `piece`'s slice of the products, N) `H_e d_e` of every element
    /// incident to its vertices, for the Hessian in `cache` and the per-vertex `direction` (m),
    /// element by element at its own vertices: the sequential bits, no element buffer, no
    /// gather. Assumes [`check_hessian_product`](Self::check_hessian_product) passed.
    ///
    /// # Errors
    /// [`MeshError::PieceIndex`] past the last vertex piece; [`MeshError::LengthMismatch`]
    /// naming [`Buffer::Hessians`], [`Buffer::Direction`], or [`Buffer::Products`] if `out`
    /// is not as long as the piece. Nothing is written on error.
    pub fn add_hessian_product_owned(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        piece: usize,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        self.add_hessian_product_span(cache, direction, one_piece(piece), out)
    }

    /// [`add_hessian_product_owned`](Self::add_hessian_product_owned) for the consecutive
    /// vertex pieces `pieces` as one owner (`out` their slices, end to end).
    pub(crate) fn add_hessian_product_span(
        &self,
        cache: &[TetHessian],
        direction: &[Vec3],
        pieces: Range<usize>,
        out: &mut [Vec3],
    ) -> Result<(), MeshError> {
        check_length(Buffer::Hessians, self.mesh.element_count(), cache.len())?;
        check_length(Buffer::Direction, self.mesh.vertex_count(), direction.len())?;
        let vertices = self.span_vertices(pieces.clone())?;
        check_length(Buffer::Products, vertices.len(), out.len())?;
        let Some(elements) = self.span_elements(pieces) else {
            return Ok(()); // No element touches these vertices.
        };
        for (range, dense) in elements.parts() {
            // The sequential product's kernel on the part (its groups of the SIMD width's
            // lanes, the same bits), restricted to this owner's vertices.
            dispatch(Product {
                tets: self.mesh.tets().get(range.clone()).unwrap_or(&[]),
                cache: cache.get(range).unwrap_or(&[]),
                direction,
                out: &mut *out,
                first: vertices.start,
                dense,
            });
        }
        Ok(())
    }

    /// The check of a partitioned [`TetMesh::add_vertex_hessian_blocks`], its tests in its
    /// order.
    ///
    /// # Errors
    /// As [`TetMesh::add_vertex_hessian_blocks`]: [`MeshError::LengthMismatch`] naming
    /// [`Buffer::Hessians`] or [`Buffer::Blocks`].
    pub fn check_vertex_blocks(
        &self,
        cache: &[TetHessian],
        blocks: &[Mat3],
    ) -> Result<(), MeshError> {
        check_length(Buffer::Hessians, self.mesh.element_count(), cache.len())?;
        check_length(Buffer::Blocks, self.mesh.vertex_count(), blocks.len())
    }

    /// Vertex piece `piece` of [`TetMesh::add_vertex_hessian_blocks`]: adds into `out` (its
    /// slice of the caller's blocks, N/m) the diagonal blocks of the Hessian in `cache` at each
    /// of its vertices, in increasing (element, corner) order: the sequential additions. Needs
    /// no element phase.
    ///
    /// # Errors
    /// [`MeshError::PieceIndex`] past the last piece; [`MeshError::LengthMismatch`] naming
    /// [`Buffer::Blocks`] if `out` is not as long as the piece, or [`Buffer::Hessians`].
    /// Nothing is written on error.
    pub fn gather_vertex_blocks(
        &self,
        cache: &[TetHessian],
        piece: usize,
        out: &mut [Mat3],
    ) -> Result<(), MeshError> {
        self.gather_vertex_blocks_span(cache, one_piece(piece), out)
    }

    /// [`gather_vertex_blocks`](Self::gather_vertex_blocks) for the consecutive vertex pieces
    /// `pieces` (`out` their slices, end to end).
    pub(crate) fn gather_vertex_blocks_span(
        &self,
        cache: &[TetHessian],
        pieces: Range<usize>,
        out: &mut [Mat3],
    ) -> Result<(), MeshError> {
        check_length(Buffer::Hessians, self.mesh.element_count(), cache.len())?;
        let vertices = self.span_vertices(pieces)?;
        check_length(Buffer::Blocks, vertices.len(), out.len())?;
        let rests = self.mesh.rest();
        for (vertex, slot) in vertices.zip(out) {
            for (element, corner) in self.incident_corners(vertex) {
                if let (Some(hessian), Some(rest)) = (cache.get(element), rests.get(element)) {
                    *slot += hessian.vertex_block(rest, corner);
                }
            }
        }
        Ok(())
    }

    /// The vertex indices, rest data and range of element piece `piece`, after checking the
    /// piece index and that the output (`buffer`) has `out_len` entries, one per element.
    #[allow(clippy::type_complexity)]
    fn piece_elements(
        &self,
        piece: usize,
        buffer: Buffer,
        out_len: usize,
    ) -> Result<(&'a [[u32; 4]], &'a [TetRest], Range<usize>), MeshError> {
        let range =
            self.check_piece(piece, self.element_piece_count(), self.element_piece(piece))?;
        check_length(buffer, range.len(), out_len)?;
        let tets = self.mesh.tets().get(range.clone()).unwrap_or(&[]);
        let rests = self.mesh.rest().get(range.clone()).unwrap_or(&[]);
        Ok((tets, rests, range))
    }
}

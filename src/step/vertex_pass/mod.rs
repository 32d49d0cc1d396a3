//! How the steppers split their passes over the vertices (integration, contact projection,
//! preconditioning, trial points, residual norms, energies, slopes) into blocks of
//! [`VERTEX_BLOCK`] vertices, so that a model running on a thread pool can run the blocks on its
//! threads ([`ElasticModel::run_vertex_pass`](super::ElasticModel::run_vertex_pass)) and still
//! give the bits of the sequential pass.
//!
//! Every vertex's own arithmetic does not depend on the block it falls in. A sum over the
//! vertices is taken block by block, each block in vertex order (its own `LaneSum` order where
//! the pass runs four vertices at a time), and the block totals are added over one fixed binary
//! tree: the blocks of a range split into the first `blocks / 2` and the rest, recursively. The
//! tree depends only on the number of vertices, so running the two halves of any split on other
//! threads changes nothing; a body of at most [`VERTEX_BLOCK`] vertices sums in plain vertex
//! order, as a single block.

use core::marker::PhantomData;

use super::super::types::Real;

pub(crate) mod passes;
// Moved below `element` (`lanes/point.rs`, the hidden half of `element::Vector`); the steppers
// name it here.
pub(crate) use super::super::lanes::point;

/// The vertices per block of the steppers' passes over the vertices (integration, contact
/// projection, trial points, residuals). Every sum over the vertices is taken block by block, in
/// vertex order within a block (four lanes at a time where the pass is vectorised), and the block
/// totals are added over one fixed binary tree: the blocks of a range split into the first
/// `blocks / 2` and the rest, recursively. The tree depends only on the number of vertices, so
/// the sums have the same bits on any number of threads; a body of at most `VERTEX_BLOCK`
/// vertices sums in plain vertex order. A multiple of the SIMD lane count, so that a block's
/// groups of vertices are the groups of the whole pass.
pub const VERTEX_BLOCK: usize = 1024;

/// A way to run two closures, one after the other or at the same time: the thread pool's `join`
/// (`rayon::join`, or any job system's). The steppers' passes over the vertices split their
/// blocks with it ([`VertexPass::run_with`]).
pub trait Join {
    /// Runs `a` and `b` (in any order, on any threads) and returns both results.
    fn join<A, B, RA, RB>(&self, a: A, b: B) -> (RA, RB)
    where
        A: FnOnce() -> RA + Send,
        B: FnOnce() -> RB + Send,
        RA: Send,
        RB: Send;
}

/// The [`Join`] that runs `a`, then `b`, on the calling thread: the sequential passes.
#[derive(Clone, Copy, Debug, Default)]
pub struct InOrder;

impl Join for InOrder {
    #[inline(always)]
    fn join<A, B, RA, RB>(&self, a: A, b: B) -> (RA, RB)
    where
        A: FnOnce() -> RA + Send,
        B: FnOnce() -> RB + Send,
        RA: Send,
        RB: Send,
    {
        (a(), b())
    }
}

pub(crate) mod sealed {
    /// Only the steppers' own passes are [`VertexPass`](super::VertexPass)es.
    pub trait Sealed {}
}

/// One of the steppers' passes over the vertices, split into blocks of [`VERTEX_BLOCK`]
/// vertices (sealed: the steppers build them). A model hands it to [`run_with`](Self::run_with)
/// with the [`Join`] of its thread pool.
pub trait VertexPass: Send + Sized + sealed::Sealed {
    /// What the pass returns: its sums, counts and first non-finite vertex.
    type Output: Send;

    /// Runs the pass, the halves of every split of its blocks given to `join`: the same bits for
    /// any [`Join`].
    fn run_with<J: Join + Sync>(self, join: &J) -> Self::Output;
}

/// What a block of a pass returns, and how two neighbouring ranges' results combine: sums add
/// (over the fixed tree of the module docs), counts add, and the first non-finite vertex is the
/// left range's if it has one.
pub(crate) trait Total: Send {
    /// The result of the range `left` followed by the range `right`.
    fn combine(left: Self, right: Self) -> Self;
}

impl Total for () {
    #[inline(always)]
    fn combine((): Self, (): Self) -> Self {}
}

impl Total for Real {
    #[inline(always)]
    fn combine(left: Self, right: Self) -> Self {
        left + right
    }
}

impl Total for usize {
    #[inline(always)]
    fn combine(left: Self, right: Self) -> Self {
        left.saturating_add(right)
    }
}

impl Total for Option<usize> {
    #[inline(always)]
    fn combine(left: Self, right: Self) -> Self {
        left.or(right)
    }
}

macro_rules! total_tuple {
    ($($name:ident $index:tt),+) => {
        impl<$($name: Total),+> Total for ($($name,)+) {
            #[inline(always)]
            fn combine(left: Self, right: Self) -> Self {
                ($($name::combine(left.$index, right.$index),)+)
            }
        }
    };
}
total_tuple!(A 0, B 1);
total_tuple!(A 0, B 1, C 2);
total_tuple!(A 0, B 1, C 2, D 3);
total_tuple!(A 0, B 1, C 2, D 3, E 4);
total_tuple!(A 0, B 1, C 2, D 3, E 4, F 5);

/// Per-vertex buffers that split at a vertex: slices (an empty slice, standing for "none",
/// splits into two empty ones) and tuples of them.
pub(crate) trait Split: Sized + Send {
    /// The vertices before `at` and from `at` on.
    fn split(self, at: usize) -> (Self, Self);
}

impl<T: Send> Split for &mut [T] {
    #[inline(always)]
    fn split(self, at: usize) -> (Self, Self) {
        self.split_at_mut_checked(at).unwrap_or_default()
    }
}

impl<T: Sync> Split for &[T] {
    #[inline(always)]
    fn split(self, at: usize) -> (Self, Self) {
        self.split_at_checked(at).unwrap_or_default()
    }
}

macro_rules! split_tuple {
    ($($name:ident $index:tt),+) => {
        impl<$($name: Split),+> Split for ($($name,)+) {
            #[inline(always)]
            #[allow(non_snake_case)]
            fn split(self, at: usize) -> (Self, Self) {
                $(let $name = self.$index.split(at);)+
                (($($name.0,)+), ($($name.1,)+))
            }
        }
    };
}
split_tuple!(A 0, B 1);
split_tuple!(A 0, B 1, C 2);
split_tuple!(A 0, B 1, C 2, D 3);
split_tuple!(A 0, B 1, C 2, D 3, E 4);

/// A pass over `vertices` vertices: `block(first, parts)` runs on each block of
/// [`VERTEX_BLOCK`] vertices (`first` its first vertex, `parts` the buffers' entries of the
/// block), and the results combine by [`Total`] over the fixed tree.
pub(crate) struct Blocks<'f, S, R, F> {
    first: usize,
    vertices: usize,
    /// The entries per block: [`VERTEX_BLOCK`], or another fixed length ([`Blocks::of_len`]);
    /// non-zero by type, so that the divisions by it keep no panic path (the firmware's link
    /// check).
    len: core::num::NonZeroUsize,
    parts: S,
    block: &'f F,
    result: PhantomData<fn() -> R>,
}

impl<'f, S: Split, R: Total, F: Fn(usize, S) -> R + Sync> Blocks<'f, S, R, F> {
    /// The pass of `block` over the `vertices` vertices of `parts`.
    #[inline(always)]
    pub fn new(vertices: usize, parts: S, block: &'f F) -> Self {
        Self::of_len(VERTEX_BLOCK, vertices, parts, block)
    }

    /// The pass of `block` over the `entries` entries of `parts` in blocks of `len` entries
    /// (at least one): the same fixed tree over those blocks, for passes over other things
    /// than vertices (the rows of the multilevel preconditioner's matrices).
    #[inline(always)]
    pub fn of_len(len: usize, entries: usize, parts: S, block: &'f F) -> Self {
        Blocks {
            first: 0,
            vertices: entries,
            len: core::num::NonZeroUsize::new(len).unwrap_or(core::num::NonZeroUsize::MIN),
            parts,
            block,
            result: PhantomData,
        }
    }

    /// The pass split into whole blocks, the first half of them and the rest; `None` for a
    /// single block.
    #[inline(always)]
    fn halves(self) -> Result<(Self, Self), Self> {
        let blocks = self.vertices / self.len + usize::from(self.vertices % self.len != 0);
        if blocks < 2 {
            return Err(self);
        }
        let at = blocks / 2 * self.len.get();
        let (left, right) = self.parts.split(at);
        let half = |first, vertices, parts| Blocks {
            first,
            vertices,
            len: self.len,
            parts,
            block: self.block,
            result: PhantomData,
        };
        Ok((
            half(self.first, at, left),
            half(self.first + at, self.vertices - at, right),
        ))
    }
}

impl<S, R, F> sealed::Sealed for Blocks<'_, S, R, F> {}

impl<S: Split, R: Total, F: Fn(usize, S) -> R + Sync> VertexPass for Blocks<'_, S, R, F> {
    type Output = R;

    fn run_with<J: Join + Sync>(self, join: &J) -> R {
        match self.halves() {
            Err(block) => (block.block)(block.first, block.parts),
            Ok((left, right)) => {
                let (left, right) = join.join(|| left.run_with(join), || right.run_with(join));
                R::combine(left, right)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::{Blocks, InOrder, Join, VERTEX_BLOCK, VertexPass};
    use crate::lanes::LANES;

    /// A [`Join`] that runs `b` before `a`: any order gives the same bits.
    struct Reversed;

    impl Join for Reversed {
        fn join<A, B, RA, RB>(&self, a: A, b: B) -> (RA, RB)
        where
            A: FnOnce() -> RA + Send,
            B: FnOnce() -> RB + Send,
            RA: Send,
            RB: Send,
        {
            let b = b();
            (a(), b)
        }
    }

    /// Terms of very different magnitudes and both signs, whose rounded sum depends on the order.
    fn term(i: usize) -> super::Real {
        let k = i as super::Real;
        (1.0 + 0.37 * k)
            * if i.is_multiple_of(3) { 1.0e6 } else { 1.0e-3 }
            * if i.is_multiple_of(2) { 1.0 } else { -1.0 }
    }

    /// The tree of the module docs, written out: the blocks `[first, first + blocks)` of `n`.
    fn tree(n: usize, first: usize, blocks: usize) -> super::Real {
        if blocks == 1 {
            let end = ((first + 1) * VERTEX_BLOCK).min(n);
            return (first * VERTEX_BLOCK..end).fold(0.0, |sum, i| sum + term(i));
        }
        let half = blocks / 2;
        tree(n, first, half) + tree(n, first + half, blocks - half)
    }

    /// Blocks see their own vertices, every vertex once and in place; sums follow the documented
    /// tree whatever the join's order; one block sums in plain vertex order.
    #[test]
    fn blocks_cover_every_vertex_once_and_sum_over_the_fixed_tree() {
        assert_eq!(VERTEX_BLOCK % LANES, 0);
        for n in [
            0,
            1,
            5,
            VERTEX_BLOCK,
            VERTEX_BLOCK + 1,
            3 * VERTEX_BLOCK + 7,
            7 * VERTEX_BLOCK,
        ] {
            let terms: Vec<_> = (0..n).map(term).collect();
            let block = |first: usize, (values, seen): (&[super::Real], &mut [usize])| {
                assert!(first.is_multiple_of(VERTEX_BLOCK) && values.len() <= VERTEX_BLOCK);
                for (j, slot) in seen.iter_mut().enumerate() {
                    *slot += first + j + 1;
                }
                values.iter().fold(0.0, |sum, t| sum + t)
            };
            let mut seen = std::vec![0; n];
            let in_order = Blocks::new(n, (&terms[..], &mut seen[..]), &block).run_with(&InOrder);
            let mut seen_reversed = std::vec![0; n];
            let reversed =
                Blocks::new(n, (&terms[..], &mut seen_reversed[..]), &block).run_with(&Reversed);
            let expected = if n == 0 {
                0.0
            } else {
                tree(n, 0, n.div_ceil(VERTEX_BLOCK))
            };
            assert_eq!(in_order.to_bits(), expected.to_bits(), "n = {n}");
            assert_eq!(reversed.to_bits(), expected.to_bits(), "n = {n}");
            let plain = terms.iter().fold(0.0, |sum, t| sum + t);
            if n <= VERTEX_BLOCK {
                assert_eq!(in_order.to_bits(), plain.to_bits(), "n = {n}");
            }
            let indices: Vec<_> = (1..=n).collect();
            assert_eq!(seen, indices);
            assert_eq!(seen_reversed, indices);
        }
    }
}

//! Decoding fuzzer bytes into choices and numbers.
//!
//! A thin layer over [`arbitrary::Unstructured`]: once the bytes run out every draw returns its
//! smallest value, so any byte string decodes to some input (libFuzzer explores them all).

use arbitrary::Unstructured;

/// The fuzzer's bytes, consumed front to back by the draws.
pub struct Draw<'a> {
    bytes: Unstructured<'a>,
}

impl<'a> Draw<'a> {
    /// Draws from `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Draw {
            bytes: Unstructured::new(data),
        }
    }

    /// A number in `0..=max`.
    pub fn up_to(&mut self, max: u32) -> u32 {
        self.bytes.int_in_range(0..=max).unwrap_or(0)
    }

    /// An index in `0..=max` as `usize`.
    pub fn index(&mut self, max: usize) -> usize {
        self.bytes.int_in_range(0..=max).unwrap_or(0)
    }

    /// `count` tetrahedra, each four indices in `0..=max` drawn corner by corner (in range or
    /// not: the library must refuse what is out of range).
    pub fn tets(&mut self, count: usize, max: usize) -> Vec<[u32; 4]> {
        (0..count)
            .map(|_| {
                let mut index = || self.index(max) as u32;
                [index(), index(), index(), index()]
            })
            .collect()
    }

    /// True with probability about `numerator / 256`.
    pub fn chance(&mut self, numerator: u8) -> bool {
        self.byte() < numerator
    }

    /// One byte.
    pub fn byte(&mut self) -> u8 {
        self.bytes.arbitrary().unwrap_or(0)
    }

    /// A `u32` from four bytes.
    pub fn u32(&mut self) -> u32 {
        self.bytes.arbitrary().unwrap_or(0)
    }

    /// A `u64` from eight bytes.
    pub fn u64(&mut self) -> u64 {
        self.bytes.arbitrary().unwrap_or(0)
    }

    /// A signed grid value in `-32768..=32767`.
    pub fn i16(&mut self) -> i16 {
        self.bytes.arbitrary().unwrap_or(0)
    }

    /// Whatever bytes are left.
    pub fn rest(&mut self) -> &'a [u8] {
        let len = self.bytes.len();
        self.bytes.bytes(len).unwrap_or(&[])
    }
}

/// Draws a float's raw bits in either precision.
pub trait FromDraw: Sized {
    /// A value with uniformly random bits (any float, NaN and infinities included).
    fn raw(draw: &mut Draw<'_>) -> Self;
}

impl FromDraw for u32 {
    fn raw(draw: &mut Draw<'_>) -> u32 {
        draw.u32()
    }
}

impl FromDraw for u64 {
    fn raw(draw: &mut Draw<'_>) -> u64 {
        draw.u64()
    }
}

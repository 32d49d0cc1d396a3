//! The unit cube's 12 outward triangles, written once for two crates: the asset tests
//! (`tests/common/shapes.rs`) and the fuzz checks (`fuzz/src/lib.rs`) each include this file
//! with `#[path]`.

/// The 12 outward triangles of the box with corners 0..8, corner `c` at
/// `(c & 1, c >> 1 & 1, c >> 2 & 1)` (index `x + 2 y + 4 z`).
pub const CUBE_TRIANGLES: [[u32; 3]; 12] = [
    [0, 2, 3],
    [0, 3, 1],
    [4, 5, 7],
    [4, 7, 6],
    [0, 1, 5],
    [0, 5, 4],
    [2, 6, 7],
    [2, 7, 3],
    [0, 4, 6],
    [0, 6, 2],
    [1, 3, 7],
    [1, 7, 5],
];

//! The checks behind softfem's cargo-fuzz targets (`fuzz_targets/*.rs`), one module per target,
//! each written once and compiled for both precisions: the check files are `#[path]`-included
//! into [`single`] (the crate root's f32 API) and [`double`] (`softfem::f64`), as the library
//! itself does.
//!
//! Every check panics (a libFuzzer crash) when softfem breaks a documented promise on the input;
//! the panic message names the promise. Inputs are decoded from the fuzzer's bytes by [`Draw`].

// One source, two precisions (see `single.rs`, `double.rs`).
// `as f64` is a no-op in the f64 instance of the shared files; checks take many inputs.
#![allow(
    clippy::duplicate_mod,
    clippy::unnecessary_cast,
    clippy::too_many_arguments,
    clippy::type_complexity,
    clippy::useless_conversion
)]

pub mod draw;

/// The box surface the voxel checks start from, shared with softfem's asset tests.
#[path = "../../tests/common/cube_triangles.rs"]
mod cube_triangles;

pub use draw::Draw;

#[path = "single.rs"]
pub mod single;

#[path = "double.rs"]
pub mod double;

/// Caps the SIMD width the batched kernels run at from bits 1-2 of a target's first byte
/// (bit 0 picks the precision): `0` no cap (the widest this CPU has), `1` scalar, `2` the 4-lane
/// SSE groups, `3` AVX2. The kernels promise the same bits at every width, so every promise a
/// check asserts must hold at each; drawing the cap from the input fuzzes the narrower code
/// paths (and the tails of each width) on any machine, not only the width it detects.
pub fn cap_width(first: u8) {
    use softfem::simd::{Width, set_max_width};
    set_max_width(match (first >> 1) & 3 {
        0 => Width::Avx512,
        1 => Width::Scalar,
        2 => Width::Sse,
        _ => Width::Avx2,
    });
}

/// With `SOFTFEM_FUZZ_TRACE` set, prints `trace: <what>` to stderr: the checks note what each
/// input reached (which outcome, whether finiteness was asserted), so that replaying a corpus
/// shows what it covers, e.g.
/// `SOFTFEM_FUZZ_TRACE=1 fuzz/target/*/release/stepper -runs=0 target/fuzz-corpus/stepper 2>&1 |
/// grep '^trace' | sort | uniq -c`.
pub fn trace(what: impl FnOnce() -> String) {
    static ENABLED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    if *ENABLED.get_or_init(|| std::env::var_os("SOFTFEM_FUZZ_TRACE").is_some()) {
        eprintln!("trace: {}", what());
    }
}

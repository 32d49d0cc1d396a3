#![no_main]
//! See `src/mesh_checks.rs`: the first byte picks the precision (bit 0) and caps the SIMD
//! width (bits 1-2, `softfem_fuzz::cap_width`), the rest is the input.

use libfuzzer_sys::fuzz_target;
use softfem_fuzz::{cap_width, double, single};

fuzz_target!(|data: &[u8]| {
    cap_width(data.first().copied().unwrap_or(0));
    match data.split_first() {
        Some((precision, rest)) if precision & 1 == 1 => double::mesh::check(rest),
        Some((_, rest)) => single::mesh::check(rest),
        None => single::mesh::check(&[]),
    }
});

#![no_main]
//! See `src/reader_checks.rs`: the first byte picks the precision, the rest is the input.

use libfuzzer_sys::fuzz_target;
use softfem_fuzz::{double, single};

fuzz_target!(|data: &[u8]| {
    match data.split_first() {
        Some((precision, rest)) if precision & 1 == 1 => double::readers::check_gmsh(rest),
        Some((_, rest)) => single::readers::check_gmsh(rest),
        None => single::readers::check_gmsh(&[]),
    }
});

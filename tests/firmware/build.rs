//! Puts `memory.x` on the linker's search path (cortex-m-rt's `link.x` includes it) and the
//! host-computed expected values into `$OUT_DIR/expected.rs`.
//!
//! The expected values come from the file named by `SOFTFEM_FIRMWARE_EXPECTED`, which
//! `tests/firmware.rs` writes. Without it the table is empty, and the firmware reports every
//! record as unexpected and fails: a build without reference values cannot pass.

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("copying memory.x into OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");

    println!("cargo:rerun-if-env-changed=SOFTFEM_FIRMWARE_EXPECTED");
    let expected = match env::var_os("SOFTFEM_FIRMWARE_EXPECTED") {
        Some(path) => {
            println!("cargo:rerun-if-changed={}", PathBuf::from(&path).display());
            fs::read_to_string(&path).unwrap_or_else(|error| {
                panic!("reading SOFTFEM_FIRMWARE_EXPECTED={path:?}: {error}")
            })
        }
        None => "/// No reference values: SOFTFEM_FIRMWARE_EXPECTED was not set.\n\
                 const EXPECTED: &[(&str, u64, u64)] = &[];\n"
            .to_owned(),
    };
    fs::write(out.join("expected.rs"), expected).expect("writing expected.rs");
}

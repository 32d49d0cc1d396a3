//! The `no_std` proof: softfem links and runs in a freestanding program with no `std`, no
//! allocator and no C library.
//!
//! Builds `tests/no_std_probe/` (a crate of its own, outside any workspace) as a static x86_64
//! Linux executable linked with `-nostartfiles -nostdlib -static`, runs it, and reads its ELF file
//! to show that it is statically linked, that no allocator, `std` or panic code made it in, and how
//! large the code is. The link arguments reach that one binary through `cargo rustc -- ...`:
//! `RUSTFLAGS` would also reach build scripts, and libm's cannot link that way.
//!
//! Only on x86_64 Linux: the probe's entry point and `exit` are raw Linux system calls.
#![cfg(all(target_arch = "x86_64", target_os = "linux"))]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

#[path = "common/demangle.rs"]
mod demangle;
use demangle::demangle;

/// The probe's exit status when every check passed (`tests/no_std_probe/src/main.rs`).
const SUCCESS: i32 = 42;
/// The probe's exit status when its panic handler ran.
const PANICKED: i32 = 101;
/// The probe's check names, indexed by the last digit of a failure status `100 + 10 case + check`.
const CHECKS: [&str; 9] = [
    "?",
    "singular values",
    "reconstruction",
    "u orthonormal",
    "v orthonormal",
    "det u = +1",
    "det v = +1",
    "ordering and sign",
    "non-finite input",
];

/// Builds the probe in release mode and returns the path of the executable.
fn build_probe() -> PathBuf {
    let probe_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/no_std_probe");
    let manifest = probe_dir.join("Cargo.toml");
    assert!(
        manifest.is_file(),
        "{} is missing: this test needs a git checkout of softfem, not the published package",
        manifest.display()
    );
    // A target directory of its own, inside the outer one: the outer build's lock cannot block
    // it, and `cargo clean` removes it.
    let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("no_std_probe");
    // The cargo that runs this test, so the probe is built by the same toolchain.
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| env!("CARGO").into());

    let output = Command::new(cargo)
        .current_dir(&probe_dir)
        // The probe's flags are exactly the ones below. Flags meant for the outer build
        // (coverage instrumentation, sanitizers, another target) cannot link without std.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .args(["rustc", "--release", "--quiet", "--manifest-path"])
        .arg(&manifest)
        .arg("--target-dir")
        .arg(&target_dir)
        .args([
            "--",
            // A non-PIE executable: with no C runtime there is nothing to apply relocations.
            "-C",
            "relocation-model=static",
            "-C",
            "link-arg=-nostartfiles",
            "-C",
            "link-arg=-nostdlib",
            "-C",
            "link-arg=-static",
        ])
        .output()
        .expect("could not run cargo to build the no_std probe");
    assert!(
        output.status.success(),
        "building the no_std probe failed ({}):\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    target_dir.join("release/no_std_probe")
}

/// What an exit status of the probe means.
fn describe_status(code: i32) -> String {
    match code {
        SUCCESS => "success".to_owned(),
        PANICKED => "the probe panicked".to_owned(),
        111..=199 if (code - 100) % 10 != 0 => {
            let (case, check) = ((code - 100) / 10, (code - 100) % 10);
            let name = CHECKS.get(check as usize).copied().unwrap_or("?");
            format!("case {case} failed check {check} ({name}); see tests/no_std_probe/src/main.rs")
        }
        _ => "not a status the probe reports".to_owned(),
    }
}

// ELF64 constants (System V gABI).
const ET_EXEC: u16 = 2;
const EM_X86_64: u16 = 62;
const PT_DYNAMIC: u32 = 2;
const PT_INTERP: u32 = 3;
const SHT_SYMTAB: u32 = 2;
const SHT_DYNAMIC: u32 = 6;
const SHT_DYNSYM: u32 = 11;
const SHN_UNDEF: u16 = 0;

/// A little-endian ELF64 file, read just far enough for the checks below.
struct Elf<'a> {
    bytes: &'a [u8],
}

/// One section header.
struct Section {
    name: String,
    kind: u32,
    offset: usize,
    size: usize,
    link: usize,
}

/// One entry of the static symbol table.
struct Symbol {
    name: String,
    size: u64,
    defined: bool,
}

impl Elf<'_> {
    fn u16_at(&self, at: usize) -> u16 {
        u16::from_le_bytes(self.bytes[at..at + 2].try_into().unwrap())
    }

    fn u32_at(&self, at: usize) -> u32 {
        u32::from_le_bytes(self.bytes[at..at + 4].try_into().unwrap())
    }

    fn u64_at(&self, at: usize) -> u64 {
        u64::from_le_bytes(self.bytes[at..at + 8].try_into().unwrap())
    }

    fn usize_at(&self, at: usize) -> usize {
        usize::try_from(self.u64_at(at)).unwrap()
    }

    /// The NUL-terminated string at `at`.
    fn str_at(&self, at: usize) -> String {
        let tail = &self.bytes[at..];
        let len = tail.iter().position(|&b| b == 0).unwrap();
        String::from_utf8_lossy(&tail[..len]).into_owned()
    }

    /// `e_type`, after checking that this is a 64-bit little-endian x86_64 ELF file.
    fn file_type(&self) -> u16 {
        assert_eq!(&self.bytes[..4], b"\x7fELF", "not an ELF file");
        assert_eq!(self.bytes[4], 2, "not a 64-bit ELF file");
        assert_eq!(self.bytes[5], 1, "not a little-endian ELF file");
        assert_eq!(self.u16_at(18), EM_X86_64, "not an x86_64 ELF file");
        self.u16_at(16)
    }

    /// The `p_type` of every program header.
    fn segment_types(&self) -> Vec<u32> {
        let (offset, entry_size, count) = (
            self.usize_at(32),
            usize::from(self.u16_at(54)),
            usize::from(self.u16_at(56)),
        );
        (0..count)
            .map(|i| self.u32_at(offset + i * entry_size))
            .collect()
    }

    fn sections(&self) -> Vec<Section> {
        let (offset, entry_size, count) = (
            self.usize_at(40),
            usize::from(self.u16_at(58)),
            usize::from(self.u16_at(60)),
        );
        let header = |i: usize| offset + i * entry_size;
        let names = self.usize_at(header(usize::from(self.u16_at(62))) + 24);
        (0..count)
            .map(|i| {
                let h = header(i);
                Section {
                    name: self.str_at(names + self.u32_at(h) as usize),
                    kind: self.u32_at(h + 4),
                    offset: self.usize_at(h + 24),
                    size: self.usize_at(h + 32),
                    link: self.u32_at(h + 40) as usize,
                }
            })
            .collect()
    }

    /// The entries of the static symbol table (`.symtab`), or `None` if the file has none.
    fn symbols(&self, sections: &[Section]) -> Option<Vec<Symbol>> {
        const ENTRY_SIZE: usize = 24;
        let table = sections.iter().find(|s| s.kind == SHT_SYMTAB)?;
        let names = sections[table.link].offset;
        let symbols = (0..table.size / ENTRY_SIZE)
            .map(|i| {
                let entry = table.offset + i * ENTRY_SIZE;
                Symbol {
                    name: self.str_at(names + self.u32_at(entry) as usize),
                    size: self.u64_at(entry + 16),
                    defined: self.u16_at(entry + 6) != SHN_UNDEF,
                }
            })
            .collect();
        Some(symbols)
    }
}

#[test]
fn softfem_links_and_runs_without_std_alloc_or_libc() {
    let started = Instant::now();
    let probe = build_probe();
    let build_time = started.elapsed();

    // 1. It runs, and every check in it passes.
    let status = Command::new(&probe)
        .status()
        .expect("could not start the no_std probe");
    match status.code() {
        Some(SUCCESS) => {}
        Some(code) => panic!("no_std probe exited with {code}: {}", describe_status(code)),
        None => panic!("no_std probe was killed: {status}"),
    }

    // 2. It is a static, non-PIE executable: nothing for a dynamic loader to do.
    let bytes = std::fs::read(&probe).unwrap();
    let elf = Elf { bytes: &bytes };
    assert_eq!(
        elf.file_type(),
        ET_EXEC,
        "the probe is not a static executable"
    );
    let segments = elf.segment_types();
    assert!(
        !segments.contains(&PT_INTERP) && !segments.contains(&PT_DYNAMIC),
        "the probe asks for a dynamic loader (program header types {segments:?})"
    );
    let sections = elf.sections();
    let dynamic: Vec<&str> = sections
        .iter()
        .filter(|s| s.kind == SHT_DYNAMIC || s.kind == SHT_DYNSYM || s.name == ".interp")
        .map(|s| s.name.as_str())
        .collect();
    assert!(
        dynamic.is_empty(),
        "the probe has dynamic sections {dynamic:?}"
    );

    // 3. Its symbol table: nothing left undefined for libc to supply, and no allocator, `std` or
    //    panic code. The last holds because the optimiser removed every panic path of `svd3`
    //    (release, LTO, inputs it cannot see): softfem's "never panics" checked at link time.
    let symbols = elf
        .symbols(&sections)
        .expect("the probe has no symbol table to inspect (was it stripped?)");
    assert!(
        symbols.iter().any(|s| s.defined && s.name == "_start"),
        "the probe's symbol table lacks _start: the checks below would prove nothing"
    );
    let undefined: Vec<&str> = symbols
        .iter()
        .filter(|s| !s.defined && !s.name.is_empty())
        .map(|s| s.name.as_str())
        .collect();
    assert!(undefined.is_empty(), "undefined symbols: {undefined:?}");
    // "alloc" catches malloc/calloc/realloc, `__rust_alloc`/`__rust_dealloc` and the `alloc`
    // crate; `std` is matched as a crate name in both the legacy (`_ZN3std`) and v0 (`_3std`)
    // manglings.
    let forbidden_names = ["alloc", "_ZN3std", "_3std", "panic", "rust_begin_unwind"];
    for forbidden in forbidden_names {
        let found: Vec<String> = symbols
            .iter()
            .filter(|s| s.name.contains(forbidden))
            .map(|s| demangle(&s.name))
            .collect();
        assert!(
            found.is_empty(),
            "the probe contains {forbidden:?} symbols: {found:?}"
        );
    }

    // 4. Sizes, for the README.
    let text = sections
        .iter()
        .find(|s| s.name == ".text")
        .expect("the probe has no .text section");
    eprintln!(
        "no_std probe: exit {SUCCESS}, static ELF executable, no allocator/std/libc/panic symbols; \
         built in {:.1} s",
        build_time.as_secs_f64()
    );
    eprintln!("  file {} bytes, .text {} bytes", bytes.len(), text.size);
    // softfem's functions that LTO kept out of line (the rest is inlined into the probe).
    for symbol in symbols.iter().filter(|s| s.name.contains("softfem")) {
        eprintln!("  {:>6} bytes  {}", symbol.size, demangle(&symbol.name));
    }
}

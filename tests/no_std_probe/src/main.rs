//! A freestanding `x86_64` Linux program that proves softfem needs nothing but `core`.
//!
//! `tests/no_std_probe.rs` links it with `-nostartfiles -nostdlib -static`: no C runtime, no libc,
//! no allocator, no `std`. The program decomposes matrices whose singular values are known in
//! closed form (rotations built from Pythagorean triples around a diagonal), checks the results,
//! and reports through its exit status alone:
//!
//! * [`SUCCESS`] (42): every check passed. Zero is deliberately not success, so that a program
//!   that exits early for any other reason cannot pass.
//! * `100 + 10 * case + check`: the first failed check (see [`Check`]) of the numbered case.
//! * [`PANICKED`] (101): the panic handler ran.
#![no_std]
#![no_main]

use core::arch::{asm, global_asm};
use core::hint::black_box;
use core::panic::PanicInfo;

use softfem::glam::{DVec3, Vec3};

/// Exit status of a run in which every check passed.
const SUCCESS: u8 = 42;
/// Exit status of a panic (none is expected: softfem documents `svd3` as panic-free).
const PANICKED: u8 = 101;

// The kernel enters `_start` with `rsp` 16-byte aligned, but a function compiled for the System V
// ABI expects `rsp + 8` to be aligned (a `call` has just pushed the return address). An
// `extern "C" fn _start` would therefore run misaligned and crash on the first aligned SSE spill,
// so the entry point is a few instructions of assembly that realign the stack and call Rust.
// (`global_asm!` rather than a naked function keeps the probe buildable on softfem's MSRV, 1.85.)
global_asm!(
    ".globl _start",
    ".type _start, @function",
    "_start:",
    "xor ebp, ebp", // Outermost frame, for debuggers.
    "and rsp, -16",
    "call {probe_main}",
    "ud2",
    probe_main = sym probe_main,
);

/// The checks run on every decomposition; a failure exits with `100 + 10 * case + check`.
#[derive(Clone, Copy)]
#[repr(u8)]
enum Check {
    /// `sigma` matches the known singular values.
    SingularValues = 1,
    /// `u * diag(sigma) * v^T` reproduces the input.
    Reconstruction = 2,
    /// `u^T u = I`.
    UOrthonormal = 3,
    /// `v^T v = I`.
    VOrthonormal = 4,
    /// `det u = +1`.
    UProper = 5,
    /// `det v = +1`.
    VProper = 6,
    /// `sigma.x >= sigma.y >= |sigma.z|`, and `sigma.z < 0` exactly when `det a < 0` (known by
    /// construction: computing `det a` would overflow for the scaled cases).
    Ordering = 7,
    /// A non-finite input gives NaN values and identity bases.
    NonFinite = 8,
}

/// The exit status that reports `check` failing on case number `case` (1 to 9).
const fn failure(case: u8, check: Check) -> u8 {
    100 + 10 * case + check as u8
}

/// Ends the process with `status` through the raw Linux `exit` system call (number 60).
fn exit(status: u8) -> ! {
    // SAFETY: `exit` takes its status in `rdi` and never returns; the `syscall` instruction
    // itself only clobbers `rcx` and `r11`, which do not matter to code that never resumes.
    unsafe {
        asm!(
            "syscall",
            in("rax") 60_usize,
            in("rdi") usize::from(status),
            options(noreturn, nostack),
        );
    }
}

#[panic_handler]
fn panic(_info: &PanicInfo) -> ! {
    exit(PANICKED)
}

// The memory routines LLVM may call for block copies and fills, which a freestanding program
// must supply itself (`compiler_builtins` exports them only on targets without a libc; on
// x86_64 Linux it leaves them to the C library). The release build happens not to call any,
// but they keep it linking should that change, and they let the unoptimised build link.
// Written with string instructions or plain byte loops that cannot be turned back into calls to
// themselves.

/// `memcpy` (C11 7.24.2.1) with `rep movsb`.
#[unsafe(no_mangle)]
unsafe extern "C" fn memcpy(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    // SAFETY: the caller guarantees `n` readable bytes at `src`, `n` writable bytes at `dest`
    // and no overlap; `rep movsb` copies exactly those bytes, forwards (the ABI keeps the
    // direction flag clear).
    unsafe {
        asm!(
            "rep movsb",
            inout("rcx") n => _,
            inout("rdi") dest => _,
            inout("rsi") src => _,
            options(nostack, preserves_flags),
        );
    }
    dest
}

/// `memmove` (C11 7.24.2.2): copies forwards, or backwards when `dest` overlaps the end of `src`.
#[unsafe(no_mangle)]
unsafe extern "C" fn memmove(dest: *mut u8, src: *const u8, n: usize) -> *mut u8 {
    if (dest as usize).wrapping_sub(src as usize) >= n {
        // SAFETY: `dest` does not start inside `src[..n]`, so a forward copy reads every byte
        // before overwriting it; the caller guarantees the two ranges are valid.
        return unsafe { memcpy(dest, src, n) };
    }
    // SAFETY: `dest` starts inside `src[..n]` (so `n > 0`): copying from the last byte down reads
    // every byte before overwriting it. The direction flag is restored before returning.
    unsafe {
        asm!(
            "std",
            "rep movsb",
            "cld",
            inout("rcx") n => _,
            inout("rdi") dest.add(n - 1) => _,
            inout("rsi") src.add(n - 1) => _,
            options(nostack),
        );
    }
    dest
}

/// `memset` (C11 7.24.6.1) with `rep stosb`.
#[unsafe(no_mangle)]
unsafe extern "C" fn memset(dest: *mut u8, value: i32, n: usize) -> *mut u8 {
    // SAFETY: the caller guarantees `n` writable bytes at `dest`; `rep stosb` writes exactly
    // those, forwards. C converts `value` to `unsigned char`: its low byte.
    unsafe {
        asm!(
            "rep stosb",
            inout("rcx") n => _,
            inout("rdi") dest => _,
            in("al") value.to_le_bytes()[0],
            options(nostack, preserves_flags),
        );
    }
    dest
}

/// `memcmp` (C11 7.24.4.1).
#[unsafe(no_mangle)]
unsafe extern "C" fn memcmp(lhs: *const u8, rhs: *const u8, n: usize) -> i32 {
    for offset in 0..n {
        // SAFETY: the caller guarantees `n` readable bytes at both `lhs` and `rhs`.
        let (left, right) = unsafe { (*lhs.add(offset), *rhs.add(offset)) };
        if left != right {
            return i32::from(left) - i32::from(right);
        }
    }
    0
}

/// `bcmp`, which LLVM emits for equality-only comparisons: `memcmp` satisfies its contract.
#[unsafe(no_mangle)]
unsafe extern "C" fn bcmp(lhs: *const u8, rhs: *const u8, n: usize) -> i32 {
    // SAFETY: same contract as `memcmp`.
    unsafe { memcmp(lhs, rhs, n) }
}

/// Referenced by the unwind tables of the precompiled `core`. With `panic = "abort"` nothing
/// unwinds, so it is never called; LTO drops the references in release builds, and this
/// definition lets the unoptimised build link too.
#[unsafe(no_mangle)]
extern "C" fn rust_eh_personality() {}

/// `err <= tol`, false for a NaN error, so that NaN always fails a check.
fn within<T: PartialOrd + Copy>(err: T, tol: T) -> bool {
    err <= tol
}

/// Rotations, a test matrix and the checks, written once and instantiated per precision (the same
/// scheme as softfem's own `f32`/`f64` modules).
macro_rules! precision {
    ($module:ident, $($precision:ident)::+) => {
        mod $module {
            use super::{within, Check, failure};
            use $($precision)::+::svd::svd3;
            use $($precision)::+::types::{Mat3, Real, Vec3};

            /// Rotation by the angle whose cosine is `a / h` and sine is `b / h` about `x`.
            pub fn rot_x(a: Real, b: Real, h: Real) -> Mat3 {
                let (c, s) = (a / h, b / h);
                Mat3::from_cols(
                    Vec3::new(1.0, 0.0, 0.0),
                    Vec3::new(0.0, c, s),
                    Vec3::new(0.0, -s, c),
                )
            }

            /// Rotation by the angle whose cosine is `a / h` and sine is `b / h` about `y`.
            pub fn rot_y(a: Real, b: Real, h: Real) -> Mat3 {
                let (c, s) = (a / h, b / h);
                Mat3::from_cols(
                    Vec3::new(c, 0.0, -s),
                    Vec3::new(0.0, 1.0, 0.0),
                    Vec3::new(s, 0.0, c),
                )
            }

            /// Rotation by the angle whose cosine is `a / h` and sine is `b / h` about `z`.
            pub fn rot_z(a: Real, b: Real, h: Real) -> Mat3 {
                let (c, s) = (a / h, b / h);
                Mat3::from_cols(
                    Vec3::new(c, s, 0.0),
                    Vec3::new(-s, c, 0.0),
                    Vec3::new(0.0, 0.0, 1.0),
                )
            }

            /// `left * diag(sigma) * right^T` behind `black_box`, so that the decomposition runs
            /// on a value the optimiser cannot see.
            pub fn opaque_product(left: Mat3, sigma: Vec3, right: Mat3) -> Mat3 {
                core::hint::black_box(left * Mat3::from_diagonal(sigma) * right.transpose())
            }

            /// The largest absolute entry of `m`.
            fn max_abs(m: Mat3) -> Real {
                m.x_axis
                    .abs()
                    .max(m.y_axis.abs())
                    .max(m.z_axis.abs())
                    .max_element()
            }

            /// Decomposes `a`, whose singular values are `expected` (sorted, signed), and checks
            /// the result to `tol` relative to the largest singular value (for values, entries of
            /// the reconstruction) or absolute (for orthonormality and determinants).
            pub fn check(case: u8, a: Mat3, expected: Vec3, tol: Real) -> Result<(), u8> {
                let svd = svd3(a);
                let scale = expected.x;
                let fail = |check| Err(failure(case, check));

                if !within((svd.sigma - expected).abs().max_element(), tol * scale) {
                    return fail(Check::SingularValues);
                }
                let reconstructed = svd.u * Mat3::from_diagonal(svd.sigma) * svd.v.transpose();
                if !within(max_abs(reconstructed - a), tol * scale) {
                    return fail(Check::Reconstruction);
                }
                if !within(max_abs(svd.u.transpose() * svd.u - Mat3::IDENTITY), tol) {
                    return fail(Check::UOrthonormal);
                }
                if !within(max_abs(svd.v.transpose() * svd.v - Mat3::IDENTITY), tol) {
                    return fail(Check::VOrthonormal);
                }
                if !within((svd.u.determinant() - 1.0).abs(), tol) {
                    return fail(Check::UProper);
                }
                if !within((svd.v.determinant() - 1.0).abs(), tol) {
                    return fail(Check::VProper);
                }
                let s = svd.sigma;
                let sorted = s.x >= s.y && s.y >= s.z.abs();
                if !sorted || (s.z < 0.0) != (expected.z < 0.0) {
                    return fail(Check::Ordering);
                }
                Ok(())
            }

            /// Checks the documented result for a non-finite input: NaN values, identity bases.
            pub fn check_non_finite(case: u8, a: Mat3) -> Result<(), u8> {
                let svd = svd3(a);
                let s = svd.sigma;
                if s.x.is_nan()
                    && s.y.is_nan()
                    && s.z.is_nan()
                    && svd.u == Mat3::IDENTITY
                    && svd.v == Mat3::IDENTITY
                {
                    Ok(())
                } else {
                    Err(failure(case, Check::NonFinite))
                }
            }
        }
    };
}

precision!(single, softfem);
precision!(double, softfem::f64);

/// Runs every case and returns the exit status of the first failure.
fn run() -> Result<(), u8> {
    use single::{check, check_non_finite, opaque_product, rot_x, rot_y, rot_z};

    // Tolerances. The inputs are themselves rounded (cosines and sines to half an ulp, each entry
    // of `left * diag * right^T` a few ulps more, which by Weyl's inequality moves the singular
    // values by a few `eps * sigma_max`), the checks round too, and softfem promises a few `eps`
    // of its own. Every error measured on these matrices is at most 2 `eps` (x86_64, rustc
    // 1.95); 16 `eps` leaves room for other code generation, while a wrong sign, order or basis
    // is off by order one.
    let tol32 = 16.0 * f32::EPSILON;
    let tol64 = 16.0 * f64::EPSILON;

    // 1. An inverted element: singular values (3, 2, -1) between rotations from the 3-4-5 and
    //    5-12-13 triangles.
    let left = rot_z(3.0, 4.0, 5.0);
    let right = rot_x(5.0, 12.0, 13.0);
    let sigma = Vec3::new(3.0, 2.0, -1.0);
    check(1, opaque_product(left, sigma, right), sigma, tol32)?;

    // 2. A general orientation (two axes on the left, 8-15-17 and 7-24-25) with values spanning
    //    a factor 20, not inverted.
    let left2 = rot_x(5.0, 12.0, 13.0) * rot_y(8.0, 15.0, 17.0);
    let right2 = rot_z(7.0, 24.0, 25.0);
    let sigma2 = Vec3::new(5.0, 0.5, 0.25);
    check(2, opaque_product(left2, sigma2, right2), sigma2, tol32)?;

    // 3. and 4. Case 1 scaled by 2^100 and 2^-100 (exact): `a^T a` would overflow, respectively
    //    underflow, in f32 without softfem's power-of-two rescaling.
    let huge = f32::from_bits((127 + 100) << 23);
    let tiny = f32::from_bits((127 - 100) << 23);
    check(
        3,
        opaque_product(left, sigma * huge, right),
        sigma * huge,
        tol32,
    )?;
    check(
        4,
        opaque_product(left, sigma * tiny, right),
        sigma * tiny,
        tol32,
    )?;

    // 5. A NaN entry propagates instead of hiding (case 7 does the same with inf in f64).
    let mut poisoned = left;
    poisoned.y_axis.z = f32::NAN;
    check_non_finite(5, black_box(poisoned))?;

    // 6. Case 2 with its last value negated (inverted), in double precision.
    let left64 = double::rot_x(5.0, 12.0, 13.0) * double::rot_y(8.0, 15.0, 17.0);
    let right64 = double::rot_z(7.0, 24.0, 25.0);
    let sigma64 = DVec3::new(5.0, 0.5, -0.25);
    double::check(
        6,
        double::opaque_product(left64, sigma64, right64),
        sigma64,
        tol64,
    )?;

    // 7. An infinite entry in double precision.
    let mut poisoned64 = left64;
    poisoned64.x_axis.x = f64::INFINITY;
    double::check_non_finite(7, black_box(poisoned64))?;
    Ok(())
}

/// The program proper, entered from `_start` on an aligned stack.
extern "C" fn probe_main() -> ! {
    match run() {
        Ok(()) => exit(SUCCESS),
        Err(status) => exit(status),
    }
}

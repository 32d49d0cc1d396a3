//! Which SIMD width the batched kernels run at: the widest the CPU has, found at run time (no
//! `std`, no `-C target-cpu`), capped by the caller.
//!
//! On x86_64 the candidates are, from narrow to wide, one value at a time ([`Width::Scalar`]),
//! the 4-lane groups of the SSE/SSE2 baseline ([`Width::Sse`]), AVX2 (8 f32 or 4 f64 per
//! register) and AVX-512F (16 f32 or 8 f64). Every width gives the same bits: each lane runs
//! the scalar code's operations, in its order, with the same IEEE rounding, and no width uses
//! fused multiply-add. A wider width only runs faster, so capping it ([`set_max_width`]) is for
//! measuring and testing, never needed for correctness.
//!
//! Elsewhere the 4-lane groups are plain arrays the compiler vectorises: [`Width::Sse`] on
//! aarch64 (NEON), [`Width::Scalar`] on targets without SIMD registers (a Cortex-M4F) and on
//! wasm32 built without SIMD128. Built with it (`-C target-feature=+simd128`), wasm32 runs at
//! [`Width::Sse`] with the f32 groups in one `v128` (`src/lanes/simd128.rs`).
//!
//! ```
//! use softfem::simd::{self, Width};
//!
//! let widest = simd::detected_width();
//! simd::set_max_width(Width::Sse); // e.g. to compare widths in a benchmark
//! assert_eq!(simd::active_width(), widest.min(Width::Sse));
//! simd::set_max_width(Width::Avx512); // no cap: the widest the CPU has
//! assert_eq!(simd::active_width(), widest);
//! ```
//!
//! The batched kernels: [`svd3_batch`](crate::svd::svd3_batch) and the mesh kernels of
//! [`TetMesh`](crate::mesh::TetMesh) (direct, principal and clamped forces, element and total
//! energies, the fused energy and force pass of the relaxation, and the product of the projected
//! Hessian with a direction from its cached element data), which take the elements in groups of
//! the width's lanes, then narrower groups, then one at a time; the explicit step's vertex
//! update, which takes the vertices in groups of the same widths when the step has no colliders
//! and no fixed axes; and the vertex passes of the relaxation and the descent solvers built on
//! it (gradient, direction, Chebyshev and trial points), which do the same with every setting
//! (ground, friction, pinned vertices; colliders queried lane by lane).
//!
//! This module holds the crate's run-time CPU checks and the only calls into code compiled for
//! CPU features beyond the baseline; the lane types themselves live beside it in `src/lanes/`
//! (`avx2.rs`, `avx512.rs`).

use core::sync::atomic::{AtomicU8, Ordering};

/// A SIMD width the batched kernels can run at, from narrow to wide (so `min` caps a width).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Width {
    /// One value at a time: the scalar code, as a Cortex-M runs it.
    Scalar,
    /// Groups of 4 ([`Lanes`](crate::lanes::Lanes)): SSE/SSE2 registers on x86_64 (always
    /// there), arrays for NEON on aarch64, one `v128` (f32) on wasm32 built with SIMD128.
    Sse,
    /// AVX2 registers: 8 f32 or 4 f64 (x86_64 with AVX2 and OS support of the YMM state).
    Avx2,
    /// AVX-512F registers: 16 f32 or 8 f64 (x86_64 with AVX-512F and OS support of the ZMM and
    /// mask state).
    Avx512,
}

impl Width {
    /// Every width, narrow to wide.
    pub const ALL: [Width; 4] = [Width::Scalar, Width::Sse, Width::Avx2, Width::Avx512];

    /// f32 values per SIMD register at this width (the batched SVD keeps two registers' worth
    /// in flight, see [`svd3_batch`](crate::svd::svd3_batch)).
    #[must_use]
    pub const fn lanes_f32(self) -> usize {
        match self {
            Width::Scalar => 1,
            Width::Sse => 4,
            Width::Avx2 => 8,
            Width::Avx512 => 16,
        }
    }

    /// f64 values per SIMD register (or register group: the 4-lane f64 [`Lanes`] are two SSE2
    /// registers) at this width.
    ///
    /// [`Lanes`]: crate::f64::lanes::Lanes
    #[must_use]
    pub const fn lanes_f64(self) -> usize {
        match self {
            Width::Scalar => 1,
            Width::Sse | Width::Avx2 => 4,
            Width::Avx512 => 8,
        }
    }

    /// The lower-case name: `scalar`, `sse`, `avx2` or `avx512`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Width::Scalar => "scalar",
            Width::Sse => "sse",
            Width::Avx2 => "avx2",
            Width::Avx512 => "avx512",
        }
    }

    /// The width called `name` (as [`Width::name`] writes it, any case), e.g. from an
    /// environment variable of a test or benchmark; `None` for anything else.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Width> {
        Width::ALL
            .into_iter()
            .find(|width| width.name().eq_ignore_ascii_case(name))
    }

    fn from_code(code: u8) -> Width {
        match code {
            0 => Width::Scalar,
            1 => Width::Sse,
            2 => Width::Avx2,
            _ => Width::Avx512,
        }
    }
}

/// `detected_width() as u8`, or [`UNKNOWN`] before the first detection.
static DETECTED: AtomicU8 = AtomicU8::new(UNKNOWN);
const UNKNOWN: u8 = u8::MAX;

/// The cap [`set_max_width`] stores; no cap to begin with.
static MAX_WIDTH: AtomicU8 = AtomicU8::new(Width::Avx512 as u8);

/// The widest [`Width`] this CPU and operating system support, found once and cached (a
/// data race between two first calls only detects twice).
#[must_use]
pub fn detected_width() -> Width {
    let cached = DETECTED.load(Ordering::Relaxed);
    if cached != UNKNOWN {
        return Width::from_code(cached);
    }
    let width = detect();
    DETECTED.store(width as u8, Ordering::Relaxed);
    width
}

/// Caps the width every batched kernel runs at, process-wide, from the next call on (a kernel
/// already running finishes at its width). [`Width::Avx512`] removes the cap. Results do not
/// depend on the width; this is for benchmarks and tests that compare widths.
pub fn set_max_width(width: Width) {
    MAX_WIDTH.store(width as u8, Ordering::Relaxed);
}

/// The cap set by [`set_max_width`] ([`Width::Avx512`] when none was set).
#[must_use]
pub fn max_width() -> Width {
    Width::from_code(MAX_WIDTH.load(Ordering::Relaxed))
}

/// The width the batched kernels run at now: the narrower of [`detected_width`] and
/// [`max_width`].
#[must_use]
pub fn active_width() -> Width {
    detected_width().min(max_width())
}

#[cfg(target_arch = "x86_64")]
fn detect() -> Width {
    use core::arch::x86_64::{__cpuid, __cpuid_count, _xgetbv};

    /// CPUID leaf 1, ECX: the OS has enabled XSAVE (so XGETBV works), and the CPU has AVX.
    const OSXSAVE: u32 = 1 << 27;
    const AVX: u32 = 1 << 28;
    /// CPUID leaf 7 subleaf 0, EBX.
    const AVX2: u32 = 1 << 5;
    const AVX512F: u32 = 1 << 16;
    /// XCR0: the register state the OS saves on a context switch. SSE (XMM) and AVX (upper
    /// YMM halves); the AVX-512 opmask registers, upper ZMM halves and ZMM16-31.
    const YMM_STATE: u64 = 0b110;
    const ZMM_STATE: u64 = 0b1110_0110;

    // CPUID exists on every x86_64 processor (so the intrinsic is safe); leaf 0 gives the
    // highest basic leaf.
    let highest_leaf = __cpuid(0).eax;
    if highest_leaf < 7 {
        return Width::Sse;
    }
    let (leaf1, leaf7) = (__cpuid(1), __cpuid_count(7, 0));
    if leaf1.ecx & (OSXSAVE | AVX) != (OSXSAVE | AVX) {
        return Width::Sse;
    }
    // SAFETY: OSXSAVE set means the OS enabled XSAVE, so XGETBV with ECX = 0 (XCR0) is valid.
    let xcr0 = unsafe { _xgetbv(0) };
    let avx2 = leaf7.ebx & AVX2 != 0 && xcr0 & YMM_STATE == YMM_STATE;
    let avx512 = avx2 && leaf7.ebx & AVX512F != 0 && xcr0 & ZMM_STATE == ZMM_STATE;
    if avx512 {
        Width::Avx512
    } else if avx2 {
        Width::Avx2
    } else {
        Width::Sse
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> Width {
    // wasm32's SIMD128 is chosen when the module is built (`-C target-feature=+simd128`, which
    // puts the f32 lanes in `v128` registers, `src/lanes/simd128.rs`); such a module runs only
    // where the engine has it.
    if cfg!(any(
        target_arch = "aarch64",
        all(target_arch = "wasm32", target_feature = "simd128")
    )) {
        Width::Sse
    } else {
        Width::Scalar
    }
}

/// One batched computation, written once per width. [`dispatch`] runs the widest the CPU has
/// (capped by [`max_width`]).
pub(crate) trait WidthKernel {
    /// What the computation returns.
    type Output;
    /// One value at a time.
    fn scalar(self) -> Self::Output;
    /// In groups of [`Lanes`](crate::lanes::Lanes).
    fn sse(self) -> Self::Output;
    /// With AVX2 lanes. Implementations are `#[inline(always)]`, so that their code is compiled
    /// inside [`dispatch`]'s AVX2 function, with AVX2 enabled.
    ///
    /// # Safety
    /// The CPU must support AVX2 (and the OS its register state): only [`dispatch`] calls this,
    /// after [`detected_width`] found it.
    #[cfg(target_arch = "x86_64")]
    unsafe fn avx2(self) -> Self::Output;
    /// With AVX-512F lanes; as [`WidthKernel::avx2`].
    ///
    /// # Safety
    /// The CPU must support AVX-512F (and the OS its register state): only [`dispatch`] calls
    /// this, after [`detected_width`] found it.
    #[cfg(target_arch = "x86_64")]
    unsafe fn avx512(self) -> Self::Output;
}

/// Runs `kernel` at [`active_width`].
#[inline]
pub(crate) fn dispatch<K: WidthKernel>(kernel: K) -> K::Output {
    match active_width() {
        // SAFETY: `active_width` is at most `detected_width`, which returns `Avx512` only when
        // CPUID reports AVX-512F and XCR0 shows the OS saves its state.
        #[cfg(target_arch = "x86_64")]
        Width::Avx512 => unsafe { run_avx512(kernel) },
        // SAFETY: as above, for AVX2 and the YMM state.
        #[cfg(target_arch = "x86_64")]
        Width::Avx2 => unsafe { run_avx2(kernel) },
        Width::Scalar => kernel.scalar(),
        _ => kernel.sse(),
    }
}

/// `kernel.avx2()` compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_avx2<K: WidthKernel>(kernel: K) -> K::Output {
    // SAFETY: this function runs only where AVX2 is enabled (its target feature), so the
    // CPU supports it.
    unsafe { kernel.avx2() }
}

/// `kernel.avx512()` compiled with AVX-512F enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn run_avx512<K: WidthKernel>(kernel: K) -> K::Output {
    // SAFETY: as in `run_avx2`, for AVX-512F.
    unsafe { kernel.avx512() }
}

/// A piece of a batched kernel that runs in a function of its own ([`outlined_avx2`],
/// [`outlined_avx512`]).
#[cfg(target_arch = "x86_64")]
pub(crate) trait Outlined {
    /// What the piece returns.
    type Output;
    /// The piece's work. Implementations are `#[inline(always)]`, so that their code is
    /// compiled inside the outlined function, with its CPU features enabled.
    fn run(self) -> Self::Output;
}

/// Runs `body` in a function of its own, compiled with AVX2 enabled: for a kernel whose code
/// for several lane types is too large to inline whole into [`dispatch`]'s function (LLVM then
/// stops inlining parts of it, down to single intrinsics, which cost a call each).
///
/// # Safety
/// As [`WidthKernel::avx2`]: the CPU must support AVX2; call it only from there.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline(never)]
pub(crate) unsafe fn outlined_avx2<B: Outlined>(body: B) -> B::Output {
    body.run()
}

/// [`outlined_avx2`] for AVX-512F.
///
/// # Safety
/// As [`WidthKernel::avx512`]: the CPU must support AVX-512F; call it only from there.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline(never)]
pub(crate) unsafe fn outlined_avx512<B: Outlined>(body: B) -> B::Output {
    body.run()
}

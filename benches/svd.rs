//! Throughput of the 3x3 SVD: softfem `svd3` in f32 and f64, `svd3_lanes` (a group of matrices per
//! call, SIMD) in f32 and f64, `svd3_batch` (a whole slice per call) at every SIMD width this
//! machine has (forced with `softfem::simd::set_max_width`) in f32 and f64, `svd3_sweeps` in f32
//! for 1 to 6 sweeps, nalgebra's `Matrix3::<f32>::svd(true, true)` as the reference, and the
//! McAdams-style SVD of the crate `fast-svd-3x3` (approximate reciprocal square roots) scalar,
//! with 8 AVX2 lanes and with 16 AVX-512F lanes, all on the same batch of matrices. The table
//! also gives each routine's largest reconstruction error `||u diag(s) v^T - a||_F / ||a||_F`
//! over the batch (in f64, from the outputs widened exactly).
//!
//! `cargo bench -p softfem-benches --bench svd` runs two passes:
//! 1. criterion, one benchmark per variant, each iteration decomposing the whole batch (criterion
//!    reports elements/s);
//! 2. a plain `Instant` pass that times every variant round-robin several times, keeps the minimum
//!    per variant and prints a markdown table (ns per decomposition, speed-up over nalgebra) ready
//!    to paste into the guide (docs/guide/10-performance.md). Interleaving the variants and taking minima means the ratios come
//!    from the same machine state, which criterion's separate runs do not guarantee.
//!
//! `SOFTFEM_BENCH_QUICK=1` skips criterion and runs the table pass with few repetitions: a smoke
//! test that finishes in about a second (used by `.ci/run`). `SOFTFEM_BENCH_CSV=<path>` appends
//! one CSV row per table row (`bench,workload,size,lanes,threads,value,unit`, see
//! `benches/common/mod.rs`). `cargo bench -p softfem-benches --bench svd -- zzz` runs only the
//! table pass (the filter matches no criterion benchmark).
//!
//! `SOFTFEM_BENCH_FTZ=1` (x86_64) sets the MXCSR's flush-to-zero and denormals-are-zero bits
//! for the whole run: subnormal results and inputs become zero, which changes some results (the
//! crate never does this) but shows what subnormal numbers cost on this CPU. On an Intel Xeon
//! they cost the batched SVD a third of its time; see the SVD section of docs/guide/10-performance.md.

mod common;

use std::hint::black_box;
use std::time::Duration;

use std::cell::RefCell;

use common::{CsvRow, TablePass, XorShift64Star};
use criterion::{BenchmarkId, Criterion, Throughput};
use nalgebra::Matrix3;
use softfem::glam::{DMat3, DVec3, Mat3, Vec3};
use softfem::simd::{self, Width};

/// Matrices per batch: enough to defeat branch prediction on the input pattern, small enough
/// (36 KiB in f32) to stay in L1/L2 so the benchmark measures arithmetic, not memory.
const BATCH_LEN: usize = 1024;

/// Sweep counts benchmarked through `svd3_sweeps`.
const SWEEP_COUNTS: std::ops::RangeInclusive<u32> = 1..=6;

/// Half general matrices (entries uniform in `[-1, 1]`, so any conditioning and either sign of
/// the determinant), half deformation gradients near identity (`I + 0.2 * noise`, what an FEM
/// step mostly sees), shuffled so the two classes do not alternate predictably.
fn input_batch() -> Vec<Mat3> {
    let mut rng = XorShift64Star(0x5eed_50f7_fe11_2026);
    let mut batch: Vec<Mat3> = (0..BATCH_LEN)
        .map(|i| {
            let mut entries = [0.0f32; 9];
            for entry in &mut entries {
                *entry = rng.next_signed_unit();
            }
            let noise = Mat3::from_cols_array(&entries);
            if i % 2 == 0 {
                noise
            } else {
                Mat3::IDENTITY + noise * 0.2
            }
        })
        .collect();
    for i in (1..batch.len()).rev() {
        let j = rng.next_below(i + 1);
        batch.swap(i, j);
    }
    batch
}

/// The same batch in the representations each variant takes, converted once, outside timing.
struct Inputs {
    f32: Vec<Mat3>,
    f64: Vec<DMat3>,
    nalgebra: Vec<Matrix3<f32>>,
    /// Where the slice-level variants write their decompositions.
    out_f32: RefCell<Vec<softfem::svd::Svd3>>,
    out_f64: RefCell<Vec<softfem::f64::svd::Svd3>>,
}

impl Inputs {
    fn new() -> Self {
        let f32 = input_batch();
        let f64 = f32.iter().map(Mat3::as_dmat3).collect();
        let nalgebra = f32
            .iter()
            .map(|m| Matrix3::from_column_slice(&m.to_cols_array()))
            .collect();
        let out_f32 = RefCell::new(vec![softfem::svd::svd3(Mat3::ZERO); BATCH_LEN]);
        let out_f64 = RefCell::new(vec![softfem::f64::svd::svd3(DMat3::ZERO); BATCH_LEN]);
        Inputs {
            f32,
            f64,
            nalgebra,
            out_f32,
            out_f64,
        }
    }
}

// One batch through each variant. Every result feeds the returned sum (singular values and one
// entry of each factor), so no part of any decomposition can be optimised away.

fn run_softfem_f32(batch: &[Mat3]) -> f32 {
    batch.iter().fold(0.0, |acc, &m| {
        let svd = softfem::svd::svd3(black_box(m));
        acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
    })
}

fn run_softfem_f64(batch: &[DMat3]) -> f64 {
    batch.iter().fold(0.0, |acc, &m| {
        let svd = softfem::f64::svd::svd3(black_box(m));
        acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
    })
}

fn run_softfem_f32_sweeps(batch: &[Mat3], sweeps: u32) -> f32 {
    batch.iter().fold(0.0, |acc, &m| {
        let svd = softfem::svd::svd3_sweeps(black_box(m), sweeps);
        acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
    })
}

fn run_softfem_f32_lanes(batch: &[Mat3]) -> f32 {
    batch
        .chunks_exact(softfem::lanes::LANES)
        .fold(0.0, |acc, chunk| {
            let group: &[Mat3; softfem::lanes::LANES] = chunk.try_into().unwrap();
            softfem::svd::svd3_lanes(black_box(group))
                .iter()
                .fold(acc, |acc, svd| {
                    acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
                })
        })
}

fn run_softfem_f64_lanes(batch: &[DMat3]) -> f64 {
    batch
        .chunks_exact(softfem::f64::lanes::LANES)
        .fold(0.0, |acc, chunk| {
            let group: &[DMat3; softfem::f64::lanes::LANES] = chunk.try_into().unwrap();
            softfem::f64::svd::svd3_lanes(black_box(group))
                .iter()
                .fold(acc, |acc, svd| {
                    acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
                })
        })
}

fn run_nalgebra_f32(batch: &[Matrix3<f32>]) -> f32 {
    batch.iter().fold(0.0, |acc, &m| {
        let svd = black_box(m).svd(true, true);
        let u = svd.u.map_or(0.0, |u| u[(0, 0)]);
        let v_t = svd.v_t.map_or(0.0, |v_t| v_t[(2, 2)]);
        acc + svd.singular_values.sum() + u + v_t
    })
}

/// A lower bound for any scalar 3x3 Jacobi SVD with exact rotations: only the chain of dependent
/// operations of `DEFAULT_SWEEPS` sweeps (three rotations each, every rotation needing the
/// previous one's result), as `jacobi_rotation` and `apply_symmetric` in `src/svd.rs` form it:
/// `r = sqrt(d^2 + y^2)`, `h = sqrt((|d| + r)^2 + y^2)`, and the next off-diagonal entry
/// `(|d| + r) (q - t p) / h`. No `v`, no QR, no sorting: the real `svd3` does all of this and
/// more, so it cannot be faster than this row.
fn run_rotation_chain(batch: &[Mat3]) -> f32 {
    let rotations = 3 * softfem::svd::DEFAULT_SWEEPS;
    batch.iter().fold(0.0, |acc, &m| {
        let m = black_box(m);
        let (mut d, mut apq, other) = (m.x_axis.x - m.y_axis.y, m.y_axis.x, m.z_axis.x);
        for _ in 0..rotations {
            let y = apq + apq;
            let r = (d * d + y * y).sqrt();
            let den = d.abs() + r;
            let h = (den * den + y * y).sqrt();
            let t = y / den;
            let next = den * (other - t * apq) / h;
            d -= t * apq;
            apq = next;
        }
        acc + apq + d
    })
}

/// The sum the other variants return, over decompositions already written to `out`.
fn checksum_f32(out: &[softfem::svd::Svd3]) -> f32 {
    out.iter().fold(0.0, |acc, svd| {
        acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
    })
}

fn checksum_f64(out: &[softfem::f64::svd::Svd3]) -> f64 {
    out.iter().fold(0.0, |acc, svd| {
        acc + svd.sigma.element_sum() + svd.u.x_axis.x + svd.v.z_axis.z
    })
}

/// `svd3_batch` of the whole batch at `width` (capped process-wide for the call).
fn run_softfem_f32_batch(batch: &[Mat3], out: &mut [softfem::svd::Svd3], width: Width) -> f32 {
    simd::set_max_width(width);
    softfem::svd::svd3_batch(black_box(batch), out).unwrap();
    simd::set_max_width(Width::Avx512);
    checksum_f32(out)
}

fn run_softfem_f64_batch(
    batch: &[DMat3],
    out: &mut [softfem::f64::svd::Svd3],
    width: Width,
) -> f64 {
    simd::set_max_width(width);
    softfem::f64::svd::svd3_batch(black_box(batch), out).unwrap();
    simd::set_max_width(Width::Avx512);
    checksum_f64(out)
}

/// The crate `fast-svd-3x3` (McAdams, Selle, Tamstorf, Teran and Sifakis, "Computing the
/// singular value decomposition of 3x3 matrices with minimal branching and elementary floating
/// point operations", University of Wisconsin-Madison technical report TR1690, 2011), written
/// once over its `SVDCompatible` number type as softfem is over `Lane`.
mod mcadams {
    use fast_svd_3x3::svd_mat;
    use fast_svd_3x3::traits::SVDCompatible;
    use softfem::glam::{Mat3, Vec3};
    use softfem::svd::Svd3;

    /// `(u, sigma, v)` of the matrix with rows `a`, each factor's rows in order.
    #[inline(always)]
    fn decompose<T: SVDCompatible>(a: [T; 9]) -> ([T; 9], [T; 3], [T; 9]) {
        let [
            mut a11,
            mut a12,
            mut a13,
            mut a21,
            mut a22,
            mut a23,
            mut a31,
            mut a32,
            mut a33,
        ] = a;
        let mut u: [T; 9] = [(); 9].map(|()| T::default());
        let mut v: [T; 9] = [(); 9].map(|()| T::default());
        let [u11, u12, u13, u21, u22, u23, u31, u32, u33] = &mut u;
        let [v11, v12, v13, v21, v22, v23, v31, v32, v33] = &mut v;
        svd_mat(
            &mut a11, &mut a12, &mut a13, &mut a21, &mut a22, &mut a23, &mut a31, &mut a32,
            &mut a33, u11, u12, u13, u21, u22, u23, u31, u32, u33, v11, v12, v13, v21, v22, v23,
            v31, v32, v33,
        );
        (u, [a11, a22, a33], v)
    }

    /// The rows of a glam (column-major) matrix, flattened.
    fn rows(m: Mat3) -> [f32; 9] {
        m.transpose().to_cols_array()
    }

    /// A factor given by its rows.
    fn from_rows(rows: [f32; 9]) -> Mat3 {
        Mat3::from_cols_array(&rows).transpose()
    }

    /// One matrix at a time (`f32` lanes: exact `1 / sqrt` in place of the approximation).
    pub fn scalar(batch: &[Mat3], out: &mut [Svd3]) {
        for (a, svd) in batch.iter().zip(out) {
            let (u, [s1, s2, s3], v) = decompose(rows(std::hint::black_box(*a)));
            *svd = Svd3 {
                u: from_rows(u),
                sigma: Vec3::new(s1, s2, s3),
                v: from_rows(v),
            };
        }
    }

    /// `WIDTH` matrices per group of lanes of type `T` (`batch.len()` a multiple of `WIDTH`),
    /// loaded and stored through arrays.
    #[inline(always)]
    fn grouped<T: SVDCompatible + Copy, const WIDTH: usize>(
        batch: &[Mat3],
        out: &mut [Svd3],
        load: impl Fn([f32; WIDTH]) -> T,
        store: impl Fn(T) -> [f32; WIDTH],
    ) {
        assert_eq!(batch.len() % WIDTH, 0);
        for (group, results) in batch.chunks_exact(WIDTH).zip(out.chunks_exact_mut(WIDTH)) {
            let rows: Vec<[f32; 9]> = group.iter().map(|m| rows(*m)).collect();
            let a: [T; 9] = std::array::from_fn(|k| load(std::array::from_fn(|i| rows[i][k])));
            let (u, sigma, v) = decompose(a);
            let (u, sigma, v) = (u.map(&store), sigma.map(&store), v.map(&store));
            for (i, svd) in results.iter_mut().enumerate() {
                *svd = Svd3 {
                    u: from_rows(std::array::from_fn(|k| u[k][i])),
                    sigma: Vec3::new(sigma[0][i], sigma[1][i], sigma[2][i]),
                    v: from_rows(std::array::from_fn(|k| v[k][i])),
                };
            }
        }
    }

    /// 8 lanes in AVX registers, through the crate's own `__m256` implementation.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub unsafe fn avx2(batch: &[Mat3], out: &mut [Svd3]) {
        use std::arch::x86_64::__m256;
        // SAFETY: `[f32; 8]` and `__m256` have the same size and every bit pattern is valid.
        let load = |values: [f32; 8]| unsafe { std::mem::transmute::<[f32; 8], __m256>(values) };
        let store = |lanes: __m256| unsafe { std::mem::transmute::<__m256, [f32; 8]>(lanes) };
        grouped::<__m256, 8>(batch, out, load, store);
    }

    /// 16 lanes in AVX-512 registers. The crate's own `__m512` implementation needs a nightly
    /// compiler (and AVX-512DQ); this one is the same operations with AVX-512F only
    /// (`rsqrt14` for the approximate reciprocal square root).
    #[cfg(target_arch = "x86_64")]
    #[derive(Clone, Copy)]
    pub struct Zmm(std::arch::x86_64::__m512);

    #[cfg(target_arch = "x86_64")]
    impl SVDCompatible for Zmm {
        type Mask = std::arch::x86_64::__mmask16;
        // SAFETY (every method): only `avx512` below uses this type, after its caller checked
        // for AVX-512F.
        #[inline(always)]
        fn default() -> Self {
            Zmm(unsafe { std::arch::x86_64::_mm512_setzero_ps() })
        }
        #[inline(always)]
        fn add(&self, other: &Self) -> Self {
            Zmm(unsafe { std::arch::x86_64::_mm512_add_ps(self.0, other.0) })
        }
        #[inline(always)]
        fn sub(&self, other: &Self) -> Self {
            Zmm(unsafe { std::arch::x86_64::_mm512_sub_ps(self.0, other.0) })
        }
        #[inline(always)]
        fn mul(&self, other: &Self) -> Self {
            Zmm(unsafe { std::arch::x86_64::_mm512_mul_ps(self.0, other.0) })
        }
        #[inline(always)]
        fn max(&self, other: &Self) -> Self {
            Zmm(unsafe { std::arch::x86_64::_mm512_max_ps(self.0, other.0) })
        }
        #[inline(always)]
        fn and(&self, other: &Self) -> Self {
            use std::arch::x86_64::{_mm512_and_si512, _mm512_castps_si512, _mm512_castsi512_ps};
            Zmm(unsafe {
                _mm512_castsi512_ps(_mm512_and_si512(
                    _mm512_castps_si512(self.0),
                    _mm512_castps_si512(other.0),
                ))
            })
        }
        #[inline(always)]
        fn xor(&self, other: &Self) -> Self {
            use std::arch::x86_64::{_mm512_castps_si512, _mm512_castsi512_ps, _mm512_xor_si512};
            Zmm(unsafe {
                _mm512_castsi512_ps(_mm512_xor_si512(
                    _mm512_castps_si512(self.0),
                    _mm512_castps_si512(other.0),
                ))
            })
        }
        #[inline(always)]
        fn cmpge(&self, other: &Self) -> Self::Mask {
            unsafe { std::arch::x86_64::_mm512_cmp_ps_mask::<13>(self.0, other.0) }
        }
        #[inline(always)]
        fn cmple(&self, other: &Self) -> Self::Mask {
            unsafe { std::arch::x86_64::_mm512_cmp_ps_mask::<2>(self.0, other.0) }
        }
        #[inline(always)]
        fn cmplt(&self, other: &Self) -> Self::Mask {
            unsafe { std::arch::x86_64::_mm512_cmp_ps_mask::<1>(self.0, other.0) }
        }
        #[inline(always)]
        fn splat(value: f32) -> Self {
            Zmm(unsafe { std::arch::x86_64::_mm512_set1_ps(value) })
        }
        #[inline(always)]
        fn rsqrt(&self) -> Self {
            Zmm(unsafe { std::arch::x86_64::_mm512_rsqrt14_ps(self.0) })
        }
        #[inline(always)]
        fn clone(&self) -> Self {
            *self
        }
        #[inline(always)]
        fn blend(mask: &Self::Mask, other_false: &Self, other_true: &Self) -> Self {
            Zmm(unsafe {
                std::arch::x86_64::_mm512_mask_blend_ps(*mask, other_false.0, other_true.0)
            })
        }
        #[inline(always)]
        fn maskz(mask: &Self::Mask, other: &Self) -> Self {
            Zmm(unsafe { std::arch::x86_64::_mm512_maskz_mov_ps(*mask, other.0) })
        }
        #[inline(always)]
        fn ones() -> Self {
            use std::arch::x86_64::{_mm512_castsi512_ps, _mm512_set1_epi32};
            Zmm(unsafe { _mm512_castsi512_ps(_mm512_set1_epi32(-1)) })
        }
    }

    /// 16 lanes in AVX-512 registers ([`Zmm`]).
    ///
    /// # Safety
    /// The CPU must support AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    pub unsafe fn avx512(batch: &[Mat3], out: &mut [Svd3]) {
        use std::arch::x86_64::__m512;
        // SAFETY: `[f32; 16]` and `__m512` have the same size and every bit pattern is valid.
        let load =
            |values: [f32; 16]| Zmm(unsafe { std::mem::transmute::<[f32; 16], __m512>(values) });
        let store = |lanes: Zmm| unsafe { std::mem::transmute::<__m512, [f32; 16]>(lanes.0) };
        grouped::<Zmm, 16>(batch, out, load, store);
    }
}

fn run_mcadams(batch: &[Mat3], out: &mut [softfem::svd::Svd3], width: Width) -> f32 {
    match width {
        // SAFETY: the variants list this width only where `simd::detected_width` found it.
        #[cfg(target_arch = "x86_64")]
        Width::Avx512 => unsafe { mcadams::avx512(black_box(batch), out) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Width::Avx2 => unsafe { mcadams::avx2(black_box(batch), out) },
        _ => mcadams::scalar(black_box(batch), out),
    }
    checksum_f32(out)
}

/// `max ||u diag(sigma) v^T - a||_F / ||a||_F` over the batch, in f64.
fn max_reconstruction_error(
    batch: impl IntoIterator<Item = DMat3>,
    factors: impl IntoIterator<Item = (DMat3, DVec3, DMat3)>,
) -> f64 {
    let frobenius = |m: DMat3| m.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt();
    batch
        .into_iter()
        .zip(factors)
        .map(|(a, (u, sigma, v))| {
            frobenius(u * DMat3::from_diagonal(sigma) * v.transpose() - a) / frobenius(a)
        })
        .fold(0.0, f64::max)
}

fn widened(svd: &softfem::svd::Svd3) -> (DMat3, DVec3, DMat3) {
    (svd.u.as_dmat3(), svd.sigma.as_dvec3(), svd.v.as_dmat3())
}

/// A benchmarked variant: its table label, its CSV workload name and lane count, one pass over
/// the batch, and its largest reconstruction error where measured.
struct Variant<'a> {
    label: String,
    workload: String,
    lanes: usize,
    run_batch: Box<dyn Fn() -> f64 + 'a>,
    max_error: Option<f64>,
}

impl<'a> Variant<'a> {
    fn new(label: String, workload: &str, lanes: usize, run_batch: impl Fn() -> f64 + 'a) -> Self {
        Variant {
            label,
            workload: workload.to_owned(),
            lanes,
            run_batch: Box::new(run_batch),
            max_error: None,
        }
    }

    fn with_error(mut self, max_error: f64) -> Self {
        self.max_error = Some(max_error);
        self
    }
}

/// The widths this machine has, narrow to wide.
fn widths() -> Vec<Width> {
    Width::ALL
        .into_iter()
        .filter(|&width| width <= simd::detected_width())
        .collect()
}

/// Every variant, nalgebra first (it is the reference for the speed-up column).
fn variants(inputs: &Inputs) -> Vec<Variant<'_>> {
    let wide_f32 = || inputs.f32.iter().map(Mat3::as_dmat3);
    let nalgebra_error = max_reconstruction_error(
        wide_f32(),
        inputs.nalgebra.iter().map(|m| {
            let svd = m.svd(true, true);
            let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
            let to_glam = |m: Matrix3<f32>| Mat3::from_cols_slice(m.as_slice()).as_dmat3();
            let s = svd.singular_values;
            (
                to_glam(u),
                Vec3::new(s[0], s[1], s[2]).as_dvec3(),
                to_glam(v_t.transpose()),
            )
        }),
    );
    let scalar_error = max_reconstruction_error(
        wide_f32(),
        inputs.f32.iter().map(|m| widened(&softfem::svd::svd3(*m))),
    );
    let scalar_error_f64 = max_reconstruction_error(
        inputs.f64.iter().copied(),
        inputs.f64.iter().map(|m| {
            let svd = softfem::f64::svd::svd3(*m);
            (svd.u, svd.sigma, svd.v)
        }),
    );
    let mut variants = vec![
        Variant::new(
            "nalgebra `Matrix3::<f32>::svd(true, true)`".into(),
            "nalgebra svd f32",
            1,
            || f64::from(run_nalgebra_f32(&inputs.nalgebra)),
        )
        .with_error(nalgebra_error),
        Variant::new(
            format!(
                "softfem `svd3` f32 ({} sweeps, default)",
                softfem::svd::DEFAULT_SWEEPS
            ),
            "softfem svd3 f32",
            1,
            || f64::from(run_softfem_f32(&inputs.f32)),
        )
        .with_error(scalar_error),
        Variant::new(
            format!(
                "softfem `svd3` f64 ({} sweeps, default)",
                softfem::f64::svd::DEFAULT_SWEEPS
            ),
            "softfem svd3 f64",
            1,
            || run_softfem_f64(&inputs.f64),
        )
        .with_error(scalar_error_f64),
        Variant::new(
            format!(
                "softfem `svd3_lanes` f32 ({} matrices per call)",
                softfem::lanes::LANES
            ),
            "softfem svd3_lanes f32",
            softfem::lanes::LANES,
            || f64::from(run_softfem_f32_lanes(&inputs.f32)),
        ),
        Variant::new(
            format!(
                "softfem `svd3_lanes` f64 ({} matrices per call)",
                softfem::f64::lanes::LANES
            ),
            "softfem svd3_lanes f64",
            softfem::f64::lanes::LANES,
            || run_softfem_f64_lanes(&inputs.f64),
        ),
    ];
    for width in widths() {
        let mut out = inputs.out_f32.borrow_mut();
        run_softfem_f32_batch(&inputs.f32, &mut out, width);
        let error = max_reconstruction_error(wide_f32(), out.iter().map(widened));
        variants.push(
            Variant::new(
                format!(
                    "softfem `svd3_batch` f32, {} ({} lanes)",
                    width.name(),
                    width.lanes_f32()
                ),
                &format!("softfem svd3_batch f32 {}", width.name()),
                width.lanes_f32(),
                move || {
                    f64::from(run_softfem_f32_batch(
                        &inputs.f32,
                        &mut inputs.out_f32.borrow_mut(),
                        width,
                    ))
                },
            )
            .with_error(error),
        );
    }
    for width in widths() {
        let mut out = inputs.out_f64.borrow_mut();
        run_softfem_f64_batch(&inputs.f64, &mut out, width);
        let error = max_reconstruction_error(
            inputs.f64.iter().copied(),
            out.iter().map(|svd| (svd.u, svd.sigma, svd.v)),
        );
        variants.push(
            Variant::new(
                format!(
                    "softfem `svd3_batch` f64, {} ({} lanes)",
                    width.name(),
                    width.lanes_f64()
                ),
                &format!("softfem svd3_batch f64 {}", width.name()),
                width.lanes_f64(),
                move || run_softfem_f64_batch(&inputs.f64, &mut inputs.out_f64.borrow_mut(), width),
            )
            .with_error(error),
        );
    }
    // fast-svd-3x3: scalar, and the widths it has SIMD lanes for that this machine has.
    for width in widths()
        .into_iter()
        .filter(|width| matches!(width, Width::Scalar | Width::Avx2 | Width::Avx512))
    {
        let mut out = inputs.out_f32.borrow_mut();
        run_mcadams(&inputs.f32, &mut out, width);
        let error = max_reconstruction_error(wide_f32(), out.iter().map(widened));
        variants.push(
            Variant::new(
                format!(
                    "fast-svd-3x3 0.2 (McAdams et al., approximate rsqrt) f32, {} ({} lanes)",
                    width.name(),
                    width.lanes_f32()
                ),
                &format!("fast-svd-3x3 f32 {}", width.name()),
                width.lanes_f32(),
                move || {
                    f64::from(run_mcadams(
                        &inputs.f32,
                        &mut inputs.out_f32.borrow_mut(),
                        width,
                    ))
                },
            )
            .with_error(error),
        );
    }
    variants.push(Variant::new(
        format!(
            "lower bound: the {} dependent rotations of {} sweeps alone (2 square roots and a \
             division each, nothing else)",
            3 * softfem::svd::DEFAULT_SWEEPS,
            softfem::svd::DEFAULT_SWEEPS
        ),
        "lower bound rotation chain f32",
        1,
        || f64::from(run_rotation_chain(&inputs.f32)),
    ));
    for sweeps in SWEEP_COUNTS {
        variants.push(Variant::new(
            format!(
                "softfem `svd3_sweeps` f32, {sweeps} sweep{}",
                if sweeps == 1 { "" } else { "s" }
            ),
            &format!("softfem svd3_sweeps f32 {sweeps} sweeps"),
            1,
            move || f64::from(run_softfem_f32_sweeps(&inputs.f32, sweeps)),
        ));
    }
    variants
}

fn criterion_benches(c: &mut Criterion, inputs: &Inputs) {
    let mut group = c.benchmark_group("svd3");
    group.throughput(Throughput::Elements(BATCH_LEN as u64));
    group.bench_function("nalgebra_f32", |b| {
        b.iter(|| run_nalgebra_f32(&inputs.nalgebra));
    });
    group.bench_function("softfem_f32", |b| {
        b.iter(|| run_softfem_f32(&inputs.f32));
    });
    group.bench_function("softfem_f64", |b| {
        b.iter(|| run_softfem_f64(&inputs.f64));
    });
    group.bench_function("softfem_f32_lanes", |b| {
        b.iter(|| run_softfem_f32_lanes(&inputs.f32));
    });
    group.bench_function("softfem_f64_lanes", |b| {
        b.iter(|| run_softfem_f64_lanes(&inputs.f64));
    });
    for width in widths() {
        group.bench_with_input(
            BenchmarkId::new("softfem_f32_batch", width.name()),
            &width,
            |b, &width| {
                b.iter(|| {
                    run_softfem_f32_batch(&inputs.f32, &mut inputs.out_f32.borrow_mut(), width)
                });
            },
        );
        group.bench_with_input(
            BenchmarkId::new("softfem_f64_batch", width.name()),
            &width,
            |b, &width| {
                b.iter(|| {
                    run_softfem_f64_batch(&inputs.f64, &mut inputs.out_f64.borrow_mut(), width)
                });
            },
        );
    }
    for sweeps in SWEEP_COUNTS {
        group.bench_with_input(
            BenchmarkId::new("softfem_f32_sweeps", sweeps),
            &sweeps,
            |b, &sweeps| b.iter(|| run_softfem_f32_sweeps(&inputs.f32, sweeps)),
        );
    }
    group.finish();
}

/// Repetitions of the batch per timed block, and round-robin rounds over all variants.
struct TablePlan {
    repetitions: u32,
    rounds: u32,
}

fn print_table(variants: &mut [Variant<'_>], plan: &TablePlan) {
    let ns = common::round_robin_min_ns(
        variants,
        |variant| {
            black_box((variant.run_batch)());
        },
        plan.repetitions,
        BATCH_LEN,
        plan.rounds,
    );
    let reference_ns = ns[0];
    println!();
    println!(
        "SVD of 3x3 matrices: {BATCH_LEN} inputs (half general, half near identity), minimum of \
         {} round-robin rounds of {} batches per variant, on {}.",
        plan.rounds,
        plan.repetitions,
        common::machine(),
    );
    println!();
    common::print_markdown_table(
        &[
            "variant",
            "ns/decomposition",
            "speed-up vs nalgebra f32",
            "max reconstruction error",
        ],
        variants.iter().zip(&ns).map(|(variant, ns)| {
            vec![
                variant.label.clone(),
                format!("{ns:.1}"),
                format!("{:.2}x", reference_ns / ns),
                variant
                    .max_error
                    .map_or_else(|| "-".into(), |error| format!("{error:.1e}")),
            ]
        }),
    );
    let rows: Vec<CsvRow> = variants
        .iter()
        .zip(&ns)
        .map(|(variant, &ns)| CsvRow {
            bench: "svd",
            workload: variant.workload.clone(),
            size: BATCH_LEN,
            lanes: variant.lanes,
            threads: 1,
            value: ns,
            unit: "ns/matrix",
        })
        .collect();
    common::append_csv_rows(&rows);
}

/// Sets the MXCSR's flush-to-zero (bit 15) and denormals-are-zero (bit 6) bits of this thread
/// when `SOFTFEM_BENCH_FTZ=1`, and says so; nothing elsewhere.
fn flush_subnormals_if_asked() {
    if std::env::var("SOFTFEM_BENCH_FTZ").is_ok_and(|value| value == "1") {
        #[cfg(target_arch = "x86_64")]
        {
            let mut csr: u32 = 0;
            // SAFETY: `stmxcsr` and `ldmxcsr` read and write this thread's SSE control register
            // through a valid `u32`; the bits set only change how subnormals are rounded.
            unsafe {
                std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack));
                csr |= 0x8040;
                std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack));
            }
            println!("SOFTFEM_BENCH_FTZ=1: subnormals flushed to zero (MXCSR {csr:#06x}).");
        }
        #[cfg(not(target_arch = "x86_64"))]
        println!("SOFTFEM_BENCH_FTZ=1 is ignored: not x86_64.");
    }
}

fn main() {
    flush_subnormals_if_asked();
    let inputs = Inputs::new();
    let mut variants = variants(&inputs);

    if common::quick() {
        print_table(
            &mut variants,
            &TablePlan {
                repetitions: 5,
                rounds: 3,
            },
        );
        return;
    }

    // Nine benchmarks at ~2.5 s each keep the whole run near 30 s; command-line flags
    // (`--measurement-time`, `--sample-size`, a name filter, ...) still override these.
    let mut criterion = Criterion::default()
        .without_plots()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30)
        .configure_from_args();
    criterion_benches(&mut criterion, &inputs);
    criterion.final_summary();

    let plan = match common::table_pass() {
        TablePass::Skip => return,
        TablePass::Test => TablePlan {
            repetitions: 1,
            rounds: 1,
        },
        // Short timed blocks (10 batches, 0.5 to 20 ms) and many rounds: on a shared machine
        // a short block is more often left alone by the scheduler, so the minima are stabler
        // than those of a few long blocks.
        TablePass::Full => TablePlan {
            repetitions: 10,
            rounds: 100,
        },
    };
    print_table(&mut variants, &plan);
}

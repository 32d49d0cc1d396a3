//! [`svd3_batch`]: the SVDs of a slice of matrices, at the widest SIMD width the CPU has
//! ([`simd`](crate::simd)), each bit for bit [`svd3`](super::svd3) of its matrix.
//!
//! The matrices go through the algorithm of [`svd3`](super::svd3) in groups, one matrix per
//! lane: pairs of registers at the active width first (two independent chains of operations
//! per group, which the processor overlaps: the sweeps are a long chain of dependent square
//! roots and divisions), then single registers and narrower ones for what is left, the last
//! group padded with identity matrices. Lanes never interact (every operation is element-wise,
//! and a lane that has converged keeps its values while others sweep on), so neither the
//! grouping nor the padding changes any result.
//!
//! On an AMD EPYC (Zen 4), f32 batches of 1024 ran 1.25x (SSE) and 1.2x (AVX2) faster in pairs
//! of registers than in single ones, and 1.3x with AVX-512 (20.2 against 26.8 ns a matrix, least
//! of six interleaved runs, 2026-12-03); four registers at a time ran slower (23.5 against
//! 21.5 ns: their values no longer fit the 32 registers). The chain, not the divider, is the
//! limit: 24 fewer divisions or 12 fewer square roots per group of 16 changed nothing
//! measurable. `cargo bench -p softfem-benches --bench svd` gives the times per width.

#[cfg(not(debug_assertions))]
use super::super::lanes::LanePair;
use super::super::lanes::{
    LANES, Lane, LaneArray, LaneMat3, LaneSvd3, LaneVec3, Lanes, MAX_WIDTH as MAX_GROUP, lane_mat3,
    transpose4,
};
use super::super::math;
use super::super::types::{Mat3, Real};
use super::{DEFAULT_SWEEPS, Prescale, Svd3, decompose_scaled, svd3_sweeps};
use crate::error::SvdBatchError;
use crate::simd::{WidthKernel, dispatch};

/// The SVD of every matrix of `matrices` into `out` (`out[i]` is the decomposition of
/// `matrices[i]`), with [`DEFAULT_SWEEPS`] Jacobi sweeps, using the widest SIMD lanes the CPU
/// has (see [`simd`](crate::simd)).
///
/// Each result is bit for bit what [`svd3`](super::svd3) returns for its matrix, whatever the
/// length, the width chosen and the other matrices of the batch (non-finite and zero matrices
/// included). Any length works, 0 too.
///
/// # Errors
/// [`SvdBatchError::OutputLength`] if `out.len() != matrices.len()`; `out` is then unchanged.
///
/// ```
/// use softfem::glam::Mat3;
/// use softfem::svd::{Svd3, svd3, svd3_batch};
///
/// let matrices: Vec<Mat3> = (0..37)
///     .map(|i| Mat3::from_rotation_z(i as f32) * Mat3::from_diagonal((1.0, 2.0, 0.5 + i as f32).into()))
///     .collect();
/// let mut out = vec![svd3(Mat3::ZERO); matrices.len()];
/// svd3_batch(&matrices, &mut out)?;
/// for (a, svd) in matrices.iter().zip(&out) {
///     assert_eq!(*svd, svd3(*a));
/// }
/// assert!(svd3_batch(&matrices, &mut out[1..]).is_err());
/// # Ok::<(), softfem::SvdBatchError>(())
/// ```
pub fn svd3_batch(matrices: &[Mat3], out: &mut [Svd3]) -> Result<(), SvdBatchError> {
    svd3_batch_sweeps(matrices, out, DEFAULT_SWEEPS)
}

/// [`svd3_batch`] with at most `sweeps` Jacobi sweeps: each result is bit for bit
/// [`svd3_sweeps`]`(matrices[i], sweeps)`.
///
/// # Errors
/// [`SvdBatchError::OutputLength`] if `out.len() != matrices.len()`; `out` is then unchanged.
pub fn svd3_batch_sweeps(
    matrices: &[Mat3],
    out: &mut [Svd3],
    sweeps: u32,
) -> Result<(), SvdBatchError> {
    if out.len() != matrices.len() {
        return Err(SvdBatchError::OutputLength {
            expected: matrices.len(),
            actual: out.len(),
        });
    }
    dispatch(Batch {
        matrices,
        out,
        sweeps,
    });
    Ok(())
}

/// One call of [`svd3_batch_sweeps`], for [`dispatch`]; `matrices` and `out` have one length.
struct Batch<'a> {
    matrices: &'a [Mat3],
    out: &'a mut [Svd3],
    sweeps: u32,
}

// Optimised builds run pairs of registers, then single registers and narrower lanes for the
// rest. Unoptimised (debug) builds run single registers of the width only, the last group
// padded: there every operation of the inlined decomposition keeps its own stack slot, and the
// full cascade of four lane types in one function took a 2.5 MiB stack frame (AVX-512), more
// than a thread's default stack; one lane type takes about a quarter of that. Both give the
// bits of `svd3`; tests/kernels/simd.rs checks the debug path and, with `--release`, the other.
impl WidthKernel for Batch<'_> {
    type Output = ();

    #[inline(always)]
    fn scalar(self) {
        for (a, svd) in self.matrices.iter().zip(self.out) {
            *svd = svd3_sweeps(*a, self.sweeps);
        }
    }

    #[inline(always)]
    fn sse(self) {
        #[cfg(not(debug_assertions))]
        let (matrices, out) = if math::SSE_PAIRS {
            whole_groups::<LanePair<Lanes>>(self.matrices, self.out, self.sweeps)
        } else {
            (self.matrices, self.out)
        };
        #[cfg(debug_assertions)]
        let (matrices, out) = (self.matrices, self.out);
        padded_groups::<Lanes>(matrices, out, self.sweeps);
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx2(self) {
        use super::super::lanes::avx2::Avx2Lanes;
        use crate::simd::outlined_avx2 as run;
        let (matrices, out, sweeps) = (self.matrices, self.out, self.sweeps);
        // SAFETY (each `run`): `avx2` runs only where `dispatch` found AVX2. Each lane type's
        // loop gets a function of its own, small enough to be inlined whole.
        #[cfg(not(debug_assertions))]
        unsafe {
            let (matrices, out) = run(Groups::<LanePair<Avx2Lanes>>::whole(matrices, out, sweeps));
            let (matrices, out) = run(Groups::<Avx2Lanes>::whole(matrices, out, sweeps));
            run(Groups::<Lanes>::padded(matrices, out, sweeps));
        }
        #[cfg(debug_assertions)]
        unsafe {
            run(Groups::<Avx2Lanes>::padded(matrices, out, sweeps));
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn avx512(self) {
        use super::super::lanes::avx512::Avx512Lanes;
        use crate::simd::outlined_avx512 as run;
        let (matrices, out, sweeps) = (self.matrices, self.out, self.sweeps);
        // SAFETY (each `run`): `avx512` runs only where `dispatch` found AVX-512F. Each lane
        // type's loop gets a function of its own, as in `avx2`.
        #[cfg(not(debug_assertions))]
        unsafe {
            use super::super::lanes::avx2::Avx2Lanes;
            let (matrices, out) = run(Groups::<LanePair<Avx512Lanes>>::whole(
                matrices, out, sweeps,
            ));
            let (matrices, out) = run(Groups::<Avx512Lanes>::whole(matrices, out, sweeps));
            let (matrices, out) = run(Groups::<Avx2Lanes>::whole(matrices, out, sweeps));
            run(Groups::<Lanes>::padded(matrices, out, sweeps));
        }
        #[cfg(debug_assertions)]
        unsafe {
            run(Groups::<Avx512Lanes>::padded(matrices, out, sweeps));
        }
    }
}

/// The decompositions of `matrices` into `out` in groups of `L::WIDTH`, as one piece of
/// [`Batch`] for [`simd`](crate::simd)'s outlined functions: whole groups only (the rest is
/// returned), or every matrix (the last group padded).
#[cfg(target_arch = "x86_64")]
struct Groups<'a, 'b, L> {
    matrices: &'a [Mat3],
    out: &'b mut [Svd3],
    sweeps: u32,
    padded: bool,
    lanes: core::marker::PhantomData<L>,
}

#[cfg(target_arch = "x86_64")]
impl<'a, 'b, L: LaneArray> Groups<'a, 'b, L> {
    #[cfg(not(debug_assertions))]
    fn whole(matrices: &'a [Mat3], out: &'b mut [Svd3], sweeps: u32) -> Self {
        Groups {
            matrices,
            out,
            sweeps,
            padded: false,
            lanes: core::marker::PhantomData,
        }
    }

    fn padded(matrices: &'a [Mat3], out: &'b mut [Svd3], sweeps: u32) -> Self {
        Groups {
            matrices,
            out,
            sweeps,
            padded: true,
            lanes: core::marker::PhantomData,
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl<'a, 'b, L: LaneArray> crate::simd::Outlined for Groups<'a, 'b, L> {
    type Output = (&'a [Mat3], &'b mut [Svd3]);

    #[inline(always)]
    fn run(self) -> Self::Output {
        if self.padded {
            padded_groups::<L>(self.matrices, self.out, self.sweeps);
            (&[], &mut [])
        } else {
            whole_groups::<L>(self.matrices, self.out, self.sweeps)
        }
    }
}

/// Decomposes the matrices in whole groups of `L::WIDTH`; returns the rest (fewer than
/// `L::WIDTH`) and their outputs.
#[cfg(any(target_arch = "x86_64", not(debug_assertions)))]
#[inline(always)]
fn whole_groups<'a, 'b, L: LaneArray>(
    matrices: &'a [Mat3],
    out: &'b mut [Svd3],
    sweeps: u32,
) -> (&'a [Mat3], &'b mut [Svd3]) {
    let mut inputs = matrices.chunks_exact(L::WIDTH);
    let mut outputs = out.chunks_exact_mut(L::WIDTH);
    for (group, results) in (&mut inputs).zip(&mut outputs) {
        decompose_group::<L>(group, results, sweeps);
    }
    (inputs.remainder(), outputs.into_remainder())
}

/// Decomposes the matrices in groups of `L::WIDTH`, the last one padded.
#[inline(always)]
fn padded_groups<L: LaneArray>(matrices: &[Mat3], out: &mut [Svd3], sweeps: u32) {
    for (group, results) in matrices.chunks(L::WIDTH).zip(out.chunks_mut(L::WIDTH)) {
        decompose_group::<L>(group, results, sweeps);
    }
}

/// Sets the value of `lane` in each of `columns`.
#[inline(always)]
fn set_lane<L: LaneArray, const N: usize>(
    columns: &mut [L::Array; N],
    lane: usize,
    values: [Real; N],
) {
    for (column, value) in columns.iter_mut().zip(values) {
        L::set_lane_value(column, lane, value);
    }
}

/// Whether the matrices go into and out of the lanes through 4x4 transposes in registers
/// (f32), or lane by lane (f64). Measured on an AMD EPYC (Zen 4), 1024 matrices, interleaved
/// runs: in f32 the transposes took the 16-lane batch from 35.8 to 31.1 ns per matrix (the
/// compiler's lane-by-lane loads had become gather instructions, and the lane-by-lane output
/// read every value from memory); in f64, where a group of [`Lanes`] is two registers, they
/// made the 8-lane batch slower (66 to 71 ns).
const REGISTER_TRANSPOSES: bool = core::mem::size_of::<Real>() == 4;

/// `out[i]` = the SVD of `matrices[i]`, for up to `L::WIDTH` matrices in one group of lanes
/// (padded with the identity), through [`decompose_entries`].
#[inline(always)]
fn decompose_group<L: LaneArray>(matrices: &[Mat3], out: &mut [Svd3], sweeps: u32) {
    let entries = if REGISTER_TRANSPOSES {
        entries_by_quarters::<L>(matrices)
    } else {
        entries_by_lanes::<L>(matrices)
    };
    let (svd, decomposed) = decompose_entries::<L>(entries, sweeps);
    let [u0, u1, u2, u3, u4, u5, u6, u7, u8] = matrix_entries(svd.u);
    let [v0, v1, v2, v3, v4, v5, v6, v7, v8] = matrix_entries(svd.v);
    let (s0, s1, s2) = (
        svd.sigma.x.to_lane_array(),
        svd.sigma.y.to_lane_array(),
        svd.sigma.z.to_lane_array(),
    );
    // Each result's 21 values (u, sigma, v) in the order of `Svd3::from_values`.
    let results = [
        u0, u1, u2, u3, u4, u5, u6, u7, u8, s0, s1, s2, v0, v1, v2, v3, v4, v5, v6, v7, v8,
    ];
    // The lane or quarter index is hidden from the optimiser, which would otherwise unroll
    // the loop and turn the lanes' stores into scatter instructions (one per entry, across the
    // matrices), several times slower on current AMD processors than plain stores of each
    // matrix's values.
    if !REGISTER_TRANSPOSES {
        for (lane, (a, svd)) in matrices.iter().zip(out).enumerate() {
            let lane = core::hint::black_box(lane);
            *svd = match decomposed.get(lane) {
                Some(true) => Svd3::from_values(&core::array::from_fn(|k| {
                    results
                        .get(k)
                        .map_or(0.0, |values| L::lane_value(values, lane))
                })),
                _ => Svd3::without_decomposition(*a),
            };
        }
        return;
    }
    let quarters = matrices.chunks(LANES).zip(out.chunks_mut(LANES));
    for (q, (inputs, outputs)) in quarters.enumerate() {
        let q = core::hint::black_box(q);
        let block = |first: usize| {
            transpose4(core::array::from_fn(|row| {
                results
                    .get(first + row)
                    .map_or(Lanes::splat(0.0), |values| L::quarter(values, q))
            }))
        };
        let blocks = [
            block(0),
            block(4),
            block(8),
            block(12),
            block(16),
            block(20),
        ];
        for (lane, (a, svd)) in inputs.iter().zip(outputs).enumerate() {
            let values: [Real; 24] = core::array::from_fn(|k| {
                blocks
                    .get(k / LANES)
                    .and_then(|block| block.get(lane))
                    .map_or(0.0, |row| {
                        row.to_array().get(k % LANES).copied().unwrap_or(0.0)
                    })
            });
            *svd = match decomposed.get(q * LANES + lane) {
                Some(true) => Svd3::from_values(&values),
                _ => Svd3::without_decomposition(*a),
            };
        }
    }
}

/// The entries of up to `L::WIDTH` matrices (the identity past the end), columns first, each
/// as the array of its lanes, lane by lane.
#[inline(always)]
fn entries_by_lanes<L: LaneArray>(matrices: &[Mat3]) -> [L::Array; 9] {
    let mut entries = [L::ZEROS; 9];
    for lane in 0..L::WIDTH {
        let a = matrices.get(lane).copied().unwrap_or(Mat3::IDENTITY);
        set_lane::<L, 9>(&mut entries, lane, a.to_cols_array());
    }
    entries
}

/// [`entries_by_lanes`] four matrices at a time, through 4x4 transposes in registers.
#[inline(always)]
fn entries_by_quarters<L: LaneArray>(matrices: &[Mat3]) -> [L::Array; 9] {
    let mut entries = [L::ZEROS; 9];
    for q in 0..L::WIDTH / LANES {
        let rows: [[Real; 12]; LANES] = core::array::from_fn(|lane| {
            let a = matrices
                .get(q * LANES + lane)
                .copied()
                .unwrap_or(Mat3::IDENTITY);
            let [a0, a1, a2, a3, a4, a5, a6, a7, a8] = a.to_cols_array();
            [a0, a1, a2, a3, a4, a5, a6, a7, a8, 0.0, 0.0, 0.0]
        });
        for (first, block) in entries.chunks_mut(LANES).enumerate() {
            let columns = transpose4(core::array::from_fn(|lane| {
                Lanes::from_array(core::array::from_fn(|j| {
                    rows.get(lane)
                        .and_then(|row| row.get(first * LANES + j))
                        .copied()
                        .unwrap_or(0.0)
                }))
            }));
            for (values, column) in block.iter_mut().zip(columns) {
                L::set_quarter(values, q, column);
            }
        }
    }
    entries
}

/// The entries of `m`, columns first, each as the array of its lanes.
#[inline(always)]
fn matrix_entries<L: LaneArray>(m: LaneMat3<L>) -> [L::Array; 9] {
    let (c0, c1, c2) = (m.c0, m.c1, m.c2);
    [
        c0.x.to_lane_array(),
        c0.y.to_lane_array(),
        c0.z.to_lane_array(),
        c1.x.to_lane_array(),
        c1.y.to_lane_array(),
        c1.z.to_lane_array(),
        c2.x.to_lane_array(),
        c2.y.to_lane_array(),
        c2.z.to_lane_array(),
    ]
}

/// The SVD of the matrix in each lane of `entries` (its entries columns first, each as the
/// array of its lanes), and which lanes had one: a zero or non-finite matrix has no
/// decomposition to run ([`Prescale::of`]); its lane runs on the identity, which keeps every
/// lane finite, and the caller replaces its result by `Svd3::without_decomposition`. The
/// scaling of step 1 is applied and undone in the lanes, with the scalar code's operations in
/// its order (`a * 2^-e_lo * 2^-e_hi`, `sigma * 2^e_lo * 2^e_hi`), so that every decomposed
/// lane gives the bits of [`svd3_sweeps`].
#[inline(always)]
fn decompose_entries<L: LaneArray>(
    mut entries: [L::Array; 9],
    sweeps: u32,
) -> (LaneSvd3<L>, [bool; MAX_GROUP]) {
    const { assert!(L::WIDTH <= MAX_GROUP) };
    let mut decomposed = [false; MAX_GROUP];
    // The largest entry magnitude of every lane's matrix (exact, so in any order), and zero
    // where every entry is finite, NaN where one is not (`0 x`).
    let zero = L::splat(0.0);
    let (mut max_abs, mut non_finite) = (zero, zero);
    for column in &entries {
        let x = L::from_lane_array(*column);
        max_abs = max_abs.max(x.abs());
        non_finite = non_finite + x * zero;
    }
    // Every lane a positive normal `max_abs` and finite entries (`non_finite` is 0 or NaN):
    // the common case, whose factors are formed in the lanes.
    let one = L::splat(1.0);
    let checked = max_abs + non_finite;
    let irregular = L::select(
        checked.ge(L::splat(Real::MIN_POSITIVE)),
        L::select(L::splat(Real::MAX).ge(checked), zero, one),
        one,
    );
    let factors = if L::none(irregular.gt(zero)) {
        for flag in decomposed.iter_mut().take(L::WIDTH) {
            *flag = true;
        }
        prescale_factors(max_abs)
    } else {
        lane_prescale_factors::<L>(max_abs, non_finite, &mut entries, &mut decomposed)
    };
    // Destructured rather than `<[_; N]>::map`, which is not always inlined: a call would run
    // its lane operations outside the function compiled for the wide registers.
    let [down_lo, down_hi, up_lo, up_hi] = factors;
    let down = |column: L::Array| L::from_lane_array(column) * down_lo * down_hi;
    let [a00, a10, a20, a01, a11, a21, a02, a12, a22] = entries;
    let scaled = LaneMat3 {
        c0: LaneVec3::new(down(a00), down(a10), down(a20)),
        c1: LaneVec3::new(down(a01), down(a11), down(a21)),
        c2: LaneVec3::new(down(a02), down(a12), down(a22)),
    };
    let (u, sigma, v) = decompose_scaled(scaled, sweeps);
    let up = |s: L| s * up_lo * up_hi;
    let sigma = LaneVec3::new(up(sigma.x), up(sigma.y), up(sigma.z));
    (LaneSvd3 { u, sigma, v }, decomposed)
}

/// The prescaling factors `[2^-e_lo, 2^-e_hi, 2^e_lo, 2^e_hi]` of [`Prescale::of_max_abs`]
/// (`e` the exponent of `max_abs`, `e_lo = e / 2` rounded toward zero, `e_hi = e - e_lo`) in
/// lanes, for lanes that all hold positive normal numbers. Every step is exact: powers of two,
/// their products and quotients in the normal range, and the square root of `2^e`, which rounds
/// to a value whose exponent is `floor(e / 2)`.
#[inline(always)]
fn prescale_factors<L: LaneArray>(max_abs: L) -> [L; 4] {
    let one = L::splat(1.0);
    let whole = max_abs.exponent_part();
    let floor_half = whole.sqrt().exponent_part();
    let ceil_half = whole / floor_half;
    // `e / 2` rounds toward zero: down for `e >= 0`, up below.
    let non_negative = whole.ge(one);
    let lo = L::select(non_negative, floor_half, ceil_half);
    let hi = L::select(non_negative, ceil_half, floor_half);
    [one / lo, one / hi, lo, hi]
}

/// The prescaling factors of [`decompose_entries`], lane by lane: a lane without a decomposition (zero or non-finite matrix, as `non_finite` and
/// `max_abs` tell) gets the identity in `entries` and factors of one, the others are marked in
/// `decomposed`.
#[inline(always)]
fn lane_prescale_factors<L: LaneArray>(
    max_abs: L,
    non_finite: L,
    entries: &mut [L::Array; 9],
    decomposed: &mut [bool; MAX_GROUP],
) -> [L; 4] {
    let (max_abs, non_finite) = (max_abs.to_lane_array(), non_finite.to_lane_array());
    let mut factors = [L::ZEROS; 4];
    for lane in 0..L::WIDTH {
        let finite = L::lane_value(&non_finite, lane) == 0.0;
        let lane_factors = match Prescale::of_max_abs(L::lane_value(&max_abs, lane), finite) {
            Some(prescale) => {
                if let Some(flag) = decomposed.get_mut(lane) {
                    *flag = true;
                }
                [
                    math::pow2(-prescale.e_lo),
                    math::pow2(-prescale.e_hi),
                    math::pow2(prescale.e_lo),
                    math::pow2(prescale.e_hi),
                ]
            }
            None => {
                set_lane::<L, 9>(entries, lane, Mat3::IDENTITY.to_cols_array());
                [1.0; 4]
            }
        };
        set_lane::<L, 4>(&mut factors, lane, lane_factors);
    }
    let [down_lo, down_hi, up_lo, up_hi] = factors;
    [
        L::from_lane_array(down_lo),
        L::from_lane_array(down_hi),
        L::from_lane_array(up_lo),
        L::from_lane_array(up_hi),
    ]
}

/// [`svd3`](super::svd3) of the matrix in each lane of `a`, in lanes: the principal-path force
/// kernels' decomposition, whose deformation gradients are already in lanes and whose stresses
/// and nodal forces are formed in lanes too. Every lane holds the bits of `svd3` of its matrix.
#[inline(always)]
pub(crate) fn svd3_of_lanes<L: LaneArray>(a: &LaneMat3<L>) -> LaneSvd3<L> {
    let (mut svd, decomposed) = decompose_entries::<L>(matrix_entries(*a), DEFAULT_SWEEPS);
    if decomposed.iter().take(L::WIDTH).all(|&flag| flag) {
        return svd;
    }
    // Rare (a collapsed element, non-finite input): the lanes without a decomposition get what
    // `svd3` returns for them, lane by lane.
    let mut u = matrix_entries(svd.u);
    let mut v = matrix_entries(svd.v);
    let mut sigma = [
        svd.sigma.x.to_lane_array(),
        svd.sigma.y.to_lane_array(),
        svd.sigma.z.to_lane_array(),
    ];
    for (lane, _) in decomposed
        .iter()
        .enumerate()
        .take(L::WIDTH)
        .filter(|(_, d)| !**d)
    {
        let lane_svd = Svd3::without_decomposition(lane_mat3(a, lane));
        set_lane::<L, 9>(&mut u, lane, lane_svd.u.to_cols_array());
        set_lane::<L, 9>(&mut v, lane, lane_svd.v.to_cols_array());
        set_lane::<L, 3>(&mut sigma, lane, lane_svd.sigma.to_array());
    }
    let matrix = |[a00, a10, a20, a01, a11, a21, a02, a12, a22]: [L::Array; 9]| {
        let column = |x, y, z| {
            LaneVec3::new(
                L::from_lane_array(x),
                L::from_lane_array(y),
                L::from_lane_array(z),
            )
        };
        LaneMat3 {
            c0: column(a00, a10, a20),
            c1: column(a01, a11, a21),
            c2: column(a02, a12, a22),
        }
    };
    let [sx, sy, sz] = sigma;
    svd = LaneSvd3 {
        u: matrix(u),
        sigma: LaneVec3::new(
            L::from_lane_array(sx),
            L::from_lane_array(sy),
            L::from_lane_array(sz),
        ),
        v: matrix(v),
    };
    svd
}

//! The AVX2 and AVX-512F instructions of this precision under precision-neutral names, so that
//! `lanes/avx2.rs` and `lanes/avx512.rs` are written once for both precisions.

pub use core::arch::x86_64::{
    __m256 as Reg256, __m512 as Reg512, __mmask16 as Mask512, _mm256_add_ps as add256,
    _mm256_and_ps as and256, _mm256_andnot_ps as andnot256, _mm256_blendv_ps as blendv256,
    _mm256_cmp_ps as cmp256, _mm256_div_ps as div256, _mm256_max_ps as max256,
    _mm256_movemask_ps as movemask256, _mm256_mul_ps as mul256, _mm256_or_ps as or256,
    _mm256_set1_ps as set1_256, _mm256_sqrt_ps as sqrt256, _mm256_sub_ps as sub256,
    _mm256_xor_ps as xor256, _mm512_abs_ps as abs512, _mm512_add_ps as add512,
    _mm512_castps_si512 as to_bits512, _mm512_castsi512_ps as from_bits512,
    _mm512_cmp_ps_mask as cmp512, _mm512_div_ps as div512, _mm512_mask_blend_ps as blend512,
    _mm512_max_ps as max512, _mm512_mul_ps as mul512, _mm512_set1_ps as set1_512,
    _mm512_sqrt_ps as sqrt512, _mm512_sub_ps as sub512,
};
/// Values of this precision per AVX register.
pub const AVX2_WIDTH: usize = 8;
/// Values of this precision per AVX-512 register.
pub const AVX512_WIDTH: usize = 16;

use super::types::Vec3;
use core::arch::x86_64::{
    _mm_loadu_ps, _mm_storeu_ps, _mm256_castpd_ps, _mm256_castps_pd, _mm256_castps128_ps256,
    _mm256_castps256_ps128, _mm256_extractf128_ps, _mm256_insertf128_ps, _mm256_shuffle_ps,
    _mm512_castpd_ps, _mm512_castpd256_pd512, _mm512_castps_pd, _mm512_castps512_ps256,
    _mm512_extractf64x4_pd, _mm512_insertf64x4,
};

/// The immediate of a shuffle taking elements `d0, d1` of its first operand and `d2, d3`
/// of its second (in each 128-bit half), as `_MM_SHUFFLE(d3, d2, d1, d0)`.
const fn shuffle(d3: i32, d2: i32, d1: i32, d0: i32) -> i32 {
    (d3 << 6) | (d2 << 4) | (d1 << 2) | d0
}

/// The first 8 vectors of `chunk` as their x, y and z coordinates in the lanes of three
/// AVX registers (lane `i` holds `chunk[i]`): six 16-byte loads and five shuffles, which
/// move bits only; `None` if `chunk` is shorter. Inlined only where AVX is enabled (the
/// AVX2 and AVX-512 lanes).
#[inline(always)]
pub fn vec3s_256(chunk: &[Vec3]) -> Option<[Reg256; 3]> {
    const { assert!(core::mem::size_of::<Vec3>() == 12) };
    let vectors: &[Vec3; 8] = chunk.first_chunk()?;
    let p = vectors.as_ptr().cast::<f32>();
    // SAFETY: glam's `Vec3` is `repr(C)` of three f32 (12 bytes, asserted), so the 8
    // vectors are 24 contiguous f32 and every load (unaligned) reads within them; AVX is
    // enabled wherever this is inlined.
    unsafe {
        // Per 128-bit half (vectors 0-3 low, 4-7 high): x0 y0 z0 x1, y1 z1 x2 y2,
        // z2 x3 y3 z3.
        let m03 = _mm256_insertf128_ps::<1>(
            _mm256_castps128_ps256(_mm_loadu_ps(p)),
            _mm_loadu_ps(p.add(12)),
        );
        let m14 = _mm256_insertf128_ps::<1>(
            _mm256_castps128_ps256(_mm_loadu_ps(p.add(4))),
            _mm_loadu_ps(p.add(16)),
        );
        let m25 = _mm256_insertf128_ps::<1>(
            _mm256_castps128_ps256(_mm_loadu_ps(p.add(8))),
            _mm_loadu_ps(p.add(20)),
        );
        // x2 y2 x3 y3 and y0 z0 y1 z1.
        let xy = _mm256_shuffle_ps::<{ shuffle(2, 1, 3, 2) }>(m14, m25);
        let yz = _mm256_shuffle_ps::<{ shuffle(1, 0, 2, 1) }>(m03, m14);
        Some([
            _mm256_shuffle_ps::<{ shuffle(2, 0, 3, 0) }>(m03, xy),
            _mm256_shuffle_ps::<{ shuffle(3, 1, 2, 0) }>(yz, xy),
            _mm256_shuffle_ps::<{ shuffle(3, 0, 3, 1) }>(yz, m25),
        ])
    }
}

/// The inverse of [`vec3s_256`]: writes lane `i` of the coordinates `[x, y, z]` as
/// `chunk[i]` for the first 8 vectors (six shuffles and six 16-byte stores); returns
/// `false`, writing nothing, if `chunk` is shorter.
#[inline(always)]
pub fn store_vec3s_256([x, y, z]: [Reg256; 3], chunk: &mut [Vec3]) -> bool {
    const { assert!(core::mem::size_of::<Vec3>() == 12) };
    let Some(vectors) = chunk.first_chunk_mut::<8>() else {
        return false;
    };
    let p = vectors.as_mut_ptr().cast::<f32>();
    // SAFETY: as in `vec3s_256`, for the stores.
    unsafe {
        // Per half: x0 x2 y0 y2, y1 y3 z1 z3, z0 z2 x1 x3.
        let a = _mm256_shuffle_ps::<{ shuffle(2, 0, 2, 0) }>(x, y);
        let b = _mm256_shuffle_ps::<{ shuffle(3, 1, 3, 1) }>(y, z);
        let c = _mm256_shuffle_ps::<{ shuffle(3, 1, 2, 0) }>(z, x);
        // x0 y0 z0 x1, y1 z1 x2 y2, z2 x3 y3 z3.
        let r03 = _mm256_shuffle_ps::<{ shuffle(2, 0, 2, 0) }>(a, c);
        let r14 = _mm256_shuffle_ps::<{ shuffle(3, 1, 2, 0) }>(b, a);
        let r25 = _mm256_shuffle_ps::<{ shuffle(3, 1, 3, 1) }>(c, b);
        _mm_storeu_ps(p, _mm256_castps256_ps128(r03));
        _mm_storeu_ps(p.add(4), _mm256_castps256_ps128(r14));
        _mm_storeu_ps(p.add(8), _mm256_castps256_ps128(r25));
        _mm_storeu_ps(p.add(12), _mm256_extractf128_ps::<1>(r03));
        _mm_storeu_ps(p.add(16), _mm256_extractf128_ps::<1>(r14));
        _mm_storeu_ps(p.add(20), _mm256_extractf128_ps::<1>(r25));
    }
    true
}

/// The first 16 vectors of `chunk` as their coordinates in the lanes of three AVX-512
/// registers: [`vec3s_256`] of each half, side by side; `None` if `chunk` is shorter.
/// Inlined only where AVX-512F is enabled.
#[inline(always)]
pub fn vec3s_512(chunk: &[Vec3]) -> Option<[Reg512; 3]> {
    let (low, high) = chunk.get(..16)?.split_at(8);
    let ([x0, y0, z0], [x1, y1, z1]) = (vec3s_256(low)?, vec3s_256(high)?);
    Some([join(x0, x1), join(y0, y1), join(z0, z1)])
}

/// The inverse of [`vec3s_512`]: `false`, writing nothing, if `chunk` is shorter than 16.
#[inline(always)]
pub fn store_vec3s_512([x, y, z]: [Reg512; 3], chunk: &mut [Vec3]) -> bool {
    let Some((low, high)) = chunk.get_mut(..16).map(|c| c.split_at_mut(8)) else {
        return false;
    };
    let ([x0, x1], [y0, y1], [z0, z1]) = (halves(x), halves(y), halves(z));
    store_vec3s_256([x0, y0, z0], low) && store_vec3s_256([x1, y1, z1], high)
}

/// The AVX-512 register of lanes `low` then `high`.
#[inline(always)]
fn join(low: Reg256, high: Reg256) -> Reg512 {
    // SAFETY: register moves only; AVX-512F is enabled wherever this is inlined.
    unsafe {
        _mm512_castpd_ps(_mm512_insertf64x4::<1>(
            _mm512_castpd256_pd512(_mm256_castps_pd(low)),
            _mm256_castps_pd(high),
        ))
    }
}

/// The low and high halves of `v`.
#[inline(always)]
fn halves(v: Reg512) -> [Reg256; 2] {
    // SAFETY: as in `join`.
    unsafe {
        [
            _mm512_castps512_ps256(v),
            _mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(_mm512_castps_pd(v))),
        ]
    }
}

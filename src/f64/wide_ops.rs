//! The AVX2 and AVX-512F instructions of this precision under precision-neutral names, so that
//! `lanes/avx2.rs` and `lanes/avx512.rs` are written once for both precisions.

pub use core::arch::x86_64::{
    __m256d as Reg256, __m512d as Reg512, __mmask8 as Mask512, _mm256_add_pd as add256,
    _mm256_and_pd as and256, _mm256_andnot_pd as andnot256, _mm256_blendv_pd as blendv256,
    _mm256_cmp_pd as cmp256, _mm256_div_pd as div256, _mm256_max_pd as max256,
    _mm256_movemask_pd as movemask256, _mm256_mul_pd as mul256, _mm256_or_pd as or256,
    _mm256_set1_pd as set1_256, _mm256_sqrt_pd as sqrt256, _mm256_sub_pd as sub256,
    _mm256_xor_pd as xor256, _mm512_abs_pd as abs512, _mm512_add_pd as add512,
    _mm512_castpd_si512 as to_bits512, _mm512_castsi512_pd as from_bits512,
    _mm512_cmp_pd_mask as cmp512, _mm512_div_pd as div512, _mm512_mask_blend_pd as blend512,
    _mm512_max_pd as max512, _mm512_mul_pd as mul512, _mm512_set1_pd as set1_512,
    _mm512_sqrt_pd as sqrt512, _mm512_sub_pd as sub512,
};
/// Values of this precision per AVX register.
pub const AVX2_WIDTH: usize = 4;
/// Values of this precision per AVX-512 register.
pub const AVX512_WIDTH: usize = 8;

use super::types::Vec3;

/// The f32 module's three-register transpose of 8 vectors; in f64 an AVX register holds 4
/// and the 4-lane transposes serve: `None`.
#[inline(always)]
pub fn vec3s_256(_chunk: &[Vec3]) -> Option<[Reg256; 3]> {
    None
}

/// The inverse of [`vec3s_256`]: `false`, nothing written.
#[inline(always)]
pub fn store_vec3s_256(_lanes: [Reg256; 3], _chunk: &mut [Vec3]) -> bool {
    false
}

/// The f32 module's transpose of 16 vectors; here `None`, as [`vec3s_256`].
#[inline(always)]
pub fn vec3s_512(_chunk: &[Vec3]) -> Option<[Reg512; 3]> {
    None
}

/// The inverse of [`vec3s_512`]: `false`, nothing written.
#[inline(always)]
pub fn store_vec3s_512(_lanes: [Reg512; 3], _chunk: &mut [Vec3]) -> bool {
    false
}

//! The folded kernel in AVX2 intrinsics: [`super::row_folded_plain`]'s operations, eight pixels
//! per vector, the same bits.
//!
//! Written for the pipes of the CPU rather than for the fewest instructions. A row goes in
//! blocks of 64 pixels, each in two stages whose eight vectors are independent (so the
//! scheduler always has work): the draws (AES rounds) and their normal deviates (in-register
//! table reads and multiply-adds), then the electrons, the draw and the ADC. The square root
//! and the division of the Cornish–Fisher draw run on the divider, beside the multiply-adds
//! (replacing them by Newton steps on the multiply pipes was measured slower), and the codes
//! are converted and packed with saturation instead of masked and shifted.

use super::{Folded, StaticRow};
use crate::sensor::normal::x86::{aes_level, fix_tail8, normal8, Counter, Keys};
use crate::sensor::normal::NoiseKey;
use std::arch::x86_64::*;

/// Pixels per block: eight vectors per stage.
const BLOCK: usize = 64;

/// [`super::row_folded_plain`] in AVX2 where the CPU has AES-NI (and VAES for eight pixels'
/// rounds per instruction), else the portable kernel.
#[inline]
pub(super) fn row_folded(
    f: &Folded,
    key: &NoiseKey,
    s: [&[f32]; 3],
    st: &StaticRow,
    row: u32,
    out: &mut [u16],
) -> (f32, u16) {
    let (aes, vaes) = aes_level();
    if !aes {
        return super::row_folded_plain(f, key, s, st, row, out);
    }
    // SAFETY: AVX2 and FMA: `simd_dispatch!` runs this arm only where the CPU has them; AES-NI
    // and VAES as detected
    unsafe {
        if vaes {
            row_vaes(f, key, s, st, row, out)
        } else {
            row_aesni(f, key, s, st, row, out)
        }
    }
}

#[target_feature(enable = "avx2,fma,aes,vaes")]
fn row_vaes(
    f: &Folded,
    key: &NoiseKey,
    s: [&[f32]; 3],
    st: &StaticRow,
    row: u32,
    out: &mut [u16],
) -> (f32, u16) {
    // SAFETY: this function's features
    unsafe { row_body::<true>(f, key, s, st, row, out) }
}

#[target_feature(enable = "avx2,fma,aes")]
fn row_aesni(
    f: &Folded,
    key: &NoiseKey,
    s: [&[f32]; 3],
    st: &StaticRow,
    row: u32,
    out: &mut [u16],
) -> (f32, u16) {
    // SAFETY: this function's features
    unsafe { row_body::<false>(f, key, s, st, row, out) }
}

/// # Safety
/// AVX2, FMA and AES-NI (and VAES when `VAES`) must be available.
#[inline(always)]
unsafe fn row_body<const VAES: bool>(
    f: &Folded,
    key: &NoiseKey,
    s: [&[f32]; 3],
    st: &StaticRow,
    row: u32,
    out: &mut [u16],
) -> (f32, u16) {
    let n = out.len();
    let [s0, s1, s2] = s;
    assert!([s0.len(), s1.len(), s2.len()].iter().all(|&l| l >= n));
    assert!([st.g.len(), st.pc.len(), st.ps.len(), st.dsnu.len()]
        .iter()
        .all(|&l| l >= n));
    let whole = n - n % 8;
    // SAFETY: the caller's features; every load and store below lies in 0..whole ≤ n, the
    // lengths asserted above
    let (mut mu_max, mut code_max) = unsafe {
        let keys = Keys::new(key);
        let cf = |v: f32| _mm256_set1_ps(v);
        let mut mx = _mm256_setzero_si256();
        let mut cmx = _mm256_setzero_si256();
        let mut c0 = 0;
        while c0 < whole {
            let nv = (BLOCK.min(whole - c0)) / 8;
            let mut z = [_mm256_setzero_ps(); BLOCK / 8];
            let mut any = _mm256_setzero_si256();
            let mut ctr = Counter::new(row, (c0 / 4) as u32);
            for zj in z.iter_mut().take(nv) {
                let (v, t) = normal8(ctr.next::<VAES>(&keys));
                *zj = v;
                any = _mm256_or_si256(any, t);
            }
            // a quarter of the blocks hold a draw with t < 2⁻⁸: their draws are made again
            // (cheaper than keeping every block's draws)
            if _mm256_testz_si256(any, any) == 0 {
                let mut ctr = Counter::new(row, (c0 / 4) as u32);
                for zj in z.iter_mut().take(nv) {
                    let b = ctr.next::<VAES>(&keys);
                    let (v, t) = normal8(b);
                    if _mm256_testz_si256(t, t) == 0 {
                        *zj = fix_tail8(b, t, v);
                    }
                }
            }
            for (j, &zj) in z.iter().enumerate().take(nv) {
                let c = c0 + 8 * j;
                let ld16 = |p: &[i16]| {
                    let x = _mm_loadu_si128(p.as_ptr().add(c) as *const __m128i);
                    _mm256_cvtepi32_ps(_mm256_cvtepi16_epi32(x))
                };
                let g = _mm_loadu_si128(st.g.as_ptr().add(c) as *const __m128i);
                let g = _mm256_cvtepi32_ps(_mm256_cvtepu16_epi32(g));
                let s0s = _mm256_mul_ps(_mm256_loadu_ps(s0.as_ptr().add(c)), cf(super::S0_SCALE));
                let acc = _mm256_fmadd_ps(ld16(st.pc), _mm256_loadu_ps(s1.as_ptr().add(c)), s0s);
                let acc = _mm256_fmadd_ps(ld16(st.ps), _mm256_loadu_ps(s2.as_ptr().add(c)), acc);
                let acc = _mm256_mul_ps(g, acc);
                let m = _mm256_fmadd_ps(_mm256_max_ps(acc, cf(0.0)), cf(f.k), cf(f.dark));
                mx = _mm256_max_epu32(mx, _mm256_castps_si256(m));
                let var = _mm256_add_ps(m, cf(f.var_r));
                let sd = _mm256_sqrt_ps(var);
                let g6 = _mm256_div_ps(m, _mm256_mul_ps(cf(6.0), var));
                let zz = _mm256_fmadd_ps(zj, zj, cf(-1.0));
                let e = _mm256_fmadd_ps(sd, zj, _mm256_fmadd_ps(g6, zz, m));
                let ds = _mm256_mul_ps(ld16(st.dsnu), cf(super::DSNU_UNIT));
                let v = _mm256_fmadd_ps(cf(f.kg), _mm256_add_ps(e, ds), cf(f.black));
                let code = _mm256_cvtps_epi32(_mm256_min_ps(v, cf(f.maxf)));
                // signed 32 → unsigned 16 bits with saturation: below 0 reads 0
                let packed = _mm256_packus_epi32(code, code);
                cmx = _mm256_max_epu16(cmx, packed);
                let q = _mm256_castsi256_si128(_mm256_permute4x64_epi64(packed, 0b11_01_10_00));
                _mm_storeu_si128(out.as_mut_ptr().add(c) as *mut __m128i, q);
            }
            c0 += nv * 8;
        }
        let (mut a, mut b) = ([0u32; 8], [0u16; 16]);
        _mm256_storeu_si256(a.as_mut_ptr() as *mut __m256i, mx);
        _mm256_storeu_si256(b.as_mut_ptr() as *mut __m256i, cmx);
        (
            a.into_iter().max().unwrap_or(0),
            b.into_iter().max().unwrap_or(0),
        )
    };
    if whole < n {
        // the last pixels, one at a time
        let (m, c) = super::row_folded_cols(f, key, s, st, row, whole, out);
        mu_max = mu_max.max(m);
        code_max = code_max.max(c);
    }
    (f32::from_bits(mu_max), code_max)
}

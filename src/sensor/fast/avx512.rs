//! The folded kernel in AVX-512 intrinsics: [`super::avx2`]'s operations, sixteen pixels per
//! vector, the same bits. Blocks of 128 pixels go in the same two stages (draws and normals,
//! then electrons, the Cornish–Fisher draw and the ADC); the AES rounds take four blocks per
//! instruction and the binade tables are read by one 16-lane permute per coefficient.

use super::{Folded, StaticRow};
use crate::sensor::normal::x86_512::{fix_tail16, normal16, vaes512, Counter, Keys};
use crate::sensor::normal::NoiseKey;
use std::arch::x86_64::*;

/// Pixels per block: eight vectors per stage.
const BLOCK: usize = 128;

/// [`super::row_folded_plain`] in AVX-512 where the CPU has VAES, else the AVX2 kernel.
///
/// # Safety
/// AVX-512F/BW/DQ/VL, AVX2 and FMA must be available (`simd_dispatch!`'s AVX-512 arm).
#[inline]
pub(super) unsafe fn row_folded(
    f: &Folded,
    key: &NoiseKey,
    s: [&[f32]; 3],
    st: &StaticRow,
    row: u32,
    out: &mut [u16],
) -> (f32, u16) {
    if !vaes512() {
        return super::avx2::row_folded(f, key, s, st, row, out);
    }
    // SAFETY: the caller's features, and VAES as detected
    unsafe { row_vaes512(f, key, s, st, row, out) }
}

#[target_feature(enable = "avx512f,avx512bw,avx512dq,avx512vl,avx2,fma,aes,vaes")]
fn row_vaes512(
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
    let whole = n - n % 16;
    // SAFETY: this function's features; every load and store below lies in 0..whole ≤ n, the
    // lengths asserted above
    let (mut mu_max, mut code_max) = unsafe {
        let keys = Keys::new(key);
        let cf = |v: f32| _mm512_set1_ps(v);
        let mut mx = _mm512_setzero_si512();
        let mut cmx = _mm256_setzero_si256();
        let mut c0 = 0;
        while c0 < whole {
            let nv = (BLOCK.min(whole - c0)) / 16;
            let mut z = [_mm512_setzero_ps(); BLOCK / 16];
            let mut any: __mmask16 = 0;
            let mut ctr = Counter::new(row, (c0 / 4) as u32);
            for zj in z.iter_mut().take(nv) {
                let (v, t) = normal16(ctr.next(&keys));
                *zj = v;
                any |= t;
            }
            // blocks holding a draw with t < 2⁻⁸ make their draws again for the tail
            if any != 0 {
                let mut ctr = Counter::new(row, (c0 / 4) as u32);
                for zj in z.iter_mut().take(nv) {
                    let b = ctr.next(&keys);
                    let (v, t) = normal16(b);
                    if t != 0 {
                        *zj = fix_tail16(b, t, v);
                    }
                }
            }
            for (j, &zj) in z.iter().enumerate().take(nv) {
                let c = c0 + 16 * j;
                let ld16 = |p: &[i16]| {
                    let x = _mm256_loadu_si256(p.as_ptr().add(c) as *const __m256i);
                    _mm512_cvtepi32_ps(_mm512_cvtepi16_epi32(x))
                };
                let g = _mm256_loadu_si256(st.g.as_ptr().add(c) as *const __m256i);
                let g = _mm512_cvtepi32_ps(_mm512_cvtepu16_epi32(g));
                let s0s = _mm512_mul_ps(_mm512_loadu_ps(s0.as_ptr().add(c)), cf(super::S0_SCALE));
                let acc = _mm512_fmadd_ps(ld16(st.pc), _mm512_loadu_ps(s1.as_ptr().add(c)), s0s);
                let acc = _mm512_fmadd_ps(ld16(st.ps), _mm512_loadu_ps(s2.as_ptr().add(c)), acc);
                let acc = _mm512_mul_ps(g, acc);
                let m = _mm512_fmadd_ps(_mm512_max_ps(acc, cf(0.0)), cf(f.k), cf(f.dark));
                mx = _mm512_max_epu32(mx, _mm512_castps_si512(m));
                let var = _mm512_add_ps(m, cf(f.var_r));
                let sd = _mm512_sqrt_ps(var);
                let g6 = _mm512_div_ps(m, _mm512_mul_ps(cf(6.0), var));
                let zz = _mm512_fmadd_ps(zj, zj, cf(-1.0));
                let e = _mm512_fmadd_ps(sd, zj, _mm512_fmadd_ps(g6, zz, m));
                let ds = _mm512_mul_ps(ld16(st.dsnu), cf(super::DSNU_UNIT));
                let v = _mm512_fmadd_ps(cf(f.kg), _mm512_add_ps(e, ds), cf(f.black));
                let code = _mm512_cvtps_epi32(_mm512_min_ps(v, cf(f.maxf)));
                // signed 32 → unsigned 16 bits with saturation, as the AVX2 kernel's packus
                let code = _mm512_max_epi32(code, _mm512_setzero_si512());
                let q = _mm512_cvtusepi32_epi16(code);
                cmx = _mm256_max_epu16(cmx, q);
                _mm256_storeu_si256(out.as_mut_ptr().add(c) as *mut __m256i, q);
            }
            c0 += nv * 16;
        }
        (
            _mm512_reduce_max_epu32(mx),
            _mm512_reduce_max_epi32(_mm512_cvtepu16_epi32(cmx)) as u16,
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

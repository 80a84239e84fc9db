//! Standard normal deviates from 32 random bits, for the fast path's noise (`docs/sensor.md`).
//!
//! The top 23 bits k give u = (2k + 1)/2²⁴ in (0, 1), and z = Φ⁻¹(u) by inversion. With
//! t = 1 − |2u − 1| = 2 min(u, 1 − u) (exact in f32), z = ±g(t), g(t) = Φ⁻¹(1 − t/2). g is
//! smooth in t within each binade t ∈ [2^−(j+1), 2^−j): there it is a degree-6 polynomial in the
//! binade's mantissa (coefficients fitted by `tools/fit_normal_binades.py`, absolute error
//! below 8e-7, z up to 4.33 at j = 15; non-decreasing in u over the whole lattice, tested). The
//! binade's 16 coefficient sets are read by index: in AVX-512 one in-register permute per
//! coefficient, in AVX2 two permutes and a blend, instead of a gather. The rare t < 2⁻¹⁶ (1.5e-5
//! of the draws, |z| > 4.33) take Giles' erfinv (M. Giles, "Approximating the erfinv function",
//! GPU Computing Gems Jade, 2011; relative error below 4e-7), which served every draw before:
//! no logarithm and no division for 99.998 % of draws, 30 % less time per normal. Every
//! instruction set gives the same bits (Horner steps are fused multiply-adds everywhere).

use crate::simd::Simd;

/// Keys of one counter-based stream (camera seed, frame, stage).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NoiseKey {
    k1: u32,
    k2: u32,
}

#[inline(always)]
fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// A bijective 32-bit mixer (xor-shift-multiply, constants of C. Wellons' "lowbias32").
#[inline(always)]
fn mix32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

impl NoiseKey {
    /// The stream of `stage` (see [`crate::sensor::noise`]'s stage ids) in frame `frame` of camera `seed`.
    pub fn new(seed: u64, frame: u64, stage: u32) -> Self {
        let h =
            splitmix64(seed ^ splitmix64(frame ^ splitmix64(0x7073_6e73_0000_0000 | stage as u64)));
        NoiseKey {
            k1: h as u32,
            k2: (h >> 32) as u32,
        }
    }
    /// 32 random bits for counter `i` (the pixel index): two keyed rounds of a bijective mixer,
    /// so each frame and stage is a different permutation, not a shifted copy.
    #[inline(always)]
    pub fn bits(&self, i: u32) -> u32 {
        mix32(mix32(i ^ self.k1) ^ self.k2)
    }
    /// The first key word (for the vector hash of [`super::normal`]).
    pub(crate) fn k1(&self) -> u32 {
        self.k1
    }
    /// The second key word.
    pub(crate) fn k2(&self) -> u32 {
        self.k2
    }
}

/// Coefficients of g per binade, highest degree first: `NORMAL_POLY[d][p]` for the binade whose
/// f32 exponent field e (of 2²³ t) has e mod 16 = p, e = 149 − j.
#[rustfmt::skip]
const NORMAL_POLY: [[f32; 16]; 7] = [
    [0.0051333155, 0.0054326486, 0.0057832273, 0.006198508, 0.0066945283, 0.006967597, 0.0035199644, 0.00361928, 0.0037271685, 0.003844897, 0.0039740023, 0.004116366, 0.0042743143, 0.0044507566, 0.0046493723, 0.004874865],
    [-0.009122663, -0.009670805, -0.010315021, -0.01108078, -0.012007609, -0.014107623, -0.0062042177, -0.0063820966, -0.0065755825, -0.0067870216, -0.0070192665, -0.0072758202, -0.00756103, -0.007880351, -0.0082407035, -0.008650971],
    [0.015045342, 0.015992988, 0.017112432, 0.018446364, 0.01998719, 0.018906986, 0.010096354, 0.010393213, 0.010716792, 0.011071216, 0.011461519, 0.011893914, 0.012376154, 0.012918015, 0.013531972, 0.014234108],
    [-0.031115174, -0.03318335, -0.035644703, -0.038640447, -0.042768963, -0.057235252, -0.020554466, -0.021176083, -0.021855304, -0.022601284, -0.023425266, -0.024341203, -0.025366606, -0.0265237, -0.027840996, -0.02935543],
    [0.073878005, 0.07916378, 0.08530636, 0.09189725, 0.09567681, 0.06925981, 0.04753009, 0.049033254, 0.05068243, 0.05250197, 0.054522056, 0.056780513, 0.059325222, 0.06221738, 0.06553568, 0.06938089],
    [-0.25533462, -0.2822418, -0.31905463, -0.37341762, -0.46441594, -0.6592981, -0.14982282, -0.1551033, -0.16096656, -0.16752633, -0.17492957, -0.18337011, -0.19310942, -0.20451008, -0.21809147, -0.2346282],
    [2.2662268, 1.9874278, 1.6759397, 1.3180108, 0.8871465, 0.31863928, 4.2346754, 4.0762067, 3.911953, 3.7412524, 3.5633078, 3.3771458, 3.1815596, 2.9750206, 2.7555487, 2.520502],
];

/// Draws with 2²³ t below this (t < 2⁻¹⁶) take Giles' erfinv.
const TAIL_BELOW: i32 = 128;

/// Pixels per block of the fast path's row kernels and of [`normals_block`]: each stage runs over
/// a whole block, so its vector iterations are independent and the long dependency chains (hash,
/// polynomial) overlap.
pub(crate) const BLOCK: usize = 64;

/// (2²³ t in 1..2²³, the sign bit of z) of 32 random bits: v = 2k + 1 − 2²³ is odd, |v| < 2²³.
#[inline(always)]
fn split(bits: u32) -> (i32, u32) {
    let v = (((bits >> 9) << 1) as i32 + 1) - (1 << 23);
    ((1 << 23) - v.abs(), (v as u32) & 0x8000_0000)
}

/// g(t) for 2²³ t = `t` ≥ [`TAIL_BELOW`]: the binade's polynomial in y = mantissa − 1.5.
#[inline(always)]
fn poly(t: i32) -> f32 {
    let f = (t as f32).to_bits();
    let p = ((f >> 23) & 15) as usize;
    let y = f32::from_bits((f & 0x007f_ffff) | 0x3f80_0000) - 1.5;
    let c = &NORMAL_POLY;
    let mut r = c[0][p];
    for cd in &c[1..] {
        r = r.mul_add(y, cd[p]);
    }
    r
}

/// The uniform (0, 1) value of 32 random bits used by [`normal_from_bits`]: (2k + 1)/2²⁴ with k
/// the top 23 bits, so u and 1 − u are both exact in f32.
#[inline(always)]
pub fn uniform_from_bits(bits: u32) -> f32 {
    (2.0 * (bits >> 9) as f32 + 1.0) * (1.0 / 16_777_216.0)
}

/// Giles' central branch of erfinv(x)/x for w = −ln(1 − x²) < 5.
#[inline(always)]
fn erfinv_central(w: f32) -> f32 {
    let wc = w - 2.5;
    let mut p = 2.810_226_4e-8f32;
    p = p.mul_add(wc, 3.432_739_4e-7);
    p = p.mul_add(wc, -3.523_387_7e-6);
    p = p.mul_add(wc, -4.391_506_5e-6);
    p = p.mul_add(wc, 0.000_218_580_87);
    p = p.mul_add(wc, -0.001_253_725);
    p = p.mul_add(wc, -0.004_177_681_6);
    p = p.mul_add(wc, 0.246_640_73);
    p.mul_add(wc, 1.501_409_4)
}

/// Giles' tail branch of erfinv(x)/x for w ≥ 5.
#[inline(always)]
fn erfinv_tail(w: f32) -> f32 {
    let wt = w.sqrt() - 3.0;
    let mut p = -0.000_200_214_26f32;
    p = p.mul_add(wt, 0.000_100_950_56);
    p = p.mul_add(wt, 0.001_349_343_2);
    p = p.mul_add(wt, -0.003_673_428_4);
    p = p.mul_add(wt, 0.005_739_507_7);
    p = p.mul_add(wt, -0.007_622_461);
    p = p.mul_add(wt, 0.009_438_870_5);
    p = p.mul_add(wt, 1.001_674);
    p.mul_add(wt, 2.832_976_8)
}

/// √2 erfinv(2u − 1) by Giles' approximation, the draws with t < 2⁻¹⁶.
#[inline(always)]
fn giles(bits: u32) -> f32 {
    let a = uniform_from_bits(bits);
    let b = 1.0 - a;
    let x = a - b; // exact
    let w = -crate::vmath::ln_f32(4.0 * a * b);
    let p = if w < 5.0 {
        erfinv_central(w)
    } else {
        erfinv_tail(w)
    };
    std::f32::consts::SQRT_2 * p * x
}

/// A standard normal deviate from 32 random bits by inversion (see the module docs).
///
/// ```
/// use psns::sensor::normal::normal_from_bits;
/// assert!(normal_from_bits(1 << 31).abs() < 1e-6); // u just above ½
/// assert_eq!(normal_from_bits(0), -normal_from_bits(u32::MAX));
/// ```
#[inline(always)]
pub fn normal_from_bits(bits: u32) -> f32 {
    let (t, s) = split(bits);
    if t < TAIL_BELOW {
        giles(bits)
    } else {
        f32::from_bits(poly(t).to_bits() ^ s)
    }
}

/// [`normal_from_bits`] of `key.bits(idx0 + i)` for every i of `z` (at most [`BLOCK`] long),
/// bit-identical, in AVX-512 or AVX2 as `simd` allows (whole vectors: lengths that are multiples
/// of 16 or 8; other lengths draw one at a time).
///
/// # Safety
/// `simd` must not exceed what the CPU has ([`Simd::detected`]); callers pass
/// [`crate::simd::simd`], read once per row. (Reading it here would cost a look-up per block.)
#[inline(always)]
pub(crate) unsafe fn normals_block(key: &NoiseKey, idx0: u32, z: &mut [f32], simd: Simd) {
    debug_assert!(z.len() <= BLOCK);
    let n = z.len().min(BLOCK);
    let z = &mut z[..n];
    // SAFETY: the caller's contract
    if unsafe { poly_block(simd, key, idx0, z) } {
        fix_tail(key, idx0, z);
    }
}

crate::simd_dispatch! {
    /// The polynomial part of [`normals_block`] (draws with t < 2⁻¹⁶ get a placeholder); returns
    /// whether any draw needs the tail.
    #[inline(always)]
    unsafe fn poly_block = {
        avx512: poly_avx512,
        avx2: poly_avx2,
        plain: poly_plain,
    }(simd: Simd; key: &NoiseKey, idx0: u32, z: &mut [f32]) -> bool
}

/// [`poly_block`] one draw at a time.
#[inline(always)]
fn poly_plain(key: &NoiseKey, idx0: u32, z: &mut [f32]) -> bool {
    let mut tail = false;
    for (i, zi) in z.iter_mut().enumerate() {
        let (t, s) = split(key.bits(idx0.wrapping_add(i as u32)));
        tail |= t < TAIL_BELOW;
        *zi = f32::from_bits(poly(t.max(TAIL_BELOW)).to_bits() ^ s);
    }
    tail
}

/// [`poly_block`] in AVX-512 for lengths that are a multiple of 16, else as [`poly_avx2`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
#[inline]
fn poly_avx512(key: &NoiseKey, idx0: u32, z: &mut [f32]) -> bool {
    if z.len().is_multiple_of(16) {
        // SAFETY: this function's features include block_avx512's; the length is asserted there
        unsafe { block_avx512(key.k1(), key.k2(), idx0, z) }
    } else {
        poly_avx2(key, idx0, z)
    }
}

/// [`poly_block`] in AVX2 for lengths that are a multiple of 8, else one draw at a time.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
fn poly_avx2(key: &NoiseKey, idx0: u32, z: &mut [f32]) -> bool {
    if z.len().is_multiple_of(8) {
        // SAFETY: this function's features are block_avx2's; the length is asserted there
        unsafe { block_avx2(key.k1(), key.k2(), idx0, z) }
    } else {
        poly_plain(key, idx0, z)
    }
}

/// Giles' value for the draws of a block with t < 2⁻¹⁶.
#[cold]
fn fix_tail(key: &NoiseKey, idx0: u32, z: &mut [f32]) {
    for (i, zi) in z.iter_mut().enumerate() {
        let b = key.bits(idx0.wrapping_add(i as u32));
        if split(b).0 < TAIL_BELOW {
            *zi = giles(b);
        }
    }
}

/// The polynomial part of [`normals_block`] for a whole block in AVX-512: the hash, t, the binade
/// as a permute index into coefficient registers, Horner with FMA (the same operations, so the
/// same bits, as [`poly`]). Returns whether any draw needs the tail.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn block_avx512(k1: u32, k2: u32, idx0: u32, z: &mut [f32]) -> bool {
    use std::arch::x86_64::*;
    assert!(z.len().is_multiple_of(16));
    let c = |v: u32| _mm512_set1_epi32(v as i32);
    let mix = |x: __m512i| {
        let x = _mm512_xor_si512(x, _mm512_srli_epi32(x, 16));
        let x = _mm512_mullo_epi32(x, c(0x7feb_352d));
        let x = _mm512_xor_si512(x, _mm512_srli_epi32(x, 15));
        let x = _mm512_mullo_epi32(x, c(0x846c_a68b));
        _mm512_xor_si512(x, _mm512_srli_epi32(x, 16))
    };
    // SAFETY: each row of NORMAL_POLY holds the 16 floats read
    let tabs: [__m512; 7] =
        std::array::from_fn(|d| unsafe { _mm512_loadu_ps(NORMAL_POLY[d].as_ptr()) });
    let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let mut tail: u16 = 0;
    for q in 0..z.len() / 16 {
        let i = _mm512_add_epi32(c(idx0.wrapping_add(16 * q as u32)), iota);
        let b = mix(_mm512_xor_si512(mix(_mm512_xor_si512(i, c(k1))), c(k2)));
        let v = _mm512_add_epi32(
            _mm512_slli_epi32(_mm512_srli_epi32(b, 9), 1),
            c((1i32 - (1 << 23)) as u32),
        );
        let t = _mm512_sub_epi32(c(1 << 23), _mm512_abs_epi32(v));
        tail |= _mm512_cmplt_epi32_mask(t, c(TAIL_BELOW as u32));
        let f = _mm512_castps_si512(_mm512_cvtepi32_ps(t));
        let p = _mm512_srli_epi32(f, 23);
        // (f & mantissa) | 1.0
        let m = _mm512_ternarylogic_epi32(f, c(0x007f_ffff), c(0x3f80_0000), 0xea);
        let y = _mm512_sub_ps(_mm512_castsi512_ps(m), _mm512_set1_ps(1.5));
        let mut r = _mm512_permutexvar_ps(p, tabs[0]);
        for tab in &tabs[1..] {
            r = _mm512_fmadd_ps(r, y, _mm512_permutexvar_ps(p, *tab));
        }
        let zs = _mm512_xor_si512(_mm512_castps_si512(r), _mm512_and_si512(v, c(0x8000_0000)));
        // SAFETY: z holds 16 floats at 16q (its length is a multiple of 16, asserted)
        unsafe { _mm512_storeu_ps(z.as_mut_ptr().add(16 * q), _mm512_castsi512_ps(zs)) };
    }
    tail != 0
}

/// [`block_avx512`] in AVX2: a 16-entry table read as two 8-entry permutes and a blend on the
/// index's bit 3.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn block_avx2(k1: u32, k2: u32, idx0: u32, z: &mut [f32]) -> bool {
    use std::arch::x86_64::*;
    assert!(z.len().is_multiple_of(8));
    let c = |v: u32| _mm256_set1_epi32(v as i32);
    let mix = |x: __m256i| {
        let x = _mm256_xor_si256(x, _mm256_srli_epi32(x, 16));
        let x = _mm256_mullo_epi32(x, c(0x7feb_352d));
        let x = _mm256_xor_si256(x, _mm256_srli_epi32(x, 15));
        let x = _mm256_mullo_epi32(x, c(0x846c_a68b));
        _mm256_xor_si256(x, _mm256_srli_epi32(x, 16))
    };
    let tabs: [[__m256; 2]; 7] = std::array::from_fn(|d| {
        let p = NORMAL_POLY[d].as_ptr();
        // SAFETY: each row of NORMAL_POLY holds the 16 floats read
        unsafe { [_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8))] }
    });
    let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let mut tail = 0;
    for q in 0..z.len() / 8 {
        let i = _mm256_add_epi32(c(idx0.wrapping_add(8 * q as u32)), iota);
        let b = mix(_mm256_xor_si256(mix(_mm256_xor_si256(i, c(k1))), c(k2)));
        let v = _mm256_add_epi32(
            _mm256_slli_epi32(_mm256_srli_epi32(b, 9), 1),
            c((1i32 - (1 << 23)) as u32),
        );
        let t = _mm256_sub_epi32(c(1 << 23), _mm256_abs_epi32(v));
        tail |= _mm256_movemask_epi8(_mm256_cmpgt_epi32(c(TAIL_BELOW as u32), t));
        let f = _mm256_castps_si256(_mm256_cvtepi32_ps(t));
        let p = _mm256_srli_epi32(f, 23);
        // bit 3 of the index as a sign bit, for the blends
        let hi = _mm256_castsi256_ps(_mm256_slli_epi32(p, 28));
        let m = _mm256_or_si256(_mm256_and_si256(f, c(0x007f_ffff)), c(0x3f80_0000));
        let y = _mm256_sub_ps(_mm256_castsi256_ps(m), _mm256_set1_ps(1.5));
        let lut = |tab: &[__m256; 2]| {
            _mm256_blendv_ps(
                _mm256_permutevar8x32_ps(tab[0], p),
                _mm256_permutevar8x32_ps(tab[1], p),
                hi,
            )
        };
        let mut r = lut(&tabs[0]);
        for tab in &tabs[1..] {
            r = _mm256_fmadd_ps(r, y, lut(tab));
        }
        let zs = _mm256_xor_si256(_mm256_castps_si256(r), _mm256_and_si256(v, c(0x8000_0000)));
        // SAFETY: z holds 8 floats at 8q (its length is a multiple of 8, asserted)
        unsafe { _mm256_storeu_ps(z.as_mut_ptr().add(8 * q), _mm256_castsi256_ps(zs)) };
    }
    tail != 0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every point of the u lattice (2²³ of them): the binade polynomials agree with Giles'
    /// approximation (itself within 4e-7 relative of Φ⁻¹) to within both errors, and z is
    /// non-decreasing in u, as an inversion must be.
    #[test]
    fn agrees_with_giles_and_is_monotone_on_the_whole_lattice() {
        let (mut worst, mut at, mut prev, mut tails) = (0f32, 0u32, f32::NEG_INFINITY, 0);
        for k in 0..1u32 << 23 {
            let bits = k << 9;
            let (z, zg) = (normal_from_bits(bits), giles(bits));
            let err = (z - zg).abs() / zg.abs().max(1.0);
            if err > worst {
                (worst, at) = (err, k);
            }
            assert!(z >= prev, "z({k}) = {z} < z({}) = {prev}", k - 1);
            prev = z;
            tails += (split(bits).0 < TAIL_BELOW) as u32;
        }
        assert!(worst < 1.5e-6, "k = {at}: {worst}");
        // t < 2⁻¹⁶: 2 · 64 lattice points
        assert_eq!(tails, 128);
    }

    /// The vector blocks give `normal_from_bits`'s bits at every instruction set, for whole
    /// blocks, vector-multiple and odd lengths, blocks holding a draw from each of the 16
    /// binades, and blocks holding tail draws.
    #[test]
    fn blocks_are_normal_from_bits_at_every_instruction_set() {
        let key = NoiseKey::new(3, 5, 1);
        // the first index whose draw lies in binade j (2²³ t in [2^(22−j), 2^(23−j))), j = 0..15,
        // and the first five tail draws
        let (mut binade, mut tails) = ([None; 16], Vec::new());
        for i in 0..8_000_000u32 {
            let t = split(key.bits(i)).0;
            if t < TAIL_BELOW {
                if tails.len() < 5 {
                    tails.push(i);
                }
            } else {
                let j = 22 - t.ilog2() as usize;
                binade[j].get_or_insert(i);
            }
            if tails.len() == 5 && binade.iter().all(|b| b.is_some()) {
                break;
            }
        }
        assert!(tails.len() == 5, "{tails:?}");
        assert!(binade.iter().all(|b| b.is_some()), "{binade:?}");
        let starts = tails
            .iter()
            .chain(binade.iter().flatten())
            .map(|&i| i & !15)
            .chain([0, 17, 1 << 31, u32::MAX - 40]);
        for idx0 in starts {
            for len in [64, 48, 16, 8, 24, 35, 7, 1] {
                let want: Vec<u32> = (0..len)
                    .map(|i| normal_from_bits(key.bits(idx0.wrapping_add(i))).to_bits())
                    .collect();
                for level in Simd::available() {
                    let mut z = vec![0f32; len as usize];
                    // SAFETY: `available` lists only what the CPU has
                    unsafe { normals_block(&key, idx0, &mut z, level) };
                    let got: Vec<u32> = z.iter().map(|v| v.to_bits()).collect();
                    assert_eq!(got, want, "{level:?}, idx0 {idx0}, len {len}");
                }
            }
        }
    }
}

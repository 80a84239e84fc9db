//! Random draws and standard normal deviates for the fast path's noise (`docs/sensor.md`).
//!
//! **Draws.** Pixel (r, c) of a frame's stage takes 32 bits of a counter-based generator in the
//! manner of ARS-5 (Salmon et al., "Parallel random numbers: as easy as 1, 2, 3", SC11; the
//! `ars5` engine of Intel's oneMKL): the 128-bit block (c/4, r, 0, 0) goes through five AES
//! rounds keyed by (camera seed, frame, stage), round key i the first plus i times a fixed odd
//! constant; the block's four 32-bit words are pixels 4⌊c/4⌋ .. 4⌊c/4⌋ + 3. Any pixel's draw is
//! computed on its own, so frames depend neither on threads nor on row order; rows never share
//! a counter, and every frame and stage has its own key (no shifted copies of one table). One
//! AES round is one instruction (`vaesenc` for 8 pixels with VAES, two `aesenc` without);
//! machines without AES-NI take the `aes` crate's constant-time software rounds, the same bits.
//!
//! **Normals.** The top 23 bits k give u = (2k + 1)/2²⁴ in (0, 1) and z = Φ⁻¹(u) by inversion.
//! With x = 2u − 1 and t = 1 − |x| = 2 min(u, 1 − u) (both exact in f32), z = sign(x) g(t):
//! - t ≥ 2⁻⁸ (99.6 % of draws, |z| < 2.66): g is a degree-4 polynomial in the mantissa of t's
//!   binade, one of eight, its coefficients read by an in-register permute (one instruction per
//!   coefficient for eight pixels, no gather, no logarithm);
//! - t < 2⁻⁸: g = Q(√w), w = −ln(t (2 − t)), Q of degree 6, down to the lattice's smallest
//!   t = 2⁻²³ (|z| = 5.3), taken by the blocks that hold such a draw.
//!
//! Coefficients are fitted by `tools/fit_normal.py`: absolute error below 3.2e-5 against Φ⁻¹
//! (an error the ADC cannot show: at the largest noise a 12-bit code can carry, 160 DN, it is
//! 0.005 DN), non-decreasing in u over the whole lattice (tested). Every instruction set gives
//! the same bits: Horner steps are fused multiply-adds everywhere, the rest exact IEEE
//! operations.

use aes::Block;

/// AES rounds per draw (ARS-5).
const ROUNDS: usize = 5;

/// Added to the round key at each round (ARS: the 64-bit golden-ratio constant and √3's).
const ROUND_STEP: [u64; 2] = [0x9e37_79b9_7f4a_7c15, 0xbb67_ae85_84ca_a73b];

/// Keys of one counter-based stream (camera seed, frame, stage): the round keys of its AES rounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NoiseKey {
    /// Round key 0 (XORed into the counter) and the keys of rounds 1..=5, as (low, high) words.
    round: [[u64; 2]; ROUNDS + 1],
}

#[inline(always)]
fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

fn block_of(words: [u64; 2]) -> Block {
    let mut b = [0u8; 16];
    b[..8].copy_from_slice(&words[0].to_le_bytes());
    b[8..].copy_from_slice(&words[1].to_le_bytes());
    Block::from(b)
}

impl NoiseKey {
    /// The stream of `stage` (see [`crate::sensor::noise`]'s stage ids) in frame `frame` of camera `seed`.
    pub fn new(seed: u64, frame: u64, stage: u32) -> Self {
        let h =
            splitmix64(seed ^ splitmix64(frame ^ splitmix64(0x7073_6e73_0000_0000 | stage as u64)));
        let mut round = [[h, splitmix64(h ^ 0x6172_7335)]; ROUNDS + 1];
        for i in 1..=ROUNDS {
            round[i] = [
                round[i - 1][0].wrapping_add(ROUND_STEP[0]),
                round[i - 1][1].wrapping_add(ROUND_STEP[1]),
            ];
        }
        NoiseKey { round }
    }

    /// The draws of pixels 4q .. 4q + 3 of row `row`.
    ///
    /// ```
    /// use psns::sensor::normal::NoiseKey;
    /// let k = NoiseKey::new(1, 0, 1);
    /// assert_eq!(k.block(3, 5)[2], k.bits(3, 22));
    /// assert_ne!(k.block(3, 5), k.block(4, 5));
    /// ```
    pub fn block(&self, row: u32, q: u32) -> [u32; 4] {
        let mut b = block_of([
            (q as u64 | (row as u64) << 32) ^ self.round[0][0],
            self.round[0][1],
        ]);
        for k in &self.round[1..] {
            aes::hazmat::cipher_round(&mut b, &block_of(*k));
        }
        std::array::from_fn(|i| u32::from_le_bytes(b[4 * i..4 * i + 4].try_into().unwrap()))
    }

    /// The draw of pixel `col` of row `row`.
    pub fn bits(&self, row: u32, col: u32) -> u32 {
        self.block(row, col >> 2)[(col & 3) as usize]
    }
}

/// g(t) for t ≥ 2⁻⁸, per binade: `NORMAL8[d][p]` is the coefficient of degree 4 − d for the
/// binade whose f32 exponent field of 2²³ t is 149 − j ≡ p (mod 8), t in [2^−(j+1), 2^−j)
/// (`tools/fit_normal.py`).
#[rustfmt::skip]
const NORMAL8: [[f32; 8]; 5] = [
    [0.016970335, 0.018030232, 0.019281141, 0.020770805, 0.022497639, 0.021519836, 0.015275487, 0.016062181],
    [-0.033966005, -0.036205478, -0.038868144, -0.04210319, -0.04652134, -0.061643887, -0.030416217, -0.032058857],
    [0.07369754, 0.07897279, 0.08510304, 0.091679335, 0.09544145, 0.069014855, 0.06537223, 0.0692095],
    [-0.25515643, -0.2820529, -0.31885317, -0.3732012, -0.46418142, -0.65902257, -0.21793053, -0.23445924],
    [2.2662292, 1.9874305, 1.6759425, 1.3180139, 0.88714975, 0.3186427, 2.755551, 2.5205045],
];

/// ln(1 + f) = f R(f) for 1 + f in [√½, √2): R, highest degree first (`tools/fit_normal.py`).
#[rustfmt::skip]
const LN: [f32; 7] = [0.11449083, -0.18779208, 0.20673835, -0.24898121, 0.33298954, -0.5000145, 1.0000042];

/// Q(s), highest degree first: g = Q(√w) in the tail (`tools/fit_normal.py`).
#[rustfmt::skip]
const TAIL: [f32; 7] = [-6.5658336e-05, 0.00096438185, -0.0039931554, -0.008325856, 0.11963611, 1.0613791, 0.10708853];

/// Draws with 2²³ t below this (t < 2⁻⁸, 0.39 % of draws) take the tail polynomial.
const TAIL_BELOW: i32 = 1 << 15;

/// (v, 2²³ t) of 32 random bits: v = 2k + 1 − 2²³ = 2²³ x is odd, |v| < 2²³, and
/// 2²³ t = 2²³ − |v| in 1..2²³.
#[inline(always)]
fn split(bits: u32) -> (i32, i32) {
    let v = ((bits >> 8) | 1) as i32 - (1 << 23);
    (v, (1 << 23) - v.abs())
}

/// Horner's rule with fused multiply-adds (exactly rounded in every build).
#[inline(always)]
fn horner<const N: usize>(c: &[f32; N], x: f32) -> f32 {
    let mut p = c[0];
    for &ck in &c[1..] {
        p = p.mul_add(x, ck);
    }
    p
}

/// g(t) for 2²³ t = `t` ≥ [`TAIL_BELOW`]: the binade's polynomial in y = mantissa − 1.5.
#[inline(always)]
fn central(t: i32) -> f32 {
    let f = (t as f32).to_bits();
    let p = ((f >> 23) & 7) as usize;
    let y = f32::from_bits((f & 0x007f_ffff) | 0x3f80_0000) - 1.5;
    let mut r = NORMAL8[0][p];
    for c in &NORMAL8[1..] {
        r = r.mul_add(y, c[p]);
    }
    r
}

/// g(t) in the tail: Q(√w), w = −ln(t (2 − t)); t and 2 − t are exact, their product rounds
/// once; the logarithm is e ln 2 + f R(f) with y = 2^e (1 + f), 1 + f in [√½, √2).
#[inline(always)]
fn tail(t: i32) -> f32 {
    let tf = t as f32 * (1.0 / 8_388_608.0);
    let y = tf * (2.0 - tf);
    // moves the mantissas from √2 up into the next binade: 1 + f then lies in [√½, √2)
    let b = y.to_bits().wrapping_add(0x3f80_0000 - 0x3f35_04f3);
    let e = ((b >> 23) as i32 - 127) as f32;
    let f = f32::from_bits((b & 0x007f_ffff) + 0x3f35_04f3) - 1.0;
    let w = -e.mul_add(std::f32::consts::LN_2, horner(&LN, f) * f);
    horner(&TAIL, w.sqrt())
}

/// The uniform (0, 1) value of 32 random bits used by [`normal_from_bits`]: (2k + 1)/2²⁴ with k
/// the top 23 bits, so u and 1 − u are both exact in f32.
#[inline(always)]
pub fn uniform_from_bits(bits: u32) -> f32 {
    (2.0 * (bits >> 9) as f32 + 1.0) * (1.0 / 16_777_216.0)
}

/// A standard normal deviate from 32 random bits by inversion (see the module docs).
///
/// ```
/// use psns::sensor::normal::normal_from_bits;
/// assert!(normal_from_bits(1 << 31).abs() < 3.3e-5); // u just above ½: z = 1.5e-7, within the fit's error
/// assert_eq!(normal_from_bits(0), -normal_from_bits(u32::MAX));
/// assert!((normal_from_bits(0) + 5.3).abs() < 0.01); // the lattice's smallest u
/// ```
#[inline(always)]
pub fn normal_from_bits(bits: u32) -> f32 {
    let (v, t) = split(bits);
    let g = if t < TAIL_BELOW { tail(t) } else { central(t) };
    f32::from_bits(g.to_bits() ^ (v as u32 & 0x8000_0000))
}

/// [`normal_from_bits`] of the draws of pixels `c0 .. c0 + z.len()` of row `row`, one at a time.
fn normals_row_plain(key: &NoiseKey, row: u32, c0: u32, z: &mut [f32]) {
    let (mut c, mut i) = (c0, 0);
    while i < z.len() {
        let b = key.block(row, c >> 2);
        let mut l = (c & 3) as usize;
        while l < 4 && i < z.len() {
            z[i] = normal_from_bits(b[l]);
            (i, l, c) = (i + 1, l + 1, c + 1);
        }
    }
}

crate::simd::simd_dispatch! {
    /// [`normal_from_bits`] of the draws of pixels `c0 .. c0 + z.len()` of row `row`,
    /// vectorised where the CPU has AVX2 and AES-NI; the same bits in every build.
    pub(crate) fn normals_row = {
        avx2: x86::normals_row,
        plain: normals_row_plain,
    }(key: &NoiseKey, row: u32, c0: u32, z: &mut [f32])
}

/// The vector draws and normals of the AVX2 kernels (8 pixels per vector).
#[cfg(target_arch = "x86_64")]
pub(crate) mod x86 {
    use super::*;
    use std::arch::x86_64::*;

    /// Whether the CPU has AES-NI, and VAES (eight pixels' AES rounds in one instruction).
    pub(crate) fn aes_level() -> (bool, bool) {
        static LEVEL: std::sync::OnceLock<(bool, bool)> = std::sync::OnceLock::new();
        *LEVEL.get_or_init(|| {
            use std::arch::is_x86_feature_detected as has;
            (has!("aes"), has!("aes") && has!("vaes"))
        })
    }

    /// A stream's round keys in both 128-bit lanes.
    #[derive(Clone, Copy)]
    pub(crate) struct Keys([__m256i; ROUNDS + 1]);

    impl Keys {
        #[inline(always)]
        pub(crate) fn new(k: &NoiseKey) -> Self {
            // SAFETY: AVX is part of every level these kernels run at
            Keys(std::array::from_fn(|i| unsafe {
                let [lo, hi] = k.round[i];
                _mm256_set_epi64x(hi as i64, lo as i64, hi as i64, lo as i64)
            }))
        }
    }

    /// The counter of a run of draws along a row: blocks (q, row) and (q + 1, row) in the two
    /// 128-bit lanes.
    #[derive(Clone, Copy)]
    pub(crate) struct Counter(__m256i);

    impl Counter {
        /// The counter of pixels 4q .. 4q + 7 of row `row`.
        #[inline(always)]
        pub(crate) fn new(row: u32, q: u32) -> Self {
            let (r, q) = (row as i32, q as i32);
            // SAFETY: AVX is part of every level these kernels run at
            Counter(unsafe { _mm256_setr_epi32(q, r, 0, 0, q + 1, r, 0, 0) })
        }

        /// The draws of the next eight pixels: five AES rounds of the two blocks (`VAES`: one
        /// instruction per round for both, else one per block).
        ///
        /// # Safety
        /// AVX2 and AES-NI (and VAES when `VAES`) must be available.
        #[inline(always)]
        pub(crate) unsafe fn next<const VAES: bool>(&mut self, keys: &Keys) -> __m256i {
            // SAFETY: the caller's contract
            unsafe {
                let mut x = _mm256_xor_si256(self.0, keys.0[0]);
                self.0 = _mm256_add_epi32(self.0, _mm256_setr_epi32(2, 0, 0, 0, 2, 0, 0, 0));
                for k in &keys.0[1..] {
                    x = if VAES {
                        _mm256_aesenc_epi128(x, *k)
                    } else {
                        let (xl, kl) = (_mm256_castsi256_si128(x), _mm256_castsi256_si128(*k));
                        let lo = _mm_aesenc_si128(xl, kl);
                        let hi = _mm_aesenc_si128(
                            _mm256_extracti128_si256(x, 1),
                            _mm256_extracti128_si256(*k, 1),
                        );
                        _mm256_set_m128i(hi, lo)
                    };
                }
                x
            }
        }
    }

    #[repr(align(32))]
    struct Row8([f32; 8]);

    /// [`NORMAL8`] as aligned vectors, for the permutes.
    static TABLES: [Row8; 5] = {
        let mut t = [const { Row8([0.0; 8]) }; 5];
        let mut d = 0;
        while d < 5 {
            t[d] = Row8(NORMAL8[d]);
            d += 1;
        }
        t
    };

    /// [`normal_from_bits`] of eight draws, the binade polynomial only, and the lanes (all
    /// bits set) that need the tail instead.
    ///
    /// # Safety
    /// AVX2 and FMA must be available.
    #[inline(always)]
    pub(crate) unsafe fn normal8(bits: __m256i) -> (__m256, __m256i) {
        // SAFETY: the caller's contract; the tables are 32-byte aligned
        unsafe {
            let c = |v: i32| _mm256_set1_epi32(v);
            let v = _mm256_sub_epi32(
                _mm256_or_si256(_mm256_srli_epi32(bits, 8), c(1)),
                c(1 << 23),
            );
            let t = _mm256_sub_epi32(c(1 << 23), _mm256_abs_epi32(v));
            let f = _mm256_cvtepi32_ps(t);
            let p = _mm256_srli_epi32(_mm256_castps_si256(f), 23);
            let mant = _mm256_and_ps(f, _mm256_castsi256_ps(c(0x007f_ffff)));
            let y = _mm256_sub_ps(_mm256_or_ps(mant, _mm256_set1_ps(1.0)), _mm256_set1_ps(1.5));
            let tab = |d: usize| _mm256_load_ps(TABLES[d].0.as_ptr());
            let mut r = _mm256_permutevar8x32_ps(tab(0), p);
            for d in 1..5 {
                r = _mm256_fmadd_ps(r, y, _mm256_permutevar8x32_ps(tab(d), p));
            }
            let sign = _mm256_castsi256_ps(_mm256_and_si256(v, c(i32::MIN)));
            (_mm256_xor_ps(r, sign), _mm256_cmpgt_epi32(c(TAIL_BELOW), t))
        }
    }

    /// The tail values of the lanes of `z` marked in `tail`, from the draws `bits` (the same
    /// operations as [`super::tail`], eight at a time).
    ///
    /// # Safety
    /// AVX2 and FMA must be available.
    #[inline(always)]
    pub(crate) unsafe fn fix_tail8(bits: __m256i, tail: __m256i, z: __m256) -> __m256 {
        // SAFETY: the caller's contract
        unsafe {
            let c = |v: i32| _mm256_set1_epi32(v);
            let cf = |v: f32| _mm256_set1_ps(v);
            let v = _mm256_sub_epi32(
                _mm256_or_si256(_mm256_srli_epi32(bits, 8), c(1)),
                c(1 << 23),
            );
            let t = _mm256_sub_epi32(c(1 << 23), _mm256_abs_epi32(v));
            let tf = _mm256_mul_ps(_mm256_cvtepi32_ps(t), cf(1.0 / 8_388_608.0));
            let y = _mm256_mul_ps(tf, _mm256_sub_ps(cf(2.0), tf));
            let b = _mm256_add_epi32(
                _mm256_castps_si256(y),
                c((0x3f80_0000u32 - 0x3f35_04f3) as i32),
            );
            let e = _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_srli_epi32(b, 23), c(127)));
            let m = _mm256_add_epi32(_mm256_and_si256(b, c(0x007f_ffff)), c(0x3f35_04f3));
            let f = _mm256_sub_ps(_mm256_castsi256_ps(m), cf(1.0));
            let mut r = cf(LN[0]);
            for &k in &LN[1..] {
                r = _mm256_fmadd_ps(r, f, cf(k));
            }
            let lny = _mm256_fmadd_ps(e, cf(std::f32::consts::LN_2), _mm256_mul_ps(r, f));
            let s = _mm256_sqrt_ps(_mm256_xor_ps(lny, cf(-0.0)));
            let mut q = cf(TAIL[0]);
            for &k in &TAIL[1..] {
                q = _mm256_fmadd_ps(q, s, cf(k));
            }
            let zt = _mm256_xor_ps(q, _mm256_castsi256_ps(_mm256_and_si256(v, c(i32::MIN))));
            _mm256_blendv_ps(z, zt, _mm256_castsi256_ps(tail))
        }
    }

    /// [`super::normals_row`] in AVX2: whole vectors where the columns allow, the rest one at a
    /// time.
    #[inline]
    pub(crate) fn normals_row(key: &NoiseKey, row: u32, c0: u32, z: &mut [f32]) {
        let (aes, vaes) = aes_level();
        if !aes {
            return super::normals_row_plain(key, row, c0, z);
        }
        // SAFETY: AVX2 and FMA: this arm of `simd_dispatch!` runs only where the CPU has them;
        // AES-NI and VAES as detected
        unsafe {
            if vaes {
                normals_row_vaes(key, row, c0, z)
            } else {
                normals_row_aesni(key, row, c0, z)
            }
        }
    }

    #[target_feature(enable = "avx2,fma,aes,vaes")]
    fn normals_row_vaes(key: &NoiseKey, row: u32, c0: u32, z: &mut [f32]) {
        // SAFETY: this function's features
        unsafe { normals_row_body::<true>(key, row, c0, z) }
    }

    #[target_feature(enable = "avx2,fma,aes")]
    fn normals_row_aesni(key: &NoiseKey, row: u32, c0: u32, z: &mut [f32]) {
        // SAFETY: this function's features
        unsafe { normals_row_body::<false>(key, row, c0, z) }
    }

    #[inline(always)]
    unsafe fn normals_row_body<const VAES: bool>(key: &NoiseKey, row: u32, c0: u32, z: &mut [f32]) {
        // the vectors start on a block boundary
        let head = ((4 - (c0 & 3)) & 3).min(z.len() as u32) as usize;
        super::normals_row_plain(key, row, c0, &mut z[..head]);
        let (c0, z) = (c0 + head as u32, &mut z[head..]);
        let keys = Keys::new(key);
        let mut chunks = z.chunks_exact_mut(8);
        let mut c = c0;
        let mut ctr = Counter::new(row, c0 >> 2);
        for out in &mut chunks {
            // SAFETY: the caller's features; `out` holds 8 floats
            unsafe {
                let b = ctr.next::<VAES>(&keys);
                let (mut v, tail) = normal8(b);
                if _mm256_testz_si256(tail, tail) == 0 {
                    v = fix_tail8(b, tail, v);
                }
                _mm256_storeu_ps(out.as_mut_ptr(), v);
            }
            c += 8;
        }
        super::normals_row_plain(key, row, c, chunks.into_remainder());
    }
}

/// The vector draws and normals of the AVX-512 kernel (16 pixels per vector): the operations of
/// [`x86`], twice as wide, the same bits.
#[cfg(target_arch = "x86_64")]
pub(crate) mod x86_512 {
    use super::*;
    use std::arch::x86_64::*;

    /// Whether the CPU has VAES with AVX-512 (sixteen pixels' AES rounds in one instruction).
    pub(crate) fn vaes512() -> bool {
        static LEVEL: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *LEVEL.get_or_init(|| {
            use std::arch::is_x86_feature_detected as has;
            has!("aes") && has!("vaes") && has!("avx512f")
        })
    }

    /// A stream's round keys in the four 128-bit lanes.
    #[derive(Clone, Copy)]
    pub(crate) struct Keys([__m512i; ROUNDS + 1]);

    impl Keys {
        /// # Safety
        /// AVX-512F must be available.
        #[inline(always)]
        pub(crate) unsafe fn new(k: &NoiseKey) -> Self {
            // SAFETY: the caller's contract
            Keys(std::array::from_fn(|i| unsafe {
                let [lo, hi] = k.round[i];
                let (lo, hi) = (lo as i64, hi as i64);
                _mm512_set_epi64(hi, lo, hi, lo, hi, lo, hi, lo)
            }))
        }
    }

    /// The counter of a run of draws along a row: blocks (q .. q + 3, row) in the four lanes.
    #[derive(Clone, Copy)]
    pub(crate) struct Counter(__m512i);

    impl Counter {
        /// The counter of pixels 4q .. 4q + 15 of row `row`.
        ///
        /// # Safety
        /// AVX-512F must be available.
        #[inline(always)]
        pub(crate) unsafe fn new(row: u32, q: u32) -> Self {
            let (r, q) = (row as i32, q as i32);
            // SAFETY: the caller's contract
            Counter(unsafe {
                _mm512_setr_epi32(q, r, 0, 0, q + 1, r, 0, 0, q + 2, r, 0, 0, q + 3, r, 0, 0)
            })
        }

        /// The draws of the next sixteen pixels: five AES rounds of the four blocks.
        ///
        /// # Safety
        /// AVX-512F and VAES must be available.
        #[inline(always)]
        pub(crate) unsafe fn next(&mut self, keys: &Keys) -> __m512i {
            // SAFETY: the caller's contract
            unsafe {
                let mut x = _mm512_xor_si512(self.0, keys.0[0]);
                let step = _mm512_setr_epi32(4, 0, 0, 0, 4, 0, 0, 0, 4, 0, 0, 0, 4, 0, 0, 0);
                self.0 = _mm512_add_epi32(self.0, step);
                for k in &keys.0[1..] {
                    x = _mm512_aesenc_epi128(x, *k);
                }
                x
            }
        }
    }

    #[repr(align(64))]
    struct Row16([f32; 16]);

    /// [`NORMAL8`] twice over, for the 16-lane permutes (which read four index bits).
    static TABLES: [Row16; 5] = {
        let mut t = [const { Row16([0.0; 16]) }; 5];
        let mut d = 0;
        while d < 5 {
            let mut i = 0;
            while i < 16 {
                t[d].0[i] = NORMAL8[d][i & 7];
                i += 1;
            }
            d += 1;
        }
        t
    };

    /// (v, 2²³ t) of sixteen draws, as [`super::split`].
    #[inline(always)]
    unsafe fn split16(bits: __m512i) -> (__m512i, __m512i) {
        // SAFETY: the caller's contract (AVX-512F)
        unsafe {
            let c = |v: i32| _mm512_set1_epi32(v);
            let v = _mm512_sub_epi32(
                _mm512_or_si512(_mm512_srli_epi32(bits, 8), c(1)),
                c(1 << 23),
            );
            (v, _mm512_sub_epi32(c(1 << 23), _mm512_abs_epi32(v)))
        }
    }

    /// [`x86::normal8`] of sixteen draws, and the lanes that need the tail instead.
    ///
    /// # Safety
    /// AVX-512F and FMA must be available.
    #[inline(always)]
    pub(crate) unsafe fn normal16(bits: __m512i) -> (__m512, __mmask16) {
        // SAFETY: the caller's contract; the tables are 64-byte aligned
        unsafe {
            let c = |v: i32| _mm512_set1_epi32(v);
            let (v, t) = split16(bits);
            let f = _mm512_cvtepi32_ps(t);
            let p = _mm512_srli_epi32(_mm512_castps_si512(f), 23);
            let mant = _mm512_and_si512(_mm512_castps_si512(f), c(0x007f_ffff));
            let y = _mm512_sub_ps(
                _mm512_castsi512_ps(_mm512_or_si512(mant, c(0x3f80_0000))),
                _mm512_set1_ps(1.5),
            );
            let tab = |d: usize| _mm512_load_ps(TABLES[d].0.as_ptr());
            let mut r = _mm512_permutexvar_ps(p, tab(0));
            for d in 1..5 {
                r = _mm512_fmadd_ps(r, y, _mm512_permutexvar_ps(p, tab(d)));
            }
            let sign = _mm512_and_si512(v, c(i32::MIN));
            let z = _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(r), sign));
            (z, _mm512_cmpgt_epi32_mask(c(TAIL_BELOW), t))
        }
    }

    /// [`x86::fix_tail8`] of sixteen draws: the tail values of the lanes in `tail`.
    ///
    /// # Safety
    /// AVX-512F and FMA must be available.
    #[inline(always)]
    pub(crate) unsafe fn fix_tail16(bits: __m512i, tail: __mmask16, z: __m512) -> __m512 {
        // SAFETY: the caller's contract
        unsafe {
            let c = |v: i32| _mm512_set1_epi32(v);
            let cf = |v: f32| _mm512_set1_ps(v);
            let (v, t) = split16(bits);
            let tf = _mm512_mul_ps(_mm512_cvtepi32_ps(t), cf(1.0 / 8_388_608.0));
            let y = _mm512_mul_ps(tf, _mm512_sub_ps(cf(2.0), tf));
            let b = _mm512_add_epi32(
                _mm512_castps_si512(y),
                c((0x3f80_0000u32 - 0x3f35_04f3) as i32),
            );
            let e = _mm512_cvtepi32_ps(_mm512_sub_epi32(_mm512_srli_epi32(b, 23), c(127)));
            let m = _mm512_add_epi32(_mm512_and_si512(b, c(0x007f_ffff)), c(0x3f35_04f3));
            let f = _mm512_sub_ps(_mm512_castsi512_ps(m), cf(1.0));
            let mut r = cf(LN[0]);
            for &k in &LN[1..] {
                r = _mm512_fmadd_ps(r, f, cf(k));
            }
            let lny = _mm512_fmadd_ps(e, cf(std::f32::consts::LN_2), _mm512_mul_ps(r, f));
            let neg = _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(lny), c(i32::MIN)));
            let s = _mm512_sqrt_ps(neg);
            let mut q = cf(TAIL[0]);
            for &k in &TAIL[1..] {
                q = _mm512_fmadd_ps(q, s, cf(k));
            }
            let sign = _mm512_and_si512(v, c(i32::MIN));
            let zt = _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(q), sign));
            _mm512_mask_blend_ps(tail, z, zt)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{with_simd, Simd};

    // Giles' single-precision erfinv (M. Giles, "Approximating the erfinv function", GPU
    // Computing Gems Jade, 2011; relative error below 4e-7), the independent reference.
    fn giles(bits: u32) -> f32 {
        let a = uniform_from_bits(bits);
        let b = 1.0 - a;
        let x = a - b;
        let w = -(4.0 * a as f64 * b as f64).ln() as f32;
        let p = if w < 5.0 {
            let wc = w - 2.5;
            [
                3.432_739_4e-7,
                -3.523_387_7e-6,
                -4.391_506_5e-6,
                0.000_218_580_87,
                -0.001_253_725,
                -0.004_177_681_6,
                0.246_640_73,
                1.501_409_4,
            ]
            .iter()
            .fold(2.810_226_4e-8f32, |p, &c| p.mul_add(wc, c))
        } else {
            let wt = w.sqrt() - 3.0;
            [
                0.000_100_950_56,
                0.001_349_343_2,
                -0.003_673_428_4,
                0.005_739_507_7,
                -0.007_622_461,
                0.009_438_870_5,
                1.001_674,
                2.832_976_8,
            ]
            .iter()
            .fold(-0.000_200_214_26f32, |p, &c| p.mul_add(wt, c))
        };
        std::f32::consts::SQRT_2 * p * x
    }

    /// Every point of the u lattice (2²³ of them): z agrees with Giles' approximation to within
    /// both errors, and is non-decreasing in u, as an inversion must be.
    #[test]
    fn agrees_with_giles_and_is_monotone_on_the_whole_lattice() {
        let (mut worst, mut at, mut prev, mut tails) = (0f32, 0u32, f32::NEG_INFINITY, 0);
        for k in 0..1u32 << 23 {
            let bits = k << 9;
            let (z, zg) = (normal_from_bits(bits), giles(bits));
            let err = (z - zg).abs();
            if err > worst {
                (worst, at) = (err, k);
            }
            assert!(z >= prev, "z({k}) = {z} < z({}) = {prev}", k - 1);
            prev = z;
            tails += (split(bits).1 < TAIL_BELOW) as u32;
        }
        assert!(worst < 3.5e-5, "k = {at}: {worst}");
        // t < 2⁻⁸: 2 · 2¹⁴ lattice points
        assert_eq!(tails, 1 << 15);
    }

    fn row_at(key: &NoiseKey, row: u32, c0: u32, z: &mut [f32]) {
        normals_row(key, row, c0, z)
    }

    /// Rows of draws give `normal_from_bits`'s bits at every instruction set, from any column
    /// and of any length, with and without tail draws; the vector AES rounds are the scalar ones.
    #[test]
    fn rows_are_normal_from_bits_at_every_instruction_set() {
        let key = NoiseKey::new(3, 5, 1);
        for row in [0u32, 1, 7, 2047, 65_535] {
            for (c0, len) in [
                (0u32, 2448usize),
                (0, 64),
                (4, 37),
                (3, 1),
                (13, 100),
                (0, 7),
            ] {
                let want: Vec<u32> = (0..len as u32)
                    .map(|i| normal_from_bits(key.bits(row, c0 + i)).to_bits())
                    .collect();
                for level in Simd::available() {
                    let mut z = vec![0f32; len];
                    with_simd(level, || row_at(&key, row, c0, &mut z));
                    let got: Vec<u32> = z.iter().map(|v| v.to_bits()).collect();
                    assert_eq!(got, want, "{level:?}, row {row}, c0 {c0}, len {len}");
                }
            }
        }
        // a long row holds many tail draws
        let tails = (0..2448u32)
            .filter(|&c| split(key.bits(0, c)).1 < TAIL_BELOW)
            .count();
        assert!(tails > 0);
    }

    /// The four words of a block are four draws: distinct, and different in the next block,
    /// row, frame and stage.
    #[test]
    fn keys_and_counters_give_different_draws() {
        let a = NoiseKey::new(1, 0, 1);
        assert_ne!(a, NoiseKey::new(1, 1, 1));
        assert_ne!(a, NoiseKey::new(1, 0, 2));
        assert_ne!(a, NoiseKey::new(2, 0, 1));
        let b = a.block(0, 0);
        assert!(b
            .iter()
            .enumerate()
            .all(|(i, x)| b[i + 1..].iter().all(|y| y != x)));
        assert_ne!(b, a.block(0, 1));
        assert_ne!(b, a.block(1, 0));
        assert_ne!(b, NoiseKey::new(1, 1, 1).block(0, 0));
    }
}

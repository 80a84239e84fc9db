//! ChaCha8 streams for the exact sensor path's row loops: word for word the stream of
//! `rand_chacha::ChaCha8Rng` with the same key (tested), with a 16-block buffer filled by an
//! AVX-512 kernel where the CPU has one (16 blocks at once, ~4 instructions per 64-bit draw against
//! ~12 for `rand_chacha`'s 4-block AVX2 kernel) and by `rand_chacha`'s own core otherwise, and a
//! draw that stays inline.

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Words in the buffer: 16 ChaCha blocks.
const WORDS: usize = 256;

/// A ChaCha8 stream with zero nonce, the generator of [`crate::rng`].
#[derive(Clone)]
pub(crate) struct Stream {
    buf: [u32; WORDS],
    /// Next unread word (`WORDS` = empty), as `rand_core`'s `BlockRng`.
    idx: usize,
    /// The key words and the next block's counter.
    key: [u32; 8],
    block: u64,
}

impl Stream {
    /// The stream of key `key` (`rand_chacha::ChaCha8Rng::from_seed(key)`).
    pub(crate) fn new(key: [u8; 32]) -> Self {
        let mut k = [0u32; 8];
        for (w, b) in k.iter_mut().zip(key.chunks_exact(4)) {
            *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        Stream {
            buf: [0; WORDS],
            idx: WORDS,
            key: k,
            block: 0,
        }
    }

    #[inline(never)]
    fn refill(&mut self) {
        blocks16(&self.key, self.block, &mut self.buf);
        self.block = self.block.wrapping_add(16);
        self.idx = 0;
    }
}

crate::simd_dispatch! {
    /// Blocks `block..block + 16` of `key` (zero nonce), block-major into `out`.
    fn blocks16 = {
        avx512: blocks16_avx512,
        plain: blocks16_core,
    }(key: &[u32; 8], block: u64, out: &mut [u32; WORDS])
}

/// [`blocks16`] by `rand_chacha`'s own core.
fn blocks16_core(key: &[u32; 8], block: u64, out: &mut [u32; WORDS]) {
    let mut seed = [0u8; 32];
    for (b, w) in seed.chunks_exact_mut(4).zip(key) {
        b.copy_from_slice(&w.to_le_bytes());
    }
    let mut rng = ChaCha8Rng::from_seed(seed);
    rng.set_word_pos(16 * u128::from(block));
    for w in out.iter_mut() {
        *w = rng.next_u32();
    }
}

impl RngCore for Stream {
    #[inline(always)]
    fn next_u32(&mut self) -> u32 {
        if self.idx >= WORDS {
            self.refill();
        }
        let v = self.buf[self.idx];
        self.idx += 1;
        v
    }

    /// Two words, low first; across a refill the last word and the new first one (`BlockRng`).
    #[inline(always)]
    fn next_u64(&mut self) -> u64 {
        let i = self.idx;
        if i < WORDS - 1 {
            self.idx = i + 2;
            return u64::from(self.buf[i]) | (u64::from(self.buf[i + 1]) << 32);
        }
        let lo = self.next_u32();
        lo as u64 | ((self.next_u32() as u64) << 32)
    }

    /// Whole words in order, the last one consumed even if only partly used (`BlockRng`).
    fn fill_bytes(&mut self, dest: &mut [u8]) {
        for chunk in dest.chunks_mut(4) {
            let w = self.next_u32().to_le_bytes();
            chunk.copy_from_slice(&w[..chunk.len()]);
        }
    }
}

/// ChaCha with 4 double rounds of blocks `block..block + 16` of `key` (zero nonce), block-major
/// into `out`: one block's state word per 32-bit lane, 16 blocks per vector.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn blocks16_avx512(key: &[u32; 8], block: u64, out: &mut [u32; WORDS]) {
    use std::arch::x86_64::*;
    let s = |v: u32| _mm512_set1_epi32(v as i32);
    let lanes = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let lo = _mm512_add_epi32(s(block as u32), lanes);
    // 64-bit block counter in words 12 (low) and 13: carry where the low word wrapped
    let carry = _mm512_cmplt_epu32_mask(lo, s(block as u32));
    let hi = _mm512_mask_add_epi32(
        s((block >> 32) as u32),
        carry,
        s((block >> 32) as u32),
        s(1),
    );
    let init = [
        s(0x6170_7865),
        s(0x3320_646e),
        s(0x7962_2d32),
        s(0x6b20_6574),
        s(key[0]),
        s(key[1]),
        s(key[2]),
        s(key[3]),
        s(key[4]),
        s(key[5]),
        s(key[6]),
        s(key[7]),
        lo,
        hi,
        s(0),
        s(0),
    ];
    let mut x = init;
    macro_rules! qr {
        ($a:expr, $b:expr, $c:expr, $d:expr) => {
            x[$a] = _mm512_add_epi32(x[$a], x[$b]);
            x[$d] = _mm512_rol_epi32::<16>(_mm512_xor_si512(x[$d], x[$a]));
            x[$c] = _mm512_add_epi32(x[$c], x[$d]);
            x[$b] = _mm512_rol_epi32::<12>(_mm512_xor_si512(x[$b], x[$c]));
            x[$a] = _mm512_add_epi32(x[$a], x[$b]);
            x[$d] = _mm512_rol_epi32::<8>(_mm512_xor_si512(x[$d], x[$a]));
            x[$c] = _mm512_add_epi32(x[$c], x[$d]);
            x[$b] = _mm512_rol_epi32::<7>(_mm512_xor_si512(x[$b], x[$c]));
        };
    }
    for _ in 0..4 {
        qr!(0, 4, 8, 12);
        qr!(1, 5, 9, 13);
        qr!(2, 6, 10, 14);
        qr!(3, 7, 11, 15);
        qr!(0, 5, 10, 15);
        qr!(1, 6, 11, 12);
        qr!(2, 7, 8, 13);
        qr!(3, 4, 9, 14);
    }
    for (v, i) in x.iter_mut().zip(init) {
        *v = _mm512_add_epi32(*v, i);
    }
    // transpose the 16 x 16 words: x[j] lane b (word j of block b) to block b's row
    let mut a = x;
    for j in (0..16).step_by(2) {
        a[j] = _mm512_unpacklo_epi32(x[j], x[j + 1]);
        a[j + 1] = _mm512_unpackhi_epi32(x[j], x[j + 1]);
    }
    // per 128-bit lane L, b[4g + m] holds words 4g..4g + 3 of block 4L + m
    let mut b = a;
    for g in (0..16).step_by(4) {
        b[g] = _mm512_unpacklo_epi64(a[g], a[g + 2]);
        b[g + 1] = _mm512_unpackhi_epi64(a[g], a[g + 2]);
        b[g + 2] = _mm512_unpacklo_epi64(a[g + 1], a[g + 3]);
        b[g + 3] = _mm512_unpackhi_epi64(a[g + 1], a[g + 3]);
    }
    for m in 0..4 {
        let (b0, b1, b2, b3) = (b[m], b[4 + m], b[8 + m], b[12 + m]);
        let c0 = _mm512_shuffle_i32x4::<0b01_00_01_00>(b0, b1);
        let c1 = _mm512_shuffle_i32x4::<0b11_10_11_10>(b0, b1);
        let c2 = _mm512_shuffle_i32x4::<0b01_00_01_00>(b2, b3);
        let c3 = _mm512_shuffle_i32x4::<0b11_10_11_10>(b2, b3);
        let rows = [
            _mm512_shuffle_i32x4::<0b10_00_10_00>(c0, c2),
            _mm512_shuffle_i32x4::<0b11_01_11_01>(c0, c2),
            _mm512_shuffle_i32x4::<0b10_00_10_00>(c1, c3),
            _mm512_shuffle_i32x4::<0b11_01_11_01>(c1, c3),
        ];
        for (l, r) in rows.into_iter().enumerate() {
            let blk = 4 * l + m;
            // SAFETY: 16 words at 16 · blk, blk < 16, inside the 256-word buffer
            unsafe { _mm512_storeu_si512(out.as_mut_ptr().add(16 * blk).cast(), r) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{with_simd, Simd};

    /// Every build's stream is `ChaCha8Rng`'s, through u64 and u32 draws, byte fills and many
    /// refills, and a block counter that carries into its high word.
    #[test]
    fn same_stream_as_rand_chacha() {
        for s in Simd::available() {
            with_simd(s, || {
                for seed in 0..4u8 {
                    let key = [seed.wrapping_mul(37); 32];
                    let (mut a, mut b) = (Stream::new(key), ChaCha8Rng::from_seed(key));
                    for i in 0..20_000 {
                        match i % 97 {
                            0 => assert_eq!(a.next_u32(), b.next_u32()),
                            1 => {
                                let (mut x, mut y) = ([0u8; 7], [0u8; 7]);
                                a.fill_bytes(&mut x);
                                b.fill_bytes(&mut y);
                                assert_eq!(x, y);
                            }
                            _ => {
                                assert_eq!(a.next_u64(), b.next_u64(), "{s:?} seed {seed} draw {i}")
                            }
                        }
                    }
                }
                // a block counter that carries into its high word
                let key = [5u8; 32];
                let (mut a, mut b) = (Stream::new(key), ChaCha8Rng::from_seed(key));
                let start = (1u64 << 32) - 8; // blocks 2^32 - 8 .. 2^32 + 40
                b.set_word_pos(16 * start as u128);
                a.block = start;
                for _ in 0..48 * 8 {
                    assert_eq!(a.next_u64(), b.next_u64(), "counter carry");
                }
            });
        }
    }
}

//! GenICam PFNC pixel packing of the ADC output (`sensor.md` §8).
//!
//! All multi-byte data little-endian, rows top to bottom, no row padding.
//!
//! | format | PFNC code | bytes / px | layout |
//! |---|---|---|---|
//! | Mono8 | 0x01080001 | 1 | code >> (bits − 8); the 8-bit value itself when the sensor outputs 8 bits |
//! | Mono12p | 0x010C0047 | 1.5 | LSB-first bit stream: b0 = P0\[7:0\]; b1 = P0\[11:8\] \| P1\[3:0\]<<4; b2 = P1\[11:4\] |
//! | Mono12Packed | 0x010C0006 | 1.5 | GigE Vision legacy: b0 = P0\[11:4\]; b1 = P0\[3:0\] \| P1\[3:0\]<<4; b2 = P1\[11:4\] |
//! | Mono16 | 0x01100007 | 2 | u16 LE, LSB-aligned; MSB-aligned (<< (16 − bits)) on request |
//!
//! Each format's properties (PFNC name and code, bits per pixel, packing, Mono8's shift of
//! deeper codes, Mono16's MSB alignment, the unpacked word) are one row of
//! [`PixelFormat::info`]; payload sizes, the valid-bits checks, stream recovery, the ROS 2
//! encoding and the GigE ADC depth derive from it.
//!
//! Codes of a 10- or 8-bit sensor sit LSB-aligned in the 12-bit containers. The number of valid
//! bits in a payload ([`bits_valid`]) is 8 for Mono8 and the sensor bit depth otherwise.
//! An odd pixel count in a 12-bit format ends with a half group of two bytes (the first two bytes
//! of the three-byte group).
//!
//! ```
//! use psns::sensor::packing::{pack, PixelFormat};
//! let mut out = Vec::new();
//! pack(&[0xABC, 0x123], 12, PixelFormat::Mono12p, false, &mut out).unwrap();
//! assert_eq!(out, [0xBC, 0x3A, 0x12]);
//! pack(&[0xABC, 0x123], 12, PixelFormat::Mono12Packed, false, &mut out).unwrap();
//! assert_eq!(out, [0xAB, 0x3C, 0x12]);
//! pack(&[0xABC, 0x123], 12, PixelFormat::Mono16, false, &mut out).unwrap();
//! assert_eq!(out, [0xBC, 0x0A, 0x23, 0x01]);
//! ```

use crate::error::{Error, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Output pixel format, identified by its standard GenICam PFNC code and name (never vendor codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum PixelFormat {
    /// 8 bits per pixel.
    Mono8,
    /// 12 bits, PFNC packed (LSB-first bit stream).
    Mono12p,
    /// 12 bits, GigE Vision legacy packing.
    Mono12Packed,
    /// 16-bit little-endian container.
    #[default]
    Mono16,
}

// the command line's names: the PFNC names in lower case
crate::names::name_table!(PixelFormat {
    Mono8 => "mono8",
    Mono12p => "mono12p",
    Mono12Packed => "mono12packed",
    Mono16 => "mono16",
});

/// The word one unpacked code takes: a ROS 2 image's pixel and a numpy array's dtype.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CodeWord {
    /// One byte (`uint8`, ROS 2 `mono8`).
    U8,
    /// Two bytes, little-endian (`uint16`, ROS 2 `mono16`).
    U16,
}

/// The properties of a pixel format ([`PixelFormat::info`], the one table of the formats).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FormatInfo {
    /// PFNC name, e.g. `Mono12p`.
    pub pfnc_name: &'static str,
    /// Standard PFNC code.
    pub pfnc_code: u32,
    /// Bits per pixel in the payload (8, 12 or 16); a payload of n pixels is
    /// ⌈n × bits / 8⌉ bytes.
    pub bits: u8,
    /// Whether deeper codes are shifted down to the format's bits (Mono8, whose payload always
    /// has 8 valid bits); otherwise codes are stored as they are, at most `bits` deep.
    pub shifts_down: bool,
    /// Whether codes may be stored MSB-aligned (Mono16).
    pub msb_alignable: bool,
    /// The word of an unpacked code.
    pub word: CodeWord,
}

impl PixelFormat {
    /// The format's properties: the one table of the formats.
    pub const fn info(self) -> FormatInfo {
        match self {
            PixelFormat::Mono8 => FormatInfo {
                pfnc_name: "Mono8",
                pfnc_code: 0x0108_0001,
                bits: 8,
                shifts_down: true,
                msb_alignable: false,
                word: CodeWord::U8,
            },
            PixelFormat::Mono12p => FormatInfo {
                pfnc_name: "Mono12p",
                pfnc_code: 0x010C_0047,
                bits: 12,
                shifts_down: false,
                msb_alignable: false,
                word: CodeWord::U16,
            },
            PixelFormat::Mono12Packed => FormatInfo {
                pfnc_name: "Mono12Packed",
                pfnc_code: 0x010C_0006,
                bits: 12,
                shifts_down: false,
                msb_alignable: false,
                word: CodeWord::U16,
            },
            PixelFormat::Mono16 => FormatInfo {
                pfnc_name: "Mono16",
                pfnc_code: 0x0110_0007,
                bits: 16,
                shifts_down: false,
                msb_alignable: true,
                word: CodeWord::U16,
            },
        }
    }

    /// Standard PFNC code.
    pub fn pfnc_code(self) -> u32 {
        self.info().pfnc_code
    }

    /// PFNC name, e.g. `Mono12p`.
    pub fn pfnc_name(self) -> &'static str {
        self.info().pfnc_name
    }

    /// Format of a standard PFNC code; vendor codes (high bit set) are rejected.
    pub fn from_pfnc(code: u32) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|f| f.pfnc_code() == code)
            .ok_or_else(|| {
                Error::Format(format!("unsupported PFNC pixel format code {code:#010x}"))
            })
    }

    /// Bits of the container: 8, 12 or 16.
    pub fn container_bits(self) -> u8 {
        self.info().bits
    }

    /// Whether a payload may say it has `bits` valid bits: exactly the format's bits when it
    /// shifts deeper codes down (Mono8), else 1 to the format's bits.
    pub fn bits_valid_ok(self, bits: u16) -> bool {
        let i = self.info();
        if i.shifts_down {
            bits == i.bits as u16
        } else {
            (1..=i.bits as u16).contains(&bits)
        }
    }
}

impl fmt::Display for PixelFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.pfnc_name())
    }
}

impl FromStr for PixelFormat {
    type Err = Error;
    /// Case-insensitive `mono8`, `mono12p`, `mono12packed`, `mono16`.
    fn from_str(s: &str) -> Result<Self> {
        Self::from_name(s).ok_or_else(|| {
            Error::Invalid(format!(
                "pixel format '{s}' is unknown (allowed {})",
                Self::names()
            ))
        })
    }
}

/// Payload bytes of a `width` x `height` frame; `None` on overflow.
pub fn payload_size_checked(fmt: PixelFormat, width: usize, height: usize) -> Option<usize> {
    let n = width.checked_mul(height)?;
    let bits = fmt.info().bits as usize;
    // whole groups of 8 pixels, then the rest: no overflow short of the payload's own
    (n / 8)
        .checked_mul(bits)?
        .checked_add((n % 8 * bits).div_ceil(8))
}

/// The pixel counts whose `fmt` payload is `bytes` bytes (none, one, or two for a packed
/// format's odd and even counts).
pub fn pixel_counts(fmt: PixelFormat, bytes: u64) -> Vec<u64> {
    let bits = fmt.info().bits as u64;
    let n = (bytes as u128 * 8 / bits as u128) as u64;
    [n, n.saturating_add(1)]
        .into_iter()
        .filter(|&k| k.checked_mul(bits).map(|b| b.div_ceil(8)) == Some(bytes))
        .collect()
}

/// Payload bytes of a `width` x `height` frame (2448 x 2048: Mono8 5 013 504, 12-bit 7 520 256,
/// Mono16 10 027 008). Saturates on overflow.
pub fn payload_size(fmt: PixelFormat, width: usize, height: usize) -> usize {
    payload_size_checked(fmt, width, height).unwrap_or(usize::MAX)
}

/// Whether a `fmt` payload (LSB-aligned) is the codes' own bytes, so that a writer can send the
/// code buffer without packing it: Mono16 on a little-endian machine.
pub fn codes_are_payload(fmt: PixelFormat) -> bool {
    fmt.info().bits == 16 && cfg!(target_endian = "little")
}

/// Valid bits of a payload produced from codes of `bit_depth` bits: 8 for Mono8, else `bit_depth`.
pub fn bits_valid(fmt: PixelFormat, bit_depth: u8) -> u8 {
    let i = fmt.info();
    if i.shifts_down {
        i.bits
    } else {
        bit_depth
    }
}

fn check_depth(fmt: PixelFormat, bit_depth: u8, msb_aligned: bool) -> Result<()> {
    let max = fmt.container_bits();
    if bit_depth < 1 || bit_depth > max {
        return Err(Error::OutOfRange {
            name: format!("bit depth for {fmt}"),
            value: bit_depth.to_string(),
            allowed: format!("1..{max}"),
        });
    }
    if msb_aligned && !fmt.info().msb_alignable {
        return Err(Error::Invalid(format!(
            "MSB alignment exists only for Mono16, not {fmt}"
        )));
    }
    Ok(())
}

/// Packs `codes` (values below 2^`bit_depth`) into `out` (resized to the payload size).
/// On an error `out`'s contents are unspecified.
///
/// For Mono8 `bit_depth` may be 8..16 and the top 8 bits are kept; for the 12-bit formats it is
/// 1..12, for Mono16 1..16. `msb_aligned` is allowed only for Mono16.
pub fn pack(
    codes: &[u16],
    bit_depth: u8,
    fmt: PixelFormat,
    msb_aligned: bool,
    out: &mut Vec<u8>,
) -> Result<()> {
    pack_impl(codes, bit_depth, fmt, msb_aligned, out, false).map(|_| ())
}

/// [`pack`], returning also the CRC-32 (IEEE, as [`crc32fast`]) of the packed bytes, taken
/// chunk by chunk right after each chunk is packed (while it is in cache) and combined: the
/// stream's payload CRC without another pass over the payload.
pub fn pack_crc32(
    codes: &[u16],
    bit_depth: u8,
    fmt: PixelFormat,
    msb_aligned: bool,
    out: &mut Vec<u8>,
) -> Result<u32> {
    pack_impl(codes, bit_depth, fmt, msb_aligned, out, true)
}

fn pack_impl(
    codes: &[u16],
    bit_depth: u8,
    fmt: PixelFormat,
    msb_aligned: bool,
    out: &mut Vec<u8>,
    crc32: bool,
) -> Result<u32> {
    // Mono8 accepts deeper codes (shifted down); the others store codes as they are.
    let bits = fmt.info().bits;
    if fmt.info().shifts_down {
        if !(bits..=16).contains(&bit_depth) {
            return Err(Error::OutOfRange {
                name: format!("bit depth for {fmt}"),
                value: bit_depth.to_string(),
                allowed: format!("{bits}..16"),
            });
        }
    } else {
        check_depth(fmt, bit_depth, msb_aligned)?;
    }
    if msb_aligned && !fmt.info().msb_alignable {
        return Err(Error::Invalid(format!(
            "MSB alignment exists only for Mono16, not {fmt}"
        )));
    }
    let limit = 1u32 << bit_depth;
    const CHUNK: usize = 1 << 16;
    // every byte is written below: reuse the buffer without clearing it
    out.resize(payload_size(fmt, codes.len(), 1), 0);
    // chunks of an even number of pixels, so Mono12 pairs never straddle two chunks; each chunk
    // is checked (its codes OR-ed together) in the same pass that packs it, and the position of
    // a code out of range is looked for only in a chunk that has one
    let bytes_per_chunk = payload_size(fmt, CHUNK, 1);
    let chunks: Vec<(Option<usize>, u32)> = out
        .par_chunks_mut(bytes_per_chunk)
        .zip(codes.par_chunks(CHUNK))
        .enumerate()
        .map(|(k, (o, c))| {
            let all = pack_chunk(c, bit_depth, fmt, msb_aligned, o) as u32;
            let bad = (all >= limit)
                .then(|| k * CHUNK + c.iter().position(|&x| x as u32 >= limit).unwrap_or(0));
            (bad, if crc32 { crc32fast::hash(o) } else { 0 })
        })
        .collect();
    let bad = chunks.iter().filter_map(|c| c.0).min();
    if let Some(i) = bad {
        return Err(Error::OutOfRange {
            name: format!("code of pixel {i}"),
            value: codes[i].to_string(),
            allowed: format!("0..{}", limit - 1),
        });
    }
    Ok(if crc32 {
        crc32_of_pieces(
            out.chunks(bytes_per_chunk)
                .zip(&chunks)
                .map(|(o, c)| (c.1, o.len())),
        )
    } else {
        0
    })
}

/// The CRC-32 (as [`crc32fast`]) of consecutive pieces of bytes, from each piece's own CRC-32
/// and length in bytes, in order (pieces checksummed in parallel while they were in cache).
pub(crate) fn crc32_of_pieces(pieces: impl IntoIterator<Item = (u32, usize)>) -> u32 {
    let mut h = crc32fast::Hasher::new();
    for (crc, len) in pieces {
        h.combine(&crc32fast::Hasher::new_with_initial_len(crc, len as u64));
    }
    h.finalize()
}

/// Packs `codes` into exactly `payload_size(fmt, codes.len(), 1)` bytes of `out`; returns all
/// codes OR-ed together (for the range check, in the same pass).
fn pack_chunk(
    codes: &[u16],
    bit_depth: u8,
    fmt: PixelFormat,
    msb_aligned: bool,
    out: &mut [u8],
) -> u16 {
    let mut all = 0u16;
    match fmt {
        PixelFormat::Mono8 => {
            let s = bit_depth - 8;
            for (o, &c) in out.iter_mut().zip(codes) {
                all |= c;
                *o = (c >> s) as u8;
            }
        }
        PixelFormat::Mono12p => {
            // whole blocks of 32 codes in AVX-512 where the CPU has it, the rest below
            let (done, a) = pack12p_blocks(codes, out);
            all |= a;
            let (codes, out) = (&codes[done..], &mut out[done / 2 * 3..]);
            // Mono12p is a little-endian bit stream of 12-bit codes: four codes are the low 48
            // bits of a | b << 12 | c << 24 | d << 36 (codes in range; out of range is an error)
            let quads = codes.len() / 4;
            let (o4, o_rest) = out.split_at_mut(6 * quads);
            for (o, p) in o4.chunks_exact_mut(6).zip(codes.chunks_exact(4)) {
                all |= p[0] | p[1] | p[2] | p[3];
                let w =
                    p[0] as u64 | (p[1] as u64) << 12 | (p[2] as u64) << 24 | (p[3] as u64) << 36;
                o.copy_from_slice(&w.to_le_bytes()[..6]);
            }
            let (codes, out) = (&codes[4 * quads..], o_rest);
            for (o, p) in out.chunks_exact_mut(3).zip(codes.chunks_exact(2)) {
                let (a, b) = (p[0], p[1]);
                all |= a | b;
                o[0] = a as u8;
                o[1] = ((a >> 8) as u8 & 0x0F) | ((b as u8) << 4);
                o[2] = (b >> 4) as u8;
            }
            if codes.len() % 2 == 1 {
                let a = codes[codes.len() - 1];
                all |= a;
                let n = out.len();
                out[n - 2] = a as u8;
                out[n - 1] = (a >> 8) as u8 & 0x0F;
            }
        }
        PixelFormat::Mono12Packed => {
            for (o, p) in out.chunks_exact_mut(3).zip(codes.chunks_exact(2)) {
                let (a, b) = (p[0], p[1]);
                all |= a | b;
                o[0] = (a >> 4) as u8;
                o[1] = (a as u8 & 0x0F) | ((b as u8) << 4);
                o[2] = (b >> 4) as u8;
            }
            if codes.len() % 2 == 1 {
                let a = codes[codes.len() - 1];
                all |= a;
                let n = out.len();
                out[n - 2] = (a >> 4) as u8;
                out[n - 1] = a as u8 & 0x0F;
            }
        }
        PixelFormat::Mono16 => {
            let s = if msb_aligned { 16 - bit_depth } else { 0 };
            for (o, &c) in out.chunks_exact_mut(2).zip(codes) {
                all |= c;
                o.copy_from_slice(&(c << s).to_le_bytes());
            }
        }
    }
    all
}

crate::simd_dispatch! {
    /// Mono12p of the first 32·k codes (k as many whole blocks as fit) into `out`, by AVX-512
    /// when [`simd`](crate::simd::simd) allows it: returns the codes packed (0 otherwise) and
    /// their OR. The bytes are those of the scalar loop (integer operations only; tested).
    fn pack12p_blocks = {
        avx512: pack12p_avx512,
        plain: pack12p_none,
    }(codes: &[u16], out: &mut [u8]) -> (usize, u16)
}

/// No blocks: the scalar loop packs every code.
fn pack12p_none(_: &[u16], _: &mut [u8]) -> (usize, u16) {
    (0, 0)
}

/// [`pack12p_blocks`] in AVX-512 (F, BW): 32 codes (64 bytes) per step. In each 32-bit lane
/// (codes a, b) the 24 bits a | b << 12 are formed, a byte shuffle keeps bytes 0..2 of every lane
/// (12 of each 16), and a dword permutation joins the four 12-byte groups into 48 bytes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw")]
unsafe fn pack12p_avx512(codes: &[u16], out: &mut [u8]) -> (usize, u16) {
    use std::arch::x86_64::*;
    let blocks = (codes.len() / 32).min(out.len() / 48);
    let lo12 = _mm512_set1_epi32(0x0000_0FFF);
    let hi12 = _mm512_set1_epi32(0x00FF_F000);
    // in every 128-bit lane: bytes 0,1,2, 4,5,6, 8,9,10, 12,13,14, then zeros (-1 = 0x80)
    let shuf = _mm512_broadcast_i32x4(_mm_setr_epi8(
        0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1,
    ));
    let perm = _mm512_setr_epi32(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, 15, 15, 15, 15);
    let mut acc = _mm512_setzero_si512();
    for b in 0..blocks {
        // SAFETY: 64 bytes from codes[32b..32b + 32], in bounds by the choice of `blocks`
        let x = unsafe { _mm512_loadu_si512(codes.as_ptr().add(32 * b).cast()) };
        acc = _mm512_or_si512(acc, x);
        let y = _mm512_or_si512(
            _mm512_and_si512(x, lo12),
            _mm512_and_si512(_mm512_srli_epi32::<4>(x), hi12),
        );
        let z = _mm512_permutexvar_epi32(perm, _mm512_shuffle_epi8(y, shuf));
        // SAFETY: at most 48 bytes (masked) to out[48b..48b + 48], in bounds by the choice of
        // `blocks`
        unsafe {
            _mm512_mask_storeu_epi8(out.as_mut_ptr().add(48 * b).cast(), (1u64 << 48) - 1, z)
        };
    }
    let a = _mm512_reduce_or_epi32(acc) as u32;
    (32 * blocks, (a | a >> 16) as u16)
}

/// Unpacks a payload of `width` x `height` pixels into values with `bits_valid` valid bits
/// (LSB-aligned; MSB-aligned Mono16 is shifted back). Mono8 returns the stored bytes.
///
/// Fails when the payload length is not [`payload_size`] or a value exceeds `bits_valid` bits.
pub fn unpack(
    payload: &[u8],
    fmt: PixelFormat,
    bits_valid: u8,
    msb_aligned: bool,
    width: usize,
    height: usize,
) -> Result<Vec<u16>> {
    let mut v = Vec::new();
    unpack_into(payload, fmt, bits_valid, msb_aligned, width, height, &mut v)?;
    Ok(v)
}

/// [`unpack`] into `v` (cleared first; its allocation is reused, so a consumer unpacking frame
/// after frame into the same vector does not fault in fresh pages every frame).
pub fn unpack_into(
    payload: &[u8],
    fmt: PixelFormat,
    bits_valid: u8,
    msb_aligned: bool,
    width: usize,
    height: usize,
    v: &mut Vec<u16>,
) -> Result<()> {
    v.clear();
    check_depth(fmt, bits_valid, msb_aligned)?;
    if !fmt.bits_valid_ok(bits_valid as u16) {
        return Err(Error::Format(format!(
            "{fmt} payload with {bits_valid} valid bits (must be {})",
            fmt.container_bits()
        )));
    }
    let n = width
        .checked_mul(height)
        .ok_or_else(|| Error::Format("frame size overflows".into()))?;
    let need = payload_size(fmt, width, height);
    if payload.len() != need {
        return Err(Error::Format(format!(
            "{fmt} payload of {width} x {height} needs {need} bytes, got {}",
            payload.len()
        )));
    }
    v.reserve(n);
    match fmt {
        PixelFormat::Mono8 => v.extend(payload.iter().map(|&b| b as u16)),
        PixelFormat::Mono12p => {
            for g in payload.chunks(3) {
                v.push(g[0] as u16 | ((g[1] as u16 & 0x0F) << 8));
                if g.len() == 3 {
                    v.push((g[1] >> 4) as u16 | ((g[2] as u16) << 4));
                }
            }
        }
        PixelFormat::Mono12Packed => {
            for g in payload.chunks(3) {
                v.push(((g[0] as u16) << 4) | (g[1] as u16 & 0x0F));
                if g.len() == 3 {
                    v.push((g[1] >> 4) as u16 | ((g[2] as u16) << 4));
                }
            }
        }
        PixelFormat::Mono16 => {
            let s = if msb_aligned { 16 - bits_valid } else { 0 };
            let low_mask = (1u16 << s) - 1;
            // straight-line loops the compiler vectorises; the first offending value is looked
            // up only when there is one (same error as checking value by value)
            v.extend(
                payload
                    .chunks_exact(2)
                    .map(|b| u16::from_le_bytes([b[0], b[1]])),
            );
            if low_mask != 0 {
                if v.iter().fold(0u16, |acc, &w| acc | (w & low_mask)) != 0 {
                    let w = v.iter().find(|&&w| w & low_mask != 0).copied().unwrap_or(0);
                    return Err(Error::Format(format!(
                        "MSB-aligned Mono16 value {w:#06x} has bits set below the {bits_valid} valid bits"
                    )));
                }
                for w in v.iter_mut() {
                    *w >>= s;
                }
            }
        }
    }
    debug_assert_eq!(v.len(), n);
    if bits_valid < 16 {
        let limit = 1u32 << bits_valid;
        let over = v.iter().fold(false, |acc, &c| acc | (c as u32 >= limit));
        if let Some(i) = over
            .then(|| v.iter().position(|&c| c as u32 >= limit))
            .flatten()
        {
            return Err(Error::Format(format!(
                "pixel {i} holds {} which exceeds {bits_valid} valid bits",
                v[i]
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mono12p packs to the same bytes and the same OR of codes in every instruction set the CPU
    /// has (the AVX-512 blocks of 32 codes and the scalar rest), at lengths around the block
    /// size, with codes using all 12 bits; with one code out of range (inside a block or after)
    /// the OR still shows it.
    #[test]
    fn mono12p_blocks_equal_the_scalar_loop() {
        use crate::simd::{with_simd, Simd};
        let levels = Simd::available();
        let mut h = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            h ^= h << 13;
            h ^= h >> 7;
            h ^= h << 17;
            (h >> 20) as u16 & 0x0FFF
        };
        let lens = [
            0usize, 1, 2, 31, 32, 33, 63, 64, 65, 95, 96, 130, 1001, 7345,
        ];
        for &n in &lens {
            for bad in [None, Some(n / 3), Some(n.saturating_sub(1))] {
                let mut codes: Vec<u16> = (0..n).map(|_| next()).collect();
                if let (Some(i), true) = (bad, n > 0) {
                    codes[i] = 0x1234;
                }
                let runs: Vec<(Vec<u8>, u16)> = levels
                    .iter()
                    .map(|&l| {
                        with_simd(l, || {
                            let mut out = vec![0xA5u8; payload_size(PixelFormat::Mono12p, n, 1)];
                            let all = pack_chunk(&codes, 12, PixelFormat::Mono12p, false, &mut out);
                            (out, all)
                        })
                    })
                    .collect();
                // the bytes of a frame with a code out of range are unspecified (pack fails)
                for (l, r) in levels.iter().zip(&runs).skip(1) {
                    assert_eq!(r.1, runs[0].1, "{l:?}, {n} codes, bad {bad:?}: OR");
                    if bad.is_none() {
                        assert_eq!(r.0, runs[0].0, "{l:?}, {n} codes: bytes");
                    }
                }
                let want_or = codes.iter().fold(0, |a, &c| a | c);
                assert_eq!(runs[0].1, want_or, "{n} codes");
            }
        }
    }

    /// The chunk-by-chunk CRC of [`pack_crc32`] is the CRC of the whole payload, in every
    /// format, on lengths around the chunk size (the last chunk short, odd counts), with the same
    /// bytes as [`pack`].
    #[test]
    fn pack_crc32_is_the_payload_crc() {
        let mut h = 0x2545_F491_4F6C_DD1Du64;
        for n in [
            0usize,
            1,
            2,
            1 << 16,
            (1 << 16) + 2,
            3 * (1 << 16) - 6,
            200_001,
        ] {
            let codes: Vec<u16> = (0..n)
                .map(|_| {
                    h ^= h << 13;
                    h ^= h >> 7;
                    h ^= h << 17;
                    (h >> 40) as u16 & 0x0FFF
                })
                .collect();
            for fmt in [
                PixelFormat::Mono8,
                PixelFormat::Mono12p,
                PixelFormat::Mono12Packed,
                PixelFormat::Mono16,
            ] {
                let (mut a, mut b) = (Vec::new(), Vec::new());
                pack(&codes, 12, fmt, false, &mut a).unwrap();
                let crc = pack_crc32(&codes, 12, fmt, false, &mut b).unwrap();
                assert_eq!(a, b, "{fmt} {n}");
                assert_eq!(crc, crc32fast::hash(&a), "{fmt} {n}");
            }
        }
    }

    #[test]
    fn golden_vectors_both_ways() {
        let p = [0xABCu16, 0x123];
        let cases: [(PixelFormat, &[u8]); 3] = [
            (PixelFormat::Mono12p, &[0xBC, 0x3A, 0x12]),
            (PixelFormat::Mono12Packed, &[0xAB, 0x3C, 0x12]),
            (PixelFormat::Mono16, &[0xBC, 0x0A, 0x23, 0x01]),
        ];
        let mut out = Vec::new();
        for (f, bytes) in cases {
            pack(&p, 12, f, false, &mut out).unwrap();
            assert_eq!(out, bytes, "{f}");
            assert_eq!(unpack(bytes, f, 12, false, 2, 1).unwrap(), p, "{f}");
        }
        pack(&p, 12, PixelFormat::Mono8, false, &mut out).unwrap();
        assert_eq!(out, [0xAB, 0x12]);
        pack(&[0xAB, 0x12], 8, PixelFormat::Mono8, false, &mut out).unwrap();
        assert_eq!(out, [0xAB, 0x12]);
        pack(&p, 12, PixelFormat::Mono16, true, &mut out).unwrap();
        assert_eq!(out, [0xC0, 0xAB, 0x30, 0x12]);
        assert_eq!(
            unpack(&out, PixelFormat::Mono16, 12, true, 2, 1).unwrap(),
            p
        );
    }

    #[test]
    fn msb_is_lsb_times_16() {
        let codes: Vec<u16> = (0..4096).collect();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        pack(&codes, 12, PixelFormat::Mono16, false, &mut a).unwrap();
        pack(&codes, 12, PixelFormat::Mono16, true, &mut b).unwrap();
        for (x, y) in a.chunks(2).zip(b.chunks(2)) {
            let (x, y) = (
                u16::from_le_bytes([x[0], x[1]]),
                u16::from_le_bytes([y[0], y[1]]),
            );
            assert_eq!(x as u32 * 16, y as u32);
        }
    }

    #[test]
    fn round_trip_all_formats_odd_and_even() {
        for bd in [8u8, 10, 12] {
            for n in [1usize, 2, 7, 64] {
                let codes: Vec<u16> = (0..n)
                    .map(|i| ((i * 2654435761) % (1 << bd)) as u16)
                    .collect();
                for f in PixelFormat::ALL {
                    let mut out = Vec::new();
                    pack(&codes, bd, f, false, &mut out).unwrap();
                    assert_eq!(out.len(), payload_size(f, n, 1));
                    let bv = bits_valid(f, bd);
                    let back = unpack(&out, f, bv, false, n, 1).unwrap();
                    let want: Vec<u16> = if f == PixelFormat::Mono8 {
                        codes.iter().map(|&c| c >> (bd - 8)).collect()
                    } else {
                        codes.clone()
                    };
                    assert_eq!(back, want, "{f} bd {bd} n {n}");
                }
            }
        }
    }

    /// Each row of the format table agrees with the packing: payload sizes (and their inverse,
    /// every count from 0 to 40 pixels) are the packed lengths, the valid bits are what the
    /// unpacker accepts, MSB alignment is refused where the table says so, the unpacked word
    /// holds the codes, and a code names its format.
    #[test]
    fn the_format_table_agrees_with_the_packing() {
        for f in PixelFormat::ALL {
            let i = f.info();
            assert_eq!(PixelFormat::from_pfnc(i.pfnc_code).unwrap(), f);
            assert_eq!(f.to_string(), i.pfnc_name);
            assert_eq!(f.name(), i.pfnc_name.to_lowercase());
            let depth = if i.shifts_down { 16 } else { i.bits };
            for n in 0..40usize {
                let codes: Vec<u16> = (0..n)
                    .map(|k| (k as u16 * 977) % (1 << (depth - 1)))
                    .collect();
                let mut out = Vec::new();
                pack(&codes, depth, f, false, &mut out).unwrap();
                assert_eq!(out.len(), payload_size(f, n, 1), "{f} n {n}");
                assert!(
                    pixel_counts(f, out.len() as u64).contains(&(n as u64)),
                    "{f} n {n}"
                );
                let bv = bits_valid(f, depth);
                assert!(f.bits_valid_ok(bv as u16));
                let back = unpack(&out, f, bv, false, n, 1).unwrap();
                let word_bits = match i.word {
                    CodeWord::U8 => 8,
                    CodeWord::U16 => 16,
                };
                assert!(back.iter().all(|&c| (c as u32) < 1 << word_bits), "{f}");
                assert_eq!(
                    pack(&codes, depth, f, true, &mut out).is_ok(),
                    i.msb_alignable,
                    "{f}"
                );
            }
            assert_eq!(f.bits_valid_ok(i.bits as u16 - 1), !i.shifts_down, "{f}");
        }
        assert_eq!(pixel_counts(PixelFormat::Mono16, 7), Vec::<u64>::new());
        assert_eq!(pixel_counts(PixelFormat::Mono12p, 8), [5]);
        assert_eq!(pixel_counts(PixelFormat::Mono12p, 9), [6]);
    }

    #[test]
    fn full_frame_sizes() {
        assert_eq!(payload_size(PixelFormat::Mono8, 2448, 2048), 5_013_504);
        assert_eq!(payload_size(PixelFormat::Mono12p, 2448, 2048), 7_520_256);
        assert_eq!(
            payload_size(PixelFormat::Mono12Packed, 2448, 2048),
            7_520_256
        );
        assert_eq!(payload_size(PixelFormat::Mono16, 2448, 2048), 10_027_008);
    }

    #[test]
    fn reports_the_first_code_out_of_range() {
        let mut codes = vec![7u16; 3 * (1 << 16) + 5];
        codes[2 * (1 << 16) + 3] = 4096;
        codes[(1 << 16) + 11] = 5000;
        for f in [
            PixelFormat::Mono12p,
            PixelFormat::Mono12Packed,
            PixelFormat::Mono16,
        ] {
            let e = pack(&codes, 12, f, false, &mut Vec::new()).unwrap_err();
            assert!(
                e.to_string().contains(&format!("pixel {}", (1 << 16) + 11)),
                "{f}: {e}"
            );
        }
        codes[(1 << 16) + 11] = 4095;
        let e = pack(&codes, 12, PixelFormat::Mono12p, false, &mut Vec::new()).unwrap_err();
        assert!(
            e.to_string()
                .contains(&format!("pixel {}", 2 * (1 << 16) + 3)),
            "{e}"
        );
        assert!(pack(
            &codes[..2 * (1 << 16)],
            12,
            PixelFormat::Mono12p,
            false,
            &mut Vec::new()
        )
        .is_ok());
    }

    #[test]
    fn rejects_bad_input() {
        let mut out = Vec::new();
        assert!(pack(&[4096], 12, PixelFormat::Mono12p, false, &mut out).is_err());
        assert!(pack(&[1024], 10, PixelFormat::Mono16, false, &mut out).is_err());
        assert!(pack(&[1], 12, PixelFormat::Mono12p, true, &mut out).is_err());
        assert!(pack(&[1], 13, PixelFormat::Mono12p, false, &mut out).is_err());
        assert!(unpack(&[0; 5], PixelFormat::Mono12p, 12, false, 2, 2).is_err());
        assert!(unpack(&[0x01, 0x00], PixelFormat::Mono16, 12, true, 1, 1).is_err());
        assert!(unpack(&[0xFF, 0xFF], PixelFormat::Mono16, 12, false, 1, 1).is_err());
        assert!(PixelFormat::from_pfnc(0x8108_0001).is_err());
        assert_eq!(
            PixelFormat::from_pfnc(0x010C_0047).unwrap(),
            PixelFormat::Mono12p
        );
        assert_eq!(
            "MONO12PACKED".parse::<PixelFormat>().unwrap(),
            PixelFormat::Mono12Packed
        );
        assert!("mono10".parse::<PixelFormat>().is_err());
    }
}

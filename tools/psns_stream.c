/* psns_stream.c - plain C99 reader for psns raw frame streams, format v1
 * (docs/stream-format.md). One file, no dependencies, little-endian hosts.
 *
 *   cc -std=c99 -O2 -o psns_stream tools/psns_stream.c
 *   psns_stream dump FILE|-          canonical header/frame lines (used by the tests)
 *   psns_stream frame FILE|- N OUT   write frame N's values as raw uint16 little-endian
 *   psns_stream check FILE|-         read every frame as a consumer does: check its CRCs, unpack
 *                                    its values, print "frame INDEX SUM"; damage and an aborted
 *                                    stream on stderr, exit status 1 if there was any
 *   psns_stream crc FILE|-           CRC-32 of the whole input, 8 hex digits (tests the CRC)
 *
 * Reads sequentially with fread (works on files, FIFOs and stdin), validates the file header
 * like Rust's FileHeader::decode, checks both CRCs, and follows the Rust StreamReader
 * (src/stream/reader/): resynchronisation on the next valid header, producer restarts (also
 * inside a record), index gaps and out-of-order indexes. `dump` prints one canonical line per
 * event on stdout; otherwise events are reported on stderr.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* zlib's CRC-32 (reflected polynomial 0xEDB88320, as crc32fast and Python's zlib.crc32), portable
   C99. Slicing by 16: crc_t[k][b] is the CRC register after byte b followed by k zero bytes, so
   sixteen table lookups advance the CRC by sixteen bytes. A long buffer is split in two halves
   whose CRCs are computed side by side (two independent chains of lookups keep the CPU busy) and
   joined with crc32_combine. Measured on a Zen 4 core (gcc -O2): 4.4 GB/s, against 2.2 GB/s for
   slicing by 8 in one chain. Tables are built at start-up (crc_init). */
static uint32_t crc_t[16][256];
static uint32_t crc_x2n[64]; /* x^(2^k) modulo the polynomial, for crc32_combine */

static uint32_t rd32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }

/* a * b modulo the CRC polynomial (bit-reflected, as in zlib's multmodp) */
static uint32_t crc_mulmod(uint32_t a, uint32_t b) {
    uint32_t m = (uint32_t)1 << 31, p = 0;
    for (;;) {
        if (a & m) {
            p ^= b;
            if ((a & (m - 1)) == 0) break;
        }
        m >>= 1;
        b = b & 1 ? (b >> 1) ^ 0xEDB88320u : b >> 1;
    }
    return p;
}
static void crc_init(void) {
    for (uint32_t i = 0; i < 256; i++) {
        uint32_t c = i;
        for (int k = 0; k < 8; k++) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
        crc_t[0][i] = c;
    }
    for (int k = 1; k < 16; k++)
        for (uint32_t i = 0; i < 256; i++)
            crc_t[k][i] = (crc_t[k - 1][i] >> 8) ^ crc_t[0][crc_t[k - 1][i] & 0xFF];
    crc_x2n[0] = (uint32_t)1 << 30; /* x^1 */
    for (int k = 1; k < 64; k++) crc_x2n[k] = crc_mulmod(crc_x2n[k - 1], crc_x2n[k - 1]);
}
/* CRC of A followed by B from crc1 = CRC(A), crc2 = CRC(B) and len2 = |B| (zlib's crc32_combine) */
static uint32_t crc32_combine(uint32_t crc1, uint32_t crc2, uint64_t len2) {
    uint32_t x = (uint32_t)1 << 31; /* x^(8 len2) */
    for (int k = 3; len2; len2 >>= 1, k++)
        if (len2 & 1) x = crc_mulmod(crc_x2n[k & 63], x);
    return crc_mulmod(x, crc1) ^ crc2;
}
/* one slicing-by-16 step of register c over 16 bytes at p */
#define CRC16_STEP(c, p)                                                                        \
    do {                                                                                        \
        uint32_t a_ = (c) ^ rd32(p), b_ = rd32((p) + 4), d_ = rd32((p) + 8), e_ = rd32((p) + 12); \
        (c) = crc_t[15][a_ & 0xFF] ^ crc_t[14][(a_ >> 8) & 0xFF] ^ crc_t[13][(a_ >> 16) & 0xFF] ^ \
              crc_t[12][a_ >> 24] ^ crc_t[11][b_ & 0xFF] ^ crc_t[10][(b_ >> 8) & 0xFF] ^        \
              crc_t[9][(b_ >> 16) & 0xFF] ^ crc_t[8][b_ >> 24] ^ crc_t[7][d_ & 0xFF] ^           \
              crc_t[6][(d_ >> 8) & 0xFF] ^ crc_t[5][(d_ >> 16) & 0xFF] ^ crc_t[4][d_ >> 24] ^    \
              crc_t[3][e_ & 0xFF] ^ crc_t[2][(e_ >> 8) & 0xFF] ^ crc_t[1][(e_ >> 16) & 0xFF] ^   \
              crc_t[0][e_ >> 24];                                                               \
    } while (0)
/* continues CRC register c (not inverted) over n bytes */
static uint32_t crc_run(uint32_t c, const uint8_t *p, size_t n) {
    for (; n >= 16; p += 16, n -= 16) CRC16_STEP(c, p);
    while (n--) c = crc_t[0][(c ^ *p++) & 0xFF] ^ (c >> 8);
    return c;
}
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(PSNS_PORTABLE_CRC)
/* Optional fast path (GCC or Clang on x86-64; -DPSNS_PORTABLE_CRC leaves it out): carry-less
   multiplication (PCLMULQDQ) folds 64 bytes per step, as crc32fast, zlib and Linux do (Intel,
   "Fast CRC computation for generic polynomials using PCLMULQDQ", bit-reflected; constants as
   in crc32fast). It is used only if the CPU has PCLMULQDQ and SSE4.1, checked at run time, and
   gives the same CRCs as the portable code (tests/stream/readers.rs compiles both). */
#include <immintrin.h>
#define CRC_CLMUL 1
#define CLMUL_TARGET __attribute__((target("pclmul,sse4.1")))
static int crc_use_clmul;
CLMUL_TARGET static __m128i crc_fold(__m128i a, __m128i b, __m128i k) {
    return _mm_xor_si128(_mm_xor_si128(b, _mm_clmulepi64_si128(a, k, 0x00)),
                         _mm_clmulepi64_si128(a, k, 0x11));
}
/* continues CRC register c over n >= 64 bytes */
CLMUL_TARGET static uint32_t crc_clmul(uint32_t c, const uint8_t *p, size_t n) {
#define LD(q) _mm_loadu_si128((const __m128i *)(const void *)(q))
    const __m128i k1k2 = _mm_set_epi64x(0x1c6e41596, 0x154442bd4);
    const __m128i k3k4 = _mm_set_epi64x(0x0ccaa009e, 0x1751997d0);
    const __m128i lo32 = _mm_set_epi32(0, 0, 0, -1), pu = _mm_set_epi64x(0x1F7011641, 0x1DB710641);
    __m128i x3 = _mm_xor_si128(LD(p), _mm_cvtsi32_si128((int)c)), x2 = LD(p + 16),
            x1 = LD(p + 32), x0 = LD(p + 48);
    for (p += 64, n -= 64; n >= 64; p += 64, n -= 64) {
        x3 = crc_fold(x3, LD(p), k1k2);
        x2 = crc_fold(x2, LD(p + 16), k1k2);
        x1 = crc_fold(x1, LD(p + 32), k1k2);
        x0 = crc_fold(x0, LD(p + 48), k1k2);
    }
    __m128i x = crc_fold(crc_fold(crc_fold(x3, x2, k3k4), x1, k3k4), x0, k3k4);
    for (; n >= 16; p += 16, n -= 16) x = crc_fold(x, LD(p), k3k4);
#undef LD
    /* 128 -> 64 bits, then a Barrett reduction to the 32-bit register */
    x = _mm_xor_si128(_mm_clmulepi64_si128(x, k3k4, 0x10), _mm_srli_si128(x, 8));
    x = _mm_xor_si128(
        _mm_clmulepi64_si128(_mm_and_si128(x, lo32), _mm_set_epi64x(0, 0x163cd6124), 0x00),
        _mm_srli_si128(x, 4));
    __m128i t1 = _mm_clmulepi64_si128(_mm_and_si128(x, lo32), pu, 0x10);
    __m128i t2 = _mm_clmulepi64_si128(_mm_and_si128(t1, lo32), pu, 0x00);
    c = (uint32_t)_mm_extract_epi32(_mm_xor_si128(x, t2), 1);
    return crc_run(c, p, n); /* the last 0..15 bytes */
}
#endif

/* CRC-32 of n bytes (little-endian host) */
static uint32_t crc32_buf(const uint8_t *p, size_t n) {
#ifdef CRC_CLMUL
    if (crc_use_clmul && n >= 64) return crc_clmul(0xFFFFFFFFu, p, n) ^ 0xFFFFFFFFu;
#endif
    if (n < 4096) return crc_run(0xFFFFFFFFu, p, n) ^ 0xFFFFFFFFu;
    size_t half = n / 2 / 16 * 16;
    const uint8_t *q = p + half;
    uint32_t c1 = 0xFFFFFFFFu, c2 = 0xFFFFFFFFu;
    for (size_t i = 0; i < half; i += 16) {
        CRC16_STEP(c1, p + i);
        CRC16_STEP(c2, q + i);
    }
    c2 = crc_run(c2, q + half, n - 2 * half); /* the second part's tail */
    return crc32_combine(c1 ^ 0xFFFFFFFFu, c2 ^ 0xFFFFFFFFu, n - half);
}

static uint16_t rd16(const uint8_t *p) { uint16_t v; memcpy(&v, p, 2); return v; }
static uint64_t rd64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }

typedef struct {
    uint32_t width, height, pfnc;
    uint16_t bits_valid, msb_aligned, aborted;
    int16_t angles[4];
    uint64_t payload, stride, frame_count, seed;
} stream_header;

static const uint8_t FILE_MAGIC[8] = {0x89, 'P', 'S', 'N', 'S', 'R', 'A', 'W'};
static const uint8_t FRAME_MAGIC[8] = {0x89, 'P', 'S', 'N', 'S', 'F', 'R', 'M'};
static const uint8_t END_MAGIC[8] = {0x89, 'P', 'S', 'N', 'S', 'E', 'N', 'D'};
#define MAX_PAYLOAD ((uint64_t)1 << 30)

/* strict UTF-8 (no overlongs, surrogates or code points above U+10FFFF), as Rust and Python */
static int utf8_ok(const uint8_t *s, size_t n) {
    size_t i = 0;
    while (i < n) {
        uint8_t c = s[i];
        size_t k;
        uint32_t cp, min;
        if (c < 0x80) { i++; continue; }
        if ((c & 0xE0) == 0xC0) { k = 1; cp = c & 0x1F; min = 0x80; }
        else if ((c & 0xF0) == 0xE0) { k = 2; cp = c & 0x0F; min = 0x800; }
        else if ((c & 0xF8) == 0xF0) { k = 3; cp = c & 0x07; min = 0x10000; }
        else return 0;
        if (n - i <= k) return 0;
        for (size_t j = 1; j <= k; j++) {
            if ((s[i + j] & 0xC0) != 0x80) return 0;
            cp = (cp << 6) | (s[i + j] & 0x3F);
        }
        if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
        i += k + 1;
    }
    return 1;
}

/* a 32-byte NUL-padded UTF-8 string field */
static int str_field_ok(const uint8_t *f) {
    size_t e = 0;
    while (e < 32 && f[e]) e++;
    for (size_t i = e; i < 32; i++)
        if (f[i]) return 0;
    return utf8_ok(f, e);
}

/* Parses and checks a 4096-byte file header with the checks of Rust FileHeader::decode:
 * magic, CRC, version, sizes, format, 1 <= width, height <= 65535, bits valid, alignment,
 * polarizer angles, angle sense, strings, JSON bounds, payload size and stride. 0 on success. */
static int parse_header(const uint8_t *b, stream_header *h) {
    if (memcmp(b, FILE_MAGIC, 8) != 0) return -1;
    if (crc32_buf(b, 4092) != rd32(b + 4092)) return -2;
    if (rd16(b + 8) != 1 || rd32(b + 12) != 4096 || rd32(b + 16) != 256) return -3;
    h->width = rd32(b + 20); h->height = rd32(b + 24); h->pfnc = rd32(b + 28);
    h->bits_valid = rd16(b + 32); h->msb_aligned = rd16(b + 34);
    for (int k = 0; k < 4; k++) h->angles[k] = (int16_t)rd16(b + 36 + 2 * k);
    h->payload = rd64(b + 48); h->stride = rd64(b + 56);
    h->frame_count = rd64(b + 64); h->seed = rd64(b + 72);
    if (h->width < 1 || h->width > 65535 || h->height < 1 || h->height > 65535) return -4;
    uint64_t n = (uint64_t)h->width * h->height, want; /* <= 2^32: no overflow below */
    unsigned maxbits;
    switch (h->pfnc) {
    case 0x01080001: want = n; maxbits = 8; break;
    case 0x010C0047: case 0x010C0006: want = (3 * n + 1) / 2; maxbits = 12; break;
    case 0x01100007: want = 2 * n; maxbits = 16; break;
    default: return -5;
    }
    if (want > MAX_PAYLOAD) return -6;
    if (h->pfnc == 0x01080001 ? h->bits_valid != 8 : (h->bits_valid < 1 || h->bits_valid > maxbits))
        return -7;
    if (h->msb_aligned > 1 || (h->msb_aligned && h->pfnc != 0x01100007)) return -8;
    int seen = 0;
    for (int k = 0; k < 4; k++) {
        int a = h->angles[k];
        int bit = a == 0 ? 1 : a == 45 ? 2 : a == 90 ? 4 : a == 135 ? 8 : 0;
        if (!bit || (seen & bit)) return -9;
        seen |= bit;
    }
    int16_t sense = (int16_t)rd16(b + 44);
    if (sense != 1 && sense != -1) return -10;
    h->aborted = rd16(b + 46);
    if (h->aborted > 1) return -14;
    if (!str_field_ok(b + 160) || !str_field_ok(b + 192)) return -11;
    uint32_t jo = rd32(b + 224), jl = rd32(b + 228);
    if (jo || jl) {
        if (jo < 232 || (uint64_t)jo + jl > 4092) return -12;
        if (!utf8_ok(b + jo, jl) || memchr(b + jo, 0, jl)) return -12;
    }
    if (h->payload != want || h->stride != (256 + want + 4095) / 4096 * 4096) return -13;
    return 0;
}

/* SIMD unpacking (-DPSNS_PORTABLE_SIMD leaves it and the SSE2 sum below out): Mono8 with SSE2
   (every x86-64), Mono12p with SSSE3's byte shuffle where GCC or Clang builds it and the CPU has
   it (checked at run time). Single-thread, per 2448 x 2048 frame (`check` of a 60-frame file,
   task-clock, median of 3): Mono8 3.63 -> 2.33 ms and Mono12p 4.62 -> 3.78 ms per frame in all
   (reading, both CRCs, unpacking and the sum). The tests compare
   these builds with the portable one. */
#if defined(__SSE2__) && !defined(PSNS_PORTABLE_SIMD)
#include <emmintrin.h>
#define SIMD_SSE2 1
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <tmmintrin.h>
#define SIMD_SSSE3 1
static int use_ssse3;
/* the first pixels of a Mono12p payload of n pixels, eight per 12 bytes (16-byte loads that stay
   inside the (3n + 1)/2 bytes); returns how many were done (a multiple of 8) */
__attribute__((target("ssse3"))) static size_t unpack12p_ssse3(const uint8_t *p, uint16_t *v,
                                                                size_t n) {
    /* 16-bit lane 2j gets bytes 3j, 3j+1 (its value is the low 12 bits), lane 2j+1 bytes 3j+1,
       3j+2 (its value is the top 12 bits) */
    const __m128i shuf = _mm_setr_epi8(0, 1, 1, 2, 3, 4, 4, 5, 6, 7, 7, 8, 9, 10, 10, 11);
    const __m128i even = _mm_set1_epi32(0x0FFF), odd = _mm_set1_epi32((int)0xFFFF0000u);
    size_t bytes = (3 * n + 1) / 2, i = 0;
    for (; i + 8 <= n && i / 2 * 3 + 16 <= bytes; i += 8) {
        __m128i x = _mm_shuffle_epi8(_mm_loadu_si128((const __m128i *)(const void *)(p + i / 2 * 3)), shuf);
        x = _mm_or_si128(_mm_and_si128(x, even), _mm_and_si128(_mm_srli_epi16(x, 4), odd));
        _mm_storeu_si128((__m128i *)(void *)(v + i), x);
    }
    return i;
}
#endif
#endif

/* payload -> values (n = width*height), one loop per format */
static void unpack(const stream_header *h, const uint8_t *restrict p, uint16_t *restrict v) {
    size_t n = (size_t)h->width * h->height, i;
    switch (h->pfnc) {
    case 0x01080001:
        i = 0;
#ifdef SIMD_SSE2
        for (const __m128i z = _mm_setzero_si128(); i + 16 <= n; i += 16) {
            __m128i x = _mm_loadu_si128((const __m128i *)(const void *)(p + i));
            _mm_storeu_si128((__m128i *)(void *)(v + i), _mm_unpacklo_epi8(x, z));
            _mm_storeu_si128((__m128i *)(void *)(v + i + 8), _mm_unpackhi_epi8(x, z));
        }
#endif
        for (; i + 4 <= n; i += 4) { /* four bytes widened to four LE uint16 at a time */
            uint32_t x = rd32(p + i);
            uint64_t w = (x & 0xFFu) | (uint64_t)(x & 0xFF00u) << 8 |
                         (uint64_t)(x & 0xFF0000u) << 16 | (uint64_t)(x >> 24) << 48;
            memcpy(v + i, &w, 8);
        }
        for (; i < n; i++) v[i] = p[i];
        break;
    case 0x01100007: {
        unsigned shift = h->msb_aligned ? 16u - h->bits_valid : 0u;
        memcpy(v, p, 2 * n); /* little-endian host */
        if (shift)
            for (i = 0; i < n; i++) v[i] = (uint16_t)(v[i] >> shift);
        break;
    }
    case 0x010C0047:
    case 0x010C0006: { /* two pixels in three bytes; an odd count ends with a half group */
        int p12 = h->pfnc == 0x010C0047;
        i = 0;
#ifdef SIMD_SSSE3
        if (p12 && use_ssse3) {
            i = unpack12p_ssse3(p, v, n);
            p += i / 2 * 3;
        }
#endif
        if (p12) /* Mono12p is a little-endian bit stream: four pixels per 8-byte load (of which
                    6 bytes are used; i + 6 <= n keeps the load inside the payload) */
            for (; i + 6 <= n; i += 4, p += 6) {
                uint64_t w = rd64(p), o = (w & 0xFFF) | (w >> 12 & 0xFFF) << 16 |
                                          (w >> 24 & 0xFFF) << 32 | (w >> 36 & 0xFFF) << 48;
                memcpy(v + i, &o, 8); /* little-endian host */
            }
        for (; i + 1 < n; i += 2, p += 3) {
            v[i] = p12 ? (uint16_t)(p[0] | ((p[1] & 0x0F) << 8))
                       : (uint16_t)((p[0] << 4) | (p[1] & 0x0F));
            v[i + 1] = (uint16_t)((p[1] >> 4) | (p[2] << 4));
        }
        if (i < n)
            v[i] = p12 ? (uint16_t)(p[0] | ((p[1] & 0x0F) << 8))
                       : (uint16_t)((p[0] << 4) | (p[1] & 0x0F));
        break;
    }
    default: /* the header check accepts no other format */
        abort();
    }
}

/* sum of n little-endian uint16 values (as a consumer would use them). With SSE2 (every x86-64):
   eight values per step widened into 32-bit lanes, flushed to 64 bits every 8192 steps (a lane
   then holds at most 8192 * 65535 < 2^31); 0.35 against 0.72 ms per 2448 x 2048 frame for the
   portable loop. Elsewhere, or with -DPSNS_PORTABLE_SIMD, four accumulators, so the adds do not
   wait for each other. */
#ifdef SIMD_SSE2
static uint64_t sum_le16(const uint8_t *p, size_t n) {
    const __m128i z = _mm_setzero_si128();
    uint64_t s = 0;
    size_t i = 0;
    while (n - i >= 8) {
        size_t m = (n - i) / 8 < 8192 ? (n - i) / 8 : 8192;
        __m128i a = z, b = z;
        for (size_t k = 0; k < m; k++, i += 8) {
            __m128i x = _mm_loadu_si128((const __m128i *)(const void *)(p + 2 * i));
            a = _mm_add_epi32(a, _mm_unpacklo_epi16(x, z));
            b = _mm_add_epi32(b, _mm_unpackhi_epi16(x, z));
        }
        uint32_t t[8];
        _mm_storeu_si128((__m128i *)(void *)t, a);
        _mm_storeu_si128((__m128i *)(void *)(t + 4), b);
        for (int k = 0; k < 8; k++) s += t[k];
    }
    for (; i < n; i++) s += rd16(p + 2 * i);
    return s;
}
#else
static uint64_t sum_le16(const uint8_t *p, size_t n) {
    uint64_t s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    size_t i = 0;
    for (; i + 4 <= n; i += 4, p += 8) {
        s0 += rd16(p); s1 += rd16(p + 2); s2 += rd16(p + 4); s3 += rd16(p + 6);
    }
    for (; i < n; i++, p += 2) s0 += rd16(p);
    return s0 + s1 + s2 + s3;
}
#endif

/* growable read buffer over a FILE*; off = stream offset of b[0] */
typedef struct { FILE *f; uint8_t *b; size_t len, cap; int eof; uint64_t off; } rbuf;

static void *xrealloc(void *p, size_t n) {
    void *q = realloc(p, n ? n : 1);
    if (!q) { fprintf(stderr, "out of memory (%zu bytes)\n", n); exit(3); }
    return q;
}
/* ensures n bytes are buffered unless the source ends first; returns the bytes buffered */
static size_t fill(rbuf *r, size_t n) {
    if (n > r->cap) { r->b = xrealloc(r->b, n); r->cap = n; }
    while (r->len < n && !r->eof) {
        size_t k = fread(r->b + r->len, 1, n - r->len, r->f);
        if (k == 0) r->eof = 1;
        r->len += k;
    }
    return r->len;
}
static void consume(rbuf *r, size_t n) {
    if (n > r->len) n = r->len;
    memmove(r->b, r->b + n, r->len - n);
    r->len -= n;
    r->off += n;
}
/* first "\x89PSNS" fully inside [lo, hi) of the buffer, or (size_t)-1 */
static size_t find_magic(const rbuf *r, size_t lo, size_t hi) {
    if (hi > r->len) hi = r->len;
    for (size_t i = lo; i + 5 <= hi; i++)
        if (!memcmp(r->b + i, FILE_MAGIC, 5)) return i;
    return (size_t)-1;
}
static int frame_header_ok(const uint8_t *p) {
    return !memcmp(p, FRAME_MAGIC, 8) && crc32_buf(p, 252) == rd32(p + 252);
}
/* a 256-byte end record (the producer stopped because of a failure): magic, CRC, status 1, a
   UTF-8 reason of at most 228 bytes at 24 whose length is at 20 */
static int end_record_ok(const uint8_t *p) {
    return !memcmp(p, END_MAGIC, 8) && crc32_buf(p, 252) == rd32(p + 252) && rd32(p + 16) == 1 &&
           rd32(p + 20) <= 228 && utf8_ok(p + 24, rd32(p + 20));
}
/* a frame header or file header with a valid CRC (and valid fields) starts at j */
static int valid_at(rbuf *r, size_t j) {
    if (fill(r, j + 8) < j + 8) return 0;
    if (!memcmp(r->b + j, END_MAGIC, 8))
        return fill(r, j + 256) >= j + 256 && end_record_ok(r->b + j);
    if (!memcmp(r->b + j, FRAME_MAGIC, 8))
        return fill(r, j + 256) >= j + 256 && frame_header_ok(r->b + j);
    if (!memcmp(r->b + j, FILE_MAGIC, 8)) {
        stream_header t;
        return fill(r, j + 4096) >= j + 4096 && parse_header(r->b + j, &t) == 0;
    }
    return 0;
}
static size_t valid_magic_within(rbuf *r, size_t lo, size_t hi) {
    size_t from = lo;
    while (from < hi) {
        size_t j = find_magic(r, from, hi);
        if (j == (size_t)-1) return j;
        if (valid_at(r, j)) return j;
        from = j + 1;
    }
    return (size_t)-1;
}

typedef struct { uint64_t *v; size_t n, cap; } u64vec;
static void push(u64vec *a, uint64_t x) {
    if (a->n == a->cap) {
        if (a->cap > ((size_t)-1) / 2 / sizeof *a->v) { fprintf(stderr, "out of memory\n"); exit(3); }
        a->cap = a->cap ? 2 * a->cap : 16;
        a->v = xrealloc(a->v, a->cap * sizeof *a->v);
    }
    a->v[a->n++] = x;
}
static int contains(const u64vec *a, uint64_t x) {
    for (size_t i = 0; i < a->n; i++)
        if (a->v[i] == x) return 1;
    return 0;
}
static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static int dump; /* 1: canonical lines on stdout; 0: reports on stderr */
static int damage; /* reports of damage or loss made on stderr (not in dump) */
static int aborted; /* an end record was read */
static void print_header(const stream_header *h) {
    printf("header %u %u %08x %u %u %llu %llu %llu %llu %d,%d,%d,%d%s\n", h->width, h->height,
           h->pfnc, h->bits_valid, h->msb_aligned, (unsigned long long)h->seed,
           (unsigned long long)h->frame_count, (unsigned long long)h->payload,
           (unsigned long long)h->stride, h->angles[0], h->angles[1], h->angles[2], h->angles[3],
           h->aborted ? " aborted" : "");
}
static void ev_aborted(uint64_t off, const uint8_t *p) {
    int n = (int)rd32(p + 20);
    aborted = 1;
    if (dump)
        printf("aborted %llu %llu %.*s\n", (unsigned long long)off,
               (unsigned long long)rd64(p + 8), n, (const char *)(p + 24));
    else
        fprintf(stderr, "stream aborted by its producer: %.*s\n", n, (const char *)(p + 24));
}
static void idx_str(char *s, int known, uint64_t i) {
    if (known) snprintf(s, 24, "%llu", (unsigned long long)i);
    else strcpy(s, dump ? "-" : "?");
}
static void ev_gap(uint64_t from, uint64_t to) {
    if (dump) printf("gap %llu..%llu\n", (unsigned long long)from, (unsigned long long)to);
    else damage++, fprintf(stderr, "gap %llu..%llu: %llu frames dropped\n", (unsigned long long)from,
                 (unsigned long long)to, (unsigned long long)(to - from));
}
static void ev_corrupt(int known, uint64_t i, uint64_t off, const char *why) {
    char s[24];
    idx_str(s, known, i);
    if (dump) printf("corrupt %s %llu\n", s, (unsigned long long)off);
    else damage++, fprintf(stderr, "frame %s at byte %llu corrupt: %s\n", s, (unsigned long long)off, why);
}
static void ev_truncated(int known, uint64_t i, uint64_t off, uint64_t have, uint64_t need) {
    char s[24];
    idx_str(s, known, i);
    if (dump)
        printf("truncated %s %llu %llu %llu\n", s, (unsigned long long)off,
               (unsigned long long)have, (unsigned long long)need);
    else
        damage++, fprintf(stderr, "frame %s at byte %llu truncated: %llu of %llu bytes\n", s,
                (unsigned long long)off, (unsigned long long)have, (unsigned long long)need);
}
static void ev_skipped(uint64_t off, uint64_t n) {
    if (dump) printf("skipped %llu %llu\n", (unsigned long long)off, (unsigned long long)n);
    else damage++, fprintf(stderr, "skipped %llu bytes at byte %llu\n", (unsigned long long)n,
                 (unsigned long long)off);
}

/* Damage at the current position (as Rust StreamReader::resync): scan for the next valid frame or
 * file header, report the damaged records by index, the gaps and the bytes skipped.
 * *has_exp / *expected: next expected index. Returns 1 at EOF. */
static int resync(rbuf *r, const stream_header *h, int *has_exp, uint64_t *expected,
                  const char *why) {
    uint64_t p0 = r->off, stride = h->stride;
    u64vec cands = {0}, ids = {0}; /* index fields of damaged records whose frame magic survived */
    size_t n_cands = 0;            /* including those too short to hold an index */
#define NOTE()                                                                    \
    do {                                                                          \
        if (r->len >= 8 && !memcmp(r->b, FRAME_MAGIC, 8)) {                       \
            n_cands++;                                                            \
            if (r->len >= 16) push(&cands, rd64(r->b + 8));                       \
        }                                                                         \
    } while (0)
    NOTE();
    consume(r, 1);
    int end; /* 0 eof, 1 frame, 2 header */
    for (;;) {
        fill(r, 4096);
        if (r->len == 0) { end = 0; break; }
        size_t i = find_magic(r, 0, r->len);
        if (i == (size_t)-1) {
            /* keep 4 bytes: a magic may straddle the next read */
            size_t keep = r->eof ? 0 : (r->len < 4 ? r->len : 4);
            consume(r, r->len - keep);
            if (r->eof) { end = 0; break; }
        } else {
            consume(r, i);
            if (valid_at(r, 0)) { end = memcmp(r->b, FRAME_MAGIC, 8) ? 2 : 1; break; }
            NOTE();
            consume(r, 1);
        }
    }
#undef NOTE
    uint64_t skipped = r->off - p0;
    int has_next = end == 1;
    uint64_t next = has_next ? rd64(r->b + 8) : 0;
    uint64_t rounded = (skipped + stride / 2) / stride;
    int has_lo = *has_exp, has_hi = has_lo && has_next && next >= *expected;
    uint64_t lo = *expected, hi = next;
    uint64_t n_damaged = n_cands > rounded ? n_cands : rounded;
    if (has_lo && has_hi && hi - lo < n_damaged) n_damaged = hi - lo;
    if (has_lo) {
        for (size_t k = 0; k < cands.n; k++) {
            uint64_t c = cands.v[k];
            if (c >= lo && (!has_hi || c < hi) && ids.n < n_damaged && !contains(&ids, c))
                push(&ids, c);
        }
        for (uint64_t i = lo; ids.n < n_damaged && (!has_hi || i < hi); i++)
            if (!contains(&ids, i)) push(&ids, i);
        if (ids.n) qsort(ids.v, ids.n, sizeof *ids.v, cmp_u64);
    }
    uint64_t n_reports = has_lo ? ids.n : n_damaged;
    for (uint64_t k = 0; k < n_reports; k++)
        ev_corrupt(k < ids.n, k < ids.n ? ids.v[k] : 0, p0 + k * stride, why);
    if (has_lo && has_hi) {
        uint64_t from = lo;
        for (size_t k = 0; k <= ids.n; k++) {
            uint64_t i = k < ids.n ? ids.v[k] : hi;
            if (i > from) ev_gap(from, i);
            from = i + 1;
        }
        *expected = hi;
    } else if (has_lo && ids.n) {
        uint64_t last = ids.v[ids.n - 1];
        *expected = (last > lo ? last : lo) + 1;
    }
    if (skipped) ev_skipped(p0, skipped);
    free(cands.v);
    free(ids.v);
    return end == 0;
}

/* `crc`: the CRC-32 of every byte of f, read in 1 MiB pieces joined with crc32_combine */
static int crc_file(FILE *f) {
    static uint8_t b[1 << 20];
    uint32_t c = 0; /* CRC of the empty input */
    size_t k;
    while ((k = fread(b, 1, sizeof b, f)) > 0) c = crc32_combine(c, crc32_buf(b, k), k);
    if (ferror(f)) { perror("reading"); return 2; }
    printf("%08x\n", c);
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 3 ||
        (strcmp(argv[1], "dump") && strcmp(argv[1], "frame") && strcmp(argv[1], "crc") &&
         strcmp(argv[1], "check")) ||
        (!strcmp(argv[1], "frame") && argc < 5)) {
        fprintf(stderr, "usage: %s dump FILE | frame FILE N OUT | check FILE | crc FILE\n",
                argv[0]);
        return 2;
    }
    crc_init();
#ifdef CRC_CLMUL
    __builtin_cpu_init();
    crc_use_clmul = __builtin_cpu_supports("pclmul") && __builtin_cpu_supports("sse4.1");
#endif
#ifdef SIMD_SSSE3
    __builtin_cpu_init();
    use_ssse3 = __builtin_cpu_supports("ssse3");
#endif
    if (!strcmp(argv[1], "crc")) {
        FILE *f = strcmp(argv[2], "-") ? fopen(argv[2], "rb") : stdin;
        if (!f) { perror(argv[2]); return 2; }
        return crc_file(f);
    }
    dump = !strcmp(argv[1], "dump");
    int check = !strcmp(argv[1], "check");
    uint64_t want_index = dump || check ? 0 : strtoull(argv[3], NULL, 10);
    rbuf r = {0};
    r.f = strcmp(argv[2], "-") ? fopen(argv[2], "rb") : stdin;
    if (!r.f) { perror(argv[2]); return 2; }
    stream_header h;
    if (fill(&r, 4096) < 4096 || parse_header(r.b, &h) != 0) {
        fprintf(stderr, "not a valid psns stream header\n");
        return 1;
    }
    consume(&r, 4096);
    if (dump) print_header(&h);
    uint16_t *v = NULL; /* unpacked values */
    size_t v_cap = 0;
    int status = dump || check ? 0 : 1;
    int has_exp = 1;       /* 0 right after a producer restart */
    uint64_t expected = 0; /* next expected index */
    for (;;) {
        size_t a = fill(&r, 8);
        if (a == 0) break;
        if (a < 8) { ev_truncated(0, 0, r.off, a, h.stride); break; }
        const char *why;
        if (!memcmp(r.b, FRAME_MAGIC, 8)) {
            if (fill(&r, 256) < 256) { ev_truncated(0, 0, r.off, r.len, h.stride); break; }
            if (!frame_header_ok(r.b)) {
                why = "frame header CRC mismatch";
            } else {
                uint64_t index = rd64(r.b + 8);
                size_t stride = (size_t)h.stride, p = (size_t)h.payload;
                if (has_exp && index < expected) {
                    /* a valid header out of order (duplicate / spliced record): skip the record */
                    ev_corrupt(1, index, r.off, "index not increasing");
                    fill(&r, stride);
                    consume(&r, stride);
                    continue;
                }
                if (fill(&r, stride) < stride) {
                    ev_truncated(1, index, r.off, r.len, stride);
                    break;
                }
                uint32_t pc = crc32_buf(r.b + 256, p); /* the one pass over the payload */
                int ok = pc == rd32(r.b + 20);
                if (!ok) {
                    /* writer died mid-record and a new record (or file header) follows inside? */
                    size_t j = valid_magic_within(&r, 256, stride);
                    if (j != (size_t)-1) {
                        ev_truncated(1, index, r.off, j, stride);
                        has_exp = 1;
                        expected = index + 1;
                        consume(&r, j);
                        continue;
                    }
                }
                size_t len = stride;
                if (ok) {
                    /* a valid header inside the zero pad: the writer died in the pad */
                    size_t j = valid_magic_within(&r, 256 + p, stride);
                    if (j != (size_t)-1) len = j;
                }
                if (has_exp && index > expected) ev_gap(expected, index);
                has_exp = 1;
                expected = index + 1;
                const uint8_t *fh = r.b, *pay = r.b + 256;
                if (!dump && !ok)
                    damage++, fprintf(stderr, "frame %llu: payload CRC mismatch\n", (unsigned long long)index);
                size_t n = (size_t)h.width * h.height; /* <= 2^30 by parse_header */
                /* LSB-aligned Mono16 on a little-endian host: the values are the payload's
                   bytes, so their sum is read from the payload and their CRC is pc */
                int raw16 = h.pfnc == 0x01100007 && !h.msb_aligned;
                int want = !dump && !check && index == want_index && ok;
                if (((dump || (check && ok)) && !raw16) || want) {
                    if (n > v_cap) { /* grows only with the frame size: no allocation per frame */
                        v = xrealloc(v, n * sizeof *v);
                        v_cap = n;
                    }
                    unpack(&h, pay, v);
                }
                if (dump) {
                    const uint8_t *vb = raw16 ? pay : (const uint8_t *)v; /* LE host */
                    uint64_t sum = sum_le16(vb, n);
                    uint32_t vc = raw16 ? pc : crc32_buf(vb, n * 2);
                    printf("frame %llu %u %d %lld %lld %lld ", (unsigned long long)index,
                           rd32(fh + 16), ok, (long long)rd64(fh + 24), (long long)rd64(fh + 32),
                           (long long)rd64(fh + 40));
                    for (int k = 0; k < 16; k++)
                        printf("%s%016llx", k ? "," : "", (unsigned long long)rd64(fh + 48 + 8 * k));
                    printf(" %u,%u,%u,%u ", rd32(fh + 176), rd32(fh + 180), rd32(fh + 184),
                           rd32(fh + 188));
                    for (int k = 0; k < 8; k++) /* turbidity, albedo, class fractions */
                        printf("%s%08x", k ? "," : "", rd32(fh + 192 + 4 * k));
                    printf(" %llu %08x\n", (unsigned long long)sum, vc);
                } else if (check && ok) {
                    /* the values a consumer gets: the payload itself for raw16, else unpacked */
                    const uint8_t *vb = raw16 ? pay : (const uint8_t *)v; /* LE host */
                    printf("frame %llu %llu\n", (unsigned long long)index,
                           (unsigned long long)sum_le16(vb, n));
                } else if (want) {
                    FILE *o = fopen(argv[4], "wb");
                    if (!o || fwrite(v, 2, n, o) != n) { perror(argv[4]); return 2; }
                    fclose(o);
                    status = 0;
                    break;
                }
                consume(&r, len);
                continue;
            }
        } else if (!memcmp(r.b, END_MAGIC, 8)) {
            if (fill(&r, 256) < 256) { ev_truncated(0, 0, r.off, r.len, h.stride); break; }
            if (end_record_ok(r.b)) {
                ev_aborted(r.off, r.b);
                consume(&r, 256);
                continue;
            }
            why = "end record invalid";
        } else if (!memcmp(r.b, FILE_MAGIC, 8)) {
            if (fill(&r, 4096) < 4096) { ev_truncated(0, 0, r.off, r.len, h.stride); break; }
            stream_header h2;
            if (parse_header(r.b, &h2) == 0) {
                h = h2;
                consume(&r, 4096);
                has_exp = 0;
                if (dump) { printf("restart\n"); print_header(&h); }
                else fprintf(stderr, "producer restart\n");
                continue;
            }
            why = "file header invalid";
        } else {
            why = "frame magic missing";
        }
        if (resync(&r, &h, &has_exp, &expected, why)) break;
    }
    if (check && h.aborted && !aborted) {
        /* the header's mark without an end record (it did not fit on a full disk) */
        fprintf(stderr, "stream aborted by its producer: reason not recorded\n");
        aborted = 1;
    }
    if (check) status = damage != 0 || aborted;
    else if (!dump && status)
        fprintf(stderr, "frame %llu not found or damaged\n", (unsigned long long)want_index);
    free(v); free(r.b);
    return status;
}

/* psns_stream.c - plain C99 reader for psns raw frame streams, format v1
 * (docs/stream-format.md). One file, no dependencies, little-endian hosts.
 *
 *   cc -std=c99 -O2 -o psns_stream tools/psns_stream.c
 *   psns_stream dump FILE|-          canonical header/frame lines (used by the tests)
 *   psns_stream frame FILE|- N OUT   write frame N's values as raw uint16 little-endian
 *
 * Reads sequentially with fread (works on files, FIFOs and stdin), checks both CRCs,
 * reports damage on stderr and resynchronises on the next frame magic.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint32_t crc_table[256];
static void crc_init(void) {
    for (uint32_t i = 0; i < 256; i++) {
        uint32_t c = i;
        for (int k = 0; k < 8; k++) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
        crc_table[i] = c;
    }
}
/* zlib's CRC-32 */
static uint32_t crc32_buf(const uint8_t *p, size_t n) {
    uint32_t c = 0xFFFFFFFFu;
    while (n--) c = crc_table[(c ^ *p++) & 0xFF] ^ (c >> 8);
    return c ^ 0xFFFFFFFFu;
}

static uint16_t rd16(const uint8_t *p) { uint16_t v; memcpy(&v, p, 2); return v; }
static uint32_t rd32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static uint64_t rd64(const uint8_t *p) { uint64_t v; memcpy(&v, p, 8); return v; }

typedef struct {
    uint32_t width, height, pfnc;
    uint16_t bits_valid, msb_aligned;
    int16_t angles[4];
    uint64_t payload, stride, frame_count, seed;
} stream_header;

static const uint8_t FILE_MAGIC[8] = {0x89, 'P', 'S', 'N', 'S', 'R', 'A', 'W'};
static const uint8_t FRAME_MAGIC[8] = {0x89, 'P', 'S', 'N', 'S', 'F', 'R', 'M'};

/* 0 on success */
static int parse_header(const uint8_t *b, stream_header *h) {
    if (memcmp(b, FILE_MAGIC, 8) != 0) return -1;
    if (crc32_buf(b, 4092) != rd32(b + 4092)) return -2;
    if (rd16(b + 8) != 1 || rd32(b + 12) != 4096 || rd32(b + 16) != 256) return -3;
    h->width = rd32(b + 20); h->height = rd32(b + 24); h->pfnc = rd32(b + 28);
    h->bits_valid = rd16(b + 32); h->msb_aligned = rd16(b + 34);
    for (int k = 0; k < 4; k++) h->angles[k] = (int16_t)rd16(b + 36 + 2 * k);
    h->payload = rd64(b + 48); h->stride = rd64(b + 56);
    h->frame_count = rd64(b + 64); h->seed = rd64(b + 72);
    uint64_t n = (uint64_t)h->width * h->height, want;
    switch (h->pfnc) {
    case 0x01080001: want = n; break;
    case 0x010C0047: case 0x010C0006: want = (3 * n + 1) / 2; break;
    case 0x01100007: want = 2 * n; break;
    default: return -4;
    }
    if (h->payload != want || h->stride != (256 + want + 4095) / 4096 * 4096) return -5;
    if (h->payload > (1u << 30)) return -6;
    return 0;
}

/* payload -> values (n = width*height) */
static void unpack(const stream_header *h, const uint8_t *p, uint16_t *v) {
    size_t n = (size_t)h->width * h->height;
    for (size_t i = 0; i < n; i++) {
        switch (h->pfnc) {
        case 0x01080001: v[i] = p[i]; break;
        case 0x01100007:
            v[i] = rd16(p + 2 * i);
            if (h->msb_aligned) v[i] >>= (16 - h->bits_valid);
            break;
        default: {
            const uint8_t *g = p + 3 * (i / 2);
            if (i % 2 == 0)
                v[i] = h->pfnc == 0x010C0047 ? (uint16_t)(g[0] | ((g[1] & 0x0F) << 8))
                                             : (uint16_t)((g[0] << 4) | (g[1] & 0x0F));
            else
                v[i] = (uint16_t)((g[1] >> 4) | (g[2] << 4));
        }
        }
    }
}

/* growable read buffer over a FILE* */
typedef struct { FILE *f; uint8_t *b; size_t len, cap; int eof; } rbuf;
static size_t fill(rbuf *r, size_t n) {
    if (n > r->cap) {
        r->b = realloc(r->b, n);
        if (!r->b) { perror("realloc"); exit(3); }
        r->cap = n;
    }
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
}

int main(int argc, char **argv) {
    if (argc < 3 || (strcmp(argv[1], "dump") && strcmp(argv[1], "frame")) ||
        (!strcmp(argv[1], "frame") && argc < 5)) {
        fprintf(stderr, "usage: %s dump FILE | frame FILE N OUT\n", argv[0]);
        return 2;
    }
    crc_init();
    int dump = !strcmp(argv[1], "dump");
    uint64_t want_index = dump ? 0 : strtoull(argv[3], NULL, 10);
    rbuf r = {0};
    r.f = strcmp(argv[2], "-") ? fopen(argv[2], "rb") : stdin;
    if (!r.f) { perror(argv[2]); return 2; }
    stream_header h;
    if (fill(&r, 4096) < 4096 || parse_header(r.b, &h) != 0) {
        fprintf(stderr, "not a valid psns stream header\n");
        return 1;
    }
    consume(&r, 4096);
    if (dump)
        printf("header %u %u %08x %u %u %llu %llu %llu %llu %d,%d,%d,%d\n", h.width, h.height,
               h.pfnc, h.bits_valid, h.msb_aligned, (unsigned long long)h.seed,
               (unsigned long long)h.frame_count, (unsigned long long)h.payload,
               (unsigned long long)h.stride, h.angles[0], h.angles[1], h.angles[2], h.angles[3]);
    uint16_t *v = NULL;
    int status = dump ? 0 : 1;
    for (;;) {
        if (fill(&r, 8) == 0) break;
        if (r.len >= 8 && !memcmp(r.b, FILE_MAGIC, 8) && fill(&r, 4096) >= 4096) {
            stream_header h2;
            if (parse_header(r.b, &h2) == 0) {
                h = h2;
                consume(&r, 4096);
                fprintf(stderr, "producer restart\n");
                continue;
            }
        } else if (r.len >= 8 && !memcmp(r.b, FRAME_MAGIC, 8) && fill(&r, 256) >= 256 &&
                   crc32_buf(r.b, 252) == rd32(r.b + 252)) {
            uint64_t index = rd64(r.b + 8);
            if (fill(&r, h.stride) < h.stride) {
                fprintf(stderr, "truncated frame %llu\n", (unsigned long long)index);
                break;
            }
            const uint8_t *fh = r.b, *pay = r.b + 256;
            int ok = crc32_buf(pay, h.payload) == rd32(fh + 20);
            if (!ok) fprintf(stderr, "frame %llu: payload CRC mismatch\n", (unsigned long long)index);
            size_t n = (size_t)h.width * h.height;
            v = realloc(v, n * sizeof *v);
            unpack(&h, pay, v);
            if (dump) {
                uint64_t sum = 0;
                for (size_t i = 0; i < n; i++) sum += v[i];
                uint32_t vc = crc32_buf((const uint8_t *)v, n * 2); /* LE host */
                printf("frame %llu %u %d %lld %lld %lld ", (unsigned long long)index, rd32(fh + 16), ok,
                       (long long)rd64(fh + 24), (long long)rd64(fh + 32), (long long)rd64(fh + 40));
                for (int k = 0; k < 16; k++)
                    printf("%s%016llx", k ? "," : "", (unsigned long long)rd64(fh + 48 + 8 * k));
                printf(" %u,%u,%u,%u %08x,%08x %llu %08x\n", rd32(fh + 176), rd32(fh + 180),
                       rd32(fh + 184), rd32(fh + 188), rd32(fh + 192), rd32(fh + 196),
                       (unsigned long long)sum, vc);
            } else if (index == want_index && ok) {
                FILE *o = fopen(argv[4], "wb");
                if (!o || fwrite(v, 2, n, o) != n) { perror(argv[4]); return 2; }
                fclose(o);
                status = 0;
                break;
            }
            consume(&r, h.stride);
            continue;
        }
        /* damage: skip to the next magic */
        fprintf(stderr, "damaged data skipped\n");
        consume(&r, 1);
        for (;;) {
            fill(&r, 1 << 16);
            uint8_t *m = NULL;
            for (size_t i = 0; i + 5 <= r.len; i++)
                if (!memcmp(r.b + i, FILE_MAGIC, 5)) { m = r.b + i; break; }
            if (m) { consume(&r, (size_t)(m - r.b)); break; }
            if (r.eof) { r.len = 0; break; }
            consume(&r, r.len > 4 ? r.len - 4 : 0);
        }
        if (r.len == 0 && r.eof) break;
    }
    if (!dump && status) fprintf(stderr, "frame %llu not found or damaged\n", (unsigned long long)want_index);
    free(v); free(r.b);
    return status;
}

/* png.c - the PNG encoder of png.h: a signature, IHDR, IDAT chunks holding the zlib
 * stream of the filtered rows, and IEND.  Used by mesh/render.c through `frep render`.
 * zlib allocates through frep's allocator, so its failures are out of memory too.
 */
#include "config.h"

#include "alloc.h"
#include "png.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* Bytes of deflate output per IDAT chunk: any size works. */
#define PNG_IDAT_BYTES (1u << 18)
/* The PNG filter types tried on each row (None, Sub, Up, Average, Paeth). */
#define PNG_FILTERS 5

uint32_t png_crc32(uint32_t crc, const uint8_t *p, size_t n)
{
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

static void be32(uint8_t *b, uint32_t v)
{
    b[0] = (uint8_t)(v >> 24);
    b[1] = (uint8_t)(v >> 16);
    b[2] = (uint8_t)(v >> 8);
    b[3] = (uint8_t)v;
}

static void chunk(FILE *f, const char *type, const uint8_t *data, uint32_t n)
{
    uint8_t head[8];
    be32(head, n);
    memcpy(head + 4, type, 4);
    fwrite(head, 1, 8, f);
    if (n) fwrite(data, 1, n, f);
    uint32_t crc = png_crc32(0, (const uint8_t *)type, 4);
    crc = png_crc32(crc, data, n);
    uint8_t tail[4];
    be32(tail, crc);
    fwrite(tail, 1, 4, f);
}

static unsigned char paeth(int a, int b, int c)
{
    int p = a + b - c, pa = abs(p - a), pb = abs(p - b), pc = abs(p - c);
    return (unsigned char)(pa <= pb && pa <= pc ? a : pb <= pc ? b : c);
}

/* Row cur (n bytes, the row above prev, NULL for the first) filtered with type t into
 * out; returns the sum of the filtered bytes as signed values, the usual estimate of
 * how well the row compresses. */
static unsigned long filter_row(int t, const uint8_t *cur, const uint8_t *prev, size_t n,
                                uint8_t *out)
{
    unsigned long cost = 0;
    for (size_t i = 0; i < n; i++) {
        int a = i >= 3 ? cur[i - 3] : 0, b = prev ? prev[i] : 0, c = prev && i >= 3 ? prev[i - 3] : 0;
        int pred = t == 1 ? a : t == 2 ? b : t == 3 ? (a + b) / 2 : t == 4 ? paeth(a, b, c) : 0;
        out[i] = (uint8_t)(cur[i] - pred);
        cost += out[i] < 128 ? out[i] : 256u - out[i];
    }
    return cost;
}

/* The filtered image: per row, the filter byte and the row with the cheapest filter. */
static uint8_t *filter_image(const uint8_t *rgb, int w, int h, size_t *len)
{
    size_t n = 3 * (size_t)w, row = n + 1;
    uint8_t *raw = frep_malloc(row * (size_t)h), *tmp = frep_malloc(n);
    if (!raw || !tmp) {
        frep_free(raw);
        frep_free(tmp);
        return NULL;
    }
    for (int y = 0; y < h; y++) {
        const uint8_t *cur = rgb + n * (size_t)y, *prev = y ? cur - n : NULL;
        uint8_t *out = raw + row * (size_t)y;
        unsigned long best = (unsigned long)-1;
        for (int t = 0; t < PNG_FILTERS; t++) {
            unsigned long cost = filter_row(t, cur, prev, n, tmp);
            if (cost < best) {
                best = cost;
                out[0] = (uint8_t)t;
                memcpy(out + 1, tmp, n);
            }
        }
    }
    frep_free(tmp);
    *len = row * (size_t)h;
    return raw;
}

static voidpf z_alloc(voidpf opaque, uInt items, uInt size)
{
    (void)opaque;
    return frep_reallocarray(NULL, items, size);
}

static void z_free(voidpf opaque, voidpf p)
{
    (void)opaque;
    frep_free(p);
}

/* The zlib stream of n bytes, written as IDAT chunks. Returns 0 or -1. */
static int write_idat(FILE *f, const uint8_t *raw, size_t n)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    z.zalloc = z_alloc;
    z.zfree = z_free;
    uint8_t *out = frep_malloc(PNG_IDAT_BYTES);
    if (!out || deflateInit(&z, Z_DEFAULT_COMPRESSION) != Z_OK) {
        frep_free(out);
        return -1;
    }
    int rc = 0, zr = Z_OK;
    size_t pos = 0;
    while (zr != Z_STREAM_END && rc == 0) {
        if (z.avail_in == 0 && pos < n) {
            uInt take = n - pos > (1u << 30) ? 1u << 30 : (uInt)(n - pos);
            z.next_in = (Bytef *)(uintptr_t)(raw + pos);
            z.avail_in = take;
            pos += take;
        }
        z.next_out = out;
        z.avail_out = PNG_IDAT_BYTES;
        zr = deflate(&z, pos == n ? Z_FINISH : Z_NO_FLUSH);
        if (zr != Z_OK && zr != Z_STREAM_END && zr != Z_BUF_ERROR) rc = -1;
        uint32_t got = PNG_IDAT_BYTES - z.avail_out;
        if (got) chunk(f, "IDAT", out, got);
    }
    deflateEnd(&z);
    frep_free(out);
    return rc;
}

int png_write_rgb(FILE *f, const uint8_t *rgb, int w, int h)
{
    if (w < 1 || h < 1 || w > PNG_MAX_SIDE || h > PNG_MAX_SIDE) return -1;
    size_t n;
    uint8_t *raw = filter_image(rgb, w, h, &n);
    if (!raw) return -1;
    static const uint8_t sig[8] = { 137, 80, 78, 71, 13, 10, 26, 10 };
    fwrite(sig, 1, 8, f);
    uint8_t ihdr[13];
    be32(ihdr, (uint32_t)w);
    be32(ihdr + 4, (uint32_t)h);
    ihdr[8] = 8;  /* bit depth */
    ihdr[9] = 2;  /* colour type: RGB */
    ihdr[10] = ihdr[11] = ihdr[12] = 0;
    chunk(f, "IHDR", ihdr, 13);
    int rc = write_idat(f, raw, n);
    frep_free(raw);
    if (rc != 0) return -1;
    chunk(f, "IEND", NULL, 0);
    return ferror(f) ? -1 : 0;
}

/* png.c - the minimal PNG encoder of png.h: a signature, IHDR, IDAT chunks holding a
 * zlib stream of stored (uncompressed) deflate blocks, and IEND.
 * Used by mesh/render.c through `frep render`.
 */
#include "config.h"

#include "alloc.h"
#include "png.h"

#include <stdlib.h>
#include <string.h>

/* Largest stored deflate block (its length field is 16 bits). */
#define PNG_STORED_MAX 65535u
/* Bytes per IDAT chunk: any size works; a few stored blocks per chunk. */
#define PNG_IDAT_BYTES (4u * (PNG_STORED_MAX + 5u))

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

int png_write_rgb(FILE *f, const uint8_t *rgb, int w, int h)
{
    if (w < 1 || h < 1 || w > PNG_MAX_SIDE || h > PNG_MAX_SIDE) return -1;
    static const uint8_t sig[8] = { 137, 80, 78, 71, 13, 10, 26, 10 };
    fwrite(sig, 1, 8, f);
    uint8_t ihdr[13];
    be32(ihdr, (uint32_t)w);
    be32(ihdr + 4, (uint32_t)h);
    ihdr[8] = 8;  /* bit depth */
    ihdr[9] = 2;  /* colour type: RGB */
    ihdr[10] = ihdr[11] = ihdr[12] = 0;
    chunk(f, "IHDR", ihdr, 13);

    /* raw scanlines: filter byte 0, then the row */
    size_t row = 1 + 3 * (size_t)w, raw_n = row * (size_t)h;
    uint8_t *raw = frep_malloc(raw_n);
    if (!raw) return -1;
    for (int y = 0; y < h; y++) {
        raw[row * (size_t)y] = 0;
        memcpy(raw + row * (size_t)y + 1, rgb + 3 * (size_t)w * (size_t)y, 3 * (size_t)w);
    }
    /* zlib stream: header, stored blocks, Adler-32 */
    size_t nblocks = (raw_n + PNG_STORED_MAX - 1) / PNG_STORED_MAX;
    size_t z_n = 2 + raw_n + 5 * nblocks + 4;
    uint8_t *z = frep_malloc(z_n);
    if (!z) {
        frep_free(raw);
        return -1;
    }
    size_t o = 0;
    z[o++] = 0x78; /* deflate, 32K window */
    z[o++] = 0x01; /* no preset dictionary, check bits make 0x7801 % 31 == 0 */
    uint32_t a = 1, b = 0;
    for (size_t pos = 0; pos < raw_n;) {
        size_t n = raw_n - pos < PNG_STORED_MAX ? raw_n - pos : PNG_STORED_MAX;
        z[o++] = pos + n == raw_n ? 1 : 0; /* BFINAL, BTYPE = 00 (stored) */
        z[o++] = (uint8_t)n;
        z[o++] = (uint8_t)(n >> 8);
        z[o++] = (uint8_t)~n;
        z[o++] = (uint8_t)(~n >> 8);
        memcpy(z + o, raw + pos, n);
        for (size_t i = 0; i < n; i++) {
            a = (a + raw[pos + i]) % 65521u;
            b = (b + a) % 65521u;
        }
        o += n;
        pos += n;
    }
    be32(z + o, (b << 16) | a);
    o += 4;
    for (size_t pos = 0; pos < o; pos += PNG_IDAT_BYTES) {
        size_t n = o - pos < PNG_IDAT_BYTES ? o - pos : PNG_IDAT_BYTES;
        chunk(f, "IDAT", z + pos, (uint32_t)n);
    }
    chunk(f, "IEND", NULL, 0);
    frep_free(raw);
    frep_free(z);
    return ferror(f) ? -1 : 0;
}

/* page.c - the self-contained HTML page of page.h: the JSON of a scene (base64 typed
 * arrays, escaped strings) spliced into the viewer template at its placeholder.
 *
 * Compact arrays: positions are 16-bit fractions of the box they span (1/65535 of it,
 * far below a pixel and below the polygonizer's grid), triangle corners the zigzag
 * LEB128 varints of their differences (neighbouring triangles share vertices, so most
 * take one or two bytes), normals one signed byte a component.  About 10 bytes a
 * triangle instead of 20 for Float32 and Uint32.
 */
#include "config.h"

#include "alloc.h"
#include "page.h"

#include <math.h>
#include <string.h>

/* The line of view/viewer.html that the scene replaces. */
#define VIEW_PLACEHOLDER "/*@FREP_SCENE@*/"

/* Base64 of a byte stream produced a few bytes at a time. */
typedef struct b64 {
    frep_buf *b;
    unsigned char pend[3];
    int npend;
} b64;

static void b64_flush3(b64 *s)
{
    static const char al[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const unsigned char *p = s->pend;
    char out[4] = { al[p[0] >> 2], al[((p[0] & 3) << 4) | (p[1] >> 4)],
                    s->npend > 1 ? al[((p[1] & 15) << 2) | (p[2] >> 6)] : '=',
                    s->npend > 2 ? al[p[2] & 63] : '=' };
    buf_put(s->b, out, 4);
    s->npend = 0;
    memset(s->pend, 0, sizeof s->pend);
}

static void b64_byte(b64 *s, unsigned char c)
{
    s->pend[s->npend++] = c;
    if (s->npend == 3) b64_flush3(s);
}

/* v as an IEEE half (binary16: sign, 5 exponent bits, 10 fraction bits), rounded to
 * nearest; beyond 65504 +-infinity, NaN a NaN.  A value too small for a half keeps
 * its sign as the smallest one (+-2^-24): the viewer counts the points inside the
 * solid by d > 0. */
uint16_t view_half(double v)
{
    uint16_t sign = signbit(v) ? 0x8000 : 0;
    double a = fabs(v);
    if (isnan(v)) return 0x7e00;
    if (a == 0) return sign;
    if (!(a < 65520)) return sign | 0x7c00;  /* 65520 and up round to infinity */
    int ex;
    double m = frexp(a, &ex);                 /* a = m 2^ex, m in [0.5, 1) */
    if (ex < -13) {                           /* below 2^-14: a subnormal, 2^-24 steps */
        long q = lrint(a * 16777216.0);       /* a / 2^-24 */
        return (uint16_t)(sign | (q > 0 ? q : 1));
    }
    long q = lrint(m * 2048.0);               /* 11 significant bits, 1024..2048 */
    if (q == 2048) {
        q = 1024;
        ex++;
    }
    return (uint16_t)(sign | ((unsigned)(ex + 14) << 10) | (unsigned)(q - 1024));
}

static void b64_end(b64 *s)
{
    if (s->npend) b64_flush3(s);
}

static void b64_u16(b64 *s, unsigned v)
{
    b64_byte(s, (unsigned char)v);
    b64_byte(s, (unsigned char)(v >> 8));
}

/* Corner c after corner prev: zigzag, then LEB128 (7 bits a byte, low first). */
static void b64_delta(b64 *s, uint32_t prev, uint32_t c)
{
    int64_t d = (int64_t)c - (int64_t)prev;
    uint64_t z = d >= 0 ? (uint64_t)d << 1 : (((uint64_t)(-d)) << 1) - 1;
    do {
        unsigned char byte = (unsigned char)(z & 127);
        z >>= 7;
        b64_byte(s, (unsigned char)(byte | (z ? 128 : 0)));
    } while (z);
}

/* The bounds of n points (three arrays, or interleaved xyz when y is NULL). */
static void bounds(size_t n, const double *x, const double *y, const double *z, double lo[3],
                   double hi[3])
{
    for (int k = 0; k < 3; k++) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (size_t i = 0; i < n; i++) {
        double p[3] = { y ? x[i] : x[3 * i], y ? y[i] : x[3 * i + 1], y ? z[i] : x[3 * i + 2] };
        for (int k = 0; k < 3; k++)
            if (isfinite(p[k])) {
                lo[k] = fmin(lo[k], p[k]);
                hi[k] = fmax(hi[k], p[k]);
            }
    }
    for (int k = 0; k < 3; k++)
        if (!(lo[k] <= hi[k])) lo[k] = hi[k] = 0;
}

/* v as a 16-bit fraction of [lo, hi]. */
static unsigned quantize(double v, double lo, double hi)
{
    double t = hi > lo ? (v - lo) / (hi - lo) : 0;
    t = isfinite(t) ? fmax(0, fmin(1, t)) : 0;
    return (unsigned)lrint(65535 * t);
}

/* "lo":[..],"hi":[..],"pos":"<base64 Uint16 x y z ...>" of n points. */
static void q16_xyz(frep_buf *b, size_t n, const double *x, const double *y, const double *z)
{
    double lo[3], hi[3];
    bounds(n, x, y, z, lo, hi);
    buf_printf(b, "\"lo\":[%.9g,%.9g,%.9g],\"hi\":[%.9g,%.9g,%.9g],\"pos\":\"", lo[0], lo[1],
               lo[2], hi[0], hi[1], hi[2]);
    b64 s = { b, { 0 }, 0 };
    for (size_t i = 0; i < n; i++) {
        double p[3] = { y ? x[i] : x[3 * i], y ? y[i] : x[3 * i + 1], y ? z[i] : x[3 * i + 2] };
        for (int k = 0; k < 3; k++) b64_u16(&s, quantize(p[k], lo[k], hi[k]));
    }
    b64_end(&s);
    buf_putc(b, '"');
}

/* The characters of s in a JSON string, safe inside a <script> element ('<' escaped). */
static void json_chars(frep_buf *b, const char *s)
{
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        if (*p == '"' || *p == '\\') {
            buf_putc(b, '\\');
            buf_putc(b, (char)*p);
        } else if (*p == '\n') buf_puts(b, "\\n");
        else if (*p < 0x20 || *p == '<' || *p == '>' || *p == '&') buf_printf(b, "\\u%04x", *p);
        else buf_putc(b, (char)*p);
    }
}

/* A JSON string of s then t (either may be NULL; both NULL: null). */
static void json_str2(frep_buf *b, const char *s, const char *t)
{
    if (!s && !t) {
        buf_puts(b, "null");
        return;
    }
    buf_putc(b, '"');
    if (s) json_chars(b, s);
    if (t) json_chars(b, t);
    buf_putc(b, '"');
}

static void json_str(frep_buf *b, const char *s)
{
    json_str2(b, s, NULL);
}

/* A number JSON can hold: non-finite values become null. */
static void json_num(frep_buf *b, double v)
{
    if (isfinite(v)) buf_printf(b, "%.9g", v);
    else buf_puts(b, "null");
}

/* n values as base64 little-endian halves (view_half): colours and counts need no
 * more than its three significant digits. */
static void f16_array(frep_buf *b, size_t n, const double *x)
{
    b64 s = { b, { 0 }, 0 };
    buf_putc(b, '"');
    for (size_t i = 0; i < n; i++) b64_u16(&s, view_half(x[i]));
    b64_end(&s);
    buf_putc(b, '"');
}

/* The mesh: 16-bit positions in its bounds, Int8 normals, Uint8 colours (rgb: NULL
 * for none), varint corner deltas. */
static void json_mesh(frep_buf *b, const frep_mesh *m, const unsigned char *rgb)
{
    buf_printf(b, "{\"nv\":%zu,\"nt\":%zu,", m->nverts, m->ntris);
    q16_xyz(b, m->nverts, m->v, NULL, NULL);
    b64 s = { b, { 0 }, 0 };
    buf_puts(b, ",\"nrm\":");
    if (m->n) {
        buf_putc(b, '"');
        for (size_t i = 0; i < 3 * m->nverts; i++) {
            double c = m->n[i];
            c = isfinite(c) ? fmax(-1, fmin(1, c)) : 0;
            b64_byte(&s, (unsigned char)(signed char)lrint(127 * c));
        }
        b64_end(&s);
        buf_putc(b, '"');
    } else buf_puts(b, "null");
    buf_puts(b, ",\"rgb\":");
    if (rgb) {
        buf_putc(b, '"');
        for (size_t i = 0; i < 3 * m->nverts; i++) b64_byte(&s, rgb[i]);
        b64_end(&s);
        buf_putc(b, '"');
    } else buf_puts(b, "null");
    buf_puts(b, ",\"idx\":\"");
    for (size_t i = 0; i < 3 * m->ntris; i++) b64_delta(&s, i ? m->tri[i - 1] : 0, m->tri[i]);
    b64_end(&s);
    buf_puts(b, "\"}");
}

static void json_points(frep_buf *b, const view_scene *s)
{
    buf_printf(b, "{\"n\":%zu,", s->npoints);
    q16_xyz(b, s->npoints, s->px, s->py, s->pz);
    buf_puts(b, ",\"d\":");
    if (s->pdist) {
        /* a half keeps +-inf (no gradient) as it is; the viewer saturates it */
        f16_array(b, s->npoints, s->pdist);
    } else buf_puts(b, "null");
    buf_puts(b, ",\"scale\":");
    json_num(b, s->pscale);
    buf_putc(b, '}');
}

void view_scene_json(frep_buf *b, const view_scene *s)
{
    buf_printf(b, "{\"version\":%u,\"name\":", s->version);
    json_str(b, s->name);
    buf_puts(b, ",\"units\":");
    json_str(b, s->units ? s->units : "model units");
    buf_puts(b, ",\"info\":");
    json_str(b, s->info);
    buf_puts(b, ",\"source\":");
    json_str(b, s->source);
    buf_puts(b, ",\"diag\":");
    json_str2(b, s->diag, s->cdiag);
    buf_printf(b, ",\"failed\":%s", s->failed ? "true" : "false");
    buf_puts(b, ",\"params\":[");
    for (size_t i = 0; i < s->nparams; i++) {
        buf_puts(b, i ? ",[" : "[");
        json_str(b, s->pnames[i]);
        buf_putc(b, ',');
        json_num(b, s->pvalues[i]);
        buf_putc(b, ']');
    }
    buf_puts(b, "],\"mesh\":");
    if (s->mesh && s->mesh->ntris) json_mesh(b, s->mesh, s->vrgb);
    else buf_puts(b, "null");
    buf_puts(b, ",\"vdist\":");
    if (s->mesh && s->mesh->ntris && s->vdist) {
        buf_puts(b, "{\"d\":");
        f16_array(b, s->mesh->nverts, s->vdist);
        buf_puts(b, ",\"scale\":");
        json_num(b, s->vscale);
        buf_putc(b, '}');
    } else buf_puts(b, "null");
    buf_puts(b, ",\"points\":");
    if (s->npoints && s->px) json_points(b, s);
    else buf_puts(b, "null");
    buf_putc(b, '}');
}

char *view_page(const view_scene *s, int watch, size_t *len, frep_error *e)
{
    const char *at = strstr(view_template, VIEW_PLACEHOLDER);
    frep_buf b = FREP_BUF_INIT;
    if (!at) at = view_template + strlen(view_template);
    buf_put(&b, view_template, (size_t)(at - view_template));
    buf_printf(&b, "var FREP_WATCH = %d;\nvar FREP_SCENE = ", watch ? 1 : 0);
    view_scene_json(&b, s);
    buf_puts(&b, ";\n");
    if (*at) buf_puts(&b, at + strlen(VIEW_PLACEHOLDER));
    char *page = buf_finish(&b, len);
    if (!page) frep_error_nomem(e);
    return page;
}

int view_write_page(FILE *f, const view_scene *s, frep_error *e)
{
    size_t len;
    char *page = view_page(s, 0, &len, e);
    if (!page) return -1;
    int rc = fwrite(page, 1, len, f) == len ? 0 : -1;
    frep_free(page);
    if (rc != 0) return frep_error_set(e, FREP_EIO, "write failed");
    return 0;
}

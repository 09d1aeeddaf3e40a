/* meshio.c - triangle mesh files (meshio.h): writers for the output of `frep mesh`
 * and readers for the meshes `frep sample MESH` turns into point clouds.
 *
 * Readers take the whole file into memory and report the first problem as
 * "file:line: what" (binary formats: "file: what"); the library never prints.
 */
#include "config.h"

#include "alloc.h"
#include "file.h"
#include "meshio.h"
#include "ply.h"
#include "threads.h"
#include "util.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* PLY header limits: real headers are a few short lines. */
#define MESHIO_PLY_MAX_PROPS 64
#define MESHIO_PLY_MAX_ELEMENTS 16
#define MESHIO_MAX_POLY 1024 /* vertices of one polygon: more is a corrupt file */

meshio_format meshio_format_for_path(const char *path)
{
    const char *dot = strrchr(path, '.');
    if (!dot) return MESHIO_UNKNOWN;
    char ext[8] = { 0 };
    size_t n = strlen(dot + 1);
    if (n == 0 || n >= sizeof ext) return MESHIO_UNKNOWN;
    for (size_t i = 0; i < n && i < sizeof ext - 1; i++)
        ext[i] = (char)tolower((unsigned char)dot[1 + i]);
    if (strcmp(ext, "stl") == 0) return MESHIO_STL;
    if (strcmp(ext, "obj") == 0) return MESHIO_OBJ;
    if (strcmp(ext, "ply") == 0) return MESHIO_PLY;
    if (strcmp(ext, "off") == 0) return MESHIO_OFF;
    if (strcmp(ext, "wrl") == 0) return MESHIO_WRL;
    return MESHIO_UNKNOWN;
}

const char *meshio_format_name(meshio_format f)
{
    switch (f) {
    case MESHIO_STL: return "STL";
    case MESHIO_OBJ: return "OBJ";
    case MESHIO_PLY: return "PLY";
    case MESHIO_OFF: return "OFF";
    case MESHIO_WRL: return "VRML";
    case MESHIO_UNKNOWN: break;
    }
    return "unknown";
}

/* ---- writers ---------------------------------------------------------------------- */

static void put_f32(unsigned char *b, double v)
{
    float f = (float)v;
    uint32_t u;
    memcpy(&u, &f, 4);
    for (int i = 0; i < 4; i++) b[i] = (unsigned char)(u >> (8 * i));
}

static void put_u32(unsigned char *b, uint32_t u)
{
    for (int i = 0; i < 4; i++) b[i] = (unsigned char)(u >> (8 * i));
}

static void face_normal(const frep_mesh *m, size_t t, double n[3])
{
    const double *a = &m->v[3 * m->tri[3 * t]], *b = &m->v[3 * m->tri[3 * t + 1]],
                 *c = &m->v[3 * m->tri[3 * t + 2]];
    double u[3] = { b[0] - a[0], b[1] - a[1], b[2] - a[2] };
    double w[3] = { c[0] - a[0], c[1] - a[1], c[2] - a[2] };
    n[0] = u[1] * w[2] - u[2] * w[1];
    n[1] = u[2] * w[0] - u[0] * w[2];
    n[2] = u[0] * w[1] - u[1] * w[0];
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    double il = l > 0 ? 1 / l : 0;
    for (int k = 0; k < 3; k++) n[k] *= il;
}

/* ---- text, formatted in parallel ----------------------------------------------------
 * A text format's lines (OFF, OBJ, ASCII PLY and STL, VRML) are formatted TEXT_CHUNK
 * items at a time into a chunk's own buffer, up to TEXT_ROUND chunks per thread at
 * once on the default thread count (frep_par_for), then written in order: the same
 * bytes as one fprintf per line, which had `frep mesh -o x.off` spend half its time
 * in the formatting, on one thread.  A section of fewer than TEXT_MIN_PAR items is
 * formatted on the calling thread alone. */
#define TEXT_CHUNK 2048
#define TEXT_ROUND 8
#define TEXT_MIN_PAR 16384

/* Item i of a section into out (at most cap bytes, with the terminating 0); returns
 * its length, as snprintf does. */
typedef int (*text_item_fn)(char *out, size_t cap, const void *ctx, size_t i);

typedef struct text_job {
    text_item_fn fn;
    const void *ctx;
    size_t n, base, cap; /* items; the round's first; bytes an item may take */
    char *buf;           /* a chunk's TEXT_CHUNK * cap bytes each */
    size_t *len;         /* bytes each chunk holds; SIZE_MAX: an item did not fit */
} text_job;

static void text_chunks(void *ctx, int thread, long c0, long c1)
{
    text_job *j = ctx;
    (void)thread;
    for (long c = c0; c < c1; c++) {
        char *out = j->buf + (size_t)c * TEXT_CHUNK * j->cap;
        size_t i0 = j->base + (size_t)c * TEXT_CHUNK, i1 = i0 + TEXT_CHUNK, len = 0;
        if (i1 > j->n) i1 = j->n;
        for (size_t i = i0; i < i1 && len != SIZE_MAX; i++) {
            int k = j->fn(out + len, j->cap, j->ctx, i);
            len = k >= 0 && (size_t)k < j->cap ? len + (size_t)k : SIZE_MAX;
        }
        j->len[c] = len;
    }
}

/* The largest item any writer formats (an ASCII STL facet, STL_FACET_MAX). */
#define TEXT_ITEM_MAX 384

/* Items [0, n) one at a time through a buffer on the stack: what write_text does
 * when its buffers cannot be had (the same bytes, on one thread). */
static int write_items(FILE *f, size_t n, size_t cap, text_item_fn fn, const void *ctx)
{
    char line[TEXT_ITEM_MAX];
    for (size_t i = 0; i < n; i++) {
        int k = fn(line, cap, ctx, i);
        if (k < 0 || (size_t)k >= cap) {
            errno = EOVERFLOW;
            return -1;
        }
        if (fwrite(line, 1, (size_t)k, f) != (size_t)k) return -1;
    }
    return 0;
}

/* Write items [0, n) of a section whose items take fewer than cap (at most
 * TEXT_ITEM_MAX) bytes each. */
static int write_text(FILE *f, size_t n, size_t cap, text_item_fn fn, const void *ctx)
{
    if (n == 0) return 0;
    int nt = n < TEXT_MIN_PAR ? 1 : frep_threads(0);
    size_t per = (size_t)nt * TEXT_ROUND, need = (n + TEXT_CHUNK - 1) / TEXT_CHUNK;
    if (per > need) per = need;   /* a small section gets buffers for its own lines */
    text_job j = { fn, ctx, n, 0, cap, frep_malloc(per * TEXT_CHUNK * cap),
                   frep_malloc(per * sizeof(size_t)) };
    int rc = 0;
    if (!j.buf || !j.len) {
        frep_free(j.buf);
        frep_free(j.len);
        return write_items(f, n, cap, fn, ctx);
    }
    for (; rc == 0 && j.base < n; j.base += per * TEXT_CHUNK) {
        size_t chunks = (n - j.base + TEXT_CHUNK - 1) / TEXT_CHUNK;
        if (chunks > per) chunks = per;
        frep_par_for(nt, (long)chunks, 1, text_chunks, &j);
        for (size_t c = 0; c < chunks && rc == 0; c++) {
            if (j.len[c] == SIZE_MAX) {
                errno = EOVERFLOW;
                rc = -1;
            } else if (fwrite(j.buf + c * TEXT_CHUNK * cap, 1, j.len[c], f) != j.len[c]) {
                rc = -1;
            }
        }
    }
    frep_free(j.buf);
    frep_free(j.len);
    return rc;
}

/* Bytes a line of up to six %.10g numbers and a few words takes at most: each number
 * 17 ("-1.234567891e-308"), an index 10. */
#define TEXT_LINE_MAX 128

/* A line of three numbers of v, printed by fmt (a literal of the writers below with
 * three double conversions). */
typedef struct triple {
    const double *v;
    const char *fmt;
} triple;

static int item_triple(char *out, size_t cap, const void *ctx, size_t i)
{
    const triple *t = ctx;
    const double *v = t->v + 3 * i;
    return snprintf(out, cap, t->fmt, v[0], v[1], v[2]);
}

/* v in decimal at out, as %u prints it (snprintf's own set-up costs more than the
 * digits of an index); returns the digits' count, at most 10. */
static size_t put_dec(char *out, uint32_t v)
{
    char d[10];
    size_t k = 0;
    do {
        d[k++] = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    for (size_t i = 0; i < k; i++) out[i] = d[k - 1 - i];
    return k;
}

static size_t put_str(char *out, const char *s)
{
    size_t k = 0;
    for (; s[k]; k++) out[k] = s[k];
    return k;
}

/* A triangle's line: `head`, the three indices `sep` apart (each twice, joined by
 * `dup`, when dup is not NULL: OBJ's "a//a"), `tail`.  At most 3 x 21 bytes and the
 * strings', well under TEXT_LINE_MAX for the formats' short words. */
static int put_tri(char *out, const char *head, const uint32_t v[3], const char *sep,
                   const char *dup, const char *tail)
{
    size_t len = put_str(out, head);
    for (int k = 0; k < 3; k++) {
        if (k) len += put_str(out + len, sep);
        len += put_dec(out + len, v[k]);
        if (dup) {
            len += put_str(out + len, dup);
            len += put_dec(out + len, v[k]);
        }
    }
    len += put_str(out + len, tail);
    out[len] = 0;
    return (int)len;
}

static int item_tri3(char *out, size_t cap, const void *ctx, size_t i)
{
    (void)cap;
    return put_tri(out, "3 ", (const uint32_t *)ctx + 3 * i, " ", NULL, "\n");
}

/* Binary STL records written per fwrite: one call per triangle cost more than
 * computing the record. */
#define STL_BATCH 256

/* An ASCII STL facet: five lines, four of them with three %.9g numbers (16 bytes). */
#define STL_FACET_MAX 384

static int item_stl_facet(char *out, size_t cap, const void *ctx, size_t t)
{
    const frep_mesh *m = ctx;
    double n[3];
    face_normal(m, t, n);
    const double *a = &m->v[3 * m->tri[3 * t]], *b = &m->v[3 * m->tri[3 * t + 1]],
                 *c = &m->v[3 * m->tri[3 * t + 2]];
    return snprintf(out, cap,
                    "  facet normal %.9g %.9g %.9g\n    outer loop\n"
                    "      vertex %.9g %.9g %.9g\n      vertex %.9g %.9g %.9g\n"
                    "      vertex %.9g %.9g %.9g\n    endloop\n  endfacet\n",
                    n[0], n[1], n[2], a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]);
}

static int write_stl(FILE *f, const frep_mesh *m, int ascii)
{
    if (ascii) {
        fprintf(f, "solid frep\n");
        if (write_text(f, m->ntris, STL_FACET_MAX, item_stl_facet, m)) return -1;
        fprintf(f, "endsolid frep\n");
        return ferror(f) ? -1 : 0;
    }
    unsigned char head[84];
    memset(head, 0, sizeof head);
    snprintf((char *)head, 80, "binary STL written by frep");
    put_u32(head + 80, (uint32_t)m->ntris);
    fwrite(head, 1, sizeof head, f);
    unsigned char buf[50 * STL_BATCH];
    size_t nb = 0;
    for (size_t t = 0; t < m->ntris; t++) {
        unsigned char *rec = buf + 50 * nb;
        double n[3];
        face_normal(m, t, n);
        for (int k = 0; k < 3; k++) put_f32(rec + 4 * k, n[k]);
        for (int v = 0; v < 3; v++) {
            const double *p = &m->v[3 * m->tri[3 * t + v]];
            for (int k = 0; k < 3; k++) put_f32(rec + 12 + 12 * v + 4 * k, p[k]);
        }
        rec[48] = rec[49] = 0;
        if (++nb == STL_BATCH) {
            fwrite(buf, 50, nb, f);
            nb = 0;
        }
    }
    if (nb) fwrite(buf, 50, nb, f);
    return ferror(f) ? -1 : 0;
}

static int item_obj_f(char *out, size_t cap, const void *ctx, size_t i)
{
    const frep_mesh *m = ctx;
    uint32_t v[3] = { m->tri[3 * i] + 1, m->tri[3 * i + 1] + 1, m->tri[3 * i + 2] + 1 };
    (void)cap;
    return put_tri(out, "f ", v, " ", m->n ? "//" : NULL, "\n");
}

static int write_obj(FILE *f, const frep_mesh *m)
{
    fprintf(f, "# written by frep: %zu vertices, %zu triangles\n", m->nverts, m->ntris);
    triple v = { m->v, "v %.10g %.10g %.10g\n" }, vn = { m->n, "vn %.6g %.6g %.6g\n" };
    if (write_text(f, m->nverts, TEXT_LINE_MAX, item_triple, &v) ||
        (m->n && write_text(f, m->nverts, TEXT_LINE_MAX, item_triple, &vn)) ||
        write_text(f, m->ntris, TEXT_LINE_MAX, item_obj_f, m))
        return -1;
    return ferror(f) ? -1 : 0;
}

typedef struct colored {
    const frep_mesh *m;
    const uint8_t *rgb;
} colored;

static int item_ply_vertex(char *out, size_t cap, const void *ctx, size_t i)
{
    const colored *o = ctx;
    const double *v = &o->m->v[3 * i], *n = o->m->n ? &o->m->n[3 * i] : NULL;
    const uint8_t *c = o->rgb ? &o->rgb[3 * i] : NULL;
    if (n && c)
        return snprintf(out, cap, "%.9g %.9g %.9g %.9g %.9g %.9g %u %u %u\n", v[0], v[1], v[2],
                        n[0], n[1], n[2], c[0], c[1], c[2]);
    if (n)
        return snprintf(out, cap, "%.9g %.9g %.9g %.9g %.9g %.9g\n", v[0], v[1], v[2], n[0],
                        n[1], n[2]);
    if (c) return snprintf(out, cap, "%.9g %.9g %.9g %u %u %u\n", v[0], v[1], v[2], c[0], c[1], c[2]);
    return snprintf(out, cap, "%.9g %.9g %.9g\n", v[0], v[1], v[2]);
}

static int write_ply(FILE *f, const frep_mesh *m, const uint8_t *rgb, int ascii)
{
    fprintf(f, "ply\nformat %s 1.0\ncomment written by frep\nelement vertex %zu\n"
               "property float x\nproperty float y\nproperty float z\n",
            ascii ? "ascii" : "binary_little_endian", m->nverts);
    if (m->n) fprintf(f, "property float nx\nproperty float ny\nproperty float nz\n");
    if (rgb) fprintf(f, "property uchar red\nproperty uchar green\nproperty uchar blue\n");
    fprintf(f, "element face %zu\nproperty list uchar int vertex_indices\nend_header\n", m->ntris);
    if (ascii) {
        colored o = { m, rgb };
        if (write_text(f, m->nverts, TEXT_LINE_MAX, item_ply_vertex, &o) ||
            write_text(f, m->ntris, TEXT_LINE_MAX, item_tri3, m->tri))
            return -1;
        return ferror(f) ? -1 : 0;
    }
    int nc = m->n ? 6 : 3;
    for (size_t i = 0; i < m->nverts; i++) {
        unsigned char b[27];
        for (int k = 0; k < 3; k++) {
            put_f32(b + 4 * k, m->v[3 * i + k]);
            if (m->n) put_f32(b + 12 + 4 * k, m->n[3 * i + k]);
        }
        if (rgb) memcpy(b + 4 * nc, &rgb[3 * i], 3);
        fwrite(b, 1, 4 * (size_t)nc + (rgb ? 3 : 0), f);
    }
    for (size_t t = 0; t < m->ntris; t++) {
        unsigned char b[13];
        b[0] = 3;
        for (int k = 0; k < 3; k++) put_u32(b + 1 + 4 * k, m->tri[3 * t + k]);
        fwrite(b, 1, sizeof b, f);
    }
    return ferror(f) ? -1 : 0;
}

static int item_wrl_color(char *out, size_t cap, const void *ctx, size_t i)
{
    const uint8_t *c = (const uint8_t *)ctx + 3 * i;
    return snprintf(out, cap, "        %.6g %.6g %.6g,\n", c[0] / 255.0, c[1] / 255.0, c[2] / 255.0);
}

static int item_wrl_index(char *out, size_t cap, const void *ctx, size_t i)
{
    (void)cap;
    return put_tri(out, "      ", (const uint32_t *)ctx + 3 * i, ", ", NULL, ", -1,\n");
}

/* VRML 2.0: one Shape whose IndexedFaceSet holds the triangles (counter-clockwise
 * seen from outside, as frep's meshes are), the vertex normals when present and the
 * vertex colours (a Color node, colorPerVertex) or a Material's diffuse colour. */
static int write_wrl(FILE *f, const frep_mesh *m, const uint8_t *rgb)
{
    static const int def[3] = { MESHIO_WRL_DEFAULT_RGB };
    fprintf(f, "#VRML V2.0 utf8\n# written by frep: %zu vertices, %zu triangles\n"
               "Shape {\n  appearance Appearance {\n    material Material {", m->nverts,
            m->ntris);
    if (!rgb)
        fprintf(f, " diffuseColor %.6g %.6g %.6g", def[0] / 255.0, def[1] / 255.0, def[2] / 255.0);
    fprintf(f, " }\n  }\n  geometry IndexedFaceSet {\n    solid TRUE\n    ccw TRUE\n"
               "    coord Coordinate {\n      point [\n");
    triple point = { m->v, "        %.9g %.9g %.9g,\n" }, vector = { m->n, "        %.6g %.6g %.6g,\n" };
    if (write_text(f, m->nverts, TEXT_LINE_MAX, item_triple, &point)) return -1;
    fprintf(f, "      ]\n    }\n");
    if (m->n) {
        fprintf(f, "    normalPerVertex TRUE\n    normal Normal {\n      vector [\n");
        if (write_text(f, m->nverts, TEXT_LINE_MAX, item_triple, &vector)) return -1;
        fprintf(f, "      ]\n    }\n");
    }
    if (rgb) {
        fprintf(f, "    colorPerVertex TRUE\n    color Color {\n      color [\n");
        if (write_text(f, m->nverts, TEXT_LINE_MAX, item_wrl_color, rgb)) return -1;
        fprintf(f, "      ]\n    }\n");
    }
    fprintf(f, "    coordIndex [\n");
    if (write_text(f, m->ntris, TEXT_LINE_MAX, item_wrl_index, m->tri)) return -1;
    fprintf(f, "    ]\n  }\n}\n");
    return ferror(f) ? -1 : 0;
}

static int write_off(FILE *f, const frep_mesh *m)
{
    fprintf(f, "OFF\n%zu %zu 0\n", m->nverts, m->ntris);
    triple v = { m->v, "%.10g %.10g %.10g\n" };
    if (write_text(f, m->nverts, TEXT_LINE_MAX, item_triple, &v) ||
        write_text(f, m->ntris, TEXT_LINE_MAX, item_tri3, m->tri))
        return -1;
    return ferror(f) ? -1 : 0;
}

int meshio_write(FILE *f, const frep_mesh *m, meshio_format fmt, int ascii)
{
    return meshio_write_colored(f, m, NULL, fmt, ascii);
}

int meshio_write_colored(FILE *f, const frep_mesh *m, const uint8_t *rgb, meshio_format fmt,
                         int ascii)
{
    switch (fmt) {
    case MESHIO_STL: return write_stl(f, m, ascii);
    case MESHIO_OBJ: return write_obj(f, m);
    case MESHIO_PLY: return write_ply(f, m, rgb, ascii);
    case MESHIO_OFF: return write_off(f, m);
    case MESHIO_WRL: return write_wrl(f, m, rgb);
    case MESHIO_UNKNOWN: break;
    }
    return -1;
}

/* ---- readers ---------------------------------------------------------------------- */

typedef struct mbuild {
    frep_mesh *m;
    size_t capv, capt;
} mbuild;

static int add_vertex(mbuild *b, double x, double y, double z)
{
    frep_mesh *m = b->m;
    if (m->nverts >= MESHIO_MAX_ELEMENTS) return -1;
    if (m->nverts == b->capv) {
        size_t cap = b->capv ? 2 * b->capv : 1024;
        double *nv = frep_realloc(m->v, 3 * cap * sizeof *nv);
        if (!nv) return -1;
        m->v = nv;
        b->capv = cap;
    }
    m->v[3 * m->nverts] = x;
    m->v[3 * m->nverts + 1] = y;
    m->v[3 * m->nverts + 2] = z;
    m->nverts++;
    return 0;
}

static int add_tri(mbuild *b, uint32_t a, uint32_t c, uint32_t d)
{
    frep_mesh *m = b->m;
    if (m->ntris >= MESHIO_MAX_ELEMENTS) return -1;
    if (m->ntris == b->capt) {
        size_t cap = b->capt ? 2 * b->capt : 1024;
        uint32_t *nt = frep_realloc(m->tri, 3 * cap * sizeof *nt);
        if (!nt) return -1;
        m->tri = nt;
        b->capt = cap;
    }
    m->tri[3 * m->ntris] = a;
    m->tri[3 * m->ntris + 1] = c;
    m->tri[3 * m->ntris + 2] = d;
    m->ntris++;
    return 0;
}

/* A polygon of n vertex indices (already 0-based and checked) as a triangle fan. */
static int add_poly(mbuild *b, const uint32_t *idx, size_t n)
{
    for (size_t i = 1; i + 1 < n; i++)
        if (add_tri(b, idx[0], idx[i], idx[i + 1]) != 0) return -1;
    return 0;
}

/* Line-oriented text cursor. */
typedef struct tcur {
    const char *p, *end;
    size_t line;
} tcur;

/* Next non-blank, non-comment line into [*s, *e); returns 0 at the end. */
static int next_line(tcur *c, const char **s, const char **e, char comment)
{
    while (c->p < c->end) {
        const char *ls = c->p;
        const char *le = memchr(ls, '\n', (size_t)(c->end - ls));
        if (!le) le = c->end;
        c->p = le < c->end ? le + 1 : le;
        c->line++;
        while (ls < le && isspace((unsigned char)*ls)) ls++;
        const char *te = le;
        while (te > ls && isspace((unsigned char)te[-1])) te--;
        if (ls == te || *ls == comment) continue;
        *s = ls;
        *e = te;
        return 1;
    }
    return 0;
}

/* Parse a number at *s (before e); advances *s. Returns 0 or -1. */
static int num(const char **s, const char *e, double *v)
{
    while (*s < e && (**s == ' ' || **s == '\t')) (*s)++;
    if (*s >= e) return -1;
    char buf[64];
    size_t n = 0;
    while (*s + n < e && !isspace((unsigned char)(*s)[n]) && n < sizeof buf - 1) {
        buf[n] = (*s)[n];
        n++;
    }
    buf[n] = '\0';
    char *end;
    errno = 0;
    *v = strtod(buf, &end);
    if (end == buf) return -1;
    *s += end - buf;
    return 0;
}

static int parse_off(const char *name, const char *data, size_t len, mbuild *b, frep_error *err)
{
    tcur c = { data, data + len, 0 };
    const char *s, *e;
    if (!next_line(&c, &s, &e, '#') || e - s < 3 || strncmp(s, "OFF", 3) != 0) {
        frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 'OFF' header", name, c.line ? c.line : 1);
        return -1;
    }
    s += 3;
    double nv, nf, ne;
    if (s >= e && !next_line(&c, &s, &e, '#')) {
        frep_error_set(err, FREP_EINPUT, "%s:%zu: missing vertex and face counts", name, c.line);
        return -1;
    }
    if (num(&s, e, &nv) || num(&s, e, &nf) || num(&s, e, &ne) || nv < 0 || nf < 0 ||
        nv > (double)MESHIO_MAX_ELEMENTS || nf > (double)MESHIO_MAX_ELEMENTS ||
        nv != floor(nv) || nf != floor(nf)) {
        frep_error_set(err, FREP_EINPUT, "%s:%zu: expected three counts 'vertices faces edges'", name, c.line);
        return -1;
    }
    for (size_t i = 0; i < (size_t)nv; i++) {
        double p[3];
        if (!next_line(&c, &s, &e, '#')) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: file ends after %zu of %zu vertices", name, c.line, i, (size_t)nv);
            return -1;
        }
        if (num(&s, e, &p[0]) || num(&s, e, &p[1]) || num(&s, e, &p[2])) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 3 coordinates", name, c.line);
            return -1;
        }
        if (add_vertex(b, p[0], p[1], p[2])) goto oom;
    }
    uint32_t idx[MESHIO_MAX_POLY];
    for (size_t i = 0; i < (size_t)nf; i++) {
        double k;
        if (!next_line(&c, &s, &e, '#')) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: file ends after %zu of %zu faces", name, c.line, i, (size_t)nf);
            return -1;
        }
        if (num(&s, e, &k) || k < 3 || k > MESHIO_MAX_POLY || k != floor(k)) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: expected a vertex count 3..%d", name, c.line, MESHIO_MAX_POLY);
            return -1;
        }
        for (size_t j = 0; j < (size_t)k; j++) {
            double v;
            if (num(&s, e, &v) || v < 0 || v >= nv || v != floor(v)) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: vertex index %zu of the face is missing or out of range 0..%zu",
                        name, c.line, j + 1, (size_t)nv - (nv > 0));
                return -1;
            }
            idx[j] = (uint32_t)v;
        }
        if (add_poly(b, idx, (size_t)k)) goto oom;
    }
    return 0;
oom:
    frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name);
    return -1;
}

static int parse_obj(const char *name, const char *data, size_t len, mbuild *b, frep_error *err)
{
    tcur c = { data, data + len, 0 };
    const char *s, *e;
    uint32_t idx[MESHIO_MAX_POLY];
    while (next_line(&c, &s, &e, '#')) {
        if (e - s >= 2 && s[0] == 'v' && (s[1] == ' ' || s[1] == '\t')) {
            double p[3];
            s += 2;
            if (num(&s, e, &p[0]) || num(&s, e, &p[1]) || num(&s, e, &p[2])) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 'v x y z'", name, c.line);
                return -1;
            }
            if (add_vertex(b, p[0], p[1], p[2])) goto oom;
        } else if (e - s >= 2 && s[0] == 'f' && (s[1] == ' ' || s[1] == '\t')) {
            size_t k = 0;
            s += 2;
            for (;;) {
                while (s < e && (*s == ' ' || *s == '\t')) s++;
                if (s >= e) break;
                char *endp;
                errno = 0;
                long v = strtol(s, &endp, 10);
                if (endp == s) {
                    frep_error_set(err, FREP_EINPUT, "%s:%zu: expected vertex indices after 'f'", name, c.line);
                    return -1;
                }
                /* 1-based; negative indices count back from the last vertex */
                long ix = v > 0 ? v - 1 : (long)b->m->nverts + v;
                if (v == 0 || ix < 0 || (size_t)ix >= b->m->nverts) {
                    frep_error_set(err, FREP_EINPUT, "%s:%zu: vertex index %ld out of range (1..%zu so far)", name, c.line,
                            v, b->m->nverts);
                    return -1;
                }
                if (k >= MESHIO_MAX_POLY) {
                    frep_error_set(err, FREP_EINPUT, "%s:%zu: polygon with more than %d vertices", name, c.line,
                            MESHIO_MAX_POLY);
                    return -1;
                }
                idx[k++] = (uint32_t)ix;
                s = endp;
                while (s < e && !isspace((unsigned char)*s)) s++; /* skip /vt/vn */
            }
            if (k < 3) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: a face needs at least 3 vertices", name, c.line);
                return -1;
            }
            if (add_poly(b, idx, k)) goto oom;
        }
        /* vn, vt, o, g, s, usemtl, mtllib: not needed for sampling */
    }
    return 0;
oom:
    frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name);
    return -1;
}

static double get_f32(const unsigned char *p, int big)
{
    uint32_t u = 0;
    for (int i = 0; i < 4; i++) u |= (uint32_t)p[big ? 3 - i : i] << (8 * i);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

static uint32_t get_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int parse_stl(const char *name, const char *data, size_t len, mbuild *b, frep_error *err)
{
    const unsigned char *u = (const unsigned char *)data;
    /* Binary when the size matches the triangle count (some binary files start with
     * "solid" too). */
    if (len >= 84) {
        uint32_t n = get_u32(u + 80);
        if ((uint64_t)84 + 50ull * n == len) {
            if (n > MESHIO_MAX_ELEMENTS / 3) {
                frep_error_set(err, FREP_EINPUT, "%s: too many triangles (%u)", name, n);
                return -1;
            }
            for (uint32_t t = 0; t < n; t++) {
                const unsigned char *r = u + 84 + 50 * (size_t)t + 12;
                uint32_t base = (uint32_t)b->m->nverts;
                for (int v = 0; v < 3; v++)
                    if (add_vertex(b, get_f32(r + 12 * v, 0), get_f32(r + 12 * v + 4, 0),
                                   get_f32(r + 12 * v + 8, 0)))
                        goto oom;
                if (add_tri(b, base, base + 1, base + 2)) goto oom;
            }
            return 0;
        }
    }
    tcur c = { data, data + len, 0 };
    const char *s, *e;
    if (!next_line(&c, &s, &e, '\0') || e - s < 5 || strncmp(s, "solid", 5) != 0) {
        frep_error_set(err, FREP_EINPUT, "%s: neither binary STL (size does not match the triangle count) nor ASCII "
                "STL (no 'solid')", name);
        return -1;
    }
    int nv = 0;
    while (next_line(&c, &s, &e, '\0')) {
        if (e - s >= 6 && strncmp(s, "vertex", 6) == 0) {
            double p[3];
            s += 6;
            if (num(&s, e, &p[0]) || num(&s, e, &p[1]) || num(&s, e, &p[2])) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 'vertex x y z'", name, c.line);
                return -1;
            }
            if (add_vertex(b, p[0], p[1], p[2])) goto oom;
            nv++;
        } else if (e - s >= 7 && strncmp(s, "endloop", 7) == 0) {
            if (nv < 3) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: a facet needs at least 3 vertices", name, c.line);
                return -1;
            }
            uint32_t base = (uint32_t)(b->m->nverts - (size_t)nv);
            for (int i = 1; i + 1 < nv; i++)
                if (add_tri(b, base, base + (uint32_t)i, base + (uint32_t)i + 1)) goto oom;
            nv = 0;
        }
    }
    return 0;
oom:
    frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name);
    return -1;
}

/* ---- PLY ---- */

typedef struct pprop {
    char name[32];
    frep_ply_type type, count_type;   /* count_type != FREP_PLY_NONE: a list */
} pprop;

typedef struct pelem {
    char name[32];
    size_t count;
    int nprops;
    pprop props[MESHIO_PLY_MAX_PROPS];
} pelem;

/* Values of one element record: fixed properties in v[], the first list in list[]. */
typedef struct prec {
    double v[MESHIO_PLY_MAX_PROPS];
    uint32_t list[MESHIO_MAX_POLY];
    size_t nlist;
} prec;

/* A PLY mesh being read: the header, then the body (one record a line in ASCII). */
typedef struct mesh_ply {
    const char *name;
    frep_error *err;
    tcur c;                  /* the lines; in a binary file the data start at c.p */
    pelem *el;
    int nel;
    int have_format;
    ply_format fmt;
    const char *s, *e;       /* ASCII: the rest of the current record's line */
    const unsigned char *bp, *bend; /* binary: the data left */
    size_t nverts_decl;      /* vertices of the last vertex element (face indices) */
} mesh_ply;

/* format TYPE ... */
static int ply_header_format(mesh_ply *h, char w[4][64])
{
    if (ply_format_of(w[1], &h->fmt))
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: unknown PLY format '%s'", h->name,
                              h->c.line, w[1]);
    h->have_format = 1;
    return 0;
}

/* element NAME COUNT ... */
static int ply_header_element(mesh_ply *h, char w[4][64])
{
    char *endp;
    double cnt = strtod(w[2], &endp);
    if (h->nel >= MESHIO_PLY_MAX_ELEMENTS || *endp || cnt < 0 ||
        cnt > (double)MESHIO_MAX_ELEMENTS || cnt != floor(cnt))
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: bad or too many elements", h->name,
                              h->c.line);
    snprintf(h->el[h->nel].name, sizeof h->el[h->nel].name, "%.31s", w[1]);
    h->el[h->nel].count = (size_t)cnt;
    h->nel++;
    return 0;
}

/* property TYPE NAME ... | property list COUNT-TYPE TYPE NAME ... (line: the whole) */
static int ply_header_property(mesh_ply *h, char w[4][64], int nw, const char *line)
{
    pelem *E = &h->el[h->nel - 1];
    if (E->nprops >= MESHIO_PLY_MAX_PROPS)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: too many properties", h->name,
                              h->c.line);
    pprop *P = &E->props[E->nprops++];
    if (strcmp(w[1], "list") == 0) {
        if (nw < 4 || (P->count_type = frep_ply_type_of(w[2])) == FREP_PLY_NONE ||
            (P->type = frep_ply_type_of(w[3])) == FREP_PLY_NONE)
            return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: bad list property", h->name,
                                  h->c.line);
        char nm[64] = "";
        sscanf(line, "%*s %*s %*s %*s %63s", nm);
        snprintf(P->name, sizeof P->name, "%.31s", nm);
        return 0;
    }
    if ((P->type = frep_ply_type_of(w[1])) == FREP_PLY_NONE)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: unknown property type '%s'",
                              h->name, h->c.line, w[1]);
    P->count_type = FREP_PLY_NONE;
    snprintf(P->name, sizeof P->name, "%.31s", w[2]);
    return 0;
}

/* The header after 'ply', up to end_header (lines cut at 255 characters, the first
 * four words read). */
static int ply_read_header(mesh_ply *h)
{
    const char *s, *e;
    for (;;) {
        if (!next_line(&h->c, &s, &e, '\0'))
            return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: header without end_header",
                                  h->name, h->c.line);
        char line[256], w[4][64];
        size_t n = (size_t)(e - s) < sizeof line - 1 ? (size_t)(e - s) : sizeof line - 1;
        memcpy(line, s, n);
        line[n] = '\0';
        int nw = sscanf(line, "%63s %63s %63s %63s", w[0], w[1], w[2], w[3]);
        int rc = 0;
        if (nw < 1) continue;
        if (strcmp(w[0], "end_header") == 0) break;
        if (strcmp(w[0], "comment") == 0 || strcmp(w[0], "obj_info") == 0) continue;
        if (strcmp(w[0], "format") == 0 && nw >= 2) rc = ply_header_format(h, w);
        else if (strcmp(w[0], "element") == 0 && nw >= 3) rc = ply_header_element(h, w);
        else if (strcmp(w[0], "property") == 0 && nw >= 3 && h->nel > 0)
            rc = ply_header_property(h, w, nw, line);
        else
            rc = frep_error_set(h->err, FREP_EINPUT, "%s:%zu: unexpected header line", h->name,
                                h->c.line);
        if (rc) return -1;
    }
    if (!h->have_format)
        return frep_error_set(h->err, FREP_EINPUT, "%s: PLY header without a format line",
                              h->name);
    return 0;
}

/* The next value of the record, of type t in a binary file; -1 when it is missing. */
static int ply_value(mesh_ply *h, frep_ply_type t, double *v)
{
    if (h->fmt == PLY_ASCII) return num(&h->s, h->e, v);
    return ply_binary_value(&h->bp, h->bend, t, h->fmt, v);
}

/* The short-record message (the data end inside a record). */
static int ply_short_record(const mesh_ply *h)
{
    if (h->fmt == PLY_ASCII)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: too few values in a record",
                              h->name, h->c.line);
    return frep_error_set(h->err, FREP_EINPUT, "%s: file ends inside the data", h->name);
}

/* One record of E into rec: scalars by property, the first list's vertex indices
 * (checked against the vertices declared so far). */
static int ply_read_record(mesh_ply *h, const pelem *E, prec *rec)
{
    rec->nlist = 0;
    int got_list = 0;
    if (h->fmt == PLY_ASCII && !next_line(&h->c, &h->s, &h->e, '\0'))
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: file ends inside element '%s'",
                              h->name, h->c.line, E->name);
    for (int k = 0; k < E->nprops; k++) {
        const pprop *P = &E->props[k];
        size_t cnt = 1;
        if (P->count_type != FREP_PLY_NONE) {
            double cv;
            if (ply_value(h, P->count_type, &cv)) return ply_short_record(h);
            if (!(cv >= 0 && cv <= MESHIO_MAX_POLY))
                return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: list of %g items in element '%s'",
                                      h->name, h->c.line, cv, E->name);
            cnt = (size_t)cv;
        }
        for (size_t j = 0; j < cnt; j++) {
            double v;
            if (ply_value(h, P->type, &v)) return ply_short_record(h);
            if (P->count_type == FREP_PLY_NONE) {
                rec->v[k] = v;
            } else if (!got_list) {
                if (!(v >= 0 && v < (double)h->nverts_decl))
                    return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: vertex index %g out of range",
                                          h->name, h->c.line, v);
                rec->list[rec->nlist++] = (uint32_t)v;
            }
        }
        if (P->count_type != FREP_PLY_NONE) got_list = 1;
    }
    return 0;
}

/* The records of element E: vertices (x, y, z) and faces (fans) go into b. */
static int ply_read_element(mesh_ply *h, const pelem *E, prec *rec, mbuild *b)
{
    int isv = strcmp(E->name, "vertex") == 0, isf = strcmp(E->name, "face") == 0;
    int ix = -1, iy = -1, iz = -1;
    for (int k = 0; k < E->nprops; k++) {
        if (strcmp(E->props[k].name, "x") == 0) ix = k;
        if (strcmp(E->props[k].name, "y") == 0) iy = k;
        if (strcmp(E->props[k].name, "z") == 0) iz = k;
    }
    if (isv && (ix < 0 || iy < 0 || iz < 0))
        return frep_error_set(h->err, FREP_EINPUT, "%s: the vertex element lacks x, y or z",
                              h->name);
    if (isv) h->nverts_decl = E->count;
    if (E->nprops == 0) return 0; /* records without properties hold no data */
    for (size_t r = 0; r < E->count; r++) {
        if (ply_read_record(h, E, rec)) return -1;
        if ((isv && add_vertex(b, rec->v[ix], rec->v[iy], rec->v[iz])) ||
            (isf && rec->nlist >= 3 && add_poly(b, rec->list, rec->nlist)))
            return frep_error_set(h->err, FREP_ENOMEM, "%s: out of memory", h->name);
    }
    return 0;
}

/* A PLY mesh: 'ply', the header, then every element's records. */
static int parse_ply(const char *name, const char *data, size_t len, mbuild *b, frep_error *err)
{
    mesh_ply h;
    memset(&h, 0, sizeof h);
    h.name = name;
    h.err = err;
    h.c = (tcur){ data, data + len, 0 };
    h.el = frep_calloc(MESHIO_PLY_MAX_ELEMENTS, sizeof *h.el);
    prec *rec = frep_malloc(sizeof *rec);
    int status = -1;
    const char *s, *e;
    if (!h.el || !rec) {
        frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name);
    } else if (!next_line(&h.c, &s, &e, '\0') || e - s != 3 || strncmp(s, "ply", 3) != 0) {
        frep_error_set(err, FREP_EINPUT, "%s:1: expected 'ply'", name);
    } else if (ply_read_header(&h) == 0) {
        h.bp = (const unsigned char *)h.c.p;
        h.bend = (const unsigned char *)h.c.end;
        status = 0;
        for (int ei = 0; ei < h.nel && status == 0; ei++)
            status = ply_read_element(&h, &h.el[ei], rec, b);
    }
    frep_free(h.el);
    frep_free(rec);
    return status;
}

int meshio_parse(const char *name, const char *data, size_t len, meshio_format fmt,
                 frep_mesh *m, frep_error *err)
{
    memset(m, 0, sizeof *m);
    frep_error_init(err);
    if (fmt == MESHIO_UNKNOWN) {
        if (len >= 3 && strncmp(data, "ply", 3) == 0) fmt = MESHIO_PLY;
        else if (len >= 3 && strncmp(data, "OFF", 3) == 0) fmt = MESHIO_OFF;
        else fmt = MESHIO_STL;
    }
    mbuild b = { m, 0, 0 };
    int rc = -1;
    switch (fmt) {
    case MESHIO_OFF: rc = parse_off(name, data, len, &b, err); break;
    case MESHIO_OBJ: rc = parse_obj(name, data, len, &b, err); break;
    case MESHIO_STL: rc = parse_stl(name, data, len, &b, err); break;
    case MESHIO_PLY: rc = parse_ply(name, data, len, &b, err); break;
    case MESHIO_WRL:
        frep_error_set(err, FREP_EINPUT, "%s: VRML files are written, not read", name);
        break;
    case MESHIO_UNKNOWN: break;
    }
    if (rc == 0 && m->ntris == 0) {
        frep_error_set(err, FREP_EINPUT, "%s: the mesh has no triangles", name);
        rc = -1;
    }
    for (size_t i = 0; rc == 0 && i < 3 * m->nverts; i++)
        if (!isfinite(m->v[i])) {
            frep_error_set(err, FREP_EINPUT, "%s: vertex %zu has a non-finite coordinate", name, i / 3 + 1);
            rc = -1;
        }
    if (rc != 0) mesh_free(m);
    return rc;
}

int meshio_read(const char *path, frep_mesh *m, frep_error *err)
{
    memset(m, 0, sizeof *m);
    frep_error_init(err);
    frep_file f;
    frep_error fe;
    frep_error_init(&fe);
    if (frep_file_read(&f, path, FREP_FILE_MAX_BYTES, 0, &fe)) {
        if (f.open_failed) frep_error_set(err, FREP_EINPUT, "%s: cannot open: %s", path, fe.msg);
        else frep_error_set(err, FREP_EINPUT, "%s: %s", path, fe.code == FREP_EIO ? "read error" : fe.msg);
        return -1;
    }
    int rc = meshio_parse(path, f.data, f.len, meshio_format_for_path(path), m, err);
    frep_free(f.data);
    return rc;
}

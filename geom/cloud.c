/* cloud.c - point clouds: storage, .xyz and PLY readers and writers, bounding box.
 *
 * The input side of fit/segment/evolve and the output side of `frep sample`.  Readers
 * take the whole file into memory and parse it, reporting the first problem as
 * "file:line: what" in a frep_error; the library never prints.
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "cloud.h"
#include "decimal.h"
#include "file.h"
#include "ply.h"
#include "util.h"

/* Longest PLY header line and most header lines we parse: real headers are a few
 * dozen short lines; more is a corrupt or hostile file. */
#define PLY_MAX_LINE 1024
#define PLY_MAX_PROPS 256
#define PLY_MAX_ELEMENTS 64
/* Longest list in a PLY element we skip (a face with more vertices is corrupt). */
#define PLY_MAX_LIST 1000000u

/* ---- storage ------------------------------------------------------------- */

frep_cloud *cloud_new(int with_normals)
{
    frep_cloud *c = frep_calloc(1, sizeof *c);
    if (c) c->has_normals = with_normals != 0;
    return c;
}

void cloud_free(frep_cloud *c)
{
    if (!c) return;
    frep_free(c->x); frep_free(c->y); frep_free(c->z);
    frep_free(c->nx); frep_free(c->ny); frep_free(c->nz);
    frep_free(c);
}

static int grow(double **a, size_t cap)
{
    double *p = frep_realloc(*a, cap * sizeof *p);
    if (!p) return -1;
    *a = p;
    return 0;
}

int cloud_reserve(frep_cloud *c, size_t cap)
{
    if (cap <= c->cap) return 0;
    if (cap > CLOUD_MAX_POINTS) return -1;
    if (grow(&c->x, cap) || grow(&c->y, cap) || grow(&c->z, cap)) return -1;
    if (c->has_normals && (grow(&c->nx, cap) || grow(&c->ny, cap) || grow(&c->nz, cap)))
        return -1;
    c->cap = cap;
    return 0;
}

int cloud_push(frep_cloud *c, const double p[3], const double nrm[3])
{
    if (c->n == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 1024;
        if (cap > CLOUD_MAX_POINTS) cap = CLOUD_MAX_POINTS;
        if (c->n >= cap || cloud_reserve(c, cap)) return -1;
    }
    c->x[c->n] = p[0];
    c->y[c->n] = p[1];
    c->z[c->n] = p[2];
    if (c->has_normals) {
        c->nx[c->n] = nrm ? nrm[0] : 0.0;
        c->ny[c->n] = nrm ? nrm[1] : 0.0;
        c->nz[c->n] = nrm ? nrm[2] : 0.0;
    }
    c->n++;
    return 0;
}

int cloud_add_normals(frep_cloud *c)
{
    if (c->has_normals) return 0;
    size_t cap = c->cap ? c->cap : 1;
    c->nx = frep_calloc(cap, sizeof(double));
    c->ny = frep_calloc(cap, sizeof(double));
    c->nz = frep_calloc(cap, sizeof(double));
    if (!c->nx || !c->ny || !c->nz) {
        frep_free(c->nx); frep_free(c->ny); frep_free(c->nz);
        c->nx = c->ny = c->nz = NULL;
        return -1;
    }
    c->has_normals = 1;
    return 0;
}

void cloud_bbox(const frep_cloud *c, double lo[3], double hi[3])
{
    if (!c || c->n == 0) {
        for (int k = 0; k < 3; k++) lo[k] = hi[k] = 0.0;
        return;
    }
    lo[0] = hi[0] = c->x[0];
    lo[1] = hi[1] = c->y[0];
    lo[2] = hi[2] = c->z[0];
    for (size_t i = 1; i < c->n; i++) {
        double v[3] = {c->x[i], c->y[i], c->z[i]};
        for (int k = 0; k < 3; k++) {
            if (v[k] < lo[k]) lo[k] = v[k];
            if (v[k] > hi[k]) hi[k] = v[k];
        }
    }
}

double cloud_diagonal(const frep_cloud *c)
{
    double lo[3], hi[3];
    cloud_bbox(c, lo, hi);
    double d = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                    (hi[2] - lo[2]) * (hi[2] - lo[2]));
    double m = fmax(fmax(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
    if ((d > 0 && isfinite(d)) || !(m > 0) || !isfinite(m)) return d > 0 ? d : m > 0 ? m : 0;
    /* the squares overflowed (extents near 1e300) or underflowed (near 1e-300) */
    double s = 0;
    for (int k = 0; k < 3; k++) s += ((hi[k] - lo[k]) / m) * ((hi[k] - lo[k]) / m);
    return m * sqrt(s);
}

int cloud_check_scale(const frep_cloud *c, const char *name, frep_error *err)
{
    double lo[3], hi[3], big = 0;
    cloud_bbox(c, lo, hi);
    for (int k = 0; k < 3; k++) big = fmax(big, fmax(fabs(lo[k]), fabs(hi[k])));
    double d = cloud_diagonal(c);
    if (big > CLOUD_MAX_COORD)
        return frep_error_set(err, FREP_EINPUT, "%s%scoordinates reach %.3g, beyond %g: "
                              "rescale the cloud", name ? name : "", name ? ": " : "", big,
                              CLOUD_MAX_COORD);
    if (d > 0 && d < CLOUD_MIN_DIAGONAL)
        return frep_error_set(err, FREP_EINPUT, "%s%sthe cloud spans %.3g, less than %g: "
                              "rescale the cloud", name ? name : "", name ? ": " : "", d,
                              CLOUD_MIN_DIAGONAL);
    return 0;
}

size_t cloud_normalize_normals(frep_cloud *c)
{
    if (!c->has_normals) return 0;
    size_t bad = 0;
    for (size_t i = 0; i < c->n; i++) {
        double l = sqrt(c->nx[i] * c->nx[i] + c->ny[i] * c->ny[i] + c->nz[i] * c->nz[i]);
        if (!(l > 0.0) || !isfinite(l)) {
            c->nx[i] = c->ny[i] = c->nz[i] = 0.0;
            bad++;
            continue;
        }
        c->nx[i] /= l;
        c->ny[i] /= l;
        c->nz[i] /= l;
    }
    return bad;
}

/* ---- .xyz text ----------------------------------------------------------- */

/* Separators between numbers: blanks, and commas/semicolons of CSV-like exports. */
static int is_sep(char ch)
{
    return ch == ' ' || ch == '\t' || ch == '\r' || ch == ',' || ch == ';' || ch == '\f' ||
           ch == '\v';
}

/* Parse one number starting at s (not past end); returns the end or NULL. Short
 * decimals convert in place (decimal_parse), the bits strtod gives them; strtod needs
 * a NUL-terminated string, so for the others the token is copied (numbers are short). */
static const char *parse_number(const char *s, const char *end, double *v)
{
    char buf[128];
    size_t k = 0;
    while (s + k < end && !is_sep(s[k]) && s[k] != '\n' && s[k] != '#') {
        if (k + 1 >= sizeof buf) return NULL;
        k++;
    }
    if (k == 0) return NULL;
    if (decimal_parse(s, s + k, v)) return s + k;
    memcpy(buf, s, k);
    buf[k] = '\0';
    char *e;
    errno = 0;
    *v = strtod(buf, &e);
    if (*e != '\0') return NULL;
    return s + k;
}

/* The numbers of one line [q, eol) (up to '#'): the first 7 into v, the count into
 * *nv. Returns -1 with err set on a word that is not a number. */
static int xyz_numbers(const char *name, size_t line, const char *q, const char *eol,
                       double v[7], int *nv, frep_error *err)
{
    *nv = 0;
    for (;;) {
        while (q < eol && is_sep(*q)) q++;
        if (q >= eol || *q == '#') return 0;
        double t;
        const char *qe = parse_number(q, eol, &t);
        if (!qe) {
            int tl = 0;
            while (q + tl < eol && !is_sep(q[tl]) && tl < 40) tl++;
            return frep_error_set(err, FREP_EINPUT, "%s:%zu: '%.*s' is not a number", name, line,
                                  tl, q);
        }
        if (*nv < 7) v[*nv] = t;
        (*nv)++;
        q = qe;
    }
}

/* An .xyz cloud: 3 or 6 finite numbers a data line, the same count on every one. */
static frep_cloud *parse_xyz(const char *name, const char *data, size_t len, frep_error *err)
{
    frep_cloud *c = NULL;
    const char *p = data, *end = data + len;
    size_t line = 0;
    int ncols = 0;           /* 3 or 6 once the first data line fixed it */
    size_t first_line = 0;
    while (p < end) {
        line++;
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        double v[7];
        int nv;
        if (xyz_numbers(name, line, p, eol, v, &nv, err)) goto fail;
        p = eol < end ? eol + 1 : end;
        if (nv == 0) continue;
        if (nv != 3 && nv != 6) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 3 or 6 numbers, got %d", name,
                           line, nv);
            goto fail;
        }
        if (ncols == 0) {
            ncols = nv;
            first_line = line;
            c = cloud_new(nv == 6);
            if (!c) { frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name); goto fail; }
        } else if (nv != ncols) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: expected %d numbers as on line %zu, got %d",
                           name, line, ncols, first_line, nv);
            goto fail;
        }
        for (int k = 0; k < nv; k++) {
            if (!isfinite(v[k])) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: number %d is not finite", name, line,
                               k + 1);
                goto fail;
            }
        }
        if (cloud_push(c, v, nv == 6 ? v + 3 : NULL)) {
            frep_error_set(err, FREP_ENOMEM, "%s:%zu: out of memory (or more than %zu points)",
                           name, line, (size_t)CLOUD_MAX_POINTS);
            goto fail;
        }
    }
    if (!c) {
        frep_error_set(err, FREP_EINPUT, "%s: no points", name);
        return NULL;
    }
    return c;
fail:
    cloud_free(c);
    return NULL;
}

/* ---- PLY ----------------------------------------------------------------- */

typedef struct ply_prop {
    frep_ply_type type;       /* scalar type, or item type of a list */
    frep_ply_type count_type; /* FREP_PLY_NONE for scalar properties */
    int role;                 /* 0..5: x y z nx ny nz in the vertex element; -1 otherwise */
} ply_prop;

typedef struct ply_element {
    size_t count;
    int is_vertex;
    size_t nprops;
    ply_prop props[PLY_MAX_PROPS];
} ply_element;

/* A PLY cloud being read: the header as parsed so far (line: the last header line). */
typedef struct cloud_ply {
    const char *name;
    frep_error *err;
    ply_element *el;
    size_t nel, line;
    ply_format fmt;
    int have_format, have_vertex;
} cloud_ply;

/* Split a header line into at most 4 words; returns the word count. */
static int split_words(char *s, char **w, int maxw)
{
    int n = 0;
    while (*s) {
        while (*s && isspace((unsigned char)*s)) *s++ = '\0';
        if (!*s) break;
        if (n == maxw) return maxw + 1;
        w[n++] = s;
        while (*s && !isspace((unsigned char)*s)) s++;
    }
    return n;
}

/* format TYPE VERSION */
static int header_format(cloud_ply *h, char **w, int nw)
{
    if (nw != 3)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: expected 'format TYPE VERSION'",
                              h->name, h->line);
    if (ply_format_of(w[1], &h->fmt))
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: unknown PLY format '%s'", h->name,
                              h->line, w[1]);
    h->have_format = 1;
    return 0;
}

/* element NAME COUNT (the first element named vertex holds the points) */
static int header_element(cloud_ply *h, char **w, int nw)
{
    if (nw != 3)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: expected 'element NAME COUNT'",
                              h->name, h->line);
    if (h->nel == PLY_MAX_ELEMENTS)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: too many elements", h->name, h->line);
    char *e;
    errno = 0;
    unsigned long long cnt = strtoull(w[2], &e, 10);
    if (*e != '\0' || w[2][0] == '-' || errno)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: bad element count '%s'", h->name,
                              h->line, w[2]);
    ply_element *E = &h->el[h->nel++];
    E->is_vertex = strcmp(w[1], "vertex") == 0 && !h->have_vertex;
    if (E->is_vertex) {
        h->have_vertex = 1;
        if (cnt > CLOUD_MAX_POINTS)
            return frep_error_set(h->err, FREP_EINPUT,
                                  "%s:%zu: %llu vertices is more than the limit of %zu", h->name,
                                  h->line, cnt, (size_t)CLOUD_MAX_POINTS);
    }
    E->count = (size_t)cnt;
    return 0;
}

/* property TYPE NAME | property list COUNT-TYPE TYPE NAME (roles: x y z nx ny nz) */
static int header_property(cloud_ply *h, char **w, int nw)
{
    if (h->nel == 0)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: property before any element",
                              h->name, h->line);
    ply_element *E = &h->el[h->nel - 1];
    if (E->nprops == PLY_MAX_PROPS)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: too many properties", h->name,
                              h->line);
    ply_prop *P = &E->props[E->nprops];
    P->role = -1;
    P->count_type = FREP_PLY_NONE;
    if (nw >= 2 && strcmp(w[1], "list") == 0) {
        if (nw != 5)
            return frep_error_set(h->err, FREP_EINPUT,
                                  "%s:%zu: expected 'property list COUNT-TYPE TYPE NAME'",
                                  h->name, h->line);
        P->count_type = frep_ply_type_of(w[2]);
        P->type = frep_ply_type_of(w[3]);
        if (P->count_type == FREP_PLY_NONE || P->type == FREP_PLY_NONE ||
            P->count_type == FREP_PLY_F32 || P->count_type == FREP_PLY_F64)
            return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: bad list types '%s %s'",
                                  h->name, h->line, w[2], w[3]);
    } else {
        if (nw != 3)
            return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: expected 'property TYPE NAME'",
                                  h->name, h->line);
        P->type = frep_ply_type_of(w[1]);
        if (P->type == FREP_PLY_NONE)
            return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: unknown property type '%s'",
                                  h->name, h->line, w[1]);
        if (E->is_vertex) {
            static const char *const roles[6] = {"x", "y", "z", "nx", "ny", "nz"};
            for (int r = 0; r < 6; r++)
                if (strcmp(w[2], roles[r]) == 0) P->role = r;
        }
    }
    E->nprops++;
    return 0;
}

/* One header line after the first (words w[0..nw)): 1 at end_header, 0 otherwise, -1
 * on an error. */
static int header_line(cloud_ply *h, char **w, int nw)
{
    if (nw == 0) return 0;
    if (strcmp(w[0], "comment") == 0 || strcmp(w[0], "obj_info") == 0) return 0;
    if (strcmp(w[0], "format") == 0) return header_format(h, w, nw);
    if (strcmp(w[0], "element") == 0) return header_element(h, w, nw);
    if (strcmp(w[0], "property") == 0) return header_property(h, w, nw);
    if (strcmp(w[0], "end_header") == 0) return 1;
    return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: unknown header keyword '%s'", h->name,
                          h->line, w[0]);
}

/* The header, line by line up to end_header; *body is the data after it. */
static int read_header(cloud_ply *h, const char *data, size_t len, const char **body)
{
    const char *p = data, *end = data + len;
    char buf[PLY_MAX_LINE];
    int ended = 0;
    while (p < end && !ended) {
        h->line++;
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) break;
        size_t l = (size_t)(eol - p);
        if (l >= sizeof buf)
            return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: header line too long", h->name,
                                  h->line);
        memcpy(buf, p, l);
        buf[l] = '\0';
        p = eol + 1;
        char *w[5];
        int nw = split_words(buf, w, 4);
        if (h->line == 1) {
            if (nw != 1 || strcmp(w[0], "ply") != 0)
                return frep_error_set(h->err, FREP_EINPUT,
                                      "%s:1: not a PLY file (first line is not 'ply')", h->name);
            continue;
        }
        ended = header_line(h, w, nw);
        if (ended < 0) return -1;
    }
    const char *what = !ended ? "header ends without end_header"
                       : !h->have_format ? "header has no format line"
                       : !h->have_vertex ? "no vertex element" : NULL;
    if (what) return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: %s", h->name, h->line, what);
    *body = p;
    return 0;
}

/* Which of x y z nx ny nz the vertex element has (of duplicates, the first counts). */
static void vertex_roles(cloud_ply *h, int has_role[6])
{
    for (size_t e = 0; e < h->nel; e++) {
        if (!h->el[e].is_vertex) continue;
        for (size_t k = 0; k < h->el[e].nprops; k++) {
            int r = h->el[e].props[k].role;
            if (r < 0) continue;
            if (has_role[r]) h->el[e].props[k].role = -1;
            else has_role[r] = 1;
        }
    }
}

/* Cursor over the ASCII body: whitespace separated tokens with line tracking. */
typedef struct ascii_cursor {
    const char *p, *end;
    size_t line;
} ascii_cursor;

static int ascii_next(ascii_cursor *a, double *v)
{
    while (a->p < a->end && isspace((unsigned char)*a->p)) {
        if (*a->p == '\n') a->line++;
        a->p++;
    }
    if (a->p >= a->end) return -1;
    const char *e = a->p;
    while (e < a->end && !isspace((unsigned char)*e)) e++;
    char buf[128];
    size_t k = (size_t)(e - a->p);
    if (k >= sizeof buf) return -2;
    memcpy(buf, a->p, k);
    buf[k] = '\0';
    char *q;
    *v = strtod(buf, &q);
    if (*q != '\0') return -2;
    a->p = e;
    return 0;
}

/* The body: ASCII tokens or binary values, in the header's format. */
typedef struct ply_body {
    ply_format fmt;
    ascii_cursor ac;
    const unsigned char *bp, *bend;
} ply_body;

/* The next value, of type t in a binary body; -1 when the data end or are bad. */
static int next_value(ply_body *b, frep_ply_type t, double *v)
{
    if (b->fmt == PLY_ASCII) return ascii_next(&b->ac, v) ? -1 : 0;
    return ply_binary_value(&b->bp, b->bend, t, b->fmt, v);
}

/* One item of E: every property (lists skipped), the roles' values into v; -1 when
 * the data end or are bad. */
static int read_item(ply_body *b, const ply_element *E, double v[6])
{
    for (size_t k = 0; k < E->nprops; k++) {
        const ply_prop *P = &E->props[k];
        size_t nitems = 1;
        if (P->count_type != FREP_PLY_NONE) {
            double cnt;
            if (next_value(b, P->count_type, &cnt)) return -1;
            if (!(cnt >= 0) || cnt > PLY_MAX_LIST || cnt != floor(cnt)) return -1;
            nitems = (size_t)cnt;
        }
        for (size_t j = 0; j < nitems; j++) {
            double t;
            if (next_value(b, P->type, &t)) return -1;
            if (P->role >= 0) v[P->role] = t;
        }
    }
    return 0;
}

/* The message for item i of E, which read_item could not read. */
static int item_error(const cloud_ply *h, const ply_body *b, const ply_element *E, size_t i)
{
    const char *what = E->is_vertex ? "vertex" : "element item";
    if (b->fmt != PLY_ASCII)
        return frep_error_set(h->err, FREP_EINPUT,
                              "%s: binary data ends or is corrupt in %s %zu of %zu", h->name,
                              what, i, E->count);
    if (b->ac.p >= b->ac.end)
        return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: data ends in %s %zu of %zu",
                              h->name, b->ac.line, what, i, E->count);
    return frep_error_set(h->err, FREP_EINPUT, "%s:%zu: bad number in %s %zu", h->name,
                          b->ac.line, what, i);
}

/* Bytes of the body not read yet; every property of an item takes at least one (a
 * digit, or a binary value of one byte or more). */
static size_t body_left(const ply_body *b)
{
    return b->fmt == PLY_ASCII ? (size_t)(b->ac.end - b->ac.p) : (size_t)(b->bend - b->bp);
}

/* The items of every element in order; the vertices go into c, reserved once their
 * count is known to fit the data left (a header declaring 200 million vertices over
 * a few bytes asked for 9.6 GB: the fuzzer's find). */
static int read_body(const cloud_ply *h, ply_body *b, frep_cloud *c)
{
    for (size_t e = 0; e < h->nel; e++) {
        const ply_element *E = &h->el[e];
        if (E->nprops == 0) continue; /* items without properties hold no data */
        if (E->is_vertex && E->count > body_left(b) / E->nprops)
            return frep_error_set(h->err, FREP_EINPUT,
                                  "%s: %zu vertices declared, more than the %zu bytes of data "
                                  "left can hold", h->name, E->count, body_left(b));
        if (E->is_vertex && cloud_reserve(c, E->count))
            return frep_error_set(h->err, FREP_ENOMEM, "%s: out of memory for %zu vertices",
                                  h->name, E->count);
        for (size_t i = 0; i < E->count; i++) {
            double v[6] = {0, 0, 0, 0, 0, 0};
            size_t item_line = b->ac.line;
            if (read_item(b, E, v)) return item_error(h, b, E, i);
            if (!E->is_vertex) continue;
            for (int r = 0; r < 6; r++) {
                if (isfinite(v[r])) continue;
                if (b->fmt == PLY_ASCII)
                    return frep_error_set(h->err, FREP_EINPUT,
                                          "%s:%zu: vertex %zu has a non-finite value", h->name,
                                          item_line, i);
                return frep_error_set(h->err, FREP_EINPUT, "%s: vertex %zu has a non-finite value",
                                      h->name, i);
            }
            cloud_push(c, v, v + 3); /* cannot fail: reserved */
        }
    }
    return 0;
}

/* A PLY cloud: the header, the vertex roles, then the body. */
static frep_cloud *parse_ply(const char *name, const char *data, size_t len, frep_error *err)
{
    cloud_ply h = {name, err, NULL, 0, 0, PLY_ASCII, 0, 0};
    h.el = frep_calloc(PLY_MAX_ELEMENTS, sizeof *h.el);
    if (!h.el) {
        frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name);
        return NULL;
    }
    frep_cloud *c = NULL;
    const char *p = NULL, *end = data + len;
    int has_role[6] = {0};
    if (read_header(&h, data, len, &p)) goto fail;
    vertex_roles(&h, has_role);
    if (!has_role[0] || !has_role[1] || !has_role[2]) {
        frep_error_set(err, FREP_EINPUT, "%s: vertex element lacks x, y or z", name);
        goto fail;
    }
    c = cloud_new(has_role[3] && has_role[4] && has_role[5]);
    if (!c) {
        frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name);
        goto fail;
    }
    ply_body b = {h.fmt, {p, end, h.line + 1}, (const unsigned char *)p,
                  (const unsigned char *)end};
    if (read_body(&h, &b, c)) goto fail;
    frep_free(h.el);
    return c;
fail:
    frep_free(h.el);
    cloud_free(c);
    return NULL;
}

frep_cloud *cloud_parse(const char *name, const char *data, size_t len, frep_error *err)
{
    frep_error_init(err);
    if (len >= 4 && memcmp(data, "ply", 3) == 0 && (data[3] == '\n' || data[3] == '\r'))
        return parse_ply(name, data, len, err);
    return parse_xyz(name, data, len, err);
}

frep_cloud *cloud_read(const char *path, frep_error *err)
{
    frep_error_init(err);
    frep_file f;
    frep_error fe;
    frep_error_init(&fe);
    if (frep_file_read(&f, path, FREP_FILE_MAX_BYTES, FREP_FILE_STDIN, &fe)) {
        frep_error_set(err, fe.code, "cannot read %s: %s", path, fe.msg);
        return NULL;
    }
    frep_cloud *c = cloud_parse(strcmp(path, "-") == 0 ? "<stdin>" : path, f.data, f.len, err);
    frep_free(f.data);
    return c;
}

/* ---- writers ------------------------------------------------------------- */

int cloud_write_xyz(FILE *f, const frep_cloud *c)
{
    for (size_t i = 0; i < c->n; i++) {
        if (c->has_normals)
            fprintf(f, "%.17g %.17g %.17g %.17g %.17g %.17g\n", c->x[i], c->y[i], c->z[i],
                    c->nx[i], c->ny[i], c->nz[i]);
        else
            fprintf(f, "%.17g %.17g %.17g\n", c->x[i], c->y[i], c->z[i]);
    }
    return ferror(f) ? -1 : 0;
}

static void put_le64(unsigned char *b, double v)
{
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    for (int i = 0; i < 8; i++) b[i] = (unsigned char)(u >> (8 * i));
}

int cloud_write_ply(FILE *f, const frep_cloud *c)
{
    fprintf(f, "ply\nformat binary_little_endian 1.0\ncomment written by frep\n"
               "element vertex %zu\nproperty double x\nproperty double y\nproperty double z\n",
            c->n);
    if (c->has_normals)
        fputs("property double nx\nproperty double ny\nproperty double nz\n", f);
    fputs("end_header\n", f);
    unsigned char b[48];
    size_t rec = c->has_normals ? 48 : 24;
    for (size_t i = 0; i < c->n; i++) {
        put_le64(b, c->x[i]);
        put_le64(b + 8, c->y[i]);
        put_le64(b + 16, c->z[i]);
        if (c->has_normals) {
            put_le64(b + 24, c->nx[i]);
            put_le64(b + 32, c->ny[i]);
            put_le64(b + 40, c->nz[i]);
        }
        if (fwrite(b, 1, rec, f) != rec) return -1;
    }
    return ferror(f) ? -1 : 0;
}

int cloud_write_for_path(FILE *f, const frep_cloud *c, const char *path)
{
    size_t l = strlen(path);
    if (l >= 4 && (strcmp(path + l - 4, ".ply") == 0 || strcmp(path + l - 4, ".PLY") == 0))
        return cloud_write_ply(f, c);
    return cloud_write_xyz(f, c);
}

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
#include "file.h"
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
    return sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                (hi[2] - lo[2]) * (hi[2] - lo[2]));
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

/* Parse one number starting at s (not past end); returns the end or NULL. strtod needs
 * a NUL-terminated string, so the token is copied (numbers are short). */
static const char *parse_number(const char *s, const char *end, double *v)
{
    char buf[128];
    size_t k = 0;
    while (s + k < end && !is_sep(s[k]) && s[k] != '\n' && s[k] != '#') {
        if (k + 1 >= sizeof buf) return NULL;
        buf[k] = s[k];
        k++;
    }
    buf[k] = '\0';
    if (k == 0) return NULL;
    char *e;
    errno = 0;
    *v = strtod(buf, &e);
    if (*e != '\0') return NULL;
    return s + k;
}

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
        int nv = 0;
        const char *q = p;
        for (;;) {
            while (q < eol && is_sep(*q)) q++;
            if (q >= eol || *q == '#') break;
            double t;
            const char *qe = parse_number(q, eol, &t);
            if (!qe) {
                int tl = 0;
                while (q + tl < eol && !is_sep(q[tl]) && tl < 40) tl++;
                frep_error_set(err, FREP_EINPUT, "%s:%zu: '%.*s' is not a number", name, line, tl, q);
                goto fail;
            }
            if (nv < 7) v[nv] = t;
            nv++;
            q = qe;
        }
        p = eol < end ? eol + 1 : end;
        if (nv == 0) continue;
        if (nv != 3 && nv != 6) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 3 or 6 numbers, got %d", name, line, nv);
            goto fail;
        }
        if (ncols == 0) {
            ncols = nv;
            first_line = line;
            c = cloud_new(nv == 6);
            if (!c) { frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name); goto fail; }
        } else if (nv != ncols) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: expected %d numbers as on line %zu, got %d", name, line, ncols,
                    first_line, nv);
            goto fail;
        }
        for (int k = 0; k < nv; k++) {
            if (!isfinite(v[k])) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: number %d is not finite", name, line, k + 1);
                goto fail;
            }
        }
        if (cloud_push(c, v, nv == 6 ? v + 3 : NULL)) {
            frep_error_set(err, FREP_ENOMEM, "%s:%zu: out of memory (or more than %zu points)", name, line,
                    (size_t)CLOUD_MAX_POINTS);
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

typedef enum ply_format { PLY_ASCII, PLY_BIN_LE, PLY_BIN_BE } ply_format;

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

static frep_cloud *parse_ply(const char *name, const char *data, size_t len, frep_error *err)
{
    ply_element *el = frep_calloc(PLY_MAX_ELEMENTS, sizeof *el);
    frep_cloud *c = NULL;
    if (!el) { frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name); return NULL; }
    size_t nel = 0, line = 0;
    ply_format fmt = PLY_ASCII;
    int have_format = 0, have_vertex = 0, ended = 0;
    const char *p = data, *end = data + len;
    char buf[PLY_MAX_LINE];
    while (p < end && !ended) {
        line++;
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) { frep_error_set(err, FREP_EINPUT, "%s:%zu: header ends without end_header", name, line); goto fail; }
        size_t l = (size_t)(eol - p);
        if (l >= sizeof buf) { frep_error_set(err, FREP_EINPUT, "%s:%zu: header line too long", name, line); goto fail; }
        memcpy(buf, p, l);
        buf[l] = '\0';
        p = eol + 1;
        char *w[5];
        int nw = split_words(buf, w, 4);
        if (line == 1) {
            if (nw != 1 || strcmp(w[0], "ply") != 0) {
                frep_error_set(err, FREP_EINPUT, "%s:1: not a PLY file (first line is not 'ply')", name);
                goto fail;
            }
            continue;
        }
        if (nw == 0) continue;
        if (strcmp(w[0], "comment") == 0 || strcmp(w[0], "obj_info") == 0) continue;
        if (strcmp(w[0], "format") == 0) {
            if (nw != 3) { frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 'format TYPE VERSION'", name, line); goto fail; }
            if (strcmp(w[1], "ascii") == 0) fmt = PLY_ASCII;
            else if (strcmp(w[1], "binary_little_endian") == 0) fmt = PLY_BIN_LE;
            else if (strcmp(w[1], "binary_big_endian") == 0) fmt = PLY_BIN_BE;
            else { frep_error_set(err, FREP_EINPUT, "%s:%zu: unknown PLY format '%s'", name, line, w[1]); goto fail; }
            have_format = 1;
        } else if (strcmp(w[0], "element") == 0) {
            if (nw != 3) { frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 'element NAME COUNT'", name, line); goto fail; }
            if (nel == PLY_MAX_ELEMENTS) { frep_error_set(err, FREP_EINPUT, "%s:%zu: too many elements", name, line); goto fail; }
            char *e;
            errno = 0;
            unsigned long long cnt = strtoull(w[2], &e, 10);
            if (*e != '\0' || w[2][0] == '-' || errno) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: bad element count '%s'", name, line, w[2]);
                goto fail;
            }
            ply_element *E = &el[nel++];
            E->is_vertex = strcmp(w[1], "vertex") == 0 && !have_vertex;
            if (E->is_vertex) {
                have_vertex = 1;
                if (cnt > CLOUD_MAX_POINTS) {
                    frep_error_set(err, FREP_EINPUT, "%s:%zu: %llu vertices is more than the limit of %zu", name, line,
                            cnt, (size_t)CLOUD_MAX_POINTS);
                    goto fail;
                }
            }
            E->count = (size_t)cnt;
        } else if (strcmp(w[0], "property") == 0) {
            if (nel == 0) { frep_error_set(err, FREP_EINPUT, "%s:%zu: property before any element", name, line); goto fail; }
            ply_element *E = &el[nel - 1];
            if (E->nprops == PLY_MAX_PROPS) { frep_error_set(err, FREP_EINPUT, "%s:%zu: too many properties", name, line); goto fail; }
            ply_prop *P = &E->props[E->nprops];
            P->role = -1;
            P->count_type = FREP_PLY_NONE;
            const char *pname;
            if (nw >= 2 && strcmp(w[1], "list") == 0) {
                if (nw != 5) { frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 'property list COUNT-TYPE TYPE NAME'", name, line); goto fail; }
                P->count_type = frep_ply_type_of(w[2]);
                P->type = frep_ply_type_of(w[3]);
                if (P->count_type == FREP_PLY_NONE || P->type == FREP_PLY_NONE ||
                    P->count_type == FREP_PLY_F32 || P->count_type == FREP_PLY_F64) {
                    frep_error_set(err, FREP_EINPUT, "%s:%zu: bad list types '%s %s'", name, line, w[2], w[3]);
                    goto fail;
                }
                pname = w[4];
            } else {
                if (nw != 3) { frep_error_set(err, FREP_EINPUT, "%s:%zu: expected 'property TYPE NAME'", name, line); goto fail; }
                P->type = frep_ply_type_of(w[1]);
                if (P->type == FREP_PLY_NONE) { frep_error_set(err, FREP_EINPUT, "%s:%zu: unknown property type '%s'", name, line, w[1]); goto fail; }
                pname = w[2];
                if (E->is_vertex) {
                    static const char *const roles[6] = {"x", "y", "z", "nx", "ny", "nz"};
                    for (int r = 0; r < 6; r++)
                        if (strcmp(pname, roles[r]) == 0) P->role = r;
                }
            }
            (void)pname;
            E->nprops++;
        } else if (strcmp(w[0], "end_header") == 0) {
            ended = 1;
        } else {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: unknown header keyword '%s'", name, line, w[0]);
            goto fail;
        }
    }
    if (!ended) { frep_error_set(err, FREP_EINPUT, "%s:%zu: header ends without end_header", name, line); goto fail; }
    if (!have_format) { frep_error_set(err, FREP_EINPUT, "%s:%zu: header has no format line", name, line); goto fail; }
    if (!have_vertex) { frep_error_set(err, FREP_EINPUT, "%s:%zu: no vertex element", name, line); goto fail; }

    /* Which vertex properties are present. */
    int has_role[6] = {0};
    for (size_t e = 0; e < nel; e++) {
        if (!el[e].is_vertex) continue;
        for (size_t k = 0; k < el[e].nprops; k++) {
            int r = el[e].props[k].role;
            if (r < 0) continue;
            if (has_role[r]) el[e].props[k].role = -1; /* duplicate: keep the first */
            else has_role[r] = 1;
        }
    }
    if (!has_role[0] || !has_role[1] || !has_role[2]) {
        frep_error_set(err, FREP_EINPUT, "%s: vertex element lacks x, y or z", name);
        goto fail;
    }
    int normals = has_role[3] && has_role[4] && has_role[5];
    c = cloud_new(normals);
    if (!c) { frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name); goto fail; }

    ascii_cursor ac = {p, end, line + 1};
    const unsigned char *bp = (const unsigned char *)p, *bend = (const unsigned char *)end;
    int big = fmt == PLY_BIN_BE;
    for (size_t e = 0; e < nel; e++) {
        ply_element *E = &el[e];
        if (E->is_vertex && cloud_reserve(c, E->count)) {
            frep_error_set(err, FREP_ENOMEM, "%s: out of memory for %zu vertices", name, E->count);
            goto fail;
        }
        for (size_t i = 0; i < E->count; i++) {
            double v[6] = {0, 0, 0, 0, 0, 0};
            size_t item_line = ac.line;
            for (size_t k = 0; k < E->nprops; k++) {
                const ply_prop *P = &E->props[k];
                size_t nitems = 1;
                if (P->count_type != FREP_PLY_NONE) {
                    double cnt;
                    if (fmt == PLY_ASCII) {
                        int rc = ascii_next(&ac, &cnt);
                        if (rc) goto data_error;
                    } else {
                        size_t sz = frep_ply_type_size(P->count_type);
                        if ((size_t)(bend - bp) < sz) goto data_error;
                        cnt = frep_ply_decode(bp, P->count_type, big);
                        bp += sz;
                    }
                    if (!(cnt >= 0) || cnt > PLY_MAX_LIST || cnt != floor(cnt)) goto data_error;
                    nitems = (size_t)cnt;
                }
                for (size_t j = 0; j < nitems; j++) {
                    double t;
                    if (fmt == PLY_ASCII) {
                        if (ascii_next(&ac, &t)) goto data_error;
                    } else {
                        size_t sz = frep_ply_type_size(P->type);
                        if ((size_t)(bend - bp) < sz) goto data_error;
                        t = frep_ply_decode(bp, P->type, big);
                        bp += sz;
                    }
                    if (P->role >= 0) v[P->role] = t;
                }
            }
            if (!E->is_vertex) continue;
            for (int r = 0; r < 6; r++) {
                if (!isfinite(v[r])) {
                    if (fmt == PLY_ASCII)
                        frep_error_set(err, FREP_EINPUT, "%s:%zu: vertex %zu has a non-finite value", name, item_line, i);
                    else
                        frep_error_set(err, FREP_EINPUT, "%s: vertex %zu has a non-finite value", name, i);
                    goto fail;
                }
            }
            cloud_push(c, v, v + 3); /* cannot fail: reserved */
            continue;
        data_error:
            if (fmt == PLY_ASCII) {
                if (ac.p >= ac.end)
                    frep_error_set(err, FREP_EINPUT, "%s:%zu: data ends in %s %zu of %zu", name, ac.line,
                            E->is_vertex ? "vertex" : "element item", i, E->count);
                else
                    frep_error_set(err, FREP_EINPUT, "%s:%zu: bad number in %s %zu", name, ac.line,
                            E->is_vertex ? "vertex" : "element item", i);
            } else {
                frep_error_set(err, FREP_EINPUT, "%s: binary data ends or is corrupt in %s %zu of %zu", name,
                        E->is_vertex ? "vertex" : "element item", i, E->count);
            }
            goto fail;
        }
    }
    frep_free(el);
    return c;
fail:
    frep_free(el);
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

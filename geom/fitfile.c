/* fitfile.c - reader and writer of the ".fit" primitive list (geom/fitfile.h).
 *
 * The parameter order per type follows the reference implementation: direction before
 * point for cylinders, cones and tori, minor radius before major radius for tori.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "fitfile.h"
#include "util.h"
#include "vec3.h"

/* Most numbers on one line (a torus has 8); one more detects trailing junk. */
#define FIT_MAX_NUMS 9

/* The type named by a line's first word and the numbers it takes; -1 for none. */
static int type_of(const char *word, prim_type *t, int *want)
{
    static const struct { const char *word; prim_type t; int n; } types[] = {
        {"plane", PRIM_PLANE, 4}, {"sphere", PRIM_SPHERE, 4}, {"cylinder", PRIM_CYLINDER, 7},
        {"cone", PRIM_CONE, 7}, {"torus", PRIM_TORUS, 8},
    };
    for (size_t k = 0; k < sizeof types / sizeof *types; k++)
        if (strcmp(word, types[k].word) == 0) {
            *t = types[k].t;
            *want = types[k].n;
            return 0;
        }
    return -1;
}

/* The blank-separated finite numbers of s into x (at most FIT_MAX_NUMS kept); the count,
 * or -1 with err set. */
static int read_numbers(const char *name, size_t line, const char *s, double *x,
                        frep_error *err)
{
    int got = 0;
    for (;;) {
        while (*s == ' ' || *s == '\t' || *s == '\r') s++;
        if (!*s) return got;
        char *e;
        double t = strtod(s, &e);
        if (e == s || (*e && *e != ' ' && *e != '\t' && *e != '\r'))
            return frep_error_set(err, FREP_EINPUT, "%s:%zu: '%.20s' is not a number", name,
                                  line, s);
        if (!isfinite(t))
            return frep_error_set(err, FREP_EINPUT, "%s:%zu: number %d is not finite", name,
                                  line, got + 1);
        if (got < FIT_MAX_NUMS) x[got] = t;
        got++;
        s = e;
    }
}

/* The primitive of type q->type from its numbers x in the file's order (direction
 * before point; minor radius before major); -1 for a zero-length normal or axis. */
static int prim_of(prim *q, const double *x)
{
    switch (q->type) {
    case PRIM_PLANE: {
        double nn[3] = {x[0], x[1], x[2]};
        double l0 = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
        int bad = vec3_normalize(nn);
        memcpy(q->p, nn, sizeof nn);
        q->r = bad ? 0 : x[3] / l0;
        return bad;
    }
    case PRIM_SPHERE:
        memcpy(q->p, x, 3 * sizeof(double));
        q->r = x[3];
        return 0;
    case PRIM_CYLINDER:
    case PRIM_CONE:
    case PRIM_TORUS:
        memcpy(q->a, x, 3 * sizeof(double));
        memcpy(q->p, x + 3, 3 * sizeof(double));
        if (q->type == PRIM_TORUS) {
            q->r = x[6];
            q->R = x[7];
        } else {
            q->r = x[6];
        }
        return vec3_normalize(q->a);
    case PRIM__COUNT:
        break;
    }
    return 0;
}

/* One non-blank, non-comment line s: its primitive into q; -1 with err set. */
static int parse_line(const char *name, size_t line, const char *s, prim *q, frep_error *err)
{
    char word[32];
    size_t wl = 0;
    while (s[wl] && s[wl] != ' ' && s[wl] != '\t' && s[wl] != '\r' && wl < sizeof word - 1) {
        word[wl] = s[wl];
        wl++;
    }
    word[wl] = '\0';
    memset(q, 0, sizeof *q);
    int want;
    if (type_of(word, &q->type, &want))
        return frep_error_set(err, FREP_EINPUT, "%s:%zu: unknown primitive type '%s'", name,
                              line, word);
    double x[FIT_MAX_NUMS];
    int got = read_numbers(name, line, s + wl, x, err);
    if (got < 0) return -1;
    if (got != want)
        return frep_error_set(err, FREP_EINPUT, "%s:%zu: expected %d numbers after '%s', got %d",
                              name, line, want, word, got);
    if (prim_of(q, x))
        return frep_error_set(err, FREP_EINPUT, "%s:%zu: zero-length %s", name, line,
                              q->type == PRIM_PLANE ? "normal" : "axis");
    const char *why = prim_degenerate(q);
    if (why) return frep_error_set(err, FREP_EINPUT, "%s:%zu: degenerate %s: %s", name, line,
                                   word, why);
    return 0;
}

int fitfile_parse(const char *name, const char *text, size_t len, prim **out, size_t *n,
                  frep_error *err)
{
    *out = NULL;
    *n = 0;
    frep_error_init(err);
    size_t cap = 0, cnt = 0, line = 0;
    prim *v = NULL;
    const char *p = text, *end = text + len;
    while (p < end) {
        line++;
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        char buf[1024];
        size_t l = (size_t)(eol - p);
        const char *lp = p;
        p = eol < end ? eol + 1 : end;
        if (l >= sizeof buf) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: line too long", name, line);
            goto fail;
        }
        memcpy(buf, lp, l);
        buf[l] = '\0';
        char *s = buf;
        while (*s == ' ' || *s == '\t' || *s == '\r') s++;
        if (*s == '\0' || *s == '#') continue;
        prim q;
        if (parse_line(name, line, s, &q, err)) goto fail;
        if (cnt == cap) {
            size_t nc = cap ? 2 * cap : 16;
            prim *nv = frep_realloc(v, nc * sizeof *nv);
            if (!nv) {
                frep_error_set(err, FREP_ENOMEM, "%s: out of memory", name);
                goto fail;
            }
            v = nv;
            cap = nc;
        }
        v[cnt++] = q;
    }
    *out = v;
    *n = cnt;
    return 0;
fail:
    frep_free(v);
    return -1;
}

int fitfile_write(FILE *f, const prim *p, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        const prim *q = &p[i];
        switch (q->type) {
        case PRIM_PLANE:
            fprintf(f, "plane %.17g %.17g %.17g %.17g\n", q->p[0], q->p[1], q->p[2], q->r);
            break;
        case PRIM_SPHERE:
            fprintf(f, "sphere %.17g %.17g %.17g %.17g\n", q->p[0], q->p[1], q->p[2], q->r);
            break;
        case PRIM_CYLINDER:
        case PRIM_CONE:
            fprintf(f, "%s %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                    q->type == PRIM_CONE ? "cone" : "cylinder", q->a[0], q->a[1], q->a[2],
                    q->p[0], q->p[1], q->p[2], q->r);
            break;
        case PRIM_TORUS:
            fprintf(f, "torus %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", q->a[0],
                    q->a[1], q->a[2], q->p[0], q->p[1], q->p[2], q->r, q->R);
            break;
        case PRIM__COUNT:
            break;
        }
    }
    return ferror(f) ? -1 : 0;
}

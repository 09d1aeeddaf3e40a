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

/* Most numbers on one line (a torus has 8); one more detects trailing junk. */
#define FIT_MAX_NUMS 9

static int unit(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(l > 0) || !isfinite(l)) return -1;
    for (int k = 0; k < 3; k++) v[k] /= l;
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
        char word[32];
        size_t wl = 0;
        while (s[wl] && s[wl] != ' ' && s[wl] != '\t' && s[wl] != '\r' && wl < sizeof word - 1) {
            word[wl] = s[wl];
            wl++;
        }
        word[wl] = '\0';
        s += wl;
        prim q;
        memset(&q, 0, sizeof q);
        int want;
        if (strcmp(word, "plane") == 0) q.type = PRIM_PLANE, want = 4;
        else if (strcmp(word, "sphere") == 0) q.type = PRIM_SPHERE, want = 4;
        else if (strcmp(word, "cylinder") == 0) q.type = PRIM_CYLINDER, want = 7;
        else if (strcmp(word, "cone") == 0) q.type = PRIM_CONE, want = 7;
        else if (strcmp(word, "torus") == 0) q.type = PRIM_TORUS, want = 8;
        else {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: unknown primitive type '%s'", name, line, word);
            goto fail;
        }
        double x[FIT_MAX_NUMS];
        int got = 0;
        for (;;) {
            while (*s == ' ' || *s == '\t' || *s == '\r') s++;
            if (!*s) break;
            char *e;
            double t = strtod(s, &e);
            if (e == s || (*e && *e != ' ' && *e != '\t' && *e != '\r')) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: '%.20s' is not a number", name, line, s);
                goto fail;
            }
            if (!isfinite(t)) {
                frep_error_set(err, FREP_EINPUT, "%s:%zu: number %d is not finite", name, line, got + 1);
                goto fail;
            }
            if (got < FIT_MAX_NUMS) x[got] = t;
            got++;
            s = e;
        }
        if (got != want) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: expected %d numbers after '%s', got %d", name, line,
                                        want, word, got);
            goto fail;
        }
        int bad = 0;
        switch (q.type) {
        case PRIM_PLANE: {
            double nn[3] = {x[0], x[1], x[2]};
            double l0 = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
            bad = unit(nn);
            memcpy(q.p, nn, sizeof nn);
            q.r = bad ? 0 : x[3] / l0;
            break;
        }
        case PRIM_SPHERE:
            memcpy(q.p, x, 3 * sizeof(double));
            q.r = x[3];
            break;
        case PRIM_CYLINDER:
        case PRIM_CONE:
        case PRIM_TORUS:
            memcpy(q.a, x, 3 * sizeof(double));
            memcpy(q.p, x + 3, 3 * sizeof(double));
            bad = unit(q.a);
            if (q.type == PRIM_TORUS) {
                q.r = x[6];
                q.R = x[7];
            } else {
                q.r = x[6];
            }
            break;
        case PRIM__COUNT:
            break;
        }
        if (bad) {
            frep_error_set(err, FREP_EINPUT, "%s:%zu: zero-length %s", name, line,
                                        q.type == PRIM_PLANE ? "normal" : "axis");
            goto fail;
        }
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

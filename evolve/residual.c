/* residual.c - the base model of `frep evolve --residual`: its source prepared for the
 * output file, its values and gradients at the cloud's points.  See residual.h; the
 * join itself is in evolve.c.
 */
#include "config.h"
#include "alloc.h"
#include "err.h"

#include "residual.h"

#include "arena.h"
#include "ast.h"

#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Points per call of the evaluator (bounds the temporary arrays). */
#define RESIDUAL_CHUNK 65536

void residual_free(evolve_base *b)
{
    frep_free(b->text);
    frep_free(b->name);
    frep_free(b->header);
    frep_free(b->call);
    memset(b, 0, sizeof *b);
}

static int name_eq(const char *a, size_t na, const char *b)
{
    size_t nb = strlen(b);
    if (na != nb) return 0;
    for (size_t i = 0; i < na; i++)
        if (tolower((unsigned char)a[i]) != tolower((unsigned char)b[i])) return 0;
    return 1;
}

static int is_id0(int c) { return isalpha(c) || c == '_'; }
static int is_id(int c) { return isalnum(c) || c == '_'; }

/* At least need bytes at *out (of *cap), grown to twice plus extra; -1 when out of
 * memory (*out is then freed). */
static int text_room(char **out, size_t *cap, size_t need, size_t extra)
{
    if (need <= *cap) return 0;
    *cap = 2 * *cap + extra;
    char *t = frep_realloc(*out, *cap);
    if (!t) {
        frep_free(*out);
        *out = NULL;
        return -1;
    }
    *out = t;
    return 0;
}

/* Copy of src with every identifier token equal to `from` (case-insensitive, as names
 * are) at or after offset `start` replaced by `to`; comments and numbers are skipped.
 * Renaming from the chosen model's header on catches its result variable and the calls
 * of later models, the only places the name can appear. */
static char *rename_ident(const char *src, size_t len, size_t start, const char *from,
                          const char *to)
{
    size_t cap = len + 1, n = 0, tl = strlen(to);
    char *out = frep_malloc(cap);
    if (!out) return NULL;
    size_t i = 0;
    while (i < len) {
        size_t j = i;
        if (src[i] == '-' && i + 1 < len && src[i + 1] == '-') {
            while (j < len && src[j] != '\n') j++;
        } else if (isdigit((unsigned char)src[i]) || src[i] == '.') {
            while (j < len && (is_id((unsigned char)src[j]) || src[j] == '.' ||
                               ((src[j] == '+' || src[j] == '-') && j > i &&
                                (src[j - 1] == 'e' || src[j - 1] == 'E'))))
                j++;
        } else if (is_id0((unsigned char)src[i])) {
            while (j < len && is_id((unsigned char)src[j])) j++;
            if (i >= start && name_eq(src + i, j - i, from)) {
                if (text_room(&out, &cap, n + tl + (len - j) + 1, tl)) return NULL;
                memcpy(out + n, to, tl);
                n += tl;
                i = j;
                continue;
            }
        } else {
            j = i + 1;
        }
        if (text_room(&out, &cap, n + (j - i) + 1, j - i)) return NULL;
        memcpy(out + n, src + i, j - i);
        n += j - i;
        i = j;
    }
    out[n] = '\0';
    return out;
}

/* Diagnostics of the second parse are those the caller saw when compiling: drop them. */
static void quiet_diag(void *user, const frep_diag *d)
{
    (void)user;
    (void)d;
}

/* The model frep_compile chose: the named one, else my_model, else the first. NULL
 * (err set) when the named one is missing. */
static const ast_model *residual_model(const ast_file *af, const char *file,
                                       const char *model, frep_error *err)
{
    const ast_model *m = &af->models[0];
    for (uint32_t k = 0; k < af->nmodels; k++) {
        const char *nm = af->models[k].name;
        if (model ? name_eq(nm, strlen(nm), model) : name_eq(nm, strlen(nm), "my_model")) {
            m = &af->models[k];
            break;
        }
    }
    if (model && !name_eq(m->name, strlen(m->name), model)) {
        frep_error_at(err, FREP_EINPUT, file, 0, 0, "no model named '%s'", model);
        return NULL;
    }
    return m;
}

/* The file's set operations (HyperFun's R-functions when it says nothing); R-alpha
 * and others are refused. */
static int residual_setops(const ast_file *af, const char *file, evolve_base *b,
                           frep_error *err)
{
    b->setops = GP_SETOPS_RFUNC; /* HyperFun's default */
    for (uint32_t k = 0; k < af->npragmas; k++) {
        const ast_pragma *p = &af->pragmas[k];
        if (strcmp(p->word, "setops") != 0) continue;
        if (strncmp(p->text, "minmax", 6) == 0) b->setops = GP_SETOPS_MINMAX;
        else if (strncmp(p->text, "rfunc", 5) == 0) b->setops = GP_SETOPS_RFUNC;
        else
            return frep_error_at(err, FREP_EINPUT, file, (long)p->loc.line, 0,
                                 "the residual of a model with '@setops %s' cannot be evolved "
                                 "(minmax or rfunc only)",
                                 p->text);
    }
    return 0;
}

/* Its name in the output: my_model is reserved for the joined model, so it becomes
 * RESIDUAL_BASE_NAME, with a digit while that is taken. */
static void residual_name(const ast_file *af, const ast_model *m, char *newname, size_t cap)
{
    snprintf(newname, cap, "%s", m->name);
    if (!name_eq(m->name, strlen(m->name), "my_model")) return;
    for (int k = 1;; k++) {
        if (k == 1) snprintf(newname, cap, "%s", RESIDUAL_BASE_NAME);
        else snprintf(newname, cap, "%s%d", RESIDUAL_BASE_NAME, k);
        int taken = 0;
        for (uint32_t q = 0; q < af->nmodels; q++)
            if (name_eq(af->models[q].name, strlen(af->models[q].name), newname)) taken = 1;
        if (!taken) return;
    }
}

/* The source with every pragma disarmed (the output's own @setops/@box come first, and
 * the base's @free parameters stay fixed: a refit changes the new primitives only),
 * and the model renamed when its name changed. 0 or -1 (memory). */
static int residual_text(const char *src, size_t len, const ast_file *af, const ast_model *m,
                         const char *newname, evolve_base *b)
{
    char *text = frep_malloc(len + 1);
    if (!text) return -1;
    memcpy(text, src, len);
    text[len] = '\0';
    for (uint32_t k = 0; k < af->npragmas; k++) {
        uint32_t at = af->pragmas[k].loc.off;
        if (at < len && text[at] == '@') text[at] = ' ';
    }
    if (strcmp(newname, m->name) == 0) {
        b->text = text;
        return 0;
    }
    b->text = rename_ident(text, len, m->loc.off, m->name, newname);
    frep_free(text);
    return b->text ? 0 : -1;
}

/* The joined model's header and its call of the base: the arrays passed on unchanged.
 * A model of fewer than 3 coordinates is refused. */
static int residual_signature(const ast_model *m, const char *newname, const char *file,
                              evolve_base *b, frep_error *err)
{
    char hdr[256], call[256 + 64];
    if (m->nparams == 3)
        snprintf(hdr, sizeof hdr, "x[%u], a[%u], s[%u]", m->params[0].size,
                 m->params[1].size, m->params[2].size);
    else
        snprintf(hdr, sizeof hdr, "x[%u], a[%u]", m->params[0].size, m->params[1].size);
    snprintf(call, sizeof call, "%s(x, a%s)", newname, m->nparams == 3 ? ", s" : "");
    if (m->params[0].size < 3)
        return frep_error_at(err, FREP_EINPUT, file, 0, 0,
                             "model '%s' takes x[%u]: a residual needs 3D points", m->name,
                             m->params[0].size);
    b->header = frep_strdup(hdr);
    b->call = frep_strdup(call);
    return 0;
}

int residual_prepare(const char *file, const char *src, size_t len, const char *model,
                     const frep_program *prog, evolve_base *b, frep_error *err)
{
    memset(b, 0, sizeof *b);
    b->prog = prog;
    arena A;
    arena_init(&A);
    diag_sink ds = { quiet_diag, NULL, file, 0, 0, NULL, 0 };
    ast_file af;
    memset(&af, 0, sizeof af);
    int rc = -1;
    const ast_model *m = NULL;
    char newname[64];
    if (ast_parse(&A, file, src, len, &ds, &af) || af.nmodels == 0) {
        if (A.failed || ds.nomem) frep_error_nomem(err);
        else frep_error_at(err, FREP_EINPUT, file, 0, 0, "cannot parse the model");
    } else if ((m = residual_model(&af, file, model, err)) && !residual_setops(&af, file, b, err)) {
        residual_name(&af, m, newname, sizeof newname);
        if (residual_text(src, len, &af, m, newname, b) || !(b->name = frep_strdup(newname)))
            frep_error_nomem(err);
        else if (!residual_signature(m, newname, file, b, err))
            rc = b->header && b->call ? 0 : frep_error_nomem(err);
    }
    arena_free(&A);
    if (rc) residual_free(b);
    return rc;
}

int residual_eval(const evolve_base *b, const frep_cloud *c, int threads, double *f,
                  double *g, uint8_t *ok, size_t *nbad)
{
    size_t n = c->n, bad = 0;
    size_t ch = n < RESIDUAL_CHUNK ? (n ? n : 1) : RESIDUAL_CHUNK;
    double *gx = frep_malloc(ch * sizeof *gx), *gy = frep_malloc(ch * sizeof *gy);
    double *gz = frep_malloc(ch * sizeof *gz);
    int rc = -1;
    if (!gx || !gy || !gz) goto out;
    for (size_t i0 = 0; i0 < n; i0 += ch) {
        size_t m = n - i0 < ch ? n - i0 : ch;
        frep_runtime_error re;
        memset(&re, 0, sizeof re);
        if (frep_eval_grad_par(b->prog, m, c->x + i0, c->y + i0, c->z + i0, NULL, f + i0, gx,
                               gy, gz, threads, &re))
            goto out;
        for (size_t k = 0; k < m; k++) {
            size_t i = i0 + k;
            ok[i] = isfinite(f[i]) && isfinite(gx[k]) && isfinite(gy[k]) && isfinite(gz[k]);
            if (!ok[i]) {
                f[i] = 0;
                g[3 * i] = g[3 * i + 1] = g[3 * i + 2] = 0;
                bad++;
                continue;
            }
            g[3 * i] = gx[k];
            g[3 * i + 1] = gy[k];
            g[3 * i + 2] = gz[k];
        }
    }
    rc = 0;
out:
    if (nbad) *nbad = bad;
    frep_free(gx);
    frep_free(gy);
    frep_free(gz);
    return rc;
}

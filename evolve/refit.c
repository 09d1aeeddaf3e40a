/* refit.c - `frep evolve --refit`: the evolved tree written as a frep model whose
 * primitive parameters are `-- @free`, compiled, and fitted on every point by fit/fit.c
 * (Levenberg-Marquardt, geometric distance, Huber loss); the fitted values go back
 * into the primitives.  See refit.h.
 */
#include "config.h"
#include "alloc.h"
#include "buf.h"
#include "err.h"

#include "refit.h"

#include "fit.h"
#include "util.h"
#include "vec3.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Points the optimizer fits at most (a seeded uniform subset; the RMS figures use every
 * point): each iteration differentiates the tree with respect to every parameter at
 * every point, and a few thousand points already fix a few dozen parameters. */
#define REFIT_MAX_POINTS 4096
/* Levenberg-Marquardt iterations per weight round, and rounds of re-frozen geometric
 * weights: the start is close (the segmented fit), so few are needed. */
#define REFIT_LM_ITER 50
#define REFIT_ROUNDS 4

/* Parameters of a primitive in frep's call order (prim_write_call). */
#define REFIT_MAX_PRIM_PARAMS 8

/* The call arguments of q (after x) into v; returns their number. */
static int prim_params(const prim *q, double v[REFIT_MAX_PRIM_PARAMS])
{
    int n = 0;
    for (int c = 0; c < 3; c++) v[n++] = q->p[c];
    switch (q->type) {
    case PRIM_PLANE:
    case PRIM_SPHERE:
        v[n++] = q->r;
        break;
    case PRIM_CYLINDER:
    case PRIM_CONE:
        for (int c = 0; c < 3; c++) v[n++] = q->a[c];
        v[n++] = q->r;
        break;
    case PRIM_TORUS:
        for (int c = 0; c < 3; c++) v[n++] = q->a[c];
        v[n++] = q->R;
        v[n++] = q->r;
        break;
    case PRIM__COUNT:
        break;
    }
    return n;
}

/* Back from call arguments; directions normalised as the frep functions do. */
static void prim_set_params(prim *q, const double *v)
{
    int n = 0;
    for (int c = 0; c < 3; c++) q->p[c] = v[n++];
    switch (q->type) {
    case PRIM_PLANE:
        /* frPlane is d - n.x / |n|: normalising n keeps the function. */
        q->r = v[n++];
        vec3_normalize(q->p);
        break;
    case PRIM_SPHERE:
        q->r = fabs(v[n++]);
        break;
    case PRIM_CYLINDER:
    case PRIM_CONE:
        for (int c = 0; c < 3; c++) q->a[c] = v[n++];
        q->r = v[n++];
        vec3_normalize(q->a);
        break;
    case PRIM_TORUS:
        for (int c = 0; c < 3; c++) q->a[c] = v[n++];
        q->R = v[n++];
        q->r = v[n++];
        vec3_normalize(q->a);
        break;
    case PRIM__COUNT:
        break;
    }
}

static const char *prim_fn(prim_type t)
{
    switch (t) {
    case PRIM_PLANE: return "frPlane";
    case PRIM_SPHERE: return "frSphere";
    case PRIM_CYLINDER: return "frCylinder";
    case PRIM_CONE: return "frCone";
    case PRIM_TORUS: return "frTorus";
    case PRIM__COUNT: break;
    }
    return "frPlane";
}

/* The model text: every used primitive's parameters as `-- @free` variables qJ_K, the
 * primitives pJ, the tree (no clipping box: it is far from the points). The string is
 * frep_free'd by the caller; NULL when out of memory. */
static char *refit_source(const evolve_result *res, const prim *prims, size_t nprims,
                          const uint8_t *used, const evolve_base *base, gp_setops s,
                          size_t *len)
{
    frep_buf b = FREP_BUF_INIT;
    buf_printf(&b, "-- @setops %s\n", s == GP_SETOPS_RFUNC ? "rfunc" : "minmax");
    if (base) buf_printf(&b, "%s\n", base->text);
    buf_printf(&b, "refit_tree(%s)\n{\n", base ? base->header : "x[3], a[1]");
    for (size_t j = 0; j < nprims; j++) {
        if (!used[j]) continue;
        double v[REFIT_MAX_PRIM_PARAMS];
        int n = prim_params(&prims[j], v);
        for (int k = 0; k < n; k++)
            buf_printf(&b, "    q%zu_%d = %.17g;  -- @free\n", j + 1, k + 1, v[k]);
        buf_printf(&b, "    p%zu = %s(x", j + 1, prim_fn(prims[j].type));
        for (int k = 0; k < n; k++) buf_printf(&b, ", q%zu_%d", j + 1, k + 1);
        buf_puts(&b, ");\n");
    }
    if (used[nprims]) buf_printf(&b, "    p%zu = %s;\n", nprims + 1, base->call);
    buf_puts(&b, "    refit_tree = ");
    tree_print(&b, res->tree.code, res->tree.len, "p");
    buf_puts(&b, ";\n}\n");
    return buf_finish(&b, len);
}

/* Compilation of generated text fails only on a bug: the first message is kept. */
typedef struct diag_keep {
    char msg[256];
} diag_keep;

static void keep_diag(void *user, const frep_diag *d)
{
    diag_keep *k = user;
    if (d->severity == FREP_ERROR && !k->msg[0])
        snprintf(k->msg, sizeof k->msg, "%u:%u: %s", d->line, d->col, d->message);
}

/* ---- the driver: the steps of doc/evolve.md ("Refining the parameters") ---- */

/* One evolve_refit: its inputs, the points, the compiled tree and its parameters.
 * Stages return 0, or -1 with err set. */
typedef struct refit_ctx {
    const evolve_options *o;
    const frep_cloud *cloud;
    prim *prims;
    size_t nprims;
    const evolve_base *base;
    evolve_result *res;
    evolve_refit_info *info;
    frep_error *err;
    uint8_t *used;           /* used[j]: the tree uses leaf j (j == nprims: the base) */
    prim *saved;             /* prims before the refit, restored on failure */
    double *px, *py, *pz;    /* the valid points ... */
    double *qx, *qy, *qz;    /* ... and their unit normals */
    fit_points pts;          /* every valid point */
    fit_points spts;         /* the optimizer's subset (pts itself when small) */
    double *sx;              /* spts's arrays (6 x m), NULL when spts is pts */
    char *src;               /* the refit model's text (refit_source) */
    frep_program *prog;
    size_t np;               /* refined parameters */
    size_t *pidx;            /* parameter k is slot pidx[2k+1] of primitive pidx[2k] */
    size_t *fidx;            /* ... and program parameter fidx[k] */
    size_t *gidx;            /* scratch: the program parameters of one group */
    double *all;             /* the values of every program parameter */
    fit_config cfg;
} refit_ctx;

/* The leaves the tree uses, and a copy of the primitives to restore on failure. */
static int refit_used(refit_ctx *c)
{
    const gp_tree *t = &c->res->tree;
    c->used = frep_calloc(c->nprims + 1, 1);
    c->saved = frep_malloc((c->nprims ? c->nprims : 1) * sizeof *c->saved);
    if (!c->used || !c->saved) return frep_error_nomem(c->err);
    memcpy(c->saved, c->prims, c->nprims * sizeof *c->prims);
    for (uint32_t pc = 0; pc < t->len; pc++)
        if (t->code[pc].op == FREP_OP_PRIM && t->code[pc].arg <= c->nprims)
            c->used[t->code[pc].arg] = 1;
    if (c->used[c->nprims] && !c->base)
        return frep_error_set(c->err, FREP_EINTERNAL,
                              "internal error: the tree uses a base model that was not given");
    return 0;
}

/* Points: finite, with a normal (the same set evolve_run scored). */
static int refit_points(refit_ctx *c)
{
    const frep_cloud *cl = c->cloud;
    size_t n = 0, N = cl->n;
    c->px = frep_malloc((N ? N : 1) * sizeof *c->px);
    c->py = frep_malloc((N ? N : 1) * sizeof *c->py);
    c->pz = frep_malloc((N ? N : 1) * sizeof *c->pz);
    c->qx = frep_malloc((N ? N : 1) * sizeof *c->qx);
    c->qy = frep_malloc((N ? N : 1) * sizeof *c->qy);
    c->qz = frep_malloc((N ? N : 1) * sizeof *c->qz);
    if (!c->px || !c->py || !c->pz || !c->qx || !c->qy || !c->qz) return frep_error_nomem(c->err);
    for (size_t i = 0; i < N; i++) {
        double q[3] = { cl->nx[i], cl->ny[i], cl->nz[i] };
        double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (!isfinite(cl->x[i]) || !isfinite(cl->y[i]) || !isfinite(cl->z[i]) ||
            !isfinite(l) || !(l > 0))
            continue;
        c->px[n] = cl->x[i];
        c->py[n] = cl->y[i];
        c->pz[n] = cl->z[i];
        c->qx[n] = q[0] / l;
        c->qy[n] = q[1] / l;
        c->qz[n] = q[2] / l;
        n++;
    }
    fit_points pts = { n, c->px, c->py, c->pz, c->qx, c->qy, c->qz };
    c->pts = pts;
    c->spts = pts;
    return 0;
}

/* The tree as a model whose primitive parameters are `-- @free`, compiled. */
static int refit_compile(refit_ctx *c)
{
    size_t slen = 0;
    c->src = refit_source(c->res, c->prims, c->nprims, c->used, c->base, c->o->gp.setops,
                          &slen);
    if (!c->src) return frep_error_nomem(c->err);
    frep_compile_options co;
    frep_compile_options_init(&co);
    co.model = "refit_tree";
    diag_keep dk;
    dk.msg[0] = '\0';
    c->prog = frep_compile("(refit)", c->src, slen, &co, keep_diag, &dk);
    if (!c->prog)
        return frep_error_set(c->err, FREP_EINTERNAL,
                              "internal error: the refit model does not compile: %s", dk.msg);
    return 0;
}

/* Program parameters: the qJ_K are refined, the others (the a[] array) held. */
static int refit_params(refit_ctx *c)
{
    size_t npa = frep_program_nparams(c->prog), np = 0;
    c->pidx = frep_malloc(2 * (npa ? npa : 1) * sizeof *c->pidx);
    c->gidx = frep_malloc((npa ? npa : 1) * sizeof *c->gidx);
    c->all = frep_malloc((npa ? npa : 1) * sizeof *c->all);
    c->fidx = frep_malloc((npa ? npa : 1) * sizeof *c->fidx);
    if (!c->pidx || !c->gidx || !c->all || !c->fidx) return frep_error_nomem(c->err);
    for (size_t k = 0; k < npa; k++) {
        const char *nm = frep_program_param_name(c->prog, k);
        size_t j = 0, sl = 0;
        c->all[k] = frep_program_param_value(c->prog, k);
        if (!nm || sscanf(nm, "q%zu_%zu", &j, &sl) != 2 || j < 1 || j > c->nprims || sl < 1 ||
            sl > REFIT_MAX_PRIM_PARAMS)
            continue;
        c->pidx[2 * np] = j - 1;
        c->pidx[2 * np + 1] = sl - 1;
        c->fidx[np++] = k;
    }
    c->np = np;
    c->info->nparams = np;
    return 0;
}

/* The optimizer's points: the first REFIT_MAX_POINTS of a seeded shuffle, copied. */
static int refit_subset(refit_ctx *c)
{
    size_t n = c->pts.n, m = n < REFIT_MAX_POINTS ? n : REFIT_MAX_POINTS;
    if (m >= n) return 0;
    double *sx = c->sx = frep_malloc(6 * m * sizeof *sx);
    size_t *perm = frep_malloc(n * sizeof *perm);
    if (!sx || !perm) {
        frep_free(perm);
        return frep_error_nomem(c->err);
    }
    for (size_t i = 0; i < n; i++) perm[i] = i;
    gp_rng rng;
    gp_rng_seed(&rng, c->o->gp.seed ^ 0x7e417e417e417e41u);
    for (size_t i = 0; i < m; i++) {
        size_t j = i + (size_t)(gp_rng_unif(&rng) * (double)(n - i));
        if (j >= n) j = n - 1;
        size_t t = perm[i];
        perm[i] = perm[j];
        perm[j] = t;
        sx[i] = c->px[perm[i]];
        sx[m + i] = c->py[perm[i]];
        sx[2 * m + i] = c->pz[perm[i]];
        sx[3 * m + i] = c->qx[perm[i]];
        sx[4 * m + i] = c->qy[perm[i]];
        sx[5 * m + i] = c->qz[perm[i]];
    }
    frep_free(perm);
    fit_points sp = { m, sx, sx + m, sx + 2 * m, sx + 3 * m, sx + 4 * m, sx + 5 * m };
    c->spts = sp;
    return 0;
}

/* Levenberg-Marquardt on the geometric distance, Huber at eps_d: points the tree does
 * not explain (other parts, outliers) pull linearly, not quadratically. */
static void refit_config(refit_ctx *c)
{
    fit_config *cfg = &c->cfg;
    fit_config_init(cfg);
    cfg->method = FIT_METHOD_LM;
    cfg->obj.kind = FIT_OBJ_GEOMETRIC;
    cfg->obj.loss = FIT_LOSS_HUBER;
    cfg->obj.loss_scale = c->res->eps_d;
    cfg->obj.nthreads = c->o->gp.threads;
    cfg->seed = c->o->gp.seed;
    cfg->lm.max_iter = REFIT_LM_ITER;
    cfg->reweight_rounds = REFIT_ROUNDS;
    /* Ctrl-C keeps the best parameters so far; the flag the cancel callback raises */
    cfg->interrupt = c->o->gp.cancel ? c->o->gp.cancel->flag : NULL;
}

/* The RMS and maximum distance over every point, with every parameter at its value:
 * before the refit (after = 0) or after it. */
static int refit_distances(refit_ctx *c, int after)
{
    evolve_refit_info *info = c->info;
    fit_model fm;
    if (fit_program_model(c->prog, c->fidx, 1, c->all, &fm)) return frep_error_nomem(c->err);
    fit_objective *ob = fit_objective_new(&fm, &c->pts, &c->cfg.obj);
    double x[1] = { c->all[c->fidx[0]] };
    int rc = !ob ? -1 : fit_objective_distances(ob, x, after ? &info->rms_after : &info->rms_before,
                                                after ? &info->max_after : &info->max_before);
    fit_objective_free(ob);
    fit_program_model_free(&fm);
    if (rc < 0) return frep_error_nomem(c->err);
    if (rc > 0)
        return frep_error_set(c->err, FREP_EINPUT, "the tree cannot be evaluated at the points");
    return 0;
}

/* The end of the group of whole primitives that starts at parameter k0: at most
 * FIT_MAX_PARAMS parameters, unless one primitive alone has more. */
static size_t refit_group_end(const refit_ctx *c, size_t k0)
{
    size_t k1 = k0;
    while (k1 < c->np) {
        size_t e = k1;
        while (e < c->np && c->pidx[2 * e] == c->pidx[2 * k1]) e++;
        if (e - k0 > FIT_MAX_PARAMS && k1 > k0) break;
        k1 = e;
    }
    return k1;
}

/* The optimizer on each group of whole primitives in order, the others held. */
static int refit_groups(refit_ctx *c)
{
    double x[FIT_MAX_PARAMS];
    for (size_t k0 = 0; k0 < c->np && !gp_cancelled(c->o->gp.cancel);) {
        size_t k1 = refit_group_end(c, k0), nf = k1 - k0;
        for (size_t k = 0; k < nf; k++) {
            c->gidx[k] = c->fidx[k0 + k];
            x[k] = c->all[c->gidx[k]];
        }
        fit_model fm;
        if (fit_program_model(c->prog, c->gidx, nf, c->all, &fm)) return frep_error_nomem(c->err);
        fit_result fr;
        frep_error fe;
        frep_error_init(&fe);
        int r = fit_run(&fm, &c->spts, NULL, NULL, x, &c->cfg, &fr, &fe);
        fit_program_model_free(&fm);
        if (r) return frep_error_set(c->err, fe.code, "refit: %s", fe.msg);
        for (size_t k = 0; k < nf; k++) c->all[c->gidx[k]] = x[k];
        c->info->groups++;
        k0 = k1;
    }
    return 0;
}

/* The fitted values back into the primitives (directions normalised). */
static void refit_write_back(refit_ctx *c)
{
    for (size_t j = 0; j < c->nprims; j++) {
        if (!c->used[j]) continue;
        double v[REFIT_MAX_PRIM_PARAMS];
        prim_params(&c->prims[j], v);
        for (size_t k = 0; k < c->np; k++)
            if (c->pidx[2 * k] == j) v[c->pidx[2 * k + 1]] = c->all[c->fidx[k]];
        prim_set_params(&c->prims[j], v);
    }
}

/* The steps: leaves, points, the model compiled, its parameters, the distances
 * before, the optimizer per group, the distances after, the primitives updated and
 * the statistics recomputed. */
static int refit_stages(refit_ctx *c)
{
    if (refit_used(c) || refit_points(c) || refit_compile(c) || refit_params(c)) return -1;
    if (c->np == 0) return 0;  /* the tree is the base model alone */
    if (c->pts.n < REFIT_MIN_POINTS_PER_PARAM * c->np)
        return frep_error_set(c->err, FREP_EINPUT,
                              "%zu points cannot determine the %zu parameters of the tree",
                              c->pts.n, c->np);
    if (refit_subset(c)) return -1;
    refit_config(c);
    if (refit_distances(c, 0) || refit_groups(c) || refit_distances(c, 1)) return -1;
    refit_write_back(c);
    if (evolve_stats(c->o, c->cloud, c->prims, c->nprims, c->res))
        return frep_error_nomem(c->err);
    return 0;
}

int evolve_refit(const evolve_options *o, const frep_cloud *cloud, prim *prims,
                 size_t nprims, const evolve_base *base, evolve_result *res,
                 evolve_refit_info *info, frep_error *err)
{
    memset(info, 0, sizeof *info);
    double t0 = frep_now_seconds();
    refit_ctx c;
    memset(&c, 0, sizeof c);
    c.o = o;
    c.cloud = cloud;
    c.prims = prims;
    c.nprims = nprims;
    c.base = base;
    c.res = res;
    c.info = info;
    c.err = err;
    int rc = refit_stages(&c);
    if (rc && c.saved) memcpy(prims, c.saved, nprims * sizeof *prims);
    info->seconds = frep_now_seconds() - t0;
    frep_program_free(c.prog);
    frep_free(c.src);
    frep_free(c.used);
    frep_free(c.saved);
    frep_free(c.pidx);
    frep_free(c.fidx);
    frep_free(c.gidx);
    frep_free(c.all);
    frep_free(c.sx);
    frep_free(c.px);
    frep_free(c.py);
    frep_free(c.pz);
    frep_free(c.qx);
    frep_free(c.qy);
    frep_free(c.qz);
    return rc;
}

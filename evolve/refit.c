/* refit.c - `frep evolve --refit`: the evolved tree written as a frep model whose
 * primitive parameters are `-- @free`, compiled, and fitted on every point by fit/fit.c
 * (Levenberg-Marquardt, geometric distance, Huber loss); the fitted values go back
 * into the primitives.  See refit.h.
 */
#define _POSIX_C_SOURCE 200809L /* open_memstream */
#include "config.h"
#include "alloc.h"
#include "err.h"

#include "refit.h"

#include "fit.h"

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

static void unit(double *a)
{
    double l = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (l > 0)
        for (int c = 0; c < 3; c++) a[c] /= l;
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
        unit(q->p);
        break;
    case PRIM_SPHERE:
        q->r = fabs(v[n++]);
        break;
    case PRIM_CYLINDER:
    case PRIM_CONE:
        for (int c = 0; c < 3; c++) q->a[c] = v[n++];
        q->r = v[n++];
        unit(q->a);
        break;
    case PRIM_TORUS:
        for (int c = 0; c < 3; c++) q->a[c] = v[n++];
        q->R = v[n++];
        q->r = v[n++];
        unit(q->a);
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
 * primitives pJ, the tree (no clipping box: it is far from the points). */
static char *refit_source(const evolve_result *res, const prim *prims, size_t nprims,
                          const uint8_t *used, const evolve_base *base, gp_setops s,
                          size_t *len)
{
    char *buf = NULL;
    size_t blen = 0;
    FILE *f = open_memstream(&buf, &blen);
    if (!f) return NULL;
    fprintf(f, "-- @setops %s\n", s == GP_SETOPS_RFUNC ? "rfunc" : "minmax");
    if (base) fprintf(f, "%s\n", base->text);
    fprintf(f, "refit_tree(%s)\n{\n", base ? base->header : "x[3], a[1]");
    for (size_t j = 0; j < nprims; j++) {
        if (!used[j]) continue;
        double v[REFIT_MAX_PRIM_PARAMS];
        int n = prim_params(&prims[j], v);
        for (int k = 0; k < n; k++) fprintf(f, "    q%zu_%d = %.17g;  -- @free\n", j + 1, k + 1, v[k]);
        fprintf(f, "    p%zu = %s(x", j + 1, prim_fn(prims[j].type));
        for (int k = 0; k < n; k++) fprintf(f, ", q%zu_%d", j + 1, k + 1);
        fprintf(f, ");\n");
    }
    if (used[nprims]) fprintf(f, "    p%zu = %s;\n", nprims + 1, base->call);
    fprintf(f, "    refit_tree = ");
    tree_print(f, res->tree.code, res->tree.len, "p");
    fprintf(f, ";\n}\n");
    /* open_memstream's buffer comes from the C library: hand over a copy made by
     * frep's allocator, which the caller releases with frep_free. */
    char *text = fclose(f) == 0 ? frep_strndup(buf, blen) : NULL;
    free(buf);
    if (text) *len = blen;
    return text;
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

int evolve_refit(const evolve_options *o, const frep_cloud *cloud, prim *prims,
                 size_t nprims, const evolve_base *base, evolve_result *res,
                 evolve_refit_info *info, frep_error *err)
{
    memset(info, 0, sizeof *info);
    double t0 = gp_now();
    int rc = -1;
    uint8_t *used = frep_calloc(nprims + 1, 1);
    size_t *pidx = NULL, *gidx = NULL;
    double *all = NULL, *sx = NULL, *px = NULL, *py = NULL, *pz = NULL, *qx = NULL, *qy = NULL, *qz = NULL;
    char *src = NULL;
    frep_program *prog = NULL;
    prim *saved = frep_malloc((nprims ? nprims : 1) * sizeof *saved);
    if (!used || !saved) goto oom;
    memcpy(saved, prims, nprims * sizeof *prims);
    for (uint32_t pc = 0; pc < res->tree.len; pc++)
        if (res->tree.code[pc].op == FREP_OP_PRIM && res->tree.code[pc].arg <= nprims)
            used[res->tree.code[pc].arg] = 1;
    if (used[nprims] && !base) {
        frep_error_set(err, FREP_EINTERNAL,
                       "internal error: the tree uses a base model that was not given");
        goto out;
    }

    /* Points: finite, with a normal (the same set evolve_run scored). */
    size_t n = 0, N = cloud->n;
    px = frep_malloc((N ? N : 1) * sizeof *px);
    py = frep_malloc((N ? N : 1) * sizeof *py);
    pz = frep_malloc((N ? N : 1) * sizeof *pz);
    qx = frep_malloc((N ? N : 1) * sizeof *qx);
    qy = frep_malloc((N ? N : 1) * sizeof *qy);
    qz = frep_malloc((N ? N : 1) * sizeof *qz);
    if (!px || !py || !pz || !qx || !qy || !qz) goto oom;
    for (size_t i = 0; i < N; i++) {
        double q[3] = { cloud->nx[i], cloud->ny[i], cloud->nz[i] };
        double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (!isfinite(cloud->x[i]) || !isfinite(cloud->y[i]) || !isfinite(cloud->z[i]) ||
            !isfinite(l) || !(l > 0))
            continue;
        px[n] = cloud->x[i];
        py[n] = cloud->y[i];
        pz[n] = cloud->z[i];
        qx[n] = q[0] / l;
        qy[n] = q[1] / l;
        qz[n] = q[2] / l;
        n++;
    }

    size_t slen = 0;
    src = refit_source(res, prims, nprims, used, base, o->gp.setops, &slen);
    if (!src) goto oom;
    frep_compile_options co;
    frep_compile_options_init(&co);
    co.model = "refit_tree";
    diag_keep dk;
    dk.msg[0] = '\0';
    prog = frep_compile("(refit)", src, slen, &co, keep_diag, &dk);
    if (!prog) {
        frep_error_set(err, FREP_EINTERNAL, "internal error: the refit model does not compile: %s",
                       dk.msg);
        goto out;
    }
    /* Program parameters: the qJ_K (refined) and others (the a[] array: held). */
    size_t npa = frep_program_nparams(prog), np = 0;
    pidx = frep_malloc(2 * (npa ? npa : 1) * sizeof *pidx);
    gidx = frep_malloc((npa ? npa : 1) * sizeof *gidx);
    all = frep_malloc((npa ? npa : 1) * sizeof *all);
    size_t *fidx = frep_malloc((npa ? npa : 1) * sizeof *fidx);
    if (!pidx || !gidx || !all || !fidx) {
        frep_free(fidx);
        goto oom;
    }
    for (size_t k = 0; k < npa; k++) {
        const char *nm = frep_program_param_name(prog, k);
        size_t j = 0, sl = 0;
        all[k] = frep_program_param_value(prog, k);
        if (!nm || sscanf(nm, "q%zu_%zu", &j, &sl) != 2 || j < 1 || j > nprims || sl < 1 ||
            sl > REFIT_MAX_PRIM_PARAMS)
            continue;
        pidx[2 * np] = j - 1;
        pidx[2 * np + 1] = sl - 1;
        fidx[np++] = k;
    }
    info->nparams = np;
    if (np == 0) { /* the tree is the base model alone */
        frep_free(fidx);
        rc = 0;
        goto out;
    }
    if (n < REFIT_MIN_POINTS_PER_PARAM * np) {
        frep_free(fidx);
        frep_error_set(err, FREP_EINPUT,
                       "%zu points cannot determine the %zu parameters of the tree", n, np);
        goto out;
    }

    fit_points pts = { n, px, py, pz, qx, qy, qz };
    /* The optimizer's subset: the first m of a seeded shuffle, copied after the points. */
    size_t m = n < REFIT_MAX_POINTS ? n : REFIT_MAX_POINTS;
    fit_points spts = pts;
    if (m < n) {
        sx = frep_malloc(6 * m * sizeof *sx);
        size_t *perm = frep_malloc(n * sizeof *perm);
        if (!sx || !perm) {
            frep_free(perm);
            frep_free(fidx);
            goto oom;
        }
        for (size_t i = 0; i < n; i++) perm[i] = i;
        gp_rng rng;
        gp_rng_seed(&rng, o->gp.seed ^ 0x7e417e417e417e41u);
        for (size_t i = 0; i < m; i++) {
            size_t j = i + (size_t)(gp_rng_unif(&rng) * (double)(n - i));
            if (j >= n) j = n - 1;
            size_t t = perm[i];
            perm[i] = perm[j];
            perm[j] = t;
            sx[i] = px[perm[i]];
            sx[m + i] = py[perm[i]];
            sx[2 * m + i] = pz[perm[i]];
            sx[3 * m + i] = qx[perm[i]];
            sx[4 * m + i] = qy[perm[i]];
            sx[5 * m + i] = qz[perm[i]];
        }
        frep_free(perm);
        fit_points sp = { m, sx, sx + m, sx + 2 * m, sx + 3 * m, sx + 4 * m, sx + 5 * m };
        spts = sp;
    }
    fit_config cfg;
    fit_config_init(&cfg);
    cfg.method = FIT_METHOD_LM;
    cfg.obj.kind = FIT_OBJ_GEOMETRIC;
    /* Huber at eps_d: points the tree does not explain (other parts, outliers) pull
     * linearly, not quadratically. */
    cfg.obj.loss = FIT_LOSS_HUBER;
    cfg.obj.loss_scale = res->eps_d;
    cfg.obj.nthreads = o->gp.threads;
    cfg.seed = o->gp.seed;
    cfg.lm.max_iter = REFIT_LM_ITER;
    cfg.reweight_rounds = REFIT_ROUNDS;

    double x[FIT_MAX_PARAMS];
    /* RMS before and after, over the tree with every parameter at its value. */
    for (int pass = 0; pass < 2; pass++) {
        fit_model fm;
        if (fit_program_model(prog, fidx, 1, all, &fm)) {
            frep_free(fidx);
            goto oom;
        }
        fit_objective *ob = fit_objective_new(&fm, &pts, &cfg.obj);
        x[0] = all[fidx[0]];
        int bad = !ob || fit_objective_distances(ob, x, pass ? &info->rms_after : &info->rms_before,
                                                 pass ? &info->max_after : &info->max_before);
        fit_objective_free(ob);
        fit_program_model_free(&fm);
        if (bad) {
            frep_free(fidx);
            frep_error_set(err, FREP_EINPUT, "the tree cannot be evaluated at the points");
            goto out;
        }
        if (pass) break;
        /* Groups of whole primitives of at most FIT_MAX_PARAMS parameters, in order. */
        for (size_t k0 = 0; k0 < np;) {
            size_t k1 = k0;
            while (k1 < np) {
                size_t e = k1;
                while (e < np && pidx[2 * e] == pidx[2 * k1]) e++;
                if (e - k0 > FIT_MAX_PARAMS && k1 > k0) break;
                k1 = e;
            }
            size_t nf = k1 - k0;
            for (size_t k = 0; k < nf; k++) {
                gidx[k] = fidx[k0 + k];
                x[k] = all[gidx[k]];
            }
            if (fit_program_model(prog, gidx, nf, all, &fm)) {
                frep_free(fidx);
                    goto oom;
            }
            fit_result fr;
            char msg[256] = "";
            int r = fit_run(&fm, &spts, NULL, NULL, x, &cfg, &fr, msg, sizeof msg);
            fit_program_model_free(&fm);
            if (r) {
                frep_free(fidx);
                frep_error_set(err, FREP_EINPUT, "refit: %s", msg);
                goto out;
            }
            for (size_t k = 0; k < nf; k++) all[gidx[k]] = x[k];
            info->groups++;
            k0 = k1;
        }
    }
    /* Back into the primitives. */
    for (size_t j = 0; j < nprims; j++) {
        if (!used[j]) continue;
        double v[REFIT_MAX_PRIM_PARAMS];
        prim_params(&prims[j], v);
        for (size_t k = 0; k < np; k++)
            if (pidx[2 * k] == j) v[pidx[2 * k + 1]] = all[fidx[k]];
        prim_set_params(&prims[j], v);
    }
    frep_free(fidx);
    if (evolve_stats(o, cloud, prims, nprims, res)) goto oom;
    rc = 0;
    goto out;
oom:
    frep_error_nomem(err);
out:
    if (rc && saved) memcpy(prims, saved, nprims * sizeof *prims);
    info->seconds = gp_now() - t0;
    frep_program_free(prog);
    frep_free(src);
    frep_free(used);
    frep_free(saved);
    frep_free(pidx);
    frep_free(gidx);
    frep_free(all);
    frep_free(sx);
    frep_free(px);
    frep_free(py);
    frep_free(pz);
    frep_free(qx);
    frep_free(qy);
    frep_free(qz);
    return rc;
}

/* evolve.c - driver of `frep evolve`: valid points, sample, primitive caches, proxy
 * boxes, partitioned or plain GA, simplification, statistics on every point, and the
 * output model (.hf) and drawing (.dot).  See evolve.h for the pipeline.
 */
#include "config.h"

#include "evolve.h"
#include "simplify.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#define EV_PI 3.14159265358979323846

void evolve_options_init(evolve_options *o)
{
    memset(o, 0, sizeof *o);
    gp_config_init(&o->gp);
    o->partition = 1;
    o->sample = EVOLVE_DEFAULT_SAMPLE;
    o->eps_rel = EVOLVE_DEFAULT_EPS_REL;
    o->alpha_deg = EVOLVE_DEFAULT_ALPHA_DEG;
    o->lambda_scale = 1.0;
    o->simplify = 1;
}

void evolve_result_free(evolve_result *r)
{
    tree_free(&r->tree);
    memset(r, 0, sizeof *r);
}

static void set_err(char **err, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void set_err(char **err, const char *fmt, ...)
{
    if (!err) return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    *err = malloc(strlen(buf) + 1);
    if (*err) strcpy(*err, buf);
}

static int cmp_size(const void *a, const void *b)
{
    size_t x = *(const size_t *)a, y = *(const size_t *)b;
    return x < y ? -1 : x > y;
}

/* Cache of prims[use[0..k)] at the points pts[0..m) (indices into x/y/z/nrm). */
static gp_cache *build_cache(const prim *prims, const uint32_t *use, uint32_t k,
                             const double *x, const double *y, const double *z,
                             const double *nrm, const size_t *pts, size_t m, gp_setops s,
                             double eps_d, double alpha, double lambda)
{
    double *px = malloc((m ? m : 1) * sizeof *px), *py = malloc((m ? m : 1) * sizeof *py);
    double *pz = malloc((m ? m : 1) * sizeof *pz), *pn = malloc(3 * (m ? m : 1) * sizeof *pn);
    double *v = malloc((size_t)(k ? k : 1) * (m ? m : 1) * sizeof *v);
    double *g = malloc((size_t)3 * (k ? k : 1) * (m ? m : 1) * sizeof *g);
    gp_cache *c = NULL;
    if (!px || !py || !pz || !pn || !v || !g) {
        free(v);
        free(g);
        goto out;
    }
    for (size_t i = 0; i < m; i++) {
        size_t q = pts[i];
        px[i] = x[q];
        py[i] = y[q];
        pz[i] = z[q];
        for (int d = 0; d < 3; d++) pn[3 * i + d] = nrm[3 * q + d];
    }
    long kl = (long)k;
#pragma omp parallel for schedule(dynamic, 1)
    for (long jl = 0; jl < kl; jl++) {
        size_t j = (size_t)jl;
        prim_eval_many(&prims[use[j]], m, px, py, pz, v + j * m, g + 3 * j * m,
                       g + (3 * j + 1) * m, g + (3 * j + 2) * m);
    }
    c = gp_cache_new(m, k, s, v, g, pn, eps_d, alpha, lambda);
out:
    free(px);
    free(py);
    free(pz);
    free(pn);
    return c;
}

int evolve_run(const evolve_options *o, const frep_cloud *cloud, const prim *prims,
               size_t nprims, gp_progress_fn fn, void *user, evolve_result *res,
               char **err)
{
    memset(res, 0, sizeof *res);
    if (err) *err = NULL;
    double t0 = gp_now();
    if (nprims == 0) {
        set_err(err, "no primitives to combine (segmentation found none; try -p or "
                     "different segment settings)");
        return -1;
    }
    if (nprims > PART_MAX_PRIMS) {
        set_err(err, "%zu primitives: at most %u are supported", nprims, PART_MAX_PRIMS);
        return -1;
    }
    if (!cloud->has_normals) {
        set_err(err, "the cloud has no normals");
        return -1;
    }
    size_t N = cloud->n;
    int rc = -1;
    size_t *valid = malloc((N ? N : 1) * sizeof *valid);
    double *nrm = malloc(3 * (N ? N : 1) * sizeof *nrm);
    size_t *samp = NULL;
    uint32_t *all = malloc(nprims * sizeof *all), *used = NULL;
    gp_cache *sc = NULL, *fc = NULL;
    gp_eval *ev = gp_eval_new();
    gp_obb *boxes = NULL;
    gp_result gr;
    memset(&gr, 0, sizeof gr);
    if (!valid || !nrm || !all || !ev) goto oom;
    for (uint32_t j = 0; j < nprims; j++) all[j] = j;

    /* Valid points: finite coordinates and a usable normal. */
    size_t nv = 0;
    for (size_t i = 0; i < N; i++) {
        double p[3] = { cloud->x[i], cloud->y[i], cloud->z[i] };
        double q[3] = { cloud->nx[i], cloud->ny[i], cloud->nz[i] };
        double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]) || !isfinite(l) || !(l > 0))
            continue;
        for (int d = 0; d < 3; d++) nrm[3 * i + d] = q[d] / l;
        valid[nv++] = i;
    }
    res->npoints = nv;
    res->dropped = N - nv;
    if (nv == 0) {
        set_err(err, "no point with finite coordinates and a normal");
        goto out;
    }
    double lo[3] = { HUGE_VAL, HUGE_VAL, HUGE_VAL }, hi[3] = { -HUGE_VAL, -HUGE_VAL, -HUGE_VAL };
    for (size_t k = 0; k < nv; k++) {
        size_t i = valid[k];
        double p[3] = { cloud->x[i], cloud->y[i], cloud->z[i] };
        for (int d = 0; d < 3; d++) {
            if (p[d] < lo[d]) lo[d] = p[d];
            if (p[d] > hi[d]) hi[d] = p[d];
        }
    }
    res->diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                     (hi[2] - lo[2]) * (hi[2] - lo[2]));
    if (!(res->diag > 0)) {
        set_err(err, "all %zu points coincide: nothing to fit", nv);
        goto out;
    }
    res->eps_d = (o->eps_rel > 0 ? o->eps_rel : EVOLVE_DEFAULT_EPS_REL) * res->diag;
    res->alpha = (o->alpha_deg > 0 ? o->alpha_deg : EVOLVE_DEFAULT_ALPHA_DEG) * EV_PI / 180;
    /* Clipping box: the principal-axes box, or the axis-aligned one when smaller (PCA
     * axes are arbitrary for symmetric shapes such as a cube). */
    part_obb_of_points(cloud->x, cloud->y, cloud->z, valid, nv, &res->obb);
    {
        double va = 1, vo = 1;
        for (int d = 0; d < 3; d++) {
            va *= hi[d] - lo[d] + 1e-12 * res->diag;
            vo *= 2 * res->obb.h[d] + 1e-12 * res->diag;
        }
        if (va <= vo * (1 + 1e-9)) {
            memset(res->obb.ax, 0, sizeof res->obb.ax);
            for (int d = 0; d < 3; d++) {
                res->obb.ax[d][d] = 1;
                res->obb.c[d] = 0.5 * (lo[d] + hi[d]);
                res->obb.h[d] = 0.5 * (hi[d] - lo[d]);
            }
        }
    }

    /* The GA's sample: a seeded uniform subset, in cloud order. */
    size_t m = o->sample && o->sample < nv ? o->sample : nv;
    samp = malloc(nv * sizeof *samp);
    if (!samp) goto oom;
    memcpy(samp, valid, nv * sizeof *samp);
    if (m < nv) {
        gp_rng r;
        gp_rng_seed(&r, o->gp.seed ^ 0x5a5a5a5a5a5a5a5au);
        for (size_t k = 0; k < m; k++) {
            size_t j = k + (size_t)(gp_rng_unif(&r) * (double)(nv - k));
            if (j >= nv) j = nv - 1;
            size_t t = samp[k];
            samp[k] = samp[j];
            samp[j] = t;
        }
        qsort(samp, m, sizeof *samp, cmp_size);
    }
    res->nsample = m;
    double ls = o->lambda_scale > 0 ? o->lambda_scale : 1.0;
    sc = build_cache(prims, all, (uint32_t)nprims, cloud->x, cloud->y, cloud->z, nrm, samp,
                     m, o->gp.setops, res->eps_d, res->alpha, ls * log((double)(m > 1 ? m : 2)));
    if (!sc) goto oom;

    /* Proxies: the primitive's own box, else the box of the sample points it explains
     * alone. Primitives explaining no point get none and overlap everything. */
    boxes = calloc(nprims, sizeof *boxes);
    size_t *idx = malloc(m * sizeof *idx);
    if (!boxes || !idx) {
        free(idx);
        goto oom;
    }
    for (uint32_t j = 0; j < nprims; j++) {
        const prim *q = &prims[j];
        if (q->has_obb) {
            gp_obb *b = &boxes[j];
            memcpy(b->c, q->obb_c, sizeof b->c);
            memcpy(b->ax, q->obb_axes, sizeof b->ax);
            memcpy(b->h, q->obb_half, sizeof b->h);
            b->valid = 1;
            continue;
        }
        size_t nk = 0;
        for (size_t i = 0; i < m; i++) {
            double f = sc->v[(size_t)j * m + i];
            double g[3] = { sc->g[(3 * (size_t)j) * m + i], sc->g[(3 * (size_t)j + 1) * m + i],
                            sc->g[(3 * (size_t)j + 2) * m + i] };
            double gl = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
            const double *nn = sc->nrm + 3 * i;
            if (fabs(f) < res->eps_d && gl > 0 &&
                -(g[0] * nn[0] + g[1] * nn[1] + g[2] * nn[2]) / gl > cos(res->alpha))
                idx[nk++] = samp[i];
        }
        part_obb_of_points(cloud->x, cloud->y, cloud->z, idx, nk, &boxes[j]);
    }
    free(idx);

    int done = 0;
    if (o->partition && nprims > 1) {
        /* part_run needs the sample's coordinates. */
        double *xs = malloc(m * sizeof *xs), *ys = malloc(m * sizeof *ys), *zs = malloc(m * sizeof *zs);
        if (!xs || !ys || !zs) {
            free(xs);
            free(ys);
            free(zs);
            goto oom;
        }
        for (size_t i = 0; i < m; i++) {
            xs[i] = cloud->x[samp[i]];
            ys[i] = cloud->y[samp[i]];
            zs[i] = cloud->z[samp[i]];
        }
        int pr = part_run(&o->gp, sc, xs, ys, zs, boxes, EVOLVE_PROXY_MARGIN * res->eps_d, fn,
                          user, &gr, &res->part);
        free(xs);
        free(ys);
        free(zs);
        if (pr) goto oom;
        done = res->part.partitioned;
        res->partitioned = done;
    }
    if (!done) {
        tree_free(&gr.best);
        if (gp_run(&o->gp, sc, NULL, 0, fn, user, &gr)) goto oom;
    }
    if (!gr.best.len) {
        set_err(err, "the run stopped before any tree was scored");
        goto out;
    }
    res->generations = gr.generations;
    res->stop = gr.stop;
    res->fitness = gr.fitness;
    if (tree_copy(&res->tree, &gr.best)) goto oom;
    if (o->simplify && simplify_tree(&res->tree, o->gp.setops, sc, ev, &res->fitness)) goto oom;

    /* Statistics on every valid point, over the primitives of the tree only. */
    {
        gp_tree local = { NULL, 0, 0 };
        uint8_t *seen = calloc(nprims, 1);
        if (!seen || tree_copy(&local, &res->tree)) {
            free(seen);
            tree_free(&local);
            goto oom;
        }
        for (uint32_t pc = 0; pc < local.len; pc++)
            if (local.code[pc].op == FREP_OP_PRIM) seen[local.code[pc].arg] = 1;
        used = malloc(nprims * sizeof *used);
        uint32_t *map = malloc(nprims * sizeof *map);
        uint32_t k = 0;
        if (used && map) {
            for (uint32_t j = 0; j < nprims; j++)
                if (seen[j]) {
                    map[j] = k;
                    used[k++] = j;
                }
            for (uint32_t pc = 0; pc < local.len; pc++)
                if (local.code[pc].op == FREP_OP_PRIM) local.code[pc].arg = map[local.code[pc].arg];
            fc = build_cache(prims, used, k, cloud->x, cloud->y, cloud->z, nrm, valid, nv,
                             o->gp.setops, res->eps_d, res->alpha, ls * log((double)(nv > 1 ? nv : 2)));
        }
        free(seen);
        free(map);
        int bad = !fc || gp_tree_stats(fc, ev, local.code, local.len, &res->stats);
        tree_free(&local);
        if (bad) goto oom;
    }

    /* The @box extent: the grown oriented box's axis-aligned hull. */
    {
        double mg = EVOLVE_CLIP_MARGIN * res->diag;
        for (int d = 0; d < 3; d++) {
            double r = 0;
            for (int a = 0; a < 3; a++) r += (res->obb.h[a] + 2 * mg) * fabs(res->obb.ax[a][d]);
            res->box[d] = res->obb.c[d] - r;
            res->box[d + 3] = res->obb.c[d] + r;
        }
    }
    res->seconds = gp_now() - t0;
    rc = 0;
    goto out;
oom:
    set_err(err, "out of memory");
out:
    if (rc) tree_free(&res->tree);
    tree_free(&gr.best);
    free(valid);
    free(nrm);
    free(samp);
    free(all);
    free(used);
    free(boxes);
    gp_cache_free(sc);
    gp_cache_free(fc);
    gp_eval_free(ev);
    return rc;
}

/* ---- output ------------------------------------------------------------------------ */

static double pct(size_t a, size_t b) { return b ? 100.0 * (double)a / (double)b : 0.0; }

int evolve_write_model(FILE *f, const evolve_result *r, const prim *prims, size_t nprims,
                       const evolve_meta *m)
{
    const gp_tree *t = &r->tree;
    uint8_t *seen = calloc(nprims ? nprims : 1, 1);
    if (!seen) return -1;
    uint32_t k = 0;
    for (uint32_t pc = 0; pc < t->len; pc++)
        if (t->code[pc].op == FREP_OP_PRIM && t->code[pc].arg < nprims && !seen[t->code[pc].arg]) {
            seen[t->code[pc].arg] = 1;
            k++;
        }
    const char *so = m->setops == GP_SETOPS_RFUNC ? "rfunc" : "minmax";
    fprintf(f, "-- Construction tree discovered by frep evolve from %s\n",
            m->cloud ? m->cloud : "a point cloud");
    if (m->command) fprintf(f, "-- command: %s\n", m->command);
    fprintf(f, "-- seed %llu, set operations %s, %s", (unsigned long long)m->seed, so,
            r->partitioned ? "partitioned" : "not partitioned");
    if (r->partitioned)
        fprintf(f, " (%u cliques, largest %u)", r->part.ncliques, r->part.largest);
    fprintf(f, ", %u generations, %.2f s\n", r->generations, r->seconds);
    fprintf(f, "-- fitness %.6g on %zu scored points; tree size %u nodes, %u primitives\n",
            r->fitness, r->nsample, t->len, k);
    fprintf(f, "-- %.2f%% of %zu points within epsilon %.6g of the surface, %.2f%% with "
               "normals within %.3g degrees, %.2f%% both\n",
            pct(r->stats.within_eps, r->npoints), r->npoints, r->eps_d,
            pct(r->stats.normals_ok, r->npoints), r->alpha * 180 / EV_PI,
            pct(r->stats.explained, r->npoints));
    fprintf(f, "-- @setops %s\n", so);
    fprintf(f, "-- @box %.9g %.9g %.9g %.9g %.9g %.9g\n\n", r->box[0], r->box[1], r->box[2],
            r->box[3], r->box[4], r->box[5]);
    fprintf(f, "evolved(x[3], a[1])\n{\n");
    fprintf(f, "    -- primitives, named after their position in the input list\n");
    for (size_t j = 0; j < nprims; j++) {
        if (!seen[j]) continue;
        fprintf(f, "    p%zu = ", j + 1);
        prim_write_call(f, &prims[j]);
        fprintf(f, ";  -- %s", prim_type_name(prims[j].type));
        if (prims[j].separating) fprintf(f, ", separating");
        else if (prims[j].support) fprintf(f, ", %zu inliers", prims[j].support);
        fputc('\n', f);
    }
    fprintf(f, "    -- the construction tree: | union, & intersection, \\ subtraction, ~ complement\n");
    fprintf(f, "    tree = ");
    tree_print(f, t->code, t->len, "p");
    fprintf(f, ";\n");
    fprintf(f, "    -- clipped by the oriented bounding box of the cloud (grown by %g of the diagonal)\n",
            EVOLVE_CLIP_MARGIN);
    double mg = EVOLVE_CLIP_MARGIN * r->diag;
    for (int a = 0; a < 3; a++)
        for (int s = 0; s < 2; s++) {
            prim q;
            memset(&q, 0, sizeof q);
            q.type = PRIM_PLANE;
            double sg = s ? -1.0 : 1.0, d = 0;
            for (int c = 0; c < 3; c++) {
                q.p[c] = sg * r->obb.ax[a][c];
                d += q.p[c] * r->obb.c[c];
            }
            q.r = d + r->obb.h[a] + mg;
            fprintf(f, "    b%d = ", 2 * a + s + 1);
            prim_write_call(f, &q);
            fprintf(f, ";\n");
        }
    fprintf(f, "    evolved = tree & (((b1 & b2) & (b3 & b4)) & (b5 & b6));\n}\n");
    free(seen);
    return ferror(f) ? -1 : 0;
}

int evolve_write_dot(FILE *f, const evolve_result *r, const prim *prims, size_t nprims)
{
    char **names = calloc(nprims ? nprims : 1, sizeof *names);
    if (!names) return -1;
    int rc = 0;
    for (size_t j = 0; j < nprims && !rc; j++) {
        names[j] = malloc(64);
        if (!names[j]) rc = -1;
        else snprintf(names[j], 64, "p%zu\\n%s", j + 1, prim_type_name(prims[j].type));
    }
    if (!rc) tree_print_dot(f, r->tree.code, r->tree.len, (const char *const *)names);
    for (size_t j = 0; j < nprims; j++) free(names[j]);
    free(names);
    return rc || ferror(f) ? -1 : 0;
}

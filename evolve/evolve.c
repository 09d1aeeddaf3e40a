/* evolve.c - driver of `frep evolve`: valid points, sample, primitive caches, proxy
 * boxes, partitioned or plain GA, simplification, statistics on every point, and the
 * output model (.hf) and drawing (.dot).  See evolve.h for the pipeline.
 */
#include "config.h"
#include "alloc.h"
#include "buf.h"
#include "err.h"

#include "canon.h"
#include "evolve.h"
#include "residual.h"
#include "simplify.h"
#include "util.h"
#include "kdtree.h"
#include "vec3.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

void evolve_options_init(evolve_options *o)
{
    memset(o, 0, sizeof *o);
    gp_config_init(&o->gp);
    o->partition = 1;
    o->sample = EVOLVE_DEFAULT_SAMPLE;
    o->eps_rel = EVOLVE_DEFAULT_EPS_REL;
    o->alpha_deg = EVOLVE_DEFAULT_ALPHA_DEG;
    o->alpha_auto = 1;
    o->lambda_scale = 1.0;
    o->simplify = 1;
    o->polish = 1;
    o->polish_stagnation = EVOLVE_POLISH_STAGNATION;
    o->support = 1;
}

void evolve_result_free(evolve_result *r)
{
    tree_free(&r->tree);
    memset(r, 0, sizeof *r);
}

static int cmp_size(const void *a, const void *b)
{
    size_t x = *(const size_t *)a, y = *(const size_t *)b;
    return x < y ? -1 : x > y;
}

static int cmp_double_asc(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Cache of prims[use[0..k)] at the points pts[0..m) (indices into x/y/z/nrm), under
 * o's set operations. Leaf number nprims (use[j] == nprims) is the base model of
 * --residual (o->base_f, o->base_g, o->base_ok). */
static gp_cache *build_cache(const evolve_options *o, const prim *prims, size_t nprims,
                             const uint32_t *use, uint32_t k, const double *x,
                             const double *y, const double *z, const double *nrm,
                             const size_t *pts, size_t m, double eps_d, double alpha,
                             double lambda, int stats_only)
{
    const double *bf = o->base_f, *bg = o->base_g;
    const uint8_t *bok = o->base_ok;
    gp_setops s = o->gp.setops;
    double *px = frep_malloc((m ? m : 1) * sizeof *px), *py = frep_malloc((m ? m : 1) * sizeof *py);
    double *pz = frep_malloc((m ? m : 1) * sizeof *pz), *pn = frep_malloc(3 * (m ? m : 1) * sizeof *pn);
    double *v = frep_malloc((size_t)(k ? k : 1) * (m ? m : 1) * sizeof *v);
    double *g = frep_malloc((size_t)3 * (k ? k : 1) * (m ? m : 1) * sizeof *g);
    gp_cache *c = NULL;
    if (!px || !py || !pz || !pn || !v || !g) {
        frep_free(v);
        frep_free(g);
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
        if (use[j] < nprims) {
            prim_eval_many(&prims[use[j]], m, px, py, pz, v + j * m, g + 3 * j * m,
                           g + (3 * j + 1) * m, g + (3 * j + 2) * m);
            continue;
        }
        for (size_t i = 0; i < m; i++) {
            size_t q = pts[i];
            int ok = !bok || bok[q];
            v[j * m + i] = ok ? bf[q] : EVOLVE_BASE_OUTSIDE;
            for (size_t d = 0; d < 3; d++) g[(3 * j + d) * m + i] = ok ? bg[3 * q + d] : 0;
        }
    }
    c = stats_only ? gp_cache_new_stats(m, k, s, v, g, pn, eps_d, alpha, lambda)
                   : gp_cache_new(m, k, s, v, g, pn, eps_d, alpha, lambda);
out:
    frep_free(px);
    frep_free(py);
    frep_free(pz);
    frep_free(pn);
    return c;
}

/* Most cloud points the support grid's distances are measured to (a regular subset
 * of larger clouds): 20,000 points on a 32-cell grid put several points in every cell
 * a face crosses, and tau grows with their spacing, so a subset finds the same
 * unsupported edges at a fraction of the kd-tree's cost. */
#define EVOLVE_SUPPORT_MAX_POINTS 20000

/* Most separating planes the support trims may use besides the tree's primitives: each
 * costs the grid's values and gradients, 36 bytes a node, up to 1.6 MB on the 35^3
 * nodes of a cubic cloud's grid; a segmentation writes up to 6 for each curved
 * primitive (45 on nine_cuboids at 0.5% noise). */
#define EVOLVE_SUPPORT_MAX_PLANES 64

/* One support_run: the grid over the clipping box and what its stages build. */
typedef struct support_ctx {
    const evolve_options *o;
    const frep_cloud *cloud;
    const prim *prims;
    size_t nprims;
    const size_t *valid;     /* the valid points (cloud indices) */
    size_t nv;
    const gp_cache *sc;      /* the sample's cache of every primitive */
    gp_eval *ev;
    evolve_result *res;
    support_grid g;
    double H[3];             /* half sides of the grown clipping box */
    double h;                /* cell side */
    double q0[3];            /* node (0, 0, 0) in the box's frame */
    size_t ng;               /* nodes */
    double *gx, *gy, *gz;    /* node positions */
    double *clip, *dist;     /* support_grid.clip and .dist */
    double *cx, *cy, *cz;    /* the cloud points of the kd-tree */
    size_t m;                /* their number */
    kd_tree *kd;
    uint32_t *used, nu;      /* the tree's primitives */
    gp_cache *gc;            /* their values at the nodes */
    gp_cache *pc;            /* the sample's cache of them */
    gp_eval *eg;             /* evaluator on the grid */
} support_ctx;

/* The grid's frame: cubic cells, SUPPORT_GRID_CELLS along the box's longest side, and
 * one node beyond each face. 1 when there is no grid to build (an empty box). */
static int support_frame(support_ctx *c)
{
    const gp_obb *b = &c->res->obb;
    double hmax = 0, mg = EVOLVE_CLIP_MARGIN * c->res->diag;
    for (int d = 0; d < 3; d++) {
        c->H[d] = b->h[d] + mg;
        if (c->H[d] > hmax) hmax = c->H[d];
    }
    c->h = 2 * hmax / SUPPORT_GRID_CELLS;
    if (!(c->h > 0) || c->nv == 0) return 1;
    c->ng = 1;
    for (int d = 0; d < 3; d++) {
        /* One node beyond the box on each side: the clip closes every part. */
        c->g.dims[d] = (size_t)ceil(2 * c->H[d] / c->h) + 3;
        c->ng *= c->g.dims[d];
    }
    /* Node (0, 0, 0) in the box's frame, and the steps along its axes. */
    for (int d = 0; d < 3; d++) c->q0[d] = -0.5 * (double)(c->g.dims[d] - 1) * c->h;
    for (int k = 0; k < 3; k++) {
        c->g.o[k] = b->c[k];
        for (int d = 0; d < 3; d++) {
            c->g.o[k] += c->q0[d] * b->ax[d][k];
            c->g.u[d][k] = c->h * b->ax[d][k];
        }
    }
    return 0;
}

/* The nodes' positions and how deep each lies inside the clipping box. */
static int support_nodes(support_ctx *c)
{
    const gp_obb *b = &c->res->obb;
    size_t ng = c->ng;
    c->gx = frep_malloc(ng * sizeof *c->gx);
    c->gy = frep_malloc(ng * sizeof *c->gy);
    c->gz = frep_malloc(ng * sizeof *c->gz);
    c->clip = frep_malloc(ng * sizeof *c->clip);
    c->dist = frep_malloc(ng * sizeof *c->dist);
    if (!c->gx || !c->gy || !c->gz || !c->clip || !c->dist) return -1;
    for (size_t i = 0, a = 0; i < c->g.dims[0]; i++)
        for (size_t j = 0; j < c->g.dims[1]; j++)
            for (size_t k = 0; k < c->g.dims[2]; k++, a++) {
                const size_t ijk[3] = { i, j, k };
                double q[3], p[3] = { b->c[0], b->c[1], b->c[2] }, in = HUGE_VAL;
                for (int d = 0; d < 3; d++) {
                    q[d] = c->q0[d] + (double)ijk[d] * c->h;
                    if (c->H[d] - fabs(q[d]) < in) in = c->H[d] - fabs(q[d]);
                    for (int e = 0; e < 3; e++) p[e] += q[d] * b->ax[d][e];
                }
                c->gx[a] = p[0];
                c->gy[a] = p[1];
                c->gz[a] = p[2];
                c->clip[a] = in;
            }
    return 0;
}

/* The kd-tree of the valid points (a regular subset beyond the limit); the node
 * distances to it are computed on demand (NAN until then). */
static int support_cloud(support_ctx *c)
{
    size_t nv = c->nv;
    size_t stride = (nv + EVOLVE_SUPPORT_MAX_POINTS - 1) / EVOLVE_SUPPORT_MAX_POINTS, m = 0;
    c->cx = frep_malloc((nv / stride + 1) * sizeof *c->cx);
    c->cy = frep_malloc((nv / stride + 1) * sizeof *c->cy);
    c->cz = frep_malloc((nv / stride + 1) * sizeof *c->cz);
    if (!c->cx || !c->cy || !c->cz) return -1;
    for (size_t q = 0; q < nv; q += stride, m++) {
        c->cx[m] = c->cloud->x[c->valid[q]];
        c->cy[m] = c->cloud->y[c->valid[q]];
        c->cz[m] = c->cloud->z[c->valid[q]];
    }
    c->m = m;
    if (!(c->kd = kd_build(m, c->cx, c->cy, c->cz))) return -1;
    for (size_t a = 0; a < c->ng; a++) c->dist[a] = NAN;
    return 0;
}

/* tau: two cells (a crossing lies within a cell of the surface it samples) and two
 * point spacings (the median distance between neighbours, of up to 1,000 points). */
static int support_tau(support_ctx *c)
{
    size_t m = c->m, ns = m < 1000 ? m : 1000, sst = m / (ns ? ns : 1), cnt = 0;
    double *sp = frep_malloc((ns ? ns : 1) * sizeof *sp);
    if (!sp) return -1;
    for (size_t q = 0; q < ns; q++) {
        size_t r = q * sst;
        double p[3] = { c->cx[r], c->cy[r], c->cz[r] }, d2[2];
        uint32_t nb[2];
        if (kd_knn(c->kd, p, 2, nb, d2) == 2) sp[cnt++] = sqrt(d2[1]);
    }
    qsort(sp, cnt, sizeof *sp, cmp_double_asc);
    double spacing = cnt ? sp[cnt / 2] : 0;
    frep_free(sp);
    c->g.tau = 2 * c->h + 2 * spacing;
    return 0;
}

/* A separating plane of the list: a trim may bound a part by it. */
static int support_plane(const prim *q) { return q->separating && q->type == PRIM_PLANE; }

/* The primitives the trims may use, sorted, into c->used and c->nu: the tree's, and the
 * separating planes of the list (the faces of its curved primitives' inlier boxes)
 * when there are at most EVOLVE_SUPPORT_MAX_PLANES of them: a curved primitive that runs
 * on past its points has no face of its own to stop it (nine_cuboids at 0.5% noise,
 * seed 1: a cone's horn 5 units long). 0 or -1 (allocation). */
static int support_prims(support_ctx *c)
{
    uint32_t n = (uint32_t)c->nprims, nsep = 0, *used = NULL;
    uint32_t nu = tree_used_prims(&c->res->tree, n, &used);
    if (!used) return -1;
    c->used = used;
    c->nu = nu;
    /* the sample's cache holds the GA's primitives: the constructed planes after them
     * only when the union of solids replaced the tree (stage_solids) */
    uint32_t ns = n < c->sc->nprims ? n : c->sc->nprims;
    for (uint32_t j = 0; j < ns; j++) nsep += support_plane(&c->prims[j]);
    if (nsep == 0 || nsep > EVOLVE_SUPPORT_MAX_PLANES) return 0;
    uint32_t *all = frep_malloc(((size_t)nu + nsep) * sizeof *all);
    if (!all) return -1;
    uint32_t m = 0, q = 0;
    for (uint32_t j = 0; j < n; j++) {
        int in_tree = q < nu && used[q] == j;
        q += (uint32_t)in_tree;
        if (in_tree || (j < ns && support_plane(&c->prims[j]))) all[m++] = j;
    }
    frep_free(used);
    c->used = all;
    c->nu = m;
    return 0;
}

/* The caches of support_prims' primitives (the trims bound the tree's parts by their
 * own faces or by separating planes, and the grid's memory grows with the tree and
 * those planes, not with a long list of curved primitives): values at the nodes (no
 * normals to score), and the sample's. */
static int support_caches(support_ctx *c)
{
    size_t ng = c->ng;
    if (support_prims(c)) return -1;
    double *v = frep_malloc((size_t)c->nu * ng * sizeof *v);
    double *gg = frep_malloc(3 * (size_t)c->nu * ng * sizeof *gg);
    if (v && gg) {
        long kl = (long)c->nu;
#pragma omp parallel for schedule(dynamic, 1)
        for (long jl = 0; jl < kl; jl++) {
            size_t j = (size_t)jl;
            prim_eval_many(&c->prims[c->used[j]], ng, c->gx, c->gy, c->gz, v + j * ng,
                           gg + 3 * j * ng, gg + (3 * j + 1) * ng, gg + (3 * j + 2) * ng);
        }
    }
    c->gc = gp_cache_values(ng, c->nu, c->o->gp.setops, v, gg);
    const gp_cache *sc = c->sc;
    size_t *all_pts = frep_malloc((sc->n ? sc->n : 1) * sizeof *all_pts);
    if (all_pts) {
        for (size_t i = 0; i < sc->n; i++) all_pts[i] = i;
        c->pc = gp_cache_subset(sc, all_pts, sc->n, c->used, c->nu, sc->lambda);
    }
    frep_free(all_pts);
    if (!c->gc || !c->pc || !(c->eg = gp_eval_new())) return -1;
    return 0;
}

/* The trims on the tree renumbered to the caches' primitives, and its new fitness. */
static int support_trims(support_ctx *c)
{
    evolve_result *res = c->res;
    c->g.c = c->gc;
    c->g.clip = c->clip;
    c->g.cloud = c->kd;
    c->g.dist = c->dist;
    tree_renumber(&res->tree, c->used, c->nu, 0);
    int bad = support_trim(&res->tree, c->o->gp.setops, c->pc, c->ev, &c->g, c->eg,
                           &res->support);
    tree_renumber(&res->tree, c->used, c->nu, 1);
    if (bad) return -1;
    if (res->support.trims &&
        gp_fitness(c->sc, c->ev, res->tree.code, res->tree.len, &res->fitness))
        return -1;
    return 0;
}

/* The support trims (support.h) of res->tree: the grid over the clipping box, its
 * distances to the cloud's valid points and the primitives at its nodes. 0 or -1
 * (allocation). */
static int support_run(const evolve_options *o, const frep_cloud *cloud, const prim *prims,
                       size_t nprims, const size_t *valid, size_t nv,
                       const gp_cache *sc, gp_eval *ev, evolve_result *res)
{
    support_ctx c;
    memset(&c, 0, sizeof c);
    c.o = o;
    c.cloud = cloud;
    c.prims = prims;
    c.nprims = nprims;
    c.valid = valid;
    c.nv = nv;
    c.sc = sc;
    c.ev = ev;
    c.res = res;
    if (support_frame(&c)) return 0;
    int rc = support_nodes(&c) || support_cloud(&c) || support_tau(&c) ||
                     support_caches(&c) || support_trims(&c)
                 ? -1
                 : 0;
    frep_free(c.used);
    gp_cache_free(c.pc);
    frep_free(c.gx);
    frep_free(c.gy);
    frep_free(c.gz);
    frep_free(c.clip);
    frep_free(c.dist);
    frep_free(c.cx);
    frep_free(c.cy);
    frep_free(c.cz);
    kd_free(c.kd);
    gp_cache_free(c.gc);
    gp_eval_free(c.eg);
    return rc;
}

/* Points the base model (o->base_f, o->base_g) explains poorly: not evaluable there,
 * |f|/|grad f| >= eps_d, or a normal more than alpha away from -grad f (a zero gradient
 * explains nothing). */
static int base_poor(const evolve_options *o, const double *nrm, size_t i, double eps_d,
                     double cos_alpha)
{
    const double *bf = o->base_f;
    if (o->base_ok && !o->base_ok[i]) return 1;
    const double *g = o->base_g + 3 * i, *n = nrm + 3 * i;
    double gl = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if (!(gl > 0)) return 1;
    if (!(fabs(bf[i]) / gl < eps_d)) return 1;
    return !(-(g[0] * n[0] + g[1] * n[1] + g[2] * n[2]) / gl > cos_alpha);
}

/* Valid points (finite coordinates, usable normal) into valid[] with unit normals in
 * nrm[3i+c]; their diagonal. Returns the count. */
static size_t valid_points(const frep_cloud *cloud, size_t *valid, double *nrm, double lo[3],
                           double hi[3], double *diag)
{
    size_t nv = 0;
    for (int d = 0; d < 3; d++) {
        lo[d] = HUGE_VAL;
        hi[d] = -HUGE_VAL;
    }
    for (size_t i = 0; i < cloud->n; i++) {
        double p[3] = { cloud->x[i], cloud->y[i], cloud->z[i] };
        double q[3] = { 0, 0, 0 };
        if (cloud->has_normals) {
            q[0] = cloud->nx[i];
            q[1] = cloud->ny[i];
            q[2] = cloud->nz[i];
        }
        double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]) || !isfinite(l) || !(l > 0))
            continue;
        for (int d = 0; d < 3; d++) {
            nrm[3 * i + d] = q[d] / l;
            if (p[d] < lo[d]) lo[d] = p[d];
            if (p[d] > hi[d]) hi[d] = p[d];
        }
        valid[nv++] = i;
    }
    *diag = nv ? sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                      (hi[2] - lo[2]) * (hi[2] - lo[2]))
               : 0;
    return nv;
}

int evolve_residual_points(const evolve_options *o, const frep_cloud *cloud, uint8_t *mask,
                           size_t *count)
{
    size_t N = cloud->n;
    size_t *valid = frep_malloc((N ? N : 1) * sizeof *valid);
    double *nrm = frep_malloc(3 * (N ? N : 1) * sizeof *nrm);
    if (!valid || !nrm) {
        frep_free(valid);
        frep_free(nrm);
        return -1;
    }
    double lo[3], hi[3], diag;
    size_t nv = valid_points(cloud, valid, nrm, lo, hi, &diag);
    double eps_d = (o->eps_rel > 0 ? o->eps_rel : EVOLVE_DEFAULT_EPS_REL) * diag;
    double ca = cos((o->alpha_deg > 0 ? o->alpha_deg : EVOLVE_DEFAULT_ALPHA_DEG) * FREP_PI / 180);
    memset(mask, 0, N);
    size_t k = 0;
    for (size_t q = 0; q < nv; q++) {
        size_t i = valid[q];
        if (o->base_f && base_poor(o, nrm, i, eps_d, ca)) {
            mask[i] = 1;
            k++;
        }
    }
    *count = k;
    frep_free(valid);
    frep_free(nrm);
    return 0;
}

/* A seeded uniform subset of m of the pool's np indices, in cloud order, into out[m]. */
static void draw_sample(const size_t *pool, size_t np, size_t m, uint64_t seed, size_t *out,
                        size_t *tmp)
{
    memcpy(tmp, pool, np * sizeof *tmp);
    if (m < np) {
        gp_rng r;
        gp_rng_seed(&r, seed);
        for (size_t k = 0; k < m; k++) {
            size_t j = k + (size_t)(gp_rng_unif(&r) * (double)(np - k));
            if (j >= np) j = np - 1;
            size_t t = tmp[k];
            tmp[k] = tmp[j];
            tmp[j] = t;
        }
        qsort(tmp, m, sizeof *tmp, cmp_size);
    }
    memcpy(out, tmp, m * sizeof *out);
}

/* Points per part of the final statistics (evolve_stats): a whole number of
 * GP_FIT_BLOCKs, so the sums are those of one cache of every point; 16384 points of a
 * 20-leaf tree take about 12 MB (36 bytes per point and leaf, 72 per point). */
#define EVOLVE_STATS_POINTS (64 * GP_FIT_BLOCK)

/* The size term of a fitness on m points: ls ln m per node (ln 2 below two points). */
static double size_term(double ls, size_t m)
{
    return ls * log((double)(m > 1 ? m : 2));
}

/* 1 when the tree uses leaf j. */
static int tree_uses(const gp_tree *t, uint32_t j)
{
    for (uint32_t pc = 0; pc < t->len; pc++)
        if (t->code[pc].op == FREP_OP_PRIM && t->code[pc].arg == j) return 1;
    return 0;
}

int evolve_stats(const evolve_options *o, const frep_cloud *cloud, const prim *prims,
                 size_t nprims, evolve_result *res)
{
    size_t N = cloud->n;
    size_t nleaves = nprims + (o->base_f ? 1 : 0);
    size_t *valid = frep_malloc((N ? N : 1) * sizeof *valid);
    double *nrm = frep_malloc(3 * (N ? N : 1) * sizeof *nrm);
    uint8_t *seen = frep_calloc(nleaves ? nleaves : 1, 1);
    uint32_t *used = frep_malloc((nleaves ? nleaves : 1) * sizeof *used);
    uint32_t *map = frep_malloc((nleaves ? nleaves : 1) * sizeof *map);
    gp_tree local = { NULL, 0, 0 };
    gp_cache *fc = NULL;
    gp_eval *ev = gp_eval_new();
    int rc = -1;
    if (!valid || !nrm || !seen || !used || !map || !ev || tree_copy(&local, &res->tree))
        goto out;
    double lo[3], hi[3], diag;
    size_t nv = valid_points(cloud, valid, nrm, lo, hi, &diag);
    for (uint32_t pc = 0; pc < local.len; pc++)
        if (local.code[pc].op == FREP_OP_PRIM) seen[local.code[pc].arg] = 1;
    uint32_t k = 0;
    for (uint32_t j = 0; j < nleaves; j++)
        if (seen[j]) {
            map[j] = k;
            used[k++] = j;
        }
    for (uint32_t pc = 0; pc < local.len; pc++)
        if (local.code[pc].op == FREP_OP_PRIM) local.code[pc].arg = map[local.code[pc].arg];
    double ls = o->lambda_scale > 0 ? o->lambda_scale : 1.0;
    double lambda = size_term(ls, nv);
    /* By parts of EVOLVE_STATS_POINTS points, each its own cache: the numbers of one
     * cache of every point (gp_tree_stats_add), in memory that does not grow with the
     * cloud. */
    gp_stats acc;
    memset(&acc, 0, sizeof acc);
    for (size_t q0 = 0; q0 < nv || q0 == 0; q0 += EVOLVE_STATS_POINTS) {
        size_t m = nv - q0 < EVOLVE_STATS_POINTS ? nv - q0 : EVOLVE_STATS_POINTS;
        fc = build_cache(o, prims, nprims, used, k, cloud->x, cloud->y, cloud->z, nrm,
                         valid + q0, m, res->eps_d, res->alpha, lambda, 1);
        if (!fc || gp_tree_stats_add(fc, ev, local.code, local.len, &acc)) goto out;
        gp_cache_free(fc);
        fc = NULL;
        if (nv == 0) break;
    }
    res->stats = acc;
    rc = 0;
out:
    tree_free(&local);
    gp_cache_free(fc);
    gp_eval_free(ev);
    frep_free(valid);
    frep_free(nrm);
    frep_free(seen);
    frep_free(used);
    frep_free(map);
    return rc;
}

/* --residual: the evolved tree t (over the primitives; may be empty) joined to the
 * base leaf B = nprims. Candidates B, B | t, B & t, B \ t, each simplified on c (the
 * cache of all leaves on a sample of every point); the fittest that still contains B
 * wins. (B & t is how a missing hole comes back: the GA finds ~cyl on the hole's wall,
 * and the rules turn B & ~cyl into B \ cyl.) */
static int join_base(const evolve_options *o, const gp_tree *t, uint32_t nprims,
                     const gp_cache *c, gp_eval *ev, gp_tree *out, double *fitness)
{
    gp_opset ops = gp_opset_of(o->gp.setops);
    uint8_t opc[4] = { 0, ops.uni, ops.inter, ops.sub };
    gp_tree cand = { NULL, 0, 0 };
    double best = -HUGE_VAL;
    int rc = -1;
    out->len = 0;
    for (int k = 0; k < (t->len ? 4 : 1); k++) {
        cand.len = 0;
        if (tree_push(&cand, FREP_OP_PRIM, nprims)) goto out;
        if (k > 0) {
            if (tree_reserve(&cand, cand.len + t->len + 1)) goto out;
            memcpy(cand.code + cand.len, t->code, t->len * sizeof *t->code);
            cand.len += t->len;
            if (tree_push(&cand, (frep_opcode)opc[k], 0)) goto out;
        }
        double fit;
        if (o->simplify) {
            gp_tree keep = { NULL, 0, 0 };
            if (tree_copy(&keep, &cand)) goto out;
            if (simplify_tree(&cand, o->gp.setops, c, ev, &fit, o->gp.cancel)) {
                tree_free(&keep);
                goto out;
            }
            if (!tree_uses(&cand, nprims)) {
                /* The simplifier dropped the base: keep the join as built. */
                tree_free(&cand);
                cand = keep;
                if (gp_fitness(c, ev, cand.code, cand.len, &fit)) goto out;
            } else {
                tree_free(&keep);
            }
        } else if (gp_fitness(c, ev, cand.code, cand.len, &fit)) {
            goto out;
        }
        if (fit > best) {
            best = fit;
            if (tree_copy(out, &cand)) goto out;
        }
    }
    *fitness = best;
    rc = 0;
out:
    tree_free(&cand);
    return rc;
}

/* ---- the driver: the steps of doc/evolve.md ("Method") as stages over run_ctx ---- */

/* One evolve_run: its inputs, the points and caches the stages build, and the GA's
 * best tree before it becomes res->tree. Stages return 0, or -1 with err set. */
typedef struct run_ctx {
    const evolve_options *o;
    const frep_cloud *cloud;
    const prim *prims;
    size_t nprims;
    gp_progress_fn fn;
    void *user;
    evolve_result *res;
    frep_error *err;
    double t0;               /* frep_now_seconds() when the run started */
    int residual;            /* --residual: o->base_f and o->base_g are set */
    size_t *valid, nv;       /* the valid points (valid_points), cloud indices */
    double *nrm;             /* their unit normals, nrm[3i+c] by cloud index */
    double lo[3], hi[3];     /* their axis-aligned extent */
    size_t *pool, np;        /* the GA's points: the valid ones, or the base's poor ones */
    size_t *samp, m;         /* the scored sample of the pool (samp holds nv entries) */
    size_t *tmp;             /* scratch of draw_sample */
    uint32_t *all;           /* all[j] = j for every leaf j <= nprims */
    double ls;               /* lambda scale: lambda = ls * ln(points) */
    gp_cache *sc;            /* the sample's cache of every primitive; NULL: no GA */
    size_t nfull;            /* every primitive; nprims leaves out the trailing constructed
                                planes until stage_solids */
    gp_eval *ev;
    gp_obb *boxes;           /* proxies, one per primitive */
    gp_result gr;            /* the GA's (or the merge's) best tree */
    int partitioned;         /* part_run partitioned the primitives */
    int grown;               /* gr.best is simplified and grown already */
} run_ctx;

static int run_oom(run_ctx *c)
{
    return frep_error_nomem(c->err);
}

/* Ctrl-C: the steps that only improve the tree are skipped (gp.h). */
static int run_cancelled(const run_ctx *c)
{
    return gp_cancelled(c->o->gp.cancel);
}

/* The inputs refused before any work: no primitives, too many, no normals. */
static int run_check(run_ctx *c)
{
    if (c->nprims == 0 && !c->residual) {
        return frep_error_set(c->err, FREP_EINPUT,
                              "no primitives to combine (segmentation found none; try -p "
                              "or different segment settings)");
    }
    if (c->nprims >= PART_MAX_PRIMS) {
        return frep_error_set(c->err, FREP_ELIMIT, "%zu primitives: at most %u are supported",
                              c->nprims, PART_MAX_PRIMS - 1);
    }
    if (!c->cloud->has_normals) {
        return frep_error_set(c->err, FREP_EINPUT, "the cloud has no normals");
    }
    return 0;
}

/* The arrays sized by the cloud and the leaf list, and the evaluator of the stages. */
static int run_alloc(run_ctx *c)
{
    size_t N = c->cloud->n;
    c->valid = frep_malloc((N ? N : 1) * sizeof *c->valid);
    c->pool = frep_malloc((N ? N : 1) * sizeof *c->pool);
    c->tmp = frep_malloc((N ? N : 1) * sizeof *c->tmp);
    c->nrm = frep_malloc(3 * (N ? N : 1) * sizeof *c->nrm);
    c->all = frep_malloc((c->nprims + 1) * sizeof *c->all);
    c->ev = gp_eval_new();
    if (!c->valid || !c->pool || !c->tmp || !c->nrm || !c->all || !c->ev) return run_oom(c);
    for (uint32_t j = 0; j <= c->nprims; j++) c->all[j] = j;
    return 0;
}

/* Valid points (finite, with a normal), the diagonal, and the tolerances eps_d and
 * alpha (the automatic alpha starts from the default). */
static int stage_points(run_ctx *c)
{
    const evolve_options *o = c->o;
    evolve_result *res = c->res;
    c->nv = valid_points(c->cloud, c->valid, c->nrm, c->lo, c->hi, &res->diag);
    res->npoints = c->nv;
    res->dropped = c->cloud->n - c->nv;
    if (c->nv == 0) {
        return frep_error_set(c->err, FREP_EINPUT,
                              "no point with finite coordinates and a normal");
    }
    if (!(res->diag > 0)) {
        return frep_error_set(c->err, FREP_EINPUT, "all %zu points coincide: nothing to fit",
                              c->nv);
    }
    res->eps_d = (o->eps_rel > 0 ? o->eps_rel : EVOLVE_DEFAULT_EPS_REL) * res->diag;
    res->alpha = (o->alpha_deg > 0 && !(o->alpha_auto && !c->residual)
                      ? o->alpha_deg
                      : EVOLVE_DEFAULT_ALPHA_DEG) *
                 FREP_PI / 180;
    return 0;
}

/* Clipping box: the principal-axes box, or the axis-aligned one when smaller (PCA axes
 * are arbitrary for symmetric shapes such as a cube). */
static void stage_clip_box(run_ctx *c)
{
    evolve_result *res = c->res;
    part_obb_of_points(c->cloud->x, c->cloud->y, c->cloud->z, c->valid, c->nv, &res->obb);
    double va = 1, vo = 1;
    for (int d = 0; d < 3; d++) {
        va *= c->hi[d] - c->lo[d] + 1e-12 * res->diag;
        vo *= 2 * res->obb.h[d] + 1e-12 * res->diag;
    }
    if (va <= vo * (1 + 1e-9)) {
        memset(res->obb.ax, 0, sizeof res->obb.ax);
        for (int d = 0; d < 3; d++) {
            res->obb.ax[d][d] = 1;
            res->obb.c[d] = 0.5 * (c->lo[d] + c->hi[d]);
            res->obb.h[d] = 0.5 * (c->hi[d] - c->lo[d]);
        }
    }
}

/* The GA's pool: every valid point, or with --residual those the base model explains
 * poorly; the sample size m drawn from it. */
static int stage_pool(run_ctx *c)
{
    const evolve_options *o = c->o;
    evolve_result *res = c->res;
    c->np = 0;
    if (c->residual) {
        double ca = cos(res->alpha);
        for (size_t q = 0; q < c->nv; q++)
            if (base_poor(o, c->nrm, c->valid[q], res->eps_d, ca))
                c->pool[c->np++] = c->valid[q];
        res->residual = 1;
        res->nresidual = c->np;
    } else {
        memcpy(c->pool, c->valid, c->nv * sizeof *c->pool);
        c->np = c->nv;
    }
    c->m = o->sample && o->sample < c->np ? o->sample : c->np;
    c->samp = frep_malloc((c->nv ? c->nv : 1) * sizeof *c->samp);
    if (!c->samp) return run_oom(c);
    c->ls = o->lambda_scale > 0 ? o->lambda_scale : 1.0;
    return 0;
}

/* A seeded sample of m of the np points pool (seed: the run's seed ^ salt) into out, and
 * its cache of leaves 0..k-1 with the size term of m points; NULL when out of memory. */
static gp_cache *sample_cache(run_ctx *c, const size_t *pool, size_t np, size_t m,
                              uint64_t salt, uint32_t k, size_t *out)
{
    const evolve_options *o = c->o;
    draw_sample(pool, np, m, o->gp.seed ^ salt, out, c->tmp);
    return build_cache(o, c->prims, c->nprims, c->all, k, c->cloud->x, c->cloud->y,
                       c->cloud->z, c->nrm, out, m, c->res->eps_d, c->res->alpha,
                       size_term(c->ls, m), 0);
}

/* The seeded sample the GA scores, and its cache of every primitive. */
static int stage_sample_cache(run_ctx *c)
{
    c->res->nsample = c->m;
    c->sc = sample_cache(c, c->pool, c->np, c->m, 0x5a5a5a5a5a5a5a5au, (uint32_t)c->nprims,
                         c->samp);
    return c->sc ? 0 : run_oom(c);
}

/* Automatic alpha: 35 degrees when the sample is noisy or faceted against the
 * primitives (evolve.h). With --residual the pool was chosen with alpha_deg already,
 * so it stays. */
static int stage_auto_alpha(run_ctx *c)
{
    evolve_result *res = c->res;
    if (!c->o->alpha_auto || c->residual) return 0;
    if (gp_cache_noise(c->sc, &res->noise)) return run_oom(c);
    res->alpha_auto = 1;
    if (res->noise.sigma_d > EVOLVE_NOISY_SIGMA || res->noise.median_deg > EVOLVE_NOISY_DEG ||
        res->noise.p90_deg > EVOLVE_FACETED_P90_DEG) {
        res->alpha = EVOLVE_NOISY_ALPHA_DEG * FREP_PI / 180;
        if (gp_cache_set_alpha(c->sc, res->alpha)) return run_oom(c);
    }
    return 0;
}

/* The sample points (cloud indices) primitive j explains alone, as itself or as a
 * complement, into idx; their count. */
static size_t proxy_points(const run_ctx *c, uint32_t j, size_t *idx)
{
    const gp_cache *sc = c->sc;
    size_t m = c->m, nk = 0;
    double ca = cos(c->res->alpha);
    for (size_t i = 0; i < m; i++) {
        double f = sc->v[(size_t)j * m + i];
        double g[3] = { sc->g[(3 * (size_t)j) * m + i], sc->g[(3 * (size_t)j + 1) * m + i],
                        sc->g[(3 * (size_t)j + 2) * m + i] };
        double gl = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
        const double *nn = sc->nrm + 3 * i;
        if (fabs(f) < c->res->eps_d && gl > 0 &&
            fabs(g[0] * nn[0] + g[1] * nn[1] + g[2] * nn[2]) / gl > ca)
            idx[nk++] = c->samp[i];
    }
    return nk;
}

/* Proxies of the partitioning: the primitive's own box, else the box of the sample
 * points it explains alone. Primitives explaining no point get none and overlap
 * everything. */
static int stage_proxies(run_ctx *c)
{
    c->boxes = frep_calloc(c->nprims, sizeof *c->boxes);
    size_t *idx = frep_malloc(c->m * sizeof *idx);
    if (!c->boxes || !idx) {
        frep_free(idx);
        return run_oom(c);
    }
    for (uint32_t j = 0; j < c->nprims; j++) {
        const prim *q = &c->prims[j];
        gp_obb *b = &c->boxes[j];
        if (q->has_obb) {
            memcpy(b->c, q->obb_c, sizeof b->c);
            memcpy(b->ax, q->obb_axes, sizeof b->ax);
            memcpy(b->h, q->obb_half, sizeof b->h);
            b->valid = 1;
            continue;
        }
        size_t nk = proxy_points(c, j, idx);
        part_obb_of_points(c->cloud->x, c->cloud->y, c->cloud->z, idx, nk, b);
    }
    frep_free(idx);
    return 0;
}

/* The partitioned GA (partition.c): cliques of overlapping proxies, a tree per clique,
 * the trees merged; it falls back (c->partitioned 0) when partitioning is useless. */
static int stage_partition(run_ctx *c)
{
    size_t m = c->m;
    /* part_run needs the sample's coordinates. */
    double *xs = frep_malloc(m * sizeof *xs), *ys = frep_malloc(m * sizeof *ys);
    double *zs = frep_malloc(m * sizeof *zs);
    if (!xs || !ys || !zs) {
        frep_free(xs);
        frep_free(ys);
        frep_free(zs);
        return run_oom(c);
    }
    for (size_t i = 0; i < m; i++) {
        xs[i] = c->cloud->x[c->samp[i]];
        ys[i] = c->cloud->y[c->samp[i]];
        zs[i] = c->cloud->z[c->samp[i]];
    }
    int pr = part_run(&c->o->gp, c->sc, xs, ys, zs, c->boxes,
                      EVOLVE_PROXY_MARGIN * c->res->eps_d, c->fn, c->user, &c->gr,
                      &c->res->part);
    frep_free(xs);
    frep_free(ys);
    frep_free(zs);
    if (pr) return run_oom(c);
    c->partitioned = c->res->part.partitioned;
    c->res->partitioned = c->partitioned;
    return 0;
}

/* The merged tree grown as the final tree is (stage_simplify): pieces the merge lost
 * (a pocket whose clique trees disagreed) come back here, before the polish, which
 * then starts from them. */
static int stage_grow_merged(run_ctx *c)
{
    const evolve_options *o = c->o;
    gp_result *gr = &c->gr;
    if (!c->partitioned || !o->simplify || !gr->best.len || run_cancelled(c)) return 0;
    if (simplify_grow_pieces(&gr->best, o->gp.setops, c->sc, c->ev, &gr->fitness, o->gp.cancel))
        return run_oom(c);
    c->grown = 1;
    if (c->fn) {
        gp_progress gpr = { gr->generations, gr->fitness, gr->best.len, frep_now_seconds() - c->t0,
                            GP_PHASE_GROWN, 0, 0 };
        if (o->gp.report_explained && gp_progress_explained(c->sc, c->ev, &gr->best, &gpr))
            return run_oom(c);
        c->fn(c->user, &gpr);
    }
    return 0;
}

/* ---- The union of closed solids, less cuts (stage_solids) ------------------------ */

/* Most candidate solids of the union seed (a sphere, a capped cylinder or a closed slab
 * each), most caps they use (a plane and its side) and most directions across a slab;
 * a pool with more offers the first ones. */
#define EVOLVE_SOLIDS_MAX 64
#define EVOLVE_SOLIDS_CAPS 64
#define EVOLVE_SOLIDS_DIRS 8
/* Planes across an axis or a slab: within this angle of perpendicular or parallel. */
#define EVOLVE_SOLIDS_DEG 2.0
/* A cap closes an end of a solid's inliers when it is the plane nearest that end and
 * within this share of the inliers' length (plus EVOLVE_SOLIDS_CAP_EPS eps_d, plus the
 * radius for a cylinder, whose inliers run on into a sphere or a rail it meets). */
#define EVOLVE_SOLIDS_CAP_REACH 0.25
#define EVOLVE_SOLIDS_CAP_EPS 4.0

/* A candidate solid: one or two fitted primitives (a slab's two faces) intersected with
 * the caps of the bits of caps (bit k: cap[k] of the solids list, its complement when
 * neg[k]). */
typedef struct solid {
    uint32_t core[2];
    int ncore;
    uint64_t caps;
} solid;

typedef struct solids {
    solid s[EVOLVE_SOLIDS_MAX];
    int n;
    uint32_t cap[EVOLVE_SOLIDS_CAPS];
    uint8_t neg[EVOLVE_SOLIDS_CAPS];
    int ncap;
} solids;

static int popcount64(uint64_t m)
{
    int k = 0;
    for (; m; m &= m - 1) k++;
    return k;
}

/* Planes that may cap a solid: the fitted planes and the constructed ones. */
static int is_cap_plane(const prim *q)
{
    return q->type == PRIM_PLANE && (!q->separating || q->constructed);
}

/* The bit of cap (j, neg), added to the list when new; -1 when the list is full. */
static int cap_bit(solids *S, uint32_t j, int neg)
{
    for (int k = 0; k < S->ncap; k++)
        if (S->cap[k] == j && S->neg[k] == neg) return k;
    if (S->ncap == EVOLVE_SOLIDS_CAPS) return -1;
    S->cap[S->ncap] = j;
    S->neg[S->ncap] = (uint8_t)neg;
    return S->ncap++;
}

/* The cap of the end t_end (side: +1 the far end along u, -1 the near one) of a solid
 * whose inliers centre on c: the plane across u nearest that end, beyond c, within
 * reach; as a bit of S (the plane's side that holds c), or -1 when none. */
static int end_cap(solids *S, const prim *pr, size_t np, const double u[3], const double c[3],
                   double t_end, int side, double reach)
{
    double cn = cos(EVOLVE_SOLIDS_DEG * FREP_PI / 180.0), tc = vec3_dot(c, u);
    double best = reach;
    int pick = -1;
    for (size_t j = 0; j < np; j++) {
        const prim *q = &pr[j];
        double nu = vec3_dot(q->p, u);
        if (!is_cap_plane(q) || fabs(nu) < cn) continue;
        double t = tc + (q->r - vec3_dot(q->p, c)) / nu;  /* where u's line through c meets q */
        if (side * (t - tc) <= 0 || fabs(t - t_end) > best) continue;
        best = fabs(t - t_end);
        pick = (int)j;
    }
    if (pick < 0) return -1;
    return cap_bit(S, (uint32_t)pick, pr[pick].r - vec3_dot(pr[pick].p, c) < 0);
}

/* Both caps of the extent [lo, hi] along u, as bits; 0 when an end has none. */
static uint64_t both_caps(solids *S, const prim *pr, size_t np, const double u[3],
                          const double c[3], double lo, double hi, double reach)
{
    int a = end_cap(S, pr, np, u, c, lo, -1, reach), b = end_cap(S, pr, np, u, c, hi, 1, reach);
    return a < 0 || b < 0 ? 0 : 1ull << a | 1ull << b;
}

/* The extent [*lo, *hi] along v of the points on the faces (planes) f[0..nf): within
 * eps of one, its normal within alpha of the face's. */
static void faces_extent(const run_ctx *c, const prim *const *f, int nf, const double v[3],
                         double *lo, double *hi)
{
    const frep_cloud *cl = c->cloud;
    double eps = c->res->eps_d, ca = cos(c->res->alpha);
    *lo = HUGE_VAL;
    *hi = -HUGE_VAL;
    for (size_t k = 0; k < c->nv; k++) {
        size_t i = c->valid[k];
        double x[3] = { cl->x[i], cl->y[i], cl->z[i] };
        for (int m = 0; m < nf; m++) {
            if (fabs(vec3_dot(f[m]->p, x) - f[m]->r) > eps || vec3_dot(f[m]->p, c->nrm + 3 * i) < ca)
                continue;
            double t = vec3_dot(v, x);
            *lo = fmin(*lo, t);
            *hi = fmax(*hi, t);
        }
    }
}

/* A slab's caps: along every direction across its faces' normal that a cap plane
 * gives, the caps of both ends of the faces' points; 0 unless two directions close. */
static uint64_t slab_caps(solids *S, const run_ctx *c, const prim *A, const prim *B)
{
    const prim *pr = c->prims;
    double sn = sin(EVOLVE_SOLIDS_DEG * FREP_PI / 180.0), cn = cos(EVOLVE_SOLIDS_DEG * FREP_PI / 180.0);
    double dirs[EVOLVE_SOLIDS_DIRS][3];
    int nd = 0;
    for (size_t j = 0; j < c->nprims && nd < EVOLVE_SOLIDS_DIRS; j++) {
        const prim *q = &pr[j];
        if (!is_cap_plane(q) || fabs(vec3_dot(q->p, A->p)) > sn) continue;
        int d = 0;
        while (d < nd && fabs(vec3_dot(dirs[d], q->p)) < cn) d++;
        if (d == nd) memcpy(dirs[nd++], q->p, sizeof dirs[0]);
    }
    const prim *faces[2] = { A, B };
    uint64_t m = 0;
    int closed = 0;
    for (int d = 0; d < nd; d++) {
        double lo, hi;
        faces_extent(c, faces, 2, dirs[d], &lo, &hi);
        if (!(lo < hi)) continue;
        double mid = 0.5 * (lo + hi), cc[3];
        /* the centre: on the faces' mid-plane, at the middle of the extent along d */
        double t0 = vec3_dot(A->obb_c, dirs[d]);
        for (int k = 0; k < 3; k++) cc[k] = A->obb_c[k] + (mid - t0) * dirs[d][k];
        double reach = EVOLVE_SOLIDS_CAP_REACH * (hi - lo) + EVOLVE_SOLIDS_CAP_EPS * c->res->eps_d;
        uint64_t b = both_caps(S, pr, c->nprims, dirs[d], cc, lo, hi, reach);
        if (b) closed++;
        m |= b;
    }
    return closed >= 2 ? m : 0;
}

/* The candidates: every fitted sphere, every fitted cylinder closed at both ends of its
 * inliers, every slab of two opposite fitted planes closed in two directions across
 * it (by fitted or constructed planes, either side). */
static void solid_candidates(const run_ctx *c, solids *S)
{
    const prim *pr = c->prims;
    size_t np = c->nprims;
    double cn = cos(EVOLVE_SOLIDS_DEG * FREP_PI / 180.0);
    S->n = S->ncap = 0;
    for (size_t i = 0; i < np && S->n < EVOLVE_SOLIDS_MAX; i++) {
        const prim *q = &pr[i];
        if (q->separating || !q->has_obb) continue;
        solid *o = &S->s[S->n];
        o->core[0] = (uint32_t)i;
        o->ncore = 1;
        o->caps = 0;
        if (q->type == PRIM_SPHERE) {
            S->n++;
        } else if (q->type == PRIM_CYLINDER) {
            double h = prim_axial_half(q), tc = vec3_dot(q->obb_c, q->a);
            double reach = EVOLVE_SOLIDS_CAP_REACH * 2 * h + q->r +
                           EVOLVE_SOLIDS_CAP_EPS * c->res->eps_d;
            o->caps = both_caps(S, pr, np, q->a, q->obb_c, tc - h, tc + h, reach);
            S->n += o->caps != 0;
        } else if (q->type == PRIM_PLANE) {
            for (size_t j = i + 1; j < np; j++) {
                const prim *b = &pr[j];
                if (b->type != PRIM_PLANE || b->separating || vec3_dot(q->p, b->p) > -cn)
                    continue;
                o->core[1] = (uint32_t)j;
                o->ncore = 2;
                o->caps = slab_caps(S, c, q, b);
                S->n += o->caps != 0;
                break;
            }
        }
    }
}

/* Primitive j into *t, intersected with (neg: subtracted from) what is on the stack
 * unless first. */
static int push_and(gp_tree *t, uint32_t j, int neg, int first, gp_opset op)
{
    return tree_push(t, FREP_OP_PRIM, j) ||
           (!first && tree_push(t, (frep_opcode)(neg ? op.sub : op.inter), 0));
}

/* A cut: fitted primitive prim whole (solid < 0), or candidate solid `solid` with the
 * caps of the bits of caps only (a hole open where it runs on into other cuts). */
typedef struct solid_cut {
    int solid;
    uint32_t prim;
    uint64_t caps;
} solid_cut;

/* The union of the solids with use[k] into *t, each cap set written once, less the
 * cuts cut[0..ncut): solids are grouped by their caps, a solid whose caps hold a
 * group's joins it with the rest of its caps inside, `((slab & y1 & y2) | rail_1 |
 * rail_2) & x1 & x2`. */
static int solid_union(const solids *S, const uint8_t *use, const solid_cut *cut, int ncut,
                       gp_opset op, gp_tree *t)
{
    uint64_t group[EVOLVE_SOLIDS_MAX];
    int ng = 0, in[EVOLVE_SOLIDS_MAX];
    t->len = 0;
    /* Groups: the distinct cap sets, smallest first (a solid joins the first that fits). */
    for (int pass = 0; pass <= EVOLVE_SOLIDS_CAPS; pass++)
        for (int k = 0; k < S->n; k++) {
            if (!use[k] || popcount64(S->s[k].caps) != pass) continue;
            int g = 0;
            while (g < ng && ((S->s[k].caps & group[g]) != group[g] ||
                              (!group[g] && S->s[k].caps)))
                g++;
            if (g == ng) group[ng++] = S->s[k].caps;
            in[k] = g;
        }
    int terms = 0;
    for (int g = 0; g < ng; g++) {
        int members = 0;
        for (int k = 0; k < S->n; k++) {
            if (!use[k] || in[k] != g) continue;
            const solid *o = &S->s[k];
            int first = 1;
            for (int c = 0; c < o->ncore; c++, first = 0)
                if (push_and(t, o->core[c], 0, first, op)) return -1;
            for (int c = 0; c < S->ncap; c++)
                if ((o->caps & ~group[g]) >> c & 1 && push_and(t, S->cap[c], S->neg[c], 0, op))
                    return -1;
            if (members++ && tree_push(t, (frep_opcode)op.uni, 0)) return -1;
        }
        for (int c = 0; c < S->ncap; c++)
            if (group[g] >> c & 1 && push_and(t, S->cap[c], S->neg[c], 0, op)) return -1;
        if (terms++ && tree_push(t, (frep_opcode)op.uni, 0)) return -1;
    }
    for (int k = 0; k < ncut && terms; k++) {
        if (cut[k].solid < 0) {
            if (push_and(t, cut[k].prim, 1, 0, op)) return -1;
            continue;
        }
        const solid *o = &S->s[cut[k].solid];
        for (int c = 0; c < o->ncore; c++)
            if (push_and(t, o->core[c], 0, c == 0, op)) return -1;
        for (int c = 0; c < S->ncap; c++)
            if (cut[k].caps >> c & 1 && push_and(t, S->cap[c], S->neg[c], 0, op)) return -1;
        if (tree_push(t, (frep_opcode)op.sub, 0)) return -1;
    }
    return 0;
}

/* Most cuts subtracted from the union of solids: a candidate solid (a capped bore, a
 * hole with a floor: the cylinder less its floor's plane) or a fitted curved primitive
 * whole (a bore through everything). */
#define EVOLVE_SOLIDS_CUTS 16

/* The k-th cut that may cut the union into *out, k from 0 on: every fitted curved
 * primitive whole, every candidate solid not in the union with all its caps and, for a
 * capped cylinder, with each cap alone.  0 past the last; 1 when *out holds a cut, -1
 * when k names none to try (a core of a solid in the union, a cut already). */
static int nth_cut(const solids *S, const uint8_t *use, const prim *pr, size_t np,
                   const solid_cut *cut, int ncut, size_t k, solid_cut *out)
{
    if (k < np) {
        out->solid = -1;
        out->prim = (uint32_t)k;
        out->caps = 0;
        if (pr[k].type == PRIM_PLANE || pr[k].separating) return -1;
        for (int m = 0; m < S->n; m++)
            if (use[m] && (S->s[m].core[0] == k || (S->s[m].ncore > 1 && S->s[m].core[1] == k)))
                return -1;
    } else {
        k -= np;
        if (k >= 3 * (size_t)S->n) return 0;
        const solid *o = &S->s[k / 3];
        out->solid = (int)(k / 3);
        out->prim = 0;
        out->caps = o->caps;
        if (use[k / 3]) return -1;
        if (k % 3) {  /* one cap of a cylinder's two */
            if (o->ncore != 1 || pr[o->core[0]].type != PRIM_CYLINDER || popcount64(o->caps) != 2)
                return -1;
            uint64_t low = o->caps & (~o->caps + 1);
            out->caps = k % 3 == 1 ? low : o->caps & ~low;
        }
    }
    for (int m = 0; m < ncut; m++)
        if (cut[m].solid == out->solid && cut[m].prim == out->prim && cut[m].caps == out->caps)
            return -1;
    return 1;
}

/* Greedily, the union of candidate solids whose fitness on sc is highest, less the
 * cuts that raise it: each round adds the solid (then the cut) that raises it most,
 * until none does.  Into *u and *fitness (u empty when there is no candidate). */
static int solids_seed(run_ctx *c, const gp_cache *sc, gp_tree *u, double *fitness)
{
    u->len = 0;
    solids *S = frep_malloc(sizeof *S);
    if (!S) return -1;
    solid_candidates(c, S);
    gp_opset op = gp_opset_of(c->o->gp.setops);
    uint8_t use[EVOLVE_SOLIDS_MAX] = { 0 };
    solid_cut cut[EVOLVE_SOLIDS_CUTS];
    int ncut = 0;
    gp_tree t = { NULL, 0, 0 };
    double best = -HUGE_VAL;
    int rc = 0;
    for (int round = 0; round < S->n && !rc; round++) {
        int pick = -1;
        double f;
        for (int k = 0; k < S->n && !rc; k++) {
            if (use[k]) continue;
            use[k] = 1;
            rc = solid_union(S, use, NULL, 0, op, &t) || gp_fitness(sc, c->ev, t.code, t.len, &f);
            use[k] = 0;
            if (!rc && f > best) {
                best = f;
                pick = k;
            }
        }
        if (pick < 0) break;
        use[pick] = 1;
    }
    while (best > -HUGE_VAL && ncut < EVOLVE_SOLIDS_CUTS && !rc) {
        solid_cut pick;
        int found = 0, more;
        double f;
        for (size_t k = 0; !rc && (more = nth_cut(S, use, c->prims, c->nprims, cut, ncut, k,
                                                  &cut[ncut])) != 0; k++) {
            if (more < 0) continue;
            rc = solid_union(S, use, cut, ncut + 1, op, &t) ||
                 gp_fitness(sc, c->ev, t.code, t.len, &f);
            if (!rc && f > best) {
                best = f;
                pick = cut[ncut];
                found = 1;
            }
        }
        if (!found) break;
        cut[ncut++] = pick;
    }
    if (!rc && best > -HUGE_VAL) rc = solid_union(S, use, cut, ncut, op, u);
    *fitness = best;
    tree_free(&t);
    frep_free(S);
    return rc ? -1 : 0;
}

/* Polish: a GA over all primitives seeded with the merged tree. The merge is greedy
 * and the clique trees see only their points; the seeded GA repairs what that misses
 * (a part a clique got wrong, a subtraction the merge placed too low) and never does
 * worse, since the seed is kept by elitism. Its depth limit leaves room to grow the
 * seed. */
static int stage_polish(run_ctx *c)
{
    const evolve_options *o = c->o;
    gp_result *gr = &c->gr;
    if (!c->partitioned || !o->polish || !gr->best.len || run_cancelled(c)) return 0;
    gp_config pc = o->gp;
    int dd = tree_depth(gr->best.code, gr->best.len) + GP_DEPTH_SLACK;
    int d0 = pc.max_depth > 0 ? pc.max_depth : gp_default_depth((uint32_t)c->nprims);
    pc.max_depth = dd > d0 ? dd : d0;
    if (o->polish_stagnation && (pc.stagnation == 0 || o->polish_stagnation < pc.stagnation))
        pc.stagnation = o->polish_stagnation;
    if (pc.max_time > 0) pc.max_time = fmax(pc.max_time - (frep_now_seconds() - c->t0), 1e-3);
    gp_result pg;
    memset(&pg, 0, sizeof pg);
    if (gp_run(&pc, c->sc, &gr->best, 1, c->fn, c->user, &pg)) {
        tree_free(&pg.best);
        return run_oom(c);
    }
    c->res->part.polish_generations = pg.generations;
    if (pg.best.len && pg.fitness > gr->fitness) {
        tree_free(&gr->best);
        gr->best = pg.best;
        gr->fitness = pg.fitness;
        c->grown = 0;  /* a new tree: simplified and grown again */
    } else {
        tree_free(&pg.best);
    }
    gr->generations += pg.generations;
    return 0;
}

/* The cache of the GA's sample over every primitive, the constructed planes too. */
static gp_cache *every_leaf_cache(run_ctx *c)
{
    return build_cache(c->o, c->prims, c->nprims, c->all, (uint32_t)c->nprims, c->cloud->x,
                       c->cloud->y, c->cloud->z, c->nrm, c->samp, c->m, c->res->eps_d,
                       c->res->alpha, size_term(c->ls, c->m), 0);
}

/* The constructed planes (segment_add_constructed, segment_close_slabs) stay out of
 * the GA: they explain no point, and in the pool they only change the GA's draws.
 * Here, after the GA, they come in: the union of the solids they and the fitted planes
 * close, less its cuts (solids_seed), replaces the GA's tree when it is fitter, scored
 * on the same sample with every primitive (a frame of rails joined by corner spheres:
 * the rails' caps lie on the other rails' axes, hidden, and the GA bounds them by
 * separating planes, mitres at the corners). */
static int stage_solids(run_ctx *c)
{
    size_t nga = c->nprims;
    c->nprims = c->nfull;
    if (nga == c->nfull || !c->gr.best.len || run_cancelled(c)) return 0;
    double lambda = size_term(c->ls, c->m);
    gp_cache *all = every_leaf_cache(c);
    if (!all) return run_oom(c);
    gp_tree u = { NULL, 0, 0 };
    double f = 0;
    if (solids_seed(c, all, &u, &f)) {
        tree_free(&u);
        gp_cache_free(all);
        return run_oom(c);
    }
    /* The union is the design's own form, a solid per feature: it replaces the GA's
     * tree when it explains the points as well (its score, the fitness before the size
     * term, at least the tree's).  Its caps, written once per group, can make it a few
     * nodes longer than a tree of half-spaces that explains as much: on base at 0.5%
     * noise the union of 9 solids, 31 nodes, scores 7 more than the GA's 14 solids in 27
     * nodes (chamfers for the corner spheres) but loses 33 to the size term. */
    if (u.len && f + lambda * (double)u.len >= c->gr.fitness + lambda * (double)c->gr.best.len) {
        gp_cache_free(c->sc);
        c->sc = all;
        tree_free(&c->gr.best);
        c->gr.best = u;
        c->gr.fitness = f;
        c->grown = 0;  /* a new tree: simplified and grown */
    } else {
        tree_free(&u);
        gp_cache_free(all);
    }
    return 0;
}

/* The GA over all primitives (gp.c), when the run is not partitioned. */
static int stage_ga(run_ctx *c)
{
    tree_free(&c->gr.best);
    if (gp_run(&c->o->gp, c->sc, NULL, 0, c->fn, c->user, &c->gr)) return run_oom(c);
    return 0;
}

/* The GA's tree becomes the result, simplified and then grown by pieces of two or
 * three primitives at the root (a subtracted pocket, an added block) that neither the
 * GA nor the one-primitive hill climb found; only on the final tree, since one pass
 * tries every pair of primitives. */
static int stage_simplify(run_ctx *c)
{
    const evolve_options *o = c->o;
    evolve_result *res = c->res;
    if (!c->gr.best.len && !c->residual) {
        return frep_error_set(c->err, FREP_ECANCEL, "the run stopped before any tree was scored");
    }
    res->generations = c->gr.generations;
    res->stop = c->gr.stop;
    res->fitness = c->gr.fitness;
    if (tree_copy(&res->tree, &c->gr.best)) return run_oom(c);
    if (!o->simplify || !res->tree.len || c->grown || run_cancelled(c)) return 0;
    if (c->fn) {  /* a stop request raises the flag the simplification polls */
        gp_progress gpr = { res->generations, res->fitness, res->tree.len,
                            frep_now_seconds() - c->t0, GP_PHASE_SIMPLIFY, 0, 0 };
        c->fn(c->user, &gpr);
    }
    if (simplify_tree(&res->tree, o->gp.setops, c->sc, c->ev, &res->fitness, o->gp.cancel) ||
        simplify_grow_pieces(&res->tree, o->gp.setops, c->sc, c->ev, &res->fitness,
                             o->gp.cancel))
        return run_oom(c);
    return 0;
}

/* The final growth (stage_grow_final) scores trees on this many times the GA's sample
 * (16,384 points by default), at most EVOLVE_FINAL_CELLS points times primitives (40
 * bytes each: 160 MB). */
#define EVOLVE_FINAL_SAMPLE_FACTOR 4
#define EVOLVE_FINAL_CELLS ((size_t)4 << 20)

/* The inner growth again (one primitive joined inside the tree, simplify_grow_inner),
 * on a sample EVOLVE_FINAL_SAMPLE_FACTOR times the GA's.  A face holding 0.5% of the
 * points has some 20 of the GA's 4,096, of which fewer than lambda = ln 4,096 = 8.3 may
 * lie where the tree misses them, too few for the growth to try it: on three_cuboids
 * (clean) the box cut into the cube's corner was left bounded by its three near faces
 * only, and took material the part keeps (Hausdorff 7%).  On four times the points the
 * evidence is four times larger and lambda grows by ln 4.  Every primitive may join
 * here, the constructed planes too: a narrow face segmentation missed has a separating
 * plane in its place, which the growth takes only where points the tree misses lie on
 * it (six_cuboids at 0.5% noise: the thin slab's top face of 0.65 by 5.2, left out, let
 * the slab run 1.2 beyond it; Hausdorff 10%). */
static int stage_grow_final(run_ctx *c)
{
    const evolve_options *o = c->o;
    evolve_result *res = c->res;
    if (!o->simplify || c->residual || !res->tree.len || run_cancelled(c)) return 0;
    uint32_t k = (uint32_t)c->nprims;  /* every leaf (stage_solids counted them all in) */
    size_t mf = EVOLVE_FINAL_SAMPLE_FACTOR * c->m, cap = EVOLVE_FINAL_CELLS / (k ? k : 1);
    if (mf > c->np) mf = c->np;
    if (mf > cap) mf = cap;
    if (mf <= c->m) return 0;
    size_t *fs = frep_malloc(mf * sizeof *fs);
    if (!fs) return run_oom(c);
    gp_cache *fc = sample_cache(c, c->pool, c->np, mf, 0x3c3c3c3c3c3c3c3cu, k, fs);
    frep_free(fs);
    if (!fc) return run_oom(c);
    uint8_t *fitted = frep_malloc(k ? k : 1);
    for (uint32_t j = 0; fitted && j < k; j++)
        fitted[j] = !c->prims[j].separating && !c->prims[j].constructed;
    int rc = !fitted ||
             simplify_grow_inner(&res->tree, o->gp.setops, fc, c->ev, NULL, o->gp.cancel) ||
             simplify_grow_pockets(&res->tree, o->gp.setops, fc, c->ev, NULL, o->gp.cancel) ||
             simplify_swap_leaves(&res->tree, o->gp.setops, fc, c->ev, fitted, NULL,
                                  o->gp.cancel);
    frep_free(fitted);
    gp_cache_free(fc);
    if (rc) return run_oom(c);
    /* A constructed plane joined: the GA's sample is scored over every leaf from now. */
    int joined = 0;
    for (uint32_t j = c->sc->nprims; j < k && !joined; j++) joined = tree_uses(&res->tree, j);
    if (joined) {
        gp_cache *all = every_leaf_cache(c);
        if (!all) return run_oom(c);
        gp_cache_free(c->sc);
        c->sc = all;
    }
    /* The reported fitness stays on the GA's sample. */
    return gp_fitness(c->sc, c->ev, res->tree.code, res->tree.len, &res->fitness) ? run_oom(c)
                                                                                   : 0;
}

/* Material no point supports, trimmed; not with --residual, whose base model is a leaf
 * known at the cloud's points only. */
static int stage_support(run_ctx *c)
{
    const evolve_options *o = c->o;
    if (!o->simplify || !o->support || c->residual || !c->sc || !c->res->tree.len ||
        run_cancelled(c))
        return 0;
    if (support_run(o, c->cloud, c->prims, c->nprims, c->valid, c->nv, c->sc, c->ev, c->res))
        return run_oom(c);
    return 0;
}

/* --residual: the tree joined to the base model (leaf nprims), on a sample of every
 * point. */
static int stage_join(run_ctx *c)
{
    const evolve_options *o = c->o;
    evolve_result *res = c->res;
    if (!c->residual) return 0;
    size_t mj = o->sample && o->sample < c->nv ? o->sample : c->nv;
    gp_cache *jc = sample_cache(c, c->valid, c->nv, mj, 0xa5a5a5a5a5a5a5a5u,
                                (uint32_t)c->nprims + 1, c->samp);
    if (!jc) return run_oom(c);
    gp_tree joined = { NULL, 0, 0 };
    int bad = join_base(o, &res->tree, (uint32_t)c->nprims, jc, c->ev, &joined, &res->fitness);
    gp_cache_free(jc);
    if (bad) {
        tree_free(&joined);
        return run_oom(c);
    }
    tree_free(&res->tree);
    res->tree = joined;
    res->nsample = mj;
    return 0;
}

/* The @box extent: the grown oriented box's axis-aligned hull. */
static void stage_box_extent(evolve_result *res)
{
    double mg = EVOLVE_CLIP_MARGIN * res->diag;
    for (int d = 0; d < 3; d++) {
        double r = 0;
        for (int a = 0; a < 3; a++) r += (res->obb.h[a] + 2 * mg) * fabs(res->obb.ax[a][d]);
        res->box[d] = res->obb.c[d] - r;
        res->box[d + 3] = res->obb.c[d] + r;
    }
}

/* The pipeline of doc/evolve.md: points and tolerances, clipping box, sample and its
 * cache, alpha, proxies, partitioned GA (merge, growth, polish) or plain GA,
 * simplification and growth, support trims, the --residual join, statistics on every
 * point. */
static int run_stages(run_ctx *c)
{
    const evolve_options *o = c->o;
    if (run_alloc(c) || stage_points(c)) return -1;
    /* The GA's primitives: all but the constructed planes at the end (stage_solids). */
    c->nfull = c->nprims;
    while (!c->residual && c->nprims > 0 && c->prims[c->nprims - 1].constructed) c->nprims--;
    stage_clip_box(c);
    if (stage_pool(c)) return -1;
    /* With --residual and fewer residual points than a tree could use, or no
     * primitive, there is nothing to evolve: the result is the base model. */
    if (c->nprims > 0 && c->m > 0) {
        if (stage_sample_cache(c) || stage_auto_alpha(c) || stage_proxies(c)) return -1;
        /* After Ctrl-C the partitioned GA would stop at once, but only after assigning
         * every sample point to its cliques: the plain GA gives the tree sooner. */
        if (o->partition && c->nprims > 1 && !run_cancelled(c) &&
            (stage_partition(c) || stage_grow_merged(c) || stage_polish(c)))
            return -1;
        if (!c->partitioned && stage_ga(c)) return -1;
        if (stage_solids(c) || stage_simplify(c) || stage_grow_final(c)) return -1;
    }
    if (stage_support(c) || stage_join(c)) return -1;
    /* Statistics on every valid point, over the leaves of the tree only. */
    if (evolve_stats(o, c->cloud, c->prims, c->nprims, c->res)) return run_oom(c);
    stage_box_extent(c->res);
    c->res->seconds = frep_now_seconds() - c->t0;
    return 0;
}

int evolve_run(const evolve_options *o, const frep_cloud *cloud, const prim *prims,
               size_t nprims, gp_progress_fn fn, void *user, evolve_result *res,
               frep_error *err)
{
    memset(res, 0, sizeof *res);
    run_ctx c;
    memset(&c, 0, sizeof c);
    c.o = o;
    c.cloud = cloud;
    c.prims = prims;
    c.nprims = nprims;
    c.fn = fn;
    c.user = user;
    c.res = res;
    c.err = err;
    c.t0 = frep_now_seconds();
    c.residual = o->base_f != NULL;
    if (run_check(&c)) return -1;
    int rc = run_stages(&c);
    if (rc) tree_free(&res->tree);
    tree_free(&c.gr.best);
    frep_free(c.valid);
    frep_free(c.pool);
    frep_free(c.tmp);
    frep_free(c.nrm);
    frep_free(c.samp);
    frep_free(c.all);
    frep_free(c.boxes);
    gp_cache_free(c.sc);
    gp_eval_free(c.ev);
    return rc;
}

/* ---- output ------------------------------------------------------------------------ */

static double pct(size_t a, size_t b) { return b ? 100.0 * (double)a / (double)b : 0.0; }

/* The header comments: the run, its figures, the notes; the @setops and @box pragmas. */
static void write_header(FILE *f, const evolve_result *r, uint32_t k,
                         const evolve_meta *m, const char *so)
{
    const gp_tree *t = &r->tree;
    fprintf(f, "-- Construction tree discovered by frep evolve from %s\n",
            m->cloud ? m->cloud : "a point cloud");
    if (m->command) fprintf(f, "-- command: %s\n", m->command);
    fprintf(f, "-- seed %llu, set operations %s, %s", (unsigned long long)m->seed, so,
            r->partitioned ? "partitioned" : "not partitioned");
    if (r->partitioned)
        fprintf(f, " (%u cliques, largest %u; %u generations polishing)", r->part.ncliques,
                r->part.largest, r->part.polish_generations);
    fprintf(f, ", %u generations, %.2f s\n", r->generations, r->seconds);
    fprintf(f, "-- fitness %.6g on %zu scored points; tree size %u nodes, %u primitives\n",
            r->fitness, r->nsample, t->len, k);
    fprintf(f, "-- %.2f%% of %zu points within epsilon %.6g of the surface, %.2f%% with "
               "normals within %.3g degrees, %.2f%% both\n",
            pct(r->stats.within_eps, r->npoints), r->npoints, r->eps_d,
            pct(r->stats.normals_ok, r->npoints), r->alpha * 180 / FREP_PI,
            pct(r->stats.explained, r->npoints));
    if (m->base)
        fprintf(f, "-- residual of model '%s': it explained %.2f%% of the points; the tree was "
                   "evolved on the %zu it explained poorly and joined to it (base_part)\n",
                m->base->name, pct(r->npoints - r->nresidual, r->npoints), r->nresidual);
    if (r->support.trims)
        fprintf(f, "-- %u trim%s of material no point supports (unsupported grid edges %zu -> "
                   "%zu; --no-support keeps it)\n",
                r->support.trims, r->support.trims == 1 ? "" : "s", r->support.before,
                r->support.after);
    if (m->refit_note) fprintf(f, "-- %s\n", m->refit_note);
    if (m->hyperfun)
        fprintf(f, "-- pure HyperFun (--hyperfun): every primitive is arithmetic of x; the "
                   "reference tools read\n-- | & \\ as R-functions, which give the same solid\n");
    else
        fprintf(f, "-- frep-only: the general-position primitives fr*() (doc/library.md); "
                   "`frep evolve --hyperfun`\n-- writes pure HyperFun, `frep export` "
                   "OpenSCAD source\n");
    fprintf(f, "-- @setops %s\n", so);
    fprintf(f, "-- @box %.9g %.9g %.9g %.9g %.9g %.9g\n\n", r->box[0], r->box[1], r->box[2],
            r->box[3], r->box[4], r->box[5]);
}

/* The --residual model's source, then the model's header. */
static void write_model_head(FILE *f, const evolve_base *base, const char *mname)
{
    if (!base) {
        fprintf(f, "%s(x[3], a[1])\n{\n", mname);
        return;
    }
    fprintf(f, "-- ---- the model given with --residual (its annotations disarmed) ----\n");
    fputs(base->text, f);
    size_t bl = strlen(base->text);
    if (bl && base->text[bl - 1] != '\n') fputc('\n', f);
    fprintf(f, "-- ---- end of the model given with --residual ----\n\n");
    fprintf(f, "%s(%s)\n{\n", mname, base->header);
}

/* The six planes of the grown oriented box and the clipped model, or the tree alone
 * when it is bounded. */
static void write_clip(FILE *f, const evolve_result *r, const char *mname, int bounded,
                       int hyperfun)
{
    if (bounded) {
        fprintf(f, "    %s = tree;  -- bounded: no clipping box\n}\n", mname);
        return;
    }
    fprintf(f, "    -- The tree is not bounded (or bounded beyond 2 diagonals): it is clipped by the\n"
               "    -- cloud's oriented box grown by %g of the diagonal. An edit that enlarges the\n"
               "    -- part must grow the offsets (the last number) of these planes too.\n",
            EVOLVE_CLIP_MARGIN);
    double mg = EVOLVE_CLIP_MARGIN * r->diag;
    static const char *const side[3][2] = { { "max", "min" }, { "max", "min" }, { "max", "min" } };
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
            fprintf(f, "    clip_%d_%s = ", a + 1, side[a][s]);
            if (hyperfun) {
                canon_prim cp;
                memset(&cp, 0, sizeof cp);
                cp.q = q;
                cp.qpos = PRIM_POS_QUANTUM * r->diag;
                cp.qdir = PRIM_DIR_QUANTUM;
                canon_write_hyperfun(f, &cp);
            } else {
                prim_write_call_scaled(f, &q, r->diag);
            }
            fprintf(f, ";\n");
        }
    fprintf(f, "    clip = clip_1_max & clip_1_min & clip_2_max & clip_2_min & clip_3_max & "
               "clip_3_min;\n");
    fprintf(f, "    %s = tree & clip;\n}\n", mname);
}

int evolve_write_model(FILE *f, const evolve_result *r, const prim *prims, size_t nprims,
                       const evolve_meta *m)
{
    canon_prim *c = frep_calloc(nprims + 1, sizeof *c);
    prim *cq = frep_calloc(nprims + 1, sizeof *cq);
    int rc = -1;
    if (!c || !cq || canon_prims(r, prims, nprims, m->points, m->exact, m->cancel, c))
        goto done;
    uint32_t k = 0;
    for (size_t j = 0; j < nprims; j++) {
        cq[j] = c[j].name[0] ? c[j].q : prims[j];
        k += c[j].name[0] != 0;
    }
    const char *mname = m->base ? "my_model" : "evolved";
    write_header(f, r, k, m, m->setops == GP_SETOPS_RFUNC ? "rfunc" : "minmax");
    write_model_head(f, m->base, mname);
    if (canon_write_body(f, r, prims, c, nprims, m->points, m->exact, m->hyperfun,
                         m->base ? m->base->call : NULL, m->cancel))
        goto done;
    write_clip(f, r, mname, canon_tree_bounded(r, cq, nprims), m->hyperfun);
    rc = ferror(f) ? -1 : 0;
done:
    frep_free(c);
    frep_free(cq);
    return rc;
}

int evolve_write_dot(FILE *f, const evolve_result *r, const prim *prims, size_t nprims)
{
    char **names = frep_calloc(nprims + 1, sizeof *names);
    if (!names) return -1;
    int rc = 0;
    for (size_t j = 0; j <= nprims && !rc; j++) {
        names[j] = frep_malloc(64);
        if (!names[j]) rc = -1;
        else if (j == nprims) snprintf(names[j], 64, "p%zu\\nbase model", j + 1);
        else snprintf(names[j], 64, "p%zu\\n%s", j + 1, prim_type_name(prims[j].type));
    }
    if (!rc) tree_print_dot(f, r->tree.code, r->tree.len, (const char *const *)names);
    for (size_t j = 0; j <= nprims; j++) frep_free(names[j]);
    frep_free(names);
    return rc || ferror(f) ? -1 : 0;
}

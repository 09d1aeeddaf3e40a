/* fitness.c - scores construction trees against an oriented point cloud from cached
 * primitive values (Fayolle & Pasko 2016, eq. 7); the inner loop of `frep evolve`.
 *
 * The trees are evaluated here straight from their bytecode by a small evaluator of
 * the GP subset (PRIM, NEG and the set operations) rather than by runtime/vm.c: for
 * min/max trees it tracks which primitive is active at each point instead of a
 * gradient, so scoring a tree costs a few comparisons per node and point and one table
 * lookup per point (the exp/acos terms are tabulated once per primitive). The crossing
 * test that keeps zero-thickness sheets from scoring runs beside it on bit masks.
 */
#include "config.h"

#include "alloc.h"
#include "fitness.h"
#include "util.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The tape of one tree (fitness.h, "Tapes"): every node's stack entry at every
 * point of the cache it was recorded on. */
typedef struct gp_tape {
    const gp_cache *c;   /* the cache of the recording; NULL: nothing recorded */
    uint32_t len;        /* nodes of the recorded tree */
    size_t cells;        /* node-point cells allocated (len * n at most) */
    size_t wcells;       /* words of side allocated */
    frep_insn *code;     /* the recorded tree, and the subtree start of each node */
    uint32_t *start;
    uint32_t codecap;
    float *vf;           /* min/max: vf[k*n + i], si[k*n + i] as in the stack */
    uint32_t *si;
    double *v, *g;       /* R-functions: v[k*n + i], g[(3k + c)*n + i] */
    uint64_t *side;      /* side[(4k + r)*nw + w]: the crossing bits */
    int valued;          /* 1: the arrays hold the node values; 0: the tree was too
                            large (GP_TAPE_MAX_BYTES), replacements are scored in full */
    gp_tree path;        /* scratch: the tree scored by gp_fitness_replaced */
} gp_tape;

struct gp_eval {
    gp_tape tape;        /* of the last gp_tape_record */
    uint32_t cap;        /* stack entries allocated */
    double *sv;          /* sv[k*GP_FIT_BLOCK + i]: value of stack entry k */
    double *sg;          /* sg[(3k + c)*GP_FIT_BLOCK + i]: gradient (R-functions) */
    float *sf;           /* sf[k*GP_FIT_BLOCK + i]: value of stack entry k (min/max) */
    uint32_t *si;        /* si[k*GP_FIT_BLOCK + i]: 2*prim + complemented (min/max) */
    uint64_t *sb;        /* sb[(4k + r)*GP_FIT_WORDS + w]: the four threshold bits of
                            stack entry k (rows r as in gp_cache.side) */
};

_Static_assert(GP_FIT_BLOCK % 64 == 0, "blocks are whole words of the crossing masks");

gp_eval *gp_eval_new(void)
{
    return frep_calloc(1, sizeof(gp_eval));
}

void gp_eval_free(gp_eval *e)
{
    if (!e) return;
    frep_free(e->tape.code);
    frep_free(e->tape.start);
    frep_free(e->tape.vf);
    frep_free(e->tape.si);
    frep_free(e->tape.v);
    frep_free(e->tape.g);
    frep_free(e->tape.side);
    tree_free(&e->tape.path);
    frep_free(e->sv);
    frep_free(e->sg);
    frep_free(e->si);
    frep_free(e->sf);
    frep_free(e->sb);
    frep_free(e);
}

static int eval_reserve(gp_eval *e, uint32_t need)
{
    if (need <= e->cap) return 0;
    uint32_t cap = e->cap ? e->cap : 16;
    while (cap < need) cap *= 2;
    double *sv = frep_malloc((size_t)cap * GP_FIT_BLOCK * sizeof *sv);
    double *sg = frep_malloc((size_t)cap * 3 * GP_FIT_BLOCK * sizeof *sg);
    uint32_t *si = frep_malloc((size_t)cap * GP_FIT_BLOCK * sizeof *si);
    float *sf = frep_malloc((size_t)cap * GP_FIT_BLOCK * sizeof *sf);
    uint64_t *sb = frep_malloc((size_t)cap * 4 * GP_FIT_WORDS * sizeof *sb);
    if (!sv || !sg || !si || !sf || !sb) {
        frep_free(sv);
        frep_free(sg);
        frep_free(si);
        frep_free(sf);
        frep_free(sb);
        return -1;
    }
    frep_free(e->sv);
    frep_free(e->sg);
    frep_free(e->si);
    frep_free(e->sf);
    frep_free(e->sb);
    e->sb = sb;
    e->sf = sf;
    e->sv = sv;
    e->sg = sg;
    e->si = si;
    e->cap = cap;
    return 0;
}

static uint32_t max_stack(const frep_insn *code, uint32_t len)
{
    long sp = 0, mx = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        sp += 1 - tree_nin(&code[pc]);
        if (sp > mx) mx = sp;
    }
    return (uint32_t)mx;
}

/* The score of one point: f its value, g the gradient of f, nrm its unit normal.
 * theta is the angle between the outward normal and -grad f (f >= 0 inside, so the
 * gradient points inward). */
static double point_term(const gp_cache *c, double f, double gx, double gy, double gz,
                         const double *nrm, int *within, int *nok)
{
    if (!isfinite(f) || !isfinite(gx) || !isfinite(gy) || !isfinite(gz)) {
        *within = *nok = 0;
        return 0.0;
    }
    double d = f / c->eps_d;
    double gn = sqrt(gx * gx + gy * gy + gz * gz);
    double theta = FREP_PI; /* no gradient: the worst angle */
    if (gn > 0) {
        double cs = -(gx * nrm[0] + gy * nrm[1] + gz * nrm[2]) / gn;
        if (cs > 1) cs = 1;
        if (cs < -1) cs = -1;
        theta = acos(cs);
    }
    double t = theta / c->alpha;
    *within = fabs(d) < 1.0;
    *nok = t < 1.0;
    return exp(-d * d) + exp(-t * t);
}

/* ---- caches ---------------------------------------------------------------- */

/* Threshold bits of every primitive at x +- h n (first order: v +- h g.n, exact for
 * planes; for curved primitives their tangent planes, which is what a crossing within
 * h means at the scale of eps_d). */
static int build_sides(gp_cache *c)
{
    size_t n = c->n, nw = (n + 63) / 64;
    c->nw = nw;
    c->side = frep_calloc((size_t)4 * c->nprims * (nw ? nw : 1), sizeof *c->side);
    if (!c->side) return -1;
    double h = GP_CROSS_H * c->eps_d, tol = GP_CROSS_TOL * c->eps_d;
    for (size_t j = 0; j < c->nprims; j++) {
        const double *v = c->v + j * n;
        const double *g = c->g + 3 * j * n;
        uint64_t *row = c->side + 4 * j * nw;
        for (size_t i = 0; i < n; i++) {
            const double *q = c->nrm + 3 * i;
            double gn = g[i] * q[0] + g[n + i] * q[1] + g[2 * n + i] * q[2];
            double vo = v[i] + h * gn, vi = v[i] - h * gn;
            uint64_t bit = (uint64_t)1 << (i & 63);
            size_t w = i >> 6;
            if (vo > tol) row[w] |= bit;
            if (vo > -tol) row[nw + w] |= bit;
            if (vi > tol) row[2 * nw + w] |= bit;
            if (vi > -tol) row[3 * nw + w] |= bit;
        }
    }
    return 0;
}

/* The score tables of a min/max cache (they depend on eps_d and alpha). */
static void fill_scores(gp_cache *c)
{
    size_t n = c->n;
    long np = (long)c->nprims;
#pragma omp parallel for schedule(static)
    for (long jl = 0; jl < np; jl++) {
        size_t j = (size_t)jl;
        const double *v = c->v + j * n;
        const double *g = c->g + 3 * j * n;
        float *s0 = c->score + 2 * j * n, *s1 = s0 + n;
        for (size_t i = 0; i < n; i++) {
            int w, k;
            double gx = g[i], gy = g[n + i], gz = g[2 * n + i];
            s0[i] = (float)point_term(c, v[i], gx, gy, gz, c->nrm + 3 * i, &w, &k);
            s1[i] = (float)point_term(c, -v[i], -gx, -gy, -gz, c->nrm + 3 * i, &w, &k);
        }
    }
}

/* gp_cache.tail: from the score tables (min/max), else 2 per point (each of the two
 * exp terms is at most 1). 0 or -1. */
static int build_tail(gp_cache *c)
{
    size_t n = c->n, B = GP_FIT_BLOCK, nb = (n + B - 1) / B;
    if (!c->tail) c->tail = frep_malloc((nb + 1) * sizeof *c->tail);
    if (!c->tail) return -1;
    c->tail[nb] = 0;
    for (size_t b = nb; b-- > 0;) {
        /* Summed in the order score_code sums the block. */
        double u = 0;
        for (size_t i = b * B; i < n && i < (b + 1) * B; i++) {
            float mx = c->score ? 0 : 2;
            for (size_t q = 0; c->score && q < 2 * (size_t)c->nprims; q++)
                if (c->score[q * n + i] > mx) mx = c->score[q * n + i];
            u += (double)mx;
        }
        c->tail[b] = u + c->tail[b + 1];
    }
    return 0;
}

/* vf, and with tables the score tables and their tail (min/max caches). */
static int build_scores(gp_cache *c, int tables)
{
    if (c->setops != GP_SETOPS_MINMAX) return tables ? build_tail(c) : 0;
    size_t n = c->n;
    c->vf = frep_malloc((size_t)c->nprims * (n ? n : 1) * sizeof *c->vf);
    if (!c->vf) return -1;
    for (size_t k = 0; k < (size_t)c->nprims * n; k++) c->vf[k] = (float)c->v[k];
    if (!tables) return 0;
    c->score = frep_malloc((size_t)2 * c->nprims * (n ? n : 1) * sizeof *c->score);
    if (!c->score) return -1;
    fill_scores(c);
    return build_tail(c);
}

int gp_cache_set_alpha(gp_cache *c, double alpha)
{
    c->alpha = alpha;
    if (c->setops != GP_SETOPS_MINMAX || !c->score) return 0;
    fill_scores(c);
    return build_tail(c);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int gp_cache_noise(const gp_cache *c, gp_noise *out)
{
    memset(out, 0, sizeof *out);
    size_t n = c->n;
    double *dist = frep_malloc((n ? n : 1) * sizeof *dist), *ang = frep_malloc((n ? n : 1) * sizeof *ang);
    if (!dist || !ang) {
        frep_free(dist);
        frep_free(ang);
        return -1;
    }
    double cmax = cos(GP_NOISE_MAX_DEG * FREP_PI / 180);
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        const double *q = c->nrm + 3 * i;
        double best = HUGE_VAL, bcos = 1;
        for (size_t j = 0; j < c->nprims; j++) {
            double f = fabs(c->v[j * n + i]);
            if (!(f < c->eps_d) || f >= best) continue;
            const double *g = c->g + 3 * j * n;
            double gx = g[i], gy = g[n + i], gz = g[2 * n + i];
            double gl = sqrt(gx * gx + gy * gy + gz * gz);
            if (!(gl > 0)) continue;
            /* Either orientation: the wall of a hole is a complemented primitive. */
            double cs = fabs(gx * q[0] + gy * q[1] + gz * q[2]) / gl;
            if (cs < cmax) continue;
            best = f;
            bcos = cs > 1 ? 1 : cs;
        }
        if (best < HUGE_VAL) {
            dist[k] = best;
            ang[k++] = acos(bcos) * 180 / FREP_PI;
        }
    }
    out->inliers = k;
    if (k) {
        qsort(dist, k, sizeof *dist, cmp_double);
        qsort(ang, k, sizeof *ang, cmp_double);
        out->sigma_d = 1.4826 * dist[k / 2] / c->eps_d;
        out->median_deg = ang[k / 2];
        out->p90_deg = ang[(k - 1) * 9 / 10];
    }
    frep_free(dist);
    frep_free(ang);
    return 0;
}

/* A cache holding v and g (taken, also on failure); NULL on allocation failure. */
static gp_cache *cache_of(size_t n, uint32_t nprims, gp_setops s, double *v, double *g)
{
    gp_cache *c = frep_calloc(1, sizeof *c);
    if (!c || !v || !g) {
        frep_free(c);
        frep_free(v);
        frep_free(g);
        return NULL;
    }
    c->n = n;
    c->nprims = nprims;
    c->setops = s;
    c->v = v;
    c->g = g;
    c->nw = (n + 63) / 64;
    return c;
}

static gp_cache *cache_new(size_t n, uint32_t nprims, gp_setops s, double *v, double *g,
                           const double *nrm, double eps_d, double alpha, double lambda,
                           int tables)
{
    gp_cache *c = cache_of(n, nprims, s, v, g);
    if (!c) return NULL;
    c->eps_d = eps_d;
    c->crossing = 1;
    c->alpha = alpha;
    c->lambda = lambda >= 0 ? lambda : (n > 1 ? log((double)n) : 0.0);
    c->nrm = frep_malloc(3 * (n ? n : 1) * sizeof *c->nrm);
    if (!c->nrm) {
        gp_cache_free(c);
        return NULL;
    }
    for (size_t i = 0; i < n; i++) {
        const double *q = nrm + 3 * i;
        double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        for (int k = 0; k < 3; k++) c->nrm[3 * i + k] = l > 0 ? q[k] / l : 0.0;
    }
    if (build_scores(c, tables) || build_sides(c)) {
        gp_cache_free(c);
        return NULL;
    }
    return c;
}

gp_cache *gp_cache_new(size_t n, uint32_t nprims, gp_setops s, double *v, double *g,
                       const double *nrm, double eps_d, double alpha, double lambda)
{
    return cache_new(n, nprims, s, v, g, nrm, eps_d, alpha, lambda, 1);
}

gp_cache *gp_cache_new_stats(size_t n, uint32_t nprims, gp_setops s, double *v, double *g,
                             const double *nrm, double eps_d, double alpha, double lambda)
{
    return cache_new(n, nprims, s, v, g, nrm, eps_d, alpha, lambda, 0);
}

gp_cache *gp_cache_values(size_t n, uint32_t nprims, gp_setops s, double *v, double *g)
{
    gp_cache *c = cache_of(n, nprims, s, v, g);
    if (!c) return NULL;
    c->values_only = 1;
    if (s == GP_SETOPS_MINMAX) {
        c->vf = frep_malloc((size_t)nprims * (n ? n : 1) * sizeof *c->vf);
        if (!c->vf) {
            gp_cache_free(c);
            return NULL;
        }
        for (size_t k = 0; k < (size_t)nprims * n; k++) c->vf[k] = (float)v[k];
    }
    return c;
}

gp_cache *gp_cache_subset(const gp_cache *c, const size_t *idx, size_t m,
                          const uint32_t *prims, uint32_t k, double lambda)
{
    /* Every table is gathered from c's (the same numbers as building them again from
     * the gathered values, without the exp and acos of the score tables). */
    size_t mm = m ? m : 1, n = c->n, nw = (m + 63) / 64;
    gp_cache *s = frep_calloc(1, sizeof *s);
    if (!s) return NULL;
    s->n = m;
    s->nprims = k;
    s->setops = c->setops;
    s->eps_d = c->eps_d;
    s->alpha = c->alpha;
    s->crossing = c->crossing;
    s->lambda = lambda >= 0 ? lambda : (m > 1 ? log((double)m) : 0.0);
    s->nw = nw;
    s->v = frep_malloc((size_t)k * mm * sizeof *s->v);
    s->g = frep_malloc((size_t)3 * k * mm * sizeof *s->g);
    s->nrm = frep_malloc(3 * mm * sizeof *s->nrm);
    s->side = frep_calloc((size_t)4 * k * (nw ? nw : 1), sizeof *s->side);
    if (c->setops == GP_SETOPS_MINMAX) {
        if (c->score) s->score = frep_malloc((size_t)2 * k * mm * sizeof *s->score);
        s->vf = frep_malloc((size_t)k * mm * sizeof *s->vf);
    }
    if (!s->v || !s->g || !s->nrm || !s->side ||
        (c->setops == GP_SETOPS_MINMAX && ((c->score && !s->score) || !s->vf))) {
        gp_cache_free(s);
        return NULL;
    }
    for (uint32_t jj = 0; jj < k; jj++) {
        size_t j = prims[jj];
        for (size_t i = 0; i < m; i++) {
            size_t q = idx[i];
            s->v[(size_t)jj * m + i] = c->v[j * n + q];
            for (size_t d = 0; d < 3; d++)
                s->g[(3 * (size_t)jj + d) * m + i] = c->g[(3 * j + d) * n + q];
            if (s->vf) s->vf[(size_t)jj * m + i] = c->vf[j * n + q];
            if (s->score) {
                s->score[2 * (size_t)jj * m + i] = c->score[2 * j * n + q];
                s->score[(2 * (size_t)jj + 1) * m + i] = c->score[(2 * j + 1) * n + q];
            }
            for (size_t r = 0; r < 4; r++)
                if (c->side[(4 * j + r) * c->nw + (q >> 6)] >> (q & 63) & 1u)
                    s->side[(4 * (size_t)jj + r) * nw + (i >> 6)] |= (uint64_t)1 << (i & 63);
        }
    }
    for (size_t i = 0; i < m; i++)
        for (int d = 0; d < 3; d++) s->nrm[3 * i + d] = c->nrm[3 * idx[i] + d];
    if ((s->score || (c->tail && s->setops != GP_SETOPS_MINMAX)) && build_tail(s)) {
        gp_cache_free(s);
        return NULL;
    }
    return s;
}

void gp_cache_free(gp_cache *c)
{
    if (!c) return;
    frep_free(c->v);
    frep_free(c->g);
    frep_free(c->nrm);
    frep_free(c->score);
    frep_free(c->vf);
    frep_free(c->side);
    frep_free(c->tail);
    frep_free(c);
}

/* ---- evaluation ------------------------------------------------------------- */

/* Min/max: values and active primitive of the block [i0, i0+m) into stack entry 0
 * (single precision: only the comparisons need the values). */
static void eval_minmax(const gp_cache *c, gp_eval *e, const frep_insn *code,
                        uint32_t len, size_t i0, size_t m, const gp_tape *tp, gp_tape *rec)
{
    const size_t B = GP_FIT_BLOCK;
    uint32_t sp = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        const frep_insn *in = &code[pc];
        switch (in->op) {
        case FREP_OP_PRIM: {
            float *v = e->sf + sp * B;
            uint32_t *ix = e->si + sp * B;
            if (in->arg < c->nprims) {
                memcpy(v, c->vf + (size_t)in->arg * c->n + i0, m * sizeof *v);
                for (size_t i = 0; i < m; i++) ix[i] = 2 * in->arg;
            } else {  /* a tape leaf */
                size_t k = in->arg - c->nprims;
                memcpy(v, tp->vf + k * c->n + i0, m * sizeof *v);
                memcpy(ix, tp->si + k * c->n + i0, m * sizeof *ix);
            }
            sp++;
            break;
        }
        case FREP_OP_NEG: {
            float *v = e->sf + (sp - 1) * B;
            uint32_t *ix = e->si + (sp - 1) * B;
            for (size_t i = 0; i < m; i++) {
                v[i] = -v[i];
                ix[i] ^= 1u;
            }
            break;
        }
        case FREP_OP_MAX:
        case FREP_OP_MIN:
        case FREP_OP_MSUB: {
            sp--;
            /* Distinct stack entries: restrict lets the selects vectorise. */
            float *restrict va = e->sf + (sp - 1) * B;
            const float *restrict vb = e->sf + sp * B;
            uint32_t *restrict ia = e->si + (sp - 1) * B;
            const uint32_t *restrict ib = e->si + sp * B;
            if (in->op == FREP_OP_MAX) {
                for (size_t i = 0; i < m; i++) {
                    float a = va[i], b = vb[i];
                    uint32_t msk = (uint32_t)0 - (uint32_t)(b > a);
                    va[i] = b > a ? b : a;
                    ia[i] = (ib[i] & msk) | (ia[i] & ~msk);
                }
            } else if (in->op == FREP_OP_MIN) {
                for (size_t i = 0; i < m; i++) {
                    float a = va[i], b = vb[i];
                    uint32_t msk = (uint32_t)0 - (uint32_t)(b < a);
                    va[i] = b < a ? b : a;
                    ia[i] = (ib[i] & msk) | (ia[i] & ~msk);
                }
            } else {
                for (size_t i = 0; i < m; i++) {
                    float a = va[i], b = -vb[i];
                    uint32_t msk = (uint32_t)0 - (uint32_t)(b < a);
                    va[i] = b < a ? b : a;
                    ia[i] = ((ib[i] ^ 1u) & msk) | (ia[i] & ~msk);
                }
            }
            break;
        }
        default:
            break;  /* R-function ops never reach a min/max cache (tree_valid) */
        }
        if (rec) {
            memcpy(rec->vf + pc * c->n + i0, e->sf + (sp - 1) * B, m * sizeof *e->sf);
            memcpy(rec->si + pc * c->n + i0, e->si + (sp - 1) * B, m * sizeof *e->si);
        }
    }
}

/* R-functions: values and gradients of the block into stack entry 0. */
static void eval_rfunc(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                       size_t i0, size_t m, const gp_tape *tp, gp_tape *rec)
{
    const size_t B = GP_FIT_BLOCK;
    uint32_t sp = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        const frep_insn *in = &code[pc];
        switch (in->op) {
        case FREP_OP_PRIM: {
            size_t j = in->arg;
            const double *v = c->v, *g = c->g;
            if (j >= c->nprims) {  /* a tape leaf */
                j -= c->nprims;
                v = tp->v;
                g = tp->g;
            }
            memcpy(e->sv + sp * B, v + j * c->n + i0, m * sizeof(double));
            for (size_t q = 0; q < 3; q++)
                memcpy(e->sg + (3 * sp + q) * B, g + (3 * j + q) * c->n + i0,
                       m * sizeof(double));
            sp++;
            break;
        }
        case FREP_OP_NEG: {
            double *v = e->sv + (sp - 1) * B, *g = e->sg + 3 * (sp - 1) * B;
            for (size_t i = 0; i < m; i++) v[i] = -v[i];
            for (size_t i = 0; i < 3 * B; i++) g[i] = -g[i];
            break;
        }
        case FREP_OP_RUNI:
        case FREP_OP_RINT:
        case FREP_OP_RSUB:
        case FREP_OP_MAX:
        case FREP_OP_MIN:
        case FREP_OP_MSUB: {
            sp--;
            double *va = e->sv + (sp - 1) * B, *vb = e->sv + sp * B;
            double *ga = e->sg + 3 * (sp - 1) * B, *gb = e->sg + 3 * sp * B;
            /* Subtraction is intersection with the complement of b. */
            double sb = in->op == FREP_OP_RSUB || in->op == FREP_OP_MSUB ? -1.0 : 1.0;
            for (size_t i = 0; i < m; i++) {
                double a = va[i], b = sb * vb[i];
                double dax = ga[i], day = ga[B + i], daz = ga[2 * B + i];
                double dbx = sb * gb[i], dby = sb * gb[B + i], dbz = sb * gb[2 * B + i];
                double f, fx, fy, fz;
                if (in->op == FREP_OP_MAX || in->op == FREP_OP_MIN ||
                    in->op == FREP_OP_MSUB) {
                    int take_b = in->op == FREP_OP_MAX ? b > a : b < a;
                    f = take_b ? b : a;
                    fx = take_b ? dbx : dax;
                    fy = take_b ? dby : day;
                    fz = take_b ? dbz : daz;
                } else {
                    double sr = in->op == FREP_OP_RUNI ? 1.0 : -1.0;
                    double r = sqrt(a * a + b * b);
                    f = a + b + sr * r;
                    double ka = 1, kb = 1;
                    if (r > 0) {
                        ka += sr * a / r;
                        kb += sr * b / r;
                    }
                    fx = ka * dax + kb * dbx;
                    fy = ka * day + kb * dby;
                    fz = ka * daz + kb * dbz;
                }
                va[i] = f;
                ga[i] = fx;
                ga[B + i] = fy;
                ga[2 * B + i] = fz;
            }
            break;
        }
        default:
            break;
        }
        if (rec) {
            memcpy(rec->v + pc * c->n + i0, e->sv + (sp - 1) * B, m * sizeof *e->sv);
            for (size_t q = 0; q < 3; q++)
                memcpy(rec->g + (3 * pc + q) * c->n + i0, e->sg + (3 * (sp - 1) + q) * B,
                       m * sizeof *e->sg);
        }
    }
}

/* The crossing test of the block [i0, i0+m): ok[w] bit i set when the tree is above
 * -tol at x_i - h n_i and not above tol at x_i + h n_i. Each stack entry carries the
 * four threshold bits of gp_cache.side (outer hi, outer lo, inner hi, inner lo). */
static void eval_sides(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                       size_t i0, size_t m, uint64_t ok[GP_FIT_WORDS], const gp_tape *tp,
                       gp_tape *rec)
{
    const size_t W = GP_FIT_WORDS;
    size_t w0 = i0 >> 6, mw = (m + 63) >> 6;
    uint64_t *sb = e->sb;
    uint32_t sp = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        const frep_insn *in = &code[pc];
        switch (in->op) {
        case FREP_OP_PRIM: {
            const uint64_t *row = in->arg < c->nprims
                                      ? c->side + 4 * (size_t)in->arg * c->nw + w0
                                      : tp->side + 4 * (size_t)(in->arg - c->nprims) * c->nw + w0;
            uint64_t *a = sb + 4 * sp * W;
            for (size_t r = 0; r < 4; r++) {
                memcpy(a + r * W, row + r * c->nw, mw * sizeof *sb);
                for (size_t w = mw; w < W; w++) a[r * W + w] = 0;
            }
            sp++;
            break;
        }
        case FREP_OP_NEG: {
            /* -a > t iff not a >= -t: hi and lo swap and flip (ties have measure 0). */
            uint64_t *a = sb + 4 * (sp - 1) * W;
            for (size_t o = 0; o < 4; o += 2)
                for (size_t w = 0; w < W; w++) {
                    uint64_t hi = a[o * W + w], lo = a[(o + 1) * W + w];
                    a[o * W + w] = ~lo;
                    a[(o + 1) * W + w] = ~hi;
                }
            break;
        }
        case FREP_OP_MAX:
        case FREP_OP_RUNI:
        case FREP_OP_MIN:
        case FREP_OP_RINT:
        case FREP_OP_MSUB:
        case FREP_OP_RSUB: {
            sp--;
            uint64_t *restrict a = sb + 4 * (sp - 1) * W;
            const uint64_t *restrict b = sb + 4 * sp * W;
            if (in->op == FREP_OP_MAX || in->op == FREP_OP_RUNI) {
                for (size_t w = 0; w < 4 * W; w++) a[w] |= b[w];
            } else if (in->op == FREP_OP_MIN || in->op == FREP_OP_RINT) {
                for (size_t w = 0; w < 4 * W; w++) a[w] &= b[w];
            } else {
                /* a \ b = min(a, -b): each threshold of a with the complement of the
                 * opposite threshold of b. */
                for (size_t o = 0; o < 4; o += 2)
                    for (size_t w = 0; w < W; w++) {
                        a[o * W + w] &= ~b[(o + 1) * W + w];
                        a[(o + 1) * W + w] &= ~b[o * W + w];
                    }
            }
            break;
        }
        default:
            break;
        }
        if (rec)
            for (size_t r = 0; r < 4; r++)
                memcpy(rec->side + (4 * pc + r) * c->nw + w0, sb + (4 * (sp - 1) + r) * W,
                       mw * sizeof *sb);
    }
    /* Outer point not above tol (not outer hi), inner point above -tol (inner lo). */
    for (size_t w = 0; w < W; w++) ok[w] = ~sb[w] & sb[3 * W + w];
}

/* 1 when point i of the block passes the crossing test (which applies where
 * |f| < eps_d; eq. 7 is unchanged elsewhere). */
static inline int crosses(const uint64_t ok[GP_FIT_WORDS], size_t i)
{
    return (int)((ok[i >> 6] >> (i & 63)) & 1u);
}

/* Value and gradient at the block's points (entry 0 of the stacks). */
static void eval_full(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                      size_t i0, size_t m, const gp_tape *tp)
{
    if (c->setops == GP_SETOPS_MINMAX) {
        eval_minmax(c, e, code, len, i0, m, tp, NULL);
        const size_t B = GP_FIT_BLOCK;
        for (size_t i = 0; i < m; i++) {
            uint32_t ix = e->si[i];
            size_t j = ix >> 1;
            double s = (ix & 1u) ? -1.0 : 1.0;
            e->sv[i] = s * c->v[j * c->n + i0 + i];
            for (size_t q = 0; q < 3; q++) e->sg[q * B + i] = s * c->g[(3 * j + q) * c->n + i0 + i];
        }
    } else {
        eval_rfunc(c, e, code, len, i0, m, tp, NULL);
    }
}

/* The score of code, whose tape leaves refer to tp, in *out; the stack entries of every
 * node go to rec when it is not NULL. *out is -HUGE_VAL as soon as gp_cache.tail shows
 * the score below floor (-HUGE_VAL: never). 0, or -1 on allocation failure or misuse
 * (an empty tree; a min/max cache without score tables). */
static int score_code(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                      const gp_tape *tp, gp_tape *rec, double floor, double *out)
{
    if (!len || eval_reserve(e, max_stack(code, len))) return -1;
    if (c->setops == GP_SETOPS_MINMAX && !c->score && !c->values_only) return -1;
    /* The bound is summed in another order than the score: a margin far above the
     * rounding keeps every decision exact. */
    const double *tail = floor > -HUGE_VAL ? c->tail : NULL;
    floor -= 1e-9 * (fabs(floor) + 1);
    double total = 0;
    if (c->values_only) {
        /* No terms to score: the values only (recorded when rec is set). */
        for (size_t i0 = 0; i0 < c->n; i0 += GP_FIT_BLOCK) {
            size_t m = c->n - i0 < GP_FIT_BLOCK ? c->n - i0 : GP_FIT_BLOCK;
            if (c->setops == GP_SETOPS_MINMAX) eval_minmax(c, e, code, len, i0, m, tp, rec);
            else eval_rfunc(c, e, code, len, i0, m, tp, rec);
        }
        *out = 0;
        return 0;
    }
    const size_t B = GP_FIT_BLOCK;
    uint64_t ok[GP_FIT_WORDS];
    const float epsf = (float)c->eps_d;
    for (size_t i0 = 0; i0 < c->n; i0 += B) {
        size_t m = c->n - i0 < B ? c->n - i0 : B;
        double part = 0;
        if (c->crossing) eval_sides(c, e, code, len, i0, m, ok, tp, rec);
        else memset(ok, 0xff, sizeof ok);
        if (c->setops == GP_SETOPS_MINMAX) {
            eval_minmax(c, e, code, len, i0, m, tp, rec);
            const float *sc = c->score + i0;
            uint64_t all = ~(uint64_t)0;
            for (size_t w = 0; w < (m >> 6); w++) all &= ok[w];
            if (m & 63) all &= ok[m >> 6] | (~(uint64_t)0 << (m & 63));
            if (all == ~(uint64_t)0) {
                /* Every point passes (the common case for good trees). */
                for (size_t i = 0; i < m; i++) part += (double)sc[(size_t)e->si[i] * c->n + i];
            } else {
                for (size_t i = 0; i < m; i++) {
                    float s = sc[(size_t)e->si[i] * c->n + i];
                    int keep = crosses(ok, i) | !(fabsf(e->sf[i]) < epsf);
                    part += keep ? (double)s : 0.0;
                }
            }
        } else {
            eval_rfunc(c, e, code, len, i0, m, tp, rec);
            for (size_t i = 0; i < m; i++) {
                int w, k;
                double s = point_term(c, e->sv[i], e->sg[i], e->sg[B + i], e->sg[2 * B + i],
                                      c->nrm + 3 * (i0 + i), &w, &k);
                if (!crosses(ok, i) && w) s = 0;
                part += s;
            }
        }
        total += part;
        if (tail && total + tail[(i0 + m + B - 1) / B] < floor) {
            *out = -HUGE_VAL;
            return 0;
        }
    }
    *out = total;
    return 0;
}

int gp_score(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len, double *score)
{
    return score_code(c, e, code, len, NULL, NULL, -HUGE_VAL, score);
}

int gp_fitness(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
               double *fitness)
{
    double sc;
    if (gp_score(c, e, code, len, &sc)) return -1;
    *fitness = sc - c->lambda * (double)len;
    return 0;
}

static int per_point(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                     const gp_tape *tp, gp_stats *st, uint8_t *ok, int add)
{
    if (!len || c->values_only || eval_reserve(e, max_stack(code, len))) return -1;
    gp_stats s;
    if (add) s = *st;
    else memset(&s, 0, sizeof s);
    const size_t B = GP_FIT_BLOCK;
    uint64_t okw[GP_FIT_WORDS];
    for (size_t i0 = 0; i0 < c->n; i0 += B) {
        size_t m = c->n - i0 < B ? c->n - i0 : B;
        if (c->crossing) eval_sides(c, e, code, len, i0, m, okw, tp, NULL);
        else memset(okw, 0xff, sizeof okw);
        eval_full(c, e, code, len, i0, m, tp);
        double part = 0;
        for (size_t i = 0; i < m; i++) {
            int w, k;
            double t = point_term(c, e->sv[i], e->sg[i], e->sg[B + i], e->sg[2 * B + i],
                                  c->nrm + 3 * (i0 + i), &w, &k);
            if (!crosses(okw, i) && w) {
                /* On a sheet: no score, not within epsilon of a boundary. */
                t = 0;
                w = 0;
            }
            part += t;
            s.within_eps += (size_t)w;
            s.normals_ok += (size_t)k;
            s.explained += (size_t)(w && k);
            if (ok) ok[i0 + i] = (uint8_t)(w && k);
        }
        s.score += part;
    }
    s.fitness = s.score - c->lambda * (double)len;
    if (st) *st = s;
    return 0;
}

int gp_tree_stats(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                  gp_stats *st)
{
    return per_point(c, e, code, len, NULL, st, NULL, 0);
}

int gp_tree_stats_add(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                      gp_stats *acc)
{
    return per_point(c, e, code, len, NULL, acc, NULL, 1);
}

static int values_code(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                       const gp_tape *tp, double *out)
{
    if (!len || eval_reserve(e, max_stack(code, len))) return -1;
    for (size_t i0 = 0; i0 < c->n; i0 += GP_FIT_BLOCK) {
        size_t m = c->n - i0 < GP_FIT_BLOCK ? c->n - i0 : GP_FIT_BLOCK;
        eval_full(c, e, code, len, i0, m, tp);
        memcpy(out + i0, e->sv, m * sizeof *out);
    }
    return 0;
}

int gp_tree_values(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                   double *out)
{
    return values_code(c, e, code, len, NULL, out);
}

int gp_explained(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                 uint8_t *ok)
{
    return per_point(c, e, code, len, NULL, NULL, ok, 0);
}

/* ---- tapes ------------------------------------------------------------------ */

/* Room in tp for cells node-point cells of c's family and wcells words of crossing
 * bits. 0 or -1. */
size_t gp_tape_max_cells(gp_setops s)
{
    /* 2 cells per byte of crossing bits (4 bits per cell). */
    return GP_TAPE_MAX_BYTES * 2 / (s == GP_SETOPS_RFUNC ? 2 * 32 + 1 : 2 * 8 + 1);
}

static int tape_reserve(gp_tape *tp, const gp_cache *c, size_t cells, size_t wcells)
{
    /* Min/max tapes keep values and active primitives, R-function tapes values and
     * gradients: the arrays of the other family are freed. */
    int rf = c->setops == GP_SETOPS_RFUNC;
    if (cells > tp->cells || (rf ? !tp->v : !tp->vf)) {
        frep_free(tp->vf);
        frep_free(tp->si);
        frep_free(tp->v);
        frep_free(tp->g);
        tp->vf = NULL;
        tp->si = NULL;
        tp->v = tp->g = NULL;
        tp->cells = 0;
        if (rf) {
            tp->v = frep_malloc(cells * sizeof *tp->v);
            tp->g = frep_malloc(3 * cells * sizeof *tp->g);
            if (!tp->v || !tp->g) return -1;
        } else {
            tp->vf = frep_malloc(cells * sizeof *tp->vf);
            tp->si = frep_malloc(cells * sizeof *tp->si);
            if (!tp->vf || !tp->si) return -1;
        }
        tp->cells = cells;
    }
    if (wcells > tp->wcells) {
        frep_free(tp->side);
        tp->side = frep_malloc((wcells ? wcells : 1) * sizeof *tp->side);
        tp->wcells = tp->side ? wcells : 0;
        if (!tp->side) return -1;
    }
    return 0;
}

int gp_tape_record(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                   double *score)
{
    /* code may be a forest (trees one after the other): each node's entry is recorded
     * all the same, and the score is the first tree's. */
    gp_tape *tp = &e->tape;
    tp->c = NULL;
    if (!len) return -1;
    size_t cells = (size_t)len * c->n, wcells = 4 * (size_t)len * c->nw;
    if (len > tp->codecap) {
        frep_insn *nc = frep_realloc(tp->code, (size_t)len * sizeof *nc);
        if (nc) tp->code = nc;
        uint32_t *ns = frep_realloc(tp->start, (size_t)len * sizeof *ns);
        if (ns) tp->start = ns;
        if (!nc || !ns) return -1;
        tp->codecap = len;
    }
    memcpy(tp->code, code, (size_t)len * sizeof *code);
    for (uint32_t k = 0; k < len; k++) tp->start[k] = tree_subtree_start(code, k);
    tp->len = len;
    /* Beyond GP_TAPE_MAX_BYTES only the code is kept: replacements are scored in full. */
    int valued = cells <= gp_tape_max_cells(c->setops);
    if (valued && tape_reserve(tp, c, cells, wcells)) return -1;
    double sc;
    if (score_code(c, e, code, len, NULL, valued ? tp : NULL, -HUGE_VAL, &sc)) return -1;
    tp->valued = valued;
    tp->c = c;
    if (score) *score = sc;
    return 0;
}

int gp_score_taped(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                   double floor, double *score)
{
    if (e->tape.c != c || !e->tape.valued) return -1;
    return score_code(c, e, code, len, &e->tape, NULL, floor, score);
}

int gp_tape_valued(const gp_cache *c, const gp_eval *e)
{
    return e->tape.c == c && e->tape.valued;
}

frep_insn gp_tape_leaf(const gp_cache *c, uint32_t node)
{
    frep_insn in;
    memset(&in, 0, sizeof in);
    in.op = FREP_OP_PRIM;
    in.arg = c->nprims + node;
    return in;
}

/* tp->path = the recorded tree below `node` with the subtree ending at `end` replaced
 * by sub and every subtree off the path from `end` to the root by its tape leaf. */
static int path_emit(const gp_cache *c, gp_tape *tp, uint32_t node, uint32_t end,
                     const frep_insn *sub, uint32_t nsub)
{
    gp_tree *p = &tp->path;
    if (node == end) {
        if (tree_reserve(p, p->len + nsub)) return -1;
        memcpy(p->code + p->len, sub, (size_t)nsub * sizeof *sub);
        p->len += nsub;
        return 0;
    }
    if (end < tp->start[node] || end > node) {
        frep_insn lf = gp_tape_leaf(c, node);
        return tree_push(p, (frep_opcode)lf.op, lf.arg);
    }
    if (tree_nin(&tp->code[node]) == 1) {
        if (path_emit(c, tp, node - 1, end, sub, nsub)) return -1;
    } else {
        uint32_t l0, l1, r0;
        tree_operands(tp->code, node, &l0, &l1, &r0);
        if (path_emit(c, tp, l1, end, sub, nsub) || path_emit(c, tp, node - 1, end, sub, nsub))
            return -1;
    }
    if (tree_reserve(p, p->len + 1)) return -1;
    p->code[p->len++] = tp->code[node];
    return 0;
}

/* Length of the tree the replacement stands for (tape leaves expanded). */
static uint32_t replaced_len(const gp_cache *c, const gp_tape *tp, uint32_t st, uint32_t end,
                             const frep_insn *sub, uint32_t nsub)
{
    uint32_t n = tp->len - (end - st + 1);
    for (uint32_t q = 0; q < nsub; q++) {
        const frep_insn *in = &sub[q];
        if (in->op == FREP_OP_PRIM && in->arg >= c->nprims) {
            uint32_t k = in->arg - c->nprims;
            n += k - tp->start[k] + 1;
        } else {
            n++;
        }
    }
    return n;
}

/* The tree to score for the replacement, in tp->path: the taped path, or without
 * values the whole tree. -1 when nothing is recorded on c (a caller's error) or on
 * allocation failure. */
static int build_path(const gp_cache *c, gp_eval *e, uint32_t st, uint32_t end,
                      const frep_insn *sub, uint32_t nsub)
{
    gp_tape *tp = &e->tape;
    if (tp->c != c || end >= tp->len || st > end) return -1;
    tp->path.len = 0;
    if (tp->valued) return path_emit(c, tp, tp->len - 1, end, sub, nsub);
    gp_tree mid = { NULL, 0, 0 };
    gp_tree *p = &tp->path;
    int rc = gp_tape_expand(c, e, sub, nsub, &mid) ||
             tree_reserve(p, tp->len - (end - st + 1) + mid.len + 1);
    if (!rc) {
        memcpy(p->code, tp->code, (size_t)st * sizeof *p->code);
        memcpy(p->code + st, mid.code, (size_t)mid.len * sizeof *p->code);
        memcpy(p->code + st + mid.len, tp->code + end + 1,
               (size_t)(tp->len - end - 1) * sizeof *p->code);
        p->len = tp->len - (end - st + 1) + mid.len;
    }
    tree_free(&mid);
    return rc ? -1 : 0;
}

int gp_fitness_replaced(const gp_cache *c, gp_eval *e, uint32_t st, uint32_t end,
                        const frep_insn *sub, uint32_t nsub, double floor, double *fitness)
{
    gp_tape *tp = &e->tape;
    if (build_path(c, e, st, end, sub, nsub)) return -1;
    double pen = c->lambda * (double)replaced_len(c, tp, st, end, sub, nsub), sc;
    if (score_code(c, e, tp->path.code, tp->path.len, tp, NULL, floor + pen, &sc)) return -1;
    *fitness = sc - pen;
    return 0;
}

int gp_values_taped(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                    double *out)
{
    if (e->tape.c != c) return -1;
    if (e->tape.valued) return values_code(c, e, code, len, &e->tape, out);
    gp_tree full = { NULL, 0, 0 };
    int rc = gp_tape_expand(c, e, code, len, &full) ||
             values_code(c, e, full.code, full.len, NULL, out);
    tree_free(&full);
    return rc ? -1 : 0;
}

int gp_values_replaced(const gp_cache *c, gp_eval *e, uint32_t st, uint32_t end,
                       const frep_insn *sub, uint32_t nsub, double *out)
{
    gp_tape *tp = &e->tape;
    if (build_path(c, e, st, end, sub, nsub)) return -1;
    return values_code(c, e, tp->path.code, tp->path.len, tp, out);
}

int gp_stats_replaced(const gp_cache *c, gp_eval *e, uint32_t st, uint32_t end,
                      const frep_insn *sub, uint32_t nsub, gp_stats *st_out)
{
    gp_tape *tp = &e->tape;
    if (build_path(c, e, st, end, sub, nsub)) return -1;
    if (per_point(c, e, tp->path.code, tp->path.len, tp, st_out, NULL, 0)) return -1;
    st_out->fitness = st_out->score - c->lambda * (double)replaced_len(c, tp, st, end, sub, nsub);
    return 0;
}

int gp_tape_expand(const gp_cache *c, const gp_eval *e, const frep_insn *sub, uint32_t nsub,
                   gp_tree *out)
{
    const gp_tape *tp = &e->tape;
    out->len = 0;
    for (uint32_t q = 0; q < nsub; q++) {
        const frep_insn *in = &sub[q];
        if (in->op == FREP_OP_PRIM && in->arg >= c->nprims) {
            uint32_t k = in->arg - c->nprims, s0 = tp->start[k];
            if (tree_reserve(out, out->len + (k - s0 + 1))) return -1;
            memcpy(out->code + out->len, tp->code + s0, (size_t)(k - s0 + 1) * sizeof *in);
            out->len += k - s0 + 1;
        } else {
            if (tree_reserve(out, out->len + 1)) return -1;
            out->code[out->len++] = *in;
        }
    }
    return 0;
}

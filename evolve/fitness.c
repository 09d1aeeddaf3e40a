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

#include "fitness.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct gp_eval {
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
    return calloc(1, sizeof(gp_eval));
}

void gp_eval_free(gp_eval *e)
{
    if (!e) return;
    free(e->sv);
    free(e->sg);
    free(e->si);
    free(e->sf);
    free(e->sb);
    free(e);
}

static int eval_reserve(gp_eval *e, uint32_t need)
{
    if (need <= e->cap) return 0;
    uint32_t cap = e->cap ? e->cap : 16;
    while (cap < need) cap *= 2;
    double *sv = malloc((size_t)cap * GP_FIT_BLOCK * sizeof *sv);
    double *sg = malloc((size_t)cap * 3 * GP_FIT_BLOCK * sizeof *sg);
    uint32_t *si = malloc((size_t)cap * GP_FIT_BLOCK * sizeof *si);
    float *sf = malloc((size_t)cap * GP_FIT_BLOCK * sizeof *sf);
    uint64_t *sb = malloc((size_t)cap * 4 * GP_FIT_WORDS * sizeof *sb);
    if (!sv || !sg || !si || !sf || !sb) {
        free(sv);
        free(sg);
        free(si);
        free(sf);
        free(sb);
        return -1;
    }
    free(e->sv);
    free(e->sg);
    free(e->si);
    free(e->sf);
    free(e->sb);
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
    double theta = 3.14159265358979323846; /* no gradient: the worst angle */
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
    c->side = calloc((size_t)4 * c->nprims * (nw ? nw : 1), sizeof *c->side);
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

static int build_scores(gp_cache *c)
{
    if (c->setops != GP_SETOPS_MINMAX) return 0;
    size_t n = c->n;
    c->score = malloc((size_t)2 * c->nprims * (n ? n : 1) * sizeof *c->score);
    c->vf = malloc((size_t)c->nprims * (n ? n : 1) * sizeof *c->vf);
    if (!c->score || !c->vf) return -1;
    for (size_t k = 0; k < (size_t)c->nprims * n; k++) c->vf[k] = (float)c->v[k];
    fill_scores(c);
    return 0;
}

int gp_cache_set_alpha(gp_cache *c, double alpha)
{
    c->alpha = alpha;
    if (c->setops == GP_SETOPS_MINMAX) fill_scores(c);
    return 0;
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
    double *dist = malloc((n ? n : 1) * sizeof *dist), *ang = malloc((n ? n : 1) * sizeof *ang);
    if (!dist || !ang) {
        free(dist);
        free(ang);
        return -1;
    }
    double cmax = cos(GP_NOISE_MAX_DEG * 3.14159265358979323846 / 180);
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
            ang[k++] = acos(bcos) * 180 / 3.14159265358979323846;
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
    free(dist);
    free(ang);
    return 0;
}

gp_cache *gp_cache_new(size_t n, uint32_t nprims, gp_setops s, double *v, double *g,
                       const double *nrm, double eps_d, double alpha, double lambda)
{
    gp_cache *c = calloc(1, sizeof *c);
    if (!c) {
        free(v);
        free(g);
        return NULL;
    }
    c->n = n;
    c->nprims = nprims;
    c->setops = s;
    c->v = v;
    c->g = g;
    c->eps_d = eps_d;
    c->crossing = 1;
    c->alpha = alpha;
    c->lambda = lambda >= 0 ? lambda : (n > 1 ? log((double)n) : 0.0);
    c->nrm = malloc(3 * (n ? n : 1) * sizeof *c->nrm);
    if (!c->v || !c->g || !c->nrm) {
        gp_cache_free(c);
        return NULL;
    }
    for (size_t i = 0; i < n; i++) {
        const double *q = nrm + 3 * i;
        double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        for (int k = 0; k < 3; k++) c->nrm[3 * i + k] = l > 0 ? q[k] / l : 0.0;
    }
    if (build_scores(c) || build_sides(c)) {
        gp_cache_free(c);
        return NULL;
    }
    return c;
}

gp_cache *gp_cache_subset(const gp_cache *c, const size_t *idx, size_t m,
                          const uint32_t *prims, uint32_t k, double lambda)
{
    size_t mm = m ? m : 1;
    double *v = malloc((size_t)k * mm * sizeof *v);
    double *g = malloc((size_t)3 * k * mm * sizeof *g);
    double *nrm = malloc(3 * mm * sizeof *nrm);
    if (!v || !g || !nrm) {
        free(v);
        free(g);
        free(nrm);
        return NULL;
    }
    size_t n = c->n;
    for (uint32_t jj = 0; jj < k; jj++) {
        size_t j = prims[jj];
        for (size_t i = 0; i < m; i++) {
            v[(size_t)jj * m + i] = c->v[j * n + idx[i]];
            for (size_t q = 0; q < 3; q++)
                g[(3 * (size_t)jj + q) * m + i] = c->g[(3 * j + q) * n + idx[i]];
        }
    }
    for (size_t i = 0; i < m; i++)
        for (int q = 0; q < 3; q++) nrm[3 * i + q] = c->nrm[3 * idx[i] + q];
    gp_cache *s = gp_cache_new(m, k, c->setops, v, g, nrm, c->eps_d, c->alpha, lambda);
    if (s) s->crossing = c->crossing;
    free(nrm);
    return s;
}

void gp_cache_free(gp_cache *c)
{
    if (!c) return;
    free(c->v);
    free(c->g);
    free(c->nrm);
    free(c->score);
    free(c->vf);
    free(c->side);
    free(c);
}

/* ---- evaluation ------------------------------------------------------------- */

/* Min/max: values and active primitive of the block [i0, i0+m) into stack entry 0
 * (single precision: only the comparisons need the values). */
static void eval_minmax(const gp_cache *c, gp_eval *e, const frep_insn *code,
                        uint32_t len, size_t i0, size_t m)
{
    const size_t B = GP_FIT_BLOCK;
    uint32_t sp = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        const frep_insn *in = &code[pc];
        switch (in->op) {
        case FREP_OP_PRIM: {
            float *v = e->sf + sp * B;
            uint32_t *ix = e->si + sp * B;
            memcpy(v, c->vf + (size_t)in->arg * c->n + i0, m * sizeof *v);
            for (size_t i = 0; i < m; i++) ix[i] = 2 * in->arg;
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
    }
}

/* R-functions: values and gradients of the block into stack entry 0. */
static void eval_rfunc(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                       size_t i0, size_t m)
{
    const size_t B = GP_FIT_BLOCK;
    uint32_t sp = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        const frep_insn *in = &code[pc];
        switch (in->op) {
        case FREP_OP_PRIM: {
            size_t j = in->arg;
            memcpy(e->sv + sp * B, c->v + j * c->n + i0, m * sizeof(double));
            for (size_t q = 0; q < 3; q++)
                memcpy(e->sg + (3 * sp + q) * B, c->g + (3 * j + q) * c->n + i0,
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
    }
}

/* The crossing test of the block [i0, i0+m): ok[w] bit i set when the tree is above
 * -tol at x_i - h n_i and not above tol at x_i + h n_i. Each stack entry carries the
 * four threshold bits of gp_cache.side (outer hi, outer lo, inner hi, inner lo). */
static void eval_sides(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                       size_t i0, size_t m, uint64_t ok[GP_FIT_WORDS])
{
    const size_t W = GP_FIT_WORDS;
    size_t w0 = i0 >> 6, mw = (m + 63) >> 6;
    uint64_t *sb = e->sb;
    uint32_t sp = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        const frep_insn *in = &code[pc];
        switch (in->op) {
        case FREP_OP_PRIM: {
            const uint64_t *row = c->side + 4 * (size_t)in->arg * c->nw + w0;
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
                      size_t i0, size_t m)
{
    if (c->setops == GP_SETOPS_MINMAX) {
        eval_minmax(c, e, code, len, i0, m);
        const size_t B = GP_FIT_BLOCK;
        for (size_t i = 0; i < m; i++) {
            uint32_t ix = e->si[i];
            size_t j = ix >> 1;
            double s = (ix & 1u) ? -1.0 : 1.0;
            e->sv[i] = s * c->v[j * c->n + i0 + i];
            for (size_t q = 0; q < 3; q++) e->sg[q * B + i] = s * c->g[(3 * j + q) * c->n + i0 + i];
        }
    } else {
        eval_rfunc(c, e, code, len, i0, m);
    }
}

double gp_score(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len)
{
    if (!len || eval_reserve(e, max_stack(code, len))) return NAN;
    double total = 0;
    const size_t B = GP_FIT_BLOCK;
    uint64_t ok[GP_FIT_WORDS];
    const float epsf = (float)c->eps_d;
    for (size_t i0 = 0; i0 < c->n; i0 += B) {
        size_t m = c->n - i0 < B ? c->n - i0 : B;
        double part = 0;
        if (c->crossing) eval_sides(c, e, code, len, i0, m, ok);
        else memset(ok, 0xff, sizeof ok);
        if (c->setops == GP_SETOPS_MINMAX) {
            eval_minmax(c, e, code, len, i0, m);
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
            eval_rfunc(c, e, code, len, i0, m);
            for (size_t i = 0; i < m; i++) {
                int w, k;
                double s = point_term(c, e->sv[i], e->sg[i], e->sg[B + i], e->sg[2 * B + i],
                                      c->nrm + 3 * (i0 + i), &w, &k);
                if (!crosses(ok, i) && w) s = 0;
                part += s;
            }
        }
        total += part;
    }
    return total;
}

double gp_fitness(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len)
{
    return gp_score(c, e, code, len) - c->lambda * (double)len;
}

static int per_point(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                     gp_stats *st, uint8_t *ok)
{
    if (!len || eval_reserve(e, max_stack(code, len))) return -1;
    gp_stats s;
    memset(&s, 0, sizeof s);
    const size_t B = GP_FIT_BLOCK;
    uint64_t okw[GP_FIT_WORDS];
    for (size_t i0 = 0; i0 < c->n; i0 += B) {
        size_t m = c->n - i0 < B ? c->n - i0 : B;
        if (c->crossing) eval_sides(c, e, code, len, i0, m, okw);
        else memset(okw, 0xff, sizeof okw);
        eval_full(c, e, code, len, i0, m);
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
    return per_point(c, e, code, len, st, NULL);
}

int gp_explained(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                 uint8_t *ok)
{
    return per_point(c, e, code, len, NULL, ok);
}

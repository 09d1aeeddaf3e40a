/* objective.c - fitting objectives over a point cloud (see objective.h).
 *
 * Points are cut into blocks of FIT_BLOCK; each block's partial sums (objective,
 * gradient, Gauss-Newton matrices) go to its own slot, and the slots are added in block
 * order afterwards.  OpenMP spreads blocks over threads, each with its own model scratch
 * and buffers, so a seed gives bit-identical fits at any thread count.
 */
#include "alloc.h"
#include "log1p.h"
#include "objective.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "optim.h"
#include "threads.h"

/* Gradient norms below this count as zero: the first-order distance is then undefined
 * and the point gets this norm instead (a huge but finite residual). */
#define FIT_GRAD_FLOOR 1e-300
/* Blocks each thread should get before a pass is worth spreading over threads: waking
 * a thread team costs about as much as evaluating a few blocks. */
#define FIT_MIN_BLOCKS_PER_THREAD 4
/* Step of the central difference that gives the normal term's gradient, relative to
 * the cloud's diagonal. Smaller than the textbook cube root of the machine epsilon
 * (6e-6): near the edges of R-function blends the third derivatives are large, so the
 * O(h^2) truncation error dominates there; the O(eps/h) rounding error stays near 1e-10
 * relative. On the test part 1e-6 gave gradients within 2e-7 of differences over the
 * parameters, 1e-5 within 2e-5. */
#define FIT_FD_XSTEP 1e-6
/* Partial sums of a gradient pass's dot products over a block (a fixed count: the bits
 * do not depend on the machine's vector width or the thread count). */
#define FIT_DOT_LANES 4

typedef struct fit_ws {
    void *scratch;
    double *f, *g, *dp;         /* f[B], g[3B], dp[M*B] */
    /* Normal term's gradient: points shifted by +-h along each point's direction v
     * (xs[0..3B) plus, xs[3B..6B) minus), the factor |v|/(2h) per point (vs[B]) and
     * the parameter derivatives at the minus points (dq[M*B]). Before that a loss
     * pass keeps its per-point terms in xs[0..5B) (block_losses) and a gradient pass
     * each point's d rho / df in vs. */
    double *xs, *vs, *dq;
} fit_ws;

struct fit_objective {
    fit_model model;
    fit_objective_config cfg;
    size_t n, m;            /* points, parameters */
    const double *x, *y, *z, *nx, *ny, *nz;
    double *own;            /* copied points of a subset (NULL: referenced) */
    double *w;              /* frozen weights 1/|grad f| (n); valid when frozen */
    double fd_step;         /* h of the normal term's gradient (FIT_FD_XSTEP x diagonal) */
    int frozen;
    size_t nblocks, slot;   /* block count; doubles per block slot */
    double *partial;        /* nblocks * slot */
    int nthreads;
    fit_ws *ws;             /* nthreads workspaces */
    int *nomem;             /* set when a pass runs out of memory; may be NULL */
    double *resid;          /* where PASS_RESID writes (n); valid during that pass only */
};

void fit_objective_config_init(fit_objective_config *c)
{
    c->kind = FIT_OBJ_ALGEBRAIC;
    c->loss = FIT_LOSS_L2;
    c->loss_scale = 1.0;
    c->normals_weight = 0;
    c->nthreads = 0;
}

size_t fit_objective_npoints(const fit_objective *o) { return o->n; }
fit_objective_kind fit_objective_kind_of(const fit_objective *o) { return o->cfg.kind; }

static void free_ws(fit_objective *o)
{
    if (o->ws == NULL) return;
    for (int t = 0; t < o->nthreads; t++) {
        fit_ws *w = &o->ws[t];
        if (w->scratch != NULL && o->model.scratch_free != NULL)
            o->model.scratch_free(o->model.user, w->scratch);
        frep_free(w->f);
    }
    frep_free(o->ws);
    o->ws = NULL;
}

void fit_objective_free(fit_objective *o)
{
    if (o == NULL) return;
    free_ws(o);
    frep_free(o->partial);
    frep_free(o->w);
    frep_free(o->own);
    frep_free(o);
}

/* Buffers and slots; the points must be set. Returns 0 or -1. */
static int setup(fit_objective *o)
{
    size_t m = o->m;
    double bmin[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, bmax[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (size_t i = 0; i < o->n; i++) {
        const double v[3] = {o->x[i], o->y[i], o->z[i]};
        for (int c = 0; c < 3; c++) bmin[c] = fmin(bmin[c], v[c]), bmax[c] = fmax(bmax[c], v[c]);
    }
    double diag = 0;
    for (int c = 0; c < 3; c++) diag += o->n ? (bmax[c] - bmin[c]) * (bmax[c] - bmin[c]) : 0;
    diag = sqrt(diag);
    o->fd_step = FIT_FD_XSTEP * (diag > 0 && isfinite(diag) ? diag : 1);
    o->nblocks = (o->n + FIT_BLOCK - 1) / FIT_BLOCK;
    o->slot = 2 + m + m * m;
    o->partial = frep_malloc((o->nblocks ? o->nblocks : 1) * o->slot * sizeof *o->partial);
    o->w = frep_malloc((o->n ? o->n : 1) * sizeof *o->w);
    int nt = frep_threads(o->cfg.nthreads);
    o->nthreads = nt;
    o->ws = frep_calloc((size_t)nt, sizeof *o->ws);
    if (o->partial == NULL || o->w == NULL || o->ws == NULL) return -1;
    for (int t = 0; t < nt; t++) {
        fit_ws *w = &o->ws[t];
        w->f = frep_malloc((11 * FIT_BLOCK + 2 * m * FIT_BLOCK) * sizeof *w->f);
        if (w->f == NULL) return -1;
        w->g = w->f + FIT_BLOCK;
        w->dp = w->g + 3 * FIT_BLOCK;
        w->xs = w->dp + m * FIT_BLOCK;
        w->vs = w->xs + 6 * FIT_BLOCK;
        w->dq = w->vs + FIT_BLOCK;
        if (o->model.scratch_new != NULL) {
            w->scratch = o->model.scratch_new(o->model.user);
            if (w->scratch == NULL) return -1;
        }
    }
    return 0;
}

fit_objective *fit_objective_new(const fit_model *m, const fit_points *pts,
                                 const fit_objective_config *cfg)
{
    if (m->nparams == 0 || m->nparams > FIT_MAX_PARAMS) return NULL;
    fit_objective *o = frep_calloc(1, sizeof *o);
    if (o == NULL) return NULL;
    o->model = *m;
    if (cfg != NULL) o->cfg = *cfg;
    else fit_objective_config_init(&o->cfg);
    o->n = pts->n;
    o->m = m->nparams;
    o->x = pts->x, o->y = pts->y, o->z = pts->z;
    if (pts->nx != NULL && pts->ny != NULL && pts->nz != NULL)
        o->nx = pts->nx, o->ny = pts->ny, o->nz = pts->nz;
    if (setup(o) != 0) {
        fit_objective_free(o);
        return NULL;
    }
    return o;
}

fit_objective *fit_objective_subset(const fit_objective *src, size_t count, uint64_t seed,
                                    const unsigned char *keep)
{
    size_t n = 0;
    for (size_t i = 0; i < src->n; i++) n += keep == NULL || keep[i];
    if (count > n) count = n;
    fit_objective *o = frep_calloc(1, sizeof *o);
    if (o == NULL) return NULL;
    o->model = src->model;
    o->cfg = src->cfg;
    o->cfg.nthreads = src->nthreads;
    o->n = count;
    o->m = src->m;
    int normals = src->nx != NULL;
    size_t *idx = frep_malloc((n ? n : 1) * sizeof *idx);
    o->own = frep_malloc((count ? count : 1) * (normals ? 6 : 3) * sizeof *o->own);
    if (idx == NULL || o->own == NULL) {
        frep_free(idx);
        fit_objective_free(o);
        return NULL;
    }
    /* Partial Fisher-Yates shuffle: the first `count` indices are a uniform sample. */
    frep_rng r;
    frep_rng_seed(&r, seed);
    for (size_t i = 0, k = 0; i < src->n; i++)
        if (keep == NULL || keep[i]) idx[k++] = i;
    for (size_t i = 0; i < count; i++) {
        size_t j = i + (size_t)(frep_rng_unit(&r) * (double)(n - i));
        if (j >= n) j = n - 1;
        size_t t = idx[i];
        idx[i] = idx[j];
        idx[j] = t;
    }
    double *a = o->own;
    for (size_t i = 0; i < count; i++) {
        size_t k = idx[i];
        a[i] = src->x[k];
        a[count + i] = src->y[k];
        a[2 * count + i] = src->z[k];
        if (normals) {
            a[3 * count + i] = src->nx[k];
            a[4 * count + i] = src->ny[k];
            a[5 * count + i] = src->nz[k];
        }
    }
    frep_free(idx);
    o->x = a, o->y = a + count, o->z = a + 2 * count;
    if (normals) o->nx = a + 3 * count, o->ny = a + 4 * count, o->nz = a + 5 * count;
    if (setup(o) != 0) {
        fit_objective_free(o);
        return NULL;
    }
    return o;
}

/* What a pass over the blocks computes. */
typedef enum pass_mode {
    PASS_VALUE,     /* slot[0] = sum rho (+ normal term) */
    PASS_GRAD,      /* and slot[1..m] = its gradient */
    PASS_LSQ,       /* slot[0] = sum rho, slot[1..m] = J^T W r, then J^T W J */
    PASS_DIST,      /* slot[0] = sum d^2, slot[1] = max d (first-order distance) */
    PASS_FREEZE,    /* store 1/|grad f| in o->w */
    PASS_RESID,     /* store |f|/|grad f| in o->resid */
    PASS_GNORM      /* store |grad f| in o->resid */
} pass_mode;

/* Sum over a block of the normal term 1 + n . grad f / |grad f| for gradients in g. */
static double normal_term(const fit_objective *o, size_t i0, size_t n, const double *g)
{
    double s = 0;
    for (size_t i = 0; i < n; i++) {
        double gx = g[i], gy = g[n + i], gz = g[2 * n + i];
        double gl = sqrt(gx * gx + gy * gy + gz * gz);
        double nx = o->nx[i0 + i], ny = o->ny[i0 + i], nz = o->nz[i0 + i];
        if (gl > 0 && (nx != 0 || ny != 0 || nz != 0))
            s += 1 + (nx * gx + ny * gy + nz * gz) / gl;
    }
    return s;
}

/* Add nw * d/dp of the block's normal term to grad[m]; w->g holds grad f at the block's
 * points. With g = grad f and the unit normal n, the term 1 + n . g/|g| changes with p_j
 * by v . dg/dp_j, v = (n - (n . u) u)/|g|, u = g/|g|. The evaluators give df/dp_j but no
 * second derivatives; since d/dp_j grad f = grad (df/dp_j), v . dg/dp_j is |v| times the
 * derivative of df/dp_j along v/|v|, taken here by one central difference in space:
 * two parameter-derivative evaluations per block, for all parameters at once, instead of
 * 2m gradient evaluations for differences over the parameters. */
static int normal_grad(const fit_objective *o, fit_ws *w, size_t i0, size_t n, const double *p,
                       double *grad)
{
    const size_t m = o->m, B = n;
    const double h = o->fd_step;
    double *xp = w->xs, *yp = xp + B, *zp = yp + B, *xm = zp + B, *ym = xm + B, *zm = ym + B;
    int any = 0;
    for (size_t i = 0; i < n; i++) {
        double gx = w->g[i], gy = w->g[n + i], gz = w->g[2 * n + i];
        double gl = sqrt(gx * gx + gy * gy + gz * gz);
        double nx = o->nx[i0 + i], ny = o->ny[i0 + i], nz = o->nz[i0 + i];
        double px = o->x[i0 + i], py = o->y[i0 + i], pz = o->z[i0 + i];
        double vx = 0, vy = 0, vz = 0, vl = 0;
        if (gl > 0 && (nx != 0 || ny != 0 || nz != 0)) {
            double nu = (nx * gx + ny * gy + nz * gz) / gl;
            vx = (nx - nu * gx / gl) / gl;
            vy = (ny - nu * gy / gl) / gl;
            vz = (nz - nu * gz / gl) / gl;
            vl = sqrt(vx * vx + vy * vy + vz * vz);
        }
        if (vl > 0 && isfinite(vl)) {
            double k = h / vl;
            xp[i] = px + k * vx, yp[i] = py + k * vy, zp[i] = pz + k * vz;
            xm[i] = px - k * vx, ym[i] = py - k * vy, zm[i] = pz - k * vz;
            w->vs[i] = vl / (2 * h);
            any = 1;
        } else {
            xp[i] = xm[i] = px, yp[i] = ym[i] = py, zp[i] = zm[i] = pz;
            w->vs[i] = 0;
        }
    }
    if (!any) return 0;
    /* The loss gradient is summed already: dp and f are free to reuse. */
    if (o->model.eval(o->model.user, w->scratch, n, xp, yp, zp, p, w->f, NULL, w->dp) != 0 ||
        o->model.eval(o->model.user, w->scratch, n, xm, ym, zm, p, w->f, NULL, w->dq) != 0)
        return -1;
    const double nw = o->cfg.normals_weight;
    for (size_t j = 0; j < m; j++) {
        const double *a = w->dp + j * n, *b = w->dq + j * n;
        double s = 0;
        for (size_t i = 0; i < n; i++) s += w->vs[i] * (a[i] - b[i]);
        grad[j] += nw * s;
    }
    return 0;
}

/* |grad f| at point i of a block of n (floored); the pass evaluated grad f. The
 * select is fmax(|g|, FIT_GRAD_FLOOR) for every |g| >= 0 or NaN, and vectorizes where
 * fmax is a libm call. */
static double grad_len(const fit_ws *w, size_t n, size_t i)
{
    double gx = w->g[i], gy = w->g[n + i], gz = w->g[2 * n + i];
    double gl = sqrt(gx * gx + gy * gy + gz * gz);
    return gl > FIT_GRAD_FLOOR ? gl : FIT_GRAD_FLOOR;
}

/* A loss pass's terms per point of a block (PASS_VALUE, PASS_GRAD, PASS_LSQ), each an
 * array of n in the workspace: wi = dr/df, the residual r = f wi, rho(r) and the IRLS
 * weight omega = rho'(r) / (2 r) (1 at r = 0). */
typedef struct block_terms {
    double *wi, *r, *rho, *omega;
} block_terms;

/* The terms of the n points of a block in w->xs (free until normal_grad), one loop per
 * stage and per loss kind so that each vectorizes (a scalar loop with the loss's switch
 * inside was a fifth of the paper's part's CPU time); the caller adds rho in point
 * order, so the sums are those of one loop over the points. The Cauchy loss's
 * log1p(r^2 / s^2) is computed a block at a time (fit_log1p_block). */
static block_terms block_losses(const fit_objective *o, fit_ws *w, size_t i0, size_t n)
{
    /* wi: 1 (algebraic) or 1/|grad f|, frozen or current */
    block_terms t = {w->xs, w->xs + FIT_BLOCK, w->xs + 2 * FIT_BLOCK,
                     w->xs + 3 * FIT_BLOCK};
    double *restrict wi = t.wi, *restrict r = t.r, *restrict rho = t.rho;
    double *restrict omega = t.omega, *restrict lq = w->xs + 4 * FIT_BLOCK;
    const double *restrict f = w->f;
    const double s = o->cfg.loss_scale;
    if (o->cfg.kind != FIT_OBJ_GEOMETRIC)
        for (size_t i = 0; i < n; i++) wi[i] = 1;
    else if (o->frozen)
        memcpy(wi, o->w + i0, n * sizeof *wi);
    else                        /* the pass evaluated grad f (need_g) */
        for (size_t i = 0; i < n; i++) wi[i] = 1 / grad_len(w, n, i);
    for (size_t i = 0; i < n; i++) r[i] = f[i] * wi[i];
    switch (o->cfg.loss) {
    case FIT_LOSS_HUBER:
        for (size_t i = 0; i < n; i++) {
            double a = fabs(r[i]), om = s / a;
            rho[i] = a <= s ? r[i] * r[i] : 2 * s * a - s * s;
            omega[i] = a <= s ? 1 : om;
        }
        break;
    case FIT_LOSS_CAUCHY:
        for (size_t i = 0; i < n; i++) rho[i] = r[i] * r[i] / (s * s);  /* q */
        fit_log1p_block(n, rho, lq);
        for (size_t i = 0; i < n; i++) {
            omega[i] = 1 / (1 + rho[i]);
            rho[i] = s * s * lq[i];
        }
        break;
    case FIT_LOSS_GEMAN:
        for (size_t i = 0; i < n; i++) {
            double q = 1 / (1 + r[i] * r[i] / (s * s));
            omega[i] = q * q;
            rho[i] = r[i] * r[i] * q;
        }
        break;
    case FIT_LOSS_L2:
        for (size_t i = 0; i < n; i++) {
            omega[i] = 1;
            rho[i] = r[i] * r[i];
        }
        break;
    }
    return t;
}

/* The per-point passes (PASS_FREEZE, PASS_RESID, PASS_GNORM, PASS_DIST) of a block. */
static void block_points(fit_objective *o, fit_ws *w, size_t i0, size_t n, pass_mode mode,
                         double *out)
{
    for (size_t i = 0; i < n; i++) {
        double f = w->f[i], gl = grad_len(w, n, i);
        if (mode == PASS_FREEZE) {
            o->w[i0 + i] = 1 / gl;
        } else if (mode == PASS_RESID || mode == PASS_GNORM) {
            o->resid[i0 + i] = mode == PASS_RESID ? fabs(f) / gl : gl;
        } else {
            double d = fabs(f) / gl;
            out[0] += d * d;
            out[1] = fmax(out[1], d);
            if (isnan(d)) out[1] = NAN;
        }
    }
}

static int run_block(fit_objective *o, fit_ws *w, size_t b, const double *p, pass_mode mode)
{
    const size_t m = o->m, i0 = b * FIT_BLOCK;
    const size_t n = o->n - i0 < FIT_BLOCK ? o->n - i0 : FIT_BLOCK;
    double *out = o->partial + b * o->slot;
    const int geo = o->cfg.kind == FIT_OBJ_GEOMETRIC;
    const int normals = o->cfg.normals_weight > 0 && o->nx != NULL &&
                        (mode == PASS_VALUE || mode == PASS_GRAD);
    const int need_g = (geo && !o->frozen) || normals || mode == PASS_DIST ||
                       mode == PASS_FREEZE || mode == PASS_RESID ||
                       mode == PASS_GNORM;
    const int need_dp = mode == PASS_GRAD || mode == PASS_LSQ;
    const double *x = o->x + i0, *y = o->y + i0, *z = o->z + i0;

    memset(out, 0, o->slot * sizeof *out);
    if (o->model.eval(o->model.user, w->scratch, n, x, y, z, p, w->f, need_g ? w->g : NULL,
                      need_dp ? w->dp : NULL) != 0)
        return -1;
    if (mode != PASS_VALUE && mode != PASS_GRAD && mode != PASS_LSQ) {
        block_points(o, w, i0, n, mode, out);
        return 0;
    }
    const block_terms t = block_losses(o, w, i0, n);
    double total = 0;
    for (size_t i = 0; i < n; i++) total += t.rho[i];
    out[0] = total;
    if (mode == PASS_GRAD) {
        for (size_t i = 0; i < n; i++)
            w->vs[i] = 2 * t.omega[i] * t.r[i] * t.wi[i];      /* d rho / d f */
    } else if (mode == PASS_LSQ) {
        double *jtr = out + 2, *jtj = out + 2 + m;
        for (size_t i = 0; i < n; i++) {
            double wi = t.wi[i], r = t.r[i], omega = t.omega[i];
            for (size_t j = 0; j < m; j++) {
                double Jj = wi * w->dp[j * n + i];
                if (Jj == 0) continue;
                jtr[j] += omega * r * Jj;
                for (size_t k = 0; k <= j; k++) jtj[j * m + k] += omega * Jj * wi * w->dp[k * n + i];
            }
        }
    }
    if (mode == PASS_GRAD) {
        /* d rho / dp_j, one parameter at a time over the contiguous rows of dp, in
         * FIT_DOT_LANES partial sums (point i goes to sum i mod FIT_DOT_LANES, added in
         * lane order at the end): one running sum waited on every addition. */
        for (size_t j = 0; j < m; j++) {
            const double *d = w->dp + j * n;
            double acc[FIT_DOT_LANES] = {0};
            size_t i = 0;
            for (; i + FIT_DOT_LANES <= n; i += FIT_DOT_LANES)
                for (size_t k = 0; k < FIT_DOT_LANES; k++) acc[k] += w->vs[i + k] * d[i + k];
            for (size_t k = 0; i < n; i++, k++) acc[k] += w->vs[i] * d[i];
            double sum = 0;
            for (size_t k = 0; k < FIT_DOT_LANES; k++) sum += acc[k];
            out[2 + j] = sum;
        }
    }
    if (normals) {
        double nw = o->cfg.normals_weight;
        out[0] += nw * normal_term(o, i0, n, w->g);
        if (mode == PASS_GRAD && normal_grad(o, w, i0, n, p, out + 2) != 0) return -1;
    }
    return 0;
}

/* Run every block; returns 0, or -1 when some block ran out of memory (recorded in
 * o->nomem once the threads have joined). */
static int run_pass(fit_objective *o, const double *p, pass_mode mode)
{
    const long nb = (long)o->nblocks;
    int failed = 0;
    long want = nb / FIT_MIN_BLOCKS_PER_THREAD;
    int nt = want < o->nthreads ? (int)(want > 1 ? want : 1) : o->nthreads;
    /* One thread runs the blocks without a parallel region: libgomp's region of one
     * thread still ends in a futex wake, a system call per pass (4% of a fit's CPU). */
    if (nt <= 1) {
        for (long b = 0; b < nb; b++)
            if (run_block(o, &o->ws[0], (size_t)b, p, mode) != 0) failed |= 1;
    } else {
#pragma omp parallel num_threads(nt) reduction(| : failed)
        {
            fit_ws *w = &o->ws[frep_thread_num()];
#pragma omp for schedule(static)
            for (long b = 0; b < nb; b++)
                if (run_block(o, w, (size_t)b, p, mode) != 0) failed |= 1;
        }
    }
    if (failed && o->nomem != NULL) *o->nomem = 1;
    return failed ? -1 : 0;
}

void fit_objective_watch_nomem(fit_objective *o, int *flag) { o->nomem = flag; }

/* Add the block slots in block order into sum[slot]. */
static void reduce(const fit_objective *o, double *sum, size_t len)
{
    memset(sum, 0, len * sizeof *sum);
    for (size_t b = 0; b < o->nblocks; b++) {
        const double *s = o->partial + b * o->slot;
        for (size_t k = 0; k < len; k++) sum[k] += s[k];
    }
}

double fit_objective_value(void *user, const double *p, double *grad)
{
    fit_objective *o = user;
    if (o->n == 0) return NAN;
    if (run_pass(o, p, grad != NULL ? PASS_GRAD : PASS_VALUE) != 0) return NAN;
    double head[2];
    reduce(o, head, 2);
    double inv = 1 / (double)o->n;
    if (grad != NULL) {
        memset(grad, 0, o->m * sizeof *grad);
        for (size_t b = 0; b < o->nblocks; b++) {
            const double *s = o->partial + b * o->slot + 2;
            for (size_t j = 0; j < o->m; j++) grad[j] += s[j];
        }
        for (size_t j = 0; j < o->m; j++) grad[j] *= inv;
    }
    return head[0] * inv;
}

double fit_objective_lsq(void *user, const double *p, double *jtj, double *jtr)
{
    fit_objective *o = user;
    const size_t m = o->m;
    if (o->n == 0 || run_pass(o, p, PASS_LSQ) != 0) return NAN;
    double cost = 0;
    memset(jtr, 0, m * sizeof *jtr);
    memset(jtj, 0, m * m * sizeof *jtj);
    for (size_t b = 0; b < o->nblocks; b++) {
        const double *s = o->partial + b * o->slot;
        cost += s[0];
        for (size_t j = 0; j < m; j++) jtr[j] += s[2 + j];
        for (size_t k = 0; k < m * m; k++) jtj[k] += s[2 + m + k];
    }
    double inv = 1 / (double)o->n;
    for (size_t j = 0; j < m; j++) {
        jtr[j] *= inv;
        for (size_t k = 0; k <= j; k++) jtj[k * m + j] = jtj[j * m + k] *= inv;
    }
    return 0.5 * cost * inv;
}

int fit_objective_freeze(fit_objective *o, const double *p)
{
    if (o->cfg.kind != FIT_OBJ_GEOMETRIC) return 0;
    o->frozen = 0;
    if (run_pass(o, p, PASS_FREEZE) != 0) return -1;
    o->frozen = 1;
    return 0;
}

void fit_objective_unfreeze(fit_objective *o) { o->frozen = 0; }

void fit_objective_set_loss(fit_objective *o, fit_loss loss, double scale)
{
    o->cfg.loss = loss;
    o->cfg.loss_scale = scale;
}

double fit_objective_loss_scale(const fit_objective *o) { return o->cfg.loss_scale; }

static int per_point(fit_objective *o, const double *p, double *r, pass_mode mode)
{
    o->resid = r;
    int rc = run_pass(o, p, mode);
    o->resid = NULL;
    if (rc != 0) return -1;
    for (size_t i = 0; i < o->n; i++)
        if (!isfinite(r[i])) return 1;
    return 0;
}

int fit_objective_residuals(fit_objective *o, const double *p, double *r)
{
    return per_point(o, p, r, PASS_RESID);
}

int fit_objective_grad_norms(fit_objective *o, const double *p, double *r)
{
    return per_point(o, p, r, PASS_GNORM);
}

int fit_objective_distances(fit_objective *o, const double *p, double *rms, double *max)
{
    if (o->n == 0) return 1;
    if (run_pass(o, p, PASS_DIST) != 0) return -1;
    double ss = 0, mx = 0;
    for (size_t b = 0; b < o->nblocks; b++) {
        const double *s = o->partial + b * o->slot;
        ss += s[0];
        mx = isnan(s[1]) || isnan(mx) ? NAN : fmax(mx, s[1]);
    }
    *rms = sqrt(ss / (double)o->n);
    *max = mx;
    return isfinite(*rms) ? 0 : 1;
}

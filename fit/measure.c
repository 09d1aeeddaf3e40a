/* measure.c - true point-to-surface distances and parameter uncertainties of a fitted
 * model (see measure.h).
 *
 * The first-order distance |f|/|grad f| is exact for a distance field but explodes where
 * the gradient vanishes (R-function edges, the flat parts of min/max fields). Here each
 * point is projected by Newton steps along the gradient; the projection is trusted when
 * it lands on the surface (first-order distance of the landing point below 1e-10 of the
 * search radius) at a distance that agrees with the first-order estimate within 1.5x,
 * and a sphere of radius 1/sqrt 2 of it shows no sign change.
 * Elsewhere a sphere search brackets the distance: spheres of shrinking radius (by
 * sqrt 2) around the point are sampled in FIT_SPHERE_DIRS directions until none shows a
 * sign change, and the crossings along the directions of the last one that did are found
 * by bisection, side by side. Every figure is the distance to a surface point actually
 * found, so an upper bound of the true distance.
 */
#include "alloc.h"
#include "linalg.h"
#include "measure.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "optim.h"
#include "threads.h"

/* A landing point counts as on the surface when its first-order distance is below this
 * fraction of the search radius. */
#define FIT_PROJ_TOL 1e-10
/* The Newton projection is trusted when its distance lies within this factor of the
 * first-order estimate at the point. */
#define FIT_PROJ_AGREE 1.5
/* ... and when no surface lies closer than its distance over this factor (a sphere
 * test), so that a kept projection is within this factor of the true distance. */
#define FIT_PROJ_VERIFY 1.4142135623730951
/* Projections shorter than this fraction of the search radius (the diagonal) are kept
 * without the sphere test: their error is below it, 1/100 of the verdict's threshold,
 * and most points of a clean cloud lie there (the test costs FIT_SPHERE_DIRS values). */
#define FIT_PROJ_VERIFY_FLOOR 1e-4
/* Bisection steps along a direction with a sign change (2^-40 of the radius). */
#define FIT_BISECT_STEPS 40
/* Directions of a sign change refined by bisection, at most. */
#define FIT_BISECT_DIRS 8
/* Gradient norms below this fraction of the median are left out of the uncertainty. */
#define FIT_SENS_GRAD_FLOOR 1e-8

/* Per-thread buffers: the model's scratch, the block's points and values. */
typedef struct dist_ws {
    void *scratch;
    double *buf;
    double *x, *y, *z, *f, *g;  /* FIT_BLOCK each (g: 3 FIT_BLOCK) */
    double *y0, *y1, *y2;       /* current Newton points */
    double f0[FIT_BLOCK], d1[FIT_BLOCK];
    int state[FIT_BLOCK];       /* 0 moving, 1 on the surface, -1 failed */
} dist_ws;

typedef struct dist_ctx {
    const fit_model *m;
    const double *params;
    const fit_points *pts;
    double radius;
    double dirs[3 * FIT_SPHERE_DIRS];
} dist_ctx;

static void fibonacci_sphere(double *d, int n)
{
    const double golden = 3.0 - sqrt(5.0);
    for (int k = 0; k < n; k++) {
        double z = 1.0 - (2.0 * k + 1.0) / n;
        double r = sqrt(fmax(0.0, 1.0 - z * z));
        double phi = golden * 3.14159265358979323846 * k;
        d[3 * k] = r * cos(phi);
        d[3 * k + 1] = r * sin(phi);
        d[3 * k + 2] = z;
    }
}

static int ws_init(const fit_model *m, dist_ws *w)
{
    memset(w, 0, sizeof *w);
    w->buf = frep_malloc(10 * FIT_BLOCK * sizeof *w->buf);
    if (w->buf == NULL) return -1;
    w->x = w->buf, w->y = w->x + FIT_BLOCK, w->z = w->y + FIT_BLOCK;
    w->f = w->z + FIT_BLOCK, w->g = w->f + FIT_BLOCK;
    w->y0 = w->g + 3 * FIT_BLOCK, w->y1 = w->y0 + FIT_BLOCK, w->y2 = w->y1 + FIT_BLOCK;
    if (m->scratch_new != NULL && (w->scratch = m->scratch_new(m->user)) == NULL) return -1;
    return 0;
}

static void ws_free(const fit_model *m, dist_ws *w)
{
    if (w->scratch != NULL && m->scratch_free != NULL) m->scratch_free(m->user, w->scratch);
    frep_free(w->buf);
}

static int eval(const dist_ctx *C, dist_ws *w, size_t n, const double *x, const double *y,
                const double *z, double *g)
{
    return C->m->eval(C->m->user, w->scratch, n, x, y, z, C->params, w->f, g, NULL);
}

/* Does the sphere of radius r around (px, py, pz) show a sign change against s0 in any
 * direction? Leaves the values in w->f. -1 when the model cannot be evaluated. */
static int sphere_crosses(const dist_ctx *C, dist_ws *w, const double *p, double s0, double r)
{
    for (int k = 0; k < FIT_SPHERE_DIRS; k++) {
        w->x[k] = p[0] + r * C->dirs[3 * k];
        w->y[k] = p[1] + r * C->dirs[3 * k + 1];
        w->z[k] = p[2] + r * C->dirs[3 * k + 2];
    }
    if (eval(C, w, FIT_SPHERE_DIRS, w->x, w->y, w->z, NULL) != 0) return -1;
    for (int k = 0; k < FIT_SPHERE_DIRS; k++)
        if (w->f[k] * s0 <= 0) return 1;
    return 0;
}

/* Distance from p to the first sign change within r along each of the nk directions
 * k[] (each with one on the sphere of radius r), by bisection, the least of them; r
 * when none can be narrowed.  The directions are bisected side by side, a point each
 * per evaluation (the same values as one by one). */
static double bisect(const dist_ctx *C, dist_ws *w, const double *p, double s0, const int *k,
                     int nk, double r)
{
    double a[FIT_BISECT_DIRS], b[FIT_BISECT_DIRS];
    for (int j = 0; j < nk; j++) a[j] = 0, b[j] = r;
    for (int it = 0; it < FIT_BISECT_STEPS; it++) {
        for (int j = 0; j < nk; j++) {
            double t = 0.5 * (a[j] + b[j]);
            w->x[j] = p[0] + t * C->dirs[3 * k[j]];
            w->y[j] = p[1] + t * C->dirs[3 * k[j] + 1];
            w->z[j] = p[2] + t * C->dirs[3 * k[j] + 2];
        }
        if (eval(C, w, (size_t)nk, w->x, w->y, w->z, NULL) != 0) break;
        for (int j = 0; j < nk; j++) {
            double t = 0.5 * (a[j] + b[j]);
            if (w->f[j] * s0 <= 0) b[j] = t;
            else a[j] = t;
        }
    }
    double d = r;
    for (int j = 0; j < nk; j++) d = fmin(d, b[j]);
    return d;
}

/* The sphere search from p (f(p) = f0 != 0) below the bound `upper` (a surface point is
 * known at that distance when `known`, else upper is the search radius). Sets *unres
 * when no surface lies within the radius. */
static double sphere_search(const dist_ctx *C, dist_ws *w, const double *p, double f0,
                            double upper, int known, int *unres, int *err)
{
    double s0 = f0 > 0 ? 1 : -1, best = upper;
    int c = sphere_crosses(C, w, p, s0, upper);
    if (c < 0) return *err = 1, upper;
    if (!c && !known) return *unres = 1, upper;
    int have = c;                   /* w->f holds the values of the sphere at best */
    double vals[FIT_SPHERE_DIRS];
    if (have) memcpy(vals, w->f, sizeof vals);
    for (int s = 0; s < FIT_SPHERE_STEPS; s++) {
        double r = best / sqrt(2.0);
        c = sphere_crosses(C, w, p, s0, r);
        if (c < 0) return *err = 1, best;
        if (!c) break;
        best = r;
        have = 1;
        memcpy(vals, w->f, sizeof vals);
    }
    if (!have) return best;         /* only the Newton point is known at `upper` */
    int dirs[FIT_BISECT_DIRS], used = 0;
    for (int k = 0; k < FIT_SPHERE_DIRS && used < FIT_BISECT_DIRS; k++)
        if (vals[k] * s0 <= 0) dirs[used++] = k;
    return fmin(bisect(C, w, p, s0, dirs, used, best), upper);
}

/* Distances of the points [i0, i0 + n) into out. Returns 0, or -1 when the model
 * cannot be evaluated. */
static int block_distances(const dist_ctx *C, dist_ws *w, size_t i0, size_t n, double *out,
                           size_t *searched, size_t *unresolved)
{
    const fit_points *P = C->pts;
    const double tol = FIT_PROJ_TOL * C->radius;
    memcpy(w->y0, P->x + i0, n * sizeof *w->y0);
    memcpy(w->y1, P->y + i0, n * sizeof *w->y1);
    memcpy(w->y2, P->z + i0, n * sizeof *w->y2);
    for (size_t i = 0; i < n; i++) w->state[i] = 0;
    for (int it = 0; it <= FIT_PROJ_ITERS; it++) {
        if (eval(C, w, n, w->y0, w->y1, w->y2, w->g) != 0) return -1;
        int moving = 0;
        for (size_t i = 0; i < n; i++) {
            if (w->state[i] != 0) continue;
            double gx = w->g[i], gy = w->g[n + i], gz = w->g[2 * n + i];
            double g2 = gx * gx + gy * gy + gz * gz, fv = w->f[i];
            if (it == 0) {
                w->f0[i] = fv;
                w->d1[i] = g2 > 0 ? fabs(fv) / sqrt(g2) : HUGE_VAL;
            }
            if (!isfinite(fv) || !isfinite(g2)) { w->state[i] = -1; continue; }
            if (fv == 0 || (g2 > 0 && fabs(fv) / sqrt(g2) <= tol)) { w->state[i] = 1; continue; }
            if (g2 == 0 || it == FIT_PROJ_ITERS) { w->state[i] = -1; continue; }
            double t = fv / g2;
            double step = fabs(t) * sqrt(g2);
            if (step > 0.25 * C->radius) t *= 0.25 * C->radius / step;
            w->y0[i] -= t * gx, w->y1[i] -= t * gy, w->y2[i] -= t * gz;
            double dx = w->y0[i] - P->x[i0 + i], dy = w->y1[i] - P->y[i0 + i],
                   dz = w->y2[i] - P->z[i0 + i];
            if (dx * dx + dy * dy + dz * dz > C->radius * C->radius) { w->state[i] = -1; continue; }
            moving = 1;
        }
        if (!moving) break;
    }
    int err = 0;
    for (size_t i = 0; i < n && !err; i++) {
        const double p[3] = {P->x[i0 + i], P->y[i0 + i], P->z[i0 + i]};
        double f0 = w->f0[i];
        if (f0 == 0) { out[i] = 0; continue; }
        double dn = HUGE_VAL;
        if (w->state[i] == 1) {
            double dx = w->y0[i] - p[0], dy = w->y1[i] - p[1], dz = w->y2[i] - p[2];
            dn = sqrt(dx * dx + dy * dy + dz * dz);
            if (dn <= FIT_PROJ_AGREE * w->d1[i] && dn * FIT_PROJ_AGREE >= w->d1[i]) {
                /* The estimate can be off as much as the landing point (near an edge
                 * of R-function slabs both overstate by 3-5x): kept only when the
                 * sphere of radius dn / FIT_PROJ_VERIFY shows no crossing. */
                int c = dn > FIT_PROJ_VERIFY_FLOOR * C->radius
                            ? sphere_crosses(C, w, p, f0 > 0 ? 1 : -1, dn / FIT_PROJ_VERIFY)
                            : 0;
                if (c < 0) { err = 1; break; }
                if (c == 0) {
                    out[i] = dn;
                    continue;
                }
            }
        }
        int known = dn < C->radius, unres = 0;
        (*searched)++;
        out[i] = sphere_search(C, w, p, f0, known ? dn : C->radius, known, &unres, &err);
        *unresolved += (size_t)unres;
    }
    return err ? -1 : 0;
}

int fit_distances(const fit_model *m, const double *params, const fit_points *pts,
                  double radius, int nthreads, double *dist, fit_distance_stats *st)
{
    memset(st, 0, sizeof *st);
    const size_t n = pts->n, nb = (n + FIT_BLOCK - 1) / FIT_BLOCK;
    if (n == 0) return 0;
    dist_ctx C = {m, params, pts, radius > 0 && isfinite(radius) ? radius : 1, {0}};
    fibonacci_sphere(C.dirs, FIT_SPHERE_DIRS);
    double *d = dist != NULL ? dist : frep_malloc(n * sizeof *d);
    size_t *cnt = frep_calloc(2 * nb, sizeof *cnt);
    int nt = frep_threads(nthreads);
    if ((size_t)nt > nb) nt = (int)nb;
    dist_ws *ws = frep_calloc((size_t)nt, sizeof *ws);
    int failed = d == NULL || cnt == NULL || ws == NULL;
    for (int t = 0; t < nt && !failed; t++) failed = ws_init(m, &ws[t]) != 0;
    if (!failed) {
        int bad = 0;
#ifdef _OPENMP
#pragma omp parallel for num_threads(nt) schedule(dynamic) reduction(|| : bad)
#endif
        for (size_t b = 0; b < nb; b++) {
            size_t i0 = b * FIT_BLOCK, k = n - i0 < FIT_BLOCK ? n - i0 : FIT_BLOCK;
            if (block_distances(&C, &ws[frep_thread_num()], i0, k, d + i0, &cnt[2 * b],
                                &cnt[2 * b + 1]) != 0)
                bad = 1;
        }
        failed = bad;
    }
    if (!failed) {
        double s = 0, mx = 0;
        for (size_t i = 0; i < n; i++) s += d[i] * d[i], mx = fmax(mx, d[i]);
        for (size_t b = 0; b < nb; b++) st->searched += cnt[2 * b], st->unresolved += cnt[2 * b + 1];
        st->rms = sqrt(s / (double)n);
        st->max = mx;
    }
    for (int t = 0; ws != NULL && t < nt; t++) ws_free(m, &ws[t]);
    frep_free(ws);
    frep_free(cnt);
    if (d != dist) frep_free(d);
    return failed ? -1 : 0;
}

/* Hoare's selection (measure.h). */
double fit_select_kth(double *v, size_t n, size_t k)
{
    long lo = 0, hi = (long)n - 1;
    while (lo < hi) {
        double pivot = v[lo + (hi - lo) / 2];
        long i = lo, j = hi;
        while (i <= j) {
            while (v[i] < pivot) i++;
            while (v[j] > pivot) j--;
            if (i <= j) {
                double t = v[i];
                v[i++] = v[j];
                v[j--] = t;
            }
        }
        if ((long)k <= j) hi = j;
        else if ((long)k >= i) lo = i;
        else break;
    }
    return v[k];
}

/* Solve for the diagonal of the inverse of the SPD matrix A (n x n, overwritten by its
 * Cholesky factor) into diag; -1 when A is not positive definite. */
static int inverse_diagonal(size_t n, double *A, double *diag, double *e)
{
    if (linalg_cholesky(n, A) != 0) return -1;
    for (size_t c = 0; c < n; c++) {
        for (size_t i = 0; i < n; i++) e[i] = i == c;
        linalg_cholesky_solve(n, A, e);
        diag[c] = e[c];
    }
    return 0;
}

int fit_uncertainty(const fit_model *m, const double *params, const fit_points *pts,
                    double cut, double *sens, double *sigma)
{
    const size_t n = pts->n, np = m->nparams;
    for (size_t j = 0; j < np; j++) sens[j] = 0, sigma[j] = HUGE_VAL;
    if (n == 0 || np == 0) return 0;
    double *f = frep_malloc((4 + np) * FIT_BLOCK * sizeof *f);
    double *gn = frep_malloc(n * sizeof *gn), *med = frep_malloc(n * sizeof *med);
    double *A = frep_calloc(np * np, sizeof *A), *B = frep_malloc(np * np * sizeof *B);
    double *e = frep_malloc(2 * np * sizeof *e);
    size_t *keep = frep_malloc(np * sizeof *keep);
    void *scratch = m->scratch_new != NULL ? m->scratch_new(m->user) : NULL;
    int rc = -1;
    if (!f || !gn || !med || !A || !B || !e || !keep || (m->scratch_new && !scratch)) goto out;
    double *g = f + FIT_BLOCK, *dp = g + 3 * FIT_BLOCK, rr = 0;
    /* Pass 1: gradient norms, for the floor. */
    for (size_t i0 = 0; i0 < n; i0 += FIT_BLOCK) {
        size_t k = n - i0 < FIT_BLOCK ? n - i0 : FIT_BLOCK;
        if (m->eval(m->user, scratch, k, pts->x + i0, pts->y + i0, pts->z + i0, params, f, g,
                    NULL) != 0)
            goto out;
        for (size_t i = 0; i < k; i++)
            gn[i0 + i] = sqrt(g[i] * g[i] + g[k + i] * g[k + i] + g[2 * k + i] * g[2 * k + i]);
    }
    memcpy(med, gn, n * sizeof *med);
    double floor = FIT_SENS_GRAD_FLOOR * fit_select_kth(med, n, n / 2);
    size_t used = 0;
    /* Pass 2: J^T J and the residuals, in point order. */
    for (size_t i0 = 0; i0 < n; i0 += FIT_BLOCK) {
        size_t k = n - i0 < FIT_BLOCK ? n - i0 : FIT_BLOCK;
        if (m->eval(m->user, scratch, k, pts->x + i0, pts->y + i0, pts->z + i0, params, f, NULL,
                    dp) != 0)
            goto out;
        for (size_t i = 0; i < k; i++) {
            double w = gn[i0 + i];
            if (!(w > floor) || !isfinite(f[i]) || !(fabs(f[i]) / w <= cut)) continue;
            used++;
            rr += (f[i] / w) * (f[i] / w);
            for (size_t a = 0; a < np; a++) {
                double ja = dp[a * k + i] / w;
                if (!isfinite(ja)) continue;
                for (size_t b = 0; b <= a; b++) A[a * np + b] += ja * dp[b * k + i] / w;
            }
        }
    }
    for (size_t a = 0; a < np; a++)
        for (size_t b = 0; b < a; b++) A[b * np + a] = A[a * np + b];
    size_t nk = 0;
    for (size_t j = 0; j < np; j++) {
        sens[j] = used ? sqrt(A[j * np + j] / (double)used) : 0;
        if (A[j * np + j] > 0 && isfinite(A[j * np + j])) keep[nk++] = j;
    }
    rc = 0;
    if (nk == 0 || used <= np) goto out;
    for (size_t a = 0; a < nk; a++)
        for (size_t b = 0; b < nk; b++) B[a * nk + b] = A[keep[a] * np + keep[b]];
    double s2 = rr / (double)(used - np);
    if (inverse_diagonal(nk, B, e + np, e) == 0)
        for (size_t a = 0; a < nk; a++)
            sigma[keep[a]] = e[np + a] >= 0 ? sqrt(s2 * e[np + a]) : HUGE_VAL;
out:
    if (scratch != NULL) m->scratch_free(m->user, scratch);
    frep_free(f), frep_free(gn), frep_free(med), frep_free(A), frep_free(B), frep_free(e);
    frep_free(keep);
    return rc;
}

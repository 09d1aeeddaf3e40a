/* optim.c - optimizers of the fitting engine: generalized simulated annealing, BFGS with
 * a strong-Wolfe line search and Levenberg-Marquardt, each honouring box bounds and a
 * shared evaluation/time budget (fit_control).  Called by fit/fit.c with objectives from
 * fit/objective.c; the unit tests drive them on textbook functions.
 */
#define _POSIX_C_SOURCE 200809L

#include "alloc.h"
#include "optim.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* pi, spelled out: M_PI is not part of C11. */
#define FIT_PI 3.14159265358979323846

/* ---- random numbers ------------------------------------------------------ */

double fit_rng_normal(frep_rng *r)
{
    /* 1 - u lies in (0, 1], so the logarithm is finite. */
    double u = 1.0 - frep_rng_unit(r), v = frep_rng_unit(r);
    return sqrt(-2.0 * log(u)) * cos(2.0 * FIT_PI * v);
}

/* ---- budget ------------------------------------------------------------------ */

double fit_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void fit_control_init(fit_control *c)
{
    memset(c, 0, sizeof *c);
    c->progress_interval = 0.2;
}

int fit_control_stop(const fit_control *c)
{
    if (c == NULL) return 0;
    if (c->out_of_memory) return 1;
    if (c->interrupt != NULL && *c->interrupt) return 1;
    if (c->max_evals > 0 && c->evals >= c->max_evals) return 1;
    /* The clock is read at most once per call; callers check once per iteration. */
    if (c->deadline > 0 && fit_now() >= c->deadline) return 1;
    return 0;
}

static void report(fit_control *c, fit_phase ph, double t, double best, int force)
{
    if (c == NULL || c->progress == NULL) return;
    double now = fit_now();
    if (!force && now - c->last_progress < c->progress_interval) return;
    c->last_progress = now;
    c->progress(c->progress_user, ph, t, best);
}

static double call(fit_fn fn, void *user, const double *x, double *g, fit_control *c)
{
    if (c != NULL) c->evals++;
    double f = fn(user, x, g);
    return isfinite(f) ? f : HUGE_VAL;
}

const char *fit_status_name(fit_status s)
{
    switch (s) {
    case FIT_CONVERGED: return "converged";
    case FIT_MAXITER: return "iteration limit";
    case FIT_STOPPED: return "stopped";
    case FIT_FAILED: return "failed";
    case FIT_NOMEM: return "out of memory";
    }
    return "?";
}

/* A phase's work arrays could not be allocated: every phase sharing c stops. */
static fit_status out_of_memory(fit_control *c)
{
    if (c != NULL) c->out_of_memory = 1;
    return FIT_NOMEM;
}

static double lo_of(const double *lo, size_t i) { return lo != NULL ? lo[i] : -HUGE_VAL; }
static double hi_of(const double *hi, size_t i) { return hi != NULL ? hi[i] : HUGE_VAL; }

static double clampd(double v, double lo, double hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

static double dot(size_t n, const double *a, const double *b)
{
    double s = 0;
    for (size_t i = 0; i < n; i++) s += a[i] * b[i];
    return s;
}

static double norm_inf(size_t n, const double *a)
{
    double m = 0;
    for (size_t i = 0; i < n; i++) m = fmax(m, fabs(a[i]));
    return m;
}

/* ---- BFGS ------------------------------------------------------------------------ */

void fit_qn_options_init(fit_qn_options *o)
{
    o->max_iter = 500;
    o->gtol = 1e-10;
    o->ftol = 1e-13;
    o->xtol = 1e-12;
}

/* Line search constants of Nocedal & Wright (ch. 3): sufficient decrease c1 and curvature
 * c2 (0.9 suits quasi-Newton directions); trial limits keep a bad function from eating
 * the budget. */
#define LS_C1 1e-4
#define LS_C2 0.9
#define LS_MAX_BRACKET 30
#define LS_MAX_ZOOM 30

typedef struct ls_ctx {
    fit_fn fn;
    void *user;
    size_t n;
    const double *x, *d, *lo, *hi;
    double *xt, *gt;        /* trial point and gradient */
    fit_control *c;
} ls_ctx;

/* phi(a) = f(x + a d) (projected on the bounds, which only matters at a = amax through
 * rounding); writes phi'(a) = g . d. */
static double ls_eval(ls_ctx *L, double a, double *dphi)
{
    for (size_t i = 0; i < L->n; i++)
        L->xt[i] = clampd(L->x[i] + a * L->d[i], lo_of(L->lo, i), hi_of(L->hi, i));
    double f = call(L->fn, L->user, L->xt, L->gt, L->c);
    *dphi = f < HUGE_VAL ? dot(L->n, L->gt, L->d) : 0;
    return f;
}

/* Minimizer of the cubic through (a, fa, da), (b, fb, db), or NaN when it has none. */
static double cubic_min(double a, double fa, double da, double b, double fb, double db)
{
    double d1 = da + db - 3 * (fa - fb) / (a - b);
    double disc = d1 * d1 - da * db;
    if (!(disc >= 0)) return NAN;
    double d2 = copysign(sqrt(disc), b - a);
    double den = db - da + 2 * d2;
    if (den == 0) return NAN;
    return b - (b - a) * (db + d2 - d1) / den;
}

/* Strong-Wolfe line search (Nocedal & Wright, algorithms 3.5 and 3.6) on [0, amax].
 * Returns the accepted step (> 0) with its value in *fa and the point/gradient in
 * xout/gout, or 0 when no step decreased f. */
static double line_search(ls_ctx *L, double f0, double dphi0, double a1, double amax,
                          double *fa, double *xout, double *gout)
{
    size_t n = L->n;
    double a_prev = 0, f_prev = f0, d_prev = dphi0;
    double a = fmin(a1, amax);
    double best_a = 0, best_f = f0;
    double alo = 0, flo = f0, dlo = dphi0, ahi = 0, fhi = 0, dhi = 0;
    double f_acc = f0;
    int zoom = 0;

    for (int i = 0; i < LS_MAX_BRACKET && !zoom; i++) {
        double da;
        double f = ls_eval(L, a, &da);
        if (f == HUGE_VAL) {            /* infeasible: shrink toward the last good step */
            amax = a;
            a = 0.5 * (a_prev + a);
            if (a - a_prev <= DBL_EPSILON * fmax(1, a)) break;
            continue;
        }
        if (f <= f0 + LS_C1 * a * dphi0 && f < best_f) {
            best_a = a, best_f = f;
            memcpy(xout, L->xt, n * sizeof *xout);
            memcpy(gout, L->gt, n * sizeof *gout);
        }
        if (f > f0 + LS_C1 * a * dphi0 || (i > 0 && f >= f_prev)) {
            alo = a_prev, flo = f_prev, dlo = d_prev, ahi = a, fhi = f, dhi = da;
            zoom = 1;
            break;
        }
        if (fabs(da) <= -LS_C2 * dphi0) { f_acc = f; goto accept; }
        if (da >= 0) {
            alo = a, flo = f, dlo = da, ahi = a_prev, fhi = f_prev, dhi = d_prev;
            zoom = 1;
            break;
        }
        if (a >= amax) { f_acc = f; goto accept; }  /* a bound stops the step */
        if (fit_control_stop(L->c)) break;
        a_prev = a, f_prev = f, d_prev = da;
        a = fmin(4 * a, amax);
    }
    for (int i = 0; zoom && i < LS_MAX_ZOOM; i++) {
        double lo = fmin(alo, ahi), hi = fmax(alo, ahi), w = hi - lo;
        if (w <= DBL_EPSILON * fmax(1, hi)) break;
        double aj = cubic_min(alo, flo, dlo, ahi, fhi, dhi);
        if (!(aj >= lo + 0.1 * w && aj <= hi - 0.1 * w)) aj = 0.5 * (alo + ahi);
        double dj;
        double f = ls_eval(L, aj, &dj);
        if (f <= f0 + LS_C1 * aj * dphi0 && f < best_f) {
            best_a = aj, best_f = f;
            memcpy(xout, L->xt, n * sizeof *xout);
            memcpy(gout, L->gt, n * sizeof *gout);
        }
        if (f > f0 + LS_C1 * aj * dphi0 || f >= flo) {
            ahi = aj, fhi = f, dhi = dj;
        } else {
            if (fabs(dj) <= -LS_C2 * dphi0) break;  /* best_* holds this point */
            if (dj * (ahi - alo) >= 0) ahi = alo, fhi = flo, dhi = dlo;
            alo = aj, flo = f, dlo = dj;
        }
        if (fit_control_stop(L->c)) break;
    }
    *fa = best_f;
    return best_a;
accept:
    memcpy(xout, L->xt, n * sizeof *xout);
    memcpy(gout, L->gt, n * sizeof *gout);
    *fa = f_acc;
    return a;
}

/* Gradient with the components of held variables (at a bound, gradient pointing out of
 * the box) set to zero: the direction the box allows. */
static void project_grad(size_t n, const double *x, const double *g, const double *lo,
                         const double *hi, double *pg)
{
    for (size_t i = 0; i < n; i++) {
        int held = (x[i] <= lo_of(lo, i) && g[i] > 0) || (x[i] >= hi_of(hi, i) && g[i] < 0);
        pg[i] = held ? 0 : g[i];
    }
}

static void set_identity(size_t n, double *H, double scale)
{
    memset(H, 0, n * n * sizeof *H);
    for (size_t i = 0; i < n; i++) H[i * n + i] = scale;
}

fit_status fit_bfgs(fit_fn fn, void *user, size_t n, double *x, const double *lo,
                    const double *hi, const fit_qn_options *opt, fit_control *c, double *fx,
                    int *iterations)
{
    fit_qn_options defaults;
    if (opt == NULL) fit_qn_options_init(&defaults), opt = &defaults;
    if (iterations) *iterations = 0;
    if (n == 0 || n > FIT_MAX_PARAMS) return FIT_FAILED;
    double *mem = frep_malloc((n * n + 8 * n) * sizeof *mem);
    if (mem == NULL) return out_of_memory(c);
    double *H = mem, *g = H + n * n, *pg = g + n, *d = pg + n, *xn = d + n, *gn = xn + n;
    double *xt = gn + n, *gt = xt + n, *Hy = gt + n;

    for (size_t i = 0; i < n; i++) x[i] = clampd(x[i], lo_of(lo, i), hi_of(hi, i));
    double f = call(fn, user, x, g, c);
    if (f == HUGE_VAL) {
        frep_free(mem);
        *fx = f;
        return FIT_FAILED;
    }
    ls_ctx L = {fn, user, n, x, d, lo, hi, xt, gt, c};
    fit_status st = FIT_MAXITER;
    int fresh = 1;      /* H is a (scaled) identity: no curvature information yet */
    int small = 0;      /* consecutive iterations with a tiny decrease */
    set_identity(n, H, 1);
    int it;
    for (it = 0; it < opt->max_iter; it++) {
        report(c, FIT_PHASE_QN, 0, f, 0);
        if (fit_control_stop(c)) {
            st = FIT_STOPPED;
            break;
        }
        project_grad(n, x, g, lo, hi, pg);
        double gmax = norm_inf(n, pg);
        if (gmax <= opt->gtol) {
            st = FIT_CONVERGED;
            break;
        }
        for (size_t i = 0; i < n; i++) {
            double s = 0;
            for (size_t j = 0; j < n; j++) s -= H[i * n + j] * pg[j];
            d[i] = pg[i] == 0 && g[i] != 0 ? 0 : s;
        }
        double dphi0 = dot(n, g, d);
        if (!(dphi0 < 0)) {             /* not a descent direction: steepest descent */
            set_identity(n, H, 1);
            fresh = 1;
            for (size_t i = 0; i < n; i++) d[i] = -pg[i];
            dphi0 = dot(n, g, d);
        }
        /* Longest step inside the box; a component already at its bound and moving
         * outwards was zeroed above. */
        double amax = HUGE_VAL;
        for (size_t i = 0; i < n; i++) {
            if (d[i] < 0 && isfinite(lo_of(lo, i)))
                amax = fmin(amax, (lo_of(lo, i) - x[i]) / d[i]);
            else if (d[i] > 0 && isfinite(hi_of(hi, i)))
                amax = fmin(amax, (hi_of(hi, i) - x[i]) / d[i]);
        }
        if (!(amax > 0)) amax = 0;
        /* Without curvature information the first trial step moves at most one unit. */
        double a1 = fresh ? fmin(1.0, 1.0 / norm_inf(n, d)) : 1.0;
        double fnew;
        double a = amax > 0 ? line_search(&L, f, dphi0, a1, amax, &fnew, xn, gn) : 0;
        if (a == 0) {
            if (fit_control_stop(c)) {
                st = FIT_STOPPED;
                break;
            }
            if (!fresh) {               /* stale curvature: retry along -g */
                set_identity(n, H, 1);
                fresh = 1;
                continue;
            }
            st = FIT_CONVERGED;         /* no decrease along steepest descent either */
            break;
        }
        double *s = d, *y = Hy;         /* reuse: d is not needed after the line search */
        double smax = 0, xmax = 0;
        for (size_t i = 0; i < n; i++) {
            s[i] = xn[i] - x[i];
            smax = fmax(smax, fabs(s[i]));
            xmax = fmax(xmax, fabs(x[i]));
        }
        double df = f - fnew;
        memcpy(x, xn, n * sizeof *x);
        for (size_t i = 0; i < n; i++) {
            double yi = gn[i] - g[i];
            g[i] = gn[i];
            gt[i] = yi;                 /* y, kept in gt (free after the line search) */
        }
        y = gt;
        f = fnew;
        double sy = dot(n, s, y), yy = dot(n, y, y);
        if (sy > 1e-12 * sqrt(dot(n, s, s) * yy)) {
            if (fresh) {                /* Nocedal & Wright (6.20): scale before the update */
                set_identity(n, H, sy / yy);
                fresh = 0;
            }
            double rho = 1 / sy;
            for (size_t i = 0; i < n; i++) {
                double t = 0;
                for (size_t j = 0; j < n; j++) t += H[i * n + j] * y[j];
                Hy[i] = t;
            }
            double yHy = dot(n, y, Hy);
            for (size_t i = 0; i < n; i++)
                for (size_t j = 0; j < n; j++)
                    H[i * n + j] += rho * ((1 + rho * yHy) * s[i] * s[j] -
                                           (Hy[i] * s[j] + s[i] * Hy[j]));
        }
        if (smax <= opt->xtol * (1 + xmax)) {
            st = FIT_CONVERGED;
            break;
        }
        if (df <= opt->ftol * fmax(fabs(f), DBL_MIN)) {
            if (++small >= 2) {
                st = FIT_CONVERGED;
                break;
            }
        } else {
            small = 0;
        }
    }
    if (iterations) *iterations = it;
    *fx = f;
    report(c, FIT_PHASE_QN, 0, f, 1);
    frep_free(mem);
    return st;
}

/* ---- Levenberg-Marquardt ------------------------------------------------------- */

void fit_lm_options_init(fit_lm_options *o)
{
    o->max_iter = 200;
    o->ftol = 1e-14;
    o->gtol = 1e-14;
    o->xtol = 1e-12;
}

/* Solve the SPD system A x = b in place by Cholesky (A is overwritten). Returns 0, or -1
 * when A is not positive definite. */
static int cholesky_solve(size_t n, double *A, double *b)
{
    for (size_t j = 0; j < n; j++) {
        double s = A[j * n + j];
        for (size_t k = 0; k < j; k++) s -= A[j * n + k] * A[j * n + k];
        if (!(s > 0)) return -1;
        double l = sqrt(s);
        A[j * n + j] = l;
        for (size_t i = j + 1; i < n; i++) {
            double t = A[i * n + j];
            for (size_t k = 0; k < j; k++) t -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = t / l;
        }
    }
    for (size_t i = 0; i < n; i++) {
        double t = b[i];
        for (size_t k = 0; k < i; k++) t -= A[i * n + k] * b[k];
        b[i] = t / A[i * n + i];
    }
    for (size_t i = n; i-- > 0;) {
        double t = b[i];
        for (size_t k = i + 1; k < n; k++) t -= A[k * n + i] * b[k];
        b[i] = t / A[i * n + i];
    }
    return 0;
}

/* Damping range: below LM_LAMBDA_MIN the step is plain Gauss-Newton already; above
 * LM_LAMBDA_MAX steps are too short to matter, so the search has stalled. */
#define LM_LAMBDA_MIN 1e-15
#define LM_LAMBDA_MAX 1e16

fit_status fit_lm(fit_lsq_fn fn, void *user, size_t n, double *x, const double *lo,
                  const double *hi, const fit_lm_options *opt, fit_control *c, double *fx,
                  int *iterations)
{
    fit_lm_options defaults;
    if (opt == NULL) fit_lm_options_init(&defaults), opt = &defaults;
    if (iterations) *iterations = 0;
    if (n == 0 || n > FIT_MAX_PARAMS) return FIT_FAILED;
    double *mem = frep_malloc((3 * n * n + 4 * n) * sizeof *mem);
    if (mem == NULL) return out_of_memory(c);
    double *A = mem, *An = A + n * n, *M = An + n * n, *b = M + n * n, *bn = b + n;
    double *delta = bn + n, *xn = delta + n;

    for (size_t i = 0; i < n; i++) x[i] = clampd(x[i], lo_of(lo, i), hi_of(hi, i));
    if (c) c->evals++;
    double cost = fn(user, x, A, b);
    if (!isfinite(cost)) {
        frep_free(mem);
        *fx = HUGE_VAL;
        return FIT_FAILED;
    }
    double lambda = 1e-3;
    fit_status st = FIT_MAXITER;
    int it;
    for (it = 0; it < opt->max_iter; it++) {
        report(c, FIT_PHASE_LM, lambda, cost, 0);
        if (fit_control_stop(c)) {
            st = FIT_STOPPED;
            break;
        }
        double gmax = 0, dmax = 0;
        for (size_t i = 0; i < n; i++) {
            int held = (x[i] <= lo_of(lo, i) && b[i] < 0) || (x[i] >= hi_of(hi, i) && b[i] > 0);
            if (!held) gmax = fmax(gmax, fabs(b[i]));
            dmax = fmax(dmax, A[i * n + i]);
        }
        if (gmax <= opt->gtol) {
            st = FIT_CONVERGED;
            break;
        }
        memcpy(M, A, n * n * sizeof *M);
        for (size_t i = 0; i < n; i++) {
            /* Marquardt scaling; a parameter the residuals ignore gets a floor. */
            double dii = fmax(A[i * n + i], 1e-12 * fmax(dmax, DBL_MIN));
            M[i * n + i] += lambda * dii;
            delta[i] = -b[i];
        }
        if (cholesky_solve(n, M, delta) != 0) {
            lambda *= 10;
            if (lambda > LM_LAMBDA_MAX) {
                st = FIT_CONVERGED;
                break;
            }
            continue;
        }
        double smax = 0, xmax = 0;
        for (size_t i = 0; i < n; i++) {
            xn[i] = clampd(x[i] + delta[i], lo_of(lo, i), hi_of(hi, i));
            smax = fmax(smax, fabs(xn[i] - x[i]));
            xmax = fmax(xmax, fabs(x[i]));
        }
        if (c) c->evals++;
        double cn = fn(user, xn, An, bn);
        if (isfinite(cn) && cn < cost) {
            double dc = cost - cn;
            memcpy(x, xn, n * sizeof *x);
            memcpy(A, An, n * n * sizeof *A);
            memcpy(b, bn, n * sizeof *b);
            cost = cn;
            lambda = fmax(lambda / 10, LM_LAMBDA_MIN);
            if (dc <= opt->ftol * cost || smax <= opt->xtol * (1 + xmax)) {
                st = FIT_CONVERGED;
                it++;
                break;
            }
        } else {
            lambda *= 10;
            if (lambda > LM_LAMBDA_MAX || smax <= opt->xtol * (1 + xmax) * 1e-3) {
                st = FIT_CONVERGED;
                break;
            }
        }
    }
    if (iterations) *iterations = it;
    *fx = cost;
    report(c, FIT_PHASE_LM, 0, cost, 1);
    frep_free(mem);
    return st;
}

/* ---- generalized simulated annealing ------------------------------------------- */

void fit_sa_options_init(fit_sa_options *o)
{
    o->qv = 2.62;
    o->qa = -5.0;
    o->t0 = 5230.0;
    o->restart_ratio = 2e-5;
    o->max_iter = 1000;
    o->stall_iter = 40;
    o->rel_improve = 1e-4;
    o->threshold = -HUGE_VAL;
    o->local = NULL;
    o->local_user = NULL;
    o->local_period = 10;
    o->bound_stall_iter = 0;
    o->chains = 1;
}

/* Relative distance to a bound under which a coordinate counts as on it (BFGS's
 * projected active set puts held variables exactly on the bound). */
#define SA_ON_BOUND 1e-9

static int on_bound(size_t n, const double *x, const double *lo, const double *hi)
{
    for (size_t i = 0; i < n; i++) {
        double tol = SA_ON_BOUND * (hi[i] - lo[i]);
        if (x[i] <= lo[i] + tol || x[i] >= hi[i] - tol) return 1;
    }
    return 0;
}

/* Visits farther than this (in parameter units) are clipped before wrapping into the box:
 * the heavy tail can produce values whose wrap-around loses all precision. */
#define SA_TAIL_LIMIT 1e8
/* Attempts to find a finite objective for a random (re)start before giving up. */
#define SA_MAX_START_TRIES 100

/* Constants of the Tsallis visiting distribution that do not depend on the temperature
 * (Tsallis & Stariolo 1996; sampled by Mantegna's method as a ratio of normals). */
typedef struct visit_consts {
    double qv, f2, f3, f5, f6;
} visit_consts;

static void visit_init(visit_consts *v, double qv)
{
    v->qv = qv;
    v->f2 = exp((4.0 - qv) * log(qv - 1.0));
    v->f3 = exp((2.0 - qv) * log(2.0) / (qv - 1.0));
    v->f5 = 1.0 / (qv - 1.0) - 0.5;
    double d1 = 2.0 - v->f5;
    v->f6 = FIT_PI * (1.0 - v->f5) / sin(FIT_PI * (1.0 - v->f5)) / exp(lgamma(d1));
}

/* Width of the distribution at temperature t. */
static double visit_sigma(const visit_consts *v, double t)
{
    double qv = v->qv;
    double f1 = exp(log(t) / (qv - 1.0));
    double f4 = sqrt(FIT_PI) * f1 * v->f2 / (v->f3 * (3.0 - qv));
    return exp(-(qv - 1.0) * log(v->f6 / f4) / (3.0 - qv));
}

static double visit_draw(const visit_consts *v, double sigma, frep_rng *r)
{
    double a = sigma * fit_rng_normal(r);
    double b = fabs(fit_rng_normal(r));
    double den = exp((v->qv - 1.0) * log(b) / (3.0 - v->qv));
    double s = a / den;
    if (!isfinite(s) || fabs(s) > SA_TAIL_LIMIT) s = copysign(SA_TAIL_LIMIT, a) * frep_rng_unit(r);
    return s;
}

/* Wrap v into [lo, hi): the box is a torus for the visiting moves. */
static double wrap(double v, double lo, double hi)
{
    double w = hi - lo;
    double t = fmod(v - lo, w);
    if (t < 0) t += w;
    double r = lo + t;
    return r < hi ? r : lo;
}

static void random_point(size_t n, double *x, const double *lo, const double *hi, frep_rng *r)
{
    for (size_t i = 0; i < n; i++) x[i] = lo[i] + (hi[i] - lo[i]) * frep_rng_unit(r);
}

/* State of one annealing chain. */
typedef struct sa_chain {
    double *cur, *best;     /* current point, the chain's best */
    double e, ebest;
} sa_chain;

/* Start a chain at x (when `from_x`) or at a random point with a finite objective, and
 * polish it first: a start near the answer then is the answer, and the chain only has
 * to beat it. Returns 0, or -1 when no finite objective was found. */
static int sa_chain_start(sa_chain *ch, fit_fn fn, void *user, size_t n, const double *x,
                          int from_x, const double *lo, const double *hi,
                          const fit_sa_options *opt, frep_rng *rng, fit_control *c,
                          double *trial)
{
    if (from_x) memcpy(ch->cur, x, n * sizeof *ch->cur);
    else random_point(n, ch->cur, lo, hi, rng);
    double e = call(fn, user, ch->cur, NULL, c);
    for (int k = 0; e == HUGE_VAL && k < SA_MAX_START_TRIES && !fit_control_stop(c); k++) {
        random_point(n, ch->cur, lo, hi, rng);
        e = call(fn, user, ch->cur, NULL, c);
    }
    if (e == HUGE_VAL) return -1;
    if (opt->local != NULL && !fit_control_stop(c)) {
        memcpy(trial, ch->cur, n * sizeof *trial);
        double el;
        if (opt->local(opt->local_user, trial, &el) == 0 && el < e) {
            memcpy(ch->cur, trial, n * sizeof *ch->cur);
            e = el;
        }
    }
    memcpy(ch->best, ch->cur, n * sizeof *ch->best);
    ch->e = ch->ebest = e;
    return 0;
}

fit_status fit_sa(fit_fn fn, void *user, size_t n, double *x, const double *lo,
                  const double *hi, const fit_sa_options *opt, frep_rng *rng, fit_control *c,
                  double *fx, long *iterations)
{
    fit_sa_options defaults;
    if (opt == NULL) fit_sa_options_init(&defaults), opt = &defaults;
    if (iterations) *iterations = 0;
    *fx = HUGE_VAL;
    if (n == 0 || n > FIT_MAX_PARAMS || lo == NULL || hi == NULL) return FIT_FAILED;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(lo[i]) || !isfinite(hi[i]) || !(lo[i] < hi[i])) return FIT_FAILED;
    if (!(opt->qv > 1 && opt->qv < 3) || !(opt->qa < 1) || !(opt->t0 > 0)) return FIT_FAILED;

    double *mem = frep_malloc(4 * n * sizeof *mem);
    if (mem == NULL) return out_of_memory(c);
    double *trial = mem, *best = trial + n;
    sa_chain ch = {best + n, best + 2 * n, HUGE_VAL, HUGE_VAL};
    visit_consts vc;
    visit_init(&vc, opt->qv);

    int inside = 1;
    for (size_t i = 0; i < n; i++) inside &= x[i] >= lo[i] && x[i] <= hi[i];
    double ebest = HUGE_VAL;
    const double t1 = exp((opt->qv - 1.0) * log(2.0)) - 1.0;
    const long nchains = opt->chains > 0 ? opt->chains : 1;
    long total = 0;
    fit_status st = FIT_MAXITER;
    int stopped = 0;

    for (long chain = 0; chain < nchains && !stopped; chain++) {
        if (chain > 0 && fit_control_stop(c)) {
            st = FIT_STOPPED;
            break;
        }
        if (sa_chain_start(&ch, fn, user, n, x, chain == 0 && inside, lo, hi, opt, rng, c,
                           trial) != 0) {
            if (chain == 0) {
                frep_free(mem);
                return FIT_FAILED;
            }
            break;
        }
        if (ch.ebest < ebest) {
            ebest = ch.ebest;
            memcpy(best, ch.best, n * sizeof *best);
        }
        double e = ch.e, emark = ch.ebest;
        double *cur = ch.cur;
        long step = 0, last_gain = 0, quiet = 0, it;
        st = FIT_MAXITER;
        for (it = 0; it < opt->max_iter; it++, total++) {
            double t2 = exp((opt->qv - 1.0) * log((double)step + 2.0)) - 1.0;
            double temp = opt->t0 * t1 / t2;
            if (temp < opt->t0 * opt->restart_ratio) {     /* cold: restart elsewhere */
                step = 0;
                temp = opt->t0;
                double er = HUGE_VAL;
                for (int k = 0; er == HUGE_VAL && k < SA_MAX_START_TRIES; k++) {
                    random_point(n, trial, lo, hi, rng);
                    er = call(fn, user, trial, NULL, c);
                }
                if (er < HUGE_VAL) {
                    memcpy(cur, trial, n * sizeof *cur);
                    e = er;
                }
            }
            double tstep = temp / (double)(step + 1);
            double sigma = visit_sigma(&vc, temp);
            /* One iteration: n moves of all coordinates, then n moves of one coordinate. */
            int found = 0;
            for (size_t j = 0; j < 2 * n; j++) {
                memcpy(trial, cur, n * sizeof *trial);
                if (j < n) {
                    for (size_t i = 0; i < n; i++)
                        trial[i] = wrap(cur[i] + visit_draw(&vc, sigma, rng), lo[i], hi[i]);
                } else {
                    size_t i = j - n;
                    trial[i] = wrap(cur[i] + visit_draw(&vc, sigma, rng), lo[i], hi[i]);
                }
                double et = call(fn, user, trial, NULL, c);
                int accept;
                if (et < e) {
                    accept = 1;
                } else {
                    double pq = 1.0 - (1.0 - opt->qa) * (et - e) / tstep;
                    double p = pq <= 0 ? 0 : exp(log(pq) / (1.0 - opt->qa));
                    accept = frep_rng_unit(rng) <= p && et < HUGE_VAL;
                }
                if (accept) {
                    memcpy(cur, trial, n * sizeof *cur);
                    e = et;
                    if (e < ch.ebest) {
                        ch.ebest = e;
                        memcpy(ch.best, cur, n * sizeof *ch.best);
                        found = 1;
                    }
                }
            }
            quiet = found ? 0 : quiet + 1;
            int suspect = on_bound(n, ch.best, lo, hi);
            long period = opt->local_period;
            long stall = suspect && opt->bound_stall_iter > 0 ? opt->bound_stall_iter
                                                              : opt->stall_iter;
            int probe = period > 0 && quiet >= period;
            if ((found || probe) && opt->local != NULL && !fit_control_stop(c)) {
                memcpy(trial, found ? ch.best : cur, n * sizeof *trial);
                quiet = 0;
                double el;
                if (opt->local(opt->local_user, trial, &el) == 0 && el < ch.ebest) {
                    ch.ebest = e = el;
                    memcpy(ch.best, trial, n * sizeof *ch.best);
                    memcpy(cur, trial, n * sizeof *cur);
                }
            }
            if (ch.ebest < ebest) {
                ebest = ch.ebest;
                memcpy(best, ch.best, n * sizeof *best);
            }
            step++;
            report(c, FIT_PHASE_SA, temp, ebest, 0);
            if (ch.ebest < emark - opt->rel_improve * fabs(emark) || ch.ebest == 0) {
                emark = ch.ebest;
                last_gain = it;
            }
            if (ebest <= opt->threshold) {
                st = FIT_CONVERGED;
                stopped = 1;
                it++, total++;
                break;
            }
            if (stall > 0 && it - last_gain >= stall) {
                st = FIT_CONVERGED;
                it++, total++;
                break;
            }
            if (fit_control_stop(c)) {
                st = FIT_STOPPED;
                stopped = 1;
                it++, total++;
                break;
            }
        }
    }
    if (iterations) *iterations = total;
    memcpy(x, best, n * sizeof *x);
    *fx = ebest;
    report(c, FIT_PHASE_SA, 0, ebest, 1);
    frep_free(mem);
    return st;
}

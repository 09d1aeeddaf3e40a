/* optim.c - optimizers of the fitting engine: generalized simulated annealing, BFGS with
 * a strong-Wolfe line search and Levenberg-Marquardt, each honouring box bounds and a
 * shared evaluation/time budget (fit_control).  Called by fit/fit.c with objectives from
 * fit/objective.c; the unit tests drive them on textbook functions.
 */
#define _POSIX_C_SOURCE 200809L

#include "alloc.h"
#include "linalg.h"
#include "optim.h"
#include "util.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>


/* ---- budget ------------------------------------------------------------------ */

void fit_control_init(fit_control *c)
{
    memset(c, 0, sizeof *c);
    c->progress_interval = 0.2;
}

int fit_control_cancelled(fit_control *c)
{
    if (c == NULL) return 0;
    if (c->cancelled) return 1;
    if (c->interrupt != NULL && *c->interrupt) return 1;
    if (c->cancel != NULL) {
        double now = frep_now_seconds();
        if (now >= c->next_cancel) {
            c->next_cancel = now + FIT_CANCEL_POLL_SECONDS;
            if (c->cancel(c->cancel_user)) c->cancelled = 1;
        }
    }
    return c->cancelled;
}

int fit_control_stop(fit_control *c)
{
    if (c == NULL) return 0;
    if (c->out_of_memory || fit_control_cancelled(c)) return 1;
    if (c->max_evals > 0 && c->evals >= c->max_evals) return 1;
    /* The clock is read at most once per call; callers check once per iteration. */
    if (c->deadline > 0 && frep_now_seconds() >= c->deadline) return 1;
    return 0;
}

static void report(fit_control *c, fit_phase ph, long it, double t, double best, int force)
{
    if (c == NULL || c->progress == NULL) return;
    double now = frep_now_seconds();
    if (!force && now - c->last_progress < c->progress_interval) return;
    c->last_progress = now;
    c->progress(c->progress_user, ph, it, t, best);
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
    case FIT_STALLED: return "not converged (the optimality test does not pass)";
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
    o->dtol = 1e-10;
    o->dtol_abs = 1e-12;
    o->max_restarts = 3;
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
    const double *g0;       /* gradient at x */
    double *xt, *gt;        /* trial point and gradient */
    double lin;             /* g0 . (xt - x): the first-order change to the last trial */
    fit_control *c;
} ls_ctx;

/* phi(a) = f(P(x + a d)), P the projection on the bounds: past a component's breakpoint
 * that component stays on its bound and the others go on. Writes the right derivative
 * phi'(a) = sum of g_i d_i over the components not on their bound, and L->lin. */
static double ls_eval(ls_ctx *L, double a, double *dphi)
{
    for (size_t i = 0; i < L->n; i++)
        L->xt[i] = clampd(L->x[i] + a * L->d[i], lo_of(L->lo, i), hi_of(L->hi, i));
    double f = call(L->fn, L->user, L->xt, L->gt, L->c);
    double dp = 0, lin = 0;
    for (size_t i = 0; i < L->n; i++) {
        double free_i = L->x[i] + a * L->d[i];
        if (free_i > lo_of(L->lo, i) && free_i < hi_of(L->hi, i)) dp += L->gt[i] * L->d[i];
        lin += L->g0[i] * (L->xt[i] - L->x[i]);
    }
    *dphi = f < HUGE_VAL ? dp : 0;
    L->lin = lin;
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

/* Strong-Wolfe line search (Nocedal & Wright, algorithms 3.5 and 3.6) on [0, amax]: a
 * bracketing phase with growing steps, then a zoom into the bracket it found. */
typedef struct ls_search {
    double f0, dphi0;           /* phi(0), phi'(0) < 0 */
    double best_a, best_f;      /* lowest trial with sufficient decrease (0, f0: none) */
    double *xout, *gout;        /* its point and gradient */
    double alo, flo, dlo;       /* the bracket of the zoom: the end with the lower value */
    double ahi, fhi, dhi;       /* and the other end */
} ls_search;

typedef enum ls_outcome {
    LS_ACCEPT,      /* the last trial satisfies the strong Wolfe conditions or hit amax */
    LS_ZOOM,        /* a bracket containing acceptable steps was found */
    LS_GIVE_UP      /* trial limit, no feasible step or the budget: keep the best trial */
} ls_outcome;

/* Remember the trial (a, f) at L->xt when it decreases f sufficiently and is the lowest. */
static void ls_keep(const ls_ctx *L, ls_search *S, double a, double f)
{
    if (f <= S->f0 + LS_C1 * L->lin && f < S->best_f) {
        S->best_a = a, S->best_f = f;
        memcpy(S->xout, L->xt, L->n * sizeof *S->xout);
        memcpy(S->gout, L->gt, L->n * sizeof *S->gout);
    }
}

static void ls_set_bracket(ls_search *S, double alo, double flo, double dlo, double ahi,
                           double fhi, double dhi)
{
    S->alo = alo, S->flo = flo, S->dlo = dlo, S->ahi = ahi, S->fhi = fhi, S->dhi = dhi;
}

/* Algorithm 3.5: try a, 4a, 16a, ... up to amax until a trial is acceptable (its step and
 * value in *a_acc, *f_acc) or brackets a minimum; halve back from infeasible trials. */
static ls_outcome ls_bracket(ls_ctx *L, ls_search *S, double a, double amax, double *a_acc,
                             double *f_acc)
{
    double a_prev = 0, f_prev = S->f0, d_prev = S->dphi0;
    for (int i = 0; i < LS_MAX_BRACKET; i++) {
        double da;
        double f = ls_eval(L, a, &da);
        if (f == HUGE_VAL) {            /* infeasible: shrink toward the last good step */
            amax = a;
            a = 0.5 * (a_prev + a);
            if (a - a_prev <= DBL_EPSILON * fmax(1, a)) return LS_GIVE_UP;
            continue;
        }
        ls_keep(L, S, a, f);
        if (f > S->f0 + LS_C1 * L->lin || (i > 0 && f >= f_prev)) {
            ls_set_bracket(S, a_prev, f_prev, d_prev, a, f, da);
            return LS_ZOOM;
        }
        if (fabs(da) <= -LS_C2 * S->dphi0) {
            *a_acc = a, *f_acc = f;
            return LS_ACCEPT;
        }
        if (da >= 0) {
            ls_set_bracket(S, a, f, da, a_prev, f_prev, d_prev);
            return LS_ZOOM;
        }
        if (a >= amax) {                /* a bound stops the step */
            *a_acc = a, *f_acc = f;
            return LS_ACCEPT;
        }
        if (fit_control_stop(L->c)) return LS_GIVE_UP;
        a_prev = a, f_prev = f, d_prev = da;
        a = fmin(4 * a, amax);
    }
    return LS_GIVE_UP;
}

/* Algorithm 3.6: narrow the bracket by cubic interpolation (bisection when the cubic's
 * minimizer is not well inside) until a trial satisfies the curvature condition; the
 * best trial is in S. */
static void ls_zoom(ls_ctx *L, ls_search *S)
{
    for (int i = 0; i < LS_MAX_ZOOM; i++) {
        double lo = fmin(S->alo, S->ahi), hi = fmax(S->alo, S->ahi), w = hi - lo;
        if (w <= DBL_EPSILON * fmax(1, hi)) return;
        double aj = cubic_min(S->alo, S->flo, S->dlo, S->ahi, S->fhi, S->dhi);
        if (!(aj >= lo + 0.1 * w && aj <= hi - 0.1 * w)) aj = 0.5 * (S->alo + S->ahi);
        double dj;
        double f = ls_eval(L, aj, &dj);
        ls_keep(L, S, aj, f);
        if (f > S->f0 + LS_C1 * L->lin || f >= S->flo) {
            S->ahi = aj, S->fhi = f, S->dhi = dj;
        } else {
            if (fabs(dj) <= -LS_C2 * S->dphi0) return;     /* S->best_* holds this point */
            if (dj * (S->ahi - S->alo) >= 0) S->ahi = S->alo, S->fhi = S->flo, S->dhi = S->dlo;
            S->alo = aj, S->flo = f, S->dlo = dj;
        }
        if (fit_control_stop(L->c)) return;
    }
}

/* The line search from phi(0) = f0 with slope dphi0 < 0 and first trial a1. Returns the
 * accepted step (> 0) with its value in *fa and the point/gradient in xout/gout, or 0
 * when no step decreased f. */
static double line_search(ls_ctx *L, double f0, double dphi0, double a1, double amax,
                          double *fa, double *xout, double *gout)
{
    ls_search S = {f0, dphi0, 0, f0, xout, gout, 0, f0, dphi0, 0, 0, 0};
    double a = 0, f = f0;
    switch (ls_bracket(L, &S, fmin(a1, amax), amax, &a, &f)) {
    case LS_ACCEPT:
        memcpy(xout, L->xt, L->n * sizeof *xout);
        memcpy(gout, L->gt, L->n * sizeof *gout);
        *fa = f;
        return a;
    case LS_ZOOM:
        ls_zoom(L, &S);
        break;
    case LS_GIVE_UP:
        break;
    }
    *fa = S.best_f;
    return S.best_a;
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

double fit_projected_gradient(size_t n, const double *x, const double *g, const double *lo,
                              const double *hi, const double *scale, double *pg)
{
    project_grad(n, x, g, lo, hi, pg);
    double m = 0;
    for (size_t i = 0; i < n; i++) m = fmax(m, fabs(pg[i]) * (scale != NULL ? scale[i] : 1));
    return m;
}

static void set_identity(size_t n, double *H, double scale)
{
    memset(H, 0, n * n * sizeof *H);
    for (size_t i = 0; i < n; i++) H[i * n + i] = scale;
}

/* The BFGS update is skipped unless s . y exceeds this times |s| |y|: with less
 * curvature along the step the update would lose positive definiteness to rounding. */
#define BFGS_MIN_CURVATURE 1e-12

/* State of one BFGS search. */
typedef struct bfgs_ctx {
    size_t n;
    double *x;
    const double *lo, *hi;
    const fit_qn_options *opt;
    fit_control *c;
    ls_ctx L;
    double *H;                  /* inverse Hessian approximation (n x n) */
    double *g, *pg, *d;         /* gradient, projected gradient, direction (then the step) */
    double *xn, *gn, *Hy;       /* line search result; H y of the update */
    double f;
    double floor;               /* dtol_abs times the objective at the start */
    double f_restart;           /* objective at the last restart from steepest descent */
    int fresh;                  /* H is a (scaled) identity: no curvature information yet */
    int small;                  /* consecutive iterations with a tiny decrease */
    int restarts;               /* restarts without real progress since (max_restarts) */
    int it;                     /* iterations so far */
} bfgs_ctx;

/* The optimality test's second half: no parameter's projected gradient times its scale
 * (its bound range, else 1 + |x|) above this fraction of the objective. A smooth
 * minimum leaves far less; at the edges of R-function templates fitted to exact samples
 * 1e-2 was seen (the objective is not smooth there); at a kink such as |x| it is
 * unbounded. */
#define QN_SCALED_GTOL 0.1
/* Restarts from steepest descent (H reset) after progress stalled while the optimality
 * test fails: one that gains more than this relative starts the count
 * (fit_qn_options.max_restarts) again. */
#define QN_RESTART_GAIN 1e-6

/* The optimality test at the current point: the projected gradient vanishes (inf-norm
 * <= gtol), or, with curvature information in H, the decrease the quadratic model
 * predicts, pg.H.pg / 2 over the free variables, is at most dtol (|f| + floor). Leaves
 * the projected gradient in B->pg. */
static size_t n_of(const bfgs_ctx *B) { return B->n; }

static int bfgs_optimal(bfgs_ctx *B)
{
    const size_t n = B->n;
    project_grad(n, B->x, B->g, B->lo, B->hi, B->pg);
    if (norm_inf(n, B->pg) <= B->opt->gtol) return 1;
    if (B->fresh) return 0;
    double dec = 0;
    for (size_t i = 0; i < n; i++) {
        if (B->pg[i] == 0) continue;
        double t = 0;
        for (size_t j = 0; j < n; j++) t += B->H[i * n + j] * B->pg[j];
        dec += B->pg[i] * t;
    }
    if (!(dec >= 0 && 0.5 * dec <= B->opt->dtol * (fabs(B->f) + B->floor))) return 0;
    /* At a kink BFGS learns a vanishing curvature and the decrement with it: the
     * gradient itself, times each parameter's scale, must be small against f as well. */
    double lim = QN_SCALED_GTOL * (fabs(B->f) + B->floor);
    for (size_t i = 0; i < n; i++) {
        double w = hi_of(B->hi, i) - lo_of(B->lo, i);
        if (!isfinite(w)) w = 1 + fabs(B->x[i]);
        if (fabs(B->pg[i]) * w > lim) return 0;
    }
    return 1;
}

/* Progress stalled (tiny steps or decreases, or no decrease at all): converged when the
 * optimality test passes, else a restart from steepest descent, else FIT_STALLED.
 * Returns 1 when the search ends. */
static int bfgs_stalled(bfgs_ctx *B, fit_status *st)
{
    if (bfgs_optimal(B)) {
        *st = FIT_CONVERGED;
        return 1;
    }
    if (B->f < B->f_restart - QN_RESTART_GAIN * fabs(B->f_restart)) B->restarts = 0;
    if (B->fresh || ++B->restarts > B->opt->max_restarts) {
        *st = FIT_STALLED;
        return 1;
    }
    B->f_restart = B->f;
    B->small = 0;
    set_identity(n_of(B), B->H, 1);
    B->fresh = 1;
    return 0;
}

/* Direction d = -H pg (components held by a bound zeroed); steepest descent, with H reset,
 * when that is not a descent direction. Returns the slope g . d. */
static double bfgs_direction(bfgs_ctx *B)
{
    const size_t n = B->n;
    const double *H = B->H, *pg = B->pg, *g = B->g;
    double *d = B->d;
    for (size_t i = 0; i < n; i++) {
        double s = 0;
        for (size_t j = 0; j < n; j++) s -= H[i * n + j] * pg[j];
        d[i] = pg[i] == 0 && g[i] != 0 ? 0 : s;
    }
    double dphi0 = dot(n, g, d);
    if (!(dphi0 < 0)) {             /* not a descent direction: steepest descent */
        set_identity(n, B->H, 1);
        B->fresh = 1;
        for (size_t i = 0; i < n; i++) d[i] = -pg[i];
        dphi0 = dot(n, g, d);
    }
    return dphi0;
}

/* Longest useful step along the projected path P(x + a d): the last breakpoint, after
 * which no component moves (HUGE_VAL when some component moves freely for ever; 0 when
 * none moves at all). */
static double max_step(size_t n, const double *x, const double *d, const double *lo,
                       const double *hi)
{
    double amax = 0;
    for (size_t i = 0; i < n; i++) {
        double t = 0;
        if (d[i] < 0) t = (lo_of(lo, i) - x[i]) / d[i];
        else if (d[i] > 0) t = (hi_of(hi, i) - x[i]) / d[i];
        amax = fmax(amax, t);       /* an infinite bound gives HUGE_VAL */
    }
    return amax;
}

/* BFGS update of the inverse Hessian with step s and gradient change y (Nocedal & Wright
 * (6.17)), H first scaled by s.y / y.y (6.20) when it holds no curvature yet. */
static void bfgs_update(bfgs_ctx *B, const double *s, const double *y)
{
    const size_t n = B->n;
    double *H = B->H, *Hy = B->Hy;
    double sy = dot(n, s, y), yy = dot(n, y, y);
    if (!(sy > BFGS_MIN_CURVATURE * sqrt(dot(n, s, s) * yy))) return;
    if (B->fresh) {
        set_identity(n, H, sy / yy);
        B->fresh = 0;
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
            H[i * n + j] += rho * ((1 + rho * yHy) * s[i] * s[j] - (Hy[i] * s[j] + s[i] * Hy[j]));
}

/* Move to the line search's point (value fnew), update H, and test convergence: a tiny
 * step, or a tiny relative decrease twice in a row. Returns 1 when the search ends. */
static int bfgs_step(bfgs_ctx *B, double fnew, fit_status *st)
{
    const size_t n = B->n;
    double *x = B->x, *g = B->g, *s = B->d;     /* d is not needed after the line search */
    double *y = B->L.gt;                        /* nor the trial gradient */
    double smax = 0, xmax = 0;
    for (size_t i = 0; i < n; i++) {
        s[i] = B->xn[i] - x[i];
        smax = fmax(smax, fabs(s[i]));
        xmax = fmax(xmax, fabs(x[i]));
    }
    double df = B->f - fnew;
    memcpy(x, B->xn, n * sizeof *x);
    for (size_t i = 0; i < n; i++) {
        double yi = B->gn[i] - g[i];
        g[i] = B->gn[i];
        y[i] = yi;
    }
    B->f = fnew;
    bfgs_update(B, s, y);
    if (smax <= B->opt->xtol * (1 + xmax)) return bfgs_stalled(B, st);
    if (!(df <= B->opt->ftol * fmax(fabs(B->f), DBL_MIN))) {
        B->small = 0;
        return 0;
    }
    if (++B->small < 2) return 0;
    return bfgs_stalled(B, st);
}

/* One iteration: projected gradient test, direction, line search, step. Returns 1 when
 * the search ends, with its status in *st. */
static int bfgs_iteration(bfgs_ctx *B, fit_status *st)
{
    const size_t n = B->n;
    report(B->c, FIT_PHASE_QN, B->it, 0, B->f, 0);
    if (fit_control_stop(B->c)) {
        *st = FIT_STOPPED;
        return 1;
    }
    /* Only a vanishing projected gradient ends the search while it makes progress: in
     * the flat regions of a template (a primitive that explains few points) the
     * quasi-Newton model predicts little decrease long before the minimum. */
    project_grad(n, B->x, B->g, B->lo, B->hi, B->pg);
    if (norm_inf(n, B->pg) <= B->opt->gtol) {
        *st = FIT_CONVERGED;
        return 1;
    }
    double dphi0 = bfgs_direction(B);
    double amax = max_step(n, B->x, B->d, B->lo, B->hi);
    /* Without curvature information the first trial step moves at most one unit. */
    double a1 = B->fresh ? fmin(1.0, 1.0 / norm_inf(n, B->d)) : 1.0;
    double fnew;
    double a = amax > 0 ? line_search(&B->L, B->f, dphi0, a1, amax, &fnew, B->xn, B->gn) : 0;
    if (a != 0) return bfgs_step(B, fnew, st);
    if (fit_control_stop(B->c)) {
        *st = FIT_STOPPED;
        return 1;
    }
    (void)n;
    return bfgs_stalled(B, st);     /* no decrease: restart along -pg, or give up */
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
    bfgs_ctx B = {.n = n, .x = x, .lo = lo, .hi = hi, .opt = opt, .c = c, .H = mem, .fresh = 1};
    B.g = B.H + n * n, B.pg = B.g + n, B.d = B.pg + n, B.xn = B.d + n, B.gn = B.xn + n;
    double *xt = B.gn + n, *gt = xt + n;
    B.Hy = gt + n;
    B.L = (ls_ctx){fn, user, n, x, B.d, lo, hi, B.g, xt, gt, 0, c};

    for (size_t i = 0; i < n; i++) x[i] = clampd(x[i], lo_of(lo, i), hi_of(hi, i));
    B.f = call(fn, user, x, B.g, c);
    if (B.f == HUGE_VAL) {
        frep_free(mem);
        *fx = B.f;
        return FIT_FAILED;
    }
    B.floor = opt->dtol_abs * fabs(B.f);
    B.f_restart = B.f;
    fit_status st = FIT_MAXITER;
    set_identity(n, B.H, 1);
    int it;
    for (it = 0; it < opt->max_iter; it++, B.it++)
        if (bfgs_iteration(&B, &st)) break;
    if (iterations) *iterations = it;
    *fx = B.f;
    report(c, FIT_PHASE_QN, it, 0, B.f, 1);
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
    o->dtol = 1e-10;
    o->dtol_abs = 1e-12;
}

/* Solve the SPD system A x = b in place by Cholesky (A is overwritten, b becomes x).
 * Returns 0, or -1 when A is not positive definite. */
static int cholesky_solve(size_t n, double *A, double *b)
{
    if (linalg_cholesky(n, A) != 0) return -1;
    linalg_cholesky_solve(n, A, b);
    return 0;
}

/* Damping range: below LM_LAMBDA_MIN the step is plain Gauss-Newton already; above
 * LM_LAMBDA_MAX steps are too short to matter, so the search has stalled. */
#define LM_LAMBDA_MIN 1e-15
#define LM_LAMBDA_MAX 1e16
/* First damping: a step close to Gauss-Newton, the usual start (Marquardt 1963). */
#define LM_LAMBDA_START 1e-3
/* Marquardt's scaling damps each parameter by its diagonal entry of J^T J; a parameter
 * the residuals ignore (entry 0) gets this fraction of the largest entry instead. */
#define LM_DIAG_FLOOR 1e-12
/* After a rejected step the search ends only when the step was this much below xtol:
 * the larger damping of the next try shrinks the step again by itself. */
#define LM_REJECT_XTOL 1e-3

/* State of one Levenberg-Marquardt search: the current point's normal equations A = J^T J
 * and b = J^T r, and the trial's (An, bn). */
typedef struct lm_ctx {
    fit_lsq_fn fn;
    void *user;
    size_t n;
    double *x;
    const double *lo, *hi;
    const fit_lm_options *opt;
    fit_control *c;
    double *A, *An, *M, *b, *bn, *delta, *xn;
    double cost, lambda;
    double floor;               /* dtol_abs times the cost at the start */
    int it;                     /* iterations; an accepted step that converges counts */
} lm_ctx;

/* The optimality test where the search stopped: the Gauss-Newton step (held variables
 * left out, a tiny damping where A is singular) predicts a decrease of at most
 * dtol (cost + floor). */
static int lm_optimal(lm_ctx *L)
{
    const size_t n = L->n;
    double dmax = 0;
    for (size_t i = 0; i < n; i++) dmax = fmax(dmax, L->A[i * n + i]);
    memcpy(L->M, L->A, n * n * sizeof *L->M);
    for (size_t i = 0; i < n; i++) {
        const double bi = L->b[i], xi = L->x[i];
        int held = (xi <= lo_of(L->lo, i) && bi > 0) || (xi >= hi_of(L->hi, i) && bi < 0);
        L->delta[i] = held ? 0 : -bi;
        L->M[i * n + i] += LM_DIAG_FLOOR * fmax(dmax, DBL_MIN);
    }
    double dec = 0;
    memcpy(L->xn, L->delta, n * sizeof *L->xn);
    if (cholesky_solve(n, L->M, L->delta) != 0) return 0;
    for (size_t i = 0; i < n; i++) dec -= L->xn[i] * L->delta[i];
    return 0.5 * dec <= L->opt->dtol * (L->cost + L->floor);
}

/* The gradient test on J^T r, ignoring parameters held at a bound; the largest diagonal
 * entry of J^T J goes to *dmax. Returns 1 when the gradient vanishes. */
static int lm_gradient_small(const lm_ctx *L, double *dmax)
{
    const size_t n = L->n;
    double gmax = 0;
    *dmax = 0;
    for (size_t i = 0; i < n; i++) {
        const double bi = L->b[i], xi = L->x[i];
        int held = (xi <= lo_of(L->lo, i) && bi > 0) || (xi >= hi_of(L->hi, i) && bi < 0);
        if (!held) gmax = fmax(gmax, fabs(bi));
        *dmax = fmax(*dmax, L->A[i * n + i]);
    }
    return gmax <= L->opt->gtol;
}

/* The damped step: solve (A + lambda diag(A)) delta = -b. Returns 0, or -1 when the
 * damped matrix is not positive definite. */
static int lm_solve(lm_ctx *L, double dmax)
{
    const size_t n = L->n;
    memcpy(L->M, L->A, n * n * sizeof *L->M);
    for (size_t i = 0; i < n; i++) {
        double dii = fmax(L->A[i * n + i], LM_DIAG_FLOOR * fmax(dmax, DBL_MIN));
        L->M[i * n + i] += L->lambda * dii;
        L->delta[i] = -L->b[i];
    }
    return cholesky_solve(n, L->M, L->delta);
}

/* Try x + delta (clipped to the bounds): accept it and lower the damping when the cost
 * decreased, else raise the damping. Returns 1 when the search ends (converged). */
static int lm_try_step(lm_ctx *L)
{
    const size_t n = L->n;
    const fit_lm_options *opt = L->opt;
    double smax = 0, xmax = 0;
    for (size_t i = 0; i < n; i++) {
        L->xn[i] = clampd(L->x[i] + L->delta[i], lo_of(L->lo, i), hi_of(L->hi, i));
        smax = fmax(smax, fabs(L->xn[i] - L->x[i]));
        xmax = fmax(xmax, fabs(L->x[i]));
    }
    if (L->c) L->c->evals++;
    double cn = L->fn(L->user, L->xn, L->An, L->bn);
    if (!(isfinite(cn) && cn < L->cost)) {
        L->lambda *= 10;
        return L->lambda > LM_LAMBDA_MAX || smax <= opt->xtol * (1 + xmax) * LM_REJECT_XTOL;
    }
    double dc = L->cost - cn;
    memcpy(L->x, L->xn, n * sizeof *L->x);
    memcpy(L->A, L->An, n * n * sizeof *L->A);
    memcpy(L->b, L->bn, n * sizeof *L->b);
    L->cost = cn;
    L->lambda = fmax(L->lambda / 10, LM_LAMBDA_MIN);
    if (dc <= opt->ftol * L->cost || smax <= opt->xtol * (1 + xmax)) {
        L->it++;
        return 1;
    }
    return 0;
}

/* One iteration: gradient test, damped step, trial. Returns 1 when the search ends, with
 * its status in *st. */
static int lm_iteration(lm_ctx *L, fit_status *st)
{
    report(L->c, FIT_PHASE_LM, L->it, 0, L->cost, 0);
    if (fit_control_stop(L->c)) {
        *st = FIT_STOPPED;
        return 1;
    }
    double dmax;
    int end;
    if (lm_gradient_small(L, &dmax)) {
        end = 1;
    } else if (lm_solve(L, dmax) != 0) {
        L->lambda *= 10;            /* not positive definite: damp more */
        end = L->lambda > LM_LAMBDA_MAX;
    } else {
        end = lm_try_step(L);
    }
    if (end) *st = lm_gradient_small(L, &dmax) || lm_optimal(L) ? FIT_CONVERGED : FIT_STALLED;
    return end;
}

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
    lm_ctx L = {.fn = fn, .user = user, .n = n, .x = x, .lo = lo, .hi = hi, .opt = opt,
                .c = c, .A = mem, .lambda = LM_LAMBDA_START};
    L.An = L.A + n * n, L.M = L.An + n * n, L.b = L.M + n * n, L.bn = L.b + n;
    L.delta = L.bn + n, L.xn = L.delta + n;

    for (size_t i = 0; i < n; i++) x[i] = clampd(x[i], lo_of(lo, i), hi_of(hi, i));
    if (c) c->evals++;
    L.cost = fn(user, x, L.A, L.b);
    if (!isfinite(L.cost)) {
        frep_free(mem);
        *fx = HUGE_VAL;
        return FIT_FAILED;
    }
    L.floor = opt->dtol_abs * L.cost;
    fit_status st = FIT_MAXITER;
    for (L.it = 0; L.it < opt->max_iter; L.it++)
        if (lm_iteration(&L, &st)) break;
    if (iterations) *iterations = L.it;
    *fx = L.cost;
    report(c, FIT_PHASE_LM, L.it, 0, L.cost, 1);
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
    o->probe_returns = 0;
    o->probe_tol = 0;
    o->chains = 1;
    o->agree = NULL;
    o->nagree = 0;
    o->agree_tol = 0;
}

long fit_sa_agreeing(const fit_sa_options *o, size_t n, const double *x, const double *lo,
                     const double *hi)
{
    for (long k = 0; o->agree != NULL && k < o->nagree; k++) {
        const double *a = o->agree + (size_t)k * n;
        size_t i = 0;
        while (i < n && fabs(x[i] - a[i]) <= o->agree_tol * (hi[i] - lo[i])) i++;
        if (i == n) return k;
    }
    return -1;
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
    v->f6 = FREP_PI * (1.0 - v->f5) / sin(FREP_PI * (1.0 - v->f5)) / exp(lgamma(d1));
}

/* Width of the distribution at temperature t. */
static double visit_sigma(const visit_consts *v, double t)
{
    double qv = v->qv;
    double f1 = exp(log(t) / (qv - 1.0));
    double f4 = sqrt(FREP_PI) * f1 * v->f2 / (v->f3 * (3.0 - qv));
    return exp(-(qv - 1.0) * log(v->f6 / f4) / (3.0 - qv));
}

static double visit_draw(const visit_consts *v, double sigma, frep_rng *r)
{
    double a = sigma * frep_rng_normal(r);
    double b = fabs(frep_rng_normal(r));
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

/* One run of fit_sa: the problem, the settings and the best point of all chains. */
typedef struct sa_ctx {
    fit_fn fn;
    void *user;
    size_t n;
    const double *lo, *hi;
    const fit_sa_options *opt;
    frep_rng *rng;
    fit_control *c;
    visit_consts vc;
    double t1;                  /* 2^(qv-1) - 1, the numerator of the cooling schedule */
    double *trial;              /* scratch point */
    double *best, ebest;        /* best of all chains */
    long total;                 /* iterations of all chains */
} sa_ctx;

/* State of one annealing chain. */
typedef struct sa_chain {
    double *cur, *best;     /* current point, the chain's best */
    double e, ebest;
    double emark;           /* the chain's best when it last improved by rel_improve */
    long step;              /* iterations since the schedule (re)started */
    long last_gain;         /* iteration of that improvement */
    long quiet;             /* iterations in a row without a new best */
    long returns;           /* probes in a row since last_gain that ended at the best */
} sa_chain;

static double sa_call(sa_ctx *S, const double *x) { return call(S->fn, S->user, x, NULL, S->c); }

/* Start a chain at x (when `from_x`) or at a random point with a finite objective, and
 * polish it first: a start near the answer then is the answer, and the chain only has
 * to beat it. Returns 0, or -1 when no finite objective was found. */
static int sa_chain_start(sa_ctx *S, sa_chain *ch, const double *x, int from_x)
{
    const size_t n = S->n;
    const fit_sa_options *opt = S->opt;
    if (from_x) memcpy(ch->cur, x, n * sizeof *ch->cur);
    else random_point(n, ch->cur, S->lo, S->hi, S->rng);
    double e = sa_call(S, ch->cur);
    for (int k = 0; e == HUGE_VAL && k < SA_MAX_START_TRIES && !fit_control_stop(S->c); k++) {
        random_point(n, ch->cur, S->lo, S->hi, S->rng);
        e = sa_call(S, ch->cur);
    }
    if (e == HUGE_VAL) return -1;
    if (opt->local != NULL && !fit_control_stop(S->c)) {
        memcpy(S->trial, ch->cur, n * sizeof *S->trial);
        double el;
        if (opt->local(opt->local_user, S->trial, &el) == 0 && el < e) {
            memcpy(ch->cur, S->trial, n * sizeof *ch->cur);
            e = el;
        }
    }
    memcpy(ch->best, ch->cur, n * sizeof *ch->best);
    ch->e = ch->ebest = e;
    ch->emark = ch->ebest;
    ch->step = ch->last_gain = ch->quiet = ch->returns = 0;
    return 0;
}

/* Temperature of the schedule T0 (2^(qv-1) - 1) / ((step+2)^(qv-1) - 1). Once it has
 * fallen below restart_ratio T0 the schedule starts again from T0 at a random point with
 * a finite objective (the chain stays where it is when none is found). */
static double sa_temperature(sa_ctx *S, sa_chain *ch)
{
    const fit_sa_options *opt = S->opt;
    double t2 = exp((opt->qv - 1.0) * log((double)ch->step + 2.0)) - 1.0;
    double temp = opt->t0 * S->t1 / t2;
    if (temp >= opt->t0 * opt->restart_ratio) return temp;
    ch->step = 0;
    double er = HUGE_VAL;
    for (int k = 0; er == HUGE_VAL && k < SA_MAX_START_TRIES; k++) {
        random_point(S->n, S->trial, S->lo, S->hi, S->rng);
        er = sa_call(S, S->trial);
    }
    if (er < HUGE_VAL) {
        memcpy(ch->cur, S->trial, S->n * sizeof *ch->cur);
        ch->e = er;
    }
    return opt->t0;
}

/* Generalized Metropolis rule (acceptance parameter qa): a worse trial et > e is taken
 * with probability [1 - (1 - qa) (et - e) / tstep]^(1 / (1 - qa)). */
static int sa_accept(sa_ctx *S, double e, double et, double tstep)
{
    if (et < e) return 1;
    const double qa = S->opt->qa;
    double pq = 1.0 - (1.0 - qa) * (et - e) / tstep;
    double p = pq <= 0 ? 0 : exp(log(pq) / (1.0 - qa));
    return frep_rng_unit(S->rng) <= p && et < HUGE_VAL;
}

/* One iteration at temperature temp: n moves of all coordinates, then n moves of one
 * coordinate, each drawn from the visiting distribution and wrapped into the box.
 * Returns 1 when the chain's best improved. */
static int sa_sweep(sa_ctx *S, sa_chain *ch, double temp)
{
    const size_t n = S->n;
    const double *lo = S->lo, *hi = S->hi;
    double *trial = S->trial, *cur = ch->cur;
    double tstep = temp / (double)(ch->step + 1);
    double sigma = visit_sigma(&S->vc, temp);
    int found = 0;
    for (size_t j = 0; j < 2 * n; j++) {
        memcpy(trial, cur, n * sizeof *trial);
        if (j < n) {
            for (size_t i = 0; i < n; i++)
                trial[i] = wrap(cur[i] + visit_draw(&S->vc, sigma, S->rng), lo[i], hi[i]);
        } else {
            size_t i = j - n;
            trial[i] = wrap(cur[i] + visit_draw(&S->vc, sigma, S->rng), lo[i], hi[i]);
        }
        double et = sa_call(S, trial);
        if (!sa_accept(S, ch->e, et, tstep)) continue;
        memcpy(cur, trial, n * sizeof *cur);
        ch->e = et;
        if (ch->e < ch->ebest) {
            ch->ebest = ch->e;
            memcpy(ch->best, cur, n * sizeof *ch->best);
            found = 1;
        }
    }
    return found;
}

/* The stall limit of the chain now: bound_stall_iter while its best lies on a bound
 * (probably a primitive switched off rather than placed), else stall_iter. */
static long sa_stall_limit(const sa_ctx *S, const sa_chain *ch)
{
    int suspect = on_bound(S->n, ch->best, S->lo, S->hi);
    return suspect && S->opt->bound_stall_iter > 0 ? S->opt->bound_stall_iter
                                                   : S->opt->stall_iter;
}

/* Dual annealing's local search: from the new best after an iteration that found one,
 * or from the current point after local_period quiet iterations (a probe of the basin
 * the chain is in). A better result becomes the chain's best and current point; a probe
 * that ends at the best's value (within probe_tol of it, relative) adds to ch->returns,
 * any other result clears it. */
static void sa_polish(sa_ctx *S, sa_chain *ch, int found)
{
    const size_t n = S->n;
    const fit_sa_options *opt = S->opt;
    int probe = opt->local_period > 0 && ch->quiet >= opt->local_period;
    if (!(found || probe) || opt->local == NULL || fit_control_stop(S->c)) return;
    memcpy(S->trial, found ? ch->best : ch->cur, n * sizeof *S->trial);
    ch->quiet = 0;
    double el;
    if (opt->local(opt->local_user, S->trial, &el) != 0) return;
    if (!found) {
        int back = fabs(el - ch->ebest) <= opt->probe_tol * fabs(ch->ebest);
        ch->returns = back ? ch->returns + 1 : 0;
    }
    if (el < ch->ebest) {
        ch->ebest = ch->e = el;
        memcpy(ch->best, S->trial, n * sizeof *ch->best);
        memcpy(ch->cur, S->trial, n * sizeof *ch->cur);
    }
}

/* The chain has stalled: stall_limit iterations since its last gain, or probe_returns
 * probes in a row that ended at a best on no bound. */
static int sa_stalled(const sa_ctx *S, const sa_chain *ch, long it, long stall)
{
    if (stall > 0 && it - ch->last_gain >= stall) return 1;
    return S->opt->probe_returns > 0 && ch->returns >= S->opt->probe_returns &&
           !on_bound(S->n, ch->best, S->lo, S->hi);
}

/* Run one chain until it stalls (FIT_CONVERGED), reaches max_iter (FIT_MAXITER), the
 * best of all chains reaches the threshold (FIT_CONVERGED) or the budget is spent
 * (FIT_STOPPED); *stop_all is set in the last two cases, which end the other chains
 * too. */
static fit_status sa_chain_run(sa_ctx *S, sa_chain *ch, int *stop_all)
{
    const fit_sa_options *opt = S->opt;
    for (long it = 0; it < opt->max_iter; it++) {
        if (fit_sa_agreeing(opt, S->n, ch->best, S->lo, S->hi) >= 0) return FIT_CONVERGED;
        double temp = sa_temperature(S, ch);
        int found = sa_sweep(S, ch, temp);
        ch->quiet = found ? 0 : ch->quiet + 1;
        long stall = sa_stall_limit(S, ch);
        sa_polish(S, ch, found);
        if (ch->ebest < S->ebest) {
            S->ebest = ch->ebest;
            memcpy(S->best, ch->best, S->n * sizeof *S->best);
        }
        ch->step++;
        S->total++;
        report(S->c, FIT_PHASE_SA, S->total, temp, S->ebest, 0);
        if (ch->ebest < ch->emark - opt->rel_improve * fabs(ch->emark) || ch->ebest == 0) {
            ch->emark = ch->ebest;
            ch->last_gain = it;
            ch->returns = 0;
        }
        if (S->ebest <= opt->threshold) {
            *stop_all = 1;
            return FIT_CONVERGED;
        }
        if (sa_stalled(S, ch, it, stall)) return FIT_CONVERGED;
        if (fit_control_stop(S->c)) {
            *stop_all = 1;
            return FIT_STOPPED;
        }
    }
    return FIT_MAXITER;
}

/* Arguments the annealing cannot work with: no or too many parameters, a box that is
 * not finite and non-empty in every coordinate, shape parameters out of range. */
static int sa_bad_arguments(size_t n, const double *lo, const double *hi,
                            const fit_sa_options *opt)
{
    if (n == 0 || n > FIT_MAX_PARAMS || lo == NULL || hi == NULL) return 1;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(lo[i]) || !isfinite(hi[i]) || !(lo[i] < hi[i])) return 1;
    return !(opt->qv > 1 && opt->qv < 3) || !(opt->qa < 1) || !(opt->t0 > 0);
}

fit_status fit_sa(fit_fn fn, void *user, size_t n, double *x, const double *lo,
                  const double *hi, const fit_sa_options *opt, frep_rng *rng, fit_control *c,
                  double *fx, long *iterations)
{
    fit_sa_options defaults;
    if (opt == NULL) fit_sa_options_init(&defaults), opt = &defaults;
    if (iterations) *iterations = 0;
    *fx = HUGE_VAL;
    if (sa_bad_arguments(n, lo, hi, opt)) return FIT_FAILED;
    double *mem = frep_malloc(4 * n * sizeof *mem);
    if (mem == NULL) return out_of_memory(c);
    sa_ctx S = {.fn = fn, .user = user, .n = n, .lo = lo, .hi = hi, .opt = opt, .rng = rng,
                .c = c, .trial = mem, .best = mem + n, .ebest = HUGE_VAL};
    S.t1 = exp((opt->qv - 1.0) * log(2.0)) - 1.0;
    visit_init(&S.vc, opt->qv);
    sa_chain ch = {.cur = mem + 2 * n, .best = mem + 3 * n, .e = HUGE_VAL, .ebest = HUGE_VAL};

    int inside = 1;
    for (size_t i = 0; i < n; i++) inside &= x[i] >= lo[i] && x[i] <= hi[i];
    const long nchains = opt->chains > 0 ? opt->chains : 1;
    fit_status st = FIT_MAXITER;
    int stop_all = 0;
    for (long chain = 0; chain < nchains && !stop_all; chain++) {
        if (chain > 0 && fit_control_stop(c)) {
            st = FIT_STOPPED;
            break;
        }
        if (sa_chain_start(&S, &ch, x, chain == 0 && inside) != 0) {
            if (chain == 0) {
                frep_free(mem);
                return FIT_FAILED;
            }
            break;
        }
        if (ch.ebest < S.ebest) {
            S.ebest = ch.ebest;
            memcpy(S.best, ch.best, n * sizeof *S.best);
        }
        st = sa_chain_run(&S, &ch, &stop_all);
    }
    if (iterations) *iterations = S.total;
    memcpy(x, S.best, n * sizeof *x);
    *fx = S.ebest;
    report(c, FIT_PHASE_SA, S.total, 0, S.ebest, 1);
    frep_free(mem);
    return st;
}

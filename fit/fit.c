/* fit.c - the template-fitting driver: global phase (chains of generalized simulated
 * annealing on a subset of the points, with short BFGS searches from each new best, as
 * in dual annealing), then the local phase (BFGS or Levenberg-Marquardt on all points)
 * from each chain's best, keeping the best result.
 * Sits between cli/cmd_fit.c and fit/optim.c + fit/objective.c.
 */
#include "alloc.h"
#include "kdtree.h"
#include "measure.h"
#include "fit.h"
#include "threads.h"
#include "util.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- names ----------------------------------------------------------------- */

static const char *const method_names[] = {"saqn", "qn", "sa", "lm"};
static const char *const objective_names[] = {"algebraic", "geometric"};
static const char *const loss_names[] = {"l2", "huber", "cauchy", "geman"};

const char *fit_method_name(fit_method m) { return method_names[m]; }
const char *fit_objective_name(fit_objective_kind k) { return objective_names[k]; }
const char *fit_loss_name(fit_loss l) { return loss_names[l]; }

static int lookup(const char *const *names, int count, const char *s)
{
    for (int i = 0; i < count; i++)
        if (strcmp(names[i], s) == 0) return i;
    return -1;
}

int fit_method_parse(const char *s, fit_method *m)
{
    int i = lookup(method_names, 4, s);
    if (i < 0) return -1;
    *m = (fit_method)i;
    return 0;
}

int fit_objective_parse(const char *s, fit_objective_kind *k)
{
    int i = lookup(objective_names, 2, s);
    if (i < 0) return -1;
    *k = (fit_objective_kind)i;
    return 0;
}

int fit_loss_parse(const char *s, fit_loss *l)
{
    int i = lookup(loss_names, 4, s);
    if (i < 0) return -1;
    *l = (fit_loss)i;
    return 0;
}

/* ---- configuration ------------------------------------------------------------ */

/* A chain stops after this many probes in a row that end at its best value, to within
 * FIT_PROBE_TOL of it (fit_sa_options.probe_returns): on the paper's part the first
 * chain's stall was 7 probes of about 400 evaluations each that all ended at the best
 * the start's search had found (or at its copy with the holes swapped); 2 in a row
 * halved the evaluations with the same results on every suite (doc/benchmarks.md). */
#define FIT_PROBE_RETURNS 2
#define FIT_PROBE_TOL 1e-6

void fit_config_init(fit_config *c)
{
    memset(c, 0, sizeof *c);
    c->method = FIT_METHOD_SAQN;
    fit_objective_config_init(&c->obj);
    c->obj.kind = FIT_OBJ_ALGEBRAIC;
    c->global_kind = FIT_OBJ_ALGEBRAIC;
    c->seed = 1;
    c->sa_points = 1024;
    c->sa_local = 1;
    c->sa_local_iter = 300;
    fit_sa_options_init(&c->sa);
    c->sa.stall_iter = 15;
    c->sa.bound_stall_iter = 60;
    c->sa.local_period = 2;
    c->sa.chains = 2;
    c->sa.probe_returns = FIT_PROBE_RETURNS;
    c->sa.probe_tol = FIT_PROBE_TOL;
    fit_qn_options_init(&c->qn);
    fit_lm_options_init(&c->lm);
    c->reweight_rounds = 8;
    c->report = 0;
    c->robust = 1;
}

/* ---- the frep_program adapter ------------------------------------------------ */

typedef struct prog_model {
    const frep_program *p;
    size_t nall, nfree;
    size_t *idx;                /* nfree program parameter indices */
    double *base;               /* nall values of the held parameters */
    int all;                    /* idx is 0..nall-1: the free rows of dp are all of them */
} prog_model;

/* Per-thread state: the evaluator scratch, a full parameter vector and the
 * derivatives of all program parameters (rows of the free ones are copied out). */
typedef struct prog_scratch {
    frep_scratch *s;
    double *full, *dp;
} prog_scratch;

static void prog_scratch_free(void *user, void *sv)
{
    (void)user;
    prog_scratch *ps = sv;
    if (ps == NULL) return;
    frep_scratch_free(ps->s);
    frep_free(ps->full);
    frep_free(ps);
}

static void *prog_scratch_new(void *user)
{
    const prog_model *pm = user;
    prog_scratch *ps = frep_calloc(1, sizeof *ps);
    if (ps == NULL) return NULL;
    ps->s = frep_scratch_new(pm->p);
    ps->full = frep_malloc((pm->nall + pm->nall * FIT_BLOCK) * sizeof *ps->full);
    if (ps->s == NULL || ps->full == NULL) {
        prog_scratch_free(user, ps);
        return NULL;
    }
    ps->dp = ps->full + pm->nall;
    memcpy(ps->full, pm->base, pm->nall * sizeof *ps->full);
    return ps;
}

static int prog_eval(void *user, void *sv, size_t n, const double *x, const double *y,
                     const double *z, const double *params, double *f, double *g, double *dp)
{
    const prog_model *pm = user;
    prog_scratch *ps = sv;
    const frep_program *p = pm->p;
    for (size_t j = 0; j < pm->nfree; j++) ps->full[pm->idx[j]] = params[j];
    if (dp != NULL && pm->all) {
        if (frep_eval_dparams(p, ps->s, n, x, y, z, ps->full, f, dp) != 0) return -1;
    } else if (dp != NULL) {
        if (frep_eval_dparams(p, ps->s, n, x, y, z, ps->full, f, ps->dp) != 0) return -1;
        for (size_t j = 0; j < pm->nfree; j++)
            memcpy(dp + j * n, ps->dp + pm->idx[j] * n, n * sizeof *dp);
    }
    if (g != NULL &&
        frep_eval_grad(p, ps->s, n, x, y, z, ps->full, f, g, g + n, g + 2 * n) != 0)
        return -1;
    if (dp == NULL && g == NULL && frep_eval(p, ps->s, n, x, y, z, ps->full, f) != 0)
        return -1;
    return 0;
}

int fit_program_model(const frep_program *p, const size_t *idx, size_t nfree,
                      const double *base, fit_model *m)
{
    memset(m, 0, sizeof *m);
    prog_model *pm = frep_calloc(1, sizeof *pm);
    if (pm == NULL) return -1;
    pm->p = p;
    pm->nall = frep_program_nparams(p);
    pm->nfree = nfree;
    pm->idx = frep_malloc((nfree ? nfree : 1) * sizeof *pm->idx);
    pm->base = frep_malloc((pm->nall ? pm->nall : 1) * sizeof *pm->base);
    if (pm->idx == NULL || pm->base == NULL) {
        frep_free(pm->idx);
        frep_free(pm->base);
        frep_free(pm);
        return -1;
    }
    memcpy(pm->idx, idx, nfree * sizeof *idx);
    memcpy(pm->base, base, pm->nall * sizeof *base);
    pm->all = nfree == pm->nall;
    for (size_t j = 0; j < nfree; j++) pm->all &= idx[j] == j;
    m->nparams = nfree;
    m->user = pm;
    m->scratch_new = prog_scratch_new;
    m->scratch_free = prog_scratch_free;
    m->eval = prog_eval;
    return 0;
}

void fit_program_model_free(fit_model *m)
{
    prog_model *pm = m->user;
    if (pm == NULL) return;
    frep_free(pm->idx);
    frep_free(pm->base);
    frep_free(pm);
    m->user = NULL;
}

/* ---- the driver ---------------------------------------------------------------------- */

static double points_diagonal(const fit_points *P);

/* The annealing's generator is seeded with cfg->seed xor this salt, so that its stream
 * is not the one that drew the annealing's point subset (seeded with cfg->seed). */
#define FIT_SA_SEED_SALT 0x5a17ca1edULL
/* Reweighting rounds of the geometric kind stop once no parameter moved by more than
 * this relative to the largest one: the frozen weights have reached their fixed point. */
#define FIT_REWEIGHT_XTOL 1e-9
/* Reweighting rounds of the searches inside the annealing: two refreezes are enough to
 * rank a basin; the local phase settles it. */
#define FIT_SA_LOCAL_ROUNDS 2

/* One fit: its settings, objectives and budget, and the state the stages pass on. */
typedef struct fit_run_ctx {
    const fit_config *cfg;
    const fit_model *model;
    const fit_points *pts;
    size_t m;                   /* parameters */
    const double *lo, *hi;
    const double *start;        /* the caller's start values (m) */
    int global;                 /* the method has an annealing phase */
    fit_objective *obj;         /* all points, the local phase's objective */
    fit_objective *sub;         /* the annealing's: a subset, another kind or obj itself */
    /* The robust refinement's (cfg.robust and a local phase; else NULL): geometric, all
     * points, Cauchy at the scale last set.  rbuf holds n doubles for residuals (its
     * scale's, and a chain's share of points near the surface). */
    fit_objective *geo;
    /* The same on the annealing's model (cfg.surrogate), when there is one and geo is
     * made: the chains' bests are refined on it first (polish_chain). */
    fit_objective *geo_s;
    /* The parameter scan's (polish_chain): geo_s, else geo, on at most FIT_SCAN_SUBSET
     * of the points (that objective itself when there are no more); its loss is set to
     * the scanned objective's before each scan. */
    fit_objective *scan;
    double *rbuf;
    double diag;                /* the points' diagonal */
    fit_control ctl;            /* evaluations, time and interrupt of all phases */
    double t0;                  /* frep_now_seconds() at the start */
    double f0;                  /* objective at the start values */
    double x[FIT_MAX_PARAMS];   /* the result so far */
    fit_status st;              /* of the phase that produced x */
    long sa_iterations;
    int local_iterations;
    /* Progress: the objective being minimized now, the chain, and the lowest values
     * seen on the subset and on all points (each reported monotone). */
    const fit_objective *active;
    long chain, nchains;
    double best_sub, best_all, best_geo;
} fit_run_ctx;

/* The caller stopped the run (Ctrl-C, a cancel callback): what is left to do must be
 * cheap. A budget of evaluations or time ends a run normally. */
static int interrupted(fit_run_ctx *R)
{
    return fit_control_cancelled(&R->ctl);
}

/* fit_control's progress callback -> the caller's, with the chain, the elapsed time and
 * a best that never goes up. */
static void on_progress(void *user, fit_phase ph, long it, double temp, double value)
{
    (void)temp;
    fit_run_ctx *R = user;
    int sub = R->active == R->geo && R->geo != NULL ? 2
              : R->active != NULL && R->active != R->obj;
    double *b = sub == 2 ? &R->best_geo : sub ? &R->best_sub : &R->best_all;
    if (value < *b) *b = value;
    fit_progress p = {ph, R->chain, R->nchains, it, *b, sub, frep_now_seconds() - R->t0};
    R->cfg->progress(R->cfg->progress_user, &p);
}

/* Local phase on objective o from x: BFGS (or LM), and for the geometric kind rounds of
 * frozen weights until the parameters settle. */
static fit_status local_phase(fit_run_ctx *R, fit_objective *o, double *x, double *fx,
                              int max_iter, int rounds)
{
    const fit_config *cfg = R->cfg;
    const fit_objective *was = R->active;
    R->active = o;
    fit_qn_options qn = cfg->qn;
    fit_lm_options lm = cfg->lm;
    if (max_iter > 0) qn.max_iter = lm.max_iter = max_iter;
    /* The searches inside the annealing rank basins: a stall ends them. */
    if (o == R->sub && R->sub != R->obj) qn.max_restarts = 0;
    int geo = fit_objective_kind_of(o) == FIT_OBJ_GEOMETRIC;
    if (!geo) rounds = 1;
    fit_status st = FIT_FAILED;
    double prev[FIT_MAX_PARAMS];
    for (int r = 0; r < rounds; r++) {
        memcpy(prev, x, R->m * sizeof *x);
        if (geo && fit_objective_freeze(o, x) != 0) break;
        int it = 0;
        if (cfg->method == FIT_METHOD_LM)
            st = fit_lm(fit_objective_lsq, o, R->m, x, R->lo, R->hi, &lm, &R->ctl, fx, &it);
        else
            st = fit_bfgs(fit_objective_value, o, R->m, x, R->lo, R->hi, &qn, &R->ctl, fx, &it);
        R->local_iterations += it;
        if (st == FIT_FAILED || st == FIT_STOPPED || st == FIT_NOMEM) break;
        double change = 0, scale = 0;
        for (size_t j = 0; j < R->m; j++) {
            change = fmax(change, fabs(x[j] - prev[j]));
            scale = fmax(scale, fabs(x[j]));
        }
        if (change <= FIT_REWEIGHT_XTOL * (1 + scale)) break;
    }
    if (geo) {
        fit_objective_unfreeze(o);
        if (!interrupted(R)) *fx = fit_objective_value(o, x, NULL);
    }
    R->active = was;
    return st;
}

/* Inner local search of the annealing (fit_sa_options.local). */
static int sa_local(void *user, double *x, double *fx)
{
    fit_run_ctx *R = user;
    fit_status st = local_phase(R, R->sub, x, fx, R->cfg->sa_local_iter, FIT_SA_LOCAL_ROUNDS);
    return st == FIT_FAILED || st == FIT_NOMEM || !isfinite(*fx) ? -1 : 0;
}

/* The median of v[0..n), n > 0 (v reordered). */
static double median(double *v, size_t n)
{
    double upper = fit_select_kth(v, n, n / 2);
    if (n % 2) return upper;
    double lower = v[0];            /* the largest of v[0..n/2), all <= upper */
    for (size_t i = 1; i < n / 2; i++) lower = fmax(lower, v[i]);
    return 0.5 * (lower + upper);
}

/* The Cauchy scale of the robust refinement at x: FIT_CAUCHY_C robust standard
 * deviations of the first-order distances (1.4826 x their median), at least
 * FIT_ROBUST_FLOOR of the diagonal. Returns it, or NaN when the distances cannot be
 * computed. */
static double robust_scale(fit_run_ctx *R, fit_objective *o, const double *x)
{
    size_t n = R->pts->n;
    if (fit_objective_residuals(o, x, R->rbuf) < 0) return NAN;
    R->ctl.evals++;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (isfinite(R->rbuf[i])) R->rbuf[k++] = R->rbuf[i];
    if (k == 0) return NAN;
    double sigma = 1.4826 * median(R->rbuf, k);
    return fmax(FIT_CAUCHY_C * sigma, FIT_ROBUST_FLOOR * R->diag);
}

/* Robust refinement from x (cfg.robust) on o (R->geo, or R->geo_s on the annealing's
 * model): rounds of scale estimation and a local phase on the geometric Cauchy
 * objective, until the scale settles. *scale gets the last scale, *fx the objective at
 * x at that scale. x is left alone when the distances cannot be computed there. */
static fit_status robust_refine(fit_run_ctx *R, fit_objective *o, double *x, double *fx,
                                double *scale, fit_status st)
{
    double s = HUGE_VAL;
    for (int round = 0; round < FIT_ROBUST_ROUNDS; round++) {
        if (fit_control_stop(&R->ctl)) return FIT_STOPPED;
        double ns = robust_scale(R, o, x);
        if (!isfinite(ns)) break;
        int settled = fabs(ns - s) <= FIT_ROBUST_SETTLE * ns;
        s = ns;
        if (settled) break;
        fit_objective_set_loss(o, FIT_LOSS_CAUCHY, s);
        double y[FIT_MAX_PARAMS], fy = HUGE_VAL;
        memcpy(y, x, R->m * sizeof *y);
        fit_status rs = local_phase(R, o, y, &fy, 0, R->cfg->reweight_rounds);
        if (rs == FIT_FAILED || rs == FIT_NOMEM || !isfinite(fy)) break;
        memcpy(x, y, R->m * sizeof *x);
        st = rs;
        if (rs == FIT_STOPPED) break;
    }
    *scale = s;
    if (isfinite(s)) fit_objective_set_loss(o, FIT_LOSS_CAUCHY, s);
    if (interrupted(R)) return FIT_STOPPED;
    *fx = fit_objective_value(o, x, NULL);
    R->ctl.evals++;
    return st;
}

/* A chain's best through the robust refinement. With an annealing model (the R-function
 * compilation of a min/max template) it is refined on that model first: the zero set is
 * the same, but min/max's first-order distances mislead where min picks the wrong
 * argument. On hfBlock's quadratic slabs, a point just inside a face of a thin plate
 * has a smaller slab value across the plate than across the face, so min hands it to
 * the plate's other faces: it stops pulling its face, which slides out over the noisy
 * points (the min/max bracket's width, 4.065 for 4 at 0.2% noise, 5 seeds of 5). The
 * R-function's intersection depends on both arguments and keeps the pull. Then the
 * template itself is refined from there, and the lower of the two points on the
 * template's loss (at its last scale) is kept, with the status of the refinement that
 * produced it. */
static fit_status refine_pair(fit_run_ctx *R, double *x, double *fx, double *scale)
{
    if (R->geo_s == NULL) return robust_refine(R, R->geo, x, fx, scale, FIT_STALLED);
    double ss;
    fit_status st = robust_refine(R, R->geo_s, x, fx, &ss, FIT_STALLED);
    *scale = ss;
    if (st == FIT_STOPPED) return st;
    double y[FIT_MAX_PARAMS], fy;
    memcpy(y, x, R->m * sizeof *y);
    fit_status sy = robust_refine(R, R->geo, y, &fy, scale, st);
    if (sy == FIT_STOPPED) return sy;
    double v = fit_objective_value(R->geo, x, NULL);
    R->ctl.evals++;
    if (fy <= v || !isfinite(v)) {
        memcpy(x, y, R->m * sizeof *x);
        *fx = fy;
        return sy;
    }
    *fx = v;
    return st;
}

/* A chain's refinement can leave a face pushed past every point: no point then depends
 * on it (in min/max a thin plate's other faces take its points; the bracket's width
 * went to its bound 6 with 2% outliers, the bushing's flange radius to 4.6 for 3, where
 * the annealing's algebraic loss barely sees the plate's ends), and no local search
 * brings it back. Each parameter is tried at FIT_SCAN_POINTS values across its range
 * on the robust loss, the others held, then as many around the best, FIT_SCAN_LEVELS times
 * (the loss is flat on the side where the face is beyond its points, so the scan, not
 * the local search, has to place it); from the best, if better than staying, the pair of
 * refinements runs again and its result is kept when lower on the loss at the chain's
 * scale. */
#define FIT_SCAN_POINTS 16
/* Levels of the scan: each spans the two cells around the best of the last, so three
 * levels end at 1/1024 of the range. */
#define FIT_SCAN_LEVELS 3
/* The scan's best is refined from only when it lies this fraction of the range or
 * more from the value (the accuracy the CAD suite asks for). */
#define FIT_SCAN_MOVE 0.01
/* Points the scan evaluates: it only places a parameter roughly (FIT_SCAN_MOVE) before
 * the refinements on all points take over, and on all points it cost 60% of the CPU
 * time of the paper's part (10,714 points: 0.87 s, 0.36 s without the scan). 2,048
 * were too few: the min/max bushing with 2% outliers (4,000 points, seed 1) ended
 * 0.398 of a range off. */
#define FIT_SCAN_SUBSET 4096

static fit_status polish_chain(fit_run_ctx *R, double *x, double *fx, double *scale)
{
    fit_status st = refine_pair(R, x, fx, scale);
    if (st == FIT_STOPPED || !isfinite(*scale) || R->lo == NULL || R->hi == NULL) return st;
    /* Scanned on the annealing's model when there is one: min/max's loss is flat on
     * the side where the face is beyond its points (they belong to other faces), the
     * R-function's still falls toward the face's place. */
    fit_objective *full = R->geo_s != NULL ? R->geo_s : R->geo, *scan = R->scan;
    for (size_t j = 0; j < R->m; j++) {
        double lo = R->lo[j], hi = R->hi[j], range = hi - lo;
        /* polled per parameter: the scan of all of them ran 1-3 s of CPU after a
         * Ctrl-C on 100,000 points under load (tests/interrupt.sh) */
        if (interrupted(R)) return FIT_STOPPED;
        if (!(range > 0) || !isfinite(range)) continue;
        fit_objective_set_loss(R->geo, FIT_LOSS_CAUCHY, *scale);
        fit_objective_set_loss(scan, FIT_LOSS_CAUCHY, fit_objective_loss_scale(full));
        double y[FIT_MAX_PARAMS];
        memcpy(y, x, R->m * sizeof *y);
        double here = fit_objective_value(R->geo, x, NULL);
        double best = fit_objective_value(scan, x, NULL), at = x[j];
        R->ctl.evals += 2;
        double a = lo, cell = range / FIT_SCAN_POINTS;
        for (int level = 0; level < FIT_SCAN_LEVELS; level++) {
            for (int k = 0; k < FIT_SCAN_POINTS; k++) {
                y[j] = fmin(hi, fmax(lo, a + (k + 0.5) * cell));
                double v = fit_objective_value(scan, y, NULL);
                R->ctl.evals++;
                if (v < best) best = v, at = y[j];
            }
            a = at - cell, cell *= 2.0 / FIT_SCAN_POINTS;
        }
        if (!(fabs(at - x[j]) > FIT_SCAN_MOVE * range)) continue;
        if (fit_control_stop(&R->ctl)) return FIT_STOPPED;
        y[j] = at;
        double fy, sy;
        fit_status ys = refine_pair(R, y, &fy, &sy);
        if (ys == FIT_STOPPED) return ys;
        fit_objective_set_loss(R->geo, FIT_LOSS_CAUCHY, *scale);
        double v = fit_objective_value(R->geo, y, NULL);
        R->ctl.evals++;
        if (v < here) {
            memcpy(x, y, R->m * sizeof *x);
            *fx = fy, *scale = sy, st = ys;
        }
    }
    if (isfinite(*scale)) fit_objective_set_loss(R->geo, FIT_LOSS_CAUCHY, *scale);
    return st;
}

/* Refuse what cannot be fitted before any work: no or too many parameters, fewer points
 * than parameters, start values that are not finite or outside their bounds, and
 * infinite bounds for the annealing, which searches the whole box. */
static int check_arguments(const fit_run_ctx *R, frep_error *err)
{
    const size_t np = R->m;
    const double *lo = R->lo, *hi = R->hi, *p = R->start;
    if (np == 0) return frep_error_set(err, FREP_EINPUT, "the template has no free parameters");
    if (np > FIT_MAX_PARAMS)
        return frep_error_set(err, FREP_ELIMIT, "%zu free parameters; at most %d are supported",
                              np, FIT_MAX_PARAMS);
    if (R->cfg->surrogate != NULL && R->cfg->surrogate->nparams != np)
        return frep_error_set(err, FREP_EINPUT, "the annealing's model has %zu parameters, "
                              "not %zu", R->cfg->surrogate->nparams, np);
    if (R->pts->n < np)
        return frep_error_set(err, FREP_EINPUT, "%zu points cannot determine %zu parameters",
                              R->pts->n, np);
    for (size_t j = 0; j < np; j++) {
        if (!isfinite(p[j]))
            return frep_error_set(err, FREP_EINPUT, "parameter %zu has no finite start value",
                                  j + 1);
        if ((lo && p[j] < lo[j]) || (hi && p[j] > hi[j]))
            return frep_error_set(err, FREP_EINPUT,
                                  "parameter %zu starts at %g, outside its bounds [%g, %g]",
                                  j + 1, p[j], lo[j], hi[j]);
        if (R->global && (lo == NULL || hi == NULL || !isfinite(lo[j]) || !isfinite(hi[j])))
            return frep_error_set(err, FREP_EINPUT,
                                  "parameter %zu has no finite bounds, which --method %s needs",
                                  j + 1, fit_method_name(R->cfg->method));
    }
    return 0;
}

/* The robust annealing leaves out isolated points: those whose FIT_ISOLATION_K-th
 * nearest neighbour is farther than FIT_ISOLATION_RATIO times the median of that
 * distance over the cloud. Points of a surface have neighbours at the sampling's
 * spacing; outliers spread over a volume are far from any. Least squares of the
 * algebraic field over such outliers is minimized by wrong shapes (a quadratic
 * cylinder grows over them: on the bushing with 2% outliers the flange radius went to
 * its bound on 5 seeds of 5), and the local phase cannot bring a face back from beyond
 * every point. The robust refinement still sees every point. */
#define FIT_ISOLATION_K 8
#define FIT_ISOLATION_RATIO 2
/* A cloud with more isolated points than this share has outliers, and the outliers the
 * isolation test keeps (those near the surface) still pull least squares: the
 * annealing's default sum of squares (--sa-loss l2) becomes Geman-McClure there.  The
 * suite's clouds (4,000 points) have 0-1 isolated points clean, at 0.2% and at 1% noise,
 * 50-60 with 2% outliers and 122-147 with 5%.  With 5% outliers the sum of squares ended
 * every chain of the bracket with its wall at the top bound, and the refinements in a
 * basin that trades the wall's top face for a smaller hole (2 seeds of 10 wrong, 1 with
 * Geman-McClure); with 2% the bushings took 11,600 evaluations, 6,800 with it. */
#define FIT_ISOLATED_OUTLIERS 0.005

/* keep[n] (caller frees): 0 for the isolated points, 1 for the others; *dropped gets
 * how many were left out. NULL when out of memory. */
static unsigned char *isolation_mask(const fit_points *P, int nthreads, size_t *dropped)
{
    const size_t n = P->n;
    *dropped = 0;
    unsigned char *keep = frep_malloc(n ? n : 1);
    double *dk = frep_malloc((n ? 2 * n : 1) * sizeof *dk);
    kd_tree *t = n > FIT_ISOLATION_K ? kd_build(n, P->x, P->y, P->z) : NULL;
    if (keep == NULL || dk == NULL || (n > FIT_ISOLATION_K && t == NULL)) {
        frep_free(keep);
        frep_free(dk);
        kd_free(t);
        return NULL;
    }
    memset(keep, 1, n);
    if (t != NULL) {
        int nt = frep_threads(nthreads);
#pragma omp parallel for num_threads(nt) schedule(static)
        for (long i = 0; i < (long)n; i++) {
            uint32_t idx[FIT_ISOLATION_K + 1];
            double d2[FIT_ISOLATION_K + 1];
            const double q[3] = {P->x[i], P->y[i], P->z[i]};
            size_t got = kd_knn(t, q, FIT_ISOLATION_K + 1, idx, d2); /* itself first */
            dk[i] = sqrt(d2[got - 1]);
        }
        memcpy(dk + n, dk, n * sizeof *dk);
        double cut = FIT_ISOLATION_RATIO * median(dk + n, n);
        for (size_t i = 0; i < n; i++)
            if (dk[i] > cut) keep[i] = 0, ++*dropped;
    }
    kd_free(t);
    frep_free(dk);
    return keep;
}

/* The objectives: the local phase's on all points, and the annealing's (its own kind
 * when --global-objective differs, on a random subset of cfg->sa_points). */
static int make_objectives(fit_run_ctx *R, frep_error *err)
{
    const fit_config *cfg = R->cfg;
    R->obj = R->sub = fit_objective_new(R->model, R->pts, &cfg->obj);
    if (R->obj == NULL) return frep_error_nomem(err);
    R->diag = points_diagonal(R->pts);
    if (!(R->diag > 0) || !isfinite(R->diag)) R->diag = 1;
    R->rbuf = frep_malloc((R->pts->n ? R->pts->n : 1) * sizeof *R->rbuf);
    if (R->rbuf == NULL) return frep_error_nomem(err);
    if (cfg->robust && cfg->method != FIT_METHOD_SA) {
        fit_objective_config gc = cfg->obj;
        gc.kind = FIT_OBJ_GEOMETRIC;
        gc.loss = FIT_LOSS_CAUCHY;
        gc.loss_scale = FIT_ROBUST_FLOOR * R->diag;
        R->geo = fit_objective_new(R->model, R->pts, &gc);
        if (R->global && cfg->surrogate != NULL) {
            R->geo_s = fit_objective_new(cfg->surrogate, R->pts, &gc);
            if (R->geo_s == NULL) return frep_error_nomem(err);
        }
        if (R->geo == NULL) return frep_error_nomem(err);
        fit_objective *full = R->geo_s != NULL ? R->geo_s : R->geo;
        R->scan = R->pts->n > FIT_SCAN_SUBSET
                      ? fit_objective_subset(full, FIT_SCAN_SUBSET, cfg->seed, NULL) : full;
        if (R->scan == NULL) return frep_error_nomem(err);
    }
    if (!R->global) return 0;
    fit_objective *gobj = R->obj;
    if (cfg->global_kind != cfg->obj.kind || cfg->surrogate != NULL) {
        fit_objective_config gc = cfg->obj;
        gc.kind = cfg->global_kind;
        gobj = R->sub = fit_objective_new(cfg->surrogate != NULL ? cfg->surrogate : R->model,
                                          R->pts, &gc);
        if (gobj == NULL) {
            R->sub = R->obj;
            return frep_error_nomem(err);
        }
    }
    unsigned char *keep = NULL;
    size_t dropped = 0;
    if (R->geo != NULL) {
        keep = isolation_mask(R->pts, cfg->obj.nthreads, &dropped);
        if (keep == NULL) {
            if (gobj != R->obj) fit_objective_free(gobj);
            R->sub = R->obj;
            return frep_error_nomem(err);
        }
    }
    if ((cfg->sa_points > 0 && cfg->sa_points < R->pts->n) || dropped > 0) {
        size_t count = cfg->sa_points > 0 ? cfg->sa_points : R->pts->n;
        R->sub = fit_objective_subset(gobj, count, cfg->seed, dropped > 0 ? keep : NULL);
        frep_free(keep);
        keep = NULL;
        if (gobj != R->obj) fit_objective_free(gobj);
        if (R->sub == NULL) {
            R->sub = R->obj;
            return frep_error_nomem(err);
        }
    }
    frep_free(keep);
    if (R->geo != NULL && cfg->global_kind == FIT_OBJ_ALGEBRAIC && R->sub == R->obj) {
        /* The annealing's loss is changed below: it needs its own objective. */
        fit_objective_config gc = cfg->obj;
        gc.kind = cfg->global_kind;
        R->sub = fit_objective_new(R->model, R->pts, &gc);
        if (R->sub == NULL) {
            R->sub = R->obj;
            return frep_error_nomem(err);
        }
    }
    fit_loss sa_loss = cfg->sa_loss;
    if (sa_loss == FIT_LOSS_L2 && (double)dropped > FIT_ISOLATED_OUTLIERS * (double)R->pts->n)
        sa_loss = FIT_LOSS_GEMAN;
    if (R->geo != NULL && sa_loss != FIT_LOSS_L2 && cfg->obj.loss == FIT_LOSS_L2) {
        size_t n = fit_objective_npoints(R->sub);
        double *g = frep_malloc((n ? n : 1) * sizeof *g);
        if (g == NULL) return frep_error_nomem(err);
        double s = FIT_SA_CAUCHY * R->diag;
        if (cfg->global_kind == FIT_OBJ_ALGEBRAIC &&
            fit_objective_grad_norms(R->sub, R->start, g) == 0 && n > 0)
            s *= median(g, n);
        frep_free(g);
        if (isfinite(s) && s > 0) fit_objective_set_loss(R->sub, sa_loss, s);
    }
    return 0;
}

static void free_objectives(fit_run_ctx *R)
{
    if (R->scan != R->geo && R->scan != R->geo_s) fit_objective_free(R->scan);
    fit_objective_free(R->geo);
    fit_objective_free(R->geo_s);
    frep_free(R->rbuf);
    if (R->sub != R->obj) fit_objective_free(R->sub);
    fit_objective_free(R->obj);
}

/* The budget every phase shares: evaluations, wall clock, Ctrl-C, progress reports. */
static void start_control(fit_run_ctx *R)
{
    const fit_config *cfg = R->cfg;
    fit_control_init(&R->ctl);
    R->ctl.max_evals = cfg->max_evals;
    R->ctl.deadline = cfg->max_time > 0 ? R->t0 + cfg->max_time : 0;
    R->ctl.interrupt = cfg->interrupt;
    R->ctl.cancel = cfg->cancel;
    R->ctl.cancel_user = cfg->progress_user;
    if (cfg->progress != NULL) {
        R->ctl.progress = on_progress;
        R->ctl.progress_user = R;
    }
    R->best_sub = R->best_all = R->best_geo = HUGE_VAL;
    if (R->geo != NULL) fit_objective_watch_nomem(R->geo, &R->ctl.out_of_memory);
    if (R->geo_s != NULL) fit_objective_watch_nomem(R->geo_s, &R->ctl.out_of_memory);
    /* Out of memory in an evaluation stops every phase, as in a phase's own arrays. */
    fit_objective_watch_nomem(R->obj, &R->ctl.out_of_memory);
    fit_objective_watch_nomem(R->sub, &R->ctl.out_of_memory);
}

/* The objective at the start values: what the result must not be worse than. Without an
 * annealing there is nowhere else to start, so it must be finite. */
static int evaluate_start(fit_run_ctx *R, frep_error *err)
{
    memcpy(R->x, R->start, R->m * sizeof *R->x);
    R->f0 = fit_objective_value(R->obj, R->x, NULL);
    R->ctl.evals++;
    if (R->ctl.out_of_memory) return frep_error_nomem(err);
    if (!isfinite(R->f0) && !R->global)
        return frep_error_set(err, FREP_EINPUT, "the model cannot be evaluated at the start "
                                                "values (a runtime error or a non-finite value)");
    return 0;
}

/* Global phase (doc/fit.md, step 1): the annealing chains. With a local phase the chains
 * run one at a time and each chain's best is polished on all points with the local
 * objective before the best is chosen: on noisy clouds the annealing's objective
 * (algebraic, on a subset) can rank a wrong basin below the right one, the final
 * objective (geometric, all points) tells them apart far better. Without one (--method
 * sa), fit_sa runs all chains itself. */
/* Chains added, at most, while every chain so far ends with a parameter on its bound:
 * in a template that is usually a feature switched off (the bracket's slots shrunk to
 * their smallest radius and length where the annealing did not find them, 2% outliers,
 * both brackets, seed 2), which no refinement switches on again; a chain from another
 * random start can find it. A template whose truth lies on a bound pays the chains. */
#define FIT_BOUND_CHAINS 2
/* Relative distance to a bound under which a parameter counts as on it (the report's
 * warning, api/api_fit.c, uses the same). */
#define FIT_CHAIN_ON_BOUND 1e-6
/* Distance, relative to each parameter's range, under which two chains' bests count as
 * the same minimum of the annealing's objective (the local searches end there to about
 * 1e-9 of the range): a later chain stops when it reaches an earlier one's, and takes
 * over that chain's refined result. */
#define FIT_CHAIN_AGREE 1e-6

/* A chain whose result puts FIT_ONE_CHAIN_SHARE of the points within FIT_WITHIN of the
 * diagonal of the surface (all points) has found the shape: the next chains are there to
 * find a better basin, and none explains the points better than that, so they are not
 * run.  On the paper's part the second chain was 4 of the 7 local searches inside the
 * annealing.  A wrong basin that leaves out a feature with 0.1% of the points, noise over
 * a fifth of FIT_WITHIN or outliers over 0.1% of the points keep every chain. */
#define FIT_ONE_CHAIN_SHARE 0.999
/* The first-order distances |f|/|grad f| decide for most points; they overestimate where
 * the gradient vanishes (hfBlock's quadratic slabs at the middle of a thin plate: 3% of
 * the bracket's points at 0.2% noise, from a chain at the truth), so the points they put
 * farther are measured again by projection (fit/measure.c), when they are at most this
 * share of the points (more could not be within the rule's tolerance by much). */
#define FIT_ONE_CHAIN_RECHECK 0.1

/* How many of the k points whose first-order distance in R->rbuf exceeds tol lie within
 * tol of the surface at x: true distances (upper bounds) on the annealing's model, as the
 * report measures them. 0 when memory runs out or the model cannot be evaluated: the
 * chains then run. */
static size_t far_within(fit_run_ctx *R, const double *x, size_t k, double tol)
{
    double *buf = frep_malloc(4 * k * sizeof *buf);
    if (buf == NULL) return 0;
    double *px = buf, *py = buf + k, *pz = buf + 2 * k, *d = buf + 3 * k;
    size_t j = 0;
    for (size_t i = 0; i < R->pts->n && j < k; i++)
        if (!(R->rbuf[i] <= tol))
            px[j] = R->pts->x[i], py[j] = R->pts->y[i], pz[j++] = R->pts->z[i];
    fit_points far = {j, px, py, pz, NULL, NULL, NULL};
    const fit_model *surface = R->cfg->surrogate != NULL ? R->cfg->surrogate : R->model;
    fit_distance_stats ds;
    size_t in = 0;
    if (fit_distances(surface, x, &far, R->diag, R->cfg->obj.nthreads, d, &ds) == 0)
        for (size_t i = 0; i < j; i++) in += d[i] <= tol;
    frep_free(buf);
    return in;
}

static int explains_all(fit_run_ctx *R, const double *x)
{
    size_t n = R->pts->n, in = 0;
    double tol = FIT_WITHIN * R->diag;
    if (n == 0 || fit_objective_residuals(R->obj, x, R->rbuf) < 0) return 0;
    R->ctl.evals++;
    for (size_t i = 0; i < n; i++) in += R->rbuf[i] <= tol;
    if ((double)in < FIT_ONE_CHAIN_SHARE * (double)n &&
        (double)(n - in) <= FIT_ONE_CHAIN_RECHECK * (double)n)
        in += far_within(R, x, n - in, tol);
    return (double)in >= FIT_ONE_CHAIN_SHARE * (double)n;
}

static int all_on_bound(const fit_run_ctx *R, const double *keep, long kept)
{
    if (R->lo == NULL || R->hi == NULL) return 0;
    for (long k = 0; k < kept; k++) {
        const double *x = keep + (size_t)k * R->m;
        int on = 0;
        for (size_t j = 0; j < R->m && !on; j++) {
            double tol = FIT_CHAIN_ON_BOUND * (R->hi[j] - R->lo[j]);
            on = x[j] <= R->lo[j] + tol || x[j] >= R->hi[j] - tol;
        }
        if (!on) return 0;
    }
    return 1;
}

static int global_phase(fit_run_ctx *R, frep_error *err)
{
    const size_t np = R->m;
    frep_rng rng;
    frep_rng_seed(&rng, R->cfg->seed ^ FIT_SA_SEED_SALT);
    fit_sa_options so = R->cfg->sa;
    if (R->cfg->sa_local) {
        so.local = sa_local;
        so.local_user = R;
    }
    long chains = so.chains > 0 ? so.chains : 1;
    int polish = R->cfg->method != FIT_METHOD_SA;
    if (polish) so.chains = 1;
    else chains = 1;
    double xs[FIT_MAX_PARAMS], fx = HUGE_VAL, fbest = HUGE_VAL;
    fit_status st_best = FIT_STALLED;
    R->nchains = polish ? chains : so.chains > 0 ? so.chains : 1;
    /* Robust: each chain's refined point, scale and status, compared after the last. */
    int robust = polish && R->geo != NULL;
    double *keep = NULL, *scales = NULL, *bests = NULL;
    fit_status *kst = NULL;
    long kept = 0;
    long limit = chains;                /* grows while every chain ends on a bound */
    if (robust) {
        long room = chains + FIT_BOUND_CHAINS;
        keep = frep_malloc((size_t)room * (2 * np + 1) * sizeof *keep);
        kst = frep_malloc((size_t)room * sizeof *kst);
        if (keep == NULL || kst == NULL) {
            frep_free(keep);
            frep_free(kst);
            return frep_error_nomem(err);
        }
        scales = keep + (size_t)room * np;
        bests = scales + room;
        so.agree = bests;
        so.agree_tol = FIT_CHAIN_AGREE;
    }
    for (long k = 0; k < limit; k++) {
        R->chain = k + 1;
        R->active = R->sub;
        /* Chains after the first start at a random point (fit_sa picks one for a start
         * outside the box). */
        memcpy(xs, R->start, np * sizeof *xs);
        if (k > 0) xs[0] = HUGE_VAL;
        long its = 0;
        R->st = fit_sa(fit_objective_value, R->sub, np, xs, R->lo, R->hi, &so, &rng, &R->ctl,
                       &fx, &its);
        R->sa_iterations += its;
        if (R->st == FIT_NOMEM || R->ctl.out_of_memory) {
            frep_free(keep);
            frep_free(kst);
            return frep_error_nomem(err);
        }
        if (R->st == FIT_FAILED) {
            if (k > 0) break;
            frep_free(keep);
            frep_free(kst);
            return frep_error_set(err, FREP_EINPUT, "the model cannot be evaluated anywhere "
                                  "the annealing looked (runtime errors or non-finite values)");
        }
        if (robust) {
            /* The chain's best is polished on the subset already; the robust
             * refinement takes it from there on all points, unless an earlier chain
             * ended at the same point: its refinement would be repeated. */
            double sc = NAN;
            long same = R->st == FIT_STOPPED ? -1 : fit_sa_agreeing(&so, np, xs, R->lo, R->hi);
            memcpy(bests + (size_t)kept * np, xs, np * sizeof *xs);
            so.nagree = kept + 1;
            if (same >= 0) {
                memcpy(xs, keep + (size_t)same * np, np * sizeof *xs);
                sc = scales[same];
                R->st = kst[same];
            } else if (R->st != FIT_STOPPED)
                R->st = polish_chain(R, xs, &fx, &sc);
            memcpy(keep + (size_t)kept * np, xs, np * sizeof *xs);
            scales[kept] = sc;
            kst[kept++] = R->st;
            if (R->st == FIT_STOPPED) break;
            if (k == limit - 1 && limit < chains + FIT_BOUND_CHAINS &&
                all_on_bound(R, keep, kept))
                limit++, R->nchains = limit;
            if (k + 1 < limit && explains_all(R, xs)) break;
            continue;
        }
        if (polish && R->st != FIT_STOPPED)
            R->st = local_phase(R, R->obj, xs, &fx, 0, R->cfg->reweight_rounds);
        else if (R->st != FIT_STOPPED)
            R->st = FIT_STALLED;                        /* the annealing tests no optimality */
        fx = fit_objective_value(R->obj, xs, NULL);     /* comparable across chains */
        R->ctl.evals++;
        if (fx < fbest || k == 0) {
            fbest = fx;
            st_best = R->st;
            memcpy(R->x, xs, np * sizeof *R->x);
        }
        if (R->st == FIT_STOPPED) break;
        if (polish && k + 1 < limit && explains_all(R, R->x)) break;
    }
    if (robust && kept > 0) {
        /* Compare the chains on the Cauchy loss at the smallest scale: the right basin
         * has the smallest residuals, and at its scale a wrong one pays for the points
         * it misses. One chain needs no comparison; after Ctrl-C they are compared on
         * the annealing's subset (all points cost seconds on a large cloud, 2.5 s of
         * CPU on 100,000 points under a sanitizer, while the user waits). */
        fit_objective *judge = interrupted(R) ? R->sub : R->geo;
        double s = HUGE_VAL;
        for (long k = 0; k < kept; k++)
            if (isfinite(scales[k])) s = fmin(s, scales[k]);
        if (isfinite(s)) fit_objective_set_loss(R->geo, FIT_LOSS_CAUCHY, s);
        for (long k = 0; k < kept; k++) {
            double v = kept == 1 ? 0 : fit_objective_value(judge, keep + (size_t)k * np, NULL);
            R->ctl.evals += kept > 1;
            if (v < fbest || k == 0) {
                fbest = v;
                st_best = kst[k];
                memcpy(R->x, keep + (size_t)k * np, np * sizeof *R->x);
            }
        }
    }
    frep_free(keep);
    frep_free(kst);
    if (R->st != FIT_STOPPED) R->st = st_best;
    return 0;
}

/* Local phase alone (--method qn or lm, doc/fit.md step 3) from the start values. */
static int local_only(fit_run_ctx *R)
{
    double fx = HUGE_VAL;
    R->st = local_phase(R, R->obj, R->x, &fx, 0, R->cfg->reweight_rounds);
    if (R->geo != NULL && R->st != FIT_STOPPED && R->st != FIT_FAILED && R->st != FIT_NOMEM) {
        double sc;
        R->st = robust_refine(R, R->geo, R->x, &fx, &sc, R->st);
    }
    return 0;
}

/* Diagonal of the points' bounding box. */
static double points_diagonal(const fit_points *P)
{
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (size_t i = 0; i < P->n; i++) {
        const double v[3] = {P->x[i], P->y[i], P->z[i]};
        for (int c = 0; c < 3; c++) lo[c] = fmin(lo[c], v[c]), hi[c] = fmax(hi[c], v[c]);
    }
    double d = 0;
    for (int c = 0; c < 3; c++) d += P->n ? (hi[c] - lo[c]) * (hi[c] - lo[c]) : 0;
    return sqrt(d);
}

/* res->noise, outliers and within_inliers from the distances d[n] (reordered). */
static void noise_and_outliers(double *d, size_t n, double diag, fit_result *res)
{
    res->noise = res->within_inliers = NAN;
    res->outliers = 0;
    if (n == 0) return;
    double sigma = 1.4826 * median(d, n);
    double cut = fmax(FIT_OUTLIER_SIGMAS * sigma, FIT_WITHIN * diag);
    double tol = FIT_WITHIN * diag;
    size_t in = 0, near = 0;
    for (size_t i = 0; i < n; i++) {
        if (!(d[i] <= cut)) continue;
        in++;
        near += d[i] <= tol;
    }
    res->noise = sigma;
    res->outliers = n - in;
    res->within_inliers = in ? (double)near / (double)in : 0;
}

/* The figures a person judges the fit by: true distances (their RMS, maximum and the
 * share within FIT_WITHIN of the diagonal) and each parameter's sensitivity and
 * standard error. Left NaN when the model cannot be evaluated; -1 when memory for the
 * distances runs out. */
static int measure(fit_run_ctx *R, fit_result *res)
{
    const size_t n = R->pts->n;
    double diag = res->diagonal > 0 && isfinite(res->diagonal) ? res->diagonal : 1;
    double *d = frep_malloc((n ? n : 1) * sizeof *d);
    if (d == NULL) return -1;
    fit_distance_stats ds;
    /* The annealing's model has the same surface; its R-function field gives first-order
     * estimates that the projection's acceptance test can trust, where min/max's
     * overestimate near thin plates (fit/measure.c). */
    const fit_model *surface = R->cfg->surrogate != NULL ? R->cfg->surrogate : R->model;
    if (fit_distances(surface, R->x, R->pts, diag, R->cfg->obj.nthreads, d, &ds) == 0) {
        size_t in = 0;
        for (size_t i = 0; i < n; i++) in += d[i] <= FIT_WITHIN * diag;
        res->rms = ds.rms, res->max_dist = ds.max;
        res->within = n ? (double)in / (double)n : 0;
        noise_and_outliers(d, n, diag, res);
        res->dist_searched = ds.searched, res->dist_unresolved = ds.unresolved;
    }
    frep_free(d);
    /* A robust fit's outliers would swamp s^2: they are left out. */
    double cut = R->geo != NULL && isfinite(res->noise)
                     ? fmax(FIT_OUTLIER_SIGMAS * res->noise, FIT_WITHIN * diag) : HUGE_VAL;
    res->have_uncertainty = fit_uncertainty(R->model, R->x, R->pts, cut, res->sens,
                                            res->sigma) == 0;
    return 0;
}

/* The result: never worse than the start, with its distances, counts and time; 0, or
 * -1 with err set when out of memory. */
static int finish(fit_run_ctx *R, double *params, fit_result *res, frep_error *err)
{
    const size_t np = R->m;
    /* Robust: compared on the robust loss at its last scale, the one the result
     * minimizes (least squares would prefer a start that fits the outliers better).
     * After Ctrl-C on the annealing's subset (at most a few thousand points), so that
     * the answer comes at once whatever the cloud's size. */
    fit_objective *judge = interrupted(R) ? R->sub : R->geo != NULL ? R->geo : R->obj;
    double fx = fit_objective_value(judge, R->x, NULL);
    if (judge != R->obj) R->f0 = fit_objective_value(judge, R->start, NULL);
    if (R->ctl.out_of_memory) return frep_error_nomem(err);
    if (!(fx <= R->f0)) {
        memcpy(R->x, R->start, np * sizeof *R->x);
        fx = R->f0;
    }
    memcpy(params, R->x, np * sizeof *params);
    res->objective = fx;
    res->rms = res->max_dist = res->within = res->noise = res->within_inliers = NAN;
    res->diagonal = points_diagonal(R->pts);
    /* After Ctrl-C the result is kept unmeasured (NaN): the true distances search
     * around every point, seconds on a large cloud, and poll nothing. */
    if (R->cfg->report && !interrupted(R) && measure(R, res) != 0) return frep_error_nomem(err);
    res->evals = R->ctl.evals;
    res->status = R->st;
    res->sa_iterations = R->sa_iterations;
    res->local_iterations = R->local_iterations;
    res->seconds = frep_now_seconds() - R->t0;
    return 0;
}

int fit_run(const fit_model *m, const fit_points *pts, const double *lo, const double *hi,
            double *params, const fit_config *cfg, fit_result *res, frep_error *err)
{
    memset(res, 0, sizeof *res);
    fit_run_ctx R = {.cfg = cfg, .model = m, .pts = pts, .m = m->nparams, .lo = lo,
                     .hi = hi, .start = params, .t0 = frep_now_seconds(), .st = FIT_CONVERGED};
    R.global = cfg->method == FIT_METHOD_SAQN || cfg->method == FIT_METHOD_SA;
    if (check_arguments(&R, err) != 0) return -1;
    if (make_objectives(&R, err) != 0) {
        free_objectives(&R);
        return -1;
    }
    start_control(&R);
    int rc = evaluate_start(&R, err);
    if (rc == 0) rc = R.global ? global_phase(&R, err) : local_only(&R);
    if (rc == 0 && R.ctl.out_of_memory) rc = frep_error_nomem(err);
    if (rc == 0) rc = finish(&R, params, res, err);
    free_objectives(&R);
    return rc;
}

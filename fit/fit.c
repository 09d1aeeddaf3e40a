/* fit.c - the template-fitting driver: global phase (chains of generalized simulated
 * annealing on a subset of the points, with short BFGS searches from each new best, as
 * in dual annealing), then the local phase (BFGS or Levenberg-Marquardt on all points)
 * from each chain's best, keeping the best result.
 * Sits between cli/cmd_fit.c and fit/optim.c + fit/objective.c.
 */
#include "alloc.h"
#include "fit.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- names ----------------------------------------------------------------- */

static const char *const method_names[] = {"saqn", "qn", "sa", "lm"};
static const char *const objective_names[] = {"algebraic", "geometric"};
static const char *const loss_names[] = {"l2", "huber", "cauchy"};

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
    int i = lookup(loss_names, 3, s);
    if (i < 0) return -1;
    *l = (fit_loss)i;
    return 0;
}

/* ---- configuration ------------------------------------------------------------ */

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
    fit_qn_options_init(&c->qn);
    fit_lm_options_init(&c->lm);
    c->reweight_rounds = 8;
}

/* ---- the frep_program adapter ------------------------------------------------ */

typedef struct prog_model {
    const frep_program *p;
    size_t nall, nfree;
    size_t *idx;                /* nfree program parameter indices */
    double *base;               /* nall values of the held parameters */
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
    if (dp != NULL) {
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

/* ---- phases ------------------------------------------------------------------------ */

static void set_err(char *err, size_t len, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static void set_err(char *err, size_t len, const char *fmt, ...)
{
    if (err == NULL || len == 0) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, len, fmt, ap);
    va_end(ap);
}

typedef struct fit_run_ctx {
    const fit_config *cfg;
    fit_objective *obj;         /* all points */
    fit_objective *sub;         /* the annealing's subset (may be obj itself) */
    size_t m;
    const double *lo, *hi;
    fit_control *ctl;
    int local_iterations;
} fit_run_ctx;

/* Local phase on objective o from x: BFGS (or LM), and for the geometric kind rounds of
 * frozen weights until the parameters settle. */
static fit_status local_phase(fit_run_ctx *R, fit_objective *o, double *x, double *fx,
                              int max_iter, int rounds)
{
    const fit_config *cfg = R->cfg;
    fit_qn_options qn = cfg->qn;
    fit_lm_options lm = cfg->lm;
    if (max_iter > 0) qn.max_iter = lm.max_iter = max_iter;
    int geo = fit_objective_kind_of(o) == FIT_OBJ_GEOMETRIC;
    if (!geo) rounds = 1;
    fit_status st = FIT_FAILED;
    double prev[FIT_MAX_PARAMS];
    for (int r = 0; r < rounds; r++) {
        memcpy(prev, x, R->m * sizeof *x);
        if (geo && fit_objective_freeze(o, x) != 0) break;
        int it = 0;
        if (cfg->method == FIT_METHOD_LM)
            st = fit_lm(fit_objective_lsq, o, R->m, x, R->lo, R->hi, &lm, R->ctl, fx, &it);
        else
            st = fit_bfgs(fit_objective_value, o, R->m, x, R->lo, R->hi, &qn, R->ctl, fx, &it);
        R->local_iterations += it;
        if (st == FIT_FAILED || st == FIT_STOPPED) break;
        double change = 0, scale = 0;
        for (size_t j = 0; j < R->m; j++) {
            change = fmax(change, fabs(x[j] - prev[j]));
            scale = fmax(scale, fabs(x[j]));
        }
        if (change <= 1e-9 * (1 + scale)) break;
    }
    if (geo) {
        fit_objective_unfreeze(o);
        *fx = fit_objective_value(o, x, NULL);
    }
    return st;
}

/* Inner local search of the annealing (fit_sa_options.local). */
static int sa_local(void *user, double *x, double *fx)
{
    fit_run_ctx *R = user;
    fit_status st = local_phase(R, R->sub, x, fx, R->cfg->sa_local_iter, 2);
    return st == FIT_FAILED || !isfinite(*fx) ? -1 : 0;
}

int fit_run(const fit_model *m, const fit_points *pts, const double *lo, const double *hi,
            double *params, const fit_config *cfg, fit_result *res, char *err, size_t errlen)
{
    const size_t np = m->nparams;
    memset(res, 0, sizeof *res);
    double t0 = fit_now();
    if (np == 0) {
        set_err(err, errlen, "the template has no free parameters");
        return -1;
    }
    if (np > FIT_MAX_PARAMS) {
        set_err(err, errlen, "%zu free parameters; at most %d are supported", np, FIT_MAX_PARAMS);
        return -1;
    }
    if (pts->n < np) {
        set_err(err, errlen, "%zu points cannot determine %zu parameters", pts->n, np);
        return -1;
    }
    int global = cfg->method == FIT_METHOD_SAQN || cfg->method == FIT_METHOD_SA;
    for (size_t j = 0; j < np; j++) {
        if (!isfinite(params[j])) {
            set_err(err, errlen, "parameter %zu has no finite start value", j + 1);
            return -1;
        }
        if ((lo && params[j] < lo[j]) || (hi && params[j] > hi[j])) {
            set_err(err, errlen, "parameter %zu starts at %g, outside its bounds [%g, %g]",
                    j + 1, params[j], lo[j], hi[j]);
            return -1;
        }
        if (global && (lo == NULL || hi == NULL || !isfinite(lo[j]) || !isfinite(hi[j]))) {
            set_err(err, errlen, "parameter %zu has no finite bounds, which --method %s needs",
                    j + 1, fit_method_name(cfg->method));
            return -1;
        }
    }

    fit_objective *obj = fit_objective_new(m, pts, &cfg->obj);
    if (obj == NULL) {
        set_err(err, errlen, "out of memory");
        return -1;
    }
    fit_objective *sub = obj, *gobj = obj;
    if (global && cfg->global_kind != cfg->obj.kind) {
        fit_objective_config gc = cfg->obj;
        gc.kind = cfg->global_kind;
        gobj = fit_objective_new(m, pts, &gc);
        if (gobj == NULL) {
            fit_objective_free(obj);
            set_err(err, errlen, "out of memory");
            return -1;
        }
        sub = gobj;
    }
    if (global && cfg->sa_points > 0 && cfg->sa_points < pts->n) {
        sub = fit_objective_subset(gobj, cfg->sa_points, cfg->seed);
        if (gobj != obj) fit_objective_free(gobj);
        gobj = NULL;
        if (sub == NULL) {
            fit_objective_free(obj);
            set_err(err, errlen, "out of memory");
            return -1;
        }
    }
    fit_control ctl;
    fit_control_init(&ctl);
    ctl.max_evals = cfg->max_evals;
    ctl.deadline = cfg->max_time > 0 ? t0 + cfg->max_time : 0;
    ctl.interrupt = cfg->interrupt;
    ctl.progress = cfg->progress;
    ctl.progress_user = cfg->progress_user;

    fit_run_ctx R = {cfg, obj, sub, np, lo, hi, &ctl, 0};
    double x[FIT_MAX_PARAMS], fx = HUGE_VAL;
    memcpy(x, params, np * sizeof *x);
    fit_status st = FIT_CONVERGED;

    double f0 = fit_objective_value(obj, x, NULL);
    ctl.evals++;
    if (!isfinite(f0) && !global) {
        fit_objective_free(sub != obj ? sub : NULL);
        fit_objective_free(obj);
        set_err(err, errlen, "the model cannot be evaluated at the start values "
                             "(a runtime error or a non-finite value)");
        return -1;
    }
    if (global) {
        frep_rng rng;
        frep_rng_seed(&rng, cfg->seed ^ 0x5a17ca1edULL);
        fit_sa_options so = cfg->sa;
        if (cfg->sa_local) {
            so.local = sa_local;
            so.local_user = &R;
        }
        /* With a local phase the chains run one at a time and each chain's best is
         * polished on all points with the local objective before the best is chosen:
         * on noisy clouds the annealing's objective (algebraic, on a subset) can rank a
         * wrong basin below the right one, the final objective (geometric, all points)
         * tells them apart far better. */
        long chains = so.chains > 0 ? so.chains : 1;
        int polish = cfg->method != FIT_METHOD_SA;
        if (polish) so.chains = 1;
        else chains = 1;
        double xs[FIT_MAX_PARAMS], best[FIT_MAX_PARAMS], fbest = HUGE_VAL;
        for (long k = 0; k < chains; k++) {
            /* Chains after the first start at a random point (fit_sa picks one for a
             * start outside the box). */
            memcpy(xs, params, np * sizeof *xs);
            if (k > 0) xs[0] = HUGE_VAL;
            long its = 0;
            st = fit_sa(fit_objective_value, sub, np, xs, lo, hi, &so, &rng, &ctl, &fx, &its);
            res->sa_iterations += its;
            if (st == FIT_FAILED) {
                if (k > 0) break;
                fit_objective_free(sub != obj ? sub : NULL);
                fit_objective_free(obj);
                set_err(err, errlen, "the model cannot be evaluated anywhere the annealing "
                                     "looked (runtime errors or non-finite values)");
                return -1;
            }
            if (polish && st != FIT_STOPPED)
                st = local_phase(&R, obj, xs, &fx, 0, cfg->reweight_rounds);
            fx = fit_objective_value(obj, xs, NULL);    /* comparable across chains */
            ctl.evals++;
            if (fx < fbest || k == 0) {
                fbest = fx;
                memcpy(best, xs, np * sizeof *best);
            }
            if (st == FIT_STOPPED) break;
        }
        memcpy(x, best, np * sizeof *x);
        fx = fbest;
    } else {
        st = local_phase(&R, obj, x, &fx, 0, cfg->reweight_rounds);
    }
    fx = fit_objective_value(obj, x, NULL);
    /* Never hand back something worse than the start. */
    if (!(fx <= f0)) {
        memcpy(x, params, np * sizeof *x);
        fx = f0;
    }
    memcpy(params, x, np * sizeof *x);
    res->objective = fx;
    if (fit_objective_distances(obj, x, &res->rms, &res->max_dist) != 0)
        res->rms = res->max_dist = NAN;
    res->evals = ctl.evals;
    res->status = st;
    res->local_iterations = R.local_iterations;
    res->seconds = fit_now() - t0;
    if (sub != obj) fit_objective_free(sub);
    fit_objective_free(obj);
    return 0;
}

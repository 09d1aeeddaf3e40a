/* api_fit.c - template fitting in the public API, the whole of `frep fit` but the
 * printing: the template compiled (and its R-function compilation for the annealing
 * of a min/max template), the parameters to fit and their bounds, the cloud checked,
 * fit/fit.c's run, the fitted template (fit/writeback.c), the parameters' warnings,
 * the verdict and the JSON report.
 */
#include "config.h"

#include "api.h"
#include "cloud.h"
#include "fit.h"
#include "program.h"
#include "writeback.h"

#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "alloc.h"
#include "util.h"

_Static_assert(FREP_FIT_SAQN == (int)FIT_METHOD_SAQN && FREP_FIT_QN == (int)FIT_METHOD_QN &&
                   FREP_FIT_SA == (int)FIT_METHOD_SA && FREP_FIT_LM == (int)FIT_METHOD_LM,
               "frep_fit_method follows fit/fit.h's fit_method");
_Static_assert(FREP_FIT_ALGEBRAIC == (int)FIT_OBJ_ALGEBRAIC &&
                   FREP_FIT_GEOMETRIC == (int)FIT_OBJ_GEOMETRIC,
               "frep_fit_objective follows fit_objective_kind");
_Static_assert(FREP_FIT_L2 == (int)FIT_LOSS_L2 && FREP_FIT_HUBER == (int)FIT_LOSS_HUBER &&
                   FREP_FIT_CAUCHY == (int)FIT_LOSS_CAUCHY && FREP_FIT_GEMAN == (int)FIT_LOSS_GEMAN,
               "frep_fit_loss follows fit_loss");

/* Room added around the cloud's bounding box in the `-- @box` line, as a fraction of its
 * diagonal: the surface must not touch the polygonizer's box. */
#define FIT_BOX_MARGIN 0.05
/* Fewest points a fit accepts beyond the number of parameters. */
#define FIT_MIN_POINTS 10
/* A fitted value this close to a bound, as a fraction of the range, is on it; this
 * close, near it. */
#define FIT_ON_BOUND 1e-6
#define FIT_NEAR_BOUND 0.01
/* A parameter whose whole range (or 1 + |value| when unbounded) moves the surface by
 * less than this fraction of the cloud's diagonal (RMS over the points) barely matters. */
#define FIT_TINY_EFFECT 1e-6
/* A standard error above this fraction of the parameter's range (or 1 + |value|) makes
 * it poorly determined by the points. */
#define FIT_LOOSE 0.05
/* Verdict: "good" needs this share of the points within FIT_WITHIN of the diagonal,
 * "poor" below FIT_VERDICT_POOR. */
#define FIT_VERDICT_GOOD 0.99
#define FIT_VERDICT_POOR 0.9
/* More points than this share taken for outliers make the fit poor whatever the rest:
 * the "outliers" are then more likely a part of the shape the model misses. */
#define FIT_VERDICT_OUTLIERS 0.25

struct frep_fit {
    api_diag d;                /* during frep_fit_template() only */
    const frep_fit_options *o;
    fit_config cfg;
    frep_program *p;
    frep_program *ps;          /* its R-function compilation, when it differs (min/max) */
    fit_model fm, fs;          /* p, and ps as the annealing's model */
    const char *src;           /* the template's text (the caller's, during the run) */
    size_t srclen;
    const char *file;
    size_t nall, nfree, nnamed; /* parameters: all, fitted, named by '-- @free' */
    frep_fit_param *rows;      /* the fitted ones */
    size_t *idx;               /* their indices in the program's parameter vector */
    double *base, *x0, *lo, *hi;
    frep_cloud *cloud;         /* during frep_fit_template() only */
    size_t npoints;
    double diagonal;
    fit_points pts;
    fit_result res;
    volatile sig_atomic_t stop; /* the cancel callback said stop */
    char *text;                /* the fitted template */
    size_t textlen;
    char verdict[320];         /* "good - 99.7% of points within 1% of the diagonal" */
    int nwarn;                 /* parameters with warnings */
};

/* ---- names (fit/fit.c's tables, the enums in step by the asserts above) ---- */

const char *frep_fit_method_name(frep_fit_method m)
{
    return (unsigned)m <= (unsigned)FREP_FIT_LM ? fit_method_name((fit_method)m) : NULL;
}

int frep_fit_method_parse(const char *name, frep_fit_method *out)
{
    fit_method m;
    if (!name || fit_method_parse(name, &m) != 0) return -1;
    *out = (frep_fit_method)m;
    return 0;
}

const char *frep_fit_objective_name(frep_fit_objective k)
{
    return (unsigned)k <= (unsigned)FREP_FIT_GEOMETRIC
               ? fit_objective_name((fit_objective_kind)k) : NULL;
}

int frep_fit_objective_parse(const char *name, frep_fit_objective *out)
{
    fit_objective_kind k;
    if (!name || fit_objective_parse(name, &k) != 0) return -1;
    *out = (frep_fit_objective)k;
    return 0;
}

const char *frep_fit_loss_name(frep_fit_loss l)
{
    return (unsigned)l <= (unsigned)FREP_FIT_GEMAN ? fit_loss_name((fit_loss)l) : NULL;
}

int frep_fit_loss_parse(const char *name, frep_fit_loss *out)
{
    fit_loss l;
    if (!name || fit_loss_parse(name, &l) != 0) return -1;
    *out = (frep_fit_loss)l;
    return 0;
}

void frep_fit_options_init(frep_fit_options *o)
{
    fit_config c;
    fit_config_init(&c);
    memset(o, 0, sizeof *o);
    o->method = (frep_fit_method)c.method;
    o->objective = (frep_fit_objective)c.obj.kind;
    o->global_objective = (frep_fit_objective)c.global_kind;
    o->loss = (frep_fit_loss)c.obj.loss;
    o->loss_scale = -1;
    o->sa_loss = (frep_fit_loss)c.sa_loss;
    o->robust = c.robust;
    o->normals_weight = c.obj.normals_weight;
    o->seed = c.seed;
    o->max_time = c.max_time;
    o->max_evals = c.max_evals;
    o->sa_points = c.sa_points;
    o->sa_stall = c.sa.stall_iter;
    o->sa_chains = c.sa.chains;
    o->sa_threshold = c.sa.threshold;
    o->nthreads = c.obj.nthreads;
}

#if defined(__GNUC__)
#define API_FIT_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define API_FIT_PRINTF(a, b)
#endif

/* A message of severity sev to the caller's callback. */
static void vreport(frep_fit *f, frep_severity sev, const char *fmt, va_list ap)
{
    char msg[512];
    vsnprintf(msg, sizeof msg, fmt, ap);
    api_report(&f->d, sev, msg);
}

static void reportf(frep_fit *f, frep_severity sev, const char *fmt, ...) API_FIT_PRINTF(3, 4);
static void reportf(frep_fit *f, frep_severity sev, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vreport(f, sev, fmt, ap);
    va_end(ap);
}

/* An error reported; returns -1. */
static int failf(frep_fit *f, const char *fmt, ...) API_FIT_PRINTF(2, 3);
static int failf(frep_fit *f, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vreport(f, FREP_ERROR, fmt, ap);
    va_end(ap);
    return -1;
}

static void ignore_diag(void *user, const frep_diag *d)
{
    (void)user, (void)d;
}

/* The template compiled, its parameter tables allocated. */
static int stage_template(frep_fit *f, const frep_compile_options *copt)
{
    f->p = frep_compile(f->file, f->src, f->srclen, copt, f->d.fn, f->d.user);
    if (f->p == NULL) return -1;
    if (f->o->max_work > 0 && frep_program_set_work_limit(f->p, f->o->max_work) != 0)
        return failf(f, "out of memory");
    /* A min/max template is annealed on its R-function compilation: the same parameters
     * and zero set, a smoother field (doc/fit.md). Its diagnostics were reported once. */
    frep_compile_options o = *copt;
    o.setops_override = FREP_SETOPS_RFUNC;
    o.strict = 0;
    f->ps = frep_compile(f->file, f->src, f->srclen, &o, ignore_diag, NULL);
    if (f->ps != NULL && f->ps->ncode == f->p->ncode && f->ps->nparams == f->p->nparams &&
        memcmp(f->ps->code, f->p->code, f->p->ncode * sizeof *f->p->code) == 0) {
        frep_program_free(f->ps);
        f->ps = NULL;
    }
    /* the annealing's program has a budget of its own, as large */
    if (f->ps != NULL && f->o->max_work > 0 &&
        frep_program_set_work_limit(f->ps, f->o->max_work) != 0)
        return failf(f, "out of memory");
    f->nall = frep_program_nparams(f->p);
    for (size_t i = 0; i < f->nall; i++) f->nnamed += f->p->params[i].end > f->p->params[i].off;
    size_t n = f->nall ? f->nall : 1;
    f->rows = frep_calloc(n, sizeof *f->rows);
    f->idx = frep_calloc(n, sizeof *f->idx);
    f->base = frep_calloc(n, sizeof *f->base);
    f->x0 = frep_calloc(n, sizeof *f->x0);
    f->lo = frep_calloc(n, sizeof *f->lo);
    f->hi = frep_calloc(n, sizeof *f->hi);
    if (!f->rows || !f->idx || !f->base || !f->x0 || !f->lo || !f->hi)
        return failf(f, "out of memory");
    if (f->o->nbounds > 0 && f->nnamed > 0)
        return failf(f, "%s: bounds of a[] are for templates fitted through a[]; this one has "
                        "'-- @free' parameters, whose bounds are in the template", f->file);
    return 0;
}

/* Is parameter i one to fit? The '-- @free' ones when there are any, else the a[]
 * elements the code reads. */
static int is_free(const frep_fit *f, size_t i)
{
    const frep_param_info *pi = &f->p->params[i];
    int named = pi->end > pi->off;
    if (f->nnamed > 0 ? !named : named) return 0;
    int used = named;
    for (uint32_t k = 0; k < f->p->ncode && !used; k++)
        used = f->p->code[k].op == FREP_OP_PARAM && f->p->code[k].arg == i;
    return used;
}

/* The parameters to fit, with their start values and bounds (o->lo, o->hi for a[]). */
static int stage_params(frep_fit *f, const frep_compile_options *copt)
{
    for (size_t i = 0; i < f->nall; i++) {
        const frep_param_info *pi = &f->p->params[i];
        f->base[i] = pi->value;
        if (!is_free(f, i)) continue;
        frep_fit_param *r = &f->rows[f->nfree];
        int named = pi->end > pi->off;
        *r = (frep_fit_param){ pi->name, i, pi->value, pi->value, pi->lo, pi->hi, NAN, NAN, 0 };
        if (!named && f->o->nbounds > 0) {
            if (f->o->nbounds != f->nall)
                return failf(f, "%zu bounds given; the template's a[] has %zu elements",
                             f->o->nbounds, f->nall);
            r->lo = f->o->lo[i], r->hi = f->o->hi[i];
        }
        f->idx[f->nfree++] = i;
    }
    if (f->nfree == 0)
        return failf(f, "%s: the template has no free parameters: mark values with "
                        "'-- @free [lo, hi]' or use an a[] array", f->file);
    if (f->nnamed == 0 && copt->na != 0 && copt->na != f->nall)
        reportf(f, FREP_NOTE, "%zu start values given for the %zu elements of a[]; the "
                              "others start at 0", copt->na, f->nall);
    for (size_t j = 0; j < f->nfree; j++) {
        const frep_fit_param *r = &f->rows[j];
        if (!(r->start >= r->lo && r->start <= r->hi))
            return failf(f, "%s: parameter %s starts at %g, outside its bounds [%g, %g]",
                         f->file, r->name, r->start, r->lo, r->hi);
    }
    return 0;
}

static int point_finite(const frep_cloud *c, size_t i)
{
    return isfinite(c->x[i]) && isfinite(c->y[i]) && isfinite(c->z[i]) &&
           (!c->has_normals || (isfinite(c->nx[i]) && isfinite(c->ny[i]) && isfinite(c->nz[i])));
}

/* The cloud checked (finite, enough points, normals for a normals weight); its
 * diagonal sets the default loss scale. */
static int stage_cloud(frep_fit *f)
{
    frep_cloud *c = f->cloud;
    for (size_t i = 0; i < c->n; i++)
        if (!point_finite(c, i))
            return failf(f, "point %zu of the cloud is not finite (NaN or infinity)", i + 1);
    if (c->n < f->nfree + FIT_MIN_POINTS)
        return failf(f, "%zu points are too few to fit %zu parameters (need at least %zu)",
                     c->n, f->nfree, f->nfree + FIT_MIN_POINTS);
    if (f->cfg.obj.normals_weight > 0 && !c->has_normals)
        return failf(f, "a normals weight needs a cloud with normals; this one has none");
    if (c->has_normals) cloud_normalize_normals(c);
    f->npoints = c->n;
    f->diagonal = cloud_diagonal(c);
    f->cfg.obj.loss_scale = f->o->loss_scale > 0 ? f->o->loss_scale
                                                 : 0.01 * (f->diagonal > 0 ? f->diagonal : 1);
    f->pts = (fit_points){ c->n, c->x, c->y, c->z, NULL, NULL, NULL };
    if (c->has_normals) f->pts.nx = c->nx, f->pts.ny = c->ny, f->pts.nz = c->nz;
    return 0;
}

/* The search box: the annealing needs a finite one, so an unbounded parameter searches
 * its start plus or minus the cloud's diagonal. */
static void stage_search_box(frep_fit *f)
{
    int global = f->cfg.method == FIT_METHOD_SAQN || f->cfg.method == FIT_METHOD_SA;
    for (size_t j = 0; j < f->nfree; j++) {
        f->lo[j] = f->rows[j].lo, f->hi[j] = f->rows[j].hi;
        f->x0[j] = f->rows[j].start;
        if (global && (!isfinite(f->lo[j]) || !isfinite(f->hi[j]))) {
            double d = f->diagonal > 0 ? f->diagonal : 1;
            if (!isfinite(f->lo[j])) f->lo[j] = f->x0[j] - d;
            if (!isfinite(f->hi[j])) f->hi[j] = f->x0[j] + d;
            reportf(f, FREP_NOTE, "%s has no bounds; the annealing searches [%g, %g]",
                    f->rows[j].name, f->lo[j], f->hi[j]);
        }
    }
}

/* fit/fit.c's progress -> the caller's; the caller's cancel polled with it. */
static void on_progress(void *user, const fit_progress *p)
{
    frep_fit *f = user;
    if (f->o->progress) {
        frep_fit_progress fp = { (int)p->phase, p->chain, p->nchains, p->iteration, p->best,
                                 p->subset, p->elapsed };
        f->o->progress(f->o->user, &fp);
    }
    if (f->o->cancel && f->o->cancel(f->o->user)) f->stop = 1;
}

/* The caller's cancel, polled between evaluations (fit_config.cancel). */
static int on_cancel(void *user)
{
    frep_fit *f = user;
    if (f->o->cancel && f->o->cancel(f->o->user)) f->stop = 1;
    return f->stop != 0;
}

static int stage_fit(frep_fit *f)
{
    if (fit_program_model(f->p, f->idx, f->nfree, f->base, &f->fm) != 0)
        return failf(f, "out of memory");
    if (f->ps != NULL) {
        if (fit_program_model(f->ps, f->idx, f->nfree, f->base, &f->fs) != 0)
            return failf(f, "out of memory");
        f->cfg.surrogate = &f->fs;
    }
    if (f->o->progress || f->o->cancel) {
        f->cfg.progress = on_progress;
        f->cfg.progress_user = f;
        f->cfg.cancel = on_cancel;
        f->cfg.interrupt = &f->stop;
    }
    frep_error err;
    frep_error_init(&err);
    int rc = fit_run(&f->fm, &f->pts, f->lo, f->hi, f->x0, &f->cfg, &f->res, &err);
    const frep_program *over = frep_program_work_spent(f->p) ? f->p
                             : f->ps != NULL && frep_program_work_spent(f->ps) ? f->ps : NULL;
    if (over != NULL)
        return failf(f, "%s: the model's loops ran over the work budget of %llu iterations "
                        "(summed over the points): evaluation stopped", f->file,
                     (unsigned long long)frep_program_work_limit(over));
    if (rc != 0) return api_fail(&f->d, &err);
    return 0;
}

/* The "-- @params v1, v2, ..." annotation of an a[] template: the values of every
 * element of a[] (the fitted ones and the others as given), which every command uses
 * when no -a is given, so the fitted file is the fitted shape on its own. */
static char *fitted_note(const frep_fit *f)
{
    size_t cap = 32 + f->nall * (FIT_NUMBER_MAX + 2), m;
    char *note = frep_malloc(cap);
    if (note == NULL) return NULL;
    m = (size_t)snprintf(note, cap, "-- @params");
    for (size_t i = 0; i < f->nall; i++) {
        char num[FIT_NUMBER_MAX];
        double v = f->base[i], lo = -INFINITY, hi = INFINITY;
        for (size_t j = 0; j < f->nfree; j++)
            if (f->idx[j] == i) v = f->x0[j], lo = f->rows[j].lo, hi = f->rows[j].hi;
        fit_format_number(num, v, lo, hi);
        m += (size_t)snprintf(note + m, cap - m, "%s %s", i ? "," : "", num);
    }
    return note;
}

/* The fitted template: named values edited in place, the cloud's box in '-- @box'. */
static int stage_writeback(frep_fit *f)
{
    fit_edit *edits = frep_malloc(f->nfree * sizeof *edits);
    size_t ne = 0;
    if (edits == NULL) return failf(f, "out of memory");
    for (size_t j = 0; j < f->nfree; j++) {
        frep_fit_param *r = &f->rows[j];
        const frep_param_info *pi = &f->p->params[r->index];
        r->value = f->x0[j];
        if (pi->end > pi->off) edits[ne++] = (fit_edit){ pi->off, pi->end, f->x0[j], r->lo, r->hi };
    }
    char *note = NULL;
    if (f->nnamed == 0 && (note = fitted_note(f)) == NULL) {
        frep_free(edits);
        return failf(f, "out of memory");
    }
    double blo3[3], bhi3[3], box[6];
    cloud_bbox(f->cloud, blo3, bhi3);
    double margin = FIT_BOX_MARGIN * (f->diagonal > 0 ? f->diagonal : 1);
    for (int k = 0; k < 3; k++) box[k] = blo3[k] - margin, box[3 + k] = bhi3[k] + margin;
    f->text = fit_writeback(f->src, f->srclen, edits, ne, box, note, &f->textlen);
    frep_free(edits);
    frep_free(note);
    if (f->text == NULL) return failf(f, "cannot rewrite the template (out of memory)");
    return 0;
}

/* The warnings of one parameter (FREP_FIT_* bits) from its value, bounds, sensitivity
 * and standard error. */
static unsigned param_warnings(const frep_fit_param *r, double diagonal)
{
    unsigned w = 0;
    double range = r->hi - r->lo;
    int bounded = isfinite(range) && range > 0;
    double scale = bounded ? range : 1 + fabs(r->value);
    if (bounded) {
        double gap = fmin(r->value - r->lo, r->hi - r->value);
        if (gap <= FIT_ON_BOUND * range) w |= FREP_FIT_ON_BOUND;
        else if (gap <= FIT_NEAR_BOUND * range) w |= FREP_FIT_NEAR_BOUND;
    }
    if (r->sensitivity == 0) w |= FREP_FIT_NO_EFFECT;
    else if (r->sensitivity * scale < FIT_TINY_EFFECT * diagonal) w |= FREP_FIT_TINY_EFFECT;
    else if (r->sigma > FIT_LOOSE * scale) w |= FREP_FIT_LOOSE;
    return w;
}

/* The parameters' warnings (reported) and the one-line verdict. */
static void stage_judge(frep_fit *f)
{
    const fit_result *res = &f->res;
    for (size_t j = 0; j < f->nfree; j++) {
        frep_fit_param *r = &f->rows[j];
        r->value = f->x0[j];
        r->sigma = res->have_uncertainty ? res->sigma[j] : NAN;
        r->sensitivity = res->have_uncertainty ? res->sens[j] : NAN;
        r->warnings = res->have_uncertainty ? param_warnings(r, f->diagonal) : 0;
        if (r->warnings) f->nwarn++;
        const char *nm = r->name;
        if (r->warnings & FREP_FIT_ON_BOUND)
            reportf(f, FREP_WARNING, "%s = %.10g is on its bound [%g, %g]: the best value may "
                    "lie beyond it (widen the bounds) or the feature it sizes is switched off",
                    nm, r->value, r->lo, r->hi);
        if (r->warnings & FREP_FIT_NEAR_BOUND)
            reportf(f, FREP_WARNING, "%s = %.10g is within 1%% of a bound of [%g, %g]", nm,
                    r->value, r->lo, r->hi);
        if (r->warnings & FREP_FIT_NO_EFFECT)
            reportf(f, FREP_WARNING, "the surface does not depend on %s (unused, assigned again "
                    "after its '@free' line, or its primitive is away from every point): its "
                    "value is arbitrary", nm);
        if (r->warnings & FREP_FIT_TINY_EFFECT)
            reportf(f, FREP_WARNING, "%s barely moves the surface (%.3g per unit): its value "
                    "is arbitrary", nm, r->sensitivity);
        if (r->warnings & FREP_FIT_LOOSE)
            reportf(f, FREP_WARNING, "%s is poorly determined by the points (standard error "
                    "%.3g)", nm, r->sigma);
    }
    const char *word;
    char why[96] = "", noise[160] = "";
    if (!isfinite(res->within)) {
        word = "unknown";
        snprintf(why, sizeof why, f->stop ? "stopped before the end, the distances not measured"
                                          : "the distances could not be measured");
    } else {
        /* Judged on the inliers: points taken for outliers are reported, not held
         * against the fit, unless they are more than FIT_VERDICT_OUTLIERS of the cloud.
         * Noise above FIT_WITHIN is reported and makes the fit doubtful: from the
         * distances alone it cannot be told apart from a fit that is off. */
        double share = isfinite(res->within_inliers) ? res->within_inliers : res->within;
        word = share >= FIT_VERDICT_GOOD ? "good" : share >= FIT_VERDICT_POOR
                                                        ? "doubtful" : "poor";
        double n = (double)f->npoints;
        if (isfinite(res->noise) && 3 * res->noise > FIT_WITHIN * f->diagonal)
            snprintf(noise, sizeof noise, "; noise %.3g (%.2g%% of the diagonal), %.1f%% of "
                     "the inliers within 1%%", res->noise, 100 * res->noise / f->diagonal,
                     100 * share);
        if (res->outliers > 0)
            snprintf(noise + strlen(noise), sizeof noise - strlen(noise),
                     "; %zu points (%.1f%%) taken for outliers", res->outliers,
                     100 * (double)res->outliers / n);
        if ((double)res->outliers > FIT_VERDICT_OUTLIERS * n) word = "poor";
        if (f->stop || res->status == FIT_STOPPED)
            snprintf(why, sizeof why, "; stopped before the end");
        else if (res->status != FIT_CONVERGED)
            snprintf(why, sizeof why, "; not converged");
        if (f->nwarn > 0)
            snprintf(why + strlen(why), sizeof why - strlen(why), "; %d parameter warning%s",
                     f->nwarn, f->nwarn == 1 ? "" : "s");
        if (why[0] != '\0' && strcmp(word, "good") == 0) word = "doubtful";
    }
    if (isfinite(res->within))
        snprintf(f->verdict, sizeof f->verdict, "%s - %.1f%% of points within 1%% of the "
                 "diagonal%s%s", word, 100 * res->within, noise, why);
    else
        snprintf(f->verdict, sizeof f->verdict, "%s - %s", word, why);
}

/* template -> parameters -> cloud -> search box -> fit -> fitted template -> judgement */
frep_fit *frep_fit_template(const char *file, const char *text, size_t len,
                            const frep_compile_options *copt, frep_cloud *c,
                            const frep_fit_options *o, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_fit *f = frep_calloc(1, sizeof *f);
    if (f == NULL) {
        api_report(&d, FREP_ERROR, "out of memory");
        return NULL;
    }
    frep_fit_options dopt;
    if (o == NULL) {
        frep_fit_options_init(&dopt);
        o = &dopt;
    }
    frep_compile_options dcopt;
    if (copt == NULL) {
        frep_compile_options_init(&dcopt);
        copt = &dcopt;
    }
    f->d = d;
    f->o = o;
    f->file = file ? file : "template";
    f->src = text;
    f->srclen = len;
    f->cloud = c;
    fit_config_init(&f->cfg);
    f->cfg.report = 1;
    f->cfg.method = (fit_method)o->method;
    f->cfg.obj.kind = (fit_objective_kind)o->objective;
    f->cfg.global_kind = (fit_objective_kind)o->global_objective;
    f->cfg.obj.loss = (fit_loss)o->loss;
    f->cfg.sa_loss = (fit_loss)o->sa_loss;
    f->cfg.robust = o->robust;
    f->cfg.obj.normals_weight = o->normals_weight;
    f->cfg.seed = o->seed;
    f->cfg.max_time = o->max_time;
    f->cfg.max_evals = o->max_evals;
    f->cfg.sa_points = o->sa_points;
    f->cfg.sa.stall_iter = o->sa_stall;
    f->cfg.sa.chains = o->sa_chains;
    f->cfg.sa.threshold = o->sa_threshold;
    f->cfg.obj.nthreads = o->nthreads;
    int rc = c == NULL ? failf(f, "no cloud to fit") : stage_template(f, copt);
    if (rc == 0) rc = stage_params(f, copt);
    if (rc == 0) rc = stage_cloud(f);
    if (rc == 0) {
        stage_search_box(f);
        rc = stage_fit(f);
    }
    if (rc == 0) rc = stage_writeback(f);
    if (rc == 0) stage_judge(f);
    f->d = (api_diag){ NULL, NULL };
    f->o = NULL;
    f->cloud = NULL;
    f->src = NULL;
    f->pts = (fit_points){ 0 };
    if (f->fm.user != NULL) fit_program_model_free(&f->fm);
    if (f->fs.user != NULL) fit_program_model_free(&f->fs);
    f->fm.user = f->fs.user = NULL;
    if (rc != 0) {
        frep_fit_free(f);
        return NULL;
    }
    return f;
}

void frep_fit_free(frep_fit *f)
{
    if (f == NULL) return;
    frep_program_free(f->ps);
    frep_program_free(f->p);
    frep_free(f->text);
    frep_free(f->rows);
    frep_free(f->idx);
    frep_free(f->base);
    frep_free(f->x0);
    frep_free(f->lo);
    frep_free(f->hi);
    frep_free(f);
}

size_t frep_fit_nparams(const frep_fit *f) { return f->nfree; }
size_t frep_fit_nvalues(const frep_fit *f) { return f->nall; }

int frep_fit_get_param(const frep_fit *f, size_t j, frep_fit_param *p)
{
    if (j >= f->nfree) return -1;
    *p = f->rows[j];
    return 0;
}

void frep_fit_get_info(const frep_fit *f, frep_fit_info *info)
{
    const fit_result *r = &f->res;
    *info = (frep_fit_info){
        .npoints = f->npoints, .nparams = f->nfree, .objective = r->objective, .rms = r->rms,
        .max_dist = r->max_dist, .within = r->within, .within_inliers = r->within_inliers,
        .diagonal = f->diagonal, .noise = r->noise, .outliers = r->outliers,
        .evals = r->evals, .seconds = r->seconds, .converged = r->status == FIT_CONVERGED,
        .interrupted = f->stop != 0,
        .status = f->stop ? "interrupted" : fit_status_name(r->status),
        .verdict = f->verdict
    };
}

int frep_fit_values(const frep_fit *f, double *v, size_t n)
{
    if (n < f->nall) return -1;
    if (f->nall) memcpy(v, f->base, f->nall * sizeof *v);
    for (size_t j = 0; j < f->nfree; j++) v[f->idx[j]] = f->x0[j];
    return 0;
}

const char *frep_fit_text(const frep_fit *f, size_t *len)
{
    if (len) *len = f->textlen;
    return f->text;
}

typedef struct text_ctx {
    const frep_fit *f;
} text_ctx;

static int write_text(FILE *out, void *ctx)
{
    const frep_fit *f = ((const text_ctx *)ctx)->f;
    return fwrite(f->text, 1, f->textlen, out) == f->textlen ? 0 : -1;
}

int frep_fit_write(const frep_fit *f, const char *path, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    text_ctx t = { f };
    return api_write_atomic(&d, path, write_text, &t);
}

static void json_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (; s && *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') fprintf(f, "\\%c", c);
        else if (c < 0x20) fprintf(f, "\\u%04x", c);
        else fputc(c, f);
    }
    fputc('"', f);
}

static void json_num(FILE *f, double v)
{
    if (isfinite(v)) fprintf(f, "%.17g", v);
    else fputs("null", f);
}

typedef struct json_ctx {
    const frep_fit *fit;
    const char *tmpl, *cloud, *output;
} json_ctx;

static int write_json(FILE *f, void *user)
{
    const json_ctx *j = user;
    const frep_fit *r = j->fit;
    const fit_config *cfg = &r->cfg;
    frep_fit_info in;
    frep_fit_get_info(r, &in);
    fputs("{\n  \"template\": ", f);
    json_str(f, j->tmpl);
    fputs(",\n  \"cloud\": ", f);
    json_str(f, j->cloud);
    fputs(",\n  \"output\": ", f);
    json_str(f, j->output);
    fprintf(f, ",\n  \"points\": %zu,\n  \"method\": \"%s\",\n  \"objective_kind\": \"%s\",\n"
               "  \"global_objective_kind\": \"%s\",\n"
               "  \"loss\": \"%s\",\n  \"seed\": %llu,\n  \"parameters\": [\n",
            r->npoints, fit_method_name(cfg->method), fit_objective_name(cfg->obj.kind),
            fit_objective_name(cfg->global_kind), fit_loss_name(cfg->obj.loss),
            (unsigned long long)cfg->seed);
    for (size_t i = 0; i < r->nfree; i++) {
        const frep_fit_param *p = &r->rows[i];
        const struct { const char *key; double v; } num[] = {
            { "start", p->start }, { "value", p->value }, { "lo", p->lo }, { "hi", p->hi },
            { "sigma", p->sigma }, { "sensitivity", p->sensitivity },
        };
        fputs("    {\"name\": ", f);
        json_str(f, p->name);
        for (size_t k = 0; k < sizeof num / sizeof num[0]; k++) {
            fprintf(f, ", \"%s\": ", num[k].key);
            json_num(f, num[k].v);
        }
        fprintf(f, ", \"on_bound\": %s, \"near_bound\": %s, \"no_effect\": %s}%s\n",
                p->warnings & FREP_FIT_ON_BOUND ? "true" : "false",
                p->warnings & FREP_FIT_NEAR_BOUND ? "true" : "false",
                p->warnings & (FREP_FIT_NO_EFFECT | FREP_FIT_TINY_EFFECT) ? "true" : "false",
                i + 1 < r->nfree ? "," : "");
    }
    fputs("  ],\n  \"objective\": ", f);
    json_num(f, in.objective);
    fputs(",\n  \"rms_distance\": ", f);
    json_num(f, in.rms);
    fputs(",\n  \"max_distance\": ", f);
    json_num(f, in.max_dist);
    fputs(",\n  \"within_1pct_of_diagonal\": ", f);
    json_num(f, in.within);
    fputs(",\n  \"diagonal\": ", f);
    json_num(f, in.diagonal);
    fputs(",\n  \"noise\": ", f);
    json_num(f, in.noise);
    fprintf(f, ",\n  \"outliers\": %zu", in.outliers);
    fprintf(f, ",\n  \"evaluations\": %ld,\n  \"seconds\": %.6f,\n  \"status\": \"%s\",\n"
               "  \"converged\": %s,\n  \"verdict\": \"%s\",\n  \"interrupted\": %s\n}\n",
            in.evals, in.seconds, in.status, in.converged ? "true" : "false", in.verdict,
            in.interrupted ? "true" : "false");
    return ferror(f) ? -1 : 0;
}

int frep_fit_write_json(const frep_fit *f, const char *path, const char *template_name,
                        const char *cloud_name, const char *output_name,
                        frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    json_ctx j = { f, template_name, cloud_name, output_name };
    return api_write_atomic(&d, path, write_json, &j);
}

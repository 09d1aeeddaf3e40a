/* api_evolve.c - construction trees in the public API: the cloud's normals
 * (geom/normals.c) when missing, the base model of a residual run (evolve/residual.c),
 * the primitives (segment/segment.c) when not given, evolve/evolve.c's genetic
 * programming, the optional refit (evolve/refit.c), the --trace lines and the model
 * writers.  The caller's cancel callback is polled where the progress is reported and
 * raises the flag every step of the run checks.
 */
#include "config.h"

#include "api.h"
#include "cloud.h"
#include "evolve.h"
#include "refit.h"
#include "residual.h"

#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "alloc.h"
#include "util.h"

_Static_assert(FREP_EVOLVE_GA == (int)GP_PHASE_GA && FREP_EVOLVE_MERGE == (int)GP_PHASE_MERGE &&
                   FREP_EVOLVE_MERGED == (int)GP_PHASE_MERGED &&
                   FREP_EVOLVE_GROWN == (int)GP_PHASE_GROWN &&
                   FREP_EVOLVE_CLIQUES == (int)GP_PHASE_CLIQUES &&
                   FREP_EVOLVE_SIMPLIFY == (int)GP_PHASE_SIMPLIFY,
               "frep_evolve_phase begins with evolve/gp.h's gp_phase");
_Static_assert(FREP_EVOLVE_MAX_DEPTH == GP_MAX_TREE_DEPTH, "the public depth limit is gp's");

/* The base model of a residual run: evolve/residual.h's, and its file name. */
struct frep_evolve_base {
    evolve_base b;
    char *file;
};

struct frep_evolution {
    evolve_options eo;
    evolve_result res;
    prim *prims;               /* the primitives the tree's leaves refer to (owned) */
    size_t nprims;
    const frep_cloud *cloud;   /* the caller's, for the writers' check */
    const frep_evolve_base *base; /* the caller's (NULL: none) */
    size_t base_explained, base_failed;
    int interrupted;
    /* the writers' cancel flag (frep_evolution_set_cancel; NULL: none) */
    volatile sig_atomic_t *cancel_flag;
    evolve_refit_info refit;   /* nparams 0 without a refit */
    char note[256];            /* the refit's comment line of the model */
};

void frep_evolve_options_init(frep_evolve_options *o)
{
    evolve_options eo;
    evolve_options_init(&eo);
    memset(o, 0, sizeof *o);
    o->seed = eo.gp.seed;
    o->nthreads = eo.gp.threads;
    o->setops = eo.gp.setops == GP_SETOPS_RFUNC ? FREP_SETOPS_RFUNC : FREP_SETOPS_MINMAX;
    o->generations = eo.gp.generations;
    o->stagnation = eo.gp.stagnation;
    o->population = eo.gp.population;
    o->tournament = eo.gp.tournament;
    o->elite = eo.gp.elite;
    o->crossover = eo.gp.p_crossover;
    o->mutation = eo.gp.p_mutation;
    o->subtree_prob = eo.gp.p_subtree;
    o->max_depth = eo.gp.max_depth;
    o->max_time = eo.gp.max_time;
    o->partition = eo.partition;
    o->polish = eo.polish;
    o->polish_stagnation = eo.polish_stagnation;
    o->simplify = eo.simplify;
    o->support = eo.support;
    o->sample = eo.sample;
    o->epsilon = eo.eps_rel;
    o->alpha_deg = eo.alpha_auto ? 0 : eo.alpha_deg;
    o->lambda_scale = eo.lambda_scale;
}

/* The caller's progress, cancel and trace: the GA's progress function, and the run's
 * gp_cancel (gp.h), whose flag is the caller's cancel_flag or stop. */
typedef struct evolve_job {
    const frep_evolve_options *o;
    api_diag d;
    volatile sig_atomic_t stop;
    gp_cancel cancel;
    double start;              /* frep_now_seconds() at the call */
    double t0;                 /* ... when the search started, */
    clock_t c0;                /* and clock() then (the trace's origins) */
    int polish;                /* 1 once a merge was traced: later GA lines are polish */
    /* the base's values at the cloud's points and where they are defined (a residual
     * run), the points it explains poorly */
    double *base_f, *base_g;
    uint8_t *base_ok, *mask;
    size_t nres;
    int normals_estimated;     /* ensure_normals estimated the cloud's normals */
} evolve_job;

/* One line to the trace callback. */
static void trace_line(const evolve_job *j, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void trace_line(const evolve_job *j, const char *fmt, ...)
{
    char line[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    j->o->trace(j->o->user, line);
}

static double share(size_t k, size_t n)
{
    return n ? 100.0 * (double)k / (double)n : 0;
}

/* A trace line for a report with a tree (the start reports have none). */
static void trace_report(evolve_job *j, const gp_progress *p)
{
    double wall = frep_now_seconds() - j->t0;
    double cpu = (double)(clock() - j->c0) / CLOCKS_PER_SEC;
    if (p->phase == GP_PHASE_MERGE) {
        j->polish = 1;
        trace_line(j, "%u %.4f %.4f nan %u - merge\n", p->generation, wall, cpu, p->best_len);
        return;
    }
    const char *ph = p->phase == GP_PHASE_MERGED ? "merged"
                     : p->phase == GP_PHASE_GROWN ? "grown"
                     : j->polish                  ? "polish"
                                                  : "ga";
    trace_line(j, "%u %.4f %.4f %.10g %u %.3f %s\n", p->generation, wall, cpu, p->best_fitness,
               p->best_len, share(p->explained, p->npoints), ph);
}

/* Poll the cancel callback (and max_time) now; nonzero once the run is stopped. */
static int poll_cancel(evolve_job *j)
{
    const frep_evolve_options *o = j->o;
    if (o->cancel && o->cancel(o->user)) *j->cancel.flag = 1;
    double now = frep_now_seconds();
    if (o->max_time > 0 && now - j->start >= o->max_time) *j->cancel.flag = 1;
    /* polled just now: gp_cancelled() waits its interval before the next call */
    j->cancel.next = now + GP_CANCEL_POLL_SECONDS;
    return *j->cancel.flag != 0;
}

static int on_progress(void *user, const gp_progress *p)
{
    evolve_job *j = user;
    const frep_evolve_options *o = j->o;
    int start = p->phase == GP_PHASE_CLIQUES || p->phase == GP_PHASE_SIMPLIFY;
    if (o->trace && !start) trace_report(j, p);
    if (o->progress) {
        frep_evolve_progress fp = { (int)p->phase, p->generation, p->best_fitness, p->best_len,
                                    p->explained, p->npoints, p->elapsed };
        o->progress(o->user, &fp);
    }
    /* the cancel polled without max_time: the GA's own limit ends the search */
    if (o->cancel && o->cancel(o->user)) *j->cancel.flag = 1;
    j->cancel.next = frep_now_seconds() + GP_CANCEL_POLL_SECONDS;
    /* stop_share: a GA phase ends once its best tree explains enough points */
    if (o->stop_share > 0 && p->phase == GP_PHASE_GA && p->npoints &&
        100.0 * (double)p->explained >= o->stop_share * (double)p->npoints)
        return 1;
    return *j->cancel.flag != 0;
}

/* A start report: the phase only; the cancel polled with it. */
static void report_phase(evolve_job *j, frep_evolve_phase phase)
{
    if (j->o->progress) {
        frep_evolve_progress fp = { (int)phase, 0, NAN, 0, 0, 0, 0 };
        j->o->progress(j->o->user, &fp);
    }
    poll_cancel(j);
}

/* Segmentation's progress: the cancel callback and max_time polled (segment_run polls
 * the flag). */
static void on_segment_progress(void *user, const char *stage, size_t done, size_t total,
                                size_t nprims)
{
    (void)stage, (void)done, (void)total, (void)nprims;
    evolve_job *j = user;
    if (frep_now_seconds() >= j->cancel.next) poll_cancel(j);
}

static void options_from(const frep_evolve_options *o, evolve_options *eo)
{
    evolve_options_init(eo);
    eo->gp.seed = o->seed;
    eo->gp.threads = o->nthreads;
    eo->gp.setops = o->setops == FREP_SETOPS_RFUNC ? GP_SETOPS_RFUNC : GP_SETOPS_MINMAX;
    eo->gp.generations = o->generations;
    eo->gp.stagnation = o->stagnation;
    eo->gp.population = o->population;
    eo->gp.tournament = o->tournament;
    eo->gp.elite = o->elite;
    eo->gp.p_crossover = o->crossover;
    eo->gp.p_mutation = o->mutation;
    eo->gp.p_subtree = o->subtree_prob;
    eo->gp.max_depth = o->max_depth;
    eo->gp.report_explained = o->report_explained || o->trace || o->stop_share > 0;
    eo->partition = o->partition;
    eo->polish = o->polish;
    eo->polish_stagnation = o->polish_stagnation;
    eo->simplify = o->simplify;
    eo->support = o->support;
    eo->sample = o->sample;
    eo->eps_rel = o->epsilon;
    eo->alpha_auto = !(o->alpha_deg > 0);
    if (o->alpha_deg > 0) eo->alpha_deg = o->alpha_deg;
    /* 0 asks for no penalty; the GA needs a positive weight to break ties by size */
    eo->lambda_scale = o->lambda_scale == 0 ? 1e-12 : o->lambda_scale;
}

/* Normals estimated when the cloud has none (or only zero-length ones). */
static int ensure_normals(evolve_job *j, frep_cloud *c)
{
    const frep_evolve_options *o = j->o;
    if (c->has_normals && cloud_normalize_normals(c) != c->n) return 0;
    report_phase(j, FREP_EVOLVE_NORMALS);
    frep_normals_info info;
    /* the flag only: no callback polled here */
    int rc = api_estimate_normals(c, o->knn, o->nthreads, j->cancel.flag, &info);
    if (rc < 0) api_report(&j->d, FREP_ERROR, "out of memory estimating normals");
    else if (rc > 0) api_report(&j->d, FREP_ERROR, "stopped while estimating normals: no model");
    else {
        char msg[200];
        j->normals_estimated = 1;
        snprintf(msg, sizeof msg, "the cloud has no normals: estimated them (%zu neighbours%s, "
                 "noise %.3g, spacing %.3g)", info.knn, o->knn ? "" : ", auto", info.noise,
                 info.spacing);
        api_report(&j->d, FREP_NOTE, msg);
    }
    return rc == 0 ? 0 : -1;
}

/* A residual run: the base's values at every point, and the points it explains
 * poorly (j->mask, j->nres of them), with the tolerances of the run. */
static int eval_base(evolve_job *j, const frep_cloud *c, frep_evolution *ev)
{
    const frep_evolve_base *b = ev->base;
    size_t N = c->n, nbad = 0;
    j->base_f = frep_malloc(N * sizeof *j->base_f);
    j->base_g = frep_malloc(3 * N * sizeof *j->base_g);
    j->base_ok = frep_malloc(N);
    j->mask = frep_malloc(N);
    if (!j->base_f || !j->base_g || !j->base_ok || !j->mask ||
        residual_eval(&b->b, c, j->o->nthreads, j->base_f, j->base_g, j->base_ok, &nbad))
        return api_fail(&j->d, NULL);
    char msg[FREP_ERROR_MSG_MAX + 160];
    if (nbad) {
        snprintf(msg, sizeof msg, "%s cannot be evaluated at %zu points (treated as "
                 "unexplained)", b->file, nbad);
        api_report(&j->d, FREP_WARNING, msg);
    }
    evolve_options *eo = &ev->eo;
    eo->base_f = j->base_f;
    eo->base_g = j->base_g;
    eo->base_ok = j->base_ok;
    if (evolve_residual_points(eo, c, j->mask, &j->nres)) return api_fail(&j->d, NULL);
    ev->base_explained = N - j->nres;
    ev->base_failed = nbad;
    snprintf(msg, sizeof msg, "%s explains %zu of %zu points; evolving for the %zu others",
             b->file, N - j->nres, N, j->nres);
    api_report(&j->d, FREP_NOTE, msg);
    return 0;
}

/* The points the base explains poorly, as a cloud to segment (with their normals). */
static frep_cloud *residual_cloud(const evolve_job *j, const frep_cloud *c)
{
    frep_cloud *sub = cloud_new(1);
    if (!sub || cloud_reserve(sub, j->nres ? j->nres : 1)) {
        cloud_free(sub);
        return NULL;
    }
    for (size_t i = 0; i < c->n; i++)
        if (j->mask[i]) {
            double p[3] = { c->x[i], c->y[i], c->z[i] };
            double q[3] = { c->nx[i], c->ny[i], c->nz[i] };
            cloud_push(sub, p, q);
        }
    return sub;
}

/* Segment c (the cloud, or a residual run's points) with frep segment's defaults.  A
 * residual whose points give no primitive is no error: the result is the base. */
static int segment_prims(evolve_job *j, frep_cloud *c, int residual, frep_evolution *ev)
{
    const frep_evolve_options *o = j->o;
    report_phase(j, FREP_EVOLVE_SEGMENT);
    segment_config sc;
    segment_config_init(&sc);
    sc.seed = o->seed;
    sc.nthreads = o->nthreads;
    sc.interrupt = j->cancel.flag;
    sc.progress = on_segment_progress;
    sc.user = j;
    sc.knn = o->knn;
    sc.normals_estimated = j->normals_estimated;
    segment_result r;
    memset(&r, 0, sizeof r);
    frep_error e;
    frep_error_init(&e);
    char msg[FREP_ERROR_MSG_MAX + 160];
    if (segment_run(c, &sc, &r, &e) != 0) {
        if (!residual) return api_fail(&j->d, &e);
        snprintf(msg, sizeof msg, "the residual points give no primitive (%s)",
                 e.msg[0] ? e.msg : "segmentation failed");
        api_report(&j->d, FREP_NOTE, msg);
        return 0;
    }
    snprintf(msg, sizeof msg, "segmented%s: %zu primitives (%zu fitted, %zu separating)%s",
             residual ? " the residual" : "", r.nprims, r.nfitted, r.nprims - r.nfitted,
             r.normals_estimated ? ", normals estimated" : "");
    api_report(&j->d, FREP_NOTE, msg);
    ev->prims = r.prims;
    ev->nprims = r.nprims;
    r.prims = NULL;
    segment_result_free(&r);
    return 0;
}

/* The primitives: a copy of the caller's, or the cloud (the residual points) segmented. */
static int get_prims(evolve_job *j, frep_cloud *c, const frep_segmentation *s,
                     frep_evolution *ev)
{
    if (s) {
        ev->nprims = s->r.nprims;
        ev->prims = frep_calloc(ev->nprims ? ev->nprims : 1, sizeof *ev->prims);
        if (!ev->prims) return api_fail(&j->d, NULL);
        if (ev->nprims) memcpy(ev->prims, s->r.prims, ev->nprims * sizeof *ev->prims);
        return 0;
    }
    if (!ev->base) return segment_prims(j, c, 0, ev);
    if (j->nres == 0) return 0;
    frep_cloud *sub = residual_cloud(j, c);
    int rc = sub ? segment_prims(j, sub, 1, ev) : api_fail(&j->d, NULL);
    cloud_free(sub);
    return rc;
}

/* Without primitives, only a residual run goes on (its tree is the base). */
static int check_prims(evolve_job *j, const frep_evolution *ev, int segmented)
{
    if (ev->nprims || ev->base) return 0;
    api_report(&j->d, FREP_ERROR, *j->cancel.flag ? "stopped before any primitive was found"
                                  : segmented ? "no primitives to combine (segmentation "
                                                "found none; try frep segment with other "
                                                "settings)"
                                              : "no primitives to combine");
    return -1;
}

/* The search: evolve_run with the trace's origins and header, max_time's remainder. */
static int search(evolve_job *j, const frep_cloud *c, frep_evolution *ev)
{
    const frep_evolve_options *o = j->o;
    report_phase(j, FREP_EVOLVE_SEARCH);
    j->t0 = frep_now_seconds();
    j->c0 = clock();
    if (o->trace) {
        trace_line(j, "# frep evolve trace, seed %llu\n", (unsigned long long)o->seed);
        trace_line(j, "# columns: generation, wall and CPU (process) seconds since the "
                      "start of the run, best fitness, tree size,\n");
        trace_line(j, "# %% of the scored points the best tree explains, phase (ga: the "
                      "GA; merge: merging clique trees;\n");
        trace_line(j, "# merged: the merged tree; grown: after the growth steps; polish: "
                      "the GA seeded with it)\n");
    }
    if (o->max_time > 0) ev->eo.gp.max_time = fmax(o->max_time - (j->t0 - j->start), 1e-3);
    frep_error e;
    frep_error_init(&e);
    if (evolve_run(&ev->eo, c, ev->prims, ev->nprims, on_progress, j, &ev->res, &e) != 0)
        return api_fail(&j->d, &e);
    return 0;
}

/* The refit: skipped once the run is stopped or its time spent; a failure keeps the
 * parameters (a warning). */
static void refit(evolve_job *j, const frep_cloud *c, frep_evolution *ev)
{
    const frep_evolve_options *o = j->o;
    if (!o->refit || *j->cancel.flag ||
        (o->max_time > 0 && frep_now_seconds() - j->start >= o->max_time))
        return;
    report_phase(j, FREP_EVOLVE_REFIT);
    if (*j->cancel.flag) return;
    evolve_refit_info ri;
    frep_error e;
    frep_error_init(&e);
    if (evolve_refit(&ev->eo, c, ev->prims, ev->nprims, ev->base ? &ev->base->b : NULL,
                     &ev->res, &ri, &e) != 0) {
        char msg[FREP_ERROR_MSG_MAX + 80];
        snprintf(msg, sizeof msg, "refit: %s (the model keeps the parameters as segmented)",
                 e.msg[0] ? e.msg : "failed");
        api_report(&j->d, FREP_WARNING, msg);
    } else if (ri.nparams) {
        ev->refit = ri;
        snprintf(ev->note, sizeof ev->note,
                 "refit: %zu parameters, RMS distance %.6g -> %.6g, max %.6g -> %.6g, %.2f s",
                 ri.nparams, ri.rms_before, ri.rms_after, ri.max_before, ri.max_after,
                 ri.seconds);
        api_report(&j->d, FREP_NOTE, ev->note);
    }
}

/* The trace's last line: the tree on every point. */
static void trace_end(const evolve_job *j, const frep_evolution *ev)
{
    const evolve_result *r = &ev->res;
    trace_line(j, "# end: %.4f s wall, %.4f s CPU, %u nodes, %.3f%% of %zu points "
                  "explained (every point, after simplification)\n",
               frep_now_seconds() - j->t0, (double)(clock() - j->c0) / CLOCKS_PER_SEC,
               r->tree.len, share(r->stats.explained, r->npoints), r->npoints);
}

/* cloud checks -> [normals] -> [base] -> primitives -> search -> [refit] -> [trace end] */
frep_evolution *frep_evolve(frep_cloud *c, const frep_segmentation *prims,
                            const frep_evolve_options *o, frep_diag_fn diag, void *user)
{
    frep_evolve_options def;
    if (!o) {
        frep_evolve_options_init(&def);
        o = &def;
    }
    evolve_job job;
    memset(&job, 0, sizeof job);
    job.o = o;
    job.d = (api_diag){ diag, user };
    job.start = frep_now_seconds();
    job.cancel = (gp_cancel){ o->cancel_flag ? o->cancel_flag : &job.stop, o->cancel, o->user, 0 };
    frep_evolution *ev = frep_calloc(1, sizeof *ev);
    if (!ev) {
        api_fail(&job.d, NULL);
        return NULL;
    }
    ev->cloud = c;
    ev->base = o->base;
    ev->refit.rms_before = ev->refit.rms_after = NAN;
    options_from(o, &ev->eo);
    if (ev->base) ev->eo.gp.setops = ev->base->b.setops;
    ev->eo.gp.cancel = &job.cancel;
    frep_error e;
    frep_error_init(&e);
    int rc = 0;
    if (!c || c->n == 0) rc = -1, api_report(&job.d, FREP_ERROR, "no points");
    else if (cloud_check_scale(c, "the cloud", &e)) rc = api_fail(&job.d, &e);
    /* without primitives or base, normals missing are left to the segmentation when
     * its knn is fixed (as frep segment's) */
    if (rc == 0 && (prims || ev->base || (!c->has_normals && o->knn == 0)))
        rc = ensure_normals(&job, c);
    if (rc == 0 && ev->base) rc = eval_base(&job, c, ev);
    if (rc == 0) rc = get_prims(&job, c, prims, ev);
    if (rc == 0) rc = check_prims(&job, ev, prims == NULL);
    if (rc == 0) rc = search(&job, c, ev);
    if (rc == 0) refit(&job, c, ev);
    if (rc == 0 && o->trace) trace_end(&job, ev);
    ev->interrupted = *job.cancel.flag != 0;
    ev->eo.gp.cancel = NULL;
    ev->eo.base_f = ev->eo.base_g = NULL;
    ev->eo.base_ok = NULL;
    frep_free(job.base_f);
    frep_free(job.base_g);
    frep_free(job.base_ok);
    frep_free(job.mask);
    if (rc != 0) {
        frep_evolution_free(ev);
        return NULL;
    }
    return ev;
}

void frep_evolution_free(frep_evolution *e)
{
    if (!e) return;
    evolve_result_free(&e->res);
    frep_free(e->prims);
    frep_free(e);
}

void frep_evolution_get_info(const frep_evolution *e, frep_evolve_info *info)
{
    const evolve_result *r = &e->res;
    const evolve_refit_info *ri = &e->refit;
    *info = (frep_evolve_info){
        .tree_size = r->tree.len, .nprims = e->nprims, .npoints = r->npoints,
        .dropped = r->dropped, .explained = r->stats.explained,
        .within_eps = r->stats.within_eps, .normals_ok = r->stats.normals_ok,
        .fitness = r->fitness, .generations = r->generations, .seconds = r->seconds,
        .alpha_deg = r->alpha * 180 / FREP_PI, .alpha_auto = r->alpha_auto,
        .partitioned = r->partitioned, .interrupted = e->interrupted,
        .refit_rms_before = ri->rms_before, .refit_rms_after = ri->rms_after,
        .refit_nparams = ri->nparams,
        .refit_max_before = ri->nparams ? ri->max_before : NAN,
        .refit_max_after = ri->nparams ? ri->max_after : NAN,
        .refit_seconds = ri->nparams ? ri->seconds : 0,
        .noise_spread = r->noise.sigma_d, .noise_median_deg = r->noise.median_deg,
        .noise_p90_deg = r->noise.p90_deg, .noise_inliers = r->noise.inliers,
        .noisy = r->alpha_auto && r->alpha * 180 / FREP_PI > EVOLVE_DEFAULT_ALPHA_DEG,
        .base_explained = e->base_explained, .base_failed = e->base_failed
    };
}

void frep_evolution_set_cancel(frep_evolution *e, volatile sig_atomic_t *flag)
{
    e->cancel_flag = flag;
}

typedef struct write_ctx {
    const frep_evolution *e;
    const evolve_meta *m;
} write_ctx;

static int write_model(FILE *f, void *user)
{
    const write_ctx *w = user;
    return evolve_write_model(f, &w->e->res, w->e->prims, w->e->nprims, w->m);
}

static int write_dot(FILE *f, void *user)
{
    const write_ctx *w = user;
    return evolve_write_dot(f, &w->e->res, w->e->prims, w->e->nprims);
}

/* What the model's comments say: the command, the cloud, the run's settings. */
static evolve_meta model_meta(const frep_evolution *e, const char *command,
                              const char *cloud_name, int exact, int hyperfun)
{
    return (evolve_meta){ command, cloud_name, e->eo.gp.seed, e->eo.gp.setops,
                          e->base ? &e->base->b : NULL, e->note[0] ? e->note : NULL,
                          e->cloud, exact, hyperfun, e->cancel_flag };
}

int frep_evolution_write(const frep_evolution *e, const char *path, const char *command,
                         const char *cloud_name, int exact, int hyperfun,
                         frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    evolve_meta meta = model_meta(e, command, cloud_name, exact, hyperfun);
    write_ctx w = { e, &meta };
    return api_write_atomic(&d, path, write_model, &w);
}

int frep_evolution_write_dot(const frep_evolution *e, const char *path, frep_diag_fn diag,
                             void *user)
{
    api_diag d = { diag, user };
    write_ctx w = { e, NULL };
    return api_write_atomic(&d, path, write_dot, &w);
}

/* What fn writes, in memory: a string of the library's allocator (frep_free). */
static char *text_of(const api_diag *d, int (*fn)(FILE *f, void *ctx), void *ctx, size_t *len)
{
    char *mem = NULL;
    size_t n = 0;
    FILE *f = open_memstream(&mem, &n);
    int rc = f ? fn(f, ctx) : -1;
    if (f && fclose(f) != 0) rc = -1;
    char *text = rc == 0 ? frep_malloc(n + 1) : NULL;
    if (text) {
        memcpy(text, mem, n);
        text[n] = '\0';
        if (len) *len = n;
    }
    free(mem);
    if (!text) api_fail(d, NULL);
    return text;
}

char *frep_evolution_model(const frep_evolution *e, const char *command,
                           const char *cloud_name, int exact, int hyperfun, size_t *len,
                           frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    evolve_meta meta = model_meta(e, command, cloud_name, exact, hyperfun);
    write_ctx w = { e, &meta };
    return text_of(&d, write_model, &w, len);
}

char *frep_evolution_dot(const frep_evolution *e, size_t *len, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    write_ctx w = { e, NULL };
    return text_of(&d, write_dot, &w, len);
}

/* ---- the base of a residual run ---- */

frep_evolve_base *frep_evolve_base_new(const frep_program *p, const char *file,
                                       const char *text, size_t len, const char *model,
                                       frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    if (!file) file = "(base)";
    frep_evolve_base *b = frep_calloc(1, sizeof *b);
    if (!b || !(b->file = frep_strdup(file))) {
        frep_free(b);
        api_fail(&d, NULL);
        return NULL;
    }
    if (!p || !text) {
        frep_error_set(&e, FREP_EINPUT, "frep_evolve_base_new: a program and its text");
        frep_evolve_base_free(b);
        api_fail(&d, &e);
        return NULL;
    }
    if (residual_prepare(file, text, len, model, p, &b->b, &e) != 0) {
        frep_evolve_base_free(b);
        api_fail(&d, &e);
        return NULL;
    }
    return b;
}

void frep_evolve_base_free(frep_evolve_base *b)
{
    if (!b) return;
    residual_free(&b->b);
    frep_free(b->file);
    frep_free(b);
}

frep_setops frep_evolve_base_setops(const frep_evolve_base *b)
{
    return b->b.setops == GP_SETOPS_RFUNC ? FREP_SETOPS_RFUNC : FREP_SETOPS_MINMAX;
}

/* api_evolve.c - construction trees in the public API: the cloud's normals
 * (geom/normals.c) and primitives (segment/segment.c) when missing, evolve/evolve.c's
 * genetic programming, the optional refit (evolve/refit.c) and the model writers.  The
 * caller's cancel callback is polled where the progress is reported and raises the
 * flag every step of the run checks.
 */
#include "config.h"

#include "api.h"
#include "cloud.h"
#include "evolve.h"
#include "normals.h"
#include "refit.h"

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>

#include "alloc.h"
#include "util.h"

struct frep_evolution {
    evolve_options eo;
    evolve_result res;
    prim *prims;               /* the primitives the tree's leaves refer to (owned) */
    size_t nprims;
    const frep_cloud *cloud;   /* the caller's, for the writers' check */
    int interrupted;
    double rms_before, rms_after; /* refit's, NaN without */
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

/* The caller's progress and cancel: the GA's progress function, and the run's
 * gp_cancel (gp.h), whose flag is the caller's cancel_flag or stop. */
typedef struct evolve_job {
    const frep_evolve_options *o;
    volatile sig_atomic_t stop;
    gp_cancel cancel;
} evolve_job;

static int on_progress(void *user, const gp_progress *p)
{
    evolve_job *j = user;
    if (j->o->progress) {
        frep_evolve_progress fp = { (int)p->phase, p->generation, p->best_fitness, p->best_len,
                                    p->explained, p->npoints, p->elapsed };
        j->o->progress(j->o->user, &fp);
    }
    if (j->o->cancel && j->o->cancel(j->o->user)) *j->cancel.flag = 1;
    /* polled just now: gp_cancelled() waits its interval before the next call */
    j->cancel.next = frep_now_seconds() + GP_CANCEL_POLL_SECONDS;
    return *j->cancel.flag != 0;
}

/* Segmentation's progress: the cancel callback polled (segment_run polls the flag). */
static void on_segment_progress(void *user, const char *stage, size_t done, size_t total,
                                size_t nprims)
{
    evolve_job *j = user;
    gp_cancelled(&j->cancel);
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
    eo->gp.max_time = o->max_time;
    eo->gp.report_explained = o->report_explained;
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
static int ensure_normals(const api_diag *d, frep_cloud *c, const frep_evolve_options *o,
                          evolve_job *job)
{
    if (c->has_normals && cloud_normalize_normals(c) != c->n) return 0;
    normals_config nc;
    normals_config_init(&nc);
    nc.knn = o->knn;
    nc.nthreads = o->nthreads;
    nc.interrupt = job->cancel.flag;  /* the flag only: no callback polled here */
    normals_info info;
    int rc = normals_run(c, &nc, &info);
    if (rc < 0) api_report(d, FREP_ERROR, "out of memory estimating normals");
    else if (rc > 0) api_report(d, FREP_ERROR, "stopped while estimating normals: no model");
    else {
        char msg[200];
        snprintf(msg, sizeof msg, "the cloud has no normals: estimated them (%zu neighbours%s, "
                 "noise %.3g, spacing %.3g)", info.knn, o->knn ? "" : ", auto", info.noise,
                 info.spacing);
        api_report(d, FREP_NOTE, msg);
    }
    return rc == 0 ? 0 : -1;
}

/* The primitives: a copy of the caller's, or the cloud segmented. */
static int get_prims(const api_diag *d, frep_cloud *c, const frep_segmentation *s,
                     const frep_evolve_options *o, frep_evolution *ev, evolve_job *job)
{
    frep_error e;
    frep_error_init(&e);
    if (s) {
        ev->nprims = s->r.nprims;
        ev->prims = frep_calloc(ev->nprims ? ev->nprims : 1, sizeof *ev->prims);
        if (!ev->prims) return api_fail(d, &e);
        if (ev->nprims) memcpy(ev->prims, s->r.prims, ev->nprims * sizeof *ev->prims);
        return ensure_normals(d, c, o, job);
    }
    /* knn 0: normals estimated here with the automatic neighbourhood, segment_run's
     * default is fixed */
    if (!c->has_normals && o->knn == 0 && ensure_normals(d, c, o, job) != 0) return -1;
    segment_config sc;
    segment_config_init(&sc);
    sc.seed = o->seed;
    sc.nthreads = o->nthreads;
    sc.interrupt = job->cancel.flag;
    sc.progress = on_segment_progress;
    sc.user = job;
    sc.knn = o->knn;
    segment_result r;
    memset(&r, 0, sizeof r);
    if (segment_run(c, &sc, &r, &e) != 0) return api_fail(d, &e);
    char msg[160];
    snprintf(msg, sizeof msg, "segmented: %zu primitives (%zu fitted, %zu separating)%s",
             r.nprims, r.nfitted, r.nprims - r.nfitted,
             r.normals_estimated ? ", normals estimated" : "");
    api_report(d, FREP_NOTE, msg);
    ev->prims = r.prims;
    ev->nprims = r.nprims;
    r.prims = NULL;
    segment_result_free(&r);
    return 0;
}

/* cloud checks -> [normals] -> primitives -> GA -> [refit] */
frep_evolution *frep_evolve(frep_cloud *c, const frep_segmentation *prims,
                            const frep_evolve_options *o, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    frep_evolve_options def;
    if (!o) {
        frep_evolve_options_init(&def);
        o = &def;
    }
    frep_evolution *ev = frep_calloc(1, sizeof *ev);
    if (!ev) {
        api_fail(&d, &e);
        return NULL;
    }
    ev->cloud = c;
    ev->rms_before = ev->rms_after = NAN;
    options_from(o, &ev->eo);
    evolve_job job = { o, 0, { NULL, o->cancel, o->user, 0 } };
    job.cancel.flag = o->cancel_flag ? o->cancel_flag : &job.stop;
    ev->eo.gp.cancel = &job.cancel;
    int rc = 0;
    if (!c || c->n == 0) rc = -1, api_report(&d, FREP_ERROR, "no points");
    else if (cloud_check_scale(c, "the cloud", &e)) rc = api_fail(&d, &e);
    if (rc == 0) rc = get_prims(&d, c, prims, o, ev, &job);
    if (rc == 0 && ev->nprims == 0)
        rc = -1, api_report(&d, FREP_ERROR, *job.cancel.flag ? "stopped before any primitive was found"
                                                      : "no primitives to combine");
    if (rc == 0 && evolve_run(&ev->eo, c, ev->prims, ev->nprims, on_progress, &job, &ev->res,
                              &e) != 0)
        rc = api_fail(&d, &e);
    if (rc == 0 && o->refit && !*job.cancel.flag) {
        evolve_refit_info ri;
        frep_error_init(&e);
        if (evolve_refit(&ev->eo, c, ev->prims, ev->nprims, NULL, &ev->res, &ri, &e) != 0) {
            char msg[FREP_ERROR_MSG_MAX + 80];
            snprintf(msg, sizeof msg, "refit: %s (the model keeps the parameters as segmented)",
                     e.msg[0] ? e.msg : "failed");
            api_report(&d, FREP_WARNING, msg);
        } else if (ri.nparams) {
            ev->rms_before = ri.rms_before;
            ev->rms_after = ri.rms_after;
            snprintf(ev->note, sizeof ev->note,
                     "refit: %zu parameters, RMS distance %.6g -> %.6g, max %.6g -> %.6g, %.2f s",
                     ri.nparams, ri.rms_before, ri.rms_after, ri.max_before, ri.max_after,
                     ri.seconds);
            api_report(&d, FREP_NOTE, ev->note);
        }
    }
    ev->interrupted = *job.cancel.flag != 0;
    ev->eo.gp.cancel = NULL;
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
    *info = (frep_evolve_info){
        .tree_size = r->tree.len, .nprims = e->nprims, .npoints = r->npoints,
        .dropped = r->dropped, .explained = r->stats.explained,
        .within_eps = r->stats.within_eps, .normals_ok = r->stats.normals_ok,
        .fitness = r->fitness, .generations = r->generations, .seconds = r->seconds,
        .alpha_deg = r->alpha * 180 / FREP_PI, .alpha_auto = r->alpha_auto,
        .partitioned = r->partitioned, .interrupted = e->interrupted,
        .refit_rms_before = e->rms_before, .refit_rms_after = e->rms_after
    };
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

int frep_evolution_write(const frep_evolution *e, const char *path, const char *command,
                         const char *cloud_name, int exact, int hyperfun,
                         frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    evolve_meta meta = { command, cloud_name, e->eo.gp.seed, e->eo.gp.setops, NULL,
                         e->note[0] ? e->note : NULL, e->cloud, exact, hyperfun };
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

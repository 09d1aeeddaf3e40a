/* api_segment.c - segmentation in the public API: the normals of a cloud without
 * them (api/api_normals.c), segment/segment.c's efficient RANSAC and separating
 * primitives over it, the .fit / .hf writers, the result's figures and primitives.  A
 * cancel callback is polled where the progress is reported, and raises the flag the
 * detector checks before each step.
 */
#include "config.h"

#include "api.h"
#include "fitfile.h"
#include "segment.h"

#include <signal.h>
#include <string.h>

#include "alloc.h"

_Static_assert(FREP_PRIM_PLANE == (int)PRIM_PLANE && FREP_PRIM_SPHERE == (int)PRIM_SPHERE &&
                   FREP_PRIM_CYLINDER == (int)PRIM_CYLINDER && FREP_PRIM_CONE == (int)PRIM_CONE &&
                   FREP_PRIM_TORUS == (int)PRIM_TORUS && PRIM__COUNT == 5,
               "frep_prim_type follows geom/prim.h's prim_type");
_Static_assert(FREP_PRIM_NTYPES == PRIM__COUNT, "one name a type");
_Static_assert(FREP_SEGMENT_NO_SMALL == SEGMENT_NO_SMALL, "no second phase");
_Static_assert(FREP_NUMBER_BUF >= PRIM_NUM_BUF, "prim_format_number's buffer");

void frep_segment_options_init(frep_segment_options *o)
{
    segment_config c;
    segment_config_init(&c);
    memset(o, 0, sizeof *o);
    o->epsilon = c.epsilon;
    o->cluster = c.cluster;
    o->normal_deg = c.normal_deg;
    o->min_points = c.min_points;
    o->min_points_small = c.min_points_small;
    o->probability = c.probability;
    o->types = c.types;
    o->seed = c.seed;
    o->nthreads = c.nthreads;
    o->knn = c.knn;
    o->separating = c.separating;
}

/* The caller's progress and cancel, seen by the segmenter as its progress and flag
 * (the caller's flag when given, else stop). */
typedef struct seg_job {
    const frep_segment_options *o;
    volatile sig_atomic_t stop;
    volatile sig_atomic_t *flag;
} seg_job;

static void seg_progress(void *user, const char *stage, size_t done, size_t total, size_t nprims)
{
    seg_job *j = user;
    if (j->o->progress) j->o->progress(j->o->user, stage, done, total, nprims);
    if (j->o->cancel && j->o->cancel(j->o->user)) *j->flag = 1;
}

/* A cloud without normals and knn 0 gets frep_normals()'s estimate with the
 * neighbourhood chosen from the data, as the frep command gives it (segment_run's own
 * would take a fixed one); an interrupted estimate leaves the flag raised, so
 * detection stops at once.  With a knn, and for zero normals among given ones,
 * segment_run estimates them itself (the same estimate, not normalized again). */
static int auto_normals(seg_job *j, frep_cloud *c, int *estimated)
{
    *estimated = 0;
    if (c->has_normals || c->n == 0 || j->o->knn) return 0;
    seg_progress(j, "normals", 0, c->n, 0);
    if (api_estimate_normals(c, j->o->knn, j->o->nthreads, j->flag, NULL) < 0) return -1;
    *estimated = 1;
    return 0;
}

frep_segmentation *frep_segment(frep_cloud *c, const frep_segment_options *o,
                                frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    frep_segment_options def;
    if (!o) {
        frep_segment_options_init(&def);
        o = &def;
    }
    segment_config cfg;
    segment_config_init(&cfg);
    cfg.epsilon = o->epsilon;
    cfg.cluster = o->cluster;
    cfg.normal_deg = o->normal_deg;
    cfg.min_points = o->min_points;
    cfg.min_points_small = o->min_points_small;
    cfg.probability = o->probability;
    cfg.types = o->types;
    cfg.seed = o->seed;
    cfg.nthreads = o->nthreads;
    cfg.knn = o->knn;
    cfg.separating = o->separating;
    seg_job job = { o, 0, o->cancel_flag };
    job.flag = job.flag ? job.flag : &job.stop;
    if (o->progress || o->cancel) {
        cfg.progress = seg_progress;
        cfg.user = &job;
    }
    cfg.interrupt = job.flag;
    frep_segmentation *s = frep_calloc(1, sizeof *s);
    if (!s) {
        api_fail(&d, &e);
        return NULL;
    }
    s->npoints = c->n;
    int estimated = 0;
    if (auto_normals(&job, c, &estimated) != 0) {
        frep_segmentation_free(s);
        api_report(&d, FREP_ERROR, "out of memory estimating normals");
        return NULL;
    }
    cfg.normals_estimated = estimated;
    if (segment_run(c, &cfg, &s->r, &e) != 0) {
        frep_segmentation_free(s);
        api_fail(&d, &e);
        return NULL;
    }
    s->r.normals_estimated |= estimated;
    return s;
}

void frep_segmentation_free(frep_segmentation *s)
{
    if (!s) return;
    segment_result_free(&s->r);
    frep_free(s);
}

size_t frep_segmentation_nprims(const frep_segmentation *s) { return s->r.nprims; }
size_t frep_segmentation_nfitted(const frep_segmentation *s) { return s->r.nfitted; }
size_t frep_segmentation_unassigned(const frep_segmentation *s) { return s->r.unassigned; }
int frep_segmentation_interrupted(const frep_segmentation *s) { return s->r.interrupted; }
const int32_t *frep_segmentation_labels(const frep_segmentation *s) { return s->r.label; }

void frep_segmentation_get_info(const frep_segmentation *s, frep_segment_info *info)
{
    const segment_result *r = &s->r;
    memset(info, 0, sizeof *info);
    info->npoints = s->npoints;
    info->nprims = r->nprims;
    info->nfitted = r->nfitted;
    info->unassigned = r->unassigned;
    info->diagonal = r->diagonal;
    info->noise = r->noise;
    info->epsilon = r->epsilon;
    info->cluster = r->cluster;
    info->normal_deg = r->normal_deg;
    info->probability = r->probability;
    info->min_points = r->min_points;
    info->min_points_small = r->min_points_small;
    info->normals_estimated = r->normals_estimated;
    info->zero_normals = r->zero_normals;
    info->draws = r->draws;
    info->interrupted = r->interrupted;
}

const char *frep_prim_type_name(int type)
{
    return type >= 0 && type < PRIM__COUNT ? prim_type_name((prim_type)type) : NULL;
}

int frep_segmentation_get_prim(const frep_segmentation *s, size_t j, frep_prim *p)
{
    if (j >= s->r.nprims) return -1;
    const prim *q = &s->r.prims[j];
    memset(p, 0, sizeof *p);
    p->type = (int)q->type;
    memcpy(p->p, q->p, sizeof p->p);
    memcpy(p->a, q->a, sizeof p->a);
    p->r = q->r;
    p->R = q->R;
    p->separating = q->separating;
    p->support = q->support;
    p->rms = q->rms;
    return 0;
}

char *frep_format_number(char *buf, size_t size, double v, double quantum)
{
    char tmp[PRIM_NUM_BUF];
    prim_format_number(tmp, v, quantum);
    if (size) snprintf(buf, size, "%s", tmp);
    return buf;
}

typedef struct seg_out {
    const frep_segmentation *s;
    const char *header;
    int fit;
} seg_out;

static int write_prims(FILE *f, void *ctx)
{
    const seg_out *o = ctx;
    const segment_result *r = &o->s->r;
    return o->fit ? fitfile_write(f, r->prims, r->nprims)
                  : segment_write_hf(f, r->prims, r->nprims, o->header, r->diagonal);
}

frep_segmentation *frep_segmentation_read(const char *path, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    frep_segmentation *s = frep_calloc(1, sizeof *s);
    if (!s) {
        api_fail(&d, &e);
        return NULL;
    }
    if (segment_read_prims(path, &s->r.prims, &s->r.nprims, &e) != 0) {
        frep_segmentation_free(s);
        api_fail(&d, &e);
        return NULL;
    }
    for (size_t i = 0; i < s->r.nprims; i++) s->r.nfitted += !s->r.prims[i].separating;
    return s;
}

int frep_segmentation_write(const frep_segmentation *s, const char *path, const char *header,
                            frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    size_t n = path ? strlen(path) : 0;
    seg_out o = { s, header, n >= 4 && strcmp(path + n - 4, ".fit") == 0 };
    return api_write_atomic(&d, path, write_prims, &o);
}

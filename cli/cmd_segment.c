/* cmd_segment.c - frep segment: detect planes, spheres, cylinders, cones and tori in a
 * point cloud (segment/segment.c) and write them, with the separating primitives a
 * construction tree needs, as a readable .hf model or a .fit list for frep evolve.
 */
#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "fitfile.h"
#include "normals.h"
#include "segment.h"
#include "util.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* Seconds between progress lines on a terminal. */
#define SEGMENT_PROGRESS_INTERVAL 0.2

static const char segment_usage[] =
    "usage: frep segment CLOUD [-o PRIMITIVES.hf|X.fit] [options]\n\n"
    "Find the primitive surfaces of a point cloud (.xyz or .ply, with or without normals)\n"
    "by efficient RANSAC (Schnabel et al. 2007) and add the separating primitives of\n"
    "Fayolle & Pasko (2016): the oriented box planes of each curved primitive and a\n"
    "cylinder for each torus. Prints a summary table; with -o writes a frep model listing\n"
    "each primitive (.hf) or the plain .fit list of the reference GP implementation.\n\n";

typedef struct progress_state {
    double last;
    int shown;
    const char *stage;   /* the stage last shown (a new one is shown at once) */
} progress_state;

static void progress(void *user, const char *stage, size_t done, size_t total, size_t nprims)
{
    progress_state *p = user;
    double t = frep_now_seconds();
    if (t - p->last < SEGMENT_PROGRESS_INTERVAL && p->stage && strcmp(stage, p->stage) == 0)
        return;
    p->last = t;
    p->stage = stage;
    p->shown = 1;
    fprintf(stderr, "\rfrep segment: %s: %zu/%zu points assigned, %zu primitives   ", stage, done,
            total, nprims);
    fflush(stderr);
}

typedef struct out_ctx {
    const segment_result *r;
    const frep_cloud *c;
    const char *header;
} out_ctx;

static int write_hf_cb(FILE *f, void *user)
{
    out_ctx *o = user;
    return segment_write_hf(f, o->r->prims, o->r->nprims, o->header, o->r->diagonal);
}

static int write_fit_cb(FILE *f, void *user)
{
    out_ctx *o = user;
    return fitfile_write(f, o->r->prims, o->r->nprims);
}

static int write_labels_cb(FILE *f, void *user)
{
    out_ctx *o = user;
    for (size_t i = 0; i < o->c->n; i++) fprintf(f, "%ld\n", (long)o->r->label[i] + 1);
    return ferror(f) ? -1 : 0;
}

static int ends_with(const char *s, const char *suf)
{
    size_t a = strlen(s), b = strlen(suf);
    return a >= b && strcmp(s + a - b, suf) == 0;
}

/* --types plane,sphere,...: a bit per type. */
static int parse_types(const char *arg, void *dest, char *why, size_t whylen)
{
    unsigned *mask = dest;
    *mask = 0;
    for (const char *p = arg; *p;) {
        const char *e = strchr(p, ',');
        size_t l = e ? (size_t)(e - p) : strlen(p);
        int found = 0;
        for (int t = 0; t < PRIM__COUNT; t++) {
            const char *nm = prim_type_name((prim_type)t);
            if (strlen(nm) == l && strncmp(nm, p, l) == 0) {
                *mask |= 1u << t;
                found = 1;
            }
        }
        if (!found) {
            snprintf(why, whylen, "unknown primitive type '%.*s' (expected plane, sphere, "
                     "cylinder, cone, torus)", (int)l, p);
            return -1;
        }
        p += l + (e ? 1 : 0);
    }
    if (!*mask) snprintf(why, whylen, "needs at least one type");
    return *mask ? 0 : -1;
}

/* Summary precision: relative to the diagonal for lengths, absolute for directions. */
#define SUMMARY_QUANTUM 1e-6

/* One number of the summary table, rounded (prim_format_number). */
static const char *num(char *buf, double v, double quantum)
{
    prim_format_number(buf, v, quantum);
    return buf;
}

static void print_params(const prim *q, double diag)
{
    char b[8][PRIM_NUM_BUF];
    double qp = SUMMARY_QUANTUM * diag, qd = SUMMARY_QUANTUM;
    switch (q->type) {
    case PRIM_PLANE:
        printf("n=(%s, %s, %s) d=%s", num(b[0], q->p[0], qd), num(b[1], q->p[1], qd),
               num(b[2], q->p[2], qd), num(b[3], q->r, qp));
        break;
    case PRIM_SPHERE:
        printf("c=(%s, %s, %s) r=%s", num(b[0], q->p[0], qp), num(b[1], q->p[1], qp),
               num(b[2], q->p[2], qp), num(b[3], q->r, qp));
        break;
    case PRIM_CYLINDER:
    case PRIM_CONE:
    case PRIM_TORUS:
        printf("%s=(%s, %s, %s) a=(%s, %s, %s)", q->type == PRIM_CYLINDER ? "p"
                                                 : q->type == PRIM_CONE   ? "apex" : "c",
               num(b[0], q->p[0], qp), num(b[1], q->p[1], qp), num(b[2], q->p[2], qp),
               num(b[3], q->a[0], qd), num(b[4], q->a[1], qd), num(b[5], q->a[2], qd));
        if (q->type == PRIM_CYLINDER)
            printf(" r=%s", num(b[6], q->r, qp));
        else if (q->type == PRIM_CONE)
            printf(" angle=%s deg", num(b[6], q->r * 180.0 / FREP_PI, 1e-4));
        else
            printf(" R=%s r=%s", num(b[6], q->R, qp), num(b[7], q->r, qp));
        break;
    case PRIM__COUNT:
        break;
    }
}

typedef struct segment_cmd {
    segment_config cfg;
    const char *in, *out, *labels;
    size_t min_small;          /* --min-points-small as given */
    double max_time;           /* --max-time: seconds; 0: none */
    int quiet;
    frep_cloud *c;
    int had_normals;           /* the file had normals (before segment_run) */
    int auto_normals;          /* normals estimated here (--knn auto) */
    segment_result r;
    double elapsed;
    char header[2048];         /* of the .hf output: the command line and every setting */
} segment_cmd;

#define OFF(f) offsetof(segment_cmd, f)
static const cli_opt segment_opts[] = {
    { 'o', "output", "FILE", CLI_OPT_STRING, OFF(out), .help = "primitives: .hf model, or .fit list" },
    { 0, "labels", "FILE", CLI_OPT_STRING, OFF(labels),
      .help = "per point (one a line): number N of its primitive pN, 0: none" },
    { 0, "types", "LIST", CLI_OPT_CUSTOM, OFF(cfg.types), .parse = parse_types,
      .help = "among plane,sphere,cylinder,cone,torus (default: all)" },
    { 0, "epsilon", "E", CLI_OPT_DOUBLE, OFF(cfg.epsilon), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .help = "inlier distance in model units (default 5 x the measured\n"
              "noise, within 0.2%..1% of the box diagonal)" },
    { 0, "cluster", "D", CLI_OPT_DOUBLE, OFF(cfg.cluster), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .help = "connectivity cell size (default: 1% of the diagonal, at\n"
              "least 3 median point spacings)" },
    { 0, "normal-threshold", "T", CLI_OPT_DOUBLE, OFF(cfg.normal_deg), .lo = 0.01, .hi = 90,
      .help = "largest normal deviation of an inlier, degrees (25)" },
    { 0, "min-points", "M", CLI_OPT_SIZE, OFF(cfg.min_points), .lo = 3, .hi = 4e9,
      .help = "smallest support of a primitive (default 1% of the points,\n"
              "at least 10)" },
    { 0, "min-points-small", "M", CLI_OPT_SIZE, OFF(min_small), .lo = 0, .hi = 4e9,
      .help = "then tight shapes down to M points (default 0.04% of the\n"
              "points, at least 10; 0: no second phase)" },
    { 0, "probability", "P", CLI_OPT_DOUBLE, OFF(cfg.probability), .lo = 0.01, .hi = 0.999999,
      .help = "confidence of not having missed a better shape (0.99)" },
    CLI_OPT_KNN(segment_cmd, cfg.knn),
    { 0, "max-time", "T", CLI_OPT_DOUBLE, OFF(max_time), .lo = 0, .hi = 1e9,
      .help = "stop after T seconds of wall time in all (reading, normals,\n"
              "detection) and write the primitives found so far" },
    { 0, "no-separating", NULL, CLI_OPT_CLEAR, OFF(cfg.separating),
      .help = "do not add separating primitives" },
    CLI_OPT_SEED(segment_cmd, cfg.seed, "random seed (default: from the clock; always printed)"),
    CLI_OPT_THREADS(segment_cmd, cfg.nthreads, "OpenMP threads (the result does not depend on it)"),
    CLI_OPT_QUIET(segment_cmd, quiet, "no summary"),
};
#undef OFF
static const cli_opt_spec segment_spec = { "segment", segment_usage, segment_opts,
                                           sizeof segment_opts / sizeof segment_opts[0], 28 };

/* Options -> one CLOUD; the seed from the clock and the process unless given. */
static int stage_options(segment_cmd *s, int argc, char **argv)
{
    cli_args args;
    int rc = cli_opt_parse(&segment_spec, argc, argv, s, &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1)
        return cli_usage_error("segment", args.n < 1 ? "missing CLOUD file" : "too many arguments");
    if (cli_opt_given(&segment_spec, &args, "min-points-small"))
        s->cfg.min_points_small = s->min_small < 1 ? SEGMENT_NO_SMALL
                                                   : s->min_small < 3 ? 3 : s->min_small;
    if (!cli_opt_given(&segment_spec, &args, "seed"))
        s->cfg.seed = (uint64_t)time(NULL) ^ ((uint64_t)getpid() << 32);
    s->in = args.v[0];
    if (s->max_time > 0 && cli_deadline_arm(s->max_time))
        return cli_usage_error("segment", "--max-time: cannot set a timer");
    return CLI_GO_ON;
}

/* RANSAC over the cloud, with progress on a terminal; Ctrl-C keeps what was found. */
static int stage_segment(segment_cmd *s)
{
    frep_error err;
    frep_error_init(&err);
    s->c = cloud_read(s->in, &err);
    if (!s->c) {
        fprintf(stderr, "frep segment: %s\n", err.msg[0] ? err.msg : "cannot read the cloud");
        return CLI_FAIL;
    }
    s->had_normals = s->c->has_normals;
    if (cli_check_cloud("segment", s->in, s->c, 0) != CLI_OK) return CLI_FAIL;
    /* --knn auto (the default): the command estimates the normals itself, the library's
     * default being a fixed NORMALS_DEFAULT_K. */
    if (!s->c->has_normals && s->cfg.knn == 0) {
        normals_config nc;
        normals_config_init(&nc);
        nc.nthreads = s->cfg.nthreads;
        nc.interrupt = cli_sigint_catch();
        if (normals_run(s->c, &nc, NULL) < 0) {
            fprintf(stderr, "frep segment: out of memory estimating normals\n");
            return CLI_FAIL;
        }
        s->auto_normals = 1;
    }
    progress_state ps = {0, 0, NULL};
    if (isatty(2) && !s->quiet) {
        s->cfg.progress = progress;
        s->cfg.user = &ps;
    }
    s->cfg.interrupt = cli_sigint_catch();
    double t0 = frep_now_seconds();
    int rc = segment_run(s->c, &s->cfg, &s->r, &err);
    s->elapsed = frep_now_seconds() - t0;
    cli_sigint_restore();
    if (ps.shown) fputs("\r\033[K", stderr);
    if (rc) {
        fprintf(stderr, "%s: error: %s\n", s->in, err.msg[0] ? err.msg : "segmentation failed");
        return CLI_FAIL;
    }
    return CLI_OK;
}

/* The header of the .hf output: the command line and every setting. */
static void stage_header(segment_cmd *s, int argc, char **argv)
{
    const segment_result *r = &s->r;
    char *h = s->header;
    size_t cap = sizeof s->header;
    int hl = snprintf(h, cap, "frep segment");
    for (int i = 1; i < argc && hl < (int)cap - 64; i++)
        hl += snprintf(h + hl, cap - (size_t)hl, " %s", argv[i]);
    snprintf(h + hl, cap - (size_t)hl,
             "\nseed %llu, epsilon %.6g, cluster %.6g, normal threshold %g deg, "
             "min points %zu (small %zu), probability %g\n%zu points, %zu fitted primitives, %zu separating, "
             "%zu unassigned points",
             (unsigned long long)s->cfg.seed, r->epsilon, r->cluster, r->normal_deg, r->min_points,
             r->min_points_small, r->probability, s->c->n, r->nfitted, r->nprims - r->nfitted,
             r->unassigned);
}

/* The summary table on stdout. */
static void stage_report(const segment_cmd *s)
{
    const segment_result *r = &s->r;
    printf("frep segment: %s: %zu points, normals %s, seed %llu\n", s->in, s->c->n,
           s->auto_normals ? "estimated" : r->normals_estimated ? (s->had_normals ? "re-estimated (zero-length ones in the file)"
                                                  : "estimated")
                                : "from the file",
           (unsigned long long)s->cfg.seed);
    printf("  epsilon %.6g, cluster %.6g, normal threshold %g deg, min points %zu (small %zu), "
           "probability %g\n", r->epsilon, r->cluster, r->normal_deg, r->min_points,
           r->min_points_small, r->probability);
    printf("  %-5s %-9s %9s %10s  %s\n", "name", "type", "support", "rms", "parameters");
    for (size_t j = 0; j < r->nprims; j++) {
        const prim *q = &r->prims[j];
        char name[32];
        snprintf(name, sizeof name, "p%zu", j + 1);
        if (q->separating)
            printf("  %-5s %-9s %9s %10s  ", name, prim_type_name(q->type), "separating", "");
        else
            printf("  %-5s %-9s %9zu %10.3g  ", name, prim_type_name(q->type), q->support, q->rms);
        print_params(q, r->diagonal);
        putchar('\n');
    }
    printf("  %zu fitted, %zu separating; %zu points unassigned; %zu samples; %.2f s\n",
           r->nfitted, r->nprims - r->nfitted, r->unassigned, r->draws, s->elapsed);
}

/* -o (.fit list or .hf model) and --labels, each atomically. */
static int stage_write(const segment_cmd *s)
{
    out_ctx o = {&s->r, s->c, s->header};
    int status = CLI_OK;
    if (s->out) {
        int w = ends_with(s->out, ".fit") ? cli_write_atomic(s->out, write_fit_cb, &o)
                                          : cli_write_atomic(s->out, write_hf_cb, &o);
        if (w) status = CLI_FAIL;
    }
    if (s->labels && cli_write_atomic(s->labels, write_labels_cb, &o)) status = CLI_FAIL;
    return status;
}

/* segment -> header -> summary -> files */
static int segment_steps(segment_cmd *s, int argc, char **argv)
{
    int rc = stage_segment(s);
    if (rc != CLI_OK) return rc;
    stage_header(s, argc, argv);
    if (!s->quiet) stage_report(s);
    rc = stage_write(s);
    int stopped = s->r.interrupted && !cli_deadline_passed();
    if (s->r.interrupted && cli_deadline_passed())
        fprintf(stderr, "frep segment: --max-time %g s reached: detection cut short after %zu "
                        "primitives%s\n", s->max_time, s->r.nfitted,
                s->r.normals_estimated && s->r.nfitted == 0 ? " (normal estimation may be unfinished)" : "");
    segment_result_free(&s->r);
    if (rc == CLI_OK && stopped)
        return cli_interrupt_status("segment", "wrote the primitives found so far");
    return rc;
}

int cmd_segment(int argc, char **argv)
{
    segment_cmd s;
    memset(&s, 0, sizeof s);
    segment_config_init(&s.cfg);
    int rc = stage_options(&s, argc, argv);
    if (rc == CLI_GO_ON) rc = segment_steps(&s, argc, argv);
    cloud_free(s.c);
    return rc;
}

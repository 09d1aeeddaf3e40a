/* cmd_segment.c - frep segment: detect planes, spheres, cylinders, cones and tori in a
 * point cloud through the public API (frep_segment(), api/api_segment.c, which
 * estimates the normals of a cloud without them first) and write them, with the
 * separating primitives a construction tree needs, as a readable .hf model or a .fit
 * list for frep evolve.  This file reads the options, prints the progress and the
 * summary table, and maps Ctrl-C and --max-time to the run's cancel flag.
 */
#include "config.h"

#include "cli.h"

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
    double t = cli_now_seconds();
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
    const frep_segmentation *g;
    size_t n;
} out_ctx;

static int write_labels_cb(FILE *f, void *user)
{
    out_ctx *o = user;
    const int32_t *label = frep_segmentation_labels(o->g);
    for (size_t i = 0; i < o->n; i++) fprintf(f, "%ld\n", (long)label[i] + 1);
    return ferror(f) ? -1 : 0;
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
        for (int t = 0; t < FREP_PRIM_NTYPES; t++) {
            const char *nm = frep_prim_type_name(t);
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
/* Cone angles are printed in degrees. */
#define SEGMENT_PI 3.14159265358979323846

/* One number of the summary table, rounded (frep_format_number). */
static const char *num(char *buf, double v, double quantum)
{
    return frep_format_number(buf, FREP_NUMBER_BUF, v, quantum);
}

static void print_params(const frep_prim *q, double diag)
{
    char b[8][FREP_NUMBER_BUF];
    double qp = SUMMARY_QUANTUM * diag, qd = SUMMARY_QUANTUM;
    switch ((frep_prim_type)q->type) {
    case FREP_PRIM_PLANE:
        printf("n=(%s, %s, %s) d=%s", num(b[0], q->p[0], qd), num(b[1], q->p[1], qd),
               num(b[2], q->p[2], qd), num(b[3], q->r, qp));
        break;
    case FREP_PRIM_SPHERE:
        printf("c=(%s, %s, %s) r=%s", num(b[0], q->p[0], qp), num(b[1], q->p[1], qp),
               num(b[2], q->p[2], qp), num(b[3], q->r, qp));
        break;
    case FREP_PRIM_CYLINDER:
    case FREP_PRIM_CONE:
    case FREP_PRIM_TORUS:
        printf("%s=(%s, %s, %s) a=(%s, %s, %s)", q->type == FREP_PRIM_CYLINDER ? "p"
                                                 : q->type == FREP_PRIM_CONE   ? "apex" : "c",
               num(b[0], q->p[0], qp), num(b[1], q->p[1], qp), num(b[2], q->p[2], qp),
               num(b[3], q->a[0], qd), num(b[4], q->a[1], qd), num(b[5], q->a[2], qd));
        if (q->type == FREP_PRIM_CYLINDER)
            printf(" r=%s", num(b[6], q->r, qp));
        else if (q->type == FREP_PRIM_CONE)
            printf(" angle=%s deg", num(b[6], q->r * 180.0 / SEGMENT_PI, 1e-4));
        else
            printf(" R=%s r=%s", num(b[6], q->R, qp), num(b[7], q->r, qp));
        break;
    }
}

typedef struct segment_cmd {
    frep_segment_options o;
    const char *in, *out, *labels;
    size_t min_small;          /* --min-points-small as given */
    double max_time;           /* --max-time: seconds; 0: none */
    int quiet;
    frep_cloud *c;
    int had_normals;           /* the file had normals (before frep_segment) */
    frep_segmentation *g;
    frep_segment_info r;
    double elapsed;
    char error[1024];          /* frep_segment's error */
    char header[2048];         /* of the .hf output: the command line and every setting */
} segment_cmd;

#define OFF(f) offsetof(segment_cmd, f)
static const cli_opt segment_opts[] = {
    { 'o', "output", "FILE", CLI_OPT_STRING, OFF(out), .help = "primitives: .hf model, or .fit list" },
    { 0, "labels", "FILE", CLI_OPT_STRING, OFF(labels),
      .help = "per point (one a line): number N of its primitive pN, 0: none" },
    { 0, "types", "LIST", CLI_OPT_CUSTOM, OFF(o.types), .parse = parse_types,
      .help = "among plane,sphere,cylinder,cone,torus (default: all)" },
    { 0, "epsilon", "E", CLI_OPT_DOUBLE, OFF(o.epsilon), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .help = "inlier distance in model units (default 5 x the measured\n"
              "noise, within 0.2%..1% of the box diagonal)" },
    { 0, "cluster", "D", CLI_OPT_DOUBLE, OFF(o.cluster), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .help = "connectivity cell size (default: 1% of the diagonal, at\n"
              "least 3 median point spacings)" },
    { 0, "normal-threshold", "T", CLI_OPT_DOUBLE, OFF(o.normal_deg), .lo = 0.01, .hi = 90,
      .help = "largest normal deviation of an inlier, degrees (25)" },
    { 0, "min-points", "M", CLI_OPT_SIZE, OFF(o.min_points), .lo = 3, .hi = 4e9,
      .help = "smallest support of a primitive (default 1% of the points,\n"
              "at least 10)" },
    { 0, "min-points-small", "M", CLI_OPT_SIZE, OFF(min_small), .lo = 0, .hi = 4e9,
      .help = "then tight shapes down to M points (default 0.04% of the\n"
              "points, 0.02% on a clean cloud with normals, at least 10;\n"
              "0: no second phase)" },
    { 0, "probability", "P", CLI_OPT_DOUBLE, OFF(o.probability), .lo = 0.01, .hi = 0.999999,
      .help = "confidence of not having missed a better shape (0.99)" },
    CLI_OPT_KNN(segment_cmd, o.knn),
    { 0, "max-time", "T", CLI_OPT_DOUBLE, OFF(max_time), .lo = 0, .hi = 1e9,
      .help = "stop after T seconds of wall time in all (reading, normals,\n"
              "detection) and write the primitives found so far" },
    { 0, "no-separating", NULL, CLI_OPT_CLEAR, OFF(o.separating),
      .help = "do not add separating primitives" },
    CLI_OPT_SEED(segment_cmd, o.seed, "random seed (default: from the clock; always printed)"),
    CLI_OPT_THREADS(segment_cmd, o.nthreads, "OpenMP threads (the result does not depend on it)"),
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
        s->o.min_points_small = s->min_small < 1   ? FREP_SEGMENT_NO_SMALL
                                : s->min_small < 3 ? 3
                                                   : s->min_small;
    if (!cli_opt_given(&segment_spec, &args, "seed"))
        s->o.seed = (uint64_t)time(NULL) ^ ((uint64_t)getpid() << 32);
    s->in = args.v[0];
    if (s->max_time > 0 && cli_deadline_arm(s->max_time))
        return cli_usage_error("segment", "--max-time: cannot set a timer");
    return CLI_GO_ON;
}

/* The library's messages: the error kept for stage_segment, the others printed. */
static void segment_diag(void *user, const frep_diag *d)
{
    segment_cmd *s = user;
    if (d->severity == FREP_ERROR && s->c) {
        snprintf(s->error, sizeof s->error, "%s", d->message);
        return;
    }
    cli_library_diag("segment", d);
}

/* RANSAC over the cloud (its normals estimated first when it has none), with progress
 * on a terminal; Ctrl-C keeps what was found. */
static int stage_segment(segment_cmd *s)
{
    s->c = frep_cloud_read(s->in, segment_diag, s);
    if (!s->c) return CLI_FAIL;
    s->had_normals = frep_cloud_has_normals(s->c);
    if (cli_check_cloud("segment", s->in, s->c, 0) != CLI_OK) return CLI_FAIL;
    progress_state ps = {0, 0, NULL};
    if (isatty(2) && !s->quiet) {
        s->o.progress = progress;
        s->o.user = &ps;
    }
    s->o.cancel_flag = cli_sigint_catch();
    double t0 = cli_now_seconds();
    s->g = frep_segment(s->c, &s->o, segment_diag, s);
    s->elapsed = cli_now_seconds() - t0;
    cli_sigint_restore();
    if (ps.shown) fputs("\r\033[K", stderr);
    if (!s->g) {
        fprintf(stderr, "frep segment: %s: %s\n", s->in, s->error[0] ? s->error : "segmentation failed");
        return CLI_FAIL;
    }
    frep_segmentation_get_info(s->g, &s->r);
    return CLI_OK;
}

/* The header of the .hf output: the command line and every setting. */
static void stage_header(segment_cmd *s, int argc, char **argv)
{
    const frep_segment_info *r = &s->r;
    char *h = s->header;
    size_t cap = sizeof s->header;
    int hl = snprintf(h, cap, "frep segment");
    for (int i = 1; i < argc && hl < (int)cap - 64; i++)
        hl += snprintf(h + hl, cap - (size_t)hl, " %s", argv[i]);
    snprintf(h + hl, cap - (size_t)hl,
             "\nseed %llu, epsilon %.6g, cluster %.6g, normal threshold %g deg, "
             "min points %zu (small %zu), probability %g\n%zu points, %zu fitted primitives, %zu separating, "
             "%zu unassigned points",
             (unsigned long long)s->o.seed, r->epsilon, r->cluster, r->normal_deg, r->min_points,
             r->min_points_small, r->probability, r->npoints, r->nfitted, r->nprims - r->nfitted,
             r->unassigned);
}

/* The summary table on stdout. */
static void stage_report(const segment_cmd *s)
{
    const frep_segment_info *r = &s->r;
    printf("frep segment: %s: %zu points, normals %s, seed %llu\n", s->in, r->npoints,
           !s->had_normals          ? "estimated"
           : r->normals_estimated ? "re-estimated (zero-length ones in the file)"
                                  : "from the file",
           (unsigned long long)s->o.seed);
    printf("  epsilon %.6g, cluster %.6g, normal threshold %g deg, min points %zu (small %zu), "
           "probability %g\n", r->epsilon, r->cluster, r->normal_deg, r->min_points,
           r->min_points_small, r->probability);
    printf("  %-5s %-9s %9s %10s  %s\n", "name", "type", "support", "rms", "parameters");
    for (size_t j = 0; j < r->nprims; j++) {
        frep_prim q;
        frep_segmentation_get_prim(s->g, j, &q);
        char name[32];
        snprintf(name, sizeof name, "p%zu", j + 1);
        if (q.separating)
            printf("  %-5s %-9s %9s %10s  ", name, frep_prim_type_name(q.type), "separating", "");
        else
            printf("  %-5s %-9s %9zu %10.3g  ", name, frep_prim_type_name(q.type), q.support, q.rms);
        print_params(&q, r->diagonal);
        putchar('\n');
    }
    printf("  %zu fitted, %zu separating; %zu points unassigned; %zu samples; %.2f s\n",
           r->nfitted, r->nprims - r->nfitted, r->unassigned, r->draws, s->elapsed);
}

/* The library's messages while writing: printed as the command's. */
static void write_diag(void *user, const frep_diag *d)
{
    cli_library_diag("segment", d);
}

/* -o (.fit list or .hf model) and --labels, each atomically. */
static int stage_write(const segment_cmd *s)
{
    out_ctx o = {s->g, s->r.npoints};
    int status = CLI_OK;
    if (s->out && frep_segmentation_write(s->g, s->out, s->header, write_diag, NULL))
        status = CLI_FAIL;
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
    if (rc == CLI_OK && stopped)
        return cli_interrupt_status("segment", "wrote the primitives found so far");
    return rc;
}

int cmd_segment(int argc, char **argv)
{
    segment_cmd s;
    memset(&s, 0, sizeof s);
    frep_segment_options_init(&s.o);
    int rc = stage_options(&s, argc, argv);
    if (rc == CLI_GO_ON) rc = segment_steps(&s, argc, argv);
    frep_segmentation_free(s.g);
    frep_cloud_free(s.c);
    return rc;
}

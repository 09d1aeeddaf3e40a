/* cmd_segment.c - frep segment: detect planes, spheres, cylinders, cones and tori in a
 * point cloud (segment/segment.c) and write them, with the separating primitives a
 * construction tree needs, as a readable .hf model or a .fit list for frep evolve.
 */
#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "fitfile.h"
#include "segment.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <signal.h>
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
    "each primitive (.hf) or the plain .fit list of the reference GP implementation.\n\n"
    "Options:\n"
    "  -o, --output FILE         primitives: .hf model, or .fit list\n"
    "      --labels FILE         per point (one a line): number N of its primitive pN, 0: none\n"
    "      --types LIST          among plane,sphere,cylinder,cone,torus (default: all)\n"
    "      --epsilon E           inlier distance (default 1% of the box diagonal; 'abs'\n"
    "                            suffix not needed: E is in model units)\n"
    "      --cluster D           connectivity cell size (default: 1% of the diagonal, at\n"
    "                            least 3 median point spacings)\n"
    "      --normal-threshold T  largest normal deviation of an inlier, degrees (25)\n"
    "      --min-points M        smallest support of a primitive (default 1% of the points,\n"
    "                            at least 10)\n"
    "      --min-points-small M  then tight shapes down to M points (default 0.25% of the\n"
    "                            points, at least 10; 0: no second phase)\n"
    "      --probability P       confidence of not having missed a better shape (0.99)\n"
    "      --knn K               neighbours for normal estimation (12)\n"
    "      --no-separating       do not add separating primitives\n"
    "      --seed S              random seed (default: from the clock; always printed)\n"
    "  -t, --threads N           OpenMP threads (the result does not depend on it)\n"
    "  -q, --quiet               no summary\n";

static volatile sig_atomic_t segment_interrupted;

static void on_sigint(int sig)
{
    (void)sig;
    segment_interrupted = 1;
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct progress_state {
    double last;
    int shown;
} progress_state;

static void progress(void *user, const char *stage, size_t done, size_t total, size_t nprims)
{
    progress_state *p = user;
    double t = now_seconds();
    if (t - p->last < SEGMENT_PROGRESS_INTERVAL) return;
    p->last = t;
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

static int parse_double(const char *opt, const char *s, double *v, double lo, double hi)
{
    char *e;
    errno = 0;
    double t = strtod(s, &e);
    if (e == s || *e || errno || !(t >= lo && t <= hi)) {
        cli_usage_error("segment", "%s expects a number in [%g, %g], got '%s'", opt, lo, hi, s);
        return -1;
    }
    *v = t;
    return 0;
}

static int parse_types(const char *s, unsigned *mask)
{
    *mask = 0;
    const char *p = s;
    while (*p) {
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
            cli_usage_error("segment", "unknown primitive type '%.*s' in --types "
                            "(expected plane, sphere, cylinder, cone, torus)", (int)l, p);
            return -1;
        }
        p += l + (e ? 1 : 0);
    }
    if (!*mask) {
        cli_usage_error("segment", "--types needs at least one type");
        return -1;
    }
    return 0;
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
            printf(" angle=%s deg", num(b[6], q->r * 180.0 / 3.14159265358979323846, 1e-4));
        else
            printf(" R=%s r=%s", num(b[6], q->R, qp), num(b[7], q->r, qp));
        break;
    case PRIM__COUNT:
        break;
    }
}

int cmd_segment(int argc, char **argv)
{
    enum { O_LABELS = 256, O_TYPES, O_EPS, O_CLUSTER, O_NORMAL, O_MINPTS, O_MINSMALL, O_PROB, O_SEED,
           O_KNN, O_NOSEP };
    static const struct option longopts[] = {
        { "help", no_argument, NULL, 'h' },
        { "output", required_argument, NULL, 'o' },
        { "labels", required_argument, NULL, O_LABELS },
        { "types", required_argument, NULL, O_TYPES },
        { "epsilon", required_argument, NULL, O_EPS },
        { "cluster", required_argument, NULL, O_CLUSTER },
        { "normal-threshold", required_argument, NULL, O_NORMAL },
        { "min-points", required_argument, NULL, O_MINPTS },
        { "min-points-small", required_argument, NULL, O_MINSMALL },
        { "probability", required_argument, NULL, O_PROB },
        { "seed", required_argument, NULL, O_SEED },
        { "knn", required_argument, NULL, O_KNN },
        { "no-separating", no_argument, NULL, O_NOSEP },
        { "threads", required_argument, NULL, 't' },
        { "quiet", no_argument, NULL, 'q' },
        { NULL, 0, NULL, 0 },
    };
    segment_config cfg;
    segment_config_init(&cfg);
    const char *out = NULL, *labels = NULL;
    int quiet = 0, have_seed = 0;
    double v;
    optind = 1;
    opterr = 0;
    int ch;
    while ((ch = getopt_long(argc, argv, ":ho:t:q", longopts, NULL)) != -1) {
        switch (ch) {
        case 'h': fputs(segment_usage, stdout); return CLI_OK;
        case 'o': out = optarg; break;
        case O_LABELS: labels = optarg; break;
        case O_TYPES: if (parse_types(optarg, &cfg.types)) return CLI_USAGE; break;
        case O_EPS:
            if (parse_double("--epsilon", optarg, &cfg.epsilon, 1e-300, 1e300)) return CLI_USAGE;
            break;
        case O_CLUSTER:
            if (parse_double("--cluster", optarg, &cfg.cluster, 1e-300, 1e300)) return CLI_USAGE;
            break;
        case O_NORMAL:
            if (parse_double("--normal-threshold", optarg, &cfg.normal_deg, 0.01, 90)) return CLI_USAGE;
            break;
        case O_MINPTS:
            if (parse_double("--min-points", optarg, &v, 3, 4e9)) return CLI_USAGE;
            cfg.min_points = (size_t)v;
            break;
        case O_MINSMALL:
            if (parse_double("--min-points-small", optarg, &v, 0, 4e9)) return CLI_USAGE;
            cfg.min_points_small = v < 1 ? SEGMENT_NO_SMALL : (size_t)(v < 3 ? 3 : v);
            break;
        case O_PROB:
            if (parse_double("--probability", optarg, &cfg.probability, 0.01, 0.999999)) return CLI_USAGE;
            break;
        case O_KNN:
            if (parse_double("--knn", optarg, &v, 3, 256)) return CLI_USAGE;
            cfg.knn = (size_t)v;
            break;
        case O_SEED: {
            char *e;
            errno = 0;
            unsigned long long s = strtoull(optarg, &e, 10);
            if (e == optarg || *e || errno || optarg[0] == '-')
                return cli_usage_error("segment", "--seed expects a non-negative integer, got '%s'", optarg);
            cfg.seed = s;
            have_seed = 1;
            break;
        }
        case O_NOSEP: cfg.separating = 0; break;
        case 't':
            if (parse_double("--threads", optarg, &v, 1, 1024)) return CLI_USAGE;
            cfg.nthreads = (int)v;
            break;
        case 'q': quiet = 1; break;
        case ':': return cli_usage_error("segment", "option '%s' needs a value", argv[optind - 1]);
        default: return cli_usage_error("segment", "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (optind != argc - 1)
        return cli_usage_error("segment", optind >= argc ? "missing CLOUD file" : "too many arguments");
    const char *in = argv[optind];
    if (!have_seed) cfg.seed = (uint64_t)time(NULL) ^ ((uint64_t)getpid() << 32);

    frep_error err;
    frep_cloud *c = cloud_read(in, &err);
    if (!c) {
        fprintf(stderr, "frep segment: %s\n", err.msg[0] ? err.msg : "cannot read the cloud");
        return CLI_FAIL;
    }
    int had_normals = c->has_normals;
    progress_state ps = {0, 0};
    if (isatty(2) && !quiet) {
        cfg.progress = progress;
        cfg.user = &ps;
    }
    cfg.interrupt = &segment_interrupted;
    void (*old)(int) = signal(SIGINT, on_sigint);
    double t0 = now_seconds();
    segment_result r;
    int rc = segment_run(c, &cfg, &r, &err);
    double elapsed = now_seconds() - t0;
    signal(SIGINT, old == SIG_ERR ? SIG_DFL : old);
    if (ps.shown) fputs("\r\033[K", stderr);
    if (rc) {
        fprintf(stderr, "%s: error: %s\n", in, err.msg[0] ? err.msg : "segmentation failed");
        cloud_free(c);
        return CLI_FAIL;
    }
    if (r.interrupted) fprintf(stderr, "frep segment: interrupted; writing what was found\n");

    /* The header of the .hf output: the command line and every setting. */
    char header[2048];
    int hl = snprintf(header, sizeof header, "frep segment");
    for (int i = 1; i < argc && hl < (int)sizeof header - 64; i++)
        hl += snprintf(header + hl, sizeof header - (size_t)hl, " %s", argv[i]);
    snprintf(header + hl, sizeof header - (size_t)hl,
             "\nseed %llu, epsilon %.6g, cluster %.6g, normal threshold %g deg, "
             "min points %zu (small %zu), probability %g\n%zu points, %zu fitted primitives, %zu separating, "
             "%zu unassigned points",
             (unsigned long long)cfg.seed, r.epsilon, r.cluster, r.normal_deg, r.min_points,
             r.min_points_small, r.probability, c->n, r.nfitted, r.nprims - r.nfitted, r.unassigned);

    if (!quiet) {
        printf("frep segment: %s: %zu points, normals %s, seed %llu\n", in, c->n,
               r.normals_estimated ? (had_normals ? "re-estimated (zero-length ones in the file)"
                                                  : "estimated")
                                   : "from the file",
               (unsigned long long)cfg.seed);
        printf("  epsilon %.6g, cluster %.6g, normal threshold %g deg, min points %zu (small %zu), "
               "probability %g\n", r.epsilon, r.cluster, r.normal_deg, r.min_points,
               r.min_points_small, r.probability);
        printf("  %-5s %-9s %9s %10s  %s\n", "name", "type", "support", "rms", "parameters");
        for (size_t j = 0; j < r.nprims; j++) {
            const prim *q = &r.prims[j];
            char name[32];
            snprintf(name, sizeof name, "p%zu", j + 1);
            if (q->separating)
                printf("  %-5s %-9s %9s %10s  ", name, prim_type_name(q->type), "separating", "");
            else
                printf("  %-5s %-9s %9zu %10.3g  ", name, prim_type_name(q->type), q->support, q->rms);
            print_params(q, r.diagonal);
            putchar('\n');
        }
        printf("  %zu fitted, %zu separating; %zu points unassigned; %zu samples; %.2f s\n",
               r.nfitted, r.nprims - r.nfitted, r.unassigned, r.draws, elapsed);
    }
    out_ctx o = {&r, c, header};
    int status = CLI_OK;
    if (out) {
        int w = ends_with(out, ".fit") ? cli_write_atomic(out, write_fit_cb, &o)
                                       : cli_write_atomic(out, write_hf_cb, &o);
        if (w) status = CLI_FAIL;
    }
    if (labels && cli_write_atomic(labels, write_labels_cb, &o)) status = CLI_FAIL;
    segment_result_free(&r);
    cloud_free(c);
    return status;
}

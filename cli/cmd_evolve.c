/* cmd_evolve.c - frep evolve: from a point cloud (and optionally its primitives) to a
 * readable .hf construction-tree model, by genetic programming (evolve/evolve.c);
 * segments the cloud first (segment/segment.c) when no primitive list is given.
 */
#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "evolve.h"
#include "normals.h"
#include "refit.h"
#include "residual.h"
#include "segment.h"
#include "buf.h"
#include "util.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef _OPENMP
#include <omp.h>
#endif
#include <unistd.h>

static const char evolve_usage[] =
    "usage: frep evolve CLOUD [-p PRIMS.hf|PRIMS.fit] [-o MODEL.hf] [options]\n\n"
    "Discover a construction tree (primitives at the leaves, set operations at the nodes)\n"
    "whose zero set fits the oriented point cloud CLOUD (.xyz or .ply), by genetic\n"
    "programming (Fayolle & Pasko 2016), accelerated by partitioning the primitives'\n"
    "overlap graph into cliques (Friedrich et al. 2018). Without -p the cloud is\n"
    "segmented first with frep segment's defaults. The result is a .hf model: the\n"
    "primitives, the tree, a clipping box, and comments with the figures of the run.\n"
    "The same seed gives the same model at any thread count (without --max-time).\n"
    "Ctrl-C stops the run and writes the best model so far.\n\n";

static int write_trace_cb(FILE *f, void *user)
{
    const frep_buf *t = user;
    if (t->len) fwrite(t->s, 1, t->len, f);
    return ferror(f) ? -1 : 0;
}

typedef struct progress_ctx {
    int tty, quiet;
    double last;
    frep_buf *trace;         /* NULL without --trace */
    double t0;               /* frep_now_seconds() when evolve_run started */
    clock_t c0;              /* clock() then */
    int polish;              /* 1 once the merge of a partitioned run was reported */
    double stop_share;       /* --stop-share: percent; 0: none */
} progress_ctx;

static int progress(void *user, const gp_progress *p)
{
    progress_ctx *c = user;
    if (p->phase == GP_PHASE_CLIQUES || p->phase == GP_PHASE_SIMPLIFY) {
        /* the start of a phase: no --trace line (it has no new tree) */
        if (c->tty && !c->quiet) {
            fprintf(stderr, "\rfrep evolve: %s, %.1f s   ",
                    p->phase == GP_PHASE_CLIQUES ? "evolving a tree per clique"
                                                 : "simplifying the tree", p->elapsed);
            fflush(stderr);
        }
        return cli_interrupted();
    }
    if (c->trace) {
        double wall = frep_now_seconds() - c->t0;
        double cpu = (double)(clock() - c->c0) / CLOCKS_PER_SEC;
        if (p->phase == GP_PHASE_MERGE) {
            c->polish = 1;
            buf_printf(c->trace, "%u %.4f %.4f nan %u - merge\n", p->generation, wall, cpu,
                      p->best_len);
        } else {
            double share = p->npoints
                               ? 100.0 * (double)p->explained / (double)p->npoints
                               : 0.0;
            const char *ph = p->phase == GP_PHASE_MERGED ? "merged"
                             : p->phase == GP_PHASE_GROWN ? "grown"
                             : c->polish                  ? "polish"
                                                          : "ga";
            buf_printf(c->trace, "%u %.4f %.4f %.10g %u %.3f %s\n", p->generation, wall, cpu,
                      p->best_fitness, p->best_len, share, ph);
        }
    }
    if (c->tty && !c->quiet && (p->elapsed - c->last >= 0.2 || p->generation == 1)) {
        c->last = p->elapsed;
        if (p->phase == GP_PHASE_MERGE || p->phase == GP_PHASE_MERGED)
            fprintf(stderr, "\rfrep evolve: merging clique trees: tree size %u, %.1f s   ",
                    p->best_len, p->elapsed);
        else if (p->phase == GP_PHASE_GROWN)
            fprintf(stderr, "\rfrep evolve: merged tree grown: tree size %u, %.1f s   ",
                    p->best_len, p->elapsed);
        else
            fprintf(stderr, "\rfrep evolve: generation %u, best fitness %.6g, tree size %u, %.1f s   ",
                    p->generation, p->best_fitness, p->best_len, p->elapsed);
        fflush(stderr);
    }
    /* --stop-share: a GA phase ends once its best tree explains enough points. */
    if (c->stop_share > 0 && p->phase == GP_PHASE_GA && p->npoints &&
        100.0 * (double)p->explained >= c->stop_share * (double)p->npoints)
        return 1;
    return cli_interrupted();
}

typedef struct write_ctx {
    const evolve_result *r;
    const prim *prims;
    size_t nprims;
    const evolve_meta *m;
} write_ctx;

static int write_model_cb(FILE *f, void *user)
{
    write_ctx *w = user;
    return evolve_write_model(f, w->r, w->prims, w->nprims, w->m);
}

static int write_dot_cb(FILE *f, void *user)
{
    write_ctx *w = user;
    return evolve_write_dot(f, w->r, w->prims, w->nprims);
}

static char *join_args(int argc, char **argv)
{
    size_t n = 16;
    for (int i = 0; i < argc; i++) n += strlen(argv[i]) + 1;
    char *s = malloc(n);
    if (!s) return NULL;
    strcpy(s, "frep");
    for (int i = 0; i < argc; i++) {
        /* Newlines would end the comment line of the model. */
        strcat(s, " ");
        size_t at = strlen(s);
        strcat(s, argv[i]);
        for (char *q = s + at; *q; q++)
            if (*q == '\n' || *q == '\r') *q = ' ';
    }
    return s;
}

/* Every step's inputs and results, from the options to the summary. */
typedef struct evolve_cmd {
    evolve_options eo;
    gp_cancel cancel;           /* Ctrl-C: the flag of the signal handler */
    const char *prims_path, *out, *dot, *residual_path, *trace_path, *view;
    double stop_share;          /* --stop-share, percent; 0: none */
    int refit, quiet, have_setops, exact, hyperfun;
    const char *cloud_path, *cmdline;
    frep_cloud *cloud;
    frep_cloud *sub;            /* --residual without -p: the points to segment */
    prim *prims;                /* from -p (frep_free()) or seg.prims */
    size_t nprims;
    segment_result seg;
    int have_seg;
    evolve_base base;           /* --residual */
    frep_program *base_prog;
    char *base_src;
    double *base_f, *base_g;
    uint8_t *mask, *base_ok;     /* base_ok: where the --residual model can be evaluated */
    progress_ctx pc;
    frep_buf trace;
    evolve_result res;
    char note[256];             /* --refit's figures for the model's comments */
    frep_error ferr;            /* of the library calls */
    size_t knn;                 /* --knn: neighbours for normals; 0: from the data */
    double max_time, t_start;   /* --max-time (0: none) and when the command started */
    const char *cut;            /* the step --max-time cut short; NULL: none */
} evolve_cmd;

static int parse_setops(const char *arg, void *dest, char *why, size_t whylen)
{
    gp_setops *s = dest;
    if (strcmp(arg, "minmax") == 0) *s = GP_SETOPS_MINMAX;
    else if (strcmp(arg, "rfunc") == 0) *s = GP_SETOPS_RFUNC;
    else return -1;
    return 0;
}

#define OFF(f) offsetof(evolve_cmd, f)
static const cli_opt evolve_opts[] = {
    { 'p', "prims", "FILE", CLI_OPT_STRING, OFF(prims_path),
      .help = "primitives: a .hf list written by frep segment, or a .fit list" },
    { 'o', "output", "FILE", CLI_OPT_STRING, OFF(out), .def = "-",
      .help = "model to write (default: standard output)" },
    { 0, "setops", "S", CLI_OPT_CUSTOM, OFF(eo.gp.setops), .parse = parse_setops,
      .expect = "minmax or rfunc", .help = "minmax (default) or rfunc" },
    { 0, "partition", NULL, CLI_OPT_SET, OFF(eo.partition),
      .help = "partition the overlap graph (default)" },
    { 0, "no-partition", NULL, CLI_OPT_CLEAR, OFF(eo.partition),
      .help = "one GA over all primitives" },
    { 0, "no-polish", NULL, CLI_OPT_CLEAR, OFF(eo.polish),
      .help = "after partitioning, skip the GA over all primitives seeded\n"
              "with the merged tree" },
    { 0, "polish-stagnation", "G", CLI_OPT_U32, OFF(eo.polish_stagnation), .lo = 1, .hi = 1e9,
      .help = "stop the polish after G generations without\n"
              "improvement (default 15; at most --stagnation)" },
    { 0, "exact-numbers", NULL, CLI_OPT_SET, OFF(exact),
      .help = "write the fitted primitives as they are: every digit, no\n"
              "direction snapped, no axis point moved (by default the\n"
              "numbers are rounded to what the inliers support)" },
    { 0, "hyperfun", NULL, CLI_OPT_SET, OFF(hyperfun),
      .help = "write pure HyperFun: each primitive as arithmetic of x\n"
              "(planes d - n.x, spheres and cylinders r^2 - distance^2),\n"
              "no frep extension, so the reference HyperFun tools read it" },
    { 0, "no-support", NULL, CLI_OPT_CLEAR, OFF(eo.support),
      .help = "keep material no point supports (by default the final\n"
              "tree is trimmed where its surface runs far from the cloud)" },
    CLI_OPT_SEED(evolve_cmd, eo.gp.seed, "random seed (default: from the clock; always printed)"),
    { 0, "generations", "G", CLI_OPT_U32, OFF(eo.gp.generations), .lo = 1, .hi = 1e9,
      .help = "generation limit (default 3000)" },
    { 0, "stagnation", "G", CLI_OPT_U32, OFF(eo.gp.stagnation), .lo = 0, .hi = 1e9,
      .help = "stop after G generations without improvement (default 40)" },
    { 0, "population", "P", CLI_OPT_U32, OFF(eo.gp.population), .lo = 1, .hi = 1e6,
      .help = "individuals (default 150)" },
    { 0, "tournament", "K", CLI_OPT_U32, OFF(eo.gp.tournament), .lo = 1, .hi = 1e6,
      .help = "tournament size (default 4)" },
    { 0, "crossover", "R", CLI_OPT_DOUBLE, OFF(eo.gp.p_crossover), .lo = 0, .hi = 1,
      .help = "crossover rate (default 0.3)" },
    { 0, "mutation", "R", CLI_OPT_DOUBLE, OFF(eo.gp.p_mutation), .lo = 0, .hi = 1,
      .help = "mutation rate (default 0.3)" },
    { 0, "elite", "E", CLI_OPT_U32, OFF(eo.gp.elite), .lo = 0, .hi = 1e6,
      .help = "best individuals kept each generation (default 2)" },
    { 0, "subtree-prob", "R", CLI_OPT_DOUBLE, OFF(eo.gp.p_subtree), .lo = 0, .hi = 1,
      .help = "probability of an operation node when growing (default 0.7)" },
    { 0, "max-depth", "D", CLI_OPT_INT, OFF(eo.gp.max_depth), .lo = 1, .hi = GP_MAX_TREE_DEPTH,
      .help = "maximum tree depth (default: ceil(log2 primitives) + 3)" },
    { 0, "max-time", "T", CLI_OPT_DOUBLE, OFF(max_time), .lo = 0, .hi = 1e9,
      .help = "stop after T seconds of wall time in all (normals,\n"
              "segmentation, GA) and write the best tree so far" },
    CLI_OPT_KNN(evolve_cmd, knn),
    { 0, "epsilon", "E", CLI_OPT_DOUBLE, OFF(eo.eps_rel), .lo = 1e-9, .hi = 1,
      .help = "distance tolerance as a fraction of the diagonal (default 0.01)" },
    { 0, "alpha", "DEG", CLI_OPT_DOUBLE, OFF(eo.alpha_deg), .lo = 0.01, .hi = 180,
      .help = "normal tolerance in degrees (default: automatic, 35 when the\n"
              "cloud is noisy or faceted against the primitives, else 10)" },
    { 0, "lambda-scale", "K", CLI_OPT_DOUBLE, OFF(eo.lambda_scale), .lo = 0, .hi = 1e6,
      .help = "size penalty K*ln(N) per node (default 1)" },
    { 0, "sample", "N", CLI_OPT_SIZE, OFF(eo.sample), .lo = 0, .hi = 1e12,
      .help = "points the GA scores (default 4096; 0: all)" },
    { 0, "no-simplify", NULL, CLI_OPT_CLEAR, OFF(eo.simplify), .help = "keep the tree as evolved" },
    { 0, "dot", "FILE", CLI_OPT_STRING, OFF(dot), .help = "also write the tree for Graphviz" },
    { 0, "view", "HTML", CLI_OPT_STRING, OFF(view),
      .help = "also write the page of the model and the cloud (frep view)" },
    { 0, "trace", "FILE", CLI_OPT_STRING, OFF(trace_path),
      .help = "write one line per generation: generation, wall and CPU\n"
              "seconds since the start, best fitness, tree size, % of the\n"
              "scored points the best tree explains, phase" },
    { 0, "stop-share", "P", CLI_OPT_DOUBLE, OFF(stop_share), .lo = 0, .hi = 100,
      .help = "end a GA phase once its best tree explains P% of the scored\n"
              "points (time-to-solution measurements)" },
    { 0, "residual", "MODEL", CLI_OPT_STRING, OFF(residual_path),
      .help = "join to MODEL.hf a tree evolved for the points it explains\n"
              "poorly (segmented from them without -p); the output holds\n"
              "MODEL's source and the joined model my_model" },
    { 0, "refit", NULL, CLI_OPT_SET, OFF(refit),
      .help = "refine the parameters of the tree's primitives together on\n"
              "every point (frep fit's Levenberg-Marquardt) and report the\n"
              "RMS distance before and after" },
    CLI_OPT_THREADS(evolve_cmd, eo.gp.threads, "OpenMP threads"),
    CLI_OPT_QUIET(evolve_cmd, quiet, "no progress and no summary"),
};
#undef OFF
static const cli_opt_spec evolve_spec = { "evolve", evolve_usage, evolve_opts,
                                          sizeof evolve_opts / sizeof evolve_opts[0], 24 };

static const char *setops_name(gp_setops s)
{
    return s == GP_SETOPS_RFUNC ? "rfunc" : "minmax";
}

/* Options -> one CLOUD; the settings the options imply (seed from the clock, automatic
 * alpha unless --alpha, lambda 0 as no penalty, the OpenMP default from -t). */
static int stage_options(evolve_cmd *e, int argc, char **argv)
{
    cli_args args;
    int rc = cli_opt_parse(&evolve_spec, argc, argv, e, &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error("evolve", args.n < 1 ? "missing CLOUD" : "one CLOUD expected");
    e->cloud_path = args.v[0];
    e->t_start = frep_now_seconds();
    if (e->max_time > 0 && cli_deadline_arm(e->max_time))
        return cli_usage_error("evolve", "--max-time: cannot set a timer");
    evolve_options *eo = &e->eo;
    if (eo->gp.p_crossover + eo->gp.p_mutation > 1)
        return cli_usage_error("evolve", "--crossover + --mutation must not exceed 1");
    e->have_setops = cli_opt_given(&evolve_spec, &args, "setops");
    if (cli_opt_given(&evolve_spec, &args, "alpha")) eo->alpha_auto = 0;
    if (!cli_opt_given(&evolve_spec, &args, "seed")) eo->gp.seed = (uint64_t)time(NULL);
    if (eo->lambda_scale == 0) eo->lambda_scale = 1e-12;  /* 0 asks for no penalty */
#ifdef _OPENMP
    /* -t also bounds the parallel loops that take no thread count (the primitive
     * caches' tables), so that -t 1 runs on one core. */
    if (eo->gp.threads > 0) omp_set_num_threads(eo->gp.threads);
#endif
    return CLI_GO_ON;
}

/* Normals for the GA: estimated when the cloud has none (or only zero-length ones). */
static int ensure_normals(evolve_cmd *e)
{
    frep_cloud *c = e->cloud;
    if (c->has_normals && cloud_normalize_normals(c) != c->n) return CLI_OK;
    normals_config nc;
    normals_config_init(&nc);
    nc.knn = e->knn;
    nc.nthreads = e->eo.gp.threads;
    nc.interrupt = cli_sigint_catch();
    normals_info info;
    int rc = normals_run(c, &nc, &info);
    if (rc < 0) {
        fprintf(stderr, "frep evolve: out of memory estimating normals\n");
        return CLI_FAIL;
    }
    if (rc > 0) {
        if (cli_deadline_passed())
            fprintf(stderr, "frep evolve: --max-time %g s reached while estimating normals: "
                            "no model, nothing written\n", e->max_time);
        return CLI_FAIL;
    }
    if (!e->quiet)
        fprintf(stderr, "frep evolve: the cloud has no normals: estimated them (%zu neighbours%s, "
                        "noise %.3g, spacing %.3g)\n", info.knn, e->knn ? "" : ", auto",
                info.noise, info.spacing);
    return CLI_OK;
}

/* The cloud read; normals are needed before the GA, and before the residual is known. */
static int stage_cloud(evolve_cmd *e)
{
    e->cloud = cloud_read(e->cloud_path, &e->ferr);
    if (!e->cloud) {
        fprintf(stderr, "frep evolve: %s\n", e->ferr.msg[0] ? e->ferr.msg : "cannot read the cloud");
        return CLI_FAIL;
    }
    if (!e->quiet) fprintf(stderr, "frep evolve: %zu points, seed %llu\n", e->cloud->n,
                           (unsigned long long)e->eo.gp.seed);
    if (e->cloud->n == 0) {
        fprintf(stderr, "frep evolve: %s: no points\n", e->cloud_path);
        return CLI_FAIL;
    }
    if (cloud_check_scale(e->cloud, e->cloud_path, &e->ferr)) {
        fprintf(stderr, "frep evolve: %s\n", e->ferr.msg);
        return CLI_FAIL;
    }
    if (cli_check_cloud("evolve", e->cloud_path, e->cloud, 1) != CLI_OK) return CLI_FAIL;
    if (e->prims_path || e->residual_path) return ensure_normals(e);
    return CLI_OK;
}

static int out_of_memory(void)
{
    fprintf(stderr, "frep evolve: out of memory\n");
    return CLI_FAIL;
}

/* The points the base model explains poorly, as a cloud to segment. */
static int residual_cloud(evolve_cmd *e, size_t nres)
{
    const frep_cloud *c = e->cloud;
    e->sub = cloud_new(1);
    if (!e->sub || cloud_reserve(e->sub, nres ? nres : 1)) return out_of_memory();
    for (size_t i = 0; i < c->n; i++)
        if (e->mask[i]) {
            double p[3] = { c->x[i], c->y[i], c->z[i] };
            double q[3] = { c->nx[i], c->ny[i], c->nz[i] };
            cloud_push(e->sub, p, q);
        }
    return CLI_OK;
}

/* --residual: the base model evaluated at every point; the GA runs for the points it
 * explains poorly, which are segmented on their own when no -p is given. */
static int stage_residual(evolve_cmd *e)
{
    evolve_options *eo = &e->eo;
    e->base_prog = cli_compile_file(e->residual_path, NULL, NULL, 0, -1, 0, &e->base_src);
    if (!e->base_prog) return CLI_FAIL;
    frep_error_init(&e->ferr);
    if (residual_prepare(e->residual_path, e->base_src, strlen(e->base_src), NULL, e->base_prog,
                         &e->base, &e->ferr)) {
        fprintf(stderr, "frep evolve: %s\n", e->ferr.msg[0] ? e->ferr.msg : "cannot use the model");
        return CLI_FAIL;
    }
    if (e->have_setops && eo->gp.setops != e->base.setops) {
        fprintf(stderr, "frep evolve: --setops %s disagrees with %s, which uses %s: the "
                        "joined model has one family\n",
                setops_name(eo->gp.setops), e->residual_path, setops_name(e->base.setops));
        return CLI_FAIL;
    }
    eo->gp.setops = e->base.setops;
    size_t N = e->cloud->n, nbad = 0, nres = 0;
    e->base_f = malloc(N * sizeof *e->base_f);
    e->base_g = malloc(3 * N * sizeof *e->base_g);
    e->mask = malloc(N);
    e->base_ok = malloc(N);
    if (!e->base_f || !e->base_g || !e->mask || !e->base_ok ||
        residual_eval(&e->base, e->cloud, eo->gp.threads, e->base_f, e->base_g, e->base_ok,
                      &nbad))
        return out_of_memory();
    if (nbad && !e->quiet)
        fprintf(stderr, "frep evolve: %s cannot be evaluated at %zu points (treated as "
                        "unexplained)\n", e->residual_path, nbad);
    eo->base_f = e->base_f;
    eo->base_g = e->base_g;
    eo->base_ok = e->base_ok;
    if (evolve_residual_points(eo, e->cloud, e->mask, &nres)) return out_of_memory();
    if (!e->quiet)
        fprintf(stderr, "frep evolve: %s explains %zu of %zu points; evolving for the %zu others\n",
                e->residual_path, N - nres, N, nres);
    return e->prims_path ? CLI_OK : residual_cloud(e, nres);
}

/* Without -p: segment the cloud (or the residual points) with frep segment's defaults. */
static int segment_prims(evolve_cmd *e)
{
    segment_config sc;
    segment_config_init(&sc);
    sc.seed = e->eo.gp.seed;
    sc.nthreads = e->eo.gp.threads;
    sc.interrupt = e->cancel.flag;
    sc.knn = e->knn;
    int failed = segment_run(e->sub ? e->sub : e->cloud, &sc, &e->seg, &e->ferr);
    if (cli_deadline_passed()) e->cut = "segmentation";
    if (failed) {
        if (!e->residual_path) {
            fprintf(stderr, "frep evolve: %s: %s\n", e->cloud_path,
                    e->ferr.msg[0] ? e->ferr.msg : "segmentation failed");
            return CLI_FAIL;
        }
        /* Too few residual points to segment: the result is the base model. */
        if (!e->quiet)
            fprintf(stderr, "frep evolve: the residual points give no primitive (%s)\n",
                    e->ferr.msg[0] ? e->ferr.msg : "segmentation failed");
        return CLI_OK;
    }
    e->have_seg = 1;
    e->prims = e->seg.prims;
    e->nprims = e->seg.nprims;
    if (!e->quiet)
        fprintf(stderr, "frep evolve: segmented%s: %zu primitives (%zu fitted, %zu separating)%s\n",
                e->sub ? " the residual" : "", e->seg.nprims, e->seg.nfitted,
                e->seg.nprims - e->seg.nfitted, e->seg.normals_estimated ? ", normals estimated" : "");
    return CLI_OK;
}

/* The primitives to combine: -p's list, or found by segmentation. */
static int stage_prims(evolve_cmd *e)
{
    int rc = CLI_OK;
    if (e->prims_path) {
        if (segment_read_prims(e->prims_path, &e->prims, &e->nprims, &e->ferr)) {
            fprintf(stderr, "frep evolve: %s\n", e->ferr.msg[0] ? e->ferr.msg : "cannot read the primitives");
            return CLI_FAIL;
        }
        rc = ensure_normals(e);
    } else if (!e->residual_path || e->sub->n > 0) {
        /* --knn auto: the normals are estimated here, segment_run's default is fixed. */
        if (!e->sub && !e->cloud->has_normals && e->knn == 0) rc = ensure_normals(e);
        if (rc == CLI_OK) rc = segment_prims(e);
    }
    if (rc == CLI_OK && e->nprims == 0 && !e->residual_path && e->cut) {
        fprintf(stderr, "frep evolve: --max-time %g s reached during segmentation before any "
                        "primitive was found: nothing written\n", e->max_time);
        return CLI_FAIL;
    }
    if (rc == CLI_OK && e->nprims == 0 && !e->residual_path) {
        fprintf(stderr, "frep evolve: no primitives to combine%s\n",
                e->prims_path ? "" : " (segmentation found none; try frep segment with other settings)");
        return CLI_FAIL;
    }
    return rc;
}

/* --trace's header lines. */
static void trace_header(frep_buf *t, uint64_t seed)
{
    buf_printf(t, "# frep evolve trace, seed %llu\n", (unsigned long long)seed);
    buf_printf(t, "# columns: generation, wall and CPU (process) seconds since the "
                  "start of the run, best fitness, tree size,\n");
    buf_printf(t, "# %% of the scored points the best tree explains, phase (ga: the "
                  "GA; merge: merging clique trees;\n");
    buf_printf(t, "# merged: the merged tree; grown: after the growth steps; polish: "
                  "the GA seeded with it)\n");
}

/* The automatic alpha and the noise estimate behind it. */
static void report_alpha(const evolve_result *res)
{
    double deg = res->alpha * 180 / FREP_PI;
    fprintf(stderr, "frep evolve: alpha %g degrees (automatic: %s; position spread %.3g eps, "
                    "normal deviation median %.2g, 90th percentile %.2g degrees over %zu "
                    "inliers; --alpha overrides)\n",
            deg, deg > EVOLVE_DEFAULT_ALPHA_DEG ? "noisy or faceted" : "clean",
            res->noise.sigma_d, res->noise.median_deg, res->noise.p90_deg, res->noise.inliers);
}

/* The GA (evolve/evolve.c) with progress, --trace and --stop-share; Ctrl-C keeps the
 * best tree so far. */
static int stage_evolve(evolve_cmd *e)
{
    progress_ctx *pc = &e->pc;
    pc->tty = isatty(2);
    pc->quiet = e->quiet;
    pc->last = -1;
    pc->stop_share = e->stop_share;
    if (e->stop_share > 0) e->eo.gp.report_explained = 1;
    if (e->trace_path) {
        pc->trace = &e->trace;
        e->eo.gp.report_explained = 1;
        trace_header(&e->trace, e->eo.gp.seed);
    }
    pc->t0 = frep_now_seconds();
    pc->c0 = clock();
    /* --max-time bounds the whole command: the GA gets what is left. */
    if (e->max_time > 0) e->eo.gp.max_time = fmax(e->max_time - (pc->t0 - e->t_start), 1e-3);
    cli_sigint_catch();
    frep_error_init(&e->ferr);
    int r = evolve_run(&e->eo, e->cloud, e->prims, e->nprims, progress, pc, &e->res, &e->ferr);
    if (!e->cut && (cli_deadline_passed() ||
                    (e->max_time > 0 && frep_now_seconds() - e->t_start >= e->max_time)))
        e->cut = "the GA";
    cli_sigint_restore();
    if (pc->tty && !e->quiet) fputc('\n', stderr);
    if (r) {
        fprintf(stderr, "frep evolve: %s: %s\n", e->cloud_path,
                e->ferr.msg[0] ? e->ferr.msg : "failed");
        return CLI_FAIL;
    }
    if (e->res.alpha_auto && !e->quiet) report_alpha(&e->res);
    return CLI_OK;
}

/* --refit: the primitives' parameters refined together; a failure keeps them. */
static void stage_refit(evolve_cmd *e)
{
    evolve_refit_info ri;
    frep_error_init(&e->ferr);
    if (evolve_refit(&e->eo, e->cloud, e->prims, e->nprims, e->residual_path ? &e->base : NULL,
                     &e->res, &ri, &e->ferr)) {
        fprintf(stderr, "frep evolve: --refit: %s (the model keeps the parameters as "
                        "segmented)\n", e->ferr.msg[0] ? e->ferr.msg : "failed");
    } else if (ri.nparams) {
        snprintf(e->note, sizeof e->note,
                 "refit: %zu parameters, RMS distance %.6g -> %.6g, max %.6g -> %.6g, %.2f s",
                 ri.nparams, ri.rms_before, ri.rms_after, ri.max_before, ri.max_after,
                 ri.seconds);
        if (!e->quiet) fprintf(stderr, "frep evolve: %s\n", e->note);
    }
}

static double percent(size_t k, size_t n)
{
    return n ? 100.0 * (double)k / (double)n : 0;
}

/* The model, --dot and --trace, each atomically. */
static int stage_write(evolve_cmd *e)
{
    evolve_meta meta = { e->cmdline, e->cloud_path, e->eo.gp.seed, e->eo.gp.setops,
                         e->residual_path ? &e->base : NULL, e->note[0] ? e->note : NULL,
                         e->cloud, e->exact, e->hyperfun };
    write_ctx w = { &e->res, e->prims, e->nprims, &meta };
    if (cli_write_atomic(e->out, write_model_cb, &w)) return CLI_FAIL;
    if (e->dot && cli_write_atomic(e->dot, write_dot_cb, &w)) return CLI_FAIL;
    cli_view_job vj = { "evolve", e->view, strcmp(e->out, "-") ? e->out : NULL, NULL,
                        e->cloud_path, write_model_cb, &w, NULL, 0, e->eo.gp.threads, e->quiet };
    if (e->view && cli_view_result(&vj) != CLI_OK) return CLI_FAIL;
    if (!e->trace_path) return CLI_OK;
    const evolve_result *res = &e->res;
    buf_printf(&e->trace, "# end: %.4f s wall, %.4f s CPU, %u nodes, %.3f%% of %zu points "
                          "explained (every point, after simplification)%s\n",
               frep_now_seconds() - e->pc.t0, (double)(clock() - e->pc.c0) / CLOCKS_PER_SEC,
               res->tree.len,
               percent(res->stats.explained, res->npoints), res->npoints,
               e->trace.failed ? "; out of memory: lines missing" : "");
    return cli_write_atomic(e->trace_path, write_trace_cb, &e->trace) ? CLI_FAIL : CLI_OK;
}

/* The summary on stderr. */
static void stage_report(const evolve_cmd *e)
{
    const evolve_result *res = &e->res;
    fprintf(stderr,
            "frep evolve: seed %llu: tree of %u nodes, %.2f%% of %zu points explained "
            "(%.2f%% within epsilon, %.2f%% normals), %s, %u generations, %.2f s\n",
            (unsigned long long)e->eo.gp.seed, res->tree.len,
            percent(res->stats.explained, res->npoints), res->npoints,
            percent(res->stats.within_eps, res->npoints), percent(res->stats.normals_ok, res->npoints),
            res->partitioned ? "partitioned" : "not partitioned", res->generations, res->seconds);
    if (res->dropped)
        fprintf(stderr, "frep evolve: %zu points without finite coordinates or normal ignored\n",
                res->dropped);
}

static void evolve_cmd_free(evolve_cmd *e)
{
    buf_free(&e->trace);
    if (e->have_seg) segment_result_free(&e->seg);
    else frep_free(e->prims);
    evolve_result_free(&e->res);
    residual_free(&e->base);
    frep_program_free(e->base_prog);
    free(e->base_src);
    free(e->base_f);
    free(e->base_g);
    free(e->mask);
    free(e->base_ok);
    cloud_free(e->sub);
    cloud_free(e->cloud);
}

/* cloud -> [residual] -> primitives -> GA -> [refit] -> files -> summary */
static int evolve_steps(evolve_cmd *e)
{
    int rc = stage_cloud(e);
    if (rc == CLI_OK && e->residual_path) rc = stage_residual(e);
    /* From the segmentation on, Ctrl-C stops the phase running and the best tree so
     * far is written (gp.h says which steps are skipped). */
    e->cancel.flag = cli_sigint_catch();
    e->eo.gp.cancel = &e->cancel;
    if (rc == CLI_OK) rc = stage_prims(e);
    if (rc == CLI_OK) rc = stage_evolve(e);
    if (rc != CLI_OK)
        return cli_interrupted() ? cli_interrupt_status("evolve", "nothing written") : rc;
    if (e->refit && !cli_interrupted() && !e->cut) stage_refit(e);
    if (e->cut && !e->quiet)
        fprintf(stderr, "frep evolve: --max-time %g s reached during %s: %s\n", e->max_time,
                e->cut, strcmp(e->cut, "segmentation") == 0
                            ? "evolved from the primitives found so far, with no time left for the GA"
                            : "wrote the best tree so far");
    rc = stage_write(e);
    if (rc == CLI_OK && !e->quiet) stage_report(e);
    if (rc == CLI_OK && cli_interrupted())
        return cli_interrupt_status("evolve", "wrote the best tree so far");
    return rc;
}

int cmd_evolve(int argc, char **argv)
{
    evolve_cmd *e = calloc(1, sizeof *e);
    if (!e) return out_of_memory();
    evolve_options_init(&e->eo);
    /* getopt_long permutes argv: keep the command line as typed for the model. */
    char *cmdline = join_args(argc, argv);
    e->cmdline = cmdline;
    int rc = stage_options(e, argc, argv);
    if (rc == CLI_GO_ON) rc = evolve_steps(e);
    evolve_cmd_free(e);
    free(e);
    free(cmdline);
    return rc;
}

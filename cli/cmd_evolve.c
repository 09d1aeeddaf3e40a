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

#include <errno.h>
#include <stdarg.h>
#include <getopt.h>
#include <math.h>
#include <signal.h>
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
    "Ctrl-C stops the run and writes the best model so far.\n\n"
    "Options:\n"
    "  -p, --prims FILE      primitives: a .hf list written by frep segment, or a .fit list\n"
    "  -o, --output FILE     model to write (default: standard output)\n"
    "      --setops S        minmax (default) or rfunc\n"
    "      --partition       partition the overlap graph (default)\n"
    "      --no-partition    one GA over all primitives\n"
    "      --no-polish       after partitioning, skip the GA over all primitives seeded\n"
    "                        with the merged tree\n"
    "      --polish-stagnation G  stop the polish after G generations without\n"
    "                        improvement (default 15; at most --stagnation)\n"
    "      --no-support      keep material no point supports (by default the final\n"
    "                        tree is trimmed where its surface runs far from the cloud)\n"
    "      --seed S          random seed (default: from the clock; always printed)\n"
    "      --generations G   generation limit (default 3000)\n"
    "      --stagnation G    stop after G generations without improvement (default 40)\n"
    "      --population P    individuals (default 150)\n"
    "      --tournament K    tournament size (default 4)\n"
    "      --crossover R     crossover rate (default 0.3)\n"
    "      --mutation R      mutation rate (default 0.3)\n"
    "      --elite E         best individuals kept each generation (default 2)\n"
    "      --subtree-prob R  probability of an operation node when growing (default 0.7)\n"
    "      --max-depth D     maximum tree depth (default: ceil(log2 primitives) + 3)\n"
    "      --max-time T      stop after T seconds\n"
    "      --epsilon E       distance tolerance as a fraction of the diagonal (default 0.01)\n"
    "      --alpha DEG       normal tolerance in degrees (default: automatic, 35 when the\n"
    "                        cloud is noisy or faceted against the primitives, else 10)\n"
    "      --lambda-scale K  size penalty K*ln(N) per node (default 1)\n"
    "      --sample N        points the GA scores (default 4096; 0: all)\n"
    "      --no-simplify     keep the tree as evolved\n"
    "      --dot FILE        also write the tree for Graphviz\n"
    "      --trace FILE      write one line per generation: generation, wall and CPU\n"
    "                        seconds since the start, best fitness, tree size, % of the\n"
    "                        scored points the best tree explains, phase\n"
    "      --stop-share P    end a GA phase once its best tree explains P% of the scored\n"
    "                        points (time-to-solution measurements)\n"
    "      --residual MODEL  join to MODEL.hf a tree evolved for the points it explains\n"
    "                        poorly (segmented from them without -p); the output holds\n"
    "                        MODEL's source and the joined model my_model\n"
    "      --refit           refine the parameters of the tree's primitives together on\n"
    "                        every point (frep fit's Levenberg-Marquardt) and report the\n"
    "                        RMS distance before and after\n"
    "  -t, --threads N       OpenMP threads\n"
    "  -q, --quiet           no progress and no summary\n";

/* The one piece of mutable global state the conventions allow: Ctrl-C. */
static volatile sig_atomic_t evolve_interrupted = 0;

static void on_sigint(int sig)
{
    (void)sig;
    evolve_interrupted = 1;
}

/* --trace: one line per generation, kept in memory and written atomically at the end
 * (a 3000-generation run is about 200 KB). */
typedef struct trace_buf {
    char *s;
    size_t len, cap;
    int failed;              /* out of memory: the trace is incomplete */
} trace_buf;

static void trace_add(trace_buf *t, const char *fmt, ...)
{
    char line[256];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (n < 0 || t->failed) return;
    size_t k = (size_t)n < sizeof line ? (size_t)n : sizeof line - 1;
    if (t->len + k + 1 > t->cap) {
        size_t cap = t->cap ? 2 * t->cap : 65536;
        while (cap < t->len + k + 1) cap *= 2;
        char *q = realloc(t->s, cap);
        if (!q) {
            t->failed = 1;
            return;
        }
        t->s = q;
        t->cap = cap;
    }
    memcpy(t->s + t->len, line, k);
    t->len += k;
    t->s[t->len] = 0;
}

static int write_trace_cb(FILE *f, void *user)
{
    const trace_buf *t = user;
    if (t->len) fwrite(t->s, 1, t->len, f);
    return ferror(f) ? -1 : 0;
}

typedef struct progress_ctx {
    int tty, quiet;
    double last;
    trace_buf *trace;        /* NULL without --trace */
    double t0;               /* gp_now() when evolve_run started */
    clock_t c0;              /* clock() then */
    int polish;              /* 1 once the merge of a partitioned run was reported */
    double stop_share;       /* --stop-share: percent; 0: none */
} progress_ctx;

static int progress(void *user, const gp_progress *p)
{
    progress_ctx *c = user;
    if (c->trace) {
        double wall = gp_now() - c->t0;
        double cpu = (double)(clock() - c->c0) / CLOCKS_PER_SEC;
        if (p->phase == GP_PHASE_MERGE) {
            c->polish = 1;
            trace_add(c->trace, "%u %.4f %.4f nan %u - merge\n", p->generation, wall, cpu,
                      p->best_len);
        } else {
            double share = p->npoints
                               ? 100.0 * (double)p->explained / (double)p->npoints
                               : 0.0;
            const char *ph = p->phase == GP_PHASE_MERGED ? "merged"
                             : p->phase == GP_PHASE_GROWN ? "grown"
                             : c->polish                  ? "polish"
                                                          : "ga";
            trace_add(c->trace, "%u %.4f %.4f %.10g %u %.3f %s\n", p->generation, wall, cpu,
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
    return evolve_interrupted != 0;
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

static int parse_num(const char *opt, const char *s, double lo, double hi, int integer,
                     double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno || !(v >= lo && v <= hi) || (integer && v != floor(v))) {
        cli_usage_error("evolve", "%s: expected %s in [%g, %g], got '%s'", opt,
                        integer ? "an integer" : "a number", lo, hi, s);
        return -1;
    }
    *out = v;
    return 0;
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

static int evolve_main(int argc, char **argv, const char *cmdline)
{
    enum {
        O_SETOPS = 256, O_PART, O_NOPART, O_SEED, O_GEN, O_STAG, O_POP, O_TOURN, O_CROSS,
        O_MUT, O_ELITE, O_SUBP, O_DEPTH, O_TIME, O_EPS, O_ALPHA, O_LAMBDA, O_SAMPLE,
        O_NOSIMP, O_DOT, O_RESIDUAL, O_REFIT, O_NOPOLISH, O_POLSTAG, O_TRACE, O_STOPSHARE,
        O_NOSUPPORT
    };
    static const struct option longopts[] = {
        { "help", no_argument, NULL, 'h' },
        { "prims", required_argument, NULL, 'p' },
        { "output", required_argument, NULL, 'o' },
        { "setops", required_argument, NULL, O_SETOPS },
        { "partition", no_argument, NULL, O_PART },
        { "no-partition", no_argument, NULL, O_NOPART },
        { "seed", required_argument, NULL, O_SEED },
        { "generations", required_argument, NULL, O_GEN },
        { "stagnation", required_argument, NULL, O_STAG },
        { "population", required_argument, NULL, O_POP },
        { "tournament", required_argument, NULL, O_TOURN },
        { "crossover", required_argument, NULL, O_CROSS },
        { "mutation", required_argument, NULL, O_MUT },
        { "elite", required_argument, NULL, O_ELITE },
        { "subtree-prob", required_argument, NULL, O_SUBP },
        { "max-depth", required_argument, NULL, O_DEPTH },
        { "max-time", required_argument, NULL, O_TIME },
        { "epsilon", required_argument, NULL, O_EPS },
        { "alpha", required_argument, NULL, O_ALPHA },
        { "lambda-scale", required_argument, NULL, O_LAMBDA },
        { "sample", required_argument, NULL, O_SAMPLE },
        { "no-simplify", no_argument, NULL, O_NOSIMP },
        { "dot", required_argument, NULL, O_DOT },
        { "trace", required_argument, NULL, O_TRACE },
        { "stop-share", required_argument, NULL, O_STOPSHARE },
        { "residual", required_argument, NULL, O_RESIDUAL },
        { "refit", no_argument, NULL, O_REFIT },
        { "no-polish", no_argument, NULL, O_NOPOLISH },
        { "no-support", no_argument, NULL, O_NOSUPPORT },
        { "polish-stagnation", required_argument, NULL, O_POLSTAG },
        { "threads", required_argument, NULL, 't' },
        { "quiet", no_argument, NULL, 'q' },
        { NULL, 0, NULL, 0 },
    };
    evolve_options eo;
    evolve_options_init(&eo);
    const char *prims_path = NULL, *out = "-", *dot = NULL, *residual_path = NULL;
    const char *trace_path = NULL;
    double stop_share = 0;
    int have_seed = 0, have_setops = 0, refit = 0, quiet = 0, c;
    double v = 0;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "hp:o:t:q", longopts, NULL)) != -1) {
        int bad = 0;
        switch (c) {
        case 'h': fputs(evolve_usage, stdout); return CLI_OK;
        case 'p': prims_path = optarg; break;
        case 'o': out = optarg; break;
        case 'q': quiet = 1; break;
        case O_SETOPS:
            if (strcmp(optarg, "minmax") == 0) eo.gp.setops = GP_SETOPS_MINMAX;
            else if (strcmp(optarg, "rfunc") == 0) eo.gp.setops = GP_SETOPS_RFUNC;
            else return cli_usage_error("evolve", "--setops: expected minmax or rfunc, got '%s'", optarg);
            have_setops = 1;
            break;
        case O_RESIDUAL: residual_path = optarg; break;
        case O_REFIT: refit = 1; break;
        case O_NOPOLISH: eo.polish = 0; break;
        case O_NOSUPPORT: eo.support = 0; break;
        case O_PART: eo.partition = 1; break;
        case O_NOPART: eo.partition = 0; break;
        case O_NOSIMP: eo.simplify = 0; break;
        case O_DOT: dot = optarg; break;
        case O_TRACE: trace_path = optarg; break;
        case O_STOPSHARE: bad = parse_num("--stop-share", optarg, 0, 100, 0, &v); stop_share = v; break;
        case O_SEED: {
            char *end;
            errno = 0;
            eo.gp.seed = strtoull(optarg, &end, 10);
            if (*end || errno || optarg[0] == '-' || !*optarg)
                return cli_usage_error("evolve", "--seed: expected a non-negative integer, got '%s'", optarg);
            have_seed = 1;
            break;
        }
        case O_GEN: bad = parse_num("--generations", optarg, 1, 1e9, 1, &v); eo.gp.generations = (uint32_t)v; break;
        case O_STAG: bad = parse_num("--stagnation", optarg, 0, 1e9, 1, &v); eo.gp.stagnation = (uint32_t)v; break;
        case O_POLSTAG:
            bad = parse_num("--polish-stagnation", optarg, 1, 1e9, 1, &v);
            eo.polish_stagnation = (uint32_t)v;
            break;
        case O_POP: bad = parse_num("--population", optarg, 1, 1e6, 1, &v); eo.gp.population = (uint32_t)v; break;
        case O_TOURN: bad = parse_num("--tournament", optarg, 1, 1e6, 1, &v); eo.gp.tournament = (uint32_t)v; break;
        case O_CROSS: bad = parse_num("--crossover", optarg, 0, 1, 0, &v); eo.gp.p_crossover = v; break;
        case O_MUT: bad = parse_num("--mutation", optarg, 0, 1, 0, &v); eo.gp.p_mutation = v; break;
        case O_ELITE: bad = parse_num("--elite", optarg, 0, 1e6, 1, &v); eo.gp.elite = (uint32_t)v; break;
        case O_SUBP: bad = parse_num("--subtree-prob", optarg, 0, 1, 0, &v); eo.gp.p_subtree = v; break;
        case O_DEPTH: bad = parse_num("--max-depth", optarg, 1, GP_MAX_TREE_DEPTH, 1, &v); eo.gp.max_depth = (int)v; break;
        case O_TIME: bad = parse_num("--max-time", optarg, 0, 1e9, 0, &v); eo.gp.max_time = v; break;
        case O_EPS: bad = parse_num("--epsilon", optarg, 1e-9, 1, 0, &v); eo.eps_rel = v; break;
        case O_ALPHA:
            bad = parse_num("--alpha", optarg, 0.01, 180, 0, &v);
            eo.alpha_deg = v;
            eo.alpha_auto = 0;
            break;
        case O_LAMBDA: bad = parse_num("--lambda-scale", optarg, 0, 1e6, 0, &v); eo.lambda_scale = v; break;
        case O_SAMPLE: bad = parse_num("--sample", optarg, 0, 1e12, 1, &v); eo.sample = (size_t)v; break;
        case 't': bad = parse_num("--threads", optarg, 1, 4096, 1, &v); eo.gp.threads = (int)v; break;
        default:
            return cli_usage_error("evolve", "unknown or incomplete option '%s'", argv[optind - 1]);
        }
        if (bad) return CLI_USAGE;
    }
    if (optind != argc - 1)
        return cli_usage_error("evolve", optind >= argc ? "missing CLOUD" : "one CLOUD expected");
    const char *cloud_path = argv[optind];
    if (eo.gp.p_crossover + eo.gp.p_mutation > 1)
        return cli_usage_error("evolve", "--crossover + --mutation must not exceed 1");
    if (!have_seed) eo.gp.seed = (uint64_t)time(NULL);
    if (eo.lambda_scale == 0) eo.lambda_scale = 1e-12;  /* 0 asks for no penalty */
#ifdef _OPENMP
    /* -t also bounds the parallel loops that take no thread count (the primitive
     * caches' tables), so that -t 1 runs on one core. */
    if (eo.gp.threads > 0) omp_set_num_threads(eo.gp.threads);
#endif

    int rc = CLI_FAIL;
    char *err = NULL;
    frep_error fe;
    frep_error_init(&fe);
    prim *prims = NULL;
    size_t nprims = 0;
    evolve_result res;
    memset(&res, 0, sizeof res);
    segment_result seg;
    memset(&seg, 0, sizeof seg);
    int have_seg = 0;
    evolve_base base;
    memset(&base, 0, sizeof base);
    frep_program *base_prog = NULL;
    char *base_src = NULL;
    double *base_f = NULL, *base_g = NULL;
    uint8_t *mask = NULL, *base_ok = NULL;
    frep_cloud *sub = NULL;
    char note[256] = "";
    trace_buf trace = { NULL, 0, 0, 0 };
    frep_cloud *cloud = cloud_read(cloud_path, &err);
    if (!cloud) {
        fprintf(stderr, "frep evolve: %s\n", err ? err : "cannot read the cloud");
        goto done;
    }
    if (!quiet) fprintf(stderr, "frep evolve: %zu points, seed %llu\n", cloud->n,
                        (unsigned long long)eo.gp.seed);
    if (cloud->n == 0) {
        fprintf(stderr, "frep evolve: %s: no points\n", cloud_path);
        goto done;
    }
    /* Normals are needed before the GA, and before the residual is known. */
    if ((prims_path || residual_path) &&
        (!cloud->has_normals || cloud_normalize_normals(cloud) == cloud->n)) {
        if (!quiet) fprintf(stderr, "frep evolve: the cloud has no normals: estimating them\n");
        if (normals_estimate(cloud, 0, eo.gp.threads)) {
            fprintf(stderr, "frep evolve: cannot estimate normals\n");
            goto done;
        }
    }
    if (residual_path) {
        base_prog = cli_compile_file(residual_path, NULL, NULL, 0, -1, &base_src);
        if (!base_prog) goto done;
        if (residual_prepare(residual_path, base_src, strlen(base_src), NULL, base_prog, &base,
                             &fe)) {
            fprintf(stderr, "frep evolve: %s\n", fe.msg[0] ? fe.msg : "cannot use the model");
            goto done;
        }
        if (have_setops && eo.gp.setops != base.setops) {
            fprintf(stderr, "frep evolve: --setops %s disagrees with %s, which uses %s: the "
                            "joined model has one family\n",
                    eo.gp.setops == GP_SETOPS_RFUNC ? "rfunc" : "minmax", residual_path,
                    base.setops == GP_SETOPS_RFUNC ? "rfunc" : "minmax");
            goto done;
        }
        eo.gp.setops = base.setops;
        size_t N = cloud->n, nbad = 0, nres = 0;
        base_f = malloc(N * sizeof *base_f);
        base_g = malloc(3 * N * sizeof *base_g);
        mask = malloc(N);
        base_ok = malloc(N);
        if (!base_f || !base_g || !mask || !base_ok ||
            residual_eval(&base, cloud, eo.gp.threads, base_f, base_g, base_ok, &nbad)) {
            fprintf(stderr, "frep evolve: out of memory\n");
            goto done;
        }
        if (nbad && !quiet)
            fprintf(stderr, "frep evolve: %s cannot be evaluated at %zu points (treated as "
                            "unexplained)\n", residual_path, nbad);
        eo.base_f = base_f;
        eo.base_g = base_g;
        eo.base_ok = base_ok;
        if (evolve_residual_points(&eo, cloud, mask, &nres)) {
            fprintf(stderr, "frep evolve: out of memory\n");
            goto done;
        }
        if (!quiet)
            fprintf(stderr, "frep evolve: %s explains %zu of %zu points; evolving for the %zu others\n",
                    residual_path, cloud->n - nres, cloud->n, nres);
        if (!prims_path) {
            /* Segment the residual points only. */
            sub = cloud_new(1);
            if (!sub || cloud_reserve(sub, nres ? nres : 1)) {
                fprintf(stderr, "frep evolve: out of memory\n");
                goto done;
            }
            for (size_t i = 0; i < N; i++)
                if (mask[i]) {
                    double p[3] = { cloud->x[i], cloud->y[i], cloud->z[i] };
                    double q[3] = { cloud->nx[i], cloud->ny[i], cloud->nz[i] };
                    cloud_push(sub, p, q);
                }
        }
    }
    if (prims_path) {
        if (segment_read_prims(prims_path, &prims, &nprims, &err)) {
            fprintf(stderr, "frep evolve: %s\n", err ? err : "cannot read the primitives");
            goto done;
        }
        if (!cloud->has_normals || cloud_normalize_normals(cloud) == cloud->n) {
            if (!quiet) fprintf(stderr, "frep evolve: the cloud has no normals: estimating them\n");
            if (normals_estimate(cloud, 0, eo.gp.threads)) {
                fprintf(stderr, "frep evolve: cannot estimate normals\n");
                goto done;
            }
        }
    } else if (!residual_path || sub->n > 0) {
        segment_config sc;
        segment_config_init(&sc);
        sc.seed = eo.gp.seed;
        sc.nthreads = eo.gp.threads;
        sc.interrupt = &evolve_interrupted;
        if (segment_run(sub ? sub : cloud, &sc, &seg, &err)) {
            if (!residual_path) {
                fprintf(stderr, "frep evolve: %s: %s\n", cloud_path, err ? err : "segmentation failed");
                goto done;
            }
            /* Too few residual points to segment: the result is the base model. */
            if (!quiet)
                fprintf(stderr, "frep evolve: the residual points give no primitive (%s)\n",
                        err ? err : "segmentation failed");
            free(err);
            err = NULL;
        } else {
            have_seg = 1;
            prims = seg.prims;
            nprims = seg.nprims;
            if (!quiet)
                fprintf(stderr, "frep evolve: segmented%s: %zu primitives (%zu fitted, %zu separating)%s\n",
                        sub ? " the residual" : "", seg.nprims, seg.nfitted,
                        seg.nprims - seg.nfitted, seg.normals_estimated ? ", normals estimated" : "");
        }
    }
    if (nprims == 0 && !residual_path) {
        fprintf(stderr, "frep evolve: no primitives to combine%s\n",
                prims_path ? "" : " (segmentation found none; try frep segment with other settings)");
        goto done;
    }

    progress_ctx pc;
    memset(&pc, 0, sizeof pc);
    pc.tty = isatty(2);
    pc.quiet = quiet;
    pc.last = -1;
    pc.stop_share = stop_share;
    if (stop_share > 0) eo.gp.report_explained = 1;
    if (trace_path) {
        pc.trace = &trace;
        eo.gp.report_explained = 1;
        trace_add(&trace, "# frep evolve trace, seed %llu\n", (unsigned long long)eo.gp.seed);
        trace_add(&trace, "# columns: generation, wall and CPU (process) seconds since the "
                          "start of the run, best fitness, tree size,\n");
        trace_add(&trace, "# %% of the scored points the best tree explains, phase (ga: the "
                          "GA; merge: merging clique trees;\n");
        trace_add(&trace, "# merged: the merged tree; grown: after the growth steps; polish: "
                          "the GA seeded with it)\n");
    }
    pc.t0 = gp_now();
    pc.c0 = clock();
    void (*old)(int) = signal(SIGINT, on_sigint);
    int r = evolve_run(&eo, cloud, prims, nprims, progress, &pc, &res, &fe);
    signal(SIGINT, old == SIG_ERR ? SIG_DFL : old);
    if (pc.tty && !quiet) fputc('\n', stderr);
    if (r) {
        fprintf(stderr, "frep evolve: %s: %s\n", cloud_path, fe.msg[0] ? fe.msg : "failed");
        goto done;
    }
    if (evolve_interrupted && !quiet)
        fprintf(stderr, "frep evolve: interrupted: writing the best tree so far\n");
    if (res.alpha_auto && !quiet)
        fprintf(stderr, "frep evolve: alpha %g degrees (automatic: %s; position spread %.3g eps, "
                        "normal deviation median %.2g, 90th percentile %.2g degrees over %zu "
                        "inliers; --alpha overrides)\n",
                res.alpha * 180 / 3.14159265358979323846,
                res.alpha * 180 / 3.14159265358979323846 > EVOLVE_DEFAULT_ALPHA_DEG ? "noisy or faceted"
                                                                                  : "clean",
                res.noise.sigma_d, res.noise.median_deg, res.noise.p90_deg, res.noise.inliers);
    if (refit && !evolve_interrupted) {
        evolve_refit_info ri;
        if (evolve_refit(&eo, cloud, prims, nprims, residual_path ? &base : NULL, &res, &ri,
                         &fe)) {
            fprintf(stderr, "frep evolve: --refit: %s (the model keeps the parameters as "
                            "segmented)\n", fe.msg[0] ? fe.msg : "failed");
        } else if (ri.nparams) {
            snprintf(note, sizeof note,
                     "refit: %zu parameters, RMS distance %.6g -> %.6g, max %.6g -> %.6g, %.2f s",
                     ri.nparams, ri.rms_before, ri.rms_after, ri.max_before, ri.max_after,
                     ri.seconds);
            if (!quiet) fprintf(stderr, "frep evolve: %s\n", note);
        }
    }
    evolve_meta meta = { cmdline, cloud_path, eo.gp.seed, eo.gp.setops,
                         residual_path ? &base : NULL, note[0] ? note : NULL };
    write_ctx w = { &res, prims, nprims, &meta };
    if (cli_write_atomic(out, write_model_cb, &w)) goto done;
    if (dot && cli_write_atomic(dot, write_dot_cb, &w)) goto done;
    if (trace_path) {
        double pe = res.npoints ? 100.0 * (double)res.stats.explained / (double)res.npoints : 0;
        trace_add(&trace, "# end: %.4f s wall, %.4f s CPU, %u nodes, %.3f%% of %zu points "
                          "explained (every point, after simplification)%s\n",
                  gp_now() - pc.t0, (double)(clock() - pc.c0) / CLOCKS_PER_SEC, res.tree.len, pe,
                  res.npoints, trace.failed ? "; out of memory: lines missing" : "");
        if (cli_write_atomic(trace_path, write_trace_cb, &trace)) goto done;
    }
    if (!quiet) {
        double pe = res.npoints ? 100.0 * (double)res.stats.explained / (double)res.npoints : 0;
        fprintf(stderr,
                "frep evolve: seed %llu: tree of %u nodes, %.2f%% of %zu points explained "
                "(%.2f%% within epsilon, %.2f%% normals), %s, %u generations, %.2f s\n",
                (unsigned long long)eo.gp.seed, res.tree.len, pe, res.npoints,
                res.npoints ? 100.0 * (double)res.stats.within_eps / (double)res.npoints : 0,
                res.npoints ? 100.0 * (double)res.stats.normals_ok / (double)res.npoints : 0,
                res.partitioned ? "partitioned" : "not partitioned", res.generations, res.seconds);
        if (res.dropped)
            fprintf(stderr, "frep evolve: %zu points without finite coordinates or normal ignored\n",
                    res.dropped);
    }
    rc = CLI_OK;
done:
    free(trace.s);
    if (have_seg) segment_result_free(&seg);
    else free(prims);
    evolve_result_free(&res);
    residual_free(&base);
    frep_program_free(base_prog);
    free(base_src);
    free(base_f);
    free(base_g);
    free(mask);
    free(base_ok);
    cloud_free(sub);
    cloud_free(cloud);
    free(err);
    return rc;
}

int cmd_evolve(int argc, char **argv)
{
    /* getopt_long permutes argv: keep the command line as typed for the model. */
    char *cmdline = join_args(argc, argv);
    int rc = evolve_main(argc, argv, cmdline);
    free(cmdline);
    return rc;
}

/* cmd_evolve.c - frep evolve: from a point cloud (and optionally its primitives) to a
 * readable .hf construction-tree model, through the public API (frep_evolve(),
 * api/api_evolve.c, which segments the cloud first when no primitive list is given):
 * this file reads the options and the files, prints the progress, the notes and the
 * summary, collects --trace's lines, and maps Ctrl-C and --max-time to the run's
 * cancel flag.
 */
#include "config.h"

#include "cli.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
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

/* Seconds between progress lines on a terminal. */
#define EVOLVE_PROGRESS_INTERVAL 0.2
/* The share of --max-time kept for the writer (rounding the numbers and forming
 * solids, whose checks evaluate the tree at the check points: 0.03-0.4 s on 20,000-
 * 200,000 points), at most EVOLVE_WRITE_RESERVE_MAX seconds: the run stops that much
 * before the deadline, and the writer's checks stop at the deadline itself. */
#define EVOLVE_WRITE_RESERVE_SHARE 0.05
#define EVOLVE_WRITE_RESERVE_MAX 5.0

/* Text in memory (a model, a drawing, the trace), for cli_write_atomic. */
typedef struct text_out {
    const char *text;
    size_t len;
} text_out;

static int write_text(FILE *f, void *user)
{
    const text_out *t = user;
    return fwrite(t->text, 1, t->len, f) == t->len ? 0 : -1;
}

/* --trace's lines, kept until the files are written. */
typedef struct trace_buf {
    char *s;
    size_t len, cap;
    int failed;              /* out of memory: lines are missing */
} trace_buf;

static void trace_append(trace_buf *t, const char *line)
{
    size_t n = strlen(line);
    if (t->failed) return;
    if (t->len + n + 1 > t->cap) {
        size_t cap = 2 * t->cap + n + 4096;
        char *s = realloc(t->s, cap);
        if (!s) {
            t->failed = 1;
            return;
        }
        t->s = s;
        t->cap = cap;
    }
    memcpy(t->s + t->len, line, n + 1);
    t->len += n;
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
    frep_evolve_options o;
    const char *prims_path, *out, *dot, *residual_path, *trace_path, *view;
    int refit, quiet, have_setops, exact, hyperfun;
    const char *cloud_path, *cmdline;
    frep_cloud *cloud;
    frep_segmentation *prims;   /* -p's (NULL: segmented by frep_evolve) */
    frep_program *base_prog;    /* --residual's model, */
    char *base_src;             /* its text */
    frep_evolve_base *base;
    frep_evolution *ev;
    frep_evolve_info info;
    trace_buf trace;
    char *model;                /* the model's text */
    size_t model_len;
    char error[1024];           /* frep_evolve's error, printed by stage_evolve */
    /* progress: on a terminal, the last line's time; a line is open (no newline yet) */
    int tty, line_open;
    double last;
    int phase, segmented;       /* the last step started; segmentation was one */
    size_t knn;                 /* --knn: neighbours for normals; 0: from the data */
    double max_time, t_start;   /* --max-time (0: none) and when the command started */
    const char *cut;            /* the step --max-time cut short; NULL: none */
} evolve_cmd;

static int parse_setops(const char *arg, void *dest, char *why, size_t whylen)
{
    (void)why, (void)whylen;
    frep_setops *s = dest;
    if (strcmp(arg, "minmax") == 0) *s = FREP_SETOPS_MINMAX;
    else if (strcmp(arg, "rfunc") == 0) *s = FREP_SETOPS_RFUNC;
    else return -1;
    return 0;
}

#define OFF(f) offsetof(evolve_cmd, f)
static const cli_opt evolve_opts[] = {
    { 'p', "prims", "FILE", CLI_OPT_STRING, OFF(prims_path),
      .help = "primitives: a .hf list written by frep segment, or a .fit list" },
    { 'o', "output", "FILE", CLI_OPT_STRING, OFF(out), .def = "-",
      .help = "model to write (default: standard output)" },
    { 0, "setops", "S", CLI_OPT_CUSTOM, OFF(o.setops), .parse = parse_setops,
      .expect = "minmax or rfunc", .help = "minmax (default) or rfunc" },
    { 0, "partition", NULL, CLI_OPT_SET, OFF(o.partition),
      .help = "partition the overlap graph (default)" },
    { 0, "no-partition", NULL, CLI_OPT_CLEAR, OFF(o.partition),
      .help = "one GA over all primitives" },
    { 0, "no-polish", NULL, CLI_OPT_CLEAR, OFF(o.polish),
      .help = "after partitioning, skip the GA over all primitives seeded\n"
              "with the merged tree" },
    { 0, "polish-stagnation", "G", CLI_OPT_U32, OFF(o.polish_stagnation), .lo = 1, .hi = 1e9,
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
    { 0, "no-support", NULL, CLI_OPT_CLEAR, OFF(o.support),
      .help = "keep material no point supports (by default the final\n"
              "tree is trimmed where its surface runs far from the cloud)" },
    CLI_OPT_SEED(evolve_cmd, o.seed, "random seed (default: from the clock; always printed)"),
    { 0, "generations", "G", CLI_OPT_U32, OFF(o.generations), .lo = 1, .hi = 1e9,
      .help = "generation limit (default 3000)" },
    { 0, "stagnation", "G", CLI_OPT_U32, OFF(o.stagnation), .lo = 0, .hi = 1e9,
      .help = "stop after G generations without improvement (default 40)" },
    { 0, "population", "P", CLI_OPT_U32, OFF(o.population), .lo = 1, .hi = 1e6,
      .help = "individuals (default 150)" },
    { 0, "tournament", "K", CLI_OPT_U32, OFF(o.tournament), .lo = 1, .hi = 1e6,
      .help = "tournament size (default 4)" },
    { 0, "crossover", "R", CLI_OPT_DOUBLE, OFF(o.crossover), .lo = 0, .hi = 1,
      .help = "crossover rate (default 0.3)" },
    { 0, "mutation", "R", CLI_OPT_DOUBLE, OFF(o.mutation), .lo = 0, .hi = 1,
      .help = "mutation rate (default 0.3)" },
    { 0, "elite", "E", CLI_OPT_U32, OFF(o.elite), .lo = 0, .hi = 1e6,
      .help = "best individuals kept each generation (default 2)" },
    { 0, "subtree-prob", "R", CLI_OPT_DOUBLE, OFF(o.subtree_prob), .lo = 0, .hi = 1,
      .help = "probability of an operation node when growing (default 0.7)" },
    { 0, "max-depth", "D", CLI_OPT_INT, OFF(o.max_depth), .lo = 1, .hi = FREP_EVOLVE_MAX_DEPTH,
      .help = "maximum tree depth (default: ceil(log2 primitives) + 3)" },
    { 0, "max-time", "T", CLI_OPT_DOUBLE, OFF(max_time), .lo = 0, .hi = 1e9,
      .help = "stop after T seconds of wall time in all (normals,\n"
              "segmentation, GA) and write the best tree so far" },
    CLI_OPT_KNN(evolve_cmd, knn),
    { 0, "epsilon", "E", CLI_OPT_DOUBLE, OFF(o.epsilon), .lo = 1e-9, .hi = 1,
      .help = "distance tolerance as a fraction of the diagonal (default 0.01)" },
    { 0, "alpha", "DEG", CLI_OPT_DOUBLE, OFF(o.alpha_deg), .lo = 0.01, .hi = 180,
      .help = "normal tolerance in degrees (default: automatic, 35 when the\n"
              "cloud is noisy or faceted against the primitives, else 10)" },
    { 0, "lambda-scale", "K", CLI_OPT_DOUBLE, OFF(o.lambda_scale), .lo = 0, .hi = 1e6,
      .help = "size penalty K*ln(N) per node (default 1)" },
    { 0, "sample", "N", CLI_OPT_SIZE, OFF(o.sample), .lo = 0, .hi = 1e12,
      .help = "points the GA scores (default 4096; 0: all); the final growth\n"
              "scores four times as many" },
    { 0, "no-simplify", NULL, CLI_OPT_CLEAR, OFF(o.simplify), .help = "keep the tree as evolved" },
    { 0, "dot", "FILE", CLI_OPT_STRING, OFF(dot), .help = "also write the tree for Graphviz" },
    { 0, "view", "HTML", CLI_OPT_STRING, OFF(view),
      .help = "also write the page of the model and the cloud (frep view)" },
    { 0, "trace", "FILE", CLI_OPT_STRING, OFF(trace_path),
      .help = "write one line per generation: generation, wall and CPU\n"
              "seconds since the start, best fitness, tree size, % of the\n"
              "scored points the best tree explains, phase" },
    { 0, "stop-share", "P", CLI_OPT_DOUBLE, OFF(o.stop_share), .lo = 0, .hi = 100,
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
    CLI_OPT_THREADS(evolve_cmd, o.nthreads, "OpenMP threads"),
    CLI_OPT_QUIET(evolve_cmd, quiet, "no progress and no summary"),
};
#undef OFF
static const cli_opt_spec evolve_spec = { "evolve", evolve_usage, evolve_opts,
                                          sizeof evolve_opts / sizeof evolve_opts[0], 24 };

static const char *setops_name(frep_setops s)
{
    return s == FREP_SETOPS_RFUNC ? "rfunc" : "minmax";
}

/* Options -> one CLOUD; the settings the options imply (seed from the clock, automatic
 * alpha unless --alpha, the OpenMP default from -t). */
static int stage_options(evolve_cmd *e, int argc, char **argv)
{
    cli_args args;
    int rc = cli_opt_parse(&evolve_spec, argc, argv, e, &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error("evolve", args.n < 1 ? "missing CLOUD" : "one CLOUD expected");
    e->cloud_path = args.v[0];
    e->t_start = cli_now_seconds();
    if (e->max_time > 0 && cli_deadline_arm(e->max_time))
        return cli_usage_error("evolve", "--max-time: cannot set a timer");
    frep_evolve_options *o = &e->o;
    if (o->crossover + o->mutation > 1)
        return cli_usage_error("evolve", "--crossover + --mutation must not exceed 1");
    e->have_setops = cli_opt_given(&evolve_spec, &args, "setops");
    if (!cli_opt_given(&evolve_spec, &args, "alpha")) o->alpha_deg = 0;  /* automatic */
    if (!cli_opt_given(&evolve_spec, &args, "seed")) o->seed = (uint64_t)time(NULL);
    o->knn = e->knn;
    o->refit = e->refit;
    cli_default_threads(o->nthreads);
    return CLI_GO_ON;
}

/* End a progress line on the terminal before another message. */
static void end_line(evolve_cmd *e)
{
    if (!e->line_open) return;
    fputc('\n', stderr);
    e->line_open = 0;
}

/* Messages of the library calls outside the run: "frep evolve: MESSAGE". */
static void print_diag(void *user, const frep_diag *d)
{
    (void)user;
    fprintf(stderr, "frep evolve: %s\n", d->message);
}

/* The run's messages: notes unless -q, warnings; the error kept for stage_evolve. */
static void run_diag(void *user, const frep_diag *d)
{
    evolve_cmd *e = user;
    if (d->severity == FREP_ERROR) {
        snprintf(e->error, sizeof e->error, "%s", d->message);
        return;
    }
    if (d->severity == FREP_NOTE && e->quiet) return;
    end_line(e);
    fprintf(stderr, "frep evolve: %s\n", d->message);
}

/* The cloud read and checked. */
static int stage_cloud(evolve_cmd *e)
{
    e->cloud = frep_cloud_read(e->cloud_path, print_diag, e);
    if (!e->cloud) return CLI_FAIL;
    size_t n = frep_cloud_size(e->cloud);
    if (!e->quiet) fprintf(stderr, "frep evolve: %zu points, seed %llu\n", n,
                           (unsigned long long)e->o.seed);
    if (n == 0) {
        fprintf(stderr, "frep evolve: %s: no points\n", e->cloud_path);
        return CLI_FAIL;
    }
    return cli_check_cloud("evolve", e->cloud_path, e->cloud, 1);
}

/* --residual: the model compiled and prepared; the tree takes its set operations. */
static int stage_base(evolve_cmd *e)
{
    e->base_prog = cli_compile_file(e->residual_path, NULL, NULL, 0, -1, 0, &e->base_src);
    if (!e->base_prog) return CLI_FAIL;
    e->base = frep_evolve_base_new(e->base_prog, e->residual_path, e->base_src,
                                   strlen(e->base_src), NULL, print_diag, e);
    if (!e->base) return CLI_FAIL;
    frep_setops s = frep_evolve_base_setops(e->base);
    if (e->have_setops && e->o.setops != s) {
        fprintf(stderr, "frep evolve: --setops %s disagrees with %s, which uses %s: the "
                        "joined model has one family\n",
                setops_name(e->o.setops), e->residual_path, setops_name(s));
        return CLI_FAIL;
    }
    e->o.base = e->base;
    return CLI_OK;
}

/* --trace: the run's lines kept. */
static void trace_cb(void *user, const char *line)
{
    evolve_cmd *e = user;
    trace_append(&e->trace, line);
}

/* One line of progress on a terminal; the step that --max-time cut short. */
static void progress(void *user, const frep_evolve_progress *p)
{
    evolve_cmd *e = user;
    if (p->phase >= FREP_EVOLVE_NORMALS) {
        if (p->phase == FREP_EVOLVE_SEGMENT) e->segmented = 1;
        if (p->phase == FREP_EVOLVE_SEARCH && e->segmented && cli_deadline_passed())
            e->cut = "segmentation";
        e->phase = p->phase;
        if (p->phase != FREP_EVOLVE_REFIT || !e->tty || e->quiet) return;
        fputs("\rfrep evolve: refitting the primitives   ", stderr);
        fflush(stderr);
        e->line_open = 1;
        return;
    }
    if (!e->tty || e->quiet) return;
    if (p->phase == FREP_EVOLVE_CLIQUES || p->phase == FREP_EVOLVE_SIMPLIFY) {
        fprintf(stderr, "\rfrep evolve: %s, %.1f s   ",
                p->phase == FREP_EVOLVE_CLIQUES ? "evolving a tree per clique"
                                                : "simplifying the tree", p->elapsed);
    } else if (p->elapsed - e->last >= EVOLVE_PROGRESS_INTERVAL || p->generation == 1) {
        e->last = p->elapsed;
        if (p->phase == FREP_EVOLVE_MERGE || p->phase == FREP_EVOLVE_MERGED)
            fprintf(stderr, "\rfrep evolve: merging clique trees: tree size %u, %.1f s   ",
                    p->tree_size, p->elapsed);
        else if (p->phase == FREP_EVOLVE_GROWN)
            fprintf(stderr, "\rfrep evolve: merged tree grown: tree size %u, %.1f s   ",
                    p->tree_size, p->elapsed);
        else
            fprintf(stderr, "\rfrep evolve: generation %u, best fitness %.6g, tree size %u, %.1f s   ",
                    p->generation, p->best_fitness, p->tree_size, p->elapsed);
    } else {
        return;
    }
    fflush(stderr);
    e->line_open = 1;
}

/* Why the run gave no model: --max-time, Ctrl-C (said by the caller) or an error. */
static void report_failure(const evolve_cmd *e)
{
    if (cli_deadline_passed() && e->phase == FREP_EVOLVE_NORMALS)
        fprintf(stderr, "frep evolve: --max-time %g s reached while estimating normals: "
                        "no model, nothing written\n", e->max_time);
    else if (cli_deadline_passed() && e->phase == FREP_EVOLVE_SEGMENT)
        fprintf(stderr, "frep evolve: --max-time %g s reached during segmentation before any "
                        "primitive was found: nothing written\n", e->max_time);
    else if (!cli_interrupted())
        fprintf(stderr, "frep evolve: %s: %s\n", e->cloud_path, e->error[0] ? e->error : "failed");
}

/* The automatic alpha and the noise estimate behind it. */
static void report_alpha(const frep_evolve_info *in)
{
    fprintf(stderr, "frep evolve: alpha %g degrees (automatic: %s; position spread %.3g eps, "
                    "normal deviation median %.2g, 90th percentile %.2g degrees over %zu "
                    "inliers; --alpha overrides)\n",
            in->alpha_deg, in->noisy ? "noisy or faceted" : "clean", in->noise_spread,
            in->noise_median_deg, in->noise_p90_deg, in->noise_inliers);
}

/* frep_evolve with progress, --trace and --stop-share; Ctrl-C and --max-time raise
 * the run's cancel flag, which keeps the best tree so far. */
static int stage_evolve(evolve_cmd *e)
{
    frep_evolve_options *o = &e->o;
    e->tty = isatty(2);
    e->last = -1;
    e->phase = -1;
    o->progress = progress;
    o->user = e;
    if (e->trace_path) o->trace = trace_cb;
    /* --max-time bounds the whole command: the run gets what is left. */
    double run_time = e->max_time -
                      fmin(EVOLVE_WRITE_RESERVE_SHARE * e->max_time, EVOLVE_WRITE_RESERVE_MAX);
    if (e->max_time > 0) o->max_time = fmax(run_time - (cli_now_seconds() - e->t_start), 1e-3);
    o->cancel_flag = cli_sigint_catch();
    e->ev = frep_evolve(e->cloud, e->prims, o, run_diag, e);
    cli_sigint_restore();
    end_line(e);
    if (!e->ev) {
        report_failure(e);
        return CLI_FAIL;
    }
    frep_evolution_get_info(e->ev, &e->info);
    if (!e->cut && (cli_deadline_passed() ||
                    (e->max_time > 0 && cli_now_seconds() - e->t_start >= run_time)))
        e->cut = "the GA";
    if (e->info.alpha_auto && !e->quiet) report_alpha(&e->info);
    return CLI_OK;
}

static double percent(size_t k, size_t n)
{
    return n ? 100.0 * (double)k / (double)n : 0;
}

/* The model, --dot, --view and --trace, each atomically. */
static int stage_write(evolve_cmd *e)
{
    /* After Ctrl-C the tree is the one so far (the clique trees united as they stand,
     * thousands of nodes): its numbers are written exact, without the rounding and box
     * cover whose checks evaluate the tree at every check point (seconds on such a
     * tree), so that the command ends within the promised second.  A Ctrl-C during
     * those checks (the run's cancel flag, which the writer polls) ends them: the
     * numbers not yet checked stay as fitted, the solids not yet formed stay.  The
     * --max-time deadline ends them the same way (the run left them
     * EVOLVE_WRITE_RESERVE_SHARE of the time). */
    int exact = e->exact || cli_interrupted();
    if (!exact && e->tty && !e->quiet) {
        fputs("\rfrep evolve: rounding the numbers and forming solids   ", stderr);
        fflush(stderr);
        e->line_open = 1;
    }
    frep_evolution_set_cancel(e->ev, cli_sigint_catch());
    e->model = frep_evolution_model(e->ev, e->cmdline, e->cloud_path, exact, e->hyperfun,
                                    &e->model_len, print_diag, e);
    end_line(e);
    if (!e->model) return CLI_FAIL;
    text_out m = { e->model, e->model_len };
    if (cli_write_atomic(e->out, write_text, &m)) return CLI_FAIL;
    if (e->dot) {
        size_t len = 0;
        char *dot = frep_evolution_dot(e->ev, &len, print_diag, e);
        text_out d = { dot, len };
        int rc = dot ? cli_write_atomic(e->dot, write_text, &d) : -1;
        frep_free(dot);
        if (rc) return CLI_FAIL;
    }
    cli_view_job vj = { "evolve", e->view, strcmp(e->out, "-") ? e->out : NULL, NULL,
                        e->cloud_path, write_text, &m, NULL, 0, e->o.nthreads, e->quiet };
    if (e->view && cli_view_result(&vj) != CLI_OK) return CLI_FAIL;
    if (!e->trace_path) return CLI_OK;
    if (e->trace.failed)
        fprintf(stderr, "frep evolve: out of memory: --trace lines missing\n");
    text_out t = { e->trace.s ? e->trace.s : "", e->trace.len };
    return cli_write_atomic(e->trace_path, write_text, &t) ? CLI_FAIL : CLI_OK;
}

/* The summary on stderr. */
static void stage_report(const evolve_cmd *e)
{
    const frep_evolve_info *in = &e->info;
    fprintf(stderr,
            "frep evolve: seed %llu: tree of %u nodes, %.2f%% of %zu points explained "
            "(%.2f%% within epsilon, %.2f%% normals), %s, %u generations, %.2f s\n",
            (unsigned long long)e->o.seed, in->tree_size,
            percent(in->explained, in->npoints), in->npoints,
            percent(in->within_eps, in->npoints), percent(in->normals_ok, in->npoints),
            in->partitioned ? "partitioned" : "not partitioned", in->generations, in->seconds);
    if (in->dropped)
        fprintf(stderr, "frep evolve: %zu points without finite coordinates or normal ignored\n",
                in->dropped);
}

static void evolve_cmd_free(evolve_cmd *e)
{
    free(e->trace.s);
    frep_free(e->model);
    frep_evolution_free(e->ev);
    frep_segmentation_free(e->prims);
    frep_evolve_base_free(e->base);
    frep_program_free(e->base_prog);
    free(e->base_src);
    frep_cloud_free(e->cloud);
}

/* cloud -> [base] -> [primitives] -> run -> files -> summary */
static int evolve_steps(evolve_cmd *e)
{
    int rc = stage_cloud(e);
    if (rc == CLI_OK && e->residual_path) rc = stage_base(e);
    if (rc == CLI_OK && e->prims_path) {
        e->prims = frep_segmentation_read(e->prims_path, print_diag, e);
        if (!e->prims) rc = CLI_FAIL;
    }
    if (rc == CLI_OK) rc = stage_evolve(e);
    if (rc != CLI_OK)
        return cli_interrupted() ? cli_interrupt_status("evolve", "nothing written") : rc;
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
    if (!e) {
        fprintf(stderr, "frep evolve: out of memory\n");
        return CLI_FAIL;
    }
    frep_evolve_options_init(&e->o);
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

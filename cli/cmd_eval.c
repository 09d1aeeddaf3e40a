/* cmd_eval.c - frep eval: evaluate a compiled model at given points, or on a regular
 * grid with a summary (inside fraction, volume estimate, value range, throughput).
 */
#include "config.h"

#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static const char eval_usage[] =
    "usage: frep eval FILE.hf [--model NAME] [-a v1,v2,...] [--grad] [POINTS]\n"
    "       frep eval FILE.hf --grid N [-b BOX] [--no-prune] [--single] [--model NAME]\n"
    "                 [-a v1,...]\n\n"
    "Evaluate a model. Without --model: my_model if the file has one, else its first model.\n\n"
    "Point mode reads points from POINTS (or standard input), one a line: the first\n"
    "three numbers of each line (further columns, e.g. normals, are ignored; blank lines\n"
    "and lines starting with # are skipped). It prints one line per point: the value,\n"
    "or with --grad 'f fx fy fz', in %.17g (nan/inf for non-finite values).\n\n"
    "Grid mode evaluates on an N x N x N grid of the box, x_i = lo + (hi-lo) i/(N-1),\n"
    "and prints the count and fraction of points inside (f >= 0), the estimated volume,\n"
    "min/max/sum of the finite values, the NaN count and the throughput. It evaluates\n"
    "16^3-point tiles, each with a program shortened by interval analysis (min/max set\n"
    "operations and selects decided over the tile); the values are exactly the same.\n"
    "With --single (on CPUs with AVX2) the values are computed in single precision\n"
    "wherever an error bound over the tile can be certified, and every block with a\n"
    "value within that bound of 0 again in double: the inside and NaN counts and the\n"
    "errors are double's, min/max/sum within the bound of double's.\n\n";

static void print_num(FILE *f, double v)
{
    if (isnan(v)) fputs("nan", f);
    else if (isinf(v)) fputs(v > 0 ? "inf" : "-inf", f);
    else fprintf(f, "%.17g", v);
}

typedef struct point_buf {
    double *x, *y, *z;
    size_t n, cap;
} point_buf;

static int push_point(point_buf *b, double x, double y, double z)
{
    if (b->n == b->cap) {
        size_t cap = b->cap ? 2 * b->cap : 1024;
        double *nx = realloc(b->x, cap * sizeof *nx);
        if (nx) b->x = nx;
        double *ny = realloc(b->y, cap * sizeof *ny);
        if (ny) b->y = ny;
        double *nz = realloc(b->z, cap * sizeof *nz);
        if (nz) b->z = nz;
        if (!nx || !ny || !nz) return -1;
        b->cap = cap;
    }
    b->x[b->n] = x;
    b->y[b->n] = y;
    b->z[b->n] = z;
    b->n++;
    return 0;
}

/* Read points: the first three numbers of each non-blank, non-# line. */
static int read_points(const char *path, point_buf *b)
{
    size_t len;
    char *text = cli_read_file(path, &len);
    if (!text) return -1;
    const char *name = strcmp(path, "-") == 0 ? "<stdin>" : path;
    char *p = text;
    size_t line = 0;
    int status = 0;
    while (*p && status == 0) {
        line++;
        char *eol = strchr(p, '\n');
        if (eol) *eol = '\0';
        char *s = p;
        while (*s == ' ' || *s == '\t' || *s == '\r') s++;
        if (*s && *s != '#') {
            double v[3];
            int k = 0;
            while (k < 3) {
                char *end;
                errno = 0;
                v[k] = strtod(s, &end);
                if (end == s) break;
                if (*end && *end != ' ' && *end != '\t' && *end != '\r' && *end != ',') {
                    end = s;
                    break;
                }
                k++;
                s = end;
                while (*s == ' ' || *s == '\t' || *s == '\r' || *s == ',') s++;
            }
            if (k < 3) {
                fprintf(stderr, "%s:%zu: expected 3 numbers (x y z), got %d\n", name, line, k);
                status = -1;
            } else if (push_point(b, v[0], v[1], v[2]) != 0) {
                fprintf(stderr, "frep: out of memory reading %s\n", name);
                status = -1;
            }
        }
        p = eol ? eol + 1 : p + strlen(p);
    }
    free(text);
    return status;
}

static void report_errors(const frep_program *p, const frep_runtime_error *e,
                          const char *src, size_t len)
{
    if (e->count == 0) return;
    cli_diag_ctx dc = { src, len, 0, 0, NULL, 0, NULL };
    frep_report_runtime_error(p, e, cli_print_diag, &dc);
    cli_diag_done(&dc);
}

static int eval_points(const frep_program *p, const char *path, int grad, int nthreads,
                       const char *src, size_t srclen)
{
    point_buf b = { 0 };
    int status = CLI_FAIL;
    double *f = NULL, *g = NULL;
    if (read_points(path, &b) != 0) goto done;
    size_t n = b.n;
    f = malloc((n ? n : 1) * sizeof *f);
    g = grad ? malloc((n ? 3 * n : 1) * sizeof *g) : NULL;
    if (!f || (grad && !g)) {
        fprintf(stderr, "frep: out of memory\n");
        goto done;
    }
    frep_runtime_error err;
    int r = grad ? frep_eval_grad_par(p, n, b.x, b.y, b.z, NULL, f, g, g + n, g + 2 * n,
                                      nthreads, &err)
                 : frep_eval_par(p, n, b.x, b.y, b.z, NULL, f, nthreads, &err);
    if (r != 0) {
        fprintf(stderr, "frep: evaluation failed (out of memory?)\n");
        goto done;
    }
    if (frep_program_work_spent(p)) {
        report_errors(p, &err, src, srclen);
        cli_work_check("eval", NULL, p);
        goto done;
    }
    for (size_t i = 0; i < n; i++) {
        print_num(stdout, f[i]);
        if (grad)
            for (int c = 0; c < 3; c++) {
                putchar(' ');
                print_num(stdout, g[(size_t)c * n + i]);
            }
        putchar('\n');
    }
    report_errors(p, &err, src, srclen);
    status = cli_stdout_close() == 0 ? CLI_OK : CLI_FAIL;
done:
    free(b.x);
    free(b.y);
    free(b.z);
    free(f);
    free(g);
    return status;
}

/* The precision line of --single: which blocks ran in float, or why none did. */
static void print_precision(const frep_grid_summary *s)
{
    if (s->precision == FREP_GRID_SINGLE)
        printf("precision single: %llu blocks in float, %llu of them again in double "
               "near the surface\n",
               (unsigned long long)s->single_blocks, (unsigned long long)s->redone_blocks);
    else if (s->precision == FREP_GRID_DOUBLE_NO_OPS)
        printf("precision double (the program has operations the float path lacks)\n");
    else
        printf("precision double (--single needs a CPU with AVX2)\n");
}

/* Grid mode (frep_eval_grid): tile by tile with a pruned program per tile, each block
 * summarized as soon as it is computed (no buffer of values), the partial sums added
 * in tile order, so every figure but the time is the same with or without pruning and
 * at any thread count. */
static int eval_grid(const frep_program *p, const frep_grid_options *o, const char *src,
                     size_t srclen)
{
    frep_grid_summary st;
    double t0 = cli_now_seconds();
    if (frep_eval_grid(p, o, &st, NULL, NULL) != 0) {
        fprintf(stderr, "frep: evaluation failed (out of memory?)\n");
        return CLI_FAIL;
    }
    if (frep_program_work_spent(p)) {
        report_errors(p, &st.errors, src, srclen);
        return cli_work_check("eval", NULL, p);
    }
    double eval_time = cli_now_seconds() - t0;
    uint64_t inside = st.inside, nans = st.nans;
    double vmin = st.min, vmax = st.max, sum = st.sum, insns = st.insns;
    double total_time = cli_now_seconds() - t0;
    long N = o->n;
    int threads = st.threads;
    const double *box = st.box;
    double npts = (double)N * (double)N * (double)N;
    double vol = (box[3] - box[0]) * (box[4] - box[1]) * (box[5] - box[2]);
    printf("grid      %ld^3 = %.0f points over [%g,%g]x[%g,%g]x[%g,%g]\n", N, npts, box[0],
           box[3], box[1], box[4], box[2], box[5]);
    printf("inside    %llu (%.6f of the points, f >= 0)\n", (unsigned long long)inside,
           (double)inside / npts);
    printf("volume    %.6g (estimate: inside fraction x box volume %.6g)\n",
           (double)inside / npts * vol, vol);
    printf("values    min %.9g  max %.9g  sum %.9g\n", vmin, vmax, sum);
    printf("nan       %llu\n", (unsigned long long)nans);
    printf("time      %.3f s evaluating (%.3f s total), %.2f million points/s on %d thread%s\n",
           eval_time, total_time, npts / eval_time * 1e-6, threads, threads == 1 ? "" : "s");
    printf("program   %zu instructions, %.1f evaluated per point on average (%s)\n",
           frep_program_size(p), insns / npts, o->prune ? "interval pruning" : "no pruning");
    if (o->single) print_precision(&st);
    report_errors(p, &st.errors, src, srclen);
    return CLI_OK;
}

typedef struct eval_cmd {
    const char *model, *boxarg;
    cli_list a;
    int grad, setops, nthreads, prune, strict, single;
    long grid;                /* points per axis; 0: point mode */
    size_t max_work;          /* --max-work; 0: the default */
    const char *file, *points;
    double box[6];
    frep_program *p;
    char *src;
} eval_cmd;

#define OFF(f) offsetof(eval_cmd, f)
static const cli_opt eval_opts[] = {
    CLI_OPT_PARAMS(eval_cmd, a, "values of the model's a[] array, comma separated"),
    { 'b', "box", "BOX", CLI_OPT_STRING, OFF(boxarg),
      .help = "HyperFun's -b: 'v' for [-v,v]^3, 'lo,hi', 'a,b,c' for\n"
              "[-a,a]x[-b,b]x[-c,c], or 'x0,y0,z0,x1,y1,z1'; default: the\n"
              "model's '-- @box' annotation, else 10" },
    { 0, "grad", NULL, CLI_OPT_SET, OFF(grad),
      .help = "also print the gradient (forward-mode differentiation)" },
    { 0, "grid", "N", CLI_OPT_LONG, OFF(grid), .lo = FREP_GRID_MIN_N, .hi = FREP_GRID_MAX_N,
      .help = "grid mode with N points per axis (2..4096)" },
    CLI_OPT_MAX_WORK(eval_cmd, max_work),
    CLI_OPT_MODEL(eval_cmd, model, "the model to evaluate"),
    { 0, "no-prune", NULL, CLI_OPT_CLEAR, OFF(prune),
      .help = "grid mode: evaluate every tile with the whole program" },
    { 0, "single", NULL, CLI_OPT_SET, OFF(single),
      .help = "grid mode: single precision where certified (AVX2), the\n"
              "inside count exact" },
    CLI_OPT_SETOPS(eval_cmd, setops, "override the file's set operations: rfunc, minmax"),
    CLI_OPT_STRICT(eval_cmd, strict),
    CLI_OPT_THREADS(eval_cmd, nthreads, "OpenMP threads (default: all cores)"),
};
#undef OFF
static const cli_opt_spec eval_spec = { "eval", eval_usage, eval_opts,
                                        sizeof eval_opts / sizeof eval_opts[0], 22 };

/* Options -> FILE.hf [POINTS]; --grid excludes POINTS and --grad, -b needs --grid. */
static int stage_options(eval_cmd *c, int argc, char **argv)
{
    cli_args args;
    int rc = cli_opt_parse(&eval_spec, argc, argv, c, &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n < 1 || args.n > 2) return cli_usage_error("eval", "expected FILE.hf [POINTS]");
    if (c->grid && (args.n == 2 || c->grad))
        return cli_usage_error("eval", "--grid takes no POINTS file and no --grad");
    if (!c->grid && c->boxarg) return cli_usage_error("eval", "-b is only for --grid");
    if (!c->grid && c->single) return cli_usage_error("eval", "--single is only for --grid");
    char why[256] = "";
    if (c->boxarg && cli_opt_box(c->boxarg, c->box, why, sizeof why) != 0)
        return cli_usage_error("eval", "-b: %s", why);
    c->file = args.v[0];
    c->points = args.n == 2 ? args.v[1] : "-";
    return CLI_GO_ON;
}

/* Compile, then evaluate on the grid or at the points. */
static int eval_run(eval_cmd *c)
{
    c->p = cli_compile_file(c->file, c->model, c->a.v, c->a.n, c->setops, c->strict,
                            &c->src);
    if (!c->p || cli_work_limit(c->p, c->max_work) != CLI_OK) return CLI_FAIL;
    size_t srclen = c->src ? strlen(c->src) : 0;
    if (!c->grid) return eval_points(c->p, c->points, c->grad, c->nthreads, c->src, srclen);
    frep_grid_options o;
    frep_grid_options_init(&o);
    o.n = c->grid;
    o.has_box = c->boxarg != NULL;
    memcpy(o.box, c->box, sizeof o.box);
    o.prune = c->prune;
    o.single = c->single;
    o.nthreads = c->nthreads;
    return eval_grid(c->p, &o, c->src, srclen);
}

int cmd_eval(int argc, char **argv)
{
    eval_cmd c = { .setops = -1, .prune = 1 };
    int rc = stage_options(&c, argc, argv);
    if (rc == CLI_GO_ON) rc = eval_run(&c);
    frep_program_free(c.p);
    free(c.src);
    cli_list_free(&c.a);
    return rc;
}

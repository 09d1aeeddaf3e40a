/* cmd_fit.c - frep fit: recover the free parameters of a template from a point cloud
 * (fit/fit.c: simulated annealing + quasi-Newton) and write the fitted template back
 * with the values in place (fit/writeback.c), atomically and next to the template.
 */
#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "fit.h"
#include "program.h"
#include "writeback.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char fit_usage[] =
    "usage: frep fit TEMPLATE.hf CLOUD [options]\n\n"
    "Fit the free parameters of TEMPLATE.hf to the points of CLOUD (.xyz with or without\n"
    "normals, or PLY) and write the template with the fitted values in place of the old\n"
    "ones (comments and layout kept) to TEMPLATE.fitted.hf. Free parameters are the\n"
    "variables marked '-- @free [lo, hi]'; a template without them fits its a[] array,\n"
    "started from -a and bounded by --bounds. See doc/fit.md.\n\n";

/* Room added around the cloud's bounding box in the `-- @box` line, as a fraction of its
 * diagonal: the surface must not touch the polygonizer's box. */
#define FIT_BOX_MARGIN 0.05
/* Fewest points a fit accepts beyond the number of parameters. */
#define FIT_MIN_POINTS 10

typedef struct param_row {
    const char *name;
    size_t index;               /* in the program's parameter vector */
    double start, value, lo, hi;
    int has_span;
    uint32_t off, end;
    double sigma, sens;         /* standard error, sensitivity (fit_result) */
    int warn;                   /* WARN_* bits */
} param_row;

typedef struct text_out {
    const char *text;
    size_t len;
} text_out;

static int write_text(FILE *f, void *user)
{
    text_out *t = user;
    return fwrite(t->text, 1, t->len, f) == t->len ? 0 : -1;
}

/* One line: phase, chain, iteration, elapsed time and the best objective so far of the
 * objective being minimized (on the annealing's subset or on all points: each never
 * goes up). */
static void progress(void *user, const fit_progress *p)
{
    (void)user;
    static const char *const names[] = {"annealing", "quasi-Newton", "Levenberg-Marquardt"};
    char chain[48] = "";
    if (p->nchains > 0) snprintf(chain, sizeof chain, "chain %ld/%ld", p->chain, p->nchains);
    fprintf(stderr, "\r%-12s %-11s iteration %-5ld %6.1f s  best %-11.5g %s\033[K",
            names[p->phase], chain, p->iteration, p->elapsed, p->best,
            p->subset == 1 ? "(annealing's points)" : p->subset == 2 ? "(robust, all points)"
                                                                  : "(all points)");
    fflush(stderr);
}

/* "dir/part.hf" -> "dir/part.fitted.hf". Returns malloc'ed. */
static char *derived_name(const char *path)
{
    size_t n = strlen(path);
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (dot == NULL || (slash != NULL && dot < slash) || dot == path) dot = path + n;
    char *s = malloc(n + 16);
    if (s == NULL) return NULL;
    size_t stem = (size_t)(dot - path);
    memcpy(s, path, stem);
    sprintf(s + stem, ".fitted%s", *dot ? dot : ".hf");
    return s;
}

static void json_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') fprintf(f, "\\%c", c);
        else if (c < 0x20) fprintf(f, "\\u%04x", c);
        else fputc(c, f);
    }
    fputc('"', f);
}

static void json_num(FILE *f, double v)
{
    if (isfinite(v)) fprintf(f, "%.17g", v);
    else fputs("null", f);
}

/* Warnings about one parameter (bits of param_row.warn). */
enum {
    WARN_ON_BOUND = 1,      /* within FIT_ON_BOUND of its range from a bound */
    WARN_NEAR_BOUND = 2,    /* within FIT_NEAR_BOUND */
    WARN_NO_EFFECT = 4,     /* the surface does not move with it */
    WARN_TINY_EFFECT = 8,   /* it moves the surface by less than FIT_TINY_EFFECT */
    WARN_LOOSE = 16         /* standard error above FIT_LOOSE of its scale */
};
/* A fitted value this close to a bound, as a fraction of the range, is on it; this
 * close, near it. */
#define FIT_ON_BOUND 1e-6
#define FIT_NEAR_BOUND 0.01
/* A parameter whose whole range (or 1 + |value| when unbounded) moves the surface by
 * less than this fraction of the cloud's diagonal (RMS over the points) barely matters. */
#define FIT_TINY_EFFECT 1e-6
/* A standard error above this fraction of the parameter's range (or 1 + |value|) makes
 * it poorly determined by the points. */
#define FIT_LOOSE 0.05
/* Verdict: "good" needs this share of the points within FIT_WITHIN of the diagonal,
 * "poor" below FIT_VERDICT_POOR. */
#define FIT_VERDICT_GOOD 0.99
#define FIT_VERDICT_POOR 0.9
/* More points than this share taken for outliers make the fit poor whatever the rest:
 * the "outliers" are then more likely a part of the shape the model misses. */
#define FIT_VERDICT_OUTLIERS 0.25

typedef struct report_ctx {
    const char *tmpl, *cloud, *output;
    const param_row *rows;
    size_t nrows, npoints;
    const fit_config *cfg;
    const fit_result *res;
    double diagonal;
    int interrupted;
    const char *verdict;
} report_ctx;

static int write_json(FILE *f, void *user)
{
    const report_ctx *r = user;
    fputs("{\n  \"template\": ", f);
    json_str(f, r->tmpl);
    fputs(",\n  \"cloud\": ", f);
    json_str(f, r->cloud);
    fputs(",\n  \"output\": ", f);
    json_str(f, r->output);
    fprintf(f, ",\n  \"points\": %zu,\n  \"method\": \"%s\",\n  \"objective_kind\": \"%s\",\n"
               "  \"global_objective_kind\": \"%s\",\n"
               "  \"loss\": \"%s\",\n  \"seed\": %llu,\n  \"parameters\": [\n",
            r->npoints, fit_method_name(r->cfg->method), fit_objective_name(r->cfg->obj.kind),
            fit_objective_name(r->cfg->global_kind), fit_loss_name(r->cfg->obj.loss), (unsigned long long)r->cfg->seed);
    for (size_t i = 0; i < r->nrows; i++) {
        fputs("    {\"name\": ", f);
        json_str(f, r->rows[i].name);
        fputs(", \"start\": ", f);
        json_num(f, r->rows[i].start);
        fputs(", \"value\": ", f);
        json_num(f, r->rows[i].value);
        fputs(", \"lo\": ", f);
        json_num(f, r->rows[i].lo);
        fputs(", \"hi\": ", f);
        json_num(f, r->rows[i].hi);
        fputs(", \"sigma\": ", f);
        json_num(f, r->rows[i].sigma);
        fputs(", \"sensitivity\": ", f);
        json_num(f, r->rows[i].sens);
        fprintf(f, ", \"on_bound\": %s, \"near_bound\": %s, \"no_effect\": %s}%s\n",
                r->rows[i].warn & WARN_ON_BOUND ? "true" : "false",
                r->rows[i].warn & WARN_NEAR_BOUND ? "true" : "false",
                r->rows[i].warn & (WARN_NO_EFFECT | WARN_TINY_EFFECT) ? "true" : "false",
                i + 1 < r->nrows ? "," : "");
    }
    fputs("  ],\n  \"objective\": ", f);
    json_num(f, r->res->objective);
    fputs(",\n  \"rms_distance\": ", f);
    json_num(f, r->res->rms);
    fputs(",\n  \"max_distance\": ", f);
    json_num(f, r->res->max_dist);
    fputs(",\n  \"within_1pct_of_diagonal\": ", f);
    json_num(f, r->res->within);
    fputs(",\n  \"diagonal\": ", f);
    json_num(f, r->diagonal);
    fputs(",\n  \"noise\": ", f);
    json_num(f, r->res->noise);
    fprintf(f, ",\n  \"outliers\": %zu", r->res->outliers);
    fprintf(f, ",\n  \"evaluations\": %ld,\n  \"seconds\": %.6f,\n  \"status\": \"%s\",\n"
               "  \"converged\": %s,\n  \"verdict\": \"%s\",\n  \"interrupted\": %s\n}\n",
            r->res->evals, r->res->seconds,
            r->interrupted ? "interrupted" : fit_status_name(r->res->status),
            r->res->status == FIT_CONVERGED ? "true" : "false", r->verdict,
            r->interrupted ? "true" : "false");
    return ferror(f) ? -1 : 0;
}

/* Parse "lo:hi,lo:hi,..." into malloc'ed lo[] and hi[]. Returns the count, or 0 after a
 * message. */
static size_t parse_bounds(const char *s, double **lo, double **hi)
{
    size_t cap = 8, n = 0;
    double *l = malloc(cap * sizeof *l), *h = malloc(cap * sizeof *h);
    const char *p = s;
    while (l != NULL && h != NULL) {
        char *e;
        errno = 0;
        double a = strtod(p, &e);
        if (e == p || *e != ':') break;
        p = e + 1;
        double b = strtod(p, &e);
        if (e == p || errno || (*e && *e != ',') || !(a <= b) || isnan(a) || isnan(b)) break;
        if (n == cap) {
            cap *= 2;
            double *nl = realloc(l, cap * sizeof *l), *nh = realloc(h, cap * sizeof *h);
            if (nl) l = nl;
            if (nh) h = nh;
            if (!nl || !nh) break;
        }
        l[n] = a, h[n] = b, n++;
        if (*e == '\0') {
            *lo = l, *hi = h;
            return n;
        }
        p = e + 1;
    }
    fprintf(stderr, "frep fit: --bounds: expected lo:hi pairs separated by commas (lo <= hi), "
                    "got '%s'\n", s);
    free(l);
    free(h);
    return 0;
}

/* Every step's inputs and results, from the options to the report. */
typedef struct fit_cmd {
    fit_config cfg;
    const char *out, *model, *json, *bounds, *view;
    cli_list a;
    double loss_scale;         /* --loss-scale; <= 0: 0.01 x the cloud's diagonal */
    int in_place, quiet, strict, no_robust;
    size_t max_work;           /* --max-work; 0: the default */
    const char *tmpl, *cloud_path;
    frep_program *p;
    frep_program *ps;          /* its R-function compilation, when it differs (min/max) */
    fit_model fs;              /* ps as the annealing's model */
    char *src;                 /* the template's text */
    size_t nall, nfree, nnamed; /* parameters: all, fitted, named by '-- @free' */
    param_row *rows;           /* the fitted ones */
    size_t *idx;               /* their indices in the program's parameter vector */
    double *base, *x0, *lo, *hi;
    double *blo, *bhi;         /* --bounds */
    size_t nb;
    frep_cloud *cloud;
    double diagonal;
    fit_model fm;
    fit_points pts;
    fit_result res;
    int interrupted;
    char *text, *output;       /* the fitted template and where it goes */
    char verdict[320];         /* "good - 99.7% of points within 1% of the diagonal" */
    int nwarn;                 /* parameter warnings printed */
} fit_cmd;

static int parse_method(const char *arg, void *dest, char *why, size_t whylen)
{
    return fit_method_parse(arg, dest);
}

static int parse_objective(const char *arg, void *dest, char *why, size_t whylen)
{
    return fit_objective_parse(arg, dest);
}

static int parse_loss(const char *arg, void *dest, char *why, size_t whylen)
{
    return fit_loss_parse(arg, dest);
}

#define OFF(f) offsetof(fit_cmd, f)
static const cli_opt fit_opts[] = {
    { 'o', "output", "FILE", CLI_OPT_STRING, OFF(out), .help = "write the fitted template here" },
    { 0, "in-place", NULL, CLI_OPT_SET, OFF(in_place), .help = "overwrite TEMPLATE.hf itself" },
    CLI_OPT_MODEL(fit_cmd, model, "the model to fit (default: my_model, else the first one)"),
    CLI_OPT_STRICT(fit_cmd, strict),
    { 0, "method", "M", CLI_OPT_CUSTOM, OFF(cfg.method), .parse = parse_method,
      .expect = "saqn, qn, sa or lm",
      .help = "saqn (annealing, then quasi-Newton; default), qn, sa, lm" },
    { 0, "objective", "K", CLI_OPT_CUSTOM, OFF(cfg.obj.kind), .parse = parse_objective,
      .expect = "algebraic or geometric",
      .help = "local phase: algebraic (f, default) or geometric (f/|grad f|)" },
    { 0, "global-objective", "K", CLI_OPT_CUSTOM, OFF(cfg.global_kind), .parse = parse_objective,
      .expect = "algebraic or geometric", .help = "the annealing's: algebraic (default) or geometric" },
    { 0, "loss", "L", CLI_OPT_CUSTOM, OFF(cfg.obj.loss), .parse = parse_loss,
      .expect = "l2, huber, cauchy or geman", .help = "l2 (default), huber, cauchy or geman (robust to outliers)" },
    { 0, "loss-scale", "S", CLI_OPT_DOUBLE, OFF(loss_scale), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .help = "scale of the robust losses (default 0.01 x cloud diagonal)" },
    { 0, "sa-loss", "L", CLI_OPT_CUSTOM, OFF(cfg.sa_loss), .parse = parse_loss,
      .expect = "l2, huber, cauchy or geman",
      .help = "the annealing's loss (l2; geman for outliers), scale 1% of\nthe diagonal in function units" },
    { 0, "no-robust", NULL, CLI_OPT_SET, OFF(no_robust),
      .help = "skip the robust refinement (geometric distances, Cauchy loss,\nscale from the residuals) that follows the local phase" },
    { 0, "normals-weight", "W", CLI_OPT_DOUBLE, OFF(cfg.obj.normals_weight), .lo = 0, .hi = INFINITY,
      .help = "weight of the normal-agreement term (cloud with normals)" },
    CLI_OPT_SEED(fit_cmd, cfg.seed, "random seed (default 1)"),
    { 0, "max-time", "T", CLI_OPT_DOUBLE, OFF(cfg.max_time), .lo = 0, .hi = INFINITY,
      .help = "stop after T seconds and keep the best so far" },
    { 0, "max-evals", "N", CLI_OPT_LONG, OFF(cfg.max_evals), .lo = 1, .hi = INFINITY,
      .help = "stop after N objective evaluations" },
    CLI_OPT_MAX_WORK(fit_cmd, max_work),
    { 0, "sa-points", "N", CLI_OPT_SIZE, OFF(cfg.sa_points), .lo = 0, .hi = INFINITY,
      .help = "points the annealing uses (default 1024; 0: all)" },
    { 0, "sa-stall", "N", CLI_OPT_LONG, OFF(cfg.sa.stall_iter), .lo = 1, .hi = INFINITY,
      .help = "end an annealing chain after N iterations without progress (15)" },
    { 0, "sa-chains", "N", CLI_OPT_LONG, OFF(cfg.sa.chains), .lo = 1, .hi = INFINITY,
      .help = "independent annealing chains, the best kept (2)" },
    { 0, "sa-threshold", "V", CLI_OPT_DOUBLE, OFF(cfg.sa.threshold), .lo = 0, .hi = INFINITY,
      .help = "leave the annealing once the objective is <= V" },
    { 0, "json", "FILE", CLI_OPT_STRING, OFF(json), .help = "also write the report as JSON" },
    { 0, "view", "HTML", CLI_OPT_STRING, OFF(view),
      .help = "also write the page of the fitted model and the cloud\n(frep view)" },
    CLI_OPT_THREADS(fit_cmd, cfg.obj.nthreads, "OpenMP threads (results do not depend on it)"),
    { 'a', "params", "LIST", CLI_OPT_LIST, OFF(a), .help = "start values of a[] (v1,v2,...)" },
    { 0, "bounds", "LIST", CLI_OPT_STRING, OFF(bounds), .help = "bounds of a[]: lo1:hi1,lo2:hi2,..." },
    CLI_OPT_QUIET(fit_cmd, quiet, "no report on stdout"),
};
#undef OFF
static const cli_opt_spec fit_spec = { "fit", fit_usage, fit_opts,
                                       sizeof fit_opts / sizeof fit_opts[0], 24 };

/* Options -> TEMPLATE.hf and CLOUD; -o and --in-place exclude each other. */
static int stage_options(fit_cmd *f, int argc, char **argv)
{
    cli_args args;
    int rc = cli_opt_parse(&fit_spec, argc, argv, f, &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 2) return cli_usage_error("fit", "expected TEMPLATE.hf and CLOUD");
    if (f->out != NULL && f->in_place)
        return cli_usage_error("fit", "-o and --in-place exclude each other");
    f->tmpl = args.v[0];
    f->cloud_path = args.v[1];
    return CLI_GO_ON;
}

/* Annotations the lexer reads start their comment: `-- @free ...`. Warn about comments
 * that mention one further on (`-- flange radius @free [1, 5]`), which are plain comments
 * and free nothing. */
static void warn_lookalike_annotations(const char *path, const char *src)
{
    static const char *const words[] = {"@free", "@params"};
    unsigned line = 1;
    for (const char *s = src; *s; line++) {
        const char *eol = strchr(s, '\n');
        size_t len = eol ? (size_t)(eol - s) : strlen(s);
        const char *c = NULL;
        for (size_t i = 0; i + 1 < len; i++)
            if (s[i] == '-' && s[i + 1] == '-') { c = s + i + 2; break; }
        if (c != NULL) {
            const char *t = c;
            while (t < s + len && (*t == ' ' || *t == '\t')) t++;
            for (size_t w = 0; w < sizeof words / sizeof words[0] && *t != '@'; w++) {
                size_t wl = strlen(words[w]);
                for (const char *q = t; q + wl <= s + len; q++) {
                    if (memcmp(q, words[w], wl) != 0 ||
                        (q + wl < s + len && (isalnum((unsigned char)q[wl]) || q[wl] == '_')))
                        continue;
                    fprintf(stderr, "%s:%u: warning: '%s' is not at the start of the comment, "
                                    "so it is not an annotation; write '-- %s ...' (a "
                                    "description may follow the bounds)\n",
                            path, line, words[w], words[w]);
                    w = sizeof words / sizeof words[0] - 1;
                    break;
                }
            }
        }
        s = eol ? eol + 1 : s + len;
    }
}

static void ignore_diag(void *user, const frep_diag *d)
{
    (void)user, (void)d;
}

/* The template compiled, its parameter tables allocated, --bounds read. */
static int stage_template(fit_cmd *f)
{
    f->p = cli_compile_file(f->tmpl, f->model, f->a.v, f->a.n, -1, f->strict, &f->src);
    if (f->p == NULL || cli_work_limit(f->p, f->max_work) != CLI_OK) return CLI_FAIL;
    warn_lookalike_annotations(f->tmpl, f->src);
    /* A min/max template is annealed on its R-function compilation: the same parameters
     * and zero set, a smoother field (doc/fit.md). Its diagnostics were printed once. */
    frep_compile_options o;
    frep_compile_options_init(&o);
    o.model = f->model;
    o.a = f->a.v;
    o.na = f->a.n;
    o.setops_override = FREP_SETOPS_RFUNC;
    f->ps = frep_compile(f->tmpl, f->src, strlen(f->src), &o, ignore_diag, NULL);
    if (f->ps != NULL && f->ps->ncode == f->p->ncode && f->ps->nparams == f->p->nparams &&
        memcmp(f->ps->code, f->p->code, f->p->ncode * sizeof *f->p->code) == 0) {
        frep_program_free(f->ps);
        f->ps = NULL;
    }
    /* the annealing's program has a budget of its own, as large */
    if (f->ps != NULL &&
        cli_work_limit(f->ps, f->max_work ? f->max_work : CLI_DEFAULT_MAX_WORK) != CLI_OK)
        return CLI_FAIL;
    f->nall = frep_program_nparams(f->p);
    for (size_t i = 0; i < f->nall; i++) f->nnamed += f->p->params[i].end > f->p->params[i].off;
    size_t n = f->nall ? f->nall : 1;
    f->rows = calloc(n, sizeof *f->rows);
    f->idx = malloc(n * sizeof *f->idx);
    f->base = malloc(n * sizeof *f->base);
    f->x0 = malloc(n * sizeof *f->x0);
    f->lo = malloc(n * sizeof *f->lo);
    f->hi = malloc(n * sizeof *f->hi);
    if (!f->rows || !f->idx || !f->base || !f->x0 || !f->lo || !f->hi) {
        fprintf(stderr, "frep fit: out of memory\n");
        return CLI_FAIL;
    }
    if (f->bounds != NULL) {
        f->nb = parse_bounds(f->bounds, &f->blo, &f->bhi);
        if (f->nb == 0) return CLI_USAGE;
        if (f->nnamed > 0) {
            fprintf(stderr, "frep fit: --bounds is for templates fitted through a[]; %s has "
                            "'-- @free' parameters, whose bounds are in the template\n", f->tmpl);
            return CLI_USAGE;
        }
    }
    return CLI_OK;
}

/* Is parameter i one to fit? The '-- @free' ones when there are any, else the a[]
 * elements the code reads. */
static int is_free(const fit_cmd *f, size_t i)
{
    const frep_param_info *pi = &f->p->params[i];
    int named = pi->end > pi->off;
    if (f->nnamed > 0 ? !named : named) return 0;
    int used = named;
    for (uint32_t k = 0; k < f->p->ncode && !used; k++)
        used = f->p->code[k].op == FREP_OP_PARAM && f->p->code[k].arg == i;
    return used;
}

/* The parameters to fit, with their start values and bounds (--bounds for a[]). */
static int stage_params(fit_cmd *f)
{
    for (size_t i = 0; i < f->nall; i++) {
        const frep_param_info *pi = &f->p->params[i];
        f->base[i] = pi->value;
        if (!is_free(f, i)) continue;
        param_row *r = &f->rows[f->nfree];
        int named = pi->end > pi->off;
        *r = (param_row){ pi->name, i, pi->value, pi->value, pi->lo, pi->hi, named, pi->off, pi->end,
                          NAN, NAN, 0 };
        if (!named && f->nb > 0) {
            if (f->nb != f->nall) {
                fprintf(stderr, "frep fit: --bounds gives %zu ranges; the template's a[] has %zu "
                                "elements\n", f->nb, f->nall);
                return CLI_USAGE;
            }
            r->lo = f->blo[i], r->hi = f->bhi[i];
        }
        f->idx[f->nfree++] = i;
    }
    if (f->nfree == 0) {
        fprintf(stderr, "%s: error: the template has no free parameters: mark values with "
                        "'-- @free [lo, hi]' or use an a[] array\n", f->tmpl);
        return CLI_FAIL;
    }
    if (f->nnamed == 0 && f->a.n != 0 && f->a.n != f->nall)
        fprintf(stderr, "frep fit: note: -a gives %zu values for the %zu elements of a[]; the "
                        "others start at 0\n", f->a.n, f->nall);
    for (size_t j = 0; j < f->nfree; j++) {
        const param_row *r = &f->rows[j];
        if (r->start < r->lo || r->start > r->hi) {
            fprintf(stderr, "%s: error: parameter %s starts at %g, outside its bounds [%g, %g]\n",
                    f->tmpl, r->name, r->start, r->lo, r->hi);
            return CLI_FAIL;
        }
    }
    return CLI_OK;
}

static int point_finite(const frep_cloud *c, size_t i)
{
    return isfinite(c->x[i]) && isfinite(c->y[i]) && isfinite(c->z[i]) &&
           (!c->has_normals || (isfinite(c->nx[i]) && isfinite(c->ny[i]) && isfinite(c->nz[i])));
}

/* The cloud read and checked (finite, enough points, normals for --normals-weight); its
 * diagonal sets the default loss scale. */
static int stage_cloud(fit_cmd *f)
{
    frep_error cerr;
    f->cloud = cloud_read(f->cloud_path, &cerr);
    if (f->cloud == NULL) {
        fprintf(stderr, "%s\n", cerr.msg[0] ? cerr.msg : "frep fit: cannot read the cloud");
        return CLI_FAIL;
    }
    frep_cloud *c = f->cloud;
    for (size_t i = 0; i < c->n; i++) {
        if (!point_finite(c, i)) {
            fprintf(stderr, "%s: point %zu is not finite (NaN or infinity)\n", f->cloud_path, i + 1);
            return CLI_FAIL;
        }
    }
    if (c->n < f->nfree + FIT_MIN_POINTS) {
        fprintf(stderr, "%s: %zu points are too few to fit %zu parameters (need at least %zu)\n",
                f->cloud_path, c->n, f->nfree, f->nfree + FIT_MIN_POINTS);
        return CLI_FAIL;
    }
    if (f->cfg.obj.normals_weight > 0 && !c->has_normals) {
        fprintf(stderr, "frep fit: --normals-weight needs a cloud with normals; %s has none\n",
                f->cloud_path);
        return CLI_USAGE;
    }
    if (c->has_normals) cloud_normalize_normals(c);
    f->diagonal = cloud_diagonal(c);
    f->cfg.obj.loss_scale = f->loss_scale > 0 ? f->loss_scale
                                              : 0.01 * (f->diagonal > 0 ? f->diagonal : 1);
    f->pts = (fit_points){ c->n, c->x, c->y, c->z, NULL, NULL, NULL };
    if (c->has_normals) f->pts.nx = c->nx, f->pts.ny = c->ny, f->pts.nz = c->nz;
    return CLI_OK;
}

/* The search box: the annealing needs a finite one, so an unbounded parameter searches
 * its start plus or minus the cloud's diagonal. */
static void stage_search_box(fit_cmd *f)
{
    int global = f->cfg.method == FIT_METHOD_SAQN || f->cfg.method == FIT_METHOD_SA;
    for (size_t j = 0; j < f->nfree; j++) {
        f->lo[j] = f->rows[j].lo, f->hi[j] = f->rows[j].hi;
        f->x0[j] = f->rows[j].start;
        if (global && (!isfinite(f->lo[j]) || !isfinite(f->hi[j]))) {
            double d = f->diagonal > 0 ? f->diagonal : 1;
            if (!isfinite(f->lo[j])) f->lo[j] = f->x0[j] - d;
            if (!isfinite(f->hi[j])) f->hi[j] = f->x0[j] + d;
            if (!f->quiet)
                fprintf(stderr, "frep fit: note: %s has no bounds; the annealing searches "
                                "[%g, %g]\n", f->rows[j].name, f->lo[j], f->hi[j]);
        }
    }
}

/* The fit itself, with progress on a terminal; Ctrl-C keeps the best so far. */
static int stage_fit(fit_cmd *f)
{
    if (fit_program_model(f->p, f->idx, f->nfree, f->base, &f->fm) != 0) {
        fprintf(stderr, "frep fit: out of memory\n");
        return CLI_FAIL;
    }
    if (f->ps != NULL) {
        if (fit_program_model(f->ps, f->idx, f->nfree, f->base, &f->fs) != 0) {
            fprintf(stderr, "frep fit: out of memory\n");
            return CLI_FAIL;
        }
        f->cfg.surrogate = &f->fs;
    }
    int tty = isatty(STDERR_FILENO) && !f->quiet;
    if (tty) f->cfg.progress = progress;
    f->cfg.interrupt = cli_sigint_catch();
    frep_error err;
    frep_error_init(&err);
    int frc = fit_run(&f->fm, &f->pts, f->lo, f->hi, f->x0, &f->cfg, &f->res, &err);
    cli_sigint_restore();
    if (tty) fputs("\r\033[K", stderr);
    if (cli_work_check("fit", f->tmpl, f->p) != CLI_OK ||
        (f->ps && cli_work_check("fit", f->tmpl, f->ps) != CLI_OK))
        return CLI_FAIL;
    if (frc != 0) {
        fprintf(stderr, "%s: error: %s\n", f->tmpl, err.msg);
        return CLI_FAIL;
    }
    f->interrupted = cli_interrupted();
    return CLI_OK;
}

/* The "-- @params v1, v2, ..." annotation of an a[] template: the values of every
 * element of a[] (the fitted ones and the others as given), which every command uses
 * when no -a is given, so the fitted file is the fitted shape on its own. */
static char *fitted_note(const fit_cmd *f)
{
    size_t cap = 32 + f->nall * (FIT_NUMBER_MAX + 2), m;
    char *note = malloc(cap);
    if (note == NULL) return NULL;
    m = (size_t)snprintf(note, cap, "-- @params");
    for (size_t i = 0; i < f->nall; i++) {
        char num[FIT_NUMBER_MAX];
        double v = f->base[i], lo = -INFINITY, hi = INFINITY;
        for (size_t j = 0; j < f->nfree; j++)
            if (f->idx[j] == i) v = f->x0[j], lo = f->rows[j].lo, hi = f->rows[j].hi;
        fit_format_number(num, v, lo, hi);
        m += (size_t)snprintf(note + m, cap - m, "%s %s", i ? "," : "", num);
    }
    return note;
}

/* The fitted template: named values edited in place, the cloud's box in '-- @box'. */
static int stage_writeback(fit_cmd *f)
{
    fit_edit *edits = malloc(f->nfree * sizeof *edits);
    size_t ne = 0;
    if (edits == NULL) return CLI_FAIL;
    for (size_t j = 0; j < f->nfree; j++) {
        param_row *r = &f->rows[j];
        r->value = f->x0[j];
        if (r->has_span) edits[ne++] = (fit_edit){ r->off, r->end, f->x0[j], r->lo, r->hi };
    }
    char *note = f->nnamed == 0 ? fitted_note(f) : NULL;
    double blo3[3], bhi3[3], box[6];
    cloud_bbox(f->cloud, blo3, bhi3);
    double margin = FIT_BOX_MARGIN * (f->diagonal > 0 ? f->diagonal : 1);
    for (int k = 0; k < 3; k++) box[k] = blo3[k] - margin, box[3 + k] = bhi3[k] + margin;
    size_t tlen = 0;
    f->text = fit_writeback(f->src, strlen(f->src), edits, ne, box, note, &tlen);
    free(edits);
    free(note);
    if (f->text == NULL) {
        fprintf(stderr, "frep fit: cannot rewrite the template (out of memory)\n");
        return CLI_FAIL;
    }
    f->output = f->in_place ? strdup(f->tmpl) : f->out != NULL ? strdup(f->out)
                                                                : derived_name(f->tmpl);
    text_out to = { f->text, tlen };
    if (f->output == NULL || cli_write_atomic(f->output, write_text, &to) != 0) return CLI_FAIL;
    return CLI_OK;
}

/* The warnings of one parameter (WARN_* bits) from its value, bounds, sensitivity and
 * standard error. */
static int param_warnings(const param_row *r, double diagonal)
{
    int w = 0;
    double range = r->hi - r->lo;
    int bounded = isfinite(range) && range > 0;
    double scale = bounded ? range : 1 + fabs(r->value);
    if (bounded) {
        double gap = fmin(r->value - r->lo, r->hi - r->value);
        if (gap <= FIT_ON_BOUND * range) w |= WARN_ON_BOUND;
        else if (gap <= FIT_NEAR_BOUND * range) w |= WARN_NEAR_BOUND;
    }
    if (r->sens == 0) w |= WARN_NO_EFFECT;
    else if (r->sens * scale < FIT_TINY_EFFECT * diagonal) w |= WARN_TINY_EFFECT;
    else if (r->sigma > FIT_LOOSE * scale) w |= WARN_LOOSE;
    return w;
}

/* Per-parameter warnings on stderr and the one-line verdict. */
static void stage_judge(fit_cmd *f)
{
    const fit_result *res = &f->res;
    for (size_t j = 0; j < f->nfree; j++) {
        param_row *r = &f->rows[j];
        r->value = f->x0[j];
        r->sigma = res->have_uncertainty ? res->sigma[j] : NAN;
        r->sens = res->have_uncertainty ? res->sens[j] : NAN;
        r->warn = res->have_uncertainty ? param_warnings(r, f->diagonal) : 0;
        if (r->warn) f->nwarn++;
        if (f->quiet) continue;
        const char *nm = r->name;
        if (r->warn & WARN_ON_BOUND)
            fprintf(stderr, "frep fit: warning: %s = %.10g is on its bound [%g, %g]: the best "
                            "value may lie beyond it (widen the bounds) or the feature it "
                            "sizes is switched off\n", nm, r->value, r->lo, r->hi);
        if (r->warn & WARN_NEAR_BOUND)
            fprintf(stderr, "frep fit: warning: %s = %.10g is within 1%% of a bound of [%g, %g]\n",
                    nm, r->value, r->lo, r->hi);
        if (r->warn & WARN_NO_EFFECT)
            fprintf(stderr, "frep fit: warning: the surface does not depend on %s (unused, "
                            "assigned again after its '@free' line, or its primitive is "
                            "away from every point): its value is arbitrary\n", nm);
        if (r->warn & WARN_TINY_EFFECT)
            fprintf(stderr, "frep fit: warning: %s barely moves the surface (%.3g per unit): "
                            "its value is arbitrary\n", nm, r->sens);
        if (r->warn & WARN_LOOSE)
            fprintf(stderr, "frep fit: warning: %s is poorly determined by the points "
                            "(standard error %.3g)\n", nm, r->sigma);
    }
    const char *word;
    char why[96] = "", noise[160] = "";
    if (!isfinite(res->within)) {
        word = "unknown";
        snprintf(why, sizeof why, "the distances could not be measured");
    } else {
        /* Judged on the inliers: points taken for outliers are reported, not held
         * against the fit, unless they are more than FIT_VERDICT_OUTLIERS of the cloud.
         * Noise above FIT_WITHIN is reported and makes the fit doubtful: from the
         * distances alone it cannot be told apart from a fit that is off. */
        double share = isfinite(res->within_inliers) ? res->within_inliers : res->within;
        word = share >= FIT_VERDICT_GOOD ? "good" : share >= FIT_VERDICT_POOR
                                                        ? "doubtful" : "poor";
        double n = (double)f->cloud->n;
        if (isfinite(res->noise) && 3 * res->noise > FIT_WITHIN * f->diagonal)
            snprintf(noise, sizeof noise, "; noise %.3g (%.2g%% of the diagonal), %.1f%% of "
                     "the inliers within 1%%", res->noise, 100 * res->noise / f->diagonal,
                     100 * share);
        if (res->outliers > 0)
            snprintf(noise + strlen(noise), sizeof noise - strlen(noise),
                     "; %zu points (%.1f%%) taken for outliers", res->outliers,
                     100 * (double)res->outliers / n);
        if ((double)res->outliers > FIT_VERDICT_OUTLIERS * n) word = "poor";
        if (f->interrupted || res->status == FIT_STOPPED)
            snprintf(why, sizeof why, "; stopped before the end");
        else if (res->status != FIT_CONVERGED)
            snprintf(why, sizeof why, "; not converged");
        if (f->nwarn > 0)
            snprintf(why + strlen(why), sizeof why - strlen(why), "; %d parameter warning%s",
                     f->nwarn, f->nwarn == 1 ? "" : "s");
        if (why[0] != '\0' && strcmp(word, "good") == 0) word = "doubtful";
    }
    if (isfinite(res->within))
        snprintf(f->verdict, sizeof f->verdict, "%s - %.1f%% of points within 1%% of the "
                 "diagonal%s%s", word, 100 * res->within, noise, why);
    else
        snprintf(f->verdict, sizeof f->verdict, "%s - %s", word, why);
}

/* The report on stdout: settings, a table of the parameters, the result. */
static void stage_report(const fit_cmd *f)
{
    const fit_config *cfg = &f->cfg;
    const fit_result *res = &f->res;
    printf("frep fit: %s <- %s (%zu points%s)\n", f->tmpl, f->cloud_path, f->cloud->n,
           f->cloud->has_normals ? ", with normals" : "");
    printf("method %s, objective %s (annealing: %s), loss %s, seed %llu\n",
           fit_method_name(cfg->method), fit_objective_name(cfg->obj.kind),
           fit_objective_name(cfg->global_kind), fit_loss_name(cfg->obj.loss),
           (unsigned long long)cfg->seed);
    if (cfg->method == FIT_METHOD_SAQN || cfg->method == FIT_METHOD_SA)
        printf("annealing: %ld chain%s on %zu points, stall %ld\n", cfg->sa.chains,
               cfg->sa.chains == 1 ? "" : "s",
               cfg->sa_points > 0 && cfg->sa_points < f->pts.n ? cfg->sa_points : f->pts.n,
               cfg->sa.stall_iter);
    printf("%-12s %16s %18s %10s   %s\n", "parameter", "start", "fitted", "+-", "bounds");
    for (size_t j = 0; j < f->nfree; j++) {
        const param_row *r = &f->rows[j];
        printf("%-12s %16.10g %18.12g %10.3g   [%g, %g]%s\n", r->name, r->start, r->value,
               r->sigma, r->lo, r->hi,
               r->warn & WARN_ON_BOUND ? "  on bound" : r->warn & WARN_NEAR_BOUND ? "  near bound"
               : r->warn & (WARN_NO_EFFECT | WARN_TINY_EFFECT) ? "  no effect"
               : r->warn & WARN_LOOSE ? "  loose" : "");
    }
    printf("objective %.6g\n", res->objective);
    printf("distance to the surface: rms %.6g, max %.6g (cloud diagonal %.6g)\n", res->rms,
           res->max_dist, f->diagonal);
    printf("evaluations %ld, time %.3f s, %s\n", res->evals, res->seconds,
           f->interrupted ? "interrupted: best so far" : fit_status_name(res->status));
    printf("fit: %s\n", f->verdict);
    printf("wrote %s\n", f->output);
}

/* --view: the page of the fitted template (a[] templates with the fitted -a). */
static int stage_view(const fit_cmd *f)
{
    text_out to = { f->text, strlen(f->text) };
    cli_view_job j = { "fit", f->view, f->output, f->model, f->cloud_path, write_text, &to,
                       f->nnamed == 0 ? f->x0 : NULL, f->nfree, f->cfg.obj.nthreads, f->quiet };
    return cli_view_result(&j);
}

/* template -> parameters -> cloud -> search box -> fit -> fitted template -> JSON ->
 * report -> [page]; 130 after Ctrl-C. */
static int fit_steps(fit_cmd *f)
{
    int rc = stage_template(f);
    if (rc == CLI_OK) rc = stage_params(f);
    if (rc == CLI_OK) rc = stage_cloud(f);
    if (rc != CLI_OK) return rc;
    stage_search_box(f);
    rc = stage_fit(f);
    if (rc == CLI_OK) rc = stage_writeback(f);
    if (rc != CLI_OK) return rc;
    stage_judge(f);
    report_ctx rep = { f->tmpl, f->cloud_path, f->output, f->rows, f->nfree, f->cloud->n,
                       &f->cfg, &f->res, f->diagonal, f->interrupted, f->verdict };
    if (f->json != NULL && cli_write_atomic(f->json, write_json, &rep) != 0) rc = CLI_FAIL;
    if (!f->quiet) stage_report(f);
    if (rc == CLI_OK && f->view) rc = stage_view(f);
    return f->interrupted && rc == CLI_OK ? 130 : rc;
}

static void fit_cmd_free(fit_cmd *f)
{
    if (f->fm.user != NULL) fit_program_model_free(&f->fm);
    if (f->fs.user != NULL) fit_program_model_free(&f->fs);
    if (f->ps != NULL) frep_program_free(f->ps);
    cloud_free(f->cloud);
    frep_free(f->text);
    free(f->output);
    free(f->rows);
    free(f->idx);
    free(f->base);
    free(f->x0);
    free(f->lo);
    free(f->hi);
    free(f->blo);
    free(f->bhi);
    free(f->src);
    cli_list_free(&f->a);
    if (f->p != NULL) frep_program_free(f->p);
}

int cmd_fit(int argc, char **argv)
{
    fit_cmd f;
    memset(&f, 0, sizeof f);
    fit_config_init(&f.cfg);
    f.cfg.report = 1;
    f.loss_scale = -1;
    int rc = stage_options(&f, argc, argv);
    if (f.no_robust) f.cfg.robust = 0;
    if (rc == CLI_GO_ON) rc = fit_steps(&f);
    fit_cmd_free(&f);
    return rc;
}

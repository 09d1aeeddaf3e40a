/* cmd_fit.c - frep fit: recover the free parameters of a template from a point cloud
 * and write the fitted template back with the values in place, through the public API
 * (frep_fit_template(), api/api_fit.c): this file reads the options and the files,
 * prints the progress, the diagnostics and the report, and maps Ctrl-C to the fit's
 * cancel callback.
 */
#include "config.h"

#include "cli.h"

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
static void progress(void *user, const frep_fit_progress *p)
{
    (void)user;
    static const char *const names[] = {"annealing", "quasi-Newton", "Levenberg-Marquardt"};
    char chain[48] = "";
    if (p->nchains > 0) snprintf(chain, sizeof chain, "chain %ld/%ld", p->chain, p->nchains);
    fprintf(stderr, "\r%-12s %-11s iteration %-5ld %6.1f s  best %-11.5g %s\033[K",
            names[p->phase < 0 || p->phase > 2 ? 0 : p->phase], chain, p->iteration,
            p->elapsed, p->best,
            p->subset == 1 ? "(annealing's points)" : p->subset == 2 ? "(robust, all points)"
                                                                  : "(all points)");
    fflush(stderr);
}

/* Ctrl-C: the fit's cancel callback. */
static int cancel(void *user)
{
    (void)user;
    return cli_interrupted() != 0;
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
    frep_fit_options o;
    const char *out, *model, *json, *bounds, *view;
    cli_list a;
    int in_place, quiet, strict, no_robust;
    size_t max_work;           /* --max-work; 0: the default */
    const char *tmpl, *cloud_path;
    char *src;                 /* the template's text */
    size_t srclen;
    double *blo, *bhi;         /* --bounds */
    frep_cloud *cloud;
    int has_normals;
    frep_fit *fit;
    char *output;              /* where the fitted template goes */
    cli_diag_ctx dc;           /* compiler diagnostics with the source line */
} fit_cmd;

static int parse_method(const char *arg, void *dest, char *why, size_t whylen)
{
    (void)why, (void)whylen;
    return frep_fit_method_parse(arg, (frep_fit_method *)dest);
}

static int parse_objective(const char *arg, void *dest, char *why, size_t whylen)
{
    (void)why, (void)whylen;
    return frep_fit_objective_parse(arg, (frep_fit_objective *)dest);
}

static int parse_loss(const char *arg, void *dest, char *why, size_t whylen)
{
    (void)why, (void)whylen;
    return frep_fit_loss_parse(arg, (frep_fit_loss *)dest);
}

#define OFF(f) offsetof(fit_cmd, f)
static const cli_opt fit_opts[] = {
    { 'o', "output", "FILE", CLI_OPT_STRING, OFF(out), .help = "write the fitted template here" },
    { 0, "in-place", NULL, CLI_OPT_SET, OFF(in_place), .help = "overwrite TEMPLATE.hf itself" },
    CLI_OPT_MODEL(fit_cmd, model, "the model to fit (default: my_model, else the first one)"),
    CLI_OPT_STRICT(fit_cmd, strict),
    { 0, "method", "M", CLI_OPT_CUSTOM, OFF(o.method), .parse = parse_method,
      .expect = "saqn, qn, sa or lm",
      .help = "saqn (annealing, then quasi-Newton; default), qn, sa, lm" },
    { 0, "objective", "K", CLI_OPT_CUSTOM, OFF(o.objective), .parse = parse_objective,
      .expect = "algebraic or geometric",
      .help = "local phase: algebraic (f, default) or geometric (f/|grad f|)" },
    { 0, "global-objective", "K", CLI_OPT_CUSTOM, OFF(o.global_objective), .parse = parse_objective,
      .expect = "algebraic or geometric", .help = "the annealing's: algebraic (default) or geometric" },
    { 0, "loss", "L", CLI_OPT_CUSTOM, OFF(o.loss), .parse = parse_loss,
      .expect = "l2, huber, cauchy or geman", .help = "l2 (default), huber, cauchy or geman (robust to outliers)" },
    { 0, "loss-scale", "S", CLI_OPT_DOUBLE, OFF(o.loss_scale), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .help = "scale of the robust losses (default 0.01 x cloud diagonal)" },
    { 0, "sa-loss", "L", CLI_OPT_CUSTOM, OFF(o.sa_loss), .parse = parse_loss,
      .expect = "l2, huber, cauchy or geman",
      .help = "the annealing's loss (l2, made geman on a cloud with over\n0.5% isolated points), scale 1% of the diagonal in\nfunction units" },
    { 0, "no-robust", NULL, CLI_OPT_SET, OFF(no_robust),
      .help = "skip the robust refinement (geometric distances, Cauchy loss,\nscale from the residuals) that follows the local phase" },
    { 0, "normals-weight", "W", CLI_OPT_DOUBLE, OFF(o.normals_weight), .lo = 0, .hi = INFINITY,
      .help = "weight of the normal-agreement term (cloud with normals)" },
    CLI_OPT_SEED(fit_cmd, o.seed, "random seed (default 1)"),
    { 0, "max-time", "T", CLI_OPT_DOUBLE, OFF(o.max_time), .lo = 0, .hi = INFINITY,
      .help = "stop after T seconds and keep the best so far" },
    { 0, "max-evals", "N", CLI_OPT_LONG, OFF(o.max_evals), .lo = 1, .hi = INFINITY,
      .help = "stop after N objective evaluations" },
    CLI_OPT_MAX_WORK(fit_cmd, max_work),
    { 0, "sa-points", "N", CLI_OPT_SIZE, OFF(o.sa_points), .lo = 0, .hi = INFINITY,
      .help = "points the annealing uses (default 1024; 0: all)" },
    { 0, "sa-stall", "N", CLI_OPT_LONG, OFF(o.sa_stall), .lo = 1, .hi = INFINITY,
      .help = "end an annealing chain after N iterations without progress (15)" },
    { 0, "sa-chains", "N", CLI_OPT_LONG, OFF(o.sa_chains), .lo = 1, .hi = INFINITY,
      .help = "independent annealing chains, the best kept (2); none\n"
              "after one that puts 99.9% of the points within 1% of the\n"
              "diagonal of the surface" },
    { 0, "sa-threshold", "V", CLI_OPT_DOUBLE, OFF(o.sa_threshold), .lo = 0, .hi = INFINITY,
      .help = "leave the annealing once the objective is <= V" },
    { 0, "json", "FILE", CLI_OPT_STRING, OFF(json), .help = "also write the report as JSON" },
    { 0, "view", "HTML", CLI_OPT_STRING, OFF(view),
      .help = "also write the page of the fitted model and the cloud\n(frep view)" },
    CLI_OPT_THREADS(fit_cmd, o.nthreads, "OpenMP threads (results do not depend on it)"),
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

/* The library's messages: the compiler's with their source line; the fit's as
 * "frep fit: ..." (notes and warnings dropped by -q). */
static void fit_diag(void *user, const frep_diag *d)
{
    fit_cmd *f = user;
    if (d->file != NULL) {
        cli_print_diag(&f->dc, d);
        return;
    }
    if (f->quiet && d->severity != FREP_ERROR) return;
    cli_library_diag("fit", d);
}

/* The template read, the cloud read, --bounds parsed. */
static int stage_inputs(fit_cmd *f)
{
    f->src = cli_read_file(f->tmpl, &f->srclen);
    if (f->src == NULL) return CLI_FAIL;
    f->dc = (cli_diag_ctx){ f->src, f->srclen, 0, 0, NULL, 0, NULL };
    warn_lookalike_annotations(f->tmpl, f->src);
    if (f->bounds != NULL) {
        size_t nb = parse_bounds(f->bounds, &f->blo, &f->bhi);
        if (nb == 0) return CLI_USAGE;
        f->o.lo = f->blo, f->o.hi = f->bhi, f->o.nbounds = nb;
    }
    f->cloud = frep_cloud_read(f->cloud_path, fit_diag, f);
    if (f->cloud == NULL) return CLI_FAIL;
    f->has_normals = frep_cloud_has_normals(f->cloud);
    if (f->o.normals_weight > 0 && !f->has_normals) {
        fprintf(stderr, "frep fit: --normals-weight needs a cloud with normals; %s has none\n",
                f->cloud_path);
        return CLI_USAGE;
    }
    return CLI_OK;
}

/* The fit, with progress on a terminal; Ctrl-C keeps the best so far. */
static int stage_fit(fit_cmd *f)
{
    frep_compile_options co;
    frep_compile_options_init(&co);
    co.model = f->model;
    co.a = f->a.v;
    co.na = f->a.n;
    co.strict = f->strict;
    int tty = isatty(STDERR_FILENO) && !f->quiet;
    if (tty) f->o.progress = progress;
    f->o.cancel = cancel;
    f->o.max_work = f->max_work ? f->max_work : CLI_DEFAULT_MAX_WORK;
    cli_sigint_catch();
    f->fit = frep_fit_template(f->tmpl, f->src, f->srclen, &co, f->cloud, &f->o, fit_diag, f);
    cli_sigint_restore();
    if (tty) fputs("\r\033[K", stderr);
    return f->fit ? CLI_OK : CLI_FAIL;
}

/* The fitted template, written atomically. */
static int stage_write(fit_cmd *f)
{
    f->output = f->in_place ? strdup(f->tmpl) : f->out != NULL ? strdup(f->out)
                                                                : derived_name(f->tmpl);
    if (f->output == NULL) return CLI_FAIL;
    size_t len;
    const char *text = frep_fit_text(f->fit, &len);
    text_out to = { text, len };
    return cli_write_atomic(f->output, write_text, &to) == 0 ? CLI_OK : CLI_FAIL;
}


/* The report on stdout: settings, a table of the parameters, the result. */
static void stage_report(const fit_cmd *f)
{
    const frep_fit_options *o = &f->o;
    frep_fit_info in;
    frep_fit_get_info(f->fit, &in);
    printf("frep fit: %s <- %s (%zu points%s)\n", f->tmpl, f->cloud_path, in.npoints,
           f->has_normals ? ", with normals" : "");
    printf("method %s, objective %s (annealing: %s), loss %s, seed %llu\n",
           frep_fit_method_name(o->method), frep_fit_objective_name(o->objective),
           frep_fit_objective_name(o->global_objective), frep_fit_loss_name(o->loss),
           (unsigned long long)o->seed);
    if (o->method == FREP_FIT_SAQN || o->method == FREP_FIT_SA)
        printf("annealing: %ld chain%s on %zu points, stall %ld\n", o->sa_chains,
               o->sa_chains == 1 ? "" : "s",
               o->sa_points > 0 && o->sa_points < in.npoints ? o->sa_points : in.npoints,
               o->sa_stall);
    printf("%-12s %16s %18s %10s   %s\n", "parameter", "start", "fitted", "+-", "bounds");
    for (size_t j = 0; j < in.nparams; j++) {
        frep_fit_param r;
        frep_fit_get_param(f->fit, j, &r);
        printf("%-12s %16.10g %18.12g %10.3g   [%g, %g]%s\n", r.name, r.start, r.value,
               r.sigma, r.lo, r.hi,
               r.warnings & FREP_FIT_ON_BOUND ? "  on bound"
               : r.warnings & FREP_FIT_NEAR_BOUND ? "  near bound"
               : r.warnings & (FREP_FIT_NO_EFFECT | FREP_FIT_TINY_EFFECT) ? "  no effect"
               : r.warnings & FREP_FIT_LOOSE ? "  loose" : "");
    }
    printf("objective %.6g\n", in.objective);
    printf("distance to the surface: rms %.6g, max %.6g (cloud diagonal %.6g)\n", in.rms,
           in.max_dist, in.diagonal);
    printf("evaluations %ld, time %.3f s, %s\n", in.evals, in.seconds,
           in.interrupted ? "interrupted: best so far" : in.status);
    printf("fit: %s\n", in.verdict);
    printf("wrote %s\n", f->output);
}

/* --view: the page of the fitted template (a[] templates with the fitted -a). */
static int stage_view(const fit_cmd *f)
{
    size_t len, n = frep_fit_nvalues(f->fit);
    const char *text = frep_fit_text(f->fit, &len);
    text_out to = { text, len };
    double *a = malloc((n ? n : 1) * sizeof *a);
    if (a == NULL) return CLI_FAIL;
    frep_fit_values(f->fit, a, n);
    int named = 0;
    for (size_t j = 0; j < frep_fit_nparams(f->fit); j++) {
        frep_fit_param r;
        frep_fit_get_param(f->fit, j, &r);
        named |= strchr(r.name, '[') == NULL;
    }
    cli_view_job j = { "fit", f->view, f->output, f->model, f->cloud_path, write_text, &to,
                       named ? NULL : a, named ? 0 : n, f->o.nthreads, f->quiet };
    int rc = cli_view_result(&j);
    free(a);
    return rc;
}

/* inputs -> fit -> fitted template -> JSON -> report -> [page]; 130 after Ctrl-C. */
static int fit_steps(fit_cmd *f)
{
    int rc = stage_inputs(f);
    if (rc == CLI_OK) rc = stage_fit(f);
    if (rc == CLI_OK) rc = stage_write(f);
    if (rc != CLI_OK) return rc;
    if (f->json != NULL &&
        frep_fit_write_json(f->fit, f->json, f->tmpl, f->cloud_path, f->output, fit_diag, f) != 0)
        rc = CLI_FAIL;
    if (!f->quiet) stage_report(f);
    if (rc == CLI_OK && f->view) rc = stage_view(f);
    frep_fit_info in;
    frep_fit_get_info(f->fit, &in);
    return (in.interrupted || cli_interrupted()) && rc == CLI_OK ? 130 : rc;
}

static void fit_cmd_free(fit_cmd *f)
{
    frep_fit_free(f->fit);
    frep_cloud_free(f->cloud);
    free(f->output);
    free(f->blo);
    free(f->bhi);
    free(f->src);
    cli_diag_done(&f->dc);
    cli_list_free(&f->a);
}

int cmd_fit(int argc, char **argv)
{
    fit_cmd f;
    memset(&f, 0, sizeof f);
    frep_fit_options_init(&f.o);
    int rc = stage_options(&f, argc, argv);
    if (f.no_robust) f.o.robust = 0;
    if (rc == CLI_GO_ON) rc = fit_steps(&f);
    fit_cmd_free(&f);
    return rc;
}

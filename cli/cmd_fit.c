/* cmd_fit.c - frep fit: recover the free parameters of a template from a point cloud
 * (fit/fit.c: simulated annealing + quasi-Newton) and write the fitted template back
 * with the values in place (fit/writeback.c), atomically and next to the template.
 */
#define _POSIX_C_SOURCE 200809L

#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "fit.h"
#include "program.h"
#include "writeback.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <signal.h>
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
    "started from -a and bounded by --bounds. See doc/fit.md.\n\n"
    "Options:\n"
    "  -o, --output FILE     write the fitted template here\n"
    "      --in-place        overwrite TEMPLATE.hf itself\n"
    "  -m, --model NAME      the model to fit (default: my_model, else the last one)\n"
    "      --method M        saqn (annealing, then quasi-Newton; default), qn, sa, lm\n"
    "      --objective K     local phase: algebraic (f, default) or geometric (f/|grad f|)\n"
    "      --global-objective K  the annealing's: algebraic (default) or geometric\n"
    "      --loss L          l2 (default), huber or cauchy (robust to outliers)\n"
    "      --loss-scale S    scale of the robust losses (default 0.01 x cloud diagonal)\n"
    "      --normals-weight W  weight of the normal-agreement term (cloud with normals)\n"
    "      --seed S          random seed (default 1)\n"
    "      --max-time T      stop after T seconds and keep the best so far\n"
    "      --max-evals N     stop after N objective evaluations\n"
    "      --sa-points N     points the annealing uses (default 1024; 0: all)\n"
    "      --sa-stall N      end an annealing chain after N iterations without progress (15)\n"
    "      --sa-chains N     independent annealing chains, the best kept (2)\n"
    "      --sa-threshold V  leave the annealing once the objective is <= V\n"
    "      --json FILE       also write the report as JSON\n"
    "  -t, --threads N       OpenMP threads (results do not depend on it)\n"
    "  -a, --params LIST     start values of a[] (v1,v2,...)\n"
    "      --bounds LIST     bounds of a[]: lo1:hi1,lo2:hi2,...\n"
    "  -q, --quiet           no report on stdout\n";

/* Ctrl-C: the one piece of global mutable state frep allows; fit/optim.c polls it. */
static volatile sig_atomic_t fit_interrupted;

static void on_sigint(int sig)
{
    (void)sig;
    fit_interrupted = 1;
}

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

static void progress(void *user, fit_phase phase, double temp, double best)
{
    (void)user;
    static const char *const names[] = {"annealing", "quasi-Newton", "Levenberg-Marquardt"};
    if (phase == FIT_PHASE_SA)
        fprintf(stderr, "\r%-20s T = %-10.4g best = %-12.6g", names[phase], temp, best);
    else
        fprintf(stderr, "\r%-20s %14s best = %-12.6g", names[phase], "", best);
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

typedef struct report_ctx {
    const char *tmpl, *cloud, *output;
    const param_row *rows;
    size_t nrows, npoints;
    const fit_config *cfg;
    const fit_result *res;
    double diagonal;
    int interrupted;
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
        fprintf(f, "}%s\n", i + 1 < r->nrows ? "," : "");
    }
    fputs("  ],\n  \"objective\": ", f);
    json_num(f, r->res->objective);
    fputs(",\n  \"rms_distance\": ", f);
    json_num(f, r->res->rms);
    fputs(",\n  \"max_distance\": ", f);
    json_num(f, r->res->max_dist);
    fputs(",\n  \"diagonal\": ", f);
    json_num(f, r->diagonal);
    fprintf(f, ",\n  \"evaluations\": %ld,\n  \"seconds\": %.6f,\n  \"status\": \"%s\",\n"
               "  \"interrupted\": %s\n}\n",
            r->res->evals, r->res->seconds,
            r->interrupted ? "interrupted" : fit_status_name(r->res->status),
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

static int parse_count(const char *opt, const char *s, long lo, long *out)
{
    char *e;
    errno = 0;
    long v = strtol(s, &e, 10);
    if (*e || e == s || errno || v < lo) {
        cli_usage_error("fit", "%s: expected an integer >= %ld, got '%s'", opt, lo, s);
        return -1;
    }
    *out = v;
    return 0;
}

static int parse_real(const char *opt, const char *s, double lo, double *out)
{
    char *e;
    errno = 0;
    double v = strtod(s, &e);
    if (*e || e == s || errno || !(v >= lo) || !isfinite(v)) {
        cli_usage_error("fit", "%s: expected a number >= %g, got '%s'", opt, lo, s);
        return -1;
    }
    *out = v;
    return 0;
}

int cmd_fit(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"help", no_argument, NULL, 'h'},
        {"output", required_argument, NULL, 'o'},
        {"in-place", no_argument, NULL, 'I'},
        {"model", required_argument, NULL, 'm'},
        {"method", required_argument, NULL, 'M'},
        {"objective", required_argument, NULL, 'K'},
        {"loss", required_argument, NULL, 'L'},
        {"global-objective", required_argument, NULL, 'G'},
        {"loss-scale", required_argument, NULL, 'S'},
        {"normals-weight", required_argument, NULL, 'W'},
        {"seed", required_argument, NULL, 's'},
        {"max-time", required_argument, NULL, 'T'},
        {"max-evals", required_argument, NULL, 'E'},
        {"sa-points", required_argument, NULL, 'P'},
        {"sa-stall", required_argument, NULL, 'X'},
        {"sa-chains", required_argument, NULL, 'C'},
        {"sa-threshold", required_argument, NULL, 'H'},
        {"json", required_argument, NULL, 'J'},
        {"threads", required_argument, NULL, 't'},
        {"params", required_argument, NULL, 'a'},
        {"bounds", required_argument, NULL, 'B'},
        {"quiet", no_argument, NULL, 'q'},
        {NULL, 0, NULL, 0},
    };
    fit_config cfg;
    fit_config_init(&cfg);
    const char *out = NULL, *model = NULL, *json = NULL, *bounds = NULL;
    double *a = NULL, loss_scale = -1;
    size_t na = 0;
    int in_place = 0, quiet = 0, c;
    long lv;
    double dv;
    int rc = CLI_OK;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "ho:m:t:a:q", longopts, NULL)) != -1) {
        int bad = 0;
        switch (c) {
        case 'h': fputs(fit_usage, stdout); free(a); return CLI_OK;
        case 'o': out = optarg; break;
        case 'I': in_place = 1; break;
        case 'm': model = optarg; break;
        case 'M':
            if (fit_method_parse(optarg, &cfg.method) != 0)
                bad = cli_usage_error("fit", "--method: expected saqn, qn, sa or lm, got '%s'", optarg);
            break;
        case 'K':
            if (fit_objective_parse(optarg, &cfg.obj.kind) != 0)
                bad = cli_usage_error("fit", "--objective: expected algebraic or geometric, got '%s'", optarg);
            break;
        case 'G':
            if (fit_objective_parse(optarg, &cfg.global_kind) != 0)
                bad = cli_usage_error("fit", "--global-objective: expected algebraic or geometric, got '%s'", optarg);
            break;
        case 'L':
            if (fit_loss_parse(optarg, &cfg.obj.loss) != 0)
                bad = cli_usage_error("fit", "--loss: expected l2, huber or cauchy, got '%s'", optarg);
            break;
        case 'S':
            if (parse_real("--loss-scale", optarg, 0, &loss_scale) || !(loss_scale > 0))
                bad = loss_scale > 0 ? CLI_USAGE : cli_usage_error("fit", "--loss-scale must be > 0");
            break;
        case 'W':
            if (parse_real("--normals-weight", optarg, 0, &cfg.obj.normals_weight)) bad = CLI_USAGE;
            break;
        case 's': {
            char *e;
            errno = 0;
            cfg.seed = strtoull(optarg, &e, 10);
            if (*e || e == optarg || errno || optarg[0] == '-')
                bad = cli_usage_error("fit", "--seed: expected a non-negative integer, got '%s'", optarg);
            break;
        }
        case 'T':
            if (parse_real("--max-time", optarg, 0, &cfg.max_time)) bad = CLI_USAGE;
            break;
        case 'E':
            if (parse_count("--max-evals", optarg, 1, &cfg.max_evals)) bad = CLI_USAGE;
            break;
        case 'P':
            if (parse_count("--sa-points", optarg, 0, &lv)) bad = CLI_USAGE;
            else cfg.sa_points = (size_t)lv;
            break;
        case 'X':
            if (parse_count("--sa-stall", optarg, 1, &cfg.sa.stall_iter)) bad = CLI_USAGE;
            break;
        case 'C':
            if (parse_count("--sa-chains", optarg, 1, &cfg.sa.chains)) bad = CLI_USAGE;
            break;
        case 'H':
            if (parse_real("--sa-threshold", optarg, 0, &dv)) bad = CLI_USAGE;
            else cfg.sa.threshold = dv;
            break;
        case 'J': json = optarg; break;
        case 't':
            if (parse_count("--threads", optarg, 1, &lv)) bad = CLI_USAGE;
            else cfg.obj.nthreads = (int)(lv > 1024 ? 1024 : lv);
            break;
        case 'a':
            free(a);
            a = cli_parse_list("-a", optarg, &na);
            if (a == NULL) bad = CLI_USAGE;
            break;
        case 'B': bounds = optarg; break;
        case 'q': quiet = 1; break;
        default:
            bad = cli_usage_error("fit", "unknown or incomplete option '%s'", argv[optind - 1]);
        }
        if (bad) {
            free(a);
            return CLI_USAGE;
        }
    }
    if (argc - optind != 2) {
        free(a);
        return cli_usage_error("fit", "expected TEMPLATE.hf and CLOUD");
    }
    if (out != NULL && in_place) {
        free(a);
        return cli_usage_error("fit", "-o and --in-place exclude each other");
    }
    const char *tmpl = argv[optind], *cloud_path = argv[optind + 1];

    char *src = NULL, *output = NULL, *text = NULL;
    double *blo = NULL, *bhi = NULL, *x0 = NULL, *lo = NULL, *hi = NULL, *base = NULL;
    size_t *idx = NULL;
    param_row *rows = NULL;
    frep_cloud *cloud = NULL;
    fit_model fm = {0};
    size_t nb = 0;

    frep_program *p = cli_compile_file(tmpl, model, a, na, -1, &src);
    if (p == NULL) {
        rc = CLI_FAIL;
        goto done;
    }
    size_t nall = frep_program_nparams(p), nfree = 0, nnamed = 0;
    for (size_t i = 0; i < nall; i++) nnamed += p->params[i].end > p->params[i].off;
    rows = calloc(nall ? nall : 1, sizeof *rows);
    idx = malloc((nall ? nall : 1) * sizeof *idx);
    base = malloc((nall ? nall : 1) * sizeof *base);
    x0 = malloc((nall ? nall : 1) * sizeof *x0);
    lo = malloc((nall ? nall : 1) * sizeof *lo);
    hi = malloc((nall ? nall : 1) * sizeof *hi);
    if (!rows || !idx || !base || !x0 || !lo || !hi) {
        fprintf(stderr, "frep fit: out of memory\n");
        rc = CLI_FAIL;
        goto done;
    }
    if (bounds != NULL) {
        nb = parse_bounds(bounds, &blo, &bhi);
        if (nb == 0) {
            rc = CLI_USAGE;
            goto done;
        }
        if (nnamed > 0) {
            fprintf(stderr, "frep fit: --bounds is for templates fitted through a[]; %s has "
                            "'-- @free' parameters, whose bounds are in the template\n", tmpl);
            rc = CLI_USAGE;
            goto done;
        }
    }
    for (size_t i = 0; i < nall; i++) {
        const frep_param_info *pi = &p->params[i];
        base[i] = pi->value;
        int named = pi->end > pi->off;
        if (nnamed > 0 ? !named : named) continue;
        /* An a[] element the code never reads is not something to fit. */
        int used = named;
        for (uint32_t k = 0; k < p->ncode && !used; k++)
            used = p->code[k].op == FREP_OP_PARAM && p->code[k].arg == i;
        if (!used) continue;
        param_row *r = &rows[nfree];
        r->name = pi->name;
        r->index = i;
        r->start = r->value = pi->value;
        r->lo = pi->lo, r->hi = pi->hi;
        r->has_span = named;
        r->off = pi->off, r->end = pi->end;
        if (!named && nb > 0) {
            if (nb != nall) {
                fprintf(stderr, "frep fit: --bounds gives %zu ranges; the template's a[] has %zu "
                                "elements\n", nb, nall);
                rc = CLI_USAGE;
                goto done;
            }
            r->lo = blo[i], r->hi = bhi[i];
        }
        idx[nfree++] = i;
    }
    if (nfree == 0) {
        fprintf(stderr, "%s: error: the template has no free parameters: mark values with "
                        "'-- @free [lo, hi]' or use an a[] array\n", tmpl);
        rc = CLI_FAIL;
        goto done;
    }
    if (nnamed == 0 && na != 0 && na != nall)
        fprintf(stderr, "frep fit: note: -a gives %zu values for the %zu elements of a[]; the "
                        "others start at 0\n", na, nall);
    for (size_t j = 0; j < nfree; j++) {
        if (rows[j].start < rows[j].lo || rows[j].start > rows[j].hi) {
            fprintf(stderr, "%s: error: parameter %s starts at %g, outside its bounds [%g, %g]\n",
                    tmpl, rows[j].name, rows[j].start, rows[j].lo, rows[j].hi);
            rc = CLI_FAIL;
            goto done;
        }
    }

    frep_error cerr;
    cloud = cloud_read(cloud_path, &cerr);
    if (cloud == NULL) {
        fprintf(stderr, "%s\n", cerr.msg[0] ? cerr.msg : "frep fit: cannot read the cloud");
        rc = CLI_FAIL;
        goto done;
    }
    for (size_t i = 0; i < cloud->n; i++) {
        if (!isfinite(cloud->x[i]) || !isfinite(cloud->y[i]) || !isfinite(cloud->z[i]) ||
            (cloud->has_normals && (!isfinite(cloud->nx[i]) || !isfinite(cloud->ny[i]) ||
                                    !isfinite(cloud->nz[i])))) {
            fprintf(stderr, "%s: point %zu is not finite (NaN or infinity)\n", cloud_path, i + 1);
            rc = CLI_FAIL;
            goto done;
        }
    }
    if (cloud->n < nfree + FIT_MIN_POINTS) {
        fprintf(stderr, "%s: %zu points are too few to fit %zu parameters (need at least %zu)\n",
                cloud_path, cloud->n, nfree, nfree + FIT_MIN_POINTS);
        rc = CLI_FAIL;
        goto done;
    }
    if (cfg.obj.normals_weight > 0 && !cloud->has_normals) {
        fprintf(stderr, "frep fit: --normals-weight needs a cloud with normals; %s has none\n",
                cloud_path);
        rc = CLI_USAGE;
        goto done;
    }
    if (cloud->has_normals) cloud_normalize_normals(cloud);
    double diagonal = cloud_diagonal(cloud);
    cfg.obj.loss_scale = loss_scale > 0 ? loss_scale : 0.01 * (diagonal > 0 ? diagonal : 1);

    /* The annealing needs a finite box: an unbounded parameter searches its start plus
     * or minus the cloud's diagonal. */
    int global = cfg.method == FIT_METHOD_SAQN || cfg.method == FIT_METHOD_SA;
    for (size_t j = 0; j < nfree; j++) {
        lo[j] = rows[j].lo, hi[j] = rows[j].hi;
        x0[j] = rows[j].start;
        if (global && (!isfinite(lo[j]) || !isfinite(hi[j]))) {
            double d = diagonal > 0 ? diagonal : 1;
            if (!isfinite(lo[j])) lo[j] = x0[j] - d;
            if (!isfinite(hi[j])) hi[j] = x0[j] + d;
            if (!quiet)
                fprintf(stderr, "frep fit: note: %s has no bounds; the annealing searches "
                                "[%g, %g]\n", rows[j].name, lo[j], hi[j]);
        }
    }

    if (fit_program_model(p, idx, nfree, base, &fm) != 0) {
        fprintf(stderr, "frep fit: out of memory\n");
        rc = CLI_FAIL;
        goto done;
    }
    fit_points pts = {cloud->n, cloud->x, cloud->y, cloud->z, NULL, NULL, NULL};
    if (cloud->has_normals) pts.nx = cloud->nx, pts.ny = cloud->ny, pts.nz = cloud->nz;
    fit_interrupted = 0;
    cfg.interrupt = &fit_interrupted;
    int tty = isatty(STDERR_FILENO) && !quiet;
    if (tty) cfg.progress = progress;
    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_sigint;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old);
    fit_result res;
    char err[256];
    int frc = fit_run(&fm, &pts, lo, hi, x0, &cfg, &res, err, sizeof err);
    sigaction(SIGINT, &old, NULL);
    if (tty) fputs("\r\033[K", stderr);
    if (frc != 0) {
        fprintf(stderr, "%s: error: %s\n", tmpl, err);
        rc = CLI_FAIL;
        goto done;
    }
    int interrupted = fit_interrupted != 0;

    /* The fitted template. */
    fit_edit *edits = malloc(nfree * sizeof *edits);
    size_t ne = 0;
    char *note = NULL;
    if (edits == NULL) {
        rc = CLI_FAIL;
        goto done;
    }
    for (size_t j = 0; j < nfree; j++) {
        rows[j].value = x0[j];
        if (rows[j].has_span)
            edits[ne++] = (fit_edit){rows[j].off, rows[j].end, x0[j], rows[j].lo, rows[j].hi};
    }
    if (nnamed == 0) {
        /* a[] templates keep their text; the values go into a comment for -a. */
        size_t cap = 32 + nfree * FIT_NUMBER_MAX, m;
        note = malloc(cap);
        if (note != NULL) {
            m = (size_t)snprintf(note, cap, "-- fitted: -a ");
            for (size_t j = 0; j < nfree; j++) {
                char num[FIT_NUMBER_MAX];
                fit_format_number(num, x0[j], rows[j].lo, rows[j].hi);
                m += (size_t)snprintf(note + m, cap - m, "%s%s", j ? "," : "", num);
            }
        }
    }
    double blo3[3], bhi3[3], box[6];
    cloud_bbox(cloud, blo3, bhi3);
    double margin = FIT_BOX_MARGIN * (diagonal > 0 ? diagonal : 1);
    for (int k = 0; k < 3; k++) box[k] = blo3[k] - margin, box[3 + k] = bhi3[k] + margin;
    size_t tlen = 0;
    text = fit_writeback(src, strlen(src), edits, ne, box, note, &tlen);
    free(edits);
    free(note);
    if (text == NULL) {
        fprintf(stderr, "frep fit: cannot rewrite the template (out of memory)\n");
        rc = CLI_FAIL;
        goto done;
    }
    output = in_place ? strdup(tmpl) : out != NULL ? strdup(out) : derived_name(tmpl);
    text_out to = {text, tlen};
    if (output == NULL || cli_write_atomic(output, write_text, &to) != 0) {
        rc = CLI_FAIL;
        goto done;
    }
    report_ctx rep = {tmpl, cloud_path, output, rows, nfree, cloud->n, &cfg, &res, diagonal,
                      interrupted};
    if (json != NULL && cli_write_atomic(json, write_json, &rep) != 0) rc = CLI_FAIL;

    if (!quiet) {
        printf("frep fit: %s <- %s (%zu points%s)\n", tmpl, cloud_path, cloud->n,
               cloud->has_normals ? ", with normals" : "");
        printf("method %s, objective %s (annealing: %s), loss %s, seed %llu\n",
               fit_method_name(cfg.method), fit_objective_name(cfg.obj.kind),
               fit_objective_name(cfg.global_kind), fit_loss_name(cfg.obj.loss),
               (unsigned long long)cfg.seed);
        if (cfg.method == FIT_METHOD_SAQN || cfg.method == FIT_METHOD_SA)
            printf("annealing: %ld chain%s on %zu points, stall %ld\n", cfg.sa.chains,
                   cfg.sa.chains == 1 ? "" : "s",
                   cfg.sa_points > 0 && cfg.sa_points < pts.n ? cfg.sa_points : pts.n,
                   cfg.sa.stall_iter);
        printf("%-12s %16s %18s   %s\n", "parameter", "start", "fitted", "bounds");
        for (size_t j = 0; j < nfree; j++)
            printf("%-12s %16.10g %18.12g   [%g, %g]\n", rows[j].name, rows[j].start,
                   rows[j].value, rows[j].lo, rows[j].hi);
        printf("objective %.6g\n", res.objective);
        printf("distance rms %.6g, max %.6g (cloud diagonal %.6g)\n", res.rms, res.max_dist,
               diagonal);
        printf("evaluations %ld, time %.3f s, %s\n", res.evals, res.seconds,
               interrupted ? "interrupted: best so far" : fit_status_name(res.status));
        printf("wrote %s\n", output);
    }
    if (interrupted && rc == CLI_OK) rc = 130;

done:
    if (fm.user != NULL) fit_program_model_free(&fm);
    cloud_free(cloud);
    free(text);
    free(output);
    free(rows);
    free(idx);
    free(base);
    free(x0);
    free(lo);
    free(hi);
    free(blo);
    free(bhi);
    free(src);
    free(a);
    if (p != NULL) frep_program_free(p);
    return rc;
}

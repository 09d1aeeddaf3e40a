/* opt.c - the option layer of the frep command (opt.h): one parser for every
 * subcommand's option table, its value checks and messages, and --help from the table.
 */
#include "config.h"

#include "cli.h"
#include "opt.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef HAVE_SYS_RESOURCE_H
#include <sys/resource.h>
#endif

/* getopt_long's value of a long-only option: past every char, so never a short name. */
#define CLI_LONG_ONLY_BASE 256
/* Room for a reason of a value parser ("the box has no extent along x: [..]"). */
#define CLI_WHY_MAX 256
/* getopt_long's value of --max-memory, an option of every subcommand (like --help). */
#define CLI_MAX_MEMORY (CLI_LONG_ONLY_BASE - 1)
/* The smallest --max-memory: what frep needs to start a command at all (the program's
 * tables, a thread's buffers); below it every command would fail at once. */
#define CLI_MIN_MEMORY (16.0 * 1024 * 1024)
/* --max-memory's help, listed after the subcommand's own options. */
#define CLI_MAX_MEMORY_HELP                                                              \
    "cap the memory frep allocates (K, M, G, T: binary\n"                                 \
    "units; 1.5G); past it the command stops with 'out of\n"                             \
    "memory' and a non-zero exit, outputs untouched"

void cli_list_free(cli_list *l)
{
    free(l->v);
    l->v = NULL;
    l->n = 0;
}

/* "v1,v2,..." -> malloc'ed numbers; NULL with a reason when malformed or out of memory. */
static double *parse_numbers(const char *s, size_t *n, char *why, size_t whylen)
{
    size_t cap = 8, k = 0;
    double *v = malloc(cap * sizeof *v);
    const char *p = s;
    while (v) {
        char *end;
        errno = 0;
        double d = strtod(p, &end);
        if (end == p || errno == ERANGE || !isfinite(d) || (*end && *end != ',')) {
            snprintf(why, whylen, "expected comma-separated numbers, got '%s'", s);
            free(v);
            return NULL;
        }
        if (k == cap) {
            cap *= 2;
            double *nv = realloc(v, cap * sizeof *v);
            if (!nv) break;
            v = nv;
        }
        v[k++] = d;
        if (!*end) {
            *n = k;
            return v;
        }
        p = end + 1;
    }
    free(v);
    snprintf(why, whylen, "out of memory");
    return NULL;
}

/* HyperFun's -b conventions: 1 number -> [-v,v]^3; 2 -> [lo,hi]^3; 3 -> [-a,a]x[-b,b]x
 * [-c,c]; 6 -> xlo,ylo,zlo,xhi,yhi,zhi. Every axis must have an extent. */
int cli_opt_box(const char *arg, void *dest, char *why, size_t whylen)
{
    double *box = dest;
    size_t n = 0;
    double *v = parse_numbers(arg, &n, why, whylen);
    if (!v) return -1;
    int ok = 1;
    switch (n) {
    case 1:
        for (int i = 0; i < 3; i++) { box[i] = -fabs(v[0]); box[i + 3] = fabs(v[0]); }
        break;
    case 2:
        for (int i = 0; i < 3; i++) { box[i] = v[0]; box[i + 3] = v[1]; }
        break;
    case 3:
        for (int i = 0; i < 3; i++) { box[i] = -fabs(v[i]); box[i + 3] = fabs(v[i]); }
        break;
    case 6:
        for (int i = 0; i < 6; i++) box[i] = v[i];
        break;
    default:
        snprintf(why, whylen, "expected 1, 2, 3 or 6 numbers, got %zu", n);
        ok = 0;
    }
    free(v);
    for (int i = 0; ok && i < 3; i++) {
        if (!(box[i] < box[i + 3])) {
            /* + 0.0 prints -b 0's lower bound -0 as 0 */
            snprintf(why, whylen, "the box has no extent along %c: [%g, %g]", "xyz"[i],
                     box[i] + 0.0, box[i + 3] + 0.0);
            ok = 0;
        }
    }
    return ok ? 0 : -1;
}

int cli_opt_setops(const char *arg, void *dest, char *why, size_t whylen)
{
    int *setops = dest;
    if (strcmp(arg, "rfunc") == 0) *setops = FREP_SETOPS_RFUNC;
    else if (strcmp(arg, "minmax") == 0) *setops = FREP_SETOPS_MINMAX;
    else return -1;
    return 0;
}

/* The largest value a numeric destination holds. */
static double kind_max(cli_opt_kind k)
{
    switch (k) {
    case CLI_OPT_INT: return (double)INT32_MAX;
    case CLI_OPT_U32: return (double)UINT32_MAX;
    case CLI_OPT_LONG:
    case CLI_OPT_SIZE: return 9007199254740992.0; /* 2^53: every integer below is exact */
    case CLI_OPT_SET:
    case CLI_OPT_CLEAR:
    case CLI_OPT_DOUBLE:
    case CLI_OPT_SEED:
    case CLI_OPT_STRING:
    case CLI_OPT_LIST:
    case CLI_OPT_CUSTOM: break;
    }
    return INFINITY;
}

/* "expected an integer in 1..1024" and the like, from the entry's range. */
static void range_text(const cli_opt *o, char *s, size_t len)
{
    int integer = o->kind != CLI_OPT_DOUBLE;
    const char *what = o->what ? o->what : integer ? "an integer" : "a number";
    if (integer && isfinite(o->hi))
        snprintf(s, len, "expected %s in %.0f..%.0f", what, o->lo, o->hi);
    else if (isfinite(o->lo) && isfinite(o->hi))
        snprintf(s, len, "expected %s in %c%g, %g]", what, o->open_lo ? '(' : '[', o->lo, o->hi);
    else if (isfinite(o->lo))
        snprintf(s, len, "expected %s %s %.*g", what, o->open_lo ? ">" : ">=", integer ? 17 : 6,
                 o->lo);
    else
        snprintf(s, len, "expected %s", what);
}

static int parse_number(const cli_opt *o, const char *arg, void *dest, char *why, size_t whylen)
{
    char *end;
    errno = 0;
    double v = strtod(arg, &end);
    int integer = o->kind != CLI_OPT_DOUBLE;
    if (end == arg || *end || errno || !isfinite(v) || (integer && v != floor(v)) ||
        !(o->open_lo ? v > o->lo : v >= o->lo) || !(v <= o->hi) || !(v <= kind_max(o->kind))) {
        char range[128];
        range_text(o, range, sizeof range);
        snprintf(why, whylen, "%s, got '%s'%s", range, arg,
                 o->above && end != arg && !*end && v > o->hi ? o->above : "");
        return -1;
    }
    switch (o->kind) {
    case CLI_OPT_INT: *(int *)dest = (int)v; break;
    case CLI_OPT_LONG: *(long *)dest = (long)v; break;
    case CLI_OPT_U32: *(uint32_t *)dest = (uint32_t)v; break;
    case CLI_OPT_SIZE: *(size_t *)dest = (size_t)v; break;
    case CLI_OPT_DOUBLE: *(double *)dest = v; break;
    case CLI_OPT_SET:
    case CLI_OPT_CLEAR:
    case CLI_OPT_SEED:
    case CLI_OPT_STRING:
    case CLI_OPT_LIST:
    case CLI_OPT_CUSTOM: break;
    }
    return 0;
}

/* A seed: decimal digits only (no sign, no space), within 64 bits. */
static int parse_seed(const char *arg, uint64_t *seed, char *why, size_t whylen)
{
    char *end;
    errno = 0;
    unsigned long long v = strtoull(arg, &end, 10);
    if (!(*arg >= '0' && *arg <= '9') || *end || errno) {
        snprintf(why, whylen, "expected a non-negative integer, got '%s'", arg);
        return -1;
    }
    *seed = (uint64_t)v;
    return 0;
}

/* Store one option's value. Returns 0, or -1 with the reason in why. */
static int store(const cli_opt *o, const char *arg, void *ctx, char *why, size_t whylen)
{
    void *dest = (char *)ctx + o->off;
    switch (o->kind) {
    case CLI_OPT_SET: *(int *)dest = 1; return 0;
    case CLI_OPT_CLEAR: *(int *)dest = 0; return 0;
    case CLI_OPT_STRING: *(const char **)dest = arg; return 0;
    case CLI_OPT_SEED: return parse_seed(arg, dest, why, whylen);
    case CLI_OPT_LIST: {
        cli_list *l = dest;
        cli_list_free(l);
        l->v = parse_numbers(arg, &l->n, why, whylen);
        return l->v ? 0 : -1;
    }
    case CLI_OPT_CUSTOM:
        if (o->parse(arg, dest, why, whylen) == 0) return 0;
        if (!why[0]) snprintf(why, whylen, "expected %s, got '%s'", o->expect, arg);
        return -1;
    case CLI_OPT_INT:
    case CLI_OPT_LONG:
    case CLI_OPT_U32:
    case CLI_OPT_SIZE:
    case CLI_OPT_DOUBLE: return parse_number(o, arg, dest, why, whylen);
    }
    return -1;
}

/* "SIZE[K|M|G|T][i][B]" (binary units) -> bytes; -1 with a reason when malformed. */
static int parse_memory(const char *arg, double *bytes, char *why, size_t whylen)
{
    char *end;
    errno = 0;
    double v = strtod(arg, &end);
    double unit = 1;
    const char *units = "KMGT";
    const char *u = *end ? strchr(units, *end & ~0x20) : NULL;
    if (u) {
        for (const char *k = units; k <= u; k++) unit *= 1024;
        end++;
        if (*end == 'i') end++;
    }
    if (*end == 'B' || *end == 'b') end++;
    if (end == arg || *end || errno == ERANGE || !isfinite(v) || v <= 0) {
        snprintf(why, whylen, "expected a size (bytes, or with K, M, G, T), got '%s'", arg);
        return -1;
    }
    *bytes = v * unit;
    if (*bytes < CLI_MIN_MEMORY) {
        snprintf(why, whylen, "expected at least 16M, got '%s' (too little to run at all)",
                 arg);
        return -1;
    }
    return 0;
}

/* --max-memory: the data segment's limit (RLIMIT_DATA: the heap and private anonymous
 * mappings: what frep allocates, its worker threads' stacks included, not the
 * program's code), so that an allocation past it fails and the command reports out of
 * memory where otherwise the system would kill it. */
static int apply_max_memory(double bytes, char *why, size_t whylen)
{
#if defined(HAVE_SYS_RESOURCE_H) && defined(RLIMIT_DATA)
    struct rlimit rl;
    if (getrlimit(RLIMIT_DATA, &rl) != 0) rl.rlim_max = RLIM_INFINITY;
    rlim_t want = bytes >= (double)RLIM_INFINITY ? RLIM_INFINITY : (rlim_t)bytes;
    if (rl.rlim_max != RLIM_INFINITY && want > rl.rlim_max) want = rl.rlim_max;
    rl.rlim_cur = want;
    if (setrlimit(RLIMIT_DATA, &rl) == 0) return 0;
    snprintf(why, whylen, "cannot set the limit: %s", strerror(errno));
#else
    (void)bytes;
    snprintf(why, whylen, "not supported on this system");
#endif
    return -1;
}

/* The getopt_long tables of a spec: --help and --max-memory first, then the entries. */
typedef struct getopt_tables {
    struct option longopts[CLI_MAX_OPTS + 3];
    char shortopts[2 * CLI_MAX_OPTS + 4];
} getopt_tables;

static void build_tables(const cli_opt_spec *spec, getopt_tables *t)
{
    size_t k = 0, s = 0;
    t->shortopts[s++] = ':'; /* a missing value returns ':', an unknown option '?' */
    t->shortopts[s++] = 'h';
    t->longopts[k++] = (struct option){ "help", no_argument, NULL, 'h' };
    t->longopts[k++] = (struct option){ "max-memory", required_argument, NULL, CLI_MAX_MEMORY };
    for (size_t i = 0; i < spec->nopts; i++) {
        const cli_opt *o = &spec->opts[i];
        int val = o->short_name ? o->short_name : CLI_LONG_ONLY_BASE + (int)i;
        t->longopts[k++] = (struct option){ o->name, o->arg ? required_argument : no_argument,
                                            NULL, val };
        if (o->short_name) {
            t->shortopts[s++] = o->short_name;
            if (o->arg) t->shortopts[s++] = ':';
        }
    }
    t->longopts[k] = (struct option){ NULL, 0, NULL, 0 };
    t->shortopts[s] = '\0';
}

static size_t entry_of(const cli_opt_spec *spec, int val)
{
    if (val >= CLI_LONG_ONLY_BASE) return (size_t)(val - CLI_LONG_ONLY_BASE);
    for (size_t i = 0; i < spec->nopts; i++)
        if (spec->opts[i].short_name == val) return i;
    return spec->nopts;
}

/* The option as typed, for a message about a bad or missing value or an unknown option:
 * the last argv element getopt_long consumed, or the short option inside a cluster. */
static void typed_option(char **argv, int before, int after, char *s, size_t len)
{
    const char *a = after > before ? argv[after - 1] : NULL;
    if (a && strncmp(a, "--", 2) == 0) snprintf(s, len, "%s", a);
    else snprintf(s, len, "-%c", optopt);
}

/* The name of a given option for a message about its value: as typed, long or short. */
static void value_option(const cli_opt *o, char **argv, int after, char *s, size_t len)
{
    const char *a = argv[after - 1];
    if (optarg == a && after >= 2) a = argv[after - 2];
    if (o->short_name && strncmp(a, "--", 2) != 0) snprintf(s, len, "-%c", o->short_name);
    else snprintf(s, len, "--%s", o->name);
}

static int apply_defaults(const cli_opt_spec *spec, void *ctx)
{
    for (size_t i = 0; i < spec->nopts; i++) {
        char why[CLI_WHY_MAX] = "";
        if (spec->opts[i].def && store(&spec->opts[i], spec->opts[i].def, ctx, why, sizeof why)) {
            fprintf(stderr, "frep %s: bad default of --%s: %s\n", spec->sub, spec->opts[i].name,
                    why);
            return CLI_FAIL;
        }
    }
    return CLI_GO_ON;
}

int cli_opt_parse(const cli_opt_spec *spec, int argc, char **argv, void *ctx, cli_args *args)
{
    memset(args, 0, sizeof *args);
    if (spec->nopts > CLI_MAX_OPTS) return CLI_FAIL;
    int rc = apply_defaults(spec, ctx);
    if (rc != CLI_GO_ON) return rc;
    getopt_tables t;
    build_tables(spec, &t);
    optind = 1;
    opterr = 0;
    for (;;) {
        int before = optind;
        int c = getopt_long(argc, argv, t.shortopts, t.longopts, NULL);
        if (c == -1) break;
        char name[64], why[CLI_WHY_MAX] = "";
        if (c == 'h') {
            cli_opt_help(spec, stdout);
            return CLI_OK;
        }
        if (c == CLI_MAX_MEMORY) {
            double bytes;
            if (parse_memory(optarg, &bytes, why, sizeof why) ||
                apply_max_memory(bytes, why, sizeof why))
                return cli_usage_error(spec->sub, "--max-memory: %s", why);
            continue;
        }
        size_t i = entry_of(spec, c);
        if (c == ':' || c == '?' || i == spec->nopts) {
            typed_option(argv, before, optind, name, sizeof name);
            return cli_usage_error(spec->sub, c == ':' ? "option '%s' needs a value"
                                                       : "unknown option '%s'", name);
        }
        const cli_opt *o = &spec->opts[i];
        args->given[i] = 1;
        if (store(o, optarg, ctx, why, sizeof why) != 0) {
            value_option(o, argv, optind, name, sizeof name);
            return cli_usage_error(spec->sub, "%s: %s", name, why);
        }
    }
    args->n = argc - optind;
    args->v = argv + optind;
    return CLI_GO_ON;
}

int cli_opt_given(const cli_opt_spec *spec, const cli_args *args, const char *name)
{
    for (size_t i = 0; i < spec->nopts; i++)
        if (strcmp(spec->opts[i].name, name) == 0) return args->given[i];
    return 0;
}

/* One option of --help: "  -o, --output FILE" padded to the column (at least two
 * spaces), the help text, its continuation lines indented to the column. */
static void help_entry(const cli_opt *o, int column, FILE *f)
{
    int n;
    if (o->short_name) n = fprintf(f, "  -%c, --%s", o->short_name, o->name);
    else n = fprintf(f, "      --%s", o->name);
    if (o->arg) n += fprintf(f, " %s", o->arg);
    int pad = column - n < 2 ? 2 : column - n;
    fprintf(f, "%*s", pad, "");
    for (const char *p = o->help; *p;) {
        const char *eol = strchr(p, '\n');
        size_t len = eol ? (size_t)(eol - p) : strlen(p);
        fprintf(f, "%.*s\n", (int)len, p);
        if (!eol) break;
        p = eol + 1;
        fprintf(f, "%*s", column, "");
    }
}

void cli_opt_help(const cli_opt_spec *spec, FILE *f)
{
    fputs(spec->usage, f);
    int listed = 0;
    for (size_t i = 0; i < spec->nopts; i++) {
        if (!spec->opts[i].help) continue;
        if (!listed++) fputs("Options:\n", f);
        help_entry(&spec->opts[i], spec->column, f);
    }
    static const cli_opt max_memory = { .name = "max-memory", .arg = "SIZE",
                                        .kind = CLI_OPT_CUSTOM, .help = CLI_MAX_MEMORY_HELP };
    if (!listed) fputs("Options:\n", f);
    help_entry(&max_memory, spec->column, f);
}

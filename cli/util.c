/* util.c - helpers shared by the frep subcommands: reading files, printing
 * diagnostics with carets, atomic output files, usage errors, Ctrl-C.
 */
#include "config.h"

#include "cli.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define CLI_MAX_INPUT_BYTES ((size_t)1 << 30) /* refuse to slurp files over 1 GiB */

char *cli_read_file(const char *path, size_t *len)
{
    FILE *f = strcmp(path, "-") == 0 ? stdin : fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "frep: cannot read %s: %s\n", path, strerror(errno));
        return NULL;
    }
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap + 1);
    while (buf) {
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (n < cap) break;
        if (cap >= CLI_MAX_INPUT_BYTES) {
            fprintf(stderr, "frep: %s: file larger than %zu bytes\n", path, CLI_MAX_INPUT_BYTES);
            free(buf);
            buf = NULL;
            break;
        }
        cap *= 2;
        char *nb = realloc(buf, cap + 1);
        if (!nb) { free(buf); buf = NULL; break; }
        buf = nb;
    }
    int err = f != stdin && ferror(f);
    if (f != stdin) fclose(f);
    if (!buf) {
        if (errno == ENOMEM) fprintf(stderr, "frep: %s: out of memory\n", path);
        return NULL;
    }
    if (err) {
        fprintf(stderr, "frep: cannot read %s\n", path);
        free(buf);
        return NULL;
    }
    buf[n] = '\0';
    if (len) *len = n;
    return buf;
}

#define CLI_MAX_SEEN_DIAGS 4096 /* remembered for de-duplication; later ones just print */

void cli_print_diag(void *user, const frep_diag *d)
{
    cli_diag_ctx *c = user;
    char *s = frep_diag_format(d, c ? c->src : NULL, c ? c->len : 0);
    if (!s) {
        fprintf(stderr, "%s\n", d->message);
        return;
    }
    if (c) {
        for (size_t i = 0; i < c->nseen; i++)
            if (strcmp(c->seen[i], s) == 0) {
                frep_free(s);
                return;
            }
        if (d->severity == FREP_ERROR) c->errors++;
        else if (d->severity == FREP_WARNING) c->warnings++;
    }
    fputs(s, stderr);
    if (c && c->copy) buf_puts(c->copy, s);
    if (c && c->nseen < CLI_MAX_SEEN_DIAGS) {
        char **ns = realloc(c->seen, (c->nseen + 1) * sizeof *ns);
        if (ns) {
            c->seen = ns;
            c->seen[c->nseen++] = s;
            return;
        }
    }
    frep_free(s);
}

void cli_diag_done(cli_diag_ctx *c)
{
    for (size_t i = 0; i < c->nseen; i++) frep_free(c->seen[i]);
    free(c->seen);
    c->seen = NULL;
    c->nseen = 0;
}

frep_program *cli_compile_file(const char *path, const char *model, const double *a,
                               size_t na, int setops, int strict, char **src)
{
    return cli_compile_file_diag(path, model, a, na, setops, strict, src, NULL);
}

frep_program *cli_compile_file_diag(const char *path, const char *model, const double *a,
                                    size_t na, int setops, int strict, char **src,
                                    frep_buf *diag)
{
    size_t len = 0;
    char *text = cli_read_file(path, &len);
    if (!text) return NULL;
    frep_program *p = cli_compile_text(path, text, len, model, a, na, setops, strict, diag);
    if (src && p) *src = text;
    else free(text);
    return p;
}

frep_program *cli_compile_text(const char *path, const char *text, size_t len,
                               const char *model, const double *a, size_t na, int setops,
                               int strict, frep_buf *diag)
{
    frep_compile_options o;
    frep_compile_options_init(&o);
    o.model = model;
    o.a = a;
    o.na = na;
    if (setops >= 0) o.setops_override = setops;
    o.strict = strict;
    cli_diag_ctx dc = { text, len, 0, 0, NULL, 0, diag };
    frep_program *p = frep_compile(path, text, len, &o, cli_print_diag, &dc);
    cli_diag_done(&dc);
    return p;
}

int cli_write_atomic(const char *path, int (*fn)(FILE *f, void *user), void *user)
{
    if (strcmp(path, "-") == 0) {
        int r = fn(stdout, user);
        return fflush(stdout) == 0 ? r : -1;
    }
    size_t n = strlen(path);
    char *tmp = malloc(n + 32);
    if (!tmp) return -1;
    snprintf(tmp, n + 32, "%s.tmp%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        fprintf(stderr, "frep: cannot write %s: %s\n", path, strerror(errno));
        free(tmp);
        return -1;
    }
    int r = fn(f, user);
    if (fflush(f) != 0 || ferror(f)) r = -1;
    if (fclose(f) != 0) r = -1;
    if (r == 0 && rename(tmp, path) != 0) {
        fprintf(stderr, "frep: cannot write %s: %s\n", path, strerror(errno));
        r = -1;
    }
    if (r != 0) {
        remove(tmp);
        if (r != -2) fprintf(stderr, "frep: %s not written\n", path);
    }
    free(tmp);
    return r == 0 ? 0 : -1;
}

int cli_usage_error(const char *sub, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "frep %s: ", sub);
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\nTry 'frep %s --help'.\n", sub);
    va_end(ap);
    return CLI_USAGE;
}

/* Set by the SIGINT handler, read by the library through cli_sigint_catch()'s pointer. */
static volatile sig_atomic_t cli_sigint_flag;
static struct sigaction cli_sigint_old;

static void on_sigint(int sig)
{
    (void)sig;
    cli_sigint_flag = 1;
}

volatile sig_atomic_t *cli_sigint_catch(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_sigint;
    sa.sa_flags = SA_RESTART;
    sigemptyset(&sa.sa_mask);
    cli_sigint_flag = 0;
    sigaction(SIGINT, &sa, &cli_sigint_old);
    return &cli_sigint_flag;
}

void cli_sigint_restore(void)
{
    sigaction(SIGINT, &cli_sigint_old, NULL);
}

int cli_interrupted(void)
{
    return cli_sigint_flag != 0;
}

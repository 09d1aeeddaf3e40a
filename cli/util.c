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
#include <sys/stat.h>
#include <sys/time.h>

#ifdef _OPENMP
#include <omp.h>
#endif
#include <time.h>
#include <unistd.h>

/* The signal helper's state (below, "The one signal helper"). */
static volatile sig_atomic_t cli_signal_flag;   /* the signal number, 0 before any */
static volatile sig_atomic_t cli_signal_polled; /* 1: the first signal only sets the flag */
static volatile sig_atomic_t cli_tmp_live;      /* 1: cli_tmp_path names a file to remove */
static volatile sig_atomic_t cli_stop_flag;     /* 1: stop: a polled signal or the deadline */
static volatile sig_atomic_t cli_deadline_hit;  /* 1: the deadline (SIGALRM) passed */
static char cli_tmp_path[CLI_MAX_TMP_PATH];

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

void cli_library_diag(const char *sub, const frep_diag *d)
{
    const char *kind = d->severity == FREP_WARNING ? "warning: "
                       : d->severity == FREP_NOTE  ? "note: "
                                                   : "";
    fprintf(stderr, "frep %s: %s%s\n", sub, kind, d->message);
}

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
    if (c && c->copy) cli_text_puts(c->copy, s);
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

/* Room for n more bytes and the NUL; 0, or -1 (nothing changed). */
static int text_reserve(cli_text *t, size_t n)
{
    if (t->len + n + 1 <= t->cap) return 0;
    size_t cap = t->cap ? t->cap : 256;
    while (cap < t->len + n + 1) cap *= 2;
    char *s = realloc(t->s, cap);
    if (!s) return -1;
    t->s = s;
    t->cap = cap;
    return 0;
}

void cli_text_puts(cli_text *t, const char *s)
{
    size_t n = strlen(s);
    if (text_reserve(t, n) != 0) return;
    memcpy(t->s + t->len, s, n + 1);
    t->len += n;
}

void cli_text_printf(cli_text *t, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0 || text_reserve(t, (size_t)n) != 0) return;
    va_start(ap, fmt);
    vsnprintf(t->s + t->len, (size_t)n + 1, fmt, ap);
    va_end(ap);
    t->len += (size_t)n;
}

void cli_text_free(cli_text *t)
{
    free(t->s);
    *t = (cli_text)CLI_TEXT_INIT;
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
                                    cli_text *diag)
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
                               int strict, cli_text *diag)
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
    if (p && frep_program_set_work_limit(p, CLI_DEFAULT_MAX_WORK) != 0) {
        fprintf(stderr, "frep: out of memory\n");
        frep_program_free(p);
        return NULL;
    }
    return p;
}

int cli_work_limit(frep_program *p, size_t max_work)
{
    if (max_work == 0 || frep_program_set_work_limit(p, max_work) == 0) return CLI_OK;
    fprintf(stderr, "frep: out of memory\n");
    return CLI_FAIL;
}

int cli_work_check(const char *sub, const char *path, const frep_program *p)
{
    if (!frep_program_work_spent(p)) return CLI_OK;
    fprintf(stderr,
            "frep %s: %s%sthe model's loops ran over the work budget of %llu iterations "
            "(summed over the points): evaluation stopped, nothing written; --max-work N "
            "raises it\n",
            sub, path ? path : "", path ? ": " : "",
            (unsigned long long)frep_program_work_limit(p));
    return CLI_FAIL;
}

/* 1 once a write error on standard output was reported (said once per process). */
static int cli_stdout_reported;

/* "frep: cannot write WHAT: reason" with errno's reason when there is one. */
static void write_failed(const char *what, int err)
{
    if (strcmp(what, "standard output") == 0) {
        if (cli_stdout_reported) return;
        cli_stdout_reported = 1;
    }
    if (err) fprintf(stderr, "frep: cannot write %s: %s\n", what, strerror(err));
    else fprintf(stderr, "frep: cannot write %s\n", what);
}

/* The stream buffer of a written file: the writers hand stdio records of tens of
 * bytes (text) or batches of tens of kilobytes (binary STL); through the default 4 KiB
 * buffer a 20 MB mesh took 3200 write calls, through this one 80. */
#define CLI_WRITE_BUFFER ((size_t)256 << 10)

int cli_write_atomic(const char *path, int (*fn)(FILE *f, void *user), void *user)
{
    if (strcmp(path, "-") == 0) {
        errno = 0;
        int r = fn(stdout, user);
        int err = errno;
        if (fflush(stdout) != 0) err = errno;
        else if (!ferror(stdout) && r == 0) return 0;
        if (r != -2) write_failed("standard output", err);
        return -1;
    }
    /* An existing output that is no regular file (a device such as /dev/null, a FIFO)
     * is written in place: a temporary renamed over it would replace the device or the
     * pipe with a plain file. */
    struct stat st;
    int in_place = stat(path, &st) == 0 && !S_ISREG(st.st_mode);
    size_t n = strlen(path);
    if (n + 32 > sizeof cli_tmp_path) {
        fprintf(stderr, "frep: cannot write %s: the name is too long\n", path);
        return -1;
    }
    char *tmp = malloc(n + 32);
    if (!tmp) return -1;
    if (in_place) memcpy(tmp, path, n + 1);
    else snprintf(tmp, n + 32, "%s.tmp%ld", path, (long)getpid());
    /* published to the signal handler before the file exists */
    memcpy(cli_tmp_path, tmp, strlen(tmp) + 1);
    cli_tmp_live = !in_place;
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        cli_tmp_live = 0;
        write_failed(path, errno);
        free(tmp);
        return -1;
    }
    /* without it, stdio's own buffer: slower, not wrong */
    char *buf = malloc(CLI_WRITE_BUFFER);
    if (buf) setvbuf(f, buf, _IOFBF, CLI_WRITE_BUFFER);
    errno = 0;
    int r = fn(f, user);
    int err = r ? errno : 0;
    if (fflush(f) != 0 || ferror(f)) {
        if (r == 0 || !err) err = errno;
        r = r ? r : -1;
    }
    if (fclose(f) != 0) {
        if (r == 0) err = errno;
        r = r ? r : -1;
    }
    free(buf);
    if (r == 0 && !in_place && rename(tmp, path) != 0) {
        write_failed(path, errno);
        r = -2;
    }
    if (r != 0 && !in_place) remove(tmp);
    cli_tmp_live = 0;
    if (r == -1) write_failed(path, err);
    free(tmp);
    return r == 0 ? 0 : -1;
}

typedef struct cloud_out {
    const frep_cloud *c;
    const char *name;   /* the output's name: its format */
} cloud_out;

static int write_cloud(FILE *f, void *user)
{
    const cloud_out *o = user;
    return frep_cloud_write_stream(o->c, f, o->name);
}

int cli_write_cloud(const char *path, const frep_cloud *c)
{
    cloud_out co = { c, path };
    return cli_write_atomic(path, write_cloud, &co);
}

int cli_stdout_close(void)
{
    errno = 0;
    int bad = ferror(stdout);
    if (fflush(stdout) != 0) bad = 1;
    if (!bad) return 0;
    write_failed("standard output", errno);
    return -1;
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

/* The one signal helper of frep: SIGINT, SIGTERM and SIGHUP.
 *
 * Its state is the one piece of global mutable state frep allows (a signal handler can
 * reach nothing else), all of it sig_atomic_t or written before it is published:
 * - polled: a command asked for the flag (cli_sigint_catch): the first signal only sets
 *   the flag, the library stops at its next poll and the command writes what it has;
 * - otherwise, and at the second signal, the handler removes the temporary file of the
 *   write in progress (cli_write_atomic) and ends the process at once with 128 + the
 *   signal (130 for Ctrl-C): an existing output file is never touched.
 * Only async-signal-safe calls (unlink, write, _exit) are made in the handler. Its
 * state is declared at the top of the file (cli_write_atomic publishes its temporary). */

static void signal_say(const char *s)
{
    ssize_t r = write(STDERR_FILENO, s, strlen(s));
    (void)r;
}

static void on_signal(int sig)
{
    if (cli_signal_polled && cli_signal_flag == 0) {
        cli_signal_flag = sig;
        cli_stop_flag = 1;
        return;
    }
    if (cli_tmp_live) unlink(cli_tmp_path);
    signal_say(cli_signal_flag ? "\nfrep: interrupted again: stopped at once, nothing written\n"
                               : "\nfrep: interrupted: stopped, nothing written\n");
    _exit(128 + sig);
}

void cli_signals_install(void)
{
    static const int sigs[] = { SIGINT, SIGTERM, SIGHUP };
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sa.sa_flags = SA_RESTART;
    sigemptyset(&sa.sa_mask);
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        struct sigaction old;
        /* SIGHUP ignored by nohup stays ignored (SIGINT is caught even in a
         * background job of a script, whose shell ignores it: scripts stop frep so) */
        if (sigs[i] == SIGHUP && sigaction(sigs[i], NULL, &old) == 0 &&
            old.sa_handler == SIG_IGN)
            continue;
        sigaction(sigs[i], &sa, NULL);
    }
}

volatile sig_atomic_t *cli_sigint_catch(void)
{
    cli_signal_polled = 1;
    return &cli_stop_flag;
}

static void on_alarm(int sig)
{
    (void)sig;
    cli_deadline_hit = 1;
    cli_stop_flag = 1;
}

int cli_deadline_arm(double seconds)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_alarm;
    sa.sa_flags = SA_RESTART;
    sigemptyset(&sa.sa_mask);
    if (sigaction(SIGALRM, &sa, NULL)) return -1;
    struct itimerval it;
    memset(&it, 0, sizeof it);
    double whole = floor(seconds);
    it.it_value.tv_sec = (time_t)whole;
    it.it_value.tv_usec = (suseconds_t)((seconds - whole) * 1e6);
    if (it.it_value.tv_sec == 0 && it.it_value.tv_usec == 0) it.it_value.tv_usec = 1;
    return setitimer(ITIMER_REAL, &it, NULL);
}

int cli_deadline_passed(void)
{
    return cli_deadline_hit;
}

void cli_sigint_restore(void)
{
    /* The command keeps polling (it writes the best result after a stop); a signal
     * during that write is the first one still, so it lets the write finish. */
}

void cli_sigint_release(void)
{
    if (cli_signal_flag == 0) cli_signal_polled = 0;
}

volatile sig_atomic_t *cli_signal_caught(void)
{
    return &cli_signal_flag;
}

int cli_interrupted(void)
{
    return cli_signal_flag;
}

void cli_interrupt_handled(void)
{
    cli_signal_flag = 0;
    cli_stop_flag = cli_deadline_hit;
}

int cli_interrupt_status(const char *sub, const char *what)
{
    int sig = cli_signal_flag;
    fprintf(stderr, "frep %s: interrupted (%s): %s\n", sub,
            sig == SIGINT ? "Ctrl-C" : sig == SIGTERM ? "SIGTERM" : sig == SIGHUP ? "SIGHUP"
                                                                              : "signal",
            what);
    return 128 + sig;
}

double cli_now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void cli_default_threads(int n)
{
#ifdef _OPENMP
    if (n > 0) omp_set_num_threads(n);
#else
    (void)n;
#endif
}

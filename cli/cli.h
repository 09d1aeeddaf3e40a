/* cli.h - the frep command: one function per subcommand (cli/cmd_*.c), dispatched by
 * cli/main.c.  Shared helpers: the option layer (cli/opt.c), reading files, diagnostics
 * printing, atomic output, Ctrl-C (cli/util.c), the model -> mesh steps (cli/model.c).
 */
#ifndef FREP_CLI_H
#define FREP_CLI_H

#include <math.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>

#include "frep.h"
#include "opt.h"

/* Messages kept besides printing them (frep view shows them in its page): a growing
 * NUL-terminated text (cli/util.c).  An append that cannot allocate is dropped; the
 * messages are on standard error anyway. */
typedef struct cli_text {
    char *s;          /* NULL before the first append */
    size_t len, cap;
} cli_text;
#define CLI_TEXT_INIT {NULL, 0, 0}
void cli_text_puts(cli_text *t, const char *s);
void cli_text_printf(cli_text *t, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* Release and empty t. */
void cli_text_free(cli_text *t);

/* A subcommand: argv[0] is the subcommand name. Returns the process exit status. */
typedef int (*cli_cmd_fn)(int argc, char **argv);

int cmd_check(int argc, char **argv);
int cmd_eval(int argc, char **argv);
int cmd_print(int argc, char **argv);
int cmd_dis(int argc, char **argv);
int cmd_mesh(int argc, char **argv);   /* cli/cmd_mesh.c */
int cmd_sample(int argc, char **argv); /* cli/cmd_sample.c */
int cmd_export(int argc, char **argv); /* cli/cmd_export.c */
int cmd_render(int argc, char **argv); /* cli/cmd_render.c */
int cmd_evolve(int argc, char **argv); /* cli/cmd_evolve.c */
int cmd_segment(int argc, char **argv); /* cli/cmd_segment.c */
int cmd_fit(int argc, char **argv);    /* cli/cmd_fit.c */
int cmd_view(int argc, char **argv);   /* cli/cmd_view.c */

/* --view of frep fit and frep evolve (cli/cmd_view.c): the page of frep view (grid
 * 128, the model's '-- @box') of the model text write_model writes, called name,
 * with the cloud; the summary line unless quiet. Returns CLI_OK or CLI_FAIL. */
typedef struct cli_view_job {
    const char *sub, *out, *name, *model, *cloud;
    int (*write_model)(FILE *f, void *user);
    void *user;
    const double *a;        /* values of a[] (NULL: the model's own) */
    size_t na;
    int nthreads, quiet;
} cli_view_job;
int cli_view_result(const cli_view_job *j);

/* Model -> mesh steps shared by frep mesh, sample and render (cli/model.c): the model
 * options (-m -a -b -g --iso -t --setops, table entries below), compile, polygonize. */
typedef struct mesh_cli {
    const char *model, *path;
    cli_list a;
    double box[6];
    int has_box, grid, nthreads, setops;
    int strict;              /* --strict: HyperFun's rejections are errors */
    size_t max_work;         /* --max-work (frep mesh, sample); 0: the default */
    int grid_axes[3];        /* hfp's -g NX,NY,NZ (frep mesh); 0: grid on every axis */
    double iso;
    frep_program *p;
    char *src;
    size_t srclen;
    frep_runtime_error err;  /* runtime errors of every evaluation so far */
    cli_text *diag;          /* may be NULL; else compiler messages are copied here */
    const char *text;        /* may be NULL; else the model's text (path names it) */
} mesh_cli;
void mesh_cli_init(mesh_cli *c);
void mesh_cli_free(mesh_cli *c);
/* cli_opt_parse() for a table holding mesh_cli entries at `mc` bytes into ctx. */
int mesh_cli_parse(const cli_opt_spec *spec, int argc, char **argv, void *ctx, size_t mc,
                   cli_args *args);
int mesh_cli_compile(mesh_cli *c, const char *path);
/* The public API's options for c's model: its box (resolved by mesh_cli_compile), grid,
 * hfp's per-axis grid, iso and threads. */
void mesh_cli_options(const mesh_cli *c, frep_mesh_options *o);
/* Polygonize the compiled model (frep_polygonize) with Ctrl-C polled, the progress on
 * a terminal, and the model's runtime errors, NaN points, work budget and what the
 * mesher found (no surface: a failure; the box reached: a note) printed as "frep SUB:
 * ...".  Returns CLI_OK with *m (frep_mesh_free) and *info filled, else the exit
 * status with *m NULL. */
int mesh_cli_mesh(mesh_cli *c, const char *sub, frep_mesh **m, frep_mesh_info *info);
/* Add runtime errors to c->err; print them (once, as a warning with the source
 * position of the first failing operation) with mesh_cli_report_errors(). */
void mesh_cli_add_errors(mesh_cli *c, const frep_runtime_error *e);
void mesh_cli_report_errors(mesh_cli *c);
/* The model's colours at the vertices of m, hfp's convention: s[1..3] red, green,
 * blue in [0,1] (0..255 in *rgb, 3 a vertex, frep_free), evaluated a hair inside
 * the surface.  *rgb is NULL when the model has fewer than 3 attributes.  Returns
 * CLI_OK, or CLI_FAIL (out of memory, printed as "frep SUB: ..."). */
int mesh_cli_vertex_colors(mesh_cli *mc, const char *sub, const struct frep_mesh *m,
                           uint8_t **rgb);
/* Is PATH a mesh file (by its extension) rather than a model? cli_mesh_read() reads
 * one (frep_mesh_read), printing why it cannot; NULL then. */
int cli_is_mesh_path(const char *path);
frep_mesh *cli_mesh_read(const char *path);

/* A cloud and its distances, for frep view (cli/model.c): each point's signed
 * distance to the surface (> 0 inside; the model's |f|/|grad f|, or the mesh's
 * nearest triangle when mc->p is NULL), each vertex's distance to the cloud, and
 * their colour scales chosen from the data (frep_cloud_distances). */
typedef struct cli_cloud_dist {
    frep_cloud *cl;
    frep_distances d;
} cli_cloud_dist;
/* Read the cloud at path and measure; prints why it cannot ("frep SUB: ..."). */
int cli_cloud_distances(const char *sub, const char *path, mesh_cli *mc,
                        const struct frep_mesh *m, cli_cloud_dist *d);
/* The same for the cloud already in d->cl (kept; the distances are allocated). */
int cli_cloud_measure(const char *sub, mesh_cli *mc, const struct frep_mesh *m,
                      cli_cloud_dist *d);
void cli_cloud_dist_free(cli_cloud_dist *d);

/* Option table entries shared by several subcommands: one parser each for the model
 * options, the thread count, the seed and -q. T is the context type, f its field. */
#define CLI_OPT_MODEL(T, f, h) \
    { 'm', "model", "NAME", CLI_OPT_STRING, offsetof(T, f), .help = h }
#define CLI_OPT_PARAMS(T, f, h) \
    { 'a', "params", "LIST", CLI_OPT_LIST, offsetof(T, f), .help = h }
#define CLI_OPT_BOX(T, f, h) \
    { 'b', "box", "BOX", CLI_OPT_CUSTOM, offsetof(T, f), .parse = cli_opt_box, .help = h }
#define CLI_OPT_GRID(T, f, d, h) \
    { 'g', "grid", "N", CLI_OPT_INT, offsetof(T, f), .lo = 1, .hi = FREP_MESH_MAX_GRID, \
      .what = "grid cells per axis", .above = " (the mesh would not fit in memory)", \
      .def = d, .help = h }
#define CLI_OPT_ISO(T, f, h) \
    { 0, "iso", "V", CLI_OPT_DOUBLE, offsetof(T, f), .lo = -INFINITY, .hi = INFINITY, .help = h }
#define CLI_OPT_SETOPS(T, f, h) \
    { 0, "setops", "S", CLI_OPT_CUSTOM, offsetof(T, f), .parse = cli_opt_setops, \
      .expect = "rfunc or minmax", .help = h }
#define CLI_OPT_THREADS(T, f, h) \
    { 't', "threads", "N", CLI_OPT_INT, offsetof(T, f), .lo = 1, .hi = CLI_MAX_THREADS, .help = h }
#define CLI_OPT_SEED(T, f, h) \
    { 0, "seed", "S", CLI_OPT_SEED, offsetof(T, f), .help = h }
#define CLI_OPT_STRICT(T, f) \
    { 0, "strict", NULL, CLI_OPT_SET, offsetof(T, f), \
      .help = "what the reference HyperFun interpreter rejects is an error, not a\n" \
              "warning 'not HyperFun: ...' (doc/language.md)" }
#define CLI_OPT_QUIET(T, f, h) \
    { 'q', "quiet", NULL, CLI_OPT_SET, offsetof(T, f), .help = h }

/* Signals (cli/util.c, the one signal helper): main() installs one handler for SIGINT,
 * SIGTERM and SIGHUP (cli_signals_install). Until a command asks for the flag, a signal
 * ends the process at once with status 128 + signal (130 for Ctrl-C), removing the
 * temporary file of a write in progress. cli_sigint_catch() makes the first signal only
 * set the flag, which the library polls through the returned pointer (the `interrupt`
 * of the segment, gp, mesh and fit configs): the command then keeps or writes the best
 * result so far and returns cli_interrupt_status(); a second signal still ends the
 * process at once. cli_sigint_restore() is kept for the callers: polling stays on. */
#define CLI_MAX_TMP_PATH 4096   /* the temporary's name, kept for the signal handler */
void cli_signals_install(void);
volatile sig_atomic_t *cli_sigint_catch(void);
void cli_sigint_restore(void);
/* A step that polls no flag follows (frep render's drawing): until the next
 * cli_sigint_catch(), a signal ends the process at once again, as before any catch
 * (unless one came already: the command then stops as it planned). */
void cli_sigint_release(void);
/* The flag a polled signal raises and the deadline does not (cli_deadline_arm): for
 * the steps after the run, which --max-time does not cut (frep evolve's writer). */
volatile sig_atomic_t *cli_signal_caught(void);
/* The signal received since the command asked for the flag (0: none). */
int cli_interrupted(void);
/* The signal was the command's normal end (frep view --watch stops at Ctrl-C): forget
 * it, so that the command exits with its own status. */
void cli_interrupt_handled(void);
/* --max-time of frep segment and frep evolve: after `seconds` (> 0) of wall time from
 * now, SIGALRM sets the flag cli_sigint_catch() returns, so that the library stops as
 * at Ctrl-C, but cli_interrupted() stays 0: the command writes its result and exits
 * as usual.  cli_deadline_passed() tells whether it fired.  Arm returns 0 or -1. */
int cli_deadline_arm(double seconds);
int cli_deadline_passed(void);
/* --knn K|auto (frep normals, segment, evolve): K in 3..KD_MAX_K into a size_t, 0 for
 * auto (neighbourhood size chosen from the data; cli/cmd_normals.c). */
int cli_opt_knn(const char *arg, void *dest, char *why, size_t whylen);
/* -t N (N > 0) also bounds the library's loops that take no thread count (the
 * primitive caches' tables, the mesh writer's formatting): OpenMP's default becomes N,
 * so that -t 1 runs on one core. */
void cli_default_threads(int n);
#define CLI_OPT_KNN(T, f) \
    { 0, "knn", "K|auto", CLI_OPT_CUSTOM, offsetof(T, f), .parse = cli_opt_knn, \
      .expect = "a neighbour count 3..256 or auto", \
      .help = "neighbours for normal estimation when the cloud has none\n" \
              "(default auto: from the noise and spacing of the cloud)" }
int cmd_normals(int argc, char **argv); /* cli/cmd_normals.c */
/* Bad input shared by frep normals, segment and evolve (cli/cmd_normals.c): a cloud out
 * of scale, with fewer than 3 points, all the same or on one line, all on one plane
 * (when need_solid), or with normals that are all zero; prints "frep SUB: PATH: why"
 * and returns CLI_FAIL, else CLI_OK. */
struct frep_cloud;
int cli_check_cloud(const char *sub, const char *path, const struct frep_cloud *c, int need_solid);
/* Print "frep SUB: interrupted (Ctrl-C): WHAT" and return the exit status, 128 + the
 * signal (130 for Ctrl-C). */
int cli_interrupt_status(const char *sub, const char *what);
/* At exit: flush standard output; a write error there (a full disk, a closed pipe) is
 * reported as "frep: cannot write standard output: reason". 0 or -1. */
int cli_stdout_close(void);

/* Seconds of a monotonic clock, for the durations the summaries print. */
double cli_now_seconds(void);

/* Exit statuses. */
#define CLI_OK 0
#define CLI_FAIL 1      /* the job failed (errors in the model, bad data) */
#define CLI_USAGE 2     /* bad command line */

/* Read a whole file (or stdin for "-") into a malloc'ed NUL-terminated buffer. On
 * failure prints "frep: cannot read FILE: reason" and returns NULL. */
char *cli_read_file(const char *path, size_t *len);

/* Diagnostics printer for frep_compile & co: `user` must point to a cli_diag_ctx. */
typedef struct cli_diag_ctx {
    const char *src;
    size_t len;
    unsigned errors, warnings;
    /* Diagnostics already printed: a file compiled once per model reports its parser
     * warnings each time, and each is printed once. Freed by cli_diag_done(). */
    char **seen;
    size_t nseen;
    cli_text *copy;  /* may be NULL; else every message printed is appended here too */
} cli_diag_ctx;
void cli_print_diag(void *user, const frep_diag *d);
/* A library message without a source position, in the commands' own style: "frep SUB:
 * MESSAGE" for an error, "frep SUB: warning: MESSAGE", "frep SUB: note: MESSAGE". */
void cli_library_diag(const char *sub, const frep_diag *d);
void cli_diag_done(cli_diag_ctx *c);

/* Compile FILE (reading it) with the common options (setops: -1 or a frep_setops value;
 * strict: --strict, frep_compile_options.strict); prints diagnostics. On success
 * returns the program and (if src != NULL) hands over the source text (free()). */
frep_program *cli_compile_file(const char *path, const char *model, const double *a,
                               size_t na, int setops, int strict, char **src);
/* The same, with a copy of the messages appended to diag (may be NULL). */
frep_program *cli_compile_file_diag(const char *path, const char *model, const double *a,
                                    size_t na, int setops, int strict, char **src,
                                    cli_text *diag);
/* The same for a text already in memory, called path in messages. */
frep_program *cli_compile_text(const char *path, const char *text, size_t len,
                               const char *model, const double *a, size_t na, int setops,
                               int strict, cli_text *diag);

/* The work budget of the commands that evaluate a model (runtime/frep.h,
 * frep_program_set_work_limit): the loop iterations of all its evaluations together,
 * counted per point.  cli_compile_text gives every model CLI_DEFAULT_MAX_WORK; eval,
 * mesh, sample and fit take --max-work N (cli_work_limit sets it when given, N > 0).
 * A model without loops never spends any.  cli_work_check says when the evaluations
 * went over it ("frep SUB: PATH: the model's loops ran over the work budget ...") and
 * returns CLI_FAIL; else CLI_OK. */
/* 10^9: about 6 s of one processor for the simplest loop (1.7 x 10^8 iterations per
 * second), room for a 100-iteration loop at 10^7 points (a mesh at grid 512) */
#define CLI_DEFAULT_MAX_WORK 1000000000ull
#define CLI_OPT_MAX_WORK(T, f) \
    { 0, "max-work", "N", CLI_OPT_SIZE, offsetof(T, f), .lo = 1, .hi = 9e15, \
      .what = "a number of loop iterations", \
      .help = "work budget: at most N loop iterations of the model in all\n" \
              "(summed over the points; default 1e9)" }
int cli_work_limit(frep_program *p, size_t max_work);
int cli_work_check(const char *sub, const char *path, const frep_program *p);

/* Write a file atomically: data goes to a temporary in the same directory (PATH.tmpPID),
 * which is renamed over `path` when `fn` succeeds and removed otherwise, also by a
 * signal. fn returns 0 on success. "-" is standard output. A failure is reported as
 * "frep: cannot write PATH: reason" (errno's, e.g. "No space left on device"). */
int cli_write_atomic(const char *path, int (*fn)(FILE *f, void *user), void *user);
/* A cloud written atomically to PATH ("-": standard output) in the format its name
 * says (.ply binary PLY, else .xyz text): cli_write_atomic over frep_cloud_write_stream. */
int cli_write_cloud(const char *path, const frep_cloud *c);

/* Usage error: prints "frep SUB: message" and a hint to --help; returns CLI_USAGE. */
int cli_usage_error(const char *sub, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

#endif

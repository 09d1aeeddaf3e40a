/* cli.h - the frep command: one function per subcommand (cli/cmd_*.c), dispatched by
 * cli/main.c.  Shared helpers (option parsing, reading files, diagnostics printing,
 * atomic output) live in cli/util.c.
 */
#ifndef FREP_CLI_H
#define FREP_CLI_H

#include <stddef.h>
#include <stdio.h>

#include "frep.h"

/* A subcommand: argv[0] is the subcommand name. Returns the process exit status. */
typedef int (*cli_cmd_fn)(int argc, char **argv);

int cmd_check(int argc, char **argv);
int cmd_eval(int argc, char **argv);
int cmd_print(int argc, char **argv);
int cmd_dis(int argc, char **argv);
int cmd_mesh(int argc, char **argv);   /* cli/cmd_mesh.c */
int cmd_sample(int argc, char **argv); /* cli/cmd_sample.c */
int cmd_render(int argc, char **argv); /* cli/cmd_render.c */
int cmd_evolve(int argc, char **argv); /* cli/cmd_evolve.c */
int cmd_segment(int argc, char **argv); /* cli/cmd_segment.c */
int cmd_fit(int argc, char **argv);    /* cli/cmd_fit.c */

/* Model -> mesh steps shared by frep mesh, sample and render (cli/cmd_mesh.c):
 * mesh_cli_option() handles -m -a -b -g --iso(I) -t --setops(S) (returns 0, a CLI_
 * status after a message, or -1 for "not mine"); compile, then polygonize. */
typedef struct mesh_cli {
    const char *model, *path;
    double *a;
    size_t na;
    double box[6];
    int has_box, grid, nthreads, setops;
    double iso;
    frep_program *p;
    char *src;
    size_t srclen;
    frep_runtime_error err;  /* runtime errors of every evaluation so far */
} mesh_cli;
void mesh_cli_init(mesh_cli *c);
void mesh_cli_free(mesh_cli *c);
int mesh_cli_option(mesh_cli *c, const char *sub, int opt, const char *arg);
int mesh_cli_compile(mesh_cli *c, const char *path);
struct frep_mesh;
struct mesh_stats;
int mesh_cli_polygonize(mesh_cli *c, const char *sub, struct frep_mesh *m, struct mesh_stats *st);
/* Add runtime errors to c->err; print them (once, as a warning with the source
 * position of the first failing operation) with mesh_cli_report_errors(). */
void mesh_cli_add_errors(mesh_cli *c, const frep_runtime_error *e);
void mesh_cli_report_errors(mesh_cli *c);

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
} cli_diag_ctx;
void cli_print_diag(void *user, const frep_diag *d);
void cli_diag_done(cli_diag_ctx *c);

/* Compile FILE (reading it) with the common options; prints diagnostics. On success
 * returns the program and (if src != NULL) hands over the source text (free()). */
frep_program *cli_compile_file(const char *path, const char *model, const double *a,
                               size_t na, int setops, char **src);

/* Parse "v1,v2,..." into a malloc'ed array; NULL + message on a malformed list. */
double *cli_parse_list(const char *opt, const char *s, size_t *n);
/* HyperFun's -b conventions: 1 number -> [-v,v]^3; 2 -> [lo,hi]^3; 3 -> [-a,a]x[-b,b]x[-c,c];
 * 6 -> xlo,ylo,zlo,xhi,yhi,zhi. Returns 0 or -1 after a message. */
int cli_parse_box(const char *s, double box[6]);

/* Write a file atomically: data goes to a temporary in the same directory, which is
 * renamed over `path` when `fn` succeeds. fn returns 0 on success. */
int cli_write_atomic(const char *path, int (*fn)(FILE *f, void *user), void *user);

/* Usage error: prints "frep SUB: message" and a hint to --help; returns CLI_USAGE. */
int cli_usage_error(const char *sub, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

#endif

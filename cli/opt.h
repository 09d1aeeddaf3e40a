/* opt.h - the option layer of the frep command: each subcommand declares its options in
 * one table (names, kind of value, range, help text); cli_opt_parse() parses argv against
 * it (GNU getopt_long underneath: abbreviations, options among the arguments), checks
 * the values, reports bad ones as usage errors, and prints --help from the same table.
 */
#ifndef FREP_CLI_OPT_H
#define FREP_CLI_OPT_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

/* The most options one subcommand declares (frep evolve has 31), --help not counted. */
#define CLI_MAX_OPTS 48
/* The most OpenMP threads -t accepts: more than any machine frep runs on, and OpenMP
 * starts every one of them. */
#define CLI_MAX_THREADS 1024

/* What an option's value is and where it goes. The destination is at `off` bytes into
 * the subcommand's context struct and has the C type named here. */
typedef enum cli_opt_kind {
    CLI_OPT_SET,     /* no value: stores 1 into an int */
    CLI_OPT_CLEAR,   /* no value: stores 0 into an int (--no-X) */
    CLI_OPT_INT,     /* an integer in [lo, hi] into an int */
    CLI_OPT_LONG,    /* ... into a long */
    CLI_OPT_U32,     /* ... into a uint32_t */
    CLI_OPT_SIZE,    /* ... into a size_t */
    CLI_OPT_DOUBLE,  /* a finite number in [lo, hi] ((lo, hi] with open_lo) into a double */
    CLI_OPT_SEED,    /* a random seed: decimal digits, into a uint64_t */
    CLI_OPT_STRING,  /* the argument itself, into a const char * */
    CLI_OPT_LIST,    /* comma-separated numbers, into a cli_list (malloc'ed) */
    CLI_OPT_CUSTOM   /* converted by the entry's `parse` */
} cli_opt_kind;

/* A value parser of a CUSTOM option: returns 0, or -1 with the reason in why (a text
 * that follows "OPTION: "); with why left empty the reason is "expected EXPECT, got
 * 'ARG'". */
typedef int (*cli_opt_parse_fn)(const char *arg, void *dest, char *why, size_t whylen);

typedef struct cli_opt {
    char short_name;        /* 0: long name only */
    const char *name;       /* long name, without the dashes */
    const char *arg;        /* the value's name in --help; NULL: takes no value */
    cli_opt_kind kind;
    size_t off;             /* destination in the context struct (offsetof) */
    double lo, hi;          /* numeric kinds: the range; hi = INFINITY: no upper bound */
    int open_lo;            /* DOUBLE: lo itself is out of range */
    const char *what;       /* numeric kinds: what the value is ("a point count"); NULL:
                               "an integer" or "a number" */
    const char *above;      /* numeric kinds: said after the message when the value is
                               above hi (why it is refused) */
    cli_opt_parse_fn parse; /* CUSTOM only */
    const char *expect;     /* CUSTOM only: what a good value is, for the message */
    const char *def;        /* a default parsed before argv (for the command's own
                               defaults; the library's come from its config init) */
    const char *help;       /* --help text; '\n' starts a continuation line; NULL:
                               not listed */
} cli_opt;

/* A subcommand's options and --help text: usage (up to the option list, which follows
 * "Options:"), then the options with their help at column `column`. */
typedef struct cli_opt_spec {
    const char *sub;        /* "fit": for messages */
    const char *usage;
    const cli_opt *opts;
    size_t nopts;
    int column;
} cli_opt_spec;

/* CLI_OPT_LIST's destination. */
typedef struct cli_list {
    double *v;
    size_t n;
} cli_list;
void cli_list_free(cli_list *l);

/* What cli_opt_parse() leaves: the positional arguments and which options were given. */
typedef struct cli_args {
    int n;
    char **v;
    unsigned char given[CLI_MAX_OPTS];
} cli_args;

/* cli_opt_parse() returns this when the command should go on; otherwise the exit
 * status to return at once (CLI_OK after --help, CLI_USAGE after a message). */
#define CLI_GO_ON (-1)
int cli_opt_parse(const cli_opt_spec *spec, int argc, char **argv, void *ctx, cli_args *args);
/* Was the option with this long name on the command line? */
int cli_opt_given(const cli_opt_spec *spec, const cli_args *args, const char *name);
/* The --help text. */
void cli_opt_help(const cli_opt_spec *spec, FILE *f);

/* Value parsers shared by several tables (CUSTOM options). */
int cli_opt_box(const char *arg, void *dest, char *why, size_t whylen);     /* double[6] */
int cli_opt_setops(const char *arg, void *dest, char *why, size_t whylen);  /* int */

#endif

/* check.h - semantic checks of a parsed file (lang/check.c), between lang/parse.y and
 * lang/lower.c: names, arities, argument kinds, array sizes and pragmas.  Every
 * problem is reported (not just the first); lowering runs only on a clean file.
 */
#ifndef FREP_CHECK_H
#define FREP_CHECK_H

#include <stdint.h>

#include "arena.h"
#include "ast.h"

/* A small string -> uint32 map in the session arena (names are case-folded keys). */
typedef struct strmap {
    arena *A;
    const char **keys;
    uint32_t *vals;
    uint32_t cap, n;
} strmap;

void strmap_init(strmap *m, arena *A);
/* Pointer to the value of key, or NULL when absent. */
uint32_t *strmap_get(const strmap *m, const char *key);
/* Insert or overwrite; returns 0, or -1 when out of memory. */
int strmap_put(strmap *m, const char *key, uint32_t val);

/* A named free parameter: `name = NUMBER;  -- @free [lo, hi]`. */
typedef struct check_free {
    const ast_node *stmt;   /* the AST_ASSIGN statement */
    const char *name;       /* variable name as written */
    double value;
    double lo, hi;          /* -inf/+inf without bounds */
    int has_bounds;
    ast_loc lit;            /* span of the literal, minus sign included */
} check_free;

/* What the checks learned about the file, for lowering. */
typedef struct check_info {
    check_free *frees;
    uint32_t nfree;
    int has_setops;         /* an `-- @setops` pragma was given */
    int setops;             /* frep_setops */
    double alpha;
    int has_box;
    double box[6];
    const double *avals;    /* `-- @params`: default values of a[] (NULL: none) */
    uint32_t navals;
} check_info;

/* Check the whole file; returns the number of errors reported through d.  strict:
 * what the reference interpreter rejects and frep accepts is an error, not a
 * warning. */
unsigned check_file(arena *A, const ast_file *f, int strict, diag_sink *d, check_info *out);

/* A model that declares no s[] array (two parameter arrays, no local array or
 * variable named s) but uses `s` as an array: the first such use, else NULL.  The
 * reference then acts as if the model declared s[1] (HF_Get_X_A in int_parse_N.c);
 * frep does the same (a local array s[1] starting at 0) with a warning. */
const ast_node *check_implicit_s(const ast_model *m);

/* Index of the model named key defined before model `before` (all models when
 * before == f->nmodels), or -1. */
int check_find_model(const ast_file *f, const char *key, uint32_t before);

/* Argument kind of position i of a library function (lib.h letters), or 0 when
 * the function takes fewer arguments. *min receives the least argument count. */
char check_lib_kind(const char *args, uint32_t i, uint32_t *min, int *variadic);

#endif

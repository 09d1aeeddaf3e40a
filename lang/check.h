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
} check_info;

/* Check the whole file; returns the number of errors reported through d.  strict:
 * what the reference interpreter rejects and frep accepts is an error, not a
 * warning. */
unsigned check_file(arena *A, const ast_file *f, int strict, diag_sink *d, check_info *out);

/* Index of the model named key defined before model `before` (all models when
 * before == f->nmodels), or -1. */
int check_find_model(const ast_file *f, const char *key, uint32_t before);

/* Argument kind of position i of a library function (lib.h letters), or 0 when
 * the function takes fewer arguments. *min receives the least argument count. */
char check_lib_kind(const char *args, uint32_t i, uint32_t *min, int *variadic);

#endif

/* lib.h - built-in functions and the HyperFun FRep library, expanded into IR.
 *
 * check.c looks calls up here (name, argument kinds); lower.c calls `expand` with
 * the arguments already lowered to IR.  Each entry of lang/lib.c carries the
 * defining formula of its function as a comment, and doc/library.md lists them all.
 */
#ifndef FREP_LIB_H
#define FREP_LIB_H

#include <stdint.h>

#include "ir.h"

/* Argument kinds, one letter each in lib_fn.args:
 *   's'  scalar expression
 *   'a'  array of at least `size` elements, read only (size from lib_fn.sizes)
 *   'x'  array of at least 3 elements (a point), read only
 *   'm'  array of at least 3 elements modified in place (space transformations)
 *   'v'  array of any size (its size is passed in lib_arg.n)
 *   'w'  array of any size written in place (attributes: the s[] of hfA_* functions)
 * A trailing '*' in args repeats the last kind (variadic).
 */
typedef struct lib_arg {
    ir_ref s;          /* scalar value (kind 's') */
    ir_ref *elems;     /* array elements (other kinds); writable for 'm' */
    uint32_t n;        /* number of elements */
} lib_arg;

typedef struct lib_ctx {
    ir *g;
    /* Report an error at the call (e.g. an array of the wrong size found only while
     * expanding). Returns IR_NONE for convenience. */
    ir_ref (*error)(struct lib_ctx *c, const char *fmt, ...);
    void *user;
    int setops;        /* frep_setops in force (for the operators | & \ and R-alpha) */
    double alpha;
} lib_ctx;

typedef ir_ref (*lib_expand_fn)(lib_ctx *c, lib_arg *args, uint32_t nargs);

typedef struct lib_fn {
    const char *name;      /* as documented, e.g. "hfSphere"; lookup is case-insensitive */
    const char *args;      /* argument kinds, e.g. "xas" */
    uint8_t sizes[12];     /* minimum sizes for 'a' arguments, by position */
    lib_expand_fn expand;
    const char *summary;   /* one line for --help and did-you-mean listings */
} lib_fn;

/* Find a function by (case-insensitive) name; NULL if none. */
const lib_fn *lib_lookup(const char *name);
/* All functions, for did-you-mean suggestions and the documentation test. */
const lib_fn *lib_all(uint32_t *count);
/* 1 when fn is one of frep's own functions (lib_ext.c), unknown to HyperFun. */
int lib_frep_only(const lib_fn *fn);

/* The operators | & \ under the given semantics (used by lower.c and by lib.c). */
ir_ref lib_union(lib_ctx *c, ir_ref a, ir_ref b);
ir_ref lib_intersection(lib_ctx *c, ir_ref a, ir_ref b);
ir_ref lib_subtraction(lib_ctx *c, ir_ref a, ir_ref b);

/* HF_round of the reference interpreter (int_parse_N.c of HyperFun), which turns
 * every number it uses as a whole number (array indices, mod's operands) into one:
 * c = ceil(d), then c - 1 when c - d > 0.5, else c, so halves round up (2.5 -> 3,
 * -2.5 -> -2, 0.5 -> 1).  lib_hf_round_k computes it, lib_hf_round builds it in IR. */
double lib_hf_round_k(double d);
ir_ref lib_hf_round(ir *g, ir_ref d);

#endif

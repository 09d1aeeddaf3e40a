/* lower.h - symbolic execution of a checked model into IR (lang/lower.c), between
 * lang/check.c and lang/emit.c.
 *
 * The result is a root IR node (the model's value) plus, only when the model needs
 * them, statements: stores to variable slots and real control flow for conditions
 * and loops that depend on the point.  A straight-line model has no statements.
 */
#ifndef FREP_LOWER_H
#define FREP_LOWER_H

#include <stdint.h>

#include "ast.h"
#include "check.h"
#include "ir.h"

/* Loop unrolling limits: a loop whose condition folds to a constant is unrolled
 * while both hold; past them it becomes a real loop (which the VM bounds with
 * FREP_MAX_LOOP_ITERATIONS), so a constant infinite loop neither hangs the compiler
 * nor makes the program huge. */
#define FREP_MAX_UNROLL 100000u           /* iterations of one loop */
#define FREP_MAX_UNROLL_NODES (1u << 20)  /* IR nodes created by unrolling one loop */
/* Nesting of model calls (each call is inlined; calls go to earlier models only, so
 * there is no recursion, but a chain of models each calling the previous one twice
 * doubles the work per level). */
#define FREP_MAX_INLINE_DEPTH 64u
/* Statement lowerings of one compile (counts every unrolled and inlined statement):
 * bounds compile time (about a second) for chains of models that each call the
 * previous one twice.  Unrolling one loop stops at a quarter of it. */
#define FREP_MAX_LOWER_STEPS (1u << 20)

typedef struct lstmt lstmt;

typedef struct lblock {
    lstmt **v;
    uint32_t n, cap;
} lblock;

typedef enum lstmt_kind {
    LS_STORE,   /* parallel assignment: all values computed, then stored to slots */
    LS_STOREI,  /* slot base + index - 1 = value (index checked at runtime) */
    LS_IF,      /* pre; if cond then body else body2 */
    LS_WHILE    /* loop: pre; if not cond break; body */
} lstmt_kind;

struct lstmt {
    lstmt_kind kind;
    uint32_t n;             /* LS_STORE: pairs */
    uint32_t *slots;        /* LS_STORE */
    ir_ref *vals;           /* LS_STORE */
    uint32_t base, size;    /* LS_STOREI: array slots and size */
    ir_ref index, value;    /* LS_STOREI */
    ir_ref cond;            /* LS_IF, LS_WHILE */
    lblock pre;             /* LS_WHILE: statements run before each test of cond */
    lblock body, body2;
    uint32_t line, col, len;/* source position for the control instructions */
};

/* A named free parameter that the lowered model uses. */
typedef struct lower_param {
    const check_free *fr;
} lower_param;

typedef struct lowered {
    lblock top;
    ir_ref root;
    uint32_t nslots;        /* variable slots used by the statements */
    uint32_t na;            /* size of the model's a[] (PARAM 0..na-1) */
    lower_param *named;     /* PARAM na + j */
    uint32_t nnamed;
    int has_s;
    ir_ref *attrs;          /* has_s: the model's s[1..nattrs] at its end */
    uint32_t nattrs;
} lowered;

typedef struct lower_options {
    const double *a;        /* values of a[] (for nothing but documentation: a[] is PARAM) */
    size_t na;
    int setops;             /* frep_setops in force */
    double alpha;
} lower_options;

/* Lower model mi of the checked file. Returns 0, or -1 after reporting an error. */
int lower_model(arena *A, const ast_file *f, uint32_t mi, const check_info *ci,
                const lower_options *o, ir *g, diag_sink *d, lowered *out);

#endif

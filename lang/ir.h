/* ir.h - the compiler's intermediate form: a hash-consed DAG of scalar operations.
 *
 * lang/lower.c builds it by symbolic execution of the checked AST (variables map to
 * DAG nodes), lang/lib.c expands library calls into it, and lang/emit.c schedules
 * it into postfix bytecode.  Nodes use the opcodes of runtime/ops.h.  Building a node
 * folds constants (when every operand is constant) and returns an existing identical
 * node when there is one (common-subexpression elimination); both can be turned off
 * (frep_compile_options.optimize = 0) for testing.
 */
#ifndef FREP_IR_H
#define FREP_IR_H

#include <stdint.h>

#include "arena.h"
#include "ops.h"

typedef uint32_t ir_ref;            /* index of a node; IR_NONE for "no node" */
#define IR_NONE UINT32_MAX

typedef struct ir_node {
    uint8_t op;          /* frep_opcode; leaves: CONST, X, PARAM, LOAD, PRIM */
    uint8_t quiet;       /* built for speculative code: suppress domain errors */
    uint32_t arg;        /* as frep_insn.arg for leaves */
    double k;            /* CONST value, AUNI/AINT alpha */
    ir_ref in[3];        /* operands (op_nin(op) of them) */
    uint32_t line, col, len; /* source position for diagnostics */
    uint32_t uses;       /* filled by the scheduler */
    uint32_t hnext;      /* hash chain */
} ir_node;

/* Why building the IR stopped: the caller reports the two differently. */
typedef enum ir_failure {
    IR_OK = 0,
    IR_NOMEM,            /* an allocation failed */
    IR_TOO_LARGE         /* over FREP_IR_MAX_NODES */
} ir_failure;

typedef struct ir {
    arena *A;
    ir_node *nodes;
    uint32_t n, cap;
    uint32_t *buckets;   /* hash table heads (IR_NONE terminated chains) */
    uint32_t nbuckets;
    int optimize;        /* fold constants and share identical nodes */
    int quiet;           /* new nodes get quiet = 1 (inside an if converted to select) */
    uint32_t line, col, len; /* position given to new nodes (ir_set_pos) */
    ir_failure failed;   /* set once a node could not be built; later builds do nothing */
    /* Called when constant folding meets a domain error (e.g. sqrt(-1)): the node is
     * left for the runtime to report; this gives the compiler a warning. May be NULL.
     * Never called for quiet nodes (their branch may not be taken). */
    void (*warn)(void *user, const ir_node *at, const char *what);
    void *warn_user;
} ir;

#define FREP_IR_MAX_NODES (1u << 24) /* IR nodes of one model: bounds compile memory */

void ir_init(ir *g, arena *A, int optimize);
void ir_set_pos(ir *g, uint32_t line, uint32_t col, uint32_t len);

ir_ref ir_const(ir *g, double k);
ir_ref ir_leaf(ir *g, frep_opcode op, uint32_t arg);    /* X, PARAM, LOAD, PRIM */
ir_ref ir_op1(ir *g, frep_opcode op, ir_ref a);
ir_ref ir_op2(ir *g, frep_opcode op, ir_ref a, ir_ref b);
ir_ref ir_op2k(ir *g, frep_opcode op, ir_ref a, ir_ref b, double k); /* AUNI/AINT */
ir_ref ir_select(ir *g, ir_ref cond, ir_ref a, ir_ref b);
/* LOADI: element `index` (1-based, a runtime value) of the `size` slots from `base`. */
ir_ref ir_loadi(ir *g, uint32_t base, uint32_t size, ir_ref index);

/* Is r a constant? Then *k receives its value. */
int ir_is_const(const ir *g, ir_ref r, double *k);

/* Shorthands used all over the library expansions. */
static inline ir_ref ir_add(ir *g, ir_ref a, ir_ref b) { return ir_op2(g, FREP_OP_ADD, a, b); }
static inline ir_ref ir_sub(ir *g, ir_ref a, ir_ref b) { return ir_op2(g, FREP_OP_SUB, a, b); }
static inline ir_ref ir_mul(ir *g, ir_ref a, ir_ref b) { return ir_op2(g, FREP_OP_MUL, a, b); }
static inline ir_ref ir_div(ir *g, ir_ref a, ir_ref b) { return ir_op2(g, FREP_OP_DIV, a, b); }
static inline ir_ref ir_sq(ir *g, ir_ref a) { return ir_op1(g, FREP_OP_SQUARE, a); }
static inline ir_ref ir_neg(ir *g, ir_ref a) { return ir_op1(g, FREP_OP_NEG, a); }
static inline ir_ref ir_sqrt(ir *g, ir_ref a) { return ir_op1(g, FREP_OP_SQRT, a); }
static inline ir_ref ir_k(ir *g, double k) { return ir_const(g, k); }

#endif

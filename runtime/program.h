/* program.h - the compiled form of a model: bytecode, its source map and parameters.
 *
 * Produced by lang/compile.c (or assembled directly by evolve/), run by runtime/vm*.c.
 * A frep_program is immutable once built and may be shared by any number of threads;
 * all mutable evaluation state lives in a vm_scratch, one per thread.
 *
 * Bytecode is postfix (stack) code of fixed-width instructions.  For straight-line
 * code every subexpression is a contiguous range of instructions, so a subtree is
 * found by scanning backwards with the stack effects of the opcode table, and the
 * genetic-programming engine splices trees with memmove (see doc/architecture.md).
 */
#ifndef FREP_PROGRAM_H
#define FREP_PROGRAM_H

#include <stdatomic.h>
#include <stddef.h>
#include <signal.h>
#include <stdint.h>

#include "frep.h"
#include "ops.h"

/* Instruction flags. */
#define INSN_KB    0x01u /* binary op: operand b is the immediate k (only a on the stack) */
#define INSN_KA    0x02u /* binary op: operand a is the immediate k (only b on the stack) */
#define INSN_QUIET 0x04u /* never report a domain error (speculative code of an if->select) */

typedef struct frep_insn {
    uint8_t op;     /* frep_opcode */
    uint8_t flags;  /* INSN_* */
    uint16_t pad;   /* zero */
    uint32_t arg;   /* slot, axis, parameter, primitive, jump target (meaning per op) */
    double k;       /* immediate (meaning per op; 0 when unused) */
} frep_insn;

_Static_assert(sizeof(frep_insn) == 16, "instructions are 16 bytes");

/* Source position of an instruction, for runtime diagnostics. line 0: no position. */
typedef struct frep_srcpos {
    uint32_t line, col, len;
} frep_srcpos;

/* A free parameter: an element of the model's `a` array or a named parameter
 * declared with an `-- @free` annotation (see doc/language.md). */
typedef struct frep_param_info {
    char *name;          /* "a[2]" or the variable's name as written */
    double value;        /* initial value (from -a or the source) */
    double lo, hi;       /* bounds; -inf/+inf when not given */
    int has_bounds;
    frep_srcpos pos;     /* position of the value in the source; line 0 for a[] */
    uint32_t off, end;   /* byte span of the value literal in the source (named only) */
} frep_param_info;

/* Limits, each with its reason. */
#define FREP_BLOCK 256              /* points per evaluation block: stack fits in L1/L2 */
#define FREP_MAX_STACK 4096         /* stack depth of one program: nesting of the source */
#define FREP_MAX_SLOTS (1u << 20)   /* variable and temporary slots of one program */
#define FREP_MAX_LOOP_ITERATIONS 1000000L /* backward jumps per point before giving up */

/* The work budget of a program (frep_program_set_work_limit): loop iterations counted
 * per point (a backward jump run by n lanes counts n) over every evaluation of the
 * program and of the programs sharing its budget (its attribute programs, the pruned
 * copies a mesher makes).  `used` is the one mutable part of a program: the threads
 * add to it atomically, in batches (VM_WORK_BATCH) and at the end of every block, so
 * the total after an evaluation does not depend on the thread count, and neither does
 * whether it went over the limit. */
typedef struct frep_work {
    uint64_t limit;            /* iterations allowed; the budget is spent once used > limit */
    _Atomic uint64_t used;
    volatile sig_atomic_t *cancel; /* non-NULL and set: loops stop as if spent
                                      (frep_program_set_cancel) */
} frep_work;

#define PROG_HAS_BRANCHES 0x01u  /* code contains JMP/JZ */
#define PROG_HAS_PRIMS    0x02u  /* code reads PRIM leaves: inputs must carry a cache */

struct frep_program {
    frep_insn *code;
    frep_srcpos *pos;          /* pos[pc]; may be NULL (assembled programs) */
    uint32_t ncode;
    uint32_t nslots;           /* variable + temporary slots */
    uint32_t max_stack;        /* maximum stack depth reached by the code */
    uint32_t nparams;
    frep_param_info *params;
    uint32_t na;               /* params[0..na-1] are the elements of a[] (<= nparams) */
    uint32_t nprims;           /* PRIM leaves refer to 0..nprims-1 */
    uint32_t flags;            /* PROG_* */
    char *file;                /* source file name for diagnostics (may be NULL) */
    char *model;               /* model name */
    double box[6];             /* extent from an `-- @box` pragma; valid when has_box */
    int has_box;
    uint32_t nattrs;           /* size of the model's s[] attribute array; 0: none */
    struct frep_program **attrs; /* nattrs programs, attrs[k] computes s[k+1]: same
                                    parameters, no attributes of their own */
    uint32_t cap;              /* allocated entries of code and pos (prog_emit's) */
    frep_work *work;           /* NULL: no budget; shared by the attribute programs */
    int owns_work;             /* work is this program's (freed with it) */
};

/* Loop iterations an evaluator counts before adding them to a budget: one atomic add
 * per 65536 (well under a millisecond of a loop's work), so the threads do not contend
 * and a spent budget is seen soon. */
#define VM_WORK_BATCH 65536u
/* What one loop iteration of the interval evaluator counts: a box costs as much as 64
 * points (45 ns per iteration against 0.6 ns per point in a block of the value
 * evaluator, measured), and a box stands for many points. */
#define VM_WORK_BOX 64u

/* Is w spent (used > limit)?  w may be NULL (no budget). */
int prog_work_spent(const frep_work *w);
/* Must loops stop: w spent or its cancel flag set? */
int prog_work_stop(const frep_work *w);

/* Allocation helpers shared by the compiler and the GP engine. */
frep_program *prog_new(void);
/* Append one instruction; returns its pc or UINT32_MAX on allocation failure. */
uint32_t prog_emit(frep_program *p, frep_opcode op, uint32_t arg, double k, uint8_t flags,
                   frep_srcpos pos);
/* Recompute max_stack and flags from the code; returns 0, or -1 when the stack
 * underflows or a jump leaves the code (the program is then unusable). */
int prog_finish(frep_program *p);

/* Opcode table queries. */
const char *op_name(frep_opcode op);      /* "ADD" */
const char *op_meaning(frep_opcode op);
int op_nin(frep_opcode op);               /* operands popped */
int op_pushes(frep_opcode op);            /* 0 or 1 */
unsigned op_flags(frep_opcode op);
/* Operands actually popped by this instruction (binary ops with INSN_KA/KB pop one). */
int insn_nin(const frep_insn *in);
/* First pc of the subexpression that ends at pc `end` (straight-line code only). */
uint32_t prog_subtree_start(const frep_insn *code, uint32_t end);

#endif

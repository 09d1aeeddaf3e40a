/* ops.h - the one opcode table of frep's bytecode.
 *
 * Expanding FREP_OP generates the enum below, the name, meaning, arity and flag table
 * of runtime/program.c (op_name, op_nin, op_flags, the disassembler's mnemonics) and
 * the flag and arity tables of the tangent evaluator.  The compiler's emitter and
 * optimizer (lang/emit.c, lang/ir.c) read those tables and op_scalar, naming only a
 * few ops.  What each op computes is written by hand, once per evaluator: see the
 * checklist below.  Opcode ids are fixed numbers: saved genomes and golden disassembly
 * keep their meaning when opcodes are added (append; never renumber).
 *
 * FREP_OP(NAME, id, nin, flags, "meaning")
 *   nin    stack operands popped (every op except STORE/JMP/JZ/STOREI pushes one value)
 *   flags  OPF_* below
 *
 * Instruction fields used by an op (see frep_insn in program.h):
 *   arg  slot, axis, parameter, primitive index or jump target
 *   k    immediate constant (CONST), alpha (AUNI/AINT), array size (LOADI/STOREI)
 * Binary ops may carry an immediate operand instead of a stack operand: flag
 * INSN_KB means "b is k" (only a is popped), INSN_KA means "a is k" (only b popped).
 *
 * Adding an opcode (doc/architecture.md, "Adding an opcode", says why each is needed).
 * Switches marked [enum] list every opcode and -Wswitch-enum (the strict build) fails
 * until the new one is there; the others list only some ops and must be checked by
 * hand.
 *   runtime/ops.h         a FREP_OP line with the next free id, its flags and meaning
 *   runtime/opsem.h       opsem_<name>() and its case in op_scalar [enum] (values: the
 *                         VM, the tangent VM and the constant folder agree through it),
 *                         op_partials [enum] (derivative rule); OPF_DOMAIN ops also
 *                         opsem_bad_<name>(), opsem_is_bad and opsem_error_what
 *   runtime/vm.c          vm_run [enum]: a UNARY/BINARY(_DOM) line
 *   runtime/vm_f32.c      optional (only some ops): f32_op_ok, f32_op_err, f32_run for
 *                         the single-precision grid path
 *   runtime/vm_tangent.c  tan_run [enum]: a TAN_UNARY/TAN_BINARY line
 *   runtime/vm_interval.c ival_op [enum] (interval rule), interval_run [enum] (stack
 *                         effect); vm_pruner_new/vm_prune if it is an R-function or
 *                         min/max-like set operation the mesh pruner may drop
 *   runtime/prune.c       prune_plan_new [enum] (may grid code contain it?);
 *                         pr_domain_ok for OPF_DOMAIN ops, pr_decide for set operations
 *   runtime/program.c     prog_check_insn and dis_operands if it uses arg or k other
 *                         than as an immediate operand; op_pushes if it pushes nothing
 *   lang/lib.c, lib_hf.c, lib_ext.c   a library function that emits it (else no
 *                         source reaches it); lang/lower.c if it is a language operator;
 *                         lang/ir.c ir_op1/ir_op2 for algebraic simplifications (optional)
 *   evolve/tree.c, fitness.c, partition.c   only for a set operation the genetic
 *                         programming engine should use (tree_nin, op_char; eval_minmax,
 *                         eval_rfunc, eval_sides; is_union, is_sub)
 *   tests/test_vm.c, test_mesh.c   the table-driven property tests cover it; the
 *                         smooth_at list of test_vm.c needs an entry where central
 *                         differences fail
 */
#ifndef FREP_OPS_H
#define FREP_OPS_H

/* Op flags. */
#define OPF_LEAF     0x01u /* pushes without popping */
#define OPF_COMMUT   0x02u /* binary and commutative */
#define OPF_CTRL     0x04u /* control flow or store: not an expression node */
#define OPF_DOMAIN   0x08u /* may raise a runtime domain error (NaN + diagnostic) */
#define OPF_SETOP    0x10u /* a set operation (union, intersection, subtraction) */
#define OPF_BOOL     0x20u /* result is 0 or 1 (comparison or logic) */
#define OPF_NOGRAD   0x40u /* piecewise constant: derivative is zero everywhere */

#define FREP_OPS(FREP_OP) \
    /* leaves */ \
    FREP_OP(CONST,  0, 0, OPF_LEAF, "push the constant k") \
    FREP_OP(X,      1, 0, OPF_LEAF, "push point coordinate arg (0=x, 1=y, 2=z)") \
    FREP_OP(PARAM,  2, 0, OPF_LEAF, "push free parameter arg") \
    FREP_OP(LOAD,   3, 0, OPF_LEAF, "push variable slot arg") \
    FREP_OP(PRIM,   4, 0, OPF_LEAF, "push cached primitive arg (genetic programming)") \
    /* stores and control flow */ \
    FREP_OP(STORE,  5, 1, OPF_CTRL, "pop into variable slot arg") \
    FREP_OP(JMP,    6, 0, OPF_CTRL, "jump to arg (a backward jump counts a loop iteration)") \
    FREP_OP(JZ,     7, 1, OPF_CTRL, "pop; jump to arg when zero") \
    FREP_OP(LOADI,  8, 1, OPF_DOMAIN, "pop index i; push slot arg+i-1 (1-based, i in 1..k)") \
    FREP_OP(STOREI, 9, 2, OPF_CTRL | OPF_DOMAIN, "pop index i, pop value; store to slot arg+i-1") \
    /* unary */ \
    FREP_OP(NEG,   10, 1, 0, "-a (also set complement)") \
    FREP_OP(NOT,   11, 1, OPF_BOOL | OPF_NOGRAD, "1 if a == 0 else 0") \
    FREP_OP(ABS,   12, 1, 0, "|a|; derivative 0 at a == 0") \
    FREP_OP(SQRT,  13, 1, OPF_DOMAIN, "sqrt(a); NaN + error when a < 0; derivative 0 at a == 0") \
    FREP_OP(SQUARE,14, 1, 0, "a*a") \
    FREP_OP(EXP,   15, 1, 0, "e^a") \
    FREP_OP(LOG,   16, 1, OPF_DOMAIN, "natural log; NaN + error when a <= 0") \
    FREP_OP(LOGD,  17, 1, OPF_DOMAIN, "log10; NaN + error when a <= 0") \
    FREP_OP(SIN,   18, 1, 0, "sin(a)") \
    FREP_OP(COS,   19, 1, 0, "cos(a)") \
    FREP_OP(TAN,   20, 1, 0, "tan(a)") \
    FREP_OP(ASIN,  21, 1, OPF_DOMAIN, "asin(a); NaN + error when |a| > 1") \
    FREP_OP(ACOS,  22, 1, OPF_DOMAIN, "acos(a); NaN + error when |a| > 1") \
    FREP_OP(ATAN,  23, 1, 0, "atan(a)") \
    FREP_OP(SINH,  24, 1, 0, "sinh(a)") \
    FREP_OP(COSH,  25, 1, 0, "cosh(a)") \
    FREP_OP(TANH,  26, 1, 0, "tanh(a)") \
    FREP_OP(SIGN,  27, 1, OPF_NOGRAD, "-1, 0 or 1") \
    FREP_OP(CEIL,  28, 1, OPF_NOGRAD, "ceil(a)") \
    FREP_OP(FLOOR, 29, 1, OPF_NOGRAD, "floor(a)") \
    FREP_OP(INT,   30, 1, OPF_NOGRAD, "a truncated toward zero") \
    FREP_OP(FRAC,  31, 1, 0, "a - int(a)") \
    /* binary */ \
    FREP_OP(ADD,   32, 2, OPF_COMMUT, "a + b") \
    FREP_OP(SUB,   33, 2, 0, "a - b") \
    FREP_OP(MUL,   34, 2, OPF_COMMUT, "a * b") \
    FREP_OP(DIV,   35, 2, OPF_DOMAIN, "a / b; NaN + error when b == 0") \
    FREP_OP(POW,   36, 2, OPF_DOMAIN, "a ^ b; NaN + error for a < 0 with non-integer b") \
    FREP_OP(MOD,   37, 2, OPF_DOMAIN, "fmod(a, b); NaN + error when b == 0") \
    FREP_OP(MIN,   38, 2, OPF_COMMUT | OPF_SETOP, "min(a, b) (min/max intersection); tie: derivative of a") \
    FREP_OP(MAX,   39, 2, OPF_COMMUT | OPF_SETOP, "max(a, b) (min/max union); tie: derivative of a") \
    FREP_OP(ATAN2, 40, 2, 0, "atan2(a, b)") \
    FREP_OP(EQ,    41, 2, OPF_COMMUT | OPF_BOOL | OPF_NOGRAD, "a = b") \
    FREP_OP(NE,    42, 2, OPF_COMMUT | OPF_BOOL | OPF_NOGRAD, "a /= b") \
    FREP_OP(LT,    43, 2, OPF_BOOL | OPF_NOGRAD, "a < b") \
    FREP_OP(LE,    44, 2, OPF_BOOL | OPF_NOGRAD, "a <= b") \
    FREP_OP(GT,    45, 2, OPF_BOOL | OPF_NOGRAD, "a > b") \
    FREP_OP(GE,    46, 2, OPF_BOOL | OPF_NOGRAD, "a >= b") \
    FREP_OP(AND,   47, 2, OPF_COMMUT | OPF_BOOL | OPF_NOGRAD, "a and b (nonzero is true)") \
    FREP_OP(OR,    48, 2, OPF_COMMUT | OPF_BOOL | OPF_NOGRAD, "a or b") \
    FREP_OP(RUNI,  49, 2, OPF_COMMUT | OPF_SETOP, "R0 union a + b + sqrt(a^2 + b^2)") \
    FREP_OP(RINT,  50, 2, OPF_COMMUT | OPF_SETOP, "R0 intersection a + b - sqrt(a^2 + b^2)") \
    FREP_OP(RSUB,  51, 2, OPF_SETOP, "R0 subtraction a - b - sqrt(a^2 + b^2)") \
    FREP_OP(MSUB,  52, 2, OPF_SETOP, "min/max subtraction min(a, -b)") \
    FREP_OP(AUNI,  53, 2, OPF_COMMUT | OPF_SETOP, "R-alpha union (a + b + sqrt(a^2 + b^2 - 2k a b)) / (1 + k)") \
    FREP_OP(AINT,  54, 2, OPF_COMMUT | OPF_SETOP, "R-alpha intersection (a + b - sqrt(a^2 + b^2 - 2k a b)) / (1 + k)") \
    /* ternary */ \
    FREP_OP(SELECT,55, 3, 0, "c ? a : b, popped as c, a, b pushed in that order")

typedef enum frep_opcode {
#define FREP_OP_ENUM(name, id, nin, flags, meaning) FREP_OP_##name = id,
    FREP_OPS(FREP_OP_ENUM)
#undef FREP_OP_ENUM
    FREP_OP__COUNT
} frep_opcode;

#endif

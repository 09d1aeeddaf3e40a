/* vm_f32.h - single-precision value evaluation with a certified error bound.
 *
 * For uses that need the side of the surface but not the last digits (the grid's
 * inside count, its value range), a straight-line program of the supported operations
 * runs in float: 8 lanes per AVX2 instruction instead of 4, and a float square root
 * costs about a quarter of a double one.  Before a box's points are evaluated,
 * vm_f32_bound walks the program over the box with intervals and gives E such that
 * |float value - double value| <= E at every point of the box (the double value being
 * what vm_eval_block computes).  A point whose float value is farther than E from 0 is
 * on the same side as in double; the caller re-evaluates the others in double.
 */
#ifndef FREP_VM_F32_H
#define FREP_VM_F32_H

#include <stddef.h>

#include "program.h"

/* Largest magnitude (operands and results, over the box) the bound is given for: far
 * below FLT_MAX even squared inside an R-function, so float neither overflows nor
 * reaches infinity where the bound is finite. */
#define VM_F32_MAX_MAG 0x1p60

/* Shortest program worth running in float: the block's conversions to float and back
 * and the tile's bound cost about as much as 8-16 instructions in double, so the
 * 9-instruction sphere ran 30% slower in float, the 447-instruction gear 1.7x faster
 * (doc/benchmarks.md, "Single precision"). */
#define VM_F32_MIN_CODE 32

typedef struct vm_f32 vm_f32;

/* Whether p can run in float: straight-line (no jumps, no indexed arrays, no cached
 * primitives), every operation one of CONST X PARAM LOAD STORE NEG ABS SQRT SQUARE ADD
 * SUB MUL DIV MIN MAX MSUB RUNI RINT RSUB. */
int vm_f32_supported(const frep_program *p);

/* Whether this CPU runs the float path faster than double (AVX2: 8 float lanes per
 * instruction); callers choose the precision with it, tests may ignore it. */
int vm_f32_cpu_ok(void);

/* The instruction sets the float loops are compiled for (function-level target
 * attributes, so the build runs on any x86-64), picked per scratch at run time:
 * VM_F32_ISA_AVX512 (16 float lanes per instruction; AVX-512 F, VL, BW, DQ), AVX2 (8),
 * BASE (the build's baseline, 4 with SSE2).  All round alike (no FMA): the values are
 * the same bit for bit whichever runs. */
enum { VM_F32_ISA_BASE, VM_F32_ISA_AVX2, VM_F32_ISA_AVX512 };

/* Whether this CPU (and build) can run `isa`. */
int vm_f32_isa_ok(int isa);

/* The ISA a new scratch uses: the best this CPU runs, unless the environment variable
 * FREP_F32_ISA (base, avx2 or avx512) asks for one it can (benchmarks compare them). */
int vm_f32_isa_default(void);

/* Make s run `isa`; 0, or -1 (s unchanged) when vm_f32_isa_ok(isa) is 0. */
int vm_f32_set_isa(vm_f32 *s, int isa);
int vm_f32_get_isa(const vm_f32 *s);

/* Per-thread scratch big enough for p (a supported program, or one of its pruned
 * copies, which are never longer). NULL when out of memory. */
vm_f32 *vm_f32_new(const frep_program *p);
void vm_f32_free(vm_f32 *s);

/* E >= 0 bounding |float - double| at every point of box = {x0, y0, z0, x1, y1, z1},
 * with the program's own parameter values; INFINITY when none can be given (an
 * unsupported operation, a magnitude over VM_F32_MAX_MAG, a square root or division
 * whose double evaluation might fail over the box: those points keep double). A finite
 * E also means the double evaluation raises no runtime error in the box. */
double vm_f32_bound(vm_f32 *s, const frep_program *p, const double box[6]);

/* Values of p at n <= FREP_BLOCK points, computed in float, into out (as doubles).
 * Returns 0, or -1 for an unsupported program or a scratch too small. */
int vm_f32_eval_block(vm_f32 *s, const frep_program *p, const double *x, const double *y,
                      const double *z, size_t n, double *out);

#endif

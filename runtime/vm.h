/* vm.h - internal interface of the bytecode evaluators (runtime/vm*.c).
 *
 * Each evaluator runs a frep_program over one block of at most FREP_BLOCK points,
 * structure-of-arrays, with a per-thread vm_scratch.  The public frep_eval* functions
 * (runtime/eval.c) split work into blocks and, in the _par variants, spread blocks over
 * OpenMP threads.  fit/ and evolve/ call these directly when they need more than the
 * public API (cached primitives, arbitrary tangent seeds).
 */
#ifndef FREP_VM_H
#define FREP_VM_H

#include <stddef.h>

#include "program.h"

/* Inputs of one block of n points (n <= FREP_BLOCK). */
typedef struct vm_inputs {
    const double *x, *y, *z;       /* coordinates of the block's points */
    const double *params;          /* program parameter values (nparams) */
    /* Cached primitives for PRIM leaves (programs with PROG_HAS_PRIMS): prim_v[j] points
     * at primitive j's values at this block's points; prim_g[3*j + c] at gradient
     * component c (needed by the tangent evaluator with xyz seeds only). */
    const double *const *prim_v;
    const double *const *prim_g;
} vm_inputs;

/* Which tangents the tangent evaluator propagates. */
typedef enum vm_seed {
    VM_SEED_XYZ,     /* 3 tangents: d/dx, d/dy, d/dz */
    VM_SEED_PARAMS   /* nparams tangents: d/dparam_j */
} vm_seed;

typedef struct vm_scratch vm_scratch;
/* The public frep_scratch is a vm_scratch. */

vm_scratch *vm_scratch_new(const frep_program *p);
void vm_scratch_free(vm_scratch *s);

/* Values at n <= FREP_BLOCK points into out[n]. Returns 0, or -1 when the program is
 * unusable with this scratch (too small). Runtime domain errors are recorded in the
 * scratch (frep_scratch_errors), never returned. */
int vm_eval_block(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                  double *out);

/* Values and tangents: out[n], dout[t*n + i] for tangent t (3 for VM_SEED_XYZ,
 * p->nparams for VM_SEED_PARAMS). */
int vm_eval_block_tangent(const frep_program *p, vm_scratch *s, const vm_inputs *in,
                          size_t n, vm_seed seed, double *out, double *dout);

#endif

/* interval.h - interval evaluation of a frep_program over an axis-aligned box.
 *
 * runtime/vm_interval.c runs the same bytecode as the point evaluators with interval
 * operands; mesh/mesh.c uses it to prove octree cells empty or full, so meshing
 * cost follows the surface instead of the volume.
 */
#ifndef FREP_INTERVAL_H
#define FREP_INTERVAL_H

#include "program.h"

#include <float.h>
#include <stdint.h>
#include <string.h>

/* A closed interval [lo, hi]; lo <= hi always ([-inf, inf] means "unknown"). */
typedef struct ival {
    double lo, hi;
} ival;

/* The next double below (above) x, for x not NaN and not -inf (+inf): nextafter(x,
 * -INFINITY) (nextafter(x, INFINITY)) without the library call, which was 5% of
 * meshing the gear (bench/bench_gear.hf), one per rounded bound.  Doubles of one sign
 * are ordered as their bit patterns: one step of the pattern is one ulp. */
static inline double ival_next_down(double x)
{
    if (x == 0) return -DBL_TRUE_MIN;
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    u = x > 0 ? u - 1 : u + 1;
    memcpy(&x, &u, sizeof x);
    return x;
}

static inline double ival_next_up(double x)
{
    if (x == 0) return DBL_TRUE_MIN;
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    u = x > 0 ? u + 1 : u - 1;
    memcpy(&x, &u, sizeof x);
    return x;
}

/* Per-thread scratch (interval stack and slots) sized for one program; as with the
 * point evaluators, a program may be shared, a scratch may not. Free with
 * vm_iscratch_free(). NULL when out of memory. */
typedef struct vm_iscratch vm_iscratch;
vm_iscratch *vm_iscratch_new(const frep_program *p);
void vm_iscratch_free(vm_iscratch *s);

/* Enclosure of f over the box {x0<=x<=x1, y0<=y<=y1, z0<=z<=z1}, box = {x0, y0, z0,
 * x1, y1, z1} (HyperFun's order), with exact parameter values `params` (NULL: the
 * program's own). On return *out holds [lo, hi] with lo <= f(p) <= hi for every point p
 * of the box at which no intermediate value is NaN (a NaN produced by a domain error is
 * not a number to enclose). Results are widened by one ulp per rounded operation, so
 * rounding never makes the enclosure unsound. Programs whose branch conditions are
 * undecided over the box, that read cached primitives, or loop beyond
 * FREP_MAX_LOOP_ITERATIONS give [-inf, inf]. Returns 0, or -1 when the scratch is
 * too small for the program (out is then [-inf, inf]). */
int vm_eval_interval(const frep_program *p, vm_iscratch *s, const double box[6],
                     const double *params, ival *out);

/* Tape pruning (libfive's idea, adapted to R-functions): a pruner holds the analysis
 * of one straight-line program (NULL from vm_pruner_new when the program has
 * branches, arrays indexed at run time or cached primitives, or on allocation
 * failure).  vm_prune() writes into code/pos/orig (each p->ncode entries) a shorter
 * program for the points of `box`: the same inside/outside at every point, the same
 * zero set and surface normals, but other values away from the surface where
 * R-functions were pruned (see vm_interval.c); orig[i] is the original pc of
 * instruction i, for error positions.  *out receives the enclosure of f over the box.
 * The side is kept exactly only for values of magnitude >= *sign_tol: rounding may
 * give values closer to 0 the other sign than the original program gives them, so
 * callers that need the same sign as the original (blocks sharing grid points)
 * re-evaluate those with the original program.  The side is relative to 0: with
 * another iso level the pruned values are useless.
 * A pruner has mutable scratch: one per thread. Returns 0, or -1 as vm_eval_interval. */
typedef struct vm_pruner vm_pruner;
vm_pruner *vm_pruner_new(const frep_program *p);
/* As vm_pruner_new, telling the cases apart: 0 with *out the pruner or NULL (the
 * program cannot be pruned), -1 on allocation failure. */
int vm_pruner_create(const frep_program *p, vm_pruner **out);
void vm_pruner_free(vm_pruner *r);
int vm_prune(vm_pruner *r, vm_iscratch *s, const double box[6], const double *params,
             frep_insn *code, frep_srcpos *pos, uint32_t *orig, uint32_t *ncode, ival *out,
             double *sign_tol);

/* One interval operation (exposed for the property tests): op applied to operands in
 * push order (v[0] first; SELECT: condition, value if true, value if false), k the
 * immediate. Leaves and control flow give [-inf, inf]. */
ival ival_op(frep_opcode op, const ival *v, double k);

#endif

/* vm_internal.h - the per-thread evaluation state shared by runtime/vm.c (values),
 * runtime/vm_tangent.c (forward-mode derivatives) and runtime/eval.c (public API).
 *
 * One vm_scratch per thread: every field is mutable evaluation state, so a scratch is
 * never shared.  Buffers grow on demand to fit the program being run.
 */
#ifndef FREP_VM_INTERNAL_H
#define FREP_VM_INTERNAL_H

#include <stdint.h>

#include "vm.h"

/* The evaluators' main loops are compiled three times, for AVX-512F, AVX2 and the
 * baseline ISA, and picked at load time (GCC function multi-versioning on x86-64
 * GNU/Linux): AVX-512 processes 8 double lanes per instruction, AVX2 4, the baseline 2
 * (the R-function gear's grid takes 0.60x the CPU time with 8 lanes as with 4,
 * doc/benchmarks.md).  No version fuses a product and a sum (-ffp-contract=off,
 * Makefile.am), so all of them round exactly like opsem.h's scalar code. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && \
    !defined(FREP_NO_CLONES)
#define VM_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define VM_CLONES
#endif

/* Entries of the value evaluator's sine/cosine cache: sin and cos of one argument are
 * computed together (opsem_sincos_fast), so the one not asked for is kept for a later
 * instruction wanting it of the same stable vector; a gyroid's 6 sines and cosines of
 * 3 arguments need 4 entries to find all 3 partners in its usual instruction order. */
#define VM_TRIG_CACHE 4

/* Runtime errors of one run of a block: committed to the scratch's totals only when
 * the run completes (a run abandoned for divergent branches records nothing). */
typedef struct vm_errstate {
    uint64_t count;     /* points with an error */
    uint32_t pc;        /* lowest pc with an error; valid when count > 0 */
    double x, y, z;     /* a point that raised the error at pc */
    const char *what;   /* opsem_error_what() of the op at pc */
} vm_errstate;

/* Tangent evaluation state for T tangents (vm_tangent.c); allocated on first use. */
typedef struct vm_tanstate vm_tanstate;

struct vm_scratch {
    /* Capacities (grown by vm_scratch_fit). */
    uint32_t cap_stack, cap_slots, cap_params, cap_prims;

    /* Value evaluator.  Every stack level owns two lane buffers (lv[2L], lv[2L+1]): an
     * operator writes the one its operand does not occupy, so loops never alias and
     * can use restrict.  sp[L] points at the level's value: a level buffer, or the
     * input, slot or parameter vector a leaf pushed (no copy). */
    double **lv;
    const double **sp;
    /* Slots: slotbuf[s] is owned storage; slotp[s] is the slot's current value, either
     * slotbuf[s] or `zeros` (never assigned in this run: variables start at 0). */
    double **slotbuf;
    const double **slotp;
    double *parambuf;          /* parameter j broadcast at parambuf[j*FREP_BLOCK] */
    /* What parambuf holds (vm_broadcast_params): lanes [0, param_lanes) of parameters
     * 0..param_count-1 hold paramval[j]; so blocks with unchanged parameter values (a
     * grid, a point cloud) skip the broadcast, which for small programs cost ~10%. */
    double *paramval;
    size_t param_lanes;
    uint32_t param_count;
    double *zeros;             /* FREP_BLOCK zeros, never written */
    double *trig[VM_TRIG_CACHE]; /* FREP_BLOCK lanes each: the sine/cosine cache */
    const double **primp;      /* per-lane PRIM pointers of a divergent rerun */
    const double **primg;      /* same for prim gradients */
    unsigned char *errlane;    /* per lane: raised an error in the current run (bit 1),
                                * its value must end NaN (VM_LANE_NAN) */
    int nan_lanes;             /* some lane of the current run has VM_LANE_NAN */

    vm_errstate blk;           /* errors of the current run */
    vm_errstate total;         /* errors since the last reset */

    /* Tangent evaluator states, NULL until used: tan[0] for xyz seeds (3 tangents),
     * tan[1] for parameter seeds, kept apart so alternating gradient and parameter
     * derivatives (as a fitter does) never reallocates. */
    vm_tanstate *tan[2];
    const frep_program *cur;   /* program of the current run (error messages) */

    /* The work budget (program.h): loop iterations counted by this scratch and not yet
     * added to the program's `used` (at most VM_WORK_BATCH - 1 between blocks: none),
     * and why the current run stopped: 0 it did not, 1 the budget is spent, 2 the
     * cancel flag is set. */
    uint64_t work_pending;
    int work_over;
};

/* The runtime error of evaluations past the budget (frep_runtime_error.what). */
#define VM_WORK_WHAT "loop iterations over the work budget"
/* ... and of evaluations stopped by the cancel flag (frep_program_set_cancel). */
#define VM_CANCEL_WHAT "loop stopped: evaluation cancelled"

/* Add the pending iterations to w (may be NULL); 1 when the budget is spent (and
 * s->work_over set), else 0. */
int vm_work_flush(vm_scratch *s, frep_work *w);
/* Count n iterations (one backward jump of n lanes) of program p; 1 when the budget is
 * spent. */
static inline int vm_work_spend(vm_scratch *s, const frep_program *p, size_t n)
{
    if (!p->work) return 0;
    s->work_pending += n;
    return s->work_pending >= VM_WORK_BATCH && vm_work_flush(s, p->work);
}
/* A block of a program with loops whose budget is spent: every lane NaN, with the
 * budget's error at its first backward jump. */
void vm_work_refuse(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                    double *out);

/* Make s big enough for p. Returns 0 or -1 on allocation failure. */
int vm_scratch_fit(vm_scratch *s, const frep_program *p);

/* Make parambuf hold p's parameter values (in->params, else the program's) over lanes
 * 0..n-1; a no-op when it already does. */
void vm_broadcast_params(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n);

/* Error bookkeeping used by both evaluators. */
void vm_err_begin(vm_scratch *s, size_t n);
/* Lane i raised an error at pc. */
void vm_err_lane(vm_scratch *s, uint32_t pc, size_t i, const vm_inputs *in);
/* Lane i raised an error at pc after which no value is defined (a store out of the
 * array: the reference interpreter stops there): its result, and its tangents, are NaN
 * whatever comes next (vm_nan_lanes at the end of the run). */
#define VM_LANE_NAN 2u
void vm_err_lane_nan(vm_scratch *s, uint32_t pc, size_t i, const vm_inputs *in);
/* Set out[i] (and dout[c * dstride + i], c < T) to NaN for the run's VM_LANE_NAN lanes. */
void vm_nan_lanes(const vm_scratch *s, size_t n, double *out, double *dout, uint32_t T,
                  size_t dstride);
/* Record the domain errors of instruction pc (opcode op) over n lanes: the lanes where
 * opsem_is_bad(op, a, b), with a = A[i] (A NULL: the immediate ka), b likewise. */
void vm_record_errors(vm_scratch *s, const vm_inputs *in, uint32_t pc, frep_opcode op,
                      const double *A, double ka, const double *B, double kb, size_t n);
/* A runaway loop at the JMP at pc: every lane's value is NaN with an error, committed
 * (the run ends there). */
void vm_runaway(vm_scratch *s, const vm_inputs *in, uint32_t pc, size_t n, double *out);
/* Commit the run's errors (n lanes) into the scratch totals. */
void vm_err_commit(vm_scratch *s, size_t n);
/* Merge error totals: deterministic (lowest pc wins, counts add). */
void vm_err_merge(vm_errstate *into, const vm_errstate *from);
/* The public form of an error total (runtime/eval.c). */
void vm_err_to_public(const vm_errstate *e, frep_runtime_error *out);

/* Inputs of lane i of *in alone, for the lane-by-lane rerun of a divergent block (the
 * PRIM pointers go to s->primp/primg). */
vm_inputs vm_lane_inputs(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t i);

void vm_tan_free(vm_tanstate *t);

/* The input vector of coordinate axis a (0 = x, 1 = y, 2 = z) of an X leaf. */
static inline const double *vm_axis(const vm_inputs *in, uint32_t a)
{
    return a == 0 ? in->x : a == 1 ? in->y : in->z;
}

/* ---- control flow shared by the point evaluators (vm_run, tan_run) --------------
 * Both run all lanes of a block together while their branches agree: a JZ whose
 * condition is zero in every lane jumps, nonzero in every lane falls through, and
 * mixed lanes make the run give up (1) so that the caller reruns the block one lane at
 * a time, which is exact for point-dependent if/while.  A backward JMP counts a loop
 * iteration; past FREP_MAX_LOOP_ITERATIONS, or when the program's work budget is
 * spent, the run ends with NaN and an error. */
typedef enum vm_branch { VM_FALL, VM_JUMP, VM_DIVERGE } vm_branch;

static inline vm_branch vm_jz(const double *C, size_t n)
{
    size_t i, zeros = 0;
    for (i = 0; i < n; i++) zeros += C[i] == 0;
    return zeros == n ? VM_JUMP : zeros == 0 ? VM_FALL : VM_DIVERGE;
}

/* The JMP and JZ cases of a dispatch loop over `pc` with locals in_ (the instruction),
 * loops, n and may_diverge.  RUNAWAY ends a runaway loop's run (its results); COND is
 * the popped condition vector.  A run that diverges without may_diverge (n == 1 cannot
 * diverge) is a bug: -1, as for an unusable program. */
#define VM_CASE_JMP(RUNAWAY)                                                       \
    case FREP_OP_JMP:                                                              \
        if (in_->arg <= pc &&                                                      \
            (++loops > FREP_MAX_LOOP_ITERATIONS || vm_work_spend(s, p, n))) {      \
            RUNAWAY;                                                               \
            return 0;                                                              \
        }                                                                          \
        pc = in_->arg;                                                             \
        continue;

#define VM_CASE_JZ(COND)                                                           \
    case FREP_OP_JZ:                                                               \
        switch (vm_jz(COND, n)) {                                                  \
        case VM_JUMP: pc = in_->arg; continue;                                     \
        case VM_DIVERGE: return may_diverge ? 1 : -1;                              \
        case VM_FALL: break;                                                       \
        }                                                                          \
        break;

#endif

/* prune.h - exact interval tape pruning and the tiled grid evaluator built on it.
 *
 * Sits between the bytecode (program.h) and the point VM (vm.h): for a sub-box of a
 * grid, an interval pass over the program decides the min/max set operations and
 * selects whose one operand dominates, and a shorter program is built that computes
 * bit for bit the same values at every point of the sub-box.  `frep eval --grid` runs
 * it (cli/cmd_eval.c); doc/architecture.md, "Tape pruning", explains the rules.
 */
#ifndef FREP_PRUNE_H
#define FREP_PRUNE_H

#include <stdint.h>

#include "frep.h"
#include "interval.h"
#include "program.h"

/* Tile edge of the grid evaluator, in grid points: 16^3 = 4096 points (16 VM blocks)
 * amortize the interval pass and program rebuild (~10-20 us for 450 instructions)
 * while still following the surface closely; 8 pays more for pruning than it saves,
 * 32 prunes less (measured in doc/benchmarks.md). */
#define PRUNE_TILE 16

/* Tiles per edge of a super-tile (64 x 64 x 16 points): pruned first, so each of its
 * tiles analyses only what the super-tile's program kept (two-level, as fidget). */
#define PRUNE_SUPER 4

/* Most tiles evaluated in one parallel region by the grid evaluator (whole slabs of
 * PRUNE_TILE planes; at least one slab): their per-tile errors and summaries (80 bytes
 * each) are kept until the region ends, so this bounds that memory (5 MB) while a
 * 1024^3 grid's 4096 tiles per slab still run 16 slabs per region. */
#define PRUNE_RUN_TILES 65536

/* Largest magnitude of an interval bound trusted by the pruner: below it no operation
 * of two bounded operands (sum, product of one with a bounded constant, the squares
 * of an R-function) overflows to infinity, so inf - inf or 0 * inf, and thus NaN,
 * cannot appear unseen at a point of the box. */
#define PRUNE_MAX_MAG 1e150

/* The analysis of one program, immutable once built and shared by threads.  NULL from
 * prune_plan_new when the program cannot be pruned: it has branches, indexed arrays
 * or cached primitives, does not end with exactly one value, has no min, max or
 * select to decide (nothing to prune), or memory ran out. */
typedef struct prune_plan prune_plan;
prune_plan *prune_plan_new(const frep_program *p);
void prune_plan_free(prune_plan *pl);

/* Per-thread pruning state: the interval trace and the pruned program's storage. */
typedef struct prune_state prune_state;
prune_state *prune_state_new(const prune_plan *pl);
void prune_state_free(prune_state *st);

/* The program for the points of box {x0, y0, z0, x1, y1, z1} with parameter values
 * params (NULL: the program's own): valid until the next call with st, same slots,
 * parameters and maximum stack as the original (the original's vm_scratch fits it).
 * At every point of the box it computes the original's value bit for bit and raises
 * the same domain errors.  *enclosure (may be NULL) receives f's interval over the box
 * ([-inf, inf] when unknown). */
const frep_program *prune_for_box(const prune_plan *pl, prune_state *st, const double box[6],
                                  const double *params, ival *enclosure);
/* The same for a box inside the box `parent` was last pruned for (parent != st):
 * starts from the parent's decisions and analyses only the parent's program, so a
 * hierarchy of boxes costs less than pruning each from scratch.  The values and
 * errors are prune_for_box's (the exact rewrites made may differ).  parent NULL: the
 * same as prune_for_box. */
const frep_program *prune_for_subbox(const prune_plan *pl, prune_state *st,
                                     const prune_state *parent, const double box[6],
                                     const double *params, ival *enclosure);
/* Original pc of instruction pc of the last pruned program (error positions). */
uint32_t prune_orig_pc(const prune_state *st, uint32_t pc);

/* Evaluate planes k0 .. k0+nk-1 of the N x N x N grid of box (x_i = lo + step * i,
 * step = (hi - lo) / (N - 1)) into f[((k - k0) * N + j) * N + i], tile by tile over
 * nthreads OpenMP threads (<= 0: the default), pruning each tile's program when
 * `prune` is nonzero and the program allows it.  Values never depend on pruning or the
 * thread count; the error summary is merged into *err (count, lowest original pc, a
 * point of the lowest-numbered tile with that pc), deterministic too.  *insns (may be
 * NULL) accumulates instructions x points evaluated.  Returns 0, or -1 on allocation
 * failure. */
int prune_eval_grid_planes(const frep_program *p, long n, const double box[6], long k0,
                           long nk, int prune, int nthreads, double *f,
                           frep_runtime_error *err, double *insns);

/* Summary of grid values: NaNs are counted apart; min/max cover the other values
 * (infinities included), sum the finite ones. */
typedef struct prune_grid_stats {
    uint64_t inside;        /* values >= 0 */
    uint64_t nans;
    double min, max, sum;
    /* With PRUNE_GRID_SINGLE: the blocks computed in float, and of them those
     * re-evaluated in double because some value was within the float error bound of 0 */
    uint64_t single, redone;
} prune_grid_stats;
/* Start value of a summary: nothing seen (min +inf, max -inf). */
void prune_grid_stats_init(prune_grid_stats *s);

/* prune_eval_grid_planes, with f optional (NULL: the values are not stored, so no
 * slab buffer is needed) and the planes' summary added to *stats (may be NULL), each
 * block summarized as soon as it is evaluated.  The sum's order of additions is fixed
 * by the tiling alone (per tile, then tiles in order), so it is the same with or
 * without pruning and at any thread count. */
int prune_eval_grid_summary(const frep_program *p, long n, const double box[6], long k0,
                            long nk, int prune, int nthreads, double *f,
                            prune_grid_stats *stats, frep_runtime_error *err, double *insns);

/* The whole N x N x N grid's summary: the same figures as prune_eval_grid_summary
 * called for the slabs of PRUNE_TILE planes k0 = 0, PRUNE_TILE, ... in order into one
 * *stats, *err merged the same way, but in few parallel regions (PRUNE_RUN_TILES), each
 * a work queue of super-tiles, and with one thread when the job is small
 * (frep_threads_for): so the threads neither wait at barriers between slabs nor cost
 * more than they gain.  *threads_used (may be NULL) receives the threads it ran on. */
int prune_eval_grid_whole(const frep_program *p, long n, const double box[6], int prune,
                          int nthreads, prune_grid_stats *stats, frep_runtime_error *err,
                          double *insns, int *threads_used);

/* prune_eval_grid_whole with flags: PRUNE_GRID_SINGLE computes the values in float
 * (runtime/vm_f32.h) wherever a tile's program is supported, at least VM_F32_MIN_CODE
 * long, and its error bound finite,
 * and re-evaluates in double every block with a value within the bound of 0 (or NaN):
 * the inside and NaN counts and the runtime errors are those of double, min/max/sum
 * are within the bound of double's.  Without the flag, the same as above. */
#define PRUNE_GRID_SINGLE 0x1
int prune_eval_grid_flags(const frep_program *p, long n, const double box[6], int prune,
                          int nthreads, unsigned flags, prune_grid_stats *stats,
                          frep_runtime_error *err, double *insns, int *threads_used);

#endif

/* api_eval.c - evaluation in the public API beyond points: runtime/vm_interval.c's
 * enclosure of a program over a box, with its per-thread scratch, and the summary of
 * a regular grid (runtime/prune.c's tiled, pruned evaluator, as frep eval --grid).
 */
#include "config.h"

#include "api.h"
#include "interval.h"
#include "prune.h"
#include "vm_f32.h"

#include <math.h>
#include <string.h>

frep_interval_scratch *frep_interval_scratch_new(const frep_program *p)
{
    return (frep_interval_scratch *)vm_iscratch_new(p);
}

void frep_interval_scratch_free(frep_interval_scratch *s)
{
    vm_iscratch_free((vm_iscratch *)s);
}

int frep_eval_interval(const frep_program *p, frep_interval_scratch *s, const double box[6],
                       const double *params, double *lo, double *hi)
{
    ival out = { -INFINITY, INFINITY };
    int rc = p && s && box ? vm_eval_interval(p, (vm_iscratch *)s, box, params, &out) : -1;
    *lo = out.lo;
    *hi = out.hi;
    return rc;
}

/* ---- evaluation on a grid (frep eval --grid) ---- */

void frep_grid_options_init(frep_grid_options *o)
{
    memset(o, 0, sizeof *o);
    o->n = 64;
    o->prune = 1;
}

/* The precision the grid ran in: single only when asked, the CPU can and the program
 * has only operations the float path has. */
static int grid_precision(const frep_program *p, int single, unsigned *flags)
{
    *flags = 0;
    if (!single) return FREP_GRID_DOUBLE;
    if (!vm_f32_cpu_ok()) return FREP_GRID_DOUBLE_NO_CPU;
    *flags = PRUNE_GRID_SINGLE;
    return vm_f32_supported(p) ? FREP_GRID_SINGLE : FREP_GRID_DOUBLE_NO_OPS;
}

int frep_eval_grid(const frep_program *p, const frep_grid_options *o, frep_grid_summary *s,
                   frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    memset(s, 0, sizeof *s);
    frep_grid_options def;
    if (!o) {
        frep_grid_options_init(&def);
        o = &def;
    }
    if (!p) {
        frep_error_set(&e, FREP_EINPUT, "no program");
        return api_fail(&d, &e);
    }
    if (o->n < FREP_GRID_MIN_N || o->n > FREP_GRID_MAX_N) {
        frep_error_set(&e, FREP_EINPUT, "grid of %ld points per axis: expected %d..%d", o->n,
                       FREP_GRID_MIN_N, FREP_GRID_MAX_N);
        return api_fail(&d, &e);
    }
    if (o->has_box) memcpy(s->box, o->box, sizeof s->box);
    else if (!frep_program_box(p, s->box))
        for (int i = 0; i < 3; i++) {
            s->box[i] = -API_DEFAULT_BOX;
            s->box[i + 3] = API_DEFAULT_BOX;
        }
    unsigned flags;
    s->precision = grid_precision(p, o->single, &flags);
    prune_grid_stats st;
    prune_grid_stats_init(&st);
    int threads = 1;
    if (prune_eval_grid_flags(p, o->n, s->box, o->prune, o->nthreads, flags, &st, &s->errors,
                              &s->insns, &threads) != 0)
        return api_fail(&d, &e);
    s->points = (uint64_t)o->n * (uint64_t)o->n * (uint64_t)o->n;
    s->inside = st.inside;
    s->nans = st.nans;
    s->min = st.min;
    s->max = st.max;
    s->sum = st.sum;
    s->single_blocks = st.single;
    s->redone_blocks = st.redone;
    s->threads = threads;
    return 0;
}

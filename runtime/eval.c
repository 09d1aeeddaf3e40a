/* eval.c - the public evaluation API of libfrep (frep.h): scratch, runtime errors,
 * and frep_eval* over any number of points.
 *
 * Splits the points into blocks of FREP_BLOCK for the evaluators of runtime/vm*.c;
 * the _par variants spread the blocks over OpenMP threads, one scratch per thread, in
 * one parallel region with no barrier inside it, and on one thread when the job is
 * smaller than FREP_PAR_MIN_WORK (threads.h).
 * Results are per point, so they do not depend on the thread count; runtime errors
 * are merged in block order (lowest pc wins, counts add), so they do not either.
 */
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "opsem.h"
#include "threads.h"
#include "vm_internal.h"

/* ---- scratch and errors ------------------------------------------------------------ */

frep_scratch *frep_scratch_new(const frep_program *p)
{
    return (frep_scratch *)vm_scratch_new(p);
}

void frep_scratch_free(frep_scratch *s)
{
    vm_scratch_free((vm_scratch *)s);
}

void vm_err_to_public(const vm_errstate *e, frep_runtime_error *out)
{
    memset(out, 0, sizeof *out);
    out->count = e->count;
    if (e->count) {
        out->pc = e->pc;
        out->what = e->what;
        out->x = e->x;
        out->y = e->y;
        out->z = e->z;
    }
}

void frep_scratch_errors(const frep_scratch *s, frep_runtime_error *e)
{
    vm_err_to_public(&((const vm_scratch *)s)->total, e);
}

void frep_scratch_reset_errors(frep_scratch *s)
{
    memset(&((vm_scratch *)s)->total, 0, sizeof(vm_errstate));
}

/* Longest runtime error message: the fixed text plus three %.9g numbers. */
#define EVAL_MSG_MAX 256

void frep_report_runtime_error(const frep_program *p, const frep_runtime_error *e,
                               frep_diag_fn diag, void *user)
{
    char msg[EVAL_MSG_MAX];
    frep_diag d;
    if (!e || e->count == 0 || !diag) return;
    snprintf(msg, sizeof msg, "%s at %llu point%s, e.g. (%.9g, %.9g, %.9g)",
             e->what ? e->what : "domain error", (unsigned long long)e->count,
             e->count == 1 ? "" : "s", e->x, e->y, e->z);
    memset(&d, 0, sizeof d);
    d.severity = FREP_ERROR;
    d.file = p ? p->file : NULL;
    if (p && p->pos && e->pc < p->ncode && p->pos[e->pc].line) {
        d.line = p->pos[e->pc].line;
        d.col = p->pos[e->pc].col;
        d.len = p->pos[e->pc].len ? p->pos[e->pc].len : 1;
    }
    d.message = msg;
    diag(user, &d);
}

/* ---- serial evaluation ----------------------------------------------------------------- */

static int check_args(const frep_program *p, const frep_scratch *s)
{
    if (!p || !s || !p->code || p->ncode == 0) return -1;
    /* Cached primitives cannot be supplied through this API: use vm_eval_block. */
    if (p->flags & PROG_HAS_PRIMS) return -1;
    return 0;
}

static vm_inputs block_inputs(const double *x, const double *y, const double *z,
                              const double *params, size_t off)
{
    vm_inputs in;
    memset(&in, 0, sizeof in);
    in.x = x + off;
    in.y = y + off;
    in.z = z + off;
    in.params = params;
    return in;
}

static size_t block_len(size_t n, size_t off)
{
    return n - off < FREP_BLOCK ? n - off : FREP_BLOCK;
}

int frep_eval(const frep_program *p, frep_scratch *s, size_t n, const double *x,
              const double *y, const double *z, const double *params, double *f)
{
    size_t off;
    if (check_args(p, s) < 0) return -1;
    for (off = 0; off < n; off += FREP_BLOCK) {
        vm_inputs in = block_inputs(x, y, z, params, off);
        if (vm_eval_block(p, (vm_scratch *)s, &in, block_len(n, off), f + off) < 0) return -1;
    }
    return 0;
}

/* One block of values and gradient into the caller's arrays; straight into them when
 * they are the rows of one array (gy = gx + nb, gz = gy + nb), as the evaluator lays
 * its tangents out. */
static int grad_block(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t nb,
                      double *f, double *gx, double *gy, double *gz)
{
    if (gy == gx + nb && gz == gy + nb)
        return vm_eval_block_tangent(p, s, in, nb, VM_SEED_XYZ, f, gx) < 0 ? -1 : 0;
    double d[3 * FREP_BLOCK];
    if (vm_eval_block_tangent(p, s, in, nb, VM_SEED_XYZ, f, d) < 0) return -1;
    memcpy(gx, d, nb * sizeof *d);
    memcpy(gy, d + nb, nb * sizeof *d);
    memcpy(gz, d + 2 * nb, nb * sizeof *d);
    return 0;
}

int frep_eval_grad(const frep_program *p, frep_scratch *s, size_t n, const double *x,
                   const double *y, const double *z, const double *params, double *f,
                   double *gx, double *gy, double *gz)
{
    size_t off;
    if (check_args(p, s) < 0) return -1;
    for (off = 0; off < n; off += FREP_BLOCK) {
        vm_inputs in = block_inputs(x, y, z, params, off);
        if (grad_block(p, (vm_scratch *)s, &in, block_len(n, off), f + off, gx + off,
                       gy + off, gz + off) < 0)
            return -1;
    }
    return 0;
}

int frep_eval_dparams(const frep_program *p, frep_scratch *s, size_t n, const double *x,
                      const double *y, const double *z, const double *params, double *f,
                      double *dp)
{
    size_t off, np;
    double *d;
    if (check_args(p, s) < 0) return -1;
    np = p->nparams;
    /* One block: its tangent rows are dp's rows (stride n), no copy. */
    if (n <= FREP_BLOCK) {
        vm_inputs in = block_inputs(x, y, z, params, 0);
        return vm_eval_block_tangent(p, (vm_scratch *)s, &in, n, VM_SEED_PARAMS, f, dp) < 0
                   ? -1 : 0;
    }
    d = frep_malloc((np ? np : 1) * FREP_BLOCK * sizeof *d);
    if (!d) return -1;
    for (off = 0; off < n; off += FREP_BLOCK) {
        vm_inputs in = block_inputs(x, y, z, params, off);
        size_t nb = block_len(n, off), j;
        if (vm_eval_block_tangent(p, (vm_scratch *)s, &in, nb, VM_SEED_PARAMS, f + off, d) < 0) {
            frep_free(d);
            return -1;
        }
        for (j = 0; j < np; j++) memcpy(dp + j * n + off, d + j * nb, nb * sizeof *d);
    }
    frep_free(d);
    return 0;
}

/* ---- parallel evaluation ------------------------------------------------------------ */

/* What one parallel evaluation computes; grad is NULL for values only. */
typedef struct par_job {
    const frep_program *p;
    size_t n;
    const double *x, *y, *z, *params;
    double *f, *gx, *gy, *gz;
} par_job;

/* Blocks [b0, b1) of a job with scratch s. */
static int par_blocks(const par_job *j, vm_scratch *s, size_t b0, size_t b1)
{
    size_t b;
    for (b = b0; b < b1; b++) {
        size_t off = b * FREP_BLOCK;
        vm_inputs in = block_inputs(j->x, j->y, j->z, j->params, off);
        size_t nb = block_len(j->n, off);
        int rc = j->gx ? grad_block(j->p, s, &in, nb, j->f + off, j->gx + off, j->gy + off,
                                    j->gz + off)
                       : vm_eval_block(j->p, s, &in, nb, j->f + off);
        if (rc < 0) return -1;
    }
    return 0;
}

/* Blocks per work unit of a parallel evaluation (4096 points): the threads take units
 * as they finish them, so a thread slowed down (descheduled on a busy machine) delays
 * the job by at most one unit, not by its share of the job. */
#define PAR_UNIT_BLOCKS 16

/* A parallel evaluation's units, shared by its threads: s[t] is thread t's scratch,
 * errs[k] unit k's errors. */
typedef struct par_team {
    const par_job *j;
    size_t nblocks;
    vm_scratch **s;
    vm_errstate *errs;
    _Atomic int failed;
} par_team;

static void par_chunk(void *ctx, int t, long k0, long k1)
{
    par_team *T = ctx;
    vm_scratch *s = T->s[t];
    for (long k = k0; k < k1; k++) {
        size_t b0 = (size_t)k * PAR_UNIT_BLOCKS;
        size_t b1 = b0 + PAR_UNIT_BLOCKS < T->nblocks ? b0 + PAR_UNIT_BLOCKS : T->nblocks;
        memset(&s->total, 0, sizeof s->total);
        if (par_blocks(T->j, s, b0, b1) < 0) atomic_store(&T->failed, 1);
        T->errs[k] = s->total;
    }
}

static int par_run(const par_job *j, int nthreads, frep_runtime_error *err)
{
    size_t nblocks = (j->n + FREP_BLOCK - 1) / FREP_BLOCK;
    vm_errstate total;
    memset(&total, 0, sizeof total);
    if (err) memset(err, 0, sizeof *err);
    if (!j->p || !j->p->code || (j->p->flags & PROG_HAS_PRIMS)) return -1;
    if (nblocks == 0) return 0;
    size_t nunits = (nblocks + PAR_UNIT_BLOCKS - 1) / PAR_UNIT_BLOCKS, u;
    int nt = frep_threads_for(nthreads, (double)j->n * (double)j->p->ncode, nunits);
    if (nt > FREP_PAR_MAX_THREADS) nt = FREP_PAR_MAX_THREADS;
    /* each unit's errors apart, merged in unit order: the serial block order */
    par_team T = { j, nblocks, frep_calloc((size_t)nt, sizeof *T.s),
                   frep_calloc(nunits, sizeof *T.errs), 0 };
    int failed = !T.s || !T.errs;
    for (int t = 0; t < nt && !failed; t++)
        if (!(T.s[t] = vm_scratch_new(j->p))) failed = 1;
    if (!failed) {
        frep_par_for(nt, (long)nunits, 1, par_chunk, &T);
        failed = atomic_load(&T.failed);
        for (u = 0; u < nunits; u++) vm_err_merge(&total, &T.errs[u]);
    }
    if (T.s)
        for (int t = 0; t < nt; t++) vm_scratch_free(T.s[t]);
    frep_free(T.s);
    frep_free(T.errs);
    if (err) vm_err_to_public(&total, err);
    return failed ? -1 : 0;
}

int frep_eval_par(const frep_program *p, size_t n, const double *x, const double *y,
                  const double *z, const double *params, double *f, int nthreads,
                  frep_runtime_error *err)
{
    par_job j = {p, n, x, y, z, params, f, NULL, NULL, NULL};
    return par_run(&j, nthreads, err);
}

int frep_eval_grad_par(const frep_program *p, size_t n, const double *x, const double *y,
                       const double *z, const double *params, double *f, double *gx,
                       double *gy, double *gz, int nthreads, frep_runtime_error *err)
{
    par_job j = {p, n, x, y, z, params, f, gx, gy, gz};
    return par_run(&j, nthreads, err);
}

size_t frep_program_nattrs(const frep_program *p) { return p->nattrs; }

/* Each attribute is a program of its own (compiled from the same lowered model with
 * s[k+1] as its root): evaluate it into a column, then interleave the columns. */
int frep_eval_attrs_par(const frep_program *p, size_t n, const double *x, const double *y,
                        const double *z, const double *params, double *s, int nthreads,
                        frep_runtime_error *err)
{
    size_t K = p->nattrs, k, i;
    double *col;
    if (err) memset(err, 0, sizeof *err);
    if (K == 0 || n == 0) return 0;
    if (n > SIZE_MAX / sizeof *col) return -1;
    col = frep_malloc(n * sizeof *col);
    if (!col) return -1;
    for (k = 0; k < K; k++) {
        frep_runtime_error e;
        if (frep_eval_par(p->attrs[k], n, x, y, z, params, col, nthreads, &e) != 0) {
            frep_free(col);
            return -1;
        }
        if (err && e.count > 0 && err->count == 0) *err = e;
        for (i = 0; i < n; i++) s[i * K + k] = col[i];
    }
    frep_free(col);
    return 0;
}

/* field.c - the field of a compiled program (mesh_field_program, mesh.h): values and
 * gradients from the VM, enclosures from the interval evaluator, and per-block tape
 * pruning (vm_prune) behind the focus callback.  The polygonizer and the sampler see
 * only the mesh_field callbacks; runtime errors are merged over the threads here.
 */
#include "config.h"

#include "alloc.h"
#include "interval.h"
#include "mesh.h"
#include "program.h"

#include <string.h>

typedef struct prog_field {
    const frep_program *p;
    const double *params;
    frep_runtime_error err;   /* merged from the threads' scratches as they are freed */
} prog_field;

/* Merge runtime error e into *acc: counts add, the lowest pc names the error (the
 * rule of frep_eval_par, so the report does not depend on the thread count). */
static void merge_error(frep_runtime_error *acc, const frep_runtime_error *e)
{
    if (e->count == 0) return;
    uint64_t c = acc->count;
    if (c == 0 || e->pc < acc->pc) *acc = *e;
    acc->count = c + e->count;
}

typedef struct prog_thread {
    frep_scratch *s;
    vm_iscratch *is;
    vm_pruner *pr;            /* NULL: the program cannot be pruned */
    frep_program sub;         /* the program pruned for the focused box (own code, pos) */
    uint32_t *orig;           /* sub's pc -> the original pc */
    const frep_program *cur;  /* what eval and grad run: the program or &sub */
    int have_sub;             /* sub is the pruned program for sub_box */
    double sub_box[6], sub_tol;
    frep_runtime_error err;   /* errors raised by sub, with original pcs */
} prog_thread;

static void prog_thread_free(void *ctx, void *ts)
{
    prog_thread *t = ts;
    prog_field *pf = ctx;
    if (!t) return;
    if (t->s) {
        /* thread states are freed one at a time (after the parallel regions) */
        frep_runtime_error e;
        frep_scratch_errors(t->s, &e);
        merge_error(&pf->err, &e);
    }
    merge_error(&pf->err, &t->err);
    frep_scratch_free(t->s);
    vm_iscratch_free(t->is);
    vm_pruner_free(t->pr);
    frep_free(t->sub.code);
    frep_free(t->sub.pos);
    frep_free(t->orig);
    frep_free(t);
}

static void *prog_thread_new(void *ctx)
{
    prog_field *pf = ctx;
    prog_thread *t = frep_calloc(1, sizeof *t);
    if (!t) return NULL;
    t->s = frep_scratch_new(pf->p);
    t->is = vm_iscratch_new(pf->p);
    t->cur = pf->p;
    if (!t->s || !t->is) {
        prog_thread_free(ctx, t);
        return NULL;
    }
    if (vm_pruner_create(pf->p, &t->pr) != 0) {
        prog_thread_free(ctx, t);
        return NULL;
    }
    if (t->pr) {
        size_t n = pf->p->ncode;
        t->sub = *pf->p;
        t->sub.code = frep_malloc(n * sizeof *t->sub.code);
        t->sub.pos = frep_malloc(n * sizeof *t->sub.pos);
        t->orig = frep_malloc(n * sizeof *t->orig);
        if (!t->sub.code || !t->sub.pos || !t->orig) {
            prog_thread_free(ctx, t);
            return NULL;
        }
    }
    return t;
}

/* Errors raised by the pruned program name its pcs: map them to the original's. */
static void prog_harvest_errors(prog_thread *t)
{
    if (t->cur != &t->sub) return;
    frep_runtime_error e;
    frep_scratch_errors(t->s, &e);
    if (e.count == 0) return;
    e.pc = e.pc < t->sub.ncode ? t->orig[e.pc] : 0;
    merge_error(&t->err, &e);
    frep_scratch_reset_errors(t->s);
}

static int prog_eval(void *ctx, void *ts, size_t n, const double *x, const double *y,
                     const double *z, double *f)
{
    prog_field *pf = ctx;
    prog_thread *t = ts;
    int rc = frep_eval(t->cur, t->s, n, x, y, z, pf->params, f);
    prog_harvest_errors(t);
    return rc;
}

static int prog_grad(void *ctx, void *ts, size_t n, const double *x, const double *y,
                     const double *z, double *f, double *gx, double *gy, double *gz)
{
    prog_field *pf = ctx;
    prog_thread *t = ts;
    int rc = frep_eval_grad(t->cur, t->s, n, x, y, z, pf->params, f, gx, gy, gz);
    prog_harvest_errors(t);
    return rc;
}

static int prog_focus(void *ctx, void *ts, const double box[6], double *sign_tol)
{
    prog_field *pf = ctx;
    prog_thread *t = ts;
    t->cur = pf->p;
    if (sign_tol) *sign_tol = 0;
    if (!box || !t->pr) return 0;
    if (!t->have_sub || memcmp(box, t->sub_box, sizeof t->sub_box) != 0) {
        ival r;
        uint32_t n;
        t->have_sub = 0;
        if (vm_prune(t->pr, t->is, box, pf->params, t->sub.code, t->sub.pos, t->orig, &n, &r,
                     &t->sub_tol) != 0)
            return 0;
        t->sub.ncode = n;
        memcpy(t->sub_box, box, sizeof t->sub_box);
        t->have_sub = 1;
    }
    t->cur = &t->sub;
    if (sign_tol) *sign_tol = t->sub_tol;
    return 0;
}

static int prog_interval(void *ctx, void *ts, const double box[6], double *lo, double *hi)
{
    prog_field *pf = ctx;
    prog_thread *t = ts;
    ival r;
    int rc = vm_eval_interval(pf->p, t->is, box, pf->params, &r);
    *lo = r.lo;
    *hi = r.hi;
    return rc;
}

int mesh_field_program(mesh_field *f, const frep_program *p, const double *params)
{
    prog_field *pf = frep_malloc(sizeof *pf);
    if (!pf) return -1;
    pf->p = p;
    pf->params = params;
    memset(&pf->err, 0, sizeof pf->err);
    f->ctx = pf;
    f->thread_new = prog_thread_new;
    f->thread_free = prog_thread_free;
    f->eval = prog_eval;
    f->grad = prog_grad;
    f->interval = prog_interval;
    f->focus = prog_focus;
    f->cost = (double)p->ncode;
    return 0;
}

void mesh_field_program_errors(const mesh_field *f, frep_runtime_error *e)
{
    const prog_field *pf = f->ctx;
    *e = pf->err;
}

void mesh_field_program_free(mesh_field *f)
{
    frep_free(f->ctx);
    f->ctx = NULL;
}

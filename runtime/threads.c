/* threads.c - frep_par_for (threads.h): the pool behind the parallel loops of the
 * mesher (mesh/octree.c, mesh/polygonize.c), the sampler (mesh/sample.c), the point
 * evaluators (runtime/eval.c) and the grid evaluator (runtime/prune.c).  Threads are
 * created per loop and joined asleep; the loops it runs are long enough
 * (frep_threads_for, frep_par_for_late) that creating them is noise.
 */
#include "config.h"

#include "threads.h"

#include <stdatomic.h>

#ifdef FREP_HAVE_PTHREADS
#include <pthread.h>
#endif

typedef struct par_loop par_loop;

typedef struct par_member {
    par_loop *loop;
    int thread;
} par_member;

/* One loop: what to run, the next chunk to hand out, and its threads.  want, started
 * and th are touched by the calling thread only (it alone starts helpers). */
struct par_loop {
    frep_par_fn fn;
    void *ctx;
    long n, chunk;
    _Atomic long next;        /* first item of the next chunk */
    frep_par_left_fn left;    /* NULL: the helpers started before the loop */
    int want, started;        /* threads wanted and running, the calling one included */
    par_member m[FREP_PAR_MAX_THREADS];
#ifdef FREP_HAVE_PTHREADS
    pthread_t th[FREP_PAR_MAX_THREADS];
#endif
};

static void *par_member_run(void *arg);

/* Start helpers started .. want-1; never tried again (one that cannot be started
 * leaves its share to the others). */
static void par_start_helpers(par_loop *L)
{
#ifdef FREP_HAVE_PTHREADS
    for (int k = L->started; k < L->want; k++) {
        L->m[k].loop = L;
        L->m[k].thread = k;
        if (pthread_create(&L->th[k], NULL, par_member_run, &L->m[k]) != 0) break;
        L->started++;
    }
#endif
    L->want = L->started;
}

/* Take chunks until none is left; the calling thread, alone so far in a late loop,
 * starts the helpers once enough work is left. */
static void *par_member_run(void *arg)
{
    par_member *m = arg;
    par_loop *L = m->loop;
    for (;;) {
        long i0 = atomic_fetch_add(&L->next, L->chunk);
        if (i0 >= L->n) break;
        long i1 = L->n - i0 > L->chunk ? i0 + L->chunk : L->n;
        L->fn(L->ctx, m->thread, i0, i1);
        if (m->thread == 0 && L->started < L->want && i1 < L->n &&
            L->left(L->ctx, i1, L->n) >= FREP_PAR_MIN_WORK)
            par_start_helpers(L);
    }
    return NULL;
}

int frep_par_for_late(int nt, long n, long chunk, frep_par_fn fn, frep_par_left_fn left,
                      void *ctx)
{
    if (chunk < 1) chunk = 1;
    if (n <= 0) return 1;
    long nchunks = (n - 1) / chunk + 1;
    if (nt > FREP_PAR_MAX_THREADS) nt = FREP_PAR_MAX_THREADS;
    if ((long)nt > nchunks) nt = (int)nchunks;
    if (nt < 1) nt = 1;
#ifndef FREP_HAVE_PTHREADS
    nt = 1;
#endif
    par_loop L;
    L.fn = fn;
    L.ctx = ctx;
    L.n = n;
    L.chunk = chunk;
    atomic_init(&L.next, 0);
    L.left = left;
    L.want = nt;
    L.started = 1;
    L.m[0].loop = &L;
    L.m[0].thread = 0;
    if (!left) par_start_helpers(&L);
    par_member_run(&L.m[0]);
#ifdef FREP_HAVE_PTHREADS
    for (int k = 1; k < L.started; k++) pthread_join(L.th[k], NULL);
#endif
    return L.started;
}

int frep_par_for(int nt, long n, long chunk, frep_par_fn fn, void *ctx)
{
    return frep_par_for_late(nt, n, chunk, fn, NULL, ctx);
}

/* threads.c - frep_par_for (threads.h): the pool behind the parallel loops of the
 * mesher (mesh/octree.c, mesh/polygonize.c), the sampler (mesh/sample.c) and the
 * point evaluators (runtime/eval.c).  Threads are created per loop and joined asleep;
 * the loops it runs are long enough (frep_threads_for) that creating them is noise.
 */
#include "config.h"

#include "threads.h"

#include <stdatomic.h>

#ifdef FREP_HAVE_PTHREADS
#include <pthread.h>
#endif

/* One loop: what to run and the next chunk to hand out. */
typedef struct par_loop {
    frep_par_fn fn;
    void *ctx;
    long n, chunk;
    _Atomic long next;        /* first item of the next chunk */
} par_loop;

typedef struct par_member {
    par_loop *loop;
    int thread;
} par_member;

/* Take chunks until none is left. */
static void *par_member_run(void *arg)
{
    par_member *m = arg;
    par_loop *L = m->loop;
    for (;;) {
        long i0 = atomic_fetch_add(&L->next, L->chunk);
        if (i0 >= L->n) break;
        long i1 = L->n - i0 > L->chunk ? i0 + L->chunk : L->n;
        L->fn(L->ctx, m->thread, i0, i1);
    }
    return NULL;
}

int frep_par_for(int nt, long n, long chunk, frep_par_fn fn, void *ctx)
{
    if (chunk < 1) chunk = 1;
    if (n <= 0) return 1;
    long nchunks = (n - 1) / chunk + 1;
    if (nt > FREP_PAR_MAX_THREADS) nt = FREP_PAR_MAX_THREADS;
    if ((long)nt > nchunks) nt = (int)nchunks;
    par_loop L = { fn, ctx, n, chunk, 0 };
    par_member m[FREP_PAR_MAX_THREADS];
    int started = 1;
    m[0].loop = &L;
    m[0].thread = 0;
#ifdef FREP_HAVE_PTHREADS
    pthread_t th[FREP_PAR_MAX_THREADS];
    for (int k = 1; k < nt; k++) {
        m[started].loop = &L;
        m[started].thread = started;
        if (pthread_create(&th[started], NULL, par_member_run, &m[started]) != 0) break;
        started++;
    }
#else
    (void)nt;
#endif
    par_member_run(&m[0]);
#ifdef FREP_HAVE_PTHREADS
    for (int k = 1; k < started; k++) pthread_join(th[k], NULL);
#endif
    return started;
}

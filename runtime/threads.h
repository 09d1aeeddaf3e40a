/* threads.h - the thread counts of the library's parallel loops and the one pool that
 * runs them (frep_par_for, runtime/threads.c): POSIX threads joined asleep, units
 * handed out from a shared counter.  The OpenMP conditional is in this one place: a
 * build without OpenMP runs every loop on one thread as thread 0 of a team of one.
 */
#ifndef FREP_THREADS_H
#define FREP_THREADS_H

#include <stddef.h>

#ifdef _OPENMP
#include <omp.h>
#endif

/* The pool's helpers are POSIX threads where OpenMP is (-fopenmp brings -pthread); a
 * build without OpenMP is serial. */
#if defined(_OPENMP) && defined(__unix__)
#define FREP_HAVE_PTHREADS 1
#endif

/* The threads of a run asking for `requested` (<= 0: OpenMP's default). Always >= 1. */
static inline int frep_threads(int requested)
{
#ifdef _OPENMP
    return requested > 0 ? requested : omp_get_max_threads();
#else
    (void)requested;
    return 1;
#endif
}

/* Smallest job given more than one thread, in node-evaluations (instructions x
 * points): 4e6 take ~1 ms on one core at 4e9 node-evaluations/s, while starting a
 * parallel region and waking its threads costs 10-100 us (creating them, the first
 * time, more), so a smaller job cannot gain much, and on a busy machine, where the
 * region's end waits for a thread that has no core yet, it loses (tests/test_vm.c
 * checks the rule; doc/benchmarks.md, "Threads that never make a job slower"). */
#define FREP_PAR_MIN_WORK 4e6

/* The threads for a job of `work` node-evaluations split into `units` independent
 * pieces, asking for `requested` (<= 0: OpenMP's default): 1 below FREP_PAR_MIN_WORK,
 * never more than the units, else frep_threads(requested). */
static inline int frep_threads_for(int requested, double work, size_t units)
{
    int nt = frep_threads(requested);
    if (work < FREP_PAR_MIN_WORK || units < 2) return 1;
    if ((size_t)nt > units) nt = (int)units;
    return nt;
}

/* Most threads of one frep_par_for run (-t is the user's: nothing else caps it). */
#define FREP_PAR_MAX_THREADS 256

/* One chunk of a parallel loop: items [i0, i1) on thread `thread` (0 .. nt-1; 0 is
 * the calling thread).  A thread runs its chunks one after the other, so per-thread
 * state indexed by `thread` needs no lock. */
typedef void (*frep_par_fn)(void *ctx, int thread, long i0, long i1);

/* Run fn over items [0, n) in chunks of `chunk` items (>= 1) on up to nt threads, the
 * calling one included: a shared counter hands out the chunks one at a time, the
 * first thread to finish one takes the next, so a thread descheduled on a busy machine
 * delays the loop by one chunk.  The helpers are POSIX threads that the calling thread
 * joins with pthread_join, which sleeps: nothing spins at the loop's end (libgomp's
 * regions spun there, doc/benchmarks.md).  nt <= 1 (or a serial build) runs fn(ctx, 0,
 * 0, n) in chunks on the calling thread, creating nothing.  A helper that cannot be
 * started leaves its share to the others.  Returns the threads that ran (>= 1). */
int frep_par_for(int nt, long n, long chunk, frep_par_fn fn, void *ctx);

/* The work left (node-evaluations, a guess) in a loop of n items of which the calling
 * thread ran [0, done) alone. */
typedef double (*frep_par_left_fn)(void *ctx, long done, long n);

/* frep_par_for for a job whose work is known only as it is done (a pruned grid): the
 * calling thread runs chunks alone and starts the helpers once left() says at least
 * FREP_PAR_MIN_WORK remains, so a job that never gets there stays on one thread.  left
 * NULL starts them at once (frep_par_for). */
int frep_par_for_late(int nt, long n, long chunk, frep_par_fn fn, frep_par_left_fn left,
                      void *ctx);

/* The calling thread's number in its OpenMP team (0 outside a parallel region). */
static inline int frep_thread_num(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

/* The number of threads in the calling thread's OpenMP team (1 outside a region). */
static inline int frep_team_size(void)
{
#ifdef _OPENMP
    return omp_get_num_threads();
#else
    return 1;
#endif
}

#endif

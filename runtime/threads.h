/* threads.h - the thread counts of the library's parallel loops, with the OpenMP
 * conditional in this one place. A build without OpenMP runs every loop on one thread
 * as thread 0 of a team of one.
 */
#ifndef FREP_THREADS_H
#define FREP_THREADS_H

#ifdef _OPENMP
#include <omp.h>
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

/* The calling thread's number in its team (0 outside a parallel region). */
static inline int frep_thread_num(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

/* The number of threads in the calling thread's team (1 outside a parallel region). */
static inline int frep_team_size(void)
{
#ifdef _OPENMP
    return omp_get_num_threads();
#else
    return 1;
#endif
}

#endif

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

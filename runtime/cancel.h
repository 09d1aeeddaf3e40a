/* cancel.h - the cancel flag of long computations (Ctrl-C).
 *
 * The caller owns the flag (the frep command's signal handler sets it: cli/util.c);
 * the library sees it only through a pointer in its config (ransac_config, segment_config,
 * gp_config, mesh_options, fit_config: the field `interrupt`, NULL for never) and polls
 * it at least every FREP_CANCEL_POLL_SECONDS of work. A stopped computation returns the
 * best result it has (segment, evolve, fit) or fails with FREP_ECANCEL (mesh, sample).
 */
#ifndef FREP_CANCEL_H
#define FREP_CANCEL_H

#include <signal.h>

/* The promise: a phase polls at least this often, so Ctrl-C answers within a second. */
#define FREP_CANCEL_POLL_SECONDS 0.1

/* Non-zero once the flag (may be NULL) was set. */
static inline int frep_cancelled(const volatile sig_atomic_t *flag)
{
    return flag != NULL && *flag != 0;
}

#endif

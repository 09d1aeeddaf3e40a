/* optim.h - the numerical optimizers behind `frep fit`: generalized simulated annealing
 * (global phase), BFGS with a strong-Wolfe line search and Levenberg-Marquardt (local
 * phase), all within box bounds.  They know nothing of models or points: fit/objective.c
 * supplies the function, fit/fit.c chains the phases.
 */
#ifndef FREP_FIT_OPTIM_H
#define FREP_FIT_OPTIM_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "rng.h"

/* Most parameters the optimizers handle: bounds the n*n matrices they keep on the heap
 * and the work per iteration (templates have a handful to a few dozen parameters). */
#define FIT_MAX_PARAMS 256

/* Objective: returns f(x) and, when grad != NULL, writes its gradient. A non-finite
 * return marks x as infeasible (the optimizers step back). */
typedef double (*fit_fn)(void *user, const double *x, double *grad);

/* Least-squares objective for Levenberg-Marquardt: returns the cost 0.5 * sum r_i^2 and
 * writes the Gauss-Newton normal equations J^T J (n*n, row-major) and J^T r (n). The
 * caller accumulates them over residuals so the Jacobian itself is never stored. */
typedef double (*fit_lsq_fn)(void *user, const double *x, double *jtj, double *jtr);

/* Phases, for progress reports. */
typedef enum fit_phase { FIT_PHASE_SA, FIT_PHASE_QN, FIT_PHASE_LM } fit_phase;

/* Budget and reporting shared by every phase of one fit. The optimizers count every
 * objective evaluation in `evals` and stop (status FIT_STOPPED) when `max_evals`
 * (0: no limit) or the wall-clock `deadline` (seconds of frep_now_seconds(); 0: none) is reached,
 * or when *interrupt becomes non-zero (Ctrl-C), or a phase ran out of memory. */
typedef struct fit_control {
    long evals;
    long max_evals;
    double deadline;
    volatile sig_atomic_t *interrupt;   /* may be NULL */
    /* Called now and then (at most every progress_interval seconds) with the phase,
     * its iteration, the temperature (SA; 0 otherwise) and the phase's best objective
     * (of the objective it minimizes). May be NULL. */
    void (*progress)(void *user, fit_phase phase, long iteration, double temperature,
                     double best);
    void *progress_user;
    double progress_interval;
    double last_progress;
    /* The caller's cancel (a Ctrl-C seen through a callback), polled by
     * fit_control_stop at most every FIT_CANCEL_POLL_SECONDS, so that it reaches every
     * evaluation and not only the iterations' progress reports; non-zero: stop.
     * May be NULL. */
    int (*cancel)(void *user);
    void *cancel_user;
    double next_cancel;
    int cancelled;
    /* Set by a phase whose work arrays could not be allocated (it returns FIT_NOMEM):
     * every phase sharing this control then stops, the searches inside the annealing
     * included, and the caller reports "out of memory". */
    int out_of_memory;
} fit_control;

/* How often fit_control_stop calls fit_control.cancel at most: far below the 0.1 s of
 * work between polls that Ctrl-C latency allows (doc/architecture.md, "Interrupts"). */
#define FIT_CANCEL_POLL_SECONDS 0.02
void fit_control_init(fit_control *c);
/* Non-zero when the budget is spent or an interrupt arrived (the cancel polled). */
int fit_control_stop(fit_control *c);
/* The caller stopped the run (the interrupt flag, or the cancel callback polled at most
 * every FIT_CANCEL_POLL_SECONDS): 1, else 0. Budgets of evaluations or time are not
 * looked at; fit_control_stop checks this first. */
int fit_control_cancelled(fit_control *c);

typedef enum fit_status {
    FIT_CONVERGED = 0,  /* a convergence test passed */
    FIT_MAXITER,        /* iteration limit of the phase */
    FIT_STOPPED,        /* budget spent or interrupted: x is the best point seen */
    FIT_FAILED,         /* no finite objective at the start, or invalid arguments */
    FIT_NOMEM,          /* out of memory (fit_control.out_of_memory is set too) */
    FIT_STALLED         /* no more progress, but the optimality test does not pass: x is
                           not known to be a (projected) stationary point */
} fit_status;

const char *fit_status_name(fit_status s);

/* First-order optimality of a box-constrained minimum: the projected gradient pg of g at
 * x (components of variables on a bound whose gradient points out of the box are zero),
 * and its largest component scaled by the parameter's scale (scale may be NULL: 1).
 * Writes pg (n values) and returns max_i |pg_i| scale_i. */
double fit_projected_gradient(size_t n, const double *x, const double *g, const double *lo,
                              const double *hi, const double *scale, double *pg);

/* ---- BFGS ---------------------------------------------------------------- */

typedef struct fit_qn_options {
    int max_iter;       /* iterations (default 500) */
    double gtol;        /* converged when the projected gradient's inf-norm <= gtol (1e-10) */
    /* Converged when the decrease the quasi-Newton model still predicts, half the
     * decrement pg.H.pg over the free variables, is at most dtol (f + floor), the floor
     * being dtol_abs times the objective at the start of the search (dtol 1e-10,
     * dtol_abs 1e-12): a scale-free first-order test. */
    double dtol, dtol_abs;
    double ftol;        /* progress is stalling when the relative decrease of f is below
                           ftol (1e-13) two iterations in a row */
    double xtol;        /* or when the step's inf-norm <= xtol * (1 + |x|) (1e-12); either
                           restarts from steepest descent, then ends FIT_STALLED unless the
                           optimality tests above pass */
    int max_restarts;   /* restarts from steepest descent without progress before
                           FIT_STALLED (3; the searches inside the annealing use 0) */
} fit_qn_options;

void fit_qn_options_init(fit_qn_options *o);

/* Minimize fn from x (n values, within [lo, hi]; lo/hi may be NULL for no bounds, and
 * entries may be infinite). BFGS on the inverse Hessian; variables at a bound whose
 * gradient points outwards are held (projected active set), the others move along the
 * projected path P(x + a d), whose breakpoints do not end the step, with a strong-Wolfe
 * line search (c1 = 1e-4, c2 = 0.9) on it. FIT_CONVERGED only when the optimality test
 * passes (gtol or dtol); FIT_STALLED when progress stopped before that. On return x holds
 * the best point and *fx its value. */
fit_status fit_bfgs(fit_fn fn, void *user, size_t n, double *x, const double *lo,
                    const double *hi, const fit_qn_options *o, fit_control *c, double *fx,
                    int *iterations);

/* ---- Levenberg-Marquardt ---------------------------------------------------- */

typedef struct fit_lm_options {
    int max_iter;       /* accepted + rejected steps (default 200) */
    double ftol;        /* relative cost decrease below which it stops (1e-14) */
    double gtol;        /* inf-norm of J^T r below which it stops (1e-14) */
    double xtol;        /* relative step below which it stops (1e-12) */
    double dtol, dtol_abs;  /* the optimality test when it stops: converged when the
                           Gauss-Newton step's predicted decrease b.A^-1.b / 2 is at most
                           dtol (cost + dtol_abs cost at the start) (1e-10, 1e-12); else
                           FIT_STALLED */
} fit_lm_options;

void fit_lm_options_init(fit_lm_options *o);

/* Minimize 0.5 * sum r^2 by Levenberg-Marquardt with Marquardt's diagonal scaling
 * (damping lambda * diag(J^T J)); steps are clipped to the bounds. */
fit_status fit_lm(fit_lsq_fn fn, void *user, size_t n, double *x, const double *lo,
                  const double *hi, const fit_lm_options *o, fit_control *c, double *fx,
                  int *iterations);

/* ---- generalized simulated annealing --------------------------------------- */

typedef struct fit_sa_options {
    double qv;              /* visiting distribution shape, 1 < qv < 3 (2.62) */
    double qa;              /* acceptance parameter, < 1 (-5) */
    double t0;              /* initial temperature (5230) */
    double restart_ratio;   /* restart from a random point when T < t0 * ratio (2e-5) */
    long max_iter;          /* annealing iterations per chain, each 2n trial moves (1000) */
    long stall_iter;        /* stop after this many iterations without a new best
                               (improvement > rel_improve relative); 0: never (40) */
    double rel_improve;     /* what counts as improving the best (1e-4) */
    double threshold;       /* stop as soon as the best objective <= threshold (-inf) */
    /* Local search run from the start and then from the best point after every
     * iteration that found a new best (dual annealing); NULL: pure annealing. It improves x in place, sets *fx and
     * returns 0, or -1 when it failed (the point is then left alone). */
    int (*local)(void *user, double *x, double *fx);
    void *local_user;
    /* Also run it from the chain's current point after this many iterations in a row
     * without a new best (0: never): probes basins the chain visits but whose raw
     * values are not yet better than the polished best (default 10; fit_config 2:
     * on the paper's test part probing every 2 quiet iterations raised the share of
     * chains reaching the truth from 67% to 96%, see doc/fit.md). */
    long local_period;
    /* A best point with a coordinate on its bound is suspect: in templates a bound-hitting
     * minimum is usually a primitive switched off (a hole shrunk to its smallest radius)
     * instead of placed. While the chain's best is such a point its stall limit is
     * bound_stall_iter (0: stall_iter), so the search keeps looking for an interior
     * minimum; a true minimum on a bound only costs the extra iterations. */
    long bound_stall_iter;
    /* A chain whose probes keep returning to its best has stalled: once probe_returns
     * probes in a row since its last gain ended at its best value (within probe_tol of
     * it, relative: the same minimum, or a copy of it under a symmetry of the model such
     * as two holes swapped), and that best lies on no bound, the chain stops as if its
     * stall limit had passed (0: never). A probe that ends elsewhere starts the count
     * again. */
    long probe_returns;
    double probe_tol;
    /* Independent chains (<= 0: 1): the first starts at x, the others at random points,
     * each runs to its own stall (max_iter is per chain) and the best of all is kept.
     * A chain lands in a wrong basin with some probability p (a primitive parked where
     * it explains no points); the best of k chains fails only when all do, about p^k. */
    long chains;
    /* Bests of chains run before (nagree points of n coordinates; NULL: none): a chain
     * whose best comes within agree_tol of one of them, relative to each coordinate's
     * range, stops there (FIT_CONVERGED): it has reached that chain's minimum, whose
     * stall the earlier chain has already waited out. */
    const double *agree;
    long nagree;
    double agree_tol;
} fit_sa_options;

void fit_sa_options_init(fit_sa_options *o);

/* The index of the first of o->agree that x lies within o->agree_tol of (relative to
 * each range of [lo, hi]), or -1. */
long fit_sa_agreeing(const fit_sa_options *o, size_t n, const double *x, const double *lo,
                     const double *hi);

/* Global minimization of fn within finite bounds [lo, hi] by generalized simulated
 * annealing (Tsallis-Stariolo, as in Xiang et al.'s dual annealing): trial points drawn
 * from a heavy-tailed distribution whose width follows the temperature, generalized
 * Metropolis acceptance, restart from a random point when the temperature has fallen by
 * restart_ratio, in o->chains independent chains. Gradients are not used (only by the
 * local searches). x holds the start on entry (may be outside: then a random start) and
 * the best point of all chains on return; *iterations counts all chains'. */
fit_status fit_sa(fit_fn fn, void *user, size_t n, double *x, const double *lo,
                  const double *hi, const fit_sa_options *o, frep_rng *rng, fit_control *c,
                  double *fx, long *iterations);

#endif

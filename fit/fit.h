/* fit.h - the template-fitting driver behind `frep fit`: chains simulated annealing
 * (global) and quasi-Newton or Levenberg-Marquardt (local) on the objectives of
 * fit/objective.h, for any model seen as a fit_model (a compiled frep_program through
 * fit_program_model(), or C callbacks in the tests).  cli/cmd_fit.c does the I/O.
 */
#ifndef FREP_FIT_FIT_H
#define FREP_FIT_FIT_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "frep.h"
#include "objective.h"
#include "optim.h"

typedef enum fit_method {
    FIT_METHOD_SAQN,    /* annealing, then quasi-Newton (the default) */
    FIT_METHOD_QN,      /* quasi-Newton only, from the start values */
    FIT_METHOD_SA,      /* annealing only (no local polish at the end) */
    FIT_METHOD_LM       /* Levenberg-Marquardt only, from the start values */
} fit_method;

const char *fit_method_name(fit_method m);
/* Parse "saqn", "qn", "sa", "lm"; returns 0 or -1. */
int fit_method_parse(const char *s, fit_method *m);
const char *fit_objective_name(fit_objective_kind k);
int fit_objective_parse(const char *s, fit_objective_kind *k);
const char *fit_loss_name(fit_loss l);
int fit_loss_parse(const char *s, fit_loss *l);

/* What the progress callback gets, now and then (at most every 0.2 s). */
typedef struct fit_progress {
    fit_phase phase;
    long chain, nchains;        /* the annealing chain being run or polished (from 1);
                                   0 in a local-only fit */
    long iteration;             /* of the phase */
    /* The lowest objective seen so far of the kind being minimized: on the annealing's
     * subset (subset = 1), on all points (0), or the robust refinement's (2; its scale
     * changes between rounds). Never goes up for a given kind. */
    double best;
    int subset;
    double elapsed;             /* seconds since the fit started */
} fit_progress;

/* Every setting of a fit, with its default from fit_config_init(). */
typedef struct fit_config {
    fit_method method;
    fit_objective_config obj;   /* the local phase's objective (algebraic by default) */
    /* The annealing's objective kind (algebraic by default: the geometric one has
     * degenerate minima far from the start, such as infinitely thin slabs, that the
     * global search finds; see doc/fit.md). Loss and threads as in obj. */
    fit_objective_kind global_kind;
    uint64_t seed;              /* 1 */
    double max_time;            /* seconds of wall clock; 0: no limit */
    long max_evals;             /* objective evaluations; 0: no limit */
    /* Global phase. The annealing runs on a random subset of the points (cheap
     * evaluations; the local phase uses them all). */
    size_t sa_points;           /* 1024 */
    int sa_local;               /* BFGS from every new best inside the annealing (1) */
    int sa_local_iter;          /* iteration cap of those inner searches (300) */
    fit_sa_options sa;          /* see optim.h; fit_config_init sets stall_iter 15,
                                   bound_stall_iter 60, local_period 2, chains 2,
                                   probe_returns 2 (probe_tol 1e-6) */
    /* Local phase. */
    fit_qn_options qn;
    fit_lm_options lm;
    int reweight_rounds;        /* geometric kind: freeze weights and refit, at most (8) */
    volatile sig_atomic_t *interrupt;   /* Ctrl-C flag; may be NULL */
    void (*progress)(void *user, const fit_progress *p);
    void *progress_user;
    /* Polled between evaluations (fit_control.cancel), with progress_user; non-zero:
     * stop with the best so far.  May be NULL. */
    int (*cancel)(void *user);
    int report;                 /* measure the result: true distances, uncertainties (0;
                                   frep fit sets 1: the measures cost a few evaluations
                                   of every point) */
    /* The annealing's model when not NULL: the same parameters and the same zero set as
     * the fitted model but a smoother field (the R-function compilation of a min/max
     * template, whose kinks and flat regions mislead the global search). The chains'
     * bests are polished and compared on the fitted model itself. */
    const fit_model *surrogate;
    /* Robust refinement (1, the default; 0: the objective as configured, alone): the
     * result of the local phase, each annealing chain's after its polish, is refined on
     * the geometric distances with a Cauchy loss whose scale comes from the residuals
     * (FIT_CAUCHY_C x 1.4826 x their median, at least FIT_ROBUST_FLOOR of the diagonal,
     * re-estimated each round), and the chains are compared on that loss at the
     * smallest of their scales: noise then costs no bias and outliers no basin. */
    int robust;
    /* With robust: the annealing's loss (l2 by default, which becomes geman on a cloud
     * with isolated points, FIT_ISOLATED_OUTLIERS in fit.c), its scale from
     * FIT_SA_CAUCHY below. */
    fit_loss sa_loss;
} fit_config;

void fit_config_init(fit_config *c);

/* Fraction of the points' diagonal within which a point counts as fitted in the
 * verdict (fit_result.within). */
#define FIT_WITHIN 0.01
/* The robust refinement's Cauchy scale in units of the residuals' robust standard
 * deviation (1.4826 x their median): 2.385 gives 95% efficiency on Gaussian noise. */
#define FIT_CAUCHY_C 2.385
/* Least Cauchy scale, relative to the diagonal: on a clean cloud the residuals vanish
 * at the truth and the loss is then least squares. */
#define FIT_ROBUST_FLOOR 1e-4
/* Rounds of the robust refinement (scale, then fit): it stops earlier once the scale
 * changed by less than FIT_ROBUST_SETTLE relative. */
#define FIT_ROBUST_ROUNDS 3
#define FIT_ROBUST_SETTLE 0.1
/* A point counts as an outlier of the result when its distance to the surface exceeds
 * both FIT_OUTLIER_SIGMAS robust standard deviations of the distances and
 * FIT_WITHIN of the diagonal. */
#define FIT_OUTLIER_SIGMAS 4
/* With cfg.robust the annealing's objective (algebraic by default) takes a bounded
 * Geman-McClure loss, of scale FIT_SA_CAUCHY of the diagonal converted to function
 * units by the median |grad f| of its points at the start: with least squares 5% of
 * outliers spread over the box pull a plate out to its bounds, and even Cauchy's
 * logarithmic tail lets quadratic primitives (r^2 - x^2 - y^2) grow over outliers. */
#define FIT_SA_CAUCHY 0.01

typedef struct fit_result {
    double objective;           /* final objective on all points */
    /* True distances of the points to the fitted surface (fit/measure.c; NaN when
     * cfg.report is 0 or they could not be computed): RMS, maximum, the fraction within
     * FIT_WITHIN of the diagonal, and how many points needed the sphere search or found
     * no surface within the diagonal. */
    double rms, max_dist, within, diagonal;
    size_t dist_searched, dist_unresolved;
    /* The noise and outliers of the result (cfg.report): noise, the robust standard
     * deviation of the distances (1.4826 x their median); outliers, the points beyond
     * FIT_OUTLIER_SIGMAS x noise and FIT_WITHIN of the diagonal; within_inliers, the share
     * of the other points within FIT_WITHIN of the diagonal (noise larger than that is
     * not told apart from a poor fit). */
    double noise, within_inliers;
    size_t outliers;
    long evals;                 /* objective evaluations, all phases (subset ones too) */
    double seconds;
    /* FIT_CONVERGED only when the local phase that produced the result passed its
     * optimality test (--method sa has none: FIT_STALLED); FIT_STOPPED after an
     * interrupt or a spent budget. */
    fit_status status;
    long sa_iterations;
    int local_iterations;
    /* Per parameter (cfg.report): sens, the RMS movement of the surface per unit of the
     * parameter; sigma, its standard error from the Jacobian (infinite when undefined);
     * see fit_uncertainty(). */
    double sens[FIT_MAX_PARAMS], sigma[FIT_MAX_PARAMS];
    int have_uncertainty;
} fit_result;

/* Fit model m to the points: params holds the start on entry (m->nparams values) and
 * the best parameters found on return, also after an interrupt or a spent budget.
 * lo/hi: bounds (entries may be infinite; the annealing methods need finite ones).
 * Returns 0, or -1 with err set (params then unchanged): FREP_EINPUT for arguments
 * or a model that cannot be fitted, FREP_ELIMIT for more than FIT_MAX_PARAMS
 * parameters, FREP_ENOMEM ("out of memory"). */
int fit_run(const fit_model *m, const fit_points *pts, const double *lo, const double *hi,
            double *params, const fit_config *cfg, fit_result *res, frep_error *err);

/* Adapter from a compiled program to a fit_model: the fitted parameters are the
 * program parameters listed in idx (nfree of them); the others keep the values in
 * base (frep_program_nparams(p) values, copied). Free with fit_program_model_free().
 * Returns 0, or -1 when out of memory. p must outlive the model. */
int fit_program_model(const frep_program *p, const size_t *idx, size_t nfree,
                      const double *base, fit_model *m);
void fit_program_model_free(fit_model *m);

#endif

/* objective.h - fitting objectives over a point cloud: algebraic least squares of the
 * model function, geometric (first-order distance f/|grad f|), an optional
 * normal-agreement term and robust losses.  Evaluated block by block over the points,
 * in parallel, with a fixed reduction order.  fit/fit.c hands these to fit/optim.c.
 */
#ifndef FREP_FIT_OBJECTIVE_H
#define FREP_FIT_OBJECTIVE_H

#include <stddef.h>
#include <stdint.h>

/* Points per block of the reduction: partial sums are formed per block, then added in
 * block order, so the result does not depend on how blocks are spread over threads. */
#define FIT_BLOCK 256

/* The model being fitted, seen through callbacks (fit/fit.c adapts a frep_program; the
 * tests plug in C functions). eval() gets n <= FIT_BLOCK points and writes f[n]; when
 * g != NULL the spatial gradient g[c*n + i] (c = 0, 1, 2 for x, y, z); when dp != NULL
 * the parameter derivatives dp[j*n + i]. Returns 0, or -1 when out of memory.
 * Each thread has its own scratch from scratch_new (may be NULL: no scratch). */
typedef struct fit_model {
    size_t nparams;
    void *user;
    void *(*scratch_new)(void *user);
    void (*scratch_free)(void *user, void *scratch);
    int (*eval)(void *user, void *scratch, size_t n, const double *x, const double *y,
                const double *z, const double *params, double *f, double *g, double *dp);
} fit_model;

/* Points (structure of arrays); nx/ny/nz NULL when there are no normals. Normals must
 * be unit length (or zero: ignored) and point out of the solid. */
typedef struct fit_points {
    size_t n;
    const double *x, *y, *z;
    const double *nx, *ny, *nz;
} fit_points;

typedef enum fit_objective_kind {
    FIT_OBJ_ALGEBRAIC,  /* residual f(x_i): the paper's sum of squares */
    FIT_OBJ_GEOMETRIC   /* residual f/|grad f|: first-order distance (Taubin) */
} fit_objective_kind;

typedef enum fit_loss {
    FIT_LOSS_L2,        /* r^2 */
    FIT_LOSS_HUBER,     /* r^2 inside [-s, s], 2 s |r| - s^2 outside */
    FIT_LOSS_CAUCHY,    /* s^2 log(1 + r^2 / s^2) */
    FIT_LOSS_GEMAN      /* Geman-McClure, s^2 r^2 / (s^2 + r^2): bounded by s^2, so a far
                           point costs the same wherever the surface is */
} fit_loss;

typedef struct fit_objective_config {
    fit_objective_kind kind;
    fit_loss loss;
    double loss_scale;      /* s of the robust losses (residual units) */
    double normals_weight;  /* weight of the normal term (0: none; needs normals) */
    int nthreads;           /* <= 0: OpenMP's default */
} fit_objective_config;

void fit_objective_config_init(fit_objective_config *c);

typedef struct fit_objective fit_objective;

/* A new objective over `pts` (the arrays are referenced, not copied: keep them alive).
 * NULL when out of memory or when the model has no parameters. Free with
 * fit_objective_free(). */
fit_objective *fit_objective_new(const fit_model *m, const fit_points *pts,
                                 const fit_objective_config *cfg);
/* The same objective on `count` points drawn without replacement from o's points by
 * a generator seeded with `seed` (all of them when count >= their number); with keep
 * != NULL only from the points i with keep[i] != 0. The points are copied. NULL when
 * out of memory. */
fit_objective *fit_objective_subset(const fit_objective *o, size_t count, uint64_t seed,
                                    const unsigned char *keep);
void fit_objective_free(fit_objective *o);

/* E(p) = (1/N) sum rho(r_i) + normals_weight (1/N) sum (1 + n_i . grad f / |grad f|).
 * With grad != NULL also dE/dp. For the geometric kind the gradient holds the weights
 * 1/|grad f| fixed (exact once fit_objective_freeze() has fixed them). The normal
 * term's gradient is the analytic chain rule with the mixed second derivatives
 * d2f/dx dp taken as one central difference in space of the analytic df/dp (error
 * O(h^2), h = 1e-6 of the cloud's diagonal). Signature of fit_fn: `user` is the
 * fit_objective. Returns NaN when the model gives NaN, or when it ran out of memory
 * (fit_objective_watch_nomem). */
double fit_objective_value(void *user, const double *p, double *grad);

/* Gauss-Newton form for Levenberg-Marquardt (fit_lsq_fn): cost (1/2N) sum rho(r_i) and
 * J^T W J, J^T W r / N with the robust loss as iteratively reweighted least squares.
 * The normal term is not included. */
double fit_objective_lsq(void *user, const double *p, double *jtj, double *jtr);

/* Geometric kind: fix the weights 1/|grad f(x_i)| at p (returns 0, or -1 when out of
 * memory); unfreeze to use the true f/|grad f| again. No effect on the algebraic kind. */
int fit_objective_freeze(fit_objective *o, const double *p);
void fit_objective_unfreeze(fit_objective *o);

/* Change the loss and its scale (residual units) of o: fit_run's robust refinement
 * re-estimates the scale from the residuals between rounds. */
void fit_objective_set_loss(fit_objective *o, fit_loss loss, double scale);
/* The scale of o's robust loss (residual units). */
double fit_objective_loss_scale(const fit_objective *o);

/* The first-order distance |f|/|grad f| of each point at p, in r[n] (n = its point
 * count). Returns 0; 1 when some are not finite; -1 when out of memory. */
int fit_objective_residuals(fit_objective *o, const double *p, double *r);
/* |grad f| at each point (at least 1e-300), the same way. */
int fit_objective_grad_norms(fit_objective *o, const double *p, double *r);

/* RMS and maximum of the first-order distance |f|/|grad f| of the points at p. Returns
 * 0; 1 when they are not finite (the model gives NaN or infinite values), or -1 when out
 * of memory. */
int fit_objective_distances(fit_objective *o, const double *p, double *rms, double *max);

/* Where o records running out of memory (the model's eval failed in a pass over the
 * points, perhaps on another thread): *flag is set to 1, besides the NaN or -1 the call
 * returns. fit_run passes its fit_control.out_of_memory, so that every phase stops and
 * the fit fails with out of memory. NULL: nowhere (the default). */
void fit_objective_watch_nomem(fit_objective *o, int *flag);

size_t fit_objective_npoints(const fit_objective *o);
fit_objective_kind fit_objective_kind_of(const fit_objective *o);

#endif

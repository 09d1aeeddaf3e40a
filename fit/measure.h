/* measure.h - what `frep fit` reports about a fitted model: the true distance of each
 * point to the model's surface (Newton projection along the gradient, checked, with a
 * sphere search where it fails), and each parameter's sensitivity and standard error from
 * the Jacobian of the distances.  Called by fit/fit.c at the result.
 */
#ifndef FREP_FIT_MEASURE_H
#define FREP_FIT_MEASURE_H

#include <stddef.h>

#include "objective.h"

/* Newton steps y <- y - f g / |g|^2 tried per point before the sphere search. */
#define FIT_PROJ_ITERS 24
/* Directions of the sphere search (a Fibonacci sphere). */
#define FIT_SPHERE_DIRS 96
/* Shrinking steps of the sphere search, each by a factor sqrt(2): 60 cover 9 decades. */
#define FIT_SPHERE_STEPS 60

typedef struct fit_distance_stats {
    double rms, max;            /* over the points */
    size_t searched;            /* points where the projection was not trusted: sphere search */
    size_t unresolved;          /* points with no surface within the search radius (counted
                                   at that radius) */
} fit_distance_stats;

/* Distance of each point of pts to the zero set of m at params, in dist[i] (may be
 * NULL): an upper bound that is tight to a factor sqrt(2) at worst, exact where the
 * Newton projection converges onto the nearest sheet. radius: the farthest the search
 * looks (the cloud's diagonal). Evaluated in parallel over blocks of points; the result
 * does not depend on the thread count. Returns 0, or -1 when the model cannot be
 * evaluated or memory runs out. */
int fit_distances(const fit_model *m, const double *params, const fit_points *pts,
                  double radius, int nthreads, double *dist, fit_distance_stats *st);

/* Sensitivity and standard error of each parameter from the Jacobian J of the first-order
 * distances r_i = f/|grad f| (weights frozen): sens[j] = sqrt(mean_i J_ij^2), the RMS
 * movement of the surface per unit of parameter j; sigma[j] = sqrt(s^2 (J^T J)^-1_jj),
 * s^2 = sum r_i^2 / (N - n) (infinite for a parameter the distances do not depend on,
 * or when J^T J is singular). Points with |grad f| below 1e-8 of the median are left
 * out, and so are points with |r_i| > cut (the outliers of a robust fit; HUGE_VAL: none).
 * Returns 0, or -1 when the model cannot be evaluated or memory runs out. */
int fit_uncertainty(const fit_model *m, const double *params, const fit_points *pts,
                    double cut, double *sens, double *sigma);

/* The k-th smallest of v[0..n) (from 0), v reordered: Hoare's selection, O(n) on
 * average where sorting for a median was 4% of a fit's CPU time (the robust scale, the
 * isolation mask, the report's floor of |grad f|). A NaN stops both scans, so they
 * end; where the values hold NaNs the result is one of them or a number, as a sort's
 * was. */
double fit_select_kth(double *v, size_t n, size_t k);

#endif

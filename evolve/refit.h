/* refit.h - `frep evolve --refit`: after the tree is found, all parameters of its
 * primitives are refined together on every point with `frep fit`'s optimizer
 * (fit/fit.h: Levenberg-Marquardt on the geometric distance f/|grad f| of the whole
 * tree, Huber loss), so that faces fitted one by one from noisy inliers agree where
 * the tree joins them.  Runs after evolve_run(), before the model is written.
 */
#ifndef FREP_EVOLVE_REFIT_H
#define FREP_EVOLVE_REFIT_H

#include <stddef.h>

#include "cloud.h"
#include "evolve.h"
#include "prim.h"
#include "residual.h"

/* Fewest points per refined parameter: fewer cannot determine them. */
#define REFIT_MIN_POINTS_PER_PARAM 4

typedef struct evolve_refit_info {
    size_t nparams;           /* parameters refined */
    int groups;               /* optimizer runs (more than one when the tree has more
                                 parameters than FIT_MAX_PARAMS) */
    double rms_before, rms_after;   /* RMS of |f|/|grad f| of the tree over every point */
    double max_before, max_after;
    double seconds;
} evolve_refit_info;

/* Refine prims[j] for every j used by res->tree (the others are untouched; base, for
 * --residual, stays fixed), then recompute res->stats. The tree's normalised
 * directions (plane normals, axes) are normalised again afterwards. Returns 0, or -1
 * with err (may be NULL) set: too few points or the optimizer failed (FREP_EINPUT),
 * out of memory (FREP_ENOMEM); prims are then unchanged. */
int evolve_refit(const evolve_options *o, const frep_cloud *cloud, prim *prims,
                 size_t nprims, const evolve_base *base, evolve_result *res,
                 evolve_refit_info *info, frep_error *err);

#endif

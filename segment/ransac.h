/* ransac.h - efficient RANSAC shape detection (Schnabel, Wahl, Klein 2007).
 *
 * Second stage of `frep segment`, after normals: finds planes, spheres, cylinders,
 * cones and tori in an oriented point cloud, each with its inliers (the largest
 * connected patch in the primitive's parameter domain), refitted by Levenberg-Marquardt
 * on Euclidean distance.  Seeded and deterministic at any thread count.
 */
#ifndef FREP_RANSAC_H
#define FREP_RANSAC_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "cloud.h"
#include "prim.h"

/* Smallest cloud segmentation accepts: below this no minimal sample has room for a
 * verification point. */
#define RANSAC_MIN_CLOUD 8
/* Candidates drawn without an extraction before giving up: bounds the main loop even
 * when the acceptance test can never pass (probability near 1) or every accepted
 * candidate falls apart into patches smaller than min_points (--cluster 1e-12). Every
 * step either extracts a shape (at most n / min_points times) or draws, and each
 * way out of a step without an extraction checks this bound. */
#define RANSAC_MAX_DRAWS 20000

/* Is a cloud of measured noise `noise` (a standard deviation; 0: unknown) noisy for
 * inlier distance epsilon?  The tests of small shapes, curved shapes' normals and the
 * default second-phase support differ on noisy and clean clouds. */
int ransac_noisy(double noise, double epsilon);

typedef struct ransac_config {
    double epsilon;       /* inlier distance (absolute units) */
    double noise;         /* the cloud's measured noise (standard deviation; 0: unknown) */
    double cos_normal;    /* cosine of the largest normal deviation of an inlier */
    double cluster;       /* cell size of the connectivity bitmap (absolute units) */
    size_t min_points;    /* smallest support of a primitive */
    size_t min_points_small; /* then down to this support for tight shapes only
                                (second phase; 0 or >= min_points: none) */
    double probability;   /* accept when the chance of having missed a better candidate
                             is below 1 - probability */
    unsigned types;       /* bit (1u << prim_type) for each type to detect */
    uint64_t seed;
    int nthreads;         /* <= 0: OpenMP's default; the result does not depend on it */
    /* Called after each extraction and now and then while drawing (stage "detect"),
     * and per pair tried by the merge of redundant primitives (stage "merge"); may be
     * NULL.  A caller's cancel callback polled here reaches every phase. */
    void (*progress)(void *user, const char *stage, size_t remaining, size_t total,
                     size_t nprims);
    void *user;
    volatile sig_atomic_t *interrupt; /* stop early when it becomes non-zero; may be NULL */
} ransac_config;

typedef struct ransac_result {
    prim *prims;          /* detected primitives, in order of extraction (frep_free()) */
    size_t nprims;
    int32_t *label;       /* per point: index into prims, or -1 (frep_free()) */
    size_t draws;         /* minimal samples drawn in all */
    int interrupted;
} ransac_result;

/* Detect primitives in c, which must have unit normals (zero normals are never
 * inliers). Returns 0, or -1 with err set (reset on entry; may be NULL) when out of
 * memory or when c has no normals.
 * Free the result with ransac_result_free(). */
int ransac_detect(const frep_cloud *c, const ransac_config *cfg, ransac_result *res,
                  frep_error *err);
void ransac_result_free(ransac_result *r);

/* Least-squares refit of q to the given points (Euclidean distance; planes by PCA,
 * other types by Levenberg-Marquardt), at most max_points of them used (an evenly
 * spaced subset). Returns 0; 1 when the fit degenerated (fewer than 3 points, a
 * singular system), or -1 when out of memory, q unchanged in both cases. */
int ransac_refit(prim *q, const frep_cloud *c, const uint32_t *idx, size_t n,
                 size_t max_points);

#endif

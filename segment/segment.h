/* segment.h - `frep segment`: split a point cloud into primitive patches and add the
 * separating primitives a construction tree needs (Fayolle & Pasko 2016, Algorithms
 * 1 and 2).  Pipeline: normals (geom/normals.c) -> efficient RANSAC
 * (segment/ransac.c) -> bounding boxes and separating primitives (here) -> .hf / .fit.
 */
#ifndef FREP_SEGMENT_H
#define FREP_SEGMENT_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "cloud.h"
#include "prim.h"

/* Defaults, as fractions of the bounding-box diagonal or of the point count. */
/* Inlier distance: SEGMENT_EPSILON_SIGMAS times the cloud's measured noise (segment.c,
 * noise_sigma), between SEGMENT_DEFAULT_EPSILON_MIN (clean samples: tight enough that a
 * cylinder does not take the rim of the sphere it meets, nor a cone a dome) and
 * SEGMENT_DEFAULT_EPSILON of the diagonal (noisier clouds: the extraction band widens
 * to the noise measured on each shape, segment/ransac.c). */
#define SEGMENT_DEFAULT_EPSILON 0.01
#define SEGMENT_DEFAULT_EPSILON_MIN 0.002
#define SEGMENT_EPSILON_SIGMAS 5.0
#define SEGMENT_DEFAULT_CLUSTER 0.01      /* connectivity cell: 1% of the diagonal ... */
#define SEGMENT_CLUSTER_SPACINGS 3.0      /* ... but at least 3 median point spacings */
#define SEGMENT_DEFAULT_NORMAL_DEG 25.0
#define SEGMENT_DEFAULT_MIN_FRACTION 0.01 /* smallest support: 1% of the points ... */
#define SEGMENT_MIN_POINTS_FLOOR 10       /* ... and never fewer than this */
/* Second detection phase (segment/ransac.c, SMALL_TIGHT): tight shapes down to 0.04% of
 * the points, so that the small faces of a part (under 1% of its area) are found. */
#define SEGMENT_DEFAULT_SMALL_FRACTION 0.0004
/* ... and on a clean cloud with normals (ransac_noisy: the noise measured far below
 * epsilon; segment.c, small_support) down to 0.02%, where the second phase's tests (median distance 0.2 epsilon, normals within 5
 * degrees) leave no leftover strip: the smallest faces of InverseCSG's nine_cuboids,
 * 10 and 27 of 50,000 points, close the pocket the part's tree cuts from a cube. */
#define SEGMENT_CLEAN_SMALL_FRACTION 0.0002
#define SEGMENT_NO_SMALL ((size_t)-1)     /* min_points_small: no second phase */
#define SEGMENT_DEFAULT_PROBABILITY 0.99
/* Separating planes closer than this angle (and epsilon in offset) to an existing plane
 * are duplicates (Algorithm 2 adds each plane once). */
#define SEGMENT_DUP_PLANE_DEG 5.0
/* Two fitted cylinders meet end to end (segment_add_constructed) when their axes are
 * perpendicular within this angle and pass within epsilon of each other. */
#define SEGMENT_MEET_DEG 2.0

typedef struct segment_config {
    double epsilon;        /* <= 0: default */
    double cluster;        /* <= 0: default */
    double normal_deg;     /* <= 0: default */
    size_t min_points;     /* 0: default */
    size_t min_points_small; /* 0: default; SEGMENT_NO_SMALL: none */
    double probability;    /* <= 0: default */
    unsigned types;        /* bit (1u << prim_type); 0: all */
    uint64_t seed;
    int nthreads;
    size_t knn;            /* neighbours for normals; 0: NORMALS_DEFAULT_K */
    int separating;        /* add separating primitives (default 1) */
    int normals_estimated; /* the cloud's normals were estimated by the caller */
    void (*progress)(void *user, const char *stage, size_t done, size_t total, size_t nprims);
    void *user;
    volatile sig_atomic_t *interrupt;
} segment_config;

void segment_config_init(segment_config *c);

typedef struct segment_result {
    prim *prims;           /* fitted primitives first, then separating ones (frep_free()) */
    size_t nprims, nfitted;
    int32_t *label;        /* per point: index of its fitted primitive or -1 (frep_free()) */
    size_t unassigned;
    double diagonal;       /* of the cloud's bounding box: the scale of the output */
    double noise;          /* measured noise (segment.c, noise_sigma; 0 when --epsilon given) */
    /* The values actually used (defaults resolved). */
    double epsilon, cluster, normal_deg, probability;
    size_t min_points;
    size_t min_points_small; /* == min_points: no second phase */
    int normals_estimated; /* 1 when normals were computed (none, or zero ones, given) */
    size_t zero_normals;   /* zero-length normals found in the input */
    size_t draws;
    int interrupted;
} segment_result;

/* Segment c (normals are added or replaced when missing or zero). Returns 0, or -1
 * with err set (reset on entry; may be NULL) for bad input (too few points, all points
 * equal) or out of memory. Free the result with segment_result_free(). */
int segment_run(frep_cloud *c, const segment_config *cfg, segment_result *res, frep_error *err);
void segment_result_free(segment_result *r);

/* Oriented bounding box of the points idx[0..n) into q->obb_* (for axial types the
 * primitive's axis is one box axis). */
void segment_fit_obb(prim *q, const frep_cloud *c, const uint32_t *idx, size_t n);
/* Algorithm 2: append separating primitives for the *n primitives of *prims (realloc'ed)
 * and set *n to the new count; eps is the duplicate offset tolerance. Returns 0, or -1
 * when out of memory (*prims still holds at least its *n primitives, *n unchanged). */
int segment_add_separating(prim **prims, size_t *n, double eps);
/* Append constructed planes (prim.constructed, also separating): where the axis of
 * fitted cylinder A meets the axis of fitted cylinder B at right angles (within
 * SEGMENT_MEET_DEG and eps) near an end of A's inliers and within B's, the plane across
 * A's axis through B's axis, facing out of A: A's cap when B's surface hides it (a
 * frame of rails joined at the corners), which no point shows.  Duplicates of planes
 * already listed are skipped.  Returns 0, or -1 when out of memory (as above). */
int segment_add_constructed(prim **prims, size_t *n, double eps);
/* Append constructed planes (PRIM_CONSTRUCTED_EXTENT) that close slabs: where two of
 * the nfitted fitted planes face away from each other (a slab's faces) and a third,
 * across them, lies within tol of one end of the faces' inliers (by label) along its
 * normal, the plane across the same normal at the other end, facing out: the slab's
 * face that other solids hide (a block standing on a plate, its side in a disc).
 * Skipped where a fitted or constructed plane lies already.  Returns 0, or -1 when out
 * of memory (as above). */
int segment_close_slabs(prim **prims, size_t *n, const frep_cloud *c, const int32_t *label,
                        size_t nfitted, double tol);

/* Write primitives as a frep model "primitives(x[3], a[1])" with one named call per
 * primitive; `header` (may be NULL) is written as comment lines first. Numbers are
 * rounded relative to `scale` (the cloud's diagonal; prim_write_call_scaled), exact
 * when scale <= 0. Returns 0 or -1 on a write error. */
int segment_write_hf(FILE *f, const prim *p, size_t n, const char *header, double scale);

/* Read primitives from a .hf file written by segment_write_hf (the frX(...) calls and
 * their comments) or from a .fit list (by extension ".fit"). Returns 0 with a malloc'ed
 * array, or -1 with err (reset on entry; may be NULL) holding "path:line: what". */
int segment_read_prims(const char *path, prim **out, size_t *n, frep_error *err);
/* The same from memory; is_fit selects the format. */
int segment_parse_prims(const char *name, const char *text, size_t len, int is_fit,
                        prim **out, size_t *n, frep_error *err);

#endif

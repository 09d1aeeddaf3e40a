/* normals.h - normal estimation for point clouds without normals: a robust weighted
 * plane fit over a neighbourhood whose size is chosen from the cloud's noise, oriented
 * consistently by propagation along a minimum spanning tree of the neighbour graph
 * (Hoppe et al. 1992), then outward, then checked patch by patch by the parity of ray
 * crossings.  First stage of `frep segment`, `frep evolve` and `frep normals` on a
 * cloud without normals.
 */
#ifndef FREP_NORMALS_H
#define FREP_NORMALS_H

#include <signal.h>
#include <stddef.h>

#include "cloud.h"

/* Smallest neighbourhood: enough points for a stable plane fit on a clean sample, few
 * enough to stay local on small features.  The automatic size is never below it. */
#define NORMALS_DEFAULT_K 12
/* Points the orientation graph links each point to (its nearest ones): few, so that
 * the graph seldom crosses a thin wall, enough to stay connected on uneven density. */
#define NORMALS_ORIENT_K 10

typedef struct normals_config {
    size_t knn;              /* neighbours (3..KD_MAX_K); 0: chosen from the data */
    int nthreads;            /* <= 0: OpenMP's default; the result does not depend on it */
    volatile sig_atomic_t *interrupt; /* polled (runtime/cancel.h); NULL: never */
} normals_config;

void normals_config_init(normals_config *c);

/* What a run found and used. */
typedef struct normals_info {
    size_t knn;              /* the neighbourhood size used */
    double spacing;          /* median distance to the nearest other point */
    double noise;            /* estimated standard deviation of the points off their
                              * surface (median plane residual of small neighbourhoods) */
    size_t components;       /* connected parts of the orientation graph */
    size_t flipped;          /* of those, turned over by the outward check */
    int interrupted;         /* 1: stopped by the interrupt flag; normals incomplete */
} normals_info;

/* Estimate unit normals for every point of c (adding normal arrays if needed and
 * overwriting any it had).  Per point: the plane of its k nearest neighbours, fitted
 * with Gaussian weights in distance and reweighted by the residuals (iteratively
 * reweighted PCA), so points across a sharp edge lose their say; on a noisy cloud a
 * point near an edge then takes the plane of a flatter neighbour's neighbourhood that
 * passes through it (geom/normals.c, shift_point).  Orientation: Prim's
 * tree over the NORMALS_ORIENT_K-nearest graph, edges weighted against normals that
 * disagree and against links along the normal (across a thin wall), or on a clean
 * cloud against a normal far from its neighbour's reflected in the plane between
 * them (thin wedges: geom/normals.c, reflected); then each
 * connected part is turned so that its normals point away from the cloud's centre on
 * the whole (sum of (p - centre).n > 0: outward for a closed surface by the divergence
 * theorem).  Last, the ray-parity check: smooth patches (nearly parallel normals,
 * coplanar feet) each cast lines along their normals through the cloud taken as discs
 * (a run of hits counts as a crossing when it holds a tenth of the hits at the line's
 * own point or more); a patch whose lines cross the cloud an odd number of times on
 * their normals' side and an even number on the other (inward) is turned over, and
 * the points outside patches with a clear vote take their sign from those inside
 * along a spanning tree (geom/normals.c, vote_patches).  info may be NULL.  Returns 0; 1 when interrupted (info->interrupted, the
 * normals are then unfinished); -1 when out of memory (c keeps zero normals). */
int normals_run(frep_cloud *c, const normals_config *cfg, normals_info *info);

/* normals_run with k neighbours (0: from the data), no interrupt.  Same returns. */
int normals_estimate(frep_cloud *c, size_t k, int nthreads);

/* Fewest points a surface (and its normals) can be estimated from: three not on one
 * line span a plane. */
#define NORMALS_MIN_POINTS 3
/* Spread off a line or a plane, relative to the bounding-box diagonal, below which the
 * points count as lying on it (rounding of coordinates written with 9 or more digits
 * stays below). */
#define NORMALS_FLAT_TOL 1e-9

/* The shape of a cloud as a surface sample: 0 when its points span more than a line
 * (*planar set to 1 when they all lie on one plane, within NORMALS_FLAT_TOL; planar
 * may be NULL); else -1 with err (FREP_EINPUT; reset on entry; may be NULL) saying
 * "name: too few points: N (at least 3 needed)", "name: all N points are the same" or
 * "name: all N points lie on one line", name naming the cloud.  Out of memory is
 * impossible (no allocation). */
int normals_check_cloud(const frep_cloud *c, const char *name, int *planar, frep_error *err);

/* Eigen-decomposition of a symmetric 3x3 matrix m (row-major) by Jacobi rotations:
 * eigenvalues ascending in ev[3], unit eigenvector k in vec[3k..3k+2] (orthonormal).
 * Never fails; used for PCA normals and oriented bounding boxes. */
void normals_sym3_eig(const double m[9], double ev[3], double vec[9]);

#endif

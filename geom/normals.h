/* normals.h - normal estimation for point clouds without normals: PCA over the k
 * nearest neighbours, oriented consistently by propagation along a minimum spanning
 * tree of the neighbour graph (Hoppe et al. 1992).  First stage of `frep segment`.
 */
#ifndef FREP_NORMALS_H
#define FREP_NORMALS_H

#include <stddef.h>

#include "cloud.h"

/* Default neighbourhood size: enough points for a stable plane fit with some noise,
 * few enough to stay local on small features. */
#define NORMALS_DEFAULT_K 12

/* Estimate unit normals for every point of c (adding normal arrays if needed and
 * overwriting any it had). k neighbours (3..KD_MAX_K; 0: the default). Each connected
 * component of the neighbour graph is oriented from its point of largest x, whose
 * normal is made to point towards +x (outward at an extreme point). nthreads <= 0:
 * OpenMP's default; the result does not depend on it. Returns 0, or -1 when out of
 * memory (c then keeps its old normals or zero normals). */
int normals_estimate(frep_cloud *c, size_t k, int nthreads);

/* Eigen-decomposition of a symmetric 3x3 matrix m (row-major) by Jacobi rotations:
 * eigenvalues ascending in ev[3], unit eigenvector k in vec[3k..3k+2] (orthonormal).
 * Never fails; used for PCA normals and oriented bounding boxes. */
void normals_sym3_eig(const double m[9], double ev[3], double vec[9]);

#endif

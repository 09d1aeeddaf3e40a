/* kdtree.h - a static kd-tree over a point cloud for k-nearest-neighbour queries.
 *
 * Used by geom/normals.c (PCA neighbourhoods and the orientation graph) and by the
 * connectivity checks of segmentation.  Built once, then read-only: any number of
 * threads may query one tree at the same time.
 */
#ifndef FREP_KDTREE_H
#define FREP_KDTREE_H

#include <stddef.h>
#include <stdint.h>

/* Points per leaf: small enough to prune well, large enough to keep the node array
 * short (a few percent of the point data). */
#define KD_LEAF 8
/* Most neighbours one query returns: bounds the caller-side buffers. */
#define KD_MAX_K 256

typedef struct kd_tree kd_tree;

/* Build over n points (copied, so the arrays may be freed afterwards). NULL when out
 * of memory or n == 0 or n > UINT32_MAX. Free with kd_free(). */
kd_tree *kd_build(size_t n, const double *x, const double *y, const double *z);
void kd_free(kd_tree *t);

/* The k (<= KD_MAX_K) nearest points to q, nearest first, ties by lower index; writes
 * their indices and squared distances and returns how many (min(k, n)). */
size_t kd_knn(const kd_tree *t, const double q[3], size_t k, uint32_t *idx, double *d2);

#endif

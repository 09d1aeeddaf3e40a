/* distance.h - how far a cloud is from a model and a model from its cloud: the numbers
 * behind the colours of `frep view` (view/page.c) and `frep render` (mesh/render.c).
 * Sits after the evaluators (runtime/) and the kd-tree (geom/), before the pictures.
 */
#ifndef FREP_DISTANCE_H
#define FREP_DISTANCE_H

#include <stddef.h>

#include "err.h"
#include "frep.h"
#include "trimesh.h"

/* Signed distance estimate of each point to the surface f = iso, first-order:
 * d = (f - iso) / |grad f|, positive inside (f > iso), +-INFINITY where the gradient
 * vanishes off the surface (0 on it).  d holds n values.  Runtime domain errors of the
 * model go to *re (may be NULL); returns 0, or -1 with *e set (FREP_ENOMEM: the
 * evaluators fail only to allocate). */
int view_point_distances(const frep_program *p, double iso, size_t n, const double *x,
                         const double *y, const double *z, int nthreads, double *d,
                         frep_runtime_error *re, frep_error *e);

/* Distance of each vertex of m to the nearest of the n points (kd-tree): where the
 * surface has no points near it, material the cloud does not show.  d holds
 * m->nverts values.  Returns 0, or -1 with *e set (FREP_ENOMEM; FREP_EINPUT for an
 * empty cloud or one beyond the kd-tree's UINT32_MAX points). */
int view_vertex_distances(const frep_mesh *m, size_t n, const double *x, const double *y,
                          const double *z, double *d, frep_error *e);

/* Signed distance of each point to the surface of a closed mesh (a mesh file used as
 * the model): the nearest point of the VIEW_MESH_CANDIDATES triangles whose centroids
 * are nearest (kd-tree), positive inside (behind that triangle's outward face).
 * Exact where triangles are of similar size, an upper bound elsewhere.  Returns 0, or
 * -1 with *e set (FREP_ENOMEM; FREP_EINPUT for a mesh without triangles). */
#define VIEW_MESH_CANDIDATES 16
int view_mesh_distances(const frep_mesh *m, size_t n, const double *x, const double *y,
                        const double *z, double *d, frep_error *e);

/* The distance a colour scale maps to its top, chosen from the data: factor times
 * the q quantile of the finite |d[i]|, rounded up to 1, 2 or 5 times a power of ten.
 * fallback is returned when no value is finite and positive.  Returns 0 with *scale
 * set, or -1 with *e set (out of memory). */
int view_auto_scale(const double *d, size_t n, double q, double factor, double fallback,
                    double *scale, frep_error *e);
/* The points' scale: their 95th percentile, so most distances spread over the colours
 * and the worst few saturate. */
#define VIEW_POINTS_QUANTILE 0.95
#define VIEW_POINTS_FACTOR 1.0
/* The surface's scale: four times its median distance to the cloud.  A well-sampled
 * surface is within about the point spacing of a point everywhere (the median is
 * near half of it), so only regions without points over several spacings, material
 * the cloud does not show, reach red. */
#define VIEW_SURFACE_QUANTILE 0.5
#define VIEW_SURFACE_FACTOR 4.0

/* v rounded up to 1, 2 or 5 times a power of ten (v > 0 and finite; else v). */
double view_nice_ceil(double v);

#endif

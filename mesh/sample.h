/* sample.h - point clouds sampled from a model's surface or from a triangle mesh.
 *
 * A model is polygonized (mesh/mesh.c), points are drawn area-weighted on the
 * triangles and projected onto the zero set with Newton steps along the gradient;
 * normals are the outward unit normals -grad f / |grad f|.  Optional Gaussian noise
 * and uniform outliers make test clouds for fit/segment/evolve.  The random stream is
 * drawn serially from the seed, so the cloud does not depend on the thread count.
 */
#ifndef FREP_SAMPLE_H
#define FREP_SAMPLE_H

#include <stdint.h>

#include "cloud.h"
#include "err.h"
#include "mesh.h"

/* Most points one call produces (cloud memory: 48 bytes a point). */
#define SAMPLE_MAX_POINTS ((size_t)1 << 28)
/* Newton projection steps onto the zero set (quadratic convergence from within a
 * fraction of a cell). */
#define SAMPLE_NEWTON_STEPS 4

typedef struct sample_options {
    size_t n;              /* points, outliers included */
    uint64_t seed;
    double noise;          /* standard deviation of the Gaussian position noise */
    int noise_absolute;    /* 0: noise is a fraction of the box diagonal; 1: model units */
    double outliers;       /* fraction of the n points drawn uniformly in the box */
    mesh_options mesh;     /* box, grid, iso and threads for the polygonization */
} sample_options;

void sample_options_init(sample_options *o);  /* 10000 points, seed 1, no noise */

/* Sample a field's surface into *out (a new cloud with normals; free with
 * cloud_free). Returns 0, or -1 with *e set: bad options or no surface in the box
 * (FREP_EINPUT), out of memory (FREP_ENOMEM), or mesh_polygonize's errors. */
int sample_field(const mesh_field *f, const sample_options *o, frep_cloud **out,
                 frep_error *e);

/* Area-weighted points on a triangle mesh with its face normals (box: the mesh's
 * bounding box, for noise and outliers). Errors as sample_field's (a mesh of zero
 * area is FREP_EINPUT). */
int sample_mesh(const frep_mesh *m, const sample_options *o, frep_cloud **out, frep_error *e);

#endif

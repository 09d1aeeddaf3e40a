/* render.h - a shaded picture of a mesh (z-buffer rasterizer, Phong shading with the
 * mesh's per-vertex normals) with an optional point overlay coloured by a per-point
 * value (the distance of a cloud to the model).  Called by `frep render` after
 * mesh/mesh.c; the image goes to mesh/png.c.
 */
#ifndef FREP_RENDER_H
#define FREP_RENDER_H

#include <stdint.h>

#include "err.h"
#include "mesh.h"

typedef struct render_points {
    size_t n;
    const double *x, *y, *z;
    const double *value;   /* colour scale input, e.g. distance to the surface; may be NULL */
    double vmax;           /* value mapped to the top of the colour scale (> 0) */
} render_points;

typedef struct render_options {
    int width, height;
    const char *view;      /* iso, front, back, top, bottom, left, right (= side) */
    double bbox[6];        /* framed region x0 y0 z0 x1 y1 z1 (e.g. the mesh's bounds) */
} render_options;

/* Names accepted for render_options.view, for the usage text. */
#define RENDER_VIEWS "iso, front, back, top, bottom, left, right, side"

/* Is `view` a known view name? */
int render_view_ok(const char *view);

/* Render into rgb (3 * width * height bytes, rows top to bottom). pts may be NULL.
 * Returns 0, or -1 with *e set: a bad view name or size (FREP_EINPUT), out of memory
 * (FREP_ENOMEM). */
int render_mesh(const frep_mesh *m, const render_points *pts, const render_options *o,
                uint8_t *rgb, frep_error *e);

#endif

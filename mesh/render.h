/* render.h - a shaded picture of a mesh (z-buffer rasterizer, Phong shading with the
 * mesh's per-vertex normals) with an optional point overlay coloured by a per-point
 * value (the distance of a cloud to the model), the surface optionally coloured by a
 * per-vertex value, and colour legends.  Called by `frep render` after mesh/mesh.c;
 * the image goes to mesh/png.c.
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
    int value_signed;      /* value > 0 means inside the solid: points inside by more
                              than the depth slack are drawn through the surface, as
                              rings (a model too large for its cloud hides no point) */
} render_points;

/* A colour legend: the scale from 0 to vmax, a title, one more line. */
typedef struct render_legend {
    const char *title;     /* "points: distance to the surface" */
    double vmax;
    const char *units;     /* "model units" */
    const char *note;      /* may be NULL */
} render_legend;

/* Legends one picture holds: the points' and the surface's. */
#define RENDER_MAX_LEGENDS 2

typedef struct render_options {
    int width, height;
    const char *view;      /* iso, front, back, top, bottom, left, right (= side) */
    double bbox[6];        /* framed region x0 y0 z0 x1 y1 z1 (e.g. the mesh's bounds) */
    const double *vertex_value; /* may be NULL; else the surface is coloured by this
                              per-vertex value (distance to the cloud) ... */
    double vertex_vmax;    /* ... mapped to the top of the colour scale (> 0) */
    int nlegends;
    render_legend legends[RENDER_MAX_LEGENDS];
    const uint8_t *vertex_rgb; /* may be NULL; else, without vertex_value, the surface's
                              colours: red, green, blue 0..255 a vertex (the model's
                              s[1..3]), interpolated over the triangles */
} render_options;

/* The colour scale of the points, the surface and the legends, value t in [0, 1]:
 * blue -> green -> red (view/viewer.html draws the same). */
void render_colour(double t, double col[3]);

/* The depth slack of overlay points, as a fraction of the framed box's diagonal:
 * points on the surface must not be hidden by it. */
#define RENDER_POINT_DEPTH_SLACK 0.01

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

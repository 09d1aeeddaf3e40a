/* page.h - the page of `frep view`: one self-contained HTML file (the WebGL viewer of
 * view/viewer.html, compiled into the library, with the scene inlined) that opens from
 * disk without a server or network.  The scene is the mesh, the cloud with the
 * distances of view/distance.h, the model's text and parameters, compiler messages.
 */
#ifndef FREP_PAGE_H
#define FREP_PAGE_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "buf.h"
#include "err.h"
#include "trimesh.h"

/* What the page shows.  Every pointer may be NULL (that part is left out). */
typedef struct view_scene {
    const char *name;          /* the model's file name: the title */
    const frep_mesh *mesh;
    const unsigned char *vrgb; /* mesh->nverts colours, red green blue 0..255: the
                                  model's s[1..3] */
    const double *vdist;       /* mesh->nverts distances of the surface to the cloud */
    double vscale;             /* vdist mapped to the top of its colour scale (> 0) */
    size_t npoints;
    const double *px, *py, *pz;
    const double *pdist;       /* npoints signed distances to the surface, > 0 inside */
    double pscale;             /* |pdist| mapped to the top of its colour scale (> 0) */
    const char *source;        /* the model's text */
    size_t nparams;
    const char *const *pnames; /* nparams names and values of the free parameters */
    const double *pvalues;
    const char *diag;          /* messages of the compiler and the polygonizer (errors
                                  and warnings), file:line:col first */
    const char *cdiag;         /* messages about the cloud */
    int failed;                /* the last build failed: the mesh is an older one */
    const char *info;          /* one line: what was done (grid, timings) */
    const char *units;         /* what a distance is measured in ("model units") */
    unsigned version;          /* --watch: the page reloads when it changes */
} view_scene;

/* The viewer (view/viewer.html, generated into view_template.c by the build). */
extern const char view_template[];

/* Append the scene as one JSON object: arrays in base64, positions as little-endian
 * Uint16 fractions of their bounds ("lo", "hi"), distances as IEEE halves
 * (view_half), normals as Int8
 * (times 127), colours as Uint8 RGB, triangle corners as zigzag LEB128 varints of their
 * differences. */
void view_scene_json(frep_buf *b, const view_scene *s);

/* v as an IEEE half (binary16), rounded to nearest; +-infinity beyond 65504; a
 * non-zero value too small for a half is +-2^-24, keeping its sign. */
uint16_t view_half(double v);

/* The page: the template with the scene inlined; watch != 0 makes it ask the server
 * that sent it for new versions of the scene.  Returns the text (free with frep_free)
 * and its length, or NULL with *e set (out of memory). */
char *view_page(const view_scene *s, int watch, size_t *len, frep_error *e);

/* view_page() written to f.  Returns 0, or -1 with *e set (FREP_ENOMEM, FREP_EIO). */
int view_write_page(FILE *f, const view_scene *s, frep_error *e);

#endif

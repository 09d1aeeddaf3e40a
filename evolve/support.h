/* support.h - trims of material that no point supports (doc/evolve.md, "Support").
 *
 * Eq. 7 scores the cloud's points, so it cannot see a part of the solid where there are
 * none: a bar of the tree running on past the part it belongs to, up to a plane that
 * bounds the part elsewhere. Such material costs no point and no node, and neither the
 * GA nor the simplifier removes it. Here the tree's surface is found on a grid over the
 * clipping box: an edge of the grid whose ends lie on both sides of the solid holds a
 * piece of surface, *unsupported* when both ends are farther than tau from every cloud
 * point. Trims S & L, as simplify.c's (S an operand of a union that adds material, L a
 * primitive or its complement keeping every point S explains), are kept when they lose
 * no point of the scored sample and remove the most unsupported surface. evolve.c
 * passes caches of the tree's own primitives and the list's separating planes (the
 * faces of the curved primitives' inlier boxes), which L may be too.
 */
#ifndef FREP_GP_SUPPORT_H
#define FREP_GP_SUPPORT_H

#include "fitness.h"
#include "kdtree.h"
#include "tree.h"

/* Cells of the grid along the longest side of the clipping box (cubic cells): 32 puts
 * 4 cells across a part an eighth of the box wide; the grid's tape of a 100-node tree
 * then stays near 30 MB. */
#define SUPPORT_GRID_CELLS 32
/* Trims kept at most, and the unsupported edges a trim must remove to be kept (fewer
 * are the grid's noise along sharp edges). */
#define SUPPORT_MAX_TRIMS 4
#define SUPPORT_MIN_GAIN 4

/* The grid: nodes (i, j, k), i < dims[0] slowest, at o + i u[0] + j u[1] + k u[2]. */
typedef struct support_grid {
    const gp_cache *c;   /* the tree's leaves at the nodes (c->n = dims[0]*dims[1]*dims[2]) */
    size_t dims[3];
    double o[3], u[3][3];
    const double *clip;  /* per node: > 0 inside the clipping box */
    const kd_tree *cloud; /* the cloud's points */
    double *dist;        /* per node: distance to the nearest cloud point, NAN until an
                            edge at the node holds surface (filled here: most nodes are
                            far from every surface and never need it) */
    double tau;          /* an edge is unsupported when both ends are farther than tau */
} support_grid;

typedef struct support_info {
    size_t before, after;  /* unsupported edges of the tree before and after */
    uint32_t trims;        /* trims kept */
} support_info;

/* Unsupported edges of the surface of the field v (per node, clipped by g->clip). */
size_t support_count(support_grid *g, const double *v);

/* Trim t (a tree over g->c's and pc's leaves, which must be the same primitives) while
 * a trim removes at least SUPPORT_MIN_GAIN unsupported edges and keeps every point of pc
 * that t explains; e and eg: evaluators for pc and for the grid (their tapes are
 * replaced). 0 or -1 (allocation). */
int support_trim(gp_tree *t, gp_setops s, const gp_cache *pc, gp_eval *e,
                 support_grid *g, gp_eval *eg, support_info *info);

#endif

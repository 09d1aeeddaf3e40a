/* canon.h - the written form of an evolved model (evolve/canon.c, used by
 * evolve_write_model): each primitive in canonical form, its numbers rounded to the
 * precision its inliers support, named after its role; the tree with those names and
 * named sub-expressions.
 */
#ifndef FREP_CANON_H
#define FREP_CANON_H

#include <stddef.h>
#include <stdio.h>

#include "buf.h"
#include "evolve.h"
#include "prim.h"

/* Rounding and snapping stay within this fraction of the cloud's diagonal at the far
 * end of the primitive's inlier patch, so the rounded model's Chamfer distance to the
 * cloud moves by less than the 0.02% of the target. */
#define CANON_MAX_SHIFT 1e-4
/* A direction is snapped to an axis, a coordinate plane or a multiple of 15 degrees
 * in one when it is within 3 standard errors of it, or within the tilt the inliers'
 * scatter cannot tell (rms / patch size); never farther than this (radians, 0.5 deg). */
#define CANON_MAX_SNAP 0.0087

typedef struct canon_prim {
    prim q;              /* canonical: cylinder axis point at the foot of the
                            perpendicular from the inlier patch's centre; directions
                            snapped; plane offsets kept through the patch's centre */
    double qpos, qdir;   /* printing quanta: lengths and positions, unit components */
    double sigma;        /* standard error of positions (0: unknown, exact input) */
    int snapped;         /* a direction was snapped */
    int polarity;        /* bit 1: used as material, bit 2: as removed material */
    char name[40];       /* plane_z_top, cyl_bore_1, ... (unique) */
} canon_prim;

/* The check of the rounded model: the mean distance of the cloud's points (at most
 * about CANON_CHECK_POINTS of them, evenly strided) to the written tree may grow by
 * this fraction of the diagonal over the exact one. */
#define CANON_MAX_CHANGE 2e-4
#define CANON_CHECK_POINTS 4096

/* The canonical form of every primitive the tree uses (others: name empty).  out has
 * nprims entries.  With the cloud (may be NULL), each primitive takes the boldest form
 * (snapped within what its inliers cannot tell, rounded to its standard error) that
 * keeps the model within CANON_MAX_CHANGE of the exact one on the points, else the
 * form bounded by CANON_MAX_SHIFT, else stays exact; without it, the bounded form.
 * exact: every primitive as it is, printed with every digit (names only).
 * Returns 0, or -1 when out of memory. */
int canon_prims(const evolve_result *r, const prim *prims, size_t nprims,
                const frep_cloud *cloud, int exact, canon_prim *out);

/* Directions sampled by canon_tree_bounded on each of its two spheres. */
#define CANON_BOUND_DIRS 4096

/* Whether the tree of r (over prims, canonical or not) is bounded: outside at every
 * point of spheres of 2 and 8 diagonals around the cloud, CANON_BOUND_DIRS directions
 * each.  A sampled test: a slab thinner than the spacing of the samples there (about
 * 0.05 diagonals at 2) could pass between them. */
int canon_tree_bounded(const evolve_result *r, const prim *prims, size_t nprims);

/* The call of a canonical primitive, e.g. "frCylinder(x, 1.2, 0, 0.25, 0, 0, 1, 0.25)". */
void canon_write_call(FILE *f, const canon_prim *c);

/* The same solid in pure HyperFun: arithmetic of x[1..3] only (planes d - n.x,
 * spheres and cylinders r^2 - distance^2, cones and tori through sqrt), which the
 * reference HyperFun tools read; numbers as canon_write_call rounds them. */
void canon_write_hyperfun(FILE *f, const canon_prim *c);

/* The feature comment: type, size, inliers, what was snapped. */
void canon_write_comment(FILE *f, const canon_prim *c);

/* The tree as statements: sub-expressions of 5 nodes or more (in trees over 11 nodes)
 * as `block_N` (an intersection of 4 or more planes), `cut_N` (subtracted) or `part_N`,
 * then `tree = ...;`, chains of one operator flat.  names[j] names leaf j.  Indented
 * by four spaces, one statement a line. */
void canon_write_tree(frep_buf *b, const gp_tree *t, const char *const *names, const prim *prims,
                      size_t nprims);

#endif

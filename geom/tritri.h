/* tritri.h - exact triangle-triangle intersection of the mesh checker (geom/trimesh.c,
 * `frep mesh --check`): the signs of orient2d/orient3d are exact (floating-point
 * filter, expansion arithmetic when the filter cannot decide), so the answer does not
 * depend on rounding.
 */
#ifndef FREP_TRITRI_H
#define FREP_TRITRI_H

/* The sign (-1, 0, 1) of det [a - d; b - d; c - d]: positive when d lies below the
 * plane of a, b, c, seen counter-clockwise from above. */
int tri_orient3d(const double *a, const double *b, const double *c, const double *d);

/* Do triangles p = (p0, p1, p2) and q = (q0, q1, q2) (closed sets) share a point that
 * is not a vertex or edge both have in common?  nshared (0..3) vertices of the two
 * triangles are the same points, listed first in each triangle in the same order
 * (p0 == q0, p1 == q1, ...).  Two triangles sharing an edge intersect only when they
 * are coplanar and fold onto each other; sharing a vertex, when the edge of one
 * opposite to it meets the other; sharing all three, always. */
int tri_tri_intersect(const double *const p[3], const double *const q[3], int nshared);

#endif

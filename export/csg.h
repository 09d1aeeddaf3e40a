/* csg.h - a model as constructive solid geometry of standard solids: the checked
 * syntax tree (lang/ast.h) run symbolically, for the exports of export/scad.c.
 *
 * Pipeline: lang/parse.y -> lang/check.c -> export/csg.c (this tree) -> export/scad.c
 * (OpenSCAD text).  The tree is built from the compiler's tree, never from text: the
 * statements run with every value a *field* of the point (x[1..3] are affine forms of
 * the world coordinates, so hfShift3D/hfRotate3D/hfScale3D are just arithmetic on them),
 * library calls become solids in the frame their x array gives, set operations become
 * Boolean nodes.  What has no Boolean meaning (a blend, x[1]^2, a point-dependent if)
 * stops the translation with an error at the source construct's position.
 */
#ifndef FREP_CSG_H
#define FREP_CSG_H

#include <stddef.h>
#include <stdint.h>

#include "arena.h"
#include "ast.h"
#include "frep.h"

/* The standard solids, each in its own local frame q (see csg_node.A, b). */
typedef enum csg_prim {
    CSG_SPHERE,      /* |q - c| <= r                                     p: c[3], r */
    CSG_ELLIPSOID,   /* sum ((q - c)_i / s_i)^2 <= 1                     p: c[3], s[3] */
    CSG_CYL_AXIS,    /* infinite (elliptic) cylinder along axis `axis`   p: c[3], a, b */
    CSG_CONE_AXIS,   /* double (elliptic) cone along axis `axis`, radii a, b at distance 1
                                                                         p: c[3], a, b */
    CSG_TORUS_AXIS,  /* torus around axis `axis`                         p: c[3], R, r */
    CSG_BLOCK,       /* box from vertex v with edge lengths d (signed)   p: v[3], d[3] */
    CSG_CYLINDER,    /* infinite cylinder through p along u              p: p[3], u[3], r */
    CSG_CONE,        /* one-sided cone: apex p, axis u, half-angle       p: p[3], u[3], angle */
    CSG_TORUS,       /* torus: centre p, axis u                          p: p[3], u[3], R, r */
    CSG_BOX          /* box centre c, half sizes h, rotations rx, ry, rz (radians, applied
                        about x, then y, then z)                         p: c[3], h[3], r[3] */
} csg_prim;

typedef enum csg_kind {
    CSG_HALF,   /* the half-space k[0] + k[1..3] . w >= 0 (world coordinates w); also a
                   constant when k[1..3] = 0, and the value of every number */
    CSG_PRIM,   /* a standard solid */
    CSG_MIN,    /* intersection (a, b) */
    CSG_MAX,    /* union (a, b) */
    CSG_NOT     /* complement (a) */
} csg_kind;

typedef struct csg_node csg_node;
struct csg_node {
    csg_kind kind;
    double k[4];          /* CSG_HALF */
    csg_prim prim;        /* CSG_PRIM */
    int axis;             /* CSG_PRIM, *_AXIS: 0, 1, 2 for x, y, z */
    double p[9];          /* CSG_PRIM: parameters, see csg_prim */
    double A[9], b[3];    /* CSG_PRIM: local frame q = A w + b (row-major A) */
    csg_node *a, *c;      /* CSG_MIN, CSG_MAX: operands; CSG_NOT: a */
    int exact;            /* the node's value is the field itself (affine forms and
                             min/max of them), not only its sign: arithmetic on it is
                             exact; 0 for solids and R-function results */
    const char *name;     /* the variable first assigned this node (NULL: none); the
                           * exports name sub-expressions after it */
    ast_loc loc;          /* the source construct that made it */
};

/* Why a translation stopped: the position and message (without "error: "). */
typedef struct csg_error {
    ast_loc loc;          /* line 0: no position */
    uint32_t len;         /* caret span */
    char msg[256];
} csg_error;

/* Translate model number `model` of a file that passed lang/check.c into a tree in
 * arena A.  setops is the file's frep_setops (it decides which set operations are
 * min/max and so exact); a[] values as for frep_compile (missing: 0).  Returns the root,
 * or NULL with *e filled (A->failed when out of memory). */
csg_node *csg_from_model(arena *A, const ast_file *f, uint32_t model, int setops,
                         const double *a, size_t na, csg_error *e);

/* Whether the solid is bounded, judged from its structure: spheres, ellipsoids, tori,
 * blocks and boxes are; half-spaces, infinite cylinders and cones, complements are not;
 * a union is when both operands are; an intersection when one operand is, or when no
 * direction recedes in all of its half-spaces and cylinders (six faces of a box, a
 * bore capped by two planes).  A cone or complement counts as unbounded: the answer
 * may say unbounded for a bounded solid, never the converse. */
int csg_bounded(const csg_node *n);

#endif

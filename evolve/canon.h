/* canon.h - the written form of an evolved model (evolve/canon.c, used by
 * evolve_write_model): each primitive in canonical form, its numbers rounded to the
 * precision its inliers support, named after its role; the tree with those names and
 * named sub-expressions.
 */
#ifndef FREP_CANON_H
#define FREP_CANON_H

#include <signal.h>
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
/* A box cut away is dropped, whatever the grid says, when without it the model explains
 * (within eps_d) every check point it did and this share of them more (ft_drop_cuts). */
#define CANON_DROP_GAIN 0.005

/* The canonical form of every primitive the tree uses (others: name empty).  out has
 * nprims entries.  With the cloud (may be NULL), each primitive takes the boldest form
 * (snapped within what its inliers cannot tell, rounded to its standard error) that
 * keeps the model within CANON_MAX_CHANGE of the exact one on the points, else the
 * form bounded by CANON_MAX_SHIFT, else stays exact; without it, the bounded form.
 * exact: every primitive as it is, printed with every digit (names only).  cancel
 * (may be NULL) raised: the primitives not yet checked keep their fitted parameters,
 * as those whose rounding fails the check.  Returns 0, or -1 when out of memory. */
int canon_prims(const evolve_result *r, const prim *prims, size_t nprims,
                const frep_cloud *cloud, int exact, const volatile sig_atomic_t *cancel,
                canon_prim *out);

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

/* Cap planes of a capped cylinder: normals within this angle of its axis (radians, 3
 * degrees).  The caps are written as they are, so the grouping never changes the solid. */
#define CANON_CAP_TILT 0.052

/* The model's statements after its header: a comment counting the solids, the
 * primitives the tree names (canonical form c, a comment each), the solids their faces
 * form (an intersection's three pairs of opposite parallel planes on orthogonal axes as
 * frBox, a cylinder with a pair of opposite planes across its axis as a capped
 * cylinder), then the tree as statements ending in `tree = ...;`: the root's removed
 * operands as `bores` (or `cuts`) under `body`, in trees over 11 nodes every
 * sub-expression of 3 operands or more as `part_N` (`cut_N` when removed).  A box whose
 * faces are not exactly orthogonal pairs (within 2 CANON_MAX_SNAP) or whose rounded
 * numbers would move the model from the cloud (more than CANON_MAX_CHANGE of the
 * diagonal over the exact tree's mean distance) keeps its planes; without the cloud or
 * with exact, only exact boxes are formed (exact: none).  base_call: the --residual
 * base model's call (NULL: none).  cancel (may be NULL) raised: no further rewrite is
 * tried (the checks refuse it), the tree as rewritten so far is written.  Returns 0, or
 * -1 (memory, write error). */
/* A rewrite keeps the solid: at the CANON_GRID^3 cell centres of the cloud's oriented
 * box grown by 10%, the sign of the tree stays wherever the tree before it is farther
 * than CANON_GRID_TOL of the diagonal from 0 (the rounding of a box's numbers moves a
 * face by its quantum, below CANON_MAX_SHIFT). */
#define CANON_GRID 20
#define CANON_GRID_TOL 1e-3

/* Parts of a model apart (apply_parts): cloud points nearer than CANON_PARTS_GAP of the
 * diagonal are of one part; at most CANON_PARTS_MAX parts are covered alone (work
 * bound: a cover per part). */
#define CANON_PARTS_GAP 0.02
#define CANON_PARTS_MAX 8

/* Face positions per axis of a frame of the box cover (free ends aside): a planar
 * subtree with more, a stair of more steps, keeps its half-spaces. */
#define COVER_MAX_OFFS 8
/* Distinct planes of a subtree the cover reads, and orthogonal triples of their
 * directions (frames) it searches: a subtree with more keeps its half-spaces (work
 * bound: the frames' candidate boxes and point sets). */
#define COVER_MAX_PLANES 48
#define COVER_MAX_FRAMES 8
/* An operation of planes alone whose cover fails whole: each of its operands, up to
 * this many, is left out in turn and the others covered (work bound: a cover search
 * per operand). */
#define COVER_MAX_LEAVE_OUT 8
/* Cuts of one term P \ (N1 | N2): a box whose outside points no two cuts remove is no
 * term (the cover takes other boxes, or fails); and terms of one cover: a subtree
 * whose inside no COVER_MAX_TERMS terms cover keeps its half-spaces (work bound: the
 * greedy cover's rounds, each over every candidate term). */
#define COVER_MAX_CUTS 2
#define COVER_MAX_TERMS 24
/* Candidate cuts a box's are chosen from: the best ranked (the impure boxes' outside
 * points they hold, less inside points), the others not tried (work bound: each
 * impure box tries each candidate for each of its cuts). */
#define COVER_MAX_NEG 256
/* Cloud points the cover labels (moved in and out along their normals): at most this
 * many, evenly spread over the cloud (canon_spread), the same on every run. */
#define COVER_CLOUD_POINTS 2048
/* A union of planes X & (h1 | h2 | h3) written as the box it cuts away, X \ box: at
 * least this many planes (the box of one plane is no fewer solids than its
 * half-space). */
#define POCKET_MIN_FACES 2
/* A pocket's faces read as one box's by ft_wedge when their normals are this close to
 * a frame's axes, in degrees: fitted to noisy points, a small face's normal is off by
 * up to 3.2 degrees (three_cuboids at 0.5% noise); the model must keep its solid. */
#define CANON_WEDGE_DEG 5.0
/* face_scan's places for a free face of a cut: this many to each eps_d. */
#define CANON_SCAN_STEPS 4
/* ... and moves one only where the points around the cut fit this many points' worth
 * better (a pocket's wrong cut through a wall loses hundreds). */
#define CANON_SCAN_GAIN 10
/* ... and where at least this many points lie on the face: within eps_d of it, inside
 * its rectangle, their normals within CANON_SCAN_NORMAL_DEG of it.  A far face of the
 * pocket three_cuboids' turned cube cuts (12-23 points of its own at 0.5% noise) has
 * 12-90 so counted. */
#define CANON_SCAN_SUPPORT 10
/* ... and where the part of the face the model shows has a point near (2 eps_d) over
 * this share of it, sampled on a CANON_SCAN_GRID square grid: a face where no point
 * lies leaves material where there is none (the points count only where they are).
 * three_cuboids' pocket's far faces at 0.5% noise: 1.0; faces a cut that must go on
 * beyond the part was stopped at by the noise (tests/evolve_pocket.sh's corner cut at
 * 1% noise): 0.29-0.41, with 0-22 points on them. */
#define CANON_SCAN_COVERED 0.6
#define CANON_SCAN_GRID 24
#define CANON_SCAN_NORMAL_DEG 25.0
/* ft_wedge places a pocket's free faces in turn this many times (each place depends on
 * where the others are). */
#define WEDGE_ROUNDS 2

/* A sphere the tree leaves out that closes cylinders of its radius (apply_joints): each
 * cylinder's radius within JOINT_RADIUS of the sphere's, its axis within JOINT_AXIS
 * radii of the centre; two cylinders' axes at right angles within JOINT_ORTHO_DEG (a
 * frame's corner); the corner cut reaches JOINT_REACH radii from the centre (the
 * crossing rails' square corner lies within one radius of it along each axis). */
#define JOINT_RADIUS 0.15
#define JOINT_AXIS 0.25
#define JOINT_ORTHO_DEG 10.0
#define JOINT_REACH 1.25

/* The k-th (k < m = min(n, most)) of m indices evenly spread over 0..n-1: floor(k n / m),
 * so that a cloud of n points gives exactly m of them, the first one 0. */
size_t canon_spread(size_t k, size_t n, size_t most);

int canon_write_body(FILE *f, const evolve_result *r, const prim *prims, const canon_prim *c,
                     size_t nprims, const frep_cloud *cloud, int exact, int hyperfun,
                     const char *base_call, const volatile sig_atomic_t *cancel);

#endif

/* mesh.h - polygonization: dual contouring of a scalar field on a sparse grid whose
 * active blocks are found by an interval-pruned octree (mesh/polygonize.c drives
 * octree.c -> mesh.c -> quads.c; mesh/field.c is the field of a compiled program).
 *
 * Sits after the evaluators (frep_eval, frep_eval_grad, vm_eval_interval) and before
 * the mesh writers of geom/meshio.c; `frep mesh`, `frep sample` and `frep render`
 * call it.  The field is abstract (mesh_field) so tests can mesh C callbacks.
 */
#ifndef FREP_MESH_H
#define FREP_MESH_H

#include <signal.h>
#include <stddef.h>
#include <stdint.h>

#include "cancel.h"
#include "err.h"
#include "frep.h"
#include "trimesh.h"

/* Limits, each with its reason. */
#define MESH_MAX_GRID 2048       /* cells per axis: a closed surface at 2048^3 already has
                                    ~10^8 triangles, more than any consumer can load */
#define MESH_MAX_WORK_BYTES ((size_t)3 << 30) /* working memory of the active blocks; past
                                    it the run stops with a message instead of swapping */
#define MESH_MAX_TRIANGLES ((size_t)1 << 30) /* uint32 vertex indices, STL's uint32 count */

/* A scalar field to polygonize: inside where f >= iso.  Callbacks receive ctx and a
 * per-thread state made by thread_new (which may return ctx itself when the field has
 * no per-thread state; NULL means out of memory); thread_free is never called by two
 * threads at once (it may merge the thread's results into ctx).  eval and grad evaluate n points and
 * return 0 or -1; interval (may be NULL: no pruning) encloses f over a box {x0, y0, z0,
 * x1, y1, z1} in [*lo, *hi], soundly ([-inf, inf] when it cannot tell). */
typedef struct mesh_field {
    void *ctx;
    void *(*thread_new)(void *ctx);
    void (*thread_free)(void *ctx, void *ts);
    int (*eval)(void *ctx, void *ts, size_t n, const double *x, const double *y,
                const double *z, double *f);
    int (*grad)(void *ctx, void *ts, size_t n, const double *x, const double *y,
                const double *z, double *f, double *gx, double *gy, double *gz);
    int (*interval)(void *ctx, void *ts, const double box[6], double *lo, double *hi);
    /* May be NULL; only used when iso is 0.  Announce that the thread's next
     * evaluations lie in box (NULL: may lie anywhere): the field may then specialize
     * itself (tape pruning), provided every value of magnitude >= *sign_tol keeps its
     * sign, the zero set and its normals stay; values closer to 0 are evaluated again
     * after focus(NULL).  Focusing again on the same box must be cheap. */
    int (*focus)(void *ctx, void *ts, const double box[6], double *sign_tol);
    /* Node-evaluations of one point's value (a program's instructions), which sizes
     * the thread count of each stage (frep_threads_for); 0: MESH_FIELD_COST. */
    double cost;
} mesh_field;

/* The cost assumed for a field that does not say (mesh_field.cost 0): a small model. */
#define MESH_FIELD_COST 32

/* The field of a compiled program with parameter values `params` (NULL: its own; the
 * array must outlive the field). Returns 0, or -1 when out of memory. Release with
 * mesh_field_program_free(). */
int mesh_field_program(mesh_field *f, const frep_program *p, const double *params);
void mesh_field_program_free(mesh_field *f);
/* Runtime domain errors (sqrt of a negative, ...) raised so far by evaluations through
 * the field, merged over threads (lowest pc first, counts added; a point evaluated
 * twice counts twice).  Report with frep_report_runtime_error(). */
void mesh_field_program_errors(const mesh_field *f, frep_runtime_error *e);

typedef struct mesh_options {
    double box[6];      /* x0, y0, z0, x1, y1, z1 */
    int grid;           /* cells per axis (1..MESH_MAX_GRID) */
    int grid_axes[3];   /* cells along x, y, z, each 1..MESH_MAX_GRID (HyperFun's
                           -g NX,NY,NZ); 0: grid */
    double iso;         /* surface level: inside where f >= iso */
    int nthreads;       /* <= 0: OpenMP's default */
    /* Called from one thread with the fraction done (0..1); may be NULL. */
    void (*progress)(void *user, double fraction);
    void *progress_user;
    /* Ctrl-C (cancel.h; may be NULL): polled per octree node and per block; the run
     * then fails with FREP_ECANCEL (a partial mesh is no result). */
    volatile sig_atomic_t *interrupt;
    /* 1: leave the vertices where the QEF put them, without projecting those farther
     * than 0.1 cell onto the surface (the sampler projects its own points). */
    int no_projection;
} mesh_options;

void mesh_options_init(mesh_options *o);   /* box [-10,10]^3, grid 30, iso 0 */
/* The cells along axis c (0..2): grid_axes[c], or grid when that is 0. */
static inline int mesh_options_cells(const mesh_options *o, int c)
{
    return o->grid_axes[c] > 0 ? o->grid_axes[c] : o->grid;
}

/* The steps of the polygonizer whose wall time mesh_stats keeps (doc/mesh.md): the
 * octree, the blocks' contouring (with the faces' resolution and the vertices'
 * numbering), the quads, the assembly of the blocks' arrays into the mesh, and the
 * settling of the vertices left off the surface. */
enum { MESH_STAGE_OCTREE, MESH_STAGE_CONTOUR, MESH_STAGE_QUADS, MESH_STAGE_ASSEMBLY,
       MESH_STAGE_SETTLE, MESH_NSTAGES };

/* What happened, for the summary line and the tests. */
typedef struct mesh_stats {
    size_t octree_nodes;     /* interval tests made */
    size_t blocks;           /* blocks evaluated (of MESH_BLOCK^3 cells) */
    size_t blocks_total;     /* blocks of the whole grid */
    size_t cells_split;      /* cells with more than one surface component */
    size_t points_nan;       /* grid points where f was NaN (counted as outside) */
    int touches_box;         /* the solid reaches the box: the mesh is capped there */
    int full;                /* every grid point is inside */
    size_t eval_points;      /* points evaluated (values only) */
    size_t grad_points;      /* points evaluated with the gradient */
    double seconds;
    double stage_seconds[MESH_NSTAGES];  /* wall time of each step (MESH_STAGE_*) */
    size_t face_vertices;    /* extra vertices on faces crossed twice by one sheet */
    size_t settled;          /* vertices moved onto the surface after the quads */
} mesh_stats;

/* Polygonize. Returns 0 with a closed, oriented mesh in *out (possibly empty: no
 * point of the grid inside, or, with stats->full, the box itself; free with
 * mesh_free), or -1 with *e set: bad options (FREP_EINPUT), a limit of this header
 * (FREP_ELIMIT), out of memory (FREP_ENOMEM), a failing field (FREP_EINPUT). */
int mesh_polygonize(const mesh_field *f, const mesh_options *o, frep_mesh *out,
                    mesh_stats *stats, frep_error *e);

/* --check's bound on mesh_distance.max_dist, in cells: dual contouring places a
 * vertex on the surface's tangent planes, so only a misplaced vertex is this far. */
#define MESH_SURFACE_TOL 0.1

/* The vertices' distances from the surface, in cells (o's box and grid scaled so that
 * a cell is a unit cube): |f - iso| / |grad f|, or where that exceeds the
 * tolerance, the smaller radius at which a search around the vertex reaches the other
 * side of the level (mesh/distance.c). */
typedef struct mesh_distance {
    double max_dist;         /* the largest distance */
    size_t worst;            /* a vertex that far */
    size_t far;              /* vertices farther than the tolerance */
    size_t capped;           /* vertices on the box's faces (caps), not measured */
    size_t skipped;          /* vertices where f or grad f is NaN, not measured */
} mesh_distance;

/* Measure m (made from f with options o) against tolerance tol (cells).  Returns 0,
 * or -1 with *e set (out of memory, a failing field). */
int mesh_surface_distance(const mesh_field *f, const mesh_options *o, const frep_mesh *m,
                          double tol, mesh_distance *r, frep_error *e);

#endif

/* mesh_internal.h - what the stages of the polygonizer share (not public API).
 *
 * mesh_polygonize (polygonize.c) runs: the octree finds the blocks (octree.c), each
 * block places its vertices by dual contouring (mesh.c), faces crossed twice are
 * confirmed and the quads made (quads.c).  The types below carry a run's state
 * between them: one mesher per run, one mblock per block of MESH_BLOCK^3 cells.
 */
#ifndef FREP_MESH_INTERNAL_H
#define FREP_MESH_INTERNAL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "mesh.h"
#include "threads.h"
#include "util.h"

/* Cells per block edge: 9^3 corner evaluations per call amortize the evaluator's
 * per-call cost, while blocks stay small enough to follow the surface. */
#define MESH_BLOCK 8
#define MESH_BLOCK_CORNERS ((MESH_BLOCK + 1) * (MESH_BLOCK + 1) * (MESH_BLOCK + 1))
#define MESH_BLOCK_CELLS (MESH_BLOCK * MESH_BLOCK * MESH_BLOCK)
#define MESH_BLOCK_EDGES (3 * MESH_BLOCK_CORNERS)
#define MESH_NO_VERTEX 0xFFFFu

/* ---- cell topology table ---------------------------------------------------------
 * Corner i of a cell is at (i & 1, (i >> 1) & 1, (i >> 2) & 1).  Edge e = 4a + u + 2v
 * runs along axis a; u and v are its coordinates along the two other axes (lower
 * axis first).  Face 2a + s is the cell's face across axis a on side s (0 low, 1 high).
 *
 * A cell's configuration is its case (bit i: corner i inside) and, in bits 8..13, bit
 * 8 + 2a + s set when face 2a + s is ambiguous (inside corners on a diagonal) and its
 * inside corners are joined across it (the field at the face's centre is inside, see
 * mesh.c); the bit is clear on every face that is not ambiguous, so only those
 * configurations occur, and only they are filled in. */
#define MESH_FACE_SHIFT 8
#define MESH_CONFIGS (256 << 6)

typedef struct cell_table {
    uint8_t ncycles[MESH_CONFIGS];
    uint8_t cycle[MESH_CONFIGS][12];   /* component of each crossing edge; 0xFF: none */
    /* bit 2a + s: face s across axis a is ambiguous (four crossings, two segments)
     * and both segments belong to one component of the cell */
    uint8_t dupface[MESH_CONFIGS];
} cell_table;

/* Fill t for the configurations that occur (mesh.c). */
void mesh_cell_table_build(cell_table *t);

/* Whether configuration cf joins the inside corners across face 2a + s (only set on
 * ambiguous faces): each of the face's two segments then cuts off an outside corner,
 * else an inside one. */
static inline int mesh_face_joined(int cf, int a, int s)
{
    return (cf >> (MESH_FACE_SHIFT + 2 * a + s)) & 1;
}

/* The two axes other than a, lower first. */
static inline void mesh_edge_other_axes(int a, int *o1, int *o2)
{
    *o1 = a == 0 ? 1 : 0;
    *o2 = a == 2 ? 1 : 2;
}

static inline int mesh_cell_index(int i, int j, int k)
{
    return i + MESH_BLOCK * (j + MESH_BLOCK * k);
}

/* ---- a run and its blocks --------------------------------------------------------- */

/* One block of cells. Valid after mesh_block_contour: vertex data and the per-cell
 * configuration and first-vertex index (cases 0 and 255 have no vertex), all NULL in
 * a block without vertices.  The arrays are held by the pools of the thread that
 * made them (mmem). */
typedef struct mblock {
    uint64_t key;
    int b[3];
    uint32_t nverts;          /* component vertices of the cells */
    /* Faces one sheet crosses twice whose high-side cell is in this block (candidates
     * after mesh_block_contour, only the confirmed ones after mesh_resolve_faces):
     * each has two vertices, one per segment, stored after the nverts cell vertices. */
    uint32_t nfaces;
    uint16_t *fkey;           /* per face: 3 * (local index of the high-side cell) + axis,
                                 ascending */
    uint32_t need;            /* bit (dx+1) + 3(dy+1) + 9(dz+1): neighbours with crossings */
    uint32_t real_crossings, inside_corners, virtual_crossings, nan_points, split_cells;
    size_t vglobal;           /* index of the first vertex in the whole mesh */
    double *vpos, *vnrm;      /* 3 * (nverts + 2 nfaces) each */
    double *vfg;              /* 4 * (...): f - iso and the gradient at each vertex */
    uint8_t *vrank;           /* QEF rank (2: on a sharp edge, 3: a corner; 0 on faces
                                 and at mass points), kept for settling */
    uint16_t *cs;             /* MESH_BLOCK_CELLS configurations (case and joined faces) */
    uint16_t *vbase;          /* MESH_BLOCK_CELLS first vertex or MESH_NO_VERTEX */
    uint32_t *tri;            /* triangles from the quads this block owns (phase 3) */
    size_t ntri;
    size_t tglobal;           /* index of its first triangle in the mesh (assembly) */
    int failed;
} mblock;

typedef struct mwork mwork;   /* per-thread buffers of mesh_block_contour (mesh.c) */

/* The blocks' arrays live in per-thread pools, one pool per kind of array, handed out
 * from slabs of MESH_SLAB_BYTES and freed a kind at a time once assembly has copied
 * it: a block's arrays cost no call to malloc, and a freed kind goes back to the
 * heap as whole slabs, which the system gets back (glibc maps chunks this large
 * on their own) or the next run's slabs reuse, not as thousands of small holes between
 * the arrays still in use. */
#define MESH_SLAB_BYTES ((size_t)1 << 20)

enum {
    MESH_POOL_CELLS,          /* cs, vbase, fkey: until assembly */
    MESH_POOL_TRI,            /* tri: until its gather */
    MESH_POOL_POS,            /* vpos: until its gather */
    MESH_POOL_NRM,            /* vnrm: until its gather */
    MESH_POOL_FG,             /* vfg, vrank: kept for settling, until the run's end */
    MESH_POOLS
};

typedef struct mslab mslab;
typedef struct mpool {
    mslab *slabs;             /* the newest first; the others are full */
} mpool;

/* One thread's pools, and its buffer for the triangles of the block at hand
 * (quads.c), reused from block to block. */
typedef struct mmem {
    mpool pool[MESH_POOLS];
    uint32_t *tri;
    size_t tricap;            /* triangles tri holds */
} mmem;

typedef struct mesher {
    const mesh_field *f;
    const mesh_options *o;
    cell_table table;
    int g[3];                 /* cells along each axis of the box */
    int G[3];                 /* padded cells along each axis: g + 2 */
    int nb[3];                /* blocks along each axis */
    int nbk;                  /* the largest nb: the stride of block keys */
    double h[3];              /* cell size per axis (tolerances; corners: mesh_coord) */
    int nthreads;
    void **ts;                /* per-thread field state */
    mwork **works;            /* per-thread block buffers */
    mmem *mems;               /* per-thread memory of the blocks' arrays */
    mblock **blocks;          /* sorted by key */
    size_t nblocks, capblocks;
    size_t bytes;
} mesher;

/* The work of a stage, in point evaluations of the field, sizes its thread count
 * (frep_threads_for, with the field's cost): an octree node's interval evaluation
 * counts as MESH_INTERVAL_POINTS points, a contoured block as its corners twice
 * (values, then gradients and the roots on crossing edges), a block's quads as its
 * cells (no evaluation: table look-ups).  An interval instruction does the work of
 * 100-140 lanes of a point block: measured on the octrees of `make bench-mesh` at -g
 * 128, 12 us a node for the gears' 447 instructions (R-functions or min/max), 1.3 us
 * for the gyroid's 37, 3.4 us for bench_mesh.hf's 153, against 0.11 us and 9 ns a
 * point for the gear and the gyroid in contouring. */
#define MESH_INTERVAL_POINTS 100
#define MESH_CONTOUR_POINTS (2.0 * MESH_BLOCK_CORNERS)
#define MESH_QUADS_POINTS (1.0 * MESH_BLOCK_CELLS)

/* Settling (settle.c) evaluates a batch's run of points in one block on the program
 * focused on the block's box (the pruned program of the block's own evaluations: the
 * whole one costs several times more on CSG parts) when the run has at least this many
 * points.  Pruning costs some tens of evaluations of the whole program, so a shorter
 * run evaluates the whole program: a vertex adds 1-8 points to a batch, and on the gear
 * of make bench-mesh, refocusing the blocks in each of the batches was 60% of the
 * settling (7 of 12 ms). */
#define SETTLE_FOCUS_MIN 32

/* The threads for a stage of `units` pieces costing `points` point evaluations in
 * all: frep_threads_for the run's -t, never more than the run's thread states. */
static inline int mesh_threads_for(const mesher *M, double points, size_t units)
{
    double cost = M->f->cost > 0 ? M->f->cost : MESH_FIELD_COST;
    int nt = frep_threads_for(M->o->nthreads, points * cost, units);
    return nt < M->nthreads ? nt : M->nthreads;
}

/* World coordinate of padded corner index P along axis c: grid point P - 1 of the
 * box's g cells (frep_grid_coord, the end points exact; P = 0 and G extrapolate). */
static inline double mesh_coord(const mesher *M, int c, long P)
{
    return frep_grid_coord(M->o->box[c], M->o->box[c + 3], P - 1, M->g[c]);
}

/* The field's box of a block reaches this fraction of a cell beyond the block's
 * corners, so that rounding cannot put a corner outside it. */
#define MESH_FOCUS_SLACK 1e-9

/* The box block B focuses the field on (its cells, MESH_FOCUS_SLACK wider). */
static inline void mesh_block_box(const mesher *M, const mblock *B, double bb[6])
{
    for (int k = 0; k < 3; k++) {
        double slack = MESH_FOCUS_SLACK * M->h[k];
        bb[k] = mesh_coord(M, k, (long)B->b[k] * MESH_BLOCK) - slack;
        bb[k + 3] = mesh_coord(M, k, (long)B->b[k] * MESH_BLOCK + MESH_BLOCK) + slack;
    }
}

/* |f - iso| / |grad f| of a point in cells (the grid scaled to unit cubes, as
 * mesh_surface_distance measures); NaN when the gradient says nothing. */
static inline double mesh_cell_distance(const mesher *M, double f, double gx, double gy, double gz)
{
    gx *= M->h[0];
    gy *= M->h[1];
    gz *= M->h[2];
    double gl = sqrt(gx * gx + gy * gy + gz * gz);
    return gl > 0 && isfinite(gl) ? fabs(f) / gl : NAN;
}

/* ---- the stages (each file's header says more) ------------------------------------ */

/* polygonize.c: n bytes (aligned for any type) from pool p; NULL when out of memory. */
void *mesh_pool_alloc(mpool *p, size_t n);
/* Free the pools of one kind on every thread. */
void mesh_pools_free(const mesher *M, int kind);

/* octree.c: the sorted list of blocks and the octree that fills it. */
uint64_t mesh_block_key(const mesher *M, long bx, long by, long bz);
mblock *mesh_block_find(const mesher *M, uint64_t key);   /* NULL: not in the list */
int mesh_block_cmp(const void *a, const void *b);         /* qsort by key */
void mesh_block_free(mblock *B);   /* the block, not its arrays (held by the pools) */
/* Append a new empty block at (bx, by, bz); 0, or -1 when out of memory. */
int mesh_block_add(mesher *M, long bx, long by, long bz);
/* The blocks the interval test cannot prove empty or full, sorted. */
int mesh_find_blocks(mesher *M, mesh_stats *st, frep_error *e);
/* After blocks [first, old) were contoured: append the unlisted neighbours towards
 * which they found crossings.  0, or -1 when out of memory. */
int mesh_add_needed_blocks(mesher *M, size_t first, size_t old);

/* mesh.c: dual contouring of one block, with per-thread buffers. */
mwork *mesh_work_new(void);
/* Add W's evaluation counts to st and free W. */
void mesh_work_free(mwork *W, mesh_stats *st);
/* Evaluate block B's corners, find its crossings and place its cell vertices. Returns 0,
 * FREP_ENOMEM when out of memory or FREP_EINPUT when the field failed. */
int mesh_block_contour(const mesher *M, mwork *W, mmem *mem, void *ts, mblock *B);

/* quads.c: the faces crossed twice on both sides, then the triangles. */
void mesh_resolve_faces(mesher *M);
/* The triangles of the quads block B owns into B->tri, from the thread's mem. 0, or
 * -1 when out of memory. */
int mesh_block_quads(mesher *M, mmem *mem, mblock *B);

/* settle.c: the cell vertices still farther than MESH_SETTLE_TOL cells from the
 * surface moved onto it where their fan does not fold.  0, FREP_ENOMEM or FREP_EINPUT
 * (the field failed). */
int mesh_settle_vertices(const mesher *M, frep_mesh *out, mesh_stats *st);

#endif

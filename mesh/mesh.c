/* mesh.c - dual contouring on a sparse grid found by an interval-pruned octree.
 *
 * Pipeline: (1) an octree over blocks of MESH_BLOCK^3 cells drops blocks the interval
 * evaluator proves empty or full; (2) each surviving block evaluates its corners,
 * finds edge crossings (regula falsi) and their normals (analytic gradient), splits
 * each cell's crossings into surface components (cycles, see below) and places one
 * vertex per component by a QEF (truncated pseudo-inverse, mass-point bias, clamped to
 * the cell), so sharp CSG edges and corners survive; (3) every crossing edge becomes a
 * quad joining the component vertices of its four cells.  The result is written by
 * geom/meshio.c.
 *
 * Manifoldness: a cell's crossing edges are paired on each face (an ambiguous face,
 * two inside corners on a diagonal, always separates the inside corners), which only
 * depends on the face, so both cells sharing a face agree; following the pairs gives
 * cycles, one vertex each.  Every mesh edge then joins the vertices of two cells across
 * one segment of their common face, and every vertex's quads follow its cycle around:
 * one closed fan.  The one exception, a face whose two segments belong to one
 * component on both sides (a tunnel thinner than a cell), would make the same mesh
 * edge twice; such faces get a vertex per segment (face_candidates, resolve_faces),
 * so the mesh is a closed 2-manifold for any field.  The grid is padded with a layer
 * of cells whose outer corners count as outside, so a solid cut by the box is closed
 * by caps on the box.  Determinism: blocks are processed independently and assembled
 * in key order, so the mesh does not depend on the thread count.
 */
#include "config.h"

#include "alloc.h"
#include "mesh.h"
#include "interval.h"
#include "linalg.h"
#include "program.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef _OPENMP
#include <omp.h>
#endif

/* Cells per block edge: 9^3 corner evaluations per call amortize the evaluator's
 * per-call cost, while blocks stay small enough to follow the surface. */
#define MESH_BLOCK 8
#define MESH_BLOCK_CORNERS ((MESH_BLOCK + 1) * (MESH_BLOCK + 1) * (MESH_BLOCK + 1))
#define MESH_BLOCK_CELLS (MESH_BLOCK * MESH_BLOCK * MESH_BLOCK)
#define MESH_BLOCK_EDGES (3 * MESH_BLOCK_CORNERS)
/* Regula falsi (Illinois) steps per crossing at most: converges superlinearly; 8 steps
 * put crossings of smooth fields far below 1e-6 cell.  A crossing stops earlier when
 * its bracket is narrower than MESH_ROOT_TOL (fraction of the edge) or it hit the
 * level exactly, so near-linear fields (planes) cost one or two evaluations. */
#define MESH_ROOT_STEPS 8
#define MESH_ROOT_TOL 1e-5
/* A crossing also stops when the secant slope over its bracket puts the last point
 * within this fraction of the edge from the root: the Newton step along the edge that
 * the gradient at the final point pays for (step 3) then takes a smooth field's
 * crossing to about the square of that. */
#define MESH_ROOT_FTOL 1e-2
/* QEF eigenvalues below this fraction of the largest are dropped (truncated
 * pseudo-inverse): near-parallel normals must not throw the vertex out of its cell. */
#define MESH_QEF_CUTOFF 0.05
/* Vertices stay this fraction of a cell inside their cell, so that vertices of
 * different cells never coincide (no zero-area triangles). */
#define MESH_CLAMP 1e-4
#define MESH_NO_VERTEX 0xFFFFu
/* Vertices of a block at most: 4 surface components per cell, plus 2 vertices on each
 * of a cell's 3 low faces when one component crosses that face twice (see
 * face_candidates). */
#define MESH_BLOCK_VMAX (10 * MESH_BLOCK_CELLS)

/* ---- cell topology table ---------------------------------------------------------
 * Corner i of a cell is at (i & 1, (i >> 1) & 1, (i >> 2) & 1).  Edge e = 4a + u + 2v
 * runs along axis a; u and v are its coordinates along the two other axes (lower
 * axis first). */

typedef struct cell_table {
    uint8_t ncycles[256];
    uint8_t cycle[256][12];   /* component of each crossing edge; 0xFF: no crossing */
    /* bit 2a + s: face s (0 low, 1 high) across axis a is ambiguous (four crossings,
     * two segments) and both segments belong to one component of the cell */
    uint8_t dupface[256];
} cell_table;

static void edge_other_axes(int a, int *o1, int *o2)
{
    *o1 = a == 0 ? 1 : 0;
    *o2 = a == 2 ? 1 : 2;
}

static int edge_start(int e)
{
    int a = e / 4, o1, o2;
    edge_other_axes(a, &o1, &o2);
    return ((e & 1) << o1) | (((e >> 1) & 1) << o2);
}

static int edge_end(int e) { return edge_start(e) | (1 << (e / 4)); }

static void build_table(cell_table *t)
{
    for (int cs = 0; cs < 256; cs++) {
        int partner[12][2], np[12];
        int cross[12];
        for (int e = 0; e < 12; e++) {
            cross[e] = ((cs >> edge_start(e)) & 1) != ((cs >> edge_end(e)) & 1);
            np[e] = 0;
            t->cycle[cs][e] = 0xFF;
        }
        for (int a = 0; a < 3; a++)
            for (int s = 0; s < 2; s++) {
                int fe[4], nf = 0;
                for (int e = 0; e < 12; e++) {
                    int ea = e / 4;
                    if (ea == a) continue;
                    int o1, o2;
                    edge_other_axes(ea, &o1, &o2);
                    int coord = o1 == a ? (e & 1) : ((e >> 1) & 1);
                    if (coord == s && cross[e]) fe[nf++] = e;
                }
                if (nf == 2) {
                    partner[fe[0]][np[fe[0]]++] = fe[1];
                    partner[fe[1]][np[fe[1]]++] = fe[0];
                } else if (nf == 4) {
                    /* Ambiguous face: cut off each inside corner on its own. */
                    for (int c = 0; c < 8; c++) {
                        if (((c >> a) & 1) != s || !((cs >> c) & 1)) continue;
                        int pair[2], k = 0;
                        for (int i = 0; i < 4; i++)
                            if (edge_start(fe[i]) == c || edge_end(fe[i]) == c) pair[k++] = fe[i];
                        if (k == 2) {
                            partner[pair[0]][np[pair[0]]++] = pair[1];
                            partner[pair[1]][np[pair[1]]++] = pair[0];
                        }
                    }
                }
            }
        uint8_t nc = 0;
        for (int e = 0; e < 12; e++) {
            if (!cross[e] || t->cycle[cs][e] != 0xFF) continue;
            int prev = -1, cur = e;
            while (cur >= 0 && t->cycle[cs][cur] == 0xFF) {
                t->cycle[cs][cur] = nc;
                int next = partner[cur][0] != prev ? partner[cur][0] : partner[cur][1];
                if (np[cur] < 2) next = -1;
                prev = cur;
                cur = next;
            }
            nc++;
        }
        t->ncycles[cs] = nc;
        t->dupface[cs] = 0;
        for (int a = 0; a < 3; a++)
            for (int s = 0; s < 2; s++) {
                int nf = 0, same = 1, first = -1;
                for (int e = 0; e < 12; e++) {
                    if (e / 4 == a || !cross[e]) continue;
                    int o1, o2;
                    edge_other_axes(e / 4, &o1, &o2);
                    if ((o1 == a ? (e & 1) : ((e >> 1) & 1)) != s) continue;
                    nf++;
                    if (first < 0) first = t->cycle[cs][e];
                    else if (t->cycle[cs][e] != first) same = 0;
                }
                if (nf == 4 && same) t->dupface[cs] |= (uint8_t)(1u << (2 * a + s));
            }
    }
}

/* ---- small linear algebra: symmetric 3x3 eigen decomposition (cyclic Jacobi) ------ */

/* The QEF matrix is a sum of n n^T over unit normals, entries of order 1 or more: an
 * off-diagonal sum below 1e-30 is far below rounding; 24 sweeps bound the loop. */
static const linalg_jacobi_stop qef_stop = {24, 1e-30, 0, 1e-300};

/* Minimize sum (n_i . (x - p_i))^2 near the mass point, inside [lo, hi]. Returns the
 * rank used: 1 on a flat patch, 2 on an edge, 3 at a corner (0: the mass point). */
static int qef_solve(int np, const double (*p)[3], const double (*nrm)[3],
                      const double lo[3], const double hi[3], double out[3])
{
    double m[3] = { 0, 0, 0 };
    for (int i = 0; i < np; i++)
        for (int c = 0; c < 3; c++) m[c] += p[i][c] / np;
    double A[3][3] = { { 0 } }, b[3] = { 0, 0, 0 };
    for (int i = 0; i < np; i++) {
        double d = nrm[i][0] * (p[i][0] - m[0]) + nrm[i][1] * (p[i][1] - m[1]) +
                   nrm[i][2] * (p[i][2] - m[2]);
        for (int r = 0; r < 3; r++) {
            b[r] += nrm[i][r] * d;
            for (int c = 0; c < 3; c++) A[r][c] += nrm[i][r] * nrm[i][c];
        }
    }
    double slack[3];
    for (int c = 0; c < 3; c++) slack[c] = MESH_CLAMP * (hi[c] - lo[c]);
    /* Flat patch, the common case: with u the mean normal's direction, the two lower
     * eigenvalues sum to at most sum (1 - (n_i.u)^2) (the trace is sum |n_i|^2) and
     * the largest is at least u'Au; when the first is below MESH_QEF_CUTOFF times the
     * second, the rank is 1 and u stands in for the top eigenvector (they differ by
     * less than the normals' spread): no eigen decomposition. */
    {
        double u[3] = { 0, 0, 0 }, tr = 0, lu = 0;
        for (int i = 0; i < np; i++)
            for (int c = 0; c < 3; c++) u[c] += nrm[i][c];
        lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        if (lu > 0) {
            for (int c = 0; c < 3; c++) u[c] /= lu;
            double uau = 0, ub = u[0] * b[0] + u[1] * b[1] + u[2] * b[2];
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++) uau += u[r] * A[r][c] * u[c];
            tr = A[0][0] + A[1][1] + A[2][2];
            if (uau > 0 && tr - uau <= MESH_QEF_CUTOFF * uau) {
                double x[3];
                int inside = 1;
                for (int c = 0; c < 3; c++) {
                    x[c] = m[c] + u[c] * ub / uau;
                    if (!(x[c] >= lo[c] + slack[c] && x[c] <= hi[c] - slack[c])) inside = 0;
                }
                int rank = inside;
                for (int c = 0; c < 3; c++) {
                    double y = inside ? x[c] : m[c];
                    out[c] = fmin(fmax(y, lo[c] + slack[c]), hi[c] - slack[c]);
                }
                return rank;
            }
        }
    }
    double w[3], V[3][3];
    linalg_sym3_jacobi((const double(*)[3])A, &qef_stop, w, V);
    int ord[3] = { 0, 1, 2 };
    for (int i = 0; i < 3; i++)
        for (int j = i + 1; j < 3; j++)
            if (w[ord[j]] > w[ord[i]]) { int t = ord[i]; ord[i] = ord[j]; ord[j] = t; }
    double wmax = w[ord[0]];
    int rank = 0;
    while (rank < 3 && wmax > 0 && w[ord[rank]] > MESH_QEF_CUTOFF * wmax) rank++;
    for (; rank >= 0; rank--) {
        double x[3] = { m[0], m[1], m[2] };
        for (int j = 0; j < rank; j++) {
            int k = ord[j];
            double coef = (V[0][k] * b[0] + V[1][k] * b[1] + V[2][k] * b[2]) / w[k];
            for (int c = 0; c < 3; c++) x[c] += coef * V[c][k];
        }
        int inside = 1;
        for (int c = 0; c < 3; c++)
            if (!(x[c] >= lo[c] + slack[c] && x[c] <= hi[c] - slack[c])) inside = 0;
        if (inside || rank == 0) {
            for (int c = 0; c < 3; c++)
                out[c] = fmin(fmax(x[c], lo[c] + slack[c]), hi[c] - slack[c]);
            return rank;
        }
    }
    return 0;
}

/* ---- the program field ------------------------------------------------------------ */

typedef struct prog_field {
    const frep_program *p;
    const double *params;
    frep_runtime_error err;   /* merged from the threads' scratches as they are freed */
} prog_field;

/* Merge runtime error e into *acc: counts add, the lowest pc names the error (the
 * rule of frep_eval_par, so the report does not depend on the thread count). */
static void merge_error(frep_runtime_error *acc, const frep_runtime_error *e)
{
    if (e->count == 0) return;
    uint64_t c = acc->count;
    if (c == 0 || e->pc < acc->pc) *acc = *e;
    acc->count = c + e->count;
}

typedef struct prog_thread {
    frep_scratch *s;
    vm_iscratch *is;
    vm_pruner *pr;            /* NULL: the program cannot be pruned */
    frep_program sub;         /* the program pruned for the focused box (own code, pos) */
    uint32_t *orig;           /* sub's pc -> the original pc */
    const frep_program *cur;  /* what eval and grad run: the program or &sub */
    int have_sub;             /* sub is the pruned program for sub_box */
    double sub_box[6], sub_tol;
    frep_runtime_error err;   /* errors raised by sub, with original pcs */
} prog_thread;

static void prog_thread_free(void *ctx, void *ts)
{
    prog_thread *t = ts;
    prog_field *pf = ctx;
    if (!t) return;
    if (t->s) {
        /* thread states are freed one at a time (after the parallel regions) */
        frep_runtime_error e;
        frep_scratch_errors(t->s, &e);
        merge_error(&pf->err, &e);
    }
    merge_error(&pf->err, &t->err);
    frep_scratch_free(t->s);
    vm_iscratch_free(t->is);
    vm_pruner_free(t->pr);
    frep_free(t->sub.code);
    frep_free(t->sub.pos);
    frep_free(t->orig);
    frep_free(t);
}

static void *prog_thread_new(void *ctx)
{
    prog_field *pf = ctx;
    prog_thread *t = frep_calloc(1, sizeof *t);
    if (!t) return NULL;
    t->s = frep_scratch_new(pf->p);
    t->is = vm_iscratch_new(pf->p);
    t->cur = pf->p;
    if (!t->s || !t->is) {
        prog_thread_free(ctx, t);
        return NULL;
    }
    t->pr = vm_pruner_new(pf->p);
    if (t->pr) {
        size_t n = pf->p->ncode;
        t->sub = *pf->p;
        t->sub.code = frep_malloc(n * sizeof *t->sub.code);
        t->sub.pos = frep_malloc(n * sizeof *t->sub.pos);
        t->orig = frep_malloc(n * sizeof *t->orig);
        if (!t->sub.code || !t->sub.pos || !t->orig) {
            /* pruning is an optimization: go without it */
            vm_pruner_free(t->pr);
            t->pr = NULL;
        }
    }
    return t;
}

/* Errors raised by the pruned program name its pcs: map them to the original's. */
static void prog_harvest_errors(prog_thread *t)
{
    if (t->cur != &t->sub) return;
    frep_runtime_error e;
    frep_scratch_errors(t->s, &e);
    if (e.count == 0) return;
    e.pc = e.pc < t->sub.ncode ? t->orig[e.pc] : 0;
    merge_error(&t->err, &e);
    frep_scratch_reset_errors(t->s);
}

static int prog_eval(void *ctx, void *ts, size_t n, const double *x, const double *y,
                     const double *z, double *f)
{
    prog_field *pf = ctx;
    prog_thread *t = ts;
    int rc = frep_eval(t->cur, t->s, n, x, y, z, pf->params, f);
    prog_harvest_errors(t);
    return rc;
}

static int prog_grad(void *ctx, void *ts, size_t n, const double *x, const double *y,
                     const double *z, double *f, double *gx, double *gy, double *gz)
{
    prog_field *pf = ctx;
    prog_thread *t = ts;
    int rc = frep_eval_grad(t->cur, t->s, n, x, y, z, pf->params, f, gx, gy, gz);
    prog_harvest_errors(t);
    return rc;
}

static int prog_focus(void *ctx, void *ts, const double box[6], double *sign_tol)
{
    prog_field *pf = ctx;
    prog_thread *t = ts;
    t->cur = pf->p;
    if (sign_tol) *sign_tol = 0;
    if (!box || !t->pr) return 0;
    if (!t->have_sub || memcmp(box, t->sub_box, sizeof t->sub_box) != 0) {
        ival r;
        uint32_t n;
        t->have_sub = 0;
        if (vm_prune(t->pr, t->is, box, pf->params, t->sub.code, t->sub.pos, t->orig, &n, &r,
                     &t->sub_tol) != 0)
            return 0;
        t->sub.ncode = n;
        memcpy(t->sub_box, box, sizeof t->sub_box);
        t->have_sub = 1;
    }
    t->cur = &t->sub;
    if (sign_tol) *sign_tol = t->sub_tol;
    return 0;
}

static int prog_interval(void *ctx, void *ts, const double box[6], double *lo, double *hi)
{
    prog_field *pf = ctx;
    prog_thread *t = ts;
    ival r;
    int rc = vm_eval_interval(pf->p, t->is, box, pf->params, &r);
    *lo = r.lo;
    *hi = r.hi;
    return rc;
}

int mesh_field_program(mesh_field *f, const frep_program *p, const double *params)
{
    prog_field *pf = frep_malloc(sizeof *pf);
    if (!pf) return -1;
    pf->p = p;
    pf->params = params;
    memset(&pf->err, 0, sizeof pf->err);
    f->ctx = pf;
    f->thread_new = prog_thread_new;
    f->thread_free = prog_thread_free;
    f->eval = prog_eval;
    f->grad = prog_grad;
    f->interval = prog_interval;
    f->focus = prog_focus;
    return 0;
}

void mesh_field_program_errors(const mesh_field *f, frep_runtime_error *e)
{
    const prog_field *pf = f->ctx;
    *e = pf->err;
}

void mesh_field_program_free(mesh_field *f)
{
    frep_free(f->ctx);
    f->ctx = NULL;
}

void mesh_options_init(mesh_options *o)
{
    memset(o, 0, sizeof *o);
    for (int c = 0; c < 3; c++) {
        o->box[c] = -10;
        o->box[c + 3] = 10;
    }
    o->grid = 30;
    o->iso = 0;
}

/* ---- the mesher ------------------------------------------------------------------- */

/* One block of cells. Valid after process_block: vertex data and the per-cell case
 * and first-vertex index (cases 0 and 255 have no vertex). */
typedef struct mblock {
    uint64_t key;
    int b[3];
    uint32_t nverts;          /* component vertices of the cells */
    /* Faces one sheet crosses twice whose high-side cell is in this block (candidates
     * after process_block, only the confirmed ones after resolve_faces): each has two
     * vertices, one per segment, stored after the nverts cell vertices. */
    uint32_t nfaces;
    uint16_t *fkey;           /* per face: 3 * (local index of the high-side cell) + axis,
                                 ascending */
    uint32_t need;            /* bit (dx+1) + 3(dy+1) + 9(dz+1): neighbours with crossings */
    uint32_t real_crossings, inside_corners, virtual_crossings, nan_points, split_cells;
    size_t vglobal;           /* index of the first vertex in the whole mesh */
    double *vpos, *vnrm;      /* 3 * (nverts + 2 nfaces) each */
    double *vfg;              /* 4 * (...): f - iso and the gradient at each vertex */
    uint8_t *vrank;           /* QEF rank (2: on a sharp edge, 3: a corner; 0 on faces) */
    uint8_t *cs;              /* MESH_BLOCK_CELLS cases */
    uint16_t *vbase;          /* MESH_BLOCK_CELLS first vertex or MESH_NO_VERTEX */
    uint32_t *tri;            /* triangles from the quads this block owns (phase 3) */
    size_t ntri;
    int failed;
} mblock;

typedef struct mesher {
    const mesh_field *f;
    const mesh_options *o;
    cell_table table;
    int g;                    /* cells per axis of the box */
    int G;                    /* padded cells per axis: g + 2 */
    int nb;                   /* blocks per axis */
    double h[3];
    int nthreads;
    void **ts;                /* per-thread field state */
    mblock **blocks;          /* sorted by key */
    size_t nblocks, capblocks;
    size_t bytes;
} mesher;

/* Per-thread buffers for one block. */
typedef struct mwork {
    double cx[MESH_BLOCK_CORNERS], cy[MESH_BLOCK_CORNERS], cz[MESH_BLOCK_CORNERS];
    double cf[MESH_BLOCK_CORNERS];
    uint8_t cin[MESH_BLOCK_CORNERS];
    uint32_t rows[MESH_BLOCK + 1][MESH_BLOCK + 1];  /* [k][j]: bit i is cin of (i, j, k) */
    int32_t eidx[MESH_BLOCK_EDGES];
    double px[MESH_BLOCK_EDGES], py[MESH_BLOCK_EDGES], pz[MESH_BLOCK_EDGES];
    double nx[MESH_BLOCK_EDGES], ny[MESH_BLOCK_EDGES], nz[MESH_BLOCK_EDGES];
    /* root finding: edge crossing index, bracket (t, f - iso) and last moved side */
    int32_t rid[MESH_BLOCK_EDGES];
    double t0[MESH_BLOCK_EDGES], g0[MESH_BLOCK_EDGES], t1[MESH_BLOCK_EDGES],
        g1[MESH_BLOCK_EDGES], tt[MESH_BLOCK_EDGES];
    double ax[MESH_BLOCK_EDGES], ay[MESH_BLOCK_EDGES], az[MESH_BLOCK_EDGES];
    double dx[MESH_BLOCK_EDGES], dy[MESH_BLOCK_EDGES], dz[MESH_BLOCK_EDGES];
    int8_t side[MESH_BLOCK_EDGES];   /* -1, 1: end moved last; 0: none yet; 2: converged */
    int32_t act[MESH_BLOCK_EDGES];   /* crossings evaluated in this step */
    double qx[MESH_BLOCK_EDGES], qy[MESH_BLOCK_EDGES], qz[MESH_BLOCK_EDGES],
        qf[MESH_BLOCK_EDGES], gx[MESH_BLOCK_EDGES], gy[MESH_BLOCK_EDGES],
        gz[MESH_BLOCK_EDGES];
    /* vertices under construction */
    double vx[MESH_BLOCK_VMAX], vy[MESH_BLOCK_VMAX], vz[MESH_BLOCK_VMAX];
    double fnx[MESH_BLOCK_VMAX], fny[MESH_BLOCK_VMAX], fnz[MESH_BLOCK_VMAX];
    double vf[MESH_BLOCK_VMAX], vgx[MESH_BLOCK_VMAX], vgy[MESH_BLOCK_VMAX],
        vgz[MESH_BLOCK_VMAX];
    uint8_t vrank[MESH_BLOCK_VMAX];
    /* face candidates: keys and their two vertices (position, mean crossing normal) */
    uint16_t fkey[3 * MESH_BLOCK_CELLS];
    double sx[6 * MESH_BLOCK_CELLS], sy[6 * MESH_BLOCK_CELLS], sz[6 * MESH_BLOCK_CELLS];
    double snx[6 * MESH_BLOCK_CELLS], sny[6 * MESH_BLOCK_CELLS], snz[6 * MESH_BLOCK_CELLS];
    size_t eval_points, grad_points;  /* work done by this thread, for mesh_stats */
} mwork;

static int corner_index(int i, int j, int k)
{
    return i + (MESH_BLOCK + 1) * (j + (MESH_BLOCK + 1) * k);
}

static int cell_index(int i, int j, int k) { return i + MESH_BLOCK * (j + MESH_BLOCK * k); }

/* World coordinate of padded corner index P along axis c. */
static double corner_coord(const mesher *M, int c, long P)
{
    if (P - 1 == M->g) return M->o->box[c + 3];
    return M->o->box[c] + (double)(P - 1) * M->h[c];
}

static int corner_is_real(const mesher *M, long P) { return P >= 1 && P <= M->G - 1; }

static void unit(double *x, double *y, double *z)
{
    double l = sqrt(*x * *x + *y * *y + *z * *z);
    if (l > 0 && isfinite(l)) {
        *x /= l;
        *y /= l;
        *z /= l;
    } else {
        *x = *y = *z = 0;
    }
}

/* Regula falsi guess for crossing r from its bracket; bisection when the values
 * cannot be used. */
static double root_guess(const mwork *W, int r)
{
    double g0 = W->g0[r], g1 = W->g1[r], t;
    if (isfinite(g0) && isfinite(g1) && g0 != g1)
        t = (W->t0[r] * g1 - W->t1[r] * g0) / (g1 - g0);
    else
        t = 0.5 * (W->t0[r] + W->t1[r]);
    if (!(t >= W->t0[r] && t <= W->t1[r])) t = 0.5 * (W->t0[r] + W->t1[r]);
    return t;
}

/* A face that one surface component of a cell crosses twice (two segments, each
 * cutting off one inside corner) would join that component's vertex to the vertex of
 * the cell across the face twice, once per segment: if the component across the face
 * also crosses it twice, four quads share that mesh edge and the mesh is not
 * 2-manifold there (a tunnel thinner than a cell).  Such a face gets one vertex per
 * segment, between its two crossings, which the quads of the segment's crossing edges
 * take as an extra corner: the two mesh edges become four distinct ones.  Here the
 * candidates: the low faces (s = 0) of cell (i, j, k) that its own component crosses
 * twice; resolve_faces() keeps those whose other side does so too.  Segment 0 is the
 * one cutting off the inside corner with the lower coordinate along the face's first
 * axis.  Returns the new number of candidates. */
static size_t face_candidates(mwork *W, int cs, int dup, int i, int j, int k, size_t nf)
{
    int cell = cell_index(i, j, k);
    for (int a = 0; a < 3; a++) {
        if (!(dup & (1 << (2 * a)))) continue;
        int ax[2];
        edge_other_axes(a, &ax[0], &ax[1]);
        W->fkey[nf] = (uint16_t)(3 * cell + a);
        for (int c = 0; c < 8; c++) {
            if (((c >> a) & 1) || !((cs >> c) & 1)) continue;
            size_t q = 2 * nf + (size_t)((c >> ax[0]) & 1);
            double p[3] = { 0, 0, 0 }, n[3] = { 0, 0, 0 };
            int np = 0;
            for (int t = 0; t < 2; t++) {
                int b = ax[t], lo = c & ~(1 << b);
                int ci = corner_index(i + (lo & 1), j + ((lo >> 1) & 1), k + ((lo >> 2) & 1));
                int id = W->eidx[3 * ci + b];
                if (id < 0) continue;
                p[0] += W->px[id];
                p[1] += W->py[id];
                p[2] += W->pz[id];
                n[0] += W->nx[id];
                n[1] += W->ny[id];
                n[2] += W->nz[id];
                np++;
            }
            if (np == 0) np = 1;
            W->sx[q] = p[0] / np;
            W->sy[q] = p[1] / np;
            W->sz[q] = p[2] / np;
            unit(&n[0], &n[1], &n[2]);
            W->snx[q] = n[0];
            W->sny[q] = n[1];
            W->snz[q] = n[2];
        }
        nf++;
    }
    return nf;
}

/* Evaluate, find crossings and place vertices for one block. Returns 0 or -1 (out of
 * memory or the field failed). */
static int process_block(mesher *M, mwork *W, void *ts, mblock *B)
{
    const mesh_field *f = M->f;
    const double iso = M->o->iso;
    long base[3];
    for (int c = 0; c < 3; c++) base[c] = (long)B->b[c] * MESH_BLOCK;

    /* 0. specialize the field to the block (every evaluation below lies in it) */
    double bb[6], sign_tol = 0;
    int focused = f->focus && iso == 0;
    if (focused) {
        for (int c = 0; c < 3; c++) {
            double slack = 1e-9 * M->h[c];
            bb[c] = M->o->box[c] + (double)(base[c] - 1) * M->h[c] - slack;
            bb[c + 3] = M->o->box[c] + (double)(base[c] + MESH_BLOCK - 1) * M->h[c] + slack;
        }
        if (f->focus(f->ctx, ts, bb, &sign_tol) != 0) return -1;
    }

    double cc[3][MESH_BLOCK + 1];          /* corner coordinates along each axis */
    int creal[3][MESH_BLOCK + 1];          /* ... and whether they are real grid points */
    static const int cstride[3] = { 1, MESH_BLOCK + 1, (MESH_BLOCK + 1) * (MESH_BLOCK + 1) };
    for (int c = 0; c < 3; c++)
        for (int q = 0; q <= MESH_BLOCK; q++) {
            cc[c][q] = corner_coord(M, c, base[c] + q);
            creal[c][q] = corner_is_real(M, base[c] + q);
        }

    /* 1. corner values */
    size_t nreal = 0;
    int32_t *map = W->eidx; /* reused: corner -> position in the batch */
    for (int k = 0; k <= MESH_BLOCK; k++)
        for (int j = 0; j <= MESH_BLOCK; j++)
            for (int i = 0; i <= MESH_BLOCK; i++) {
                int ci = corner_index(i, j, k);
                map[ci] = -1;
                if (creal[0][i] && creal[1][j] && creal[2][k]) {
                    W->cx[nreal] = cc[0][i];
                    W->cy[nreal] = cc[1][j];
                    W->cz[nreal] = cc[2][k];
                    map[ci] = (int32_t)nreal++;
                }
            }
    if (nreal && f->eval(f->ctx, ts, nreal, W->cx, W->cy, W->cz, W->qf) != 0) return -1;
    W->eval_points += nreal;
    if (focused && sign_tol > 0) {
        /* Corners are shared with the neighbouring blocks, which prune differently:
         * values near 0, whose sign rounding may decide, come from the whole program
         * so that all blocks agree. */
        size_t nz = 0;
        for (size_t q = 0; q < nreal; q++)
            if (fabs(W->qf[q]) < sign_tol) {
                W->rid[nz] = (int32_t)q;
                W->qx[nz] = W->cx[q];
                W->qy[nz] = W->cy[q];
                W->qz[nz] = W->cz[q];
                nz++;
            }
        if (nz) {
            if (f->focus(f->ctx, ts, NULL, NULL) != 0 ||
                f->eval(f->ctx, ts, nz, W->qx, W->qy, W->qz, W->tt) != 0 ||
                f->focus(f->ctx, ts, bb, &sign_tol) != 0)
                return -1;
            W->eval_points += nz;
            for (size_t q = 0; q < nz; q++) W->qf[W->rid[q]] = W->tt[q];
        }
    }
    for (int ci = 0; ci < MESH_BLOCK_CORNERS; ci++) {
        if (map[ci] < 0) {
            W->cf[ci] = NAN;
            W->cin[ci] = 0;
        } else {
            double v = W->qf[map[ci]];
            W->cf[ci] = v;
            W->cin[ci] = v >= iso;
            if (isnan(v)) B->nan_points++;
            if (W->cin[ci]) B->inside_corners++;
        }
    }

    /* 2. crossing edges */
    int ncross = 0, nroot = 0;
    memset(W->eidx, 0xFF, sizeof W->eidx);  /* -1: no crossing */
    /* inside corners as bit rows along x, so that crossing edges are found a row of
     * edges at a time (most rows have none) */
    for (int k = 0; k <= MESH_BLOCK; k++)
        for (int j = 0; j <= MESH_BLOCK; j++) {
            unsigned m = 0;
            for (int i = 0; i <= MESH_BLOCK; i++) m |= (unsigned)W->cin[corner_index(i, j, k)] << i;
            W->rows[k][j] = m;
        }
    for (int k = 0; k <= MESH_BLOCK; k++)
        for (int j = 0; j <= MESH_BLOCK; j++)
            for (int a = 0; a < 3; a++) {
                unsigned row = W->rows[k][j], cross;
                if (a == 0) cross = (row ^ (row >> 1)) & ((1u << MESH_BLOCK) - 1);
                else if (a == 1) cross = j < MESH_BLOCK ? row ^ W->rows[k][j + 1] : 0;
                else cross = k < MESH_BLOCK ? row ^ W->rows[k + 1][j] : 0;
                for (int i = 0; cross; i++, cross >>= 1) {
                    if (!(cross & 1)) continue;
                    int ci = corner_index(i, j, k);
                    int q[3] = { i, j, k };
                    int ei = 3 * ci + a;
                    int cj = ci + cstride[a];
                    int id = ncross++;
                    W->eidx[ei] = id;
                    int q2[3] = { i, j, k };
                    q2[a]++;
                    int real0 = creal[0][i] && creal[1][j] && creal[2][k];
                    int real1 = creal[0][q2[0]] && creal[1][q2[1]] && creal[2][q2[2]];
                    double x0 = cc[0][i], y0 = cc[1][j], z0 = cc[2][k];
                    double x1 = cc[0][q2[0]], y1 = cc[1][q2[1]], z1 = cc[2][q2[2]];
                    /* which cells around the edge lie in other blocks (only edges on
                     * the block's faces have such cells) */
                    int o1, o2;
                    edge_other_axes(a, &o1, &o2);
                    int on_face = !(q[o1] > 0 && q[o1] < MESH_BLOCK && q[o2] > 0 &&
                                    q[o2] < MESH_BLOCK);
                    for (int d2 = 0; d2 < 2 && on_face; d2++)
                        for (int d1 = 0; d1 < 2; d1++) {
                            int cell[3] = { i, j, k };
                            cell[o1] -= d1;
                            cell[o2] -= d2;
                            int off[3];
                            for (int c = 0; c < 3; c++)
                                off[c] = cell[c] < 0 ? -1 : (cell[c] >= MESH_BLOCK ? 1 : 0);
                            if (off[0] || off[1] || off[2])
                                B->need |= 1u << ((off[0] + 1) + 3 * (off[1] + 1) + 9 * (off[2] + 1));
                        }
                    if (real0 && real1) {
                        B->real_crossings++;
                        int r = nroot++;
                        W->rid[r] = id;
                        W->ax[r] = x0; W->ay[r] = y0; W->az[r] = z0;
                        W->dx[r] = x1 - x0; W->dy[r] = y1 - y0; W->dz[r] = z1 - z0;
                        W->t0[r] = 0; W->g0[r] = W->cf[ci] - iso;
                        W->t1[r] = 1; W->g1[r] = W->cf[cj] - iso;
                        W->side[r] = 0;
                    } else {
                        /* A cap on the box: the crossing sits on the real (inside)
                         * corner, its normal points out of the box. */
                        B->virtual_crossings++;
                        int in0 = W->cin[ci];
                        W->px[id] = in0 ? x0 : x1;
                        W->py[id] = in0 ? y0 : y1;
                        W->pz[id] = in0 ? z0 : z1;
                        W->nx[id] = W->ny[id] = W->nz[id] = 0;
                        double sg = in0 ? 1.0 : -1.0;
                        if (a == 0) W->nx[id] = sg;
                        else if (a == 1) W->ny[id] = sg;
                        else W->nz[id] = sg;
                    }
                }
            }

    /* 3. root finding on the real crossings (Illinois regula falsi, batched): each
     * step evaluates only the crossings whose bracket is still too wide. */
    for (int r = 0; r < nroot; r++) W->tt[r] = NAN;
    for (int step = 0; step < MESH_ROOT_STEPS && nroot > 0; step++) {
        int na = 0;
        for (int r = 0; r < nroot; r++) {
            if (W->side[r] == 2) continue;
            double t = root_guess(W, r);
            if (W->t1[r] - W->t0[r] <= MESH_ROOT_TOL || W->g0[r] == 0 || W->g1[r] == 0) {
                W->side[r] = 2; /* converged: the final guess below lands here */
                continue;
            }
            W->tt[r] = t;
            W->act[na] = r;
            W->qx[na] = W->ax[r] + t * W->dx[r];
            W->qy[na] = W->ay[r] + t * W->dy[r];
            W->qz[na] = W->az[r] + t * W->dz[r];
            na++;
        }
        if (na == 0) break;
        if (f->eval(f->ctx, ts, (size_t)na, W->qx, W->qy, W->qz, W->qf) != 0) return -1;
        W->eval_points += (size_t)na;
        for (int q = 0; q < na; q++) {
            int r = W->act[q];
            double gv = W->qf[q] - iso;
            int in_t = W->qf[q] >= iso, in_0 = W->g0[r] >= 0;
            if (in_t == in_0) {
                W->t0[r] = W->tt[r];
                W->g0[r] = gv;
                if (W->side[r] == -1) W->g1[r] *= 0.5; /* Illinois: unstick the far end */
                W->side[r] = -1;
            } else {
                W->t1[r] = W->tt[r];
                W->g1[r] = gv;
                if (W->side[r] == 1) W->g0[r] *= 0.5;
                W->side[r] = 1;
            }
            /* close: by the secant slope over the new bracket, the root is within
             * MESH_ROOT_FTOL of the edge */
            if (fabs(gv) * (W->t1[r] - W->t0[r]) <= MESH_ROOT_FTOL * fabs(W->g1[r] - W->g0[r]))
                W->side[r] = 2;
        }
    }
    for (int r = 0; r < nroot; r++) {
        double t = root_guess(W, r);
        int id = W->rid[r];
        W->tt[r] = t;
        W->px[id] = W->qx[r] = W->ax[r] + t * W->dx[r];
        W->py[id] = W->qy[r] = W->ay[r] + t * W->dy[r];
        W->pz[id] = W->qz[r] = W->az[r] + t * W->dz[r];
    }
    if (nroot > 0 &&
        f->grad(f->ctx, ts, (size_t)nroot, W->qx, W->qy, W->qz, W->qf, W->gx, W->gy, W->gz) != 0)
        return -1;
    W->grad_points += (size_t)nroot;
    for (int r = 0; r < nroot; r++) {
        int id = W->rid[r];
        /* One Newton step along the edge from the final point, with the value and
         * gradient evaluated there anyway; kept only inside the bracket (a kink of a
         * CSG field may send it anywhere). */
        double fd = W->gx[r] * W->dx[r] + W->gy[r] * W->dy[r] + W->gz[r] * W->dz[r];
        double tn = fd != 0 ? W->tt[r] - (W->qf[r] - iso) / fd : NAN;
        if (tn >= W->t0[r] && tn <= W->t1[r]) {
            W->px[id] = W->ax[r] + tn * W->dx[r];
            W->py[id] = W->ay[r] + tn * W->dy[r];
            W->pz[id] = W->az[r] + tn * W->dz[r];
        }
        /* inside is f >= iso, so the gradient points inward */
        double nx = -W->gx[r], ny = -W->gy[r], nz = -W->gz[r];
        unit(&nx, &ny, &nz);
        if (nx == 0 && ny == 0 && nz == 0) {
            /* no usable gradient: the edge direction, from inside to outside */
            double s = W->g0[r] >= 0 ? 1.0 : -1.0;
            nx = s * W->dx[r];
            ny = s * W->dy[r];
            nz = s * W->dz[r];
            unit(&nx, &ny, &nz);
        }
        W->nx[id] = nx;
        W->ny[id] = ny;
        W->nz[id] = nz;
    }

    /* 4. one vertex per surface component of each cell */
    size_t nv = 0, nf = 0;
    B->cs = frep_malloc(MESH_BLOCK_CELLS * sizeof *B->cs);
    B->vbase = frep_malloc(MESH_BLOCK_CELLS * sizeof *B->vbase);
    if (!B->cs || !B->vbase) return -1;
    for (int k = 0; k < MESH_BLOCK; k++)
        for (int j = 0; j < MESH_BLOCK; j++)
            for (int i = 0; i < MESH_BLOCK; i++) {
                int cell = cell_index(i, j, k);
                int cs = 0;
                B->vbase[cell] = MESH_NO_VERTEX;
                if (base[0] + i >= M->G || base[1] + j >= M->G || base[2] + k >= M->G) {
                    B->cs[cell] = 0;
                    continue;
                }
                /* corner c = x + 2y + 4z: two bits from each of four rows */
                cs = (int)(((W->rows[k][j] >> i) & 3u) | (((W->rows[k][j + 1] >> i) & 3u) << 2) |
                           (((W->rows[k + 1][j] >> i) & 3u) << 4) |
                           (((W->rows[k + 1][j + 1] >> i) & 3u) << 6));
                B->cs[cell] = (uint8_t)cs;
                int ncyc = M->table.ncycles[cs];
                if (ncyc == 0) continue;
                if (ncyc > 1) B->split_cells++;
                B->vbase[cell] = (uint16_t)nv;
                double lo[3] = { corner_coord(M, 0, base[0] + i), corner_coord(M, 1, base[1] + j),
                                 corner_coord(M, 2, base[2] + k) };
                double hi[3] = { corner_coord(M, 0, base[0] + i + 1),
                                 corner_coord(M, 1, base[1] + j + 1),
                                 corner_coord(M, 2, base[2] + k + 1) };
                for (int cyc = 0; cyc < ncyc; cyc++) {
                    double pts[12][3], nrm[12][3], sn[3] = { 0, 0, 0 };
                    int np = 0;
                    for (int e = 0; e < 12; e++) {
                        if (M->table.cycle[cs][e] != cyc) continue;
                        int s0 = edge_start(e);
                        int ci = corner_index(i + (s0 & 1), j + ((s0 >> 1) & 1), k + ((s0 >> 2) & 1));
                        int id = W->eidx[3 * ci + e / 4];
                        if (id < 0) continue;
                        pts[np][0] = W->px[id];
                        pts[np][1] = W->py[id];
                        pts[np][2] = W->pz[id];
                        nrm[np][0] = W->nx[id];
                        nrm[np][1] = W->ny[id];
                        nrm[np][2] = W->nz[id];
                        for (int c = 0; c < 3; c++) sn[c] += nrm[np][c];
                        np++;
                    }
                    double x[3];
                    int rank = 0;
                    if (np == 0) {
                        for (int c = 0; c < 3; c++) x[c] = 0.5 * (lo[c] + hi[c]);
                    } else {
                        rank = qef_solve(np, (const double(*)[3])pts, (const double(*)[3])nrm, lo,
                                         hi, x);
                    }
                    W->vrank[nv] = (uint8_t)rank;
                    W->vx[nv] = x[0];
                    W->vy[nv] = x[1];
                    W->vz[nv] = x[2];
                    unit(&sn[0], &sn[1], &sn[2]);
                    W->fnx[nv] = sn[0];
                    W->fny[nv] = sn[1];
                    W->fnz[nv] = sn[2];
                    nv++;
                }
                if (M->table.dupface[cs] & 0x15)
                    nf = face_candidates(W, cs, M->table.dupface[cs], i, j, k, nf);
            }
    B->nverts = (uint32_t)nv;
    B->nfaces = (uint32_t)nf;
    if (nv == 0) return focused ? f->focus(f->ctx, ts, NULL, NULL) : 0;
    if (nf) {
        B->fkey = frep_malloc(nf * sizeof *B->fkey);
        if (!B->fkey) return -1;
        memcpy(B->fkey, W->fkey, nf * sizeof *B->fkey);
        for (size_t q = 0; q < 2 * nf; q++) {
            W->vx[nv + q] = W->sx[q];
            W->vy[nv + q] = W->sy[q];
            W->vz[nv + q] = W->sz[q];
            W->fnx[nv + q] = W->snx[q];
            W->fny[nv + q] = W->sny[q];
            W->fnz[nv + q] = W->snz[q];
            W->vrank[nv + q] = 0;
        }
    }
    size_t nall = nv + 2 * nf;
    B->vpos = frep_malloc(3 * nall * sizeof *B->vpos);
    B->vnrm = frep_malloc(3 * nall * sizeof *B->vnrm);
    B->vfg = frep_malloc(4 * nall * sizeof *B->vfg);
    B->vrank = frep_malloc(nall);
    if (!B->vpos || !B->vnrm || !B->vfg || !B->vrank) return -1;
    memcpy(B->vrank, W->vrank, nall);
    if (f->grad(f->ctx, ts, nall, W->vx, W->vy, W->vz, W->vf, W->vgx, W->vgy, W->vgz) != 0)
        return -1;
    W->grad_points += nall;
    for (size_t v = 0; v < nall; v++) {
        B->vpos[3 * v] = W->vx[v];
        B->vpos[3 * v + 1] = W->vy[v];
        B->vpos[3 * v + 2] = W->vz[v];
        B->vfg[4 * v] = W->vf[v] - M->o->iso;
        B->vfg[4 * v + 1] = W->vgx[v];
        B->vfg[4 * v + 2] = W->vgy[v];
        B->vfg[4 * v + 3] = W->vgz[v];
        double nx = -W->vgx[v], ny = -W->vgy[v], nz = -W->vgz[v];
        unit(&nx, &ny, &nz);
        /* on a box cap, or where the gradient says nothing, use the crossings' normals */
        if ((nx == 0 && ny == 0 && nz == 0) || nx * W->fnx[v] + ny * W->fny[v] + nz * W->fnz[v] < 0) {
            nx = W->fnx[v];
            ny = W->fny[v];
            nz = W->fnz[v];
        }
        B->vnrm[3 * v] = nx;
        B->vnrm[3 * v + 1] = ny;
        B->vnrm[3 * v + 2] = nz;
    }
    if (focused && f->focus(f->ctx, ts, NULL, NULL) != 0) return -1;
    return 0;
}

static uint64_t block_key(const mesher *M, long bx, long by, long bz)
{
    return ((uint64_t)bz * (uint64_t)M->nb + (uint64_t)by) * (uint64_t)M->nb + (uint64_t)bx;
}

static mblock *find_block(const mesher *M, uint64_t key)
{
    size_t lo = 0, hi = M->nblocks;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (M->blocks[mid]->key < key) lo = mid + 1;
        else hi = mid;
    }
    return lo < M->nblocks && M->blocks[lo]->key == key ? M->blocks[lo] : NULL;
}

static int cmp_block(const void *a, const void *b)
{
    const mblock *x = *(mblock *const *)a, *y = *(mblock *const *)b;
    return x->key < y->key ? -1 : x->key > y->key;
}

static void free_block(mblock *B)
{
    if (!B) return;
    frep_free(B->vpos);
    frep_free(B->vnrm);
    frep_free(B->vfg);
    frep_free(B->vrank);
    frep_free(B->fkey);
    frep_free(B->cs);
    frep_free(B->vbase);
    frep_free(B->tri);
    frep_free(B);
}

static mblock *new_block(const mesher *M, long bx, long by, long bz)
{
    mblock *B = frep_calloc(1, sizeof *B);
    if (!B) return NULL;
    B->b[0] = (int)bx;
    B->b[1] = (int)by;
    B->b[2] = (int)bz;
    B->key = block_key(M, bx, by, bz);
    return B;
}

/* What the diagonal choice needs of a quad's vertex. */
typedef struct qcorner {
    const double *pos, *fg;   /* position; f - iso and gradient there */
    int rank;
} qcorner;

/* f - iso at the midpoint of a and b estimated by the cubic Hermite interpolant of the
 * values and gradients at the ends: (fa + fb) / 2 + (ga - gb) . (b - a) / 8. */
static double hermite_mid(const qcorner *a, const qcorner *b)
{
    double d = 0;
    for (int c = 0; c < 3; c++) d += (a->fg[c + 1] - b->fg[c + 1]) * (b->pos[c] - a->pos[c]);
    return 0.5 * (a->fg[0] + b->fg[0]) + d / 8;
}

/* The block holding cell C (global padded index) and the cell's index in it; NULL
 * when the block was not processed. */
static mblock *cell_block(const mesher *M, const long C[3], int *cell)
{
    if (C[0] < 0 || C[1] < 0 || C[2] < 0 || C[0] >= M->G || C[1] >= M->G || C[2] >= M->G)
        return NULL;
    mblock *B = find_block(M, block_key(M, C[0] / MESH_BLOCK, C[1] / MESH_BLOCK, C[2] / MESH_BLOCK));
    if (!B || !B->cs) return NULL;
    *cell = cell_index((int)(C[0] % MESH_BLOCK), (int)(C[1] % MESH_BLOCK), (int)(C[2] % MESH_BLOCK));
    return B;
}

/* The quads of block B only reach cells in B and its 7 lower neighbours: looked up
 * once per block (below[dx + 2 dy + 4 dz] is the block at B - (dx, dy, dz)), not once
 * per cell.  A NULL table falls back to the search. */
typedef struct nbhood {
    const mblock *B;
    mblock *below[8];
} nbhood;

static void nbhood_init(const mesher *M, mblock *B, nbhood *h)
{
    h->B = B;
    for (int c = 0; c < 8; c++) {
        long bx = B->b[0] - (c & 1), by = B->b[1] - ((c >> 1) & 1), bz = B->b[2] - (c >> 2);
        h->below[c] = bx < 0 || by < 0 || bz < 0 ? NULL : find_block(M, block_key(M, bx, by, bz));
    }
}

static mblock *cell_block_nb(const mesher *M, const nbhood *h, const long C[3], int *cell)
{
    if (!h) return cell_block(M, C, cell);
    if (C[0] < 0 || C[1] < 0 || C[2] < 0 || C[0] >= M->G || C[1] >= M->G || C[2] >= M->G)
        return NULL;
    long d[3];
    for (int c = 0; c < 3; c++) {
        d[c] = h->B->b[c] - C[c] / MESH_BLOCK;
        if (d[c] < 0 || d[c] > 1) return cell_block(M, C, cell);
    }
    mblock *B = h->below[d[0] + 2 * d[1] + 4 * d[2]];
    if (!B || !B->cs) return NULL;
    *cell = cell_index((int)(C[0] % MESH_BLOCK), (int)(C[1] % MESH_BLOCK), (int)(C[2] % MESH_BLOCK));
    return B;
}

/* Cell C (global padded index) -> vertex of the component containing edge e, and the
 * cell's case. */
static int cell_vertex(const mesher *M, const nbhood *h, const long C[3], int e, uint32_t *v,
                       qcorner *q, int *cs)
{
    int cell;
    mblock *B = cell_block_nb(M, h, C, &cell);
    if (!B || B->vbase[cell] == MESH_NO_VERTEX) return -1;
    *cs = B->cs[cell];
    uint8_t cyc = M->table.cycle[B->cs[cell]][e];
    if (cyc == 0xFF) return -1;
    uint32_t local = (uint32_t)B->vbase[cell] + cyc;
    *v = (uint32_t)(B->vglobal + local);
    q->pos = &B->vpos[3 * local];
    q->fg = &B->vfg[4 * local];
    q->rank = B->vrank[local];
    return 0;
}

static double tri_area2(const double *a, const double *b, const double *c)
{
    double u[3], w[3];
    for (int i = 0; i < 3; i++) {
        u[i] = b[i] - a[i];
        w[i] = c[i] - a[i];
    }
    double x = u[1] * w[2] - u[2] * w[1], y = u[2] * w[0] - u[0] * w[2],
           z = u[0] * w[1] - u[1] * w[0];
    return sqrt(x * x + y * y + z * z);
}

/* Make room for at least 8 more triangles in *tri (capacity *cap triangles). On failure
 * frees *tri. */
static int grow_tris(mblock *B, uint32_t **tri, size_t *cap)
{
    (void)B;
    size_t nc = *cap + *cap / 2 + 16;
    uint32_t *nt = frep_realloc(*tri, 3 * nc * sizeof *nt);
    if (!nt) {
        frep_free(*tri);
        *tri = NULL;
        return -1;
    }
    *tri = nt;
    *cap = nc;
    return 0;
}

/* Global index of the vertex of segment seg on the face across axis ax below cell C
 * (the face's high-side cell), or -1 when resolve_faces() did not confirm it. */
static int face_vertex(const mesher *M, const nbhood *h, const long C[3], int ax, int seg)
{
    int cell;
    mblock *B = cell_block_nb(M, h, C, &cell);
    if (!B || seg < 0 || seg > 1) return -1;
    uint16_t key = (uint16_t)(3 * cell + ax);
    size_t lo = 0, hi = B->nfaces;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (B->fkey[mid] < key) lo = mid + 1;
        else hi = mid;
    }
    if (lo == B->nfaces || B->fkey[lo] != key) return -1;
    return (int)(B->vglobal + B->nverts + 2 * lo + (size_t)seg);
}

/* Triangles of polygon p[0..n-1] (ring order, reversed when flip), where mid[t] marks
 * the face vertices: fanned from the first face vertex, so every new diagonal ends at
 * a vertex only the two polygons of one face segment share and no mesh edge is made
 * twice.  Returns 0 or -1 (out of memory; *tri freed). */
static int quad_fan(mblock *B, uint32_t **tri, size_t *cap, size_t *nt, const uint32_t *p,
                    const uint8_t *mid, int n, int flip)
{
    uint32_t r[8];
    int s = -1;
    for (int t = 0; t < n; t++) {
        int from = flip ? (n - t) % n : t;
        r[t] = p[from];
        if (mid[from] && s < 0) s = t;
    }
    if (s < 0) s = 0;
    if (*nt + 8 > *cap && grow_tris(B, tri, cap) != 0) return -1;
    for (int t = 1; t + 1 < n; t++) {
        uint32_t *o = &(*tri)[3 * (*nt)++];
        o[0] = r[s];
        o[1] = r[(s + t) % n];
        o[2] = r[(s + t + 1) % n];
    }
    return 0;
}

/* Quads of the crossing edges whose owner cell (the cell at the edge's lower corner)
 * lies in block B, each split into two triangles.  The diagonal: the one joining two
 * feature vertices (QEF rank >= 2) when only one does, since it lies on the sharp edge;
 * otherwise the one whose midpoint is closer to the surface by the Hermite estimate
 * from the vertices' values and gradients (no extra evaluations); never a split that
 * makes a zero-area triangle. */
static int block_quads(mesher *M, mblock *B)
{
    size_t cap = 0, nt = 0;
    uint32_t *tri = NULL;
    /* two triangles per crossing edge owned (more only for the rare polygons): sized
     * up front, as over-allocation here was a good part of the peak memory */
    for (int cell = 0; cell < MESH_BLOCK_CELLS; cell++) {
        int cs = B->cs[cell];
        cap += (size_t)(((cs ^ (cs >> 1)) & 1) + ((cs ^ (cs >> 2)) & 1) + ((cs ^ (cs >> 4)) & 1));
    }
    cap *= 2;
    if (cap == 0) {
        B->ntri = 0;
        B->tri = NULL;
        return 0;
    }
    tri = frep_malloc(3 * cap * sizeof *tri);
    if (!tri) return -1;
    nbhood nh;
    nbhood_init(M, B, &nh);
    long base[3];
    for (int c = 0; c < 3; c++) base[c] = (long)B->b[c] * MESH_BLOCK;
    for (int k = 0; k < MESH_BLOCK; k++)
        for (int j = 0; j < MESH_BLOCK; j++)
            for (int i = 0; i < MESH_BLOCK; i++) {
                int cell = cell_index(i, j, k);
                int cs = B->cs[cell];
                if (cs == 0 || cs == 255) continue;
                const int L[3] = { i, j, k };
                for (int a = 0; a < 3; a++) {
                    int in0 = cs & 1, in1 = (cs >> (1 << a)) & 1;
                    if (in0 == in1) continue;
                    int o1, o2;
                    edge_other_axes(a, &o1, &o2);
                    /* (d1, d2) counter-clockwise around +a when (o1, o2, a) is right-handed */
                    static const int ring[4][2] = { { 1, 1 }, { 0, 1 }, { 0, 0 }, { 1, 0 } };
                    uint32_t v[4];
                    qcorner q[4];
                    int okq = 1, csr[4];
                    long C[4][3];
                    for (int r = 0; r < 4 && okq; r++) {
                        C[r][0] = base[0] + i;
                        C[r][1] = base[1] + j;
                        C[r][2] = base[2] + k;
                        C[r][o1] -= ring[r][0];
                        C[r][o2] -= ring[r][1];
                        int e = 4 * a + ring[r][0] + 2 * ring[r][1];
                        if (cell_vertex(M, &nh, C[r], e, &v[r], &q[r], &csr[r]) != 0) okq = 0;
                    }
                    if (!okq) {
                        B->failed = 1;
                        continue;
                    }
                    /* (o1, o2, a) is right-handed except for a == 1 (x, z, y); the quad
                     * must face away from the inside end of the edge. */
                    int flip = (a == 1) ^ (in0 == 0);
                    /* faces crossed twice on both sides get a vertex per segment
                     * (face_candidates): then the quad is a polygon, fanned out */
                    uint32_t poly[8];
                    uint8_t pmid[8];
                    int npoly = 0, nmid = 0;
                    for (int r = 0; r < 4; r++) {
                        pmid[npoly] = 0;
                        poly[npoly++] = v[r];
                        int r2 = (r + 1) & 3, ax = C[r][o1] != C[r2][o1] ? o1 : o2;
                        int hi = C[r][ax] > C[r2][ax] ? r : r2, lo = hi == r ? r2 : r;
                        if (!((M->table.dupface[csr[lo]] >> (2 * ax + 1)) & 1) ||
                            !((M->table.dupface[csr[hi]] >> (2 * ax)) & 1))
                            continue;
                        int u = a < 3 - a - ax ? a : 3 - a - ax;
                        long pin = base[u] + L[u] + (u == a ? !in0 : 0);
                        int mv = face_vertex(M, &nh, C[hi], ax, (int)(pin - C[hi][u]));
                        if (mv < 0) {
                            B->failed = 1;
                            continue;
                        }
                        pmid[npoly] = 1;
                        poly[npoly++] = (uint32_t)mv;
                        nmid++;
                    }
                    if (nmid) {
                        if (quad_fan(B, &tri, &cap, &nt, poly, pmid, npoly, flip) != 0) return -1;
                        continue;
                    }
                    if (flip) {
                        uint32_t t = v[1]; v[1] = v[3]; v[3] = t;
                        qcorner tq = q[1]; q[1] = q[3]; q[3] = tq;
                    }
                    int f02 = q[0].rank >= 2 && q[2].rank >= 2;
                    int f13 = q[1].rank >= 2 && q[3].rank >= 2;
                    int use02;
                    if (f02 != f13) {
                        use02 = f02;
                    } else {
                        double e02 = fabs(hermite_mid(&q[0], &q[2]));
                        double e13 = fabs(hermite_mid(&q[1], &q[3]));
                        use02 = !(e13 < e02) || isnan(e13);
                        if (isnan(e02) && !isnan(e13)) use02 = 0;
                    }
                    double a02 = fmin(tri_area2(q[0].pos, q[1].pos, q[2].pos),
                                      tri_area2(q[0].pos, q[2].pos, q[3].pos));
                    double a13 = fmin(tri_area2(q[0].pos, q[1].pos, q[3].pos),
                                      tri_area2(q[1].pos, q[2].pos, q[3].pos));
                    double amax = fmax(a02, a13);
                    if (use02 && a02 <= 1e-9 * amax) use02 = 0;
                    else if (!use02 && a13 <= 1e-9 * amax) use02 = 1;
                    if (nt + 2 > cap && grow_tris(B, &tri, &cap) != 0) return -1;
                    uint32_t *t = &tri[3 * nt];
                    nt += 2;
                    if (use02) {
                        t[0] = v[0]; t[1] = v[1]; t[2] = v[2];
                        t[3] = v[0]; t[4] = v[2]; t[5] = v[3];
                    } else {
                        t[0] = v[0]; t[1] = v[1]; t[2] = v[3];
                        t[3] = v[1]; t[4] = v[2]; t[5] = v[3];
                    }
                }
            }
    B->ntri = nt;
    B->tri = tri;
    return 0;
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int thread_num(void)
{
#ifdef _OPENMP
    return omp_get_thread_num();
#else
    return 0;
#endif
}

/* Keep the face candidates of face_candidates() whose cell across the face has its
 * component cross the face twice as well (only then would the mesh edge be made four
 * times), dropping the other candidates' vertices.  Serial and in block order: the
 * vertex numbering stays independent of the thread count. */
static void resolve_faces(mesher *M)
{
    for (size_t b = 0; b < M->nblocks; b++) {
        mblock *B = M->blocks[b];
        uint32_t keep = 0;
        for (uint32_t q = 0; q < B->nfaces; q++) {
            int cell = B->fkey[q] / 3, a = B->fkey[q] % 3, ocell;
            long C[3] = { (long)B->b[0] * MESH_BLOCK + cell % MESH_BLOCK,
                          (long)B->b[1] * MESH_BLOCK + (cell / MESH_BLOCK) % MESH_BLOCK,
                          (long)B->b[2] * MESH_BLOCK + cell / (MESH_BLOCK * MESH_BLOCK) };
            C[a]--;
            const mblock *O = cell_block(M, C, &ocell);
            if (!O || !((M->table.dupface[O->cs[ocell]] >> (2 * a + 1)) & 1)) continue;
            if (keep != q) {
                size_t from = B->nverts + 2 * (size_t)q, to = B->nverts + 2 * (size_t)keep;
                memmove(&B->vpos[3 * to], &B->vpos[3 * from], 6 * sizeof *B->vpos);
                memmove(&B->vnrm[3 * to], &B->vnrm[3 * from], 6 * sizeof *B->vnrm);
                memmove(&B->vfg[4 * to], &B->vfg[4 * from], 8 * sizeof *B->vfg);
                memmove(&B->vrank[to], &B->vrank[from], 2);
                B->fkey[keep] = B->fkey[q];
            }
            keep++;
        }
        B->nfaces = keep;
    }
}

typedef struct onode {
    int x, y, z, s;
} onode;

/* Octree over blocks: returns the sorted blocks whose cells the interval test cannot
 * prove all outside or all inside. */
static int find_blocks(mesher *M, mesh_stats *st, char *err, size_t errlen)
{
    int S = 1;
    while (S < M->nb) S *= 2;
    onode *cur = frep_malloc(sizeof *cur), *next = NULL;
    size_t ncur = 1;
    if (!cur) goto oom;
    cur[0].x = cur[0].y = cur[0].z = 0;
    cur[0].s = S;
    while (ncur > 0) {
        uint8_t *keep = frep_malloc(ncur);
        if (!keep) goto oom;
        st->octree_nodes += ncur;
        long n = (long)ncur;
#pragma omp parallel for schedule(dynamic, 8) num_threads(M->nthreads)
        for (long i = 0; i < n; i++) {
            const onode *nd = &cur[i];
            long c0[3] = { (long)nd->x * MESH_BLOCK, (long)nd->y * MESH_BLOCK, (long)nd->z * MESH_BLOCK };
            long c1[3];
            int pad = 0;
            double box[6];
            for (int c = 0; c < 3; c++) {
                c1[c] = c0[c] + (long)nd->s * MESH_BLOCK;
                if (c1[c] > M->G) c1[c] = M->G;
                if (c0[c] == 0 || c1[c] == M->G) pad = 1;
                box[c] = M->o->box[c] + (double)(c0[c] - 1) * M->h[c];
                box[c + 3] = M->o->box[c] + (double)(c1[c] - 1) * M->h[c];
            }
            keep[i] = 1;
            if (M->f->interval) {
                double lo = -INFINITY, hi = INFINITY;
                if (M->f->interval(M->f->ctx, M->ts[thread_num()], box, &lo, &hi) == 0) {
                    if (hi < M->o->iso) keep[i] = 0;
                    else if (lo >= M->o->iso && !pad) keep[i] = 0;
                }
            }
        }
        size_t nnext = 0, capn = 0;
        next = NULL;
        for (size_t i = 0; i < ncur; i++) {
            if (!keep[i]) continue;
            const onode *nd = &cur[i];
            if (nd->s == 1) {
                if (M->nblocks == M->capblocks) {
                    M->capblocks = M->capblocks ? 2 * M->capblocks : 1024;
                    mblock **nbk = frep_realloc(M->blocks, M->capblocks * sizeof *nbk);
                    if (!nbk) { frep_free(keep); goto oom; }
                    M->blocks = nbk;
                }
                mblock *B = new_block(M, nd->x, nd->y, nd->z);
                if (!B) { frep_free(keep); goto oom; }
                M->blocks[M->nblocks++] = B;
                continue;
            }
            int hs = nd->s / 2;
            for (int c = 0; c < 8; c++) {
                onode ch = { nd->x + (c & 1) * hs, nd->y + ((c >> 1) & 1) * hs,
                             nd->z + ((c >> 2) & 1) * hs, hs };
                if (ch.x >= M->nb || ch.y >= M->nb || ch.z >= M->nb) continue;
                if (nnext == capn) {
                    capn = capn ? 2 * capn : 64;
                    onode *nn = frep_realloc(next, capn * sizeof *nn);
                    if (!nn) { frep_free(keep); goto oom; }
                    next = nn;
                }
                next[nnext++] = ch;
            }
        }
        frep_free(keep);
        frep_free(cur);
        cur = next;
        next = NULL;
        ncur = nnext;
    }
    frep_free(cur);
    if (M->nblocks > 1) qsort(M->blocks, M->nblocks, sizeof *M->blocks, cmp_block);
    return 0;
oom:
    frep_free(cur);
    frep_free(next);
    snprintf(err, errlen, "out of memory building the octree");
    return -1;
}

int mesh_polygonize(const mesh_field *f, const mesh_options *o, frep_mesh *out,
                    mesh_stats *stats, char *err, size_t errlen)
{
    double t_start = now_seconds();
    mesh_stats st_local;
    mesh_stats *st = stats ? stats : &st_local;
    memset(st, 0, sizeof *st);
    memset(out, 0, sizeof *out);
    if (o->grid < 1 || o->grid > MESH_MAX_GRID) {
        snprintf(err, errlen, "grid of %d cells per axis is outside 1..%d", o->grid, MESH_MAX_GRID);
        return -1;
    }
    for (int c = 0; c < 3; c++) {
        if (!isfinite(o->box[c]) || !isfinite(o->box[c + 3]) || !(o->box[c + 3] > o->box[c])) {
            snprintf(err, errlen, "empty or invalid box: %c from %g to %g", "xyz"[c], o->box[c],
                     o->box[c + 3]);
            return -1;
        }
    }
    if (!isfinite(o->iso)) {
        snprintf(err, errlen, "the iso level must be a finite number");
        return -1;
    }
    mesher *M = frep_calloc(1, sizeof *M);
    if (!M) {
        snprintf(err, errlen, "out of memory");
        return -1;
    }
    int status = -1;
    mwork **works = NULL;
    M->f = f;
    M->o = o;
    build_table(&M->table);
    M->g = o->grid;
    M->G = o->grid + 2;
    M->nb = (M->G + MESH_BLOCK - 1) / MESH_BLOCK;
    for (int c = 0; c < 3; c++) M->h[c] = (o->box[c + 3] - o->box[c]) / o->grid;
#ifdef _OPENMP
    M->nthreads = o->nthreads > 0 ? o->nthreads : omp_get_max_threads();
#else
    M->nthreads = 1;
#endif
    st->blocks_total = (size_t)M->nb * (size_t)M->nb * (size_t)M->nb;
    M->ts = frep_calloc((size_t)M->nthreads, sizeof *M->ts);
    works = frep_calloc((size_t)M->nthreads, sizeof *works);
    if (!M->ts || !works) goto oom;
    for (int t = 0; t < M->nthreads; t++) {
        M->ts[t] = f->thread_new(f->ctx);
        works[t] = frep_malloc(sizeof **works);
        if (!M->ts[t] || !works[t]) goto oom;
        works[t]->eval_points = works[t]->grad_points = 0;
    }
    if (find_blocks(M, st, err, errlen) != 0) goto done;

    /* Process blocks; blocks found to have crossings towards a block not yet visited
     * (the interval test is sound, but NaN and rounding are not its business) bring
     * that block in, until the surface is closed. */
    size_t first = 0, done_blocks = 0;
    while (first < M->nblocks) {
        long n = (long)(M->nblocks - first);
        int failed = 0;
        mblock **todo = M->blocks + first;
#pragma omp parallel for schedule(dynamic, 1) num_threads(M->nthreads)
        for (long i = 0; i < n; i++) {
            int t = thread_num();
            if (process_block(M, works[t], M->ts[t], todo[i]) != 0) {
#pragma omp atomic write
                failed = 1;
            }
            if (t == 0 && o->progress) {
                size_t d;
#pragma omp atomic read
                d = done_blocks;
                o->progress(o->progress_user, 0.9 * (double)d / (double)(M->nblocks + 1));
            }
#pragma omp atomic
            done_blocks++;
        }
        if (failed) {
            snprintf(err, errlen, "out of memory or evaluation failure while meshing");
            goto done;
        }
        size_t old = M->nblocks;
        for (size_t i = first; i < old; i++) {
            M->bytes += sizeof(mblock) + MESH_BLOCK_CELLS * 3 + 48 * (size_t)M->blocks[i]->nverts;
        }
        if (M->bytes > MESH_MAX_WORK_BYTES) {
            snprintf(err, errlen, "the mesh needs more than %zu MiB of working memory; use a "
                     "smaller -g", MESH_MAX_WORK_BYTES >> 20);
            goto done;
        }
        /* blocks [0, old) are processed: sort them for lookups; new ones go after */
        if (old > 1) qsort(M->blocks, old, sizeof *M->blocks, cmp_block);
        size_t nsorted = old;
        for (size_t i = first; i < old; i++) {
            mblock *B = M->blocks[i];
            for (int bit = 0; bit < 27; bit++) {
                if (!(B->need & (1u << bit))) continue;
                long nx = B->b[0] + bit % 3 - 1, ny = B->b[1] + (bit / 3) % 3 - 1,
                     nz = B->b[2] + bit / 9 - 1;
                if (nx < 0 || ny < 0 || nz < 0 || nx >= M->nb || ny >= M->nb || nz >= M->nb)
                    continue;
                uint64_t key = block_key(M, nx, ny, nz);
                size_t save = M->nblocks;
                M->nblocks = nsorted;
                mblock *have = find_block(M, key);
                M->nblocks = save;
                if (have) continue;
                int dup = 0;
                for (size_t q = old; q < M->nblocks; q++)
                    if (M->blocks[q]->key == key) { dup = 1; break; }
                if (dup) continue;
                if (M->nblocks == M->capblocks) {
                    M->capblocks *= 2;
                    mblock **nbk = frep_realloc(M->blocks, M->capblocks * sizeof *nbk);
                    if (!nbk) goto oom;
                    M->blocks = nbk;
                }
                mblock *NB = new_block(M, nx, ny, nz);
                if (!NB) goto oom;
                M->blocks[M->nblocks++] = NB;
            }
        }
        first = old;
    }
    if (M->nblocks > 1) qsort(M->blocks, M->nblocks, sizeof *M->blocks, cmp_block);
    st->blocks = M->nblocks;
    resolve_faces(M);

    /* drop blocks without vertices, number the vertices */
    size_t nkeep = 0, nverts = 0;
    uint32_t inside = 0, real_cross = 0;
    for (size_t i = 0; i < M->nblocks; i++) {
        mblock *B = M->blocks[i];
        st->points_nan += B->nan_points;
        st->cells_split += B->split_cells;
        inside += B->inside_corners > 0;
        real_cross += B->real_crossings > 0;
        if (B->virtual_crossings) st->touches_box = 1;
        if (B->nverts == 0) {
            free_block(B);
            continue;
        }
        B->vglobal = nverts;
        nverts += B->nverts + 2 * (size_t)B->nfaces;
        st->face_vertices += 2 * (size_t)B->nfaces;
        M->blocks[nkeep++] = B;
    }
    M->nblocks = nkeep;
    st->full = inside > 0 && real_cross == 0;
    if (nverts >= UINT32_MAX) {
        snprintf(err, errlen, "the mesh has more than 2^32 vertices; use a smaller -g");
        goto done;
    }

    /* quads */
    {
        long n = (long)M->nblocks;
        int failed = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(M->nthreads)
        for (long i = 0; i < n; i++) {
            int t = thread_num();
            if (block_quads(M, M->blocks[i]) != 0) {
#pragma omp atomic write
                failed = 1;
            }
            if (t == 0 && o->progress)
                o->progress(o->progress_user, 0.9 + 0.1 * (double)i / (double)(n + 1));
        }
        if (failed) {
            snprintf(err, errlen, "out of memory or evaluation failure while meshing");
            goto done;
        }
    }
    size_t ntris = 0;
    int holes = 0;
    for (size_t i = 0; i < M->nblocks; i++) {
        ntris += M->blocks[i]->ntri;
        holes |= M->blocks[i]->failed;
    }
    if (holes) {
        snprintf(err, errlen, "internal error: a surface cell was not evaluated");
        goto done;
    }
    if (ntris > MESH_MAX_TRIANGLES) {
        snprintf(err, errlen, "the mesh has more than %zu triangles; use a smaller -g",
                 (size_t)MESH_MAX_TRIANGLES);
        goto done;
    }
    out->nverts = nverts;
    out->ntris = ntris;
    out->v = frep_malloc((3 * nverts + 1) * sizeof *out->v);
    out->n = frep_malloc((3 * nverts + 1) * sizeof *out->n);
    out->tri = frep_malloc((3 * ntris + 1) * sizeof *out->tri);
    if (!out->v || !out->n || !out->tri) {
        mesh_free(out);
        goto oom;
    }
    size_t tpos = 0;
    for (size_t i = 0; i < M->nblocks; i++) {
        mblock *B = M->blocks[i];
        /* empty blocks may hold NULL arrays: memcpy from NULL is undefined even for 0 */
        if (B->nverts) {
            size_t nall = B->nverts + 2 * (size_t)B->nfaces;
            memcpy(out->v + 3 * B->vglobal, B->vpos, 3 * nall * sizeof *out->v);
            memcpy(out->n + 3 * B->vglobal, B->vnrm, 3 * nall * sizeof *out->n);
        }
        if (B->ntri) memcpy(out->tri + 3 * tpos, B->tri, 3 * B->ntri * sizeof *out->tri);
        tpos += B->ntri;
    }
    if (o->progress) o->progress(o->progress_user, 1.0);
    status = 0;
    goto done;
oom:
    snprintf(err, errlen, "out of memory");
done:
    if (M->blocks)
        for (size_t i = 0; i < M->nblocks; i++) free_block(M->blocks[i]);
    frep_free(M->blocks);
    if (M->ts)
        for (int t = 0; t < M->nthreads; t++)
            if (M->ts[t]) f->thread_free(f->ctx, M->ts[t]);
    frep_free(M->ts);
    if (works)
        for (int t = 0; t < M->nthreads; t++) {
            if (works[t]) {
                st->eval_points += works[t]->eval_points;
                st->grad_points += works[t]->grad_points;
            }
            frep_free(works[t]);
        }
    frep_free(works);
    frep_free(M);
    st->seconds = now_seconds() - t_start;
    return status;
}

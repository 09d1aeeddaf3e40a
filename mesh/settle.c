/* settle.c - the last step of the polygonizer (step 6 of doc/mesh.md): cell vertices
 * the blocks left farther than MESH_SETTLE_TOL cells from the surface are moved onto
 * it, once the triangles exist, where their fan does not fold.
 *
 * mesh.c projects far vertices inside each block, but not where that could fold the
 * quads over their neighbours' (cells with a corner exactly on the level, cells with
 * several components), and its clamped Newton steps stop on a cell face when the
 * gradient leans out of the cell (the R-functions' gradients near creases).  Here each
 * such vertex (and each face vertex of quads.c) gets targets on the surface inside its
 * cell (Newton steps, then a bisection towards the cell's corners on the other side of
 * the level), and moves to the nearest one where every triangle of its fan keeps its
 * orientation and meets no triangle nearby.  The vertices no target lets move get a
 * second pass: targets up to half a cell beyond their cell and along 28 directions
 * around them, and triangles allowed to turn up to a right angle; those still left
 * try the corners of their cell that lie on the level.  Targets are
 * computed per vertex; the moves are decided serially in vertex order, so the mesh
 * does not depend on the thread count.
 */
#include "config.h"

#include "alloc.h"
#include "mesh_internal.h"
#include "trimesh.h"
#include "vec3.h"

#include <math.h>
#include <string.h>

/* Vertices farther than this (cells, as mesh_surface_distance measures) are settled:
 * below --check's MESH_SURFACE_TOL, so that a vertex the first-order estimate puts a
 * little over it still gets there. */
#define MESH_SETTLE_TOL 0.08
/* A cell vertex the QEF left at the mass point (rank 0) nearer than MESH_SETTLE_TOL
 * but farther than this is settled (to targets this near) when its fan meets another
 * triangle: beside a box's corner such a vertex stopped 0.035-0.05 cell off a face,
 * where its fan met its neighbours' (tests/models/segment_box.hf at -g 54 and 102,
 * -b 1.2); settling every such vertex moved some that were clean deeper inside. */
#define MESH_SETTLE_TOL_MASS 0.02
/* A vertex already on the surface moved to unfold its fan goes to a point at most
 * this far from it (cells): it must not leave the surface for --check's tolerance. */
#define MESH_SETTLE_FOLD_TOL 0.01
/* Newton steps along the gradient, one batch of gradients each. */
#define MESH_SETTLE_STEPS 4
/* Bisection steps between the vertex and a cell corner across the level: 2^-10 of the
 * segment, far below the tolerance. */
#define MESH_SETTLE_BISECT 10
/* Targets stay this fraction of a cell inside the cell's faces: on the faces, the
 * vertices of neighbouring cells could meet (zero-area or folded triangles). */
#define MESH_SETTLE_MARGIN 0.02
/* A moved triangle must keep this much of its old orientation (cosine between the
 * old and the new normal), and must not turn towards the triangle across one of its
 * outer edges more than that one's normal already did: no new folds. */
#define MESH_SETTLE_TURN 0.2
/* The second pass lets a triangle turn up to a right angle (a sliver along a flat
 * face turns that much when its far vertex reaches the face), still no flip. */
#define MESH_SETTLE_TURN_WIDE 0.0

/* A vertex to settle: its index, its cell (less the margin), where it is and where it
 * may go (position, f - iso, gradient, distance in cells). */
typedef struct svert {
    uint32_t v;
    const mblock *B;          /* its block, whose box the field is focused on */
    double lo[3], hi[3];
    double x[3], f, g[3], d;
    double n[3];              /* the vertex normal: the side the surface must face */
    double x0[3], f0, g0[3], d0;  /* where it is in the mesh */
    int nc;                   /* targets found, cand[SETTLE_MAX_CANDS * k ..], nearest
                                 to x0 first */
    int moved;
    int fold;                 /* on the surface, but a triangle of its fan folds over:
                                 moved only to unfold it */
    double tol;               /* targets this near the surface (cells) */
    int tangled;              /* a mass point under MESH_SETTLE_TOL: moved only when
                                 its fan meets another triangle */
} svert;

/* A target on the surface: position, f - iso, gradient. */
typedef struct scand {
    double x[3], f, g[3];
} scand;

/* A run of the settling: the vertices and one batch of evaluation buffers. */
typedef struct settle_run {
    const mesher *M;
    void *ts;
    svert *sv;
    size_t n;
    /* one batch: SETTLE_BATCH_PER entries per vertex */
    double *bx, *by, *bz, *bf, *bgx, *bgy, *bgz;
    uint32_t *bid;            /* batch entry -> sv index */
    size_t eval_points, grad_points;  /* work done, for mesh_stats */
    double *sa, *sb;          /* bisection: 3 per entry, the ends on the vertex's side
                                 and on the other */
    scand *cand;              /* SETTLE_MAX_CANDS per vertex */
    double turn;              /* MESH_SETTLE_TURN or, in the second pass, _WIDE */
} settle_run;

/* A vertex whose targets in its own cell all fail (its surface lies in the next cell,
 * or every move would fold its fan) looks again this many cells beyond its cell's
 * faces, trying every target found there, nearest first. */
#define MESH_SETTLE_REACH 0.5
/* Targets kept per vertex: the Newton steps' and the bisections' (one per corner). */
#define SETTLE_MAX_CANDS 16
/* The look around a vertex in the second pass: the 26 directions to a cube's
 * neighbours and the two along the gradient (as mesh/distance.c measures), out to
 * these radii (cells); the first point of each direction across the level is bisected
 * against the one before it. */
#define SETTLE_NDIRS 28
#define SETTLE_NRADII 8
static const double settle_radii[SETTLE_NRADII] = { 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.75 };

/* Triangles around one vertex, and around the vertices of its fan, beyond which a
 * vertex is not moved (a dual-contouring vertex has 4 to 12 or so triangles). */
#define SETTLE_MAX_FAN 32
#define SETTLE_MAX_NEAR 256

/* Batch entries per vertex: one per corner of its cell in the bisection. */
#define SETTLE_BATCH_PER 8

/* Meshes of fewer triangles are checked for folds and searched for the vertices to
 * settle on one thread (~10 ns a triangle: 0.6 ms, while starting a helper costs
 * 10-100 us); a thread takes SETTLE_TRI_CHUNK triangles at a time. */
#define SETTLE_PAR_MIN_TRIS 65536
#define SETTLE_TRI_CHUNK 4096

/* The box of the cell holding a vertex at p, less the margin, or 0 when that cell is in
 * the padding layer (on a box cap, not on the surface). */
static int vertex_cell(const mesher *M, const double p[3], double reach, double lo[3],
                       double hi[3])
{
    for (int c = 0; c < 3; c++) {
        double t = (p[c] - M->o->box[c]) / M->h[c];
        long P = (long)floor(t) + 1;
        if (P < 1 || P + 1 >= M->G[c]) return 0;
        double a = mesh_coord(M, c, P), b = mesh_coord(M, c, P + 1);
        if (!(p[c] >= a && p[c] <= b)) return 0;
        double s = (MESH_SETTLE_MARGIN - reach) * (b - a);
        lo[c] = fmax(a + s, mesh_coord(M, c, 1));
        hi[c] = fmin(b - s, mesh_coord(M, c, M->G[c] - 1));
    }
    return 1;
}

/* Box lo..hi lies in block B's box, where the field focused on B is the model's
 * (a vertex on a block face may have its cell in the next block). */
static int inside_block(const mesher *M, const mblock *B, const double lo[3], const double hi[3])
{
    double bb[6];
    mesh_block_box(M, B, bb);
    for (int c = 0; c < 3; c++)
        if (!(lo[c] >= bb[c] && hi[c] <= bb[c + 3])) return 0;
    return 1;
}

/* Vertex l of block B, at x in the mesh, as a vertex to settle into *s: farther than
 * MESH_SETTLE_TOL from the surface, a mass point farther than MESH_SETTLE_TOL_MASS, or
 * a vertex of a folded triangle (folded[]), in a cell of the box.  0: none of them. */
static int far_vertex(const mesher *M, const frep_mesh *out, const uint8_t *folded,
                      const mblock *B, uint32_t l, svert *s)
{
    const double *fg = &B->vfg[4 * l];
    double d = mesh_cell_distance(M, fg[0], fg[1], fg[2], fg[3]);
    uint32_t v = (uint32_t)(B->vglobal + l);
    int tangled = l < B->nverts && B->vrank[l] == 0 && d > MESH_SETTLE_TOL_MASS &&
                  !(d > MESH_SETTLE_TOL);
    double tol = tangled ? MESH_SETTLE_TOL_MASS : MESH_SETTLE_TOL;
    int fold = !(d > tol);
    if (fold && !folded[v]) return 0;
    s->v = v;
    s->fold = fold;
    s->tol = tol;
    s->tangled = tangled;
    s->B = B;
    const double *x = &out->v[3 * (size_t)v];
    if (!vertex_cell(M, x, 0, s->lo, s->hi)) return 0;
    if (fold && !inside_block(M, B, s->lo, s->hi)) return 0;
    memcpy(s->x, x, sizeof s->x);
    s->f = fg[0];
    memcpy(s->g, &fg[1], sizeof s->g);
    s->d = d;
    memcpy(s->n, &out->n[3 * s->v], sizeof s->n);
    memcpy(s->x0, s->x, sizeof s->x);
    memcpy(s->g0, s->g, sizeof s->g);
    s->f0 = s->f;
    s->d0 = d;
    s->nc = 0;
    s->moved = 0;
    return 1;
}

/* Blocks handed to a thread at a time when looking for the vertices to settle. */
#define SETTLE_BLOCK_CHUNK 16

/* The search for the vertices to settle, shared by its threads: a pass that counts
 * each block's (sv NULL; first[b + 1]), then, first[] summed, one that fills sv from
 * first[b] on, so that they come in block order at any thread count. */
typedef struct far_job {
    const mesher *M;
    const frep_mesh *out;
    const uint8_t *folded;
    size_t *first;
    svert *sv;
} far_job;

static void far_chunk(void *ctx, int t, long b0, long b1)
{
    (void)t;
    far_job *J = ctx;
    for (long b = b0; b < b1; b++) {
        const mblock *B = J->M->blocks[b];
        size_t n = 0;
        svert s;      /* a vertex not kept writes here: its place is the next one's */
        for (uint32_t l = 0; l < B->nverts + 2 * B->nfaces; l++) {
            if (!far_vertex(J->M, J->out, J->folded, B, l, &s)) continue;
            if (J->sv) J->sv[J->first[b] + n] = s;
            n++;
        }
        if (!J->sv) J->first[b + 1] = n;
    }
}

/* The blocks' vertices to settle (far_vertex), in vertex order, into r->sv (NULL when
 * there are none), on as many threads as settling's fold check.  0, or -1 when out of
 * memory. */
static int far_vertices(settle_run *r, const frep_mesh *out, const uint8_t *folded)
{
    const mesher *M = r->M;
    long nb = (long)M->nblocks;
    far_job J = { M, out, folded, frep_calloc((size_t)nb + 1, sizeof *J.first), NULL };
    if (!J.first) return -1;
    int nt = out->ntris < SETTLE_PAR_MIN_TRIS ? 1 : M->nthreads;
    frep_par_for(nt, nb, SETTLE_BLOCK_CHUNK, far_chunk, &J);
    for (long b = 0; b < nb; b++) J.first[b + 1] += J.first[b];
    r->n = J.first[nb];
    if (r->n) {
        J.sv = r->sv = frep_malloc(r->n * sizeof *r->sv);
        if (J.sv) frep_par_for(nt, nb, SETTLE_BLOCK_CHUNK, far_chunk, &J);
    }
    frep_free(J.first);
    return r->n && !r->sv ? -1 : 0;
}

/* Values (grad 0) or values and gradients at the batch's first m points, a run of
 * entries of one block at a time, focused on the block's box when the run is long
 * enough (SETTLE_FOCUS_MIN).  0 or FREP_EINPUT. */
static int batch_eval(settle_run *r, size_t m, int grad)
{
    const mesh_field *f = r->M->f;
    int focus = f->focus && r->M->o->iso == 0;
    int rc = 0;
    for (size_t i = 0, j; i < m && rc == 0; i = j) {
        const mblock *B = r->sv[r->bid[i]].B;
        for (j = i + 1; j < m && r->sv[r->bid[j]].B == B; j++) continue;
        if (focus) {
            double bb[6];
            mesh_block_box(r->M, B, bb);
            if (f->focus(f->ctx, r->ts, j - i >= SETTLE_FOCUS_MIN ? bb : NULL, NULL) != 0)
                return FREP_EINPUT;
        }
        size_t n = j - i;
        *(grad ? &r->grad_points : &r->eval_points) += n;
        rc = grad ? f->grad(f->ctx, r->ts, n, r->bx + i, r->by + i, r->bz + i, r->bf + i,
                            r->bgx + i, r->bgy + i, r->bgz + i)
                  : f->eval(f->ctx, r->ts, n, r->bx + i, r->by + i, r->bz + i, r->bf + i);
    }
    if (focus && f->focus(f->ctx, r->ts, NULL, NULL) != 0) return FREP_EINPUT;
    return rc != 0 ? FREP_EINPUT : 0;
}

static int batch_grad(settle_run *r, size_t m) { return batch_eval(r, m, 1); }

/* Batch entry q as vertex s's target when it is closer to the surface and the surface
 * there faces the vertex's way (not another sheet of the cell). */
static void take_if_better(settle_run *r, size_t q, svert *s)
{
    double f = r->bf[q] - r->M->o->iso, g[3] = { r->bgx[q], r->bgy[q], r->bgz[q] };
    double d = mesh_cell_distance(r->M, f, g[0], g[1], g[2]);
    if (!(d < s->d) || !(-vec3_dot(g, s->n) > 0)) return;
    s->x[0] = r->bx[q];
    s->x[1] = r->by[q];
    s->x[2] = r->bz[q];
    s->f = f;
    memcpy(s->g, g, sizeof g);
    s->d = d;
}

/* Target (x, f, g) into vertex s's list (index k), kept sorted by the distance from
 * the vertex; the farthest falls off a full list. */
static double from_vertex2(const svert *s, const double x[3])
{
    double e[3];
    vec3_sub(x, s->x0, e);
    return vec3_dot(e, e);
}

static void add_candidate(settle_run *r, size_t k, const double x[3], double f, const double g[3])
{
    svert *s = &r->sv[k];
    scand *c = &r->cand[SETTLE_MAX_CANDS * k];
    double d2 = from_vertex2(s, x);
    int i = s->nc;
    if (i == SETTLE_MAX_CANDS) {
        if (!(from_vertex2(s, c[i - 1].x) > d2)) return;
        i--;
    } else {
        s->nc++;
    }
    for (; i > 0 && from_vertex2(s, c[i - 1].x) > d2; i--) c[i] = c[i - 1];
    memcpy(c[i].x, x, sizeof c[i].x);
    c[i].f = f;
    memcpy(c[i].g, g, sizeof c[i].g);
}

/* Newton steps x - (f - iso) grad f / |grad f|^2 clamped to the cell, for the vertices
 * still far. */
static int newton_targets(settle_run *r)
{
    for (int step = 0; step < MESH_SETTLE_STEPS; step++) {
        size_t m = 0;
        for (size_t k = 0; k < r->n; k++) {
            svert *s = &r->sv[k];
            double gg = vec3_dot(s->g, s->g);
            if (s->moved || !(s->d > s->tol) || !(gg > 0)) continue;
            double t = s->f / gg, x[3];
            for (int c = 0; c < 3; c++) x[c] = fmin(fmax(s->x[c] - t * s->g[c], s->lo[c]), s->hi[c]);
            r->bx[m] = x[0];
            r->by[m] = x[1];
            r->bz[m] = x[2];
            r->bid[m++] = (uint32_t)k;
        }
        if (m == 0) break;
        int rc = batch_grad(r, m);
        if (rc) return rc;
        for (size_t q = 0; q < m; q++) take_if_better(r, q, &r->sv[r->bid[q]]);
    }
    return 0;
}

/* Bisect the ns segments sa -> sb (sa on the side of the level of vertex bid's
 * original position), then take the midpoints on the surface that face the vertex's
 * way as its targets. */
static int bisect_segments(settle_run *r, size_t ns)
{
    double iso = r->M->o->iso;
    int rc;
    for (int it = 0; it <= MESH_SETTLE_BISECT; it++) {
        for (size_t q = 0; q < ns; q++) {
            r->bx[q] = 0.5 * (r->sa[3 * q] + r->sb[3 * q]);
            r->by[q] = 0.5 * (r->sa[3 * q + 1] + r->sb[3 * q + 1]);
            r->bz[q] = 0.5 * (r->sa[3 * q + 2] + r->sb[3 * q + 2]);
        }
        if (it == MESH_SETTLE_BISECT) break;
        if ((rc = batch_eval(r, ns, 0)) != 0) return rc;
        for (size_t q = 0; q < ns; q++) {
            const svert *s = &r->sv[r->bid[q]];
            double *end = (r->bf[q] >= iso) == (s->f0 >= 0) ? &r->sa[3 * q] : &r->sb[3 * q];
            end[0] = r->bx[q];
            end[1] = r->by[q];
            end[2] = r->bz[q];
        }
    }
    if ((rc = batch_grad(r, ns)) != 0) return rc;
    /* the midpoints on the surface that face the vertex's way are its targets */
    for (size_t q = 0; q < ns; q++) {
        uint32_t k = r->bid[q];
        const svert *s = &r->sv[k];
        double g[3] = { r->bgx[q], r->bgy[q], r->bgz[q] };
        double d = mesh_cell_distance(r->M, r->bf[q] - iso, g[0], g[1], g[2]);
        if (!(d <= (s->fold ? MESH_SETTLE_FOLD_TOL : s->tol)) || !(-vec3_dot(g, s->n) > 0))
            continue;
        double x[3] = { r->bx[q], r->by[q], r->bz[q] };
        add_candidate(r, k, x, r->bf[q] - iso, g);
    }
    return 0;
}

/* The 8 corners of the cell [lo, hi] as batch points m.. of far vertex k; the next m. */
static size_t push_corners(settle_run *r, size_t m, const double lo[3], const double hi[3],
                           size_t k)
{
    for (int c = 0; c < 8; c++) {
        r->bx[m] = (c & 1) ? hi[0] : lo[0];
        r->by[m] = (c & 2) ? hi[1] : lo[1];
        r->bz[m] = (c & 4) ? hi[2] : lo[2];
        r->bid[m++] = (uint32_t)k;
    }
    return m;
}

/* Targets where the segments from the vertex (from Newton's best point) to the
 * corners of its box on the other side of the level cross it: for the vertices still
 * far (all: every vertex not moved yet). */
static int bisect_targets(settle_run *r, int all)
{
    double iso = r->M->o->iso;
    size_t m = 0;
    for (size_t k = 0; k < r->n; k++) {
        const svert *s = &r->sv[k];
        if (s->moved || (!all && !(s->d > s->tol))) continue;
        m = push_corners(r, m, s->lo, s->hi, k);
    }
    if (m == 0) return 0;
    int rc = batch_eval(r, m, 0);
    if (rc) return rc;
    size_t ns = 0;
    for (size_t q = 0; q < m; q++) {
        const svert *s = &r->sv[r->bid[q]];
        if (isnan(r->bf[q]) || (r->bf[q] >= iso) == (s->f0 >= 0)) continue;
        memcpy(&r->sa[3 * ns], s->x, 3 * sizeof *s->x);
        r->sb[3 * ns] = r->bx[q];
        r->sb[3 * ns + 1] = r->by[q];
        r->sb[3 * ns + 2] = r->bz[q];
        r->bid[ns++] = r->bid[q];
    }
    return ns ? bisect_segments(r, ns) : 0;
}

/* The points of the look around vertex s into the batch: SETTLE_NRADII rings of
 * SETTLE_NDIRS, ring by ring. */
static size_t look_points(settle_run *r, const svert *s, uint32_t k)
{
    const double *h = r->M->h;
    double gc[3] = { s->g0[0] * h[0], s->g0[1] * h[1], s->g0[2] * h[2] };
    double gl = vec3_len(gc);
    size_t m = 0;
    for (int ri = 0; ri < SETTLE_NRADII; ri++) {
        double t = settle_radii[ri];
        for (int q = 0; q < SETTLE_NDIRS; q++) {
            double dir[3];
            if (q < 26) {
                int e = q < 13 ? q : q + 1;   /* 0..26 less the centre, 13 */
                dir[0] = e % 3 - 1;
                dir[1] = (e / 3) % 3 - 1;
                dir[2] = e / 9 - 1;
                vec3_normalize(dir);
            } else {
                double sg = q == 26 ? 1 : -1;
                for (int c = 0; c < 3; c++) dir[c] = gl > 0 ? sg * gc[c] / gl : 0;
            }
            r->bx[m] = s->x0[0] + t * dir[0] * h[0];
            r->by[m] = s->x0[1] + t * dir[1] * h[1];
            r->bz[m] = s->x0[2] + t * dir[2] * h[2];
            r->bid[m++] = k;
        }
    }
    return m;
}

/* Targets around each vertex not moved yet: along each direction of the look, the
 * first point across the level bisected against the one before it (the vertex for
 * the first ring). */
static int look_targets(settle_run *r)
{
    double iso = r->M->o->iso;
    for (size_t k = 0; k < r->n; k++) {
        const svert *s = &r->sv[k];
        if (s->moved || s->fold) continue;
        size_t m = look_points(r, s, (uint32_t)k);
        int rc = batch_eval(r, m, 0);
        if (rc) return rc;
        size_t ns = 0;
        for (int q = 0; q < SETTLE_NDIRS; q++)
            for (int ri = 0; ri < SETTLE_NRADII; ri++) {
                size_t i = (size_t)ri * SETTLE_NDIRS + (size_t)q;
                if (isnan(r->bf[i])) break;
                if ((r->bf[i] >= iso) == (s->f0 >= 0)) continue;
                const double *a = s->x0;
                double pa[3];
                if (ri > 0) {
                    size_t j = i - SETTLE_NDIRS;
                    pa[0] = r->bx[j];
                    pa[1] = r->by[j];
                    pa[2] = r->bz[j];
                    a = pa;
                }
                memcpy(&r->sa[3 * ns], a, 3 * sizeof *a);
                r->sb[3 * ns] = r->bx[i];
                r->sb[3 * ns + 1] = r->by[i];
                r->sb[3 * ns + 2] = r->bz[i];
                ns++;
                break;
            }
        for (size_t q = 0; q < ns; q++) r->bid[q] = (uint32_t)k;
        if (ns && (rc = bisect_segments(r, ns)) != 0) return rc;
    }
    return 0;
}

/* Targets at the corners of each far vertex's cell that lie exactly on the level,
 * MESH_SETTLE_MARGIN inside the cell, for the vertices both passes left.  Parts whose
 * faces lie on grid planes leave cells between them whose corners are on the level or
 * outside: the QEF of the crossings at those corners (the parts' edges, with a kink's
 * normal) finds a phantom crease off the surface, and no target of Newton's steps or
 * the bisections lets its fan keep its orientation; a corner on a part's edge does
 * (tests/models/sharp/near.hf at -g 24, -b 1.2: 4 vertices 0.3 cell off between a
 * block's edge and the wall's).  A pass of its own: as targets of the second pass,
 * nearer than those some vertices took there, they left a neighbour taken later
 * without a move (tests/models/sharp/holes.hf at -g 24: a vertex 2 cells off). */
static int level_corner_targets(settle_run *r)
{
    double iso = r->M->o->iso;
    size_t m = 0;
    for (size_t k = 0; k < r->n; k++) {
        const svert *s = &r->sv[k];
        double lo[3], hi[3];
        if (s->moved || s->fold || !vertex_cell(r->M, s->x0, MESH_SETTLE_MARGIN, lo, hi) ||
            !inside_block(r->M, s->B, lo, hi))
            continue;
        m = push_corners(r, m, lo, hi, k);
    }
    if (m == 0) return 0;
    int rc = batch_eval(r, m, 0);
    if (rc) return rc;
    size_t ns = 0;
    for (size_t q = 0; q < m; q++) {
        if (r->bf[q] != iso) continue;
        const svert *s = &r->sv[r->bid[q]];
        double lo[3], hi[3];
        vertex_cell(r->M, s->x0, 0, lo, hi);
        double x[3] = { r->bx[q], r->by[q], r->bz[q] };
        for (int c = 0; c < 3; c++) x[c] = fmin(fmax(x[c], lo[c]), hi[c]);
        r->bx[ns] = x[0];
        r->by[ns] = x[1];
        r->bz[ns] = x[2];
        r->bid[ns++] = r->bid[q];
    }
    if (ns == 0) return 0;
    if ((rc = batch_grad(r, ns)) != 0) return rc;
    for (size_t q = 0; q < ns; q++) {
        uint32_t k = r->bid[q];
        const svert *s = &r->sv[k];
        double g[3] = { r->bgx[q], r->bgy[q], r->bgz[q] };
        double d = mesh_cell_distance(r->M, r->bf[q] - iso, g[0], g[1], g[2]);
        if (!(d <= s->tol) || !(-vec3_dot(g, s->n) > 0)) continue;
        double x[3] = { r->bx[q], r->by[q], r->bz[q] };
        add_candidate(r, k, x, r->bf[q] - iso, g);
    }
    return 0;
}

/* The targets of the vertices not moved yet: Newton's, then (all: for every such
 * vertex, else only where Newton's steps did not get there) the bisections'. */
static int find_targets(settle_run *r, int all)
{
    int rc = newton_targets(r);
    if (rc) return rc;
    for (size_t k = 0; k < r->n; k++) {
        const svert *s = &r->sv[k];
        if (!s->moved && !s->fold && s->d <= s->tol) add_candidate(r, k, s->x, s->f, s->g);
    }
    return bisect_targets(r, all);
}

/* ---- the moves -------------------------------------------------------------------- */

/* The triangles around the far vertices and around their neighbours: vertex w of
 * ids[0..nids-1] (the far vertices first, as r->sv) has triangles
 * list[start[i] .. start[i + 1] - 1]. */
typedef struct fan_index {
    uint32_t *map;            /* vertex -> its place in ids, or UINT32_MAX */
    uint32_t *ids, *start, *list;
    size_t nids;
} fan_index;

static void fan_index_free(fan_index *x)
{
    frep_free(x->map);
    frep_free(x->ids);
    frep_free(x->start);
    frep_free(x->list);
}

/* Number vertex w in x if it is not yet. */
static void fan_mark(fan_index *x, uint32_t w)
{
    if (x->map[w] != UINT32_MAX) return;
    x->map[w] = (uint32_t)x->nids;
    x->ids[x->nids++] = w;
}

/* One pass over the triangles: count (list NULL) or fill the fans of the numbered
 * vertices. */
static size_t fan_pass(const frep_mesh *m, fan_index *x, uint32_t *fill)
{
    size_t total = 0;
    for (size_t t = 0; t < 3 * m->ntris; t++) {
        uint32_t i = x->map[m->tri[t]];
        if (i == UINT32_MAX) continue;
        if (fill) x->list[fill[i]++] = (uint32_t)(t / 3);
        else x->start[i + 1]++;
        total++;
    }
    return total;
}

/* The fans of the far vertices, then of their neighbours.  0, or -1 when out of
 * memory. */
static int build_fans(const settle_run *r, const frep_mesh *m, fan_index *x)
{
    memset(x, 0, sizeof *x);
    x->map = frep_malloc(m->nverts * sizeof *x->map);
    x->ids = frep_malloc(m->nverts * sizeof *x->ids);
    x->start = frep_calloc(m->nverts + 1, sizeof *x->start);
    if (!x->map || !x->ids || !x->start) return -1;
    frep_prefault(x->map, m->nverts * sizeof *x->map);
    memset(x->map, 0xFF, m->nverts * sizeof *x->map);
    for (size_t k = 0; k < r->n; k++) fan_mark(x, r->sv[k].v);
    /* the neighbours: every vertex of a far vertex's triangle */
    for (size_t t = 0; t < m->ntris; t++) {
        const uint32_t *tv = &m->tri[3 * t];
        uint32_t a = x->map[tv[0]], b = x->map[tv[1]], c = x->map[tv[2]];
        if ((a == UINT32_MAX || a >= r->n) && (b == UINT32_MAX || b >= r->n) &&
            (c == UINT32_MAX || c >= r->n))
            continue;
        for (int i = 0; i < 3; i++) fan_mark(x, tv[i]);
    }
    size_t total = fan_pass(m, x, NULL);
    for (size_t i = 0; i < x->nids; i++) x->start[i + 1] += x->start[i];
    x->list = frep_malloc((total + 1) * sizeof *x->list);
    if (!x->list) return -1;
    frep_prefault(x->list, total * sizeof *x->list);
    /* ids is full only when every vertex was numbered; start + 1 serves as the cursor
     * otherwise, so the cursor is a copy */
    uint32_t *cur = frep_malloc((x->nids + 1) * sizeof *cur);
    if (!cur) return -1;
    memcpy(cur, x->start, x->nids * sizeof *cur);
    fan_pass(m, x, cur);
    frep_free(cur);
    return 0;
}

/* Normal (not normalized) of triangle t, with vertex v at x. */
static void tri_normal(const frep_mesh *m, uint32_t t, uint32_t v, const double x[3], double n[3])
{
    const double *p[3];
    for (int i = 0; i < 3; i++) {
        uint32_t w = m->tri[3 * (size_t)t + (size_t)i];
        p[i] = w == v ? x : &m->v[3 * w];
    }
    double u[3], w[3];
    vec3_sub(p[1], p[0], u);
    vec3_sub(p[2], p[0], w);
    vec3_cross(u, w, n);
}

static double cosine(const double a[3], const double b[3])
{
    double la = vec3_len(a), lb = vec3_len(b);
    return la > 0 && lb > 0 ? vec3_dot(a, b) / (la * lb) : -1;
}


/* Triangle t (normal n) faces against the normals of its vertices (their sum into
 * ns): it folds over its neighbours. */
static int tri_folded(const frep_mesh *m, uint32_t t, const double n[3], double ns[3])
{
    ns[0] = ns[1] = ns[2] = 0;
    for (int i = 0; i < 3; i++) {
        const double *vn = &m->n[3 * (size_t)m->tri[3 * (size_t)t + (size_t)i]];
        for (int c = 0; c < 3; c++) ns[c] += vn[c];
    }
    return vec3_dot(n, ns) < 0;
}

/* The triangles' folds (tri_folded), one byte a triangle, shared by the threads. */
typedef struct fold_job {
    const frep_mesh *m;
    uint8_t *tfold;
} fold_job;

static void fold_chunk(void *ctx, int t, long i0, long i1)
{
    (void)t;
    fold_job *J = ctx;
    for (long i = i0; i < i1; i++) {
        double n[3], ns[3];
        tri_normal(J->m, (uint32_t)i, UINT32_MAX, NULL, n);
        J->tfold[i] = (uint8_t)tri_folded(J->m, (uint32_t)i, n, ns);
    }
}

/* The vertices of the folded triangles (tri_folded) marked in folded[]: the triangles
 * checked in parallel, the vertices marked serially.  0, or -1 when out of memory. */
static int mark_folded(const mesher *M, const frep_mesh *m, uint8_t *folded)
{
    fold_job J = { m, frep_malloc(m->ntris + 1) };
    if (!J.tfold) return -1;
    frep_prefault(J.tfold, m->ntris);
    int nt = m->ntris < SETTLE_PAR_MIN_TRIS ? 1 : M->nthreads;
    frep_par_for(nt, (long)m->ntris, SETTLE_TRI_CHUNK, fold_chunk, &J);
    memset(folded, 0, m->nverts);
    for (size_t t = 0; t < m->ntris; t++)
        if (J.tfold[t])
            for (int i = 0; i < 3; i++) folded[m->tri[3 * t + (size_t)i]] = 1;
    frep_free(J.tfold);
    return 0;
}

/* The bounding box of triangle t with vertex v at x. */
static void tri_box(const frep_mesh *m, uint32_t t, uint32_t v, const double x[3], double b[6])
{
    for (int c = 0; c < 3; c++) {
        b[c] = INFINITY;
        b[c + 3] = -INFINITY;
    }
    for (int i = 0; i < 3; i++) {
        uint32_t w = m->tri[3 * (size_t)t + (size_t)i];
        const double *p = w == v ? x : &m->v[3 * (size_t)w];
        for (int c = 0; c < 3; c++) {
            b[c] = fmin(b[c], p[c]);
            b[c + 3] = fmax(b[c + 3], p[c]);
        }
    }
}

static int boxes_meet(const double a[6], const double b[6])
{
    for (int c = 0; c < 3; c++)
        if (a[c] > b[c + 3] || b[c] > a[c + 3]) return 0;
    return 1;
}

/* May far vertex k move to its target?  Every triangle of its fan keeps its
 * orientation (cosine of the turn above MESH_SETTLE_TURN) and meets no triangle
 * around the fan's vertices (the exact test of --check) beyond the vertices they
 * share.  More than SETTLE_MAX_FAN fan or SETTLE_MAX_NEAR nearby triangles: no move. */
static int move_is_clean(const frep_mesh *m, const fan_index *x, const svert *s, size_t k,
                         const double to[3], double turn)
{
    const uint32_t *fan = &x->list[x->start[k]];
    uint32_t nfan = x->start[k + 1] - x->start[k];
    if (nfan > SETTLE_MAX_FAN) return 0;
    double fbox[SETTLE_MAX_FAN][6];
    for (uint32_t i = 0; i < nfan; i++) {
        double n0[3], n1[3], ns[3];
        tri_normal(m, fan[i], s->v, &m->v[3 * s->v], n0);
        tri_normal(m, fan[i], s->v, to, n1);
        /* keeps its orientation, or unfolds */
        if (!(cosine(n0, n1) > turn) && !(tri_folded(m, fan[i], n0, ns) && vec3_dot(n1, ns) > 0))
            return 0;
        tri_box(m, fan[i], s->v, to, fbox[i]);
    }
    /* the triangles around the fan's other vertices, each once, the fan's own apart */
    uint32_t near[SETTLE_MAX_NEAR];
    size_t nnear = 0;
    for (uint32_t i = 0; i < nfan; i++)
        for (int c = 0; c < 3; c++) {
            uint32_t w = m->tri[3 * (size_t)fan[i] + (size_t)c];
            if (w == s->v) continue;
            uint32_t iw = x->map[w];
            for (uint32_t j = x->start[iw]; j < x->start[iw + 1]; j++) {
                uint32_t u = x->list[j], q;
                for (q = 0; q < nfan && fan[q] != u; q++) continue;
                if (q < nfan) continue;
                size_t e;
                for (e = 0; e < nnear && near[e] != u; e++) continue;
                if (e < nnear) continue;
                if (nnear == SETTLE_MAX_NEAR) return 0;
                near[nnear++] = u;
            }
        }
    /* the fan's triangles among themselves (a fold inside the fan) and against those */
    for (uint32_t i = 0; i < nfan; i++)
        for (uint32_t q = i + 1; q < nfan; q++)
            if (mesh_pair_meets(m, fan[i], fan[q], s->v, to)) return 0;
    for (size_t e = 0; e < nnear; e++) {
        double ub[6];
        tri_box(m, near[e], s->v, to, ub);
        for (uint32_t q = 0; q < nfan; q++)
            if (boxes_meet(fbox[q], ub) && mesh_pair_meets(m, fan[q], near[e], s->v, to)) return 0;
    }
    return 1;
}

/* Tangled vertices checked at a time by a thread (a check is 10-20 us: 816 far
 * vertices of examples/gear.hf at -g 64, most of them tangled, took 15 ms). */
#define SETTLE_TANGLED_CHUNK 32

typedef struct tangled_job {
    settle_run *r;
    const frep_mesh *out;
    const fan_index *x;
} tangled_job;

static void tangled_chunk(void *ctx, int t, long k0, long k1)
{
    (void)t;
    tangled_job *J = ctx;
    for (long k = k0; k < k1; k++) {
        svert *s = &J->r->sv[k];
        if (s->tangled && move_is_clean(J->out, J->x, s, (size_t)k, &J->out->v[3 * s->v],
                                        J->r->turn))
            s->moved = 1;
    }
}

/* The tangled vertices whose fan meets no other triangle where they are stay there,
 * before any target is sought: most of them do (their targets were half the
 * settling's time on examples/gear.hf -g 64).  The checks read the mesh only, so
 * they run on the run's threads once there are two chunks of them, whatever the size
 * of the mesh (that gear's mesh has 57,808 triangles and 800 tangled vertices). */
static void leave_clean_tangles(settle_run *r, const frep_mesh *out, const fan_index *x)
{
    tangled_job J = { r, out, x };
    size_t tangled = 0;
    for (size_t k = 0; k < r->n; k++) tangled += r->sv[k].tangled != 0;
    int nt = tangled < 2 * SETTLE_TANGLED_CHUNK ? 1 : r->M->nthreads;
    frep_par_for(nt, (long)r->n, SETTLE_TANGLED_CHUNK, tangled_chunk, &J);
}

/* Move each vertex not moved yet to its nearest target its fan allows, in vertex
 * order (a tangled vertex stays where it is once its fan meets no other triangle, an
 * earlier move having untangled it); returns how many moved. */
static size_t apply_moves(settle_run *r, frep_mesh *out, const fan_index *x)
{
    size_t moved = 0;
    for (size_t k = 0; k < r->n; k++) {
        svert *s = &r->sv[k];
        if (s->moved) continue;
        if (s->tangled && move_is_clean(out, x, s, k, &out->v[3 * s->v], r->turn)) {
            s->moved = 1;
            continue;
        }
        const scand *c = &r->cand[SETTLE_MAX_CANDS * k];
        int i;
        for (i = 0; i < s->nc && !move_is_clean(out, x, s, k, c[i].x, r->turn); i++) continue;
        if (i == s->nc) continue;
        memcpy(&out->v[3 * s->v], c[i].x, sizeof c[i].x);
        double n[3] = { -c[i].g[0], -c[i].g[1], -c[i].g[2] };
        if (!vec3_normalize(n)) memcpy(&out->n[3 * s->v], n, sizeof n);
        s->moved = 1;
        moved++;
    }
    return moved;
}

/* The vertices left where they were look again MESH_SETTLE_REACH beyond their cell,
 * from where they are. */
static void widen(settle_run *r)
{
    for (size_t k = 0; k < r->n; k++) {
        svert *s = &r->sv[k];
        s->nc = 0;
        if (s->moved) continue;
        if (!vertex_cell(r->M, s->x0, s->fold ? 0 : MESH_SETTLE_REACH, s->lo, s->hi)) {
            s->moved = 1;     /* not a candidate any more */
            continue;
        }
        memcpy(s->x, s->x0, sizeof s->x);
        memcpy(s->g, s->g0, sizeof s->g);
        s->f = s->f0;
        s->d = s->d0;
    }
}

int mesh_settle_vertices(const mesher *M, frep_mesh *out, mesh_stats *st)
{
    settle_run r = { .M = M, .ts = M->ts[0], .turn = MESH_SETTLE_TURN };
    uint8_t *folded = frep_malloc(out->nverts + 1);
    if (!folded || mark_folded(M, out, folded) != 0) {
        frep_free(folded);
        return FREP_ENOMEM;
    }
    int frc = far_vertices(&r, out, folded);
    frep_free(folded);
    if (frc != 0) {
        frep_free(r.sv);
        return FREP_ENOMEM;
    }
    if (r.n == 0) {
        frep_free(r.sv);
        return 0;
    }
    size_t cap = SETTLE_BATCH_PER * r.n;
    if (cap < SETTLE_NDIRS * SETTLE_NRADII) cap = SETTLE_NDIRS * SETTLE_NRADII;
    double *buf = frep_malloc(13 * cap * sizeof *buf);
    r.bid = frep_malloc(cap * sizeof *r.bid);
    r.cand = frep_malloc(SETTLE_MAX_CANDS * r.n * sizeof *r.cand);
    fan_index fx;
    memset(&fx, 0, sizeof fx);
    int rc = !buf || !r.bid || !r.cand ? FREP_ENOMEM : 0;
    if (rc == 0) {
        double *b = buf;
        r.bx = b; b += cap;
        r.by = b; b += cap;
        r.bz = b; b += cap;
        r.bf = b; b += cap;
        r.bgx = b; b += cap;
        r.bgy = b; b += cap;
        r.bgz = b; b += cap;
        r.sa = b; b += 3 * cap;
        r.sb = b;
        rc = build_fans(&r, out, &fx) != 0 ? FREP_ENOMEM : 0;
        if (rc == 0) {
            leave_clean_tangles(&r, out, &fx);
            rc = find_targets(&r, 0);
        }
    }
    if (rc == 0) {
        st->settled = apply_moves(&r, out, &fx);
        widen(&r);
        r.turn = MESH_SETTLE_TURN_WIDE;
        if ((rc = find_targets(&r, 1)) == 0 && (rc = look_targets(&r)) == 0)
            st->settled += apply_moves(&r, out, &fx);
        /* the last pass: the corners on the level of the vertices still left */
        for (size_t k = 0; k < r.n; k++) r.sv[k].nc = 0;
        if (rc == 0 && (rc = level_corner_targets(&r)) == 0)
            st->settled += apply_moves(&r, out, &fx);
    }
    st->eval_points += r.eval_points;
    st->grad_points += r.grad_points;
    fan_index_free(&fx);
    frep_free(buf);
    frep_free(r.bid);
    frep_free(r.cand);
    frep_free(r.sv);
    return rc;
}

/* settle.c - the last step of the polygonizer (step 6 of doc/mesh.md): cell vertices
 * the blocks left farther than MESH_SETTLE_TOL cells from the surface are moved onto
 * it, once the triangles exist, where their fan does not fold.
 *
 * mesh.c projects far vertices inside each block, but not where that could fold the
 * quads over their neighbours' (cells with a corner exactly on the level, cells with
 * several components), and its clamped Newton steps stop on a cell face when the
 * gradient leans out of the cell (the R-functions' gradients near creases).  Here each
 * such vertex gets a target on the surface inside its cell (Newton steps, then a
 * bisection towards the cell's corners on the other side of the level), and moves
 * there only when every triangle of its fan keeps its orientation and stays clear of
 * a fold with the triangles across its outer edges.  Targets are computed per vertex;
 * the moves are decided serially in vertex order, so the mesh does not depend on the
 * thread count.
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

/* A vertex to settle: its index, its cell (less the margin), where it is and where it
 * may go (position, f - iso, gradient, distance in cells). */
typedef struct svert {
    uint32_t v;
    const mblock *B;          /* its block, whose box the field is focused on */
    double lo[3], hi[3];
    double x[3], f, g[3], d;
    double n[3];              /* the vertex normal: the side the surface must face */
} svert;

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
} settle_run;

/* Triangles around one vertex, and around the vertices of its fan, beyond which a
 * vertex is not moved (a dual-contouring vertex has 4 to 12 or so triangles). */
#define SETTLE_MAX_FAN 32
#define SETTLE_MAX_NEAR 256

/* Batch entries per vertex: one per corner of its cell in the bisection. */
#define SETTLE_BATCH_PER 8

/* The box of the cell holding a vertex at p, less the margin, or 0 when that cell is in
 * the padding layer (on a box cap, not on the surface). */
static int vertex_cell(const mesher *M, const double p[3], double lo[3], double hi[3])
{
    for (int c = 0; c < 3; c++) {
        double t = (p[c] - M->o->box[c]) / M->h[c];
        long P = (long)floor(t) + 1;
        if (P < 1 || P + 1 >= M->G[c]) return 0;
        double a = mesh_coord(M, c, P), b = mesh_coord(M, c, P + 1);
        if (!(p[c] >= a && p[c] <= b)) return 0;
        lo[c] = a + MESH_SETTLE_MARGIN * (b - a);
        hi[c] = b - MESH_SETTLE_MARGIN * (b - a);
    }
    return 1;
}

/* The blocks' cell vertices farther than MESH_SETTLE_TOL from the surface into
 * r->sv (NULL when there are none).  0, or -1 when out of memory. */
static int far_vertices(settle_run *r, const frep_mesh *out)
{
    const mesher *M = r->M;
    size_t n = 0, cap = 0;
    for (size_t b = 0; b < M->nblocks; b++) {
        const mblock *B = M->blocks[b];
        for (uint32_t l = 0; l < B->nverts; l++) {
            const double *fg = &B->vfg[4 * l];
            double d = mesh_cell_distance(M, fg[0], fg[1], fg[2], fg[3]);
            if (!(d > MESH_SETTLE_TOL)) continue;
            svert s;
            s.v = (uint32_t)(B->vglobal + l);
            s.B = B;
            if (!vertex_cell(M, &B->vpos[3 * l], s.lo, s.hi)) continue;
            if (n == cap) {
                size_t nc = cap ? 2 * cap : 64;
                svert *ns = frep_realloc(r->sv, nc * sizeof *ns);
                if (!ns) return -1;
                r->sv = ns;
                cap = nc;
            }
            memcpy(s.x, &B->vpos[3 * l], sizeof s.x);
            s.f = fg[0];
            memcpy(s.g, &fg[1], sizeof s.g);
            s.d = d;
            memcpy(s.n, &out->n[3 * s.v], sizeof s.n);
            r->sv[n++] = s;
        }
    }
    r->n = n;
    return 0;
}

/* Values (grad 0) or values and gradients at the batch's first m points, a run of
 * entries of one block at a time with the field focused on the block's box (the
 * pruned program of the blocks' own evaluations: the whole one costs several times
 * more on CSG parts).  0 or FREP_EINPUT. */
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
            if (f->focus(f->ctx, r->ts, bb, NULL) != 0) return FREP_EINPUT;
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

/* Newton steps x - (f - iso) grad f / |grad f|^2 clamped to the cell, for the vertices
 * still far. */
static int newton_targets(settle_run *r)
{
    for (int step = 0; step < MESH_SETTLE_STEPS; step++) {
        size_t m = 0;
        for (size_t k = 0; k < r->n; k++) {
            svert *s = &r->sv[k];
            double gg = vec3_dot(s->g, s->g);
            if (!(s->d > MESH_SETTLE_TOL) || !(gg > 0)) continue;
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

/* The closest point to the vertex among those found on the surface: for the vertices
 * still far, the segments from the vertex to the corners of its (shrunk) cell on the
 * other side of the level are bisected (values only), then the gradients at the
 * segments' midpoints decide. */
static int bisect_targets(settle_run *r)
{
    double iso = r->M->o->iso;
    size_t m = 0;
    for (size_t k = 0; k < r->n; k++) {
        const svert *s = &r->sv[k];
        if (!(s->d > MESH_SETTLE_TOL)) continue;
        for (int c = 0; c < 8; c++) {
            r->bx[m] = (c & 1) ? s->hi[0] : s->lo[0];
            r->by[m] = (c & 2) ? s->hi[1] : s->lo[1];
            r->bz[m] = (c & 4) ? s->hi[2] : s->lo[2];
            r->bid[m++] = (uint32_t)k;
        }
    }
    if (m == 0) return 0;
    int rc = batch_eval(r, m, 0);
    if (rc) return rc;
    size_t ns = 0;
    for (size_t q = 0; q < m; q++) {
        const svert *s = &r->sv[r->bid[q]];
        if (isnan(r->bf[q]) || (r->bf[q] >= iso) == (s->f >= 0)) continue;
        memcpy(&r->sa[3 * ns], s->x, 3 * sizeof *s->x);
        r->sb[3 * ns] = r->bx[q];
        r->sb[3 * ns + 1] = r->by[q];
        r->sb[3 * ns + 2] = r->bz[q];
        r->bid[ns++] = r->bid[q];
    }
    if (ns == 0) return 0;
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
            double *end = (r->bf[q] >= iso) == (s->f >= 0) ? &r->sa[3 * q] : &r->sb[3 * q];
            end[0] = r->bx[q];
            end[1] = r->by[q];
            end[2] = r->bz[q];
        }
    }
    if ((rc = batch_grad(r, ns)) != 0) return rc;
    /* per vertex, the midpoint nearest to it that is on the surface and faces its way
     * (sa and sb are free now: the best squared distance and entry per vertex) */
    double *best = r->sa, *bestq = r->sb;
    for (size_t k = 0; k < r->n; k++) best[k] = INFINITY;
    for (size_t q = 0; q < ns; q++) {
        uint32_t k = r->bid[q];
        const svert *s = &r->sv[k];
        double g[3] = { r->bgx[q], r->bgy[q], r->bgz[q] };
        double d = mesh_cell_distance(r->M, r->bf[q] - iso, g[0], g[1], g[2]);
        if (!(d <= MESH_SETTLE_TOL) || !(-vec3_dot(g, s->n) > 0)) continue;
        double e[3] = { r->bx[q] - s->x[0], r->by[q] - s->x[1], r->bz[q] - s->x[2] };
        double e2 = vec3_dot(e, e);
        if (e2 < best[k]) {
            best[k] = e2;
            bestq[k] = (double)q;
        }
    }
    for (size_t k = 0; k < r->n; k++) {
        if (!(best[k] < INFINITY)) continue;
        size_t q = (size_t)bestq[k];
        svert *s = &r->sv[k];
        s->x[0] = r->bx[q];
        s->x[1] = r->by[q];
        s->x[2] = r->bz[q];
        s->f = r->bf[q] - iso;
        s->g[0] = r->bgx[q];
        s->g[1] = r->bgy[q];
        s->g[2] = r->bgz[q];
        s->d = mesh_cell_distance(r->M, s->f, s->g[0], s->g[1], s->g[2]);
    }
    return 0;
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
static int move_is_clean(const frep_mesh *m, const fan_index *x, const svert *s, size_t k)
{
    const uint32_t *fan = &x->list[x->start[k]];
    uint32_t nfan = x->start[k + 1] - x->start[k];
    if (nfan > SETTLE_MAX_FAN) return 0;
    double fbox[SETTLE_MAX_FAN][6];
    for (uint32_t i = 0; i < nfan; i++) {
        double n0[3], n1[3];
        tri_normal(m, fan[i], s->v, &m->v[3 * s->v], n0);
        tri_normal(m, fan[i], s->v, s->x, n1);
        if (!(cosine(n0, n1) > MESH_SETTLE_TURN)) return 0;
        tri_box(m, fan[i], s->v, s->x, fbox[i]);
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
            if (mesh_pair_meets(m, fan[i], fan[q], s->v, s->x)) return 0;
    for (size_t e = 0; e < nnear; e++) {
        double ub[6];
        tri_box(m, near[e], s->v, s->x, ub);
        for (uint32_t q = 0; q < nfan; q++)
            if (boxes_meet(fbox[q], ub) && mesh_pair_meets(m, fan[q], near[e], s->v, s->x)) return 0;
    }
    return 1;
}

/* Move the vertices whose fans allow it, in vertex order; returns how many moved. */
static size_t apply_moves(settle_run *r, frep_mesh *out, const fan_index *x)
{
    size_t moved = 0;
    for (size_t k = 0; k < r->n; k++) {
        const svert *s = &r->sv[k];
        const double *p = &out->v[3 * s->v];
        if (s->x[0] == p[0] && s->x[1] == p[1] && s->x[2] == p[2]) continue;
        if (!move_is_clean(out, x, s, k)) continue;
        memcpy(&out->v[3 * s->v], s->x, sizeof s->x);
        double n[3] = { -s->g[0], -s->g[1], -s->g[2] };
        if (!vec3_normalize(n)) memcpy(&out->n[3 * s->v], n, sizeof n);
        moved++;
    }
    return moved;
}

int mesh_settle_vertices(const mesher *M, frep_mesh *out, mesh_stats *st)
{
    settle_run r = { .M = M, .ts = M->ts[0] };
    if (far_vertices(&r, out) != 0) {
        frep_free(r.sv);
        return FREP_ENOMEM;
    }
    if (r.n == 0) {
        frep_free(r.sv);
        return 0;
    }
    size_t cap = SETTLE_BATCH_PER * r.n;
    double *buf = frep_malloc(13 * cap * sizeof *buf);
    r.bid = frep_malloc(cap * sizeof *r.bid);
    fan_index fx;
    memset(&fx, 0, sizeof fx);
    int rc = !buf || !r.bid ? FREP_ENOMEM : 0;
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
        if ((rc = newton_targets(&r)) == 0 && (rc = bisect_targets(&r)) == 0)
            rc = build_fans(&r, out, &fx) != 0 ? FREP_ENOMEM : 0;
    }
    if (rc == 0) st->settled = apply_moves(&r, out, &fx);
    st->eval_points += r.eval_points;
    st->grad_points += r.grad_points;
    fan_index_free(&fx);
    frep_free(buf);
    frep_free(r.bid);
    frep_free(r.sv);
    return rc;
}

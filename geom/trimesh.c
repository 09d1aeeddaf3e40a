/* trimesh.c - the indexed triangle mesh every mesh stage shares: release and the
 * invariant checks of `frep mesh --check` and the tests (closed, 2-manifold, oriented,
 * free of self-intersections).  Made by mesh/mesh.c (polygonization) and geom/meshio.c
 * (mesh files); the pair test is geom/tritri.c.
 */
#include "alloc.h"
#include "trimesh.h"
#include "tritri.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void mesh_free(frep_mesh *m)
{
    if (!m) return;
    frep_free(m->v);
    frep_free(m->n);
    frep_free(m->tri);
    memset(m, 0, sizeof *m);
}

uint8_t *mesh_colors(const frep_mesh *m, mesh_color_fn fn, void *user)
{
    uint8_t *rgb = frep_malloc(m->nverts ? 3 * m->nverts : 1);
    if (!rgb) return NULL;
    for (size_t i = 0; i < m->nverts; i++) fn(user, &m->v[3 * i], &rgb[3 * i]);
    return rgb;
}

/* ---- validation ------------------------------------------------------------------- */

typedef struct dedge {
    uint32_t a, b;   /* a < b */
    int dir;         /* +1: a->b, -1: b->a */
} dedge;

static int cmp_dedge(const void *x, const void *y)
{
    const dedge *p = x, *q = y;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    if (p->b != q->b) return p->b < q->b ? -1 : 1;
    return p->dir - q->dir;
}

/* Vertex fans: triangle (a, b, c) gives each of its vertices a link edge (a: b -> c,
 * b: c -> a, c: a -> b).  Around a vertex of a closed, oriented 2-manifold the link
 * edges form exactly one cycle; two cycles are two cones touching at the vertex. */
static int check_fans(const frep_mesh *m, mesh_check *c)
{
    size_t nv = m->nverts;
    size_t *start = frep_calloc(nv + 2, sizeof *start);
    uint32_t *lk = frep_malloc((6 * m->ntris + 1) * sizeof *lk);
    if (!start || !lk) {
        frep_free(start);
        frep_free(lk);
        return -1;
    }
    for (size_t i = 0; i < 3 * m->ntris; i++)
        if (m->tri[i] < nv) start[m->tri[i] + 2]++;
    for (size_t v = 0; v < nv; v++) start[v + 2] += start[v + 1];
    for (size_t t = 0; t < m->ntris; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->tri[3 * t + k];
            if (v >= nv) continue;
            size_t at = start[v + 1]++;
            lk[2 * at] = m->tri[3 * t + (k + 1) % 3];
            lk[2 * at + 1] = m->tri[3 * t + (k + 2) % 3];
        }
    /* now start[v] .. start[v + 1] are v's link edges */
    for (size_t v = 0; v < nv; v++) {
        size_t s = start[v], d = start[v + 1] - s;
        if (d == 0) {
            c->unused_verts++;
            continue;
        }
        /* follow the cycle through the first edge: it must use every edge once */
        uint32_t first = lk[2 * s], to = lk[2 * s + 1];
        size_t steps = 1;
        while (to != first && steps <= d) {
            size_t q;
            for (q = 0; q < d && lk[2 * (s + q)] != to; q++) continue;
            if (q == d) break;
            to = lk[2 * (s + q) + 1];
            steps++;
        }
        if (to != first || steps != d) c->nonmanifold_verts++;
    }
    frep_free(start);
    frep_free(lk);
    return 0;
}

int mesh_validate(const frep_mesh *m, mesh_check *c)
{
    memset(c, 0, sizeof *c);
    for (size_t i = 0; i < 3 * m->nverts; i++)
        if (!isfinite(m->v[i])) c->nonfinite++;
    dedge *E = frep_malloc((3 * m->ntris + 1) * sizeof *E);
    if (!E) return -1;
    for (size_t t = 0; t < m->ntris; t++) {
        const uint32_t *v = &m->tri[3 * t];
        const double *p0 = &m->v[3 * v[0]], *p1 = &m->v[3 * v[1]], *p2 = &m->v[3 * v[2]];
        double u[3], w[3], cr[3];
        for (int k = 0; k < 3; k++) {
            u[k] = p1[k] - p0[k];
            w[k] = p2[k] - p0[k];
        }
        cr[0] = u[1] * w[2] - u[2] * w[1];
        cr[1] = u[2] * w[0] - u[0] * w[2];
        cr[2] = u[0] * w[1] - u[1] * w[0];
        double a2 = sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
        double lu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
        double lw = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        if (!(a2 > 1e-12 * fmax(lu, lw))) c->degenerate++;
        c->area += 0.5 * a2;
        c->volume += (p0[0] * (p1[1] * p2[2] - p1[2] * p2[1]) - p0[1] * (p1[0] * p2[2] - p1[2] * p2[0]) +
                      p0[2] * (p1[0] * p2[1] - p1[1] * p2[0])) / 6.0;
        for (int k = 0; k < 3; k++) {
            uint32_t a = v[k], b = v[(k + 1) % 3];
            dedge *d = &E[3 * t + k];
            d->a = a < b ? a : b;
            d->b = a < b ? b : a;
            d->dir = a < b ? 1 : -1;
        }
    }
    size_t ne = 3 * m->ntris;
    if (ne > 1) qsort(E, ne, sizeof *E, cmp_dedge);
    for (size_t i = 0; i < ne;) {
        size_t j = i;
        int sum = 0;
        while (j < ne && E[j].a == E[i].a && E[j].b == E[i].b) sum += E[j++].dir;
        size_t cnt = j - i;
        if (cnt == 1) c->open_edges++;
        else if (cnt > 2) c->nonmanifold_edges++;
        else if (sum != 0) c->flipped_edges++;
        i = j;
    }
    frep_free(E);
    return check_fans(m, c) != 0 ? -1 : 0;
}

/* ---- self-intersections ----------------------------------------------------------- */

/* The grid's cell is this many times the mean largest side of the triangles' boxes:
 * a triangle then covers one to eight cells, a cell holds a few triangles. */
#define SELFINT_CELL_SCALE 1.5
/* Cells per axis at most: keys pack three 21-bit coordinates. */
#define SELFINT_MAX_DIM ((1 << 21) - 1)
/* Grid entries per triangle at most (a few huge triangles in a file mesh): past it
 * the cells are made twice as large. */
#define SELFINT_MAX_ENTRIES_PER_TRI 27

/* The uniform grid: cells of side s from lo, entries (cell key, triangle) grouped by
 * a hash of the key in buckets; a bucket may hold several cells. */
typedef struct tgrid {
    const frep_mesh *m;
    double lo[3], s;
    size_t nent, nbuckets;   /* nbuckets: a power of two */
    size_t *start;           /* bucket b's entries: start[b] .. start[b + 1] - 1 */
    uint64_t *key;
    uint32_t *tri;
} tgrid;

static void tri_box(const frep_mesh *m, size_t t, double bmin[3], double bmax[3])
{
    const uint32_t *v = &m->tri[3 * t];
    for (int k = 0; k < 3; k++) {
        double a = m->v[3 * v[0] + k], b = m->v[3 * v[1] + k], c = m->v[3 * v[2] + k];
        bmin[k] = fmin(a, fmin(b, c));
        bmax[k] = fmax(a, fmax(b, c));
    }
}

static uint64_t cell_of(const tgrid *G, const double p[3], int k)
{
    double q = floor((p[k] - G->lo[k]) / G->s);
    return q < 0 ? 0 : (q > SELFINT_MAX_DIM ? SELFINT_MAX_DIM : (uint64_t)q);
}

static uint64_t cell_key(uint64_t i, uint64_t j, uint64_t k) { return i | (j << 21) | (k << 42); }

static size_t key_bucket(const tgrid *G, uint64_t key)
{
    key *= 0x9E3779B97F4A7C15ull;   /* Fibonacci hashing */
    return (size_t)(key >> 32) & (G->nbuckets - 1);
}

/* Call fn(G, key, t, arg) for every cell triangle t's box covers. */
static void tri_cells(tgrid *G, size_t t, void (*fn)(tgrid *, uint64_t, size_t, void *), void *arg)
{
    double bmin[3], bmax[3];
    tri_box(G->m, t, bmin, bmax);
    uint64_t c0[3], c1[3];
    for (int k = 0; k < 3; k++) {
        c0[k] = cell_of(G, bmin, k);
        c1[k] = cell_of(G, bmax, k);
    }
    for (uint64_t z = c0[2]; z <= c1[2]; z++)
        for (uint64_t y = c0[1]; y <= c1[1]; y++)
            for (uint64_t x = c0[0]; x <= c1[0]; x++) fn(G, cell_key(x, y, z), t, arg);
}

static void count_entry(tgrid *G, uint64_t key, size_t t, void *arg)
{
    (void)t;
    (void)arg;
    if (G->start) G->start[key_bucket(G, key) + 1]++;
    else G->nent++;
}

static void put_entry(tgrid *G, uint64_t key, size_t t, void *arg)
{
    (void)arg;
    size_t at = G->start[key_bucket(G, key)]++;
    G->key[at] = key;
    G->tri[at] = (uint32_t)t;
}

/* The grid's origin and cell side: SELFINT_CELL_SCALE times the mean box side, at
 * most SELFINT_MAX_DIM cells per axis, at most SELFINT_MAX_ENTRIES_PER_TRI entries a
 * triangle on average.  Counts the entries. */
static void tgrid_size(tgrid *G)
{
    const frep_mesh *m = G->m;
    double hi[3], ext = 0;
    for (int k = 0; k < 3; k++) G->lo[k] = hi[k] = m->v[3 * m->tri[0] + k];
    for (size_t t = 0; t < m->ntris; t++) {
        double bmin[3], bmax[3], e = 0;
        tri_box(m, t, bmin, bmax);
        for (int k = 0; k < 3; k++) {
            G->lo[k] = fmin(G->lo[k], bmin[k]);
            hi[k] = fmax(hi[k], bmax[k]);
            e = fmax(e, bmax[k] - bmin[k]);
        }
        ext += e;
    }
    G->s = SELFINT_CELL_SCALE * ext / (double)m->ntris;
    for (int k = 0; k < 3; k++) G->s = fmax(G->s, (hi[k] - G->lo[k]) / (SELFINT_MAX_DIM - 1));
    if (!(G->s > 0)) G->s = 1;
    for (;;) {
        G->nent = 0;
        for (size_t t = 0; t < m->ntris; t++) tri_cells(G, t, count_entry, NULL);
        if (G->nent <= SELFINT_MAX_ENTRIES_PER_TRI * m->ntris) break;
        G->s *= 2;
    }
}

/* Entries bucketed by a counting sort on the hash of their keys. */
static int tgrid_fill(tgrid *G)
{
    G->nbuckets = 1;
    while (G->nbuckets < G->nent) G->nbuckets *= 2;
    G->start = frep_calloc(G->nbuckets + 1, sizeof *G->start);
    G->key = frep_malloc(G->nent * sizeof *G->key);
    G->tri = frep_malloc(G->nent * sizeof *G->tri);
    if (!G->start || !G->key || !G->tri) return -1;
    for (size_t t = 0; t < G->m->ntris; t++) tri_cells(G, t, count_entry, NULL);
    for (size_t b = 0; b < G->nbuckets; b++) G->start[b + 1] += G->start[b];
    for (size_t t = 0; t < G->m->ntris; t++) tri_cells(G, t, put_entry, NULL);
    /* put_entry moved each start[b] to the end of bucket b, the start of b + 1 */
    for (size_t b = G->nbuckets; b > 0; b--) G->start[b] = G->start[b - 1];
    G->start[0] = 0;
    return 0;
}

int mesh_pair_meets(const frep_mesh *m, uint32_t s, uint32_t t, uint32_t v, const double *x)
{
    const uint32_t *a = &m->tri[3 * (size_t)s], *b = &m->tri[3 * (size_t)t];
    int pa[3], pb[3], n = 0, usedb[3] = { 0, 0, 0 }, useda[3] = { 0, 0, 0 };
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (a[i] == b[j] && !usedb[j] && !useda[i]) {
                pa[n] = i;
                pb[n++] = j;
                useda[i] = usedb[j] = 1;
            }
    int na = n, nb = n;
    for (int i = 0; i < 3; i++) {
        if (!useda[i]) pa[na++] = i;
        if (!usedb[i]) pb[nb++] = i;
    }
    const double *p[3], *q[3];
    for (int i = 0; i < 3; i++) {
        p[i] = x && a[pa[i]] == v ? x : &m->v[3 * (size_t)a[pa[i]]];
        q[i] = x && b[pb[i]] == v ? x : &m->v[3 * (size_t)b[pb[i]]];
    }
    return tri_tri_intersect(p, q, n);
}

/* Triangles s and t intersect beyond their common vertices. */
static int tri_pair(const frep_mesh *m, uint32_t s, uint32_t t)
{
    return mesh_pair_meets(m, s, t, 0, NULL);
}

/* Entries e and f of one bucket hold the same cell, which is where the boxes of their
 * triangles overlap first (so each pair is tested in one cell only). */
static int pair_here(const tgrid *G, size_t e, size_t f)
{
    if (G->key[e] != G->key[f] || G->tri[e] == G->tri[f]) return 0;
    double amin[3], amax[3], bmin[3], bmax[3], c[3];
    tri_box(G->m, G->tri[e], amin, amax);
    tri_box(G->m, G->tri[f], bmin, bmax);
    for (int k = 0; k < 3; k++) {
        if (amax[k] < bmin[k] || bmax[k] < amin[k]) return 0;
        c[k] = fmax(amin[k], bmin[k]);
    }
    return cell_key(cell_of(G, c, 0), cell_of(G, c, 1), cell_of(G, c, 2)) == G->key[e];
}

int mesh_self_intersections(const frep_mesh *m, size_t *pairs, uint32_t first[2])
{
    *pairs = 0;
    if (m->ntris < 2) return 0;
    tgrid G = { .m = m };
    tgrid_size(&G);
    int rc = tgrid_fill(&G);
    for (size_t b = 0; rc == 0 && b < G.nbuckets; b++)
        for (size_t e = G.start[b]; e < G.start[b + 1]; e++)
            for (size_t f = e + 1; f < G.start[b + 1]; f++) {
                if (!pair_here(&G, e, f) || !tri_pair(m, G.tri[e], G.tri[f])) continue;
                uint32_t s = G.tri[e] < G.tri[f] ? G.tri[e] : G.tri[f];
                uint32_t t = G.tri[e] ^ G.tri[f] ^ s;
                if (first && (*pairs == 0 || s < first[0] || (s == first[0] && t < first[1]))) {
                    first[0] = s;
                    first[1] = t;
                }
                (*pairs)++;
            }
    frep_free(G.start);
    frep_free(G.key);
    frep_free(G.tri);
    return rc;
}

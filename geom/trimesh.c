/* trimesh.c - the indexed triangle mesh every mesh stage shares: release and the
 * invariant checks of `frep mesh --check` and the tests (closed, 2-manifold, oriented).
 * Made by mesh/mesh.c (polygonization) and geom/meshio.c (mesh files).
 */
#include "alloc.h"
#include "trimesh.h"

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
    return check_fans(m, c);
}

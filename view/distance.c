/* distance.c - point-to-model and model-to-cloud distances and the colour scale chosen
 * from them (distance.h), for the legends of frep view and frep render.
 */
#include "config.h"

#include "alloc.h"
#include "distance.h"
#include "kdtree.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int view_point_distances(const frep_program *p, double iso, size_t n, const double *x,
                         const double *y, const double *z, int nthreads, double *d,
                         frep_runtime_error *re, frep_error *e)
{
    if (n == 0) return 0;
    double *g = frep_reallocarray(NULL, n, 3 * sizeof *g);
    if (!g) return frep_error_nomem(e);
    frep_runtime_error local;
    int rc = frep_eval_grad_par(p, n, x, y, z, NULL, d, g, g + n, g + 2 * n, nthreads,
                                re ? re : &local);
    if (rc != 0) {
        frep_free(g);
        return frep_error_nomem(e); /* a compiled program fails only to allocate */
    }
    for (size_t i = 0; i < n; i++) {
        double gx = g[i], gy = g[n + i], gz = g[2 * n + i];
        double gl = sqrt(gx * gx + gy * gy + gz * gz);
        double f = d[i] - iso;
        d[i] = gl > 0 ? f / gl : (f == 0 ? 0 : copysign(INFINITY, f));
    }
    frep_free(g);
    return 0;
}

int view_vertex_distances(const frep_mesh *m, size_t n, const double *x, const double *y,
                          const double *z, double *d, frep_error *e)
{
    if (n == 0 || n > UINT32_MAX)
        return frep_error_set(e, FREP_EINPUT, "a cloud of %zu points", n);
    kd_tree *t = kd_build(n, x, y, z);
    if (!t) return frep_error_nomem(e);
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < m->nverts; i++) {
        uint32_t idx;
        double d2 = INFINITY;
        kd_knn(t, &m->v[3 * i], 1, &idx, &d2);
        d[i] = sqrt(d2);
    }
    kd_free(t);
    return 0;
}

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The point of triangle (a, b, c) nearest to p, into q (Ericson, Real-Time Collision
 * Detection, 5.1.5: the Voronoi region of p among the corners, edges and face). */
static void closest_on_triangle(const double p[3], const double a[3], const double b[3],
                                const double c[3], double q[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    for (int k = 0; k < 3; k++) {
        ab[k] = b[k] - a[k];
        ac[k] = c[k] - a[k];
        ap[k] = p[k] - a[k];
        bp[k] = p[k] - b[k];
        cp[k] = p[k] - c[k];
    }
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap), d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    double u = 0, v = 0; /* q = a + u ab + v ac */
    if (d1 <= 0 && d2 <= 0) { /* corner a */
    } else if (d3 >= 0 && d4 <= d3) u = 1;
    else if (d6 >= 0 && d5 <= d6) v = 1;
    else if (vc <= 0 && d1 >= 0 && d3 <= 0) u = d1 / (d1 - d3);
    else if (vb <= 0 && d2 >= 0 && d6 <= 0) v = d2 / (d2 - d6);
    else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        u = 1 - w;
        v = w;
    } else {
        double den = va + vb + vc;
        u = den != 0 ? vb / den : 0;
        v = den != 0 ? vc / den : 0;
    }
    for (int k = 0; k < 3; k++) q[k] = a[k] + u * ab[k] + v * ac[k];
}

/* Signed distance of p to triangle t of m (positive behind its outward face). */
static double triangle_distance(const frep_mesh *m, size_t t, const double p[3])
{
    const double *a = &m->v[3 * m->tri[3 * t]], *b = &m->v[3 * m->tri[3 * t + 1]];
    const double *c = &m->v[3 * m->tri[3 * t + 2]];
    double q[3], ab[3], ac[3], nrm[3], pq[3];
    closest_on_triangle(p, a, b, c, q);
    for (int k = 0; k < 3; k++) {
        ab[k] = b[k] - a[k];
        ac[k] = c[k] - a[k];
        pq[k] = p[k] - q[k];
    }
    nrm[0] = ab[1] * ac[2] - ab[2] * ac[1];
    nrm[1] = ab[2] * ac[0] - ab[0] * ac[2];
    nrm[2] = ab[0] * ac[1] - ab[1] * ac[0];
    double dist = sqrt(dot3(pq, pq));
    return dot3(pq, nrm) < 0 ? dist : -dist;
}

/* The centroids of m's triangles as three arrays (one allocation). */
static double *centroids(const frep_mesh *m)
{
    size_t nt = m->ntris;
    double *c = frep_reallocarray(NULL, nt, 3 * sizeof *c);
    if (!c) return NULL;
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++)
            c[k * nt + t] = (m->v[3 * m->tri[3 * t] + k] + m->v[3 * m->tri[3 * t + 1] + k] +
                             m->v[3 * m->tri[3 * t + 2] + k]) / 3;
    return c;
}

int view_mesh_distances(const frep_mesh *m, size_t n, const double *x, const double *y,
                        const double *z, double *d, frep_error *e)
{
    size_t nt = m->ntris;
    if (nt == 0 || nt > UINT32_MAX)
        return frep_error_set(e, FREP_EINPUT, "a mesh of %zu triangles", nt);
    double *c = centroids(m);
    kd_tree *t = c ? kd_build(nt, c, c + nt, c + 2 * nt) : NULL;
    frep_free(c);
    if (!t) return frep_error_nomem(e);
#pragma omp parallel for schedule(dynamic, 256)
    for (size_t i = 0; i < n; i++) {
        double p[3] = { x[i], y[i], z[i] }, d2[VIEW_MESH_CANDIDATES];
        uint32_t idx[VIEW_MESH_CANDIDATES];
        size_t k = kd_knn(t, p, VIEW_MESH_CANDIDATES, idx, d2);
        double best = INFINITY;
        for (size_t j = 0; j < k; j++) {
            double dj = triangle_distance(m, idx[j], p);
            if (fabs(dj) < fabs(best)) best = dj;
        }
        d[i] = best;
    }
    kd_free(t);
    return 0;
}

double view_nice_ceil(double v)
{
    if (!(v > 0) || !isfinite(v)) return v;
    double p = pow(10, floor(log10(v)));
    static const double steps[] = { 1, 2, 5, 10 };
    for (size_t i = 0; i < sizeof steps / sizeof steps[0]; i++)
        if (steps[i] * p >= v * (1 - 1e-12)) return steps[i] * p;
    return 10 * p;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int view_auto_scale(const double *d, size_t n, double q, double factor, double fallback,
                    double *scale, frep_error *e)
{
    double *a = frep_reallocarray(NULL, n ? n : 1, sizeof *a);
    if (!a) return frep_error_nomem(e);
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (isfinite(d[i])) a[k++] = fabs(d[i]);
    double v = 0;
    if (k > 0) {
        qsort(a, k, sizeof *a, cmp_double);
        v = factor * a[(size_t)(q * (double)(k - 1))];
        if (!(v > 0)) v = factor * a[k - 1];
    }
    frep_free(a);
    *scale = v > 0 ? view_nice_ceil(v) : fallback;
    return 0;
}

/* segment.c - the segmentation driver (segment/segment.h): defaults scaled to the
 * cloud, normals when needed, efficient RANSAC, oriented boxes, separating primitives
 * (Fayolle & Pasko 2016, Algorithm 2) and the .hf/.fit primitive lists.
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "ast.h"
#include "cancel.h"
#include "file.h"
#include "fitfile.h"
#include "kdtree.h"
#include "normals.h"
#include "ransac.h"
#include "segment.h"
#include "util.h"
#include "vec3.h"

/* Points whose nearest-neighbour distance estimates the sampling density. */
#define SPACING_SAMPLES 2000
/* Most points in the spacing estimate's tree (see median_spacing). */
#define SPACING_TREE_MAX 100000
/* Neighbours searched for the nearest distinct position (a point may be repeated). */
#define SPACING_K 16
/* Largest primitive list read: 256 MiB is millions of primitives, far more than a
 * segmentation finds or a construction tree combines. */
#define SEGMENT_PRIMS_MAX_BYTES ((size_t)1 << 28)
/* Longest line of a .hf primitive list we parse. */
#define HF_MAX_LINE 4096

void segment_config_init(segment_config *c)
{
    memset(c, 0, sizeof *c);
    c->types = 0;
    c->seed = 1;
    c->separating = 1;
}

void segment_result_free(segment_result *r)
{
    frep_free(r->prims);
    frep_free(r->label);
    r->prims = NULL;
    r->label = NULL;
    r->nprims = r->nfitted = 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The median distance to the nearest other position over SPACING_SAMPLES evenly
 * spaced points of tree t (of nt points, every stride-th of c), scaled back by
 * sqrt(stride), into *med: on a surface the spacing goes as one over the square root
 * of the density. 0, or -1 when out of memory. */
static int sampled_spacing(const frep_cloud *c, const kd_tree *t, size_t nt, size_t stride,
                           double *med)
{
    size_t m = nt < SPACING_SAMPLES ? nt : SPACING_SAMPLES;
    double *d = frep_malloc(m * sizeof *d);
    if (!d) return -1;
    size_t got = 0;
    for (size_t j = 0; j < m; j++) {
        size_t i = (size_t)((double)j * (double)nt / (double)m) * stride;
        double q[3] = {c->x[i], c->y[i], c->z[i]}, d2[SPACING_K];
        uint32_t idx[SPACING_K];
        size_t k = kd_knn(t, q, SPACING_K, idx, d2);
        /* The nearest other position: duplicates of the point itself do not count. */
        for (size_t e = 0; e < k; e++)
            if (d2[e] > 0) {
                d[got++] = sqrt(d2[e]);
                break;
            }
    }
    *med = 0;
    if (got) {
        qsort(d, got, sizeof *d, cmp_double);
        *med = d[got / 2] / sqrt((double)stride);
    }
    frep_free(d);
    return 0;
}

/* Median distance to the nearest other point over an evenly spaced sample into *med;
 * 0, or -1 when out of memory. Large clouds use a tree of every stride-th point only
 * (SPACING_TREE_MAX of them). */
static int median_spacing(const frep_cloud *c, double *med)
{
    size_t stride = c->n > SPACING_TREE_MAX ? (c->n + SPACING_TREE_MAX - 1) / SPACING_TREE_MAX : 1;
    size_t nt = (c->n + stride - 1) / stride;
    double *sx = NULL, *sy = NULL, *sz = NULL;
    kd_tree *t = NULL;
    if (stride > 1) {
        sx = frep_malloc(nt * sizeof *sx);
        sy = frep_malloc(nt * sizeof *sy);
        sz = frep_malloc(nt * sizeof *sz);
        if (sx && sy && sz) {
            for (size_t j = 0; j < nt; j++) {
                sx[j] = c->x[j * stride];
                sy[j] = c->y[j * stride];
                sz[j] = c->z[j * stride];
            }
            t = kd_build(nt, sx, sy, sz);
        }
    } else {
        t = kd_build(c->n, c->x, c->y, c->z);
    }
    int rc = t ? sampled_spacing(c, t, nt, stride, med) : -1;
    kd_free(t);
    frep_free(sx);
    frep_free(sy);
    frep_free(sz);
    return rc;
}

/* Points whose neighbourhood measures the noise (evenly spaced over the cloud). */
#define NOISE_SAMPLES 2000
/* Neighbours of each: enough for a stable plane fit, few enough that the curvature of
 * small features adds little. */
#define NOISE_K 16

/* The noise estimate is a low quantile of the neighbourhoods' deviations, not their
 * median: on a sparse sample of a part with many small faces (nine_cuboids' stacked
 * cubes at 10,000 points) most neighbourhoods of NOISE_K points reach across an edge,
 * and the median measured the edges (0.044, a quarter of a percent of the diagonal, on
 * a clean sample whose lower quartile is 1e-8), which set a 1% epsilon and merged faces
 * 11-22 degrees apart. Scaled by NOISE_MEDIAN_PER_QUANTILE, the ratio of the median to
 * this quantile when every neighbourhood is flat and noisy (1.14-1.15, simulated for
 * Gaussian noise of 0.03-0.3 point spacings), so that on a noisy cloud the estimate
 * stays the median's. */
#define NOISE_QUANTILE 0.25
#define NOISE_MEDIAN_PER_QUANTILE 1.15

/* The noise of the cloud into *sigma: over NOISE_SAMPLES evenly spaced points, the RMS
 * distance of their NOISE_K nearest neighbours from the plane fitted to them (the square
 * root of the neighbourhood covariance's smallest eigenvalue), its NOISE_QUANTILE
 * quantile times NOISE_MEDIAN_PER_QUANTILE. On a clean sample of flat faces this is 0;
 * on noisy data about the median deviation of a flat neighbourhood; curvature and edges
 * add to it only where they reach more than three quarters of the points. 0, or -1 when
 * out of memory. */
static int noise_sigma(const frep_cloud *c, double *sigma)
{
    *sigma = 0;
    size_t k = c->n < NOISE_K ? c->n : NOISE_K, m = c->n < NOISE_SAMPLES ? c->n : NOISE_SAMPLES;
    if (k < 4 || m == 0) return 0;
    kd_tree *t = kd_build(c->n, c->x, c->y, c->z);
    double *r = frep_malloc(m * sizeof *r);
    if (!t || !r) {
        kd_free(t);
        frep_free(r);
        return -1;
    }
    for (size_t j = 0; j < m; j++) {
        size_t i = (size_t)((double)j * (double)c->n / (double)m);
        double q[3] = {c->x[i], c->y[i], c->z[i]}, d2[NOISE_K], mean[3] = {0, 0, 0};
        double cov[9] = {0}, ev[3], vec[9];
        uint32_t idx[NOISE_K];
        size_t got = kd_knn(t, q, k, idx, d2);
        for (size_t e = 0; e < got; e++) {
            mean[0] += c->x[idx[e]] / (double)got;
            mean[1] += c->y[idx[e]] / (double)got;
            mean[2] += c->z[idx[e]] / (double)got;
        }
        for (size_t e = 0; e < got; e++) {
            double v[3] = {c->x[idx[e]] - mean[0], c->y[idx[e]] - mean[1],
                           c->z[idx[e]] - mean[2]};
            for (int a = 0; a < 3; a++)
                for (int b = 0; b < 3; b++) cov[3 * a + b] += v[a] * v[b] / (double)got;
        }
        normals_sym3_eig(cov, ev, vec);
        r[j] = sqrt(fmax(0, fmin(ev[0], fmin(ev[1], ev[2]))));
    }
    qsort(r, m, sizeof *r, cmp_double);
    *sigma = NOISE_MEDIAN_PER_QUANTILE * r[(size_t)(NOISE_QUANTILE * (double)m)];
    kd_free(t);
    frep_free(r);
    return 0;
}

/* Box axes with ax[0] = fixed (the primitive's normal or axis): the other two by PCA
 * in the perpendicular plane (the angle of its principal direction). */
static void axes_around(const double fixed[3], const frep_cloud *c, const uint32_t *idx,
                        size_t n, const double mean[3], double ax[3][3])
{
    double u[3], v[3];
    vec3_basis(fixed, u, v);
    double suu = 0, suv = 0, svv = 0;
    for (size_t j = 0; j < n; j++) {
        double w[3] = {c->x[idx[j]] - mean[0], c->y[idx[j]] - mean[1], c->z[idx[j]] - mean[2]};
        double pu = w[0] * u[0] + w[1] * u[1] + w[2] * u[2];
        double pv = w[0] * v[0] + w[1] * v[1] + w[2] * v[2];
        suu += pu * pu;
        suv += pu * pv;
        svv += pv * pv;
    }
    double th = 0.5 * atan2(2 * suv, suu - svv), cs = cos(th), sn = sin(th);
    for (int k = 0; k < 3; k++) {
        ax[0][k] = fixed[k];
        ax[1][k] = cs * u[k] + sn * v[k];
        ax[2][k] = -sn * u[k] + cs * v[k];
    }
}

/* Box axes by full PCA (spheres), largest variance first. */
static void axes_pca(const frep_cloud *c, const uint32_t *idx, size_t n, const double mean[3],
                     double ax[3][3])
{
    double cov[9] = {0};
    for (size_t j = 0; j < n; j++) {
        double w[3] = {c->x[idx[j]] - mean[0], c->y[idx[j]] - mean[1], c->z[idx[j]] - mean[2]};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) cov[3 * a + b] += w[a] * w[b];
    }
    double ev[3], vec[9];
    normals_sym3_eig(cov, ev, vec);
    for (int a = 0; a < 3; a++)
        for (int k = 0; k < 3; k++) ax[a][k] = vec[3 * (2 - a) + k];
}

void segment_fit_obb(prim *q, const frep_cloud *c, const uint32_t *idx, size_t n)
{
    double mean[3] = {0, 0, 0}, ax[3][3];
    q->has_obb = 0;
    if (n == 0) return;
    for (size_t j = 0; j < n; j++) {
        mean[0] += c->x[idx[j]] / (double)n;
        mean[1] += c->y[idx[j]] / (double)n;
        mean[2] += c->z[idx[j]] / (double)n;
    }
    if (q->type == PRIM_PLANE) axes_around(q->p, c, idx, n, mean, ax);
    else if (q->type != PRIM_SPHERE) axes_around(q->a, c, idx, n, mean, ax);
    else axes_pca(c, idx, n, mean, ax);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t j = 0; j < n; j++) {
        double w[3] = {c->x[idx[j]] - mean[0], c->y[idx[j]] - mean[1], c->z[idx[j]] - mean[2]};
        for (int a = 0; a < 3; a++) {
            double t = w[0] * ax[a][0] + w[1] * ax[a][1] + w[2] * ax[a][2];
            if (t < lo[a]) lo[a] = t;
            if (t > hi[a]) hi[a] = t;
        }
    }
    for (int k = 0; k < 3; k++) q->obb_c[k] = mean[k];
    for (int a = 0; a < 3; a++) {
        double mid = 0.5 * (lo[a] + hi[a]);
        for (int k = 0; k < 3; k++) q->obb_c[k] += mid * ax[a][k];
        q->obb_half[a] = 0.5 * (hi[a] - lo[a]);
        for (int k = 0; k < 3; k++) q->obb_axes[a][k] = ax[a][k];
    }
    q->has_obb = 1;
}

static int plane_dup(const prim *list, size_t n, const double nrm[3], double d, double eps)
{
    double cmin = cos(SEGMENT_DUP_PLANE_DEG * FREP_PI / 180.0);
    for (size_t i = 0; i < n; i++) {
        if (list[i].type != PRIM_PLANE) continue;
        double c = nrm[0] * list[i].p[0] + nrm[1] * list[i].p[1] + nrm[2] * list[i].p[2];
        if (c > cmin && fabs(d - list[i].r) <= eps) return 1;
        if (c < -cmin && fabs(d + list[i].r) <= eps) return 1;
    }
    return 0;
}

/* plane_dup among the fitted (not separating) planes of the list. */
static int fitted_plane_dup(const prim *list, size_t n, const double nrm[3], double d, double eps)
{
    for (size_t i = 0; i < n; i++)
        if (!list[i].separating && plane_dup(list + i, 1, nrm, d, eps)) return 1;
    return 0;
}

/* plane_dup among the constructed planes of the list. */
static int constructed_plane_dup(const prim *list, size_t n, const double nrm[3], double d,
                                 double eps)
{
    for (size_t i = 0; i < n; i++)
        if (list[i].constructed && plane_dup(list + i, 1, nrm, d, eps)) return 1;
    return 0;
}

int segment_add_separating(prim **prims, size_t *count, double eps)
{
    size_t n = *count, cap = n + 8, cnt = n;
    prim *v = frep_realloc(*prims, cap * sizeof *v);
    if (!v) return -1;
    for (size_t i = 0; i < n; i++) {
        prim q = v[i];
        if (q.type == PRIM_PLANE || q.separating || !q.has_obb) continue;
        for (int pass = 0; pass < 2; pass++) {
            prim add[6];
            int nadd = 0;
            if (pass == 0) {
                for (int a = 0; a < 3; a++)
                    for (int s = -1; s <= 1; s += 2) {
                        prim *p = &add[nadd++];
                        memset(p, 0, sizeof *p);
                        p->type = PRIM_PLANE;
                        for (int k = 0; k < 3; k++) p->p[k] = s * q.obb_axes[a][k];
                        double cn = p->p[0] * q.obb_c[0] + p->p[1] * q.obb_c[1] +
                                    p->p[2] * q.obb_c[2];
                        p->r = cn + q.obb_half[a];
                        p->separating = 1;
                    }
            } else if (q.type == PRIM_TORUS) {
                prim *p = &add[nadd++];
                memset(p, 0, sizeof *p);
                p->type = PRIM_CYLINDER;
                memcpy(p->p, q.p, sizeof q.p);
                memcpy(p->a, q.a, sizeof q.a);
                p->r = q.R;
                p->separating = 1;
            }
            for (int j = 0; j < nadd; j++) {
                if (add[j].type == PRIM_PLANE && plane_dup(v, cnt, add[j].p, add[j].r, eps))
                    continue;
                if (cnt == cap) {
                    cap *= 2;
                    prim *nv = frep_realloc(v, cap * sizeof *nv);
                    if (!nv) {
                        *prims = v;
                        return -1;
                    }
                    v = nv;
                }
                v[cnt++] = add[j];
            }
        }
    }
    *prims = v;
    *count = cnt;
    return 0;
}

/* The point of A's axis closest to B's axis into m; the distance between the axes. */
static double axes_meet(const prim *A, const prim *B, double m[3])
{
    double w[3], n[3];
    for (int k = 0; k < 3; k++) w[k] = B->p[k] - A->p[k];
    vec3_cross(A->a, B->a, n);
    double nn = vec3_dot(n, n);
    /* t along A: (w x b) . n / |n|^2 for lines p + t a and q + s b. */
    double wb[3];
    vec3_cross(w, B->a, wb);
    double t = vec3_dot(wb, n) / nn;
    for (int k = 0; k < 3; k++) m[k] = A->p[k] + t * A->a[k];
    return fabs(vec3_dot(w, n)) / sqrt(nn);
}

static int cap_of(const prim *A, const prim *B, double eps, prim *out)
{
    if (fabs(vec3_dot(A->a, B->a)) > sin(SEGMENT_MEET_DEG * FREP_PI / 180.0)) return 0;
    double m[3];
    if (!(axes_meet(A, B, m) <= eps)) return 0;
    double dA[3], dB[3];
    for (int k = 0; k < 3; k++) {
        dA[k] = m[k] - A->obb_c[k];
        dB[k] = m[k] - B->obb_c[k];
    }
    double tA = vec3_dot(dA, A->a), tB = vec3_dot(dB, B->a);
    /* Near an end of A (B's radius covers the cap), within B's length. */
    if (fabs(fabs(tA) - prim_axial_half(A)) > B->r + eps || fabs(tB) > prim_axial_half(B) + A->r + eps)
        return 0;
    memset(out, 0, sizeof *out);
    out->type = PRIM_PLANE;
    double s = tA >= 0 ? 1 : -1;
    for (int k = 0; k < 3; k++) out->p[k] = s * A->a[k];
    out->r = vec3_dot(out->p, m);
    out->separating = 1;
    out->constructed = PRIM_CONSTRUCTED_MEET;
    return 1;
}

int segment_add_constructed(prim **prims, size_t *count, double eps)
{
    size_t n = *count, cnt = n, most = 0;
    prim *v = *prims, q;
    /* Pass 0 counts the pairs that give a cap (room for all, allocated once); pass 1
     * adds the caps that are not duplicates. */
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            if (most == 0) return 0;
            v = frep_realloc(*prims, (n + most) * sizeof *v);
            if (!v) return -1;
            *prims = v;
        }
        for (size_t i = 0; i < n; i++)
            for (size_t j = 0; j < n; j++) {
                if (i == j || v[i].type != PRIM_CYLINDER || v[j].type != PRIM_CYLINDER ||
                    v[i].separating || v[j].separating || !v[i].has_obb || !v[j].has_obb ||
                    !cap_of(&v[i], &v[j], eps, &q))
                    continue;
                if (pass == 0) {
                    most++;
                    continue;
                }
                /* A fitted face there is the cap already; another constructed plane too.
                 * A separating plane there (a face of a corner sphere's box, which ends
                 * where the rails do) is not: the GA's pool and the caps are kept apart. */
                if (fitted_plane_dup(v, n, q.p, q.r, eps) || plane_dup(v + n, cnt - n, q.p, q.r, eps))
                    continue;
                v[cnt++] = q;
            }
    }
    *prims = v;
    *count = cnt;
    return 0;
}

/* ---- Inliers by label: the points of each fitted primitive ---------------------- */

/* The inliers of each fitted primitive (labels 0 .. np-1; -1: none), by a counting
 * sort: primitive j's points are order[start[j] .. start[j + 1]). */
typedef struct label_lists {
    size_t *start;
    uint32_t *order;
} label_lists;

static void label_lists_free(label_lists *L)
{
    frep_free(L->start);
    frep_free(L->order);
}

/* Returns -1 when out of memory (nothing to free then). */
static int label_lists_build(label_lists *L, const frep_cloud *c, const int32_t *label, size_t np)
{
    L->start = frep_calloc(np + 2, sizeof *L->start);
    L->order = frep_malloc((c->n ? c->n : 1) * sizeof *L->order);
    size_t *fill = frep_calloc(np + 1, sizeof *fill);
    if (!L->start || !L->order || !fill) {
        frep_free(fill);
        label_lists_free(L);
        return -1;
    }
    for (size_t i = 0; i < c->n; i++)
        if (label[i] >= 0) L->start[label[i] + 1]++;
    for (size_t j = 0; j < np; j++) L->start[j + 1] += L->start[j];
    for (size_t i = 0; i < c->n; i++)
        if (label[i] >= 0) L->order[L->start[label[i]] + fill[label[i]]++] = (uint32_t)i;
    frep_free(fill);
    return 0;
}

/* ---- Slabs closed at their faces' extent (segment_close_slabs) ------------------ */

/* The extent [*lo, *hi] along v of the inliers of fitted planes i and j. */
static void slab_extent(const frep_cloud *c, const label_lists *L, size_t i, size_t j,
                        const double v[3], double *lo, double *hi)
{
    *lo = HUGE_VAL;
    *hi = -HUGE_VAL;
    size_t face[2] = {i, j};
    for (int f = 0; f < 2; f++)
        for (size_t e = L->start[face[f]]; e < L->start[face[f] + 1]; e++) {
            uint32_t k = L->order[e];
            double t = v[0] * c->x[k] + v[1] * c->y[k] + v[2] * c->z[k];
            *lo = fmin(*lo, t);
            *hi = fmax(*hi, t);
        }
}

/* Whether fitted planes i and j face away from each other (a slab's two faces). */
static int slab_faces(const prim *v, size_t i, size_t j)
{
    double cn = cos(SEGMENT_MEET_DEG * FREP_PI / 180.0);
    return i != j && v[i].type == PRIM_PLANE && v[j].type == PRIM_PLANE && !v[i].separating &&
           !v[j].separating && v[i].has_obb && v[j].has_obb && vec3_dot(v[i].p, v[j].p) < -cn;
}

/* The plane that closes slab (i, j) across fitted plane q's normal at the end of the
 * faces' inliers opposite q, into *out; 0 when q bounds neither end (or is one of the
 * faces, or not across them). */
static int slab_close(const frep_cloud *c, const label_lists *L, const prim *v, size_t i,
                      size_t j, size_t q, double tol, prim *out)
{
    const prim *Q = &v[q];
    if (q == i || q == j || Q->type != PRIM_PLANE || Q->separating ||
        fabs(vec3_dot(Q->p, v[i].p)) > sin(SEGMENT_MEET_DEG * FREP_PI / 180.0))
        return 0;
    double lo, hi;
    slab_extent(c, L, i, j, Q->p, &lo, &hi);
    if (!(lo < hi)) return 0;
    double s;
    if (fabs(Q->r - hi) <= tol) s = -1;       /* Q at the far end: close the near one */
    else if (fabs(Q->r - lo) <= tol) s = 1;   /* Q at the near end: close the far one */
    else return 0;
    memset(out, 0, sizeof *out);
    out->type = PRIM_PLANE;
    for (int k = 0; k < 3; k++) out->p[k] = s * Q->p[k];
    out->r = s < 0 ? -lo : hi;
    out->separating = 1;
    out->constructed = PRIM_CONSTRUCTED_EXTENT;
    return 1;
}

int segment_close_slabs(prim **prims, size_t *count, const frep_cloud *c, const int32_t *label,
                        size_t nfitted, double tol)
{
    size_t n = *count, cnt = n, cap = n;
    prim *v = *prims, q;
    label_lists L;
    if (label_lists_build(&L, c, label, nfitted)) return -1;
    /* Each closing plane is added unless a listed plane, fitted or constructed (one
     * added before it included), stands for it already; the list grows as needed. */
    for (size_t i = 0; i < nfitted; i++)
        for (size_t j = i + 1; j < nfitted; j++) {
            if (!slab_faces(v, i, j)) continue;
            for (size_t k = 0; k < nfitted; k++) {
                if (!slab_close(c, &L, v, i, j, k, tol, &q) || fitted_plane_dup(v, n, q.p, q.r, tol) ||
                    constructed_plane_dup(v, cnt, q.p, q.r, tol))
                    continue;
                if (cnt == cap) {
                    size_t grown = 2 * cap + 4;
                    prim *w = frep_realloc(v, grown * sizeof *w);
                    if (!w) {
                        label_lists_free(&L);
                        *prims = v;
                        return -1;
                    }
                    v = w;
                    cap = grown;
                }
                v[cnt++] = q;
            }
        }
    label_lists_free(&L);
    *prims = v;
    *count = cnt;
    return 0;
}

/* Adapts the detector's progress reports to segment_config's. */
static void ransac_progress(void *user, const char *stage, size_t remaining, size_t total,
                            size_t nprims)
{
    const segment_config *cfg = user;
    cfg->progress(cfg->user, stage, total - remaining, total, nprims);
}

/* The settings the run uses, as reported in res: the configured ones, or defaults
 * scaled to the cloud (its diagonal, point spacing and count); -1 when out of memory. */
static int scaled_defaults(const frep_cloud *c, const segment_config *cfg, double diag,
                           segment_result *res, frep_error *err)
{
    res->diagonal = diag;
    /* Stopped already (--max-time or Ctrl-C during normal estimation): detection will
     * not run, so the noise and the spacing are not measured (two neighbour searches
     * over the cloud, each a fraction of a second past the deadline); the settings
     * reported are the diagonal's defaults. */
    int stopped = frep_cancelled(cfg->interrupt);
    if (cfg->epsilon > 0) {
        res->epsilon = cfg->epsilon;
    } else {
        if (!stopped && noise_sigma(c, &res->noise)) return frep_error_nomem(err);
        res->epsilon = fmin(SEGMENT_DEFAULT_EPSILON * diag,
                            fmax(SEGMENT_DEFAULT_EPSILON_MIN * diag,
                                 SEGMENT_EPSILON_SIGMAS * res->noise));
    }
    if (cfg->cluster > 0) {
        res->cluster = cfg->cluster;
    } else {
        double sp;
        sp = 0;
        if (!stopped && median_spacing(c, &sp)) return frep_error_nomem(err);
        res->cluster = fmax(SEGMENT_DEFAULT_CLUSTER * diag, SEGMENT_CLUSTER_SPACINGS * sp);
    }
    res->normal_deg = cfg->normal_deg > 0 ? cfg->normal_deg : SEGMENT_DEFAULT_NORMAL_DEG;
    res->probability = cfg->probability > 0 && cfg->probability < 1
                           ? cfg->probability : SEGMENT_DEFAULT_PROBABILITY;
    size_t mp = (size_t)(SEGMENT_DEFAULT_MIN_FRACTION * (double)c->n);
    res->min_points = cfg->min_points ? cfg->min_points
                                      : (mp > SEGMENT_MIN_POINTS_FLOOR ? mp : SEGMENT_MIN_POINTS_FLOOR);
    return 0;
}

/* The second phase's smallest support, once the normals are known: lower on a clean
 * cloud (noise measured, none or far below epsilon) with the file's normals.
 * Estimated normals blend across the edges of even a clean sample, and there shapes
 * of 10-20 points along them (thin cylinders) pass the small shapes' tests. */
static void small_support(const frep_cloud *c, const segment_config *cfg, segment_result *res)
{
    int clean = cfg->epsilon <= 0 && !ransac_noisy(res->noise, res->epsilon) &&
                !res->normals_estimated && !cfg->normals_estimated;
    size_t ms = (size_t)((clean ? SEGMENT_CLEAN_SMALL_FRACTION : SEGMENT_DEFAULT_SMALL_FRACTION) *
                         (double)c->n);
    if (ms < SEGMENT_MIN_POINTS_FLOOR) ms = SEGMENT_MIN_POINTS_FLOOR;
    if (cfg->min_points_small) ms = cfg->min_points_small;
    res->min_points_small = ms < res->min_points ? ms : res->min_points;
}

/* Normals: those of the file, normalized, unless there are none or some are zero;
 * then all are estimated. */
static int ensure_normals(frep_cloud *c, const segment_config *cfg, segment_result *res,
                          frep_error *err)
{
    if (c->has_normals) res->zero_normals = cloud_normalize_normals(c);
    if (c->has_normals && res->zero_normals == 0) return 0;
    if (cfg->progress) cfg->progress(cfg->user, "normals", 0, c->n, 0);
    normals_config nc = {cfg->knn ? cfg->knn : NORMALS_DEFAULT_K, cfg->nthreads, cfg->interrupt};
    if (normals_run(c, &nc, NULL) < 0)
        return frep_error_set(err, FREP_ENOMEM, "out of memory estimating normals");
    res->normals_estimated = 1;
    return 0;
}

/* The detection settings from the run's. */
static void detect_config(const segment_config *cfg, const segment_result *res,
                          ransac_config *rc)
{
    memset(rc, 0, sizeof *rc);
    rc->epsilon = res->epsilon;
    rc->noise = res->noise;
    rc->cos_normal = cos(res->normal_deg * FREP_PI / 180.0);
    rc->cluster = res->cluster;
    rc->min_points = res->min_points;
    rc->min_points_small = res->min_points_small;
    rc->probability = res->probability;
    rc->types = cfg->types ? cfg->types : (1u << PRIM__COUNT) - 1;
    rc->seed = cfg->seed;
    rc->nthreads = cfg->nthreads;
    rc->interrupt = cfg->interrupt;
    if (cfg->progress) {
        rc->progress = ransac_progress;
        rc->user = (void *)(uintptr_t)cfg;
    }
}

/* The oriented box of every fitted primitive from its inliers. Returns -1 when out of
 * memory. */
static int fit_boxes(const frep_cloud *c, prim *prims, size_t np, const int32_t *label)
{
    label_lists L;
    if (label_lists_build(&L, c, label, np)) return -1;
    for (size_t j = 0; j < np; j++)
        segment_fit_obb(&prims[j], c, L.order + L.start[j], L.start[j + 1] - L.start[j]);
    label_lists_free(&L);
    return 0;
}

/* No shape at all: an error that says why when it can. An epsilon below the noise
 * leaves every candidate's support in pieces; the measured noise gives the epsilon
 * the defaults would use. Frees res; returns -1 with err set. */
static int nothing_found(const frep_cloud *c, segment_result *res, frep_error *err)
{
    double sigma = res->noise, eps = res->epsilon;
    size_t mp = res->min_points;
    int rc = res->noise > 0 || noise_sigma(c, &sigma) == 0;
    segment_result_free(res);
    if (!rc) return frep_error_nomem(err);
    if (SEGMENT_EPSILON_SIGMAS * sigma > eps)
        return frep_error_set(err, FREP_EINPUT,
                              "no primitive found: epsilon %g is below the noise of the "
                              "cloud (about %g): try --epsilon %.3g or more",
                              eps, sigma, SEGMENT_EPSILON_SIGMAS * sigma);
    return frep_error_set(err, FREP_EINPUT,
                          "no primitive of at least %zu points found within epsilon %g "
                          "(noise about %g): try a larger --epsilon or a smaller --min-points",
                          mp, eps, sigma);
}

int segment_run(frep_cloud *c, const segment_config *cfg, segment_result *res, frep_error *err)
{
    memset(res, 0, sizeof *res);
    frep_error_init(err);
    if (c->n < RANSAC_MIN_CLOUD)
        return frep_error_set(err, FREP_EINPUT,
                              "too few points: %zu (segmentation needs at least %d)", c->n,
                              RANSAC_MIN_CLOUD);
    double diag = cloud_diagonal(c);
    if (!(diag > 0))
        return frep_error_set(err, FREP_EINPUT,
                              "all %zu points are the same point: nothing to segment", c->n);
    if (cloud_check_scale(c, NULL, err)) return -1;
    if (scaled_defaults(c, cfg, diag, res, err)) return -1;
    if (ensure_normals(c, cfg, res, err)) return -1;
    small_support(c, cfg, res);
    ransac_config rc;
    detect_config(cfg, res, &rc);
    ransac_result rr;
    if (ransac_detect(c, &rc, &rr, err)) return -1;
    res->draws = rr.draws;
    res->interrupted = rr.interrupted;
    res->label = rr.label;
    res->prims = rr.prims;
    res->nprims = res->nfitted = rr.nprims;
    for (size_t i = 0; i < c->n; i++) res->unassigned += rr.label[i] < 0;
    if (res->nfitted == 0 && !res->interrupted) return nothing_found(c, res, err);
    if (fit_boxes(c, res->prims, res->nprims, res->label)) {
        segment_result_free(res);
        return frep_error_nomem(err);
    }
    if (cfg->separating) {
        if (segment_add_separating(&res->prims, &res->nprims, res->epsilon) ||
            segment_add_constructed(&res->prims, &res->nprims, res->epsilon) ||
            segment_close_slabs(&res->prims, &res->nprims, c, res->label, res->nfitted,
                                res->cluster)) {
            segment_result_free(res);
            return frep_error_nomem(err);
        }
    }
    return 0;
}

/* ---- .hf primitive lists -------------------------------------------------------- */

int segment_write_hf(FILE *f, const prim *p, size_t n, const char *header, double scale)
{
    int exact = !(scale > 0) || !isfinite(scale);
    double qp = exact ? 0 : PRIM_POS_QUANTUM * scale, qd = exact ? 0 : PRIM_DIR_QUANTUM;
    if (header) {
        const char *s = header;
        while (*s) {
            const char *e = strchr(s, '\n');
            size_t l = e ? (size_t)(e - s) : strlen(s);
            fprintf(f, "-- %.*s\n", (int)l, s);
            s += l + (e ? 1 : 0);
        }
    }
    fputs("primitives(x[3], a[1])\n{\n", f);
    for (size_t i = 0; i < n; i++) {
        const prim *q = &p[i];
        fprintf(f, "  p%zu = ", i + 1);
        prim_write_call_scaled(f, q, scale);
        if (q->constructed)
            fprintf(f, ";  -- separating %s, constructed: %s\n", prim_type_name(q->type),
                    prim_constructed_why(q));
        else if (q->separating)
            fprintf(f, ";  -- separating %s\n", prim_type_name(q->type));
        else
            fprintf(f, ";  -- %s: %zu points, rms %.3g\n", prim_type_name(q->type), q->support,
                    q->rms);
        if (q->has_obb) {
            /* Centre, three axes, half sizes: groups of three separated by two blanks. */
            const double *v[5] = {q->obb_c, q->obb_axes[0], q->obb_axes[1], q->obb_axes[2],
                                  q->obb_half};
            fputs("  --   obb", f);
            for (int g = 0; g < 5; g++) {
                fputs(g ? " " : "", f);
                for (int k = 0; k < 3; k++) {
                    char buf[PRIM_NUM_BUF];
                    prim_format_number(buf, v[g][k], g == 0 || g == 4 ? qp : qd);
                    fprintf(f, " %s", buf);
                }
            }
            fputc('\n', f);
        }
    }
    /* A valid model so the file evaluates: the union of the fitted primitives. */
    fputs("  primitives = ", f);
    int any = 0;
    for (size_t i = 0; i < n; i++) {
        if (p[i].separating) continue;
        fprintf(f, "%sp%zu", any ? " | " : "", i + 1);
        any = 1;
    }
    if (!any) fputs("-1", f);
    fputs(";\n}\n", f);
    return ferror(f) ? -1 : 0;
}

/* ---- reading .hf primitive lists through the front end ----------------------------
 * The model is parsed by lang/ (ast_parse), so a list is any valid HyperFun file: the
 * primitives are its assignments `name = frX(x, c1, c2, ...)` with constant arguments,
 * in file order. The comments segment_write_hf adds (support, rms, "separating", the
 * "--   obb" box line after a call) are read from the source lines of those calls. */

typedef struct hf_call {
    const char *key;   /* lower-case name, as the front end keys calls */
    const char *name;  /* as written, for messages */
    prim_type type;
    int nargs;         /* constants after x */
} hf_call;

static const hf_call hf_calls[] = {
    {"frplane", "frPlane", PRIM_PLANE, 4},       {"frsphere", "frSphere", PRIM_SPHERE, 4},
    {"frcylinder", "frCylinder", PRIM_CYLINDER, 7}, {"frcone", "frCone", PRIM_CONE, 7},
    {"frtorus", "frTorus", PRIM_TORUS, 8},
};

/* One reading of a list: the primitives found so far with the source line of each and
 * the offset where its call ends (its comment follows). */
typedef struct hf_reader {
    const char *name, *src;
    size_t len;
    frep_error *err;
    prim *v;
    uint32_t *line;
    uint32_t *end;
    size_t n, cap;
} hf_reader;

/* The front end's first error, as "file:line:col: message". */
static void hf_diag(void *user, const frep_diag *d)
{
    if (d->severity == FREP_ERROR)
        frep_error_at(user, FREP_EINPUT, d->file, d->line, (int)d->col, "%s", d->message);
}

/* A constant argument: a number or a negated number. Returns -1 for anything else. */
static int hf_const(const ast_node *a, double *v)
{
    if (a->kind == AST_NUM) *v = a->num;
    else if (a->kind == AST_UNARY && a->op == '-' && a->a->kind == AST_NUM) *v = -a->a->num;
    else return -1;
    return isfinite(*v) ? 0 : -1;
}

/* The primitive of call k with constants a: axes and plane normals made unit (a
 * plane's offset with its normal). Returns -1 for a zero-length one. */
static int hf_prim_of(const hf_call *k, const double *a, prim *q)
{
    memset(q, 0, sizeof *q);
    q->type = k->type;
    memcpy(q->p, a, 3 * sizeof(double));
    if (q->type == PRIM_PLANE || q->type == PRIM_SPHERE) {
        q->r = a[3];
        if (q->type != PRIM_PLANE) return 0;
        double l0 = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        if (vec3_normalize(q->p)) return -1;
        q->r /= l0;
        return 0;
    }
    memcpy(q->a, a + 3, 3 * sizeof(double));
    if (q->type == PRIM_TORUS) {
        q->R = a[6];
        q->r = a[7];
    } else {
        q->r = a[6];
    }
    return vec3_normalize(q->a);
}

/* The primitive of an assignment's value, if it is a primitive call: 1 when found, 0
 * when the value is something else, -1 (error set) when the call is malformed. */
static int hf_call_prim(hf_reader *r, const ast_node *call, prim *q)
{
    const hf_call *k = NULL;
    for (size_t j = 0; j < sizeof hf_calls / sizeof *hf_calls && call->kind == AST_CALL; j++)
        if (strcmp(call->key, hf_calls[j].key) == 0) k = &hf_calls[j];
    if (!k) return 0;
    const ast_loc *at = &call->op_loc;
    const ast_node *x = call->list.n > 0 ? call->list.v[0] : NULL;
    if (!x || x->kind != AST_VAR || strcmp(x->key, "x") != 0)
        return frep_error_at(r->err, FREP_EINPUT, r->name, x ? x->loc.line : at->line,
                             (int)(x ? x->loc.col : at->col),
                             "expected 'x' as the first argument of %s()", k->name);
    if (call->list.n - 1 != (uint32_t)k->nargs)
        return frep_error_at(r->err, FREP_EINPUT, r->name, at->line, (int)at->col,
                             "%s needs %d numbers after x, got %u", k->name, k->nargs,
                             call->list.n - 1);
    double a[9];
    for (int j = 0; j < k->nargs; j++) {
        const ast_node *arg = call->list.v[j + 1];
        if (hf_const(arg, &a[j]))
            return frep_error_at(r->err, FREP_EINPUT, r->name, arg->loc.line, (int)arg->loc.col,
                                 "arguments of %s() must be numbers", k->name);
    }
    if (hf_prim_of(k, a, q))
        return frep_error_at(r->err, FREP_EINPUT, r->name, at->line, (int)at->col,
                             "zero-length %s", k->type == PRIM_PLANE ? "normal" : "axis");
    const char *why = prim_degenerate(q);
    if (why)
        return frep_error_at(r->err, FREP_EINPUT, r->name, at->line, (int)at->col,
                             "degenerate %s(): %s", k->name, why);
    return 1;
}

/* Append q, called at the given span, to the list; -1 when out of memory. */
static int hf_push(hf_reader *r, const prim *q, const ast_loc *loc)
{
    if (r->n == r->cap) {
        size_t cap = r->cap ? 2 * r->cap : 16;
        prim *nv = frep_realloc(r->v, cap * sizeof *nv);
        if (nv) r->v = nv;
        uint32_t *nl = nv ? frep_realloc(r->line, cap * sizeof *nl) : NULL;
        if (nl) r->line = nl;
        uint32_t *ne = nl ? frep_realloc(r->end, cap * sizeof *ne) : NULL;
        if (!ne) return frep_error_set(r->err, FREP_ENOMEM, "%s: out of memory", r->name);
        r->end = ne;
        r->cap = cap;
    }
    r->v[r->n] = *q;
    r->line[r->n] = loc->line;
    r->end[r->n] = loc->end;
    r->n++;
    return 0;
}

/* The primitives of every model's top-level assignments, in file order. */
static int hf_collect(hf_reader *r, const ast_file *f)
{
    for (uint32_t m = 0; m < f->nmodels; m++) {
        const ast_list *body = &f->models[m].body;
        for (uint32_t i = 0; i < body->n; i++) {
            const ast_node *st = body->v[i];
            if (st->kind != AST_ASSIGN || !st->a) continue;
            prim q;
            int got = hf_call_prim(r, st->a, &q);
            if (got < 0 || (got > 0 && hf_push(r, &q, &st->a->loc))) return -1;
        }
    }
    return 0;
}

/* Parse up to max comma/blank separated numbers from s; returns the count (max + 1 if
 * more) or -1 on a non-number. */
static int parse_nums(const char *s, const char *end, double *v, int max)
{
    int n = 0;
    for (;;) {
        while (s < end && (*s == ',' || isspace((unsigned char)*s))) s++;
        if (s >= end) return n;
        char buf[64];
        size_t l = 0;
        while (s + l < end && s[l] != ',' && !isspace((unsigned char)s[l])) {
            if (l + 1 >= sizeof buf) return -1;
            buf[l] = s[l];
            l++;
        }
        buf[l] = '\0';
        char *e;
        double t = strtod(buf, &e);
        if (*e || !isfinite(t)) return -1;
        if (n < max) v[n] = t;
        n++;
        if (n > max) return n;
        s += l;
    }
}

/* The comment after a call: "N points", "rms R" or "separating". */
static void hf_comment(prim *q, const char *cm)
{
    q->separating = strstr(cm, "separating") != NULL;
    q->constructed = !strstr(cm, "constructed") ? 0
                     : strstr(cm, "extent") ? PRIM_CONSTRUCTED_EXTENT : PRIM_CONSTRUCTED_MEET;
    const char *pts = strstr(cm, " points");
    if (pts) {
        const char *b = pts;
        while (b > cm && isdigit((unsigned char)b[-1])) b--;
        q->support = (size_t)strtoull(b, NULL, 10);
    }
    const char *rms = strstr(cm, "rms ");
    if (rms) q->rms = strtod(rms + 4, NULL);
}

/* A "--   obb" line: centre, three axes and half sizes of the primitive before it. */
static int hf_obb(hf_reader *r, prim *q, const char *s, size_t ln)
{
    double b[15];
    if (parse_nums(s + 8, s + strlen(s), b, 15) != 15)
        return frep_error_set(r->err, FREP_EINPUT, "%s:%zu: expected 15 numbers after 'obb'",
                              r->name, ln);
    memcpy(q->obb_c, b, 3 * sizeof(double));
    for (int a = 0; a < 3; a++) memcpy(q->obb_axes[a], b + 3 + 3 * a, 3 * sizeof(double));
    memcpy(q->obb_half, b + 12, 3 * sizeof(double));
    q->has_obb = 1;
    return 0;
}

/* The comments segment_write_hf puts on and after each call's line, line by line:
 * the current primitive is the last one called on or before the line. */
static int hf_metadata(hf_reader *r)
{
    const char *p = r->src, *end = r->src + r->len;
    size_t j = 0;
    for (size_t ln = 1; p < end; ln++) {
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        const char *lp = p;
        p = eol < end ? eol + 1 : end;
        while (j < r->n && r->line[j] <= ln) j++;
        if (j == 0) continue;
        prim *q = &r->v[j - 1];
        int on_call = r->line[j - 1] == ln;
        /* On the call's line only what follows the call is a comment. */
        const char *from = on_call ? r->src + r->end[j - 1] : lp;
        if (from > eol) from = eol;
        size_t l = (size_t)(eol - from);
        if (l >= HF_MAX_LINE)
            return frep_error_set(r->err, FREP_EINPUT, "%s:%zu: line too long", r->name, ln);
        char buf[HF_MAX_LINE];
        memcpy(buf, from, l);
        buf[l] = '\0';
        char *s = buf;
        while (isspace((unsigned char)*s)) s++;
        if (!on_call && strncmp(s, "--   obb", 8) == 0) {
            if (hf_obb(r, q, s, ln)) return -1;
        } else if (on_call) {
            char *cm = strstr(s, "--");
            if (cm) hf_comment(q, cm + 2);
        }
    }
    return 0;
}

static int parse_hf(const char *name, const char *text, size_t len, prim **out, size_t *n,
                    frep_error *err)
{
    hf_reader r = {name, text, len, err, NULL, NULL, NULL, 0, 0};
    arena A;
    arena_init(&A);
    diag_sink ds = {hf_diag, err, name, 0, 0, &A, 0};
    ast_file f;
    memset(&f, 0, sizeof f);
    int rc = -1;
    if (ast_parse(&A, name, text, len, &ds, &f) || ds.errors) {
        if (A.failed) frep_error_nomem(err);
        frep_error_set(err, FREP_EINPUT, "%s: cannot parse the primitive list", name);
    } else if (hf_collect(&r, &f) == 0 && hf_metadata(&r) == 0) {
        if (r.n == 0)
            frep_error_set(err, FREP_EINPUT,
                           "%s: no frPlane/frSphere/frCylinder/frCone/frTorus calls", name);
        else rc = 0;
    }
    arena_free(&A);
    frep_free(r.line);
    frep_free(r.end);
    if (rc) {
        frep_free(r.v);
        return -1;
    }
    *out = r.v;
    *n = r.n;
    return 0;
}

int segment_parse_prims(const char *name, const char *text, size_t len, int is_fit,
                        prim **out, size_t *n, frep_error *err)
{
    frep_error_init(err);
    *out = NULL;
    *n = 0;
    if (is_fit) return fitfile_parse(name, text, len, out, n, err);
    return parse_hf(name, text, len, out, n, err);
}

int segment_read_prims(const char *path, prim **out, size_t *n, frep_error *err)
{
    frep_error_init(err);
    frep_file f;
    frep_error fe;
    frep_error_init(&fe);
    if (frep_file_read(&f, path, SEGMENT_PRIMS_MAX_BYTES, 0, &fe)) {
        if (f.open_failed || fe.code == FREP_ELIMIT)
            return frep_error_set(err, fe.code, "cannot read %s: %s", path, fe.msg);
        return frep_error_set(err, fe.code, "cannot read %s", path);
        return -1;
    }
    size_t pl = strlen(path);
    int is_fit = pl >= 4 && strcmp(path + pl - 4, ".fit") == 0;
    int rc = segment_parse_prims(path, f.data, f.len, is_fit, out, n, err);
    frep_free(f.data);
    return rc;
}

/* normals.c - PCA normals and their consistent orientation (geom/normals.h).
 *
 * Per point: covariance of its k nearest neighbours, normal = eigenvector of the
 * smallest eigenvalue (OpenMP over points; each point is independent, so the result
 * does not depend on the thread count). Then Prim's algorithm over the k-NN graph with
 * weights 1 - |ni.nj| flips normals so neighbours agree.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "kdtree.h"
#include "linalg.h"
#include "normals.h"
#include "threads.h"

/* Jacobi sweeps for a 3x3 symmetric matrix: converges quadratically, 50 sweeps is far
 * beyond what double precision needs, and bounds the loop. */
#define JACOBI_MAX_SWEEPS 50
/* Covariances of neighbourhoods and patches: converged when the off-diagonal part is
 * at most 1e-17 of the diagonal (double precision at the matrix's own scale), or at
 * most 1e-300 for a matrix of zeros or of tiny entries (1.0000000000000002e-300 is the
 * double after 1e-300, so the solver's `off <` test stops at off <= 1e-300); only
 * pairs that are exactly zero are left unrotated (|apq| < DBL_TRUE_MIN). */
static const linalg_jacobi_stop pca_stop = {JACOBI_MAX_SWEEPS, 1.0000000000000002e-300,
                                            1e-17, DBL_TRUE_MIN};

void normals_sym3_eig(const double m[9], double ev[3], double vec[9])
{
    linalg_sym3_eig(m, &pca_stop, ev, vec);
}

/* Indexed binary min-heap over nodes with decrease-key, for Prim's algorithm. */
typedef struct iheap {
    uint32_t *heap;     /* node ids */
    uint32_t *pos;      /* position of a node in heap, UINT32_MAX when absent */
    double *key;
    size_t n;
} iheap;

static void ih_swap(iheap *h, size_t i, size_t j)
{
    uint32_t a = h->heap[i], b = h->heap[j];
    h->heap[i] = b;
    h->heap[j] = a;
    h->pos[b] = (uint32_t)i;
    h->pos[a] = (uint32_t)j;
}

/* Order by key, then node id so the tree does not depend on heap history. */
static int ih_less(const iheap *h, uint32_t a, uint32_t b)
{
    return h->key[a] < h->key[b] || (h->key[a] == h->key[b] && a < b);
}

static void ih_up(iheap *h, size_t i)
{
    while (i > 0) {
        size_t p = (i - 1) / 2;
        if (!ih_less(h, h->heap[i], h->heap[p])) break;
        ih_swap(h, i, p);
        i = p;
    }
}

static void ih_down(iheap *h, size_t i)
{
    for (;;) {
        size_t l = 2 * i + 1, r = l + 1, m = i;
        if (l < h->n && ih_less(h, h->heap[l], h->heap[m])) m = l;
        if (r < h->n && ih_less(h, h->heap[r], h->heap[m])) m = r;
        if (m == i) return;
        ih_swap(h, i, m);
        i = m;
    }
}

static void ih_push_or_decrease(iheap *h, uint32_t node, double key)
{
    if (h->pos[node] == UINT32_MAX) {
        h->key[node] = key;
        h->heap[h->n] = node;
        h->pos[node] = (uint32_t)h->n;
        h->n++;
        ih_up(h, h->n - 1);
    } else if (key < h->key[node]) {
        h->key[node] = key;
        ih_up(h, h->pos[node]);
    }
}

static uint32_t ih_pop(iheap *h)
{
    uint32_t top = h->heap[0];
    ih_swap(h, 0, h->n - 1);
    h->n--;
    h->pos[top] = UINT32_MAX;
    if (h->n) ih_down(h, 0);
    return top;
}

/* qsort has no user pointer in C11: sort (x, index) pairs instead. */
typedef struct xkey {
    double x;
    uint32_t i;
} xkey;

static int cmp_xkey(const void *a, const void *b)
{
    const xkey *p = a, *q = b;
    if (p->x > q->x) return -1;
    if (p->x < q->x) return 1;
    return (p->i > q->i) - (p->i < q->i);
}

/* The PCA normal of point i: the smallest-eigenvalue eigenvector of the covariance of
 * its k nearest neighbours, whose indices go to idx[0..k) (padded with i). */
static void pca_normal(frep_cloud *c, const kd_tree *t, size_t i, size_t k, uint32_t *idx)
{
    double d2[KD_MAX_K];
    double q[3] = {c->x[i], c->y[i], c->z[i]};
    size_t m = kd_knn(t, q, k, idx, d2);
    for (size_t j = m; j < k; j++) idx[j] = (uint32_t)i;
    double mean[3] = {0, 0, 0};
    for (size_t j = 0; j < m; j++) {
        mean[0] += c->x[idx[j]];
        mean[1] += c->y[idx[j]];
        mean[2] += c->z[idx[j]];
    }
    for (int d = 0; d < 3; d++) mean[d] /= (double)m;
    double cov[9] = {0};
    for (size_t j = 0; j < m; j++) {
        double v[3] = {c->x[idx[j]] - mean[0], c->y[idx[j]] - mean[1], c->z[idx[j]] - mean[2]};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) cov[3 * a + b] += v[a] * v[b];
    }
    double ev[3], vec[9];
    normals_sym3_eig(cov, ev, vec);
    c->nx[i] = vec[0];
    c->ny[i] = vec[1];
    c->nz[i] = vec[2];
}

/* Unoriented normals of every point (parallel: each point is independent); the k
 * neighbours of point i into nb[i k ..]. Returns -1 when out of memory. */
static int pca_normals(frep_cloud *c, size_t k, int nthreads, uint32_t *nb)
{
    kd_tree *t = kd_build(c->n, c->x, c->y, c->z);
    if (!t) return -1;
    long ln = (long)c->n;
#ifdef _OPENMP
#pragma omp parallel for schedule(static, 1024) num_threads(frep_threads(nthreads))
#else
    (void)nthreads;
#endif
    for (long li = 0; li < ln; li++) pca_normal(c, t, (size_t)li, k, nb + (size_t)li * k);
    kd_free(t);
    return 0;
}

/* The orientation pass: Prim's algorithm over the symmetric k-NN graph. */
typedef struct orienter {
    frep_cloud *c;
    size_t k;
    const uint32_t *nb;      /* k out-neighbours per point */
    size_t *rstart;          /* in-neighbours of i: rev[rstart[i] .. rstart[i + 1]) */
    uint32_t *rev;
    iheap h;
    uint32_t *parent;
    unsigned char *done;
    xkey *order;             /* points by decreasing x: the seeds */
} orienter;

/* Reverse edges in CSR form: the k-NN relation is not symmetric, and orientation must
 * cross edges both ways. */
static void reverse_edges(orienter *o)
{
    size_t n = o->c->n, k = o->k;
    for (size_t e = 0; e < n * k; e++) o->rstart[o->nb[e] + 1]++;
    for (size_t i = 0; i < n; i++) o->rstart[i + 1] += o->rstart[i];
    for (size_t e = 0; e < n * k; e++) o->rev[o->rstart[o->nb[e]]++] = (uint32_t)(e / k);
    for (size_t i = n; i > 0; i--) o->rstart[i] = o->rstart[i - 1];
    o->rstart[0] = 0;
}

static void flip(frep_cloud *c, size_t i)
{
    c->nx[i] = -c->nx[i];
    c->ny[i] = -c->ny[i];
    c->nz[i] = -c->nz[i];
}

/* Orient the component of seed: its normal towards +x, then each point as its tree
 * parent, along the minimum spanning tree of weights 1 - |ni.nj|. */
static void orient_component(orienter *o, uint32_t seed)
{
    frep_cloud *c = o->c;
    iheap *h = &o->h;
    if (c->nx[seed] < 0) flip(c, seed);
    o->parent[seed] = seed;
    ih_push_or_decrease(h, seed, 0.0);
    while (h->n) {
        uint32_t i = ih_pop(h);
        o->done[i] = 1;
        uint32_t p = o->parent[i];
        if (p != i && c->nx[i] * c->nx[p] + c->ny[i] * c->ny[p] + c->nz[i] * c->nz[p] < 0)
            flip(c, i);
        size_t nout = o->k, nin = o->rstart[i + 1] - o->rstart[i];
        for (size_t j = 0; j < nout + nin; j++) {
            uint32_t q = j < nout ? o->nb[(size_t)i * o->k + j] : o->rev[o->rstart[i] + (j - nout)];
            if (o->done[q] || q == i) continue;
            double w = 1.0 - fabs(c->nx[i] * c->nx[q] + c->ny[i] * c->ny[q] + c->nz[i] * c->nz[q]);
            uint32_t before = h->pos[q];
            double old = before == UINT32_MAX ? INFINITY : h->key[q];
            ih_push_or_decrease(h, q, w);
            if (w < old) o->parent[q] = i;
        }
    }
}

/* Consistent orientation, component by component, each from its point of largest x.
 * Returns -1 when out of memory. */
static int orient_normals(frep_cloud *c, size_t k, const uint32_t *nb)
{
    size_t n = c->n;
    orienter o = {c, k, nb, NULL, NULL, {NULL, NULL, NULL, 0}, NULL, NULL, NULL};
    o.h.heap = frep_malloc(n * sizeof *o.h.heap);
    o.h.pos = frep_malloc(n * sizeof *o.h.pos);
    o.h.key = frep_malloc(n * sizeof *o.h.key);
    o.parent = frep_malloc(n * sizeof *o.parent);
    o.done = frep_calloc(n, 1);
    o.order = frep_malloc(n * sizeof *o.order);
    o.rstart = frep_calloc(n + 1, sizeof *o.rstart);
    o.rev = frep_malloc(n * k * sizeof *o.rev);
    int rc = -1;
    if (o.h.heap && o.h.pos && o.h.key && o.parent && o.done && o.order && o.rstart && o.rev) {
        reverse_edges(&o);
        for (size_t i = 0; i < n; i++) {
            o.h.pos[i] = UINT32_MAX;
            o.order[i].x = c->x[i];
            o.order[i].i = (uint32_t)i;
        }
        qsort(o.order, n, sizeof *o.order, cmp_xkey);
        for (size_t s = 0; s < n; s++)
            if (!o.done[o.order[s].i]) orient_component(&o, o.order[s].i);
        rc = 0;
    }
    frep_free(o.h.heap);
    frep_free(o.h.pos);
    frep_free(o.h.key);
    frep_free(o.parent);
    frep_free(o.done);
    frep_free(o.order);
    frep_free(o.rstart);
    frep_free(o.rev);
    return rc;
}

int normals_estimate(frep_cloud *c, size_t k, int nthreads)
{
    size_t n = c->n;
    if (n == 0) return 0;
    if (k == 0) k = NORMALS_DEFAULT_K;
    if (k < 3) k = 3;
    if (k > KD_MAX_K) k = KD_MAX_K;
    if (k > n) k = n;
    if (!c->has_normals && cloud_add_normals(c)) return -1;
    uint32_t *nb = frep_malloc(n * k * sizeof *nb);
    int rc = nb && pca_normals(c, k, nthreads, nb) == 0 ? orient_normals(c, k, nb) : -1;
    frep_free(nb);
    return rc;
}

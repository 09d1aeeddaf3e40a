/* kdtree.c - static kd-tree for k-nearest-neighbour queries (geom/kdtree.h).
 *
 * Balanced by median splits on the widest axis, stored implicitly: node i covers a
 * contiguous range of the permuted points and has children 2i and 2i+1, so the tree is
 * a permutation plus one split record per node.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>

#include "alloc.h"
#include "kdtree.h"

typedef struct kd_split {
    double value;
    int dim;        /* 0..2; -1 for a leaf */
} kd_split;

struct kd_tree {
    size_t n;
    double *pts;        /* 3 * n, in tree order */
    uint32_t *id;       /* original index of tree-order point i */
    kd_split *nodes;    /* 1-based heap numbering; nnodes entries (index 0 unused) */
    size_t nnodes;
};

/* Hoare quickselect of the k-th point along dim within [lo, hi): puts it at k with
 * no larger key before and no smaller after. Copes with many equal keys (a cloud of one
 * repeated point) without quadratic time. */
static void select_kth(kd_tree *t, size_t lo, size_t hi, size_t k, int dim)
{
    double *p = t->pts;
    while (hi - lo > 1) {
        /* Classic Hoare scheme: with the pivot taken at the lower middle, the split j
         * satisfies lo <= j < hi - 1, so both parts shrink. */
        double piv = p[3 * (lo + (hi - lo - 1) / 2) + dim];
        size_t i = lo - 1, j = hi; /* lo - 1 may wrap; incremented before use */
        for (;;) {
            do i++; while (p[3 * i + dim] < piv);
            do j--; while (p[3 * j + dim] > piv);
            if (i >= j) break;
            for (int d = 0; d < 3; d++) {
                double tmp = p[3 * i + d];
                p[3 * i + d] = p[3 * j + d];
                p[3 * j + d] = tmp;
            }
            uint32_t ti = t->id[i];
            t->id[i] = t->id[j];
            t->id[j] = ti;
        }
        /* Now [lo, j] <= piv <= [j+1, hi) (Hoare's invariant with j < hi - 1). */
        if (k <= j) hi = j + 1;
        else lo = j + 1;
    }
}

static void build(kd_tree *t, size_t node, size_t lo, size_t hi)
{
    if (node >= t->nnodes) return;
    if (hi - lo <= KD_LEAF) {
        t->nodes[node].dim = -1;
        return;
    }
    double mn[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, mx[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
    for (size_t i = lo; i < hi; i++)
        for (int d = 0; d < 3; d++) {
            double v = t->pts[3 * i + d];
            if (v < mn[d]) mn[d] = v;
            if (v > mx[d]) mx[d] = v;
        }
    int dim = 0;
    for (int d = 1; d < 3; d++)
        if (mx[d] - mn[d] > mx[dim] - mn[dim]) dim = d;
    size_t mid = lo + (hi - lo) / 2;
    select_kth(t, lo, hi, mid, dim);
    t->nodes[node].dim = dim;
    t->nodes[node].value = t->pts[3 * mid + dim];
    build(t, 2 * node, lo, mid);
    build(t, 2 * node + 1, mid, hi);
}

kd_tree *kd_build(size_t n, const double *x, const double *y, const double *z)
{
    if (n == 0 || n > UINT32_MAX) return NULL;
    kd_tree *t = frep_calloc(1, sizeof *t);
    if (!t) return NULL;
    t->n = n;
    /* Leaves hold <= KD_LEAF points, so depth <= log2(n / KD_LEAF) + 2 levels. */
    size_t nn = 2;
    while (nn / 2 * KD_LEAF < n) nn *= 2;
    t->nnodes = 2 * nn;
    t->pts = frep_malloc(3 * n * sizeof *t->pts);
    t->id = frep_malloc(n * sizeof *t->id);
    t->nodes = frep_calloc(t->nnodes, sizeof *t->nodes);
    if (!t->pts || !t->id || !t->nodes) {
        kd_free(t);
        return NULL;
    }
    for (size_t i = 0; i < n; i++) {
        t->pts[3 * i] = x[i];
        t->pts[3 * i + 1] = y[i];
        t->pts[3 * i + 2] = z[i];
        t->id[i] = (uint32_t)i;
    }
    for (size_t i = 0; i < t->nnodes; i++) t->nodes[i].dim = -1;
    build(t, 1, 0, n);
    return t;
}

void kd_free(kd_tree *t)
{
    if (!t) return;
    frep_free(t->pts);
    frep_free(t->id);
    frep_free(t->nodes);
    frep_free(t);
}

/* Max-heap of the best k candidates so far, ordered by (d2, index). */
typedef struct knn_heap {
    size_t k, n;
    uint32_t *idx;
    double *d2;
} knn_heap;

static int worse(double da, uint32_t ia, double db, uint32_t ib)
{
    return da > db || (da == db && ia > ib);
}

static void heap_offer(knn_heap *h, double d, uint32_t id)
{
    size_t i;
    if (h->n < h->k) {
        i = h->n++;
        while (i > 0) {
            size_t p = (i - 1) / 2;
            if (!worse(d, id, h->d2[p], h->idx[p])) break;
            h->d2[i] = h->d2[p];
            h->idx[i] = h->idx[p];
            i = p;
        }
    } else {
        if (!worse(h->d2[0], h->idx[0], d, id)) return;
        i = 0;
        for (;;) {
            size_t l = 2 * i + 1, r = l + 1, m = i;
            double md = d;
            uint32_t mi = id;
            if (l < h->n && worse(h->d2[l], h->idx[l], md, mi)) m = l, md = h->d2[l], mi = h->idx[l];
            if (r < h->n && worse(h->d2[r], h->idx[r], md, mi)) m = r;
            if (m == i) break;
            h->d2[i] = h->d2[m];
            h->idx[i] = h->idx[m];
            i = m;
        }
    }
    h->d2[i] = d;
    h->idx[i] = id;
}

static void search(const kd_tree *t, size_t node, size_t lo, size_t hi, const double q[3],
                   knn_heap *h)
{
    if (node >= t->nnodes || t->nodes[node].dim < 0) {
        for (size_t i = lo; i < hi; i++) {
            const double *p = t->pts + 3 * i;
            double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
            heap_offer(h, dx * dx + dy * dy + dz * dz, t->id[i]);
        }
        return;
    }
    size_t mid = lo + (hi - lo) / 2;
    const kd_split *s = &t->nodes[node];
    double diff = q[s->dim] - s->value;
    if (diff < 0) {
        search(t, 2 * node, lo, mid, q, h);
        if (h->n < h->k || diff * diff <= h->d2[0]) search(t, 2 * node + 1, mid, hi, q, h);
    } else {
        search(t, 2 * node + 1, mid, hi, q, h);
        if (h->n < h->k || diff * diff <= h->d2[0]) search(t, 2 * node, lo, mid, q, h);
    }
}

size_t kd_knn(const kd_tree *t, const double q[3], size_t k, uint32_t *idx, double *d2)
{
    if (k > KD_MAX_K) k = KD_MAX_K;
    if (k > t->n) k = t->n;
    if (k == 0) return 0;
    knn_heap h = {k, 0, idx, d2};
    search(t, 1, 0, t->n, q, &h);
    /* Heap sort in place: repeatedly move the worst to the end. */
    size_t n = h.n;
    while (h.n > 1) {
        double d = h.d2[h.n - 1];
        uint32_t id = h.idx[h.n - 1];
        h.d2[h.n - 1] = h.d2[0];
        h.idx[h.n - 1] = h.idx[0];
        h.n--;
        size_t i = 0;
        for (;;) {
            size_t l = 2 * i + 1, r = l + 1, m = i;
            double md = d;
            uint32_t mi = id;
            if (l < h.n && worse(h.d2[l], h.idx[l], md, mi)) m = l, md = h.d2[l], mi = h.idx[l];
            if (r < h.n && worse(h.d2[r], h.idx[r], md, mi)) m = r;
            if (m == i) break;
            h.d2[i] = h.d2[m];
            h.idx[i] = h.idx[m];
            i = m;
        }
        h.d2[i] = d;
        h.idx[i] = id;
    }
    return n;
}

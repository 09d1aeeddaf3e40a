/* normals.c - robust normals and their consistent orientation (geom/normals.h).
 *
 * scale (noise, spacing -> k) -> per point: weighted PCA, then iteratively reweighted
 * by plane residuals (OpenMP over points; each point is independent, so the result
 * does not depend on the thread count) -> Prim's tree over the nearest-neighbour graph
 * orients the smooth (first-pass) normals -> each robust normal takes the side of its
 * smooth one -> each connected part is turned outward on the whole.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "cancel.h"
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

/* Scale selection: probe points (a fixed stride through the cloud, so the choice does
 * not depend on threads) give the spacing, the noise and the neighbourhood radii. */
#define NORMALS_PROBES 2000
/* Neighbours of the noise probe: a plane fit of 32 points leaves a residual close to
 * the noise (3 of 32 degrees of freedom taken by the plane) while its radius (about
 * 3 spacings) keeps the bias of curved surfaces small on most points. */
#define NORMALS_PROBE_K 32
/* The predicted median angular error of a plane fit of k points within radius r over
 * noise sigma: 2.35 sigma / (r sqrt(k)) radians (slope variance 4 sigma^2 / (k r^2) per
 * axis for a uniform disc; the median of the Rayleigh-distributed angle is 1.18 of
 * its scale).  The automatic k is the smallest that brings it under the target. */
#define NORMALS_ERROR_CONST 2.35
#define NORMALS_TARGET_RAD (2.0 * 3.14159265358979323846 / 180.0)
/* Reweighting passes after the first weighted fit: each halves or better the say of
 * points across an edge; three settle within the noise. */
#define NORMALS_IRLS_PASSES 3
/* Residual scale of the reweighting: this many noise deviations, and at least this
 * fraction of the spacing (clean and faceted samples have noise near zero). */
#define NORMALS_IRLS_SIGMAS 2.0
#define NORMALS_IRLS_MIN_SPACING 0.5
/* Weight of a link along the normals in the orientation graph's plain rule (0..2 added
 * to the 0..1 of normals that disagree): steers the tree around thin walls. */
#define NORMALS_SIDE_WEIGHT 0.5
/* Noise below this fraction of the point spacing: the cloud is clean (an exact sample,
 * a facetted mesh) and orientation uses the reflection rule on the robust normals;
 * above it the segment between two feet turns with the noise where two faces meet
 * (a foot lands past the edge), and the plain rule on the smooth normals is the
 * steadier one (tests/normals.sh: the wedge and the plate at 0.2% noise). */
#define NORMALS_REFLECT_MAX_NOISE 0.1
/* Points between two polls of the interrupt flag in the serial orientation pass. */
#define NORMALS_POLL_POINTS 4096

static const size_t knn_candidates[] = {12, 16, 20, 24, 32, 40, 48, 64, 80, 96, 128, 160, 192, 256};
#define NCAND (sizeof knn_candidates / sizeof knn_candidates[0])

void normals_config_init(normals_config *c)
{
    memset(c, 0, sizeof *c);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median_of(double *v, size_t n)
{
    if (n == 0) return 0;
    qsort(v, n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Weighted plane of the m points idx[] (weights w[]): unit normal and weighted mean.
 * Returns -1 when the weights vanish. */
static int weighted_plane(const frep_cloud *c, const uint32_t *idx, const double *w, size_t m,
                          double nrm[3], double mean[3])
{
    double sw = 0;
    mean[0] = mean[1] = mean[2] = 0;
    for (size_t j = 0; j < m; j++) {
        sw += w[j];
        mean[0] += w[j] * c->x[idx[j]];
        mean[1] += w[j] * c->y[idx[j]];
        mean[2] += w[j] * c->z[idx[j]];
    }
    if (!(sw > 0)) return -1;
    for (int d = 0; d < 3; d++) mean[d] /= sw;
    double cov[9] = {0};
    for (size_t j = 0; j < m; j++) {
        double v[3] = {c->x[idx[j]] - mean[0], c->y[idx[j]] - mean[1], c->z[idx[j]] - mean[2]};
        for (int a = 0; a < 3; a++)
            for (int b = a; b < 3; b++) cov[3 * a + b] += w[j] * v[a] * v[b];
    }
    cov[3] = cov[1];
    cov[6] = cov[2];
    cov[7] = cov[5];
    double ev[3], vec[9];
    normals_sym3_eig(cov, ev, vec);
    nrm[0] = vec[0];
    nrm[1] = vec[1];
    nrm[2] = vec[2];
    return 0;
}

/* Spacing, noise and the neighbourhood size from the probe points; k given (> 0)
 * is kept.  Returns -1 when out of memory. */
static int choose_scale(const frep_cloud *c, const kd_tree *t, size_t k, normals_info *info)
{
    size_t n = c->n, np = n < NORMALS_PROBES ? n : NORMALS_PROBES;
    size_t kmax = n < KD_MAX_K ? n : KD_MAX_K;
    double *sp = frep_malloc(np * sizeof *sp), *noise = frep_malloc(np * sizeof *noise);
    double *rad = frep_malloc(np * NCAND * sizeof *rad);
    uint32_t *idx = frep_malloc(KD_MAX_K * sizeof *idx);
    double *d2 = frep_malloc(KD_MAX_K * sizeof *d2), *w = frep_malloc(KD_MAX_K * sizeof *w);
    int rc = -1;
    if (sp && noise && rad && idx && d2 && w) {
        for (size_t s = 0; s < np; s++) {
            size_t i = (size_t)((double)s * (double)n / (double)np);
            double q[3] = {c->x[i], c->y[i], c->z[i]};
            size_t m = kd_knn(t, q, kmax, idx, d2);
            sp[s] = m > 1 ? sqrt(d2[1]) : 0;
            for (size_t a = 0; a < NCAND; a++) {
                size_t kk = knn_candidates[a] < m ? knn_candidates[a] : m;
                rad[a * np + s] = kk ? sqrt(d2[kk - 1]) : 0;
            }
            size_t mp = m < NORMALS_PROBE_K ? m : NORMALS_PROBE_K;
            double nrm[3], mean[3];
            for (size_t j = 0; j < mp; j++) w[j] = 1;
            noise[s] = 0;
            if (mp > 3 && weighted_plane(c, idx, w, mp, nrm, mean) == 0) {
                double ss = 0;
                for (size_t j = 0; j < mp; j++) {
                    double r = (c->x[idx[j]] - mean[0]) * nrm[0] + (c->y[idx[j]] - mean[1]) * nrm[1] +
                               (c->z[idx[j]] - mean[2]) * nrm[2];
                    ss += r * r;
                }
                noise[s] = sqrt(ss / (double)(mp - 3));
            }
        }
        info->spacing = median_of(sp, np);
        info->noise = median_of(noise, np);
        if (k == 0) {
            k = knn_candidates[NCAND - 1];
            for (size_t a = 0; a < NCAND; a++) {
                double r = median_of(rad + a * np, np);
                double kk = (double)knn_candidates[a];
                if (r > 0 && NORMALS_ERROR_CONST * info->noise / (r * sqrt(kk)) <= NORMALS_TARGET_RAD) {
                    k = knn_candidates[a];
                    break;
                }
            }
        }
        info->knn = k < kmax ? k : kmax;
        rc = 0;
    }
    frep_free(sp);
    frep_free(noise);
    frep_free(rad);
    frep_free(idx);
    frep_free(d2);
    frep_free(w);
    return rc;
}

/* Per-thread scratch of the fits. */
typedef struct fit_scratch {
    uint32_t idx[KD_MAX_K];
    double d2[KD_MAX_K], ws[KD_MAX_K], w[KD_MAX_K];
} fit_scratch;

/* The normals of point i: smooth (the Gaussian-weighted fit of its k neighbours) into
 * sm[3i..], robust (reweighted by residuals) into c's normal, with the foot of i on the
 * robust plane into sm[3 (n + i)..] (the point without its noise across the surface);
 * the first ko neighbours into nb[i ko ..] (padded with i). */
static void fit_point(frep_cloud *c, const kd_tree *t, size_t i, size_t k, size_t ko,
                      double scale, double *sm, uint32_t *nb, fit_scratch *f)
{
    double q[3] = {c->x[i], c->y[i], c->z[i]};
    size_t m = kd_knn(t, q, k, f->idx, f->d2);
    for (size_t j = 0; j < ko; j++) nb[(size_t)i * ko + j] = j < m ? f->idx[j] : (uint32_t)i;
    double h2 = m ? f->d2[m - 1] : 0;
    for (size_t j = 0; j < m; j++) f->ws[j] = h2 > 0 ? exp(-f->d2[j] / h2) : 1.0;
    double nrm[3] = {0, 0, 1}, mean[3] = {q[0], q[1], q[2]};
    if (weighted_plane(c, f->idx, f->ws, m, nrm, mean) == 0) {
        double *s = sm + 3 * i;
        s[0] = nrm[0];
        s[1] = nrm[1];
        s[2] = nrm[2];
        double inv = 1.0 / (2.0 * scale * scale);
        for (int pass = 0; pass < NORMALS_IRLS_PASSES && scale > 0; pass++) {
            for (size_t j = 0; j < m; j++) {
                double r = (c->x[f->idx[j]] - mean[0]) * nrm[0] + (c->y[f->idx[j]] - mean[1]) * nrm[1] +
                           (c->z[f->idx[j]] - mean[2]) * nrm[2];
                f->w[j] = f->ws[j] * exp(-r * r * inv);
            }
            double n2[3], m2[3];
            if (weighted_plane(c, f->idx, f->w, m, n2, m2)) break;
            memcpy(nrm, n2, sizeof nrm);
            memcpy(mean, m2, sizeof mean);
        }
    }
    double h = (q[0] - mean[0]) * nrm[0] + (q[1] - mean[1]) * nrm[1] + (q[2] - mean[2]) * nrm[2];
    double *foot = sm + 3 * (c->n + i);
    for (int d = 0; d < 3; d++) foot[d] = q[d] - h * nrm[d];
    if (m == 0) sm[3 * i] = 0, sm[3 * i + 1] = 0, sm[3 * i + 2] = 1;
    c->nx[i] = nrm[0];
    c->ny[i] = nrm[1];
    c->nz[i] = nrm[2];
}

/* Every point's normals (parallel: each point is independent).  Returns 1 when
 * interrupted. */
static int fit_all(frep_cloud *c, const kd_tree *t, size_t k, size_t ko, double scale,
                   double *sm, uint32_t *nb, const normals_config *cfg)
{
    long ln = (long)c->n;
    int stopped = 0;
#ifdef _OPENMP
#pragma omp parallel num_threads(frep_threads(cfg->nthreads)) reduction(| : stopped)
#endif
    {
        fit_scratch f;
#ifdef _OPENMP
#pragma omp for schedule(static, 256)
#endif
        for (long li = 0; li < ln; li++) {
            if (frep_cancelled(cfg->interrupt)) {
                stopped = 1;
                continue;
            }
            fit_point(c, t, (size_t)li, k, ko, scale, sm, nb, &f);
        }
    }
    return stopped;
}

/* The orientation pass: Prim's algorithm over the symmetric nearest-neighbour graph,
 * on the normals sm (their signs change; c's follow afterwards). */
typedef struct orienter {
    const frep_cloud *c;
    double *sm;              /* n normals, then the n feet (fit_point) */
    int reflect;             /* 1: the reflection rule (clean clouds); 0: the plain one */
    size_t k;
    const uint32_t *nb;      /* k out-neighbours per point */
    size_t *rstart;          /* in-neighbours of i: rev[rstart[i] .. rstart[i + 1]) */
    uint32_t *rev;
    iheap h;
    uint32_t *parent;
    unsigned char *done;
    uint32_t *comp;          /* connected part of each point */
    size_t ncomp;
    xkey *order;             /* points by decreasing x: the seeds */
    volatile sig_atomic_t *interrupt;
    size_t popped;
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

static void flip3(double *v)
{
    v[0] = -v[0];
    v[1] = -v[1];
    v[2] = -v[2];
}

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The normal of i reflected in the plane that bisects the segment between the feet
 * of i and q, into r.  On a circular arc through both feet (the osculating circle of
 * a smooth surface; two faces symmetric about their edge; the two walls of a thin
 * plate across it) the reflection is q's consistently oriented normal (Konig and
 * Gumhold 2009); along a flat face the segment lies in the tangent plane and r is
 * i's normal.  The feet, not the points, give the segment: on a noisy scan the noise
 * across the surface is as large as the spacing and would turn it at random. */
static void reflected(const orienter *o, uint32_t i, uint32_t q, double r[3])
{
    size_t n = o->c->n;
    const double *ni = o->sm + 3 * (size_t)i, *fi = o->sm + 3 * (n + i), *fq = o->sm + 3 * (n + q);
    double d[3] = {fq[0] - fi[0], fq[1] - fi[1], fq[2] - fi[2]}, d2 = dot3(d, d);
    double t = d2 > 0 ? 2.0 * dot3(ni, d) / d2 : 0;
    for (int k = 0; k < 3; k++) r[k] = ni[k] - t * d[k];
}

/* The weight of edge i-q.  Reflection rule: how far q's normal is from i's reflected
 * one (either way).  Across the tip of a thin wedge, where the two faces' normals are
 * nearly opposite, the plain angle between the normals is as small as along a face
 * (and their sign turns one face inside out); the reflection tells the two apart.
 * Plain rule (Hoppe et al.): normals that disagree, and a link along them (across a
 * thin wall rather than along the surface). */
static double edge_weight(const orienter *o, uint32_t i, uint32_t q)
{
    const double *ni = o->sm + 3 * (size_t)i, *nq = o->sm + 3 * (size_t)q;
    if (o->reflect) {
        double r[3];
        reflected(o, i, q, r);
        return 1.0 - fabs(dot3(r, nq));
    }
    const frep_cloud *c = o->c;
    double d[3] = {c->x[q] - c->x[i], c->y[q] - c->y[i], c->z[q] - c->z[i]};
    double len = sqrt(dot3(d, d));
    double side = len > 0 ? 0.5 * (fabs(dot3(d, ni)) + fabs(dot3(d, nq))) / len : 0;
    return 1.0 - fabs(dot3(ni, nq)) + NORMALS_SIDE_WEIGHT * side;
}

/* Orient the component of seed: its normal towards +x, then each point as its tree
 * parent, along the minimum spanning tree.  Returns 1 when interrupted. */
static int orient_component(orienter *o, uint32_t seed)
{
    iheap *h = &o->h;
    double *sm = o->sm;
    if (sm[3 * (size_t)seed] < 0) flip3(sm + 3 * (size_t)seed);
    o->parent[seed] = seed;
    ih_push_or_decrease(h, seed, 0.0);
    while (h->n) {
        if (++o->popped % NORMALS_POLL_POINTS == 0 && frep_cancelled(o->interrupt)) return 1;
        uint32_t i = ih_pop(h);
        o->done[i] = 1;
        o->comp[i] = (uint32_t)o->ncomp;
        uint32_t p = o->parent[i];
        double r[3] = {sm[3 * (size_t)p], sm[3 * (size_t)p + 1], sm[3 * (size_t)p + 2]};
        if (p != i && o->reflect) reflected(o, p, i, r);
        if (p != i && dot3(sm + 3 * (size_t)i, r) < 0) flip3(sm + 3 * (size_t)i);
        size_t nout = o->k, nin = o->rstart[i + 1] - o->rstart[i];
        for (size_t j = 0; j < nout + nin; j++) {
            uint32_t q = j < nout ? o->nb[(size_t)i * o->k + j] : o->rev[o->rstart[i] + (j - nout)];
            if (o->done[q] || q == i) continue;
            double w = edge_weight(o, i, q);
            uint32_t before = h->pos[q];
            double old = before == UINT32_MAX ? INFINITY : h->key[q];
            ih_push_or_decrease(h, q, w);
            if (w < old) o->parent[q] = i;
        }
    }
    o->ncomp++;
    return 0;
}

/* Each connected part turned so that sum (p - centre).n > 0 over its points, the centre
 * being the cloud's mean: outward for a closed surface (the sum is 3 times the enclosed
 * volume over the area per point), away from the part's inside for an open one.
 * Returns -1 when out of memory. */
static int orient_outward(orienter *o, normals_info *info)
{
    const frep_cloud *c = o->c;
    size_t n = c->n;
    double ctr[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        ctr[0] += c->x[i];
        ctr[1] += c->y[i];
        ctr[2] += c->z[i];
    }
    for (int d = 0; d < 3; d++) ctr[d] /= (double)n;
    double *sum = frep_calloc(o->ncomp, sizeof *sum);
    if (!sum) return -1;
    for (size_t i = 0; i < n; i++) {
        double v[3] = {c->x[i] - ctr[0], c->y[i] - ctr[1], c->z[i] - ctr[2]};
        sum[o->comp[i]] += dot3(v, o->sm + 3 * i);
    }
    for (size_t i = 0; i < n; i++)
        if (sum[o->comp[i]] < 0) flip3(o->sm + 3 * i);
    info->components = o->ncomp;
    for (size_t a = 0; a < o->ncomp; a++) info->flipped += sum[a] < 0;
    frep_free(sum);
    return 0;
}

/* Consistent orientation of sm, component by component, each from its point of largest
 * x, then outward.  Returns 0, 1 when interrupted, -1 when out of memory. */
static int orient_normals(const frep_cloud *c, double *sm, int reflect, size_t k, const uint32_t *nb,
                          const normals_config *cfg, normals_info *info)
{
    size_t n = c->n;
    orienter o = {c, sm, reflect, k, nb, NULL, NULL, {NULL, NULL, NULL, 0}, NULL, NULL, NULL, 0, NULL,
                  cfg->interrupt, 0};
    o.h.heap = frep_malloc(n * sizeof *o.h.heap);
    o.h.pos = frep_malloc(n * sizeof *o.h.pos);
    o.h.key = frep_malloc(n * sizeof *o.h.key);
    o.parent = frep_malloc(n * sizeof *o.parent);
    o.done = frep_calloc(n, 1);
    o.comp = frep_malloc(n * sizeof *o.comp);
    o.order = frep_malloc(n * sizeof *o.order);
    o.rstart = frep_calloc(n + 1, sizeof *o.rstart);
    o.rev = frep_malloc(n * k * sizeof *o.rev);
    int rc = -1;
    if (o.h.heap && o.h.pos && o.h.key && o.parent && o.done && o.comp && o.order && o.rstart &&
        o.rev) {
        reverse_edges(&o);
        for (size_t i = 0; i < n; i++) {
            o.h.pos[i] = UINT32_MAX;
            o.order[i].x = c->x[i];
            o.order[i].i = (uint32_t)i;
        }
        qsort(o.order, n, sizeof *o.order, cmp_xkey);
        rc = 0;
        for (size_t s = 0; s < n && rc == 0; s++)
            if (!o.done[o.order[s].i]) rc = orient_component(&o, o.order[s].i);
        if (rc == 0) rc = orient_outward(&o, info);
    }
    frep_free(o.h.heap);
    frep_free(o.h.pos);
    frep_free(o.h.key);
    frep_free(o.parent);
    frep_free(o.done);
    frep_free(o.comp);
    frep_free(o.order);
    frep_free(o.rstart);
    frep_free(o.rev);
    return rc;
}

int normals_run(frep_cloud *c, const normals_config *cfg, normals_info *info)
{
    normals_info dummy;
    if (!info) info = &dummy;
    memset(info, 0, sizeof *info);
    size_t n = c->n;
    if (n == 0) return 0;
    size_t k = cfg->knn;
    if (k > 0 && k < 3) k = 3;
    if (k > KD_MAX_K) k = KD_MAX_K;
    if (!c->has_normals && cloud_add_normals(c)) return -1;
    kd_tree *t = kd_build(n, c->x, c->y, c->z);
    if (!t) return -1;
    if (choose_scale(c, t, k, info)) {
        kd_free(t);
        return -1;
    }
    k = info->knn;
    size_t ko = k < NORMALS_ORIENT_K ? k : NORMALS_ORIENT_K;
    double scale = fmax(NORMALS_IRLS_SIGMAS * info->noise, NORMALS_IRLS_MIN_SPACING * info->spacing);
    uint32_t *nb = frep_malloc(n * ko * sizeof *nb);
    double *sm = frep_malloc(6 * n * sizeof *sm);
    int rc = -1;
    if (nb && sm) {
        rc = fit_all(c, t, k, ko, scale, sm, nb, cfg);
        /* Clean: the robust normals are oriented (reflection rule); else the smooth. */
        int reflect = info->noise < NORMALS_REFLECT_MAX_NOISE * info->spacing;
        if (rc == 0 && reflect)
            for (size_t i = 0; i < n; i++) {
                sm[3 * i] = c->nx[i];
                sm[3 * i + 1] = c->ny[i];
                sm[3 * i + 2] = c->nz[i];
            }
        if (rc == 0) rc = orient_normals(c, sm, reflect, ko, nb, cfg, info);
        if (rc == 0)
            for (size_t i = 0; i < n; i++) {
                double v[3] = {c->nx[i], c->ny[i], c->nz[i]};
                if (dot3(v, sm + 3 * i) < 0) {
                    c->nx[i] = -v[0];
                    c->ny[i] = -v[1];
                    c->nz[i] = -v[2];
                }
            }
    }
    if (rc == 1) info->interrupted = 1;
    kd_free(t);
    frep_free(nb);
    frep_free(sm);
    return rc;
}

int normals_estimate(frep_cloud *c, size_t k, int nthreads)
{
    normals_config cfg;
    normals_config_init(&cfg);
    cfg.knn = k;
    cfg.nthreads = nthreads;
    return normals_run(c, &cfg, NULL);
}

int normals_check_cloud(const frep_cloud *c, const char *name, int *planar, frep_error *err)
{
    frep_error_init(err);
    if (planar) *planar = 0;
    if (!name) name = "the cloud";
    size_t n = c->n;
    if (n < NORMALS_MIN_POINTS)
        return frep_error_set(err, FREP_EINPUT, "%s: too few points: %zu (at least %d needed)",
                              name, n, NORMALS_MIN_POINTS);
    double diag = cloud_diagonal(c);
    if (!(diag > 0))
        return frep_error_set(err, FREP_EINPUT, "%s: all %zu points are the same", name, n);
    double mean[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        mean[0] += c->x[i];
        mean[1] += c->y[i];
        mean[2] += c->z[i];
    }
    for (int d = 0; d < 3; d++) mean[d] /= (double)n;
    double cov[9] = {0};
    for (size_t i = 0; i < n; i++) {
        double v[3] = {(c->x[i] - mean[0]) / diag, (c->y[i] - mean[1]) / diag,
                       (c->z[i] - mean[2]) / diag};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) cov[3 * a + b] += v[a] * v[b] / (double)n;
    }
    double ev[3], vec[9];
    normals_sym3_eig(cov, ev, vec);
    double tol2 = NORMALS_FLAT_TOL * NORMALS_FLAT_TOL;
    if (ev[1] <= tol2)
        return frep_error_set(err, FREP_EINPUT, "%s: all %zu points lie on one line", name, n);
    if (planar) *planar = ev[0] <= tol2;
    return 0;
}

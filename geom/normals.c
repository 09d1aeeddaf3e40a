/* normals.c - robust normals and their consistent orientation (geom/normals.h).
 *
 * scale (noise, spacing -> k) -> per point: weighted PCA, then iteratively reweighted
 * by plane residuals (OpenMP over points; each point is independent, so the result
 * does not depend on the thread count) -> on noisy clouds, each point near an edge
 * takes the plane of a flatter neighbourhood that passes through it (shift_point) ->
 * Prim's tree over the nearest-neighbour graph orients the smooth (first-pass)
 * normals -> each robust normal takes the side of the smooth one where its plane came
 * from -> each connected part is turned outward on the whole -> patches checked
 * by ray parity (lines in parallel, votes summed in a fixed order), the rest oriented
 * from them.
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

/* What the per-point passes (fit_point, shift_point) read and write; each unpacks the
 * fields it uses at its top. */
typedef struct point_pass {
    frep_cloud *c;
    const kd_tree *t;
    size_t k, ko;            /* neighbours fitted; kept for the orientation */
    double scale;            /* the reweighting's scale, the shift's tolerance */
    double *sm, *res;        /* 3 n smooth normals then 3 n feet; residuals */
    uint32_t *nb, *kept;     /* n ko neighbours; n k neighbours (NULL: not kept) */
    double *out;             /* the shift's 6 n results */
    uint32_t *from;          /* the point whose plane each took */
} point_pass;

typedef void (*point_fn)(const point_pass *p, size_t i, fit_scratch *f);

/* fn on every point, in parallel (each point is independent).  Returns 1 when
 * interrupted. */
static int each_point(const point_pass *p, point_fn fn, const normals_config *cfg)
{
    long ln = (long)p->c->n;
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
            fn(p, (size_t)li, &f);
        }
    }
    return stopped;
}

/* The normals of point i: smooth (the Gaussian-weighted fit of its k neighbours) into
 * sm[3i..], robust (reweighted by residuals) into c's normal, with the foot of i on the
 * robust plane into sm[3 (n + i)..] (the point without its noise across the surface)
 * and the RMS distance of the neighbours from that plane, weighted in distance only,
 * into res[i] (a neighbourhood across an edge leaves more than the noise); the first
 * ko neighbours into nb[i ko ..] (padded with i), and all of them into kept[i k ..]
 * when kept is not NULL (for shift_point). */
static void fit_point(const point_pass *p, size_t i, fit_scratch *f)
{
    frep_cloud *c = p->c;
    size_t k = p->k, ko = p->ko;
    double scale = p->scale, *sm = p->sm, *res = p->res;
    uint32_t *nb = p->nb, *kept = p->kept;
    double q[3] = {c->x[i], c->y[i], c->z[i]};
    size_t m = kd_knn(p->t, q, k, f->idx, f->d2);
    for (size_t j = 0; j < ko; j++) nb[(size_t)i * ko + j] = j < m ? f->idx[j] : (uint32_t)i;
    if (kept) memcpy(kept + i * k, f->idx, m * sizeof *kept);
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
    double ss = 0, sw = 0;
    for (size_t j = 0; j < m; j++) {
        double r = (c->x[f->idx[j]] - mean[0]) * nrm[0] + (c->y[f->idx[j]] - mean[1]) * nrm[1] +
                   (c->z[f->idx[j]] - mean[2]) * nrm[2];
        ss += f->ws[j] * r * r;
        sw += f->ws[j];
    }
    res[i] = sw > 0 ? sqrt(ss / sw) : 0;
    double h = (q[0] - mean[0]) * nrm[0] + (q[1] - mean[1]) * nrm[1] + (q[2] - mean[2]) * nrm[2];
    double *foot = sm + 3 * (c->n + i);
    for (int d = 0; d < 3; d++) foot[d] = q[d] - h * nrm[d];
    if (m == 0) sm[3 * i] = 0, sm[3 * i + 1] = 0, sm[3 * i + 2] = 1;
    c->nx[i] = nrm[0];
    c->ny[i] = nrm[1];
    c->nz[i] = nrm[2];
}

/* Shifted neighbourhoods (noisy clouds). A point within a neighbourhood's radius of a
 * sharp edge fits a plane across both faces, and the reweighting keeps a tilt when the
 * edge cuts the neighbourhood near its middle: a face one or two radii wide (the end of
 * a thin slab) has such points all over, and its normals spread 10-45 degrees. A
 * neighbour farther into the face has a neighbourhood on the face alone, whose plane
 * passes through the point. So each point takes, among the robust planes of its k
 * neighbours that pass within tol of it and whose residual res (RMS distance of their
 * neighbourhood) is below NORMALS_SHIFT_GAIN of its own, the flattest one: its normal,
 * and the point's foot on it. On a smooth face or a curved surface the residuals are
 * all alike and nothing moves. Where two such planes more than
 * NORMALS_SHIFT_AMBIGUOUS_DEG apart pass through the point (within the noise of their
 * edge), it keeps its own: taking either face there puts a point on the wrong one half
 * the time, and strips along the edges then fit small cylinders. Reads the robust
 * normals and feet, writes into out (6 per point: normal, foot) and the point whose
 * plane it took into from[i] (its side is taken later from that point's smooth
 * normal: near a crevice's tip the point's own smooth normal lies between two faces
 * whose normals are 150 degrees apart), in parallel: each point is independent. */
#define NORMALS_SHIFT_GAIN 0.7
#define NORMALS_SHIFT_AMBIGUOUS_DEG 20.0
/* The k neighbours of every point are kept from the fit for the shift (half the
 * neighbour searches, which are most of the time) up to this many bytes of indices:
 * 256 MiB, half a million points at k = 128 (the automatic k of a 0.5%-noise scan is
 * 48-128), 1.4 million at 48. */
#define NORMALS_KEEP_MAX_BYTES ((size_t)256 << 20)
static void shift_point(const point_pass *ps, size_t i, fit_scratch *f)
{
    const frep_cloud *c = ps->c;
    size_t k = ps->k;
    double tol = ps->scale, *out = ps->out;
    const double *feet = ps->sm + 3 * c->n, *res = ps->res;
    const uint32_t *kept = ps->kept;
    uint32_t *from = ps->from;
    double q[3] = {c->x[i], c->y[i], c->z[i]};
    const uint32_t *idx = kept ? kept + i * k : f->idx;
    size_t m = kept ? (k < c->n ? k : c->n) : kd_knn(ps->t, q, k, f->idx, f->d2), best = i;
    double least = NORMALS_SHIFT_GAIN * res[i];
    for (size_t j = 0; j < m; j++) {
        size_t p = idx[j];
        f->w[j] = 0;
        if (!(res[p] < NORMALS_SHIFT_GAIN * res[i])) continue;
        const double *fp = feet + 3 * p;
        double h = (q[0] - fp[0]) * c->nx[p] + (q[1] - fp[1]) * c->ny[p] + (q[2] - fp[2]) * c->nz[p];
        if (!(fabs(h) <= tol)) continue;
        f->w[j] = 1;
        if (res[p] < least) {
            best = p;
            least = res[p];
        }
    }
    /* Two faces pass through the point (within the noise of their edge): undecided, the
     * point keeps its own plane. */
    double cosa = cos(NORMALS_SHIFT_AMBIGUOUS_DEG * 3.14159265358979323846 / 180.0);
    for (size_t j = 0; j < m && best != i; j++) {
        size_t p = idx[j];
        if (f->w[j] > 0 && fabs(c->nx[p] * c->nx[best] + c->ny[p] * c->ny[best] +
                                c->nz[p] * c->nz[best]) < cosa)
            best = i;
    }
    from[i] = (uint32_t)best;
    double nrm[3] = {c->nx[best], c->ny[best], c->nz[best]};
    if (nrm[0] * c->nx[i] + nrm[1] * c->ny[i] + nrm[2] * c->nz[i] < 0)
        for (int d = 0; d < 3; d++) nrm[d] = -nrm[d];
    const double *fb = feet + 3 * best;
    double h = (q[0] - fb[0]) * nrm[0] + (q[1] - fb[1]) * nrm[1] + (q[2] - fb[2]) * nrm[2];
    double *o = out + 6 * i;
    for (int d = 0; d < 3; d++) {
        o[d] = nrm[d];
        o[3 + d] = q[d] - h * nrm[d];
    }
}

/* Every point's shifted plane (shift_point), on the neighbours the fit kept (NULL:
 * searched again); the normals and feet replaced. Returns 1 when interrupted, -1 when
 * out of memory. */
static int shift_all(point_pass *p, const normals_config *cfg)
{
    frep_cloud *c = p->c;
    size_t n = c->n;
    double *out = frep_malloc(6 * n * sizeof *out), *feet = p->sm + 3 * n;
    if (!out) return -1;
    p->out = out;
    int stopped = each_point(p, shift_point, cfg);
    if (!stopped)
        for (size_t i = 0; i < n; i++) {
            const double *o = out + 6 * i;
            c->nx[i] = o[0];
            c->ny[i] = o[1];
            c->nz[i] = o[2];
            memcpy(feet + 3 * i, o + 3, 3 * sizeof *o);
        }
    frep_free(out);
    p->out = NULL;
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
static int grow_tree(orienter *o);

static int orient_component(orienter *o, uint32_t seed)
{
    double *sm = o->sm;
    if (sm[3 * (size_t)seed] < 0) flip3(sm + 3 * (size_t)seed);
    o->parent[seed] = seed;
    ih_push_or_decrease(&o->h, seed, 0.0);
    return grow_tree(o);
}

/* Prim's tree from the points in the heap (their own parents), each point popped
 * taking its parent's side.  Returns 1 when interrupted. */
static int grow_tree(orienter *o)
{
    iheap *h = &o->h;
    double *sm = o->sm;
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
                          const unsigned char *fixed, const normals_config *cfg, normals_info *info)
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
        if (fixed) {
            for (size_t i = 0; i < n; i++)
                if (fixed[i]) {
                    o.parent[i] = (uint32_t)i;
                    ih_push_or_decrease(&o.h, (uint32_t)i, 0.0);
                }
            rc = grow_tree(&o);
        } else {
            for (size_t s = 0; s < n && rc == 0; s++)
                if (!o.done[o.order[s].i]) rc = orient_component(&o, o.order[s].i);
            if (rc == 0) rc = orient_outward(&o, info);
        }
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

/* ---- Patches and their outside by ray parity --------------------------------------
 * One spanning tree carries the sign across every edge of a part, and one wrong
 * crossing turns a whole region inside out: where a face leaves another at a shallow
 * angle (a crevice of air, as where the cuboid stacks' turned cubes stand on their
 * plates) the unoriented normals turn by only that angle around the crevice's tip, and
 * under noise no local rule tells the tip from a gentle bend.  So a global test checks
 * the tree's result, patch by patch.  Patches: neighbours whose robust normals are
 * nearly parallel and whose feet lie on each other's plane are joined (most parallel
 * first, each patch within NORMALS_PATCH_DEG of its mean normal, so that no chain of
 * small turns leads around a tip or a bend).  Parity: the line through a point's foot
 * along its normal crosses a closed surface an even number of times besides at the
 * point, so the crossings on the outward side are even and those on the inward side odd
 * (a ray-parity test of inside and outside); the surface is the cloud's feet as discs
 * of radius NORMALS_SPLAT_SPACINGS point spacings on their planes.  A line whose two
 * counts do not add up to an odd number (a hole between the discs, a line grazing a
 * face, an open scan whose back is missing) does not vote.  A patch with enough votes
 * takes the sign they give; the points outside such patches take theirs from them
 * along a spanning tree, as before. */

/* Largest angle between the robust normals of two neighbours joined into one patch,
 * and between a patch's mean normal and a patch it absorbs: above the normals' error
 * at the noise the automatic k allows (2-4 degrees), below the 30 degrees of the
 * crevices the patches must keep apart. */
#define NORMALS_PATCH_DEG 12.0
/* Fewest points of a patch that votes: a patch of a few points is a fragment along
 * an edge, where the discs of two faces overlap. */
#define NORMALS_PATCH_MIN 24
/* Lines cast per patch (points of the patch taken at an even stride): a majority of
 * 16 outweighs the lines that pass through holes or along faces. */
#define NORMALS_PATCH_RAYS 16
/* Votes a patch needs, and the share of them that must agree, to take their sign. */
#define NORMALS_VOTE_MIN 4
#define NORMALS_VOTE_SHARE 0.7
/* Disc radius in point spacings: holes between random points on a surface cover
 * exp(-0.69 r^2 / s^2) of it, 0.2% at 3 spacings. */
#define NORMALS_SPLAT_SPACINGS 3.0
/* Hits along a line farther apart than this many spacings are two crossings (the two
 * walls of a thin plate, 3 spacings apart in tests/normals.sh, stay two). */
#define NORMALS_CROSS_GAP 0.5
/* A run of hits along a line counts as a crossing when it holds at least this share of
 * the hits of the line's own run (t = 0): a line meets as many discs of a sheet
 * whatever its angle, while the feet that noisy plane fits leave inside a thin wall
 * (the cup of tests/normals.sh at 1% noise: runs of 1-15 hits against 50-140) would
 * add crossings at random and turn the parity of the lines from its inner faces. */
#define NORMALS_RUN_MIN_SHARE 0.1
/* Grid cells at most (cells are made larger beyond): bounds the grid's memory. */
#define NORMALS_GRID_MAX_CELLS 4000000
/* Hits one line may gather; a line with more (along a face) does not vote. */
#define NORMALS_RAY_MAX_HITS 8192
/* Lines nearly in a disc's plane (|cos| below this) do not cross it. */
#define NORMALS_RAY_MIN_COS 0.05

/* Union-find with the parity of each point relative to its parent (1: opposite). */
typedef struct puf {
    uint32_t *up, *size;
    unsigned char *par;
} puf;

static uint32_t puf_find(puf *u, uint32_t i, int *parity)
{
    uint32_t r = i;
    int p = 0;
    while (u->up[r] != r) {
        p ^= u->par[r];
        r = u->up[r];
    }
    uint32_t x = i;
    int px = p;
    while (x != r) {
        uint32_t nx = u->up[x];
        int pn = px ^ u->par[x];
        u->up[x] = r;
        u->par[x] = (unsigned char)px;
        x = nx;
        px = pn;
    }
    *parity = p;
    return r;
}

/* A link between neighbours i and q, |cos| of their normals and its sign. */
typedef struct plink {
    double w;
    uint32_t a, b;
} plink;

static int cmp_plink(const void *x, const void *y)
{
    const plink *p = x, *q = y;
    double a = fabs(p->w), b = fabs(q->w);
    if (a != b) return a < b ? 1 : -1;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}

/* The grid of discs: cell (ix, iy, iz) holds the points whose disc's bounding sphere
 * meets it, in item[start[cell] .. start[cell + 1]). */
typedef struct dgrid {
    double lo[3], h, r;
    size_t dim[3];
    size_t *start;
    uint32_t *item;
} dgrid;

typedef struct voter {
    const frep_cloud *c;
    const double *feet;      /* 3 per point */
    const double *nrm;       /* 3 per point: the robust normals */
    dgrid g;
    double gap;
} voter;

static size_t cell_of(const dgrid *g, const double p[3], int d)
{
    double v = floor((p[d] - g->lo[d]) / g->h);
    if (v < 0) v = 0;
    if (v > (double)(g->dim[d] - 1)) v = (double)(g->dim[d] - 1);
    return (size_t)v;
}

/* Returns 0; 1 when the cloud has no extent for discs (r not positive: the spacing of
 * a cloud of duplicates; or cells beyond double range); -1 when out of memory. */
static int grid_build(voter *v, double r)
{
    const frep_cloud *c = v->c;
    size_t n = c->n;
    dgrid *g = &v->g;
    double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    g->lo[0] = g->lo[1] = g->lo[2] = INFINITY;
    for (size_t i = 0; i < n; i++)
        for (int d = 0; d < 3; d++) {
            g->lo[d] = fmin(g->lo[d], v->feet[3 * i + d] - r);
            hi[d] = fmax(hi[d], v->feet[3 * i + d] + r);
        }
    g->r = r;
    g->h = 2 * r;
    double vol = (hi[0] - g->lo[0]) * (hi[1] - g->lo[1]) * (hi[2] - g->lo[2]);
    if (vol / (g->h * g->h * g->h) > NORMALS_GRID_MAX_CELLS) g->h = cbrt(vol / NORMALS_GRID_MAX_CELLS);
    if (!(r > 0 && isfinite(vol) && g->h > 0 && isfinite(g->h))) return 1;
    size_t ncell = 1;
    for (int d = 0; d < 3; d++) {
        g->dim[d] = (size_t)((hi[d] - g->lo[d]) / g->h) + 1;
        ncell *= g->dim[d];
    }
    g->start = frep_calloc(ncell + 1, sizeof *g->start);
    if (!g->start) return -1;
    for (int pass = 0; pass < 2; pass++) {
        for (size_t i = 0; i < n; i++) {
            const double *f = v->feet + 3 * i;
            double a[3] = {f[0] - r, f[1] - r, f[2] - r}, b[3] = {f[0] + r, f[1] + r, f[2] + r};
            size_t a0 = cell_of(g, a, 0), a1 = cell_of(g, a, 1), a2 = cell_of(g, a, 2);
            size_t b0 = cell_of(g, b, 0), b1 = cell_of(g, b, 1), b2 = cell_of(g, b, 2);
            for (size_t x = a0; x <= b0; x++)
                for (size_t y = a1; y <= b1; y++)
                    for (size_t z = a2; z <= b2; z++) {
                        size_t cell = (x * g->dim[1] + y) * g->dim[2] + z;
                        if (pass == 0) g->start[cell + 1]++;
                        else g->item[g->start[cell]++] = (uint32_t)i;
                    }
        }
        if (pass == 0) {
            for (size_t a = 0; a < ncell; a++) g->start[a + 1] += g->start[a];
            g->item = frep_malloc((g->start[ncell] ? g->start[ncell] : 1) * sizeof *g->item);
            if (!g->item) return -1;
        } else {
            for (size_t a = ncell; a > 0; a--) g->start[a] = g->start[a - 1];
            g->start[0] = 0;
        }
    }
    return 0;
}

/* The vote of the line through point i's foot along its normal: +1 when the normal
 * points outward (its side crossed an even number of times, the other side an odd
 * number), -1 when inward, 0 when the counts do not add up to odd.  hits: scratch of
 * NORMALS_RAY_MAX_HITS. */
static int line_vote(const voter *v, size_t i, double *hits)
{
    const dgrid *g = &v->g;
    const double *o = v->feet + 3 * i, *d = v->nrm + 3 * i;
    /* The part of the line inside the grid's box. */
    double t0 = -INFINITY, t1 = INFINITY;
    for (int a = 0; a < 3; a++) {
        double lo = g->lo[a], hi = g->lo[a] + (double)g->dim[a] * g->h;
        if (fabs(d[a]) < 1e-300) continue;
        double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
        if (ta > tb) {
            double s = ta;
            ta = tb;
            tb = s;
        }
        t0 = fmax(t0, ta);
        t1 = fmin(t1, tb);
    }
    if (!(t0 < t1)) return 0;
    /* Amanatides-Woo traversal of the cells from t0. */
    double p[3] = {o[0] + t0 * d[0], o[1] + t0 * d[1], o[2] + t0 * d[2]};
    size_t cell[3];
    double tnext[3], tstep[3];
    int step[3];
    for (int a = 0; a < 3; a++) {
        cell[a] = cell_of(g, p, a);
        step[a] = d[a] > 0 ? 1 : d[a] < 0 ? -1 : 0;
        if (step[a] == 0) {
            tnext[a] = tstep[a] = INFINITY;
            continue;
        }
        double edge = g->lo[a] + (double)(cell[a] + (step[a] > 0)) * g->h;
        tnext[a] = (edge - o[a]) / d[a];
        tstep[a] = g->h / fabs(d[a]);
    }
    size_t nh = 0;
    double r2 = g->r * g->r;
    for (;;) {
        size_t id = (cell[0] * g->dim[1] + cell[1]) * g->dim[2] + cell[2];
        for (size_t e = g->start[id]; e < g->start[id + 1]; e++) {
            uint32_t q = g->item[e];
            const double *fq = v->feet + 3 * (size_t)q, *nq = v->nrm + 3 * (size_t)q;
            double den = dot3(d, nq);
            if (fabs(den) < NORMALS_RAY_MIN_COS) continue;
            double w[3] = {fq[0] - o[0], fq[1] - o[1], fq[2] - o[2]};
            double t = dot3(w, nq) / den;
            double x[3] = {o[0] + t * d[0] - fq[0], o[1] + t * d[1] - fq[1], o[2] + t * d[2] - fq[2]};
            if (dot3(x, x) >= r2) continue;
            if (nh == NORMALS_RAY_MAX_HITS) return 0;
            hits[nh++] = t;
        }
        int a = tnext[0] < tnext[1] ? (tnext[0] < tnext[2] ? 0 : 2) : (tnext[1] < tnext[2] ? 1 : 2);
        if (tnext[a] > t1) break;
        if ((step[a] < 0 && cell[a] == 0) || (step[a] > 0 && cell[a] + 1 >= g->dim[a])) break;
        cell[a] = step[a] > 0 ? cell[a] + 1 : cell[a] - 1;
        tnext[a] += tstep[a];
    }
    qsort(hits, nh, sizeof *hits, cmp_double);
    /* Crossings: runs of hits closer than the gap; the one holding t = 0 is the point's
     * own surface (own: its hits), and a run of fewer than NORMALS_RUN_MIN_SHARE of
     * those is no crossing. */
    size_t below = 0, above = 0, own = 0;
    for (size_t e = 0; e < nh;) {
        size_t f = e + 1;
        while (f < nh && hits[f] - hits[f - 1] <= v->gap) f++;
        if (!(hits[f - 1] < -v->gap * 0.5) && !(hits[e] > v->gap * 0.5)) own = f - e;
        e = f;
    }
    for (size_t e = 0; e < nh;) {
        size_t f = e + 1;
        while (f < nh && hits[f] - hits[f - 1] <= v->gap) f++;
        if ((double)(f - e) < NORMALS_RUN_MIN_SHARE * (double)own) {
            e = f;
            continue;
        }
        if (hits[f - 1] < -v->gap * 0.5) below++;
        else if (hits[e] > v->gap * 0.5) above++;
        e = f;
    }
    if (!own || (above + below) % 2 == 0) return 0;
    return above % 2 == 0 ? 1 : -1;
}

/* Patches into u: links between neighbours (nb, ko per point) whose robust normals
 * (nrm) are within NORMALS_PATCH_DEG and whose feet lie within tol of each other's
 * plane, strongest first, each join kept within NORMALS_PATCH_DEG of the patch's mean
 * normal (acc: the sums, at the roots). */
static void join_patches(const double *feet, const double *nrm, size_t n, size_t ko, const uint32_t *nb,
                         double tol, puf *u, double *acc, plink *links)
{
    size_t m = 0;
    double cosmax = cos(NORMALS_PATCH_DEG * 3.14159265358979323846 / 180.0);
    for (size_t i = 0; i < n; i++) {
        const double *ni = nrm + 3 * i;
        for (size_t j = 0; j < ko; j++) {
            uint32_t q = nb[i * ko + j];
            if (q == i) continue;
            const double *nq = nrm + 3 * (size_t)q;
            double d[3] = {feet[3 * (size_t)q] - feet[3 * i], feet[3 * (size_t)q + 1] - feet[3 * i + 1],
                           feet[3 * (size_t)q + 2] - feet[3 * i + 2]};
            double dot = dot3(ni, nq);
            if (fabs(dot) >= cosmax && fabs(dot3(d, ni)) <= tol && fabs(dot3(d, nq)) <= tol)
                links[m++] = (plink){dot, (uint32_t)i, q};
        }
    }
    qsort(links, m, sizeof *links, cmp_plink);
    for (size_t e = 0; e < m; e++) {
        int pa, pb;
        uint32_t ra = puf_find(u, links[e].a, &pa), rb = puf_find(u, links[e].b, &pb);
        if (ra == rb) continue;
        if (u->size[ra] < u->size[rb] || (u->size[ra] == u->size[rb] && ra > rb)) {
            uint32_t t = ra;
            ra = rb;
            rb = t;
        }
        int prb = (links[e].w < 0) ^ pa ^ pb;
        double *x = acc + 3 * (size_t)ra, *y = acc + 3 * (size_t)rb;
        double lx = sqrt(dot3(x, x)), ly = sqrt(dot3(y, y));
        if (!(lx > 0 && ly > 0) || fabs(dot3(x, y)) < cosmax * lx * ly) continue;
        for (int k = 0; k < 3; k++) x[k] += prb ? -y[k] : y[k];
        u->up[rb] = ra;
        u->par[rb] = (unsigned char)prb;
        u->size[ra] += u->size[rb];
    }
}

/* Ray-parity check of c's oriented normals (the block comment above); the points of
 * patches with a clear vote are set into fixed with their voted sign in c.  Returns 0,
 * 1 when interrupted, -1 when out of memory. */
static int vote_patches(frep_cloud *c, const double *feet, size_t ko, const uint32_t *nb, double tol,
                        double spacing, unsigned char *fixed, const normals_config *cfg)
{
    size_t n = c->n;
    voter v = {c, feet, NULL, {{0, 0, 0}, 0, 0, {0, 0, 0}, NULL, NULL}, NORMALS_CROSS_GAP * spacing};
    puf u = {frep_malloc(n * sizeof *u.up), frep_malloc(n * sizeof *u.size), frep_calloc(n, 1)};
    double *nrm = frep_malloc(3 * n * sizeof *nrm), *acc = frep_malloc(3 * n * sizeof *acc);
    plink *links = frep_malloc(n * ko * sizeof *links);
    size_t *first = frep_calloc(n + 1, sizeof *first);
    uint32_t *member = frep_malloc(n * sizeof *member), *ray = frep_malloc(n * sizeof *ray);
    signed char *vote = frep_malloc(n);
    int rc = -1;
    if (!(u.up && u.size && u.par && nrm && acc && links && first && member && ray && vote)) goto done;
    for (size_t i = 0; i < n; i++) {
        u.up[i] = (uint32_t)i;
        u.size[i] = 1;
        nrm[3 * i] = acc[3 * i] = c->nx[i];
        nrm[3 * i + 1] = acc[3 * i + 1] = c->ny[i];
        nrm[3 * i + 2] = acc[3 * i + 2] = c->nz[i];
    }
    join_patches(feet, nrm, n, ko, nb, tol, &u, acc, links);
    /* Each patch made consistent (its root's sign); members listed by root. */
    for (size_t i = 0; i < n; i++) {
        int p;
        uint32_t r = puf_find(&u, (uint32_t)i, &p);
        if (p) flip3(nrm + 3 * i);
        first[r + 1]++;
    }
    for (size_t r = 0; r < n; r++) first[r + 1] += first[r];
    for (size_t i = 0; i < n; i++) {
        member[first[u.up[i]]++] = (uint32_t)i;
    }
    for (size_t r = n; r > 0; r--) first[r] = first[r - 1];
    first[0] = 0;
    /* The lines: NORMALS_PATCH_RAYS points of each large enough patch. */
    size_t nray = 0;
    for (size_t r = 0; r < n; r++) {
        size_t m = first[r + 1] - first[r];
        if (m < NORMALS_PATCH_MIN) continue;
        for (size_t s = 0; s < NORMALS_PATCH_RAYS; s++)
            ray[nray++] = member[first[r] + (2 * s + 1) * m / (2 * NORMALS_PATCH_RAYS)];
    }
    v.nrm = nrm;
    int built = grid_build(&v, NORMALS_SPLAT_SPACINGS * spacing);
    if (built == 1) rc = 0;
    if (built) goto done;
    int stopped = 0;
    long lr = (long)nray;
#ifdef _OPENMP
#pragma omp parallel num_threads(frep_threads(cfg->nthreads)) reduction(| : stopped)
#endif
    {
        double *hits = frep_malloc(NORMALS_RAY_MAX_HITS * sizeof *hits);
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 16)
#endif
        for (long e = 0; e < lr; e++) {
            if (!hits || frep_cancelled(cfg->interrupt)) {
                stopped |= hits ? 1 : 2;
                continue;
            }
            vote[e] = (signed char)line_vote(&v, ray[e], hits);
        }
        frep_free(hits);
    }
    if (stopped & 2) goto done;
    rc = 1;
    if (stopped) goto done;
    /* Each patch's count, then its sign on its points. */
    for (size_t e = 0; e < nray;) {
        uint32_t r = u.up[ray[e]];
        long pro = 0, con = 0;
        size_t f = e;
        for (; f < nray && u.up[ray[f]] == r; f++) {
            pro += vote[f] > 0;
            con += vote[f] < 0;
        }
        e = f;
        if (pro + con < NORMALS_VOTE_MIN) continue;
        int sign = (double)pro >= NORMALS_VOTE_SHARE * (double)(pro + con) ? 1
                 : (double)con >= NORMALS_VOTE_SHARE * (double)(pro + con) ? -1 : 0;
        if (!sign) continue;
        for (size_t a = first[r]; a < first[r + 1]; a++) {
            uint32_t i = member[a];
            fixed[i] = 1;
            c->nx[i] = sign * nrm[3 * (size_t)i];
            c->ny[i] = sign * nrm[3 * (size_t)i + 1];
            c->nz[i] = sign * nrm[3 * (size_t)i + 2];
        }
    }
    rc = 0;
done:
    frep_free(u.up);
    frep_free(u.size);
    frep_free(u.par);
    frep_free(nrm);
    frep_free(acc);
    frep_free(links);
    frep_free(first);
    frep_free(member);
    frep_free(ray);
    frep_free(vote);
    frep_free(v.g.start);
    frep_free(v.g.item);
    return rc;
}

/* The ray-parity check of the oriented normals of c (vote_patches), then the points
 * outside voted patches oriented from those inside along a spanning tree with the same
 * rule as the first pass (sm: scratch of 3 n, then the feet).  Returns 0, 1 when
 * interrupted, -1 when out of memory. */
static int check_patches(frep_cloud *c, double *sm, int reflect, size_t ko, const uint32_t *nb, double tol,
                         double spacing, const normals_config *cfg, normals_info *info)
{
    size_t n = c->n;
    unsigned char *fixed = frep_calloc(n, 1);
    if (!fixed) return -1;
    int rc = vote_patches(c, sm + 3 * n, ko, nb, tol, spacing, fixed, cfg);
    if (rc == 0) {
        for (size_t i = 0; i < n; i++) {
            sm[3 * i] = c->nx[i];
            sm[3 * i + 1] = c->ny[i];
            sm[3 * i + 2] = c->nz[i];
        }
        rc = orient_normals(c, sm, reflect, ko, nb, fixed, cfg, info);
    }
    if (rc == 0)
        for (size_t i = 0; i < n; i++) {
            c->nx[i] = sm[3 * i];
            c->ny[i] = sm[3 * i + 1];
            c->nz[i] = sm[3 * i + 2];
        }
    frep_free(fixed);
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
    /* Stopped before the start (a second estimate after a cut one): not even the
     * tree (a quarter of a second on 50,000 points). */
    if (frep_cancelled(cfg->interrupt)) {
        info->interrupted = 1;
        return 1;
    }
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
    double *sm = frep_malloc(6 * n * sizeof *sm), *res = frep_malloc(n * sizeof *res);
    uint32_t *from = frep_malloc(n * sizeof *from);
    /* Clean: the robust normals are oriented (reflection rule); else the smooth.
     * Clean edges are crisp within the reweighting's scale and the residuals
     * measure the sampling, not the edges: the planes are shifted under noise only,
     * on the neighbours the fit found when they fit in NORMALS_KEEP_MAX_BYTES (and the
     * memory is there: else they are searched again, with the same result). */
    int reflect = info->noise < NORMALS_REFLECT_MAX_NOISE * info->spacing;
    uint32_t *kept = !reflect && n <= NORMALS_KEEP_MAX_BYTES / sizeof *kept / k
                         ? frep_malloc(n * k * sizeof *kept) : NULL;
    int rc = -1;
    if (nb && sm && res && from) {
        point_pass p = {c, t, k, ko, scale, sm, res, nb, kept, NULL, from};
        rc = each_point(&p, fit_point, cfg);
        for (size_t i = 0; i < n; i++) from[i] = (uint32_t)i;
        if (rc == 0 && !reflect) rc = shift_all(&p, cfg);
        if (rc == 0 && reflect)
            for (size_t i = 0; i < n; i++) {
                sm[3 * i] = c->nx[i];
                sm[3 * i + 1] = c->ny[i];
                sm[3 * i + 2] = c->nz[i];
            }
        if (rc == 0) rc = orient_normals(c, sm, reflect, ko, nb, NULL, cfg, info);
        if (rc == 0)
            for (size_t i = 0; i < n; i++) {
                double v[3] = {c->nx[i], c->ny[i], c->nz[i]};
                if (dot3(v, sm + 3 * (size_t)from[i]) < 0) {
                    c->nx[i] = -v[0];
                    c->ny[i] = -v[1];
                    c->nz[i] = -v[2];
                }
            }
        if (rc == 0) rc = check_patches(c, sm, reflect, ko, nb, 0.5 * scale, info->spacing, cfg, info);
    }
    if (rc == 1) info->interrupted = 1;
    kd_free(t);
    frep_free(nb);
    frep_free(sm);
    frep_free(res);
    frep_free(from);
    frep_free(kept);
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

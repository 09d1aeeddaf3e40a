/* ransac.c - efficient RANSAC primitive detection (segment/ransac.h).
 *
 * Schnabel, Wahl, Klein, "Efficient RANSAC for point-cloud shape detection" (2007):
 * minimal samples drawn locally through an octree (here: points sorted by Morton code,
 * so an octree cell is a contiguous range), candidates scored on growing random
 * subsets with confidence intervals, the best one extracted once the probability of
 * having missed a better one is small, restricted to its largest connected component
 * in the parameter domain and refitted on Euclidean distance.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "cancel.h"
#include "rng.h"
#include "normals.h"
#include "ransac.h"
#include "threads.h"
#include "util.h"
#include "vec3.h"

/* Octree depth for localized sampling: 10 levels = cells of 1/1024 of the box side,
 * finer than any useful sampling neighbourhood. */
#define OCT_LEVELS 10
/* Points in the first scoring subset; later subsets double. Small enough that scoring
 * a fresh candidate is cheap, large enough for a first estimate. */
#define SUBSET_FIRST 512
/* Most scoring subsets (doubling from SUBSET_FIRST covers 2^31 points). */
#define MAX_SUBSETS 40
/* Point tests below which a loop runs on one thread: starting a parallel region costs
 * more than this work, and idle OpenMP threads spin, which on a loaded machine takes
 * CPU from the working one. */
#define PAR_MIN_WORK 65536
/* Minimal samples drawn per round before the acceptance test. */
#define DRAWS_PER_ROUND 64
/* Candidates kept alive at once: older, weaker ones are dropped beyond this. */
#define MAX_POOL 1024
/* Rivals of the best candidate refined per step (see the main loop). */
#define REFINE_TOP 4
/* Points per minimal sample (the torus needs four). */
#define SAMPLE_SIZE 4
/* Attempts to find distinct live points in an octree cell for one sample. */
#define SAMPLE_TRIES 16
/* Points used by a least-squares refit: an evenly spaced subset beyond this keeps the
 * refit of huge patches fast without changing the estimate materially. */
#define REFIT_MAX_POINTS 10000
/* Levenberg-Marquardt iterations per refit. */
#define LM_MAX_ITER 60
/* ... and the relative cost decrease below which it has converged: parameters then
 * move by about sqrt(1e-10) of the noise, far below anything the output shows. */
#define LM_REL_STOP 1e-10
/* ... counted only once the damping is this small: with heavy damping the steps are
 * tiny however far the minimum is. */
#define LM_LAMBDA_CONVERGED 1e-2
/* Smallest damping: the point on an axis (and an axis' length) is free, so the normal
 * equations are singular and an undamped step may run off along those directions. */
#define LM_LAMBDA_MIN 1e-6
/* Damping increases (x10 each) tried per iteration before giving up: from
 * LM_LAMBDA_MIN up to about 1e14, i.e. down to a plain gradient step. */
#define LM_TRIES 20
/* Cells per axis of the connectivity bitmap; the cell grows past the configured
 * cluster size when a patch would need more (ids must fit in 64 bits). */
#define BITMAP_MAX_CELLS_AXIS (1u << 20)
/* Cone half-angles outside [CONE_MIN_ANGLE, pi/2 - CONE_MIN_ANGLE] are degenerate
 * (a cylinder or a plane describes the data better). */
#define CONE_MIN_ANGLE (2.0 * FREP_PI / 180.0)
/* Curved primitives with radii above this many box diagonals are planes in disguise. */
#define MAX_RADIUS_DIAGONALS 2.0

/* ---- small vector and random helpers --------------------------------------- */

/* The shared generator (runtime/rng.h) under this file's short names. */
typedef frep_rng rng;
static void rng_seed(rng *r, uint64_t seed) { frep_rng_seed(r, seed); }
static uint64_t rng_next(rng *r) { return frep_rng_next(r); }

/* Uniform integer in [0, n), n > 0 (modulo bias is negligible for n << 2^64). */
static size_t rng_below(rng *r, size_t n) { return (size_t)(rng_next(r) % n); }
static double rng_unit(rng *r) { return frep_rng_unit(r); }

static void point(const frep_cloud *c, size_t i, double p[3])
{
    p[0] = c->x[i];
    p[1] = c->y[i];
    p[2] = c->z[i];
}

static void normal(const frep_cloud *c, size_t i, double n[3])
{
    n[0] = c->nx[i];
    n[1] = c->ny[i];
    n[2] = c->nz[i];
}

/* Is point i an inlier of q: within eps and its normal within the angle? */
static int compatible(const prim *q, const frep_cloud *c, size_t i, double eps, double cosn)
{
    double p[3], g[3];
    point(c, i, p);
    double f = prim_eval(q, p, g);
    if (!(fabs(f) <= eps)) return 0;
    double gl = vec3_len(g);
    double d = c->nx[i] * g[0] + c->ny[i] * g[1] + c->nz[i] * g[2];
    return fabs(d) >= cosn * gl && gl > 0;
}

/* The test of compatible() for many points: the type's formula with its constants
 * hoisted (no gradient normalization, no call per point). Unit axes and normals. */
typedef struct kern {
    prim_type t;
    double p[3], a[3], r, R, s, c; /* s, c: sine and cosine of a cone's half-angle */
    double eps, cosn;
} kern;

static void kern_init(kern *k, const prim *q, double eps, double cosn)
{
    k->t = q->type;
    memcpy(k->p, q->p, sizeof k->p);
    memcpy(k->a, q->a, sizeof k->a);
    k->r = q->r;
    k->R = q->R;
    k->s = q->type == PRIM_CONE ? sin(q->r) : 0;
    k->c = q->type == PRIM_CONE ? cos(q->r) : 0;
    k->eps = eps;
    k->cosn = cosn;
}

static inline int kern_test(const kern *k, const double x[3], const double nv[3])
{
    if (k->t == PRIM_PLANE) {
        double f = k->r - vec3_dot(k->p, x);
        return fabs(f) <= k->eps && fabs(vec3_dot(k->p, nv)) >= k->cosn;
    }
    double v[3];
    vec3_sub(x, k->p, v);
    if (k->t == PRIM_SPHERE) {
        double l = vec3_len(v);
        return fabs(k->r - l) <= k->eps && l > 0 && fabs(vec3_dot(v, nv)) >= k->cosn * l;
    }
    double h = vec3_dot(v, k->a), rho2 = vec3_dot(v, v) - h * h;
    double rho = sqrt(rho2 > 0 ? rho2 : 0);
    if (!(rho > 0)) return 0;
    double an = vec3_dot(k->a, nv), wn = vec3_dot(v, nv) - h * an; /* w = v - h a, the radial part */
    switch (k->t) {
    case PRIM_CYLINDER:
        return fabs(k->r - rho) <= k->eps && fabs(wn) >= k->cosn * rho;
    case PRIM_CONE:
        return fabs(h * k->s - rho * k->c) <= k->eps &&
               fabs(k->s * an * rho - k->c * wn) >= k->cosn * rho;
    case PRIM_TORUS: {
        double dr = rho - k->R, l = sqrt(dr * dr + h * h);
        return fabs(k->r - l) <= k->eps && l > 0 &&
               fabs(dr * wn + h * an * rho) >= k->cosn * l * rho;
    }
    case PRIM_PLANE: case PRIM_SPHERE: case PRIM__COUNT: break;
    }
    return 0;
}

/* ---- candidates from minimal samples --------------------------------------- */

/* Closest points of lines p1 + t d1 and p2 + s d2; returns -1 when parallel. */
static int line_closest(const double p1[3], const double d1[3], const double p2[3],
                        const double d2[3], double m[3])
{
    double w[3];
    vec3_sub(p1, p2, w);
    double a = vec3_dot(d1, d1), b = vec3_dot(d1, d2), cc = vec3_dot(d2, d2), d = vec3_dot(d1, w), e = vec3_dot(d2, w);
    double den = a * cc - b * b;
    if (!(fabs(den) > 1e-9 * a * cc)) return -1;
    double t = (b * e - cc * d) / den, s = (a * e - b * d) / den;
    for (int k = 0; k < 3; k++) m[k] = 0.5 * (p1[k] + t * d1[k] + p2[k] + s * d2[k]);
    return 0;
}

/* Circle through three points: centre, unit normal and radius; -1 if collinear. */
static int circle3(const double a3[3], const double b3[3], const double c3[3], double ctr[3],
                   double nrm[3], double *rad)
{
    double a[3], b[3], axb[3];
    vec3_sub(a3, c3, a);
    vec3_sub(b3, c3, b);
    vec3_cross(a, b, axb);
    double l2 = vec3_dot(axb, axb);
    if (!(l2 > 1e-24 * vec3_dot(a, a) * vec3_dot(b, b)) || l2 == 0) return -1;
    double t[3], u[3];
    for (int k = 0; k < 3; k++) t[k] = vec3_dot(a, a) * b[k] - vec3_dot(b, b) * a[k];
    vec3_cross(t, axb, u);
    for (int k = 0; k < 3; k++) ctr[k] = c3[k] + u[k] / (2.0 * l2);
    for (int k = 0; k < 3; k++) nrm[k] = axb[k];
    vec3_normalize(nrm);
    double d[3];
    vec3_sub(a3, ctr, d);
    *rad = vec3_len(d);
    return 0;
}

/* Solve the 3x3 system m x = b (Cramer); -1 when singular. */
static int solve3(const double m[3][3], const double b[3], double x[3])
{
    double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                 m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                 m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if (!(fabs(det) > 1e-12)) return -1;
    for (int k = 0; k < 3; k++) {
        double t[3][3];
        memcpy(t, m, sizeof t);
        for (int r = 0; r < 3; r++) t[r][k] = b[r];
        x[k] = (t[0][0] * (t[1][1] * t[2][2] - t[1][2] * t[2][1]) -
                t[0][1] * (t[1][0] * t[2][2] - t[1][2] * t[2][0]) +
                t[0][2] * (t[1][0] * t[2][1] - t[1][1] * t[2][0])) / det;
    }
    return 0;
}

typedef struct sample {
    double p[SAMPLE_SIZE][3], n[SAMPLE_SIZE][3];
} sample;

static int make_plane(const sample *s, prim *q)
{
    double u[3], v[3], n[3];
    vec3_sub(s->p[1], s->p[0], u);
    vec3_sub(s->p[2], s->p[0], v);
    vec3_cross(u, v, n);
    if (vec3_normalize(n)) return -1;
    if (vec3_dot(n, s->n[0]) < 0) for (int k = 0; k < 3; k++) n[k] = -n[k];
    q->type = PRIM_PLANE;
    memcpy(q->p, n, sizeof n);
    q->r = vec3_dot(n, s->p[0]);
    return 0;
}

static int make_sphere(const sample *s, prim *q)
{
    double c[3];
    if (line_closest(s->p[0], s->n[0], s->p[1], s->n[1], c)) return -1;
    double d0[3], d1[3];
    vec3_sub(s->p[0], c, d0);
    vec3_sub(s->p[1], c, d1);
    q->type = PRIM_SPHERE;
    memcpy(q->p, c, sizeof c);
    q->r = 0.5 * (vec3_len(d0) + vec3_len(d1));
    return 0;
}

static int make_cylinder(const sample *s, prim *q)
{
    double a[3];
    vec3_cross(s->n[0], s->n[1], a);
    if (vec3_len(a) < 1e-2 || vec3_normalize(a)) return -1;
    double c[3];
    if (line_closest(s->p[0], s->n[0], s->p[1], s->n[1], c)) return -1;
    q->type = PRIM_CYLINDER;
    memcpy(q->p, c, sizeof c);
    memcpy(q->a, a, sizeof a);
    double r = 0;
    for (int i = 0; i < 2; i++) {
        double v[3], w[3];
        vec3_sub(s->p[i], c, v);
        double h = vec3_dot(v, a);
        for (int k = 0; k < 3; k++) w[k] = v[k] - h * a[k];
        r += 0.5 * vec3_len(w);
    }
    q->r = r;
    return 0;
}

static int make_cone(const sample *s, prim *q)
{
    double m[3][3], b[3], apex[3];
    for (int i = 0; i < 3; i++) {
        for (int k = 0; k < 3; k++) m[i][k] = s->n[i][k];
        b[i] = vec3_dot(s->n[i], s->p[i]);
    }
    if (solve3(m, b, apex)) return -1;
    double d[3][3];
    for (int i = 0; i < 3; i++) {
        vec3_sub(s->p[i], apex, d[i]);
        if (vec3_normalize(d[i])) return -1;
    }
    double u[3], v[3], a[3];
    vec3_sub(d[1], d[0], u);
    vec3_sub(d[2], d[0], v);
    vec3_cross(u, v, a);
    if (vec3_normalize(a)) return -1;
    if (vec3_dot(a, d[0]) < 0) for (int k = 0; k < 3; k++) a[k] = -a[k];
    double ang = 0;
    for (int i = 0; i < 3; i++) ang += acos(fmin(1.0, fmax(-1.0, vec3_dot(a, d[i])))) / 3.0;
    if (ang < CONE_MIN_ANGLE || ang > FREP_PI / 2 - CONE_MIN_ANGLE) return -1;
    q->type = PRIM_CONE;
    memcpy(q->p, apex, sizeof apex);
    memcpy(q->a, a, sizeof a);
    q->r = ang;
    return 0;
}

/* det[c2 - c1, c3 - c1, c4 - c1] with ci = pi - r ni: zero when the four tube centres
 * are coplanar, as the spine circle of a torus is. */
static double torus_det(const sample *s, double r)
{
    double c[4][3], u[3], v[3], w[3], x[3];
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 3; k++) c[i][k] = s->p[i][k] - r * s->n[i][k];
    vec3_sub(c[1], c[0], u);
    vec3_sub(c[2], c[0], v);
    vec3_sub(c[3], c[0], w);
    vec3_cross(v, w, x);
    return vec3_dot(u, x);
}

/* Subdivisions of the minor-radius interval searched for roots of torus_det. */
#define TORUS_ROOT_SCAN 48

static int make_torus(const sample *s, prim *q, double rmax, double eps)
{
    double prev_r = -rmax, prev = torus_det(s, prev_r);
    for (int k = 1; k <= TORUS_ROOT_SCAN; k++) {
        double r1 = -rmax + 2.0 * rmax * k / TORUS_ROOT_SCAN, f1 = torus_det(s, r1);
        if ((prev < 0) != (f1 < 0)) {
            double lo = prev_r, hi = r1, flo = prev;
            for (int it = 0; it < 60; it++) {
                double mid = 0.5 * (lo + hi), fm = torus_det(s, mid);
                if ((fm < 0) == (flo < 0)) lo = mid, flo = fm;
                else hi = mid;
            }
            double r = 0.5 * (lo + hi);
            double c[4][3];
            for (int i = 0; i < 4; i++)
                for (int j = 0; j < 3; j++) c[i][j] = s->p[i][j] - r * s->n[i][j];
            double ctr[3], ax[3], R;
            if (fabs(r) > eps && !circle3(c[0], c[1], c[2], ctr, ax, &R)) {
                /* The fourth tube centre must lie on the same circle. */
                double v[3];
                vec3_sub(c[3], ctr, v);
                double h = vec3_dot(v, ax), rho2 = vec3_dot(v, v) - h * h;
                double rho = sqrt(fmax(0.0, rho2));
                if (fabs(h) < eps && fabs(rho - R) < eps && R > fabs(r) * 0.05) {
                    q->type = PRIM_TORUS;
                    memcpy(q->p, ctr, sizeof ctr);
                    memcpy(q->a, ax, sizeof ax);
                    q->R = R;
                    q->r = fabs(r);
                    return 0;
                }
            }
        }
        prev_r = r1;
        prev = f1;
    }
    return -1;
}

/* ---- connected component in the parameter domain --------------------------- */

typedef struct cellpt {
    uint64_t cell;
    uint32_t pt;      /* position in the inlier list */
} cellpt;

static int cmp_cellpt(const void *a, const void *b)
{
    const cellpt *x = a, *y = b;
    if (x->cell != y->cell) return x->cell < y->cell ? -1 : 1;
    return (x->pt > y->pt) - (x->pt < y->pt);
}

/* Radix sort bits per pass: 2^11 counters fit in L1. */
#define RADIX_BITS 11
/* Sort by (cell, pt) as cmp_cellpt does, by a stable LSD radix sort on the cell (the
 * input is in pt order, so equal cells stay in pt order): linear time where qsort's
 * comparisons dominated the extraction of large patches. Returns -1 when out of
 * memory (nothing sorted). */
static int sort_cellpt(cellpt *a, size_t n)
{
    uint64_t maxc = 0;
    for (size_t i = 0; i < n; i++)
        if (a[i].cell > maxc) maxc = a[i].cell;
    int bits = 0;
    while (bits < 64 && (maxc >> bits) != 0) bits++;
    if (bits == 0) return 0;
    cellpt *tmp = frep_malloc(n * sizeof *tmp);
    if (!tmp) return -1;
    size_t cnt[1u << RADIX_BITS];
    cellpt *src = a, *dst = tmp;
    for (int sh = 0; sh < bits; sh += RADIX_BITS) {
        memset(cnt, 0, sizeof cnt);
        for (size_t i = 0; i < n; i++) cnt[(src[i].cell >> sh) & ((1u << RADIX_BITS) - 1)]++;
        size_t sum = 0;
        for (size_t k = 0; k < (1u << RADIX_BITS); k++) {
            size_t t = cnt[k];
            cnt[k] = sum;
            sum += t;
        }
        for (size_t i = 0; i < n; i++) dst[cnt[(src[i].cell >> sh) & ((1u << RADIX_BITS) - 1)]++] = src[i];
        cellpt *t = src;
        src = dst;
        dst = t;
    }
    if (src != a) memcpy(a, src, n * sizeof *a);
    frep_free(tmp);
    return 0;
}

/* The parameter domain of q, flattened: point i of the patch at (uv[2i], uv[2i+1]),
 * lengths along the surface; period[k] > 0 for an axis that wraps around. */
typedef struct pdomain {
    double *uv;
    double period[2];
    double lo[2];          /* the bitmap's corner */
    double cell[2];        /* its cell sizes */
    uint64_t ncell[2];     /* its cells per axis */
} pdomain;

/* Mean distance from a cone's axis over the inliers: the radius its angle is scaled by. */
static double cone_mean_rho(const prim *q, const frep_cloud *c, const uint32_t *idx, size_t n)
{
    double mean_rho = 0;
    for (size_t i = 0; i < n; i++) {
        double p[3], v[3];
        point(c, idx[i], p);
        vec3_sub(p, q->p, v);
        double h = vec3_dot(v, q->a);
        mean_rho += sqrt(fmax(0, vec3_dot(v, v) - h * h)) / (double)n;
    }
    return mean_rho;
}

/* The domain coordinates of every inlier (see doc/segment.md, extraction): in-plane
 * axes; longitude and colatitude times r; angle times r (or the cone's mean radius,
 * or R) with height, slant distance or the tube angle times r. */
static void domain_coords(const prim *q, const frep_cloud *c, const uint32_t *idx, size_t n,
                          pdomain *D)
{
    double e1[3], e2[3];
    const double *ax = q->type == PRIM_PLANE ? q->p : q->a;
    double zaxis[3] = {0, 0, 1};
    if (q->type == PRIM_SPHERE) ax = zaxis;
    vec3_basis(ax, e1, e2);
    D->period[0] = D->period[1] = 0;
    double mean_rho = q->type == PRIM_CONE ? cone_mean_rho(q, c, idx, n) : 0;
    for (size_t i = 0; i < n; i++) {
        double p[3], v[3];
        point(c, idx[i], p);
        double u = 0, w = 0;
        switch (q->type) {
        case PRIM_PLANE:
            u = vec3_dot(p, e1);
            w = vec3_dot(p, e2);
            break;
        case PRIM_SPHERE: {
            vec3_sub(p, q->p, v);
            vec3_normalize(v);
            u = q->r * atan2(vec3_dot(v, e2), vec3_dot(v, e1));
            w = q->r * acos(fmin(1, fmax(-1, vec3_dot(v, ax))));
            D->period[0] = 2 * FREP_PI * q->r;
            break;
        }
        case PRIM_CYLINDER:
        case PRIM_CONE:
        case PRIM_TORUS: {
            vec3_sub(p, q->p, v);
            double h = vec3_dot(v, q->a);
            double ang = atan2(vec3_dot(v, e2), vec3_dot(v, e1));
            double rho = sqrt(fmax(0, vec3_dot(v, v) - h * h));
            if (q->type == PRIM_CYLINDER) {
                u = q->r * ang;
                w = h;
                D->period[0] = 2 * FREP_PI * q->r;
            } else if (q->type == PRIM_CONE) {
                u = mean_rho * ang;
                w = sqrt(h * h + rho * rho);
                D->period[0] = 2 * FREP_PI * mean_rho;
            } else {
                u = q->R * ang;
                w = q->r * atan2(h, rho - q->R);
                D->period[0] = 2 * FREP_PI * q->R;
                D->period[1] = 2 * FREP_PI * q->r;
            }
            break;
        }
        case PRIM__COUNT:
            break;
        }
        D->uv[2 * i] = u;
        D->uv[2 * i + 1] = w;
    }
}

/* The bitmap over the coordinates: cells of beta (larger when an axis would need more
 * than BITMAP_MAX_CELLS_AXIS); a periodic axis wraps onto whole cells of ext / ncell. */
static void domain_grid(pdomain *D, size_t n, double beta)
{
    double hi[2] = {-DBL_MAX, -DBL_MAX};
    D->lo[0] = D->lo[1] = DBL_MAX;
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 2; k++) {
            if (D->uv[2 * i + k] < D->lo[k]) D->lo[k] = D->uv[2 * i + k];
            if (D->uv[2 * i + k] > hi[k]) hi[k] = D->uv[2 * i + k];
        }
    double ext[2];
    for (int k = 0; k < 2; k++) {
        ext[k] = D->period[k] > 0 ? D->period[k] : hi[k] - D->lo[k];
        if (D->period[k] > 0) D->lo[k] = -0.5 * D->period[k];
        if (ext[k] / beta > BITMAP_MAX_CELLS_AXIS - 1) beta = ext[k] / (BITMAP_MAX_CELLS_AXIS - 1);
    }
    for (int k = 0; k < 2; k++) D->ncell[k] = (uint64_t)floor(ext[k] / beta) + 1;
    for (int k = 0; k < 2; k++) {
        D->cell[k] = D->period[k] > 0 ? ext[k] / (double)D->ncell[k] : beta;
        if (!(D->cell[k] > 0)) D->cell[k] = 1;
    }
}

/* The bitmap cell of every point, sorted by cell (then by point). */
static void domain_cells(const pdomain *D, size_t n, cellpt *cp)
{
    for (size_t i = 0; i < n; i++) {
        uint64_t ci[2];
        for (int k = 0; k < 2; k++) {
            double t = floor((D->uv[2 * i + k] - D->lo[k]) / D->cell[k]);
            if (!(t >= 0)) t = 0;
            ci[k] = (uint64_t)t;
            if (ci[k] >= D->ncell[k])
                ci[k] = D->period[k] > 0 ? ci[k] % D->ncell[k] : D->ncell[k] - 1;
        }
        cp[i].cell = ci[0] * D->ncell[1] + ci[1];
        cp[i].pt = (uint32_t)i;
    }
    if (sort_cellpt(cp, n)) qsort(cp, n, sizeof *cp, cmp_cellpt);
}

/* Union-find over the occupied cells (cell j spans cp[start[j] .. start[j + 1])): each
 * cell joins its 8 neighbours, across the seam of a periodic axis. */
static void join_neighbours(const pdomain *D, const cellpt *cp, const uint32_t *start,
                            size_t ncells, uint32_t *par)
{
    const uint64_t *ncell = D->ncell;
    for (size_t j = 0; j < ncells; j++) par[j] = (uint32_t)j;
    for (size_t j = 0; j < ncells; j++) {
        uint64_t id = cp[start[j]].cell, cu = id / ncell[1], cv = id % ncell[1];
        for (int du = -1; du <= 1; du++)
            for (int dv = -1; dv <= 1; dv++) {
                if (!du && !dv) continue;
                int64_t nu = (int64_t)cu + du, nv = (int64_t)cv + dv;
                if (nu < 0 || nu >= (int64_t)ncell[0]) {
                    if (D->period[0] <= 0) continue;
                    nu = (nu + (int64_t)ncell[0]) % (int64_t)ncell[0];
                }
                if (nv < 0 || nv >= (int64_t)ncell[1]) {
                    if (D->period[1] <= 0) continue;
                    nv = (nv + (int64_t)ncell[1]) % (int64_t)ncell[1];
                }
                uint64_t nid = (uint64_t)nu * ncell[1] + (uint64_t)nv;
                if (nid <= id) continue; /* each pair once, from its smaller id */
                size_t a = 0, b = ncells;
                while (a < b) {
                    size_t m = (a + b) / 2;
                    if (cp[start[m]].cell < nid) a = m + 1;
                    else b = m;
                }
                if (a < ncells && cp[start[a]].cell == nid) frep_uf_join(par, (uint32_t)j, (uint32_t)a);
            }
    }
}

/* The component of most points (the first of equals); keep[pt] marks its points. */
static void mark_largest(const cellpt *cp, const uint32_t *start, size_t ncells,
                         uint32_t *par, uint32_t *cnt, unsigned char *keep)
{
    for (size_t j = 0; j < ncells; j++) cnt[frep_uf_root(par, (uint32_t)j)] += start[j + 1] - start[j];
    uint32_t best = 0;
    for (size_t j = 1; j < ncells; j++)
        if (cnt[j] > cnt[best]) best = (uint32_t)j;
    for (size_t j = 0; j < ncells; j++)
        if (frep_uf_root(par, (uint32_t)j) == best)
            for (uint32_t i = start[j]; i < start[j + 1]; i++) keep[cp[i].pt] = 1;
}

/* The bitmap of cells beta over q's parameter domain for the points list[0..n): its
 * grid into *D (without the coordinates) and the cell of every point, sorted by cell
 * (then by point), as a new array; NULL when out of memory. */
static cellpt *patch_cells(const prim *q, const frep_cloud *c, const uint32_t *list, size_t n,
                           double beta, pdomain *D)
{
    D->uv = frep_malloc(2 * n * sizeof *D->uv);
    cellpt *cp = D->uv ? frep_malloc(n * sizeof *cp) : NULL;
    if (cp) {
        domain_coords(q, c, list, n, D);
        domain_grid(D, n, beta);
        domain_cells(D, n, cp);
    }
    frep_free(D->uv);
    D->uv = NULL;
    return cp;
}

/* Keep only the inliers (idx[0..n)) in the largest 8-connected patch of a bitmap with
 * cells of size beta over the parameter domain of q; their count into *kept. Returns 0,
 * or -1 when out of memory (idx unchanged, *kept = n). */
static int largest_component(const prim *q, const frep_cloud *c, uint32_t *idx, size_t n,
                             double beta, size_t *kept)
{
    *kept = n;
    if (n == 0) return 0;
    pdomain D;
    cellpt *cp = patch_cells(q, c, idx, n, beta, &D);
    uint32_t *start = cp ? frep_malloc((n + 1) * sizeof *start) : NULL;
    uint32_t *par = start ? frep_malloc(n * sizeof *par) : NULL;
    uint32_t *cnt = par ? frep_calloc(n, sizeof *cnt) : NULL;
    unsigned char *keep = cnt ? frep_calloc(n, 1) : NULL;
    int rc = -1;
    if (keep) {
        size_t ncells = 0;
        for (size_t i = 0; i < n; i++)
            if (i == 0 || cp[i].cell != cp[i - 1].cell) start[ncells++] = (uint32_t)i;
        start[ncells] = (uint32_t)n;
        join_neighbours(&D, cp, start, ncells, par);
        mark_largest(cp, start, ncells, par, cnt, keep);
        /* The inliers of the best component, in their original order. */
        size_t m = 0;
        for (size_t i = 0; i < n; i++)
            if (keep[i]) idx[m++] = idx[i];
        *kept = m;
        rc = 0;
    }
    frep_free(cp);
    frep_free(start);
    frep_free(par);
    frep_free(cnt);
    frep_free(keep);
    return rc;
}

/* The share of the points list[mq .. mq + mp) that fall in a cell holding one of the
 * points list[0 .. mq), on a bitmap of cells beta over q's parameter domain, into
 * *share: near 1 for a part lying over the first one's patch (a shell of its noise
 * fitted apart), near 0 for a part beside it. Returns 0, or -1 when out of memory. */
static int patch_overlap(const prim *q, const frep_cloud *c, const uint32_t *list, size_t mq,
                         size_t mp, double beta, double *share)
{
    size_t n = mq + mp;
    *share = 0;
    if (mp == 0) return 0;
    pdomain D;
    cellpt *cp = patch_cells(q, c, list, n, beta, &D);
    if (!cp) return -1;
    size_t over = 0;
    for (size_t i = 0, j; i < n; i = j) {
        /* Within a cell the points come in list order: the first one tells. */
        int first_has = cp[i].pt < mq;
        for (j = i; j < n && cp[j].cell == cp[i].cell; j++)
            over += first_has && cp[j].pt >= mq;
    }
    *share = (double)over / (double)mp;
    frep_free(cp);
    return 0;
}

/* ---- least-squares refit ----------------------------------------------------- */

/* Robust sigma from the median absolute residual, for Gaussian noise. */
#define NOISE_MAD_TO_SIGMA 1.4826

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int npar(prim_type t)
{
    switch (t) {
    case PRIM_SPHERE: return 4;
    case PRIM_CYLINDER: case PRIM_CONE: return 7;
    case PRIM_TORUS: return 8;
    case PRIM_PLANE: case PRIM__COUNT: break;
    }
    return 0;
}

static void pack(const prim *q, double *v)
{
    memcpy(v, q->p, 3 * sizeof(double));
    if (q->type == PRIM_SPHERE) {
        v[3] = q->r;
        return;
    }
    memcpy(v + 3, q->a, 3 * sizeof(double));
    if (q->type == PRIM_TORUS) {
        v[6] = q->R;
        v[7] = q->r;
    } else {
        v[6] = q->r;
    }
}

static int unpack(prim *q, const double *v)
{
    memcpy(q->p, v, 3 * sizeof(double));
    if (q->type == PRIM_SPHERE) {
        q->r = v[3];
        return q->r > 0 ? 0 : -1;
    }
    double a[3] = {v[3], v[4], v[5]};
    if (vec3_normalize(a)) return -1;
    memcpy(q->a, a, sizeof a);
    if (q->type == PRIM_TORUS) {
        q->R = v[6];
        q->r = v[7];
        return q->r > 0 && q->R > 0 ? 0 : -1;
    }
    q->r = v[6];
    if (q->type == PRIM_CONE) return q->r > 0 && q->r < FREP_PI / 2 ? 0 : -1;
    return q->r > 0 ? 0 : -1;
}

/* Gaussian elimination with partial pivoting on an m x m system; -1 when singular. */
static int solve_n(double *A, double *b, int m)
{
    for (int k = 0; k < m; k++) {
        int piv = k;
        for (int i = k + 1; i < m; i++)
            if (fabs(A[i * m + k]) > fabs(A[piv * m + k])) piv = i;
        if (!(fabs(A[piv * m + k]) > 1e-300)) return -1;
        if (piv != k) {
            for (int j = 0; j < m; j++) {
                double t = A[k * m + j];
                A[k * m + j] = A[piv * m + j];
                A[piv * m + j] = t;
            }
            double t = b[k];
            b[k] = b[piv];
            b[piv] = t;
        }
        for (int i = k + 1; i < m; i++) {
            double f = A[i * m + k] / A[k * m + k];
            for (int j = k; j < m; j++) A[i * m + j] -= f * A[k * m + j];
            b[i] -= f * b[k];
        }
    }
    for (int k = m - 1; k >= 0; k--) {
        double s = b[k];
        for (int j = k + 1; j < m; j++) s -= A[k * m + j] * b[j];
        b[k] = s / A[k * m + k];
    }
    return 0;
}

static double cost_of(const prim *q, const double *px, size_t n)
{
    double s = 0, sc[2];
    prim_trig(q, sc);
    for (size_t i = 0; i < n; i++) {
        double f = prim_value(q, sc, px + 3 * i);
        s += f * f;
    }
    return s;
}

/* The least-squares plane through the m points px: the covariance's smallest-eigenvalue
 * eigenvector, oriented as the inliers' (idx[0..n)) summed normals when they have a
 * clear direction (a plane that replaces a curved shape has none of its own), else as
 * q was. */
static int refit_plane(prim *q, const frep_cloud *c, const uint32_t *idx, size_t n,
                       const double *px, size_t m)
{
    double mean[3] = {0, 0, 0}, cov[9] = {0};
    for (size_t j = 0; j < m; j++)
        for (int k = 0; k < 3; k++) mean[k] += px[3 * j + k] / (double)m;
    for (size_t j = 0; j < m; j++)
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                cov[3 * a + b] += (px[3 * j + a] - mean[a]) * (px[3 * j + b] - mean[b]);
    double ev[3], vec[9];
    normals_sym3_eig(cov, ev, vec);
    double nrm[3] = {vec[0], vec[1], vec[2]};
    double ref[3] = {q->p[0], q->p[1], q->p[2]};
    if (c->has_normals) {
        double sn[3] = {0, 0, 0};
        for (size_t j = 0; j < n; j++) {
            sn[0] += c->nx[idx[j]];
            sn[1] += c->ny[idx[j]];
            sn[2] += c->nz[idx[j]];
        }
        if (fabs(vec3_dot(sn, nrm)) > 1e-9 * (double)n) memcpy(ref, sn, sizeof ref);
    }
    if (vec3_dot(nrm, ref) < 0) for (int k = 0; k < 3; k++) nrm[k] = -nrm[k];
    memcpy(q->p, nrm, sizeof nrm);
    q->r = vec3_dot(nrm, mean);
    return 0;
}

/* J^T J and J^T f of the np parameters v of q over the m points px, with
 * forward-difference Jacobians (steps 1e-7 of each parameter's size; positions count
 * the points' extent, scale). */
static void lm_normal_equations(const prim *q, const double *v, int np, const double *px,
                                size_t m, double scale, double *JtJ, double *Jtr)
{
    double h[8], vt[8], sc[9][2];
    prim tq[8];
    memset(JtJ, 0, 64 * sizeof *JtJ);
    memset(Jtr, 0, 8 * sizeof *Jtr);
    for (int k = 0; k < np; k++) {
        h[k] = 1e-7 * (fabs(v[k]) + (k < 3 ? scale : 1.0));
        memcpy(vt, v, sizeof vt);
        vt[k] += h[k];
        tq[k] = *q;
        unpack(&tq[k], vt);
        prim_trig(&tq[k], sc[k]);
    }
    prim_trig(q, sc[8]);
    for (size_t j = 0; j < m; j++) {
        double f = prim_value(q, sc[8], px + 3 * j), J[8];
        for (int k = 0; k < np; k++) J[k] = (prim_value(&tq[k], sc[k], px + 3 * j) - f) / h[k];
        for (int a = 0; a < np; a++) {
            Jtr[a] += J[a] * f;
            for (int b = a; b < np; b++) JtJ[a * np + b] += J[a] * J[b];
        }
    }
    /* The lower triangle: the same products summed in the same order. */
    for (int a = 1; a < np; a++)
        for (int b = 0; b < a; b++) JtJ[a * np + b] = JtJ[b * np + a];
}

/* The Levenberg-Marquardt fit of q's parameters to the m points px (Euclidean
 * distance): damping from 1e-3, times 10 after a failed step, a tenth after a good one. */
static int refit_lm(prim *q, const double *px, size_t m)
{
    int np = npar(q->type);
    double v[8], vt[8], JtJ[64], Jtr[8], A[64], step[8];
    pack(q, v);
    double scale = 0;
    for (size_t j = 0; j < m; j++)
        scale = fmax(scale, fabs(px[3 * j]) + fabs(px[3 * j + 1]) + fabs(px[3 * j + 2]));
    scale = fmax(scale, 1e-12);
    double cost = cost_of(q, px, m), lambda = 1e-3;
    prim t = *q;
    int rc = -1;
    for (int it = 0; it < LM_MAX_ITER; it++) {
        lm_normal_equations(q, v, np, px, m, scale, JtJ, Jtr);
        int improved = 0;
        for (int tries = 0; tries < LM_TRIES && !improved; tries++) {
            memcpy(A, JtJ, sizeof A);
            for (int k = 0; k < np; k++) {
                A[k * np + k] += lambda * (JtJ[k * np + k] + 1e-12);
                step[k] = -Jtr[k];
            }
            if (solve_n(A, step, np) == 0) {
                for (int k = 0; k < np; k++) vt[k] = v[k] + step[k];
                t = *q;
                if (unpack(&t, vt) == 0) {
                    double nc = cost_of(&t, px, m);
                    if (nc < cost) {
                        double rel = (cost - nc) / fmax(cost, 1e-300);
                        *q = t;
                        pack(q, v);
                        cost = nc;
                        lambda = fmax(lambda * 0.1, LM_LAMBDA_MIN);
                        improved = 1;
                        rc = 0;
                        if (rel < LM_REL_STOP && lambda < LM_LAMBDA_CONVERGED) it = LM_MAX_ITER;
                        break;
                    }
                }
            }
            lambda *= 10;
        }
        if (!improved) break;
    }
    return rc == 0 || cost >= 0 ? 0 : -1;
}

/* The least-squares fit of q to the m points px (3 coordinates each); idx[0..n) are
 * the inliers, whose normals orient a plane. */
static int refit_points(prim *q, const frep_cloud *c, const uint32_t *idx, size_t n,
                        const double *px, size_t m)
{
    if (q->type == PRIM_PLANE) return refit_plane(q, c, idx, n, px, m);
    return refit_lm(q, px, m);
}

/* Points farther than TRIM_SIGMAS robust standard deviations (1.4826 median |f|)
 * from the first fit are dropped and the fit is repeated: a few points of a
 * neighbouring surface (at an edge, where estimated normals are poor) would otherwise
 * pull a least-squares fit by far more than the noise. */
#define TRIM_SIGMAS 3.0
/* ... unless fewer than this fraction would remain (then the fit itself is poor). */
#define TRIM_KEEP_MIN 0.5

int ransac_refit(prim *q, const frep_cloud *c, const uint32_t *idx, size_t n,
                 size_t max_points)
{
    if (n < 3) return 1;
    if (max_points == 0 || max_points > n) max_points = n;
    size_t m = max_points;
    double *px = frep_malloc(3 * m * sizeof *px), *res = frep_malloc(2 * m * sizeof *res);
    if (!px || !res) {
        frep_free(px);
        frep_free(res);
        return -1;
    }
    for (size_t j = 0; j < m; j++) {
        size_t i = idx[(size_t)((double)j * (double)n / (double)m)];
        point(c, i, px + 3 * j);
    }
    prim t = *q;
    int rc = refit_points(&t, c, idx, n, px, m) ? 1 : 0;
    if (rc == 0) {
        *q = t;
        double *sorted = res + m;
        for (size_t j = 0; j < m; j++) {
            res[j] = fabs(prim_eval(q, px + 3 * j, NULL));
            sorted[j] = res[j];
        }
        qsort(sorted, m, sizeof *sorted, cmp_double);
        double lim = TRIM_SIGMAS * NOISE_MAD_TO_SIGMA * sorted[m / 2];
        size_t kept = 0;
        for (size_t j = 0; j < m; j++)
            if (res[j] <= lim) {
                memmove(px + 3 * kept, px + 3 * j, 3 * sizeof *px);
                kept++;
            }
        if (kept < m && kept >= 3 && (double)kept >= TRIM_KEEP_MIN * (double)m &&
            refit_points(&t, c, idx, n, px, kept) == 0)
            *q = t;
        /* A cylinder's point is free along its axis (LM may leave it hundreds of units
         * away): the foot of the points' centroid, so that it lies by the patch. */
        if (q->type == PRIM_CYLINDER) {
            double h = 0;
            for (size_t j = 0; j < m; j++) {
                double v[3];
                vec3_sub(px + 3 * j, q->p, v);
                h += vec3_dot(v, q->a) / (double)m;
            }
            for (int k = 0; k < 3; k++) q->p[k] += h * q->a[k];
        }
    }
    frep_free(px);
    frep_free(res);
    return rc;
}

/* ---- the detection loop -------------------------------------------------------- */

typedef struct cand {
    prim q;
    int level;          /* octree level the sample came from */
    int ksample;        /* minimal sample size (for the acceptance probability) */
    int nsub;           /* scoring subsets evaluated */
    size_t score;       /* inliers among live points of those subsets */
    size_t seen;        /* live points in those subsets */
    double est, lo, hi; /* estimated support and its confidence interval */
} cand;

typedef struct det {
    const frep_cloud *c;
    const ransac_config *cfg;
    size_t n, nalive;
    unsigned char *alive;
    uint32_t *shuf;          /* random permutation: the scoring subsets in order */
    double *spts;            /* points and normals in that order, 6 per point, so that
                                scoring streams through memory */
    unsigned char *salive;   /* alive[] in that order */
    size_t sub_start[MAX_SUBSETS + 1];
    size_t sub_alive[MAX_SUBSETS];
    int nsub;
    uint32_t *morton_idx;    /* point indices sorted by Morton code */
    uint64_t *morton;        /* sorted codes */
    uint32_t *alive_list;    /* live points, for drawing the first sample point */
    double level_score[OCT_LEVELS + 1];
    double rmax;
    double band;             /* inlier distance of the current extraction (>= epsilon) */
    uint32_t *tmp;           /* scratch index list of n entries */
    /* Set by a helper of the extraction or the merge whose scratch could not be
     * allocated: the value it returns is then meaningless (but safe to use), and the
     * driver fails the run with out of memory after the step (detect_step,
     * ransac_detect). */
    int nomem;
} det;

static uint64_t spread3(uint64_t v)
{
    uint64_t r = 0;
    for (int b = 0; b < OCT_LEVELS; b++) r |= ((v >> b) & 1u) << (3 * b);
    return r;
}

typedef struct mkey {
    uint64_t code;
    uint32_t i;
} mkey;

static int cmp_mkey(const void *a, const void *b)
{
    const mkey *x = a, *y = b;
    if (x->code != y->code) return x->code < y->code ? -1 : 1;
    return (x->i > y->i) - (x->i < y->i);
}

static void update_estimate(const det *d, cand *k)
{
    double N = (double)d->nalive, m = (double)k->seen, s = (double)k->score;
    if (m <= 0) {
        k->est = k->lo = 0;
        k->hi = N;
        return;
    }
    double frac = s / m;
    k->est = frac * N;
    /* Hypergeometric standard deviation of the subset count, scaled to the whole. */
    double var = m * frac * (1 - frac) * (N > m ? (N - m) / fmax(N - 1, 1) : 0);
    double sd = sqrt(fmax(var, 0)) * N / m + (N > m ? N / m : 0);
    k->lo = fmax(0, k->est - 2 * sd);
    k->hi = k->est + 2 * sd;
}

/* Score candidates [from, to) on their next scoring subset (parallel, per candidate). */
static void score_next(det *d, cand *cs, const int *which, size_t nw)
{
    const ransac_config *cfg = d->cfg;
    long lw = (long)nw;
    size_t work = 0;
    if (frep_cancelled(cfg->interrupt)) return;  /* Ctrl-C: the loop stops at its poll */
    for (size_t w = 0; w < nw; w++) {
        const cand *k = &cs[which[w]];
        if (k->nsub < d->nsub) work += d->sub_start[k->nsub + 1] - d->sub_start[k->nsub];
    }
    (void)work;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 4) if (work >= PAR_MIN_WORK) num_threads(frep_threads(cfg->nthreads))
#endif
    for (long w = 0; w < lw; w++) {
        cand *k = &cs[which[w]];
        if (k->nsub >= d->nsub) continue;
        size_t s = 0;
        kern kn;
        kern_init(&kn, &k->q, cfg->epsilon, cfg->cos_normal);
        for (size_t j = d->sub_start[k->nsub]; j < d->sub_start[k->nsub + 1]; j++)
            s += d->salive[j] && kern_test(&kn, d->spts + 6 * j, d->spts + 6 * j + 3);
        k->score += s;
        k->seen += d->sub_alive[k->nsub];
        k->nsub++;
    }
    for (size_t w = 0; w < nw; w++) update_estimate(d, &cs[which[w]]);
}

static void recount_subsets(det *d)
{
    for (int b = 0; b < d->nsub; b++) {
        size_t a = 0;
        for (size_t j = d->sub_start[b]; j < d->sub_start[b + 1]; j++) {
            d->salive[j] = d->alive[d->shuf[j]];
            a += d->salive[j];
        }
        d->sub_alive[b] = a;
    }
    size_t m = 0;
    for (size_t i = 0; i < d->n; i++)
        if (d->alive[i]) d->alive_list[m++] = (uint32_t)i;
    d->nalive = m;
}

/* Draw one localized minimal sample; returns the octree level or -1. */
static int draw_sample(det *d, rng *r, sample *s)
{
    if (d->nalive < SAMPLE_SIZE) return -1;
    uint32_t first = d->alive_list[rng_below(r, d->nalive)];
    /* Level by the adaptive distribution: half uniform, half by past success. */
    double tot = 0;
    for (int l = 1; l <= OCT_LEVELS; l++) tot += d->level_score[l];
    double u = rng_unit(r), acc = 0;
    int level = OCT_LEVELS;
    for (int l = 1; l <= OCT_LEVELS; l++) {
        acc += 0.5 / OCT_LEVELS + (tot > 0 ? 0.5 * d->level_score[l] / tot : 0.5 / OCT_LEVELS);
        if (u < acc) {
            level = l;
            break;
        }
    }
    /* Cell of `first` at this level: all codes sharing its top 3*level bits. */
    size_t a, b;
    /* The codes by point index follow the sorted codes (see ransac_detect). */
    uint64_t code = d->morton[d->n + 1 + first];
    int shift = 3 * (OCT_LEVELS - level);
    uint64_t pre = code >> shift;
    size_t lo2 = 0, hi2 = d->n;
    while (lo2 < hi2) {
        size_t m = (lo2 + hi2) / 2;
        if ((d->morton[m] >> shift) < pre) lo2 = m + 1;
        else hi2 = m;
    }
    a = lo2;
    hi2 = d->n;
    while (lo2 < hi2) {
        size_t m = (lo2 + hi2) / 2;
        if ((d->morton[m] >> shift) <= pre) lo2 = m + 1;
        else hi2 = m;
    }
    b = lo2;
    if (b - a < SAMPLE_SIZE) return -1;
    uint32_t pick[SAMPLE_SIZE];
    pick[0] = first;
    for (int k = 1; k < SAMPLE_SIZE; k++) {
        int found = 0;
        for (int t = 0; t < SAMPLE_TRIES && !found; t++) {
            uint32_t cand_i = d->morton_idx[a + rng_below(r, b - a)];
            if (!d->alive[cand_i]) continue;
            int dup = 0;
            for (int j = 0; j < k; j++) dup |= pick[j] == cand_i;
            if (dup) continue;
            pick[k] = cand_i;
            found = 1;
        }
        if (!found) return -1;
    }
    for (int k = 0; k < SAMPLE_SIZE; k++) {
        point(d->c, pick[k], s->p[k]);
        normal(d->c, pick[k], s->n[k]);
    }
    return level;
}

/* Minimal sample points a candidate of type t is checked against. */
static int verify_count(prim_type t)
{
    return t == PRIM_TORUS ? 4 : 3;
}

static int verify(const prim *q, const sample *s, int nv, double eps, double cosn)
{
    for (int k = 0; k < nv; k++) {
        double g[3];
        double f = prim_eval(q, s->p[k], g);
        if (!(fabs(f) <= eps)) return 0;
        double gl = vec3_len(g);
        if (!(gl > 0) || fabs(vec3_dot(g, s->n[k])) < cosn * gl) return 0;
    }
    return 1;
}

/* Do a and b, of one type, have parameters within tol (positions, radii) and deg
 * degrees (directions, cone angles)? */
static int shapes_close(const prim *a, const prim *b, double tol, double deg)
{
    double cmin = cos(deg * FREP_PI / 180.0), dp[3];
    vec3_sub(a->p, b->p, dp);
    switch (a->type) {
    case PRIM_PLANE:
        return vec3_dot(a->p, b->p) > cmin && fabs(a->r - b->r) < tol;
    case PRIM_SPHERE:
        return vec3_len(dp) < tol && fabs(a->r - b->r) < tol;
    case PRIM_CYLINDER: {
        double h = vec3_dot(dp, b->a), w[3];
        for (int k = 0; k < 3; k++) w[k] = dp[k] - h * b->a[k];
        return fabs(vec3_dot(a->a, b->a)) > cmin && vec3_len(w) < tol && fabs(a->r - b->r) < tol;
    }
    case PRIM_CONE:
        return vec3_len(dp) < tol && vec3_dot(a->a, b->a) > cmin && fabs(a->r - b->r) < deg * FREP_PI / 180.0;
    case PRIM_TORUS:
        return vec3_len(dp) < tol && fabs(vec3_dot(a->a, b->a)) > cmin && fabs(a->r - b->r) < tol &&
               fabs(a->R - b->R) < tol;
    case PRIM__COUNT:
        break;
    }
    return 0;
}

/* Same shape within the tolerances (epsilon in position, DUP_DEG in direction)? A
 * candidate like one already pooled adds nothing but scoring work. */
#define DUP_DEG 2.0
static int same_shape(const prim *a, const prim *b, double eps)
{
    return a->type == b->type && shapes_close(a, b, eps, DUP_DEG);
}

static int sane(const prim *q, double rmax)
{
    double v[9] = {q->p[0], q->p[1], q->p[2], q->a[0], q->a[1], q->a[2], q->r, q->R, 0};
    for (int k = 0; k < 8; k++)
        if (!isfinite(v[k])) return 0;
    switch (q->type) {
    case PRIM_SPHERE: case PRIM_CYLINDER: return q->r > 0 && q->r < rmax;
    case PRIM_TORUS: return q->r > 0 && q->R > 0 && q->R + q->r < rmax;
    case PRIM_PLANE: case PRIM_CONE: case PRIM__COUNT: break;
    }
    return 1;
}

/* Refit / band-widening passes per extraction: the band settles in two or three. */
#define NOISE_PASSES 4
/* A new band must exceed the current one by this factor to be worth another pass. */
#define NOISE_BAND_GROWTH 1.05

/* Probability of drawing a minimal sample of k points from a shape of size `support`
 * with localized sampling (Schnabel et al., eq. 2). */
static double p_draw(double support, double N, int k)
{
    return support / (N * OCT_LEVELS * (double)(1u << (k - 1)));
}

static int cmp_cand_est(const cand *a, const cand *b)
{
    if (a->est != b->est) return a->est > b->est ? -1 : 1;
    if (a->q.type != b->q.type) return a->q.type < b->q.type ? -1 : 1;
    return 0;
}

/* All inliers of q among live points (parallel flagging, serial gather). */
static size_t gather_inliers(det *d, const prim *q, unsigned char *flag, uint32_t *out)
{
    const ransac_config *cfg = d->cfg;
    const frep_cloud *c = d->c;
    long ln = (long)d->n;
    /* Ctrl-C: no inliers, so an extraction in progress records nothing and the
     * detection loop stops at its next poll (a pass is ~10 ms per 10^6 points) */
    if (frep_cancelled(cfg->interrupt)) {
        memset(flag, 0, d->n);
        return 0;
    }
    kern kn;
    kern_init(&kn, q, d->band, cfg->cos_normal);
#ifdef _OPENMP
#pragma omp parallel for schedule(static, 4096) if (d->n >= PAR_MIN_WORK) num_threads(frep_threads(cfg->nthreads))
#endif
    for (long li = 0; li < ln; li++) {
        size_t i = (size_t)li;
        double x[3] = {c->x[i], c->y[i], c->z[i]}, nv[3] = {c->nx[i], c->ny[i], c->nz[i]};
        flag[i] = d->alive[i] && kern_test(&kn, x, nv);
    }
    size_t m = 0;
    for (size_t i = 0; i < d->n; i++)
        if (flag[i]) out[m++] = (uint32_t)i;
    return m;
}

static size_t support_of(det *d, const prim *q, unsigned char *flag, uint32_t *inl)
{
    size_t m = gather_inliers(d, q, flag, inl), kept;
    /* A wider band spreads a patch as much in the parameter domain. */
    if (largest_component(q, d->c, inl, m, fmax(d->cfg->cluster, d->band), &kept))
        d->nomem = 1;
    return kept;
}

/* ransac_refit of q on the n points idx within a run: 0 when q was refitted; out of
 * memory sets d->nomem. */
static int refit(det *d, prim *q, const uint32_t *idx, size_t n)
{
    int rc = ransac_refit(q, d->c, idx, n, REFIT_MAX_POINTS);
    if (rc < 0) d->nomem = 1;
    return rc;
}

/* Noise-adaptive extraction band. With Gaussian noise of about epsilon, a band of
 * epsilon holds only the middle of a surface's points and the rest come back as
 * shells of the same shape (an onion of spheres). The noise is measured on the
 * refitted shape: sigma = 1.4826 median|f| over the live, normal-compatible points
 * within NOISE_PROBE epsilons (robust to the few points of other surfaces there), and
 * the band becomes NOISE_BAND_SIGMAS sigma when that is at most NOISE_PROBE epsilons
 * (noise up to about 1.2 epsilon; beyond that, raise --epsilon). On clean or mildly
 * noisy data sigma is far below epsilon and nothing changes. */
#define NOISE_PROBE 3.0
#define NOISE_BAND_SIGMAS 2.5
static double noise_band(det *d, const prim *q, unsigned char *flag)
{
    uint32_t *tmp = d->tmp;
    double eps = d->cfg->epsilon, saved = d->band;
    d->band = NOISE_PROBE * eps;
    size_t m = gather_inliers(d, q, flag, tmp);
    d->band = saved;
    if (m < RANSAC_MIN_CLOUD) return eps;
    double *r = frep_malloc(m * sizeof *r);
    if (!r) {
        d->nomem = 1;
        return eps;
    }
    for (size_t j = 0; j < m; j++) {
        double p[3];
        point(d->c, tmp[j], p);
        r[j] = fabs(prim_eval(q, p, NULL));
    }
    /* Median by selection (Hoare's quickselect; bounded: each pass shrinks the range). */
    size_t lo = 0, hi = m - 1, k = m / 2;
    while (lo < hi) {
        double pivot = r[lo + (hi - lo) / 2];
        size_t i = lo, j = hi;
        while (i <= j) {
            while (r[i] < pivot) i++;
            while (r[j] > pivot) j--;
            if (i <= j) {
                double t = r[i];
                r[i] = r[j];
                r[j] = t;
                i++;
                if (j == 0) break;
                j--;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break;
    }
    double sigma = NOISE_MAD_TO_SIGMA * r[k];
    frep_free(r);
    /* Residuals that fill the whole probe evenly are not noise about this surface but
     * a wrong shape (a sphere touching a cone): widening would only feed it. */
    if (NOISE_BAND_SIGMAS * sigma > NOISE_PROBE * eps) return eps;
    return fmax(eps, NOISE_BAND_SIGMAS * sigma);
}

/* A curved candidate that a plane (or a cone that a cylinder) explains about as well is
 * replaced by the simpler shape: with a tolerance epsilon, a large-radius sphere or a
 * near-flat cone fits a plane's points too. inl holds q's m inliers on entry; returns
 * the support of the (possibly replaced) q; inl is then stale. */
#define SIMPLER_KEEP 0.95 /* the simpler shape must keep this fraction of the support */
/* ... and fit it about as tightly: an RMS distance of at most SIMPLER_RMS_GROWTH times
 * q's plus SIMPLER_RMS_SLACK epsilon. A plane across the middle of a small fillet holds
 * as many points within epsilon as the fillet's cylinder (the faces beside it took the
 * rest of the arc), but with the arc's sagitta as its RMS where the cylinder has ~0;
 * a large sphere standing in for a plane has the plane's RMS (the noise). */
#define SIMPLER_RMS_GROWTH 1.5
#define SIMPLER_RMS_SLACK 0.1
static double rms_of(const prim *q, const frep_cloud *c, const uint32_t *idx, size_t n);
static size_t prefer_simpler(det *d, prim *q, size_t m, unsigned char *flag, uint32_t *inl)
{
    const frep_cloud *c = d->c;
    prim alt[2];
    int nalt = 0;
    if (q->type != PRIM_PLANE && (d->cfg->types & (1u << PRIM_PLANE))) {
        prim *p = &alt[nalt++];
        memset(p, 0, sizeof *p);
        p->type = PRIM_PLANE;
        p->p[2] = 1;
    }
    if (q->type == PRIM_CONE && (d->cfg->types & (1u << PRIM_CYLINDER))) {
        prim *p = &alt[nalt++];
        memset(p, 0, sizeof *p);
        p->type = PRIM_CYLINDER;
        memcpy(p->p, q->p, sizeof q->p);
        memcpy(p->a, q->a, sizeof q->a);
        p->r = cone_mean_rho(q, c, inl, m);
    }
    uint32_t *keep = frep_malloc(m * sizeof *keep);
    if (!keep) {
        d->nomem = 1;
        return m;
    }
    memcpy(keep, inl, m * sizeof *keep);
    size_t best_m = m;
    prim best = *q;
    double rms_q = rms_of(q, c, keep, m);
    for (int k = 0; k < nalt; k++) {
        prim t = alt[k];
        if (refit(d, &t, keep, m) || !sane(&t, d->rmax)) continue;
        size_t mt = support_of(d, &t, flag, inl);
        if ((double)mt >= SIMPLER_KEEP * (double)m &&
            rms_of(&t, c, inl, mt) <= SIMPLER_RMS_GROWTH * rms_q + SIMPLER_RMS_SLACK * d->cfg->epsilon &&
            (best.type == q->type || mt > best_m)) {
            best = t;
            best_m = mt;
        }
    }
    frep_free(keep);
    *q = best;
    return best_m;
}

/* A refit is kept unless it loses more than this fraction of the support: a rough
 * candidate's band may hold a few points of a neighbouring surface that the true
 * shape (the least-squares fit) leaves out. */
#define REFIT_ACCEPT 0.97

/* Inliers of q at epsilon, refitted, then at the noise-adaptive band (noise_band)
 * and refitted again until the band settles; q is updated, inl holds its support
 * (returned) and d->band the band used. */
static size_t refit_with_band(det *d, prim *q, size_t min_pts, unsigned char *flag,
                              uint32_t *inl)
{
    d->band = d->cfg->epsilon;
    size_t m = support_of(d, q, flag, inl);
    for (int pass = 0; pass < NOISE_PASSES; pass++) {
        prim q2 = *q;
        if (m >= min_pts && refit(d, &q2, inl, m) == 0 && sane(&q2, d->rmax)) {
            size_t m2 = support_of(d, &q2, flag, inl);
            if ((double)m2 >= REFIT_ACCEPT * (double)m) {
                *q = q2;
                m = m2;
            } else {
                m = support_of(d, q, flag, inl);
            }
        }
        if (m < min_pts) break;
        double nb = noise_band(d, q, flag);
        if (nb <= d->band * NOISE_BAND_GROWTH) break;
        d->band = nb;
        m = support_of(d, q, flag, inl);
    }
    return m;
}

static double rms_of(const prim *q, const frep_cloud *c, const uint32_t *idx, size_t n)
{
    double s = 0;
    for (size_t j = 0; j < n; j++) {
        double p[3];
        point(c, idx[j], p);
        double f = prim_eval(q, p, NULL);
        s += f * f;
    }
    return n ? sqrt(s / (double)n) : 0;
}

/* A measure of q at cloud point i, whose median median_over takes. */
typedef double (*point_measure)(const prim *q, const frep_cloud *c, size_t i);

/* The median of fn over (an evenly spaced subset of at most MODE_VOTERS of) the points
 * idx[0..n) into *med (0 when n is 0). Returns 0, or -1 when out of memory (d->nomem
 * set). */
#define MODE_VOTERS 4096
static int median_over(det *d, const prim *q, const uint32_t *idx, size_t n,
                       point_measure fn, double *med)
{
    size_t k = n < MODE_VOTERS ? n : MODE_VOTERS;
    *med = 0;
    if (k == 0) return 0;
    double *r = frep_malloc(k * sizeof *r);
    if (!r) {
        d->nomem = 1;
        return -1;
    }
    for (size_t j = 0; j < k; j++)
        r[j] = fn(q, d->c, idx[(size_t)((double)j * (double)n / (double)k)]);
    qsort(r, k, sizeof *r, cmp_double);
    *med = r[k / 2];
    frep_free(r);
    return 0;
}

/* |f| of q at point i. */
static double abs_value(const prim *q, const frep_cloud *c, size_t i)
{
    double p[3];
    point(c, i, p);
    return fabs(prim_eval(q, p, NULL));
}

/* f of q at point i: signed, positive on the side the normal points to. */
static double signed_value(const prim *q, const frep_cloud *c, size_t i)
{
    double p[3];
    point(c, i, p);
    return prim_eval(q, p, NULL);
}

/* Median |f| of q over the points idx[0..n) (median_over). */
static int median_abs(det *d, const prim *q, const uint32_t *idx, size_t n, double *med)
{
    return median_over(d, q, idx, n, abs_value, med);
}

/* Shapes across faces. A plane's band (epsilon, or wider on noisy data) and normal
 * threshold also hold nearby faces of the same or a similar orientation: the two
 * walls of a thin shell 2 epsilon apart (the least-squares plane then lies between
 * them, explaining neither), a staircase of parallel faces (a tilted plane through
 * all of them), a face and its neighbour meeting at 10-20 degrees (a plane tilted
 * between them); and a curved shape of large radius or a flat cone can lie across
 * two or three such faces. The face is found from the inliers' own normals and
 * offsets: the dominant normal (the inlier normal with the most others within
 * MODE_NORMAL_DEG), then the densest slab of offsets along it, MODE_SLAB bands wide.
 * The plane refitted on that slab, extracted as a fresh shape (at epsilon, then at its
 * own measured noise), replaces q when the median distance of its inliers is below
 * MODE_GAIN of q's. One face under noise gives the same plane
 * and about the same median, so noisy data keep their fit; a mixed shape's median is
 * of the order of the faces' spacing, a pure plane's of the noise. A curved shape is
 * examined only when the dominant normal holds MODE_FLAT of its inliers: the facets of
 * a facetted cylinder or sphere each hold a few percent. */
#define MODE_NORMAL_DEG 8.0
#define MODE_SLAB 0.5
#define MODE_GAIN 0.5
#define MODE_FLAT 0.5
/* A median distance under this fraction of epsilon is an exact fit (clean data, one
 * face): nothing to separate, and the search is skipped. */
#define MODE_EXACT 1e-3
/* Inliers examined as centres of the dominant normal (a fixed subset bounds the
 * quadratic count; the voters are MODE_VOTERS). */
#define MODE_CENTRES 256
static int cmp_mode_t(const void *a, const void *b)
{
    double x = ((const double *)a)[0], y = ((const double *)b)[0];
    return (x > y) - (x < y);
}

/* Is unit normal n within the cone of cosine cosm (either way) of one of the nskip
 * normals skip[3 i ..]? */
static int near_any(const double *skip, int nskip, const double n[3], double cosm)
{
    for (int i = 0; i < nskip; i++)
        if (fabs(vec3_dot(skip + 3 * i, n)) >= cosm) return 1;
    return 0;
}

/* The dominant normal among q's m inliers: the centre (of MODE_CENTRES evenly spaced
 * ones) with the most of MODE_VOTERS voters within MODE_NORMAL_DEG (voters within it of
 * one of the nskip normals skip left out: the next mode); its inlier index, with its
 * vote count in *count. */
static size_t dominant_normal(const frep_cloud *c, const uint32_t *inl, size_t m, double cosm,
                              const double *skip, int nskip, size_t *count)
{
    size_t nv = m < MODE_VOTERS ? m : MODE_VOTERS, ncen = m < MODE_CENTRES ? m : MODE_CENTRES;
    size_t best_cnt = 0, best_j = 0;
    for (size_t k = 0; k < ncen; k++) {
        size_t j = (size_t)((double)k * (double)m / (double)ncen);
        double nj[3];
        normal(c, inl[j], nj);
        size_t cnt = 0;
        for (size_t v = 0; v < nv; v++) {
            double nk[3];
            normal(c, inl[(size_t)((double)v * (double)m / (double)nv)], nk);
            cnt += fabs(vec3_dot(nj, nk)) >= cosm && !near_any(skip, nskip, nk, cosm);
        }
        if (cnt > best_cnt) {
            best_cnt = cnt;
            best_j = j;
        }
    }
    *count = best_cnt;
    return best_j;
}

/* The inliers whose normal is within MODE_NORMAL_DEG of nc (either way): their indices
 * into tv[2 j + 1], their summed normal (oriented as nc) into ns. Returns the count. */
static size_t dominant_group(const frep_cloud *c, const uint32_t *inl, size_t m,
                             const double nc[3], double cosm, double ns[3], double *tv)
{
    size_t nt = 0;
    for (size_t j = 0; j < m; j++) {
        double nj[3];
        normal(c, inl[j], nj);
        double cs = vec3_dot(nj, nc);
        if (fabs(cs) < cosm) continue;
        for (int k = 0; k < 3; k++) ns[k] += cs < 0 ? -nj[k] : nj[k];
        tv[2 * nt + 1] = (double)inl[j];
        nt++;
    }
    return nt;
}

/* The densest slab, w wide, of the group's offsets along unit ns: its points into
 * slab (returns their count) and the plane through its middle point into alt. */
static size_t densest_slab(const frep_cloud *c, double *tv, size_t nt, const double ns[3],
                           double w, uint32_t *slab, prim *alt)
{
    for (size_t j = 0; j < nt; j++) {
        double x[3];
        point(c, (size_t)tv[2 * j + 1], x);
        tv[2 * j] = vec3_dot(ns, x);
    }
    qsort(tv, nt, 2 * sizeof *tv, cmp_mode_t);
    size_t lo = 0, blo = 0, bhi = 0;
    for (size_t hi = 0; hi < nt; hi++) {
        while (tv[2 * hi] - tv[2 * lo] > w) lo++;
        if (hi - lo > bhi - blo) {
            blo = lo;
            bhi = hi;
        }
    }
    size_t ns_pts = 0;
    for (size_t j = blo; j <= bhi; j++) slab[ns_pts++] = (uint32_t)tv[2 * j + 1];
    memset(alt, 0, sizeof *alt);
    alt->type = PRIM_PLANE;
    memcpy(alt->p, ns, 3 * sizeof *ns);
    alt->r = tv[2 * ((blo + bhi) / 2)];
    return ns_pts;
}

/* A noisy cloud: measured noise at least NOISY_EPSILON_SHARE of epsilon (the default
 * epsilon is 5 noise deviations, or less where capped; on clean samples it is its
 * floor, far above the noise). Samples of a facetted mesh (InverseCSG's coarse meshes,
 * 12-sided prisms) are not noisy: their cylinders' facet normals are 7 degrees off in
 * the median, and are what the curved shapes there must explain. */
#define NOISY_EPSILON_SHARE 0.1
int ransac_noisy(double noise, double epsilon)
{
    return noise >= NOISY_EPSILON_SHARE * epsilon && noise > 0;
}

static int noisy(const det *d) { return ransac_noisy(d->cfg->noise, d->cfg->epsilon); }

/* Under noise, does a curved shape's normals hold two modes (the first, nc, with
 * best_cnt voters) that together make MODE_FACES of its voters? A cylinder of a
 * radius like the faces' size, its axis along their edge, lies within the band of two
 * faces meeting at 30-60 degrees over most of their width; a true cylinder's normals
 * spread over its arc, a few percent in each mode. */
#define MODE_FACES 0.7
static int two_faces(const det *d, const uint32_t *inl, size_t m, double cosm,
                     const double nc[3], size_t best_cnt)
{
    if (!noisy(d)) return 0;
    size_t nv = m < MODE_VOTERS ? m : MODE_VOTERS, cnt2;
    dominant_normal(d->c, inl, m, cosm, nc, 1, &cnt2);
    return (double)(best_cnt + cnt2) >= MODE_FACES * (double)nv;
}

/* The share of the voters among q's m inliers whose normals lie within MODE_NORMAL_DEG
 * of their FACE_MODES most common directions (taken one after the other). */
#define FACE_MODES 3
static double faces_share(const frep_cloud *c, const uint32_t *inl, size_t m, double cosm)
{
    size_t nv = m < MODE_VOTERS ? m : MODE_VOTERS, sum = 0;
    double modes[3 * FACE_MODES];
    for (int k = 0; k < FACE_MODES && nv > 0; k++) {
        size_t cnt, j = dominant_normal(c, inl, m, cosm, modes, k, &cnt);
        normal(c, inl[j], modes + 3 * k);
        sum += cnt;
    }
    return nv > 0 ? (double)sum / (double)nv : 0;
}

/* The share of the voters among torus q's m inliers whose normals' angles around the
 * tube (from the equator's plane, in the section through the axis) lie within
 * MODE_NORMAL_DEG of their FACE_MODES most common angles (taken one after the other).
 * A torus across a disc's top and the two coaxial walls below it (mount's bore inside
 * its disc) holds faces whose normals are one angle each (90, 0 and 180 degrees) but
 * turn around the axis, so faces_share does not see the two walls as modes; a fillet's
 * normals spread over its angles. Out of memory: 0, and d->nomem set. */
static double tube_share(det *d, const prim *q, const uint32_t *inl, size_t m)
{
    const frep_cloud *c = d->c;
    size_t nv = m < MODE_VOTERS ? m : MODE_VOTERS, sum = 0;
    if (nv == 0) return 0;
    double *v = frep_malloc(nv * sizeof *v);
    size_t *pre = frep_malloc((nv + 1) * sizeof *pre);
    unsigned char *used = frep_calloc(nv, 1);
    if (!v || !pre || !used) {
        frep_free(v);
        frep_free(pre);
        frep_free(used);
        d->nomem = 1;
        return 0;
    }
    for (size_t j = 0; j < nv; j++) {
        size_t i = inl[(size_t)((double)j * (double)m / (double)nv)];
        double p[3], n[3], g[3], e[3];
        point(c, i, p);
        normal(c, i, n);
        prim_eval(q, p, g);
        double sg = vec3_dot(n, g) < 0 ? -1 : 1;
        for (int k = 0; k < 3; k++) n[k] *= sg;
        vec3_sub(p, q->p, e);
        double h = vec3_dot(e, q->a);
        for (int k = 0; k < 3; k++) e[k] -= h * q->a[k];
        double el = vec3_len(e);
        v[j] = atan2(vec3_dot(n, q->a), el > 0 ? vec3_dot(n, e) / el : 0);
    }
    qsort(v, nv, sizeof *v, cmp_double);
    double w = 2 * MODE_NORMAL_DEG * FREP_PI / 180.0;
    for (int k = 0; k < FACE_MODES; k++) {
        pre[0] = 0;
        for (size_t j = 0; j < nv; j++) pre[j + 1] = pre[j] + !used[j];
        size_t lo = 0, blo = 0, bhi = 0, best = 0;
        for (size_t hi = 0; hi < nv; hi++) {
            while (v[hi] - v[lo] > w) lo++;
            if (pre[hi + 1] - pre[lo] > best) {
                best = pre[hi + 1] - pre[lo];
                blo = lo;
                bhi = hi;
            }
        }
        for (size_t j = blo; best > 0 && j <= bhi; j++) used[j] = 1;
        sum += best;
    }
    frep_free(v);
    frep_free(pre);
    frep_free(used);
    return (double)sum / (double)nv;
}

/* Does a face with ma inliers of median distance meda replace q (median med0)? When it
 * halves the median (MODE_GAIN) and has the phase's minimum support. Under noise both
 * medians are the noise's, and a curved shape that spans a small face and a little of
 * its neighbours (a cone over a block's top, a cylinder tilted across its side) is as
 * tight as the face: there the face replaces a curved q when its median is at most
 * MODE_NOISE_MEDIAN q's and it keeps MODE_FACE_KEEP of the mode_pts inliers whose
 * normals made it, whatever the phase's minimum (a face just under it loses its
 * points to any curved shape that reaches past its edges). */
#define MODE_NOISE_MEDIAN 1.1
#define MODE_FACE_KEEP 0.8
static int face_better(const det *d, const prim *q, double mode_pts, size_t ma, size_t min_pts,
                       double meda, double med0)
{
    if (ma >= min_pts && meda < MODE_GAIN * med0) return 1;
    return q->type != PRIM_PLANE && noisy(d) &&
           (double)ma >= MODE_FACE_KEEP * mode_pts && meda <= MODE_NOISE_MEDIAN * med0;
}

/* The plane alt refitted on the slab, extracted as a fresh shape (at epsilon, then at
 * its own measured noise: q's band may have been widened by the mixture itself): its
 * support (inliers in inl) when it is better than q (face_better), else 0. */
static size_t try_face(det *d, const prim *q, double mode_pts, prim *alt, const uint32_t *slab,
                       size_t ns_pts, size_t min_pts, double med0, unsigned char *flag,
                       uint32_t *inl)
{
    if (ns_pts < 3 || refit(d, alt, slab, ns_pts) != 0) return 0;
    d->band = d->cfg->epsilon;
    double nb = noise_band(d, alt, flag);
    if (nb > d->band * NOISE_BAND_GROWTH) d->band = nb;
    size_t ma = support_of(d, alt, flag, inl);
    double meda;
    if (ma < 3 || median_abs(d, alt, inl, ma, &meda)) return 0;
    return face_better(d, q, mode_pts, ma, min_pts, meda, med0) ? ma : 0;
}

/* q's m inliers (inl) searched for a face (see "Shapes across faces"): a curved q is
 * searched when its dominant normal holds MODE_FLAT of them, when they make two faces,
 * or when force is set. Returns the support of q, replaced by the face or not; inl then
 * holds it. */
static size_t face_modes(det *d, prim *q, size_t m, size_t min_pts, int force,
                         unsigned char *flag, uint32_t *inl)
{
    const frep_cloud *c = d->c;
    if (m < min_pts || m < RANSAC_MIN_CLOUD || !c->has_normals ||
        !(d->cfg->types & (1u << PRIM_PLANE)))
        return m;
    double med0, band0 = d->band;
    /* Exact already (clean data): nothing to separate. */
    if (median_abs(d, q, inl, m, &med0) || !(med0 > MODE_EXACT * d->cfg->epsilon)) return m;
    double cosm = cos(MODE_NORMAL_DEG * FREP_PI / 180.0);
    size_t nv = m < MODE_VOTERS ? m : MODE_VOTERS;
    double *tv = frep_malloc(2 * m * sizeof *tv);
    uint32_t *slab = frep_malloc(m * sizeof *slab);
    if (!tv || !slab) {
        frep_free(tv);
        frep_free(slab);
        d->nomem = 1;
        return m;
    }
    size_t best_cnt, best_j = dominant_normal(c, inl, m, cosm, NULL, 0, &best_cnt);
    double nc[3], ns[3] = {0, 0, 0};
    normal(c, inl[best_j], nc);
    size_t nt = 0, ma = 0;
    if (q->type == PRIM_PLANE || force || (double)best_cnt >= MODE_FLAT * (double)nv ||
        two_faces(d, inl, m, cosm, nc, best_cnt))
        nt = dominant_group(c, inl, m, nc, cosm, ns, tv);
    if (nt >= RANSAC_MIN_CLOUD && vec3_normalize(ns) == 0) {
        prim alt;
        size_t ns_pts = densest_slab(c, tv, nt, ns, MODE_SLAB * band0, slab, &alt);
        ma = try_face(d, q, (double)best_cnt * (double)m / (double)nv, &alt, slab, ns_pts,
                      min_pts, med0, flag, inl);
        if (ma > 0) *q = alt;
    }
    frep_free(tv);
    frep_free(slab);
    if (ma > 0) return ma;
    /* Keep q: its inliers back. */
    d->band = band0;
    return support_of(d, q, flag, inl);
}

/* A primitive is redundant when at least MERGE_FRACTION of its inliers are inliers of
 * a larger one (at MERGE_BAND_SLACK times that one's band) and the two patches touch
 * in the larger one's parameter domain, or are one surface apart (the same shape
 * within the band). That is a facetted cylinder split in two, the outer rim of a noisy
 * torus taken by a sphere, a torus made of the leftovers around a facetted sphere, or
 * a face split in two by a part standing on it. */
#define MERGE_FRACTION 0.8
#define MERGE_BAND_SLACK 1.5
/* The union of the two patches must be one connected patch up to this fraction. */
#define MERGE_CONNECTED 0.95
/* The primitive refitted on the union may have an RMS distance of at most this many
 * times the larger of the two parts' plus this fraction of epsilon (clean parts have
 * RMS near 0; a facetted cylinder's halves have the chord error, and so has the union). */
#define MERGE_RMS_GROWTH 2.0
#define MERGE_RMS_SLACK 0.1
/* A part whose points share cells (of the cluster size) with the larger one's less than
 * MERGE_OVERLAP lies beside it, and folds into it only when the median signed distance
 * of its points from the union's shape is within MERGE_OFFSET epsilon. At 0.5% noise the
 * parts folded as one face were within 0.22 epsilon (0.00-0.22 over six InverseCSG
 * parts); a pocket's floor beside a plate was 1.01 away, and two parallel faces of
 * six_cuboids 0.67 and 1.18 (kept apart, one or two more true faces per seed). */
#define MERGE_OVERLAP 0.5
#define MERGE_OFFSET 0.5

/* Parameters of two primitives of one type closer than tol (lengths) and MERGE_DEG
 * (directions): worth trying as one. */
#define MERGE_NEAR 4.0
#define MERGE_DEG 10.0
static int near_same(const prim *a, const prim *b, double tol)
{
    return shapes_close(a, b, tol, MERGE_DEG);
}

/* The inliers of each primitive, contiguous: those of j are order[start[j] ..
 * start[j + 1]) (a counting sort by label). */
static void inliers_by_label(const ransac_result *res, size_t n, size_t *start, uint32_t *order)
{
    size_t np = res->nprims;
    for (size_t i = 0; i < n; i++)
        if (res->label[i] >= 0) start[res->label[i] + 1]++;
    for (size_t j = 0; j < np; j++) start[j + 1] += start[j];
    for (size_t i = 0; i < n; i++)
        if (res->label[i] >= 0) order[start[res->label[i]]++] = (uint32_t)i;
    for (size_t j = np; j > 0; j--) start[j] = start[j - 1];
    start[0] = 0;
}

/* The merge state of one pass: the inliers by label and a scratch list. */
typedef struct merger {
    det *d;
    ransac_result *res;
    double *bands;
    size_t *start;
    uint32_t *order;
    uint32_t *buf;       /* the union: Q's inliers, then P's */
} merger;

/* Does primitive pi fold into the larger qi (see MERGE_FRACTION)? Then *q2 is the
 * shape of the union (buf[0 .. mu)) and *refitted says whether it was refitted. */
static int mergeable(merger *g, size_t pi, size_t qi, prim *q2, int *refitted)
{
    det *d = g->d;
    const frep_cloud *c = d->c;
    const prim *P = &g->res->prims[pi], *Q = &g->res->prims[qi];
    size_t mp = g->start[pi + 1] - g->start[pi], mq = g->start[qi + 1] - g->start[qi];
    double band = MERGE_BAND_SLACK * fmax(g->bands[qi], g->bands[pi]);
    size_t hit = 0, mu = mp + mq;
    for (size_t j = g->start[pi]; j < g->start[pi + 1]; j++)
        hit += compatible(Q, c, g->order[j], band, d->cfg->cos_normal) != 0;
    int apart = (double)hit < MERGE_FRACTION * (double)mp;
    /* Two pieces of one shape fitted apart (a noisy torus split into inner and outer
     * halves): one shape of the same type explains both once refitted on the union.
     * Tested before the refit, the cost of a pair. */
    if (apart && (P->type != Q->type || !near_same(P, Q, MERGE_NEAR * band))) return 0;
    memcpy(g->buf, g->order + g->start[qi], mq * sizeof *g->buf);
    memcpy(g->buf + mq, g->order + g->start[pi], mp * sizeof *g->buf);
    *q2 = *Q;
    *refitted = refit(d, q2, g->buf, mu) == 0 && sane(q2, d->rmax);
    if (apart) {
        if (!*refitted) return 0;
        size_t hu = 0;
        for (size_t j = 0; j < mu; j++)
            hu += compatible(q2, c, g->buf[j], band, d->cfg->cos_normal) != 0;
        if ((double)hu < MERGE_FRACTION * (double)mu) return 0;
    }
    /* The union must be about as tight as its parts: two walls of a thin shell, 2
     * epsilon apart, are both within the slack band of the plane between them, which
     * explains neither. */
    if (*refitted && rms_of(q2, c, g->buf, mu) > MERGE_RMS_GROWTH * fmax(P->rms, Q->rms) +
                                                   MERGE_RMS_SLACK * d->cfg->epsilon)
        return 0;
    /* Beside Q's patch rather than over it, P is the same surface only at Q's level: a
     * pocket's floor 1.0 epsilon above the plate around it is within the slack band
     * under noise, and its patch touches the plate's at cells that wide. */
    const prim *U = *refitted ? q2 : Q;
    double share, off;
    if (patch_overlap(U, c, g->buf, mq, mp, d->cfg->cluster, &share) ||
        median_over(d, U, g->order + g->start[pi], mp, signed_value, &off)) {
        d->nomem = 1;
        return 0;
    }
    if (share < MERGE_OVERLAP && fabs(off) > MERGE_OFFSET * d->cfg->epsilon) return 0;
    /* Touching: one patch in Q's parameter domain. */
    size_t kept;
    if (largest_component(*refitted ? q2 : Q, c, g->buf, mu, fmax(d->cfg->cluster, band),
                          &kept)) {
        d->nomem = 1;
        return 0;
    }
    if ((double)kept >= MERGE_CONNECTED * (double)mu) return 1;
    /* Apart, but one surface: the same shape within the band (a face split in two by a
     * part standing on it, a bore interrupted by a slot). The tree needs it once. */
    return P->type == Q->type && *refitted && same_shape(P, Q, band) && same_shape(q2, Q, band);
}

/* Fold pi into qi: qi becomes q2 (when refitted) with the union's support and RMS, the
 * labels of pi move to qi, and pi leaves the list (later ones shift, labels follow). */
static void fold(merger *g, size_t pi, size_t qi, const prim *q2, int refitted)
{
    ransac_result *res = g->res;
    const frep_cloud *c = g->d->c;
    size_t np = res->nprims, n = c->n;
    size_t mp = g->start[pi + 1] - g->start[pi], mq = g->start[qi + 1] - g->start[qi];
    size_t mu = mp + mq;
    memcpy(g->buf, g->order + g->start[qi], mq * sizeof *g->buf);
    memcpy(g->buf + mq, g->order + g->start[pi], mp * sizeof *g->buf);
    if (refitted) res->prims[qi] = *q2;
    res->prims[qi].support = mu;
    res->prims[qi].rms = rms_of(&res->prims[qi], c, g->buf, mu);
    for (size_t j = g->start[pi]; j < g->start[pi + 1]; j++)
        res->label[g->order[j]] = (int32_t)qi;
    for (size_t k = pi; k + 1 < np; k++) {
        res->prims[k] = res->prims[k + 1];
        g->bands[k] = g->bands[k + 1];
    }
    for (size_t i = 0; i < n; i++)
        if (res->label[i] > (int32_t)pi) res->label[i]--;
    res->nprims--;
}

/* One pass: the first pair (pi into a larger qi) that merges is folded. Returns 1 when
 * one was. */
static int merge_pass(merger *g)
{
    size_t np = g->res->nprims;
    for (size_t pi = 0; pi < np; pi++) {
        size_t mp = g->start[pi + 1] - g->start[pi];
        for (size_t qi = 0; qi < np; qi++) {
            size_t mq = g->start[qi + 1] - g->start[qi];
            if (qi == pi || mq < mp || (mq == mp && qi > pi)) continue;
            const ransac_config *cfg = g->d->cfg;
            if (cfg->progress)
                cfg->progress(cfg->user, "merge", g->d->nalive, g->d->n, g->res->nprims);
            if (frep_cancelled(cfg->interrupt)) return 0;
            prim q2;
            int refitted;
            if (!mergeable(g, pi, qi, &q2, &refitted)) {
                if (g->d->nomem) return 0;
                continue;
            }
            fold(g, pi, qi, &q2, refitted);
            return 1;
        }
    }
    return 0;
}

/* Fold redundant primitives into the ones that explain their points: labels move,
 * the larger primitive is refitted on the union, and the list is compacted. Every
 * fold removes a primitive, so the loop ends. Out of memory sets d->nomem. */
static void merge_redundant(det *d, ransac_result *res, double *bands, uint32_t *buf)
{
    size_t n = d->c->n;
    for (int changed = 1; changed && res->nprims > 1;) {
        merger g = {d, res, bands, frep_calloc(res->nprims + 1, sizeof(size_t)),
                    frep_malloc((n + 1) * sizeof(uint32_t)), buf};
        if (!g.start || !g.order) {
            frep_free(g.start);
            frep_free(g.order);
            d->nomem = 1;
            return;
        }
        inliers_by_label(res, n, g.start, g.order);
        changed = merge_pass(&g);
        frep_free(g.start);
        frep_free(g.order);
    }
}

/* Second phase of detection (ransac_config.min_points_small): once no shape of
 * min_points is left, detection goes on down to min_points_small, for the small faces
 * of a part (the top of a thin wall, a rounded corner). Among few points a rough
 * shape fits leftovers as easily as a surface (strips along sharp edges on noisy
 * data), so a small shape is kept only when the median distance of its inliers is
 * below SMALL_TIGHT epsilon: on clean or mildly noisy data (noise under about 0.3
 * epsilon, facetted meshes) small surfaces are found, on noisy data nothing is added. */
#define SMALL_TIGHT 0.2
/* ... or below this many noise deviations when the noise is measured and the epsilon
 * is capped below SEGMENT_EPSILON_SIGMAS of it (0.5% noise on a part: epsilon 2.5
 * deviations, so 0.2 epsilon is 0.5 of one, under the 0.67 that the median distance
 * of a true surface's noisy points has, and the noise measured by segment.c's 16-point
 * fits is about 0.75 of the true one): the caps of the corner spheres of a frame at
 * 0.5% noise, what the rails leave of them, fit their points within 1.1-1.4 of it. */
#define SMALL_TIGHT_SIGMAS 1.5
/* ... and when the patch is at least SMALL_WIDTH epsilon wide (the width of a uniform
 * strip with the patch's second principal variance, sqrt(12 var)): what is left along
 * a sharp edge once both faces are extracted (where estimated normals turn from one
 * face to the other) is a strip narrower than epsilon that a thin cylinder or torus
 * fits tightly; the smallest faces worth finding (the top of a wall 2 epsilon thick,
 * a step 2 epsilon high) are wider. */
#define SMALL_WIDTH 1.5
/* A leftover strip around a circular edge (a cone's cap) is a ring, wide by that
 * measure, which a thin torus fits: small shapes are planes, spheres and cylinders
 * only (what small features of parts are: faces, rounded corners and edges), of radius
 * at least SMALL_RADIUS epsilon. */
#define SMALL_RADIUS 2.0
/* ... and the median angle between the inliers' normals and the shape's is at most
 * SMALL_NORMAL_DEG: the normals of a real face agree with it (exactly on clean data,
 * within half a facet angle on a facetted mesh), while the blended normals along an
 * edge, which a sphere through the edge's circle fits within the normal threshold,
 * turn across the strip. */
#define SMALL_NORMAL_DEG 5.0
/* ... except on a wide face (a plane whose patch is at least SMALL_FACE_WIDTH epsilon
 * wide), whose normals may deviate up to SMALL_FACE_NOISE times the median deviation
 * of the normals on the planes the first phase found: that is the estimate's own error
 * on this cloud (2.9-4.7 degrees at 0.5-1% noise), and a small face's points lie
 * nearer its edges, where neighbourhoods reach across (a block's side beside the disc
 * it stands on, 369 points and 5.4 degrees; the face of a sphere's thin cap, 199 points
 * and 6.1 degrees, at 0.5% noise).  A plane across a curved surface or along an edge
 * is not both: within a band its width is that of the sagitta, about 2 sqrt(2 R band),
 * and its normals turn by a quarter of width / R at the median (14 degrees at the
 * widest on a cylinder of radius 1.04 at 0.5% noise), while the plane strips that
 * pass the other tests at 1% noise are at most 2 epsilon wide. */
#define SMALL_FACE_WIDTH 3.0
#define SMALL_FACE_NOISE 2.0
/* ... and a small sphere's up to SMALL_SPHERE_NOISE times it: at 1% noise the corner
 * spheres of a frame (what the rails leave of them) deviate 1.05-1.3 times the planes'
 * deviation (base: 5.2-6.05 degrees against 4.65), while the spheres that fit the
 * blended normals along the edges of stacked cuboids deviate 2-3.5 times it (six_cuboids
 * at 1% noise: 10.9 degrees and more against 7.57). */
#define SMALL_SPHERE_NOISE 1.35
/* Where the noise is wider than epsilon (1% noise: epsilon is capped at 1% of the
 * diagonal, about one deviation), a small curved shape's band is widened to its own
 * residuals (NOISE_BAND_SIGMAS deviations, refit_with_band) and its inliers are tight
 * when their median distance is at most SMALL_TIGHT_BAND times that band: a surface's
 * noisy points have 0.674 deviations, 0.27 of the band, points filling the band evenly
 * (a strip along an edge) 0.5 of it, while 0.5 epsilon, small_tight's cap, is what
 * even a true surface's points in an epsilon of one deviation have (base's corner
 * spheres at 1% noise: 0.066-0.079 against 0.068).  Not for planes: along the edges of
 * stacked cuboids at 1% noise it kept strips as faces (two_spheres_one_cuboid 2 -> 7
 * spurious). */
#define SMALL_TIGHT_BAND 0.35
/* The angle between point i's normal and q's gradient there (pi/2 without one). */
static double normal_angle(const prim *q, const frep_cloud *c, size_t i)
{
    double p[3], g[3], nv[3];
    point(c, i, p);
    normal(c, i, nv);
    prim_eval(q, p, g);
    double gl = vec3_len(g), cs = gl > 0 ? fabs(vec3_dot(g, nv)) / gl : 0;
    return acos(fmin(1, cs));
}

static double patch_width(const frep_cloud *c, const uint32_t *idx, size_t n)
{
    size_t k = n < MODE_VOTERS ? n : MODE_VOTERS;
    if (k < 3) return 0;
    double mean[3] = {0, 0, 0}, cov[9] = {0}, ev[3], vec[9];
    for (size_t j = 0; j < k; j++) {
        double p[3];
        point(c, idx[(size_t)((double)j * (double)n / (double)k)], p);
        for (int a = 0; a < 3; a++) mean[a] += p[a] / (double)k;
    }
    for (size_t j = 0; j < k; j++) {
        double p[3];
        point(c, idx[(size_t)((double)j * (double)n / (double)k)], p);
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                cov[3 * a + b] += (p[a] - mean[a]) * (p[b] - mean[b]) / (double)k;
    }
    normals_sym3_eig(cov, ev, vec);
    return sqrt(12.0 * fmax(0, ev[1]));
}

/* ---- the driver ------------------------------------------------------------------ */

/* One detection run (ransac_detect): the point structures, the candidate pool, the
 * result being built and the counters of the stopping rules. */
typedef struct run {
    det d;
    rng rng;              /* the seeded generator: subsets, then every sample */
    ransac_result *res;
    double *bands;        /* extraction band of each primitive of res (for the merge) */
    size_t cap_prims;     /* room in res->prims and bands */
    cand *pool;           /* candidates alive, at most MAX_POOL */
    size_t npool;
    int *which;           /* scratch: pool indices to score */
    uint32_t *inl;        /* inliers of the shape being extracted */
    unsigned char *flag;  /* scratch: per point, inlier of that shape */
    size_t ntypes;        /* types detected (at least 1) */
    size_t min_pts;       /* smallest support of the current phase */
    size_t small_pts;     /* smallest support of the second phase */
    int phase;            /* 0: shapes of min_points; 1: small shapes */
    size_t first_small;   /* index in res->prims of the first small shape */
    size_t draws_since;   /* minimal samples drawn since the last extraction */
    double log_fail;      /* log(1 - probability): the acceptance threshold */
    double normal_dev;    /* median normal deviation on the first phase's planes */
} run;

/* Free what run_alloc and build_octree allocated (not the result). */
static void run_free(run *r)
{
    det *d = &r->d;
    frep_free(r->bands);
    frep_free(d->alive);
    frep_free(d->shuf);
    frep_free(d->spts);
    frep_free(d->salive);
    frep_free(d->tmp);
    frep_free(d->morton_idx);
    frep_free(d->morton);
    frep_free(d->alive_list);
    frep_free(r->pool);
    frep_free(r->which);
    frep_free(r->inl);
    frep_free(r->flag);
}

/* The buffers of a run and of its result, every point alive and unlabelled; 0, or -1
 * with err set (out of memory, or a cloud without normals). */
static int run_alloc(run *r, const frep_cloud *c, const ransac_config *cfg,
                     ransac_result *res, frep_error *err)
{
    det *d = &r->d;
    size_t n = c->n;
    memset(r, 0, sizeof *r);
    d->c = c;
    d->cfg = cfg;
    d->n = n;
    r->res = res;
    r->cap_prims = 16;
    r->bands = frep_malloc(r->cap_prims * sizeof *r->bands);
    res->label = frep_malloc((n ? n : 1) * sizeof *res->label);
    res->prims = frep_malloc(r->cap_prims * sizeof *res->prims);
    d->alive = frep_malloc(n + 1);
    d->shuf = frep_malloc((n + 1) * sizeof *d->shuf);
    d->spts = frep_malloc((6 * n + 6) * sizeof *d->spts);
    d->salive = frep_malloc(n + 1);
    d->tmp = frep_malloc((n + 1) * sizeof *d->tmp);
    d->morton_idx = frep_malloc((n + 1) * sizeof *d->morton_idx);
    d->morton = frep_malloc((2 * n + 2) * sizeof *d->morton);
    d->alive_list = frep_malloc((n + 1) * sizeof *d->alive_list);
    r->pool = frep_malloc(MAX_POOL * sizeof *r->pool);
    r->which = frep_malloc(MAX_POOL * sizeof *r->which);
    r->inl = frep_malloc((n + 1) * sizeof *r->inl);
    r->flag = frep_malloc(n + 1);
    if (!r->bands || !d->tmp || !d->spts || !d->salive || !res->label || !res->prims ||
        !d->alive || !d->shuf || !d->morton_idx || !d->morton || !d->alive_list || !r->pool ||
        !r->which || !r->inl || !r->flag || !c->has_normals) {
        if (!c->has_normals) return frep_error_set(err, FREP_EINPUT, "the cloud has no normals");
        return frep_error_nomem(err);
    }
    for (size_t i = 0; i < n; i++) {
        res->label[i] = -1;
        d->alive[i] = 1;
    }
    d->rmax = MAX_RADIUS_DIAGONALS * fmax(cloud_diagonal(c), 1e-300);
    return 0;
}

/* The octree as Morton order over the bounding cube: d->morton holds the sorted codes,
 * then (from n + 1) each point's code by index; d->morton_idx the points in that order.
 * Returns -1 when out of memory. */
static int build_octree(det *d)
{
    const frep_cloud *c = d->c;
    size_t n = d->n;
    mkey *mk = frep_malloc((n + 1) * sizeof *mk);
    if (!mk) return -1;
    double lo[3], hi[3];
    cloud_bbox(c, lo, hi);
    double side = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    if (!(side > 0)) side = 1;
    double cells = (double)(1u << OCT_LEVELS);
    for (size_t i = 0; i < n; i++) {
        double p[3];
        point(c, i, p);
        uint64_t code = 0;
        for (int k = 0; k < 3; k++) {
            double t = floor((p[k] - lo[k]) / side * cells);
            if (t < 0) t = 0;
            if (t > cells - 1) t = cells - 1;
            code |= spread3((uint64_t)t) << (2 - k);
        }
        mk[i].code = code;
        mk[i].i = (uint32_t)i;
    }
    qsort(mk, n, sizeof *mk, cmp_mkey);
    for (size_t j = 0; j < n; j++) {
        d->morton[j] = mk[j].code;
        d->morton_idx[j] = mk[j].i;
        d->morton[n + 1 + mk[j].i] = mk[j].code;
    }
    d->morton[n] = 0;
    frep_free(mk);
    return 0;
}

/* Scoring subsets: a seeded permutation of the points (with their normals copied in
 * that order, so that scoring streams through memory) cut into doubling blocks. */
static void build_subsets(det *d, rng *r)
{
    const frep_cloud *c = d->c;
    size_t n = d->n;
    for (size_t i = 0; i < n; i++) d->shuf[i] = (uint32_t)i;
    for (size_t i = n; i > 1; i--) {
        size_t j = rng_below(r, i);
        uint32_t t = d->shuf[i - 1];
        d->shuf[i - 1] = d->shuf[j];
        d->shuf[j] = t;
    }
    for (size_t j = 0; j < n; j++) {
        uint32_t i = d->shuf[j];
        double *sp = d->spts + 6 * j;
        sp[0] = c->x[i];
        sp[1] = c->y[i];
        sp[2] = c->z[i];
        sp[3] = c->nx[i];
        sp[4] = c->ny[i];
        sp[5] = c->nz[i];
    }
    d->sub_start[0] = 0;
    size_t sz = SUBSET_FIRST;
    d->nsub = 0;
    while (d->sub_start[d->nsub] < n && d->nsub < MAX_SUBSETS) {
        size_t e = d->sub_start[d->nsub] + sz;
        if (e > n || d->nsub == MAX_SUBSETS - 1) e = n;
        d->sub_start[++d->nsub] = e;
        sz *= 2;
    }
    recount_subsets(d);
}

/* The thresholds of both phases and of the acceptance test, from the configuration. */
static void init_phases(run *r)
{
    const ransac_config *cfg = r->d.cfg;
    r->ntypes = 0;
    for (int ty = 0; ty < PRIM__COUNT; ty++) r->ntypes += (cfg->types >> ty) & 1u;
    if (r->ntypes == 0) r->ntypes = 1;
    r->min_pts = cfg->min_points < 3 ? 3 : cfg->min_points;
    r->small_pts = cfg->min_points_small < 3 ? 3 : cfg->min_points_small;
    if (cfg->min_points_small == 0) r->small_pts = r->min_pts;
    r->phase = 0;
    r->log_fail = log(fmax(1e-12, 1.0 - cfg->probability));
}

/* Every candidate of the pool scored afresh from its first subset (the live points
 * have changed). */
static void rescore_all(run *r)
{
    for (size_t j = 0; j < r->npool; j++) {
        r->pool[j].nsub = 0;
        r->pool[j].score = r->pool[j].seen = 0;
        r->which[j] = (int)j;
    }
    score_next(&r->d, r->pool, r->which, r->npool);
}

/* The median angle between the normals of the points of the primitives found so far
 * (only the planes when planes_only) and their primitive's (0 without such points; a
 * subsample of at most MODE_VOTERS).  Out of memory: 0, r->d.nomem set. */
static double found_normal_dev(run *r, int planes_only)
{
    const ransac_result *res = r->res;
    const det *d = &r->d;
    size_t n = 0;
    for (size_t i = 0; i < d->n; i++)
        n += res->label[i] >= 0 && (!planes_only || res->prims[res->label[i]].type == PRIM_PLANE);
    if (n == 0) return 0;
    size_t step = n / MODE_VOTERS + 1, k = 0, seen = 0;
    double *a = frep_malloc((n / step + 1) * sizeof *a);
    if (!a) {
        r->d.nomem = 1;
        return 0;
    }
    for (size_t i = 0; i < d->n; i++) {
        int32_t l = res->label[i];
        if (l < 0 || (planes_only && res->prims[l].type != PRIM_PLANE)) continue;
        if (seen++ % step == 0) a[k++] = normal_angle(&res->prims[l], d->c, i);
    }
    qsort(a, k, sizeof *a, cmp_double);
    double med = a[k / 2];
    frep_free(a);
    return med;
}

/* Second phase (see SMALL_TIGHT): once no shape of min_points is left, detection goes
 * on down to small_pts. Returns 1 when the phase began (detection goes on), 0 when
 * there is none (detection is over). */
static int next_phase(run *r)
{
    if (r->phase != 0 || r->small_pts >= r->min_pts) return 0;
    r->phase = 1;
    r->first_small = r->res->nprims;
    r->min_pts = r->small_pts;
    r->draws_since = 0;
    r->normal_dev = found_normal_dev(r, 1);
    /* Candidates whose patch was too small were kept scored zero (so as not to be
     * drawn again): a small shape may be among them, so every candidate is rescored. */
    rescore_all(r);
    return 1;
}

/* The candidate of type ty from sample s; -1 when degenerate, implausible or not an
 * inlier shape of its own sample points. */
static int make_candidate(const run *r, const sample *s, prim_type ty, prim *q)
{
    const ransac_config *cfg = r->d.cfg;
    memset(q, 0, sizeof *q);
    int bad;
    switch (ty) {
    case PRIM_PLANE: bad = make_plane(s, q); break;
    case PRIM_SPHERE: bad = make_sphere(s, q); break;
    case PRIM_CYLINDER: bad = make_cylinder(s, q); break;
    case PRIM_CONE: bad = make_cone(s, q); break;
    case PRIM_TORUS: bad = make_torus(s, q, r->d.rmax, cfg->epsilon); break;
    case PRIM__COUNT: default: bad = 1; break;
    }
    if (bad || !sane(q, r->d.rmax) ||
        !verify(q, s, verify_count(q->type), cfg->epsilon, cfg->cos_normal))
        return -1;
    return 0;
}

/* Pool candidate q from a sample at the given level, unless the pool holds the same
 * shape; a full pool drops its weakest candidate first (*first_new, the first new
 * candidate of the round, follows the slot that moves). */
static void pool_add(run *r, const prim *q, int level, size_t *first_new)
{
    for (size_t j = 0; j < r->npool; j++)
        if (same_shape(q, &r->pool[j].q, r->d.cfg->epsilon)) return;
    if (r->npool == MAX_POOL) {
        size_t w = 0;
        for (size_t j = 1; j < r->npool; j++)
            if (r->pool[j].est < r->pool[w].est) w = j;
        r->pool[w] = r->pool[--r->npool];
        if (*first_new > r->npool) *first_new = r->npool;
    }
    cand *k = &r->pool[r->npool++];
    memset(k, 0, sizeof *k);
    k->q = *q;
    k->level = level;
    k->ksample = verify_count(q->type);
}

/* A round of DRAWS_PER_ROUND minimal samples, each giving one candidate per type;
 * the new candidates are scored on their first subset. */
static void draw_round(run *r)
{
    size_t first_new = r->npool;
    for (int t = 0; t < DRAWS_PER_ROUND; t++) {
        sample s;
        int level = draw_sample(&r->d, &r->rng, &s);
        r->draws_since++;
        r->res->draws++;
        if (level < 0) continue;
        for (int ty = 0; ty < PRIM__COUNT; ty++) {
            prim q;
            if (!(r->d.cfg->types & (1u << ty)) || make_candidate(r, &s, (prim_type)ty, &q))
                continue;
            pool_add(r, &q, level, &first_new);
        }
    }
    size_t nw = 0;
    for (size_t j = first_new; j < r->npool; j++)
        if (r->pool[j].nsub == 0) r->which[nw++] = (int)j;
    score_next(&r->d, r->pool, r->which, nw);
}

/* Into r->which: the best candidate (unless scored on every subset) and the
 * REFINE_TOP rivals of highest upper bound that still overlap it, so that
 * near-duplicates of one shape are not all scored on every point. Returns the count. */
static size_t pick_leaders(run *r, size_t best)
{
    const cand *pool = r->pool;
    int *which = r->which;
    int nsub = r->d.nsub;
    size_t nw = 0;
    if (pool[best].nsub < nsub) which[nw++] = (int)best;
    size_t base = nw;
    for (size_t j = 0; j < r->npool; j++) {
        if (j == best || pool[j].nsub >= nsub || pool[j].hi < pool[best].lo) continue;
        size_t pos = nw;
        if (nw - base == REFINE_TOP) {
            if (pool[j].hi <= pool[which[nw - 1]].hi) continue;
            pos = nw - 1;
        } else {
            nw++;
        }
        while (pos > base && pool[which[pos - 1]].hi < pool[j].hi) {
            which[pos] = which[pos - 1];
            pos--;
        }
        which[pos] = (int)j;
    }
    return nw;
}

/* Refine the leaders until the best one's interval separates from the rest; returns
 * the best candidate, SIZE_MAX when the pool is empty. */
static size_t refine_leaders(run *r)
{
    size_t best = SIZE_MAX;
    for (int rounds = 0; rounds <= MAX_SUBSETS && r->npool > 0; rounds++) {
        best = 0;
        for (size_t j = 1; j < r->npool; j++)
            if (cmp_cand_est(&r->pool[j], &r->pool[best]) < 0) best = j;
        size_t nw = pick_leaders(r, best);
        if (nw == 0) break;
        score_next(&r->d, r->pool, r->which, nw);
    }
    return best;
}

/* Would a shape of the phase's minimum size have been found by now? */
static int min_shape_missed(const run *r)
{
    double pm = fmin(p_draw((double)r->min_pts, (double)r->d.nalive, 3), 0.999999);
    return (double)r->draws_since * log1p(-pm) < r->log_fail;
}

/* The acceptance test: b is large enough, and the chance of having missed a better
 * candidate, (1 - P(n))^s, is below 1 - probability. */
static int accepted(const run *r, const cand *b)
{
    double pd = fmin(p_draw(b->est, (double)r->d.nalive, b->ksample), 0.999999);
    return b->est >= (double)r->min_pts && (double)r->draws_since * log1p(-pd) < r->log_fail;
}

/* The sphere q from the normals of its m points idx: the centre nearest (least
 * squares) to the lines through the points along their normals, the radius the mean
 * distance to it.  A cap of a few tens of degrees leaves the centre and the radius of a
 * fit on positions free to trade along the cap's axis; the normals fix the centre.
 * Returns 0, 1 when degenerate. */
static int sphere_from_normals(prim *q, const frep_cloud *c, const uint32_t *idx, size_t m)
{
    double A[3][3] = {{0}}, b[3] = {0}, ctr[3];
    for (size_t e = 0; e < m; e++) {
        double p[3], n[3];
        point(c, idx[e], p);
        normal(c, idx[e], n);
        for (int a = 0; a < 3; a++)
            for (int k = 0; k < 3; k++) {
                double pr = (a == k) - n[a] * n[k];
                A[a][k] += pr;
                b[a] += pr * p[k];
            }
    }
    if (solve3(A, b, ctr)) return 1;
    double sr = 0;
    for (size_t e = 0; e < m; e++) {
        double p[3];
        point(c, idx[e], p);
        sr += sqrt((p[0] - ctr[0]) * (p[0] - ctr[0]) + (p[1] - ctr[1]) * (p[1] - ctr[1]) +
                   (p[2] - ctr[2]) * (p[2] - ctr[2]));
    }
    memcpy(q->p, ctr, sizeof ctr);
    q->r = sr / (double)m;
    return !(q->r > 0);
}

/* The largest median normal deviation of small shape q whose patch is `width` wide:
 * SMALL_NORMAL_DEG, or for a wide plane SMALL_FACE_NOISE times the deviation measured
 * on the first phase's planes (run.normal_dev), for a sphere SMALL_SPHERE_NOISE times
 * it, whichever is larger. */
static double small_normal_limit(const run *r, const prim *q, double width)
{
    double lim = SMALL_NORMAL_DEG * FREP_PI / 180.0;
    if (q->type == PRIM_PLANE && width >= SMALL_FACE_WIDTH * r->d.cfg->epsilon)
        lim = fmax(lim, SMALL_FACE_NOISE * r->normal_dev);
    if (q->type == PRIM_SPHERE) lim = fmax(lim, SMALL_SPHERE_NOISE * r->normal_dev);
    return lim;
}

/* The largest median distance of a small shape's inliers: SMALL_TIGHT epsilon, or
 * SMALL_TIGHT_SIGMAS times the measured noise, at most half epsilon, if larger. */
static double small_tight(const det *d)
{
    double eps = d->cfg->epsilon;
    return fmax(SMALL_TIGHT * eps, fmin(SMALL_TIGHT_SIGMAS * d->cfg->noise, 0.5 * eps));
}

/* Is small shape q (second phase) with its m inliers tight (see SMALL_TIGHT and the
 * limits after it)? Out of memory: no (r->d.nomem set). */
static int tight_small_shape(run *r, const prim *q, size_t m)
{
    double eps = r->d.cfg->epsilon, med, dev, tight = small_tight(&r->d);
    if (q->type != PRIM_PLANE && r->d.band > eps)
        tight = fmax(tight, SMALL_TIGHT_BAND * r->d.band);
    const frep_cloud *c = r->d.c;
    double width = patch_width(c, r->inl, m);
    return !(q->type == PRIM_CONE || q->type == PRIM_TORUS ||
             (q->type != PRIM_PLANE && !(q->r >= SMALL_RADIUS * eps)) ||
             median_abs(&r->d, q, r->inl, m, &med) || !(med <= tight) ||
             median_over(&r->d, q, r->inl, m, normal_angle, &dev) ||
             !(dev <= small_normal_limit(r, q, width)) || !(width >= SMALL_WIDTH * eps));
}

/* A narrow face between faces already found (a block's top strip between a groove and
 * the block's side, a thin cap's face) has normals blended with its neighbours' all
 * over, since every neighbourhood reaches across an edge: on InverseCSG's parts at 0.5%
 * noise 9-12 degrees, 3-4.1 times the first phase's planes' deviation (the thin cap
 * of two_spheres_one_cuboid at seed 2: 11.9 degrees, 4.08 times), against
 * small_normal_limit's 2.  The strips along edges that the normal test keeps out are
 * alike on normals, but they are made of the found faces' own points (kept out of both
 * faces' bands by those blended normals): over every second-phase plane candidate on
 * the 17 parts (n0.5 seeds 1-3, n1 seed 1), the share of the inliers within epsilon of
 * a shape found before is 0.95 at the median for the candidates that match no true
 * surface, 0.46 for those that match one the list lacks.  So a second-phase plane that
 * fails only on its normals is kept when at most FREE_FACE_SHARE of its inliers lie on
 * found shapes, it is within FREE_FACE_PARALLEL_DEG of parallel to a found plane (the
 * faces of a part are; a narrow face's own fit tilts toward its neighbours' rims, 5
 * degrees on mount's strip) that fits its own points well (part_direction), and, once
 * turned parallel to that plane, it is tight (tight_small_shape's median distance and
 * width) with normals within FREE_FACE_NOISE times the first phase's planes'
 * deviation. */
#define FREE_FACE_SHARE 0.5
#define FREE_FACE_PARALLEL_DEG 6.0
#define FREE_FACE_NOISE 5.0
#define FREE_FACE_RMS 1.25

/* |f| / |grad f| of q at point i (infinite where the gradient vanishes). */
static double distance_to(const prim *q, const frep_cloud *c, size_t i)
{
    double p[3], g[3];
    point(c, i, p);
    double f = prim_eval(q, p, g), gl = vec3_len(g);
    return gl > 0 ? fabs(f) / gl : INFINITY;
}

/* The share of the m points idx within epsilon of a shape found before (positions
 * only). */
static double found_share(const run *r, const uint32_t *idx, size_t m)
{
    const ransac_result *res = r->res;
    size_t near = 0;
    for (size_t e = 0; e < m; e++)
        for (size_t j = 0; j < res->nprims; j++)
            if (distance_to(&res->prims[j], r->d.c, idx[e]) < r->d.cfg->epsilon) {
                near++;
                break;
            }
    return m ? (double)near / (double)m : 1;
}

/* n . x of point i, for plane q of normal n. */
static double plane_offset(const prim *q, const frep_cloud *c, size_t i)
{
    double p[3];
    point(c, i, p);
    return vec3_dot(q->p, p);
}

/* The median of the found planes' rms distances to their inliers (*med); -1 when out
 * of memory. */
static int found_plane_rms(const run *r, double *med)
{
    const ransac_result *res = r->res;
    double *a = frep_malloc((res->nprims + 1) * sizeof *a);
    if (!a) return -1;
    size_t k = 0;
    for (size_t j = 0; j < res->nprims; j++)
        if (res->prims[j].type == PRIM_PLANE) a[k++] = res->prims[j].rms;
    qsort(a, k, sizeof *a, cmp_double);
    *med = k ? a[k / 2] : INFINITY;
    frep_free(a);
    return 0;
}

#define CROSS_MIN_SINE 0.5
static int fits_own_points(const prim *f, double rms)
{
    return f->type == PRIM_PLANE && f->rms <= FREE_FACE_RMS * rms;
}

/* n as dir when it is nearer q's normal than *best (a cosine; updated). */
static int nearer(const double n[3], const prim *q, double *best, double dir[3])
{
    double cs = fabs(vec3_dot(n, q->p));
    if (!(cs >= *best)) return 0;
    *best = cs;
    memcpy(dir, n, 3 * sizeof *n);
    return 1;
}

/* The part's direction nearest plane q's normal, within FREE_FACE_PARALLEL_DEG, into
 * dir: the normal of a found plane as near its own inliers as FREE_FACE_RMS times the
 * found planes' median rms (a plane across two faces that meet at a shallow angle is
 * farther from its points: on the tower of six_cuboids at 0.5% noise, 3.5 degrees off
 * the two faces of a step, 1.5 times the median; the narrow faces' parallels on mount
 * and the cap, 0.96-1.02), or where no such plane is parallel, the cross product of two
 * of them (a CAD part's faces meet at right angles: mount's block shows its two sides,
 * each a U of narrow legs around the groove, and no other plane of their direction).
 * The two planes must be CROSS_MIN_SINE apart (30 degrees).  Returns 1 when there is
 * one, 0 when not. */
static int part_direction(const run *r, const prim *q, double rms, double dir[3])
{
    const ransac_result *res = r->res;
    double best = cos(FREE_FACE_PARALLEL_DEG * FREP_PI / 180.0);
    int found = 0;
    for (size_t j = 0; j < res->nprims; j++)
        if (fits_own_points(&res->prims[j], rms)) found |= nearer(res->prims[j].p, q, &best, dir);
    if (found) return 1;
    for (size_t j = 0; j < res->nprims; j++)
        for (size_t k = j + 1; k < res->nprims; k++) {
            double n[3];
            if (!fits_own_points(&res->prims[j], rms) || !fits_own_points(&res->prims[k], rms))
                continue;
            vec3_cross(res->prims[j].p, res->prims[k].p, n);
            if (vec3_len(n) >= CROSS_MIN_SINE && vec3_normalize(n) == 0)
                found |= nearer(n, q, &best, dir);
        }
    return found;
}

/* Second-phase plane q with m inliers (r->inl) that tight_small_shape refused: kept as
 * a narrow face between found ones (above), turned parallel to its found plane at the
 * median offset of its inliers, its inliers gathered again.  Returns its support, 0
 * when it is not kept. */
static size_t narrow_face(run *r, prim *q, size_t m)
{
    det *d = &r->d;
    double rms;
    if (!(found_share(r, r->inl, m) <= FREE_FACE_SHARE)) return 0;
    if (found_plane_rms(r, &rms)) {
        d->nomem = 1;
        return 0;
    }
    double dir[3] = { 0, 0, 0 };
    if (!part_direction(r, q, rms, dir)) return 0;
    double sg = vec3_dot(dir, q->p) < 0 ? -1 : 1, off;
    for (int k = 0; k < 3; k++) q->p[k] = sg * dir[k];
    if (median_over(d, q, r->inl, m, plane_offset, &off)) return 0;
    q->r = off;
    m = support_of(d, q, r->flag, r->inl);
    double eps = d->cfg->epsilon, med, dev;
    if (m < r->min_pts || median_abs(d, q, r->inl, m, &med) || !(med <= small_tight(d)) ||
        median_over(d, q, r->inl, m, normal_angle, &dev) ||
        !(dev <= FREE_FACE_NOISE * r->normal_dev) ||
        !(patch_width(d->c, r->inl, m) >= SMALL_WIDTH * eps))
        return 0;
    return found_share(r, r->inl, m) <= FREE_FACE_SHARE ? m : 0;
}

/* Under noise a curved shape of the first phase can lie across two or three faces
 * that meet at an edge or a corner (a cone around a cuboid's corner holds strips of its
 * three faces, a torus two faces of a step): its points lie within the band and the
 * normal threshold, but their normals keep their faces' directions instead of turning
 * with the shape's.  A shape's normals agree with it when the median angle between its
 * inliers' normals and its own is at most CURVED_NORMAL_GROWTH times the median over
 * the primitives found so far (the estimate's own error on this cloud: 2.7-3.5 degrees
 * at 0.5% noise, 4.7-6.6 at 1%), or CURVED_NORMAL_FLOOR_DEG.  On InverseCSG's parts at
 * 0.5% and 1% noise the true cylinders and spheres measure 0.8-1.35 times that
 * reference (the most for radii of a few neighbourhoods), the shapes across faces
 * 1.6-5 times.  Clean data (not noisy) and the first shape (no reference) are not
 * tested. */
#define CURVED_NORMAL_GROWTH 1.5
#define CURVED_NORMAL_FLOOR_DEG 5.0
/* The largest median deviation a shape's normals may have now (radians); infinite
 * where there is no test. */
static double normal_limit(run *r)
{
    if (!noisy(&r->d) || r->res->nprims == 0) return INFINITY;
    return fmax(CURVED_NORMAL_FLOOR_DEG * FREP_PI / 180.0,
                CURVED_NORMAL_GROWTH * found_normal_dev(r, 0));
}

/* Do the normals of q's m inliers (r->inl) agree with it within lim (normal_limit)? */
static int normals_agree(run *r, const prim *q, size_t m, double lim)
{
    double dev;
    if (isinf(lim)) return 1;
    if (median_over(&r->d, q, r->inl, m, normal_angle, &dev)) return 0;
    return dev <= lim;
}

/* A curved shape whose normals disagree is searched for a face (face_modes, whatever
 * its dominant normal's share), which replaces it when it fits the points as tightly
 * and its own normals agree (a plane tangent to a blind hole's wall fits as tightly,
 * with normals 13 degrees off).  Without such a face the shape is dropped when
 * FACE_MODES normal directions hold CURVED_FACES_SHARE of its inliers (faces: 0.5-0.9
 * of them on the curved shapes of six_cuboids at 0.5% noise) and kept otherwise: a
 * mount's disc, a short cylinder's side that a sphere fits within the band, holds 0.38
 * in three directions, and dropping it leaves its points to the second phase, whose
 * candidates from them are rejected round after round until the phase runs out of
 * draws before the frame's corner spheres come up.  Over the 250 shapes that came here
 * on InverseCSG's 17 parts at 0.5% and 1% noise (seeds 1-3), 8 matched a true surface,
 * 3 of them under 0.45 and none in [0.45, 0.5), where 20 wrong ones were (mount's disc
 * as a cylinder tilted 32 degrees whose flanks lie on the block's two sides, 0.48, cut
 * the block's corners).  Returns the support of q, replaced or not (inliers in r->inl),
 * or 0 when it is dropped. */
#define CURVED_FACES_SHARE 0.45

/* The cylinder t of axis a whose section fits the m points idx across the axis best
 * (Kasa's algebraic circle: |x|^2 = 2 c.x + r^2 - |c|^2, linear in c and r^2).
 * Returns 0, 1 when degenerate. */
static int cylinder_on_axis(prim *t, const frep_cloud *c, const uint32_t *idx, size_t m,
                            const double a[3])
{
    double u[3], w[3], A[3][3] = {{0}}, b[3] = {0}, x[3];
    vec3_basis(a, u, w);
    for (size_t e = 0; e < m; e++) {
        double p[3];
        point(c, idx[e], p);
        double row[3] = { vec3_dot(p, u), vec3_dot(p, w), 1 };
        double z = row[0] * row[0] + row[1] * row[1];
        for (int i = 0; i < 3; i++) {
            for (int k = 0; k < 3; k++) A[i][k] += row[i] * row[k];
            b[i] += row[i] * z;
        }
    }
    if (solve3(A, b, x)) return 1;
    double cu = x[0] / 2, cw = x[1] / 2, r2 = x[2] + cu * cu + cw * cw;
    if (!(r2 > 0)) return 1;
    memset(t, 0, sizeof *t);
    t->type = PRIM_CYLINDER;
    for (int k = 0; k < 3; k++) {
        t->p[k] = cu * u[k] + cw * w[k];
        t->a[k] = a[k];
    }
    t->r = sqrt(r2);
    return 0;
}

/* A sphere or a torus whose normals disagree may stand for a short cylinder under
 * noise: mount_with_hole's disc, a wall 0.71 high between the plate and the disc's
 * narrow top, is a sphere of radius 1.69 within the band at 0.5% noise (its points'
 * normals, blended at both edges, 10-13 degrees off either shape), and the bore inside
 * it a torus of tube 1.04 (1,080 points, where the bore's cylinder holds 1,023).  The
 * normals cannot tell them apart there; the simpler shape on the part's own directions
 * can.  On a CAD part a cylinder's axis is a face's normal: a cylinder is fitted along
 * each found plane's normal (each direction once, AXIS_SAME_DEG apart), extracted as any
 * shape, and the one with the most support replaces q when it keeps CYLINDER_AXIS_KEEP
 * of q's m inliers.  Returns the support of q, replaced or not (inliers in r->inl). */
#define AXIS_SAME_DEG 5.0
#define CYLINDER_AXIS_KEEP 0.9
#define MAX_AXES 16
static size_t cylinder_on_axes(run *r, prim *q, size_t m)
{
    det *d = &r->d;
    const ransac_result *res = r->res;
    double axes[MAX_AXES][3], band = d->band, best_band = band;
    int na = 0;
    for (size_t j = 0; j < res->nprims && na < MAX_AXES; j++) {
        const prim *f = &res->prims[j];
        int k = 0;
        if (f->type != PRIM_PLANE) continue;
        while (k < na && fabs(vec3_dot(axes[k], f->p)) < cos(AXIS_SAME_DEG * FREP_PI / 180.0)) k++;
        if (k == na) memcpy(axes[na++], f->p, sizeof axes[0]);
    }
    uint32_t *own = frep_malloc((m + 1) * sizeof *own);
    if (!own) {
        d->nomem = 1;
        return m;
    }
    memcpy(own, r->inl, m * sizeof *own);
    prim best = *q;
    size_t best_m = 0;
    for (int k = 0; k < na; k++) {
        prim t;
        if (cylinder_on_axis(&t, d->c, own, m, axes[k]) || !sane(&t, d->rmax)) continue;
        size_t mt = refit_with_band(d, &t, r->min_pts, r->flag, r->inl);
        if (mt >= r->min_pts && sane(&t, d->rmax) && mt > best_m &&
            (double)mt >= CYLINDER_AXIS_KEEP * (double)m) {
            best = t;
            best_m = mt;
            best_band = d->band;
        }
    }
    frep_free(own);
    *q = best;
    d->band = best_m ? best_band : band;
    return support_of(d, q, r->flag, r->inl);
}

static size_t across_faces(run *r, prim *q, size_t m, double lim)
{
    det *d = &r->d;
    if (q->type == PRIM_SPHERE || q->type == PRIM_TORUS) {
        m = cylinder_on_axes(r, q, m);
        if (q->type == PRIM_CYLINDER) return m;
    }
    prim t = *q;
    double band = d->band;
    m = face_modes(d, q, m, r->min_pts, 1, r->flag, r->inl);
    if (q->type != t.type && !normals_agree(r, q, m, lim)) {
        *q = t;
        d->band = band;
        m = support_of(d, q, r->flag, r->inl);
    }
    if (q->type != t.type) return m;
    double share = faces_share(d->c, r->inl, m, cos(MODE_NORMAL_DEG * FREP_PI / 180.0));
    if (q->type == PRIM_TORUS) share = fmax(share, tube_share(d, q, r->inl, m));
    return share >= CURVED_FACES_SHARE ? 0 : m;
}

/* A plane across an arc.  A concave or convex arc of a few tens of degrees lies within
 * a plane's band and normal threshold under noise: mount's middle with its groove, an
 * exact cylinder of radius 1.07 (tests/models/segment_groove.hf), at 0.5% noise gave
 * one or two planes across the arc on seeds 2-4; on clouds of mount's coarse mesh,
 * whose groove is three facets 30 degrees apart, a plane of 805 points lay across two
 * of them, its inliers' normals 12.7 degrees off it at the median where the found
 * shapes' are 2.7-3.5.  A plane whose normals disagree (normal_limit) is tried as the
 * cylinder its inliers' normals describe (cylinder_from_normals); the cylinder
 * replaces it when it holds at least as many points and its own normals agree. */
static int cylinder_from_normals(prim *q, const frep_cloud *c, const uint32_t *idx, size_t m);
static size_t plane_on_arc(run *r, prim *q, size_t m, double lim)
{
    det *d = &r->d;
    if (!(d->cfg->types & (1u << PRIM_CYLINDER))) return m;
    prim t = *q;
    double band = d->band;
    if (cylinder_from_normals(&t, d->c, r->inl, m) == 0 && sane(&t, d->rmax)) {
        size_t mt = refit_with_band(d, &t, r->min_pts, r->flag, r->inl);
        if (mt >= m && sane(&t, d->rmax) && normals_agree(r, &t, mt, lim)) {
            *q = t;
            return mt;
        }
    }
    d->band = band;
    return support_of(d, q, r->flag, r->inl);
}

/* The cylinder q whose axis is the direction the m points' normals idx are most nearly
 * perpendicular to (the normals' scatter matrix's smallest eigenvector), its section's
 * centre c and radius r the least-squares solution of p = c + r n over the points and
 * their normals projected across the axis (the normals turned to agree with their
 * mean).  On an arc of a few tens of degrees under noise the positions alone (a circle
 * fit) leave the radius free: that plane's points, 55 degrees of an arc of radius about
 * 1.05 in a band 0.3 wide, give 0.32 from positions, 0.88 from this, and the
 * least-squares refit goes on from there (1.06).  Returns 0, 1 when degenerate. */
static int cylinder_from_normals(prim *q, const frep_cloud *c, const uint32_t *idx, size_t m)
{
    double S[9] = {0}, ev[3], vec[9], mean[3] = {0, 0, 0}, nmean[3] = {0, 0, 0};
    if (m < 3) return 1;
    for (size_t e = 0; e < m; e++) {
        double n[3], p[3];
        normal(c, idx[e], n);
        point(c, idx[e], p);
        for (int a = 0; a < 3; a++) {
            mean[a] += p[a] / (double)m;
            for (int k = 0; k < 3; k++) S[3 * a + k] += n[a] * n[k];
        }
    }
    normals_sym3_eig(S, ev, vec);
    const double *ax = vec, *u = vec + 3, *w = vec + 6;
    /* The normals' orientation: the largest eigenvector, the way most of them point. */
    for (size_t e = 0; e < m; e++) {
        double n[3];
        normal(c, idx[e], n);
        double sg = vec3_dot(n, w) >= 0 ? 1 : -1;
        for (int k = 0; k < 3; k++) nmean[k] += sg * n[k];
    }
    /* Unknowns (cx, cy, r); each point gives x = cx + r nx and y = cy + r ny. */
    double A[3][3] = {{0}}, b[3] = {0}, sol[3];
    for (size_t e = 0; e < m; e++) {
        double p[3], v[3], n[3];
        point(c, idx[e], p);
        normal(c, idx[e], n);
        vec3_sub(p, mean, v);
        double sg = vec3_dot(n, nmean) >= 0 ? 1 : -1;
        double x = vec3_dot(v, u), y = vec3_dot(v, w), nx = sg * vec3_dot(n, u), ny = sg * vec3_dot(n, w);
        double nl = sqrt(nx * nx + ny * ny);
        if (!(nl > 0)) continue;
        nx /= nl;
        ny /= nl;
        double rx[3] = {1, 0, nx}, ry[3] = {0, 1, ny};
        for (int a = 0; a < 3; a++) {
            for (int k = 0; k < 3; k++) A[a][k] += rx[a] * rx[k] + ry[a] * ry[k];
            b[a] += rx[a] * x + ry[a] * y;
        }
    }
    if (solve3(A, b, sol) || !(fabs(sol[2]) > 0)) return 1;
    q->type = PRIM_CYLINDER;
    for (int k = 0; k < 3; k++) q->p[k] = mean[k] + sol[0] * u[k] + sol[1] * w[k];
    memcpy(q->a, ax, sizeof q->a);
    q->r = fabs(sol[2]);
    return 0;
}

/* ---- Small spheres take back their points -----------------------------------------
 * A small sphere of the second phase was fitted to what the large shapes left: the
 * corner sphere of a frame whose rails, infinite cylinders in the extraction, took every
 * point of the sphere within epsilon and the normal threshold of their surface, leaving
 * a cap a third of its size, whose fit on positions trades centre for radius along the
 * cap's axis (radius 0.58-0.91 for a true 0.714 at 0.5% noise).  Each such sphere is
 * refitted from its points' normals, then takes the points near it that it explains
 * better than their curved primitive does, in distance and in normal (a plane's points
 * stay: a sphere grown by the noise reaches past a face it touches), or that nothing
 * explains, and is refitted from the normals of them all, a few times: the four
 * spheres of that frame come out with radii 0.688-0.716 and centres within 0.05. */
#define RECLAIM_PASSES 3
/* Reach around the shape's inliers (in its radii) where points are considered. */
#define RECLAIM_REACH 1.0
/* A refit is kept when its radius stays within this factor of the previous one. */
#define RECLAIM_RADIUS_FACTOR 1.5

static void reclaim_one(run *r, size_t j)
{
    det *d = &r->d;
    ransac_result *res = r->res;
    const frep_cloud *c = d->c;
    double eps = d->cfg->epsilon, cosn = d->cfg->cos_normal;
    for (int pass = 0; pass < RECLAIM_PASSES; pass++) {
        prim *q = &res->prims[j];
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        size_t own = 0;
        for (size_t i = 0; i < d->n; i++)
            if (res->label[i] == (int32_t)j) {
                double p[3];
                point(c, i, p);
                for (int a = 0; a < 3; a++) {
                    lo[a] = fmin(lo[a], p[a]);
                    hi[a] = fmax(hi[a], p[a]);
                }
                own++;
            }
        if (own < 3) return;
        if (pass == 0) {
            size_t k = 0;
            for (size_t i = 0; i < d->n; i++)
                if (res->label[i] == (int32_t)j) r->inl[k++] = (uint32_t)i;
            prim t = *q;
            if (sphere_from_normals(&t, c, r->inl, k) == 0 && sane(&t, d->rmax)) *q = t;
        }
        double reach = RECLAIM_REACH * q->r + eps;
        size_t m = 0;
        for (size_t i = 0; i < d->n; i++) {
            double p[3];
            point(c, i, p);
            int inside = 1;
            for (int a = 0; a < 3; a++) inside &= p[a] >= lo[a] - reach && p[a] <= hi[a] + reach;
            if (!inside || !compatible(q, c, i, eps, cosn)) continue;
            int32_t l = res->label[i];
            if (l >= 0 && l != (int32_t)j &&
                (res->prims[l].type == PRIM_PLANE || !(distance_to(q, c, i) < distance_to(&res->prims[l], c, i)) ||
                 !(normal_angle(q, c, i) < normal_angle(&res->prims[l], c, i))))
                continue;
            r->inl[m++] = (uint32_t)i;
        }
        prim t = *q;
        if (m < own || sphere_from_normals(&t, c, r->inl, m) != 0 || !sane(&t, d->rmax) ||
            !(t.r <= RECLAIM_RADIUS_FACTOR * q->r && t.r * RECLAIM_RADIUS_FACTOR >= q->r))
            return;
        /* The refitted shape's inliers among the considered points. */
        size_t k = 0;
        for (size_t e = 0; e < m; e++)
            if (compatible(&t, c, r->inl[e], eps, cosn)) r->inl[k++] = r->inl[e];
        for (size_t i = 0; i < d->n; i++)
            if (res->label[i] == (int32_t)j) res->label[i] = -1;
        for (size_t e = 0; e < k; e++) {
            int32_t l = res->label[r->inl[e]];
            if (l >= 0) res->prims[l].support--;
            res->label[r->inl[e]] = (int32_t)j;
        }
        t.support = k;
        t.rms = rms_of(&t, c, r->inl, k);
        *q = t;
    }
}

static void reclaim_small(run *r)
{
    ransac_result *res = r->res;
    for (size_t j = r->first_small; j < res->nprims; j++)
        if (res->prims[j].type == PRIM_SPHERE) reclaim_one(r, j);
}

/* Under noise a shape across several surfaces collects residuals that spread over
 * its band, and refit_with_band widens the band to their spread: on mount_with_hole at
 * 0.5% noise a cylinder tilted 11 degrees through the bore and the disc around it took
 * 1,544 points in a band of 0.376, where the 7 shapes found before it had bands of
 * 0.161-0.176 (rms 4.2 times the cloud's measured noise against their 1.5).  A shape
 * whose band is wider than BAND_OUTLIER times the median band of the shapes found so
 * far (at least BAND_OUTLIER_SHAPES of them) is rejected; its points stay for the
 * shapes they lie on.  Not a shape near one found before (near_same, as the merge
 * tests them): the outer shell of a torus at 1% noise, whose first extraction took the
 * points within epsilon, has a band 2.9 times the others' (tests/segment.sh) and is
 * folded into it by the merge.  Clean data (not noisy) is not tested. */
#define BAND_OUTLIER 1.6
#define BAND_OUTLIER_SHAPES 2
static int band_too_wide(run *r, const prim *q)
{
    const ransac_result *res = r->res;
    size_t n = res->nprims;
    if (!noisy(&r->d) || n < BAND_OUTLIER_SHAPES) return 0;
    for (size_t j = 0; j < n; j++)
        if (res->prims[j].type == q->type && near_same(q, &res->prims[j], MERGE_NEAR * r->bands[j]))
            return 0;
    double *a = frep_malloc(n * sizeof *a);
    if (!a) {
        r->d.nomem = 1;
        return 0;
    }
    memcpy(a, r->bands, n * sizeof *a);
    qsort(a, n, sizeof *a, cmp_double);
    double med = a[n / 2];
    frep_free(a);
    return r->d.band > BAND_OUTLIER * med;
}

/* Extract the accepted shape q: inliers, largest patch, refit, again with the refined
 * shape, the band widened to the measured noise (refit_with_band); a face of mixed
 * faces (face_modes); a simpler shape when it explains as much. Returns the support
 * (inliers in r->inl), 0 when a small shape is not tight. */
static size_t cylinder_on_axes(run *r, prim *q, size_t m);
static size_t extract(run *r, prim *q)
{
    det *d = &r->d;
    size_t m = refit_with_band(d, q, r->min_pts, r->flag, r->inl);
    m = face_modes(d, q, m, r->min_pts, 0, r->flag, r->inl);
    if (m >= r->min_pts) {
        prim_type before = q->type;
        m = prefer_simpler(d, q, m, r->flag, r->inl);
        /* A simpler shape measures its own noise: the band of a large cylinder
         * standing in for a plane is wider than the plane's. */
        if (q->type != before) {
            m = refit_with_band(d, q, r->min_pts, r->flag, r->inl);
            m = face_modes(d, q, m, r->min_pts, 0, r->flag, r->inl);
        }
    }
    m = support_of(d, q, r->flag, r->inl);
    if (r->phase == 1 && q->type == PRIM_SPHERE && m >= 3) {
        prim t = *q;
        if (sphere_from_normals(&t, d->c, r->inl, m) == 0 && sane(&t, d->rmax)) {
            size_t mt = support_of(d, &t, r->flag, r->inl);
            if (mt >= m) {
                *q = t;
                m = mt;
            } else {
                m = support_of(d, q, r->flag, r->inl);
            }
        }
    }
    if (r->phase == 0 && m >= r->min_pts && band_too_wide(r, q)) return 0;
    if (r->phase == 0 && m >= r->min_pts) {
        double lim = normal_limit(r);
        if (!normals_agree(r, q, m, lim))
            m = q->type == PRIM_PLANE ? plane_on_arc(r, q, m, lim) : across_faces(r, q, m, lim);
    }
    if (r->phase == 1 && m >= r->min_pts && !tight_small_shape(r, q, m))
        m = q->type == PRIM_PLANE ? narrow_face(r, q, m) : 0;
    return m;
}

/* The estimate of b was optimistic: keep it, scored zero, so that duplicates of it
 * are not drawn again. */
static void keep_rejected(const det *d, cand *b)
{
    b->nsub = d->nsub;
    b->score = 0;
    b->seen = 1;
    update_estimate(d, b);
}

/* Append q with its m inliers (r->inl) to the result: the points leave the live set
 * and the level that sampled q gains their count. Returns -1 when out of memory. */
static int record_prim(run *r, prim *q, size_t m, int level)
{
    det *d = &r->d;
    ransac_result *res = r->res;
    if (res->nprims == r->cap_prims) {
        prim *np = frep_realloc(res->prims, 2 * r->cap_prims * sizeof *np);
        if (!np) return -1;
        res->prims = np;
        double *nb = frep_realloc(r->bands, 2 * r->cap_prims * sizeof *nb);
        if (!nb) return -1;
        r->bands = nb;
        r->cap_prims *= 2;
    }
    r->bands[res->nprims] = d->band;
    q->support = m;
    q->rms = rms_of(q, d->c, r->inl, m);
    q->separating = 0;
    for (size_t j = 0; j < m; j++) {
        d->alive[r->inl[j]] = 0;
        res->label[r->inl[j]] = (int32_t)res->nprims;
    }
    res->prims[res->nprims++] = *q;
    d->level_score[level] += (double)m;
    recount_subsets(d);
    return 0;
}

/* After an extraction: old candidates were scored on points now removed, so all are
 * rescored from scratch, and those that lost their support are dropped. */
static void prune_pool(run *r)
{
    rescore_all(r);
    size_t keep = 0;
    for (size_t j = 0; j < r->npool; j++)
        if (r->pool[j].hi >= (double)r->min_pts) r->pool[keep++] = r->pool[j];
    r->npool = keep;
    r->draws_since = r->npool / r->ntypes;
}

static void report(const run *r)
{
    const ransac_config *cfg = r->d.cfg;
    if (cfg->progress) cfg->progress(cfg->user, "detect", r->d.nalive, r->d.n, r->res->nprims);
}

/* One step of detection: a round of samples, the leaders refined, and the best
 * candidate extracted when it passes the acceptance test. Returns 1 to go on, 0 when
 * detection is over, -1 when out of memory. */
static int detect_step(run *r)
{
    det *d = &r->d;
    if (d->nalive < r->min_pts || d->nalive < RANSAC_MIN_CLOUD) return next_phase(r);
    draw_round(r);
    size_t best = refine_leaders(r);
    report(r);
    if (best == SIZE_MAX)
        return min_shape_missed(r) || r->draws_since > RANSAC_MAX_DRAWS ? next_phase(r) : 1;
    cand *b = &r->pool[best];
    if (!accepted(r, b)) {
        int over = (b->est < (double)r->min_pts && min_shape_missed(r)) ||
                   r->draws_since > RANSAC_MAX_DRAWS;
        return over ? next_phase(r) : 1;
    }
    prim q = b->q;
    size_t m = extract(r, &q);
    if (d->nomem) return -1;
    if (m < r->min_pts) {
        keep_rejected(d, b);
        return r->draws_since > RANSAC_MAX_DRAWS ? next_phase(r) : 1;
    }
    int level = b->level;
    r->pool[best] = r->pool[--r->npool];
    if (record_prim(r, &q, m, level)) return -1;
    prune_pool(r);
    report(r);
    return 1;
}

int ransac_detect(const frep_cloud *c, const ransac_config *cfg, ransac_result *res,
                  frep_error *err)
{
    memset(res, 0, sizeof *res);
    frep_error_init(err);
    run r;
    if (run_alloc(&r, c, cfg, res, err)) goto fail;
    /* A stop during normal estimation skips the octree and the subsets (a second of a
     * loaded processor on 50,000 points): no shape, every point unassigned. */
    if (frep_cancelled(cfg->interrupt)) {
        res->interrupted = 1;
        run_free(&r);
        return 0;
    }
    rng_seed(&r.rng, cfg->seed);
    if (build_octree(&r.d)) goto oom;
    build_subsets(&r.d, &r.rng);
    init_phases(&r);
    for (;;) {
        if (frep_cancelled(cfg->interrupt)) {
            res->interrupted = 1;
            break;
        }
        int go = detect_step(&r);
        if (go < 0) goto oom;
        if (go == 0) break;
    }
    if (!res->interrupted && r.phase == 1) reclaim_small(&r);
    if (!res->interrupted) merge_redundant(&r.d, res, r.bands, r.inl);
    if (frep_cancelled(cfg->interrupt)) res->interrupted = 1;  /* the merge cut short */
    if (r.d.nomem) goto oom;
    run_free(&r);
    return 0;
oom:
    frep_error_nomem(err);
fail:
    run_free(&r);
    ransac_result_free(res);
    return -1;
}

void ransac_result_free(ransac_result *r)
{
    frep_free(r->prims);
    frep_free(r->label);
    r->prims = NULL;
    r->label = NULL;
    r->nprims = 0;
}

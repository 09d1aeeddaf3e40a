/* test_segment.c - tests of evolve/: kd-tree against brute force, PCA normals,
 * efficient RANSAC on clouds sampled here from analytic primitives (clean, noisy, with
 * outliers), separating primitives, the .fit and .hf lists, bad input, and the
 * growth steps of evolve/simplify.c that complete a tree short of faces, and the
 * planes that close slabs.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cloud.h"
#include "fitfile.h"
#include "frep.h"
#include "kdtree.h"
#include "normals.h"
#include "prim.h"
#include "rng.h"
#include "segment.h"
#include "simplify.h"
#include "tap.h"
#include "vec3.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ---- a seeded sampler: the shared generator (runtime/rng.h), seeded apart ---- */

typedef frep_rng trng;

static trng trng_new(uint64_t seed)
{
    trng r;
    frep_rng_seed(&r, seed);
    return r;
}

static double uni(trng *r) { return frep_rng_unit(r); }
static double gauss(trng *r) { return frep_rng_normal(r); }

static void add(frep_cloud *c, const double p[3], const double n[3])
{
    cloud_push(c, p, n);
}

/* Points on the six faces of the box [lo, hi]^3 (equal counts per face). */
static void sample_box(frep_cloud *c, trng *r, double lo, double hi, size_t per_face)
{
    for (int f = 0; f < 6; f++)
        for (size_t i = 0; i < per_face; i++) {
            int ax = f / 2;
            double p[3], n[3] = {0, 0, 0};
            for (int k = 0; k < 3; k++) p[k] = lo + (hi - lo) * uni(r);
            p[ax] = f % 2 ? hi : lo;
            n[ax] = f % 2 ? 1 : -1;
            add(c, p, n);
        }
}

static void sample_sphere(frep_cloud *c, trng *r, const double ctr[3], double rad, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        double d[3] = {gauss(r), gauss(r), gauss(r)};
        double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        double p[3];
        for (int k = 0; k < 3; k++) {
            d[k] /= l;
            p[k] = ctr[k] + rad * d[k];
        }
        add(c, p, d);
    }
}

/* Closed cylinder: side and both caps at density ~ n / area. */
static void sample_cylinder(frep_cloud *c, trng *r, const double base[3], const double a[3],
                            double rad, double h, size_t nside, size_t ncap)
{
    double u[3], v[3];
    vec3_basis(a, u, v);
    for (size_t i = 0; i < nside; i++) {
        double t = 2 * M_PI * uni(r), z = h * uni(r), p[3], n[3];
        for (int k = 0; k < 3; k++) {
            n[k] = cos(t) * u[k] + sin(t) * v[k];
            p[k] = base[k] + z * a[k] + rad * n[k];
        }
        add(c, p, n);
    }
    for (int cap = 0; cap < 2; cap++)
        for (size_t i = 0; i < ncap; i++) {
            double t = 2 * M_PI * uni(r), s = rad * sqrt(uni(r)), p[3], n[3];
            for (int k = 0; k < 3; k++) {
                n[k] = cap ? a[k] : -a[k];
                p[k] = base[k] + (cap ? h : 0) * a[k] + s * (cos(t) * u[k] + sin(t) * v[k]);
            }
            add(c, p, n);
        }
}

/* Cone frustum between heights h0 and h1 from the apex, with a cap at h1. */
static void sample_cone(frep_cloud *c, trng *r, const double apex[3], const double a[3],
                        double ang, double h0, double h1, size_t nside, size_t ncap)
{
    double u[3], v[3];
    vec3_basis(a, u, v);
    for (size_t i = 0; i < nside; i++) {
        double h = sqrt(h0 * h0 + uni(r) * (h1 * h1 - h0 * h0)), t = 2 * M_PI * uni(r);
        double rho = h * tan(ang), p[3], n[3];
        for (int k = 0; k < 3; k++) {
            double e = cos(t) * u[k] + sin(t) * v[k];
            p[k] = apex[k] + h * a[k] + rho * e;
            n[k] = cos(ang) * e - sin(ang) * a[k];
        }
        add(c, p, n);
    }
    for (size_t i = 0; i < ncap; i++) {
        double t = 2 * M_PI * uni(r), s = h1 * tan(ang) * sqrt(uni(r)), p[3];
        for (int k = 0; k < 3; k++) p[k] = apex[k] + h1 * a[k] + s * (cos(t) * u[k] + sin(t) * v[k]);
        add(c, p, a);
    }
}

static void sample_torus(frep_cloud *c, trng *r, const double ctr[3], const double a[3],
                         double R, double rr, size_t n)
{
    double u[3], v[3];
    vec3_basis(a, u, v);
    for (size_t i = 0; i < n;) {
        double t = 2 * M_PI * uni(r), s = 2 * M_PI * uni(r);
        /* Area element (R + r cos s): rejection sampling. */
        if (uni(r) * (R + rr) > R + rr * cos(s)) continue;
        double p[3], nn[3];
        for (int k = 0; k < 3; k++) {
            double e = cos(t) * u[k] + sin(t) * v[k];
            nn[k] = cos(s) * e + sin(s) * a[k];
            p[k] = ctr[k] + R * e + rr * nn[k];
        }
        add(c, p, nn);
        i++;
    }
}

static void perturb(frep_cloud *c, trng *r, double sigma, size_t outliers)
{
    double lo[3], hi[3];
    cloud_bbox(c, lo, hi);
    for (size_t i = 0; i < c->n; i++) {
        c->x[i] += sigma * gauss(r);
        c->y[i] += sigma * gauss(r);
        c->z[i] += sigma * gauss(r);
    }
    for (size_t i = 0; i < outliers; i++) {
        double p[3], n[3] = {gauss(r), gauss(r), gauss(r)};
        for (int k = 0; k < 3; k++) p[k] = lo[k] + (hi[k] - lo[k]) * uni(r);
        add(c, p, n);
    }
}

/* ---- matching detected primitives against the truth ---- */

static double axis_angle_deg(const double a[3], const double b[3])
{
    double d = fabs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
    return acos(fmin(1.0, d)) * 180.0 / M_PI;
}

/* Distance of point p from the line (q, a). */
static double line_dist(const double p[3], const double q[3], const double a[3])
{
    double v[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
    double h = v[0] * a[0] + v[1] * a[1] + v[2] * a[2];
    double w[3] = {v[0] - h * a[0], v[1] - h * a[1], v[2] - h * a[2]};
    return sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
}

/* Does detected d match truth t within position tolerance tol (absolute) and angular
 * tolerance deg? Plane normals may be flipped. */
static int matches(const prim *d, const prim *t, double tol, double deg)
{
    if (d->type != t->type) return 0;
    switch (t->type) {
    case PRIM_PLANE: {
        double c = d->p[0] * t->p[0] + d->p[1] * t->p[1] + d->p[2] * t->p[2];
        double off = c > 0 ? fabs(d->r - t->r) : fabs(d->r + t->r);
        return axis_angle_deg(d->p, t->p) < deg && off < tol;
    }
    case PRIM_SPHERE: {
        double dc = sqrt(pow(d->p[0] - t->p[0], 2) + pow(d->p[1] - t->p[1], 2) +
                         pow(d->p[2] - t->p[2], 2));
        return dc < tol && fabs(d->r - t->r) < tol;
    }
    case PRIM_CYLINDER:
        return axis_angle_deg(d->a, t->a) < deg && line_dist(d->p, t->p, t->a) < tol &&
               fabs(d->r - t->r) < tol;
    case PRIM_CONE: {
        double dc = sqrt(pow(d->p[0] - t->p[0], 2) + pow(d->p[1] - t->p[1], 2) +
                         pow(d->p[2] - t->p[2], 2));
        double dd = d->a[0] * t->a[0] + d->a[1] * t->a[1] + d->a[2] * t->a[2];
        return dd > 0 && axis_angle_deg(d->a, t->a) < deg && dc < 3 * tol &&
               fabs(d->r - t->r) * 180 / M_PI < deg;
    }
    case PRIM_TORUS: {
        double dc = sqrt(pow(d->p[0] - t->p[0], 2) + pow(d->p[1] - t->p[1], 2) +
                         pow(d->p[2] - t->p[2], 2));
        return axis_angle_deg(d->a, t->a) < deg && dc < tol && fabs(d->R - t->R) < tol &&
               fabs(d->r - t->r) < tol;
    }
    case PRIM__COUNT:
        break;
    }
    return 0;
}

/* Run segmentation and check every truth primitive is found once; with `exact`, no
 * other fitted primitive may appear. */
static void check_found(const char *what, frep_cloud *c, const prim *truth, size_t nt,
                        double tol, double deg, int exact, unsigned types)
{
    segment_config cfg;
    segment_config_init(&cfg);
    cfg.seed = 7;
    cfg.types = types;
    segment_result res;
    frep_error err;
    int rc = segment_run(c, &cfg, &res, &err);
    ok(rc == 0, "%s: segmentation runs%s%s", what, err.msg[0] ? ": " : "", err.msg[0] ? err.msg : "");
    if (rc) return;
    for (size_t i = 0; i < nt; i++) {
        int found = 0;
        for (size_t j = 0; j < res.nfitted; j++) found += matches(&res.prims[j], &truth[i], tol, deg);
        ok(found >= 1, "%s: %s %zu found", what, prim_type_name(truth[i].type), i + 1);
    }
    if (exact)
        is_int(res.nfitted, nt, "%s: no spurious primitives", what);
    else
        ok(res.nfitted <= nt + nt / 2 + 1, "%s: few spurious primitives (%zu for %zu)", what,
           res.nfitted, nt);
    for (size_t j = 0; j < res.nfitted; j++)
        diag("  %s support %zu rms %.3g", prim_type_name(res.prims[j].type), res.prims[j].support,
             res.prims[j].rms);
    segment_result_free(&res);
}

static prim mk(prim_type t, double p0, double p1, double p2, double a0, double a1, double a2,
               double r, double R)
{
    prim q;
    memset(&q, 0, sizeof q);
    q.type = t;
    q.p[0] = p0, q.p[1] = p1, q.p[2] = p2;
    double l = sqrt(a0 * a0 + a1 * a1 + a2 * a2);
    if (l > 0) q.a[0] = a0 / l, q.a[1] = a1 / l, q.a[2] = a2 / l;
    q.r = r;
    q.R = R;
    return q;
}

/* ---- the tests ---- */

static void test_kdtree(void)
{
    trng r = trng_new(42);
    size_t n = 3000;
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y), *z = malloc(n * sizeof *z);
    for (size_t i = 0; i < n; i++) {
        x[i] = uni(&r);
        y[i] = uni(&r);
        z[i] = i % 7 == 0 ? 0.5 : uni(&r); /* many equal keys */
    }
    x[10] = x[11], y[10] = y[11], z[10] = z[11]; /* an exact duplicate */
    kd_tree *t = kd_build(n, x, y, z);
    int good = t != NULL;
    for (int q = 0; q < 200 && good; q++) {
        double p[3] = {uni(&r), uni(&r), uni(&r)};
        uint32_t idx[10];
        double d2[10];
        size_t m = kd_knn(t, p, 10, idx, d2);
        /* Brute force: the 10th smallest distance must equal d2[9]. */
        double best[10];
        for (int k = 0; k < 10; k++) best[k] = INFINITY;
        for (size_t i = 0; i < n; i++) {
            double d = (x[i] - p[0]) * (x[i] - p[0]) + (y[i] - p[1]) * (y[i] - p[1]) +
                       (z[i] - p[2]) * (z[i] - p[2]);
            for (int k = 0; k < 10; k++)
                if (d < best[k]) {
                    memmove(best + k + 1, best + k, (size_t)(9 - k) * sizeof *best);
                    best[k] = d;
                    break;
                }
        }
        good = m == 10;
        for (int k = 0; k < 10 && good; k++) good = d2[k] == best[k];
    }
    ok(good, "kd-tree k-NN agrees with brute force (200 queries, duplicates)");
    kd_free(t);
    /* One point repeated: no crash, k results. */
    for (size_t i = 0; i < n; i++) x[i] = y[i] = z[i] = 1.0;
    t = kd_build(n, x, y, z);
    uint32_t idx[5];
    double d2[5], q[3] = {0, 0, 0};
    ok(t && kd_knn(t, q, 5, idx, d2) == 5 && d2[4] == 3.0, "kd-tree of one repeated point");
    kd_free(t);
    free(x);
    free(y);
    free(z);
}

static void test_normals(void)
{
    trng r = trng_new(3);
    frep_cloud *c = cloud_new(1);
    double ctr[3] = {0.1, 0.2, 0.3};
    sample_sphere(c, &r, ctr, 1.0, 3000);
    sample_box(c, &r, 3.0, 4.0, 500); /* a second component, away from the sphere */
    frep_cloud *d = cloud_new(0);
    for (size_t i = 0; i < c->n; i++) {
        double p[3] = {c->x[i], c->y[i], c->z[i]};
        cloud_push(d, p, NULL);
    }
    ok(normals_estimate(d, 0, 0) == 0, "normals estimated");
    /* Sphere points (the first 3000): accurate axes. Box edges blur, so on the box
     * only the orientation of the well-estimated normals is checked. */
    size_t agree = 0, good_axis = 0, nsph = 3000, good_all = 0;
    for (size_t i = 0; i < c->n; i++) {
        double dd = c->nx[i] * d->nx[i] + c->ny[i] * d->ny[i] + c->nz[i] * d->nz[i];
        int good = fabs(dd) > cos(10 * M_PI / 180);
        if (i < nsph) good_axis += good;
        good_all += good;
        agree += good && dd > 0;
    }
    ok((double)good_axis > 0.99 * (double)nsph, "PCA normals on the sphere within 10 degrees (%zu of %zu)",
       good_axis, nsph);
    ok(agree == good_all, "orientation outward on both components (%zu of %zu)", agree, good_all);
    cloud_free(c);
    cloud_free(d);
}

static void test_shapes(void)
{
    trng r = trng_new(1);
    /* Box: six planes. */
    frep_cloud *c = cloud_new(1);
    sample_box(c, &r, -1, 1, 1500);
    prim box[6];
    for (int f = 0; f < 6; f++) {
        double n[3] = {0, 0, 0};
        n[f / 2] = f % 2 ? 1 : -1;
        box[f] = mk(PRIM_PLANE, n[0], n[1], n[2], 0, 0, 0, 1, 0);
    }
    check_found("box", c, box, 6, 0.01, 1.0, 1, 0);
    cloud_free(c);

    /* Sphere. */
    c = cloud_new(1);
    double sc[3] = {0.2, -0.1, 0.3};
    sample_sphere(c, &r, sc, 0.8, 6000);
    prim sph = mk(PRIM_SPHERE, 0.2, -0.1, 0.3, 0, 0, 0, 0.8, 0);
    check_found("sphere", c, &sph, 1, 0.01, 1.0, 1, 0);
    cloud_free(c);

    /* Closed cylinder, tilted: side plus two cap planes. */
    c = cloud_new(1);
    double base[3] = {0.1, 0.2, -0.5}, ax[3] = {0.3, 0.2, 0.93};
    double l = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]);
    for (int k = 0; k < 3; k++) ax[k] /= l;
    sample_cylinder(c, &r, base, ax, 0.5, 2.0, 6000, 1000);
    prim cyl[3];
    cyl[0] = mk(PRIM_CYLINDER, base[0], base[1], base[2], ax[0], ax[1], ax[2], 0.5, 0);
    cyl[1] = mk(PRIM_PLANE, ax[0], ax[1], ax[2], 0, 0, 0,
                ax[0] * base[0] + ax[1] * base[1] + ax[2] * base[2] + 2.0, 0);
    cyl[2] = mk(PRIM_PLANE, ax[0], ax[1], ax[2], 0, 0, 0,
                ax[0] * base[0] + ax[1] * base[1] + ax[2] * base[2], 0);
    check_found("cylinder", c, cyl, 3, 0.02, 1.0, 1, 0);
    cloud_free(c);

    /* Cone frustum with its cap. */
    c = cloud_new(1);
    double apex[3] = {0, 0, 1}, ca[3] = {0, 0, -1};
    sample_cone(c, &r, apex, ca, 30 * M_PI / 180, 0.3, 1.5, 6000, 1500);
    prim cone[2];
    cone[0] = mk(PRIM_CONE, 0, 0, 1, 0, 0, -1, 30 * M_PI / 180, 0);
    cone[1] = mk(PRIM_PLANE, 0, 0, -1, 0, 0, 0, 0.5, 0);
    check_found("cone", c, cone, 2, 0.02, 1.5, 1, 0);
    cloud_free(c);

    /* Torus, tilted. */
    c = cloud_new(1);
    double tc[3] = {0.5, 0, 0}, ta[3] = {0, 0.6, 0.8};
    sample_torus(c, &r, tc, ta, 1.0, 0.3, 8000);
    prim tor = mk(PRIM_TORUS, 0.5, 0, 0, 0, 0.6, 0.8, 0.3, 1.0);
    check_found("torus", c, &tor, 1, 0.02, 1.0, 1, 0);
    cloud_free(c);

    /* Noisy (sigma 0.2% of the diagonal) with 1% outliers, normals estimated. */
    c = cloud_new(1);
    sample_cylinder(c, &r, base, ax, 0.5, 2.0, 6000, 1000);
    sample_sphere(c, &r, (double[3]){2.5, 0, 0}, 0.6, 4000);
    perturb(c, &r, 0.002 * cloud_diagonal(c), c->n / 100);
    frep_cloud *d = cloud_new(0);
    for (size_t i = 0; i < c->n; i++) {
        double p[3] = {c->x[i], c->y[i], c->z[i]};
        cloud_push(d, p, NULL);
    }
    prim both[4] = {cyl[0], cyl[1], cyl[2], mk(PRIM_SPHERE, 2.5, 0, 0, 0, 0, 0, 0.6, 0)};
    check_found("noisy cylinder + sphere, estimated normals", d, both, 4, 0.03, 3.0, 0, 0);
    cloud_free(c);
    cloud_free(d);
}

static void test_determinism(void)
{
    trng r = trng_new(5);
    frep_cloud *c = cloud_new(1);
    double base[3] = {0, 0, 0}, ax[3] = {0, 0, 1};
    sample_cylinder(c, &r, base, ax, 0.5, 1.0, 4000, 800);
    frep_cloud *c2 = cloud_new(1);
    for (size_t i = 0; i < c->n; i++) {
        double p[3] = {c->x[i], c->y[i], c->z[i]}, n[3] = {c->nx[i], c->ny[i], c->nz[i]};
        cloud_push(c2, p, n);
    }
    segment_config cfg;
    segment_config_init(&cfg);
    cfg.seed = 99;
    segment_result a, b;
    cfg.nthreads = 1;
    int ra = segment_run(c, &cfg, &a, NULL);
    cfg.nthreads = 2;
    int rb = segment_run(c2, &cfg, &b, NULL);
    ok(ra == 0 && rb == 0 && a.nprims == b.nprims &&
           memcmp(a.prims, b.prims, a.nprims * sizeof *a.prims) == 0 &&
           memcmp(a.label, b.label, c->n * sizeof *a.label) == 0,
       "same seed: same primitives and labels at 1 and 2 threads");
    /* Separating primitives: the cylinder gets box planes, no duplicates of its caps. */
    size_t sep = 0, sep_planes = 0;
    for (size_t j = 0; j < a.nprims; j++) {
        sep += a.prims[j].separating;
        sep_planes += a.prims[j].separating && a.prims[j].type == PRIM_PLANE;
        ok(a.prims[j].separating || a.prims[j].has_obb, "primitive %zu has a box", j + 1);
    }
    is_int(sep_planes, 4, "cylinder: 4 separating box planes (2 are the caps already)");
    segment_result_free(&a);
    segment_result_free(&b);
    cloud_free(c);
    cloud_free(c2);

    /* Torus: separating cylinder of the major radius. */
    prim t = mk(PRIM_TORUS, 0, 0, 0, 0, 0, 1, 0.2, 1.0);
    t.has_obb = 1;
    for (int a2 = 0; a2 < 3; a2++) t.obb_axes[a2][a2] = 1;
    t.obb_half[0] = t.obb_half[1] = 1.2;
    t.obb_half[2] = 0.2;
    prim *list = malloc(sizeof *list);
    list[0] = t;
    size_t n = 1;
    ok(segment_add_separating(&list, &n, 1e-3) == 0, "torus: separating primitives added");
    is_int(n, 8, "torus: 6 planes and 1 cylinder added");
    ok(n == 8 && list[7].type == PRIM_CYLINDER && list[7].r == 1.0 && list[7].separating,
       "torus: separating cylinder with the major radius");
    free(list);

    /* Two tori apart along x: 10 additions (their y and z planes coincide), more than
     * the list's first size holds. */
    prim t2 = t;
    t2.p[0] = t2.obb_c[0] = 5;
    list = malloc(2 * sizeof *list);
    list[0] = t;
    list[1] = t2;
    n = 2;
    ok(segment_add_separating(&list, &n, 1e-3) == 0, "two tori: separating primitives added");
    is_int(n, 12, "two tori: 8 planes and 2 cylinders added");
    free(list);
}

/* Readable output: numbers rounded relative to the scale, never by more than half a
 * quantum, round-off noise printed as 0, and exact output without a scale. */
static void test_rounding(void)
{
    char buf[PRIM_NUM_BUF];
    prim_format_number(buf, 2.9e-13, 1e-7);
    is_str(buf, "0", "round-off noise below the quantum is 0");
    prim_format_number(buf, -2.9e-13, 1e-7);
    is_str(buf, "0", "negative noise is 0, not -0");
    prim_format_number(buf, 0.49999999987, 1e-7);
    is_str(buf, "0.5", "shortest form within half a quantum");
    prim_format_number(buf, 1.2345678912345, 1e-7);
    ok(fabs(strtod(buf, NULL) - 1.2345678912345) <= 0.5e-7 && strlen(buf) <= 10,
       "1.2345678912345 at 1e-7: %s", buf);
    prim_format_number(buf, 0.1 + 0.2, 0);
    ok(strtod(buf, NULL) == 0.1 + 0.2, "quantum 0: exact round trip (%s)", buf);
    prim_format_number(buf, 0.5, 0);
    is_str(buf, "0.5", "quantum 0: still shortest");

    /* A tilted cylinder with round-off in every parameter, written at scale 3. */
    prim q;
    memset(&q, 0, sizeof q);
    q.type = PRIM_CYLINDER;
    double a[3] = {0.6, 1e-14, 0.8 + 3e-13}, l = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    for (int k = 0; k < 3; k++) q.a[k] = a[k] / l;
    q.p[0] = 0.25 + 4e-12;
    q.p[1] = -1.5 - 2e-11;
    q.p[2] = 3.1e-13;
    q.r = 0.7499999999;
    FILE *f = tmpfile();
    prim_write_call_scaled(f, &q, 3.0);
    long len = ftell(f);
    rewind(f);
    char line[256] = "";
    size_t got = fread(line, 1, sizeof line - 1, f);
    line[got] = '\0';
    fclose(f);
    (void)len;
    is_str(line, "frCylinder(x, 0.25, -1.5, 0, 0.6, 0, 0.8, 0.75)", "readable cylinder call");
    prim *back = NULL;
    size_t nb = 0;
    char src[400];
    snprintf(src, sizeof src, "m(x[3], a[1])\n{\n  p1 = %s;\n}\n", line);
    int rc = segment_parse_prims("r.hf", src, strlen(src), 0, &back, &nb, NULL);
    ok(rc == 0 && nb == 1, "rounded call reads back");
    if (rc == 0 && nb == 1) {
        /* The surface moves by far less than the quantum times the scale. */
        double worst = 0;
        for (int i = 0; i < 50; i++) {
            double t = 0.1 * i, x[3] = {q.p[0] + t * q.a[0] + 0.75 * 0.8,
                                        q.p[1] + 0.3 * t, q.p[2] + t * q.a[2] - 0.75 * 0.6};
            double d = fabs(prim_eval(&q, x, NULL) - prim_eval(back, x, NULL));
            if (d > worst) worst = d;
        }
        ok(worst < 10 * PRIM_POS_QUANTUM * 3.0, "rounding moves the surface by %.2g", worst);
    }
    free(back);
}

static void test_files(void)
{
    const char *fit = "# comment\nplane 0 0 2 1\nsphere 1 2 3 0.5\n"
                      "cylinder 0 0 1 1 2 3 0.25\ncone 0 1 0 0 0 0 0.5\n"
                      "torus 1 0 0 0 0 0 0.1 2\n";
    prim *p = NULL;
    size_t n = 0;
    frep_error err;
    int rc = fitfile_parse("t.fit", fit, strlen(fit), &p, &n, &err);
    ok(rc == 0 && n == 5, ".fit parsed: %s", err.msg[0] ? err.msg : "ok");
    if (rc == 0 && n == 5) {
        is_double(p[0].r, 0.5, 1e-15, "plane normal normalized with its offset");
        is_double(p[2].p[2], 3, 0, "cylinder: point after axis");
        is_double(p[2].a[2], 1, 0, "cylinder axis");
        is_double(p[4].r, 0.1, 0, "torus minor radius first");
        is_double(p[4].R, 2, 0, "torus major radius second");
        /* Round trip through the writer. */
        FILE *f = tmpfile();
        fitfile_write(f, p, n);
        long len = ftell(f);
        rewind(f);
        char *buf = malloc((size_t)len + 1);
        size_t got = fread(buf, 1, (size_t)len, f);
        fclose(f);
        prim *q = NULL;
        size_t m = 0;
        rc = fitfile_parse("rt.fit", buf, got, &q, &m, NULL);
        ok(rc == 0 && m == n && memcmp(p, q, n * sizeof *p) == 0, ".fit round trip exact");
        free(q);
        free(buf);

        /* .hf written and read back, boxes included. */
        p[1].has_obb = 1;
        p[1].obb_half[0] = 0.5;
        p[1].obb_axes[0][0] = 1;
        p[1].support = 123;
        p[1].rms = 0.001;
        p[3].separating = 1;
        f = tmpfile();
        segment_write_hf(f, p, n, "frep segment test\nseed 1", 0.0);
        len = ftell(f);
        rewind(f);
        buf = malloc((size_t)len + 1);
        got = fread(buf, 1, (size_t)len, f);
        fclose(f);
        rc = segment_parse_prims("t.hf", buf, got, 0, &q, &m, &err);
        ok(rc == 0 && m == n, ".hf read back: %s", err.msg[0] ? err.msg : "ok");
        int same = rc == 0 && m == n;
        for (size_t i = 0; same && i < n; i++)
            same = q[i].type == p[i].type && q[i].r == p[i].r && q[i].R == p[i].R &&
                   memcmp(q[i].p, p[i].p, sizeof p[i].p) == 0 && q[i].separating == p[i].separating;
        ok(same, ".hf round trip of parameters is exact");
        ok(rc == 0 && q[1].support == 123 && q[1].has_obb && q[1].obb_half[0] == 0.5,
           ".hf keeps support and box");
        ok(strstr(buf, "primitives = p1 | p2 | p3 | p5;") != NULL, ".hf model is the union of fitted ones");
        free(q);
        free(buf);
    }
    free(p);

    test_rounding();

    const char *bad[][2] = {
        {"plane 0 0 1\n", "t.fit:1: expected 4 numbers after 'plane', got 3"},
        {"\nblob 1 2 3\n", "t.fit:2: unknown primitive type 'blob'"},
        {"cylinder 0 0 0 1 2 3 4\n", "t.fit:1: zero-length axis"},
        {"sphere 1 2 x 4\n", "t.fit:1: 'x 4' is not a number"},
        {"sphere 1 2 nan 4\n", "t.fit:1: number 3 is not finite"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        p = NULL;
        rc = fitfile_parse("t.fit", bad[i][0], strlen(bad[i][0]), &p, &n, &err);
        ok(rc == -1, "bad .fit %zu rejected", i + 1);
        is_str(err.msg[0] ? err.msg : "", bad[i][1], "message");
        free(p);
    }
    const char *hf = "m(x[3], a[1])\n{\n  p1 = frCylinder(x, 1, 2, 3, 0, 0, 1);\n}\n";
    rc = segment_parse_prims("t.hf", hf, strlen(hf), 0, &p, &n, &err);
    ok(rc == -1, "short frCylinder call rejected");
    is_str(err.msg[0] ? err.msg : "", "t.hf:3:8: frCylinder needs 7 numbers after x, got 6", "message");
    /* Lists go through the front end: positions of what is not a primitive list. */
    const char *bad_hf[][2] = {
        {"m(x[3], a[1])\n{\n  p1 = frSphere(x, 0, 0, a[0], 1);\n  m = p1;\n}\n",
         "t.hf:3:26: arguments of frSphere() must be numbers"},
        {"m(x[3], a[1])\n{\n  p1 = frPlane(a, 0, 0, 1, 0);\n  m = p1;\n}\n",
         "t.hf:3:16: expected 'x' as the first argument of frPlane()"},
        {"m(x[3], a[1])\n{\n  p1 = frPlane(x, 0, 0, 0, 1);\n  m = p1;\n}\n",
         "t.hf:3:8: zero-length normal"},
        {"m(x[3], a[1])\n{\n  p1 = hfSphere(x, 0, 0, 0, 1);\n  m = p1;\n}\n",
         "t.hf: no frPlane/frSphere/frCylinder/frCone/frTorus calls"},
    };
    for (size_t i = 0; i < sizeof bad_hf / sizeof bad_hf[0]; i++) {
        p = NULL;
        rc = segment_parse_prims("t.hf", bad_hf[i][0], strlen(bad_hf[i][0]), 0, &p, &n, &err);
        ok(rc == -1, "bad .hf %zu rejected", i + 1);
        is_str(err.msg[0] ? err.msg : "", bad_hf[i][1], "message");
        free(p);
    }
    const char *syntax = "m(x[3], a[1])\n{\n  p1 = frPlane(x, 0, 0, 1, 0)\n  m = p1;\n}\n";
    rc = segment_parse_prims("t.hf", syntax, strlen(syntax), 0, &p, &n, &err);
    ok(rc == -1 && strncmp(err.msg, "t.hf:3:30: expected ';'", 23) == 0,
       "syntax error reported by the front end with line and column: %s", err.msg);
    /* Negative constants, primitives inside any model, comments after the call. */
    const char *two = "m1(x[3], a[1])\n{\n  s = frSphere(x, -1, 0, 0, 2);  -- sphere: 7 points, rms 0.5\n"
                      "  m1 = s;\n}\nm2(x[3], a[1])\n{\n  t = frPlane(x, 0, -2, 0, 1);  -- separating plane\n"
                      "  m2 = t;\n}\n";
    rc = segment_parse_prims("t.hf", two, strlen(two), 0, &p, &n, &err);
    ok(rc == 0 && n == 2 && p[0].p[0] == -1 && p[0].support == 7 && p[0].rms == 0.5 &&
           !p[0].separating && p[1].separating && p[1].p[1] == -1 && p[1].r == 0.5,
       "two models: negative constants, comments read%s%s", err.msg[0] ? ": " : "", err.msg);
    free(p);
}

static void test_bad_input(void)
{
    segment_config cfg;
    segment_config_init(&cfg);
    segment_result res;
    frep_error err;
    frep_cloud *c = cloud_new(0);
    double p[3] = {1, 2, 3};
    for (int i = 0; i < 5; i++) cloud_push(c, p, NULL);
    ok(segment_run(c, &cfg, &res, &err) == -1, "5 points rejected");
    is_str(err.msg[0] ? err.msg : "", "too few points: 5 (segmentation needs at least 8)", "message");
    for (int i = 0; i < 1000; i++) cloud_push(c, p, NULL);
    ok(segment_run(c, &cfg, &res, &err) == -1, "one point repeated rejected");
    is_str(err.msg[0] ? err.msg : "", "all 1005 points are the same point: nothing to segment", "message");
    cloud_free(c);

    /* All points on one plane, every point twice, zero normals: one plane found. */
    trng r = trng_new(8);
    c = cloud_new(1);
    for (int i = 0; i < 2000; i++) {
        double q[3] = {uni(&r), uni(&r), 0.25}, zero[3] = {0, 0, 0};
        cloud_push(c, q, zero);
        cloud_push(c, q, zero);
    }
    int rc = segment_run(c, &cfg, &res, &err);
    ok(rc == 0, "planar cloud with duplicates and zero normals: %s", err.msg[0] ? err.msg : "ok");
    if (rc == 0) {
        ok(res.normals_estimated && res.zero_normals == c->n, "zero normals detected and replaced");
        is_int(res.nfitted, 1, "exactly one primitive");
        ok(res.nfitted == 1 && res.prims[0].type == PRIM_PLANE &&
               fabs(fabs(res.prims[0].p[2]) - 1) < 1e-9 && fabs(fabs(res.prims[0].r) - 0.25) < 1e-9,
           "it is the plane z = 0.25");
        is_int(res.unassigned, 0, "every point assigned");
        segment_result_free(&res);
    }
    cloud_free(c);
}

/* simplify_grow_pieces completes a tree that lacks a face of one part of a union:
 * boxes A = [0,1]^3 and B = [2,3] x [0,1]^2 sampled on their faces, the tree
 * A | B' with B' lacking B's face x >= 2, so that B' is a slab over A too (A's x = 0
 * face and B's x = 2 face explained by nothing). Joining a primitive at the root
 * cannot fix that (& x>=2 cuts A away); the face must go into B's subtree, or the
 * slab be cut by t & ((x<=1 & x>=0) | x>=2). */
static void test_grow_inner(void)
{
    /* Planes: A's six (x<=1, x>=0, y<=1, y>=0, z<=1, z>=0), then B's x<=3, x>=2. */
    prim pl[8];
    memset(pl, 0, sizeof pl);
    const double nx[8] = {1, -1, 0, 0, 0, 0, 1, -1}, ny[8] = {0, 0, 1, -1, 0, 0, 0, 0},
                 nz[8] = {0, 0, 0, 0, 1, -1, 0, 0}, d[8] = {1, 0, 1, 0, 1, 0, 3, -2};
    for (int j = 0; j < 8; j++) {
        pl[j].type = PRIM_PLANE;
        pl[j].p[0] = nx[j];
        pl[j].p[1] = ny[j];
        pl[j].p[2] = nz[j];
        pl[j].r = d[j];
    }
    /* 300 points on each face of each box, outward normals. */
    enum { PER_FACE = 300, NPTS = 2 * 6 * PER_FACE };
    double *x = malloc(3 * NPTS * sizeof *x), *nrm = malloc(3 * NPTS * sizeof *nrm);
    trng r = trng_new(11);
    size_t n = 0;
    for (int b = 0; b < 2; b++)
        for (int axis = 0; axis < 3; axis++)
            for (int sg = 0; sg < 2; sg++)
                for (int k = 0; k < PER_FACE; k++, n++) {
                    for (int a = 0; a < 3; a++) {
                        x[3 * n + a] = uni(&r);
                        nrm[3 * n + a] = 0;
                    }
                    x[3 * n + axis] = sg ? 0 : 1;
                    nrm[3 * n + axis] = sg ? -1 : 1;
                    x[3 * n] += 2 * b;
                }
    double *v = malloc(8 * n * sizeof *v), *g = malloc(3 * 8 * n * sizeof *g);
    for (uint32_t j = 0; j < 8; j++)
        for (size_t i = 0; i < n; i++) {
            double gg[3];
            v[j * n + i] = prim_eval(&pl[j], x + 3 * i, gg);
            for (int a = 0; a < 3; a++) g[(3 * j + (uint32_t)a) * n + i] = gg[a];
        }
    /* eps_d 1% of the diagonal (sqrt(11)), alpha 10 degrees, lambda ln(n). */
    gp_cache *c = gp_cache_new(n, 8, GP_SETOPS_MINMAX, v, g, nrm, 0.01 * sqrt(11.0),
                               10 * M_PI / 180, -1);
    gp_eval *e = gp_eval_new();
    gp_opset o = gp_opset_of(GP_SETOPS_MINMAX);
    gp_tree t = {NULL, 0, 0};
    /* (p0 & p1 & p2 & p3 & p4 & p5) | (p6 & p2 & p3 & p4 & p5) */
    tree_push(&t, FREP_OP_PRIM, 0);
    for (uint32_t j = 1; j < 6; j++) {
        tree_push(&t, FREP_OP_PRIM, j);
        tree_push(&t, (frep_opcode)o.inter, 0);
    }
    tree_push(&t, FREP_OP_PRIM, 6);
    for (uint32_t j = 2; j < 6; j++) {
        tree_push(&t, FREP_OP_PRIM, j);
        tree_push(&t, (frep_opcode)o.inter, 0);
    }
    tree_push(&t, (frep_opcode)o.uni, 0);
    uint8_t *okp = malloc(n);
    size_t before = 0, after = 0;
    if (c && e && okp && gp_explained(c, e, t.code, t.len, okp) == 0)
        for (size_t i = 0; i < n; i++) before += okp[i];
    ok(c && e && before < n - PER_FACE, "the slab tree explains %zu of %zu points", before, n);
    double fit = 0;
    int rc = c && e ? simplify_grow_pieces(&t, GP_SETOPS_MINMAX, c, e, &fit, NULL) : -1;
    if (rc == 0 && gp_explained(c, e, t.code, t.len, okp) == 0)
        for (size_t i = 0; i < n; i++) after += okp[i];
    ok(rc == 0 && after >= n - n / 100, "completed: %zu of %zu points explained, %u nodes", after,
       n, t.len);
    ok(rc == 0 && tree_count_prims(t.code, t.len, 8) == 8, "it uses all 8 planes");
    tree_free(&t);
    free(okp);
    gp_eval_free(e);
    gp_cache_free(c);
    free(x);
    free(nrm);
}

/* Three boxes apart on the diagonal: 18 planes, more than the detector's first
 * primitive array holds. A box of over 100000 points: the spacing estimate then uses a
 * tree of every other point only. */
static void test_large(void)
{
    trng r = trng_new(13);
    frep_cloud *c = cloud_new(1);
    prim truth[18];
    for (int b = 0; b < 3; b++) {
        double lo = 3.0 * b - 1, hi = lo + 2;
        sample_box(c, &r, lo, hi, 400);
        for (int f = 0; f < 6; f++) {
            double n[3] = {0, 0, 0};
            n[f / 2] = f % 2 ? 1 : -1;
            truth[6 * b + f] = mk(PRIM_PLANE, n[0], n[1], n[2], 0, 0, 0, f % 2 ? hi : -lo, 0);
        }
    }
    check_found("three boxes", c, truth, 18, 0.01, 1.0, 1, 0);
    cloud_free(c);
    c = cloud_new(1);
    sample_box(c, &r, -1, 1, 16700);
    check_found("large box", c, truth, 6, 0.01, 1.0, 1, 0);
    cloud_free(c);
}

/* ---- slabs closed at their faces' extent (segment_close_slabs) ---- */

/* An allocator that forwards to the C library until `fail_realloc` is set, then
 * refuses every resize (segment_close_slabs grows the list with one). */
static int fail_realloc;

static void *test_alloc(void *user, void *p, size_t n)
{
    (void)user;
    if (n == 0) {
        free(p);
        return NULL;
    }
    if (p) return fail_realloc ? NULL : realloc(p, n);
    return malloc(n);
}

/* A block x in [0, 2], y in [0, 1] whose faces y = 0 and y = 1 (a slab) show their
 * points, and of the faces across them only x = 0 (the end at x = 2 hidden, as a
 * block's side inside a disc): the plane x = 2, facing +x, closes the slab. */
static void test_close_slabs(void)
{
    frep_cloud *c = cloud_new(0);
    trng r = trng_new(41);
    prim v[3];
    memset(v, 0, sizeof v);
    double nrm[3][3] = {{0, -1, 0}, {0, 1, 0}, {-1, 0, 0}}, off[3] = {0, 1, 0};
    for (int f = 0; f < 3; f++) {
        v[f].type = PRIM_PLANE;
        memcpy(v[f].p, nrm[f], sizeof nrm[f]);
        v[f].r = off[f];
        v[f].has_obb = 1;
    }
    int32_t label[900];
    for (int i = 0; i < 900; i++) {
        int f = i / 300;
        double p[3] = {2 * uni(&r), uni(&r), uni(&r)};
        if (f == 2) p[0] = 0;
        else p[1] = f;
        add(c, p, NULL);
        label[i] = f;
    }
    prim *list = malloc(3 * sizeof *list);
    memcpy(list, v, sizeof v);
    size_t n = 3;
    int rc = c && list ? segment_close_slabs(&list, &n, c, label, 3, 0.01) : -2;
    ok(rc == 0 && n == 4, "one plane closes the slab (%zu planes)", n);
    ok(n == 4 && list[3].type == PRIM_PLANE && fabs(list[3].p[0] - 1) < 1e-12 &&
           fabs(list[3].r - 2) < 0.01 && list[3].separating &&
           list[3].constructed == PRIM_CONSTRUCTED_EXTENT,
       "it is x = 2 facing +x at the faces' extent (r %.4f)", n == 4 ? list[3].r : 0);
    rc = segment_close_slabs(&list, &n, c, label, 3, 0.01);
    ok(rc == 0 && n == 4, "a second call adds no duplicate (%zu planes)", n);
    n = 3;
    fail_realloc = 1;
    rc = segment_close_slabs(&list, &n, c, label, 3, 0.01);
    fail_realloc = 0;
    ok(rc == -1 && n == 3 && list[2].type == PRIM_PLANE && list[2].p[0] == -1,
       "out of memory: -1, the list and its count kept (%zu planes)", n);
    free(list);
    cloud_free(c);
}

/* ---- a small face whose normals are as rough as the cloud's (SMALL_FACE_NOISE) ---- */

/* Normal n turned by Gaussian angles of sigma radians about two axes across it. */
static void jitter_normal(trng *r, double n[3], double sigma)
{
    double u[3] = {1, 0, 0};
    if (fabs(n[0]) > 0.9) u[0] = 0, u[1] = 1;
    double t1[3], t2[3];
    vec3_cross(n, u, t1);
    vec3_normalize(t1);
    vec3_cross(n, t1, t2);
    double a = sigma * gauss(r), b = sigma * gauss(r);
    for (int k = 0; k < 3; k++) n[k] += a * t1[k] + b * t2[k];
    vec3_normalize(n);
}

/* The faces of the box [-1, 1]^3 (1,500 points each) with normals turned by a median
 * of 4 degrees (an estimate's error on a noisy scan), and a face of 60 points at z =
 * 1.5 over [0.2, 0.6]^2, too few for the first phase, turned by `tilt_deg` about the x
 * axis through its centre, whose normals are turned by a median of `face_deg`: whether
 * the second phase finds it. */
static int small_face_found(double face_deg, double tilt_deg)
{
    const double rayleigh_median = sqrt(2 * log(2.0)), deg = M_PI / 180;
    const double ct = cos(tilt_deg * deg), st = sin(tilt_deg * deg);
    trng r = trng_new(5);
    frep_cloud *c = cloud_new(1);
    for (int f = 0; f < 6; f++)
        for (int i = 0; i < 1500; i++) {
            int ax = f / 2;
            double p[3], n[3] = {0, 0, 0};
            for (int k = 0; k < 3; k++) p[k] = 2 * uni(&r) - 1;
            p[ax] = f % 2 ? 1 : -1;
            n[ax] = f % 2 ? 1 : -1;
            jitter_normal(&r, n, 4 * deg / rayleigh_median);
            add(c, p, n);
        }
    for (int i = 0; i < 60; i++) {
        double y = 0.4 * uni(&r) - 0.2;
        double p[3] = {0.2 + 0.4 * uni(&r), 0.4 + ct * y, 1.5 + st * y}, n[3] = {0, -st, ct};
        jitter_normal(&r, n, face_deg * deg / rayleigh_median);
        add(c, p, n);
    }
    segment_config cfg;
    segment_config_init(&cfg);
    cfg.seed = 3;
    segment_result res;
    frep_error err;
    int found = -1;
    if (segment_run(c, &cfg, &res, &err) == 0) {
        found = 0;
        prim face = mk(PRIM_PLANE, 0, -st, ct, 0, 0, 0, -st * 0.4 + ct * 1.5, 0);
        for (size_t j = 0; j < res.nfitted; j++) found += matches(&res.prims[j], &face, 0.01, 2.0);
        segment_result_free(&res);
    }
    cloud_free(c);
    return found;
}

static void test_small_face(void)
{
    /* 6.5 degrees: over SMALL_NORMAL_DEG (5), within twice the faces' 4. */
    int f = small_face_found(6.5, 0);
    ok(f == 1, "a small face with normals 6.5 degrees off, on a cloud 4 degrees off, is found (%d)", f);
    f = small_face_found(6.5, 20);
    ok(f == 1, "and turned 20 degrees from the box's faces (%d)", f);
    /* 10 degrees: over twice the faces' 4 (what a strip across a curved surface shows),
     * on a face 20 degrees from parallel to the box's. */
    f = small_face_found(10, 20);
    ok(f == 0, "one 10 degrees off, turned 20 degrees from the box's faces, is not (%d)", f);
    /* The same parallel to a face found, with none of its points on one: a narrow face
     * (segment/ransac.c, narrow_face), whose normals are blended with its neighbours'. */
    f = small_face_found(10, 0);
    ok(f == 1, "one 10 degrees off, parallel to the box's top and apart from it, is found (%d)", f);
}

int main(void)
{
    frep_set_allocator(test_alloc, NULL);
    test_kdtree();
    test_normals();
    test_files();
    test_bad_input();
    test_determinism();
    test_shapes();
    test_grow_inner();
    test_large();
    test_close_slabs();
    test_small_face();
    return done_testing();
}

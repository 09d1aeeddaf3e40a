/* test_sample.c - unit tests of surface sampling (mesh/sample.c): points lie on the
 * zero set, normals are the outward analytic normals, density is even, the cloud does
 * not depend on the thread count, noise and outliers have the requested size, and mesh
 * sampling uses face normals.
 */
#include "config.h"

#include "sample.h"
#include "tap.h"

#include <stdlib.h>

/* Ellipsoid x^2/a^2 + y^2/b^2 + z^2/c^2 <= 1 as f = 1 - (...) >= 0; a sphere when equal. */
typedef struct ell {
    double a, b, c;
} ell;

static int e_eval(void *ctx, void *ts, size_t n, const double *x, const double *y,
                  const double *z, double *f)
{
    const ell *e = ctx;
    (void)ts;
    for (size_t i = 0; i < n; i++)
        f[i] = 1 - x[i] * x[i] / (e->a * e->a) - y[i] * y[i] / (e->b * e->b) -
               z[i] * z[i] / (e->c * e->c);
    return 0;
}

static int e_grad(void *ctx, void *ts, size_t n, const double *x, const double *y,
                  const double *z, double *f, double *gx, double *gy, double *gz)
{
    const ell *e = ctx;
    e_eval(ctx, ts, n, x, y, z, f);
    for (size_t i = 0; i < n; i++) {
        gx[i] = -2 * x[i] / (e->a * e->a);
        gy[i] = -2 * y[i] / (e->b * e->b);
        gz[i] = -2 * z[i] / (e->c * e->c);
    }
    return 0;
}

static void *e_new(void *ctx) { return ctx; }
static void e_free(void *ctx, void *ts) { (void)ctx; (void)ts; }

static mesh_field field(ell *e)
{
    mesh_field f = { e, e_new, e_free, e_eval, e_grad, NULL, NULL, 0 };
    return f;
}

static sample_options opts(size_t n, int threads)
{
    sample_options o;
    sample_options_init(&o);
    o.n = n;
    o.seed = 7;
    for (int k = 0; k < 3; k++) {
        o.mesh.box[k] = -1.5;
        o.mesh.box[k + 3] = 1.5;
    }
    o.mesh.grid = 40;
    o.mesh.nthreads = threads;
    return o;
}

/* sample_field and sample_mesh with a fresh error (the first error set wins). */
static int sample_f(const mesh_field *f, const sample_options *o, frep_cloud **out,
                    frep_error *err)
{
    frep_error_init(err);
    return sample_field(f, o, out, err);
}

static int sample_m(const frep_mesh *m, const sample_options *o, frep_cloud **out,
                    frep_error *err)
{
    frep_error_init(err);
    return sample_mesh(m, o, out, err);
}

int main(void)
{
    ell sph = { 1, 1, 1 };
    mesh_field f = field(&sph);
    f.cost = 1e9; /* every stage worth its threads (mesh_threads_for), however small */
    frep_error err;
    frep_cloud *c = NULL, *c2 = NULL;
    sample_options o = opts(20000, 2);
    ok(sample_f(&f, &o, &c, &err) == 0 && c && c->n == 20000,
       "20000 points sampled from a sphere");
    if (c) {
        double worst = 0, worst_n = 0;
        /* density: count points per octant and per z band of equal area (Archimedes:
         * equal-height bands of a sphere have equal area) */
        size_t band[10] = { 0 }, oct[8] = { 0 };
        for (size_t i = 0; i < c->n; i++) {
            double r = sqrt(c->x[i] * c->x[i] + c->y[i] * c->y[i] + c->z[i] * c->z[i]);
            if (fabs(r - 1) > worst) worst = fabs(r - 1);
            double dn = 1 - (c->nx[i] * c->x[i] + c->ny[i] * c->y[i] + c->nz[i] * c->z[i]) / r;
            if (dn > worst_n) worst_n = dn;
            int b = (int)((c->z[i] + 1) * 5);
            band[b < 0 ? 0 : (b > 9 ? 9 : b)]++;
            oct[(c->x[i] > 0) + 2 * (c->y[i] > 0) + 4 * (c->z[i] > 0)]++;
        }
        ok(worst < 1e-9, "points lie on the sphere (max |r - 1| = %.2e)", worst);
        ok(worst_n < 1e-9, "normals are the outward radial normals (max 1 - cos = %.2e)", worst_n);
        /* 2000 expected per band: 5 sigma of a binomial is ~212 */
        size_t lo = 20000, hi = 0;
        for (int b = 0; b < 10; b++) {
            if (band[b] < lo) lo = band[b];
            if (band[b] > hi) hi = band[b];
        }
        ok(lo > 1790 && hi < 2210, "even density: equal-area bands hold %zu..%zu of 2000 expected",
           lo, hi);
        lo = 20000, hi = 0;
        for (int k = 0; k < 8; k++) {
            if (oct[k] < lo) lo = oct[k];
            if (oct[k] > hi) hi = oct[k];
        }
        ok(lo > 2330 && hi < 2670, "even density: octants hold %zu..%zu of 2500 expected", lo, hi);
    }
    sample_options o1 = opts(20000, 1);
    ok(sample_f(&f, &o1, &c2, &err) == 0 && c && c2 && c2->n == c->n &&
       memcmp(c->x, c2->x, c->n * sizeof *c->x) == 0 &&
       memcmp(c->nz, c2->nz, c->n * sizeof *c->nz) == 0,
       "the same cloud at 1 and 2 threads");
    cloud_free(c2);
    c2 = NULL;
    sample_options o0 = opts(20000, 0);
    ok(sample_f(&f, &o0, &c2, &err) == 0 && c && c2 && c2->n == c->n &&
       memcmp(c->x, c2->x, c->n * sizeof *c->x) == 0 &&
       memcmp(c->y, c2->y, c->n * sizeof *c->y) == 0 &&
       memcmp(c->nx, c2->nx, c->n * sizeof *c->nx) == 0,
       "the same cloud at 2 threads and the default");
    cloud_free(c2);
    c2 = NULL;

    /* ellipsoid: normals follow the gradient, not the radius */
    ell el = { 1.2, 0.7, 0.5 };
    mesh_field fe = field(&el);
    o = opts(5000, 2);
    if (sample_f(&fe, &o, &c2, &err) == 0) {
        double worst = 0, worst_n = 0;
        for (size_t i = 0; i < c2->n; i++) {
            double x = c2->x[i], y = c2->y[i], z = c2->z[i];
            double g[3] = { 2 * x / 1.44, 2 * y / 0.49, 2 * z / 0.25 };
            double gl = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
            double fv = 1 - x * x / 1.44 - y * y / 0.49 - z * z / 0.25;
            if (fabs(fv) / gl > worst) worst = fabs(fv) / gl;
            double dn = 1 - (c2->nx[i] * g[0] + c2->ny[i] * g[1] + c2->nz[i] * g[2]) / gl;
            if (dn > worst_n) worst_n = dn;
        }
        ok(worst < 1e-9 && worst_n < 1e-9, "ellipsoid: |f|/|grad f| %.1e, normal error %.1e",
           worst, worst_n);
    } else {
        ok(0, "ellipsoid sampled: %s", err.msg);
    }
    cloud_free(c2);
    c2 = NULL;

    /* noise and outliers */
    o = opts(10000, 2);
    o.noise = 0.01;
    o.outliers = 0.1;
    if (sample_f(&f, &o, &c2, &err) == 0) {
        double s2 = 0;
        size_t far = 0;
        for (size_t i = 0; i < 9000; i++) {
            double r = sqrt(c2->x[i] * c2->x[i] + c2->y[i] * c2->y[i] + c2->z[i] * c2->z[i]);
            s2 += (r - 1) * (r - 1);
        }
        for (size_t i = 9000; i < 10000; i++) {
            double r = sqrt(c2->x[i] * c2->x[i] + c2->y[i] * c2->y[i] + c2->z[i] * c2->z[i]);
            if (fabs(r - 1) > 0.1) far++;
        }
        double sigma = 0.01 * sqrt(27.0), got = sqrt(s2 / 9000);
        diag("noise sigma %.4f (0.01 x the box diagonal)", sigma);
        is_double(got, sigma, 0.1 * sigma, "noise: radial deviation of the surface points");
        ok(far > 700, "outliers: %zu of the last 1000 points are off the surface", far);
    } else {
        ok(0, "noisy sampling: %s", err.msg);
    }
    cloud_free(c2);
    c2 = NULL;

    /* a mesh: one triangle per face of a unit cube's two opposite faces */
    double v[] = { 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1 };
    uint32_t t[] = { 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7 };
    frep_mesh m = { 8, 4, v, NULL, t };
    o = opts(4000, 1);
    if (sample_m(&m, &o, &c2, &err) == 0) {
        size_t bad = 0, top = 0;
        for (size_t i = 0; i < c2->n; i++) {
            int up = c2->z[i] > 0.5;
            top += up;
            if (fabs(c2->z[i] - (up ? 1 : 0)) > 1e-12 || fabs(c2->nz[i] - (up ? 1 : -1)) > 1e-12)
                bad++;
        }
        ok(bad == 0, "mesh sampling: points on the faces with face normals (%zu bad)", bad);
        ok(top > 1800 && top < 2200, "mesh sampling is area-weighted (%zu of 4000 on top)", top);
    } else {
        ok(0, "mesh sampled: %s", err.msg);
    }
    cloud_free(c2);
    o = opts(0, 1);
    ok(sample_f(&f, &o, &c2, &err) != 0 && err.code == FREP_EINPUT, "zero points refused: %s", err.msg);
    o = opts(10, 1);
    o.outliers = 2;
    ok(sample_f(&f, &o, &c2, &err) != 0 && err.code == FREP_EINPUT, "outlier fraction 2 refused: %s", err.msg);
    ell tiny = { 0.01, 0.01, 0.01 };
    mesh_field ft = field(&tiny);
    o = opts(10, 1);
    o.mesh.grid = 9; /* no grid point within 0.01 of the origin */
    ok(sample_f(&ft, &o, &c2, &err) != 0 && err.msg[0] && err.code == FREP_EINPUT,
       "a model smaller than the grid: %s", err.msg);
    cloud_free(c);
    return done_testing();
}

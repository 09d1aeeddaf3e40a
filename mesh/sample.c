/* sample.c - surface sampling (sample.h): area-weighted points on a mesh, projected
 * onto the model's zero set by Newton steps, with normals from the gradient; noise and
 * outliers for test clouds.  Used by `frep sample`.
 */
#include "config.h"

#include "alloc.h"
#include "sample.h"
#include "rng.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

/* Points per evaluation batch in the projection: a multiple of FREP_BLOCK. */
#define SAMPLE_BATCH 1024

void sample_options_init(sample_options *o)
{
    memset(o, 0, sizeof *o);
    o->n = 10000;
    o->seed = 1;
    mesh_options_init(&o->mesh);
    o->mesh.grid = 0; /* chosen from the point count unless set */
}

/* The shared generator (runtime/rng.h) under this file's short names. */
typedef frep_rng rng;
static void rng_seed(rng *r, uint64_t seed) { frep_rng_seed(r, seed); }

static double rng_unit(rng *r) { return frep_rng_unit(r); }

static double rng_gauss(rng *r)
{
    double u = rng_unit(r), v = rng_unit(r);
    return sqrt(-2 * log(1 - u)) * cos(6.283185307179586 * v);
}

/* Draw n points on m's triangles, area-weighted; tri_of[i] receives the triangle. */
static int draw_on_mesh(const frep_mesh *m, rng *r, size_t n, frep_cloud *c, size_t *tri_of)
{
    double *cum = frep_malloc((m->ntris + 1) * sizeof *cum);
    if (!cum) return -1;
    double total = 0;
    for (size_t t = 0; t < m->ntris; t++) {
        const double *a = &m->v[3 * m->tri[3 * t]], *b = &m->v[3 * m->tri[3 * t + 1]],
                     *d = &m->v[3 * m->tri[3 * t + 2]];
        double u[3] = { b[0] - a[0], b[1] - a[1], b[2] - a[2] };
        double w[3] = { d[0] - a[0], d[1] - a[1], d[2] - a[2] };
        double cx = u[1] * w[2] - u[2] * w[1], cy = u[2] * w[0] - u[0] * w[2],
               cz = u[0] * w[1] - u[1] * w[0];
        total += 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
        cum[t] = total;
    }
    if (!(total > 0)) {
        frep_free(cum);
        return -2;
    }
    for (size_t i = 0; i < n; i++) {
        double u = rng_unit(r) * total;
        size_t lo = 0, hi = m->ntris - 1;
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (cum[mid] <= u) lo = mid + 1;
            else hi = mid;
        }
        double s = rng_unit(r), t = rng_unit(r);
        if (s + t > 1) {
            s = 1 - s;
            t = 1 - t;
        }
        const double *a = &m->v[3 * m->tri[3 * lo]], *b = &m->v[3 * m->tri[3 * lo + 1]],
                     *d = &m->v[3 * m->tri[3 * lo + 2]];
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = a[k] + s * (b[k] - a[k]) + t * (d[k] - a[k]);
        double u3[3] = { b[0] - a[0], b[1] - a[1], b[2] - a[2] };
        double w3[3] = { d[0] - a[0], d[1] - a[1], d[2] - a[2] };
        double nrm[3] = { u3[1] * w3[2] - u3[2] * w3[1], u3[2] * w3[0] - u3[0] * w3[2],
                          u3[0] * w3[1] - u3[1] * w3[0] };
        double l = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        for (int k = 0; k < 3; k++) nrm[k] = l > 0 ? nrm[k] / l : 0;
        if (cloud_push(c, p, nrm) != 0) {
            frep_free(cum);
            return -1;
        }
        if (tri_of) tri_of[i] = lo;
    }
    frep_free(cum);
    return 0;
}

/* Noise and outliers, drawn after the surface points so that the surface points of
 * a cloud do not change when only these options do. */
static void perturb(const sample_options *o, const double box[6], rng *r, frep_cloud *c,
                    size_t nsurf)
{
    double dx = box[3] - box[0], dy = box[4] - box[1], dz = box[5] - box[2];
    double diag = sqrt(dx * dx + dy * dy + dz * dz);
    double sigma = o->noise_absolute ? o->noise : o->noise * diag;
    if (sigma > 0)
        for (size_t i = 0; i < nsurf; i++) {
            c->x[i] += sigma * rng_gauss(r);
            c->y[i] += sigma * rng_gauss(r);
            c->z[i] += sigma * rng_gauss(r);
        }
    for (size_t i = nsurf; i < c->n; i++) {
        c->x[i] = box[0] + dx * rng_unit(r);
        c->y[i] = box[1] + dy * rng_unit(r);
        c->z[i] = box[2] + dz * rng_unit(r);
        double nv[3] = { rng_gauss(r), rng_gauss(r), rng_gauss(r) };
        double l = sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
        c->nx[i] = l > 0 ? nv[0] / l : 1;
        c->ny[i] = l > 0 ? nv[1] / l : 0;
        c->nz[i] = l > 0 ? nv[2] / l : 0;
    }
}

static int check_opts(const sample_options *o, char *err, size_t errlen)
{
    if (o->n < 1 || o->n > SAMPLE_MAX_POINTS) {
        snprintf(err, errlen, "the number of points must be 1..%zu", (size_t)SAMPLE_MAX_POINTS);
        return -1;
    }
    if (!(o->noise >= 0) || !isfinite(o->noise)) {
        snprintf(err, errlen, "the noise must be a finite number >= 0");
        return -1;
    }
    if (!(o->outliers >= 0 && o->outliers <= 1)) {
        snprintf(err, errlen, "the outlier fraction must be in [0, 1]");
        return -1;
    }
    return 0;
}

static size_t n_outliers(const sample_options *o)
{
    return (size_t)floor(o->outliers * (double)o->n + 0.5);
}

int sample_mesh(const frep_mesh *m, const sample_options *o, frep_cloud **out, char *err,
                size_t errlen)
{
    *out = NULL;
    if (check_opts(o, err, errlen)) return -1;
    size_t nout = n_outliers(o), nsurf = o->n - nout;
    frep_cloud *c = cloud_new(1);
    if (!c || cloud_reserve(c, o->n) != 0) goto oom;
    rng r;
    rng_seed(&r, o->seed);
    int rc = draw_on_mesh(m, &r, nsurf, c, NULL);
    if (rc == -2) {
        snprintf(err, errlen, "the mesh has zero area");
        cloud_free(c);
        return -1;
    }
    if (rc) goto oom;
    double box[6] = { INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY };
    for (size_t i = 0; i < m->nverts; i++)
        for (int k = 0; k < 3; k++) {
            box[k] = fmin(box[k], m->v[3 * i + k]);
            box[k + 3] = fmax(box[k + 3], m->v[3 * i + k]);
        }
    for (size_t i = nsurf; i < o->n; i++) {
        double zero[3] = { 0, 0, 0 };
        if (cloud_push(c, zero, zero)) goto oom;
    }
    perturb(o, box, &r, c, nsurf);
    *out = c;
    return 0;
oom:
    cloud_free(c);
    snprintf(err, errlen, "out of memory");
    return -1;
}

int sample_field(const mesh_field *f, const sample_options *o, frep_cloud **out, char *err,
                 size_t errlen)
{
    *out = NULL;
    if (check_opts(o, err, errlen)) return -1;
    mesh_options mo = o->mesh;
    if (mo.grid <= 0) {
        /* about 4 points per mesh triangle at most: the grid follows the density */
        double g = sqrt((double)o->n / 6.0);
        mo.grid = g < 32 ? 32 : (g > 256 ? 256 : (int)g);
    }
    frep_mesh m;
    mesh_stats st;
    if (mesh_polygonize(f, &mo, &m, &st, err, errlen) != 0) return -1;
    if (m.ntris == 0 || st.full) {
        snprintf(err, errlen, st.full ? "the model fills the whole box: no surface to sample"
                                      : "the model is empty in the box: no surface to sample");
        mesh_free(&m);
        return -1;
    }
    size_t nout = n_outliers(o), nsurf = o->n - nout;
    frep_cloud *c = cloud_new(1);
    if (!c || cloud_reserve(c, o->n) != 0) goto oom;
    rng r;
    rng_seed(&r, o->seed);
    if (draw_on_mesh(&m, &r, nsurf, c, NULL) != 0) goto oom;
    mesh_free(&m);

    /* project onto the zero set: p -= (f - iso) grad / |grad|^2, staying inside a
     * cell of the start (a step longer than that means a bad gradient) */
    double cell = 0;
    for (int k = 0; k < 3; k++) cell = fmax(cell, (mo.box[k + 3] - mo.box[k]) / mo.grid);
    long nb = (long)((nsurf + SAMPLE_BATCH - 1) / SAMPLE_BATCH);
    int failed = 0;
    int nthreads = mo.nthreads;
#ifdef _OPENMP
    if (nthreads <= 0) nthreads = omp_get_max_threads();
#else
    (void)nthreads; /* serial build: the pragma below is ignored */
#endif
#pragma omp parallel num_threads(nthreads)
    {
        void *ts = f->thread_new(f->ctx);
        double *buf = frep_malloc(7 * SAMPLE_BATCH * sizeof *buf);
        if (!ts || !buf) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 4)
        for (long b = 0; b < nb; b++) {
            if (!ts || !buf) continue;
            size_t i0 = (size_t)b * SAMPLE_BATCH;
            size_t n = nsurf - i0 < SAMPLE_BATCH ? nsurf - i0 : SAMPLE_BATCH;
            double *x = buf, *y = x + SAMPLE_BATCH, *z = y + SAMPLE_BATCH, *fv = z + SAMPLE_BATCH,
                   *gx = fv + SAMPLE_BATCH, *gy = gx + SAMPLE_BATCH, *gz = gy + SAMPLE_BATCH;
            memcpy(x, c->x + i0, n * sizeof *x);
            memcpy(y, c->y + i0, n * sizeof *y);
            memcpy(z, c->z + i0, n * sizeof *z);
            for (int step = 0; step <= SAMPLE_NEWTON_STEPS; step++) {
                if (f->grad(f->ctx, ts, n, x, y, z, fv, gx, gy, gz) != 0) {
#pragma omp atomic write
                    failed = 1;
                    break;
                }
                for (size_t i = 0; i < n; i++) {
                    double g2 = gx[i] * gx[i] + gy[i] * gy[i] + gz[i] * gz[i];
                    if (step == SAMPLE_NEWTON_STEPS) {
                        double l = sqrt(g2);
                        if (l > 0 && isfinite(l) && isfinite(fv[i])) {
                            c->x[i0 + i] = x[i];
                            c->y[i0 + i] = y[i];
                            c->z[i0 + i] = z[i];
                            c->nx[i0 + i] = -gx[i] / l;
                            c->ny[i0 + i] = -gy[i] / l;
                            c->nz[i0 + i] = -gz[i] / l;
                        }
                        continue;
                    }
                    if (!(g2 > 0) || !isfinite(g2) || !isfinite(fv[i])) continue;
                    double s = (fv[i] - mo.iso) / g2;
                    double dx = s * gx[i], dy = s * gy[i], dz = s * gz[i];
                    double len = sqrt(dx * dx + dy * dy + dz * dz);
                    if (len > cell) continue;
                    double nxp = x[i] - dx, nyp = y[i] - dy, nzp = z[i] - dz;
                    double ox = c->x[i0 + i] - nxp, oy = c->y[i0 + i] - nyp, oz = c->z[i0 + i] - nzp;
                    if (ox * ox + oy * oy + oz * oz > cell * cell) continue;
                    x[i] = nxp;
                    y[i] = nyp;
                    z[i] = nzp;
                }
            }
        }
        frep_free(buf);
        if (ts) {
            /* thread_free may merge per-thread state (runtime errors) into ctx */
#pragma omp critical(sample_thread_free)
            f->thread_free(f->ctx, ts);
        }
    }
    if (failed) {
        cloud_free(c);
        snprintf(err, errlen, "out of memory or evaluation failure while sampling");
        return -1;
    }
    for (size_t i = nsurf; i < o->n; i++) {
        double zero[3] = { 0, 0, 0 };
        if (cloud_push(c, zero, zero)) goto oom;
    }
    perturb(o, mo.box, &r, c, nsurf);
    *out = c;
    return 0;
oom:
    mesh_free(&m);
    cloud_free(c);
    snprintf(err, errlen, "out of memory");
    return -1;
}

/* distance.c - how far a mesh's vertices are from the surface it approximates
 * (mesh_surface_distance, mesh.h): |f - iso| / |grad f| at each vertex, in cells of the
 * grid, evaluated with the field.  `frep mesh --check` and the tests bound it.
 */
#include "config.h"

#include "mesh.h"

#include <math.h>
#include <string.h>

/* Vertices evaluated per field call. */
#define DIST_BATCH 1024
/* Vertices this fraction of a cell or closer to a box face are on a cap (the solid cut
 * by the box) and not on the surface. */
#define DIST_CAP_SLACK 1e-3

typedef struct dist_run {
    const mesh_options *o;
    double cell;              /* the smallest cell side */
    double tol;
    mesh_distance *r;
} dist_run;

/* On or outside the box (within DIST_CAP_SLACK cells of a face). */
static int on_cap(const dist_run *d, const double *p)
{
    for (int k = 0; k < 3; k++) {
        double h = (d->o->box[k + 3] - d->o->box[k]) / mesh_options_cells(d->o, k);
        double s = DIST_CAP_SLACK * h;
        if (p[k] <= d->o->box[k] + s || p[k] >= d->o->box[k + 3] - s) return 1;
    }
    return 0;
}

/* Vertex v with value f and gradient g into the counts. */
static void add_vertex(dist_run *d, size_t v, double f, const double g[3])
{
    double gl = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if (isnan(f) || isnan(gl)) {
        d->r->skipped++;
        return;
    }
    double dist = f == d->o->iso ? 0 : fabs(f - d->o->iso) / gl / d->cell;
    if (dist > d->tol) d->r->far++;
    if (dist > d->r->max_dist) {
        d->r->max_dist = dist;
        d->r->worst = v;
    }
}

int mesh_surface_distance(const mesh_field *f, const mesh_options *o, const frep_mesh *m,
                          double tol, mesh_distance *r, frep_error *e)
{
    memset(r, 0, sizeof *r);
    dist_run d = { .o = o, .tol = tol, .r = r, .cell = INFINITY };
    for (int k = 0; k < 3; k++)
        d.cell = fmin(d.cell, (o->box[k + 3] - o->box[k]) / mesh_options_cells(o, k));
    void *ts = f->thread_new(f->ctx);
    if (!ts) return frep_error_nomem(e);
    double x[DIST_BATCH], y[DIST_BATCH], z[DIST_BATCH], fv[DIST_BATCH];
    double gx[DIST_BATCH], gy[DIST_BATCH], gz[DIST_BATCH];
    size_t idx[DIST_BATCH];
    int rc = 0;
    for (size_t v0 = 0; v0 < m->nverts && rc == 0; v0 += DIST_BATCH) {
        size_t n = 0;
        for (size_t v = v0; v < m->nverts && v < v0 + DIST_BATCH; v++) {
            const double *p = &m->v[3 * v];
            if (on_cap(&d, p)) {
                r->capped++;
                continue;
            }
            x[n] = p[0];
            y[n] = p[1];
            z[n] = p[2];
            idx[n++] = v;
        }
        if (n && f->grad(f->ctx, ts, n, x, y, z, fv, gx, gy, gz) != 0) {
            rc = frep_error_set(e, FREP_EINPUT, "the field failed at the mesh's vertices");
            break;
        }
        for (size_t q = 0; q < n; q++) {
            const double g[3] = { gx[q], gy[q], gz[q] };
            add_vertex(&d, idx[q], fv[q], g);
        }
    }
    f->thread_free(f->ctx, ts);
    return rc;
}

/* distance.c - how far a mesh's vertices are from the surface it approximates
 * (mesh_surface_distance, mesh.h): |f - iso| / |grad f| at each vertex, in cells of the
 * grid (coordinates scaled so that a cell is a unit cube: a vertex on a face normal to
 * x is measured in cells along x, whatever the other sides), evaluated with the
 * field.  Where that first-order estimate exceeds the
 * tolerance (a field whose gradient is not a distance's, e.g. an R-function union
 * near a concave edge, where |grad f| is much smaller off the surface than on it),
 * the vertex is measured again by a search for the surface: the smallest radius of
 * DIST_RADII at which one of DIST_NDIRS directions reaches the other side of the
 * level, an upper bound of the true distance.  `frep mesh --check` and the tests bound
 * it.
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
/* The search for the surface around a vertex: the 26 directions to a cube's
 * neighbours and the two along the gradient, at these radii (cells): four steps up to
 * the tolerance of --check, then coarser ones for the report. */
#define DIST_NDIRS 28
#define DIST_NRADII 12
static const double dist_radii[DIST_NRADII] = { 0.025, 0.05, 0.075, 0.1, 0.15, 0.2,
                                                0.3, 0.5, 0.75, 1, 1.5, 2 };

typedef struct dist_run {
    const mesh_options *o;
    double h[3];              /* the cell's sides */
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

/* The smallest radius of dist_radii (cells) at which a point in one of the search
 * directions around p lies on the other side of the level than f, or INFINITY; -1
 * when the field fails. */
static double search_surface(const mesh_field *fl, void *ts, const dist_run *d,
                             const double p[3], double f, const double g[3])
{
    enum { NP = DIST_NDIRS * DIST_NRADII };
    double dir[DIST_NDIRS][3];
    int nd = 0;
    for (int a = -1; a <= 1; a++)
        for (int b = -1; b <= 1; b++)
            for (int c = -1; c <= 1; c++) {
                if (!a && !b && !c) continue;
                double l = sqrt((double)(a * a + b * b + c * c));
                dir[nd][0] = a / l;
                dir[nd][1] = b / l;
                dir[nd][2] = c / l;
                nd++;
            }
    /* the gradient in cell units: along the steepest direction of the grid's index space */
    double gc[3] = { g[0] * d->h[0], g[1] * d->h[1], g[2] * d->h[2] };
    double gl = sqrt(gc[0] * gc[0] + gc[1] * gc[1] + gc[2] * gc[2]);
    for (int s = -1; s <= 1; s += 2, nd++)
        for (int k = 0; k < 3; k++) dir[nd][k] = gl > 0 ? s * gc[k] / gl : 0;
    double x[NP], y[NP], z[NP], fv[NP];
    for (int r = 0; r < DIST_NRADII; r++)
        for (int q = 0; q < DIST_NDIRS; q++) {
            double t = dist_radii[r];
            x[r * DIST_NDIRS + q] = p[0] + t * dir[q][0] * d->h[0];
            y[r * DIST_NDIRS + q] = p[1] + t * dir[q][1] * d->h[1];
            z[r * DIST_NDIRS + q] = p[2] + t * dir[q][2] * d->h[2];
        }
    if (fl->eval(fl->ctx, ts, NP, x, y, z, fv) != 0) return -1;
    int in = f >= d->o->iso;
    for (int i = 0; i < NP; i++)
        if ((fv[i] >= d->o->iso) != in && !isnan(fv[i])) return dist_radii[i / DIST_NDIRS];
    return INFINITY;
}

/* Vertex v at p with value f and gradient g into the counts.  0, or -1 when the field
 * fails. */
static int add_vertex(const mesh_field *fl, void *ts, dist_run *d, size_t v, const double p[3],
                      double f, const double g[3])
{
    double gc[3] = { g[0] * d->h[0], g[1] * d->h[1], g[2] * d->h[2] };
    double gl = sqrt(gc[0] * gc[0] + gc[1] * gc[1] + gc[2] * gc[2]);
    if (isnan(f) || isnan(gl)) {
        d->r->skipped++;
        return 0;
    }
    double dist = f == d->o->iso ? 0 : fabs(f - d->o->iso) / gl;
    if (dist > d->tol) {
        double r = search_surface(fl, ts, d, p, f, g);
        if (r < 0) return -1;
        dist = fmin(dist, r);
    }
    if (dist > d->tol) d->r->far++;
    if (dist > d->r->max_dist) {
        d->r->max_dist = dist;
        d->r->worst = v;
    }
    return 0;
}

int mesh_surface_distance(const mesh_field *f, const mesh_options *o, const frep_mesh *m,
                          double tol, mesh_distance *r, frep_error *e)
{
    memset(r, 0, sizeof *r);
    dist_run d = { .o = o, .tol = tol, .r = r };
    for (int k = 0; k < 3; k++) d.h[k] = (o->box[k + 3] - o->box[k]) / mesh_options_cells(o, k);
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
        for (size_t q = 0; q < n && rc == 0; q++) {
            const double g[3] = { gx[q], gy[q], gz[q] };
            if (add_vertex(f, ts, &d, idx[q], &m->v[3 * idx[q]], fv[q], g) != 0)
                rc = frep_error_set(e, FREP_EINPUT, "the field failed near the mesh's vertices");
        }
    }
    f->thread_free(f->ctx, ts);
    return rc;
}

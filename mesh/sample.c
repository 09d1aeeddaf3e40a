/* sample.c - surface sampling (sample.h): area-weighted points on a mesh, projected
 * onto the model's zero set by Newton steps, with normals from the gradient; noise and
 * outliers for test clouds.  Used by `frep sample`.
 */
#include "config.h"

#include "alloc.h"
#include "mesh_internal.h"
#include "rng.h"
#include "sample.h"
#include "util.h"
#include "vec3.h"

#include <math.h>
#include <stdatomic.h>
#include <string.h>

/* Points per evaluation batch in the projection: a multiple of FREP_BLOCK. */
#define SAMPLE_BATCH 1024
/* The grid chosen from the point count, sqrt(n / SAMPLE_POINTS_PER_GRID2) within these
 * bounds: about 4 points per mesh triangle at most, so the grid follows the density. */
#define SAMPLE_GRID_MIN 32
#define SAMPLE_GRID_MAX 256
#define SAMPLE_POINTS_PER_GRID2 6.0
/* Ctrl-C is polled once per 2^16 points drawn on a mesh (about a millisecond). */
#define SAMPLE_POLL_MASK 0xffffu

void sample_options_init(sample_options *o)
{
    memset(o, 0, sizeof *o);
    o->n = 10000;
    o->seed = 1;
    mesh_options_init(&o->mesh);
    o->mesh.grid = 0; /* chosen from the point count unless set */
}

/* The cross product of b - a and d - a over sc^2 (sc > 0 a length of the mesh's scale):
 * finite for coordinates near the largest double, where the plain product overflows. */
static void scaled_cross(const double *a, const double *b, const double *d, double sc,
                         double n[3])
{
    double u[3], w[3];
    for (int k = 0; k < 3; k++) {
        u[k] = b[k] / sc - a[k] / sc;
        w[k] = d[k] / sc - a[k] / sc;
    }
    vec3_cross(u, w, n);
}

/* The largest coordinate magnitude of m (1 when 0 or not finite): the unit of
 * scaled_cross. */
static double mesh_scale(const frep_mesh *m)
{
    double sc = 0;
    for (size_t i = 0; i < 3 * m->nverts; i++) sc = fmax(sc, fabs(m->v[i]));
    return sc > 0 && isfinite(sc) ? sc : 1;
}

/* cum[t]: the area of m's triangles 0..t; returns the total. Meshes whose areas
 * overflow (coordinates near 1e300) are measured in units of *unit squared
 * (*unit = 1 otherwise): draw_point only needs the proportions. */
static double triangle_areas(const frep_mesh *m, double *cum, double *unit)
{
    double total = 0;
    *unit = 1;
    for (size_t t = 0; t < m->ntris; t++) {
        const double *a = &m->v[3 * m->tri[3 * t]], *b = &m->v[3 * m->tri[3 * t + 1]],
                     *d = &m->v[3 * m->tri[3 * t + 2]];
        double u[3], w[3], n[3];
        vec3_sub(b, a, u);
        vec3_sub(d, a, w);
        vec3_cross(u, w, n);
        total += 0.5 * vec3_len(n);
        cum[t] = total;
    }
    if (isfinite(total)) return total;
    *unit = mesh_scale(m);
    total = 0;
    for (size_t t = 0; t < m->ntris; t++) {
        double n[3];
        scaled_cross(&m->v[3 * m->tri[3 * t]], &m->v[3 * m->tri[3 * t + 1]],
                     &m->v[3 * m->tri[3 * t + 2]], *unit, n);
        total += 0.5 * vec3_len(n);
        cum[t] = total;
    }
    return total;
}

/* One point uniform on m's surface (cum and total from triangle_areas) with its
 * triangle's unit normal (by vertex order); returns the triangle. */
static size_t draw_point(const frep_mesh *m, const double *cum, double total, frep_rng *r,
                         double p[3], double nrm[3])
{
    double u = frep_rng_unit(r) * total;
    size_t lo = 0, hi = m->ntris - 1;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (cum[mid] <= u) lo = mid + 1;
        else hi = mid;
    }
    double s = frep_rng_unit(r), t = frep_rng_unit(r);
    if (s + t > 1) {
        s = 1 - s;
        t = 1 - t;
    }
    const double *a = &m->v[3 * m->tri[3 * lo]], *b = &m->v[3 * m->tri[3 * lo + 1]],
                 *d = &m->v[3 * m->tri[3 * lo + 2]];
    for (int k = 0; k < 3; k++) {
        p[k] = a[k] + s * (b[k] - a[k]) + t * (d[k] - a[k]);
        /* the edges overflow near the largest double; the convex combination cannot */
        if (!isfinite(p[k])) p[k] = (1 - s - t) * a[k] + s * b[k] + t * d[k];
    }
    double u3[3], w3[3];
    vec3_sub(b, a, u3);
    vec3_sub(d, a, w3);
    vec3_cross(u3, w3, nrm);
    double l = vec3_len(nrm);
    if (!isfinite(l) || (l == 0 && !(vec3_len(u3) == 0 || vec3_len(w3) == 0))) {
        /* overflow, or underflow of a tiny triangle: the same product, scaled */
        double sc = fmax(fmax(fabs(a[0]), fabs(a[1])), fabs(a[2]));
        for (int k = 0; k < 3; k++) sc = fmax(sc, fmax(fabs(b[k]), fabs(d[k])));
        if (sc > 0) scaled_cross(a, b, d, sc, nrm);
        l = vec3_len(nrm);
    }
    for (int k = 0; k < 3; k++) nrm[k] = l > 0 ? nrm[k] / l : 0;
    return lo;
}

/* Draw n points on m's triangles, area-weighted, into c. */
static int draw_on_mesh(const frep_mesh *m, frep_rng *r, size_t n, frep_cloud *c,
                        volatile sig_atomic_t *cancel, frep_error *e)
{
    double *cum = frep_malloc((m->ntris + 1) * sizeof *cum);
    if (!cum) return frep_error_nomem(e);
    double unit;
    double total = triangle_areas(m, cum, &unit);
    int rc = 0;
    if (!(total > 0)) rc = frep_error_set(e, FREP_EINPUT, "the mesh has zero area");
    for (size_t i = 0; i < n && rc == 0; i++) {
        if ((i & SAMPLE_POLL_MASK) == 0 && frep_cancelled(cancel))
            rc = frep_error_set(e, FREP_ECANCEL, "interrupted");
        double p[3], nrm[3];
        draw_point(m, cum, total, r, p, nrm);
        if (cloud_push(c, p, nrm) != 0) rc = frep_error_nomem(e);
    }
    frep_free(cum);
    return rc;
}

/* Noise and outliers, drawn after the surface points so that the surface points of
 * a cloud do not change when only these options do. */
static void perturb(const sample_options *o, const double box[6], frep_rng *r, frep_cloud *c,
                    size_t nsurf)
{
    double dx = box[3] - box[0], dy = box[4] - box[1], dz = box[5] - box[2];
    double diag = sqrt(dx * dx + dy * dy + dz * dz);
    if (!isfinite(diag)) {  /* a box near the largest double: the same length, scaled */
        double sc = fmax(fmax(fabs(dx), fabs(dy)), fabs(dz));
        if (isfinite(sc)) diag = sc * sqrt(pow(dx / sc, 2) + pow(dy / sc, 2) + pow(dz / sc, 2));
    }
    double sigma = o->noise_absolute ? o->noise : o->noise * diag;
    if (sigma > 0)
        for (size_t i = 0; i < nsurf; i++) {
            c->x[i] += sigma * frep_rng_normal(r);
            c->y[i] += sigma * frep_rng_normal(r);
            c->z[i] += sigma * frep_rng_normal(r);
        }
    for (size_t i = nsurf; i < c->n; i++) {
        for (int k = 0; k < 3; k++) {
            double u = frep_rng_unit(r), v = box[k] + (box[k + 3] - box[k]) * u;
            if (!isfinite(v)) v = (1 - u) * box[k] + u * box[k + 3];
            (k == 0 ? c->x : k == 1 ? c->y : c->z)[i] = v;
        }
        double nv[3] = { frep_rng_normal(r), frep_rng_normal(r), frep_rng_normal(r) };
        double l = vec3_len(nv);
        c->nx[i] = l > 0 ? nv[0] / l : 1;
        c->ny[i] = l > 0 ? nv[1] / l : 0;
        c->nz[i] = l > 0 ? nv[2] / l : 0;
    }
}

/* No non-finite number leaves the sampler: noise near the largest double (--noise
 * 1e308) would move points to infinity, which no reader accepts. */
static int finite_cloud(const sample_options *o, const frep_cloud *c, frep_error *e)
{
    for (size_t i = 0; i < c->n; i++)
        if (!isfinite(c->x[i]) || !isfinite(c->y[i]) || !isfinite(c->z[i]) ||
            !isfinite(c->nx[i]) || !isfinite(c->ny[i]) || !isfinite(c->nz[i]))
            return frep_error_set(e, FREP_EINPUT, "point %zu would not be finite (noise %g%s): "
                                  "use a smaller --noise", i + 1, o->noise,
                                  o->noise_absolute ? "" : " x the box diagonal");
    return 0;
}

/* The outliers' slots after the nsurf surface points of c, then noise and outliers
 * (perturb) over box. */
static int add_outliers(const sample_options *o, const double box[6], frep_rng *r,
                        frep_cloud *c, size_t nsurf, frep_error *e)
{
    for (size_t i = nsurf; i < o->n; i++) {
        double zero[3] = { 0, 0, 0 };
        if (cloud_push(c, zero, zero)) return frep_error_nomem(e);
    }
    perturb(o, box, r, c, nsurf);
    return finite_cloud(o, c, e);
}

static int check_opts(const sample_options *o, frep_error *e)
{
    if (o->n < 1 || o->n > SAMPLE_MAX_POINTS)
        return frep_error_set(e, FREP_EINPUT, "the number of points must be 1..%zu",
                              (size_t)SAMPLE_MAX_POINTS);
    if (!(o->noise >= 0) || !isfinite(o->noise))
        return frep_error_set(e, FREP_EINPUT, "the noise must be a finite number >= 0");
    if (!(o->outliers >= 0 && o->outliers <= 1))
        return frep_error_set(e, FREP_EINPUT, "the outlier fraction must be in [0, 1]");
    return 0;
}

static size_t n_outliers(const sample_options *o)
{
    return (size_t)floor(o->outliers * (double)o->n + 0.5);
}

/* A new cloud with normals and room for o->n points, or NULL when out of memory. */
static frep_cloud *new_cloud(const sample_options *o)
{
    frep_cloud *c = cloud_new(1);
    if (c && cloud_reserve(c, o->n) != 0) {
        cloud_free(c);
        c = NULL;
    }
    return c;
}

/* The bounding box of m's vertices. */
static void mesh_bounds(const frep_mesh *m, double box[6])
{
    for (int k = 0; k < 3; k++) {
        box[k] = INFINITY;
        box[k + 3] = -INFINITY;
    }
    for (size_t i = 0; i < m->nverts; i++)
        for (int k = 0; k < 3; k++) {
            box[k] = fmin(box[k], m->v[3 * i + k]);
            box[k + 3] = fmax(box[k + 3], m->v[3 * i + k]);
        }
}

int sample_mesh(const frep_mesh *m, const sample_options *o, frep_cloud **out, frep_error *e)
{
    *out = NULL;
    if (check_opts(o, e)) return -1;
    size_t nsurf = o->n - n_outliers(o);
    frep_cloud *c = new_cloud(o);
    if (!c) return frep_error_nomem(e);
    frep_rng r;
    frep_rng_seed(&r, o->seed);
    double box[6];
    mesh_bounds(m, box);
    if (draw_on_mesh(m, &r, nsurf, c, o->mesh.interrupt, e) != 0 || add_outliers(o, box, &r, c, nsurf, e) != 0) {
        cloud_free(c);
        return -1;
    }
    *out = c;
    return 0;
}

/* ---- projection onto the zero set ------------------------------------------------- */

/* One thread's projection: its field state and a batch of points with their values
 * and gradients. */
typedef struct proj {
    const mesh_field *f;
    void *ts;
    frep_cloud *c;
    double iso, cell;         /* the level; the longest step (a cell of the grid) */
    double *x, *y, *z, *fv, *gx, *gy, *gz;   /* SAMPLE_BATCH each */
} proj;

/* Point i of the batch starting at cloud point i0, at the last step: onto the cloud
 * with the outward normal -grad f / |grad f|, where that is defined. */
static void proj_store(proj *P, size_t i0, size_t i)
{
    double g2 = P->gx[i] * P->gx[i] + P->gy[i] * P->gy[i] + P->gz[i] * P->gz[i];
    double l = sqrt(g2);
    if (!(l > 0 && isfinite(l) && isfinite(P->fv[i]))) return;
    frep_cloud *c = P->c;
    c->x[i0 + i] = P->x[i];
    c->y[i0 + i] = P->y[i];
    c->z[i0 + i] = P->z[i];
    c->nx[i0 + i] = -P->gx[i] / l;
    c->ny[i0 + i] = -P->gy[i] / l;
    c->nz[i0 + i] = -P->gz[i] / l;
}

/* One Newton step of point i: p -= (f - iso) grad / |grad|^2, refused when longer than
 * a cell or ending more than a cell from the start (a bad gradient). */
static void proj_step(proj *P, size_t i0, size_t i)
{
    double g2 = P->gx[i] * P->gx[i] + P->gy[i] * P->gy[i] + P->gz[i] * P->gz[i];
    if (!(g2 > 0) || !isfinite(g2) || !isfinite(P->fv[i])) return;
    double s = (P->fv[i] - P->iso) / g2;
    double dx = s * P->gx[i], dy = s * P->gy[i], dz = s * P->gz[i];
    double len = sqrt(dx * dx + dy * dy + dz * dz);
    if (len > P->cell) return;
    double nxp = P->x[i] - dx, nyp = P->y[i] - dy, nzp = P->z[i] - dz;
    const frep_cloud *c = P->c;
    double ox = c->x[i0 + i] - nxp, oy = c->y[i0 + i] - nyp, oz = c->z[i0 + i] - nzp;
    if (ox * ox + oy * oy + oz * oz > P->cell * P->cell) return;
    P->x[i] = nxp;
    P->y[i] = nyp;
    P->z[i] = nzp;
}

/* Project the n cloud points from i0 by SAMPLE_NEWTON_STEPS steps. 0, or -1 when the
 * field failed. */
static int proj_batch(proj *P, size_t i0, size_t n)
{
    memcpy(P->x, P->c->x + i0, n * sizeof *P->x);
    memcpy(P->y, P->c->y + i0, n * sizeof *P->y);
    memcpy(P->z, P->c->z + i0, n * sizeof *P->z);
    for (int step = 0; step <= SAMPLE_NEWTON_STEPS; step++) {
        if (P->f->grad(P->f->ctx, P->ts, n, P->x, P->y, P->z, P->fv, P->gx, P->gy, P->gz) != 0)
            return -1;
        for (size_t i = 0; i < n; i++) {
            if (step == SAMPLE_NEWTON_STEPS) proj_store(P, i0, i);
            else proj_step(P, i0, i);
        }
    }
    return 0;
}

/* The batches of project(), shared by its threads: P[t] is thread t's. */
typedef struct proj_job {
    proj *P;
    const mesh_options *mo;
    size_t nsurf;
    _Atomic int bad;
} proj_job;

static void proj_chunk(void *ctx, int t, long b0, long b1)
{
    proj_job *J = ctx;
    for (long b = b0; b < b1; b++) {
        if (frep_cancelled(J->mo->interrupt)) continue;
        size_t i0 = (size_t)b * SAMPLE_BATCH;
        size_t n = J->nsurf - i0 < SAMPLE_BATCH ? J->nsurf - i0 : SAMPLE_BATCH;
        if (proj_batch(&J->P[t], i0, n) != 0) atomic_store(&J->bad, 1);
    }
}

/* A point's value and gradient cost this many values (the tangent evaluator carries
 * three partials with the value): sizes the projection's threads. */
#define SAMPLE_GRAD_POINTS 4
/* Batches handed to a thread at a time. */
#define SAMPLE_CHUNK 4

/* Move the first nsurf points of c onto f = iso, in parallel batches; their normals
 * from the gradient. */
static int project(const mesh_field *f, const mesh_options *mo, frep_cloud *c, size_t nsurf,
                   frep_error *e)
{
    double cell = 0;
    for (int k = 0; k < 3; k++)
        cell = fmax(cell, (mo->box[k + 3] - mo->box[k]) / mesh_options_cells(mo, k));
    long nb = (long)((nsurf + SAMPLE_BATCH - 1) / SAMPLE_BATCH);
    double cost = f->cost > 0 ? f->cost : MESH_FIELD_COST;
    double work = (double)nsurf * (SAMPLE_NEWTON_STEPS + 1) * SAMPLE_GRAD_POINTS * cost;
    int nt = frep_threads_for(mo->nthreads, work, (size_t)(nb + SAMPLE_CHUNK - 1) / SAMPLE_CHUNK);
    proj *P = frep_calloc((size_t)nt, sizeof *P);
    double *buf = frep_malloc((size_t)nt * 7 * SAMPLE_BATCH * sizeof *buf);
    int nomem = !P || !buf;
    for (int t = 0; t < nt && !nomem; t++) {
        double *b = buf + (size_t)t * 7 * SAMPLE_BATCH;
        P[t] = (proj){ f, f->thread_new(f->ctx), c, mo->iso, cell, b, b + SAMPLE_BATCH,
                       b + 2 * SAMPLE_BATCH, b + 3 * SAMPLE_BATCH, b + 4 * SAMPLE_BATCH,
                       b + 5 * SAMPLE_BATCH, b + 6 * SAMPLE_BATCH };
        if (!P[t].ts) nomem = 1;
    }
    proj_job J = { P, mo, nsurf, 0 };
    if (!nomem) frep_par_for(nt, nb, SAMPLE_CHUNK, proj_chunk, &J);
    /* thread_free may merge per-thread state (runtime errors) into ctx: one at a time */
    if (P)
        for (int t = 0; t < nt; t++)
            if (P[t].ts) f->thread_free(f->ctx, P[t].ts);
    frep_free(buf);
    frep_free(P);
    if (frep_cancelled(mo->interrupt)) return frep_error_set(e, FREP_ECANCEL, "interrupted");
    if (nomem || atomic_load(&J.bad))
        return frep_error_set(e, nomem ? FREP_ENOMEM : FREP_EINPUT,
                              "out of memory or evaluation failure while sampling");
    return 0;
}

/* The polygonizer's options for sampling: the grid follows the point count unless
 * set. */
static mesh_options sample_mesh_options(const sample_options *o)
{
    mesh_options mo = o->mesh;
    /* the points are projected onto the surface: the mesh's vertices need not be */
    mo.no_projection = 1;
    if (mo.grid <= 0) {
        double g = sqrt((double)o->n / SAMPLE_POINTS_PER_GRID2);
        mo.grid = g < SAMPLE_GRID_MIN ? SAMPLE_GRID_MIN : (g > SAMPLE_GRID_MAX ? SAMPLE_GRID_MAX : (int)g);
    }
    return mo;
}

/* The polygonized surface to sample: not empty, not the whole box. */
static int surface_mesh(const mesh_field *f, const mesh_options *mo, frep_mesh *m,
                        frep_error *e)
{
    mesh_stats st;
    if (mesh_polygonize(f, mo, m, &st, e) != 0) return -1;
    if (m->ntris > 0 && !st.full) return 0;
    mesh_free(m);
    return frep_error_set(e, FREP_EINPUT, st.full
                                              ? "the model fills the whole box: no surface to sample"
                                              : "the model is empty in the box: no surface to sample");
}

int sample_field(const mesh_field *f, const sample_options *o, frep_cloud **out, frep_error *e)
{
    *out = NULL;
    if (check_opts(o, e)) return -1;
    mesh_options mo = sample_mesh_options(o);
    frep_mesh m;
    if (surface_mesh(f, &mo, &m, e) != 0) return -1;
    size_t nsurf = o->n - n_outliers(o);
    frep_cloud *c = new_cloud(o);
    frep_rng r;
    frep_rng_seed(&r, o->seed);
    int rc = c ? draw_on_mesh(&m, &r, nsurf, c, o->mesh.interrupt, e) : frep_error_nomem(e);
    mesh_free(&m);
    if (rc == 0) rc = project(f, &mo, c, nsurf, e);
    if (rc == 0) rc = add_outliers(o, mo.box, &r, c, nsurf, e);
    if (rc != 0) {
        cloud_free(c);
        return -1;
    }
    *out = c;
    return 0;
}

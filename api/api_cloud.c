/* api_cloud.c - point clouds in the public API: frep_cloud is geom/cloud.h's cloud,
 * read, made and written by geom/cloud.c.
 */
#include "config.h"

#include "api.h"
#include "cloud.h"

#include <string.h>

frep_cloud *frep_cloud_read(const char *path, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    frep_cloud *c = cloud_read(path, &e);
    if (!c) api_fail(&d, &e);
    return c;
}

frep_cloud *frep_cloud_new(size_t n, const double *x, const double *y, const double *z,
                           const double *nx, const double *ny, const double *nz,
                           frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    int normals = nx != NULL;
    if ((n && (!x || !y || !z)) || (normals && (!ny || !nz)) || (!normals && (ny || nz))) {
        frep_error_set(&e, FREP_EINPUT, "frep_cloud_new: x, y, z and all or none of nx, ny, nz");
        api_fail(&d, &e);
        return NULL;
    }
    if (n > CLOUD_MAX_POINTS) {
        frep_error_set(&e, FREP_ELIMIT, "frep_cloud_new: %zu points, more than %zu", n,
                       (size_t)CLOUD_MAX_POINTS);
        api_fail(&d, &e);
        return NULL;
    }
    frep_cloud *c = cloud_new(normals);
    if (!c || cloud_reserve(c, n) != 0) {
        cloud_free(c);
        api_fail(&d, &e);
        return NULL;
    }
    if (n) {
        memcpy(c->x, x, n * sizeof *x);
        memcpy(c->y, y, n * sizeof *y);
        memcpy(c->z, z, n * sizeof *z);
        if (normals) {
            memcpy(c->nx, nx, n * sizeof *nx);
            memcpy(c->ny, ny, n * sizeof *ny);
            memcpy(c->nz, nz, n * sizeof *nz);
        }
    }
    c->n = n;
    return c;
}

void frep_cloud_free(frep_cloud *c)
{
    cloud_free(c);
}

size_t frep_cloud_size(const frep_cloud *c)
{
    return c->n;
}

int frep_cloud_has_normals(const frep_cloud *c)
{
    return c->has_normals != 0;
}

void frep_cloud_arrays(const frep_cloud *c, const double **x, const double **y,
                       const double **z, const double **nx, const double **ny,
                       const double **nz)
{
    int h = c->has_normals != 0;
    if (x) *x = c->x;
    if (y) *y = c->y;
    if (z) *z = c->z;
    if (nx) *nx = h ? c->nx : NULL;
    if (ny) *ny = h ? c->ny : NULL;
    if (nz) *nz = h ? c->nz : NULL;
}

typedef struct cloud_out {
    const frep_cloud *c;
    const char *path;
} cloud_out;

static int write_cloud(FILE *f, void *ctx)
{
    const cloud_out *o = ctx;
    return cloud_write_for_path(f, o->c, o->path);
}

int frep_cloud_write(const frep_cloud *c, const char *path, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    cloud_out o = { c, path };
    return api_write_atomic(&d, path, write_cloud, &o);
}

int frep_cloud_write_stream(const frep_cloud *c, FILE *f, const char *name)
{
    return cloud_write_for_path(f, c, name ? name : "");
}

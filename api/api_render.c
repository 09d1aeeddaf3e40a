/* api_render.c - pictures in the public API: mesh/render.c's rasterizer over a mesh,
 * with a cloud drawn over it coloured by its distance to the surface and the surface
 * by its distance to the cloud (view/distance.c), encoded by mesh/png.c.
 */
#include "config.h"

#include "api.h"
#include "cloud.h"
#include "distance.h"
#include "png.h"
#include "render.h"
#include "trimesh.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "alloc.h"

_Static_assert(FREP_RENDER_MAX_SIDE == PNG_MAX_SIDE, "the PNG writer's limit");
_Static_assert(sizeof FREP_RENDER_VIEWS == sizeof RENDER_VIEWS, "the rasterizer's views");

/* Colour scale when no distance is finite and positive: as a fraction of the framed
 * box diagonal. */
#define RENDER_FALLBACK_FRACTION 0.02

struct frep_image {
    int width, height;
    uint8_t *rgb;
};

int frep_render_view_ok(const char *view)
{
    return view && render_view_ok(view);
}

void frep_render_options_init(frep_render_options *o)
{
    memset(o, 0, sizeof *o);
    o->width = 800;
    o->height = 600;
    o->view = "iso";
}

/* The points' distances to the surface and the surface's to the points, their
 * scales, the counts of the summary; the framed box grown to hold the points. */
typedef struct overlay {
    double *pdist, *vdist;
    double pscale, vscale;
    char note[96];
} overlay;

static int measure(const api_diag *d, const frep_mesh *m, const frep_render_options *o,
                   double bbox[6], overlay *ov, frep_render_info *in)
{
    const frep_cloud *cl = o->points;
    frep_distances dist;
    if (frep_cloud_distances(cl, m, o->program, o->iso, o->nthreads, &dist, d->fn, d->user) != 0)
        return -1;
    ov->pdist = dist.point;
    ov->vdist = dist.vertex;
    ov->pscale = dist.point_scale;
    ov->vscale = dist.vertex_scale;
    for (size_t i = 0; i < cl->n; i++) {
        double a = fabs(ov->pdist[i]);
        if (isfinite(a)) {
            in->mean_dist += a / (double)cl->n;
            in->max_dist = fmax(in->max_dist, a);
        }
        in->inside += ov->pdist[i] > 0;
        bbox[0] = fmin(bbox[0], cl->x[i]);
        bbox[3] = fmax(bbox[3], cl->x[i]);
        bbox[1] = fmin(bbox[1], cl->y[i]);
        bbox[4] = fmax(bbox[4], cl->y[i]);
        bbox[2] = fmin(bbox[2], cl->z[i]);
        bbox[5] = fmax(bbox[5], cl->z[i]);
    }
    double diag = sqrt((bbox[3] - bbox[0]) * (bbox[3] - bbox[0]) +
                       (bbox[4] - bbox[1]) * (bbox[4] - bbox[1]) +
                       (bbox[5] - bbox[2]) * (bbox[5] - bbox[2]));
    if (!(ov->pscale > 0)) ov->pscale = RENDER_FALLBACK_FRACTION * diag;
    if (!(ov->vscale > 0)) ov->vscale = RENDER_FALLBACK_FRACTION * diag;
    if (o->scale > 0) ov->pscale = o->scale;
    for (size_t i = 0; i < cl->n; i++) in->rings += ov->pdist[i] > RENDER_POINT_DEPTH_SLACK * diag;
    snprintf(ov->note, sizeof ov->note, "%zu of %zu points inside the solid, %zu as rings",
             in->inside, cl->n, in->rings);
    in->npoints = cl->n;
    in->point_scale = ov->pscale;
    in->surface_scale = o->plain ? 0 : ov->vscale;
    return 0;
}

/* mesh box -> [points: distances, scales, box] -> raster */
frep_image *frep_render(const frep_mesh *m, const frep_render_options *o,
                        frep_render_info *info, frep_diag_fn diag, void *user)
{
    api_diag d = { diag, user };
    frep_error e;
    frep_error_init(&e);
    frep_render_options def;
    if (!o) {
        frep_render_options_init(&def);
        o = &def;
    }
    frep_render_info in;
    memset(&in, 0, sizeof in);
    if (o->width < 1 || o->height < 1 || o->width > FREP_RENDER_MAX_SIDE ||
        o->height > FREP_RENDER_MAX_SIDE) {
        frep_error_set(&e, FREP_EINPUT, "picture size %dx%d: each side must be 1..%d",
                       o->width, o->height, FREP_RENDER_MAX_SIDE);
        api_fail(&d, &e);
        return NULL;
    }
    const char *view = o->view ? o->view : "iso";
    if (!render_view_ok(view)) {
        frep_error_set(&e, FREP_EINPUT, "unknown view '%s'; expected one of %s", view,
                       RENDER_VIEWS);
        api_fail(&d, &e);
        return NULL;
    }
    double bbox[6];
    for (int k = 0; k < 3; k++) {
        bbox[k] = INFINITY;
        bbox[k + 3] = -INFINITY;
    }
    for (size_t i = 0; i < m->nverts; i++)
        for (int k = 0; k < 3; k++) {
            bbox[k] = fmin(bbox[k], m->v[3 * i + k]);
            bbox[k + 3] = fmax(bbox[k + 3], m->v[3 * i + k]);
        }
    overlay ov;
    memset(&ov, 0, sizeof ov);
    frep_image *img = frep_calloc(1, sizeof *img);
    int rc = img ? 0 : api_fail(&d, &e);
    if (rc == 0 && o->points) rc = measure(&d, m, o, bbox, &ov, &in);
    if (rc == 0) {
        img->width = o->width;
        img->height = o->height;
        img->rgb = frep_malloc(3 * (size_t)o->width * (size_t)o->height);
        if (!img->rgb) {
            frep_error_set(&e, FREP_ENOMEM, "out of memory for a %dx%d picture", o->width,
                           o->height);
            rc = api_fail(&d, &e);
        }
    }
    if (rc == 0) {
        render_options ro = { .width = o->width, .height = o->height, .view = view,
                              .vertex_rgb = o->vertex_rgb };
        memcpy(ro.bbox, bbox, sizeof bbox);
        render_points rp;
        if (o->points) {
            const frep_cloud *cl = o->points;
            rp = (render_points){ cl->n, cl->x, cl->y, cl->z, ov.pdist, ov.pscale, 1 };
            ro.legends[ro.nlegends++] = (render_legend){ "points: distance to the surface",
                                                         ov.pscale, "model units", ov.note };
            if (!o->plain) {
                ro.vertex_value = ov.vdist;
                ro.vertex_vmax = ov.vscale;
                ro.legends[ro.nlegends++] = (render_legend){
                    "surface: distance to the nearest point", ov.vscale, "model units", NULL };
            }
        }
        if (render_mesh(m, o->points ? &rp : NULL, &ro, img->rgb, &e) != 0) rc = api_fail(&d, &e);
    }
    frep_free(ov.pdist);
    frep_free(ov.vdist);
    if (rc != 0) {
        frep_image_free(img);
        return NULL;
    }
    in.ntris = m->ntris;
    if (info) *info = in;
    return img;
}

void frep_image_free(frep_image *img)
{
    if (!img) return;
    frep_free(img->rgb);
    frep_free(img);
}

const uint8_t *frep_image_pixels(const frep_image *img, int *width, int *height)
{
    if (width) *width = img->width;
    if (height) *height = img->height;
    return img->rgb;
}

typedef struct png_ctx {
    const frep_image *img;
} png_ctx;

int frep_image_write_png_stream(const frep_image *img, FILE *f)
{
    return png_write_rgb(f, img->rgb, img->width, img->height);
}

static int write_png(FILE *f, void *ctx)
{
    return frep_image_write_png_stream(((const png_ctx *)ctx)->img, f);
}

int frep_image_write_png(const frep_image *img, const char *path, frep_diag_fn diag,
                         void *user)
{
    api_diag d = { diag, user };
    png_ctx c = { img };
    return api_write_atomic(&d, path, write_png, &c);
}

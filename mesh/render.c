/* render.c - z-buffer rasterization of a triangle mesh with Phong shading (render.h).
 *
 * Orthographic camera looking at the centre of the framed box from a named direction;
 * two-sided lighting (a key light over the viewer's shoulder plus ambient), normals
 * interpolated from the mesh's vertex normals (the face normal where a vertex normal
 * disagrees with it by more than 30 degrees, and where the mesh has none).  Cloud
 * points are drawn as small depth-tested discs on top, coloured blue (on the surface)
 * to red (far from it).
 */
#include "config.h"

#include "alloc.h"
#include "render.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Disc radius of an overlay point, in pixels per 1000 pixels of image height. */
#define RENDER_POINT_RADIUS 2.5
/* A vertex normal deviating from the triangle's own normal by more than this angle
 * (cosine of 30 degrees) is not used for that triangle: gradient normals at R-function
 * creases and at vertices snapped onto sharp edges belong to the other side of the
 * edge, and interpolating them makes edges look jagged; the face normal keeps them
 * crisp while smooth surfaces keep their smooth shading. */
#define RENDER_CREASE_COS 0.866
/* Depth slack for overlay points, as a fraction of the framed box's diagonal: points on
 * the surface must not be hidden by it. */
#define RENDER_POINT_DEPTH_SLACK 0.01

typedef struct view_def {
    const char *name;
    double from[3], up[3];
} view_def;

static const view_def views[] = {
    { "iso", { 1, -1, 0.8 }, { 0, 0, 1 } },
    { "front", { 0, -1, 0 }, { 0, 0, 1 } },
    { "back", { 0, 1, 0 }, { 0, 0, 1 } },
    { "top", { 0, 0, 1 }, { 0, 1, 0 } },
    { "bottom", { 0, 0, -1 }, { 0, -1, 0 } },
    { "right", { 1, 0, 0 }, { 0, 0, 1 } },
    { "side", { 1, 0, 0 }, { 0, 0, 1 } },
    { "left", { -1, 0, 0 }, { 0, 0, 1 } },
};

static const view_def *find_view(const char *name)
{
    for (size_t i = 0; i < sizeof views / sizeof views[0]; i++)
        if (strcmp(views[i].name, name) == 0) return &views[i];
    return NULL;
}

int render_view_ok(const char *view) { return find_view(view) != NULL; }

static void normalize(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (l > 0)
        for (int i = 0; i < 3; i++) v[i] /= l;
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

typedef struct camera {
    double right[3], up[3], fwd[3], centre[3];
    double scale;   /* pixels per model unit */
    int w, h;
} camera;

/* Model point -> pixel coordinates (sx, sy) and depth (larger is farther). */
static void project(const camera *c, const double p[3], double *sx, double *sy, double *d)
{
    double q[3] = { p[0] - c->centre[0], p[1] - c->centre[1], p[2] - c->centre[2] };
    *sx = 0.5 * c->w + c->scale * dot(q, c->right);
    *sy = 0.5 * c->h - c->scale * dot(q, c->up);
    *d = dot(q, c->fwd);
}

static uint8_t to_byte(double v)
{
    v = v < 0 ? 0 : (v > 1 ? 1 : v);
    return (uint8_t)(255.0 * v + 0.5);
}

int render_mesh(const frep_mesh *m, const render_points *pts, const render_options *o,
                uint8_t *rgb)
{
    const view_def *vd = find_view(o->view ? o->view : "iso");
    if (!vd || o->width < 1 || o->height < 1) return -1;
    int W = o->width, H = o->height;
    size_t npix = (size_t)W * (size_t)H;
    double *zbuf = frep_malloc(npix * sizeof *zbuf);
    if (!zbuf) return -1;
    for (size_t i = 0; i < npix; i++) zbuf[i] = INFINITY;
    /* background: a light vertical gradient */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double t = (double)y / H;
            uint8_t *px = &rgb[3 * ((size_t)y * W + x)];
            px[0] = to_byte(0.93 - 0.12 * t);
            px[1] = to_byte(0.94 - 0.12 * t);
            px[2] = to_byte(0.97 - 0.10 * t);
        }

    camera cam;
    cam.w = W;
    cam.h = H;
    double back[3] = { vd->from[0], vd->from[1], vd->from[2] };
    normalize(back);
    for (int i = 0; i < 3; i++) cam.fwd[i] = -back[i];
    double upv[3] = { vd->up[0], vd->up[1], vd->up[2] };
    cross(cam.fwd, upv, cam.right);
    normalize(cam.right);
    cross(cam.right, cam.fwd, cam.up);
    normalize(cam.up);
    for (int i = 0; i < 3; i++) cam.centre[i] = 0.5 * (o->bbox[i] + o->bbox[i + 3]);
    /* fit the projected box corners into 90% of the image */
    double ex = 0, ey = 0;
    for (int k = 0; k < 8; k++) {
        double p[3] = { o->bbox[(k & 1) ? 3 : 0] - cam.centre[0],
                        o->bbox[(k & 2) ? 4 : 1] - cam.centre[1],
                        o->bbox[(k & 4) ? 5 : 2] - cam.centre[2] };
        ex = fmax(ex, fabs(dot(p, cam.right)));
        ey = fmax(ey, fabs(dot(p, cam.up)));
    }
    cam.scale = 0.45 * fmin(W / fmax(ex, 1e-300), H / fmax(ey, 1e-300));
    double diag = sqrt((o->bbox[3] - o->bbox[0]) * (o->bbox[3] - o->bbox[0]) +
                       (o->bbox[4] - o->bbox[1]) * (o->bbox[4] - o->bbox[1]) +
                       (o->bbox[5] - o->bbox[2]) * (o->bbox[5] - o->bbox[2]));

    /* light: from the viewer, up and to the left */
    double light[3];
    for (int i = 0; i < 3; i++) light[i] = back[i] + 0.5 * cam.up[i] - 0.4 * cam.right[i];
    normalize(light);
    double half[3];
    for (int i = 0; i < 3; i++) half[i] = light[i] + back[i];
    normalize(half);

    for (size_t t = 0; t < m->ntris; t++) {
        double sx[3], sy[3], sd[3];
        const double *P[3], *N[3];
        double fn[3];
        for (int k = 0; k < 3; k++) P[k] = &m->v[3 * m->tri[3 * t + k]];
        double u[3], w[3];
        for (int i = 0; i < 3; i++) {
            u[i] = P[1][i] - P[0][i];
            w[i] = P[2][i] - P[0][i];
        }
        cross(u, w, fn);
        normalize(fn);
        for (int k = 0; k < 3; k++) {
            project(&cam, P[k], &sx[k], &sy[k], &sd[k]);
            N[k] = m->n ? &m->n[3 * m->tri[3 * t + k]] : fn;
            if (!(dot(N[k], fn) >= RENDER_CREASE_COS)) N[k] = fn;
        }
        double area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
        if (area == 0 || !isfinite(area)) continue;
        int x0 = (int)floor(fmin(sx[0], fmin(sx[1], sx[2]))), x1 = (int)ceil(fmax(sx[0], fmax(sx[1], sx[2])));
        int y0 = (int)floor(fmin(sy[0], fmin(sy[1], sy[2]))), y1 = (int)ceil(fmax(sy[0], fmax(sy[1], sy[2])));
        if (x0 < 0) x0 = 0;
        if (y0 < 0) y0 = 0;
        if (x1 > W - 1) x1 = W - 1;
        if (y1 > H - 1) y1 = H - 1;
        for (int y = y0; y <= y1; y++)
            for (int x = x0; x <= x1; x++) {
                double px = x + 0.5, py = y + 0.5;
                double b0 = ((sx[1] - px) * (sy[2] - py) - (sx[2] - px) * (sy[1] - py)) / area;
                double b1 = ((sx[2] - px) * (sy[0] - py) - (sx[0] - px) * (sy[2] - py)) / area;
                double b2 = 1 - b0 - b1;
                if (b0 < 0 || b1 < 0 || b2 < 0) continue;
                double d = b0 * sd[0] + b1 * sd[1] + b2 * sd[2];
                size_t pi = (size_t)y * W + x;
                if (d >= zbuf[pi]) continue;
                zbuf[pi] = d;
                double n[3];
                for (int i = 0; i < 3; i++) n[i] = b0 * N[0][i] + b1 * N[1][i] + b2 * N[2][i];
                normalize(n);
                /* seen from behind (inside a cut-open model): shade the back side */
                if (dot(n, back) < 0)
                    for (int i = 0; i < 3; i++) n[i] = -n[i];
                double diff = fmax(0, dot(n, light));
                double spec = pow(fmax(0, dot(n, half)), 40);
                double base[3] = { 0.62, 0.70, 0.82 };
                uint8_t *c = &rgb[3 * pi];
                for (int i = 0; i < 3; i++)
                    c[i] = to_byte(base[i] * (0.22 + 0.78 * diff) + 0.35 * spec);
            }
    }

    if (pts) {
        double r = RENDER_POINT_RADIUS * H / 1000.0;
        if (r < 1.2) r = 1.2;
        int ir = (int)ceil(r);
        double slack = RENDER_POINT_DEPTH_SLACK * diag;
        for (size_t i = 0; i < pts->n; i++) {
            double p[3] = { pts->x[i], pts->y[i], pts->z[i] }, sx, sy, d;
            project(&cam, p, &sx, &sy, &d);
            double t = pts->value && pts->vmax > 0 ? fabs(pts->value[i]) / pts->vmax : 0;
            if (!(t <= 1)) t = 1;
            /* blue -> green -> red */
            double col[3] = { t < 0.5 ? 0.1 : 2 * (t - 0.5) + 0.1 * (1 - t),
                              t < 0.5 ? 0.3 + 1.2 * t : 1.8 * (1 - t),
                              t < 0.5 ? 0.9 * (1 - 2 * t) + 0.1 : 0.05 };
            for (int dy = -ir; dy <= ir; dy++)
                for (int dx = -ir; dx <= ir; dx++) {
                    int x = (int)floor(sx) + dx, y = (int)floor(sy) + dy;
                    if (x < 0 || y < 0 || x >= W || y >= H) continue;
                    double ddx = x + 0.5 - sx, ddy = y + 0.5 - sy;
                    if (ddx * ddx + ddy * ddy > r * r) continue;
                    size_t pi = (size_t)y * W + x;
                    if (d > zbuf[pi] + slack) continue;
                    uint8_t *c = &rgb[3 * pi];
                    for (int k = 0; k < 3; k++) c[k] = to_byte(col[k]);
                }
        }
    }
    frep_free(zbuf);
    return 0;
}

/* render.c - z-buffer rasterization of a triangle mesh with Phong shading (render.h).
 *
 * Orthographic camera looking at the centre of the framed box from a named direction;
 * two-sided lighting (a key light over the viewer's shoulder plus ambient), normals
 * interpolated from the mesh's vertex normals (the face normal where a vertex normal
 * disagrees with it by more than 30 degrees, and where the mesh has none).  Cloud
 * points are drawn as small depth-tested discs on top, coloured blue (on the surface)
 * to red (far from it); points deep inside the solid as rings through it.  Legends
 * (mesh/font.c) go to the bottom-right corner.
 */
#include "config.h"

#include "alloc.h"
#include "font.h"
#include "render.h"
#include "vec3.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* Disc radius of an overlay point, in pixels per 1000 pixels of image height. */
#define RENDER_POINT_RADIUS 2.5
/* A vertex normal deviating from the triangle's own normal by more than this angle
 * (cosine of 30 degrees) is not used for that triangle: gradient normals at R-function
 * creases and at vertices snapped onto sharp edges belong to the other side of the
 * edge, and interpolating them makes edges look jagged; the face normal keeps them
 * crisp while smooth surfaces keep their smooth shading. */
#define RENDER_CREASE_COS 0.866
/* Smallest disc radius of an overlay point, in pixels: smaller discs vanish. */
#define RENDER_POINT_MIN_RADIUS 1.2
/* The framed box's projection fills this fraction of the image's half-size. */
#define RENDER_FILL 0.45
/* Phong shading: ambient and diffuse shares, specular weight and exponent. */
#define RENDER_AMBIENT 0.22
#define RENDER_DIFFUSE 0.78
#define RENDER_SPECULAR 0.35
#define RENDER_SHININESS 40

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

typedef struct camera {
    double right[3], up[3], fwd[3], centre[3];
    double scale;   /* pixels per model unit */
    int w, h;
} camera;

/* Model point -> pixel coordinates (sx, sy) and depth (larger is farther). */
static void project(const camera *c, const double p[3], double *sx, double *sy, double *d)
{
    double q[3] = { p[0] - c->centre[0], p[1] - c->centre[1], p[2] - c->centre[2] };
    *sx = 0.5 * c->w + c->scale * vec3_dot(q, c->right);
    *sy = 0.5 * c->h - c->scale * vec3_dot(q, c->up);
    *d = vec3_dot(q, c->fwd);
}

static uint8_t to_byte(double v)
{
    v = v < 0 ? 0 : (v > 1 ? 1 : v);
    return (uint8_t)(255.0 * v + 0.5);
}

/* A picture being drawn: camera, lights and the depth of each pixel. */
typedef struct raster {
    camera cam;
    double back[3];           /* towards the viewer */
    double light[3], half[3]; /* key light; half vector of light and view (specular) */
    double diag;              /* the framed box's diagonal */
    double *zbuf;             /* w * h depths, INFINITY: nothing drawn */
    uint8_t *rgb;
    const double *vval;       /* per-vertex colour values (NULL: the plain surface) */
    double vmax;
    const uint8_t *vrgb;      /* per-vertex colours (NULL: none; vval wins) */
} raster;

/* The empty picture: a light vertical gradient, nothing in depth. */
static void clear_picture(raster *R)
{
    int W = R->cam.w, H = R->cam.h;
    for (size_t i = 0; i < (size_t)W * (size_t)H; i++) R->zbuf[i] = INFINITY;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double t = (double)y / H;
            uint8_t *px = &R->rgb[3 * ((size_t)y * W + x)];
            px[0] = to_byte(0.93 - 0.12 * t);
            px[1] = to_byte(0.94 - 0.12 * t);
            px[2] = to_byte(0.97 - 0.10 * t);
        }
}

/* An orthographic camera looking at the centre of the framed box from view vd, the
 * projected box corners fitted into 90% of the image. */
static void camera_init(raster *R, const view_def *vd, const render_options *o)
{
    camera *cam = &R->cam;
    double *back = R->back;
    cam->w = o->width;
    cam->h = o->height;
    for (int i = 0; i < 3; i++) back[i] = vd->from[i];
    vec3_normalize(back);
    for (int i = 0; i < 3; i++) cam->fwd[i] = -back[i];
    double upv[3] = { vd->up[0], vd->up[1], vd->up[2] };
    vec3_cross(cam->fwd, upv, cam->right);
    vec3_normalize(cam->right);
    vec3_cross(cam->right, cam->fwd, cam->up);
    vec3_normalize(cam->up);
    for (int i = 0; i < 3; i++) cam->centre[i] = 0.5 * (o->bbox[i] + o->bbox[i + 3]);
    double ex = 0, ey = 0;
    for (int k = 0; k < 8; k++) {
        double p[3] = { o->bbox[(k & 1) ? 3 : 0] - cam->centre[0],
                        o->bbox[(k & 2) ? 4 : 1] - cam->centre[1],
                        o->bbox[(k & 4) ? 5 : 2] - cam->centre[2] };
        ex = fmax(ex, fabs(vec3_dot(p, cam->right)));
        ey = fmax(ey, fabs(vec3_dot(p, cam->up)));
    }
    cam->scale = RENDER_FILL * fmin(cam->w / fmax(ex, 1e-300), cam->h / fmax(ey, 1e-300));
    R->diag = sqrt((o->bbox[3] - o->bbox[0]) * (o->bbox[3] - o->bbox[0]) +
                   (o->bbox[4] - o->bbox[1]) * (o->bbox[4] - o->bbox[1]) +
                   (o->bbox[5] - o->bbox[2]) * (o->bbox[5] - o->bbox[2]));
}

/* The key light: from the viewer, up and to the left; and the half vector. */
static void lights_init(raster *R)
{
    for (int i = 0; i < 3; i++)
        R->light[i] = R->back[i] + 0.5 * R->cam.up[i] - 0.4 * R->cam.right[i];
    vec3_normalize(R->light);
    for (int i = 0; i < 3; i++) R->half[i] = R->light[i] + R->back[i];
    vec3_normalize(R->half);
}

/* One triangle in screen space: corners, depths, the normals to interpolate. */
typedef struct stri {
    double sx[3], sy[3], sd[3];
    const double *N[3];
    double val[3];            /* the corners' colour values (when R->vval) */
    double col[3][3];         /* the corners' colours (when R->vrgb) */
    double area;              /* twice the signed screen area */
} stri;

/* Pixel (x, y) of triangle T when it covers the pixel's centre in front of what is
 * there: depth, and the Phong shading of the interpolated normal (two-sided: seen
 * from behind, inside a cut-open model, the back side is shaded). */
static void shade_pixel(raster *R, const stri *T, int x, int y)
{
    double px = x + 0.5, py = y + 0.5;
    const double *sx = T->sx, *sy = T->sy;
    double b0 = ((sx[1] - px) * (sy[2] - py) - (sx[2] - px) * (sy[1] - py)) / T->area;
    double b1 = ((sx[2] - px) * (sy[0] - py) - (sx[0] - px) * (sy[2] - py)) / T->area;
    double b2 = 1 - b0 - b1;
    if (b0 < 0 || b1 < 0 || b2 < 0) return;
    double d = b0 * T->sd[0] + b1 * T->sd[1] + b2 * T->sd[2];
    size_t pi = (size_t)y * R->cam.w + x;
    if (d >= R->zbuf[pi]) return;
    R->zbuf[pi] = d;
    double n[3];
    for (int i = 0; i < 3; i++) n[i] = b0 * T->N[0][i] + b1 * T->N[1][i] + b2 * T->N[2][i];
    vec3_normalize(n);
    if (vec3_dot(n, R->back) < 0)
        for (int i = 0; i < 3; i++) n[i] = -n[i];
    double diff = fmax(0, vec3_dot(n, R->light));
    double spec = pow(fmax(0, vec3_dot(n, R->half)), RENDER_SHININESS);
    double base[3] = { 0.62, 0.70, 0.82 };
    if (R->vval) render_colour((b0 * T->val[0] + b1 * T->val[1] + b2 * T->val[2]) / R->vmax, base);
    else if (R->vrgb)
        for (int i = 0; i < 3; i++) base[i] = b0 * T->col[0][i] + b1 * T->col[1][i] + b2 * T->col[2][i];
    uint8_t *c = &R->rgb[3 * pi];
    for (int i = 0; i < 3; i++)
        c[i] = to_byte(base[i] * (RENDER_AMBIENT + RENDER_DIFFUSE * diff) + RENDER_SPECULAR * spec);
}

/* Triangle t of m, z-buffered: vertex normals where they agree with the face normal
 * within RENDER_CREASE_COS, the face normal elsewhere. */
static void draw_triangle(raster *R, const frep_mesh *m, size_t t)
{
    stri T;
    const double *P[3];
    double fn[3];
    for (int k = 0; k < 3; k++) P[k] = &m->v[3 * m->tri[3 * t + k]];
    double u[3], w[3];
    vec3_sub(P[1], P[0], u);
    vec3_sub(P[2], P[0], w);
    vec3_cross(u, w, fn);
    vec3_normalize(fn);
    for (int k = 0; k < 3; k++) {
        project(&R->cam, P[k], &T.sx[k], &T.sy[k], &T.sd[k]);
        T.N[k] = m->n ? &m->n[3 * m->tri[3 * t + k]] : fn;
        T.val[k] = R->vval ? R->vval[m->tri[3 * t + k]] : 0;
        for (int i = 0; i < 3; i++)
            T.col[k][i] = R->vrgb ? R->vrgb[3 * (size_t)m->tri[3 * t + k] + i] / 255.0 : 0;
        if (!(vec3_dot(T.N[k], fn) >= RENDER_CREASE_COS)) T.N[k] = fn;
    }
    const double *sx = T.sx, *sy = T.sy;
    T.area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
    if (T.area == 0 || !isfinite(T.area)) return;
    int x0 = (int)floor(fmin(sx[0], fmin(sx[1], sx[2]))), x1 = (int)ceil(fmax(sx[0], fmax(sx[1], sx[2])));
    int y0 = (int)floor(fmin(sy[0], fmin(sy[1], sy[2]))), y1 = (int)ceil(fmax(sy[0], fmax(sy[1], sy[2])));
    if (x0 < 0) x0 = 0;
    if (y0 < 0) y0 = 0;
    if (x1 > R->cam.w - 1) x1 = R->cam.w - 1;
    if (y1 > R->cam.h - 1) y1 = R->cam.h - 1;
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) shade_pixel(R, &T, x, y);
}

void render_colour(double t, double col[3])
{
    if (!(t >= 0)) t = t < 0 ? 0 : 1;
    if (t > 1) t = 1;
    col[0] = t < 0.5 ? 0.1 : 2 * (t - 0.5) + 0.1 * (1 - t);
    col[1] = t < 0.5 ? 0.3 + 1.2 * t : 1.8 * (1 - t);
    col[2] = t < 0.5 ? 0.9 * (1 - 2 * t) + 0.1 : 0.05;
}

/* Overlay point i as a disc of radius r pixels, depth-tested with slack; or, as a
 * ring (inner half left out, dark rim) drawn through the surface, when ring. */
static void draw_point(raster *R, const render_points *pts, size_t i, double r, double slack,
                       int ring)
{
    int W = R->cam.w, H = R->cam.h, ir = (int)ceil(r);
    double p[3] = { pts->x[i], pts->y[i], pts->z[i] }, sx, sy, d;
    project(&R->cam, p, &sx, &sy, &d);
    double t = pts->value && pts->vmax > 0 ? fabs(pts->value[i]) / pts->vmax : 0;
    if (!(t <= 1)) t = 1;
    double col[3];
    render_colour(t, col);
    for (int dy = -ir; dy <= ir; dy++)
        for (int dx = -ir; dx <= ir; dx++) {
            int x = (int)floor(sx) + dx, y = (int)floor(sy) + dy;
            if (x < 0 || y < 0 || x >= W || y >= H) continue;
            double ddx = x + 0.5 - sx, ddy = y + 0.5 - sy, q = ddx * ddx + ddy * ddy;
            if (q > r * r || (ring && q < 0.2 * r * r)) continue;
            size_t pi = (size_t)y * W + x;
            if (!ring && d > R->zbuf[pi] + slack) continue;
            uint8_t *c = &R->rgb[3 * pi];
            int rim = ring && q > 0.6 * r * r;
            for (int k = 0; k < 3; k++) c[k] = to_byte(rim ? 0 : col[k]);
        }
}

/* Is point i inside the solid by more than the depth slack? */
static int deep_inside(const render_points *pts, size_t i, double slack)
{
    return pts->value_signed && pts->value && pts->value[i] > slack;
}

/* The overlay: every point on top of the surface, coloured by its value; then the
 * points deep inside as larger rings over everything. */
static void draw_points(raster *R, const render_points *pts)
{
    double r = RENDER_POINT_RADIUS * R->cam.h / 1000.0;
    if (r < RENDER_POINT_MIN_RADIUS) r = RENDER_POINT_MIN_RADIUS;
    double slack = RENDER_POINT_DEPTH_SLACK * R->diag;
    for (size_t i = 0; i < pts->n; i++)
        if (!deep_inside(pts, i, slack)) draw_point(R, pts, i, r, slack, 0);
    for (size_t i = 0; i < pts->n; i++)
        if (deep_inside(pts, i, slack)) draw_point(R, pts, i, 1.6 * r + 1, slack, 1);
}

/* Legend layout, in font pixels (scaled with the picture): the colour bar's size, the
 * padding, the gap between lines. */
#define LEGEND_BAR_W 150
#define LEGEND_BAR_H 8
#define LEGEND_PAD 4
#define LEGEND_GAP 3
/* Ticks under the bar: 0, 1/2, the top of the scale. */
#define LEGEND_TICKS 3

/* A blend of the rectangle [x0, x1) x [y0, y1) towards white, clipped. */
static void veil(raster *R, int x0, int y0, int x1, int y1)
{
    for (int y = y0 < 0 ? 0 : y0; y < y1 && y < R->cam.h; y++)
        for (int x = x0 < 0 ? 0 : x0; x < x1 && x < R->cam.w; x++) {
            uint8_t *c = &R->rgb[3 * ((size_t)y * R->cam.w + x)];
            for (int k = 0; k < 3; k++) c[k] = (uint8_t)(c[k] / 8 + 255 * 7 / 8);
        }
}

/* One legend with its top-left corner at (x, y), k pixels per font pixel: title, the
 * bar, tick values, the note.  Returns its height. */
static int draw_legend(raster *R, const render_legend *L, int x, int y, int k)
{
    static const uint8_t ink[3] = { 30, 30, 40 };
    int W = R->cam.w, H = R->cam.h, line = (FONT_H + LEGEND_GAP) * k, y0 = y;
    char s[160];
    snprintf(s, sizeof s, "%s (%s)", L->title, L->units ? L->units : "model units");
    font_draw(R->rgb, W, H, x, y, k, s, ink);
    y += line;
    for (int bx = 0; bx < LEGEND_BAR_W * k; bx++) {
        double col[3];
        render_colour((double)bx / (LEGEND_BAR_W * k - 1), col);
        for (int by = 0; by < LEGEND_BAR_H * k; by++) {
            int px = x + bx, py = y + by;
            if (px < 0 || py < 0 || px >= W || py >= H) continue;
            uint8_t *c = &R->rgb[3 * ((size_t)py * W + px)];
            for (int j = 0; j < 3; j++) c[j] = to_byte(col[j]);
        }
    }
    y += (LEGEND_BAR_H + LEGEND_GAP) * k;
    for (int i = 0; i < LEGEND_TICKS; i++) {
        double v = L->vmax * i / (LEGEND_TICKS - 1);
        snprintf(s, sizeof s, i == LEGEND_TICKS - 1 ? ">=%.3g" : "%.3g", v);
        int tx = x + (LEGEND_BAR_W * k - 1) * i / (LEGEND_TICKS - 1) -
                 font_width(s, k) * i / (LEGEND_TICKS - 1);
        font_draw(R->rgb, W, H, tx, y, k, s, ink);
    }
    y += line;
    if (L->note) {
        font_draw(R->rgb, W, H, x, y, k, L->note, ink);
        y += line;
    }
    return y - y0;
}

/* Width of a legend's widest line, in pixels. */
static int legend_width(const render_legend *L, int k)
{
    char s[160];
    snprintf(s, sizeof s, "%s (%s)", L->title, L->units ? L->units : "model units");
    int w = font_width(s, k);
    if (L->note && font_width(L->note, k) > w) w = font_width(L->note, k);
    return w > LEGEND_BAR_W * k ? w : LEGEND_BAR_W * k;
}

/* The legends stacked in the bottom-right corner on a light veil. */
static void draw_legends(raster *R, const render_options *o)
{
    int k = R->cam.h >= 900 ? R->cam.h / 450 : 1, w = 0, h = 0;
    int line = (FONT_H + LEGEND_GAP) * k;
    for (int i = 0; i < o->nlegends; i++) {
        const render_legend *L = &o->legends[i];
        int lw = legend_width(L, k);
        if (lw > w) w = lw;
        h += 2 * line + (LEGEND_BAR_H + LEGEND_GAP) * k + (L->note ? line : 0) + LEGEND_PAD * k;
    }
    int x = R->cam.w - w - 2 * LEGEND_PAD * k, y = R->cam.h - h - 2 * LEGEND_PAD * k;
    veil(R, x - LEGEND_PAD * k, y - LEGEND_PAD * k, R->cam.w - LEGEND_PAD * k, R->cam.h - LEGEND_PAD * k);
    for (int i = 0; i < o->nlegends; i++)
        y += draw_legend(R, &o->legends[i], x, y, k) + LEGEND_PAD * k;
}

int render_mesh(const frep_mesh *m, const render_points *pts, const render_options *o,
                uint8_t *rgb, frep_error *e)
{
    const char *view = o->view ? o->view : "iso";
    const view_def *vd = find_view(view);
    if (!vd) return frep_error_set(e, FREP_EINPUT, "unknown view '%s' (known: %s)", view, RENDER_VIEWS);
    if (o->width < 1 || o->height < 1)
        return frep_error_set(e, FREP_EINPUT, "a picture of %dx%d pixels", o->width, o->height);
    raster R;
    R.rgb = rgb;
    R.zbuf = frep_malloc((size_t)o->width * (size_t)o->height * sizeof *R.zbuf);
    if (!R.zbuf) return frep_error_nomem(e);
    R.vval = o->vertex_value && o->vertex_vmax > 0 ? o->vertex_value : NULL;
    R.vmax = o->vertex_vmax;
    R.vrgb = o->vertex_rgb;
    camera_init(&R, vd, o);
    clear_picture(&R);
    lights_init(&R);
    for (size_t t = 0; t < m->ntris; t++) draw_triangle(&R, m, t);
    if (pts) draw_points(&R, pts);
    if (o->nlegends > 0) draw_legends(&R, o);
    frep_free(R.zbuf);
    return 0;
}

/* cmd_render.c - frep render: a shaded PNG picture of a model (polygonized by
 * mesh/mesh.c, rasterized by mesh/render.c, encoded by mesh/png.c), optionally
 * with a point cloud drawn over it, coloured by its distance to the surface, and the
 * surface coloured by its distance to the cloud (view/distance.c), with legends.
 */
#include "config.h"

#include "alloc.h"
#include "cli.h"
#include "cloud.h"
#include "mesh.h"
#include "png.h"
#include "render.h"

#include <stdlib.h>
#include <string.h>

/* Colour scale when no distance is finite and positive: as a fraction of the framed
 * box diagonal. */
#define RENDER_FALLBACK_FRACTION 0.02
#define RENDER_STR_(x) #x
#define RENDER_STR(x) RENDER_STR_(x)

static const char render_usage[] =
    "usage: frep render FILE.hf -o VIEW.png [options]\n"
    "       frep render MESH.(off|obj|stl|ply) -o VIEW.png [options]\n\n"
    "Draw a shaded picture of a model (polygonized as by frep mesh) or of a mesh file.\n"
    "With --points, the points of a cloud are drawn over it, coloured by their distance\n"
    "|f|/|grad f| to the model's surface (to the nearest triangle for a mesh file): blue\n"
    "on the surface, red at the scale or farther; the scale is chosen from the data (the\n"
    "95th percentile rounded up to 1, 2 or 5 x 10^k) unless --scale gives it. Points\n"
    "inside the solid by more than 1% of the box diagonal are drawn through the surface\n"
    "as rings. The surface is coloured by its distance to the nearest point (material the\n"
    "cloud does not show) unless --plain. Legends give the scales in model units.\n"
    "A model with colours (s[1..3], e.g. hfA_SetColor) is drawn in them, unless the\n"
    "surface is coloured by its distance to a cloud.\n\n";

typedef struct render_cmd {
    mesh_cli mc;
    const char *in, *out, *view, *points;
    int size[2];             /* width, height */
    int quiet, plain;
    double scale;            /* --scale; 0: from the data */
    frep_mesh m;
    mesh_stats st;
    double bbox[6];          /* the framed region: the mesh and the points */
    cli_cloud_dist cd;       /* --points and its distances */
    double dmean, dmax;
    size_t inside, deep;     /* points inside the solid, and deeper than the slack */
    char note[96];
    render_points rp;
    uint8_t *vrgb;           /* the model's colours at the vertices, else NULL */
    uint8_t *rgb;
} render_cmd;

/* --size WxH. */
static int parse_size(const char *arg, void *dest, char *why, size_t whylen)
{
    int *wh = dest;
    char x;
    int n = sscanf(arg, "%d%c%d", &wh[0], &x, &wh[1]);
    return n != 3 || (x != 'x' && x != 'X') || wh[0] < 1 || wh[1] < 1 || wh[0] > PNG_MAX_SIDE ||
                   wh[1] > PNG_MAX_SIDE ? -1 : 0;
}

static int parse_view(const char *arg, void *dest, char *why, size_t whylen)
{
    if (!render_view_ok(arg)) return -1;
    *(const char **)dest = arg;
    return 0;
}

#define OFF(f) offsetof(render_cmd, f)
static const cli_opt render_opts[] = {
    { 'o', "output", "PNG", CLI_OPT_STRING, OFF(out), .help = "the picture to write (required)" },
    { 0, "size", "WxH", CLI_OPT_CUSTOM, OFF(size), .parse = parse_size, .def = "800x600",
      .expect = "WxH with sides 1.." RENDER_STR(PNG_MAX_SIDE),
      .help = "picture size in pixels (default 800x600)" },
    { 0, "view", "V", CLI_OPT_CUSTOM, OFF(view), .parse = parse_view, .def = "iso",
      .expect = "one of " RENDER_VIEWS, .help = RENDER_VIEWS " (default iso)" },
    { 0, "points", "CLOUD", CLI_OPT_STRING, OFF(points),
      .help = "overlay a point cloud (.xyz or .ply)" },
    { 0, "scale", "D", CLI_OPT_DOUBLE, OFF(scale), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .what = "a distance", .help = "point distance drawn red (default: from the data)" },
    { 0, "plain", NULL, CLI_OPT_SET, OFF(plain),
      .help = "do not colour the surface by its distance to the cloud" },
    CLI_OPT_MODEL(render_cmd, mc.model, "the model (default: my_model, else the first one)"),
    CLI_OPT_PARAMS(render_cmd, mc.a, "values of the model's a[] array"),
    CLI_OPT_BOX(render_cmd, mc.box, "HyperFun's -b (default: the model's '-- @box', else 10)"),
    CLI_OPT_GRID(render_cmd, mc.grid, "128", "grid cells per axis of the mesh (default 128)"),
    CLI_OPT_ISO(render_cmd, mc.iso, "draw f = V"),
    CLI_OPT_SETOPS(render_cmd, mc.setops, "override the file's set operations: rfunc, minmax"),
    CLI_OPT_STRICT(render_cmd, mc.strict),
    CLI_OPT_THREADS(render_cmd, mc.nthreads, "OpenMP threads"),
    CLI_OPT_QUIET(render_cmd, quiet, "no summary line"),
};
#undef OFF
static const cli_opt_spec render_spec = { "render", render_usage, render_opts,
                                          sizeof render_opts / sizeof render_opts[0], 22 };

/* Options -> one input and -o. */
static int stage_options(render_cmd *c, int argc, char **argv)
{
    cli_args args;
    int rc = mesh_cli_parse(&render_spec, argc, argv, c, offsetof(render_cmd, mc), &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error("render", "expected one input: FILE.hf or a mesh file");
    if (!c->out) return cli_usage_error("render", "-o VIEW.png is required");
    c->in = args.v[0];
    return CLI_GO_ON;
}

/* The mesh to draw: a mesh file as it is, or the model polygonized; the box it spans. */
static int stage_mesh(render_cmd *c)
{
    if (cli_is_mesh_path(c->in)) {
        if (cli_read_mesh("render", c->in, &c->m) != CLI_OK) return CLI_FAIL;
    } else {
        if (mesh_cli_compile(&c->mc, c->in) != CLI_OK) return CLI_FAIL;
        if (mesh_cli_polygonize(&c->mc, "render", &c->m, &c->st) != CLI_OK) return CLI_FAIL;
        if (mesh_cli_vertex_colors(&c->mc, "render", &c->m, &c->vrgb) != CLI_OK) return CLI_FAIL;
    }
    for (int k = 0; k < 3; k++) {
        c->bbox[k] = INFINITY;
        c->bbox[k + 3] = -INFINITY;
    }
    for (size_t i = 0; i < c->m.nverts; i++)
        for (int k = 0; k < 3; k++) {
            c->bbox[k] = fmin(c->bbox[k], c->m.v[3 * i + k]);
            c->bbox[k + 3] = fmax(c->bbox[k + 3], c->m.v[3 * i + k]);
        }
    return CLI_OK;
}

/* The mean and largest finite |distance| for the summary, the points inside; the
 * framed box grows to hold the points. */
static void point_stats(render_cmd *c)
{
    const frep_cloud *cl = c->cd.cl;
    for (size_t i = 0; i < cl->n; i++) {
        double d = fabs(c->cd.pdist[i]);
        if (isfinite(d)) {
            c->dmean += d / (double)cl->n;
            c->dmax = fmax(c->dmax, d);
        }
        c->inside += c->cd.pdist[i] > 0;
        c->bbox[0] = fmin(c->bbox[0], cl->x[i]);
        c->bbox[3] = fmax(c->bbox[3], cl->x[i]);
        c->bbox[1] = fmin(c->bbox[1], cl->y[i]);
        c->bbox[4] = fmax(c->bbox[4], cl->y[i]);
        c->bbox[2] = fmin(c->bbox[2], cl->z[i]);
        c->bbox[5] = fmax(c->bbox[5], cl->z[i]);
    }
}

/* --points: the cloud and its distances (cli/model.c), the framed box grown to hold
 * it, the scales (--scale, else from the data, else a share of the box), the points
 * inside. */
static int stage_points(render_cmd *c)
{
    if (cli_cloud_distances("render", c->points, &c->mc, &c->m, &c->cd) != CLI_OK) return CLI_FAIL;
    point_stats(c);
    const double *b = c->bbox;
    double diag = sqrt((b[3] - b[0]) * (b[3] - b[0]) + (b[4] - b[1]) * (b[4] - b[1]) +
                       (b[5] - b[2]) * (b[5] - b[2]));
    cli_cloud_dist *d = &c->cd;
    if (!(d->pscale > 0)) d->pscale = RENDER_FALLBACK_FRACTION * diag;
    if (!(d->vscale > 0)) d->vscale = RENDER_FALLBACK_FRACTION * diag;
    if (c->scale > 0) d->pscale = c->scale;
    for (size_t i = 0; i < d->cl->n; i++)
        c->deep += d->pdist[i] > RENDER_POINT_DEPTH_SLACK * diag;
    snprintf(c->note, sizeof c->note, "%zu of %zu points inside the solid, %zu as rings",
             c->inside, d->cl->n, c->deep);
    c->rp = (render_points){ d->cl->n, d->cl->x, d->cl->y, d->cl->z, d->pdist, d->pscale, 1 };
    return CLI_OK;
}

/* The colour legends: the points' distances, the surface's. */
static void set_legends(const render_cmd *c, render_options *ro)
{
    if (!c->points) return;
    ro->legends[ro->nlegends++] = (render_legend){ "points: distance to the surface", c->rp.vmax,
                                                   "model units", c->note };
    if (c->plain) return;
    ro->vertex_value = c->cd.vdist;
    ro->vertex_vmax = c->cd.vscale;
    ro->legends[ro->nlegends++] = (render_legend){ "surface: distance to the nearest point",
                                                   c->cd.vscale, "model units", NULL };
}

/* Rasterize the mesh (and the points) into c->rgb. */
static int stage_draw(render_cmd *c)
{
    int W = c->size[0], H = c->size[1];
    c->rgb = malloc(3 * (size_t)W * (size_t)H);
    if (!c->rgb) {
        fprintf(stderr, "frep render: out of memory for a %dx%d picture\n", W, H);
        return CLI_FAIL;
    }
    render_options ro = { .width = W, .height = H, .view = c->view, .vertex_rgb = c->vrgb };
    memcpy(ro.bbox, c->bbox, sizeof c->bbox);
    set_legends(c, &ro);
    frep_error err;
    frep_error_init(&err);
    if (render_mesh(&c->m, c->points ? &c->rp : NULL, &ro, c->rgb, &err) != 0) {
        fprintf(stderr, "frep render: %s\n", err.msg);
        return CLI_FAIL;
    }
    return CLI_OK;
}

static int write_png_cb(FILE *f, void *user)
{
    render_cmd *c = user;
    return png_write_rgb(f, c->rgb, c->size[0], c->size[1]);
}

static void stage_report(const render_cmd *c)
{
    printf("%s: %dx%d, %s view of %zu triangles", c->out, c->size[0], c->size[1], c->view,
           c->m.ntris);
    if (c->points)
        printf(", %zu points (distance to the surface: mean %.3g, max %.3g)", c->cd.cl->n, c->dmean,
               c->dmax);
    printf("\n");
}

/* mesh -> [points] -> draw -> write -> report */
static int render_steps(render_cmd *c)
{
    int rc = stage_mesh(c);
    if (rc == CLI_OK && c->points) rc = stage_points(c);
    if (rc == CLI_OK) rc = stage_draw(c);
    if (rc == CLI_OK && cli_write_atomic(c->out, write_png_cb, c) != 0) rc = CLI_FAIL;
    if (rc == CLI_OK && !c->quiet) stage_report(c);
    return rc;
}

int cmd_render(int argc, char **argv)
{
    render_cmd c;
    memset(&c, 0, sizeof c);
    mesh_cli_init(&c.mc);
    int rc = stage_options(&c, argc, argv);
    if (rc == CLI_GO_ON) rc = render_steps(&c);
    mesh_free(&c.m);
    cli_cloud_dist_free(&c.cd);
    free(c.rgb);
    frep_free(c.vrgb);
    mesh_cli_free(&c.mc);
    return rc;
}

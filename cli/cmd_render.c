/* cmd_render.c - frep render: a shaded PNG picture of a model (polygonized as frep
 * mesh does, cli/model.c) or of a mesh file, optionally with a point cloud drawn over
 * it, coloured by its distance to the surface, and the surface coloured by its
 * distance to the cloud, with legends (frep_render()): on the public API alone.
 */
#include "config.h"

#include "cli.h"

#include <stdlib.h>
#include <string.h>

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
    frep_mesh *m;
    frep_mesh_info mi;
    frep_cloud *cl;          /* --points */
    uint8_t *vrgb;           /* the model's colours at the vertices, else NULL */
    frep_image *img;
    frep_render_info info;
} render_cmd;

/* --size WxH. */
static int parse_size(const char *arg, void *dest, char *why, size_t whylen)
{
    int *wh = dest;
    char x;
    int n = sscanf(arg, "%d%c%d", &wh[0], &x, &wh[1]);
    return n != 3 || (x != 'x' && x != 'X') || wh[0] < 1 || wh[1] < 1 || wh[0] > FREP_RENDER_MAX_SIDE ||
                   wh[1] > FREP_RENDER_MAX_SIDE ? -1 : 0;
}

static int parse_view(const char *arg, void *dest, char *why, size_t whylen)
{
    if (!frep_render_view_ok(arg)) return -1;
    *(const char **)dest = arg;
    return 0;
}

#define OFF(f) offsetof(render_cmd, f)
static const cli_opt render_opts[] = {
    { 'o', "output", "PNG", CLI_OPT_STRING, OFF(out), .help = "the picture to write (required)" },
    { 0, "size", "WxH", CLI_OPT_CUSTOM, OFF(size), .parse = parse_size, .def = "800x600",
      .expect = "WxH with sides 1.." RENDER_STR(FREP_RENDER_MAX_SIDE),
      .help = "picture size in pixels (default 800x600)" },
    { 0, "view", "V", CLI_OPT_CUSTOM, OFF(view), .parse = parse_view, .def = "iso",
      .expect = "one of " FREP_RENDER_VIEWS, .help = FREP_RENDER_VIEWS " (default iso)" },
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

/* The library's messages as "frep render: ...", compiler ones with their position. */
static void render_diag(void *user, const frep_diag *d)
{
    (void)user;
    if (d->file == NULL) {
        cli_library_diag("render", d);
        return;
    }
    char *s = frep_diag_format(d, NULL, 0);
    fprintf(stderr, "%s", s ? s : d->message);
    if (!s) fputc('\n', stderr);
    frep_free(s);
}

/* The mesh to draw: a mesh file as it is, or the model polygonized (with its
 * colours). */
static int stage_mesh(render_cmd *c)
{
    if (cli_is_mesh_path(c->in)) return (c->m = cli_mesh_read(c->in)) ? CLI_OK : CLI_FAIL;
    if (mesh_cli_compile(&c->mc, c->in) != CLI_OK) return CLI_FAIL;
    if (mesh_cli_mesh(&c->mc, "render", &c->m, &c->mi) != CLI_OK) return CLI_FAIL;
    return mesh_cli_vertex_colors(&c->mc, "render", c->m, &c->vrgb);
}

/* The picture (frep_render(): the points' distances, legends, raster). */
static int stage_draw(render_cmd *c)
{
    frep_render_options o;
    frep_render_options_init(&o);
    o.width = c->size[0];
    o.height = c->size[1];
    o.view = c->view;
    o.scale = c->scale;
    o.plain = c->plain;
    o.program = c->mc.p;
    o.iso = c->mc.iso;
    o.nthreads = c->mc.nthreads;
    o.vertex_rgb = c->vrgb;
    if (c->points) {
        c->cl = frep_cloud_read(c->points, render_diag, NULL);
        if (!c->cl) return CLI_FAIL;
        o.points = c->cl;
    }
    c->img = frep_render(c->m, &o, &c->info, render_diag, NULL);
    return c->img ? CLI_OK : CLI_FAIL;
}

static void stage_report(const render_cmd *c)
{
    printf("%s: %dx%d, %s view of %zu triangles", c->out, c->size[0], c->size[1], c->view,
           c->info.ntris);
    if (c->points)
        printf(", %zu points (distance to the surface: mean %.3g, max %.3g)", c->info.npoints,
               c->info.mean_dist, c->info.max_dist);
    printf("\n");
}

/* The picture's bytes, for cli_write_atomic (whose temporary the signal handler
 * removes). */
static int write_png(FILE *f, void *user)
{
    return frep_image_write_png_stream(user, f);
}

/* mesh -> draw (points measured) -> write -> report */
static int render_steps(render_cmd *c)
{
    int rc = stage_mesh(c);
    /* the drawing polls nothing: from here a signal stops the command at once, the
     * picture not written (an old one untouched) */
    cli_sigint_release();
    if (rc == CLI_OK && cli_interrupted())
        rc = cli_interrupt_status("render", "stopped before drawing, nothing written");
    if (rc == CLI_OK) rc = stage_draw(c);
    if (rc == CLI_OK && cli_write_atomic(c->out, write_png, c->img) != 0) rc = CLI_FAIL;
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
    frep_mesh_free(c.m);
    frep_cloud_free(c.cl);
    frep_image_free(c.img);
    frep_free(c.vrgb);
    mesh_cli_free(&c.mc);
    return rc;
}

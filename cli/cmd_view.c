/* cmd_view.c - frep view: the page of a model (polygonized as by frep mesh, through
 * cli/model.c, or a mesh file) and of a cloud with its distances (view/distance.c),
 * written by view/page.c as one self-contained HTML file with a WebGL viewer.
 */
#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "distance.h"
#include "mesh.h"
#include "page.h"

#include <stdlib.h>
#include <string.h>

/* Colour scale when no distance is finite and positive (a cloud exactly on the
 * surface): any positive value draws every point blue. */
#define VIEW_FALLBACK_SCALE 1.0

static const char view_usage[] =
    "usage: frep view FILE.hf [--points CLOUD] [-o VIEW.html] [options]\n"
    "       frep view MESH.(off|obj|stl|ply) [--points CLOUD] [-o VIEW.html]\n\n"
    "Write one self-contained HTML page (it opens from disk: no server, no network) that\n"
    "draws the model, polygonized as by frep mesh, in WebGL: orbit (left drag), pan\n"
    "(right or shift drag), zoom (wheel), standard views, a section plane, wireframe.\n"
    "With --points the cloud is drawn too, each point coloured by its distance\n"
    "|f|/|grad f| to the surface, points inside the solid drawn through it as rings,\n"
    "and the surface can be coloured by its distance to the nearest point (material the\n"
    "cloud does not show). The model's text and parameters are beside the picture.\n\n";

typedef struct view_cmd {
    mesh_cli mc;
    const char *in, *out, *points;
    double scale;            /* --scale: 0 chooses it from the data */
    int quiet;
    frep_mesh m;
    mesh_stats st;
    frep_cloud *cl;
    double *pdist, *vdist;   /* signed point distances, vertex distances */
    double pscale, vscale;
    size_t np;
    const char **pnames;
    double *pvalues;
    char info[160];
} view_cmd;

#define OFF(f) offsetof(view_cmd, f)
static const cli_opt view_opts[] = {
    { 'o', "output", "HTML", CLI_OPT_STRING, OFF(out), .def = "view.html",
      .help = "the page to write (default view.html)" },
    { 0, "points", "CLOUD", CLI_OPT_STRING, OFF(points), .help = "a point cloud (.xyz or .ply)" },
    { 0, "scale", "D", CLI_OPT_DOUBLE, OFF(scale), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .what = "a distance", .help = "distance drawn red (default: from the data, the 95th\n"
                                    "percentile rounded up to 1, 2 or 5 x 10^k)" },
    CLI_OPT_MODEL(view_cmd, mc.model, "the model (default: my_model, else the last one)"),
    CLI_OPT_PARAMS(view_cmd, mc.a, "values of the model's a[] array"),
    CLI_OPT_BOX(view_cmd, mc.box, "HyperFun's -b (default: the model's '-- @box', else 10)"),
    CLI_OPT_GRID(view_cmd, mc.grid, "128", "grid cells per axis of the mesh (default 128)"),
    CLI_OPT_ISO(view_cmd, mc.iso, "draw f = V"),
    CLI_OPT_SETOPS(view_cmd, mc.setops, "override the file's set operations: rfunc, minmax"),
    CLI_OPT_THREADS(view_cmd, mc.nthreads, "OpenMP threads"),
    CLI_OPT_QUIET(view_cmd, quiet, "no summary line"),
};
#undef OFF
static const cli_opt_spec view_spec = { "view", view_usage, view_opts,
                                        sizeof view_opts / sizeof view_opts[0], 22 };

/* The model's mesh: a mesh file as it is, or the model compiled and polygonized. */
static int stage_mesh(view_cmd *c)
{
    if (cli_is_mesh_path(c->in)) return cli_read_mesh("view", c->in, &c->m);
    if (mesh_cli_compile(&c->mc, c->in) != CLI_OK) return CLI_FAIL;
    return mesh_cli_polygonize(&c->mc, "view", &c->m, &c->st);
}

/* The free parameters of the model, for the side panel. */
static int stage_params(view_cmd *c)
{
    if (!c->mc.p) return CLI_OK;
    c->np = frep_program_nparams(c->mc.p);
    c->pnames = calloc(c->np + 1, sizeof *c->pnames);
    c->pvalues = calloc(c->np + 1, sizeof *c->pvalues);
    if (!c->pnames || !c->pvalues) {
        fprintf(stderr, "frep view: out of memory\n");
        return CLI_FAIL;
    }
    for (size_t i = 0; i < c->np; i++) {
        c->pnames[i] = frep_program_param_name(c->mc.p, i);
        c->pvalues[i] = frep_program_param_value(c->mc.p, i);
    }
    return CLI_OK;
}

/* --points: the cloud, each point's signed distance to the surface (the model's
 * |f|/|grad f|, or the mesh's nearest triangle), each vertex's distance to the cloud,
 * and the two colour scales. */
static int stage_points(view_cmd *c)
{
    char *msg = NULL;
    c->cl = cloud_read(c->points, &msg);
    if (!c->cl) {
        fprintf(stderr, "%s\n", msg ? msg : "frep view: cannot read the cloud");
        free(msg);
        return CLI_FAIL;
    }
    const frep_cloud *cl = c->cl;
    c->pdist = malloc((cl->n + 1) * sizeof *c->pdist);
    c->vdist = malloc((c->m.nverts + 1) * sizeof *c->vdist);
    frep_error e;
    frep_error_init(&e);
    if (!c->pdist || !c->vdist) {
        frep_error_nomem(&e);
        goto fail;
    }
    frep_runtime_error re;
    memset(&re, 0, sizeof re);
    int rc = c->mc.p ? view_point_distances(c->mc.p, c->mc.iso, cl->n, cl->x, cl->y, cl->z,
                                            c->mc.nthreads, c->pdist, &re, &e)
                     : view_mesh_distances(&c->m, cl->n, cl->x, cl->y, cl->z, c->pdist, &e);
    if (rc != 0) goto fail;
    mesh_cli_add_errors(&c->mc, &re);
    mesh_cli_report_errors(&c->mc);
    if (view_vertex_distances(&c->m, cl->n, cl->x, cl->y, cl->z, c->vdist, &e) != 0 ||
        view_auto_scale(c->pdist, cl->n, VIEW_FALLBACK_SCALE, &c->pscale, &e) != 0 ||
        view_auto_scale(c->vdist, c->m.nverts, VIEW_FALLBACK_SCALE, &c->vscale, &e) != 0)
        goto fail;
    if (c->scale > 0) c->pscale = c->vscale = c->scale;
    return CLI_OK;
fail:
    fprintf(stderr, "frep view: %s: %s\n", c->points, e.msg);
    return CLI_FAIL;
}

/* The scene of the page from what the stages made. */
static void make_scene(const view_cmd *c, view_scene *s)
{
    memset(s, 0, sizeof *s);
    s->name = c->in;
    s->mesh = &c->m;
    s->source = c->mc.src;
    s->nparams = c->np;
    s->pnames = c->pnames;
    s->pvalues = c->pvalues;
    s->info = c->info;
    if (c->cl) {
        s->npoints = c->cl->n;
        s->px = c->cl->x;
        s->py = c->cl->y;
        s->pz = c->cl->z;
        s->pdist = c->pdist;
        s->pscale = c->pscale;
        s->vdist = c->vdist;
        s->vscale = c->vscale;
    }
}

static int write_page_cb(FILE *f, void *user)
{
    const view_cmd *c = user;
    view_scene s;
    make_scene(c, &s);
    frep_error e;
    frep_error_init(&e);
    if (view_write_page(f, &s, &e) == 0) return 0;
    fprintf(stderr, "frep view: %s\n", e.msg);
    return -1;
}

/* The summary line: the page, its size, what it holds. */
static void stage_report(const view_cmd *c)
{
    FILE *f = fopen(c->out, "rb");
    long size = -1;
    if (f && fseek(f, 0, SEEK_END) == 0) size = ftell(f);
    if (f) fclose(f);
    printf("%s: %.2f MB, %zu triangles", c->out, (double)size / 1e6, c->m.ntris);
    if (c->cl) printf(", %zu points (colour scale %g)", c->cl->n, c->pscale);
    printf("\n");
}

/* mesh -> parameters -> [points] -> write -> report */
static int view_steps(view_cmd *c)
{
    int rc = stage_mesh(c);
    if (rc == CLI_OK) rc = stage_params(c);
    if (rc == CLI_OK && c->points) rc = stage_points(c);
    if (rc != CLI_OK) return rc;
    if (c->mc.p)
        snprintf(c->info, sizeof c->info, "grid %d, box [%g,%g]x[%g,%g]x[%g,%g], meshed in %.2f s",
                 c->mc.grid, c->mc.box[0], c->mc.box[3], c->mc.box[1], c->mc.box[4], c->mc.box[2],
                 c->mc.box[5], c->st.seconds);
    if (cli_write_atomic(c->out, write_page_cb, c) != 0) return CLI_FAIL;
    if (!c->quiet) stage_report(c);
    return CLI_OK;
}

/* Options -> one model or mesh file. */
static int stage_options(view_cmd *c, int argc, char **argv)
{
    cli_args args;
    int rc = mesh_cli_parse(&view_spec, argc, argv, c, offsetof(view_cmd, mc), &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error("view", "expected one input: FILE.hf or a mesh file");
    c->in = args.v[0];
    return CLI_GO_ON;
}

static void view_free(view_cmd *c)
{
    mesh_free(&c->m);
    memset(&c->m, 0, sizeof c->m);
    cloud_free(c->cl);
    free(c->pdist);
    free(c->vdist);
    free(c->pnames);
    free(c->pvalues);
    c->cl = NULL;
    c->pdist = c->vdist = c->pvalues = NULL;
    c->pnames = NULL;
    c->np = 0;
}

int cmd_view(int argc, char **argv)
{
    view_cmd c;
    memset(&c, 0, sizeof c);
    mesh_cli_init(&c.mc);
    int rc = stage_options(&c, argc, argv);
    if (rc == CLI_GO_ON) rc = view_steps(&c);
    view_free(&c);
    mesh_cli_free(&c.mc);
    return rc;
}

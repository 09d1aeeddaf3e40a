/* cmd_mesh.c - frep mesh: polygonize a model (mesh/mesh.c, through the steps of
 * cli/model.c) and write STL, OBJ, PLY or OFF (geom/meshio.c), atomically.
 */
#include "config.h"

#include "cli.h"
#include "mesh.h"
#include "meshio.h"

#include <stdlib.h>
#include <string.h>

static const char mesh_usage[] =
    "usage: frep mesh FILE.hf -o OUT [options]\n\n"
    "Polygonize a model: dual contouring on an octree pruned by interval arithmetic.\n"
    "The mesh is closed, 2-manifold and oriented outward, keeps sharp edges and corners,\n"
    "and carries per-vertex normals from the analytic gradient. Where the solid reaches\n"
    "the box, the mesh is closed by caps on the box faces.\n\n"
    "The format comes from OUT's extension: .stl (binary; --ascii for text STL), .obj,\n"
    ".ply (binary; --ascii for text PLY), .off. OUT '-' writes binary STL to stdout.\n\n";

typedef struct mesh_cmd {
    mesh_cli mc;
    const char *out;
    int ascii, quiet, check, check_self, verbose;
    meshio_format fmt;
    frep_mesh m;
    mesh_stats st;
    FILE *summary;           /* stdout, or stderr when the mesh goes to stdout */
} mesh_cmd;

#define OFF(f) offsetof(mesh_cmd, f)
static const cli_opt mesh_opts[] = {
    { 'o', "output", "OUT", CLI_OPT_STRING, OFF(out), .help = "the mesh file to write (required)" },
    CLI_OPT_MODEL(mesh_cmd, mc.model, "the model to mesh (default: my_model, else the last one)"),
    CLI_OPT_PARAMS(mesh_cmd, mc.a, "values of the model's a[] array, comma separated"),
    CLI_OPT_BOX(mesh_cmd, mc.box,
                "HyperFun's -b: 'v' for [-v,v]^3, 'lo,hi', 'a,b,c' for\n"
                "[-a,a]x[-b,b]x[-c,c], or 'x0,y0,z0,x1,y1,z1'; default: the\n"
                "model's '-- @box' annotation, else 10"),
    CLI_OPT_GRID(mesh_cmd, mc.grid, "64", "grid cells per axis (HyperFun's -g; default 64, at most 2048)"),
    CLI_OPT_ISO(mesh_cmd, mc.iso, "polygonize f = V instead of f = 0 (inside is f >= V)"),
    { 0, "ascii", NULL, CLI_OPT_SET, OFF(ascii), .help = "text STL / text PLY" },
    CLI_OPT_SETOPS(mesh_cmd, mc.setops, "override the file's set operations: rfunc, minmax"),
    CLI_OPT_THREADS(mesh_cmd, mc.nthreads, "OpenMP threads (default: all cores); the mesh is the same"),
    { 0, "check", NULL, CLI_OPT_SET, OFF(check),
      .help = "verify the mesh (closed, 2-manifold at edges and vertices,\n"
              "oriented, no degenerate triangles), print the counts and the\n"
              "enclosed volume; fail if not" },
    { 0, "check-intersections", NULL, CLI_OPT_SET, OFF(check_self),
      .help = "--check, and also count the self-intersecting triangle\n"
              "pairs (exact predicates; slower: seconds per 10^5\n"
              "triangles) and the vertices farther than 0.1 cell from\n"
              "the surface" },
    CLI_OPT_QUIET(mesh_cmd, quiet, "no summary line"),
    { 'v', "verbose", NULL, CLI_OPT_SET, OFF(verbose),
      .help = "also print the work done: octree nodes (interval tests),\n"
              "blocks, points evaluated, gradients evaluated, cells with\n"
              "several sheets, vertices added on faces a sheet crosses twice" },
};
#undef OFF
static const cli_opt_spec mesh_spec = { "mesh", mesh_usage, mesh_opts,
                                        sizeof mesh_opts / sizeof mesh_opts[0], 22 };

/* Options -> one model file and an output whose extension names a format. */
static int stage_options(mesh_cmd *c, int argc, char **argv, const char **in)
{
    cli_args args;
    int rc = mesh_cli_parse(&mesh_spec, argc, argv, c, offsetof(mesh_cmd, mc), &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error("mesh", "expected one model file FILE.hf");
    if (!c->out) return cli_usage_error("mesh", "-o OUT is required (.stl, .obj, .ply or .off)");
    c->fmt = strcmp(c->out, "-") == 0 ? MESHIO_STL : meshio_format_for_path(c->out);
    if (c->fmt == MESHIO_UNKNOWN)
        return cli_usage_error("mesh", "cannot tell the format of '%s': use .stl, .obj, .ply or .off",
                               c->out);
    c->summary = strcmp(c->out, "-") == 0 ? stderr : stdout;
    *in = args.v[0];
    return CLI_GO_ON;
}

static int write_mesh_cb(FILE *f, void *user)
{
    mesh_cmd *c = user;
    return meshio_write(f, &c->m, c->fmt, c->ascii);
}

/* The vertices' distances from the model's surface, for --check. */
static int vertex_distance(mesh_cmd *c, mesh_distance *d)
{
    mesh_field f;
    if (mesh_field_program(&f, c->mc.p, NULL) != 0) {
        fprintf(stderr, "frep mesh: out of memory checking the mesh\n");
        return CLI_FAIL;
    }
    mesh_options o;
    mesh_options_init(&o);
    memcpy(o.box, c->mc.box, sizeof o.box);
    o.grid = c->mc.grid;
    o.iso = c->mc.iso;
    frep_error err;
    frep_error_init(&err);
    int rc = mesh_surface_distance(&f, &o, &c->m, MESH_SURFACE_TOL, d, &err);
    mesh_field_program_free(&f);
    if (rc != 0) fprintf(stderr, "frep mesh: %s\n", err.msg);
    return rc != 0 ? CLI_FAIL : CLI_OK;
}

/* --check-intersections: the self-intersecting pairs and the vertices farther than
 * MESH_SURFACE_TOL cells from the surface. */
static int stage_check_self(mesh_cmd *c)
{
    size_t pairs = 0;
    mesh_distance md;
    if (mesh_self_intersections(&c->m, &pairs, NULL) != 0) {
        fprintf(stderr, "frep mesh: out of memory checking the mesh\n");
        return CLI_FAIL;
    }
    if (vertex_distance(c, &md) != CLI_OK) return CLI_FAIL;
    fprintf(c->summary, "check: self-intersecting triangle pairs %zu, vertices farther than %g "
                        "cell from the surface %zu (largest %.3g cell)\n",
            pairs, MESH_SURFACE_TOL, md.far, md.max_dist);
    return CLI_OK;
}

/* --check: the mesh is closed, manifold, oriented, without degenerate triangles. */
static int stage_check(mesh_cmd *c)
{
    mesh_check mk;
    if (mesh_validate(&c->m, &mk) != 0) {
        fprintf(stderr, "frep mesh: out of memory checking the mesh\n");
        return CLI_FAIL;
    }
    fprintf(c->summary, "check: open edges %zu, non-manifold edges %zu, flipped edges %zu, "
                        "non-manifold vertices %zu, unused vertices %zu, degenerate "
                        "triangles %zu, non-finite coordinates %zu, volume %.9g, area %.9g\n",
            mk.open_edges, mk.nonmanifold_edges, mk.flipped_edges, mk.nonmanifold_verts,
            mk.unused_verts, mk.degenerate, mk.nonfinite, mk.volume, mk.area);
    if (c->check_self && stage_check_self(c) != CLI_OK) return CLI_FAIL;
    if (mk.open_edges || mk.nonmanifold_edges || mk.flipped_edges || mk.nonmanifold_verts ||
        mk.unused_verts || mk.degenerate || mk.nonfinite || !(mk.volume > 0)) {
        /* the mesh is written (to look at), and the failure said in words */
        fprintf(stderr, "frep mesh: %s fails the check (counts above)\n", c->out);
        return CLI_FAIL;
    }
    return CLI_OK;
}

/* The summary line, the work done (-v), the check (--check). */
static int stage_report(mesh_cmd *c)
{
    const mesh_cli *mc = &c->mc;
    if (!c->quiet)
        fprintf(c->summary, "%s: %zu vertices, %zu triangles (%s%s), box [%g,%g]x[%g,%g]x[%g,%g], "
                            "grid %d, %.3f s\n", c->out, c->m.nverts, c->m.ntris,
                c->ascii ? "ASCII " : "", meshio_format_name(c->fmt), mc->box[0], mc->box[3],
                mc->box[1], mc->box[4], mc->box[2], mc->box[5], mc->grid, c->st.seconds);
    if (c->verbose)
        fprintf(c->summary, "work: %zu octree nodes, %zu of %zu blocks, %zu points evaluated, %zu "
                            "gradients, %zu cells with several components, %zu face vertices\n",
                c->st.octree_nodes, c->st.blocks, c->st.blocks_total, c->st.eval_points,
                c->st.grad_points, c->st.cells_split, c->st.face_vertices);
    return c->check || c->check_self ? stage_check(c) : CLI_OK;
}

/* compile -> polygonize -> write -> report */
static int mesh_steps(mesh_cmd *c, const char *in)
{
    int rc = mesh_cli_compile(&c->mc, in);
    if (rc == CLI_OK) rc = mesh_cli_polygonize(&c->mc, "mesh", &c->m, &c->st);
    if (rc != CLI_OK) return rc;
    rc = cli_write_atomic(c->out, write_mesh_cb, c) != 0 ? CLI_FAIL : stage_report(c);
    mesh_free(&c->m);
    return rc;
}

int cmd_mesh(int argc, char **argv)
{
    mesh_cmd c;
    memset(&c, 0, sizeof c);
    mesh_cli_init(&c.mc);
    const char *in = NULL;
    int rc = stage_options(&c, argc, argv, &in);
    if (rc == CLI_GO_ON) rc = mesh_steps(&c, in);
    mesh_cli_free(&c.mc);
    return rc;
}

/* cmd_mesh.c - frep mesh: polygonize a model (frep_polygonize, through the steps of
 * cli/model.c), colour it and write STL, OBJ, PLY, OFF or VRML atomically
 * (frep_mesh_write_stream), --check it (frep_mesh_check, frep_mesh_surface_distance):
 * on the public API alone (frep.h), as tests/layers.sh checks.
 */
#include "config.h"

#include "cli.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char mesh_usage[] =
    "usage: frep mesh FILE.hf -o OUT [options]\n\n"
    "Polygonize a model: dual contouring on an octree pruned by interval arithmetic.\n"
    "The mesh is closed, 2-manifold and oriented outward, keeps sharp edges and corners,\n"
    "and carries per-vertex normals from the analytic gradient. Where the solid reaches\n"
    "the box, the mesh is closed by caps on the box faces.\n\n"
    "The format comes from OUT's extension: .stl (binary; --ascii for text STL), .obj,\n"
    ".ply (binary; --ascii for text PLY), .off, .wrl (VRML 2.0). OUT '-' writes binary\n"
    "STL to stdout. PLY and VRML get vertex colours: the model's own when it declares\n"
    "s[] with at least 3 attributes (s[1..3] = red, green, blue in [0,1]), else none;\n"
    "--color sets one colour for all, --color none turns them off.\n\n"
    "HyperFun hfp's options work too: -stl/-stlb/-wrl FILE (text STL, binary STL, VRML\n"
    "to FILE), -g NX,NY,NZ (cells per axis), -i V (iso value), -cf R,G,B (face colour: --color),\n"
    "-ct (colours from s[1..3]: --color model), -x X,Y,Z, -t without a number (time\n"
    "report: the summary line has the time); hfp's -o names a model (frep: -m NAME).\n"
    "The viewer's -cl, -d, -w and -pov/-cli output are refused with what to use instead.\n\n";

/* Where the vertices' colours come from (--color). */
typedef enum {
    COLOR_AUTO,    /* the model's s[1..3] when it has them and the format carries colours */
    COLOR_NONE,    /* --color none */
    COLOR_MODEL,   /* --color model, hfp's -ct: s[1..3], an error without them */
    COLOR_UNIFORM  /* --color V or R,G,B */
} color_source;

typedef struct mesh_color {
    color_source src;
    int rgb[3];              /* COLOR_UNIFORM's colour */
} mesh_color;

typedef struct mesh_cmd {
    mesh_cli mc;
    const char *out;
    int ascii, quiet, check, verbose;
    mesh_color color;        /* --color */
    frep_mesh_format fmt;
    frep_mesh_format hfp_fmt; /* hfp's -stl/-stlb/-wrl chose the format, else AUTO */
    uint8_t *vrgb;           /* the vertices' colours, else NULL */
    uint8_t *uniform;        /* --color V or R,G,B's colours (malloc'ed; vrgb points here) */
    char grid_arg[16];       /* the largest of hfp's -g NX,NY,NZ, for the table's -g */
    frep_mesh *m;
    frep_mesh_info mi;
    FILE *summary;           /* stdout, or stderr when the mesh goes to stdout */
} mesh_cmd;

/* A colour source: "model", "none", or "V" (grey V) or "R,G,B", each 0..255 (hfp's
 * -cf / -cl syntax). */
static int parse_color(const char *arg, void *dest, char *why, size_t whylen)
{
    mesh_color *mcol = dest;
    int *rgb = mcol->rgb, v[3], n = 0;
    const char *p = arg;
    (void)why;
    (void)whylen;
    if (!strcmp(arg, "model") || !strcmp(arg, "none")) {
        mcol->src = arg[0] == 'm' ? COLOR_MODEL : COLOR_NONE;
        return 0;
    }
    for (;;) {
        char *end;
        long x = strtol(p, &end, 10);
        if (end == p || x < 0 || x > 255 || n == 3) return -1;
        v[n++] = (int)x;
        if (*end == '\0') break;
        if (*end != ',') return -1;
        p = end + 1;
    }
    if (n != 1 && n != 3) return -1;
    for (int k = 0; k < 3; k++) rgb[k] = v[n == 1 ? 0 : k];
    mcol->src = COLOR_UNIFORM;
    return 0;
}

#define OFF(f) offsetof(mesh_cmd, f)
static const cli_opt mesh_opts[] = {
    { 'o', "output", "OUT", CLI_OPT_STRING, OFF(out), .help = "the mesh file to write (required)" },
    CLI_OPT_MAX_WORK(mesh_cmd, mc.max_work),
    CLI_OPT_MODEL(mesh_cmd, mc.model, "the model to mesh (default: my_model, else the first one)"),
    CLI_OPT_PARAMS(mesh_cmd, mc.a, "values of the model's a[] array, comma separated"),
    CLI_OPT_BOX(mesh_cmd, mc.box,
                "HyperFun's -b: 'v' for [-v,v]^3, 'lo,hi', 'a,b,c' for\n"
                "[-a,a]x[-b,b]x[-c,c], or 'x0,y0,z0,x1,y1,z1'; default: the\n"
                "model's '-- @box' annotation, else 10"),
    CLI_OPT_GRID(mesh_cmd, mc.grid, "64", "grid cells per axis (HyperFun's -g; default 64, at most 2048)"),
    CLI_OPT_ISO(mesh_cmd, mc.iso, "polygonize f = V instead of f = 0 (inside is f >= V)"),
    { 0, "ascii", NULL, CLI_OPT_SET, OFF(ascii), .help = "text STL / text PLY" },
    { 0, "color", "RGB", CLI_OPT_CUSTOM, OFF(color), .parse = parse_color,
      .expect = "model, none, V or R,G,B with each in 0..255",
      .help = "the vertex colours (PLY, VRML Color): 'V' (grey) or 'R,G,B',\n"
              "each 0..255, for all (hfp's -cf); 'model': s[1..3] (hfp's\n"
              "-ct); 'none'. Default: 'model' if the model has s[1..3]" },
    CLI_OPT_SETOPS(mesh_cmd, mc.setops, "override the file's set operations: rfunc, minmax"),
    CLI_OPT_STRICT(mesh_cmd, mc.strict),
    CLI_OPT_THREADS(mesh_cmd, mc.nthreads, "OpenMP threads (default: all cores); the mesh is the same"),
    { 0, "check", NULL, CLI_OPT_SET, OFF(check),
      .help = "verify the mesh (closed, 2-manifold at edges and vertices,\n"
              "oriented, no degenerate triangles; fail if not), print the\n"
              "counts, the self-intersecting triangle pairs (exact\n"
              "predicates), the vertices farther than 0.1 cell from the\n"
              "surface and the enclosed volume" },
    { 0, "check-intersections", NULL, CLI_OPT_SET, OFF(check),
      .help = "the same as --check (its self-intersection and vertex\n"
              "distance counts were once only here)" },
    CLI_OPT_QUIET(mesh_cmd, quiet, "no summary line"),
    { 'v', "verbose", NULL, CLI_OPT_SET, OFF(verbose),
      .help = "also print the work done: octree nodes (interval tests),\n"
              "blocks, points evaluated, gradients evaluated, cells with\n"
              "several sheets, vertices added on faces a sheet crosses twice,\n"
              "and the wall time of each step" },
};
#undef OFF
static const cli_opt_spec mesh_spec = { "mesh", mesh_usage, mesh_opts,
                                        sizeof mesh_opts / sizeof mesh_opts[0], 22 };

/* Does the model file at path define a model called name?  (Its header: the name, then
 * '(' and 'x', at the start of a line or after '}'; case-insensitive like HyperFun.) */
static int file_names_model(const char *path, const char *name)
{
    size_t len = 0, n = strlen(name);
    char *text = n ? cli_read_file(path, &len) : NULL;
    int found = 0;
    for (size_t i = 0; text && !found && i + n <= len; i++) {
        if (i > 0 && !isspace((unsigned char)text[i - 1]) && text[i - 1] != '}') continue;
        size_t k = 0;
        while (k < n && tolower((unsigned char)text[i + k]) == tolower((unsigned char)name[k])) k++;
        if (k < n) continue;
        size_t j = i + n;
        while (j < len && isspace((unsigned char)text[j])) j++;
        if (j < len && text[j] == '(') {
            for (j++; j < len && isspace((unsigned char)text[j]);) j++;
            found = j < len && (text[j] == 'x' || text[j] == 'X');
        }
    }
    free(text);
    return found;
}

/* An unsigned decimal integer (a thread count after -t)? */
static int is_count(const char *s)
{
    if (!*s) return 0;
    for (; *s; s++)
        if (!isdigit((unsigned char)*s)) return 0;
    return 1;
}

/* hfp's options (HyperFun's polygonizer), so that its command lines work: its
 * multi-letter single-dash options are rewritten into frep's before the table parses
 * argv, or refused with what to use instead (they would otherwise read as clusters of
 * short options, -stl as -s -t -l).  The rewritten argv goes to *out (malloc'ed, free
 * it; its strings are argv's or static).  Returns CLI_GO_ON or a usage error. */
static int hfp_options(mesh_cmd *c, int argc, char **argv, char ***out, int *outc)
{
    char **v = malloc(((size_t)argc + 1) * sizeof *v);
    int n = 0;
    if (!v) {
        fprintf(stderr, "frep mesh: out of memory\n");
        return CLI_FAIL;
    }
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
        int rc = CLI_GO_ON;
        if (i == 0 || a[0] != '-' || a[1] == '-' || a[1] == '\0') {
            v[n++] = argv[i];
            if (strcmp(a, "--") == 0)
                while (++i < argc) v[n++] = argv[i];
            continue;
        }
        if (!strcmp(a, "-stl") || !strcmp(a, "-stlb") || !strcmp(a, "-wrl")) {
            if (!val) rc = cli_usage_error("mesh", "hfp's %s needs a file name", a);
            else if (c->hfp_fmt != FREP_MESH_AUTO)
                rc = cli_usage_error("mesh", "%s: the output is already '%s'", a, c->out);
            else {
                c->out = val;
                c->hfp_fmt = a[1] == 'w' ? FREP_MESH_WRL : FREP_MESH_STL;
                if (!strcmp(a, "-stl")) c->ascii = 1;
                i++;
                continue;
            }
        } else if (!strcmp(a, "-pov") || !strcmp(a, "-cli")) {
            rc = cli_usage_error("mesh", "hfp's %s output (%s) is not a format frep writes: use "
                                         "-o FILE.stl, .obj, .ply, .off or .wrl", a,
                                 a[1] == 'p' ? "POV-Ray mesh" : "CLI slices");
        } else if (!strcmp(a, "-cf")) {
            v[n++] = "--color";
            continue;
        } else if (!strcmp(a, "-cl")) {
            rc = cli_usage_error("mesh", "hfp's -cl is the wireframe colour of its viewer; frep "
                                         "mesh draws nothing (see the mesh with frep view)");
        } else if (!strcmp(a, "-ct")) {
            v[n++] = "--color=model";
            continue;
        } else if (!strcmp(a, "-d") || !strcmp(a, "-w")) {
            rc = cli_usage_error("mesh", "hfp's %s sets its viewer's %s; frep mesh has no viewer "
                                         "(frep view shows a mesh)", a,
                                 a[1] == 'd' ? "display mode" : "window size");
        } else if (!strcmp(a, "-s")) {
            rc = cli_usage_error("mesh", "hfp's -s (vertex search) is not needed: frep finds "
                                         "every vertex on the surface by root finding");
        } else if (!strcmp(a, "-x")) {
            if (!val) rc = cli_usage_error("mesh", "hfp's -x needs a mapping such as X,Y,Z");
            else if (strcmp(val, "X,Y,Z") != 0 && strcmp(val, "x,y,z") != 0)
                rc = cli_usage_error("mesh", "-x %s: frep meshes x[1], x[2], x[3] as x, y, z and "
                                             "reads x[4..] as 0; other mappings are not supported",
                                     val);
            else {
                i++;
                continue;
            }
        } else if (!strcmp(a, "-i")) {
            v[n++] = "--iso";
            continue;
        } else if ((!strcmp(a, "-g") || !strcmp(a, "--grid")) && val && strchr(val, ',')) {
            /* hfp's per-axis densities NX,NY,NZ: equal ones are one N */
            int g[3], k = 0;
            const char *p = val;
            while (k < 3) {
                char *end;
                long x = strtol(p, &end, 10);
                if (end == p || x < 1 || x > FREP_MESH_MAX_GRID) break;
                g[k++] = (int)x;
                if (*end != ',') {
                    p = end;
                    break;
                }
                p = end + 1;
            }
            if (k != 3 || *p)
                rc = cli_usage_error("mesh", "%s %s: expected N or NX,NY,NZ with each in 1..%d", a,
                                     val, FREP_MESH_MAX_GRID);
            else {
                /* the table's -g gets the largest (the summary's figure) */
                int gmax = g[0] > g[1] ? g[0] : g[1];
                gmax = gmax > g[2] ? gmax : g[2];
                int same = g[0] == g[1] && g[1] == g[2];
                for (int q = 0; q < 3; q++) c->mc.grid_axes[q] = same ? 0 : g[q];
                snprintf(c->grid_arg, sizeof c->grid_arg, "%d", gmax);
                v[n++] = argv[i];
                v[n++] = c->grid_arg;
                i++;
                continue;
            }
        } else if (!strcmp(a, "-t") && !(val && is_count(val))) {
            continue; /* hfp's time report: frep's summary line has the time */
        } else {
            v[n++] = argv[i];
            continue;
        }
        free(v);
        return rc;
    }
    v[n] = NULL;
    *out = v;
    *outc = n;
    return CLI_GO_ON;
}

/* Options -> one model file and an output whose extension names a format. */
static int stage_options(mesh_cmd *c, int argc, char **argv, const char **in)
{
    cli_args args;
    char **v = NULL;
    int n = 0;
    int rc = hfp_options(c, argc, argv, &v, &n);
    if (rc != CLI_GO_ON) return rc;
    const char *hfp_out = c->out;
    rc = mesh_cli_parse(&mesh_spec, n, v, c, offsetof(mesh_cmd, mc), &args);
    if (rc == CLI_GO_ON && hfp_out && c->out != hfp_out)
        rc = cli_usage_error("mesh", "-o %s: the output is already '%s'", c->out, hfp_out);
    if (rc == CLI_GO_ON && args.n != 1) rc = cli_usage_error("mesh", "expected one model file FILE.hf");
    if (rc == CLI_GO_ON) *in = args.v[0];
    free(v);
    if (rc != CLI_GO_ON) return rc;
    if (!c->out) return cli_usage_error("mesh", "-o OUT is required (.stl, .obj, .ply, .off or .wrl)");
    cli_default_threads(c->mc.nthreads);
    c->fmt = c->hfp_fmt != FREP_MESH_AUTO ? c->hfp_fmt
             : strcmp(c->out, "-") == 0 ? FREP_MESH_STL : frep_mesh_format_for_path(c->out);
    if (c->fmt == FREP_MESH_AUTO && file_names_model(*in, c->out))
        return cli_usage_error("mesh", "-o %s: frep's -o is the output file; %s is a model in %s: "
                                       "did you mean -m %s?", c->out, c->out, *in, c->out);
    if (c->fmt == FREP_MESH_AUTO)
        return cli_usage_error("mesh", "cannot tell the format of '%s': use .stl, .obj, .ply, .off "
                                       "or .wrl", c->out);
    int colored = c->fmt == FREP_MESH_PLY || c->fmt == FREP_MESH_WRL;
    if ((c->color.src == COLOR_UNIFORM || c->color.src == COLOR_MODEL) && !colored)
        return cli_usage_error("mesh", "--color: %s files carry no colours (use .ply or .wrl)",
                               frep_mesh_format_name(c->fmt));
    if (c->color.src == COLOR_AUTO && !colored) c->color.src = COLOR_NONE;
    c->summary = strcmp(c->out, "-") == 0 ? stderr : stdout;
    return CLI_GO_ON;
}

/* --color V or R,G,B: every vertex the same. */
static int uniform_colors(mesh_cmd *c)
{
    size_t n = frep_mesh_nverts(c->m);
    c->vrgb = c->uniform = malloc(3 * n + 1);
    if (!c->uniform) {
        fprintf(stderr, "frep mesh: out of memory colouring the mesh\n");
        return CLI_FAIL;
    }
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) c->uniform[3 * i + k] = (uint8_t)c->color.rgb[k];
    return CLI_OK;
}

/* The model's colours: s[1..3] at every vertex (cli/model.c).  AUTO without three
 * attributes: no colours. */
static int model_colors(mesh_cmd *c)
{
    size_t k = frep_program_nattrs(c->mc.p);
    if (k < 3) {
        if (c->color.src == COLOR_AUTO) return CLI_OK;
        fprintf(stderr, "frep mesh: --color model: %s has %zu attributes; colours need s[1..3] "
                        "(declare the model as name(x[3], a[M], s[3]))\n", c->mc.path, k);
        return CLI_FAIL;
    }
    return mesh_cli_vertex_colors(&c->mc, "mesh", c->m, &c->vrgb);
}

static int write_mesh_cb(FILE *f, void *user)
{
    mesh_cmd *c = user;
    return frep_mesh_write_stream(c->m, c->vrgb, f, c->fmt, c->ascii);
}

/* The library's message as "frep mesh: ...". */
static void mesh_diag(void *user, const frep_diag *d)
{
    (void)user;
    cli_library_diag("mesh", d);
}

/* --check: the mesh is closed, manifold, oriented, without degenerate triangles, without
 * self-intersecting triangle pairs and without vertices farther than
 * FREP_MESH_SURFACE_TOL cells from the surface (else a failure, the mesh written). */
static int stage_check(mesh_cmd *c)
{
    frep_mesh_check_result mk;
    frep_mesh_distance md;
    if (frep_mesh_check(c->m, 1, &mk, NULL, NULL) != 0) {
        fprintf(stderr, "frep mesh: out of memory checking the mesh\n");
        return CLI_FAIL;
    }
    fprintf(c->summary, "check: open edges %zu, non-manifold edges %zu, flipped edges %zu, "
                        "non-manifold vertices %zu, unused vertices %zu, degenerate "
                        "triangles %zu, non-finite coordinates %zu, volume %.9g, area %.9g\n",
            mk.open_edges, mk.nonmanifold_edges, mk.flipped_edges, mk.nonmanifold_verts,
            mk.unused_verts, mk.degenerate, mk.nonfinite, mk.volume, mk.area);
    frep_mesh_options o;
    mesh_cli_options(&c->mc, &o);
    if (frep_mesh_surface_distance(c->mc.p, &o, c->m, FREP_MESH_SURFACE_TOL, &md, mesh_diag,
                                   NULL) != 0)
        return CLI_FAIL;
    fprintf(c->summary, "check: self-intersecting triangle pairs %zu, vertices farther than %g "
                        "cell from the surface %zu (largest %.3g cell)\n",
            mk.self_intersections, FREP_MESH_SURFACE_TOL, md.far, md.max_dist);
    if (mk.open_edges || mk.nonmanifold_edges || mk.flipped_edges || mk.nonmanifold_verts ||
        mk.unused_verts || mk.degenerate || mk.nonfinite || !(mk.volume > 0)) {
        /* the mesh is written (to look at), and the failure said in words */
        fprintf(stderr, "frep mesh: %s fails the check (counts above)\n", c->out);
        return CLI_FAIL;
    }
    /* Other tools (Open3D, slicers) reject a self-intersecting mesh, and a vertex off
     * the surface misplaces a face: both fail the check too (doc/mesh.md). */
    if (mk.self_intersections || md.far) {
        fprintf(stderr, "frep mesh: %s fails the check: %s%s%s (counts above)\n", c->out,
                mk.self_intersections ? "self-intersecting triangles" : "",
                mk.self_intersections && md.far ? " and " : "",
                md.far ? "vertices off the surface" : "");
        return CLI_FAIL;
    }
    return CLI_OK;
}

/* The summary line, the work done (-v), the check (--check). */
static int stage_report(mesh_cmd *c)
{
    const mesh_cli *mc = &c->mc;
    char grid[48];
    if (mc->grid_axes[0])
        snprintf(grid, sizeof grid, "%d,%d,%d", mc->grid_axes[0], mc->grid_axes[1], mc->grid_axes[2]);
    else snprintf(grid, sizeof grid, "%d", mc->grid);
    if (!c->quiet)
        fprintf(c->summary, "%s: %zu vertices, %zu triangles (%s%s), box [%g,%g]x[%g,%g]x[%g,%g], "
                            "grid %s, %.3f s\n", c->out, frep_mesh_nverts(c->m),
                frep_mesh_ntris(c->m),
                c->ascii ? "ASCII " : "", frep_mesh_format_name(c->fmt), mc->box[0], mc->box[3],
                mc->box[1], mc->box[4], mc->box[2], mc->box[5], grid, c->mi.seconds);
    if (c->verbose)
        fprintf(c->summary, "work: %zu octree nodes, %zu of %zu blocks, %zu points evaluated, %zu "
                            "gradients, %zu cells with several components, %zu face vertices, %zu vertices "
                            "settled\n",
                c->mi.octree_nodes, c->mi.blocks, c->mi.blocks_total, c->mi.eval_points,
                c->mi.grad_points, c->mi.cells_split, c->mi.face_vertices, c->mi.settled);
    if (c->verbose)
        fprintf(c->summary, "time: octree %.1f ms, contouring %.1f ms, quads %.1f ms, assembly "
                            "%.1f ms, settling %.1f ms\n",
                1e3 * c->mi.octree_seconds, 1e3 * c->mi.contour_seconds,
                1e3 * c->mi.quads_seconds, 1e3 * c->mi.assembly_seconds,
                1e3 * c->mi.settle_seconds);
    return c->check ? stage_check(c) : CLI_OK;
}

/* compile -> polygonize -> colour -> write -> report */
static int mesh_steps(mesh_cmd *c, const char *in)
{
    int rc = mesh_cli_compile(&c->mc, in);
    if (rc == CLI_OK) rc = mesh_cli_mesh(&c->mc, "mesh", &c->m, &c->mi);
    if (rc == CLI_OK && c->color.src == COLOR_UNIFORM) rc = uniform_colors(c);
    else if (rc == CLI_OK && (c->color.src == COLOR_AUTO || c->color.src == COLOR_MODEL))
        rc = model_colors(c);
    if (rc == CLI_OK)
        rc = cli_write_atomic(c->out, write_mesh_cb, c) != 0 ? CLI_FAIL : stage_report(c);
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
    if (c.vrgb != c.uniform) frep_free(c.vrgb);
    free(c.uniform);
    frep_mesh_free(c.m);
    mesh_cli_free(&c.mc);
    return rc;
}

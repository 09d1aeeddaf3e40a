/* cmd_mesh.c - frep mesh: polygonize a model (mesh/mesh.c) and write STL, OBJ, PLY
 * or OFF (geom/meshio.c).  Also holds the model-to-mesh steps that frep sample and
 * frep render share (mesh_cli_*).
 */
#include "config.h"

#include "cli.h"
#include "mesh.h"
#include "meshio.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char mesh_usage[] =
    "usage: frep mesh FILE.hf -o OUT [options]\n\n"
    "Polygonize a model: dual contouring on an octree pruned by interval arithmetic.\n"
    "The mesh is closed, 2-manifold and oriented outward, keeps sharp edges and corners,\n"
    "and carries per-vertex normals from the analytic gradient. Where the solid reaches\n"
    "the box, the mesh is closed by caps on the box faces.\n\n"
    "The format comes from OUT's extension: .stl (binary; --ascii for text STL), .obj,\n"
    ".ply (binary; --ascii for text PLY), .off. OUT '-' writes binary STL to stdout.\n\n"
    "Options:\n"
    "  -o, --output OUT    the mesh file to write (required)\n"
    "  -m, --model NAME    the model to mesh (default: my_model, else the last one)\n"
    "  -a, --params LIST   values of the model's a[] array, comma separated\n"
    "  -b, --box BOX       HyperFun's -b: 'v' for [-v,v]^3, 'lo,hi', 'a,b,c' for\n"
    "                      [-a,a]x[-b,b]x[-c,c], or 'x0,y0,z0,x1,y1,z1'; default: the\n"
    "                      model's '-- @box' annotation, else 10\n"
    "  -g, --grid N        grid cells per axis (HyperFun's -g; default 64, at most 2048)\n"
    "      --iso V         polygonize f = V instead of f = 0 (inside is f >= V)\n"
    "      --ascii         text STL / text PLY\n"
    "      --setops S      override the file's set operations: rfunc, minmax\n"
    "  -t, --threads N     OpenMP threads (default: all cores); the mesh is the same\n"
    "      --check         verify the mesh (closed, 2-manifold at edges and vertices,\n"
    "                      oriented, no degenerate triangles), print the counts and the\n"
    "                      enclosed volume; fail if not\n"
    "  -q, --quiet         no summary line\n"
    "  -v, --verbose       also print the work done: octree nodes (interval tests),\n"
    "                      blocks, points evaluated, gradients evaluated, cells with\n"
    "                      several sheets, vertices added on faces a sheet crosses twice\n";

void mesh_cli_init(mesh_cli *c)
{
    memset(c, 0, sizeof *c);
    c->grid = 64;
    c->setops = -1;
}

void mesh_cli_free(mesh_cli *c)
{
    free(c->a);
    if (c->p) frep_program_free(c->p);
    free(c->src);
    c->a = NULL;
    c->p = NULL;
    c->src = NULL;
}

int mesh_cli_option(mesh_cli *c, const char *sub, int opt, const char *arg)
{
    char *end;
    switch (opt) {
    case 'm': c->model = arg; return 0;
    case 'a':
        free(c->a);
        c->a = cli_parse_list("-a", arg, &c->na);
        return c->a ? 0 : CLI_USAGE;
    case 'b':
        if (cli_parse_box(arg, c->box) != 0) return CLI_USAGE;
        c->has_box = 1;
        return 0;
    case 'g': {
        errno = 0;
        long g = strtol(arg, &end, 10);
        if (*end || errno || g < 1 || g > MESH_MAX_GRID)
            return cli_usage_error(sub, "-g: expected grid cells per axis in 1..%d, got '%s'%s",
                                   MESH_MAX_GRID, arg,
                                   g > MESH_MAX_GRID ? " (the mesh would not fit in memory)" : "");
        c->grid = (int)g;
        return 0;
    }
    case 'I':
        errno = 0;
        c->iso = strtod(arg, &end);
        if (*end || errno || !isfinite(c->iso))
            return cli_usage_error(sub, "--iso: expected a number, got '%s'", arg);
        return 0;
    case 't':
        errno = 0;
        c->nthreads = (int)strtol(arg, &end, 10);
        if (*end || errno || c->nthreads < 1 || c->nthreads > 1024)
            return cli_usage_error(sub, "--threads: expected an integer in 1..1024");
        return 0;
    case 'S':
        if (strcmp(arg, "rfunc") == 0) c->setops = FREP_SETOPS_RFUNC;
        else if (strcmp(arg, "minmax") == 0) c->setops = FREP_SETOPS_MINMAX;
        else return cli_usage_error(sub, "--setops: expected rfunc or minmax, got '%s'", arg);
        return 0;
    default: break;
    }
    return -1;
}

void mesh_cli_add_errors(mesh_cli *c, const frep_runtime_error *e)
{
    if (e->count == 0) return;
    uint64_t n = c->err.count;
    if (n == 0 || e->pc < c->err.pc) c->err = *e;
    c->err.count = n + e->count;
}

/* Runtime errors do not stop meshing (the points are NaN and count as outside), so
 * they are warnings here; frep eval's format otherwise. */
static void warning_diag(void *user, const frep_diag *d)
{
    frep_diag w = *d;
    w.severity = FREP_WARNING;
    cli_print_diag(user, &w);
}

void mesh_cli_report_errors(mesh_cli *c)
{
    if (c->err.count == 0 || !c->p) return;
    cli_diag_ctx dc = { c->src, c->srclen, 0, 0, NULL, 0 };
    frep_report_runtime_error(c->p, &c->err, warning_diag, &dc);
    cli_diag_done(&dc);
    memset(&c->err, 0, sizeof c->err);
}

static void progress_cb(void *user, double frac)
{
    int *last = user;
    int pct = (int)(100 * frac);
    if (pct == *last) return;
    *last = pct;
    fprintf(stderr, "\rfrep: meshing %3d%%", pct);
    fflush(stderr);
}

int mesh_cli_compile(mesh_cli *c, const char *path)
{
    c->path = path;
    c->p = cli_compile_file(path, c->model, c->a, c->na, c->setops, &c->src);
    if (!c->p) return CLI_FAIL;
    c->srclen = c->src ? strlen(c->src) : 0;
    if (!c->has_box && !frep_program_box(c->p, c->box)) {
        for (int i = 0; i < 3; i++) {
            c->box[i] = -10;
            c->box[i + 3] = 10;
        }
    }
    return CLI_OK;
}

int mesh_cli_polygonize(mesh_cli *c, const char *sub, frep_mesh *m, mesh_stats *st)
{
    mesh_field f;
    if (mesh_field_program(&f, c->p, NULL) != 0) {
        fprintf(stderr, "frep %s: out of memory\n", sub);
        return CLI_FAIL;
    }
    mesh_options o;
    mesh_options_init(&o);
    memcpy(o.box, c->box, sizeof o.box);
    o.grid = c->grid;
    o.iso = c->iso;
    o.nthreads = c->nthreads;
    int last = -1;
    int tty = isatty(2);
    if (tty) {
        o.progress = progress_cb;
        o.progress_user = &last;
    }
    frep_error err;
    frep_error_init(&err);
    int rc = mesh_polygonize(&f, &o, m, st, &err);
    frep_runtime_error re;
    mesh_field_program_errors(&f, &re);
    mesh_cli_add_errors(c, &re);
    mesh_field_program_free(&f);
    mesh_cli_report_errors(c);
    if (tty && last >= 0) fputs("\r                     \r", stderr);
    if (rc != 0) {
        fprintf(stderr, "frep %s: %s\n", sub, err.msg);
        return CLI_FAIL;
    }
    if (st->points_nan)
        fprintf(stderr, "%s: warning: the model is NaN (undefined) at %zu grid points; they count "
                        "as outside\n", c->path, st->points_nan);
    if (m->ntris == 0 || st->full) {
        fprintf(stderr, "frep %s: %s: the model %s the box [%g,%g]x[%g,%g]x[%g,%g] at grid %d: "
                        "no surface (check -b and -g)\n", sub, c->path,
                st->full ? "fills all of" : "is empty in", c->box[0], c->box[3], c->box[1],
                c->box[4], c->box[2], c->box[5], c->grid);
        mesh_free(m);
        return CLI_FAIL;
    }
    if (st->touches_box)
        fprintf(stderr, "%s: note: the solid reaches the box; the mesh is closed by caps on the "
                        "box faces (a larger -b shows all of it)\n", c->path);
    return CLI_OK;
}

typedef struct mesh_write_ctx {
    const frep_mesh *m;
    meshio_format fmt;
    int ascii;
} mesh_write_ctx;

static int write_mesh_cb(FILE *f, void *user)
{
    mesh_write_ctx *w = user;
    return meshio_write(f, w->m, w->fmt, w->ascii);
}

int cmd_mesh(int argc, char **argv)
{
    static const struct option longopts[] = {
        { "help", no_argument, NULL, 'h' },
        { "output", required_argument, NULL, 'o' },
        { "model", required_argument, NULL, 'm' },
        { "params", required_argument, NULL, 'a' },
        { "box", required_argument, NULL, 'b' },
        { "grid", required_argument, NULL, 'g' },
        { "iso", required_argument, NULL, 'I' },
        { "ascii", no_argument, NULL, 'A' },
        { "setops", required_argument, NULL, 'S' },
        { "threads", required_argument, NULL, 't' },
        { "quiet", no_argument, NULL, 'q' },
        { "check", no_argument, NULL, 'C' },
        { "verbose", no_argument, NULL, 'v' },
        { NULL, 0, NULL, 0 },
    };
    mesh_cli mc;
    mesh_cli_init(&mc);
    const char *out = NULL;
    int ascii = 0, quiet = 0, check = 0, verbose = 0, c, rc;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "ho:m:a:b:g:t:qv", longopts, NULL)) != -1) {
        switch (c) {
        case 'h': fputs(mesh_usage, stdout); mesh_cli_free(&mc); return CLI_OK;
        case 'o': out = optarg; break;
        case 'A': ascii = 1; break;
        case 'q': quiet = 1; break;
        case 'C': check = 1; break;
        case 'v': verbose = 1; break;
        default:
            rc = mesh_cli_option(&mc, "mesh", c, optarg);
            if (rc == -1)
                rc = cli_usage_error("mesh", "unknown or incomplete option '%s'", argv[optind - 1]);
            if (rc != 0) {
                mesh_cli_free(&mc);
                return rc;
            }
        }
    }
    if (argc - optind != 1) {
        mesh_cli_free(&mc);
        return cli_usage_error("mesh", "expected one model file FILE.hf");
    }
    if (!out) {
        mesh_cli_free(&mc);
        return cli_usage_error("mesh", "-o OUT is required (.stl, .obj, .ply or .off)");
    }
    meshio_format fmt = strcmp(out, "-") == 0 ? MESHIO_STL : meshio_format_for_path(out);
    if (fmt == MESHIO_UNKNOWN) {
        mesh_cli_free(&mc);
        return cli_usage_error("mesh", "cannot tell the format of '%s': use .stl, .obj, .ply or .off",
                               out);
    }
    rc = mesh_cli_compile(&mc, argv[optind]);
    if (rc != CLI_OK) {
        mesh_cli_free(&mc);
        return rc;
    }
    frep_mesh m;
    mesh_stats st;
    rc = mesh_cli_polygonize(&mc, "mesh", &m, &st);
    if (rc == CLI_OK) {
        mesh_write_ctx w = { &m, fmt, ascii };
        if (cli_write_atomic(out, write_mesh_cb, &w) != 0) {
            rc = CLI_FAIL;
        } else if (!quiet) {
            FILE *sf = strcmp(out, "-") == 0 ? stderr : stdout;
            fprintf(sf, "%s: %zu vertices, %zu triangles (%s%s), box [%g,%g]x[%g,%g]x[%g,%g], "
                        "grid %d, %.3f s\n", out, m.nverts, m.ntris, ascii ? "ASCII " : "",
                    meshio_format_name(fmt), mc.box[0], mc.box[3], mc.box[1], mc.box[4],
                    mc.box[2], mc.box[5], mc.grid, st.seconds);
        }
        if (rc == CLI_OK && verbose) {
            FILE *sf = strcmp(out, "-") == 0 ? stderr : stdout;
            fprintf(sf, "work: %zu octree nodes, %zu of %zu blocks, %zu points evaluated, %zu "
                        "gradients, %zu cells with several components, %zu face vertices\n",
                    st.octree_nodes, st.blocks, st.blocks_total, st.eval_points, st.grad_points,
                    st.cells_split, st.face_vertices);
        }
        if (rc == CLI_OK && check) {
            mesh_check mk;
            if (mesh_validate(&m, &mk) != 0) {
                fprintf(stderr, "frep mesh: out of memory checking the mesh\n");
                rc = CLI_FAIL;
            } else {
                FILE *sf = strcmp(out, "-") == 0 ? stderr : stdout;
                fprintf(sf, "check: open edges %zu, non-manifold edges %zu, flipped edges %zu, "
                            "non-manifold vertices %zu, unused vertices %zu, degenerate "
                            "triangles %zu, non-finite coordinates %zu, volume %.9g, area %.9g\n",
                        mk.open_edges, mk.nonmanifold_edges, mk.flipped_edges,
                        mk.nonmanifold_verts, mk.unused_verts, mk.degenerate, mk.nonfinite,
                        mk.volume, mk.area);
                if (mk.open_edges || mk.nonmanifold_edges || mk.flipped_edges ||
                    mk.nonmanifold_verts || mk.unused_verts || mk.degenerate || mk.nonfinite ||
                    !(mk.volume > 0))
                    rc = CLI_FAIL;
            }
        }
        mesh_free(&m);
    }
    mesh_cli_free(&mc);
    return rc;
}

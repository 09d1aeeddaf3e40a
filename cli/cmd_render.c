/* cmd_render.c - frep render: a shaded PNG picture of a model (polygonized by
 * mesh/mesh.c, rasterized by mesh/render.c, encoded by mesh/png.c), optionally
 * with a point cloud drawn over it, coloured by its distance to the surface.
 */
#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "mesh.h"
#include "meshio.h"
#include "png.h"
#include "render.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Distance (as a fraction of the framed box diagonal) drawn fully red by --points. */
#define RENDER_FAR_FRACTION 0.02

static const char render_usage[] =
    "usage: frep render FILE.hf -o VIEW.png [options]\n"
    "       frep render MESH.(off|obj|stl|ply) -o VIEW.png [options]\n\n"
    "Draw a shaded picture of a model (polygonized as by frep mesh) or of a mesh file.\n"
    "With --points, the points of a cloud are drawn over it, coloured by their distance\n"
    "|f|/|grad f| to the model's surface: blue on the surface, red at 2% of the picture's\n"
    "box diagonal or farther.\n\n"
    "Options:\n"
    "  -o, --output PNG    the picture to write (required)\n"
    "      --size WxH      picture size in pixels (default 800x600)\n"
    "      --view V        " RENDER_VIEWS " (default iso)\n"
    "      --points CLOUD  overlay a point cloud (.xyz or .ply)\n"
    "  -m, --model NAME    the model (default: my_model, else the last one)\n"
    "  -a, --params LIST   values of the model's a[] array\n"
    "  -b, --box BOX       HyperFun's -b (default: the model's '-- @box', else 10)\n"
    "  -g, --grid N        grid cells per axis of the mesh (default 128)\n"
    "      --iso V         draw f = V\n"
    "      --setops S      override the file's set operations: rfunc, minmax\n"
    "  -t, --threads N     OpenMP threads\n"
    "  -q, --quiet         no summary line\n";

typedef struct png_ctx {
    const uint8_t *rgb;
    int w, h;
} png_ctx;

static int write_png_cb(FILE *f, void *user)
{
    png_ctx *p = user;
    return png_write_rgb(f, p->rgb, p->w, p->h);
}

int cmd_render(int argc, char **argv)
{
    static const struct option longopts[] = {
        { "help", no_argument, NULL, 'h' },
        { "output", required_argument, NULL, 'o' },
        { "size", required_argument, NULL, 'Z' },
        { "view", required_argument, NULL, 'V' },
        { "points", required_argument, NULL, 'P' },
        { "model", required_argument, NULL, 'm' },
        { "params", required_argument, NULL, 'a' },
        { "box", required_argument, NULL, 'b' },
        { "grid", required_argument, NULL, 'g' },
        { "iso", required_argument, NULL, 'I' },
        { "setops", required_argument, NULL, 'S' },
        { "threads", required_argument, NULL, 't' },
        { "quiet", no_argument, NULL, 'q' },
        { NULL, 0, NULL, 0 },
    };
    mesh_cli mc;
    mesh_cli_init(&mc);
    mc.grid = 128;
    const char *out = NULL, *view = "iso", *points = NULL;
    int W = 800, H = 600, quiet = 0, c, rc;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "ho:m:a:b:g:t:q", longopts, NULL)) != -1) {
        rc = 0;
        switch (c) {
        case 'h': fputs(render_usage, stdout); mesh_cli_free(&mc); return CLI_OK;
        case 'o': out = optarg; break;
        case 'Z': {
            char x;
            int n = sscanf(optarg, "%d%c%d", &W, &x, &H);
            if (n != 3 || (x != 'x' && x != 'X') || W < 1 || H < 1 || W > PNG_MAX_SIDE ||
                H > PNG_MAX_SIDE)
                rc = cli_usage_error("render", "--size: expected WxH with sides 1..%d, got '%s'",
                                     PNG_MAX_SIDE, optarg);
            break;
        }
        case 'V':
            view = optarg;
            if (!render_view_ok(view))
                rc = cli_usage_error("render", "--view: expected one of %s, got '%s'", RENDER_VIEWS,
                                     optarg);
            break;
        case 'P': points = optarg; break;
        case 'q': quiet = 1; break;
        default:
            rc = mesh_cli_option(&mc, "render", c, optarg);
            if (rc == -1)
                rc = cli_usage_error("render", "unknown or incomplete option '%s'", argv[optind - 1]);
        }
        if (rc != 0) {
            mesh_cli_free(&mc);
            return rc;
        }
    }
    if (argc - optind != 1) {
        mesh_cli_free(&mc);
        return cli_usage_error("render", "expected one input: FILE.hf or a mesh file");
    }
    if (!out) {
        mesh_cli_free(&mc);
        return cli_usage_error("render", "-o VIEW.png is required");
    }
    const char *in = argv[optind];
    int is_mesh = meshio_format_for_path(in) != MESHIO_UNKNOWN;
    frep_mesh m;
    memset(&m, 0, sizeof m);
    mesh_stats st;
    memset(&st, 0, sizeof st);
    frep_cloud *cl = NULL;
    double *dist = NULL;
    uint8_t *rgb = NULL;
    rc = CLI_FAIL;
    if (is_mesh) {
        frep_error msg;
        if (meshio_read(in, &m, &msg) != 0) {
            fprintf(stderr, "%s\n", msg.msg[0] ? msg.msg : "frep render: cannot read the mesh");
            goto done;
        }
        if (points) {
            fprintf(stderr, "frep render: --points needs a model (FILE.hf) to measure distances\n");
            rc = CLI_USAGE;
            goto done;
        }
    } else {
        if (mesh_cli_compile(&mc, in) != CLI_OK) goto done;
        if (mesh_cli_polygonize(&mc, "render", &m, &st) != CLI_OK) goto done;
    }
    double bbox[6] = { INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY };
    for (size_t i = 0; i < m.nverts; i++)
        for (int k = 0; k < 3; k++) {
            bbox[k] = fmin(bbox[k], m.v[3 * i + k]);
            bbox[k + 3] = fmax(bbox[k + 3], m.v[3 * i + k]);
        }
    render_points rp;
    memset(&rp, 0, sizeof rp);
    double dmean = 0, dmax = 0;
    if (points) {
        frep_error msg;
        cl = cloud_read(points, &msg);
        if (!cl) {
            fprintf(stderr, "%s\n", msg.msg[0] ? msg.msg : "frep render: cannot read the cloud");
            goto done;
        }
        dist = malloc((cl->n + 1) * 4 * sizeof *dist);
        if (!dist) {
            fprintf(stderr, "frep render: out of memory\n");
            goto done;
        }
        double *g = dist + cl->n;
        frep_runtime_error e;
        if (frep_eval_grad_par(mc.p, cl->n, cl->x, cl->y, cl->z, NULL, dist, g, g + cl->n,
                               g + 2 * cl->n, mc.nthreads, &e) != 0) {
            fprintf(stderr, "frep render: evaluation failed\n");
            goto done;
        }
        mesh_cli_add_errors(&mc, &e);
        mesh_cli_report_errors(&mc);
        for (size_t i = 0; i < cl->n; i++) {
            double gx = g[i], gy = g[cl->n + i], gz = g[2 * cl->n + i];
            double gl = sqrt(gx * gx + gy * gy + gz * gz);
            dist[i] = gl > 0 ? fabs(dist[i] - mc.iso) / gl : INFINITY;
            if (isfinite(dist[i])) {
                dmean += dist[i] / (double)cl->n;
                dmax = fmax(dmax, dist[i]);
            }
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
        rp.n = cl->n;
        rp.x = cl->x;
        rp.y = cl->y;
        rp.z = cl->z;
        rp.value = dist;
        rp.vmax = RENDER_FAR_FRACTION * diag;
    }
    rgb = malloc(3 * (size_t)W * (size_t)H);
    if (!rgb) {
        fprintf(stderr, "frep render: out of memory for a %dx%d picture\n", W, H);
        goto done;
    }
    render_options ro = { W, H, view, { 0 } };
    memcpy(ro.bbox, bbox, sizeof bbox);
    if (render_mesh(&m, points ? &rp : NULL, &ro, rgb) != 0) {
        fprintf(stderr, "frep render: out of memory\n");
        goto done;
    }
    png_ctx pc = { rgb, W, H };
    if (cli_write_atomic(out, write_png_cb, &pc) != 0) goto done;
    if (!quiet) {
        printf("%s: %dx%d, %s view of %zu triangles", out, W, H, view, m.ntris);
        if (points)
            printf(", %zu points (distance to the surface: mean %.3g, max %.3g)", cl->n, dmean,
                   dmax);
        printf("\n");
    }
    rc = CLI_OK;
done:
    mesh_free(&m);
    cloud_free(cl);
    free(dist);
    free(rgb);
    mesh_cli_free(&mc);
    return rc;
}

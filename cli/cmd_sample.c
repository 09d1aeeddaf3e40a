/* cmd_sample.c - frep sample: a point cloud with normals from a model's surface (or
 * from a triangle mesh file), with optional noise and outliers (mesh/sample.c),
 * written as .xyz or PLY (geom/cloud.c).
 */
#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "mesh.h"
#include "meshio.h"
#include "sample.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static const char sample_usage[] =
    "usage: frep sample FILE.hf -n N -o CLOUD [options]\n"
    "       frep sample MESH.(off|obj|stl|ply) -n N -o CLOUD [options]\n\n"
    "Sample N points evenly over a model's surface f = 0 (inside the box), each with its\n"
    "outward unit normal -grad f/|grad f|: area-weighted points on a fine mesh, projected\n"
    "onto the surface by Newton steps. From a triangle mesh file: area-weighted points\n"
    "with the face normals. The same seed gives the same cloud at any thread count.\n"
    "CLOUD is .xyz text (x y z nx ny nz a line) or .ply (binary).\n\n"
    "Options:\n"
    "  -n, --points N      number of points, outliers included (required)\n"
    "  -o, --output CLOUD  file to write (required; '-' for .xyz on stdout)\n"
    "      --noise SIGMA   Gaussian noise on the positions: standard deviation SIGMA times\n"
    "                      the box diagonal (the mesh's bounding box for mesh input), or\n"
    "                      SIGMA in model units when written with the suffix 'abs' (0.01abs)\n"
    "      --outliers F    fraction F of the N points drawn uniformly in the box\n"
    "      --seed S        random seed (default: from the clock; always printed)\n"
    "  -m, --model NAME    the model (default: my_model, else the last one)\n"
    "  -a, --params LIST   values of the model's a[] array\n"
    "  -b, --box BOX       HyperFun's -b (default: the model's '-- @box', else 10)\n"
    "  -g, --grid N        grid of the sampling mesh (default: from N, 32..256)\n"
    "      --iso V         sample f = V\n"
    "      --setops S      override the file's set operations: rfunc, minmax\n"
    "  -t, --threads N     OpenMP threads\n"
    "  -q, --quiet         no summary line\n";

typedef struct cloud_write_ctx {
    const frep_cloud *c;
    const char *path;
} cloud_write_ctx;

static int write_cloud_cb(FILE *f, void *user)
{
    cloud_write_ctx *w = user;
    return cloud_write_for_path(f, w->c, w->path);
}

int cmd_sample(int argc, char **argv)
{
    static const struct option longopts[] = {
        { "help", no_argument, NULL, 'h' },
        { "points", required_argument, NULL, 'n' },
        { "output", required_argument, NULL, 'o' },
        { "noise", required_argument, NULL, 'N' },
        { "outliers", required_argument, NULL, 'O' },
        { "seed", required_argument, NULL, 's' },
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
    mc.grid = 0;
    sample_options so;
    sample_options_init(&so);
    so.n = 0;
    const char *out = NULL;
    int have_seed = 0, quiet = 0, c, rc;
    char *end;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "hn:o:m:a:b:g:t:q", longopts, NULL)) != -1) {
        rc = 0;
        switch (c) {
        case 'h': fputs(sample_usage, stdout); mesh_cli_free(&mc); return CLI_OK;
        case 'n': {
            errno = 0;
            double v = strtod(optarg, &end);
            if (*end || errno || !(v >= 1 && v <= (double)SAMPLE_MAX_POINTS) || v != floor(v))
                rc = cli_usage_error("sample", "-n: expected a point count in 1..%zu, got '%s'",
                                     (size_t)SAMPLE_MAX_POINTS, optarg);
            so.n = (size_t)v;
            break;
        }
        case 'o': out = optarg; break;
        case 'N':
            errno = 0;
            so.noise = strtod(optarg, &end);
            so.noise_absolute = strcmp(end, "abs") == 0;
            if ((*end && !so.noise_absolute) || errno || !(so.noise >= 0) || !isfinite(so.noise))
                rc = cli_usage_error("sample", "--noise: expected a number >= 0, optionally with "
                                     "the suffix 'abs', got '%s'", optarg);
            break;
        case 'O':
            errno = 0;
            so.outliers = strtod(optarg, &end);
            if (*end || errno || !(so.outliers >= 0 && so.outliers <= 1))
                rc = cli_usage_error("sample", "--outliers: expected a fraction in [0, 1], got '%s'",
                                     optarg);
            break;
        case 's':
            errno = 0;
            so.seed = strtoull(optarg, &end, 10);
            if (*end || errno || optarg[0] == '-')
                rc = cli_usage_error("sample", "--seed: expected a non-negative integer, got '%s'",
                                     optarg);
            have_seed = 1;
            break;
        case 'q': quiet = 1; break;
        default:
            rc = mesh_cli_option(&mc, "sample", c, optarg);
            if (rc == -1)
                rc = cli_usage_error("sample", "unknown or incomplete option '%s'", argv[optind - 1]);
        }
        if (rc != 0) {
            mesh_cli_free(&mc);
            return rc;
        }
    }
    if (argc - optind != 1) {
        mesh_cli_free(&mc);
        return cli_usage_error("sample", "expected one input: FILE.hf or a mesh file");
    }
    if (!out || so.n == 0) {
        mesh_cli_free(&mc);
        return cli_usage_error("sample", "-n N and -o CLOUD are required");
    }
    if (!have_seed) so.seed = (uint64_t)time(NULL);
    const char *in = argv[optind];
    frep_cloud *cl = NULL;
    char err[256];
    double t0 = (double)clock();
    if (meshio_format_for_path(in) != MESHIO_UNKNOWN) {
        frep_mesh m;
        frep_error msg;
        if (meshio_read(in, &m, &msg) != 0) {
            fprintf(stderr, "%s\n", msg.msg[0] ? msg.msg : "frep sample: cannot read the mesh");
            mesh_cli_free(&mc);
            return CLI_FAIL;
        }
        rc = sample_mesh(&m, &so, &cl, err, sizeof err);
        mesh_free(&m);
    } else {
        rc = mesh_cli_compile(&mc, in);
        if (rc != CLI_OK) {
            mesh_cli_free(&mc);
            return rc;
        }
        mesh_field f;
        if (mesh_field_program(&f, mc.p, NULL) != 0) {
            mesh_cli_free(&mc);
            fprintf(stderr, "frep sample: out of memory\n");
            return CLI_FAIL;
        }
        memcpy(so.mesh.box, mc.box, sizeof mc.box);
        so.mesh.grid = mc.grid;
        so.mesh.iso = mc.iso;
        so.mesh.nthreads = mc.nthreads;
        rc = sample_field(&f, &so, &cl, err, sizeof err);
        frep_runtime_error re;
        mesh_field_program_errors(&f, &re);
        mesh_cli_add_errors(&mc, &re);
        mesh_field_program_free(&f);
        mesh_cli_report_errors(&mc);
    }
    if (rc != 0) {
        fprintf(stderr, "frep sample: %s: %s\n", in, err);
        mesh_cli_free(&mc);
        return CLI_FAIL;
    }
    cloud_write_ctx w = { cl, out };
    rc = cli_write_atomic(out, write_cloud_cb, &w) == 0 ? CLI_OK : CLI_FAIL;
    if (rc == CLI_OK && !quiet) {
        FILE *sf = strcmp(out, "-") == 0 ? stderr : stdout;
        size_t nout = (size_t)floor(so.outliers * (double)so.n + 0.5);
        fprintf(sf, "%s: %zu points (%zu outliers), noise %g%s, seed %llu, %.2f s cpu\n", out,
                cl->n, nout, so.noise, so.noise_absolute ? " (absolute)" : " x box diagonal",
                (unsigned long long)so.seed, ((double)clock() - t0) / CLOCKS_PER_SEC);
    }
    cloud_free(cl);
    mesh_cli_free(&mc);
    return rc;
}

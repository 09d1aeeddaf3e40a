/* cmd_sample.c - frep sample: a point cloud with normals from a model's surface (or
 * from a triangle mesh file), with optional noise and outliers (frep_sample,
 * frep_sample_mesh), written as .xyz or PLY (frep_cloud_write_stream): on the public
 * API alone (frep.h).
 */
#include "config.h"

#include "cli.h"

#include <errno.h>
#include <math.h>
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
    "CLOUD is .xyz text (x y z nx ny nz a line) or .ply (binary).\n\n";

typedef struct sample_cmd {
    mesh_cli mc;
    frep_sample_options so;
    const char *in, *out;
    int quiet;
    frep_cloud *cl;
    double t0;               /* clock() when the input is read */
} sample_cmd;

/* --noise SIGMA or SIGMAabs (model units). */
static int parse_noise(const char *arg, void *dest, char *why, size_t whylen)
{
    frep_sample_options *so = dest;
    char *end;
    errno = 0;
    so->noise = strtod(arg, &end);
    so->noise_absolute = strcmp(end, "abs") == 0;
    return (*end && !so->noise_absolute) || errno || !(so->noise >= 0) || !isfinite(so->noise)
               ? -1 : 0;
}

#define OFF(f) offsetof(sample_cmd, f)
static const cli_opt sample_opts[] = {
    { 'n', "points", "N", CLI_OPT_SIZE, OFF(so.n), .lo = 1, .hi = (double)FREP_SAMPLE_MAX_POINTS,
      .what = "a point count", .help = "number of points, outliers included (required)" },
    { 'o', "output", "CLOUD", CLI_OPT_STRING, OFF(out),
      .help = "file to write (required; '-' for .xyz on stdout)" },
    { 0, "noise", "SIGMA", CLI_OPT_CUSTOM, OFF(so), .parse = parse_noise,
      .expect = "a number >= 0, optionally with the suffix 'abs'",
      .help = "Gaussian noise on the positions: standard deviation SIGMA times\n"
              "the box diagonal (the mesh's bounding box for mesh input), or\n"
              "SIGMA in model units when written with the suffix 'abs' (0.01abs)" },
    { 0, "outliers", "F", CLI_OPT_DOUBLE, OFF(so.outliers), .lo = 0, .hi = 1, .what = "a fraction",
      .help = "fraction F of the N points drawn uniformly in the box" },
    CLI_OPT_SEED(sample_cmd, so.seed, "random seed (default: from the clock; always printed)"),
    CLI_OPT_MAX_WORK(sample_cmd, mc.max_work),
    CLI_OPT_MODEL(sample_cmd, mc.model, "the model (default: my_model, else the first one)"),
    CLI_OPT_PARAMS(sample_cmd, mc.a, "values of the model's a[] array"),
    CLI_OPT_BOX(sample_cmd, mc.box, "HyperFun's -b (default: the model's '-- @box', else 10)"),
    CLI_OPT_GRID(sample_cmd, mc.grid, NULL, "grid of the sampling mesh (default: from N, 32..256)"),
    CLI_OPT_ISO(sample_cmd, mc.iso, "sample f = V"),
    CLI_OPT_SETOPS(sample_cmd, mc.setops, "override the file's set operations: rfunc, minmax"),
    CLI_OPT_STRICT(sample_cmd, mc.strict),
    CLI_OPT_THREADS(sample_cmd, mc.nthreads, "OpenMP threads"),
    CLI_OPT_QUIET(sample_cmd, quiet, "no summary line"),
};
#undef OFF
static const cli_opt_spec sample_spec = { "sample", sample_usage, sample_opts,
                                          sizeof sample_opts / sizeof sample_opts[0], 22 };

/* Options -> one input, -n and -o; the seed from the clock unless given. */
static int stage_options(sample_cmd *c, int argc, char **argv)
{
    cli_args args;
    int rc = mesh_cli_parse(&sample_spec, argc, argv, c, offsetof(sample_cmd, mc), &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error("sample", "expected one input: FILE.hf or a mesh file");
    if (!c->out || c->so.n == 0) return cli_usage_error("sample", "-n N and -o CLOUD are required");
    if (!cli_opt_given(&sample_spec, &args, "seed")) c->so.seed = (uint64_t)time(NULL);
    c->in = args.v[0];
    return CLI_GO_ON;
}

/* What the sampler reports: the model's runtime errors (with their position) at once,
 * as warnings with the source line; its error kept for sampled(). */
typedef struct sample_diag {
    sample_cmd *c;
    char error[512];
} sample_diag;

static void sample_diag_cb(void *user, const frep_diag *d)
{
    sample_diag *sd = user;
    if (d->file) {
        mesh_cli *mc = &sd->c->mc;
        cli_diag_ctx dc = { mc->src, mc->srclen, 0, 0, NULL, 0, mc->diag };
        cli_print_diag(&dc, d);
        cli_diag_done(&dc);
    } else if (d->severity == FREP_ERROR && !sd->error[0])
        snprintf(sd->error, sizeof sd->error, "%s", d->message);
}

/* The sampler's result -> the exit status, with its reason. */
static int sampled(const sample_cmd *c, const sample_diag *sd)
{
    if (c->cl) return CLI_OK;
    if (cli_interrupted())
        return cli_interrupt_status("sample", "stopped while sampling, nothing written");
    fprintf(stderr, "frep sample: %s: %s\n", c->in, sd->error[0] ? sd->error : "out of memory");
    return CLI_FAIL;
}

/* Area-weighted points on a mesh file's triangles. */
static int stage_sample_mesh(sample_cmd *c)
{
    frep_mesh *m = cli_mesh_read(c->in);
    if (!m) return CLI_FAIL;
    sample_diag sd = { c, "" };
    c->so.mesh.cancel_flag = cli_sigint_catch();
    c->cl = frep_sample_mesh(m, &c->so, sample_diag_cb, &sd);
    frep_mesh_free(m);
    return sampled(c, &sd);
}

/* Points on the model's surface, through the sampling mesh of the model's box. */
static int stage_sample_model(sample_cmd *c)
{
    mesh_cli *mc = &c->mc;
    int rc = mesh_cli_compile(mc, c->in);
    if (rc != CLI_OK) return rc;
    mesh_cli_options(mc, &c->so.mesh); /* grid 0 (no -g): from the point count */
    c->so.mesh.cancel_flag = cli_sigint_catch();
    sample_diag sd = { c, "" };
    c->cl = frep_sample(mc->p, &c->so, sample_diag_cb, &sd);
    if (frep_program_work_spent(mc->p) && !cli_interrupted()) {
        frep_cloud_free(c->cl);
        c->cl = NULL;
        return cli_work_check("sample", c->in, mc->p);
    }
    return sampled(c, &sd);
}

/* The summary line: on stderr when the cloud goes to stdout. */
static void stage_report(const sample_cmd *c)
{
    FILE *sf = strcmp(c->out, "-") == 0 ? stderr : stdout;
    size_t nout = (size_t)floor(c->so.outliers * (double)c->so.n + 0.5);
    fprintf(sf, "%s: %zu points (%zu outliers), noise %g%s, seed %llu, %.2f s cpu\n", c->out,
            frep_cloud_size(c->cl), nout, c->so.noise, c->so.noise_absolute ? " (absolute)" : " x box diagonal",
            (unsigned long long)c->so.seed, ((double)clock() - c->t0) / CLOCKS_PER_SEC);
}

/* sample (a mesh file or a model) -> write -> report */
static int sample_steps(sample_cmd *c)
{
    c->t0 = (double)clock();
    int rc = cli_is_mesh_path(c->in) ? stage_sample_mesh(c) : stage_sample_model(c);
    if (rc == CLI_OK) rc = cli_write_cloud(c->out, c->cl) == 0 ? CLI_OK : CLI_FAIL;
    if (rc == CLI_OK && !c->quiet) stage_report(c);
    return rc;
}

int cmd_sample(int argc, char **argv)
{
    sample_cmd c;
    memset(&c, 0, sizeof c);
    mesh_cli_init(&c.mc);
    frep_sample_options_init(&c.so);
    c.so.n = 0;
    int rc = stage_options(&c, argc, argv);
    if (rc == CLI_GO_ON) rc = sample_steps(&c);
    frep_cloud_free(c.cl);
    mesh_cli_free(&c.mc);
    return rc;
}

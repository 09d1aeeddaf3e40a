/* cmd_normals.c - frep normals: estimate the normals of a point cloud through the
 * public API (frep_normals(), api/api_normals.c), the first stage frep segment and frep
 * evolve run on a cloud without normals, on its own so that the estimate can be looked
 * at and reused.  Also the --knn option parser and the cloud checks the three commands
 * share.
 */
#include "config.h"

#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char normals_usage[] =
    "usage: frep normals CLOUD -o OUT.xyz|OUT.ply [options]\n\n"
    "Estimate unit normals for every point of CLOUD (.xyz or .ply; normals it has are\n"
    "replaced) as frep segment and frep evolve do on a cloud without normals: a plane\n"
    "fitted to the K nearest points with Gaussian weights, reweighted by its residuals\n"
    "so that points across a sharp edge lose their say; K chosen from the cloud's noise\n"
    "and spacing unless given. The normals are oriented consistently along a minimum\n"
    "spanning tree of the neighbour graph, then outward; then each smooth patch is\n"
    "checked by the parity of the crossings of lines cast along its normals (outward\n"
    "on a closed surface: even). Writes the points with their normals (6 columns) and\n"
    "prints the spacing, noise and K used.\n\n";

int cli_opt_knn(const char *arg, void *dest, char *why, size_t whylen)
{
    size_t *k = dest;
    if (strcmp(arg, "auto") == 0) {
        *k = 0;
        return 0;
    }
    char *end;
    long v = strtol(arg, &end, 10);
    if (end == arg || *end || v < FREP_NORMALS_MIN_KNN || v > FREP_NORMALS_MAX_KNN) {
        snprintf(why, whylen, "expected a neighbour count %d..%d or auto, got '%s'",
                 FREP_NORMALS_MIN_KNN, FREP_NORMALS_MAX_KNN, arg);
        return -1;
    }
    *k = (size_t)v;
    return 0;
}

/* A library message as "frep SUB: message". */
typedef struct sub_name {
    const char *sub;
} sub_name;

static void sub_diag(void *user, const frep_diag *d)
{
    const sub_name *s = user;
    cli_library_diag(s->sub, d);
}

int cli_check_cloud(const char *sub, const char *path, const frep_cloud *c, int need_solid)
{
    int planar = 0;
    sub_name sn = { sub };
    if (frep_cloud_check(c, path, &planar, sub_diag, &sn)) return CLI_FAIL;
    size_t n = frep_cloud_size(c);
    if (need_solid && planar) {
        fprintf(stderr, "frep %s: %s: all %zu points lie on one plane: they bound no solid\n",
                sub, path, n);
        return CLI_FAIL;
    }
    const double *nx, *ny, *nz;
    frep_cloud_arrays(c, NULL, NULL, NULL, &nx, &ny, &nz);
    if (nx) {
        size_t zero = 0;
        for (size_t i = 0; i < n; i++) {
            double l = nx[i] * nx[i] + ny[i] * ny[i] + nz[i] * nz[i];
            zero += !(l > 0) || !isfinite(l);
        }
        if (zero == n) {
            fprintf(stderr, "frep %s: %s: all %zu normals are zero: give the points alone "
                            "(3 columns) to have normals estimated, or see frep normals\n",
                    sub, path, n);
            return CLI_FAIL;
        }
    }
    return CLI_OK;
}

typedef struct normals_cmd {
    const char *in, *out;
    frep_normals_options o;
    int quiet;
} normals_cmd;

#define OFF(f) offsetof(normals_cmd, f)
static const cli_opt normals_opts[] = {
    { 'o', "output", "FILE", CLI_OPT_STRING, OFF(out),
      .help = "the cloud with its normals: .ply (binary), else .xyz text" },
    CLI_OPT_KNN(normals_cmd, o.knn),
    CLI_OPT_THREADS(normals_cmd, o.nthreads, "OpenMP threads (the result does not depend on it)"),
    CLI_OPT_QUIET(normals_cmd, quiet, "no summary"),
};
#undef OFF
static const cli_opt_spec normals_spec = { "normals", normals_usage, normals_opts,
                                           sizeof normals_opts / sizeof normals_opts[0], 24 };

/* read -> check -> estimate (Ctrl-C: nothing written) -> write (cli_write_cloud, whose
 * temporary the signal handler removes; PLY or .xyz by the output's name) -> summary */
static int normals_steps(normals_cmd *n, frep_cloud **cp)
{
    sub_name sn = { "normals" };
    frep_cloud *c = *cp = frep_cloud_read(n->in, sub_diag, &sn);
    if (!c) return CLI_FAIL;
    /* Normals in the file are replaced: zero ones are no error here. */
    if (frep_cloud_check(c, n->in, NULL, sub_diag, &sn)) return CLI_FAIL;
    n->o.cancel_flag = cli_sigint_catch();
    frep_normals_info info;
    double t0 = cli_now_seconds();
    int rc = frep_normals(c, &n->o, &info, sub_diag, &sn);
    double dt = cli_now_seconds() - t0;
    if (rc < 0) return CLI_FAIL;
    if (rc > 0) return cli_interrupt_status("normals", "nothing written");
    if (cli_write_cloud(n->out, c)) return CLI_FAIL;
    if (!n->quiet)
        fprintf(stderr, "frep normals: %zu points, spacing %.4g, noise %.4g, %zu neighbours%s, "
                        "%zu connected part%s (%zu turned outward), %.2f s\n",
                frep_cloud_size(c), info.spacing, info.noise, info.knn, n->o.knn ? "" : " (auto)",
                info.components, info.components == 1 ? "" : "s", info.flipped, dt);
    return CLI_OK;
}

int cmd_normals(int argc, char **argv)
{
    normals_cmd n;
    memset(&n, 0, sizeof n);
    frep_normals_options_init(&n.o);
    cli_args args;
    int rc = cli_opt_parse(&normals_spec, argc, argv, &n, &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1)
        return cli_usage_error("normals", args.n < 1 ? "missing CLOUD file" : "too many arguments");
    if (!n.out) return cli_usage_error("normals", "missing -o OUT");
    n.in = args.v[0];
    frep_cloud *c = NULL;
    rc = normals_steps(&n, &c);
    frep_cloud_free(c);
    return rc;
}

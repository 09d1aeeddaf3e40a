/* cmd_normals.c - frep normals: estimate the normals of a point cloud (geom/normals.c),
 * the first stage frep segment and frep evolve run on a cloud without normals, on its
 * own so that the estimate can be looked at and reused.  Also the --knn option parser
 * the three commands share.
 */
#include "config.h"

#include "cli.h"
#include "cloud.h"
#include "kdtree.h"
#include "normals.h"
#include "util.h"

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
    if (end == arg || *end || v < 3 || v > KD_MAX_K) {
        snprintf(why, whylen, "expected a neighbour count 3..%d or auto, got '%s'", KD_MAX_K, arg);
        return -1;
    }
    *k = (size_t)v;
    return 0;
}

int cli_check_cloud(const char *sub, const char *path, const frep_cloud *c, int need_solid)
{
    frep_error err;
    frep_error_init(&err);
    int planar = 0;
    if (cloud_check_scale(c, path, &err) || normals_check_cloud(c, path, &planar, &err)) {
        fprintf(stderr, "frep %s: %s\n", sub, err.msg);
        return CLI_FAIL;
    }
    if (need_solid && planar) {
        fprintf(stderr, "frep %s: %s: all %zu points lie on one plane: they bound no solid\n",
                sub, path, c->n);
        return CLI_FAIL;
    }
    if (c->has_normals) {
        size_t zero = 0;
        for (size_t i = 0; i < c->n; i++) {
            double l = c->nx[i] * c->nx[i] + c->ny[i] * c->ny[i] + c->nz[i] * c->nz[i];
            zero += !(l > 0) || !isfinite(l);
        }
        if (zero == c->n) {
            fprintf(stderr, "frep %s: %s: all %zu normals are zero: give the points alone "
                            "(3 columns) to have normals estimated, or see frep normals\n",
                    sub, path, c->n);
            return CLI_FAIL;
        }
    }
    return CLI_OK;
}

typedef struct normals_cmd {
    const char *in, *out;
    normals_config cfg;
    int quiet;
} normals_cmd;

#define OFF(f) offsetof(normals_cmd, f)
static const cli_opt normals_opts[] = {
    { 'o', "output", "FILE", CLI_OPT_STRING, OFF(out),
      .help = "the cloud with its normals: .ply (binary), else .xyz text" },
    CLI_OPT_KNN(normals_cmd, cfg.knn),
    CLI_OPT_THREADS(normals_cmd, cfg.nthreads, "OpenMP threads (the result does not depend on it)"),
    CLI_OPT_QUIET(normals_cmd, quiet, "no summary"),
};
#undef OFF
static const cli_opt_spec normals_spec = { "normals", normals_usage, normals_opts,
                                           sizeof normals_opts / sizeof normals_opts[0], 24 };

typedef struct write_ctx {
    const frep_cloud *c;
    const char *path;
} write_ctx;

static int write_cloud_cb(FILE *f, void *user)
{
    const write_ctx *w = user;
    return cloud_write_for_path(f, w->c, w->path);
}

int cmd_normals(int argc, char **argv)
{
    normals_cmd n;
    memset(&n, 0, sizeof n);
    normals_config_init(&n.cfg);
    cli_args args;
    int rc = cli_opt_parse(&normals_spec, argc, argv, &n, &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1)
        return cli_usage_error("normals", args.n < 1 ? "missing CLOUD file" : "too many arguments");
    if (!n.out) return cli_usage_error("normals", "missing -o OUT");
    n.in = args.v[0];
    frep_error err;
    frep_error_init(&err);
    frep_cloud *c = cloud_read(n.in, &err);
    if (!c) {
        fprintf(stderr, "frep normals: %s\n", err.msg[0] ? err.msg : "cannot read the cloud");
        return CLI_FAIL;
    }
    /* Normals in the file are replaced: zero ones are no error here. */
    if (cloud_check_scale(c, n.in, &err) || normals_check_cloud(c, n.in, NULL, &err)) {
        fprintf(stderr, "frep normals: %s\n", err.msg);
        cloud_free(c);
        return CLI_FAIL;
    }
    n.cfg.interrupt = cli_sigint_catch();
    normals_info info;
    double t0 = frep_now_seconds();
    rc = normals_run(c, &n.cfg, &info);
    double dt = frep_now_seconds() - t0;
    if (rc < 0) {
        fprintf(stderr, "frep normals: out of memory\n");
        cloud_free(c);
        return CLI_FAIL;
    }
    if (rc > 0) {
        cloud_free(c);
        return cli_interrupt_status("normals", "nothing written");
    }
    write_ctx w = { c, n.out };
    rc = cli_write_atomic(n.out, write_cloud_cb, &w) ? CLI_FAIL : CLI_OK;
    if (rc == CLI_OK && !n.quiet)
        fprintf(stderr, "frep normals: %zu points, spacing %.4g, noise %.4g, %zu neighbours%s, "
                        "%zu connected part%s (%zu turned outward), %.2f s\n",
                c->n, info.spacing, info.noise, info.knn, n.cfg.knn ? "" : " (auto)",
                info.components, info.components == 1 ? "" : "s", info.flipped, dt);
    cloud_free(c);
    return rc;
}

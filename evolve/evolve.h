/* evolve.h - the driver of `frep evolve`: from an oriented point cloud and fitted
 * primitives to a simplified construction tree, and from the tree to a readable .hf
 * model (and a Graphviz drawing).
 *
 * Pipeline: cloud + prims -> caches (fitness.c) -> partition.c or gp.c -> simplify.c
 * -> statistics on every point -> evolve_write_model().  cli/cmd_evolve.c is the
 * command around it.
 */
#ifndef FREP_EVOLVE_H
#define FREP_EVOLVE_H

#include <stddef.h>
#include <stdio.h>

#include "cloud.h"
#include "err.h"
#include "fitness.h"
#include "gp.h"
#include "partition.h"
#include "prim.h"
#include "support.h"

/* Defaults of the options that are not the GA's. */
#define EVOLVE_DEFAULT_EPS_REL 0.01     /* eps_d: 1% of the bounding-box diagonal (paper) */
#define EVOLVE_DEFAULT_ALPHA_DEG 10.0   /* normal tolerance; the paper uses 35 for noisy data */
/* Automatic alpha (doc/evolve.md, "Automatic alpha"): the paper's 35 degrees when the
 * cloud is noisy or faceted against the primitives, else 10. Noisy: the inliers'
 * robust position spread exceeds EVOLVE_NOISY_SIGMA x eps_d (0.05% of the diagonal: a
 * sampled surface is exact to 1e-6 eps_d, a scan is not), or their median normal
 * deviation exceeds EVOLVE_NOISY_DEG (gp_cache_noise). */
#define EVOLVE_NOISY_ALPHA_DEG 35.0
#define EVOLVE_NOISY_SIGMA 0.05
#define EVOLVE_NOISY_DEG 2.0
/* ... or when a tenth of them deviate by more than this (facetted curved surfaces
 * beside exact planes: InverseCSG's mount, 12-facet rails, p90 15 degrees, median 0;
 * its cuboid stacks: p90 0). */
#define EVOLVE_FACETED_P90_DEG 8.0
/* Points the GA scores at most: a uniform random subset keeps every surface patch
 * represented while each generation stays cheap; the final statistics and the
 * simplification use every point. */
#define EVOLVE_DEFAULT_SAMPLE 4096
/* The polish GA stops after this many generations without improvement (or the run's
 * --stagnation when smaller): it searches around a good tree, kept by elitism, where
 * the whole run's GA searches from random trees. (Real data, seed 1: 10, 20 and 40
 * give the same Chamfer distances; 40 lowers one Hausdorff distance, nine_cuboids',
 * from 7.3% to 4.0%, at twice the polish's time.) */
#define EVOLVE_POLISH_STAGNATION 15
/* Proxy boxes are grown by this many eps_d so that faces meeting at an edge overlap. */
#define EVOLVE_PROXY_MARGIN 2.0
/* The base model's value (--residual) where it cannot be evaluated: far outside, so
 * that the leaf explains nothing there and is not inside any part of the joined tree. */
#define EVOLVE_BASE_OUTSIDE (-1e30)
/* The clipping box is the cloud's oriented box grown by this fraction of the diagonal,
 * far enough not to cut the surface. */
#define EVOLVE_CLIP_MARGIN 0.02

typedef struct evolve_options {
    gp_config gp;            /* population, rates, seed, threads, max_time, setops */
    int partition;           /* 1: partition acceleration (falls back when useless) */
    size_t sample;           /* 0: all points */
    double eps_rel;
    double alpha_deg;        /* used when alpha_auto is 0 (and for --residual runs) */
    int alpha_auto;          /* 1 (default): alpha from the cloud's noise, see above */
    double lambda_scale;     /* lambda = lambda_scale * ln(N) per node */
    int simplify;            /* 1: simplify the result */
    int polish;              /* 1: after a partitioned run, a GA over all primitives
                                seeded with the merged tree (not in the paper) */
    uint32_t polish_stagnation; /* its stagnation limit (min with gp.stagnation) */
    int support;             /* 1: trim material no point supports (support.h) */
    /* --residual: the base model's value bf[i] and gradient bg[3i+c] at every cloud
     * point, and base_ok[i] = 1 where it could be evaluated (residual_eval), NULL
     * otherwise. The GA then runs on the points the base explains poorly (and those it
     * cannot evaluate), and its tree is joined to the base, which is leaf number nprims
     * of the result's tree; where the base cannot be evaluated the leaf's value is
     * EVOLVE_BASE_OUTSIDE with a zero gradient. */
    const double *base_f, *base_g;
    const uint8_t *base_ok;
} evolve_options;

void evolve_options_init(evolve_options *o);

typedef struct evolve_result {
    gp_tree tree;            /* PRIM j refers to the input primitive j */
    gp_stats stats;          /* on every (valid) point */
    double fitness;          /* on the scored sample */
    size_t npoints;          /* valid points */
    size_t dropped;          /* points with NaN/inf coordinates or no usable normal */
    size_t nsample;          /* points scored by the GA */
    double diag, eps_d, alpha;
    int alpha_auto;          /* 1: alpha was chosen from noise (below) */
    gp_noise noise;          /* the estimate behind it (valid when alpha_auto) */
    uint32_t generations;
    gp_stop stop;
    int partitioned;
    part_info part;
    double seconds;
    gp_obb obb;              /* oriented box of the cloud (not grown) */
    double box[6];           /* axis-aligned extent for the @box pragma (grown) */
    int residual;            /* 1: --residual run; leaf nprims is the base model */
    size_t nresidual;        /* valid points the base model explains poorly */
    support_info support;    /* the support trims (all 0 when not run) */
} evolve_result;

/* Run. The cloud must have normals. Returns 0, or -1 with err (may be NULL) set: bad
 * input (FREP_EINPUT: no primitives, no valid point; FREP_ELIMIT: too many primitives),
 * a run stopped before any tree was scored (FREP_ECANCEL), out of memory (FREP_ENOMEM).
 * fn (may be NULL) gets the progress and may stop the run; the best tree so far is
 * then kept. Free the result with evolve_result_free(). */
int evolve_run(const evolve_options *o, const frep_cloud *cloud, const prim *prims,
               size_t nprims, gp_progress_fn fn, void *user, evolve_result *res,
               frep_error *err);
void evolve_result_free(evolve_result *r);

/* Recompute r->stats of r->tree on every valid point (after the primitives changed,
 * e.g. by evolve_refit). r->eps_d and r->alpha must be set. 0 or -1 (memory). */
int evolve_stats(const evolve_options *o, const frep_cloud *cloud, const prim *prims,
                 size_t nprims, evolve_result *r);
/* --residual: mask[i] = 1 for the valid points the base model (o->base_f, o->base_g)
 * explains poorly, with the tolerances evolve_run uses; *count of them. 0 or -1. */
int evolve_residual_points(const evolve_options *o, const frep_cloud *cloud, uint8_t *mask,
                           size_t *count);

/* What the model's header comments say about the run. */
typedef struct evolve_meta {
    const char *command;     /* the command line (may be NULL) */
    const char *cloud;       /* cloud file name (may be NULL) */
    uint64_t seed;
    gp_setops setops;
    /* --residual: the base model (residual.h) written before the joined model, which
     * is then called my_model; NULL otherwise. */
    const struct evolve_base *base;
    const char *refit_note;  /* a comment line about --refit (may be NULL) */
    /* The cloud, for the check of the rounded model (may be NULL: rounding then stays
     * within CANON_MAX_SHIFT of the diagonal, evolve/canon.h). */
    const frep_cloud *points;
    int exact;               /* the primitives unchanged, every digit written */
    int hyperfun;            /* pure HyperFun: primitives as arithmetic of x */
    /* A stop flag (may be NULL) polled while the numbers are rounded and checked and
     * solids formed: once raised, every primitive not yet checked keeps its fitted
     * parameters and no further rewrite is tried, so the rest is written at once. */
    const volatile sig_atomic_t *cancel;
} evolve_meta;

/* The .hf model: primitives named pN after their input position, the tree with the
 * language's operators under the matching @setops, clipped by the cloud's oriented box;
 * comments with the figures; an @box pragma. Returns 0, or -1 on a write error. */
int evolve_write_model(FILE *f, const evolve_result *r, const prim *prims, size_t nprims,
                       const evolve_meta *m);
/* Graphviz drawing of the tree with primitive names and types. */
int evolve_write_dot(FILE *f, const evolve_result *r, const prim *prims, size_t nprims);

#endif

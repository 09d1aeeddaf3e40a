/* fitness.h - fitness of construction trees against an oriented point cloud
 * (Fayolle & Pasko 2016, eq. 7), over caches of primitive values and gradients.
 *
 * The cache is built once per run (or per clique) from the primitives; every tree is
 * then scored straight from its bytecode in blocks of points without evaluating a
 * primitive again.  Used by gp.c, simplify.c, partition.c and evolve.c.
 */
#ifndef FREP_GP_FITNESS_H
#define FREP_GP_FITNESS_H

#include <stddef.h>
#include <stdint.h>

#include "tree.h"

/* Points scored per block: the evaluation stack (value, gradient, active primitive)
 * of a deep tree stays in the L2 cache. */
#define GP_FIT_BLOCK 256

/* Score tables, caches: immutable once built, shared by all threads. */
typedef struct gp_cache {
    size_t n;            /* points */
    uint32_t nprims;
    gp_setops setops;
    double *v;           /* v[j*n + i]: value of primitive j at point i */
    double *g;           /* g[(3*j + c)*n + i]: gradient component c */
    double *nrm;         /* nrm[3*i + c]: unit outward normal of point i */
    /* score[(2*j + s)*n + i]: the term exp(-d^2) + exp(-theta^2) of point i when the
     * tree's value there is primitive j (s = 0) or its complement (s = 1); min/max
     * trees take their value and gradient from one primitive at every point, so their
     * fitness is a sum of table entries. Valid when setops == GP_SETOPS_MINMAX. */
    float *score;
    float *vf;           /* v in single precision for the min/max comparisons (half the
                            memory traffic); valid when setops == GP_SETOPS_MINMAX */
    double eps_d;        /* distance tolerance (0.01 x bounding-box diagonal) */
    double alpha;        /* angle tolerance, radians */
    double lambda;       /* size penalty per node */
} gp_cache;

/* Build a cache from primitive values/gradients computed by the caller:
 * v[j*n+i], g[(3j+c)*n+i] (the cache takes ownership of both malloc'ed arrays, also on
 * failure), normals nrm[3i+c] (copied; normalised here). lambda < 0: ln(n).
 * Returns NULL on allocation failure. */
gp_cache *gp_cache_new(size_t n, uint32_t nprims, gp_setops s, double *v, double *g,
                       const double *nrm, double eps_d, double alpha, double lambda);
/* The cache restricted to points idx[0..m) and primitives prims[0..k) (renumbered
 * 0..k-1); lambda < 0: ln(m). */
gp_cache *gp_cache_subset(const gp_cache *c, const size_t *idx, size_t m,
                          const uint32_t *prims, uint32_t k, double lambda);
void gp_cache_free(gp_cache *c);

/* Per-thread evaluation state. */
typedef struct gp_eval gp_eval;
gp_eval *gp_eval_new(void);
void gp_eval_free(gp_eval *e);

/* Raw score sum_i exp(-d_i^2) + exp(-theta_i^2) of a tree (no size penalty). NaN on
 * allocation failure. Deterministic: the same tree gives the same bits on any thread. */
double gp_score(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len);
/* Fitness (eq. 7): score - lambda * len. */
double gp_fitness(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len);

/* How well a tree explains the points. */
typedef struct gp_stats {
    double score, fitness;
    size_t within_eps;   /* points with |f| < eps_d */
    size_t normals_ok;   /* points whose normal is within alpha of -grad f */
    size_t explained;    /* both */
} gp_stats;
int gp_tree_stats(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                  gp_stats *st);
/* Per point: 1 when explained (within eps and normal agrees). ok[n]. */
int gp_explained(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                 uint8_t *ok);

#endif

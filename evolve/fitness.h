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
/* The crossing test (doc/evolve.md, "Fitness"): a point with |f| < eps_d counts only
 * when f(x - h n) > -tol and f(x + h n) < tol, h = GP_CROSS_H x eps_d, tol =
 * GP_CROSS_TOL x eps_d. With h = eps_d a correct boundary anywhere in that band passes
 * (the offsets reach the other side); the tolerance lets pass points that noise put
 * just beyond a neighbouring face at an edge, and walls or gaps thicker than h - tol.
 * A sheet (|f| = h |g.n| at both offsets) fails while the normal is within 60 degrees
 * of its gradient. */
#define GP_CROSS_H 1.0
#define GP_CROSS_TOL 0.5
/* 64-bit words of one block's bit masks (the crossing test). */
#define GP_FIT_WORDS (GP_FIT_BLOCK / 64)

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
    /* tail[b]: an upper bound of the score of the points from block b (GP_FIT_BLOCK
     * points each) to the end, b = 0..nblocks: the sum of each point's largest table
     * entry, since a min/max tree scores at most that at the point (R-functions: 2 per
     * point, each exp term being at most 1). A search that only wants trees above a
     * floor stops scoring one once the blocks scored plus this bound fall below it
     * (gp_fitness_replaced). NULL for the caches of gp_cache_new_stats and
     * gp_cache_values, which are not scored. */
    double *tail;
    /* The crossing test (above): a point on the tree's zero set counts only when the
     * field changes sign across it along the point's normal, so a zero-thickness sheet
     * (max(p, -p) = |p|, whose zero set is a plane but which is inside on both sides)
     * explains nothing. side[(4*j + r)*nw + i/64], bit i%64, for the first-order value
     * q = v + s h g.n of primitive j at point i: r = 0: q > tol at the outer point
     * (s = 1); r = 1: q > -tol there; r = 2, 3: the same at the inner point (s = -1).
     * Whether a min/max tree exceeds a threshold is a Boolean function of whether its
     * leaves exceed it or its negative (max(a, b) > t iff a > t or b > t; -a > t iff
     * not a >= -t), so each offset is a few word operations per node and 64 points. R0
     * functions lie beyond min/max (union >= max, intersection <= min) and use the
     * same logic. */
    uint64_t *side;
    size_t nw;           /* words per row of side: ceil(n / 64) */
    int crossing;        /* 1 (default): apply the crossing test; 0: plain eq. 7 */
    int values_only;     /* 1: gp_cache_values (no normals, tables or crossing bits) */
    double eps_d;        /* distance tolerance (0.01 x bounding-box diagonal) */
    double alpha;        /* angle tolerance, radians */
    double lambda;       /* size penalty per node */
} gp_cache;

/* Build a cache from primitive values/gradients computed by the caller (crossing test
 * on):
 * v[j*n+i], g[(3j+c)*n+i] (the cache takes ownership of both malloc'ed arrays, also on
 * failure), normals nrm[3i+c] (copied; normalised here). lambda < 0: ln(n).
 * Returns NULL on allocation failure. */
gp_cache *gp_cache_new(size_t n, uint32_t nprims, gp_setops s, double *v, double *g,
                       const double *nrm, double eps_d, double alpha, double lambda);
/* gp_cache_new without the score tables, for gp_tree_stats and gp_explained only
 * (they score each point from the tree's value and gradient): the exp and acos of
 * 2 x nprims terms per point are left out. Min/max scores on it are NaN (R-function
 * scores need no tables). */
gp_cache *gp_cache_new_stats(size_t n, uint32_t nprims, gp_setops s, double *v, double *g,
                             const double *nrm, double eps_d, double alpha, double lambda);
/* A cache for the values of trees only (gp_tree_values, tapes, gp_values_*), at points
 * that have no normals (a grid): v and g as in gp_cache_new (taken, also on failure),
 * no score tables or crossing bits; every score on it is 0. NULL on allocation failure. */
gp_cache *gp_cache_values(size_t n, uint32_t nprims, gp_setops s, double *v, double *g);
/* The cache restricted to points idx[0..m) and primitives prims[0..k) (renumbered
 * 0..k-1); lambda < 0: ln(m). */
gp_cache *gp_cache_subset(const gp_cache *c, const size_t *idx, size_t m,
                          const uint32_t *prims, uint32_t k, double lambda);
void gp_cache_free(gp_cache *c);
/* Change the angle tolerance (radians): the score tables are rebuilt. 0 or -1. */
int gp_cache_set_alpha(gp_cache *c, double alpha);

/* Normals further than this from a primitive's are not its inliers in the noise
 * estimate: beyond it a point belongs to another surface (an edge, a distractor), not
 * to this one with a noisy normal. */
#define GP_NOISE_MAX_DEG 45.0

/* How noisy the cloud is against the primitives (the automatic alpha of evolve.c):
 * each point's inlier primitive is the one with the smallest |f| among those with
 * |f| < eps_d and the normal within GP_NOISE_MAX_DEG of its own. */
typedef struct gp_noise {
    size_t inliers;      /* points with an inlier primitive */
    double sigma_d;      /* 1.4826 x median |f| of the inliers / eps_d: a robust standard
                            deviation of the positions against the surfaces */
    double p90_deg;      /* 90th percentile of those angles: a coarsely facetted part
                            (a tenth of the points on cylinders of 12 facets) shows
                            here while planes hold the median at 0 */
    double median_deg;   /* median angle between the inliers' normals and the
                            primitives' (degrees) */
} gp_noise;
/* Returns 0, or -1 on allocation failure. */
int gp_cache_noise(const gp_cache *c, gp_noise *out);

/* Per-thread evaluation state. */
typedef struct gp_eval gp_eval;
gp_eval *gp_eval_new(void);
void gp_eval_free(gp_eval *e);

/* Raw score sum_i exp(-d_i^2) + exp(-theta_i^2) of a tree (no size penalty) in *score,
 * where a point with |f| < eps_d across which the field does not change sign (crossing
 * test) scores 0. Deterministic: the same tree gives the same bits on any thread (NaN
 * only when the primitives are NaN at a point). 0, or -1 on allocation failure or
 * misuse (an empty tree; a min/max cache of gp_cache_new_stats). */
int gp_score(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len, double *score);
/* Fitness (eq. 7): score - lambda * len, in *fitness. 0 or -1, as gp_score. */
int gp_fitness(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
               double *fitness);

/* How well a tree explains the points. */
typedef struct gp_stats {
    double score, fitness;
    size_t within_eps;   /* points with |f| < eps_d, except those failing the crossing
                            test (on a sheet, not a boundary) */
    size_t normals_ok;   /* points whose normal is within alpha of -grad f */
    size_t explained;    /* both */
} gp_stats;
int gp_tree_stats(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                  gp_stats *st);
/* The same over c's points added to *acc (score and counts; fitness is acc's score less
 * c's lambda x len): a cloud scored by parts whose sizes are multiples of GP_FIT_BLOCK
 * gets the very numbers of one cache of all its points (the blocks are summed in the
 * same order). */
int gp_tree_stats_add(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                      gp_stats *acc);
/* Per point: 1 when explained (within eps and normal agrees). ok[n]. */
/* The tree's value at every point of c: out[0..c->n) (min/max: the value of the active
 * primitive, as scored). 0 or -1 (allocation). */
int gp_tree_values(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                   double *out);
int gp_explained(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                 uint8_t *ok);

/* ---- Tapes: scoring a tree with one subtree replaced ----
 *
 * The simplifier and the merge of partition.c score hundreds of variants of one tree,
 * each differing from it in one subtree. gp_tape_record evaluates the tree once and
 * keeps every node's stack entry (min/max: value and active primitive; R-functions:
 * value and gradient; the crossing bits) at every point of the cache, in the gp_eval.
 * A variant is then scored from the replacement and the path from it to the root, the
 * subtrees off the path read from the tape as "tape leaves" (PRIM nprims + node): a
 * few nodes instead of the whole tree, with the same bits as gp_fitness of the
 * variant, since min/max select and R-functions compute the same numbers in the same
 * order. A replacement may itself hold tape leaves (an operand of the tree joined
 * elsewhere). The tape belongs to the gp_eval: any gp_tape_record on it replaces it. */

/* Bytes a tape keeps at most (per gp_eval): a node-point cell takes 8 bytes with
 * min/max and 32 with R-functions, plus half a byte of crossing bits. Beyond it the
 * tree is kept without values and replacements are scored in full. */
#define GP_TAPE_MAX_BYTES ((size_t)128 << 20)
/* The node-point cells that makes for the family s. */
size_t gp_tape_max_cells(gp_setops s);

/* Record code on c in e's tape; its score (gp_score) in *score. 0 or -1 (allocation;
 * the tape is then empty). */
int gp_tape_record(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                   double *score);
/* Score (no size penalty) of code whose tape leaves refer to e's tape, in *score. The
 * tape may have been recorded from a forest (several trees one after the other: their
 * nodes are all recorded). floor: as in gp_fitness_replaced, on the score. 0, or -1 on
 * allocation failure or when the tape holds no values for c (gp_tape_valued). */
int gp_score_taped(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                   double floor, double *score);
/* 1 when e's tape holds node values recorded on c. */
int gp_tape_valued(const gp_cache *c, const gp_eval *e);
/* The leaf standing for the recorded tree's subtree ending at node. */
frep_insn gp_tape_leaf(const gp_cache *c, uint32_t node);
/* Fitness (eq. 7, the size penalty on the expanded length) of the recorded tree with
 * its subtree [st, end] replaced by sub[0..nsub), in *fitness. 0, or -1 on allocation
 * failure or when nothing is recorded on c.
 * floor: searches keep a variant only when it beats a fitness (the best so far, the
 * tree's own); a variant that cannot reach floor is left as soon as gp_cache.tail
 * shows it and *fitness is -HUGE_VAL (a bound, below floor). Every fitness at or above
 * floor is exact, so the searches choose as with full scores. -HUGE_VAL: always exact. */
int gp_fitness_replaced(const gp_cache *c, gp_eval *e, uint32_t st, uint32_t end,
                        const frep_insn *sub, uint32_t nsub, double floor, double *fitness);
/* The tree's value at every point of c (out[0..c->n)) with the subtree [st, end] of
 * the recorded tree replaced by sub, as gp_tree_values. 0 or -1. */
int gp_values_replaced(const gp_cache *c, gp_eval *e, uint32_t st, uint32_t end,
                       const frep_insn *sub, uint32_t nsub, double *out);
/* The values of code whose tape leaves refer to e's tape (recorded on c), as
 * gp_tree_values. 0 or -1. */
int gp_values_taped(const gp_cache *c, gp_eval *e, const frep_insn *code, uint32_t len,
                    double *out);
/* The same as gp_tree_stats. 0 or -1. */
int gp_stats_replaced(const gp_cache *c, gp_eval *e, uint32_t st, uint32_t end,
                      const frep_insn *sub, uint32_t nsub, gp_stats *st_out);
/* out = sub with its tape leaves expanded to the recorded subtrees. 0 or -1. */
int gp_tape_expand(const gp_cache *c, const gp_eval *e, const frep_insn *sub, uint32_t nsub,
                   gp_tree *out);

#endif

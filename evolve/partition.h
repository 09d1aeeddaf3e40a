/* partition.h - the partition acceleration of `frep evolve` (Friedrich, Feld, Phan,
 * Fayolle, WSCG 2018): a primitive overlap graph from bounded proxies (oriented boxes
 * of the inliers), its maximal cliques (Bron-Kerbosch with pivoting), one small GA per
 * clique, then a merge of the clique trees through their largest common subtree.
 * Sits between evolve.c (driver) and gp.c / simplify.c.
 */
#ifndef FREP_GP_PARTITION_H
#define FREP_GP_PARTITION_H

#include <stddef.h>
#include <stdint.h>

#include "fitness.h"
#include "gp.h"
#include "tree.h"

/* Most maximal cliques enumerated before giving up partitioning (a dense graph has
 * exponentially many; the unpartitioned GA is then the better choice). */
#define PART_MAX_CLIQUES 4096
/* Most primitives the bitset graph takes (words of 64 bits per row). */
#define PART_MAX_PRIMS 65536
/* Cliques of at most this many primitives are solved by trying every tree that uses
 * each primitive once (1,180 trees for four, 26,880 for five: there the GA is
 * cheaper); larger ones by a GA. */
#define PART_EXHAUSTIVE_MAX 4

/* An oriented box: centre, orthonormal axes ax[k], half sizes h[k]. */
typedef struct gp_obb {
    double c[3], ax[3][3], h[3];
    int valid;          /* 0: no proxy (overlaps everything) */
} gp_obb;

/* Box of the points idx[0..m) (all points when idx == NULL, m = n): axes from the
 * covariance (PCA), extents from the points. valid = 0 when m == 0. */
void part_obb_of_points(const double *x, const double *y, const double *z,
                        const size_t *idx, size_t m, gp_obb *b);
/* Separating-axis test of two boxes, each grown by `margin` on every side. Invalid
 * boxes overlap everything. */
int part_obb_overlap(const gp_obb *a, const gp_obb *b, double margin);
int part_obb_contains(const gp_obb *b, const double p[3], double margin);

/* Undirected graph as bit rows: bit j of row i set when i and j overlap. */
typedef struct gp_graph {
    uint32_t n, words;
    uint64_t *adj;      /* n * words */
} gp_graph;

/* Overlap graph of n boxes grown by margin. Candidate pairs come from a sweep over
 * the boxes' x extents (sort and sweep) instead of all pairs. 0 or -1 (allocation). */
int part_overlap_graph(const gp_obb *boxes, uint32_t n, double margin, gp_graph *g);
void part_graph_free(gp_graph *g);
int part_graph_has(const gp_graph *g, uint32_t i, uint32_t j);
void part_graph_set(gp_graph *g, uint32_t i, uint32_t j);

/* Maximal cliques in compressed rows: clique q is members[start[q] .. start[q+1]). */
typedef struct gp_cliques {
    uint32_t count;
    uint32_t *start;    /* count + 1 */
    uint32_t *members;  /* ascending within a clique */
} gp_cliques;

/* All maximal cliques (Bron-Kerbosch with Tomita pivoting), in a deterministic order.
 * Returns 0, 1 when there are more than max_cliques (out is then empty), -1 on
 * allocation failure. */
int part_cliques(const gp_graph *g, uint32_t max_cliques, gp_cliques *out);
void part_cliques_free(gp_cliques *c);

/* 1 when the subtree ending at `target` sits in `code` (root at len-1) below unions
 * and first operands of subtractions only, so replacing it by a tree that contains it
 * keeps the rest of the shape. */
int part_graft_valid(const frep_insn *code, uint32_t len, uint32_t target);
/* Largest subtree common to a and b (structural equality): its ends in a and b and
 * its length (0 when the trees share no primitive). */
uint32_t part_largest_common(const gp_tree *a, const gp_tree *b, uint32_t *ea,
                             uint32_t *eb);

/* Merge two trees over the same primitive numbering, choosing by fitness on c among:
 * grafts of one into the other at their largest common subtree (where valid), a | b
 * and a & b; the winner is simplified. Returns 0 or -1. */
int part_merge_pair(const gp_tree *a, const gp_tree *b, gp_setops s, const gp_cache *c,
                    gp_eval *e, gp_tree *out, double *fitness, gp_cancel *k);

/* The best tree for a clique of at most PART_EXHAUSTIVE_MAX primitives (c's), by
 * trying every tree over a non-empty subset of them that uses each once, with the four
 * set operations (a | b, a & b, a \ b, b \ a) at every node: 4 trees over two
 * primitives, 48 over three, 960 over four (1,180 in all for a clique of four). The
 * fittest goes to *t (ties: the first enumerated, subsets by size, so the shortest).
 * Trees with a primitive twice or with a complement are left out: a solid built from
 * the primitives once each, as CAD parts are, is in the set. 0, or -1 on allocation
 * failure or too many primitives. */
int part_exhaustive(gp_setops s, const gp_cache *c, gp_eval *e, gp_tree *t);

/* Statistics of a partitioned run. */
typedef struct part_info {
    uint32_t nedges, ncliques, largest;  /* graph and clique figures */
    int partitioned;     /* 0: fell back (one clique, too many cliques) */
    uint32_t generations;/* sum over the cliques' GAs */
    uint32_t polish_generations; /* of the seeded GA after the merge (evolve.c) */
} part_info;

/* The whole acceleration on cache c, whose points are x/y/z[0..c->n), with proxy
 * boxes[0..c->nprims) grown by margin. On success with info->partitioned == 1 the
 * merged, simplified tree is in res (global primitive numbers); with 0 the caller
 * runs the unpartitioned GA. Cliques run in parallel, each GA on one thread, seeded
 * from cfg->seed and the clique number. fn gets the merged progress (may be NULL).
 * Returns 0 or -1. */
int part_run(const gp_config *cfg, const gp_cache *c, const double *x, const double *y,
             const double *z, const gp_obb *boxes, double margin, gp_progress_fn fn,
             void *user, gp_result *res, part_info *info);

#endif

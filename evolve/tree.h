/* tree.h - construction trees of `frep evolve` as postfix bytecode (frep_insn arrays).
 *
 * A GP tree is straight-line code whose leaves are PRIM j and whose nodes are the set
 * operations of one family (min/max: MAX MIN MSUB NEG; R-functions: RUNI RINT RSUB NEG).
 * Every subtree is a contiguous instruction range, so the GP engine (gp.c), the
 * simplifier and the merge of partition.c edit trees by splicing ranges with memmove.
 */
#ifndef FREP_GP_TREE_H
#define FREP_GP_TREE_H

#include <stdint.h>

#include "rng.h"
#include <stdio.h>

#include "buf.h"

#include "program.h"

/* Deepest tree any tree operation accepts: recursion (printing, comparison) is bounded
 * by it, and merged trees of many cliques stay far below it. */
#define GP_MAX_TREE_DEPTH 1024
/* Longest tree, so that lengths and pcs fit uint32_t with room to splice two trees. */
#define GP_MAX_TREE_LEN (1u << 24)
/* Largest random tree tree_grow makes: a tree of depth D may have 2^D leaves, so at
 * --max-depth 64 (or p_subtree 1) growth would otherwise never end; past this size
 * the nodes still to grow are leaves. */
#define GP_MAX_GROW_NODES (1u << 12)
/* Longest child of a crossover or mutation: a longer one is cancelled (the parent is
 * kept), so bloat under a deep --max-depth stops here instead of exhausting memory. */
#define GP_MAX_BRED_LEN (1u << 16)

/* Set-operation family of the trees. */
typedef enum gp_setops {
    GP_SETOPS_MINMAX,   /* max = union, min = intersection, min(a,-b) = subtraction */
    GP_SETOPS_RFUNC     /* Rvachev R0 functions */
} gp_setops;

/* The opcodes of one family. */
typedef struct gp_opset {
    uint8_t uni, inter, sub, neg;
} gp_opset;

gp_opset gp_opset_of(gp_setops s);

/* Deterministic random numbers (xoshiro256**): one generator per independent stream,
 * never shared between threads. */
typedef frep_rng gp_rng;                         /* runtime/rng.h */

void gp_rng_seed(gp_rng *r, uint64_t seed);
uint64_t gp_rng_next(gp_rng *r);
double gp_rng_unif(gp_rng *r);                 /* [0, 1) */
uint32_t gp_rng_below(gp_rng *r, uint32_t n);  /* [0, n), n >= 1 */

/* A growable tree. len instructions of code[0..cap). An empty tree has len 0. */
typedef struct gp_tree {
    frep_insn *code;
    uint32_t len, cap;
} gp_tree;

/* Returns 0, or -1 on allocation failure (the tree is unchanged). */
int tree_reserve(gp_tree *t, uint32_t cap);
void tree_free(gp_tree *t);
int tree_copy(gp_tree *dst, const gp_tree *src);
int tree_set(gp_tree *dst, const frep_insn *code, uint32_t len);
int tree_push(gp_tree *t, frep_opcode op, uint32_t arg);

/* Operands of a GP node (0 leaf, 1 NEG, 2 binary set operation). */
int tree_nin(const frep_insn *in);
/* First pc of the subtree ending at `end`. */
uint32_t tree_subtree_start(const frep_insn *code, uint32_t end);
/* Operand ranges of the binary node at `end`: left [*l0, *l1], right [*r0, end-1]. */
void tree_operands(const frep_insn *code, uint32_t end, uint32_t *l0, uint32_t *l1,
                   uint32_t *r0);
/* Depth of the tree (a leaf has depth 1), GP_MAX_TREE_DEPTH + 1 for any deeper one;
 * 0 for an empty tree. */
int tree_depth(const frep_insn *code, uint32_t len);
/* Level of each node (root 1) into lev[len]; 0, or -1 when out of memory. */
int tree_levels(const frep_insn *code, uint32_t len, uint16_t *lev);
/* 1 when the code is a well-formed GP tree over nprims primitives of family s. */
int tree_valid(const frep_insn *code, uint32_t len, uint32_t nprims, gp_setops s);
/* Number of distinct primitives used. */
uint32_t tree_count_prims(const frep_insn *code, uint32_t len, uint32_t nprims);

/* Replace the range [s0, s1] of t by src[0..n). Returns 0 or -1 (allocation). */
int tree_splice(gp_tree *t, uint32_t s0, uint32_t s1, const frep_insn *src, uint32_t n);

/* Append a random tree grown as in Fayolle & Pasko 2016: each node becomes an
 * operation with probability p_sub while the depth allows (max_depth >= 1) and the
 * tree is shorter than GP_MAX_GROW_NODES, else a leaf with a uniformly chosen
 * primitive. */
int tree_grow(gp_tree *t, gp_rng *r, gp_setops s, uint32_t nprims, int max_depth,
              double p_sub);

/* Subtree crossover: child = a with a random subtree replaced by a random subtree of
 * b. Returns 1 when done, 0 when cancelled because the child would be deeper than
 * max_depth or longer than GP_MAX_BRED_LEN (child is then a copy of a), -1 on
 * allocation failure. */
int tree_crossover(gp_tree *child, const gp_tree *a, const gp_tree *b, gp_rng *r,
                   int max_depth);
/* Mutation: with probability 1/2 a whole new tree, else a random subtree replaced by
 * a new random one that keeps the depth within max_depth (t unchanged when the result
 * would be longer than GP_MAX_BRED_LEN). */
int tree_mutate(gp_tree *t, gp_rng *r, gp_setops s, uint32_t nprims, int max_depth,
                double p_sub);

/* Structural comparison of two subtrees (ranges ending at ea / eb): <0, 0, >0. */
int tree_compare(const frep_insn *a, uint32_t ea, const frep_insn *b, uint32_t eb);
/* 64-bit hash of a code range. */
uint64_t tree_hash(const frep_insn *code, uint32_t len);

/* Append the tree infix to b with primitive names `prefix`1.. (p1 | p2) & ~p3. The
 * operators are those of the language: | & \ ~ (their meaning set by the model's
 * setops). A failed allocation marks b failed (buf.h). */
void tree_print(frep_buf *b, const frep_insn *code, uint32_t len, const char *prefix);
/* Graphviz digraph of the tree; names[j] labels primitive j (NULL: pJ). */
void tree_print_dot(FILE *f, const frep_insn *code, uint32_t len,
                    const char *const *names);

/* The primitives t uses, ascending, into *out (malloc'ed; NULL and 0 on allocation
 * failure). nprims: the leaves' range. */
uint32_t tree_used_prims(const gp_tree *t, uint32_t nprims, uint32_t **out);
/* Renumber the PRIM leaves of t: global -> local through the ascending list
 * prims[0..k) (dir = 0; every leaf must be in it), or local -> global (dir = 1). */
void tree_renumber(gp_tree *t, const uint32_t *prims, uint32_t k, int dir);

#endif

/* simplify.h - simplification of construction trees found by `frep evolve`:
 * exact rewrite rules (p & p -> p, ~~p -> p, a & ~b -> a \ b, ...) and the removal of
 * every node whose removal does not lower the fitness (Fayolle & Pasko 2016, 5.4).
 * Used on each GP result, on merged partition trees (partition.c) and by evolve.c.
 */
#ifndef FREP_GP_SIMPLIFY_H
#define FREP_GP_SIMPLIFY_H

#include "fitness.h"
#include "gp.h"
#include "tree.h"

/* Cancellation (k, gp.h; may be NULL): the fitness-guarded searches below poll it
 * between candidates and, once it is raised, stop with the tree as it stands, every
 * step taken so far kept (each keeps the fitness from falling), and *fitness its
 * fitness. */

/* Apply the identities, exact for min/max and for R0 functions alike, until none
 * applies; commutative operands are put in a canonical order, so that equal subtrees
 * are equal code. Returns 0 or -1 (allocation; t unchanged then). */
int simplify_rules(gp_tree *t, gp_setops s);

/* Rules, then fitness-guarded moves on `c` until none applies: a node replaced by one
 * of its operands, or an operand replaced by one of its own operands under any of the
 * three operations, when the fitness does not decrease; then a hill climb joining one
 * primitive at the root while that raises the fitness, each time followed by the
 * removal moves again. *fitness (may be NULL) receives the final fitness. */
int simplify_tree(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e, double *fitness,
                  gp_cancel *k);
/* simplify_tree with the removal moves tried from the root down (simplify_tree's
 * order: the largest removals first) and, on a copy, from the leaves up; the fitter
 * result (ties: the shorter, then the first). The greedy removals of one order can
 * drop the part that another part made redundant and keep the wrong one: a merged tree
 * with a pocket both as its clique trees built it, through (a clique without the
 * pocket's floor) and complete, keeps the complete one only from the leaves up. */
int simplify_tree_both(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                       double *fitness, gp_cancel *k);

/* The first step of simplify_grow_pieces (below) alone: while that raises the fitness
 * (at most 16 times), the best S & p, S \ p or S | p replacing any subtree S, each
 * followed by simplify_tree (evolve.c runs it once more on a larger sample).  *fitness
 * (may be NULL) receives the final fitness. 0 or -1 (allocation). */
int simplify_grow_inner(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                        double *fitness, gp_cancel *k);

/* The second step of simplify_grow_pieces (below) alone: while that raises the fitness
 * (at most 3 times), the best pocket or box cut replacing any subtree S, each followed
 * by simplify_tree (evolve.c runs it once more on a larger sample).  *fitness (may be
 * NULL) receives the final fitness. 0 or -1 (allocation). */
int simplify_grow_pockets(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                          double *fitness, gp_cancel *k);

/* While that raises the fitness (at most 8 times), the best leaf replaced by another
 * primitive j with fitted[j] set, explaining at least 2 points the tree misses, each
 * swap followed by simplify_tree (evolve.c runs it on its final, larger sample).
 * *fitness (may be NULL) receives the final fitness. 0 or -1 (allocation). */
int simplify_swap_leaves(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                         const uint8_t *fitted, double *fitness, gp_cancel *k);

/* After simplify_tree: first, while that raises the fitness (at most 16 times), the
 * best S & p, S \ p or S | p replacing any subtree S, p a primitive explaining points
 * the tree misses (a face missing from one part of a union, which cannot be added at
 * the root without cutting the other parts). Then, while that raises the fitness (at
 * most 3 times), the best pocket S & (L1 | ... | Lm) replacing any subtree S,
 * 2 <= m <= 4, Li a primitive or its complement as its missed points say, the faces
 * chosen among the 8 primitives explaining the most missed points and such that each
 * face's missed points lie on the pocket's boundary (a box cut from one part of a
 * union, which no part of it improves alone), or a box cut: 2 or 3 such plane faces
 * each closed by the plane primitive facing it (a pocket whose far walls hold too few
 * points to be chosen, or a blind pocket of five walls). Then join at the root, while
 * that raises the fitness (at most 3 times), the best piece of two or three primitives, t | P,
 * t \ P or t & P with P = a & b, a \ b, a | b, (a & b) & c, (a & b) \ c, (a | b) | c,
 * ... (a pocket such as a groove, three planes intersected then subtracted, or a notch
 * t & (a | b | c) cut by faces that point into it, which no single primitive
 * improves); pairs must bring a primitive explaining points the tree misses, and the
 * best pairs by fitness are extended by a third primitive. The tree is simplified
 * again after each step. Last, at most 8 times, the best trim S & p or S & ~p of an
 * operand S of a union (one adding material) that keeps every point S explains, makes
 * inliers of p the tree misses explained and does not lower the score without the size
 * penalty: a part bounded only by the clipping box where no points are (the fitness
 * does not pay for such faces, so only the exact rules follow). *fitness (may be NULL)
 * receives the final fitness. 0 or -1 (allocation). */
int simplify_grow_pieces(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                         double *fitness, gp_cancel *k);

/* pol[k] = 1 when node k of t adds material to the solid (an even number of
 * complements and right operands of subtractions above it), 0 when it removes some. */
void simplify_polarity(const gp_tree *t, gp_setops s, uint8_t *pol);

/* The trims S & L of the growth steps (simplify.c) and of support.c, L = p or ~p for
 * primitive j, must keep every point S explains that the tree explains (oks[i] and
 * ok[i] set): can[0] (L = p) is cleared when p < -eps_d at such a point, can[1]
 * (L = ~p) when p > eps_d, or when the union's other operand (ending at node other)
 * is p itself (A | (B & ~A) is A | B). */
void simplify_trim_keeps(const gp_tree *t, uint32_t other, const gp_cache *c, uint32_t j,
                         const uint8_t *ok, const uint8_t *oks, int can[2]);
/* sub = head[0..nhead) & L, L = PRIM j (neg 0) or its complement (neg 1). 0 or -1. */
int simplify_trim_code(gp_tree *sub, const frep_insn *head, uint32_t nhead, uint32_t j,
                       int neg, const gp_opset *o);

#endif

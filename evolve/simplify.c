/* simplify.c - smaller equivalent construction trees: exact identities applied
 * bottom-up while copying the tree, then fitness-driven removal of nodes.
 * Runs after each GA (gp.c) and after each partition merge (partition.c).
 */
#include "config.h"

#include "alloc.h"
#include "gp.h"
#include "simplify.h"
#include "threads.h"
#include "util.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* Primitives the final hill climb may add at the root: each costs one pass over all
 * primitives, and a GA result rarely lacks more than one or two. */
#define SIMPLIFY_MAX_GROWTH 4

static void remove_at(gp_tree *t, uint32_t pc)
{
    memmove(t->code + pc, t->code + pc + 1, (size_t)(t->len - pc - 1) * sizeof *t->code);
    t->len--;
}

/* Exchange the adjacent ranges [a, b-1] and [b, len-1] at the end of t. */
static int swap_tail(gp_tree *t, uint32_t a, uint32_t b)
{
    uint32_t n = t->len - a;
    frep_insn *tmp = frep_malloc((size_t)n * sizeof *tmp);
    if (!tmp) return -1;
    uint32_t nr = t->len - b, nl = b - a;
    memcpy(tmp, t->code + b, (size_t)nr * sizeof *tmp);
    memcpy(tmp + nr, t->code + a, (size_t)nl * sizeof *tmp);
    memcpy(t->code + a, tmp, (size_t)n * sizeof *tmp);
    frep_free(tmp);
    return 0;
}

/* What simp() left for a subtree: a tree pushed to out, or a degenerate set that needs
 * no code.  Regularized CSG (the closure of the interior): a | ~a is all of space and
 * a & ~a, a \ a are empty; with min/max their functions |a| and -|a| would otherwise
 * leave zero-thickness sheets on the plane a = 0 that explain points without being
 * solid, which the fitness rewards and a person would not write. */
enum { SIMP_TREE = 0, SIMP_FULL = 1, SIMP_EMPTY = 2 };

static int simp_flip(int r) { return r == SIMP_FULL ? SIMP_EMPTY : r == SIMP_EMPTY ? SIMP_FULL : r; }

/* Copy the subtree ending at `end` to the end of out, simplified. Returns SIMP_TREE,
 * SIMP_FULL or SIMP_EMPTY (nothing pushed), -1 on allocation failure. Recursion depth
 * is the tree depth (<= GP_MAX_TREE_DEPTH). */
static int simp(const frep_insn *code, uint32_t end, gp_tree *out, const gp_opset *o);

/* ~a with a simplified at out's end: ~~a -> a; the complement of a constant set. */
static int simp_neg(const frep_insn *code, uint32_t end, gp_tree *out, const gp_opset *o)
{
    int r = simp(code, end - 1, out, o);
    if (r != SIMP_TREE) return r < 0 ? r : simp_flip(r);
    if (out->code[out->len - 1].op == o->neg) {  /* ~~a = a */
        out->len--;
        return SIMP_TREE;
    }
    return tree_push(out, (frep_opcode)o->neg, 0);
}

/* a op b where a (result rl, from ls) or b (rr) is a degenerate set: the result is a
 * constant set or one operand. */
static int simp_constant_operand(gp_tree *out, uint32_t ls, int rl, int rr, uint8_t op,
                                 const gp_opset *o)
{
    int keep_left = 0, keep_right = 0, result = SIMP_TREE;
    if (op == o->uni) {
        if (rl == SIMP_FULL || rr == SIMP_FULL) result = SIMP_FULL;
        else if (rl == SIMP_EMPTY) keep_right = 1;
        else keep_left = 1;
    } else if (op == o->inter) {
        if (rl == SIMP_EMPTY || rr == SIMP_EMPTY) result = SIMP_EMPTY;
        else if (rl == SIMP_FULL) keep_right = 1;
        else keep_left = 1;
    } else {  /* a \ b */
        if (rl == SIMP_EMPTY || rr == SIMP_FULL) result = SIMP_EMPTY;
        else if (rr == SIMP_EMPTY) keep_left = 1;
        else {  /* all \ b = ~b */
            keep_right = 1;
            if (out->code[out->len - 1].op == o->neg) out->len--;
            else if (tree_push(out, (frep_opcode)o->neg, 0)) return -1;
        }
    }
    if (keep_left) return rl;        /* the right side pushed nothing */
    if (keep_right) return rr;       /* the left side pushed nothing */
    out->len = ls;
    return result;
}

/* The complement rules on the operands out[ls..rs) and out[rs..len) of *op, until none
 * applies: De Morgan, a \ ~b -> a & b, a & ~b -> a \ b, ~a & b -> b & ~a,
 * ~a \ b -> ~(a | b); *negate toggles for each complement moved above *op. */
static int simp_complements(gp_tree *out, uint32_t ls, uint32_t *rs, uint8_t *op,
                            int *negate, const gp_opset *o)
{
    for (;;) {
        int lneg = out->code[*rs - 1].op == o->neg, rneg = out->code[out->len - 1].op == o->neg;
        if ((*op == o->uni || *op == o->inter) && lneg && rneg) {
            /* De Morgan: ~a | ~b = ~(a & b), ~a & ~b = ~(a | b) (exact for R0 too). */
            out->len--;
            remove_at(out, *rs - 1);
            (*rs)--;
            *op = *op == o->uni ? o->inter : o->uni;
            *negate ^= 1;
        } else if (*op == o->sub && rneg) {  /* a \ ~b = a & b */
            out->len--;
            *op = o->inter;
        } else if (*op == o->inter && rneg) {  /* a & ~b = a \ b */
            out->len--;
            *op = o->sub;
        } else if (*op == o->inter && lneg) {  /* ~a & b = b & ~a */
            if (swap_tail(out, ls, *rs)) return -1;
            *rs = ls + (out->len - *rs);
        } else if (*op == o->sub && lneg) {  /* ~a \ b = ~a & ~b = ~(a | b) */
            remove_at(out, *rs - 1);
            (*rs)--;
            *op = o->uni;
            *negate ^= 1;
        } else {
            return 0;
        }
    }
}

/* Regularization (see SIMP_FULL): a \ a is empty; a | ~a is everything. SIMP_TREE
 * when neither. */
static int simp_degenerate(const gp_tree *out, uint32_t ls, uint32_t rs, uint8_t op,
                           const gp_opset *o)
{
    if (op == o->sub && tree_compare(out->code, rs - 1, out->code, out->len - 1) == 0)
        return SIMP_EMPTY;
    if (op == o->uni && out->code[out->len - 1].op == o->neg && out->len - 1 > rs &&
        tree_compare(out->code, rs - 1, out->code, out->len - 2) == 0)
        return SIMP_FULL;
    if (op == o->uni && out->code[rs - 1].op == o->neg && rs - 1 > ls &&
        tree_compare(out->code, rs - 2, out->code, out->len - 1) == 0)
        return SIMP_FULL;
    return SIMP_TREE;
}

/* The node: commutative operands in canonical order, a | a = a & a = a, and the
 * complement moved above it. */
static int simp_emit(gp_tree *out, uint32_t ls, uint32_t rs, uint8_t op, int negate,
                     const gp_opset *o)
{
    int emit = 1;
    if (op == o->uni || op == o->inter) {
        int c = tree_compare(out->code, rs - 1, out->code, out->len - 1);
        if (c == 0) {  /* a | a = a & a = a */
            out->len = rs;
            emit = 0;
        } else if (c > 0) {
            if (swap_tail(out, ls, rs)) return -1;
        }
    }
    if (emit && tree_push(out, (frep_opcode)op, 0)) return -1;
    if (negate) {
        if (out->code[out->len - 1].op == o->neg) out->len--;
        else if (tree_push(out, (frep_opcode)o->neg, 0)) return -1;
    }
    return SIMP_TREE;
}

static int simp(const frep_insn *code, uint32_t end, gp_tree *out, const gp_opset *o)
{
    const frep_insn *in = &code[end];
    int k = tree_nin(in);
    if (k == 0) return tree_push(out, FREP_OP_PRIM, in->arg);
    if (k == 1) return simp_neg(code, end, out, o);
    uint32_t l0, l1, r0;
    tree_operands(code, end, &l0, &l1, &r0);
    (void)l0;
    (void)r0;
    uint32_t ls = out->len;
    int rl = simp(code, l1, out, o);
    if (rl < 0) return -1;
    uint32_t rs = out->len;
    int rr = simp(code, end - 1, out, o);
    if (rr < 0) return -1;
    uint8_t op = in->op;
    if (rl != SIMP_TREE || rr != SIMP_TREE) return simp_constant_operand(out, ls, rl, rr, op, o);
    int negate = 0;
    if (simp_complements(out, ls, &rs, &op, &negate, o)) return -1;
    int degenerate = simp_degenerate(out, ls, rs, op, o);
    if (degenerate != SIMP_TREE) {
        out->len = ls;
        return negate ? simp_flip(degenerate) : degenerate;
    }
    return simp_emit(out, ls, rs, op, negate, o);
}

int simplify_rules(gp_tree *t, gp_setops s)
{
    if (!t->len) return 0;
    gp_opset o = gp_opset_of(s);
    gp_tree out = { NULL, 0, 0 };
    /* A pass can enable another (a De Morgan exposes a double complement above). */
    for (int pass = 0; pass < 8; pass++) {
        out.len = 0;
        if (tree_reserve(&out, t->len)) {
            tree_free(&out);
            return -1;
        }
        int r = simp(t->code, t->len - 1, &out, &o);
        if (r < 0) {
            tree_free(&out);
            return -1;
        }
        if (r != SIMP_TREE) break; /* the whole tree is degenerate: leave it as it is */
        int same = out.len == t->len &&
                   memcmp(out.code, t->code, (size_t)t->len * sizeof *t->code) == 0;
        if (tree_copy(t, &out)) {
            tree_free(&out);
            return -1;
        }
        if (same) break;
    }
    tree_free(&out);
    return 0;
}

/* Try replacing the subtree [st, end] of t by cand, which may hold tape leaves of t
 * (fitness.h; e holds t's tape); keep it when the fitness does not drop, the expanded
 * cand then in trial and t's tape recorded again. Returns 1 when kept, 0 when not, -1
 * on allocation failure. */
static int try_replace(gp_tree *t, gp_tree *trial, uint32_t st, uint32_t end,
                       const gp_tree *cand, const gp_cache *c, gp_eval *e, double *fit)
{
    double f;
    if (gp_fitness_replaced(c, e, st, end, cand->code, cand->len, *fit, &f)) return -1;
    if (!(f >= *fit)) return 0;
    if (gp_tape_expand(c, e, cand->code, cand->len, trial) ||
        tree_splice(t, st, end, trial->code, trial->len) ||
        gp_tape_record(c, e, t->code, t->len, NULL))
        return -1;
    *fit = f;
    return 1;
}

/* t's tape recorded in e, and t's fitness. 0 or -1. */
static int record(const gp_tree *t, const gp_cache *c, gp_eval *e, double *fit)
{
    double sc;
    if (gp_tape_record(c, e, t->code, t->len, &sc)) return -1;
    if (fit) *fit = sc - c->lambda * (double)t->len;
    return 0;
}

/* cand = the tape leaf of node a (a whole subtree of the recorded tree). */
static int leaf1(gp_tree *cand, const gp_cache *c, uint32_t a)
{
    frep_insn la = gp_tape_leaf(c, a);
    cand->len = 0;
    return tree_push(cand, (frep_opcode)la.op, la.arg);
}

/* cand = (subtree ending at a) (subtree ending at b) op, as tape leaves. */
static int build2(gp_tree *cand, const gp_cache *c, uint32_t a, uint32_t b, uint8_t op)
{
    frep_insn la = gp_tape_leaf(c, a), lb = gp_tape_leaf(c, b);
    cand->len = 0;
    return tree_push(cand, (frep_opcode)la.op, la.arg) ||
           tree_push(cand, (frep_opcode)lb.op, lb.arg) || tree_push(cand, (frep_opcode)op, 0);
}

/* The moves at node `end`, smallest change first: the node replaced by an operand;
 * then an operand that is itself an operation replaced by one of its operands, with
 * any of the three operations at the node (a \ (b \ c) -> a & c when a lies in b).
 * Every move shrinks the tree, so the search ends. Returns the new length of the
 * node's subtree when a move was kept, 0 when none, -1 on allocation failure. */
static long node_moves(gp_tree *t, gp_tree *trial, gp_tree *cand, uint32_t end,
                       const gp_opset *o, const gp_cache *c, gp_eval *e, double *fit)
{
    int k = tree_nin(&t->code[end]);
    uint32_t st = tree_subtree_start(t->code, end);
    uint32_t rng[2][2];
    int nr = 0;
    if (k == 1) {
        rng[nr][0] = st;
        rng[nr++][1] = end - 1;
    } else {
        uint32_t l0, l1, r0;
        tree_operands(t->code, end, &l0, &l1, &r0);
        rng[nr][0] = l0;
        rng[nr++][1] = l1;
        rng[nr][0] = r0;
        rng[nr++][1] = end - 1;
    }
    for (int q = 0; q < nr; q++) {
        if (leaf1(cand, c, rng[q][1])) return -1;
        int r = try_replace(t, trial, st, end, cand, c, e, fit);
        if (r) return r < 0 ? -1 : (long)trial->len;
    }
    if (k != 2) return 0;
    const uint8_t ops[3] = { o->uni, o->inter, o->sub };
    for (int side = 0; side < 2; side++) {
        uint32_t ce = rng[side][1];
        if (tree_nin(&t->code[ce]) != 2) continue;
        uint32_t c0, c1, d0;
        tree_operands(t->code, ce, &c0, &c1, &d0);
        uint32_t sub[2][2] = { { c0, c1 }, { d0, ce - 1 } };
        const uint32_t *other = rng[1 - side];
        for (int g = 0; g < 2; g++)
            for (int w = 0; w < 4; w++) {
                /* w == 3: subtraction with the operands exchanged */
                uint8_t op = ops[w < 3 ? w : 2];
                int kept_first = (side == 0) != (w == 3);
                int bad = kept_first ? build2(cand, c, sub[g][1], other[1], op)
                                     : build2(cand, c, other[1], sub[g][1], op);
                if (bad) return -1;
                int r = try_replace(t, trial, st, end, cand, c, e, fit);
                if (r) return r < 0 ? -1 : (long)trial->len;
            }
    }
    return 0;
}

/* Hill climb at the root: the best of t | p, t & p, t \ p over all primitives p, while
 * it raises the fitness (a GA can stall one primitive short of the solution).
 * Returns 1 when the tree grew, 0 when not, -1 on allocation failure. */
static int grow_root(gp_tree *t, gp_tree *trial, const gp_opset *o, const gp_cache *c,
                     gp_eval *e, double *fit, gp_cancel *k)
{
    const uint8_t ops[3] = { o->uni, o->inter, o->sub };
    uint32_t best_j = 0;
    int best_w = -1;
    double bf = *fit;
    if (record(t, c, e, NULL)) return -1;
    for (uint32_t j = 0; j < c->nprims; j++) {
        if (gp_cancelled(k)) return 0;
        for (int w = 0; w < 3; w++) {
            if (leaf1(trial, c, t->len - 1) || tree_push(trial, FREP_OP_PRIM, j) ||
                tree_push(trial, (frep_opcode)ops[w], 0))
                return -1;
            double f;
            if (gp_fitness_replaced(c, e, 0, t->len - 1, trial->code, trial->len, bf, &f))
                return -1;
            if (f > bf) {
                bf = f;
                best_j = j;
                best_w = w;
            }
        }
    }
    if (best_w < 0) return 0;
    if (tree_push(t, FREP_OP_PRIM, best_j) || tree_push(t, (frep_opcode)ops[best_w], 0))
        return -1;
    *fit = bf;
    return 1;
}

/* node_moves at node `end` of a removal scan: -1 on allocation failure, 0 when no move
 * applies, else 1 with *took the end of the node that took the place. */
static int reduce_at(gp_tree *t, gp_tree *trial, gp_tree *cand, uint32_t end,
                     const gp_opset *o, const gp_cache *c, gp_eval *e, double *fit,
                     uint32_t *took)
{
    if (tree_nin(&t->code[end]) == 0) return 0;
    uint32_t st = tree_subtree_start(t->code, end);
    long r = node_moves(t, trial, cand, end, o, c, e, fit);
    if (r <= 0) return (int)r;
    *took = st + (uint32_t)r - 1;
    return 1;
}

/* Removal moves until none applies. */
static int reduce(gp_tree *t, gp_tree *trial, gp_tree *cand, gp_setops s, const gp_opset *o,
                  const gp_cache *c, gp_eval *e, double *fit, int leaves_first, gp_cancel *k)
{
    int changed = 1;
    while (changed && !gp_cancelled(k)) {
        changed = 0;
        if (record(t, c, e, fit)) return -1;
        uint32_t took = 0;
        if (!leaves_first) {
            /* Root first: removing high nodes saves the most. After a replacement the
             * scan continues at the node that took the place. */
            for (uint32_t end = t->len; end-- > 0 && !gp_cancelled(k);) {
                int r = reduce_at(t, trial, cand, end, o, c, e, fit, &took);
                if (r < 0) return -1;
                if (r > 0) {
                    changed = 1;
                    end = took + 1;  /* the loop decrements to the new node */
                }
            }
        } else {
            /* Deepest first (postfix order): a part removed before a larger part that
             * only it made redundant (partition.c, merged trees). After a replacement
             * the scan continues after the node that took the place. */
            for (uint32_t end = 0; end < t->len && !gp_cancelled(k); end++) {
                int r = reduce_at(t, trial, cand, end, o, c, e, fit, &took);
                if (r < 0) return -1;
                if (r > 0) {
                    changed = 1;
                    end = took;  /* the loop increments past it */
                }
            }
        }
        if (changed && simplify_rules(t, s)) return -1;
    }
    return 0;
}

static int simplify_order(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                          double *fitness, int leaves_first, gp_cancel *k)
{
    if (simplify_rules(t, s)) return -1;
    gp_opset o = gp_opset_of(s);
    double fit;
    if (gp_fitness(c, e, t->code, t->len, &fit)) return -1;
    gp_tree trial = { NULL, 0, 0 }, cand = { NULL, 0, 0 };
    int rc = -1;
    if (reduce(t, &trial, &cand, s, &o, c, e, &fit, leaves_first, k)) goto out;
    for (int round = 0; round < SIMPLIFY_MAX_GROWTH && !gp_cancelled(k); round++) {
        int g = grow_root(t, &trial, &o, c, e, &fit, k);
        if (g < 0) goto out;
        if (g == 0) break;
        if (simplify_rules(t, s)) goto out;
        if (gp_fitness(c, e, t->code, t->len, &fit)) goto out;
        if (reduce(t, &trial, &cand, s, &o, c, e, &fit, leaves_first, k)) goto out;
    }
    rc = 0;
    if (fitness) *fitness = fit;
out:
    tree_free(&trial);
    tree_free(&cand);
    return rc;
}

int simplify_tree(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e, double *fitness,
                  gp_cancel *k)
{
    return simplify_order(t, s, c, e, fitness, 0, k);
}

int simplify_tree_both(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                       double *fitness, gp_cancel *k)
{
    gp_tree u = { NULL, 0, 0 };
    double fr = 0, fl = 0;
    int rc = -1;
    if (tree_copy(&u, t) || simplify_order(t, s, c, e, &fr, 0, k) ||
        simplify_order(&u, s, c, e, &fl, 1, k))
        goto out;
    if (fl > fr || (fl == fr && u.len < t->len)) {
        if (tree_copy(t, &u)) goto out;
        fr = fl;
    }
    if (fitness) *fitness = fr;
    rc = 0;
out:
    tree_free(&u);
    return rc;
}

/* ---- pieces: two or three primitives joined at the root ------------------------ */

/* Best two-leaf pieces kept for the extension by a third leaf. A pocket such as M0's
 * groove (three planes intersected, then subtracted) scores nothing as a single plane
 * and little as a pair, so the pairs are ranked, not required to improve. */
#define SIMPLIFY_PIECE_BEAM 24
/* Pieces added at most: each round is one pass over the pairs. */
#define SIMPLIFY_MAX_PIECES 3

typedef struct piece {
    double f;
    uint32_t a, b, c;          /* c == UINT32_MAX: a two-leaf piece */
    uint8_t inner, third, outer;
} piece;

/* head (a inner b) [c third] outer, in postfix; head is t, or t's tape leaf. */
static int build_piece(gp_tree *trial, const frep_insn *head, uint32_t nhead, const piece *p)
{
    if (tree_set(trial, head, nhead) || tree_push(trial, FREP_OP_PRIM, p->a) ||
        tree_push(trial, FREP_OP_PRIM, p->b) || tree_push(trial, (frep_opcode)p->inner, 0))
        return -1;
    if (p->c != UINT32_MAX &&
        (tree_push(trial, FREP_OP_PRIM, p->c) || tree_push(trial, (frep_opcode)p->third, 0)))
        return -1;
    return tree_push(trial, (frep_opcode)p->outer, 0);
}

/* Insert p into the beam sorted by decreasing fitness (ties: first found first, so
 * the result does not depend on anything but the order of the loops). */
static void beam_insert(piece *beam, int *nb, const piece *p)
{
    int full = *nb == SIMPLIFY_PIECE_BEAM;  /* only then is beam[k] a kept piece */
    if (full && !(p->f > beam[SIMPLIFY_PIECE_BEAM - 1].f)) return;
    int k = full ? SIMPLIFY_PIECE_BEAM - 1 : (*nb)++;
    while (k > 0 && p->f > beam[k - 1].f) {
        beam[k] = beam[k - 1];
        k--;
    }
    beam[k] = *p;
}

/* Primitives that explain, alone or complemented, more than lambda points the tree
 * does not explain: a piece must bring at least one of them, else it cannot pay for
 * its nodes. use[j] = 1 for those. When cnt is not NULL, cnt[j] receives how many
 * such points primitive j explains and neg[j] whether most of them need its
 * complement (f >= 0 inside: p explains a point when -grad p agrees with the outward
 * normal). Returns how many, or -1 on allocation failure. */
static long useful_prims_oriented(const gp_tree *t, const gp_cache *c, gp_eval *e,
                                  uint8_t *use, double *cnt_out, uint8_t *neg);

static long useful_prims(const gp_tree *t, const gp_cache *c, gp_eval *e, uint8_t *use)
{
    return useful_prims_oriented(t, c, e, use, NULL, NULL);
}

static long useful_prims_oriented(const gp_tree *t, const gp_cache *c, gp_eval *e,
                                  uint8_t *use, double *cnt_out, uint8_t *neg)
{
    uint8_t *ok = frep_malloc(c->n ? c->n : 1);
    if (!ok) return -1;
    if (gp_explained(c, e, t->code, t->len, ok)) {
        frep_free(ok);
        return -1;
    }
    double ca = cos(c->alpha);
    long nu = 0;
    for (uint32_t j = 0; j < c->nprims; j++) {
        const double *v = c->v + (size_t)j * c->n;
        const double *gx = c->g + 3 * (size_t)j * c->n, *gy = gx + c->n, *gz = gy + c->n;
        double cnt = 0, cneg = 0;
        for (size_t i = 0; i < c->n; i++) {
            if (ok[i] || !(fabs(v[i]) < c->eps_d)) continue;
            double gl = sqrt(gx[i] * gx[i] + gy[i] * gy[i] + gz[i] * gz[i]);
            if (!(gl > 0)) continue;
            const double *nn = c->nrm + 3 * i;
            double cs = (gx[i] * nn[0] + gy[i] * nn[1] + gz[i] * nn[2]) / gl;
            if (fabs(cs) > ca) cnt += 1;  /* either sign: the piece may complement it */
            if (cs > ca) cneg += 1;       /* grad p along the outward normal: ~p */
        }
        use[j] = cnt > c->lambda;
        if (cnt_out) cnt_out[j] = cnt;
        if (neg) neg[j] = 2 * cneg > cnt;
        nu += use[j];
    }
    frep_free(ok);
    return nu;
}

/* The growth steps below find their best change in the scratch tree trial, then keep
 * it here: t becomes trial unless trial is deeper than GP_MAX_TREE_DEPTH.
 * Returns 1 (kept), 0 (too deep: t unchanged) or -1 (out of memory). */
static int commit_trial(gp_tree *t, const gp_tree *trial)
{
    if (tree_depth(trial->code, trial->len) > GP_MAX_TREE_DEPTH) return 0;
    return tree_copy(t, trial) ? -1 : 1;
}

/* commit_trial of t with the subtree ending at `end` replaced by sub (built in trial). */
static int commit_splice(gp_tree *t, gp_tree *trial, uint32_t end, const gp_tree *sub)
{
    if (tree_copy(trial, t) ||
        tree_splice(trial, tree_subtree_start(t->code, end), end, sub->code, sub->len))
        return -1;
    return commit_trial(t, trial);
}

/* One round: the best piece t | P, t \ P or t & P, P = a & b, a \ b, b \ a or a | b,
 * optionally extended by & c, \ c or | c, when it raises the fitness and keeps the
 * depth limit. */
static int grow_piece(gp_tree *t, gp_tree *trial, const gp_opset *o, const gp_cache *c,
                      gp_eval *e, double *fit, gp_cancel *cancel)
{
    uint32_t k = c->nprims;
    if (k < 2) return 0;
    uint8_t *use = frep_malloc(k);
    piece *beam = frep_malloc(SIMPLIFY_PIECE_BEAM * sizeof *beam);
    int rc = -1, nb = 0;
    if (!use || !beam) goto out;
    long nu = useful_prims(t, c, e, use);
    if (nu < 0) goto out;
    rc = 0;
    if (nu == 0) goto out;
    /* t & (a | b | c) is the pocket cut by the faces' complements, t \ (~a & ~b & ~c)
     * (a notch cut by a box corner, fitted faces pointing into the notch). */
    const uint8_t outers[3] = { o->uni, o->sub, o->inter };
    piece best = { *fit, 0, 0, UINT32_MAX, 0, 0, 0 };
    int found = 0;
    if (record(t, c, e, NULL)) { rc = -1; goto out; }
    frep_insn root = gp_tape_leaf(c, t->len - 1);
    for (uint32_t a = 0; a < k; a++)
        for (uint32_t b = a + 1; b < k; b++) {
            if (gp_cancelled(cancel)) goto out;   /* rc 0: the tree stays as it stands */
            if (!use[a] && !use[b]) continue;
            for (int w = 0; w < 3; w++)
                for (int q = 0; q < 4; q++) {
                    piece p = { 0, q == 2 ? b : a, q == 2 ? a : b, UINT32_MAX,
                                q == 0 ? o->inter : q == 3 ? o->uni : o->sub, 0, outers[w] };
                    if (build_piece(trial, &root, 1, &p)) { rc = -1; goto out; }
                    /* Below the beam's last piece a piece is neither kept nor best. */
                    double fl = nb == SIMPLIFY_PIECE_BEAM ? beam[nb - 1].f : -HUGE_VAL;
                    if (gp_fitness_replaced(c, e, 0, t->len - 1, trial->code, trial->len,
                                            fl, &p.f)) { rc = -1; goto out; }
                    if (p.f > best.f) { best = p; found = 1; }
                    beam_insert(beam, &nb, &p);
                }
        }
    for (int i = 0; i < nb; i++)
        for (uint32_t cc = 0; cc < k; cc++) {
            if (gp_cancelled(cancel)) goto out;
            if (cc == beam[i].a || cc == beam[i].b) continue;
            for (int q = 0; q < 3; q++) {
                piece p = beam[i];
                p.c = cc;
                p.third = q == 0 ? o->inter : q == 1 ? o->sub : o->uni;
                if (build_piece(trial, &root, 1, &p)) { rc = -1; goto out; }
                if (gp_fitness_replaced(c, e, 0, t->len - 1, trial->code, trial->len,
                                        best.f, &p.f)) { rc = -1; goto out; }
                if (p.f > best.f) { best = p; found = 1; }
            }
        }
    if (!found) goto out;
    if (build_piece(trial, t->code, t->len, &best)) { rc = -1; goto out; }
    if ((rc = commit_trial(t, trial)) <= 0) goto out;
    *fit = best.f;
out:
    frep_free(use);
    frep_free(beam);
    return rc;
}

/* ---- inner growth: one primitive joined below the root ------------------------- */

/* Primitives joined inside the tree at most (each is one pass over every subtree and
 * every useful primitive). */
#define SIMPLIFY_MAX_INNER 16

/* Candidates (subtree end x useful primitive x operation) of one inner-growth round
 * above which the round runs in parallel (each thread records its own tape of t). */
#define SIMPLIFY_PAR_MIN 512

/* The best inner growth among the subtree ends [e0, e1), scored on ev (t's tape
 * recorded there): *bf raised, *best = end * 3k + j * 3 + w, the sequential order of
 * the candidates (UINT64_MAX: none beats *bf). 0 or -1. */
static int inner_range(const gp_tree *t, const uint8_t *use, const uint8_t ops[3],
                       const gp_cache *c, gp_eval *ev, uint32_t e0, uint32_t e1,
                       gp_tree *cand, double *bf, uint64_t *best)
{
    uint32_t k = c->nprims;
    for (uint32_t end = e0; end < e1; end++) {
        uint32_t st = tree_subtree_start(t->code, end);
        for (uint32_t j = 0; j < k; j++) {
            if (!use[j]) continue;
            for (int w = 0; w < 3; w++) {
                /* [st, end] followed by PRIM j, op */
                if (leaf1(cand, c, end) || tree_push(cand, FREP_OP_PRIM, j) ||
                    tree_push(cand, (frep_opcode)ops[w], 0))
                    return -1;
                double f;
                if (gp_fitness_replaced(c, ev, st, end, cand->code, cand->len, *bf, &f))
                    return -1;
                if (f > *bf) {
                    *bf = f;
                    *best = ((uint64_t)end * k + j) * 3 + (uint64_t)w;
                }
            }
        }
    }
    return 0;
}

/* inner_range over the subtree ends of t split between nt threads (each with its own
 * evaluator and tape); the best of the threads is the first in the sequential order
 * among the fittest, as in one thread. 0 or -1. */
static int inner_parallel(const gp_tree *t, const uint8_t *use, const uint8_t ops[3],
                          const gp_cache *c, int nt, double fit, double *bf, uint64_t *best)
{
    double *tbf = frep_malloc((size_t)nt * sizeof *tbf);
    uint64_t *tbest = frep_malloc((size_t)nt * sizeof *tbest);
    if (!tbf || !tbest) {
        frep_free(tbf);
        frep_free(tbest);
        return -1;
    }
    int failed = 0;
    uint32_t len = t->len;
#pragma omp parallel num_threads(nt) reduction(| : failed)
    {
        int id = frep_thread_num(), n = frep_team_size();
        gp_eval *ev = gp_eval_new();
        gp_tree cand = { NULL, 0, 0 };
        tbf[id] = fit;
        tbest[id] = UINT64_MAX;
        uint32_t e0 = (uint32_t)((uint64_t)len * (uint64_t)id / (uint64_t)n);
        uint32_t e1 = (uint32_t)((uint64_t)len * (uint64_t)(id + 1) / (uint64_t)n);
        if (!ev || record(t, c, ev, NULL) ||
            inner_range(t, use, ops, c, ev, e0, e1, &cand, &tbf[id], &tbest[id]))
            failed = 1;
        tree_free(&cand);
        gp_eval_free(ev);
        if (id == 0) nt = n;
    }
    for (int q = 0; q < nt && !failed; q++)
        if (tbest[q] != UINT64_MAX && (tbf[q] > *bf || (tbf[q] == *bf && tbest[q] < *best))) {
            *bf = tbf[q];
            *best = tbest[q];
        }
    frep_free(tbf);
    frep_free(tbest);
    return failed ? -1 : 0;
}

/* The insertion best = (end * k + j) * 3 + w: the subtree ending at `end` joined with
 * primitive j by ops[w]. As commit_splice: 1 when kept, 0 when not, -1. */
static int inner_apply(gp_tree *t, gp_tree *trial, const uint8_t ops[3], uint32_t k,
                       uint64_t best)
{
    uint32_t best_end = (uint32_t)(best / 3 / k), best_j = (uint32_t)(best / 3 % k);
    int best_w = (int)(best % 3);
    uint32_t st = tree_subtree_start(t->code, best_end);
    gp_tree sub = { NULL, 0, 0 };
    int rc = tree_set(&sub, t->code + st, best_end - st + 1) ||
                     tree_push(&sub, FREP_OP_PRIM, best_j) ||
                     tree_push(&sub, (frep_opcode)ops[best_w], 0)
                 ? -1
                 : commit_splice(t, trial, best_end, &sub);
    tree_free(&sub);
    return rc;
}

/* One round: the best S & p, S \ p or S | p replacing a subtree S of t, over every
 * subtree and every primitive p that explains points t misses (useful_prims), when it
 * raises the fitness. A face missing from one part of a union (a subtracted box short
 * of two of its faces, so that it cuts away a whole quadrant) cannot be added at the
 * root, where it would cut every other part too. Returns 1 when t changed, 0 when
 * not, -1 on allocation failure. */
static int grow_inner(gp_tree *t, gp_tree *trial, const gp_opset *o, const gp_cache *c,
                      gp_eval *e, double *fit)
{
    uint32_t k = c->nprims;
    uint8_t *use = frep_malloc(k ? k : 1);
    int rc = -1;
    if (!use) return -1;
    long nu = useful_prims(t, c, e, use);
    if (nu < 0) goto out;
    rc = 0;
    if (nu == 0) goto out;
    const uint8_t ops[3] = { o->inter, o->sub, o->uni };
    double bf = *fit;
    uint64_t best = UINT64_MAX;
    int nt = 1;
#ifdef _OPENMP
    if (!omp_in_parallel() && (uint64_t)t->len * (uint64_t)nu * 3 >= SIMPLIFY_PAR_MIN)
        nt = frep_threads(0);
#endif
    if (nt <= 1 ? record(t, c, e, NULL) ||
                      inner_range(t, use, ops, c, e, 0, t->len, trial, &bf, &best)
                : inner_parallel(t, use, ops, c, nt, *fit, &bf, &best)) {
        rc = -1;
        goto out;
    }
    if (best == UINT64_MAX) goto out;
    rc = inner_apply(t, trial, ops, k, best);
    if (rc > 0) *fit = bf;
out:
    frep_free(use);
    return rc;
}

/* ---- swaps: a leaf for another primitive ---------------------------------------- */

/* A primitive is offered in a swap when it explains at least SIMPLIFY_SWAP_MIN points
 * the tree misses: a swap keeps the tree's size, so it pays for itself with any gain,
 * where a growth needs lambda points (ln n). */
#define SIMPLIFY_SWAP_MIN 2
/* Swaps kept at most (each followed by simplify_tree). */
#define SIMPLIFY_MAX_SWAPS 8

/* One round: the best leaf of t replaced by another fitted primitive (fitted[j])
 * explaining points t misses, when that raises the fitness. A small face the GA never saw (a pocket's wall
 * of 25 of 50,000 points, some 2 of its 4,096) leaves the GA free to put any plane of
 * about its direction in its place: six_cuboids' cube less a turned cube came out with
 * a face of the part 24 degrees off the pocket's sixth wall, cutting a wedge from the
 * cube's corner (Hausdorff 4.4% on a clean cloud).  Only fitted primitives come in:
 * a plane placed by construction (a separating plane) has no points of its own, and
 * under noise a swap for one gains a few points of the noise (mount at 0.5% noise: the
 * block's bottom tilted 5 degrees, 0.3 off at its corner).  Returns 1 when t changed,
 * 0 when not, -1 on allocation failure. */
static int grow_swap(gp_tree *t, gp_tree *trial, const gp_cache *c, gp_eval *e,
                     const uint8_t *fitted, double *fit)
{
    uint32_t k = c->nprims;
    uint8_t *use = frep_malloc(k ? k : 1);
    double *cnt = frep_malloc((k ? k : 1) * sizeof *cnt);
    gp_tree cand = { NULL, 0, 0 };
    int rc = -1;
    if (!use || !cnt || useful_prims_oriented(t, c, e, use, cnt, NULL) < 0 ||
        record(t, c, e, NULL))
        goto out;
    double bf = *fit;
    uint32_t best_i = UINT32_MAX, best_j = 0;
    for (uint32_t i = 0; i < t->len; i++) {
        if (t->code[i].op != FREP_OP_PRIM) continue;
        for (uint32_t j = 0; j < k; j++) {
            double f;
            if (j == t->code[i].arg || !fitted[j] || !(cnt[j] >= SIMPLIFY_SWAP_MIN)) continue;
            cand.len = 0;
            if (tree_push(&cand, FREP_OP_PRIM, j) ||
                gp_fitness_replaced(c, e, i, i, cand.code, cand.len, bf, &f))
                goto out;
            if (f > bf) {
                bf = f;
                best_i = i;
                best_j = j;
            }
        }
    }
    rc = 0;
    if (best_i == UINT32_MAX) goto out;
    cand.len = 0;
    rc = tree_push(&cand, FREP_OP_PRIM, best_j) ? -1 : commit_splice(t, trial, best_i, &cand);
    if (rc > 0) *fit = bf;
out:
    tree_free(&cand);
    frep_free(use);
    frep_free(cnt);
    return rc;
}

/* A growth step for climb: one round of changes to t (trial its scratch), *fit raised
 * when it changed; 1 (changed), 0 (not), -1 (allocation). */
typedef int (*growth_step)(gp_tree *t, gp_tree *trial, const gp_cache *c, gp_eval *e,
                           const void *arg, double *fit);

/* step while it changes t and at most `rounds` times, each change followed by
 * simplify_tree; *fitness (may be NULL) the final fitness.  0 or -1. */
static int climb(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e, growth_step step,
                 const void *arg, int rounds, double *fitness, gp_cancel *k)
{
    if (!t->len) return 0;
    gp_tree trial = { NULL, 0, 0 };
    double fit;
    int rc = -1;
    if (gp_fitness(c, e, t->code, t->len, &fit)) goto out;
    for (int round = 0; round < rounds && !gp_cancelled(k); round++) {
        int g = step(t, &trial, c, e, arg, &fit);
        if (g < 0) goto out;
        if (g == 0) break;
        if (simplify_tree(t, s, c, e, &fit, k)) goto out;
    }
    rc = 0;
    if (fitness) *fitness = fit;
out:
    tree_free(&trial);
    return rc;
}

static int swap_step(gp_tree *t, gp_tree *trial, const gp_cache *c, gp_eval *e,
                     const void *fitted, double *fit)
{
    return grow_swap(t, trial, c, e, fitted, fit);
}

int simplify_swap_leaves(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                         const uint8_t *fitted, double *fitness, gp_cancel *k)
{
    return climb(t, s, c, e, swap_step, fitted, SIMPLIFY_MAX_SWAPS, fitness, k);
}

/* ---- pockets: up to four primitives joined below the root ---------------------- */

/* Primitives a pocket is built from: the useful ones explaining the most missed
 * points (a 4-face pocket needs its 4 faces among them; 8 gives 154 subsets). */
#define SIMPLIFY_POCKET_CANDS 8
/* Faces of a pocket at most: a box pocket cut through a part has four walls. */
#define SIMPLIFY_POCKET_MAX 4
/* Faces of a boss at most: a box has six. */
#define SIMPLIFY_BOSS_MAX 6
/* Pockets and bosses added at most (each round is one pass over subtrees and subsets). */
#define SIMPLIFY_MAX_POCKETS 3
/* Which candidates may form a boss: only planes whose intersection is bounded. A boss
 * of a few planes is unbounded: joined by a union it adds material through empty
 * space, where no point objects (six_cuboids, GA seed 3: Chamfer 0.82% -> 1.21% with
 * unbounded bosses). A pocket is cut from S and so bounded by it. */

/* 1 when primitive j of c is a plane (the same gradient at every point); its
 * gradient in g. */
static int cache_plane(const gp_cache *c, uint32_t j, double g[3])
{
    size_t n = c->n;
    if (n == 0) return 0;
    const double *gx = c->g + 3 * (size_t)j * n, *gy = gx + n, *gz = gy + n;
    g[0] = gx[0];
    g[1] = gy[0];
    g[2] = gz[0];
    double l = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if (!(l > 0)) return 0;
    for (size_t i = 1; i < n; i++)
        if (fabs(gx[i] - g[0]) + fabs(gy[i] - g[1]) + fabs(gz[i] - g[2]) > 1e-9 * l) return 0;
    return 1;
}

/* 1 when the half-spaces with outward normals nn[0..m) bound a finite region: no
 * direction u has nn[k].u <= 0 for every k. Such a direction, when there is one,
 * can be taken along an edge of the cone of them, the cross product of two normals
 * (or the normals span no more than a plane). */
static int planes_bounded(const double (*nn)[3], int m)
{
    if (m < 4) return 0;
    int rank3 = 0;
    for (int i = 0; i < m; i++)
        for (int j = i + 1; j < m; j++) {
            double u[3] = { nn[i][1] * nn[j][2] - nn[i][2] * nn[j][1],
                            nn[i][2] * nn[j][0] - nn[i][0] * nn[j][2],
                            nn[i][0] * nn[j][1] - nn[i][1] * nn[j][0] };
            double ul = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
            if (!(ul > 1e-9)) continue;
            for (int sg = -1; sg <= 1; sg += 2) {
                int all = 1;
                for (int k = 0; k < m && all; k++)
                    all = sg * (nn[k][0] * u[0] + nn[k][1] * u[1] + nn[k][2] * u[2]) <= 1e-9 * ul;
                if (all) return 0;
            }
            for (int k = 0; k < m; k++)
                if (fabs(nn[k][0] * u[0] + nn[k][1] * u[1] + nn[k][2] * u[2]) > 1e-6 * ul) rank3 = 1;
        }
    return rank3;
}

/* sub = code[st..end] then the piece over literals lits[0..m): pocket (form 0):
 * S & (L1 | L2 | ...), the material kept near each face being the side its points
 * say; boss (form 1): S | (L1 & L2 & ...). L = ~p where lneg[q] is set, else p. */
static int build_pocket(gp_tree *sub, const frep_insn *code, uint32_t st, uint32_t end,
                        const uint32_t *lits, const uint8_t *lneg, int m, int form,
                        const gp_opset *o)
{
    if (tree_set(sub, code + st, end - st + 1)) return -1;
    for (int q = 0; q < m; q++) {
        if (tree_push(sub, FREP_OP_PRIM, lits[q])) return -1;
        if (lneg[q] && tree_push(sub, (frep_opcode)o->neg, 0)) return -1;
        if (q > 0 && tree_push(sub, (frep_opcode)(form == 0 ? o->uni : o->inter), 0))
            return -1;
    }
    return tree_push(sub, (frep_opcode)(form == 0 ? o->inter : o->uni), 0);
}

/* One grow_pocket round: the candidate faces, which pairs of them can bound one
 * pocket or boss, and the best variant so far. */
typedef struct pocket_state {
    const gp_cache *c;
    gp_eval *e;
    const gp_opset *o;
    uint8_t *use, *neg;      /* per primitive: useful; used complemented (useful_prims_oriented) */
    double *cnt;             /* per primitive: missed points it explains */
    uint8_t *ok;             /* per point: the tree explains it */
    uint32_t cand[SIMPLIFY_POCKET_CANDS];
    int nc;                  /* candidates */
    /* fits[form][a][b]: most missed points of face a lie where literal b allows the
     * piece's boundary (form 0, pocket: L_b <= eps_d; form 1, boss: L_b >= -eps_d). */
    uint8_t fits[2][SIMPLIFY_POCKET_CANDS][SIMPLIFY_POCKET_CANDS];
    double pn[SIMPLIFY_POCKET_CANDS][3];   /* outward normals of the plane candidates */
    uint8_t isplane[SIMPLIFY_POCKET_CANDS];
    /* The far wall of each plane candidate (box_partners): a plane primitive, and
     * whether its literal is complemented; UINT32_MAX: none. */
    uint32_t far[SIMPLIFY_POCKET_CANDS];
    uint8_t far_neg[SIMPLIFY_POCKET_CANDS];
    double bf;               /* best fitness (the tree's to start with) */
    uint32_t best_end, best_lits[SIMPLIFY_BOSS_MAX];
    uint8_t best_neg[SIMPLIFY_BOSS_MAX];
    int best_m, best_form;   /* best_m 0: nothing better found */
    gp_tree sub;             /* scratch: a replacement */
} pocket_state;

/* The candidates: useful primitives by decreasing count (ties: lower index). */
static void pocket_candidates(pocket_state *ps)
{
    uint32_t k = ps->c->nprims, *cand = ps->cand;
    int nc = 0;
    for (uint32_t j = 0; j < k; j++) {
        if (!ps->use[j]) continue;
        int full = nc == SIMPLIFY_POCKET_CANDS;
        if (full && !(ps->cnt[j] > ps->cnt[cand[nc - 1]])) continue;
        int q = full ? nc - 1 : nc++;
        while (q > 0 && ps->cnt[j] > ps->cnt[cand[q - 1]]) {
            cand[q] = cand[q - 1];
            q--;
        }
        cand[q] = j;
    }
    ps->nc = nc;
}

/* fits[.][a][.] for candidate a, from its missed inliers. */
static void pocket_fits_of(pocket_state *ps, int a)
{
    const gp_cache *c = ps->c;
    double ca = cos(c->alpha);
    uint32_t ja = ps->cand[a];
    const double *va = c->v + (size_t)ja * c->n;
    const double *gx = c->g + 3 * (size_t)ja * c->n, *gy = gx + c->n, *gz = gy + c->n;
    double na = 0, in[2][SIMPLIFY_POCKET_CANDS];
    memset(in, 0, sizeof in);
    for (size_t i = 0; i < c->n; i++) {
        if (ps->ok[i] || !(fabs(va[i]) < c->eps_d)) continue;
        double gl = sqrt(gx[i] * gx[i] + gy[i] * gy[i] + gz[i] * gz[i]);
        if (!(gl > 0)) continue;
        const double *nn = c->nrm + 3 * i;
        if (!(fabs(gx[i] * nn[0] + gy[i] * nn[1] + gz[i] * nn[2]) / gl > ca)) continue;
        na += 1;
        for (int b = 0; b < ps->nc; b++) {
            double lb = c->v[(size_t)ps->cand[b] * c->n + i];
            if (ps->neg[ps->cand[b]]) lb = -lb;
            if (lb < c->eps_d) in[0][b] += 1;
            if (lb > -c->eps_d) in[1][b] += 1;
        }
    }
    for (int form = 0; form < 2; form++)
        for (int b = 0; b < ps->nc; b++) ps->fits[form][a][b] = 2 * in[form][b] > na;
}

/* ---- box cuts: a pocket closed by its far walls ---- */

/* A pocket in the shape of a box turned against the part (InverseCSG's cube with a
 * turned cube cut into its corner, in three_cuboids, six_cuboids and nine_cuboids)
 * shows three near walls that the points hold well and three far walls of 10-45
 * points of 50,000 each (a few of the GA's 4,096, so never useful candidates).  The
 * near walls alone cut a trihedral wedge through the whole part; closed by their far
 * walls they cut the box.  A plane candidate's far wall is the plane primitive
 * parallel to it within SIMPLIFY_BOX_PARALLEL_DEG, facing it (its outward normal
 * opposite), nearest beyond it: the box between them at least SIMPLIFY_BOX_MIN_WIDTH
 * eps_d thick. */
#define SIMPLIFY_BOX_PARALLEL_DEG 3.0
#define SIMPLIFY_BOX_MIN_WIDTH 2.0

/* far[] and far_neg[] of every plane candidate.  Literal values are planar, L(x) =
 * e - n.x with n the literal's outward normal, so two facing walls (normals n and -n)
 * sum to -(the width between them) at every point. */
static void box_partners(pocket_state *ps)
{
    const gp_cache *c = ps->c;
    double cp = cos(SIMPLIFY_BOX_PARALLEL_DEG * FREP_PI / 180.0);
    for (int a = 0; a < ps->nc; a++) {
        ps->far[a] = UINT32_MAX;
        ps->far_neg[a] = 0;
        if (!ps->isplane[a] || c->n == 0) continue;
        uint32_t ja = ps->cand[a];
        double pl = sqrt(ps->pn[a][0] * ps->pn[a][0] + ps->pn[a][1] * ps->pn[a][1] +
                         ps->pn[a][2] * ps->pn[a][2]);
        double la = c->v[(size_t)ja * c->n] / pl;
        if (ps->neg[ja]) la = -la;
        double best = INFINITY;
        for (uint32_t j = 0; j < c->nprims; j++) {
            double g[3];
            if (j == ja || !cache_plane(c, j, g)) continue;
            double gl = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
            /* literal p has outward normal -g, ~p has g: the far wall's faces -pn[a] */
            double cs = (g[0] * ps->pn[a][0] + g[1] * ps->pn[a][1] + g[2] * ps->pn[a][2]) /
                        (gl * pl);
            if (!(fabs(cs) >= cp)) continue;
            int ng = cs < 0;  /* ~p's outward normal g must be -pn[a] */
            double lj = c->v[(size_t)j * c->n] / gl;
            if (ng) lj = -lj;
            double width = -(la + lj);
            if (width >= SIMPLIFY_BOX_MIN_WIDTH * c->eps_d && width < best) {
                best = width;
                ps->far[a] = j;
                ps->far_neg[a] = (uint8_t)ng;
            }
        }
    }
}

/* Which candidates can be faces of one pocket or boss (the pairs test prunes most
 * subsets before any tree is scored: a tree of 100 nodes and 154 subsets would
 * otherwise cost 30,000 fitness evaluations per round), and the outward normals of the
 * plane candidates as literals (f >= 0 inside: -grad p points out). */
static int pocket_faces(pocket_state *ps, const gp_tree *t)
{
    const gp_cache *c = ps->c;
    ps->ok = frep_malloc(c->n ? c->n : 1);
    if (!ps->ok || gp_explained(c, ps->e, t->code, t->len, ps->ok)) return -1;
    for (int a = 0; a < ps->nc; a++) pocket_fits_of(ps, a);
    for (int a = 0; a < ps->nc; a++) {
        double g[3] = { 0, 0, 0 };
        ps->isplane[a] = (uint8_t)cache_plane(c, ps->cand[a], g);
        double sg = ps->neg[ps->cand[a]] ? 1.0 : -1.0;
        for (int d = 0; d < 3; d++) ps->pn[a][d] = sg * g[d];
    }
    box_partners(ps);
    return 0;
}

/* The box cut over the near walls idx[0..m) (2 or 3 plane candidates, a pocket's
 * faces by the pairs test): their literals, then their far walls', into lits and lneg
 * (2m of them).  0 when a wall has no far wall or two share one. */
static int box_cut(const pocket_state *ps, const int *idx, int m, uint32_t *lits, uint8_t *lneg)
{
    if (m < 2 || 2 * m > SIMPLIFY_BOSS_MAX) return 0;
    for (int a = 0; a < m; a++) {
        uint32_t f = ps->far[idx[a]];
        if (f == UINT32_MAX) return 0;
        for (int b = 0; b < m; b++)
            if (f == ps->cand[idx[b]] || (b < a && f == ps->far[idx[b]])) return 0;
        lits[a] = ps->cand[idx[a]];
        lneg[a] = ps->neg[lits[a]];
        lits[m + a] = f;
        lneg[m + a] = ps->far_neg[idx[a]];
    }
    return 1;
}

/* One subset of the candidates: its literals (a pocket or a boss over them), its box
 * cut's (box_cut), and which of the three forms it may build. */
typedef struct pocket_forms {
    uint32_t lits[SIMPLIFY_BOSS_MAX], box[SIMPLIFY_BOSS_MAX];
    uint8_t neg[SIMPLIFY_BOSS_MAX], box_neg[SIMPLIFY_BOSS_MAX];
    int m, box_m, ok[3];
} pocket_forms;

/* The literals of the candidates in mask (pf->lits, pf->neg, pf->m), and in pf->ok
 * which forms they may build: 2 to SIMPLIFY_POCKET_MAX faces for a pocket, 4 to
 * SIMPLIFY_BOSS_MAX planes bounding a finite region for a boss, every pair fitting;
 * a box cut (box_cut, into pf->box). 0: none. */
static int pocket_subset(const pocket_state *ps, unsigned mask, pocket_forms *pf)
{
    uint32_t *lits = pf->lits;
    int *form_ok = pf->ok;
    int idx[SIMPLIFY_BOSS_MAX];
    double bn[SIMPLIFY_BOSS_MAX][3];
    int m = 0, planes = 1;
    for (int q = 0; q < ps->nc; q++)
        if (mask >> q & 1u) {
            if (m == SIMPLIFY_BOSS_MAX) { m = SIMPLIFY_BOSS_MAX + 1; break; }
            idx[m] = q;
            planes &= ps->isplane[q];
            memcpy(bn[m], ps->pn[q], sizeof bn[m]);
            pf->neg[m] = ps->neg[ps->cand[q]];
            lits[m++] = ps->cand[q];
        }
    pf->m = m;
    if (m < 2 || m > SIMPLIFY_BOSS_MAX) return 0;
    form_ok[0] = m <= SIMPLIFY_POCKET_MAX;
    form_ok[1] = planes && m >= 4;
    for (int form = 0; form < 2; form++)
        for (int a = 0; a < m; a++)
            for (int b = 0; b < m; b++)
                if (a != b && !ps->fits[form][idx[a]][idx[b]]) form_ok[form] = 0;
    if (form_ok[1] && !planes_bounded((const double (*)[3])bn, m)) form_ok[1] = 0;
    form_ok[2] = form_ok[0] && planes && box_cut(ps, idx, m, pf->box, pf->box_neg);
    pf->box_m = form_ok[2] ? 2 * m : 0;
    return form_ok[0] || form_ok[1] || form_ok[2];
}

/* The pieces of the allowed forms below every subtree of t (taped), the fittest kept.
 * A box cut (form 2) is built as a pocket over its walls. */
static int pocket_try(pocket_state *ps, const gp_tree *t, const pocket_forms *pf)
{
    for (uint32_t end = 0; end < t->len; end++) {
        uint32_t st = tree_subtree_start(t->code, end);
        frep_insn lf = gp_tape_leaf(ps->c, end);
        for (int form = 0; form < 3; form++) {
            if (!pf->ok[form]) continue;
            const uint32_t *lits = form == 2 ? pf->box : pf->lits;
            const uint8_t *neg = form == 2 ? pf->box_neg : pf->neg;
            int m = form == 2 ? pf->box_m : pf->m;
            double f;
            if (build_pocket(&ps->sub, &lf, 0, 0, lits, neg, m, form == 1, ps->o) ||
                gp_fitness_replaced(ps->c, ps->e, st, end, ps->sub.code, ps->sub.len, ps->bf,
                                    &f))
                return -1;
            if (f > ps->bf) {
                ps->bf = f;
                ps->best_end = end;
                ps->best_m = m;
                ps->best_form = form == 1;
                memcpy(ps->best_lits, lits, (size_t)m * sizeof *lits);
                memcpy(ps->best_neg, neg, (size_t)m);
            }
        }
    }
    return 0;
}

/* The round's search: candidates, faces, every subset (as bit masks over the
 * candidates) below every subtree. 1: a better variant found, 0: none. */
static int pocket_search(pocket_state *ps, gp_tree *t)
{
    long nu = useful_prims_oriented(t, ps->c, ps->e, ps->use, ps->cnt, ps->neg);
    if (nu < 0) return -1;
    if (nu < 2) return 0;
    pocket_candidates(ps);
    if (pocket_faces(ps, t) || record(t, ps->c, ps->e, NULL)) return -1;
    for (unsigned mask = 0; mask < (1u << ps->nc); mask++) {
        pocket_forms pf;
        if (!pocket_subset(ps, mask, &pf)) continue;
        if (pocket_try(ps, t, &pf)) return -1;
    }
    return ps->best_m != 0;
}

/* One round: the best pocket of 2 to SIMPLIFY_POCKET_MAX primitives cut from
 * any subtree S (a box cut from one part of a union: its faces intersected there, not
 * at the root where they would cut every part), or boss of 4 to SIMPLIFY_BOSS_MAX
 * planes bounding a finite region joined to S (a missing cuboid), when it raises the
 * fitness. No part of either improves the tree alone (one wall cuts a half-space away,
 * one face of a box adds a half-space), so the inner growth and the root pieces cannot
 * build them. 1 when t changed, 0 when not, -1 on allocation failure. */
static int grow_pocket(gp_tree *t, gp_tree *trial, const gp_opset *o, const gp_cache *c,
                       gp_eval *e, double *fit)
{
    uint32_t k = c->nprims;
    if (k < 2) return 0;
    pocket_state ps;
    memset(&ps, 0, sizeof ps);
    ps.c = c;
    ps.e = e;
    ps.o = o;
    ps.bf = *fit;
    ps.use = frep_malloc(k);
    ps.neg = frep_malloc(k);
    ps.cnt = frep_malloc(k * sizeof *ps.cnt);
    int rc = !ps.use || !ps.neg || !ps.cnt ? -1 : pocket_search(&ps, t);
    if (rc > 0) {
        uint32_t st = tree_subtree_start(t->code, ps.best_end);
        rc = build_pocket(&ps.sub, t->code, st, ps.best_end, ps.best_lits, ps.best_neg, ps.best_m,
                          ps.best_form, o)
                 ? -1
                 : commit_splice(t, trial, ps.best_end, &ps.sub);
        if (rc > 0) *fit = ps.bf;
    }
    tree_free(&ps.sub);
    frep_free(ps.use);
    frep_free(ps.neg);
    frep_free(ps.cnt);
    frep_free(ps.ok);
    return rc;
}

/* ---- trims: a part of a union bounded by a face it lacks ----------------------- */

/* Trims added at most (each round is one pass over the union's parts and every
 * primitive, both orientations). */
#define SIMPLIFY_MAX_TRIMS 8

/* Polarity of every node of t: 1 when its material adds to the solid (an even number
 * of complements and right operands of subtractions above it), 0 when it is removed.
 * pol[len] filled; parents come after their children in postfix, so one pass from the
 * root down sets every node. */
static void node_polarity(const gp_tree *t, const gp_opset *o, uint8_t *pol)
{
    if (!t->len) return;
    pol[t->len - 1] = 1;
    for (uint32_t end = t->len; end-- > 0;) {
        int k = tree_nin(&t->code[end]);
        if (k == 0) continue;
        uint8_t op = (uint8_t)t->code[end].op;
        if (k == 1) {
            pol[end - 1] = op == o->neg ? (uint8_t)!pol[end] : pol[end];
            continue;
        }
        uint32_t l0, l1, r0;
        tree_operands(t->code, end, &l0, &l1, &r0);
        pol[l1] = pol[end];
        pol[end - 1] = op == o->sub ? (uint8_t)!pol[end] : pol[end];
    }
}

void simplify_polarity(const gp_tree *t, gp_setops s, uint8_t *pol)
{
    gp_opset o = gp_opset_of(s);
    node_polarity(t, &o, pol);
}

void simplify_trim_keeps(const gp_tree *t, uint32_t other, const gp_cache *c, uint32_t j,
                         const uint8_t *ok, const uint8_t *oks, int can[2])
{
    const double *v = c->v + (size_t)j * c->n;
    for (size_t i = 0; i < c->n && (can[0] || can[1]); i++) {
        if (!oks[i] || !ok[i]) continue;
        if (v[i] < -c->eps_d) can[0] = 0;
        if (v[i] > c->eps_d) can[1] = 0;
    }
    /* A | (B & ~A) is A | B: no trim when the other operand is p. */
    const frep_insn *oth = &t->code[other];
    if (tree_nin(oth) == 0 && oth->arg == j) can[1] = 0;
}

int simplify_trim_code(gp_tree *sub, const frep_insn *head, uint32_t nhead, uint32_t j,
                       int neg, const gp_opset *o)
{
    return tree_set(sub, head, nhead) || tree_push(sub, FREP_OP_PRIM, j) ||
                   (neg && tree_push(sub, (frep_opcode)o->neg, 0)) ||
                   tree_push(sub, (frep_opcode)o->inter, 0)
               ? -1
               : 0;
}

/* One round: the best S & L replacing an operand S of a union that adds material,
 * L = p or ~p for a primitive p that keeps every point S explains (L >= -eps_d there),
 * when the trimmed tree explains more points and scores no lower (size penalty aside).
 * A part whose points lie between two planes the tree does not use runs through empty
 * space to the clipping box; eq. 7 sees no material where there are no points, and the
 * few points of the part's small end faces (inside it until trimmed) do not pay for
 * the nodes, so the fitness alone never adds the face. The trim is supported by those
 * points: it is kept only when the face explains points the tree missed, so a plane
 * merely lying beyond S's points (which would cut nothing the points show) is not
 * added. 1 when t changed, 0 when not, -1 on allocation failure. */
static int grow_trim(gp_tree *t, gp_tree *trial, const gp_opset *o, const gp_cache *c,
                     gp_eval *e, gp_cancel *cancel)
{
    uint32_t k = c->nprims;
    size_t n = c->n;
    uint8_t *pol = frep_malloc(t->len), *ok = frep_malloc(n ? n : 1), *oks = frep_malloc(n ? n : 1);
    uint8_t *sup = NULL;
    gp_tree sub = { NULL, 0, 0 };
    int rc = -1;
    if (!pol || !ok || !oks) goto out;
    if (gp_explained(c, e, t->code, t->len, ok)) goto out;
    node_polarity(t, o, pol);
    /* sup[2j + ng]: L = p (ng 0) or ~p (ng 1) has inliers the tree misses, the points a
     * trim by it can explain (and the cheap test that prunes most candidates). */
    sup = frep_calloc(2 * (size_t)(k ? k : 1), 1);
    if (!sup) goto out;
    {
        double ca = cos(c->alpha);
        for (uint32_t j = 0; j < k; j++) {
            const double *v = c->v + (size_t)j * n;
            const double *gx = c->g + 3 * (size_t)j * n, *gy = gx + n, *gz = gy + n;
            for (size_t i = 0; i < n && !(sup[2 * j] && sup[2 * j + 1]); i++) {
                if (ok[i] || !(fabs(v[i]) < c->eps_d)) continue;
                double gl = sqrt(gx[i] * gx[i] + gy[i] * gy[i] + gz[i] * gz[i]);
                if (!(gl > 0)) continue;
                const double *nn = c->nrm + 3 * i;
                double cs = (gx[i] * nn[0] + gy[i] * nn[1] + gz[i] * nn[2]) / gl;
                if (-cs > ca) sup[2 * j] = 1;     /* f >= 0 inside: -grad p points out */
                if (cs > ca) sup[2 * j + 1] = 1;
            }
        }
    }
    gp_stats st0;
    if (gp_tree_stats(c, e, t->code, t->len, &st0) || record(t, c, e, NULL)) goto out;
    double bs = st0.score;
    size_t bn = st0.explained;
    uint32_t best_end = 0, best_j = 0;
    int best_neg = -1;
    for (uint32_t u = 0; u < t->len; u++) {
        if (tree_nin(&t->code[u]) != 2 || t->code[u].op != o->uni || !pol[u]) continue;
        uint32_t l0, l1, r0;
        tree_operands(t->code, u, &l0, &l1, &r0);
        const uint32_t ends[2] = { l1, u - 1 };
        for (int side = 0; side < 2; side++) {
            uint32_t end = ends[side];
            uint32_t st = tree_subtree_start(t->code, end);
            /* The points S explains alone that the tree explains too. */
            if (gp_explained(c, e, t->code + st, end - st + 1, oks)) goto out;
            frep_insn lf = gp_tape_leaf(c, end);
            for (uint32_t j = 0; j < k; j++) {
                if (gp_cancelled(cancel)) {   /* the tree stays as it stands */
                    rc = 0;
                    goto out;
                }
                int can[2] = { sup[2 * j], sup[2 * j + 1] };  /* keeps them as p, ~p */
                simplify_trim_keeps(t, ends[1 - side], c, j, ok, oks, can);
                for (int ng = 0; ng < 2; ng++) {
                    if (!can[ng]) continue;
                    if (simplify_trim_code(&sub, &lf, 1, j, ng, o)) goto out;
                    gp_stats stt;
                    if (gp_stats_replaced(c, e, st, end, sub.code, sub.len, &stt)) goto out;
                    if (stt.explained > bn && !(stt.score < bs)) {
                        bs = stt.score;
                        bn = stt.explained;
                        best_end = end;
                        best_j = j;
                        best_neg = ng;
                    }
                }
            }
        }
    }
    rc = 0;
    if (best_neg < 0) goto out;
    {
        uint32_t st = tree_subtree_start(t->code, best_end);
        rc = simplify_trim_code(&sub, t->code + st, best_end - st + 1, best_j, best_neg, o)
                 ? -1
                 : commit_splice(t, trial, best_end, &sub);
    }
out:
    tree_free(&sub);
    frep_free(pol);
    frep_free(ok);
    frep_free(oks);
    frep_free(sup);
    return rc;
}

static int inner_step(gp_tree *t, gp_tree *trial, const gp_cache *c, gp_eval *e,
                      const void *o, double *fit)
{
    return grow_inner(t, trial, o, c, e, fit);
}

static int pocket_step(gp_tree *t, gp_tree *trial, const gp_cache *c, gp_eval *e,
                       const void *o, double *fit)
{
    return grow_pocket(t, trial, o, c, e, fit);
}

int simplify_grow_pockets(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                          double *fitness, gp_cancel *k)
{
    gp_opset o = gp_opset_of(s);
    return climb(t, s, c, e, pocket_step, &o, SIMPLIFY_MAX_POCKETS, fitness, k);
}

int simplify_grow_inner(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                        double *fitness, gp_cancel *k)
{
    gp_opset o = gp_opset_of(s);
    return climb(t, s, c, e, inner_step, &o, SIMPLIFY_MAX_INNER, fitness, k);
}

int simplify_grow_pieces(gp_tree *t, gp_setops s, const gp_cache *c, gp_eval *e,
                         double *fitness, gp_cancel *k)
{
    if (!t->len) return 0;
    double fit;
    if (simplify_grow_inner(t, s, c, e, &fit, k) || simplify_grow_pockets(t, s, c, e, &fit, k))
        return -1;
    gp_opset o = gp_opset_of(s);
    gp_tree trial = { NULL, 0, 0 };
    int rc = -1;
    for (int round = 0; round < SIMPLIFY_MAX_PIECES && !gp_cancelled(k); round++) {
        int g = grow_piece(t, &trial, &o, c, e, &fit, k);
        if (g < 0) goto out;
        if (g == 0) break;
        /* The piece may make part of the tree redundant (a face the GA had faked). */
        if (simplify_tree(t, s, c, e, &fit, k)) goto out;
    }
    /* Last: a trim costs two nodes the fitness does not pay for, so the removal moves
     * of simplify_tree would take it out again; only the exact rules follow it. */
    for (int round = 0; round < SIMPLIFY_MAX_TRIMS && !gp_cancelled(k); round++) {
        int g = grow_trim(t, &trial, &o, c, e, k);
        if (g < 0) goto out;
        if (g == 0) break;
        if (simplify_rules(t, s)) goto out;
        if (gp_fitness(c, e, t->code, t->len, &fit)) goto out;
    }
    rc = 0;
    if (fitness) *fitness = fit;
out:
    tree_free(&trial);
    return rc;
}

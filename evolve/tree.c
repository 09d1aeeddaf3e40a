/* tree.c - GP construction trees as postfix bytecode: random growth, splicing
 * crossover and mutation, structural comparison, printing (infix and Graphviz).
 * Used by gp.c (evolution), simplify.c and partition.c (merge); see tree.h.
 */
#include "config.h"

#include "alloc.h"
#include "buf.h"
#include "tree.h"

#include <stdlib.h>
#include <string.h>

gp_opset gp_opset_of(gp_setops s)
{
    gp_opset o;
    if (s == GP_SETOPS_RFUNC) {
        o.uni = FREP_OP_RUNI;
        o.inter = FREP_OP_RINT;
        o.sub = FREP_OP_RSUB;
    } else {
        o.uni = FREP_OP_MAX;
        o.inter = FREP_OP_MIN;
        o.sub = FREP_OP_MSUB;
    }
    o.neg = FREP_OP_NEG;
    return o;
}

/* ---- random numbers ------------------------------------------------------- */

void gp_rng_seed(gp_rng *r, uint64_t seed) { frep_rng_seed(r, seed); }
uint64_t gp_rng_next(gp_rng *r) { return frep_rng_next(r); }
double gp_rng_unif(gp_rng *r) { return frep_rng_unit(r); }

uint32_t gp_rng_below(gp_rng *r, uint32_t n)
{
    /* Multiply-shift: bias below 2^-32, irrelevant for selection. */
    return (uint32_t)(((gp_rng_next(r) >> 32) * (uint64_t)n) >> 32);
}

/* ---- storage -------------------------------------------------------------- */

int tree_reserve(gp_tree *t, uint32_t cap)
{
    if (cap <= t->cap) return 0;
    if (cap > GP_MAX_TREE_LEN) return -1;
    uint32_t nc = t->cap ? t->cap : 16;
    while (nc < cap) nc = nc > GP_MAX_TREE_LEN / 2 ? GP_MAX_TREE_LEN : nc * 2;
    frep_insn *c = frep_realloc(t->code, (size_t)nc * sizeof *c);
    if (!c) return -1;
    t->code = c;
    t->cap = nc;
    return 0;
}

void tree_free(gp_tree *t)
{
    frep_free(t->code);
    t->code = NULL;
    t->len = t->cap = 0;
}

int tree_set(gp_tree *dst, const frep_insn *code, uint32_t len)
{
    if (tree_reserve(dst, len ? len : 1)) return -1;
    if (len) memmove(dst->code, code, (size_t)len * sizeof *code);
    dst->len = len;
    return 0;
}

int tree_copy(gp_tree *dst, const gp_tree *src)
{
    return tree_set(dst, src->code, src->len);
}

int tree_push(gp_tree *t, frep_opcode op, uint32_t arg)
{
    if (tree_reserve(t, t->len + 1)) return -1;
    frep_insn in = { (uint8_t)op, 0, 0, arg, 0.0 };
    t->code[t->len++] = in;
    return 0;
}

/* ---- structure ------------------------------------------------------------ */

int tree_nin(const frep_insn *in)
{
    switch (in->op) {
    case FREP_OP_PRIM:
        return 0;
    case FREP_OP_NEG:
        return 1;
    default:
        return 2;
    }
}

uint32_t tree_subtree_start(const frep_insn *code, uint32_t end)
{
    /* Walk back until the values still needed by `end` have all been produced. */
    long need = 1;
    uint32_t pc = end;
    for (;;) {
        need += tree_nin(&code[pc]) - 1;
        if (need == 0 || pc == 0) return pc;
        pc--;
    }
}

void tree_operands(const frep_insn *code, uint32_t end, uint32_t *l0, uint32_t *l1,
                   uint32_t *r0)
{
    uint32_t rs = tree_subtree_start(code, end - 1);
    *r0 = rs;
    *l1 = rs - 1;
    *l0 = tree_subtree_start(code, rs - 1);
}

int tree_levels(const frep_insn *code, uint32_t len, uint16_t *lev)
{
    /* Reversed postfix is a preorder (right operand first): a stack of the levels of
     * the nodes still to visit assigns each node its level. */
    if (!len) return 0;
    uint16_t *st = frep_malloc((size_t)len * sizeof *st);
    if (!st) return -1;
    uint32_t sp = 0;
    st[sp++] = 1;
    for (uint32_t pc = len; pc-- > 0;) {
        uint16_t l = sp ? st[--sp] : 1;
        lev[pc] = l;
        int k = tree_nin(&code[pc]);
        for (int i = 0; i < k && sp < len; i++) st[sp++] = (uint16_t)(l + 1);
    }
    frep_free(st);
    return 0;
}

int tree_depth(const frep_insn *code, uint32_t len)
{
    /* Postfix evaluation of heights. The stack of a tree never holds more entries than
     * its depth (each entry below the top waits for a distinct ancestor of the top), so
     * GP_MAX_TREE_DEPTH + 1 of them decide every depth up to the limit: no allocation
     * that could fail. */
    int st[GP_MAX_TREE_DEPTH + 1];
    uint32_t sp = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        int k = tree_nin(&code[pc]), h = 0;
        for (int i = 0; i < k && sp > 0; i++) {
            int c = st[--sp];
            if (c > h) h = c;
        }
        if (h >= GP_MAX_TREE_DEPTH + 1 || sp == GP_MAX_TREE_DEPTH + 1)
            return GP_MAX_TREE_DEPTH + 1;
        st[sp++] = h + 1;
    }
    return sp ? st[sp - 1] : 0;
}

int tree_valid(const frep_insn *code, uint32_t len, uint32_t nprims, gp_setops s)
{
    if (!len) return 0;
    gp_opset o = gp_opset_of(s);
    long sp = 0;
    for (uint32_t pc = 0; pc < len; pc++) {
        const frep_insn *in = &code[pc];
        if (in->op == FREP_OP_PRIM) {
            if (in->arg >= nprims) return 0;
        } else if (in->op != o.uni && in->op != o.inter && in->op != o.sub &&
                   in->op != o.neg) {
            return 0;
        }
        sp += 1 - tree_nin(in);
        if (sp < 1) return 0;
    }
    return sp == 1 && tree_depth(code, len) <= GP_MAX_TREE_DEPTH;
}

uint32_t tree_count_prims(const frep_insn *code, uint32_t len, uint32_t nprims)
{
    uint8_t *seen = frep_calloc(nprims ? nprims : 1, 1);
    if (!seen) return 0;
    uint32_t n = 0;
    for (uint32_t pc = 0; pc < len; pc++)
        if (code[pc].op == FREP_OP_PRIM && code[pc].arg < nprims && !seen[code[pc].arg]) {
            seen[code[pc].arg] = 1;
            n++;
        }
    frep_free(seen);
    return n;
}

int tree_splice(gp_tree *t, uint32_t s0, uint32_t s1, const frep_insn *src, uint32_t n)
{
    uint32_t old = s1 - s0 + 1;
    uint32_t nlen = t->len - old + n;
    if (n > old && tree_reserve(t, nlen)) return -1;
    memmove(t->code + s0 + n, t->code + s1 + 1, (size_t)(t->len - s1 - 1) * sizeof *t->code);
    memmove(t->code + s0, src, (size_t)n * sizeof *src);
    t->len = nlen;
    return 0;
}

/* ---- random growth and variation ------------------------------------------ */

/* Grow recursively; the recursion depth is bounded by max_depth, the size by limit
 * (past it every node still to make is a leaf, so the tree ends within limit + 2 x
 * depth nodes). */
static int grow(gp_tree *t, gp_rng *r, const gp_opset *o, uint32_t nprims, int depth_left,
                double p_sub, uint32_t limit)
{
    if (depth_left > 1 && gp_rng_unif(r) < p_sub && t->len < limit) {
        /* The four operations of the paper, equally likely. */
        uint32_t w = gp_rng_below(r, 4);
        if (w == 3) {
            if (grow(t, r, o, nprims, depth_left - 1, p_sub, limit)) return -1;
            return tree_push(t, (frep_opcode)o->neg, 0);
        }
        if (grow(t, r, o, nprims, depth_left - 1, p_sub, limit)) return -1;
        if (grow(t, r, o, nprims, depth_left - 1, p_sub, limit)) return -1;
        uint8_t op = w == 0 ? o->uni : w == 1 ? o->inter : o->sub;
        return tree_push(t, (frep_opcode)op, 0);
    }
    return tree_push(t, FREP_OP_PRIM, gp_rng_below(r, nprims));
}

int tree_grow(gp_tree *t, gp_rng *r, gp_setops s, uint32_t nprims, int max_depth,
              double p_sub)
{
    gp_opset o = gp_opset_of(s);
    if (max_depth < 1) max_depth = 1;
    if (max_depth > GP_MAX_TREE_DEPTH) max_depth = GP_MAX_TREE_DEPTH;
    return grow(t, r, &o, nprims ? nprims : 1, max_depth, p_sub, t->len + GP_MAX_GROW_NODES);
}

int tree_crossover(gp_tree *child, const gp_tree *a, const gp_tree *b, gp_rng *r,
                   int max_depth)
{
    if (tree_copy(child, a)) return -1;
    uint32_t ea = gp_rng_below(r, a->len), eb = gp_rng_below(r, b->len);
    uint32_t sa = tree_subtree_start(a->code, ea), sb = tree_subtree_start(b->code, eb);
    if ((uint64_t)a->len - (ea - sa + 1) + (eb - sb + 1) > GP_MAX_BRED_LEN) return 0;
    if (tree_splice(child, sa, ea, b->code + sb, eb - sb + 1)) return -1;
    if (tree_depth(child->code, child->len) > max_depth) {
        if (tree_copy(child, a)) return -1;
        return 0;
    }
    return 1;
}

int tree_mutate(gp_tree *t, gp_rng *r, gp_setops s, uint32_t nprims, int max_depth,
                double p_sub)
{
    if (t->len == 0 || gp_rng_unif(r) < 0.5) {
        t->len = 0;
        return tree_grow(t, r, s, nprims, max_depth, p_sub);
    }
    uint32_t e = gp_rng_below(r, t->len);
    uint32_t st = tree_subtree_start(t->code, e);
    uint16_t *lev = frep_malloc((size_t)t->len * sizeof *lev);
    if (!lev || tree_levels(t->code, t->len, lev)) {
        frep_free(lev);
        return -1;
    }
    int room = max_depth - lev[e] + 1;
    frep_free(lev);
    gp_tree sub = { NULL, 0, 0 };
    if (tree_grow(&sub, r, s, nprims, room < 1 ? 1 : room, p_sub)) {
        tree_free(&sub);
        return -1;
    }
    if ((uint64_t)t->len - (e - st + 1) + sub.len > GP_MAX_BRED_LEN) {
        tree_free(&sub);  /* too long a child: t stays as it was */
        return 0;
    }
    if (tree_splice(t, st, e, sub.code, sub.len)) {
        tree_free(&sub);
        return -1;
    }
    tree_free(&sub);
    return 0;
}

/* ---- comparison and hashing ----------------------------------------------- */

int tree_compare(const frep_insn *a, uint32_t ea, const frep_insn *b, uint32_t eb)
{
    uint32_t sa = tree_subtree_start(a, ea), sb = tree_subtree_start(b, eb);
    uint32_t na = ea - sa + 1, nb = eb - sb + 1;
    if (na != nb) return na < nb ? -1 : 1;
    for (uint32_t i = 0; i < na; i++) {
        const frep_insn *x = &a[sa + i], *y = &b[sb + i];
        if (x->op != y->op) return x->op < y->op ? -1 : 1;
        if (x->arg != y->arg) return x->arg < y->arg ? -1 : 1;
    }
    return 0;
}

uint64_t tree_hash(const frep_insn *code, uint32_t len)
{
    uint64_t h = 0xcbf29ce484222325u ^ len;
    for (uint32_t i = 0; i < len; i++) {
        h ^= (uint64_t)code[i].op | ((uint64_t)code[i].arg << 8);
        h *= 0x100000001b3u;
        h ^= h >> 29;
    }
    return h;
}

/* ---- printing ------------------------------------------------------------- */

static char op_char(uint8_t op)
{
    switch (op) {
    case FREP_OP_MAX:
    case FREP_OP_RUNI:
        return '|';
    case FREP_OP_MIN:
    case FREP_OP_RINT:
        return '&';
    case FREP_OP_MSUB:
    case FREP_OP_RSUB:
        return '\\';
    default:
        return '?';
    }
}

static void print_rec(frep_buf *b, const frep_insn *code, uint32_t end, const char *prefix,
                      int top)
{
    const frep_insn *in = &code[end];
    int k = tree_nin(in);
    if (k == 0) {
        buf_printf(b, "%s%u", prefix, in->arg + 1);
    } else if (k == 1) {
        buf_putc(b, '~');
        print_rec(b, code, end - 1, prefix, 0);
    } else {
        uint32_t l0, l1, r0;
        tree_operands(code, end, &l0, &l1, &r0);
        (void)l0;
        if (!top) buf_putc(b, '(');
        print_rec(b, code, l1, prefix, 0);
        buf_printf(b, " %c ", op_char(in->op));
        print_rec(b, code, end - 1, prefix, 0);
        if (!top) buf_putc(b, ')');
    }
}

void tree_print(frep_buf *b, const frep_insn *code, uint32_t len, const char *prefix)
{
    if (!len) return;
    print_rec(b, code, len - 1, prefix, 1);
}

void tree_print_dot(FILE *f, const frep_insn *code, uint32_t len,
                    const char *const *names)
{
    fprintf(f, "digraph frep_tree {\n  node [fontname=\"Helvetica\"];\n");
    /* Node ids are pcs; each binary node links to the ends of its operands. */
    for (uint32_t pc = 0; pc < len; pc++) {
        const frep_insn *in = &code[pc];
        int k = tree_nin(in);
        if (k == 0) {
            if (names && names[in->arg])
                fprintf(f, "  n%u [shape=box,label=\"%s\"];\n", pc, names[in->arg]);
            else
                fprintf(f, "  n%u [shape=box,label=\"p%u\"];\n", pc, in->arg + 1);
        } else if (k == 1) {
            fprintf(f, "  n%u [shape=circle,label=\"~\"];\n  n%u -> n%u;\n", pc, pc, pc - 1);
        } else {
            uint32_t l0, l1, r0;
            tree_operands(code, pc, &l0, &l1, &r0);
            (void)l0;
            (void)r0;
            const char *lab = op_char(in->op) == '|' ? "union"
                            : op_char(in->op) == '&' ? "intersection" : "subtraction";
            fprintf(f, "  n%u [shape=ellipse,label=\"%s\"];\n", pc, lab);
            fprintf(f, "  n%u -> n%u [label=\"1\"];\n  n%u -> n%u [label=\"2\"];\n", pc, l1,
                    pc, pc - 1);
        }
    }
    fprintf(f, "}\n");
}

uint32_t tree_used_prims(const gp_tree *t, uint32_t nprims, uint32_t **out)
{
    uint8_t *seen = frep_calloc(nprims ? nprims : 1, 1);
    uint32_t n = 0;
    *out = NULL;
    if (!seen) return 0;
    for (uint32_t pc = 0; pc < t->len; pc++)
        if (t->code[pc].op == FREP_OP_PRIM) seen[t->code[pc].arg] = 1;
    for (uint32_t j = 0; j < nprims; j++) n += seen[j];
    *out = frep_malloc((size_t)(n ? n : 1) * sizeof **out);
    if (*out) {
        n = 0;
        for (uint32_t j = 0; j < nprims; j++)
            if (seen[j]) (*out)[n++] = j;
    } else {
        n = 0;
    }
    frep_free(seen);
    return n;
}

void tree_renumber(gp_tree *t, const uint32_t *prims, uint32_t k, int dir)
{
    for (uint32_t pc = 0; pc < t->len; pc++) {
        frep_insn *in = &t->code[pc];
        if (in->op != FREP_OP_PRIM) continue;
        if (dir) {
            in->arg = prims[in->arg];
        } else {
            uint32_t lo = 0, hi = k;
            while (lo < hi) {
                uint32_t mid = (lo + hi) / 2;
                if (prims[mid] < in->arg) lo = mid + 1;
                else hi = mid;
            }
            in->arg = lo;
        }
    }
}

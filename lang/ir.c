/* ir.c - the compiler's IR: a hash-consed DAG of scalar operations (see ir.h).
 *
 * Pipeline: lang/lower.c and lang/lib.c build it node by node; lang/emit.c schedules
 * it into bytecode.  Building a node folds constants with the runtime's own scalar
 * semantics (runtime/opsem.h), applies a few simplifications that are exact in IEEE
 * arithmetic, and returns an existing identical node when there is one (CSE).
 *
 * Simplifications (all exact, signed zeros and NaN included; each checked in
 * tests/test_compile.c):
 *   a*1 = 1*a = a      a/1 = a        a-0 = a       a+(-0) = a
 *   a*-1 = -a          -(-a) = a      a*a = square(a)
 *   a+(-b) = a-b       a-(-b) = a+b
 *   square(-a) = square(|a|) = square(a)     |-a| = |a|
 *   select(c, a, a) = a      select(const c, a, b) = a or b
 * Not done, because they are not exact: a+0 (-0+0 is +0), a*0 (NaN, inf, -0),
 * a-a (inf, NaN), -(a-b) = b-a (signed zero).  Commutative operands are put in a
 * canonical order for CSE, except for min and max: on a tie they return (and
 * differentiate) their first operand, so min(-0, +0) differs from min(+0, -0).
 */
#include "ir.h"

#include <math.h>
#include <string.h>

#include "opsem.h"
#include "program.h"

#define IR_INITIAL_CAP 256u      /* nodes; doubled as needed */
#define IR_INITIAL_BUCKETS 512u  /* hash heads; kept >= nodes / 2 */

void ir_init(ir *g, arena *A, int optimize)
{
    memset(g, 0, sizeof *g);
    g->A = A;
    g->optimize = optimize;
}

void ir_set_pos(ir *g, uint32_t line, uint32_t col, uint32_t len)
{
    g->line = line;
    g->col = col;
    g->len = len;
}

static uint64_t ir_dbits(double k)
{
    uint64_t u;
    memcpy(&u, &k, sizeof u);
    return u;
}

static uint32_t ir_hash(const ir_node *n)
{
    uint64_t h = 1469598103934665603ull;
    uint64_t parts[6];
    unsigned i;
    parts[0] = (uint64_t)n->op | ((uint64_t)n->quiet << 8) | ((uint64_t)n->arg << 16);
    parts[1] = ir_dbits(n->k);
    parts[2] = n->in[0];
    parts[3] = n->in[1];
    parts[4] = n->in[2];
    parts[5] = 0x9e3779b97f4a7c15ull;
    for (i = 0; i < 6; i++) {
        h ^= parts[i];
        h *= 1099511628211ull;
        h ^= h >> 29;
    }
    return (uint32_t)(h ^ (h >> 32));
}

static int ir_same(const ir_node *a, const ir_node *b)
{
    return a->op == b->op && a->quiet == b->quiet && a->arg == b->arg &&
           ir_dbits(a->k) == ir_dbits(b->k) && a->in[0] == b->in[0] &&
           a->in[1] == b->in[1] && a->in[2] == b->in[2];
}

static int ir_rehash(ir *g, uint32_t nb)
{
    uint32_t *b = arena_alloc(g->A, (size_t)nb * sizeof *b);
    uint32_t i;
    if (!b) return -1;
    for (i = 0; i < nb; i++) b[i] = IR_NONE;
    for (i = 0; i < g->n; i++) {
        uint32_t h = ir_hash(&g->nodes[i]) & (nb - 1);
        g->nodes[i].hnext = b[h];
        b[h] = i;
    }
    g->buckets = b;
    g->nbuckets = nb;
    return 0;
}

/* Find or append node t. On failure (memory, node limit) returns 0 with g->failed set
 * to the reason;
 * node 0 always exists then (or the caller sees failed before using refs). */
static ir_ref ir_intern(ir *g, ir_node t)
{
    uint32_t h, i;
    t.uses = 0;
    t.hnext = IR_NONE;
    t.quiet = (uint8_t)(t.quiet || g->quiet);
    if (g->failed) return 0;
    if (g->optimize && g->buckets) {
        h = ir_hash(&t) & (g->nbuckets - 1);
        for (i = g->buckets[h]; i != IR_NONE; i = g->nodes[i].hnext)
            if (ir_same(&g->nodes[i], &t)) return i;
    }
    if (g->n >= FREP_IR_MAX_NODES) {
        g->failed = IR_TOO_LARGE;
        return 0;
    }
    if (g->n == g->cap) {
        uint32_t ncap = g->cap ? 2 * g->cap : IR_INITIAL_CAP;
        ir_node *nn = arena_grow(g->A, g->nodes, g->n, ncap, sizeof *nn);
        if (!nn) {
            g->failed = IR_NOMEM;
            return 0;
        }
        g->nodes = nn;
        g->cap = ncap;
    }
    t.line = g->line;
    t.col = g->col;
    t.len = g->len;
    g->nodes[g->n] = t;
    i = g->n++;
    if (g->optimize) {
        if (!g->buckets || g->n > 2 * g->nbuckets) {
            if (ir_rehash(g, g->buckets ? 2 * g->nbuckets : IR_INITIAL_BUCKETS) < 0) {
                g->failed = IR_NOMEM;
                return 0;
            }
        } else {
            h = ir_hash(&g->nodes[i]) & (g->nbuckets - 1);
            g->nodes[i].hnext = g->buckets[h];
            g->buckets[h] = i;
        }
    }
    return i;
}

static ir_node ir_blank(frep_opcode op)
{
    ir_node t;
    memset(&t, 0, sizeof t);
    t.op = (uint8_t)op;
    t.in[0] = t.in[1] = t.in[2] = IR_NONE;
    return t;
}

int ir_is_const(const ir *g, ir_ref r, double *k)
{
    if (r >= g->n || g->nodes[r].op != FREP_OP_CONST) return 0;
    if (k) *k = g->nodes[r].k;
    return 1;
}

ir_ref ir_const(ir *g, double k)
{
    ir_node t = ir_blank(FREP_OP_CONST);
    t.k = k;
    /* Constants are never quiet: they cannot fail, and sharing them keeps the
     * immediates of quiet and loud code identical. */
    {
        int q = g->quiet;
        ir_ref r;
        g->quiet = 0;
        r = ir_intern(g, t);
        g->quiet = q;
        return r;
    }
}

ir_ref ir_leaf(ir *g, frep_opcode op, uint32_t arg)
{
    ir_node t = ir_blank(op);
    int q = g->quiet;
    ir_ref r;
    t.arg = arg;
    g->quiet = 0; /* leaves cannot fail either */
    r = ir_intern(g, t);
    g->quiet = q;
    return r;
}

ir_ref ir_loadi(ir *g, uint32_t base, uint32_t size, ir_ref index)
{
    ir_node t = ir_blank(FREP_OP_LOADI);
    t.arg = base;
    t.k = (double)size;
    t.in[0] = index;
    return ir_intern(g, t);
}

static int ir_op_is(const ir *g, ir_ref r, frep_opcode op)
{
    return r < g->n && g->nodes[r].op == op;
}

/* Fold op on constant operands unless that is a domain error; returns IR_NONE when
 * not folded. */
static ir_ref ir_fold(ir *g, frep_opcode op, const double *v, double k)
{
    int bad = 0;
    double r = op_scalar(op, v[0], v[1], v[2], k, &bad);
    if (bad) {
        if (g->warn && !g->quiet) {
            ir_node at = ir_blank(op);
            at.line = g->line;
            at.col = g->col;
            at.len = g->len;
            g->warn(g->warn_user, &at, opsem_error_what(op));
        }
        return IR_NONE;
    }
    return ir_const(g, r);
}

ir_ref ir_op1(ir *g, frep_opcode op, ir_ref a)
{
    ir_node t;
    double v[3] = { 0, 0, 0 };
    if (g->failed) return 0;
    if (g->optimize) {
        if (ir_is_const(g, a, &v[0])) {
            ir_ref r = ir_fold(g, op, v, 0);
            if (r != IR_NONE) return r;
        }
        switch ((unsigned)op) { /* only the simplified ops are listed */
        case FREP_OP_NEG:
            if (ir_op_is(g, a, FREP_OP_NEG)) return g->nodes[a].in[0];
            break;
        case FREP_OP_SQUARE: case FREP_OP_ABS:
            while (ir_op_is(g, a, FREP_OP_NEG) || ir_op_is(g, a, FREP_OP_ABS))
                a = g->nodes[a].in[0];
            break;
        default:
            break;
        }
    }
    t = ir_blank(op);
    t.in[0] = a;
    return ir_intern(g, t);
}

static int ir_reorderable(frep_opcode op)
{
    return (op_flags(op) & OPF_COMMUT) && op != FREP_OP_MIN && op != FREP_OP_MAX;
}

ir_ref ir_op2k(ir *g, frep_opcode op, ir_ref a, ir_ref b, double k)
{
    ir_node t;
    double v[3] = { 0, 0, 0 };
    if (g->failed) return 0;
    if (g->optimize) {
        int ca = ir_is_const(g, a, &v[0]), cb = ir_is_const(g, b, &v[1]);
        if (ca && cb) {
            ir_ref r = ir_fold(g, op, v, k);
            if (r != IR_NONE) return r;
        }
        switch ((unsigned)op) { /* only the simplified ops are listed */
        case FREP_OP_MUL:
            if (cb && v[1] == 1) return a;
            if (ca && v[0] == 1) return b;
            if (cb && v[1] == -1) return ir_op1(g, FREP_OP_NEG, a);
            if (ca && v[0] == -1) return ir_op1(g, FREP_OP_NEG, b);
            if (a == b) return ir_op1(g, FREP_OP_SQUARE, a);
            break;
        case FREP_OP_DIV:
            if (cb && v[1] == 1) return a;
            break;
        case FREP_OP_SUB:
            if (cb && v[1] == 0 && !signbit(v[1])) return a;
            if (ir_op_is(g, b, FREP_OP_NEG)) return ir_op2(g, FREP_OP_ADD, a, g->nodes[b].in[0]);
            break;
        case FREP_OP_ADD:
            if (cb && v[1] == 0 && signbit(v[1])) return a;
            if (ca && v[0] == 0 && signbit(v[0])) return b;
            if (ir_op_is(g, b, FREP_OP_NEG)) return ir_op2(g, FREP_OP_SUB, a, g->nodes[b].in[0]);
            if (ir_op_is(g, a, FREP_OP_NEG)) return ir_op2(g, FREP_OP_SUB, b, g->nodes[a].in[0]);
            break;
        default:
            break;
        }
        if (ir_reorderable(op) && a > b) {
            ir_ref tmp = a;
            a = b;
            b = tmp;
        }
    }
    t = ir_blank(op);
    t.in[0] = a;
    t.in[1] = b;
    t.k = k;
    return ir_intern(g, t);
}

ir_ref ir_op2(ir *g, frep_opcode op, ir_ref a, ir_ref b) { return ir_op2k(g, op, a, b, 0); }

ir_ref ir_select(ir *g, ir_ref cond, ir_ref a, ir_ref b)
{
    ir_node t;
    if (g->failed) return 0;
    if (g->optimize) {
        double c;
        if (ir_is_const(g, cond, &c)) return opsem_select(c, 1, 0) != 0 ? a : b;
        if (a == b) return a;
    }
    t = ir_blank(FREP_OP_SELECT);
    t.in[0] = cond;
    t.in[1] = a;
    t.in[2] = b;
    return ir_intern(g, t);
}

/* emit.c - schedule lowered IR (lang/lower.c) into postfix bytecode (program.h).
 *
 * Code is emitted region by region: the top level of a model (its stores, if
 * conditions and final value) is one region; each statement inside real control
 * flow is a region of its own.  Within a region a node used more than once is
 * computed once, before the expression that first needs it ("hoisted"), STOREd to a
 * temporary slot and LOADed at each use; the slot is reused after the last use.
 * Everything else is a tree, emitted in Sethi-Ullman order (for operands that may be
 * swapped exactly) so the stack stays shallow, with constant operands of binary ops
 * as immediates.  So every expression is a contiguous range of instructions
 * (prog_subtree_start finds it), which the GP engine relies on for splicing.
 */
#include "alloc.h"
#include "emit.h"

#include <stdlib.h>
#include <string.h>

/* Per-node bookkeeping of a region.  The top level keeps its bank while statements
 * inside control flow (each a region, strictly one after another) use the other. */
typedef struct bank {
    uint32_t *ureg;     /* region in which uses[] was counted */
    uint32_t *uses;     /* parent edges + root references; counts down as LOADs go out */
    uint32_t *need;     /* stack needed to evaluate the tree (shared children: 1) */
    uint32_t *height;
    uint8_t *forced;    /* hoisted because too deep / needing too much stack */
    uint32_t *mat;      /* temp slot + 1 while materialized (in region mreg) */
    uint32_t *mreg;
    uint32_t *rem;      /* LOADs still to come while materialized */
} bank;

typedef struct em {
    const ir *g;
    const lowered *lo;
    frep_program *p;
    bank banks[2];
    bank *b;            /* banks[0] at the top level, banks[1] inside control flow */
    uint32_t *ureg, *uses, *need, *height, *mat, *mreg, *rem; /* = b's arrays */
    uint8_t *forced;
    uint32_t *vis;      /* DFS stamp */
    uint32_t stamp;
    uint32_t region;
    uint32_t *stk;      /* DFS stack: node, child index pairs */
    uint32_t *post;     /* postorder buffer */
    uint32_t *freet;    /* free temporaries */
    uint32_t nfree;
    uint32_t next_temp;
    long depth, max_depth; /* stack depth after the code so far, and its maximum */
    emit_status failed;  /* EMIT_OK until something fails; then nothing more is emitted */
} em;

static void use_bank(em *E, int i)
{
    bank *b = &E->banks[i];
    E->b = b;
    E->ureg = b->ureg;
    E->uses = b->uses;
    E->need = b->need;
    E->height = b->height;
    E->forced = b->forced;
    E->mat = b->mat;
    E->mreg = b->mreg;
    E->rem = b->rem;
}

static int is_leaf(const ir_node *n) { return (op_flags((frep_opcode)n->op) & OPF_LEAF) != 0; }

static int reorderable(frep_opcode op)
{
    /* min/max return (and differentiate) their first operand on a tie. */
    return (op_flags(op) & OPF_COMMUT) && op != FREP_OP_MIN && op != FREP_OP_MAX;
}

/* Binary ops that may carry a constant operand as the immediate k. */
static int takes_imm(frep_opcode op)
{
    return op_nin(op) == 2 && !(op_flags(op) & OPF_CTRL) && op != FREP_OP_AUNI &&
           op != FREP_OP_AINT;
}

static int is_const(const em *E, ir_ref r) { return E->g->nodes[r].op == FREP_OP_CONST; }

static int shared(const em *E, ir_ref r)
{
    const ir_node *n = &E->g->nodes[r];
    if (is_leaf(n)) return 0;
    return E->ureg[r] == E->region && (E->uses[r] >= 2 || E->forced[r]);
}

static frep_srcpos node_pos(const ir_node *n)
{
    frep_srcpos s;
    s.line = n->line;
    s.col = n->col;
    s.len = n->len;
    return s;
}

static uint32_t put(em *E, frep_opcode op, uint32_t arg, double k, uint8_t flags,
                    frep_srcpos pos)
{
    uint32_t pc = prog_emit(E->p, op, arg, k, flags, pos);
    if (pc == UINT32_MAX) {
        /* prog_emit fails when memory runs out (its cap of UINT32_MAX / 4
         * instructions is 28 GB of code) */
        if (!E->failed) E->failed = EMIT_NOMEM;
        return pc;
    }
    /* The code is emitted in execution order and every statement leaves the stack
     * as it found it, so this running count is the depth prog_finish will find. */
    E->depth += op_pushes(op) - insn_nin(&E->p->code[pc]);
    if (E->depth > E->max_depth) E->max_depth = E->depth;
    return pc;
}

static uint32_t temp_alloc(em *E)
{
    if (E->nfree) return E->freet[--E->nfree];
    if (E->next_temp >= FREP_MAX_SLOTS) {
        if (!E->failed) E->failed = EMIT_SLOTS;
        return 0;
    }
    return E->next_temp++;
}

static void temp_free(em *E, uint32_t t) { E->freet[E->nfree++] = t; }

/* Count uses of everything reachable from root r in the current region and append
 * newly reached nodes to post[] in postorder. */
static void count_root(em *E, ir_ref r, uint32_t *npost)
{
    uint32_t sp = 0;
    if (E->ureg[r] == E->region) {
        E->uses[r]++;
        return;
    }
    E->ureg[r] = E->region;
    E->uses[r] = 1;
    E->forced[r] = 0;
    E->stk[sp++] = r;
    E->stk[sp++] = 0;
    while (sp) {
        uint32_t n = E->stk[sp - 2], i = E->stk[sp - 1];
        const ir_node *nd = &E->g->nodes[n];
        if ((int)i < op_nin((frep_opcode)nd->op) && !is_leaf(nd)) {
            ir_ref c = nd->in[i];
            E->stk[sp - 1] = i + 1;
            if (E->ureg[c] == E->region) {
                E->uses[c]++;
            } else {
                E->ureg[c] = E->region;
                E->uses[c] = 1;
                E->forced[c] = 0;
                E->stk[sp++] = c;
                E->stk[sp++] = 0;
            }
        } else {
            sp -= 2;
            E->post[(*npost)++] = n;
        }
    }
}

static uint32_t eff_need(const em *E, ir_ref c)
{
    return shared(E, c) || is_leaf(&E->g->nodes[c]) ? 1 : E->need[c];
}

static uint32_t eff_height(const em *E, ir_ref c)
{
    return shared(E, c) || is_leaf(&E->g->nodes[c]) ? 1 : E->height[c];
}

static uint32_t max2(uint32_t a, uint32_t b) { return a > b ? a : b; }

/* Stack need and height of the region's nodes, children first; hoist nodes over the
 * limits. */
static void analyze(em *E, uint32_t npost)
{
    uint32_t i;
    for (i = 0; i < npost; i++) {
        ir_ref r = E->post[i];
        const ir_node *n = &E->g->nodes[r];
        frep_opcode op = (frep_opcode)n->op;
        uint32_t need, h = 1;
        int k, nin = op_nin(op);
        if (is_leaf(n)) {
            E->need[r] = E->height[r] = 1;
            continue;
        }
        for (k = 0; k < nin; k++) h = max2(h, eff_height(E, n->in[k]) + 1);
        if (nin == 1) {
            need = eff_need(E, n->in[0]);
        } else if (nin == 2) {
            uint32_t na = eff_need(E, n->in[0]), nb = eff_need(E, n->in[1]);
            if (takes_imm(op) && is_const(E, n->in[1])) need = na;
            else if (takes_imm(op) && is_const(E, n->in[0])) need = nb;
            else if (reorderable(op)) need = na == nb ? na + 1 : max2(na, nb);
            else need = max2(na, nb + 1);
        } else {
            need = max2(eff_need(E, n->in[0]),
                        max2(eff_need(E, n->in[1]) + 1, eff_need(E, n->in[2]) + 2));
        }
        E->need[r] = need;
        E->height[r] = h;
        if (h > FREP_EMIT_MAX_HEIGHT || need > FREP_EMIT_MAX_NEED) E->forced[r] = 1;
    }
}

static void begin_region(em *E, const ir_ref *roots, uint32_t nroots)
{
    uint32_t i, npost = 0;
    E->region++;
    for (i = 0; i < nroots; i++) count_root(E, roots[i], &npost);
    analyze(E, npost);
}

static void emit_use(em *E, ir_ref r);

/* The instructions of node r itself (not a LOAD of its temporary). */
static void emit_tree(em *E, ir_ref r)
{
    const ir_node *n = &E->g->nodes[r];
    frep_opcode op = (frep_opcode)n->op;
    frep_srcpos pos = node_pos(n);
    uint8_t q = n->quiet ? INSN_QUIET : 0;
    int nin = op_nin(op);
    if (E->failed) return;
    if (is_leaf(n)) {
        /* Leaves cannot fail, and a shared leaf has no single position. */
        frep_srcpos none = { 0, 0, 0 };
        put(E, op, n->arg, n->k, 0, none);
        return;
    }
    if (op == FREP_OP_LOADI) {
        emit_use(E, n->in[0]);
        put(E, op, n->arg, n->k, q, pos);
        return;
    }
    if (nin == 1) {
        emit_use(E, n->in[0]);
        put(E, op, 0, 0, q, pos);
        return;
    }
    if (nin == 2) {
        ir_ref a = n->in[0], b = n->in[1];
        if (takes_imm(op) && is_const(E, b)) {
            emit_use(E, a);
            put(E, op, 0, E->g->nodes[b].k, (uint8_t)(q | INSN_KB), pos);
        } else if (takes_imm(op) && is_const(E, a)) {
            emit_use(E, b);
            put(E, op, 0, E->g->nodes[a].k,
                (uint8_t)(q | (reorderable(op) ? INSN_KB : INSN_KA)), pos);
        } else {
            if (reorderable(op) && eff_need(E, b) > eff_need(E, a)) {
                ir_ref t = a;
                a = b;
                b = t;
            }
            emit_use(E, a);
            emit_use(E, b);
            put(E, op, 0, n->k, q, pos);
        }
        return;
    }
    emit_use(E, n->in[0]);
    emit_use(E, n->in[1]);
    emit_use(E, n->in[2]);
    put(E, op, 0, n->k, q, pos);
}

/* A use of r: a leaf, a LOAD of its temporary, or its tree. */
static void emit_use(em *E, ir_ref r)
{
    const ir_node *n = &E->g->nodes[r];
    if (is_leaf(n) || !shared(E, r)) {
        emit_tree(E, r);
        return;
    }
    if (E->mreg[r] != E->region || !E->mat[r]) {
        if (!E->failed) E->failed = EMIT_BUG; /* hoisting guarantees this never happens */
        return;
    }
    put(E, FREP_OP_LOAD, E->mat[r] - 1, 0, 0, node_pos(n)); /* the value it reloads */
    if (--E->rem[r] == 0) {
        temp_free(E, E->mat[r] - 1);
        E->mat[r] = 0;
    }
}

/* Compute the shared nodes below r that are not materialized yet, children first,
 * each into a temporary; then r itself. */
static void emit_root(em *E, ir_ref r)
{
    uint32_t sp = 0, npost = 0, i;
    E->stamp++;
    E->vis[r] = E->stamp;
    E->stk[sp++] = r;
    E->stk[sp++] = 0;
    while (sp) {
        uint32_t n = E->stk[sp - 2], k = E->stk[sp - 1];
        const ir_node *nd = &E->g->nodes[n];
        int stop = is_leaf(nd) || (shared(E, n) && E->mreg[n] == E->region && E->mat[n]);
        if (!stop && (int)k < op_nin((frep_opcode)nd->op)) {
            ir_ref c = nd->in[k];
            E->stk[sp - 1] = k + 1;
            if (E->vis[c] != E->stamp) {
                E->vis[c] = E->stamp;
                E->stk[sp++] = c;
                E->stk[sp++] = 0;
            }
        } else {
            sp -= 2;
            if (!stop && shared(E, n)) E->post[npost++] = n;
        }
    }
    for (i = 0; i < npost && !E->failed; i++) {
        ir_ref n = E->post[i];
        uint32_t t;
        emit_tree(E, n);
        t = temp_alloc(E);
        put(E, FREP_OP_STORE, t, 0, 0, node_pos(&E->g->nodes[n]));
        E->mat[n] = t + 1;
        E->mreg[n] = E->region;
        E->rem[n] = E->uses[n];
    }
    emit_use(E, r);
}

static frep_srcpos stmt_pos(const lstmt *s)
{
    frep_srcpos p;
    p.line = s->line;
    p.col = s->col;
    p.len = s->len;
    return p;
}

/* Roots a statement evaluates in its own region (not those of nested bodies). */
static uint32_t stmt_roots(const lstmt *s, ir_ref *out)
{
    uint32_t i;
    switch (s->kind) {
    case LS_STORE:
        for (i = 0; i < s->n; i++) out[i] = s->vals[i];
        return s->n;
    case LS_STOREI:
        out[0] = s->value;
        out[1] = s->index;
        return 2;
    case LS_IF:
        out[0] = s->cond;
        return 1;
    case LS_WHILE:
        return 0;
    }
    return 0;
}

static void emit_block(em *E, const lblock *b);

/* LS_STORE: the values on the stack, then the stores in reverse; more than
 * FREP_EMIT_MAX_PARALLEL values go through temporaries, so that every value is
 * computed before any slot changes. */
static void emit_store(em *E, const lstmt *s, frep_srcpos pos)
{
    uint32_t i, *t;
    if (s->n <= FREP_EMIT_MAX_PARALLEL) {
        for (i = 0; i < s->n; i++) emit_root(E, s->vals[i]);
        for (i = s->n; i-- > 0;) put(E, FREP_OP_STORE, s->slots[i], 0, 0, pos);
        return;
    }
    t = frep_malloc(s->n * sizeof *t);
    if (!t) {
        E->failed = EMIT_NOMEM;
        return;
    }
    for (i = 0; i < s->n; i++) {
        emit_root(E, s->vals[i]);
        t[i] = temp_alloc(E);
        put(E, FREP_OP_STORE, t[i], 0, 0, pos);
    }
    for (i = 0; i < s->n; i++) {
        put(E, FREP_OP_LOAD, t[i], 0, 0, pos);
        put(E, FREP_OP_STORE, s->slots[i], 0, 0, pos);
        temp_free(E, t[i]);
    }
    frep_free(t);
}

/* LS_IF: cond JZ(else) body [JMP(end)] else: body2 end: */
static void emit_if(em *E, const lstmt *s, frep_srcpos pos)
{
    uint32_t jz, jmp = UINT32_MAX;
    emit_root(E, s->cond);
    jz = put(E, FREP_OP_JZ, 0, 0, 0, pos);
    emit_block(E, &s->body);
    if (s->body2.n) jmp = put(E, FREP_OP_JMP, 0, 0, 0, pos);
    if (E->failed) return;
    E->p->code[jz].arg = E->p->ncode;
    emit_block(E, &s->body2);
    if (E->failed) return;
    if (jmp != UINT32_MAX) E->p->code[jmp].arg = E->p->ncode;
}

/* LS_WHILE: top: pre cond JZ(end) body JMP(top) end:  (cond in a region of its own,
 * as it runs after pre on every iteration) */
static void emit_while(em *E, const lstmt *s, frep_srcpos pos)
{
    uint32_t top = E->p->ncode, jz, region = E->region;
    bank *saved = E->b;
    ir_ref r = s->cond;
    emit_block(E, &s->pre);
    use_bank(E, 1);
    begin_region(E, &r, 1);
    emit_root(E, r);
    jz = put(E, FREP_OP_JZ, 0, 0, 0, pos);
    emit_block(E, &s->body);
    put(E, FREP_OP_JMP, top, 0, 0, pos);
    use_bank(E, saved == &E->banks[0] ? 0 : 1);
    E->region = region;
    if (E->failed) return;
    E->p->code[jz].arg = E->p->ncode;
}

/* Emit statement s whose region (roots) has been counted already. */
static void emit_stmt(em *E, const lstmt *s)
{
    frep_srcpos pos = stmt_pos(s);
    if (E->failed) return;
    switch (s->kind) {
    case LS_STORE:
        emit_store(E, s, pos);
        break;
    case LS_STOREI:
        emit_root(E, s->value);
        emit_root(E, s->index);
        put(E, FREP_OP_STOREI, s->base, (double)s->size, 0, pos);
        break;
    case LS_IF:
        emit_if(E, s, pos);
        break;
    case LS_WHILE:
        emit_while(E, s, pos);
        break;
    }
}

/* Statements inside real control flow: each its own region. */
static void emit_block(em *E, const lblock *b)
{
    uint32_t i, region = E->region;
    bank *saved = E->b;
    for (i = 0; i < b->n && !E->failed; i++) {
        const lstmt *s = b->v[i];
        ir_ref *roots = frep_malloc((s->n + 2) * sizeof *roots);
        uint32_t nr;
        if (!roots) {
            E->failed = EMIT_NOMEM;
            return;
        }
        nr = stmt_roots(s, roots);
        use_bank(E, 1);
        begin_region(E, roots, nr);
        frep_free(roots);
        emit_stmt(E, s);
    }
    /* Back to the caller's region (the top level's survives nested regions). */
    use_bank(E, saved == &E->banks[0] ? 0 : 1);
    E->region = region;
}

/* The per-node arrays of both banks and the DFS scratch, for nn nodes. */
static int em_alloc(em *E, uint32_t nn)
{
    uint32_t i;
    for (i = 0; i < 2; i++) {
        bank *b = &E->banks[i];
        b->ureg = frep_calloc(nn, sizeof *b->ureg);
        b->uses = frep_calloc(nn, sizeof *b->uses);
        b->need = frep_calloc(nn, sizeof *b->need);
        b->height = frep_calloc(nn, sizeof *b->height);
        b->forced = frep_calloc(nn, 1);
        b->mat = frep_calloc(nn, sizeof *b->mat);
        b->mreg = frep_calloc(nn, sizeof *b->mreg);
        b->rem = frep_calloc(nn, sizeof *b->rem);
        if (!b->ureg || !b->uses || !b->need || !b->height || !b->forced || !b->mat ||
            !b->mreg || !b->rem)
            return -1;
    }
    E->vis = frep_calloc(nn, sizeof *E->vis);
    E->stk = frep_malloc(2 * nn * sizeof *E->stk);
    E->post = frep_malloc(nn * sizeof *E->post);
    E->freet = frep_malloc((E->g->n + E->lo->nslots + 1) * sizeof *E->freet);
    return E->vis && E->stk && E->post && E->freet ? 0 : -1;
}

static void em_release(em *E)
{
    uint32_t i;
    for (i = 0; i < 2; i++) {
        bank *b = &E->banks[i];
        frep_free(b->ureg);
        frep_free(b->uses);
        frep_free(b->need);
        frep_free(b->height);
        frep_free(b->forced);
        frep_free(b->mat);
        frep_free(b->mreg);
        frep_free(b->rem);
    }
    frep_free(E->vis);
    frep_free(E->stk);
    frep_free(E->post);
    frep_free(E->freet);
}

/* program -> top-level statements, then the root: one region, counted at once so a
 * node shared between statements is computed once. */
static void emit_top(em *E)
{
    const lowered *lo = E->lo;
    uint32_t nroots = 0, n = 0, i, top_region;
    ir_ref *roots;
    for (i = 0; i < lo->top.n; i++) {
        const lstmt *s = lo->top.v[i];
        nroots += s->kind == LS_STORE ? s->n : 2;
    }
    roots = frep_malloc((nroots + 1) * sizeof *roots);
    if (!roots) {
        E->failed = EMIT_NOMEM;
        return;
    }
    for (i = 0; i < lo->top.n; i++) n += stmt_roots(lo->top.v[i], roots + n);
    roots[n++] = lo->root;
    use_bank(E, 0);
    begin_region(E, roots, n);
    frep_free(roots);
    top_region = E->region;
    for (i = 0; i < lo->top.n && !E->failed; i++) {
        use_bank(E, 0);
        E->region = top_region;
        emit_stmt(E, lo->top.v[i]);
    }
    use_bank(E, 0);
    E->region = top_region;
    emit_root(E, lo->root);
}

emit_status emit_program(const ir *g, const lowered *lo, frep_program *p)
{
    em E;
    memset(&E, 0, sizeof E);
    E.g = g;
    E.lo = lo;
    E.p = p;
    E.next_temp = lo->nslots;
    if (em_alloc(&E, g->n + 1) < 0) E.failed = EMIT_NOMEM;
    if (!E.failed) emit_top(&E);
    /* prog_finish fails on code built here only when memory runs out or the stack
     * is too deep (the code is valid by construction); put() counted the depth. */
    if (!E.failed && prog_finish(p) != 0)
        E.failed = E.max_depth > FREP_MAX_STACK ? EMIT_STACK : EMIT_NOMEM;
    em_release(&E);
    return E.failed;
}

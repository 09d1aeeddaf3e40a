/* lower.c - symbolic execution of a checked model into IR (see lower.h).
 *
 * Pipeline: lang/check.c -> here -> lang/emit.c.  Every scalar variable and array
 * element is a "cell" holding an IR node; statements update cells, so straight-line
 * code becomes one DAG and its value is the model's result cell.  Calls to earlier
 * models are inlined, library calls expanded (lang/lib.c).
 *
 * Control flow, in order of preference:
 *  - a condition that folds to a constant runs only the taken branch; a loop whose
 *    condition folds is unrolled (bounded by FREP_MAX_UNROLL[_NODES]);
 *  - an if whose branches are straight-line is lowered twice, speculatively
 *    (quiet nodes: no domain errors), and each cell merged with SELECT;
 *  - otherwise the construct becomes real control flow ("depth > 0"): every cell it
 *    may write is first spilled to a variable slot, and inside it every write is a
 *    store and every cell a LOAD of its slot.  Slots spilled at depth 0 are fresh, and
 *    written only by their own construct, so an IR node built outside a construct
 *    stays valid forever; inside, each statement is emitted on its own.
 * Array arguments of model calls are passed by value, as the reference interpreter
 * does (it copies x and a into the callee's frame and never copies them back); the
 * third, s[] (attributes), is copied back, as there.
 */
#include "lower.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "frep.h"
#include "lib.h"
#include "program.h"

/* Integer powers a^n with |n| up to this are multiplication chains, evaluated
 * exactly as the reference interpreter's loop evaluates them. */
#define FREP_POW_CHAIN_MAX 64

/* Tolerance of '=' and '/=': the reference interpreter's EPS (int_global.c of
 * HyperFun), so `a = b` is |a - b| < 1e-6 and `a /= b` is |a - b| >= 1e-6
 * (FUNC_bool_equal, FUNC_bool_not_equal in int_calc.c). */
#define HF_EPS 1e-6

#define NO_SLOT UINT32_MAX

typedef struct sym {
    uint32_t first, size;   /* cells [first, first + size) */
    int is_array;
} sym;

typedef struct scope {
    const ast_model *m;
    strmap names;           /* key -> sym index */
    sym *syms;
    uint32_t nsyms;
    ir_ref *vals;           /* cell values; IR_NONE: not yet assigned */
    uint32_t *slot;         /* depth > 0: the slot holding the cell, or NO_SLOT */
    uint32_t *cell_sym;
    uint32_t ncells;
    uint32_t result;        /* cell of the model's result */
} scope;

typedef struct lw {
    arena *A;
    const ast_file *f;
    const check_info *ci;
    ir *g;
    diag_sink *d;
    lib_ctx lc;
    const ast_node *call;   /* library call being expanded (for lc.error) */
    lblock *cur;            /* where statements go */
    int depth;              /* nesting of real control flow */
    int trial;              /* > 0: speculative if->select lowering */
    int abort;              /* the trial met something needing real control flow */
    int dead;               /* a fatal error was reported: stop */
    uint32_t nslots;
    uint32_t inline_depth;
    uint32_t steps;
    uint32_t na;
    lower_param *named;
    uint32_t nnamed;
    strmap seen;            /* reported diagnostics, to report each once */
} lw;

/* ---- diagnostics ---------------------------------------------------------------- */

static void lw_vreport(lw *L, frep_severity sev, uint32_t line, uint32_t col, uint32_t len,
                       const char *fmt, va_list ap)
{
    char msg[512], key[600];
    ast_loc loc;
    char *k;
    vsnprintf(msg, sizeof msg, fmt, ap);
    (void)snprintf(key, sizeof key, "%u:%u:%s", (unsigned)line, (unsigned)col, msg);
    if (strmap_get(&L->seen, key)) return;
    k = arena_strndup(L->A, key, strlen(key));
    if (k) (void)strmap_put(&L->seen, k, 1);
    memset(&loc, 0, sizeof loc);
    loc.line = line;
    loc.col = col;
    diag_report(L->d, sev, loc, len ? len : 1, "%s", msg);
}

static void lw_report(lw *L, frep_severity sev, ast_loc at, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
static void lw_report(lw *L, frep_severity sev, ast_loc at, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    lw_vreport(L, sev, at.line, at.col, at.end > at.off ? at.end - at.off : 1, fmt, ap);
    va_end(ap);
}

static void lw_fatal(lw *L, ast_loc at, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static void lw_fatal(lw *L, ast_loc at, const char *fmt, ...)
{
    va_list ap;
    if (L->dead) return;
    va_start(ap, fmt);
    lw_vreport(L, FREP_ERROR, at.line, at.col, at.end > at.off ? at.end - at.off : 1, fmt, ap);
    va_end(ap);
    L->dead = 1;
}

static ir_ref lib_error_cb(lib_ctx *c, const char *fmt, ...)
{
    lw *L = c->user;
    va_list ap;
    ast_loc at;
    memset(&at, 0, sizeof at);
    if (L->call) at = L->call->op_loc;
    va_start(ap, fmt);
    lw_vreport(L, FREP_ERROR, at.line, at.col, at.end > at.off ? at.end - at.off : 1, fmt, ap);
    va_end(ap);
    return IR_NONE;
}

static void ir_warn_cb(void *user, const ir_node *at, const char *what)
{
    lw *L = user;
    {
        ast_loc loc;
        memset(&loc, 0, sizeof loc);
        loc.line = at->line;
        loc.col = at->col;
        loc.off = 0;
        loc.end = at->len;
        lw_report(L, FREP_WARNING, loc, "%s in a constant expression: the value is NaN "
                  "and the error is reported at runtime", what);
    }
}

/* ---- statements and slots ----------------------------------------------------------- */

static int block_push(lw *L, lblock *b, lstmt *s)
{
    if (b->n == b->cap) {
        uint32_t ncap = b->cap ? 2 * b->cap : 8;
        lstmt **v = arena_grow(L->A, b->v, b->n, ncap, sizeof *v);
        if (!v) return -1;
        b->v = v;
        b->cap = ncap;
    }
    b->v[b->n++] = s;
    return 0;
}

static lstmt *stmt_new(lw *L, lstmt_kind kind)
{
    lstmt *s = arena_alloc(L->A, sizeof *s);
    if (!s) return NULL;
    s->kind = kind;
    s->line = L->g->line;
    s->col = L->g->col;
    s->len = L->g->len;
    if (block_push(L, L->cur, s) < 0) return NULL;
    return s;
}

static uint32_t slot_alloc(lw *L, uint32_t n, ast_loc at)
{
    uint32_t base = L->nslots;
    if (n > FREP_MAX_SLOTS || base > FREP_MAX_SLOTS - n) {
        lw_fatal(L, at, "model needs more than %u variable slots", (unsigned)FREP_MAX_SLOTS);
        return 0;
    }
    L->nslots += n;
    return base;
}

/* The value of cell c; NaN for a cell no assignment has reached: the reference
 * interpreter stops with "Not initialized variable" (or "Unassigned identificator",
 * "Some items of array are unassigned") at such a read, and frep's value for a
 * runtime error of the reference is NaN.  (x, a and s are always assigned.) */
static ir_ref cell_value(lw *L, const scope *sc, uint32_t c)
{
    return sc->vals[c] == IR_NONE ? ir_const(L->g, NAN) : sc->vals[c];
}

/* A store of n (slot, value) pairs, all values computed before any store. */
static void emit_stores(lw *L, const uint32_t *slots, const ir_ref *vals, uint32_t n)
{
    lstmt *s;
    if (n == 0) return;
    s = stmt_new(L, LS_STORE);
    if (!s) return;
    s->slots = arena_alloc(L->A, n * sizeof *s->slots);
    s->vals = arena_alloc(L->A, n * sizeof *s->vals);
    if (!s->slots || !s->vals) return;
    memcpy(s->slots, slots, n * sizeof *slots);
    memcpy(s->vals, vals, n * sizeof *vals);
    s->n = n;
}

/* Give every cell of sym a slot (contiguous) holding its current value. */
static void ensure_slots(lw *L, scope *sc, uint32_t si, ast_loc at)
{
    sym *y = &sc->syms[si];
    uint32_t base, j, *slots;
    ir_ref *vals;
    if (y->size == 0 || sc->slot[y->first] != NO_SLOT) return;
    base = slot_alloc(L, y->size, at);
    if (L->dead) return;
    slots = arena_alloc(L->A, y->size * sizeof *slots);
    vals = arena_alloc(L->A, y->size * sizeof *vals);
    if (!slots || !vals) return;
    for (j = 0; j < y->size; j++) {
        slots[j] = base + j;
        vals[j] = cell_value(L, sc, y->first + j);
    }
    emit_stores(L, slots, vals, y->size);
    for (j = 0; j < y->size; j++) {
        sc->slot[y->first + j] = base + j;
        sc->vals[y->first + j] = ir_leaf(L->g, FREP_OP_LOAD, base + j);
    }
}

/* Assign values to cells (a parallel assignment: values were computed from the old
 * cells). */
static void assign_cells(lw *L, scope *sc, const uint32_t *cells, const ir_ref *vals,
                         uint32_t n, ast_loc at)
{
    uint32_t i, k = 0, *slots;
    ir_ref *v;
    if (L->depth == 0) {
        for (i = 0; i < n; i++) sc->vals[cells[i]] = vals[i];
        return;
    }
    slots = arena_alloc(L->A, (n + 1) * sizeof *slots);
    v = arena_alloc(L->A, (n + 1) * sizeof *v);
    if (!slots || !v) return;
    for (i = 0; i < n; i++) {
        ensure_slots(L, sc, sc->cell_sym[cells[i]], at);
        if (L->dead) return;
        slots[k] = sc->slot[cells[i]];
        v[k++] = vals[i];
    }
    emit_stores(L, slots, v, k);
    for (i = 0; i < n; i++) sc->vals[cells[i]] = ir_leaf(L->g, FREP_OP_LOAD, sc->slot[cells[i]]);
}

/* ---- scopes ------------------------------------------------------------------------ */

static uint32_t scope_add(lw *L, scope *sc, const char *key, int is_array, uint32_t size,
                          uint32_t *cap)
{
    uint32_t *old = strmap_get(&sc->names, key);
    sym *y;
    if (old) return *old;
    if (sc->nsyms == *cap) {
        uint32_t ncap = *cap ? 2 * *cap : 16;
        sym *ns = arena_grow(L->A, sc->syms, sc->nsyms, ncap, sizeof *ns);
        if (!ns) return 0;
        sc->syms = ns;
        *cap = ncap;
    }
    y = &sc->syms[sc->nsyms];
    y->first = sc->ncells;
    y->size = size;
    y->is_array = is_array;
    sc->ncells += size;
    (void)strmap_put(&sc->names, key, sc->nsyms);
    return sc->nsyms++;
}

static void scope_scalars(lw *L, scope *sc, const ast_list *l, uint32_t *cap)
{
    uint32_t i;
    for (i = 0; i < l->n; i++) {
        const ast_node *n = l->v[i];
        if (n->kind == AST_ASSIGN) (void)scope_add(L, sc, n->key, 0, 1, cap);
        scope_scalars(L, sc, &n->body, cap);
        scope_scalars(L, sc, &n->body2, cap);
    }
}

/* Build the scope of model m: its arrays, then every scalar it assigns. Cells start
 * unassigned; the caller fills the parameter arrays. */
static int scope_init(lw *L, scope *sc, const ast_model *m)
{
    uint32_t cap = 0, i;
    memset(sc, 0, sizeof *sc);
    sc->m = m;
    strmap_init(&sc->names, L->A);
    for (i = 0; i < m->nparams; i++) (void)scope_add(L, sc, m->params[i].key, 1, m->params[i].size, &cap);
    for (i = 0; i < m->narrays; i++) (void)scope_add(L, sc, m->arrays[i].key, 1, m->arrays[i].size, &cap);
    (void)scope_add(L, sc, m->key, 0, 1, &cap);
    /* s used and not declared: a local s[1] starting at 0 (check_implicit_s) */
    int implicit_s = check_implicit_s(m) != NULL && !strmap_get(&sc->names, "s");
    uint32_t s_sym = implicit_s ? scope_add(L, sc, "s", 1, 1, &cap) : 0;
    scope_scalars(L, sc, &m->body, &cap);
    sc->vals = arena_alloc(L->A, (sc->ncells + 1) * sizeof *sc->vals);
    sc->slot = arena_alloc(L->A, (sc->ncells + 1) * sizeof *sc->slot);
    sc->cell_sym = arena_alloc(L->A, (sc->ncells + 1) * sizeof *sc->cell_sym);
    if (!sc->vals || !sc->slot || !sc->cell_sym || !sc->syms) return -1;
    for (i = 0; i < sc->ncells; i++) {
        sc->vals[i] = IR_NONE;
        sc->slot[i] = NO_SLOT;
    }
    if (implicit_s) sc->vals[sc->syms[s_sym].first] = ir_const(L->g, 0);
    for (i = 0; i < sc->nsyms; i++) {
        uint32_t j;
        for (j = 0; j < sc->syms[i].size; j++) sc->cell_sym[sc->syms[i].first + j] = i;
    }
    sc->result = sc->syms[*strmap_get(&sc->names, m->key)].first;
    return 0;
}

static const sym *scope_sym(const scope *sc, const char *key)
{
    const uint32_t *i = strmap_get(&sc->names, key);
    return i ? &sc->syms[*i] : NULL;
}

/* ---- pre-scan: cells a construct may write or index dynamically ------------------- */

static int is_literal(const ast_node *n)
{
    return n->kind == AST_NUM ||
           (n->kind == AST_UNARY && n->op == '-' && n->a && n->a->kind == AST_NUM);
}

static void ps_mark(scope *sc, const char *key, uint8_t *mark)
{
    const uint32_t *i = strmap_get(&sc->names, key);
    if (i) mark[*i] = 1;
}

static void ps_expr(scope *sc, const ast_node *n, uint8_t *mark)
{
    uint32_t i;
    if (!n) return;
    switch (n->kind) {
    case AST_INDEX:
        if (!is_literal(n->a)) ps_mark(sc, n->key, mark);
        ps_expr(sc, n->a, mark);
        break;
    case AST_CALL: {
        const lib_fn *fn = lib_lookup(n->name);
        for (i = 0; i < n->list.n; i++) {
            char kind = fn ? check_lib_kind(fn->args, i, NULL, NULL) : 0;
            if (n->list.v[i]->kind == AST_VAR && (kind == 'm' || kind == 'w'))
                ps_mark(sc, n->list.v[i]->key, mark);
            /* a model's s[] comes back to the third argument (copy_back_attrs);
             * marked for any three-argument call, which is only more careful */
            if (i == 2 && n->list.n == 3 && n->list.v[i]->kind == AST_VAR)
                ps_mark(sc, n->list.v[i]->key, mark);
            ps_expr(sc, n->list.v[i], mark);
        }
        break;
    }
    case AST_UNARY: case AST_BINARY:
        ps_expr(sc, n->a, mark);
        ps_expr(sc, n->b, mark);
        break;
    case AST_NUM: case AST_VAR:
        break;
    case AST_ASSIGN: case AST_ASSIGN_INDEX: case AST_ASSIGN_ARRAY: case AST_IF:
    case AST_WHILE:
        break;
    }
}

static void ps_stmts(scope *sc, const ast_list *l, uint8_t *mark)
{
    uint32_t i, j;
    for (i = 0; i < l->n; i++) {
        const ast_node *n = l->v[i];
        switch (n->kind) {
        case AST_ASSIGN:
            ps_mark(sc, n->key, mark);
            ps_expr(sc, n->a, mark);
            break;
        case AST_ASSIGN_INDEX:
            ps_mark(sc, n->key, mark);
            ps_expr(sc, n->a, mark);
            ps_expr(sc, n->b, mark);
            break;
        case AST_ASSIGN_ARRAY:
            ps_mark(sc, n->key, mark);
            for (j = 0; j < n->list.n; j++) ps_expr(sc, n->list.v[j], mark);
            break;
        case AST_IF: case AST_WHILE:
            ps_expr(sc, n->a, mark);
            ps_stmts(sc, &n->body, mark);
            ps_stmts(sc, &n->body2, mark);
            break;
        case AST_NUM: case AST_VAR: case AST_INDEX: case AST_CALL: case AST_UNARY:
        case AST_BINARY:
            ps_expr(sc, n, mark);
            break;
        }
    }
}

/* Enter real control flow for statement n: spill what it may write. */
static void enter_construct(lw *L, scope *sc, const ast_node *n)
{
    uint8_t *mark = arena_alloc(L->A, sc->nsyms + 1);
    uint32_t i, k = 0, nslot = 0, *slots;
    ir_ref *vals;
    if (!mark) return;
    if (L->depth == 0)
        for (i = 0; i < sc->ncells; i++) sc->slot[i] = NO_SLOT;
    ps_expr(sc, n->a, mark);
    ps_stmts(sc, &n->body, mark);
    ps_stmts(sc, &n->body2, mark);
    for (i = 0; i < sc->nsyms; i++)
        if (mark[i] && sc->slot[sc->syms[i].first] == NO_SLOT)
            nslot += sc->syms[i].size;
    /* One parallel store for all spilled cells. */
    slots = arena_alloc(L->A, (nslot + 1) * sizeof *slots);
    vals = arena_alloc(L->A, (nslot + 1) * sizeof *vals);
    if (!slots || !vals) return;
    for (i = 0; i < sc->nsyms; i++) {
        sym *y = &sc->syms[i];
        uint32_t base, j;
        if (!mark[i] || sc->slot[y->first] != NO_SLOT) continue;
        base = slot_alloc(L, y->size, n->loc);
        if (L->dead) return;
        for (j = 0; j < y->size; j++) {
            slots[k] = base + j;
            vals[k++] = cell_value(L, sc, y->first + j);
            sc->slot[y->first + j] = base + j;
        }
    }
    emit_stores(L, slots, vals, k);
    for (i = 0; i < sc->ncells; i++)
        if (sc->slot[i] != NO_SLOT) sc->vals[i] = ir_leaf(L->g, FREP_OP_LOAD, sc->slot[i]);
    L->depth++;
}

/* ---- expressions -------------------------------------------------------------------- */

static void set_pos(lw *L, ast_loc l)
{
    ir_set_pos(L->g, l.line, l.col, l.end > l.off ? l.end - l.off : 1);
}

static ir_ref lw_expr(lw *L, scope *sc, const ast_node *n);
static void lw_stmts(lw *L, scope *sc, const ast_list *l);

static ir_ref nan_ref(lw *L) { return ir_const(L->g, NAN); }

/* Base slot of array y holding its current elements contiguously, for a dynamic
 * index. `write`: the caller will store into it. */
static uint32_t dyn_base(lw *L, scope *sc, uint32_t si, int write, ast_loc at)
{
    sym *y = &sc->syms[si];
    uint32_t j, base, *slots;
    ir_ref *vals;
    if (L->depth > 0) {
        ensure_slots(L, sc, si, at);
        return sc->slot[y->first];
    }
    if (!write) {
        /* Already the LOADs of contiguous slots (after an earlier materialization)? */
        const ir_node *n0 = sc->vals[y->first] < L->g->n ? &L->g->nodes[sc->vals[y->first]] : NULL;
        if (n0 && n0->op == FREP_OP_LOAD) {
            base = n0->arg;
            for (j = 0; j < y->size; j++) {
                ir_ref v = sc->vals[y->first + j];
                if (v == IR_NONE || L->g->nodes[v].op != FREP_OP_LOAD ||
                    L->g->nodes[v].arg != base + j)
                    break;
            }
            if (j == y->size) return base;
        }
    }
    /* Fresh slots: nothing built so far reads them, so storing is safe. */
    base = slot_alloc(L, y->size, at);
    if (L->dead) return 0;
    slots = arena_alloc(L->A, y->size * sizeof *slots);
    vals = arena_alloc(L->A, y->size * sizeof *vals);
    if (!slots || !vals) return 0;
    for (j = 0; j < y->size; j++) {
        slots[j] = base + j;
        vals[j] = cell_value(L, sc, y->first + j);
    }
    emit_stores(L, slots, vals, y->size);
    for (j = 0; j < y->size; j++) sc->vals[y->first + j] = ir_leaf(L->g, FREP_OP_LOAD, base + j);
    return base;
}

/* Resolve name[idx]: a cell (returned, *dyn = IR_NONE) or a dynamic index (*dyn = the
 * index node, returns the symbol index | 0x80000000). UINT32_MAX on error. */
#define DYN_FLAG 0x80000000u

/* Is IR node r a whole number (or NaN) whatever the point, so that rounding it as an
 * index changes nothing?  The results of CEIL, FLOOR and INT. */
static int index_is_whole(const ir *g, ir_ref r)
{
    frep_opcode op;
    if (r >= g->n) return 0;
    op = (frep_opcode)g->nodes[r].op;
    return op == FREP_OP_CEIL || op == FREP_OP_FLOOR || op == FREP_OP_INT;
}
static uint32_t lw_cellref(lw *L, scope *sc, const ast_node *n, ir_ref *dyn)
{
    const uint32_t *si = strmap_get(&sc->names, n->key);
    ir_ref idx = lw_expr(L, sc, n->a);
    double v;
    sym *y;
    *dyn = IR_NONE;
    if (!si || !sc->syms[*si].is_array) return UINT32_MAX;
    y = &sc->syms[*si];
    /* The reference rounds an index to the nearest whole number (lib_hf_round), so
     * LOADI/STOREI, which truncate, get it rounded already. */
    if (ir_is_const(L->g, idx, &v)) {
        double r = lib_hf_round_k(v);
        if (!(r >= 1 && r <= (double)y->size)) {
            if (!L->g->quiet)
                lw_report(L, FREP_ERROR, n->a->loc, "index %g is out of range for array '%s' "
                          "of size %u", v, n->name, (unsigned)y->size);
            return UINT32_MAX;
        }
        return y->first + (uint32_t)r - 1;
    }
    if (L->trial) {
        L->abort = 1;
        return UINT32_MAX;
    }
    set_pos(L, n->a->loc);
    *dyn = index_is_whole(L->g, idx) ? idx : lib_hf_round(L->g, idx);
    return *si | DYN_FLAG;
}

static ir_ref lw_pow(lw *L, ir_ref a, ir_ref b)
{
    double e;
    ir *g = L->g;
    if (g->optimize && ir_is_const(g, b, &e) && e == trunc(e) && fabs(e) <= FREP_POW_CHAIN_MAX) {
        int n = (int)fabs(e), i;
        ir_ref r;
        if (n == 0) return ir_const(g, 1);
        r = a;
        for (i = 1; i < n; i++) r = ir_mul(g, r, a);
        return e < 0 ? ir_div(g, ir_const(g, 1), r) : r;
    }
    return ir_op2(g, FREP_OP_POW, a, b);
}

/* a / b as the reference divides (FUNC_binary_divide in int_calc.c of HyperFun): a
 * divisor with |b| < EPS is its runtime error "Division by zero", so NaN here (as
 * for the other errors of the reference).  A constant divisor of at least EPS needs
 * no test; a constant 0 keeps the DIV opcode's own domain error. */
static ir_ref lw_div(lw *L, ir_ref a, ir_ref b)
{
    ir *g = L->g;
    double k;
    if (ir_is_const(g, b, &k) && (fabs(k) >= HF_EPS || k == 0))
        return ir_div(g, a, b);
    return ir_select(g, ir_op2(g, FREP_OP_LT, ir_op1(g, FREP_OP_ABS, b), ir_k(g, HF_EPS)),
                     nan_ref(L), ir_div(g, a, b));
}

static ir_ref lw_call_model(lw *L, scope *sc, const ast_node *n, uint32_t mi);

static ir_ref lw_call_lib(lw *L, scope *sc, const ast_node *n, const lib_fn *fn)
{
    lib_arg *args = arena_alloc(L->A, (n->list.n + 1) * sizeof *args);
    uint32_t i;
    ir_ref r;
    const ast_node *saved = L->call;
    if (!args) return nan_ref(L);
    for (i = 0; i < n->list.n; i++) {
        const ast_node *a = n->list.v[i];
        char kind = check_lib_kind(fn->args, i, NULL, NULL);
        if (kind == 's' || kind == 0) {
            args[i].s = lw_expr(L, sc, a);
        } else {
            const sym *y = scope_sym(sc, a->key);
            uint32_t j;
            if (!y) return nan_ref(L);
            args[i].n = y->size;
            args[i].elems = arena_alloc(L->A, (y->size + 1) * sizeof *args[i].elems);
            if (!args[i].elems) return nan_ref(L);
            for (j = 0; j < y->size; j++) args[i].elems[j] = cell_value(L, sc, y->first + j);
            args[i].s = IR_NONE;
        }
        if (L->abort || L->dead) return nan_ref(L);
    }
    set_pos(L, n->op_loc);
    L->call = n;
    r = fn->expand(&L->lc, args, n->list.n);
    L->call = saved;
    if (r == IR_NONE) r = nan_ref(L);
    /* 'm' and 'w' arguments were changed in place: write the new elements back. */
    for (i = 0; i < n->list.n; i++) {
        const ast_node *a = n->list.v[i];
        char kind = check_lib_kind(fn->args, i, NULL, NULL);
        if (kind == 'm' || kind == 'w') {
            const sym *y = scope_sym(sc, a->key);
            uint32_t *cells, j;
            if (!y) continue;
            cells = arena_alloc(L->A, (y->size + 1) * sizeof *cells);
            if (!cells) continue;
            for (j = 0; j < y->size; j++) cells[j] = y->first + j;
            assign_cells(L, sc, cells, args[i].elems, y->size, n->op_loc);
        }
    }
    return r;
}

static frep_opcode cmp_op(int op)
{
    switch (op) {
    case AST_OP_EQ: return FREP_OP_EQ;
    case AST_OP_NE: return FREP_OP_NE;
    case AST_OP_LT: return FREP_OP_LT;
    case AST_OP_LE: return FREP_OP_LE;
    case AST_OP_GT: return FREP_OP_GT;
    case AST_OP_GE: return FREP_OP_GE;
    case AST_OP_AND: return FREP_OP_AND;
    case AST_OP_OR: return FREP_OP_OR;
    default: return FREP_OP__COUNT;
    }
}

/* expr -> VAR '[' expr ']': the cell, or a LOADI when the index depends on the point. */
static ir_ref lw_element(lw *L, scope *sc, const ast_node *n)
{
    ir_ref dyn;
    uint32_t c = lw_cellref(L, sc, n, &dyn);
    if (c == UINT32_MAX) return nan_ref(L);
    if (dyn != IR_NONE) {
        uint32_t si = c & ~DYN_FLAG, base;
        base = dyn_base(L, sc, si, 0, n->loc);
        set_pos(L, n->op_loc);
        return ir_loadi(L->g, base, sc->syms[si].size, dyn);
    }
    return cell_value(L, sc, c);
}

/* expr -> CALL: an earlier model (inlined) or a library function (expanded). */
static ir_ref lw_call(lw *L, scope *sc, const ast_node *n)
{
    int mi = check_find_model(L->f, n->key, (uint32_t)(sc->m - L->f->models));
    const lib_fn *fn;
    if (mi >= 0) return lw_call_model(L, sc, n, (uint32_t)mi);
    fn = lib_lookup(n->name);
    if (!fn) return nan_ref(L);
    return lw_call_lib(L, sc, n, fn);
}

/* binary -> expr OP expr: arithmetic, the set operations of the @setops in force,
 * comparisons (with the reference's tolerance for = and /=) and logic. */
static ir_ref lw_cond(lw *L, scope *sc, const ast_node *n);

static ir_ref lw_binary(lw *L, scope *sc, const ast_node *n)
{
    ir *g = L->g;
    const int logic = n->op == AST_OP_AND || n->op == AST_OP_OR;
    ir_ref a = logic ? lw_cond(L, sc, n->a) : lw_expr(L, sc, n->a);
    ir_ref b = logic ? lw_cond(L, sc, n->b) : lw_expr(L, sc, n->b);
    set_pos(L, n->op_loc);
    switch (n->op) {
    case '+': return ir_add(g, a, b);
    case '-': return ir_sub(g, a, b);
    case '*': return ir_mul(g, a, b);
    case '/': return lw_div(L, a, b);
    case '^': return lw_pow(L, a, b);
    case '|': return lib_union(&L->lc, a, b);
    case '&': case '@': return lib_intersection(&L->lc, a, b);
    case '\\': return lib_subtraction(&L->lc, a, b);
    case AST_OP_EQ:
        return ir_op2(g, FREP_OP_LT, ir_op1(g, FREP_OP_ABS, ir_sub(g, a, b)), ir_k(g, HF_EPS));
    case AST_OP_NE:
        return ir_op2(g, FREP_OP_GE, ir_op1(g, FREP_OP_ABS, ir_sub(g, a, b)), ir_k(g, HF_EPS));
    default: {
        frep_opcode op = cmp_op(n->op);
        if (op == FREP_OP__COUNT) return nan_ref(L);
        return ir_op2(g, op, a, b);
    }
    }
}

/* expr -> NUM | VAR | VAR[expr] | CALL | unary | binary (see lang/parse.y) */
static ir_ref lw_expr(lw *L, scope *sc, const ast_node *n)
{
    ir *g = L->g;
    ir_ref a;
    if (L->dead || L->abort || !n) return nan_ref(L);
    switch (n->kind) {
    case AST_NUM:
        return ir_const(g, n->num);
    case AST_VAR: {
        const sym *y = scope_sym(sc, n->key);
        if (!y || y->is_array) return nan_ref(L);
        return cell_value(L, sc, y->first);
    }
    case AST_INDEX:
        return lw_element(L, sc, n);
    case AST_CALL:
        return lw_call(L, sc, n);
    case AST_UNARY:
        a = n->op == AST_OP_NOT ? lw_cond(L, sc, n->a) : lw_expr(L, sc, n->a);
        set_pos(L, n->op_loc);
        if (n->op == AST_OP_NOT) return ir_op1(g, FREP_OP_NOT, a);
        return ir_neg(g, a);
    case AST_BINARY:
        return lw_binary(L, sc, n);
    case AST_ASSIGN: case AST_ASSIGN_INDEX: case AST_ASSIGN_ARRAY: case AST_IF:
    case AST_WHILE:
        break;
    }
    return nan_ref(L);
}

/* cond -> a condition of if/while, an operand of and/or/not: a comparison, and/or/not
 * as they are; any other value v holds where |v| >= 1e-6, as the reference tests
 * conditions (CODE_if and FUNC_bool_* in int_calc.c compare with EPS). */
static ir_ref lw_cond(lw *L, scope *sc, const ast_node *n)
{
    ir *g = L->g;
    ir_ref v;
    if (n && ((n->kind == AST_BINARY && cmp_op(n->op) != FREP_OP__COUNT) ||
              (n->kind == AST_UNARY && n->op == AST_OP_NOT)))
        return lw_expr(L, sc, n);
    v = lw_expr(L, sc, n);
    if (L->dead || L->abort || !n) return v;
    set_pos(L, n->loc);
    return ir_op2(g, FREP_OP_GE, ir_op1(g, FREP_OP_ABS, v), ir_k(g, HF_EPS));
}

/* The callee's s[] comes back to the caller's third argument: the reference
 * interpreter copies that array in and, after the call, out again (I_EXTERN_CALL in
 * int_calc.c: "s[] of a called function ... will be available in the caller with the
 * modified values"), so the attributes a model sets survive in the models that call
 * it.  x and a are not copied back. */
static void copy_back_attrs(lw *L, scope *sc, const scope *callee, const ast_node *n)
{
    const sym *y = scope_sym(sc, n->list.v[2]->key);
    const sym *p = &callee->syms[2];
    uint32_t j, k, *cells;
    ir_ref *vals;
    if (!y || !y->is_array) return;
    k = p->size < y->size ? p->size : y->size;
    cells = arena_alloc(L->A, (k + 1) * sizeof *cells);
    vals = arena_alloc(L->A, (k + 1) * sizeof *vals);
    if (!cells || !vals) return;
    for (j = 0; j < k; j++) {
        cells[j] = y->first + j;
        vals[j] = cell_value(L, callee, p->first + j);
    }
    assign_cells(L, sc, cells, vals, k, n->op_loc);
}

static ir_ref lw_call_model(lw *L, scope *sc, const ast_node *n, uint32_t mi)
{
    const ast_model *m = &L->f->models[mi];
    scope callee;
    uint32_t i, j;
    ir_ref r;
    if (L->inline_depth >= FREP_MAX_INLINE_DEPTH) {
        lw_fatal(L, n->op_loc, "model calls nested more than %u deep",
                 (unsigned)FREP_MAX_INLINE_DEPTH);
        return nan_ref(L);
    }
    if (scope_init(L, &callee, m) < 0) return nan_ref(L);
    /* Arrays are passed by value: the callee works on copies of the elements. */
    for (i = 0; i < m->nparams && i < n->list.n; i++) {
        const sym *y = scope_sym(sc, n->list.v[i]->key);
        const sym *p = &callee.syms[i];
        for (j = 0; j < p->size; j++)
            callee.vals[p->first + j] =
                y && j < y->size ? cell_value(L, sc, y->first + j) : ir_const(L->g, 0);
    }
    L->inline_depth++;
    lw_stmts(L, &callee, &m->body);
    L->inline_depth--;
    r = cell_value(L, &callee, callee.result);
    if (m->nparams == 3 && n->list.n == 3) copy_back_attrs(L, sc, &callee, n);
    return r;
}

/* ---- statements ----------------------------------------------------------------------- */

static const check_free *free_param(lw *L, const ast_node *st)
{
    uint32_t i;
    for (i = 0; i < L->ci->nfree; i++)
        if (L->ci->frees[i].stmt == st) return &L->ci->frees[i];
    return NULL;
}

static ir_ref named_param(lw *L, const check_free *fr)
{
    uint32_t j;
    for (j = 0; j < L->nnamed; j++)
        if (L->named[j].fr == fr) break;
    if (j == L->nnamed) L->named[L->nnamed++].fr = fr;
    set_pos(L, fr->lit);
    return ir_leaf(L->g, FREP_OP_PARAM, L->na + j);
}

static void lw_if(lw *L, scope *sc, const ast_node *n);
static void lw_while(lw *L, scope *sc, const ast_node *n);

/* stmt -> NAME '=' expr ';' (a '@free' literal becomes its PARAM). */
static void lw_assign(lw *L, scope *sc, const ast_node *n)
{
    const sym *y = scope_sym(sc, n->key);
    const check_free *fr = free_param(L, n);
    ir_ref v = fr ? named_param(L, fr) : lw_expr(L, sc, n->a);
    uint32_t c;
    if (!y || L->abort) return;
    c = y->first;
    set_pos(L, n->op_loc);
    assign_cells(L, sc, &c, &v, 1, n->loc);
}

/* stmt -> NAME '[' expr ']' '=' expr ';': a cell, or a STOREI when the index depends
 * on the point. */
static void lw_assign_element(lw *L, scope *sc, const ast_node *n)
{
    ir_ref dyn, v;
    uint32_t c = lw_cellref(L, sc, n, &dyn), si, base;
    lstmt *s;
    if (c == UINT32_MAX) return;
    v = lw_expr(L, sc, n->b);
    if (L->abort || L->dead) return;
    set_pos(L, n->op_loc);
    if (dyn == IR_NONE) {
        assign_cells(L, sc, &c, &v, 1, n->loc);
        return;
    }
    si = c & ~DYN_FLAG;
    base = dyn_base(L, sc, si, 1, n->loc);
    if (L->dead) return;
    s = stmt_new(L, LS_STOREI);
    if (!s) return;
    s->base = base;
    s->size = sc->syms[si].size;
    s->index = dyn;
    s->value = v;
}

/* stmt -> NAME '=' '[' expr {',' expr} ']' ';': a parallel assignment. */
static void lw_assign_list(lw *L, scope *sc, const ast_node *n)
{
    const sym *y = scope_sym(sc, n->key);
    uint32_t i, *cells;
    ir_ref *vals;
    if (!y) return;
    cells = arena_alloc(L->A, (n->list.n + 1) * sizeof *cells);
    vals = arena_alloc(L->A, (n->list.n + 1) * sizeof *vals);
    if (!cells || !vals) return;
    for (i = 0; i < n->list.n && i < y->size; i++) {
        cells[i] = y->first + i;
        vals[i] = lw_expr(L, sc, n->list.v[i]);
    }
    /* A shorter list (a warning: HyperFun rejects it) sets the rest to 0. */
    if (i < y->size) {
        uint32_t *c2 = arena_alloc(L->A, y->size * sizeof *c2);
        ir_ref *v2 = arena_alloc(L->A, y->size * sizeof *v2);
        if (!c2 || !v2) return;
        memcpy(c2, cells, i * sizeof *c2);
        memcpy(v2, vals, i * sizeof *v2);
        for (; i < y->size; i++) {
            c2[i] = y->first + i;
            v2[i] = ir_const(L->g, 0);
        }
        cells = c2;
        vals = v2;
    }
    if (L->abort || L->dead) return;
    set_pos(L, n->op_loc);
    assign_cells(L, sc, cells, vals, i, n->loc);
}

/* stmt -> assignment | if_stmt | while_stmt | expr ';', within the step limit; a
 * failed IR build stops lowering (out of memory, or over FREP_IR_MAX_NODES). */
static void lw_stmt(lw *L, scope *sc, const ast_node *n)
{
    if (L->dead || L->abort) return;
    if (++L->steps > FREP_MAX_LOWER_STEPS) {
        lw_fatal(L, n->loc, "model too large: more than %u statements to compile after "
                 "unrolling loops and inlining model calls", (unsigned)FREP_MAX_LOWER_STEPS);
        return;
    }
    switch (n->kind) {
    case AST_ASSIGN:
        lw_assign(L, sc, n);
        break;
    case AST_ASSIGN_INDEX:
        lw_assign_element(L, sc, n);
        break;
    case AST_ASSIGN_ARRAY:
        lw_assign_list(L, sc, n);
        break;
    case AST_IF:
        lw_if(L, sc, n);
        break;
    case AST_WHILE:
        lw_while(L, sc, n);
        break;
    case AST_NUM: case AST_VAR: case AST_INDEX: case AST_CALL: case AST_UNARY:
    case AST_BINARY:
        (void)lw_expr(L, sc, n);
        break;
    }
    if (L->A->failed || L->g->failed == IR_NOMEM)
        L->dead = 1; /* reported as out of memory by lower_model */
    else if (L->g->failed == IR_TOO_LARGE)
        lw_fatal(L, n->loc, "model too large: more than %u IR nodes",
                 (unsigned)FREP_IR_MAX_NODES);
}

static void lw_stmts(lw *L, scope *sc, const ast_list *l)
{
    uint32_t i;
    for (i = 0; i < l->n && !L->dead && !L->abort; i++) lw_stmt(L, sc, l->v[i]);
}

/* if_stmt at depth 0 with a point-dependent cond: both branches lowered
 * speculatively (quiet nodes) and every cell they change merged with SELECT.
 * Returns 0 when done, -1 when a branch needs real control flow (cells restored). */
static int lw_if_select(lw *L, scope *sc, const ast_node *n, ir_ref cond)
{
    size_t bytes = sc->ncells * sizeof(ir_ref);
    ir_ref *before = arena_alloc(L->A, bytes + sizeof(ir_ref));
    ir_ref *then_v = arena_alloc(L->A, bytes + sizeof(ir_ref));
    int quiet = L->g->quiet;
    uint32_t i;
    if (!before || !then_v) return 0;
    memcpy(before, sc->vals, bytes);
    L->trial++;
    L->g->quiet = 1;
    lw_stmts(L, sc, &n->body);
    memcpy(then_v, sc->vals, bytes);
    memcpy(sc->vals, before, bytes);
    if (!L->abort) lw_stmts(L, sc, &n->body2);
    L->g->quiet = quiet;
    L->trial--;
    if (L->dead) return 0;
    if (!L->abort) {
        set_pos(L, n->a->loc);
        for (i = 0; i < sc->ncells; i++) {
            ir_ref t = then_v[i], e = sc->vals[i];
            if (t == e) continue;
            sc->vals[i] = ir_select(L->g, cond,
                                    t == IR_NONE ? ir_const(L->g, NAN) : t,
                                    e == IR_NONE ? ir_const(L->g, NAN) : e);
        }
        return 0;
    }
    memcpy(sc->vals, before, bytes);
    return -1;
}

/* if_stmt as real control flow: the cells it may write spilled to slots, an LS_IF
 * with both bodies inside. */
static void lw_if_branch(lw *L, scope *sc, const ast_node *n, ir_ref cond)
{
    lblock *saved;
    lstmt *s;
    enter_construct(L, sc, n);
    if (L->dead) return;
    set_pos(L, n->a->loc);
    s = stmt_new(L, LS_IF);
    if (!s) return;
    s->cond = cond;
    saved = L->cur;
    L->cur = &s->body;
    lw_stmts(L, sc, &n->body);
    L->cur = &s->body2;
    lw_stmts(L, sc, &n->body2);
    L->cur = saved;
    L->depth--;
}

/* if_stmt -> IF cond THEN stmts [ELSE stmts] ENDIF: the taken branch when cond folds,
 * else SELECTs when both branches are straight-line, else real control flow. */
static void lw_if(lw *L, scope *sc, const ast_node *n)
{
    ir_ref cond = lw_cond(L, sc, n->a);
    double c;
    if (L->abort || L->dead) return;
    if (ir_is_const(L->g, cond, &c)) {
        lw_stmts(L, sc, c != 0 ? &n->body : &n->body2);
        return;
    }
    if (L->depth == 0) {
        if (lw_if_select(L, sc, n, cond) == 0) return;
        if (L->trial) return; /* the enclosing trial fails too */
        L->abort = 0;
    } else if (L->trial) {
        L->abort = 1;
        return;
    }
    lw_if_branch(L, sc, n, cond);
}

/* while_stmt -> WHILE cond LOOP stmts ENDLOOP */
static void lw_while(lw *L, scope *sc, const ast_node *n)
{
    uint32_t iter = 0, nodes0 = L->g->n, steps0 = L->steps;
    lblock *saved;
    lstmt *s;
    for (;;) {
        ir_ref cond;
        double c;
        if (L->dead || L->abort) return;
        cond = lw_cond(L, sc, n->a);
        if (L->dead || L->abort) return;
        if (!ir_is_const(L->g, cond, &c)) break;
        if (c == 0) return;
        if (iter >= FREP_MAX_UNROLL || L->g->n - nodes0 >= FREP_MAX_UNROLL_NODES ||
            L->steps - steps0 >= FREP_MAX_LOWER_STEPS / 4) {
            ast_loc kw = n->loc; /* the 'while' keyword */
            kw.end = kw.off + 5;
            if (!L->trial)
                lw_report(L, FREP_WARNING, kw, "loop not unrolled after %u iterations: "
                          "it runs at evaluation time (at most %ld iterations per point)",
                          (unsigned)iter, (long)FREP_MAX_LOOP_ITERATIONS);
            break;
        }
        lw_stmts(L, sc, &n->body);
        iter++;
    }
    if (L->trial) {
        L->abort = 1;
        return;
    }
    enter_construct(L, sc, n);
    if (L->dead) return;
    set_pos(L, n->a->loc);
    s = stmt_new(L, LS_WHILE);
    if (!s) return;
    saved = L->cur;
    L->cur = &s->pre;
    s->cond = lw_cond(L, sc, n->a);
    L->cur = &s->body;
    lw_stmts(L, sc, &n->body);
    L->cur = saved;
    L->depth--;
}

int lower_model(arena *A, const ast_file *f, uint32_t mi, const check_info *ci,
                const lower_options *o, ir *g, diag_sink *d, lowered *out)
{
    lw L;
    scope sc;
    const ast_model *m = &f->models[mi];
    uint32_t j;
    unsigned errors0 = d->errors;
    memset(&L, 0, sizeof L);
    memset(out, 0, sizeof *out);
    L.A = A;
    L.f = f;
    L.ci = ci;
    L.g = g;
    L.d = d;
    L.cur = &out->top;
    L.lc.g = g;
    L.lc.error = lib_error_cb;
    L.lc.user = &L;
    L.lc.setops = o->setops;
    L.lc.alpha = o->alpha;
    strmap_init(&L.seen, A);
    L.named = arena_alloc(A, (ci->nfree + 1) * sizeof *L.named);
    if (!L.named) {
        diag_nomem(d);
        return -1;
    }
    g->warn = ir_warn_cb;
    g->warn_user = &L;
    if (scope_init(&L, &sc, m) < 0) {
        diag_nomem(d);
        return -1;
    }
    /* x: the point (elements past the third read 0); a: parameters; s: attributes. */
    for (j = 0; j < sc.syms[0].size; j++)
        sc.vals[sc.syms[0].first + j] = j < 3 ? ir_leaf(g, FREP_OP_X, j) : ir_const(g, 0);
    L.na = sc.syms[1].size;
    for (j = 0; j < sc.syms[1].size; j++)
        sc.vals[sc.syms[1].first + j] = ir_leaf(g, FREP_OP_PARAM, j);
    if (m->nparams == 3)
        for (j = 0; j < sc.syms[2].size; j++) sc.vals[sc.syms[2].first + j] = ir_const(g, 0);
    lw_stmts(&L, &sc, &m->body);
    out->root = cell_value(&L, &sc, sc.result);
    g->warn = NULL;
    g->warn_user = NULL;
    out->nslots = L.nslots;
    out->na = L.na;
    out->named = L.named;
    out->nnamed = L.nnamed;
    out->has_s = m->nparams == 3;
    if (out->has_s) {
        /* The attributes as the model leaves them (doc/language.md, "Attributes"). */
        out->nattrs = sc.syms[2].size;
        out->attrs = arena_alloc(A, (out->nattrs + 1) * sizeof *out->attrs);
        if (out->attrs)
            for (j = 0; j < out->nattrs; j++)
                out->attrs[j] = cell_value(&L, &sc, sc.syms[2].first + j);
    }
    (void)o->a;
    if (A->failed || g->failed == IR_NOMEM) {
        diag_nomem(d);
        return -1;
    }
    return L.dead || d->errors != errors0 ? -1 : 0;
}

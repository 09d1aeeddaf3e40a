/* prune.c - exact interval tape pruning (libfive's and fidget's technique) and the
 * tiled grid evaluator of `frep eval --grid`.
 *
 * bytecode -> prune_plan (data flow of the straight-line program, once) -> per tile:
 * interval pass, decisions, dead-code removal -> shorter program -> runtime/vm.c.
 * Only exact rewrites are made (min/max, min(a, -b), decided selects), so values and
 * domain errors are those of the original program; R-functions are left alone.
 */
#include "config.h"

#include "alloc.h"
#include "prune.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "threads.h"
#include "util.h"
#include "vm_f32.h"
#include "vm_internal.h"

#define PR_NONE UINT32_MAX

/* What the pruned program does with an instruction of the original. */
enum {
    ACT_KEEP,   /* emitted as it is */
    ACT_FWD,    /* not emitted: its value is that of instruction fwd[pc] */
    ACT_CONST,  /* emitted as CONST k (a min/max decided for its immediate operand) */
    ACT_NEG_B   /* emitted as NEG of operand b (min(a, -b) decided for -b) */
};

struct prune_plan {
    const frep_program *p;
    uint32_t n;
    uint32_t root;          /* pc producing the program's result */
    uint32_t *opnd;         /* opnd[3*pc + i]: producer of stack operand i (push order);
                               LOAD: the STORE it reads (PR_NONE: slot never written) */
    uint8_t *nopnd;         /* stack operands of pc (LOAD: 1 when it reads a STORE) */
    uint8_t *sink;          /* STORE nobody reads: always kept (its errors must show) */
};

struct prune_state {
    const prune_plan *pl;
    ival *iv;               /* iv[pc]: enclosure of the value pc pushes (STORE: stores) */
    uint8_t *clean;         /* value finite, |.| <= PRUNE_MAX_MAG, no error, at every
                               point of the box (so iv[pc] holds at every point) */
    uint8_t *errfree;       /* no reported domain error anywhere in pc's data flow */
    uint8_t *act;           /* ACT_* */
    uint32_t *fwd;          /* valid when act == ACT_FWD */
    uint8_t *need;
    frep_insn *code;        /* the pruned program */
    frep_srcpos *pos;
    uint32_t *orig;
    frep_program view;      /* the original's fields with code/pos/ncode replaced */
};

void prune_plan_free(prune_plan *pl)
{
    if (!pl) return;
    frep_free(pl->opnd);
    frep_free(pl->nopnd);
    frep_free(pl->sink);
    frep_free(pl);
}

/* May grid code contain op?  Jumps, indexed arrays and cached primitives have no
 * single producer per operand, so programs with them are not pruned. */
static int plan_supported(frep_opcode op)
{
    switch (op) {
    case FREP_OP_JMP: case FREP_OP_JZ: case FREP_OP_LOADI: case FREP_OP_STOREI:
    case FREP_OP_PRIM: case FREP_OP__COUNT:
        return 0;
    case FREP_OP_CONST: case FREP_OP_X: case FREP_OP_PARAM: case FREP_OP_LOAD:
    case FREP_OP_STORE: case FREP_OP_NEG: case FREP_OP_NOT: case FREP_OP_ABS:
    case FREP_OP_SQRT: case FREP_OP_SQUARE: case FREP_OP_EXP: case FREP_OP_LOG:
    case FREP_OP_LOGD: case FREP_OP_SIN: case FREP_OP_COS: case FREP_OP_TAN:
    case FREP_OP_ASIN: case FREP_OP_ACOS: case FREP_OP_ATAN: case FREP_OP_SINH:
    case FREP_OP_COSH: case FREP_OP_TANH: case FREP_OP_SIGN: case FREP_OP_CEIL:
    case FREP_OP_FLOOR: case FREP_OP_INT: case FREP_OP_FRAC: case FREP_OP_ADD:
    case FREP_OP_SUB: case FREP_OP_MUL: case FREP_OP_DIV: case FREP_OP_POW:
    case FREP_OP_MOD: case FREP_OP_MIN: case FREP_OP_MAX: case FREP_OP_ATAN2:
    case FREP_OP_EQ: case FREP_OP_NE: case FREP_OP_LT: case FREP_OP_LE:
    case FREP_OP_GT: case FREP_OP_GE: case FREP_OP_AND: case FREP_OP_OR:
    case FREP_OP_RUNI: case FREP_OP_RINT: case FREP_OP_RSUB: case FREP_OP_MSUB:
    case FREP_OP_AUNI: case FREP_OP_AINT: case FREP_OP_SELECT:
        return 1;
    default:
        return 0;
    }
}

/* The symbolic run of the stack: each instruction's operand producers, each LOAD's
 * STORE (read[] marks the stores some LOAD reads).  Returns the pc producing the
 * result, or PR_NONE when the code is not supported or does not leave one value. */
static uint32_t plan_symbolic_run(prune_plan *pl, uint32_t *stack, uint32_t *last,
                                  uint8_t *read)
{
    const frep_program *p = pl->p;
    uint32_t sp = 0;
    for (uint32_t j = 0; j <= p->nslots; j++) last[j] = PR_NONE;
    for (uint32_t pc = 0; pc < pl->n; pc++) {
        const frep_insn *in = &p->code[pc];
        frep_opcode op = (frep_opcode)in->op;
        if (!plan_supported(op)) return PR_NONE;
        int nin = insn_nin(in);
        if (nin < 0 || nin > 3 || (uint32_t)nin > sp) return PR_NONE;
        for (int i = 0; i < 3; i++) pl->opnd[3 * pc + (uint32_t)i] = PR_NONE;
        sp -= (uint32_t)nin;
        for (int i = 0; i < nin; i++) pl->opnd[3 * pc + (uint32_t)i] = stack[sp + (uint32_t)i];
        pl->nopnd[pc] = (uint8_t)nin;
        if (op == FREP_OP_LOAD || op == FREP_OP_STORE) {
            if (in->arg >= p->nslots) return PR_NONE;
            if (op == FREP_OP_LOAD) {
                pl->opnd[3 * pc] = last[in->arg];
                pl->nopnd[pc] = last[in->arg] != PR_NONE;
                if (last[in->arg] != PR_NONE) read[last[in->arg]] = 1;
            } else {
                last[in->arg] = pc;
            }
        }
        if (op_pushes(op)) stack[sp++] = pc;
    }
    return sp == 1 ? stack[0] : PR_NONE;
}

/* Does the program have a min, max or select to decide?  (If not, the caller saves
 * the interval pass.) */
static int plan_has_decisions(const frep_program *p)
{
    for (uint32_t pc = 0; pc < p->ncode; pc++) {
        uint8_t op = p->code[pc].op;
        if (op == FREP_OP_MIN || op == FREP_OP_MAX || op == FREP_OP_MSUB ||
            op == FREP_OP_SELECT)
            return 1;
    }
    return 0;
}

prune_plan *prune_plan_new(const frep_program *p)
{
    if (!p || !p->code || p->ncode == 0 || (p->flags & (PROG_HAS_BRANCHES | PROG_HAS_PRIMS)))
        return NULL;
    uint32_t n = p->ncode;
    prune_plan *pl = frep_calloc(1, sizeof *pl);
    uint32_t *stack = frep_malloc((size_t)(n + 1) * sizeof *stack);
    uint32_t *last = frep_malloc((size_t)(p->nslots + 1) * sizeof *last);
    uint8_t *read = frep_calloc((size_t)n + 1, 1);
    if (!pl || !stack || !last || !read) goto fail;
    pl->p = p;
    pl->n = n;
    pl->opnd = frep_malloc((size_t)n * 3 * sizeof *pl->opnd);
    pl->nopnd = frep_calloc(n, 1);
    pl->sink = frep_calloc(n, 1);
    if (!pl->opnd || !pl->nopnd || !pl->sink) goto fail;
    pl->root = plan_symbolic_run(pl, stack, last, read);
    if (pl->root == PR_NONE || !plan_has_decisions(p)) goto fail;
    for (uint32_t pc = 0; pc < n; pc++)
        pl->sink[pc] = p->code[pc].op == FREP_OP_STORE && !read[pc];
    frep_free(stack);
    frep_free(last);
    frep_free(read);
    return pl;
fail:
    frep_free(stack);
    frep_free(last);
    frep_free(read);
    prune_plan_free(pl);
    return NULL;
}

void prune_state_free(prune_state *st)
{
    if (!st) return;
    frep_free(st->iv);
    frep_free(st->clean);
    frep_free(st->errfree);
    frep_free(st->act);
    frep_free(st->fwd);
    frep_free(st->need);
    frep_free(st->code);
    frep_free(st->pos);
    frep_free(st->orig);
    frep_free(st);
}

prune_state *prune_state_new(const prune_plan *pl)
{
    prune_state *st = frep_calloc(1, sizeof *st);
    if (!st) return NULL;
    uint32_t n = pl->n;
    st->pl = pl;
    st->iv = frep_malloc(n * sizeof *st->iv);
    st->clean = frep_malloc(n);
    st->errfree = frep_malloc(n);
    st->act = frep_malloc(n);
    st->fwd = frep_calloc(n, sizeof *st->fwd);
    st->need = frep_malloc(n);
    st->code = frep_malloc(n * sizeof *st->code);
    st->pos = frep_malloc(n * sizeof *st->pos);
    st->orig = frep_malloc(n * sizeof *st->orig);
    if (!st->iv || !st->clean || !st->errfree || !st->act || !st->fwd || !st->need ||
        !st->code || !st->pos || !st->orig) {
        prune_state_free(st);
        return NULL;
    }
    st->view = *pl->p;
    st->view.code = st->code;
    st->view.pos = st->pos;
    st->view.cap = n;
    return st;
}

uint32_t prune_orig_pc(const prune_state *st, uint32_t pc)
{
    return pc < st->view.ncode ? st->orig[pc] : pc;
}

/* ---- the interval pass ----------------------------------------------------------- */

static ival pr_iv(double lo, double hi)
{
    ival r = { lo, hi };
    return r;
}

static int pr_bounded(ival a)
{
    return fabs(a.lo) <= PRUNE_MAX_MAG && fabs(a.hi) <= PRUNE_MAX_MAG;
}

/* Is a domain-checked operation error-free at every point, given operands that are
 * clean (so their intervals hold everywhere)?  The conditions are the complements of
 * opsem.h's opsem_bad_* tests. */
static int pr_domain_ok(frep_opcode op, ival a, ival b)
{
    switch ((unsigned)op) { /* not an enum switch: only the OPF_DOMAIN ops matter */
    case FREP_OP_SQRT: return a.lo >= 0;
    case FREP_OP_LOG: case FREP_OP_LOGD: return a.lo > 0;
    case FREP_OP_ASIN: case FREP_OP_ACOS: return a.lo >= -1 && a.hi <= 1;
    case FREP_OP_DIV: case FREP_OP_MOD: return b.lo > 0 || b.hi < 0;
    case FREP_OP_POW: return a.lo >= 0 || (b.lo == b.hi && b.lo == trunc(b.lo));
    default: return 0;
    }
}

/* Over a sub-box, the facts of pc that follow from the parent's decision alone; 0 when
 * pc is kept by the parent and must be analysed. */
static int pr_inherit(const prune_plan *pl, prune_state *st, const prune_state *parent,
                      uint32_t pc)
{
    const frep_insn *in = &pl->p->code[pc];
    if (parent->act[pc] == ACT_FWD) {
        /* the same values as the instruction it forwards to, here too */
        uint32_t q = parent->fwd[pc];
        st->iv[pc] = st->iv[q];
        st->clean[pc] = st->clean[q];
        st->errfree[pc] = st->errfree[q];
    } else if (!parent->need[pc]) {
        /* not in the parent's program, so in none of its sub-boxes' */
        st->iv[pc] = pr_iv(-INFINITY, INFINITY);
        st->clean[pc] = 0;
        st->errfree[pc] = 0;
    } else if (parent->act[pc] == ACT_CONST) {
        double k = in->op == FREP_OP_MSUB && (in->flags & INSN_KB) ? -in->k : in->k;
        st->iv[pc] = pr_iv(k, k);
        st->clean[pc] = (uint8_t)pr_bounded(st->iv[pc]);
        st->errfree[pc] = 1;
    } else if (parent->act[pc] == ACT_NEG_B) {
        uint32_t b = pl->opnd[3 * pc + pl->nopnd[pc] - 1];
        st->iv[pc] = pr_iv(-st->iv[b].hi, -st->iv[b].lo);
        st->clean[pc] = st->clean[b];
        st->errfree[pc] = st->errfree[b];
    } else {
        return 0;
    }
    return 1;
}

/* The enclosure of an operator pc from its operands'; a domain operation keeps *clean
 * (and, unless quiet, *errfree) only when its operands are provably inside the domain. */
static ival pr_operator(const prune_plan *pl, const prune_state *st, uint32_t pc, int *clean,
                        int *errfree)
{
    const frep_insn *in = &pl->p->code[pc];
    frep_opcode op = (frep_opcode)in->op;
    const uint32_t *o = &pl->opnd[3 * pc];
    ival v[3];
    uint32_t j = 0;
    if (op_nin(op) == 2 && (in->flags & INSN_KA)) v[j++] = pr_iv(in->k, in->k);
    for (uint32_t i = 0; i < pl->nopnd[pc]; i++) v[j++] = st->iv[o[i]];
    if (op_nin(op) == 2 && (in->flags & INSN_KB)) v[j++] = pr_iv(in->k, in->k);
    while (j < 3) v[j++] = pr_iv(0, 0);
    ival r = ival_op(op, v, in->k);
    /* ival_op widens every rounded bound by an ulp, so a sum or product of nonnegative
     * numbers could get a negative lower bound and hide that a later sqrt is safe; in
     * IEEE arithmetic such results are never < 0. */
    if ((op == FREP_OP_ADD || op == FREP_OP_MUL) && v[0].lo >= 0 && v[1].lo >= 0 && r.lo < 0)
        r.lo = 0;
    if (op_flags(op) & OPF_DOMAIN) {
        int ok = *clean && pr_domain_ok(op, v[0], v[1]);
        *clean &= ok;
        if (!(in->flags & INSN_QUIET)) *errfree &= ok;
    }
    return r;
}

/* The enclosure of instruction pc over the box (leaves, slots, operators). */
static ival pr_enclosure(const prune_plan *pl, const prune_state *st, uint32_t pc,
                         const double box[6], const double *params, int *clean, int *errfree)
{
    const frep_program *p = pl->p;
    const frep_insn *in = &p->code[pc];
    const uint32_t o0 = pl->opnd[3 * pc];
    switch ((unsigned)in->op) { /* not an enum switch: the operators share the default */
    case FREP_OP_CONST: return pr_iv(in->k, in->k);
    case FREP_OP_X:
        return in->arg <= 2 ? pr_iv(box[in->arg], box[in->arg + 3]) : pr_iv(-INFINITY, INFINITY);
    case FREP_OP_PARAM: {
        double v = in->arg < p->nparams ? (params ? params[in->arg] : p->params[in->arg].value)
                                        : NAN;
        return pr_iv(v, v);
    }
    case FREP_OP_LOAD: case FREP_OP_STORE: return o0 == PR_NONE ? pr_iv(0, 0) : st->iv[o0];
    default: return pr_operator(pl, st, pc, clean, errfree);
    }
}

/* Enclosures, cleanliness and error-freedom of every instruction over the box. */
static void pr_intervals(const prune_plan *pl, prune_state *st, const prune_state *parent,
                         const double box[6], const double *params)
{
    for (uint32_t pc = 0; pc < pl->n; pc++) {
        const uint32_t *o = &pl->opnd[3 * pc];
        int clean = 1, errfree = 1;
        if (parent && pr_inherit(pl, st, parent, pc)) continue;
        for (uint32_t i = 0; i < pl->nopnd[pc]; i++) {
            clean &= st->clean[o[i]];
            errfree &= st->errfree[o[i]];
        }
        ival r = pr_enclosure(pl, st, pc, box, params, &clean, &errfree);
        if (isnan(r.lo) || isnan(r.hi) || !(r.lo <= r.hi)) r = pr_iv(-INFINITY, INFINITY);
        st->iv[pc] = r;
        st->clean[pc] = (uint8_t)(clean && pr_bounded(r));
        st->errfree[pc] = (uint8_t)errfree;
    }
}

/* ---- decisions and the pruned program ---------------------------------------------- */

static uint32_t pr_resolve(const prune_state *st, uint32_t pc)
{
    while (st->act[pc] == ACT_FWD) pc = st->fwd[pc];
    return pc;
}

/* Decide instruction pc over the box. A binary set operation with a clean operand
 * strictly below (min) or above (max) the other at every point returns that operand
 * exactly (opsem_min/max: no tie, no NaN); the other is dropped, which is allowed only
 * when it raises no error. */
static void pr_decide(const prune_plan *pl, prune_state *st, uint32_t pc)
{
    const frep_insn *in = &pl->p->code[pc];
    frep_opcode op = (frep_opcode)in->op;
    const uint32_t *o = &pl->opnd[3 * pc];
    if (op == FREP_OP_SELECT) {
        uint32_t c = o[0];
        if (!st->clean[c]) return;
        ival ci = st->iv[c];
        int t = ci.lo > 0 || ci.hi < 0, f = ci.lo == 0 && ci.hi == 0;
        uint32_t keep = t ? o[1] : o[2], drop = t ? o[2] : o[1];
        if ((t || f) && st->errfree[drop]) {
            st->act[pc] = ACT_FWD;
            st->fwd[pc] = keep;
        }
        return;
    }
    if (op != FREP_OP_MIN && op != FREP_OP_MAX && op != FREP_OP_MSUB) return;
    /* operands a, b in the op's order; ka/kb: that operand is the immediate */
    int ka = (in->flags & INSN_KA) != 0, kb = (in->flags & INSN_KB) != 0;
    uint32_t pa = ka ? PR_NONE : o[0], pb = kb ? PR_NONE : o[ka ? 0 : 1];
    ival k = { in->k, in->k };
    ival A = ka ? k : st->iv[pa], B = kb ? k : st->iv[pb];
    int ca = ka ? pr_bounded(k) : st->clean[pa], cb = kb ? pr_bounded(k) : st->clean[pb];
    if (!ca || !cb) return;
    if (op == FREP_OP_MSUB) B = pr_iv(-B.hi, -B.lo);
    int keep_a = 0, keep_b = 0;
    if (op == FREP_OP_MAX) {
        keep_a = A.lo > B.hi;
        keep_b = B.lo > A.hi;
    } else {
        keep_a = A.hi < B.lo;
        keep_b = B.hi < A.lo;
    }
    if (keep_a) {
        if (ka) st->act[pc] = ACT_CONST;
        else {
            st->act[pc] = ACT_FWD;
            st->fwd[pc] = pa;
        }
    } else if (keep_b) {
        if (op == FREP_OP_MSUB) {
            /* -b: b's value negated (exact); a constant folds to -k */
            if (kb) st->act[pc] = ACT_CONST;
            else st->act[pc] = ACT_NEG_B;
        } else if (kb) {
            st->act[pc] = ACT_CONST;
        } else {
            st->act[pc] = ACT_FWD;
            st->fwd[pc] = pb;
        }
    }
}

const frep_program *prune_for_box(const prune_plan *pl, prune_state *st, const double box[6],
                                  const double *params, ival *enclosure)
{
    return prune_for_subbox(pl, st, NULL, box, params, enclosure);
}

/* Decide every instruction over the box; on a sub-box the parent's decisions hold, so
 * only what the parent kept is decided again. */
static void pr_decide_box(const prune_plan *pl, prune_state *st, const prune_state *parent)
{
    uint32_t n = pl->n;
    if (parent) {
        memcpy(st->act, parent->act, n);
        memcpy(st->fwd, parent->fwd, n * sizeof *st->fwd);
        for (uint32_t pc = 0; pc < n; pc++)
            if (parent->need[pc] && parent->act[pc] == ACT_KEEP) pr_decide(pl, st, pc);
    } else {
        memset(st->act, ACT_KEEP, n);
        for (uint32_t pc = 0; pc < n; pc++) pr_decide(pl, st, pc);
    }
}

/* Mark what the result, and stores nobody reads, depend on (through forwards). */
static void pr_mark_needed(const prune_plan *pl, prune_state *st)
{
    memset(st->need, 0, pl->n);
    st->need[pr_resolve(st, pl->root)] = 1;
    for (uint32_t pc = pl->n; pc-- > 0;) {
        if (pl->sink[pc]) st->need[pc] = 1;
        if (!st->need[pc]) continue;
        const uint32_t *o = &pl->opnd[3 * pc];
        switch (st->act[pc]) {
        case ACT_KEEP:
            for (uint32_t i = 0; i < pl->nopnd[pc]; i++) st->need[pr_resolve(st, o[i])] = 1;
            break;
        case ACT_NEG_B:
            st->need[pr_resolve(st, o[pl->nopnd[pc] - 1])] = 1;
            break;
        default:
            break;
        }
    }
}

/* The needed instructions in their original order (rewritten per their action): valid
 * stack code, since every value has one consumer. */
static void pr_build(const prune_plan *pl, prune_state *st)
{
    const frep_program *p = pl->p;
    uint32_t m = 0;
    for (uint32_t pc = 0; pc < pl->n; pc++) {
        if (!st->need[pc]) continue;
        frep_insn in = p->code[pc];
        if (st->act[pc] == ACT_CONST) {
            /* the kept immediate: k, or -k when it is b of min(a, -b) */
            double k = in.op == FREP_OP_MSUB && (in.flags & INSN_KB) ? -in.k : in.k;
            in.op = FREP_OP_CONST;
            in.flags = 0;
            in.arg = 0;
            in.k = k;
        } else if (st->act[pc] == ACT_NEG_B) {
            in.op = FREP_OP_NEG;
            in.flags = 0;
            in.arg = 0;
            in.k = 0;
        }
        st->code[m] = in;
        st->pos[m] = p->pos ? p->pos[pc] : (frep_srcpos){ 0, 0, 0 };
        st->orig[m] = pc;
        m++;
    }
    st->view.ncode = m;
}

const frep_program *prune_for_subbox(const prune_plan *pl, prune_state *st,
                                     const prune_state *parent, const double box[6],
                                     const double *params, ival *enclosure)
{
    pr_intervals(pl, st, parent, box, params);
    pr_decide_box(pl, st, parent);
    pr_mark_needed(pl, st);
    pr_build(pl, st);
    if (enclosure) {
        ival r = st->iv[pl->root];
        *enclosure = st->clean[pl->root] ? r : pr_iv(-INFINITY, INFINITY);
    }
    return &st->view;
}

/* ---- the tiled grid evaluator --------------------------------------------------- */

void prune_grid_stats_init(prune_grid_stats *s)
{
    memset(s, 0, sizeof *s);
    s->min = INFINITY;
    s->max = -INFINITY;
}

/* Independent accumulators of the summary loop: one per lane of two AVX2 vectors, so
 * the loop has no branch and no serial dependence and GCC vectorizes it (all of them
 * doubles: mixing in integer counters stopped it; counts of at most FREP_BLOCK are
 * exact in a double).  The lanes are combined in a fixed order, so the sum depends
 * only on the block's values. */
#define SUM_LANES 8

/* Add the summary of f[0..n-1] to *t. */
static void grid_summarize(const double *f, size_t n, prune_grid_stats *t) VM_CLONES;
static void grid_summarize(const double *f, size_t n, prune_grid_stats *t)
{
    double mn[SUM_LANES], mx[SUM_LANES], sm[SUM_LANES], ge[SUM_LANES], lt[SUM_LANES];
    size_t i = 0, l;
    for (l = 0; l < SUM_LANES; l++) {
        mn[l] = INFINITY;
        mx[l] = -INFINITY;
        sm[l] = ge[l] = lt[l] = 0;
    }
    /* NaN fails every comparison: neither >= 0 nor < 0 (so NaNs are the rest), and
     * leaves min and max alone */
#define SUMMARIZE_LANE(v, l)                                                       \
    do {                                                                           \
        ge[l] += (v) >= 0 ? 1.0 : 0.0;                                             \
        lt[l] += (v) < 0 ? 1.0 : 0.0;                                              \
        mn[l] = (v) < mn[l] ? (v) : mn[l];                                         \
        mx[l] = (v) > mx[l] ? (v) : mx[l];                                         \
        sm[l] += fabs(v) < INFINITY ? (v) : 0.0;                                   \
    } while (0)
    for (; i + SUM_LANES <= n; i += SUM_LANES)
        for (l = 0; l < SUM_LANES; l++) SUMMARIZE_LANE(f[i + l], l);
    for (l = 0; i < n; i++, l++) SUMMARIZE_LANE(f[i], l);
#undef SUMMARIZE_LANE
    double sum = 0, nge = 0, nlt = 0;
    for (l = 0; l < SUM_LANES; l++) {
        nge += ge[l];
        nlt += lt[l];
        if (mn[l] < t->min) t->min = mn[l];
        if (mx[l] > t->max) t->max = mx[l];
        sum += sm[l];
    }
    t->inside += (uint64_t)nge;
    t->nans += (uint64_t)n - (uint64_t)nge - (uint64_t)nlt;
    t->sum += sum;
}

/* One thread's tools. */
typedef struct grid_worker {
    vm_scratch *s;
    prune_state *st;         /* a tile's pruned program */
    prune_state *sp;         /* its super-tile's */
    double *x, *y, *z, *f;   /* one block of points */
    double *zp;              /* z of each plane of the slab over a block (see below) */
    long zp_k0;              /* first plane zp holds; -1: none */
    uint32_t *idx;           /* their offsets in the caller's f */
    vm_f32 *f32;             /* the float evaluator (PRUNE_GRID_SINGLE), else NULL */
    double e32;              /* the current tile's float error bound; INFINITY: double */
} grid_worker;

static void worker_free(grid_worker *w)
{
    vm_scratch_free(w->s);
    prune_state_free(w->st);
    prune_state_free(w->sp);
    frep_free(w->x);
    frep_free(w->y);
    frep_free(w->z);
    frep_free(w->zp);
    frep_free(w->f);
    frep_free(w->idx);
    vm_f32_free(w->f32);
}

static int worker_init(grid_worker *w, const frep_program *p, const prune_plan *pl, int single)
{
    memset(w, 0, sizeof *w);
    w->zp_k0 = -1;
    w->e32 = INFINITY;
    if (single && !(w->f32 = vm_f32_new(p))) return -1;
    w->s = vm_scratch_new(p);
    w->st = pl ? prune_state_new(pl) : NULL;
    w->sp = pl ? prune_state_new(pl) : NULL;
    w->x = frep_malloc(FREP_BLOCK * sizeof *w->x);
    w->y = frep_malloc(FREP_BLOCK * sizeof *w->y);
    w->z = frep_malloc(FREP_BLOCK * sizeof *w->z);
    w->zp = frep_malloc((size_t)PRUNE_TILE * FREP_BLOCK * sizeof *w->zp);
    w->f = frep_malloc(FREP_BLOCK * sizeof *w->f);
    w->idx = frep_malloc(FREP_BLOCK * sizeof *w->idx);
    if (!w->s || (pl && (!w->st || !w->sp)) || !w->x || !w->y || !w->z || !w->zp || !w->f ||
        !w->idx) {
        worker_free(w);
        return -1;
    }
    return 0;
}

typedef struct grid_job {
    const frep_program *p;
    const prune_plan *pl;
    /* planes [k0, k1) in slabs of nk planes from k0 (the last one may be thinner); each
     * slab is cut into ntx x ntx tiles, in super-tiles of PRUNE_SUPER x PRUNE_SUPER */
    long n, k0, k1, nk, ntx, nsx;
    const double *c[3];      /* the grid's coordinates per axis: frep_grid_coord */
    double *f;               /* the values ((k - k0) * n + j) * n + i, or NULL */
    /* Tiles are numbered slab by slab, row by row: t = (slab * ntx + ty) * ntx + tx.
     * The per-tile results of the current run of tiles [tbase, tbase + count). */
    long tbase;
    vm_errstate *terr;       /* terr[t - tbase] */
    prune_grid_stats *tst;   /* tst[t - tbase], or NULL: no summary */
    int sized;               /* threads chosen by the job's size (grid_threads) */
    int single;              /* PRUNE_GRID_SINGLE and the program runs in float */
} grid_job;

/* Whether every float value of f[n] is farther than e from 0 (so on double's side). */
static int f32_certain(const double *f, size_t n, double e)
{
    int near = 0;
    for (size_t i = 0; i < n; i++) near |= !(fabs(f[i]) > e);
    return !near;
}

/* The lanes of f[n] within e of 0 (or NaN) again in double: gathered into one short
 * block, evaluated, scattered back. */
static int f32_redo(const frep_program *q, vm_scratch *s, const vm_inputs *in, size_t n,
                    double e, double *f)
{
    double x[FREP_BLOCK], y[FREP_BLOCK], z[FREP_BLOCK], v[FREP_BLOCK];
    uint16_t at[FREP_BLOCK];
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        if (fabs(f[i]) > e) continue;
        x[m] = in->x[i];
        y[m] = in->y[i];
        z[m] = in->z[i];
        at[m++] = (uint16_t)i;
    }
    vm_inputs g = *in;
    g.x = x;
    g.y = y;
    g.z = z;
    if (vm_eval_block(q, s, &g, m, v) < 0) return -1;
    for (size_t k = 0; k < m; k++) f[at[k]] = v[k];
    return 0;
}

/* Evaluate nb points gathered in w, scatter rows back to f (row r of w's block has
 * idx[r] as its first offset and `row` points). */
static int grid_flush(const grid_job *g, grid_worker *w, const frep_program *q, size_t nb,
                      size_t row, const double *z, prune_grid_stats *tst, double *insns)
{
    vm_inputs in;
    memset(&in, 0, sizeof in);
    in.x = w->x;
    in.y = w->y;
    in.z = z;
    if (w->e32 < INFINITY && vm_f32_eval_block(w->f32, q, w->x, w->y, z, nb, w->f) == 0) {
        if (tst) tst->single++;
        if (!f32_certain(w->f, nb, w->e32)) {
            if (tst) tst->redone++;
            if (f32_redo(q, w->s, &in, nb, w->e32, w->f) < 0) return -1;
        }
    } else if (vm_eval_block(q, w->s, &in, nb, w->f) < 0) {
        return -1;
    }
    if (g->f)
        for (size_t b = 0; b < nb; b += row)
            memcpy(g->f + w->idx[b / row], w->f + b, row * sizeof *w->f);
    if (tst) grid_summarize(w->f, nb, tst);
    *insns += (double)q->ncode * (double)nb;
    return 0;
}

/* The index ranges [i0, i1) x [j0, j1) x [k0, k1) of one tile. */
typedef struct tile_span {
    long i0, i1, j0, j1, k0, k1;
} tile_span;

/* The planes [k0, k1) of slab s. */
static void slab_planes(const grid_job *g, long s, long *k0, long *k1)
{
    *k0 = g->k0 + s * g->nk;
    *k1 = *k0 + g->nk < g->k1 ? *k0 + g->nk : g->k1;
}

static tile_span tile_span_of(const grid_job *g, long t)
{
    tile_span ts;
    long per = g->ntx * g->ntx, r = t % per;
    long tx = r % g->ntx, ty = r / g->ntx;
    ts.i0 = tx * PRUNE_TILE;
    ts.j0 = ty * PRUNE_TILE;
    ts.i1 = ts.i0 + PRUNE_TILE < g->n ? ts.i0 + PRUNE_TILE : g->n;
    ts.j1 = ts.j0 + PRUNE_TILE < g->n ? ts.j0 + PRUNE_TILE : g->n;
    slab_planes(g, t / per, &ts.k0, &ts.k1);
    return ts;
}

/* Offset in the caller's f of the first point of row (j, k) of the tile. */
static uint32_t tile_row_offset(const grid_job *g, const tile_span *ts, long j, long k)
{
    size_t nn = (size_t)g->n;
    return (uint32_t)(((size_t)(k - g->k0) * nn + (size_t)j) * nn + (size_t)ts->i0);
}

/* A whole tile: each block is one plane of it, so y is the same in every block (written
 * once per tile) and z constant over a block (written once per slab): no coordinate is
 * written per point. */
static int grid_tile_planes(const grid_job *g, grid_worker *w, const frep_program *q,
                            const tile_span *ts, prune_grid_stats *tst, double *insns)
{
    size_t row = (size_t)(ts->i1 - ts->i0);
    for (long j = ts->j0; j < ts->j1; j++)
        for (size_t i = 0; i < row; i++) w->y[(size_t)(j - ts->j0) * row + i] = g->c[1][j];
    if (w->zp_k0 != ts->k0) {
        for (long k = ts->k0; k < ts->k1; k++)
            for (size_t i = 0; i < FREP_BLOCK; i++)
                w->zp[(size_t)(k - ts->k0) * FREP_BLOCK + i] = g->c[2][k];
        w->zp_k0 = ts->k0;
    }
    for (long k = ts->k0; k < ts->k1; k++) {
        if (g->f)
            for (long j = ts->j0; j < ts->j1; j++) w->idx[j - ts->j0] = tile_row_offset(g, ts, j, k);
        if (grid_flush(g, w, q, FREP_BLOCK, row, w->zp + (size_t)(k - ts->k0) * FREP_BLOCK, tst,
                       insns) < 0)
            return -1;
    }
    return 0;
}

/* Any tile: rows gathered into blocks of whole rows, y and z written per point. */
static int grid_tile_rows(const grid_job *g, grid_worker *w, const frep_program *q,
                          const tile_span *ts, prune_grid_stats *tst, double *insns)
{
    size_t row = (size_t)(ts->i1 - ts->i0), nb = 0;
    for (long k = ts->k0; k < ts->k1; k++) {
        const double zk = g->c[2][k];
        for (long j = ts->j0; j < ts->j1; j++) {
            if (nb + row > FREP_BLOCK) {
                if (grid_flush(g, w, q, nb, row, w->z, tst, insns) < 0) return -1;
                nb = 0;
            }
            const double yj = g->c[1][j];
            double *y = w->y + nb, *z = w->z + nb;
            for (size_t i = 0; i < row; i++) {
                y[i] = yj;
                z[i] = zk;
            }
            if (g->f) w->idx[nb / row] = tile_row_offset(g, ts, j, k);
            nb += row;
        }
    }
    if (nb && grid_flush(g, w, q, nb, row, w->z, tst, insns) < 0) return -1;
    return 0;
}

/* Evaluate tile t (rows of up to PRUNE_TILE points, PRUNE_TILE^2 rows); its errors
 * (original pcs) and summary go to the job's per-tile arrays, its cost to *insns. */
static int grid_tile(const grid_job *g, grid_worker *w, long t, double *insns)
{
    tile_span ts = tile_span_of(g, t);
    const frep_program *q = g->p;
    /* the coordinates are monotone in the index, so the corners bound the tile */
    double box[6] = { g->c[0][ts.i0], g->c[1][ts.j0], g->c[2][ts.k0],
                      g->c[0][ts.i1 - 1], g->c[1][ts.j1 - 1], g->c[2][ts.k1 - 1] };
    if (g->pl) q = prune_for_subbox(g->pl, w->st, w->sp, box, NULL, NULL);
    /* per tile: a super-tile's bound (64 x 64 x 16 points) is loose enough to send half
     * the gear's blocks back to double */
    w->e32 = g->single && q->ncode >= VM_F32_MIN_CODE ? vm_f32_bound(w->f32, q, box) : INFINITY;
    memset(&w->s->total, 0, sizeof w->s->total);
    prune_grid_stats *tst = g->tst ? &g->tst[t - g->tbase] : NULL;
    if (tst) prune_grid_stats_init(tst);
    size_t row = (size_t)(ts.i1 - ts.i0);
    /* x repeats the tile's row in every block: written once per tile */
    for (size_t b = 0; b + row <= FREP_BLOCK; b += row)
        memcpy(w->x + b, g->c[0] + ts.i0, row * sizeof *w->x);
    int whole = row * (size_t)(ts.j1 - ts.j0) == FREP_BLOCK && g->nk <= PRUNE_TILE;
    int rc = whole ? grid_tile_planes(g, w, q, &ts, tst, insns)
                   : grid_tile_rows(g, w, q, &ts, tst, insns);
    if (rc < 0) return -1;
    vm_errstate *err = &g->terr[t - g->tbase];
    *err = w->s->total;
    if (err->count && g->pl) err->pc = prune_orig_pc(w->st, err->pc);
    return 0;
}

/* Evaluate super-tile u (numbered slab by slab): prune for its box, then each of its
 * tiles from there. */
static int grid_super(const grid_job *g, grid_worker *w, long u, double *insns)
{
    long per = g->nsx * g->nsx, slab = u / per, r = u % per;
    long sx = r % g->nsx, sy = r / g->nsx;
    long tx0 = sx * PRUNE_SUPER, ty0 = sy * PRUNE_SUPER;
    long tx1 = tx0 + PRUNE_SUPER < g->ntx ? tx0 + PRUNE_SUPER : g->ntx;
    long ty1 = ty0 + PRUNE_SUPER < g->ntx ? ty0 + PRUNE_SUPER : g->ntx;
    if (g->pl) {
        long i1 = tx1 * PRUNE_TILE < g->n ? tx1 * PRUNE_TILE : g->n;
        long j1 = ty1 * PRUNE_TILE < g->n ? ty1 * PRUNE_TILE : g->n;
        long k0, k1;
        slab_planes(g, slab, &k0, &k1);
        double box[6] = { g->c[0][tx0 * PRUNE_TILE], g->c[1][ty0 * PRUNE_TILE], g->c[2][k0],
                          g->c[0][i1 - 1], g->c[1][j1 - 1], g->c[2][k1 - 1] };
        prune_for_box(g->pl, w->sp, box, NULL, NULL);
    }
    for (long ty = ty0; ty < ty1; ty++)
        for (long tx = tx0; tx < tx1; tx++) {
            long t = (slab * g->ntx + ty) * g->ntx + tx;
            if (grid_tile(g, w, t, insns) < 0) return -1;
        }
    return 0;
}

int prune_eval_grid_planes(const frep_program *p, long n, const double box[6], long k0,
                           long nk, int prune, int nthreads, double *f,
                           frep_runtime_error *err, double *insns)
{
    return prune_eval_grid_summary(p, n, box, k0, nk, prune, nthreads, f, NULL, err, insns);
}

/* The grid's coordinates per axis, lo + (hi - lo) i / (n - 1), into g->c (one allocation, returned
 * for frep_free; NULL when out of memory). */
static double *grid_coords(grid_job *g, const double box[6])
{
    size_t n = (size_t)g->n;
    double *coord = frep_malloc(n * 3 * sizeof *coord);
    if (!coord) return NULL;
    for (int c = 0; c < 3; c++) {
        for (long i = 0; i < g->n; i++)
            coord[(size_t)c * n + (size_t)i] = frep_grid_coord(box[c], box[c + 3], i, g->n - 1);
        g->c[c] = coord + (size_t)c * n;
    }
    return coord;
}

/* The threads for super-tiles [u0, u1) of the job: with g->sized, frep_threads_for
 * its work, the points times the program's length (pruning only shortens it); else
 * frep_threads(nthreads), at most one per super-tile. */
static int grid_threads(const grid_job *g, long u0, long u1, int nthreads)
{
    if (!g->sized) {
        int nt = frep_threads(nthreads);
        return (long)nt > u1 - u0 ? (int)(u1 - u0) : nt;
    }
    long per = g->nsx * g->nsx;
    double slabs = (double)(u1 - u0) / (double)per;
    double pts = slabs * (double)g->nk * (double)g->n * (double)g->n;
    return frep_threads_for(nthreads, pts * (double)g->p->ncode, (size_t)(u1 - u0));
}

/* One run of super-tiles [u0, u1) on frep_par_for_late: one super-tile a chunk, each
 * thread with its own tools (set up on its first super-tile) and its own cost. */
typedef struct grid_team {
    const grid_job *g;
    long u0;
    _Atomic int failed;
    double insns[FREP_PAR_MAX_THREADS];      /* instructions x points thread k evaluated */
    int ready[FREP_PAR_MAX_THREADS];         /* w[k] set up */
    grid_worker w[FREP_PAR_MAX_THREADS];
} grid_team;

static void grid_chunk(void *ctx, int thread, long i0, long i1)
{
    grid_team *tm = ctx;
    grid_worker *w = &tm->w[thread];
    if (!tm->ready[thread]) {
        if (worker_init(w, tm->g->p, tm->g->pl, tm->g->single) != 0) {
            atomic_store(&tm->failed, 1);
            return;
        }
        tm->ready[thread] = 1;
    }
    for (long i = i0; i < i1; i++)
        if (grid_super(tm->g, w, tm->u0 + i, &tm->insns[thread]) < 0)
            atomic_store(&tm->failed, 1);
}

/* A pruned grid's work is known only as it is done: the unpruned length that
 * frep_threads_for is given overstates the min/max gear's 34 instructions a point 13x,
 * so the work left is estimated from the super-tiles the calling thread has done. */
static double grid_left(void *ctx, long done, long n)
{
    const grid_team *tm = ctx;
    return tm->insns[0] / (double)done * (double)(n - done);
}

/* Evaluate super-tiles [u0, u1) on up to grid_threads() threads, the calling one
 * included, on frep_par_for_late (threads.c: joined asleep, nothing spins; helpers
 * started at once when the work is known up front, unpruned or a thread count asked
 * for, else once grid_left reaches FREP_PAR_MIN_WORK).
 * The instructions x points evaluated are added to *cost (whole numbers, so the sum
 * does not depend on the order).  Returns -1 if a worker could not be set up or a tile
 * failed (out of memory); a thread that cannot be started leaves its share to the
 * others. */
static int grid_run(const grid_job *g, long u0, long u1, int nthreads, double *cost,
                    int *used)
{
    grid_team *tm = frep_malloc(sizeof *tm);
    if (!tm) return -1;
    tm->g = g;
    tm->u0 = u0;
    atomic_init(&tm->failed, 0);
    int nt = grid_threads(g, u0, u1, nthreads);
    if (nt > FREP_PAR_MAX_THREADS) nt = FREP_PAR_MAX_THREADS;
    for (int k = 0; k < nt; k++) {
        tm->insns[k] = 0;
        tm->ready[k] = 0;
    }
    int ran = frep_par_for_late(nt, u1 - u0, 1, grid_chunk,
                                g->sized && g->pl ? grid_left : NULL, tm);
    for (int k = 0; k < ran; k++) {
        *cost += tm->insns[k];
        if (tm->ready[k]) worker_free(&tm->w[k]);
    }
    if (ran > *used) *used = ran;
    int rc = atomic_load(&tm->failed) ? -1 : 0;
    frep_free(tm);
    return rc;
}

/* Add the tiles' summaries to *stats in tile order: the sum does not depend on which
 * thread ran which tile. */
static void grid_add_stats(prune_grid_stats *stats, const prune_grid_stats *tst, long ntiles)
{
    for (long t = 0; t < ntiles; t++) {
        const prune_grid_stats *ts = &tst[t];
        stats->inside += ts->inside;
        stats->nans += ts->nans;
        if (ts->min < stats->min) stats->min = ts->min;
        if (ts->max > stats->max) stats->max = ts->max;
        stats->sum += ts->sum;
        stats->single += ts->single;
        stats->redone += ts->redone;
    }
}

/* Planes [k0, k1) in slabs of nk planes: the slabs' super-tiles in runs of at most
 * PRUNE_RUN_TILES tiles (whole slabs), each run one parallel region; the per-tile
 * results merged in tile order after each run, so the figures do not depend on the
 * thread count or the runs' size. */
static int grid_eval(const frep_program *p, long n, const double box[6], long k0, long k1,
                     long nk, int prune, int nthreads, int sized, int single, double *f,
                     prune_grid_stats *stats, frep_runtime_error *err, double *insns,
                     int *threads_used)
{
    int used = 1;
    grid_job g;
    memset(&g, 0, sizeof g);
    g.sized = sized;
    g.single = single && vm_f32_supported(p);
    g.p = p;
    g.n = n;
    g.k0 = k0;
    g.k1 = k1;
    g.nk = nk;
    g.f = f;
    if (err) memset(err, 0, sizeof *err);
    if (k1 <= k0) return 0;
    /* the flat index of a point in f is a uint32_t: plenty for a slab of planes */
    if (f && (double)n * (double)n * (double)(k1 - k0) > 4294967295.0) return -1;
    double *coord = grid_coords(&g, box);
    if (!coord) return -1;
    prune_plan *pl = prune ? prune_plan_new(p) : NULL;
    g.pl = pl;
    g.ntx = (n + PRUNE_TILE - 1) / PRUNE_TILE;
    g.nsx = (g.ntx + PRUNE_SUPER - 1) / PRUNE_SUPER;
    long slab_tiles = g.ntx * g.ntx, slab_supers = g.nsx * g.nsx;
    long nslabs = (k1 - k0 + nk - 1) / nk;
    long run_slabs = PRUNE_RUN_TILES / slab_tiles;
    if (run_slabs < 1) run_slabs = 1;
    if (run_slabs > nslabs) run_slabs = nslabs;
    g.terr = frep_calloc((size_t)(run_slabs * slab_tiles), sizeof *g.terr);
    g.tst = stats ? frep_malloc((size_t)(run_slabs * slab_tiles) * sizeof *g.tst) : NULL;
    double cost = 0;
    vm_errstate all;
    memset(&all, 0, sizeof all);
    int rc = !g.terr || (stats && !g.tst) ? -1 : 0;
    for (long s0 = 0; s0 < nslabs && rc == 0; s0 += run_slabs) {
        long s1 = s0 + run_slabs < nslabs ? s0 + run_slabs : nslabs;
        long ntiles = (s1 - s0) * slab_tiles;
        g.tbase = s0 * slab_tiles;
        rc = grid_run(&g, s0 * slab_supers, s1 * slab_supers, nthreads, &cost, &used);
        for (long t = 0; t < ntiles; t++) vm_err_merge(&all, &g.terr[t]);
        if (stats && rc == 0) grid_add_stats(stats, g.tst, ntiles);
    }
    frep_free(g.terr);
    frep_free(g.tst);
    frep_free(coord);
    prune_plan_free(pl);
    if (rc < 0) return -1;
    if (err) vm_err_to_public(&all, err);
    if (insns) *insns += cost;
    if (threads_used) *threads_used = used;
    return 0;
}

int prune_eval_grid_summary(const frep_program *p, long n, const double box[6], long k0,
                            long nk, int prune, int nthreads, double *f,
                            prune_grid_stats *stats, frep_runtime_error *err, double *insns)
{
    return grid_eval(p, n, box, k0, k0 + nk, nk, prune, nthreads, 0, 0, f, stats, err, insns,
                     NULL);
}

int prune_eval_grid_whole(const frep_program *p, long n, const double box[6], int prune,
                          int nthreads, prune_grid_stats *stats, frep_runtime_error *err,
                          double *insns, int *threads_used)
{
    return prune_eval_grid_flags(p, n, box, prune, nthreads, 0, stats, err, insns,
                                 threads_used);
}

int prune_eval_grid_flags(const frep_program *p, long n, const double box[6], int prune,
                          int nthreads, unsigned flags, prune_grid_stats *stats,
                          frep_runtime_error *err, double *insns, int *threads_used)
{
    return grid_eval(p, n, box, 0, n, PRUNE_TILE, prune, nthreads, 1,
                     (flags & PRUNE_GRID_SINGLE) != 0, NULL, stats, err, insns, threads_used);
}

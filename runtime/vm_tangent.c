/* vm_tangent.c - forward-mode automatic differentiation over a block of points.
 *
 * Runs the same bytecode as vm.c but every stack entry carries a value vector and T
 * tangent vectors: T = 3 for the gradient (seeds d/dx, d/dy, d/dz) or T = nparams for
 * the derivatives with respect to the free parameters (used by fit/).  The derivative
 * rules, including the defined values at kinks, are op_partials() of opsem.h; a NULL
 * tangent means "identically zero" and lets constant subtrees skip all tangent work.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "opsem.h"
#include "vm_internal.h"

/* Op flags and arities, as a local table so the dispatch loop needs no calls. */
static const unsigned char tan_flags[FREP_OP__COUNT] = {
#define FREP_OP_TF(name, id, nin, flags, meaning) [id] = (unsigned char)(flags),
    FREP_OPS(FREP_OP_TF)
#undef FREP_OP_TF
};
static const unsigned char tan_nin[FREP_OP__COUNT] = {
#define FREP_OP_TN(name, id, nin, flags, meaning) [id] = nin,
    FREP_OPS(FREP_OP_TN)
#undef FREP_OP_TN
};

/* Buffers are grouped in "sets": a value vector followed by T tangent vectors. */
struct vm_tanstate {
    uint32_t T;
    uint32_t cap_stack, cap_slots;
    double **lvset;          /* 2 sets per stack level (as vm.c's lv) */
    double **slotset;        /* one owned set per slot */
    const double **ev;       /* entry value, per level */
    const double **et;       /* entry tangents, et[L*T + t]; NULL = zero */
    int *eset;               /* set the entry occupies: 0/1 (level's own) or -1 */
    const double **sv;       /* slot value: slotset[s] or zeros */
    const double **st;       /* slot tangents st[s*T + t]; NULL = zero */
    double *pa, *pb;         /* partial derivatives of the current op */
    double *ones;            /* seed vector */
};

static size_t set_doubles(uint32_t T) { return (size_t)(T + 1) * FREP_BLOCK; }

void vm_tan_free(vm_tanstate *t)
{
    uint32_t i;
    if (!t) return;
    for (i = 0; i < 2 * t->cap_stack; i++) frep_aligned_free(t->lvset[i]);
    for (i = 0; i < t->cap_slots; i++) frep_aligned_free(t->slotset[i]);
    frep_free(t->lvset);
    frep_free(t->slotset);
    frep_free(t->ev);
    frep_free(t->et);
    frep_free(t->eset);
    frep_free(t->sv);
    frep_free(t->st);
    frep_aligned_free(t->pa);
    frep_aligned_free(t->pb);
    frep_aligned_free(t->ones);
    frep_free(t);
}

static double *new_set(uint32_t T)
{
    double *b = frep_aligned_alloc(64, set_doubles(T) * sizeof(double));
    if (b) memset(b, 0, set_doubles(T) * sizeof(double));
    return b;
}

/* Make the tangent state fit p with T tangents (rebuilt when T changes). */
static int tan_fit(vm_scratch *s, const frep_program *p, uint32_t T, vm_tanstate **slot)
{
    vm_tanstate *t = *slot;
    uint32_t i, ns = p->max_stack, nsl = p->nslots;
    if (t && t->T == T && t->cap_stack >= ns && t->cap_slots >= nsl) return 0;
    if (t && t->T == T) {
        if (ns < t->cap_stack) ns = t->cap_stack;
        if (nsl < t->cap_slots) nsl = t->cap_slots;
    }
    vm_tan_free(t);
    *slot = t = frep_calloc(1, sizeof *t);
    if (!t) return -1;
    t->T = T;
    if (ns == 0) ns = 1;
    t->lvset = frep_calloc(2 * (size_t)ns, sizeof *t->lvset);
    t->slotset = frep_calloc(nsl ? nsl : 1, sizeof *t->slotset);
    t->ev = frep_calloc(ns, sizeof *t->ev);
    t->et = frep_calloc((size_t)ns * (T ? T : 1), sizeof *t->et);
    t->eset = frep_calloc(ns, sizeof *t->eset);
    t->sv = frep_calloc(nsl ? nsl : 1, sizeof *t->sv);
    t->st = frep_calloc((size_t)(nsl ? nsl : 1) * (T ? T : 1), sizeof *t->st);
    t->pa = frep_aligned_alloc(64, FREP_BLOCK * sizeof(double));
    t->pb = frep_aligned_alloc(64, FREP_BLOCK * sizeof(double));
    t->ones = frep_aligned_alloc(64, FREP_BLOCK * sizeof(double));
    if (!t->lvset || !t->slotset || !t->ev || !t->et || !t->eset || !t->sv || !t->st ||
        !t->pa || !t->pb || !t->ones)
        goto fail;
    t->cap_stack = ns;
    for (i = 0; i < 2 * ns; i++)
        if (!(t->lvset[i] = new_set(T))) goto fail;
    t->cap_slots = nsl;
    for (i = 0; i < nsl; i++)
        if (!(t->slotset[i] = new_set(T))) goto fail;
    for (i = 0; i < FREP_BLOCK; i++) t->ones[i] = 1.0;
    return 0;
fail:
    vm_tan_free(t);
    *slot = NULL;
    return -1;
}

static inline double *set_val(double *set) { return set; }
static inline double *set_tan(double *set, uint32_t t)
{
    return set + (size_t)(t + 1) * FREP_BLOCK;
}

/* The free set of level L: the one entry L does not occupy. */
static inline int free_set(const vm_tanstate *t, uint32_t L)
{
    return t->eset[L] == 0 ? 1 : 0;
}

/* Inlined into tan_run so that they are compiled for its target clones. */
#if defined(__GNUC__)
#define TAN_INLINE static inline __attribute__((always_inline))
#else
#define TAN_INLINE static inline
#endif

/* r = pa*ta + pb*tb with vector partials (NULL tangents are zero). */
TAN_INLINE void combine_vv(double *restrict r, const double *restrict pa, const double *ta,
                       const double *restrict pb, const double *tb, size_t n)
{
    size_t i;
    if (ta && tb)
        for (i = 0; i < n; i++) r[i] = pa[i] * ta[i] + pb[i] * tb[i];
    else if (ta)
        for (i = 0; i < n; i++) r[i] = pa[i] * ta[i];
    else
        for (i = 0; i < n; i++) r[i] = pb[i] * tb[i];
}

/* r = ka*ta + kb*tb with constant partials. */
TAN_INLINE void combine_ss(double *restrict r, double ka, const double *ta, double kb,
                       const double *tb, size_t n)
{
    size_t i;
    if (ta && tb) {
        if (ka == 1 && kb == 1)
            for (i = 0; i < n; i++) r[i] = ta[i] + tb[i];
        else if (ka == 1 && kb == -1)
            for (i = 0; i < n; i++) r[i] = ta[i] - tb[i];
        else
            for (i = 0; i < n; i++) r[i] = ka * ta[i] + kb * tb[i];
    } else if (ta) {
        for (i = 0; i < n; i++) r[i] = ka * ta[i];
    } else {
        for (i = 0; i < n; i++) r[i] = kb * tb[i];
    }
}

/* Copy entry j into a set of its own level (it pointed at a slot about to change). */
static void tan_unalias_slot(vm_tanstate *t, uint32_t slot, uint32_t depth, size_t n)
{
    uint32_t j, k;
    const double *b = set_val(t->slotset[slot]);
    if (t->sv[slot] != b) return;
    for (j = 0; j < depth; j++) {
        if (t->ev[j] == b) {
            double *set = t->lvset[2 * j];
            memcpy(set_val(set), b, n * sizeof(double));
            t->ev[j] = set_val(set);
            for (k = 0; k < t->T; k++) {
                const double *tk = t->et[(size_t)j * t->T + k];
                if (tk) {
                    memcpy(set_tan(set, k), tk, n * sizeof(double));
                    t->et[(size_t)j * t->T + k] = set_tan(set, k);
                }
            }
            t->eset[j] = 0;
        }
    }
}

static void tan_materialize_slot(vm_tanstate *t, const double *zeros, uint32_t slot, size_t n)
{
    if (t->sv[slot] != set_val(t->slotset[slot])) {
        memset(set_val(t->slotset[slot]), 0, n * sizeof(double));
        t->sv[slot] = set_val(t->slotset[slot]);
    }
    (void)zeros;
}

static void tan_record(vm_scratch *s, const vm_inputs *in, uint32_t pc, frep_opcode op,
                       const double *A, double ka, const double *B, double kb, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        double a = A ? A[i] : ka, b = B ? B[i] : kb;
        if (opsem_is_bad(op, a, b)) vm_err_lane(s, pc, i, in);
    }
}

/* Value and partials of a unary op, with its constant opcode folded into the loop.
 * (A variant fusing the 3-tangent chain rule into this loop measured 1.5-2x slower
 * with GCC 12: too many streams per loop; the separate passes below vectorize well.) */
#define TAN_UNARY(NAME)                                                            \
    case FREP_OP_##NAME:                                                           \
        for (i = 0; i < n; i++) {                                                  \
            double a = A[i], r = op_scalar(FREP_OP_##NAME, a, 0, 0, 0, NULL), dd[3]; \
            op_partials(FREP_OP_##NAME, a, 0, 0, 0, r, dd);                        \
            R[i] = r;                                                              \
            PA[i] = dd[0];                                                         \
        }                                                                          \
        break;

#define TAN_BINARY_LOOP(NAME, AV, BV)                                             \
    for (i = 0; i < n; i++) {                                                      \
        double a = (AV), b = (BV), dd[3];                                          \
        double r = op_scalar(FREP_OP_##NAME, a, b, 0, k, NULL);                    \
        op_partials(FREP_OP_##NAME, a, b, 0, k, r, dd);                            \
        R[i] = r;                                                                  \
        PA[i] = dd[0];                                                             \
        PB[i] = dd[1];                                                             \
    }

/* Binary: separate loops for stack operands and immediates, so each vectorizes. */
#define TAN_BINARY(NAME)                                                           \
    case FREP_OP_##NAME:                                                           \
        if (A && B) {                                                              \
            TAN_BINARY_LOOP(NAME, A[i], B[i])                                      \
        } else if (A) {                                                            \
            TAN_BINARY_LOOP(NAME, A[i], kb)                                        \
        } else {                                                                   \
            TAN_BINARY_LOOP(NAME, ka, B[i])                                        \
        }                                                                          \
        break;

/* Run over lanes 0..n-1; return codes as vm.c's vm_run. */
static int tan_run(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                   vm_seed seed, double *out, double *dout, size_t dstride, int may_diverge)
    VM_CLONES;
static int tan_run(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                   vm_seed seed, double *out, double *dout, size_t dstride, int may_diverge)
{
    vm_tanstate *t = s->tan[seed == VM_SEED_XYZ ? 0 : 1];
    const uint32_t T = t->T;
    const frep_insn *code = p->code;
    uint32_t pc = 0, d = 0, j, c;
    long loops = 0;
    size_t i;

    s->cur = p;
    vm_err_begin(s, n);
    for (j = 0; j < p->nslots; j++) {
        t->sv[j] = s->zeros;
        for (c = 0; c < T; c++) t->st[(size_t)j * T + c] = NULL;
    }

    while (pc < p->ncode) {
        const frep_insn *in_ = &code[pc];
        frep_opcode op = (frep_opcode)in_->op;
        unsigned fl = op < FREP_OP__COUNT ? tan_flags[op] : 0;
        const double **et_d = t->et + (size_t)d * T;
        switch ((unsigned)op) { /* not an enum switch: operators are handled below */
        case FREP_OP_CONST: {
            double *set = t->lvset[2 * d + (uint32_t)free_set(t, d)];
            double *R = set_val(set);
            int w = free_set(t, d);
            for (i = 0; i < n; i++) R[i] = in_->k;
            t->ev[d] = R;
            t->eset[d] = w;
            for (c = 0; c < T; c++) et_d[c] = NULL;
            d++;
            pc++;
            continue;
        }
        case FREP_OP_X:
            t->ev[d] = in_->arg == 0 ? in->x : in_->arg == 1 ? in->y : in->z;
            t->eset[d] = -1;
            for (c = 0; c < T; c++)
                et_d[c] = seed == VM_SEED_XYZ && c == in_->arg ? t->ones : NULL;
            d++;
            pc++;
            continue;
        case FREP_OP_PARAM:
            t->ev[d] = s->parambuf + (size_t)in_->arg * FREP_BLOCK;
            t->eset[d] = -1;
            for (c = 0; c < T; c++)
                et_d[c] = seed == VM_SEED_PARAMS && c == in_->arg ? t->ones : NULL;
            d++;
            pc++;
            continue;
        case FREP_OP_LOAD:
            t->ev[d] = t->sv[in_->arg];
            t->eset[d] = -1;
            for (c = 0; c < T; c++) et_d[c] = t->st[(size_t)in_->arg * T + c];
            d++;
            pc++;
            continue;
        case FREP_OP_PRIM:
            t->ev[d] = in->prim_v[in_->arg];
            t->eset[d] = -1;
            for (c = 0; c < T; c++)
                et_d[c] = seed == VM_SEED_XYZ ? in->prim_g[3 * in_->arg + c] : NULL;
            d++;
            pc++;
            continue;
        case FREP_OP_STORE: {
            uint32_t slot = in_->arg;
            const double **src;
            d--;
            src = t->et + (size_t)d * T;
            if (t->ev[d] == t->sv[slot]) { pc++; continue; }
            tan_unalias_slot(t, slot, d, n);
            if (t->eset[d] >= 0) {
                /* Trade the level's set for the slot's: no copy. */
                uint32_t w = 2 * d + (uint32_t)t->eset[d];
                double *tmp = t->slotset[slot];
                t->slotset[slot] = t->lvset[w];
                t->lvset[w] = tmp;
                t->eset[d] = -1;
                t->sv[slot] = t->ev[d];
                for (c = 0; c < T; c++) t->st[(size_t)slot * T + c] = src[c];
            } else {
                double *set = t->slotset[slot];
                memcpy(set_val(set), t->ev[d], n * sizeof(double));
                t->sv[slot] = set_val(set);
                for (c = 0; c < T; c++) {
                    if (src[c]) {
                        memcpy(set_tan(set, c), src[c], n * sizeof(double));
                        t->st[(size_t)slot * T + c] = set_tan(set, c);
                    } else {
                        t->st[(size_t)slot * T + c] = NULL;
                    }
                }
            }
            pc++;
            continue;
        }
        case FREP_OP_JMP:
            if (in_->arg <= pc && ++loops > FREP_MAX_LOOP_ITERATIONS) {
                for (i = 0; i < n; i++) {
                    out[i] = NAN;
                    for (c = 0; c < T; c++) dout[c * dstride + i] = NAN;
                    vm_err_lane(s, pc, i, in);
                }
                vm_err_commit(s, n);
                return 0;
            }
            pc = in_->arg;
            continue;
        case FREP_OP_JZ: {
            const double *C = t->ev[--d];
            size_t zeros = 0;
            for (i = 0; i < n; i++) zeros += C[i] == 0;
            if (zeros == n) { pc = in_->arg; continue; }
            if (zeros != 0) return may_diverge ? 1 : -1;
            pc++;
            continue;
        }
        case FREP_OP_LOADI: {
            const double *I = t->ev[d - 1];
            int w = free_set(t, d - 1);
            double *set = t->lvset[2 * (d - 1) + (uint32_t)w];
            const double k = in_->k;
            const uint32_t kk = (uint32_t)k;
            const double **eo = t->et + (size_t)(d - 1) * T;
            double *R = set_val(set);
            for (c = 0; c < T; c++) {
                /* A tangent is nonzero when any element of the array has one. */
                const double *any = NULL;
                for (j = 0; j < kk && !any; j++) any = t->st[(size_t)(in_->arg + j) * T + c];
                eo[c] = any ? set_tan(set, c) : NULL;
            }
            for (i = 0; i < n; i++) {
                double ix = I[i];
                if (opsem_bad_index(ix, k)) {
                    R[i] = NAN;
                    for (c = 0; c < T; c++)
                        if (eo[c]) set_tan(set, c)[i] = NAN;
                    if (!(in_->flags & INSN_QUIET)) vm_err_lane(s, pc, i, in);
                } else {
                    uint32_t slot = in_->arg + (uint32_t)ix - 1;
                    R[i] = t->sv[slot][i];
                    for (c = 0; c < T; c++) {
                        if (eo[c]) {
                            const double *st = t->st[(size_t)slot * T + c];
                            set_tan(set, c)[i] = st ? st[i] : 0.0;
                        }
                    }
                }
            }
            t->ev[d - 1] = R;
            t->eset[d - 1] = w;
            pc++;
            continue;
        }
        case FREP_OP_STOREI: {
            const double *I = t->ev[d - 1];
            const double *V = t->ev[d - 2];
            const double **vt = t->et + (size_t)(d - 2) * T;
            const double k = in_->k;
            const uint32_t kk = (uint32_t)k;
            d -= 2;
            for (j = 0; j < kk; j++) {
                uint32_t slot = in_->arg + j;
                tan_unalias_slot(t, slot, d, n);
                tan_materialize_slot(t, s->zeros, slot, n);
                for (c = 0; c < T; c++) {
                    /* A slot whose tangent becomes nonzero gets zeroed storage. */
                    if (vt[c] && !t->st[(size_t)slot * T + c]) {
                        double *b = set_tan(t->slotset[slot], c);
                        memset(b, 0, n * sizeof(double));
                        t->st[(size_t)slot * T + c] = b;
                    }
                }
            }
            for (i = 0; i < n; i++) {
                double ix = I[i];
                if (opsem_bad_index(ix, k)) {
                    if (!(in_->flags & INSN_QUIET)) vm_err_lane(s, pc, i, in);
                } else {
                    uint32_t slot = in_->arg + (uint32_t)ix - 1;
                    double *sb = set_val(t->slotset[slot]);
                    sb[i] = V[i];
                    for (c = 0; c < T; c++) {
                        double *st = (double *)(uintptr_t)t->st[(size_t)slot * T + c];
                        if (st) st[i] = vt[c] ? vt[c][i] : 0.0;
                    }
                }
            }
            pc++;
            continue;
        }
        case FREP_OP_SELECT: {
            const double *C = t->ev[d - 3], *A = t->ev[d - 2], *B = t->ev[d - 1];
            const double **ta = t->et + (size_t)(d - 2) * T, **tb = t->et + (size_t)(d - 1) * T;
            const double **eo = t->et + (size_t)(d - 3) * T;
            int w = free_set(t, d - 3);
            double *set = t->lvset[2 * (d - 3) + (uint32_t)w];
            double *R = set_val(set);
            for (i = 0; i < n; i++) R[i] = opsem_select(C[i], A[i], B[i]);
            for (c = 0; c < T; c++) {
                const double *xa = ta[c], *xb = tb[c];
                if (!xa && !xb) { eo[c] = NULL; continue; }
                if (!xa) xa = s->zeros;
                if (!xb) xb = s->zeros;
                {
                    double *r = set_tan(set, c);
                    for (i = 0; i < n; i++) r[i] = C[i] != 0 ? xa[i] : xb[i];
                    eo[c] = r;
                }
            }
            t->ev[d - 3] = R;
            t->eset[d - 3] = w;
            d -= 2;
            pc++;
            continue;
        }
        case FREP_OP__COUNT:
            return -1;
        default:
            break;
        }

        /* Unary and binary operators. */
        {
            int binary = tan_nin[op] == 2;
            int nin = binary && (in_->flags & (INSN_KA | INSN_KB)) ? 1 : tan_nin[op];
            uint32_t L = d - (uint32_t)nin; /* result level */
            const double *A = NULL, *B = NULL, **ta = NULL, **tb = NULL;
            double ka = in_->k, kb = in_->k, k = in_->k;
            int w = free_set(t, L);
            double *set = t->lvset[2 * L + (uint32_t)w];
            double *R = set_val(set), *PA = t->pa, *PB = t->pb;
            const double **eo;
            int constpart = 0;
            double ca = 0, cb = 0;

            if (!binary) {
                A = t->ev[d - 1];
                ta = t->et + (size_t)(d - 1) * T;
            } else if (in_->flags & INSN_KB) {
                A = t->ev[d - 1];
                ta = t->et + (size_t)(d - 1) * T;
            } else if (in_->flags & INSN_KA) {
                B = t->ev[d - 1];
                tb = t->et + (size_t)(d - 1) * T;
            } else {
                A = t->ev[d - 2];
                B = t->ev[d - 1];
                ta = t->et + (size_t)(d - 2) * T;
                tb = t->et + (size_t)(d - 1) * T;
            }
            if ((fl & OPF_DOMAIN) && !(in_->flags & INSN_QUIET))
                tan_record(s, in, pc, op, A, ka, B, kb, n);
            switch (op) {
            /* Cheap ops: value loop plus constant or operand-vector partials. */
            case FREP_OP_ADD: case FREP_OP_SUB: case FREP_OP_MUL: {
                if (A && B) {
                    if (op == FREP_OP_ADD) for (i = 0; i < n; i++) R[i] = A[i] + B[i];
                    else if (op == FREP_OP_SUB) for (i = 0; i < n; i++) R[i] = A[i] - B[i];
                    else for (i = 0; i < n; i++) R[i] = A[i] * B[i];
                } else if (A) {
                    if (op == FREP_OP_ADD) for (i = 0; i < n; i++) R[i] = A[i] + kb;
                    else if (op == FREP_OP_SUB) for (i = 0; i < n; i++) R[i] = A[i] - kb;
                    else for (i = 0; i < n; i++) R[i] = A[i] * kb;
                } else {
                    if (op == FREP_OP_ADD) for (i = 0; i < n; i++) R[i] = ka + B[i];
                    else if (op == FREP_OP_SUB) for (i = 0; i < n; i++) R[i] = ka - B[i];
                    else for (i = 0; i < n; i++) R[i] = ka * B[i];
                }
                if (op == FREP_OP_MUL) {
                    if (A && B) { PA = (double *)(uintptr_t)B; PB = (double *)(uintptr_t)A; }
                    else { constpart = 1; ca = A ? kb : 0; cb = B ? ka : 0; }
                } else {
                    constpart = 1;
                    ca = 1;
                    cb = op == FREP_OP_SUB ? -1 : 1;
                }
                break;
            }
            case FREP_OP_NEG:
                for (i = 0; i < n; i++) R[i] = -A[i];
                constpart = 1;
                ca = -1;
                break;
            TAN_UNARY(NOT) TAN_UNARY(ABS) TAN_UNARY(SQRT) TAN_UNARY(SQUARE)
            TAN_UNARY(EXP) TAN_UNARY(LOG) TAN_UNARY(LOGD)
            case FREP_OP_SIN: case FREP_OP_COS: {
                /* value and derivative from one vectorized opsem_sincos_fast, libm
                 * for the lanes outside its range: the bits of op_scalar and
                 * op_partials */
                int slow = 0, is_sin = op == FREP_OP_SIN;
                for (i = 0; i < n; i++) {
                    double sv, cv;
                    opsem_sincos_fast(A[i], &sv, &cv);
                    R[i] = is_sin ? sv : cv;
                    PA[i] = is_sin ? cv : -sv;
                    slow |= opsem_trig_slow(A[i]);
                }
                if (slow)
                    for (i = 0; i < n; i++) {
                        if (!opsem_trig_slow(A[i])) continue;
                        R[i] = is_sin ? opsem_sin(A[i]) : opsem_cos(A[i]);
                        PA[i] = is_sin ? opsem_cos(A[i]) : -opsem_sin(A[i]);
                    }
                break;
            }
            TAN_UNARY(TAN) TAN_UNARY(ASIN) TAN_UNARY(ACOS) TAN_UNARY(ATAN)
            TAN_UNARY(SINH) TAN_UNARY(COSH) TAN_UNARY(TANH) TAN_UNARY(SIGN)
            TAN_UNARY(CEIL) TAN_UNARY(FLOOR) TAN_UNARY(INT) TAN_UNARY(FRAC)
            TAN_BINARY(DIV) TAN_BINARY(POW) TAN_BINARY(MOD) TAN_BINARY(MIN)
            TAN_BINARY(MAX) TAN_BINARY(ATAN2) TAN_BINARY(EQ) TAN_BINARY(NE)
            TAN_BINARY(LT) TAN_BINARY(LE) TAN_BINARY(GT) TAN_BINARY(GE)
            TAN_BINARY(AND) TAN_BINARY(OR) TAN_BINARY(RUNI) TAN_BINARY(RINT)
            TAN_BINARY(RSUB) TAN_BINARY(MSUB) TAN_BINARY(AUNI) TAN_BINARY(AINT)
            case FREP_OP_CONST: case FREP_OP_X: case FREP_OP_PARAM: case FREP_OP_LOAD:
            case FREP_OP_PRIM: case FREP_OP_STORE: case FREP_OP_JMP: case FREP_OP_JZ:
            case FREP_OP_LOADI: case FREP_OP_STOREI: case FREP_OP_SELECT:
            case FREP_OP__COUNT:
                return -1;
            }

            /* Tangents by the chain rule; NOGRAD ops and constant operands give NULL. */
            eo = t->et + (size_t)L * T;
            for (c = 0; c < T; c++) {
                const double *xa = ta ? ta[c] : NULL, *xb = tb ? tb[c] : NULL;
                if ((fl & OPF_NOGRAD) || (!xa && !xb)) { eo[c] = NULL; continue; }
                if (constpart) {
                    if ((!xa || ca == 0) && (!xb || cb == 0)) { eo[c] = NULL; continue; }
                    combine_ss(set_tan(set, c), ca, ca != 0 ? xa : NULL, cb,
                               cb != 0 ? xb : NULL, n);
                } else {
                    combine_vv(set_tan(set, c), PA, xa, PB, xb, n);
                }
                eo[c] = set_tan(set, c);
            }
            t->ev[L] = R;
            t->eset[L] = w;
            d = L + 1;
            pc++;
        }
    }
    if (d != 1) return -1;
    memcpy(out, t->ev[0], n * sizeof *out);
    for (c = 0; c < T; c++) {
        const double *tc = t->et[c];
        if (tc) memcpy(dout + c * dstride, tc, n * sizeof(double));
        else memset(dout + c * dstride, 0, n * sizeof(double));
    }
    vm_err_commit(s, n);
    return 0;
}

/* Parameters broadcast over the lanes (as vm.c does). */
static void tan_broadcast_params(const frep_program *p, vm_scratch *s, const vm_inputs *in,
                                 size_t n)
{
    vm_broadcast_params(p, s, in, n);
}

int vm_eval_block_tangent(const frep_program *p, vm_scratch *s, const vm_inputs *in,
                          size_t n, vm_seed seed, double *out, double *dout)
{
    uint32_t T = seed == VM_SEED_XYZ ? 3u : p->nparams;
    int rc;
    size_t i;
    if (n == 0) return 0;
    if (n > FREP_BLOCK || vm_scratch_fit(s, p) < 0 ||
        tan_fit(s, p, T, &s->tan[seed == VM_SEED_XYZ ? 0 : 1]) < 0)
        return -1;
    if ((p->flags & PROG_HAS_PRIMS) &&
        (!in->prim_v || (seed == VM_SEED_XYZ && !in->prim_g)))
        return -1;
    tan_broadcast_params(p, s, in, n);
    rc = tan_run(p, s, in, n, seed, out, dout, n, n > 1);
    if (rc != 1) return rc;
    /* Divergent branches: one lane at a time (see vm.c). */
    for (i = 0; i < n; i++) {
        vm_inputs li = *in;
        uint32_t j;
        li.x = in->x + i;
        li.y = in->y + i;
        li.z = in->z + i;
        if (p->nprims) {
            for (j = 0; j < p->nprims; j++) s->primp[j] = in->prim_v[j] + i;
            li.prim_v = s->primp;
            if (in->prim_g) {
                for (j = 0; j < 3 * p->nprims; j++) s->primg[j] = in->prim_g[j] + i;
                li.prim_g = s->primg;
            }
        }
        if (tan_run(p, s, &li, 1, seed, out + i, dout + i, n, 0) < 0) return -1;
    }
    return 0;
}

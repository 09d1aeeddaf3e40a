/* vm_tangent.c - forward-mode automatic differentiation over a block of points.
 *
 * Runs the same bytecode as vm.c but every stack entry carries a value vector and T
 * tangent vectors: T = 3 for the gradient (seeds d/dx, d/dy, d/dz) or T = nparams for
 * the derivatives with respect to the free parameters (used by fit/).  The derivative
 * rules, including the defined values at kinks, are op_partials() of opsem.h; a NULL
 * tangent means "identically zero" and lets constant subtrees skip all tangent work.
 * tan_run is laid out like vm.c's vm_run, and shares its jumps (vm_internal.h).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "opsem.h"
#include "vm_internal.h"

/* Op flags and arities from the opcode table: each operator case indexes them with
 * its constant opcode, so they fold to constants (op_flags() would be a call). */
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

/* r = pa*ta + pb*tb with vector partials (NULL tangents are zero); inlined into
 * tan_chain so that it is compiled for its target clones. */
OPSEM_INLINE void combine_vv(double *restrict r, const double *restrict pa, const double *ta,
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
OPSEM_INLINE void combine_ss(double *restrict r, double ka, const double *ta, double kb,
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

/* ---- leaves, slots and arrays ------------------------------------------------------ */

/* No tangent: the seed index of a leaf that is not a seed. */
#define TAN_NONE UINT32_MAX

/* Push the constant k: a value in the level's free set, zero tangents. */
static inline void tan_push_const(vm_tanstate *t, uint32_t L, double k, size_t n)
{
    int w = free_set(t, L);
    double *R = set_val(t->lvset[2 * L + (uint32_t)w]);
    size_t i;
    uint32_t c;
    for (i = 0; i < n; i++) R[i] = k;
    t->ev[L] = R;
    t->eset[L] = w;
    for (c = 0; c < t->T; c++) t->et[(size_t)L * t->T + c] = NULL;
}

/* Push an input vector v (not copied) whose only nonzero tangent is the seed
 * `seeded` (d v / d v = 1; TAN_NONE: v is constant for these tangents). */
static inline void tan_push_seed(vm_tanstate *t, uint32_t L, const double *v, uint32_t seeded)
{
    uint32_t c;
    t->ev[L] = v;
    t->eset[L] = -1;
    for (c = 0; c < t->T; c++) t->et[(size_t)L * t->T + c] = c == seeded ? t->ones : NULL;
}

/* Push a vector v with tangents tans[0..T-1] (neither copied; tans NULL: all zero). */
static inline void tan_push_ref(vm_tanstate *t, uint32_t L, const double *v,
                                const double *const *tans)
{
    uint32_t c;
    t->ev[L] = v;
    t->eset[L] = -1;
    for (c = 0; c < t->T; c++) t->et[(size_t)L * t->T + c] = tans ? tans[c] : NULL;
}

/* Before slot `slot` is overwritten: any stack entry below `depth` still pointing at
 * its set (a live LOAD) gets a copy in a set of its own level, values and tangents. */
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

/* Make slot `slot` own writable storage holding its current value (0 if unwritten). */
static void tan_materialize_slot(vm_tanstate *t, uint32_t slot, size_t n)
{
    if (t->sv[slot] != set_val(t->slotset[slot])) {
        memset(set_val(t->slotset[slot]), 0, n * sizeof(double));
        t->sv[slot] = set_val(t->slotset[slot]);
    }
}

/* STORE: pop level L into slot `slot`, trading sets when L owns its value. */
static void tan_store(vm_tanstate *t, uint32_t slot, uint32_t L, size_t n)
{
    const uint32_t T = t->T;
    const double **src = t->et + (size_t)L * T;
    uint32_t c;
    if (t->ev[L] == t->sv[slot]) return; /* LOAD s; STORE s */
    tan_unalias_slot(t, slot, L, n);
    if (t->eset[L] >= 0) {
        /* The value is in a set of the level: trade it for the slot's, no copy. */
        uint32_t w = 2 * L + (uint32_t)t->eset[L];
        double *tmp = t->slotset[slot];
        t->slotset[slot] = t->lvset[w];
        t->lvset[w] = tmp;
        t->eset[L] = -1;
        t->sv[slot] = t->ev[L];
        for (c = 0; c < T; c++) t->st[(size_t)slot * T + c] = src[c];
    } else {
        double *set = t->slotset[slot];
        memcpy(set_val(set), t->ev[L], n * sizeof(double));
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
}

/* LOADI: replace the index at level L by element arg+i-1 of the array (NaN and an
 * error for an index out of range). */
static void tan_loadi(vm_scratch *s, vm_tanstate *t, const vm_inputs *in,
                      const frep_insn *in_, uint32_t pc, uint32_t L, size_t n)
{
    const uint32_t T = t->T;
    const double *I = t->ev[L];
    int w = free_set(t, L);
    double *set = t->lvset[2 * L + (uint32_t)w];
    const double k = in_->k;
    const uint32_t kk = (uint32_t)k;
    const double **eo = t->et + (size_t)L * T;
    double *R = set_val(set);
    uint32_t c, j;
    size_t i;
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
    t->ev[L] = R;
    t->eset[L] = w;
}

/* STOREI: store the value at level L into element arg+i-1, i the index at L+1 (both
 * popped); an index out of range makes the lane's result NaN, as vm.c.  Each lane reads its value and index before it writes its own lane of one
 * slot, so only older stack entries need unaliasing (as vm.c). */
static void tan_storei(vm_scratch *s, vm_tanstate *t, const vm_inputs *in,
                       const frep_insn *in_, uint32_t pc, uint32_t L, size_t n)
{
    const uint32_t T = t->T;
    const double *I = t->ev[L + 1];
    const double *V = t->ev[L];
    const double **vt = t->et + (size_t)L * T;
    const double k = in_->k;
    const uint32_t kk = (uint32_t)k;
    uint32_t c, j;
    size_t i;
    for (j = 0; j < kk; j++) {
        uint32_t slot = in_->arg + j;
        tan_unalias_slot(t, slot, L, n);
        tan_materialize_slot(t, slot, n);
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
            if (!(in_->flags & INSN_QUIET)) vm_err_lane_nan(s, pc, i, in);
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
}

/* SELECT c, a, b at levels L..L+2 into level L: value and tangents of the chosen
 * branch, lane by lane. */
static void tan_select(const vm_scratch *s, vm_tanstate *t, uint32_t L, size_t n)
{
    const uint32_t T = t->T;
    const double *C = t->ev[L], *A = t->ev[L + 1], *B = t->ev[L + 2];
    const double **ta = t->et + (size_t)(L + 1) * T, **tb = t->et + (size_t)(L + 2) * T;
    const double **eo = t->et + (size_t)L * T;
    int w = free_set(t, L);
    double *set = t->lvset[2 * L + (uint32_t)w];
    double *R = set_val(set);
    uint32_t c;
    size_t i;
    for (i = 0; i < n; i++) R[i] = opsem_select(C[i], A[i], B[i]);
    for (c = 0; c < T; c++) {
        const double *xa = ta[c], *xb = tb[c];
        double *r;
        if (!xa && !xb) { eo[c] = NULL; continue; }
        if (!xa) xa = s->zeros;
        if (!xb) xb = s->zeros;
        r = set_tan(set, c);
        for (i = 0; i < n; i++) r[i] = C[i] != 0 ? xa[i] : xb[i];
        eo[c] = r;
    }
    t->ev[L] = R;
    t->eset[L] = w;
}

/* ---- operators ------------------------------------------------------------------
 * An operator instruction (unary, binary, binary with an immediate) runs in three
 * steps: tan_operands finds the operands and the result set and records domain
 * errors; the op's own loop computes the value R and the partials (per lane into
 * t->pa/t->pb, or the constants ca/cb); tan_chain applies the chain rule to every
 * tangent. */

typedef struct tan_op {
    const double *A, *B;       /* operand values; NULL: the immediate ka or kb (or none) */
    const double **ta, **tb;   /* their tangents, T each; NULL: all zero */
    double ka, kb;
    uint32_t L;                /* level of the result */
    int w;                     /* which of L's sets receives it (free_set) */
    double *R;                 /* the value vector of that set */
    const double *pa, *pb;     /* partials d r/d a, d r/d b per lane; unless constpart */
    int constpart;             /* the partials are the constants ca, cb */
    double ca, cb;
} tan_op;

OPSEM_INLINE tan_op tan_operands(vm_scratch *s, vm_tanstate *t, const vm_inputs *in,
                                 const frep_insn *in_, uint32_t pc, uint32_t d, size_t n,
                                 frep_opcode op)
{
    const uint32_t T = t->T;
    int binary = tan_nin[op] == 2;
    int nin = binary && (in_->flags & (INSN_KA | INSN_KB)) ? 1 : tan_nin[op];
    tan_op o;
    o.A = o.B = NULL;
    o.ta = o.tb = NULL;
    o.ka = o.kb = in_->k;
    o.L = d - (uint32_t)nin;
    o.w = free_set(t, o.L);
    o.R = set_val(t->lvset[2 * o.L + (uint32_t)o.w]);
    o.pa = t->pa;
    o.pb = t->pb;
    o.constpart = 0;
    o.ca = o.cb = 0;
    if (!binary || (in_->flags & INSN_KB)) {
        o.A = t->ev[d - 1];
        o.ta = t->et + (size_t)(d - 1) * T;
    } else if (in_->flags & INSN_KA) {
        o.B = t->ev[d - 1];
        o.tb = t->et + (size_t)(d - 1) * T;
    } else {
        o.A = t->ev[d - 2];
        o.B = t->ev[d - 1];
        o.ta = t->et + (size_t)(d - 2) * T;
        o.tb = t->et + (size_t)(d - 1) * T;
    }
    if ((tan_flags[op] & OPF_DOMAIN) && !(in_->flags & INSN_QUIET))
        vm_record_errors(s, in, pc, op, o.A, o.ka, o.B, o.kb, n);
    return o;
}

/* The tangents of o's result by the chain rule, and the result pushed; returns the new
 * stack depth.  NOGRAD ops and zero operand tangents give NULL (zero) tangents. */
static uint32_t tan_chain(vm_tanstate *t, const tan_op *o, size_t n, int nograd) VM_CLONES;
static uint32_t tan_chain(vm_tanstate *t, const tan_op *o, size_t n, int nograd)
{
    const uint32_t T = t->T;
    double *set = t->lvset[2 * o->L + (uint32_t)o->w];
    const double **eo = t->et + (size_t)o->L * T;
    uint32_t c;
    for (c = 0; c < T; c++) {
        /* eo may be ta: entry c is read before it is written */
        const double *xa = o->ta ? o->ta[c] : NULL, *xb = o->tb ? o->tb[c] : NULL;
        if (nograd || (!xa && !xb)) { eo[c] = NULL; continue; }
        if (o->constpart) {
            if ((!xa || o->ca == 0) && (!xb || o->cb == 0)) { eo[c] = NULL; continue; }
            combine_ss(set_tan(set, c), o->ca, o->ca != 0 ? xa : NULL, o->cb,
                       o->cb != 0 ? xb : NULL, n);
        } else {
            combine_vv(set_tan(set, c), o->pa, xa, o->pb, xb, n);
        }
        eo[c] = set_tan(set, c);
    }
    t->ev[o->L] = o->R;
    t->eset[o->L] = o->w;
    return o->L + 1;
}

/* sin or cos of A into R with its derivative into PA, from one vectorized
 * opsem_sincos_fast, libm for the lanes outside its range: the bits of op_scalar and
 * op_partials. */
OPSEM_INLINE void tan_sincos(const double *A, double *R, double *PA, size_t n, int is_sin)
{
    size_t i;
    int slow = 0;
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
}

/* Products: vector partials (b, a) when both operands are on the stack, else the
 * immediate as a constant partial. */
static inline void tan_mul_partials(tan_op *o)
{
    if (o->A && o->B) {
        o->pa = o->B;
        o->pb = o->A;
    } else {
        o->constpart = 1;
        o->ca = o->A ? o->kb : 0;
        o->cb = o->B ? o->ka : 0;
    }
}

/* One operator case: operands, then VALUES (computing R and the partials from A, B,
 * ka, kb, k into PA, PB or o), then the chain rule. */
#define TAN_OPERATOR(NAME, ...)                                                    \
    case FREP_OP_##NAME: {                                                         \
        tan_op o = tan_operands(s, t, in, in_, pc, d, n, FREP_OP_##NAME);          \
        const double *A = o.A, *B = o.B;                                           \
        const double ka = o.ka, kb = o.kb, k = in_->k;                             \
        double *R = o.R, *PA = t->pa, *PB = t->pb;                                 \
        size_t i;                                                                  \
        (void)B; (void)ka; (void)kb; (void)k; (void)PA; (void)PB; (void)i;         \
        __VA_ARGS__                                                                \
        d = tan_chain(t, &o, n, (tan_flags[FREP_OP_##NAME] & OPF_NOGRAD) != 0);    \
        break;                                                                     \
    }

/* Value and partial of a unary op, its constant opcode folded into the loop.  (A
 * variant fusing the 3-tangent chain rule into this loop measured 1.5-2x slower with
 * GCC 12: too many streams per loop; the separate passes vectorize well.) */
#define TAN_UNARY_LOOP(NAME)                                                       \
    for (i = 0; i < n; i++) {                                                      \
        double a = A[i], r = op_scalar(FREP_OP_##NAME, a, 0, 0, 0, NULL), dd[3];   \
        op_partials(FREP_OP_##NAME, a, 0, 0, 0, r, dd);                            \
        R[i] = r;                                                                  \
        PA[i] = dd[0];                                                             \
    }

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
#define TAN_BINARY_LOOPS(NAME)                                                     \
    if (A && B) {                                                                  \
        TAN_BINARY_LOOP(NAME, A[i], B[i])                                          \
    } else if (A) {                                                                \
        TAN_BINARY_LOOP(NAME, A[i], kb)                                            \
    } else {                                                                       \
        TAN_BINARY_LOOP(NAME, ka, B[i])                                            \
    }

/* The value alone (for ops whose partials need no per-lane loop). */
#define TAN_VALUE_LOOPS(EXPR)                                                      \
    if (A && B) {                                                                  \
        for (i = 0; i < n; i++) { double a = A[i], b = B[i]; R[i] = (EXPR); }     \
    } else if (A) {                                                                \
        for (i = 0; i < n; i++) { double a = A[i], b = kb; R[i] = (EXPR); }       \
    } else {                                                                       \
        for (i = 0; i < n; i++) { double a = ka, b = B[i]; R[i] = (EXPR); }       \
    }

#define TAN_UNARY(NAME) TAN_OPERATOR(NAME, TAN_UNARY_LOOP(NAME))
#define TAN_BINARY(NAME) TAN_OPERATOR(NAME, TAN_BINARY_LOOPS(NAME))
/* Sums and differences: constant partials CA, CB, so the chain rule is a plain sum. */
#define TAN_LINEAR(NAME, EXPR, CA, CB)                                             \
    TAN_OPERATOR(NAME, TAN_VALUE_LOOPS(EXPR) o.constpart = 1; o.ca = (CA); o.cb = (CB);)

/* ---- the evaluator ------------------------------------------------------------------ */

/* A runaway loop: value and every tangent NaN, with an error at every lane. */
static void tan_runaway(vm_scratch *s, const vm_inputs *in, uint32_t pc, size_t n,
                        uint32_t T, double *out, double *dout, size_t dstride)
{
    uint32_t c;
    size_t i;
    for (c = 0; c < T; c++)
        for (i = 0; i < n; i++) dout[c * dstride + i] = NAN;
    vm_runaway(s, in, pc, n, out);
}

/* Copy the result (level 0) to out and dout and commit the run's errors. */
static void tan_result(vm_scratch *s, const vm_tanstate *t, size_t n, double *out,
                       double *dout, size_t dstride)
{
    uint32_t c;
    memcpy(out, t->ev[0], n * sizeof *out);
    for (c = 0; c < t->T; c++) {
        const double *tc = t->et[c];
        if (tc) memcpy(dout + c * dstride, tc, n * sizeof(double));
        else memset(dout + c * dstride, 0, n * sizeof(double));
    }
    vm_nan_lanes(s, n, out, dout, t->T, dstride);
    vm_err_commit(s, n);
}

/* Run over lanes 0..n-1 (dout[c * dstride + i]: tangent c at lane i); return codes as
 * vm.c's vm_run. */
static int tan_run(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                   vm_seed seed, double *out, double *dout, size_t dstride, int may_diverge)
    VM_CLONES;
static int tan_run(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                   vm_seed seed, double *out, double *dout, size_t dstride, int may_diverge)
{
    vm_tanstate *t = s->tan[seed == VM_SEED_XYZ ? 0 : 1];
    const uint32_t T = t->T;
    const frep_insn *code = p->code;
    const uint32_t ncode = p->ncode;
    const uint32_t xyz = seed == VM_SEED_XYZ; /* X leaves are seeds, else PARAM leaves */
    uint32_t pc = 0, d = 0, j, c;
    long loops = 0;

    s->cur = p;
    vm_err_begin(s, n);
    for (j = 0; j < p->nslots; j++) {
        t->sv[j] = s->zeros;
        for (c = 0; c < T; c++) t->st[(size_t)j * T + c] = NULL;
    }

    while (pc < ncode) {
        const frep_insn *in_ = &code[pc];
        switch ((frep_opcode)in_->op) {
        case FREP_OP_CONST: tan_push_const(t, d++, in_->k, n); break;
        case FREP_OP_X:
            tan_push_seed(t, d++, vm_axis(in, in_->arg), xyz ? in_->arg : TAN_NONE);
            break;
        case FREP_OP_PARAM:
            tan_push_seed(t, d++, s->parambuf + (size_t)in_->arg * FREP_BLOCK,
                          xyz ? TAN_NONE : in_->arg);
            break;
        case FREP_OP_LOAD:
            tan_push_ref(t, d++, t->sv[in_->arg], t->st + (size_t)in_->arg * T);
            break;
        case FREP_OP_PRIM:
            tan_push_ref(t, d++, in->prim_v[in_->arg],
                         xyz ? in->prim_g + 3 * (size_t)in_->arg : NULL);
            break;
        case FREP_OP_STORE: tan_store(t, in_->arg, --d, n); break;
        VM_CASE_JMP(tan_runaway(s, in, pc, n, T, out, dout, dstride))
        VM_CASE_JZ(t->ev[--d])
        case FREP_OP_LOADI: tan_loadi(s, t, in, in_, pc, d - 1, n); break;
        case FREP_OP_STOREI: d -= 2; tan_storei(s, t, in, in_, pc, d, n); break;
        TAN_OPERATOR(NEG, for (i = 0; i < n; i++) R[i] = -A[i]; o.constpart = 1; o.ca = -1;)
        TAN_UNARY(NOT)
        TAN_UNARY(ABS)
        TAN_UNARY(SQRT)
        TAN_UNARY(SQUARE)
        TAN_UNARY(EXP)
        TAN_UNARY(LOG)
        TAN_UNARY(LOGD)
        TAN_OPERATOR(SIN, tan_sincos(A, R, PA, n, 1);)
        TAN_OPERATOR(COS, tan_sincos(A, R, PA, n, 0);)
        TAN_UNARY(TAN)
        TAN_UNARY(ASIN)
        TAN_UNARY(ACOS)
        TAN_UNARY(ATAN)
        TAN_UNARY(SINH)
        TAN_UNARY(COSH)
        TAN_UNARY(TANH)
        TAN_UNARY(SIGN)
        TAN_UNARY(CEIL)
        TAN_UNARY(FLOOR)
        TAN_UNARY(INT)
        TAN_UNARY(FRAC)
        TAN_LINEAR(ADD, a + b, 1, 1)
        TAN_LINEAR(SUB, a - b, 1, -1)
        TAN_OPERATOR(MUL, TAN_VALUE_LOOPS(a * b) tan_mul_partials(&o);)
        TAN_BINARY(DIV)
        TAN_BINARY(POW)
        TAN_BINARY(MOD)
        TAN_BINARY(MIN)
        TAN_BINARY(MAX)
        TAN_BINARY(ATAN2)
        TAN_BINARY(EQ)
        TAN_BINARY(NE)
        TAN_BINARY(LT)
        TAN_BINARY(LE)
        TAN_BINARY(GT)
        TAN_BINARY(GE)
        TAN_BINARY(AND)
        TAN_BINARY(OR)
        TAN_BINARY(RUNI)
        TAN_BINARY(RINT)
        TAN_BINARY(RSUB)
        TAN_BINARY(MSUB)
        TAN_BINARY(AUNI)
        TAN_BINARY(AINT)
        case FREP_OP_SELECT: d -= 2; tan_select(s, t, d - 1, n); break;
        case FREP_OP__COUNT:
        default:
            return -1;
        }
        pc++;
    }
    if (d != 1) return -1;
    tan_result(s, t, n, out, dout, dstride);
    return 0;
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
    if (p->work && (p->flags & PROG_HAS_BRANCHES) && prog_work_stop(p->work)) {
        for (i = 0; i < (size_t)T * n; i++) dout[i] = NAN;
        vm_work_refuse(p, s, in, n, out);
        return 0;
    }
    vm_broadcast_params(p, s, in, n);
    rc = tan_run(p, s, in, n, seed, out, dout, n, n > 1);
    /* Divergent branches: one lane at a time (see vm_internal.h). */
    for (i = 0; rc == 1 && i < n; i++) {
        vm_inputs li = vm_lane_inputs(p, s, in, i);
        if (tan_run(p, s, &li, 1, seed, out + i, dout + i, n, 0) < 0) rc = -1;
    }
    vm_work_flush(s, p->work);
    return rc < 0 ? -1 : 0;
}

/* vm_f32.c - the single-precision value evaluator and its error bound (vm_f32.h).
 *
 * The evaluator is a stack of float lane vectors, one buffer per level; every operator
 * is one loop over the block that GCC vectorizes, compiled for AVX-512 (16 lanes),
 * AVX2 (8) and the baseline, the copy picked per scratch at run time (vm_f32_set_isa);
 * no FMA (-ffp-contract=off), so the roundings are the ones the bound counts.
 * Leaves and LOAD copy into their level: simple, and a LOADed value can never change
 * under a later STORE.
 *
 * The bound runs the program once over intervals (ival_op, the interval evaluator's
 * rules): for each instruction, V the enclosure of its double value and E a bound on
 * |float - double|.  The float operands lie in V widened by E (Vw), so an operator's
 * error is what its operands' errors can move it (a Lipschitz bound over Vw) plus its
 * own roundings (float's and double's: RHO per rounding of the largest magnitude, plus
 * ETA for underflow, which a square root can lift to 2^-75).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "interval.h"
#include "opsem.h"
#include "vm_f32.h"
#include "vm_internal.h"

/* One rounding, float's and double's together (2^-24 + 2^-53, rounded up), and the
 * absolute error underflow can leave after a square root. */
#define RHO 0x1p-23
#define ETA 0x1p-60

struct vm_f32 {
    uint32_t cap_stack, cap_slots;
    float *lv;                 /* cap_stack levels of FREP_BLOCK lanes */
    const float **sp;          /* each level's value: its lanes, an axis or a slot */
    float *slot;               /* cap_slots slots of FREP_BLOCK lanes */
    unsigned char *stored;     /* per slot: stored in this run (else it reads zeros) */
    float *zeros;              /* FREP_BLOCK zeros, never written */
    float *xyz;                /* the block's x, y, z in float */
    ival *iv, *ivslot;         /* the bound's interval stack and slots */
    double *e, *eslot;         /* its error stack and slots */
    int isa;                   /* VM_F32_ISA_*: which compiled f32_run runs */
};

static int f32_op_ok(const frep_insn *in)
{
    switch (in->op) { /* some ops: the rest are unsupported */
    case FREP_OP_X: return in->arg < 3;
    case FREP_OP_CONST: case FREP_OP_PARAM: case FREP_OP_LOAD: case FREP_OP_STORE:
    case FREP_OP_NEG: case FREP_OP_ABS: case FREP_OP_SQRT: case FREP_OP_SQUARE:
    case FREP_OP_ADD: case FREP_OP_SUB: case FREP_OP_MUL: case FREP_OP_DIV:
    case FREP_OP_MIN: case FREP_OP_MAX: case FREP_OP_MSUB:
    case FREP_OP_RUNI: case FREP_OP_RINT: case FREP_OP_RSUB:
        return 1;
    default:
        return 0;
    }
}

int vm_f32_supported(const frep_program *p)
{
    if (!p || !p->code || p->ncode == 0 || (p->flags & (PROG_HAS_BRANCHES | PROG_HAS_PRIMS)))
        return 0;
    for (uint32_t pc = 0; pc < p->ncode; pc++)
        if (!f32_op_ok(&p->code[pc])) return 0;
    return 1;
}

int vm_f32_cpu_ok(void)
{
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
#else
    return 0;
#endif
}

/* The ISA-specific copies of the float loops exist on x86-64 with GCC or clang. */
#if defined(__GNUC__) && defined(__x86_64__) && !defined(FREP_NO_CLONES)
#define F32_ISA_COPIES 1
#endif

int vm_f32_isa_ok(int isa)
{
    if (isa == VM_F32_ISA_BASE) return 1;
#ifdef F32_ISA_COPIES
    __builtin_cpu_init();
    if (isa == VM_F32_ISA_AVX2) return __builtin_cpu_supports("avx2") != 0;
    if (isa == VM_F32_ISA_AVX512)
        return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
               __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq");
#endif
    return 0;
}

int vm_f32_isa_default(void)
{
    const char *env = getenv("FREP_F32_ISA");
    if (env) {
        int want = strcmp(env, "avx512") == 0 ? VM_F32_ISA_AVX512
                   : strcmp(env, "avx2") == 0 ? VM_F32_ISA_AVX2
                   : strcmp(env, "base") == 0 ? VM_F32_ISA_BASE : -1;
        if (want >= 0 && vm_f32_isa_ok(want)) return want;
    }
    if (vm_f32_isa_ok(VM_F32_ISA_AVX512)) return VM_F32_ISA_AVX512;
    if (vm_f32_isa_ok(VM_F32_ISA_AVX2)) return VM_F32_ISA_AVX2;
    return VM_F32_ISA_BASE;
}

int vm_f32_set_isa(vm_f32 *s, int isa)
{
    if (!vm_f32_isa_ok(isa)) return -1;
    s->isa = isa;
    return 0;
}

int vm_f32_get_isa(const vm_f32 *s) { return s->isa; }

void vm_f32_free(vm_f32 *s)
{
    if (!s) return;
    frep_aligned_free(s->lv);
    frep_free(s->sp);
    frep_aligned_free(s->slot);
    frep_free(s->stored);
    frep_aligned_free(s->zeros);
    frep_aligned_free(s->xyz);
    frep_free(s->iv);
    frep_free(s->ivslot);
    frep_free(s->e);
    frep_free(s->eslot);
    frep_free(s);
}

vm_f32 *vm_f32_new(const frep_program *p)
{
    vm_f32 *s = frep_calloc(1, sizeof *s);
    if (!s) return NULL;
    s->cap_stack = p->max_stack ? p->max_stack : 1;
    s->cap_slots = p->nslots ? p->nslots : 1;
    size_t lanes = FREP_BLOCK * sizeof(float);
    s->lv = frep_aligned_alloc(64, s->cap_stack * lanes);
    s->slot = frep_aligned_alloc(64, s->cap_slots * lanes);
    s->xyz = frep_aligned_alloc(64, 3 * lanes);
    s->stored = frep_malloc(s->cap_slots);
    s->zeros = frep_aligned_alloc(64, lanes);
    s->sp = frep_malloc(s->cap_stack * sizeof *s->sp);
    s->iv = frep_malloc(s->cap_stack * sizeof *s->iv);
    s->ivslot = frep_malloc(s->cap_slots * sizeof *s->ivslot);
    s->e = frep_malloc(s->cap_stack * sizeof *s->e);
    s->eslot = frep_malloc(s->cap_slots * sizeof *s->eslot);
    if (!s->lv || !s->sp || !s->slot || !s->stored || !s->zeros || !s->xyz || !s->iv || !s->ivslot || !s->e || !s->eslot) {
        vm_f32_free(s);
        return NULL;
    }
    memset(s->zeros, 0, lanes);
    s->isa = vm_f32_isa_default();
    return s;
}

/* ---- the bound ------------------------------------------------------------------- */

static double mag(ival v) { return fmax(fabs(v.lo), fabs(v.hi)); }
static ival widen(ival v, double e) { ival w = { v.lo - e, v.hi + e }; return w; }
/* Smallest |v| over v (0 when v holds 0). */
static double mag_min(ival v) { return v.lo > 0 ? v.lo : v.hi < 0 ? -v.hi : 0; }

/* The range of a / sqrt(a^2 + b^2) over a x b (the cosine of the point's angle): it
 * grows with a, and moves towards 0 as |b| grows. [-1, 1] where undefined (0, 0). */
static ival cos_range(ival a, ival b)
{
    double bmin = mag_min(b), bmax = mag(b);
    ival g;
    if (a.hi >= 0) g.hi = bmin == 0 ? 1 : a.hi / hypot(a.hi, bmin);
    else g.hi = a.hi / hypot(a.hi, bmax);
    if (a.lo <= 0) g.lo = bmin == 0 ? -1 : a.lo / hypot(a.lo, bmin);
    else g.lo = a.lo / hypot(a.lo, bmax);
    /* hypot's own rounding: stay inside [-1, 1] but never narrower than computed */
    g.lo = fmax(-1, g.lo - 0x1p-50);
    g.hi = fmin(1, g.hi + 0x1p-50);
    return g;
}

/* Error of an R-function a ± b ± sqrt(a^2 + b^2) (sa, sb the signs of a and b
 * outside the root): its partial derivatives are sa + a/n and sb + b/n, bounded over
 * the widened operands; five roundings of magnitudes up to |a| + |b| each. */
static double f32_rfunc_err(ival aw, ival bw, double ea, double eb, double sa, double sb,
                            double sn)
{
    ival ga = cos_range(aw, bw), gb = cos_range(bw, aw);
    double la = fmax(fabs(sa + sn * ga.lo), fabs(sa + sn * ga.hi));
    double lb = fmax(fabs(sb + sn * gb.lo), fabs(sb + sn * gb.hi));
    return la * ea + lb * eb + 8 * RHO * (mag(aw) + mag(bw)) + 4 * ETA;
}

/* The error of one operator with operands v (push order), errors e, immediate k. */
static double f32_op_err(const frep_insn *in, const ival *v, const double *e)
{
    ival a = v[0], b = v[1];
    ival aw = widen(a, e[0]), bw = widen(b, e[1]);
    ival ws[2] = { aw, bw };
    ival rw = ival_op((frep_opcode)in->op, ws, in->k);
    double rm = mag(rw);
    if (!(mag(aw) <= VM_F32_MAX_MAG) || !(mag(bw) <= VM_F32_MAX_MAG) ||
        !(rm <= VM_F32_MAX_MAG))
        return INFINITY;
    switch (in->op) { /* some ops: the rest are unsupported */
    case FREP_OP_NEG: case FREP_OP_ABS: return e[0];
    case FREP_OP_MIN: case FREP_OP_MAX: case FREP_OP_MSUB: return fmax(e[0], e[1]);
    case FREP_OP_ADD: case FREP_OP_SUB: return e[0] + e[1] + RHO * rm + ETA;
    case FREP_OP_MUL: return mag(bw) * e[0] + mag(a) * e[1] + RHO * rm + ETA;
    case FREP_OP_SQUARE: return (mag(aw) + mag(a)) * e[0] + RHO * rm + ETA;
    case FREP_OP_DIV: {
        double mb = mag_min(b), mbw = mag_min(bw);
        if (!(mbw > 0)) return INFINITY;   /* double or float might divide by 0 */
        return e[0] / mbw + mag(a) * e[1] / (mb * mbw) + RHO * rm + ETA;
    }
    case FREP_OP_SQRT: {
        /* the float evaluator takes sqrt(max(a, 0)); sqrt is 1/2-Hoelder (sqrt(e))
         * and Lipschitz away from 0 */
        if (a.lo < 0) return INFINITY;     /* double might report sqrt of a negative */
        double den = sqrt(fmax(aw.lo, 0)) + sqrt(a.lo);
        double prop = sqrt(e[0]);
        if (den > 0 && e[0] / den < prop) prop = e[0] / den;
        return prop + RHO * rm + ETA;
    }
    case FREP_OP_RUNI: return f32_rfunc_err(aw, bw, e[0], e[1], 1, 1, 1);
    case FREP_OP_RINT: return f32_rfunc_err(aw, bw, e[0], e[1], 1, 1, -1);
    case FREP_OP_RSUB: return f32_rfunc_err(aw, bw, e[0], e[1], 1, -1, -1);
    default: return INFINITY;
    }
}

/* An exact value x and the error of its conversion to float. */
static void f32_leaf(vm_f32 *s, uint32_t d, ival v)
{
    s->iv[d] = v;
    s->e[d] = RHO * mag(v) + ETA;
}

double vm_f32_bound(vm_f32 *s, const frep_program *p, const double box[6])
{
    uint32_t d = 0;
    if (!vm_f32_supported(p) || p->max_stack > s->cap_stack || p->nslots > s->cap_slots)
        return INFINITY;
    for (uint32_t j = 0; j < p->nslots; j++) {
        s->ivslot[j].lo = s->ivslot[j].hi = 0;
        s->eslot[j] = 0;
    }
    for (uint32_t pc = 0; pc < p->ncode; pc++) {
        const frep_insn *in = &p->code[pc];
        switch (in->op) { /* some ops: the rest are unsupported */
        case FREP_OP_CONST: f32_leaf(s, d++, (ival){ in->k, in->k }); continue;
        case FREP_OP_X: f32_leaf(s, d++, (ival){ box[in->arg], box[in->arg + 3] }); continue;
        case FREP_OP_PARAM: {
            double v = p->params ? p->params[in->arg].value : 0;
            f32_leaf(s, d++, (ival){ v, v });
            continue;
        }
        case FREP_OP_LOAD:
            s->iv[d] = s->ivslot[in->arg];
            s->e[d++] = s->eslot[in->arg];
            continue;
        case FREP_OP_STORE:
            d--;
            s->ivslot[in->arg] = s->iv[d];
            s->eslot[in->arg] = s->e[d];
            continue;
        default: break;
        }
        ival v[2];
        double e[2];
        uint32_t at;
        if (op_nin((frep_opcode)in->op) == 1) {
            at = d - 1;
            v[0] = s->iv[at];
            e[0] = s->e[at];
            v[1] = v[0];
            e[1] = 0;
        } else if (in->flags & INSN_KB) {
            at = d - 1;
            v[0] = s->iv[at];
            e[0] = s->e[at];
            v[1] = (ival){ in->k, in->k };
            e[1] = RHO * fabs(in->k) + ETA;
        } else if (in->flags & INSN_KA) {
            at = d - 1;
            v[0] = (ival){ in->k, in->k };
            e[0] = RHO * fabs(in->k) + ETA;
            v[1] = s->iv[at];
            e[1] = s->e[at];
        } else {
            at = d - 2;
            v[0] = s->iv[at];
            e[0] = s->e[at];
            v[1] = s->iv[at + 1];
            e[1] = s->e[at + 1];
            d--;
        }
        double err = f32_op_err(in, v, e);
        if (!(err < INFINITY)) return INFINITY;
        s->iv[at] = ival_op((frep_opcode)in->op, v, in->k);
        s->e[at] = err;
    }
    return d == 1 ? s->e[0] : INFINITY;
}

/* ---- the evaluator ----------------------------------------------------------------- */

#define LANES(L) (s->lv + (size_t)(L) * FREP_BLOCK)
#define SLOT(j) (s->slot + (size_t)(j) * FREP_BLOCK)

/* Operators write their level's own lanes; an operand may be those same lanes (an
 * element-wise update in place) or an axis or slot the level points at. */
#define F32_UNARY(NAME, EXPR)                                                      \
    case FREP_OP_##NAME: {                                                         \
        const float *A = s->sp[d - 1];                                             \
        float *R = LANES(d - 1);                                                   \
        for (i = 0; i < n; i++) { float a = A[i]; R[i] = (EXPR); }                \
        s->sp[d - 1] = R;                                                          \
        break;                                                                     \
    }

#define F32_BINARY(NAME, EXPR)                                                     \
    case FREP_OP_##NAME:                                                           \
        if (in->flags & INSN_KB) {                                                 \
            const float *A = s->sp[d - 1];                                         \
            float *R = LANES(d - 1);                                               \
            const float b = (float)in->k;                                          \
            for (i = 0; i < n; i++) { float a = A[i]; R[i] = (EXPR); }            \
            s->sp[d - 1] = R;                                                      \
        } else if (in->flags & INSN_KA) {                                          \
            const float *B = s->sp[d - 1];                                         \
            float *R = LANES(d - 1);                                               \
            const float a = (float)in->k;                                          \
            for (i = 0; i < n; i++) { float b = B[i]; R[i] = (EXPR); }            \
            s->sp[d - 1] = R;                                                      \
        } else {                                                                   \
            const float *A = s->sp[d - 2], *B = s->sp[d - 1];                      \
            float *R = LANES(d - 2);                                               \
            for (i = 0; i < n; i++) { float a = A[i], b = B[i]; R[i] = (EXPR); }  \
            s->sp[d - 2] = R;                                                      \
            d--;                                                                   \
        }                                                                          \
        break;

static inline float f32_min(float a, float b) { return b < a ? b : a; }
static inline float f32_max(float a, float b) { return b > a ? b : a; }

/* STORE level L into slot j: a level still pointing at the slot (a live LOAD) first
 * takes a copy of the old value. */
static void f32_store(vm_f32 *s, uint32_t j, uint32_t L, size_t n)
{
    float *S = SLOT(j);
    if (s->sp[L] == S) return;
    for (uint32_t k = 0; k < L; k++)
        if (s->sp[k] == S) {
            memcpy(LANES(k), S, n * sizeof(float));
            s->sp[k] = LANES(k);
        }
    memcpy(S, s->sp[L], n * sizeof(float));
    s->stored[j] = 1;
}

/* The float loops, inlined into one copy per ISA (f32_run_avx512 etc. below). */
static inline __attribute__((always_inline)) int f32_run_body(vm_f32 *s, const frep_program *p,
                                                              size_t n)
{
    uint32_t d = 0;
    size_t i;
    for (uint32_t pc = 0; pc < p->ncode; pc++) {
        const frep_insn *in = &p->code[pc];
        switch (in->op) { /* some ops: the rest are unsupported */
        case FREP_OP_CONST: {
            float *R = LANES(d), k = (float)in->k;
            for (i = 0; i < n; i++) R[i] = k;
            s->sp[d++] = R;
            break;
        }
        case FREP_OP_PARAM: {
            float *R = LANES(d);
            float k = (float)(p->params ? p->params[in->arg].value : 0);
            for (i = 0; i < n; i++) R[i] = k;
            s->sp[d++] = R;
            break;
        }
        case FREP_OP_X:
            if (in->arg > 2) return -1;
            s->sp[d++] = s->xyz + (size_t)in->arg * FREP_BLOCK;
            break;
        case FREP_OP_LOAD: s->sp[d++] = s->stored[in->arg] ? SLOT(in->arg) : s->zeros; break;
        case FREP_OP_STORE: d--; f32_store(s, in->arg, d, n); break;
        F32_UNARY(NEG, -a)
        F32_UNARY(ABS, fabsf(a))
        F32_UNARY(SQRT, sqrtf(a > 0 ? a : 0.0f))
        F32_UNARY(SQUARE, a * a)
        F32_BINARY(ADD, a + b)
        F32_BINARY(SUB, a - b)
        F32_BINARY(MUL, a * b)
        F32_BINARY(DIV, a / b)
        F32_BINARY(MIN, f32_min(a, b))
        F32_BINARY(MAX, f32_max(a, b))
        F32_BINARY(MSUB, f32_min(a, -b))
        F32_BINARY(RUNI, a + b + sqrtf(a * a + b * b))
        F32_BINARY(RINT, a + b - sqrtf(a * a + b * b))
        F32_BINARY(RSUB, a - b - sqrtf(a * a + b * b))
        default:
            return -1;
        }
    }
    if (d != 1) return -1;
    if (s->sp[0] != s->lv) memcpy(s->lv, s->sp[0], n * sizeof(float));
    return 0;
}

#ifdef F32_ISA_COPIES
/* 512-bit vectors asked for: GCC's tuning for AVX-512 CPUs otherwise stays at 256. */
#ifdef __clang__
#define F32_AVX512 "avx512f,avx512vl,avx512bw,avx512dq"
#else
#define F32_AVX512 "avx512f,avx512vl,avx512bw,avx512dq,prefer-vector-width=512"
#endif
__attribute__((target(F32_AVX512)))
static int f32_run_avx512(vm_f32 *s, const frep_program *p, size_t n)
{
    return f32_run_body(s, p, n);
}

__attribute__((target("avx2"))) static int f32_run_avx2(vm_f32 *s, const frep_program *p, size_t n)
{
    return f32_run_body(s, p, n);
}
#endif

static int f32_run_base(vm_f32 *s, const frep_program *p, size_t n)
{
    return f32_run_body(s, p, n);
}

static int f32_run(vm_f32 *s, const frep_program *p, size_t n)
{
#ifdef F32_ISA_COPIES
    if (s->isa == VM_F32_ISA_AVX512) return f32_run_avx512(s, p, n);
    if (s->isa == VM_F32_ISA_AVX2) return f32_run_avx2(s, p, n);
#endif
    return f32_run_base(s, p, n);
}

int vm_f32_eval_block(vm_f32 *s, const frep_program *p, const double *x, const double *y,
                      const double *z, size_t n, double *out)
{
    if (n > FREP_BLOCK || p->max_stack > s->cap_stack || p->nslots > s->cap_slots ||
        (p->flags & (PROG_HAS_BRANCHES | PROG_HAS_PRIMS)))
        return -1;
    for (size_t i = 0; i < n; i++) {
        s->xyz[i] = (float)x[i];
        s->xyz[FREP_BLOCK + i] = (float)y[i];
        s->xyz[2 * FREP_BLOCK + i] = (float)z[i];
    }
    memset(s->stored, 0, p->nslots);
    if (f32_run(s, p, n) < 0) return -1;
    for (size_t i = 0; i < n; i++) out[i] = s->lv[i];
    return 0;
}

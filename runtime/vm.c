/* vm.c - the value evaluator: runs a frep_program over a block of points.
 *
 * Called by runtime/eval.c (public API) and directly by fit/ and evolve/.  The stack
 * holds POINTERS to lane vectors: leaves push the input, slot or parameter vector
 * itself, operators write a buffer owned by their stack level, and every operator is
 * a simple loop over the block's lanes that GCC vectorizes.  Branches run all lanes
 * together while they agree; when a JZ condition differs between lanes the block is
 * re-run one lane at a time, which is exact for point-dependent if/while.  Sine and
 * cosine are opsem.h's vectorizable ones; the one of a pair not asked for is kept for a
 * later instruction on the same input or variable (vm_trig).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "cancel.h"
#include "opsem.h"
#include "vm_internal.h"

/* ---- scratch -------------------------------------------------------------------- */

static void *grow(void *p, size_t count, size_t size)
{
    if (count == 0) count = 1;
    return frep_realloc(p, count * size);
}

/* Allocate n lane buffers into v[from..n-1] (each FREP_BLOCK doubles, aligned for
 * vector loads). */
static int alloc_lanes(double **v, uint32_t from, uint32_t n)
{
    uint32_t i;
    for (i = from; i < n; i++) {
        v[i] = frep_aligned_alloc(64, FREP_BLOCK * sizeof(double));
        if (!v[i]) {
            while (i > from) {
                frep_aligned_free(v[--i]);
                v[i] = NULL;   /* the trig cache is freed whole by vm_scratch_free */
            }
            return -1;
        }
        memset(v[i], 0, FREP_BLOCK * sizeof(double));
    }
    return 0;
}

int vm_scratch_fit(vm_scratch *s, const frep_program *p)
{
    if (p->max_stack > s->cap_stack) {
        uint32_t n = p->max_stack;
        double **lv = grow(s->lv, 2u * n, sizeof *lv);
        const double **sp;
        if (!lv) return -1;
        s->lv = lv;
        sp = grow(s->sp, n, sizeof *sp);
        if (!sp) return -1;
        /* lvl_out reads a level's entry before its first push */
        memset(sp + s->cap_stack, 0, (n - s->cap_stack) * sizeof *sp);
        s->sp = sp;
        if (alloc_lanes(s->lv, 2u * s->cap_stack, 2u * n) < 0) return -1;
        s->cap_stack = n;
    }
    if (p->nslots > s->cap_slots) {
        uint32_t n = p->nslots;
        double **sb = grow(s->slotbuf, n, sizeof *sb);
        const double **spp;
        if (!sb) return -1;
        s->slotbuf = sb;
        spp = grow(s->slotp, n, sizeof *spp);
        if (!spp) return -1;
        s->slotp = spp;
        if (alloc_lanes(s->slotbuf, s->cap_slots, n) < 0) return -1;
        s->cap_slots = n;
    }
    if (p->nparams > s->cap_params) {
        double *pb = frep_aligned_alloc(64, (size_t)p->nparams * FREP_BLOCK * sizeof(double));
        double *pv = pb ? frep_malloc((size_t)p->nparams * sizeof *pv) : NULL;
        if (!pv) {
            frep_aligned_free(pb);
            return -1;
        }
        frep_aligned_free(s->parambuf);
        frep_free(s->paramval);
        s->parambuf = pb;
        s->paramval = pv;
        s->param_lanes = 0;
        s->param_count = 0;
        s->cap_params = p->nparams;
    }
    if (p->nprims > s->cap_prims) {
        const double **pp = grow(s->primp, p->nprims, sizeof *pp);
        if (!pp) return -1;
        s->primp = pp;
        pp = grow(s->primg, 3u * p->nprims, sizeof *pp);
        if (!pp) return -1;
        s->primg = pp;
        s->cap_prims = p->nprims;
    }
    return 0;
}

vm_scratch *vm_scratch_new(const frep_program *p)
{
    vm_scratch *s = frep_calloc(1, sizeof *s);
    if (!s) return NULL;
    s->zeros = frep_aligned_alloc(64, FREP_BLOCK * sizeof(double));
    s->errlane = frep_malloc(FREP_BLOCK);
    if (!s->zeros || !s->errlane || alloc_lanes(s->trig, 0, VM_TRIG_CACHE) < 0 ||
        (p && vm_scratch_fit(s, p) < 0)) {
        vm_scratch_free(s);
        return NULL;
    }
    memset(s->zeros, 0, FREP_BLOCK * sizeof(double));
    return s;
}

void vm_scratch_free(vm_scratch *s)
{
    uint32_t i;
    if (!s) return;
    for (i = 0; i < 2 * s->cap_stack; i++) frep_aligned_free(s->lv[i]);
    for (i = 0; i < s->cap_slots; i++) frep_aligned_free(s->slotbuf[i]);
    frep_free(s->lv);
    frep_free(s->sp);
    frep_free(s->slotbuf);
    frep_free(s->slotp);
    frep_aligned_free(s->parambuf);
    frep_free(s->paramval);
    frep_aligned_free(s->zeros);
    for (i = 0; i < VM_TRIG_CACHE; i++) frep_aligned_free(s->trig[i]);
    frep_free(s->primp);
    frep_free(s->primg);
    frep_free(s->errlane);
    vm_tan_free(s->tan[0]);
    vm_tan_free(s->tan[1]);
    frep_free(s);
}

/* ---- runtime errors ------------------------------------------------------------------ */

void vm_err_begin(vm_scratch *s, size_t n)
{
    s->blk.count = 0;
    s->work_over = 0;
    s->nan_lanes = 0;
    memset(s->errlane, 0, n);
}

void vm_err_lane(vm_scratch *s, uint32_t pc, size_t i, const vm_inputs *in)
{
    int first = s->blk.count == 0;
    if (!s->errlane[i]) {
        s->errlane[i] = 1;
        s->blk.count++;
    }
    /* The example point is the first lane seen at the lowest pc. */
    if (first || pc < s->blk.pc) {
        s->blk.pc = pc;
        s->blk.what = opsem_error_what((frep_opcode)s->cur->code[pc].op);
        s->blk.x = in->x[i];
        s->blk.y = in->y[i];
        s->blk.z = in->z[i];
    }
}

void vm_err_lane_nan(vm_scratch *s, uint32_t pc, size_t i, const vm_inputs *in)
{
    vm_err_lane(s, pc, i, in);
    s->errlane[i] |= VM_LANE_NAN;
    s->nan_lanes = 1;
}

void vm_nan_lanes(const vm_scratch *s, size_t n, double *out, double *dout, uint32_t T,
                  size_t dstride)
{
    uint32_t c;
    size_t i;
    if (!s->nan_lanes) return;
    for (i = 0; i < n; i++) {
        if (!(s->errlane[i] & VM_LANE_NAN)) continue;
        out[i] = NAN;
        for (c = 0; c < T; c++) dout[c * dstride + i] = NAN;
    }
}

void vm_err_merge(vm_errstate *into, const vm_errstate *from)
{
    if (from->count == 0) return;
    if (into->count == 0 || from->pc < into->pc) {
        into->pc = from->pc;
        into->what = from->what;
        into->x = from->x;
        into->y = from->y;
        into->z = from->z;
    }
    into->count += from->count;
}

void vm_err_commit(vm_scratch *s, size_t n)
{
    (void)n;
    vm_err_merge(&s->total, &s->blk);
    s->blk.count = 0;
}

/* ---- the evaluator ---------------------------------------------------------------- */

/* A level's free buffer: the one its current value does not occupy. */
static inline double *lvl_out(vm_scratch *s, uint32_t L)
{
    return s->sp[L] == s->lv[2 * L] ? s->lv[2 * L + 1] : s->lv[2 * L];
}

/* Before slot `slot` is overwritten: any stack entry still pointing at its buffer
 * (a LOAD whose value is live) gets a private copy, so it keeps the loaded value. */
static void unalias_slot(vm_scratch *s, uint32_t slot, uint32_t depth, size_t n)
{
    uint32_t j;
    const double *b = s->slotbuf[slot];
    if (s->slotp[slot] != b) return;
    for (j = 0; j < depth; j++) {
        if (s->sp[j] == b) {
            double *o = lvl_out(s, j);
            memcpy(o, b, n * sizeof *o);
            s->sp[j] = o;
        }
    }
}

/* Make slot `slot` own writable storage holding its current value. */
static void materialize_slot(vm_scratch *s, uint32_t slot, size_t n)
{
    if (s->slotp[slot] != s->slotbuf[slot]) {
        memset(s->slotbuf[slot], 0, n * sizeof(double));
        s->slotp[slot] = s->slotbuf[slot];
    }
}

void vm_record_errors(vm_scratch *s, const vm_inputs *in, uint32_t pc, frep_opcode op,
                      const double *A, double ka, const double *B, double kb, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        double a = A ? A[i] : ka, b = B ? B[i] : kb;
        if (opsem_is_bad(op, a, b)) vm_err_lane(s, pc, i, in);
    }
}

void vm_runaway(vm_scratch *s, const vm_inputs *in, uint32_t pc, size_t n, double *out)
{
    size_t i;
    for (i = 0; i < n; i++) {
        out[i] = NAN;
        vm_err_lane(s, pc, i, in);
    }
    if (s->work_over && s->blk.pc == pc)
        s->blk.what = s->work_over == 2 ? VM_CANCEL_WHAT : VM_WORK_WHAT;
    s->work_over = 0;
    vm_err_commit(s, n);
}

/* ---- the work budget ---------------------------------------------------------------- */

int vm_work_flush(vm_scratch *s, frep_work *w)
{
    uint64_t add = s->work_pending;
    s->work_pending = 0;
    if (!w) return 0;
    if (add) atomic_fetch_add_explicit(&w->used, add, memory_order_relaxed);
    if (prog_work_spent(w)) s->work_over = 1;
    else if (frep_cancelled(w->cancel)) s->work_over = 2;
    else return 0;
    return 1;
}

void vm_work_refuse(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                    double *out)
{
    uint32_t pc = 0;
    while (pc < p->ncode && !(p->code[pc].op == FREP_OP_JMP && p->code[pc].arg <= pc)) pc++;
    if (pc == p->ncode) pc = 0;
    s->cur = p;
    vm_err_begin(s, n);
    s->work_over = prog_work_spent(p->work) ? 1 : 2;
    vm_runaway(s, in, pc, n, out);
}

#define VM_RESTRICT restrict

/* Loop bodies.  Each macro expands to a case computing R[i] from operand vectors
 * A (and B) or immediates; the domain check runs only for OPF_DOMAIN ops and its
 * slow path (vm_record_errors) only when some lane failed. */
#define UNARY(NAME, EXPR)                                                          \
    case FREP_OP_##NAME: {                                                         \
        const double *VM_RESTRICT A = s->sp[d - 1];                                \
        double *VM_RESTRICT R = lvl_out(s, d - 1);                                 \
        for (i = 0; i < n; i++) { double a = A[i]; R[i] = (EXPR); }               \
        s->sp[d - 1] = R;                                                          \
        break;                                                                     \
    }

#define UNARY_DOM(NAME, EXPR, BAD)                                                 \
    case FREP_OP_##NAME: {                                                         \
        const double *VM_RESTRICT A = s->sp[d - 1];                                \
        double *VM_RESTRICT R = lvl_out(s, d - 1);                                 \
        for (i = 0; i < n; i++) { double a = A[i]; R[i] = (EXPR); }               \
        if (!(in_->flags & INSN_QUIET)) {                                          \
            int bad = 0;                                                           \
            for (i = 0; i < n; i++) { double a = A[i]; bad |= (BAD); }            \
            if (bad) vm_record_errors(s, in, pc, FREP_OP_##NAME, A, 0, NULL, 0, n);   \
        }                                                                          \
        s->sp[d - 1] = R;                                                          \
        break;                                                                     \
    }

/* Binary: three variants (both on the stack, b immediate, a immediate). */
#define BINARY_LOOPS(EXPR)                                                         \
    if (in_->flags & INSN_KB) {                                                    \
        const double *VM_RESTRICT A = s->sp[d - 1];                                \
        const double b = in_->k;                                                   \
        R = lvl_out(s, d - 1);                                                     \
        for (i = 0; i < n; i++) { double a = A[i]; R[i] = (EXPR); }               \
        s->sp[d - 1] = R;                                                          \
    } else if (in_->flags & INSN_KA) {                                             \
        const double *VM_RESTRICT B = s->sp[d - 1];                                \
        const double a = in_->k;                                                   \
        R = lvl_out(s, d - 1);                                                     \
        for (i = 0; i < n; i++) { double b = B[i]; R[i] = (EXPR); }               \
        s->sp[d - 1] = R;                                                          \
    } else {                                                                       \
        const double *VM_RESTRICT A = s->sp[d - 2];                                \
        const double *VM_RESTRICT B = s->sp[d - 1];                                \
        R = lvl_out(s, d - 2);                                                     \
        for (i = 0; i < n; i++) { double a = A[i], b = B[i]; R[i] = (EXPR); }     \
        s->sp[d - 2] = R;                                                          \
        d--;                                                                       \
    }

#define BINARY(NAME, EXPR)                                                         \
    case FREP_OP_##NAME: {                                                         \
        double *VM_RESTRICT R;                                                     \
        BINARY_LOOPS(EXPR)                                                         \
        break;                                                                     \
    }

/* Binary with a domain check, done on the operands before they are overwritten. */
#define BINARY_DOM(NAME, EXPR, BAD)                                                \
    case FREP_OP_##NAME: {                                                         \
        double *VM_RESTRICT R;                                                     \
        if (!(in_->flags & INSN_QUIET)) {                                          \
            const double *A = NULL, *B = NULL;                                     \
            double ka = in_->k, kb = in_->k;                                       \
            int bad = 0;                                                           \
            if (in_->flags & INSN_KB) A = s->sp[d - 1];                            \
            else if (in_->flags & INSN_KA) B = s->sp[d - 1];                       \
            else { A = s->sp[d - 2]; B = s->sp[d - 1]; }                           \
            if (A && B) {                                                          \
                for (i = 0; i < n; i++) { double a = A[i], b = B[i]; bad |= (BAD); } \
            } else if (A) {                                                        \
                for (i = 0; i < n; i++) { double a = A[i], b = kb; bad |= (BAD); } \
            } else {                                                               \
                for (i = 0; i < n; i++) { double a = ka, b = B[i]; bad |= (BAD); } \
            }                                                                      \
            if (bad) vm_record_errors(s, in, pc, FREP_OP_##NAME, A, ka, B, kb, n);    \
        }                                                                          \
        BINARY_LOOPS(EXPR)                                                         \
        break;                                                                     \
    }

/* ---- leaves, slots and arrays ------------------------------------------------------ */

/* Push the constant k: a lane vector in the level's free buffer. */
OPSEM_INLINE void vm_push_const(vm_scratch *s, uint32_t L, double k, size_t n)
{
    double *VM_RESTRICT R = lvl_out(s, L);
    size_t i;
    for (i = 0; i < n; i++) R[i] = k;
    s->sp[L] = R;
}

/* STORE: pop level L into slot `slot`. */
static void vm_store(vm_scratch *s, uint32_t slot, uint32_t L, size_t n)
{
    const double *v = s->sp[L];
    if (v == s->slotp[slot]) return; /* LOAD s; STORE s */
    unalias_slot(s, slot, L, n);
    if (v == s->lv[2 * L] || v == s->lv[2 * L + 1]) {
        /* The value is in a level buffer: trade buffers instead of copying. */
        uint32_t w = v == s->lv[2 * L] ? 2 * L : 2 * L + 1;
        double *t = s->slotbuf[slot];
        s->slotbuf[slot] = s->lv[w];
        s->lv[w] = t;
    } else {
        memcpy(s->slotbuf[slot], v, n * sizeof(double));
    }
    s->slotp[slot] = s->slotbuf[slot];
}

/* LOADI: replace the index at level L by element arg+i-1 of the array (NaN and an
 * error for an index out of range). */
static void vm_loadi(vm_scratch *s, const vm_inputs *in, const frep_insn *in_, uint32_t pc,
                     uint32_t L, size_t n)
{
    const double *I = s->sp[L];
    double *R = lvl_out(s, L);
    const double k = in_->k;
    int bad = 0;
    size_t i;
    for (i = 0; i < n; i++) {
        double ix = I[i];
        if (opsem_bad_index(ix, k)) {
            R[i] = NAN;
            bad = 1;
        } else {
            R[i] = s->slotp[in_->arg + (uint32_t)ix - 1][i];
        }
    }
    if (bad && !(in_->flags & INSN_QUIET))
        for (i = 0; i < n; i++)
            if (opsem_bad_index(I[i], k)) vm_err_lane(s, pc, i, in);
    s->sp[L] = R;
}

/* STOREI: store the value at level L into element arg+i-1, i the index at L+1 (both
 * popped); an index out of range is an error that makes the lane's result NaN (the
 * reference interpreter stops there).  Each lane reads its value and index before it writes its own lane of one
 * slot, so V or I being a slot of the array is harmless; only older stack entries
 * need unaliasing. */
static void vm_storei(vm_scratch *s, const vm_inputs *in, const frep_insn *in_, uint32_t pc,
                      uint32_t L, size_t n)
{
    const double *I = s->sp[L + 1];
    const double *V = s->sp[L];
    const double k = in_->k;
    const uint32_t kk = (uint32_t)k;
    uint32_t j;
    size_t i;
    for (j = 0; j < kk; j++) {
        unalias_slot(s, in_->arg + j, L, n);
        materialize_slot(s, in_->arg + j, n);
    }
    for (i = 0; i < n; i++) {
        double ix = I[i];
        if (opsem_bad_index(ix, k)) {
            if (!(in_->flags & INSN_QUIET)) vm_err_lane_nan(s, pc, i, in);
        } else {
            s->slotbuf[in_->arg + (uint32_t)ix - 1][i] = V[i];
        }
    }
}

/* SELECT c, a, b at levels L..L+2 into level L. */
OPSEM_INLINE void vm_select(vm_scratch *s, uint32_t L, size_t n)
{
    const double *VM_RESTRICT C = s->sp[L];
    const double *VM_RESTRICT A = s->sp[L + 1];
    const double *VM_RESTRICT B = s->sp[L + 2];
    double *VM_RESTRICT R = lvl_out(s, L);
    size_t i;
    for (i = 0; i < n; i++) R[i] = opsem_select(C[i], A[i], B[i]);
    s->sp[L] = R;
}

/* The sine/cosine cache of one run.  An entry holds the sine (want_sin) or cosine of
 * the vector arg, valid while gen (bumped by every store) is unchanged.  Only stable
 * vectors are cached: the inputs and slot buffers, which change only by stores; the
 * stack's level buffers are rewritten by every operator. */
typedef struct trig_cache {
    const double *arg[VM_TRIG_CACHE];
    int has_sin[VM_TRIG_CACHE];
    unsigned long gen[VM_TRIG_CACHE];
    unsigned next;
} trig_cache;

static int vm_stable(const frep_program *p, const vm_scratch *s, const vm_inputs *in,
                     const double *a)
{
    uint32_t j;
    if (a == in->x || a == in->y || a == in->z) return 1;
    for (j = 0; j < p->nslots; j++)
        if (s->slotp[j] == a) return 1;
    return 0;
}

/* SIN or COS of A into R (n lanes), through the cache tc (inlined into each of
 * vm_run's clones, so the loops get AVX2 code there). */
OPSEM_INLINE void vm_trig(const frep_program *p, vm_scratch *s, const vm_inputs *in,
                          trig_cache *tc, unsigned long gen, int want_sin,
                          const double *VM_RESTRICT A, double *VM_RESTRICT R, size_t n)
{
    size_t i;
    unsigned e;
    int slow = 0;
    for (e = 0; e < VM_TRIG_CACHE; e++)
        if (tc->arg[e] == A && tc->gen[e] == gen && tc->has_sin[e] == want_sin) {
            memcpy(R, s->trig[e], n * sizeof *R);
            return;
        }
    /* opsem.h's own sin/cos: a vectorized loop, then libm for the lanes outside its
     * range (rare); the same bits as opsem_sin/opsem_cos */
    e = tc->next;
    {
        double *VM_RESTRICT T = s->trig[e];
        if (want_sin) {
            for (i = 0; i < n; i++) {
                double sv, cv;
                opsem_sincos_fast(A[i], &sv, &cv);
                R[i] = sv;
                T[i] = cv;
                slow |= opsem_trig_slow(A[i]);
            }
        } else {
            for (i = 0; i < n; i++) {
                double sv, cv;
                opsem_sincos_fast(A[i], &sv, &cv);
                R[i] = cv;
                T[i] = sv;
                slow |= opsem_trig_slow(A[i]);
            }
        }
        if (slow)
            for (i = 0; i < n; i++) {
                if (!opsem_trig_slow(A[i])) continue;
                R[i] = want_sin ? opsem_sin(A[i]) : opsem_cos(A[i]);
                T[i] = want_sin ? opsem_cos(A[i]) : opsem_sin(A[i]);
            }
    }
    if (vm_stable(p, s, in, A)) {
        tc->arg[e] = A;
        tc->gen[e] = gen;
        tc->has_sin[e] = !want_sin;
        tc->next = (e + 1) % VM_TRIG_CACHE;
    }
}

/* SIN or COS through the run's cache. */
#define TRIG(NAME, WANT_SIN)                                                       \
    case FREP_OP_##NAME: {                                                         \
        double *R = lvl_out(s, d - 1);                                             \
        vm_trig(p, s, in, &tc, gen, WANT_SIN, s->sp[d - 1], R, n);                 \
        s->sp[d - 1] = R;                                                          \
        break;                                                                     \
    }

/* Run the code over lanes 0..n-1.  Returns 0 when done, 1 when a branch diverged
 * (only if may_diverge; nothing is committed then), -1 on an unusable program. */
static int vm_run(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                  double *out, int may_diverge)
    VM_CLONES;
static int vm_run(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                  double *out, int may_diverge)
{
    const frep_insn *code = p->code;
    const uint32_t ncode = p->ncode;
    uint32_t pc = 0, d = 0, j;
    long loops = 0;
    size_t i;
    trig_cache tc;
    unsigned long gen = 0;      /* stores so far: the trig cache's validity */

    memset(&tc, 0, sizeof tc);
    s->cur = p;
    vm_err_begin(s, n);
    for (j = 0; j < p->nslots; j++) s->slotp[j] = s->zeros;

    while (pc < ncode) {
        const frep_insn *in_ = &code[pc];
        switch ((frep_opcode)in_->op) {
        case FREP_OP_CONST: vm_push_const(s, d++, in_->k, n); break;
        case FREP_OP_X: s->sp[d++] = vm_axis(in, in_->arg); break;
        case FREP_OP_PARAM: s->sp[d++] = s->parambuf + (size_t)in_->arg * FREP_BLOCK; break;
        case FREP_OP_LOAD: s->sp[d++] = s->slotp[in_->arg]; break;
        case FREP_OP_PRIM: s->sp[d++] = in->prim_v[in_->arg]; break;
        case FREP_OP_STORE: gen++; vm_store(s, in_->arg, --d, n); break;
        VM_CASE_JMP(vm_runaway(s, in, pc, n, out))
        VM_CASE_JZ(s->sp[--d])
        case FREP_OP_LOADI: vm_loadi(s, in, in_, pc, d - 1, n); break;
        case FREP_OP_STOREI: d -= 2; gen++; vm_storei(s, in, in_, pc, d, n); break;
        UNARY(NEG, opsem_neg(a))
        UNARY(NOT, opsem_not(a))
        UNARY(ABS, opsem_abs(a))
        UNARY_DOM(SQRT, opsem_sqrt(a), opsem_bad_sqrt(a))
        UNARY(SQUARE, opsem_square(a))
        UNARY(EXP, opsem_exp(a))
        UNARY_DOM(LOG, opsem_log(a), opsem_bad_log(a))
        UNARY_DOM(LOGD, opsem_logd(a), opsem_bad_log(a))
        TRIG(SIN, 1)
        TRIG(COS, 0)
        UNARY(TAN, opsem_tan(a))
        UNARY_DOM(ASIN, opsem_asin(a), opsem_bad_asin(a))
        UNARY_DOM(ACOS, opsem_acos(a), opsem_bad_asin(a))
        UNARY(ATAN, opsem_atan(a))
        UNARY(SINH, opsem_sinh(a))
        UNARY(COSH, opsem_cosh(a))
        UNARY(TANH, opsem_tanh(a))
        UNARY(SIGN, opsem_sign(a))
        UNARY(CEIL, opsem_ceil(a))
        UNARY(FLOOR, opsem_floor(a))
        UNARY(INT, opsem_int(a))
        UNARY(FRAC, opsem_frac(a))
        BINARY(ADD, opsem_add(a, b))
        BINARY(SUB, opsem_sub(a, b))
        BINARY(MUL, opsem_mul(a, b))
        BINARY_DOM(DIV, opsem_div(a, b), opsem_bad_div(a, b))
        BINARY_DOM(POW, opsem_pow(a, b), opsem_bad_pow(a, b))
        BINARY_DOM(MOD, opsem_mod(a, b), opsem_bad_mod(a, b))
        BINARY(MIN, opsem_min(a, b))
        BINARY(MAX, opsem_max(a, b))
        BINARY(ATAN2, opsem_atan2(a, b))
        BINARY(EQ, opsem_eq(a, b))
        BINARY(NE, opsem_ne(a, b))
        BINARY(LT, opsem_lt(a, b))
        BINARY(LE, opsem_le(a, b))
        BINARY(GT, opsem_gt(a, b))
        BINARY(GE, opsem_ge(a, b))
        BINARY(AND, opsem_and(a, b))
        BINARY(OR, opsem_or(a, b))
        BINARY(RUNI, opsem_runi(a, b))
        BINARY(RINT, opsem_rint(a, b))
        BINARY(RSUB, opsem_rsub(a, b))
        BINARY(MSUB, opsem_msub(a, b))
        BINARY(AUNI, opsem_auni(a, b, in_->k))
        BINARY(AINT, opsem_aint(a, b, in_->k))
        case FREP_OP_SELECT: d -= 2; vm_select(s, d - 1, n); break;
        case FREP_OP__COUNT:
        default:
            return -1;
        }
        pc++;
    }
    if (d != 1) return -1;
    memcpy(out, s->sp[0], n * sizeof *out);
    vm_nan_lanes(s, n, out, NULL, 0, 0);
    vm_err_commit(s, n);
    return 0;
}

/* Broadcast the parameter values over the block's lanes, unless they are there
 * already (compared bit for bit: a NaN or -0 parameter must be rewritten exactly). */
void vm_broadcast_params(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n)
{
    uint32_t j;
    size_t i;
    int same = n <= s->param_lanes && p->nparams <= s->param_count;
    if (same && in->params && p->nparams)   /* one call: a fit evaluates single points */
        same = memcmp(in->params, s->paramval, p->nparams * sizeof *in->params) == 0;
    for (j = 0; j < p->nparams && same && !in->params; j++) {
        double v = p->params ? p->params[j].value : 0.0;
        same = memcmp(&v, &s->paramval[j], sizeof v) == 0;
    }
    if (same) return;
    for (j = 0; j < p->nparams; j++) {
        double *b = s->parambuf + (size_t)j * FREP_BLOCK;
        double v = in->params ? in->params[j] : p->params ? p->params[j].value : 0.0;
        for (i = 0; i < n; i++) b[i] = v;
        s->paramval[j] = v;
    }
    s->param_lanes = n;
    s->param_count = p->nparams;
}

vm_inputs vm_lane_inputs(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t i)
{
    vm_inputs li = *in;
    uint32_t j;
    li.x = in->x + i;
    li.y = in->y + i;
    li.z = in->z + i;
    if (p->nprims && in->prim_v) {
        for (j = 0; j < p->nprims; j++) s->primp[j] = in->prim_v[j] + i;
        li.prim_v = s->primp;
        if (in->prim_g) {
            for (j = 0; j < 3 * p->nprims; j++) s->primg[j] = in->prim_g[j] + i;
            li.prim_g = s->primg;
        }
    }
    return li;
}

int vm_eval_block(const frep_program *p, vm_scratch *s, const vm_inputs *in, size_t n,
                  double *out)
{
    int rc;
    size_t i;
    if (n == 0) return 0;
    if (n > FREP_BLOCK || vm_scratch_fit(s, p) < 0) return -1;
    if ((p->flags & PROG_HAS_PRIMS) && !in->prim_v) return -1;
    if (p->work && (p->flags & PROG_HAS_BRANCHES) && prog_work_stop(p->work)) {
        vm_work_refuse(p, s, in, n, out);
        return 0;
    }
    vm_broadcast_params(p, s, in, n);
    rc = vm_run(p, s, in, n, out, n > 1);
    for (i = 0; rc == 1 && i < n; i++) {
        vm_inputs li = vm_lane_inputs(p, s, in, i);
        if (vm_run(p, s, &li, 1, out + i, 0) < 0) rc = -1;
    }
    vm_work_flush(s, p->work);
    return rc < 0 ? -1 : 0;
}

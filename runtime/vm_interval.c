/* vm_interval.c - the interval evaluator: runs a program's bytecode with intervals for
 * x, y, z and yields a sound enclosure of f over a box (interval.h).
 *
 * Used by the octree of mesh/mesh.c to skip space the surface cannot cross.  Every
 * opcode of ops.h is handled; the common ones (arithmetic, R-functions, min/max,
 * elementary functions, integer powers) give tight bounds, exotic ones a safe hull.
 */
#include "config.h"

#include "alloc.h"
#include "interval.h"
#include "opsem.h"
#include "util.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* pi/2 and 2 pi: scaling by two is exact, so these are the doubles nearest the reals. */
#define IV_HALF_PI (FREP_PI / 2)
#define IV_TWO_PI (2 * FREP_PI)

struct vm_iscratch {
    uint32_t nstack, nslots;
    long loops;              /* backward jumps of the current run */
    ival *stack;
    ival *slots;
};

vm_iscratch *vm_iscratch_new(const frep_program *p)
{
    vm_iscratch *s = frep_calloc(1, sizeof *s);
    if (!s) return NULL;
    s->nstack = p->max_stack + 1;
    s->nslots = p->nslots + 1;
    s->stack = frep_malloc(s->nstack * sizeof *s->stack);
    s->slots = frep_malloc(s->nslots * sizeof *s->slots);
    if (!s->stack || !s->slots) {
        vm_iscratch_free(s);
        return NULL;
    }
    return s;
}

void vm_iscratch_free(vm_iscratch *s)
{
    if (!s) return;
    frep_free(s->stack);
    frep_free(s->slots);
    frep_free(s);
}

/* ---- helpers ------------------------------------------------------------------ */

static ival iv(double lo, double hi) { ival r = { lo, hi }; return r; }
static ival iv_entire(void) { return iv(-INFINITY, INFINITY); }
static ival iv_exact(double v) { return isnan(v) ? iv_entire() : iv(v, v); }

/* A NaN bound (inf - inf, 0 * inf) means "anything" on that side. */
static ival iv_fix(ival r)
{
    if (isnan(r.lo)) r.lo = -INFINITY;
    if (isnan(r.hi)) r.hi = INFINITY;
    if (r.lo > r.hi) return iv_entire();
    return r;
}

/* Widen outward by one ulp: round-to-nearest operations (and glibc's elementary
 * functions, accurate to within an ulp in their main ranges) then stay inside. */
static ival iv_round(ival r)
{
    r = iv_fix(r);
    if (r.lo > -INFINITY) r.lo = ival_next_down(r.lo);
    if (r.hi < INFINITY) r.hi = ival_next_up(r.hi);
    return r;
}

static ival iv_hull(ival a, ival b) { return iv(fmin(a.lo, b.lo), fmax(a.hi, b.hi)); }

static int iv_is_exact(ival a) { return a.lo == a.hi; }
/* Truth of an interval as a condition: nonzero is true (NaN included). */
static int iv_surely_true(ival a) { return a.lo > 0 || a.hi < 0; }
static int iv_surely_false(ival a) { return a.lo == 0 && a.hi == 0; }
static ival iv_bool(int surely_true, int surely_false)
{
    return surely_true ? iv(1, 1) : (surely_false ? iv(0, 0) : iv(0, 1));
}

static double min4(double a, double b, double c, double d)
{
    /* fmin drops NaN operands, which here are 0 * inf products: never extremes. */
    return fmin(fmin(a, b), fmin(c, d));
}
static double max4(double a, double b, double c, double d)
{
    return fmax(fmax(a, b), fmax(c, d));
}

static ival iv_mul(ival a, ival b)
{
    double p1 = a.lo * b.lo, p2 = a.lo * b.hi, p3 = a.hi * b.lo, p4 = a.hi * b.hi;
    return iv_round(iv(min4(p1, p2, p3, p4), max4(p1, p2, p3, p4)));
}

static ival iv_div(ival a, ival b)
{
    if (b.lo <= 0 && b.hi >= 0) return iv_entire();
    return iv_mul(a, iv_round(iv(1.0 / b.hi, 1.0 / b.lo)));
}

static ival iv_square(ival a)
{
    double l = a.lo * a.lo, h = a.hi * a.hi;
    if (a.lo <= 0 && a.hi >= 0) return iv(0, iv_round(iv(0, fmax(l, h))).hi);
    return iv_round(iv(fmin(l, h), fmax(l, h)));
}

/* Monotone nondecreasing / nonincreasing functions. */
static ival iv_incr(double (*f)(double), ival a) { return iv_round(iv(f(a.lo), f(a.hi))); }

/* Does [lo, hi] contain c + 2 pi n for some integer n? Conservative near the ends. */
static int iv_has_phase(ival a, double c)
{
    double n = ceil((a.lo - c) / IV_TWO_PI - 1e-12);
    return c + n * IV_TWO_PI <= a.hi + 1e-12 * (1 + fabs(a.hi));
}

/* sin and cos are those of opsem.h, within OPSEM_TRIG_ULPS + 1 = 4 ulp of exact:
 * the bounds are widened by 2^-50 absolute, 8 ulp of any value in [-1, 1]. */
#define IV_TRIG_SLACK 0x1p-50

static ival iv_sin(ival a)
{
    if (!isfinite(a.lo) || !isfinite(a.hi) || a.hi - a.lo >= IV_TWO_PI) return iv(-1, 1);
    double s1 = opsem_sin(a.lo), s2 = opsem_sin(a.hi);
    ival r = iv(fmin(s1, s2) - IV_TRIG_SLACK, fmax(s1, s2) + IV_TRIG_SLACK);
    if (iv_has_phase(a, IV_HALF_PI)) r.hi = 1;
    if (iv_has_phase(a, -IV_HALF_PI)) r.lo = -1;
    r = iv_round(r);
    return iv(fmax(r.lo, -1), fmin(r.hi, 1));
}

static ival iv_cos(ival a)
{
    if (!isfinite(a.lo) || !isfinite(a.hi) || a.hi - a.lo >= IV_TWO_PI) return iv(-1, 1);
    double c1 = opsem_cos(a.lo), c2 = opsem_cos(a.hi);
    ival r = iv(fmin(c1, c2) - IV_TRIG_SLACK, fmax(c1, c2) + IV_TRIG_SLACK);
    if (iv_has_phase(a, 0)) r.hi = 1;
    if (iv_has_phase(a, FREP_PI)) r.lo = -1;
    r = iv_round(r);
    return iv(fmax(r.lo, -1), fmin(r.hi, 1));
}

static ival iv_tan(ival a)
{
    if (!isfinite(a.lo) || !isfinite(a.hi) || a.hi - a.lo >= FREP_PI) return iv_entire();
    /* tan is increasing between its poles pi/2 + n pi. */
    if (iv_has_phase(a, IV_HALF_PI) || iv_has_phase(a, -IV_HALF_PI)) return iv_entire();
    return iv_round(iv(tan(a.lo), tan(a.hi)));
}

/* x^n for an integer n (pow with a constant integer exponent). */
static ival iv_powi(ival a, double n)
{
    if (n == 0) return iv(1, 1);
    int even = fmod(n, 2.0) == 0;
    if (n > 0) {
        if (!even) return iv_round(iv(pow(a.lo, n), pow(a.hi, n)));
        double l = pow(a.lo, n), h = pow(a.hi, n);
        if (a.lo <= 0 && a.hi >= 0) return iv(0, iv_round(iv(0, fmax(l, h))).hi);
        return iv_round(iv(fmin(l, h), fmax(l, h)));
    }
    if (a.lo <= 0 && a.hi >= 0) return iv_entire();
    double l = pow(a.lo, n), h = pow(a.hi, n);
    return iv_round(iv(fmin(l, h), fmax(l, h)));
}

static ival iv_pow(ival a, ival b)
{
    if (iv_is_exact(b) && isfinite(b.lo) && b.lo == trunc(b.lo)) return iv_powi(a, b.lo);
    if (a.lo >= 0 && iv_is_exact(b) && isfinite(b.lo)) {
        if (b.lo > 0) return iv_round(iv(pow(a.lo, b.lo), pow(a.hi, b.lo)));
        return iv_round(iv(pow(a.hi, b.lo), pow(a.lo, b.lo)));
    }
    if (a.lo > 0) {
        /* a^b = exp(b log a): monotone in each factor. */
        ival l = iv_round(iv(log(a.lo), log(a.hi)));
        ival m = iv_mul(b, l);
        return iv_round(iv(exp(m.lo), exp(m.hi)));
    }
    return iv_entire();
}

static ival iv_fmod(ival a, ival b)
{
    if (b.lo <= 0 && b.hi >= 0) return iv_entire();
    double m = fmax(fabs(b.lo), fabs(b.hi));
    if (iv_is_exact(b) && isfinite(a.lo) && isfinite(a.hi) && (a.lo >= 0 || a.hi <= 0)) {
        double c = fabs(b.lo);
        double q1 = trunc(a.lo / c), q2 = trunc(a.hi / c);
        if (q1 == q2) return iv_round(iv(fmod(a.lo, c), fmod(a.hi, c)));
    }
    /* |fmod(a, b)| < |b| and <= |a|, with the sign of a. */
    double lo = a.lo >= 0 ? 0 : fmax(-m, a.lo);
    double hi = a.hi <= 0 ? 0 : fmin(m, a.hi);
    return iv(lo, hi);
}

static ival iv_frac(ival a)
{
    if (isfinite(a.lo) && isfinite(a.hi) && trunc(a.lo) == trunc(a.hi) &&
        (a.lo >= 0 || a.hi <= 0)) {
        double t = trunc(a.lo);
        return iv_round(iv(a.lo - t, a.hi - t));
    }
    if (a.lo >= 0) return iv(0, 1);
    if (a.hi <= 0) return iv(-1, 0);
    return iv(-1, 1);
}

static ival iv_atan2(ival y, ival x)
{
    /* Away from the branch cut (the negative x axis) and the origin, atan2 is
     * continuous and monotone in each argument over the box: corners bound it. */
    if (y.lo > 0 || y.hi < 0 || x.lo > 0) {
        double c1 = atan2(y.lo, x.lo), c2 = atan2(y.lo, x.hi);
        double c3 = atan2(y.hi, x.lo), c4 = atan2(y.hi, x.hi);
        return iv_round(iv(min4(c1, c2, c3, c4), max4(c1, c2, c3, c4)));
    }
    return iv_round(iv(-FREP_PI, FREP_PI));
}

/* R-functions are nondecreasing in each argument (d/da = 1 +- a/sqrt(a^2+b^2) >= 0),
 * so the corners (lo, lo) and (hi, hi) bound them. */
static ival iv_mono2(double (*f)(double, double), ival a, ival b)
{
    return iv_round(iv(f(a.lo, b.lo), f(a.hi, b.hi)));
}

/* R-alpha functions are monotone too when |alpha| <= 1 (a^2+b^2-2k ab >= (a-kb)^2). */
static ival iv_ralpha(frep_opcode op, ival a, ival b, double k)
{
    if (!(k >= -1 && k <= 1) || k == -1) return iv_entire();
    if (op == FREP_OP_AUNI)
        return iv_round(iv(opsem_auni(a.lo, b.lo, k), opsem_auni(a.hi, b.hi, k)));
    return iv_round(iv(opsem_aint(a.lo, b.lo, k), opsem_aint(a.hi, b.hi, k)));
}

static double iv_runi_f(double a, double b) { return opsem_runi(a, b); }
static double iv_rint_f(double a, double b) { return opsem_rint(a, b); }

/* Comparisons are decided when the operand intervals do not overlap (or touch, for the
 * strict ones); otherwise both truth values are possible. */
static ival iv_compare(frep_opcode op, ival a, ival b)
{
    int exact_eq = iv_is_exact(a) && iv_is_exact(b) && a.lo == b.lo;
    int apart = a.hi < b.lo || b.hi < a.lo;
    if (op == FREP_OP_EQ) return iv_bool(exact_eq, apart);
    if (op == FREP_OP_NE) return iv_bool(apart, exact_eq);
    if (op == FREP_OP_LT) return iv_bool(a.hi < b.lo, a.lo >= b.hi);
    if (op == FREP_OP_LE) return iv_bool(a.hi <= b.lo, a.lo > b.hi);
    if (op == FREP_OP_GT) return iv_bool(a.lo > b.hi, a.hi <= b.lo);
    return iv_bool(a.lo >= b.hi, a.hi < b.lo); /* GE */
}

static ival iv_abs(ival a)
{
    if (a.lo >= 0) return a;
    if (a.hi <= 0) return iv(-a.hi, -a.lo);
    return iv(0, fmax(-a.lo, a.hi));
}

static ival iv_sqrt(ival a)
{
    if (a.hi < 0) return iv_entire(); /* NaN everywhere: nothing to enclose */
    return iv_round(iv(sqrt(fmax(a.lo, 0)), sqrt(a.hi)));
}

/* log or log10 (f): increasing on a > 0, -inf toward 0; NaN everywhere when a.hi <= 0. */
static ival iv_log(double (*f)(double), ival a)
{
    if (a.hi <= 0) return iv_entire();
    return iv_round(iv(a.lo > 0 ? f(a.lo) : -INFINITY, f(a.hi)));
}

static ival iv_asin(ival a)
{
    if (a.lo > 1 || a.hi < -1) return iv_entire();
    return iv_round(iv(asin(fmax(a.lo, -1)), asin(fmin(a.hi, 1))));
}

static ival iv_acos(ival a)
{
    if (a.lo > 1 || a.hi < -1) return iv_entire();
    return iv_round(iv(acos(fmin(a.hi, 1)), acos(fmax(a.lo, -1))));
}

static ival iv_cosh(ival a)
{
    double l = cosh(a.lo), h = cosh(a.hi);
    if (a.lo <= 0 && a.hi >= 0) return iv_round(iv(1, fmax(l, h)));
    return iv_round(iv(fmin(l, h), fmax(l, h)));
}

static ival iv_and(ival a, ival b)
{
    return iv_bool(iv_surely_true(a) && iv_surely_true(b),
                   iv_surely_false(a) || iv_surely_false(b));
}

static ival iv_or(ival a, ival b)
{
    return iv_bool(iv_surely_true(a) || iv_surely_true(b),
                   iv_surely_false(a) && iv_surely_false(b));
}

static ival iv_select(ival c, ival a, ival b)
{
    if (iv_surely_true(c)) return a;
    if (iv_surely_false(c)) return b;
    return iv_hull(a, b);
}

ival ival_op(frep_opcode op, const ival *v, double k)
{
    ival a = v[0], b = v[1];
    switch (op) {
    case FREP_OP_NEG: return iv(-a.hi, -a.lo);
    case FREP_OP_NOT: return iv_bool(iv_surely_false(a), iv_surely_true(a));
    case FREP_OP_ABS: return iv_abs(a);
    case FREP_OP_SQRT: return iv_sqrt(a);
    case FREP_OP_SQUARE: return iv_square(a);
    case FREP_OP_EXP: return iv_round(iv(fmax(exp(a.lo), 0), exp(a.hi)));
    case FREP_OP_LOG: return iv_log(log, a);
    case FREP_OP_LOGD: return iv_log(log10, a);
    case FREP_OP_SIN: return iv_sin(a);
    case FREP_OP_COS: return iv_cos(a);
    case FREP_OP_TAN: return iv_tan(a);
    case FREP_OP_ASIN: return iv_asin(a);
    case FREP_OP_ACOS: return iv_acos(a);
    case FREP_OP_ATAN: return iv_incr(atan, a);
    case FREP_OP_SINH: return iv_incr(sinh, a);
    case FREP_OP_COSH: return iv_cosh(a);
    case FREP_OP_TANH: return iv_incr(tanh, a);
    case FREP_OP_SIGN: return iv(opsem_sign(a.lo), opsem_sign(a.hi));
    case FREP_OP_CEIL: return iv(ceil(a.lo), ceil(a.hi));
    case FREP_OP_FLOOR: return iv(floor(a.lo), floor(a.hi));
    case FREP_OP_INT: return iv(trunc(a.lo), trunc(a.hi));
    case FREP_OP_FRAC: return iv_frac(a);
    case FREP_OP_ADD: return iv_round(iv(a.lo + b.lo, a.hi + b.hi));
    case FREP_OP_SUB: return iv_round(iv(a.lo - b.hi, a.hi - b.lo));
    case FREP_OP_MUL: return iv_mul(a, b);
    case FREP_OP_DIV: return iv_div(a, b);
    case FREP_OP_POW: return iv_pow(a, b);
    case FREP_OP_MOD: return iv_fmod(a, b);
    case FREP_OP_MIN: return iv(fmin(a.lo, b.lo), fmin(a.hi, b.hi));
    case FREP_OP_MAX: return iv(fmax(a.lo, b.lo), fmax(a.hi, b.hi));
    case FREP_OP_ATAN2: return iv_atan2(a, b);
    case FREP_OP_EQ: case FREP_OP_NE: case FREP_OP_LT: case FREP_OP_LE:
    case FREP_OP_GT: case FREP_OP_GE:
        return iv_compare(op, a, b);
    case FREP_OP_AND: return iv_and(a, b);
    case FREP_OP_OR: return iv_or(a, b);
    case FREP_OP_RUNI: return iv_mono2(iv_runi_f, a, b);
    case FREP_OP_RINT: return iv_mono2(iv_rint_f, a, b);
    case FREP_OP_RSUB: return iv_mono2(iv_rint_f, a, iv(-b.hi, -b.lo));
    case FREP_OP_MSUB: return iv(fmin(a.lo, -b.hi), fmin(a.hi, -b.lo));
    case FREP_OP_AUNI: case FREP_OP_AINT: return iv_ralpha(op, a, b, k);
    case FREP_OP_SELECT: return iv_select(v[0], v[1], v[2]);
    case FREP_OP_CONST: case FREP_OP_X: case FREP_OP_PARAM: case FREP_OP_LOAD:
    case FREP_OP_PRIM: case FREP_OP_STORE: case FREP_OP_JMP: case FREP_OP_JZ:
    case FREP_OP_LOADI: case FREP_OP_STOREI: case FREP_OP__COUNT:
        break;
    }
    return iv_entire();
}

/* The 1-based slot range an index interval may select in an array of size k;
 * returns 0 when the interval holds an index out of range (opsem_bad_index): the
 * point evaluators give NaN there (a LOADI's value, a STOREI's whole result), so no
 * enclosure, and no sign, can be claimed for the box. */
static int iv_index_range(ival i, double k, uint32_t *first, uint32_t *last)
{
    double lo = trunc(i.lo), hi = trunc(i.hi);
    if (opsem_bad_index(i.lo, k) || opsem_bad_index(i.hi, k)) return 0;
    *first = (uint32_t)lo - 1;
    *last = (uint32_t)hi - 1;
    return 1;
}

/* LOADI over the index interval *idx (replaced by the hull of every element it may
 * select); 0 when an index may be out of range or the array leaves the slots. */
static int iv_loadi(const frep_program *p, const vm_iscratch *s, const frep_insn *in,
                    ival *idx)
{
    uint32_t first, last;
    if (!iv_index_range(*idx, in->k, &first, &last) || (uint64_t)in->arg + last >= p->nslots)
        return 0;
    ival r = s->slots[in->arg + first];
    for (uint32_t j = first + 1; j <= last; j++) r = iv_hull(r, s->slots[in->arg + j]);
    *idx = r;
    return 1;
}

/* STOREI of val at the index interval idx; 0 as iv_loadi. */
static int iv_storei(const frep_program *p, vm_iscratch *s, const frep_insn *in, ival idx,
                     ival val)
{
    uint32_t first, last;
    if (!iv_index_range(idx, in->k, &first, &last) || (uint64_t)in->arg + last >= p->nslots)
        return 0;
    /* An undecided index may write any candidate slot: each keeps the hull. */
    for (uint32_t j = first; j <= last; j++) {
        ival *slot = &s->slots[in->arg + j];
        *slot = first == last ? val : iv_hull(*slot, val);
    }
    return 1;
}

/* An operator (unary, binary, binary with an immediate, SELECT): pop its operands from
 * st[0..*sp), push ival_op of them in push order; 0 on a stack underflow. */
static int iv_operator(ival *st, uint32_t *sp, const frep_insn *in)
{
    frep_opcode op = (frep_opcode)in->op;
    uint32_t nin = (uint32_t)insn_nin(in), j = 0;
    ival v[3] = { { 0, 0 }, { 0, 0 }, { 0, 0 } };
    if (*sp < nin) return 0;
    *sp -= nin;
    if (op_nin(op) == 2 && (in->flags & INSN_KA)) v[j++] = iv_exact(in->k);
    for (uint32_t i = 0; i < nin; i++) v[j++] = st[*sp + i];
    if (op_nin(op) == 2 && (in->flags & INSN_KB)) v[j++] = iv_exact(in->k);
    st[(*sp)++] = ival_op(op, v, in->k);
    return 1;
}

/* Give up on a bound: the result is [-inf, inf] (no error). */
#define IV_UNKNOWN_UNLESS(c) \
    do {                     \
        if (!(c)) return 0;  \
    } while (0)

/* The interval evaluator; trace (may be NULL; p->ncode entries) receives the value
 * each instruction pushes.  The stack effects are checked as it runs (a program the
 * point evaluators reject gives [-inf, inf] here); ival_op holds the interval rule of
 * each operator. */
static int interval_body(const frep_program *p, vm_iscratch *s, const double box[6],
                         const double *params, ival *out, ival *trace)
{
    *out = iv_entire();
    if (p->max_stack + 1 > s->nstack || p->nslots + 1 > s->nslots) return -1;
    if (p->flags & PROG_HAS_PRIMS) return 0;
    ival *st = s->stack;
    uint32_t sp = 0;
    for (uint32_t i = 0; i < p->nslots; i++) s->slots[i] = iv(0, 0);
    for (uint32_t pc = 0; pc < p->ncode;) {
        const frep_insn *in = &p->code[pc];
        uint32_t next = pc + 1;
        switch ((frep_opcode)in->op) {
        case FREP_OP_CONST: st[sp++] = iv_exact(in->k); break;
        case FREP_OP_X:
            IV_UNKNOWN_UNLESS(in->arg <= 2);
            st[sp++] = iv(box[in->arg], box[in->arg + 3]);
            break;
        case FREP_OP_PARAM:
            IV_UNKNOWN_UNLESS(in->arg < p->nparams);
            st[sp++] = iv_exact(params ? params[in->arg] : p->params[in->arg].value);
            break;
        case FREP_OP_LOAD:
            IV_UNKNOWN_UNLESS(in->arg < p->nslots);
            st[sp++] = s->slots[in->arg];
            break;
        case FREP_OP_PRIM: return 0;
        case FREP_OP_STORE:
            IV_UNKNOWN_UNLESS(in->arg < p->nslots && sp >= 1);
            s->slots[in->arg] = st[--sp];
            break;
        case FREP_OP_JMP:
            if (in->arg <= pc) {
                IV_UNKNOWN_UNLESS(++s->loops <= FREP_MAX_LOOP_ITERATIONS);
                /* the work budget, in batches as the point evaluators count */
                if (p->work && s->loops % (VM_WORK_BATCH / VM_WORK_BOX) == 0) {
                    atomic_fetch_add_explicit(&p->work->used, VM_WORK_BATCH,
                                              memory_order_relaxed);
                    IV_UNKNOWN_UNLESS(!prog_work_stop(p->work));
                }
            }
            next = in->arg;
            break;
        case FREP_OP_JZ:
            IV_UNKNOWN_UNLESS(sp >= 1);
            sp--;
            if (iv_surely_false(st[sp])) next = in->arg;
            else IV_UNKNOWN_UNLESS(iv_surely_true(st[sp])); /* undecided branch */
            break;
        case FREP_OP_LOADI: IV_UNKNOWN_UNLESS(sp >= 1 && iv_loadi(p, s, in, &st[sp - 1])); break;
        case FREP_OP_STOREI:
            IV_UNKNOWN_UNLESS(sp >= 2);
            sp -= 2;
            IV_UNKNOWN_UNLESS(iv_storei(p, s, in, st[sp + 1], st[sp]));
            break;
        case FREP_OP_NEG: case FREP_OP_NOT: case FREP_OP_ABS: case FREP_OP_SQRT:
        case FREP_OP_SQUARE: case FREP_OP_EXP: case FREP_OP_LOG: case FREP_OP_LOGD:
        case FREP_OP_SIN: case FREP_OP_COS: case FREP_OP_TAN: case FREP_OP_ASIN:
        case FREP_OP_ACOS: case FREP_OP_ATAN: case FREP_OP_SINH: case FREP_OP_COSH:
        case FREP_OP_TANH: case FREP_OP_SIGN: case FREP_OP_CEIL: case FREP_OP_FLOOR:
        case FREP_OP_INT: case FREP_OP_FRAC:
        case FREP_OP_ADD: case FREP_OP_SUB: case FREP_OP_MUL: case FREP_OP_DIV:
        case FREP_OP_POW: case FREP_OP_MOD: case FREP_OP_MIN: case FREP_OP_MAX:
        case FREP_OP_ATAN2: case FREP_OP_EQ: case FREP_OP_NE: case FREP_OP_LT:
        case FREP_OP_LE: case FREP_OP_GT: case FREP_OP_GE: case FREP_OP_AND:
        case FREP_OP_OR: case FREP_OP_RUNI: case FREP_OP_RINT: case FREP_OP_RSUB:
        case FREP_OP_MSUB: case FREP_OP_AUNI: case FREP_OP_AINT: case FREP_OP_SELECT:
            IV_UNKNOWN_UNLESS(iv_operator(st, &sp, in));
            break;
        case FREP_OP__COUNT:
        default:
            return 0;
        }
        if (sp > s->nstack) return 0;
        if (trace && sp >= 1) trace[pc] = st[sp - 1];
        pc = next;
    }
    if (sp >= 1) *out = iv_fix(st[sp - 1]);
    return 0;
}

/* interval_body, its loop iterations counted in p's work budget (VM_WORK_BOX each);
 * once the budget is spent, a program with loops gives [-inf, inf]. */
static int interval_run(const frep_program *p, vm_iscratch *s, const double box[6],
                        const double *params, ival *out, ival *trace)
{
    if (p->work && (p->flags & PROG_HAS_BRANCHES) && prog_work_stop(p->work)) {
        *out = iv_entire();
        return 0;
    }
    s->loops = 0;
    int rc = interval_body(p, s, box, params, out, trace);
    uint64_t rest = (uint64_t)(s->loops % (VM_WORK_BATCH / VM_WORK_BOX));
    if (p->work && rest)
        atomic_fetch_add_explicit(&p->work->used, rest * VM_WORK_BOX, memory_order_relaxed);
    return rc;
}

int vm_eval_interval(const frep_program *p, vm_iscratch *s, const double box[6],
                     const double *params, ival *out)
{
    return interval_run(p, s, box, params, out, NULL);
}

/* ---- tape pruning ---------------------------------------------------------------
 * Over a box, a set operation whose interval operands decide it can be replaced by
 * one operand.  min/max (and min(a, -b)) keep their values exactly.  The R-functions
 * keep only the sign: a | b with b < 0 on the box has the sign of a, the same zero
 * set and, on it, the same gradient (d/db = 1 + b/|b| = 0 there); likewise a & b with
 * b > 0 and a \ b with b < 0 (a \ b with a > 0 is -b).  So an R-function is pruned
 * only where its value reaches the result through sign-preserving operations alone
 * (set operations, negation, variables read only by those): the zero set, the
 * inside/outside of every point and the surface normals do not change, the values
 * off the surface may.  A dropped operand must not contain a domain check (its
 * errors and NaNs must still be seen) nor a store.  Stores nobody reads any more are
 * removed with the code computing their values. */

enum { PR_NONE, PR_KEEP_A, PR_KEEP_B, PR_KEEP_NEG_B };

/* Relative size of the values whose sign pruning may change through rounding: far
 * above the rounding error of thousands of operations (1e-13 relative), far below
 * any value a sampled grid point has off the surface. */
#define VM_PRUNE_MARGIN 1e-8

struct vm_pruner {
    const frep_program *p;
    uint32_t n;
    uint32_t *a0, *b0;       /* operand starts of a prunable set operation (else 0) */
    uint8_t *kind;           /* 0: not prunable; 1: exact (min/max); 2: sign (R0) */
    uint32_t *ndomain;       /* prefix counts: domain ops, stores in code[0..pc) */
    uint32_t *nstore;
    uint32_t *vstart;        /* STORE: start of the stored value's subtree */
    ival *trace;             /* scratch of vm_prune: one per pruner, hence per thread */
    uint8_t *keep, *neg, *live;
};

void vm_pruner_free(vm_pruner *r)
{
    if (!r) return;
    frep_free(r->a0);
    frep_free(r->b0);
    frep_free(r->kind);
    frep_free(r->ndomain);
    frep_free(r->nstore);
    frep_free(r->vstart);
    frep_free(r->trace);
    frep_free(r->keep);
    frep_free(r->neg);
    frep_free(r->live);
    frep_free(r);
}

/* Straight-line code without arrays indexed at run time or cached primitives: what
 * the analysis below can follow. */
static int pr_supported(const frep_program *p)
{
    if (!p || !p->code || p->ncode == 0 || (p->flags & (PROG_HAS_BRANCHES | PROG_HAS_PRIMS)))
        return 0;
    for (uint32_t pc = 0; pc < p->ncode; pc++) {
        frep_opcode op = (frep_opcode)p->code[pc].op;
        if (op == FREP_OP_LOADI || op == FREP_OP_STOREI || op == FREP_OP_JMP ||
            op == FREP_OP_JZ || op == FREP_OP_PRIM || op >= FREP_OP__COUNT)
            return 0;
    }
    return 1;
}

/* The data flow of a program, needed only while its pruner is built. */
typedef struct pr_flow {
    uint32_t *producer;      /* stack of producing pcs */
    uint32_t *consumer;      /* pc popping the value of pc (n: the result; PR_NOBODY) */
    uint32_t *reads;         /* LOAD: the STORE it reads (PR_NOBODY: none) */
    uint32_t *last;          /* per slot: its last STORE so far */
    uint8_t *sign;           /* only the value's sign reaches the result */
    uint8_t *store_ok;       /* STORE: every LOAD of it passes on only the sign */
} pr_flow;

#define PR_NOBODY UINT32_MAX

static void pr_flow_free(pr_flow *f)
{
    frep_free(f->producer);
    frep_free(f->consumer);
    frep_free(f->reads);
    frep_free(f->last);
    frep_free(f->sign);
    frep_free(f->store_ok);
}

static int pr_flow_alloc(pr_flow *f, uint32_t n, uint32_t nslots)
{
    f->producer = frep_malloc((n + 1) * sizeof *f->producer);
    f->consumer = frep_malloc((n + 1) * sizeof *f->consumer);
    f->reads = frep_malloc((n + 1) * sizeof *f->reads);
    f->last = frep_malloc((nslots + 1) * sizeof *f->last);
    f->sign = frep_malloc(n + 1);
    f->store_ok = frep_malloc(n + 1);
    return f->producer && f->consumer && f->reads && f->last && f->sign && f->store_ok ? 0 : -1;
}

static vm_pruner *pr_alloc(const frep_program *p)
{
    uint32_t n = p->ncode;
    vm_pruner *r = frep_calloc(1, sizeof *r);
    if (!r) return NULL;
    r->p = p;
    r->n = n;
    r->a0 = frep_calloc(n, sizeof *r->a0);
    r->b0 = frep_calloc(n, sizeof *r->b0);
    r->kind = frep_calloc(n, 1);
    r->ndomain = frep_malloc((n + 1) * sizeof *r->ndomain);
    r->nstore = frep_malloc((n + 1) * sizeof *r->nstore);
    r->vstart = frep_calloc(n, sizeof *r->vstart);
    r->trace = frep_malloc(n * sizeof *r->trace);
    r->keep = frep_malloc(n);
    r->neg = frep_malloc(n);
    r->live = frep_malloc(p->nslots + 1);
    if (!r->a0 || !r->b0 || !r->kind || !r->ndomain || !r->nstore || !r->vstart || !r->trace ||
        !r->keep || !r->neg || !r->live) {
        vm_pruner_free(r);
        return NULL;
    }
    return r;
}

/* Forward: who consumes each value, which store each load reads, where each stored
 * value starts, and the prefix counts of domain ops and stores.  -1 on a malformed
 * program. */
static int pr_forward(vm_pruner *r, pr_flow *f)
{
    const frep_program *p = r->p;
    uint32_t n = r->n, sp = 0;
    for (uint32_t j = 0; j <= p->nslots; j++) f->last[j] = PR_NOBODY;
    r->ndomain[0] = r->nstore[0] = 0;
    for (uint32_t pc = 0; pc < n; pc++) {
        const frep_insn *in = &p->code[pc];
        frep_opcode op = (frep_opcode)in->op;
        int nin = insn_nin(in);
        if ((uint32_t)nin > sp || in->arg > p->nslots) return -1;
        for (int i = 0; i < nin; i++) f->consumer[f->producer[--sp]] = pc;
        f->consumer[pc] = PR_NOBODY;
        f->reads[pc] = PR_NOBODY;
        if (op == FREP_OP_LOAD) f->reads[pc] = f->last[in->arg];
        if (op == FREP_OP_STORE) {
            f->last[in->arg] = pc;
            r->vstart[pc] = pc > 0 ? prog_subtree_start(p->code, pc - 1) : 0;
        }
        if (op_pushes(op)) f->producer[sp++] = pc;
        r->ndomain[pc + 1] = r->ndomain[pc] + ((op_flags(op) & OPF_DOMAIN) != 0);
        r->nstore[pc + 1] = r->nstore[pc] + (op == FREP_OP_STORE);
    }
    /* the values left on the stack are the result: their sign is what counts */
    for (uint32_t i = 0; i < sp; i++) f->consumer[f->producer[i]] = n;
    return 0;
}

/* Backward: is each value used only through sign-preserving operations (set
 * operations, negation, stores whose loads are)? */
static void pr_backward(const vm_pruner *r, pr_flow *f)
{
    const frep_program *p = r->p;
    uint32_t n = r->n;
    for (uint32_t pc = 0; pc < n; pc++) f->store_ok[pc] = 1;
    for (uint32_t pc = n; pc-- > 0;) {
        frep_opcode op = (frep_opcode)p->code[pc].op;
        uint32_t c = f->consumer[pc];
        int ok = 0;
        if (op == FREP_OP_STORE) {
            f->sign[pc] = f->store_ok[pc];
            continue;
        }
        if (c == n) {
            ok = 1;
        } else if (c != PR_NOBODY) {
            frep_opcode cop = (frep_opcode)p->code[c].op;
            if (cop == FREP_OP_RUNI || cop == FREP_OP_RINT || cop == FREP_OP_RSUB ||
                cop == FREP_OP_MIN || cop == FREP_OP_MAX || cop == FREP_OP_MSUB ||
                cop == FREP_OP_NEG || cop == FREP_OP_STORE)
                ok = f->sign[c];
        }
        f->sign[pc] = (uint8_t)ok;
        if (op == FREP_OP_LOAD && f->reads[pc] != PR_NOBODY && !ok) f->store_ok[f->reads[pc]] = 0;
    }
}

/* The prunable set operations: min/max always (exact), R-functions when only their
 * sign matters; their operand ranges a0..b0-1 and b0..pc-1. */
static void pr_set_operations(vm_pruner *r, const pr_flow *f)
{
    const frep_program *p = r->p;
    for (uint32_t pc = 0; pc < r->n; pc++) {
        const frep_insn *in = &p->code[pc];
        frep_opcode op = (frep_opcode)in->op;
        int k = 0;
        if (op == FREP_OP_MIN || op == FREP_OP_MAX || op == FREP_OP_MSUB) k = 1;
        else if ((op == FREP_OP_RUNI || op == FREP_OP_RINT || op == FREP_OP_RSUB) && f->sign[pc])
            k = 2;
        if (!k || (in->flags & (INSN_KA | INSN_KB)) || pc < 2) continue;
        uint32_t b0 = prog_subtree_start(p->code, pc - 1);
        if (b0 == 0) continue;
        uint32_t a0 = prog_subtree_start(p->code, b0 - 1);
        r->a0[pc] = a0;
        r->b0[pc] = b0;
        r->kind[pc] = (uint8_t)k;
    }
}

int vm_pruner_create(const frep_program *p, vm_pruner **out)
{
    pr_flow f;
    vm_pruner *r;
    *out = NULL;
    if (!pr_supported(p)) return 0;
    memset(&f, 0, sizeof f);
    r = pr_alloc(p);
    if (!r || pr_flow_alloc(&f, p->ncode, p->nslots) < 0) {
        pr_flow_free(&f);
        vm_pruner_free(r);
        return -1;
    }
    if (pr_forward(r, &f) < 0) {
        pr_flow_free(&f);
        vm_pruner_free(r);
        return 0;
    }
    pr_backward(r, &f);
    pr_set_operations(r, &f);
    pr_flow_free(&f);
    *out = r;
    return 0;
}

vm_pruner *vm_pruner_new(const frep_program *p)
{
    vm_pruner *r;
    return vm_pruner_create(p, &r) == 0 ? r : NULL;
}

/* May the code [from, to) be dropped? */
static int pr_droppable(const vm_pruner *r, uint32_t from, uint32_t to)
{
    return r->ndomain[to] == r->ndomain[from] && r->nstore[to] == r->nstore[from];
}

/* Rounding: the original and the pruned program may disagree on the sign of values
 * within their rounding errors of 0.  Those are below VM_PRUNE_MARGIN x the largest
 * intermediate magnitude S; an R-function is pruned only when the dropped operand
 * keeps its sign by more than T = VM_PRUNE_MARGIN S, and the caller re-evaluates
 * values smaller than T with the original program. */
static double pr_sign_tol(const vm_pruner *r)
{
    double S = 0;
    for (uint32_t pc = 0; pc < r->n; pc++) {
        if (isfinite(r->trace[pc].lo)) S = fmax(S, fabs(r->trace[pc].lo));
        if (isfinite(r->trace[pc].hi)) S = fmax(S, fabs(r->trace[pc].hi));
    }
    return VM_PRUNE_MARGIN * S;
}

/* Which operand decides set operation op over the box, given its operands' intervals
 * A and B (PR_NONE: neither). */
static int pr_decision(frep_opcode op, ival A, ival B, double T)
{
    switch ((unsigned)op) { /* not an enum switch: only the prunable set operations */
    case FREP_OP_RUNI:
        if (B.hi < -T) return PR_KEEP_A;
        if (A.hi < -T) return PR_KEEP_B;
        break;
    case FREP_OP_RINT:
        if (B.lo > T) return PR_KEEP_A;
        if (A.lo > T) return PR_KEEP_B;
        break;
    case FREP_OP_RSUB:
        if (B.hi < -T) return PR_KEEP_A;
        if (A.lo > T) return PR_KEEP_NEG_B;
        break;
    case FREP_OP_MIN:
        if (A.hi < B.lo) return PR_KEEP_A;
        if (B.hi < A.lo) return PR_KEEP_B;
        break;
    case FREP_OP_MAX:
        if (A.lo > B.hi) return PR_KEEP_A;
        if (B.lo > A.hi) return PR_KEEP_B;
        break;
    case FREP_OP_MSUB: /* min(a, -b) */
        if (A.hi < -B.hi) return PR_KEEP_A;
        if (-B.lo < A.lo) return PR_KEEP_NEG_B;
        break;
    default:
        break;
    }
    return PR_NONE;
}

/* Decide every set operation still kept, in program order, dropping the code of the
 * operand it does not need (when that code may be dropped).  Returns 1 if any was. */
static int pr_decide_all(vm_pruner *r, double T)
{
    int changed = 0;
    memset(r->keep, 1, r->n);
    memset(r->neg, 0, r->n);
    for (uint32_t pc = 0; pc < r->n; pc++) {
        if (!r->kind[pc] || !r->keep[pc]) continue;
        ival A = r->trace[r->b0[pc] - 1], B = r->trace[pc - 1];
        int d = pr_decision((frep_opcode)r->p->code[pc].op, A, B, T);
        uint32_t a0 = r->a0[pc], b0 = r->b0[pc];
        if (d == PR_KEEP_A && pr_droppable(r, b0, pc)) {
            memset(r->keep + b0, 0, pc + 1 - b0);
            changed = 1;
        } else if ((d == PR_KEEP_B || d == PR_KEEP_NEG_B) && pr_droppable(r, a0, b0)) {
            memset(r->keep + a0, 0, b0 - a0);
            if (d == PR_KEEP_B) r->keep[pc] = 0;
            else r->neg[pc] = 1;
            changed = 1;
        }
    }
    return changed;
}

/* Drop the stores nobody reads any more, with the code of their values. */
static void pr_dead_stores(vm_pruner *r)
{
    const frep_program *p = r->p;
    memset(r->live, 0, p->nslots + 1);
    for (uint32_t pc = r->n; pc-- > 0;) {
        if (!r->keep[pc]) continue;
        const frep_insn *in = &p->code[pc];
        if (in->op == FREP_OP_STORE) {
            if (!r->live[in->arg] && pr_droppable(r, r->vstart[pc], pc) &&
                r->ndomain[pc] == r->ndomain[r->vstart[pc]]) {
                memset(r->keep + r->vstart[pc], 0, pc + 1 - r->vstart[pc]);
                continue;
            }
            r->live[in->arg] = 0;
        } else if (in->op == FREP_OP_LOAD) {
            r->live[in->arg] = 1;
        }
    }
}

/* Write the kept instructions (a set operation decided for -b becomes NEG). */
static uint32_t pr_emit(const vm_pruner *r, frep_insn *code, frep_srcpos *pos, uint32_t *orig)
{
    const frep_program *p = r->p;
    uint32_t m = 0;
    for (uint32_t pc = 0; pc < r->n; pc++) {
        if (!r->keep[pc]) continue;
        code[m] = p->code[pc];
        if (r->neg[pc]) {
            code[m].op = FREP_OP_NEG;
            code[m].flags = 0;
            code[m].arg = 0;
            code[m].k = 0;
        }
        pos[m] = p->pos ? p->pos[pc] : (frep_srcpos){ 0, 0, 0 };
        orig[m] = pc;
        m++;
    }
    return m;
}

int vm_prune(vm_pruner *r, vm_iscratch *s, const double box[6], const double *params,
             frep_insn *code, frep_srcpos *pos, uint32_t *orig, uint32_t *ncode, ival *out,
             double *sign_tol)
{
    for (uint32_t pc = 0; pc < r->n; pc++) r->trace[pc] = iv_entire();
    if (interval_run(r->p, s, box, params, out, r->trace) != 0) return -1;
    *sign_tol = pr_sign_tol(r);
    if (pr_decide_all(r, *sign_tol)) pr_dead_stores(r);
    *ncode = pr_emit(r, code, pos, orig);
    return 0;
}

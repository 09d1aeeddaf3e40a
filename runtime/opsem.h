/* opsem.h - the reference scalar semantics of every opcode of ops.h, and its
 * derivative rules.
 *
 * The compiler's constant folder (lang/ir.c), the block evaluators (runtime/vm*.c) and
 * the tests all call these inline functions, so a folded constant equals what the VM
 * would have computed, bit for bit.  Nothing here allocates or has state.
 */
#ifndef FREP_OPSEM_H
#define FREP_OPSEM_H

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "ops.h"

/* The dispatch functions below are large switches that fold to one case when the
 * opcode is a constant; forcing them inline lets the evaluators' loops vectorize. */
#if defined(__GNUC__)
#define OPSEM_INLINE static inline __attribute__((always_inline))
#else
#define OPSEM_INLINE static inline
#endif

/* ln(10), for the derivative of log10 (M_LN10 is not ISO C). */
#define OPSEM_LN10 2.30258509299404568402

/* ---- sine and cosine --------------------------------------------------------
 * frep's own sin and cos: libm's are calls the evaluators' lane loops cannot
 * vectorize (they were 40% of the time of meshing a gyroid).  opsem_sincos_fast() is
 * branch-free straight-line arithmetic, so a loop over it compiles to AVX2 code, and
 * the scalar opsem_sin/opsem_cos run the same operations: the VM, the tangent VM and
 * the constant folder agree bit for bit (no FMA contraction: the x86-64 builds do not
 * enable FMA, see vm_internal.h).
 *  - Reduction: k = round(a 2/pi) (adding 1.5 * 2^52 rounds to an integer, whose low
 *    bits are the quadrant), r = a - k pi/2 with pi/2 split Cody-Waite style into
 *    three 33-bit parts and a tail: for |k| < 2^20 each k * part is exact and
 *    a - k P1 is exact, so r keeps its relative accuracy even next to a multiple of
 *    pi/2 (the closest double there is ~2^-60 away).
 *  - Kernels on |r| <= pi/4: the minimax polynomials of fdlibm's __kernel_sin (degree
 *    13) and __kernel_cos (degree 14), published coefficients; tiny r returns r itself
 *    (sin(-0) = -0, subnormals exact).
 *  - Accuracy: within OPSEM_TRIG_ULPS ulp of glibc's sin and cos (themselves within
 *    an ulp of exact); tests/test_vm.c checks it, and 2 ulp is the most seen over 12
 *    million arguments; |sin|, |cos| <= 1.
 *  - |a| > OPSEM_TRIG_MAX, inf and NaN: libm's sin and cos (opsem_trig_slow tells
 *    which lanes; the evaluators patch those lanes after their vector loop). */
#define OPSEM_TRIG_MAX 1.0e6  /* |k| = |round(a 2/pi)| < 2^20: k times a 33-bit part of
                                 pi/2 fits the 53-bit significand exactly */
#define OPSEM_TRIG_ULPS 3     /* documented bound on the difference from glibc */

/* The reduction needs double arithmetic rounded to double (FLT_EVAL_METHOD 0: SSE2,
 * AArch64, ...); with x87 extended precision every argument takes libm's path. */
#if defined(FLT_EVAL_METHOD) && FLT_EVAL_METHOD == 0
#define OPSEM_TRIG_FAST 1
#else
#define OPSEM_TRIG_FAST 0
#endif

static inline int opsem_trig_slow(double a)
{
    return !OPSEM_TRIG_FAST || !(fabs(a) <= OPSEM_TRIG_MAX);
}

/* sin(a) and cos(a) for |a| <= OPSEM_TRIG_MAX (other arguments give some finite or
 * NaN garbage, never undefined behaviour). */
static inline void opsem_sincos_fast(double a, double *sinv, double *cosv)
{
    const double two_over_pi = 6.36619772367581382433e-01;
    const double round_magic = 6755399441055744.0;        /* 1.5 * 2^52 */
    const double p1 = 1.57079632673412561417e+00;         /* first 33 bits of pi/2 */
    const double p2 = 6.07710050630396597660e-11;         /* next 33 bits */
    const double p3 = 2.02226624871116645580e-21;         /* next 33 bits */
    const double p3t = 8.47842766036889956997e-32;        /* pi/2 - p1 - p2 - p3 */
    const double S1 = -1.66666666666666324348e-01, S2 = 8.33333333332248946124e-03,
                 S3 = -1.98412698298579493134e-04, S4 = 2.75573137070700676789e-06,
                 S5 = -2.50507602534068634195e-08, S6 = 1.58969099521155010221e-10;
    const double C1 = 4.16666666666666019037e-02, C2 = -1.38888888888741095749e-03,
                 C3 = 2.48015872894767294178e-05, C4 = -2.75573143513906633035e-07,
                 C5 = 2.08757232129817482790e-09, C6 = -1.13596475577881948265e-11;
    double t = a * two_over_pi + round_magic;
    double k = t - round_magic;
    uint64_t bits;
    memcpy(&bits, &t, sizeof bits);
    double r = a - k * p1;
    r = r - k * p2;
    r = r - k * p3;
    r = r - k * p3t;
    double z = r * r, w = z * z;
    double ps = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)));
    double s = r + z * r * (S1 + z * ps);
    double pc = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    double hz = 0.5 * z, c1 = 1.0 - hz;
    double c = c1 + (((1.0 - c1) - hz) + z * pc);
    /* quadrant q = k mod 4: sin a = s, c, -s, -c; cos a = c, -s, -c, s.  Chosen with
     * bit masks on the representations: GCC vectorizes these, not the ternaries. */
    uint64_t sb, cb, rb, odd = (uint64_t)0 - (bits & 1u);
    memcpy(&sb, &s, sizeof sb);
    memcpy(&cb, &c, sizeof cb);
    memcpy(&rb, &r, sizeof rb);
    /* |r| < 2^-27: sin r = r within half an ulp (keeps sin(-0) = -0, subnormals) */
    uint64_t tiny = (uint64_t)0 - (uint64_t)((int64_t)(rb & 0x7FFFFFFFFFFFFFFFu) <
                                             (int64_t)0x3E40000000000000);
    sb = (sb & ~tiny) | (rb & tiny);
    uint64_t rs = ((sb & ~odd) | (cb & odd)) ^ ((bits & 2u) << 62);
    uint64_t rc = ((cb & ~odd) | (sb & odd)) ^ (((bits + 1u) & 2u) << 62);
    memcpy(sinv, &rs, sizeof rs);
    memcpy(cosv, &rc, sizeof rc);
}

static inline double opsem_sin(double a)
{
    double s, c;
    if (opsem_trig_slow(a)) return sin(a);
    opsem_sincos_fast(a, &s, &c);
    return s;
}

static inline double opsem_cos(double a)
{
    double s, c;
    if (opsem_trig_slow(a)) return cos(a);
    opsem_sincos_fast(a, &s, &c);
    return c;
}

/* ---- values ---------------------------------------------------------------
 * NaN conventions:
 *  - NaN operands propagate through arithmetic, min/max and set operations.
 *  - Comparisons follow IEEE 754: any comparison with NaN is false (so NE gives 1).
 *  - Logic treats every nonzero value, NaN included, as true; JZ jumps only on 0.
 *  - A domain error (opsem_bad_* below is true) gives NaN; the evaluator also records
 *    a diagnostic unless the instruction carries INSN_QUIET.  A NaN operand is not a
 *    domain error: only the operation that creates a NaN reports it.
 */

static inline double opsem_neg(double a) { return -a; }
static inline double opsem_not(double a) { return a == 0 ? 1.0 : 0.0; }
static inline double opsem_abs(double a) { return fabs(a); }
/* sqrt of a negative number is NaN in IEEE arithmetic already. */
static inline double opsem_sqrt(double a) { return sqrt(a); }
static inline double opsem_square(double a) { return a * a; }
static inline double opsem_exp(double a) { return exp(a); }
/* log(0) would be -inf; frep treats a <= 0 as a domain error (NaN), as documented. */
static inline double opsem_log(double a) { return a > 0 ? log(a) : (a <= 0 ? NAN : a); }
static inline double opsem_logd(double a) { return a > 0 ? log10(a) : (a <= 0 ? NAN : a); }
static inline double opsem_tan(double a) { return tan(a); }
static inline double opsem_asin(double a) { return asin(a); }
static inline double opsem_acos(double a) { return acos(a); }
static inline double opsem_atan(double a) { return atan(a); }
static inline double opsem_sinh(double a) { return sinh(a); }
static inline double opsem_cosh(double a) { return cosh(a); }
static inline double opsem_tanh(double a) { return tanh(a); }
/* sign(0) = 0 (the reference HyperFun returns 1 for everything: a bug); sign(NaN) = NaN. */
static inline double opsem_sign(double a) { return a > 0 ? 1.0 : (a < 0 ? -1.0 : a * 0.0); }
static inline double opsem_ceil(double a) { return ceil(a); }
static inline double opsem_floor(double a) { return floor(a); }
static inline double opsem_int(double a) { return trunc(a); }
/* frac(+-inf) is NaN (inf - inf): there is no fractional part to give. */
static inline double opsem_frac(double a) { return a - trunc(a); }

static inline double opsem_add(double a, double b) { return a + b; }
static inline double opsem_sub(double a, double b) { return a - b; }
static inline double opsem_mul(double a, double b) { return a * b; }
/* Division by exactly 0 is a domain error with a NaN result, not +-inf: an infinite
 * field value would silently poison every set operation above it. */
static inline double opsem_div(double a, double b) { return b != 0 ? a / b : NAN; }
static inline double opsem_pow(double a, double b) { return pow(a, b); }
static inline double opsem_mod(double a, double b) { return fmod(a, b); }
/* min/max propagate NaN (fmin/fmax would drop it); on a tie they return a. */
static inline double opsem_min(double a, double b)
{
    double r = b < a ? b : a;
    return b != b ? b : r;
}
static inline double opsem_max(double a, double b)
{
    double r = b > a ? b : a;
    return b != b ? b : r;
}
static inline double opsem_atan2(double a, double b) { return atan2(a, b); }
static inline double opsem_eq(double a, double b) { return a == b ? 1.0 : 0.0; }
static inline double opsem_ne(double a, double b) { return a != b ? 1.0 : 0.0; }
static inline double opsem_lt(double a, double b) { return a < b ? 1.0 : 0.0; }
static inline double opsem_le(double a, double b) { return a <= b ? 1.0 : 0.0; }
static inline double opsem_gt(double a, double b) { return a > b ? 1.0 : 0.0; }
static inline double opsem_ge(double a, double b) { return a >= b ? 1.0 : 0.0; }
static inline double opsem_and(double a, double b) { return ((a != 0) & (b != 0)) ? 1.0 : 0.0; }
static inline double opsem_or(double a, double b) { return ((a != 0) | (b != 0)) ? 1.0 : 0.0; }
/* R0 functions with sqrt(a*a + b*b) as the reference writes them (not hypot: it is
 * several times slower and does not vectorize; overflow above ~1e154 gives inf). */
static inline double opsem_runi(double a, double b) { return a + b + sqrt(a * a + b * b); }
static inline double opsem_rint(double a, double b) { return a + b - sqrt(a * a + b * b); }
static inline double opsem_rsub(double a, double b) { return a - b - sqrt(a * a + b * b); }
static inline double opsem_msub(double a, double b) { return opsem_min(a, -b); }
/* R-alpha: the radicand a^2 + b^2 - 2k a b is >= 0 for |k| <= 1 in exact arithmetic;
 * rounding can make it slightly negative (k = 1, a = b), so it is clamped at 0. */
static inline double opsem_ralpha_root(double a, double b, double k)
{
    double s = a * a + b * b - 2.0 * k * a * b;
    return sqrt(s < 0 ? 0.0 : s);
}
static inline double opsem_auni(double a, double b, double k)
{
    return (a + b + opsem_ralpha_root(a, b, k)) / (1.0 + k);
}
static inline double opsem_aint(double a, double b, double k)
{
    return (a + b - opsem_ralpha_root(a, b, k)) / (1.0 + k);
}
/* c is true when nonzero (NaN included). */
static inline double opsem_select(double c, double a, double b) { return c != 0 ? a : b; }

/* ---- domain errors --------------------------------------------------------
 * True when the operation at these operands is a domain error.  Written without
 * branches so the evaluators can test whole lane vectors cheaply. */
static inline int opsem_bad_sqrt(double a) { return a < 0; }
static inline int opsem_bad_log(double a) { return a <= 0; }
static inline int opsem_bad_asin(double a) { return fabs(a) > 1; }
static inline int opsem_bad_div(double a, double b) { (void)a; return b == 0; }
/* pow: a negative base with a finite non-integer exponent has no real value. */
static inline int opsem_bad_pow(double a, double b)
{
    return (a < 0) & (b != trunc(b)) & (fabs(b) < INFINITY);
}
static inline int opsem_bad_mod(double a, double b) { (void)a; return b == 0; }

/* The 1-based array index i of LOADI/STOREI (array of size k): truncated toward zero
 * like the reference's integer conversion; valid when 1 <= i < k + 1 (NaN is not). */
static inline int opsem_bad_index(double i, double k) { return !((i >= 1) & (i < k + 1)); }

/* What a domain error of opcode op means, for diagnostics ("sqrt of a negative number
 * at 12 points, e.g. ..."). JMP reports the loop iteration limit. */
static inline const char *opsem_error_what(frep_opcode op)
{
    switch ((unsigned)op) { /* not an enum switch: most ops have no error */
    case FREP_OP_SQRT: return "sqrt of a negative number";
    case FREP_OP_LOG: return "log of a number <= 0";
    case FREP_OP_LOGD: return "logd of a number <= 0";
    case FREP_OP_ASIN: return "asin of a number outside [-1, 1]";
    case FREP_OP_ACOS: return "acos of a number outside [-1, 1]";
    case FREP_OP_DIV: return "division by zero";
    case FREP_OP_POW: return "negative number raised to a non-integer power";
    case FREP_OP_MOD: return "mod with divisor zero";
    case FREP_OP_LOADI: return "array index out of range";
    case FREP_OP_STOREI: return "array index out of range in assignment";
    case FREP_OP_JMP: return "loop iteration limit exceeded";
    default: return "domain error";
    }
}

/* Is op(a, b, c) a domain error? (Ops without OPF_DOMAIN: never.) */
OPSEM_INLINE int opsem_is_bad(frep_opcode op, double a, double b)
{
    switch ((unsigned)op) { /* not an enum switch: most ops have no error */
    case FREP_OP_SQRT: return opsem_bad_sqrt(a);
    case FREP_OP_LOG: case FREP_OP_LOGD: return opsem_bad_log(a);
    case FREP_OP_ASIN: case FREP_OP_ACOS: return opsem_bad_asin(a);
    case FREP_OP_DIV: return opsem_bad_div(a, b);
    case FREP_OP_POW: return opsem_bad_pow(a, b);
    case FREP_OP_MOD: return opsem_bad_mod(a, b);
    default: return 0;
    }
}

/* The value of an expression op (unary, binary or SELECT) at operands given in the
 * order they were pushed: v0 first.  For SELECT v0 is the condition, v1 the value
 * when true, v2 when false.  k is the immediate (alpha of AUNI/AINT).  *bad (may be
 * NULL) is set to 1 on a domain error, else left alone.  Leaves, stores and control
 * flow are not expressions: NaN. */
OPSEM_INLINE double op_scalar(frep_opcode op, double v0, double v1, double v2, double k,
                               int *bad)
{
    double a = v0, b = v1;
    if (bad && opsem_is_bad(op, a, b)) *bad = 1;
    switch (op) {
    case FREP_OP_NEG: return opsem_neg(a);
    case FREP_OP_NOT: return opsem_not(a);
    case FREP_OP_ABS: return opsem_abs(a);
    case FREP_OP_SQRT: return opsem_sqrt(a);
    case FREP_OP_SQUARE: return opsem_square(a);
    case FREP_OP_EXP: return opsem_exp(a);
    case FREP_OP_LOG: return opsem_log(a);
    case FREP_OP_LOGD: return opsem_logd(a);
    case FREP_OP_SIN: return opsem_sin(a);
    case FREP_OP_COS: return opsem_cos(a);
    case FREP_OP_TAN: return opsem_tan(a);
    case FREP_OP_ASIN: return opsem_asin(a);
    case FREP_OP_ACOS: return opsem_acos(a);
    case FREP_OP_ATAN: return opsem_atan(a);
    case FREP_OP_SINH: return opsem_sinh(a);
    case FREP_OP_COSH: return opsem_cosh(a);
    case FREP_OP_TANH: return opsem_tanh(a);
    case FREP_OP_SIGN: return opsem_sign(a);
    case FREP_OP_CEIL: return opsem_ceil(a);
    case FREP_OP_FLOOR: return opsem_floor(a);
    case FREP_OP_INT: return opsem_int(a);
    case FREP_OP_FRAC: return opsem_frac(a);
    case FREP_OP_ADD: return opsem_add(a, b);
    case FREP_OP_SUB: return opsem_sub(a, b);
    case FREP_OP_MUL: return opsem_mul(a, b);
    case FREP_OP_DIV: return opsem_div(a, b);
    case FREP_OP_POW: return opsem_pow(a, b);
    case FREP_OP_MOD: return opsem_mod(a, b);
    case FREP_OP_MIN: return opsem_min(a, b);
    case FREP_OP_MAX: return opsem_max(a, b);
    case FREP_OP_ATAN2: return opsem_atan2(a, b);
    case FREP_OP_EQ: return opsem_eq(a, b);
    case FREP_OP_NE: return opsem_ne(a, b);
    case FREP_OP_LT: return opsem_lt(a, b);
    case FREP_OP_LE: return opsem_le(a, b);
    case FREP_OP_GT: return opsem_gt(a, b);
    case FREP_OP_GE: return opsem_ge(a, b);
    case FREP_OP_AND: return opsem_and(a, b);
    case FREP_OP_OR: return opsem_or(a, b);
    case FREP_OP_RUNI: return opsem_runi(a, b);
    case FREP_OP_RINT: return opsem_rint(a, b);
    case FREP_OP_RSUB: return opsem_rsub(a, b);
    case FREP_OP_MSUB: return opsem_msub(a, b);
    case FREP_OP_AUNI: return opsem_auni(a, b, k);
    case FREP_OP_AINT: return opsem_aint(a, b, k);
    case FREP_OP_SELECT: return opsem_select(v0, v1, v2);
    case FREP_OP_CONST: case FREP_OP_X: case FREP_OP_PARAM: case FREP_OP_LOAD:
    case FREP_OP_PRIM: case FREP_OP_STORE: case FREP_OP_JMP: case FREP_OP_JZ:
    case FREP_OP_LOADI: case FREP_OP_STOREI: case FREP_OP__COUNT:
        break;
    }
    return NAN;
}

/* ---- derivative rules -----------------------------------------------------
 * op_partials() gives the partial derivatives d[0..2] of op with respect to its
 * operands (push order, as op_scalar), at operands v0..v2 with value r = op_scalar().
 * The tangent evaluator combines them (chain rule); where the derivative does not
 * exist frep defines it, so that gradients are finite wherever the value is:
 *  - min/max: on a tie, the derivative of the first operand (a).
 *  - abs at 0: 0.   sqrt at 0: 0 (the one-sided derivative is +inf).
 *  - R-functions and R-alpha: the root term contributes 0 where it is 0 (a = b = 0).
 *  - atan2 at (0, 0): 0.
 *  - pow: d/da at a = 0 is 0 when b < 1 (sqrt-like cusp) or b = 0 (constant);
 *    d/db is 0 when a <= 0 (only integer b is defined there).
 *  - comparisons, logic, not, sign, ceil, floor, int (OPF_NOGRAD): 0 everywhere,
 *    frac: 1, mod: d/da = 1, d/db = -trunc(a/b).
 *  - SELECT: the tangents of the chosen branch (evaluators copy them; the partials
 *    here say the same: 1 for the chosen operand, 0 otherwise).
 * Where the value is a domain error (NaN), the partials are NaN too. */
OPSEM_INLINE void op_partials(frep_opcode op, double v0, double v1, double v2, double k,
                               double r, double d[3])
{
    double a = v0, b = v1, s;
    d[0] = d[1] = d[2] = 0;
    switch (op) {
    case FREP_OP_NEG: d[0] = -1; break;
    case FREP_OP_ABS: d[0] = a > 0 ? 1.0 : (a < 0 ? -1.0 : 0.0); break;
    case FREP_OP_SQRT: d[0] = a > 0 ? 0.5 / (a > 0 ? r : 1.0) : (a == 0 ? 0.0 : NAN); break;
    case FREP_OP_SQUARE: d[0] = 2 * a; break;
    case FREP_OP_EXP: d[0] = r; break;
    case FREP_OP_LOG: d[0] = a > 0 ? 1 / (a > 0 ? a : 1.0) : NAN; break;
    case FREP_OP_LOGD: d[0] = a > 0 ? 1 / ((a > 0 ? a : 1.0) * OPSEM_LN10) : NAN; break;
    case FREP_OP_SIN: d[0] = opsem_cos(a); break;
    case FREP_OP_COS: d[0] = -opsem_sin(a); break;
    case FREP_OP_TAN: d[0] = 1 + r * r; break;
    case FREP_OP_ASIN: d[0] = 1 / sqrt(1 - a * a); break;
    case FREP_OP_ACOS: d[0] = -1 / sqrt(1 - a * a); break;
    case FREP_OP_ATAN: d[0] = 1 / (1 + a * a); break;
    case FREP_OP_SINH: d[0] = cosh(a); break;
    case FREP_OP_COSH: d[0] = sinh(a); break;
    case FREP_OP_TANH: d[0] = 1 - r * r; break;
    case FREP_OP_FRAC: d[0] = 1; break;
    case FREP_OP_ADD: d[0] = 1; d[1] = 1; break;
    case FREP_OP_SUB: d[0] = 1; d[1] = -1; break;
    case FREP_OP_MUL: d[0] = b; d[1] = a; break;
    case FREP_OP_DIV:
        s = 1 / (b != 0 ? b : 1.0);
        d[0] = b != 0 ? s : NAN;
        d[1] = b != 0 ? -r * s : NAN;
        break;
    case FREP_OP_POW:
        if (b == 0) d[0] = 0;
        else if (a == 0 && b < 1) d[0] = 0;
        else d[0] = b * pow(a, b - 1);
        d[1] = a > 0 ? r * log(a) : (a <= 0 ? 0.0 : NAN);
        break;
    case FREP_OP_MOD:
        d[0] = b != 0 ? 1.0 : NAN;
        d[1] = b != 0 ? -trunc(a / (b != 0 ? b : 1.0)) : NAN;
        break;
    case FREP_OP_MIN: if (b < a) d[1] = 1; else d[0] = 1; break;
    case FREP_OP_MAX: if (b > a) d[1] = 1; else d[0] = 1; break;
    case FREP_OP_MSUB: if (-b < a) d[1] = -1; else d[0] = 1; break;
    case FREP_OP_ATAN2:
        s = a * a + b * b;
        s = s > 0 ? 1 / (s > 0 ? s : 1.0) : 0.0;
        d[0] = b * s;
        d[1] = -a * s;
        break;
    case FREP_OP_RUNI: case FREP_OP_RINT: case FREP_OP_RSUB: {
        double sg = op == FREP_OP_RUNI ? 1.0 : -1.0;
        /* (divisions are written so that none is conditional: loops vectorize) */
        s = sqrt(a * a + b * b);
        s = s > 0 ? sg / (s > 0 ? s : 1.0) : 0.0;
        d[0] = 1 + a * s;
        d[1] = (op == FREP_OP_RSUB ? -1.0 : 1.0) + b * s;
        break;
    }
    case FREP_OP_AUNI: case FREP_OP_AINT: {
        double sg = op == FREP_OP_AUNI ? 1.0 : -1.0;
        s = opsem_ralpha_root(a, b, k);
        s = s > 0 ? sg / (s > 0 ? s : 1.0) : 0.0;
        d[0] = (1 + (a - k * b) * s) / (1 + k);
        d[1] = (1 + (b - k * a) * s) / (1 + k);
        break;
    }
    case FREP_OP_SELECT:
        if (v0 != 0) d[1] = 1; else d[2] = 1;
        break;
    case FREP_OP_NOT: case FREP_OP_SIGN: case FREP_OP_CEIL: case FREP_OP_FLOOR:
    case FREP_OP_INT: case FREP_OP_EQ: case FREP_OP_NE: case FREP_OP_LT: case FREP_OP_LE:
    case FREP_OP_GT: case FREP_OP_GE: case FREP_OP_AND: case FREP_OP_OR:
        break;
    case FREP_OP_CONST: case FREP_OP_X: case FREP_OP_PARAM: case FREP_OP_LOAD:
    case FREP_OP_PRIM: case FREP_OP_STORE: case FREP_OP_JMP: case FREP_OP_JZ:
    case FREP_OP_LOADI: case FREP_OP_STOREI: case FREP_OP__COUNT:
        break;
    }
    (void)v2;
}

#endif

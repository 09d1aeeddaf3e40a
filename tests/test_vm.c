/* test_vm.c - property tests of the bytecode evaluators (runtime/vm*.c), driven by
 * the opcode table: every opcode against its opsem.h reference at awkward arguments,
 * tangents against central differences, batch against single point, branches, loops,
 * domain errors and thread-count independence.  Programs are assembled with
 * prog_emit, so no compiler is needed.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "interval.h"
#include "opsem.h"
#include "program.h"
#include "tap.h"
#include "threads.h"
#include "vm.h"

#define NB FREP_BLOCK

static const frep_srcpos nopos = {0, 0, 0};

/* Deterministic xorshift generator: tests must not depend on the clock. */
static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double urand(double lo, double hi)
{
    return tap_urand(&rng_state, lo, hi);
}

/* Same bits, or both NaN. */
static int same(double a, double b)
{
    if (isnan(a) || isnan(b)) return isnan(a) && isnan(b);
    return memcmp(&a, &b, sizeof a) == 0;
}

static void emit(frep_program *p, frep_opcode op, uint32_t arg, double k, uint8_t fl)
{
    prog_emit(p, op, arg, k, fl, nopos);
}

static frep_program *finish(frep_program *p)
{
    if (prog_finish(p) != 0) {
        diag("prog_finish failed");
        frep_program_free(p);
        return NULL;
    }
    return p;
}

static vm_inputs inputs(const double *x, const double *y, const double *z, const double *pr)
{
    vm_inputs in;
    memset(&in, 0, sizeof in);
    in.x = x;
    in.y = y;
    in.z = z;
    in.params = pr;
    return in;
}

static int is_expr(frep_opcode op)
{
    unsigned f = op_flags(op);
    return !(f & (OPF_LEAF | OPF_CTRL)) && op != FREP_OP_LOADI;
}

static const double awkward[16] = {0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 2.0, 3.7,
                                   -2.5, 1e300, -1e300, 1e-300, 5e-324, NAN, INFINITY,
                                   -INFINITY};

/* ---- (1) every opcode equals its scalar reference ------------------------------- */

static void test_opsem_parity(void)
{
    double x[NB], y[NB], z[NB], out[NB];
    int op;
    size_t i;
    vm_scratch *s = vm_scratch_new(NULL);
    /* Lanes: all pairs of awkward values (16 x 16 = 256), z alternating for SELECT. */
    for (i = 0; i < NB; i++) {
        x[i] = awkward[i % 16];
        y[i] = awkward[i / 16];
        z[i] = (i % 3) == 0 ? 0.0 : (i % 3 == 1 ? NAN : -1.0);
    }
    for (op = 0; op < FREP_OP__COUNT; op++) {
        int nin = op_nin((frep_opcode)op), okv = 1, variant;
        if (!is_expr((frep_opcode)op)) continue;
        /* variant 0: stack operands; 1: b immediate; 2: a immediate. */
        for (variant = 0; variant < 3; variant++) {
            int kidx;
            if (variant > 0 && (nin != 2 || op == FREP_OP_AUNI || op == FREP_OP_AINT)) break;
            for (kidx = 0; kidx < (variant ? 16 : 1); kidx++) {
                double k = variant ? awkward[kidx] : 0.0;
                double alpha = op == FREP_OP_AUNI || op == FREP_OP_AINT ? 0.5 : 0.0;
                frep_program *p = prog_new();
                vm_inputs in = inputs(x, y, z, NULL);
                frep_runtime_error e;
                uint64_t want_bad = 0;
                if (nin == 3) emit(p, FREP_OP_X, 2, 0, 0);
                if (variant != 2) emit(p, FREP_OP_X, 0, 0, 0);
                if (nin >= 2 && variant != 1) emit(p, FREP_OP_X, 1, 0, 0);
                emit(p, (frep_opcode)op, 0, variant ? k : alpha,
                     (uint8_t)(variant == 1 ? INSN_KB : variant == 2 ? INSN_KA : 0));
                if (nin == 3) {
                    /* SELECT pops c, a, b: reorder by emitting z first (above). */
                }
                p = finish(p);
                if (!p) { okv = 0; continue; }
                vm_eval_block(p, s, &in, NB, out);
                for (i = 0; i < NB; i++) {
                    double a = variant == 2 ? k : x[i], b = variant == 1 ? k : y[i], r;
                    int bad = 0;
                    if (nin == 3) r = op_scalar((frep_opcode)op, z[i], x[i], y[i], 0, &bad);
                    else r = op_scalar((frep_opcode)op, a, b, 0, variant ? 0 : alpha, &bad);
                    if (!same(out[i], r)) {
                        if (okv) diag("%s variant %d lane %zu (%g, %g): got %.17g want %.17g",
                                      op_name((frep_opcode)op), variant, i, a, b, out[i], r);
                        okv = 0;
                    }
                    want_bad += (uint64_t)bad;
                }
                frep_scratch_errors((frep_scratch *)s, &e);
                if (e.count != want_bad || (want_bad && e.pc != (uint32_t)(p->ncode - 1))) {
                    if (okv) diag("%s variant %d: %llu errors at pc %u, want %llu",
                                  op_name((frep_opcode)op), variant,
                                  (unsigned long long)e.count, e.pc,
                                  (unsigned long long)want_bad);
                    okv = 0;
                }
                frep_scratch_reset_errors((frep_scratch *)s);
                /* The same with INSN_QUIET reports nothing and gives the same values. */
                p->code[p->ncode - 1].flags |= INSN_QUIET;
                vm_eval_block(p, s, &in, NB, out);
                frep_scratch_errors((frep_scratch *)s, &e);
                if (e.count != 0) {
                    if (okv) diag("%s quiet still reports", op_name((frep_opcode)op));
                    okv = 0;
                }
                frep_program_free(p);
            }
        }
        /* Random arguments too. */
        {
            frep_program *p = prog_new();
            vm_inputs in = inputs(x, y, z, NULL);
            double rx[NB], ry[NB], rz[NB];
            for (i = 0; i < NB; i++) {
                rx[i] = urand(-4, 4);
                ry[i] = urand(-4, 4);
                rz[i] = urand(-1, 1) > 0 ? 1.0 : 0.0;
            }
            in = inputs(rx, ry, rz, NULL);
            if (nin == 3) emit(p, FREP_OP_X, 2, 0, 0);
            emit(p, FREP_OP_X, 0, 0, 0);
            if (nin >= 2) emit(p, FREP_OP_X, 1, 0, 0);
            emit(p, (frep_opcode)op, 0, 0.25, 0);
            p = finish(p);
            if (p) {
                vm_eval_block(p, s, &in, NB, out);
                for (i = 0; i < NB; i++) {
                    double r = nin == 3 ? op_scalar((frep_opcode)op, rz[i], rx[i], ry[i], 0, NULL)
                                        : op_scalar((frep_opcode)op, rx[i], ry[i], 0, 0.25, NULL);
                    if (!same(out[i], r)) {
                        if (okv) diag("%s random lane %zu", op_name((frep_opcode)op), i);
                        okv = 0;
                    }
                }
                frep_program_free(p);
            } else {
                okv = 0;
            }
            frep_scratch_reset_errors((frep_scratch *)s);
        }
        ok(okv, "%s equals opsem.h at awkward and random arguments, with immediates",
           op_name((frep_opcode)op));
    }
    vm_scratch_free(s);
}

/* ---- (2) tangents against central differences ---------------------------------- */

/* Build op(u, v) with u = x + 0.5 y - 0.25 z, v = y - 0.2 x + 0.3 z (binary), or
 * op(u) (unary), or select(z > 0, u, v).  With params: u = x p0 + 0.1, v = y + p1. */
/* mode 0: xyz; 1: params; 2: op(u, 0.7) with b immediate; 3: op(1.3, v), a immediate. */
#define KB_VALUE 0.7
#define KA_VALUE 1.3
static frep_program *tangent_program(frep_opcode op, int mode)
{
    frep_program *p = prog_new();
    int nin = op_nin(op), with_params = mode == 1;
    if (mode >= 2) {
        if (mode == 2) {
            emit(p, FREP_OP_X, 0, 0, 0);
            emit(p, FREP_OP_X, 1, 0, 0);
            emit(p, FREP_OP_MUL, 0, 0.5, INSN_KB);
            emit(p, FREP_OP_ADD, 0, 0, 0);
            emit(p, FREP_OP_X, 2, 0, 0);
            emit(p, FREP_OP_MUL, 0, 0.25, INSN_KB);
            emit(p, FREP_OP_SUB, 0, 0, 0);
            emit(p, op, 0, KB_VALUE, INSN_KB);
        } else {
            emit(p, FREP_OP_X, 1, 0, 0);
            emit(p, FREP_OP_X, 0, 0, 0);
            emit(p, FREP_OP_MUL, 0, 0.2, INSN_KB);
            emit(p, FREP_OP_SUB, 0, 0, 0);
            emit(p, FREP_OP_X, 2, 0, 0);
            emit(p, FREP_OP_MUL, 0, 0.3, INSN_KA);
            emit(p, FREP_OP_ADD, 0, 0, 0);
            emit(p, op, 0, KA_VALUE, INSN_KA);
        }
        return finish(p);
    }
    if (with_params) {
        p->nparams = 2;
        p->params = calloc(2, sizeof *p->params);
    }
    if (nin == 3) {
        emit(p, FREP_OP_X, 2, 0, 0);
        emit(p, FREP_OP_GT, 0, 0, INSN_KB);
    }
    if (with_params) {
        emit(p, FREP_OP_X, 0, 0, 0);
        emit(p, FREP_OP_PARAM, 0, 0, 0);
        emit(p, FREP_OP_MUL, 0, 0, 0);
        emit(p, FREP_OP_ADD, 0, 0.1, INSN_KB);
    } else {
        emit(p, FREP_OP_X, 0, 0, 0);
        emit(p, FREP_OP_X, 1, 0, 0);
        emit(p, FREP_OP_MUL, 0, 0.5, INSN_KB);
        emit(p, FREP_OP_ADD, 0, 0, 0);
        emit(p, FREP_OP_X, 2, 0, 0);
        emit(p, FREP_OP_MUL, 0, 0.25, INSN_KB);
        emit(p, FREP_OP_SUB, 0, 0, 0);
    }
    if (nin >= 2) {
        if (with_params) {
            emit(p, FREP_OP_X, 1, 0, 0);
            emit(p, FREP_OP_PARAM, 1, 0, 0);
            emit(p, FREP_OP_ADD, 0, 0, 0);
        } else {
            emit(p, FREP_OP_X, 1, 0, 0);
            emit(p, FREP_OP_X, 0, 0, 0);
            emit(p, FREP_OP_MUL, 0, 0.2, INSN_KB);
            emit(p, FREP_OP_SUB, 0, 0, 0);
            emit(p, FREP_OP_X, 2, 0, 0);
            emit(p, FREP_OP_MUL, 0, 0.3, INSN_KA);
            emit(p, FREP_OP_ADD, 0, 0, 0);
        }
    }
    emit(p, op, 0, 0.5, 0);
    return finish(p);
}

/* Is op smooth at (u, v), far enough from kinks for a central difference? */
static int smooth_at(frep_opcode op, double u, double v)
{
    switch ((unsigned)op) {
    case FREP_OP_SQRT: case FREP_OP_LOG: case FREP_OP_LOGD: return u > 0.1;
    case FREP_OP_ASIN: case FREP_OP_ACOS: return fabs(u) < 0.9;
    case FREP_OP_TAN: return fabs(u) < 1.2;
    case FREP_OP_ABS: return fabs(u) > 1e-3;
    case FREP_OP_FRAC: return fabs(u - round(u)) > 1e-3;
    case FREP_OP_EXP: case FREP_OP_SINH: case FREP_OP_COSH: return fabs(u) < 5;
    case FREP_OP_DIV: return fabs(v) > 0.2;
    case FREP_OP_POW: return u > 0.2 && u < 3 && fabs(v) < 3;
    case FREP_OP_MOD: {
        double q = u / v;
        return fabs(v) > 0.2 && fabs(q - round(q)) > 1e-3;
    }
    case FREP_OP_MIN: case FREP_OP_MAX: return fabs(u - v) > 1e-3;
    case FREP_OP_MSUB: return fabs(u + v) > 1e-3;
    case FREP_OP_ATAN2: case FREP_OP_RUNI: case FREP_OP_RINT: case FREP_OP_RSUB:
    case FREP_OP_AUNI: case FREP_OP_AINT:
        return u * u + v * v > 1e-4;
    default: return 1;
    }
}

static void test_tangents(void)
{
    double x[NB], y[NB], z[NB], f[NB], d[3 * NB], fp[NB], fm[NB];
    double xs[NB], ys[NB], zs[NB];
    double params[2] = {0.8, -0.3}, dpar[2 * NB];
    vm_scratch *s = vm_scratch_new(NULL);
    const double h = 1e-5;
    int op;
    size_t i, c;
    for (op = 0; op < FREP_OP__COUNT; op++) {
        frep_program *p;
        int okv = 1, checked = 0, mode;
        if (!is_expr((frep_opcode)op)) continue;
        for (mode = 0; mode < 4; mode++) {
            int seeds = mode == 1;
            if (mode >= 2 && (op_nin((frep_opcode)op) != 2 || op == FREP_OP_AUNI ||
                              op == FREP_OP_AINT))
                break;
            p = tangent_program((frep_opcode)op, mode);
            if (!p) { okv = 0; continue; }
            for (i = 0; i < NB; i++) {
                x[i] = urand(-2, 2);
                y[i] = urand(-2, 2);
                z[i] = urand(-2, 2);
            }
            {
                vm_inputs in = inputs(x, y, z, params);
                if (vm_eval_block_tangent(p, s, &in, NB, seeds ? VM_SEED_PARAMS : VM_SEED_XYZ,
                                          f, seeds ? dpar : d) != 0) {
                    okv = 0;
                    frep_program_free(p);
                    continue;
                }
                /* Values equal the value evaluator's. */
                vm_eval_block(p, s, &in, NB, fp);
                for (i = 0; i < NB; i++)
                    if (!same(f[i], fp[i])) {
                        if (okv)
                            diag("%s: tangent evaluator value differs", op_name((frep_opcode)op));
                        okv = 0;
                        break;
                    }
            }
            for (c = 0; c < (seeds ? 2u : 3u); c++) {
                double pp[2], pm[2];
                vm_inputs inp, inm;
                memcpy(xs, x, sizeof xs);
                memcpy(ys, y, sizeof ys);
                memcpy(zs, z, sizeof zs);
                memcpy(pp, params, sizeof pp);
                memcpy(pm, params, sizeof pm);
                if (seeds) {
                    pp[c] += h;
                    pm[c] -= h;
                    inp = inputs(x, y, z, pp);
                    inm = inputs(x, y, z, pm);
                    vm_eval_block(p, s, &inp, NB, fp);
                    vm_eval_block(p, s, &inm, NB, fm);
                } else {
                    double *axis = c == 0 ? xs : c == 1 ? ys : zs;
                    const double *orig = c == 0 ? x : c == 1 ? y : z;
                    for (i = 0; i < NB; i++) axis[i] = orig[i] + h;
                    inp = inputs(c == 0 ? xs : x, c == 1 ? ys : y, c == 2 ? zs : z, params);
                    vm_eval_block(p, s, &inp, NB, fp);
                    for (i = 0; i < NB; i++) axis[i] = orig[i] - h;
                    vm_eval_block(p, s, &inp, NB, fm);
                }
                for (i = 0; i < NB; i++) {
                    double u, v, fd, ad = seeds ? dpar[c * NB + i] : d[c * NB + i];
                    if (seeds) {
                        u = x[i] * params[0] + 0.1;
                        v = y[i] + params[1];
                    } else {
                        u = x[i] + 0.5 * y[i] - 0.25 * z[i];
                        v = y[i] - 0.2 * x[i] + 0.3 * z[i];
                        if (mode == 2) v = KB_VALUE;
                        if (mode == 3) { u = KA_VALUE; v = y[i] - 0.2 * x[i] + 0.3 * z[i]; }
                    }
                    if (op_flags((frep_opcode)op) & OPF_NOGRAD) {
                        if (ad != 0) {
                            if (okv) diag("%s: NOGRAD tangent %g", op_name((frep_opcode)op), ad);
                            okv = 0;
                        }
                        continue;
                    }
                    if (!smooth_at((frep_opcode)op, u, v)) continue;
                    if (op == FREP_OP_SELECT && fabs(z[i]) < 1e-3) continue;
                    fd = (fp[i] - fm[i]) / (2 * h);
                    if (!isfinite(fd)) continue;
                    checked++;
                    if (!(fabs(ad - fd) <= 1e-5 * (1 + fabs(fd)))) {
                        if (okv) diag("%s mode %d tangent %zu: at u=%g v=%g AD %.12g FD %.12g",
                                      op_name((frep_opcode)op), mode, c, u, v, ad, fd);
                        okv = 0;
                    }
                }
            }
            frep_program_free(p);
        }
        frep_scratch_reset_errors((frep_scratch *)s);
        ok(okv && (checked > 100 || (op_flags((frep_opcode)op) & OPF_NOGRAD)),
           "%s tangents (xyz, parameter seeds, immediates) match central differences (%d checks)",
           op_name((frep_opcode)op), checked);
    }
    vm_scratch_free(s);
}

/* Defined derivatives at kinks (op_partials' rules), checked through the evaluator. */
static void test_kink_rules(void)
{
    vm_scratch *s = vm_scratch_new(NULL);
    double x[4] = {0, 1, 0, -1}, y[4] = {0, 1, 2, 3}, z[4] = {0, 0, 0, 0};
    double f[4], d[12];
    vm_inputs in = inputs(x, y, z, NULL);
    frep_program *p;
    /* min(x, x*1) tie -> derivative of a; here both are x: 1. max(x, y) at x = y -> dx. */
    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_X, 1, 0, 0);
    emit(p, FREP_OP_MAX, 0, 0, 0);
    p = finish(p);
    vm_eval_block_tangent(p, s, &in, 4, VM_SEED_XYZ, f, d);
    ok(d[0] == 1 && d[4] == 0 && d[1] == 1 && d[5] == 0,
       "max tie: derivative of the first operand");
    frep_program_free(p);
    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_ABS, 0, 0, 0);
    p = finish(p);
    vm_eval_block_tangent(p, s, &in, 4, VM_SEED_XYZ, f, d);
    ok(d[0] == 0 && d[1] == 1 && d[3] == -1, "abs: derivative 0 at 0, sign elsewhere");
    frep_program_free(p);
    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_SQRT, 0, 0, 0);
    p = finish(p);
    vm_eval_block_tangent(p, s, &in, 4, VM_SEED_XYZ, f, d);
    ok(d[0] == 0 && d[1] == 0.5 && isnan(d[3]), "sqrt: derivative 0 at 0, NaN where undefined");
    frep_program_free(p);
    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_X, 2, 0, 0);
    emit(p, FREP_OP_RUNI, 0, 0, 0);
    p = finish(p);
    vm_eval_block_tangent(p, s, &in, 4, VM_SEED_XYZ, f, d);
    ok(d[0] == 1 && d[8] == 1 && d[4] == 0, "R-union at (0, 0): root term contributes 0");
    frep_program_free(p);
    vm_scratch_free(s);
}

/* ---- (3) batch, single point and odd block sizes agree --------------------------- */

static frep_program *mixed_program(void)
{
    /* s0 = sqrt(x^2 + y^2) - 1; f = runi(s0, z - 0.5) * (1 + p0) + atan2(y, x) */
    frep_program *p = prog_new();
    p->nparams = 1;
    p->params = calloc(1, sizeof *p->params);
    p->params[0].value = 0.25;
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_SQUARE, 0, 0, 0);
    emit(p, FREP_OP_X, 1, 0, 0);
    emit(p, FREP_OP_SQUARE, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    emit(p, FREP_OP_SQRT, 0, 0, 0);
    emit(p, FREP_OP_SUB, 0, 1, INSN_KB);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_X, 2, 0, 0);
    emit(p, FREP_OP_SUB, 0, 0.5, INSN_KB);
    emit(p, FREP_OP_RUNI, 0, 0, 0);
    emit(p, FREP_OP_PARAM, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 1, INSN_KA);
    emit(p, FREP_OP_MUL, 0, 0, 0);
    emit(p, FREP_OP_X, 1, 0, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_ATAN2, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    return finish(p);
}

static void test_batch_vs_single(void)
{
    enum { N = 1000 };
    static double x[N], y[N], z[N], f1[N], f2[N], g1[3 * N], g2[3 * NB];
    frep_program *p = mixed_program();
    vm_scratch *s = vm_scratch_new(p);
    size_t i, off, step;
    int okv = 1, okg = 1;
    for (i = 0; i < N; i++) {
        x[i] = urand(-2, 2);
        y[i] = urand(-2, 2);
        z[i] = urand(-2, 2);
    }
    /* Reference: one point at a time. */
    for (i = 0; i < N; i++) {
        vm_inputs in = inputs(x + i, y + i, z + i, NULL);
        double d[3];
        vm_eval_block(p, s, &in, 1, f1 + i);
        vm_eval_block_tangent(p, s, &in, 1, VM_SEED_XYZ, f2, d);
        okg &= same(f2[0], f1[i]);
        g1[i] = d[0];
        g1[N + i] = d[1];
        g1[2 * N + i] = d[2];
    }
    for (step = 1; step <= NB; step = step == 1 ? 37 : step == 37 ? 255 : step + 1) {
        for (off = 0; off < N; off += step) {
            size_t nb = N - off < step ? N - off : step;
            vm_inputs in = inputs(x + off, y + off, z + off, NULL);
            vm_eval_block(p, s, &in, nb, f2 + off);
            vm_eval_block_tangent(p, s, &in, nb, VM_SEED_XYZ, f2 + off, g2);
            for (i = 0; i < nb; i++)
                for (int c = 0; c < 3; c++) okg &= same(g2[c * nb + i], g1[c * N + off + i]);
        }
        for (i = 0; i < N; i++) okv &= same(f1[i], f2[i]);
    }
    ok(okv, "values: blocks of 1, 37, 255 and 256 points equal single-point evaluation");
    ok(okg, "gradients: blocks of 1, 37, 255 and 256 points equal single-point evaluation");
    /* The parameter vector passed explicitly equals the program's own values. */
    {
        double pr = 0.25;
        vm_inputs in = inputs(x, y, z, &pr);
        vm_eval_block(p, s, &in, NB, f2);
        okv = 1;
        for (i = 0; i < NB; i++) okv &= same(f1[i], f2[i]);
        ok(okv, "explicit parameters equal the program's initial values");
    }
    vm_scratch_free(s);
    frep_program_free(p);
}

/* ---- (4) branches and loops -------------------------------------------------------- */

/* while i < x loop acc = acc + i*y; i = i + 1 endloop; f = acc + (x > 5 ? 1 : -1) * z
 * (the if as JZ).  Slots: 0 = i, 1 = acc. */
static frep_program *loop_program(void)
{
    frep_program *p = prog_new();
    uint32_t top, jz, jz2, jmp2;
    emit(p, FREP_OP_CONST, 0, 0, 0);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    top = p->ncode;
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_LT, 0, 0, 0);
    jz = p->ncode;
    emit(p, FREP_OP_JZ, 0, 0, 0);
    emit(p, FREP_OP_LOAD, 1, 0, 0);
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_X, 1, 0, 0);
    emit(p, FREP_OP_MUL, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    emit(p, FREP_OP_STORE, 1, 0, 0);
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 1, INSN_KB);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    emit(p, FREP_OP_JMP, top, 0, 0);
    p->code[jz].arg = p->ncode;
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_GT, 0, 5, INSN_KB);
    jz2 = p->ncode;
    emit(p, FREP_OP_JZ, 0, 0, 0);
    emit(p, FREP_OP_X, 2, 0, 0);
    emit(p, FREP_OP_STORE, 2, 0, 0);
    jmp2 = p->ncode;
    emit(p, FREP_OP_JMP, 0, 0, 0);
    p->code[jz2].arg = p->ncode;
    emit(p, FREP_OP_X, 2, 0, 0);
    emit(p, FREP_OP_NEG, 0, 0, 0);
    emit(p, FREP_OP_STORE, 2, 0, 0);
    p->code[jmp2].arg = p->ncode;
    emit(p, FREP_OP_LOAD, 1, 0, 0);
    emit(p, FREP_OP_LOAD, 2, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    return finish(p);
}

static void test_branches(void)
{
    static double x[NB], y[NB], z[NB], f[NB], ft[NB], g[3 * NB];
    frep_program *p = loop_program();
    vm_scratch *s = vm_scratch_new(p);
    vm_inputs in = inputs(x, y, z, NULL);
    frep_runtime_error e;
    size_t i;
    int okv = 1, okg = 1;
    ok(p && (p->flags & PROG_HAS_BRANCHES), "loop program assembles, flagged as branching");
    for (i = 0; i < NB; i++) {
        x[i] = urand(0, 10);
        y[i] = urand(-1, 1);
        z[i] = urand(-1, 1);
    }
    vm_eval_block(p, s, &in, NB, f);
    vm_eval_block_tangent(p, s, &in, NB, VM_SEED_XYZ, ft, g);
    for (i = 0; i < NB; i++) {
        double acc = 0, want, it;
        long m = 0;
        for (it = 0; it < x[i]; it += 1) { acc += it * y[i]; m++; }
        want = acc + (x[i] > 5 ? z[i] : -z[i]);
        okv &= fabs(f[i] - want) <= 1e-12 * (1 + fabs(want)) && same(ft[i], f[i]);
        /* d/dy = sum of i = m(m-1)/2; d/dz = +-1; d/dx = 0 (loop count is discrete). */
        okg &= fabs(g[NB + i] - (double)m * (double)(m - 1) / 2) <= 1e-9 &&
               g[2 * NB + i] == (x[i] > 5 ? 1.0 : -1.0) && g[i] == 0;
    }
    ok(okv, "divergent while/if: values equal a per-point reference");
    ok(okg, "divergent while/if: gradients equal the per-point derivatives");
    frep_scratch_errors((frep_scratch *)s, &e);
    is_int(e.count, 0, "no runtime errors in the loop program");
    frep_program_free(p);

    /* A runaway loop: while 1 loop endloop. */
    p = prog_new();
    emit(p, FREP_OP_CONST, 0, 1, 0);
    emit(p, FREP_OP_JZ, 3, 0, 0);
    emit(p, FREP_OP_JMP, 0, 0, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    p = finish(p);
    in = inputs(x, y, z, NULL);
    vm_eval_block(p, s, &in, 3, f);
    frep_scratch_errors((frep_scratch *)s, &e);
    ok(isnan(f[0]) && isnan(f[2]) && e.count == 3 && e.pc == 2 &&
       strstr(e.what, "loop") != NULL,
       "a runaway loop stops at FREP_MAX_LOOP_ITERATIONS with NaN and an error at the JMP");
    frep_scratch_reset_errors((frep_scratch *)s);
    vm_eval_block_tangent(p, s, &in, 2, VM_SEED_XYZ, f, g);
    frep_scratch_errors((frep_scratch *)s, &e);
    ok(isnan(f[0]) && isnan(g[0]) && e.count == 2, "the tangent evaluator stops it too");
    frep_program_free(p);
    vm_scratch_free(s);
}

/* ---- slots: stores, aliasing, arrays -------------------------------------------------- */

static void test_slots(void)
{
    double x[5] = {1, 2, 3, 0.5, -4}, y[5] = {0, 0, 0, 0, 0}, z[5] = {0, 0, 0, 0, 0};
    double f[5], ft[5], g[15];
    vm_scratch *s = vm_scratch_new(NULL);
    vm_inputs in = inputs(x, y, z, NULL);
    frep_runtime_error e;
    frep_program *p;
    size_t i;
    int okv;

    /* s0 = 5; push s0; s0 = 2x (a computed value: buffers are swapped); f = old + new */
    p = prog_new();
    emit(p, FREP_OP_CONST, 0, 5, 0);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_MUL, 0, 2, INSN_KB);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    p = finish(p);
    vm_eval_block(p, s, &in, 5, f);
    vm_eval_block_tangent(p, s, &in, 5, VM_SEED_XYZ, ft, g);
    okv = 1;
    for (i = 0; i < 5; i++) okv &= f[i] == 5 + 2 * x[i] && ft[i] == f[i] && g[i] == 2;
    ok(okv, "a loaded value stays live while its slot is reassigned (swap path)");
    frep_program_free(p);

    /* Same with the copy path (storing an input), and an unassigned slot reads 0. */
    p = prog_new();
    emit(p, FREP_OP_LOAD, 1, 0, 0);
    emit(p, FREP_OP_CONST, 0, 5, 0);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    p = finish(p);
    vm_eval_block(p, s, &in, 5, f);
    vm_eval_block_tangent(p, s, &in, 5, VM_SEED_XYZ, ft, g);
    okv = 1;
    for (i = 0; i < 5; i++) okv &= f[i] == 5 + x[i] && ft[i] == f[i] && g[i] == 1;
    ok(okv, "a loaded value stays live while its slot is reassigned (copy path)");
    frep_program_free(p);

    /* Array c[3] in slots 0..2: c[idx] = x with idx = 1 + (x > 1) + (x > 2.5), then
     * f = c[1] + 10 c[2] + 100 c[3], and c[round(x)] read directly. */
    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_GT, 0, 1, INSN_KB);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_GT, 0, 2.5, INSN_KB);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 1, INSN_KB);
    emit(p, FREP_OP_STOREI, 0, 3, 0);
    emit(p, FREP_OP_CONST, 0, 1, 0);
    emit(p, FREP_OP_LOADI, 0, 3, 0);
    emit(p, FREP_OP_CONST, 0, 2, 0);
    emit(p, FREP_OP_LOADI, 0, 3, 0);
    emit(p, FREP_OP_MUL, 0, 10, INSN_KB);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    emit(p, FREP_OP_CONST, 0, 3, 0);
    emit(p, FREP_OP_LOADI, 0, 3, 0);
    emit(p, FREP_OP_MUL, 0, 100, INSN_KB);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    p = finish(p);
    ok(p && p->nslots == 3, "STOREI/LOADI: prog_finish sizes the slots from the array");
    vm_eval_block(p, s, &in, 5, f);
    vm_eval_block_tangent(p, s, &in, 5, VM_SEED_XYZ, ft, g);
    okv = 1;
    for (i = 0; i < 5; i++) {
        double w = x[i] > 1 ? (x[i] > 2.5 ? 100 : 10) : 1;
        okv &= f[i] == w * x[i] && ft[i] == f[i] && g[i] == w;
    }
    ok(okv, "STOREI scatters per lane, LOADI gathers; tangents follow");
    frep_program_free(p);

    /* Index out of range: LOADI gives NaN + error; STOREI is ignored + error. */
    p = prog_new();
    emit(p, FREP_OP_X, 1, 0, 0);     /* value 0 */
    emit(p, FREP_OP_X, 0, 0, 0);     /* index x: 1, 2, 3, 0.5, -4 */
    emit(p, FREP_OP_STOREI, 0, 2, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_LOADI, 0, 2, 0);
    p = finish(p);
    frep_scratch_reset_errors((frep_scratch *)s);
    vm_eval_block(p, s, &in, 5, f);
    frep_scratch_errors((frep_scratch *)s, &e);
    ok(f[0] == 0 && f[1] == 0 && isnan(f[2]) && isnan(f[3]) && isnan(f[4]),
       "LOADI out of range (3, 0.5, -4 in an array of 2) gives NaN");
    ok(e.count == 3 && e.pc == 2 && e.x == 3, "index errors: 3 points, first at the STOREI");
    frep_program_free(p);

    /* A store out of the array makes the point's value NaN even when the result does
     * not read the array (the reference interpreter stops at it): c[x] = 0 with c[2],
     * f = y + 1 (1 at every point, gradient 0). */
    p = prog_new();
    emit(p, FREP_OP_CONST, 0, 0, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_STOREI, 0, 2, 0);
    emit(p, FREP_OP_X, 1, 0, 0);
    emit(p, FREP_OP_ADD, 0, 1, INSN_KB);
    p = finish(p);
    frep_scratch_reset_errors((frep_scratch *)s);
    vm_eval_block(p, s, &in, 5, f);
    frep_scratch_errors((frep_scratch *)s, &e);
    ok(f[0] == 1 && f[1] == 1 && isnan(f[2]) && isnan(f[3]) && isnan(f[4]) &&
       e.count == 3 && e.pc == 2, "STOREI out of range: NaN at those points, with the error");
    vm_eval_block_tangent(p, s, &in, 5, VM_SEED_XYZ, ft, g);
    okv = ft[0] == 1 && ft[1] == 1;
    for (i = 0; i < 3; i++) /* d/dx, d/dy, d/dz of y + 1 */
        okv &= g[i * 5] == (i == 1) && g[i * 5 + 1] == (i == 1);
    for (i = 2; i < 5; i++)
        okv &= isnan(ft[i]) && isnan(g[i]) && isnan(g[5 + i]) && isnan(g[10 + i]);
    ok(okv, "... and in the tangent evaluator: value and gradient NaN there");
    /* One lane at a time (a divergent block's rerun) gives the same. */
    okv = 1;
    for (i = 0; i < 5; i++) {
        double xi = x[i], yi = y[i], zi = z[i], fi;
        vm_inputs li = inputs(&xi, &yi, &zi, NULL);
        vm_eval_block(p, s, &li, 1, &fi);
        okv &= same(fi, f[i]);
    }
    ok(okv, "... one point at a time as in a block");
    {
        /* Interval: no enclosure is claimed over a box where an index may be out of
         * range (the value there is NaN, neither inside nor outside). */
        vm_iscratch *is = vm_iscratch_new(p);
        const double in_box[6] = { 1, 0, 0, 2.4, 1, 1 }, out_box[6] = { 1, 0, 0, 3, 1, 1 };
        const double low_box[6] = { 0.5, 0, 0, 2, 1, 1 };
        ival r1 = { 0, 0 }, r2 = { 0, 0 }, r3 = { 0, 0 };
        ok(is && vm_eval_interval(p, is, in_box, NULL, &r1) == 0 && r1.lo >= 1 - 1e-9 &&
           r1.hi <= 2 + 1e-9, "interval: indices in range, the enclosure of y + 1");
        ok(is && vm_eval_interval(p, is, out_box, NULL, &r2) == 0 && r2.lo == -INFINITY &&
           r2.hi == INFINITY && vm_eval_interval(p, is, low_box, NULL, &r3) == 0 &&
           r3.lo == -INFINITY && r3.hi == INFINITY,
           "interval: an index that may be out of range (above, below): [-inf, inf]");
        vm_iscratch_free(is);
    }
    /* Quiet (a speculative branch the point may not take): no NaN, no error. */
    p->code[2].flags |= INSN_QUIET;
    frep_scratch_reset_errors((frep_scratch *)s);
    vm_eval_block(p, s, &in, 5, f);
    frep_scratch_errors((frep_scratch *)s, &e);
    okv = e.count == 0;
    for (i = 0; i < 5; i++) okv &= f[i] == 1;
    ok(okv, "a quiet STOREI out of range changes nothing");
    frep_program_free(p);

    /* LOADI over an index interval partly out of range: no enclosure either. */
    p = prog_new();
    emit(p, FREP_OP_CONST, 0, 7, 0);
    emit(p, FREP_OP_CONST, 0, 1, 0);
    emit(p, FREP_OP_STOREI, 0, 2, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_LOADI, 0, 2, 0);
    p = finish(p);
    {
        vm_iscratch *is = vm_iscratch_new(p);
        const double in_box[6] = { 1, 0, 0, 1.4, 1, 1 }, out_box[6] = { 0.5, 0, 0, 1.4, 1, 1 };
        ival r1 = { 0, 0 }, r2 = { 0, 0 };
        ok(is && vm_eval_interval(p, is, in_box, NULL, &r1) == 0 && r1.lo <= 7 && r1.hi >= 7 &&
           r1.hi < 8, "interval LOADI: c[1] over [1, 1.4]");
        ok(is && vm_eval_interval(p, is, out_box, NULL, &r2) == 0 && r2.lo == -INFINITY &&
           r2.hi == INFINITY, "interval LOADI: an index that may be 0.5: [-inf, inf]");
        vm_iscratch_free(is);
    }
    frep_program_free(p);
    vm_scratch_free(s);
}

/* ---- (5) domain errors --------------------------------------------------------------- */

typedef struct diag_capture {
    char msg[512];
    uint32_t line, col;
    int n;
} diag_capture;

static void capture(void *user, const frep_diag *d)
{
    diag_capture *c = user;
    snprintf(c->msg, sizeof c->msg, "%s", d->message);
    c->line = d->line;
    c->col = d->col;
    c->n++;
}

static void test_domain_errors(void)
{
    double x[6] = {1, -1, 4, -2, NAN, 0}, y[6] = {1, 1, 0, 1, 1, 0}, z[6] = {0, 0, 0, 0, 0, 0};
    double f[6];
    vm_scratch *s = vm_scratch_new(NULL);
    vm_inputs in = inputs(x, y, z, NULL);
    frep_runtime_error e;
    diag_capture cap;
    frep_srcpos pos = {7, 12, 4};
    frep_program *p = prog_new();
    /* f = sqrt(x) + x / y: sqrt fails at x = -1, -2; division at y = 0 (x = 4, 0). */
    prog_emit(p, FREP_OP_X, 0, 0, 0, nopos);
    prog_emit(p, FREP_OP_SQRT, 0, 0, 0, pos);
    prog_emit(p, FREP_OP_X, 0, 0, 0, nopos);
    prog_emit(p, FREP_OP_X, 1, 0, 0, nopos);
    prog_emit(p, FREP_OP_DIV, 0, 0, 0, nopos);
    prog_emit(p, FREP_OP_ADD, 0, 0, 0, nopos);
    p = finish(p);
    p->file = strdup("part.hf");
    vm_eval_block(p, s, &in, 6, f);
    frep_scratch_errors((frep_scratch *)s, &e);
    ok(isnan(f[1]) && isnan(f[2]) && isnan(f[3]) && isnan(f[5]),
       "domain errors give NaN");
    is_double(f[0], 2.0, 0.0, "sqrt(1) + 1/1 = 2 where there is no error");
    is_int(e.count, 4, "4 points raised errors (NaN input is not an error)");
    is_int(e.pc, 1, "the lowest pc is reported");
    ok(e.x == -1 && strcmp(e.what, "sqrt of a negative number") == 0,
       "with the first offending point and what happened");
    memset(&cap, 0, sizeof cap);
    frep_report_runtime_error(p, &e, capture, &cap);
    is_str(cap.msg, "sqrt of a negative number at 4 points, e.g. (-1, 1, 0)",
           "frep_report_runtime_error message");
    ok(cap.line == 7 && cap.col == 12, "reported at the instruction's source position");
    /* Errors accumulate over calls until reset. */
    vm_eval_block(p, s, &in, 6, f);
    frep_scratch_errors((frep_scratch *)s, &e);
    is_int(e.count, 8, "errors accumulate across blocks");
    frep_scratch_reset_errors((frep_scratch *)s);
    frep_scratch_errors((frep_scratch *)s, &e);
    is_int(e.count, 0, "reset clears them");
    /* Division by exactly zero only: a tiny divisor is fine. */
    y[2] = 5e-324;
    vm_eval_block(p, s, &in, 6, f);
    frep_scratch_errors((frep_scratch *)s, &e);
    ok(e.count == 3 && isinf(f[2]), "division by a denormal is not an error");
    frep_program_free(p);
    vm_scratch_free(s);
}

/* ---- program building and disassembly -------------------------------------------- */

static void test_program(void)
{
    frep_program *p = prog_new();
    char *dis;
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    ok(prog_finish(p) == -1, "prog_finish rejects a stack underflow");
    frep_program_free(p);
    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_JZ, 9, 0, 0);
    emit(p, FREP_OP_X, 0, 0, 0);
    ok(prog_finish(p) == -1, "prog_finish rejects a jump out of the code");
    frep_program_free(p);
    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_X, 1, 0, 0);
    ok(prog_finish(p) == -1, "prog_finish rejects code leaving two values");
    frep_program_free(p);
    p = prog_new();
    emit(p, FREP_OP_PARAM, 0, 0, 0);
    ok(prog_finish(p) == -1, "prog_finish rejects an unknown parameter");
    frep_program_free(p);

    p = mixed_program();
    ok(p && p->max_stack == 3, "max_stack computed (3 for the mixed program)");
    is_int(prog_subtree_start(p->code, 6), 0, "subtree of the SUB at pc 6 starts at 0");
    is_int(prog_subtree_start(p->code, 14), 8, "subtree of the MUL at pc 14 starts at 8");
    is_int(prog_subtree_start(p->code, 3), 2, "subtree of a unary op");
    dis = frep_disassemble(p);
    ok(dis && strstr(dis, "SQRT") && strstr(dis, "b=1") && strstr(dis, "a=1") &&
       strstr(dis, "STORE   s0") && strstr(dis, "stack 3"),
       "disassembly names ops, immediates, slots and the stack size");
    if (dis) diag("%s", strtok(dis, "\n"));
    free(dis);
    frep_program_free(p);
    {
        int okt = 1, op;
        for (op = 0; op < FREP_OP__COUNT; op++) {
            okt &= op_name((frep_opcode)op)[0] != '?' && op_meaning((frep_opcode)op)[0] != 0;
            okt &= op_pushes((frep_opcode)op) == ((op_flags((frep_opcode)op) & OPF_CTRL) ? 0 : 1) ||
                   op == FREP_OP_LOADI;
        }
        ok(okt, "every opcode has a name, a meaning and a push count");
    }
}

/* ---- (6) thread count does not change anything --------------------------------------- */

/* The thread count of a job follows its size (threads.h): one thread below
 * FREP_PAR_MIN_WORK node-evaluations or for one unit of work, at most one per unit. */
static void test_thread_sizing(void)
{
    int nt = frep_threads(2);
    ok(frep_threads_for(2, FREP_PAR_MIN_WORK * 0.99, 1000) == 1,
       "a job under FREP_PAR_MIN_WORK gets one thread");
    ok(frep_threads_for(0, 1000, 1000) == 1, "a tiny job gets one thread by default too");
    ok(frep_threads_for(2, FREP_PAR_MIN_WORK * 100, 1) == 1, "one unit of work: one thread");
    ok(frep_threads_for(2, FREP_PAR_MIN_WORK, 1000) == nt,
       "a job of FREP_PAR_MIN_WORK gets the threads asked for (%d)", nt);
    ok(frep_threads_for(8, FREP_PAR_MIN_WORK * 100, 3) == (frep_threads(8) < 3 ? frep_threads(8) : 3),
       "never more threads than units of work");
}

/* A late loop (frep_par_for_late): items run once each; the calling thread runs them
 * alone until left() reaches FREP_PAR_MIN_WORK, and a loop whose left() never does
 * stays on one thread. */
#define LATE_N 64
typedef struct late_ctx {
    int runs[LATE_N], thread[LATE_N];
    long start_at;     /* left() says enough from this many items done on; -1: never */
} late_ctx;

static void late_fn(void *ctx, int thread, long i0, long i1)
{
    late_ctx *c = ctx;
    for (long i = i0; i < i1; i++) {
        c->runs[i]++;
        c->thread[i] = thread;
    }
}

static double late_left(void *ctx, long done, long n)
{
    const late_ctx *c = ctx;
    (void)n;
    return c->start_at >= 0 && done >= c->start_at ? FREP_PAR_MIN_WORK : 0;
}

static void test_par_for_late(void)
{
    for (int pass = 0; pass < 2; pass++) {
        late_ctx c;
        memset(&c, 0, sizeof c);
        c.start_at = pass ? 5 : -1;
        int ran = frep_par_for_late(2, LATE_N, 1, late_fn, late_left, &c);
        int once = 1, early = 1;
        for (int i = 0; i < LATE_N; i++) {
            once &= c.runs[i] == 1;
            if (i < (pass ? 5 : LATE_N)) early &= c.thread[i] == 0;
        }
        if (pass == 0) {
            ok(ran == 1 && once && early,
               "late loop, left() never enough: one thread ran every item once (%d)", ran);
        } else {
            ok(ran == frep_threads(2) && once && early,
               "late loop: items 0..4 on the calling thread alone, then %d threads, every "
               "item once", ran);
        }
    }
}

static void test_threads(void)
{
    /* big enough for 2 threads (FREP_PAR_MIN_WORK) with both programs (19 and 20
     * instructions) */
    enum { N = 250007 };
    static double x[N], y[N], z[N], f1[N], f2[N], g1[3 * N], g2[3 * N];
    frep_program *p = mixed_program();
    frep_runtime_error e1, e2;
    size_t i;
    int okv = 1;
    for (i = 0; i < N; i++) {
        x[i] = urand(-2, 2);
        y[i] = urand(-2, 2);
        z[i] = urand(-2, 2);
    }
    /* An error region: sqrt(x^2+y^2) is fine; make params produce none, errors come
     * from a second program below. */
    frep_eval_par(p, N, x, y, z, NULL, f1, 1, &e1);
    frep_eval_par(p, N, x, y, z, NULL, f2, 2, &e2);
    for (i = 0; i < N; i++) okv &= same(f1[i], f2[i]);
    ok(okv, "frep_eval_par: 1 and 2 threads give identical values");
    frep_eval_grad_par(p, N, x, y, z, NULL, f1, g1, g1 + N, g1 + 2 * N, 1, &e1);
    frep_eval_grad_par(p, N, x, y, z, NULL, f2, g2, g2 + N, g2 + 2 * N, 2, &e2);
    okv = 1;
    for (i = 0; i < 3 * N; i++) okv &= same(g1[i], g2[i]);
    ok(okv, "frep_eval_grad_par: 1 and 2 threads give identical gradients");
    frep_program_free(p);

    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_LOG, 0, 0, 0);
    emit(p, FREP_OP_X, 1, 0, 0);
    emit(p, FREP_OP_SQRT, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    for (i = 0; i < 5; i++) { /* + z^2 five times: 20 instructions, no more errors */
        emit(p, FREP_OP_X, 2, 0, 0);
        emit(p, FREP_OP_SQUARE, 0, 0, 0);
        emit(p, FREP_OP_ADD, 0, 0, 0);
    }
    p = finish(p);
    ok(p->ncode * (double)N >= FREP_PAR_MIN_WORK, "the error program is big enough for threads");
    frep_eval_par(p, N, x, y, z, NULL, f1, 1, &e1);
    frep_eval_par(p, N, x, y, z, NULL, f2, 2, &e2);
    ok(e1.count == e2.count && e1.pc == e2.pc && same(e1.x, e2.x) && same(e1.y, e2.y) &&
       e1.count > 0 && e1.pc == 1, "errors merge identically at 1 and 2 threads");
    {
        /* The serial API agrees. */
        frep_scratch *s = frep_scratch_new(p);
        frep_runtime_error e3;
        frep_eval(p, s, N, x, y, z, NULL, f2);
        frep_scratch_errors(s, &e3);
        ok(e3.count == e1.count && e3.pc == e1.pc && same(e3.x, e1.x),
           "frep_eval reports the same errors as frep_eval_par");
        frep_scratch_free(s);
    }
    frep_program_free(p);
}

/* ---- the public API against the block evaluators ------------------------------------ */

static void test_public_api(void)
{
    enum { N = 700 };
    static double x[N], y[N], z[N], f[N], fb[N], gx[N], gy[N], gz[N], dp[N], g[3 * NB], d[NB];
    frep_program *p = mixed_program();
    frep_scratch *s = frep_scratch_new(p);
    vm_scratch *vs = vm_scratch_new(p);
    double pr = 0.7;
    size_t i, off;
    int okv = 1, okg = 1, okd = 1;
    for (i = 0; i < N; i++) {
        x[i] = urand(-2, 2);
        y[i] = urand(-2, 2);
        z[i] = urand(-2, 2);
    }
    ok(frep_eval(p, s, N, x, y, z, &pr, f) == 0 &&
       frep_eval_grad(p, s, N, x, y, z, &pr, fb, gx, gy, gz) == 0,
       "frep_eval and frep_eval_grad succeed on 700 points");
    for (off = 0; off < N; off += NB) {
        size_t nb = N - off < NB ? N - off : NB;
        vm_inputs in = inputs(x + off, y + off, z + off, &pr);
        double v[NB];
        vm_eval_block_tangent(p, vs, &in, nb, VM_SEED_XYZ, v, g);
        for (i = 0; i < nb; i++) {
            okv &= same(v[i], f[off + i]) && same(v[i], fb[off + i]);
            okg &= same(g[i], gx[off + i]) && same(g[nb + i], gy[off + i]) &&
                   same(g[2 * nb + i], gz[off + i]);
        }
        vm_eval_block_tangent(p, vs, &in, nb, VM_SEED_PARAMS, v, d);
        memcpy(fb + off, d, nb * sizeof *d);
    }
    ok(okv, "frep_eval/frep_eval_grad values equal the block evaluators'");
    ok(okg, "frep_eval_grad gradients equal the block tangent evaluator's");
    ok(frep_eval_dparams(p, s, N, x, y, z, &pr, f, dp) == 0, "frep_eval_dparams succeeds");
    for (i = 0; i < N; i++) okd &= same(dp[i], fb[i]);
    /* d f / d p0 = runi(...) by construction: f = runi * (1 + p0) + atan2. */
    for (i = 0; i < N; i++) {
        double r = sqrt(x[i] * x[i] + y[i] * y[i]) - 1, w = z[i] - 0.5;
        okd &= fabs(dp[i] - opsem_runi(r, w)) <= 1e-12 * (1 + fabs(dp[i]));
    }
    ok(okd, "frep_eval_dparams: df/dp0 equals the factor it multiplies");
    ok(frep_program_size(p) == p->ncode && frep_program_nparams(p) == 1 &&
       frep_program_param_value(p, 0) == 0.25 && frep_program_param_name(p, 3) == NULL,
       "program queries");
    ok(frep_eval(p, s, 0, x, y, z, NULL, f) == 0, "zero points is fine");
    frep_scratch_free(s);
    vm_scratch_free(vs);
    frep_program_free(p);
}

/* ---- the work budget (frep_program_set_work_limit) ----------------------------------- */

/* i = 0; while i < K loop i = i + 1; endloop; result i + x (K = the bound: a constant
 * when kconst, else x itself, so each point loops ceil(x) times); *jmp: the backward
 * jump's pc. */
static frep_program *count_program(int kconst, double K, uint32_t *jmp)
{
    frep_program *p = prog_new();
    uint32_t top, jz;
    emit(p, FREP_OP_CONST, 0, 0, 0);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    top = p->ncode;
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    if (kconst) emit(p, FREP_OP_CONST, 0, K, 0);
    else emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_LT, 0, 0, 0);
    jz = p->ncode;
    emit(p, FREP_OP_JZ, 0, 0, 0);
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_ADD, 0, 1, INSN_KB);
    emit(p, FREP_OP_STORE, 0, 0, 0);
    *jmp = p->ncode;
    emit(p, FREP_OP_JMP, top, 0, 0);
    p->code[jz].arg = p->ncode;
    emit(p, FREP_OP_LOAD, 0, 0, 0);
    emit(p, FREP_OP_X, 1, 0, 0);
    emit(p, FREP_OP_ADD, 0, 0, 0);
    return finish(p);
}

static void test_work_budget(void)
{
    /* enough points for two threads (FREP_PAR_MIN_WORK) */
    enum { N = 400000 };
    static double x[N], y[N], z[N], f[N], gx[N], gy[N], gz[N];
    frep_runtime_error e, e2;
    uint32_t jmp;
    size_t i;
    frep_program *p = count_program(0, 0, &jmp);
    if (!p) return;
    ok(frep_program_work_limit(p) == 0 && frep_program_work_used(p) == 0 &&
           !frep_program_work_spent(p),
       "a program has no work budget until one is set");
    /* every point loops 3 times: 3N iterations in all, counted exactly (no divergence) */
    for (i = 0; i < N; i++) {
        x[i] = 3;
        y[i] = urand(-1, 1);
        z[i] = 0;
    }
    ok(frep_program_set_work_limit(p, 10ull * N) == 0 && frep_program_work_limit(p) == 10ull * N,
       "set a budget of 10 iterations per point");
    ok(frep_eval_par(p, N, x, y, z, NULL, f, 2, &e) == 0 && e.count == 0 &&
           frep_program_work_used(p) == 3ull * N && !frep_program_work_spent(p) &&
           f[N - 1] == 3 + y[N - 1],
       "within the budget: the values, no error, 3 iterations counted per point");
    /* ceil(x) iterations with x in [0, 4): the count does not depend on the threads */
    for (i = 0; i < N; i++) x[i] = urand(0, 4);
    frep_program_set_work_limit(p, 100ull * N);
    ok(frep_program_work_used(p) == 0, "setting the limit again starts the count at 0");
    frep_eval_par(p, N, x, y, z, NULL, f, 1, &e);
    uint64_t u1 = frep_program_work_used(p);
    frep_program_set_work_limit(p, 100ull * N);
    frep_eval_par(p, N, x, y, z, NULL, f, 2, &e);
    uint64_t u2 = frep_program_work_used(p);
    uint64_t least = 0;
    for (i = 0; i < N; i++) least += (uint64_t)ceil(x[i]);
    ok(u1 == u2 && u1 >= least && u1 < 2 * least + N,
       "1 and 2 threads count the same work (%llu; %llu iterations at least)",
       (unsigned long long)u1, (unsigned long long)least);
    /* over the budget: NaN with the budget's error at the loop's jump, at any thread count */
    for (int t = 1; t <= 2; t++) {
        frep_program_set_work_limit(p, (uint64_t)N);
        frep_eval_par(p, N, x, y, z, NULL, f, t, &e);
        size_t nans = 0;
        for (i = 0; i < N; i++) nans += isnan(f[i]) != 0;
        ok(frep_program_work_spent(p) && e.count > 0 && e.count == nans && e.pc == jmp &&
               e.what && strstr(e.what, "work budget") != NULL,
           "%d thread%s: over the budget, %zu points NaN with the error '%s' at the jump", t,
           t == 1 ? "" : "s", nans, e.what ? e.what : "");
    }
    frep_eval_par(p, 1, x, y, z, NULL, f, 1, &e2);
    ok(isnan(f[0]) && e2.count == 1 && e2.pc == jmp,
       "once spent, the next evaluation is NaN at once, with the error");
    ok(frep_eval_grad_par(p, 3, x, y, z, NULL, f, gx, gy, gz, 1, &e2) == 0 && isnan(f[2]) &&
           isnan(gx[0]) && isnan(gz[2]) && e2.count == 3,
       "the gradient evaluator refuses too: values and gradients NaN");
    frep_program_set_work_limit(p, 0);
    ok(frep_program_work_limit(p) == 0 && !frep_program_work_spent(p) &&
           frep_eval_par(p, 1, x, y, z, NULL, f, 1, &e2) == 0 && e2.count == 0 &&
           f[0] == ceil(x[0]) + y[0],
       "limit 0 removes the budget: the program evaluates again");
    frep_program_free(p);

    /* the interval evaluator: a constant 1000-iteration loop */
    p = count_program(1, 1000, &jmp);
    vm_iscratch *is = vm_iscratch_new(p);
    double box[6] = { 0, 0, 0, 1, 1, 1 };
    ival r;
    frep_program_set_work_limit(p, 1500 * VM_WORK_BOX);
    vm_eval_interval(p, is, box, NULL, &r);
    /* (the widened bounds of i leave the exit undecided at i = 1000: [-inf, inf]) */
    ok(frep_program_work_used(p) == 1000 * VM_WORK_BOX,
       "interval evaluation counts a box's 1000 iterations as VM_WORK_BOX points' (%llu)",
       (unsigned long long)frep_program_work_used(p));
    vm_eval_interval(p, is, box, NULL, &r);
    ok(frep_program_work_spent(p) && isinf(r.lo) && isinf(r.hi),
       "over the budget, interval evaluation gives [-inf, inf]");
    vm_iscratch_free(is);
    /* a program without loops never spends, and evaluates past a spent budget */
    frep_program_free(p);
    p = mixed_program();
    frep_program_set_work_limit(p, 1);
    ok(frep_eval_par(p, 100, x, y, z, NULL, f, 1, &e) == 0 && !isnan(f[0]) &&
           frep_program_work_used(p) == 0,
       "a program without loops spends nothing");
    frep_program_free(p);
}

/* ---- the cancel flag (frep_program_set_cancel) ------------------------------------ */

static void test_cancel_flag(void)
{
    enum { N = 3000 };
    static double x[N], y[N], z[N], f[N];
    volatile sig_atomic_t flag = 0;
    frep_runtime_error e;
    uint32_t jmp;
    size_t i, nans = 0;
    frep_program *p = count_program(0, 0, &jmp);
    if (!p) return;
    for (i = 0; i < N; i++) x[i] = 3, y[i] = urand(-1, 1), z[i] = 0;
    ok(frep_program_set_cancel(p, &flag) == 0 && frep_program_work_limit(p) == 0,
       "a cancel flag alone sets no work budget");
    ok(frep_eval_par(p, N, x, y, z, NULL, f, 2, &e) == 0 && e.count == 0 && f[N - 1] == 3 + y[N - 1],
       "flag clear: the loop runs, the values are right");
    flag = 1;
    frep_eval_par(p, N, x, y, z, NULL, f, 2, &e);
    for (i = 0; i < N; i++) nans += isnan(f[i]) != 0;
    ok(nans == N && e.count == N && e.pc == jmp && e.what && strstr(e.what, "cancelled") &&
           !frep_program_work_spent(p),
       "flag set: every point NaN with '%s' at the loop's jump, the budget not spent",
       e.what ? e.what : "");
    frep_program_set_work_limit(p, 0);
    frep_eval_par(p, 1, x, y, z, NULL, f, 1, &e);
    ok(isnan(f[0]), "removing the budget keeps the flag");
    ok(frep_program_set_work_limit(p, 10ull * N) == 0 && frep_program_set_cancel(p, NULL) == 0 &&
           frep_eval_par(p, N, x, y, z, NULL, f, 1, &e) == 0 && e.count == 0 &&
           frep_program_work_limit(p) == 10ull * N && frep_program_work_used(p) == 3ull * N,
       "without the flag the budget still counts, and the program evaluates");
    frep_program_free(p);

    p = count_program(1, 1000, &jmp);
    vm_iscratch *is = vm_iscratch_new(p);
    double box[6] = { 0, 0, 0, 1, 1, 1 };
    ival r;
    frep_program_set_cancel(p, &flag);
    vm_eval_interval(p, is, box, NULL, &r);
    ok(isinf(r.lo) && isinf(r.hi), "flag set: interval evaluation gives [-inf, inf]");
    vm_iscratch_free(is);
    frep_program_free(p);

    p = mixed_program();
    frep_program_set_cancel(p, &flag);
    ok(frep_eval_par(p, 100, x, y, z, NULL, f, 1, &e) == 0 && e.count == 0 && !isnan(f[0]),
       "a program without loops evaluates with the flag set");
    frep_program_free(p);
}

/* ---- sin and cos: opsem.h's own, against libm ---------------------------------- */

/* |a - b| in ulps of b. */
static double ulps(double a, double b)
{
    if (a == b) return 0;
    return fabs(a - b) / (nextafter(fabs(b), INFINITY) - fabs(b));
}

static void test_trig(void)
{
    double worst = 0, wx = 0;
    int range, bounded = 1;
    long k;
    /* random arguments over growing ranges up to the fast path's limit */
    for (range = 0; range < 4; range++) {
        double R = range == 0 ? 1 : range == 1 ? 10 : range == 2 ? 1000 : OPSEM_TRIG_MAX;
        for (k = 0; k < 100000; k++) {
            double x = urand(-R, R), sv = opsem_sin(x), cv = opsem_cos(x);
            double e = fmax(ulps(sv, sin(x)), ulps(cv, cos(x)));
            if (e > worst) { worst = e; wx = x; }
            if (!(fabs(sv) <= 1 && fabs(cv) <= 1)) bounded = 0;
        }
    }
    /* next to multiples of pi/2, where the reduction cancels */
    for (k = 1; k < 636000; k += 997) {
        double x = (double)k * 1.5707963267948966, y = x;
        int d;
        for (d = 0; d < 4; d++) {
            double e = fmax(ulps(opsem_sin(y), sin(y)), ulps(opsem_cos(y), cos(y)));
            if (e > worst) { worst = e; wx = y; }
            y = nextafter(y, INFINITY);
        }
    }
    ok(worst <= OPSEM_TRIG_ULPS, "sin, cos within %d ulp of libm for |x| <= %g (worst %.2f at %.17g)",
       OPSEM_TRIG_ULPS, OPSEM_TRIG_MAX, worst, wx);
    ok(bounded, "sin, cos stay in [-1, 1]");
    ok(same(opsem_sin(-0.0), -0.0) && same(opsem_sin(0.0), 0.0) && same(opsem_cos(-0.0), 1.0) &&
       same(opsem_sin(5e-324), 5e-324) && same(opsem_sin(-1e-300), -1e-300),
       "sin keeps signed zeros and tiny arguments; cos(-0) = 1");
    ok(same(opsem_sin(1e7), sin(1e7)) && same(opsem_cos(-3e300), cos(-3e300)) &&
       isnan(opsem_sin(INFINITY)) && isnan(opsem_cos(-INFINITY)) && isnan(opsem_sin(NAN)),
       "outside the fast range: libm's values; inf and NaN give NaN");
    {
        /* the vectorized VM loop gives the scalar bits, also with slow lanes mixed in */
        double x[NB], y[NB], z[NB], out[NB];
        size_t i;
        int op, okv = 1;
        vm_scratch *sc = vm_scratch_new(NULL);
        for (i = 0; i < NB; i++) {
            x[i] = i % 50 == 7 ? 3e9 : urand(-20, 20);
            y[i] = z[i] = 0;
        }
        for (op = FREP_OP_SIN; op <= FREP_OP_COS; op++) {
            frep_program *p = prog_new();
            vm_inputs in = inputs(x, y, z, NULL);
            emit(p, FREP_OP_X, 0, 0, 0);
            emit(p, (frep_opcode)op, 0, 0, 0);
            p = finish(p);
            if (!p || vm_eval_block(p, sc, &in, NB, out) != 0) { okv = 0; continue; }
            for (i = 0; i < NB; i++)
                if (!same(out[i], op_scalar((frep_opcode)op, x[i], 0, 0, 0, NULL))) okv = 0;
            frep_program_free(p);
        }
        ok(okv, "sin, cos: the block VM equals the scalar reference bit for bit");
        vm_scratch_free(sc);
    }
    {
        /* The VM keeps the cosine computed with a sine (and the reverse) for a later
         * instruction on the same input or slot: it must never serve a stale value. */
        double x[NB], y[NB], z[NB], out[NB];
        size_t i;
        int which, okc = 1;
        vm_scratch *sc = vm_scratch_new(NULL);
        for (i = 0; i < NB; i++) {
            x[i] = i % 61 == 5 ? -2e7 : urand(-9, 9);
            y[i] = z[i] = 0;
        }
        for (which = 0; which < 3; which++) {
            frep_program *p = prog_new();
            vm_inputs in = inputs(x, y, z, NULL);
            if (which == 0) {
                /* cos(3 sin(2x)) + x: the argument of COS reuses the buffer that
                 * held 2x, the argument of SIN */
                emit(p, FREP_OP_X, 0, 0, 0);
                emit(p, FREP_OP_MUL, 0, 2.0, INSN_KB);
                emit(p, FREP_OP_SIN, 0, 0, 0);
                emit(p, FREP_OP_MUL, 0, 3.0, INSN_KB);
                emit(p, FREP_OP_COS, 0, 0, 0);
                emit(p, FREP_OP_X, 0, 0, 0);
            } else if (which == 1) {
                /* s0 = 2x; sin(s0); s0 = x (copied into the same buffer); cos(s0) */
                emit(p, FREP_OP_X, 0, 0, 0);
                emit(p, FREP_OP_MUL, 0, 2.0, INSN_KB);
                emit(p, FREP_OP_STORE, 0, 0, 0);
                emit(p, FREP_OP_LOAD, 0, 0, 0);
                emit(p, FREP_OP_SIN, 0, 0, 0);
                emit(p, FREP_OP_X, 0, 0, 0);
                emit(p, FREP_OP_STORE, 0, 0, 0);
                emit(p, FREP_OP_LOAD, 0, 0, 0);
                emit(p, FREP_OP_COS, 0, 0, 0);
            } else {
                /* sin(x) + cos(x): the cached partner */
                emit(p, FREP_OP_X, 0, 0, 0);
                emit(p, FREP_OP_SIN, 0, 0, 0);
                emit(p, FREP_OP_X, 0, 0, 0);
                emit(p, FREP_OP_COS, 0, 0, 0);
            }
            emit(p, FREP_OP_ADD, 0, 0, 0);
            p = finish(p);
            if (!p || vm_eval_block(p, sc, &in, NB, out) != 0) { okc = 0; continue; }
            for (i = 0; i < NB; i++) {
                double want = which == 0 ? opsem_cos(3 * opsem_sin(2 * x[i])) + x[i]
                            : which == 1 ? opsem_sin(2 * x[i]) + opsem_cos(x[i])
                                         : opsem_sin(x[i]) + opsem_cos(x[i]);
                if (!same(out[i], want)) {
                    if (okc) diag("case %d lane %zu: got %.17g want %.17g", which, i, out[i], want);
                    okc = 0;
                }
            }
            frep_program_free(p);
        }
        ok(okc, "sin/cos partner cache: level buffers, stores and inputs give fresh values");
        vm_scratch_free(sc);
    }
}

/* The interval bounds' outward rounding (ival_next_down/up) is nextafter's, bit for
 * bit: zeros, subnormals, the largest doubles, infinities on the side they may take,
 * and a million random bit patterns. */
static void test_next_ulp(void)
{
    const double special[] = { 0.0, -0.0, DBL_TRUE_MIN, -DBL_TRUE_MIN, DBL_MIN, -DBL_MIN,
                               DBL_MAX, -DBL_MAX, 1.0, -1.0, 0.1, -3.5e-310 };
    int bad = 0, n = 0;
    for (size_t i = 0; i < sizeof special / sizeof *special; i++, n++) {
        double x = special[i];
        bad += memcmp(&(double){ ival_next_down(x) }, &(double){ nextafter(x, -INFINITY) },
                      sizeof x) != 0;
        bad += memcmp(&(double){ ival_next_up(x) }, &(double){ nextafter(x, INFINITY) },
                      sizeof x) != 0;
    }
    bad += ival_next_down(INFINITY) != DBL_MAX || ival_next_up(-INFINITY) != -DBL_MAX;
    uint64_t u = 0x9e3779b97f4a7c15u;
    for (int i = 0; i < 1000000; i++) {
        u ^= u << 13, u ^= u >> 7, u ^= u << 17;
        double x;
        memcpy(&x, &u, sizeof x);
        if (isnan(x) || isinf(x)) continue;
        double a = ival_next_down(x), b = nextafter(x, -INFINITY);
        double c = ival_next_up(x), d = nextafter(x, INFINITY);
        bad += memcmp(&a, &b, sizeof a) != 0 || memcmp(&c, &d, sizeof c) != 0;
        n++;
    }
    ok(bad == 0, "interval rounding: ival_next_down/up equal nextafter on %d doubles "
                 "(%d differ)", n, bad);
}

int main(void)
{
    test_program();
    test_next_ulp();
    test_trig();
    test_opsem_parity();
    test_tangents();
    test_kink_rules();
    test_batch_vs_single();
    test_branches();
    test_slots();
    test_domain_errors();
    test_thread_sizing();
    test_par_for_late();
    test_threads();
    test_public_api();
    test_work_budget();
    test_cancel_flag();
    return done_testing();
}

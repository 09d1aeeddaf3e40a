/* test_compile.c - tests of the compiler (lang/check.c, ir.c, lower.c, emit.c,
 * compile.c): diagnostics with positions, folding and CSE in instruction counts,
 * control flow evaluated at points on both sides, loops, free parameters, limits,
 * and allocation failures (reported as "out of memory", never as something else).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "frep.h"
#include "lower.h"
#include "program.h"
#include "tap.h"

/* Collected diagnostics of one compile. */
#define MAX_DIAGS 64
typedef struct diags {
    int n, errors, warnings;
    char msg[MAX_DIAGS][512];
    uint32_t line[MAX_DIAGS], col[MAX_DIAGS], len[MAX_DIAGS];
    frep_severity sev[MAX_DIAGS];
} diags;

static void collect(void *user, const frep_diag *d)
{
    diags *D = user;
    if (d->severity == FREP_ERROR) D->errors++;
    if (d->severity == FREP_WARNING) D->warnings++;
    if (D->n >= MAX_DIAGS) return;
    (void)snprintf(D->msg[D->n], sizeof D->msg[0], "%s", d->message);
    D->line[D->n] = d->line;
    D->col[D->n] = d->col;
    D->len[D->n] = d->len;
    D->sev[D->n] = d->severity;
    D->n++;
}

static frep_program *compile_opt(const char *src, diags *D, const frep_compile_options *o)
{
    memset(D, 0, sizeof *D);
    return frep_compile("t.hf", src, strlen(src), o, collect, D);
}

static frep_program *compile(const char *src, diags *D)
{
    return compile_opt(src, D, NULL);
}

/* Index of the first diagnostic containing `part`, or -1. */
static int find_diag(const diags *D, const char *part)
{
    int i;
    for (i = 0; i < D->n; i++)
        if (strstr(D->msg[i], part)) return i;
    return -1;
}

static void dump(const diags *D)
{
    int i;
    for (i = 0; i < D->n; i++)
        diag("  %u:%u (+%u): %s", (unsigned)D->line[i], (unsigned)D->col[i],
             (unsigned)D->len[i], D->msg[i]);
}

/* Expect an error containing `part` at line:col. */
static void expect_error(const char *src, const char *part, uint32_t line, uint32_t col,
                         const char *what)
{
    diags D;
    frep_program *p = compile(src, &D);
    int i = find_diag(&D, part);
    ok(p == NULL && i >= 0 && D.sev[i] == FREP_ERROR && D.line[i] == line && D.col[i] == col,
       "%s: error '%s' at %u:%u", what, part, (unsigned)line, (unsigned)col);
    if (!(p == NULL && i >= 0 && D.line[i] == line && D.col[i] == col)) dump(&D);
    frep_program_free(p);
}

static double eval1(const frep_program *p, double x, double y, double z)
{
    frep_scratch *s = frep_scratch_new(p);
    double f = NAN;
    if (s && frep_eval(p, s, 1, &x, &y, &z, NULL, &f) != 0) f = NAN;
    frep_scratch_free(s);
    return f;
}

static size_t count_op(const frep_program *p, frep_opcode op)
{
    size_t i, n = 0;
    for (i = 0; i < p->ncode; i++) n += p->code[i].op == op;
    return n;
}

static void test_basic(void)
{
    diags D;
    frep_program *p = compile("m(x[3], a[1]) { m = 1 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3]; }", &D);
    ok(p != NULL, "sphere compiles");
    if (!p) { dump(&D); return; }
    is_double(eval1(p, 0, 0, 0), 1.0, 0, "sphere at origin");
    is_double(eval1(p, 0.5, 0.5, 0.5), 0.25, 1e-15, "sphere at (.5,.5,.5)");
    ok(count_op(p, FREP_OP_SQUARE) == 3, "x*x becomes SQUARE");
    frep_program_free(p);
}

/* Evaluate at n points along x (y = z = 0 unless given) into f. */
static void eval_n(const frep_program *p, size_t n, const double *x, const double *y,
                   const double *z, const double *params, double *f)
{
    frep_scratch *s = frep_scratch_new(p);
    if (!s || frep_eval(p, s, n, x, y, z, params, f) != 0) {
        size_t i;
        for (i = 0; i < n; i++) f[i] = NAN;
    }
    frep_scratch_free(s);
}

static void test_checks(void)
{
    diags D;
    frep_program *p;
    expect_error("m(x[3], a[1]) {\n  rad = 1;\n  m = radd + x[1];\n}", "unknown variable 'radd'; "
                 "did you mean 'rad'?", 3, 7, "unknown variable");
    expect_error("m(x[3], a[1]) {\n  m = r;\n  r = 1;\n}", "variable 'r' is used before it is "
                 "assigned", 2, 7, "use before assignment");
    expect_error("m(x[3], a[1]) {\n  array c[2];\n  c = [1, 2];\n  m = c + 1;\n}",
                 "array 'c' used as a number", 4, 7, "array as a number");
    expect_error("m(x[3], a[1]) { m = x[4]; }", "index 4 is out of range for array 'x' of "
                 "size 3", 1, 23, "constant index out of range");
    expect_error("m(x[3], a[1]) { m = x[0]; }", "index 0 is out of range", 1, 23,
                 "index 0 (indices are 1-based)");
    expect_error("m(x[3], a[1]) { r = 1; }", "model 'm' never assigns its result", 1, 1,
                 "model without result");
    expect_error("a1(x[3], a[1]) { a1 = b1(x, a); }\nb1(x[3], a[1]) { b1 = 1; }",
                 "model 'b1' is defined later", 1, 23, "call of a later model");
    expect_error("m(x[3], a[1]) { m = m(x, a); }", "model 'm' cannot call itself", 1, 21,
                 "recursion");
    expect_error("m(x[3], a[1]) { m = hfSphere(x, 1); }", "'hfSphere' takes 3 arguments, 2 "
                 "given", 1, 21, "arity");
    expect_error("m(x[3], a[1]) { m = sqrt(1, 2); }", "'sqrt' takes 1 argument, 2 given", 1, 21,
                 "built-in arity");
    expect_error("m(x[3], a[1]) {\n  array c[3];\n  c = [0, 0, 0];\n  m = hfSphere(x, c, c);\n}",
                 "argument 3 of 'hfSphere' must be a number, but 'c' is an array", 4, 22,
                 "number argument given an array");
    expect_error("m(x[3], a[1]) { m = hfSphere(x, 1, 2); }", "argument 2 of 'hfSphere' must be "
                 "an array", 1, 33, "array argument given a number");
    expect_error("m(x[3], a[1]) {\n  array c[2];\n  c = [0, 0];\n  m = hfSphere(x, c, 1);\n}",
                 "argument 2 of 'hfSphere' must have at least 3 elements, 'c' has 2", 4, 19,
                 "array argument too small");
    expect_error("m(x[3], a[1]) { m = x[1] < 2; }", "comparison '<' is only allowed in an if or "
                 "while condition", 1, 26, "comparison outside a condition");
    expect_error("m(x[3], a[1]) {\n  array c[2];\n  c = 3;\n  m = 1;\n}",
                 "cannot assign a number to array 'c'", 3, 3, "number assigned to an array");
    expect_error("m(x[3], a[1]) {\n  array c[2], a[3];\n  m = 1;\n}",
                 "array 'a' is already declared", 2, 15, "an array named like a parameter");
    /* An array declared twice: the first declaration counts, as in the reference
     * (HF_Find_In_Name_Array finds the first), so c has 2 elements. */
    expect_error("m(x[3], a[1]) {\n  array c[2], c[3];\n  c[3] = 1;\n  m = 1;\n}",
                 "index 3 is out of range for array 'c' of size 2", 3, 5,
                 "duplicate array: the first declaration counts");
    expect_error("m(x[3], a[1]) {\n  array c[2];\n  c = [1, 2, 3];\n  m = 1;\n}",
                 "array 'c' has 2 elements, but 3 values are assigned", 3, 3,
                 "array literal too long");
    expect_error("u(x[3], a[2]) { u = a[2]; }\nm(x[3], a[1]) { m = u(x, a); }",
                 "array 'a' has 1 elements; model 'u' needs 2 for 'a'", 2, 26,
                 "model call with a small array");
    expect_error("u(x[3], a[1]) { u = 1; }\nm(x[3], a[1]) { m = u(x); }",
                 "model 'u' takes 2 array arguments, 1 given", 2, 21, "model call arity");
    expect_error("m(x[3], a[1]) {\n  r = 1; -- @free\n  r = 2; -- @free\n  m = r;\n}",
                 "'@free' must mark the first assignment", 3, 13, "@free on a reassignment");
    expect_error("m(x[3], a[1]) {\n  r = 1 + 2; -- @free\n  m = r;\n}",
                 "'@free' must follow a statement 'name = NUMBER;'", 2, 17, "@free on an expression");
    expect_error("m(x[3], a[1]) {\n  r = 1; -- @free [2, 1]\n  m = r;\n}",
                 "are empty", 2, 13, "@free with empty bounds");
    expect_error("m(x[3], a[1]) {\n  r = 1; -- @free [0 1]\n  m = r;\n}",
                 "malformed '@free'", 2, 13, "@free with malformed bounds");
    expect_error("m(x[3], a[1]) { m = 1; }\n-- @setops minmax\n", "'@setops' must come before "
                 "the first model", 2, 4, "@setops after a model");
    expect_error("-- @setops ralpha 3\nm(x[3], a[1]) { m = 1; }", "ALPHA in [-1, 1]", 1, 4,
                 "@setops ralpha out of range");
    expect_error("-- @box 1 2 3\nm(x[3], a[1]) { m = 1; }", "'@box' expects six numbers", 1, 4,
                 "@box with three numbers");

    /* Every problem is reported, not only the first. */
    p = compile("m(x[3], a[1]) {\n  m = foo(x) + bar + x[7];\n  z = 1 < 2;\n}", &D);
    ok(p == NULL && D.errors == 4, "four independent errors reported together (got %d)",
       D.errors);
    if (D.errors != 4) dump(&D);
    frep_program_free(p);

    /* Unknown pragma: warning only. */
    p = compile("-- @frobnicate 3\nm(x[3], a[1]) { m = 1; }", &D);
    ok(p != NULL && D.warnings == 1 && find_diag(&D, "unknown pragma '@frobnicate'") >= 0 &&
           D.line[0] == 1 && D.col[0] == 4,
       "unknown pragma: a warning at its '@'");
    frep_program_free(p);
}

static void test_fold_cse(void)
{
    diags D;
    frep_compile_options o;
    frep_program *p, *q;
    double x[3] = { -0.7, 0.3, 2 }, y[3] = { 0, 0, 0 }, f1[3], f2[3];
    const char *twice = "m(x[3], a[1]) { m = sin(x[1]) * 2 + sin(x[1]) * (4 - 1); }";
    frep_compile_options_init(&o);
    p = compile(twice, &D);
    o.optimize = 0;
    q = compile_opt(twice, &D, &o);
    ok(p && q, "CSE test compiles with and without optimization");
    if (!p || !q) return;
    is_int(count_op(p, FREP_OP_SIN), 1, "CSE: sin(x[1]) computed once");
    is_int(count_op(q, FREP_OP_SIN), 2, "optimize = 0: sin(x[1]) computed twice");
    is_int(count_op(p, FREP_OP_SUB), 0, "folding: 4 - 1 is folded");
    ok(p->ncode < q->ncode, "optimized code is shorter (%u < %u)", (unsigned)p->ncode,
       (unsigned)q->ncode);
    eval_n(p, 3, x, y, y, NULL, f1);
    eval_n(q, 3, x, y, y, NULL, f2);
    ok(f1[0] == f2[0] && f1[1] == f2[1] && f1[2] == f2[2],
       "optimized and unoptimized code agree exactly");
    is_double(f1[1], 5 * sin(0.3), 1e-15, "value of the CSE model");
    frep_program_free(p);
    frep_program_free(q);

    /* Exact simplifications only: x*1 and x-0 vanish, x+0 stays (-0 + 0 = +0). */
    p = compile("m(x[3], a[1]) { m = (x[1] * 1 - 0) / 1; }", &D);
    ok(p && p->ncode == 1 && p->code[0].op == FREP_OP_X, "x*1 - 0 / 1 is just x");
    frep_program_free(p);
    p = compile("m(x[3], a[1]) { m = x[1] + 0; }", &D);
    ok(p && count_op(p, FREP_OP_ADD) == 1, "x + 0 is kept (not exact for -0)");
    if (p) {
        double mz = -0.0, z0 = 0, f;
        eval_n(p, 1, &mz, &z0, &z0, NULL, &f);
        ok(f == 0 && !signbit(f), "-0 + 0 evaluates to +0");
    }
    frep_program_free(p);

    /* Folding a constant expression. */
    p = compile("m(x[3], a[1]) { m = x[1] + sqrt(16) * 2 ^ 3; }", &D);
    ok(p && count_op(p, FREP_OP_SQRT) == 0 && count_op(p, FREP_OP_POW) == 0 && p->ncode == 2,
       "sqrt(16) * 2^3 folded into an immediate");
    if (p) is_double(eval1(p, 1, 0, 0), 33, 0, "folded value");
    frep_program_free(p);

    /* A domain error is not folded: runtime reports it; compile warns. */
    p = compile("m(x[3], a[1]) {\n  m = x[1] + sqrt(-1);\n}", &D);
    ok(p && count_op(p, FREP_OP_SQRT) == 1, "sqrt(-1) is left for the runtime");
    ok(D.warnings == 1 && find_diag(&D, "sqrt of a negative number") >= 0 && D.line[0] == 2 &&
       D.col[0] == 14, "... with a warning at 'sqrt'");
    if (p) {
        frep_scratch *s = frep_scratch_new(p);
        frep_runtime_error e;
        double xx = 1, zz = 0, f = 0;
        frep_eval(p, s, 1, &xx, &zz, &zz, NULL, &f);
        frep_scratch_errors(s, &e);
        ok(isnan(f) && e.count == 1, "... and evaluates to NaN with a runtime error");
        frep_scratch_free(s);
    }
    frep_program_free(p);

    /* Integer powers: multiplication chains up to FREP_POW_CHAIN_MAX, then POW. */
    p = compile("m(x[3], a[1]) { m = x[1] ^ 3 + x[2] ^ -2 + x[3] ^ 0.5; }", &D);
    ok(p && count_op(p, FREP_OP_POW) == 1 && count_op(p, FREP_OP_SQUARE) == 2,
       "x^3 and x^-2 are multiplications, x^0.5 is POW");
    if (p) is_double(eval1(p, 1.5, 2, 4), 1.5 * 1.5 * 1.5 + 1 / (2.0 * 2.0) + 2, 1e-15,
                     "value of the powers");
    frep_program_free(p);
    p = compile("m(x[3], a[1]) { m = x[1] ^ 64 + x[2] ^ 65; }", &D);
    ok(p && count_op(p, FREP_OP_POW) == 1, "x^64 is a chain, x^65 a POW (FREP_POW_CHAIN_MAX)");
    frep_program_free(p);
}

static void test_control(void)
{
    diags D;
    frep_program *p, *q;
    double xs[4] = { -2, -0.5, 0.5, 2 }, zero[4] = { 0, 0, 0, 0 }, f[4], g[4];
    int i;
    /* Straight-line branches: select; both sides of x = 0. */
    p = compile("m(x[3], a[1]) {\n  if x[1] > 0 then\n    t = sqrt(x[1]);\n  else\n"
                "    t = -x[1] * 3;\n  endif;\n  m = t;\n}", &D);
    ok(p && count_op(p, FREP_OP_SELECT) == 1 && count_op(p, FREP_OP_JZ) == 0,
       "straight-line if becomes SELECT");
    if (p) {
        eval_n(p, 4, xs, zero, zero, NULL, f);
        ok(f[0] == 6 && f[1] == 1.5 && f[2] == sqrt(0.5) && f[3] == sqrt(2.0),
           "select if: values on both sides");
        for (i = 0; i < (int)p->ncode; i++)
            if (p->code[i].op == FREP_OP_SQRT) break;
        ok(i < (int)p->ncode && (p->code[i].flags & INSN_QUIET), "speculative sqrt is quiet");
        {
            frep_scratch *s = frep_scratch_new(p);
            frep_runtime_error e;
            frep_eval(p, s, 4, xs, zero, zero, NULL, f);
            frep_scratch_errors(s, &e);
            ok(e.count == 0, "no domain error from the branch not taken");
            frep_scratch_free(s);
        }
    }
    frep_program_free(p);

    /* A loop depending on x inside the if: real control flow. */
    p = compile("m(x[3], a[1]) {\n  n = 0;\n  if x[1] > 0 then\n    v = x[1];\n"
                "    while v < 8 loop v = v * 2; n = n + 1; endloop;\n  else\n    n = -1;\n"
                "  endif;\n  m = n;\n}", &D);
    ok(p && count_op(p, FREP_OP_JZ) == 2, "if with a point-dependent loop: real branches");
    if (p) {
        eval_n(p, 4, xs, zero, zero, NULL, f);
        ok(f[0] == -1 && f[1] == -1 && f[2] == 4 && f[3] == 2, "real if/while: values (%g %g %g %g)",
           f[0], f[1], f[2], f[3]);
    }
    frep_program_free(p);

    /* The same loop unrolled (constant bound) and real (bound depends on x). */
    p = compile("m(x[3], a[1]) {\n  i = 0; s = 0;\n  while i < 5 loop\n    s = s + x[1] * i;\n"
                "    i = i + 1;\n  endloop;\n  m = s;\n}", &D);
    q = compile("m(x[3], a[1]) {\n  i = 0; s = 0;\n  while i < 5 + 0 * x[1] loop\n"
                "    s = s + x[1] * i;\n    i = i + 1;\n  endloop;\n  m = s;\n}", &D);
    ok(p && q && count_op(p, FREP_OP_JMP) == 0 && count_op(q, FREP_OP_JMP) == 1,
       "constant loop unrolled, point-dependent loop kept");
    if (p && q) {
        eval_n(p, 4, xs, zero, zero, NULL, f);
        eval_n(q, 4, xs, zero, zero, NULL, g);
        ok(f[0] == g[0] && f[1] == g[1] && f[2] == g[2] && f[3] == g[3] && f[3] == 20,
           "unrolled and real loops agree");
    }
    frep_program_free(p);
    frep_program_free(q);

    /* Dynamic index in a real loop: LOADI/STOREI. */
    p = compile("m(x[3], a[1]) {\n  array c[4];\n  c = [10, 20, 30, 40];\n  k = 1;\n"
                "  while k < x[1] loop k = k + 1; endloop;\n  r = c[k];\n  c[k] = -1;\n"
                "  m = r + c[k];\n}", &D);
    ok(p && count_op(p, FREP_OP_LOADI) >= 1 && count_op(p, FREP_OP_STOREI) == 1,
       "dynamic index uses LOADI/STOREI");
    if (p) {
        double x2[3] = { 1, 2.5, 9 };
        eval_n(p, 3, x2, zero, zero, NULL, f);
        ok(f[0] == 9 && f[1] == 29 && isnan(f[2]), "dynamic index values, NaN out of range");
    }
    frep_program_free(p);

    /* A write out of the array: the reference stops ("Index out of range"), frep's value
     * is NaN, though the result does not read the array. */
    p = compile("m(x[3], a[1]) {\n  array c[2];\n  c[x[1]] = 1;\n  m = x[2] + 5;\n}", &D);
    ok(p && count_op(p, FREP_OP_STOREI) == 1, "a point-dependent write: STOREI");
    if (p) {
        double x2[4] = { 1, 2, 3, 0 }, y2[4] = { 1, 2, 3, 4 };
        eval_n(p, 4, x2, y2, zero, NULL, f);
        ok(f[0] == 6 && f[1] == 7 && isnan(f[2]) && isnan(f[3]),
           "a write out of range: NaN at that point");
    }
    frep_program_free(p);

    /* Runaway loops are stopped. */
    p = compile("m(x[3], a[1]) {\n  v = 0;\n  while x[1] < 1 loop v = v + 1; endloop;\n"
                "  m = v;\n}", &D);
    if (p) {
        frep_scratch *s = frep_scratch_new(p);
        frep_runtime_error e;
        double xx[2] = { 0, 2 }, zz[2] = { 0, 0 };
        frep_eval(p, s, 2, xx, zz, zz, NULL, f);
        frep_scratch_errors(s, &e);
        ok(isnan(f[0]) && f[1] == 0 && e.count == 1, "runaway loop stopped: NaN + error");
        frep_scratch_free(s);
    } else {
        ok(0, "runaway loop compiles");
    }
    frep_program_free(p);

    /* A constant infinite loop: unrolled up to FREP_MAX_UNROLL, then a real loop. */
    p = compile("m(x[3], a[1]) {\n  i = 0;\n  while 1 < 2 loop i = i + 1; endloop;\n  m = i;\n}", &D);
    ok(p && find_diag(&D, "loop not unrolled after 100000 iterations") >= 0,
       "FREP_MAX_UNROLL: warning, loop kept");
    if (p) ok(isnan(eval1(p, 0, 0, 0)), "... and stopped at runtime");
    frep_program_free(p);

    /* FREP_MAX_UNROLL_NODES: a loop with a big body stops unrolling earlier. */
    p = compile("m(x[3], a[1]) {\n  i = 0; s = 0;\n  while i < 200000 loop\n"
                "    s = s + sin(x[1] + i) * cos(x[2] + i) * tan(x[3] + i) * exp(x[1] - i);\n"
                "    i = i + 1;\n  endloop;\n  m = s;\n}", &D);
    {
        int k = find_diag(&D, "loop not unrolled after ");
        ok(p && k >= 0 && !strstr(D.msg[k], "after 100000 "),
           "FREP_MAX_UNROLL_NODES: unrolling stops on the node budget");
        if (k >= 0) diag("  %s", D.msg[k]);
    }
    frep_program_free(p);
}

static void test_params(void)
{
    diags D;
    frep_compile_options o;
    frep_program *p;
    const char *src = "m(x[3], a[2]) {\n  r = -0.5; -- @free [-1, 1]\n  k = 2;  -- @free\n"
                      "  m = a[2] * x[1] + r * k;\n}";
    double av[2] = { 7, 3 };
    frep_compile_options_init(&o);
    o.a = av;
    o.na = 2;
    p = compile_opt(src, &D, &o);
    ok(p != NULL, "free parameters compile");
    if (!p) { dump(&D); return; }
    is_int(frep_program_nparams(p), 4, "a[1], a[2], r, k");
    is_str(frep_program_param_name(p, 1), "a[2]", "name of a[2]");
    is_double(frep_program_param_value(p, 1), 3, 0, "a[2] from the options");
    is_str(frep_program_param_name(p, 2), "r", "name of r");
    is_double(frep_program_param_value(p, 2), -0.5, 0, "value of r");
    {
        double lo = 0, hi = 0;
        ok(frep_program_param_bounds(p, 2, &lo, &hi) == 1 && lo == -1 && hi == 1, "bounds of r");
        ok(frep_program_param_bounds(p, 3, &lo, &hi) == 0, "k has no bounds");
    }
    ok(p->params[2].off == (uint32_t)(strstr(src, "-0.5") - src) &&
       p->params[2].end == p->params[2].off + 4, "span of r's literal includes the minus");
    ok(p->params[3].off == (uint32_t)(strstr(src, "2;") - src) && p->params[3].end ==
       p->params[3].off + 1, "span of k's literal");
    ok(p->params[2].pos.line == 2 && p->params[2].pos.col == 7, "position of r's literal");
    is_double(eval1(p, 2, 0, 0), 3 * 2 - 1, 0, "value with the initial parameters");
    {
        double pv[4] = { 0, 1, 0.25, 4 }, xx = 2, zz = 0, f;
        eval_n(p, 1, &xx, &zz, &zz, pv, &f);
        is_double(f, 2 + 1, 0, "value with other parameters");
    }
    frep_program_free(p);
}

static void test_models(void)
{
    diags D;
    frep_compile_options o;
    frep_program *p;
    size_t n = 0;
    char **names;
    const char *src = "shift(x[3], a[1]) {\n  d = hfShift3D(x, 1, 0, 0);\n  shift = x[1];\n}\n"
                      "my_model(x[3], a[1]) {\n  t = shift(x, a);\n  my_model = t * 10 + x[1];\n}\n"
                      "last(x[3], a[1]) { last = 5; }\n";
    p = compile(src, &D);
    ok(p && strcmp(p->model, "my_model") == 0, "my_model is the default");
    if (p) is_double(eval1(p, 3, 0, 0), 23, 0, "model call: arrays passed by value");
    frep_program_free(p);
    frep_compile_options_init(&o);
    o.model = "LAST";
    p = compile_opt(src, &D, &o);
    ok(p && strcmp(p->model, "last") == 0 && eval1(p, 0, 0, 0) == 5, "--model (case-insensitive)");
    frep_program_free(p);
    o.model = "nope";
    p = compile_opt(src, &D, &o);
    ok(!p && find_diag(&D, "no model named 'nope'") >= 0, "unknown --model");
    /* The reference interpreter and hfp evaluate the first body of a file. */
    p = compile("a1(x[3], a[1]) { a1 = 1; }\nb1(x[3], a[1]) { b1 = 2; }", &D);
    ok(p && eval1(p, 0, 0, 0) == 1, "without my_model: the first model");
    frep_program_free(p);
    names = frep_list_models("t.hf", src, strlen(src), &n, collect, &D);
    ok(names && n == 3 && strcmp(names[0], "shift") == 0 && strcmp(names[2], "last") == 0,
       "frep_list_models");
    frep_free_strings(names, n);

    /* x[4..] read 0; s[] starts at 0 and reads back what was written (int_calc.c of
     * HyperFun keeps s[] in the frame like any array). */
    p = compile("m(x[4], a[1], s[2]) {\n  t = s[1];\n  s[1] = 5;\n  m = x[4] + s[1] + x[1] + t;\n}",
                &D);
    ok(p && eval1(p, 2, 0, 0) == 7, "x[4] reads 0, s[1] reads what was written");
    frep_program_free(p);

    /* Set-operation semantics: pragma and override. */
    p = compile("-- @setops minmax\nm(x[3], a[1]) { m = x[1] | x[2] & x[3] \\ x[1]; }", &D);
    ok(p && count_op(p, FREP_OP_MAX) == 1 && count_op(p, FREP_OP_MIN) == 1 &&
       count_op(p, FREP_OP_MSUB) == 1, "@setops minmax");
    frep_program_free(p);
    frep_compile_options_init(&o);
    o.setops_override = FREP_SETOPS_RFUNC;
    p = compile_opt("-- @setops minmax\nm(x[3], a[1]) { m = x[1] | x[2] @ x[3]; }", &D, &o);
    ok(p && count_op(p, FREP_OP_RUNI) == 1 && count_op(p, FREP_OP_RINT) == 1,
       "override wins; '@' is an intersection as in the reference");
    frep_program_free(p);
    p = compile("-- @box -1 -2 -3 1 2 3\nm(x[3], a[1]) { m = 1; }", &D);
    {
        double b[6] = { 0 };
        ok(p && frep_program_box(p, b) == 1 && b[0] == -1 && b[5] == 3, "@box");
    }
    frep_program_free(p);
}

/* Attributes of n points of the line (t, 0, 0): s[i * K + k]. */
static int attrs_at(const frep_program *p, size_t n, const double *t, double *s)
{
    double y[8] = { 0 }, z[8] = { 0 };
    frep_runtime_error e;
    return frep_eval_attrs_par(p, n, t, y, z, NULL, s, 1, &e);
}

/* The attribute library's pattern, table and spline functions and hfBezierVolume
 * (hflibrary_lib of HyperFun: hfA_LookUpTable.c, hfA_SmoothLookUpTable.c,
 * hfA_spline.c, hfA_CheckerBoard.c, hfA_Circles.c, hfA_Crackles.c, hfA_noiseg.c,
 * hfBezierVolume.c).  Values worked out by hand from those sources, except the noise
 * values, which come from tests/conformance/hfref.py (an independent Python
 * transcription of the same formulas). */
static void test_hyperfun_tables(void)
{
    diags D;
    frep_program *p;
    double t4[4] = { 0.5, 1.5, -1, 2 }, s[16];

    /* rows (1,0,0) (0,1,0) (0,0,1) at entries 0, 1, 2; below the first entry the
     * reference ends with the last row (its "not found" case overwrites the first) */
    p = compile("m(x[3], a[1], s[3]) {\n  array e[3], tab[9];\n  e = [0, 1, 2];\n"
                "  tab = [1, 0, 0, 0, 1, 0, 0, 0, 1];\n  d = hfA_LookUpTable(x[1], s, tab, e);\n"
                "  m = d;\n}", &D);
    if (p && attrs_at(p, 4, t4, s) == 0)
        ok(s[0] == 1 && s[1] == 0 && s[4] == 1 && s[3] == 0 && s[8] == 1 && s[6] == 0 &&
           s[11] == 1 && s[9] == 0, "hfA_LookUpTable: rows, and the last row below and above");
    else
        ok(0, "hfA_LookUpTable compiles");
    frep_program_free(p);
    p = compile("m(x[3], a[1], s[3]) {\n  array e[3], tab[9];\n  e = [0, 1, 2];\n"
                "  tab = [1, 0, 0, 0, 1, 0, 0, 0, 1];\n"
                "  d = hfA_SmoothLookUpTable(x[1], s, tab, e);\n  m = d;\n}", &D);
    if (p && attrs_at(p, 4, t4, s) == 0)
        ok(s[0] == 0.5 && s[1] == 0.5 && s[2] == 0 && s[3] == 0 && s[4] == 0.5 &&
           s[5] == 0.5 && s[8] == 1 && s[11] == 1, "hfA_SmoothLookUpTable mixes rows");
    else
        ok(0, "hfA_SmoothLookUpTable compiles");
    frep_program_free(p);
    expect_error("m(x[3], a[1], s[3]) {\n  array e[3], tab[8];\n  d = hfA_LookUpTable(x[1], s, tab, e);\n"
                 "  m = d;\n}", "needs at least 9 elements", 3, 7, "hfA_LookUpTable: table size");

    /* Catmull-Rom through the squares 0 1 4 9 16 (two spans) reproduces the parabola:
     * at u in [0, 1], s = (1 + 2u)^2; u = 1 exactly is the reference's span
     * spans - 3 = -1, outside the knots: NaN. */
    p = compile("m(x[3], a[1], s[1]) {\n  array k[5];\n  k = [0, 1, 4, 9, 16];\n"
                "  d = hfA_Spline(s, k, x[1], 0, 1);\n  m = d;\n}", &D);
    {
        double tt[5] = { 0.25, 0.75, -1, 2, 1 };
        if (p && attrs_at(p, 5, tt, s) == 0)
            ok(fabs(s[0] - 2.25) < 1e-15 && fabs(s[1] - 6.25) < 1e-15 && s[2] == 0 &&
               s[3] == 16 && isnan(s[4]), "hfA_Spline: Catmull-Rom, ends, the u = 1 quirk");
        else
            ok(0, "hfA_Spline compiles");
    }
    frep_program_free(p);

    /* cells of 1 and gaps of 1: inside where 2 floor(x / 2) < x < 2 floor(x / 2) + 1 */
    p = compile("m(x[3], a[1], s[1]) {\n  array p[3], b[3], g[3], ib[1], ig[1];\n"
                "  p = [x[1], 0.5, 0.5];\n  b = [1, 1, 1];\n  g = [1, 1, 1];\n  ib = [7];\n"
                "  ig = [3];\n  d = hfA_CheckerBoard(p, b, g, s, ib, ig);\n  m = d;\n}", &D);
    {
        double tt[4] = { 0.5, 1.5, -1.5, 1 };
        if (p && attrs_at(p, 4, tt, s) == 0)
            ok(s[0] == 7 && s[1] == 3 && s[2] == 7 && s[3] == 3, "hfA_CheckerBoard");
        else
            ok(0, "hfA_CheckerBoard compiles");
    }
    frep_program_free(p);

    /* v = fmod(|x|, 1); map [0, 0.5, 1] selects row 1 (10, 20) or row 2 (30, 40), and
     * the reference first sets attr[4] (its color[n_prob], n_prob = 3) to 1.1 */
    p = compile("m(x[3], a[1], s[2]) {\n  array c[4], q[3];\n  c = [10, 20, 30, 40];\n"
                "  q = [0, 0.5, 1];\n  d = hfA_Circles(x, s, c, q);\n  m = d;\n}", &D);
    {
        double tt[4] = { 0.25, 0.75, 1.25, -2.75 };
        if (p && attrs_at(p, 4, tt, s) == 0)
            ok(s[0] == 10 && s[1] == 20 && s[2] == 30 && s[3] == 1.1 && s[4] == 10 &&
               s[5] == 20 && s[6] == 30 && s[7] == 1.1, "hfA_Circles");
        else
            ok(0, "hfA_Circles compiles");
    }
    frep_program_free(p);

    /* Crackles at (t, 0, 0), freq 1.5: hfref.py gives the pattern value 0.5188... at
     * t = 0.37 (row 2) and 0.1861... at t = 3.7 (row 1) */
    p = compile("m(x[3], a[1], s[1]) {\n  array c[2], q[3];\n  c = [1, 2];\n"
                "  q = [0, 0.5, 1];\n  d = hfA_Crackles(x, s, 1.5, c, q);\n  m = d;\n}", &D);
    {
        double tt[2] = { 0.37, 3.7 };
        if (p && attrs_at(p, 2, tt, s) == 0)
            ok(s[0] == 2 && s[1] == 1, "hfA_Crackles");
        else
            ok(0, "hfA_Crackles compiles");
    }
    frep_program_free(p);

    p = compile("m(x[3], a[1]) { m = hfA_NoiseG(x, 1.3, 2.0); }", &D);
    if (p) is_double(eval1(p, 0.3, -0.7, 1.1), 0.46716436744106343, 1e-14, "hfA_NoiseG");
    frep_program_free(p);

    /* Order 2 on each axis with w[i m n + j n + k] = 4i + 2j + k is the trilinear
     * 4u + 2v + t, v from x3 and t from x2 (the reference's order): 2.4 at
     * (0.5, 0.2, 0.1) in the unit box; then clipped by the box with R_int. */
    p = compile("m(x[3], a[1]) {\n  array b[6], w[8];\n  b = [0, 0, 0, 1, 1, 1];\n"
                "  w = [0, 1, 2, 3, 4, 5, 6, 7];\n  m = hfBezierVolume(x, 2, 2, 2, b, w);\n}", &D);
    if (p) {
        double X = 0.5 * 0.5, Y = 0.8 * 0.2, Z = 0.9 * 0.1, r;
        r = X + Y - sqrt(X * X + Y * Y);
        r = r + Z - sqrt(r * r + Z * Z);
        r = r + 2.4 - sqrt(r * r + 2.4 * 2.4);
        is_double(eval1(p, 0.5, 0.2, 0.1), r, 1e-14, "hfBezierVolume");
    }
    frep_program_free(p);
    expect_error("m(x[3], a[1]) {\n  array b[6], w[8];\n  m = hfBezierVolume(x, x[1], 2, 2, b, w);\n}",
                 "must be a constant", 3, 7, "hfBezierVolume: orders constant");
}

/* hfA_NoiseP and hfA_Turbulence: Perlin's noise3 with gradients from the fixed hash
 * doc/library.md gives (the reference's come from rand() seeded with the time). */
static double perlin_hash_component(double i, double j, double k, int m)
{
    static const double abc[3][3] = {
        { 12.9898, 78.233, 37.719 }, { 39.3467, 11.1351, 83.1554 }, { 73.156, 52.235, 9.151 }
    };
    double h = 43758.5453 * sin(abc[m][0] * i + abc[m][1] * j + abc[m][2] * k);
    return 2 * (h - floor(h)) - 1;
}

static void test_perlin(void)
{
    diags D;
    frep_program *p, *q;
    static const double lattice[][3] = { { 0, 0, 0 }, { 1, 2, 3 }, { -4, 7, 2 }, { -1, -1, -9 } };
    double lo = 1, hi = -1, sum = 0, sum2 = 0, worst_jump = 0;
    int i, same = 1, count = 0;
    p = compile("m(x[3], a[1]) { m = hfA_NoiseP(x); }", &D);
    q = compile("m(x[3], a[1], s[1]) { array y[3];\n y = [x[1], x[2], x[3]];\n"
                " s[1] = hfA_NoiseP(y);\n m = hfA_NoiseP(y); }", &D);
    if (!p || !q) {
        ok(0, "hfA_NoiseP compiles");
        frep_program_free(p);
        frep_program_free(q);
        return;
    }
    for (i = 0; i < 4; i++) {
        const double *l = lattice[i];
        double g[3], len = 0, h = 1e-7, slope[3];
        int d;
        is_double(eval1(p, l[0], l[1], l[2]), 0, 0, "hfA_NoiseP: 0 at a lattice point");
        /* the slope at a lattice point is its gradient: the documented hash, normalised */
        for (d = 0; d < 3; d++) {
            g[d] = perlin_hash_component(l[0], l[1], l[2], d);
            len += g[d] * g[d];
        }
        for (d = 0; d < 3; d++) {
            double e[3] = { l[0], l[1], l[2] };
            e[d] += h;
            slope[d] = eval1(p, e[0], e[1], e[2]) / h;
        }
        for (d = 0; d < 3; d++)
            is_double(slope[d], g[d] / sqrt(len), 1e-5, "hfA_NoiseP: the hashed gradient");
    }
    /* over a 20^3 grid of [-5, 5]^3 (off the lattice): within [-1, 1], mean ~0, not
     * flat, continuous (a step of 1e-6 moves it by less than 1e-4), the same in
     * another model, and s[] gets the same value */
    for (i = 0; i < 8000; i++) {
        double x = -5 + 10 * ((i % 20) + 0.37) / 20, y = -5 + 10 * ((i / 20 % 20) + 0.61) / 20;
        double z = -5 + 10 * ((i / 400) + 0.23) / 20, v = eval1(p, x, y, z);
        double w = eval1(p, x + 1e-6, y, z);
        if (fabs(w - v) > worst_jump) worst_jump = fabs(w - v);
        if (v != eval1(q, x, y, z)) same = 0;
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
        sum += v;
        sum2 += v * v;
        count++;
    }
    ok(lo > -1 && hi < 1 && lo < -0.3 && hi > 0.3, "hfA_NoiseP within [-1, 1], spread: [%.3f, %.3f]", lo, hi);
    ok(fabs(sum / count) < 0.02 && sqrt(sum2 / count) > 0.1, "hfA_NoiseP: mean %.4f, rms %.3f",
       sum / count, sqrt(sum2 / count));
    ok(worst_jump < 1e-4, "hfA_NoiseP continuous: largest change %.2g over 1e-6", worst_jump);
    ok(same, "hfA_NoiseP: the same in another model");
    {
        double s[1] = { 0 }, t[1] = { 0.3 };
        if (attrs_at(q, 1, t, s) == 0) is_double(s[0], eval1(p, 0.3, 0, 0), 0, "hfA_NoiseP into s[]");
    }
    frep_program_free(p);
    frep_program_free(q);

    /* hfA_Turbulence(x, 4) = |2n(4x) - 1|/4 + |2n(2x) - 1|/2 + |2n(x) - 1| */
    p = compile("m(x[3], a[1]) { array p[3], q[3];\n p = [4*x[1], 4*x[2], 4*x[3]];\n"
                " q = [2*x[1], 2*x[2], 2*x[3]];\n"
                " m = hfA_Turbulence(x, 4) - (abs(2*hfA_NoiseP(p) - 1)/4 + "
                "abs(2*hfA_NoiseP(q) - 1)/2 + abs(2*hfA_NoiseP(x) - 1)); }", &D);
    q = compile("m(x[3], a[1]) { m = hfA_Turbulence(x, 4); }", &D);
    if (p && q) {
        double worst = 0, least = 1e9;
        for (i = 0; i < 200; i++) {
            double x = sin(i * 1.3) * 3, y = cos(i * 0.7) * 3, z = i * 0.031 - 3;
            double d = fabs(eval1(p, x, y, z)), t = eval1(q, x, y, z);
            worst = d > worst ? d : worst;
            least = t < least ? t : least;
        }
        ok(worst < 1e-12, "hfA_Turbulence: the sum of its octaves (largest difference %.2g)", worst);
        ok(least > 0, "hfA_Turbulence > 0 (least %.3f)", least);
    } else
        ok(0, "hfA_Turbulence compiles");
    frep_program_free(p);
    frep_program_free(q);
    p = compile("m(x[3], a[1]) { m = hfA_Turbulence(x, 0.9); }", &D);
    if (p) is_double(eval1(p, 0.3, 0.2, 0.1), 0, 0, "hfA_Turbulence: no octave below freq 1");
    frep_program_free(p);
    expect_error("m(x[3], a[1]) { m = hfA_Turbulence(x, x[1]); }",
                 "the frequency freq must be a constant", 1, 21, "hfA_Turbulence: freq constant");
    expect_error("m(x[3], a[1]) { m = hfA_Turbulence(x, 1e10); }",
                 "more than 32 terms", 1, 21, "hfA_Turbulence: FREP_TURBULENCE_MAX_TERMS");
    expect_error("m(x[3], a[1], s[2]) { m = hfA_NoiseP(s); }",
                 "must have at least 3 elements", 1, 38, "hfA_NoiseP: a point of 3 coordinates");
}

/* Behaviour of the reference HyperFun interpreter (src/interpreter_lib of HyperFun:
 * int_calc.c, int_parse_N.c, int_global.c; src/hflibrary_lib for hfSawtooth and
 * hfA_*); every expected value is worked out by hand from that source. */
static void test_hyperfun(void)
{
    diags D;
    frep_program *p;
    double t[4] = { 1, -1, 0.5, 2 }, s[12];

    /* mod: fmod(HF_round(a), HF_round(b)), halves rounded up. */
    p = compile("m(x[3], a[1]) { m = mod(2.7, 2) * 1000 + mod(-7, 3) * 100 + "
                "mod(7.2, -3) * 10 + mod(-2.5, 2) + mod(x[1], 2.5); }", &D);
    /* 1000 - 100 + 10 + (-0) + fmod(round(x), 3) */
    if (p) is_double(eval1(p, 1.5, 0, 0), 910 + 2, 0, "mod rounds its arguments");
    if (p) is_double(eval1(p, -1.5, 0, 0), 910 - 1, 0, "... -1.5 rounds to -1");
    frep_program_free(p);
    /* a / b: the reference's FUNC_binary_divide stops with "Division by zero" where
     * |b| < EPS = 1e-6, not only at 0 (found by prospero.hf of FRep-Designer-Bench,
     * whose t263 / t269 divides by 7.7e-302): NaN there, plain division elsewhere. */
    p = compile("m(x[3], a[1]) { m = x[1] / x[2] + x[1] / 1e-7 * 0; }", &D);
    if (p) ok(isnan(eval1(p, 1, 0, 0)), "division by a constant below EPS: NaN");
    frep_program_free(p);
    p = compile("m(x[3], a[1]) { m = x[1] / x[2]; }", &D);
    if (p) {
        ok(isnan(eval1(p, 1, 9.9e-7, 0)) && isnan(eval1(p, 1, -1e-300, 0)),
           "division by |b| < 1e-6: NaN, the reference's runtime error");
        is_double(eval1(p, 1, 1e-6, 0), 1e6, 1e-9, "... |b| = 1e-6 divides");
        is_double(eval1(p, 3, -2, 0), -1.5, 0, "... ordinary division");
    }
    frep_program_free(p);
    /* tan: the reference's FUNC_tan errors where |cos(a)| < EPS */
    p = compile("m(x[3], a[1]) { m = tan(x[1]); }", &D);
    if (p) {
        ok(isnan(eval1(p, 1.5707963, 0, 0)), "tan where |cos| < 1e-6: NaN");
        is_double(eval1(p, 1, 0, 0), tan(1.0), 1e-15, "... tan(1)");
        is_double(eval1(p, 1.5707, 0, 0), tan(1.5707), 1e-9, "... |cos| = 9.6e-5 computes");
    }
    frep_program_free(p);
    p = compile("m(x[3], a[1]) { m = mod(5, x[1]); }", &D);
    if (p) ok(isnan(eval1(p, 0.4, 0, 0)), "mod by a divisor that rounds to 0: NaN");
    if (p) is_double(eval1(p, 0.6, 0, 0), 0, 0, "... 0.6 rounds to 1");
    frep_program_free(p);

    /* Array indices: HF_round, halves up (int_calc.c of HyperFun rounds the index of
     * every element read and written): 1.5 -> 2, 2.4999 -> 2, 0.5 -> 1, 2.5 -> 3. */
    p = compile("m(x[3], a[1]) {\n  array v[3];\n  v = [10, 20, 30];\n"
                "  m = v[1.5] + 100 * v[2.4999] + 1000 * v[0.5];\n}", &D);
    if (p) is_double(eval1(p, 0, 0, 0), 20 + 2000 + 10000, 0, "constant indices are rounded");
    frep_program_free(p);
    /* A point-dependent index (a real loop keeps k unknown to the compiler). */
    p = compile("m(x[3], a[1]) {\n  array v[3];\n  v = [10, 20, 30];\n  k = 0;\n"
                "  while k < x[1] loop k = k + 0.5; endloop;\n  r = v[k];\n  v[k] = -r;\n"
                "  m = v[1] + v[2] + v[3] + 0 * r;\n}", &D);
    ok(p && count_op(p, FREP_OP_LOADI) >= 1 && count_op(p, FREP_OP_STOREI) == 1,
       "rounded dynamic index: LOADI/STOREI");
    if (p) {
        /* x = 0.5: k = 0.5 -> element 1; 1.5 -> 2; 2.5 -> 3; 0.4: k = 0.5; 3: k = 3;
         * 3.5: k = 3.5 -> 4, out of range (NaN) */
        double xs[6] = { 0.5, 1.5, 2.5, 0.4, 3, 3.5 }, zs[6] = { 0 }, f[6];
        eval_n(p, 6, xs, zs, zs, NULL, f);
        ok(f[0] == 40 && f[1] == 20 && f[2] == 0 && f[3] == 40 && f[4] == 0 && isnan(f[5]),
           "point-dependent indices are rounded, halves up");
    }
    frep_program_free(p);

    /* Chained comparisons: ((-1 <= x) < 0.5), the truth value compared. */
    p = compile("m(x[3], a[1]) {\n  r = 0;\n  if -1 <= x[1] < 0.5 then r = 1; endif;\n  m = r;\n}",
                &D);
    ok(p && find_diag(&D, "compares the truth value") >= 0, "chained comparison: a warning");
    if (p) ok(eval1(p, 0, 0, 0) == 0 && eval1(p, -2, 0, 0) == 1,
              "... true only where -1 <= x[1] is false");
    frep_program_free(p);

    /* A number as a condition, or as an operand of and/or/not: true where |v| >= 1e-6
     * (CODE_if, FUNC_bool_and/or/not of int_calc.c), with a warning. */
    p = compile("m(x[3], a[1]) {\n  r = 0;\n  if x[1] then r = 1; endif;\n"
                "  if not x[1] then r = r + 10; endif;\n"
                "  if x[1] and x[2] - 1 then r = r + 100; endif;\n  m = r;\n}", &D);
    ok(p && find_diag(&D, "a number used as a condition") >= 0,
       "a number as a condition: accepted with a warning");
    /* (x, y): (2e-6, 0): x true, y - 1 = -1 true -> 101; (5e-7, 0): x false -> 10;
     * (1, 1 + 5e-7): |y - 1| < 1e-6 false -> 1 */
    if (p) ok(eval1(p, 2e-6, 0, 0) == 101 && eval1(p, -2e-6, 0, 0) == 101 &&
              eval1(p, 5e-7, 0, 0) == 10 && eval1(p, 0, 0, 0) == 10 &&
              eval1(p, 1, 2, 0) == 101 && eval1(p, 1, 1 + 5e-7, 0) == 1,
              "... true where |value| >= 1e-6, for if, not and 'and'");
    frep_program_free(p);

    /* A read no assignment reached on the point's path: the reference stops with "Not
     * initialized variable" / "Unassigned identificator" (int_calc.c); frep gives NaN.
     * The elements a short list leaves are 0 (a warning). */
    p = compile("m(x[3], a[1]) {\n  array c[3], d[3];\n  c[1] = 5;\n  d = [7];\n"
                "  if x[1] > 0 then y = 1; endif;\n"
                "  m = y + 10 * c[1] + 100 * d[1] + 1000 * d[3] + 0 * c[x[2]];\n}", &D);
    ok(p && find_diag(&D, "may be used before it is assigned") >= 0,
       "a variable assigned on some paths: a warning");
    if (p) {
        double xs[3] = { 1, -1, 1 }, ys[3] = { 1, 1, 2 }, zs[3] = { 0 }, f[3];
        eval_n(p, 3, xs, ys, zs, NULL, f);
        ok(f[0] == 751 && isnan(f[1]) && isnan(f[2]),
           "unassigned variable or element read: NaN (short list: 0)");
    }
    frep_program_free(p);

    /* '=' and '/=' within EPS = 1e-6. */
    p = compile("m(x[3], a[1]) {\n  r = 0;\n  if x[1] = 1 then r = 1; endif;\n"
                "  if x[1] /= 1 then r = r + 10; endif;\n  m = r;\n}", &D);
    if (p) ok(eval1(p, 1 + 1e-7, 0, 0) == 1 && eval1(p, 1 + 2e-6, 0, 0) == 10 &&
              eval1(p, 1, 0, 0) == 1, "'=' and '/=' with the reference's tolerance 1e-6");
    frep_program_free(p);

    /* Attributes: s[] carried out of the evaluation. */
    p = compile("m(x[3], a[1], s[3]) {\n  d = hfA_SetColor(x[1], s, 0.25, 0.5, x[1]);\n"
                "  m = d;\n}", &D);
    ok(p && frep_program_nattrs(p) == 3, "three attributes");
    if (p && attrs_at(p, 2, t, s) == 0)
        ok(s[0] == 0.25 && s[1] == 0.5 && s[2] == 1 && s[3] == 0 && s[4] == 0 && s[5] == 0,
           "hfA_SetColor sets s[] where f >= 0 only");
    frep_program_free(p);
    p = compile("c(x[3], a[1], s[2]) {\n  s[2] = x[1] * 3;\n  c = 1;\n}\n"
                "m(x[3], a[1], s[2]) {\n  v = c(x, a, s);\n  m = s[2] + v;\n}", &D);
    if (p) {
        frep_compile_options o;
        frep_program *q;
        frep_compile_options_init(&o);
        o.model = "m";
        q = compile_opt("c(x[3], a[1], s[2]) {\n  s[2] = x[1] * 3;\n  c = 1;\n}\n"
                        "m(x[3], a[1], s[2]) {\n  v = c(x, a, s);\n  m = s[2] + v;\n}", &D, &o);
        ok(q && eval1(q, 2, 0, 0) == 7, "a called model's s[] comes back to the caller");
        if (q && attrs_at(q, 1, t, s) == 0) ok(s[0] == 0 && s[1] == 3, "... and out");
        frep_program_free(q);
    }
    frep_program_free(p);
    p = compile("m(x[3], a[1]) { m = 1; }", &D);
    ok(p && frep_program_nattrs(p) == 0 && attrs_at(p, 2, t, s) == 0, "no s[]: no attributes");
    frep_program_free(p);

    /* HSV <-> RGB, hfA_Union, hfA_Lerp. */
    p = compile("m(x[3], a[1], s[3]) {\n  array h[3], c1[3], c2[3];\n  h = [240, 1, 1];\n"
                "  d = hfA_HSVToRGB(h, s);\n  m = d;\n}", &D);
    if (p && attrs_at(p, 1, t, s) == 0)
        ok(s[0] == 0 && s[1] == 0 && s[2] == 1, "hfA_HSVToRGB(240, 1, 1) is blue");
    frep_program_free(p);
    p = compile("m(x[3], a[1], s[3]) {\n  array c[3];\n  c = [0, 0, 0.5];\n"
                "  d = hfA_RGBToHSV(c, s);\n  m = d;\n}", &D);
    if (p && attrs_at(p, 1, t, s) == 0)
        ok(s[0] == 240 && s[1] == 1 && s[2] == 0.5, "hfA_RGBToHSV(0, 0, 0.5)");
    frep_program_free(p);
    p = compile("m(x[3], a[1], s[1]) {\n  array c1[1], c2[1];\n  c1 = [3];\n  c2 = [5];\n"
                "  u = hfA_Union(x[1], -x[1] - 1, s, c1, c2, 4);\n  m = u;\n}", &D);
    /* t = 1: f1 = 1, f2 = -2 -> s = c1; t = -1: f1 = -1, f2 = 0 -> s = c2;
     * t = -0.5: f1 = f2 = -0.5, u = -1 + sqrt(0.5) < 0 -> unchanged (0) */
    {
        double tt[3] = { 1, -1, -0.5 };
        if (p && attrs_at(p, 3, tt, s) == 0)
            ok(s[0] == 3 && s[1] == 5 && s[2] == 0, "hfA_Union picks the attributes");
        if (p) is_double(eval1(p, 1, 0, 0), -1 + sqrt(5.0), 1e-15, "... its value is R0 union");
    }
    frep_program_free(p);
    p = compile("m(x[3], a[1], s[2]) {\n  array c1[2], c2[2];\n  c1 = [0, 10];\n  c2 = [4, 20];\n"
                "  f = hfA_Lerp(s, c1, c2, x[1], 0, 2);\n  m = f;\n}", &D);
    if (p && attrs_at(p, 4, t, s) == 0)
        ok(s[0] == 2 && s[1] == 15 && s[2] == 0 && s[3] == 10 && s[4] == 1 &&
           s[5] == 12.5 && s[6] == 4 && s[7] == 20, "hfA_Lerp");
    frep_program_free(p);

    /* hfSawtooth(t, n, a, f) = (0.5 - sum_{k<n} sin(2 pi k f t) / k) * 2 / (a pi). */
    p = compile("m(x[3], a[1]) { m = hfSawtooth(x[1], 3, 2, 1) + hfSawtooth(x[1], 1, 1, 1); }", &D);
    if (p) {
        double tv = 0.125, pi = 3.14159265358979323846;
        double want = (0.5 - sin(2 * pi * tv) - sin(4 * pi * tv) / 2) * (2 / (2 * pi));
        is_double(eval1(p, tv, 0, 0), want, 1e-15, "hfSawtooth");
    }
    frep_program_free(p);
    expect_error("m(x[3], a[1]) { m = hfSawtooth(x[1], x[2], 1, 1); }",
                 "the number of terms n must be a constant", 1, 21, "hfSawtooth: n constant");
    test_perlin();
    test_hyperfun_tables();
}

static void test_limits(void)
{
    diags D;
    frep_compile_options o;
    frep_program *p;
    char *src = malloc(200000);
    size_t len = 0;
    int i;
    /* FREP_MAX_INLINE_DEPTH: a chain of 70 models each calling the previous one. */
    len += (size_t)sprintf(src + len, "m0(x[3], a[1]) { m0 = x[1]; }\n");
    for (i = 1; i < 70; i++)
        len += (size_t)sprintf(src + len, "m%d(x[3], a[1]) { m%d = m%d(x, a) + 1; }\n", i, i, i - 1);
    frep_compile_options_init(&o);
    o.model = "m69"; /* the last: the default is the first, as in the reference */
    p = compile_opt(src, &D, &o);
    ok(!p && find_diag(&D, "model calls nested more than 64 deep") >= 0,
       "FREP_MAX_INLINE_DEPTH");
    frep_program_free(p);

    /* FREP_MAX_LOWER_STEPS: 2^21 inlined statements. */
    len = 0;
    len += (size_t)sprintf(src + len, "m0(x[3], a[1]) { m0 = x[1]; }\n");
    for (i = 1; i < 22; i++)
        len += (size_t)sprintf(src + len, "m%d(x[3], a[1]) { m%d = m%d(x, a) + m%d(x, a); }\n",
                               i, i, i - 1, i - 1);
    o.model = "m21";
    p = compile_opt(src, &D, &o);
    ok(!p && find_diag(&D, "model too large: more than 1048576 statements") >= 0,
       "FREP_MAX_LOWER_STEPS");
    frep_program_free(p);

    /* FREP_EMIT_MAX_HEIGHT: a 5000-term chain is split with temporaries. */
    p = compile("m(x[3], a[1]) {\n  i = 0; s = 0;\n  while i < 5000 loop s = s + x[1] * x[2]; "
                "i = i + 1; endloop;\n  m = s;\n}", &D);
    ok(p && p->max_stack <= 4 && count_op(p, FREP_OP_STORE) >= 2,
       "FREP_EMIT_MAX_HEIGHT: deep chain hoisted (stack %u)", p ? (unsigned)p->max_stack : 0);
    if (p) is_double(eval1(p, 0.5, 3, 0), 5000 * 1.5, 1e-9, "... value of the deep chain");
    frep_program_free(p);

    /* FREP_EMIT_MAX_NEED: right-nested subtractions need a deep stack. */
    len = 0;
    len += (size_t)sprintf(src + len, "m(x[3], a[1]) { m = ");
    for (i = 0; i < 100; i++) len += (size_t)sprintf(src + len, "x[%d] - (", i % 3 + 1);
    len += (size_t)sprintf(src + len, "x[1]");
    for (i = 0; i < 100; i++) src[len++] = ')';
    (void)sprintf(src + len, "; }");
    p = compile(src, &D);
    ok(p && p->max_stack <= 70, "FREP_EMIT_MAX_NEED: stack bounded (%u)",
       p ? (unsigned)p->max_stack : 0);
    if (p) {
        /* x - (y - (z - (x - ...))): with x = 1, y = 2, z = 4 the terms alternate. */
        double v = 1, xv[3] = { 1, 2, 4 };
        for (i = 99; i >= 0; i--) v = xv[i % 3] - v;
        is_double(eval1(p, 1, 2, 4), v, 0, "... value of the nested subtractions");
    }
    frep_program_free(p);

    /* FREP_EMIT_MAX_PARALLEL: a 20-element array rotated inside a real loop. */
    len = 0;
    len += (size_t)sprintf(src + len, "m(x[3], a[1]) {\n  array c[20];\n  c = [");
    for (i = 0; i < 20; i++) len += (size_t)sprintf(src + len, "%s%d", i ? ", " : "", i + 1);
    len += (size_t)sprintf(src + len, "];\n  k = 0;\n  while k < x[1] loop\n    c = [");
    for (i = 0; i < 20; i++) len += (size_t)sprintf(src + len, "%sc[%d]", i ? ", " : "", (i + 1) % 20 + 1);
    (void)sprintf(src + len, "];\n    k = k + 1;\n  endloop;\n  m = c[1] * 100 + c[20];\n}");
    p = compile(src, &D);
    ok(p != NULL, "FREP_EMIT_MAX_PARALLEL: large parallel store compiles");
    if (p) is_double(eval1(p, 3, 0, 0), 4 * 100 + 3, 0, "... rotated by three");
    frep_program_free(p);
    free(src);
}

/* ---- out of memory ----------------------------------------------------------- */

/* An allocator hook that fails allocation number `fail_at` (0-based) and every one
 * after it, counting allocations and resizes; frees always succeed. */
typedef struct failing {
    long count, fail_at;
} failing;

static void *failing_alloc(void *user, void *p, size_t n)
{
    failing *f = user;
    if (n == 0) {
        free(p);
        return NULL;
    }
    if (f->count++ >= f->fail_at) return NULL;
    return p ? realloc(p, n) : malloc(n);
}

/* Every stage meets an allocation failure for some N: then the compile fails with
 * exactly one error, and it says "out of memory" (never "too large" or a bogus
 * error about the source); with enough memory the same source compiles. */
static void test_out_of_memory(void)
{
    const char *src =
        "-- @setops rfunc\n"
        "-- @box -2 -2 -2 2 2 2\n"
        "base(x[3], a[1]) { base = 1 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3]; }\n"
        "m(x[3], a[2]) {\n"
        "  array t[3], c[3];\n"
        "  r = 0.75;  -- @free [0.1, 2]\n"
        "  t = [1, 2, 3]; c = [0, 0, 0];\n"
        "  k = 1;\n"
        "  while k < x[1] loop k = k + 1; endloop;\n"
        "  t[k] = t[k] * x[2];\n"
        "  if x[3] > 0 then s = hfSphere(x, c, r); else s = base(x, a); endif;\n"
        "  v = abs(x[1]) + 1; n = 0;\n"
        "  while v > 0.1 loop v = v / 2; n = n + 1; endloop;\n"
        "  m = s | (t[1] + t[2] + t[3] - n) & a[2];\n"
        "}\n";
    /* and a long model, so that the arena takes new chunks in every stage */
    char *big = malloc(200000);
    size_t len = 0;
    failing f;
    long n, failures = 0, bad = 0;
    int compiled = 0, i;
    len += (size_t)sprintf(big + len, "%s", src);
    len += (size_t)sprintf(big + len, "long(x[3], a[2]) {\n  v0 = x[1];\n");
    for (i = 1; i < 3000; i++)
        len += (size_t)sprintf(big + len, "  v%d = v%d * x[%d] + %d;\n", i, i - 1, i % 3 + 1, i);
    len += (size_t)sprintf(big + len, "  long = v2999 - m(x, a);\n}\n");
    frep_set_allocator(failing_alloc, &f);
    for (n = 0; n < 20000 && !compiled; n++) {
        diags D;
        frep_program *p;
        f.count = 0;
        f.fail_at = n;
        memset(&D, 0, sizeof D);
        p = frep_compile("t.hf", big, len, NULL, collect, &D);
        if (p) {
            compiled = D.errors == 0;
            frep_program_free(p);
            continue;
        }
        failures++;
        if (D.errors != 1 || strcmp(D.msg[0], "out of memory") != 0) {
            if (bad++ == 0) {
                diag("allocation %ld failing:", n);
                dump(&D);
            }
        }
    }
    frep_set_allocator(NULL, NULL);
    free(big);
    ok(compiled, "the source compiles once allocation %ld succeeds", n - 1);
    ok(failures > 10 && bad == 0,
       "each of %ld earlier failures is reported as one error 'out of memory' (%ld not)",
       failures, bad);

    {
        size_t count = 99;
        char **names;
        int reported = 0;
        diags D;
        for (n = 0; n < 1000; n++) {
            memset(&D, 0, sizeof D);
            f.count = 0;
            f.fail_at = n;
            frep_set_allocator(failing_alloc, &f);
            names = frep_list_models("t.hf", src, strlen(src), &count, collect, &D);
            frep_set_allocator(NULL, NULL);
            if (names) break;
            if (D.errors == 1 && strcmp(D.msg[0], "out of memory") == 0) reported++;
        }
        ok(names && count == 2 && reported == n,
           "frep_list_models: %d of %ld failures reported as out of memory", reported, n);
        frep_free_strings(names, count);
    }

    /* The two string builders (runtime/buf.h): NULL when memory runs out, else the
     * whole text. */
    {
        frep_diag d = { FREP_ERROR, "t.hf", 4, 8, 3, "some message" };
        char *want = frep_diag_format(&d, src, strlen(src)), *got = NULL;
        int same = 1;
        for (n = 0; !got; n++) {
            f.count = 0;
            f.fail_at = n;
            frep_set_allocator(failing_alloc, &f);
            got = frep_diag_format(&d, src, strlen(src));
            frep_set_allocator(NULL, NULL);
            if (got && strcmp(got, want) != 0) same = 0;
        }
        ok(want && same, "frep_diag_format: NULL for %ld failures, then the text", n - 1);
        frep_free(want);
        frep_free(got);
    }
    {
        arena A;
        ast_file af;
        char *want, *got = NULL;
        int same = 1;
        arena_init(&A);
        ok(ast_parse(&A, "t.hf", src, strlen(src), NULL, &af) == 0, "source parses");
        want = ast_print(&af);
        for (n = 0; !got; n++) {
            f.count = 0;
            f.fail_at = n;
            frep_set_allocator(failing_alloc, &f);
            got = ast_print(&af);
            frep_set_allocator(NULL, NULL);
            if (got && strcmp(got, want) != 0) same = 0;
        }
        ok(want && same, "ast_print: NULL for %ld failures, then the text", n - 1);
        frep_free(want);
        frep_free(got);
        arena_free(&A);
    }
}

int main(void)
{
    test_basic();
    test_checks();
    test_fold_cse();
    test_control();
    test_params();
    test_models();
    test_hyperfun();
    test_limits();
    test_out_of_memory();
    return done_testing();
}

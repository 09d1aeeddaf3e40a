/* test_f32.c - the single-precision evaluator and its error bound (runtime/vm_f32.c):
 * on random straight-line programs (spheres, square roots, divisions, min/max,
 * R-functions, shared slots, parameters, immediates) over random boxes, the float value
 * is within the certified bound of the double value at every point tried, and a finite
 * bound means double raises no runtime error there; the grid evaluated with
 * PRUNE_GRID_SINGLE has double's inside and NaN counts and errors, min/max/sum close to
 * double's, the same figures at 1, 2 and the default threads; a point where float
 * alone gives the wrong side is re-evaluated in double.  Programs are assembled with
 * prog_emit, so no compiler is needed; nothing here depends on the CPU (the AVX2 check
 * only chooses the path in `frep eval --single`).
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "program.h"
#include "prune.h"
#include "tap.h"
#include "vm.h"
#include "vm_f32.h"
#include "vm_internal.h"

static const frep_srcpos nopos = {0, 0, 0};

/* Deterministic xorshift generator: tests must not depend on the clock. */
static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double urand(double lo, double hi)
{
    return tap_urand(&rng_state, lo, hi);
}
static int irand(int n) { return (int)urand(0, n) % n; }

static void emit(frep_program *p, frep_opcode op, uint32_t arg, double k, uint8_t fl)
{
    prog_emit(p, op, arg, k, fl, nopos);
}

typedef struct gen {
    frep_program *p;
    uint32_t nstored;
} gen;

enum { MAX_SLOTS = 8 };

/* A leaf shape: sphere, sqrt-distance cylinder, scaled half-space with a parameter, a
 * stored slot, or a division that may hit zero. */
static void gen_prim(gen *g)
{
    frep_program *p = g->p;
    int kind = irand(5);
    if (kind == 3 && g->nstored == 0) kind = 0;
    switch (kind) {
    case 0:
        for (uint32_t a = 0; a < 3; a++) {
            emit(p, FREP_OP_X, a, 0, 0);
            emit(p, FREP_OP_SUB, 0, urand(-1, 1), INSN_KB);
            emit(p, FREP_OP_SQUARE, 0, 0, 0);
            if (a) emit(p, FREP_OP_ADD, 0, 0, 0);
        }
        emit(p, FREP_OP_SUB, 0, urand(0.01, 0.6), INSN_KA);
        break;
    case 1:
        for (uint32_t a = 0; a < 2; a++) {
            emit(p, FREP_OP_X, (a + (uint32_t)irand(3)) % 3, 0, 0);
            emit(p, FREP_OP_MUL, 0, urand(0.5, 2), INSN_KB);
            emit(p, FREP_OP_SQUARE, 0, 0, 0);
            if (a) emit(p, FREP_OP_ADD, 0, 0, 0);
        }
        emit(p, FREP_OP_SQRT, 0, 0, 0);
        emit(p, FREP_OP_SUB, 0, urand(0.1, 0.8), INSN_KA);
        break;
    case 2:
        emit(p, FREP_OP_X, (uint32_t)irand(3), 0, 0);
        emit(p, FREP_OP_PARAM, 0, 0, 0);
        emit(p, FREP_OP_MUL, 0, 0, 0);
        emit(p, FREP_OP_ADD, 0, urand(-0.8, 0.8), INSN_KB);
        emit(p, FREP_OP_ABS, 0, 0, 0);
        emit(p, FREP_OP_NEG, 0, 0, 0);
        emit(p, FREP_OP_ADD, 0, 0.7, INSN_KB);
        break;
    case 3:
        emit(p, FREP_OP_LOAD, (uint32_t)irand((int)g->nstored), 0, 0);
        break;
    default: /* 0.05 / (x_a - c): no bound where x_a may equal c */
        emit(p, FREP_OP_X, (uint32_t)irand(3), 0, 0);
        emit(p, FREP_OP_SUB, 0, (double)irand(5) * 0.25 - 0.5, INSN_KB);
        emit(p, FREP_OP_DIV, 0, 0.05, INSN_KA);
        break;
    }
}

static void gen_tree(gen *g, int depth)
{
    frep_program *p = g->p;
    if (depth == 0 || urand(0, 1) < 0.1) {
        gen_prim(g);
        return;
    }
    if (g->nstored < MAX_SLOTS && urand(0, 1) < 0.2) {
        gen_prim(g);
        emit(p, FREP_OP_STORE, g->nstored++, 0, 0);
    }
    if (urand(0, 1) < 0.15) {
        gen_tree(g, depth - 1);
        emit(p, irand(2) ? FREP_OP_MIN : FREP_OP_MSUB, 0, urand(-0.5, 0.5),
             irand(2) ? INSN_KA : INSN_KB);
        return;
    }
    static const frep_opcode ops[] = { FREP_OP_MIN, FREP_OP_MAX, FREP_OP_MSUB, FREP_OP_RUNI,
                                       FREP_OP_RINT, FREP_OP_RSUB, FREP_OP_ADD, FREP_OP_MUL };
    gen_tree(g, depth - 1);
    gen_tree(g, depth - 1);
    emit(p, ops[irand(8)], 0, 0, 0);
}

static frep_program *random_program(int depth)
{
    gen g = { prog_new(), 0 };
    gen_tree(&g, depth);
    /* one parameter, a[1] */
    g.p->params = frep_calloc(1, sizeof *g.p->params);
    if (!g.p->params) {
        frep_program_free(g.p);
        return NULL;
    }
    g.p->nparams = g.p->na = 1;
    g.p->params[0].value = urand(-1.5, 1.5);
    if (prog_finish(g.p) != 0) {
        frep_program_free(g.p);
        return NULL;
    }
    return g.p;
}

/* Random points of the box (its corners first) into x, y, z. */
static void box_points(const double box[6], size_t n, double *x, double *y, double *z)
{
    for (size_t i = 0; i < n; i++) {
        double *c[3] = { x, y, z };
        for (int a = 0; a < 3; a++)
            c[a][i] = i < 8 ? box[a + 3 * ((i >> a) & 1)] : urand(box[a], box[a + 3]);
    }
}

static void test_bound(void)
{
    enum { NPROG = 150, NBOX = 12, NPT = FREP_BLOCK };
    static double x[NPT], y[NPT], z[NPT], fd[NPT], ff[NPT];
    int supported = 0, bounded = 0, unbounded = 0, held = 1, clean = 1, differ = 0;
    double worst = 0;  /* largest error over its bound */
    for (int t = 0; t < NPROG; t++) {
        frep_program *p = random_program(2 + t % 5);
        if (!p) {
            ok(0, "random program %d assembles", t);
            continue;
        }
        supported += vm_f32_supported(p);
        vm_f32 *fs = vm_f32_new(p);
        vm_scratch *ds = vm_scratch_new(p);
        for (int b = 0; b < NBOX && fs && ds; b++) {
            /* boxes from a grid cell's size to the whole model, some far away */
            double h = pow(10, urand(-3, 0)), far = b % 4 == 3 ? urand(2, 50) : 0;
            double box[6];
            for (int a = 0; a < 3; a++) {
                box[a] = urand(-1.2, 1.2) + far;
                box[a + 3] = box[a] + h;
            }
            double e = vm_f32_bound(fs, p, box);
            if (!(e < INFINITY)) {
                unbounded++;
                continue;
            }
            bounded++;
            box_points(box, NPT, x, y, z);
            vm_inputs in;
            memset(&in, 0, sizeof in);
            in.x = x;
            in.y = y;
            in.z = z;
            memset(&ds->total, 0, sizeof ds->total);
            if (vm_eval_block(p, ds, &in, NPT, fd) < 0 ||
                vm_f32_eval_block(fs, p, x, y, z, NPT, ff) < 0) {
                held = 0;
                continue;
            }
            if (ds->total.count) clean = 0;
            for (size_t i = 0; i < NPT; i++) {
                double err = fabs(ff[i] - fd[i]);
                if (err > 0) differ++;
                if (!(err <= e)) {
                    if (held)
                        diag("program %d box %d point (%g, %g, %g): float %.9g double %.17g "
                             "bound %g", t, b, x[i], y[i], z[i], ff[i], fd[i], e);
                    held = 0;
                }
                if (e > 0 && err / e > worst) worst = err / e;
            }
        }
        vm_f32_free(fs);
        vm_scratch_free(ds);
        frep_program_free(p);
    }
    ok(supported == NPROG, "every random program runs in float (%d of %d)", supported, NPROG);
    ok(held, "float within the bound of double at every point (%d boxes x %d points; "
             "largest error %.3g of its bound)", bounded, NPT, worst);
    ok(clean, "a finite bound means no runtime error in double");
    ok(bounded > NPROG * NBOX / 2 && unbounded > 0,
       "bounds finite in %d boxes, refused in %d (divisions by 0, square roots of "
       "negatives)", bounded, unbounded);
    ok(differ > 1000, "float and double do differ (%d points)", differ);
}

/* Every ISA copy of the float loops (vm_f32_set_isa) gives the base copy's values bit
 * for bit on random programs at random points (no FMA, the same roundings); an ISA the
 * CPU lacks is refused and its check skipped, saying so. */
static void test_isa(void)
{
    enum { NPROG = 60, NPT = FREP_BLOCK };
    static double x[NPT], y[NPT], z[NPT], fb[NPT], fi[NPT];
    static const char *names[] = { "base", "AVX2", "AVX-512" };
    ok(vm_f32_isa_ok(VM_F32_ISA_BASE), "the base ISA always runs");
    for (int isa = VM_F32_ISA_AVX2; isa <= VM_F32_ISA_AVX512; isa++) {
        if (!vm_f32_isa_ok(isa)) {
            ok(1, "%s float loops: same values as base # SKIP this CPU lacks %s", names[isa],
               names[isa]);
            continue;
        }
        int same = 1, ran = 0;
        for (int t = 0; t < NPROG; t++) {
            frep_program *p = random_program(2 + t % 5);
            vm_f32 *fs = p ? vm_f32_new(p) : NULL;
            if (fs) {
                const double box[6] = { -1.5, -1.5, -1.5, 1.5, 1.5, 1.5 };
                box_points(box, NPT, x, y, z);
                int rb = vm_f32_set_isa(fs, VM_F32_ISA_BASE) == 0 &&
                         vm_f32_eval_block(fs, p, x, y, z, NPT, fb) == 0;
                int ri = vm_f32_set_isa(fs, isa) == 0 && vm_f32_get_isa(fs) == isa &&
                         vm_f32_eval_block(fs, p, x, y, z, NPT, fi) == 0;
                if (!rb || !ri || memcmp(fb, fi, sizeof fb) != 0) same = 0;
                ran += rb && ri;
            }
            vm_f32_free(fs);
            frep_program_free(p);
        }
        ok(same && ran == NPROG, "%s float loops: the base copy's values bit for bit (%d "
           "programs x %d points)", names[isa], ran, NPT);
    }
    frep_program *p = random_program(3);
    vm_f32 *fs = p ? vm_f32_new(p) : NULL;
    ok(fs && vm_f32_set_isa(fs, 99) == -1, "an unknown ISA is refused");
    ok(fs && vm_f32_get_isa(fs) == vm_f32_isa_default(), "a new scratch runs the default ISA");
    vm_f32_free(fs);
    /* FREP_F32_ISA picks the default among the ISAs the CPU runs */
    setenv("FREP_F32_ISA", "base", 1);
    ok(vm_f32_isa_default() == VM_F32_ISA_BASE, "FREP_F32_ISA=base picks the base copy");
    setenv("FREP_F32_ISA", "avx2", 1);
    ok(vm_f32_isa_default() == (vm_f32_isa_ok(VM_F32_ISA_AVX2) ? VM_F32_ISA_AVX2 : VM_F32_ISA_BASE),
       "FREP_F32_ISA=avx2 picks AVX2 where the CPU has it");
    unsetenv("FREP_F32_ISA");
    ok(vm_f32_isa_default() == (vm_f32_isa_ok(VM_F32_ISA_AVX512) ? VM_F32_ISA_AVX512
                                : vm_f32_isa_ok(VM_F32_ISA_AVX2) ? VM_F32_ISA_AVX2
                                                                 : VM_F32_ISA_BASE),
       "by default the best ISA the CPU runs");
    frep_program_free(p);
}

/* A program of more than VM_F32_MIN_CODE instructions: the min of 2 - |x|^2, of twelve
 * planes y + 3 + j (never the least: padding) and of x - c.  With c = 0.1 + 1e-12, x and
 * c round to the same float near x = 0.1, where float gives 0 (inside) and double a
 * negative value. */
static frep_program *plane_program(double c)
{
    frep_program *p = prog_new();
    for (uint32_t a = 0; a < 3; a++) {
        emit(p, FREP_OP_X, a, 0, 0);
        emit(p, FREP_OP_SQUARE, 0, 0, 0);
        if (a) emit(p, FREP_OP_ADD, 0, 0, 0);
    }
    emit(p, FREP_OP_SUB, 0, 2.0, INSN_KA);
    for (int j = 0; j < 12; j++) {
        emit(p, FREP_OP_X, 1, 0, 0);
        emit(p, FREP_OP_SUB, 0, -3.0 - j, INSN_KB);
        emit(p, FREP_OP_MIN, 0, 0, 0);
    }
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_SUB, 0, c, INSN_KB);
    emit(p, FREP_OP_MIN, 0, 0, 0);
    if (prog_finish(p) != 0) {
        frep_program_free(p);
        return NULL;
    }
    return p;
}

static int stats_same(const prune_grid_stats *a, const prune_grid_stats *b)
{
    return a->inside == b->inside && a->nans == b->nans &&
           memcmp(&a->sum, &b->sum, sizeof a->sum) == 0 && a->min == b->min &&
           a->max == b->max && a->single == b->single && a->redone == b->redone;
}

static void test_grid(void)
{
    enum { N = 65 };
    int nprog = 24, counts = 1, close = 1, threads_same = 1, used = 0, redone = 0;
    for (int t = 0; t < nprog + 1; t++) {
        /* the last one: the plane program, on a grid through x = 0.1 */
        frep_program *p = t < nprog ? random_program(4 + t % 3) : plane_program(0.1 + 1e-12);
        if (!p) {
            ok(0, "program %d assembles", t);
            continue;
        }
        double box[6] = { -1.1, -1.1, -0.9, 1.1, 1.1, 0.9 };
        if (t == nprog) { /* x_32 = -1.5 + 3.2 * 32 / 64: 0.1 within a double's rounding */
            box[0] = 0.1 - 0.05 * 32;
            box[3] = 0.1 + 0.05 * 32;
        }
        prune_grid_stats sd, sf[3];
        frep_runtime_error ed, ef[3];
        prune_grid_stats_init(&sd);
        int prune = t < nprog && t % 2; /* pruning shortens the plane program below
                                           VM_F32_MIN_CODE */
        int r = prune_eval_grid_flags(p, N, box, prune, 1, 0, &sd, &ed, NULL, NULL);
        static const int threads[3] = { 1, 2, 0 };
        for (int k = 0; k < 3; k++) {
            prune_grid_stats_init(&sf[k]);
            r |= prune_eval_grid_flags(p, N, box, prune, threads[k], PRUNE_GRID_SINGLE, &sf[k],
                                       &ef[k], NULL, NULL);
            if (k && !stats_same(&sf[0], &sf[k])) threads_same = 0;
        }
        if (r || sd.inside != sf[0].inside || sd.nans != sf[0].nans ||
            ed.count != ef[0].count || (ed.count && ed.pc != ef[0].pc)) {
            diag("program %d: inside %llu / %llu, nan %llu / %llu, errors %llu / %llu", t,
                 (unsigned long long)sd.inside, (unsigned long long)sf[0].inside,
                 (unsigned long long)sd.nans, (unsigned long long)sf[0].nans,
                 (unsigned long long)ed.count, (unsigned long long)ef[0].count);
            counts = 0;
        }
        double scale = 1e-4 * (1 + fabs(sd.max) + fabs(sd.min));
        if (!(fabs(sd.min - sf[0].min) <= scale && fabs(sd.max - sf[0].max) <= scale &&
              fabs(sd.sum - sf[0].sum) <= scale * N * N * N)) {
            diag("program %d: min %g / %g, max %g / %g, sum %g / %g", t, sd.min, sf[0].min,
                 sd.max, sf[0].max, sd.sum, sf[0].sum);
            close = 0;
        }
        used += sf[0].single > 0;
        if (t == nprog) {
            vm_f32 *fs = vm_f32_new(p);
            double x = 0.1, y = 0, z = 0, ff = 1, fd = 1;
            vm_scratch *ds = vm_scratch_new(p);
            vm_inputs in;
            memset(&in, 0, sizeof in);
            in.x = &x;
            in.y = &y;
            in.z = &z;
            int ran = fs && ds && vm_f32_eval_block(fs, p, &x, &y, &z, 1, &ff) == 0 &&
                      vm_eval_block(p, ds, &in, 1, &fd) == 0;
            ok(ran && ff >= 0 && fd < 0, "at x = 0.1 float alone says inside (%g), double "
                                         "outside (%g)", ff, fd);
            ok(sf[0].redone > 0 && sf[0].single > sf[0].redone,
               "the grid through x = 0.1 re-evaluates %llu of %llu float blocks in double",
               (unsigned long long)sf[0].redone, (unsigned long long)sf[0].single);
            is_double(sf[0].max, sd.max, 1e-5, "its largest value within 1e-5 of double's");
            vm_f32_free(fs);
            vm_scratch_free(ds);
        }
        redone += sf[0].redone > 0;
        frep_program_free(p);
    }
    ok(counts, "with PRUNE_GRID_SINGLE the inside and NaN counts and errors are double's "
               "(%d programs, %d^3 points)", nprog + 1, N);
    ok(close, "min, max and sum within 1e-4 of double's");
    ok(threads_same, "the same figures at 1, 2 and the default threads");
    ok(used > nprog / 2 && redone > 0, "float ran on %d programs, re-checks on %d", used,
       redone);
}

int main(void)
{
    test_bound();
    test_isa();
    test_grid();
    return done_testing();
}

/* test_prune.c - exact interval tape pruning (runtime/prune.c): on random CSG programs
 * (min/max, min(a, -b), selects, R-functions, shared subexpressions, immediates,
 * domain errors) the pruned grid evaluation gives bit-identical values and the same
 * errors as the unpruned one, at 1 and 2 threads, and it does shorten programs.
 * Programs are assembled with prog_emit, so no compiler is needed.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "program.h"
#include "prune.h"
#include "tap.h"
#include "threads.h"
#include "vm.h"

static const frep_srcpos nopos = {0, 0, 0};

/* Deterministic xorshift generator: tests must not depend on the clock. */
static uint64_t rng_state = 0x2545F4914F6CDD1Dull;
static double urand(double lo, double hi)
{
    return tap_urand(&rng_state, lo, hi);
}
static int irand(int n) { return (int)urand(0, n) % n; }

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

/* Random program state: slots written so far (LOAD may read them). */
typedef struct gen {
    frep_program *p;
    uint32_t nstored;
    int risky;        /* allow divisions that hit zero (domain errors, infinities) */
} gen;

enum { MAX_SLOTS = 12 };

/* A primitive: sphere, sqrt-distance sphere, half-space, a stored slot, a division. */
static void gen_prim(gen *g)
{
    frep_program *p = g->p;
    int kind = irand(g->risky ? 6 : 5);
    if (kind == 4 && g->nstored == 0) kind = 0;
    switch (kind) {
    case 0: /* r^2 - |x - c|^2 */
        for (uint32_t a = 0; a < 3; a++) {
            emit(p, FREP_OP_X, a, 0, 0);
            emit(p, FREP_OP_SUB, 0, urand(-1, 1), INSN_KB);
            emit(p, FREP_OP_SQUARE, 0, 0, 0);
            if (a) emit(p, FREP_OP_ADD, 0, 0, 0);
        }
        emit(p, FREP_OP_SUB, 0, urand(0.01, 0.6), INSN_KA);
        break;
    case 1: /* r - sqrt(x'^2 + y'^2): a domain op the pruner must prove safe */
        for (uint32_t a = 0; a < 2; a++) {
            emit(p, FREP_OP_X, (a + (uint32_t)irand(3)) % 3, 0, 0);
            emit(p, FREP_OP_SUB, 0, urand(-1, 1), INSN_KB);
            emit(p, FREP_OP_SQUARE, 0, 0, 0);
            if (a) emit(p, FREP_OP_ADD, 0, 0, 0);
        }
        emit(p, FREP_OP_SQRT, 0, 0, 0);
        emit(p, FREP_OP_SUB, 0, urand(0.1, 0.8), INSN_KA);
        break;
    case 2: case 3: /* s * x_a + d */
        emit(p, FREP_OP_X, (uint32_t)irand(3), 0, 0);
        emit(p, FREP_OP_MUL, 0, urand(-1, 1) < 0 ? -1.0 : 1.0, INSN_KB);
        emit(p, FREP_OP_ADD, 0, urand(-0.8, 0.8), INSN_KB);
        break;
    case 4:
        emit(p, FREP_OP_LOAD, (uint32_t)irand((int)g->nstored), 0, 0);
        break;
    default: /* 0.05 / (x_a - c): errors and infinities where x_a == c */
        emit(p, FREP_OP_X, (uint32_t)irand(3), 0, 0);
        emit(p, FREP_OP_SUB, 0, (double)irand(5) * 0.25 - 0.5, INSN_KB);
        emit(p, FREP_OP_DIV, 0, 0.05, INSN_KA);
        break;
    }
}

static void gen_tree(gen *g, int depth)
{
    frep_program *p = g->p;
    if (depth == 0 || urand(0, 1) < 0.15) {
        gen_prim(g);
        return;
    }
    /* a shared value hoisted into this subtree, as the compiler's scheduler does */
    if (g->nstored < MAX_SLOTS && urand(0, 1) < 0.2) {
        gen_prim(g);
        emit(p, FREP_OP_STORE, g->nstored++, 0, 0);
    }
    int kind = irand(10);
    if (kind == 9) { /* select(a' < k, b, c) */
        gen_tree(g, depth - 1);
        emit(p, FREP_OP_LT, 0, urand(-0.5, 0.5), INSN_KB);
        gen_tree(g, depth - 1);
        gen_tree(g, depth - 1);
        emit(p, FREP_OP_SELECT, 0, 0, 0);
        return;
    }
    if (kind == 8) { /* min/max with an immediate */
        gen_tree(g, depth - 1);
        emit(p, irand(2) ? FREP_OP_MIN : FREP_OP_MAX, 0, urand(-0.5, 0.5),
             irand(2) ? INSN_KA : INSN_KB);
        return;
    }
    if (kind == 7) { /* min(k, -b) or min(a, -k) */
        gen_tree(g, depth - 1);
        emit(p, FREP_OP_MSUB, 0, urand(-0.5, 0.5), irand(2) ? INSN_KA : INSN_KB);
        return;
    }
    static const frep_opcode ops[] = { FREP_OP_MIN, FREP_OP_MAX, FREP_OP_MSUB, FREP_OP_MIN,
                                       FREP_OP_MAX, FREP_OP_RUNI, FREP_OP_ADD };
    gen_tree(g, depth - 1);
    gen_tree(g, depth - 1);
    emit(p, ops[irand(7)], 0, 0, 0);
}

static frep_program *random_program(int depth, int risky)
{
    gen g = { prog_new(), 0, risky };
    gen_tree(&g, depth);
    if (prog_finish(g.p) != 0) {
        diag("prog_finish failed");
        frep_program_free(g.p);
        return NULL;
    }
    return g.p;
}

enum { GN = 21 }; /* grid points per axis: one full tile and a partial one */

static void test_random_grids(void)
{
    static double f0[GN * GN * GN], f1[GN * GN * GN], f2[GN * GN * GN], f3[GN * GN * GN];
    int nprog = 60, all_same = 1, errs_same = 1, threads_same = 1, prunable = 0;
    int slabs_same = 1, stats_ok = 1;
    int with_errors = 0;
    double cost_full = 0, cost_pruned = 0;
    for (int t = 0; t < nprog; t++) {
        frep_program *p = random_program(3 + t % 4, t % 3 == 2);

        if (!p) {
            ok(0, "random program %d assembles", t);
            continue;
        }
        /* risky programs get [-1, 1] in x so grid points hit the poles x = -0.5, 0, 0.5 */
        int risky = t % 3 == 2;
        double c = risky ? 0 : urand(-0.3, 0.3), h = risky ? 1 : urand(0.6, 1.4);
        double box[6] = { c - h, -h, c - 0.5 * h, c + h, h, c + 0.5 * h };
        frep_runtime_error e0, e1, e2;
        double i0 = 0, i1 = 0, i2 = 0;
        int r = prune_eval_grid_planes(p, GN, box, 0, GN, 0, 1, f0, &e0, &i0);
        r |= prune_eval_grid_planes(p, GN, box, 0, GN, 1, 1, f1, &e1, &i1);
        r |= prune_eval_grid_planes(p, GN, box, 0, GN, 1, 2, f2, &e2, &i2);
        if (r != 0) {
            ok(0, "random program %d evaluates", t);
            frep_program_free(p);
            continue;
        }
        /* as frep eval --grid: slabs of PRUNE_TILE planes (whole tiles take another
         * path), summarized on the fly; the summary must be f0's */
        prune_grid_stats st;
        prune_grid_stats_init(&st);
        for (long k0 = 0; k0 < GN; k0 += PRUNE_TILE) {
            long nk = GN - k0 < PRUNE_TILE ? GN - k0 : PRUNE_TILE;
            r |= prune_eval_grid_summary(p, GN, box, k0, nk, 1, 2, f3 + (size_t)k0 * GN * GN,
                                         &st, NULL, NULL);
        }
        uint64_t ins = 0, nans = 0;
        double mn = INFINITY, mx = -INFINITY, sum = 0, mag = 0;
        int s = 1, s2 = 1, s3 = 1;
        for (size_t i = 0; i < (size_t)GN * GN * GN; i++) {
            s &= same(f0[i], f1[i]);
            s2 &= same(f1[i], f2[i]);
            s3 &= same(f0[i], f3[i]);
            double v = f0[i];
            if (isnan(v)) { nans++; continue; }
            ins += v >= 0;
            if (v < mn) mn = v;
            if (v > mx) mx = v;
            if (isfinite(v)) { sum += v; mag += fabs(v); }
        }
        slabs_same &= s3;
        if (r != 0 || st.inside != ins || st.nans != nans || st.min < mn || st.min > mn ||
            st.max < mx || st.max > mx || !(fabs(st.sum - sum) <= 1e-12 * mag)) {
            diag("program %d: summary %llu %llu %g %g %g, expected %llu %llu %g %g %g", t,
                 (unsigned long long)st.inside, (unsigned long long)st.nans, st.min, st.max,
                 st.sum, (unsigned long long)ins, (unsigned long long)nans, mn, mx, sum);
            stats_ok = 0;
        }
        if (!s) diag("program %d (%u instructions): pruned values differ", t, p->ncode);
        all_same &= s;
        threads_same &= s2 && e1.count == e2.count && e1.pc == e2.pc && same(e1.x, e2.x) &&
                        same(e1.y, e2.y) && same(e1.z, e2.z);
        if (e0.count != e1.count || (e0.count && e0.pc != e1.pc)) {
            diag("program %d: errors %llu at pc %u, pruned %llu at pc %u", t,
                 (unsigned long long)e0.count, e0.pc, (unsigned long long)e1.count, e1.pc);
            errs_same = 0;
        }
        with_errors += e0.count > 0;
        {
            int dec = 0;
            for (uint32_t pc = 0; pc < p->ncode; pc++)
                dec |= p->code[pc].op == FREP_OP_MIN || p->code[pc].op == FREP_OP_MAX ||
                       p->code[pc].op == FREP_OP_MSUB || p->code[pc].op == FREP_OP_SELECT;
            prune_plan *pl = prune_plan_new(p);
            prunable += (pl != NULL) == dec;
            prune_plan_free(pl);
        }
        cost_full += i0;
        cost_pruned += i1;
        frep_program_free(p);
    }
    ok(all_same, "pruned grid values are bit-identical to unpruned ones (%d programs)", nprog);
    ok(errs_same, "pruned grids report the same domain errors (%d programs had some)",
       with_errors);
    ok(with_errors > 0, "some random programs raise domain errors");
    ok(threads_same, "pruned grids: 1 and 2 threads give the same values and errors");
    ok(slabs_same, "slabs of %d planes give the values of the whole grid", PRUNE_TILE);
    ok(stats_ok, "on-the-fly summaries (inside, NaNs, min, max, sum) match the values");
    ok(prunable == nprog, "a straight-line program gets a prune plan iff it has a min, max or select");
    ok(cost_pruned < 0.8 * cost_full,
       "pruning shortens the programs (%.0f of %.0f instruction-evaluations)", cost_pruned,
       cost_full);
}

/* A random box inside `outer`, from a tenth of its size to all of it. */
static void sub_box(const double outer[6], double box[6])
{
    for (int c = 0; c < 3; c++) {
        double w = (outer[c + 3] - outer[c]) * urand(0.1, 1);
        box[c] = outer[c] + urand(0, 1) * (outer[c + 3] - outer[c] - w);
        box[c + 3] = box[c] + w;
    }
}

/* prune_for_box and prune_for_subbox on random boxes, checked at random points of
 * the innermost box against the original program (values and error counts). */
static void test_random_boxes(void)
{
    enum { NPROG = 80, NBOX = 20, NPT = 256 };
    static double x[NPT], y[NPT], z[NPT], f0[NPT], f1[NPT], f2[NPT];
    int vals = 1, errs = 1, shorter = 0, checked = 0;
    for (int t = 0; t < NPROG; t++) {
        frep_program *p = random_program(3 + t % 5, 0);
        prune_plan *pl = p ? prune_plan_new(p) : NULL;
        if (!pl) {
            frep_program_free(p);
            continue;
        }
        prune_state *sa = prune_state_new(pl), *sb = prune_state_new(pl);
        vm_scratch *s = vm_scratch_new(p);
        for (int b = 0; b < NBOX && sa && sb && s; b++) {
            double world[6] = { -1.5, -1.5, -1.5, 1.5, 1.5, 1.5 }, outer[6], inner[6];
            sub_box(world, outer);
            sub_box(outer, inner);
            for (int i = 0; i < NPT; i++) {
                x[i] = urand(inner[0], inner[3]);
                y[i] = urand(inner[1], inner[4]);
                z[i] = urand(inner[2], inner[5]);
            }
            x[0] = inner[0], y[0] = inner[1], z[0] = inner[2];
            x[1] = inner[3], y[1] = inner[4], z[1] = inner[5];
            vm_inputs in;
            memset(&in, 0, sizeof in);
            in.x = x;
            in.y = y;
            in.z = z;
            frep_runtime_error e0, e1, e2;
            frep_scratch_reset_errors((frep_scratch *)s);
            vm_eval_block(p, s, &in, NPT, f0);
            frep_scratch_errors((frep_scratch *)s, &e0);
            const frep_program *q1 = prune_for_box(pl, sa, outer, NULL, NULL);
            const frep_program *q2 = prune_for_subbox(pl, sb, sa, inner, NULL, NULL);
            frep_scratch_reset_errors((frep_scratch *)s);
            vm_eval_block(q1, s, &in, NPT, f1);
            frep_scratch_errors((frep_scratch *)s, &e1);
            frep_scratch_reset_errors((frep_scratch *)s);
            vm_eval_block(q2, s, &in, NPT, f2);
            frep_scratch_errors((frep_scratch *)s, &e2);
            for (int i = 0; i < NPT; i++) {
                if (!same(f0[i], f1[i]) || !same(f0[i], f2[i])) {
                    if (vals)
                        diag("program %d box %d point %d: %.17g, box %.17g, sub-box %.17g", t,
                             b, i, f0[i], f1[i], f2[i]);
                    vals = 0;
                }
            }
            errs &= e0.count == e1.count && e0.count == e2.count;
            shorter += q2->ncode < q1->ncode;
            checked++;
        }
        vm_scratch_free(s);
        prune_state_free(sa);
        prune_state_free(sb);
        prune_plan_free(pl);
        frep_program_free(p);
    }
    ok(checked > NPROG * NBOX / 2, "%d random boxes checked", checked);
    ok(vals, "box- and sub-box-pruned programs give the original's values at random points");
    ok(errs, "and the same error counts");
    ok(shorter > 0, "sub-boxes prune further (%d of %d)", shorter, checked);
}

/* A hand-checked case: max(sphere at -1, sphere at +1); over a box around +1 the
 * left sphere is dominated and only the right one (and no MAX) remains. */
static void test_hand_case(void)
{
    frep_program *p = prog_new();
    for (int s = 0; s < 2; s++) {
        emit(p, FREP_OP_X, 0, 0, 0);
        emit(p, FREP_OP_SUB, 0, s ? 1.0 : -1.0, INSN_KB);
        emit(p, FREP_OP_SQUARE, 0, 0, 0);
        emit(p, FREP_OP_SUB, 0, 0.25, INSN_KA); /* 0.25 - (x - c)^2 */
    }
    emit(p, FREP_OP_MAX, 0, 0, 0);
    ok(prog_finish(p) == 0, "hand case assembles");
    prune_plan *pl = prune_plan_new(p);
    prune_state *st = pl ? prune_state_new(pl) : NULL;
    ok(pl && st, "hand case: plan and state");
    if (pl && st) {
        double box[6] = { 0.8, -1, -1, 1.2, 1, 1 };
        ival e;
        const frep_program *q = prune_for_box(pl, st, box, NULL, &e);
        is_int(q->ncode, 4, "max(a, b) over b's region keeps b's 4 instructions");
        ok(q->code[0].op == FREP_OP_X && q->code[3].op == FREP_OP_SUB &&
           prune_orig_pc(st, 0) == 4, "the kept instructions are b's, mapped to pcs 4..7");
        ok(e.lo <= 0.25 - 0.04 && e.hi >= 0.25, "enclosure [%g, %g] holds f's range", e.lo,
           e.hi);
        is_double(e.hi, 0.25, 1e-12, "the enclosure is tight at the top");
        double wide[6] = { -1.2, -1, -1, 1.2, 1, 1 };
        q = prune_for_box(pl, st, wide, NULL, NULL);
        is_int(q->ncode, 9, "over both spheres nothing is pruned");
    }
    prune_state_free(st);
    prune_plan_free(pl);
    frep_program_free(p);
    /* branches: no plan */
    p = prog_new();
    emit(p, FREP_OP_X, 0, 0, 0);
    emit(p, FREP_OP_JZ, 0, 0, 0);
    p->code[1].arg = 2;
    emit(p, FREP_OP_CONST, 0, 1, 0);
    ok(prog_finish(p) == 0 && prune_plan_new(p) == NULL, "a program with a jump gets no plan");
    frep_program_free(p);
}

/* prune_eval_grid_whole (frep eval --grid: few parallel regions, threads by job size)
 * gives exactly the figures of the slab-by-slab summary on one thread, at any thread
 * count, with and without pruning.  GW^3 points make every job big enough for two
 * threads (FREP_PAR_MIN_WORK: random programs have more than 6 instructions) and
 * span several slabs and super-tiles. */
enum { GW = 81 }; /* odd, over [-1, 1] in x for the risky programs: x hits -0.5, 0, 0.5 */

static int stats_equal(const prune_grid_stats *a, const prune_grid_stats *b)
{
    return a->inside == b->inside && a->nans == b->nans && same(a->min, b->min) &&
           same(a->max, b->max) && same(a->sum, b->sum);
}

static int errors_equal(const frep_runtime_error *a, const frep_runtime_error *b)
{
    return a->count == b->count &&
           (a->count == 0 || (a->pc == b->pc && same(a->x, b->x) && same(a->y, b->y) &&
                              same(a->z, b->z)));
}

static void test_whole_grid(void)
{
    int nprog = 8, same_all = 1, with_errors = 0, big = 1;
    for (int t = 0; t < nprog; t++) {
        frep_program *p = random_program(3 + t % 4, t % 2 == 1);
        if (!p) {
            ok(0, "random program %d assembles", t);
            continue;
        }
        big &= (double)p->ncode * GW * GW * GW >= FREP_PAR_MIN_WORK;
        double h = t % 2 ? 1 : 1.2;
        double box[6] = { -h, -h, -0.7 * h, h, h, 0.7 * h };
        for (int prune = 0; prune < 2; prune++) {
            prune_grid_stats s1, sw[3];
            frep_runtime_error e1 = { 0 }, ew[3];
            double c1 = 0, cw[3] = { 0, 0, 0 };
            int r = 0;
            prune_grid_stats_init(&s1);
            for (long k0 = 0; k0 < GW; k0 += PRUNE_TILE) {
                long nk = GW - k0 < PRUNE_TILE ? GW - k0 : PRUNE_TILE;
                frep_runtime_error e;
                r |= prune_eval_grid_summary(p, GW, box, k0, nk, prune, 1, NULL, &s1, &e, &c1);
                if (e.count && (e1.count == 0 || e.pc < e1.pc)) {
                    uint64_t c = e1.count;
                    e1 = e;
                    e1.count += c;
                } else {
                    e1.count += e.count;
                }
            }
            static const int threads[3] = { 1, 2, 0 };
            for (int k = 0; k < 3; k++) {
                prune_grid_stats_init(&sw[k]);
                r |= prune_eval_grid_whole(p, GW, box, prune, threads[k], &sw[k], &ew[k], &cw[k], NULL);
                if (!stats_equal(&s1, &sw[k]) || !errors_equal(&e1, &ew[k]) || cw[k] != c1) {
                    diag("program %d, prune %d, %d threads: whole grid %llu %.17g, slabs "
                         "%llu %.17g", t, prune, threads[k], (unsigned long long)sw[k].inside,
                         sw[k].sum, (unsigned long long)s1.inside, s1.sum);
                    same_all = 0;
                }
            }
            if (r) same_all = 0;
            with_errors += e1.count > 0;
        }
        frep_program_free(p);
    }
    ok(same_all, "whole-grid summaries and errors equal the slab-by-slab ones at 1, 2 and "
                 "the default threads (%d programs, %d^3 points)", nprog, GW);
    ok(with_errors > 0, "some of them raise domain errors (%d runs)", with_errors);
    ok(big, "each of them is big enough for two threads (FREP_PAR_MIN_WORK)");
}

int main(void)
{
    test_hand_case();
    test_random_grids();
    test_random_boxes();
    test_whole_grid();
    return done_testing();
}

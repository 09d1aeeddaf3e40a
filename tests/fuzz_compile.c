/* fuzz_compile.c - libFuzzer target for the front end and compiler: any byte string
 * is compiled as a model file and, when it compiles, evaluated (values, gradient,
 * parameter derivatives) at a few points.  Built and run by tests/fuzz.sh with clang;
 * not part of make check.  Crashers found become golden or unit regression tests.
 */
#include <stddef.h>
#include <stdint.h>

#include "frep.h"

static void ignore_diag(void *user, const frep_diag *d)
{
    (void)user;
    (void)d;
}

/* Loop iterations of one input's evaluations in all (frep_program_set_work_limit). */
#define FUZZ_MAX_WORK 100000

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    frep_compile_options o;
    frep_compile_options_init(&o);
    frep_program *p = frep_compile("fuzz.hf", (const char *)data, size, &o, ignore_diag, NULL);
    if (!p) return 0;
    /* Two points, and a work budget as every frep command has: a runaway loop stops
     * after FUZZ_MAX_WORK iterations in all instead of FREP_MAX_LOOP_ITERATIONS per
     * point and evaluation (tests/fuzz/compile/runaway_gear.hf, a gear whose loop
     * never ends, took 86 s under the sanitizers on a loaded machine). */
    if (frep_program_set_work_limit(p, FUZZ_MAX_WORK) != 0) {
        frep_program_free(p);
        return 0;
    }
    double x[2] = { 0.5, -1e6 }, y[2] = { 0.25, 1e6 }, z[2] = { 1e-9, 0 };
    double f[2], gx[2], gy[2], gz[2];
    frep_scratch *s = frep_scratch_new(p);
    if (s) {
        frep_eval(p, s, 2, x, y, z, NULL, f);
        frep_eval_grad(p, s, 2, x, y, z, NULL, f, gx, gy, gz);
        size_t np = frep_program_nparams(p);
        if (np > 0 && np < 64) {
            double dp[64 * 2];
            frep_eval_dparams(p, s, 2, x, y, z, NULL, f, dp);
        }
        frep_scratch_free(s);
    }
    frep_program_free(p);
    return 0;
}

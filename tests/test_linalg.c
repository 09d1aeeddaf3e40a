/* test_linalg.c - unit tests of runtime/linalg.c, the symmetric 3x3 eigen solver of
 * the shared base: A V = V diag(w) and V orthonormal on random symmetric matrices at
 * several scales, ascending order, and the degenerate cases (zero, diagonal, repeated);
 * then the 3-vector helpers (runtime/vec3.h) and the thread counts (runtime/threads.h).
 */
#include <float.h>
#include <math.h>

#include "linalg.h"
#include "rng.h"
#include "tap.h"
#include "threads.h"
#include "vec3.h"

/* Random matrices per scale: enough to meet near-repeated eigenvalues. */
#define RANDOM_MATRICES 200

/* The rule of the PCA callers (geom/normals.c), which converges to rounding. */
static const linalg_jacobi_stop tight = {50, 1e-300, 1e-17, DBL_TRUE_MIN};

/* Largest |(A V - V diag(w))_ij| and |(V^T V - I)_ij|, relative to the norm of A. */
static void residuals(const double a[3][3], const double w[3], const double v[3][3],
                      double *eig_err, double *orth_err)
{
    double an = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) an = fmax(an, fabs(a[i][j]));
    *eig_err = *orth_err = 0;
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) {
            double av = 0, vv = 0;
            for (int j = 0; j < 3; j++) {
                av += a[i][j] * v[j][k];
                vv += v[j][i] * v[j][k];
            }
            *eig_err = fmax(*eig_err, fabs(av - v[i][k] * w[k]) / fmax(an, DBL_MIN));
            *orth_err = fmax(*orth_err, fabs(vv - (i == k)));
        }
}

static void test_random(void)
{
    static const double scales[] = {1e-12, 1e-3, 1, 1e6};
    frep_rng r;
    frep_rng_seed(&r, 12);
    for (size_t s = 0; s < sizeof scales / sizeof *scales; s++) {
        double worst_eig = 0, worst_orth = 0;
        for (int t = 0; t < RANDOM_MATRICES; t++) {
            double a[3][3], w[3], v[3][3], e, o;
            for (int i = 0; i < 3; i++)
                for (int j = i; j < 3; j++)
                    a[i][j] = a[j][i] = scales[s] * (2 * frep_rng_unit(&r) - 1);
            linalg_sym3_jacobi((const double(*)[3])a, &tight, w, v);
            residuals((const double(*)[3])a, w, v, &e, &o);
            worst_eig = fmax(worst_eig, e);
            worst_orth = fmax(worst_orth, o);
        }
        ok(worst_eig < 1e-14, "random, scale %g: A V = V diag(w) (worst %.3g)", scales[s],
           worst_eig);
        ok(worst_orth < 1e-14, "random, scale %g: V orthonormal (worst %.3g)", scales[s],
           worst_orth);
    }
}

static void test_sorted(void)
{
    /* Row-major, eigenvalues 1, 2, 4 (a rotation of diag(4, 1, 2)). */
    double m[9] = {2.5, 1.5, 0, 1.5, 2.5, 0, 0, 0, 2}, ev[3], vec[9];
    linalg_sym3_eig(m, &tight, ev, vec);
    is_double(ev[0], 1, 1e-14, "sorted: smallest eigenvalue first");
    is_double(ev[1], 2, 1e-14, "sorted: middle eigenvalue");
    is_double(ev[2], 4, 1e-14, "sorted: largest eigenvalue last");
    /* Eigenvector k in vec[3k..]: (1, -1, 0) / sqrt 2 for 1, (0, 0, 1) for 2. */
    is_double(fabs(vec[0] - vec[1]), sqrt(2.0), 1e-14, "sorted: eigenvector of 1");
    is_double(fabs(vec[5]), 1, 1e-14, "sorted: eigenvector of 2");
    /* An asymmetric m is read as (m + m^T) / 2. */
    double n[9] = {2.5, 3, 0, 0, 2.5, 0, 0, 0, 2}, ev2[3], vec2[9];
    linalg_sym3_eig(n, &tight, ev2, vec2);
    ok(ev2[0] == ev[0] && ev2[1] == ev[1] && ev2[2] == ev[2], "asymmetric input symmetrized");
}

static void test_degenerate(void)
{
    double z[3][3] = {{0}}, w[3], v[3][3];
    linalg_sym3_jacobi((const double(*)[3])z, &tight, w, v);
    ok(w[0] == 0 && w[1] == 0 && w[2] == 0 && v[0][0] == 1 && v[1][1] == 1 && v[2][2] == 1,
       "zero matrix: zero eigenvalues, identity vectors");
    double d[3][3] = {{3, 0, 0}, {0, -1, 0}, {0, 0, 2}};
    linalg_sym3_jacobi((const double(*)[3])d, &tight, w, v);
    ok(w[0] == 3 && w[1] == -1 && w[2] == 2 && v[0][1] == 0, "diagonal matrix: unchanged");
    /* Repeated eigenvalue: 1 (twice) and 4 from the all-ones matrix plus the identity. */
    double rep[3][3] = {{2, 1, 1}, {1, 2, 1}, {1, 1, 2}}, e, o;
    linalg_sym3_jacobi((const double(*)[3])rep, &tight, w, v);
    residuals((const double(*)[3])rep, w, v, &e, &o);
    ok(e < 1e-14 && o < 1e-14, "repeated eigenvalue: a valid basis (%.3g, %.3g)", e, o);
    /* One sweep at most: a stop rule's max_sweeps is honoured. */
    linalg_jacobi_stop one = {1, 0, 0, 0};
    double m[3][3] = {{1, 1e-3, 2e-3}, {1e-3, 2, 3e-3}, {2e-3, 3e-3, 3}};
    linalg_sym3_jacobi((const double(*)[3])m, &one, w, v);
    residuals((const double(*)[3])m, w, v, &e, &o);
    ok(e > 0 && e < 1e-5 && o < 1e-14, "one sweep: close, not exact (%.3g)", e);
}

/* Products, length, difference and both unit-vector rules, on exact values. */
static void test_vec3(void)
{
    const double a[3] = {1, 2, 3}, b[3] = {4, -5, 6};
    double c[3], d[3];
    ok(vec3_dot(a, b) == 12, "vec3_dot");
    vec3_cross(a, b, c);
    ok(c[0] == 27 && c[1] == 6 && c[2] == -13, "vec3_cross");
    ok(vec3_dot(c, a) == 0 && vec3_dot(c, b) == 0, "vec3_cross: orthogonal to both");
    vec3_sub(b, a, d);
    ok(d[0] == 3 && d[1] == -7 && d[2] == 3, "vec3_sub: b - a");
    double v[3] = {3, 0, 4};
    ok(vec3_len(v) == 5, "vec3_len");
    ok(vec3_normalize(v) == 0 && v[0] == 0.6 && v[1] == 0 && v[2] == 0.8, "vec3_normalize");
    double z[3] = {0, 0, 0}, inf[3] = {INFINITY, 0, 0};
    ok(vec3_normalize(z) == -1 && z[0] == 0, "vec3_normalize: zero fails, unchanged");
    ok(vec3_normalize(inf) == -1 && inf[0] == INFINITY, "vec3_normalize: infinite fails");
    double big[3] = {1e200, 0, 1e200}, tiny[3] = {1e-170, 0, 0}, small[3] = {0, 3e-150, 4e-150};
    double nan3[3] = {NAN, 1, 0};
    ok(vec3_normalize(big) == -1 && big[0] == 1e200, "vec3_normalize: |v| overflows, fails");
    ok(vec3_normalize(tiny) == -1 && tiny[0] == 1e-170, "vec3_normalize: v.v underflows, fails");
    ok(vec3_normalize(small) == 0 && fabs(small[1] - 0.6) < 1e-15 && fabs(small[2] - 0.8) < 1e-15,
       "vec3_normalize: short but representable");
    ok(vec3_normalize(nan3) == -1 && isnan(nan3[0]) && nan3[1] == 1, "vec3_normalize: NaN fails");
}

/* A request is honoured; 0 or less means the default, never below one thread. */
static void test_threads(void)
{
    ok(frep_threads(3) == 3 || frep_threads(3) == 1, "frep_threads: a request (1 without OpenMP)");
    ok(frep_threads(0) >= 1 && frep_threads(-2) == frep_threads(0), "frep_threads: the default");
    ok(frep_thread_num() == 0 && frep_team_size() == 1, "outside a parallel region: thread 0 of 1");
}

int main(void)
{
    test_random();
    test_sorted();
    test_degenerate();
    test_vec3();
    test_threads();
    return done_testing();
}

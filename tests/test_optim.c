/* test_optim.c - unit tests of fit/optim.c: BFGS, Levenberg-Marquardt and simulated
 * annealing on test functions with known minima (Rosenbrock, six-hump camel,
 * Goldstein-Price, Shekel, Rastrigin) and the NIST StRD nonlinear regression set MGH09
 * with its certified parameters.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "optim.h"
#include "tap.h"

#define PI 3.14159265358979323846
/* Evaluations a phase may take past its budget: the check runs once per trial step. */
#define LS_LIMIT_SLACK 2

/* Rosenbrock in n dimensions: sum 100 (x[i+1] - x[i]^2)^2 + (1 - x[i])^2; min 0 at 1. */
static double rosenbrock(void *user, const double *x, double *g)
{
    size_t n = *(const size_t *)user;
    double f = 0;
    if (g) memset(g, 0, n * sizeof *g);
    for (size_t i = 0; i + 1 < n; i++) {
        double a = x[i + 1] - x[i] * x[i], b = 1 - x[i];
        f += 100 * a * a + b * b;
        if (g) {
            g[i] += -400 * a * x[i] - 2 * b;
            g[i + 1] += 200 * a;
        }
    }
    return f;
}

/* Six-hump camel: min -1.0316284535 at (0.0898, -0.7126) and (-0.0898, 0.7126). */
/* sum of (i + 1) (x_i - c_i)^2 with c = (3, -2, 0.5, 7). */
static double shifted_quadratic(void *user, const double *x, double *g)
{
    static const double c[4] = {3, -2, 0.5, 7};
    size_t n = *(const size_t *)user;
    double f = 0;
    for (size_t i = 0; i < n; i++) {
        f += (double)(i + 1) * (x[i] - c[i]) * (x[i] - c[i]);
        if (g) g[i] = 2.0 * (double)(i + 1) * (x[i] - c[i]);
    }
    return f;
}

/* |x - 0.3| + y^2: smooth except on the line x = 0.3, where its minimum lies. */
static double kinked(void *user, const double *v, double *g)
{
    (void)user;
    if (g) g[0] = v[0] >= 0.3 ? 1 : -1, g[1] = 2 * v[1];
    return fabs(v[0] - 0.3) + v[1] * v[1];
}

static double camel(void *user, const double *v, double *g)
{
    (void)user;
    double x = v[0], y = v[1];
    double f = (4 - 2.1 * x * x + x * x * x * x / 3) * x * x + x * y + (-4 + 4 * y * y) * y * y;
    if (g) {
        g[0] = 8 * x - 8.4 * x * x * x + 2 * x * x * x * x * x + y;
        g[1] = x - 8 * y + 16 * y * y * y;
    }
    return f;
}

/* Goldstein-Price: min 3 at (0, -1), several local minima in [-2, 2]^2. */
static double goldstein_price(void *user, const double *v, double *g)
{
    (void)user;
    double x = v[0], y = v[1];
    double s1 = x + y + 1, q1 = 19 - 14 * x + 3 * x * x - 14 * y + 6 * x * y + 3 * y * y;
    double s2 = 2 * x - 3 * y, q2 = 18 - 32 * x + 12 * x * x + 48 * y - 36 * x * y + 27 * y * y;
    double A = 1 + s1 * s1 * q1, B = 30 + s2 * s2 * q2;
    if (g) {
        double Ax = 2 * s1 * q1 + s1 * s1 * (-14 + 6 * x + 6 * y);
        double Ay = 2 * s1 * q1 + s1 * s1 * (-14 + 6 * x + 6 * y);
        double Bx = 4 * s2 * q2 + s2 * s2 * (-32 + 24 * x - 36 * y);
        double By = -6 * s2 * q2 + s2 * s2 * (48 - 36 * x + 54 * y);
        g[0] = Ax * B + A * Bx;
        g[1] = Ay * B + A * By;
    }
    return A * B;
}

/* Shekel with m = 10 in [0, 10]^4: global min -10.5364 near (4, 4, 4, 4). */
static const double shekel_a[10][4] = {
    {4, 4, 4, 4}, {1, 1, 1, 1}, {8, 8, 8, 8}, {6, 6, 6, 6}, {3, 7, 3, 7},
    {2, 9, 2, 9}, {5, 5, 3, 3}, {8, 1, 8, 1}, {6, 2, 6, 2}, {7, 3.6, 7, 3.6}};
static const double shekel_c[10] = {0.1, 0.2, 0.2, 0.4, 0.4, 0.6, 0.3, 0.7, 0.5, 0.5};

static double shekel(void *user, const double *x, double *g)
{
    (void)user;
    double f = 0;
    if (g) memset(g, 0, 4 * sizeof *g);
    for (int i = 0; i < 10; i++) {
        double d = shekel_c[i];
        for (int j = 0; j < 4; j++) d += (x[j] - shekel_a[i][j]) * (x[j] - shekel_a[i][j]);
        f -= 1 / d;
        if (g)
            for (int j = 0; j < 4; j++) g[j] += 2 * (x[j] - shekel_a[i][j]) / (d * d);
    }
    return f;
}

/* Rastrigin in n dimensions: 10 n + sum x^2 - 10 cos(2 pi x); min 0 at 0, a local
 * minimum near every integer point. */
static double rastrigin(void *user, const double *x, double *g)
{
    size_t n = *(const size_t *)user;
    double f = 10.0 * (double)n;
    for (size_t i = 0; i < n; i++) {
        f += x[i] * x[i] - 10 * cos(2 * PI * x[i]);
        if (g) g[i] = 2 * x[i] + 20 * PI * sin(2 * PI * x[i]);
    }
    return f;
}

/* NIST StRD MGH09 (Kowalik & Osborne): y = b1 (x^2 + x b2) / (x^2 + x b3 + b4). */
static const double mgh09_x[11] = {4, 2, 1, 0.5, 0.25, 0.167, 0.125, 0.1, 0.0833, 0.0714, 0.0625};
static const double mgh09_y[11] = {0.1957, 0.1947, 0.1735, 0.16,   0.0844, 0.0627,
                                   0.0456, 0.0342, 0.0323, 0.0235, 0.0246};
static const double mgh09_cert[4] = {1.9280693458E-01, 1.9128232873E-01, 1.2305650693E-01,
                                     1.3606233068E-01};
static const double mgh09_rss = 3.0750560385E-04;

static double mgh09(void *user, const double *b, double *jtj, double *jtr)
{
    (void)user;
    double cost = 0;
    memset(jtj, 0, 16 * sizeof *jtj);
    memset(jtr, 0, 4 * sizeof *jtr);
    for (int i = 0; i < 11; i++) {
        double x = mgh09_x[i];
        double num = x * x + x * b[1], den = x * x + x * b[2] + b[3];
        double r = b[0] * num / den - mgh09_y[i];
        double J[4] = {num / den, b[0] * x / den, -b[0] * num * x / (den * den),
                       -b[0] * num / (den * den)};
        cost += 0.5 * r * r;
        for (int j = 0; j < 4; j++) {
            jtr[j] += J[j] * r;
            for (int k = 0; k < 4; k++) jtj[j * 4 + k] += J[j] * J[k];
        }
    }
    return cost;
}

/* The same as a plain function with gradient, for BFGS. */
static double mgh09_f(void *user, const double *b, double *g)
{
    double jtj[16], jtr[4];
    double c = mgh09(user, b, jtj, jtr);
    if (g) memcpy(g, jtr, sizeof jtr);
    return c;
}

/* Central-difference check of an analytic gradient at x. */
static double grad_error(fit_fn fn, void *user, size_t n, const double *x)
{
    double g[8], xp[8], worst = 0;
    fn(user, x, g);
    for (size_t i = 0; i < n; i++) {
        double h = 1e-6 * fmax(1, fabs(x[i]));
        memcpy(xp, x, n * sizeof *x);
        xp[i] = x[i] + h;
        double fp = fn(user, xp, NULL);
        xp[i] = x[i] - h;
        double fm = fn(user, xp, NULL);
        double fd = (fp - fm) / (2 * h);
        worst = fmax(worst, fabs(fd - g[i]) / fmax(1, fabs(g[i])));
    }
    return worst;
}

/* SA then BFGS from its best point: the hybrid the fitter uses. */
static double hybrid(fit_fn fn, void *user, size_t n, double *x, const double *lo,
                     const double *hi, uint64_t seed, long *evals)
{
    frep_rng rng;
    frep_rng_seed(&rng, seed);
    fit_control c;
    fit_control_init(&c);
    fit_sa_options so;
    fit_sa_options_init(&so);
    double f;
    fit_sa(fn, user, n, x, lo, hi, &so, &rng, &c, &f, NULL);
    fit_bfgs(fn, user, n, x, lo, hi, NULL, &c, &f, NULL);
    if (evals) *evals = c.evals;
    return f;
}

/* Local search hook of fit_sa: BFGS within the bounds. */
typedef struct local_ctx {
    fit_fn fn;
    void *user;
    size_t n;
    const double *lo, *hi;
    fit_control *c;
} local_ctx;

static int local_bfgs(void *user, double *x, double *fx)
{
    local_ctx *L = user;
    fit_status s = fit_bfgs(L->fn, L->user, L->n, x, L->lo, L->hi, NULL, L->c, fx, NULL);
    return s == FIT_FAILED || s == FIT_NOMEM ? -1 : 0;
}

/* fit_sa with BFGS from every new best (dual annealing, as frep fit runs it) on
 * Shekel-10 in [0, 10]^4 from (1, 1, 1, 1), with the options so (the local search is set
 * here) and a generator seeded with seed. x gets the best point, *its (may be NULL) the
 * iterations; returns the best value. */
static double shekel_dual(fit_sa_options *so, uint64_t seed, double x[4], long *its)
{
    double lo[4] = {0, 0, 0, 0}, hi[4] = {10, 10, 10, 10}, f;
    for (int j = 0; j < 4; j++) x[j] = 1;
    frep_rng rng;
    frep_rng_seed(&rng, seed);
    fit_control c;
    fit_control_init(&c);
    local_ctx L = {shekel, NULL, 4, lo, hi, &c};
    so->local = local_bfgs;
    so->local_user = &L;
    fit_sa(shekel, NULL, 4, x, lo, hi, so, &rng, &c, &f, its);
    return f;
}

int main(void)
{
    /* RNG: deterministic, uniform in [0, 1), normal with the right moments. */
    {
        frep_rng a, b;
        frep_rng_seed(&a, 42);
        frep_rng_seed(&b, 42);
        int same = 1;
        for (int i = 0; i < 100; i++) same &= frep_rng_next(&a) == frep_rng_next(&b);
        ok(same, "rng: the same seed gives the same stream");
        double s = 0, s2 = 0, umin = 1, umax = 0;
        for (int i = 0; i < 100000; i++) {
            double u = frep_rng_unit(&a);
            umin = fmin(umin, u), umax = fmax(umax, u);
            double z = frep_rng_normal(&a);
            s += z, s2 += z * z;
        }
        ok(umin >= 0 && umax < 1 && umin < 1e-3 && umax > 0.999, "rng: uniform in [0, 1)");
        is_double(s / 100000, 0, 0.02, "rng: normal mean 0");
        is_double(s2 / 100000, 1, 0.02, "rng: normal variance 1");
    }

    /* Analytic gradients of the test functions themselves. */
    {
        size_t n2 = 2, n5 = 5;
        double p[5] = {0.3, -0.7, 1.1, 0.2, -0.4}, q[4] = {3.1, 4.2, 5.3, 2.4};
        ok(grad_error(rosenbrock, &n5, 5, p) < 1e-5, "gradient of rosenbrock");
        ok(grad_error(camel, NULL, 2, p) < 1e-5, "gradient of six-hump camel");
        ok(grad_error(goldstein_price, NULL, 2, p) < 1e-5, "gradient of goldstein-price");
        ok(grad_error(shekel, NULL, 4, q) < 1e-5, "gradient of shekel");
        ok(grad_error(rastrigin, &n2, 2, p) < 1e-5, "gradient of rastrigin");
        ok(grad_error(mgh09_f, NULL, 4, q) < 1e-5, "gradient of mgh09");
    }

    /* BFGS on Rosenbrock from the classic start (-1.2, 1) and in 10 dimensions. */
    {
        size_t n = 2;
        double x[2] = {-1.2, 1}, f;
        int iters;
        fit_control c;
        fit_control_init(&c);
        fit_status st = fit_bfgs(rosenbrock, &n, n, x, NULL, NULL, NULL, &c, &f, &iters);
        is_int(st, FIT_CONVERGED, "bfgs rosenbrock 2d converges");
        is_double(x[0], 1, 1e-6, "bfgs rosenbrock x");
        is_double(x[1], 1, 1e-6, "bfgs rosenbrock y");
        ok(iters < 60, "bfgs rosenbrock 2d in %d iterations (< 60)", iters);
        diag("bfgs rosenbrock 2d: %d iterations, %ld evaluations, f = %g", iters, c.evals, f);

        size_t n10 = 10;
        double y[10];
        for (int i = 0; i < 10; i++) y[i] = i % 2 ? 1 : -1.2;
        fit_control_init(&c);
        fit_bfgs(rosenbrock, &n10, n10, y, NULL, NULL, NULL, &c, &f, &iters);
        double err = 0;
        for (int i = 0; i < 10; i++) err = fmax(err, fabs(y[i] - 1));
        ok(err < 1e-6, "bfgs rosenbrock 10d reaches 1 (max error %g)", err);
    }

    /* Bounds: Rosenbrock restricted to x <= 0.5 has its minimum on the bound, at
     * (0.5, 0.25) (for fixed x, y = x^2 is best and (1 - x)^2 decreases up to x = 1). */
    {
        size_t n = 2;
        double x[2] = {-1.2, 1}, f, lo[2] = {-2, -2}, hi[2] = {0.5, 2};
        fit_status st = fit_bfgs(rosenbrock, &n, n, x, lo, hi, NULL, NULL, &f, NULL);
        is_int(st, FIT_CONVERGED, "bfgs with bounds converges");
        is_double(x[0], 0.5, 1e-9, "bfgs: x held on its upper bound");
        is_double(x[1], 0.25, 1e-6, "bfgs: y free at x^2");
    }

    /* Bounded quasi-Newton: a quadratic whose minimum (3, -2, 0.5, 7) lies outside the
     * box [0, 1]^4 in three coordinates, started near the far corner: it must end on the
     * bounds (1, 0, 0.5, 1) with a vanishing projected gradient, however the steps cross
     * the breakpoints of the projection. */
    {
        size_t n = 4;
        double x[4] = {0.01, 0.99, 0.02, 0.03}, f, lo[4] = {0, 0, 0, 0}, hi[4] = {1, 1, 1, 1};
        double g[4], pg[4];
        fit_status st = fit_bfgs(shifted_quadratic, &n, n, x, lo, hi, NULL, NULL, &f, NULL);
        shifted_quadratic(&n, x, g);
        double pgn = fit_projected_gradient(n, x, g, lo, hi, NULL, pg);
        ok(st == FIT_CONVERGED && fabs(x[0] - 1) < 1e-12 && fabs(x[1]) < 1e-12 &&
           fabs(x[2] - 0.5) < 1e-8 && fabs(x[3] - 1) < 1e-12 && pgn < 1e-8,
           "bfgs on a box: (%g, %g, %g, %g), %s, projected gradient %g", x[0], x[1], x[2],
           x[3], fit_status_name(st), pgn);
    }

    /* A kink is not a stationary point: on |x - 0.3| + y^2 BFGS ends near x = 0.3 where
     * the gradient is +-1, and must not call that converged. */
    {
        size_t n = 2;
        double x[2] = {1.7, 1}, f;
        fit_status st = fit_bfgs(kinked, &n, n, x, NULL, NULL, NULL, NULL, &f, NULL);
        ok(st == FIT_STALLED && fabs(x[0] - 0.3) < 1e-3,
           "bfgs at a kink: %s at x = %.6g", fit_status_name(st), x[0]);
    }

    /* Budget: a limit of 20 evaluations stops BFGS with FIT_STOPPED. */
    {
        size_t n = 2;
        double x[2] = {-1.2, 1}, f;
        fit_control c;
        fit_control_init(&c);
        c.max_evals = 20;
        fit_status st = fit_bfgs(rosenbrock, &n, n, x, NULL, NULL, NULL, &c, &f, NULL);
        is_int(st, FIT_STOPPED, "bfgs stops when the evaluation budget is spent");
        ok(c.evals <= 20 + 2 * LS_LIMIT_SLACK, "bfgs used %ld evaluations", c.evals);
        ok(f < rosenbrock(&n, (double[]){-1.2, 1}, NULL), "bfgs returns a point better than the start");
    }

    /* Interrupt flag. */
    {
        size_t n = 2;
        double x[2] = {-1.2, 1}, f;
        volatile sig_atomic_t flag = 1;
        fit_control c;
        fit_control_init(&c);
        c.interrupt = &flag;
        is_int(fit_bfgs(rosenbrock, &n, n, x, NULL, NULL, NULL, &c, &f, NULL), FIT_STOPPED,
               "bfgs honours the interrupt flag");
    }

    /* MGH09 with Levenberg-Marquardt from NIST's second start, and with BFGS. */
    {
        double b[4] = {0.25, 0.39, 0.415, 0.39}, f;
        fit_status st = fit_lm(mgh09, NULL, 4, b, NULL, NULL, NULL, NULL, &f, NULL);
        is_int(st, FIT_CONVERGED, "lm mgh09 converges");
        for (int j = 0; j < 4; j++)
            is_double(b[j] / mgh09_cert[j], 1, 1e-6, "lm mgh09 b%d matches the certified value", j + 1);
        is_double(2 * f / mgh09_rss, 1, 1e-8, "lm mgh09 residual sum of squares");

        double c[4] = {0.25, 0.39, 0.415, 0.39};
        fit_bfgs(mgh09_f, NULL, 4, c, NULL, NULL, NULL, NULL, &f, NULL);
        for (int j = 0; j < 4; j++)
            is_double(c[j] / mgh09_cert[j], 1, 1e-5, "bfgs mgh09 b%d matches the certified value", j + 1);
    }

    /* Simulated annealing + BFGS on multimodal functions. */
    {
        double lo[2] = {-3, -2}, hi[2] = {3, 2}, x[2] = {2.5, 1.5};
        long evals;
        double f = hybrid(camel, NULL, 2, x, lo, hi, 1, &evals);
        is_double(f, -1.0316284535, 1e-8, "sa+bfgs six-hump camel global minimum");
        ok(fabs(fabs(x[0]) - 0.0898) < 1e-3 && fabs(fabs(x[1]) - 0.7126) < 1e-3,
           "six-hump camel at (%g, %g)", x[0], x[1]);
        diag("camel: %ld evaluations", evals);
    }
    {
        double lo[2] = {-2, -2}, hi[2] = {2, 2}, x[2] = {1.5, 1.5};
        double f = hybrid(goldstein_price, NULL, 2, x, lo, hi, 2, NULL);
        is_double(f, 3, 1e-8, "sa+bfgs goldstein-price global minimum 3");
        is_double(x[0], 0, 1e-5, "goldstein-price x = 0");
        is_double(x[1], -1, 1e-5, "goldstein-price y = -1");
        /* BFGS alone from (1.5, 1.5) is trapped in a local minimum (f = 30 or 84). */
        double y[2] = {1.5, 1.5}, fl;
        fit_bfgs(goldstein_price, NULL, 2, y, lo, hi, NULL, NULL, &fl, NULL);
        ok(fl > 3.5, "bfgs alone stops in a local minimum of goldstein-price (f = %g)", fl);
    }
    {
        /* Shekel's narrow global basin defeats annealing alone; with BFGS from every new
         * best (dual annealing, as frep fit runs it) most seeds find it. */
        int hits = 0;
        double worst = 0;
        for (uint64_t seed = 1; seed <= 10; seed++) {
            double x[4];
            fit_sa_options so;
            fit_sa_options_init(&so);
            double f = shekel_dual(&so, seed, x, NULL);
            if (f < -10.536) {
                hits++;
                for (int j = 0; j < 4; j++) worst = fmax(worst, fabs(x[j] - 4));
            }
        }
        ok(hits >= 6, "sa with local searches: shekel-10 global minimum for %d of 10 seeds", hits);
        /* Independent chains: the best of three fails only where all three do. With
         * probes every 2 quiet iterations, as frep fit runs them. */
        int hits3 = 0;
        long its1 = 0, its3 = 0;
        for (uint64_t seed = 1; seed <= 10; seed++) {
            for (int chains = 1; chains <= 3; chains += 2) {
                double x[4];
                fit_sa_options so;
                fit_sa_options_init(&so);
                so.local_period = 2;
                so.chains = chains;
                long its = 0;
                double f = shekel_dual(&so, seed, x, &its);
                if (chains == 3) hits3 += f < -10.536, its3 += its;
                else its1 += its;
            }
        }
        ok(hits3 == 10, "sa, 3 chains: shekel-10 global minimum for %d of 10 seeds", hits3);
        ok(its3 > its1, "3 chains run more iterations than 1 (%ld against %ld)", its3, its1);
        ok(hits > 0 && worst < 0.01, "shekel-10 minimum near (4, 4, 4, 4) (max error %g)", worst);
    }
    {
        /* A chain stops once its best reaches a point an earlier chain ended at
         * (agree, within agree_tol of each range): the same run up to there, without
         * the stall after it. A point it never reaches changes nothing. */
        double x0[4], x1[4], x2[4], far[4] = {9, 9, 9, 9};
        long its0 = 0, its1 = 0, its2 = 0;
        fit_sa_options so;
        fit_sa_options_init(&so);
        so.local_period = 2;
        double f0 = shekel_dual(&so, 3, x0, &its0);
        so.agree = x0, so.nagree = 1, so.agree_tol = 1e-6;
        double f1 = shekel_dual(&so, 3, x1, &its1);
        so.agree = far;
        double f2 = shekel_dual(&so, 3, x2, &its2);
        ok(f0 < -10.536 && f1 == f0 && its1 < its0,
           "sa: a chain stops at an earlier chain's best (%ld iterations, %ld without)",
           its1, its0);
        ok(f2 == f0 && its2 == its0, "sa: a point never reached changes nothing");
        /* A chain whose probes keep ending at its best value stops after
         * probe_returns of them in a row instead of waiting out its stall. */
        double x3[4];
        long its3 = 0;
        fit_sa_options_init(&so);
        so.local_period = 2;
        so.probe_returns = 2, so.probe_tol = 1e-6;
        double f3 = shekel_dual(&so, 3, x3, &its3);
        ok(fabs(f3 - f0) <= 1e-9 * fabs(f0) && its3 < its0,
           "sa: probes that return to the best end the chain (%ld iterations, %ld without)",
           its3, its0);
        /* Not when that best lies on a bound: the minimum of sum (i + 1) (x_i - c_i)^2
         * with c = (3, -2) in [-1, 1]^2 is the corner (1, -1). */
        long itsb[2];
        for (int k = 0; k < 2; k++) {
            size_t nq = 2;
            double qlo[2] = {-1, -1}, qhi[2] = {1, 1}, q[2] = {0, 0}, fq;
            frep_rng rng;
            frep_rng_seed(&rng, 5);
            fit_control c;
            fit_control_init(&c);
            local_ctx L = {shifted_quadratic, &nq, 2, qlo, qhi, &c};
            fit_sa_options_init(&so);
            so.local = local_bfgs, so.local_user = &L;
            so.local_period = 2, so.probe_tol = 1e-6, so.probe_returns = k ? 2 : 0;
            fit_sa(shifted_quadratic, &nq, 2, q, qlo, qhi, &so, &rng, &c, &fq, &itsb[k]);
        }
        ok(itsb[1] == itsb[0] && itsb[0] > so.stall_iter,
           "sa: a best on a bound waits out the stall (%ld iterations, %ld without returns)",
           itsb[1], itsb[0]);
        double lo[2] = {0, -1}, hi[2] = {10, 1}, a[2] = {4, 0};
        fit_sa_options ag;
        fit_sa_options_init(&ag);
        ag.agree = a, ag.nagree = 1, ag.agree_tol = 1e-6;
        double near[2] = {4 + 0.9e-5, 0 - 1.9e-6}, off[2] = {4, 2.1e-6};
        ok(fit_sa_agreeing(&ag, 2, near, lo, hi) == 0 &&
           fit_sa_agreeing(&ag, 2, off, lo, hi) == -1,
           "sa: agreement is within agree_tol of each coordinate's range");
    }
    {
        size_t n = 5;
        double lo[5], hi[5], x[5];
        for (int j = 0; j < 5; j++) lo[j] = -5.12, hi[j] = 5.12, x[j] = 3.3;
        double f = hybrid(rastrigin, &n, n, x, lo, hi, 4, NULL);
        is_double(f, 0, 1e-9, "sa+bfgs rastrigin 5d global minimum 0");
        /* Determinism: the same seed gives the same answer bit for bit. */
        double y[5];
        for (int j = 0; j < 5; j++) y[j] = 3.3;
        long e1, e2;
        double x2[5];
        for (int j = 0; j < 5; j++) x2[j] = 3.3;
        double f1 = hybrid(rastrigin, &n, n, y, lo, hi, 9, &e1);
        double f2 = hybrid(rastrigin, &n, n, x2, lo, hi, 9, &e2);
        ok(f1 == f2 && e1 == e2 && memcmp(y, x2, sizeof y) == 0, "sa: same seed, same result");
    }

    /* SA rejects unusable bounds. */
    {
        double lo[1] = {1}, hi[1] = {1}, x[1] = {1}, f;
        frep_rng r;
        frep_rng_seed(&r, 1);
        size_t n = 1;
        is_int(fit_sa(rastrigin, &n, 1, x, lo, hi, NULL, &r, NULL, &f, NULL), FIT_FAILED,
               "sa refuses an empty box");
    }
    return done_testing();
}

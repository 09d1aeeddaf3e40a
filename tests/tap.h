/* tap.h - minimal Test Anything Protocol helpers for frep's C unit tests, run under
 * Automake's tap-driver.sh.  Header-only: each test program includes it once.
 */
#ifndef FREP_TAP_H
#define FREP_TAP_H

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

static int tap_n, tap_failed;

/* A deterministic xorshift step (tests must not depend on the clock): the next value of
 * *state mapped to [lo, hi).  Each test keeps its own state and seed. */
static inline double tap_urand(uint64_t *state, double lo, double hi)
{
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    return lo + (hi - lo) * (double)(*state >> 11) / 9007199254740992.0;
}

static void tap_vok(int cond, const char *fmt, va_list ap)
{
    ++tap_n;
    if (!cond) ++tap_failed;
    printf("%s %d - ", cond ? "ok" : "not ok", tap_n);
    vprintf(fmt, ap);
    putchar('\n');
    fflush(stdout);
}

static int ok(int cond, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static int ok(int cond, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    tap_vok(cond, fmt, ap);
    va_end(ap);
    return cond;
}

static void diag(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;
static void diag(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fputs("# ", stdout);
    vprintf(fmt, ap);
    putchar('\n');
    va_end(ap);
}

#define is_int(got, want, ...) \
    (ok((long long)(got) == (long long)(want), __VA_ARGS__) || \
     (diag("  got %lld, want %lld", (long long)(got), (long long)(want)), 0))

/* Equal within eps (absolute), or both NaN, or the same infinity. */
static int tap_close(double a, double b, double eps)
{
    if (isnan(a) || isnan(b)) return isnan(a) && isnan(b);
    if (isinf(a) || isinf(b)) return a == b;
    return fabs(a - b) <= eps;
}

#define is_double(got, want, eps, ...) \
    (ok(tap_close((got), (want), (eps)), __VA_ARGS__) || \
     (diag("  got %.17g, want %.17g (eps %g)", (double)(got), (double)(want), (double)(eps)), 0))

#define is_str(got, want, ...) \
    (ok(strcmp((got), (want)) == 0, __VA_ARGS__) || \
     (diag("  got '%s'\n#  want '%s'", (got), (want)), 0))

static int done_testing(void)
{
    printf("1..%d\n", tap_n);
    return tap_failed ? 1 : 0;
}

#endif

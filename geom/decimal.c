/* decimal.c - exact conversion of short decimal numbers (see decimal.h): the cloud
 * readers' fast path, where strtod was most of the time of reading a cloud.
 *
 * Clinger's fast path (1990): a significand w <= 2^53 and a power of ten 10^k,
 * |k| <= 22, are both exact doubles, so w * 10^k or w / 10^k rounded once is the
 * correctly rounded value. The 17-digit numbers that shortest round-trip printing
 * writes (frep sample's) have w above 2^53; where long double has a 64-bit significand
 * (x87) w < 2^64 and 10^k, |k| <= 27, are exact in it, and its product or quotient
 * rounded to 64 bits, then to 53, is the value rounded once unless the 64-bit result
 * lies on a tie between two doubles (double rounding): such results go to strtod. (A
 * value below a tie cannot round up onto it and then past it: the tie is a 64-bit
 * number, so rounding to 64 bits keeps the value on its side or puts it on the tie.)
 * Both assume rounding to nearest, which frep never changes.
 */
#include "decimal.h"

#include <float.h>
#include <stdint.h>
#include <string.h>

/* Largest power of ten of Clinger's path: 10^22 = 2^22 5^22, 5^22 < 2^53. */
#define DECIMAL_EXACT_POW 22
/* Largest power of ten of the long double path: 5^27 < 2^64. */
#define DECIMAL_EXACT_POW_L 27
/* Exponent digits are read up to this value and no further (the value then only has
 * to be out of every exact range; strtod takes it from there). */
#define DECIMAL_EXP_CAP 100000

static const double pow10_d[DECIMAL_EXACT_POW + 1] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int is_digit(char c) { return c >= '0' && c <= '9'; }

/* w * 10^k by Clinger's path; 0 when w or k is out of its range. */
static int clinger(uint64_t w, long k, double *v)
{
#if FLT_EVAL_METHOD == 0
    if (w > (UINT64_C(1) << 53) || k < -DECIMAL_EXACT_POW || k > DECIMAL_EXACT_POW) return 0;
    double d = (double)w;
    *v = k >= 0 ? d * pow10_d[k] : d / pow10_d[-k];
    return 1;
#else
    (void)w, (void)k, (void)v;
    return 0;   /* double arithmetic in a wider format: rounded twice */
#endif
}

/* w * 10^k through the x87 long double (64-bit significand, stored first, little
 * endian); 0 out of range or on a tie. */
static int extended(uint64_t w, long k, double *v)
{
#if LDBL_MANT_DIG == 64 && (defined(__x86_64__) || defined(__i386__))
    static const long double pow10_l[DECIMAL_EXACT_POW_L + 1] = {
        1e0L,  1e1L,  1e2L,  1e3L,  1e4L,  1e5L,  1e6L,  1e7L,  1e8L,  1e9L,
        1e10L, 1e11L, 1e12L, 1e13L, 1e14L, 1e15L, 1e16L, 1e17L, 1e18L, 1e19L,
        1e20L, 1e21L, 1e22L, 1e23L, 1e24L, 1e25L, 1e26L, 1e27L};
    if (k < -DECIMAL_EXACT_POW_L || k > DECIMAL_EXACT_POW_L) return 0;
    long double l = (long double)w;
    l = k >= 0 ? l * pow10_l[k] : l / pow10_l[-k];
    /* A tie between the two doubles of l's binade around l: the 11 bits below the 53
     * of a double are 10000000000. (l is normal: 1e-27 <= l < 1e47.) */
    uint64_t sig;
    memcpy(&sig, &l, sizeof sig);
    if ((sig & 0x7ff) == 0x400) return 0;
    *v = (double)l;
    return 1;
#else
    (void)w, (void)k, (void)v;
    return 0;
#endif
}

/* number -> [+-] digits* [. digits*] [(e|E) [+-] digits+], with a digit before the
 * exponent */
int decimal_parse(const char *s, const char *end, double *v)
{
    const char *p = s;
    int neg = 0, seen = 0, digits = 0;
    uint64_t w = 0;
    long k = 0;                 /* the value is w * 10^k */
    if (p < end && (*p == '+' || *p == '-')) neg = *p++ == '-';
    for (; p < end && is_digit(*p); p++) {
        seen = 1;
        if (w == 0 && *p == '0') continue;      /* leading zeros are not significant */
        if (++digits > DECIMAL_MAX_DIGITS) return 0;
        w = 10 * w + (uint64_t)(*p - '0');
    }
    if (p < end && *p == '.')
        for (p++; p < end && is_digit(*p); p++) {
            seen = 1;
            k--;
            if (w == 0 && *p == '0') continue;
            if (++digits > DECIMAL_MAX_DIGITS) return 0;
            w = 10 * w + (uint64_t)(*p - '0');
        }
    if (!seen) return 0;
    if (p < end && (*p == 'e' || *p == 'E')) {
        int eneg = 0;
        long x = 0;
        p++;
        if (p < end && (*p == '+' || *p == '-')) eneg = *p++ == '-';
        if (p >= end || !is_digit(*p)) return 0;
        for (; p < end && is_digit(*p); p++)
            if (x < DECIMAL_EXP_CAP) x = 10 * x + (*p - '0');
        k += eneg ? -x : x;
    }
    if (p != end) return 0;
    double d;
    if (w == 0) d = 0;          /* zero with any exponent, as strtod gives it */
    else if (!clinger(w, k, &d) && !extended(w, k, &d)) return 0;
    *v = neg ? -d : d;
    return 1;
}
